"""Scenes (scene.py, parameters.py) and the model built from them (model.py).

Checks: the shipped default scene loads by name, by path and as flat parameters, and all
three give the same scene; every bad parameter is refused with a message naming the
source (file or parameter source) and the dotted parameter; node parameters pass; and the
model holds only the force terms and passes the scene declares.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scene_builders import flatten, make_scene, write_scene

import hecker_dynamics.dynamics.forces as forces
import hecker_dynamics.dynamics.model as model_module
from hecker_dynamics import Simulation
from hecker_dynamics.geometry.shapes import box
from hecker_dynamics.integrators.methods import METHODS
from hecker_dynamics.scene.load import (
    DEFAULT_SCENE,
    SceneError,
    load_scene,
    scene_from_parameters,
    scene_path,
    shipped_scenes,
)
from hecker_dynamics.scene.parameters import seconds_text

SAMPLE = Path(__file__).resolve().parents[2] / "config" / "sample.yaml"


def _params_of(path: Path) -> dict:
    return yaml.safe_load(path.read_text())["dynamics_node"]["ros__parameters"]


def _is_the_shipped_sample(path) -> bool:
    """The repository's config/sample.yaml or its installed copy (package data, ROS share)."""
    path = Path(path)
    return path.name == SAMPLE.name and path.read_bytes() == SAMPLE.read_bytes()


def _without_source(scene):
    return dataclasses.replace(scene, source="")


# ------------------------------------------------------------------ loading

@pytest.mark.parametrize("ns, text", [
    (1_700_000_000_750_000_001, "1700000000.750000001"), (1_700_000_000_750_000_000,
                                                         "1700000000.75"),
    (4_166_667, "0.004166667"), (1_000_000_000, "1"), (0, "0"), (1, "0.000000001"),
    (-1_500_000_000, "-1.5"), (9_223_372_036_854_775_807, "9223372036.854775807"),
])
def test_seconds_are_written_exactly_from_nanoseconds(ns, text):
    """Times in messages are the exact decimal of their nanoseconds, which --start reads
    back as the same ns; through a double (ns * 1e-9) 1700000000750000001 ns printed
    1700000000.750000238 with :.9f and 1.7e+09 with :g."""
    assert seconds_text(ns) == text


def test_sample_scene_loads_with_the_declared_contents():
    scene = load_scene("sample")
    assert _is_the_shipped_sample(scene.source)
    assert [b.name for b in scene.bodies] == ["left", "right"]
    assert scene.step_ns == 1_000_000 and scene.publish_period_ns == 20_000_000
    assert scene.integrator == "semi_implicit_euler"
    assert scene.duration_ns == 10_000_000_000 and scene.input_timeout_ns == 500_000_000
    left = scene.bodies[0]
    assert left.mass.mass == pytest.approx(1.0, rel=1e-14)
    assert left.mass.moment_of_inertia == pytest.approx((0.8 ** 2 + 0.4 ** 2) / 12, rel=1e-12)
    assert left.points == {"hook": (0.4, 0.0)}
    assert sorted(w.name for w in scene.walls) == ["ceiling", "floor", "left_wall", "right_wall"]
    assert {type(f).__name__ for f in scene.forces} == {"Gravity", "SpringSpec"}
    (kick,) = scene.script
    assert (kick.body, kick.frame_id, kick.stamp_ns, kick.duration_ns) == (
        "left", "left", 3_000_000_000, 100_000_000)
    assert "sample" in shipped_scenes() and DEFAULT_SCENE == "sample"


def test_sample_by_name_by_path_default_and_as_flat_parameters_are_equal():
    by_name = load_scene("sample")
    by_default = load_scene()
    by_path = load_scene(SAMPLE)
    by_str_path = load_scene(str(SAMPLE))
    flat = scene_from_parameters(flatten(_params_of(SAMPLE)), str(SAMPLE))
    for other in (by_str_path, flat):
        assert other == by_path
    for other in (by_name, by_default):
        assert _without_source(other) == _without_source(by_path)


def test_two_loads_of_a_scene_compare_equal():
    """Scene == Scene works (it raised ValueError while Polygon.vertices and
    MassProperties.center_of_mass were bare numpy arrays in frozen dataclasses)."""
    assert load_scene("sample") == load_scene("sample")


def test_single_shape_body_angle_is_not_the_shape_angle():
    """``bodies.b.angle`` places the body frame; the box is defined in that frame, unturned.
    (Found here: _read_shape used to read the body's 'angle' as the box's angle too, so
    sample.yaml's 'left' box at 0.3 rad collided and was drawn at 0.6 rad.)"""
    scene = make_scene({"bodies": {"b": {"shape": "box", "size": [2.0, 1.0], "mass": 1.0,
                                         "angle": 0.5}}})
    assert scene.bodies[0].angle == 0.5
    np.testing.assert_allclose(scene.bodies[0].shapes[0].vertices, box(2.0, 1.0).vertices,
                               atol=1e-15)


FULL = {
    "frame_id": "map",
    "step": 0.002,
    "publish_rate": 25.0,
    "integrator": "rk4",
    "tolerance": 1e-7,
    "duration": 3.0,
    "input_timeout": 0.25,
    "input_max_lead": 2.0,
    "twist_frame": "world",
    "restitution_threshold": 0.05,
    "publish": {"odometry": True, "markers": True, "diagnostics": False},
    "bodies": {
        "a": {"shape": "box", "size": [1.0, 0.5], "mass": 1.0, "points": {"tip": [0.5, 0.0]},
              "velocity": [1.0, 0.0], "angular_velocity": 0.5},
        "b": {"shape": "circle", "radius": 0.3, "density": 2.0, "position": [2.0, 0.0]},
        "c": {"shape": "polygon", "vertices": [0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "mass": 0.5,
              "position": [-2.0, 0.0]},
    },
    "forces": {
        "g": {"type": "gravity", "acceleration": [0.0, -3.0], "bodies": ["a", "b"]},
        "s": {"type": "spring", "body_a": "a", "point_a": "tip", "body_b": "b",
              "stiffness": 10.0, "rest_length": 1.0, "damping": 0.1},
        "pin": {"type": "spring", "body_a": "c", "point_a": [0.1, 0.1], "anchor": [-2.0, 1.0],
                "stiffness": 5.0},
        "air": {"type": "quadratic_drag", "bodies": ["a"], "point": "tip", "coefficient": 0.1},
        "visc": {"type": "linear_drag", "coefficient": 0.05},
        "spin": {"type": "angular_damping", "bodies": ["c"], "coefficient": 0.01},
        "push": {"type": "constant_force", "body": "b", "force": [0.5, 0.0], "axes": "body",
                 "point": [0.0, 0.3]},
        "twist": {"type": "constant_torque", "body": "c", "torque": 0.2},
    },
    "walls": {"floor": {"point": [0.0, -1.0], "normal": [0.0, 2.0], "restitution": 0.3,
                        "friction": 0.4, "bodies": ["a", "b"]}},
    "wrench_topics": {"thrust": {"body": "a", "frame_id": "a/tip", "topic": "a/thrust"}},
    "script": {"kick": {"time": 0.5, "body": "a", "frame_id": "a/tip", "force": [1.0, 0.0],
                        "duration": 0.1, "id": "kicker"},
               "nudge": {"time": 0.25, "body": "b", "torque": 0.5}},
}


def test_yaml_file_and_flat_parameters_give_the_same_scene(tmp_path):
    path = write_scene(tmp_path, FULL, "full.yaml")
    from_file = load_scene(path)
    from_params = scene_from_parameters(flatten(FULL), str(path))
    assert from_file == from_params
    # and what was declared is what was read
    assert from_file.frame_id == "map" and from_file.step_ns == 2_000_000
    assert from_file.publish_period_ns == 40_000_000
    assert from_file.walls[0].normal == pytest.approx((0.0, 1.0))
    assert [c.source for c in from_file.script] == ["nudge", "kicker"]  # sorted by time
    assert from_file.wrench_topics[0].frame_id == "a/tip"


def test_node_parameters_are_tolerated(tmp_path):
    """rclpy adds use_sim_time and qos_overrides.<topic>.<...> to a node's parameters."""
    node = {"use_sim_time": True, "scene": "sample", "lockstep": False,
            "qos_overrides": {"/clock": {"subscription": {"depth": 1, "reliability": "reliable"}}}}
    params = {**copy.deepcopy(FULL), **node}
    plain = make_scene(FULL, "src")
    assert make_scene(params, "src") == plain
    flat = flatten(FULL)
    flat.update({"use_sim_time": True, "qos_overrides./clock.subscription.depth": 1,
                 "qos_overrides./parameter_events.publisher.depth": 1000})
    assert scene_from_parameters(flat, "src") == plain
    del params["scene"]  # with scene parameters, refused in a file as the node refuses it
    loaded = load_scene(write_scene(tmp_path, params))
    assert _without_source(loaded) == _without_source(plain)


def test_wildcard_node_name_is_accepted(tmp_path):
    path = tmp_path / "wild.yaml"
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": FULL}}))
    assert _without_source(load_scene(path)) == _without_source(make_scene(FULL))


# ------------------------------------------------------------------ errors

BASE = {
    "step": 0.001,
    "publish_rate": 50.0,
    "integrator": "rk4",
    "bodies": {
        "a": {"shape": "box", "size": [1.0, 0.5], "mass": 1.0, "points": {"tip": [0.5, 0.0]}},
        "b": {"shape": "circle", "radius": 0.3, "mass": 2.0, "position": [2.0, 0.0]},
    },
    "forces": {
        "g": {"type": "gravity"},
        "s": {"type": "spring", "body_a": "a", "point_a": "tip", "body_b": "b",
              "stiffness": 10.0},
    },
    "walls": {"floor": {"point": [0.0, -1.0], "normal": [0.0, 1.0]}},
    "wrench_topics": {"thrust": {"body": "a", "frame_id": "a/tip"}},
    "script": {"kick": {"time": 0.5, "body": "a", "force": [1.0, 0.0]}},
}

DELETE = object()

#: case -> (parameter to set, value or DELETE, parameter the message must name, words)
ERRORS = {
    "misspelt_top": ("stepp", 0.001, "stepp", "not a known parameter"),
    "misspelt_body": ("bodies.a.masss", 1.0, "bodies.a.masss", "not a known parameter"),
    "misspelt_force": ("forces.s.stifness", 1.0, "forces.s.stifness", "not a known parameter"),
    "misspelt_wall": ("walls.floor.restitusion", 0.5, "walls.floor.restitusion", "not a known"),
    "misspelt_script": ("script.kick.forse", [1.0, 0.0], "script.kick.forse", "not a known"),
    "wrong_type_number": ("step", "fast", "step", "must be a number"),
    "wrong_type_bool": ("publish.odometry", "yes", "publish.odometry", "true or false"),
    "wrong_type_array": ("bodies.a.position", "origin", "bodies.a.position", "array"),
    "wrong_type_nested": ("bodies.b", 3.0, "bodies.b", "nested"),
    "wrong_length": ("bodies.a.velocity", [1.0, 2.0, 3.0], "bodies.a.velocity", "2 numbers"),
    "mixed_int_double": ("bodies.a.position", [1, 2.5], "bodies.a.position", "homogeneous"),
    "nan_number": ("forces.s.stiffness", float("nan"), "forces.s.stiffness", "finite"),
    "missing_required": ("forces.s.stiffness", DELETE, "forces.s.stiffness", "required"),
    "missing_radius": ("bodies.b.radius", DELETE, "bodies.b.radius", "required"),
    "missing_shape": ("bodies.b.shape", DELETE, "bodies.b.shape", "required"),
    "missing_script_time": ("script.kick.time", DELETE, "script.kick.time", "required"),
    "unknown_body_spring": ("forces.s.body_b", "c", "forces.s.body_b", "unknown body"),
    "unknown_body_gravity": ("forces.g.bodies", ["a", "zz"], "forces.g.bodies", "unknown body"),
    "unknown_body_wall": ("walls.floor.bodies", ["zz"], "walls.floor.bodies", "unknown body"),
    # Contact events name the map's boxes 'map': a wall of that name shared its touches.
    "wall_named_map": ("walls.map", {"point": [0.0, -1.0], "normal": [0.0, 1.0]}, "walls.map",
                       "'map' names the map's boxes in contact events"),
    "unknown_body_script": ("script.kick.body", "zz", "script.kick.body", "unknown body"),
    "unknown_body_topic": ("wrench_topics.thrust.body", "zz", "wrench_topics.thrust.body",
                           "unknown body"),
    "duplicate_body": ("forces.g.bodies", ["a", "a"], "forces.g.bodies", "more than once"),
    "bad_frame_script": ("script.kick.frame_id", "odom", "script.kick.frame_id", "odom"),
    "bad_point_frame_script": ("script.kick.frame_id", "a/nowhere", "script.kick.frame_id",
                               "a/nowhere"),
    "bad_frame_topic": ("wrench_topics.thrust.frame_id", "b/tip",
                        "wrench_topics.thrust.frame_id", "b/tip"),
    "publish_rate_not_whole": ("publish_rate", 300.0, "publish_rate", "whole number"),
    "publish_rate_too_fast": ("publish_rate", 2000.0, "publish_rate",
                              "faster than the physics step of 0.001 s can sample (at most "
                              "1000 Hz)"),
    "spring_body_b_and_anchor": ("forces.s.anchor", [0.0, 0.0], "forces.s.anchor",
                                 "exactly one"),
    "spring_neither": ("forces.s.body_b", DELETE, "forces.s.anchor", "exactly one"),
    "spring_to_itself": ("forces.s.body_b", "a", "forces.s.body_b", "itself"),
    "unknown_point": ("forces.s.point_a", "hook", "forces.s.point_a", "tip"),
    "bad_integrator": ("integrator", "leapfrog", "integrator", "semi_implicit_euler"),
    "bad_force_type": ("forces.g.type", "magnetism", "forces.g.type", "gravity"),
    "bad_twist_frame": ("twist_frame", "odom", "twist_frame", "body"),
    "invalid_body_name": ("bodies.my-body", {"shape": "circle", "radius": 1.0, "mass": 1.0},
                          "bodies.my-body", "not a valid name"),
    "invalid_body_name_digit": ("bodies.9lives", {"shape": "circle", "radius": 1.0,
                                                  "mass": 1.0}, "bodies.9lives", "valid name"),
    "invalid_force_name": ("forces.bad name", {"type": "gravity"}, "forces.bad name",
                           "valid name"),
    "frame_id_is_a_body": ("frame_id", "a", "frame_id", "body"),
    "frame_id_with_slash": ("frame_id", "world/x", "frame_id", "not a valid name"),
    "frame_id_with_space": ("frame_id", "my world", "frame_id", "not a valid name"),
    "frame_id_unicode": ("frame_id", "wörld", "frame_id", "not a valid name"),
    "frame_id_digit": ("frame_id", "9world", "frame_id", "not a valid name"),
    "frame_id_empty": ("frame_id", "", "frame_id", "not a valid name"),
    "frame_id_too_long": ("frame_id", "w" * 101, "frame_id", "at most 100"),
    "negative_step": ("step", -0.001, "step", "positive"),
    "zero_step": ("step", 0.0, "step", "positive"),
    "zero_wall_normal": ("walls.floor.normal", [0.0, 0.0], "walls.floor.normal", "zero"),
    "mass_and_density": ("bodies.a.density", 1.0, "bodies.a.mass", "not both"),
    "no_bodies": ("bodies", {}, "bodies", "at least one body"),
    "negative_stiffness": ("forces.s.stiffness", -1.0, "forces.s.stiffness", "at least 0"),
    "three_threads": ("contacts.threads", 3, "contacts.threads", "must be 1 or 2, not 3"),
    "no_threads": ("contacts.threads", 0, "contacts.threads", "must be 1 or 2"),
    "threads_double": ("contacts.threads", 2.0, "contacts.threads", "not 2.0"),
    "threads_bool": ("contacts.threads", True, "contacts.threads", "not True"),
    "zero_converged": ("contacts.converged", 0.0, "contacts.converged", "must be positive"),
    "negative_converged": ("contacts.converged", -1e-6, "contacts.converged", "positive"),
    "converged_text": ("contacts.converged", "tight", "contacts.converged", "must be a number"),
}


def _mutated(case):
    key, value, _, _ = ERRORS[case]
    params = copy.deepcopy(BASE)
    params.setdefault("publish", {})
    node = params
    *parents, last = key.split(".")
    for part in parents:
        node = node.setdefault(part, {})
    if value is DELETE:
        del node[last]
    else:
        node[last] = value
    return params


def test_base_scene_of_the_error_cases_is_valid():
    scene = make_scene(BASE)
    assert len(scene.bodies) == 2


@pytest.mark.parametrize("case", sorted(ERRORS))
def test_bad_parameter_error_names_file_and_parameter(case, tmp_path):
    _, _, parameter, words = ERRORS[case]
    path = write_scene(tmp_path, _mutated(case), f"bad_{case}.yaml")
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert str(path) in message
    assert f"'{parameter}'" in message
    assert words in message


@pytest.mark.parametrize("case", sorted(ERRORS))
def test_bad_flat_parameter_error_names_source_and_parameter(case):
    _, _, parameter, words = ERRORS[case]
    with pytest.raises(SceneError) as caught:
        scene_from_parameters(flatten(_mutated(case)), "/dynamics_node")
    message = str(caught.value)
    assert message.startswith("/dynamics_node: ")
    assert f"'{parameter}'" in message
    assert words in message


def test_flat_parameters_with_a_value_and_children_are_refused():
    flat = flatten(BASE)
    flat["bodies.a.mass.extra"] = 1.0
    with pytest.raises(SceneError, match=r"^src: .*bodies\.a\.mass"):
        scene_from_parameters(flat, "src")


def test_unreadable_files_name_the_file(tmp_path):
    missing = tmp_path / "missing.yaml"
    with pytest.raises(SceneError, match="missing.yaml"):
        load_scene(missing)
    broken = tmp_path / "broken.yaml"
    broken.write_text("dynamics_node: {ros__parameters: [unclosed\n")
    with pytest.raises(SceneError, match="broken.yaml"):
        load_scene(broken)
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(yaml.safe_dump({"other_node": {"ros__parameters": BASE}}))
    with pytest.raises(SceneError, match="wrong.yaml.*dynamics_node"):
        load_scene(wrong)
    with pytest.raises(SceneError, match="no shipped scene called 'nonesuch'.*sample"):
        load_scene("nonesuch")
    assert _is_the_shipped_sample(scene_path("sample"))


@pytest.mark.parametrize("make, message", [
    (lambda p: None, r"no such scene file$"),
    (lambda p: p.mkdir(), r"is a directory, not a scene file$"),
    (lambda p: os.mkfifo(p), r"is not a regular file$"),
])
def test_a_scene_path_that_is_no_file_says_what_it_is(tmp_path, make, message):
    path = tmp_path / "scene.yaml"
    make(path)
    with pytest.raises(SceneError, match=f"^{re.escape(str(path))}: {message}"):
        load_scene(path)


@pytest.mark.parametrize("loop", [True, False])
def test_a_symlink_that_leads_nowhere_is_named_so_not_taken_for_a_scene_name(tmp_path,
                                                                               monkeypatch,
                                                                               loop):
    """A bare name that is a dangling symlink or a symlink loop is the file the user
    meant, not a shipped scene's name."""
    monkeypatch.chdir(tmp_path)
    Path("scene").symlink_to("other" if loop else "gone.yaml")
    if loop:
        Path("other").symlink_to("scene")
    with pytest.raises(SceneError, match=r"^scene: is a broken symlink or a symlink loop$"):
        load_scene("scene")


# ------------------------------------------------------------------ model: only what is declared

def _contact_pass(model):
    """The model's contact pass (``contacts`` in the current core, ``walls`` before)."""
    for attribute in ("contacts", "walls"):
        if hasattr(model, attribute):
            return getattr(model, attribute)
    raise AssertionError("the model has no contact-pass attribute")


def _contact_class():
    for name in ("ContactPass", "WallContacts"):
        if hasattr(model_module, name):
            return getattr(model_module, name)
    raise AssertionError("model.py builds no known contact class")


def _poison(monkeypatch, cls):
    def refuse(*args, **kwargs):
        raise AssertionError(f"{cls.__name__} code ran")
    for name, value in list(vars(cls).items()):
        if callable(value) or isinstance(value, (staticmethod, classmethod)):
            monkeypatch.setattr(cls, name, refuse)


def _bodies_scene(forces_=None, walls=None, integrator="semi_implicit_euler", **body):
    params = {"integrator": integrator,
              "bodies": {"a": {"shape": "box", "size": [1.0, 0.5], "mass": 1.0,
                               "points": {"tip": [0.5, 0.0]}, "velocity": [1.0, 2.0],
                               "angular_velocity": 3.0, **body},
                         "b": {"shape": "circle", "radius": 0.3, "mass": 2.0,
                               "position": [2.0, 0.0]}}}
    if forces_:
        params["forces"] = forces_
    if walls:
        params["walls"] = walls
    return make_scene(params)


def test_scene_without_walls_builds_and_runs_no_contact_code(monkeypatch):
    scene = _bodies_scene({"g": {"type": "gravity"}})
    _poison(monkeypatch, _contact_class())
    sim = Simulation(scene)
    assert _contact_pass(sim.model) is None
    sim.advance_to(200_000_000)
    assert sim.steps == 200


def test_poisoned_contact_code_is_noticed_when_walls_exist(monkeypatch):
    """The check above can fail: with a wall, the same poisoning stops the run."""
    scene = _bodies_scene({"g": {"type": "gravity"}},
                          walls={"floor": {"point": [0.0, -5.0], "normal": [0.0, 1.0]}})
    _poison(monkeypatch, _contact_class())
    with pytest.raises(AssertionError, match="code ran"):
        Simulation(scene).advance_to(10_000_000)


SPRING_TERMS = {"AnchorSpringTerm", "BodySpringTerm"}


def _term_names(scene):
    return sorted(type(t).__name__ for t in Simulation(scene).model.terms)


def test_terms_built_match_declared_forces():
    assert _term_names(_bodies_scene()) == []
    assert _term_names(_bodies_scene({"g": {"type": "gravity"}})) == ["GravityTerm"]
    assert not SPRING_TERMS & set(_term_names(_bodies_scene({"g": {"type": "gravity"},
                                                             "d": {"type": "linear_drag",
                                                                   "coefficient": 0.1}})))
    assert _term_names(_bodies_scene({"t": {"type": "constant_torque", "body": "a",
                                            "torque": 1.0}})) == ["ConstantWrenchTerm"]
    full = make_scene(FULL)
    assert _term_names(full) == sorted([
        "GravityTerm", "BodySpringTerm", "AnchorSpringTerm", "CenterDragTerm",
        "PointDragTerm", "AngularDampingTerm", "ConstantWrenchTerm"])
    # springs: only anchored ones -> only the anchor term
    assert _term_names(_bodies_scene({"pin": {"type": "spring", "body_a": "a",
                                              "anchor": [0.0, 0.0], "stiffness": 1.0}})) == [
        "AnchorSpringTerm"]


def test_can_turn_only_bodies_that_something_turns():
    """Gravity and CM drag never turn; a spring at the CM does not either; a spring at an
    off-center point, point drag, angular damping, torques and walls do."""
    assert not Simulation(_bodies_scene({"g": {"type": "gravity"}, "d": {
        "type": "quadratic_drag", "coefficient": 0.1}})).model.can_turn().any()
    center_spring = {"s": {"type": "spring", "body_a": "a", "body_b": "b", "stiffness": 1.0}}
    assert not Simulation(_bodies_scene(center_spring)).model.can_turn().any()
    off_center = {"s": {"type": "spring", "body_a": "a", "point_a": "tip", "body_b": "b",
                        "stiffness": 1.0}}
    assert list(Simulation(_bodies_scene(off_center)).model.can_turn()) == [True, False]
    damped = {"w": {"type": "angular_damping", "bodies": ["b"], "coefficient": 0.1}}
    assert list(Simulation(_bodies_scene(damped)).model.can_turn()) == [False, True]
    walled = _bodies_scene(walls={"floor": {"point": [0.0, -5.0], "normal": [0.0, 1.0],
                                            "bodies": ["b"]}})
    assert list(Simulation(walled).model.can_turn()) == [False, True]
    assert Simulation(make_scene(FULL)).model.can_turn().all()


@pytest.mark.parametrize("integrator", METHODS)
@pytest.mark.parametrize("lean", [True, False], ids=["lean", "vector"])
def test_body_nothing_turns_does_no_torque_work(integrator, lean, monkeypatch):
    """Gravity + CM drag only: no orientation is ever computed (on either evaluation path
    the kinematics are built without angles) and the angular velocity stays bit-identical over
    the run, whatever the integrator."""
    scene = _bodies_scene({"g": {"type": "gravity"},
                           "d": {"type": "linear_drag", "coefficient": 0.3},
                           "q": {"type": "quadratic_drag", "coefficient": 0.1}},
                          integrator=integrator)
    sim = Simulation(scene)
    sim.model.use_python(lean)
    assert not sim.model.can_turn().any()
    oriented = []
    scalar_of, vector_init = forces.ScalarKinematics.of.__func__, forces.Kinematics.__init__

    def scalar_spy(cls, q, v, orient):
        oriented.append(orient)
        return scalar_of(cls, q, v, orient)

    def vector_spy(self, q, v, orient=True):
        oriented.append(orient)
        vector_init(self, q, v, orient)
    monkeypatch.setattr(forces.ScalarKinematics, "of", classmethod(scalar_spy))
    monkeypatch.setattr(forces.Kinematics, "__init__", vector_spy)
    omega0 = sim.v[:, 2].copy()
    angle0 = sim.q[:, 2].copy()
    sim.advance_to(300_000_000)
    assert sim.v[:, 2].tobytes() == omega0.tobytes()
    # the angle still advances with the constant spin: theta0 + w t (wrapped)
    expected = (angle0 + omega0 * 0.3 + math.pi) % (2 * math.pi) - math.pi
    assert sim.q[:, 2] == pytest.approx(expected, abs=1e-12)
    # and the CM really moved (the run did something), with forces evaluated without angles
    assert sim.v[0, 1] < 2.0 - 0.3 * 9.81 * 0.9
    assert oriented and not any(oriented)


def test_rclpy_array_parameters_are_accepted():
    """rclpy gives double arrays as array.array('d') when parameters come from a
    ParameterValue message; they read as the same scene as lists."""
    import array

    as_lists = scene_from_parameters(
        {"bodies.a.shape": "box", "bodies.a.size": [1.0, 2.0], "bodies.a.mass": 1.0,
         "bodies.a.position": [0.5, 0.25]}, "lists")
    as_arrays = scene_from_parameters(
        {"bodies.a.shape": "box", "bodies.a.size": array.array("d", [1.0, 2.0]),
         "bodies.a.mass": 1.0, "bodies.a.position": array.array("d", [0.5, 0.25])}, "lists")
    assert as_arrays == as_lists


@pytest.mark.parametrize("frame, known", [("world", True), ("left", True), ("left/hook", True),
                                          ("left/nope", False), ("nobody", False),
                                          ("nobody/hook", False), ("", False)])
def test_scene_knows_its_frames(frame, known):
    assert load_scene("sample").has_frame(frame) is known


ONE_BOX = {"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}}}


@pytest.mark.parametrize("change, parameter", [
    ({"step": 10 ** 400}, "step"),
    ({"step": 1e300}, "step"),
    ({"duration": 1e300}, "duration"),
    ({"publish_rate": 1e-300}, "publish_rate"),
    ({"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 10 ** 400}}}, "bodies.b.mass"),
    ({"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                       "position": [10 ** 400, 0]}}}, "bodies.b.position"),
    ({"walls": {"w": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 1.5}}},
     "walls.w.restitution"),
    ({"bodies": {"b\n": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}}}, "bodies"),
    ({"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                       "points": {"tip\n": [0.5, 0.0]}}}}, "bodies.b.points"),
    ({"wrench_topics": {"jet": {"body": "b", "topic": "b//jet"}}}, "wrench_topics.jet.topic"),
    ({"wrench_topics": {"jet": {"body": "b", "topic": "b/jet/"}}}, "wrench_topics.jet.topic"),
    # Names and topics longer than ROS 2's topic names take (247 characters in all).
    ({"bodies": {"b" * 101: {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}}}, "bodies"),
    ({"bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                       "points": {"p" * 101: [0.5, 0.0]}}}}, "bodies.b.points"),
    ({"wrench_topics": {"jet": {"body": "b", "topic": "/".join(["j" * 50] * 5)}}},
     "wrench_topics.jet.topic"),
])
def test_out_of_range_values_and_names_are_errors_not_crashes(tmp_path, change, parameter):
    """Numbers too large for a double or for the nanosecond clock, a restitution above 1
    (it would add energy at every bounce), names a ROS topic cannot carry: each gives a
    SceneError naming the parameter, never an OverflowError or a later rclpy failure."""
    params = {**ONE_BOX, **change}
    with pytest.raises(SceneError, match=re.escape(parameter)):
        load_scene(write_scene(tmp_path, params))


@pytest.mark.parametrize("change, message", [
    ({"sensors": {"l": {"type": "laser", "body": "b", "count": 0}}},
     "parameter 'sensors.l.count': must be at least 1, not 0"),
    ({"sensors": {"l": {"type": "laser", "body": "b", "count": 200000}}},
     "parameter 'sensors.l.count': must be at most 100000, not 200000"),
    ({"step": 0.004166667, "publish_rate": 7},
     "parameter 'publish_rate': 7 Hz is not a whole number of physics steps of 0.004166667 s"),
    ({"step": 0.0},  "parameter 'step': must be positive, not 0"),
    ({"publish_rate": -2.5},  "parameter 'publish_rate': must be positive, not -2.5"),
])
def test_refusals_give_numbers_as_written(tmp_path, change, message):
    """A count of 0 was refused as "must be at least 1.0, not 0.0" and a step of
    0.004166667 s shown as 0.004166667000000001 s: whole numbers are given without '.0',
    others by the shortest text that reads back as the same double."""
    with pytest.raises(SceneError) as error:
        load_scene(write_scene(tmp_path, {**ONE_BOX, **change}))
    assert str(error.value).endswith(message), str(error.value)


def test_parameter_names_must_be_strings(tmp_path):
    path = tmp_path / "keys.yaml"
    path.write_text("dynamics_node:\n  ros__parameters:\n    bodies:\n      1: {shape: box}\n")
    with pytest.raises(SceneError, match="names must be strings"):
        load_scene(path)


@pytest.mark.parametrize("written, read", [("y", "True"), ("off", "False"), ("1", "1"),
                                           ("1.5", "1.5")])
def test_a_name_yaml_reads_as_another_type_is_named_as_written(tmp_path, written, read):
    """YAML reads an unquoted y, yes, on (n, no, off) as a boolean and digits as a
    number: a joint named y was refused as "'joints.True': names must be strings", a
    name the user never wrote. The refusal names what was written, where, and says to
    quote it."""
    path = tmp_path / "keys.yaml"
    path.write_text("dynamics_node:\n  ros__parameters:\n    bodies:\n"
                    f"      {written}: {{shape: box}}\n")
    with pytest.raises(SceneError) as error:
        load_scene(path)
    assert str(error.value) == (
        f"{path}: line 4, column 7: parameter 'bodies.{written}': names must be strings, "
        f"and YAML reads {written} as {read}: quote it ('{written}')")


def test_a_directory_named_like_a_shipped_scene_does_not_hide_it(tmp_path, monkeypatch):
    """`hecker-dynamics script ship -o ship` makes a bag directory called ship; the name
    must still mean the shipped scene."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ship").mkdir()
    assert load_scene("ship").source.endswith("ship.yaml")


def test_polygon_parts_turn_about_their_center():
    scene = make_scene({"bodies": {"b": {"density": 1.0, "parts": {
        "p": {"shape": "polygon", "vertices": [0.0, 0.0, 2.0, 0.0, 0.0, 1.0],
              "center": [1.0, 1.0], "angle": math.pi / 2}}}}})
    vertices = scene.bodies[0].shapes[0].vertices
    np.testing.assert_allclose(vertices, [[1.0, 1.0], [1.0, 3.0], [0.0, 1.0]], atol=1e-15)


def test_a_folder_named_without_a_separator_is_named_as_a_folder(tmp_path, monkeypatch):
    """``hecker-dynamics run robots`` with a folder ``robots`` here was refused as "no
    shipped scene called 'robots'", which sent the user looking for a typo."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "robots").mkdir()
    with pytest.raises(SceneError) as caught:
        load_scene("robots")
    assert str(caught.value).startswith("robots: is a directory, not a scene file, and no "
                                        "shipped scene is called so (shipped: ")


@pytest.mark.parametrize("tiny", [5e-324, 1e-310])
def test_a_wall_normal_or_slider_axis_of_subnormal_numbers_is_made_a_unit_vector(tiny):
    """hypot(5e-324, 5e-324) is 5e-324 (subnormals keep too few digits), so the normal
    (5e-324, 5e-324) was divided into (1, 1): a wall whose "unit" normal was sqrt(2) long,
    through which a box resting on it fell at g. Such a vector is scaled up before it is
    divided by its length: the same direction as (1, 1), of length 1 to rounding. A
    1 x 1 box on the slope that normal makes, frictionless, slides down it at g sin 45 deg
    (its velocity along the slope after 1 s, to the contact pass's 1e-3)."""
    joint = {"type": "prismatic", "body_b": "box", "axis": [tiny, tiny]}
    unit = make_scene({"bodies": {"box": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}},
                       "walls": {"slope": {"point": [0.0, -0.7072], "normal": [1.0, 1.0]}}})
    scene = make_scene({"bodies": {"box": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}},
                        "walls": {"slope": {"point": [0.0, -0.7072], "normal": [tiny, tiny]}},
                        "forces": {"g": {"type": "gravity", "acceleration": [0.0, -9.81]}},
                        "integrator": "semi_implicit_euler"})
    assert scene.walls[0].normal == unit.walls[0].normal
    assert math.hypot(*scene.walls[0].normal) == pytest.approx(1.0, abs=1e-15)
    slider = make_scene({"bodies": {"box": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}},
                         "joints": {"slide": joint}})
    assert slider.joints[0].axis == unit.walls[0].normal
    sim = Simulation(scene)
    sim.advance_to(1_000_000_000)
    along = (sim.v[0, 0] - sim.v[0, 1]) / math.sqrt(2.0)
    assert along == pytest.approx(9.81 * math.sqrt(0.5), rel=1e-3)
