"""Joints solved with the contacts (hecker_dynamics.contact.coupled): contact impulses
travel through pins and gears, in Python and in the kernel with the same bits."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.dynamics import Simulation, kernel
from hecker_dynamics.scene import load_scene

G = 9.81
#: The seesaw's lever (2 m x 0.1 m, pinned at its center to the world at (0, 1)) and the
#: two boxes on it, (mass, x) with m_1 x_1 + m_2 x_2 = 0, so the lever is balanced.
LEVER_MASS = 1.5
BOXES = ((1.0, -0.6), (2.0, 0.3))


def seesaw_scene():
    """The balanced seesaw: boxes of 0.2 m resting on the lever's top face (y = 1.05)."""
    bodies = {"lever": {"shape": "box", "size": [2.0, 0.1], "mass": LEVER_MASS,
                        "position": [0.0, 1.0]}}
    for k, (mass, x) in enumerate(BOXES):
        bodies[f"box{k}"] = {"shape": "box", "size": [0.2, 0.2], "mass": mass,
                             "position": [x, 1.15]}
    return make_scene({
        "step": 0.001, "integrator": "semi_implicit_euler", "publish_rate": 10.0,
        "bodies": bodies, "forces": {"gravity": {"type": "gravity"}},
        "joints": {"pin": {"type": "revolute", "body_b": "lever"}},
        "collisions": {"stack": {"bodies": list(bodies), "restitution": 0.0,
                                 "friction": 0.5}}})


def test_a_balanced_seesaw_rests_and_its_pin_carries_the_whole_weight():
    """Static equilibrium: the boxes rest on the lever and the lever does not turn (the
    torques of the boxes' weights about the pin cancel, m_1 x_1 + m_2 x_2 = 0; the
    balance is unstable, the CM above the pin, so rounding grows: 1e-7 rad and rad/s after
    2 s, measured 6e-10 and 1.3e-9, the boxes within 1e-7 m and m/s), and the
    pin's reaction over the step is the total weight to 1e-6 relative: the lever's own
    weight held by the joint pass's position stage (its multiplier nu moves q by
    M^-1 G^T nu and v by that over h: an impulse nu / h), the boxes' weight by the pin's
    velocity row in the contact solve (the joint pass's impulse plus the extra)."""
    sim = Simulation(seesaw_scene())
    sim.advance_to(2_000_000_000)
    joints = sim.model.joints
    h = joints.step_h
    impulse = list(joints.warm)
    for nu, row in zip(joints.newton, joints.rigid):
        impulse[row] += nu / h
    reaction = dict(zip(joints.keys, impulse))
    weight = (LEVER_MASS + sum(mass for mass, _ in BOXES)) * G
    assert reaction[("pin", "y")] / h == pytest.approx(weight, rel=1e-6)
    assert abs(reaction[("pin", "x")]) / h <= 1e-6 * weight
    lever = sim.model.index["lever"]
    assert abs(sim.q[lever, 2]) < 1e-7 and abs(sim.v[lever, 2]) < 1e-7
    for k, (_, x) in enumerate(BOXES):
        box = sim.model.index[f"box{k}"]
        assert sim.q[box, 0] == pytest.approx(x, abs=1e-7)
        assert np.abs(sim.v[box]).max() < 1e-7


def pendulum_wall_scene(restitution: float):
    """A rod (1 m x 0.05 m, 2 kg) hanging from the world at its top end (0, 0), turning at
    2 rad/s about it (its CM at 1 m/s) without gravity toward a frictionless wall at
    x = 0.3."""
    return make_scene({
        "step": 0.001, "integrator": "semi_implicit_euler", "publish_rate": 10.0,
        "bodies": {"rod": {"shape": "box", "size": [0.05, 1.0], "mass": 2.0,
                           "position": [0.0, -0.5], "velocity": [1.0, 0.0],
                           "angular_velocity": 2.0,
                           "points": {"top": [0.0, 0.5]}}},
        "joints": {"pin": {"type": "revolute", "body_b": "rod", "point_b": "top"}},
        "walls": {"wall": {"point": [0.3, 0.0], "normal": [-1.0, 0.0],
                           "restitution": restitution, "friction": 0.0}}})


@pytest.mark.parametrize("restitution", [0.0, 0.5, 1.0])
def test_a_pendulum_bounces_off_a_wall_about_its_pivot(restitution):
    """The rod's corner hits the wall; the contact and the pin solved together give the
    impulse about the pivot, so the angular velocity after is -e times the 2 rad/s before
    (the bounce reverses the normal velocity at the contact point, omega times its arm
    from the pivot; with e = 0 the rod stops against the wall, to 1e-9 rad/s). The contact
    model takes the approach speed from the step's start and the arms at its end, which
    the rod reaches turned by h omega = 2 mrad: to first order in that angle, so within
    2e-3 relative (measured: 3e-4 at e = 0.5, 4e-5 at e = 1). The pivot stays put
    (1e-9 m)."""
    sim = Simulation(pendulum_wall_scene(restitution))
    sim.advance_to(1_000_000_000)
    rod = sim.model.index["rod"]
    assert sim.v[rod, 2] == pytest.approx(-2.0 * restitution, rel=2e-3, abs=1e-9)
    top = sim.q[rod, :2] + 0.5 * np.array([-math.sin(sim.q[rod, 2]), math.cos(sim.q[rod, 2])])
    assert np.hypot(*top) < 1e-9


def test_the_gears_jam_and_the_motor_gives_its_maximum():
    """The shipped gears jammed by the bar: from 2 s to the end the train does not turn
    (every 10 ms sample below 1e-9 rad/s: the contact solve converges to rounding, with
    the motor's row at its bound; the angle within 1e-9 rad) and the motor's effort is its
    maximum, 20 N m, to rounding (before the joints were in the contact solve the train
    crept on at 0.22 to 0.28 rad/s)."""
    scene = load_scene("gears")
    sim = Simulation(scene)
    for command in scene.script:
        sim.push(command)
    sim.advance_to(2_000_000_000)
    start = sim.model.joints.joint_state(sim.q, sim.v)["small_axle"][0]
    while sim.time_ns < scene.duration_ns:
        sim.advance_to(sim.time_ns + 10_000_000)
        angle, speed, effort = sim.model.joints.joint_state(sim.q, sim.v)["small_axle"]
        assert abs(speed) < 1e-9 and abs(angle - start) < 1e-9
        assert effort == pytest.approx(-20.0, rel=1e-12)


def _run_gears(python: bool, method: str, until_ns: int) -> Simulation:
    scene = load_scene("gears")
    scene = type(scene)(**{**scene.__dict__, "integrator": method})
    sim = Simulation(scene)
    if python:
        sim.model.use_python()
    for command in scene.script:
        sim.push(command)
    sim.advance_to(until_ns)
    return sim


@pytest.mark.parametrize("method,until_ns", [("semi_implicit_euler", 3_000_000_000),
                                             ("implicit_midpoint", 2_000_000_000)])
def test_the_kernel_jams_the_gears_with_the_bits_of_python(method, until_ns):
    """Through the jam, whole steps in the kernel (semi-implicit Euler) or Python steps
    with the kernel's passes (implicit midpoint) give the bits of Python's passes: the
    state, the joints' impulses and the contact solve's extras."""
    if not kernel.enabled():
        pytest.skip("the compiled kernel is not built or HECKER_DYNAMICS_KERNEL=0")
    fast, slow = _run_gears(False, method, until_ns), _run_gears(True, method, until_ns)
    assert fast.model.joints.compiled and not slow.model.joints.compiled
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    assert fast.model.joints.warm == slow.model.joints.warm
    assert fast.model.joints.extra == slow.model.joints.extra
    assert any(x != 0.0 for x in fast.model.joints.extra)
    assert fast.model.contacts.export_state() == slow.model.contacts.export_state()
