"""The scenes' force law in plain Python on plain floats, for the peers and the references.

A peer engine's user writes the forces its engine does not have (springs, drags, angular
damping, constant forces) and the scripted wrenches in Python. :func:`make_program` is
that loop as lean as we found it (docs/benchmark.md, "The peers' Python force loops"): one
closure per force term, with the peer's own calls for a body point and its velocity and
for a force at a point bound once (:class:`BodyCalls`), so a step makes only the calls
its terms need. :func:`make_wrenches` is the same law on states read off the bodies (the
references use it, from the force terms as :class:`~.reference.PlainModel` lists them).
:func:`scripted_wrench` is one scripted command's wrench, and :func:`line_of_action` the
point where a force alone carries a wrench's torque (one call of a peer's API instead of a
force and a torque).

Only the standard library: the Box2D v3 worker (:mod:`.box2d_v3_worker`) loads this file
by its path in another interpreter, where this package is not installed.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, Optional

__all__ = ["BodyCalls", "line_of_action", "make_program", "make_stepper", "make_wrenches",
           "scripted_wrench"]

#: A body's CM state as plain floats: x, y, angle, vx, vy, omega.
State = Sequence[float]
#: Force (fx, fy) and torque about the CM of every body.
Wrenches = list[list[float]]
#: One force term's fields, as :func:`make_wrenches` lists them per kind.
Terms = Sequence[Sequence[Any]]


def make_wrenches(springs: Terms, drags: Terms, angular: Terms, forces: Terms,
                  constant: Sequence[Sequence[float]]) -> Callable[[Sequence[State]], Wrenches]:
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


class BodyCalls(NamedTuple):
    """A peer body's calls, bound once: ``point(local)`` the world point of a point of the
    CM frame, ``point_velocity(world)`` the body point's velocity at a world point (Eq. 9),
    ``push(force, world)`` a force at a world point (the peer adds its torque about the CM,
    Eq. 11), ``state()`` (x, y, angle, vx, vy, omega) of the CM, ``push_torque(tau)``."""

    point: Callable[[Sequence[float]], Sequence[float]]
    point_velocity: Callable[[Sequence[float]], Sequence[float]]
    push: Callable[[Sequence[float], Sequence[float]], object]
    state: Callable[[], State]
    push_torque: Callable[[float], object]


def _spring(calls: Sequence[BodyCalls], a: int, la: Sequence[float], b: int,
            lb: Sequence[float], k: float, rest: float, damp: float) -> Callable[[], None]:
    """A spring between a point of body ``a`` and one of body ``b`` (or the fixed point
    ``lb`` for ``b`` -1): the force along the line joining them, pushed at both ends."""
    hypot = math.hypot
    point_a, velocity_a, push_a = calls[a].point, calls[a].point_velocity, calls[a].push
    if b < 0:
        bx, by = lb

        def anchored() -> None:
            pa = point_a(la)
            va = velocity_a(pa)
            dx, dy = pa[0] - bx, pa[1] - by
            if rest == 0.0:
                push_a((-k * dx - damp * va[0], -k * dy - damp * va[1]), pa)
                return
            length = hypot(dx, dy)
            ux, uy = dx / length, dy / length
            mag = -(k * (length - rest) + damp * (va[0] * ux + va[1] * uy))
            push_a((mag * ux, mag * uy), pa)
        return anchored
    point_b, velocity_b, push_b = calls[b].point, calls[b].point_velocity, calls[b].push

    def between() -> None:
        pa, pb = point_a(la), point_b(lb)
        va, vb = velocity_a(pa), velocity_b(pb)
        dx, dy = pa[0] - pb[0], pa[1] - pb[1]
        dvx, dvy = va[0] - vb[0], va[1] - vb[1]
        if rest == 0.0:
            fx, fy = -k * dx - damp * dvx, -k * dy - damp * dvy
        else:
            length = hypot(dx, dy)
            ux, uy = dx / length, dy / length
            mag = -(k * (length - rest) + damp * (dvx * ux + dvy * uy))
            fx, fy = mag * ux, mag * uy
        push_a((fx, fy), pa)
        push_b((-fx, -fy), pb)
    return between


def _body_terms(calls: BodyCalls, drags: Terms, angular: Terms, forces: Terms,
                constant: Sequence[float]) -> Callable[[], None]:
    """The terms that act on one body alone (drags, angular damping, constant forces and
    wrenches) as one force along its line of action and, without a force, a torque."""
    wrench = make_wrenches((), [(0, *d[1:]) for d in drags], [(0, *a[1:]) for a in angular],
                           [(0, *f[1:]) for f in forces], [constant])
    state, push, push_torque = calls.state, calls.push, calls.push_torque

    def alone() -> None:
        now = state()
        (fx, fy, tau), = wrench([now])
        point = line_of_action(now, fx, fy, tau)
        if point is not None:
            push((fx, fy), point)
        elif tau:
            push_torque(tau)
    return alone


def make_program(springs: Terms, drags: Terms, angular: Terms, forces: Terms,
                 constant: Sequence[Sequence[float]],
                 calls: Sequence[BodyCalls]) -> Optional[Callable[[], None]]:
    """apply(): the force terms (as :func:`make_wrenches` takes them) pushed onto the peer's
    bodies through their ``calls``, from their state now; None where there are none."""
    terms = [_spring(calls, *spring) for spring in springs]
    for i, body in enumerate(calls):
        mine_drags, mine_angular, mine_forces = (
            [t for t in kind if t[0] == i] for kind in (drags, angular, forces))
        if mine_drags or mine_angular or mine_forces or any(constant[i]):
            terms.append(_body_terms(body, mine_drags, mine_angular, mine_forces, constant[i]))
    if not terms:
        return None
    if len(terms) == 1:
        return terms[0]

    def apply() -> None:
        for term in terms:
            term()
    return apply


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


def make_stepper(program: Optional[Callable[[], None]], script: Terms,
                 calls: Sequence[BodyCalls], wake: Callable[[int], object],
                 advance: Callable[[], object], h_ns: int) -> Callable[[int], float]:
    """step(count) -> the seconds its steps took: before each step the ``program``'s
    forces and the wrenches of the scripted commands acting then go on the bodies, then
    ``advance()`` takes the peer's step. ``script``: (body, start ns, end ns, frame body or
    -1, point, force, torque) per command (:func:`scripted_wrench`); a pushed body is woken
    (``wake(body)``) before any force of that step goes on it. With neither forces nor a
    script (a pyramid), the loop is the peer's own steps and nothing else, as its users
    write it."""
    if program is None and not script:
        def bare(count: int) -> float:
            start = time.perf_counter()
            for _ in range(count):
                advance()
            return time.perf_counter() - start

        return bare
    spans = [(-(-start // h_ns), -(-end // h_ns), body, (body, frame) if frame >= 0 else (body,),
              scripted_wrench(body, frame, point, force, torque))
             for body, start, end, frame, point, force, torque in script]
    changes = sorted({n for first, last, *_ in spans for n in (first, last)})
    active: list[tuple[Any, ...]] = []
    done = [0]

    def push_scripted() -> None:
        for i, read, wrench in active:
            states = {j: calls[j].state() for j in read}
            fx, fy, tau = wrench(states)
            point = line_of_action(states[i], fx, fy, tau)
            if point is not None:
                calls[i].push((fx, fy), point)
            elif tau:
                calls[i].push_torque(tau)

    def step(count: int) -> float:
        start = time.perf_counter()
        for _ in range(count):
            n = done[0]
            if changes and n >= changes[0]:  # the commands acting change at this step
                while changes and n >= changes[0]:
                    changes.pop(0)
                active[:] = [span[2:] for span in spans if span[0] <= n < span[1]]
            for i, _, _ in active:
                wake(i)
            if program is not None:
                program()
            if active:
                push_scripted()
            advance()
            done[0] = n + 1
        return time.perf_counter() - start

    return step
