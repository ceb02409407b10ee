/* The arithmetic of the solver's rows (contact/rows.py: ContactRow, Block and the _solve_
 * functions), operation for operation, for solver.c's sequential passes and wide.c's
 * scalar remainder; always inlined, so each caller keeps its velocities in registers.
 */
#ifndef HECKER_DYNAMICS_ROWS_H
#define HECKER_DYNAMICS_ROWS_H

#include <math.h>

#include "contact.h"


/* (v_B + omega_B perp(r_B) - v_A - omega_A perp(r_A)) . n (contact/rows.py: normal_velocity). */
static HD_HOT double hd_normal_velocity(const double *va, const double *vb, const hd_row *r)
{
    return (vb[0] - vb[2] * r->rby - va[0] + va[2] * r->ray) * r->nx
           + (vb[1] + vb[2] * r->rbx - va[1] - va[2] * r->rax) * r->ny;
}

/* Impulse (px, py) at the contact: +P to body b, -P to body a (ContactRow.push). */
static HD_HOT void hd_push(double *va, double *vb, const hd_row *r, double px, double py)
{
    va[0] -= px * r->im_a;
    va[1] -= py * r->im_a;
    va[2] -= (r->rax * py - r->ray * px) * r->ii_a;
    vb[0] += px * r->im_b;
    vb[1] += py * r->im_b;
    vb[2] += (r->rbx * py - r->rby * px) * r->ii_b;
}

/* One contact's normal impulse, clamped at zero; returns the change of its normal
 * velocity (contact/rows.py: solve_normal). */
static HD_HOT double hd_solve_normal(hd_row *r, double *va, double *vb)
{
    const double jn = r->jn;
    const double new_n = hd_max(jn + (r->target - hd_normal_velocity(va, vb, r)) * r->mass_n, 0.0);
    hd_push(va, vb, r, (new_n - jn) * r->nx, (new_n - jn) * r->ny);
    r->jn = new_n;
    return fabs(new_n - jn) / r->mass_n;
}

/* One contact's tangent impulse within |jt| <= mu jn; returns the change of its tangent
 * velocity (contact/rows.py: solve_friction). */
static HD_HOT double hd_solve_friction(hd_row *r, double *va, double *vb)
{
    if (!(r->mu > 0.0))
        return 0.0;
    const double dvx = vb[0] - vb[2] * r->rby - va[0] + va[2] * r->ray;
    const double dvy = vb[1] + vb[2] * r->rbx - va[1] - va[2] * r->rax;
    const double jt = r->jt, bound = r->mu * r->jn;
    const double new_t = hd_min(hd_max(jt - (-dvx * r->ny + dvy * r->nx) * r->mass_t, -bound),
                                bound);
    hd_push(va, vb, r, -(new_t - jt) * r->ny, (new_t - jt) * r->nx);
    r->jt = new_t;
    return fabs(new_t - jt) / r->mass_t;
}

/* The two normal impulses of a two-point manifold at once, as the 2 x 2 linear
 * complementarity problem, then each point's friction (contact/rows.py: Block.solve). */
static inline double hd_solve_block(const hd_unit *u, hd_row *one, hd_row *two, double *va,
                                    double *vb)
{
    const double old1 = one->jn, old2 = two->jn;
    const double b1 =
        hd_normal_velocity(va, vb, one) - one->target - (u->k11 * old1 + u->k12 * old2);
    const double b2 =
        hd_normal_velocity(va, vb, two) - two->target - (u->k12 * old1 + u->k22 * old2);
    double x1 = -(u->inv11 * b1 + u->inv12 * b2);
    double x2 = -(u->inv12 * b1 + u->inv22 * b2);
    if (!(x1 >= 0.0 && x2 >= 0.0)) {
        x1 = -one->mass_n * b1;
        x2 = 0.0;
        if (!(x1 >= 0.0 && u->k12 * x1 + b2 >= 0.0)) {
            x1 = 0.0;
            x2 = -two->mass_n * b2;
            if (!(x2 >= 0.0 && u->k12 * x2 + b1 >= 0.0)) {
                x1 = 0.0;
                x2 = 0.0;
                if (!(b1 >= 0.0 && b2 >= 0.0)) {
                    x1 = old1;
                    x2 = old2;
                }
            }
        }
    }
    hd_push(va, vb, one, (x1 - old1) * one->nx, (x1 - old1) * one->ny);
    hd_push(va, vb, two, (x2 - old2) * two->nx, (x2 - old2) * two->ny);
    one->jn = x1;
    two->jn = x2;
    double change = hd_max(fabs(x1 - old1) / one->mass_n, fabs(x2 - old2) / two->mass_n);
    change = hd_max(change, hd_solve_friction(one, va, vb));
    return hd_max(change, hd_solve_friction(two, va, vb));
}

/* One unit's impulses: its block, or its point's normal then tangent impulse; returns
 * the largest velocity change (contact/solve.py: solve_velocities). */
static HD_HOT double hd_solve_unit(const hd_unit *u, hd_row *rows, double *velocity)
{
    hd_row *r = rows + u->first;
    double *va = velocity + 3 * r->a, *vb = velocity + 3 * r->b;
    if (u->pair)
        return hd_solve_block(u, r, r + 1, va, vb);
    const double change = hd_solve_normal(r, va, vb);
    return hd_max(change, hd_solve_friction(r, va, vb));
}

/* Row r's depth after the velocity change beyond its slop, depth - h (v_n' - v_n) - slop
 * (x - slop <= 0 exactly when x <= slop; contact/solve.py: correct_positions). */
static HD_HOT double hd_depth_after(const hd_contact_model *m, const hd_row *r, double h)
{
    return r->depth - h * (hd_normal_velocity(m->velocity + 3 * r->a, m->velocity + 3 * r->b, r)
                           - r->approach)
           - r->slop;
}

/* Whether the deepest of the rows of the units `members` (size of them), their
 * hd_depth_after in base[row], is beyond its slop, the deepest found as Python's max()
 * finds it in the order swept, whose first row is `first` (contact/solve.py:
 * correct_positions). That max keeps its first value if it is NaN and else is the largest
 * of the values that are not NaN (or one of two zeros, alike against HD_SLOP) in any
 * order, so the members are taken in their order in memory. */
static inline int hd_deepest_beyond(const hd_contact_model *m, const long *members, long size,
                                    long first, const double *base)
{
    double deepest = base[first];
    for (long k = 0; k < size; ++k) {
        const hd_unit *u = m->units + members[k];
        for (long i = u->first; i <= u->first + u->pair; ++i)
            deepest = hd_max(deepest, base[i]);
    }
    return !(deepest <= 0.0);
}

/* The rows of the units `members` (size of them): hd_depth_after into base[row], then
 * hd_deepest_beyond. */
static inline int hd_depths_after(const hd_contact_model *m, const long *members, long size,
                                  long first, double h, double *base)
{
    for (long k = 0; k < size; ++k) {
        const hd_unit *u = m->units + members[k];
        for (long i = u->first; i <= u->first + u->pair; ++i)
            base[i] = hd_depth_after(m, m->rows + i, h);
    }
    return hd_deepest_beyond(m, members, size, first, base);
}

/* One pass of the position correction over a unit's rows: each moves its bodies' shifts
 * apart along the normal by a fraction of the excess of its depth beyond its slop, `base`
 * (contact/solve.py: correct_positions). */
static HD_HOT void hd_correct_unit(const hd_unit *u, const hd_row *rows, const double *base,
                                   double *shift)
{
    for (long i = u->first; i <= u->first + u->pair; ++i) {
        const hd_row *r = rows + i;
        double *sa = shift + 3 * r->a, *sb = shift + 3 * r->b;
        const double excess = base[i] - hd_normal_velocity(sa, sb, r);
        if (excess <= 0.0)
            continue;
        const double amount = hd_min(HD_CORRECTION * excess, HD_MAX_CORRECTION) * r->mass_n;
        hd_push(sa, sb, r, amount * r->nx, amount * r->ny);
    }
}

#endif
