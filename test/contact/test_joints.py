"""Joints (hecker_dynamics.contact.joints) against exact solutions and conserved quantities.

The pendulum tests use ``velocity_verlet`` with h = 1 ms: with it the joint pass is RATTLE,
second order and symplectic (docs/scenes.md, `joints.<name>`), so the period is within about
6e-7 of the exact one at that step and the energy stays bounded.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scene_builders import box_inertia, make_scene, write_scene

from hecker_dynamics.dynamics import DivergenceError, Simulation, kernel
from hecker_dynamics.scene import SceneError, load_scene

G = 9.81
ROD = dict(mass=2.0, width=0.05, length=1.0)  # pinned at one end: d = 0.5 m
I_PIVOT = box_inertia(ROD["mass"], ROD["width"], ROD["length"]) + ROD["mass"] * 0.25
SMALL_PERIOD = 2.0 * math.pi * math.sqrt(I_PIVOT / (ROD["mass"] * G * 0.5))


def elliptic_k(k: float) -> float:
    """Complete elliptic integral of the first kind, K(k) = pi / (2 AGM(1, sqrt(1 - k^2)))."""
    a, b = 1.0, math.sqrt(1.0 - k * k)
    for _ in range(40):  # quadratic convergence: a handful of passes reach rounding
        if abs(a - b) <= 4e-16 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return math.pi / (2.0 * a)


def exact_period(amplitude: float) -> float:
    """The rigid pendulum's period at ``amplitude``: T0 (2 / pi) K(sin(amplitude / 2))."""
    return SMALL_PERIOD * 2.0 / math.pi * elliptic_k(math.sin(0.5 * amplitude))


def pendulum_scene(amplitude: float, step: float = 0.001, method: str = "velocity_verlet",
                   **extra):
    """A rod hanging from the world at its top end, let go at ``amplitude`` from below."""
    return make_scene({
        "step": step, "integrator": method, "publish_rate": 10.0,
        "bodies": {"rod": {"shape": "box", "size": [ROD["width"], ROD["length"]],
                           "mass": ROD["mass"], "angle": amplitude,
                           "position": [0.5 * math.sin(amplitude), -0.5 * math.cos(amplitude)],
                           "points": {"top": [0.0, 0.5]}}},
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"pin": {"type": "revolute", "body_b": "rod", "point_b": "top", **extra}},
    })


def measured_period(sim: Simulation, periods: int) -> float:
    """Mean time between downward zero crossings of the angle (linear interpolation, whose
    error is third order there: the angle's curvature vanishes at the bottom)."""
    h, crossings, before = sim.step_seconds, [], float(sim.q[0, 2])
    while len(crossings) <= periods:
        sim.step()
        after = float(sim.q[0, 2])
        if before > 0.0 >= after:
            crossings.append(sim.time_ns * 1e-9 - h + h * before / (before - after))
        before = after
    return (crossings[-1] - crossings[0]) / periods


def pivot_error(sim: Simulation) -> float:
    """Distance of the rod's top from the anchor at the origin."""
    x, y, angle = sim.q[0]
    return math.hypot(x - 0.5 * math.sin(angle), y + 0.5 * math.cos(angle))


def test_agm_elliptic_integral_matches_its_series():
    k = 0.3  # K = pi/2 (1 + k^2/4 + 9 k^4/64 + 25 k^6/256 + 1225 k^8/16384 + ...)
    series = math.pi / 2 * (1 + k**2 / 4 + 9 * k**4 / 64 + 25 * k**6 / 256
                            + 1225 * k**8 / 16384 + 3969 * k**10 / 65536)
    assert elliptic_k(k) == pytest.approx(series, rel=1e-7)


def test_small_amplitude_period_is_the_compound_pendulum_period():
    period = measured_period(Simulation(pendulum_scene(1e-3)), periods=4)
    assert abs(period / SMALL_PERIOD - 1.0) < 1e-4


def test_large_amplitude_period_is_the_elliptic_integral_period():
    amplitude = 2.5
    period = measured_period(Simulation(pendulum_scene(amplitude)), periods=2)
    assert exact_period(amplitude) / SMALL_PERIOD > 1.5  # far from the small-angle period
    assert abs(period / exact_period(amplitude) - 1.0) < 1e-4


def test_the_joint_pass_is_second_order():
    """Period error at h and h/2 against the exact period: ratio 4 for order two."""
    amplitude = 1.0
    errors = [abs(measured_period(Simulation(pendulum_scene(amplitude, step)), periods=2)
                  / exact_period(amplitude) - 1.0) for step in (0.004, 0.002)]
    assert 3.5 < errors[0] / errors[1] < 4.5


def test_energy_stays_bounded_and_the_pivot_stays_on_its_anchor():
    """100,000 steps in 100 blocks; 20,000 without the kernel, which repeats the Python
    path's steps bit for bit (test_joints_compiled)."""
    sim = Simulation(pendulum_scene(1.0))
    start = sim.snapshot().energy
    scale = ROD["mass"] * G * 0.5  # the swing's potential energy range is about this
    block = 1000 if kernel.enabled() else 200
    drift = []
    for _ in range(100):
        sim.advance_to(sim.time_ns + block * sim.step_ns, keep=False)
        drift.append(abs(sim.snapshot().energy - start))
        if sim.steps == 60 * block:
            assert pivot_error(sim) < 1e-6
    assert sim.steps == 100 * block
    assert max(drift) < 1e-4 * scale
    assert max(drift[-10:]) < 2.0 * max(drift[:10]) + 1e-12 * scale  # bounded, not growing


def chain_scene(links: int, masses=None, step: float = 0.001):
    """``links`` rods of 0.1 m laid out horizontally from the world pin at the origin,
    each pinned to the next at their shared end."""
    masses = masses or [0.1] * links
    bodies, joints = {}, {}
    for i in range(links):
        bodies[f"l{i}"] = {"shape": "box", "size": [0.1, 0.02], "mass": masses[i],
                           "position": [0.05 + 0.1 * i, 0.0],
                           "points": {"left": [-0.05, 0.0], "right": [0.05, 0.0]}}
        joints[f"j{i}"] = ({"type": "revolute", "body_b": "l0", "point_b": "left"} if i == 0 else
                           {"type": "revolute", "body_a": f"l{i - 1}", "point_a": "right",
                            "body_b": f"l{i}", "point_b": "left"})
    return make_scene({"step": step, "integrator": "velocity_verlet", "publish_rate": 10.0,
                       "bodies": bodies, "forces": {"gravity": {"type": "gravity"}},
                       "joints": joints})


def chain_error(sim: Simulation) -> float:
    """Largest distance between the ends that a joint of the chain holds together."""
    links = sim.q[[sim.model.index[f"l{i}"] for i in range(sim.model.size)]]
    x, y, angle = links[:, 0], links[:, 1], links[:, 2]
    ends = [(x - 0.05 * np.cos(angle), y - 0.05 * np.sin(angle)),
            (x + 0.05 * np.cos(angle), y + 0.05 * np.sin(angle))]
    gaps = [math.hypot(ends[0][0][0], ends[0][1][0])]
    gaps += np.hypot(ends[0][0][1:] - ends[1][0][:-1], ends[0][1][1:] - ends[1][1][:-1]).tolist()
    return max(gaps)


def test_a_chain_of_twenty_links_stays_connected_and_gains_no_energy():
    sim = Simulation(chain_scene(20))
    start = sim.snapshot().energy
    drop = 0.1 * 20 * G * 1.0  # the chain's potential energy range, about m g L
    worst, highest = 0.0, -math.inf
    for _ in range(30):
        for _ in range(50):
            sim.step()
        worst = max(worst, chain_error(sim))
        highest = max(highest, sim.snapshot().energy - start)
    assert worst < 1e-3
    assert highest < 1e-3 * drop
    assert float(np.min(sim.q[:, 1])) < -0.3  # it did swing down


def test_a_mass_ratio_of_100_across_a_joint_is_stable():
    sim = Simulation(chain_scene(2, masses=[1.0, 100.0]))
    start = sim.snapshot().energy
    for _ in range(3000):
        sim.step()
    assert chain_error(sim) < 1e-9
    assert abs(sim.snapshot().energy - start) < 1e-3 * 101.0 * G * 0.2


SLOPE = 0.4  # rad below the horizontal


def slider_scene(**joint):
    """A box on a slider fixed in the world, its axis pointing down a slope of SLOPE."""
    return make_scene({
        "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
        "bodies": {"box": {"shape": "box", "size": [0.2, 0.1], "mass": 3.0, "angle": 0.3,
                           "angular_velocity": 0.0}},
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"rail": {"type": "prismatic", "body_b": "box",
                            "axis": [math.cos(SLOPE), -math.sin(SLOPE)], **joint}},
    })


def slider_state(sim: Simulation) -> tuple[float, float, float]:
    return sim.model.joints.joint_state(sim.q, sim.v)["rail"]


def test_a_slider_slides_at_g_sin_a():
    sim = Simulation(slider_scene())
    for _ in range(1000):
        sim.step()
    t = sim.time_ns * 1e-9
    along, rate, _ = slider_state(sim)
    assert along == pytest.approx(0.5 * G * math.sin(SLOPE) * t * t, rel=1e-9)
    assert rate == pytest.approx(G * math.sin(SLOPE) * t, rel=1e-9)
    assert sim.q[0, 2] == pytest.approx(0.3, abs=1e-12)  # the slider keeps its angle


def test_a_slider_limit_stops_it():
    sim = Simulation(slider_scene(lower=-0.1, upper=0.5))
    for _ in range(2000):
        sim.step()
        assert slider_state(sim)[0] <= 0.5 + 1e-9
    along, rate, effort = slider_state(sim)
    assert along == pytest.approx(0.5, abs=1e-9)
    assert abs(rate) < 1e-9
    assert effort == pytest.approx(-3.0 * G * math.sin(SLOPE), rel=1e-6)  # holds gravity


def test_a_slider_motor_reaches_its_speed_when_its_force_suffices():
    weight = 3.0 * G * math.sin(SLOPE)  # gravity's pull along the axis
    sim = Simulation(slider_scene(motor={"speed": -0.5, "max_force": 2.0 * weight}))
    for _ in range(1000):
        sim.step()
    _, rate, effort = slider_state(sim)
    assert rate == pytest.approx(-0.5, abs=1e-12)
    assert effort == pytest.approx(-weight, rel=1e-9)


def test_a_slider_motor_too_weak_is_dragged_down():
    weight = 3.0 * G * math.sin(SLOPE)
    sim = Simulation(slider_scene(motor={"speed": -0.5, "max_force": 0.5 * weight}))
    for _ in range(1000):
        sim.step()
    _, rate, effort = slider_state(sim)
    t = sim.time_ns * 1e-9
    assert rate == pytest.approx((weight - 0.5 * weight) / 3.0 * t, rel=1e-9)
    assert effort == pytest.approx(-0.5 * weight, rel=1e-12)


def weld_scenes():
    """A box 1 x 0.5 with a box 0.5 x 0.5 welded to its right, pinned at the big box's left
    end and let go turning; and the same shape as one compound body."""
    common = {"step": 0.0005, "integrator": "velocity_verlet", "publish_rate": 10.0,
              "forces": {"gravity": {"type": "gravity"}}}
    angle, position = 0.4, [0.5 * math.cos(0.4), 0.5 * math.sin(0.4)]
    c, s = math.cos(angle), math.sin(angle)
    welded = make_scene({**common, "bodies": {
        "big": {"shape": "box", "size": [1.0, 0.5], "mass": 2.0, "position": position,
                "angle": angle, "angular_velocity": 1.0},
        "small": {"shape": "box", "size": [0.5, 0.5], "mass": 1.0, "angle": angle,
                  "position": [position[0] + 0.75 * c, position[1] + 0.75 * s],
                  "angular_velocity": 1.0, "velocity": [-0.75 * s, 0.75 * c]}},
        "joints": {"glue": {"type": "weld", "body_a": "big", "body_b": "small",
                            "point_b": [-0.25, 0.0]},
                   "pin": {"type": "revolute", "body_b": "big", "point_b": [-0.5, 0.0]}}})
    compound = make_scene({**common, "bodies": {
        "big": {"parts": {"left": {"shape": "box", "size": [1.0, 0.5], "density": 4.0},
                          "right": {"shape": "box", "size": [0.5, 0.5], "density": 4.0,
                                    "center": [0.75, 0.0]}},
                "position": position, "angle": angle, "angular_velocity": 1.0}},
        "joints": {"pin": {"type": "revolute", "body_b": "big", "point_b": [-0.5, 0.0]}}})
    return welded, compound


def test_a_weld_moves_like_the_compound_body():
    """Over 5 s at h = 0.5 ms: both runs are second order, and differ by 2.9e-6 m at 1 ms."""
    welded, compound = (Simulation(scene) for scene in weld_scenes())
    worst = 0.0
    for _ in range(10000):
        welded.step()
        compound.step()
        a = welded.snapshot().bodies[0]
        b = compound.snapshot().bodies[0]
        worst = max(worst, math.hypot(a.position[0] - b.position[0],
                                      a.position[1] - b.position[1]))
    assert worst < 1e-6
    assert abs(a.angle - b.angle) < 2e-6  # 1.2e-6 rad: 0.9e-6 m at the far corner


def test_a_soft_weld_sags_to_its_discrete_equilibrium():
    """The soft rows act on velocities only, after the step has moved the positions by
    h^2 g / 2 (velocity Verlet), so at rest the step ends with velocity -h g / 2, which the
    damper sees: the sag is g / k + h g (k h + c) / (2 k) with k = omega^2, c = 2 zeta omega
    per unit mass (first order in h; g / omega^2 as h -> 0)."""
    frequency = 5.0
    omega = 2.0 * math.pi * frequency
    k, c, h = omega ** 2, 2.0 * omega, 0.001
    sim = Simulation(make_scene({
        "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
        "bodies": {"box": {"shape": "box", "size": [0.2, 0.2], "mass": 4.0}},
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"mount": {"type": "weld", "body_b": "box", "frequency": frequency,
                             "damping_ratio": 1.0}}}))
    for _ in range(5000):
        sim.step()
    assert sim.q[0, 1] == pytest.approx(-(G / k + h * G * (k * h + c) / (2.0 * k)), rel=1e-9)
    assert abs(sim.q[0, 1] * k / G + 1.0) < 0.04  # near the continuous sag


def test_a_revolute_spring_holds_a_torque_near_torque_over_stiffness():
    """As the soft weld: the discrete equilibrium is tau / k + h tau (k h + c) / (2 I k)."""
    k, c, h, tau, inertia = 3.0, 1.0, 0.001, 1.5, 0.5 * 2.0 * 0.3 ** 2
    sim = Simulation(make_scene({
        "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
        "bodies": {"wheel": {"shape": "circle", "radius": 0.3, "mass": 2.0}},
        "forces": {"twist": {"type": "constant_torque", "body": "wheel", "torque": 1.5}},
        "joints": {"axle": {"type": "revolute", "body_b": "wheel",
                            "spring": {"stiffness": 3.0, "damping": 1.0, "rest_angle": 0.1}}}}))
    for _ in range(12000):
        sim.step()
    angle, rate, effort = sim.model.joints.joint_state(sim.q, sim.v)["axle"]
    assert angle == pytest.approx(0.1 + tau / k + h * tau * (k * h + c) / (2.0 * inertia * k),
                                  rel=1e-9)
    assert effort == pytest.approx(-tau, rel=1e-9)


def test_a_rod_makes_a_simple_pendulum_and_a_rope_stops_a_fall():
    length = 0.8
    rod = Simulation(make_scene({
        "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
        "bodies": {"bob": {"shape": "circle", "radius": 0.01, "mass": 1.0,
                           "position": [length * math.sin(1e-3), -length * math.cos(1e-3)]}},
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"rod": {"type": "distance", "body_b": "bob"}}}))
    period, before, crossings = None, float(rod.q[0, 0]), []
    while len(crossings) < 4:
        rod.step()
        after = float(rod.q[0, 0])
        if before > 0.0 >= after:
            crossings.append(rod.time_ns * 1e-9 - 0.001 + 0.001 * before / (before - after))
        before = after
    period = (crossings[-1] - crossings[0]) / 3
    assert period / (2.0 * math.pi * math.sqrt(length / G)) == pytest.approx(1.0, abs=1e-4)
    rope = Simulation(make_scene({
        "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
        "bodies": {"bob": {"shape": "circle", "radius": 0.01, "mass": 1.0,
                           "position": [0.0, -0.2]}},
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"rope": {"type": "distance", "body_b": "bob", "max_length": length}}}))
    for _ in range(100):
        rope.step()  # slack: free fall
    assert rope.q[0, 1] == pytest.approx(-0.2 - 0.5 * G * 0.1 ** 2, rel=1e-9)
    for _ in range(1000):
        rope.step()
        assert -rope.q[0, 1] <= length + 1e-9
    assert -rope.q[0, 1] == pytest.approx(length, abs=1e-9)


def gear_scene(ratio: float, motor: dict, limit: dict = None):
    """Two wheels on pins in the world, meshing with ``ratio``; wheel a has a motor."""
    return make_scene({
        "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
        "bodies": {"a": {"shape": "circle", "radius": 0.2, "mass": 1.0},
                   "b": {"shape": "circle", "radius": 0.2 * abs(ratio), "mass": 2.0,
                         "position": [0.2 * (1 + abs(ratio)), 0.0]}},
        "joints": {"axle_a": {"type": "revolute", "body_b": "a", "motor": motor},
                   "axle_b": {"type": "revolute", "body_b": "b", **(limit or {})},
                   "mesh": {"type": "gear", "joint_a": "axle_a", "joint_b": "axle_b",
                            "ratio": ratio}}})


@pytest.mark.parametrize("ratio", [2.5, -0.4])
def test_a_gear_pair_keeps_its_ratio_over_many_turns(ratio):
    sim = Simulation(gear_scene(ratio, {"speed": 30.0, "max_torque": 2.0}))
    worst = 0.0
    for _ in range(3000):
        sim.step()
        state = sim.model.joints.joint_state(sim.q, sim.v)
        worst = max(worst, abs(state["axle_a"][0] + ratio * state["axle_b"][0]))
    assert state["axle_a"][0] > 4.0 * math.pi  # past several turns, counted
    assert worst < 1e-9


def test_a_jammed_gear_train_stops_and_its_motor_gives_all_it_has():
    sim = Simulation(gear_scene(2.0, {"speed": 5.0, "max_torque": 0.3},
                                {"lower": -1.0, "upper": 1.0}))
    for _ in range(4000):
        sim.step()
    state = sim.model.joints.joint_state(sim.q, sim.v)
    assert state["axle_b"][0] == pytest.approx(-1.0, abs=1e-9)  # against its stop
    assert abs(state["axle_a"][1]) < 1e-9 and abs(state["axle_b"][1]) < 1e-9
    assert state["axle_a"][2] == pytest.approx(0.3, rel=1e-12)


def test_the_joint_pass_is_deterministic():
    runs = []
    for _ in range(2):
        sim = Simulation(chain_scene(4))
        for _ in range(200):
            sim.step()
        runs.append(sim.snapshot())
    assert runs[0] == runs[1]


def test_joined_bodies_do_not_collide_unless_asked():
    def scene(collide: bool):
        return make_scene({
            "bodies": {"a": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0},
                       "b": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0,
                             "position": [0.9, 0.0]}},
            "collisions": {"all": {"bodies": ["a", "b"]}},
            "joints": {"pin": {"type": "revolute", "body_a": "a", "point_a": [0.45, 0.0],
                               "body_b": "b", "point_b": [-0.45, 0.0],
                               "collide_connected": collide}}})
    apart, together = (Simulation(scene(c)).model.contacts for c in (False, True))
    assert apart.pairs.get(0, 1) is None and apart.colliding == []
    assert together.pairs.get(0, 1) == (0.2, 0.5) and together.colliding == [0, 1]


def test_reset_returns_the_joints_to_their_start():
    sim = Simulation(gear_scene(2.0, {"speed": 30.0, "max_torque": 2.0}))
    for _ in range(500):
        sim.step()
    first = sim.snapshot()
    sim.reset()
    for _ in range(500):
        sim.step()
    assert sim.snapshot() == first


def test_a_continuation_from_exported_state_is_bit_identical():
    """export_state carries the joints' counted angles, warm starts and motor speeds."""
    scene = gear_scene(2.0, {"speed": 5.0, "max_torque": 0.3}, {"lower": -1.0, "upper": 1.0})
    sim = Simulation(scene)
    for _ in range(700):
        sim.step()
    sim.model.joints.motor_speed["axle_a"] = -4.0
    state = json.loads(json.dumps(sim.export_state()))
    other = Simulation(scene)
    other.import_state(state)
    for _ in range(700):
        sim.step()
        other.step()
    assert other.snapshot() == sim.snapshot()
    assert other.model.joints.efforts == sim.model.joints.efforts


BASE = {"bodies": {"a": {"shape": "circle", "radius": 0.1, "mass": 1.0},
                   "b": {"shape": "circle", "radius": 0.1, "mass": 1.0}}}
BAD_JOINTS = [
    ({"type": "revolute", "body_b": "nobody"}, "joints.j.body_b", "unknown body 'nobody'"),
    ({"type": "revolute", "body_a": "ghost", "body_b": "b"}, "joints.j.body_a", "unknown body"),
    ({"type": "weld", "body_a": "b", "body_b": "b"}, "joints.j.body_b", "to itself"),
    ({"type": "revolute", "body_b": "b", "lower": 0.5, "upper": -0.5}, "joints.j.upper",
     "at least lower"),
    ({"type": "prismatic", "body_b": "b", "axis": [1.0, 0.0], "lower": 0.2, "upper": 0.1},
     "joints.j.upper", "at least lower"),
    ({"type": "prismatic", "body_b": "b", "axis": [0.0, 0.0]}, "joints.j.axis", "zero"),
    ({"type": "revolute", "body_a": "a", "point_a": [1.0, 0.0], "body_b": "b"},
     "joints.j.point_a", "from point_b"),
    ({"type": "gear", "joint_a": "pin", "joint_b": "missing", "ratio": 1.0},
     "joints.j.joint_b", "not a revolute joint"),
    ({"type": "gear", "joint_a": "pin", "joint_b": "slide", "ratio": 1.0},
     "joints.j.joint_b", "not a revolute joint"),
    ({"type": "gear", "joint_a": "pin", "joint_b": "pin2", "ratio": 0.0},
     "joints.j.ratio", "must not be zero"),
    ({"type": "hinge", "body_b": "b"}, "joints.j.type", "must be one of"),
    ({"type": "revolute", "body_b": "b", "motor": {"speed": 1.0}}, "joints.j.motor.max_torque",
     "required"),
]


@pytest.mark.parametrize("joint, parameter, problem", BAD_JOINTS)
def test_bad_joints_give_one_line_naming_the_file_and_parameter(tmp_path, joint, parameter,
                                                               problem):
    others = {"pin": {"type": "revolute", "body_b": "a"},
              "pin2": {"type": "revolute", "body_b": "b"},
              "slide": {"type": "prismatic", "body_b": "b", "axis": [1.0, 0.0]}}
    path = write_scene(tmp_path, {**BASE, "joints": {**others, "j": joint}})
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: parameter '{parameter}'")
    assert problem in message and "\n" not in message


def period_errors(methods=("velocity_verlet", "semi_implicit_euler", "rk4",
                           "implicit_midpoint"), steps=(0.004, 0.002, 0.001)) -> None:
    """Print the table of docs/scenes.md, `joints.<name>`: the pendulum's period error at 1 rad
    by method and step, and the ratios of successive errors (4 for order two)."""
    print("| method | " + " | ".join(f"h = {1e3 * h:g} ms" for h in steps) + " | ratios |")
    print("| --- " * (len(steps) + 2) + "|")
    for method in methods:
        errors = [measured_period(Simulation(pendulum_scene(1.0, h, method)), periods=2)
                  / exact_period(1.0) - 1.0 for h in steps]
        ratios = ", ".join(f"{a / b:.2f}" for a, b in zip(errors, errors[1:]))
        print(f"| `{method}` | " + " | ".join(f"{e:.2e}" for e in errors) + f" | {ratios} |")


if __name__ == "__main__":  # PYTHONPATH=test python test/contact/test_joints.py
    period_errors()


def test_the_shipped_gears_keep_their_ratio_then_jam_on_the_bar():
    """The shipped ``gears`` scene: while the bar is held (to 1.5 s) and falls (about 0.25 s
    more), the motor turns the train at its 2 rad/s and the angles keep the ratio to 1e-9
    rad. From 2 s to the end the bar sits wedged in the gap between the rims (its center
    below the small rim's top at y = 1.28, above the line of the centers, its sides either
    side of the gap at x = 0.28 to 0.32), and the motor gives its full 20 N m (to 1e-12)
    without reaching its speed: the train runs below a fifth of it (the joints' rows are
    solved with the contacts, so it stops: test/contact/test_coupled.py)."""
    scene = load_scene("gears")
    sim = Simulation(scene)
    for command in scene.script:
        sim.push(command)
    bar = sim.model.index["bar"]
    worst = 0.0
    while sim.time_ns < 1_750_000_000:
        sim.advance_to(sim.time_ns + 10_000_000)
        state = sim.model.joints.joint_state(sim.q, sim.v)
        worst = max(worst, abs(state["small_axle"][0] + 2.0 * state["big_axle"][0]))
        if sim.time_ns >= 200_000_000:
            assert state["small_axle"][1] == pytest.approx(-2.0, abs=1e-9)
    assert worst < 1e-9
    sim.advance_to(2_000_000_000)
    for _ in range(20):
        sim.advance_to(sim.time_ns + 100_000_000)
        state = sim.model.joints.joint_state(sim.q, sim.v)
        assert state["small_axle"][2] == pytest.approx(-20.0, rel=1e-12)
        assert abs(state["small_axle"][1]) < 0.2 * 2.0
        x, y = sim.q[bar, :2]
        assert 1.0 < y < 1.28 and x - 0.05 < 0.28 and x + 0.05 > 0.32


def _complementarity_error(pattern, diagonal, lower, b, bounds, x):
    """The largest violation of solve's conditions by x, in impulses (the residual over
    the row's diagonal): (K x - b)_i zero between the bounds, >= 0 at the lower, <= 0 at
    the upper."""
    from hecker_dynamics.contact.joint_solve import row_sum
    low_bound, high_bound = bounds
    worst = 0.0
    for i in range(len(b)):
        r = row_sum(pattern, diagonal, lower, i, x) - b[i]
        error = max(0.0, -r) if x[i] <= low_bound[i] else (
            max(0.0, r) if x[i] >= high_bound[i] else abs(r))
        worst = max(worst, error / diagonal[i])
    return worst


def test_the_ragdolls_limit_impulses_meet_their_conditions_to_rounding(monkeypatch):
    """The shipped ragdoll falls onto the floor with its joints at their limits: every
    velocity solve of its first half second gives impulses that meet the conditions of
    the bounded rows (equation between the bounds, the right sign of the residual at
    them) to 1e-14 of the largest impulse (measured: 1e-17). Projected Gauss-Seidel
    passes stopped at an impulse change of 1e-13 left 3.8e-13 here (7e-9 in the first
    second): their change per pass is not their error."""
    from hecker_dynamics.contact import joints
    solve, worst, bounded = joints.solve, [0.0], [0]

    def checked(pattern, diagonal, lower, b, bounds, warm):
        x = solve(pattern, diagonal, lower, b, bounds, warm)
        if any(lo > -math.inf or up < math.inf for lo, up in zip(*bounds)):
            bounded[0] += 1
            error = _complementarity_error(pattern, diagonal, lower, b, bounds, x)
            worst[0] = max(worst[0], error / (1.0 + max(map(abs, x))))
        return x

    monkeypatch.setattr(joints, "solve", checked)
    sim = Simulation(load_scene("ragdoll"))
    sim.model.use_python()
    sim.advance_to(500_000_000, keep=False)
    assert bounded[0] == sim.steps
    assert worst[0] < 1e-14


def _refusal(path, problem):
    """The scene at ``path`` loaded when ``problem`` is None (None returned), else its
    refusal's message."""
    if problem is None:
        load_scene(path)
        return None
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    return str(caught.value)


PAIR = {"bodies": {"a": {"shape": "box", "size": [1.0, 0.1], "mass": 1.0},
                   "b": {"shape": "box", "size": [1.0, 0.1], "mass": 1.0,
                         "position": [1.0, 0.0]}}}
PAIR_PIN = {"type": "revolute", "body_a": "a", "body_b": "b", "point_b": [-0.5, 0.0]}
PAIR_ROD = {"type": "distance", "body_a": "a", "body_b": "b"}  # origin to origin, 1 m at start


@pytest.mark.parametrize("others, length, problem", [
    ({"pin": PAIR_PIN}, 2.0, "pin 'pin' joins its bodies, so the rod's points stay 0 to 1 m apart"),
    ({"pin": PAIR_PIN}, 0.8, None),
    ({"w": {**PAIR_PIN, "type": "weld"}}, 1.5,
     "'w' holds its bodies rigidly beside it, so the rod's points stay 1 m apart"),
    ({"w": {**PAIR_PIN, "type": "weld", "frequency": 5.0}}, 1.5, None),  # a spring, not rigid
    ({"pin": PAIR_PIN, "pin2": {**PAIR_PIN, "point_b": [0.0, 0.0]}}, 1.5,
     "'pin2' holds its bodies rigidly beside it, so the rod's points stay 1 m apart"),
    ({"pin": PAIR_PIN, "pin2": {**PAIR_PIN, "point_b": [0.0, 0.0]}}, 1.0, None),
    ({"pin": PAIR_PIN, "s": {"type": "prismatic", "body_a": "a", "body_b": "b",
                        "axis": [1.0, 0.0]}}, 1.2, "'s' holds its bodies rigidly"),
    ({"pin": {**PAIR_PIN, "body_a": "b", "body_b": "a", "point_b": [0.5, 0.0]}}, 2.5,
     "stay 0 to 1 m apart"),
])
def test_a_rod_the_other_joints_of_its_pair_never_let_reach_is_refused(tmp_path, others,
                                                                       length, problem):
    """A rod beside a pin of the same two bodies can only span |d_a - d_b| to d_a + d_b
    (its points' distances from the pin), beside a weld (or two pins at different points,
    or a pin and a slider: each holds as a weld) only the gap it starts with. A rod out of
    that reach was loaded and tore the pin open; a soft weld is a spring, so anything
    goes beside it. Pins and welds of one pair need no such check: their points coincide
    at the start, so every set of them holds there."""
    path = write_scene(tmp_path, {**PAIR, "joints": {**others, "rod": {**PAIR_ROD,
                                                                       "length": length}}})
    message = _refusal(path, problem)
    assert message is None or message.startswith(
        f"{path}: parameter 'joints.rod.length': {length:g} m is out of reach: ") \
        and problem in message and "\n" not in message


def _box(x: float, y: float) -> dict:
    return {"shape": "box", "size": [0.2, 0.1], "mass": 1.0, "position": [x, y]}


#: A four-bar linkage: cranks pinned to the world at (0, 0) and (2, 0), their tops pinned
#: to the ends of a 2 m coupler; and a ring of six boxes pinned at their sides' midpoints.
FOUR_BAR = {"bodies": {"crank": _box(0.0, 0.5), "coupler": _box(1.0, 1.0),
                       "rocker": _box(2.0, 0.5)},
            "joints": {"g1": {"type": "revolute", "body_b": "crank", "point_b": [0.0, -0.5]},
                       "p1": {"type": "revolute", "body_a": "crank", "point_a": [0.0, 0.5],
                              "body_b": "coupler", "point_b": [-1.0, 0.0]},
                       "p2": {"type": "revolute", "body_a": "coupler", "point_a": [1.0, 0.0],
                              "body_b": "rocker", "point_b": [0.0, 0.5]},
                       "g2": {"type": "revolute", "body_b": "rocker", "point_b": [0.0, -0.5]}}}
TOPS = {"type": "distance", "body_a": "crank", "point_a": [0.0, 0.5], "body_b": "rocker",
        "point_b": [0.0, 0.5]}
RING = [(math.cos(i * math.pi / 3), math.sin(i * math.pi / 3)) for i in range(6)]
PIN_RING = {"bodies": {f"r{i}": _box(*RING[i]) for i in range(6)},
            "joints": {f"p{i}": {"type": "revolute", "body_a": f"r{i}", "body_b":
                                 f"r{(i + 1) % 6}",
                                 "point_a": [(RING[(i + 1) % 6][0] - RING[i][0]) / 2,
                                             (RING[(i + 1) % 6][1] - RING[i][1]) / 2],
                                 "point_b": [(RING[i][0] - RING[(i + 1) % 6][0]) / 2,
                                             (RING[i][1] - RING[(i + 1) % 6][1]) / 2]}
                       for i in range(6)}}
TRIANGLE = {"bodies": {"a": _box(0.0, 0.0), "b": _box(1.0, 0.0), "c": _box(0.5, 0.8)}}


@pytest.mark.parametrize("scene, rod, length, problem", [
    (FOUR_BAR, TOPS, 5.0, "the loop through 'p1', 'p2' holds the rod's points 2 m apart"),
    (FOUR_BAR, TOPS, 1.5, "the loop through 'p1', 'p2' holds the rod's points 2 m apart"),
    (FOUR_BAR, TOPS, 2.0, None),
    ({**FOUR_BAR, "joints": {k: v for k, v in FOUR_BAR["joints"].items() if k in ("g1", "g2")}},
     TOPS, 10.0, "the loop through 'g1', 'g2' holds the rod's points 0 to 4 m apart"),
    ({**FOUR_BAR, "joints": {k: v for k, v in FOUR_BAR["joints"].items() if k in ("g1", "g2")}},
     TOPS, 3.5, None),
    (PIN_RING, {"type": "distance", "body_a": "r0", "body_b": "r3"}, 5.0,
     "the loop through 'p0', 'p1', 'p2' holds the rod's points 0 to 2.73205 m apart"),
    (PIN_RING, {"type": "distance", "body_a": "r0", "body_b": "r3"}, 1.0, None),
    ({**TRIANGLE, "joints": {"x": {"type": "distance", "body_a": "b", "body_b": "c",
                                   "length": 1.0},
                             "z": {"type": "distance", "body_a": "c", "body_b": "a",
                                   "length": 1.0}}},
     {"type": "distance", "body_a": "a", "body_b": "b"}, 5.0,
     "the loop through 'z', 'x' holds the rod's points 0 to 2 m apart"),
    ({**TRIANGLE, "joints": {"x": {"type": "distance", "body_a": "b", "body_b": "c",
                                   "max_length": 1.0},
                             "z": {"type": "distance", "body_a": "c", "body_b": "a",
                                   "length": 1.0}}},
     {"type": "distance", "body_a": "a", "body_b": "b"}, 5.0, None),  # a rope gives no bound
])
def test_a_rod_a_loop_of_joints_never_lets_reach_is_refused(tmp_path, scene, rod, length,
                                                             problem):
    """A rod closing a loop of pins, welds and rods (a four-bar's coupler, a rod across a
    ring of six pinned links, a triangle of rods 1, 1 and 5 m) must lie within the reach of
    the loop's other path: loaded, the joint pass tore the loop's pins open by up to 5 m
    in 3 s, and the run ended without a word."""
    path = write_scene(tmp_path, {**scene, "joints": {**scene["joints"],
                                                      "rod": {**rod, "length": length}}})
    message = _refusal(path, problem)
    assert message is None or message == (
        f"{path}: parameter 'joints.rod.length': {length:g} m is out of reach: {problem}"), message


@pytest.mark.parametrize("switch", ["1", "0"], ids=["kernel", "python"])
def test_a_gear_of_ratio_1e12_is_told_to_turn_round_and_runs_so(monkeypatch, switch):
    """A gear's row is angle_a + ratio angle_b: at a ratio of 1e12 the joints have no
    solution within rounding, and the advice once spoke of masses (these are 2 and 8 kg).
    It names the gear and the same gear written the other way round, ratio 1e-12, which
    runs: the motor turns wheel a at 2 rad/s and wheel b 1e12 times slower."""
    if switch == "1" and not kernel.built():
        pytest.skip("the compiled kernel is not built")
    monkeypatch.setenv(kernel.SWITCH, switch)

    def scene(gear: dict):
        return make_scene({
            "step": 0.001, "integrator": "semi_implicit_euler",
            "bodies": {"a": {"shape": "circle", "radius": 0.3, "mass": 2.0},
                       "b": {"shape": "circle", "radius": 0.6, "mass": 8.0,
                             "position": [1.0, 0.0]}},
            "joints": {"axle_a": {"type": "revolute", "body_b": "a",
                                  "motor": {"speed": -2.0, "max_torque": 20.0}},
                       "axle_b": {"type": "revolute", "body_b": "b", "point_b": [1.0, 0.0]},
                       "mesh": dict(gear, type="gear")}})

    with pytest.raises(DivergenceError) as caught:
        Simulation(scene({"joint_a": "axle_a", "joint_b": "axle_b", "ratio": 1e12})
                   ).advance_to(10_000_000)
    message = str(caught.value)
    assert "mass" not in message
    assert ("or gear 'mesh' ties its joints at a ratio of 1e+12, which its row's rounding "
            "grows with; write it the other way round, the same gear (joint_a: axle_b, "
            "joint_b: axle_a, ratio: 1e-12), or take a shorter step") in message
    sim = Simulation(scene({"joint_a": "axle_b", "joint_b": "axle_a", "ratio": 1e-12}))
    sim.advance_to(1_000_000_000)
    assert sim.v[0, 2] == pytest.approx(-2.0, rel=1e-9)
    assert sim.v[1, 2] == pytest.approx(2e-12, rel=1e-9)
