"""The compiled kernel (hecker_dynamics._kernel) against Python's plain-float path.

The kernel claims to repeat ``add_scalar`` (the plain-float force path) and the fixed-step
integrators operation for operation, so these tests compare raw bytes, not values within
a tolerance:

- accelerations of every kind of force term and of input wrenches, ``Model(scene)``
  (compiled) against ``Model(scene, lean=True)``, on random states;
- whole runs of explicit Euler, semi-implicit Euler, velocity Verlet and RK4 on the
  benchmark scenes and rings, ``Simulation(scene)`` against a simulation whose model was
  switched to the plain-float path (``use_python(True)``): states, clocks, step counts,
  evaluation counters and snapshots;
- runs cut into chunks by publish instants, input changes (stamps, durations, the input
  timeout, replacements) and ``max_steps``, and single ``step()`` calls;
- failures: the same ``DivergenceError`` message and the same last finite state.

Three comparisons are not bit for bit, on purpose:

- Spring lengths and quadratic-drag speeds whose squares underflow (about 1e-170) or
  overflow (about 1e160) are taken by ``hypot``: C's (glibc) and Python's ``math.hypot``
  are different implementations that differ by one ulp in about 0.5 % of random cases
  (measured), so the accelerations are held within 8 ulps of the largest one.
- dopri5 and dop853 sum their stages in the kernel in their own order, where Python calls
  numpy's matrix products (BLAS, whose order and fused multiply-adds are its own). Each
  accepted sub-step may then round differently, by some ulps of the largest component of
  the state (more for dop853, whose stage coefficients reach 43 in size and cancel), and
  on these short, non-chaotic runs the differences add up about linearly. The states are
  held within 32 eps x (accepted sub-steps) x max(1, largest |component| seen). Measured
  (10 ms steps, tolerance 1e-10, 100 to 7500 sub-steps): 2e-15 to 6e-11 absolute, at most
  0.23 x 4 eps per sub-step, so the bound leaves a margin of about 30; a wrong coefficient
  or controller would differ by about the tolerance (1e-10 relative per sub-step) and
  change the counts, which must be equal (evaluations, sub-steps, refused sub-steps).
- The binding's refusals compare exception types and messages only.

Without the extension every test here skips (with the reason), except the ``fallback``
tests, which check the pure-Python path that then runs. The environment switch
``HECKER_DYNAMICS_KERNEL`` is cleared for the compiled tests, so that they still test the
kernel when the suite runs with the switch at 0.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.bench.pyramid import pyramid
from hecker_dynamics.bench.scenes import bench_scene, configure, ring
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.divergence import BUDGET_ROWS, GROWTH
from hecker_dynamics.dynamics.forces import WrenchRow
from hecker_dynamics.dynamics.model import LEAN_BODIES, Model, wrench_term
from hecker_dynamics.dynamics.simulation import DivergenceError, Simulation
from hecker_dynamics.integrators.methods import EmbeddedRungeKutta
from hecker_dynamics.scene.commands import WrenchCommand

MS = 1_000_000
SEC = 1_000_000_000
EPS = float(np.finfo(float).eps)
FIXED = ("explicit_euler", "semi_implicit_euler", "velocity_verlet", "rk4")
ADAPTIVE = ("dopri5", "dop853")
NOT_BUILT = ("the compiled kernel hecker_dynamics._kernel is not built (build it in place "
             "from src/kernel/*.c, see hecker_dynamics/kernel.py)")


@pytest.fixture(autouse=True)
def ext(request, monkeypatch):
    """The extension module; skips every test but the fallback ones when it is missing,
    and clears the switch so that new models use the kernel."""
    if request.node.name.startswith("test_fallback"):
        return None
    module = pytest.importorskip("hecker_dynamics._kernel", reason=NOT_BUILT)
    monkeypatch.delenv(kernel.SWITCH, raising=False)
    return module


# ----------------------------------------------------------------- scenes

BODIES = {
    "a": {"shape": "box", "size": [1.0, 0.4], "mass": 2.0, "center": [0.2, 0.1],
          "angle": 0.4, "angular_velocity": 1.5, "points": {"tip": [0.5, 0.2]}},
    "b": {"shape": "circle", "radius": 0.3, "mass": 1.5, "position": [2.0, 1.0],
          "velocity": [0.3, -0.2]},
    "c": {"parts": {"hull": {"shape": "polygon", "vertices": [-1.0, -0.5, 1.0, -0.5, 0.0, 1.0]},
                    "ball": {"shape": "circle", "radius": 0.2, "center": [0.0, -0.8]}},
          "density": 3.0, "position": [-2.0, 0.5], "angle": -2.5},
}

#: One force of each kind, by name: the model builds one term per kind from them.
FORCES = {
    "gravity": {"type": "gravity", "acceleration": [0.3, -9.81], "bodies": ["a", "c"]},
    "anchor_spring_rest": {"type": "spring", "body_a": "a", "point_a": "tip",
                           "anchor": [0.0, 3.0], "stiffness": 40.0, "rest_length": 0.5,
                           "damping": 0.7},
    "anchor_spring_zero": {"type": "spring", "body_a": "c", "point_a": [0.3, 0.2],
                           "anchor": [-2.0, 0.0], "stiffness": 50.0, "damping": 2.0},
    "body_spring_rest": {"type": "spring", "body_a": "a", "point_a": [-0.3, 0.1], "body_b": "b",
                         "point_b": [0.1, -0.2], "stiffness": 25.0, "rest_length": 1.0,
                         "damping": 0.3},
    "body_spring_zero": {"type": "spring", "body_a": "b", "body_b": "c", "stiffness": 10.0,
                         "damping": 0.4},
    "linear_drag_cm": {"type": "linear_drag", "coefficient": 0.4},
    "quadratic_drag_cm": {"type": "quadratic_drag", "bodies": ["b", "c"], "coefficient": 0.3},
    "linear_drag_point": {"type": "linear_drag", "bodies": ["a"], "coefficient": 0.9,
                          "point": "tip"},
    "quadratic_drag_point": {"type": "quadratic_drag", "bodies": ["c"], "coefficient": 0.2,
                             "point": [0.5, 0.5]},
    "angular_damping": {"type": "angular_damping", "bodies": ["a", "b"], "coefficient": 0.05},
    "force_world_cm": {"type": "constant_force", "body": "b", "force": [-1.0, 0.5]},
    "force_world_point": {"type": "constant_force", "body": "a", "force": [0.0, 2.0],
                          "point": [0.4, 0.0]},
    "force_body_cm": {"type": "constant_force", "body": "c", "force": [1.5, -0.5],
                      "axes": "body"},
    "force_body_point": {"type": "constant_force", "body": "c", "force": [3.0, 1.0],
                         "axes": "body", "point": [0.2, -0.4]},
    "torque": {"type": "constant_torque", "body": "b", "torque": 1.5},
}


def scene_of(forces=tuple(FORCES), integrator="semi_implicit_euler", **extra):
    """The three bodies with the named forces: 1 ms steps, publishing every 5 steps."""
    return make_scene({"step": 0.001, "publish_rate": 200.0, "integrator": integrator,
                       "input_timeout": 0.023, "bodies": BODIES,
                       "forces": {name: FORCES[name] for name in forces}, **extra})


def random_states(size, count, seed):
    """(q, v) with positions of a few metres and angles well outside [-pi, pi) too."""
    rng = np.random.default_rng(seed)
    states = []
    for k in range(count):
        q = rng.normal(scale=2.0, size=(size, 3))
        q[:, 2] = rng.uniform(-40.0, 40.0, size)
        if k == 0:
            q[:, 2] = [-math.pi, math.pi, 1e6][:size] + [0.0] * (size - 3)
        v = rng.normal(scale=[1.0, 1.0, 5.0], size=(size, 3))
        states.append((q, v))
    return states


def compiled_model(scene) -> Model:
    model = Model(scene)
    assert model.compiled is not None, "Model(scene) should use the kernel"
    return model


# ----------------------------------------------------------------- 1. accelerations

@pytest.mark.parametrize("forces", [(name,) for name in FORCES] + [tuple(FORCES)],
                         ids=[*FORCES, "all"])
def test_accelerations_of_each_force_term_are_bit_identical(forces):
    scene = scene_of(forces)
    fast, lean = compiled_model(scene), Model(scene, lean=True)
    assert lean.compiled is None
    for q, v in random_states(fast.size, 40, seed=len(forces)):
        expected = lean.accelerations(q, v)
        assert fast.accelerations(q, v).tobytes() == expected.tobytes()
        assert np.isfinite(expected).all()


#: Input rows as Simulation._row builds them: (target, force, torque, axes, owner, point,
#: at_point): the world frame, the target's own axes and point, another body's frame.
INPUT_ROWS = [
    (0, (1.0, -2.0), 0.3, -1, -1, (0.5, 0.5), True),
    (1, (0.5, 0.0), 0.0, 1, 1, (0.1, 0.2), True),
    (2, (-1.0, 1.0), -0.2, 0, 0, (0.3, 0.1), True),
    (1, (0.0, 0.0), 0.7, -1, -1, (0.0, 0.0), True),
    (0, (2.0, 0.5), 0.0, 2, 2, (-0.4, 0.0), True),
]


@pytest.mark.parametrize("forces", [("gravity",), tuple(FORCES), ()],
                         ids=["gravity only (no angles)", "all", "no scene forces"])
def test_accelerations_with_input_wrenches_are_bit_identical(forces):
    """Inputs join the scene's terms; with gravity alone the inputs are what needs the
    bodies' angles, so the kernel must be told (``oriented``) when they arrive."""
    scene = scene_of(forces)
    fast, lean = compiled_model(scene), Model(scene, lean=True)
    for rows in (INPUT_ROWS, INPUT_ROWS[:1], INPUT_ROWS[1:2], INPUT_ROWS[2:3]):
        fast.inputs = wrench_term(rows)
        lean.inputs = wrench_term(rows)
        assert fast.oriented == lean.oriented
        for q, v in random_states(fast.size, 15, seed=len(rows)):
            assert fast.accelerations(q, v).tobytes() == lean.accelerations(q, v).tobytes()
    fast.inputs = lean.inputs = None
    for q, v in random_states(fast.size, 5, seed=99):
        assert fast.accelerations(q, v).tobytes() == lean.accelerations(q, v).tobytes()


def test_new_input_values_in_place_give_the_bits_of_a_new_program():
    """A term of new values at the same places (``with_values``, a drive's control
    instant) updates the kernel's inputs program in place: the same program object, and
    the accelerations of a program packed anew and of the plain-float sums."""
    scene = scene_of(tuple(FORCES))
    fast, lean = compiled_model(scene), Model(scene, lean=True)
    fast.inputs = lean.inputs = wrench_term(INPUT_ROWS)
    program = fast.compiled.inputs
    for k in range(3):
        rows = [WrenchRow(body, (fx * (k - 1.5), fy + k), torque * k, axes, owner, point, at)
                for body, (fx, fy), torque, axes, owner, point, at in INPUT_ROWS]
        fast.inputs = fast.inputs.with_values(rows)
        lean.inputs = wrench_term(rows)
        assert fast.compiled.inputs is program
        for q, v in random_states(fast.size, 5, seed=k):
            assert fast.accelerations(q, v).tobytes() == lean.accelerations(q, v).tobytes()
    fast.inputs = wrench_term(INPUT_ROWS[:2])  # other places: a new program
    assert fast.compiled.inputs is not program


def test_the_binding_refuses_input_values_it_cannot_take_whole(ext, program):
    """wrench_values takes 3 floats a row of a program of one wrench term, by name, and
    leaves the program as it was where it refuses them."""
    inputs = ext.program(2, None, [(7, np.array([[0, -1, -1, 0], [1, -1, -1, 0]], np.int64),
                                    np.array([[1.0, 2.0, 3.0, 0.0, 0.0],
                                              [4.0, 5.0, 6.0, 0.0, 0.0]]))])
    q, v, out = np.zeros(6), np.zeros(6), np.empty(6)
    ext.wrench_values(inputs, values=[-1.0, 0.5, 2.0, 0.0, -0.0, 7.0])
    ext.accelerations(program, inputs, False, q, v, out)
    assert out.tolist() == [-1.0, 0.5 - 9.81, 2.0, 0.0, 0.0, 7.0]  # gravity on body 0
    for values, error, message in (([1.0] * 5, ValueError, "a list of 6 floats"),
                                   ((1.0,) * 6, ValueError, "a list of 6 floats"),
                                   ([1.0] * 5 + ["x"], TypeError, "must be real number")):
        with pytest.raises(error, match=message):
            ext.wrench_values(inputs, values=values)
    with pytest.raises(ValueError, match="one wrench term"):
        ext.wrench_values(program, values=[])
    with pytest.raises(TypeError, match="unexpected keyword argument 'value'"):
        ext.wrench_values(inputs, value=[1.0] * 6)
    ext.accelerations(program, inputs, False, q, v, out)
    assert out.tolist() == [-1.0, 0.5 - 9.81, 2.0, 0.0, 0.0, 7.0]  # gravity on body 0


def test_no_active_terms_give_zeros():
    scene = scene_of(())
    fast, lean = compiled_model(scene), Model(scene, lean=True)
    assert fast.terms == ()
    for q, v in random_states(fast.size, 3, seed=5):
        a = fast.accelerations(q, v)
        assert a.tobytes() == lean.accelerations(q, v).tobytes() == np.zeros((3, 3)).tobytes()


def test_spring_ends_that_coincide_give_no_spring_force():
    """Springs with a rest length whose ends meet (at points off the CMs: angle 0 makes
    the offsets exact, so d is exactly zero) have no direction and give no force, damped or
    not; the zero-rest-length spring between the same points gives -c dv only."""
    scene = make_scene({"bodies": {
        "p": {"shape": "circle", "radius": 0.1, "mass": 1.0},
        "r": {"shape": "circle", "radius": 0.1, "mass": 2.0, "position": [0.5, 0.0]}},
        "forces": {
            "anchored": {"type": "spring", "body_a": "p", "point_a": [0.25, 0.0],
                         "anchor": [0.25, 0.0], "stiffness": 100.0, "rest_length": 0.5,
                         "damping": 3.0},
            "joined": {"type": "spring", "body_a": "p", "point_a": [0.25, 0.0], "body_b": "r",
                       "point_b": [-0.25, 0.0], "stiffness": 70.0, "rest_length": 0.2,
                       "damping": 1.0}}})
    fast, lean = compiled_model(scene), Model(scene, lean=True)
    q = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])
    v = np.array([[1.0, 2.0, 0.0], [-1.0, 0.5, 0.0]])
    a = fast.accelerations(q, v)
    assert a.tobytes() == lean.accelerations(q, v).tobytes()
    assert a.tobytes() == np.zeros((2, 3)).tobytes()


@pytest.mark.parametrize("scale, coefficient", [(1e-170, 0.3), (1e160, 1e-20)],
                         ids=["squares underflow", "squares overflow"])
def test_lengths_whose_squares_leave_the_range_agree_within_a_few_ulps(scale, coefficient):
    """Spring vectors and drag velocities of ~1e-170 (squares below the smallest normal
    double) or ~1e160 (squares above the largest): both paths take hypot, C's and Python's,
    which may differ by an ulp; so within 8 ulps of the largest acceleration, not bits."""
    scene = make_scene({"bodies": {
        "p": {"shape": "circle", "radius": 0.1, "mass": 1.0},
        "r": {"shape": "box", "size": [1.0, 0.5], "mass": 2.0}},
        "forces": {
            "anchored": {"type": "spring", "body_a": "p", "anchor": [0.0, 0.0],
                         "stiffness": 100.0, "rest_length": 0.5, "damping": 3.0},
            "joined": {"type": "spring", "body_a": "p", "body_b": "r", "stiffness": 70.0,
                       "rest_length": 0.2, "damping": 1.0},
            "drag": {"type": "quadratic_drag", "bodies": ["p"], "coefficient": coefficient},
            "wake": {"type": "quadratic_drag", "bodies": ["r"], "coefficient": coefficient,
                     "point": [0.5, 0.25]}}})
    fast, lean = compiled_model(scene), Model(scene, lean=True)
    rng = np.random.default_rng(7)
    for _ in range(300):
        q = rng.normal(size=(2, 3)) * [scale, scale, 1.0]
        q[:, 2] = rng.uniform(-10.0, 10.0, 2)
        v = rng.normal(size=(2, 3)) * scale
        d = q[0, :2] - q[1, :2]
        for x, y in (q[0, :2].tolist(), d.tolist(), v[0, :2].tolist()):  # hypot's branch
            assert not np.finfo(float).tiny <= x * x + y * y <= np.finfo(float).max
        expected = lean.accelerations(q, v)
        got = fast.accelerations(q, v)
        assert np.isfinite(expected).all() and np.abs(expected).max() > 0.0
        np.testing.assert_allclose(got, expected, rtol=0.0,
                                   atol=8 * EPS * float(np.abs(expected).max()))


# ----------------------------------------------------------------- helpers for runs

def both_paths(scene, start_ns=0):
    """A simulation stepping in the kernel and one on the plain-float Python path."""
    fast = Simulation(scene, start_ns=start_ns)
    assert fast.model.compiled is not None and fast._compiled is not None
    slow = Simulation(scene, start_ns=start_ns)
    slow.model.use_python(True)
    return fast, slow


def state_bytes(sim) -> bytes:
    return sim.q.tobytes() + sim.v.tobytes()


def snapshot_rows(snapshots) -> np.ndarray:
    return np.array([[s.time_ns, s.steps, s.energy] +
                     [x for b in s.bodies for x in (*b.position, b.angle, *b.linear_velocity,
                                                    b.angular_velocity)]
                     for s in snapshots], dtype=float)


def snapshot_bytes(snapshots) -> bytes:
    return snapshot_rows(snapshots).tobytes() + np.array(
        [(s.time_ns, s.steps) for s in snapshots], dtype=np.int64).tobytes()


def assert_identical(fast, slow, fast_snapshots, slow_snapshots):
    """The two runs are the same to the bit: snapshots, state, clock, counters."""
    assert len(fast_snapshots) == len(slow_snapshots)
    assert fast_snapshots == slow_snapshots
    assert snapshot_bytes(fast_snapshots) == snapshot_bytes(slow_snapshots)
    assert state_bytes(fast) == state_bytes(slow)
    assert (fast.time_ns, fast.steps) == (slow.time_ns, slow.steps)
    assert fast.integrator.counters == slow.integrator.counters


def assert_refused_alike(fast, slow, end):
    """The stiff spring (omega = 1000 rad/s, undamped) with 1 ms explicit Euler steps:
    each step multiplies the energy by 1 + (omega h)^2 = 2, so at the first publish instant
    (20 steps, one kernel chunk) it is 2^20 times the initial energy, over GROWTH times the
    energy bound (no force does work, so the bound is the initial energy). Both paths
    refuse that state alike and go back to the initial one."""
    outcomes = []
    for sim in (fast, slow):
        with pytest.raises(DivergenceError) as caught:
            sim.advance_to(end)
        outcomes.append((str(caught.value), sim._bound.worst_ratio, state_bytes(sim),
                         sim.time_ns, sim.steps, sim.integrator.counters))
    assert outcomes[0] == outcomes[1]
    # The refused state's energy over the limit, B_20 / (GROWTH B_0): equal to the bit on
    # both paths above, and 2^20 / GROWTH to the rounding of 20 steps.
    assert outcomes[0][1] == pytest.approx(2.0 ** 20 / GROWTH, rel=1e-12)
    assert "energy" in outcomes[0][0] and fast.time_ns == 0 and fast.steps == 0
    assert state_bytes(fast) == state_bytes(Simulation(fast.scene))


def spy_on_chunks(sim, runs: list | None = None) -> list[tuple[int, int]]:
    """Record (steps asked, steps taken) of each chunk of the kernel's stepping: of each
    call of ``advance``, and of each run of steps from one publish instant to the next
    inside a call of ``run`` (which ``runs``, if given, records as (first, per, steps))."""
    calls = []
    advance, run = sim._compiled.advance, sim._compiled.run

    def spy(q, v, h, steps, *settings):
        done = advance(q, v, h, steps, *settings)
        calls.append((steps, kernel.Advanced(*done).taken))
        return done

    def spy_run(q, v, qs, vs, first, steps, *settings):
        done = run(q, v, qs, vs, first, steps, *settings)
        per = sim._per_publish
        if runs is not None:
            runs.append((first, per, steps))
        left, end = done[0][1], 0
        while end < steps:
            asked = min(first if end == 0 else per, steps - end)
            calls.append((asked, min(asked, left)))
            left -= min(asked, left)
            end += asked
        return done

    sim._compiled.advance = spy
    sim._compiled.run = spy_run
    return calls


# ----------------------------------------------------------------- 2. whole runs

BENCH = ("free_spin", "harmonic", "spring_pendulum", "two_bodies", "stiff")


@pytest.mark.parametrize("method", FIXED)
@pytest.mark.parametrize("name", BENCH)
def test_fixed_step_runs_of_the_bench_scenes_are_bit_identical(name, method):
    scene = configure(bench_scene(name), method, 0.001)
    fast, slow = both_paths(scene)
    chunks = spy_on_chunks(fast)
    end = 250 * scene.step_ns
    if (name, method) == ("stiff", "explicit_euler"):
        assert_refused_alike(fast, slow, end)
        return
    assert_identical(fast, slow, fast.advance_to(end), slow.advance_to(end))
    assert fast.steps == 250 and max(asked for asked, _ in chunks) == 20  # whole periods
    assert np.isfinite(fast.q).all()


@pytest.mark.parametrize("method", FIXED)
@pytest.mark.parametrize("n", [1, 3, LEAN_BODIES + 8])
def test_fixed_step_runs_of_rings_are_bit_identical(n, method):
    """Above LEAN_BODIES Python defaults to numpy; the kernel repeats the plain-float
    path, which ``use_python(True)`` picks at any size."""
    scene = configure(ring(n), method, 0.001)
    fast, slow = both_paths(scene)
    assert fast.model.lean == (n <= LEAN_BODIES)
    end = 60 * scene.step_ns
    assert_identical(fast, slow, fast.advance_to(end), slow.advance_to(end))


def adaptive_bound(sim, snapshots) -> float:
    """32 eps per accepted sub-step, of the largest component seen (see the docstring)."""
    rows = snapshot_rows(snapshots)[:, 3:]
    scale = max(1.0, float(np.abs(rows).max()), float(np.abs(sim.q).max()),
                float(np.abs(sim.v).max()))
    return 32.0 * EPS * sim.integrator.counters.substeps * scale


def angle_aware_difference(a: np.ndarray, b: np.ndarray, angles) -> np.ndarray:
    difference = a - b
    difference[..., angles] = np.remainder(difference[..., angles] + math.pi,
                                           2.0 * math.pi) - math.pi
    return np.abs(difference)


@pytest.mark.parametrize("method", ADAPTIVE)
@pytest.mark.parametrize("name, steps", [("free_spin", 200), ("harmonic", 200),
                                         ("spring_pendulum", 200), ("two_bodies", 200),
                                         ("stiff", 30), ("ring3", 100)])
def test_adaptive_runs_agree_to_rounding_with_the_same_counts(name, steps, method):
    """10 ms steps at a tolerance of 1e-10: several sub-steps a step, some refused. The
    carried sub-step size follows the error estimate, a sum that cancels down to the
    tolerance's size, so its relative rounding is about eps / tolerance (1e-6; measured up
    to 8e-7), damped by the power 1 / (error order + 1): 1e-4 relative."""
    base = ring(3) if name == "ring3" else bench_scene(name)
    scene = configure(base, method, 0.01, tolerance=1e-10)
    fast, slow = both_paths(scene)
    end = steps * scene.step_ns
    fast_snapshots, slow_snapshots = fast.advance_to(end), slow.advance_to(end)
    assert (fast.time_ns, fast.steps) == (slow.time_ns, slow.steps) == (end, steps)
    assert fast.integrator.counters == slow.integrator.counters
    assert fast.integrator.counters.substeps >= steps
    assert [(s.time_ns, s.steps) for s in fast_snapshots] == \
        [(s.time_ns, s.steps) for s in slow_snapshots]
    bound = adaptive_bound(slow, slow_snapshots)
    n = fast.model.size
    rows = angle_aware_difference(snapshot_rows(fast_snapshots)[:, 3:],
                                  snapshot_rows(slow_snapshots)[:, 3:],
                                  [6 * i + 2 for i in range(n)])
    state = angle_aware_difference(np.concatenate([fast.q, fast.v]),
                                   np.concatenate([slow.q, slow.v]), [2])
    assert rows.max() <= bound and state.max() <= bound, (rows.max(), state.max(), bound)
    assert fast.integrator.substep_size == pytest.approx(slow.integrator.substep_size,
                                                         rel=1e-4)


def test_evaluation_only_uses_give_the_same_bits():
    """Where the kernel does not step (implicit methods), Python steps on the kernel's
    accelerations, which are the plain-float bits; where it steps with a contact pass
    (src/kernel/contact.h), the pass repeats Python's: the runs stay identical."""
    for scene, steps in ((scene_of(integrator="implicit_midpoint"), False),
                         (scene_of(integrator="rk4", walls={"floor": {"point": [0.0, -1.0],
                                                                      "normal": [0.0, 1.0]}}),
                          True)):
        fast, slow = Simulation(scene), Simulation(scene)
        slow.model.use_python(True)
        assert fast.model.compiled is not None and (fast._compiled is not None) == steps
        end = 40 * MS
        assert_identical(fast, slow, fast.advance_to(end), slow.advance_to(end))


# ----------------------------------------------------------------- 3. chunking

#: Stamps relative to the start: mid-step and mid-period starts, a duration ending between
#: publish instants, the input timeout (23 ms) ending others, a replacement (same body and
#: source), inputs in every frame, two changes at the same instant.
COMMANDS = (
    WrenchCommand(2_500_000, "a", "joy", "world", (0.5, 0.5), (1.0, -2.0), 0.3),
    WrenchCommand(7 * MS, "b", "pad", "b", (0.1, 0.2), (0.5, 0.0), 0.0, 11_300_000),
    WrenchCommand(12 * MS, "a", "joy", "a/tip", (0.0, 0.0), (0.0, 3.0), 0.1),
    WrenchCommand(12 * MS, "c", "tug", "a/tip", (0.0, 0.1), (-1.0, 1.0), -0.2, 3 * MS),
    WrenchCommand(41_700_001, "b", "motor", "world", (0.0, 0.0), (0.0, 0.0), 0.8),
    WrenchCommand(52 * MS, "c", "tug", "c", (0.2, 0.0), (0.0, -4.0), 0.0, 9 * MS),
)
UNTIL = 90 * MS


def push_all(sim, commands=COMMANDS):
    for command in commands:
        sim.push(dataclasses.replace(command, stamp_ns=sim.start_ns + command.stamp_ns))


def run_played(sim):
    return sim.play(COMMANDS, UNTIL)


def run_pushed(sim):
    push_all(sim)
    return sim.advance_to(sim.start_ns + UNTIL)


def run_max_steps(sim):
    push_all(sim)
    snapshots = []
    while sim.time_ns + sim.step_ns <= sim.start_ns + UNTIL:
        snapshots += sim.advance_to(sim.start_ns + UNTIL, max_steps=7)
    return snapshots


def run_stepped(sim):
    push_all(sim)
    snapshots = []
    while sim.time_ns < sim.start_ns + UNTIL:
        sim.step()
        snapshots.append(sim.snapshot())
    return snapshots


RUNS = {"play": run_played, "pushed": run_pushed, "max_steps": run_max_steps,
        "step": run_stepped}


@pytest.mark.parametrize("start_ns", [0, 1_234_567])
@pytest.mark.parametrize("method", FIXED)
def test_chunked_runs_with_inputs_are_bit_identical(method, start_ns):
    scene = scene_of(integrator=method)
    assert scene.publish_period_ns == 5 * scene.step_ns
    finals = set()
    for name, run in RUNS.items():
        fast, slow = both_paths(scene, start_ns)
        chunks = spy_on_chunks(fast)
        assert_identical(fast, slow, run(fast), run(slow))
        assert fast.time_ns == start_ns + UNTIL and fast.steps == 90
        assert all(asked == taken for asked, taken in chunks)
        assert sum(taken for _, taken in chunks) == 90
        if name in ("play", "pushed"):
            sizes = {asked for asked, _ in chunks}
            assert max(sizes) == 5 and sizes & {1, 2, 3, 4}  # periods, cut by inputs
        finals.add(state_bytes(fast))
    assert len(finals) == 1  # however the run was cut, the same bits


def test_a_publish_period_that_is_not_whole_steps_runs_one_step_at_a_time():
    scene = dataclasses.replace(scene_of(integrator="rk4"), publish_period_ns=2_500_000)
    fast, slow = both_paths(scene)
    chunks = spy_on_chunks(fast)
    assert_identical(fast, slow, run_pushed(fast), run_pushed(slow))
    assert {asked for asked, _ in chunks} == {1}
    assert [s.time_ns for s in run_pushed(Simulation(scene))][:2] == [5 * MS, 10 * MS]


def test_inputs_without_a_timeout_and_without_commands():
    """No timeout: a command holds to the end; no commands: one chunk per period."""
    scene = scene_of(integrator="velocity_verlet", input_timeout=0.0)
    for commands in (COMMANDS[:1], ()):
        fast, slow = both_paths(scene)
        chunks = spy_on_chunks(fast)
        assert_identical(fast, slow, fast.play(commands, UNTIL), slow.play(commands, UNTIL))
        assert fast.steps == 90
        if not commands:
            assert [asked for asked, _ in chunks] == [5] * 18


def test_repeated_compiled_runs_are_bit_identical():
    scene = scene_of(integrator="rk4")
    runs = []
    for _ in range(2):
        sim = Simulation(scene)
        snapshots = run_played(sim)
        runs.append((state_bytes(sim), snapshot_bytes(snapshots), sim.integrator.counters))
    assert runs[0] == runs[1]


def one_instant_per_call(sim):
    """The simulation without :meth:`Simulation._run_checked`: one kernel call per publish
    instant, the energy bound checked from Python after each, as before runs of many
    instants took one call."""
    sim._run_checked = lambda limit, snapshots: 0
    return sim


def bound_bytes(sim) -> bytes:
    return sim._bound._budget.tobytes() + np.float64(sim._bound.worst_ratio).tobytes()


#: Scenes whose runs go through many publish instants in one kernel call: a pyramid of
#: boxes on a floor (contacts), free_spin with RK4 publishing every 0.1 s step and with
#: dopri5 every 0.5 s step, and the three bodies of every force but the constant ones
#: (whose lever arms move, so the bound takes their rates at every check).
RUN_SCENES = {
    "pyramid": lambda: pyramid(3, 0.4),
    "free_spin_rk4": lambda: configure(bench_scene("free_spin"), "rk4", 0.1),
    "free_spin_dopri5": lambda: configure(bench_scene("free_spin"), "dopri5", 0.5, 1e-9),
    "forces": lambda: scene_of([name for name in FORCES if not name.startswith(("force",
                                                                                "torque"))]),
}


@pytest.mark.parametrize("name", RUN_SCENES)
def test_runs_of_many_publish_instants_in_one_call_give_the_same_bits(name):
    """A run whose energy checks take nothing from Python but the state goes through its
    publish instants in one kernel call (``run``), the checks made between the steps, and
    gives the bits of one call per instant with the checks from Python: snapshots, state,
    clock, counters and the bound's budget and worst ratio."""
    scene = RUN_SCENES[name]()
    end = min(scene.duration_ns, 100 * scene.publish_period_ns)
    fast, slow = Simulation(scene), one_instant_per_call(Simulation(scene))
    runs: list = []
    spy_on_chunks(fast, runs)
    assert_identical(fast, slow, fast.advance_to(end), slow.advance_to(end))
    assert bound_bytes(fast) == bound_bytes(slow)
    assert fast._checked[2:] == slow._checked[2:] == (fast.time_ns, fast.steps)
    period = scene.publish_period_ns // scene.step_ns
    assert len(runs) == 1 and runs[0][1] == period and runs[0][2] >= 4 * period


def test_a_blow_up_inside_a_run_stops_where_one_instant_at_a_time_does():
    """A 1e-6 kg disc on a spring too stiff for the step (omega h = 2.05, its energy
    growing about 3.4 times a step), in a collision group with a 1 kg disc 3 m away,
    publishing every step: the energy passes some checks, then one refuses it inside a
    run of many instants. The run stops there alike either way: the same message, state
    (that of the last check passed, not the start's), clock, counters and budget."""
    params = {"integrator": "semi_implicit_euler", "step": 0.001, "publish_rate": 1000.0,
              "bodies": {"spring": {"shape": "circle", "radius": 0.05, "mass": 1e-6,
                                    "velocity": [0.1, 0.0]},
                         "other": {"shape": "circle", "radius": 0.5, "mass": 1.0,
                                   "position": [3.0, 0.0]}},
              "forces": {"hold": {"type": "spring", "body_a": "spring", "anchor": [0.0, 0.0],
                                  "stiffness": 1e-6 * 2050.0 ** 2}},
              "collisions": {"all": {"bodies": ["spring", "other"]}}}
    scene = make_scene(params)
    outcomes = []
    runs: list = []
    for sim in (Simulation(scene), one_instant_per_call(Simulation(scene))):
        if not runs:
            spy_on_chunks(sim, runs)
        with pytest.raises(DivergenceError) as caught:
            sim.advance_to(SEC)
        outcomes.append((str(caught.value), state_bytes(sim), sim.time_ns, sim.steps,
                         sim.integrator.counters, bound_bytes(sim)))
    assert outcomes[0] == outcomes[1]
    assert "spring" in outcomes[0][0] and outcomes[0][3] >= 3
    assert len(runs) == 1 and runs[0][2] > outcomes[0][3] + 1  # refused inside the run


# ----------------------------------------------------------------- 4. failures

@pytest.mark.parametrize("first", [0, 1])
def test_explicit_euler_divergence_keeps_the_same_last_finite_state(first):
    """The stiff spring (omega = 1000 rad/s) with 10 ms explicit Euler steps grows about
    10x a step and overflows after some 300 steps, inside a chunk of the kernel: with
    publish instants 10 s apart no energy check comes first (see the next test). The
    kernel steps between two pairs of buffers, so the failing step is met once on each
    (``first``: steps taken in a call of their own before)."""
    scene = dataclasses.replace(configure(bench_scene("stiff"), "explicit_euler", 0.01),
                                publish_period_ns=10_000 * MS)
    results = []
    for sim in both_paths(scene):
        sim.advance_to(first * scene.step_ns)
        with pytest.raises(DivergenceError) as caught:
            sim.advance_to(10_000 * scene.step_ns)
        assert np.isfinite(sim.q).all() and np.isfinite(sim.v).all()
        results.append((str(caught.value), state_bytes(sim), sim.time_ns, sim.steps,
                        sim.integrator.counters))
        with pytest.raises(DivergenceError):  # refused again, nothing changes
            sim.step()
        assert state_bytes(sim) == results[-1][1]
    assert results[0] == results[1]
    assert "state of mass diverged" in results[0][0] and results[0][3] > 100
    assert "energy" not in results[0][0]  # stopped by the finiteness check


def test_explicit_euler_blow_up_is_refused_by_the_bound_alike_on_both_paths():
    """The same run publishing every 20 ms (2 steps): the energy grows by
    1 + (omega h)^2 = 101 a step, so the first publish instant's state has 101^2 times the
    initial energy, over GROWTH times the bound. Both paths refuse it, keep the initial
    state, and keep refusing."""
    scene = configure(bench_scene("stiff"), "explicit_euler", 0.01)
    results = []
    for sim in both_paths(scene):
        with pytest.raises(DivergenceError) as caught:
            sim.advance_to(10_000 * scene.step_ns)
        results.append((str(caught.value), sim._bound.worst_ratio, state_bytes(sim),
                        sim.time_ns, sim.steps))
        with pytest.raises(DivergenceError) as again:
            sim.step()
        assert str(again.value) == results[-1][0] and state_bytes(sim) == results[-1][2]
    assert results[0] == results[1]
    start = Simulation(scene)  # the ratio leaves out the body's floor, 1 m/s and 1 rad/s
    floor = 0.5 * (start.model.mass[0] + start.model.inertia[0])
    energy = start.snapshot().energy
    assert results[0][1] == pytest.approx((101.0 ** 2 * energy - floor) / (GROWTH * energy),
                                          rel=1e-12)
    assert "state of mass diverged" in results[0][0] and "energy" in results[0][0]
    assert results[0][3:] == (0, 0)


def whipped_box() -> Simulation:
    """A 1 kg unit box on a damped spring (c = 1000 N s/m) at the off-center point (0.5, 0),
    under a torque of 1e308 N m: RK4's first angular acceleration overflows to inf, so its
    third stage has an infinite angle, whose cosine Python's math.cos refuses (C's gives
    NaN)."""
    return Simulation(make_scene({
        "step": 0.01, "integrator": "rk4", "publish_rate": 100.0,
        "bodies": {"m": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}},
        "forces": {"s": {"type": "spring", "body_a": "m", "point_a": [0.5, 0.0],
                         "anchor": [1.0, 0.5], "stiffness": 100.0, "damping": 1000.0},
                   "t": {"type": "constant_torque", "body": "m", "torque": 1e308}}}))


def test_an_infinite_stage_angle_diverges_the_same_way():
    """Both paths report the divergence (not a math domain error) with the same message and
    keep the same finite state."""
    results = []
    for python in (False, True):
        sim = whipped_box()
        if python:
            sim.model.use_python(True)
        with pytest.raises(DivergenceError) as caught:
            sim.step()
        results.append((str(caught.value), state_bytes(sim), sim.time_ns, sim.steps))
    assert results[0] == results[1]
    assert "state of m diverged" in results[0][0]


@pytest.mark.parametrize("switch", ["1", "0"], ids=["kernel", "python"])
def test_fallback_an_infinite_angle_before_the_contact_pass_diverges(switch, monkeypatch):
    """A torque of 1e308 on a box resting on a floor: one step makes its angle infinite, and the
    contact pass (math.cos of the new angle) must not turn that into a ValueError: the step
    raises DivergenceError and keeps the last finite state, with the kernel or without."""
    monkeypatch.setenv(kernel.SWITCH, switch)
    sim = Simulation(make_scene({
        "step": 0.01, "integrator": "semi_implicit_euler", "publish_rate": 100.0,
        "bodies": {"m": {"shape": "box", "size": [0.1, 0.1], "mass": 1.0,
                         "position": [0.0, 0.05]}},
        "forces": {"t": {"type": "constant_torque", "body": "m", "torque": 1e308}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}}}))
    q0 = sim.q.copy()
    with pytest.raises(DivergenceError, match="state of m diverged"):
        sim.step()
    assert sim.steps == 0 and np.array_equal(sim.q, q0)


def test_fallback_an_infinite_stage_angle_diverges_in_python(monkeypatch):
    """With the kernel switched off, an infinite stage angle ends the step with
    DivergenceError, as in the kernel, not with math.cos's ValueError."""
    monkeypatch.setenv(kernel.SWITCH, "0")
    sim = whipped_box()
    assert sim.model.compiled is None
    with pytest.raises(DivergenceError, match="state of m diverged"):
        sim.step()
    assert sim.steps == 0 and np.isfinite(sim.q).all()


@pytest.mark.parametrize("method", ADAPTIVE)
def test_an_underflowing_sub_step_fails_the_same_way(method):
    """A tolerance of 1e-300 can never be met: the sub-step shrinks below 1e-14 h."""
    scene = configure(bench_scene("stiff"), method, 0.001, tolerance=1e-300)
    results = []
    for sim in both_paths(scene):
        with pytest.raises(DivergenceError) as caught:
            sim.advance_to(10 * scene.step_ns)
        results.append((str(caught.value), state_bytes(sim), sim.time_ns, sim.steps,
                        sim.integrator.counters))
    assert results[0] == results[1]
    assert f"{method}: the sub-step size underflowed" in results[0][0]
    assert results[0][2:4] == (0, 0)


def test_too_many_sub_steps_fail_the_same_way():
    """dopri5 at 1e-13 on the stiff spring needs some 60 000 sub-steps a second: a step
    of 2 s passes MAX_SUBSTEPS (Python's loop takes a few seconds to get there)."""
    scene = configure(bench_scene("stiff"), "dopri5", 1.0, tolerance=1e-13)
    results = []
    for sim in both_paths(scene):
        with pytest.raises(DivergenceError) as caught:
            sim.step()
        counters = sim.integrator.counters
        assert counters.substeps + counters.rejected == EmbeddedRungeKutta.MAX_SUBSTEPS
        results.append((str(caught.value), state_bytes(sim), sim.time_ns, sim.steps, counters))
    assert results[0] == results[1]
    assert f"more than {EmbeddedRungeKutta.MAX_SUBSTEPS} sub-steps" in results[0][0]


def test_the_kernel_has_python_s_limit_of_sub_steps(ext):
    assert ext.MAX_SUBSTEPS == EmbeddedRungeKutta.MAX_SUBSTEPS


# ----------------------------------------------------------------- 5. the binding

def _gravity(body=0):
    return (1, np.array([[body]], dtype=np.int64), np.array([[0.0, -9.81]]))


@pytest.fixture
def program(ext):
    return ext.program(2, np.ones(6), [_gravity()])


@pytest.mark.parametrize("term, error, message", [
    ((99, np.zeros((1, 1), np.int64), np.zeros((1, 2))), ValueError, "unknown term kind 99"),
    ((0, np.zeros((1, 1), np.int64), np.zeros((1, 2))), ValueError, "unknown term kind 0"),
    ((1, np.zeros((1, 1), np.int32), np.zeros((1, 2))), TypeError, "term ints: expected int64"),
    ((1, np.zeros((1, 1), np.uint64), np.zeros((1, 2))), TypeError, "term ints: expected int64"),
    ((1, np.zeros((1, 1)), np.zeros((1, 2))), TypeError, "term ints: expected int64"),
    ((1, np.zeros((1, 1), np.int64), np.zeros((1, 2), np.float32)), TypeError,
     "term reals: expected float64"),
    ((1, np.zeros((1, 1), np.int64), np.zeros((1, 3))), ValueError,
     "term reals: expected 2 values, got 3"),
    ((1, np.zeros((2, 1), np.int64), np.zeros((1, 2))), ValueError,
     "term reals: expected 4 values, got 2"),
    ((3, np.zeros(3, np.int64), np.zeros((1, 7))), ValueError, "not a whole number of rows"),
    ((1, np.zeros((4, 2), np.int64)[:, 0], np.zeros((4, 2))), ValueError, "not C-contiguous"),
    ((1, np.array([[2]], np.int64), np.zeros((1, 2))), ValueError, "out of range for 2 bodies"),
    ((1, np.array([[-1]], np.int64), np.zeros((1, 2))), ValueError, "out of range"),
    ((3, np.array([[0, 2]], np.int64), np.zeros((1, 7))), ValueError, "out of range"),
    ((7, np.array([[0, 2, -1, 1]], np.int64), np.zeros((1, 5))), ValueError, "out of range"),
    ((7, np.array([[0, -1, -2, 1]], np.int64), np.zeros((1, 5))), ValueError, "out of range"),
    ((1, np.zeros((1, 1), np.int64)), TypeError, "a term is"),
    ([1, np.zeros((1, 1), np.int64), np.zeros((1, 2))], TypeError, "a term is"),
])
def test_the_binding_refuses_bad_terms(ext, term, error, message):
    with pytest.raises(error, match=message):
        ext.program(2, np.ones(6), [_gravity(), term])


def test_the_binding_refuses_bad_programs(ext):
    with pytest.raises(ValueError, match="expected 6 values, got 5"):
        ext.program(2, np.ones(5), [])
    with pytest.raises(TypeError, match="inverse_mass: expected float64"):
        ext.program(2, np.ones(6, np.float32), [])
    with pytest.raises(ValueError, match="must not be negative"):
        ext.program(-1, None, [])
    with pytest.raises(TypeError, match="not iterable"):
        ext.program(2, np.ones(6), 5)
    # 3 N values of 8 bytes must fit a Py_ssize_t: a count past that would wrap around.
    for bodies in (2 ** 62 + 1, 2 ** 61):
        with pytest.raises(ValueError, match="too many bodies"):
            ext.program(bodies, np.ones(3), [_gravity(10 ** 9)])
        with pytest.raises(ValueError, match="too many bodies"):
            ext.program(bodies, None, [])


def test_the_binding_reads_a_copy_of_the_terms(ext):
    """A term whose kind empties the list while it is read (through __index__) cannot pull
    the terms from under the reader: the program is built from a tuple of them taken first."""
    terms = []

    class Emptying:
        def __index__(self):
            terms.clear()
            return 1

    terms.append((Emptying(), np.array([[0]], np.int64), np.array([[0.0, -9.81]])))
    terms.append(_gravity())
    program = ext.program(2, np.ones(6), terms)
    out = np.empty(6)
    ext.accelerations(program, None, False, np.zeros(6), np.zeros(6), out)
    assert out.tolist() == [0.0, -2 * 9.81, 0.0, 0.0, 0.0, 0.0]


def test_the_binding_refuses_pairs_of_absurd_size(ext):
    for slopes in (1, 65, 2 ** 61):
        with pytest.raises(ValueError, match="2 to 64 slopes"):
            ext.pair(slopes, np.ones(2), np.ones(2), 1)


def test_the_binding_refuses_bad_arrays(ext, program):
    q, v, out = np.zeros(6), np.zeros(6), np.empty(6)
    ext.accelerations(program, None, False, q, v, out)
    assert out.tolist() == [0.0, -9.81, 0.0, 0.0, 0.0, 0.0]
    read_only = np.empty(6)
    read_only.flags.writeable = False
    strided = np.zeros(12)[::2]
    numpy_refusals = (ValueError, BufferError)
    cases = [
        ((q[:5].copy(), v, out), ValueError, "q: expected 6 values, got 5"),
        ((q, np.zeros(7), out), ValueError, "v: expected 6 values, got 7"),
        ((q, v, np.empty(3)), ValueError, "out: expected 6 values, got 3"),
        ((q.astype(np.float32), v, out), TypeError, "q: expected float64"),
        ((q, v.astype(np.int64), out), TypeError, "v: expected float64"),
        ((strided, v, out), numpy_refusals, "contiguous"),
        ((q, v, strided), numpy_refusals, "contiguous"),
        ((np.zeros((3, 2)).T, v, out), numpy_refusals, "contiguous"),
        ((q, v, read_only), numpy_refusals, "read-only"),
        (([0.0] * 6, v, out), TypeError, None),  # no buffer
    ]
    for arrays, error, message in cases:
        with pytest.raises(error, match=message):
            ext.accelerations(program, None, False, *arrays)
    stepper = ext.stepper(program, 0, None, 0.0, None)
    for k, name in enumerate(("q", "v")):
        arrays = [np.zeros(6), np.zeros(6)]
        for bad, error, message in ((read_only, numpy_refusals, "read-only"),
                                    (strided, numpy_refusals, "contiguous"),
                                    (np.zeros(5), ValueError, f"{name}: expected 6 values"),
                                    (np.zeros(6, np.float32), TypeError, f"{name}: expected")):
            arrays[k] = bad
            with pytest.raises(error, match=message):
                ext.step(stepper, None, False, *arrays, 0.001, 3, 0.0, None)
            with pytest.raises(error, match=message):
                ext.failed_state(stepper, *arrays)
    with pytest.raises(TypeError, match="missing required argument 'size'"):
        ext.step(stepper, None, False, np.zeros(6), np.zeros(6), 0.001, 3)


def test_the_binding_refuses_mismatched_programs_methods_and_pairs(ext, program):
    q, v, out = np.zeros(6), np.zeros(6), np.empty(6)
    other = ext.program(3, None, [])
    inputs = ext.program(2, None, [(7, np.array([[0, -1, -1, 0]], np.int64),
                                    np.array([[1.0, 2.0, 3.0, 0.0, 0.0]]))])
    with pytest.raises(ValueError, match="inputs: a program for other bodies"):
        ext.accelerations(program, other, False, q, v, out)
    with pytest.raises(TypeError, match="a program with masses is needed"):
        ext.accelerations(inputs, None, False, q, v, out)
    with pytest.raises(ValueError):
        ext.accelerations(5, None, False, q, v, out)
    pair = ext.pair(2, np.array([0.0, 1.0]), np.array([1.0, -1.0]), 1)
    with pytest.raises(ValueError):
        ext.accelerations(pair, None, False, q, v, out)
    ext.accelerations(program, inputs, False, q, v, out)
    assert out.tolist() == [1.0, 2.0 - 9.81, 3.0, 0.0, 0.0, 0.0]

    def advance(method, pair=None, inputs=None):
        stepper = ext.stepper(program, method, pair, 1e-6, None)
        return ext.step(stepper, inputs, False, np.zeros(6), np.zeros(6), 0.001, 3, math.inf,
                        None)

    assert advance(0)[:3] == (0, 3, 3)
    assert advance(4, pair)[:2] == (0, 3)
    for method in (-1, 5, 99):
        with pytest.raises(ValueError, match=f"unknown method {method}"):
            advance(method)
    with pytest.raises(ValueError, match="inputs: a program for other bodies"):
        advance(0, inputs=other)
    with pytest.raises(ValueError):
        advance(4)  # the embedded method without a pair
    with pytest.raises(ValueError):
        advance(4, program)  # a program is no pair
    for args, message in (((3, np.zeros(5), np.zeros(3), 2), "a: expected 6 values, got 5"),
                          ((3, np.zeros(7), np.zeros(3), 2), "a: expected 6 values, got 7"),
                          ((3, np.zeros(6, np.float32), np.zeros(3), 2), "a: expected float64"),
                          ((2, np.zeros(2), np.zeros(6), 2), "1 or 2 rows"),
                          ((2, np.zeros(2), np.zeros(3), 2), "1 or 2 rows"),
                          ((2, np.zeros(2), np.zeros(0), 2), "1 or 2 rows"),
                          ((1, np.zeros(0), np.zeros(1), 2), "2 to 64 slopes")):
        with pytest.raises((ValueError, TypeError), match=message):
            ext.pair(*args)


def test_the_binding_s_runs_check_their_arrays_and_segments(ext, program):
    """``run`` takes (first + whole periods) in rows of its own: 10 steps from 1 to the
    first instant, then every 4, are 4 rows (1, 4, 4, 1 steps); the rows' state, the
    bound's statics, units and budget are checked against the bodies, and a segment of
    no step is refused."""
    statics, unit = np.ones(6), np.zeros(2, np.int64)

    def run(rows=4, first=1, per=4, steps=10, statics=statics, unit=unit, budget=None,
            inputs=None):
        stepper = ext.stepper(program, 0, None, 0.0, None, h=0.001, per=per,
                              period_seconds=0.004, springs=None, statics=statics, unit=unit,
                              budget=np.zeros(BUDGET_ROWS) if budget is None else budget,
                              growth=1000.0)
        qs, vs = np.zeros((2, rows, 2, 3))
        done = ext.run(stepper, inputs, False, np.zeros(6), np.zeros(6), qs, vs, first, steps,
                       0.0, 0.001)
        return done, qs

    (status, taken, *_, checked, worst), qs = run()
    assert (status, taken, checked) == (0, 10, 3) and worst == 0.0
    # each row the state after 1, 5, 9 and 10 steps, as step() takes them
    q, v = np.zeros(6), np.zeros(6)
    stepper = ext.stepper(program, 0, None, 0.0, None)
    for row, steps in enumerate((1, 4, 4, 1)):
        ext.step(stepper, None, False, q, v, 0.001, steps, 0.0, None)
        assert qs[row].tobytes() == q.tobytes()
    assert q[1] < 0.0  # gravity moved the first body
    for kwargs, error, message in (
            ({"rows": 3}, ValueError, "q: expected 24 values, got 18"),
            ({"first": 0}, ValueError, "first needs at least 1 step"),
            ({"per": 0}, ValueError, "runs need a step h > 0 and per >= 1"),
            ({"statics": np.ones(5)}, ValueError, "statics: expected 6 values"),
            ({"unit": np.zeros(2)}, TypeError, "unit: expected int64"),
            ({"unit": np.ones(2, np.int64)}, ValueError, "unit index is out of range"),
            ({"budget": np.zeros(BUDGET_ROWS - 1)}, ValueError, "whole number of columns"),
            ({"inputs": ext.program(3, None, [])}, ValueError, "a program for other bodies")):
        with pytest.raises(error, match=message):
            run(**kwargs)
    with pytest.raises(TypeError, match=r"run\(\) missing required argument 'q'"):
        ext.run(stepper, None, False)
    with pytest.raises(ValueError, match="built without the energy bound's budget"):
        ext.run(stepper, None, False, np.zeros(6), np.zeros(6), *np.zeros((2, 1, 2, 3)), 1, 1,
                0.0, 0.001)


def test_the_force_binding_takes_its_arguments_by_name(ext):
    """program, pair, accelerations and bound take their arguments by keyword: the
    accelerations by name are those by position, bound's check by name is the one by
    position, and a keyword unknown or missing is refused by name."""
    program = ext.program(bodies=2, inverse_mass=np.array([1.0, 1.0, 2.0, 0.5, 0.5, 4.0]),
                          terms=[_gravity(0), _gravity(1)])
    q, v = np.array([0.0, 1.0, 0.3, 1.0, 0.0, -0.2]), np.array([1.0, 0.0, 2.0, 0.0, 0.5, 1.0])
    named, placed = np.empty(6), np.empty(6)
    ext.accelerations(program, inputs=None, oriented=True, q=q, v=v, out=named)
    ext.accelerations(program, None, True, q, v, placed)
    assert named.tolist() == placed.tolist() == [0.0, -9.81, 0.0, 0.0, -9.81 * 0.5, 0.0]
    assert ext.pair(slopes=2, a=np.array([0.0, 1.0]), error=np.array([1.0, -1.0]),
                    error_order=1) is not None
    statics, unit = np.array([1.0, 2.0, 0.1, 0.2, -1.0, -1.0]), np.zeros(2, np.int64)
    budgets = np.zeros((2, BUDGET_ROWS))
    checks = [ext.bound(None, q=q, v=v, statics=statics, unit=unit, budget=budgets[0],
                        seconds=0.01, growth=10.0),
              ext.bound(None, q, v, statics, unit, budgets[1], 0.01, 10.0)]
    assert checks[0] == checks[1] and budgets[0].tobytes() == budgets[1].tobytes()
    assert budgets[0].any()
    with pytest.raises(TypeError, match="unexpected keyword argument 'outs'"):
        ext.accelerations(program, inputs=None, oriented=True, q=q, v=v, outs=named)
    with pytest.raises(TypeError, match="missing required argument 'out'"):
        ext.accelerations(program, inputs=None, oriented=True, q=q, v=v)
    with pytest.raises(TypeError, match="missing required argument 'budget'"):
        ext.bound(None, q=q, v=v, statics=statics, unit=unit)


def test_the_stepper_binding_takes_its_arguments_by_name(ext, program):
    """stepper, step, run and failed_state take their arguments by keyword: steps by name
    have the bits of steps by position, and a keyword unknown, missing or given twice is
    refused by name."""
    stepper = ext.stepper(program=program, method=ext.RK4, pair=None, tolerance=0.0,
                          contacts=None)
    q, v = np.array([0.0, 1.0, 0.3, 1.0, 0.0, -0.2]), np.array([1.0, 0.0, 2.0, 0.0, 0.5, 1.0])
    named, placed = (q.copy(), v.copy()), (q.copy(), v.copy())
    done = ext.step(stepper, inputs=None, oriented=True, q=named[0], v=named[1], h=0.01,
                    steps=7, size=0.0, joints=None)
    assert done == ext.step(stepper, None, True, *placed, 0.01, 7, 0.0, None)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(named, placed))
    assert not np.array_equal(named[0], q)
    ext.failed_state(stepper=stepper, q=np.zeros(6), v=np.zeros(6))
    qs, vs = np.zeros((2, 1, 2, 3))
    runs = ext.stepper(program=program, method=ext.RK4, pair=None, tolerance=0.0,
                       contacts=None, h=0.001, per=5, period_seconds=0.005, springs=None,
                       statics=np.ones(6), unit=np.zeros(2, np.int64),
                       budget=np.zeros(BUDGET_ROWS), growth=1000.0)
    arguments = dict(inputs=None, oriented=False, q=q, v=v, qs=qs, vs=vs, first=5, steps=5,
                     size=0.0, first_seconds=0.005)
    named = ext.run(runs, **arguments)
    assert named[:2] == (ext.ADVANCED, 5)
    placed = qs.copy()
    assert ext.run(runs, *arguments.values()) == named and qs.tobytes() == placed.tobytes()
    first = arguments.pop("first_seconds")
    with pytest.raises(TypeError, match="unexpected keyword argument 'first_second'"):
        ext.run(runs, **arguments, first_second=first)
    with pytest.raises(TypeError, match="missing required argument 'first_seconds'"):
        ext.run(runs, **arguments)
    with pytest.raises(TypeError, match="multiple values for argument 'q'"):
        ext.run(runs, None, False, q, q=q, v=v, qs=qs, vs=vs, first=5, steps=5, size=0.0,
                first_seconds=first)
    with pytest.raises(TypeError, match="unexpected keyword argument 'h'"):
        ext.run(runs, **arguments, first_seconds=first, h=0.001)
    with pytest.raises(TypeError, match="'period' is an invalid keyword"):
        ext.stepper(program=program, method=ext.RK4, pair=None, tolerance=0.0, contacts=None,
                    period=5)
    with pytest.raises(TypeError, match="multiple values for argument 'q'"):
        ext.step(stepper, None, True, q, v, 0.01, 7, 0.0, None, q=q)
    with pytest.raises(TypeError, match="missing required argument 'tolerance'"):
        ext.stepper(program=program, method=ext.RK4, pair=None, tolerances=0.0,
                    contacts=None)


# ----------------------------------------------------------------- 6. fallback

def test_fallback_switched_off_runs_in_python(monkeypatch):
    monkeypatch.setenv(kernel.SWITCH, "0")
    scene = scene_of(integrator="rk4")
    assert not kernel.enabled()
    assert Model(scene).compiled is None
    sim, reference = Simulation(scene), Simulation(scene)
    assert sim.model.compiled is None and sim._compiled is None
    reference.model.use_python(True)
    assert_identical(sim, reference, run_played(sim), run_played(reference))
    assert sim.steps == 90


def test_fallback_without_the_extension(monkeypatch):
    monkeypatch.setattr(kernel, "_kernel", None)
    monkeypatch.delenv(kernel.SWITCH, raising=False)
    scene = scene_of(integrator="semi_implicit_euler")
    assert not kernel.built() and not kernel.enabled()
    with pytest.raises(RuntimeError, match="not built"):
        Model(scene, compiled=True)
    assert Model(scene).compiled is None
    assert Model(scene, compiled=False).compiled is None
    sim = Simulation(scene)
    assert sim.model.compiled is None and sim._compiled is None
    assert len(run_played(sim)) == 18 and sim.steps == 90


def test_fallback_a_python_path_chosen_explicitly_is_never_compiled():
    scene = scene_of()
    for lean in (True, False):
        assert Model(scene, lean=lean).compiled is None
