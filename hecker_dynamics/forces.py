"""Force terms: each turns the state into generalised forces (Fx, Fy, torque) per body.

This is steps 3 to 5 of the article's algorithm ("Physics, Part 2: Angular Effects"):
every force has a point of application; the forces add up at the CM (Equation 4, F = M a)
and each contributes the torque perp-dot(r, F) about the CM, with r the offset from the CM
to the point (Equation 6). A body point's velocity is v_P = v_CM + omega perp(r)
(Equation 7), which springs and drag at points use.

A term exists only if the scene declares such a force, and one applied at the CM never
touches the torque. Each term evaluates in two ways that tests hold equal to rounding:

- ``add``: vectorised over all its instances with numpy, for scenes of many bodies;
- ``add_scalar``: plain Python floats, for the few-body scenes ROS users mostly run, where
  numpy's cost per call (about a microsecond) would outweigh the arithmetic.

State layout: ``q[i] = (x_CM, y_CM, angle)`` and ``v[i] = (vx_CM, vy_CM, omega)``. Body
points are stored as offsets from the CM in body axes; :class:`Pose` and
:class:`ScalarPose` rotate them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .planar import perp, perp_dot, rotate

Wrench = list[float]  # [Fx, Fy, torque] of one body, accumulated in place


@dataclass
class Pose:
    """Per-evaluation cache of the bodies' orientations (cos and sin of each angle)."""

    q: np.ndarray
    v: np.ndarray
    cos: np.ndarray
    sin: np.ndarray

    @classmethod
    def of(cls, q: np.ndarray, v: np.ndarray) -> Pose:
        return cls(q, v, np.cos(q[:, 2]), np.sin(q[:, 2]))

    def offset(self, body: np.ndarray, local: np.ndarray) -> np.ndarray:
        """World offsets r = R(angle) local of points given relative to each body's CM."""
        return rotate(local, self.cos[body], self.sin[body])

    def point_velocity(self, body: np.ndarray, r: np.ndarray) -> np.ndarray:
        """v_P = v_CM + omega perp(r) (article Equation 7)."""
        return self.v[body, :2] + self.v[body, 2:3] * perp(r)


@dataclass
class ScalarPose:
    """The same as :class:`Pose`, as Python lists of floats."""

    q: list[list[float]]
    v: list[list[float]]
    cos: list[float]
    sin: list[float]

    @classmethod
    def of(cls, q: list[list[float]], v: list[list[float]], oriented: bool) -> ScalarPose:
        if not oriented:
            return cls(q, v, [], [])
        return cls(q, v, [math.cos(b[2]) for b in q], [math.sin(b[2]) for b in q])

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
    #: Bodies the term can turn (it applies torque to them).
    turns: np.ndarray

    def add(self, pose: Pose, out: np.ndarray) -> None:
        """Add to ``out`` (N, 3), vectorised."""

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        """Add to ``out`` (a [Fx, Fy, torque] list per body), in plain floats."""


def _scatter(out: np.ndarray, body: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """Add per-instance forces and torques to their bodies (bodies may repeat)."""
    n = len(out)
    out[:, 0] += np.bincount(body, force[:, 0], minlength=n)
    out[:, 1] += np.bincount(body, force[:, 1], minlength=n)
    out[:, 2] += np.bincount(body, torque, minlength=n)


def _apply_scalar(wrench: Wrench, rx: float, ry: float, fx: float, fy: float) -> None:
    """Add force (fx, fy) at offset (rx, ry) from the CM: the force and perp-dot torque."""
    wrench[0] += fx
    wrench[1] += fy
    wrench[2] += rx * fy - ry * fx


class GravityTerm:
    """m g at the CM of each body: no torque (article: gravity acts at the CM)."""

    uses_orientation = False

    def __init__(self, bodies: np.ndarray, weights: np.ndarray) -> None:
        self.bodies = bodies
        self.weights = weights  # (k, 2) = m g per body
        self.turns = np.zeros(0, dtype=int)
        self._rows = list(zip(bodies.tolist(), weights.tolist()))

    def add(self, pose: Pose, out: np.ndarray) -> None:
        out[self.bodies, :2] += self.weights

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for body, (wx, wy) in self._rows:
            wrench = out[body]
            wrench[0] += wx
            wrench[1] += wy

    def potential(self, q: np.ndarray) -> float:
        return -float(np.sum(self.weights * q[self.bodies, :2]))


def spring_force(d: np.ndarray, dv: np.ndarray, stiffness: np.ndarray,
                 rest_length: np.ndarray, damping: np.ndarray) -> np.ndarray:
    """Force on end A of damped springs, with d = p_A - p_B and dv = v_A - v_B.

    With a rest length, Hooke's law and a dashpot act along the spring:
    F = -(k (|d| - L0) + c (dv . u)) u with u = d / |d|. A zero-rest-length spring is the
    linear law F = -k d - c dv, defined even when both ends meet.
    """
    length = np.hypot(d[:, 0], d[:, 1])
    zero_rest = rest_length == 0.0
    safe = np.where(length > 0.0, length, 1.0)
    u = d / safe[:, None] * (length > 0.0)[:, None]
    along = -(stiffness * (length - rest_length) + damping * np.sum(dv * u, axis=1))
    linear = -stiffness[:, None] * d - damping[:, None] * dv
    return np.where(zero_rest[:, None], linear, along[:, None] * u)


def spring_force_scalar(dx: float, dy: float, dvx: float, dvy: float, stiffness: float,
                        rest_length: float, damping: float) -> tuple[float, float]:
    """:func:`spring_force` for one spring, in plain floats."""
    if rest_length == 0.0:
        return -stiffness * dx - damping * dvx, -stiffness * dy - damping * dvy
    length = math.hypot(dx, dy)
    if length == 0.0:
        return 0.0, 0.0
    ux, uy = dx / length, dy / length
    along = -(stiffness * (length - rest_length) + damping * (dvx * ux + dvy * uy))
    return along * ux, along * uy


def spring_energy(d: np.ndarray, stiffness: np.ndarray, rest_length: np.ndarray) -> float:
    length = np.hypot(d[:, 0], d[:, 1])
    return float(np.sum(0.5 * stiffness * (length - rest_length) ** 2))


class AnchorSpringTerm:
    """Damped springs from body points to fixed anchors."""

    uses_orientation = True

    def __init__(self, body: np.ndarray, local: np.ndarray, anchor: np.ndarray,
                 stiffness: np.ndarray, rest_length: np.ndarray, damping: np.ndarray) -> None:
        self.body, self.local, self.anchor = body, local, anchor
        self.stiffness, self.rest_length, self.damping = stiffness, rest_length, damping
        self.turns = np.unique(body[np.any(local != 0.0, axis=1)])
        self._rows = list(zip(body.tolist(), local.tolist(), anchor.tolist(), stiffness.tolist(),
                              rest_length.tolist(), damping.tolist()))

    def add(self, pose: Pose, out: np.ndarray) -> None:
        r = pose.offset(self.body, self.local)
        d = pose.q[self.body, :2] + r - self.anchor
        force = spring_force(d, pose.point_velocity(self.body, r), self.stiffness,
                             self.rest_length, self.damping)
        _scatter(out, self.body, force, perp_dot(r, force))

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for body, (lx, ly), (ax, ay), k, rest, c in self._rows:
            rx, ry = pose.offset(body, lx, ly)
            x, y, _ = pose.q[body]
            fx, fy = spring_force_scalar(x + rx - ax, y + ry - ay,
                                         *pose.point_velocity(body, rx, ry), k, rest, c)
            _apply_scalar(out[body], rx, ry, fx, fy)

    def potential(self, q: np.ndarray) -> float:
        pose = Pose.of(q, np.zeros_like(q))
        d = q[self.body, :2] + pose.offset(self.body, self.local) - self.anchor
        return spring_energy(d, self.stiffness, self.rest_length)


class BodySpringTerm:
    """Damped springs between points of two bodies (equal and opposite forces)."""

    uses_orientation = True

    def __init__(self, body_a: np.ndarray, local_a: np.ndarray, body_b: np.ndarray,
                 local_b: np.ndarray, stiffness: np.ndarray, rest_length: np.ndarray,
                 damping: np.ndarray) -> None:
        self.body_a, self.local_a, self.body_b, self.local_b = body_a, local_a, body_b, local_b
        self.stiffness, self.rest_length, self.damping = stiffness, rest_length, damping
        self.turns = np.unique(np.concatenate([body_a[np.any(local_a != 0.0, axis=1)],
                                               body_b[np.any(local_b != 0.0, axis=1)]]))
        self._both = np.concatenate([body_a, body_b])
        self._rows = list(zip(body_a.tolist(), local_a.tolist(), body_b.tolist(),
                              local_b.tolist(), stiffness.tolist(), rest_length.tolist(),
                              damping.tolist()))

    def _ends(self, pose: Pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r_a = pose.offset(self.body_a, self.local_a)
        r_b = pose.offset(self.body_b, self.local_b)
        d = pose.q[self.body_a, :2] + r_a - pose.q[self.body_b, :2] - r_b
        return r_a, r_b, d

    def add(self, pose: Pose, out: np.ndarray) -> None:
        r_a, r_b, d = self._ends(pose)
        dv = pose.point_velocity(self.body_a, r_a) - pose.point_velocity(self.body_b, r_b)
        force = spring_force(d, dv, self.stiffness, self.rest_length, self.damping)
        _scatter(out, self._both, np.concatenate([force, -force]),
                 np.concatenate([perp_dot(r_a, force), -perp_dot(r_b, force)]))

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for a, (lax, lay), b, (lbx, lby), k, rest, c in self._rows:
            rax, ray = pose.offset(a, lax, lay)
            rbx, rby = pose.offset(b, lbx, lby)
            xa, ya, _ = pose.q[a]
            xb, yb, _ = pose.q[b]
            vax, vay = pose.point_velocity(a, rax, ray)
            vbx, vby = pose.point_velocity(b, rbx, rby)
            fx, fy = spring_force_scalar(xa + rax - xb - rbx, ya + ray - yb - rby,
                                         vax - vbx, vay - vby, k, rest, c)
            _apply_scalar(out[a], rax, ray, fx, fy)
            _apply_scalar(out[b], rbx, rby, -fx, -fy)

    def potential(self, q: np.ndarray) -> float:
        _, _, d = self._ends(Pose.of(q, np.zeros_like(q)))
        return spring_energy(d, self.stiffness, self.rest_length)


def drag_force(velocity: np.ndarray, coefficient: np.ndarray, quadratic: np.ndarray) -> np.ndarray:
    """-c v (linear) or -c |v| v (quadratic), per row."""
    speed = np.where(quadratic, np.hypot(velocity[:, 0], velocity[:, 1]), 1.0)
    return -(coefficient * speed)[:, None] * velocity


def drag_force_scalar(vx: float, vy: float, coefficient: float,
                      quadratic: bool) -> tuple[float, float]:
    """:func:`drag_force` for one point, in plain floats."""
    scale = coefficient * math.hypot(vx, vy) if quadratic else coefficient
    return -scale * vx, -scale * vy


class CentreDragTerm:
    """Linear or quadratic drag at the CM: no torque."""

    uses_orientation = False

    def __init__(self, body: np.ndarray, coefficient: np.ndarray, quadratic: np.ndarray) -> None:
        self.body, self.coefficient, self.quadratic = body, coefficient, quadratic
        self.turns = np.zeros(0, dtype=int)
        self._rows = list(zip(body.tolist(), coefficient.tolist(), quadratic.tolist()))

    def add(self, pose: Pose, out: np.ndarray) -> None:
        force = drag_force(pose.v[self.body, :2], self.coefficient, self.quadratic)
        _scatter(out, self.body, force, np.zeros(len(self.body)))

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for body, c, quadratic in self._rows:
            vx, vy, _ = pose.v[body]
            fx, fy = drag_force_scalar(vx, vy, c, quadratic)
            out[body][0] += fx
            out[body][1] += fy


class PointDragTerm:
    """Linear or quadratic drag at body points, using the point velocity v_P."""

    uses_orientation = True

    def __init__(self, body: np.ndarray, local: np.ndarray, coefficient: np.ndarray,
                 quadratic: np.ndarray) -> None:
        self.body, self.local = body, local
        self.coefficient, self.quadratic = coefficient, quadratic
        self.turns = np.unique(body)
        self._rows = list(zip(body.tolist(), local.tolist(), coefficient.tolist(),
                              quadratic.tolist()))

    def add(self, pose: Pose, out: np.ndarray) -> None:
        r = pose.offset(self.body, self.local)
        force = drag_force(pose.point_velocity(self.body, r), self.coefficient, self.quadratic)
        _scatter(out, self.body, force, perp_dot(r, force))

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for body, (lx, ly), c, quadratic in self._rows:
            rx, ry = pose.offset(body, lx, ly)
            fx, fy = drag_force_scalar(*pose.point_velocity(body, rx, ry), c, quadratic)
            _apply_scalar(out[body], rx, ry, fx, fy)


class AngularDampingTerm:
    """Torque -c omega."""

    uses_orientation = False

    def __init__(self, body: np.ndarray, coefficient: np.ndarray) -> None:
        self.body, self.coefficient = body, coefficient
        self.turns = np.unique(body)
        self._rows = list(zip(body.tolist(), coefficient.tolist()))

    def add(self, pose: Pose, out: np.ndarray) -> None:
        out[:, 2] += np.bincount(self.body, -self.coefficient * pose.v[self.body, 2],
                                 minlength=len(out))

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for body, c in self._rows:
            out[body][2] -= c * pose.v[body][2]


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
        self.rotated = axes_body >= 0
        self.moving_point = at_point & (point_body >= 0)
        self.uses_orientation = bool(self.rotated.any() or self.moving_point.any())
        self.turns = np.unique(body[at_point | (torque != 0.0)])
        self._rows = list(zip(body.tolist(), force.tolist(), torque.tolist(), axes_body.tolist(),
                              point_body.tolist(), point.tolist(), at_point.tolist()))

    def add(self, pose: Pose, out: np.ndarray) -> None:
        force = self.force
        if self.rotated.any():
            axes = np.maximum(self.axes_body, 0)
            force = np.where(self.rotated[:, None],
                             rotate(force, pose.cos[axes], pose.sin[axes]), force)
        torque = self.torque
        if self.at_point.any():
            point = self.point
            if self.moving_point.any():
                owner = np.maximum(self.point_body, 0)
                point = np.where(self.moving_point[:, None],
                                 pose.q[owner, :2] + pose.offset(owner, point), point)
            r = np.where(self.at_point[:, None], point - pose.q[self.body, :2], 0.0)
            torque = torque + perp_dot(r, force)
        _scatter(out, self.body, force, torque)

    def add_scalar(self, pose: ScalarPose, out: list[Wrench]) -> None:
        for body, (fx, fy), torque, axes, owner, (px, py), at_point in self._rows:
            if axes >= 0:
                fx, fy = pose.offset(axes, fx, fy)
            wrench = out[body]
            wrench[2] += torque
            if not at_point:
                wrench[0] += fx
                wrench[1] += fy
                continue
            if owner >= 0:
                ox, oy = pose.offset(owner, px, py)
                px, py = pose.q[owner][0] + ox, pose.q[owner][1] + oy
            x, y, _ = pose.q[body]
            _apply_scalar(wrench, px - x, py - y, fx, fy)
