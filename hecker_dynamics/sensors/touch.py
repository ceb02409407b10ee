"""Contact events: when two bodies, or a body and a wall or the map, begin and end touching,
and the impulses the contact pass gave them over the touch.

With ``publish.contacts`` on, the node's run loop samples after every step (on leaving
each instant, as the sensors do: :mod:`.schedule`). The pairs touching at an instant are
those whose parts the step that ended there found in contact (within the contact
margin) and answered, as the contact pass keeps them for warm starting; each contact's
normal and tangent impulses are the whole impulses of that step (the collision impulse
j and its friction, warm start included). A pair that is new begins touching at that
instant; one that is gone ends touching there. A ``BEGIN`` carries the impulses of its
first step, an ``END`` the sums over every step of the touch, so a bumper sees both edges
and a test the momentum a touch exchanged (the force of Eq. 5, F = M a, integrated over
the touch). While an
island sleeps its impulses are not summed: it is not being solved.

Events come in a fixed order: ends before begins, each by (surface, body a, body b).
"""
from __future__ import annotations

import enum
from typing import Any, NamedTuple, Optional

from ..dynamics.simulation import Simulation
from ..scene.load import MAP_SURFACE, Scene

__all__ = ["TouchKind", "TouchEvent", "Touches", "MAP_SURFACE"]

#: A touching pair: the fixed surface (a wall's name, :data:`MAP_SURFACE`, or "" between
#: two bodies), body a ("" against a surface) and body b.
Pair = tuple[str, str, str]


class TouchKind(enum.IntEnum):
    """Which edge of a touch an event is (the message's constants)."""

    BEGIN = 0
    END = 1


class TouchEvent(NamedTuple):
    """A touch beginning or ending at ``stamp_ns``, with its impulses (N s)."""

    stamp_ns: int
    kind: TouchKind
    surface: str
    body_a: str
    body_b: str
    normal_impulse: float
    tangent_impulse: float


class Touches:
    """The touching pairs of one scene's run and their impulses so far."""

    def __init__(self, scene: Scene) -> None:
        self.enabled = scene.publish_contacts
        self.walls = [wall.name for wall in scene.walls]
        #: Per touching pair, its impulses summed since it began.
        self.touching: dict[Pair, tuple[float, float]] = {}
        self.sampled_ns: Optional[int] = None

    def next_stop(self, sim: Simulation) -> Optional[int]:
        """The next instant to sample at: the end of the next step (None when off)."""
        return sim.time_ns + sim.step_ns if self.enabled else None

    def _pair(self, names: tuple[str, ...], a: int, b: int) -> Pair:
        if a >= 0:
            return "", names[a], names[b]
        wall = -1 - a
        return (self.walls[wall] if wall < len(self.walls) else MAP_SURFACE), "", names[b]

    def _impulses(self, sim: Simulation) -> dict[Pair, tuple[float, float]]:
        """Per pair touching now, the impulses of the step that ended now (zero for a
        sleeping one)."""
        contacts = sim.model.contacts
        if contacts is None:
            return {}
        state = contacts.export_state()
        warm: list[list[Any]] = state["warm"] if isinstance(state, dict) else state
        island = state["island"] if isinstance(state, dict) else None
        names = sim.model.names
        found: dict[Pair, tuple[float, float]] = {}
        for (a, b, _, _), points in warm:
            pair = self._pair(names, int(a), int(b))
            normal, tangent = found.get(pair, (0.0, 0.0))
            if island is None or island[b] < 0:
                for _, _, jn, jt in points:
                    normal, tangent = normal + jn, tangent + jt
            found[pair] = (normal, tangent)
        return found

    def sample(self, sim: Simulation) -> list[TouchEvent]:
        """The touches that began or ended in the step that ended at the simulation's
        present instant (each instant once; none when off)."""
        now = sim.time_ns
        if not self.enabled or now == self.sampled_ns:
            return []
        self.sampled_ns = now
        found = self._impulses(sim)
        events = [TouchEvent(now, TouchKind.END, *pair, *self.touching.pop(pair))
                  for pair in sorted(set(self.touching) - set(found))]
        for pair in sorted(found):
            normal, tangent = found[pair]
            if pair not in self.touching:
                events.append(TouchEvent(now, TouchKind.BEGIN, *pair, normal, tangent))
                self.touching[pair] = (normal, tangent)
            else:
                total_normal, total_tangent = self.touching[pair]
                self.touching[pair] = (total_normal + normal, total_tangent + tangent)
        return events

    def export_state(self) -> list[list[Any]]:
        """The touching pairs and their sums, as plain data for a keyframe."""
        return [[*pair, *sums] for pair, sums in sorted(self.touching.items())]

    def import_state(self, data: list[list[Any]]) -> None:
        self.touching = {(str(s), str(a), str(b)): (float(n), float(t))
                         for s, a, b, n, t in data}
        self.sampled_ns = None
