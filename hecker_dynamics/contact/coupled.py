"""Joint rows inside the contact solve, so that contact impulses travel through the joints.

The joint pass (:mod:`.joints`) solves the joints alone, exactly, before the contacts. A
contact on a jointed body (a bar wedged between two pinned gears) then needs the joints'
reaction in the same solve: without it the contact pushes the body off its pin, the next
joint pass undoes part of the push, and a jammed train creeps on. So in each contact
island that holds a jointed body, the contact solver's sequential-impulse passes sweep the
joints' velocity rows too, each as one more unit (:class:`JointUnit`) with its own
accumulated impulse, the ``extra`` on top of what the joint pass gave it, warm-started
from the last step's extra (clamped to this step's bounds) as the contacts are:

- a rigid row (pin, weld, slider, rod, gear) keeps its velocity J v at zero, unbounded;
- a motor drives J v to its speed with extra impulses within
  [-bound - x, bound - x], x the joint pass's impulse: the total stays within max effort
  x h, so a jammed motor saturates at its maximum;
- a limit (or rope) keeps J v >= -max(C, 0) / h, its total impulse x + extra >= 0;
- a soft row (a rotary spring, a soft weld) is left out: its impulse follows its spring
  law over the step, which the joint pass solved.

A unit's update is the sequential impulse of a contact's normal row, with the effective
mass 1 / (J M^-1 J^T) of the row; its impulse changes the velocities by M^-1 J^T lambda
(the force part by Eq. 5, the angular part by tau = I alpha, Eq. 14).
The extras are added to the joint pass's impulses afterwards (:meth:`.JointPass.take_extra`),
so the joints' efforts include them. Position drift the extras leave is the next step's
joint pass's to remove, by positions only. The kernel's ``src/kernel/coupled.c`` repeats
this module operation for operation.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["JointUnit"]

Entries = list[tuple[int, float, float, float]]


@dataclass(slots=True)
class JointUnit:
    """One velocity row of a joint in the contact solve: the joint pass's row ``slot``, its
    Jacobian ``entries`` and M^-1 J^T ``direction`` per body (the scene's indices), its
    effective mass, the velocity J v it aims for (``target``), the bounds of its extra
    impulse, and the extra impulse accumulated so far (at first the warm start)."""

    slot: int
    entries: Entries
    direction: Entries
    mass: float
    target: float
    lower: float
    upper: float
    extra: float = 0.0

    def bodies(self) -> list[int]:
        """The bodies the row acts on."""
        return [entry[0] for entry in self.entries]

    def warm_start(self, velocity: dict[Any, Any]) -> None:
        """Apply the extra impulse the unit starts from (last step's, within this step's
        bounds)."""
        self._push(velocity, self.extra)

    def _push(self, velocity: dict[Any, Any], impulse: float) -> None:
        """v += M^-1 J^T impulse."""
        for b, dx, dy, dw in self.direction:
            vb = velocity[b]
            vb[0] += dx * impulse
            vb[1] += dy * impulse
            vb[2] += dw * impulse

    def solve(self, velocity: dict[Any, Any]) -> float:
        """The accumulated extra impulse that brings J v to the target within the bounds.
        Returns the change of J v."""
        rate = 0.0
        for b, jx, jy, jw in self.entries:
            vb = velocity[b]
            rate += jx * vb[0] + jy * vb[1] + jw * vb[2]
        extra = self.extra
        new = min(max(extra + (self.target - rate) * self.mass, self.lower), self.upper)
        change = new - extra
        self._push(velocity, change)
        self.extra = new
        return abs(change) / self.mass
