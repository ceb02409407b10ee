"""Simulation: determinism to the bit, reset, publish instants, divergence, integer time.

These are exact properties (same floating-point operations in the same order, integer
clocks), so the comparisons are on raw bytes and integers: no tolerances.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import push_unchecked
from scene_builders import make_scene

from hecker_dynamics import DivergenceError, Simulation, WrenchCommand, load_scene
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.integrators.methods import METHODS
from hecker_dynamics.scene.load import shipped_scenes

MS = 1_000_000
ROOT = Path(__file__).resolve().parents[2]


def _snapshot_bytes(snapshots):
    rows = [[s.time_ns, s.steps, s.energy] + [x for b in s.bodies for x in
                                               (*b.position, b.angle, *b.linear_velocity,
                                                b.angular_velocity)]
            for s in snapshots]
    return np.array(rows, dtype=float).tobytes() + np.array(
        [s.time_ns for s in snapshots], dtype=np.int64).tobytes()


EXTRA = (
    WrenchCommand(500 * MS, "right", "joy", "right/hook", (0.0, 0.0), (3.0, 5.0), 0.2, 0),
    WrenchCommand(700 * MS, "left", "joy", "world", (-1.0, 2.5), (-4.0, 1.0), 0.0, 80 * MS),
    WrenchCommand(900 * MS, "right", "joy", "right", (0.3, 0.0), (0.0, 0.0), -1.0, 0),
)


def _run_sample(chunk_ms=None, duration_ms=3500):
    """The sample scene with its scripted kick (at 3 s) plus a few pushed commands."""
    scene = load_scene("sample")
    sim = Simulation(scene)
    states, snapshots = [], []
    commands = sorted(scene.script + EXTRA, key=lambda c: c.stamp_ns)
    for command in commands:
        if command.stamp_ns >= duration_ms * MS:
            break
        snapshots += _advance(sim, command.stamp_ns, chunk_ms, states)
        sim.push(command)
    snapshots += _advance(sim, duration_ms * MS, chunk_ms, states)
    return b"".join(states), _snapshot_bytes(snapshots), snapshots


def _advance(sim, t_ns, chunk_ms, states):
    snaps = []
    while sim.time_ns < t_ns:
        target = t_ns if chunk_ms is None else min(t_ns, sim.time_ns + chunk_ms * MS)
        snaps += sim.advance_to(target)
        if chunk_ms is None:
            states.append(sim.q.tobytes() + sim.v.tobytes())
    return snaps


def test_repeat_runs_are_bit_identical():
    first = _run_sample()
    second = _run_sample()
    assert first[0] == second[0]
    assert first[1] == second[1]
    assert first[2] == second[2]
    assert len(first[2]) == 175  # 3.5 s at 50 Hz


def test_chunking_of_advance_to_does_not_change_the_result():
    """Advancing in odd 7 ms chunks passes the same publish instants with the same bytes."""
    whole = _run_sample()
    chunked = _run_sample(chunk_ms=7)
    assert whole[1] == chunked[1]


_DIGEST = """
import hashlib, sys
sys.path.insert(0, {root!r})
from hecker_dynamics import Simulation, load_scene
scene = load_scene("sample")
sim = Simulation(scene)
sim.play(scene.script, 3_200_000_000)
print(hashlib.sha256(sim.q.tobytes() + sim.v.tobytes()).hexdigest())
"""


def test_fresh_processes_with_different_hash_seeds_agree():
    """No hidden dependence on set/dict iteration order or process state."""
    digests = set()
    for seed in ("1", "12345"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        out = subprocess.run([sys.executable, "-c", _DIGEST.format(root=str(ROOT))], env=env,
                             capture_output=True, text=True, check=True, timeout=120)
        digests.add(out.stdout.strip())
    scene = load_scene("sample")
    sim = Simulation(scene)
    sim.play(scene.script, 3_200_000_000)
    digests.add(hashlib.sha256(sim.q.tobytes() + sim.v.tobytes()).hexdigest())
    assert len(digests) == 1


def test_reset_returns_to_the_initial_state_and_repeats_the_run():
    scene = load_scene("sample")
    sim = Simulation(scene, start_ns=5 * MS)
    q0, v0 = sim.q.tobytes(), sim.v.tobytes()
    first0 = sim.snapshot()
    sim.push(WrenchCommand(5 * MS + 300 * MS, "left", "a", "left", (0.1, 0.0), (0.0, 9.0),
                           0.0, 0))
    run1 = sim.advance_to(5 * MS + 1200 * MS)
    # a command still pending at reset must be dropped
    sim.push(WrenchCommand(sim.time_ns + 100 * MS, "right", "late", "world", (0.0, 0.0),
                           (50.0, 0.0), 0.0, 0))
    sim.reset()
    assert sim.q.tobytes() == q0 and sim.v.tobytes() == v0
    assert sim.time_ns == 5 * MS and sim.steps == 0
    assert sim.snapshot() == first0
    sim.push(WrenchCommand(5 * MS + 300 * MS, "left", "a", "left", (0.1, 0.0), (0.0, 9.0),
                           0.0, 0))
    run2 = sim.advance_to(5 * MS + 1200 * MS)
    assert _snapshot_bytes(run1) == _snapshot_bytes(run2)


def test_reset_with_a_new_start_time():
    sim = Simulation(load_scene("sample"))
    sim.advance_to(100 * MS)
    sim.reset(start_ns=10**18)
    assert sim.time_ns == 10**18 and sim.steps == 0
    snaps = sim.advance_to(10**18 + 100 * MS)
    assert [s.time_ns for s in snaps] == [10**18 + k * 20 * MS for k in range(1, 6)]


def _free_scene(step=0.001, rate=50.0, integrator="rk4", forces=True):
    params = {"step": step, "publish_rate": rate, "integrator": integrator,
              "bodies": {"b": {"shape": "circle", "radius": 0.5, "mass": 1.0,
                               "velocity": [1.0, 0.0]}}}
    if forces:
        params["forces"] = {"g": {"type": "gravity"}}
    return make_scene(params)


def test_snapshots_at_every_publish_period():
    sim = Simulation(_free_scene())
    snaps = sim.advance_to(1000 * MS)
    assert [s.time_ns for s in snaps] == [k * 20 * MS for k in range(1, 51)]
    assert [s.steps for s in snaps] == [k * 20 for k in range(1, 51)]
    # a target between steps: only whole steps are taken; max_steps bounds a call
    assert sim.advance_to(1000 * MS + 1_500_000) == [] and sim.time_ns == 1001 * MS
    sim.advance_to(2000 * MS, max_steps=5)
    assert sim.time_ns == 1006 * MS
    later = sim.advance_to(1100 * MS)
    assert [s.time_ns for s in later] == [1020 * MS, 1040 * MS, 1060 * MS, 1080 * MS,
                                          1100 * MS]


def test_publish_instants_count_from_an_unaligned_start():
    start = 1_700_000_000_000_000_000 + 3 * MS + 7  # not a multiple of the period or step
    sim = Simulation(_free_scene(), start_ns=start)
    snaps = sim.advance_to(start + 100 * MS)
    assert [s.time_ns for s in snaps] == [start + k * 20 * MS for k in range(1, 6)]


def test_snapshot_state_is_the_state_at_its_instant():
    """A snapshot published at t equals a snapshot taken directly after stepping to t, though
    its energy and body states are first read after the simulation moved on and reset
    (they are computed on first use, from a copy of the state)."""
    a = Simulation(_free_scene())
    published = a.advance_to(60 * MS)[0]
    a.reset()
    b = Simulation(_free_scene())
    for _ in range(20):
        b.step()
    assert published.time_ns == 20 * MS
    assert published == b.snapshot()
    taken = b.snapshot()
    expected = repr(taken)  # reads energy and bodies now
    again = b.snapshot()
    b.q[:], b.v[:] = 7.0, 7.0  # the simulation's arrays changed in place
    assert repr(again) == expected


@pytest.mark.parametrize("name", shipped_scenes())
def test_lean_body_frames_are_numpys_to_the_bit(name):
    """A small world's snapshot takes its body frames in plain floats: the bits of the
    numpy path (the sign of zero included), for off-centre CMs, any angle, and NaN where
    an angle is infinite, so a snapshot does not depend on the world's size."""
    model = Model(load_scene(name))
    rng = np.random.default_rng(7)
    for trial in range(300):
        q, v = rng.normal(0.0, 3.0, (2, model.size, 3))
        q[:, 2] = rng.uniform(-np.pi, np.pi, model.size) if trial % 3 else \
            rng.normal(0.0, 1e6, model.size)
        if trial == 1:
            q[0, 2], v[0, 0] = np.inf, np.nan
        q[:, :2] *= rng.integers(0, 2, (model.size, 2))  # zeros of both signs, too
        q[:, :2] *= rng.choice([-1.0, 1.0], (model.size, 2))
        with np.errstate(all="ignore"):
            origin, velocity = model.body_frames(q, v)
        rows = model.body_frame_rows(q.tolist(), v.tolist())
        lean = np.array([[x, y, vx, vy] for (x, y), _, (vx, vy), _ in rows])
        numpy = np.column_stack([origin, velocity])
        # Every bit, the sign of zero too, but a NaN's sign and payload.
        assert np.array_equal(np.isnan(lean), np.isnan(numpy))
        known = ~np.isnan(numpy)
        assert lean[known].tobytes() == numpy[known].tobytes()
        assert [(a, w) for _, a, _, w in rows] == list(zip(q[:, 2].tolist(), v[:, 2].tolist()))


def test_time_in_integer_ns_never_drifts():
    """1e-4 s is not a binary fraction: a float clock summing it drifts, the ns one not."""
    sim = Simulation(_free_scene(step=0.0001, rate=50.0, integrator="explicit_euler",
                                 forces=False))
    assert sim.step_ns == 100_000
    snaps = sim.advance_to(3_000_000_000)
    assert sim.time_ns == 3_000_000_000 and type(sim.time_ns) is int
    assert sim.steps == 30_000
    assert [s.time_ns for s in snaps] == [k * 20 * MS for k in range(1, 151)]
    assert all(type(s.time_ns) is int for s in snaps)
    clock = 0.0
    for _ in range(30_000):
        clock += 0.0001
    assert clock != 3.0  # what a float clock would have done


def _diverging(integrator):
    scene = make_scene({"step": 0.001, "integrator": integrator,
                        "bodies": {"calm": {"shape": "circle", "radius": 0.5, "mass": 1.0},
                                   "tiny": {"shape": "circle", "radius": 0.1, "mass": 1e-3,
                                            "position": [2.0, 0.0]}},
                        "forces": {"g": {"type": "gravity"}}, "input_timeout": 0.0})
    sim = Simulation(scene)
    push_unchecked(sim, WrenchCommand(50 * MS, "tiny", "boom", "world", (2.0, 0.1),
                                      (1e308, 1e308), 0.0, 0))
    return sim


def _blow_up(python: bool) -> tuple[str, bytes, bytes, bytes]:
    """Diverge :func:`_diverging`'s scene in the kernel or in Python with numpy (``python``):
    the error, the state kept, and the accelerations the huge input gives at it."""
    sim = _diverging("semi_implicit_euler")
    if python:
        sim.model.use_python(lean=False)
    sim.advance_to(50 * MS)
    accelerations = sim.accelerations().tobytes()
    with pytest.raises(DivergenceError) as caught:
        sim.advance_to(100 * MS)
    return str(caught.value), sim.q.tobytes(), sim.v.tobytes(), accelerations


@pytest.mark.parametrize("python", [False, True])
def test_a_run_sets_its_own_floating_point_error_settings_where_numpy_steps(python):
    """Steps and accelerations in Python quiet numpy's floating-point errors themselves,
    and the kernel's, which skip those settings, do no numpy arithmetic: a caller's
    settings that raise on every error change nothing, overflow included."""
    if not python and not kernel.enabled():
        pytest.skip("needs the compiled kernel")
    quiet = _blow_up(python)
    with np.errstate(all="raise"):
        assert _blow_up(python) == quiet
    assert not np.isfinite(np.frombuffer(quiet[3])).all()  # the input overflowed them


@pytest.mark.parametrize("integrator", METHODS)
def test_divergence_error_keeps_the_last_finite_state(integrator):
    """A finite but huge wrench on a light body overflows the state: the step raises
    DivergenceError naming the body and the simulation keeps the state before it."""
    sim = _diverging(integrator)
    sim.advance_to(50 * MS)
    q, v, t, steps = sim.q.tobytes(), sim.v.tobytes(), sim.time_ns, sim.steps
    with pytest.raises(DivergenceError) as caught:
        sim.advance_to(100 * MS)
    assert "kept the last finite state" in str(caught.value)
    assert sim.q.tobytes() == q and sim.v.tobytes() == v
    assert sim.time_ns == t == 50 * MS and sim.steps == steps == 50
    assert np.isfinite(sim.q).all() and np.isfinite(sim.v).all()
    assert np.isfinite(sim.snapshot().energy)
    with pytest.raises(DivergenceError):  # it stays refused, and still changes nothing
        sim.step()
    assert sim.q.tobytes() == q and sim.v.tobytes() == v
    sim.reset()
    assert sim.advance_to(100 * MS)[-1].time_ns == 100 * MS


def test_divergence_error_names_the_body():
    sim = _diverging("semi_implicit_euler")
    with pytest.raises(DivergenceError, match="tiny"):
        sim.advance_to(100 * MS)


@pytest.mark.parametrize("lean", [True, False])
def test_huge_but_finite_state_is_not_called_divergent(lean):
    """Two bodies at x = 1e308 at rest: their coordinates would sum to infinity, but every
    value is finite, so a step must not report divergence (on either path)."""
    sim = Simulation(make_scene({"bodies": {
        name: {"shape": "circle", "radius": 1.0, "mass": 1.0, "position": [1e308, 0.0]}
        for name in ("a", "b")}}))
    sim.model.use_python(lean)
    sim.step()
    assert sim.q[:, 0].tolist() == [1e308, 1e308]


@pytest.mark.parametrize("name, integrator", [("sample", None), ("door", None),
                                              ("ship", "dopri5")])
def test_play_reporting_progress_takes_the_same_steps(name, integrator):
    """Progress is reported between publish instants only: the run's bits, snapshots and
    step counts are those of a run without it, and the fractions climb to 1."""
    import dataclasses

    from hecker_dynamics import load_scene
    from hecker_dynamics.dynamics.simulation import PROGRESS_UPDATES

    scene = load_scene(name)
    if integrator:
        scene = dataclasses.replace(scene, integrator=integrator)
    until = 3_000_000_000
    quiet, reporting = Simulation(scene), Simulation(scene)
    fractions: list[float] = []
    expected = quiet.play(scene.script, until)
    got = reporting.play(scene.script, until, progress=fractions.append)
    assert [(s.time_ns, s.steps) for s in got] == [(s.time_ns, s.steps) for s in expected]
    assert np.array_equal(reporting.q, quiet.q) and np.array_equal(reporting.v, quiet.v)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    periods = until // scene.publish_period_ns  # a chunk is a whole number of periods
    assert min(PROGRESS_UPDATES, periods) <= len(fractions) <= \
        min(2 * PROGRESS_UPDATES, periods) + len(scene.script) + 1
