/* The solver's units and islands (hecker_dynamics/contact/islands.py): two-point
 * manifolds made blocks, then the units grouped by the bodies they join, by union-find.
 */
#include <stdlib.h>

#include "contact.h"
#include "coupled.h"
#include "solver.h"

/* The block of rows one and two, or 0 where K is too ill-conditioned (contact/islands.py:
 * make_block). */
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
 * one normal), else single rows (contact/islands.py: schedule, whose runs of one key are the
 * rows' `points`); returns their count. */
long hd_schedule(hd_contact_model *m, long count)
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

/* Group the units by island (contact/islands.py: islands): m->order holds the units' indices,
 * each island's together and in their order, island i from m->island_start[i] to
 * [i + 1]; returns the number of islands. */
long hd_islands(hd_contact_model *m, long units)
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
int hd_same_units(hd_contact_model *m, long units)
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
