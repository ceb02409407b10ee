/* The coloured solve of a big island: wide.h. The colours are greedy, first fit in island
 * order (contact/islands.py: coloured); within each colour its two-point blocks go four at a time
 * through lanes of GCC's vector extensions (AVX where the CPU has it, else two SSE2
 * halves: the same IEEE operations, so the same bits), a colour's last four padded with
 * empty lanes, and every other unit of the colour (one-point contacts, and all the units
 * that fit no colour) through rows.h one by one.
 */
#include <stdlib.h>
#include <string.h>

#include "contact.h"
#include "crew.h"
#include "rows.h"
#include "simd.h"
#include "wide.h"

/* Four blocks of one colour, lane by lane: first what the position correction reads (rows
 * one and two's arms, the normal, the inverse masses, the normal masses, the rows' depths
 * once the passes ran, the body pair), together in as few cache lines as it can be; then
 * what only the velocity passes read besides: the targets, the tangent masses, the friction
 * coefficient (one, as a block's rows come from one pair of parts and so one material), the
 * block's K and K^-1, the rows' impulses while the passes run. */
typedef struct {
    hd_v4 rax1, ray1, rbx1, rby1, rax2, ray2, rbx2, rby2, nx, ny, im_a, ii_a, im_b, ii_b;
    hd_v4 mass_n1, mass_n2, base1, base2;
    long a[HD_LANES], b[HD_LANES];
    hd_v4 target1, target2, mass_t1, mass_t2, mu;
    hd_v4 k11, k12, k22, inv11, inv12, inv22, jn1, jn2, jt1, jt2;
    long first[HD_LANES];
} hd_lanes;

/* The colours of each island solved here are kept from step to step, for as long as
 * its units are the same (solver.c: hd_same_units). */
struct hd_wide {
    long capacity;          /* units of an island */
    long sorted_capacity;   /* units of all islands */
    long colourings;        /* islands */
    int *colour;            /* per unit of the island, in island order */
    long *sorted;           /* each island's units by colour, each colour's in island order,
                             * where its units are in m->order */
    long (*colour_start)[HD_COLOURS + 2];  /* per island: its colours' units in `sorted` */
    long *single;           /* per colour, the units not in lanes */
    long lane_start[HD_COLOURS + 2], single_start[HD_COLOURS + 2];
    uint64_t *used;         /* bodies + 1: the colours each body has */
    hd_lanes *lanes;
};

void hd_wide_free(struct hd_wide *w)
{
    if (w == NULL)
        return;
    free(w->colour);
    free(w->sorted);
    free(w->colour_start);
    free(w->single);
    free(w->used);
    free(w->lanes);
    free(w);
}

/* Room for island `wide` of `size` units, and for its colours, and the other islands',
 * kept. */
static int hd_reserve(hd_contact_model *m, long wide, long size)
{
    if (m->wide == NULL) {
        m->wide = calloc(1, sizeof(struct hd_wide));
        if (m->wide == NULL)
            return -1;
    }
    if (m->wide->used == NULL) {
        m->wide->used = calloc((size_t)m->bodies + 1, sizeof(uint64_t));
        if (m->wide->used == NULL)
            return -1;
    }
    struct hd_wide *w = m->wide;
    if (m->row_capacity > w->sorted_capacity) {
        long *sorted = realloc(w->sorted, (size_t)m->row_capacity * sizeof(long));
        if (sorted == NULL)
            return -1;
        w->sorted = sorted;
        w->sorted_capacity = m->row_capacity;
    }
    if (wide >= w->colourings) {
        long(*starts)[HD_COLOURS + 2] = realloc(w->colour_start,
                                                (size_t)(wide + 1) * sizeof *starts);
        if (starts == NULL)
            return -1;
        w->colour_start = starts;
        w->colourings = wide + 1;
    }
    if (size > w->capacity) {
        free(w->colour);
        free(w->single);
        free(w->lanes);
        w->colour = malloc((size_t)size * sizeof(int));
        w->single = malloc((size_t)size * sizeof(long));
#if HD_VECTORS
        /* The vectors need their own alignment, which malloc does not promise. Each colour
         * but the last fills its sets of lanes but one, which it pads. */
        const size_t sets = (size_t)(size / HD_LANES + HD_COLOURS);
        w->lanes = aligned_alloc(_Alignof(hd_lanes), sets * sizeof(hd_lanes));
        const int lanes_ok = w->lanes != NULL;
#else
        const int lanes_ok = 1;
#endif
        if (!w->colour || !w->single || !lanes_ok) {
            w->capacity = 0;
            return -1;
        }
        w->capacity = size;
    }
    return 0;
}

static int hd_lowest_free(uint64_t taken)
{
    if (taken == UINT64_MAX)
        return HD_COLOURS;
    int colour = 0;
    while (taken & ((uint64_t)1 << colour))
        colour += 1;
    return colour;
}

/* Each unit's colour: the lowest that neither of its bodies has yet (the walls' slot takes
 * none), or HD_COLOURS when none is left; then the units sorted by colour into `sorted`,
 * where the colours start into `colour_start`. */
static void hd_colour_units(hd_contact_model *m, const long *members, long size, long *sorted,
                            long *colour_start)
{
    struct hd_wide *w = m->wide;
    const long wall = m->bodies;
    long count[HD_COLOURS + 2] = {0};
    for (long k = 0; k < size; ++k) {
        const hd_row *r = m->rows + m->units[members[k]].first;
        const uint64_t taken = (r->a == wall ? 0 : w->used[r->a]) | w->used[r->b];
        const int colour = hd_lowest_free(taken);
        if (colour < HD_COLOURS) {
            if (r->a != wall)
                w->used[r->a] |= (uint64_t)1 << colour;
            w->used[r->b] |= (uint64_t)1 << colour;
        }
        w->colour[k] = colour;
        count[colour + 1] += 1;
    }
    for (long k = 0; k < size; ++k) {
        const hd_row *r = m->rows + m->units[members[k]].first;
        w->used[r->a] = w->used[r->b] = 0;
    }
    for (int c = 0; c <= HD_COLOURS; ++c)
        count[c + 1] += count[c];
    memcpy(colour_start, count, sizeof count);
    for (long k = 0; k < size; ++k)
        sorted[count[w->colour[k]]++] = members[k];
}

/* A small island's units in their order (solve.c: hd_level_order's) cut into runs that
 * share no body but the walls' slot, each run a colour: a run's units commute, so the
 * lanes solve them at once with the bits of the island's sequential sweep. In level order
 * the runs are the levels (a level's first unit shares a body with a unit of the level
 * before). `sorted` gets the units in their order. */
static void hd_level_runs(hd_contact_model *m, const long *members, long size, long *sorted,
                          long *colour_start)
{
    uint64_t *used = m->wide->used;
    const long wall = m->bodies;
    int run = 0;
    colour_start[0] = 0;
    for (long k = 0; k < size; ++k) {
        const hd_row *r = m->rows + m->units[members[k]].first;
        if ((r->a != wall && used[r->a]) || used[r->b]) {
            for (long j = colour_start[run]; j < k; ++j) {
                const hd_row *q = m->rows + m->units[sorted[j]].first;
                used[q->a] = used[q->b] = 0;
            }
            colour_start[++run] = k;
        }
        if (r->a != wall)
            used[r->a] = 1;
        used[r->b] = 1;
        sorted[k] = members[k];
    }
    for (long j = colour_start[run]; j < size; ++j) {
        const hd_row *q = m->rows + m->units[sorted[j]].first;
        used[q->a] = used[q->b] = 0;
    }
    for (int c = run + 1; c <= HD_COLOURS + 1; ++c)
        colour_start[c] = size;
}

/* The colour order visits the units and their rows all over memory: how many units ahead
 * the packing of lanes asks for a unit's rows (and twice as far for the unit itself). */
#define HD_AHEAD 8

#if defined(__GNUC__)
#define hd_prefetch(address, write) __builtin_prefetch((address), (write))
#else
#define hd_prefetch(address, write) ((void)(address), (void)(write))
#endif

/* Ask for the cache lines of rows `first` and `first` + 1 (a block's). */
static void hd_prefetch_rows(const hd_contact_model *m, long first, int write)
{
    const char *start = (const char *)(m->rows + first);
    for (size_t at = 0; at < 2 * sizeof(hd_row); at += 64)
        hd_prefetch(start + at, write);
}

static double *hd_lane(hd_v4 *v, int l) { return (double *)v + l; }

/* The blocks of the `filled` units `pair` into lanes, the lanes beyond them empty: the
 * walls' slot on both sides, no arms, normal or inverse masses, so they push it by zeros
 * only, which keep it +0, and change nothing (unit effective masses, no friction). */
static void hd_load_lanes(const hd_contact_model *m, const long *pair, int filled, hd_lanes *x)
{
    /* A full set's lanes get every field below but their depths, which hd_store_lanes sets
     * before the position correction reads them: only a padded set needs zeros first. */
    if (filled < HD_LANES)
        memset(x, 0, sizeof *x);
    for (int l = filled; l < HD_LANES; ++l) {
        x->a[l] = x->b[l] = m->bodies;
        x->first[l] = -1;
        *hd_lane(&x->mass_n1, l) = *hd_lane(&x->mass_n2, l) = 1.0;
        *hd_lane(&x->mass_t1, l) = *hd_lane(&x->mass_t2, l) = 1.0;
    }
    for (int l = 0; l < filled; ++l) {
        const hd_unit *u = m->units + pair[l];
        const hd_row *one = m->rows + u->first, *two = one + 1;
        x->a[l] = one->a;
        x->b[l] = one->b;
        x->first[l] = u->first;
        *hd_lane(&x->rax1, l) = one->rax;
        *hd_lane(&x->ray1, l) = one->ray;
        *hd_lane(&x->rbx1, l) = one->rbx;
        *hd_lane(&x->rby1, l) = one->rby;
        *hd_lane(&x->rax2, l) = two->rax;
        *hd_lane(&x->ray2, l) = two->ray;
        *hd_lane(&x->rbx2, l) = two->rbx;
        *hd_lane(&x->rby2, l) = two->rby;
        *hd_lane(&x->nx, l) = one->nx;
        *hd_lane(&x->ny, l) = one->ny;
        *hd_lane(&x->im_a, l) = one->im_a;
        *hd_lane(&x->ii_a, l) = one->ii_a;
        *hd_lane(&x->im_b, l) = one->im_b;
        *hd_lane(&x->ii_b, l) = one->ii_b;
        *hd_lane(&x->target1, l) = one->target;
        *hd_lane(&x->target2, l) = two->target;
        *hd_lane(&x->mass_n1, l) = one->mass_n;
        *hd_lane(&x->mass_n2, l) = two->mass_n;
        *hd_lane(&x->mass_t1, l) = one->mass_t;
        *hd_lane(&x->mass_t2, l) = two->mass_t;
        *hd_lane(&x->mu, l) = one->mu;
        *hd_lane(&x->k11, l) = u->k11;
        *hd_lane(&x->k12, l) = u->k12;
        *hd_lane(&x->k22, l) = u->k22;
        *hd_lane(&x->inv11, l) = u->inv11;
        *hd_lane(&x->inv12, l) = u->inv12;
        *hd_lane(&x->inv22, l) = u->inv22;
        *hd_lane(&x->jn1, l) = one->jn;
        *hd_lane(&x->jn2, l) = two->jn;
        *hd_lane(&x->jt1, l) = one->jt;
        *hd_lane(&x->jt2, l) = two->jt;
    }
}

/* The lanes' impulses back into their rows, and the rows' hd_depth_after after a step of
 * h into base[row] and into the lanes: one visit of each row after the passes. */
static void hd_store_lanes(hd_contact_model *m, hd_lanes *x, double h, double *base)
{
    for (int l = 0; l < HD_LANES && x->first[l] >= 0; ++l) {
        hd_row *one = m->rows + x->first[l], *two = one + 1;
        one->jn = *hd_lane(&x->jn1, l);
        two->jn = *hd_lane(&x->jn2, l);
        one->jt = *hd_lane(&x->jt1, l);
        two->jt = *hd_lane(&x->jt2, l);
        *hd_lane(&x->base1, l) = base[x->first[l]] = hd_depth_after(m, one, h);
        *hd_lane(&x->base2, l) = base[x->first[l] + 1] = hd_depth_after(m, two, h);
    }
}

/* A velocity pass over colour c's units that are not in lanes, in their order, their
 * changes folded into `largest`. */
static HD_HOT double hd_singles_of(hd_contact_model *m, int c, double largest)
{
    const struct hd_wide *w = m->wide;
    for (long s = w->single_start[c]; s < w->single_start[c + 1]; ++s)
        largest = hd_max(largest, hd_solve_unit(m->units + w->single[s], m->rows, m->velocity));
    return largest;
}

#if HD_VECTORS
/* m ? x : y, lane by lane (m: all ones or all zeros). */
static HD_HOT hd_v4 hd_pick(hd_m4 m, hd_v4 x, hd_v4 y)
{
    return (hd_v4)(((hd_m4)x & m) | ((hd_m4)y & ~m));
}

static HD_HOT hd_v4 hd_max_v(hd_v4 x, hd_v4 y) { return hd_pick(y > x, y, x); }  /* hd_max */
static HD_HOT hd_v4 hd_min_v(hd_v4 x, hd_v4 y) { return hd_pick(y < x, y, x); }  /* hd_min */

static HD_HOT hd_v4 hd_abs_v(hd_v4 x)
{
    const hd_m4 magnitude = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
    return (hd_v4)((hd_m4)x & magnitude);
}

/* A body's velocity, lane by lane: (vx, vy, omega) of body[l] in each lane l. */
typedef struct {
    hd_v4 x, y, w;
} hd_twist4;

/* x where `on`, else y, lane by lane. */
static HD_HOT hd_twist4 hd_pick_twist(hd_m4 on, hd_twist4 x, hd_twist4 y)
{
    return (hd_twist4){hd_pick(on, x.x, y.x), hd_pick(on, x.y, y.y), hd_pick(on, x.w, y.w)};
}

static HD_HOT hd_twist4 hd_gather(const double *velocity, const long *body)
{
    const double *p0 = velocity + 3 * body[0], *p1 = velocity + 3 * body[1],
                 *p2 = velocity + 3 * body[2], *p3 = velocity + 3 * body[3];
    return (hd_twist4){{p0[0], p1[0], p2[0], p3[0]}, {p0[1], p1[1], p2[1], p3[1]},
                       {p0[2], p1[2], p2[2], p3[2]}};
}

/* gather's inverse, lane by lane in lane order; spelled out, not looped, as GCC then
 * stores straight from the vector registers (a loop sent each vector through the stack). */
static HD_HOT void hd_scatter(double *velocity, const long *body, hd_twist4 v)
{
    double *p0 = velocity + 3 * body[0], *p1 = velocity + 3 * body[1],
           *p2 = velocity + 3 * body[2], *p3 = velocity + 3 * body[3];
    p0[0] = v.x[0];
    p0[1] = v.y[0];
    p0[2] = v.w[0];
    p1[0] = v.x[1];
    p1[1] = v.y[1];
    p1[2] = v.w[1];
    p2[0] = v.x[2];
    p2[1] = v.y[2];
    p2[2] = v.w[2];
    p3[0] = v.x[3];
    p3[1] = v.y[3];
    p3[2] = v.w[3];
}

/* rows.h's hd_normal_velocity, lane by lane. */
static HD_HOT hd_v4 hd_normal_velocity4(hd_twist4 va, hd_twist4 vb, hd_v4 rax, hd_v4 ray,
                                        hd_v4 rbx, hd_v4 rby, hd_v4 nx, hd_v4 ny)
{
    return (vb.x - vb.w * rby - va.x + va.w * ray) * nx
           + (vb.y + vb.w * rbx - va.y - va.w * rax) * ny;
}

/* rows.h's push, lane by lane. */
static HD_HOT void hd_push4(hd_twist4 *va, hd_twist4 *vb, const hd_lanes *x, hd_v4 rax,
                            hd_v4 ray, hd_v4 rbx, hd_v4 rby, hd_v4 px, hd_v4 py)
{
    va->x = va->x - px * x->im_a;
    va->y = va->y - py * x->im_a;
    va->w = va->w - (rax * py - ray * px) * x->ii_a;
    vb->x = vb->x + px * x->im_b;
    vb->y = vb->y + py * x->im_b;
    vb->w = vb->w + (rbx * py - rby * px) * x->ii_b;
}

/* rows.h's solve_friction, lane by lane: a lane without friction keeps its velocities and
 * impulse (pushing a zero impulse could turn a -0 velocity into +0). */
static HD_HOT hd_v4 hd_friction4(hd_twist4 *va, hd_twist4 *vb, const hd_lanes *x, hd_v4 rax,
                                 hd_v4 ray, hd_v4 rbx, hd_v4 rby, hd_v4 mass_t, hd_v4 mu,
                                 hd_v4 jn, hd_v4 *jt)
{
    const hd_v4 zero = {0.0, 0.0, 0.0, 0.0};
    const hd_m4 on = mu > zero;
    const hd_v4 dvx = vb->x - vb->w * rby - va->x + va->w * ray;
    const hd_v4 dvy = vb->y + vb->w * rbx - va->y - va->w * rax;
    const hd_v4 old = *jt, bound = mu * jn;
    const hd_v4 new_t = hd_min_v(hd_max_v(old - (-dvx * x->ny + dvy * x->nx) * mass_t, -bound),
                                 bound);
    hd_twist4 a = *va, b = *vb;
    hd_push4(&a, &b, x, rax, ray, rbx, rby, -(new_t - old) * x->ny, (new_t - old) * x->nx);
    *va = hd_pick_twist(on, a, *va);
    *vb = hd_pick_twist(on, b, *vb);
    *jt = hd_pick(on, new_t, old);
    return hd_pick(on, hd_abs_v(new_t - old) / mass_t, zero);
}

/* rows.h's hd_solve_block in four lanes, on their bodies' velocities *pa and *pb; returns
 * each lane's largest change. */
static HD_HOT hd_v4 hd_block4(hd_lanes *x, hd_twist4 *pa, hd_twist4 *pb)
{
    const hd_v4 zero = {0.0, 0.0, 0.0, 0.0};
    hd_twist4 va = *pa, vb = *pb;
    const hd_v4 old1 = x->jn1, old2 = x->jn2;
    const hd_v4 b1 = hd_normal_velocity4(va, vb, x->rax1, x->ray1, x->rbx1, x->rby1, x->nx, x->ny)
                     - x->target1 - (x->k11 * old1 + x->k12 * old2);
    const hd_v4 b2 = hd_normal_velocity4(va, vb, x->rax2, x->ray2, x->rbx2, x->rby2, x->nx, x->ny)
                     - x->target2 - (x->k12 * old1 + x->k22 * old2);
    /* The cascade of hd_solve_block, innermost case first. */
    const hd_v4 both1 = -(x->inv11 * b1 + x->inv12 * b2), both2 = -(x->inv12 * b1 + x->inv22 * b2);
    const hd_v4 first1 = -x->mass_n1 * b1, second2 = -x->mass_n2 * b2;
    const hd_m4 both = (both1 >= zero) & (both2 >= zero);
    const hd_m4 first = (first1 >= zero) & (x->k12 * first1 + b2 >= zero);
    const hd_m4 second = (second2 >= zero) & (x->k12 * second2 + b1 >= zero);
    const hd_m4 apart = (b1 >= zero) & (b2 >= zero);
    hd_v4 x1 = hd_pick(apart, zero, old1), x2 = hd_pick(apart, zero, old2);
    x1 = hd_pick(second, zero, x1);
    x2 = hd_pick(second, second2, x2);
    x1 = hd_pick(first, first1, x1);
    x2 = hd_pick(first, zero, x2);
    x1 = hd_pick(both, both1, x1);
    x2 = hd_pick(both, both2, x2);
    hd_push4(&va, &vb, x, x->rax1, x->ray1, x->rbx1, x->rby1, (x1 - old1) * x->nx,
             (x1 - old1) * x->ny);
    hd_push4(&va, &vb, x, x->rax2, x->ray2, x->rbx2, x->rby2, (x2 - old2) * x->nx,
             (x2 - old2) * x->ny);
    x->jn1 = x1;
    x->jn2 = x2;
    hd_v4 change = hd_max_v(hd_abs_v(x1 - old1) / x->mass_n1, hd_abs_v(x2 - old2) / x->mass_n2);
    change = hd_max_v(change, hd_friction4(&va, &vb, x, x->rax1, x->ray1, x->rbx1, x->rby1,
                                           x->mass_t1, x->mu, x1, &x->jt1));
    change = hd_max_v(change, hd_friction4(&va, &vb, x, x->rax2, x->ray2, x->rbx2, x->rby2,
                                           x->mass_t2, x->mu, x2, &x->jt2));
    *pa = va;
    *pb = vb;
    return change;
}

/* rows.h's hd_correct_unit for one row in four lanes: a lane whose excess is not positive
 * keeps its shifts. */
static HD_HOT void hd_correct4(hd_twist4 *sa, hd_twist4 *sb, const hd_lanes *x, hd_v4 rax,
                               hd_v4 ray, hd_v4 rbx, hd_v4 rby, hd_v4 base, hd_v4 mass_n)
{
    const hd_v4 zero = {0.0, 0.0, 0.0, 0.0};
    const hd_v4 fraction = {HD_CORRECTION, HD_CORRECTION, HD_CORRECTION, HD_CORRECTION};
    const hd_v4 most = {HD_MAX_CORRECTION, HD_MAX_CORRECTION, HD_MAX_CORRECTION,
                        HD_MAX_CORRECTION};
    const hd_v4 excess =
        base - hd_normal_velocity4(*sa, *sb, rax, ray, rbx, rby, x->nx, x->ny);
    const hd_m4 on = ~(excess <= zero);
    const hd_v4 amount = hd_min_v(fraction * excess, most) * mass_n;
    hd_twist4 a = *sa, b = *sb;
    hd_push4(&a, &b, x, rax, ray, rbx, rby, amount * x->nx, amount * x->ny);
    *sa = hd_pick_twist(on, a, *sa);
    *sb = hd_pick_twist(on, b, *sb);
}

/* Sets of lanes solved together, all gathered before any is scattered (a colour's blocks
 * share no moving body): each set's solve is one long chain of dependent operations, and
 * only with GCC's scheduling before register allocation (-fschedule-insns, setup.py)
 * do the sets' chains overlap. */
#define HD_GROUP 2

/* block4 over the `n` sets of lanes from x; their changes fold in order into `most`, as
 * one set at a time would fold them. */
static HD_HOT void hd_solve_sets(hd_lanes *x, int n, double *velocity, hd_v4 *most)
{
    hd_twist4 a[HD_GROUP], b[HD_GROUP];
    hd_v4 change[HD_GROUP];
#pragma GCC unroll 4
    for (int g = 0; g < n; ++g) {
        a[g] = hd_gather(velocity, x[g].a);
        b[g] = hd_gather(velocity, x[g].b);
    }
#pragma GCC unroll 4
    for (int g = 0; g < n; ++g)
        change[g] = hd_block4(x + g, a + g, b + g);
#pragma GCC unroll 4
    for (int g = 0; g < n; ++g) {
        hd_scatter(velocity, x[g].a, a[g]);
        hd_scatter(velocity, x[g].b, b[g]);
        *most = hd_max_v(*most, change[g]);
    }
}

/* correct4 over both rows of the `n` sets of lanes from x. */
static HD_HOT void hd_correct_sets(const hd_lanes *x, int n, double *shift)
{
    hd_twist4 a[HD_GROUP], b[HD_GROUP];
#pragma GCC unroll 4
    for (int g = 0; g < n; ++g) {
        a[g] = hd_gather(shift, x[g].a);
        b[g] = hd_gather(shift, x[g].b);
    }
#pragma GCC unroll 4
    for (int g = 0; g < n; ++g) {
        const hd_lanes *y = x + g;
        hd_correct4(a + g, b + g, y, y->rax1, y->ray1, y->rbx1, y->rby1, y->base1, y->mass_n1);
        hd_correct4(a + g, b + g, y, y->rax2, y->ray2, y->rbx2, y->rby2, y->base2, y->mass_n2);
    }
#pragma GCC unroll 4
    for (int g = 0; g < n; ++g) {
        hd_scatter(shift, x[g].a, a[g]);
        hd_scatter(shift, x[g].b, b[g]);
    }
}

/* A velocity pass over `count` sets of lanes of one colour, HD_GROUP at a time, their
 * changes into `most`. */
static HD_HOT void hd_solve_colour_sets(hd_lanes *lanes, long count, double *velocity,
                                        hd_v4 *most)
{
    long k = 0;
    for (; k + HD_GROUP <= count; k += HD_GROUP)
        hd_solve_sets(lanes + k, HD_GROUP, velocity, most);
    for (; k < count; ++k)
        hd_solve_sets(lanes + k, 1, velocity, most);
}

/* One pass over `count` lanes of one colour. */
HD_PER_CPU static double hd_pass_lanes(hd_lanes *lanes, long count, double *velocity,
                                       double largest)
{
    hd_v4 most = {largest, largest, largest, largest};
    hd_solve_colour_sets(lanes, count, velocity, &most);
    for (int l = 0; l < HD_LANES; ++l)
        largest = hd_max(largest, most[l]);
    return largest;
}

/* One velocity pass on this thread over the `count` colours in use (`colours`, in
 * order), each colour's sets of lanes and then its other units, as hd_sweep takes them
 * with hd_pass_chunk and hd_pass_singles, without its calls per colour: a pile's levels
 * hold one set of lanes or none. The largest change, a maximum (a NaN change counts for
 * none), is hd_sweep's in any order of folding. */
HD_PER_CPU static double hd_pass_colours(hd_contact_model *m, const int *colours, int count)
{
    const struct hd_wide *w = m->wide;
    hd_v4 most = {0.0, 0.0, 0.0, 0.0};
    double largest = 0.0;
    for (int i = 0; i < count; ++i) {
        const int c = colours[i];
        hd_solve_colour_sets(w->lanes + w->lane_start[c], w->lane_start[c + 1] - w->lane_start[c],
                             m->velocity, &most);
        largest = hd_singles_of(m, c, largest);
    }
    for (int l = 0; l < HD_LANES; ++l)
        largest = hd_max(largest, most[l]);
    return largest;
}

/* One pass of the position correction over `count` lanes of one colour. */
HD_PER_CPU static void hd_correct_lanes(const hd_lanes *lanes, long count, double *shift)
{
    long k = 0;
    for (; k + HD_GROUP <= count; k += HD_GROUP)
        hd_correct_sets(lanes + k, HD_GROUP, shift);
    for (; k < count; ++k)
        hd_correct_sets(lanes + k, 1, shift);
}
#else
static double hd_pass_colours(hd_contact_model *m, const int *colours, int count)
{
    double largest = 0.0;
    for (int i = 0; i < count; ++i)
        largest = hd_singles_of(m, colours[i], largest);
    return largest;
}

static double hd_pass_lanes(hd_lanes *lanes, long count, double *velocity, double largest)
{
    (void)lanes;
    (void)count;
    (void)velocity;
    return largest;
}

static void hd_correct_lanes(const hd_lanes *lanes, long count, double *shift)
{
    (void)lanes;
    (void)count;
    (void)shift;
}
#endif

/* Sets of lanes in a chunk of a colour shared between two threads (crew.h), at least. */
#define HD_CHUNK 8

/* The velocity passes and the position correction of one island (hd_wide_solve): the
 * colour at hand and the sets of lanes of each of its chunks when two threads share it,
 * and the rows' depths for the correction. */
typedef struct {
    hd_contact_model *m;
    const double *base;
    int colour;
    long chunk_sets;
} hd_passes;

/* Lanes `from` to `to` - 1 of chunk `chunk` of the colour at hand. */
static void hd_chunk_lanes(const hd_passes *job, long chunk, long *from, long *to)
{
    const struct hd_wide *w = job->m->wide;
    *from = w->lane_start[job->colour] + chunk * job->chunk_sets;
    const long end = w->lane_start[job->colour + 1];
    *to = *from + job->chunk_sets < end ? *from + job->chunk_sets : end;
}

/* hd_chunk: a velocity pass over a chunk of the colour's blocks. */
static double hd_pass_chunk(void *passes, long chunk)
{
    hd_passes *job = passes;
    long from, to;
    hd_chunk_lanes(job, chunk, &from, &to);
    return hd_pass_lanes(job->m->wide->lanes + from, to - from, job->m->velocity, 0.0);
}

/* A velocity pass over the colour's units that are not in lanes, in their order. */
static double hd_pass_singles(void *passes)
{
    const hd_passes *job = passes;
    return hd_singles_of(job->m, job->colour, 0.0);
}

/* hd_chunk: a pass of the position correction over a chunk of the colour's blocks. */
static double hd_correct_chunk(void *passes, long chunk)
{
    hd_passes *job = passes;
    long from, to;
    hd_chunk_lanes(job, chunk, &from, &to);
    hd_correct_lanes(job->m->wide->lanes + from, to - from, job->m->shift);
    return 0.0;
}

/* A pass of the position correction over the colour's units not in lanes, in order. */
static double hd_correct_singles(void *passes)
{
    hd_passes *job = passes;
    hd_contact_model *m = job->m;
    const struct hd_wide *w = m->wide;
    for (long s = w->single_start[job->colour]; s < w->single_start[job->colour + 1]; ++s)
        hd_correct_unit(m->units + w->single[s], m->rows, job->base, m->shift);
    return 0.0;
}

/* One pass of `chunk` and `singles` over the `count` colours the island's units have
 * (`colours`, in order): on the crew where there is one (each colour's chunks to
 * whichever thread takes them first, its other units on this thread meanwhile), else on
 * this thread; the largest change. A
 * colour's units share no moving body, so each is solved as one thread would solve it,
 * and the largest change, a maximum of numbers (a NaN change counts for none either way),
 * is one thread's too. */
static double hd_sweep(hd_passes *job, const int *colours, int count, struct hd_crew *crew,
                       hd_chunk chunk, double (*singles)(void *))
{
    const struct hd_wide *w = job->m->wide;
    double largest = 0.0;
    for (int k = 0; k < count; ++k) {
        const int c = colours[k];
        job->colour = c;
        const long sets = w->lane_start[c + 1] - w->lane_start[c];
        if (crew == NULL || sets == 0) {
            job->chunk_sets = sets;
            largest = hd_max(largest, sets > 0 ? chunk(job, 0) : 0.0);
            if (w->single_start[c + 1] > w->single_start[c])  /* none: a change of 0 */
                largest = hd_max(largest, singles(job));
            continue;
        }
        const long fewest = (sets + HD_MOST_CHUNKS - 1) / HD_MOST_CHUNKS;
        job->chunk_sets = fewest > HD_CHUNK ? fewest : HD_CHUNK;
        largest = hd_max(largest, hd_crew_share(crew, chunk, job,
                                                (sets + job->chunk_sets - 1) / job->chunk_sets,
                                                singles));
    }
    return largest;
}

/* The crew of an island of `size` units, woken: where the model asks for two threads and
 * the island is big enough to gain (the worker started on first use), else NULL. */
static struct hd_crew *hd_crew_for(hd_contact_model *m, long size)
{
    if (size < HD_CREW_UNITS || m->threads < 2)
        return NULL;
    if (m->crew == NULL)
        m->crew = hd_crew_new();  /* NULL: no second thread to be had */
    if (m->crew != NULL)
        hd_crew_begin(m->crew);
    return m->crew;
}

int hd_wide_solve(hd_contact_model *m, long wide, int known, int levels, const long *members,
                  long size, long passes, double scale, double h, double *base, long *ran)
{
    if (hd_reserve(m, wide, size) < 0)
        return -1;
    struct hd_wide *w = m->wide;
    long *sorted = w->sorted + (members - m->order), *colour_start = w->colour_start[wide];
    if (!known && levels)
        hd_level_runs(m, members, size, sorted, colour_start);
    else if (!known)
        hd_colour_units(m, members, size, sorted, colour_start);
    /* Each colour's blocks four to a set of lanes, the rest of it one by one (the units
     * that fit no colour one by one in their order). */
    long lanes = 0, singles = 0;
    /* The colours the island's units have, in order: a pass skips the others without
     * looking at them (a pile's levels are a few of the HD_COLOURS + 1). */
    int colours[HD_COLOURS + 1], used = 0;
    for (int c = 0; c <= HD_COLOURS; ++c) {
        w->lane_start[c] = lanes;
        w->single_start[c] = singles;
        if (colour_start[c + 1] > colour_start[c])
            colours[used++] = c;
        long pair[HD_LANES];
        int filled = 0;
        for (long k = colour_start[c]; k < colour_start[c + 1]; ++k) {
            if (k + 2 * HD_AHEAD < size)
                hd_prefetch(m->units + sorted[k + 2 * HD_AHEAD], 0);
            if (k + HD_AHEAD < size)
                hd_prefetch_rows(m, m->units[sorted[k + HD_AHEAD]].first, 0);
            const long u = sorted[k];
            if (HD_VECTORS && c < HD_COLOURS && m->units[u].pair) {
                pair[filled++] = u;
                if (filled == HD_LANES) {
                    hd_load_lanes(m, pair, filled, w->lanes + lanes++);
                    filled = 0;
                }
            } else {
                w->single[singles++] = u;
            }
        }
        if (filled == 1)  /* one block alone: cheaper one by one than in padded lanes */
            w->single[singles++] = pair[0];
        else if (filled > 0)
            hd_load_lanes(m, pair, filled, w->lanes + lanes++);
    }
    /* A big island's colours last first (contact/islands.py: coloured), as its passes and
     * position correction take them; a small island's levels in their order. */
    for (int i = 0; !levels && i < used / 2; ++i) {
        const int c = colours[i];
        colours[i] = colours[used - 1 - i];
        colours[used - 1 - i] = c;
    }
    w->lane_start[HD_COLOURS + 1] = lanes;
    w->single_start[HD_COLOURS + 1] = singles;
    hd_passes job = {m, base, 0, 0};
    int converged = 0;
    struct hd_crew *crew = hd_crew_for(m, size);
    *ran = 0;
    while (*ran < passes && !converged) {
        const double largest = crew == NULL ? hd_pass_colours(m, colours, used)
                               : hd_sweep(&job, colours, used, crew, hd_pass_chunk,
                                          hd_pass_singles);
        converged = largest <= m->converged * scale;
        *ran += 1;
    }
    for (long k = 0; k < lanes; ++k) {
        for (int l = 0; k + 1 < lanes && l < HD_LANES && w->lanes[k + 1].first[l] >= 0; ++l)
            hd_prefetch_rows(m, w->lanes[k + 1].first[l], 1);
        hd_store_lanes(m, w->lanes + k, h, base);
    }
    for (long s = 0; s < singles; ++s) {
        const hd_unit *u = m->units + w->single[s];
        for (long i = u->first; i <= u->first + u->pair; ++i)
            base[i] = hd_depth_after(m, m->rows + i, h);
    }
    const int deep = hd_deepest_beyond(m, members, size, m->units[sorted[0]].first, base);
    crew = deep ? hd_crew_for(m, size) : NULL;
    for (int iteration = 0; deep && iteration < HD_POSITION_ITERATIONS; ++iteration)
        hd_sweep(&job, colours, used, crew, hd_correct_chunk, hd_correct_singles);
    return converged;
}
