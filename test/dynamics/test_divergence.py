"""Blown-up states: a DivergenceError with the last good state kept, never an exit 0.

The bound (:mod:`hecker_dynamics.dynamics.divergence`): the energy of motion and of the
springs, B = K + U_springs, can only grow by the work of gravity, constant forces and
torques and inputs, at a rate of at most c sqrt(B) (c from the forces, masses, moments
of inertia and lever arms), so sqrt(B(t)) <= sqrt(B(0)) + int c / 2 dt. A state with B
more than GROWTH times that bound (and above the floor of every body moving at 1 m/s
and 1 rad/s) is refused.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from scene_builders import make_scene, write_scene

from hecker_dynamics.bench.scenes import bench_scene, configure
from hecker_dynamics.cli import main
from hecker_dynamics.dynamics import DivergenceError, Simulation, WrenchCommand
from hecker_dynamics.dynamics.divergence import GROWTH
from hecker_dynamics.ros.session import decode_state, encode_state
from hecker_dynamics.scene.load import load_scene, scene_path, shipped_scenes

SEC = 1_000_000_000


def _sample_params() -> dict:
    return yaml.safe_load(scene_path("sample").read_text())["dynamics_node"]["ros__parameters"]


def _stiff_sample(method: str, **spring) -> dict:
    """The sample scene with its spring made 1e9 N/m (omega h = 44.7 at 1 ms), no script."""
    params = _sample_params()
    params["integrator"] = method
    params["forces"]["link"].update(stiffness=1.0e9, **spring)
    params.pop("script", None)
    return params


def _run_or_diverge(scene, until_ns):
    """(snapshots passed, the error or None, the state kept)."""
    sim = Simulation(scene)
    snapshots = []
    error = None
    try:
        while sim.time_ns < until_ns:
            snapshots += sim.advance_to(min(sim.time_ns + scene.publish_period_ns, until_ns))
    except DivergenceError as caught:
        error = caught
    return sim, snapshots, error


@pytest.mark.parametrize("method", ["semi_implicit_euler", "explicit_euler", "rk4",
                                    "velocity_verlet", "implicit_midpoint", "auto"])
def test_a_blown_up_spring_never_passes_silently(method):
    """Rows 1 to 3 of issue 15: no contact pass ZeroDivisionError, no energy growing by
    orders of magnitude with exit 0. Without inputs and with dissipative walls and a
    damped spring the energy cannot grow: every state published (and the one kept when
    the run stops) has at most its initial energy, to the integrator's error, or the run
    stops with a DivergenceError."""
    scene = make_scene(_stiff_sample(method))
    sim, snapshots, error = _run_or_diverge(scene, SEC // 5)
    start = Simulation(scene).snapshot().energy
    kept = sim.snapshot()
    assert all(np.isfinite(kept._q).ravel()) and all(np.isfinite(kept._v).ravel())
    if error is None:
        assert max(s.energy for s in snapshots) <= start * (1 + 1e-3), method
    else:
        assert "kept" in str(error)
        assert kept.energy <= GROWTH * start


def test_semi_implicit_euler_blow_up_is_a_divergence_error_naming_the_energy():
    _, _, error = _run_or_diverge(make_scene(_stiff_sample("semi_implicit_euler")), 2 * SEC)
    assert error is not None and "energy" in str(error)


@pytest.mark.parametrize("change", [
    {"forces": {"g": {"type": "gravity", "acceleration": [0.0, -1e308]}}},
    {"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1e-300,
                      "position": [0.0, 1.0]}},
     "forces": {"pin": {"type": "spring", "body_a": "b", "point_a": [0.5, 0.5],
                        "anchor": [0.0, 3.0], "stiffness": 50.0}}},
    {"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0, "position": [0.0, 1.0],
                      "velocity": [1e308, 1e308]}}},
])
@pytest.mark.parametrize("method", ["rk4", "implicit_midpoint", "auto"])
def test_infinite_states_meet_the_contact_pass_as_divergence(tmp_path, capsys, change, method):
    params = {"integrator": method, "step": 0.001,
              "bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                               "position": [0.0, 1.0]}},
              "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]},
                        "side": {"point": [5.0, 0.0], "normal": [-1.0, 0.0]}}}
    params.update(copy.deepcopy(change))
    path = write_scene(tmp_path, params)
    code = main(["run", str(path), "--duration", "0.1"])
    err = capsys.readouterr().err
    if code == 0:  # a 1e-300 kg body on an A-stable method: a finite, bounded run
        assert "mass" in str(change) and method != "rk4" and not err
        return
    assert code == 2 and err.count("\n") == 1 and "kept" in err


def test_the_bound_holds_exactly_for_a_constant_force_from_rest():
    """From rest, a constant force F on mass m gives sqrt(K) = F t / sqrt(2 m): the bound
    without its growth factor, met with equality; the run never trips, over energies
    from 0 to 5e10 J."""
    scene = make_scene({"integrator": "semi_implicit_euler", "duration": 10.0,
                        "bodies": {"b": {"shape": "circle", "radius": 0.1, "mass": 1e-3}},
                        "forces": {"push": {"type": "constant_force", "body": "b",
                                            "force": [1000.0, 0.0]}}})
    sim = Simulation(scene)
    sim.play((), 10 * SEC)
    kinetic = sim.snapshot().energy
    assert kinetic == pytest.approx(1000.0 ** 2 * 100 / (2 * 1e-3), rel=1e-2)
    assert sim._bound.limit() >= kinetic


def test_inputs_raise_the_bound():
    """A pushed body gains energy from zero only by the input's work; the bound counts it
    (a scripted 1e4 N push on 1 kg for 5 s: 1.25e9 J)."""
    scene = make_scene({"integrator": "rk4", "input_timeout": 10.0,
                        "bodies": {"b": {"shape": "circle", "radius": 0.1, "mass": 1.0}}})
    sim = Simulation(scene)
    push = WrenchCommand(0, "b", "test", "world", (0.0, 0.0), (1e4, 0.0), 0.0, 5 * SEC)
    sim.play((push,), 5 * SEC)
    assert sim.snapshot().energy == pytest.approx(0.5 * (1e4 * 5) ** 2, rel=1e-6)


@pytest.mark.parametrize("name", shipped_scenes())
def test_the_shipped_scenes_never_trip_the_bound(name):
    """Each shipped scene's full run stays far inside the bound: the largest ratio of B
    to the bound's value must be below 1 / 10 of the growth allowed."""
    scene = load_scene(name)
    sim = Simulation(scene)
    sim.play(scene.script, scene.duration_ns)
    assert sim._bound.worst_ratio < GROWTH / 10


def test_run_keeps_no_snapshots_for_a_long_run(monkeypatch, capsys):
    """`run` prints the first and last state only: it takes two snapshots whatever the
    duration (it kept one per publish instant: 180,000 for an hour at 50 Hz)."""
    from hecker_dynamics.dynamics import simulation
    taken = []
    original = simulation.Snapshot.__init__

    def counting(self, *args, **kwargs):
        taken.append(1)
        original(self, *args, **kwargs)
    monkeypatch.setattr(simulation.Snapshot, "__init__", counting)
    assert main(["run", "sample", "--duration", "20"]) == 0
    assert len(taken) == 2


def _restored(sim: Simulation) -> Simulation:
    """A new simulation of ``sim``'s scene continuing from its exported state, through a
    keyframe's JSON as a live session records it."""
    again = Simulation(sim.scene)
    again.import_state(decode_state(encode_state(sim.export_state())))
    return again


def test_a_restored_simulation_stops_where_the_original_does():
    """The undamped 1e6 N/m oscillator on 0.05 ms explicit Euler steps: each step
    multiplies the energy by 1 + (omega h)^2 = 1.0025, e^(0.0025 * 400) = 2.7 per 20 ms
    publish period, so it passes six checks, then trips the bound (GROWTH = 1000).
    Restored from a publish instant before that, it carries the bound's budget and the
    state a refused check returns to, so it stops at the same instant, with the same
    message and the same kept state, bit for bit."""
    scene = configure(bench_scene("stiff"), "explicit_euler", 5e-5)
    _, snapshots, error = _run_or_diverge(scene, 2 * SEC)
    assert error is not None and "energy" in str(error) and len(snapshots) == 6
    for restart in (1, len(snapshots) // 2, len(snapshots) - 1):
        original = Simulation(scene)
        original.advance_to(snapshots[restart - 1].time_ns)
        copy_ = _restored(original)
        outcomes = []
        for sim in (original, copy_):
            with pytest.raises(DivergenceError) as caught:
                sim.advance_to(2 * SEC)
            outcomes.append((str(caught.value), sim.q.tobytes(), sim.v.tobytes(),
                             sim.time_ns, sim.steps, sim._bound.worst_ratio))
        assert outcomes[0] == outcomes[1]
        assert outcomes[0][0] == str(error)


def test_a_restored_stopped_simulation_keeps_refusing():
    scene = make_scene(_stiff_sample("semi_implicit_euler"))
    sim, _, error = _run_or_diverge(scene, 2 * SEC)
    again = _restored(sim)
    with pytest.raises(DivergenceError) as caught:
        again.step()
    assert str(caught.value) == str(error)
    assert again.q.tobytes() == sim.q.tobytes() and again.time_ns == sim.time_ns


def test_setting_a_body_state_joins_its_energy_to_the_bound():
    """A body set moving at 1e4 m/s from outside (a world service) has 5e7 J where the
    scene started with none: that is the new budget, not a blow-up; the run goes on."""
    scene = make_scene({"integrator": "rk4",
                        "bodies": {"b": {"shape": "circle", "radius": 0.1, "mass": 1.0}}})
    sim = Simulation(scene)
    sim.advance_to(scene.publish_period_ns)
    sim.set_body_state("b", (0.0, 0.0), 0.0, (1e4, 0.0), 0.0)
    snapshots = sim.advance_to(SEC)
    assert snapshots and snapshots[-1].energy == pytest.approx(0.5 * 1e4 ** 2, rel=1e-12)
    assert sim._bound.worst_ratio <= 1.0 / GROWTH * (1 + 1e-12)


@pytest.mark.parametrize("name", ["sample", "car_flip", "ship", "door"])
def test_plain_float_bound_equals_the_array_bound(name):
    """The bound's energy and work rate in plain floats (scenes of Model.lean's size) and
    with numpy arrays agree to rounding, at states where every spring is stretched and
    every input acts at a point away from its body's CM: the two sums differ only in
    order and in hypot's last bit, so 1e-12 relative is ample and a dropped or doubled
    term (a spring, gravity, a lever arm) is far outside it."""
    from hecker_dynamics.dynamics.divergence import EnergyBound
    from hecker_dynamics.dynamics.forces import ConstantWrenchTerm
    from hecker_dynamics.dynamics.model import Model

    scene = load_scene(scene_path(name))
    lean, arrays = Model(scene, lean=True), Model(scene, lean=False)
    rng = np.random.default_rng(7)
    n = len(lean.names)
    inputs = ConstantWrenchTerm(np.arange(n), rng.normal(size=(n, 2)) * 50.0,
                                rng.normal(size=n), np.full(n, -1), np.roll(np.arange(n), 1),
                                rng.normal(size=(n, 2)), np.ones(n, dtype=bool))
    for _ in range(5):
        q, v = rng.normal(size=(n, 3)) * 3.0, rng.normal(size=(n, 3)) * 2.0
        bound_lean = EnergyBound(lean, q, v)
        bound_arrays = EnergyBound(arrays, q, v)
        assert bound_lean.energy(q, v) == pytest.approx(bound_arrays.energy(q, v), rel=1e-12)
        assert bound_lean.rate(q, inputs) == pytest.approx(bound_arrays.rate(q, inputs),
                                                           rel=1e-12)
        assert bound_lean.rate(q, inputs) > bound_lean.rate(q, None) >= 0.0
