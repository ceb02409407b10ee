"""The benchmark's correctness (never its speed): references, plain loops, peers, report.

Peers (pymunk, Box2D, MuJoCo) and the C compiler are optional: their tests skip cleanly.
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from hecker_dynamics.bench import peers, reference, report, ring, run, scenes
from hecker_dynamics.bench.measure import Budget, Case, Outcome, Row
from hecker_dynamics.cli import main
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.dynamics.simulation import Simulation


def core_final(scene, method, step, duration, tolerance=1e-6):
    sim = Simulation(scenes.configure(scene, method, step, tolerance, duration=duration))
    sim.play(sim.scene.script, sim.scene.duration_ns)
    return sim.q, sim.v


def position_error(q, ref_q):
    return float(np.max(np.hypot(*(q[:, :2] - ref_q[:, :2]).T)))


@pytest.mark.parametrize("name", scenes.BENCH_SCENES)
def test_scenes_load_and_plain_model_matches_core(name):
    scene = scenes.bench_scene(name)
    plain = reference.PlainModel(scene)
    model = Model(scene)
    q, v = model.initial_state()
    y = np.concatenate([q.ravel(), v.ravel()])
    assert np.allclose(y, plain.y0, rtol=0, atol=1e-14)
    # A state away from the start, so angles and velocities matter.
    rng = np.random.default_rng(1)
    q2, v2 = q + rng.normal(0, 0.3, q.shape), v + rng.normal(0, 1.0, v.shape)
    expected = model.accelerations(q2, v2).ravel()
    got = np.array(plain.accelerations(np.concatenate([q2.ravel(), v2.ravel()])))
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_scene_parameters_are_the_issues():
    spin = scenes.free_spin()
    assert spin.bodies[0].mass.mass == 10.0
    assert spin.bodies[0].mass.moment_of_inertia == pytest.approx(10.0 * (4 + 0.25) / 12)
    pendulum = reference.PlainModel(scenes.spring_pendulum())
    (_, local, _, _, k, rest, _), = pendulum.springs
    assert (local, k, rest) == ((0.4, 0.0), 200.0, 0.5)
    assert reference.PlainModel(scenes.stiff()).springs[0][4] == 1e6
    assert len(scenes.ring(7).forces) == 7 and len(scenes.ring(1).forces) == 1


@pytest.mark.parametrize("name, method, step, duration, tol", [
    ("free_spin", "rk4", 0.05, 10.0, 1e-9),  # constant acceleration: RK4 exact to rounding
    ("free_spin", "velocity_verlet", 0.1, 10.0, 1e-9),
    ("harmonic", "rk4", 0.0005, 2.0, 1e-9),
    ("stiff", "rk4", 1e-5, 0.002, 1e-9),
])
def test_exact_solutions_agree_with_the_core_at_small_steps(name, method, step, duration, tol):
    scene = scenes.bench_scene(name)
    ref = reference.exact(scene, duration)
    q, _ = core_final(scene, method, step, duration)
    assert position_error(q, ref.q) < tol
    assert float(np.max(np.abs(np.remainder(q[:, 2] - ref.q[:, 2] + math.pi, 2 * math.pi)
                               - math.pi))) < tol


@pytest.mark.parametrize("name", ["spring_pendulum", "two_bodies"])
def test_gbs_reference_agrees_with_tight_dopri5_and_estimates_its_error(name):
    scene = scenes.bench_scene(name)
    ref = reference.gbs_reference(scene, duration=1.0, big=0.05)
    assert ref.error < 1e-10
    q, _ = core_final(scene, "dopri5", 0.05, 1.0, tolerance=1e-13)
    assert position_error(q, ref.q) < 1e-9


def test_gbs_reproduces_the_exact_oscillator():
    scene = scenes.harmonic()
    ref = reference.gbs_reference(scene, duration=2.0, big=0.05)
    assert position_error(ref.q, reference.exact(scene, 2.0).q) < 1e-11


def test_errors_and_energy_drift():
    from hecker_dynamics.bench.measure import errors
    scene = scenes.harmonic()
    ref = reference.exact(scene)
    plain = reference.PlainModel(scene)
    pos, ang, drift = errors(ref.q, ref.v, ref, plain)
    assert pos == 0.0 and ang == 0.0 and drift < 1e-12
    moved = ref.q.copy()
    moved[0, 0] += 3e-3
    assert errors(moved, ref.v, ref, plain)[0] == pytest.approx(3e-3)


@pytest.mark.skipif(ring.compiler() is None, reason="no C compiler")
@pytest.mark.parametrize("n", [1, 2, 6])
def test_c_loop_is_the_cores_semi_implicit_euler(n):
    outcome = ring.c_run(n, 1e-3, 0.2)
    q, v = core_final(scenes.ring(n), "semi_implicit_euler", 1e-3, 0.2)
    dq = q - outcome.q
    dq[:, 2] = np.remainder(dq[:, 2] + math.pi, 2 * math.pi) - math.pi
    assert np.max(np.abs(dq)) < 1e-11
    assert np.max(np.abs(v - outcome.v)) < 1e-10


PEER_PARAMS = [(p, m) for p in peers.PEERS for m in peers.PEER_METHODS[p]]


@pytest.mark.parametrize("peer, method", PEER_PARAMS)
@pytest.mark.parametrize("name", ["harmonic", "spring_pendulum", "free_spin"])
def test_peer_reproduces_its_claimed_scheme(peer, method, name):
    if not peers.available(peer):
        pytest.skip(f"{peer} not installed")
    check = peers.check_peer(peer, method, name, scenes.bench_scene(name), steps=100)
    # float64 peers to rounding; Box2D keeps float32 state.
    limit = 1e-5 if peer == "box2d" else 1e-12
    assert check.difference <= limit * max(1.0, check.scale)


def test_pymunk_forces_set_before_step_make_explicit_euler():
    if not peers.available("pymunk"):
        pytest.skip("pymunk not installed")
    scene = scenes.spring_pendulum()
    trap = peers.check_peer("pymunk", "python", "spring_pendulum", scene, steps=100,
                            scheme="explicit_euler", forces_before_step=True)
    right = peers.check_peer("pymunk", "python", "spring_pendulum", scene, steps=100,
                             scheme="position_first_euler", forces_before_step=True)
    assert trap.difference < 1e-12 and right.difference > 1e-4


def test_mujoco_does_not_reset_a_diverged_state():
    if not peers.available("mujoco"):
        pytest.skip("mujoco not installed")
    outcome = peers.peer_run("mujoco", scenes.stiff(), "euler", 0.01, 1.0)
    assert outcome.failed or not np.all(np.isfinite(outcome.q)) \
        or np.max(np.abs(outcome.q)) > 1e6


# A budget no run exceeds: the test checks the files a run writes, and on a loaded machine
# without the kernel a tight one skipped the very cases it reads (RK4 at h = 0.01 s). The
# default scene and the ball drop shrink to what the files need: a second of the scene, one
# tolerance and one step of the drop.
TINY = run.Mode(
    "tiny", steps={s: [0.1, 0.01] for s in scenes.BENCH_SCENES}, tolerances=[1e-6],
    adaptive_steps=[0.1], budget=Budget(60.0, 2, 60.0, 5), ring_sizes=[1, 4], ring_wall=0.01,
    shipped_duration=0.2, shipped_steps=[1.0], shipped_ref_divisor=2.0, profile_steps=60,
    sample_duration=1.0, bounce_tolerances=[1e-6], bounce_steps=[0.004])


def test_quick_bench_runs_end_to_end_and_writes_well_formed_files(tmp_path, monkeypatch):
    monkeypatch.setitem(run.MODES, "tiny", TINY)
    results = run.run_bench("tiny", tmp_path, scenes=["harmonic", "sample"], peers=True,
                            log=lambda s: None, command="test")
    with open(tmp_path / "results.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert rows and set(rows[0]) == set(run.Row.FIELDS)
    assert {r["scene"] for r in rows} == {"harmonic", "sample"}
    ok = [r for r in rows if r["status"] == "ok"]
    assert ok and all(float(r["cost"]) > 0 for r in ok)
    harmonic_rk4 = [r for r in ok if r["method"] == "rk4" and r["engine"] == "hecker_dynamics"
                    and float(r["step"]) == 0.01]
    assert harmonic_rk4 and float(harmonic_rk4[0]["position_error"]) < 1e-3
    with open(tmp_path / "ring.csv") as handle:
        ring_rows = list(csv.DictReader(handle))
    assert {r["engine"] for r in ring_rows} >= {"hecker_dynamics"}
    if ring.load_c_loop() is not None:
        assert sorted(results.ring_pairs) == [1, 4]
        assert all(len(p) == run.RING_PAIRS and min(p) > 0 for p in results.ring_pairs.values())
    text = (tmp_path / "report.md").read_text()
    assert "## Targets" in text and "## Headline" in text
    for block in text.split("\n\n"):
        lines = [line for line in block.splitlines() if line.startswith("|")]
        if lines:
            assert len({line.count("|") for line in lines}) == 1, block
    assert results.sample["hecker_dynamics"] > 0


def test_ring_pairs_divide_runs_made_back_to_back():
    """The machine's speed changes between pairs of runs (here 1, 3, 0.5, ... times), never
    within one: each pair's ratio is then the engines' true ratio, 2, however it drifts."""
    calls = []

    def timed(cost):
        def runner(duration):
            speed = (1.0, 3.0, 0.5, 1.7, 0.9)[len(calls) // 2 % 5]
            calls.append(cost)
            return Outcome(cost * speed * 100, np.zeros((1, 3)), np.zeros((1, 3)), steps=100)
        return runner

    ours = Case("ring10", "hecker_dynamics", "semi_implicit_euler", 1e-3, math.nan, 0.1,
                timed(2.0))
    c_loop = Case("ring10", "c", "semi_implicit_euler", 1e-3, math.nan, 0.1, timed(1.0))
    ratios = run.ring_pairs(ours, c_loop)
    assert ratios == [2.0] * run.RING_PAIRS
    assert calls[:4] == [2.0, 1.0, 1.0, 2.0]  # A B, B A: each pair back to back


def _row(engine, method, step, cost, error, status="ok"):
    return Row("harmonic", engine, method, step, math.nan, 1.0, status=status, cost=cost,
               position_error=error)


def test_headline_takes_the_cheapest_reaching_configuration_and_says_why_a_peer_has_none():
    """The cheapest row under each error wins; a peer with no reaching row is told apart
    from one whose finer configurations were skipped for the run budget."""
    rows = [_row("hecker_dynamics", "rk4", 0.01, 2e-3, 1e-4),
            _row("hecker_dynamics", "dop853", 0.5, 1e-3, 1e-7),
            _row("mujoco", "rk4", 0.01, 4e-3, 1e-4),
            _row("mujoco", "rk4", 0.001, 4e-2, 1e-10),
            _row("pymunk", "native", 0.01, 1e-4, 1e-2),
            _row("pymunk", "native", 0.001, math.nan, math.nan, status="skipped")]
    head = {e.threshold: e for e in report.headline(rows)}
    best = head[1e-3].best["hecker_dynamics"]
    assert best is not None and best.method == "dop853"
    assert head[1e-3].ratios["mujoco"] == pytest.approx(0.25)
    assert head[1e-6].ratios["mujoco"] == pytest.approx(0.025)
    assert head[1e-9].ratios["mujoco"] == math.inf  # only the peer reaches 1e-9
    assert head[1e-3].ratios["pymunk"] == 0.0
    assert "box2d" not in head[1e-3].ratios  # not run on this scene
    assert "pymunk" in head[1e-3].skipped and "mujoco" not in head[1e-3].skipped
    assert "skipped" in report._ratio_text(0.0, skipped=True)
    assert report._ratio_text(0.0) == "peer never reaches"
    assert report._ratio_text(0.5) == "0.50 (met)" and report._ratio_text(0.51) == "0.51 (missed)"


def test_cli_bench_help_and_bad_scene(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "--help"])
    assert exit_info.value.code == 0
    assert "--quick" in capsys.readouterr().out
    assert main(["bench", "--scenes", "nonesuch"]) == 2
    assert "unknown benchmark scene" in capsys.readouterr().err
