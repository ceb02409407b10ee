"""Narrow phase: where two convex shapes (or a shape and a wall) touch.

Each function takes shapes already placed in the fixed frame and returns the contact
points of their manifold as ``(point, normal, depth)``: the point halfway between
the two surfaces, the unit normal pointing from the first shape to the second, and the
penetration depth (positive when overlapping, negative for a gap). Points with a gap up
to ``margin`` are reported too, so that resting contacts do not flicker in and out of the
manifold.

Polygon against polygon uses the separating-axis test to find the axis of least
penetration, then clips the most anti-parallel ("incident") edge of the other polygon
against the side planes of that reference edge, which yields up to two points (the method
of Box2D's ``b2CollidePolygons``). Polygons must be convex and counter-clockwise here;
:class:`ConvexPolygon` makes them so.

Plain Python floats are used throughout: shapes have a handful of vertices, where numpy's
per-call cost would dominate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Union

import numpy as np

from ..geometry.planar import magnitude, perp_dot
from ..geometry.shapes import is_convex

__all__ = ["CirclePart", "PolygonPart", "Part", "ConvexPolygon", "polygon_polygon",
           "polygon_circle", "circle_circle", "half_plane_polygon", "half_plane_circle"]

Point = tuple[float, float]
ContactPoint = tuple[Point, Point, float]


class CirclePart(NamedTuple):
    """A circular part of a body: its center and radius (in body axes relative to the CM,
    or placed in the fixed frame)."""

    center: tuple[float, float]
    radius: float


class PolygonPart(NamedTuple):
    """A polygonal part of a body: its vertices and the outward unit normals of its edges
    (edge i from vertex i to i + 1), in body axes relative to the CM or placed. A body that
    collides only with walls keeps its outline as given and no normals: walls need only the
    vertices, so it may be concave."""

    vertices: list[tuple[float, float]]
    normals: list[tuple[float, float]]


Part = Union[CirclePart, PolygonPart]


@dataclass(frozen=True)
class ConvexPolygon:
    """A convex polygon in body axes, relative to the body's CM, counter-clockwise."""

    vertices: np.ndarray  # (k, 2)
    normals: np.ndarray  # (k, 2) outward unit normal of edge i -> i+1

    @classmethod
    def from_vertices(cls, vertices: np.ndarray) -> ConvexPolygon:
        """Orient counter-clockwise and check convexity; raises ValueError if not convex."""
        v = np.asarray(vertices, dtype=float)
        if not is_convex(v):
            raise ValueError("the polygon is not convex; split it into convex parts")
        if perp_dot(v, np.roll(v, -1, axis=0)).sum() < 0.0:
            v = v[::-1].copy()
        edges = np.roll(v, -1, axis=0) - v
        length = np.hypot(edges[:, 0], edges[:, 1])
        normals = np.column_stack([edges[:, 1], -edges[:, 0]]) / length[:, None]
        return cls(v, normals)

    def part(self) -> PolygonPart:
        """The polygon as plain floats, for detection."""
        return PolygonPart([(x, y) for x, y in self.vertices.tolist()],
                           [(x, y) for x, y in self.normals.tolist()])

    @property
    def inradius(self) -> float:
        """Distance from the vertex centroid to the nearest edge: half a thickness."""
        center = self.vertices.mean(axis=0)
        return float(np.min(np.einsum("ki,ki->k", self.normals, self.vertices - center)))


def _max_separation(verts1: list[Point], normals1: list[Point],
                    verts2: list[Point]) -> tuple[int, float]:
    """Edge of polygon 1 along whose normal polygon 2 is farthest out, and that distance."""
    best_edge, best = 0, -math.inf
    for i, ((nx, ny), (vx, vy)) in enumerate(zip(normals1, verts1)):
        s = min(nx * (x - vx) + ny * (y - vy) for x, y in verts2)
        if s > best:
            best_edge, best = i, s
    return best_edge, best


def _clip(p0: Point, p1: Point, nx: float, ny: float, offset: float) -> list[Point]:
    """Keep the part of segment p0-p1 with n . p <= offset (Sutherland-Hodgman, one plane)."""
    d0 = nx * p0[0] + ny * p0[1] - offset
    d1 = nx * p1[0] + ny * p1[1] - offset
    out = []
    if d0 <= 0.0:
        out.append(p0)
    if d1 <= 0.0:
        out.append(p1)
    if d0 * d1 < 0.0:
        t = d0 / (d0 - d1)
        out.append((p0[0] + t * (p1[0] - p0[0]), p0[1] + t * (p1[1] - p0[1])))
    return out


def polygon_polygon(verts_a: list[Point], normals_a: list[Point], verts_b: list[Point],
                    normals_b: list[Point], margin: float) -> list[ContactPoint]:
    """Contact manifold of two convex counter-clockwise polygons (normal from A to B)."""
    edge_a, sep_a = _max_separation(verts_a, normals_a, verts_b)
    if sep_a > margin:
        return []
    edge_b, sep_b = _max_separation(verts_b, normals_b, verts_a)
    if sep_b > margin:
        return []
    # Prefer A as the reference unless B's axis is clearly better: keeps the choice, and so
    # the contacts' feature names, stable from step to step.
    flip = sep_b > sep_a + 0.1 * margin
    if flip:
        ref_v, ref_n, edge, inc_v, inc_n = verts_b, normals_b, edge_b, verts_a, normals_a
    else:
        ref_v, ref_n, edge, inc_v, inc_n = verts_a, normals_a, edge_a, verts_b, normals_b
    nx, ny = ref_n[edge]
    incident = min(range(len(inc_n)), key=lambda i: nx * inc_n[i][0] + ny * inc_n[i][1])
    c0, c1 = inc_v[incident], inc_v[(incident + 1) % len(inc_v)]
    v1, v2 = ref_v[edge], ref_v[(edge + 1) % len(ref_v)]
    tx, ty = -ny, nx  # edge direction of a counter-clockwise polygon
    clipped = _clip(c0, c1, -tx, -ty, -(tx * v1[0] + ty * v1[1]))
    if len(clipped) < 2:
        return []
    clipped = _clip(clipped[0], clipped[1], tx, ty, tx * v2[0] + ty * v2[1])
    front = nx * v1[0] + ny * v1[1]
    normal = (-nx, -ny) if flip else (nx, ny)
    contacts = []
    for px, py in clipped:
        depth = front - (nx * px + ny * py)
        if depth >= -margin:
            contacts.append(((px + nx * depth / 2.0, py + ny * depth / 2.0), normal, depth))
    return contacts


def polygon_circle(verts: list[Point], normals: list[Point], center: Point,
                   radius: float, margin: float) -> list[ContactPoint]:
    """Contact of a convex polygon and a circle (normal from the polygon to the circle)."""
    cx, cy = center
    edge, sep = 0, -math.inf
    for i, ((nx, ny), (vx, vy)) in enumerate(zip(normals, verts)):
        s = nx * (cx - vx) + ny * (cy - vy)
        if s > sep:
            edge, sep = i, s
    if sep > radius + margin:
        return []
    v1, v2 = verts[edge], verts[(edge + 1) % len(verts)]
    if sep > 0.0:
        for vertex, other in ((v1, v2), (v2, v1)):
            if ((cx - vertex[0]) * (other[0] - vertex[0])
                    + (cy - vertex[1]) * (other[1] - vertex[1])) <= 0.0:
                dx, dy = cx - vertex[0], cy - vertex[1]
                distance = magnitude(dx, dy)
                if distance > radius + margin or distance == 0.0:
                    return []
                n = (dx / distance, dy / distance)
                depth = radius - distance
                point = (vertex[0] - n[0] * depth / 2.0, vertex[1] - n[1] * depth / 2.0)
                return [(point, n, depth)]
    n = normals[edge]
    depth = radius - sep
    point = (cx - n[0] * (radius - depth / 2.0), cy - n[1] * (radius - depth / 2.0))
    return [(point, n, depth)]


def circle_circle(center_a: Point, radius_a: float, center_b: Point,
                  radius_b: float, margin: float) -> list[ContactPoint]:
    """Contact of two circles (normal from A to B)."""
    dx, dy = center_b[0] - center_a[0], center_b[1] - center_a[1]
    distance = magnitude(dx, dy)
    depth = radius_a + radius_b - distance
    if depth < -margin:
        return []
    n = (dx / distance, dy / distance) if distance > 0.0 else (0.0, 1.0)
    reach = radius_a - depth / 2.0
    return [((center_a[0] + n[0] * reach, center_a[1] + n[1] * reach), n, depth)]


def half_plane_polygon(normal: Point, offset: float, verts: list[Point],
                       margin: float) -> list[ContactPoint]:
    """Vertices of a polygon behind the wall n . x >= offset (normal from wall to body)."""
    nx, ny = normal
    contacts = []
    for x, y in verts:
        depth = offset - (nx * x + ny * y)
        if depth > -margin:
            contacts.append(((x + nx * depth / 2.0, y + ny * depth / 2.0), normal, depth))
    return contacts


def half_plane_circle(normal: Point, offset: float, center: Point,
                      radius: float, margin: float) -> list[ContactPoint]:
    """A circle behind the wall n . x >= offset (normal from wall to body)."""
    nx, ny = normal
    depth = offset - (nx * center[0] + ny * center[1] - radius)
    if depth <= -margin:
        return []
    reach = radius - depth / 2.0
    return [((center[0] - nx * reach, center[1] - ny * reach), normal, depth)]
