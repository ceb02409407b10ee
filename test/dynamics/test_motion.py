"""Closed-form motion: constant force and torque, torque-free spin, off-center forces,
the harmonic oscillator.

Each test compares the core with a solution worked out by hand (the article's steps 4-6,
"Physics, Part 2: Angular Effects": F = M a at the CM, torque = perp-dot(r, F),
alpha = torque / I), not with the core's own formulas.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import angle_difference, exact_wrapped_angle, make_scene, oscillator

from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.integrators.methods import METHODS, make_integrator

EPS = np.finfo(float).eps

# ----------------------------------------------------------------------------- constant force

# Box 2 m x 1 m of 2 kg: I = m (w^2 + h^2) / 12 = 5/6 kg m^2.
MASS, INERTIA = 2.0, 2.0 * (2.0 ** 2 + 1.0 ** 2) / 12.0
FORCE, TORQUE, GRAVITY = np.array([3.0, -2.0]), 0.5, np.array([0.0, -9.81])
X0, A0, V0, W0 = np.array([1.0, 2.0]), 0.3, np.array([0.7, 1.1]), -0.4


def constant_wrench_scene():
    return make_scene({
        "bodies": {"b": {"shape": "box", "size": [2.0, 1.0], "mass": MASS,
                         "position": X0.tolist(), "angle": A0, "velocity": V0.tolist(),
                         "angular_velocity": W0}},
        "forces": {
            "gravity": {"type": "gravity", "acceleration": GRAVITY.tolist()},
            "push": {"type": "constant_force", "body": "b", "force": FORCE.tolist()},
            "twist": {"type": "constant_torque", "body": "b", "torque": TORQUE},
        },
    })


# Position error of each method under a constant acceleration a after n steps of h
# (t = n h), as a multiple of a h t / 2. Velocities are exact for every method.
#   explicit Euler:            x_n = x0 + h sum_{k<n} v_k   -> -a h t / 2
#   semi-implicit Euler:       x_n = x0 + h sum_{k<=n} v_k  -> +a h t / 2
#   backward Euler (v* = v1):  the same update as semi-implicit Euler -> +a h t / 2
#   Verlet, RK4, DOPRI5, DOP853, implicit midpoint: exact for a quadratic in t.
EULER_COEFFICIENT = {"explicit_euler": -1.0, "semi_implicit_euler": 1.0, "backward_euler": 1.0}


@pytest.mark.parametrize("method", METHODS)
def test_constant_force_and_torque_follow_the_parabola(method):
    model = Model(constant_wrench_scene())
    assert model.mass[0] == pytest.approx(MASS, rel=1e-15)
    assert model.inertia[0] == pytest.approx(INERTIA, rel=1e-14)
    a = FORCE / MASS + GRAVITY
    alpha = TORQUE / INERTIA
    integrator = make_integrator(method, 1e-8)
    q, v = model.initial_state()
    n, h = 50, 0.02
    for _ in range(n):
        q, v = integrator.step(model.accelerations, q, v, h)
    t = n * h
    c = EULER_COEFFICIENT.get(method, 0.0)
    x = X0 + V0 * t + a * t * t / 2 + c * a * h * t / 2
    angle = A0 + W0 * t + alpha * t * t / 2 + c * alpha * h * t / 2
    # Values are O(10); 50 steps of a few roundings of O(10) each stay far below 1e-12.
    np.testing.assert_allclose(q[0, :2], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[0, :2], V0 + a * t, rtol=0, atol=1e-12)
    assert q[0, 2] == pytest.approx(angle, abs=1e-12)
    assert v[0, 2] == pytest.approx(W0 + alpha * t, abs=1e-12)
    if c:  # the first-order error is really there, with its sign: not an exact method
        assert np.all(np.sign(q[0, :2] - (X0 + V0 * t + a * t * t / 2)) == c * np.sign(a))


# ----------------------------------------------------------------------------- free spin

def test_torque_free_spin_wraps_and_keeps_the_cm_still():
    """A body whose frame origin is 0.3 m from its CM spins freely for 10^4 steps: the
    published angle stays in [-pi, pi) and matches the exact wrapped angle; the CM does not
    move and the published origin circles it.

    The scene's velocity is that of the body-frame origin, so a still CM needs the origin
    to start with v = omega perp(origin - CM) = offset omega (sin a0, -cos a0)."""
    omega, angle0, step = 3.7, 1.0, 0.001
    offset = 0.3  # the box's center, hence the CM, in the body frame
    origin_velocity = offset * omega * np.array([math.sin(angle0), -math.cos(angle0)])
    scene = make_scene({
        "step": step, "publish_rate": 100.0, "integrator": "semi_implicit_euler",
        "bodies": {"b": {"shape": "box", "size": [0.4, 0.2], "center": [offset, 0.0],
                         "mass": 1.0, "position": [2.0, -1.0], "angle": angle0,
                         "velocity": origin_velocity.tolist(), "angular_velocity": omega}},
    })
    sim = Simulation(scene)
    cm = np.array([2.0, -1.0]) + offset * np.array([math.cos(angle0), math.sin(angle0)])
    np.testing.assert_allclose(sim.q[0, :2], cm, atol=1e-15)
    np.testing.assert_allclose(sim.v[0], [0.0, 0.0, omega], atol=1e-15)
    snapshots = sim.advance_to(10 * 10 ** 9)
    assert len(snapshots) == 1000
    angles = []
    for snap in snapshots:
        body = snap.bodies[0]
        n = round(snap.time_ns / scene.step_ns)
        exact = exact_wrapped_angle(angle0, omega, step, n)
        assert -math.pi <= body.angle < math.pi
        # One add and at most one wrap per step, each rounding by ~eps * pi: after 10^4
        # steps at most ~1e-11 even if every rounding went the same way.
        assert angle_difference(body.angle, exact) < 1e-11
        assert body.angular_velocity == omega  # nothing acts: bit for bit
        c, s = math.cos(body.angle), math.sin(body.angle)
        np.testing.assert_allclose(body.position, cm - offset * np.array([c, s]), atol=1e-12)
        np.testing.assert_allclose(body.linear_velocity, offset * omega * np.array([s, -c]),
                                   atol=1e-12)
        angles.append(body.angle)
    assert min(angles) < -3.0 and max(angles) > 3.0  # it went round several times
    np.testing.assert_allclose(sim.q[0, :2], cm, atol=1e-12)


# ----------------------------------------------------------------------------- off-center force

def off_center_scene(angle: float, axes: str):
    """A 2 m x 1 m box of 2 kg centered at (0.2, -0.1) in its frame, pushed by (3, 4) N at its
    named point 'tip' = (1.0, 0.5), which is (0.8, 0.6) from the CM in body axes."""
    return make_scene({
        "bodies": {"b": {"shape": "box", "size": [2.0, 1.0], "center": [0.2, -0.1],
                         "mass": 2.0, "position": [5.0, 7.0], "angle": angle,
                         "velocity": [0.3, -0.2], "angular_velocity": 1.5,
                         "points": {"tip": [1.0, 0.5]}}},
        "forces": {"push": {"type": "constant_force", "body": "b", "force": [3.0, 4.0],
                            "point": "tip", "axes": axes}},
    })


# Hand values, I = 5/6. With angle 0 the offset r is (0.8, 0.6) in world axes too; with
# angle pi/2 it is (-0.6, 0.8), and a body-axes force (3, 4) is (-4, 3) in world axes.
#   tau = r_x F_y - r_y F_x
OFF_CENTER_CASES = [
    # angle, axes, world force, torque
    (0.0, "world", (3.0, 4.0), 0.8 * 4.0 - 0.6 * 3.0),            # 1.4
    (0.0, "body", (3.0, 4.0), 0.8 * 4.0 - 0.6 * 3.0),             # 1.4
    (math.pi / 2, "world", (3.0, 4.0), -0.6 * 4.0 - 0.8 * 3.0),   # -4.8
    (math.pi / 2, "body", (-4.0, 3.0), -0.6 * 3.0 - 0.8 * -4.0),  # 1.4: rotation-invariant
]


@pytest.mark.parametrize("angle, axes, force, torque", OFF_CENTER_CASES)
def test_off_center_force_makes_perp_dot_torque(angle, axes, force, torque):
    model = Model(off_center_scene(angle, axes))
    q, v = model.initial_state()
    acc = model.accelerations(q, v)
    # cos(pi/2) is 6e-17, not 0: errors of a few 1e-16 on O(1) values.
    np.testing.assert_allclose(acc[0, :2], np.array(force) / 2.0, rtol=0, atol=1e-14)
    assert acc[0, 2] == pytest.approx(torque / (5.0 / 6.0), abs=1e-14)
    # The torque depends only on the point and the force, not on the velocity.
    acc_still = model.accelerations(q, np.zeros_like(v))
    np.testing.assert_array_equal(acc, acc_still)


@pytest.mark.parametrize("rest_length, force, torque", [
    # Zero rest length, the linear law F = -k d - c v_P:
    #   F = -10 (0, 2) - 3 (-1.2, -0.95) = (3.6, -17.15); tau = -0.6 * -17.15 - 0.8 * 3.6
    (0.0, (3.6, -17.15), 7.41),
    # Rest length 0.5, along u = (0, 1): F = -(10 (2 - 0.5) + 3 (v_P . u)) u = (0, -12.15);
    #   tau = -0.6 * -12.15
    (0.5, (0.0, -12.15), 7.29),
])
def test_damped_spring_at_a_named_point_uses_the_point_velocity(rest_length, force, torque):
    """The box of the previous test, turned by pi/2 with its frame origin at (5, 7): its CM
    is at (5.1, 7.2) and its tip at (4.5, 8.0), r = (-0.6, 0.8). A spring k = 10, c = 3
    joins the tip to an anchor at (4.5, 6.0), so d = (0, 2). The origin moves at (0.3, -0.2)
    and the body turns at 1.5 rad/s, so the tip moves at
    v_P = (0.3, -0.2) + 1.5 perp((-0.5, 1.0)) = (-1.2, -0.95) (Eq. 9)."""
    model = Model(make_scene({
        "bodies": {"b": {"shape": "box", "size": [2.0, 1.0], "center": [0.2, -0.1],
                         "mass": 2.0, "position": [5.0, 7.0], "angle": math.pi / 2,
                         "velocity": [0.3, -0.2], "angular_velocity": 1.5,
                         "points": {"tip": [1.0, 0.5]}}},
        "forces": {"spring": {"type": "spring", "body_a": "b", "point_a": "tip",
                              "anchor": [4.5, 6.0], "stiffness": 10.0, "damping": 3.0,
                              "rest_length": rest_length}},
    }))
    q, v = model.initial_state()
    np.testing.assert_allclose(q[0], [5.1, 7.2, math.pi / 2], rtol=0, atol=1e-14)
    acc = model.accelerations(q, v)
    # Inputs of O(10) with cos(pi/2) = 6e-17 instead of 0: a few 1e-15 of rounding.
    np.testing.assert_allclose(acc[0, :2], np.array(force) / 2.0, rtol=0, atol=1e-13)
    assert acc[0, 2] == pytest.approx(torque / (5.0 / 6.0), abs=1e-13)


def test_force_at_cm_and_gravity_make_no_torque():
    model = Model(make_scene({
        "bodies": {"b": {"shape": "box", "size": [2.0, 1.0], "center": [0.2, -0.1],
                         "mass": 2.0, "angle": 0.7, "angular_velocity": 3.0,
                         "points": {"cm": [0.2, -0.1]}}},
        "forces": {"gravity": {"type": "gravity"},
                   "push": {"type": "constant_force", "body": "b", "force": [3.0, 4.0],
                            "point": "cm", "axes": "body"}},
    }))
    q, v = model.initial_state()
    acc = model.accelerations(q, v)
    c, s = math.cos(0.7), math.sin(0.7)
    np.testing.assert_allclose(acc[0, :2], [(3 * c - 4 * s) / 2, (3 * s + 4 * c) / 2 - 9.81],
                               rtol=0, atol=1e-14)
    assert abs(acc[0, 2]) < 1e-14  # the point is the CM up to rounding of the centroid


# ----------------------------------------------------------------------------- oscillator

@pytest.mark.parametrize("method, bound", [
    # Phase error per step of RK4 on x'' = -w^2 x is (wh)^5 / 120 (amplitude error
    # (wh)^6 / 144, negligible): after time t, |x - A cos wt| <= A w t (wh)^4 / 120.
    ("rk4", lambda A, w, h, t: A * w * t * (w * h) ** 4 / 120),
    # Implicit midpoint keeps the amplitude and turns by 2 atan(wh/2) per step: the phase
    # error per step is (wh)^3 / 12 to leading order.
    ("implicit_midpoint", lambda A, w, h, t: A * w * t * (w * h) ** 2 / 12),
])
def test_harmonic_oscillator_follows_a_cosine(method, bound):
    """1 kg on a zero-length spring k = 100 to an anchor at the CM, run through the
    Simulation: x = A cos(wt), y = (v0 / w) sin(wt), w = 10 rad/s, and no rotation."""
    k, A, vy0, step = 100.0, 0.5, 2.0, 0.001
    w = math.sqrt(k)
    sim = Simulation(oscillator(k, position=(A, 0.0), velocity=(0.0, vy0), step=step,
                                publish_rate=50.0, integrator=method))
    assert sim.integrator.name == method
    snapshots = sim.advance_to(2 * 10 ** 9)
    assert len(snapshots) == 100
    worst = 0.0
    for snap in snapshots:
        t = snap.time_ns * 1e-9
        body = snap.bodies[0]
        allowed = 1.1 * bound(max(A, vy0 / w), w, step, t) + 1e-13
        x_err = abs(body.position[0] - A * math.cos(w * t))
        y_err = abs(body.position[1] - vy0 / w * math.sin(w * t))
        assert x_err <= allowed and y_err <= allowed
        worst = max(worst, x_err / allowed)
        assert body.angle == 0.0 and body.angular_velocity == 0.0
        # Energy stays at its initial value within the same relative accuracy.
        assert snap.energy == pytest.approx(0.5 * (k * A * A + vy0 * vy0), rel=1e-6)
    assert worst > 0.3  # the predicted error is the real one, not a loose bound
