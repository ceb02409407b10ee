/* The coloured solve of a big island (contact/islands.py: coloured): its units in colour order,
 * the last colour first, four two-point blocks of one colour at a time in SIMD lanes.
 *
 * A colour's units share no body but the walls' slot, whose velocity stays +0 (it is
 * only ever changed by a product with a zero inverse mass), so they can be solved in any
 * order, or at once, and give the bits the Python path's sequential sweep in colour order
 * gives; `largest` is a maximum of non-negative changes, which no order changes either.
 */
#ifndef HECKER_DYNAMICS_WIDE_H
#define HECKER_DYNAMICS_WIDE_H

#include "contact.h"

/* The constants of contact/islands.py: islands of at least HD_WIDE_UNITS units (and no
 * joint rows) are solved in colour order; HD_COLOURS colours at most, the units that fit
 * none last, one by one in their order. */
#define HD_WIDE_UNITS 64
#define HD_COLOURS 64
/* Smaller islands of at least HD_LEVEL_UNITS units (and no joint rows) go through the
 * lanes too, level by level (solve.c: hd_level_order): the same bits as their sequential
 * sweep; below it, packing the lanes costs more than they save. */
#define HD_LEVEL_UNITS 16
/* ... and only while such an island ran more than HD_LEVEL_PASSES passes the step before
 * (a settled pile converges in one, which costs less than packing the lanes). */
#define HD_LEVEL_PASSES 2
/* Islands of at least HD_CREW_UNITS units run their velocity passes and position
 * correction on two threads (crew.h) where the contact model's `threads` is 2: below it a
 * colour has a chunk or two, and handing them out costs more than the second core gains. */
#define HD_CREW_UNITS 256

struct hd_wide;

/* At most `passes` Gauss-Seidel passes over the island's `size` units (`members`, indices
 * into m->units, in island order, within m->order) in colour order (`levels`: a small
 * island's, in their order, a run of units that share no body at a time), until no impulse
 * changes a velocity by more than m->converged * scale, then the island's position
 * correction after a step of h into m->shift in the same order (`base`: a double per row,
 * for their depths); `wide`: how many islands this step solved here before it; `known`:
 * whether this step's islands are last step's, when its colours are kept from then; `ran`:
 * the passes run. 1 when the passes converged, 0 when they ran out, -1 out of memory. */
int hd_wide_solve(hd_contact_model *m, long wide, int known, int levels, const long *members,
                  long size, long passes, double scale, double h, double *base, long *ran);
void hd_wide_free(struct hd_wide *w);

#endif
