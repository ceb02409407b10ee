"""When and why the node stops, and with which exit status and log line, without ROS.

The node installs its own SIGINT and SIGTERM handlers (``rclpy.init`` with no signal
handlers) that only call :meth:`Shutdown.request`. rclpy's own handlers shut the context
down from a separate thread (the deferred signal handler of ``_rclpy_pybind11``) while a
timer callback may be publishing in the main thread, which then fails with "publisher's
context is invalid"; with the request recorded instead, the spin loop ends between two
callbacks and the context is shut down after the last publish. ``ros2 launch`` stops a
node with SIGINT, then SIGTERM after its timeout, so both end the same way: exit status 0
and one info line.

The spin loop is :func:`spin_until`: one ``spin_once`` after another with a short timeout.
``Executor.spin_until_future_complete`` adds a done-callback to its future at every turn
(rclpy's ``spin_once_until_future_complete``), so a future that never completes (the node
outside lockstep) holds one more closure per callback run, one per message received.
"""
from __future__ import annotations

import enum
import signal
from collections.abc import Callable
from typing import NamedTuple, Optional

__all__ = ["StopReason", "Outcome", "Shutdown", "spin_until", "POLL_S", "HANDLED_SIGNALS"]

#: The longest one turn of the spin loop waits for work, in seconds: a signal that
#: arrives while the executor waits is seen at most this late (a ROS-time timer may not
#: fire at all before the first /clock message).
POLL_S = 0.1
#: The signals that end the node cleanly.
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopReason(enum.Enum):
    """Why the spin loop ended."""

    SIGNAL = "signal"          # SIGINT (Ctrl-C, ros2 launch) or SIGTERM
    FINISHED = "finished"      # a lockstep run reached the scene's duration
    DIVERGED = "diverged"      # a lockstep run halted on a divergence
    CONTEXT = "context"        # someone else shut the ROS context down


class Outcome(NamedTuple):
    """The node's exit status and the line it logs at the end (empty: nothing more)."""

    status: int
    message: str


class Shutdown:
    """The stop request of one node run: the first signal received, if any."""

    def __init__(self) -> None:
        self.signal: Optional[int] = None
        self.repeated = 0

    def request(self, signum: int, _frame: object = None) -> None:
        """Record a signal (the signature of a :func:`signal.signal` handler).

        Only the first one counts; a second Ctrl-C while the node winds down is counted
        and changes nothing, so the shutdown stays the same however often it is asked for.
        """
        if self.signal is None:
            self.signal = signum
        else:
            self.repeated += 1

    @property
    def requested(self) -> bool:
        return self.signal is not None

    def reason(self, *, lockstep_result: Optional[bool], context_ok: bool) -> StopReason:
        """Why the loop ended: the signal first (it may arrive during the last tick), then a
        lockstep result (True: ran to its duration, False: diverged), then the context."""
        if self.signal is not None:
            return StopReason.SIGNAL
        if lockstep_result is not None:
            return StopReason.FINISHED if lockstep_result else StopReason.DIVERGED
        if not context_ok:
            return StopReason.CONTEXT
        raise ValueError("the spin loop ended with no reason to stop")

    def outcome(self, reason: StopReason) -> Outcome:
        """The exit status (1 only for a diverged lockstep run) and the closing log line."""
        if reason is StopReason.SIGNAL:
            assert self.signal is not None
            return Outcome(0, f"{signal.Signals(self.signal).name} received: shutting down")
        if reason is StopReason.CONTEXT:
            return Outcome(0, "the ROS context was shut down: stopping")
        # The lockstep tick has already logged where the run ended.
        return Outcome(0 if reason is StopReason.FINISHED else 1, "")


def spin_until(spin_once: Callable[[float], None], stop: Callable[[], bool],
               poll_s: float = POLL_S) -> None:
    """Call ``spin_once(poll_s)`` until ``stop()`` is true (checked before every turn)."""
    while not stop():
        spin_once(poll_s)
