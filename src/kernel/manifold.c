/* The narrow phase: hecker_dynamics/contact/collision.py, operation for operation.
 *
 * Vertices and normals are interleaved x, y pairs of a counter-clockwise convex polygon;
 * each function writes its points to `out` and returns how many (at most 2, or one per
 * vertex for a polygon against a wall).
 */
#include <math.h>

#include "contact.h"
#include "kernel.h"
#include "simd.h"

/* The edge of polygon 1 along whose normal polygon 2 is farthest out, and that distance
 * (contact/collision.py: _max_separation; Python's min keeps the first of equal values). Stops at
 * the first edge farther out than `margin`: the polygons are apart, whichever edge is.
 * Each edge's distance is the same fold of the same products as one edge at a time; they
 * are found two edges at a time (an odd count's last edge twice), and a second edge found
 * past the stop changes nothing. */
static HD_HOT long hd_max_separation(const double *v1, const double *n1, long k1,
                                     const double *v2, long k2, double margin,
                                     double *separation)
{
    long best_edge = 0;
    double best = -INFINITY;
#pragma GCC unroll 2
    for (long i = 0; i < k1; i += 2) {
        const long e = i + 1 < k1 ? i + 1 : i;
        const hd_v2 nx = hd_v2_pair(n1[2 * i], n1[2 * e]),
                    ny = hd_v2_pair(n1[2 * i + 1], n1[2 * e + 1]);
        const hd_v2 vx = hd_v2_pair(v1[2 * i], v1[2 * e]),
                    vy = hd_v2_pair(v1[2 * i + 1], v1[2 * e + 1]);
        hd_v2 s = hd_v2_add(hd_v2_mul(nx, hd_v2_sub(hd_v2_all(v2[0]), vx)),
                            hd_v2_mul(ny, hd_v2_sub(hd_v2_all(v2[1]), vy)));
#pragma GCC unroll 3
        for (long j = 1; j < k2; ++j) {
            const hd_v2 t = hd_v2_add(hd_v2_mul(nx, hd_v2_sub(hd_v2_all(v2[2 * j]), vx)),
                                      hd_v2_mul(ny, hd_v2_sub(hd_v2_all(v2[2 * j + 1]), vy)));
            s = hd_v2_min(t, s);
        }
        double edge[2];
        hd_v2_store(edge, s);
        for (long l = i; l <= e; ++l) {
            if (edge[l - i] > best) {
                best_edge = l;
                best = edge[l - i];
                if (best > margin)
                    break;
            }
        }
        if (best > margin)
            break;
    }
    *separation = best;
    return best_edge;
}

/* The part of segment p0-p1 with n . p <= offset (contact/collision.py: _clip); returns the count.
 */
static int hd_clip(const double *p0, const double *p1, double nx, double ny, double offset,
                   double *out)
{
    const double d0 = nx * p0[0] + ny * p0[1] - offset;
    const double d1 = nx * p1[0] + ny * p1[1] - offset;
    int count = 0;
    if (d0 <= 0.0) {
        out[0] = p0[0];
        out[1] = p0[1];
        count = 1;
    }
    if (d1 <= 0.0) {
        out[2 * count] = p1[0];
        out[2 * count + 1] = p1[1];
        count += 1;
    }
    if (d0 * d1 < 0.0) {
        const double t = d0 / (d0 - d1);
        out[2 * count] = p0[0] + t * (p1[0] - p0[0]);
        out[2 * count + 1] = p0[1] + t * (p1[1] - p0[1]);
        count += 1;
    }
    return count;
}

/* hd_polygon_polygon, inlined into it twice: for two quadrilaterals (boxes, most pairs), where
 * the loops have constant counts and unroll and the next vertex's index is a mask, and for
 * any other pair; the same operations either way. */
static HD_HOT int hd_polygons(const double *va, const double *na, long ka, const double *vb,
                              const double *nb, long kb, double margin, hd_found *out)
{
    double sep_a, sep_b;
    const long edge_a = hd_max_separation(va, na, ka, vb, kb, margin, &sep_a);
    if (sep_a > margin)
        return 0;
    const long edge_b = hd_max_separation(vb, nb, kb, va, ka, margin, &sep_b);
    if (sep_b > margin)
        return 0;
    const int flip = sep_b > sep_a + 0.1 * margin;
    const double *ref_v = flip ? vb : va, *ref_n = flip ? nb : na;
    const double *inc_v = flip ? va : vb, *inc_n = flip ? na : nb;
    const long edge = flip ? edge_b : edge_a, k_ref = flip ? kb : ka, k_inc = flip ? ka : kb;
    const double nx = ref_n[2 * edge], ny = ref_n[2 * edge + 1];
    long incident = 0;
    double lowest = nx * inc_n[0] + ny * inc_n[1];
    for (long i = 1; i < k_inc; ++i) {
        const double d = nx * inc_n[2 * i] + ny * inc_n[2 * i + 1];
        if (d < lowest) {
            incident = i;
            lowest = d;
        }
    }
    const double *c0 = inc_v + 2 * incident, *c1 = inc_v + 2 * ((incident + 1) % k_inc);
    const double *v1 = ref_v + 2 * edge, *v2 = ref_v + 2 * ((edge + 1) % k_ref);
    const double tx = -ny, ty = nx;
    double first[6], second[6];
    if (hd_clip(c0, c1, -tx, -ty, -(tx * v1[0] + ty * v1[1]), first) < 2)
        return 0;
    const int kept = hd_clip(first, first + 2, tx, ty, tx * v2[0] + ty * v2[1], second);
    const double front = nx * v1[0] + ny * v1[1];
    const double normal_x = flip ? -nx : nx, normal_y = flip ? -ny : ny;
    int count = 0;
    for (int p = 0; p < kept; ++p) {
        const double px = second[2 * p], py = second[2 * p + 1];
        const double depth = front - (nx * px + ny * py);
        if (depth >= -margin) {
            out[count] = (hd_found){px + nx * depth / 2.0, py + ny * depth / 2.0, normal_x,
                                    normal_y, depth};
            count += 1;
        }
    }
    return count;
}

int hd_polygon_polygon(const double *va, const double *na, long ka, const double *vb,
                       const double *nb, long kb, double margin, hd_found *out)
{
    if (ka == 4 && kb == 4)
        return hd_polygons(va, na, 4, vb, nb, 4, margin, out);
    return hd_polygons(va, na, ka, vb, nb, kb, margin, out);
}

int hd_polygon_circle(const double *v, const double *n, long k, double cx, double cy,
                      double radius, double margin, hd_found *out)
{
    long edge = 0;
    double sep = -INFINITY;
    for (long i = 0; i < k; ++i) {
        const double s = n[2 * i] * (cx - v[2 * i]) + n[2 * i + 1] * (cy - v[2 * i + 1]);
        if (s > sep) {
            edge = i;
            sep = s;
        }
    }
    if (sep > radius + margin)
        return 0;
    const double *v1 = v + 2 * edge, *v2 = v + 2 * ((edge + 1) % k);
    if (sep > 0.0) {
        const double *ends[2][2] = {{v1, v2}, {v2, v1}};
        for (int e = 0; e < 2; ++e) {
            const double *vertex = ends[e][0], *other = ends[e][1];
            if ((cx - vertex[0]) * (other[0] - vertex[0]) +
                    (cy - vertex[1]) * (other[1] - vertex[1]) <= 0.0) {
                const double dx = cx - vertex[0], dy = cy - vertex[1];
                const double distance = hd_length(dx, dy);
                if (distance > radius + margin || distance == 0.0)
                    return 0;
                const double ux = dx / distance, uy = dy / distance;
                const double depth = radius - distance;
                out[0] = (hd_found){vertex[0] - ux * depth / 2.0, vertex[1] - uy * depth / 2.0,
                                    ux, uy, depth};
                return 1;
            }
        }
    }
    const double ux = n[2 * edge], uy = n[2 * edge + 1];
    const double depth = radius - sep;
    out[0] = (hd_found){cx - ux * (radius - depth / 2.0), cy - uy * (radius - depth / 2.0),
                        ux, uy, depth};
    return 1;
}

int hd_circle_circle(double ax, double ay, double ra, double bx, double by, double rb,
                     double margin, hd_found *out)
{
    const double dx = bx - ax, dy = by - ay;
    const double distance = hd_length(dx, dy);
    const double depth = ra + rb - distance;
    if (depth < -margin)
        return 0;
    const double ux = distance > 0.0 ? dx / distance : 0.0;
    const double uy = distance > 0.0 ? dy / distance : 1.0;
    const double reach = ra - depth / 2.0;
    out[0] = (hd_found){ax + ux * reach, ay + uy * reach, ux, uy, depth};
    return 1;
}

int hd_half_plane_polygon(double nx, double ny, double offset, const double *v, long k,
                          double margin, hd_found *out)
{
    int count = 0;
    for (long i = 0; i < k; ++i) {
        const double x = v[2 * i], y = v[2 * i + 1];
        const double depth = offset - (nx * x + ny * y);
        if (depth > -margin) {
            out[count] = (hd_found){x + nx * depth / 2.0, y + ny * depth / 2.0, nx, ny, depth};
            count += 1;
        }
    }
    return count;
}

int hd_half_plane_circle(double nx, double ny, double offset, double cx, double cy,
                         double radius, double margin, hd_found *out)
{
    const double depth = offset - (nx * cx + ny * cy - radius);
    if (depth <= -margin)
        return 0;
    const double reach = radius - depth / 2.0;
    out[0] = (hd_found){cx - nx * reach, cy - ny * reach, nx, ny, depth};
    return 1;
}
