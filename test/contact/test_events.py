"""Event location (``contacts.events``): wall impacts at the instant of touch.

References: the bouncing ball's closed form (:mod:`hecker_dynamics.bench.bounce`: impact
times t_k, apex heights r + e^(2k) d, the state at any time), the collision impulse
j = -(1 + e) v_rel.n / K with K = 1/M + (perp(r).n)^2 / I, and free flight at constant
velocity or acceleration. ``dopri5``, ``dop853`` and ``rk4`` integrate a parabola exactly
(order >= 2), so with event location every difference from the closed form comes from the
root find, which stops within delta = tolerance (1 + |x_CM|) of the wall.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics import Simulation
from hecker_dynamics.bench.bounce import BallDrop, ball_drop_scene
from hecker_dynamics.dynamics import kernel

G = 9.81
DROP = BallDrop(height=1.1, radius=0.1, gravity=G, restitution=0.8)
BOUNCES = 5


def _run(scene, until):
    sim = Simulation(scene)
    heights, times = [], []
    while sim.time_ns * 1e-9 < until - 1e-12:
        sim.step()
        times.append(sim.time_ns * 1e-9)
        heights.append(float(sim.q[0, 1]))
    return sim, np.array(times), np.array(heights)


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_adaptive_methods_meet_the_closed_form_to_their_tolerance(method):
    """tol 1e-10, h = 10 ms: the root find stops within delta = 1e-10 (1 + 1.1) m of the
    floor, i.e. within delta / v_k <= 1.2e-10 s of the touch (v_k >= e^4 v_1 = 1.8 m/s);
    the velocity at the impulse is then off by g x that, 1.2e-9 m/s, moving each later
    flight by 2/g of it, 2.4e-10 s, and its apex by v_k / g x 1.2e-9 m/s < 1e-9 m. Over five
    bounces: times within 5 x 3.6e-10 < 2e-9 s, apexes and the state at every step end
    (height within 1e-9 + the flight's shift x the speed, 2e-9 x 4.4 m/s) within 1e-8:
    asserted, impact times to 1e-8 s as the issue asks."""
    scene = ball_drop_scene(DROP, 0.01, method, tolerance=1e-10, events=True)
    until = DROP.impact_time(BOUNCES + 1) - 0.01
    sim, times, heights = _run(scene, until)
    impacts = sim.impacts[:BOUNCES]
    assert len(sim.impacts) == BOUNCES
    for k, impact in enumerate(impacts, start=1):
        assert impact.time == pytest.approx(DROP.impact_time(k), abs=1e-8)
        apex = impact.q[1] + impact.v[1] ** 2 / (2.0 * G)  # free flight from the impulse
        assert apex == pytest.approx(DROP.apex_height(k), abs=1e-8)
    exact = np.array([DROP.state(t)[0] for t in times])
    assert np.abs(heights - exact).max() <= 1e-8


def test_energy_after_each_bounce_is_e_squared_times_before():
    """Energy above the resting height, g (y - r) + v^2 / 2 per kg, right after each
    located impact: e^2 times that after the one before (the flight keeps it: dopri5 is
    exact on a parabola), the first e^2 g d. To 1e-9 relative: the impulse acts up to
    1.2e-10 s from the touch (see above), changing v_k by 1.2e-9 m/s of >= 1.8 m/s."""
    scene = ball_drop_scene(DROP, 0.01, "dopri5", tolerance=1e-10, events=True)
    sim, _, _ = _run(scene, DROP.impact_time(BOUNCES) + 0.05)
    energies = [G * (i.q[1] - DROP.radius) + 0.5 * i.v[1] ** 2 for i in sim.impacts]
    before = G * DROP.first_fall
    assert len(energies) == BOUNCES
    for energy in energies:
        assert energy == pytest.approx(DROP.energy_ratio() * before, rel=1e-9)
        before = energy


def _contact_pass_error(step):
    """Largest height error at the step ends before the fourth impact, dopri5 without
    event location."""
    scene = ball_drop_scene(DROP, step, "dopri5", tolerance=1e-10)
    _, times, heights = _run(scene, DROP.impact_time(4))
    exact = np.array([DROP.state(t)[0] for t in times])
    return float(np.abs(heights - exact).max())


def test_without_events_the_error_is_first_order_in_the_step():
    """The contact pass bounces at the step's end, so the error is O(h) whatever the
    tolerance (dopri5 at 1e-10 is exact in flight): from h = 4 ms to 1 ms it falls by
    2.5 to 6 (first order: 4; second order would give 16), and at 1 ms it is over 1e-4 m,
    a million times the error with event location."""
    coarse, fine = _contact_pass_error(0.004), _contact_pass_error(0.001)
    assert 2.5 <= coarse / fine <= 6.0
    assert fine > 1e-4


def test_a_fast_ball_does_not_tunnel_and_bounces_at_the_right_time():
    """No gravity, 1000 m/s at the floor from 5.1 m (center; r = 0.1), 20 ms steps (20 m
    of travel a step): the impact at 5 / 1000 s, leaving at e x 1000 m/s, so at 20 ms the
    center is at r + 800 x 0.015 m. Constant velocity is exact for every method, so the
    time is within delta / v = 1e-6 (1 + 5.1) / 1000 s."""
    sim = Simulation(make_scene({
        "step": 0.02, "integrator": "dopri5", "contacts": {"events": True},
        "bodies": {"ball": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                            "position": [0.0, 5.1], "velocity": [0.0, -1000.0]}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.8,
                            "friction": 0.0}}}))
    sim.step()
    (impact,) = sim.impacts
    assert impact.time == pytest.approx(0.005, abs=1e-8)
    assert sim.v[0, 1] == pytest.approx(800.0, rel=1e-12)
    assert sim.q[0, 1] == pytest.approx(0.1 + 800.0 * 0.015, abs=1e-5)


def test_a_tilted_box_lands_on_its_corner_with_the_impulse_formula():
    """A 1 x 0.5 box of 2 kg turned 0.3 rad, dropped (no spin) with its lowest corner
    0.5 m above the floor, e = 0.5, rk4 at 10 ms (exact on a parabola), tolerance 1e-10 (so
    the touch within 1e-10 (1 + 0.5) m / 3.1 m/s = 5e-11 s): the corner touches
    at sqrt(2 x 0.5 / g), at v = -g t; the impulse j = -(1 + e) v / K with
    K = 1/M + (r x n)^2 / I sets v_y' = v + j / M and omega' = (r x n) j / I."""
    angle, mass, e = 0.3, 2.0, 0.5
    c, s = math.cos(angle), math.sin(angle)
    corners = [(c * x - s * y, s * x + c * y) for x, y in
               ((-0.5, -0.25), (0.5, -0.25), (0.5, 0.25), (-0.5, 0.25))]
    low = min(corners, key=lambda p: p[1])
    center_height = 0.5 - low[1]
    sim = Simulation(make_scene({
        "step": 0.01, "integrator": "rk4", "tolerance": 1e-10, "contacts": {"events": True},
        "bodies": {"box": {"shape": "box", "size": [1.0, 0.5], "mass": mass,
                           "angle": angle, "position": [0.0, center_height]}},
        "forces": {"g": {"type": "gravity"}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": e,
                            "friction": 0.0}}}))
    for _ in range(40):
        sim.step()
    impact = sim.impacts[0]
    t1 = math.sqrt(2.0 * 0.5 / G)
    assert impact.time == pytest.approx(t1, abs=1e-8)
    inertia = mass * (1.0 + 0.25) / 12.0
    arm = low[0]  # r x n with n = (0, 1)
    k = 1.0 / mass + arm * arm / inertia
    j = (1.0 + e) * G * t1 / k
    assert impact.v[1] == pytest.approx(-G * t1 + j / mass, abs=1e-7)
    assert impact.v[2] == pytest.approx(arm * j / inertia, abs=1e-7)


def test_the_ball_comes_to_rest_through_the_contact_pass():
    """Past the Zeno time (4.06 s) the bounces are too slow for the threshold: the contact
    pass holds the ball at rest, touching the floor (within its slop), not sinking, its
    velocity what the pass leaves a resting body (under one step's gravity, g h)."""
    scene = ball_drop_scene(DROP, 0.01, "dopri5", tolerance=1e-8, events=True)
    sim, _, heights = _run(scene, 5.0)
    assert DROP.zeno_time < 4.1
    assert abs(sim.q[0, 1] - DROP.radius) <= 1e-4
    assert abs(sim.v[0, 1]) <= G * 0.01
    assert heights.min() >= DROP.radius - 1e-4


def test_events_step_in_python_with_the_same_bits_with_and_without_the_kernel():
    """The kernel locates no events: a scene asking for them takes the Python path in
    every build (its compiled forces and contact pass give Python's bits), so a build with
    the kernel and one without agree exactly; events off, the kernel steps it."""
    scene = ball_drop_scene(DROP, 0.002, "dopri5", tolerance=1e-9, events=True)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast._compiled is None
    for sim in (fast, slow):
        sim.advance_to(2_000_000_000, keep=False)
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    assert fast.impacts == slow.impacts
    if kernel.enabled():
        plain = Simulation(ball_drop_scene(DROP, 0.002, "dopri5", tolerance=1e-9))
        assert plain._compiled is not None


def test_events_are_deterministic_and_restart_with_reset():
    scene = ball_drop_scene(DROP, 0.01, "dop853", tolerance=1e-9, events=True)
    sim = Simulation(scene)
    sim.advance_to(1_500_000_000, keep=False)
    first, state = sim.impacts, (sim.q.copy(), sim.v.copy())
    sim.reset()
    assert sim.impacts == []
    sim.advance_to(1_500_000_000, keep=False)
    assert sim.impacts == first
    assert np.array_equal(sim.q, state[0]) and np.array_equal(sim.v, state[1])


def test_a_resting_pyramid_gives_the_same_bits_with_events_on():
    """Resting contacts and friction stay with the contact pass: a pyramid of boxes
    resting on the floor (friction 0.6) crosses the floor by at most a step's gravity,
    slower than the restitution threshold, so no impact is located and every step is the
    one taken without events."""
    from dataclasses import replace

    from hecker_dynamics.bench.pyramid import pyramid

    scene = pyramid(3)
    plain, located = Simulation(scene), Simulation(replace(scene, events=True))
    for sim in (plain, located):
        sim.advance_to(1_000_000_000, keep=False)
    assert located.impacts == []
    assert np.array_equal(plain.q, located.q) and np.array_equal(plain.v, located.v)


def test_a_step_split_for_a_colliding_pair_logs_its_impact_once():
    """Two balls (r = 0.05) that collide with each other make the simulation split a step
    in which one moves more than half a ball (20 m/s x 10 ms = 0.2 m: 4 sub-steps, 2 in
    the step of the bounce); the first attempt's located impact is dropped with it, and
    the sub-steps locate it again: no gravity, center 1.055 m up at 20 m/s down, so the
    touch at 1.005 / 20 s."""
    sim = Simulation(make_scene({
        "step": 0.01, "integrator": "dopri5", "tolerance": 1e-10,
        "contacts": {"events": True},
        "bodies": {"fast": {"shape": "circle", "radius": 0.05, "mass": 1.0,
                            "position": [0.0, 1.055], "velocity": [0.0, -20.0]},
                   "slow": {"shape": "circle", "radius": 0.05, "mass": 1.0,
                            "position": [3.0, 1.0]}},
        "collisions": {"balls": {"bodies": ["fast", "slow"]}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.5,
                            "friction": 0.0}}}))
    assert sim.model.contacts.substeps(sim.q, sim.q + [[0.0, -0.2, 0.0], [0.0, 0.0, 0.0]]) == 4
    for _ in range(8):
        sim.step()
    (impact,) = sim.impacts
    assert impact.time == pytest.approx(1.005 / 20.0, abs=1e-9)
    assert sim.v[0, 1] == pytest.approx(10.0, rel=1e-12)
