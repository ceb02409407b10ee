/* The compiled kernel of hecker_dynamics: force terms and explicit integrators in C.
 *
 * It does what the Python modules dynamics/forces.py and dynamics/model.py (the
 * accelerations, for every scene) and integrators/methods.py (the explicit methods, for
 * scenes without contacts) do, in the same order of floating-point operations as their
 * plain-float path; the build must not contract a * b + c into a fused multiply-add
 * (-ffp-contract=off). How far the results agree with Python's is stated once, in
 * hecker_dynamics/dynamics/kernel.py. Python stays the reference; this is its fast path.
 *
 * State layout, as in Python: q[3 i .. 3 i + 2] = (x_CM, y_CM, angle) of body i and
 * v[3 i ..] = (vx_CM, vy_CM, omega), each a C-contiguous (N, 3) array of doubles.
 */
#ifndef HECKER_DYNAMICS_KERNEL_H
#define HECKER_DYNAMICS_KERNEL_H

#include <float.h>
#include <math.h>
#include <stddef.h>

/* |(x, y)|: sqrt of the sum of squares where it neither underflows nor overflows, else
 * hypot (geometry/planar.py: `magnitude`), so that C and Python round it alike; C's hypot
 * and CPython's math.hypot may differ in the last bit. */
static inline double hd_length(double x, double y)
{
    const double square = x * x + y * y;
    if (square >= DBL_MIN && square <= DBL_MAX)
        return sqrt(square);
    return hypot(x, y);
}

/* Exported names carry the prefix hd_: a plain `advance` would be bound to glibc's. */

/* The kinds of force term, each with its integer and real columns per instance (the
 * Python packing in hecker_dynamics/dynamics/kernel.py writes the same layout). */
enum hd_term_kind {
    HD_GRAVITY = 1,         /* ints: body;                 reals: wx, wy (m g)            */
    HD_ANCHOR_SPRING = 2,   /* ints: body;                 reals: lx, ly, ax, ay, k, L0, c */
    HD_BODY_SPRING = 3,     /* ints: a, b;                 reals: lax, lay, lbx, lby, k, L0, c */
    HD_CENTER_DRAG = 4,     /* ints: body, quadratic;      reals: c                       */
    HD_POINT_DRAG = 5,      /* ints: body, quadratic;      reals: lx, ly, c               */
    HD_ANGULAR_DAMPING = 6, /* ints: body;                 reals: c                       */
    HD_WRENCH = 7  /* ints: body, axes, owner, at_point; reals: fx, fy, torque, px, py */
};

typedef struct {
    int kind;
    long count;
    long *ints;     /* count x hd_int_columns(kind) */
    double *reals;  /* count x hd_real_columns(kind) */
} hd_term;

typedef struct {
    long bodies;
    double *inverse_mass;  /* 3 per body: 1/m, 1/m, 1/I (NULL for a program of inputs) */
    long term_count;
    hd_term *terms;
} hd_program;

int hd_int_columns(int kind);   /* 0 for an unknown kind */
int hd_real_columns(int kind);

/* Scratch space of one evaluation: cos and sin per body, the wrench per body. */
typedef struct {
    double *cos, *sin, *wrench;
} hd_scratch;

/* The summed force and torque per body into scratch->wrench (3 N), and, with `oriented`,
 * each body's cos and sin into scratch->cos and scratch->sin: the terms of `program`, then
 * those of `inputs` (may be NULL). */
void hd_wrench(const hd_program *program, const hd_program *inputs, int oriented,
               const double *q, const double *v, hd_scratch *scratch);

/* (ax, ay, alpha) per body into `out` (3 N): the terms of `program`, then those of
 * `inputs` (may be NULL), summed per body and divided by mass and inertia (F = M a, Eq. 5;
 * tau = I alpha, Eq. 14). `oriented`: some term needs the bodies' angles. */
void hd_accelerations(const hd_program *program, const hd_program *inputs, int oriented,
                      const double *q, const double *v, double *out, hd_scratch *scratch);

/* Each spring's potential energy at q, k (|d| - L0)^2 / 2, added to `energy` and `excess`
 * at the unit of its first body (`unit`: one per body), term by term in the program's
 * order and spring by spring within each, as dynamics/divergence.py's plain-float loop adds them,
 * so that the two give the same bits. */
void hd_unit_spring_potential(const hd_program *program, const double *q, const long *unit,
                              double *energy, double *excess, hd_scratch *scratch);

/* The rows of the energy bound's budget (dynamics/divergence.py: ROOT ... MOTOR_RATE),
 * each one value per unit. */
enum hd_budget_row { HD_BUDGET_ROOT, HD_BUDGET_WORK, HD_BUDGET_RATE, HD_BUDGET_INPUT_RATE,
                     HD_BUDGET_POWER, HD_BUDGET_ENERGY, HD_BUDGET_EXCESS, HD_BUDGET_LIMIT,
                     HD_BUDGET_MOTOR_ROOT, HD_BUDGET_MOTOR_RATE, HD_BUDGET_ROWS };

/* Each unit's B = K + U_springs at (q, v) into the budget's ENERGY row, and B less each
 * body's kinetic energy up to its floor into its EXCESS row. `statics`: the bodies'
 * masses, then their moments of inertia, then their floors; `unit`: one per body, in
 * [0, units); `springs` (NULL: none) the springs' program. */
void hd_unit_energy(const hd_program *springs, const double *q, const double *v, long bodies,
                    const double *statics, const long *unit, long units, double *budget,
                    hd_scratch *scratch);

/* One check of the energy bound (dynamics/divergence.py: EnergyBound._check): each unit's budget
 * advanced by `seconds` (ROOT by half the rates, WORK by the power, MOTOR_ROOT by half the
 * motors' rate), its energy, excess and limit, `growth` times (ROOT + the smaller of
 * sqrt(WORK) and MOTOR_ROOT)^2; returns the largest ratio of excess to limit (0 for none,
 * inf for an energy that is not finite). */
double hd_bound_check(const hd_program *springs, const double *q, const double *v,
                      long bodies, const double *statics, const long *unit, long units,
                      double *budget, double seconds, double growth, hd_scratch *scratch);

/* An embedded Runge-Kutta pair (see hecker_dynamics/integrators/tableaux.py): `a` is S x (S - 1),
 * `error` is error_rows x S. `needs_new_state`: the error estimate reads k_S, the slope
 * at the new state (else k_S is evaluated only for an accepted sub-step); set once, when
 * the pair is made. */
typedef struct {
    long slopes;
    long error_rows;
    int error_order;
    int needs_new_state;
    double *a;
    double *error;
} hd_pair;

enum hd_method { HD_EXPLICIT_EULER = 0, HD_SEMI_IMPLICIT_EULER = 1, HD_VELOCITY_VERLET = 2,
                 HD_RK4 = 3, HD_EMBEDDED = 4 };

/* Most sub-steps of an embedded pair in one step (integrators/methods.py: MAX_SUBSTEPS). */
#define HD_MAX_PAIR_SUBSTEPS 100000L

enum hd_status { HD_ADVANCED = 0, HD_NOT_FINITE = 1, HD_SUBSTEP_UNDERFLOW = 2,
                 HD_TOO_MANY_SUBSTEPS = 3, HD_OUT_OF_MEMORY = 4,
                 HD_UNSOLVED_JOINTS = 5 };

typedef struct {
    long evaluations, substeps, rejected;
} hd_work;

/* Whole steps of one method on one program, with the working memory they need kept from
 * call to call (hd_stepper_init allocates it, hd_stepper_free releases it). `contacts`
 * (NULL: none): the contact pass of contact.h after each step, in sub-steps as the
 * simulation takes them. */
struct hd_contact_model;
struct hd_joint_model;
typedef struct {
    const hd_program *program;
    int method;
    const hd_pair *pair;
    double tolerance;
    struct hd_contact_model *contacts;
    double *memory;
    double *levels;  /* a joint pass's parts, allocated by the first step that needs them */
    double *q_new, *v_new;  /* after HD_NOT_FINITE: the failed state */
    double *start_q, *start_v;  /* hd_stepper_keep_starts: the last step's start (else NULL) */
} hd_stepper;

int hd_stepper_init(hd_stepper *s, const hd_program *program, int method,
                    const hd_pair *pair, double tolerance, struct hd_contact_model *contacts);
void hd_stepper_free(hd_stepper *s);

/* Advance (q, v) by up to `steps` steps of `h`, wrapping angles into [-pi, pi) after each
 * step as the simulation does. Stops early at a step whose new state is not finite
 * (HD_NOT_FINITE: (q, v) keep the last finite state, the stepper's (q_new, v_new) the failed
 * one) or whose adaptive sub-steps fail. `inputs` (NULL: none): the active inputs' program;
 * `*size` is the adaptive method's sub-step size, carried from step to step. `*taken`
 * counts the steps completed. `joints` (NULL: none): the joint pass of joint.h after each
 * step and sub-step, before the contacts, in parts or halves where it needs them
 * (HD_UNSOLVED_JOINTS: still no solution near the end of a part of a step taken in
 * HD_MOST_SUBSTEPS parts). */
int hd_stepper_keep_starts(hd_stepper *s);
int hd_stepper_advance(hd_stepper *s, const hd_program *inputs, int oriented,
                       struct hd_joint_model *joints, double *size, double *q, double *v,
                       double h, long steps, long *taken, hd_work *work);

#endif
