/* The differential drives in the kernel's run: drives/diff_drive.py's PI law and wheel
 * forces (`DiffDrive.wrenches`), the simulation's reach check of the wheel commands
 * (`Simulation.check_reach`) and the energy bound's rates of the inputs
 * (dynamics/divergence.py: `EnergyBound.inputs_changed` and `_refresh`), repeated operation
 * for operation at the drives' control instants between a run's steps, so that a run no
 * longer stops there. Python stays the reference: an instant whose wheel commands the
 * simulation would refuse is left to it (the run ends there).
 *
 * Every length is CPython's math.hypot, called back through `hypot` (C's hypot may round
 * the last bit otherwise).
 */
#ifndef HECKER_DYNAMICS_DRIVE_H
#define HECKER_DYNAMICS_DRIVE_H

#include "kernel.h"

/* The integer columns of a drive (int64): its body's row, its control period (ns), the rows
 * of its left and right wheels in the inputs' program, whether it has a command, whether a
 * script's command is renewed at each instant (stamped then), the command's stamp and the
 * cmd_vel timeout (ns, 0: none), the sim time of its next instant (ns); written by the run:
 * the instants it took and the sim time of the last (ns). */
enum hd_drive_int {
    HD_DRIVE_BODY, HD_DRIVE_PERIOD_NS, HD_DRIVE_ROW_LEFT, HD_DRIVE_ROW_RIGHT,
    HD_DRIVE_COMMANDED, HD_DRIVE_RESTAMP, HD_DRIVE_STAMP_NS, HD_DRIVE_TIMEOUT_NS,
    HD_DRIVE_NEXT_NS, HD_DRIVE_INSTANTS, HD_DRIVE_LAST_NS, HD_DRIVE_INTS
};

/* The real columns of a drive (float64): its control period (s), gains, wheel separation,
 * force cap, traction and lateral damping, the axle centre's y and each wheel's x from the
 * CM (body frame), its body's mass and moment of inertia, each wheel's lever arm, the
 * commanded forward speed and angular velocity; kept by the run: the controller's two
 * integrals and the wheels' last forces (left x, y, right x, y; body frame). */
enum hd_drive_real {
    HD_DRIVE_PERIOD, HD_DRIVE_LINEAR_KP, HD_DRIVE_LINEAR_KI, HD_DRIVE_ANGULAR_KP,
    HD_DRIVE_ANGULAR_KI, HD_DRIVE_SEPARATION, HD_DRIVE_MAX_FORCE, HD_DRIVE_TRACTION,
    HD_DRIVE_LATERAL_DAMPING, HD_DRIVE_AXLE_Y, HD_DRIVE_OFFSET_LEFT, HD_DRIVE_OFFSET_RIGHT,
    HD_DRIVE_MASS, HD_DRIVE_INERTIA, HD_DRIVE_LEVER_LEFT, HD_DRIVE_LEVER_RIGHT,
    HD_DRIVE_LINEAR_X, HD_DRIVE_ANGULAR_Z, HD_DRIVE_INTEGRAL_V, HD_DRIVE_INTEGRAL_W,
    HD_DRIVE_LEFT_X, HD_DRIVE_LEFT_Y, HD_DRIVE_RIGHT_X, HD_DRIVE_RIGHT_Y, HD_DRIVE_REALS
};

/* The most drives one run takes. */
#define HD_DRIVE_MOST 8

/* |(x, y)| as CPython's math.hypot gives it; sets *failed (and returns NaN) where it could
 * not be called. */
typedef double (*hd_hypot)(void *context, double x, double y, int *failed);

/* The drives of one run: `count` drives' columns, and per row of the inputs' program (every
 * one a drive's wheel) its body's unit and sqrt(2 / m), sqrt(2 / I) and lever arm; each
 * unit's steady rate (gravity's) and room for a rate per unit; the run's start (ns) and
 * step (ns and s); the length and its context, and whether it failed. */
typedef struct {
    long count;
    long *ints;
    double *reals;
    long rows;
    const long *row_unit;
    const double *row_rates;
    const double *steady;
    double *rates;  /* room for a rate per unit */
    long start_ns, step_ns;
    double h;
    hd_hypot hypot;
    void *context;
    int failed;
} hd_drives;

/* The step of the drives' next instant from the run's start. */
long hd_drives_next(const hd_drives *d);

/* The instant at `step` (from the run's start) with the state (q, v): each drive due there
 * computes its wheel forces, which the inputs' program `in` then holds, and the budget's
 * input rates take the larger of theirs and the new inputs' (`units` columns). 1 done; 0,
 * and nothing changed, where a wheel command would be refused (not finite, or past the
 * reach check): the instant is Python's; -1 where a length could not be taken (out of
 * memory). */
int hd_drives_arrive(hd_drives *d, long step, const double *q, const double *v,
                     hd_program *in, double *budget, long units);

/* After a check passed: the rates of work from the inputs now (EnergyBound._refresh); -1
 * where a length could not be taken (out of memory), else 0. */
int hd_drives_refresh(hd_drives *d, const hd_program *in, double *budget, long units);

#endif
