"""The scenes' force law in plain Python on plain floats, for the peers and the references.

A peer engine's user writes the forces its engine does not have (springs, drags, angular
damping, constant forces) and the scripted wrenches in Python, reading plain floats off
the bodies; :func:`make_wrenches` is that loop for any scene, from the force terms as
:class:`~.reference.PlainModel` lists them. :func:`scripted_wrench` is one scripted
command's wrench, and :func:`line_of_action` the point where a force alone carries a
wrench's torque (one call of a peer's API instead of a force and a torque).

Only the standard library: the Box2D v3 worker (:mod:`.box2d_v3_worker`) loads this file
by its path in another interpreter, where this package is not installed.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Optional

__all__ = ["line_of_action", "make_wrenches", "scripted_wrench"]

#: A body's CM state as plain floats: x, y, angle, vx, vy, omega.
State = Sequence[float]
#: Force (fx, fy) and torque about the CM of every body.
Wrenches = list[list[float]]


def make_wrenches(springs: Sequence, drags: Sequence, angular: Sequence, forces: Sequence,
                  constant: Sequence) -> Callable[[Sequence[State]], Wrenches]:
    """wrenches(states): force and torque about the CM on every body from each body's CM
    state (a body point's velocity by Eq. 9, a force's torque about the CM by Eq. 11).

    The terms: ``springs`` (a, local_a, b or -1, local_b or the fixed anchor, k, rest
    length, damping), ``drags`` (body, local point or None, coefficient, quadratic),
    ``angular`` (body, coefficient), ``forces`` (body, fx, fy, in body axes, local point or
    None) and ``constant`` (fx, fy, torque per body); points are in the CM frames."""
    constant = [tuple(c) for c in constant]

    def wrenches(states: Sequence[State]) -> Wrenches:
        total = [list(c) for c in constant]
        cs = [(math.cos(state[2]), math.sin(state[2])) for state in states]

        def point(i: int, local: Sequence[float]) -> tuple[float, ...]:
            c, s = cs[i]
            x, y, _, vx, vy, w = states[i]
            rx, ry = c * local[0] - s * local[1], s * local[0] + c * local[1]
            return rx, ry, x + rx, y + ry, vx - w * ry, vy + w * rx

        def apply(i: int, rx: float, ry: float, fx: float, fy: float) -> None:
            wrench = total[i]
            wrench[0] += fx
            wrench[1] += fy
            wrench[2] += rx * fy - ry * fx

        for a, la, b, lb, k, rest, damp in springs:
            rax, ray, pax, pay, vax, vay = point(a, la)
            if b < 0:
                rbx = rby = vbx = vby = 0.0
                pbx, pby = lb
            else:
                rbx, rby, pbx, pby, vbx, vby = point(b, lb)
            dx, dy, dvx, dvy = pax - pbx, pay - pby, vax - vbx, vay - vby
            if rest == 0.0:
                fx, fy = -k * dx - damp * dvx, -k * dy - damp * dvy
            else:
                length = math.hypot(dx, dy)
                ux, uy = dx / length, dy / length
                mag = -(k * (length - rest) + damp * (dvx * ux + dvy * uy))
                fx, fy = mag * ux, mag * uy
            apply(a, rax, ray, fx, fy)
            if b >= 0:
                apply(b, rbx, rby, -fx, -fy)
        for i, local, coef, quadratic in drags:
            if local is None:
                rx = ry = 0.0
                vx, vy = states[i][3], states[i][4]
            else:
                rx, ry, _, _, vx, vy = point(i, local)
            scale = coef * (math.hypot(vx, vy) if quadratic else 1.0)
            apply(i, rx, ry, -scale * vx, -scale * vy)
        for i, coef in angular:
            total[i][2] -= coef * states[i][5]
        for i, fx, fy, body_axes, local in forces:
            c, s = cs[i]
            if body_axes:
                fx, fy = c * fx - s * fy, s * fx + c * fy
            rx, ry = (0.0, 0.0) if local is None else (c * local[0] - s * local[1],
                                                       s * local[0] + c * local[1])
            apply(i, rx, ry, fx, fy)
        return total

    return wrenches


def scripted_wrench(body: int, frame: int, point: Sequence[float], force: Sequence[float],
                    torque: float) -> Callable[[Sequence[State]], tuple[float, float, float]]:
    """wrench(states): the force and torque about ``body``'s CM of a command whose
    ``point`` and ``force`` are in the axes of body ``frame`` (``point`` in its CM frame)
    or, for ``frame`` -1, in the fixed frame."""
    px, py = point
    fx, fy = force

    if frame < 0:
        def world(states: Sequence[State]) -> tuple[float, float, float]:
            rx, ry = px - states[body][0], py - states[body][1]
            return fx, fy, rx * fy - ry * fx + torque
        return world

    def in_body(states: Sequence[State]) -> tuple[float, float, float]:
        x, y, a = states[frame][:3]
        c, s = math.cos(a), math.sin(a)
        wx, wy = c * fx - s * fy, s * fx + c * fy
        ax, ay = x + c * px - s * py, y + s * px + c * py
        return wx, wy, (ax - states[body][0]) * wy - (ay - states[body][1]) * wx + torque
    return in_body


def line_of_action(state: State, fx: float, fy: float,
                   tau: float) -> Optional[tuple[float, float]]:
    """A world point where the force (fx, fy) alone has the torque ``tau`` about the CM of
    the body in ``state``, or None for a zero force."""
    square = fx * fx + fy * fy
    if not square:
        return None
    scale = tau / square  # r = tau (fy, -fx) / |F|^2, so r x F = tau
    return state[0] + scale * fy, state[1] - scale * fx
