/* Laser ray casts: sensors/laser.py: cast, surface by surface with its operations in its
 * order, behind a broad phase that only skips what no ray can hit.
 *
 * The Python twin tests every ray against every surface of the bodies within range; here
 * a body is cast only along the rays that sweep its bounding circle (the arc it subtends
 * from the origin, one ray of margin each side), nearest bodies first, and not at all
 * along a ray whose nearest hit so far is closer than the body's bounding circle (Box2D
 * v3 clips a ray's fraction in its dynamic tree the same way). The nearest hit of a ray is
 * the minimum of its hits, which no skipped body lowers and no order changes, so the bits
 * are Python's.
 */
#include <math.h>
#include <stdlib.h>

#include "floats.h"
#include "raycast.h"

int hd_laser_prepare(hd_laser *l)
{
    long most_circles = 1, most_edges = 1;
    for (long b = 0; b < l->body_count; ++b) {
        most_circles = l->circle_first[b + 1] - l->circle_first[b] > most_circles
                       ? l->circle_first[b + 1] - l->circle_first[b] : most_circles;
        most_edges = l->edge_first[b + 1] - l->edge_first[b] > most_edges
                     ? l->edge_first[b + 1] - l->edge_first[b] : most_edges;
    }
    l->order = malloc(((size_t)l->body_count + 1) * sizeof(hd_ray_body));
    l->circle_world = malloc(3 * (size_t)most_circles * sizeof(double));
    l->edge_world = malloc(5 * (size_t)most_edges * sizeof(double));
    return l->order == NULL || l->circle_world == NULL || l->edge_world == NULL ? -1 : 0;
}

void hd_laser_free(hd_laser *l)
{
    if (l == NULL)
        return;
    free(l->circle_first);
    free(l->edge_first);
    free(l->reach);
    free(l->circles);
    free(l->edges);
    free(l->walls);
    free(l->order);
    free(l->circle_world);
    free(l->edge_world);
    free(l);
}

/* A hit where 0 <= t <= range_max (never for NaN), kept if nearer. */
static HD_HOT void hd_keep(double *best, double t, double range_max)
{
    if (t >= 0.0 && t <= range_max && t < *best)
        *best = t;
}

static int hd_nearer(const void *a, const void *b)
{
    const double x = ((const hd_ray_body *)a)->near, y = ((const hd_ray_body *)b)->near;
    return (x > y) - (x < y);
}

/* One body's circles and edges turned into the fixed frame (sensors/laser.py:
 * Laser.distances) and taken relative to the origin as cast does. */
static void hd_place(hd_laser *l, long b, const double *q, double c, double s, double ox,
                     double oy)
{
    const double cmx = q[3 * b], cmy = q[3 * b + 1];
    for (long k = l->circle_first[b], j = 0; k < l->circle_first[b + 1]; ++k, j += 3) {
        const double *circle = l->circles + 3 * k;
        const double x = cmx + (c * circle[0] - s * circle[1]);
        const double y = cmy + (s * circle[0] + c * circle[1]);
        const double mx = ox - x, my = oy - y;
        l->circle_world[j] = mx, l->circle_world[j + 1] = my;
        l->circle_world[j + 2] = mx * mx + my * my - circle[2] * circle[2];
    }
    for (long k = l->edge_first[b], j = 0; k < l->edge_first[b + 1]; ++k, j += 5) {
        const double *edge = l->edges + 4 * k;
        const double ax = cmx + (c * edge[0] - s * edge[1]) - ox;
        const double ay = cmy + (s * edge[0] + c * edge[1]) - oy;
        const double ex = c * edge[2] - s * edge[3], ey = s * edge[2] + c * edge[3];
        l->edge_world[j] = ax, l->edge_world[j + 1] = ay;
        l->edge_world[j + 2] = ex, l->edge_world[j + 3] = ey;
        l->edge_world[j + 4] = ax * ey - ay * ex;
    }
}

/* Ray (dx, dy) against the placed shapes of a body with `circles` circles and `edges`
 * edges. */
static HD_HOT void hd_cast_body(const hd_laser *l, long circles, long edges, double dx,
                                double dy, double *best)
{
    for (long j = 0; j < 3 * circles; j += 3) {
        const double *m = l->circle_world + j;
        const double b = dx * m[0] + dy * m[1];
        const double root = sqrt(b * b - m[2]);
        const double near = -b - root;
        hd_keep(best, near >= 0.0 ? near : -b + root, l->range_max);
    }
    for (long j = 0; j < 5 * edges; j += 5) {
        const double *e = l->edge_world + j;
        const double denominator = dx * e[3] - dy * e[2];
        const double t = e[4] / denominator;
        const double along = (e[0] * dy - e[1] * dx) / denominator;
        if (along >= 0.0 && along <= 1.0)
            hd_keep(best, t, l->range_max);
    }
}

void hd_laser_cast(hd_laser *l, const double *q, const double *c, const double *s,
                   double ox, double oy, const double *directions, long rays, double first,
                   double increment, double *best)
{
    const double turn = 2.0 * HD_PI;
    for (long k = 0; k < rays; ++k)
        best[k] = INFINITY;
    for (long w = 0; w < l->wall_count; ++w) {
        const double *wall = l->walls + 4 * w;
        const double ahead = (wall[0] - ox) * wall[2] + (wall[1] - oy) * wall[3];
        for (long k = 0; k < rays; ++k) {
            const double *d = directions + 2 * k;
            hd_keep(best + k, ahead / (d[0] * wall[2] + d[1] * wall[3]), l->range_max);
        }
    }
    long kept = 0;
    for (long b = 0; b < l->body_count; ++b) {
        if (l->circle_first[b] == l->circle_first[b + 1]
                && l->edge_first[b] == l->edge_first[b + 1])
            continue; /* no shape: the laser's own body */
        const double near = hypot(q[3 * b] - ox, q[3 * b + 1] - oy) - l->reach[b];
        if (near <= l->range_max)
            l->order[kept].near = near, l->order[kept++].body = b;
    }
    qsort(l->order, (size_t)kept, sizeof(hd_ray_body), hd_nearer);
    for (long i = 0; i < kept; ++i) {
        const long b = l->order[i].body;
        const double near = l->order[i].near;
        const long circles = l->circle_first[b + 1] - l->circle_first[b];
        const long edges = l->edge_first[b + 1] - l->edge_first[b];
        hd_place(l, b, q, c[b], s[b], ox, oy);
        const double cx = q[3 * b] - ox, cy = q[3 * b + 1] - oy;
        const double distance = hypot(cx, cy);
        if (near <= 0.0 || !(increment > 0.0) || !isfinite(increment) || rays == 1) {
            /* The origin within the bounding circle, or no sweep to cull along. */
            for (long k = 0; k < rays; ++k)
                if (!(best[k] < near))
                    hd_cast_body(l, circles, edges, directions[2 * k], directions[2 * k + 1],
                                 best + k);
            continue;
        }
        const double half = asin(l->reach[b] / distance);
        double centre = fmod(atan2(cy, cx) - first, turn);
        if (centre < 0.0)
            centre += turn;
        /* Each turn of the sweep that may meet the arc, one ray of margin each side. */
        for (double at = centre - turn; (at - half) / increment <= (double)rays; at += turn) {
            const double low = ceil((at - half) / increment) - 1.0;
            const double high = floor((at + half) / increment) + 1.0;
            if (high < 0.0)
                continue;
            const long k0 = low < 0.0 ? 0 : (long)low;
            const long k1 = high > (double)(rays - 1) ? rays - 1 : (long)high;
            for (long k = k0; k <= k1; ++k)
                if (!(best[k] < near))
                    hd_cast_body(l, circles, edges, directions[2 * k], directions[2 * k + 1],
                                 best + k);
        }
    }
    for (long k = 0; k < rays; ++k)
        best[k] = best[k] + 0.0; /* -0.0 and 0.0 alike as +0.0, as cast does */
}
