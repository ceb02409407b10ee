/* The joint pass: hecker_dynamics/contact/joints.py with its rows (contact/joint_rows.py) and
 * their solve (contact/joint_solve.py), operation for operation (see joint.h).
 *
 * Each function names the Python function it repeats. Python's min and max keep their
 * first argument unless the second is strictly smaller or larger, and Python's float %
 * takes the sign of the divisor: the helpers below do the same, so that zeros' signs and
 * ties come out as in Python.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE  /* glibc's sincos (hd_turn_all) */
#endif
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "floats.h"
#include "joint.h"
#include "sparse.h"


/* CPython's float %: fmod, moved to the sign of the divisor. */
static double hd_py_mod(double x, double y)
{
    double r = fmod(x, y);
    if (r != 0.0) {
        if ((y < 0.0) != (r < 0.0))
            r += y;
    } else {
        r = copysign(0.0, y);
    }
    return r;
}

/* contact/joint_rows.py: wrap, an angle in [-pi, pi); fmod is exact and leaves what is already in
 * [0, 2 pi) unchanged, so that case skips it. */
static double hd_wrap(double angle)
{
    const double shifted = angle + HD_PI;
    if (shifted >= 0.0 && shifted < 2.0 * HD_PI)
        return shifted - HD_PI;
    return hd_py_mod(shifted, 2.0 * HD_PI) - HD_PI;
}

/* contact/joint_rows.py: Frame.place: the point (x, y), its arm (rx, ry) from the CM, the angle. */
typedef struct { double x, y, rx, ry, angle; } hd_anchor;

/* `trig`: cos and sin of each body's angle in q (the same values _Frame.place takes). */
static inline hd_anchor hd_place(long body, const double *local, const double *q,
                          const double *trig)
{
    hd_anchor p;
    if (body < 0) {
        p.x = local[0], p.y = local[1], p.rx = 0.0, p.ry = 0.0, p.angle = 0.0;
        return p;
    }
    const double x = q[3 * body], y = q[3 * body + 1], angle = q[3 * body + 2];
    const double c = trig[2 * body], s = trig[2 * body + 1];
    p.rx = c * local[0] - s * local[1];
    p.ry = s * local[0] + c * local[1];
    p.x = x + p.rx, p.y = y + p.ry, p.angle = angle;
    return p;
}

static void hd_add_entry(hd_joint_row *r, long body, double jx, double jy, double jw)
{
    r->body[r->count] = body;
    r->j[r->count][0] = jx, r->j[r->count][1] = jy, r->j[r->count][2] = jw;
    r->count += 1;
}

static hd_joint_row *hd_new_row(hd_joint_row *rows, long *n, int kind, double c)
{
    hd_joint_row *r = rows + (*n)++;
    r->kind = kind, r->count = 0, r->scaled = 0, r->pair = 0;
    r->c = c, r->speed = 0.0, r->bound = INFINITY, r->stiffness = 0.0, r->damping = 0.0;
    return r;
}

/* contact/joint_rows.py: fixed_entries (a direction fixed in the world) and line_entries (fixed
 * in body a). */
static void hd_fixed(hd_joint_row *r, const hd_joint *jt, hd_anchor pa, hd_anchor pb, double ux,
                     double uy)
{
    if (jt->b >= 0)
        hd_add_entry(r, jt->b, ux, uy, ux * -pb.ry + uy * pb.rx);
    if (jt->a >= 0)
        hd_add_entry(r, jt->a, -ux, -uy, -(ux * -pa.ry + uy * pa.rx));
}

static void hd_line(hd_joint_row *r, const hd_joint *jt, hd_anchor pa, hd_anchor pb, double ux,
                    double uy)
{
    if (jt->b >= 0)
        hd_add_entry(r, jt->b, ux, uy, ux * -pb.ry + uy * pb.rx);
    if (jt->a >= 0) {
        const double dx = pa.rx + pb.x - pa.x, dy = pa.ry + pb.y - pa.y;
        hd_add_entry(r, jt->a, -ux, -uy, -(ux * -dy + uy * dx));
    }
}

static void hd_angle_entries(hd_joint_row *r, long a, long b, double scale)
{
    hd_add_entry(r, b, 0.0, 0.0, scale);
    if (a >= 0)
        hd_add_entry(r, a, 0.0, 0.0, -scale);
}

static void hd_negate(hd_joint_row *r)
{
    for (int e = 0; e < r->count; ++e)
        for (int k = 0; k < 3; ++k)
            r->j[e][k] = -r->j[e][k];
}

/* contact/joints.py: JointPass._joint_angle. */
static double hd_joint_angle(const hd_joint *jt, hd_anchor pa, hd_anchor pb)
{
    return jt->angle + hd_wrap(pb.angle - pa.angle - jt->raw);
}

/* contact/joint_rows.py: point_rows. */
static void hd_point_rows(hd_joint_row *rows, long *n, const hd_joint *jt, hd_anchor pa,
                          hd_anchor pb, int kind, double stiffness, double damping)
{
    for (int axis = 0; axis < 2; ++axis) {
        const double ux = axis == 0 ? 1.0 : 0.0, uy = axis == 0 ? 0.0 : 1.0;
        hd_joint_row *r = hd_new_row(rows, n, kind, ux * (pb.x - pa.x) + uy * (pb.y - pa.y));
        hd_fixed(r, jt, pa, pb, ux, uy);
        r->stiffness = stiffness, r->damping = damping, r->scaled = 1;
        r->pair = axis == 0 && kind == HD_RIGID;
    }
}

/* One end of a plain pin (_Frame.place, the same operations as hd_place): the point (*x, *y)
 * and its arm (*rx, *ry) from the CM. */
static HD_HOT void hd_pin_end(long body, const double *local, const double *q,
                              const double *trig, double *x, double *y, double *rx, double *ry)
{
    if (body < 0) {
        *x = local[0], *y = local[1], *rx = 0.0, *ry = 0.0;
        return;
    }
    const double c = trig[2 * body], s = trig[2 * body + 1];
    *rx = c * local[0] - s * local[1];
    *ry = s * local[0] + c * local[1];
    *x = q[3 * body] + *rx, *y = q[3 * body + 1] + *ry;
}

/* The entries of a pin's row along (ux, uy) (contact/joint_rows.py: fixed_entries): on body
 * b, u and perp(r_b) . u; on body a their negatives. */
static HD_HOT void hd_pin_entries(hd_joint_row *r, const hd_joint *jt, double ux, double uy,
                                  double rax, double ray, double rbx, double rby)
{
    int count = 0;
    if (jt->b >= 0) {
        double *j = r->j[count];
        r->body[count++] = jt->b;
        j[0] = ux, j[1] = uy, j[2] = ux * -rby + uy * rbx;
    }
    if (jt->a >= 0) {
        double *j = r->j[count];
        r->body[count++] = jt->a;
        j[0] = -ux, j[1] = -uy, j[2] = -(ux * -ray + uy * rax);
    }
    r->count = count;
}

/* contact/joint_rows.py: point_rows of a rigid pin with no limit, motor or spring, written
 * out (the same operations as point_rows): its x row, then its y row. `values_only`: their
 * values alone (which is all an iterate that keeps the last matrix reads of them). */
static HD_HOT void hd_pin_rows(hd_joint_row *r, const hd_joint *jt, const double *q,
                               const double *trig, int values_only)
{
    double xa, ya, rax, ray, xb, yb, rbx, rby;
    hd_pin_end(jt->a, jt->point_a, q, trig, &xa, &ya, &rax, &ray);
    hd_pin_end(jt->b, jt->point_b, q, trig, &xb, &yb, &rbx, &rby);
    const double dx = xb - xa, dy = yb - ya;
    r[0].c = 1.0 * dx + 0.0 * dy;
    r[1].c = 0.0 * dx + 1.0 * dy;
    if (values_only)
        return;
    for (int axis = 0; axis < 2; ++axis) {
        r[axis].kind = HD_RIGID, r[axis].scaled = 1, r[axis].pair = axis == 0;
        r[axis].speed = 0.0, r[axis].bound = INFINITY, r[axis].stiffness = 0.0;
        r[axis].damping = 0.0;
    }
    hd_pin_entries(r, jt, 1.0, 0.0, rax, ray, rbx, rby);
    hd_pin_entries(r + 1, jt, 0.0, 1.0, rax, ray, rbx, rby);
}

/* contact/joint_rows.py: bounded_rows, the coordinate `value` with the Jacobian of `coordinate`. */
static void hd_bounded_rows(hd_joint_row *rows, long *n, const hd_joint *jt, double value,
                            const hd_joint_row *coordinate, double h)
{
    if (jt->has_lower) {
        hd_joint_row *r = hd_new_row(rows, n, HD_LIMIT, value - jt->lower);
        memcpy(r->body, coordinate->body, sizeof r->body);
        memcpy(r->j, coordinate->j, sizeof r->j);
        r->count = coordinate->count;
    }
    if (jt->has_upper) {
        hd_joint_row *r = hd_new_row(rows, n, HD_LIMIT, jt->upper - value);
        memcpy(r->body, coordinate->body, sizeof r->body);
        memcpy(r->j, coordinate->j, sizeof r->j);
        r->count = coordinate->count;
        hd_negate(r);
    }
    if (jt->has_motor) {
        hd_joint_row *r = hd_new_row(rows, n, HD_MOTOR, value);
        memcpy(r->body, coordinate->body, sizeof r->body);
        memcpy(r->j, coordinate->j, sizeof r->j);
        r->count = coordinate->count;
        r->speed = jt->motor_speed, r->bound = jt->max_effort * h;
    }
}

/* contact/joints.py: JointPass._axis. */
static void hd_axis_of(const hd_joint *jt, double angle_a, double *ux, double *uy)
{
    const double c = cos(angle_a), s = sin(angle_a);
    *ux = c * jt->axis[0] - s * jt->axis[1];
    *uy = s * jt->axis[0] + c * jt->axis[1];
}

/* cos and sin of every body's angle in q into m->trig (2 per body), computed again only
 * for the angles that changed (bit for bit) since the last time: m->angles keeps them. */
static void hd_turn_all(const hd_joint_model *m, const double *q)
{
    for (long b = 0; b < m->body_count; ++b) {
        const double angle = q[3 * b + 2];
        if (memcmp(&angle, m->angles + b, sizeof angle) == 0)
            continue;
        m->angles[b] = angle;
#ifdef __GLIBC__
        /* glibc's sincos runs its sin's and cos's code: the same bits as Python's math. */
        sincos(angle, m->trig + 2 * b + 1, m->trig + 2 * b);
#else
        m->trig[2 * b] = cos(angle);
        m->trig[2 * b + 1] = sin(angle);
#endif
    }
}

/* A revolute joint with no limit, motor or spring: its two point rows alone (hd_pin_rows). */
static int hd_plain_pin(const hd_joint *jt)
{
    return jt->kind == HD_REVOLUTE && !(jt->has_lower || jt->has_upper || jt->has_motor ||
                                        jt->has_spring);
}

/* contact/joints.py: JointPass.rows (joint.h). */
long hd_joint_rows(const hd_joint_model *m, const double *q, double h, hd_joint_row *rows,
                   int values_only)
{
    long n = 0;
    const double *trig = m->trig;
    hd_turn_all(m, q);
    if (m->plain_pins) {  /* a chain's or a tree's: the loop below, its pins' branch alone */
        for (long i = 0; i < m->joint_count; ++i)
            hd_pin_rows(rows + 2 * i, m->joints + i, q, trig, values_only);
        return 2 * m->joint_count;
    }
    for (long i = 0; i < m->joint_count; ++i) {
        const hd_joint *jt = m->joints + i;
        if (jt->kind == HD_GEAR) {
            hd_joint_row *r = hd_new_row(rows, &n, HD_RIGID, 0.0);
            const long pair[2] = {jt->gear_a, jt->gear_b};
            const double scales[2] = {1.0, jt->ratio};
            double value = 0.0;
            for (int k = 0; k < 2; ++k) {
                const hd_joint *g = m->joints + pair[k];
                const hd_anchor pa = hd_place(g->a, g->point_a, q, trig),
                            pb = hd_place(g->b, g->point_b, q, trig);
                value += scales[k] * hd_joint_angle(g, pa, pb);
                hd_angle_entries(r, g->a, g->b, scales[k]);
            }
            r->c = value;
            continue;
        }
        if (hd_plain_pin(jt)) {
            hd_pin_rows(rows + n, jt, q, trig, values_only);  /* its angle is not wanted */
            n += 2;
            continue;
        }
        const hd_anchor pa = hd_place(jt->a, jt->point_a, q, trig),
                    pb = hd_place(jt->b, jt->point_b, q, trig);
        if (jt->kind == HD_REVOLUTE) {
            hd_point_rows(rows, &n, jt, pa, pb, HD_RIGID, 0.0, 0.0);
            const double angle = hd_joint_angle(jt, pa, pb);
            hd_joint_row coordinate = {0};
            hd_angle_entries(&coordinate, jt->a, jt->b, 1.0);
            hd_bounded_rows(rows, &n, jt, angle, &coordinate, h);
            if (jt->has_spring) {
                hd_joint_row *r = hd_new_row(rows, &n, HD_SOFT, angle - jt->rest);
                hd_angle_entries(r, jt->a, jt->b, 1.0);
                r->stiffness = jt->stiffness, r->damping = jt->damping;
            }
        } else if (jt->kind == HD_WELD) {
            const int kind = jt->has_spring ? HD_SOFT : HD_RIGID;
            hd_point_rows(rows, &n, jt, pa, pb, kind, jt->stiffness, jt->damping);
            hd_joint_row *r = hd_new_row(rows, &n, kind,
                                         hd_wrap(pb.angle - pa.angle - jt->reference_angle));
            hd_angle_entries(r, jt->a, jt->b, 1.0);
            r->stiffness = jt->stiffness, r->damping = jt->damping, r->scaled = 1;
        } else if (jt->kind == HD_PRISMATIC) {
            double ux, uy;
            hd_axis_of(jt, pa.angle, &ux, &uy);
            hd_joint_row *r = hd_new_row(rows, &n, HD_RIGID,
                                         -uy * (pb.x - pa.x) + ux * (pb.y - pa.y));
            hd_line(r, jt, pa, pb, -uy, ux);
            r = hd_new_row(rows, &n, HD_RIGID, hd_wrap(pb.angle - pa.angle - jt->reference_angle));
            hd_angle_entries(r, jt->a, jt->b, 1.0);
            /* JointPass._coordinate: the translation along the axis. */
            hd_axis_of(jt, pa.angle, &ux, &uy);
            const double along = ux * (pb.x - pa.x) + uy * (pb.y - pa.y) - jt->reference_along;
            hd_joint_row coordinate = {0};
            hd_line(&coordinate, jt, pa, pb, ux, uy);
            hd_bounded_rows(rows, &n, jt, along, &coordinate, h);
        } else {  /* a rod or a rope */
            const double dx = pb.x - pa.x, dy = pb.y - pa.y;
            const double length = sqrt(dx * dx + dy * dy);
            const double ux = length > 0.0 ? dx / length : 1.0,
                         uy = length > 0.0 ? dy / length : 0.0;
            if (jt->kind == HD_ROPE) {
                hd_joint_row *r = hd_new_row(rows, &n, HD_LIMIT, jt->length - length);
                hd_fixed(r, jt, pa, pb, ux, uy);
                hd_negate(r);
            } else {
                hd_joint_row *r = hd_new_row(rows, &n, HD_RIGID, length - jt->length);
                hd_fixed(r, jt, pa, pb, ux, uy);
            }
        }
    }
    return n;
}

/* contact/joint_solve.py: directions: per row, M^-1 J^T (rows[index[k]] for k < n; index
 * NULL: rows k).
 */
void hd_joint_directions(const hd_joint_model *m, const hd_joint_row *rows, const long *index,
                         long n, hd_joint_row *out)
{
    for (long k = 0; k < n; ++k) {
        const hd_joint_row *row = rows + (index == NULL ? k : index[k]);
        const int count = row->count;
        hd_joint_row *d = out + k;
        d->count = count;  /* _apply and _dot read no more of a direction */
        for (int e = 0; e < count; ++e) {
            const long body = row->body[e];
            const double *im = m->inverse_mass + 3 * body;
            d->body[e] = body;
            d->j[e][0] = im[0] * row->j[e][0];
            d->j[e][1] = im[1] * row->j[e][1];
            d->j[e][2] = im[2] * row->j[e][2];
        }
    }
}

/* Entry e of the direction d times `amount`, added to its body's three coordinates in x. */
static HD_HOT void hd_add_along(double *x, const hd_joint_row *d, int e, double amount)
{
    double *target = x + 3 * d->body[e];
    const double *j = d->j[e];
    target[0] += j[0] * amount;
    target[1] += j[1] * amount;
    target[2] += j[2] * amount;
}

/* contact/joint_solve.py: apply: x += M^-1 J^T impulse, row by row, skipping zero impulses;
 * each row's entries in their order, a pin's two written out (the loop over them cost a
 * third of the adds' instructions). */
static void hd_apply(double *x, const hd_joint_row *direction, long n, const double *impulse)
{
    for (long i = 0; i < n; ++i) {
        const double amount = impulse[i];
        if (amount == 0.0)
            continue;
        const hd_joint_row *d = direction + i;
        const int count = d->count;
        if (count == 2) {
            hd_add_along(x, d, 0, amount);
            hd_add_along(x, d, 1, amount);
            continue;
        }
        for (int e = 0; e < count; ++e)
            hd_add_along(x, d, e, amount);
    }
}

/* contact/joint_solve.py: dot, over the pairs `first` .. `end` of `meets`, their entries found
 * from the first row `rows` and the first direction `directions`. */
static HD_HOT double hd_dot_meeting(const hd_meets *meets, const char *rows,
                                    const char *directions, long first, long end)
{
    double s = 0.0;
    for (long k = first; k < end; ++k) {
        const double *a = (const double *)(rows + meets->row_at[k]);
        const double *b = (const double *)(directions + meets->direction_at[k]);
        s += a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    }
    return s;
}

/* The pairs of entries of `row` and `direction` on a common body into `out` (NULL: count
 * only); returns how many. */
static long hd_meeting(const hd_joint_row *row, const hd_joint_row *direction, unsigned char *out)
{
    long count = 0;
    for (int e = 0; e < row->count; ++e)
        for (int f = 0; f < direction->count; ++f)
            if (row->body[e] == direction->body[f]) {
                if (out != NULL)
                    out[count] = (unsigned char)(e << 2 | f);
                count += 1;
            }
    return count;
}

/* Where the entries of the pairs `first` .. `end` of m are: row `row`'s and direction
 * `direction`'s (hd_meets.row_at, direction_at). */
static void hd_place_pairs(hd_meets *m, long first, long end, long row, long direction)
{
    for (long k = first; k < end; ++k) {
        m->row_at[k] = row * (long)sizeof(hd_joint_row) + (long)offsetof(hd_joint_row, j)
                       + (m->pair[k] >> 2) * 3 * (long)sizeof(double);
        m->direction_at[k] = direction * (long)sizeof(hd_joint_row)
                             + (long)offsetof(hd_joint_row, j)
                             + (m->pair[k] & 3) * 3 * (long)sizeof(double);
    }
}

/* The meets of pattern p's row pairs, for the rows rows[index[k]] (index NULL: rows k);
 * 0, or -1 out of memory. */
static int hd_make_meets(const hd_pattern *p, const hd_joint_row *rows, const long *index,
                         hd_meets *m)
{
    const long n = p->n, slots = p->start[n];
    m->diag = malloc(((size_t)n + 1) * sizeof(long));
    m->lower = malloc(((size_t)slots + 1) * sizeof(long));
    m->upper = malloc(((size_t)slots + 1) * sizeof(long));
    if (m->diag == NULL || m->lower == NULL || m->upper == NULL)
        return -1;
    for (int pass = 0; pass < 2; ++pass) {
        long count = 0;
        for (long i = 0; i < n; ++i) {
            const hd_joint_row *row = rows + (index == NULL ? i : index[i]);
            unsigned char *out = pass == 1 ? m->pair : NULL;
            m->diag[i] = count;
            count += hd_meeting(row, row, out == NULL ? NULL : out + count);
            for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
                const long j = p->columns[slot];
                const hd_joint_row *other = rows + (index == NULL ? j : index[j]);
                m->lower[slot] = count;
                count += hd_meeting(row, other, out == NULL ? NULL : out + count);
                m->upper[slot] = count;
                count += hd_meeting(other, row, out == NULL ? NULL : out + count);
            }
        }
        if (pass == 0 && ((m->pair = malloc((size_t)count + 1)) == NULL ||
                          (m->row_at = malloc(((size_t)count + 1) * sizeof(long))) == NULL ||
                          (m->direction_at = malloc(((size_t)count + 1) * sizeof(long))) == NULL))
            return -1;
        m->diag[n] = count;  /* the ends of the last lists */
        if (slots > 0)
            m->lower[slots] = m->upper[slots] = count;
    }
    /* Each pair's entries: the row's and the direction's of the diagonal, or of the lower's
     * (row i, direction j) or the upper's (row j, direction i) of each slot. */
    for (long i = 0; i < n; ++i) {
        const long row_i = index == NULL ? i : index[i];
        long end = p->start[i] < p->start[i + 1] ? m->lower[p->start[i]] : m->diag[i + 1];
        hd_place_pairs(m, m->diag[i], end, row_i, i);
        for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
            const long j = p->columns[slot], row_j = index == NULL ? j : index[j];
            hd_place_pairs(m, m->lower[slot], m->upper[slot], row_i, j);
            end = slot + 1 < p->start[i + 1] ? m->lower[slot + 1] : m->diag[i + 1];
            hd_place_pairs(m, m->upper[slot], end, row_j, i);
        }
    }
    return 0;
}

static void hd_free_meets(hd_meets *m)
{
    free(m->diag);
    free(m->lower);
    free(m->upper);
    free(m->pair);
    free(m->row_at);
    free(m->direction_at);
}

/* contact/joint_solve.py: matrix, on the rows `rows` and the directions `direction` (one per
 * row of the pattern), whose entries meet, and where, as `meets` says (the rows it was made
 * for: all, or the rigid ones of `rows`); `upper` NULL: the symmetric K, its lower triangle
 * only. */
static void hd_matrix(const hd_pattern *p, const hd_meets *meets, const hd_joint_row *rows,
                      const hd_joint_row *direction, const int *active, double *diagonal,
                      double *lower, double *upper)
{
    const char *row0 = (const char *)rows, *direction0 = (const char *)direction;
    for (long i = 0; i < p->n; ++i) {
        const long first = p->start[i], end = p->start[i + 1];
        if (active != NULL && !active[i]) {
            diagonal[i] = 0.0;
            for (long slot = first; slot < end; ++slot) {
                lower[slot] = 0.0;
                if (upper != NULL)
                    upper[slot] = 0.0;
            }
            continue;
        }
        /* Row i's lists: its diagonal's, then per slot the lower's and the upper's. */
        const long diag_end = first < end ? meets->lower[first] : meets->diag[i + 1];
        diagonal[i] = hd_dot_meeting(meets, row0, direction0, meets->diag[i], diag_end);
        for (long slot = first; slot < end; ++slot) {
            if (active != NULL && !active[p->columns[slot]]) {
                lower[slot] = 0.0;
                if (upper != NULL)
                    upper[slot] = 0.0;
                continue;
            }
            lower[slot] = hd_dot_meeting(meets, row0, direction0, meets->lower[slot],
                                         meets->upper[slot]);
            if (upper != NULL) {
                const long next = slot + 1 < end ? meets->lower[slot + 1] : meets->diag[i + 1];
                upper[slot] = hd_dot_meeting(meets, row0, direction0, meets->upper[slot], next);
            }
        }
    }
}

/* contact/joint_solve.py: row_sum. */
static double hd_row_sum(const hd_pattern *p, const double *diagonal, const double *lower, long i,
                         const double *x, const int *skip)
{
    double s = 0.0;
    for (long slot = p->start[i]; slot < p->start[i + 1]; ++slot) {
        const long j = p->columns[slot];
        if (skip == NULL || !skip[j])
            s += lower[slot] * x[j];
    }
    if (skip == NULL || !skip[i])
        s += diagonal[i] * x[i];
    for (long k = p->above_start[i]; k < p->above_start[i + 1]; ++k) {
        const long j = p->above_row[k];
        if (skip == NULL || !skip[j])
            s += lower[p->above_slot[k]] * x[j];
    }
    return s;
}

/* contact/joint_solve.py: solve, the impulses into m->x (K in m->diagonal and m->lower). */
static void hd_solve(hd_joint_model *m)
{
    const hd_pattern *p = &m->pattern;
    const long n = m->row_count;
    const double *diagonal = m->diagonal, *lower = m->lower, *b = m->b;
    const double *low_bound = m->low_bound, *high_bound = m->high_bound;
    double *x = m->x;
    int all_free = 1, any_free = 0;
    for (long i = 0; i < n; ++i) {
        m->free[i] = low_bound[i] == -INFINITY && high_bound[i] == INFINITY;
        all_free = all_free && m->free[i];
        any_free = any_free || m->free[i];
    }
    if (all_free) {
        memcpy(x, b, (size_t)n * sizeof(double));
        hd_factor(p, diagonal, lower, NULL, m->low, m->diag, m->out);
        hd_substitute(p, m->low, m->diag, m->out, x);
        return;
    }
    long nb = 0;
    int *side = m->side, *holds = m->active;  /* -1 at the lower bound, 1 at the upper */
    for (long i = 0; i < n; ++i) {
        const double start = m->warm[i], low = low_bound[i], high = high_bound[i];
        side[i] = m->free[i] ? 0 : start <= low || low == high ? -1 : start >= high ? 1 : 0;
        if (!m->free[i])
            m->bounded[nb++] = i;
    }
    for (long set = 0; set < HD_ACTIVE_SETS; ++set) {
        for (long i = 0; i < n; ++i) {
            holds[i] = side[i] == 0;
            x[i] = side[i] == 0 ? 0.0 : side[i] < 0 ? low_bound[i] : high_bound[i];
        }
        for (long i = 0; i < n; ++i)
            m->rhs[i] = holds[i] ? b[i] - hd_row_sum(p, diagonal, lower, i, x, holds) : 0.0;
        hd_factor(p, diagonal, lower, holds, m->low, m->diag, m->out);
        hd_substitute(p, m->low, m->diag, m->out, m->rhs);
        for (long i = 0; i < n; ++i)
            if (holds[i])
                x[i] = m->rhs[i];
        int settled = 1;
        for (long k = 0; k < nb; ++k) {
            const long i = m->bounded[k];
            if (side[i] == 0) {
                side[i] = x[i] < low_bound[i] ? -1 : x[i] > high_bound[i] ? 1 : 0;
            } else if (low_bound[i] < high_bound[i]) {
                const double wanted = b[i] - hd_row_sum(p, diagonal, lower, i, x, NULL);
                side[i] = wanted * side[i] < 0.0 ? 0 : side[i];
            }
            settled = settled && (side[i] == 0) == holds[i];
        }
        if (settled)
            return;
    }
    if (any_free)
        hd_factor(p, diagonal, lower, m->free, m->low, m->diag, m->out);
    for (long iteration = 0; iteration < HD_JOINT_MAX_ITERATIONS; ++iteration) {
        if (any_free) {
            for (long i = 0; i < n; ++i)
                m->rhs[i] = m->free[i] ? b[i] - hd_row_sum(p, diagonal, lower, i, x, m->free)
                                       : 0.0;
            hd_substitute(p, m->low, m->diag, m->out, m->rhs);
            for (long i = 0; i < n; ++i)
                if (m->free[i])
                    x[i] = m->rhs[i];
        }
        double largest = 0.0;
        for (long k = 0; k < nb; ++k) {
            const long i = m->bounded[k];
            const double s = hd_row_sum(p, diagonal, lower, i, x, NULL);
            const double updated = hd_min(hd_max(x[i] + (b[i] - s) / diagonal[i], low_bound[i]),
                                          high_bound[i]);
            const double change = fabs(updated - x[i]);
            largest = change > largest ? change : largest;
            x[i] = updated;
        }
        double biggest = fabs(x[0]);
        for (long i = 1; i < n; ++i)
            if (fabs(x[i]) > biggest)
                biggest = fabs(x[i]);
        if (largest <= HD_JOINT_CONVERGED * (1.0 + biggest))
            break;
    }
}

/* contact/joint_solve.py: refine, K x = b (m->diagonal, m->lower, m->b) into m->x on the Newton
 * matrix's L U (m->low, m->upper, m->diag, m->out over the rigid rows, which are all the rows);
 * 0 where it does not get every row's residual, the dropped rows' too, to `residual`. */
static int hd_refine(hd_joint_model *m, double residual)
{
    const long n = m->row_count;
    const hd_pattern *p = &m->pattern, *q = &m->rigid_pattern;
    double *x = m->x, *r = m->rhs;
    memcpy(x, m->b, (size_t)n * sizeof(double));
    hd_lu_solve(q, m->low, m->upper, m->diag, m->out, x);
    double previous = INFINITY;
    for (long correction = 0; correction <= HD_REFINEMENTS; ++correction) {
        double largest = 0.0;
        for (long i = 0; i < n; ++i) {
            r[i] = m->b[i] - hd_row_sum(p, m->diagonal, m->lower, i, x, NULL);
            largest = hd_max(largest, fabs(r[i]));
        }
        if (largest <= residual)
            return 1;
        if (correction == HD_REFINEMENTS || !(largest <= 0.5 * previous))
            return 0;
        previous = largest;
        for (long i = 0; i < n; ++i)
            if (m->out[i])
                r[i] = 0.0;
        hd_lu_solve(q, m->low, m->upper, m->diag, m->out, r);
        for (long i = 0; i < n; ++i)
            x[i] = x[i] + r[i];
    }
    return 0;
}

static double hd_largest_abs(const double *x, long n)
{
    double largest = fabs(x[0]);
    for (long i = 1; i < n; ++i)
        if (fabs(x[i]) > largest)
            largest = fabs(x[i]);
    return largest;
}

/* contact/joints.py: JointPass._newton, from the multipliers in m->nu, on m->q (which was
 * m->moved), the directions and targets of the rigid rows in m->dir0 and m->target; the first
 * iterate's largest error in m->first_error. */
static int hd_newton(hd_joint_model *m, double h)
{
    const long nr = m->rigid_count;
    const hd_pattern *p = &m->rigid_pattern;
    const long n3 = 3 * m->body_count;
    hd_apply(m->q, m->dir0, nr, m->nu);
    /* The rows' values round at about eps |q|: no error can be asked below that. */
    const double tolerance = hd_max(m->tolerance,
                                    HD_JOINT_ROUNDING * (1.0 + hd_largest_abs(m->q, n3)));
    /* The last two iterates' largest errors (`before` 1: a fresh step from the first about
     * squares its error, in metres and radians). */
    double previous = INFINITY, before = 1.0;
    int factored = 0, fresh = 0;  /* the last matrix's L U is kept; it was that iterate's */
    for (long iteration = 0; iteration < HD_NEWTON_ITERATIONS; ++iteration) {
        /* An iterate that may take the last matrix needs its rows' values alone, unless it is
         * likely the last (its error, cut as the last step cut it, within the tolerance): then
         * the whole rows the pass goes on with, at once (the same values). */
        const int whole = !factored || previous * (previous / before) <= tolerance;
        hd_joint_rows(m, m->q, h, m->rows, !whole);
        /* The errors, negated as the step's right-hand side (|-e| = |e|), and the largest (as
         * hd_largest_abs finds it), in one sweep. */
        double largest = 0.0;
        for (long k = 0; k < nr; ++k) {
            const double error = m->rows[m->rigid[k]].c - m->target[k];
            m->step[k] = -error;
            if (k == 0 || fabs(error) > largest)
                largest = fabs(error);
        }
        if (iteration == 0)
            m->first_error = largest;
        if (largest <= tolerance) {
            double turned = 0.0;
            for (long k = 2; k < n3; k += 3)
                turned = hd_max(turned, fabs(m->q[k] - m->moved[k]));
            if (turned > m->max_turn)
                return HD_JOINTS_UNSOLVED;
            memcpy(m->newton, m->nu, (size_t)nr * sizeof(double));
            m->newton_valid = 1;
            m->near = factored;
            if (!whole)
                hd_joint_rows(m, m->q, h, m->rows, 0);
            return HD_JOINTS_OK;
        }
        if (fresh && !(largest <= 0.5 * previous))
            return HD_JOINTS_UNSOLVED;
        fresh = !factored || !(largest <= HD_CHORD * previous);
        if (fresh) {
            if (!whole)
                hd_joint_rows(m, m->q, h, m->rows, 0);
            hd_matrix(p, &m->rigid_meets, m->rows, m->dir0, NULL, m->diagonal, m->lower, m->upper);
            hd_lu(p, m->diagonal, m->lower, m->upper, m->low, m->diag, m->out);
            factored = 1;
        }
        before = iteration == 0 ? before : previous;
        previous = largest;
        hd_lu_solve(p, m->low, m->upper, m->diag, m->out, m->step);
        for (long k = 0; k < nr; ++k)
            m->nu[k] = m->nu[k] + m->step[k];
        hd_apply(m->q, m->dir0, nr, m->step);
    }
    return HD_JOINTS_UNSOLVED;
}

/* contact/joints.py: JointPass._hold, on m->q; the rows at the new q in m->rows. `again`: m->dir0
 * holds the directions of the rows at q0 already. */
static int hd_hold(hd_joint_model *m, double h, int again)
{
    const long nr = m->rigid_count;
    m->near = 0;
    if (nr == 0) {
        hd_joint_rows(m, m->q, h, m->rows, 0);
        return HD_JOINTS_OK;
    }
    if (!again)
        hd_joint_directions(m, m->rows0, m->rigid, nr, m->dir0);
    for (long k = 0; k < nr; ++k)
        m->target[k] = m->rows0[m->rigid[k]].c;
    if (m->newton_valid) {
        double scale = h / m->last_h;
        scale = scale * scale;
        for (long k = 0; k < nr; ++k)
            m->nu[k] = m->newton[k] * scale;
        if (hd_newton(m, h) == HD_JOINTS_OK)
            return HD_JOINTS_OK;
        memcpy(m->q, m->moved, (size_t)(3 * m->body_count) * sizeof(double));
        hd_joint_rows(m, m->q, h, m->rows, 1);
        for (long k = 0; k < nr; ++k)
            m->step[k] = m->rows[m->rigid[k]].c - m->target[k];
        if (!(hd_largest_abs(m->step, nr) < m->first_error))
            return HD_JOINTS_UNSOLVED;
    }
    for (long k = 0; k < nr; ++k)
        m->nu[k] = 0.0;
    return hd_newton(m, h);
}

/* contact/joints.py: JointPass._correct, on m->q and m->rows. */
static void hd_correct(hd_joint_model *m, double h)
{
    const long n = m->row_count;
    const hd_pattern *p = &m->pattern;
    for (long iteration = 0; iteration < HD_DRIFT_ITERATIONS; ++iteration) {
        int off = 0;
        for (long i = 0; i < n && !off; ++i) {
            const hd_joint_row *r = m->rows + i;
            off = (r->kind == HD_RIGID && fabs(r->c) > m->tolerance) ||
                  (r->kind == HD_LIMIT && r->c < -m->tolerance);
        }
        if (!off)
            break;
        for (long i = 0; i < n; ++i) {
            const hd_joint_row *r = m->rows + i;
            m->active[i] = r->kind == HD_RIGID || (r->kind == HD_LIMIT && r->c < 0.0);
            m->rhs[i] = m->active[i] ? -r->c : 0.0;
        }
        m->near = 0;  /* the positions move off the Newton matrix's, whose L U goes */
        hd_joint_directions(m, m->rows, NULL, n, m->dir);
        hd_matrix(p, &m->meets, m->rows, m->dir, m->active, m->diagonal, m->lower, NULL);
        hd_factor(p, m->diagonal, m->lower, m->active, m->low, m->diag, m->out);
        hd_substitute(p, m->low, m->diag, m->out, m->rhs);
        hd_apply(m->q, m->dir, n, m->rhs);
        hd_joint_rows(m, m->q, h, m->rows, 0);
    }
}

/* contact/joints.py: JointPass._velocities, on m->v at the rows m->rows. */
static void hd_velocities(hd_joint_model *m, double h)
{
    const long n = m->row_count;
    hd_joint_directions(m, m->rows, NULL, n, m->dir);
    hd_matrix(&m->pattern, &m->meets, m->rows, m->dir, NULL, m->diagonal, m->lower, NULL);
    for (long i = 0; i < n; ++i) {
        const hd_joint_row *row = m->rows + i;
        m->b[i] = -hd_joint_rate(row, m->v);
        m->low_bound[i] = -INFINITY, m->high_bound[i] = INFINITY;
        if (row->kind == HD_LIMIT) {
            m->b[i] -= (0.0 > row->c ? 0.0 : row->c) / h;
            m->low_bound[i] = 0.0;
        } else if (row->kind == HD_MOTOR) {
            m->b[i] += row->speed;
            m->low_bound[i] = -row->bound, m->high_bound[i] = row->bound;
        } else if (row->kind == HD_SOFT) {
            double *diagonal = m->diagonal + i;
            const double scale = row->scaled ? 1.0 / *diagonal : 1.0;
            const double stiffness = row->stiffness * scale, damping = row->damping * scale;
            const double compliance = stiffness * h + damping;
            if (compliance == 0.0) {
                m->low_bound[i] = m->high_bound[i] = 0.0;
                continue;
            }
            *diagonal += 1.0 / (h * compliance);
            m->b[i] -= stiffness * row->c / compliance;
        }
    }
    int refined = 0;
    if (m->share && m->near) {  /* rigid rows alone: no bounds */
        double largest = 0.0;
        for (long i = 0; i < n; ++i)
            largest = hd_max(largest, fabs(m->b[i]));
        refined = hd_refine(m, hd_max(m->tolerance / h, HD_JOINT_ROUNDING * (1.0 + largest)));
    }
    if (!refined)
        hd_solve(m);
    hd_apply(m->v, m->dir, n, m->x);
    memcpy(m->warm, m->x, (size_t)n * sizeof(double));
    m->last_h = h;
}

void hd_joints_remember(hd_joint_model *m)
{
    if (m->needed > m->remembered) {
        m->remembered = m->needed, m->settled_steps = 0;
    } else if (m->remembered > 1) {
        m->settled_steps += 1;
        if (m->settled_steps == HD_SETTLED_STEPS)
            m->remembered = m->remembered / 2, m->settled_steps = 0;
    }
    m->needed = 1;
}

long hd_joints_parts(const hd_joint_model *m, const double *q0, const double *q1)
{
    double turn = 0.0;
    for (long k = 0; k < m->turning_count; ++k) {
        const long b = m->turning[k];
        turn = hd_max(turn, fabs(q1[3 * b + 2] - q0[3 * b + 2]));
    }
    for (long i = 0; i < m->joint_count; ++i) {  /* the rods and ropes */
        const hd_joint *jt = m->joints + i;
        if (jt->kind != HD_ROD && jt->kind != HD_ROPE)
            continue;
        double ends[2][2][2];  /* [start or end][a or b][x or y] */
        const double *poses[2] = {q0, q1};
        for (int t = 0; t < 2; ++t) {
            const long bodies[2] = {jt->a, jt->b};
            const double *points[2] = {jt->point_a, jt->point_b};
            for (int e = 0; e < 2; ++e) {  /* _Frame.place, on the model's indices */
                if (bodies[e] < 0) {
                    ends[t][e][0] = points[e][0], ends[t][e][1] = points[e][1];
                    continue;
                }
                const double *pose = poses[t] + 3 * m->bodies[bodies[e]];
                const double c = cos(pose[2]), s = sin(pose[2]);
                ends[t][e][0] = pose[0] + (c * points[e][0] - s * points[e][1]);
                ends[t][e][1] = pose[1] + (s * points[e][0] + c * points[e][1]);
            }
        }
        const double dx = ends[0][1][0] - ends[0][0][0], dy = ends[0][1][1] - ends[0][0][1];
        const double ex = ends[1][1][0] - ends[1][0][0], ey = ends[1][1][1] - ends[1][0][1];
        turn = hd_max(turn, atan2(fabs(dx * ey - dy * ex), dx * ex + dy * ey));
    }
    if (!(turn > m->max_turn))  /* within, or not finite: the divergence check reports it */
        return 1;
    const double parts = turn / m->max_turn;
    if (parts >= (double)HD_MOST_SUBSTEPS)
        return HD_MOST_SUBSTEPS;
    return ceil(parts) < 2.0 ? 2 : (long)ceil(parts);
}

void hd_joint_count_turns(hd_joint_model *m)
{
    for (long i = 0; i < m->joint_count; ++i) {
        hd_joint *jt = m->joints + i;
        if (jt->kind == HD_GEAR)
            continue;
        const hd_anchor pa = hd_place(jt->a, jt->point_a, m->q, m->trig),
                    pb = hd_place(jt->b, jt->point_b, m->q, m->trig);
        jt->angle = hd_joint_angle(jt, pa, pb);
        jt->raw = pb.angle - pa.angle;
    }
}

void hd_joint_rows_again(hd_joint_model *m)
{
    hd_joint_row *swap = m->rows0;
    m->rows0 = m->rows, m->rows = swap;
    swap = m->dir0, m->dir0 = m->dir, m->dir = swap;
}

void hd_joint_ended(hd_joint_model *m, double *q1, double *v1)
{
    for (long k = 0; k < m->body_count; ++k)
        for (int c = 0; c < 3; ++c) {
            q1[3 * m->bodies[k] + c] = m->q[3 * k + c];
            v1[3 * m->bodies[k] + c] = m->v[3 * k + c];
        }
    m->ended = 1;
}

/* contact/joints.py: JointPass.ringing, the bodies at the pose of `rows`. */
static double hd_ringing(const hd_joint_model *m, const hd_joint_row *rows, double h)
{
    double *stiffness = m->stiffness;
    for (long b = 0; b < m->body_count; ++b)
        stiffness[b] = 0.0;
    for (long k = 0; k < m->pin_count; ++k) {
        const long i = m->pins[k];
        const double x = m->warm[i] - m->extra[i], y = m->warm[i + 1] - m->extra[i + 1];
        const hd_joint_row *along_x = rows + i, *along_y = rows + i + 1;
        for (int e = 0; e < along_x->count && e < along_y->count; ++e)
            stiffness[along_x->body[e]] += x * along_y->j[e][2] - y * along_x->j[e][2];
    }
    if (h > 0.0) {  /* JointPass.ringing's bound: the largest |k| / I */
        double most = 0.0;
        for (long b = 0; b < m->body_count; ++b)
            most = hd_max(most, fabs(stiffness[b]) * m->free_turn[b]);
        const double bound = 2.0 * HD_RATING_BOUND * most / m->last_h;
        if (h * h * bound <= HD_MAX_RING * HD_MAX_RING)
            return bound;
    }
    const double *inverse = m->inverse_mass;
    double most = 0.0;
    for (long b = 0; b < m->body_count; ++b) {
        if (m->free_turn[b] == 0.0 || inverse[3 * b] == 0.0)
            continue;
        const struct hd_pin_end *pins = m->pinned + m->pinned_start[b];
        const long count = m->pinned_start[b + 1] - m->pinned_start[b];
        for (long pivot = -1; pivot < count; ++pivot) {  /* about its CM, then each pin */
            const double px = pivot < 0 ? 0.0 : pins[pivot].x;
            const double py = pivot < 0 ? 0.0 : pins[pivot].y;
            double turn = stiffness[b];
            double inertia = 1.0 / m->free_turn[b] + (px * px + py * py) / inverse[3 * b];
            int held = 0;
            for (long j = 0; j < count; ++j) {
                if (j == pivot)
                    continue;
                const long other = pins[j].other;
                /* no turn about here */
                held = other < 0 || inverse[3 * other] == 0.0 || m->free_turn[other] == 0.0;
                if (held)
                    break;
                const double dx = pins[j].x - px, dy = pins[j].y - py;
                const double moved = dx * dx + dy * dy;
                if (pins[j].reach > 0.0) {  /* it turns along */
                    const double share = moved / (pins[j].reach * pins[j].reach);
                    turn += stiffness[other] * share;
                    inertia += share / m->free_turn[other];
                } else {  /* it moves along */
                    inertia += moved / inverse[3 * other];
                }
            }
            if (!held)
                most = hd_max(most, turn / inertia);
        }
    }
    return 2.0 * most / m->last_h;
}

int hd_joints_resolve(hd_joint_model *m, const double *q0, double *q1, double *v1, double h)
{
    const long nb = m->body_count;
    /* Where the last pass ended is where this step starts (no contact moved a body, no
     * angle was wrapped), its rows all rigid and the step as long: its final rows and their
     * directions are this pass's rows at q0 and their directions, bit for bit. */
    int again = m->ended && m->rigid_count == m->row_count && h == m->last_h;
    for (long k = 0; k < nb; ++k)
        for (int c = 0; c < 3; ++c) {
            const double start = q0[3 * m->bodies[k] + c];
            again = again && memcmp(&start, m->q + 3 * k + c, sizeof start) == 0;
            m->start[3 * k + c] = start;
        }
    for (long k = 0; k < nb; ++k)
        for (int c = 0; c < 3; ++c) {
            m->q[3 * k + c] = m->moved[3 * k + c] = q1[3 * m->bodies[k] + c];
            m->v[3 * k + c] = v1[3 * m->bodies[k] + c];
        }
    m->ended = 0;
    if (again)
        hd_joint_rows_again(m);
    else
        hd_joint_rows(m, m->start, h, m->rows0, 0);
    if (h * h * hd_ringing(m, m->rows0, h) > HD_MAX_RING * HD_MAX_RING)
        return HD_JOINTS_UNSOLVED;
    const int status = hd_hold(m, h, again);
    if (status != HD_JOINTS_OK)
        return status;
    for (long k = 0; k < 3 * nb; ++k)
        m->v[k] += (m->q[k] - m->moved[k]) / h;
    hd_correct(m, h);
    memcpy(m->settled, m->v, (size_t)(3 * nb) * sizeof(double));
    hd_velocities(m, h);
    hd_joint_count_turns(m);
    hd_joint_ended(m, q1, v1);
    return HD_JOINTS_OK;
}

/* contact/joints.py: JointPass.pinned, in m->pinned_start and m->pinned: the pins (the
 * rigid point rows) of the joints in their order, each on body a, then on body b. */
static int hd_pin_ends(hd_joint_model *m)
{
    const long nb = m->body_count;
    m->pinned_start = calloc((size_t)nb + 2, sizeof(long));
    m->pinned = malloc((2 * (size_t)m->joint_count + 1) * sizeof(struct hd_pin_end));
    if (m->pinned_start == NULL || m->pinned == NULL)
        return HD_JOINTS_OUT_OF_MEMORY;
    for (int pass = 0; pass < 2; ++pass) {
        long *next = m->pinned_start + (pass == 0 ? 2 : 1);
        for (long i = 0; i < m->joint_count; ++i) {
            const hd_joint *jt = m->joints + i;
            if (!(jt->kind == HD_REVOLUTE || (jt->kind == HD_WELD && !jt->has_spring)))
                continue;
            const long ends[2] = {jt->a, jt->b};
            const double *points[2] = {jt->point_a, jt->point_b};
            for (int e = 0; e < 2; ++e) {
                if (ends[e] < 0)
                    continue;
                if (pass == 0) {
                    ++next[ends[e]];
                    continue;
                }
                const double *far = points[1 - e];
                m->pinned[next[ends[e]]++] = (struct hd_pin_end){
                    points[e][0], points[e][1], ends[1 - e], sqrt(far[0] * far[0] + far[1] * far[1])};
            }
        }
        if (pass == 0)
            for (long b = 0; b < nb; ++b)
                m->pinned_start[b + 2] += m->pinned_start[b + 1];
    }
    return HD_JOINTS_OK;
}

int hd_joints_prepare(hd_joint_model *m)
{
    /* Rows at any pose: the same count, kinds and bodies (the values do not matter). */
    const long nb = m->body_count, rows_most = 6 * m->joint_count + 1;
    hd_joint_row *probe = calloc((size_t)rows_most, sizeof(hd_joint_row));
    double *zero = calloc((size_t)(3 * nb + 1), sizeof(double));
    m->trig = malloc((size_t)(3 * nb + 1) * sizeof(double));
    if (probe == NULL || zero == NULL || m->trig == NULL) {
        free(probe);
        free(zero);
        return HD_JOINTS_OUT_OF_MEMORY;
    }
    m->angles = m->trig + 2 * nb;
    m->remembered = m->needed = 1, m->settled_steps = 0;
    for (long b = 0; b < nb; ++b)
        m->angles[b] = NAN;  /* no angle's cos and sin computed yet */
    m->plain_pins = 1;
    for (long i = 0; i < m->joint_count; ++i)
        m->plain_pins = m->plain_pins && hd_plain_pin(m->joints + i);
    const long n = hd_joint_rows(m, zero, 1.0, probe, 0);
    m->row_count = n;
    m->rigid = malloc((size_t)(n + 1) * sizeof(long));
    m->rigid_count = 0;
    for (long i = 0; m->rigid != NULL && i < n; ++i)
        if (probe[i].kind == HD_RIGID)
            m->rigid[m->rigid_count++] = i;
    m->pins = malloc((size_t)(n + 1) * sizeof(long));
    m->pin_count = 0;
    for (long i = 0; m->pins != NULL && i < n; ++i)
        if (probe[i].pair)
            m->pins[m->pin_count++] = i;
    int status = m->rigid == NULL || m->pins == NULL ? HD_JOINTS_OUT_OF_MEMORY : HD_JOINTS_OK;
    if (status == HD_JOINTS_OK && (m->pattern.n != n || m->rigid_pattern.n != m->rigid_count))
        status = HD_JOINTS_MISMATCH;
    if (status == HD_JOINTS_OK && (hd_make_meets(&m->pattern, probe, NULL, &m->meets) < 0 ||
            hd_make_meets(&m->rigid_pattern, probe, m->rigid, &m->rigid_meets) < 0))
        status = HD_JOINTS_OUT_OF_MEMORY;
    free(probe);
    free(zero);
    if (status != HD_JOINTS_OK)
        return status;
    const size_t R = (size_t)n + 1, B = 3 * (size_t)nb + 1;
    const size_t S = (size_t)(m->pattern.start[m->pattern.n] > m->rigid_pattern.start[
                                  m->rigid_pattern.n] ? m->pattern.start[m->pattern.n]
                              : m->rigid_pattern.start[m->rigid_pattern.n]) + 1;
    m->row_memory = calloc(4 * R, sizeof(hd_joint_row));
    m->memory = calloc(4 * B + 11 * R + 4 * S, sizeof(double));
    m->bounded = malloc(R * sizeof(long));
    m->flags = malloc(4 * R * sizeof(int));
    m->warm = calloc(R, sizeof(double));
    m->newton = calloc(R, sizeof(double));
    m->extra = calloc(R, sizeof(double));
    m->settled = calloc(B, sizeof(double));
    m->stiffness = calloc(B, sizeof(double));
    if (m->stiffness == NULL || m->rigid == NULL ||
            m->row_memory == NULL || m->memory == NULL || m->bounded == NULL ||
            m->flags == NULL || m->warm == NULL || m->newton == NULL || m->extra == NULL ||
            m->settled == NULL)
        return HD_JOINTS_OUT_OF_MEMORY;
    if (hd_pin_ends(m) != HD_JOINTS_OK)
        return HD_JOINTS_OUT_OF_MEMORY;
    m->rows0 = m->row_memory, m->rows = m->rows0 + R, m->dir0 = m->rows + R;
    m->dir = m->dir0 + R;
    m->free = m->flags, m->out = m->flags + R, m->active = m->flags + 2 * R;
    m->side = m->flags + 3 * R;
    double *p = m->memory;
    m->start = p, m->q = p + B, m->moved = p + 2 * B, m->v = p + 3 * B;
    p += 4 * B;
    double **vectors[] = {&m->target, &m->nu, &m->step, &m->rhs, &m->b, &m->low_bound,
                          &m->high_bound, &m->x, &m->diag, &m->diagonal};
    for (size_t k = 0; k < sizeof vectors / sizeof vectors[0]; ++k, p += R)
        *vectors[k] = p;
    p += R;
    m->lower = p, p += S;
    m->upper = p, p += S;
    m->low = p;
    return HD_JOINTS_OK;
}

void hd_joints_free(hd_joint_model *m)
{
    if (m == NULL)
        return;
    free(m->bodies);
    free(m->inverse_mass);
    free(m->joints);
    free(m->rigid);
    free(m->pins);
    free(m->stiffness);
    free(m->free_turn);
    free(m->pinned_start);
    free(m->pinned);
    free(m->turning);
    free(m->trig);
    free(m->warm);
    free(m->newton);
    free(m->extra);
    free(m->settled);
    free(m->memory);
    free(m->row_memory);
    free(m->bounded);
    free(m->flags);
    hd_pattern_free(&m->pattern);
    hd_pattern_free(&m->rigid_pattern);
    hd_free_meets(&m->meets);
    hd_free_meets(&m->rigid_meets);
    free(m);
}
