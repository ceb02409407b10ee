"""The world services (pause, resume, step, set_body_state) through the run loop the node
drives: their effect on the simulation, their refusals, and their records."""
from __future__ import annotations

import math

import pytest

from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.ros.session import WorldChange
from hecker_dynamics.scene import load_scene

S = 1_000_000_000


@pytest.fixture
def runner() -> Runner:
    runner = Runner(load_scene("sample"), start_ns=5 * S, record=True)
    runner.advance(6 * S)
    runner.take_records()
    return runner


def test_a_paused_simulation_stands_still_and_steps_exactly_when_asked(runner):
    step = runner.sim.step_ns
    before = runner.sim.snapshot()
    assert runner.pause().accepted
    assert runner.advance(9 * S).snapshots == [] and runner.sim.snapshot() == before
    record, tick = runner.step(45)
    assert record.accepted and record.values == (45.0,) and record.stamp_ns == 6 * S
    assert runner.sim.time_ns == 6 * S + 45 * step and runner.paused
    period = runner.scene.publish_period_ns
    assert [s.time_ns for s in tick.snapshots] == [6 * S + k * period
                                                   for k in range(1, 45 * step // period + 1)]


def test_resume_skips_the_paused_time_to_a_publish_instant(runner):
    runner.pause()
    runner.step(7)
    paused_at, start = runner.sim.time_ns, runner.sim.start_ns
    record = runner.resume(paused_at + 3 * S + 1)
    period = runner.scene.publish_period_ns
    assert record.accepted and record.time_ns == runner.sim.time_ns
    assert runner.sim.time_ns >= paused_at + 3 * S + 1 > runner.sim.time_ns - period
    assert runner.sim.time_ns - runner.sim.start_ns == paused_at - start  # the start moved too
    assert [s.time_ns % period for s in runner.advance(runner.sim.time_ns + S).snapshots] == \
        [start % period] * 50


def test_set_body_state_puts_the_body_frame_where_asked(runner):
    values = (0.25, 1.5, 2.0, -0.5, 0.75, 3.0)
    assert runner.set_body_state("left", values).accepted
    left = next(b for b in runner.sim.snapshot().bodies if b.name == "left")
    assert left.position == pytest.approx(values[:2], abs=1e-15)
    assert left.angle == pytest.approx(values[2], abs=1e-15)
    assert left.linear_velocity == pytest.approx(values[3:5], abs=1e-15)
    assert left.angular_velocity == values[5]


@pytest.mark.parametrize("call,reason", [
    (lambda r: r.resume(10 * S), "not paused"),
    (lambda r: r.step(3)[0], "needs a paused simulation"),
    (lambda r: r.set_body_state("ghost", (0.0,) * 6), "unknown body 'ghost'"),
    (lambda r: r.set_body_state("left", (math.nan,) + (0.0,) * 5), "non-finite"),
    (lambda r: r.set_body_state("left", (0.0,) * 5), "6 values"),
])
def test_bad_calls_are_refused_with_a_reason_and_change_nothing(runner, call, reason):
    before = runner.sim.export_state()
    record = call(runner)
    assert not record.accepted and reason in record.reason
    assert runner.sim.export_state() == before
    assert runner.take_records() == [record]


def test_changes_share_the_input_events_sequence(runner):
    first = runner.sequence
    kinds = [runner.pause().kind, runner.step(2)[0].kind, runner.resume(0).kind]
    assert kinds == [WorldChange.PAUSE, WorldChange.STEP, WorldChange.RESUME]
    assert [r.sequence for r in runner.take_records()] == [first, first + 1, first + 2]
    assert runner.sequence == first + 3
