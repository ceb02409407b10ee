/* Joint rows inside the contact solve: hecker_dynamics/contact/coupled.py (and the parts of
 * JointPass.contact_units, settled_velocities and take_extra it uses), repeated operation
 * for operation and so bit for bit.
 *
 * When hd_resolve's model has a joint pass (m->joints, set by its caller for the call),
 * the joint pass's last velocity rows but the soft ones become units of the contact solve
 * (hd_coupled_row), swept after the contact units of each island that holds one of their
 * bodies; their extra impulses go back into the joint pass's impulses afterwards.
 */
#ifndef HECKER_DYNAMICS_COUPLED_H
#define HECKER_DYNAMICS_COUPLED_H

#include "contact.h"
#include "joint.h"

/* contact/coupled.py: JointUnit, on the contact model's body indices. */
typedef struct {
    long slot;  /* the joint pass's row */
    int count;
    long body[4];
    double j[4][3], d[4][3];  /* J and M^-1 J^T per body */
    double mass, target, lower, upper, extra;
} hd_coupled_row;

typedef struct hd_coupled {
    long count, capacity, bodies;
    hd_coupled_row *rows;
    long *island;            /* per row: its contact island, or -1 */
    long *order, *start;     /* the rows island by island: island i's at start[i] .. [i + 1] */
    double *reference;       /* (bodies + 1) x 3: the velocities the positions moved with */
} hd_coupled;

/* The joint pass's rows as units (JointPass.contact_units), the touched flags of their
 * bodies set; -1 out of memory. */
int hd_couple(hd_contact_model *m);
/* The velocities the step's positions moved with: m->arrived, but for the jointed bodies
 * their velocity before the joint pass's velocity stage (ContactPass.resolve: moved). */
const double *hd_coupled_reference(hd_contact_model *m);
/* Islands (solver.c: hd_islands): before the contacts' union-find, the rows' bodies as sets
 * of their own; after it, the rows' joins; after the numbering of `count` islands, each
 * row's island. */
void hd_coupled_reset(hd_contact_model *m, long *parent, long *island);
void hd_coupled_join(hd_contact_model *m, long *parent);
int hd_coupled_islands(hd_contact_model *m, long *parent, const long *island, long count);
/* Island i: its rows' count; their warm start; the fastest velocity component of their
 * bodies with `fastest`; one sweep of its rows, returning the largest change with
 * `largest` (contact/solve.py: solve_velocities). */
long hd_coupled_size(const hd_contact_model *m, long i);
void hd_coupled_warm_start(hd_contact_model *m, long i);
double hd_coupled_fastest(const hd_contact_model *m, long i, double fastest);
double hd_coupled_sweep(hd_contact_model *m, long i, double largest);
/* JointPass.take_extra: the extras into the joint pass's impulses (none: `solved` 0). */
void hd_coupled_store(hd_contact_model *m, int solved);
void hd_coupled_free(hd_coupled *c);

#endif
