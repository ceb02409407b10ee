/* The velocity solve and the position correction (hecker_dynamics/contact/solve.py):
 * Gauss-Seidel passes island by island over the units of islands.c, the big islands'
 * through wide.c's lanes in colour order, a settling small island's through them level by
 * level, with the arithmetic of rows.h.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "contact.h"
#include "coupled.h"
#include "rows.h"
#include "simd.h"
#include "solver.h"
#include "wide.h"

/* The rows of a big island (solved in colour order) whose passes ran out before it
 * converged: each keeps its friction by HD_FRICTION_CARRY for the next step's warm start
 * (contact/solve.py: solve_velocities). */
static void hd_carry_friction(hd_contact_model *m, const long *members, long size)
{
    for (long k = 0; k < size; ++k) {
        const hd_unit *u = m->units + members[k];
        for (long i = u->first; i <= u->first + u->pair; ++i)
            m->rows[i].carry = HD_FRICTION_CARRY;
    }
}

/* Put the `size` units `members` of a small island (fewer than HD_WIDE_UNITS) in the order
 * of their levels, each level's in their order: a unit's level is one past the last level
 * of the units before it that share a body with it (the walls' slot is none: its velocity
 * stays +0, wide.h). Units of a body keep their order, so only units that share no body
 * trade places, and those commute: a pass in the new order gives the bits of a pass in
 * the old, and so does the largest change, a maximum of non-negative changes (a NaN
 * counts for none either way). A level's units follow each other, so that the CPU
 * overlaps their chains of operations; sorting twice gives the order sorting once gives. */
static void hd_level_order(const hd_contact_model *m, long *members, long size)
{
    const long wall = m->bodies;
    long a[HD_WIDE_UNITS], b[HD_WIDE_UNITS], level[HD_WIDE_UNITS], sorted[HD_WIDE_UNITS];
    long count[HD_WIDE_UNITS + 1] = {0};
    for (long k = 0; k < size; ++k) {
        const hd_row *r = m->rows + m->units[members[k]].first;
        a[k] = r->a;
        b[k] = r->b;
        level[k] = 0;
        for (long j = 0; j < k; ++j) {
            const int shared = (a[k] != wall && (a[k] == a[j] || a[k] == b[j])) ||
                               b[k] == a[j] || b[k] == b[j];
            if (shared && level[j] >= level[k])
                level[k] = level[j] + 1;
        }
        count[level[k] + 1] += 1;
    }
    for (long l = 0; l < size; ++l)
        count[l + 1] += count[l];
    for (long k = 0; k < size; ++k)
        sorted[count[level[k]]++] = members[k];
    memcpy(members, sorted, (size_t)size * sizeof(long));
}

/* Gauss-Seidel passes over the units island by island, each until no impulse changes a
 * velocity by more than m->converged relative to its fastest body, or HD_WORK / (its
 * units) passes, but at least HD_MIN_ITERATIONS and (its units) / HD_SETTLE and at most
 * HD_MAX_ITERATIONS
 * (contact/solve.py: solve_velocities); then each island's position correction into m->shift,
 * in the order its units were swept (contact/solve.py: correct_positions), with `base` for
 * the rows' depths. A small island of at least HD_LEVEL_UNITS units goes through wide.c's
 * lanes a level at a time (wide.h) while last step's such islands needed more than
 * HD_LEVEL_PASSES passes, else one unit at a time: either way with the bits of its
 * sequential sweep, so the choice, made from last step, changes no bit. */
int hd_solve_velocities(hd_contact_model *m, long count, double h, double *base)
{
    const long units = hd_schedule(m, count);
    const int same_units = hd_same_units(m, units);
    if (same_units < 0)
        return -1;
    /* Small islands through the lanes while the last step's needed passes; the colours
     * kept in wide.h are only this step's where last step took the same way. */
    const int level_lanes = HD_VECTORS && m->level_passes > HD_LEVEL_PASSES;
    const int same = same_units && level_lanes == m->level_lanes;
    m->level_lanes = level_lanes;
    m->level_passes = 0;
    if (!same_units)
        m->island_count = hd_islands(m, units);
    const long count_islands = m->island_count;
    if (count_islands < 0)
        return -1;
    long wide = 0;  /* the islands solved in colour order so far */
    for (long i = 0; i < count_islands; ++i) {
        long *members = m->order + m->island_start[i];
        const long size = m->island_start[i + 1] - m->island_start[i];
        if (!same_units && size < HD_WIDE_UNITS && hd_coupled_size(m, i) == 0)
            hd_level_order(m, members, size);
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
        const long settle = (size + coupled) / HD_SETTLE;
        passes = passes < settle ? settle : passes;
        passes = passes > HD_MAX_ITERATIONS ? HD_MAX_ITERATIONS : passes;
        long ran = 0;
        if (size >= HD_WIDE_UNITS && coupled == 0) {
            const int converged = hd_wide_solve(m, wide++, same, 0, members, size, passes,
                                                scale, h, base, &ran);
            if (converged < 0)
                return -1;
            if (!converged)
                hd_carry_friction(m, members, size);
            continue;
        }
        const int levels = size >= HD_LEVEL_UNITS && coupled == 0;
        if (levels && level_lanes) {
            if (hd_wide_solve(m, wide++, same, 1, members, size, passes, scale, h, base,
                              &ran) < 0)
                return -1;
            m->level_passes = ran > m->level_passes ? ran : m->level_passes;
            continue;
        }
        for (long iteration = 0; iteration < passes; ++iteration) {
            double largest = 0.0;
            ran += 1;
            for (long k = 0; k < size; ++k)
                largest = hd_max(largest,
                                 hd_solve_unit(m->units + members[k], m->rows, m->velocity));
            largest = hd_coupled_sweep(m, i, largest);
            if (largest <= m->converged * scale)
                break;
        }
        if (levels)
            m->level_passes = ran > m->level_passes ? ran : m->level_passes;
        if (!hd_depths_after(m, members, size, m->units[members[0]].first, h, base))
            continue;
        for (int iteration = 0; iteration < HD_POSITION_ITERATIONS; ++iteration) {
            for (long k = 0; k < size; ++k)
                hd_correct_unit(m->units + members[k], m->rows, base, m->shift);
        }
    }
    m->islands_known = m->joints == NULL;
    return 0;
}
