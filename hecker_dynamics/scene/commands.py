"""Wrench commands: the core's form of an input, independent of any ROS message type.

A command is a planar wrench (force x, y and torque z) that starts to act on a body at
``stamp_ns`` and holds until a command with the same ``(body, source)`` replaces it, until
its ``duration_ns`` ends, or (when ``duration_ns`` is zero) until the simulation's input
timeout passes without a new command from that source.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

from .parameters import number_text, seconds_text

__all__ = ["InputError", "WrenchCommand", "shorter_than_a_step"]


class InputError(ValueError):
    """A command the simulation refuses; the message says which and why."""


def shorter_than_a_step(duration_ns: int, step_ns: int,
                        written: Optional[float] = None) -> Optional[str]:
    """Why a force lasting ``duration_ns`` (``written`` seconds, if the caller read them)
    cannot act at steps of ``step_ns``, or None if it can: a force acts over whole steps
    (each step that begins before its end), so one shorter than a step would give a whole
    step's impulse, not its own. 0 ns is no duration (held until replaced), so a positive
    duration written that rounds to 0 ns is refused too. Each caller names the duration
    before this text, in its own way (a scene parameter, an argument, a command)."""
    if not (duration_ns > 0 or (written is not None and written > 0.0)) or \
            duration_ns >= step_ns:
        return None
    seconds = seconds_text(duration_ns) if written is None else number_text(written)
    return (f"{seconds} s is shorter than one step ({seconds_text(step_ns)} s), over which "
            "a force acts whole")


@dataclass(frozen=True)
class WrenchCommand:
    """A planar wrench acting on ``body`` from ``stamp_ns`` on.

    ``frame_id`` names the frame that ``point``, ``force`` and ``torque`` are expressed in:
    the scene's fixed frame, a body's frame (``"<body>"``), or a named point of a body
    (``"<body>/<point>"``: origin at the point, axes of the body). ``point`` is the
    application point in that frame. ``source`` is the sender's id: a new command with the
    same ``body`` and ``source`` replaces the previous one.
    """

    stamp_ns: int
    body: str
    source: str
    frame_id: str
    point: tuple[float, float]
    force: tuple[float, float]
    torque: float = 0.0
    duration_ns: int = 0

    def check_finite(self) -> None:
        """Raise :class:`InputError` if any number of the wrench is NaN or infinite."""
        numbers = (*self.point, *self.force, self.torque)
        if not all(map(math.isfinite, numbers)):
            raise InputError(
                f"wrench for body '{self.body}' from '{self.source}' has a non-finite "
                f"value (point={self.point}, force={self.force}, torque={self.torque})")
        if self.duration_ns < 0:
            raise InputError(
                f"wrench for body '{self.body}' from '{self.source}' has a negative "
                f"duration ({self.duration_ns} ns)")
