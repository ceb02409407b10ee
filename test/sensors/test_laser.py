"""Laser scans against closed forms: the distance from a point along a direction to the
walls of a room (the inside slab), to a circle (the quadratic's near root) and to a turned
box (the slab method in the box's frame), to 1e-12 m; the seeded noise replays."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.scene.parameters import SceneError
from hecker_dynamics.scene.world import deleted
from hecker_dynamics.sensors.laser import Laser

ROOM = (6.0, 4.0)  # walls at x = 0, x = 6, y = 0, y = 4
WALLS = {"left": {"point": [0.0, 0.0], "normal": [1.0, 0.0]},
         "right": {"point": [ROOM[0], 0.0], "normal": [-1.0, 0.0]},
         "floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]},
         "ceiling": {"point": [0.0, ROOM[1]], "normal": [0.0, -1.0]}}


def laser_of(params: dict, **laser) -> tuple[Laser, Model]:
    spec = {"type": "laser", "body": "robot", "range_max": 100.0, **laser}
    scene = make_scene({**params, "sensors": {"front": spec}})
    model = Model(scene)
    return Laser(scene.sensors[0], scene, model.cm_local), model


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
    ({"rate": 3.0}, "not a whole number of physics steps"),
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
