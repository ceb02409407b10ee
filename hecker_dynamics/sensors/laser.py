"""Laser scans: closest-hit ray casts against walls, the other bodies' shapes and the map.

Each ray leaves the sensor's origin o along a unit direction d and travels a distance t to
its first hit within ``range_max``, found in closed form for every surface (rays x
surfaces):

- a wall (the half-plane n . (x - p) >= 0): t = n . (p - o) / (n . d);
- a circle of radius r at c: t = -b - sqrt(b^2 - |o - c|^2 + r^2) with b = (o - c) . d,
  the far root when the origin is inside;
- a polygon edge from a to a + e: t = perp_dot(a - o, e) / perp_dot(d, e) where the hit
  lies on the edge, 0 <= perp_dot(a - o, d) / perp_dot(d, e) <= 1 (boxes are polygons).

A hit beyond ``range_max`` is no return (the ray is a segment of that length, as in
Box2D's ray casts). The shapes ride on their bodies: a shape's points are kept as offsets
from the body's CM in body axes and turned by the body's angle at scan time, as every
body point is. The body carrying the sensor is not seen (the scanner sits inside it).

The cast runs in the compiled kernel when it is built and on (``src/kernel/raycast.c``),
else in numpy (:func:`cast`, the Python twin). Both take the same inputs (the origin, the
rays' directions and the bodies' cosines and sines, all from numpy) and evaluate each
surface's formula with the same operations in the same order; a hit counts where
0 <= t <= range_max; the nearest hit of a ray is the minimum of a set, whatever the order
its members were found in. So the two give the same bits, and the kernel may skip what
cannot be hit: bodies whose bounding circle (``reach`` plus :data:`SLACK`) lies beyond
``range_max`` or outside a ray's sweep, and bodies farther than a ray's nearest hit so
far (Box2D v3's dynamic tree clips a ray the same way). The map's boxes are fixed bodies
of their own, each at its centre and unturned, so they are culled the same way.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..dynamics import kernel
from ..geometry.planar import rotate
from ..geometry.shapes import Circle
from ..scene.load import Scene
from ..scene.sensors import LaserSpec
from .noise import Noise

try:
    from .. import _kernel  # type: ignore[attr-defined]
except ImportError:  # not built: no compiler or headers when installed
    _kernel = None

__all__ = ["Laser", "LaserScan", "SLACK", "cast"]

#: Slack added to each body's bounding radius (m) before anything is culled by it: far
#: above the rounding of a turned shape point or a hit distance (1e-16 of the scene's
#: size), so no body that a ray hits within range_max is ever culled.
SLACK = 1e-6


@dataclass(frozen=True)
class LaserScan:
    """One scan: ``ranges`` (m, float64; -inf below range_min, +inf for no return within
    range_max, as REP 117 says) at the sensor's ``angles`` (sensor frame)."""

    stamp_ns: int
    ranges: np.ndarray


def cast(origin: np.ndarray, directions: np.ndarray, range_max: float,
         walls: tuple[np.ndarray, np.ndarray], circles: tuple[np.ndarray, np.ndarray],
         edges: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Distance along each unit direction (R, 2) from ``origin`` (2,) to the first hit
    within ``range_max``, or +inf: ``walls`` are (points, unit normals), ``circles``
    (centers, radii) and ``edges`` (starts, end - start), all in the fixed frame. A ray
    grazing a surface (parallel to a wall or an edge) does not hit it. Every product and
    sum is written out as ``src/kernel/raycast.c`` evaluates it (no matrix products,
    whose sums BLAS may fuse or reorder)."""
    ox, oy = float(origin[0]), float(origin[1])
    dx, dy = directions[:, 0, None], directions[:, 1, None]  # (R, 1)
    best = np.full(len(directions), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        points, normals = walls
        if len(points):
            nx, ny = normals[:, 0], normals[:, 1]
            ahead = (points[:, 0] - ox) * nx + (points[:, 1] - oy) * ny
            _closest(best, ahead / (dx * nx + dy * ny), range_max)
        centers, radii = circles
        if len(centers):
            mx, my = ox - centers[:, 0], oy - centers[:, 1]
            b = dx * mx + dy * my  # (R, C)
            c = mx * mx + my * my - radii * radii
            root = np.sqrt(b * b - c)
            near = -b - root
            _closest(best, np.where(near >= 0.0, near, -b + root), range_max)
        starts, spans = edges
        if len(starts):
            ax, ay = starts[:, 0] - ox, starts[:, 1] - oy
            ex, ey = spans[:, 0], spans[:, 1]
            denominator = dx * ey - dy * ex  # perp_dot(d, e), (R, E)
            t = (ax * ey - ay * ex) / denominator
            s = (ax * dy - ay * dx) / denominator
            _closest(best, np.where((s >= 0.0) & (s <= 1.0), t, np.nan), range_max)
    return best + 0.0  # -0.0 and 0.0 alike as +0.0, whichever the minimum kept


def _closest(best: np.ndarray, t: np.ndarray, range_max: float) -> None:
    """Lower ``best`` (R,) to the nearest hit 0 <= t <= range_max of each row of ``t``
    (R, K); NaN is no hit."""
    hit = (t >= 0.0) & (t <= range_max)
    np.minimum(best, np.min(np.where(hit, t, np.inf), axis=1), out=best)


class Laser:
    """A laser scanner of a scene: the shapes of every body but its own, as offsets from
    their bodies' CMs, and the scene's walls; :meth:`scan` casts its rays at a state.
    ``compiled``: cast in the kernel (default: where :func:`..dynamics.kernel.enabled`)."""

    def __init__(self, spec: LaserSpec, scene: Scene, cm_local: np.ndarray,
                 compiled: Optional[bool] = None) -> None:
        """``cm_local`` (N, 2): each body's CM in its body frame (Model.cm_local)."""
        self.spec = spec
        self.noise = Noise(spec.seed, spec.frame_id, spec.period_ns)
        names = [b.name for b in scene.bodies]
        self.body = names.index(spec.body)
        self.mount = np.asarray(spec.position, dtype=float) - cm_local[self.body]
        # At the angles a LaserScan describes: its angle fields are float32 on the wire.
        self.increment = float(np.float32(spec.angle_increment))
        self.angles = float(np.float32(spec.angle_min)) + np.arange(spec.count) * self.increment
        self.walls = (np.array([w.point for w in scene.walls], dtype=float).reshape(-1, 2),
                      np.array([w.normal for w in scene.walls], dtype=float).reshape(-1, 2))
        circle_body, centers, radii, edge_body, starts, ends = [], [], [], [], [], []
        reach = np.zeros(len(names))
        for index, body in enumerate(scene.bodies):
            if index == self.body:
                continue
            cm = cm_local[index]
            for shape in body.shapes:
                if isinstance(shape, Circle):
                    center = np.asarray(shape.center) - cm
                    circle_body.append(index)
                    centers.append(center)
                    radii.append(shape.radius)
                    reach[index] = max(reach[index], np.hypot(*center) + shape.radius)
                else:
                    corners = shape.vertices - cm
                    edge_body.extend([index] * len(corners))
                    starts.extend(corners)
                    ends.extend(np.roll(corners, -1, axis=0))
                    reach[index] = max(reach[index], float(np.max(np.hypot(*corners.T))))
        self._circle_body = np.array(circle_body, dtype=np.int64)
        self._centers = np.array(centers, dtype=float).reshape(-1, 2)
        self._radii = np.array(radii, dtype=float)
        self._edge_body = np.array(edge_body, dtype=np.int64)
        self._starts = np.array(starts, dtype=float).reshape(-1, 2)
        self._spans = np.array(ends, dtype=float).reshape(-1, 2) - self._starts
        # The map's boxes are fixed bodies after the scene's: each at its centre, unturned,
        # its corners as offsets from there (the rows :meth:`distances` appends to q).
        boxes = np.zeros((0, 4, 2)) if scene.map is None else scene.map.occupancy.box_vertices()
        centers = boxes.mean(axis=1)
        self._map_rows = np.column_stack([centers, np.zeros(len(boxes))])
        corners = boxes - centers[:, None, :]
        first = len(names)
        self._edge_body = np.concatenate([self._edge_body, np.repeat(
            np.arange(first, first + len(boxes), dtype=np.int64), 4)])
        self._starts = np.concatenate([self._starts, corners.reshape(-1, 2)])
        self._spans = np.concatenate([self._spans, (np.roll(corners, -1, axis=1)
                                                    - corners).reshape(-1, 2)])
        reach = np.concatenate([reach, np.max(np.hypot(corners[..., 0], corners[..., 1]),
                                              axis=1, initial=0.0)])
        self._reach = reach + SLACK
        self._compiled = None
        if kernel.enabled() if compiled is None else compiled:
            if not kernel.built():
                raise ImportError("the compiled kernel is not built")
            self._compiled = _kernel.laser(
                reach=self._reach, circle_body=self._circle_body,
                circles=np.column_stack([self._centers, self._radii]),
                edge_body=self._edge_body, edges=np.hstack([self._starts, self._spans]),
                walls=np.hstack(self.walls), range_max=float(spec.range_max))

    @property
    def compiled(self) -> bool:
        """Whether the rays are cast in the kernel."""
        return self._compiled is not None

    def origin_and_heading(self, q: np.ndarray) -> tuple[np.ndarray, float]:
        """The sensor's origin (fixed frame) and the heading of its x axis, at CM state q."""
        x, y, theta = q[self.body].tolist()
        # numpy's cos and sin, as every other angle here; the turn of the mount in plain
        # floats (rotate's operations, without its arrays' overhead).
        c, s = float(np.cos(theta)), float(np.sin(theta))
        mx, my = self.mount.tolist()
        return np.array([x + (c * mx - s * my), y + (s * mx + c * my)]), theta + self.spec.angle

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Noise-free distance along each ray to its first hit within range_max (+inf for
        none), at CM state q (N, 3)."""
        origin, heading = self.origin_and_heading(q)
        angles = heading + self.angles
        directions = np.column_stack([np.cos(angles), np.sin(angles)])
        if len(self._map_rows):
            q = np.concatenate([q, self._map_rows])
        theta = q[:, 2]
        c, s = np.cos(theta), np.sin(theta)
        if self._compiled is not None:
            ranges = np.empty(len(angles))
            _kernel.laser_cast(self._compiled, q=np.ascontiguousarray(q, dtype=float), cos=c,
                               sin=s, origin=origin, directions=directions,
                               first=float(angles[0]), increment=self.increment,
                               ranges=ranges)
            return ranges
        cm = q[:, :2]
        # Broad phase: bodies whose bounding circle reaches within range_max of the origin.
        near = np.hypot(*(cm - origin).T) - self._reach <= self.spec.range_max
        circles = near[self._circle_body]
        body = self._circle_body[circles]
        centers = cm[body] + rotate(self._centers[circles], c[body], s[body])
        edges = near[self._edge_body]
        body = self._edge_body[edges]
        starts = cm[body] + rotate(self._starts[edges], c[body], s[body])
        spans = rotate(self._spans[edges], c[body], s[body])
        return cast(origin, directions, self.spec.range_max, self.walls,
                    (centers, self._radii[circles]), (starts, spans))

    def scan(self, q: np.ndarray, stamp_ns: int) -> LaserScan:
        """The scan at CM state q stamped ``stamp_ns``: distances plus seeded noise, then
        -inf below range_min and +inf beyond range_max (REP 117)."""
        spec = self.spec
        ranges = self.distances(q)
        if spec.noise > 0.0:
            # The noise goes on the hits only: a no-return stays +inf, where a draw that
            # overflows to -inf (a noise past 1e308 / 8.6) would make it NaN.
            draws = self.noise.normals(stamp_ns, len(ranges))
            ranges = np.where(ranges == np.inf, ranges, ranges + spec.noise * draws)
        ranges[ranges > spec.range_max] = np.inf
        ranges[ranges < spec.range_min] = -np.inf
        return LaserScan(stamp_ns, ranges)
