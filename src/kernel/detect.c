/* Detection: hecker_dynamics/contact/detect.py's Detection.detect, operation for
 * operation: the walls against each body's bounding circle, the map's boxes against each
 * body's bounding box, then a sort-and-sweep broad phase on the x extent of the colliding
 * bodies' bounding boxes (CM +- reach; in bands in y in a tall pile, for the same pairs),
 * then the narrow phase (manifold.c) for the parts of each candidate pair.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact.h"

/* The body's parts placed at its pose (contact/detect.py: Detection._world_parts and _bounds). */
static void hd_place_parts(hd_contact_model *m, const double *q, long body)
{
    m->placed_flag[body] = 1;
    const double x = q[3 * body], y = q[3 * body + 1], angle = q[3 * body + 2];
    hd_cos_sin(angle, m->cos_sin + 2 * body);
    const double c = m->cos_sin[2 * body], s = m->cos_sin[2 * body + 1];
    for (long p = m->part_first[body]; p < m->part_first[body + 1]; ++p) {
        hd_part *part = m->parts + p;
        const double *l = part->local;
        double *w = part->placed;
        if (part->kind == HD_CIRCLE) {
            w[0] = x + c * l[0] - s * l[1];
            w[1] = y + s * l[0] + c * l[1];
            w[2] = l[2];
            part->bounds[0] = w[0] - w[2];
            part->bounds[1] = w[0] + w[2];
            part->bounds[2] = w[1] - w[2];
            part->bounds[3] = w[1] + w[2];
            continue;
        }
        const long k = part->count, values = part->kind == HD_POLYGON ? 2 * k : k;
        for (long i = 0; i < k; ++i) {
            w[2 * i] = x + c * l[2 * i] - s * l[2 * i + 1];
            w[2 * i + 1] = y + s * l[2 * i] + c * l[2 * i + 1];
        }
        for (long i = k; i < values; ++i) {
            w[2 * i] = c * l[2 * i] - s * l[2 * i + 1];
            w[2 * i + 1] = s * l[2 * i] + c * l[2 * i + 1];
        }
        double x0 = w[0], x1 = w[0], y0 = w[1], y1 = w[1];
        for (long i = 1; i < k; ++i) {
            if (w[2 * i] < x0) x0 = w[2 * i];
            if (w[2 * i] > x1) x1 = w[2 * i];
            if (w[2 * i + 1] < y0) y0 = w[2 * i + 1];
            if (w[2 * i + 1] > y1) y1 = w[2 * i + 1];
        }
        part->bounds[0] = x0;
        part->bounds[1] = x1;
        part->bounds[2] = y0;
        part->bounds[3] = y1;
    }
}

/* place_parts once per detection; inlined, so that the pairs of a body placed already
 * (most of them) make no call. */
static inline void hd_place(hd_contact_model *m, const double *q, long body)
{
    if (!m->placed_flag[body])
        hd_place_parts(m, q, body);
}

static int hd_add_contacts(hd_contact_model *m, long a, long b, const hd_found *found, int count,
                           double e, double mu, long k0, long k1, long k2, long k3)
{
    if (m->contact_count + count > m->contact_capacity) {
        long capacity = 2 * m->contact_capacity + count + 16;
        hd_contact *grown = realloc(m->contacts, (size_t)capacity * sizeof(hd_contact));
        if (grown == NULL)
            return -1;
        m->contacts = grown;
        m->contact_capacity = capacity;
    }
    for (int i = 0; i < count; ++i) {
        const hd_found *f = found + i;
        m->contacts[m->contact_count++] = (hd_contact){a, b, f->px, f->py, f->nx, f->ny,
                                                      f->depth, e, mu, {k0, k1, k2, k3},
                                                      count};
    }
    return 0;
}

/* contact/detect.py: collide, normal from A to B. */
static int hd_collide(const hd_part *pa, const hd_part *pb, hd_found *out)
{
    const double *a = pa->placed, *b = pb->placed;
    if (pa->kind != HD_CIRCLE && pb->kind != HD_CIRCLE)
        return hd_polygon_polygon(a, a + 2 * pa->count, pa->count, b, b + 2 * pb->count,
                                  pb->count, HD_MARGIN, out);
    if (pa->kind == HD_CIRCLE && pb->kind == HD_CIRCLE)
        return hd_circle_circle(a[0], a[1], a[2], b[0], b[1], b[2], HD_MARGIN, out);
    if (pa->kind != HD_CIRCLE)
        return hd_polygon_circle(a, a + 2 * pa->count, pa->count, b[0], b[1], b[2], HD_MARGIN,
                                 out);
    const int count = hd_polygon_circle(b, b + 2 * pb->count, pb->count, a[0], a[1], a[2],
                                        HD_MARGIN, out);
    for (int i = 0; i < count; ++i) {
        out[i].nx = -out[i].nx;
        out[i].ny = -out[i].ny;
    }
    return count;
}

/* Whether pair (i, j), i < j, is among the sorted pairs that do not collide. */
static int hd_is_apart(const hd_contact_model *m, long i, long j)
{
    long low = 0, high = m->apart_count;
    while (low < high) {
        const long mid = low + (high - low) / 2;
        const long *p = m->apart + 2 * mid;
        if (p[0] < i || (p[0] == i && p[1] < j))
            low = mid + 1;
        else
            high = mid;
    }
    return low < m->apart_count && m->apart[2 * low] == i && m->apart[2 * low + 1] == j;
}

/* The material of pair (i, j), i < j, or NULL if it does not collide
 * (contact/materials.py: PairMaterials.get). */
static const double *hd_material_of(const hd_contact_model *m, long i, long j)
{
    const long c = m->body_class[i], d = m->body_class[j];
    if (c < 0 || d < 0)
        return NULL;
    const long group = m->class_group[c * m->class_count + d];
    if (group < 0 || (m->apart_count > 0 && hd_is_apart(m, i, j)))
        return NULL;
    return m->material + 2 * group;
}

/* contact/detect.py: Detection._pair_contacts. */
static int hd_pair_contacts(hd_contact_model *m, long a, long b, const double *material)
{
    for (long pa = m->part_first[a]; pa < m->part_first[a + 1]; ++pa) {
        const double *ba = m->parts[pa].bounds;
        for (long pb = m->part_first[b]; pb < m->part_first[b + 1]; ++pb) {
            const double *bb = m->parts[pb].bounds;
            if (bb[0] > ba[1] + HD_MARGIN || bb[1] < ba[0] - HD_MARGIN ||
                    bb[2] > ba[3] + HD_MARGIN || bb[3] < ba[2] - HD_MARGIN)
                continue;
            const int count = hd_collide(m->parts + pa, m->parts + pb, m->found);
            if (hd_add_contacts(m, a, b, m->found, count, material[0], material[1], a, b,
                                pa - m->part_first[a], pb - m->part_first[b]) < 0)
                return -1;
        }
    }
    return 0;
}

/* Python sorts the tuples (x0, body, ...): by x0, then by body. Whether box (x0, body)
 * comes after box (y0, other). */
static int hd_after(double x0, long body, double y0, long other)
{
    return x0 > y0 || (!(x0 < y0) && body > other);
}

/* Sort the boxes (`count` of each of the four edges from `edge` on, and their bodies) by
 * left edge, then body. They are sorted as in the last step and bodies move little in a
 * step, so insertion sort does about one comparison per box; the order is total (bodies
 * differ), so it is the one any sort gives. */
static void hd_sort_boxes(double *edge, long *body, long count)
{
    for (long k = 1; k < count; ++k) {
        if (!hd_after(edge[k - 1], body[k - 1], edge[k], body[k]))
            continue;
        double box[4];
        for (int e = 0; e < 4; ++e)
            box[e] = edge[e * count + k];
        const long b = body[k];
        long l = k;
        for (; l > 0 && hd_after(edge[l - 1], body[l - 1], box[0], b); --l) {
            for (int e = 0; e < 4; ++e)
                edge[e * count + l] = edge[e * count + l - 1];
            body[l] = body[l - 1];
        }
        for (int e = 0; e < 4; ++e)
            edge[e * count + l] = box[e];
        body[l] = b;
    }
}

/* A box's left edge and body, and where it was, for hd_sort_all. */
typedef struct {
    double x0;
    long body, at;
} hd_sort_key;

static int hd_by_left_edge(const void *p, const void *q)
{
    const hd_sort_key *u = p, *w = q;
    return hd_after(u->x0, u->body, w->x0, w->body) - hd_after(w->x0, w->body, u->x0, u->body);
}

/* hd_sort_boxes for boxes in any order (the first detection's, in body order: insertion
 * sort would move each box past about half the others): with every left edge finite,
 * (x0, body) orders them totally, so quicksort gives insertion sort's order. 0 when sorted,
 * -1 when there was no memory for it (hd_sort_boxes then sorts them). */
static int hd_sort_all(double *edge, long *body, long count)
{
    hd_sort_key *keys = malloc((size_t)count * sizeof *keys);
    double *copy = malloc(4 * (size_t)count * sizeof(double));
    long *bodies = malloc((size_t)count * sizeof(long));
    if (keys == NULL || copy == NULL || bodies == NULL) {
        free(keys);
        free(copy);
        free(bodies);
        return -1;
    }
    for (long k = 0; k < count; ++k)
        keys[k] = (hd_sort_key){edge[k], body[k], k};
    qsort(keys, (size_t)count, sizeof *keys, hd_by_left_edge);
    memcpy(copy, edge, 4 * (size_t)count * sizeof(double));
    memcpy(bodies, body, (size_t)count * sizeof(long));
    for (long k = 0; k < count; ++k) {
        for (int e = 0; e < 4; ++e)
            edge[e * count + k] = copy[e * count + keys[k].at];
        body[k] = bodies[keys[k].at];
    }
    free(keys);
    free(copy);
    free(bodies);
    return 0;
}

/* The sweep (contact/detect.py: Detection._candidate_pairs) pairs each box with the
 * boxes after it up to the first whose left edge is past its right edge, those that
 * overlap in y too, in that order. In a tall pile most of those are far off in y (a
 * box's x range spans a box or two of every row, and only the rows next to it overlap it
 * in y), so the sweep can look for box k's pairs in one band in y, which lists in sweep
 * order the boxes that may overlap k in y.
 *
 * Band j holds y from base + j / scale on, the last all above. Box l is in every band from
 * that of low_l - below to that of top_l (low: bottom - margin, high: top + margin, as the
 * sweep computes them), where `below` is at least high_k - low_k for every box k; box k
 * looks in the band of low_k, one of its own as low_k <= top_k. That band holds each box l
 * that overlaps k in y: top_l >= low_k, and bottom_l <= high_k, so that low_l - below <=
 * high_k - below <= low_k; the band of y only grows with y (each step rounds
 * monotonically), so low_k's band lies in l's. With every edge finite the left edges
 * ascend in sweep order, so the boxes after k in its band up to the first past k's right
 * edge are the sweep's pairs of k in y.
 *
 * One band (last 0) is the sweep's own columns: with an edge not finite (the left edges
 * may not ascend, and the sweep's comparisons with NaN decide) or low_k > top_k (a
 * negative reach), with fewer boxes than HD_BAND_BOXES or room for fewer bands than
 * HD_MIN_BANDS, where listing the boxes band by band costs more than the sweep spends on
 * the boxes far off in y (in a pyramid of boxes, about as much at 15 bands, 20 rows), or
 * with a box nearly as tall as the pile. */
#define HD_BAND_BOXES 64
#define HD_MIN_BANDS 16

typedef struct {
    double base, scale, below;
    long last;
} hd_bands;

/* The band of y: (y - base) * scale rounded down, at most the last. */
static inline long hd_band_of(const hd_bands *bands, double y)
{
    const double t = (y - bands->base) * bands->scale;
    return t < (double)bands->last ? (long)t : bands->last;
}

/* What plan_bands needs to know of the boxes, gathered as hd_detect makes them. */
typedef struct {
    double lowest, highest, widest;  /* the least low, the greatest top and high - low */
    int wild;                        /* an edge not finite, or low > top */
} hd_extent;

static inline void hd_extend(hd_extent *extent, double left, double right, double bottom,
                             double top)
{
    const double low = bottom - HD_MARGIN, high = top + HD_MARGIN;
    extent->wild |= !(isfinite(left) && isfinite(right) && isfinite(bottom) &&
                      isfinite(top) && low <= top);
    extent->lowest = low < extent->lowest ? low : extent->lowest;
    extent->highest = top > extent->highest ? top : extent->highest;
    extent->widest = high - low > extent->widest ? high - low : extent->widest;
}

/* Bands as tall as the tallest box with margins, so that a box is in two or three of them,
 * or taller to make one per box at most; or one band. */
static hd_bands hd_plan_bands(const hd_extent *extent, long count)
{
    const hd_bands one = {0, 0, 0, 0};
    if (count < HD_BAND_BOXES || extent->wild)
        return one;
    /* high - low rounded may fall short of the exact difference by a relative 2^-53; a
     * relative 2^-40 more covers it. */
    const double widest = extent->widest, below = (1 + 0x1p-40) * widest,
                 base = extent->lowest - below, span = extent->highest - base,
                 room = span / widest;
    if (!(isfinite(span) && room >= HD_MIN_BANDS))
        return one;
    const long bands = room < (double)count ? (long)room : count;
    const double scale = (double)bands / span;
    return isfinite(scale) ? (hd_bands){base, scale, below, bands - 1} : one;
}

/* Copy the boxes band by band into m->band_edge (their left, bottom and top edges, as
 * columns of m->band_capacity) and m->band_body, and note where box k's pairs may be: from
 * m->band_from[k], just after k in the band of low_k, to m->band_to[k]; -1 out of
 * memory. */
static int hd_list_bands(hd_contact_model *m, long count, const hd_bands *bands)
{
    const double *left = m->sweep, *bottom = left + 2 * count, *top = bottom + count;
    long *end = m->band_end, *next = m->band_next;
    /* Each box adds 1 to the boxes of its first band and takes it off after its last: the
     * running sum counts the boxes of each band. */
    memset(end, 0, (size_t)(bands->last + 2) * sizeof(long));
    for (long k = 0; k < count; ++k) {
        end[hd_band_of(bands, bottom[k] - HD_MARGIN - bands->below)] += 1;
        end[hd_band_of(bands, top[k]) + 1] -= 1;
    }
    long total = 0, boxes = 0;
    for (long j = 0; j <= bands->last; ++j) {
        boxes += end[j];
        total += boxes;
        end[j] = next[j] = total;
    }
    if (total > m->band_capacity) {  /* room to span more later; nothing to keep */
        const long capacity = total + count;
        double *edge = malloc(3 * (size_t)capacity * sizeof(double));
        long *body = malloc((size_t)capacity * sizeof(long));
        if (edge == NULL || body == NULL) {
            free(edge);
            free(body);
            return -1;
        }
        free(m->band_edge);
        free(m->band_body);
        m->band_edge = edge;
        m->band_body = body;
        m->band_capacity = capacity;
    }
    double *edge = m->band_edge;
    const long capacity = m->band_capacity;
    /* From the last box back, so that each band lists its boxes in sweep order and box k
     * is at next[j] once it is in band j. */
    for (long k = count - 1; k >= 0; --k) {
        const double low = bottom[k] - HD_MARGIN;
        for (long j = hd_band_of(bands, low - bands->below), j1 = hd_band_of(bands, top[k]);
                j <= j1; ++j) {
            const long p = --next[j];
            edge[p] = left[k];
            edge[capacity + p] = bottom[k];
            edge[2 * capacity + p] = top[k];
            m->band_body[p] = m->sweep_body[k];
        }
        const long own = hd_band_of(bands, low);
        m->band_from[k] = next[own] + 1;
        m->band_to[k] = end[own];
    }
    return 0;
}

/* contact/detect.py: Detection._static_contacts. The map's boxes (body -1; box k's key
 * -1 - (walls + k)) against the awake bodies that collide with them, body by body, the
 * boxes within the body's bounding box in the map's order. */
static int hd_static_contacts(hd_contact_model *m, const double *q)
{
    const long first = -1 - m->walls;
    const double *bounds = m->static_bounds;
    for (long s = 0; s < m->static_body_count; ++s) {
        const long b = m->static_body[s];
        if (m->island[b] >= 0)
            continue;
        const double x = q[3 * b], y = q[3 * b + 1], r = m->reach[b] + HD_MARGIN;
        for (long k = 0; k < m->static_count; ++k) {
            const double *box = bounds + 4 * k;
            if (!(box[0] <= x + r && box[1] >= x - r && box[2] <= y + r && box[3] >= y - r))
                continue;
            hd_place(m, q, b);
            for (long p = m->part_first[b]; p < m->part_first[b + 1]; ++p) {
                const int count = hd_collide(m->statics + k, m->parts + p, m->found);
                if (hd_add_contacts(m, -1, b, m->found, count, m->static_material[0],
                                    m->static_material[1], first - k, b, 0,
                                    p - m->part_first[b]) < 0)
                    return -1;
            }
        }
    }
    return 0;
}

int hd_detect(hd_contact_model *m, const double *q)
{
    m->contact_count = 0;
    memset(m->placed_flag, 0, (size_t)m->bodies * sizeof(int));
    for (long w = 0; w < m->walls; ++w) {
        const double *wall = m->wall + 5 * w;
        const double nx = wall[0], ny = wall[1], offset = wall[2];
        for (long k = m->wall_first[w]; k < m->wall_first[w + 1]; ++k) {
            const long b = m->wall_body[k];
            if (m->island[b] >= 0)
                continue;
            if (nx * q[3 * b] + ny * q[3 * b + 1] - offset > m->reach[b] + HD_MARGIN)
                continue;
            hd_place(m, q, b);
            for (long p = m->part_first[b]; p < m->part_first[b + 1]; ++p) {
                const hd_part *part = m->parts + p;
                const int count = part->kind == HD_CIRCLE
                    ? hd_half_plane_circle(nx, ny, offset, part->placed[0], part->placed[1],
                                           part->placed[2], HD_MARGIN, m->found)
                    : hd_half_plane_polygon(nx, ny, offset, part->placed, part->count,
                                            HD_MARGIN, m->found);
                if (hd_add_contacts(m, -1, b, m->found, count, wall[3], wall[4], -1 - w, b, 0,
                                    p - m->part_first[b]) < 0)
                    return -1;
            }
        }
    }
    if (hd_static_contacts(m, q) < 0)
        return -1;
    const long count = m->colliding_count;
    long awake = 0;  /* with every colliding body asleep no pair needs looking at */
    while (awake < count && m->island[m->colliding[awake]] >= 0)
        awake += 1;
    if (awake == count)
        return 0;
    double *left = m->sweep, *right = left + count, *bottom = right + count,
           *top = bottom + count;
    hd_extent extent = {INFINITY, -INFINITY, 0, 0};
    for (long k = 0; k < count; ++k) {
        const long b = m->sweep_order ? m->sweep_body[k] : m->colliding[k];
        const double x = q[3 * b], y = q[3 * b + 1], r = m->reach[b];
        left[k] = x - r;
        right[k] = x + r;
        bottom[k] = y - r;
        top[k] = y + r;
        m->sweep_body[k] = b;
        hd_extend(&extent, left[k], right[k], bottom[k], top[k]);
    }
    if (m->sweep_order || extent.wild || hd_sort_all(m->sweep, m->sweep_body, count) < 0)
        hd_sort_boxes(m->sweep, m->sweep_body, count);
    m->sweep_order = 1;
    const hd_bands bands = hd_plan_bands(&extent, count);
    /* One band: the sweep's own columns, each box's pairs from the next box on. */
    const int banded = bands.last > 0;
    if (banded && hd_list_bands(m, count, &bands) < 0)
        return -1;
    const double *band_left = banded ? m->band_edge : left,
                 *band_bottom = banded ? band_left + m->band_capacity : bottom,
                 *band_top = banded ? band_bottom + m->band_capacity : top;
    const long *band_body = banded ? m->band_body : m->sweep_body;
    for (long k = 0; k < count; ++k) {
        const long b1 = m->sweep_body[k];
        const double reach = right[k] + HD_MARGIN, low = bottom[k] - HD_MARGIN,
                     high = top[k] + HD_MARGIN;
        for (long p = banded ? m->band_from[k] : k + 1, end = banded ? m->band_to[k] : count;
                p < end && !(band_left[p] > reach); ++p) {
            if (!(band_bottom[p] <= high && band_top[p] >= low))
                continue;
            const long b2 = band_body[p];
            const long i = b1 < b2 ? b1 : b2, j = b1 < b2 ? b2 : b1;
            const long sleeping = m->island[i] > m->island[j] ? m->island[i] : m->island[j];
            if (sleeping >= 0 && m->island[i] >= 0 && m->island[j] >= 0)
                continue;
            const double *material = hd_material_of(m, i, j);
            if (material == NULL)
                continue;
            hd_place(m, q, i);
            hd_place(m, q, j);
            const long found = m->contact_count;
            if (hd_pair_contacts(m, i, j, material) < 0)
                return -1;
            if (sleeping >= 0 && m->contact_count > found) {
                m->wake[sleeping] = 1;
                m->woken = 1;
            }
        }
    }
    return 0;
}
