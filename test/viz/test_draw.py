"""One frame read back pixel by pixel: a body's fill where its shape is at its pose and
background where it is not, and force arrows pointing along their force.

The view is 4 m x 3 m drawn on 400 x 300 pixels, so one metre is exactly 100 pixels and
the pixel of a point follows from the view alone; every sampled point is at least 5 pixels
from an edge, a mark or another shape, so anti-aliasing cannot reach it.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib is not installed (the viz extra)")
pytest.importorskip("PIL", reason="Pillow is not installed (the viz extra)")
from scene_builders import box_body, make_scene  # noqa: E402

from hecker_dynamics.scene import WrenchCommand  # noqa: E402
from hecker_dynamics.viz.draw import ARROW_COLOR, BACKGROUND, BODY_COLORS, Drawing, View  # noqa: E402
from hecker_dynamics.viz.frames import BodyPose, Timeline  # noqa: E402

VIEW = View(-2.0, -1.5, 2.0, 1.5)
SIZE = (400, 300)


def _rgb(hex_color: str) -> tuple[int, int, int]:
    return tuple(int(hex_color[i:i + 2], 16) for i in (1, 3, 5))


def _pixel(image: np.ndarray, x: float, y: float) -> tuple[int, int, int]:
    """The color shown at fixed-frame point (x, y): 100 px per metre from the view's
    top-left corner (-2, 1.5)."""
    column, row = int((x - VIEW.xmin) * 100), int((VIEW.ymax - y) * 100)
    return tuple(int(c) for c in image[row, column, :3])


def _scene():
    return make_scene({"step": 0.01, "bodies": {"box": box_body(size=(1.0, 0.5))}})


def _picture(pose: BodyPose, commands=(), force_scale=None) -> np.ndarray:
    scene = _scene()
    timeline = Timeline(scene, 0, 10**9, [0], [(pose,)], list(commands))
    drawing = Drawing(timeline, VIEW, SIZE, force_scale=force_scale)
    assert drawing.view == VIEW  # the view already has the picture's aspect
    drawing.draw(next(timeline.frames([0])))
    image = drawing.rgba()
    assert image.shape == (300, 400, 4)
    return image


def test_box_is_filled_at_its_pose_and_nowhere_else():
    image = _picture(BodyPose(1.0, 0.5, 0.0))  # spans x 0.5..1.5, y 0.25..0.75
    fill, background = _rgb(BODY_COLORS[0]), _rgb(BACKGROUND)
    for x, y in [(0.75, 0.4), (1.25, 0.6), (0.6, 0.3)]:
        assert _pixel(image, x, y) == fill
    for x, y in [(1.6, 0.5), (1.0, 0.85), (1.0, 0.15), (0.4, 0.5), (-1.0, -1.0)]:
        assert _pixel(image, x, y) == background


def test_turned_box_is_filled_where_the_turn_puts_it():
    # A quarter turn about the body origin: the box now spans x 0.75..1.25, y 0..1.
    image = _picture(BodyPose(1.0, 0.5, math.pi / 2))
    fill, background = _rgb(BODY_COLORS[0]), _rgb(BACKGROUND)
    for x, y in [(0.85, 0.1), (1.15, 0.9), (0.85, 0.9)]:
        assert _pixel(image, x, y) == fill
    for x, y in [(0.6, 0.5), (1.4, 0.5), (1.0, 1.1)]:  # inside the unturned box's span
        assert _pixel(image, x, y) == background


def _command(frame_id, point, force):
    return WrenchCommand(0, "box", "test", frame_id, point, force)


@pytest.mark.parametrize("force, along", [((10.0, 0.0), (1.0, 0.0)), ((0.0, 10.0), (0.0, 1.0)),
                                          ((-10.0, 0.0), (-1.0, 0.0))])
def test_world_force_arrow_points_along_the_force(force, along):
    # Scale 0.075 m/N: a 10 N arrow is 0.75 m long from its tail at (-1, 0), its head the
    # last 0.12 m and 0.26 m wide; 0.66 m along is inside the head.
    image = _picture(BodyPose(1.0, 0.5, 0.0), [_command("world", (-1.0, 0.0), force)],
                     force_scale=0.075)
    red, background = _rgb(ARROW_COLOR), _rgb(BACKGROUND)
    assert _pixel(image, -1.0 + 0.66 * along[0], 0.66 * along[1]) == red
    for ax, ay in [(-along[0], -along[1]), (along[1], along[0]), (-along[1], -along[0])]:
        assert _pixel(image, -1.0 + 0.66 * ax, 0.66 * ay) == background


def test_body_frame_force_turns_with_the_body():
    # Force (10, 0) N in the axes of a box turned by a quarter turn points along +y, from
    # the body point (0.5, 0) (the box's right edge midpoint), which is at world (0.5, 0).
    pose = BodyPose(0.5, -0.5, math.pi / 2)
    image = _picture(pose, [_command("box", (0.5, 0.0), (10.0, 0.0))], force_scale=0.075)
    red, background = _rgb(ARROW_COLOR), _rgb(BACKGROUND)
    assert _pixel(image, 0.5, 0.66) == red
    assert _pixel(image, 0.5 + 0.66, 0.0) == background
    assert _pixel(image, 0.5 - 0.66, 0.0) == background


def test_ended_command_draws_no_arrow():
    command = WrenchCommand(0, "box", "test", "world", (-1.0, 0.0), (10.0, 0.0),
                            duration_ns=500_000_000)
    scene = _scene()
    timeline = Timeline(scene, 0, 10**9, [0], [(BodyPose(1.0, 0.5, 0.0),)], [command])
    during, after = timeline.frames([400_000_000, 500_000_000])
    assert len(during.arrows) == 1 and during.arrows[0].force == (10.0, 0.0)
    assert after.arrows == ()


def test_a_pin_is_drawn_at_its_point_as_the_body_turns():
    """A box pinned to the world at its left end, (-1, 0.5): the pin's ring is white at
    that point, over the box's fill, whatever the box's angle."""
    from hecker_dynamics.viz.draw import JOINT_COLOR
    scene = make_scene({"step": 0.01, "bodies": {"box": box_body(size=(1.0, 0.5),
                                                               position=[-0.5, 0.5])},
                        "joints": {"pin": {"type": "revolute", "body_b": "box",
                                           "point_b": [-0.5, 0.0]}}})
    for angle in (0.0, 0.7):
        pose = BodyPose(-1.0 + 0.5 * math.cos(angle), 0.5 + 0.5 * math.sin(angle), angle)
        timeline = Timeline(scene, 0, 10**9, [0], [(pose,)], [])
        drawing = Drawing(timeline, VIEW, SIZE)
        drawing.draw(next(timeline.frames([0])))
        image = drawing.rgba()
        assert _pixel(image, -1.0, 0.5) == _rgb(JOINT_COLOR)
        assert _pixel(image, -1.0 + 0.3 * math.cos(angle), 0.5 + 0.3 * math.sin(angle)) == \
            _rgb(BODY_COLORS[0])


def test_laser_rays_run_from_the_laser_to_their_hits_under_the_bodies():
    """A laser at the origin, its three rays along +x, +y and -x: the wall at x = -1.5
    (1.5 m), the box's face at x = 0.75 (0.25 m short of its centre at 1, half-length
    0.25), nothing up. The ray's colour shows between the laser and its hits, not beyond
    them."""
    from hecker_dynamics.viz.draw import RAY_COLOR

    scene = make_scene({"step": 0.01, "bodies": {
        "robot": {"shape": "circle", "radius": 0.05, "mass": 1.0},
        "box": box_body(size=(0.5, 0.5), position=[1.0, 0.0])},
        "walls": {"west": {"point": [-1.5, 0.0], "normal": [1.0, 0.0]}},
        "sensors": {"laser": {"type": "laser", "body": "robot", "angle_min": 0.0,
                              "angle_max": math.pi, "count": 3, "range_max": 5.0}}})
    poses = (BodyPose(1.0, 0.0, 0.0), BodyPose(0.0, 0.0, 0.0))  # box, robot (by name)
    timeline = Timeline(scene, 0, 10**9, [0], [poses], [])
    frame = next(timeline.frames([0]))
    (east_start, east), (west_start, west) = frame.rays
    assert west_start == east_start == (0.0, 0.0)
    assert east == (0.75, 0.0)
    assert west == pytest.approx((-1.5, 0.0), abs=1e-6)  # along float32(pi), not pi
    drawing = Drawing(timeline, VIEW, SIZE)
    drawing.draw(frame)
    image = drawing.rgba()

    def tinted(x: float, y: float) -> bool:
        """The ray's colour over the background, anti-aliased: a thin line on a pixel
        border covers two rows in part."""
        red, green, blue = _pixel(image, x, y)
        return red > 240 and green == blue and green < 250

    assert tinted(-0.8, 0.0) and tinted(0.4, 0.0) and _rgb(RAY_COLOR)[1] < 200
    assert not tinted(-1.6, 0.0) and not tinted(0.0, 0.6)  # past the wall; the ray up missed
    assert _pixel(image, 0.85, 0.0) == _rgb(BODY_COLORS[0])  # the ray stopped at the face


def test_a_run_draws_its_drive_s_wheel_forces_at_the_wheels():
    """The robot's drive pushes from 0.5 s: at 0.6 s two forward arrows, one at each
    wheel, the wheels' separation (0.34 m) apart."""
    from hecker_dynamics.scene import load_scene
    from hecker_dynamics.viz.frames import run_timeline

    timeline = run_timeline(load_scene("robot"), 1_000_000_000)
    assert {c.source for c in timeline.commands} == {"drive/base/left", "drive/base/right"}
    left, right = next(timeline.frames([600_000_000])).arrows
    assert math.dist(left.point, right.point) == pytest.approx(0.34, abs=1e-3)
    assert left.force[0] > 1.0 and right.force[0] > 1.0


def test_a_map_is_drawn_as_one_collection_of_its_boxes():
    """The warehouse map's boxes were one patch each: a 3000 x 3000-cell map with 2 %
    of its cells occupied (180 000 boxes) took over 1.3 GB and minutes a frame to render.
    They are one collection, every box in it, drawn before the bodies."""
    from hecker_dynamics.scene import load_scene

    scene = load_scene("warehouse")
    boxes = scene.map.occupancy.box_vertices()
    timeline = Timeline(scene, 0, 10**9, [0], [tuple(BodyPose(0.0, 0.0, 0.0)
                                                     for _ in scene.bodies)], [])
    drawing = Drawing(timeline, View(-1.0, -1.0, 8.0, 6.0), SIZE)
    maps = [c for c in drawing.axes.collections if len(c.get_paths()) == len(boxes)]
    assert len(boxes) > 3 and len(maps) == 1
    assert len(drawing.axes.patches) == len(scene.walls)
    assert all(np.array_equal(path.vertices[:4], corners)
               for path, corners in zip(maps[0].get_paths(), boxes))
