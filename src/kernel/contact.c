/* The contact model: the memory of the pass that contact.h describes, made once from the
 * scene (hecker_dynamics/contact/compiled.py packs it) and released with it.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact.h"
#include "crew.h"
#include "wide.h"

int hd_contact_prepare(hd_contact_model *m)
{
    const long n = m->bodies;
    m->placed_flag = calloc((size_t)n + 1, sizeof(int));
    m->touched = calloc((size_t)n + 1, sizeof(int));
    m->sweep = malloc(((size_t)m->colliding_count * 4 + 1) * sizeof(double));
    m->sweep_body = malloc(((size_t)m->colliding_count + 1) * sizeof(long));
    m->band_end = malloc((4 * (size_t)m->colliding_count + 1) * sizeof(long));
    m->band_next = m->band_end == NULL ? NULL : m->band_end + m->colliding_count + 1;
    m->band_from = m->band_next == NULL ? NULL : m->band_next + m->colliding_count;
    m->band_to = m->band_from == NULL ? NULL : m->band_from + m->colliding_count;
    m->band_capacity = 3 * m->colliding_count + 1;  /* grown when boxes span more */
    m->band_edge = malloc(3 * (size_t)m->band_capacity * sizeof(double));
    m->band_body = malloc((size_t)m->band_capacity * sizeof(long));
    m->found = malloc(((size_t)m->max_vertices + 2) * sizeof(hd_found));
    m->velocity = malloc((size_t)(5 * 3 * (n + 1)) * sizeof(double));
    m->cos_sin = malloc((size_t)(2 * (n + 1)) * sizeof(double));
    m->turn_cos_sin = malloc((size_t)(2 * (n + 1)) * sizeof(double));
    m->parent = malloc((size_t)(2 * (n + 1)) * sizeof(long));
    m->island_of = m->parent == NULL ? NULL : m->parent + n + 1;
    m->calm = calloc(2 * ((size_t)n + 1), sizeof(int));
    m->wake = m->calm == NULL ? NULL : m->calm + n + 1;
    m->rested = calloc((size_t)n + 1, sizeof(double));
    m->island = malloc(((size_t)n + 1) * sizeof(long));
    if (!m->placed_flag || !m->touched || !m->sweep || !m->sweep_body || !m->band_end ||
            !m->band_edge || !m->band_body || !m->found ||
            !m->velocity ||
            !m->cos_sin || !m->turn_cos_sin || !m->parent || !m->calm || !m->rested || !m->island)
        return -1;
    for (long b = 0; b <= n; ++b)
        m->island[b] = -1;
    m->sleep = m->woken = 0;
    m->arrived = m->velocity + 3 * (n + 1);
    m->before = m->arrived + 3 * (n + 1);
    m->shift = m->before + 3 * (n + 1);
    m->poses = m->shift + 3 * (n + 1);
    m->contacts = NULL;
    m->rows = NULL;
    m->units = NULL;
    m->order = NULL;
    m->seen = NULL;
    m->seen_count = m->seen_capacity = m->island_count = 0;
    m->islands_known = 0;
    m->warm = NULL;
    m->warm_table = NULL;
    m->warm_table_size = 0;
    m->warm_indexed = 0;
    m->warm_awake = 0;
    m->wide = NULL;
    m->contact_count = m->contact_capacity = m->row_capacity = 0;
    m->warm_count = m->warm_capacity = 0;
    return 0;
}

void hd_contact_free(hd_contact_model *m)
{
    if (m == NULL)
        return;
    for (long p = 0; m->parts != NULL && p < m->part_count; ++p) {
        free(m->parts[p].local);
        free(m->parts[p].placed);
    }
    free(m->parts);
    free(m->part_first);
    for (long k = 0; m->statics != NULL && k < m->static_count; ++k)
        free(m->statics[k].placed);
    free(m->statics);
    free(m->static_bounds);
    free(m->static_body);
    free(m->swept);
    free(m->inverse_mass);
    free(m->inverse_inertia);
    free(m->reach);
    free(m->slop);
    free(m->wall);
    free(m->wall_first);
    free(m->wall_body);
    free(m->colliding);
    free(m->body_class);
    free(m->class_group);
    free(m->material);
    free(m->apart);
    free(m->placed_flag);
    free(m->touched);
    free(m->sweep);
    free(m->sweep_body);
    free(m->band_end);
    free(m->band_edge);
    free(m->band_body);
    free(m->found);
    free(m->velocity);
    free(m->contacts);
    free(m->rows);
    free(m->units);
    free(m->order);
    free(m->seen);
    free(m->parent);
    free(m->warm);
    free(m->warm_table);
    free(m->cos_sin);
    free(m->turn_cos_sin);
    free(m->calm);
    free(m->rested);
    free(m->island);
    hd_wide_free(m->wide);
    hd_crew_free(m->crew);
    free(m);
}
