/* Sleeping islands (hecker_dynamics/contact/sleep.py): sleeping bodies held where they
 * were, islands woken by a touch, rest times kept and islands put to sleep.
 */
#include <math.h>
#include <string.h>

#include "contact.h"
#include "solver.h"

/* Put the sleeping bodies back at (q0, v0) (contact/sleep.py: Sleep._awake_contacts). */
void hd_hold(const hd_contact_model *m, double *q1, double *v1, const double *q0,
                 const double *v0)
{
    for (long b = 0; b < m->bodies; ++b) {
        if (m->island[b] < 0)
            continue;
        memcpy(q1 + 3 * b, q0 + 3 * b, 3 * sizeof(double));
        memcpy(v1 + 3 * b, v0 + 3 * b, 3 * sizeof(double));
    }
}

/* Wake the islands detection marked (contact/sleep.py: Sleep._wake). */
void hd_wake_marked(hd_contact_model *m)
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
 * HD_TIME_TO_SLEEP (contact/sleep.py: Sleep._doze). */
void hd_doze(hd_contact_model *m, double *v1, long count, double h)
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
        const long ra = hd_root(parent, r->a), rb = hd_root(parent, r->b);
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
        const long r = hd_root(parent, b);
        shortest[r] = hd_min(shortest[r], m->rested[b]);
    }
    for (long b = 0; b < n; ++b) {
        if (m->island[b] >= 0)
            continue;
        const long r = hd_root(parent, b);
        if (shortest[r] >= HD_TIME_TO_SLEEP) {
            m->island[b] = r;
            v1[3 * b] = v1[3 * b + 1] = v1[3 * b + 2] = 0.0;
        }
    }
}
