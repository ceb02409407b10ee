"""The node's stop decisions without ROS: signals, lockstep results, the spin loop.

The rclpy side (a node process that gets SIGINT or SIGTERM) is in test_node_process.py.
"""
from __future__ import annotations

import os
import signal

import pytest

from hecker_dynamics.ros.lifecycle import (HANDLED_SIGNALS, POLL_S, Outcome, Shutdown,
                                           StopReason, spin_until)


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


def test_a_real_signal_during_a_callback_ends_the_loop_before_the_next_one():
    """The handler only records the signal: the callback that was running finishes (no
    KeyboardInterrupt inside it), and no callback runs after it."""
    stop = Shutdown()
    calls: list[float] = []
    published_after_signal = []

    def spin_once(timeout: float) -> None:
        calls.append(timeout)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)   # arrives in the middle of this callback
            published_after_signal.append(stop.requested)
    previous = signal.signal(signal.SIGINT, stop.request)
    try:
        spin_until(spin_once, lambda: stop.requested or len(calls) > 10)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert calls == [POLL_S] * 3
    assert stop.signal == signal.SIGINT
    # Python runs the handler between bytecodes, so by the end of the callback it has run.
    assert published_after_signal == [True]


def test_spin_until_checks_before_every_turn():
    calls = []
    spin_until(calls.append, lambda: True)
    assert calls == []
    spin_until(calls.append, lambda: len(calls) >= 4, poll_s=0.25)
    assert calls == [0.25] * 4
