/* The response: hecker_dynamics/contact/solver.py's ContactPass.resolve, operation for
 * operation. Sequential impulses (the article series' collision impulse for each contact
 * with both bodies' mass and moment of inertia, accumulated and clamped, with Coulomb
 * friction), warm-started from the last step's impulses (the friction's by
 * HD_FRICTION_CARRY where a big island's passes ran out), two-point manifolds solved as
 * blocks, island by island, each with at most HD_WORK / (its units) passes (at least
 * HD_MIN_ITERATIONS and (its units) / HD_SETTLE, at most HD_MAX_ITERATIONS);
 * then the position change h (v' - v) of each body the impulses moved, and the position
 * correction of the overlap beyond HD_SLOP.
 *
 * Velocities live in a table of bodies + 1 rows of (vx, vy, omega): the last row is the
 * walls', which stays zero (an impulse on a wall is multiplied by its zero inverse mass,
 * as in Python).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact.h"
#include "coupled.h"
#include "rows.h"
#include "solver.h"

/* An arm (rx, ry) of body's part at the step's end carried back to the step's start by
 * the body's turn in the step: a vertex's with the body, a circle's centre with the body
 * and its offset from the centre along the normal kept (contact/solver.py:
 * ContactPass._carry_back). */
static HD_HOT void hd_carry_back(const hd_contact_model *m, long body, long part, double *rx,
                                 double *ry)
{
    const hd_part *p = m->parts + m->part_first[body] + part;
    double x = *rx, y = *ry, ox = 0.0, oy = 0.0;
    if (p->kind == HD_CIRCLE) {
        const double c = m->cos_sin[2 * body], s = m->cos_sin[2 * body + 1];
        const double *l = p->local;
        ox = x - (c * l[0] - s * l[1]);
        oy = y - (s * l[0] + c * l[1]);
        x = x - ox;
        y = y - oy;
    }
    const double c = m->turn_cos_sin[2 * body], s = m->turn_cos_sin[2 * body + 1];
    *rx = c * x - s * y + ox;
    *ry = s * x + c * y + oy;
}

/* The row's effective masses and approach speed for its arms (contact/solver.py:
 * ContactPass._row). */
static HD_HOT void hd_row_masses(hd_row *r, const double *reference)
{
    const double nx = r->nx, ny = r->ny;
    const double rna = r->rax * ny - r->ray * nx, rnb = r->rbx * ny - r->rby * nx;
    const double rta = -r->rax * nx - r->ray * ny, rtb = -r->rbx * nx - r->rby * ny;
    r->mass_n = 1.0 / (r->im_a + r->im_b + rna * rna * r->ii_a + rnb * rnb * r->ii_b);
    r->mass_t = 1.0 / (r->im_a + r->im_b + rta * rta * r->ii_a + rtb * rtb * r->ii_b);
    r->approach = hd_normal_velocity(reference + 3 * r->a, reference + 3 * r->b, r);
}

/* The solver row of contact c (contact/solver.py: ContactPass._prepare); `reference`: the
 * velocities the step's positions moved with; warm[low] to warm[end - 1]: its key's impulses. */
static void hd_prepare(hd_contact_model *m, const hd_contact *c, hd_row *r, double h,
                       const double *reference, long low, long end)
{
    const long wall = m->bodies;
    const long a = c->a >= 0 ? c->a : wall, b = c->b;
    const double *pa = m->poses + 3 * a, *pb = m->poses + 3 * b;
    r->a = a;
    r->b = b;
    r->nx = c->nx;
    r->ny = c->ny;
    r->im_a = c->a >= 0 ? m->inverse_mass[a] : 0.0;
    r->ii_a = c->a >= 0 ? m->inverse_inertia[a] : 0.0;
    r->im_b = m->inverse_mass[b];
    r->ii_b = m->inverse_inertia[b];
    const double rbx = c->px - pb[0], rby = c->py - pb[1];
    /* The arms where the step's new velocity moves the bodies from (docs/scenes.md); a
     * bounce keeps those it was found at. */
    r->rax = c->a >= 0 ? c->px - pa[0] : 0.0;
    r->ray = c->a >= 0 ? c->py - pa[1] : 0.0;
    r->rbx = rbx;
    r->rby = rby;
    if (c->a >= 0)
        hd_carry_back(m, a, c->key[2], &r->rax, &r->ray);
    hd_carry_back(m, b, c->key[3], &r->rbx, &r->rby);
    hd_row_masses(r, reference);
    const int bounces = c->depth > 0.0 && r->approach < -m->threshold;
    if (bounces) {
        r->rax = c->a >= 0 ? c->px - pa[0] : 0.0;
        r->ray = c->a >= 0 ? c->py - pa[1] : 0.0;
        r->rbx = rbx;
        r->rby = rby;
        hd_row_masses(r, reference);
    }
    /* An elastic contact's target is never above -e times its impact either (the work its
     * impulse would add to the method's energy). */
    double target = hd_min(r->approach + c->depth / h, 0.0);
    if (bounces || c->e != 0.0) {
        double impact = hd_normal_velocity(m->before + 3 * a, m->before + 3 * b, r);
        if (m->lead != 0.0)
            impact -= m->lead * (r->approach - impact);
        if (bounces)
            target = hd_max(target, -c->e * hd_min(impact, 0.0));
        else if (c->e != 0.0)
            target = hd_min(target, -c->e * impact);
    }
    r->target = target;
    r->carry = 1.0;
    r->slop = c->a >= 0 ? hd_min(m->slop[a], m->slop[b]) : m->slop[b];
    r->mu = c->mu;
    r->depth = c->depth;
    memcpy(r->key, c->key, sizeof r->key);
    r->points = c->points;
    hd_recall(m, low, end, rbx, rby, m->cos_sin[2 * b], m->cos_sin[2 * b + 1], &r->jn,
              &r->jt);
}

/* Move the bodies by the position correction's shifts (contact/solve.py: correct_positions). */
static void hd_apply_shifts(const hd_contact_model *m, double *q1)
{
    for (long b = 0; b < m->bodies; ++b) {
        const double *s = m->shift + 3 * b;
        if (m->touched[b] && (s[0] != 0.0 || s[1] != 0.0 || s[2] != 0.0 ||
                              isnan(s[0]) || isnan(s[1]) || isnan(s[2]))) {
            for (int i = 0; i < 3; ++i)
                q1[3 * b + i] += s[i];
        }
    }
}

int hd_resolve(hd_contact_model *m, double *q1, double *v1, const double *q0,
               const double *v0, double h)
{
    if (m->sleep)
        hd_hold(m, q1, v1, q0, v0);
    for (;;) {
        if (hd_detect(m, q1) < 0)
            return -1;
        if (!m->woken)
            break;
        hd_wake_marked(m);
    }
    const long count = m->contact_count, n = m->bodies;
    if (count == 0) {
        hd_coupled_store(m, 0);
        hd_keep_sleeping_warm(m);
        hd_doze(m, v1, 0, h);
        return 0;
    }
    /* The rows, then `count` doubles for the position correction's depths. */
    const long needed = count + (count * (long)sizeof(double)) / (long)sizeof(hd_row) + 1;
    if (needed > m->row_capacity) {
        hd_row *grown = realloc(m->rows, (size_t)needed * sizeof(hd_row));
        if (grown == NULL)
            return -1;
        m->rows = grown;
        hd_unit *units = realloc(m->units, (size_t)needed * sizeof(hd_unit));
        if (units == NULL)
            return -1;
        m->units = units;
        long *order = realloc(m->order, (size_t)(4 * needed + 1) * sizeof(long));
        if (order == NULL)
            return -1;
        m->order = order;
        m->unit_island = order + needed;
        m->island_start = order + 2 * needed;
        m->island_fill = order + 3 * needed + 1;
        m->row_capacity = needed;
        m->islands_known = 0;  /* the islands moved */
    }
    memset(m->touched, 0, (size_t)n * sizeof(int));
    for (long k = 0; k < count; ++k) {
        if (m->contacts[k].a >= 0)
            m->touched[m->contacts[k].a] = 1;
        m->touched[m->contacts[k].b] = 1;
    }
    if (m->joints != NULL && hd_couple(m) < 0)
        return -1;
    for (long b = 0; b < n; ++b) {
        if (!m->touched[b])
            continue;
        memcpy(m->poses + 3 * b, q1 + 3 * b, 3 * sizeof(double));
        memcpy(m->velocity + 3 * b, v1 + 3 * b, 3 * sizeof(double));
        memcpy(m->arrived + 3 * b, v1 + 3 * b, 3 * sizeof(double));
        memcpy(m->before + 3 * b, v0 + 3 * b, 3 * sizeof(double));
        hd_cos_sin(q0[3 * b + 2] - q1[3 * b + 2], m->turn_cos_sin + 2 * b);
    }
    memset(m->velocity + 3 * n, 0, 3 * sizeof(double));
    memset(m->before + 3 * n, 0, 3 * sizeof(double));
    memset(m->arrived + 3 * n, 0, 3 * sizeof(double));
    const double *reference = hd_coupled_reference(m);
    /* The impulses of the contact's key, where the last key found ended, and where the
     * contacts of the contact's key end. */
    long low = -1, end = -1, next = m->warm_awake, run = 0;
    for (long k = 0; k < count; ++k) {
        const hd_contact *c = m->contacts + k;
        if (k == run) {
            if (hd_find_warm(m, c->key, next, &low, &end) < 0)
                return -1;
            next = end < 0 ? next : end;
            run = k + c->points;
        }
        hd_prepare(m, c, m->rows + k, h, reference, low, end);
    }
    for (long k = 0; k < count; ++k) {  /* warm start, once every target is set */
        const hd_row *r = m->rows + k;
        hd_push(m->velocity + 3 * r->a, m->velocity + 3 * r->b, r,
                r->jn * r->nx - r->jt * r->ny, r->jn * r->ny + r->jt * r->nx);
    }
    memset(m->shift, 0, (size_t)(3 * (n + 1)) * sizeof(double));
    if (hd_solve_velocities(m, count, h, (double *)(m->rows + count)) < 0)
        return -1;
    hd_coupled_store(m, 1);
    if (hd_remember(m, count) < 0)
        return -1;
    for (long b = 0; b < n; ++b) {
        if (!m->touched[b])
            continue;
        const double *now = m->velocity + 3 * b, *was = m->arrived + 3 * b;
        if (now[0] == was[0] && now[1] == was[1] && now[2] == was[2])
            continue;
        for (int i = 0; i < 3; ++i) {
            q1[3 * b + i] = m->poses[3 * b + i] + h * (now[i] - reference[3 * b + i]);
            v1[3 * b + i] = now[i];
        }
    }
    hd_apply_shifts(m, q1);
    hd_doze(m, v1, count, h);
    return 0;
}
