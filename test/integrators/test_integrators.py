"""Accuracy of the integrators: exact discrete solutions, observed orders of convergence,
the adaptive methods meeting their tolerance and their tableaux meeting the order
conditions.

The problems are scenes run through the Model (``Model.accelerations``), so forces, mass
properties and integrators are tested together:

- ``harmonic``: 1 kg on a zero-length spring k = 100 from the CM to a fixed anchor
  (w = 10 rad/s), x0 = 1, v0 = 0; exact x = cos(wt).
- ``damped``: the same with damping c = 2 N s/m; exact x = e^(-t) (cos wd t + sin(wd t)/wd),
  wd = sqrt(99). The damping force depends on the velocity, which Verlet must handle.
- ``coupled``: a 1 m x 0.5 m box on a spring with rest length, attached 0.45 m off-center,
  under gravity, starting turned and spinning: rotation and translation drive each other.
  No closed form; the reference is DOPRI5 at tolerance 1e-13 in one call, checked against
  Richardson-extrapolated RK4 (an independent method).
"""
from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from helpers import integrate, make_scene, observed_order, oscillator

from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.integrators.methods import ADAPTIVE, Counters, make_integrator
from hecker_dynamics.integrators.tableaux import DOP853, DOPRI5

DURATION = 0.6  # s: about one period of the 10 rad/s oscillator
EPS = np.finfo(float).eps
FIXED_STEP = ("explicit_euler", "semi_implicit_euler", "velocity_verlet", "rk4",
              "implicit_midpoint", "backward_euler")
ORDER = {"explicit_euler": 1, "semi_implicit_euler": 1, "velocity_verlet": 2, "rk4": 4,
         "implicit_midpoint": 2, "backward_euler": 1}


def damped_exact(t: float, c: float = 2.0, w2: float = 100.0) -> tuple[float, float]:
    """x'' + c x' + w2 x = 0 with x(0) = 1, x'(0) = 0."""
    g = c / 2
    wd = math.sqrt(w2 - g * g)
    decay = math.exp(-g * t)
    return (decay * (math.cos(wd * t) + g / wd * math.sin(wd * t)),
            -decay * (w2 / wd) * math.sin(wd * t))


def coupled_scene():
    return make_scene({
        "bodies": {"b": {"shape": "box", "size": [1.0, 0.5], "mass": 1.0,
                         "position": [1.0, 0.3], "angle": 0.2, "velocity": [0.0, 0.5],
                         "angular_velocity": 1.0}},
        "forces": {"gravity": {"type": "gravity"},
                   "spring": {"type": "spring", "body_a": "b", "point_a": [0.4, 0.2],
                              "anchor": [0.0, 0.0], "stiffness": 50.0, "rest_length": 0.5}},
    })


@cache
def problem(name: str):
    """(model, final q, final v, rate w used to scale velocity errors)."""
    if name == "harmonic":
        model = Model(oscillator(100.0))
        x, vx = math.cos(10.0 * DURATION), -10.0 * math.sin(10.0 * DURATION)
        return model, np.array([[x, 0.0, 0.0]]), np.array([[vx, 0.0, 0.0]]), 10.0
    if name == "damped":
        model = Model(oscillator(100.0, damping=2.0))
        x, vx = damped_exact(DURATION)
        return model, np.array([[x, 0.0, 0.0]]), np.array([[vx, 0.0, 0.0]]), 10.0
    model = Model(coupled_scene())
    q, v = make_integrator("dopri5", 1e-13).step(model.accelerations, *model.initial_state(),
                                                 DURATION)
    return model, q, v, model.stiffness()


def error(name: str, q: np.ndarray, v: np.ndarray) -> float:
    """Max-norm error of the final state; velocities divided by the problem's rate w."""
    _, q_ref, v_ref, w = problem(name)
    return max(float(np.max(np.abs(q - q_ref))), float(np.max(np.abs(v - v_ref))) / w)


# Step counts: four halvings of h. On the oscillators RK4 uses half as many steps, so that
# its smallest error (~2e-8) stays far above rounding. All errors stay at least 100 times
# the reference's error bound, so that error shifts a local order by less than 0.015.
STEPS = {"harmonic": [60, 120, 240, 480], "damped": [60, 120, 240, 480],
         "coupled": [120, 240, 480, 960]}
RK4_STEPS = {"harmonic": [30, 60, 120, 240], "damped": [30, 60, 120, 240],
             "coupled": [120, 240, 480, 960]}
REFERENCE_ERROR_BOUND = 1e-11  # checked by test_coupled_reference_is_accurate


def test_coupled_reference_is_accurate():
    """DOPRI5 at 1e-13 agrees with Richardson-extrapolated RK4 (1500 and 3000 steps; the
    extrapolation removes the h^4 term of RK4's 2.6e-11 error), so its error is below 1e-11
    (measured 3.8e-12): over 100 times smaller than every error the sweeps measure."""
    model, q_ref, v_ref, w = problem("coupled")
    q1, v1 = integrate(model, "rk4", DURATION, 1500)
    q2, v2 = integrate(model, "rk4", DURATION, 3000)
    q_x, v_x = q2 + (q2 - q1) / 15, v2 + (v2 - v1) / 15
    assert error("coupled", q_x, v_x) < REFERENCE_ERROR_BOUND
    # The problem really couples the two: the spin changed by far more than a free spin's.
    assert abs(q_ref[0, 2] - (0.2 + 1.0 * DURATION)) > 1.0
    assert abs(v_ref[0, 2] - 1.0) > 1.0


@pytest.mark.parametrize("name", ["harmonic", "damped", "coupled"])
@pytest.mark.parametrize("method", FIXED_STEP)
def test_observed_order_of_convergence(method, name):
    """Fit log(error) against log(h) over four halvings of h. The fitted slope must be
    within 0.25 of the method's order (neighbouring orders differ by at least 1, so this
    tells them apart) and the finest pair's local order within 0.15: pre-asymptotic
    terms of relative size O(h) shrink with each halving (measured: within 0.12, RK4 on
    the coupled problem; the fits are within 0.22)."""
    model = problem(name)[0]
    steps = (RK4_STEPS if method == "rk4" else STEPS)[name]
    errors = [error(name, *integrate(model, method, DURATION, n)) for n in steps]
    hs = [DURATION / n for n in steps]
    order = ORDER[method]
    assert min(errors) > 100 * REFERENCE_ERROR_BOUND
    assert all(a > b for a, b in zip(errors, errors[1:]))
    assert observed_order(hs, errors) == pytest.approx(order, abs=0.25)
    assert math.log2(errors[-2] / errors[-1]) == pytest.approx(order, abs=0.15)


# ----------------------------------------------------------------------------- exact maps

def one_step_matrix(method: str, z: float) -> np.ndarray:
    """The exact one-step map of each method on x'' = -w^2 x for (x, v/w), with z = w h.

    Runge-Kutta methods on (x, v) act on zeta = x + i v / w (zeta' = -i w zeta) through
    their stability function R(-iz); the partitioned methods are written out directly.
    """
    if method == "semi_implicit_euler":   # v1 = v - h w^2 x; x1 = x + h v1
        return np.array([[1 - z * z, z], [-z, 1.0]])
    # velocity Verlet: x1 = x + h v - h^2 w^2 x / 2; v1 = v - h w^2 (x + x1) / 2
    if method == "velocity_verlet":
        return np.array([[1 - z * z / 2, z], [-z * (1 - z * z / 4), 1 - z * z / 2]])
    y = -1j * z
    r = {"explicit_euler": 1 + y,
         "rk4": 1 + y + y ** 2 / 2 + y ** 3 / 6 + y ** 4 / 24,
         "implicit_midpoint": (1 + y / 2) / (1 - y / 2),
         "backward_euler": 1 / (1 - y)}[method]
    # zeta1 = r zeta0 with zeta = x + i u (u = v / w): as a real map on (x, u).
    return np.array([[r.real, -r.imag], [r.imag, r.real]])


@pytest.mark.parametrize("method", FIXED_STEP)
def test_each_method_is_its_exact_discrete_map_on_the_oscillator(method):
    """On the linear oscillator every fixed-step method is a known linear map M(wh): the
    state after n steps is M^n (x0, v0/w). This checks every coefficient of each method,
    not only its order. 200 steps of wh = 0.05; both sides round by ~n eps, hence 1e-12."""
    model = Model(oscillator(100.0, position=(0.8, -0.3), velocity=(1.5, 2.0)))
    w, h, n = 10.0, 0.005, 200
    q, v = integrate(model, method, n * h, n)
    m = np.linalg.matrix_power(one_step_matrix(method, w * h), n)
    for axis, (x0, v0) in enumerate([(0.8, 1.5), (-0.3, 2.0)]):
        x, u = m @ np.array([x0, v0 / w])
        assert q[0, axis] == pytest.approx(x, abs=1e-12)
        assert v[0, axis] / w == pytest.approx(u, abs=1e-12)


# ----------------------------------------------------------------------------- adaptive

TOLERANCES = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]


@pytest.mark.parametrize("pair", [DOPRI5, DOP853], ids=lambda p: p.name)
def test_tableau_meets_the_quadrature_order_conditions(pair):
    """sum b_i c_i^(k-1) = 1/k for k = 1..order, with c_i the row sums of the stage
    coefficients, and each error combination e annihilates c^(k-1) up to its estimate's
    order (5th and 3rd for DOP853, 4th for DOPRI5; the slope at the new state has c = 1).
    Each node c_i, a row sum of coefficients rounded to doubles, may be off by about
    eps sum_j |a_ij| (up to 1e-14 here, where coefficients reach 43); the bound carries that
    through c^(k-1), plus a few eps per term for the products (the sums themselves are
    exact: fsum). The first condition past the order misses by 1e-6 or more, so a mistyped
    weight or node shows up here."""
    c = pair.a.sum(axis=1)  # the last row sums the weights: 1, the new state's node
    c_error = (EPS * np.abs(pair.a).sum(axis=1)).tolist()
    b = pair.a[-1]

    def condition(weights: np.ndarray, nodes: np.ndarray, k: int) -> tuple[float, float]:
        """sum w_i x_i^(k-1), and a bound on its error from the rounded nodes and products."""
        terms = [w * x ** (k - 1) for w, x in zip(weights.tolist(), nodes.tolist())]
        spread = [abs(w) * (k - 1) * abs(x) ** max(k - 2, 0) * dx
                  for w, x, dx in zip(weights.tolist(), nodes.tolist(), c_error)]
        return math.fsum(terms), math.fsum(spread) + 4 * k * EPS * math.fsum(map(abs, terms))

    for k in range(1, pair.order + 1):
        value, bound = condition(b, c[:-1], k)
        assert abs(value - 1.0 / k) <= bound
    assert abs(condition(b, c[:-1], pair.order + 1)[0] - 1.0 / (pair.order + 1)) > 1e-6
    estimate_orders = {"dopri5": (4,), "dop853": (5, 3)}[pair.name]
    for e, order in zip(pair.error, estimate_orders):
        for k in range(1, order + 1):
            value, bound = condition(e, c, k)
            assert abs(value) <= bound
        assert abs(condition(e, c, order + 1)[0]) > 1e-5


@pytest.mark.parametrize("name", ["harmonic", "damped"])
def test_dop853_is_eighth_order(name):
    """With a tolerance so loose that no sub-step is refused, DOP853 is a fixed-step method:
    from 3 to 24 steps over 0.6 s (w h = 2 .. 0.25) the error falls as h^8 (local orders
    measured 7.88-8.29; the errors run from 1e-4 down to 3e-12, far above rounding)."""
    model = problem(name)[0]
    steps = [3, 6, 12, 24]
    errors = []
    for n in steps:
        integrator = make_integrator("dop853", 1e3)
        q, v = model.initial_state()
        for _ in range(n):
            q, v = integrator.step(model.accelerations, q, v, DURATION / n)
        assert integrator.counters.substeps == n
        errors.append(error(name, q, v))
    assert observed_order([DURATION / n for n in steps], errors) == pytest.approx(8, abs=0.25)
    assert math.log2(errors[-2] / errors[-1]) == pytest.approx(8, abs=0.15)


def adaptive_error(method: str, tolerance: float, step: float,
                   duration: float = 1.0) -> tuple[float, int]:
    """Max error over the run on the harmonic oscillator (x0 = 1), and the sub-steps."""
    model = Model(oscillator(100.0))
    integrator = make_integrator(method, tolerance)
    q, v = model.initial_state()
    worst = 0.0
    n = round(duration / step)
    for i in range(1, n + 1):
        q, v = integrator.step(model.accelerations, q, v, step)
        t = i * step
        worst = max(worst, abs(q[0, 0] - math.cos(10 * t)),
                    abs(v[0, 0] + 10 * math.sin(10 * t)) / 10, abs(q[0, 1]), abs(q[0, 2]))
    return worst, integrator.counters.substeps


@pytest.mark.parametrize("method", ADAPTIVE)
@pytest.mark.parametrize("step", [1.0, 0.01])
@pytest.mark.parametrize("tolerance", TOLERANCES)
def test_adaptive_method_meets_its_tolerance(method, tolerance, step):
    """Global error over 1 s (1.6 periods) against the exact cosine. The controller bounds
    the error made per sub-step, scaled by tol (1 + |y|) with |y| ~ 1..10; these add up
    over the run, so the global error is a small multiple of tol: measured 3.7-7.3 x tol
    (dopri5) and 1.8-6.0 x tol (dop853) with free sub-steps (step = 1 s), less when the
    10 ms step caps them. 15 x tol allows for that growth and fails for a controller that
    ignores the tolerance."""
    worst, _ = adaptive_error(method, tolerance, step)
    assert worst <= 15 * tolerance


@pytest.mark.parametrize("method", ADAPTIVE)
def test_adaptive_error_falls_with_tolerance(method):
    """Over tol = 1e-3..1e-10 the error falls at every step, in proportion to tol (log-log
    slope measured 1.04 for dopri5 and 1.05 for dop853; 0.8-1.25 allowed), and the work
    rises."""
    results = [adaptive_error(method, tol, 1.0) for tol in TOLERANCES]
    errors = [e for e, _ in results]
    substeps = [s for _, s in results]
    assert all(a > b for a, b in zip(errors, errors[1:]))
    assert all(a < b for a, b in zip(substeps, substeps[1:]))
    assert 0.8 < observed_order(TOLERANCES, errors) < 1.25


def adaptive_work(method: str, tolerance: float, step: float = 1.0) -> Counters:
    integrator = make_integrator(method, tolerance)
    model = Model(oscillator(100.0))
    q, v = model.initial_state()
    for _ in range(round(1.0 / step)):
        q, v = integrator.step(model.accelerations, q, v, step)
    return integrator.counters


@pytest.mark.parametrize("method, new_per_trial, new_on_accept",
                         [("dopri5", 6, 0), ("dop853", 11, 1)])
def test_adaptive_evaluations_per_trial(method, new_per_trial, new_on_accept):
    """Each step evaluates k_1 once; each trial sub-step its new stages; DOP853, whose
    error estimate does not read the slope at the new state, evaluates it only for an
    accepted sub-step. Steps of 0.25 s at tol 1e-9 make the first trials too long: some
    are refused (counted), so both terms are exercised."""
    work = adaptive_work(method, 1e-9, 0.25)
    assert work.rejected > 0
    trials = work.substeps + work.rejected
    assert work.evaluations == 4 + new_per_trial * trials + new_on_accept * work.substeps


def test_dop853_needs_fewer_evaluations_than_dopri5_at_tight_tolerances():
    """The point of the higher order: at tol 1e-10 over 1 s of the oscillator, DOP853 needs
    fewer than half the evaluations of DOPRI5 (measured 369 against 1457), and is more
    accurate for it."""
    dopri5, dop853 = (adaptive_work(m, 1e-10).evaluations for m in ADAPTIVE)
    assert dop853 < 0.5 * dopri5
    assert adaptive_error("dop853", 1e-10, 1.0)[0] < adaptive_error("dopri5", 1e-10, 1.0)[0]
