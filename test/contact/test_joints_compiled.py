"""The joint pass in the compiled kernel against the Python pass: the same bits.

The kernel repeats contact/joints.py operation for operation (src/kernel/joint.c), the
sparse factorizations of contact/sparse.py included (src/kernel/sparse.c), so scenes with
joints stepped in the kernel and in Python give identical positions, velocities, efforts
and carried state, for every fixed-step method the kernel steps, and for a method stepped
in Python with the kernel's joint pass.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scene_builders import make_scene
from test_joints import chain_scene, gear_scene, pendulum_scene, slider_scene, weld_scenes
from test_sparse import spinning_grid

from hecker_dynamics import Simulation
from hecker_dynamics.contact import joint_solve, joints, sparse
from hecker_dynamics.dynamics import kernel

pytestmark = pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not "
                                "built or HECKER_DYNAMICS_KERNEL=0")


SCENES = {
    "pendulum": lambda method: pendulum_scene(1.0, method=method),
    "chain": lambda method: _method(chain_scene(20), method),
    "limited_chain": lambda method: _limited_chain(method),
    "gears": lambda method: _method(gear_scene(2.0, {"speed": 5.0, "max_torque": 0.3},
                                               {"lower": -1.0, "upper": 1.0}), method),
    "slider": lambda method: _method(slider_scene(lower=-0.1, upper=0.05, motor={
        "speed": 0.5, "max_force": 40.0}), method),
    "weld": lambda method: _method(weld_scenes()[0], method),
    "soft_weld_rope": lambda method: make_scene({
        "step": 0.001, "integrator": method, "publish_rate": 10.0,
        "bodies": {"a": {"shape": "box", "size": [0.4, 0.2], "mass": 1.0},
                   "b": {"shape": "box", "size": [0.4, 0.2], "mass": 1.0,
                         "position": [0.4, 0.0]},
                   "bob": {"shape": "circle", "radius": 0.05, "mass": 0.5,
                           "position": [0.6, -0.3]}},
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"hinge": {"type": "revolute", "body_b": "a", "point_b": [-0.2, 0.0],
                             "spring": {"stiffness": 3.0, "damping": 0.1}},
                   "glue": {"type": "weld", "body_a": "a", "body_b": "b",
                            "point_b": [-0.2, 0.0], "frequency": 4.0, "damping_ratio": 0.3},
                   "rope": {"type": "distance", "body_a": "b", "point_a": [0.2, 0.0],
                            "body_b": "bob", "max_length": 0.45},
                   "rod": {"type": "distance", "body_b": "bob", "point_a": [0.9, 0.0],
                           "length": 0.5}}}),
}


def _method(scene, method):
    """``scene`` with another integrator."""
    return replace(scene, integrator=method)


def _limited_chain(method: str):
    """A chain of 8 plain pins ending in a pin with a limit and a motor: the kernel builds
    the plain pins' rows apart only where every joint is one (a chain of plain pins alone),
    so this one takes the general rows, its plain pins among them."""
    bodies, pins = {}, {}
    for i in range(9):
        bodies[f"l{i}"] = {"shape": "box", "size": [0.1, 0.02], "mass": 0.1,
                           "position": [0.05 + 0.1 * i, 0.0]}
        pins[f"j{i}"] = {"type": "revolute", "body_b": f"l{i}", "point_b": [-0.05, 0.0]}
        if i:
            pins[f"j{i}"].update(body_a=f"l{i - 1}", point_a=[0.05, 0.0])
    pins["j8"].update(lower=-0.3, upper=0.3, motor={"speed": 2.0, "max_torque": 0.05})
    return make_scene({"step": 0.001, "integrator": method, "publish_rate": 10.0,
                       "bodies": bodies, "forces": {"gravity": {"type": "gravity"}},
                       "joints": pins})


def _compare(fast: Simulation, slow: Simulation) -> None:
    assert fast.steps == slow.steps
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    assert fast.model.joints.export_state() == slow.model.joints.export_state()


@pytest.mark.parametrize("method", ["explicit_euler", "semi_implicit_euler",
                                    "velocity_verlet", "rk4"])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_kernel_steps_joint_scenes_with_the_bits_of_python(name, method):
    """0.6 s of each scene: whole steps in the kernel, and steps in Python with the
    Python joint pass, give identical states and joint states."""
    scene = SCENES[name](method)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast._compiled is not None and fast.model.joints.compiled
    assert not slow.model.joints.compiled
    fast.advance_to(600_000_000)
    slow.advance_to(600_000_000)
    _compare(fast, slow)
    assert any(x != 0.0 for x in fast.model.joints.warm)


def test_kernel_refines_a_spinning_grid_with_the_bits_of_python(monkeypatch):
    """A spinning 10 x 10 grid of pins, whose velocity stage refines on the Newton
    matrix's L U in some steps and factors K in others (JointPass.share): 30 steps in the
    kernel and in Python give the same bits."""
    outcomes = []

    def counted(*args):
        x = joint_solve.refine(*args)
        outcomes.append(x is not None)
        return x

    monkeypatch.setattr(joints, "refine", counted)
    scene = spinning_grid(10, 1.0)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast.model.joints.share and fast.model.joints.compiled
    fast.advance_to(30 * scene.step_ns)
    slow.advance_to(30 * scene.step_ns)
    assert any(outcomes) and not all(outcomes)
    _compare(fast, slow)


@pytest.mark.parametrize("name", ["chain", "gears", "slider"])
def test_the_kernels_joint_pass_after_a_python_step_has_the_bits_of_python(name):
    """implicit_midpoint steps in Python; its joint pass runs in C (joints_resolve) or in
    Python: the same bits."""
    scene = SCENES[name]("implicit_midpoint")
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.joints.use_python()
    assert fast._compiled is None and fast.model.joints.compiled
    for _ in range(300):
        fast.step()
        slow.step()
    _compare(fast, slow)


def test_a_motor_command_between_kernel_calls_is_seen_by_the_kernel():
    scene = SCENES["gears"]("velocity_verlet")
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    for sim in (fast, slow):
        sim.advance_to(400_000_000)
        sim.model.joints.motor_speed["axle_a"] = -3.0
        sim.advance_to(900_000_000)
    _compare(fast, slow)
    assert fast.model.joints.efforts["axle_a"] == pytest.approx(-0.3, rel=1e-12)


def test_the_joint_binding_takes_its_per_step_arguments_by_name():
    """joints_resolve and joint_state take their arguments by keyword: the state set by
    name reads back as given, a step resolved by name has the bits of one resolved by
    position from the same state, and a keyword unknown or missing is refused by name."""
    from hecker_dynamics import _kernel

    sim = Simulation(SCENES["chain"]("implicit_midpoint"))
    for _ in range(20):
        sim.step()
    bridge = sim.model.joints._in_kernel()
    capsule, saved = bridge.kernel, np.zeros_like(bridge._state)
    _kernel.joint_state(capsule, state=saved, load=False)
    q0, q1, v1 = sim.q.copy(), sim.q + 1e-4 * sim.v, sim.v.copy()
    by_name, by_position = (q1.copy(), v1.copy()), (q1.copy(), v1.copy())
    assert _kernel.joints_resolve(capsule, bodies=len(q0), q0=q0, q1=by_name[0],
                                  v1=by_name[1], h=1e-4)
    _kernel.joint_state(capsule, state=saved, load=True)
    assert _kernel.joints_resolve(capsule, len(q0), q0, *by_position, 1e-4)
    assert np.array_equal(by_name[0], by_position[0]) and not np.array_equal(by_name[0], q1)
    assert np.array_equal(by_name[1], by_position[1])
    loaded, state = np.arange(saved.size, dtype=np.float64) * 0.25, np.zeros_like(saved)
    loaded[-4] = 1.0  # the flag of set multipliers reads back as 0.0 or 1.0
    loaded[-2:] = 6.0, 2.0  # the parts remembered and the steps since: whole numbers
    _kernel.joint_state(capsule, state=loaded, load=True)
    _kernel.joint_state(capsule, state=state, load=False)
    assert np.array_equal(state, loaded)
    with pytest.raises(TypeError, match="unexpected keyword argument 'v0'"):
        _kernel.joints_resolve(capsule, bodies=len(q0), q0=q0, q1=q1, v0=v1, h=1e-4)
    with pytest.raises(TypeError, match="missing required argument 'h'"):
        _kernel.joints_resolve(capsule, bodies=len(q0), q0=q0, q1=q1, v1=v1)
    with pytest.raises(TypeError, match="missing required argument 'load'"):
        _kernel.joint_state(capsule, state=state)


def test_kernel_has_the_joint_constants():
    k = kernel._kernel
    assert (k.JOINT_TOLERANCE, k.JOINT_CONVERGED, k.JOINT_NEWTON_ITERATIONS,
            k.JOINT_DRIFT_ITERATIONS, k.JOINT_MAX_ITERATIONS, k.JOINT_ROUNDING,
            k.JOINT_MAX_TURN, k.JOINT_MOST_SUBSTEPS, k.JOINT_DEPENDENT, k.JOINT_CHORD,
            k.JOINT_ACTIVE_SETS, k.JOINT_SETTLED_STEPS, k.JOINT_MAX_RING, k.JOINT_RATING_BOUND,
            k.JOINT_REFINEMENTS) == \
        (joints.TOLERANCE, joint_solve.CONVERGED, joints.NEWTON_ITERATIONS,
         joints.DRIFT_ITERATIONS, joint_solve.MAX_ITERATIONS, joints.ROUNDING, joints.MAX_TURN,
         joints.MOST_SUBSTEPS, sparse.DEPENDENT, joints.CHORD, joint_solve.ACTIVE_SETS,
         joints.SETTLED_STEPS, joints.MAX_RING, joints.RATING_BOUND, joint_solve.REFINEMENTS)


def test_a_repeated_pin_is_dropped_and_the_rod_swings_as_on_one_pin():
    """Two pins at the same point of the same body: the second one's rows repeat the
    first's, their pivots vanish and they are dropped (sparse.DEPENDENT), so the rod swings
    as on one pin (to rounding), with the same bits in the kernel and in Python."""
    def rod(pins):
        return make_scene({"step": 0.001, "integrator": "velocity_verlet",
                           "bodies": {"rod": {"shape": "box", "size": [0.05, 1.0], "mass": 1.0,
                                              "position": [0.0, -0.5], "velocity": [0.1, 0.0]}},
                           "forces": {"gravity": {"type": "gravity"}},
                           "joints": {name: {"type": "revolute", "body_b": "rod",
                                             "point_b": [0.0, 0.5]} for name in pins}})
    runs = []
    for pins, python in ((("one", "two"), False), (("one", "two"), True), (("one",), False)):
        sim = Simulation(rod(pins))
        if python:
            sim.model.use_python()
        sim.advance_to(1_000_000_000)
        runs.append(sim)
    _compare(runs[0], runs[1])
    assert np.abs(runs[0].q - runs[2].q).max() < 1e-12
    assert np.abs(runs[0].v - runs[2].v).max() < 1e-11
    assert abs(runs[0].q[0, 2]) > 0.02  # it swung (0.025 rad)


def _grid_and_chain(soft: bool) -> dict[str, object]:
    from hecker_dynamics.bench.joints import chain, grid
    return {"grid": grid(6, soft=soft), "chain": chain(30, 1.0 / 60.0, soft=soft)}


@pytest.mark.parametrize("soft", [False, True])
@pytest.mark.parametrize("name", ["grid", "chain"])
def test_a_run_in_one_step_calls_has_the_bits_of_one_call(name, soft):
    """The joint state stays in the kernel between calls and is read back only when read:
    a run taken one step a call, one taken so while reading the joint state after every
    call, one carried through export_state and import_state halfway (which loads the state
    back into the kernel), and one moved by hand halfway (the pass forgets its warm
    starts) give, at every call's end, the bits of the same run in one call (the last
    moved likewise) and of the Python pass; anything the calls left out of the state
    moved (an angle, a warm start, the Newton multipliers, the step length) shows here."""
    scene = _grid_and_chain(soft)[name]
    steps = 16

    def run(calls: str, python: bool = False, moved: bool = False
            ) -> tuple[Simulation, list[tuple[np.ndarray, np.ndarray]]]:
        sim = Simulation(scene)
        if python:
            sim.model.use_python()
        assert sim.model.joints.compiled != python
        ends = []
        for k in range(steps) if calls != "one" else [steps - 1]:
            end = sim.time_ns + (steps if calls == "one" else 1) * sim.step_ns
            if moved and calls == "one":  # the body moved halfway, as the others move it
                sim.advance_to(sim.time_ns + steps // 2 * sim.step_ns, keep=False)
            if moved and (calls == "one" or k == steps // 2):
                sim.set_body_state(scene.bodies[3].name, (3.1, -0.2), 0.3, (0.5, 0.0), 1.0)
            if calls == "carried" and k == steps // 2:
                sim.import_state(sim.export_state())
            sim.advance_to(end, keep=False)
            if calls == "read":
                sim.model.joints.export_state()
            ends.append((sim.q.copy(), sim.v.copy()))
        return sim, ends

    for moved in (False, True):
        one, [(q, v)] = run("one", moved=moved)
        slow, slow_ends = run("each", python=True, moved=moved)
        _compare(one, slow)
        assert np.array_equal(q, slow_ends[-1][0]) and np.array_equal(v, slow_ends[-1][1])
        for calls in ("each", "read", "carried"):
            fast, ends = run(calls, moved=moved)
            _compare(fast, slow)
            assert all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
                       for a, b in zip(ends, slow_ends))
    assert any(x != 0.0 for x in fast.model.joints.warm)


@pytest.mark.parametrize("method", ["velocity_verlet", "implicit_midpoint"])
def test_the_parts_remembered_carry_across_calls_as_within_one(method):
    """The 200-link chain at h = 1/60 s stalls whole from about 1 s and its steps start in
    the parts remembered: from such a state, steps in one call and in one-step calls
    (reading the joint state after each, which takes the state back from the kernel) give
    the same bits and remember the same, whether the kernel takes whole steps
    (``velocity_verlet``) or the simulation takes them with the kernel's resolve alone
    (``implicit_midpoint``: the simulation keeps the parts)."""
    from hecker_dynamics.bench.joints import chain

    start = Simulation(chain(200, 1.0 / 60.0, 10.0))
    start.advance_to(1_500_000_000, keep=False)
    state = start.export_state()
    assert state["joints"]["parts"][0] > 1
    ends = []
    for calls in (1, 6):
        sim = Simulation(replace(chain(200, 1.0 / 60.0, 10.0), integrator=method))
        sim.import_state(state)
        for _ in range(calls):
            sim.advance_to(sim.time_ns + 6 // calls * sim.step_ns, keep=False)
            if calls > 1:
                sim.model.joints.export_state()
        ends.append(sim)
    _compare(*ends)
    assert (ends[0].model.joints.remembered, ends[0].model.joints.settled_steps) == \
        (ends[1].model.joints.remembered, ends[1].model.joints.settled_steps)
