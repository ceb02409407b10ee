"""Sleeping of resting islands (the scene's ``contacts.sleep``).

A stack of three boxes starts resting on a floor; with sleeping on it falls asleep once
every box has rested TIME_TO_SLEEP, and from then on its state repeats bit for bit from
step to step (held, not integrated: gravity would otherwise pull it through the floor).
What wakes it: a falling box landing on it, an input held on one of its boxes, a state
set from outside. Sleeping off, or before anything sleeps, the bits are those of a scene
without sleeping. Each test runs in the kernel and in Python.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics import Simulation
from hecker_dynamics.bench.pyramid import pyramid
from hecker_dynamics.contact import solver
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.scene.commands import WrenchCommand
from hecker_dynamics.scene.load import SceneError

H = 0.004
STEP_NS = 4_000_000
BOXES = ["box0", "box1", "box2"]

paths = pytest.mark.parametrize("compiled", [
    False, pytest.param(True, marks=pytest.mark.skipif(
        not kernel.enabled(), reason="the compiled kernel is not built or "
        "HECKER_DYNAMICS_KERNEL=0"))])


def _stack(sleep: object = True, dropper: bool = False, extra: dict | None = None):
    """Three 0.5 m boxes stacked on the floor, touching; ``dropper``: a fourth box 6 m up
    above them, which lands on the stack after about 1 s."""
    bodies = {name: {"shape": "box", "size": [0.5, 0.5], "mass": 1.0,
                     "position": [0.0, 0.25 + 0.5 * k]} for k, name in enumerate(BOXES)}
    if dropper:
        bodies["drop"] = {"shape": "box", "size": [0.5, 0.5], "mass": 1.0,
                          "position": [0.1, 6.0]}
    params = {"step": H, "integrator": "semi_implicit_euler", "bodies": bodies,
              "forces": {"g": {"type": "gravity"}, **(extra or {})},
              "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                                  "restitution": 0.0, "friction": 0.6}},
              "collisions": {"all": {"bodies": list(bodies), "restitution": 0.0,
                                     "friction": 0.6}},
              "contacts": {"sleep": sleep}}
    return make_scene(params)


def _simulation(scene, compiled: bool) -> Simulation:
    sim = Simulation(scene)
    if not compiled:
        sim.model.use_python()
    assert sim.model.contacts.compiled == compiled
    return sim


def _until_asleep(sim: Simulation, bodies: list[int], limit_s: float = 3.0) -> float:
    """Step until ``bodies`` all sleep; the time then."""
    for _ in range(round(limit_s / H)):
        sim.step()
        if set(bodies) <= set(sim.model.contacts.sleeping()):
            return sim.time_ns * 1e-9
    raise AssertionError(f"bodies {bodies} not asleep after {limit_s} s")


@paths
def test_resting_stack_sleeps_after_the_time_to_sleep_and_then_holds_its_bits(compiled):
    """The stack rests from the start, so it sleeps at TIME_TO_SLEEP (within a step of
    rounding the rest times up), not earlier; asleep, its velocities are zero and 200
    further steps (0.8 s, which would drop a free box 3 m) change no bit."""
    sim = _simulation(_stack(), compiled)
    contacts = sim.model.contacts
    before = None
    while not contacts.sleeping():
        state = contacts.export_state()
        before = state["rested"]
        sim.step()
        assert sim.time_ns * 1e-9 < 2.0, "the stack never fell asleep"
    asleep_at = sim.time_ns * 1e-9
    assert solver.TIME_TO_SLEEP <= asleep_at <= solver.TIME_TO_SLEEP + 2 * H
    assert min(before) < solver.TIME_TO_SLEEP  # one step earlier it was still resting
    assert contacts.sleeping() == [0, 1, 2]
    assert not sim.v.any()
    q, v = sim.q.copy(), sim.v.copy()
    for _ in range(200):
        sim.step()
        assert np.array_equal(sim.q, q) and np.array_equal(sim.v, v)
    assert contacts.sleeping() == [0, 1, 2]


@paths
def test_a_box_landing_on_a_sleeping_stack_wakes_it(compiled):
    """The stack sleeps while the fourth box falls (a separate island, moving); the box
    lands at about 0.96 s and the stack wakes: its top box is pushed from where it slept.
    Then the four rest together and sleep as one island."""
    sim = _simulation(_stack(dropper=True), compiled)
    asleep_at = _until_asleep(sim, [0, 1, 2])
    assert asleep_at < 0.9 and 3 not in sim.model.contacts.sleeping()
    slept = sim.q[2].copy()
    sim.advance_to(1_100_000_000)
    assert not set(sim.model.contacts.sleeping()) & {0, 1, 2}
    assert not np.array_equal(sim.q[2], slept)
    _until_asleep(sim, [0, 1, 2, 3], limit_s=4.0)
    assert np.all(sim.q[:3, 1] > 0.0)  # none fell through the floor


@paths
def test_an_input_wakes_a_body_and_keeps_it_awake(compiled):
    """A sideways push on the sleeping top box wakes the stack and slides the box; while
    held (0.6 s), its island stays awake, though the box stops after 0.2 s; after it
    ends the stack sleeps again."""
    sim = _simulation(_stack(), compiled)
    _until_asleep(sim, [0, 1, 2])
    slept = sim.q[2].copy()
    start = sim.time_ns
    sim.push(WrenchCommand(start, "box2", "test", "box2", (0.0, 0.0), (7.0, 0.0),
                           duration_ns=200_000_000))
    sim.push(WrenchCommand(start, "box2", "hold", "box2", (0.0, 0.0), (0.0, 0.0),
                           duration_ns=600_000_000))
    for _ in range(round(0.6 / H) - 1):
        sim.step()
        assert 2 not in sim.model.contacts.sleeping()
    assert abs(sim.v[2]).max() == 0.0 or np.hypot(*sim.v[2][:2]) < 1e-3  # it stopped
    assert sim.q[2][0] > slept[0] + 0.01  # 7 N against 0.6 x 9.81 N of friction: slides
    assert _until_asleep(sim, [0, 1, 2]) >= start * 1e-9 + 0.6 + solver.TIME_TO_SLEEP


@paths
def test_setting_a_body_state_wakes_it(compiled):
    """The top box of the sleeping stack set 0.2 m higher: it falls back at once."""
    sim = _simulation(_stack(), compiled)
    _until_asleep(sim, [0, 1, 2])
    x, y, angle = sim.q[2]
    sim.set_body_state("box2", (x, y + 0.2), angle, (0.0, 0.0), 0.0)
    assert sim.model.contacts.sleeping() == []
    sim.step()
    assert sim.v[2][1] < 0.0 and sim.q[2][1] < y + 0.2


@paths
def test_a_body_with_another_force_never_sleeps(compiled):
    """Angular damping on the bottom box: it never sleeps, so neither does its island (all
    three), though it rests as still as without the damping."""
    sim = _simulation(_stack(extra={"spin": {"type": "angular_damping", "bodies": ["box0"],
                                             "coefficient": 0.1}}), compiled)
    sim.advance_to(2_000_000_000)
    assert sim.model.contacts.sleeping() == []
    assert np.abs(sim.v).max() < solver.SLEEP_SPEED


@paths
def test_sleeping_changes_no_bit_before_anything_sleeps(compiled):
    """A pyramid of 4 rows with sleeping on and off over 0.4 s (before any island has
    rested 0.5 s): the same states and warm starts; with sleeping off the pass exports
    the warm starts alone, as without sleeping."""
    on, off = (_simulation(pyramid(4, sleep=sleep), compiled) for sleep in (True, False))
    on.advance_to(400_000_000)
    off.advance_to(400_000_000)
    assert np.array_equal(on.q, off.q) and np.array_equal(on.v, off.v)
    state = on.model.contacts.export_state()
    assert state["warm"] == off.model.contacts.export_state()
    assert isinstance(off.model.contacts.export_state(), list)
    assert on.model.contacts.sleeping() == [] and min(state["rested"]) > 0.0


@paths
@pytest.mark.parametrize("at_ns", [300_000_000, 1_800_000_000, 2_400_000_000])
def test_restored_sleeping_simulation_continues_bit_for_bit(compiled, at_ns):
    """The stack with the falling box, saved (through JSON, as a keyframe) while the
    stack's rest times count (0.3 s), while the four boxes' count after the landing woke
    the stack (1.8 s), or while all four sleep (2.4 s), and restored into a new simulation:
    1.5 s on, the same bits and the same sleeping bodies at every publish. Restored without
    the sleep state (warm starts only), the rest times start again and the run differs."""
    scene = _stack(dropper=True)
    original = _simulation(scene, compiled)
    original.advance_to(at_ns)
    saved = json.loads(json.dumps(original.export_state()))

    def restored(sleep_state: bool) -> Simulation:
        sim = _simulation(scene, compiled)
        state = json.loads(json.dumps(saved))
        if not sleep_state:
            state["contacts"] = state["contacts"]["warm"]
        sim.import_state(state)
        return sim

    again, cold = restored(True), restored(False)
    differs = False
    for k in range(1, 76):
        stop = at_ns + k * 20_000_000
        for sim in (original, again, cold):
            sim.advance_to(stop)
        assert np.array_equal(again.q, original.q) and np.array_equal(again.v, original.v)
        assert again.model.contacts.sleeping() == original.model.contacts.sleeping()
        differs |= cold.model.contacts.sleeping() != original.model.contacts.sleeping()
    assert again.model.contacts.export_state() == original.model.contacts.export_state()
    assert differs


def test_the_scene_reads_contacts_sleep_and_names_a_bad_value():
    """Default off; a value that is not a boolean is refused naming file and parameter; the
    bodies a spring, drag or constant force acts on are the restless ones."""
    assert not _stack(sleep=False).sleep and _stack().sleep
    assert not Simulation(make_scene({"bodies": {"a": {"shape": "circle", "radius": 0.1,
                                                       "mass": 1.0}}})).scene.sleep
    with pytest.raises(SceneError, match=r"^test-scene: parameter 'contacts.sleep': must be "
                                         "true or false"):
        _stack(sleep="yes")
    pushed = _stack(extra={"push": {"type": "constant_force", "body": "box1",
                                    "force": [0.0, 1.0]},
                           "air": {"type": "linear_drag", "bodies": ["box2"],
                                   "coefficient": 0.1}})
    assert Simulation(pushed).model.contacts.calm == [True, False, False]


@paths
def test_a_spawn_or_delete_wakes_every_body(compiled):
    """with_world (here: the world given again, as a spawn and delete leave the others)
    wakes the sleeping stack; it keeps its pose and sleeps again after TIME_TO_SLEEP."""
    scene = _stack()
    sim = _simulation(scene, compiled)
    _until_asleep(sim, [0, 1, 2])
    moved = sim.with_world(scene)
    if not compiled:
        moved.model.use_python()
    assert moved.model.contacts.sleeping() == [] and np.array_equal(moved.q, sim.q)
    start = moved.time_ns * 1e-9
    assert _until_asleep(moved, [0, 1, 2]) >= start + solver.TIME_TO_SLEEP


@paths
def test_steps_of_a_scene_fully_asleep_are_skipped_and_change_no_bit(compiled, monkeypatch):
    """Once every body sleeps, a step is skipped (no force evaluation, in the kernel and in
    Python): it would put each body back where it started. The bits are those of taking
    every step in full (Python with the skip turned off), through the sleep, a push that
    wakes the stack and the sleep after it."""
    def run(sim: Simulation) -> tuple[list[np.ndarray], list[int]]:
        states, evaluations = [], []
        for k in range(round(2.5 / H)):
            if k == round(1.2 / H):
                sim.push(WrenchCommand(sim.time_ns, "box2", "test", "box2", (0.0, 0.0),
                                       (7.0, 0.0), duration_ns=100_000_000))
            sim.step()
            states.append(np.concatenate([sim.q, sim.v]))
            evaluations.append(sim.integrator.counters.evaluations)
        return states, evaluations

    with monkeypatch.context() as patch:
        patch.setattr("hecker_dynamics.dynamics.simulation.FIXED_STEP", ())
        full, full_evaluations = run(_simulation(_stack(), False))
    sim = _simulation(_stack(), compiled)
    skipped, evaluations = run(sim)
    assert all(np.array_equal(a, b) for a, b in zip(full, skipped))
    assert np.diff(full_evaluations).min() == 1  # semi-implicit Euler: one per step
    idle = [k for k in range(1, len(evaluations)) if evaluations[k] == evaluations[k - 1]]
    # Asleep from about 0.5 s until the push at 1.2 s, and again about 0.5 s after it.
    assert idle and idle[0] * H < 0.6 and any(k * H > 1.9 for k in idle)
    assert not any(round(1.2 / H) <= k < round(1.3 / H) for k in idle)
