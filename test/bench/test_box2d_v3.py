"""The Box2D v3 peer (never its speed): the scene description carries the scene's bodies,
joints, forces and script; the worker, in its own interpreter, builds what it describes
(welds hold, rays hit what they should, Python springs swing at their frequency, angles
unwrap); the interpreter is found where the docs say."""
from __future__ import annotations

import importlib.util
import math
import sys

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.bench import box2d_v3
from hecker_dynamics.scene import load_scene


def _needs_worker() -> None:
    if not box2d_v3.available():
        pytest.skip("Box2D v3's binding (box2d-python) imports in no interpreter found")


def test_description_places_each_body_at_its_cm_with_the_scenes_mass():
    """An L of two boxes: its CM is off the body origin; the description puts the body at
    the CM, its shapes around it, and carries the scene's mass and moment of inertia."""
    scene = make_scene({"step": 0.001, "duration": 1.0, "bodies": {"l": {
        "parts": {"long": {"shape": "box", "size": [2.0, 0.5], "center": [1.0, 0.0]},
                  "tall": {"shape": "box", "size": [0.5, 1.0], "center": [0.0, 0.75]}},
        "density": 1.0, "position": [3.0, 4.0], "angle": 0.5}}})
    body = scene.bodies[0]
    (cx, cy), c, s = body.mass.center_of_mass, math.cos(0.5), math.sin(0.5)
    described = box2d_v3.describe(scene)["bodies"][0]
    assert described["position"] == pytest.approx([3.0 + c * cx - s * cy, 4.0 + s * cx + c * cy])
    assert described["angle"] == 0.5
    assert described["mass"] == body.mass.mass
    assert described["inertia"] == body.mass.moment_of_inertia
    corners = np.array([p for polygon in described["polygons"] for p in polygon])
    # The first box spans x from 0 to 2 in the body frame: -cx to 2 - cx in the CM frame.
    assert corners[:, 0].min() == pytest.approx(-0.25 - cx) and \
        corners[:, 0].max() == pytest.approx(2.0 - cx)


def test_description_carries_springs_script_and_refuses_gears():
    sample = box2d_v3.describe(load_scene("sample"))
    assert len(sample["forces"]["springs"]) == 1 and sample["script"]
    assert sample["gravity"] == [0.0, -9.81]
    with pytest.raises(ValueError, match="no gear joint"):
        box2d_v3.describe(load_scene("gears"))


def test_the_variable_alone_names_the_interpreter(monkeypatch):
    """Where the variable is set, only its interpreter is tried: this one finds the
    binding exactly where ``box2d`` imports here."""
    monkeypatch.setenv(box2d_v3.PYTHON_VARIABLE, sys.executable)
    monkeypatch.setattr(box2d_v3, "_FOUND", {})
    here = importlib.util.find_spec("box2d") is not None
    assert box2d_v3.interpreter() == (sys.executable if here else None)
    monkeypatch.setenv(box2d_v3.PYTHON_VARIABLE, "/nonexistent/python")
    monkeypatch.setattr(box2d_v3, "_FOUND", {})
    assert box2d_v3.interpreter() is None and not box2d_v3.available()


def _two_boxes(joints: dict, **extra) -> dict:
    return {"step": 0.001, "duration": 1.0, "forces": {"gravity": {"type": "gravity"}},
            "bodies": {"a": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0,
                             "position": [0.5, 0.0]},
                       "b": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0,
                             "position": [1.5, 0.0]}},
            "joints": joints, **extra}


def test_a_weld_holds_two_boxes_as_one():
    """Box a is pinned to the world at its left end, b welded to its right end: the pair
    swings down as one rigid bar, so b's angle stays a's (within 0.01 rad: v3's joints are
    soft) and b's CM 1 m from a's."""
    _needs_worker()
    scene = make_scene(_two_boxes({
        "pin": {"type": "revolute", "body_b": "a", "point_a": [0.0, 0.0], "point_b": [-0.5, 0.0]},
        "weld": {"type": "weld", "body_a": "a", "body_b": "b", "point_a": [0.5, 0.0],
                 "point_b": [-0.5, 0.0]}}))
    step, poses = box2d_v3.scene_engine(scene, 0.001)
    for _ in range(10):
        step(100)
        (xa, ya, a), (xb, yb, b) = poses()
        assert abs(a - b) < 0.01 and math.hypot(xb - xa, yb - ya) == pytest.approx(1.0, abs=5e-3)
    assert a < -0.5  # it fell


def test_a_python_spring_swings_at_its_frequency():
    """A mass of 1 kg on a zero-length spring of 100 N/m, its force from the worker's
    Python loop: after half a period (pi / 10 s) it is at x = -1 m, after one and a half at
    -1 m again (semi-implicit Euler at h = 1 ms, float32: within 1 and 2 %)."""
    _needs_worker()
    scene = make_scene({"step": 0.001, "duration": 1.0, "bodies": {"m": {
        "shape": "circle", "radius": 0.1, "mass": 1.0, "position": [1.0, 0.0]}},
        "forces": {"k": {"type": "spring", "body_a": "m", "anchor": [0.0, 0.0],
                         "stiffness": 100.0}}})
    step, poses = box2d_v3.scene_engine(scene, 0.001)
    step(314)  # half a period
    assert poses()[0, 0] == pytest.approx(-1.0, abs=0.01)
    step(942 - 314)  # three half periods
    assert poses()[0, 0] == pytest.approx(-1.0, abs=0.02)


def test_angles_unwrap_between_reads_and_blocks_are_counted():
    """A free body spinning at 10 rad/s for 2 s, read every 0.1 s, has turned 20 rad; a
    step of 100 with block statistics gives 4 blocks of 25 steps."""
    _needs_worker()
    scene = make_scene({"step": 0.001, "duration": 2.0, "bodies": {"s": {
        "shape": "box", "size": [1.0, 0.5], "mass": 1.0, "position": [0.0, 0.0],
        "angular_velocity": 10.0}}})
    blocks: list[float] = []
    step, poses = box2d_v3.scene_engine(scene, 0.001, blocks=blocks)
    for _ in range(20):
        assert step(100) > 0.0
        angle = poses()[0, 2]
    assert angle == pytest.approx(20.0, rel=1e-5)
    assert len(blocks) == 80 and min(blocks) > 0.0


def test_rays_hit_the_nearest_shape():
    """A unit box at (2, 0) and a floor at y = -1: a ray from the origin along +x hits the
    box's face x = 1.5 at fraction 0.5 of its 3 m; one down hits the floor (-1) at 1 m of
    its 2 m; one up hits nothing."""
    _needs_worker()
    scene = make_scene({"step": 0.001, "duration": 1.0, "bodies": {"box": {
        "shape": "box", "size": [1.0, 1.0], "mass": 1.0, "position": [2.0, 0.0]}},
        "walls": {"floor": {"point": [0.0, -1.0], "normal": [0.0, 1.0]}}})
    per_ray, hits = box2d_v3.cast_rays(scene, [(0.0, 0.0, 3.0, 0.0), (0.0, 0.0, 0.0, -2.0),
                                              (0.0, 0.0, 0.0, 2.0)], repeats=3)
    (body, fraction, x, y), (wall, down, _, wy), (nothing, *_) = hits
    assert body == 0 and fraction == pytest.approx(0.5, abs=1e-6) and \
        (x, y) == pytest.approx((1.5, 0.0), abs=1e-6)
    assert wall == -1 and down == pytest.approx(0.5, abs=1e-6) and wy == pytest.approx(-1.0)
    assert nothing is None and per_ray > 0.0
