"""Sleeping islands (C twin: ``src/kernel/sleep.c``): see :mod:`.solver` for the rule.
Sleeping bodies are put back where they were before detection, islands wake when an
awake body touches them, and rest times add up step by step until an island sleeps.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Optional

from .detect import Contact, Detection
from .islands import join, root
from .rows import ContactRow, States

if TYPE_CHECKING:
    from .compiled import CompiledContacts

__all__ = ["SLEEP_SPEED", "TIME_TO_SLEEP", "Sleep"]

#: Sleeping: the largest speed (m/s) of a resting body's fastest point, |v| + reach |omega|
#: (Box2D v3's default sleep threshold), and how long (s) every body of an island must rest
#: before it sleeps (Box2D's time to sleep).
SLEEP_SPEED = 0.05
TIME_TO_SLEEP = 0.5


class Sleep(Detection):
    """Sleep for :class:`~.solver.ContactPass`: per body whether it may sleep (``calm``),
    how long it has rested (``rested``, s) and the island it sleeps in (``island``, the
    lowest body of it; -1 while awake)."""

    sleep: bool
    calm: list[bool]
    rested: list[float]
    island: list[int]
    _restless: frozenset[int]
    _members: set[int]
    _kernel: Optional[CompiledContacts]

    def hold(self, bodies: Iterable[int]) -> None:
        """Inputs are held on ``bodies`` (and on no other): wake their islands and keep
        them awake while the inputs last."""
        held = set(bodies)
        self.calm = self._calm(held)
        self._sync_sleep()
        self._wake({self.island[b] for b in held} - {-1})
        if self._kernel is not None:
            self._kernel.set_sleep(self)

    def sleeping(self) -> list[int]:
        """The bodies asleep now, in order."""
        self._sync_sleep()
        return [b for b, island in enumerate(self.island) if island >= 0]

    def everything_asleep(self) -> bool:
        """Whether every body of the scene sleeps: a step would put each back where it
        started and find no contact."""
        if not self.sleep:
            return False
        self._sync_sleep()
        return all(island >= 0 for island in self.island)

    def _calm(self, held: Iterable[int]) -> list[bool]:
        """Per body, whether it may sleep while inputs are held on ``held``."""
        restless = self._restless | set(held)
        return [b in self._members and b not in restless for b in range(len(self.island))]

    def _sync_sleep(self) -> None:
        """Take the rest times and islands from the kernel, where it holds them."""
        if self._kernel is not None:
            self.rested, self.island = self._kernel.sleep_state()

    def _wake(self, islands: set[int]) -> None:
        """Wake the bodies of the sleeping ``islands``."""
        if not islands:
            return
        for b, sleeping in enumerate(self.island):
            if sleeping in islands:
                self.island[b] = -1
                self.rested[b] = 0.0

    def _awake_contacts(self, q1: States, v1: States, q0: States,
                        v0: States) -> list[Contact]:
        """The contacts of the awake bodies at ``q1``, after putting the sleeping ones back
        at (q0, v0) and waking the islands that awake bodies touch."""
        if not self.sleep:
            return self.detect(q1)
        for b, sleeping in enumerate(self.island):
            if sleeping >= 0:
                q1[b], v1[b] = q0[b], v0[b]
        while True:
            self._woken = set()
            contacts = self._detect(q1, self.island)
            if not self._woken:
                return contacts
            self._wake(self._woken)

    def _doze(self, rows: list[ContactRow], v1: States, h: float) -> None:
        """Add ``h`` to the rest time of each awake body that may sleep and rests (else
        start it again at zero), and put to sleep, with zero velocity, each island of awake
        bodies (joined by ``rows``) whose every body has rested :data:`TIME_TO_SLEEP`."""
        if not self.sleep:
            return
        island, rested = self.island, self.rested
        awake = [b for b, sleeping in enumerate(island) if sleeping < 0]
        parent = {b: b for b in awake}
        for row in rows:
            if row.a >= 0:
                join(parent, row.a, row.b)
        velocities = v1.tolist()
        shortest: dict[int, float] = {}
        for b in awake:
            vx, vy, omega = velocities[b]
            resting = self.calm[b] and (math.sqrt(vx * vx + vy * vy)
                                        + self.reach[b] * abs(omega) <= SLEEP_SPEED)
            rested[b] = rested[b] + h if resting else 0.0
            r = root(parent, b)
            shortest[r] = min(shortest.get(r, rested[b]), rested[b])
        for b in awake:
            r = root(parent, b)
            if shortest[r] >= TIME_TO_SLEEP:
                island[b] = r
                v1[b] = 0.0
