"""Rate-limited log lines: at most one line per reason per period, counting the rest.

The node meets bad input at whatever rate senders produce it (a flood of NaN wrenches, a
clock that keeps jumping). Each kind of problem gets a key; :class:`RateLimiter` lets the
first line of a key through, suppresses the following ones for ``period_ns`` and reports
how many it suppressed with the next line it lets through. It has no ROS import: the node
hands the lines it returns to its logger. The clock is injectable so tests need no sleeping.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Optional

__all__ = ["RateLimiter"]

DEFAULT_PERIOD_NS = 5_000_000_000


@dataclass
class _KeyState:
    """When a key last let a line through, and how many lines it held back since."""

    last_emit_ns: int
    suppressed: int = 0


class RateLimiter:
    """Lets through at most one line per key every ``period_ns`` of ``clock`` time."""

    def __init__(self, period_ns: int = DEFAULT_PERIOD_NS,
                 clock: Callable[[], int] = time.monotonic_ns) -> None:
        if period_ns < 0:
            raise ValueError(f"period_ns must not be negative, not {period_ns}")
        self._period_ns = period_ns
        self._clock = clock
        self._keys: dict[str, _KeyState] = {}

    def line(self, key: str, message: str) -> Optional[str]:
        """Return the line to log for ``message`` under ``key``, or None to stay quiet.

        A returned line carries, in parentheses, how many lines of the same key were
        suppressed since the previous one.
        """
        now_ns = self._clock()
        state = self._keys.get(key)
        if state is not None and now_ns - state.last_emit_ns < self._period_ns:
            state.suppressed += 1
            return None
        suppressed = state.suppressed if state is not None else 0
        self._keys[key] = _KeyState(last_emit_ns=now_ns)
        if suppressed:
            noun = "line" if suppressed == 1 else "lines"
            return f"{message} ({suppressed} similar {noun} suppressed)"
        return message
