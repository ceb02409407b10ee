"""Warm starts (C twin: ``src/kernel/warm.c``): each step's impulses kept per pair of
parts with the contact point in the second body's axes, and given back to the contact of
that pair nearest the same point next step, if within :data:`MATCH`: the normal impulse
whole, the tangent impulse by :data:`FRICTION_CARRY` where a big island's passes ran out.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Optional

from ..geometry.planar import cos_sin_of
from .rows import ContactRow, PartKey, Velocities

if TYPE_CHECKING:
    from .compiled import CompiledContacts

__all__ = ["FRICTION_CARRY", "MATCH", "WarmImpulses", "WarmStarts"]

#: Distance (m) within which a contact point is taken for last step's, for warm starting.
MATCH = 1e-2
#: Fraction of its tangent impulse a contact keeps for the next step's warm start where its
#: island is big (swept in colour order) and its passes ran out before converging; small
#: islands and those with joint rows keep it whole (a jam of gears holds only so). Carried
#: whole, the friction of a pile whose passes do not converge integrates the sliding they
#: failed to stop into an impulse that outlives it, an undamped spring: the pile's static
#: friction and the normal impulses it leans on swing against each other, and pyramids of
#: 40 and 50 rows still sway at 0.08 and 0.2 m/s after 2 s; carrying half settles them
#: below 2 and 5 mm/s, where none or a quarter leaves 2 cm/s.
FRICTION_CARRY = 0.5

#: Per pair of parts, the remembered contacts (lx, ly, jn, jt): point in the second body's
#: axes, normal and tangent impulse.
WarmImpulses = dict[PartKey, list[tuple[float, float, float, float]]]


class WarmStarts:
    """Warm starts for :class:`~.solver.ContactPass`: in Python ``_warm``, in the kernel
    ``_kernel``'s; ``island``: each body's sleeping island (-1 awake)."""

    sleep: bool
    island: list[int]
    _warm: WarmImpulses
    _kernel: Optional[CompiledContacts]

    def _export_warm(self) -> list[list[Any]]:
        if self._kernel is None:
            warm = self._warm
        else:
            warm = {}
            for a, b, part_a, part_b, lx, ly, jn, jt in self._kernel.impulses():
                warm.setdefault((a, b, part_a, part_b), []).append((lx, ly, jn, jt))
        return [[list(key), [list(contact) for contact in warm[key]]] for key in sorted(warm)]

    def _recall(self, pair: PartKey, rx: float, ry: float, angle: float) -> tuple[float, float]:
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

    def _remember(self, rows: list[ContactRow], poses: Velocities,
                  points: list[tuple[float, float]]) -> None:
        """Keep each contact's impulses with its point (``points``, where it was found at
        ``poses``; a row's arms may be carried back) in the second body's frame, the tangent
        one by the row's ``carry`` (and those of the sleeping islands)."""
        self._warm = self._sleeping_warm()
        for row, (px, py) in zip(rows, points):
            pose = poses[row.b]
            rbx, rby, angle = px - pose[0], py - pose[1], pose[2]
            c, s = cos_sin_of(angle)
            self._warm.setdefault(row.key, []).append(
                (c * rbx + s * rby, -s * rbx + c * rby, row.jn, row.jt * row.carry))

    def _sleeping_warm(self) -> WarmImpulses:
        """The warm-start impulses of the sleeping islands' contacts, kept while they
        sleep."""
        if not self.sleep:
            return {}
        return {key: warm for key, warm in self._warm.items() if self.island[key[1]] >= 0}
