"""The node's stop decisions without ROS: signals, lockstep results, the worker thread.

The rclpy side (the executor's loop in a node process that gets SIGINT or SIGTERM) is in
test_node_process.py.
"""
from __future__ import annotations

import os
import signal
import threading
from typing import Optional

import pytest

from hecker_dynamics.ros.lifecycle import (
    HANDLED_SIGNALS,
    Outcome,
    Shutdown,
    StopReason,
    serve,
    tick_every,
)


def test_the_first_signal_is_the_reason_and_later_ones_change_nothing():
    stop = Shutdown()
    assert not stop.requested
    stop.request(signal.SIGTERM)
    stop.request(signal.SIGINT)
    stop.request(signal.SIGINT)
    assert stop.requested and stop.signal == signal.SIGTERM and stop.repeated == 2
    assert stop.outcome(stop.reason(lockstep_result=None, context_ok=True)) == Outcome(
        0, "SIGTERM received: shutting down")


@pytest.mark.parametrize("signum", HANDLED_SIGNALS)
def test_a_signal_ends_with_status_zero_whatever_else_happened(signum):
    for lockstep_result in (None, True, False):
        for context_ok in (True, False):
            stop = Shutdown()
            stop.request(signum)
            reason = stop.reason(lockstep_result=lockstep_result, context_ok=context_ok)
            assert reason is StopReason.SIGNAL
            status, message = stop.outcome(reason)
            assert status == 0 and message == f"{signal.Signals(signum).name} received: " \
                                               "shutting down"


def test_lockstep_results_and_a_context_shut_down_elsewhere():
    stop = Shutdown()
    finished = stop.reason(lockstep_result=True, context_ok=True)
    diverged = stop.reason(lockstep_result=False, context_ok=False)
    external = stop.reason(lockstep_result=None, context_ok=False)
    assert (finished, diverged, external) == (StopReason.FINISHED, StopReason.DIVERGED,
                                              StopReason.CONTEXT)
    # The lockstep tick logs where the run ended; the end adds no line of its own.
    assert stop.outcome(finished) == Outcome(0, "")
    assert stop.outcome(diverged) == Outcome(1, "")
    assert stop.outcome(external) == Outcome(0, "the ROS context was shut down: stopping")
    with pytest.raises(ValueError, match="no reason to stop"):
        stop.reason(lockstep_result=None, context_ok=True)


def test_a_real_signal_wakes_the_waiting_worker_and_ends_it():
    """The worker's wait has no timeout (as the node's executor waits): only the handler's
    wake ends it. The signal may be delivered to the worker's thread, where Python does not
    run handlers; the main thread, waiting in turns of POLL_S, runs it."""
    stop = Shutdown()
    woken = threading.Event()
    stop.wake = woken.set
    turns: list[str] = []

    def run_callbacks() -> None:
        while not stop.requested:
            turns.append(threading.current_thread().name)
            if len(turns) == 3:
                os.kill(os.getpid(), signal.SIGINT)
                assert woken.wait(timeout=60.0), "the handler never woke the worker"
    previous = signal.signal(signal.SIGINT, stop.request)
    try:
        serve([run_callbacks], stop)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert turns == ["run_callbacks"] * 3
    assert stop.signal == signal.SIGINT and stop.repeated == 0


def test_only_the_first_request_wakes_the_worker():
    stop = Shutdown()
    wakes: list[None] = []
    stop.wake = lambda: wakes.append(None)
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGINT):
        stop.request(signum)
    assert len(wakes) == 1 and stop.repeated == 2


def test_a_worker_that_raises_stops_the_others_and_its_error_is_raised():
    stop = Shutdown()
    woken = threading.Event()
    stop.wake = woken.set

    def run_callbacks() -> None:
        raise RuntimeError(f"raised in {threading.current_thread().name}")

    def ticks() -> None:
        assert woken.wait(timeout=60.0), "the failure never woke the other worker"
    with pytest.raises(RuntimeError, match="raised in run_callbacks"):
        serve([run_callbacks, ticks], stop, poll_s=0.01)
    assert stop.failed and stop.requested and stop.signal is None
    assert not {"run_callbacks", "ticks"} & {t.name for t in threading.enumerate()}  # joined


def test_serve_returns_when_the_workers_end():
    ran = []
    serve([lambda: ran.append(threading.current_thread() is threading.main_thread())] * 2,
          Shutdown())
    assert ran == [False, False]


class FakeTime(threading.Event):
    """A clock that a wait moves on by its timeout (or not at all once set)."""

    def __init__(self) -> None:
        super().__init__()
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def wait(self, timeout=None) -> bool:
        if not self.is_set() and timeout is not None and timeout > 0:
            self.now += timeout
        return self.is_set()


def test_ticks_come_every_period_and_a_late_one_is_followed_by_the_next_due():
    """An rcl timer's schedule: start + k period; after a tick that took 3.5 periods, one
    tick at once (its time was due), then the next multiple of the period, none missed
    made up in a burst."""
    fake = FakeTime()
    times: list[float] = []

    def tick() -> None:
        times.append(fake.now)
        if len(times) == 3:
            fake.now += 0.07
    tick_every(0.02, tick, lambda: len(times) >= 6, fake, clock=fake)
    assert [t - 100.0 for t in times] == pytest.approx(
        [0.02, 0.04, 0.06, 0.13, 0.14, 0.16], abs=1e-9)


def test_a_tick_that_names_its_next_sets_when_that_one_comes():
    """A tick that returns seconds sets the next one that long after the clock read before
    it (the node's next publish instant), a tick that returns None an rcl timer's next: the
    first two ticks name theirs, 0.013 s and then 0.031 s on, the rest keep the period from
    the last."""
    fake = FakeTime()
    times: list[float] = []

    def tick() -> Optional[float]:
        times.append(fake.now)
        return [0.013, 0.031][len(times) - 1] if len(times) <= 2 else None
    tick_every(0.02, tick, lambda: len(times) >= 5, fake, clock=fake)
    assert [t - 100.0 for t in times] == pytest.approx(
        [0.02, 0.033, 0.064, 0.084, 0.104], abs=1e-9)


def test_the_stop_ends_the_ticks_without_another_one():
    fake = FakeTime()
    times: list[float] = []

    def tick() -> None:
        times.append(fake.now)
        if len(times) == 2:
            fake.set()
    tick_every(0.02, tick, fake.is_set, fake, clock=fake)
    assert len(times) == 2
