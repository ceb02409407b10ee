/* The parts of the contact response (hd_resolve in solver.c), one file per concept as
 * in hecker_dynamics/contact/: warm.c, islands.c, solve.c, sleep.c.
 */
#ifndef HECKER_DYNAMICS_SOLVER_H
#define HECKER_DYNAMICS_SOLVER_H

#include "contact.h"

/* warm.c (contact/warm.py). Where the impulses of `key` are, searching from `next`
 * (*low .. *end, -1 for none); -1 out of memory. */
int hd_find_warm(hd_contact_model *m, const long *key, long next, long *low, long *end);
/* The impulses of the nearest unused point within HD_MATCH among low .. end. */
void hd_recall(hd_contact_model *m, long low, long end, double rx, double ry, double c,
               double s, double *jn, double *jt);
/* Keep only the sleeping islands' impulses; returns how many. */
long hd_keep_sleeping_warm(hd_contact_model *m);
/* Keep the `count` rows' impulses after the sleeping islands'; -1 out of memory. */
int hd_remember(hd_contact_model *m, long count);

/* islands.c (contact/islands.py). The units of the `count` rows; returns their count. */
long hd_schedule(hd_contact_model *m, long count);
/* The units' islands into m->order and m->island_start; returns their count. */
long hd_islands(hd_contact_model *m, long units);
/* The union-find root of `body`'s set in `parent`, halving the path. */
long hd_root(long *parent, long body);
/* Whether the units are last step's (their islands kept); -1 out of memory. */
int hd_same_units(hd_contact_model *m, long units);

/* solve.c (contact/solve.py). The velocity passes and the position correction of the
 * `count` rows; -1 out of memory. */
int hd_solve_velocities(hd_contact_model *m, long count, double h, double *base);

/* sleep.c (contact/sleep.py). Sleeping bodies back at (q0, v0). */
void hd_hold(const hd_contact_model *m, double *q1, double *v1, const double *q0,
             const double *v0);
/* Wake the islands detection marked. */
void hd_wake_marked(hd_contact_model *m);
/* Rest times after a step of h; islands that rested long enough fall asleep. */
void hd_doze(hd_contact_model *m, double *v1, long count, double h);

#endif
