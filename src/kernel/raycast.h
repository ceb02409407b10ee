/* Laser ray casts (raycast.c), the twin of sensors/laser.py: cast.
 */
#ifndef HECKER_DYNAMICS_RAYCAST_H
#define HECKER_DYNAMICS_RAYCAST_H

/* A body the broad phase keeps for a scan: the nearest a hit on it can be, and which. */
typedef struct {
    double near;
    long body;
} hd_ray_body;

/* A laser's fixed surfaces and the other bodies' shapes in their CM frames. */
typedef struct {
    long body_count;
    long *circle_first, *edge_first; /* body_count + 1 each: each body's shapes */
    double *reach;                   /* bounding radius about the CM plus SLACK of the twin */
    double *circles;                 /* 3 per circle: CM-frame center x, y, radius */
    double *edges;                   /* 4 per edge: CM-frame start x, y, span x, y */
    long wall_count;
    double *walls;                   /* 4 per wall: point x, y, unit normal x, y */
    double range_max;
    /* scratch of a scan */
    hd_ray_body *order;              /* body_count */
    double *circle_world;            /* 3 per circle of one body: mx, my, |m|^2 - r^2 */
    double *edge_world;              /* 5 per edge of one body: ax, ay, ex, ey, perp_dot(a, e) */
} hd_laser;

/* The scratch of a laser whose fields the caller has filled; -1 out of memory. */
int hd_laser_prepare(hd_laser *l);
void hd_laser_free(hd_laser *l);

/* The distance along each of the `rays` unit `directions` (x, y pairs) from (ox, oy) to
 * its first hit within range_max, +inf for none, into `best`. The bodies are at CM state
 * `q` (x, y, angle per body) with the cosines and sines of their angles `c`, `s`; ray k
 * points about `first` + k `increment` rad (for culling only). */
void hd_laser_cast(hd_laser *l, const double *q, const double *c, const double *s,
                   double ox, double oy, const double *directions, long rays, double first,
                   double increment, double *best);

#endif
