"""Laser scans: closest-hit ray casts against walls, the other bodies' shapes and the map.

Each ray leaves the sensor's origin along a unit direction d and travels a distance t to
its first hit, found in closed form for every surface at once (numpy, rays x surfaces):

- a wall (the half-plane n . (x - p) >= 0): t = n . (p - o) / (n . d);
- a circle of radius r at c: t = -b - sqrt(b^2 - |o - c|^2 + r^2) with b = (o - c) . d,
  the far root when the origin is inside;
- a polygon edge from a to a + e: t = perp_dot(a - o, e) / perp_dot(d, e) where the hit
  lies on the edge, 0 <= perp_dot(a - o, d) / perp_dot(d, e) <= 1 (boxes are polygons).

The shapes ride on their bodies: a shape's points are kept as offsets from the body's CM
in body axes and turned by the body's angle at scan time, as every body point is. The body
carrying the sensor is not seen (the scanner sits inside it). A per-scan broad phase drops
the bodies whose bounding circle lies beyond ``range_max``. The map's boxes are polygons
fixed in the world.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from ..geometry.planar import perp_dot, rotate
from ..geometry.shapes import Circle
from ..scene.load import Scene
from ..scene.sensors import LaserSpec

__all__ = ["Laser", "LaserScan", "cast", "noise_generator"]


@dataclass(frozen=True)
class LaserScan:
    """One scan: ``ranges`` (m, float64; -inf below range_min, +inf for no return within
    range_max, as REP 117 says) at the sensor's ``angles`` (sensor frame)."""

    stamp_ns: int
    ranges: np.ndarray


def noise_generator(seed: int, name: str, stamp_ns: int) -> np.random.Generator:
    """The generator of a sensor's noise at one instant: a function of the seed, the
    sensor's name and the stamp only, so a replay that starts at a keyframe draws the
    same numbers as the live run did (SeedSequence and PCG64 are stable across numpy
    versions)."""
    entropy = [seed, zlib.crc32(name.encode()), stamp_ns % (1 << 64)]
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy)))


def cast(origin: np.ndarray, directions: np.ndarray, walls: tuple[np.ndarray, np.ndarray],
         circles: tuple[np.ndarray, np.ndarray], edges: tuple[np.ndarray, np.ndarray]
         ) -> np.ndarray:
    """Distance along each unit direction (R, 2) from ``origin`` (2,) to the first hit, or
    +inf: ``walls`` are (points, unit normals), ``circles`` (centers, radii) and ``edges``
    (starts, end - start), all in the fixed frame. A ray grazing a surface (parallel to a
    wall or an edge) does not hit it."""
    best = np.full(len(directions), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        points, normals = walls
        if len(points):
            t = np.einsum("ij,ij->i", points - origin, normals)[None, :] \
                / (directions @ normals.T)
            _closest(best, t, t >= 0.0)
        centers, radii = circles
        if len(centers):
            m = origin - centers  # (C, 2)
            b = directions @ m.T  # (R, C)
            c = np.einsum("ij,ij->i", m, m) - radii * radii
            root = np.sqrt(b * b - c)
            near = -b - root
            t = np.where(near >= 0.0, near, -b + root)
            _closest(best, t, t >= 0.0)
        starts, spans = edges
        if len(starts):
            to_start = starts - origin  # (E, 2)
            denominator = directions[:, None, 0] * spans[None, :, 1] \
                - directions[:, None, 1] * spans[None, :, 0]  # perp_dot(d, e)
            t = perp_dot(to_start, spans)[None, :] / denominator
            s = (to_start[None, :, 0] * directions[:, None, 1]
                 - to_start[None, :, 1] * directions[:, None, 0]) / denominator
            _closest(best, t, (t >= 0.0) & (s >= 0.0) & (s <= 1.0))
    return best


def _closest(best: np.ndarray, t: np.ndarray, hit: np.ndarray) -> None:
    """Lower ``best`` (R,) to the nearest hit of each row of ``t`` (R, K)."""
    np.minimum(best, np.min(np.where(hit, t, np.inf), axis=1), out=best)


class Laser:
    """A laser scanner of a scene: the shapes of every body but its own, as offsets from
    their bodies' CMs, and the scene's walls; :meth:`scan` casts its rays at a state."""

    def __init__(self, spec: LaserSpec, scene: Scene, cm_local: np.ndarray) -> None:
        """``cm_local`` (N, 2): each body's CM in its body frame (Model.cm_local)."""
        self.spec = spec
        names = [b.name for b in scene.bodies]
        self.body = names.index(spec.body)
        self.mount = np.asarray(spec.position, dtype=float) - cm_local[self.body]
        # At the angles a LaserScan describes: its angle fields are float32 on the wire.
        self.angles = float(np.float32(spec.angle_min)) + \
            np.arange(spec.count) * float(np.float32(spec.angle_increment))
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
        self._circle_body = np.array(circle_body, dtype=int)
        self._centers = np.array(centers, dtype=float).reshape(-1, 2)
        self._radii = np.array(radii, dtype=float)
        self._edge_body = np.array(edge_body, dtype=int)
        self._starts = np.array(starts, dtype=float).reshape(-1, 2)
        self._spans = np.array(ends, dtype=float).reshape(-1, 2) - self._starts
        self._reach = reach
        # The map's boxes stay where they are: their edges in the fixed frame, seen always.
        boxes = np.zeros((0, 4, 2)) if scene.map is None else scene.map.occupancy.box_vertices()
        self._map_starts = boxes.reshape(-1, 2)
        self._map_spans = (np.roll(boxes, -1, axis=1) - boxes).reshape(-1, 2)

    def origin_and_heading(self, q: np.ndarray) -> tuple[np.ndarray, float]:
        """The sensor's origin (fixed frame) and the heading of its x axis, at CM state q."""
        x, y, theta = q[self.body]
        c, s = np.cos(theta), np.sin(theta)
        return np.array([x, y]) + rotate(self.mount, c, s), float(theta + self.spec.angle)

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Noise-free distance along each ray to its first hit (+inf for none), at CM
        state q (N, 3)."""
        origin, heading = self.origin_and_heading(q)
        angles = heading + self.angles
        directions = np.column_stack([np.cos(angles), np.sin(angles)])
        cm, theta = q[:, :2], q[:, 2]
        # Broad phase: bodies whose bounding circle reaches within range_max of the origin.
        near = np.hypot(*(cm - origin).T) - self._reach <= self.spec.range_max
        circles = near[self._circle_body]
        body = self._circle_body[circles]
        centers = cm[body] + rotate(self._centers[circles], np.cos(theta[body]),
                                    np.sin(theta[body]))
        edges = near[self._edge_body]
        body = self._edge_body[edges]
        c, s = np.cos(theta[body]), np.sin(theta[body])
        starts = cm[body] + rotate(self._starts[edges], c, s)
        spans = rotate(self._spans[edges], c, s)
        return cast(origin, directions, self.walls, (centers, self._radii[circles]),
                    (np.concatenate([starts, self._map_starts]),
                     np.concatenate([spans, self._map_spans])))

    def scan(self, q: np.ndarray, stamp_ns: int) -> LaserScan:
        """The scan at CM state q stamped ``stamp_ns``: distances plus seeded noise, then
        -inf below range_min and +inf beyond range_max (REP 117)."""
        spec = self.spec
        ranges = self.distances(q)
        if spec.noise > 0.0:
            ranges = ranges + spec.noise * noise_generator(
                spec.seed, spec.frame_id, stamp_ns).standard_normal(len(ranges))
        ranges = np.where(ranges > spec.range_max, np.inf, ranges)
        ranges = np.where(ranges < spec.range_min, -np.inf, ranges)
        return LaserScan(stamp_ns, ranges)
