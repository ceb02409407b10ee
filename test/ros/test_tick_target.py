"""The node's ticks step to the last publish instant at or before the clock
(:func:`~hecker_dynamics.ros.runner.tick_target`) and wake just after the next one
(:func:`~hecker_dynamics.ros.runner.next_tick_in`). A tick that went on a step or two past
an instant, or stopped a step short of it, as a wake on the wall clock lands, takes a stop
at the instant and a second run for those steps; on the instants each tick is one run, and
since every decision is made at sim instants, the outputs are the same bits."""
from __future__ import annotations

import pytest

from hecker_dynamics.bench.sensors import robot_at_1khz
from hecker_dynamics.dynamics.simulation import Snapshot
from hecker_dynamics.ros import runner as runner_module
from hecker_dynamics.ros.cdr import SnapshotSerializer, serialize_output
from hecker_dynamics.ros.outputs import SnapshotOutputs
from hecker_dynamics.ros.runner import TICK_MARGIN_NS, Runner, next_tick_in, tick_target
from hecker_dynamics.scene.load import Scene, load_scene

MS = 1_000_000
START = 1_765_000_000_123_456_789  # a wall-clock start, off every round number


def test_a_tick_steps_to_the_last_publish_instant_at_or_before_its_clock():
    period = 20 * MS
    assert tick_target(START, START, period) == START
    assert tick_target(START + period - 1, START, period) == START
    assert tick_target(START + period, START, period) == START + period
    assert tick_target(START + 3 * period + 66_000, START, period) == START + 3 * period
    assert tick_target(START + 5 * period - 66_000, START, period) == START + 4 * period
    assert tick_target(START - 5 * MS, START, period) == START  # a clock behind the start


def test_the_next_tick_is_due_just_after_the_next_publish_instant():
    period = 20 * MS
    assert next_tick_in(START, START, period) == period + TICK_MARGIN_NS
    late = START + 7 * period + 381_000  # a wake 0.381 ms after its instant
    assert late + next_tick_in(late, START, period) == START + 8 * period + TICK_MARGIN_NS
    early = START + 7 * period - 66_000  # a wake before its instant
    assert early + next_tick_in(early, START, period) == START + 7 * period + TICK_MARGIN_NS
    assert 0 < TICK_MARGIN_NS < MS // 2  # well inside a step of the fastest shipped scene


@pytest.fixture
def runs(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The runs the node's loop takes (:func:`advance_with_drives` calls), counted."""
    counted: list[int] = []
    advance = runner_module.advance_with_drives

    def run(*args, **kwargs):  # type: ignore[no-untyped-def]
        counted.append(1)
        return advance(*args, **kwargs)
    monkeypatch.setattr(runner_module, "advance_with_drives", run)
    return counted


def node_ticks(scene: Scene, clock_ns: list[int], to_instants: bool
               ) -> list[tuple[int, bytes]]:
    """Every output the node publishes for ticks at ``clock_ns`` (from the start), stepping
    to the clock itself (main's node) or to the last instant before it, with their stamps."""
    runner = Runner(scene, start_ns=START)
    serialize = SnapshotSerializer(SnapshotOutputs(scene))
    period = scene.publish_period_ns
    out: list[tuple[int, bytes]] = []
    for now in clock_ns:
        target = tick_target(START + now, START, period) if to_instants else START + now
        tick = runner.advance(target)
        assert tick.diverged is None and not tick.script_errors
        for stamp, item in tick.in_order():
            if isinstance(item, Snapshot):
                out += [(stamp, data) for _, data in serialize(item)]
            else:
                out.append((stamp, serialize_output(item)))
    return out


@pytest.mark.parametrize("scene", [robot_at_1khz(), load_scene("robot")],
                         ids=["robot at 1 kHz", "robot at 2 ms"])
@pytest.mark.parametrize("offset_ns", [-66_000, 381_000, 1_200_000])
def test_ticks_on_the_instants_take_one_run_each_and_publish_the_same_bits(
        scene: Scene, offset_ns: int, runs: list[int]) -> None:
    """The robot scene (drive, IMU, laser, contacts) over 3 s of ticks a fixed offset off
    their instants, as the live node's land: main's node stepping to the clock took two
    runs a tick wherever the offset crosses a step; stepping to the instants takes one, and
    every output's bytes and stamps are the same, the last tick ending both on an instant."""
    period = scene.publish_period_ns
    count = 150
    clock = [k * period + offset_ns for k in range(1, count)] + [count * period]
    on_clock = node_ticks(scene, clock, to_instants=False)
    runs_on_clock = len(runs)
    runs.clear()
    on_instants = node_ticks(scene, clock, to_instants=True)
    assert on_instants == on_clock and len(on_clock) > 8 * count
    crosses_a_step = offset_ns < 0 or offset_ns >= scene.step_ns
    assert runs_on_clock == (2 * count - 1 if crosses_a_step else count)
    # Ticks before their instants step to the one before: the first none, the last two.
    assert len(runs) == count
