"""The model: a scene turned into arrays and only the force terms and passes it declares.

``Model.accelerations`` is steps 3 to 6 of the article's algorithm ("Physics, Part 2:
Angular Effects"): collect the forces with their points, sum them at the CM, add up the
perp-dot torques (Eq. 11), and divide by the mass (F = M a, Eq. 5) and by the moment of
inertia (tau = I alpha, Eq. 14).
A scene without walls or collisions has no contact pass; a scene without springs has no
spring term; a force at the CM computes no torque.
"""
from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from typing import Any, Optional

import numpy as np

from ..contact.joints import JointPass
from ..contact.soft_joints import SoftJointPass
from ..contact.solver import ContactPass
from ..geometry.planar import cos_sin_of, perp, rotate
from ..integrators.coloring import Coloring, color
from ..scene.load import (
    AngularDampingSpec,
    ConstantForceSpec,
    ConstantTorqueSpec,
    DragSpec,
    Gravity,
    Scene,
    SpringSpec,
    check_soft_joints,
)
from . import kernel
from .forces import (
    AnchorSpringTerm,
    AngularDampingTerm,
    BodySpringTerm,
    CenterDragTerm,
    ConstantWrenchTerm,
    ForceTerm,
    GravityTerm,
    Kinematics,
    PointDragTerm,
    ScalarKinematics,
    WrenchRow,
)

__all__ = ["LEAN_BODIES", "FrameRow", "Model", "wrench_term"]


#: Up to this many bodies the forces are summed in plain Python floats (``add_scalar``),
#: above it with numpy (``add``): the crossing point measured by ``hecker-dynamics bench``.
LEAN_BODIES = 32

#: A body frame in plain floats: origin (x, y), angle, origin velocity (vx, vy), omega.
FrameRow = tuple[tuple[float, float], float, tuple[float, float], float]


class Model:
    """Arrays and force terms for one scene; state is (q, v), each (N, 3)."""

    def __init__(self, scene: Scene, *, lean: Optional[bool] = None,
                 compiled: Optional[bool] = None) -> None:
        """``lean`` chooses the Python path (plain floats or numpy; default by the number
        of bodies), ``compiled`` the kernel (default: when it is built and enabled, and
        no Python path was chosen)."""
        self.scene = scene
        self.names = tuple(b.name for b in scene.bodies)
        self.index = {name: i for i, name in enumerate(self.names)}
        self.mass = np.array([b.mass.mass for b in scene.bodies])
        self.inertia = np.array([b.mass.moment_of_inertia for b in scene.bodies])
        self.inverse_mass = np.column_stack([1.0 / self.mass, 1.0 / self.mass, 1.0 / self.inertia])
        self.cm_local = np.array([b.mass.center_of_mass for b in scene.bodies])
        self._cm_local_rows = [(float(x), float(y)) for x, y in self.cm_local]
        self.terms: tuple[ForceTerm, ...] = tuple(_build_terms(self, scene))
        self._terms_oriented = any(t.uses_orientation for t in self.terms)
        # The scene's couplings, the inputs' couplings and the coloring of both, once asked.
        self._term_couplings: Optional[tuple[tuple[int, int], ...]] = None
        self._coloring: Optional[tuple[tuple[tuple[int, int], ...], Coloring]] = None
        self.lean = self.size <= LEAN_BODIES if lean is None else lean
        if compiled is None:
            compiled = lean is None and kernel.enabled()
        if compiled and not kernel.built():
            raise RuntimeError("the compiled kernel hecker_dynamics._kernel is not built")
        #: The kernel's program of these forces, or None: Python evaluates them.
        self.compiled: Optional[kernel.CompiledForces] = (
            kernel.CompiledForces(self.inverse_mass, self.terms) if compiled else None)
        self.inputs = None
        self._inverse_mass_rows = self.inverse_mass.tolist()
        check_soft_joints(scene)  # as its file would be, after a command line's changes
        self.joints: Optional[JointPass] = (
            (JointPass if scene.soft_joints is None else SoftJointPass)(
                scene, self.inverse_mass, self.cm_local, compiled=self.compiled is not None)
            if scene.joints else None)
        self.contacts: Optional[ContactPass] = (
            ContactPass(scene, self.mass, self.inertia, self.cm_local,
                        _restitution_threshold(scene), lean=self.lean,
                        # joined bodies do not collide by default
                        apart=() if self.joints is None else self.joints.connected,
                        compiled=self.compiled is not None,
                        sleep=scene.sleep, restless=_restless(self, scene), joints=self.joints,
                        threads=scene.threads)
            # A group that deletes left with one body or none pairs nothing: no pass for it.
            if scene.walls or scene.map or any(len(group.bodies) > 1
                                               for group in scene.collisions) else None)

    @property
    def inputs(self) -> Optional[ConstantWrenchTerm]:
        """The wrenches of the inputs active this step (None when there are none)."""
        return self._inputs

    @inputs.setter
    def inputs(self, term: Optional[ConstantWrenchTerm]) -> None:
        self._inputs = term
        self._active = self.terms if term is None else (*self.terms, term)
        self._oriented = self._terms_oriented or (term is not None and term.uses_orientation)
        if self.compiled is not None:
            self.compiled.set_inputs(term)

    def use_python(self, lean: Optional[bool] = None) -> None:
        """Evaluate the forces and contacts in Python from now on, not in the compiled
        kernel: the forces in plain floats (``lean``) or with numpy (default: by the number
        of bodies, as without the kernel). The tests and the benchmark compare the paths."""
        self.lean = self.size <= LEAN_BODIES if lean is None else lean
        self.compiled = None
        if self.contacts is not None:
            self.contacts.use_python()
        if self.joints is not None:
            self.joints.use_python()

    @property
    def oriented(self) -> bool:
        """True if some active force depends on the bodies' angles."""
        return self._oriented

    @property
    def size(self) -> int:
        return len(self.names)

    def jacobian_coloring(self) -> Coloring:
        """The groups of bodies a Jacobian by colored differences bumps together, for the
        scene's forces and the inputs active now (see :mod:`.coloring`).

        Computed when first asked for, and again only when the inputs couple other bodies
        (an input whose axes or point belong to a body other than its target); contacts are
        not part of :meth:`accelerations` and couple nothing.
        """
        if self._term_couplings is None:
            self._term_couplings = _couplings(self.terms)
        extra = _couplings(() if self._inputs is None else (self._inputs,))
        if self._coloring is None or self._coloring[0] != extra:
            self._coloring = (extra, color(self.size, self._term_couplings + extra))
        return self._coloring[1]

    def local(self, body: int, point: tuple[float, float]) -> np.ndarray:
        """A body-frame point as an offset from the body's CM, in body axes."""
        return np.asarray(point, dtype=float) - self.cm_local[body]

    def can_turn(self) -> np.ndarray:
        """Mask of bodies that some declared force, wall or collision can apply torque to."""
        mask = np.zeros(self.size, dtype=bool)
        for term in self.terms:
            mask[term.turns] = True
        if self.contacts is not None:
            mask[self.contacts.bodies] = True
        if self.joints is not None:
            mask[self.joints.bodies] = True
        return mask

    def accelerations(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(ax, ay, alpha) per body: summed forces over mass (Eq. 5), summed torques over
        inertia (Eq. 14)."""
        if self.compiled is not None:
            return self.compiled.accelerations(q, v, self._oriented)
        terms, oriented = self._active, self._oriented
        if not terms:
            return np.zeros_like(q)
        if self.lean:
            state = ScalarKinematics.of(q.tolist(), v.tolist(), oriented)
            wrenches = [[0.0, 0.0, 0.0] for _ in range(self.size)]
            for term in terms:
                term.add_scalar(state, wrenches)
            return np.array([[fx * im, fy * im2, tq * ii]
                             for (fx, fy, tq), (im, im2, ii) in zip(wrenches,
                                                                    self._inverse_mass_rows)])
        columns = Kinematics(q, v, oriented)
        sums = np.zeros((3, self.size))  # rows Fx, Fy, torque: contiguous per component
        for term in terms:
            term.add(columns, sums)
        return np.multiply(sums.T, self.inverse_mass, out=np.empty_like(q))

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic energy plus the potential energy of gravity and springs."""
        kinetic = 0.5 * float(np.sum(self.mass * (v[:, 0] ** 2 + v[:, 1] ** 2))
                              + np.sum(self.inertia * v[:, 2] ** 2))
        potential = sum(term.potential(q) for term in self.terms if hasattr(term, "potential"))
        return kinetic + potential

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """CM state from the scene's body-frame poses and origin velocities."""
        bodies = self.scene.bodies
        return self.cm_states(np.arange(self.size), np.array([b.position for b in bodies]),
                              np.array([b.angle for b in bodies]),
                              np.array([b.velocity for b in bodies]),
                              np.array([b.angular_velocity for b in bodies]))

    def cm_states(self, index: np.ndarray, origin: np.ndarray, angle: np.ndarray,
                  origin_velocity: np.ndarray, omega: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """CM states (q, v rows) of the bodies ``index`` whose body frames have these poses
        and origin velocities: the CM, a body point, moves at the origin's velocity plus
        omega perp(r), a body point's velocity (Eq. 9)."""
        r_cm = rotate(self.cm_local[index], np.cos(angle), np.sin(angle))  # origin -> CM
        q = np.column_stack([origin + r_cm, angle])
        v = np.column_stack([origin_velocity + omega[:, None] * perp(r_cm), omega])
        return q, v

    def body_frames(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Origin positions and origin velocities of the body frames (fixed-frame axes)."""
        r_origin = -rotate(self.cm_local, np.cos(q[:, 2]), np.sin(q[:, 2]))  # CM -> origin
        return q[:, :2] + r_origin, v[:, :2] + v[:, 2:3] * perp(r_origin)

    def body_frame_rows(self, q: list[list[float]], v: list[list[float]]) -> list[FrameRow]:
        """:meth:`body_frames` in plain floats, a row per body with its angle and angular
        velocity: the same operations on the same values, so the same bits (numpy's
        float64 cos and sin are the C library's, as math's are; test_simulation checks),
        but for the sign of the NaN an infinite angle gives. A small world's publish
        instant spent most of its frames' time in numpy's per-call cost."""
        rows = []
        for (x, y, angle), (vx, vy, omega), (lx, ly) in zip(q, v, self._cm_local_rows):
            c, s = cos_sin_of(angle)
            rx, ry = -(c * lx - s * ly), -(s * lx + c * ly)  # CM -> origin
            rows.append(((x + rx, y + ry), angle, (vx + omega * -ry, vy + omega * rx), omega))
        return rows

    def stiffness(self) -> float:
        """Largest rate (1/s) the forces can impose: spring frequencies and damping rates.

        For a spring the effective inverse mass along its line is at most
        1/m_A + |r_A|^2/I_A (+ the same for B), so omega^2 <= k * that; a damper c gives a
        rate c * that, and so does linear drag at a point; at the CM, c / m. Quadratic
        drag's rate, 2 c |v| / m, depends on the speed and is left out. Explicit methods need
        this rate times the step to stay small.
        """
        rates = [0.0]
        for term in self.terms:
            if isinstance(term, (AnchorSpringTerm, BodySpringTerm)):
                mobility = self._mobility(*_ends(term))
                rates.extend(np.sqrt(term.law.stiffness * mobility))
                rates.extend(term.law.damping * mobility)
            elif isinstance(term, CenterDragTerm):
                rates.extend((term.coefficient / self.mass[term.body])[~term.quadratic])
            elif isinstance(term, PointDragTerm):
                mobility = self._mobility([(term.body, term.local)])
                rates.extend((term.coefficient * mobility)[~term.quadratic])
            elif isinstance(term, AngularDampingTerm):
                rates.extend(term.coefficient / self.inertia[term.body])
        return float(max(rates))

    def _mobility(self, ends: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        total: np.ndarray | float = 0.0
        for body, local in ends:
            total = total + 1.0 / self.mass[body] + np.sum(local ** 2, axis=1) / self.inertia[body]
        return np.asarray(total)


def _ends(term: AnchorSpringTerm | BodySpringTerm) -> tuple[list[tuple[np.ndarray, np.ndarray]]]:
    if isinstance(term, AnchorSpringTerm):
        return ([(term.body, term.local)],)
    return ([(term.body_a, term.local_a), (term.body_b, term.local_b)],)


def _couplings(terms: tuple[ForceTerm, ...]) -> tuple[tuple[int, int], ...]:
    """The distinct (source, target) body pairs the terms couple, sorted."""
    pairs = {(s, t) for term in terms
             for s, t in zip(term.couplings[0].tolist(), term.couplings[1].tolist()) if s != t}
    return tuple(sorted(pairs))


def _restitution_threshold(scene: Scene) -> float:
    """Approach speed below which contacts do not bounce (default: 4 steps of gravity)."""
    if scene.restitution_threshold is not None:
        return scene.restitution_threshold
    g = max((math.hypot(*f.acceleration) for f in scene.forces if isinstance(f, Gravity)),
            default=0.0)
    return max(1e-3, 4.0 * g * scene.step_ns * 1e-9)


def _restless(model: Model, scene: Scene) -> set[int]:
    """The bodies that never sleep: those a force of the scene other than gravity, or a
    joint, acts on (a sleeping body feels only gravity and contacts, both held off)."""
    names: set[str] = set()
    for spec in scene.forces:
        if isinstance(spec, Gravity):
            continue
        for field in ("body", "body_a", "body_b"):
            if isinstance(getattr(spec, field, None), str):
                names.add(getattr(spec, field))
        names.update(getattr(spec, "bodies", ()))
    restless = {model.index[name] for name in names}
    if model.joints is not None:
        restless.update(int(b) for b in model.joints.bodies)
    return restless


def _build_terms(model: Model, scene: Scene) -> list[ForceTerm]:
    """One vectorised term per kind of force the scene declares, and none for the others."""
    by_kind: dict[type, list[Any]] = defaultdict(list)
    for spec in scene.forces:
        by_kind[type(spec)].append(spec)
    idx = model.index
    terms: list[ForceTerm] = []

    weights = np.zeros((model.size, 2))
    pulled = np.zeros(model.size, dtype=bool)
    for spec in by_kind[Gravity]:
        for name in spec.bodies:
            weights[idx[name]] += model.mass[idx[name]] * np.asarray(spec.acceleration)
            pulled[idx[name]] = True
    if pulled.any():
        bodies = np.flatnonzero(pulled)
        terms.append(GravityTerm(bodies, weights[bodies]))

    springs = by_kind[SpringSpec]
    anchored = [s for s in springs if s.body_b is None]
    joined = [s for s in springs if s.body_b is not None]

    def law(group: list[SpringSpec]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (np.array([s.stiffness for s in group]), np.array([s.rest_length for s in group]),
                np.array([s.damping for s in group]))

    if anchored:
        body = np.array([idx[s.body_a] for s in anchored])
        terms.append(AnchorSpringTerm(
            body, np.array([model.local(idx[s.body_a], s.point_a) for s in anchored]),
            np.array([s.point_b for s in anchored]), *law(anchored)))
    if joined:
        terms.append(BodySpringTerm(
            np.array([idx[s.body_a] for s in joined]),
            np.array([model.local(idx[s.body_a], s.point_a) for s in joined]),
            np.array([idx[s.body_b] for s in joined]),
            np.array([model.local(idx[s.body_b], s.point_b) for s in joined]), *law(joined)))

    drags = [(idx[name], s) for s in by_kind[DragSpec] for name in s.bodies]
    center = [(i, s) for i, s in drags if s.point is None]
    pointed = [(i, s) for i, s in drags if s.point is not None]
    if center:
        terms.append(CenterDragTerm(np.array([i for i, _ in center]),
                                    np.array([s.coefficient for _, s in center]),
                                    np.array([s.quadratic for _, s in center])))
    if pointed:
        terms.append(PointDragTerm(np.array([i for i, _ in pointed]),
                                   np.array([model.local(i, s.point) for i, s in pointed]),
                                   np.array([s.coefficient for _, s in pointed]),
                                   np.array([s.quadratic for _, s in pointed])))

    damped = [(idx[name], s.coefficient) for s in by_kind[AngularDampingSpec] for name in s.bodies]
    if damped:
        terms.append(AngularDampingTerm(np.array([i for i, _ in damped]),
                                        np.array([c for _, c in damped])))

    wrenches = by_kind[ConstantForceSpec] + by_kind[ConstantTorqueSpec]
    if wrenches:
        rows = []
        for spec in wrenches:
            i = idx[spec.body]
            if isinstance(spec, ConstantTorqueSpec):
                rows.append(WrenchRow(i, (0.0, 0.0), spec.torque, -1, -1, (0.0, 0.0), False))
            else:
                at_point = spec.point is not None
                local = model.local(i, spec.point) if at_point else (0.0, 0.0)
                rows.append(WrenchRow(i, spec.force, 0.0, i if spec.body_axes else -1, i,
                                      tuple(local), at_point))
        terms.append(wrench_term(rows))
    return terms


def wrench_term(rows: Sequence[WrenchRow]) -> ConstantWrenchTerm:
    """Build a :class:`ConstantWrenchTerm` from its rows."""
    body, force, torque, axes, owner, point, at_point = zip(*rows)
    return ConstantWrenchTerm(np.array(body), np.array(force, dtype=float).reshape(-1, 2),
                              np.array(torque, dtype=float), np.array(axes), np.array(owner),
                              np.array(point, dtype=float).reshape(-1, 2), np.array(at_point))
