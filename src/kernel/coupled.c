/* Joint rows inside the contact solve (coupled.h): hecker_dynamics/contact/coupled.py and
 * the parts of JointPass it uses, operation for operation. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "floats.h"
#include "coupled.h"
#include "solver.h"


/* The working memory for the joint pass's rows and the model's bodies; -1 out of memory. */
static int hd_reserve(hd_contact_model *m, long rows)
{
    hd_coupled *c = m->coupled;
    if (c != NULL && c->capacity >= rows)
        return 0;
    hd_coupled_free(c);
    m->coupled = c = calloc(1, sizeof(hd_coupled));
    if (c == NULL)
        return -1;
    const long n = m->bodies + 1;
    c->capacity = rows;
    c->bodies = m->bodies;
    c->rows = malloc((size_t)(rows + 1) * sizeof(hd_coupled_row));
    c->island = malloc((size_t)(2 * rows + n + 2) * sizeof(long));
    c->reference = malloc((size_t)(3 * n) * sizeof(double));
    if (c->rows == NULL || c->island == NULL || c->reference == NULL)
        return -1;
    c->order = c->island + rows;
    c->start = c->order + rows;
    return 0;
}

int hd_couple(hd_contact_model *m)
{
    const hd_joint_model *j = m->joints;
    if (hd_reserve(m, j->row_count) < 0)
        return -1;
    hd_coupled *c = m->coupled;
    const double h = j->last_h;
    c->count = 0;
    for (long i = 0; i < j->row_count; ++i) {  /* JointPass.contact_units */
        const hd_joint_row *row = j->rows + i, *towards = j->dir + i;
        if (row->kind == HD_SOFT)
            continue;
        const double x = j->warm[i];
        hd_coupled_row *u = c->rows + c->count++;
        u->slot = i;
        u->count = row->count;
        for (int e = 0; e < row->count; ++e) {
            u->body[e] = j->bodies[row->body[e]];
            for (int k = 0; k < 3; ++k) {
                u->j[e][k] = row->j[e][k];
                u->d[e][k] = towards->j[e][k];
            }
            m->touched[u->body[e]] = 1;
        }
        u->target = 0.0, u->lower = -INFINITY, u->upper = INFINITY;
        if (row->kind == HD_LIMIT) {
            u->target = -(0.0 > row->c ? 0.0 : row->c) / h;
            u->lower = -x;
        } else if (row->kind == HD_MOTOR) {
            u->target = row->speed;
            u->lower = -row->bound - x;
            u->upper = row->bound - x;
        }
        u->mass = 1.0 / hd_joint_dot(row, towards);
        u->extra = hd_min(hd_max(j->extra[i], u->lower), u->upper);
    }
    return 0;
}

const double *hd_coupled_reference(hd_contact_model *m)
{
    if (m->joints == NULL)
        return m->arrived;
    const hd_joint_model *j = m->joints;
    double *reference = m->coupled->reference;
    memcpy(reference, m->arrived, (size_t)(3 * (m->bodies + 1)) * sizeof(double));
    for (long k = 0; k < j->body_count; ++k)
        memcpy(reference + 3 * j->bodies[k], j->settled + 3 * k, 3 * sizeof(double));
    return reference;
}

void hd_coupled_reset(hd_contact_model *m, long *parent, long *island)
{
    const hd_coupled *c = m->coupled;
    for (long k = 0; m->joints != NULL && k < c->count; ++k)
        for (int e = 0; e < c->rows[k].count; ++e) {
            parent[c->rows[k].body[e]] = c->rows[k].body[e];
            island[c->rows[k].body[e]] = -1;
        }
}

void hd_coupled_join(hd_contact_model *m, long *parent)
{
    const hd_coupled *c = m->coupled;
    for (long k = 0; m->joints != NULL && k < c->count; ++k) {
        const hd_coupled_row *u = c->rows + k;
        for (int e = 1; e < u->count; ++e) {
            const long ra = hd_root(parent, u->body[0]), rb = hd_root(parent, u->body[e]);
            if (ra != rb)
                parent[ra > rb ? ra : rb] = ra > rb ? rb : ra;
        }
    }
}

int hd_coupled_islands(hd_contact_model *m, long *parent, const long *island, long count)
{
    if (m->joints == NULL)
        return 0;
    hd_coupled *c = m->coupled;
    long *start = c->start;  /* count + 1 slots: row counts, then each island's start */
    memset(start, 0, (size_t)(count + 1) * sizeof(long));
    for (long k = 0; k < c->count; ++k) {
        c->island[k] = island[hd_root(parent, c->rows[k].body[0])];
        if (c->island[k] >= 0)
            start[c->island[k] + 1] += 1;
    }
    for (long i = 0; i < count; ++i)
        start[i + 1] += start[i];
    /* Fill with start[i] as island i's cursor, which leaves it at island i + 1's start;
       shifting back by one slot restores the starts without a second buffer. */
    for (long k = 0; k < c->count; ++k)
        if (c->island[k] >= 0)
            c->order[start[c->island[k]]++] = k;
    for (long i = count; i > 0; --i)
        start[i] = start[i - 1];
    start[0] = 0;
    return 0;
}

long hd_coupled_size(const hd_contact_model *m, long i)
{
    return m->joints == NULL ? 0 : m->coupled->start[i + 1] - m->coupled->start[i];
}

/* v += M^-1 J^T impulse (contact/coupled.py: JointUnit._push). */
static void hd_push(const hd_coupled_row *u, double *velocity, double impulse)
{
    for (int e = 0; e < u->count; ++e) {
        double *v = velocity + 3 * u->body[e];
        v[0] += u->d[e][0] * impulse;
        v[1] += u->d[e][1] * impulse;
        v[2] += u->d[e][2] * impulse;
    }
}

void hd_coupled_warm_start(hd_contact_model *m, long i)
{
    if (m->joints == NULL)
        return;
    for (long k = m->coupled->start[i]; k < m->coupled->start[i + 1]; ++k) {
        const hd_coupled_row *u = m->coupled->rows + m->coupled->order[k];
        hd_push(u, m->velocity, u->extra);
    }
}

double hd_coupled_fastest(const hd_contact_model *m, long i, double fastest)
{
    if (m->joints == NULL)
        return fastest;
    for (long k = m->coupled->start[i]; k < m->coupled->start[i + 1]; ++k) {
        const hd_coupled_row *u = m->coupled->rows + m->coupled->order[k];
        for (int e = 0; e < u->count; ++e)
            for (int c = 0; c < 3; ++c)
                fastest = hd_max(fastest, fabs(m->velocity[3 * u->body[e] + c]));
    }
    return fastest;
}

double hd_coupled_sweep(hd_contact_model *m, long i, double largest)
{
    if (m->joints == NULL)
        return largest;
    for (long k = m->coupled->start[i]; k < m->coupled->start[i + 1]; ++k) {
        hd_coupled_row *u = m->coupled->rows + m->coupled->order[k];
        double rate = 0.0;  /* contact/coupled.py: JointUnit.solve */
        for (int e = 0; e < u->count; ++e) {
            const double *v = m->velocity + 3 * u->body[e];
            rate += u->j[e][0] * v[0] + u->j[e][1] * v[1] + u->j[e][2] * v[2];
        }
        const double extra = u->extra;
        const double updated = hd_min(hd_max(extra + (u->target - rate) * u->mass, u->lower),
                                      u->upper);
        const double change = updated - extra;
        hd_push(u, m->velocity, change);
        u->extra = updated;
        largest = hd_max(largest, fabs(change) / u->mass);
    }
    return largest;
}

void hd_coupled_store(hd_contact_model *m, int solved)
{
    hd_joint_model *j = m->joints;
    if (j == NULL)
        return;
    memset(j->extra, 0, (size_t)j->row_count * sizeof(double));
    for (long k = 0; solved && k < m->coupled->count; ++k) {
        const hd_coupled_row *u = m->coupled->rows + k;
        if (u->extra != 0.0) {
            j->warm[u->slot] += u->extra;
            j->extra[u->slot] = u->extra;
        }
    }
}

void hd_coupled_free(hd_coupled *c)
{
    if (c == NULL)
        return;
    free(c->rows);
    free(c->island);
    free(c->reference);
    free(c);
}
