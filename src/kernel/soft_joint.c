/* Soft joints: hecker_dynamics/contact/soft_joints.py (SoftJointPass.resolve), operation for
 * operation (see joint.h): one sub-step's warm start, sweep with bias, position update and
 * sweep without bias, as Box2D v3's solver stages, on the rows joint.c builds.
 */
#include <stddef.h>

#include "floats.h"
#include "joint.h"

/* The sweep's small functions take `n`, the entries of a row whose bodies are each once in it
 * (a slider's, a weld's or a rod's rows: 1 or 2), as a constant, so that each is unrolled for
 * it; 0: any row, as the Python functions take it. None changes an operation. */

/* contact/soft_joints.py: _push, v += M^-1 J^T amount along one row's direction (no zero
 * skipped: a zero impulse still adds its signed zeros, as Python does). */
static HD_HOT void hd_push(double *v, const hd_joint_row *direction, double amount, int n)
{
    const int count = n ? n : direction->count;
    for (int e = 0; e < count; ++e) {
        double *target = v + 3 * direction->body[e];
        target[0] += direction->j[e][0] * amount;
        target[1] += direction->j[e][1] * amount;
        target[2] += direction->j[e][2] * amount;
    }
}

/* contact/joint_solve.py: dot; with n, of a row and a direction on the same bodies in the same
 * order, each once: only entry e meets entry e, so the sum takes them in dot's order without
 * its search. */
static HD_HOT double hd_dot(const hd_joint_row *row, const hd_joint_row *direction, int n)
{
    if (n == 0)
        return hd_joint_dot(row, direction);
    double s = 0.0;
    for (int e = 0; e < n; ++e)
        s += row->j[e][0] * direction->j[e][0] + row->j[e][1] * direction->j[e][1]
             + row->j[e][2] * direction->j[e][2];
    return s;
}

/* contact/joint_solve.py: rate. */
static HD_HOT double hd_rate(const hd_joint_row *row, const double *v, int n)
{
    const int count = n ? n : row->count;
    double s = 0.0;
    for (int e = 0; e < count; ++e) {
        const double *w = v + 3 * row->body[e];
        s += row->j[e][0] * w[0] + row->j[e][1] * w[1] + row->j[e][2] * w[2];
    }
    return s;
}

/* The entries of a row whose bodies are each once in it (1 or 2), else 0. */
static HD_HOT int hd_distinct(const hd_joint_row *row)
{
    if (row->count == 1 || (row->count == 2 && row->body[0] != row->body[1]))
        return row->count;
    return 0;
}

/* contact/soft_joints.py: _pin_block, a pin's velocity error J v into b[0], b[1] and its K into
 * k[0] (k11), k[1] (k12), k[2] (k22), read off its rows' Jacobians: (1, 0, p), (0, 1, q) on body B
 * (entry 0), (-1, 0, p'), (0, -1, q') on body A (entry 1, if any). */
static HD_HOT void hd_pin_block(const hd_joint_row *row, const double *v, const double *inverse,
                                double *b, double *k)
{
    const hd_joint_row *other = row + 1;
    const long body = row->body[0];
    double p = row->j[0][2], q = other->j[0][2];
    double w = v[3 * body + 2];
    b[0] = v[3 * body] + p * w, b[1] = v[3 * body + 1] + q * w;
    double turn = inverse[3 * body + 2];
    k[0] = inverse[3 * body] + p * (turn * p);
    k[1] = p * (turn * q);
    k[2] = inverse[3 * body + 1] + q * (turn * q);
    if (row->count > 1) {
        const long a = row->body[1];
        p = row->j[1][2], q = other->j[1][2];
        w = v[3 * a + 2];
        b[0] += p * w - v[3 * a];
        b[1] += q * w - v[3 * a + 1];
        turn = inverse[3 * a + 2];
        k[0] += inverse[3 * a] + p * (turn * p);
        k[1] += p * (turn * q);
        k[2] += inverse[3 * a + 1] + q * (turn * q);
    }
}

/* contact/soft_joints.py: _push_pin, v += M^-1 J^T (ix, iy) for a pin's x and y rows. */
static HD_HOT void hd_push_pin(double *v, const hd_joint_row *row, double ix, double iy,
                               const double *inverse)
{
    const hd_joint_row *other = row + 1;
    const long body = row->body[0];
    double *target = v + 3 * body;
    const double *im = inverse + 3 * body;
    target[0] += im[0] * ix;
    target[1] += im[1] * iy;
    target[2] += im[2] * (row->j[0][2] * ix + other->j[0][2] * iy);
    if (row->count > 1) {
        const long a = row->body[1];
        target = v + 3 * a, im = inverse + 3 * a;
        target[0] -= im[0] * ix;
        target[1] -= im[1] * iy;
        target[2] += im[2] * (row->j[1][2] * ix + other->j[1][2] * iy);
    }
}

/* contact/soft_joints.py: SoftJointPass._sweep, a pin's x and y rows (`row` and the next, on
 * the same bodies) as Box2D's 2 x 2 point block, `lam` their impulses. */
static HD_HOT void hd_pin(const hd_joint_row *row, double *lam, double *v, const double *inverse,
                          const double *soft)
{
    const hd_joint_row *other = row + 1;
    double b[2], k[3];
    hd_pin_block(row, v, inverse, b, k);
    double bx = b[0], by = b[1];
    double scale = 1.0, keep = 0.0;
    if (soft != NULL) {
        bx += soft[0] * row->c;
        by += soft[0] * other->c;
        scale = soft[1], keep = soft[2];
    }
    const double k11 = k[0], k12 = k[1], k22 = k[2];
    double det = k11 * k22 - k12 * k12;
    det = det != 0.0 ? 1.0 / det : det;
    const double sx = det * (k22 * bx - k12 * by), sy = det * (k11 * by - k12 * bx);
    const double ix = -scale * sx - keep * lam[0];
    const double iy = -scale * sy - keep * lam[1];
    lam[0] += ix;
    lam[1] += iy;
    hd_push_pin(v, row, ix, iy, inverse);
}

/* contact/soft_joints.py: SoftJointPass._sweep, one row but a pin's. */
static HD_HOT void hd_row(const hd_joint_row *row, const hd_joint_row *towards, double *lam,
                          double *v, double h, const double *soft, int n)
{
    const double diagonal = hd_dot(row, towards, n);
    const double mass = diagonal > 0.0 ? 1.0 / diagonal : 0.0;
    const double velocity = hd_rate(row, v, n);
    const double old = *lam;
    double new;
    if (row->kind == HD_SOFT) {  /* the row's own spring, in both sweeps */
        const double stiffness = row->stiffness, damping = row->damping;
        const double compliance = h * (damping + h * stiffness);
        const double a2 = row->scaled ? compliance : compliance * diagonal;
        const double bias = compliance > 0.0 ? stiffness / (damping + h * stiffness) : 0.0;
        new = old - a2 / (1.0 + a2) * mass * (velocity + bias * row->c) - old / (1.0 + a2);
    } else if (row->kind == HD_MOTOR) {
        new = hd_min(hd_max(old - mass * (velocity - row->speed), -row->bound), row->bound);
    } else {  /* rigid or a limit */
        double bias = 0.0, scale = 1.0, keep = 0.0;
        if (row->kind == HD_LIMIT && row->c > 0.0) {  /* open: speculative */
            bias = row->c / h;
        } else if (soft != NULL) {
            bias = soft[0] * row->c, scale = soft[1], keep = soft[2];
        }
        new = old - scale * mass * (velocity + bias) - keep * old;
        if (row->kind == HD_LIMIT)
            new = hd_max(new, 0.0);
    }
    *lam = new;
    hd_push(v, towards, new - old, n);
}

/* contact/soft_joints.py: SoftJointPass._sweep over rows with their directions on m->v, adding to
 * the impulses m->warm; `soft` the (bias rate, mass scale, impulse scale) of the sweep with
 * bias, NULL for the relaxing sweep. */
static void hd_sweep(hd_joint_model *m, const hd_joint_row *rows, const hd_joint_row *towards,
                     double h, const double *soft)
{
    double *lam = m->warm, *v = m->v;
    const long n = m->row_count;
    long i = 0;
    while (i < n) {
        const hd_joint_row *row = rows + i;
        if (row->pair) {
            hd_pin(row, lam + i, v, m->inverse_mass, soft);
            i += 2;
        } else {
            const int along = hd_distinct(row);  /* constants below: each case unrolled */
            if (along == 2)
                hd_row(row, towards + i, lam + i, v, h, soft, 2);
            else if (along == 1)
                hd_row(row, towards + i, lam + i, v, h, soft, 1);
            else
                hd_row(row, towards + i, lam + i, v, h, soft, 0);
            i += 1;
        }
    }
}

/* contact/joint_solve.py: directions with SoftJointPass.in_pins skipped: M^-1 J^T of the rows
 * outside pins (a pin's block takes its masses itself). */
static void hd_soft_directions(const hd_joint_model *m, const hd_joint_row *rows,
                               hd_joint_row *out)
{
    for (long i = 0; i < m->row_count; ++i) {
        if (rows[i].pair) {
            out[i].count = out[i + 1].count = 0;
            i += 1;
        } else {
            hd_joint_directions(m, rows + i, NULL, 1, out + i);
        }
    }
}

/* contact/soft_joints.py: SoftJointPass._warm_start, the impulses m->warm on m->v along the rows
 * at q0. */
static void hd_warm_start(hd_joint_model *m)
{
    for (long i = 0; i < m->row_count; ++i) {
        if (m->rows0[i].pair) {
            hd_push_pin(m->v, m->rows0 + i, m->warm[i], m->warm[i + 1], m->inverse_mass);
            i += 1;
        } else {
            hd_push(m->v, m->dir0 + i, m->warm[i], 0);
        }
    }
}

void hd_soft_joints_resolve(hd_joint_model *m, const double *q0, double *q1, double *v1,
                            double h)
{
    const long nb = m->body_count;
    /* The last sub-step's end, its rows built at the same length, is this one's start
     * (compared as Python compares floats). */
    int again = m->ended && h == m->last_h;
    for (long k = 0; k < nb; ++k)
        for (int c = 0; c < 3; ++c) {
            const double start = q0[3 * m->bodies[k] + c];
            again = again && start == m->q[3 * k + c];
            m->start[3 * k + c] = start;
        }
    if (again) {
        hd_joint_rows_again(m);
    } else {
        hd_joint_rows(m, m->start, h, m->rows0, 0);
        hd_soft_directions(m, m->rows0, m->dir0);
    }
    for (long k = 0; k < nb; ++k)
        for (int c = 0; c < 3; ++c) {
            m->q[3 * k + c] = q1[3 * m->bodies[k] + c];
            m->v[3 * k + c] = m->moved[3 * k + c] = v1[3 * m->bodies[k] + c];  /* moved: free */
        }
    hd_warm_start(m);  /* stage 1 */
    /* contact/soft_joints.py: softness, Box2D v3's b2MakeSoft */
    const double omega = 2.0 * HD_PI * m->hertz;
    const double a1 = 2.0 * m->damping_ratio + h * omega;
    const double a2 = h * omega * a1;
    const double a3 = 1.0 / (1.0 + a2);
    const double soft[3] = {omega / a1, a2 * a3, a3};
    hd_sweep(m, m->rows0, m->dir0, h, soft);
    for (long k = 0; k < 3 * nb; ++k)  /* stage 3 */
        m->q[k] += h * (m->v[k] - m->moved[k]);
    hd_joint_rows(m, m->q, h, m->rows, 0);
    hd_soft_directions(m, m->rows, m->dir);
    hd_sweep(m, m->rows, m->dir, h, NULL);
    m->last_h = h;
    hd_joint_count_turns(m);
    hd_joint_ended(m, q1, v1);
}
