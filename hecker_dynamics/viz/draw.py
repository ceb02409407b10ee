"""Draw one frame of a scene with matplotlib (Agg, no window): bodies, springs, joints,
walls, forces at their points of application (a drive's wheel forces among them), the
lasers' rays to their hits (under the bodies), contact points, trails and the sim time.

Joints are drawn over the bodies: a pin (revolute) as a ring at its point, a weld as a
square, a slider (prismatic) as a ring on a short line along its axis, a rod as a solid
line and a rope as a dashed one between their points, a gear as a dotted line between its
two pins.

The article's subject is where each force acts: a force F at a point r from the CM turns
the body by the torque perp(r) . F (Eq. 11), so every applied force is drawn as an arrow
whose tail sits at its point of application, and every body shows its CM (where gravity
acts, making no torque) and a mark along its body-frame x axis that shows its angle.

Only the figure object and the Agg canvas are used (never pyplot), so drawing to files
works without a display and the pixels depend on nothing but the frame and the options.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle as CirclePatch
from matplotlib.patches import FancyArrow, Patch
from matplotlib.patches import Polygon as PolygonPatch

from ..dynamics import Model
from ..geometry import Circle, Polygon
from ..scene import Scene
from ..scene.joints import (
    DistanceJoint,
    GearJoint,
    JointSpec,
    PrismaticJoint,
    RevoluteJoint,
    WeldJoint,
)
from ..scene.load import SpringSpec
from .frames import BodyPose, Frame, Timeline, VizError, world_point

__all__ = ["View", "Trail", "Drawing", "BACKGROUND", "BODY_COLORS", "ARROW_COLOR", "RAY_COLOR",
           "DRAWING_COLORS", "parse_view", "parse_size", "parse_trail", "fit_view"]

BACKGROUND = "#ffffff"
WALL_COLOR = "#c8c8c8"
EDGE_COLOR = "#202020"
SPRING_COLOR = "#606060"
ARROW_COLOR = "#d62728"
CONTACT_COLOR = "#ff7f0e"
TRAIL_COLOR = "#7f7f7f"
JOINT_COLOR = "#ffffff"
RAY_COLOR = "#f7b6b6"
#: One fill per body, in the scene's order (matplotlib's tab10 without the arrow's red).
BODY_COLORS = ("#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf",
                "#ff7f0e")
#: Every colour a frame is drawn in (a GIF's palette holds each of them).
DRAWING_COLORS = (BACKGROUND, WALL_COLOR, EDGE_COLOR, SPRING_COLOR, ARROW_COLOR, CONTACT_COLOR,
                  TRAIL_COLOR, JOINT_COLOR, RAY_COLOR, *BODY_COLORS)
#: The longest force of a picture is drawn this fraction of the view's smaller side long.
ARROW_FRACTION = 0.25
#: Margin around the bodies' extent when the view is fitted, as a fraction of its size.
MARGIN = 0.08
DPI = 100


@dataclass(frozen=True)
class View:
    """The part of the fixed frame a picture shows (m)."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float


@dataclass(frozen=True)
class Trail:
    """A body point whose path is drawn: ``local`` in the body frame (its CM by default)."""

    body: int
    local: tuple[float, float]
    label: str
    points: list[tuple[float, float]] = field(default_factory=list, compare=False)


def parse_view(text: str) -> View:
    """``xmin,ymin,xmax,ymax`` (m) with a positive width and height."""
    try:
        numbers = [float(part) for part in text.split(",")]
    except ValueError:
        numbers = []
    if len(numbers) != 4 or not all(math.isfinite(x) for x in numbers):
        raise VizError(f"--view {text}: give four finite numbers xmin,ymin,xmax,ymax")
    view = View(*numbers)
    if not (view.xmax > view.xmin and view.ymax > view.ymin):
        raise VizError(f"--view {text}: the box has zero size (need xmax > xmin and "
                       "ymax > ymin)")
    return view


def parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, each from 16 to 4096."""
    width, _, height = text.lower().partition("x")
    try:
        size = (int(width), int(height))
    except ValueError:
        raise VizError(f"--size {text}: give WIDTHxHEIGHT in pixels, e.g. 480x360") from None
    if not all(16 <= n <= 4096 for n in size):
        raise VizError(f"--size {text}: width and height must be 16 to 4096 pixels")
    return size


def parse_trail(scene: Scene, text: str) -> Trail:
    """``BODY`` (its CM) or ``BODY/POINT`` (a named point of the body)."""
    name, slash, point = text.partition("/")
    names = [body.name for body in scene.bodies]
    if name not in names:
        raise VizError(f"--trail {text}: unknown body '{name}' (bodies: {', '.join(names)})")
    body = scene.bodies[names.index(name)]
    if slash and not point:
        raise VizError(f"--trail {text}: name a point of '{name}' after the '/', or give "
                       f"'{name}' alone for its CM")
    if not point:
        return Trail(names.index(name), body.mass.center_of_mass, text)
    if point not in body.points:
        raise VizError(f"--trail {text}: body '{name}' has no point '{point}' (points: "
                       f"{', '.join(body.points) or 'none'})")
    return Trail(names.index(name), body.points[point], text)


def _shape_extent(shape: Polygon | Circle, pose: BodyPose) -> np.ndarray:
    """Points whose bounding box is the shape's at ``pose``."""
    if isinstance(shape, Circle):
        cx, cy = world_point(pose, shape.center)
        r = shape.radius
        return np.array([[cx - r, cy - r], [cx + r, cy + r]])
    return np.array([world_point(pose, v) for v in shape.vertices.tolist()])


def fit_view(scene: Scene, frames: Sequence[Frame], size: tuple[int, int]) -> View:
    """A view around every body at every frame and the springs' anchors, reaching out to
    the walls near them, with the aspect of ``size``."""
    points = [_shape_extent(shape, pose) for frame in frames
              for body, pose in zip(scene.bodies, frame.poses) for shape in body.shapes]
    points += [np.array([force.point_b]) for force in scene.forces
               if isinstance(force, SpringSpec) and force.body_b is None]
    if scene.map is not None:  # the whole map: the world the bodies move in
        points.append(scene.map.occupancy.box_vertices().reshape(-1, 2))
    every = np.concatenate(points)
    (xmin, ymin), (xmax, ymax) = every.min(axis=0), every.max(axis=0)
    span = max(xmax - xmin, ymax - ymin, 1e-3)
    for wall in scene.walls:  # a wall within one extent of the bodies is part of the scene
        (px, py), (nx, ny) = wall.point, wall.normal
        if abs(ny) > 0.9 and ymin - span <= py <= ymax + span:
            ymin, ymax = min(ymin, py), max(ymax, py)
        elif abs(nx) > 0.9 and xmin - span <= px <= xmax + span:
            xmin, xmax = min(xmin, px), max(xmax, px)
    margin = MARGIN * max(xmax - xmin, ymax - ymin, 1e-3)
    return _with_aspect(View(xmin - margin, ymin - margin, xmax + margin, ymax + margin), size)


def _with_aspect(view: View, size: tuple[int, int]) -> View:
    """``view`` grown about its center in one direction so that one metre is as many pixels
    across as up (equal axes)."""
    width, height = view.xmax - view.xmin, view.ymax - view.ymin
    aspect = size[0] / size[1]
    if width / height < aspect:
        width = height * aspect
    else:
        height = width / aspect
    cx, cy = (view.xmin + view.xmax) / 2, (view.ymin + view.ymax) / 2
    return View(cx - width / 2, cy - height / 2, cx + width / 2, cy + height / 2)


def _zigzag(a: tuple[float, float], b: tuple[float, float], turns: int = 8,
            width: float = 0.0) -> np.ndarray:
    """A spring's zigzag from a to b, ``width`` across (a straight line when it is 0)."""
    a_, b_ = np.array(a), np.array(b)
    along = b_ - a_
    length = float(np.hypot(*along))
    if length == 0.0 or width == 0.0:
        return np.array([a_, b_])
    side = np.array([-along[1], along[0]]) / length * width / 2
    t = np.linspace(0.0, 1.0, 2 * turns + 3)
    offsets = np.zeros_like(t)
    offsets[2:-2] = np.where(np.arange(2 * turns - 1) % 2 == 0, 1.0, -1.0)
    return a_ + t[:, None] * along + offsets[:, None] * side


class Drawing:
    """A figure of ``size`` pixels showing ``view`` of a timeline's scene.

    :meth:`draw` replaces what the previous frame drew; the walls and the background are
    drawn once. :meth:`rgba` gives the pixels (rows from the top).
    """

    def __init__(self, timeline: Timeline, view: View, size: tuple[int, int], *,
                 trails: Sequence[Trail] = (), contacts: bool = False,
                 force_scale: Optional[float] = None) -> None:
        self.timeline = timeline
        self.scene = timeline.scene
        self.size = size
        self.view = _with_aspect(view, size)
        self.trails = [Trail(t.body, t.local, t.label) for t in trails]
        self.model = Model(self.scene) if contacts else None
        self.figure = Figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI,
                             facecolor=BACKGROUND)
        self.canvas = FigureCanvasAgg(self.figure)
        self.axes = self.figure.add_axes((0.0, 0.0, 1.0, 1.0))
        self.axes.set_axis_off()
        self.axes.set_xlim(self.view.xmin, self.view.xmax)
        self.axes.set_ylim(self.view.ymin, self.view.ymax)
        self.axes.set_autoscale_on(False)
        self.reach = [max(self._reach(shape, body.mass.center_of_mass) for shape in body.shapes)
                      for body in self.scene.bodies]
        side = min(self.view.xmax - self.view.xmin, self.view.ymax - self.view.ymin)
        largest = max((math.hypot(*c.force) for c in timeline.commands), default=0.0)
        self.force_scale = force_scale if force_scale is not None else \
            (ARROW_FRACTION * side / largest if largest > 0 else 0.0)
        self._artists: list[Any] = []
        self._index = {body.name: i for i, body in enumerate(self.scene.bodies)}
        self._named = {j.name: j for j in self.scene.joints}
        self._draw_walls()

    @staticmethod
    def _reach(shape: Polygon | Circle, cm: tuple[float, float]) -> float:
        if isinstance(shape, Circle):
            return math.hypot(shape.center[0] - cm[0], shape.center[1] - cm[1]) + shape.radius
        return float(np.max(np.hypot(*(shape.vertices - np.array(cm)).T)))

    def _draw_walls(self) -> None:
        """Each wall as its line with the solid side shaded, out to well past the view, and
        the map's boxes."""
        far = 10.0 * max(self.view.xmax - self.view.xmin, self.view.ymax - self.view.ymin)
        cx, cy = (self.view.xmin + self.view.xmax) / 2, (self.view.ymin + self.view.ymax) / 2
        for wall in self.scene.walls:
            (px, py), (nx, ny) = wall.point, wall.normal
            # The foot of the view center on the wall's line, so the line spans the view.
            d = nx * (cx - px) + ny * (cy - py)
            fx, fy = cx - d * nx, cy - d * ny
            tx, ty = -ny, nx
            solid = [(fx + far * tx, fy + far * ty), (fx - far * tx, fy - far * ty),
                     (fx - far * tx - far * nx, fy - far * ty - far * ny),
                     (fx + far * tx - far * nx, fy + far * ty - far * ny)]
            self.axes.add_patch(PolygonPatch(solid, closed=True, facecolor=WALL_COLOR,
                                             edgecolor=EDGE_COLOR, linewidth=1.0))
        if self.scene.map is not None:  # its occupied cells, as the bodies collide with them
            # One collection, not a patch a box: a map of 10^5 boxes took minutes a frame.
            self.axes.add_collection(PolyCollection(
                self.scene.map.occupancy.box_vertices(), closed=True, facecolors=WALL_COLOR,
                edgecolors=WALL_COLOR, linewidths=0.5))

    def pixel(self, x: float, y: float) -> tuple[int, int]:
        """The (column, row) of the pixel that shows the fixed-frame point (x, y)."""
        v, (w, h) = self.view, self.size
        return (int((x - v.xmin) / (v.xmax - v.xmin) * w),
                int((v.ymax - y) / (v.ymax - v.ymin) * h))

    def follow(self, frame: Frame) -> None:
        """Add ``frame``'s positions of the trailed points to their trails."""
        for trail in self.trails:
            trail.points.append(world_point(frame.poses[trail.body], trail.local))

    def draw(self, frame: Frame) -> None:
        """Draw ``frame`` over the walls, replacing the previous frame's drawing."""
        for artist in self._artists:
            artist.remove()
        self._artists = []
        add = self._artists.append
        axes = self.axes
        self.follow(frame)
        for trail in self.trails:
            xs, ys = zip(*trail.points)
            add(axes.plot(xs, ys, color=TRAIL_COLOR, linewidth=1.0)[0])
        if frame.rays:  # under the walls' and bodies' patches (zorder 1)
            add(axes.add_collection(LineCollection(frame.rays, colors=RAY_COLOR,
                                                   linewidths=0.6, zorder=0.5,
                                                   antialiaseds=False)))
        for force in self.scene.forces:
            if isinstance(force, SpringSpec):
                add(self._spring(force, frame.poses))
        for i, (body, pose) in enumerate(zip(self.scene.bodies, frame.poses)):
            color = BODY_COLORS[i % len(BODY_COLORS)]
            for shape in body.shapes:
                add(axes.add_patch(self._patch(shape, pose, color)))
            cm = world_point(pose, body.mass.center_of_mass)
            tip = world_point(pose, (body.mass.center_of_mass[0] + 0.5 * self.reach[i],
                                     body.mass.center_of_mass[1]))
            add(axes.plot([cm[0], tip[0]], [cm[1], tip[1]], color=EDGE_COLOR,
                          linewidth=1.5, solid_capstyle="butt")[0])
            add(axes.plot([cm[0]], [cm[1]], marker="o", markersize=3, color=EDGE_COLOR)[0])
        for joint in self.scene.joints:
            for artist in self._joint(joint, frame.poses):
                add(artist)
        if self.model is not None:
            points = self.timeline.contact_points(frame.poses, self.model)
            if points:
                xs, ys = zip(*points)
                add(axes.plot(xs, ys, linestyle="none", marker="o", markersize=3,
                              color=CONTACT_COLOR)[0])
        side = min(self.view.xmax - self.view.xmin, self.view.ymax - self.view.ymin)
        for arrow in frame.arrows:
            dx, dy = arrow.force[0] * self.force_scale, arrow.force[1] * self.force_scale
            length = math.hypot(dx, dy)
            if length > 0:
                head = min(0.04 * side, 0.5 * length)
                add(axes.add_patch(FancyArrow(
                    arrow.point[0], arrow.point[1], dx, dy, width=0.008 * side,
                    head_width=2.2 * head, head_length=head, length_includes_head=True,
                    color=ARROW_COLOR, linewidth=0)))
        add(axes.text(0.02, 0.97, f"t = {frame.time_ns * 1e-9:.2f} s", transform=axes.transAxes,
                      ha="left", va="top", fontsize=9, color=EDGE_COLOR))

    @staticmethod
    def _patch(shape: Polygon | Circle, pose: BodyPose, color: str) -> Patch:
        if isinstance(shape, Circle):
            return CirclePatch(world_point(pose, shape.center), shape.radius, facecolor=color,
                               edgecolor=EDGE_COLOR, linewidth=1.0)
        return PolygonPatch([world_point(pose, v) for v in shape.vertices.tolist()],
                            closed=True, facecolor=color, edgecolor=EDGE_COLOR,
                            linewidth=1.0)

    def _spring(self, spring: SpringSpec, poses: tuple[BodyPose, ...]) -> Line2D:
        index = {body.name: i for i, body in enumerate(self.scene.bodies)}
        a = world_point(poses[index[spring.body_a]], spring.point_a)
        b = spring.point_b if spring.body_b is None else \
            world_point(poses[index[spring.body_b]], spring.point_b)
        width = 0.03 * min(self.view.xmax - self.view.xmin, self.view.ymax - self.view.ymin)
        line = _zigzag(a, b, width=width)
        return self.axes.plot(line[:, 0], line[:, 1], color=SPRING_COLOR, linewidth=1.0)[0]

    def _ends(self, joint: JointSpec, poses: tuple[BodyPose, ...]
              ) -> tuple[tuple[float, float], tuple[float, float]]:
        """Where a joint's two points are now (fixed-frame coordinates)."""
        assert not isinstance(joint, GearJoint)
        index = self._index
        a = joint.point_a if joint.body_a is None else \
            world_point(poses[index[joint.body_a]], joint.point_a)
        return a, world_point(poses[index[joint.body_b]], joint.point_b)

    def _joint(self, joint: JointSpec, poses: tuple[BodyPose, ...]) -> list[Any]:
        axes, side = self.axes, min(self.view.xmax - self.view.xmin,
                                    self.view.ymax - self.view.ymin)
        mark: dict[str, Any] = dict(color=JOINT_COLOR, markeredgecolor=EDGE_COLOR, markersize=6,
                                    linestyle="none")
        if isinstance(joint, GearJoint):
            pins = [self._ends(self._named[name], poses)[1]
                    for name in (joint.joint_a, joint.joint_b)]
            (xa, ya), (xb, yb) = pins
            return [axes.plot([xa, xb], [ya, yb], color=EDGE_COLOR, linewidth=1.0,
                              linestyle=":")[0]]
        a, b = self._ends(joint, poses)
        if isinstance(joint, DistanceJoint):
            return [axes.plot([a[0], b[0]], [a[1], b[1]], color=EDGE_COLOR, linewidth=1.5,
                              linestyle="--" if joint.rope else "-")[0]]
        artists = []
        if isinstance(joint, PrismaticJoint):
            angle = 0.0 if joint.body_a is None else \
                poses[self._index[joint.body_a]].angle
            c, s = math.cos(angle), math.sin(angle)
            ux, uy = c * joint.axis[0] - s * joint.axis[1], s * joint.axis[0] + c * joint.axis[1]
            reach = 0.1 * side
            artists.append(axes.plot([a[0] - reach * ux, a[0] + reach * ux],
                                     [a[1] - reach * uy, a[1] + reach * uy],
                                     color=EDGE_COLOR, linewidth=1.0)[0])
        marker = "s" if isinstance(joint, WeldJoint) else "o"
        assert isinstance(joint, (RevoluteJoint, PrismaticJoint, WeldJoint))
        artists.append(axes.plot([b[0]], [b[1]], marker=marker, **mark)[0])
        return artists

    def rgba(self) -> np.ndarray:
        """The picture's pixels, (height, width, 4) uint8, rows from the top."""
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba()).copy()
