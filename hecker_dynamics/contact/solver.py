"""The contact pass: walls and bodies that touch, answered with impulses.

After the integrator has taken a step from (q0, v0) to (q1, v1), the pass:

1. finds contacts at q1: shape points behind walls, and overlapping convex parts of bodies
   that the scene lets collide (a sort-and-sweep broad phase on the x extent, then the
   narrow phase of :mod:`hecker_dynamics.contact.collision`: :mod:`.detect`);
2. solves for impulses at the contact points with both bodies' mass and moment of
   inertia: the article series' collision impulse
   j = -(1 + e) v_rel.n / (1/M_A + 1/M_B + (perp(r_A).n)^2/I_A + (perp(r_B).n)^2/I_B),
   for all contacts together (and the velocity rows of the joints of their islands:
   :mod:`.coupled`) by sequential impulses with accumulated, clamped totals
   (:mod:`.rows`, :mod:`.solve`), warm-started from the previous step's impulses (the
   friction, where a big island's passes ran out, from :data:`~.warm.FRICTION_CARRY` of its
   own; a contact is recognised by its
   pair of parts and its point, fixed in the second body, staying within
   :data:`~.warm.MATCH`: :mod:`.warm`), plus Coulomb friction
   |j_t| <= mu j_n. The two points of a manifold are solved as one block
   (:class:`~.rows.Block`, the 2 x 2 complementarity problem), which a stack of boxes
   needs to converge in few passes. The work per step is bounded by the number of
   contacts alone (:func:`~.solve.passes`), island by island (bodies joined through
   contacts, which share no body with another island: :mod:`.islands`): up to
   :data:`~.solve.WORK` contact solves (at least :data:`~.solve.MIN_ITERATIONS` passes and,
   so that deep piles settle, one per :data:`~.solve.SETTLE` of the island's units; at
   most :data:`~.solve.MAX_ITERATIONS`), fewer when no impulse changes
   a velocity by more than :data:`~.solve.CONVERGED` relative to the island's fastest
   body. An island of at least :data:`~.islands.WIDE_UNITS` units and no joint rows is
   swept in colour order (units of one colour share no body; Box2D v3's graph
   colouring), so that the compiled kernel can solve four blocks of a colour at once. A
   contact that closed during the step bounces with restitution e if it approached
   faster than the restitution threshold; otherwise its normal velocity is made just
   enough that the bodies end the step touching, neither overlapping nor pushed apart,
   so resting contacts stay at rest;
3. moves each body whose velocity the impulses changed by h times the change from the
   velocity its position moved with in the step (a jointed body's before the joint pass's
   velocity stage), so a body held still by contacts does not move at all and a sliding
   body moves with the velocity friction left it;
4. pushes apart what still overlaps by more than a small slop, a fraction per step, by
   moving positions only (no velocity, so no kinetic energy, is added).

Resting islands may sleep (the scene's ``contacts.sleep``; :mod:`.sleep`): a body of the
pass that only gravity and contacts push (no spring, drag, constant force or joint of the
scene, no input held on it) rests while its fastest point, at |v| + reach |omega| (reach:
its farthest shape point from the CM), moves at most :data:`~.sleep.SLEEP_SPEED`; an
island (bodies joined through contacts, walls joining nothing) whose every body has
rested :data:`~.sleep.TIME_TO_SLEEP` falls asleep: its velocities become zero, and from
then on each step puts its bodies back where they were, with zero velocity, before
detection, which skips its walls and its own pairs. An island wakes, its bodies' rest
times back at zero, when an awake body touches one of its bodies, an input is held on one
of them, or the state is set from outside (:meth:`ContactPass.reset`); its contacts'
warm-start impulses are kept while it sleeps.

Fast bodies do not pass through thin ones: :meth:`ContactPass.substeps` tells the
simulation to split a step whenever some colliding body would move more than half the
thinnest colliding part in it.

Where the compiled kernel is built and enabled, the pass runs in C
(:mod:`.compiled`, ``src/kernel/contact.h``; each module here has its C file of the
same name: docs/architecture.md) with the same arithmetic and the same bits;
:meth:`ContactPass.export_state` and :meth:`ContactPass.import_state` carry the only
state kept from step to step, the warm-start impulses and, with sleeping on, each body's
rest time and island, either way.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from ..geometry.planar import cos_sin_of
from ..geometry.shapes import Circle, Polygon, area_properties
from . import compiled as _compiled
from .collision import CirclePart, ConvexPolygon, Part, PolygonPart
from .detect import Contact
from .materials import PairMaterials
from .rows import ContactRow, States, Velocities, normal_velocity
from .sleep import Sleep
from .solve import CONVERGED, correct_positions, slop, solve_velocities
from .warm import WarmImpulses, WarmStarts

if TYPE_CHECKING:
    from ..scene.load import Scene
    from .joints import JointPass

__all__ = ["MASS_RATIO", "ContactPass", "MassRatioWarning"]

#: The largest ratio of the masses of two bodies that may touch that the velocity solver
#: settles: sequential impulses carry a heavy body's weight through a light one at a rate
#: of about the ratio's inverse per pass, so a 1 kg box under a 1 m box of 300 kg drifts
#: by under a millimetre in 3 s, of 1e3 kg slides off at 0.08 m/s, of 1e4 kg presses it
#: 2 mm into the floor, and of 1e6 kg squeezes it out sideways.
MASS_RATIO = 1e3


class MassRatioWarning(UserWarning):
    """Bodies that may touch differ in mass by more than :data:`MASS_RATIO`."""


def _warn_mass_ratios(scene: Scene, mass: States) -> None:
    """Warn, once per collision group, when a body that gravity pulls is more than
    :data:`MASS_RATIO` times the group's lightest. A heavy body that no gravity pulls (a
    fixed incline made of a body) presses nothing, nor does one whose weight a pin, weld or
    distance joint to the fixed frame carries (the tumbler's drum)."""
    from ..scene.joints import DistanceJoint, RevoluteJoint, WeldJoint
    from ..scene.load import Gravity

    index = {body.name: i for i, body in enumerate(scene.bodies)}
    held = {joint.body_b for joint in scene.joints
            if isinstance(joint, (RevoluteJoint, WeldJoint, DistanceJoint))
            and joint.body_a is None}
    pulled = {b for force in scene.forces if isinstance(force, Gravity)
              and any(force.acceleration) for b in force.bodies} - held
    for group in scene.collisions:
        if not group.bodies:  # left empty by deletes (scene/world.py)
            continue
        light, small = min((float(mass[index[b]]), b) for b in group.bodies)
        heavy, big = max(((float(mass[index[b]]), b) for b in group.bodies if b in pulled),
                         default=(0.0, ""))
        if heavy > MASS_RATIO * light:
            warnings.warn(
                f"collision group '{group.name}': '{big}' ({heavy:g} kg) is {heavy / light:.3g} "
                f"times as heavy as '{small}' ({light:g} kg); a body resting on one more than "
                f"{MASS_RATIO:g} times lighter presses it into what it lies on or squeezes it "
                "out (docs/scenes.md: Contacts)", MassRatioWarning, stacklevel=2)


def _polygon_part(local: np.ndarray, colliding: bool) -> tuple[PolygonPart, float, float]:
    """A polygon's part from its vertices ``local`` (relative to the CM, body axes), its
    farthest vertex from the CM and its thickness; a colliding polygon is checked convex
    and turned counter-clockwise, with its edges' normals, and is as thick as its incircle;
    one that meets only walls (maybe concave) 2 area / perimeter, the thickness of a long
    thin strip."""
    extent = float(np.max(np.hypot(local[:, 0], local[:, 1])))
    if not colliding:
        edges = np.roll(local, -1, axis=0) - local
        perimeter = float(np.sum(np.hypot(edges[:, 0], edges[:, 1])))
        area = area_properties(Polygon(local)).area
        return (PolygonPart([tuple(p) for p in local.tolist()], []), extent,
                2.0 * area / perimeter)
    poly = ConvexPolygon.from_vertices(local)
    return poly.part(), extent, 2.0 * poly.inradius


class ContactPass(Sleep, WarmStarts):
    """Contact detection and response for one scene's walls and collision groups."""

    def __init__(self, scene: Scene, mass: States, inertia: States,
                 center_of_mass: States, threshold: float, *, lean: bool,
                 apart: Iterable[tuple[int, int]] = (), compiled: bool = False,
                 sleep: bool = False, restless: Iterable[int] = (),
                 joints: Optional[JointPass] = None, threads: int = 1) -> None:
        """The pass for ``scene``'s walls and collision groups, with the bodies' ``mass``,
        moment of ``inertia`` and ``center_of_mass`` (N x 2, body axes) in the scene's
        order; ``threshold``: the approach speed below which contacts do not bounce;
        ``lean``: plain floats rather than numpy where both would do; ``apart``: pairs of
        bodies (i < j) that do not collide although a group names them; ``compiled``:
        resolve in the kernel (:mod:`.compiled`), which must be built; ``sleep``: let
        resting islands sleep; ``restless``: bodies that never sleep (pushed by more than
        gravity and contacts); ``joints``: the scene's joint pass, whose velocity rows the
        solve sweeps with the contacts of the islands they are in (:mod:`.coupled`);
        ``threads``: the kernel's threads for the velocity passes of big islands (1 or 2,
        the same bits either way; the Python path has one)."""
        index = {body.name: i for i, body in enumerate(scene.bodies)}
        _warn_mass_ratios(scene, mass)
        self.threshold = threshold
        self.inverse_mass = (1.0 / mass).tolist()
        self.inverse_inertia = (1.0 / inertia).tolist()
        self.wall_normal = [(w.normal[0], w.normal[1]) for w in scene.walls]
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
        self._read_map(scene, index)
        # Bodies that meet other convex parts: the collision groups' and the map's.
        swept = sorted(set(colliding) | set(self.static_bodies))
        self.parts: list[list[Part]] = []
        reach, thickness = [], []
        # A pile's bodies share a few outlines: each is checked and oriented once.
        outlines: dict[tuple[bytes, bool], tuple[PolygonPart, float, float]] = {}
        convex = set(swept)
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
                key = (local.tobytes(), i in convex)
                if key not in outlines:
                    outlines[key] = _polygon_part(local, i in convex)
                outline, extent, width = outlines[key]
                parts.append(PolygonPart(list(outline.vertices), list(outline.normals)))
                extents.append(extent)
                widths.append(width)
            self.parts.append(parts)
            reach.append(max(extents))
            thickness.append(min(widths, default=math.inf))
        self.colliding = colliding
        #: Farthest shape point from each body's CM, and thinnest colliding part.
        self.reach = reach
        #: Per body, the overlap the position correction leaves it (solve.py: slop): by its
        #: thinnest part (at most twice its reach).
        self.slop = [slop(min(width, 2.0 * extent)) for width, extent in zip(thickness, reach)]
        self.thickness = min((thickness[i] for i in swept), default=math.inf)
        if scene.map is not None:  # a wall of the map may be one cell thin
            self.thickness = min(self.thickness, scene.map.occupancy.resolution)
        self._lean = lean
        self.swept = swept
        self._colliding_index = np.array(swept, dtype=int)
        self._colliding_reach = np.array([reach[i] for i in swept])
        touching = {b for bodies in self.wall_bodies for b in bodies} | set(swept)
        self.bodies = np.array(sorted(touching), dtype=int)
        self._warm: WarmImpulses = {}
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
        self.threads = threads
        #: The velocity passes' tolerance: the scene's ``contacts.converged``, by default
        #: :data:`~.solve.CONVERGED`.
        self.converged = CONVERGED if scene.converged is None else scene.converged
        #: How far a bounce carries the step's change of the contact's normal velocity
        #: (:meth:`follow`); 0 for a method whose positions move with the step's end velocity.
        self.lead = 0.0
        self._kernel: Optional[_compiled.CompiledContacts] = (
            _compiled.CompiledContacts(self) if compiled else None)

    def follow(self, position_share: float) -> None:
        """Bounce as the integrator that steps the bodies keeps its energy: one whose
        positions move with the share s of the step's change of velocity
        (:attr:`~..integrators.methods.Integrator.position_share`: q1 = q0 + h (v0 + s a h)
        under a constant acceleration a).

        A bounce reverses the contact's normal velocity u0 from before the step, as if met
        at the step's start, the forces then acting over the whole step. Through an elastic
        bounce (e = 1) such a method keeps its own conserved energy (its modified energy
        E + (s - 1/2) h m a . v under a constant force, E itself for s = 1/2) exactly when
        the bounce leaves the normal velocity -u0 + 2 (1 - s) (u1 - u0), u1 the normal
        velocity the step ended with: reversing u0 alone gains m |a| h |u0| at each bounce
        for s = 1/2 (a box on a floor with e = 1 and rk4 or dopri5 bounced five times as
        high after 20 s). So the bounce reverses e times u0 - :attr:`lead` (u1 - u0), with
        :attr:`lead` = 2 (1 - s): 0 for semi-implicit and backward Euler, 1 for Verlet, the
        Runge-Kutta methods and implicit midpoint, 2 for explicit Euler."""
        lead = 2.0 * (1.0 - position_share)
        if lead == self.lead:
            return
        self.lead = lead
        if self._kernel is not None:  # the kernel's pass reads it when made
            state = self.export_state()
            self._kernel = _compiled.CompiledContacts(self)
            self.import_state(state)

    def _read_map(self, scene: Scene, index: dict[str, int]) -> None:
        """The map's boxes as convex parts fixed in the world, their bounds, material and
        the bodies that collide with them (none without a map)."""
        self.static_parts = []
        self.static_bodies = []
        self.static_material = (0.0, 0.0)
        self.static_bounds = np.zeros((0, 4))
        if scene.map is None:
            return
        boxes = scene.map.occupancy.box_vertices()
        self.static_parts = [ConvexPolygon.from_vertices(corners).part() for corners in boxes]
        self.static_bounds = np.column_stack([boxes[:, :, 0].min(axis=1),
                                              boxes[:, :, 0].max(axis=1),
                                              boxes[:, :, 1].min(axis=1),
                                              boxes[:, :, 1].max(axis=1)])
        self.static_material = (scene.map.restitution, scene.map.friction)
        self.static_bodies = sorted(index[b] for b in scene.map.bodies)

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

    @property
    def compiled(self) -> bool:
        """True while the pass resolves in the compiled kernel."""
        return self._kernel is not None

    def kernel_pass(self) -> object:
        """The kernel's contact pass (a capsule), for whole steps in the kernel."""
        if self._kernel is None:
            raise RuntimeError("the contact pass resolves in Python")
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

    def import_state(self, state: list[list[Any]] | dict[str, Any]) -> None:
        """Restore :meth:`export_state`'s data: the next step gives the same bits as it
        would have after the step that data was taken at. Warm starts alone (a list) wake
        every body."""
        warm: list[list[Any]]
        if isinstance(state, dict):
            self.rested = [float(t) for t in state["rested"]]
            self.island = [int(i) for i in state["island"]]
            warm = state["warm"]
        else:
            self.rested = [0.0] * len(self.rested)
            self.island = [-1] * len(self.island)
            warm = state
        if self._kernel is not None:
            self._kernel.set_sleep(self)
        self._warm = {(int(a), int(b), int(part_a), int(part_b)):
                      [(float(lx), float(ly), float(jn), float(jt)) for lx, ly, jn, jt in contacts]
                      for (a, b, part_a, part_b), contacts in warm}
        if self._kernel is not None:
            self._kernel.set_impulses([(*key, *contact) for key, contacts in self._warm.items()
                                       for contact in contacts])
            self._warm = {}

    def resolve(self, q1: States, v1: States, q0: States, v0: States,
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
        # each body's turn back from the step's end to its start
        turns = {b: cos_sin_of(float(q0[b, 2]) - poses[b][2]) for b in touched}
        rows = [self._prepare(c, poses, turns, moved, before, h) for c in contacts]
        for row in rows:  # warm start, once every target is set from the step's velocities
            jn, jt, nx, ny = row.jn, row.jt, row.nx, row.ny
            row.push(velocity, jn * nx - jt * ny, jn * ny + jt * nx)
        islands = solve_velocities(rows, velocity, units, self.converged)
        if joints is not None:
            joints.take_extra(units)
        self._remember(rows, poses, [c.point for c in contacts])
        for b in touched:
            if velocity[b] != arrived[b]:
                poses[b] = [p + h * (new - old)
                            for p, new, old in zip(poses[b], velocity[b], moved[b])]
                q1[b] = poses[b]
                v1[b] = velocity[b]
        correct_positions(islands, velocity, q1, h)
        self._doze(rows, v1, h)

    def _prepare(self, contact: Contact, poses: Velocities, turns: dict[int, tuple[float, float]],
                 velocity: Velocities, before: Velocities, h: float) -> ContactRow:
        """The solver row of ``contact``, its impulses warm-started from the last step;
        ``velocity``: the bodies' velocities the step's positions moved with, ``turns``: the
        cosine and sine of each body's turn back from the step's end to its start.

        Its arms are taken where the step's new velocity moves the bodies from, at the
        step's start: taken at its end, which the step has turned, the velocity from before
        the step already separated a pivoting corner, and a frictionless box rocking on its
        corners at e = 1 sank, was lifted out by the position correction and gained 74 % in
        100 s (docs/scenes.md). A bounce keeps the arms it was found at, where the article's
        collision impulse applies."""
        row = self._row(contact, poses, velocity, turns)
        bounces = row.depth > 0.0 and row.approach < -self.threshold
        if bounces:
            row = self._row(contact, poses, velocity)
        a, b, approach, depth = row.a, row.b, row.approach, row.depth
        # End the step just touching (never pushed apart by velocity: overlap left from
        # earlier steps is the position correction's job) or, if the contact closed during
        # the step fast enough, bounce. The bounce reverses the approach speed from before
        # the step, the forces acting after it (follow): reversing the speed they added
        # during the step too would add energy at every bounce.
        # The contact's impulse j adds j (target + impact) / 2 to the energy the method
        # keeps, so an elastic contact that does not bounce never aims above -e impact:
        # one that was separating before the step (a resting corner that the step's
        # rotation had lifted) and was stopped at 0 added j impact / 2 (a box rocking at
        # e = 1 gained 20 % in 100 s). With e = 0 the cap is 0, which no target exceeds.
        target = min(approach + depth / h, 0.0)
        if bounces or contact.e != 0.0:
            impact = normal_velocity(before[a], before[b], row.rax, row.ray, row.rbx, row.rby,
                                      row.nx, row.ny)
            if self.lead != 0.0:  # as the integrator keeps its energy (follow)
                impact -= self.lead * (approach - impact)
            if bounces:
                target = max(target, -contact.e * min(impact, 0.0))
            elif contact.e != 0.0:
                target = min(target, -contact.e * impact)
        row.target = target
        px, py = contact.point
        row.jn, row.jt = self._recall(contact.key, px - poses[b][0], py - poses[b][1],
                                      poses[b][2])
        return row

    def _carry_back(self, body: int, part: int, rx: float, ry: float, angle: float,
                    turn: tuple[float, float]) -> tuple[float, float]:
        """The arm (rx, ry) of ``body``'s ``part`` at ``angle`` turned by ``turn`` (its
        cosine and sine): a vertex's with the body; a circle's centre with the body, its
        offset from the centre along the normal kept."""
        ox = oy = 0.0
        shape = self.parts[body][part]
        if isinstance(shape, CirclePart):
            c, s = cos_sin_of(angle)
            cx, cy = shape.center
            ox, oy = rx - (c * cx - s * cy), ry - (s * cx + c * cy)
            rx, ry = rx - ox, ry - oy
        c, s = turn
        return c * rx - s * ry + ox, s * rx + c * ry + oy

    def _row(self, contact: Contact, poses: Velocities, velocity: Velocities,
             turns: Optional[dict[int, tuple[float, float]]] = None) -> ContactRow:
        """The solver row of ``contact`` at ``poses`` and ``velocity``: arms (turned back by
        each body's ``turns``, where given: :meth:`_carry_back`), effective masses and
        approach speed, with no impulse yet and target 0."""
        a, b, (px, py), (nx, ny), depth, _, mu, key = contact
        im_a, ii_a = (self.inverse_mass[a], self.inverse_inertia[a]) if a >= 0 else (0.0, 0.0)
        im_b, ii_b = self.inverse_mass[b], self.inverse_inertia[b]
        rax, ray = (px - poses[a][0], py - poses[a][1]) if a >= 0 else (0.0, 0.0)
        rbx, rby = px - poses[b][0], py - poses[b][1]
        if turns is not None:
            if a >= 0:
                rax, ray = self._carry_back(a, key[2], rax, ray, poses[a][2], turns[a])
            rbx, rby = self._carry_back(b, key[3], rbx, rby, poses[b][2], turns[b])
        rna, rnb = rax * ny - ray * nx, rbx * ny - rby * nx  # perp(r) . n = r x n
        rta, rtb = -rax * nx - ray * ny, -rbx * nx - rby * ny  # perp(r) . t, t = perp(n)
        mass_n = 1.0 / (im_a + im_b + rna * rna * ii_a + rnb * rnb * ii_b)
        mass_t = 1.0 / (im_a + im_b + rta * rta * ii_a + rtb * rtb * ii_b)
        if not (mass_n > 0.0 and mass_t > 0.0):
            raise ArithmeticError("the contact's effective mass underflowed (a lever arm or "
                                  "inverse mass too large for a double)")
        approach = normal_velocity(velocity[a], velocity[b], rax, ray, rbx, rby, nx, ny)
        overlap = min(self.slop[a], self.slop[b]) if a >= 0 else self.slop[b]
        return ContactRow(a, b, rax, ray, rbx, rby, nx, ny, mass_n, mass_t, 0.0, mu, 0.0, 0.0,
                          depth, im_a, ii_a, im_b, ii_b, approach, key, overlap)

    def impact(self, q: States, v: States, contacts: list[Contact]) -> bool:
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
        solve_velocities(rows, velocity, [], self.converged)
        for b in touched:
            v[b] = velocity[b]
        return True
