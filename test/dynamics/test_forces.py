"""The two evaluations of every force term agree: numpy-vectorised and plain-float.

``Model.accelerations`` sums forces with numpy for many bodies and in plain Python floats
for few (``Model.lean``). They are independent implementations of the same formulas, so
holding them equal on random states checks both. They may differ only by rounding: the
sums run in a different order, so the tolerance is a few ulps of the largest term.
"""
from __future__ import annotations

import numpy as np
import pytest
from scene_builders import EVERY_FORCE, make_scene

from hecker_dynamics.dynamics.forces import BodySum
from hecker_dynamics.dynamics.model import LEAN_BODIES, Model
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.geometry.planar import HALF_ANGLE_FROM
from hecker_dynamics.scene.commands import WrenchCommand

COMMANDS = [
    WrenchCommand(0, "a", "world", "world", (0.5, 0.5), (1.0, -2.0), 0.3),
    WrenchCommand(0, "b", "body", "b", (0.1, 0.2), (0.5, 0.0), 0.0),
    WrenchCommand(0, "c", "point", "a/tip", (0.0, 0.1), (-1.0, 1.0), -0.2),
]


def random_states(model: Model, count: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [(rng.normal(scale=[2.0, 2.0, 3.0], size=(model.size, 3)),
             rng.normal(scale=[1.0, 1.0, 5.0], size=(model.size, 3))) for _ in range(count)]


def both_paths(scene) -> tuple[Model, Model]:
    return Model(scene, lean=True), Model(scene, lean=False)


def assert_same(lean: np.ndarray, vector: np.ndarray) -> None:
    # Each component is a sum of a handful of terms of size up to ~1e3: 1e-12 relative to
    # the largest is a few hundred ulps, far below any formula error (which is O(1)).
    scale = max(1.0, float(np.abs(vector).max()))
    np.testing.assert_allclose(lean, vector, rtol=0.0, atol=1e-12 * scale)


def test_every_force_term_agrees_between_lean_and_vector_paths():
    lean, vector = both_paths(make_scene(EVERY_FORCE))
    assert {type(t).__name__ for t in lean.terms} == {
        "GravityTerm", "AnchorSpringTerm", "BodySpringTerm", "CenterDragTerm", "PointDragTerm",
        "AngularDampingTerm", "ConstantWrenchTerm"}
    for q, v in random_states(lean, 20, seed=1):
        assert_same(lean.accelerations(q, v), vector.accelerations(q, v))


def pushed(scene, lean: bool) -> Simulation:
    """A simulation on one evaluation path with :data:`COMMANDS` pushed."""
    sim = Simulation(scene)
    sim.model.use_python(lean)
    for command in COMMANDS:
        sim.push(command)
    return sim


def test_applied_wrenches_in_every_frame_agree_between_paths():
    scene = make_scene(EVERY_FORCE)
    runs = []
    for lean in (True, False):
        sim = pushed(scene, lean)
        sim.step()  # activates the commands as the model's input term
        assert sim.model.inputs is not None
        runs.append(sim.model)
    for q, v in random_states(runs[0], 20, seed=2):
        assert_same(runs[0].accelerations(q, v), runs[1].accelerations(q, v))


def test_a_zero_length_spring_whose_ends_meet_gives_zero_force_on_both_paths():
    scene = make_scene({"bodies": {"m": {"shape": "circle", "radius": 0.1, "mass": 1.0}},
                        "forces": {"s": {"type": "spring", "body_a": "m", "anchor": [0.0, 0.0],
                                         "stiffness": 100.0, "rest_length": 0.5}}})
    q = np.zeros((1, 3))
    v = np.array([[1.0, 2.0, 3.0]])
    for model in both_paths(scene):
        np.testing.assert_array_equal(model.accelerations(q, v), np.zeros((1, 3)))


@pytest.mark.parametrize("size, expected", [(1, True), (LEAN_BODIES, True),
                                            (LEAN_BODIES + 1, False)])
def test_the_lean_path_is_chosen_by_body_count(size, expected):
    bodies = {f"b{i}": {"shape": "circle", "radius": 0.1, "mass": 1.0, "position": [float(i), 0.0]}
              for i in range(size)}
    assert Model(make_scene({"bodies": bodies})).lean is expected


def test_runs_on_both_paths_stay_together():
    """A whole run (all terms, inputs, walls) on each path: rounding differences grow only
    as the dynamics amplify them; over 0.5 s of this non-chaotic scene they stay tiny."""
    params = dict(EVERY_FORCE, walls={"floor": {"point": [0.0, -3.0], "normal": [0.0, 1.0]}})
    scene = make_scene(params)
    finals = []
    for lean in (True, False):
        sim = pushed(scene, lean)
        sim.advance_to(500_000_000)
        finals.append(np.concatenate([sim.q, sim.v]))
    np.testing.assert_allclose(finals[0], finals[1], rtol=0.0, atol=1e-9)


def test_a_spring_shorter_than_the_smallest_double_agrees_on_both_paths():
    """At a length of 1e-310 (a subnormal) 1/length overflows; the direction must still be
    d / |d| on both paths, not NaN on the vector one."""
    scene = make_scene({"bodies": {"m": {"shape": "circle", "radius": 0.1, "mass": 1.0}},
                        "forces": {"s": {"type": "spring", "body_a": "m", "anchor": [0.0, 0.0],
                                         "stiffness": 100.0, "rest_length": 0.1}}})
    q = np.array([[1e-310, 0.0, 0.0]])
    v = np.zeros((1, 3))
    lean, vector = both_paths(scene)
    expected = np.array([[100.0 * 0.1, 0.0, 0.0]])  # pushed out along +x with k (L0 - L)
    np.testing.assert_allclose(lean.accelerations(q, v), expected, rtol=1e-12)
    np.testing.assert_allclose(vector.accelerations(q, v), expected, rtol=1e-12)


def many_bodies_scene(count: int, seed: int = 3) -> dict:
    """``count`` boxes with every kind of term, laid out so that each way of summing per
    body is used: gravity on all (a block in order), springs in a ring whose instances run
    in a shuffled body order (a permuted block), anchors on every third body (gaps), extra
    springs from random bodies (repeats), drag on a shuffled half."""
    rng = np.random.default_rng(seed)
    names = [f"b{i:04d}" for i in range(count)]
    order = rng.permutation(count)
    bodies = {name: {"shape": "box", "size": [0.2, 0.1], "mass": 1.0 + (i % 5) * 0.1,
                     "position": [float(i % 20), float(i // 20)], "angle": 0.1 * i}
              for i, name in enumerate(names)}
    forces = {"gravity": {"type": "gravity"},
              "drag": {"type": "linear_drag", "coefficient": 0.3,
                       "bodies": [names[i] for i in order[: count // 2]]},
              "spin": {"type": "angular_damping", "coefficient": 0.01}}
    for k, i in enumerate(order):
        forces[f"ring{k:04d}"] = {"type": "spring", "body_a": names[i], "point_a": [0.1, 0.0],
                                  "body_b": names[(i + 1) % count], "point_b": [-0.1, 0.0],
                                  "stiffness": 100.0, "rest_length": 0.1, "damping": 0.5}
    for i in range(0, count, 3):
        forces[f"pin{i:04d}"] = {"type": "spring", "body_a": names[i], "point_a": [0.05, 0.02],
                                 "anchor": [float(i % 20), float(i // 20) + 1.0],
                                 "stiffness": 20.0}
    for k in range(count // 4):
        a, b = rng.integers(count, size=2)
        forces[f"extra{k:04d}"] = {"type": "spring", "body_a": names[a], "body_b": names[b],
                                   "point_b": [0.1, 0.05], "stiffness": 5.0,
                                   "rest_length": 0.3}
    return {"step": 0.001, "bodies": bodies, "forces": forces}


def test_many_bodies_agree_between_paths():
    """300 bodies: above the count from which the vector path takes cos and sin by the
    half-angle tangent, and with every per-body summing layout; the lean path (plain floats,
    math.cos/sin) must agree to rounding."""
    scene = make_scene(many_bodies_scene(300))
    assert len(scene.bodies) >= HALF_ANGLE_FROM
    lean, vector = both_paths(scene)
    for q, v in random_states(lean, 3, seed=4):
        assert_same(lean.accelerations(q, v), vector.accelerations(q, v))


@pytest.mark.parametrize("body", [[], [0, 1, 2, 3], [2, 0, 3, 1], [5, 4, 6], [0, 2, 5],
                                  [1, 1, 3, 0, 1], [4]])
def test_body_sum_matches_bincount_for_every_layout(body):
    """In order, shuffled, offset, with gaps, with repeats, single, empty: the per-body sums
    equal numpy's bincount reference, added to and subtracted from an existing total."""
    body = np.array(body, dtype=int)
    rng = np.random.default_rng(len(body))
    value = rng.normal(size=len(body))
    total = rng.normal(size=8)
    expected = total + np.bincount(body, value, minlength=8)
    summed = BodySum(body)
    added = total.copy()
    summed.add(added, value)
    np.testing.assert_allclose(added, expected, rtol=0.0, atol=1e-15)
    summed.subtract(added, value)
    np.testing.assert_allclose(added, total, rtol=0.0, atol=1e-15)


def test_an_input_in_body_axes_turns_with_the_body_when_no_scene_force_needs_angles():
    """Gravity alone needs no orientation; a command in body axes does, and the model must
    notice it when the input arrives: a body turned a quarter turn and pushed along its own
    x axis accelerates along world +y, on both paths."""
    scene = make_scene({"bodies": {"m": {"shape": "circle", "radius": 0.1, "mass": 2.0,
                                         "angle": np.pi / 2}},
                        "forces": {"g": {"type": "gravity", "acceleration": [0.0, -1.0]}},
                        "input_timeout": 0.0})
    for lean in (True, False):
        sim = Simulation(scene)
        sim.model.use_python(lean)
        assert not sim.model._oriented
        sim.push(WrenchCommand(0, "m", "test", "m", (0.0, 0.0), (4.0, 0.0), 0.0))
        sim.step()
        q, v = sim.model.initial_state()
        np.testing.assert_allclose(sim.model.accelerations(q, v), [[0.0, 1.0, 0.0]],
                                   rtol=0.0, atol=1e-15)
