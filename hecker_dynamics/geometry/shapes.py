"""Shapes and their mass properties, integrated over the area.

Step 1 of the article's algorithm ("Physics, Part 2: Angular Effects", the center of mass
and the moment of inertia as integrals over the body, Eq. 3 and Eq. 13): the mass, the
center of mass (CM) and the moment of inertia about the CM follow from the shape and its
density. Polygons are integrated exactly by summing signed triangles fanned from the
origin, so either winding works; circles use their closed forms; a body made of several
shapes combines them with the parallel-axis theorem.

All shapes are given in their body's frame (the frame whose origin and axes the shape is
defined in), which need not have its origin at the CM.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Union

import numpy as np

from .planar import perp_dot

__all__ = ["GeometryError", "Polygon", "Circle", "Shape", "box", "AreaProperties", "MassProperties",
           "is_simple", "is_convex", "area_properties", "mass_properties",
           "energy_of_motion"]


class GeometryError(ValueError):
    """A shape that has no well-defined area or mass."""


@dataclass(frozen=True)
class Polygon:
    """A simple polygon, vertices in order (either winding), in the body frame."""

    vertices: np.ndarray  # (k, 2)

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices, dtype=float)
        if vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3:
            raise GeometryError("a polygon needs at least 3 vertices of 2 coordinates each")
        if not np.all(np.isfinite(vertices)):
            raise GeometryError("a polygon vertex is not a finite number")
        vertices.setflags(write=False)
        object.__setattr__(self, "vertices", vertices)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Polygon) and np.array_equal(self.vertices, other.vertices)

    def __hash__(self) -> int:
        return hash(self.vertices.tobytes())


@dataclass(frozen=True)
class Circle:
    """A disc of ``radius`` centered at ``center`` in the body frame."""

    center: tuple[float, float]
    radius: float

    def __post_init__(self) -> None:
        center = (float(self.center[0]), float(self.center[1]))
        if not all(math.isfinite(x) for x in (*center, self.radius)):
            raise GeometryError("a circle's center and radius must be finite numbers")
        if self.radius <= 0.0:
            raise GeometryError(f"a circle's radius must be positive, not {self.radius}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "radius", float(self.radius))


Shape = Union[Polygon, Circle]


def box(width: float, height: float, center: tuple[float, float] = (0.0, 0.0),
        angle: float = 0.0) -> Polygon:
    """Return a ``width`` x ``height`` rectangle centered at ``center``, turned by ``angle``."""
    if not (width > 0.0 and height > 0.0):
        raise GeometryError(f"a box needs a positive width and height, not {width} x {height}")
    half = np.array([[-width, -height], [width, -height], [width, height], [-width, height]]) / 2
    c, s = math.cos(angle), math.sin(angle)
    turned = half @ np.array([[c, s], [-s, c]])
    return Polygon(turned + np.asarray(center, dtype=float))


@dataclass(frozen=True)
class AreaProperties:
    """Area, centroid and polar second moment of area about the centroid of a shape."""

    area: float
    centroid: np.ndarray  # (2,)
    second_moment: float  # integral of |r - centroid|^2 dA


@dataclass(frozen=True)
class MassProperties:
    """Mass, center of mass and moment of inertia about the CM (Eq. 3 and Eq. 13)."""

    mass: float
    center_of_mass: tuple[float, float]  # body frame
    moment_of_inertia: float

    def energy_of_motion(self, speed: float, spin: float) -> float:
        """:func:`energy_of_motion` of this body."""
        return energy_of_motion(float(self.mass), float(self.moment_of_inertia),
                                float(speed), float(spin))


def energy_of_motion(mass: float, moment_of_inertia: float, speed: float, spin: float) -> float:
    """1/2 M v^2 + 1/2 I omega^2 of a body of ``mass`` moving its CM at ``speed`` and
    turning at ``spin``, I its moment of inertia about the CM (Eq. 13): ``inf`` where no
    double holds it. Plain floats (not numpy's), which overflow to inf quietly."""
    return 0.5 * mass * speed * speed + 0.5 * moment_of_inertia * spin * spin


def _segments_cross(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Whether closed segments p1-p2 and q1-q2 touch or cross, element-wise over the
    leading axes (the last holds x, y). Collinear touching is tested only where an
    orientation is zero."""
    d1 = perp_dot(q2 - q1, p1 - q1)
    d2 = perp_dot(q2 - q1, p2 - q1)
    d3 = perp_dot(p2 - p1, q1 - p1)
    d4 = perp_dot(p2 - p1, q2 - p1)
    touch = ((d1 > 0) != (d2 > 0)) & (d1 != 0) & (d2 != 0) & \
        ((d3 > 0) != (d4 > 0)) & (d3 != 0) & (d4 != 0)
    for a, b, p, d in ((q1, q2, p1, d1), (q1, q2, p2, d2), (p1, p2, q1, d3), (p1, p2, q2, d4)):
        zero = np.nonzero(d == 0)
        if zero[0].size:
            a, b, p = (np.broadcast_to(x, d.shape + (2,))[zero] for x in (a, b, p))
            touch[zero] |= np.all((np.minimum(a, b) <= p) & (p <= np.maximum(a, b)), axis=-1)
    return touch


def is_simple(vertices: np.ndarray) -> bool:
    """True if no two non-adjacent edges of the polygon touch: all k^2 / 2 pairs tested,
    a block of rows at a time (for scene loading, which bounds k)."""
    k = len(vertices)
    starts, ends = vertices, np.roll(vertices, -1, axis=0)
    edges = ends - starts
    turns = perp_dot(edges, np.roll(edges, -1, axis=0))
    if np.all(turns > 0.0) or np.all(turns < 0.0):
        # Strictly convex turns, each by less than pi, add up to whole turns: one is a
        # simple polygon (linear work, the common case), more a star.
        angles = np.arctan2(np.abs(turns), np.sum(edges * np.roll(edges, -1, axis=0), axis=1))
        if float(np.sum(angles)) < 3.0 * math.pi:
            return True
    block = 64
    for first in range(0, k - 2, block):
        i = np.arange(first, min(first + block, k - 2))[:, None]
        j = np.arange(first + 2, k)[None, :]
        # Pairs i < j that share no vertex: j >= i + 2, and not edges 0 and k - 1.
        apart = (j >= i + 2) & ~((i == 0) & (j == k - 1))
        pair_i, pair_j = np.broadcast_arrays(i, j)
        pair_i, pair_j = pair_i[apart], pair_j[apart]
        if np.any(_segments_cross(starts[pair_i], ends[pair_i], starts[pair_j], ends[pair_j])):
            return False
    return True


def is_convex(vertices: np.ndarray) -> bool:
    """True if every turn along the polygon goes the same way (collinear turns allowed)."""
    edges = np.roll(vertices, -1, axis=0) - vertices
    turns = perp_dot(edges, np.roll(edges, -1, axis=0))
    return bool(np.all(turns >= 0.0) or np.all(turns <= 0.0))


def area_properties(shape: Shape) -> AreaProperties:
    """Integrate area, centroid and second moment of area of a shape.

    For a polygon the integrals are sums over the signed triangles (o, v_i, v_i+1) fanned
    from a point o: each has signed area cross_i / 2, centroid (v_i + v_i+1) / 3 and polar
    second moment about o cross_i (v_i.v_i + v_i.v_i+1 + v_i+1.v_i+1) / 12, with the v_i
    taken relative to o. Fanning from the mean vertex, not the frame origin, keeps the
    parallel-axis step back to the centroid free of cancellation for a small shape far from
    its frame's origin. Dividing by the sign of the total makes the result independent of
    the winding.
    """
    if isinstance(shape, Circle):
        if not shape.radius < 1e150:  # as for polygons: the second moment would overflow
            raise GeometryError("the circle is too large to integrate in double precision")
        area = math.pi * shape.radius ** 2
        return AreaProperties(area, np.array(shape.center), area * shape.radius ** 2 / 2.0)
    vertices = np.ascontiguousarray(shape.vertices, dtype=float)
    known = _polygon_properties(vertices.tobytes(), len(vertices))
    return AreaProperties(known.area, known.centroid.copy(), known.second_moment)


@functools.lru_cache(maxsize=1024)
def _polygon_properties(data: bytes, count: int) -> AreaProperties:
    """:func:`area_properties` of the polygon of ``count`` vertices whose float64 (x, y)
    pairs are ``data``: a pile or a chain of like bodies integrates its outline once."""
    vertices = np.frombuffer(data).reshape(count, 2)
    repeated = np.flatnonzero((vertices == np.roll(vertices, -1, axis=0)).all(axis=1))
    if repeated.size:  # an edge of no length, which is_simple() takes for a crossing
        i = int(repeated[0])
        raise GeometryError(f"the polygon's vertices {i} and {(i + 1) % count} are the same "
                            "point (give each corner once: the last does not repeat the "
                            "first)")
    if not is_simple(vertices):
        raise GeometryError("the polygon's edges cross each other (it is not simple)")
    fan = vertices.mean(axis=0)
    v = vertices - fan
    w = np.roll(v, -1, axis=0)
    cross = perp_dot(v, w)
    signed_area = cross.sum() / 2.0
    scale = float(np.max(np.ptp(v, axis=0)))
    if not math.isfinite(signed_area) or not scale < 1e150:
        raise GeometryError("the polygon is too large to integrate in double precision")
    if not abs(signed_area) > 1e-12 * scale * scale:
        raise GeometryError("the polygon has zero area")
    centroid = (cross[:, None] * (v + w)).sum(axis=0) / (6.0 * signed_area)
    dots = (v * v).sum(axis=1) + (v * w).sum(axis=1) + (w * w).sum(axis=1)
    second_moment_fan = (cross * dots).sum() / 12.0 / math.copysign(1.0, signed_area)
    area = abs(signed_area)
    second_moment = second_moment_fan - area * float(centroid @ centroid)
    return AreaProperties(area, centroid + fan, second_moment)


def mass_properties(shapes: list[Shape] | tuple[Shape, ...],
                    densities: list[float]) -> MassProperties:
    """Combine shapes of the given densities into one body's mass, CM and inertia.

    The CM is the mass-weighted mean of the shapes' centroids (Eq. 3); each
    shape's inertia is moved to the common CM with the parallel-axis theorem.
    """
    if len(shapes) != len(densities) or not shapes:
        raise GeometryError("a body needs at least one shape, each with a density")
    parts = [area_properties(shape) for shape in shapes]
    masses = np.array([p.area * rho for p, rho in zip(parts, densities)])
    if not np.all(np.isfinite(masses)) or np.any(masses <= 0.0):
        raise GeometryError("every shape needs a positive, finite mass (check density or mass)")
    total = float(masses.sum())
    center = sum(m * p.centroid for m, p in zip(masses, parts)) / total
    inertia = sum(rho * p.second_moment + m * float((p.centroid - center) @ (p.centroid - center))
                  for m, rho, p in zip(masses, densities, parts))
    if not (math.isfinite(total) and math.isfinite(inertia) and inertia > 0.0):
        raise GeometryError(f"the mass ({total}) or moment of inertia ({inertia}) is not a "
                            "positive finite number")
    # F = M a (Eq. 5) and tau = I alpha (Eq. 14) are solved for a and alpha by dividing:
    # below 1/DBL_MAX (5.6e-309) the inverse is inf.
    if not (math.isfinite(1.0 / total) and math.isfinite(1.0 / float(inertia))):
        raise GeometryError(f"the mass ({total:g} kg) or moment of inertia ({inertia:g} kg m^2) "
                            "is so small that its inverse overflows a double")
    return MassProperties(total, (float(center[0]), float(center[1])), float(inertia))
