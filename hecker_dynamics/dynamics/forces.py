"""Force terms: each turns the state into generalised forces (Fx, Fy, torque) per body.

This is steps 3 to 5 of the article's algorithm ("Physics, Part 2: Angular Effects"):
every force has a point of application; the forces add up at the CM (F = M a, Eq. 5)
and each contributes the torque perp-dot(r, F) about the CM, with r the offset from the CM
to the point (Eq. 11). A body point's velocity is v_P = v_CM + omega perp(r)
(Eq. 9), which springs and drag at points use.

A term exists only if the scene declares such a force, and one applied at the CM never
touches the torque. Each term evaluates in two ways that tests hold equal to rounding:

- ``add``: vectorised over all its instances with numpy, for scenes of many bodies;
- ``add_scalar``: plain Python floats, for the few-body scenes ROS users mostly run, where
  numpy's cost per call (about a microsecond) would outweigh the arithmetic.

State layout: ``q[i] = (x_CM, y_CM, angle)`` and ``v[i] = (vx_CM, vy_CM, omega)``. Body
points are stored as offsets from the CM in body axes; :class:`Kinematics` and
:class:`ScalarKinematics` rotate them.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Optional, Protocol

import numpy as np

from ..geometry.planar import LARGEST_SQUARE, SMALLEST_SQUARE, cos_sin, cos_sin_of, magnitude

__all__ = ["Kinematics", "ScalarKinematics", "ForceTerm", "BodySum", "GravityTerm", "SpringLaw",
           "spring_force", "spring_force_scalar", "spring_energy", "spring_energy_scalar",
           "AnchorSpringTerm", "BodySpringTerm", "drag_force", "drag_force_scalar",
           "CenterDragTerm", "PointDragTerm", "AngularDampingTerm", "WrenchRow", "lever_arm",
           "ConstantWrenchTerm"]


Wrench = list[float]  # [Fx, Fy, torque] of one body, accumulated in place


class Kinematics:
    """The state of one evaluation in components, with the cos and sin of each angle.

    Components (x, y, vx, ...) rather than (N, 2) stacks keep numpy on contiguous 1-D
    arrays and avoid the temporaries of stacking, which dominate for many bodies.
    """

    def __init__(self, q: np.ndarray, v: np.ndarray, oriented: bool = True) -> None:
        self.x, self.y = q[:, 0], q[:, 1]
        self.vx, self.vy, self.omega = v[:, 0], v[:, 1], v[:, 2]
        if oriented:
            self.cos, self.sin = cos_sin(q[:, 2])

    def offset(self, body: np.ndarray, lx: np.ndarray,
               ly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World offsets r = R(angle) l of points given relative to each body's CM."""
        c, s = self.cos[body], self.sin[body]
        return c * lx - s * ly, s * lx + c * ly

    def point_velocity(self, body: np.ndarray, rx: np.ndarray,
                       ry: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """v_P = v_CM + omega perp(r) (Eq. 9)."""
        omega = self.omega[body]
        return self.vx[body] - omega * ry, self.vy[body] + omega * rx


@dataclass
class ScalarKinematics:
    """The same as :class:`Kinematics`, as Python lists of floats."""

    q: list[list[float]]
    v: list[list[float]]
    cos: list[float]
    sin: list[float]

    @classmethod
    def of(cls, q: list[list[float]], v: list[list[float]], oriented: bool) -> ScalarKinematics:
        if not oriented:
            return cls(q, v, [], [])
        try:
            return cls(q, v, [math.cos(b[2]) for b in q], [math.sin(b[2]) for b in q])
        except ValueError:  # an infinite angle: NaN for it, as numpy and C give
            cos, sin = zip(*(cos_sin_of(b[2]) for b in q))
            return cls(q, v, list(cos), list(sin))

    def offset(self, body: int, lx: float, ly: float) -> tuple[float, float]:
        c, s = self.cos[body], self.sin[body]
        return c * lx - s * ly, s * lx + c * ly

    def point_velocity(self, body: int, rx: float, ry: float) -> tuple[float, float]:
        vx, vy, omega = self.v[body]
        return vx - omega * ry, vy + omega * rx


class ForceTerm(Protocol):
    """A group of forces of one kind, accumulated into per-body generalised forces."""

    #: True if the term's forces depend on orientation and so need the bodies' angles.
    uses_orientation: bool

    @property
    def turns(self) -> np.ndarray:
        """Bodies the term can turn (it applies torque to them)."""

    @property
    def couplings(self) -> tuple[np.ndarray, np.ndarray]:
        """(sources, targets): the force on ``targets[e]`` depends on the state of
        ``sources[e]``, another body (every force depends on its own body's state)."""

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        """Add to ``out`` (3, N): rows Fx, Fy and torque (contiguous), vectorised."""

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        """Add to ``out`` (a [Fx, Fy, torque] list per body), in plain floats."""


class BodySum:
    """Sums per-instance values into per-body totals, by a rule chosen once from the topology.

    ``body[i]`` is the body of instance ``i``. Where the bodies are a block of consecutive
    bodies, each once (every body the end A of exactly one spring, say), no accumulation is
    needed: the values are gathered into body order (or taken as they are, if already in
    it) and added to a slice. Any other layout (a body repeated, or gaps between the
    bodies) is summed with ``np.bincount``.
    """

    def __init__(self, body: np.ndarray) -> None:
        self.body = body
        self._block: Optional[slice] = None  # the bodies, if each of a block appears once
        self._order: Optional[np.ndarray] = None  # instance of each body of the block
        first = int(body.min()) if len(body) else 0
        if np.array_equal(np.sort(body), np.arange(first, first + len(body))):
            self._block = slice(first, first + len(body))
            order = np.argsort(body)
            if not np.array_equal(order, np.arange(len(body))):
                self._order = order

    def _in_body_order(self, value: np.ndarray) -> np.ndarray:
        return value if self._order is None else value[self._order]

    def _combine(self, operation: np.ufunc, total: np.ndarray, value: np.ndarray) -> None:
        """``total[body] = operation(total[body], value)`` in place, per-body sums first."""
        if self._block is not None:
            part = total[self._block]
            operation(part, self._in_body_order(value), out=part)
        else:
            operation(total, np.bincount(self.body, value, minlength=len(total)), out=total)

    def add(self, total: np.ndarray, value: np.ndarray) -> None:
        """``total[body[i]] += value[i]`` for every instance ``i``."""
        self._combine(np.add, total, value)

    def subtract(self, total: np.ndarray, value: np.ndarray) -> None:
        """``total[body[i]] -= value[i]`` for every instance ``i``."""
        self._combine(np.subtract, total, value)

    def add_wrench(self, out: np.ndarray, fx: np.ndarray, fy: np.ndarray,
                   torque: Optional[np.ndarray] = None) -> None:
        """Add forces (and torques) to the rows Fx, Fy (and torque) of ``out`` (3, N)."""
        self._combine_wrench(np.add, out, fx, fy, torque)

    def subtract_wrench(self, out: np.ndarray, fx: np.ndarray, fy: np.ndarray,
                        torque: np.ndarray) -> None:
        """Subtract forces and torques from the rows of ``out`` (3, N)."""
        self._combine_wrench(np.subtract, out, fx, fy, torque)

    def _combine_wrench(self, operation: np.ufunc, out: np.ndarray, fx: np.ndarray,
                        fy: np.ndarray, torque: Optional[np.ndarray]) -> None:
        self._combine(operation, out[0], fx)
        self._combine(operation, out[1], fy)
        if torque is not None:
            self._combine(operation, out[2], torque)


def _no_couplings() -> tuple[np.ndarray, np.ndarray]:
    empty = np.zeros(0, dtype=int)
    empty.flags.writeable = False  # shared by every such term
    return empty, empty


#: The couplings of a term whose forces depend on their own body's state only.
NO_COUPLINGS: tuple[np.ndarray, np.ndarray] = _no_couplings()


#: The cached columns of a :class:`ConstantWrenchTerm` that depend on where its wrenches act
#: and not on their values (``turns`` does: a torque of zero turns nothing).
_PLACE_COLUMNS = ("rotated", "moving_point", "couplings", "_sums", "_point_columns", "places")


def _columns(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contiguous x and y columns of an (n, 2) array of points."""
    return np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])


def _apply_scalar(wrench: Wrench, rx: float, ry: float, fx: float, fy: float) -> None:
    """Add force (fx, fy) at offset (rx, ry) from the CM: the force and perp-dot torque
    (Eq. 11)."""
    wrench[0] += fx
    wrench[1] += fy
    wrench[2] += rx * fy - ry * fx


class GravityTerm:
    """m g at the CM of each body: no torque (article: gravity acts at the CM)."""

    uses_orientation = False
    couplings = NO_COUPLINGS

    def __init__(self, bodies: np.ndarray, weights: np.ndarray) -> None:
        self.bodies = bodies
        self.weights = weights  # (k, 2) = m g per body
        self.turns = np.zeros(0, dtype=int)
        self._sum = BodySum(bodies)
        self._weights = _columns(weights)
        self._rows = list(zip(bodies.tolist(), weights.tolist()))

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        self._sum.add_wrench(out, *self._weights)

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for body, (wx, wy) in self._rows:
            wrench = out[body]
            wrench[0] += wx
            wrench[1] += wy

    def potential(self, q: np.ndarray) -> float:
        return -float(np.sum(self.weights * q[self.bodies, :2]))


class SpringLaw:
    """Stiffness k, rest length L0 and damping c of a group of springs, with the group's
    zero-rest-length springs (the linear law) found once."""

    def __init__(self, stiffness: np.ndarray, rest_length: np.ndarray,
                 damping: np.ndarray) -> None:
        self.stiffness, self.rest_length, self.damping = stiffness, rest_length, damping
        self.zero_rest = rest_length == 0.0
        self.all_zero_rest = bool(self.zero_rest.all())
        self.any_zero_rest = bool(self.zero_rest.any())


def spring_force(dx: np.ndarray, dy: np.ndarray, dvx: np.ndarray, dvy: np.ndarray,
                 law: SpringLaw) -> tuple[np.ndarray, np.ndarray]:
    """Force on end A of damped springs, with d = p_A - p_B and dv = v_A - v_B.

    With a rest length, Hooke's law and a dashpot act along the spring:
    F = -(k (|d| - L0) + c (dv . u)) u with u = d / |d| (no force where both ends meet).
    A zero-rest-length spring is the linear law F = -k d - c dv.
    """
    k, c = law.stiffness, law.damping
    if law.all_zero_rest:
        return -k * dx - c * dvx, -k * dy - c * dvy
    length, ux, uy = _direction(dx, dy)
    along = -(k * (length - law.rest_length) + c * (dvx * ux + dvy * uy))
    fx, fy = along * ux, along * uy
    if law.any_zero_rest:
        fx = np.where(law.zero_rest, -k * dx - c * dvx, fx)
        fy = np.where(law.zero_rest, -k * dy - c * dvy, fy)
    return fx, fy


def _direction(dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lengths |d| and unit vectors u = d / |d| (u = 0 where |d| = 0).

    sqrt(dx^2 + dy^2) is several times cheaper than ``np.hypot``; where a square underflows
    or overflows (or both ends meet) the careful ``np.hypot`` and a guarded division are
    used instead.
    """
    square = dx * dx
    square += dy * dy
    if square.min() >= SMALLEST_SQUARE and square.max() <= LARGEST_SQUARE:
        length = np.sqrt(square, out=square)
        return length, dx / length, dy / length
    length = np.hypot(dx, dy)
    apart = length > 0.0
    ux = np.divide(dx, length, out=np.zeros_like(length), where=apart)
    uy = np.divide(dy, length, out=np.zeros_like(length), where=apart)
    return length, ux, uy


def spring_force_scalar(dx: float, dy: float, dvx: float, dvy: float, stiffness: float,
                        rest_length: float, damping: float) -> tuple[float, float]:
    """:func:`spring_force` for one spring, in plain floats."""
    if rest_length == 0.0:
        return -stiffness * dx - damping * dvx, -stiffness * dy - damping * dvy
    distance = magnitude(dx, dy)
    if distance == 0.0:
        return 0.0, 0.0
    ux, uy = dx / distance, dy / distance
    along = -(stiffness * (distance - rest_length) + damping * (dvx * ux + dvy * uy))
    return along * ux, along * uy


def spring_energy(dx: np.ndarray, dy: np.ndarray, stiffness: np.ndarray,
                  rest_length: np.ndarray) -> float:
    length = np.hypot(dx, dy)
    return float(np.sum(0.5 * stiffness * (length - rest_length) ** 2))


def spring_energy_scalar(dx: float, dy: float, stiffness: float, rest_length: float) -> float:
    """k (|d| - L0)^2 / 2 of one spring in plain floats (inf where it overflows); |d| as
    the kernel computes it (``magnitude``), so that its sum gives the same bits."""
    stretch = magnitude(dx, dy) - rest_length
    return 0.5 * stiffness * (stretch * stretch)


class AnchorSpringTerm:
    """Damped springs from body points to fixed anchors."""

    uses_orientation = True
    couplings = NO_COUPLINGS

    def __init__(self, body: np.ndarray, local: np.ndarray, anchor: np.ndarray,
                 stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray) -> None:
        self.body, self.local, self.anchor = body, local, anchor
        self.law = SpringLaw(stiffness, rest_length, damping)
        self.turns = np.unique(body[np.any(local != 0.0, axis=1)])
        self._local, self._anchor = _columns(local), _columns(anchor)
        self._sum = BodySum(body)
        self._rows = list(zip(body.tolist(), local.tolist(), anchor.tolist(), stiffness.tolist(),
                              rest_length.tolist(), damping.tolist()))

    def _stretch(self, state: Kinematics) -> tuple[np.ndarray, ...]:
        """Offsets of the attachment points and the spring vectors d = p - anchor."""
        rx, ry = state.offset(self.body, *self._local)
        ax, ay = self._anchor
        return rx, ry, state.x[self.body] + rx - ax, state.y[self.body] + ry - ay

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        rx, ry, dx, dy = self._stretch(state)
        fx, fy = spring_force(dx, dy, *state.point_velocity(self.body, rx, ry), self.law)
        self._sum.add_wrench(out, fx, fy, rx * fy - ry * fx)

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for body, (lx, ly), (ax, ay), k, rest, c in self._rows:
            rx, ry = state.offset(body, lx, ly)
            x, y, _ = state.q[body]
            fx, fy = spring_force_scalar(x + rx - ax, y + ry - ay,
                                         *state.point_velocity(body, rx, ry), k, rest, c)
            _apply_scalar(out[body], rx, ry, fx, fy)

    def potential(self, q: np.ndarray) -> float:
        _, _, dx, dy = self._stretch(Kinematics(q, np.zeros_like(q)))
        return spring_energy(dx, dy, self.law.stiffness, self.law.rest_length)

    def potential_scalar(self, state: ScalarKinematics) -> float:
        total = 0.0
        for body, (lx, ly), (ax, ay), k, rest, _ in self._rows:
            rx, ry = state.offset(body, lx, ly)
            x, y, _ = state.q[body]
            total += spring_energy_scalar(x + rx - ax, y + ry - ay, k, rest)
        return total


class BodySpringTerm:
    """Damped springs between points of two bodies (equal and opposite forces)."""

    uses_orientation = True

    def __init__(self, body_a: np.ndarray, local_a: np.ndarray, body_b: np.ndarray,
                 local_b: np.ndarray, stiffness: np.ndarray, rest_length: np.ndarray,
                 damping: np.ndarray) -> None:
        self.body_a, self.local_a, self.body_b, self.local_b = body_a, local_a, body_b, local_b
        self.law = SpringLaw(stiffness, rest_length, damping)
        self.turns = np.unique(np.concatenate([body_a[np.any(local_a != 0.0, axis=1)],
                                               body_b[np.any(local_b != 0.0, axis=1)]]))
        self._local_a, self._local_b = _columns(local_a), _columns(local_b)
        self._sum_a, self._sum_b = BodySum(body_a), BodySum(body_b)
        self.couplings = (np.concatenate([body_a, body_b]), np.concatenate([body_b, body_a]))
        self._rows = list(zip(body_a.tolist(), local_a.tolist(), body_b.tolist(),
                              local_b.tolist(), stiffness.tolist(), rest_length.tolist(),
                              damping.tolist()))

    def _ends(self, state: Kinematics) -> tuple[np.ndarray, ...]:
        """Offsets of both ends from their CMs and the spring vectors d = p_A - p_B."""
        a, b = self.body_a, self.body_b
        rax, ray = state.offset(a, *self._local_a)
        rbx, rby = state.offset(b, *self._local_b)
        return (rax, ray, rbx, rby,
                state.x[a] + rax - state.x[b] - rbx, state.y[a] + ray - state.y[b] - rby)

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        rax, ray, rbx, rby, dx, dy = self._ends(state)
        vax, vay = state.point_velocity(self.body_a, rax, ray)
        vbx, vby = state.point_velocity(self.body_b, rbx, rby)
        fx, fy = spring_force(dx, dy, vax - vbx, vay - vby, self.law)
        self._sum_a.add_wrench(out, fx, fy, rax * fy - ray * fx)
        # End B takes -F, whose torque is perp-dot(r_B, -F).
        self._sum_b.subtract_wrench(out, fx, fy, rbx * fy - rby * fx)

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for a, (lax, lay), b, (lbx, lby), k, rest, c in self._rows:
            rax, ray = state.offset(a, lax, lay)
            rbx, rby = state.offset(b, lbx, lby)
            xa, ya, _ = state.q[a]
            xb, yb, _ = state.q[b]
            vax, vay = state.point_velocity(a, rax, ray)
            vbx, vby = state.point_velocity(b, rbx, rby)
            fx, fy = spring_force_scalar(xa + rax - xb - rbx, ya + ray - yb - rby,
                                         vax - vbx, vay - vby, k, rest, c)
            _apply_scalar(out[a], rax, ray, fx, fy)
            _apply_scalar(out[b], rbx, rby, -fx, -fy)

    def potential(self, q: np.ndarray) -> float:
        *_, dx, dy = self._ends(Kinematics(q, np.zeros_like(q)))
        return spring_energy(dx, dy, self.law.stiffness, self.law.rest_length)

    def potential_scalar(self, state: ScalarKinematics) -> float:
        total = 0.0
        for a, (lax, lay), b, (lbx, lby), k, rest, _ in self._rows:
            rax, ray = state.offset(a, lax, lay)
            rbx, rby = state.offset(b, lbx, lby)
            xa, ya, _ = state.q[a]
            xb, yb, _ = state.q[b]
            total += spring_energy_scalar(xa + rax - xb - rbx, ya + ray - yb - rby, k, rest)
        return total


def drag_force(vx: np.ndarray, vy: np.ndarray, coefficient: np.ndarray,
               quadratic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """-c v (linear) or -c |v| v (quadratic), per point."""
    scale = np.where(quadratic, coefficient * np.hypot(vx, vy), coefficient)
    return -scale * vx, -scale * vy


def drag_force_scalar(vx: float, vy: float, coefficient: float,
                      quadratic: bool) -> tuple[float, float]:
    """:func:`drag_force` for one point, in plain floats."""
    scale = coefficient * magnitude(vx, vy) if quadratic else coefficient
    return -scale * vx, -scale * vy


class CenterDragTerm:
    """Linear or quadratic drag at the CM: no torque."""

    uses_orientation = False
    couplings = NO_COUPLINGS

    def __init__(self, body: np.ndarray, coefficient: np.ndarray, quadratic: np.ndarray) -> None:
        self.body, self.coefficient, self.quadratic = body, coefficient, quadratic
        self.turns = np.zeros(0, dtype=int)
        self._sum = BodySum(body)
        self._rows = list(zip(body.tolist(), coefficient.tolist(), quadratic.tolist()))

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        body = self.body
        self._sum.add_wrench(out, *drag_force(state.vx[body], state.vy[body], self.coefficient,
                                              self.quadratic))

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for body, c, quadratic in self._rows:
            vx, vy, _ = state.v[body]
            fx, fy = drag_force_scalar(vx, vy, c, quadratic)
            out[body][0] += fx
            out[body][1] += fy


class PointDragTerm:
    """Linear or quadratic drag at body points, using the point velocity v_P."""

    uses_orientation = True
    couplings = NO_COUPLINGS

    def __init__(self, body: np.ndarray, local: np.ndarray, coefficient: np.ndarray,
                 quadratic: np.ndarray) -> None:
        self.body, self.local = body, local
        self.coefficient, self.quadratic = coefficient, quadratic
        self.turns = np.unique(body)
        self._local = _columns(local)
        self._sum = BodySum(body)
        self._rows = list(zip(body.tolist(), local.tolist(), coefficient.tolist(),
                              quadratic.tolist()))

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        rx, ry = state.offset(self.body, *self._local)
        fx, fy = drag_force(*state.point_velocity(self.body, rx, ry), self.coefficient,
                            self.quadratic)
        self._sum.add_wrench(out, fx, fy, rx * fy - ry * fx)

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for body, (lx, ly), c, quadratic in self._rows:
            rx, ry = state.offset(body, lx, ly)
            fx, fy = drag_force_scalar(*state.point_velocity(body, rx, ry), c, quadratic)
            _apply_scalar(out[body], rx, ry, fx, fy)


class AngularDampingTerm:
    """Torque -c omega."""

    uses_orientation = False
    couplings = NO_COUPLINGS

    def __init__(self, body: np.ndarray, coefficient: np.ndarray) -> None:
        self.body, self.coefficient = body, coefficient
        self.turns = np.unique(body)
        self._sum = BodySum(body)
        self._rows = list(zip(body.tolist(), coefficient.tolist()))

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        self._sum.subtract(out[2], self.coefficient * state.omega[self.body])

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for body, c in self._rows:
            out[body][2] -= c * state.v[body][2]


class WrenchRow(NamedTuple):
    """One wrench of a :class:`ConstantWrenchTerm`: a constant force or torque of the scene,
    or an input's applied wrench with its frame resolved (see that class for the frames)."""

    body: int  # the body it acts on
    force: tuple[float, float]
    torque: float
    axes_body: int  # the body whose axes the force is in; -1: the fixed frame's
    point_body: int  # the body whose CM the point is relative to; -1: the fixed frame
    point: tuple[float, float]
    at_point: bool  # False: at the CM of ``body``


def lever_arm(body: int, point_body: int, point: tuple[float, float],
              positions: np.ndarray | Sequence[Sequence[float]]) -> float:
    """At most the lever arm r a force at ``point`` has about ``body``'s CM (its torque,
    Eq. 11), from the bodies' ``positions`` (rows x, y, ...): exact for a point of the body
    itself or of the fixed frame (``point_body`` -1); for another body's point, whose
    orientation it does not read, the sum of the point's distance from that body's CM and
    of the CMs'."""
    px, py = point
    if point_body == body:
        return math.hypot(px, py)
    x, y = positions[body][0], positions[body][1]
    if point_body < 0:
        return math.hypot(px - x, py - y)
    return math.hypot(px, py) + math.hypot(positions[point_body][0] - x,
                                           positions[point_body][1] - y)


class ConstantWrenchTerm:
    """Constant wrenches: forces at the CM or at points, plus torques.

    It carries the scene's constant forces and torques and the applied wrenches of inputs,
    which are held constant over a step. The force's axes are the fixed frame's or a body's
    (``axes_body``; -1 = fixed frame), and so is its point (``point_body``; the point is
    relative to that body's CM, or in fixed-frame coordinates for -1). A row whose
    ``at_point`` is false acts at the target body's CM.
    """

    def __init__(self, body: np.ndarray, force: np.ndarray, torque: np.ndarray,
                 axes_body: np.ndarray, point_body: np.ndarray, point: np.ndarray,
                 at_point: np.ndarray) -> None:
        self.body, self.force, self.torque = body, force, torque
        self.axes_body, self.point_body, self.point, self.at_point = (
            axes_body, point_body, point, at_point)
        self._rows = list(zip(body.tolist(), force.tolist(), torque.tolist(), axes_body.tolist(),
                              point_body.tolist(), point.tolist(), at_point.tolist()))
        self.uses_orientation = any(axes >= 0 or (at and owner >= 0)
                                    for _, _, _, axes, owner, _, at in self._rows)

    def with_values(self, rows: Sequence[WrenchRow]) -> ConstantWrenchTerm:
        """The term :func:`~.model.wrench_term` builds from ``rows``, which differ from this
        term's only in their forces and torques (each row acts on the same body at the
        same point in the same axes, in the same order): the columns that do not hold the
        values are this term's, only the forces and torques are new."""
        term = ConstantWrenchTerm.__new__(ConstantWrenchTerm)
        term.body, term.axes_body, term.point_body, term.point, term.at_point = (
            self.body, self.axes_body, self.point_body, self.point, self.at_point)
        # As tolist() gives them: plain floats, each value as float64 rounds it.
        term._rows = [(body, [float(row.force[0]), float(row.force[1])], float(row.torque),
                       axes, owner, point, at_point)
                      for (body, _, _, axes, owner, point, at_point), row in zip(self._rows, rows)]
        term.uses_orientation = self.uses_orientation
        cached = term.__dict__
        for name in _PLACE_COLUMNS:
            if name in self.__dict__:  # the same for the new values
                cached[name] = self.__dict__[name]
        return term

    # The inputs make a new term whenever they change, and the kernel and the plain-float
    # sums read its rows only: the columns of the numpy sums are made when first needed.

    @functools.cached_property
    def force(self) -> np.ndarray:
        return np.array([row[1] for row in self._rows], dtype=float).reshape(-1, 2)

    @functools.cached_property
    def torque(self) -> np.ndarray:
        return np.array([row[2] for row in self._rows], dtype=float)

    @functools.cached_property
    def places(self) -> np.ndarray:
        """(body, axes_body, point_body, at_point) per wrench, int64: where each acts."""
        return np.array([(body, axes, owner, at) for body, _, _, axes, owner, _, at
                         in self._rows], dtype=np.int64).reshape(-1, 4)

    @functools.cached_property
    def rotated(self) -> np.ndarray:
        return self.axes_body >= 0

    @functools.cached_property
    def moving_point(self) -> np.ndarray:
        return self.at_point & (self.point_body >= 0)

    @functools.cached_property
    def turns(self) -> np.ndarray:
        return np.unique(self.body[self.at_point | (self.torque != 0.0)])

    @functools.cached_property
    def couplings(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.concatenate([self.axes_body[self.rotated], self.point_body[self.moving_point]]),
                np.concatenate([self.body[self.rotated], self.body[self.moving_point]]))

    @property
    def rows(self) -> list[tuple[Any, ...]]:
        """Each wrench as (body, force, torque, axes_body, point_body, point, at_point) in
        plain Python values."""
        return self._rows

    def add(self, state: Kinematics, out: np.ndarray) -> None:
        fx, fy = self._force_columns
        if self.rotated.any():
            axes = np.maximum(self.axes_body, 0)
            turned = state.offset(axes, fx, fy)
            fx, fy = np.where(self.rotated, turned[0], fx), np.where(self.rotated, turned[1], fy)
        torque = self.torque
        if self.at_point.any():
            px, py = self._point_columns
            if self.moving_point.any():
                owner = np.maximum(self.point_body, 0)
                ox, oy = state.offset(owner, px, py)
                px = np.where(self.moving_point, state.x[owner] + ox, px)
                py = np.where(self.moving_point, state.y[owner] + oy, py)
            rx = np.where(self.at_point, px - state.x[self.body], 0.0)
            ry = np.where(self.at_point, py - state.y[self.body], 0.0)
            torque = torque + rx * fy - ry * fx
        self._sums.add_wrench(out, fx, fy, torque)

    @functools.cached_property
    def _sums(self) -> BodySum:
        return BodySum(self.body)

    @functools.cached_property
    def _force_columns(self) -> tuple[np.ndarray, np.ndarray]:
        return _columns(self.force)

    @functools.cached_property
    def _point_columns(self) -> tuple[np.ndarray, np.ndarray]:
        return _columns(self.point)

    def add_scalar(self, state: ScalarKinematics, out: list[Wrench]) -> None:
        for body, (fx, fy), torque, axes, owner, (px, py), at_point in self._rows:
            if axes >= 0:
                fx, fy = state.offset(axes, fx, fy)
            wrench = out[body]
            wrench[2] += torque
            if not at_point:
                wrench[0] += fx
                wrench[1] += fy
                continue
            if owner >= 0:
                ox, oy = state.offset(owner, px, py)
                px, py = state.q[owner][0] + ox, state.q[owner][1] + oy
            x, y, _ = state.q[body]
            _apply_scalar(wrench, px - x, py - y, fx, fy)
