/* The energy bound: a check, per unit of bodies that can pass energy to each other, that
 * a state has not blown up (hecker_dynamics/dynamics/divergence.py says what is bounded
 * and why). Every function repeats, operation for operation, that module's Python path
 * (`_sums`, `_check_python`): the same bits, so the same verdict either way.
 */
#include <math.h>

#include "kernel.h"

void hd_unit_energy(const hd_program *springs, const double *q, const double *v, long bodies,
                    const double *statics, const long *unit, long units, double *budget,
                    hd_scratch *scratch)
{
    const double *mass = statics, *inertia = statics + bodies, *floor = statics + 2 * bodies;
    double *energy = budget + HD_BUDGET_ENERGY * units;
    double *excess = budget + HD_BUDGET_EXCESS * units;
    for (long u = 0; u < units; ++u) {
        energy[u] = 0.0;
        excess[u] = 0.0;
    }
    for (long b = 0; b < bodies; ++b) {
        const double vx = v[3 * b], vy = v[3 * b + 1], omega = v[3 * b + 2];
        const double kinetic = 0.5 * (mass[b] * (vx * vx + vy * vy) +
                                      inertia[b] * (omega * omega));
        energy[unit[b]] += kinetic;
        excess[unit[b]] += !(kinetic <= floor[b]) ? kinetic - floor[b] : 0.0;
    }
    if (springs != NULL)
        hd_unit_spring_potential(springs, q, unit, energy, excess, scratch);
}

/* How far a unit is over its limit: excess / limit, 0 without excess, inf for an energy
 * that is not finite or an excess over a limit of zero. */
static double hd_over(double energy, double excess, double limit)
{
    if (!isfinite(energy))
        return INFINITY;
    if (excess <= 0.0)
        return 0.0;
    const double ratio = limit > 0.0 ? excess / limit : INFINITY;
    return isnan(ratio) ? INFINITY : ratio;
}

/* What a unit's motors add to R: the smaller of sqrt(W) and M, sqrt(W) where they are
 * equal (dynamics/divergence.py: _motors_share). */
static double hd_motors_share(double work, double turned)
{
    const double swept = sqrt(work);
    return turned < swept ? turned : swept;
}

double hd_bound_check(const hd_program *springs, const double *q, const double *v,
                      long bodies, const double *statics, const long *unit, long units,
                      double *budget, double seconds, double growth, hd_scratch *scratch)
{
    hd_unit_energy(springs, q, v, bodies, statics, unit, units, budget, scratch);
    double *root = budget + HD_BUDGET_ROOT * units, *work = budget + HD_BUDGET_WORK * units;
    const double *rate = budget + HD_BUDGET_RATE * units;
    const double *input_rate = budget + HD_BUDGET_INPUT_RATE * units;
    const double *power = budget + HD_BUDGET_POWER * units;
    double *turned = budget + HD_BUDGET_MOTOR_ROOT * units;
    const double *motor_rate = budget + HD_BUDGET_MOTOR_RATE * units;
    const double *energy = budget + HD_BUDGET_ENERGY * units;
    const double *excess = budget + HD_BUDGET_EXCESS * units;
    double *limit = budget + HD_BUDGET_LIMIT * units;
    double worst = 0.0;
    for (long u = 0; u < units; ++u) {
        root[u] += 0.5 * seconds * (rate[u] + input_rate[u]);
        work[u] += seconds * power[u];
        turned[u] += 0.5 * seconds * motor_rate[u];
        const double reach = root[u] + hd_motors_share(work[u], turned[u]);
        limit[u] = growth * (reach * reach);
        const double ratio = hd_over(energy[u], excess[u], limit[u]);
        if (ratio > worst)
            worst = ratio;
    }
    return worst;
}
