/* Integrators: step 7 of the article's algorithm, and the step loop of the simulation.
 *
 * The fixed-step methods repeat hecker_dynamics/integrators/methods.py operation for
 * operation (numpy's element-wise arithmetic rounds each operation as C does); the embedded
 * pairs follow the same controller but sum their stages in their own order.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "floats.h"
#include "simd.h"
#include "contact.h"
#include "joint.h"
#include "kernel.h"

/* math.pi, the same double (strict C has no M_PI). */
typedef struct {
    const hd_program *program, *inputs;
    int oriented;
    long n3;  /* 3 N: the length of q, of v and of the accelerations */
    hd_scratch scratch;
    hd_work *work;
} hd_forces;

static void hd_evaluate(hd_forces *f, const double *q, const double *v, double *a)
{
    f->work->evaluations += 1;
    hd_accelerations(f->program, f->inputs, f->oriented, q, v, a, &f->scratch);
}

/* What a pass over a new state found: whether every value is finite, and the first and
 * last body whose angle lies outside [-pi, pi) (last -1: none), the span the wrapping pass
 * walks (hd_settle): on a large scene some angle crosses +-pi at many steps, few at once. */
typedef struct {
    int finite;
    long first, last;
} hd_check;

/* The sums of such a pass, body by body: x - x is 0 for a finite x and NaN otherwise, and a
 * NaN stays in the sum (positions and velocities two at a time, simd.h). */
typedef struct {
    hd_v2 pairs;
    double angles;
    long first, last;
} hd_tally;

#define HD_TALLY_START {hd_v2_all(0.0), 0.0, 0, -1}

static HD_HOT void hd_tally_body(hd_tally *t, long b, hd_v2 position, hd_v2 velocity,
                                 double theta, double omega)
{
    t->pairs = hd_v2_add(t->pairs, hd_v2_add(hd_v2_sub(position, position),
                                             hd_v2_sub(velocity, velocity)));
    t->angles += (theta - theta) + (omega - omega);
    if (!(theta >= -HD_PI && theta < HD_PI)) {
        if (t->last < 0)
            t->first = b;
        t->last = b;
    }
}

static HD_HOT hd_check hd_tally_end(const hd_tally *t)
{
    double sums[2];
    hd_v2_store(sums, t->pairs);
    return (hd_check){sums[0] + sums[1] + t->angles == 0.0, t->first, t->last};
}

/* Euler's update of N bodies, v1 = v + h a, then q1 = q + h v1 (`symplectic`) or q + h v,
 * with a = w / m per element when `inverse_mass` is not NULL (w in `a`, which may be v1
 * itself: each body's values are read before they are written), else a as given; and the
 * check of the new state in the same pass. One pass a body, its x and y two at a time. */
static HD_HOT hd_check hd_euler_update(const double *q, const double *v, const double *a,
                                       const double *inverse_mass, double *q1, double *v1,
                                       double h, int symplectic, long n)
{
    const hd_v2 step = hd_v2_all(h);
    hd_tally tally = HD_TALLY_START;
    for (long b = 0; b < n; ++b) {
        const long k = 3 * b;
        hd_v2 acceleration = hd_v2_pair(a[k], a[k + 1]);
        double alpha = a[k + 2];
        if (inverse_mass != NULL) {
            acceleration = hd_v2_mul(acceleration,
                                     hd_v2_pair(inverse_mass[k], inverse_mass[k + 1]));
            alpha = alpha * inverse_mass[k + 2];
        }
        const hd_v2 before = hd_v2_pair(v[k], v[k + 1]);
        const hd_v2 after = hd_v2_add(before, hd_v2_mul(step, acceleration));
        const hd_v2 position = hd_v2_add(hd_v2_pair(q[k], q[k + 1]),
                                         hd_v2_mul(step, symplectic ? after : before));
        const double omega = v[k + 2] + h * alpha;
        const double theta = q[k + 2] + h * (symplectic ? omega : v[k + 2]);
        hd_v2_store(v1 + k, after);
        v1[k + 2] = omega;
        hd_v2_store(q1 + k, position);
        q1[k + 2] = theta;
        hd_tally_body(&tally, b, position, after, theta, omega);
    }
    return hd_tally_end(&tally);
}

/* The article's explicit Euler, x += h v and v += h a from the start of the step
 * (integrators/methods.py: ExplicitEuler), or, `symplectic`, semi-implicit Euler: v += h a(q, v),
 * then x += h v with the new velocity (SemiImplicitEuler); the new state's check into
 * `check`. v1 must not be v: the forces are summed into v1 (no array of their own, one
 * stream of memory less on a large scene) and the update turns them into velocities in
 * place, the accelerations w / m taken in the same pass. */
static void hd_euler(hd_forces *f, const double *q, const double *v, double *q1, double *v1,
                     double h, double *a, int symplectic, hd_check *check)
{
    const hd_program *p = f->program;
    const long n = f->n3 / 3;
    const double *inverse_mass = NULL;
    if (p->term_count == 0 && (f->inputs == NULL || f->inputs->term_count == 0))
        hd_evaluate(f, q, v, a);
    else {
        hd_scratch scratch = f->scratch;
        scratch.wrench = a = v1;
        f->work->evaluations += 1;
        hd_wrench(p, f->inputs, f->oriented, q, v, &scratch);
        inverse_mass = p->inverse_mass;
    }
    /* the method a constant in each copy of the loop */
    *check = symplectic ? hd_euler_update(q, v, a, inverse_mass, q1, v1, h, 1, n)
                        : hd_euler_update(q, v, a, inverse_mass, q1, v1, h, 0, n);
}

/* x1 = x + h v + h^2/2 a0; v1 = v + h/2 (a0 + a(x1, v + h a0)) (VelocityVerlet). */
static void hd_velocity_verlet(hd_forces *f, const double *q, const double *v, double *q1,
                               double *v1, double h, double *a0)
{
    double *a1 = a0 + f->n3, *predicted = a1 + f->n3;
    const double half_h2 = 0.5 * h * h, half_h = 0.5 * h;
    hd_evaluate(f, q, v, a0);
    for (long k = 0; k < f->n3; ++k) {
        q1[k] = q[k] + h * v[k] + half_h2 * a0[k];
        predicted[k] = v[k] + h * a0[k];
    }
    hd_evaluate(f, q1, predicted, a1);
    for (long k = 0; k < f->n3; ++k)
        v1[k] = v[k] + half_h * (a0[k] + a1[k]);
}

/* A later stage of RK4 from the last slopes (kq, kv), c = h/2 or h: the slope of q is
 * v + c kv, that of v the acceleration at (q + c kq, v + c kv). */
static void hd_rk4_stage(hd_forces *f, const double *q, const double *v, const double *kq,
                         const double *kv, double c, double *at, double *next_q, double *next_v)
{
    for (long k = 0; k < f->n3; ++k) {
        next_q[k] = v[k] + c * kv[k];
        at[k] = q[k] + c * kq[k];
    }
    hd_evaluate(f, at, next_q, next_v);
}

/* Classical fourth-order Runge-Kutta on (q' = v, v' = a) (RungeKutta4). */
static void hd_rk4(hd_forces *f, const double *q, const double *v, double *q1, double *v1,
                   double h, double *buffer)
{
    const long n3 = f->n3;
    double *k1v = buffer, *k2q = k1v + n3, *k2v = k2q + n3, *k3q = k2v + n3,
           *k3v = k3q + n3, *k4q = k3v + n3, *k4v = k4q + n3, *at = k4v + n3;
    const double half_h = 0.5 * h, sixth_h = h / 6.0;
    hd_evaluate(f, q, v, k1v);  /* k1 = (v, a(q, v)) */
    hd_rk4_stage(f, q, v, v, k1v, half_h, at, k2q, k2v);
    hd_rk4_stage(f, q, v, k2q, k2v, half_h, at, k3q, k3v);
    hd_rk4_stage(f, q, v, k3q, k3v, h, at, k4q, k4v);
    for (long k = 0; k < n3; ++k) {
        q1[k] = q[k] + sixth_h * (v[k] + 2.0 * k2q[k] + 2.0 * k3q[k] + k4q[k]);
        v1[k] = v[k] + sixth_h * (k1v[k] + 2.0 * k2v[k] + 2.0 * k3v[k] + k4v[k]);
    }
}

/* (q', v') = (v, a(q, v)) of the flat state y = (q, v) into `slope`. */
static void hd_rhs(hd_forces *f, const double *y, double *slope)
{
    memcpy(slope, y + f->n3, (size_t)f->n3 * sizeof(double));
    hd_evaluate(f, y, y + f->n3, slope + f->n3);
}

/* out = sum over j < count of (scale c_j) k_j, slope by slope (each element summed in the
 * order of j, as a matrix product would), skipping zero coefficients. */
static void hd_combine(const double *c, long count, double scale, const double *slopes, long m,
                       double *out)
{
    int first = 1;
    for (long j = 0; j < count; ++j) {
        if (c[j] == 0.0)
            continue;
        const double coefficient = scale * c[j], *k = slopes + j * m;
        if (first) {
            for (long i = 0; i < m; ++i)
                out[i] = coefficient * k[i];
            first = 0;
        } else {
            for (long i = 0; i < m; ++i)
                out[i] += coefficient * k[i];
        }
    }
    if (first)
        for (long i = 0; i < m; ++i)
            out[i] = 0.0;
}

/* One number from the scaled error estimates: at most 1 accepts the sub-step
 * (integrators/tableaux.py: EmbeddedPair.error_norm). */
static double hd_error_norm(const hd_pair *pair, const double *scaled, long m)
{
    if (pair->error_rows == 1) {
        double sum = 0.0;
        for (long k = 0; k < m; ++k)
            sum += scaled[k] * scaled[k];
        return sqrt(sum / (double)m);
    }
    double e5 = 0.0, e3 = 0.0;
    for (long k = 0; k < m; ++k) {
        e5 += scaled[k] * scaled[k];
        e3 += scaled[m + k] * scaled[m + k];
    }
    if (!(isfinite(e5) && isfinite(e3)))
        return INFINITY;
    if (e5 == 0.0)
        return 0.0;
    return e5 / sqrt((double)m * (e5 + 0.01 * e3));
}

/* One step of an embedded pair, sub-stepped to meet the tolerance (integrators/methods.py:
 * EmbeddedRungeKutta.step, the same controller). `buffer` holds S + 3 + error_rows flat
 * states (q and v together). */
static int hd_embedded(hd_forces *f, const hd_pair *pair, double tolerance, double *size,
                       const double *q, const double *v, double *q1, double *v1, double h,
                       double *buffer)
{
    const long n3 = f->n3, m = 2 * n3, S = pair->slopes, E = pair->error_rows;
    double *slopes = buffer, *y = slopes + S * m, *y_new = y + m, *stage = y_new + m,
           *scaled = stage + m;
    const int needs_new_state = pair->needs_new_state;
    const long error_slopes = needs_new_state ? S : S - 1;
    const double exponent = -1.0 / (pair->error_order + 1);
    memcpy(y, q, (size_t)n3 * sizeof(double));
    memcpy(y + n3, v, (size_t)n3 * sizeof(double));
    hd_rhs(f, y, slopes);
    double step = fmin(*size, h), done = 0.0;
    for (long count = 0; count < HD_MAX_PAIR_SUBSTEPS; ++count) {
        const double remaining = h - done;
        const int last = step >= remaining * (1.0 - 1e-12);
        const double trial = last ? remaining : step;
        for (long s = 1; s < S; ++s) {  /* stages 2..S-1, then the new state (row S-1) */
            double *target = s < S - 1 ? stage : y_new;
            hd_combine(pair->a + s * (S - 1), s, trial, slopes, m, target);
            for (long k = 0; k < m; ++k)
                target[k] = y[k] + target[k];
            if (s < S - 1)
                hd_rhs(f, stage, slopes + s * m);
        }
        if (needs_new_state)
            hd_rhs(f, y_new, slopes + (S - 1) * m);
        double *scale = stage;  /* free until the next trial */
        for (long k = 0; k < m; ++k)
            scale[k] = tolerance * (1.0 + fmax(fabs(y[k]), fabs(y_new[k])));
        for (long r = 0; r < E; ++r) {
            double *estimate = scaled + r * m;
            hd_combine(pair->error + r * S, error_slopes, 1.0, slopes, m, estimate);
            for (long k = 0; k < m; ++k)
                estimate[k] = trial * estimate[k] / scale[k];
        }
        double norm = hd_error_norm(pair, scaled, m);
        if (!isfinite(norm))
            norm = INFINITY;  /* an overshooting trial: refuse it, shrink the sub-step */
        const double factor = norm == 0.0 ? 5.0 : fmin(5.0, fmax(0.2, 0.9 * pow(norm, exponent)));
        if (norm <= 1.0) {
            if (!needs_new_state)
                hd_rhs(f, y_new, slopes + (S - 1) * m);
            f->work->substeps += 1;
            memcpy(y, y_new, (size_t)m * sizeof(double));
            done += trial;
            memcpy(slopes, slopes + (S - 1) * m, (size_t)m * sizeof(double));
            if (last) {
                /* A sub-step shortened to land on the end says little about the next. */
                *size = trial >= step ? trial * factor : step;
                memcpy(q1, y, (size_t)n3 * sizeof(double));
                memcpy(v1, y + n3, (size_t)n3 * sizeof(double));
                return HD_ADVANCED;
            }
        } else {
            f->work->rejected += 1;
        }
        step = trial * factor;
        if (step < 1e-14 * h)
            return HD_SUBSTEP_UNDERFLOW;
    }
    return HD_TOO_MANY_SUBSTEPS;
}

/* The check of the new state (q, v) of N bodies, in one pass. */
static hd_check hd_check_state(const double *q, const double *v, long n)
{
    hd_tally tally = HD_TALLY_START;
    for (long b = 0; b < n; ++b) {
        const double *x = q + 3 * b, *u = v + 3 * b;
        hd_tally_body(&tally, b, hd_v2_pair(x[0], x[1]), hd_v2_pair(u[0], u[1]), x[2], u[2]);
    }
    return hd_tally_end(&tally);
}

/* Whether the new state of N bodies is finite (`check`, of that state); if so, its angles
 * are wrapped into [-pi, pi), touching only those outside (geometry/planar.py: wrap_angle,
 * with numpy's remainder: fmod moved to the sign of the divisor), between the first and
 * the last body the check found outside. */
static int hd_settle(double *q, hd_check check)
{
    if (!check.finite)
        return 0;
    for (long b = check.first; b <= check.last; ++b) {
        double theta = q[3 * b + 2];
        if (theta >= -HD_PI && theta < HD_PI)
            continue;
        double r = fmod(theta + HD_PI, (2.0 * HD_PI));
        if (r != 0.0) {
            if (r < 0.0)
                r += (2.0 * HD_PI);
        } else {
            r = 0.0;
        }
        double wrapped = r - HD_PI;
        q[3 * b + 2] = wrapped >= HD_PI ? -HD_PI : wrapped;
    }
    return 1;
}

static long hd_buffer_states(int method, const hd_pair *pair)
{
    switch (method) {
    case HD_VELOCITY_VERLET: return 3;
    case HD_RK4: return 8;
    case HD_EMBEDDED: return 2 * (pair->slopes + 3 + pair->error_rows);  /* in units of 3 N */
    default: return 1;
    }
}

typedef struct {
    hd_forces *f;
    int method;
    const hd_pair *pair;
    double tolerance, *size, *buffer;
    double *levels;  /* constrained_step's parts: two states per level of splitting */
    hd_check check;  /* of the state the last Euler step wrote */
} hd_run;

/* One step of the method from (q, v) to (q1, v1). */
static int hd_one_step(hd_run *s, const double *q, const double *v, double *q1, double *v1,
                       double h)
{
    switch (s->method) {
    case HD_EXPLICIT_EULER:
        hd_euler(s->f, q, v, q1, v1, h, s->buffer, 0, &s->check);
        return HD_ADVANCED;
    case HD_SEMI_IMPLICIT_EULER:
        hd_euler(s->f, q, v, q1, v1, h, s->buffer, 1, &s->check);
        return HD_ADVANCED;
    case HD_VELOCITY_VERLET:
        hd_velocity_verlet(s->f, q, v, q1, v1, h, s->buffer);
        return HD_ADVANCED;
    case HD_RK4: hd_rk4(s->f, q, v, q1, v1, h, s->buffer); return HD_ADVANCED;
    default:
        return hd_embedded(s->f, s->pair, s->tolerance, s->size, q, v, q1, v1, h, s->buffer);
    }
}

/* A step of soft joints (soft_joint.c), as dynamics/simulation.py: Simulation._constrained_step
 * takes it: in the joints' equal sub-steps, each the method's step and their pass. The sub-steps'
 * ends go through the first level of `s->levels`. */
static int hd_soft_step(hd_run *s, hd_joint_model *joints, const double *q, const double *v,
                        double *q1, double *v1, double h)
{
    const long n3 = s->f->n3;
    double *q_part = s->levels, *v_part = q_part + n3;
    const double part = h / (double)joints->substeps;
    const double *from_q = q, *from_v = v;
    for (long k = 0; k < joints->substeps; ++k) {
        const int status = hd_one_step(s, from_q, from_v, q1, v1, part);
        if (status != HD_ADVANCED)
            return status;
        hd_soft_joints_resolve(joints, from_q, q1, v1, part);
        memcpy(q_part, q1, (size_t)n3 * sizeof(double));
        memcpy(v_part, v1, (size_t)n3 * sizeof(double));
        from_q = q_part, from_v = v_part;
    }
    return HD_ADVANCED;
}

/* One step of the method and the joint pass (joint.h; `joints` NULL: none), as
 * dynamics/simulation.py: Simulation._constrained_step takes them: in equal parts when a joint's
 * arm would turn too far (hd_joints_parts), in halves when the joints have no solution near the
 * step's end, each part the same way, a whole step in at least the parts the joints remember
 * (hd_joints_remember); `room`: how many parts this step may still be cut into
 * (HD_MOST_SUBSTEPS at the top), `pieces`: how many parts of the whole step this one is,
 * `level`: how deep this part is. `s->levels` holds two states per level for the parts' ends. */
static int hd_constrained_step(hd_run *s, hd_joint_model *joints, const double *q,
                               const double *v, double *q1, double *v1, double h, long room,
                               long pieces, int level)
{
    if (joints != NULL && joints->substeps > 0)
        return hd_soft_step(s, joints, q, v, q1, v1, h);
    int status = hd_one_step(s, q, v, q1, v1, h);
    if (status != HD_ADVANCED || joints == NULL)
        return status;
    const int whole = room == HD_MOST_SUBSTEPS;
    long parts = hd_joints_parts(joints, q, q1);
    if (whole && joints->remembered > parts)
        parts = joints->remembered;
    parts = parts < room ? parts : room;
    if (parts == 1) {
        switch (hd_joints_resolve(joints, q, q1, v1, h)) {
        case HD_JOINTS_OK:
            if (whole)
                hd_joints_remember(joints);
            return HD_ADVANCED;
        case HD_JOINTS_UNSOLVED:
            if (room < 2)
                return HD_UNSOLVED_JOINTS;
            parts = 2;
            if (2 * pieces > joints->needed)
                joints->needed = 2 * pieces;
            break;
        default: return HD_OUT_OF_MEMORY;
        }
    }
    const long n3 = s->f->n3;
    double *q_part = s->levels + 2 * n3 * level, *v_part = q_part + n3;
    const double part = h / (double)parts;
    const double *from_q = q, *from_v = v;
    for (long k = 0; k < parts; ++k) {
        if ((status = hd_constrained_step(s, joints, from_q, from_v, q1, v1, part, room / parts,
                                          pieces * parts, level + 1)) != HD_ADVANCED)
            return status;
        memcpy(q_part, q1, (size_t)n3 * sizeof(double));
        memcpy(v_part, v1, (size_t)n3 * sizeof(double));
        from_q = q_part, from_v = v_part;
    }
    if (whole)
        hd_joints_remember(joints);
    return HD_ADVANCED;
}

/* How many sub-steps keep the travel of every body that meets convex parts (the colliding
 * bodies and the map's) under half the thinnest of them (contact/detect.py:
 * Detection.substeps, its plain-float path). */
static long hd_substeps(const hd_contact_model *m, const double *q0, const double *q1)
{
    if (m->swept_count == 0)
        return 1;
    double farthest = 0.0;
    for (long k = 0; k < m->swept_count; ++k) {
        const long i = m->swept[k];
        const double moved = hd_length(q1[3 * i] - q0[3 * i], q1[3 * i + 1] - q0[3 * i + 1])
                             + fabs(q1[3 * i + 2] - q0[3 * i + 2]) * m->reach[i];
        if (k == 0 || moved > farthest)
            farthest = moved;
    }
    if (!isfinite(farthest))
        return 1;  /* a blown-up state: the finiteness check reports it */
    const double parts = ceil(farthest / (0.5 * m->thickness));
    return parts < 1.0 ? 1 : (parts > HD_MAX_SUBSTEPS ? HD_MAX_SUBSTEPS : (long)parts);
}

/* A step and the contact pass, in sub-steps when a colliding body would move more than half the
 * thinnest colliding part (dynamics/simulation.py: Simulation._integrate). `spare`: 4 states. */
static int hd_step_with_contacts(hd_run *s, hd_contact_model *m, hd_joint_model *joints,
                                 const double *q, const double *v, double *q1, double *v1,
                                 double h, double *spare)
{
    const long n3 = s->f->n3;
    int status = hd_constrained_step(s, joints, q, v, q1, v1, h, HD_MOST_SUBSTEPS, 1, 0);
    if (status != HD_ADVANCED)
        return status;
    const long parts = hd_substeps(m, q, q1);
    if (parts == 1)
        return hd_resolve(m, q1, v1, q, v, h) < 0 ? HD_OUT_OF_MEMORY : HD_ADVANCED;
    double *q_part = spare, *v_part = spare + n3, *q_next = spare + 2 * n3,
           *v_next = spare + 3 * n3;
    memcpy(q_part, q, (size_t)n3 * sizeof(double));
    memcpy(v_part, v, (size_t)n3 * sizeof(double));
    const double part = h / (double)parts;
    for (long k = 0; k < parts; ++k) {
        if ((status = hd_constrained_step(s, joints, q_part, v_part, q_next, v_next, part,
                                          HD_MOST_SUBSTEPS, 1, 0))
                != HD_ADVANCED)
            return status;
        if (hd_resolve(m, q_next, v_next, q_part, v_part, part) < 0)
            return HD_OUT_OF_MEMORY;
        memcpy(q_part, q_next, (size_t)n3 * sizeof(double));
        memcpy(v_part, v_next, (size_t)n3 * sizeof(double));
    }
    memcpy(q1, q_part, (size_t)n3 * sizeof(double));
    memcpy(v1, v_part, (size_t)n3 * sizeof(double));
    return HD_ADVANCED;
}

/* Whether every body sleeps, with no joint pass and a fixed-step method (which carries
 * nothing from step to step): the step would put each body back where it started (solver.c:
 * hold) and find no contact, so it is skipped (dynamics/simulation.py: Simulation._integrate). */
static int hd_everything_asleep(const hd_contact_model *m, const hd_joint_model *joints,
                                int method, long n)
{
    if (m == NULL || joints != NULL || !m->sleep || method == HD_EMBEDDED)
        return 0;
    for (long b = 0; b < n; ++b)
        if (m->island[b] < 0)
            return 0;
    return 1;
}

int hd_stepper_init(hd_stepper *s, const hd_program *program, int method,
                    const hd_pair *pair, double tolerance, hd_contact_model *contacts)
{
    const long n = program->bodies, n3 = 3 * n, states = hd_buffer_states(method, pair);
    /* cos, sin (N each) and the wrench (3 N) of an evaluation, the method's states, 4 states
     * for the sub-steps of a contact scene, the new state (q, v) and a pair to swap in */
    s->memory = malloc((size_t)(5 * n + n3 * (states + 4 + 4) + 1) * sizeof(double));
    if (s->memory == NULL)
        return HD_OUT_OF_MEMORY;
    s->program = program;
    s->method = method;
    s->pair = pair;
    s->tolerance = tolerance;
    s->contacts = contacts;
    s->levels = NULL;
    s->start_q = s->start_v = NULL;
    s->q_new = s->memory + 5 * n + n3 * (states + 4);
    s->v_new = s->q_new + n3;
    return HD_ADVANCED;
}

void hd_stepper_free(hd_stepper *s)
{
    free(s->memory);
    free(s->levels);
    free(s->start_q);
    s->memory = NULL;
    s->levels = NULL;
    s->start_q = s->start_v = NULL;
}

/* From now on, keep the state each call's last step started from in (start_q, start_v):
 * an IMU reads the step that ended at its sample (sensors/imu.py). */
int hd_stepper_keep_starts(hd_stepper *s)
{
    if (s->start_q != NULL)
        return HD_ADVANCED;
    const long n3 = 3 * s->program->bodies;
    if ((s->start_q = calloc((size_t)(2 * n3 + 1), sizeof(double))) == NULL)
        return HD_OUT_OF_MEMORY;
    s->start_v = s->start_q + n3;
    return HD_ADVANCED;
}

/* Leave the last good state in (q, v) and the failed one in the stepper's (q_new, v_new)
 * when the steps ended on the other pair of buffers than the one they began on. */
static void hd_settle_buffers(const hd_stepper *s, long n3, double *q, double *v,
                              const double *good_q, const double *good_v, int failed)
{
    const size_t bytes = (size_t)n3 * sizeof(double);
    if (good_q == q)
        return;
    if (failed) {  /* the failed state is in (q, v): swap it with the good one */
        double *spare_q = s->v_new + n3, *spare_v = spare_q + n3;
        memcpy(spare_q, q, bytes);
        memcpy(spare_v, v, bytes);
        memcpy(q, good_q, bytes);
        memcpy(v, good_v, bytes);
        memcpy(s->q_new, spare_q, bytes);
        memcpy(s->v_new, spare_v, bytes);
        return;
    }
    memcpy(q, good_q, bytes);
    memcpy(v, good_v, bytes);
}

int hd_stepper_advance(hd_stepper *s, const hd_program *inputs, int oriented,
                       hd_joint_model *joints, double *size, double *q, double *v, double h,
                       long steps, long *taken, hd_work *work)
{
    const hd_program *program = s->program;
    hd_contact_model *contacts = s->contacts;
    const long n = program->bodies, n3 = 3 * n;
    double *memory = s->memory, *buffer = memory + 5 * n;
    hd_forces f = {program, inputs, oriented, n3, {memory, memory + n, memory + 2 * n}, work};
    double *spare = buffer + n3 * hd_buffer_states(s->method, s->pair);
    /* The state steps from (cur) into (next), and the two pairs of buffers swap roles:
     * no copy per step. */
    double *cur_q = q, *cur_v = v, *next_q = s->q_new, *next_v = s->v_new;
    int status = HD_ADVANCED;
    *taken = 0;
    if (joints != NULL && s->levels == NULL) {
        /* two states per level of a joint pass's splitting (constrained_step) */
        s->levels = malloc((size_t)(2 * (HD_MAX_SPLITS + 1) * n3 + 1) * sizeof(double));
        if (s->levels == NULL)
            return HD_OUT_OF_MEMORY;
    }
    hd_run stepper = {&f, s->method, s->pair, s->tolerance, size, buffer, s->levels,
                      {0, 0, -1}};
    /* With no joint or contact pass after it, an Euler step's own check of the state it
     * wrote is the step's: no second pass over the new state. */
    const int checked = contacts == NULL && joints == NULL
                        && (s->method == HD_EXPLICIT_EULER || s->method == HD_SEMI_IMPLICIT_EULER);
    if (contacts != NULL)
        contacts->joints = joints;  /* for these steps: coupled.h */
    const double *start_q = NULL, *start_v = NULL;  /* where the last step began */
    for (long t = 0; t < steps; ++t) {
        start_q = cur_q;
        start_v = cur_v;
        if (hd_everything_asleep(contacts, joints, s->method, n)) {
            *taken += 1;
            continue;
        }
        status = contacts == NULL
                 ? hd_constrained_step(&stepper, joints, cur_q, cur_v, next_q, next_v, h,
                                       HD_MOST_SUBSTEPS, 1, 0)
                 : hd_step_with_contacts(&stepper, contacts, joints, cur_q, cur_v, next_q, next_v,
                                         h, spare);
        if (status != HD_ADVANCED)
            break;
        if (!hd_settle(next_q, checked ? stepper.check : hd_check_state(next_q, next_v, n))) {
            status = HD_NOT_FINITE;
            break;
        }
        double *swap_q = cur_q, *swap_v = cur_v;
        cur_q = next_q;
        cur_v = next_v;
        next_q = swap_q;
        next_v = swap_v;
        *taken += 1;
    }
    if (contacts != NULL)
        contacts->joints = NULL;
    /* Before settling, which may write over the buffers the last step began from. */
    if (s->start_q != NULL && status == HD_ADVANCED && start_q != NULL) {
        memcpy(s->start_q, start_q, (size_t)n3 * sizeof(double));
        memcpy(s->start_v, start_v, (size_t)n3 * sizeof(double));
    }
    hd_settle_buffers(s, n3, q, v, cur_q, cur_v, status == HD_NOT_FINITE);
    return status;
}
