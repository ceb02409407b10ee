"""The contact pass: walls and bodies that touch, answered with impulses.

After the integrator has taken a step from (q0, v0) to (q1, v1), the pass:

1. finds contacts at q1: shape points behind walls, and overlapping convex parts of bodies
   that the scene lets collide (a sort-and-sweep broad phase on the x extent, then the
   narrow phase of :mod:`hecker_dynamics.contact.collision`);
2. solves for impulses at the contact points with both bodies' mass and moment of
   inertia: the article series' collision impulse
   j = -(1 + e) v_rel.n / (1/M_A + 1/M_B + (perp(r_A).n)^2/I_A + (perp(r_B).n)^2/I_B),
   for all contacts together (and the velocity rows of the joints of their islands:
   :mod:`.coupled`) by sequential impulses with accumulated, clamped totals,
   warm-started from the previous step's impulses (a contact is recognised by its pair
   of parts and its point, fixed in the second body, staying within :data:`MATCH`), plus
   Coulomb friction |j_t| <= mu j_n. The two points of a manifold are solved as one block
   (:class:`Block`, the 2 x 2 complementarity problem), which a stack of boxes needs to
   converge in few passes. The work per step is bounded by the number of contacts alone
   (:func:`passes`), island by island (bodies joined through contacts, which share no
   body with another island): up to :data:`WORK` contact solves (at least
   :data:`MIN_ITERATIONS`, at most :data:`MAX_ITERATIONS` passes), fewer when no impulse
   changes a velocity by more than :data:`CONVERGED` relative to the island's fastest
   body. An island of at least :data:`WIDE_UNITS` units and no joint rows is swept in
   colour order (units of one colour share no body; Box2D v3's graph colouring), so that
   the compiled kernel can solve four blocks of a colour at once. A contact that closed
   during the step bounces with restitution e if it approached faster than the
   restitution threshold; otherwise its normal velocity is made just
   enough that the bodies end the step touching, neither overlapping nor pushed apart,
   so resting contacts stay at rest;
3. moves each body whose velocity the impulses changed by h times the change from the
   velocity its position moved with in the step (a jointed body's before the joint pass's
   velocity stage), so a body held still by contacts does not move at all and a sliding
   body moves with the velocity friction left it;
4. pushes apart what still overlaps by more than a small slop, a fraction per step, by
   moving positions only (no velocity, so no kinetic energy, is added).

Resting islands may sleep (the scene's ``contacts.sleep``): a body of the pass that only
gravity and contacts push (no spring, drag, constant force or joint of the scene, no input
held on it) rests while its fastest point, at |v| + reach |omega| (reach: its farthest
shape point from the CM), moves at most :data:`SLEEP_SPEED`; an island (bodies joined
through contacts, walls joining nothing) whose every body has rested
:data:`TIME_TO_SLEEP` falls asleep: its velocities become zero, and from then on each
step puts its bodies back where they were, with zero velocity, before detection, which
skips its walls and its own pairs. An island wakes, its bodies' rest times back at zero,
when an awake body touches one of its bodies, an input is held on one of them, or the
state is set from outside (:meth:`ContactPass.reset`); its contacts' warm-start impulses
are kept while it sleeps.

Fast bodies do not pass through thin ones: :meth:`ContactPass.substeps` tells the
simulation to split a step whenever some colliding body would move more than half the
thinnest colliding part in it.

Where the compiled kernel is built and enabled, the pass runs in C
(:mod:`.compiled`, ``src/kernel/contact.h``) with the same arithmetic and the same bits;
:meth:`ContactPass.export_state` and :meth:`ContactPass.import_state` carry the only
state kept from step to step, the warm-start impulses and, with sleeping on, each body's
rest time and island, either way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, NamedTuple, Optional

import numpy as np

from .collision import (CirclePart, ConvexPolygon, Part, PolygonPart, circle_circle,
                        half_plane_circle, half_plane_polygon, polygon_circle, polygon_polygon)
from ..geometry.shapes import Circle
from ..geometry.planar import cos_sin_of, magnitude
from . import compiled as _compiled
from .coupled import JointUnit
from .materials import Material, PairMaterials

if TYPE_CHECKING:
    from ..scene.load import Scene
    from .joints import JointPass

#: The velocity solver's passes over the contacts per step: as many as fit in
#: :data:`WORK` solves of a contact or two-point manifold, but at least
#: :data:`MIN_ITERATIONS` and at most :data:`MAX_ITERATIONS`, and fewer when converged
#: (no impulse changes a velocity by more than :data:`CONVERGED` relative to the fastest
#: body). So a scene's cost per step is bounded by its number of contacts alone: small
#: scenes converge to rounding, large ones take the fixed minimum, as game engines do.
WORK = 600
MIN_ITERATIONS = 6
MAX_ITERATIONS = 40
CONVERGED = 1e-13
#: An island of at least :data:`WIDE_UNITS` units and no joint rows is swept in colour
#: order (:func:`_coloured`, :data:`COLOURS` colours at most), in which the compiled kernel
#: solves four blocks of one colour at once (``src/kernel/wide.h``) with these same bits.
WIDE_UNITS = 64
COLOURS = 64
#: Largest condition number of a two-point manifold's 2 x 2 effective-mass matrix that is
#: still solved as one block.
MAX_CONDITION = 1000.0
#: Gap (m) within which shapes already count as touching, so resting contacts persist.
MARGIN = 5e-3
#: Distance (m) within which a contact point is taken for last step's, for warm starting.
MATCH = 1e-2
#: Overlap left alone (m) by the position correction.
SLOP = 1e-4
#: Fraction of the remaining overlap removed per step, and the most removed per step (m).
CORRECTION = 0.2
MAX_CORRECTION = 0.05
POSITION_ITERATIONS = 4
MAX_SUBSTEPS = 256
#: Sleeping: the largest speed (m/s) of a resting body's fastest point, |v| + reach |omega|
#: (Box2D v3's default sleep threshold), and how long (s) every body of an island must rest
#: before it sleeps (Box2D's time to sleep).
SLEEP_SPEED = 0.05
TIME_TO_SLEEP = 0.5

__all__ = ["Block", "COLOURS", "Contact", "ContactPass", "ContactRow", "CONVERGED",
           "MAX_CONDITION", "MAX_ITERATIONS", "MIN_ITERATIONS", "SLEEP_SPEED", "SLOP",
           "TIME_TO_SLEEP", "WIDE_UNITS", "WORK", "passes"]


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


@dataclass(slots=True)
class ContactRow:
    """One contact in the impulse solver, set up from the positions at the step's end.

    Bodies ``a`` (-1 for a wall) and ``b``; arms r_A = (rax, ray) and r_B = (rbx, rby) from
    their CMs to the contact point; unit normal n = (nx, ny) from A to B; effective masses
    along n and along t = perp(n); the normal velocity the impulses aim for (``target``);
    friction coefficient ``mu``; the accumulated normal and tangent impulses ``jn`` and
    ``jt``, the only fields the solver changes; the overlap at the step's end (``depth``,
    negative for a gap within :data:`MARGIN`); inverse masses and inertias (zero for a
    wall); the normal velocity before any impulse (``approach``); and the pair of parts
    (``key``), for warm starting.
    """

    a: int
    b: int
    rax: float
    ray: float
    rbx: float
    rby: float
    nx: float
    ny: float
    mass_n: float
    mass_t: float
    target: float
    mu: float
    jn: float
    jt: float
    depth: float
    im_a: float
    ii_a: float
    im_b: float
    ii_b: float
    approach: float
    key: tuple

    def normal_velocity(self, velocity: dict) -> float:
        """The contact's normal velocity for the bodies' ``velocity`` (see
        :func:`_normal_velocity`)."""
        return _normal_velocity(velocity[self.a], velocity[self.b], self.rax, self.ray,
                                self.rbx, self.rby, self.nx, self.ny)

    def push(self, velocity: dict, px: float, py: float) -> None:
        """Apply impulse (px, py) at the contact: +P to body b, -P to body a."""
        va, vb = velocity[self.a], velocity[self.b]
        va[0] -= px * self.im_a
        va[1] -= py * self.im_a
        va[2] -= (self.rax * py - self.ray * px) * self.ii_a
        vb[0] += px * self.im_b
        vb[1] += py * self.im_b
        vb[2] += (self.rbx * py - self.rby * px) * self.ii_b


class ContactPass:
    """Contact detection and response for one scene's walls and collision groups."""

    def __init__(self, scene: Scene, mass: np.ndarray, inertia: np.ndarray,
                 center_of_mass: np.ndarray, threshold: float, *, lean: bool,
                 apart: Iterable[tuple[int, int]] = (), compiled: bool = False,
                 sleep: bool = False, restless: Iterable[int] = (),
                 joints: Optional[JointPass] = None) -> None:
        """The pass for ``scene``'s walls and collision groups, with the bodies' ``mass``,
        moment of ``inertia`` and ``center_of_mass`` (N x 2, body axes) in the scene's
        order; ``threshold``: the approach speed below which contacts do not bounce;
        ``lean``: plain floats rather than numpy where both would do; ``apart``: pairs of
        bodies (i < j) that do not collide although a group names them; ``compiled``:
        resolve in the kernel (:mod:`.compiled`), which must be built; ``sleep``: let
        resting islands sleep; ``restless``: bodies that never sleep (pushed by more than
        gravity and contacts); ``joints``: the scene's joint pass, whose velocity rows the
        solve sweeps with the contacts of the islands they are in (:mod:`.coupled`)."""
        index = {body.name: i for i, body in enumerate(scene.bodies)}
        self.threshold = threshold
        self.inverse_mass = (1.0 / mass).tolist()
        self.inverse_inertia = (1.0 / inertia).tolist()
        self.wall_normal = [tuple(w.normal) for w in scene.walls]
        self.wall_offset = [w.normal[0] * w.point[0] + w.normal[1] * w.point[1]
                            for w in scene.walls]
        self.wall_material = [(w.restitution, w.friction) for w in scene.walls]
        self.wall_bodies = [sorted(index[b] for b in w.bodies) for w in scene.walls]
        self.pairs = PairMaterials([([index[b] for b in group.bodies], group.restitution,
                                     group.friction) for group in scene.collisions],
                                   len(scene.bodies), apart)
        # Per body, its parts relative to the CM in body axes, as plain floats; the scene
        # loader has checked that colliding bodies are convex.
        colliding = self.pairs.colliding()
        self.parts: list[list[Part]] = []
        reach, thickness = [], []
        for i, body in enumerate(scene.bodies):
            parts: list[Part] = []
            extents, widths = [], []
            for shape in body.shapes:
                if isinstance(shape, Circle):
                    center = np.asarray(shape.center, dtype=float) - center_of_mass[i]
                    parts.append(CirclePart(tuple(center.tolist()), shape.radius))
                    extents.append(float(np.hypot(*center)) + shape.radius)
                    widths.append(2.0 * shape.radius)
                    continue
                local = shape.vertices - center_of_mass[i]
                extents.append(float(np.max(np.hypot(local[:, 0], local[:, 1]))))
                if i in colliding:
                    poly = ConvexPolygon.from_vertices(local)
                    parts.append(PolygonPart([tuple(p) for p in poly.vertices.tolist()],
                                             [tuple(n) for n in poly.normals.tolist()]))
                    widths.append(2.0 * poly.inradius)
                else:
                    parts.append(PolygonPart([tuple(p) for p in local.tolist()], []))
            self.parts.append(parts)
            reach.append(max(extents))
            thickness.append(min(widths, default=math.inf))
        self.colliding = colliding
        #: Farthest shape point from each body's CM, and thinnest colliding part.
        self.reach = reach
        self.thickness = min((thickness[i] for i in colliding), default=math.inf)
        self._lean = lean
        self._colliding_index = np.array(colliding, dtype=int)
        self._colliding_reach = np.array([reach[i] for i in colliding])
        touching = {b for bodies in self.wall_bodies for b in bodies} | set(colliding)
        self.bodies = np.array(sorted(touching), dtype=int)
        self._warm: dict[tuple, list[tuple[float, float, float, float]]] = {}
        self.sleep = sleep
        self._restless = frozenset(int(b) for b in restless)
        size = len(scene.bodies)
        #: Per body: whether it may sleep, how long it has rested (s), and the island it
        #: sleeps in (the lowest body of it; -1 while awake).
        self._members = {int(b) for b in self.bodies}
        self.rested = [0.0] * size
        self.island = [-1] * size
        self.calm = self._calm(())
        self._woken: set[int] = set()
        self._joints = joints
        self._kernel: Optional[_compiled.CompiledContacts] = (
            _compiled.CompiledContacts(self) if compiled else None)

    def reset(self) -> None:
        """Forget the impulses kept for warm starting, and wake every body (held by no
        input: see :meth:`hold`)."""
        self._warm = {}
        self.calm = self._calm(())
        self.rested = [0.0] * len(self.rested)
        self.island = [-1] * len(self.island)
        if self._kernel is not None:
            self._kernel.set_impulses([])
            self._kernel.set_sleep(self)

    def hold(self, bodies: Iterable[int]) -> None:
        """Inputs are held on ``bodies`` (and on no other): wake their islands and keep
        them awake while the inputs last."""
        held = set(bodies)
        self.calm = self._calm(held)
        self._sync_sleep()
        self._wake({self.island[b] for b in held} - {-1})
        if self._kernel is not None:
            self._kernel.set_sleep(self)

    def sleeping(self) -> list[int]:
        """The bodies asleep now, in order."""
        self._sync_sleep()
        return [b for b, island in enumerate(self.island) if island >= 0]

    def everything_asleep(self) -> bool:
        """Whether every body of the scene sleeps: a step would put each back where it
        started and find no contact."""
        if not self.sleep:
            return False
        self._sync_sleep()
        return all(island >= 0 for island in self.island)

    def _calm(self, held: Iterable[int]) -> list[bool]:
        """Per body, whether it may sleep while inputs are held on ``held``."""
        restless = self._restless | set(held)
        return [b in self._members and b not in restless for b in range(len(self.island))]

    def _sync_sleep(self) -> None:
        """Take the rest times and islands from the kernel, where it holds them."""
        if self._kernel is not None:
            self.rested, self.island = self._kernel.sleep_state()

    def _wake(self, islands: set[int]) -> None:
        """Wake the bodies of the sleeping ``islands``."""
        if not islands:
            return
        for b, sleeping in enumerate(self.island):
            if sleeping in islands:
                self.island[b] = -1
                self.rested[b] = 0.0

    @property
    def compiled(self) -> bool:
        """True while the pass resolves in the compiled kernel."""
        return self._kernel is not None

    def kernel_pass(self):
        """The kernel's contact pass (a capsule), for whole steps in the kernel."""
        return self._kernel.kernel

    def use_python(self) -> None:
        """Resolve in Python from now on, carrying the warm-start impulses over."""
        state = self.export_state()
        self._kernel = None
        self.import_state(state)

    def export_state(self) -> list[list[Any]] | dict[str, Any]:
        """The impulses kept for warm starting, as plain data: per pair of parts (sorted by
        their names), the remembered contacts [lx, ly, jn, jt] (point in the second body's
        frame, normal and tangent impulse) in the order the solver met them; the same
        whether the pass runs in Python or in the kernel. With sleeping on, a dict of
        those (``warm``) and per body its rest time (``rested``) and sleeping island
        (``island``)."""
        warm_state = self._export_warm()
        if not self.sleep:
            return warm_state
        self._sync_sleep()
        return {"warm": warm_state, "rested": list(self.rested), "island": list(self.island)}

    def _export_warm(self) -> list[list[Any]]:
        if self._kernel is None:
            warm = self._warm
        else:
            warm = {}
            for *key, lx, ly, jn, jt in self._kernel.impulses():
                warm.setdefault(tuple(key), []).append((lx, ly, jn, jt))
        return [[list(key), [list(contact) for contact in warm[key]]] for key in sorted(warm)]

    def import_state(self, state: list[list[Any]] | dict[str, Any]) -> None:
        """Restore :meth:`export_state`'s data: the next step gives the same bits as it
        would have after the step that data was taken at. Warm starts alone (a list) wake
        every body."""
        if isinstance(state, dict):
            self.rested = [float(t) for t in state["rested"]]
            self.island = [int(i) for i in state["island"]]
            state = state["warm"]
        else:
            self.rested = [0.0] * len(self.rested)
            self.island = [-1] * len(self.island)
        if self._kernel is not None:
            self._kernel.set_sleep(self)
        self._warm = {tuple(int(k) for k in key): [tuple(float(x) for x in contact)
                                                   for contact in contacts]
                      for key, contacts in state}
        if self._kernel is not None:
            self._kernel.set_impulses([(*key, *contact) for key, contacts in self._warm.items()
                                       for contact in contacts])
            self._warm = {}

    # ------------------------------------------------------------------ detection

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

    def detect(self, q: np.ndarray) -> list[Contact]:
        """The contacts at positions ``q``: walls first, then the pairs the broad phase
        finds, in a deterministic order."""
        return self._detect(q, None)

    def _detect(self, q: np.ndarray, island: Optional[list[int]]) -> list[Contact]:
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
        if island is not None and all(island[b] >= 0 for b in self.colliding):
            return contacts  # with every colliding body asleep no pair needs looking at
        for a, b, material in self._candidate_pairs(poses) if self.colliding else ():
            sleeping = -1 if island is None else max(island[a], island[b])
            if sleeping >= 0 and min(island[a], island[b]) >= 0:  # type: ignore[index]
                continue
            for body in (a, b):
                if body not in world:
                    world[body] = self._world_parts(poses[body], body)
            found = self._pair_contacts(a, b, material, world)
            if found and sleeping >= 0:
                self._woken.add(sleeping)
            contacts.extend(found)
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
                for point, normal, depth in _collide(part_a, part_b):
                    contacts.append(Contact(a, b, point, normal, depth, *material, (a, b, pa, pb)))
        return contacts

    def substeps(self, q0: np.ndarray, q1: np.ndarray) -> int:
        """How many sub-steps keep every colliding body's travel under half the thinnest
        colliding part (1 when the step is short enough)."""
        if not self.colliding:
            return 1
        if self._lean:  # a few bodies: plain floats beat numpy's cost per call
            before, after = q0.tolist(), q1.tolist()
            farthest = max(magnitude(after[i][0] - before[i][0], after[i][1] - before[i][1])
                           + abs(after[i][2] - before[i][2]) * self.reach[i]
                           for i in self.colliding)
        else:
            index = self._colliding_index
            moved = q1[index] - q0[index]
            farthest = float((np.hypot(moved[:, 0], moved[:, 1])
                              + np.abs(moved[:, 2]) * self._colliding_reach).max())
        if not math.isfinite(farthest):
            return 1  # a blown-up state: the simulation's divergence check reports it
        return min(max(math.ceil(farthest / (0.5 * self.thickness)), 1), MAX_SUBSTEPS)

    # ------------------------------------------------------------------ response

    def resolve(self, q1: np.ndarray, v1: np.ndarray, q0: np.ndarray, v0: np.ndarray,
                h: float) -> None:
        """Respond to the contacts found at ``q1`` after a step of ``h`` from (``q0``,
        ``v0``); updates ``q1`` and ``v1`` (C-contiguous) in place; sleeping bodies go back
        to (q0, v0). A state that is not finite is left to the simulation's divergence
        check."""
        if not (np.isfinite(q1).all() and np.isfinite(v1).all()):
            return
        joints = self._joints
        if self._kernel is not None and joints is not None and not joints.compiled:
            self.use_python()  # the joint rows are Python's: solve with them here
        if self._kernel is not None:
            if joints is None:
                self._kernel.resolve(q1, v1, q0, v0, h)
                return
            self._kernel.resolve(q1, v1, q0, v0, h, joints.kernel_pass())
            joints.kernel_done()
            return
        contacts = self._awake_contacts(q1, v1, q0, v0)
        if not contacts:
            if joints is not None:
                joints.take_extra([])
            self._warm = self._sleeping_warm()
            self._doze([], v1, h)
            return
        units = [] if joints is None else joints.contact_units()
        touched = sorted(({c.a for c in contacts} | {c.b for c in contacts}
                          | {b for unit in units for b in unit.bodies()}) - {-1})
        still = [0.0, 0.0, 0.0]
        poses = {b: q1[b].tolist() for b in touched}
        velocity = {b: v1[b].tolist() for b in touched}
        velocity[-1] = still
        arrived = {b: list(velocity[b]) for b in touched}
        moved = dict(arrived)  # the velocities the step's positions moved with
        if joints is not None:
            moved.update(joints.settled_velocities())
        moved[-1] = still
        before = {b: v0[b].tolist() for b in touched}
        before[-1] = still
        rows = [self._prepare(c, poses, moved, before, h) for c in contacts]
        for row in rows:  # warm start, once every target is set from the step's velocities
            jn, jt, nx, ny = row.jn, row.jt, row.nx, row.ny
            row.push(velocity, jn * nx - jt * ny, jn * ny + jt * nx)
        islands = self._solve_velocities(rows, velocity, units)
        if joints is not None:
            joints.take_extra(units)
        self._remember(rows, poses)
        for b in touched:
            if velocity[b] != arrived[b]:
                poses[b] = [p + h * (new - old)
                            for p, new, old in zip(poses[b], velocity[b], moved[b])]
                q1[b] = poses[b]
                v1[b] = velocity[b]
        self._correct_positions(islands, velocity, q1, h)
        self._doze(rows, v1, h)

    def _awake_contacts(self, q1: np.ndarray, v1: np.ndarray, q0: np.ndarray,
                        v0: np.ndarray) -> list[Contact]:
        """The contacts of the awake bodies at ``q1``, after putting the sleeping ones back
        at (q0, v0) and waking the islands that awake bodies touch."""
        if not self.sleep:
            return self.detect(q1)
        for b, sleeping in enumerate(self.island):
            if sleeping >= 0:
                q1[b], v1[b] = q0[b], v0[b]
        while True:
            self._woken = set()
            contacts = self._detect(q1, self.island)
            if not self._woken:
                return contacts
            self._wake(self._woken)

    def _sleeping_warm(self) -> dict[tuple, list[tuple[float, float, float, float]]]:
        """The warm-start impulses of the sleeping islands' contacts, kept while they
        sleep."""
        if not self.sleep:
            return {}
        return {key: warm for key, warm in self._warm.items() if self.island[key[1]] >= 0}

    def _doze(self, rows: list[ContactRow], v1: np.ndarray, h: float) -> None:
        """Add ``h`` to the rest time of each awake body that may sleep and rests (else
        start it again at zero), and put to sleep, with zero velocity, each island of awake
        bodies (joined by ``rows``) whose every body has rested :data:`TIME_TO_SLEEP`."""
        if not self.sleep:
            return
        island, rested = self.island, self.rested
        awake = [b for b, sleeping in enumerate(island) if sleeping < 0]
        parent = {b: b for b in awake}
        for row in rows:
            if row.a >= 0:
                _join(parent, row.a, row.b)
        velocities = v1.tolist()
        shortest: dict[int, float] = {}
        for b in awake:
            vx, vy, omega = velocities[b]
            resting = self.calm[b] and (math.sqrt(vx * vx + vy * vy)
                                        + self.reach[b] * abs(omega) <= SLEEP_SPEED)
            rested[b] = rested[b] + h if resting else 0.0
            r = _root(parent, b)
            shortest[r] = min(shortest.get(r, rested[b]), rested[b])
        for b in awake:
            r = _root(parent, b)
            if shortest[r] >= TIME_TO_SLEEP:
                island[b] = r
                v1[b] = 0.0

    def _prepare(self, contact: Contact, poses: dict, velocity: dict, before: dict,
                 h: float) -> ContactRow:
        """The solver row of ``contact``, its impulses warm-started from the last step;
        ``velocity``: the bodies' velocities the step's positions moved with."""
        row = self._row(contact, poses, velocity)
        a, b, approach, depth = row.a, row.b, row.approach, row.depth
        # End the step just touching (never pushed apart by velocity: overlap left from
        # earlier steps is the position correction's job) or, if the contact closed during
        # the step fast enough, bounce. The bounce reverses the approach speed from before
        # the step: the speed the forces added during the step was not there at impact, and
        # reversing it too would add energy at every bounce.
        target = min(approach + depth / h, 0.0)
        if depth > 0.0 and approach < -self.threshold:
            impact = _normal_velocity(before[a], before[b], row.rax, row.ray, row.rbx, row.rby,
                                      row.nx, row.ny)
            target = max(target, -contact.e * min(impact, 0.0))
        row.target = target
        row.jn, row.jt = self._recall(contact.key, row.rbx, row.rby, poses[b][2])
        return row

    def _row(self, contact: Contact, poses: dict, velocity: dict) -> ContactRow:
        """The solver row of ``contact`` at ``poses`` and ``velocity``: arms, effective
        masses and approach speed, with no impulse yet and target 0."""
        a, b, (px, py), (nx, ny), depth, _, mu, key = contact
        im_a, ii_a = (self.inverse_mass[a], self.inverse_inertia[a]) if a >= 0 else (0.0, 0.0)
        im_b, ii_b = self.inverse_mass[b], self.inverse_inertia[b]
        rax, ray = (px - poses[a][0], py - poses[a][1]) if a >= 0 else (0.0, 0.0)
        rbx, rby = px - poses[b][0], py - poses[b][1]
        rna, rnb = rax * ny - ray * nx, rbx * ny - rby * nx  # perp(r) . n = r x n
        rta, rtb = -rax * nx - ray * ny, -rbx * nx - rby * ny  # perp(r) . t, t = perp(n)
        mass_n = 1.0 / (im_a + im_b + rna * rna * ii_a + rnb * rnb * ii_b)
        mass_t = 1.0 / (im_a + im_b + rta * rta * ii_a + rtb * rtb * ii_b)
        if not (mass_n > 0.0 and mass_t > 0.0):
            raise ArithmeticError("the contact's effective mass underflowed (a lever arm or "
                                  "inverse mass too large for a double)")
        approach = _normal_velocity(velocity[a], velocity[b], rax, ray, rbx, rby, nx, ny)
        return ContactRow(a, b, rax, ray, rbx, rby, nx, ny, mass_n, mass_t, 0.0, mu, 0.0, 0.0,
                          depth, im_a, ii_a, im_b, ii_b, approach, key)

    def impact(self, q: np.ndarray, v: np.ndarray, contacts: list[Contact]) -> bool:
        """Bounce at the instant of touch: the impulses of ``contacts`` (found at ``q``,
        where the shapes just touch) that give each contact approaching faster than the
        restitution threshold the normal velocity -e v_n, by the same solver and friction
        as :meth:`resolve` (the collision impulse j = -(1 + e) v_rel.n / K for a single
        point), no warm start and no position change; updates ``v`` in place. False (and
        ``v`` unchanged) when no contact approaches that fast: a resting contact is the
        contact pass's."""
        touched = sorted(({c.b for c in contacts} | {c.a for c in contacts}) - {-1})
        poses = {b: q[b].tolist() for b in touched}
        velocity = {b: v[b].tolist() for b in touched}
        velocity[-1] = [0.0, 0.0, 0.0]
        rows = [self._row(contact, poses, velocity) for contact in contacts]
        bouncing = [row.approach < -self.threshold for row in rows]
        if not any(bouncing):
            return False
        for row, contact, bounces in zip(rows, contacts, bouncing):
            if bounces:  # the others end touching (target 0) or, separating, get nothing
                row.target = -contact.e * row.approach
        self._solve_velocities(rows, velocity, [])
        for b in touched:
            v[b] = velocity[b]
        return True

    def _recall(self, pair: tuple, rx: float, ry: float, angle: float) -> tuple[float, float]:
        """Last step's impulses of the contact of ``pair`` nearest this point, if within
        :data:`MATCH`; each remembered contact is used once."""
        remembered = self._warm.get(pair)
        if not remembered:
            return 0.0, 0.0
        c, s = cos_sin_of(angle)
        lx, ly = c * rx + s * ry, -s * rx + c * ry
        best, nearest = None, MATCH * MATCH
        for i, (mx, my, _, _) in enumerate(remembered):
            d = (mx - lx) ** 2 + (my - ly) ** 2
            if d <= nearest:
                best, nearest = i, d
        if best is None:
            return 0.0, 0.0
        _, _, jn, jt = remembered.pop(best)
        return jn, jt

    def _remember(self, rows: list[ContactRow], poses: dict) -> None:
        """Keep each contact's impulses with its point in the second body's frame (and
        those of the sleeping islands)."""
        self._warm = self._sleeping_warm()
        for row in rows:
            rbx, rby, angle = row.rbx, row.rby, poses[row.b][2]
            c, s = cos_sin_of(angle)
            self._warm.setdefault(row.key, []).append(
                (c * rbx + s * rby, -s * rbx + c * rby, row.jn, row.jt))

    def _solve_velocities(self, rows: list[ContactRow], velocity: dict,
                          joint_units: list[JointUnit]) -> list[list[ContactRow | Block]]:
        """Gauss-Seidel passes over the rows, each two-point manifold as one block
        (:class:`Block`), every other contact point by point, then the velocity rows of the
        joints in the island (:mod:`.coupled`), island by island (bodies that touch,
        through contacts or joints, share no body with another island; a joint's rows are
        swept only in an island that has a contact): each until no impulse changes a
        velocity by more than :data:`CONVERGED` relative to its fastest body, or
        :func:`passes` passes for its own number of units. Islands are independent, so
        each gets the bits it would get alone; a big island without joint rows is swept in
        colour order (:func:`_coloured`). Returns each island's units in the order swept."""
        swept = []
        for island, coupled in _islands(_schedule(rows), joint_units):
            if len(island) >= WIDE_UNITS and not coupled:
                island = _coloured(island)
            swept.append(island)
            for joint in coupled:
                joint.warm_start(velocity)
            fastest = max(abs(x) for unit in island for body in _unit_bodies(unit)
                          for x in velocity[body])
            for joint in coupled:
                fastest = max(fastest, max(abs(x) for body in joint.bodies()
                                           for x in velocity[body]))
            scale = 1.0 + fastest
            for _ in range(passes(len(island) + len(coupled))):
                largest = 0.0
                for unit in island:
                    change = (unit.solve(velocity) if isinstance(unit, Block)
                              else _solve_point(unit, velocity))
                    largest = max(largest, change)
                for joint in coupled:
                    largest = max(largest, joint.solve(velocity))
                if largest <= CONVERGED * scale:
                    break
        return swept

    def _correct_positions(self, islands: list[list[ContactRow | Block]], velocity: dict,
                           q1: np.ndarray, h: float) -> None:
        """Remove overlap beyond :data:`SLOP` by moving positions only, island by island,
        each in the order its velocities were swept; an island with no contact that deep
        moves nothing (islands share no body, so each gets the bits it would get alone).

        A contact's depth after the velocity change is depth - h (v_n' - v_n), linear in the
        arms; each pass moves the two bodies apart along the normal by a fraction of the
        excess, weighted by their inverse masses and inertias.
        """
        shift = {b: [0.0, 0.0, 0.0] for b in velocity}
        for island in islands:
            rows = [row for unit in island
                    for row in ((unit.first, unit.second) if isinstance(unit, Block)
                                else (unit,))]
            base = [row.depth - h * (row.normal_velocity(velocity) - row.approach)
                    for row in rows]
            if max(base) <= SLOP:
                continue
            for _ in range(POSITION_ITERATIONS):
                for row, depth in zip(rows, base):
                    excess = depth - SLOP - row.normal_velocity(shift)
                    if excess <= 0.0:
                        continue
                    push = min(CORRECTION * excess, MAX_CORRECTION) * row.mass_n
                    row.push(shift, push * row.nx, push * row.ny)
        for b, s in shift.items():
            if b >= 0 and any(s):
                q1[b] += s


def _normal_velocity(va: list, vb: list, rax: float, ray: float, rbx: float, rby: float,
                     nx: float, ny: float) -> float:
    """(v_B + omega_B perp(r_B) - v_A - omega_A perp(r_A)) . n: negative when approaching."""
    return ((vb[0] - vb[2] * rby - va[0] + va[2] * ray) * nx
            + (vb[1] + vb[2] * rbx - va[1] - va[2] * rax) * ny)


def passes(units: int) -> int:
    """The most passes of the velocity solver over ``units`` contacts and blocks."""
    return min(max(WORK // units, MIN_ITERATIONS), MAX_ITERATIONS)


def _solve_normal(row: ContactRow, velocity: dict) -> float:
    """One contact's normal impulse: the accumulated total that brings its normal velocity
    to its target, clamped at zero (contacts push, never pull). Returns the change of the
    normal velocity."""
    jn = row.jn
    new_n = max(jn + (row.target - row.normal_velocity(velocity)) * row.mass_n, 0.0)
    row.push(velocity, (new_n - jn) * row.nx, (new_n - jn) * row.ny)
    row.jn = new_n
    return abs(new_n - jn) / row.mass_n


def _solve_friction(row: ContactRow, velocity: dict) -> float:
    """One contact's tangent impulse: the accumulated total that stops its sliding, within
    Coulomb's cone |j_t| <= mu j_n. Returns the change of the tangent velocity."""
    if not row.mu > 0.0:
        return 0.0
    va, vb = velocity[row.a], velocity[row.b]
    dvx = vb[0] - vb[2] * row.rby - va[0] + va[2] * row.ray
    dvy = vb[1] + vb[2] * row.rbx - va[1] - va[2] * row.rax
    jt, bound = row.jt, row.mu * row.jn
    new_t = min(max(jt - (-dvx * row.ny + dvy * row.nx) * row.mass_t, -bound), bound)
    row.push(velocity, -(new_t - jt) * row.ny, (new_t - jt) * row.nx)
    row.jt = new_t
    return abs(new_t - jt) / row.mass_t


def _solve_point(row: ContactRow, velocity: dict) -> float:
    """A contact solved on its own: normal impulse, then friction. Returns the larger
    velocity change."""
    change = _solve_normal(row, velocity)
    return max(change, _solve_friction(row, velocity))


@dataclass(slots=True)
class Block:
    """The two points of one manifold (same bodies, same normal), whose normal impulses
    are solved together: the 2 x 2 linear complementarity problem
    K x + b >= 0, x >= 0, x . (K x + b) = 0, by trying which points are active (Box2D's
    block solver). K's entries k11, k12, k22 are the two points' effective inverse masses
    along n and their coupling; (inv11, inv12, inv22) is K's inverse."""

    first: ContactRow
    second: ContactRow
    k11: float
    k12: float
    k22: float
    inv11: float
    inv12: float
    inv22: float

    def solve(self, velocity: dict) -> float:
        """Both normal impulses at once, then each point's friction. Returns the largest
        velocity change."""
        one, two = self.first, self.second
        old1, old2 = one.jn, two.jn
        b1 = one.normal_velocity(velocity) - one.target - (self.k11 * old1 + self.k12 * old2)
        b2 = two.normal_velocity(velocity) - two.target - (self.k12 * old1 + self.k22 * old2)
        x1 = -(self.inv11 * b1 + self.inv12 * b2)
        x2 = -(self.inv12 * b1 + self.inv22 * b2)
        if not (x1 >= 0.0 and x2 >= 0.0):  # both pushing failed: only the first
            x1, x2 = -one.mass_n * b1, 0.0
            if not (x1 >= 0.0 and self.k12 * x1 + b2 >= 0.0):  # only the second
                x1, x2 = 0.0, -two.mass_n * b2
                if not (x2 >= 0.0 and self.k12 * x2 + b1 >= 0.0):  # neither
                    x1, x2 = 0.0, 0.0
                    if not (b1 >= 0.0 and b2 >= 0.0):
                        x1, x2 = old1, old2  # no solution (degenerate): leave them
        one.push(velocity, (x1 - old1) * one.nx, (x1 - old1) * one.ny)
        two.push(velocity, (x2 - old2) * two.nx, (x2 - old2) * two.ny)
        one.jn, two.jn = x1, x2
        change = max(abs(x1 - old1) / one.mass_n, abs(x2 - old2) / two.mass_n)
        change = max(change, _solve_friction(one, velocity))
        return max(change, _solve_friction(two, velocity))


def _block(one: ContactRow, two: ContactRow) -> Optional[Block]:
    """The block of two points of a manifold, or None where K is too ill-conditioned
    (condition number above :data:`MAX_CONDITION`: points almost on one line through the
    bodies' CMs), which are then solved point by point."""
    nx, ny = one.nx, one.ny
    rna1, rnb1 = one.rax * ny - one.ray * nx, one.rbx * ny - one.rby * nx
    rna2, rnb2 = two.rax * ny - two.ray * nx, two.rbx * ny - two.rby * nx
    mass = one.im_a + one.im_b
    k11 = mass + rna1 * rna1 * one.ii_a + rnb1 * rnb1 * one.ii_b
    k22 = mass + rna2 * rna2 * one.ii_a + rnb2 * rnb2 * one.ii_b
    k12 = mass + rna1 * rna2 * one.ii_a + rnb1 * rnb2 * one.ii_b
    determinant = k11 * k22 - k12 * k12
    if not k11 * k11 < MAX_CONDITION * determinant:
        return None
    inverse = 1.0 / determinant
    return Block(one, two, k11, k12, k22, k22 * inverse, -k12 * inverse, k11 * inverse)


def _unit_bodies(unit: ContactRow | Block) -> tuple[int, int]:
    """The two bodies of a solver unit (the first -1 for a wall)."""
    row = unit.first if isinstance(unit, Block) else unit
    return row.a, row.b


def _islands(units: list[ContactRow | Block], joints: list[JointUnit]
             ) -> list[tuple[list[ContactRow | Block], list[JointUnit]]]:
    """The units grouped by island (union-find over the bodies they join, contacts and
    joints; walls and the fixed frame join nothing), in order of each island's first
    unit, each island's units in their order, with the joint rows of that island (in the
    joint pass's order); joint rows of islands without a contact are left out."""
    parent: dict[int, int] = {}
    for unit in units:
        a, b = _unit_bodies(unit)
        parent.setdefault(b, b)
        if a >= 0:
            parent.setdefault(a, a)
            _join(parent, a, b)
    for joint in joints:
        first, *others = joint.bodies()
        parent.setdefault(first, first)
        for body in others:
            parent.setdefault(body, body)
            _join(parent, first, body)
    islands: dict[int, tuple[list[ContactRow | Block], list[JointUnit]]] = {}
    for unit in units:
        islands.setdefault(_root(parent, _unit_bodies(unit)[1]), ([], []))[0].append(unit)
    for joint in joints:
        island = islands.get(_root(parent, joint.entries[0][0]))
        if island is not None:
            island[1].append(joint)
    return list(islands.values())


def _coloured(island: list[ContactRow | Block]) -> list[ContactRow | Block]:
    """The island's units by colour, greedy first fit in their order: each unit takes the
    lowest of :data:`COLOURS` colours that neither of its bodies has yet (a wall has none),
    and the units that fit none come last, in their order. Units of one colour share no
    body, so they could be solved in any order, or at once, with the same result: a wall's
    velocity stays zero (Box2D v3's graph colouring, ``src/constraint_graph.c``)."""
    taken: dict[int, int] = {}
    colours: list[list[ContactRow | Block]] = [[] for _ in range(COLOURS + 1)]
    for unit in island:
        a, b = _unit_bodies(unit)
        free = ~(taken.get(a, 0) | taken.get(b, 0)) & ((1 << COLOURS) - 1)
        colour = (free & -free).bit_length() - 1 if free else COLOURS
        if free:
            if a >= 0:
                taken[a] = taken.get(a, 0) | 1 << colour
            taken[b] = taken.get(b, 0) | 1 << colour
        colours[colour].append(unit)
    return [unit for units in colours for unit in units]


def _root(parent: dict[int, int], body: int) -> int:
    """The root of ``body``'s set in the union-find forest ``parent`` (halving the path)."""
    while parent[body] != body:
        parent[body] = parent[parent[body]]
        body = parent[body]
    return body


def _join(parent: dict[int, int], a: int, b: int) -> None:
    """Join the sets of bodies a and b under the lower root."""
    ra, rb = _root(parent, a), _root(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)


def _schedule(rows: list[ContactRow]) -> list[ContactRow | Block]:
    """The solver's units in row order: a :class:`Block` for each manifold of exactly two
    points (consecutive rows of one pair of parts with one normal), else single rows."""
    units: list[ContactRow | Block] = []
    count, k = len(rows), 0
    while k < count:
        row = rows[k]
        end = k + 1
        while end < count and rows[end].key == row.key:
            end += 1
        block = (_block(row, rows[k + 1]) if end - k == 2 and row.nx == rows[k + 1].nx
                 and row.ny == rows[k + 1].ny else None)
        if block is None:
            units.extend(rows[k:end])
        else:
            units.append(block)
        k = end
    return units


def _collide(part_a: Part, part_b: Part) -> list:
    """Narrow phase for two placed parts, normal from A to B."""
    if isinstance(part_a, CirclePart):
        if isinstance(part_b, CirclePart):
            return circle_circle(*part_a, *part_b, MARGIN)
        flipped = polygon_circle(*part_b, *part_a, MARGIN)
        return [(point, (-n[0], -n[1]), depth) for point, n, depth in flipped]
    if isinstance(part_b, CirclePart):
        return polygon_circle(*part_a, *part_b, MARGIN)
    return polygon_polygon(*part_a, *part_b, MARGIN)
