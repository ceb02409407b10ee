/* The differential drives in the kernel's run (drive.h says what each function repeats). */
#include <math.h>

#include "drive.h"

long hd_drives_next(const hd_drives *d)
{
    long next = -1;
    for (long k = 0; k < d->count; ++k) {
        const long step = (d->ints[k * HD_DRIVE_INTS + HD_DRIVE_NEXT_NS] - d->start_ns) /
                          d->step_ns;
        if (next < 0 || step < next)
            next = step;
    }
    return next;
}

/* A wheel's force in body axes (DiffDrive._grip): its push forward and the lateral
 * damping's grip against its sideways slip, the whole capped at the traction. */
static void hd_grip(hd_drives *d, const double *r, double push, double slip, double *force)
{
    const double grip = -r[HD_DRIVE_LATERAL_DAMPING] * slip;
    double scale = 1.0;
    if (push != 0.0 || grip != 0.0) {  /* NaN is true in Python too */
        const double ratio = r[HD_DRIVE_TRACTION] / d->hypot(d->context, push, grip, &d->failed);
        scale = ratio < 1.0 ? ratio : 1.0;  /* min(1.0, ratio) */
    }
    force[0] = push * scale;
    force[1] = grip * scale;
}

/* Whether a wheel's force, acting alone for one step from the body's velocity v (vx, vy,
 * omega), leaves its energy of motion finite (Simulation.check_reach, with the command's
 * finiteness checks before it). */
static int hd_reach(hd_drives *d, const double *r, const double *force, double lever,
                    const double *v)
{
    if (!isfinite(force[0]) || !isfinite(force[1]))
        return 0;
    const double magnitude = d->hypot(d->context, force[0], force[1], &d->failed);
    const double arm = magnitude != 0.0 ? lever : 0.0;
    const double mass = r[HD_DRIVE_MASS], inertia = r[HD_DRIVE_INERTIA];
    const double speed = d->hypot(d->context, v[0], v[1], &d->failed) + magnitude * d->h / mass;
    const double turn = fabs(v[2]) + (0.0 + arm * magnitude) * d->h / inertia;
    const double energy = 0.5 * mass * speed * speed + 0.5 * inertia * turn * turn;
    return isfinite(energy);
}

/* One drive's wheel forces at the instant `time_ns` from the state (q, v) (DiffDrive.wrenches
 * after DriveSet.arrive's scripted command), into `forces` (left x, y, right x, y) and its
 * new integrals. */
static void hd_wheels(hd_drives *d, const long *i, const double *r, long time_ns,
                      const double *q, const double *v, double *forces, double *integrals)
{
    const long body = i[HD_DRIVE_BODY];
    const double theta = q[3 * body + 2];
    const double vx = v[3 * body], vy = v[3 * body + 1], omega = v[3 * body + 2];
    const double c = cos(theta), s = sin(theta);
    const long timeout = i[HD_DRIVE_TIMEOUT_NS];
    const int active = i[HD_DRIVE_COMMANDED] &&
        (i[HD_DRIVE_RESTAMP] || timeout == 0 || time_ns - i[HD_DRIVE_STAMP_NS] < timeout);
    double left = 0.0, right = 0.0;
    integrals[0] = integrals[1] = 0.0;
    if (active) {
        const double period = r[HD_DRIVE_PERIOD];
        /* The axle centre's velocity, a body point's velocity (Eq. 9), in body axes. */
        const double u = c * vx + s * vy - omega * r[HD_DRIVE_AXLE_Y];
        const double error_v = r[HD_DRIVE_LINEAR_X] - u, error_w = r[HD_DRIVE_ANGULAR_Z] - omega;
        const double integral_v = r[HD_DRIVE_INTEGRAL_V], integral_w = r[HD_DRIVE_INTEGRAL_W];
        const double force = r[HD_DRIVE_LINEAR_KP] * error_v +
            r[HD_DRIVE_LINEAR_KI] * (integral_v + error_v * period);
        const double torque = r[HD_DRIVE_ANGULAR_KP] * error_w +
            r[HD_DRIVE_ANGULAR_KI] * (integral_w + error_w * period);
        const double wanted_left = force / 2.0 - torque / r[HD_DRIVE_SEPARATION];
        const double wanted_right = force / 2.0 + torque / r[HD_DRIVE_SEPARATION];
        const double limit = r[HD_DRIVE_MAX_FORCE];
        /* min(max(wanted, -limit), limit) as Python takes them: a NaN passes as itself. */
        const int capped_left = -limit > wanted_left || limit < wanted_left;
        const int capped_right = -limit > wanted_right || limit < wanted_right;
        left = -limit > wanted_left ? -limit : (limit < wanted_left ? limit : wanted_left);
        right = -limit > wanted_right ? -limit : (limit < wanted_right ? limit : wanted_right);
        if (!capped_left && !capped_right) {  /* conditional integration: no wind-up */
            integrals[0] = integral_v + error_v * period;
            integrals[1] = integral_w + error_w * period;
        } else {
            integrals[0] = integral_v;
            integrals[1] = integral_w;
        }
    }
    /* The sideways slip: the body-y component of the wheel's point's velocity (Eq. 9). */
    const double across = -s * vx + c * vy;
    hd_grip(d, r, left, across + omega * r[HD_DRIVE_OFFSET_LEFT], forces);
    hd_grip(d, r, right, across + omega * r[HD_DRIVE_OFFSET_RIGHT], forces + 2);
}

/* Each unit's rate of work of the inputs' program `in` (EnergyBound._unit_rates, every
 * lever arm fixed) into `rates`. */
static void hd_input_rates(hd_drives *d, const hd_program *in, double *rates, long units)
{
    for (long u = 0; u < units; ++u)
        rates[u] = 0.0;
    const double *values = in->terms[0].reals;
    for (long row = 0; row < d->rows; ++row) {
        const double *w = values + 5 * row, *c = d->row_rates + 3 * row;
        const double force = d->hypot(d->context, w[0], w[1], &d->failed);
        rates[d->row_unit[row]] += force * c[0] + (c[2] * force + fabs(w[2])) * c[1];
    }
}

int hd_drives_arrive(hd_drives *d, long step, const double *q, const double *v,
                     hd_program *in, double *budget, long units)
{
    const long time_ns = d->start_ns + step * d->step_ns;
    double forces[4 * HD_DRIVE_MOST], integrals[2 * HD_DRIVE_MOST];
    int due[HD_DRIVE_MOST];
    d->failed = 0;
    for (long k = 0; k < d->count; ++k) {  /* all of them first: an instant is whole */
        const long *i = d->ints + k * HD_DRIVE_INTS;
        const double *r = d->reals + k * HD_DRIVE_REALS;
        due[k] = time_ns >= i[HD_DRIVE_NEXT_NS];
        if (!due[k])
            continue;
        hd_wheels(d, i, r, time_ns, q, v, forces + 4 * k, integrals + 2 * k);
        const double *body_v = v + 3 * i[HD_DRIVE_BODY];
        const int within = hd_reach(d, r, forces + 4 * k, r[HD_DRIVE_LEVER_LEFT], body_v) &&
            hd_reach(d, r, forces + 4 * k + 2, r[HD_DRIVE_LEVER_RIGHT], body_v);
        if (d->failed)
            return -1;
        if (!within)
            return 0;
    }
    double *values = in->terms[0].reals;
    for (long k = 0; k < d->count; ++k) {
        if (!due[k])
            continue;
        long *i = d->ints + k * HD_DRIVE_INTS;
        double *r = d->reals + k * HD_DRIVE_REALS;
        r[HD_DRIVE_INTEGRAL_V] = integrals[2 * k];
        r[HD_DRIVE_INTEGRAL_W] = integrals[2 * k + 1];
        for (int w = 0; w < 4; ++w)
            r[HD_DRIVE_LEFT_X + w] = forces[4 * k + w];
        const long rows[2] = {i[HD_DRIVE_ROW_LEFT], i[HD_DRIVE_ROW_RIGHT]};
        for (int w = 0; w < 2; ++w) {
            values[5 * rows[w]] = forces[4 * k + 2 * w];
            values[5 * rows[w] + 1] = forces[4 * k + 2 * w + 1];
            values[5 * rows[w] + 2] = 0.0;
        }
        if (i[HD_DRIVE_RESTAMP])
            i[HD_DRIVE_STAMP_NS] = time_ns;
        i[HD_DRIVE_NEXT_NS] = time_ns + i[HD_DRIVE_PERIOD_NS];
        i[HD_DRIVE_INSTANTS] += 1;
        i[HD_DRIVE_LAST_NS] = time_ns;
    }
    /* The new inputs' rates (EnergyBound.inputs_changed): the larger of the two counts. */
    double *input_rate = budget + HD_BUDGET_INPUT_RATE * units;
    double *rates = d->rates;
    hd_input_rates(d, in, rates, units);
    for (long u = 0; u < units; ++u)
        input_rate[u] = rates[u] > input_rate[u] ? rates[u] : input_rate[u];
    return d->failed ? -1 : 1;
}

int hd_drives_refresh(hd_drives *d, const hd_program *in, double *budget, long units)
{
    double *rate = budget + HD_BUDGET_RATE * units;
    double *input_rate = budget + HD_BUDGET_INPUT_RATE * units;
    d->failed = 0;
    hd_input_rates(d, in, input_rate, units);
    for (long u = 0; u < units; ++u) {
        rate[u] = d->steady[u] + input_rate[u];
        input_rate[u] = 0.0;
    }
    return d->failed ? -1 : 0;
}
