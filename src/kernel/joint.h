/* The joint pass in C: hecker_dynamics/contact/joints.py (JointPass.resolve), repeated
 * operation for operation and so bit for bit.
 *
 * A joint is described once (hd_joint, packed by JointPass.kernel_pass); its state (the
 * start pose's references, the counted joint angles, the motors' speeds, the warm-start
 * impulses and Newton multipliers) is loaded before and read back after each call, so
 * Python's JointPass stays the one owner of it. Bodies are the pass's own (local) list:
 * `bodies` maps them to the model's indices.
 */
#ifndef HECKER_DYNAMICS_JOINT_H
#define HECKER_DYNAMICS_JOINT_H

#include "sparse.h"

/* The constants of contact/joints.py and contact/joint_solve.py; the binding exports them and
 * test/contact/test_joints_compiled.py checks them.
 */
#define HD_JOINT_TOLERANCE 1e-12
#define HD_JOINT_ROUNDING (16.0 * 2.220446049250313e-16)
#define HD_NEWTON_ITERATIONS 50
#define HD_CHORD 0.125
#define HD_DRIFT_ITERATIONS 8
#define HD_ACTIVE_SETS 8
#define HD_JOINT_MAX_ITERATIONS 200
#define HD_JOINT_CONVERGED 1e-13
/* contact/joint_solve.py: REFINEMENTS */
#define HD_REFINEMENTS 8
#define HD_MAX_TURN 0.1
#define HD_MAX_RING 1.0
#define HD_RATING_BOUND (1.0 + 1e-9)  /* JointPass.ringing's bound over its rating */
#define HD_MOST_SUBSTEPS 1024L
#define HD_SETTLED_STEPS 4
#define HD_MAX_SPLITS 10  /* the halvings in HD_MOST_SUBSTEPS: the levels of parts */

enum hd_joint_kind { HD_REVOLUTE = 0, HD_PRISMATIC = 1, HD_WELD = 2, HD_ROD = 3, HD_ROPE = 4,
                     HD_GEAR = 5 };
enum hd_row_kind { HD_RIGID = 0, HD_LIMIT = 1, HD_MOTOR = 2, HD_SOFT = 3 };

/* Packed columns per joint (contact/joints.py: JointPass.kernel_pass writes them). */
#define HD_JOINT_INTS 9   /* kind, a, b, lower?, upper?, motor?, spring (or soft weld)?, gear a, b */
#define HD_JOINT_REALS 14 /* point_a (2), point_b (2), axis (2), lower, upper, max_effort,
                             stiffness, damping, rest_angle, length, ratio */
#define HD_JOINT_STATE 5  /* per joint: reference angle, reference translation, counted
                             angle, raw relative angle, motor speed */

typedef struct {
    int kind;
    long a, b;  /* local body indices; a = -1: the fixed frame (point_a in its coordinates) */
    int has_lower, has_upper, has_motor, has_spring;  /* has_spring: a soft weld too */
    long gear_a, gear_b;  /* a gear's two revolute joints (indices into the joints) */
    double point_a[2], point_b[2], axis[2];
    double lower, upper, max_effort, stiffness, damping, rest, length, ratio;
    /* state */
    double reference_angle, reference_along, angle, raw, motor_speed;
} hd_joint;

/* Which entries of two rows meet on a body, per pair of rows a pattern couples (the bodies
 * of the rows' entries are the same at any pose): `pair` holds e << 2 | f for entry e of
 * the row and f of the direction, in contact/joint_solve.py dot's order; the diagonal's for
 * row i at diag[i] .. diag[i + 1], the strict lower triangle's (row i, direction j) and the
 * upper's (row j, direction i) for each slot likewise. */
typedef struct {
    long *diag, *lower, *upper;
    unsigned char *pair;
    /* Per pair, where its row's and its direction's entries are (bytes from the first row
     * and the first direction): hd_matrix walks these instead of finding the rows. */
    long *row_at, *direction_at;
} hd_meets;

/* One scalar constraint (contact/joint_rows.py: JointRow): up to four (body, jx, jy, jw)
 * entries. */
typedef struct {
    int kind, count, scaled;
    int pair;  /* the first of a rigid point's two rows, x then y (soft_joint.c's blocks) */
    long body[4];
    double j[4][3];
    double c, speed, bound, stiffness, damping;
} hd_joint_row;

typedef struct hd_joint_model {
    long joint_count, body_count, row_count, rigid_count;
    long *bodies;          /* body_count model indices */
    double *inverse_mass;  /* 3 per local body */
    double *free_turn;     /* JointPass.free_turn: per body, 1/I, or 0 where its turn is held */
    hd_joint *joints;      /* in the order JointPass solves them */
    long *rigid;           /* the rigid rows' indices */
    long *pins, pin_count; /* JointPass.pins: each rigid point's x row (its y row next) */
    /* Where the factors of all rows' matrices, and of the rigid rows' alone, can be
     * non-zero (contact/sparse.py: Pattern, JointPass.pattern and rigid_pattern). */
    hd_pattern pattern, rigid_pattern;
    hd_meets meets, rigid_meets;
    /* JointPass.parts: the model indices of the bodies whose turning turns a joint's arm. */
    long *turning, turning_count;
    double tolerance, max_turn;  /* JointPass.tolerance and max_turn */
    /* JointPass.share: the velocity stage refines on the Newton matrix's L U; `near`: that
     * L U (low, upper, diag, out) is this pass's, at its positions (JointPass._near). */
    int share, near;
    int plain_pins;  /* every joint a revolute one with no limit, motor or spring (a chain) */
    /* Soft joints (soft_joint.c): the sub-steps of a step (0: this exact pass), and the
     * rows' softness (SoftJoints.hertz, damping_ratio). */
    long substeps;
    double hertz, damping_ratio;
    double *warm, *newton; /* row_count, rigid_count */
    /* The extra impulses the last contact solve added to `warm` (coupled.h), row_count;
     * the velocities before the last velocity stage (3 per body). */
    double *extra, *settled;
    int newton_valid;
    double last_h;
    /* JointPass.remembered, settled_steps and needed: the parts a whole step starts in, the
     * steps in a row that needed no more, and the parts the step under way has needed. */
    long remembered, settled_steps, needed;
    double first_error;  /* JointPass.first_error */
    /* Whether the last pass ended well: m->q, m->rows and m->dir are its final pose, rows
     * and directions (hd_joints_resolve starts from them when it may). */
    int ended;
    /* working memory */
    double *stiffness;     /* per body (hd_ringing) */
    /* JointPass.pinned: per body b, its pins' ends at pinned[pinned_start[b]] ..
     * pinned[pinned_start[b + 1] - 1]. */
    long *pinned_start;
    struct hd_pin_end { double x, y; long other; double reach; } *pinned;
    double *memory, *trig, *angles;  /* trig: cos, sin of `angles` (joint.c: hd_turn_all) */
    hd_joint_row *row_memory, *rows0, *rows, *dir0, *dir;  /* the last four in the first */
    double *start, *q, *moved, *v, *target, *nu, *step, *rhs, *b, *low_bound, *high_bound, *x;
    double *diagonal, *lower, *upper, *low, *diag;
    long *bounded;
    int *flags, *free, *out, *active, *side;
} hd_joint_model;

enum hd_joint_status { HD_JOINTS_OK = 0, HD_JOINTS_OUT_OF_MEMORY = -1, HD_JOINTS_UNSOLVED = -2,
                       HD_JOINTS_MISMATCH = -3 };

/* Allocate the working memory once the joints, bodies, masses and patterns are set; counts
 * the rows (row_count, rigid_count, rigid); HD_JOINTS_MISMATCH if the patterns are not of
 * that many rows, else HD_JOINTS_OUT_OF_MEMORY or OK. */
int hd_joints_prepare(hd_joint_model *m);
void hd_joints_free(hd_joint_model *m);
/* contact/joint_solve.py: dot, J_row . (M^-1 J^T)_direction over the bodies the two share
 * (inline: the soft sweeps take three a pin). */
static inline double hd_joint_dot(const hd_joint_row *row, const hd_joint_row *direction)
{
    double s = 0.0;
    for (int e = 0; e < row->count; ++e)
        for (int f = 0; f < direction->count; ++f)
            if (row->body[e] == direction->body[f])
                s += row->j[e][0] * direction->j[f][0] + row->j[e][1] * direction->j[f][1]
                     + row->j[e][2] * direction->j[f][2];
    return s;
}

/* contact/joint_solve.py: rate, the row's velocity J v (v: 3 per local body). */
static inline double hd_joint_rate(const hd_joint_row *row, const double *v)
{
    double s = 0.0;
    for (int e = 0; e < row->count; ++e) {
        const double *w = v + 3 * row->body[e];
        s += row->j[e][0] * w[0] + row->j[e][1] * w[1] + row->j[e][2] * w[2];
    }
    return s;
}
/* contact/joints.py: JointPass.rows at q (local bodies) into `rows`; returns their count and
 * leaves the cosines and sines of q's angles in m->trig. `values_only`: the plain pins'
 * Jacobians are not wanted. */
long hd_joint_rows(const hd_joint_model *m, const double *q, double h, hd_joint_row *rows,
                   int values_only);
/* contact/joint_solve.py: directions: M^-1 J^T of rows[index[k]] for k < n (index NULL:
 * rows k) into `out`. */
void hd_joint_directions(const hd_joint_model *m, const hd_joint_row *rows, const long *index,
                         long n, hd_joint_row *out);
/* contact/joints.py: JointPass._count_turns at the pose of m->trig, m->q. */
void hd_joint_count_turns(hd_joint_model *m);
/* The last pass's final rows and directions (m->rows, m->dir) as this pass's rows at its start
 * (m->rows0, m->dir0): where the last pass ended is where this one starts. */
void hd_joint_rows_again(hd_joint_model *m);
/* The pass's final m->q and m->v into the model's q1 and v1 of all bodies; marks m->q, m->rows
 * and m->dir the final pose, rows and directions (m->ended). */
void hd_joint_ended(hd_joint_model *m, double *q1, double *v1);
/* contact/joints.py: JointPass.remember, after a whole step. */
void hd_joints_remember(hd_joint_model *m);
/* contact/joints.py: JointPass.parts, for the model's q0 and q1 of all bodies. */
long hd_joints_parts(const hd_joint_model *m, const double *q0, const double *q1);
/* contact/joints.py: JointPass.resolve on the model's (q0, q1, v1) of all bodies, q1 and v1 in
 * place; HD_JOINTS_UNSOLVED (nothing changed but the working memory) when the positions
 * have no solution near the step's end (JointsUnsolved). */
int hd_joints_resolve(hd_joint_model *m, const double *q0, double *q1, double *v1, double h);
/* contact/soft_joints.py: SoftJointPass.resolve, one sub-step of `h` on the model's (q0, q1, v1)
 * of all bodies, q1 and v1 in place (soft_joint.c). */
void hd_soft_joints_resolve(hd_joint_model *m, const double *q0, double *q1, double *v1,
                            double h);

#endif
