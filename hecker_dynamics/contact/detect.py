"""Detection (C twin: ``src/kernel/detect.c``): shape points behind
walls, bodies against the map's boxes, and overlapping convex parts of bodies that the
scene lets collide, found by a sort-and-sweep broad phase
on the x extent, then the narrow phase of :mod:`.collision` (``src/kernel/manifold.c``).
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np
from numpy.typing import NDArray

from ..geometry.planar import cos_sin_of, magnitude
from .collision import (
    CirclePart,
    ContactPoint,
    Part,
    PolygonPart,
    circle_circle,
    half_plane_circle,
    half_plane_polygon,
    polygon_circle,
    polygon_polygon,
)
from .materials import Material, PairMaterials
from .rows import States

__all__ = ["MARGIN", "MAX_SUBSTEPS", "Contact", "Detection", "collide"]

#: Gap (m) within which shapes already count as touching, so resting contacts persist.
MARGIN = 5e-3
#: The most sub-steps :meth:`Detection.substeps` asks for.
MAX_SUBSTEPS = 256


class Contact(NamedTuple):
    """A contact found by detection: bodies ``a`` (-1 for a wall) and ``b``, the point
    halfway between the surfaces, the unit normal from a to b, the overlap (negative for a
    gap within :data:`MARGIN`), restitution ``e`` and friction ``mu``, and the names of the
    two parts (``key``: a wall is body -1 - its index) by which warm starting knows it."""

    a: int
    b: int
    point: tuple[float, float]
    normal: tuple[float, float]
    depth: float
    e: float
    mu: float
    key: tuple[int, int, int, int]


class Detection:
    """Detection for :class:`~.solver.ContactPass`, which sets these attributes up from
    the scene: each wall's bodies, normal, offset and material; the pairs' materials; each
    body's parts (relative to its CM, in body axes) and reach (its farthest shape point
    from the CM); the colliding bodies and their thinnest part."""

    wall_bodies: list[list[int]]
    wall_normal: list[tuple[float, float]]
    wall_offset: list[float]
    wall_material: list[tuple[float, float]]
    pairs: PairMaterials
    parts: list[list[Part]]
    colliding: list[int]
    reach: list[float]
    thickness: float
    _lean: bool
    static_parts: list[PolygonPart]
    static_bounds: NDArray[np.float64]
    static_material: tuple[float, float]
    static_bodies: list[int]
    #: The bodies whose travel sets the sub-steps: the colliding ones and the map's.
    swept: list[int]
    _colliding_index: NDArray[np.int_]
    _colliding_reach: NDArray[np.float64]
    _woken: set[int]

    def _world_parts(self, pose: list[float], body: int) -> list[Part]:
        """The body's parts placed at ``pose`` = [x, y, angle] of its CM."""
        x, y, angle = pose
        c, s = cos_sin_of(angle)
        placed: list[Part] = []
        for part in self.parts[body]:
            if isinstance(part, CirclePart):
                lx, ly = part.center
                placed.append(CirclePart((x + c * lx - s * ly, y + s * lx + c * ly),
                                         part.radius))
            else:
                verts = [(x + c * a - s * b, y + s * a + c * b) for a, b in part.vertices]
                normals = [(c * a - s * b, s * a + c * b) for a, b in part.normals]
                placed.append(PolygonPart(verts, normals))
        return placed

    @staticmethod
    def _bounds(part: Part) -> tuple[float, float, float, float]:
        if isinstance(part, CirclePart):
            (x, y), r = part
            return x - r, x + r, y - r, y + r
        xs = [p[0] for p in part.vertices]
        ys = [p[1] for p in part.vertices]
        return min(xs), max(xs), min(ys), max(ys)

    def detect(self, q: States) -> list[Contact]:
        """The contacts at positions ``q``: walls first, then the pairs the broad phase
        finds, in a deterministic order."""
        return self._detect(q, None)

    def _detect(self, q: States, island: Optional[list[int]]) -> list[Contact]:
        """:meth:`detect`, but with ``island`` (each body's sleeping island, -1 awake)
        skipping sleeping bodies' walls and pairs and noting in ``_woken`` the islands an
        awake body touches."""
        world: dict[int, list[Part]] = {}
        poses = q.tolist()
        contacts: list[Contact] = []
        for w, bodies in enumerate(self.wall_bodies):
            normal, offset = self.wall_normal[w], self.wall_offset[w]
            nx, ny = normal
            e, mu = self.wall_material[w]
            for b in bodies:
                if island is not None and island[b] >= 0:
                    continue
                x, y, _ = poses[b]
                if nx * x + ny * y - offset > self.reach[b] + MARGIN:
                    continue  # the body's bounding circle is clear of the wall
                if b not in world:
                    world[b] = self._world_parts(poses[b], b)
                for p, part in enumerate(world[b]):
                    found = (half_plane_circle(normal, offset, *part, MARGIN)
                             if isinstance(part, CirclePart)
                             else half_plane_polygon(normal, offset, part.vertices, MARGIN))
                    for point, n, depth in found:
                        contacts.append(Contact(-1, b, point, n, depth, e, mu, (-1 - w, b, 0, p)))
        if self.static_bodies:
            contacts.extend(self._static_contacts(poses, island, world))
        if island is not None and all(island[b] >= 0 for b in self.colliding):
            return contacts  # with every colliding body asleep no pair needs looking at
        for a, b, material in self._candidate_pairs(poses) if self.colliding else ():
            sleeping = -1 if island is None else max(island[a], island[b])
            if sleeping >= 0 and min(island[a], island[b]) >= 0:  # type: ignore[index]
                continue
            for body in (a, b):
                if body not in world:
                    world[body] = self._world_parts(poses[body], body)
            touching = self._pair_contacts(a, b, material, world)
            if touching and sleeping >= 0:
                self._woken.add(sleeping)
            contacts.extend(touching)
        return contacts

    def _static_contacts(self, poses: list[list[float]], island: Optional[list[int]],
                         world: dict[int, list[Part]]) -> list[Contact]:
        """Contacts of the map's boxes (body -1; box k's key -1 - (walls + k)) with the
        awake bodies that collide with them, box by box in the map's order."""
        contacts: list[Contact] = []
        first = -1 - len(self.wall_bodies)
        e, mu = self.static_material
        x0, x1, y0, y1 = self.static_bounds.T
        for b in self.static_bodies:
            if island is not None and island[b] >= 0:
                continue
            x, y, _ = poses[b]
            r = self.reach[b] + MARGIN
            near = np.flatnonzero((x0 <= x + r) & (x1 >= x - r) & (y0 <= y + r) & (y1 >= y - r))
            if not len(near):
                continue
            if b not in world:
                world[b] = self._world_parts(poses[b], b)
            for k in near.tolist():
                for p, part in enumerate(world[b]):
                    for point, n, depth in collide(self.static_parts[k], part):
                        contacts.append(Contact(-1, b, point, n, depth, e, mu,
                                                (first - k, b, 0, p)))
        return contacts

    def _candidate_pairs(self, poses: list[list[float]]) -> list[tuple[int, int, Material]]:
        """Colliding pairs whose bounding boxes (CM +- reach) overlap, with their material:
        sort and sweep on x."""
        boxes = sorted((x - self.reach[b], b, x + self.reach[b], y - self.reach[b],
                        y + self.reach[b]) for b in self.colliding for x, y, _ in (poses[b],))
        pairs = []
        for n, (_, b1, x1, y0, y1) in enumerate(boxes):
            for u0, b2, _, v0, v1 in boxes[n + 1:]:
                if u0 > x1 + MARGIN:
                    break
                if not (v0 <= y1 + MARGIN and v1 >= y0 - MARGIN):
                    continue
                a, b = (b1, b2) if b1 < b2 else (b2, b1)
                material = self.pairs.get(a, b)
                if material is not None:
                    pairs.append((a, b, material))
        return pairs

    def _pair_contacts(self, a: int, b: int, material: Material,
                       world: dict[int, list[Part]]) -> list[Contact]:
        """Contacts between the parts of bodies a < b whose bounds overlap, of ``material``."""
        bounds_b = [self._bounds(part) for part in world[b]]
        contacts = []
        for pa, part_a in enumerate(world[a]):
            x0, x1, y0, y1 = self._bounds(part_a)
            for pb, (part_b, (u0, u1, v0, v1)) in enumerate(zip(world[b], bounds_b)):
                if u0 > x1 + MARGIN or u1 < x0 - MARGIN or v0 > y1 + MARGIN or v1 < y0 - MARGIN:
                    continue
                for point, normal, depth in collide(part_a, part_b):
                    contacts.append(Contact(a, b, point, normal, depth, *material, (a, b, pa, pb)))
        return contacts

    def substeps(self, q0: States, q1: States) -> int:
        """How many sub-steps keep every colliding body's travel under half the thinnest
        colliding part (1 when the step is short enough)."""
        if not self.swept:
            return 1
        farthest: float
        if self._lean:  # a few bodies: plain floats beat numpy's cost per call
            before, after = q0.tolist(), q1.tolist()
            farthest = max(magnitude(after[i][0] - before[i][0], after[i][1] - before[i][1])
                           + abs(after[i][2] - before[i][2]) * self.reach[i]
                           for i in self.swept)
        else:
            index = self._colliding_index
            moved = q1[index] - q0[index]
            farthest = float((np.hypot(moved[:, 0], moved[:, 1])
                              + np.abs(moved[:, 2]) * self._colliding_reach).max())
        if not math.isfinite(farthest):
            return 1  # a blown-up state: the simulation's divergence check reports it
        return min(max(math.ceil(farthest / (0.5 * self.thickness)), 1), MAX_SUBSTEPS)


def collide(part_a: Part, part_b: Part) -> list[ContactPoint]:
    """Narrow phase for two placed parts, normal from A to B."""
    if isinstance(part_a, CirclePart):
        if isinstance(part_b, CirclePart):
            return circle_circle(*part_a, *part_b, MARGIN)
        flipped = polygon_circle(*part_b, *part_a, MARGIN)
        return [(point, (-n[0], -n[1]), depth) for point, n, depth in flipped]
    if isinstance(part_b, CirclePart):
        return polygon_circle(*part_a, *part_b, MARGIN)
    return polygon_polygon(*part_a, *part_b, MARGIN)
