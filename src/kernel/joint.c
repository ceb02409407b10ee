/* The joint pass: hecker_dynamics/contact/joints.py, operation for operation (see joint.h).
 *
 * Each function names the Python function it repeats. Python's min and max keep their
 * first argument unless the second is strictly smaller or larger, and Python's float %
 * takes the sign of the divisor: the helpers below do the same, so that zeros' signs and
 * ties come out as in Python.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "joint.h"

static const double PI = 3.141592653589793;

static double py_max(double a, double b) { return b > a ? b : a; }
static double py_min(double a, double b) { return b < a ? b : a; }

/* CPython's float %: fmod, moved to the sign of the divisor. */
static double py_mod(double x, double y)
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

/* joints.py: _wrap, an angle in [-pi, pi). */
static double wrap(double angle) { return py_mod(angle + PI, 2.0 * PI) - PI; }

/* joints.py: _Frame.place: the point (x, y), its arm (rx, ry) from the CM, the angle. */
typedef struct { double x, y, rx, ry, angle; } Place;

static Place place(long body, const double *local, const double *q)
{
    Place p;
    if (body < 0) {
        p.x = local[0], p.y = local[1], p.rx = 0.0, p.ry = 0.0, p.angle = 0.0;
        return p;
    }
    const double x = q[3 * body], y = q[3 * body + 1], angle = q[3 * body + 2];
    const double c = cos(angle), s = sin(angle);
    p.rx = c * local[0] - s * local[1];
    p.ry = s * local[0] + c * local[1];
    p.x = x + p.rx, p.y = y + p.ry, p.angle = angle;
    return p;
}

static void add_entry(hd_joint_row *r, long body, double jx, double jy, double jw)
{
    r->body[r->count] = body;
    r->j[r->count][0] = jx, r->j[r->count][1] = jy, r->j[r->count][2] = jw;
    r->count += 1;
}

static hd_joint_row *new_row(hd_joint_row *rows, long *n, int kind, double c)
{
    hd_joint_row *r = rows + (*n)++;
    memset(r, 0, sizeof *r);
    r->kind = kind, r->c = c, r->bound = INFINITY;
    return r;
}

/* joints.py: _fixed (a direction fixed in the world) and _line (fixed in body a). */
static void fixed(hd_joint_row *r, const hd_joint *jt, Place pa, Place pb, double ux, double uy)
{
    if (jt->b >= 0)
        add_entry(r, jt->b, ux, uy, ux * -pb.ry + uy * pb.rx);
    if (jt->a >= 0)
        add_entry(r, jt->a, -ux, -uy, -(ux * -pa.ry + uy * pa.rx));
}

static void line(hd_joint_row *r, const hd_joint *jt, Place pa, Place pb, double ux, double uy)
{
    if (jt->b >= 0)
        add_entry(r, jt->b, ux, uy, ux * -pb.ry + uy * pb.rx);
    if (jt->a >= 0) {
        const double dx = pa.rx + pb.x - pa.x, dy = pa.ry + pb.y - pa.y;
        add_entry(r, jt->a, -ux, -uy, -(ux * -dy + uy * dx));
    }
}

static void angle_entries(hd_joint_row *r, long a, long b, double scale)
{
    add_entry(r, b, 0.0, 0.0, scale);
    if (a >= 0)
        add_entry(r, a, 0.0, 0.0, -scale);
}

static void negate(hd_joint_row *r)
{
    for (int e = 0; e < r->count; ++e)
        for (int k = 0; k < 3; ++k)
            r->j[e][k] = -r->j[e][k];
}

/* joints.py: JointPass._joint_angle. */
static double joint_angle(const hd_joint *jt, Place pa, Place pb)
{
    return jt->angle + wrap(pb.angle - pa.angle - jt->raw);
}

/* joints.py: _point_rows. */
static void point_rows(hd_joint_row *rows, long *n, const hd_joint *jt, Place pa, Place pb,
                       int kind, double stiffness, double damping)
{
    for (int axis = 0; axis < 2; ++axis) {
        const double ux = axis == 0 ? 1.0 : 0.0, uy = axis == 0 ? 0.0 : 1.0;
        hd_joint_row *r = new_row(rows, n, kind, ux * (pb.x - pa.x) + uy * (pb.y - pa.y));
        fixed(r, jt, pa, pb, ux, uy);
        r->stiffness = stiffness, r->damping = damping, r->scaled = 1;
    }
}

/* joints.py: _bounded_rows, the coordinate `value` with the Jacobian of `coordinate`. */
static void bounded_rows(hd_joint_row *rows, long *n, const hd_joint *jt, double value,
                         const hd_joint_row *coordinate, double h)
{
    if (jt->has_lower) {
        hd_joint_row *r = new_row(rows, n, HD_LIMIT, value - jt->lower);
        memcpy(r->body, coordinate->body, sizeof r->body);
        memcpy(r->j, coordinate->j, sizeof r->j);
        r->count = coordinate->count;
    }
    if (jt->has_upper) {
        hd_joint_row *r = new_row(rows, n, HD_LIMIT, jt->upper - value);
        memcpy(r->body, coordinate->body, sizeof r->body);
        memcpy(r->j, coordinate->j, sizeof r->j);
        r->count = coordinate->count;
        negate(r);
    }
    if (jt->has_motor) {
        hd_joint_row *r = new_row(rows, n, HD_MOTOR, value);
        memcpy(r->body, coordinate->body, sizeof r->body);
        memcpy(r->j, coordinate->j, sizeof r->j);
        r->count = coordinate->count;
        r->speed = jt->motor_speed, r->bound = jt->max_effort * h;
    }
}

/* joints.py: JointPass._axis. */
static void axis_of(const hd_joint *jt, double angle_a, double *ux, double *uy)
{
    const double c = cos(angle_a), s = sin(angle_a);
    *ux = c * jt->axis[0] - s * jt->axis[1];
    *uy = s * jt->axis[0] + c * jt->axis[1];
}

/* joints.py: JointPass.rows: every joint's rows at q (local bodies); returns their count. */
static long build_rows(const hd_joint_model *m, const double *q, double h, hd_joint_row *rows)
{
    long n = 0;
    for (long i = 0; i < m->joint_count; ++i) {
        const hd_joint *jt = m->joints + i;
        if (jt->kind == HD_GEAR) {
            hd_joint_row *r = new_row(rows, &n, HD_RIGID, 0.0);
            const long pair[2] = {jt->gear_a, jt->gear_b};
            const double scales[2] = {1.0, jt->ratio};
            double value = 0.0;
            for (int k = 0; k < 2; ++k) {
                const hd_joint *g = m->joints + pair[k];
                const Place pa = place(g->a, g->point_a, q), pb = place(g->b, g->point_b, q);
                value += scales[k] * joint_angle(g, pa, pb);
                angle_entries(r, g->a, g->b, scales[k]);
            }
            r->c = value;
            continue;
        }
        const Place pa = place(jt->a, jt->point_a, q), pb = place(jt->b, jt->point_b, q);
        if (jt->kind == HD_REVOLUTE) {
            point_rows(rows, &n, jt, pa, pb, HD_RIGID, 0.0, 0.0);
            const double angle = joint_angle(jt, pa, pb);
            hd_joint_row coordinate = {0};
            angle_entries(&coordinate, jt->a, jt->b, 1.0);
            bounded_rows(rows, &n, jt, angle, &coordinate, h);
            if (jt->has_spring) {
                hd_joint_row *r = new_row(rows, &n, HD_SOFT, angle - jt->rest);
                angle_entries(r, jt->a, jt->b, 1.0);
                r->stiffness = jt->stiffness, r->damping = jt->damping;
            }
        } else if (jt->kind == HD_WELD) {
            const int kind = jt->has_spring ? HD_SOFT : HD_RIGID;
            point_rows(rows, &n, jt, pa, pb, kind, jt->stiffness, jt->damping);
            hd_joint_row *r = new_row(rows, &n, kind,
                                      wrap(pb.angle - pa.angle - jt->reference_angle));
            angle_entries(r, jt->a, jt->b, 1.0);
            r->stiffness = jt->stiffness, r->damping = jt->damping, r->scaled = 1;
        } else if (jt->kind == HD_PRISMATIC) {
            double ux, uy;
            axis_of(jt, pa.angle, &ux, &uy);
            hd_joint_row *r = new_row(rows, &n, HD_RIGID,
                                      -uy * (pb.x - pa.x) + ux * (pb.y - pa.y));
            line(r, jt, pa, pb, -uy, ux);
            r = new_row(rows, &n, HD_RIGID, wrap(pb.angle - pa.angle - jt->reference_angle));
            angle_entries(r, jt->a, jt->b, 1.0);
            /* JointPass._coordinate: the translation along the axis. */
            axis_of(jt, pa.angle, &ux, &uy);
            const double along = ux * (pb.x - pa.x) + uy * (pb.y - pa.y) - jt->reference_along;
            hd_joint_row coordinate = {0};
            line(&coordinate, jt, pa, pb, ux, uy);
            bounded_rows(rows, &n, jt, along, &coordinate, h);
        } else {  /* a rod or a rope */
            const double dx = pb.x - pa.x, dy = pb.y - pa.y;
            const double length = sqrt(dx * dx + dy * dy);
            const double ux = length > 0.0 ? dx / length : 1.0,
                         uy = length > 0.0 ? dy / length : 0.0;
            if (jt->kind == HD_ROPE) {
                hd_joint_row *r = new_row(rows, &n, HD_LIMIT, jt->length - length);
                fixed(r, jt, pa, pb, ux, uy);
                negate(r);
            } else {
                hd_joint_row *r = new_row(rows, &n, HD_RIGID, length - jt->length);
                fixed(r, jt, pa, pb, ux, uy);
            }
        }
    }
    return n;
}

/* joints.py: _directions: per row, M^-1 J^T. */
static void directions(const hd_joint_model *m, const hd_joint_row *rows, long n,
                       hd_joint_row *out)
{
    for (long i = 0; i < n; ++i) {
        out[i] = rows[i];
        for (int e = 0; e < rows[i].count; ++e) {
            const double *im = m->inverse_mass + 3 * rows[i].body[e];
            for (int k = 0; k < 3; ++k)
                out[i].j[e][k] = im[k] * rows[i].j[e][k];
        }
    }
}

/* joints.py: _apply: x += M^-1 J^T impulse, row by row. */
static void apply(double *x, const hd_joint_row *direction, long n, const double *impulse)
{
    for (long i = 0; i < n; ++i) {
        const double amount = impulse[i];
        for (int e = 0; e < direction[i].count; ++e) {
            double *target = x + 3 * direction[i].body[e];
            target[0] += direction[i].j[e][0] * amount;
            target[1] += direction[i].j[e][1] * amount;
            target[2] += direction[i].j[e][2] * amount;
        }
    }
}

/* joints.py: _bandwidth (first: one slot per local body). */
static long bandwidth(const hd_joint_model *m, const hd_joint_row *rows, long n)
{
    long *first = m->first, width = 0;
    for (long b = 0; b < m->body_count; ++b)
        first[b] = -1;
    for (long i = 0; i < n; ++i)
        for (int e = 0; e < rows[i].count; ++e) {
            const long b = rows[i].body[e];
            if (first[b] < 0)
                first[b] = i;
            if (i - first[b] > width)
                width = i - first[b];
        }
    return width;
}

/* joints.py: _dot. */
static double dot(const hd_joint_row *row, const hd_joint_row *direction)
{
    double s = 0.0;
    for (int e = 0; e < row->count; ++e)
        for (int f = 0; f < direction->count; ++f)
            if (row->body[e] == direction->body[f])
                s += row->j[e][0] * direction->j[f][0] + row->j[e][1] * direction->j[f][1]
                     + row->j[e][2] * direction->j[f][2];
    return s;
}

double hd_joint_dot(const hd_joint_row *row, const hd_joint_row *direction)
{
    return dot(row, direction);
}

/* joints.py: _products, band (2 w + 1 per row). */
static void products(const hd_joint_row *rows, const hd_joint_row *direction, long n, long w,
                     double *a)
{
    for (long i = 0; i < n; ++i)
        for (long j = i - w; j <= i + w; ++j)
            a[i * (2 * w + 1) + (j - i + w)] = 0 <= j && j < n ? dot(rows + i, direction + j)
                                                              : 0.0;
}

/* joints.py: _lu. */
static int lu(double *a, long n, long w)
{
    const long stride = 2 * w + 1;
    for (long k = 0; k < n; ++k) {
        const double pivot = a[k * stride + w];
        if (!(pivot != 0.0))
            return HD_JOINTS_DEPENDENT;
        const long end = n < k + w + 1 ? n : k + w + 1;
        for (long i = k + 1; i < end; ++i) {
            const double factor = a[i * stride + (k - i + w)] / pivot;
            a[i * stride + (k - i + w)] = factor;
            for (long j = k + 1; j < end; ++j)
                a[i * stride + (j - i + w)] -= factor * a[k * stride + (j - k + w)];
        }
    }
    return HD_JOINTS_OK;
}

/* joints.py: _lu_solve, x in place of the right-hand side. */
static void lu_solve(const double *a, long n, long w, double *x)
{
    const long stride = 2 * w + 1;
    for (long i = 0; i < n; ++i) {
        double s = x[i];
        for (long k = i > w ? i - w : 0; k < i; ++k)
            s -= a[i * stride + (k - i + w)] * x[k];
        x[i] = s;
    }
    for (long i = n - 1; i >= 0; --i) {
        double s = x[i];
        const long end = n < i + w + 1 ? n : i + w + 1;
        for (long j = i + 1; j < end; ++j)
            s -= a[i * stride + (j - i + w)] * x[j];
        x[i] = s / a[i * stride + w];
    }
}

/* joints.py: _normal_matrix: the lower band (w + 1 per row) of J M^-1 J^T. */
static void normal_matrix(const hd_joint_row *rows, const hd_joint_row *direction, long n,
                          long w, double *band)
{
    for (long i = 0; i < n; ++i)
        for (long d = 0; d <= w; ++d)
            band[i * (w + 1) + d] = d <= i ? dot(rows + i, direction + i - d) : 0.0;
}

/* joints.py: Band.at. */
static double band_at(const double *band, long w, long i, long j)
{
    return j <= i ? band[i * (w + 1) + (i - j)] : band[j * (w + 1) + (j - i)];
}

/* joints.py: _factor, into low (w + 1 per row) and diag. */
static int factor(const double *band, long n, long w, double *low, double *diag)
{
    const long stride = w + 1;
    for (long k = 0; k < n * stride; ++k)
        low[k] = 0.0;
    for (long i = 0; i < n; ++i) {
        const long start = i > w ? i - w : 0;
        double *li = low + i * stride;
        for (long j = start; j < i; ++j) {
            double s = band[i * stride + (i - j)];
            const double *lj = low + j * stride;
            for (long k = start; k < j; ++k)
                s -= li[i - k] * diag[k] * lj[j - k];
            li[i - j] = s / diag[j];
        }
        double s = band[i * stride];
        for (long k = start; k < i; ++k)
            s -= li[i - k] * diag[k] * li[i - k];
        if (!(s > 0.0))
            return HD_JOINTS_DEPENDENT;
        diag[i] = s;
    }
    return HD_JOINTS_OK;
}

/* joints.py: _substitute, x in place of the right-hand side. */
static void substitute(const double *low, const double *diag, long n, long w, double *x)
{
    const long stride = w + 1;
    for (long i = 0; i < n; ++i) {
        double s = x[i];
        for (long k = i > w ? i - w : 0; k < i; ++k)
            s -= low[i * stride + (i - k)] * x[k];
        x[i] = s / diag[i];
    }
    for (long i = n - 1; i >= 0; --i) {
        double s = x[i];
        const long end = n < i + w + 1 ? n : i + w + 1;
        for (long j = i + 1; j < end; ++j)
            s -= low[j * stride + (j - i)] * x[j];
        x[i] = s;
    }
}

/* joints.py: _solve, the impulses into m->x. */
static int solve(hd_joint_model *m, long n, long w)
{
    const double *k = m->band, *b = m->b, *lower = m->lower, *upper = m->upper;
    double *x = m->x;
    int all_free = 1;
    for (long i = 0; i < n; ++i) {
        m->free[i] = lower[i] == -INFINITY && upper[i] == INFINITY;
        all_free = all_free && m->free[i];
    }
    if (all_free) {
        memcpy(x, b, (size_t)n * sizeof(double));
        if (factor(k, n, w, m->low, m->diag) != HD_JOINTS_OK)
            return HD_JOINTS_DEPENDENT;
        substitute(m->low, m->diag, n, w, x);
        return HD_JOINTS_OK;
    }
    long nf = 0, nb = 0;
    for (long i = 0; i < n; ++i) {
        x[i] = m->free[i] ? 0.0 : py_min(py_max(m->warm[i], lower[i]), upper[i]);
        if (m->free[i])
            m->free_index[nf++] = i;
        else
            m->bounded[nb++] = i;
    }
    if (nf > 0) {  /* Band.part */
        for (long p = 0; p < nf; ++p) {
            const long i = m->free_index[p];
            for (long d = 0; d <= w; ++d)
                m->part[p * (w + 1) + d] = d <= p && i - m->free_index[p - d] <= w
                                           ? band_at(k, w, i, m->free_index[p - d]) : 0.0;
        }
        if (factor(m->part, nf, w, m->low, m->diag) != HD_JOINTS_OK)
            return HD_JOINTS_DEPENDENT;
    }
    for (long iteration = 0; iteration < HD_JOINT_MAX_ITERATIONS; ++iteration) {
        if (nf > 0) {
            for (long p = 0; p < nf; ++p) {
                const long i = m->free_index[p], end = n < i + w + 1 ? n : i + w + 1;
                double s = 0.0;
                for (long j = i > w ? i - w : 0; j < end; ++j)
                    if (!m->free[j])
                        s += band_at(k, w, i, j) * x[j];
                m->rhs[p] = b[i] - s;
            }
            substitute(m->low, m->diag, nf, w, m->rhs);
            for (long p = 0; p < nf; ++p)
                x[m->free_index[p]] = m->rhs[p];
        }
        double largest = 0.0;
        for (long q = 0; q < nb; ++q) {
            const long i = m->bounded[q], end = n < i + w + 1 ? n : i + w + 1;
            double s = 0.0;
            for (long j = i > w ? i - w : 0; j < end; ++j)
                s += band_at(k, w, i, j) * x[j];
            const double updated = py_min(py_max(x[i] + (b[i] - s) / k[i * (w + 1)], lower[i]),
                                          upper[i]);
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
    return HD_JOINTS_OK;
}

static double largest_error(const double *error, long n)
{
    double largest = fabs(error[0]);
    for (long i = 1; i < n; ++i)
        if (fabs(error[i]) > largest)
            largest = fabs(error[i]);
    return largest;
}

/* joints.py: JointPass._hold, on m->q; the rows at the new q in m->rows. */
static int hold(hd_joint_model *m, double h)
{
    const long nr = m->rigid_count;
    if (nr == 0) {
        build_rows(m, m->q, h, m->rows);
        return HD_JOINTS_OK;
    }
    for (long k = 0; k < nr; ++k)
        m->subset[k] = m->rows0[m->rigid[k]];
    directions(m, m->subset, nr, m->dir0);
    const long w = bandwidth(m, m->subset, nr);
    for (long k = 0; k < nr; ++k) {
        m->target[k] = m->subset[k].c;
        m->nu[k] = m->newton_valid ? m->newton[k] : 0.0;
    }
    apply(m->q, m->dir0, nr, m->nu);
    int converged = 0;
    for (long iteration = 0; iteration < HD_NEWTON_ITERATIONS; ++iteration) {
        build_rows(m, m->q, h, m->rows);
        for (long k = 0; k < nr; ++k)
            m->step[k] = m->rows[m->rigid[k]].c - m->target[k];
        if (largest_error(m->step, nr) <= HD_JOINT_TOLERANCE) {
            converged = 1;
            break;
        }
        for (long k = 0; k < nr; ++k) {
            m->subset[k] = m->rows[m->rigid[k]];
            m->step[k] = -m->step[k];
        }
        products(m->subset, m->dir0, nr, w, m->matrix);
        if (lu(m->matrix, nr, w) != HD_JOINTS_OK)
            return HD_JOINTS_DEPENDENT;
        lu_solve(m->matrix, nr, w, m->step);
        for (long k = 0; k < nr; ++k)
            m->nu[k] = m->nu[k] + m->step[k];
        apply(m->q, m->dir0, nr, m->step);
    }
    if (!converged)
        build_rows(m, m->q, h, m->rows);
    memcpy(m->newton, m->nu, (size_t)nr * sizeof(double));
    m->newton_valid = 1;
    return HD_JOINTS_OK;
}

/* joints.py: JointPass._correct, on m->q and m->rows. */
static int correct(hd_joint_model *m, double h)
{
    const long n = m->row_count;
    for (long iteration = 0; iteration < HD_DRIFT_ITERATIONS; ++iteration) {
        int off = 0;
        for (long i = 0; i < n && !off; ++i) {
            const hd_joint_row *r = m->rows + i;
            off = (r->kind == HD_RIGID && fabs(r->c) > HD_JOINT_TOLERANCE) ||
                  (r->kind == HD_LIMIT && r->c < -HD_JOINT_TOLERANCE);
        }
        if (!off)
            break;
        long count = 0;
        for (long i = 0; i < n; ++i) {
            const hd_joint_row *r = m->rows + i;
            if (r->kind == HD_RIGID || (r->kind == HD_LIMIT && r->c < 0.0)) {
                m->subset[count] = *r;
                m->rhs[count] = -r->c;
                count += 1;
            }
        }
        directions(m, m->subset, count, m->dir);
        const long w = bandwidth(m, m->subset, count);
        normal_matrix(m->subset, m->dir, count, w, m->band);
        if (factor(m->band, count, w, m->low, m->diag) != HD_JOINTS_OK)
            return HD_JOINTS_DEPENDENT;
        substitute(m->low, m->diag, count, w, m->rhs);
        apply(m->q, m->dir, count, m->rhs);
        build_rows(m, m->q, h, m->rows);
    }
    return HD_JOINTS_OK;
}

/* joints.py: _rate. */
static double rate(const hd_joint_row *row, const double *v)
{
    double s = 0.0;
    for (int e = 0; e < row->count; ++e) {
        const double *w = v + 3 * row->body[e];
        s += row->j[e][0] * w[0] + row->j[e][1] * w[1] + row->j[e][2] * w[2];
    }
    return s;
}

/* joints.py: JointPass._velocities, on m->v at the rows m->rows. */
static int velocities(hd_joint_model *m, double h)
{
    const long n = m->row_count;
    directions(m, m->rows, n, m->dir);
    const long w = bandwidth(m, m->rows, n);
    normal_matrix(m->rows, m->dir, n, w, m->band);
    for (long i = 0; i < n; ++i) {
        const hd_joint_row *row = m->rows + i;
        m->b[i] = -rate(row, m->v);
        m->lower[i] = -INFINITY, m->upper[i] = INFINITY;
        if (row->kind == HD_LIMIT) {
            m->b[i] -= (0.0 > row->c ? 0.0 : row->c) / h;
            m->lower[i] = 0.0;
        } else if (row->kind == HD_MOTOR) {
            m->b[i] += row->speed;
            m->lower[i] = -row->bound, m->upper[i] = row->bound;
        } else if (row->kind == HD_SOFT) {
            double *diagonal = m->band + i * (w + 1);
            const double scale = row->scaled ? 1.0 / *diagonal : 1.0;
            const double stiffness = row->stiffness * scale, damping = row->damping * scale;
            const double compliance = stiffness * h + damping;
            if (compliance == 0.0) {
                m->lower[i] = m->upper[i] = 0.0;
                continue;
            }
            *diagonal += 1.0 / (h * compliance);
            m->b[i] -= stiffness * row->c / compliance;
        }
    }
    if (solve(m, n, w) != HD_JOINTS_OK)
        return HD_JOINTS_DEPENDENT;
    apply(m->v, m->dir, n, m->x);
    memcpy(m->warm, m->x, (size_t)n * sizeof(double));
    m->last_h = h;
    return HD_JOINTS_OK;
}

int hd_joints_resolve(hd_joint_model *m, const double *q0, double *q1, double *v1, double h)
{
    const long nb = m->body_count;
    for (long k = 0; k < nb; ++k)
        for (int c = 0; c < 3; ++c) {
            m->start[3 * k + c] = q0[3 * m->bodies[k] + c];
            m->q[3 * k + c] = m->moved[3 * k + c] = q1[3 * m->bodies[k] + c];
            m->v[3 * k + c] = v1[3 * m->bodies[k] + c];
        }
    build_rows(m, m->start, h, m->rows0);
    int status = hold(m, h);
    if (status != HD_JOINTS_OK)
        return status;
    for (long k = 0; k < 3 * nb; ++k)
        m->v[k] += (m->q[k] - m->moved[k]) / h;
    if ((status = correct(m, h)) != HD_JOINTS_OK)
        return status;
    memcpy(m->settled, m->v, (size_t)(3 * nb) * sizeof(double));
    if ((status = velocities(m, h)) != HD_JOINTS_OK)
        return status;
    for (long i = 0; i < m->joint_count; ++i) {  /* JointPass._count_turns */
        hd_joint *jt = m->joints + i;
        if (jt->kind == HD_GEAR)
            continue;
        const Place pa = place(jt->a, jt->point_a, m->q), pb = place(jt->b, jt->point_b, m->q);
        jt->angle = joint_angle(jt, pa, pb);
        jt->raw = pb.angle - pa.angle;
    }
    for (long k = 0; k < nb; ++k)
        for (int c = 0; c < 3; ++c) {
            q1[3 * m->bodies[k] + c] = m->q[3 * k + c];
            v1[3 * m->bodies[k] + c] = m->v[3 * k + c];
        }
    return HD_JOINTS_OK;
}

int hd_joints_prepare(hd_joint_model *m)
{
    /* Rows at any pose: the same count, kinds and bodies (the values do not matter). */
    const long nb = m->body_count, rows_most = 6 * m->joint_count + 1;
    hd_joint_row *probe = calloc((size_t)rows_most, sizeof(hd_joint_row));
    double *zero = calloc((size_t)(3 * nb + 1), sizeof(double));
    m->first = malloc((size_t)(nb + 1) * sizeof(long));
    if (probe == NULL || zero == NULL || m->first == NULL) {
        free(probe);
        free(zero);
        return HD_JOINTS_OUT_OF_MEMORY;
    }
    const long n = build_rows(m, zero, 1.0, probe);
    m->row_count = n;
    m->width = bandwidth(m, probe, n);
    m->rigid = malloc((size_t)(n + 1) * sizeof(long));
    m->rigid_count = 0;
    for (long i = 0; m->rigid != NULL && i < n; ++i)
        if (probe[i].kind == HD_RIGID)
            m->rigid[m->rigid_count++] = i;
    free(probe);
    free(zero);
    const size_t R = (size_t)n + 1, W = (size_t)m->width, B = 3 * (size_t)nb + 1;
    m->rows0 = calloc(5 * R, sizeof(hd_joint_row));
    m->memory = calloc(4 * B + 10 * R + R * (2 * W + 1) + 3 * R * (W + 1), sizeof(double));
    m->free_index = malloc(2 * R * sizeof(long));
    m->free = malloc(R * sizeof(int));
    m->warm = calloc(R, sizeof(double));
    m->newton = calloc(R, sizeof(double));
    m->extra = calloc(R, sizeof(double));
    m->settled = calloc(B, sizeof(double));
    if (m->rigid == NULL || m->rows0 == NULL || m->memory == NULL || m->free_index == NULL ||
            m->free == NULL || m->warm == NULL || m->newton == NULL || m->extra == NULL ||
            m->settled == NULL)
        return HD_JOINTS_OUT_OF_MEMORY;
    m->rows = m->rows0 + R, m->subset = m->rows + R, m->dir0 = m->subset + R;
    m->dir = m->dir0 + R;
    double *p = m->memory;
    m->start = p, m->q = p + B, m->moved = p + 2 * B, m->v = p + 3 * B;
    p += 4 * B;
    double **vectors[] = {&m->target, &m->nu, &m->step, &m->rhs, &m->b, &m->lower, &m->upper,
                          &m->x, &m->diag};
    for (size_t k = 0; k < sizeof vectors / sizeof vectors[0]; ++k, p += R)
        *vectors[k] = p;
    p += R;
    m->matrix = p, p += R * (2 * W + 1);
    m->band = p, p += R * (W + 1);
    m->part = p, p += R * (W + 1);
    m->low = p;
    m->bounded = m->free_index + R;
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
    free(m->warm);
    free(m->newton);
    free(m->extra);
    free(m->settled);
    free(m->memory);
    free(m->rows0);
    free(m->first);
    free(m->free_index);
    free(m->free);
    free(m);
}
