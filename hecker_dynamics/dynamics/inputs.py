"""The input buffer: which commanded wrenches act during each step.

Rules: a command starts to act at the first step that begins at or
after its stamp; a newer command with the same ``(body, source)`` replaces it; it stops at
``stamp + duration`` when it has a duration, else at ``stamp + timeout`` (the safety
timeout, like a velocity-command timeout; 0 disables it). Commands are held constant over
a step. Commands with equal stamps take effect in the order they were pushed, so the same
inputs in the same order always give the same forces.
"""
from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable, Sequence
from dataclasses import asdict
from typing import Any, NamedTuple, Optional

from ..scene.commands import InputError, WrenchCommand
from .forces import WrenchRow

__all__ = ["Held", "InputBuffer", "same_place"]


class Held(NamedTuple):
    """A command in the buffer with its resolved force row and the time it stops acting (a
    named tuple: the drives hold two new ones at every control instant)."""

    command: WrenchCommand
    row: WrenchRow
    end_ns: Optional[int]


class InputBuffer:
    """Pending and active commands, keyed by ``(body, source)``."""

    def __init__(self, timeout_ns: int, max_pending: int = 10_000, max_active: int = 1_000) -> None:
        self.timeout_ns = timeout_ns
        self.max_pending = max_pending
        self.max_active = max_active
        self._pending: list[tuple[int, int, Held]] = []
        self._active: dict[tuple[str, str], Held] = {}
        #: The first end of an active command (None: none ends), kept as they change: the
        #: simulation asks at every stop whether anything changes, mostly when nothing does.
        self._first_end: Optional[int] = None
        #: How many pending commands each key has (a plain dict: a Counter's updates cost
        #: more, and the drives add two commands at every control instant).
        self._pending_keys: dict[tuple[str, str], int] = {}
        self._order = itertools.count()
        #: Commands taken by :meth:`replace`, as pending entries (stamp, order, held) due
        #: at the next :meth:`update`, outside the heap: never beside pending ones.
        self._staged: list[tuple[int, int, Held]] = []
        #: Whether the last :meth:`update` that changed the active commands only replaced
        #: some by commands acting at the same place (:func:`same_place`): the active rows
        #: differ from before in their forces and torques alone.
        self.values_only = False

    def end_of(self, command: WrenchCommand) -> Optional[int]:
        """When a command stops acting, if nothing replaces it (None: never)."""
        if command.duration_ns > 0:
            return command.stamp_ns + command.duration_ns
        if self.timeout_ns > 0:
            return command.stamp_ns + self.timeout_ns
        return None

    def add(self, command: WrenchCommand, row: WrenchRow) -> None:
        """Queue a command; raises :class:`InputError` when the buffer is full."""
        for entry in self._staged:  # queued before it, as the heap would hold them
            heapq.heappush(self._pending, entry)
            key = (entry[2].command.body, entry[2].command.source)
            self._pending_keys[key] = self._pending_keys.get(key, 0) + 1
        self._staged = []
        if len(self._pending) >= self.max_pending:
            raise InputError(f"input buffer full ({self.max_pending} pending commands); "
                             f"dropped {_what(command)}")
        key = (command.body, command.source)
        new_source = key not in self._active and key not in self._pending_keys
        if new_source and self._sources_at_cap():
            raise InputError(f"more than {self.max_active} input sources at once; dropped "
                             f"{_what(command)}")
        held = Held(command, row, self.end_of(command))
        self._pending_keys[key] = self._pending_keys.get(key, 0) + 1
        heapq.heappush(self._pending, (command.stamp_ns, next(self._order), held))

    def _sources_at_cap(self) -> bool:
        """Whether the sources with a command active or pending number ``max_active``.
        Their count is at least the larger of the two key sets and at most their sum, so
        the union (1,000 keys at the cap) is built only when the cap lies between those,
        not for every message of a flood."""
        active, pending, cap = len(self._active), len(self._pending_keys), self.max_active
        if max(active, pending) >= cap:
            return True
        if active + pending < cap:
            return False
        return len(self._active.keys() | self._pending_keys.keys()) >= cap

    def replace(self, commands: Sequence[WrenchCommand], rows: Sequence[WrenchRow],
                now_ns: int) -> bool:
        """Queue ``commands`` (with their resolved ``rows``), each stamped ``now_ns`` and
        from a body and source whose command is active (a drive's wheels at its control
        instant), as :meth:`add` would, where nothing is pending: they wait outside the
        heap, with their order numbers, for the next :meth:`update`, which takes them as
        it would from the heap. False, and nothing queued, otherwise."""
        if self._pending or self._staged:
            return False
        active = self._active
        for command in commands:
            if command.stamp_ns != now_ns or (command.body, command.source) not in active:
                return False
        self._staged = [(now_ns, next(self._order), Held(command, row, self.end_of(command)))
                        for command, row in zip(commands, rows)]
        return True

    def wheels(self, keys: Sequence[tuple[str, str]]) -> Optional[list[int]]:
        """Where the commands of ``keys`` stand among the active ones (their rows' order),
        where they are all the commands, active, and none pending: a differential drive's
        wheels that the kernel's run renews (:meth:`renew`). None otherwise."""
        active = self._active
        if self._pending or self._staged or len(active) != len(keys):
            return None
        rows = {key: row for row, key in enumerate(active)}
        found = [rows.get(key) for key in keys]
        return None if None in found else found  # type: ignore[return-value]

    def only_active(self, count: int) -> bool:
        """Whether ``count`` commands are active and none pending."""
        return not (self._pending or self._staged) and len(self._active) == count

    def holds(self, key: tuple[str, str]) -> bool:
        """Whether a command of ``key`` (body, source) is held, pending or staged."""
        return key in self._active or key in self._pending_keys or any(
            (held.command.body, held.command.source) == key for _, _, held in self._staged)

    def end(self, key: tuple[str, str]) -> Optional[int]:
        """When the active command of ``key`` stops acting (None: never)."""
        return self._active[key].end_ns

    def renew(self, renewed: Sequence[tuple[tuple[str, str], int, tuple[float, float]]],
              commands: int) -> None:
        """Take what the kernel's run made of the wheels of its drives: each ``(key, stamp,
        force)`` of ``renewed`` a command of ``key``'s active one stamped anew with a new
        force (and no torque), as :meth:`replace` and :meth:`update` would have made the last
        one of the ``commands`` it renewed in all; their order numbers counted."""
        active = self._active
        for key, stamp, force in renewed:
            old = active[key]
            c = old.command
            command = WrenchCommand(stamp, c.body, c.source, c.frame_id, c.point, force, 0.0,
                                    c.duration_ns)
            active[key] = Held(command, old.row._replace(force=force, torque=0.0),
                               self.end_of(command))
        self._order = itertools.count(next(self._order) + commands)
        self._track_ends()
        self.values_only = True

    def update(self, now_ns: int) -> bool:
        """Start due commands and stop ended ones at the start of a step; True if any changed."""
        if not self._staged and (not self._pending or self._pending[0][0] > now_ns) and \
                (self._first_end is None or self._first_end > now_ns):
            return False
        changed = False
        values_only = True
        due = [entry[2] for entry in self._staged]  # never beside pending ones (add)
        self._staged = []
        while self._pending and self._pending[0][0] <= now_ns:
            held = heapq.heappop(self._pending)[2]
            key = (held.command.body, held.command.source)
            left = self._pending_keys.pop(key) - 1
            if left:
                self._pending_keys[key] = left
            due.append(held)
        for held in due:
            key = (held.command.body, held.command.source)
            replaced = self._active.get(key)
            if replaced is None or not same_place(replaced.row, held.row):
                values_only = False
            self._active[key] = held  # a replaced key keeps its place in the order
            changed = True
        self._track_ends()
        ended: list[tuple[str, str]] = []
        # Looked for only where one ends now: at a drive's control instant the commands
        # ending now were just replaced, and the scan would find none.
        if self._first_end is not None and self._first_end <= now_ns:
            ended = [key for key, held in self._active.items()
                     if held.end_ns is not None and held.end_ns <= now_ns]
            for key in ended:
                del self._active[key]
            self._track_ends()
        self.values_only = values_only and not ended
        return changed or bool(ended)

    def next_change(self) -> Optional[int]:
        """The earliest time at which :meth:`update` may change the active commands: the
        first pending stamp or the first end of an active command (None: never, unless a
        command is added)."""
        first = self._first_end
        if self._pending or self._staged:
            stamp = (self._pending or self._staged)[0][0]
            return stamp if first is None or stamp < first else first
        return first

    def _track_ends(self) -> None:
        """Take the first end of the active commands again, after they changed."""
        ends = [held.end_ns for held in self._active.values() if held.end_ns is not None]
        self._first_end = min(ends) if ends else None

    def export_state(self) -> dict[str, Any]:
        """The buffer as plain data: pending commands in heap order with their order
        numbers, active ones in the order they act (their rows are summed in that order),
        and the next order number. :meth:`import_state` restores it exactly."""
        order = next(self._order)
        self._order = itertools.count(order)
        return {
            "pending": [[stamp, number, _command_data(held.command)]
                        for stamp, number, held in self._pending or self._staged],
            "active": [_command_data(held.command) for held in self._active.values()],
            "next_order": order,
        }

    def import_state(self, state: dict[str, Any],
                     row_of: Callable[[WrenchCommand], WrenchRow]) -> None:
        """Restore :meth:`export_state`'s data; ``row_of`` resolves a command's force row."""
        def held(data: dict[str, Any]) -> Held:
            command = _command_from_data(data)
            return Held(command, row_of(command), self.end_of(command))

        self.clear()
        self._pending = [(int(stamp), int(number), held(data))
                         for stamp, number, data in state["pending"]]
        for _, _, item in self._pending:
            key = (item.command.body, item.command.source)
            self._pending_keys[key] = self._pending_keys.get(key, 0) + 1
        for data in state["active"]:
            item = held(data)
            self._active[(item.command.body, item.command.source)] = item
        self._track_ends()
        self._order = itertools.count(int(state["next_order"]))

    def active(self) -> list[Held]:
        return list(self._active.values())

    def clear(self) -> None:
        self._staged = []
        self._pending.clear()
        self._pending_keys.clear()
        self._active.clear()
        self._first_end = None

    def __len__(self) -> int:
        return len(self._pending) + len(self._staged) + len(self._active)


def _what(command: WrenchCommand) -> str:
    return f"the command for '{command.body}' from '{command.source}'"


def same_place(a: WrenchRow, b: WrenchRow) -> bool:
    """Whether rows ``a`` and ``b`` act on the same body at the same point in the same axes
    (their forces and torques aside), to the bit: equal points with a zero in them may
    differ in its sign, so they count only as the same object. A buffer kept without rows
    (the viewer's, whose commands are only drawn) has empty ones: never the same place."""
    if not (a and b):
        return False
    return a.body == b.body and a.axes_body == b.axes_body and \
        a.point_body == b.point_body and a.at_point == b.at_point and \
        (a.point is b.point or (a.point == b.point and 0.0 not in a.point))


def _command_data(command: WrenchCommand) -> dict[str, Any]:
    data = asdict(command)
    data["point"], data["force"] = list(command.point), list(command.force)
    return data


def _command_from_data(data: dict[str, Any]) -> WrenchCommand:
    return WrenchCommand(
        stamp_ns=int(data["stamp_ns"]), body=str(data["body"]), source=str(data["source"]),
        frame_id=str(data["frame_id"]), point=(float(data["point"][0]), float(data["point"][1])),
        force=(float(data["force"][0]), float(data["force"][1])), torque=float(data["torque"]),
        duration_ns=int(data["duration_ns"]))
