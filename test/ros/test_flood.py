"""Bounded memory under a flood of input: 200,000 messages (20 s of a 10 kHz flood) through
the node's glue-free path.

On Jazzy a flood of 10,000 AppliedWrench messages a second grew the node by about 115
bytes per message and kept it: rclpy's ``spin_once_until_future_complete`` adds a
done-callback to the future at every turn of ``spin_until_future_complete``, and the
node's future never completes outside lockstep. The node now runs its callbacks with
``wait_for_ready_callbacks`` (:func:`hecker_dynamics.ros.node.run_callbacks`);
test_node_process.py floods a real node.
Here the node's own per-message work (Runner.accept with the conversion and the session
record of the input, taken after each message as the node publishes it; the rate-limited
log lines; Runner.advance at every tick and the outputs of every snapshot, as the node
calls them) must keep no state per message: the input buffer keeps one command per
(body, id), the rate limiter one entry per key, the runner its counters.
"""
from __future__ import annotations

import gc
import math
import sys
import tracemalloc
from types import SimpleNamespace

import pytest
from scene_builders import box_body, make_scene

from hecker_dynamics.dynamics.inputs import InputBuffer
from hecker_dynamics.ros.outputs import SnapshotOutputs
from hecker_dynamics.ros.ratelimit import RateLimiter
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.scene.commands import InputError, WrenchCommand

MESSAGES = 200_000
#: The last TRACED messages run under tracemalloc: the first half of them lets every
#: bounded structure (the buffer's 50 held commands, the limiter's keys) be replaced by
#: objects allocated while tracing; the second half must then add next to nothing.
TRACED = 40_000
#: What the second traced half may add, in bytes: 4 KiB, less than 0.2 byte per message
#: (the leak seen on Jazzy was 115 bytes per message, 2.3 MB over 20,000 messages). A
#: bounded structure that resizes (a dict of the 50 ids, a heap of pending commands) may
#: move by a few hundred bytes; measured: +568 to +648 bytes over 20,000 messages.
TRACED_GROWTH_LIMIT = 4096
#: Messages between two ticks: 200 at the 50 Hz publish rate is the 10,000 a second of the
#: Jazzy flood.
PER_TICK = 200
IDS = 50


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> SimpleNamespace:
    return SimpleNamespace(x=x, y=y, z=z)


def _message(body: str, source: str, force_x: float, frame_id: str = "") -> SimpleNamespace:
    """An AppliedWrench with the ROS field names, stamped zero (on arrival), held."""
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=0, nanosec=0), frame_id=frame_id),
        body=body, id=source, point=_vector(0.1), duration=SimpleNamespace(sec=0, nanosec=0),
        wrench=SimpleNamespace(force=_vector(force_x), torque=_vector(z=0.5)))


def _live_blocks() -> int:
    """Blocks held by live objects: a full collection first empties the free lists.

    Python keeps freed floats, tuples and dicts on free lists for reuse, and those blocks
    count as allocated; how full the lists are depends on what ran before in the process
    (under pytest-xdist, other tests), and moved a bare count by 3,800 blocks in CI.
    """
    gc.collect()
    return sys.getallocatedblocks()


def test_a_flood_of_messages_keeps_memory_flat():
    # Semi-implicit Euler: one force evaluation a step; the flood, not the method, is tested.
    scene = make_scene({"step": 0.01, "publish_rate": 50.0, "input_timeout": 0.5,
                        "integrator": "semi_implicit_euler",
                        "publish": {"markers": True, "odometry": True},
                        "bodies": {"a": box_body(points={"tip": [0.5, 0.0]}),
                                   "b": box_body(position=[3.0, 0.0])}})
    runner = Runner(scene, max_steps=1000, wall_clock=lambda: 0, record=True,
                    keyframe_period_ns=1_000_000_000)
    outputs_of = SnapshotOutputs(scene)
    limiter = RateLimiter(clock=lambda: runner.sim.time_ns)
    # Good messages from 50 ids on both bodies and frames, and rejected ones: NaN, an
    # unknown body, an unknown frame. Reused, as rclpy hands each callback a new message
    # that is freed after it.
    good = [_message("ab"[i % 2], f"sender{i}", 1.0, ("", "a/tip", "world")[i % 3])
            for i in range(IDS)]
    bad = [_message("a", "nan", math.nan), _message("ghost", "g", 1.0),
           _message("b", "f", 1.0, frame_id="b/nowhere")]
    cycle = good + bad
    published = logged = records = 0
    now_ns = 0

    def flood(count: int, first: int) -> None:
        nonlocal published, logged, records, now_ns
        for k in range(first, first + count):
            for line in runner.accept("/applied_wrench", cycle[k % len(cycle)], now_ns):
                logged += limiter.line(line.key, line.message) is not None
            records += len(runner.take_records())
            if k % PER_TICK == PER_TICK - 1:
                now_ns += scene.publish_period_ns
                tick = runner.advance(now_ns)
                records += len(runner.take_records())
                for snapshot in tick.snapshots:
                    published += len(outputs_of(snapshot))

    blocks = []
    untraced = MESSAGES - TRACED
    chunk = untraced // 4
    for part in range(4):
        flood(chunk, part * chunk)
        blocks.append(_live_blocks())
    tracemalloc.start()
    try:
        flood(TRACED // 2, untraced)
        gc.collect()
        settled = tracemalloc.get_traced_memory()[0]
        flood(TRACED // 2, untraced + TRACED // 2)
        gc.collect()
        final = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()

    # The flood did what the node does: both kinds of input, every tick published.
    assert runner.accepted + runner.rejected == MESSAGES
    assert runner.rejected == MESSAGES // len(cycle) * len(bad) + \
        max(0, MESSAGES % len(cycle) - len(good))
    assert runner.halted is None and runner.sim.time_ns == now_ns
    # One input event per message, and the keyframes (one a second of sim time).
    assert records >= MESSAGES
    ticks = MESSAGES // PER_TICK
    assert published == ticks * (2 * 3 + 2)    # pose, twist, odom per body; markers; /tf
    # Rate-limited: a line per key every 5 s of sim time at most, not one per message.
    assert 0 < logged <= 3 * (now_ns // 5_000_000_000 + 1)
    # Flat: about as many live objects after 160,000 messages as after 80,000 (a leak of
    # one object per message would add 80,000 blocks; measured: +1), and next to no traced
    # growth. The first quarter may still fill bounded structures (measured: +3
    # blocks between the first and the second sample).
    assert blocks[-1] - blocks[1] < 100, blocks
    assert final - settled <= TRACED_GROWTH_LIMIT, (settled, final)


class _CountedKeys(dict):
    """A dict that counts the calls of ``keys()``: the input buffer's union of its active
    and pending sources."""

    calls = 0

    def keys(self):  # type: ignore[override]
        _CountedKeys.calls += 1
        return super().keys()


def test_the_cap_on_input_sources_is_exact_without_a_union_per_message():
    """1,000 sources at once (``max_active``), active or pending: the 1,001st is refused,
    a known one replaced. A flood of new ids at the cap built the union of both sets, 1,000
    keys, for each message (5.3 s for 100,000 messages through the runner, 1.5 s from one
    id or with this change); it is built only where its size is not known from theirs."""
    buffer = InputBuffer(timeout_ns=0)
    buffer._active, buffer._pending_keys = _CountedKeys(), _CountedKeys()

    def add(source: str, stamp_ns: int = 0) -> bool:
        try:
            buffer.add(WrenchCommand(stamp_ns, "a", source, "world", (0.0, 0.0), (1.0, 0.0),
                                     0.0), None)  # type: ignore[arg-type]
        except InputError as error:
            assert "more than 1000 input sources at once" in str(error)
            return False
        return True

    assert all(add(f"s{i}") for i in range(600))
    buffer.update(0)  # 600 active
    assert all(add(f"t{i}", 10) for i in range(400))  # 400 pending: 1,000 sources
    assert not add("late", 10) and add("s5", 10) and add("t5", 10)  # new refused, known taken
    buffer.update(10)  # 1,000 active
    _CountedKeys.calls = 0
    assert not any(add(f"flood{i}") for i in range(5000))
    assert _CountedKeys.calls == 0
    assert len(buffer) == 1000


@pytest.mark.parametrize("resent, taken", [(400, True), (100, False)])
def test_sources_active_and_pending_at_once_count_once(resent, taken):
    """600 sources active and 500 pending (``resent`` of them active ones sent again):
    1,100 keys, but 1,100 - ``resent`` sources, so a new one is taken below the cap of
    1,000 (700 sources) and refused at it (1,000), however many keys the two sets hold."""
    buffer = InputBuffer(timeout_ns=0)

    def add(source: str, stamp_ns: int) -> None:
        buffer.add(WrenchCommand(stamp_ns, "a", source, "world", (0.0, 0.0), (1.0, 0.0), 0.0),
                   None)  # type: ignore[arg-type]

    for i in range(600):
        add(f"s{i}", 0)
    buffer.update(0)
    for i in range(500):
        add(f"s{i}" if i < resent else f"t{i}", 10)
    if taken:
        add("new", 10)
    else:
        with pytest.raises(InputError, match="more than 1000 input sources at once"):
            add("new", 10)
