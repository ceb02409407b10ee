"""The joints' rows: each joint kind's scalar constraints C(q) at given positions, with
their Jacobians (C twin: the row builders of ``src/kernel/joint.c``, up to
``hd_build_rows``).

A point constraint between P_A and P_B has the rows (1, 0, -r_By) and (0, 1, r_Bx) on body
B and their negatives on A, from the body point velocity v_P = v_CM + omega perp(r)
(Eq. 9); an angle constraint the row (0, 0, 1). :class:`~.joints.JointPass` builds every
joint's rows from these at each stage and solves them with :mod:`.joint_solve`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

from ..scene.joints import Motor, WeldJoint

__all__ = ["EFFORT_SIGNS", "LIMIT", "MOTOR", "RIGID", "SOFT", "Entries", "Frame", "JointRow",
           "Point", "Vec2", "angle_entries", "bounded_rows", "fixed_entries", "line_entries",
           "negated", "point_rows", "weld_law", "wrap"]

# Row kinds.
RIGID, LIMIT, MOTOR, SOFT = "rigid", "limit", "motor", "soft"


Vec2 = tuple[float, float]
#: A point as the rows take it: a Vec2, or a body-frame offset as a tuple.
Point = tuple[float, ...]

@dataclass(slots=True)
class JointRow:
    """One scalar constraint at given positions: its ``key`` (joint, part), ``kind``,
    value ``c``, Jacobian ``entries`` [(body, jx, jy, jw)] (local body indices), and for a
    motor its ``speed`` and largest effort ``bound``, for a soft row its ``stiffness``
    and ``damping`` (per unit effective mass when ``scaled``)."""

    key: tuple[str, str]
    kind: str
    c: float
    entries: list[tuple[int, float, float, float]]
    speed: float = 0.0
    bound: float = math.inf
    stiffness: float = 0.0
    damping: float = 0.0
    scaled: bool = False


def weld_law(weld: WeldJoint) -> tuple[float, float]:
    """A soft weld's stiffness and damping per unit effective mass: omega^2 and
    2 zeta omega of its frequency (zero for a rigid weld)."""
    omega = 2.0 * math.pi * weld.frequency
    return omega * omega, 2.0 * weld.damping_ratio * omega


def wrap(angle: float) -> float:
    """``angle`` in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


Entries = list[tuple[int, float, float, float]]


def negated(entries: Entries) -> Entries:
    return [(b, -jx, -jy, -jw) for b, jx, jy, jw in entries]


class Frame:
    """A joint end: a body's CM pose (or the world) and a point in it."""

    __slots__ = ("body", "local")

    def __init__(self, body: int, local: tuple[float, float]) -> None:
        self.body, self.local = body, local  # body -1: the world; local then fixed-frame

    def place(self, q: list[float]) -> tuple[float, float, float, float, float]:
        """(x, y) of the point, its arm (r_x, r_y) from the CM, and the body angle, at
        the poses ``q`` (3 values per body)."""
        if self.body < 0:
            return self.local[0], self.local[1], 0.0, 0.0, 0.0
        x, y, angle = q[3 * self.body], q[3 * self.body + 1], q[3 * self.body + 2]
        c, s = math.cos(angle), math.sin(angle)
        rx = c * self.local[0] - s * self.local[1]
        ry = s * self.local[0] + c * self.local[1]
        return x + rx, y + ry, rx, ry, angle


def line_entries(a: Frame, b: Frame, pa: Point, pb: Point, ux: float, uy: float) -> list[Any]:
    """Jacobian entries of u . (P_B - P_A) for a direction u fixed in body A: on B
    (u, perp(r_B) . u), on A (-u, -perp(P_B - x_A) . u), since u turns with A."""
    entries = []
    if b.body >= 0:
        entries.append((b.body, ux, uy, ux * -pb[3] + uy * pb[2]))
    if a.body >= 0:
        dx, dy = pa[2] + pb[0] - pa[0], pa[3] + pb[1] - pa[1]  # P_B - x_A
        entries.append((a.body, -ux, -uy, -(ux * -dy + uy * dx)))
    return entries


def fixed_entries(a: Frame, b: Frame, pa: Point, pb: Point, ux: float, uy: float) -> list[Any]:
    """Jacobian entries of u . (P_B - P_A) for a direction u fixed in the world (or
    following both ends): on B (u, perp(r_B) . u), on A (-u, -perp(r_A) . u)."""
    entries = []
    if b.body >= 0:
        entries.append((b.body, ux, uy, ux * -pb[3] + uy * pb[2]))
    if a.body >= 0:
        entries.append((a.body, -ux, -uy, -(ux * -pa[3] + uy * pa[2])))
    return entries


def point_rows(name: str, a: Frame, b: Frame, pa: Point, pb: Point, kind: str,
                stiffness: float = 0.0, damping: float = 0.0) -> list[JointRow]:
    """The two rows of P_B - P_A = 0 (x and y); a soft row's ``stiffness`` and
    ``damping`` are per unit effective mass."""
    return [JointRow((name, axis), kind, ux * (pb[0] - pa[0]) + uy * (pb[1] - pa[1]),
                     fixed_entries(a, b, pa, pb, ux, uy), stiffness=stiffness, damping=damping,
                     scaled=True)
            for axis, (ux, uy) in (("x", (1.0, 0.0)), ("y", (0.0, 1.0)))]


def angle_entries(a: int, b: int, scale: float = 1.0) -> list[Any]:
    entries = [(b, 0.0, 0.0, scale)]
    if a >= 0:
        entries.append((a, 0.0, 0.0, -scale))
    return entries


def bounded_rows(name: str, value: float, entries: list[Any], lower: Optional[float],
                  upper: Optional[float], motor: Optional[Motor], h: float) -> list[JointRow]:
    """Limit rows (value - lower >= 0, upper - value >= 0) and a motor row on a joint
    coordinate ``value`` whose Jacobian is ``entries``."""
    rows = []
    if lower is not None:
        rows.append(JointRow((name, "lower"), LIMIT, value - lower, entries))
    if upper is not None:
        rows.append(JointRow((name, "upper"), LIMIT, upper - value, negated(entries)))
    if motor is not None:
        rows.append(JointRow((name, "motor"), MOTOR, value, entries, speed=motor.speed,
                             bound=motor.max_effort * h))
    return rows


#: Parts of a joint that act along its coordinate, with the sign of their effort.
EFFORT_SIGNS = {"lower": 1.0, "upper": -1.0, "motor": 1.0, "spring": 1.0}
