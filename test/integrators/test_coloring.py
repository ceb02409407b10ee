"""Jacobians by colored differences (Curtis-Powell-Reid) for the implicit methods.

The model groups the bodies so that no two in a group influence a common body (a distance-2
coloring of the coupling graph of springs and inputs in another body's frame); the
implicit methods then bump one state component of a whole group per evaluation. Each entry
is computed by the same arithmetic as the dense Jacobian's, so the two agree bit for bit,
and so do whole implicit runs.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import make_scene
from scene_builders import box_body

from hecker_dynamics.bench.scenes import ring
from hecker_dynamics.dynamics.model import Model, wrench_term
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.integrators.coloring import color
from hecker_dynamics.integrators.methods import ImplicitTheta
from hecker_dynamics.scene.commands import WrenchCommand

#: b0-b1-b2-b3 a chain of springs (offsets, rest lengths, damping), b4 and b5 on springs
#: to fixed anchors, b6 free under gravity; b3 pushed along its own axes.
CHAIN = {
    "step": 0.001, "integrator": "implicit_midpoint",
    "bodies": {
        "b0": box_body(position=[0.0, 0.0], angle=0.3, angular_velocity=1.0,
                       points={"tip": [0.4, 0.1]}),
        "b1": box_body(position=[1.5, 0.2], velocity=[0.2, -0.1]),
        "b2": box_body(mass=3.0, position=[3.0, -0.1], angle=-0.5),
        "b3": box_body(position=[4.5, 0.3], angular_velocity=-2.0),
        "b4": box_body(position=[0.0, -2.0], angle=1.0),
        "b5": box_body(position=[2.0, -2.0]),
        "b6": box_body(position=[4.0, -2.0], velocity=[0.5, 0.5]),
    },
    "forces": {
        "gravity": {"type": "gravity", "acceleration": [0.0, -9.81]},
        "s01": {"type": "spring", "body_a": "b0", "point_a": "tip", "body_b": "b1",
                "point_b": [-0.4, 0.0], "stiffness": 2e4, "rest_length": 1.0, "damping": 5.0},
        "s12": {"type": "spring", "body_a": "b1", "point_a": [0.4, 0.1], "body_b": "b2",
                "point_b": [-0.3, -0.1], "stiffness": 5e3, "rest_length": 0.8},
        "s23": {"type": "spring", "body_a": "b3", "body_b": "b2", "stiffness": 800.0,
                "damping": 1.0},
        "a4": {"type": "spring", "body_a": "b4", "point_a": [0.3, 0.2], "anchor": [0.0, -1.0],
               "stiffness": 1e4, "rest_length": 0.5, "damping": 2.0},
        "a5": {"type": "spring", "body_a": "b5", "anchor": [2.0, -1.5], "stiffness": 300.0},
        "drag": {"type": "linear_drag", "coefficient": 0.2, "bodies": ["b1"],
                 "point": [0.1, 0.0]},
        "thrust": {"type": "constant_force", "body": "b3", "force": [1.0, 2.0], "axes": "body",
                   "point": [0.2, 0.1]},
    },
}

MS = 1_000_000

#: Inputs on b6 at b0's point "tip" and on b5 in b2's axes: b0 -> b6 and b2 -> b5.
COMMANDS = (WrenchCommand(0, "b6", "pilot", "b0/tip", (0.1, 0.0), (3.0, -1.0), 0.2, 10**9),
            WrenchCommand(0, "b5", "tug", "b2", (0.0, 0.3), (-2.0, 1.0), 0.0, 10**9))


def chain_scene():
    return make_scene(CHAIN)


def chain_model(lean: bool) -> Model:
    """The chain scene with both inputs active, as a Simulation would set them."""
    scene = chain_scene()
    sim = Simulation(scene)
    model = Model(scene, lean=lean)
    model.inputs = wrench_term([sim._row(command) for command in COMMANDS])
    return model


def ring_model(n: int, lean: bool) -> Model:
    return Model(ring(n), lean=lean)


def moved_state(model: Model, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The initial state moved a little, so that every spring and angle is in play."""
    rng = np.random.default_rng(seed)
    q, v = model.initial_state()
    return (q + rng.normal(scale=[0.05, 0.05, 0.5], size=q.shape),
            v + rng.normal(scale=[1.0, 1.0, 3.0], size=v.shape))


def jacobians(model: Model, colored: bool, seed: int = 1):
    integrator = ImplicitTheta(0.5)
    if colored:
        integrator.coloring_source = model.jacobian_coloring
    q, v = moved_state(model, seed)
    a = model.accelerations(q, v)
    return integrator.jacobians(model.accelerations, q, v, a), integrator.counters.evaluations


MODELS = {"chain": chain_model, "ring7": lambda lean: ring_model(7, lean),
          "ring30": lambda lean: ring_model(30, lean), "ring64": lambda lean: ring_model(64, lean)}


@pytest.mark.parametrize("name", MODELS)
def test_no_two_bodies_of_a_group_influence_a_common_body(name):
    coloring = MODELS[name](True).jacobian_coloring()
    assert coloring.is_valid()
    for group in coloring.groups:
        for j in group:
            for k in group:
                if j < k:
                    assert not set(coloring.influenced[j]) & set(coloring.influenced[k])


def test_springs_and_inputs_couple_their_bodies():
    influenced = [set(s.tolist()) for s in chain_model(True).jacobian_coloring().influenced]
    assert influenced == [{0, 1, 6}, {0, 1, 2}, {1, 2, 3, 5}, {2, 3}, {4}, {5}, {6}]


def test_the_coloring_follows_the_inputs():
    model = chain_model(True)
    with_inputs = model.jacobian_coloring()
    model.inputs = None
    without = model.jacobian_coloring()
    assert [s.tolist() for s in without.influenced[:3]] == [[0, 1], [0, 1, 2], [1, 2, 3]]
    model.inputs = wrench_term([Simulation(chain_scene())._row(COMMANDS[0])])
    assert model.jacobian_coloring().influenced[0].tolist() == [0, 1, 6]
    assert model.jacobian_coloring().influenced[2].tolist() == [1, 2, 3]
    assert with_inputs.influenced[2].tolist() == [1, 2, 3, 5]


def test_a_ring_takes_three_to_five_groups():
    assert len(ring_model(30, True).jacobian_coloring().groups) == 3
    for n in (10, 31, 64, 100):
        assert 3 <= len(ring_model(n, False).jacobian_coloring().groups) <= 5


@pytest.mark.parametrize("lean", [True, False])
@pytest.mark.parametrize("name", MODELS)
def test_colored_jacobians_equal_the_dense_ones_bit_for_bit(name, lean):
    model = MODELS[name](lean)
    for seed in (1, 2):
        colored, evaluations = jacobians(model, True, seed)
        dense, _ = jacobians(model, False, seed)
        for c, d in zip(colored, dense):
            assert c.tobytes() == d.tobytes()
        assert np.count_nonzero(dense[0]) > 0 and np.count_nonzero(dense[1]) > 0
        assert evaluations == 6 * len(model.jacobian_coloring().groups) < 6 * model.size


def run(scene, colored: bool, steps: int, lean=None):
    sim = Simulation(scene)
    if lean is not None:
        sim.model.use_python(lean)
    if not colored:
        sim.integrator.coloring_source = None
    if scene.bodies[0].name == "b0":
        for command in COMMANDS:
            sim.push(command)
    sim.advance_to(steps * scene.step_ns)
    return sim


@pytest.mark.parametrize("lean", [True, False])
@pytest.mark.parametrize(("scene", "steps"), [(chain_scene, 150), (lambda: dataclasses.replace(
    ring(40), integrator="implicit_midpoint"), 40)], ids=["chain", "ring40"])
def test_implicit_runs_are_the_same_bit_for_bit(scene, steps, lean):
    colored, dense = run(scene(), True, steps, lean), run(scene(), False, steps, lean)
    assert colored.q.tobytes() == dense.q.tobytes()
    assert colored.v.tobytes() == dense.v.tobytes()
    assert colored.integrator.counters.newton_iterations == \
        dense.integrator.counters.newton_iterations
    assert colored.integrator.counters.evaluations < dense.integrator.counters.evaluations
    if colored.model.inputs is not None:  # the chain, with its inputs still active
        assert colored.model.jacobian_coloring().influenced[0].tolist() == [0, 1, 6]


def test_backward_euler_is_colored_too():
    scene = dataclasses.replace(ring(12), integrator="backward_euler")
    sim = Simulation(scene)
    assert sim.integrator.coloring_source is not None
    sim.step()
    groups = len(sim.model.jacobian_coloring().groups)
    assert sim.integrator.counters.evaluations == \
        6 * groups + sim.integrator.counters.newton_iterations


def test_a_fully_coupled_scene_keeps_the_dense_jacobian():
    coloring = color(3, [(0, 1), (1, 2), (2, 0)])
    assert len(coloring.groups) == 3 and coloring.is_valid()


@pytest.mark.parametrize("lean", [True, False])
def test_inputs_that_end_and_begin_mid_run_recolor_and_stay_bit_identical(lean):
    """Inputs coupling other bodies end at 40 ms and a new one begins at 60 ms: the coloring
    follows (coupled, uncoupled, coupled again) and the run still equals the dense one."""
    short = tuple(dataclasses.replace(c, duration_ns=40 * MS) for c in COMMANDS)
    late = WrenchCommand(60 * MS, "b4", "late", "b0/tip", (0.0, 0.1), (1.0, 2.0), 0.1, 10**9)
    finals, influenced = [], []
    for colored in (True, False):
        sim = Simulation(chain_scene())
        sim.model.use_python(lean)
        if not colored:
            sim.integrator.coloring_source = None
        for command in short:
            sim.push(command)
        sim.advance_to(50 * MS)
        influenced.append(sim.model.jacobian_coloring().influenced[0].tolist())
        sim.push(late)
        sim.advance_to(100 * MS)
        influenced.append(sim.model.jacobian_coloring().influenced[0].tolist())
        finals.append((sim.q.tobytes(), sim.v.tobytes()))
    assert finals[0] == finals[1]
    # b0 reaches b1 by its spring; b6 while the tip input lasts (not at 50 ms); b4 after 60 ms.
    assert influenced[:2] == [[0, 1], [0, 1, 4]]
