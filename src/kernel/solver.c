/* The response: hecker_dynamics/contact/solver.py's ContactPass.resolve, operation for
 * operation. Sequential impulses (the article series' collision impulse for each contact
 * with both bodies' mass and moment of inertia, accumulated and clamped, with Coulomb
 * friction), warm-started from the last step's impulses, two-point manifolds solved as
 * blocks, island by island, each with at most HD_WORK / (its units) passes (within
 * HD_MIN_ITERATIONS .. HD_MAX_ITERATIONS);
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
#include "wide.h"

static int hd_same_key(const long *k, const long *l)
{
    return k[0] == l[0] && k[1] == l[1] && k[2] == l[2] && k[3] == l[3];
}

static int hd_key_order(const long *k, const long *l)
{
    for (int i = 0; i < 4; ++i)
        if (k[i] != l[i])
            return k[i] < l[i] ? -1 : 1;
    return 0;
}

/* By key, then by position in the list (qsort is not stable: `used` holds it meanwhile). */
static int hd_by_key(const void *p, const void *q)
{
    const hd_warm *u = p, *w = q;
    const int order = hd_key_order(u->key, w->key);
    return order ? order : (u->used > w->used) - (u->used < w->used);
}

static unsigned long hd_hash_key(const long *k)
{
    unsigned long h = 1469598103934665603UL;
    for (int i = 0; i < 4; ++i)
        h = (h ^ (unsigned long)k[i]) * 1099511628211UL;
    return h ^ (h >> 29);
}

/* The table from each key to its first warm-start impulse: the impulses of one key are
 * contiguous (one pair of parts is detected at once); -1 out of memory. */
static int hd_index_warm(hd_contact_model *m)
{
    long size = 16;
    while (size < 2 * m->warm_count)
        size *= 2;
    if (size > m->warm_table_size) {
        long *grown = realloc(m->warm_table, (size_t)size * sizeof(long));
        if (grown == NULL)
            return -1;
        m->warm_table = grown;
        m->warm_table_size = size;
    }
    size = m->warm_table_size;
    for (long i = 0; i < size; ++i)
        m->warm_table[i] = -1;
    for (long k = 0; k < m->warm_count; ++k) {
        if (k > 0 && hd_same_key(m->warm[k - 1].key, m->warm[k].key))
            continue;
        unsigned long slot = hd_hash_key(m->warm[k].key) & (unsigned long)(size - 1);
        while (m->warm_table[slot] >= 0)
            slot = (slot + 1) & (unsigned long)(size - 1);
        m->warm_table[slot] = k;
    }
    m->warm_indexed = 1;
    return 0;
}

void hd_set_warm(hd_contact_model *m)
{
    for (long i = 0; i < m->warm_count; ++i)
        m->warm[i].used = (int)i;
    qsort(m->warm, (size_t)m->warm_count, sizeof(hd_warm), hd_by_key);
    for (long i = 0; i < m->warm_count; ++i)
        m->warm[i].used = 0;
    m->warm_indexed = m->warm_awake = 0;
}

/* How far hd_find_warm looks from where the last key's impulses ended before it asks the
 * table. */
#define HD_NEAR 64

/* The first impulse of `key` within HD_NEAR of warm[next], a run's first, nearest first;
 * -1 if none. */
static long hd_near_warm(const hd_contact_model *m, const long *key, long next)
{
    for (long d = 0; d <= HD_NEAR; ++d) {
        if (next + d < m->warm_count && hd_same_key(m->warm[next + d].key, key))
            return next + d;  /* a run's first: warm[next + d - 1] was not the key's */
        long i = next - 1 - d;
        if (i >= 0 && hd_same_key(m->warm[i].key, key)) {
            while (i > 0 && hd_same_key(m->warm[i - 1].key, key))  /* from the run's last */
                i -= 1;
            return i;
        }
    }
    return -1;
}

/* The warm-start impulses of `key`, warm[*low] to warm[*end - 1] (none: *low = *end =
 * -1); `next`: where the last key's ended (or the first of last step's contacts' starts);
 * -1 out of memory.
 *
 * Each key's impulses are one run (its pair of parts is detected once a step, and no
 * awake contact has a sleeping island's key), so a run of `key` found anywhere is the one
 * the table holds. The contacts come in detection order, and last step's impulses were
 * kept in the order of its contacts, after the sleeping islands', so most often the run
 * starts at `next`, or a few runs off where bodies swapped places in the sweep's order:
 * then neither the table nor a hash is needed. */
static int hd_find_warm(hd_contact_model *m, const long *key, long next, long *low, long *end)
{
    *low = *end = -1;
    if (m->warm_count == 0)
        return 0;
    *low = hd_near_warm(m, key, next);
    if (*low < 0) {
        if (!m->warm_indexed && hd_index_warm(m) < 0)
            return -1;
        const unsigned long mask = (unsigned long)(m->warm_table_size - 1);
        for (unsigned long slot = hd_hash_key(key) & mask; m->warm_table[slot] >= 0;
             slot = (slot + 1) & mask) {
            if (hd_same_key(m->warm[m->warm_table[slot]].key, key)) {
                *low = m->warm_table[slot];
                break;
            }
        }
        if (*low < 0)
            return 0;
    }
    *end = *low + 1;
    while (*end < m->warm_count && hd_same_key(m->warm[*end].key, key))
        *end += 1;
    return 0;
}

/* Last step's impulses of the contact nearest this point among warm[low] to
 * warm[end - 1], its key's, if within HD_MATCH, each used once (solver.py: _recall; `<=`:
 * the last of equally near ones); (c, s) the cosine and sine of body b's angle. */
static void hd_recall(hd_contact_model *m, long low, long end, double rx, double ry, double c,
                   double s, double *jn, double *jt)
{
    *jn = 0.0;
    *jt = 0.0;
    if (low < 0)
        return;
    const double lx = c * rx + s * ry, ly = -s * rx + c * ry;
    long best = -1;
    double nearest = HD_MATCH * HD_MATCH;
    for (long i = low; i < end; ++i) {
        if (m->warm[i].used)
            continue;
        const double d = pow(m->warm[i].lx - lx, 2.0) + pow(m->warm[i].ly - ly, 2.0);
        if (d <= nearest) {
            best = i;
            nearest = d;
        }
    }
    if (best < 0)
        return;
    m->warm[best].used = 1;
    *jn = m->warm[best].jn;
    *jt = m->warm[best].jt;
}

/* The solver row of contact c (solver.py: _prepare); `reference`: the velocities the
 * step's positions moved with; warm[low] to warm[end - 1]: its key's impulses. */
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
    r->rax = c->a >= 0 ? c->px - pa[0] : 0.0;
    r->ray = c->a >= 0 ? c->py - pa[1] : 0.0;
    r->rbx = c->px - pb[0];
    r->rby = c->py - pb[1];
    const double nx = c->nx, ny = c->ny;
    const double rna = r->rax * ny - r->ray * nx, rnb = r->rbx * ny - r->rby * nx;
    const double rta = -r->rax * nx - r->ray * ny, rtb = -r->rbx * nx - r->rby * ny;
    r->mass_n = 1.0 / (r->im_a + r->im_b + rna * rna * r->ii_a + rnb * rnb * r->ii_b);
    r->mass_t = 1.0 / (r->im_a + r->im_b + rta * rta * r->ii_a + rtb * rtb * r->ii_b);
    r->approach = hd_normal_velocity(reference + 3 * a, reference + 3 * b, r);
    double target = hd_min(r->approach + c->depth / h, 0.0);
    if (c->depth > 0.0 && r->approach < -m->threshold) {
        const double impact = hd_normal_velocity(m->before + 3 * a, m->before + 3 * b, r);
        target = hd_max(target, -c->e * hd_min(impact, 0.0));
    }
    r->target = target;
    r->mu = c->mu;
    r->depth = c->depth;
    memcpy(r->key, c->key, sizeof r->key);
    r->points = c->points;
    hd_recall(m, low, end, r->rbx, r->rby, m->cos_sin[2 * b], m->cos_sin[2 * b + 1], &r->jn,
           &r->jt);
}

/* The block of rows one and two, or 0 where K is too ill-conditioned (solver.py: _block). */
static int hd_make_block(const hd_row *one, const hd_row *two, hd_unit *u)
{
    const double nx = one->nx, ny = one->ny;
    const double rna1 = one->rax * ny - one->ray * nx, rnb1 = one->rbx * ny - one->rby * nx;
    const double rna2 = two->rax * ny - two->ray * nx, rnb2 = two->rbx * ny - two->rby * nx;
    const double mass = one->im_a + one->im_b;
    const double k11 = mass + rna1 * rna1 * one->ii_a + rnb1 * rnb1 * one->ii_b;
    const double k22 = mass + rna2 * rna2 * one->ii_a + rnb2 * rnb2 * one->ii_b;
    const double k12 = mass + rna1 * rna2 * one->ii_a + rnb1 * rnb2 * one->ii_b;
    const double determinant = k11 * k22 - k12 * k12;
    if (!(k11 * k11 < HD_MAX_CONDITION * determinant))
        return 0;
    const double inverse = 1.0 / determinant;
    u->k11 = k11;
    u->k12 = k12;
    u->k22 = k22;
    u->inv11 = k22 * inverse;
    u->inv12 = -k12 * inverse;
    u->inv22 = k11 * inverse;
    return 1;
}

/* The solver's units in row order: a block for each manifold of exactly two points (with
 * one normal), else single rows (solver.py: _schedule, whose runs of one key are the
 * rows' `points`); returns their count. */
static long hd_schedule(hd_contact_model *m, long count)
{
    long units = 0;
    for (long k = 0; k < count;) {
        const hd_row *r = m->rows + k;
        const long end = k + r->points;
        hd_unit *u = m->units + units;
        if (r->points == 2 && r->nx == r[1].nx && r->ny == r[1].ny && hd_make_block(r, r + 1, u)) {
            u->first = k;
            u->pair = 1;
            units += 1;
        } else {
            for (long i = k; i < end; ++i) {
                m->units[units].first = i;
                m->units[units].pair = 0;
                units += 1;
            }
        }
        k = end;
    }
    return units;
}

static long hd_root_of(long *parent, long body)
{
    while (parent[body] != body) {
        parent[body] = parent[parent[body]];
        body = parent[body];
    }
    return body;
}

long hd_root(long *parent, long body) { return hd_root_of(parent, body); }

/* Group the units by island (solver.py: _islands): m->order holds the units' indices,
 * each island's together and in their order, island i from m->island_start[i] to
 * [i + 1]; returns the number of islands. */
static long hd_islands(hd_contact_model *m, long units)
{
    const long wall = m->bodies;
    long *parent = m->parent, *island = m->island_of;
    hd_coupled_reset(m, parent, island);
    for (long k = 0; k < units; ++k) {
        const hd_row *r = m->rows + m->units[k].first;
        parent[r->a] = r->a;
        parent[r->b] = r->b;
        island[r->a] = island[r->b] = -1;
    }
    for (long k = 0; k < units; ++k) {
        const hd_row *r = m->rows + m->units[k].first;
        if (r->a == wall)
            continue;
        const long ra = hd_root_of(parent, r->a), rb = hd_root_of(parent, r->b);
        if (ra != rb)
            parent[ra > rb ? ra : rb] = ra > rb ? rb : ra;
    }
    hd_coupled_join(m, parent);
    long count = 0;
    for (long k = 0; k < units; ++k) {  /* islands numbered by first unit; their sizes */
        const long root = hd_root_of(parent, m->rows[m->units[k].first].b);
        if (island[root] < 0) {
            island[root] = count;
            m->island_start[++count] = 0;
        }
        m->unit_island[k] = island[root];
        m->island_start[island[root] + 1] += 1;
    }
    m->island_start[0] = 0;
    for (long i = 0; i < count; ++i)
        m->island_start[i + 1] += m->island_start[i];
    for (long i = 0; i < count; ++i)
        m->island_fill[i] = m->island_start[i];
    for (long k = 0; k < units; ++k)
        m->order[m->island_fill[m->unit_island[k]]++] = k;
    return hd_coupled_islands(m, parent, island, count) < 0 ? -1 : count;
}

/* Whether the `units` are last step's, each with the same bodies and pair flag, so that
 * their islands and the big islands' colours, functions of those alone, are still in
 * m->order and wide.h's memory; keeps them as the units seen. Never with joint rows,
 * which join islands too. -1 out of memory. */
static int hd_same_units(hd_contact_model *m, long units)
{
    int same = m->islands_known && units == m->seen_count;
    m->islands_known = 0;
    if (m->joints != NULL)
        return 0;
    if (units > m->seen_capacity) {
        long *grown = realloc(m->seen, (size_t)(2 * units) * sizeof(long));
        if (grown == NULL)
            return -1;
        m->seen = grown;
        m->seen_capacity = units;
    }
    for (long k = 0; k < units; ++k) {
        const hd_unit *u = m->units + k;
        const hd_row *r = m->rows + u->first;
        const long tail = 2 * r->b + u->pair;
        if (!same || m->seen[2 * k] != r->a || m->seen[2 * k + 1] != tail) {
            same = 0;
            m->seen[2 * k] = r->a;
            m->seen[2 * k + 1] = tail;
        }
    }
    m->seen_count = units;
    return same;
}

/* Gauss-Seidel passes over the units island by island, each until no impulse changes a
 * velocity by more than HD_CONVERGED relative to its fastest body, or HD_WORK / (its
 * units) passes, but at least HD_MIN_ITERATIONS and at most HD_MAX_ITERATIONS
 * (solver.py: _solve_velocities); then each island's position correction into m->shift,
 * in the order its units were swept (solver.py: _correct_positions), with `base` for
 * the rows' depths. */
static int hd_solve_velocities(hd_contact_model *m, long count, double h, double *base)
{
    const long units = hd_schedule(m, count);
    const int same = hd_same_units(m, units);
    if (same < 0)
        return -1;
    if (!same)
        m->island_count = hd_islands(m, units);
    const long count_islands = m->island_count;
    if (count_islands < 0)
        return -1;
    long wide = 0;  /* the islands solved in colour order so far */
    for (long i = 0; i < count_islands; ++i) {
        const long *members = m->order + m->island_start[i];
        const long size = m->island_start[i + 1] - m->island_start[i];
        hd_coupled_warm_start(m, i);
        double fastest = 0.0;
        for (long k = 0; k < size; ++k) {
            const hd_row *r = m->rows + m->units[members[k]].first;
            for (int c = 0; c < 3; ++c) {
                fastest = hd_max(hd_max(fastest, fabs(m->velocity[3 * r->a + c])),
                                 fabs(m->velocity[3 * r->b + c]));
            }
        }
        const double scale = 1.0 + hd_coupled_fastest(m, i, fastest);
        const long coupled = hd_coupled_size(m, i);
        long passes = HD_WORK / (size + coupled);
        passes = passes < HD_MIN_ITERATIONS ? HD_MIN_ITERATIONS : passes;
        passes = passes > HD_MAX_ITERATIONS ? HD_MAX_ITERATIONS : passes;
        if (size >= HD_WIDE_UNITS && coupled == 0) {
            if (hd_wide_solve(m, wide++, same, members, size, passes, scale, h, base) < 0)
                return -1;
            continue;
        }
        for (long iteration = 0; iteration < passes; ++iteration) {
            double largest = 0.0;
            for (long k = 0; k < size; ++k)
                largest = hd_max(largest, hd_solve_unit(m->units + members[k], m->rows, m->velocity));
            largest = hd_coupled_sweep(m, i, largest);
            if (largest <= HD_CONVERGED * scale)
                break;
        }
        if (!hd_depths_after(m, members, size, h, base))
            continue;
        for (int iteration = 0; iteration < HD_POSITION_ITERATIONS; ++iteration) {
            for (long k = 0; k < size; ++k)
                hd_correct_unit(m->units + members[k], m->rows, base, m->shift);
        }
    }
    m->islands_known = m->joints == NULL;
    return 0;
}

/* Keep only the warm-start impulses of the sleeping islands' contacts, in their order
 * (solver.py: _sleeping_warm); returns how many. */
static long hd_keep_sleeping_warm(hd_contact_model *m)
{
    long kept = 0;
    for (long k = 0; m->sleep && k < m->warm_count; ++k) {
        if (m->island[m->warm[k].key[1]] < 0)
            continue;
        if (kept != k)  /* while none was dropped each stays in place */
            m->warm[kept] = m->warm[k];
        m->warm[kept].used = 0;
        kept += 1;
    }
    if (kept != m->warm_count)
        m->warm_indexed = 0;
    m->warm_count = m->warm_awake = kept;
    return kept;
}

/* Keep each contact's impulses with its point in body b's axes, after those of the
 * sleeping islands (solver.py: _remember). */
static int hd_remember(hd_contact_model *m, long count)
{
    const long kept = hd_keep_sleeping_warm(m);
    if (kept + count > m->warm_capacity) {
        hd_warm *grown = realloc(m->warm, (size_t)(kept + count) * sizeof(hd_warm));
        if (grown == NULL)
            return -1;
        m->warm = grown;
        m->warm_capacity = kept + count;
    }
    for (long k = 0; k < count; ++k) {
        const hd_row *r = m->rows + k;
        const double c = m->cos_sin[2 * r->b], s = m->cos_sin[2 * r->b + 1];
        hd_warm *w = m->warm + kept + k;
        memcpy(w->key, r->key, sizeof w->key);
        w->lx = c * r->rbx + s * r->rby;
        w->ly = -s * r->rbx + c * r->rby;
        w->jn = r->jn;
        w->jt = r->jt;
        w->used = 0;
    }
    m->warm_count = kept + count;
    m->warm_indexed = 0;
    return 0;
}

/* Put the sleeping bodies back at (q0, v0) (solver.py: _awake_contacts). */
static void hd_hold(const hd_contact_model *m, double *q1, double *v1, const double *q0,
                 const double *v0)
{
    for (long b = 0; b < m->bodies; ++b) {
        if (m->island[b] < 0)
            continue;
        memcpy(q1 + 3 * b, q0 + 3 * b, 3 * sizeof(double));
        memcpy(v1 + 3 * b, v0 + 3 * b, 3 * sizeof(double));
    }
}

/* Wake the islands detection marked (solver.py: _wake). */
static void hd_wake_marked(hd_contact_model *m)
{
    for (long b = 0; b < m->bodies; ++b) {
        if (m->island[b] >= 0 && m->wake[m->island[b]]) {
            m->island[b] = -1;
            m->rested[b] = 0.0;
        }
    }
    memset(m->wake, 0, (size_t)(m->bodies + 1) * sizeof(int));
    m->woken = 0;
}

/* The rest times of the awake bodies after a step of h, and sleep, with zero velocity, for
 * each island of awake bodies (joined by the `count` rows) whose every body has rested
 * HD_TIME_TO_SLEEP (solver.py: _doze). */
static void hd_doze(hd_contact_model *m, double *v1, long count, double h)
{
    if (!m->sleep)
        return;
    const long n = m->bodies, wall = m->bodies;
    long *parent = m->parent;
    double *shortest = m->shift;
    for (long b = 0; b < n; ++b) {
        parent[b] = b;
        shortest[b] = INFINITY;
    }
    for (long k = 0; k < count; ++k) {
        const hd_row *r = m->rows + k;
        if (r->a == wall)
            continue;
        const long ra = hd_root_of(parent, r->a), rb = hd_root_of(parent, r->b);
        if (ra != rb)
            parent[ra > rb ? ra : rb] = ra > rb ? rb : ra;
    }
    for (long b = 0; b < n; ++b) {
        if (m->island[b] >= 0)
            continue;
        const double *v = v1 + 3 * b;
        const int resting = m->calm[b] && sqrt(v[0] * v[0] + v[1] * v[1])
                                            + m->reach[b] * fabs(v[2]) <= HD_SLEEP_SPEED;
        m->rested[b] = resting ? m->rested[b] + h : 0.0;
        const long r = hd_root_of(parent, b);
        shortest[r] = hd_min(shortest[r], m->rested[b]);
    }
    for (long b = 0; b < n; ++b) {
        if (m->island[b] >= 0)
            continue;
        const long r = hd_root_of(parent, b);
        if (shortest[r] >= HD_TIME_TO_SLEEP) {
            m->island[b] = r;
            v1[3 * b] = v1[3 * b + 1] = v1[3 * b + 2] = 0.0;
        }
    }
}

/* Move the bodies by the position correction's shifts (solver.py: _correct_positions). */
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
