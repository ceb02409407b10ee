/* Warm starts: last step's impulses, found again by the pair of parts and the point in
 * the second body's axes (hecker_dynamics/contact/warm.py), kept sorted by their parts'
 * names so that each key's run is found by hashing or a short search.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact.h"
#include "solver.h"

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
int hd_find_warm(hd_contact_model *m, const long *key, long next, long *low, long *end)
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

/* Last step's impulses of the contact nearest this point among warm[low] to warm[end - 1], its
 * key's, if within HD_MATCH, each used once (contact/warm.py: WarmStarts._recall; `<=`: the
 * last of equally near ones); (c, s) the cosine and sine of body b's angle. */
void hd_recall(hd_contact_model *m, long low, long end, double rx, double ry, double c,
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

/* Keep only the warm-start impulses of the sleeping islands' contacts, in their order
 * (contact/warm.py: WarmStarts._sleeping_warm); returns how many. */
long hd_keep_sleeping_warm(hd_contact_model *m)
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
 * sleeping islands (contact/warm.py: WarmStarts._remember). */
int hd_remember(hd_contact_model *m, long count)
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
        /* the point where it was found: the row's arm may be carried back (solver.c) */
        const double *pose = m->poses + 3 * r->b;
        const double rbx = m->contacts[k].px - pose[0], rby = m->contacts[k].py - pose[1];
        hd_warm *w = m->warm + kept + k;
        memcpy(w->key, r->key, sizeof w->key);
        w->lx = c * rbx + s * rby;
        w->ly = -s * rbx + c * rby;
        w->jn = r->jn;
        w->jt = r->jt * r->carry;
        w->used = 0;
    }
    m->warm_count = kept + count;
    m->warm_indexed = 0;
    return 0;
}
