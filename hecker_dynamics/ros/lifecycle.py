"""When and why the node stops, and with which exit status and log line, without ROS.

The node installs its own SIGINT and SIGTERM handlers (``rclpy.init`` with no signal
handlers) that only call :meth:`Shutdown.request`. rclpy's own handlers shut the context
down from a separate thread (the deferred signal handler of ``_rclpy_pybind11``) while a
timer callback may be publishing, which then fails with "publisher's context is invalid";
with the request recorded instead, the callbacks stop and the context is shut down after
the last publish. ``ros2 launch`` stops a node with SIGINT, then SIGTERM after its
timeout, so both end the same way: exit status 0 and one info line.

The node's work runs in worker threads (:func:`serve`): the executor's callbacks, which
wait for work with no timeout, and, on the system clock, the ticks (:func:`tick_every`).
An rclpy timer costs a tick two turns of the executor, each building its wait set anew
(a callback's end triggers the executor's guard condition), and ``spin_once(timeout_sec)``
also creates an rcl timer for its timeout at every turn: on Jazzy a bare node publishing
10 messages at 50 Hz took 1.0 ms of CPU per tick that way, 0.25 ms with the ticks in a
thread of their own. A Python signal handler only runs in the main thread, and only once
that thread is back in the interpreter; the main thread therefore waits for the workers
in turns of :data:`POLL_S`, and its handler records the stop and wakes the workers' waits.
Each worker checks the stop whenever its wait returns, so the context is shut down by the
main thread after the last callback and the last tick.
``Executor.spin_until_future_complete`` is not used: it adds a done-callback to its future
at every turn (rclpy's ``spin_once_until_future_complete``), so a future that never
completes (the node outside lockstep) holds one more closure per callback run, one per
message received.
"""
from __future__ import annotations

import enum
import signal
import threading
import time
from collections.abc import Callable, Sequence
from typing import NamedTuple, Optional

__all__ = ["StopReason", "Outcome", "Shutdown", "serve", "tick_every", "POLL_S", "HANDLED_SIGNALS"]

#: How often the main thread looks at the signals while the workers run, in seconds: a
#: signal delivered to another thread (a worker's or one of DDS's) is seen at most this
#: late.
POLL_S = 0.1
#: The signals that end the node cleanly.
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopReason(enum.Enum):
    """Why the callbacks stopped."""

    SIGNAL = "signal"          # SIGINT (Ctrl-C, ros2 launch) or SIGTERM
    FINISHED = "finished"      # a lockstep run reached the scene's duration
    DIVERGED = "diverged"      # a lockstep run halted on a divergence
    CONTEXT = "context"        # someone else shut the ROS context down


class Outcome(NamedTuple):
    """The node's exit status and the line it logs at the end (empty: nothing more)."""

    status: int
    message: str


class Shutdown:
    """The stop request of one node run: the first signal received, if any, or a worker's
    failure."""

    def __init__(self) -> None:
        self.signal: Optional[int] = None
        self.repeated = 0
        self.failed = False
        #: Called at the first signal and at a failure: wakes the workers' waits.
        self.wake: Callable[[], None] = lambda: None

    def request(self, signum: int, _frame: object = None) -> None:
        """Record a signal (the signature of a :func:`signal.signal` handler).

        Only the first one counts; a second Ctrl-C while the node winds down is counted
        and changes nothing, so the shutdown stays the same however often it is asked for.
        """
        if self.signal is None:
            self.signal = signum
            self.wake()
        else:
            self.repeated += 1

    def fail(self) -> None:
        """Stop the other workers: one of them raised."""
        self.failed = True
        self.wake()

    @property
    def requested(self) -> bool:
        return self.signal is not None or self.failed

    def reason(self, *, lockstep_result: Optional[bool], context_ok: bool) -> StopReason:
        """Why the loop ended: the signal first (it may arrive during the last tick), then a
        lockstep result (True: ran to its duration, False: diverged), then the context."""
        if self.signal is not None:
            return StopReason.SIGNAL
        if lockstep_result is not None:
            return StopReason.FINISHED if lockstep_result else StopReason.DIVERGED
        if not context_ok:
            return StopReason.CONTEXT
        raise ValueError("the callbacks stopped with no reason to stop")

    def outcome(self, reason: StopReason) -> Outcome:
        """The exit status (1 only for a diverged lockstep run) and the closing log line."""
        if reason is StopReason.SIGNAL:
            assert self.signal is not None
            return Outcome(0, f"{signal.Signals(self.signal).name} received: shutting down")
        if reason is StopReason.CONTEXT:
            return Outcome(0, "the ROS context was shut down: stopping")
        # The lockstep tick has already logged where the run ended.
        return Outcome(0 if reason is StopReason.FINISHED else 1, "")


def serve(workers: Sequence[Callable[[], None]], stop: Shutdown, poll_s: float = POLL_S) -> None:
    """Run each of ``workers`` in a thread of its own until all have returned, the main
    thread waiting in turns of ``poll_s`` so that its signal handlers run. A worker that
    raises stops the others (:meth:`Shutdown.fail`); the first error is raised here."""
    raised: list[BaseException] = []

    def run(worker: Callable[[], None]) -> None:
        try:
            worker()
        except BaseException as error:  # handed to the main thread, which raises it
            raised.append(error)
            stop.fail()
    threads = [threading.Thread(target=run, args=(worker,), name=getattr(worker, "__name__", None))
               for worker in workers]
    for thread in threads:
        thread.start()
    for thread in threads:
        while thread.is_alive():
            thread.join(poll_s)
    if raised:
        raise raised[0]


def tick_every(period_s: float, tick: Callable[[], Optional[float]], stopped: Callable[[], bool],
               woken: threading.Event, clock: Callable[[], float] = time.monotonic) -> None:
    """Call ``tick()`` every ``period_s`` of ``clock`` until ``stopped()``, as an rcl timer
    fires: at start + k period, a late tick followed by the next one due (those missed are
    skipped, not run in a burst). A tick that returns a number of seconds instead sets the
    next one due that long after the clock's reading before it, so that the ticks follow
    instants of the tick's own (the node's publish instants on its own clock). ``woken``
    ends a wait early; it is set with the stop, so once stopped every wait returns at
    once."""
    due = clock() + period_s
    while not stopped():
        woken.wait(due - clock())
        if stopped():
            return
        now = clock()
        if now < due:
            continue
        after = tick()
        due = now + after if after is not None else \
            due + period_s * (1 + (now - due) // period_s)
