"""Laser scans against closed forms: the distance from a point along a direction to the
walls of a room (the inside slab), to a circle (the quadratic's near root) and to a turned
box (the slab method in the box's frame), to 1e-12 m, cast in the kernel and in Python;
the seeded noise replays; the kernel's casts have Python's bits, through rays that graze
edges, corners and circles and bodies that straddle range_max and the seam of a full
turn."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.geometry.shapes import Circle
from hecker_dynamics.scene.parameters import SceneError
from hecker_dynamics.scene.world import deleted
from hecker_dynamics.sensors.laser import Laser

ROOM = (6.0, 4.0)  # walls at x = 0, x = 6, y = 0, y = 4
WALLS = {"left": {"point": [0.0, 0.0], "normal": [1.0, 0.0]},
         "right": {"point": [ROOM[0], 0.0], "normal": [-1.0, 0.0]},
         "floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]},
         "ceiling": {"point": [0.0, ROOM[1]], "normal": [0.0, -1.0]}}


@pytest.fixture(autouse=True, params=["1", "0"], ids=["kernel", "python"])
def switch(request, monkeypatch):
    """Every test casts in the kernel (where built) and in Python."""
    monkeypatch.setenv(kernel.SWITCH, request.param)
    return request.param


def laser_of(params: dict, **laser) -> tuple[Laser, Model]:
    spec = {"type": "laser", "body": "robot", "range_max": 100.0, **laser}
    scene = make_scene({**params, "sensors": {"front": spec}})
    model = Model(scene)
    cast = Laser(scene.sensors[0], scene, model.cm_local)
    assert cast.compiled == kernel.enabled()
    return cast, model


def robot(**state) -> dict:
    # The CM is off the body-frame origin, so the mount's offset from the CM matters.
    return {"shape": "circle", "radius": 0.2, "center": [0.05, -0.03], "mass": 1.0, **state}


def expected_rays(position, heading, laser: Laser) -> tuple[np.ndarray, np.ndarray]:
    body_angle = laser.spec.angle
    c, s = math.cos(heading), math.sin(heading)
    mx, my = laser.spec.position
    origin = np.array([position[0] + c * mx - s * my, position[1] + s * mx + c * my])
    return origin, heading + body_angle + laser.angles


def test_walls_of_a_room_at_their_inside_slab_distances():
    position, heading = (1.7, 1.1), 0.4
    laser, model = laser_of({"bodies": {"robot": robot(position=list(position), angle=heading)},
                             "walls": WALLS},
                            position=[0.1, 0.05], angle=0.3, count=73)
    q, _ = model.initial_state()
    origin, angles = expected_rays(position, heading, laser)
    d = np.column_stack([np.cos(angles), np.sin(angles)])
    with np.errstate(divide="ignore"):
        tx = np.where(d[:, 0] > 0, (ROOM[0] - origin[0]) / d[:, 0], -origin[0] / d[:, 0])
        ty = np.where(d[:, 1] > 0, (ROOM[1] - origin[1]) / d[:, 1], -origin[1] / d[:, 1])
    expected = np.minimum(np.abs(tx), np.abs(ty))
    ranges = laser.scan(q, 0).ranges
    np.testing.assert_allclose(ranges, expected, rtol=0, atol=1e-12)


def test_a_circle_at_the_near_root_and_missed_beyond_its_tangents():
    distance, radius = 3.0, 0.5
    laser, model = laser_of({"bodies": {"robot": robot(),
                                        "ball": {"shape": "circle", "radius": radius,
                                                 "mass": 1.0, "position": [distance, 0.0]}}},
                            angle_min=-0.3, angle_max=0.3, count=61)
    q, _ = model.initial_state()
    ranges = laser.scan(q, 0).ranges
    a = laser.angles
    off = distance * np.sin(np.abs(a))
    hit = off < radius
    expected = distance * np.cos(a[hit]) - np.sqrt(radius ** 2 - off[hit] ** 2)
    assert hit.sum() == 33  # |angle| < asin(r / D) = 0.167
    assert np.all(np.isinf(ranges[~hit]))
    np.testing.assert_allclose(ranges[hit], expected, rtol=0, atol=1e-12)
    # The middle ray, at float32 angles a few 1e-8 rad off zero, meets the near pole.
    assert ranges[30] == pytest.approx(distance - radius, abs=1e-12)


def test_a_turned_box_at_its_slab_entry():
    width, height, phi, center = 1.2, 0.6, 0.7, np.array([2.5, 1.0])
    laser, model = laser_of({"bodies": {"robot": robot(),
                                        "crate": {"parts": {"hull": {"shape": "box",
                                                                     "size": [width, height]}},
                                                  "mass": 1.0, "position": center.tolist(),
                                                  "angle": phi}}},
                            angle_min=0.0, angle_max=0.8, count=81)
    q, _ = model.initial_state()
    ranges = laser.scan(q, 0).ranges
    # The slab method in the box's frame: entry = max of the per-axis nearer crossings.
    c, s = math.cos(-phi), math.sin(-phi)
    turn = np.array([[c, -s], [s, c]])
    origin = turn @ (np.zeros(2) - center)
    d = np.column_stack([np.cos(laser.angles), np.sin(laser.angles)]) @ turn.T
    half = np.array([width, height]) / 2
    with np.errstate(divide="ignore"):
        t1, t2 = (-half - origin) / d, (half - origin) / d
    enter = np.max(np.minimum(t1, t2), axis=1)
    leave = np.min(np.maximum(t1, t2), axis=1)
    hit = (enter <= leave) & (enter >= 0)
    assert 10 < hit.sum() < 81 and np.all(np.isinf(ranges[~hit]))
    np.testing.assert_allclose(ranges[hit], enter[hit], rtol=0, atol=1e-12)


def test_the_carrying_body_is_unseen_and_ranges_outside_the_limits_read_infinite():
    laser, model = laser_of({"bodies": {"robot": {"shape": "box", "size": [1.0, 1.0],
                                                  "mass": 1.0}},
                             "walls": WALLS},
                            angle_min=0.0, angle_max=0.0, count=1, range_min=0.0,
                            range_max=100.0)
    q, _ = model.initial_state()
    q[0, :2] = (1.0, 2.0)
    assert laser.scan(q, 0).ranges.tolist() == [5.0]  # the right wall, not the box itself
    near, _ = laser_of({"bodies": {"robot": robot()}, "walls": WALLS}, angle_min=0.0,
                       angle_max=math.pi, count=2, range_min=2.0, range_max=3.5)
    q[0, :2] = (1.0, 2.0)
    # Ahead: the wall 5 m away is beyond 3.5 m (+inf); behind: 1 m is below 2 m (-inf).
    assert near.scan(q, 0).ranges.tolist() == [math.inf, -math.inf]


def test_noise_is_gaussian_seeded_by_stamp_and_replays():
    laser, model = laser_of({"bodies": {"robot": robot(position=[3.0, 2.0])},
                             "walls": {"ceiling": WALLS["ceiling"]}},
                            angle_min=math.pi / 2, angle_max=math.pi / 2, count=1)
    q, _ = model.initial_state()
    exact = laser.distances(q)[0]
    noisy, _ = laser_of({"bodies": {"robot": robot(position=[3.0, 2.0])},
                         "walls": {"ceiling": WALLS["ceiling"]}},
                        angle_min=math.pi / 2, angle_max=math.pi / 2, count=1,
                        noise=0.01, seed=7)
    samples = np.array([noisy.scan(q, stamp).ranges[0] for stamp in range(4000)])
    assert np.array_equal(samples, [noisy.scan(q, stamp).ranges[0] for stamp in range(4000)])
    error = samples - exact
    assert abs(error.mean()) < 5 * 0.01 / math.sqrt(4000)
    assert error.std() == pytest.approx(0.01, rel=0.05)  # 5 sigma of a 4000-sample std


@pytest.mark.parametrize("laser, problem", [
    ({"body": "nobody"}, "names an unknown body"),
    ({"count": 2.5}, "must be a whole number"),
    ({"range_min": 2.0, "range_max": 1.0}, "must exceed range_min"),
    ({"angle_min": 1.0, "angle_max": 0.0}, "must be at least angle_min"),
    # One ray, cast at angle_min, under a scan that claimed angle_max 2.0 (increment 0).
    ({"angle_min": -2.0, "angle_max": 2.0, "count": 1}, "one ray is cast at angle_min"),
    ({"rate": 3.0}, "3 Hz is not a whole number of physics steps of 0.01 s"),
    # A period of 1e11 steps of 0.01 s (1e9 s) is whole; one of 1e13 is past what a
    # double divided from the rate tells to a step; a rate above 1/step samples nothing.
    ({"rate": 1e-13}, "1e-13 Hz is too slow: its period is 1e\\+15 physics steps of 0.01 s, "
                      "more than 1e\\+12"),
    ({"rate": 1000.0}, "1000 Hz is faster than the physics step of 0.01 s can sample "
                       "\\(at most 100 Hz\\)"),
    ({"rate": 150.0}, "150 Hz is faster than the physics step of 0.01 s can sample"),
    # Degrees where radians are meant: rays 270 rad round, each cast 43 times over.
    ({"angle_min": -135, "angle_max": 135},
     r"'sensors.front.angle_max': must be at most a full turn \(2 pi rad\) past angle_min "
     r"\(-135\), not 135: angles are in radians"),
])
def test_bad_laser_parameters_are_refused_by_name(laser, problem):
    spec = {"type": "laser", "body": "robot", **laser}
    with pytest.raises(SceneError, match=problem):
        make_scene({"step": 0.01, "bodies": {"robot": robot()}, "sensors": {"front": spec}})


def test_a_sensor_refuses_the_delete_of_its_body():
    scene = make_scene({"bodies": {"robot": robot(), "ball": robot(position=[1.0, 0.0])},
                        "sensors": {"front": {"type": "laser", "body": "robot"}}})
    with pytest.raises(SceneError, match="'robot' is named by sensor 'front'"):
        deleted(scene, "robot")
    assert [b.name for b in deleted(scene, "ball").bodies] == ["robot"]


def test_a_hit_beyond_range_max_is_no_return_whatever_the_noise():
    # Straight up from y = 2 to the ceiling at y = 4: 2 m, 1 mm beyond range_max. A noise
    # of 1 cm added to that hit would bring nearly half the readings within range.
    params = {"bodies": {"robot": robot(position=[3.0, 2.0])},
              "walls": {"ceiling": WALLS["ceiling"]}}
    ray = {"angle_min": math.pi / 2, "angle_max": math.pi / 2, "count": 1, "noise": 0.01,
           "seed": 3}
    beyond, model = laser_of(params, range_max=1.999, **ray)
    within, _ = laser_of(params, range_max=2.001, **ray)
    q, _ = model.initial_state()
    assert within.distances(q)[0] == pytest.approx(2.0, abs=1e-12)
    assert all(beyond.scan(q, stamp).ranges[0] == math.inf for stamp in range(200))
    assert sum(math.isfinite(within.scan(q, stamp).ranges[0]) for stamp in range(200)) > 50


def test_a_no_return_stays_infinite_under_a_noise_whose_draws_overflow():
    # Nothing above the robot within range_max: +inf, never inf + (-inf) = NaN from a
    # draw below -1.8 times a noise of 1e308 (such draws overflow to -inf).
    laser, model = laser_of({"bodies": {"robot": robot(position=[3.0, 2.0])}},
                            angle_min=-3.0, angle_max=3.0, count=50, noise=1e308, seed=5)
    q, _ = model.initial_state()
    ranges = np.concatenate([laser.scan(q, stamp).ranges for stamp in range(20)])
    assert np.all(ranges == math.inf)


def _shapes(rng: np.random.Generator) -> dict:
    kind = rng.integers(3)
    if kind == 0:
        return {"shape": "box", "size": rng.uniform(0.1, 1.0, 2).tolist()}
    if kind == 1:
        return {"shape": "circle", "radius": float(rng.uniform(0.05, 0.5))}
    corners = int(rng.integers(3, 9))
    turns = np.sort(rng.uniform(0.0, 2 * math.pi, corners))
    radii = rng.uniform(0.1, 0.6, corners)
    return {"shape": "polygon",
            "vertices": np.column_stack([radii * np.cos(turns), radii * np.sin(turns)]).ravel()
            .tolist()}


def test_kernel_casts_with_the_bits_of_python_through_grazing_rays(switch):
    """Random boxes, circles and polygons, at random states, then each moved so that a
    corner or a circle's tangent point lies on one of the rays (to the last bit of the
    turned shape), or so that the scanner sits inside it: a full turn of rays short of
    range_max (bodies straddle it and the seam at +-pi) and a fan whose first ray runs
    exactly along x, along a box's edge and tangent to a circle."""
    if switch == "0" or not kernel.built():
        pytest.skip("compares the kernel with Python")
    rng = np.random.default_rng(36)
    bodies = {"robot": robot(position=[0.5, 0.25]),
              # Along the fan's first ray y = 0.25: the box's lower edge, the circle's top.
              "slab": {"shape": "box", "size": [1.0, 0.5], "mass": 1.0, "position": [3.5, 0.5]},
              "drum": {"shape": "circle", "radius": 0.5, "mass": 1.0, "position": [6.0, -0.25]}}
    for k in range(24):  # named b*: the scene keeps its bodies in the order of their names
        bodies[f"b{k}"] = {**_shapes(rng), "mass": 1.0, "position": [float(k), -3.0]}  # unseen
    scene = make_scene({"bodies": bodies, "walls": WALLS, "sensors": {
        "turn": {"type": "laser", "body": "robot", "position": [0.1, 0.0], "count": 720,
                 "range_max": 3.0},
        "fan": {"type": "laser", "body": "robot", "angle_min": 0.0, "angle_max": 1.5,
                "count": 100, "range_max": 100.0}}})
    model = Model(scene)
    turn, fan = ([Laser(spec, scene, model.cm_local, compiled=compiled) for compiled in (1, 0)]
                 for name in ("turn", "fan") for spec in scene.sensors if spec.name == name)
    q0, _ = model.initial_state()
    ranges = fan[0].distances(q0)
    # The fan's first ray meets the slab's corner (3, 0.25) and grazes the drum's top.
    assert ranges[0] == 2.5 and ranges.tobytes() == fan[1].distances(q0).tobytes()
    # Each random body's shape about its CM: polygon corners, or circle (center, radius).
    local = []
    random = [i for i, body in enumerate(scene.bodies) if body.name.startswith("b")]
    for index in random:
        shape = scene.bodies[index].shapes[0]
        local.append((index, (np.asarray(shape.center) - model.cm_local[index], shape.radius)
                      if isinstance(shape, Circle) else shape.vertices - model.cm_local[index]))
    grazes = 0
    for _ in range(60):
        q = q0.copy()
        q[random, :2] = rng.uniform(-1.0, 7.0, (len(random), 2))
        q[:, 2] = rng.uniform(-math.pi, math.pi, len(q))
        origin, heading = turn[0].origin_and_heading(q)
        angles = heading + turn[0].angles
        for index, shape in local:
            aim = rng.integers(len(angles))
            d = np.array([math.cos(angles[aim]), math.sin(angles[aim])])
            if rng.random() < 0.1:  # the scanner inside the body
                q[index, :2] = origin
                continue
            c, s = math.cos(q[index, 2]), math.sin(q[index, 2])
            at = origin + rng.uniform(0.3, 3.5) * d
            if isinstance(shape, tuple):  # the circle's tangent point on the ray
                center, radius = shape
                at = at + radius * np.array([-d[1], d[0]]) * rng.choice([-1.0, 1.0])
                q[index, :2] = at - (c * center[0] - s * center[1], s * center[0] + c * center[1])
            else:
                x, y = shape[rng.integers(len(shape))]
                q[index, :2] = at - (c * x - s * y, s * x + c * y)
            grazes += 1
        for compiled, python in (turn, fan):
            assert compiled.distances(q).tobytes() == python.distances(q).tobytes()
    assert grazes > 1000
