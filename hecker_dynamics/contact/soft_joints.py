"""Soft joints: the joints solved as Box2D v3 solves them (``joint_solver.type: soft``),
the cheap and inexact option beside :class:`~.joints.JointPass`'s exact projection.

Each step is taken in ``substeps`` equal sub-steps of semi-implicit Euler (the simulation
takes them, :meth:`~..dynamics.simulation.Simulation._constrained_step`); after each
sub-step's free step, which moved the bodies from (q0, v0) to (q1 = q0 + h v1, v1) under
the smooth forces alone, :meth:`SoftJointPass.resolve` does what Box2D v3's solver stages
do between its velocity and position integration (erincatto/box2d ``src/solver.c``):

1. *Warm start*: every row's impulse of the last sub-step, along its Jacobian at q0.
2. *Solve, with bias*: one sweep of sequential impulses over the rows at q0 (their
   Jacobians from the body point velocity v_P = v_CM + omega perp(r), Eq. 9; an impulse
   lambda changes the velocities by M^-1 J^T lambda: the force over the mass, F = m a of
   Eq. 5, and the torque perp(r) . P of Eq. 11 over inertia, Eq. 14), each
   rigid row soft: its position error C fed back as a velocity bias, a spring-damper of
   ``hertz`` and ``damping_ratio`` per unit effective mass integrated implicitly over the
   sub-step (b2MakeSoft: bias rate omega / (2 zeta + h omega), mass scale and impulse scale
   from h omega (2 zeta + h omega)). A pin's two rows are one 2 x 2 block, as Box2D's
   point constraint is, its velocity error and K = J M^-1 J^T taken straight from its
   arms (:func:`_pin_block`) as Box2D's revolute joint takes them, without the rows'
   directions: the sweeps' and the rows' cost is mostly pins.
3. *Integrate positions*: q1 moves by h times the velocity change of stages 1 and 2, so
   the positions move with the solved velocities, as they do in Box2D.
4. *Relax, without bias*: one sweep over the rows at the new q1 toward zero velocity
   (rigid rows with their whole effective mass, no bias), so the bias of stage 2 adds no
   kinetic energy to the step's end.

Limits are Box2D's: speculative while open (the joint may approach its limit by what
closes it within the sub-step), soft when passed; motors are clamped to their largest
effort times the sub-step; springs (a revolute spring, a soft weld) take their own
stiffness and damping in the same implicit form, in both sweeps. The impulses carry to the
next sub-step and step (Box2D's warm start). The rows are :class:`~.joints.JointPass`'s,
in its solve order (the joint graph's, never the names'), so every joint kind is solved,
and the efforts are the rows' impulses over the sub-step.

It is first order and holds the joints only as well as one sweep of sequential impulses
per sub-step does: a pin opens by millimetres on long chains, as Box2D v3's do
(docs/scenes.md has the measured gaps). The compiled kernel's ``src/kernel/soft_joint.c``
repeats :meth:`SoftJointPass.resolve` operation for operation, so both give the same bits.
"""
from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Optional

import numpy as np

from ..scene.joints import JointEnds, SoftJoints, softness
from .joint_rows import LIMIT, MOTOR, RIGID, SOFT, JointRow
from .joint_solve import Directions, directions, dot, rate
from .joints import JointPass
from .solver import MassRatioWarning

if TYPE_CHECKING:
    from ..scene.load import Scene

__all__ = ["SOFT_MASS_RATIO", "SoftJointPass", "softness"]


#: Masses a soft joint joins more than this many times apart: one sweep of sequential
#: impulses a sub-step leaves such a joint far open (a 20-link chain at h = 1/60 s whose
#: middle link is 10 times lighter than its neighbours: pins open 0.05 m; 100 times: 3 m;
#: 1e6 times: 123 m, the chain torn apart with no other sign), as Box2D v3's do.
SOFT_MASS_RATIO = 10.0


def _warn_mass_ratios(scene: Scene) -> None:
    """Warn, naming the joint whose two bodies' masses lie furthest apart, where they
    lie more than :data:`SOFT_MASS_RATIO` apart; the exact pass holds such joints."""
    mass = {body.name: float(body.mass.mass) for body in scene.bodies}
    ratio, name, heavy, light = 0.0, "", "", ""
    for joint in scene.joints:
        if isinstance(joint, JointEnds) and joint.body_a is not None:
            a, b = sorted((joint.body_a, joint.body_b), key=mass.__getitem__)
            if mass[b] / mass[a] > ratio:
                ratio, name, heavy, light = mass[b] / mass[a], joint.name, b, a
    if ratio > SOFT_MASS_RATIO:
        warnings.warn(
            f"joint '{name}': '{heavy}' ({mass[heavy]:g} kg) is {ratio:.3g} times as heavy as "
            f"'{light}' ({mass[light]:g} kg); soft joints between masses more than "
            f"{SOFT_MASS_RATIO:g} times apart open far (by metres at 100 times); "
            "joint_solver.type exact holds them (docs/scenes.md)", MassRatioWarning,
            stacklevel=2)


class SoftJointPass(JointPass):
    """The scene's joints, solved in soft sub-steps (see the module docstring)."""

    def __init__(self, scene: Scene, inverse_mass: np.ndarray, cm_local: np.ndarray,
                 compiled: bool = False) -> None:
        soft = scene.soft_joints
        assert soft is not None  # the scene asks for soft joints
        self.soft: SoftJoints = soft
        #: The sub-steps of a step, which the simulation takes (0: the exact pass's parts).
        self.substeps = soft.substeps
        #: The last sub-step's end pose, its rows and their directions there: the next
        #: sub-step's start and rows, unless something moved the bodies in between or the
        #: sub-step's length changed (the kernel's keeps them likewise, m->ended).
        self._end: Optional[tuple[list[float], list[JointRow], Directions]] = None
        #: Per row, whether it begins a pin's two rows (x, then y, rigid): one 2 x 2 block.
        self.pairs: list[bool] = []
        super().__init__(scene, inverse_mass, cm_local, compiled)
        _warn_mass_ratios(scene)

    def reset(self, q: Optional[np.ndarray] = None) -> None:
        super().reset(q)
        self.pairs = [kind == RIGID and part == "x" for (_, part), kind in
                      zip(self.keys, self.kinds)]
        #: Per row, whether it is one of a pin's two rows, which need no directions.
        self.in_pins = [pair or (i > 0 and self.pairs[i - 1]) for i, pair in
                        enumerate(self.pairs)]

    def forget(self) -> None:
        super().forget()
        self._end = None

    def restore(self, warm: list[float], newton: Optional[list[float]], step_h: float) -> None:
        """Take the kernel's state; the kernel moved the bodies since :attr:`_end`."""
        super().restore(warm, newton, step_h)
        self._end = None

    def resolve(self, q0: np.ndarray, q1: np.ndarray, v1: np.ndarray, h: float) -> None:
        """One sub-step of length ``h`` from ``q0`` to (``q1``, ``v1``), after its free
        semi-implicit Euler step; updates ``q1`` and ``v1`` (all bodies) in place."""
        if self._initial is None:
            self.reset(q0)
        if self._compiled:
            self._in_kernel().resolve(q0, q1, v1, h)  # its restore drops _end
            return
        index = self.bodies
        start = q0[index].reshape(-1).tolist()
        end = self._end
        if end is not None and end[0] == start and h == self.step_h:
            rows, towards = end[1], end[2]
        else:
            rows = self.rows(start, h)
            towards = directions(rows, self.inverse_mass, self.in_pins)
        q = q1[index].reshape(-1).tolist()
        v = v1[index].reshape(-1).tolist()
        free = list(v)
        self._warm_start(rows, towards, v)
        self._sweep(rows, towards, v, h, softness(self.soft.hertz, self.soft.damping_ratio, h))
        for k in range(len(q)):  # stage 3
            q[k] += h * (v[k] - free[k])
        rows = self.rows(q, h)
        towards = directions(rows, self.inverse_mass, self.in_pins)
        self._sweep(rows, towards, v, h, None)
        self._end = (q, rows, towards)
        self.step_h = h
        self._set_efforts()
        self._count_turns(q)
        q1[index] = np.array(q).reshape(-1, 3)
        v1[index] = np.array(v).reshape(-1, 3)

    def _warm_start(self, rows: list[JointRow], towards: Directions, v: list[float]) -> None:
        """Stage 1: every row's impulse of the last sub-step (:attr:`warm`) on ``v``, along
        its Jacobian at q0."""
        lam, pairs = self.warm, self.pairs
        i, n = 0, len(rows)
        while i < n:
            if pairs[i]:
                _push_pin(v, rows[i], rows[i + 1], lam[i], lam[i + 1], self.inverse_mass)
                i += 2
            else:
                _push(v, towards[i], lam[i])
                i += 1

    def _sweep(self, rows: list[JointRow], towards: Directions, v: list[float], h: float,
               soft: Optional[tuple[float, float, float]]) -> None:
        """One sweep of sequential impulses over ``rows`` (with their directions M^-1 J^T
        ``towards``; a pin's block takes its masses itself) on the velocities ``v``,
        adding to the impulses :attr:`warm`; with the ``soft`` (bias rate, mass scale,
        impulse scale) of stage 2, or None: stage 4."""
        lam, pairs, inverse = self.warm, self.pairs, self.inverse_mass
        i, n = 0, len(rows)
        while i < n:
            row = rows[i]
            if pairs[i]:  # a pin's x and y rows: Box2D's 2 x 2 point block
                other = rows[i + 1]
                bx, by, k11, k12, k22 = _pin_block(row, other, v, inverse)
                scale, keep = 1.0, 0.0
                if soft is not None:
                    bx += soft[0] * row.c
                    by += soft[0] * other.c
                    scale, keep = soft[1], soft[2]
                det = k11 * k22 - k12 * k12
                det = 1.0 / det if det != 0.0 else det
                sx, sy = det * (k22 * bx - k12 * by), det * (k11 * by - k12 * bx)
                ix = -scale * sx - keep * lam[i]
                iy = -scale * sy - keep * lam[i + 1]
                lam[i] += ix
                lam[i + 1] += iy
                _push_pin(v, row, other, ix, iy, inverse)
                i += 2
                continue
            diagonal = dot(row, towards[i])
            mass = 1.0 / diagonal if diagonal > 0.0 else 0.0
            velocity = rate(row, v)
            old = lam[i]
            if row.kind == SOFT:  # the row's own spring, in both sweeps
                stiffness, damping = row.stiffness, row.damping
                compliance = h * (damping + h * stiffness)
                a2 = compliance if row.scaled else compliance * diagonal
                bias = stiffness / (damping + h * stiffness) if compliance > 0.0 else 0.0
                new = old - a2 / (1.0 + a2) * mass * (velocity + bias * row.c) - old / (1.0 + a2)
            elif row.kind == MOTOR:
                new = min(max(old - mass * (velocity - row.speed), -row.bound), row.bound)
            else:  # rigid or a limit
                bias, scale, keep = 0.0, 1.0, 0.0
                if row.kind == LIMIT and row.c > 0.0:  # open: speculative
                    bias = row.c / h
                elif soft is not None:
                    bias, scale, keep = soft[0] * row.c, soft[1], soft[2]
                new = old - scale * mass * (velocity + bias) - keep * old
                if row.kind == LIMIT:
                    new = max(new, 0.0)
            lam[i] = new
            _push(v, towards[i], new - old)
            i += 1


def _push(v: list[float], entries: list[tuple[int, float, float, float]], amount: float) -> None:
    """v += M^-1 J^T amount for one row's direction ``entries``."""
    for b, dx, dy, dw in entries:
        v[3 * b] += dx * amount
        v[3 * b + 1] += dy * amount
        v[3 * b + 2] += dw * amount


def _pin_block(x_row: JointRow, y_row: JointRow, v: list[float], inverse_mass: list[float]
               ) -> tuple[float, float, float, float, float]:
    """A pin's velocity error J v (its x and y rows) and the entries k11, k12, k22 of its
    K = J M^-1 J^T, read off the rows' Jacobians without their directions: (1, 0, p) and
    (0, 1, q) on body B, (-1, 0, p') and (0, -1, q') on body A, where (p, q) = perp(r) of
    the body point velocity v_P = v_CM + omega perp(r) (Eq. 9) for the arm r to the pin.
    Box2D v3's point block (revolute_joint.c), its K from the arms each time."""
    b, _, _, p = x_row.entries[0]
    q = y_row.entries[0][3]
    w = v[3 * b + 2]
    bx, by = v[3 * b] + p * w, v[3 * b + 1] + q * w
    turn = inverse_mass[3 * b + 2]
    k11 = inverse_mass[3 * b] + p * (turn * p)
    k12 = p * (turn * q)
    k22 = inverse_mass[3 * b + 1] + q * (turn * q)
    if len(x_row.entries) > 1:
        a, _, _, p = x_row.entries[1]
        q = y_row.entries[1][3]
        w = v[3 * a + 2]
        bx += p * w - v[3 * a]
        by += q * w - v[3 * a + 1]
        turn = inverse_mass[3 * a + 2]
        k11 += inverse_mass[3 * a] + p * (turn * p)
        k12 += p * (turn * q)
        k22 += inverse_mass[3 * a + 1] + q * (turn * q)
    return bx, by, k11, k12, k22


def _push_pin(v: list[float], x_row: JointRow, y_row: JointRow, ix: float, iy: float,
              inverse_mass: list[float]) -> None:
    """v += M^-1 J^T (ix, iy) for a pin's x and y rows (their Jacobians as
    :func:`_pin_block` reads them): the force over the mass (Eq. 5), the torque of the
    impulse at its arm (Eq. 11) and the angular acceleration, torque over I (Eq. 14)."""
    b, _, _, p = x_row.entries[0]
    q = y_row.entries[0][3]
    v[3 * b] += inverse_mass[3 * b] * ix
    v[3 * b + 1] += inverse_mass[3 * b + 1] * iy
    v[3 * b + 2] += inverse_mass[3 * b + 2] * (p * ix + q * iy)
    if len(x_row.entries) > 1:
        a, _, _, p = x_row.entries[1]
        q = y_row.entries[1][3]
        v[3 * a] -= inverse_mass[3 * a] * ix
        v[3 * a + 1] -= inverse_mass[3 * a + 1] * iy
        v[3 * a + 2] += inverse_mass[3 * a + 2] * (p * ix + q * iy)
