/* Force terms: steps 3 to 6 of the algorithm of "Physics, Part 2: Angular Effects".
 *
 * Each force has a point of application; the forces add up at the CM (F = M a, Eq. 5)
 * and each adds the perp-dot torque of its offset from the CM (Eq. 11); a point's velocity
 * is v_CM + omega perp(r) (Eq. 9). Every function repeats, operation for operation,
 * the plain-float path of hecker_dynamics/dynamics/forces.py (`add_scalar`).
 */
#include <float.h>
#include <math.h>

#include "floats.h"
#include "kernel.h"

int hd_int_columns(int kind)
{
    switch (kind) {
    case HD_GRAVITY: case HD_ANCHOR_SPRING: case HD_ANGULAR_DAMPING: return 1;
    case HD_BODY_SPRING: case HD_CENTER_DRAG: case HD_POINT_DRAG: return 2;
    case HD_WRENCH: return 4;
    default: return 0;
    }
}

int hd_real_columns(int kind)
{
    switch (kind) {
    case HD_GRAVITY: return 2;
    case HD_ANCHOR_SPRING: case HD_BODY_SPRING: return 7;
    case HD_CENTER_DRAG: case HD_ANGULAR_DAMPING: return 1;
    case HD_POINT_DRAG: return 3;
    case HD_WRENCH: return 5;
    default: return 0;
    }
}

/* World offset r = R(angle) l of a point l given relative to a body's CM. */
static void hd_offset(const hd_scratch *s, long body, double lx, double ly, double *rx, double *ry)
{
    double c = s->cos[body], sn = s->sin[body];
    *rx = c * lx - sn * ly;
    *ry = sn * lx + c * ly;
}

/* v_P = v_CM + omega perp(r) (Eq. 9). */
static void hd_point_velocity(const double *v, long body, double rx, double ry,
                              double *vx, double *vy)
{
    const double *b = v + 3 * body;
    *vx = b[0] - b[2] * ry;
    *vy = b[1] + b[2] * rx;
}

/* Force (fx, fy) at offset (rx, ry) from the CM: the force and its perp-dot torque
 * (Eq. 11). */
static void hd_apply(double *wrench, double rx, double ry, double fx, double fy)
{
    wrench[0] += fx;
    wrench[1] += fy;
    wrench[2] += rx * fy - ry * fx;
}

/* Force on end A of a damped spring, d = p_A - p_B, dv = v_A - v_B (dynamics/forces.py:
 * `spring_force_scalar`). */
static HD_HOT void hd_spring(double dx, double dy, double dvx, double dvy, double k, double rest,
                      double c, double *fx, double *fy)
{
    if (rest == 0.0) {
        *fx = -k * dx - c * dvx;
        *fy = -k * dy - c * dvy;
        return;
    }
    double l = hd_length(dx, dy);
    if (l == 0.0) {
        *fx = 0.0;
        *fy = 0.0;
        return;
    }
    double ux = dx / l, uy = dy / l;
    double along = -(k * (l - rest) + c * (dvx * ux + dvy * uy));
    *fx = along * ux;
    *fy = along * uy;
}

/* -c v (linear) or -c |v| v (quadratic). */
static void hd_drag(double vx, double vy, double c, long quadratic, double *fx, double *fy)
{
    double scale = quadratic ? c * hd_length(vx, vy) : c;
    *fx = -scale * vx;
    *fy = -scale * vy;
}

/* GCC's pairing of scalar operations into vectors (on at -O2 from GCC 12) packs and unpacks
 * each spring's x and y halves: a quarter more instructions in the springs' loop, the most
 * of a large ring's step. Off here; the operations, and so the bits, are the same. */
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-tree-slp-vectorize")))
#endif
static void hd_add_term(const hd_term *t, const hd_scratch *s, const double *q, const double *v)
{
    const int ni = hd_int_columns(t->kind), nr = hd_real_columns(t->kind);
    double *w = s->wrench;
    /* One loop per kind (not a switch per instance), so each loop keeps its columns in
     * registers: the springs of a large ring are most of a step. */
    const long *i = t->ints;
    const double *r = t->reals;
    double rx, ry, vx, vy, fx, fy;
    switch (t->kind) {
    case HD_GRAVITY:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr) {
            w[3 * i[0]] += r[0];
            w[3 * i[0] + 1] += r[1];
        }
        break;
    case HD_ANCHOR_SPRING:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr) {
            long b = i[0];
            hd_offset(s, b, r[0], r[1], &rx, &ry);
            hd_point_velocity(v, b, rx, ry, &vx, &vy);
            hd_spring(q[3 * b] + rx - r[2], q[3 * b + 1] + ry - r[3], vx, vy, r[4], r[5], r[6],
                      &fx, &fy);
            hd_apply(w + 3 * b, rx, ry, fx, fy);
        }
        break;
    case HD_BODY_SPRING:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr) {
            long a = i[0], b = i[1];
            double rax, ray, rbx, rby, vax, vay, vbx, vby;
            hd_offset(s, a, r[0], r[1], &rax, &ray);
            hd_offset(s, b, r[2], r[3], &rbx, &rby);
            hd_point_velocity(v, a, rax, ray, &vax, &vay);
            hd_point_velocity(v, b, rbx, rby, &vbx, &vby);
            hd_spring(q[3 * a] + rax - q[3 * b] - rbx, q[3 * a + 1] + ray - q[3 * b + 1] - rby,
                      vax - vbx, vay - vby, r[4], r[5], r[6], &fx, &fy);
            hd_apply(w + 3 * a, rax, ray, fx, fy);
            hd_apply(w + 3 * b, rbx, rby, -fx, -fy);
        }
        break;
    case HD_CENTER_DRAG:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr) {
            long b = i[0];
            hd_drag(v[3 * b], v[3 * b + 1], r[0], i[1], &fx, &fy);
            w[3 * b] += fx;
            w[3 * b + 1] += fy;
        }
        break;
    case HD_POINT_DRAG:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr) {
            long b = i[0];
            hd_offset(s, b, r[0], r[1], &rx, &ry);
            hd_point_velocity(v, b, rx, ry, &vx, &vy);
            hd_drag(vx, vy, r[2], i[1], &fx, &fy);
            hd_apply(w + 3 * b, rx, ry, fx, fy);
        }
        break;
    case HD_ANGULAR_DAMPING:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr)
            w[3 * i[0] + 2] -= r[0] * v[3 * i[0] + 2];
        break;
    case HD_WRENCH:
        for (long e = 0; e < t->count; ++e, i += ni, r += nr) {
            long b = i[0], axes = i[1], owner = i[2];
            double px = r[3], py = r[4];
            fx = r[0];
            fy = r[1];
            if (axes >= 0) {
                double bx = fx, by = fy;
                hd_offset(s, axes, bx, by, &fx, &fy);
            }
            w[3 * b + 2] += r[2];
            if (!i[3]) {  /* at the CM */
                w[3 * b] += fx;
                w[3 * b + 1] += fy;
                continue;
            }
            if (owner >= 0) {
                double ox, oy;
                hd_offset(s, owner, px, py, &ox, &oy);
                px = q[3 * owner] + ox;
                py = q[3 * owner + 1] + oy;
            }
            hd_apply(w + 3 * b, px - q[3 * b], py - q[3 * b + 1], fx, fy);
        }
        break;
    }
}

/* cos and sin of every body's angle (glibc takes both at once: sincos, the same bits as
 * cos and sin apart), and, unless `wrench` is NULL, each body's wrench set to zero in the
 * same pass: on a large scene each pass over the bodies is a trip to memory. */
static void hd_angles(const double *q, long n, hd_scratch *scratch, double *wrench)
{
    double *c = scratch->cos, *sn = scratch->sin;
    for (long b = 0; b < n; ++b) {
        const double theta = q[3 * b + 2];
        c[b] = cos(theta);
        sn[b] = sin(theta);
        if (wrench != NULL) {
            wrench[3 * b] = 0.0;
            wrench[3 * b + 1] = 0.0;
            wrench[3 * b + 2] = 0.0;
        }
    }
}

void hd_wrench(const hd_program *program, const hd_program *inputs, int oriented,
               const double *q, const double *v, hd_scratch *scratch)
{
    const long n = program->bodies;
    if (oriented)
        hd_angles(q, n, scratch, scratch->wrench);
    else
        for (long k = 0; k < 3 * n; ++k)
            scratch->wrench[k] = 0.0;
    for (long t = 0; t < program->term_count; ++t)
        hd_add_term(program->terms + t, scratch, q, v);
    if (inputs != NULL)
        for (long t = 0; t < inputs->term_count; ++t)
            hd_add_term(inputs->terms + t, scratch, q, v);
}

void hd_accelerations(const hd_program *program, const hd_program *inputs, int oriented,
                      const double *q, const double *v, double *out, hd_scratch *scratch)
{
    const long n = program->bodies;
    if (program->term_count == 0 && (inputs == NULL || inputs->term_count == 0)) {
        for (long k = 0; k < 3 * n; ++k)
            out[k] = 0.0;
        return;
    }
    hd_wrench(program, inputs, oriented, q, v, scratch);
    for (long k = 0; k < 3 * n; ++k)
        out[k] = scratch->wrench[k] * program->inverse_mass[k];
}

/* k (|d| - L0)^2 / 2 of one spring (dynamics/forces.py: `spring_energy_scalar`). */
static double hd_spring_energy(double dx, double dy, double k, double rest)
{
    const double stretch = hd_length(dx, dy) - rest;
    return 0.5 * k * (stretch * stretch);
}

void hd_unit_spring_potential(const hd_program *program, const double *q, const long *unit,
                              double *energy, double *excess, hd_scratch *scratch)
{
    hd_angles(q, program->bodies, scratch, NULL);
    for (long t = 0; t < program->term_count; ++t) {
        const hd_term *term = program->terms + t;
        if (term->kind != HD_ANCHOR_SPRING && term->kind != HD_BODY_SPRING)
            continue;
        const int ni = hd_int_columns(term->kind), nr = hd_real_columns(term->kind);
        for (long e = 0; e < term->count; ++e) {
            const long *i = term->ints + ni * e;
            const double *r = term->reals + nr * e;
            double hd_spring;
            if (term->kind == HD_ANCHOR_SPRING) {
                double rx, ry;
                hd_offset(scratch, i[0], r[0], r[1], &rx, &ry);
                hd_spring = hd_spring_energy(q[3 * i[0]] + rx - r[2], q[3 * i[0] + 1] + ry - r[3],
                                             r[4], r[5]);
            } else {
                const long a = i[0], b = i[1];
                double rax, ray, rbx, rby;
                hd_offset(scratch, a, r[0], r[1], &rax, &ray);
                hd_offset(scratch, b, r[2], r[3], &rbx, &rby);
                hd_spring = hd_spring_energy(q[3 * a] + rax - q[3 * b] - rbx,
                                             q[3 * a + 1] + ray - q[3 * b + 1] - rby, r[4], r[5]);
            }
            energy[unit[i[0]]] += hd_spring;
            excess[unit[i[0]]] += hd_spring;
        }
    }
}
