"""Soft joints (``joint_solver.type: soft``, hecker_dynamics.contact.soft_joints): Box2D v3's
sub-stepped soft solve, against the kernel's bits, itself, a pendulum's period, the
benchmark chains' energy and Box2D v3's measured pin gaps, and the scenes it refuses.

References: the kernel repeats the pass operation for operation (the same bits); gravity is
conservative and the soft rows only take energy out over a step (the relaxing sweep ends
each sub-step at the rigid rows' velocities), so a chain's energy never rises by more than
the sub-steps' first-order error; a small swing's period is 2 pi sqrt(I_pivot / (m g d))
to first order in the step; the chains' pins open by about as much as Box2D v3's do on
the same chains, the same solver in floats (docs/bench/joints.md: 0.0037, 0.015, 0.047
and 0.28 m at 2, 10, 50 and 200 links at h = 1/60 s; 0.0014, 0.0043, 0.038, 0.075 m at
1/240 s, each the largest of 10 samples of a chaotic motion, so a factor of two).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from scene_builders import make_scene, write_scene
from test_joints import I_PIVOT, ROD, pendulum_scene
from test_joints_compiled import SCENES

from hecker_dynamics.bench.joints import chain, pin_gap
from hecker_dynamics.cli import main
from hecker_dynamics.contact.joint_solve import directions, dot, rate
from hecker_dynamics.contact.soft_joints import SOFT_MASS_RATIO, _pin_block
from hecker_dynamics.contact.solver import MassRatioWarning
from hecker_dynamics.dynamics import Simulation, kernel
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.scene import SceneError
from hecker_dynamics.scene.joints import SoftJoints

needs_kernel = pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not "
                                  "built or HECKER_DYNAMICS_KERNEL=0")
SECOND = 1_000_000_000
#: Box2D v3's largest pin gaps on the benchmark chains (docs/bench/joints.md), m, by
#: (links, steps per second).
BOX2D_V3_GAPS = {(2, 60): 0.0037, (10, 60): 0.015, (50, 60): 0.047, (200, 60): 0.28,
                 (2, 240): 0.0014, (10, 240): 0.0043, (50, 240): 0.038, (200, 240): 0.075}


def soft(scene, **settings):
    """``scene`` with soft joints (``settings``: SoftJoints' fields) stepped as they step."""
    return replace(scene, integrator="semi_implicit_euler", soft_joints=SoftJoints(**settings))


def _same(a: Simulation, b: Simulation) -> None:
    assert a.steps == b.steps
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)
    assert a.model.joints.export_state() == b.model.joints.export_state()


@needs_kernel
@pytest.mark.parametrize("name", sorted(SCENES))
def test_kernel_steps_soft_joints_with_the_bits_of_python(name):
    """0.3 s of each joint scene (pins, a chain, gears with a motor and limits, a slider
    with limits and a motor, welds, a spring, a soft weld, a rope and a rod) with soft
    joints: whole steps in the kernel and steps in Python give the same bits."""
    scene = soft(SCENES[name]("semi_implicit_euler"))
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast._compiled is not None and fast.model.joints.compiled
    fast.advance_to(300_000_000)
    slow.advance_to(300_000_000)
    _same(fast, slow)
    assert any(x != 0.0 for x in fast.model.joints.warm)


@needs_kernel
def test_the_kernels_soft_pass_after_a_python_step_has_the_bits_of_python():
    """The kernel's soft sub-step called from a step taken in Python (the binding's
    joints_resolve) gives Python's bits, its rows rebuilt where Python reuses them."""
    scene = soft(SCENES["gears"]("semi_implicit_euler"), substeps=3)
    fast, slow = Simulation(scene), Simulation(scene)
    fast._compiled = None  # steps in Python, the joint pass in the kernel
    slow.model.use_python()
    fast.advance_to(200_000_000)
    slow.advance_to(200_000_000)
    _same(fast, slow)


@needs_kernel
def test_python_and_the_kernel_take_turns_with_the_bits_of_python():
    """Steps in Python, then whole steps in the kernel, then Python again, give the bits of
    Python alone: the pass's state (impulses, counted angles, sub-step) goes across, and
    no rows kept from before the kernel's steps are used after them."""
    scene = soft(SCENES["slider"]("semi_implicit_euler"))
    mixed, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    steps, joints = mixed._compiled, mixed.model.joints
    mixed._compiled, joints._compiled = None, False  # Python first
    mixed.advance_to(100_000_000)
    mixed._compiled, joints._compiled = steps, True  # then the kernel
    mixed.advance_to(200_000_000)
    mixed.model.use_python()
    mixed.advance_to(300_000_000)
    slow.advance_to(300_000_000)
    _same(mixed, slow)


@pytest.mark.parametrize("python", [False, True])
def test_two_runs_give_the_same_bits(python):
    scene = soft(chain(20, 1.0 / 60.0, 1.0))
    runs = [Simulation(scene) for _ in range(2)]
    for sim in runs:
        if python:
            sim.model.use_python()
        sim.advance_to(SECOND)
    _same(*runs)


def test_a_small_swing_has_the_pendulum_s_period():
    """A rod pinned at its end swinging 0.05 rad: its period within 0.1 % of
    2 pi sqrt(I_pivot / (m g d)) at h = 1/60 s in 4 sub-steps (measured: 0.015 % long;
    first order, and the soft pin gives a little)."""
    amplitude, h = 0.05, 1.0 / 60.0
    sim = Simulation(soft(replace(pendulum_scene(amplitude), step_ns=round(h * 1e9),
                                  publish_period_ns=round(h * 1e9))))
    crossings, before = [], float(sim.q[0, 2])
    while len(crossings) < 6:
        sim.step()
        after = float(sim.q[0, 2])
        if before > 0.0 >= after:
            crossings.append(sim.time_ns * 1e-9 - h * after / (after - before))
        before = after
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    exact = 2.0 * math.pi * math.sqrt(I_PIVOT / (ROD["mass"] * 9.81 * 0.5))
    assert period == pytest.approx(exact, rel=1e-3)


@needs_kernel
@pytest.mark.parametrize("links", [2, 10, 50, 200])
@pytest.mark.parametrize("per_second", [60, 240])
def test_soft_chains_run_their_10_s_within_box2d_v3_s_gaps(links, per_second):
    """The benchmark's chains over 10 s, sampled every 0.1 s: they run, the energy never
    rises above its start by more than 1 % of m g L N^2 / 2 (the energy the chain gives up
    hanging down), and the pins open by at most twice Box2D v3's largest gap there."""
    scene = soft(chain(links, 1.0 / per_second, 10.0))
    sim, model = Simulation(scene), Model(scene)
    scale = 9.81 * 0.5 * links * links / 2.0
    start = model.energy(sim.q, sim.v)
    worst, highest = 0.0, start
    for k in range(1, 101):
        sim.advance_to(k * SECOND // 10, keep=False)
        worst = max(worst, pin_gap(scene, model, sim.q))
        highest = max(highest, model.energy(sim.q, sim.v))
    assert highest - start <= 0.01 * scale
    assert 0.0 < worst <= 2.0 * BOX2D_V3_GAPS[links, per_second]


@pytest.mark.parametrize("name", ["chain", "weld", "pendulum", "gears"])
def test_a_pins_block_is_its_rows_k_and_velocity_error(name):
    """A pin's 2 x 2 block read off its arms (``_pin_block``, Box2D v3's way) is, bit for
    bit, J M^-1 J^T and J v of its two rows as the rows' directions give them (the
    entries it leaves out are zeros), at random poses and velocities."""
    sim = Simulation(soft(SCENES[name]("semi_implicit_euler")))
    joints = sim.model.joints
    joints.reset(sim.q)
    generator = np.random.default_rng(33)
    blocks = 0
    for _ in range(20):
        q = (sim.q[joints.bodies] + generator.normal(size=(len(joints.bodies), 3))).reshape(-1)
        v = generator.normal(size=q.size).tolist()
        rows = joints.rows(q.tolist(), 0.01)
        towards = directions(rows, joints.inverse_mass)
        for i in (i for i, pair in enumerate(joints.pairs) if pair):
            x, y = rows[i], rows[i + 1]
            assert _pin_block(x, y, v, joints.inverse_mass) == (
                rate(x, v), rate(y, v), dot(x, towards[i]), dot(x, towards[i + 1]),
                dot(y, towards[i + 1]))
            blocks += 1
    assert blocks >= 20


def _with_light_link(scene, ratio: float):
    """``scene`` (a chain of 1 kg links) with its middle link ``ratio`` times lighter."""
    bodies = list(scene.bodies)
    middle = len(bodies) // 2
    mass = bodies[middle].mass
    bodies[middle] = replace(bodies[middle], mass=replace(
        mass, mass=mass.mass / ratio, moment_of_inertia=mass.moment_of_inertia / ratio))
    return replace(scene, bodies=tuple(bodies))


def test_a_soft_joint_between_masses_far_apart_is_warned_of_and_does_open():
    """One sweep of impulses a sub-step holds a pin between a heavy and a light body
    badly: a 20-link chain at h = 1/60 s with its middle link 100 times lighter opens by
    metres within 5 s (measured 3 m; 0.05 m at 10 times). Such a scene is warned of by the
    joint and both masses; the chain with equal links and one at the bound are not."""
    scene = soft(chain(20, 1.0 / 60.0, 5.0))
    scene = replace(scene, publish_period_ns=round(0.1 / (scene.step_ns * 1e-9)) * scene.step_ns)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Simulation(scene)
        Simulation(_with_light_link(scene, SOFT_MASS_RATIO))
    light = _with_light_link(scene, 100.0)
    with pytest.warns(MassRatioWarning, match=r"joint 'pin00(09|10)': 'link00(09|11)' \(1 kg\) "
                      r"is 100 times as heavy as 'link0010' \(0.01 kg\)"):
        sim, model = Simulation(light), Model(light)
    gaps = [pin_gap(light, model, snapshot._state()[0])
            for snapshot in sim.advance_to(5 * SECOND)]
    assert max(gaps) > 0.5


@pytest.mark.parametrize("change, problem", [
    ({"integrator": "velocity_verlet"}, "set integrator to semi_implicit_euler, not "
                                        "'velocity_verlet'"),
    ({"integrator": None}, "not 'auto'"),
    ({"walls": {"floor": {"point": [0.0, -5.0], "normal": [0.0, 1.0]}}},
     "this scene has walls: use joint_solver.type exact"),
    ({"joint_solver": {"type": "soft", "substeps": 0}}, "must be an integer from 1 to 64"),
    ({"joint_solver": {"type": "soft", "substeps": 2.0}}, "must be an integer from 1 to 64"),
    ({"joint_solver": {"type": "soft", "hertz": 0.0}}, "hertz"),
    ({"joint_solver": {"type": "soft", "damping_ratio": -1.0}}, "damping_ratio"),
    # The spring's implicit terms overflow: NaN impulses at the first sub-step.
    ({"joint_solver": {"type": "soft", "hertz": 1e308}},
     "'joint_solver.hertz': hertz 1e.308 with damping_ratio 2 over sub-steps of 0.0025 s "
     "is a spring too stiff for a double"),
    ({"joint_solver": {"type": "soft", "damping_ratio": 1e308}},
     "'joint_solver.damping_ratio': hertz 60 with damping_ratio 1e.308"),
    ({"joint_solver": {"type": "exact", "substeps": 4}},
     "'joint_solver.substeps': is a setting of joint_solver.type soft, not exact"),
    ({"joint_solver": {"type": "stiff"}}, "joint_solver.type"),
    ({"joint_solver": {"type": "soft", "pin_gap": 1e-9}},
     "'joint_solver.pin_gap': is a setting of joint_solver.type exact, not soft"),
])
def test_soft_joints_refuse_what_they_cannot_solve(change, problem):
    params = {"step": 0.01, "integrator": "semi_implicit_euler",
              "bodies": {"rod": {"shape": "box", "size": [1.0, 0.1], "mass": 1.0}},
              "joints": {"pin": {"type": "revolute", "body_b": "rod", "point_b": [-0.5, 0.0]}},
              "joint_solver": {"type": "soft"}}
    params.update(change)
    params = {key: value for key, value in params.items() if value is not None}
    with pytest.raises(SceneError, match=problem.replace("(", r"\(")) as error:
        make_scene(params)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("change, problem", [
    ({"integrator": "rk4"}, "set integrator to semi_implicit_euler, not 'rk4'"),
    ({"walls": (None,)}, "this scene has walls"),
])
@pytest.mark.parametrize("joints", [True, False], ids=["pendulum", "no joints"])
def test_a_scene_changed_after_loading_is_refused_too(change, problem, joints):
    """What a command line may change after loading (``--integrator``, ``--map``) is
    refused when the simulation is made, with the loader's message, whether the scene has
    joints or not (without joints it ran: no soft pass was made to refuse it)."""
    scene = soft(SCENES["pendulum"]("semi_implicit_euler"))
    if not joints:
        scene = replace(scene, joints=())
    with pytest.raises(SceneError, match=f"parameter 'joint_solver.type': .*{problem}"):
        Simulation(replace(scene, **change))


def test_the_command_line_refuses_soft_joints_as_the_file_does(tmp_path, capsys):
    """``run --integrator rk4`` on a file with soft joints and no joints was accepted,
    where the same integrator in the file is refused: the same line now, status 2."""
    params = {"step": 0.01, "integrator": "semi_implicit_euler", "duration": 0.1,
              "joint_solver": {"type": "soft"},
              "bodies": {"ball": {"shape": "circle", "radius": 0.1, "mass": 1.0}}}
    rk4_file = write_scene(tmp_path, {**params, "integrator": "rk4"}, "soft.yaml")
    assert main(["run", str(rk4_file)]) == 2
    from_file = capsys.readouterr().err
    soft_file = write_scene(tmp_path, params, "soft.yaml")
    assert main(["run", str(soft_file), "--integrator", "rk4"]) == 2
    assert capsys.readouterr().err == from_file
    assert "parameter 'joint_solver.type': soft joints take" in from_file


def test_the_default_is_the_exact_pass_and_soft_takes_its_defaults():
    params = {"step": 0.01, "integrator": "semi_implicit_euler",
              "bodies": {"rod": {"shape": "box", "size": [1.0, 0.1], "mass": 1.0}},
              "joints": {"pin": {"type": "revolute", "body_b": "rod", "point_b": [-0.5, 0.0]}}}
    assert make_scene(params).soft_joints is None
    scene = make_scene({**params, "joint_solver": {"type": "soft"}})
    assert scene.soft_joints == SoftJoints(4, 60.0, 2.0)
    assert Simulation(scene).model.joints.substeps == 4
