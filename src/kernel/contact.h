/* The contact pass in C: hecker_dynamics/contact/solver.py, its parts and
 * contact/collision.py, repeated operation for operation (and so bit for bit, but for
 * math.hypot, which CPython computes itself and C's hypot may round differently in the
 * last bit: only circles use it).
 *
 * Each C file has the name of the Python module it mirrors: manifold.c the narrow phase
 * (contact/collision.py), contact.c the model, detect.c the broad phase and detection
 * (contact/detect.py), and the response (contact/solver.py: ContactPass.resolve) in
 * solver.c with warm.c, islands.c, solve.c, sleep.c and rows.h (contact/warm.py,
 * contact/islands.py, contact/solve.py, contact/sleep.py, contact/rows.py; solver.h joins
 * them).
 */
#ifndef HECKER_DYNAMICS_CONTACT_H
#define HECKER_DYNAMICS_CONTACT_H

#include "floats.h"

/* The constants of contact/solve.py, contact/detect.py, contact/warm.py,
 * contact/islands.py and contact/sleep.py; the binding exports them and
 * test/contact/test_compiled.py checks them. */
#define HD_WORK 600
#define HD_MIN_ITERATIONS 6
#define HD_MAX_ITERATIONS 40
#define HD_SETTLE 625
#define HD_CONVERGED 1e-13
#define HD_MAX_CONDITION 1000.0
#define HD_MARGIN 5e-3
#define HD_MATCH 1e-2
#define HD_FRICTION_CARRY 0.5
#define HD_SLOP 1e-4
#define HD_CORRECTION 0.2
#define HD_MAX_CORRECTION 0.05
#define HD_POSITION_ITERATIONS 4
#define HD_MAX_SUBSTEPS 256
#define HD_SLEEP_SPEED 0.05
#define HD_TIME_TO_SLEEP 0.5


/* A point of a manifold: halfway between the surfaces, unit normal from the first shape
 * to the second, penetration depth (negative for a gap within the margin). */
typedef struct {
    double px, py, nx, ny, depth;
} hd_found;

/* A part in the fixed frame (circle: x, y, radius in `reals`; polygon: count vertices,
 * then count outward normals if it collides with bodies). */
enum hd_part_kind { HD_CIRCLE = 0, HD_POLYGON = 1, HD_OUTLINE = 2 /* vertices only */ };

typedef struct {
    int kind;
    long count;     /* vertices of a polygon */
    double *local;  /* body axes, relative to the CM: as `placed`, below */
    double *placed; /* circle: x, y, r; polygon: x0, y0, ..., then nx0, ny0, ... */
    double bounds[4];  /* x0, x1, y0, y1 of the placed part */
} hd_part;

int hd_polygon_polygon(const double *va, const double *na, long ka, const double *vb,
                       const double *nb, long kb, double margin, hd_found *out);
int hd_polygon_circle(const double *v, const double *n, long k, double cx, double cy,
                      double radius, double margin, hd_found *out);
int hd_circle_circle(double ax, double ay, double ra, double bx, double by, double rb,
                     double margin, hd_found *out);
int hd_half_plane_polygon(double nx, double ny, double offset, const double *v, long k,
                          double margin, hd_found *out);
int hd_half_plane_circle(double nx, double ny, double offset, double cx, double cy,
                         double radius, double margin, hd_found *out);

/* A contact found by detection: bodies a (-1: a wall) and b, point, normal a -> b, depth, material,
 * and the names of its two parts (key, as in contact/detect.py: Contact); `points`: how many
 * contacts its pair of parts has, all found together, one after the other (and a key is found once
 * a detection, so they are the run of its key that contact/islands.py: schedule groups). */
typedef struct {
    long a, b;
    double px, py, nx, ny, depth, e, mu;
    long key[4];
    int points;
} hd_contact;

/* One row of the impulse solver (contact/rows.py: ContactRow); `points` as its contact's. */
typedef struct {
    long a, b;  /* body indices into the velocity table; a wall is the last slot */
    double rax, ray, rbx, rby, nx, ny, mass_n, mass_t, target, mu, jn, jt, depth;
    double im_a, ii_a, im_b, ii_b, approach, carry;
    double slop;  /* the smaller of its bodies' (contact/solve.py: slop) */
    long key[4];
    int points;
} hd_row;

/* A unit of the velocity solver: the single row `first`, or (pair) the two-point
 * manifold of rows first and first + 1 solved as one block, with its effective-mass
 * matrix K = [k11 k12; k12 k22] and K's inverse (contact/rows.py: Block). */
typedef struct {
    long first;
    int pair;
    double k11, k12, k22, inv11, inv12, inv22;
} hd_unit;

/* A contact's impulses kept for warm starting: its point in body b's axes. */
typedef struct {
    long key[4];
    double lx, ly, jn, jt;
    int used;
} hd_warm;

typedef struct hd_contact_model {
    long bodies;
    double *inverse_mass, *inverse_inertia, *reach, *slop;  /* per body */
    long *part_first;  /* bodies + 1: the parts of body i are part_first[i] .. [i + 1] - 1 */
    hd_part *parts;
    long part_count, max_vertices;
    long walls;
    double *wall;       /* per wall: nx, ny, offset, restitution, friction */
    long *wall_first;   /* walls + 1, into wall_body */
    long *wall_body;
    long colliding_count;
    long *colliding;    /* sorted */
    /* Which pairs collide (contact/materials.py: PairMaterials): per body its class (-1: in no
     * group), per pair of classes the group of their material (-1: none), per group its
     * restitution and friction, and the pairs (i, j), i < j, sorted, that a group names
     * but do not collide. */
    long *body_class;
    long class_count;
    long *class_group;  /* class_count x class_count */
    double *material;
    long apart_count;
    long *apart;
    double threshold;  /* restitution threshold (m/s) */
    double lead;       /* the bounce's share of the step's change (contact/solver.py: follow) */
    double converged;  /* the passes' tolerance (contacts.converged; HD_CONVERGED by default) */
    double thickness;  /* of the thinnest colliding part */
    /* The map's boxes (contact/detect.py: Detection._static_contacts): static_count convex
     * parts fixed in the world (`placed` only), their bounds (x0, x1, y0, y1 each), their
     * restitution and friction, and the bodies that collide with them, sorted. */
    long static_count;
    hd_part *statics;
    double *static_bounds;
    double static_material[2];
    long static_body_count;
    long *static_body;
    /* The bodies whose travel sets the sub-steps (contact/solver.py: ContactPass._swept):
     * the colliding bodies and the map's, sorted. */
    long swept_count;
    long *swept;
    /* Working memory, kept from call to call, and the warm-start impulses. */
    int *placed_flag, *touched;
    /* The broad phase's boxes, as columns so that the sweep reads each edge contiguously:
     * colliding_count left edges, then as many right, bottom and top edges, and the box's
     * body; in the last detection's order once sweep_order is 1. */
    double *sweep;
    long *sweep_body;
    int sweep_order;
    /* The sweep's bands in y (contact.c: hd_list_bands): per band (colliding_count at most)
     * where its boxes end and a cursor; the boxes band by band, their left, bottom and top
     * edges as columns (band_capacity each) and their bodies; per box where its pairs may
     * be (from, to). */
    long *band_end, *band_next, *band_from, *band_to, *band_body;
    double *band_edge;
    long band_capacity;
    hd_found *found;
    hd_contact *contacts;
    long contact_count, contact_capacity;
    hd_row *rows;
    hd_unit *units;     /* row_capacity of them */
    /* The islands (row_capacity each, island_start one more): the units in island order,
     * each unit's island, where each island starts, and a cursor per island. */
    long *order, *unit_island, *island_start, *island_fill;
    long *parent, *island_of;  /* bodies + 1: union-find over the bodies, island of a root */
    long row_capacity;
    /* The units the islands above (island_count of them) and wide.h's colours were made
     * for: per unit its body a, then body b twice plus its pair flag (seen_count units,
     * room for seen_capacity); islands_known: 0 while they were not, or are no more. */
    long *seen;
    long seen_count, seen_capacity, island_count;
    int islands_known;
    double *velocity, *arrived, *before, *shift, *poses;  /* (bodies + 1) x 3 */
    double *cos_sin;    /* bodies x 2: of each placed body's angle */
    /* bodies x 2: of each touched body's turn back from the step's end to its start
     * (contact/solver.py: ContactPass._carry_back). */
    double *turn_cos_sin;
    hd_warm *warm;      /* in the order of the rows they came from */
    long warm_count, warm_capacity;
    long *warm_table;   /* open addressing: the first impulse of each key, or -1 */
    long warm_table_size;
    int warm_indexed;   /* 1 while warm_table indexes `warm`: built only when needed */
    long warm_awake;    /* the first impulse after the sleeping islands' */
    /* Sleeping (contact/sleep.py: Sleep._doze): on or off; per body whether it may sleep
     * (calm), its rest time (s) and its sleeping island (the island's lowest body; -1
     * awake); per island, whether an awake body touched it in this detection (wake), and
     * whether any did (woken). */
    int sleep, woken;
    int *calm, *wake;
    double *rested;
    long *island;
    /* The joint pass whose velocity rows hd_resolve sweeps with the contacts (coupled.h;
     * NULL: none), set by the caller for the call, and the rows' working memory. */
    struct hd_joint_model *joints;
    struct hd_coupled *coupled;
    struct hd_wide *wide;  /* wide.h's working memory, made on first use */
    /* The most passes a small island of at least HD_LEVEL_UNITS units ran last step, and
     * whether this step's went through wide.h's lanes (solve.c: hd_solve_velocities). */
    long level_passes;
    int level_lanes;
    /* Threads of the big islands' velocity passes (1 or 2; wide.h: HD_CREW_UNITS) and the
     * second one's crew (crew.h), started on first use. */
    int threads;
    struct hd_crew *crew;
} hd_contact_model;

/* 0 on success, -1 out of memory. */
int hd_contact_prepare(hd_contact_model *m);
void hd_contact_free(hd_contact_model *m);
/* The contacts at q (m->contacts, m->contact_count) of the awake bodies, marking in
 * m->wake the sleeping islands an awake body touches; -1 out of memory. */
int hd_detect(hd_contact_model *m, const double *q);
/* contact/solver.py: ContactPass.resolve after a step from (q0, v0); q1 and v1 change in place,
 * sleeping bodies back at (q0, v0); -1 out of memory. */
int hd_resolve(hd_contact_model *m, double *q1, double *v1, const double *q0,
               const double *v0, double h);
/* After the warm-start impulses were replaced: group them by their parts' names (sorted,
 * keeping their order within a name). */
void hd_set_warm(hd_contact_model *m);

#endif
