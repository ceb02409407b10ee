"""A live session of the node, simulated without ROS, recorded as ``ros2 bag record`` would.

The node's loop is the one :class:`~hecker_dynamics.ros.node.DynamicsNode` runs: a timer on
the ROS clock that fires late (and now and then after a stall, in a burst), input callbacks
between ticks, and everything published through the same field functions. The recorder
subscribes to each topic a little after its own start (as its topic discovery does), gets
the latest messages of the transient_local topics on subscribing, and logs every message at
its arrival, a small random delay after it was published (in order per topic).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from hecker_dynamics.bags import io as bags
from hecker_dynamics.bags.io import resolve_topic
from hecker_dynamics.bags.replay import APPLIED_WRENCH_TOPIC, output_message, snapshot_messages
from hecker_dynamics.dynamics import Snapshot
from hecker_dynamics.ros.cmd_vel import cmd_vel_topics
from hecker_dynamics.ros.fields import applied_wrench_fields
from hecker_dynamics.ros.joint_states import motor_topics
from hecker_dynamics.ros.outputs import SnapshotOutputs
from hecker_dynamics.ros.runner import Runner, Tick, TickAction, plan_tick
from hecker_dynamics.ros.session import (
    INPUT_EVENTS_DEPTH,
    KEYFRAME_DEPTH,
    SESSION_DEPTH,
    WORLD_EVENTS_DEPTH,
    InputEventFields,
    KeyframeFields,
    SessionFields,
    WorldEventFields,
)
from hecker_dynamics.scene import Scene, WrenchCommand

S = 1_000_000_000
NODE = "/dynamics_node"
#: Session record topics as the node resolves them, with their message builders and depths.
RECORDS = {
    SessionFields: (f"{NODE}/session", bags.SESSION_INFO, bags.session_info_message,
                    SESSION_DEPTH),
    KeyframeFields: (f"{NODE}/keyframe", bags.KEYFRAME, bags.keyframe_message, KEYFRAME_DEPTH),
    InputEventFields: (f"{NODE}/input_events", bags.INPUT_EVENT, bags.input_event_message,
                       INPUT_EVENTS_DEPTH),
    WorldEventFields: (f"{NODE}/world_events", bags.WORLD_EVENT, bags.world_event_message,
                       WORLD_EVENTS_DEPTH),
}


@dataclass
class Published:
    topic: str
    msgtype: str
    publish_ns: int
    msg: Any
    depth: Optional[int] = None  # keep-last depth of a transient_local topic


@dataclass
class LiveSession:
    """What was published, in order, and the options it ran with."""

    scene: Scene
    published: list[Published] = field(default_factory=list)
    start_ns: int = 0
    end_ns: int = 0

    def publish(self, tick: Tick, at_ns: int, world: Scene) -> None:
        """The node's outputs for the snapshots and sensor readings of ``tick`` in the
        world ``world`` (the scene with the bodies spawned and deleted so far), published
        at ROS time ``at_ns``."""
        for stamp, item in tick.in_order():
            outputs = snapshot_messages(world, item, tf=True, base=self.scene) \
                if isinstance(item, Snapshot) else [output_message(item, stamp)]
            for output in outputs:
                self.published.append(Published(output.topic, output.msgtype, at_ns,
                                                output.msg))


def _input_message(scene: Scene, rng: np.random.Generator, arrival_ns: int,
                   previous: list[Any]) -> Any:
    """An AppliedWrench as a user would send one: early, late, zero-stamped, replacing an
    earlier one, out of order, a duplicate, or (rarely) bad."""
    roll = rng.random()
    if previous and roll < 0.08:
        return previous[int(rng.integers(len(previous)))]  # duplicated
    bodies = [b.name for b in scene.bodies]
    body = bodies[int(rng.integers(len(bodies)))]
    kind = rng.random()
    if kind < 0.25:
        stamp = 0                                              # "now"
    elif kind < 0.55:
        stamp = arrival_ns - int(rng.uniform(0, 0.3) * S)      # late: behind the clock
    elif kind < 0.85:
        stamp = arrival_ns + int(rng.uniform(0, 0.3) * S)      # early
    else:
        stamp = arrival_ns - int(rng.uniform(0.3, 2.0) * S)    # out of order, maybe ended
    force = (float(rng.normal(0, 30)), float(rng.normal(0, 30)))
    if rng.random() < 0.03:
        force = (math.nan, 0.0)                                # rejected by the node
    if rng.random() < 0.02:
        body = "ghost"                                         # rejected: unknown body
    frame = "world" if rng.random() < 0.5 else (body if body != "ghost" else "world")
    duration = 0 if rng.random() < 0.3 else int(rng.uniform(0.01, 0.5) * S)
    source = f"src{int(rng.integers(3))}"                      # replaces one of three
    command = WrenchCommand(stamp, body, source, frame,
                            (float(rng.uniform(-0.2, 0.2)), float(rng.uniform(-0.1, 0.1))),
                            force, float(rng.normal(0, 1)), duration)
    return bags.applied_wrench_msg(applied_wrench_fields(command))


#: A call of the spawn or delete service: ("spawn", name, YAML, collision groups) or
#: ("delete", name).
BodyCall = tuple[Any, ...]


def run_live(scene: Scene, seed: int, *, duration_ns: int = 4 * S, inputs: int = 25,
             play_script: bool = True, keyframe_period_ns: int = S,
             max_steps: Optional[int] = None, reset_at: Optional[int] = None,
             record: bool = True, lockstep: bool = False, world: int = 0,
             bodies: Sequence[tuple[int, BodyCall]] = (), motors: int = 0,
             cmd_vels: int = 0) -> LiveSession:
    """Run the node's loop for ``duration_ns`` of ROS time with a jittered timer and
    ``inputs`` messages at random arrival times; ``reset_at`` (ns after the start) calls the
    reset service once; ``world`` times the world services are called (pause, a few steps,
    a body moved, resume; and a call refused now and then); ``bodies`` spawns and deletes
    bodies, each call at its time (ns after the start); ``motors`` speed commands go to
    the scene's motor topics (one in ten not finite, which the node refuses), and
    ``cmd_vels`` twists to its driven bodies' cmd_vel topics (likewise). In
    ``lockstep`` the simulation starts at sim time 0, each tick steps one publish period,
    and a message arrives at the sim time it finds."""
    rng = np.random.default_rng(seed)
    t0 = 1_700_000_000 * S + int(rng.integers(S))
    period = scene.publish_period_ns
    ticks, now = [], t0
    while now < t0 + duration_ns:
        now += period
        late = rng.exponential(0.002 * S) if rng.random() > 0.05 else rng.uniform(0.05, 0.3) * S
        ticks.append(int(now + late))
    ticks.sort()
    arrivals = sorted(int(t0 + rng.uniform(0, duration_ns)) for _ in range(inputs))
    timeline = sorted([(t, 1, None) for t in ticks] + [(t, 0, "input") for t in arrivals]
                      + ([(t0 + reset_at, 0, "reset")] if reset_at is not None else [])
                      + [(int(t0 + rng.uniform(0, duration_ns)), 0, "world")
                         for _ in range(world)]
                      + [(int(t0 + rng.uniform(0, duration_ns)), 0, "motor")
                         for _ in range(motors)]
                      + [(int(t0 + rng.uniform(0, duration_ns)), 0, "cmd_vel")
                         for _ in range(cmd_vels)]
                      + [(t0 + at, 0, f"body:{n}") for n, (at, _) in enumerate(bodies)])
    runner = Runner(scene, play_script=play_script, max_steps=max_steps, started=lockstep,
                    record=record, keyframe_period_ns=keyframe_period_ns, lockstep=lockstep,
                    wall_clock=lambda: int(rng.integers(10**6)))
    session = LiveSession(scene, start_ns=t0, end_ns=t0 + duration_ns)
    sent: list[Any] = []
    last_tick: Optional[int] = None

    shown = [SnapshotOutputs(runner.scene, base=scene)]

    def publish_records(at_ns: int) -> None:
        for record in runner.take_records():
            topic, msgtype, build, depth = RECORDS[type(record)]
            session.published.append(Published(topic, msgtype, at_ns, build(record), depth))
        if shown[0].scene is not runner.scene:  # the node's _follow_world
            previous = shown[0]
            shown[0] = SnapshotOutputs(runner.scene, base=scene)
            for gone in shown[0].markers_gone(previous, runner.sim.time_ns):
                session.published.append(Published(resolve_topic(gone.topic), bags.MARKER_ARRAY,
                                                   at_ns, bags.marker_array_message(gone.fields)))

    for at_ns, _, what in timeline:
        now_ns = runner.sim.time_ns if lockstep else at_ns  # the node's _now_ns
        if what == "input":
            msg = _input_message(runner.scene, rng, now_ns, sent)
            sent.append(msg)
            session.published.append(Published(APPLIED_WRENCH_TOPIC, bags.APPLIED_WRENCH,
                                               at_ns - int(rng.integers(S // 1000)), msg))
            runner.accept(APPLIED_WRENCH_TOPIC, msg, now_ns)
        elif what == "world":
            _change_world(runner, rng, now_ns, session, at_ns)
        elif what is not None and what.startswith("body:"):
            call = bodies[int(what[5:])][1]
            if call[0] == "spawn":
                runner.spawn_body(*call[1:])
            else:
                runner.delete_body(*call[1:])
        elif what == "motor":
            motor = motor_topics(scene)[int(rng.integers(len(motor_topics(scene))))]
            speed = float(rng.uniform(-4.0, 4.0)) if rng.random() > 0.1 else math.nan
            msg = bags.default_message(bags.FLOAT64, data=speed)
            topic = resolve_topic(motor.topic)
            session.published.append(Published(topic, bags.FLOAT64,
                                               at_ns - int(rng.integers(S // 1000)), msg))
            runner.accept(topic, msg, now_ns, motor)
        elif what == "cmd_vel":
            driven = cmd_vel_topics(scene)[int(rng.integers(len(cmd_vel_topics(scene))))]
            turn = float(rng.uniform(-1.0, 1.0)) if rng.random() > 0.1 else math.inf
            vector = "geometry_msgs/msg/Vector3"
            msg = bags.default_message(
                bags.TWIST, linear=bags.default_message(vector, x=float(rng.uniform(-0.5, 1.0))),
                angular=bags.default_message(vector, z=turn))
            topic = resolve_topic(driven.topic)
            session.published.append(Published(topic, bags.TWIST,
                                               at_ns - int(rng.integers(S // 1000)), msg))
            runner.accept(topic, msg, now_ns, driven)
        elif what == "reset":
            if runner.started:
                runner.restart(now_ns, "reset")
                last_tick = at_ns
        else:
            if lockstep:
                target = runner.sim.time_ns + period
            else:
                action, _ = plan_tick(at_ns, last_tick)
                if action is TickAction.START:
                    runner.restart(at_ns, "start")
                last_tick = target = at_ns
            session.publish(runner.advance(target), at_ns, runner.scene)
        publish_records(at_ns)
    return session


def _change_world(runner: Runner, rng: np.random.Generator, now_ns: int,
                  session: LiveSession, at_ns: int) -> None:
    """One service call as a user makes it: pause, step a few times, move a body, resume
    (or, a tenth of the time, a call the node refuses)."""
    if rng.random() < 0.1:
        runner.resume(now_ns)  # refused: not paused
        return
    runner.pause()
    for _ in range(int(rng.integers(3))):
        _, tick = runner.step(int(rng.integers(1, 40)))
        session.publish(tick, at_ns, runner.scene)
    bodies = runner.scene.bodies
    body = bodies[int(rng.integers(len(bodies)))].name
    runner.set_body_state(body, tuple(float(x) for x in rng.uniform(-1, 1, 6)))
    runner.resume(now_ns + int(rng.uniform(0, 0.5) * S))


#: The types of the messages a user sends the node.
INPUT_TYPES = frozenset({bags.APPLIED_WRENCH, bags.WRENCH_STAMPED, bags.FLOAT64})


def _appears(first: Published, node_start_ns: int, period_ns: int) -> int:
    """When the publisher of ``first``'s topic appears: the node's records and outputs at
    the node's start (a spawned body's a publish period before its first message), a
    user's input publisher when it sends its first message."""
    if first.msgtype in INPUT_TYPES:
        return first.publish_ns
    if first.depth is not None:
        return node_start_ns
    return max(node_start_ns, first.publish_ns - period_ns)


def record(session: LiveSession, path: Path, seed: int, *, late_ns: int = 0,
           discovery_ns: int = 50_000_000, stop_ns: Optional[int] = None,
           drop: Callable[[int, Published], bool] = lambda index, item: False) -> Path:
    """Write what a recorder started ``late_ns`` after the node and stopped ``stop_ns``
    after the node's start (None: after the node) would have logged, less the messages
    ``drop`` picks (by their index among the logged ones, and their content).

    As ``ros2 bag record -a`` does, the recorder subscribes to a topic once it has seen
    its publisher: within ``discovery_ns`` of its own start, or of the topic's appearance
    for a topic that appears later (a spawned body's, about a publish period before its
    first message; an input topic's, at its first message, which is lost). On stopping,
    it drops its subscriptions one by one within a few milliseconds."""
    rng = np.random.default_rng(seed + 1000)
    start = session.start_ns + late_ns
    period = session.scene.publish_period_ns
    first: dict[str, Published] = {}
    for item in session.published:
        first.setdefault(item.topic, item)
    appear = {topic: _appears(item, session.start_ns, period) for topic, item in first.items()}
    subscribed = {topic: max(start, appear[topic]) + int(rng.uniform(0, discovery_ns))
                  for topic in first}
    stopping = np.random.default_rng(seed + 2000)
    unsubscribed = {topic: (session.start_ns + stop_ns + int(stopping.integers(5_000_000))
                            if stop_ns is not None else None) for topic in first}
    logged: list[tuple[int, int, Published]] = []
    last_log: dict[str, int] = {}
    latched: dict[str, list[Published]] = {}
    for order, item in enumerate(session.published):
        at = subscribed[item.topic]
        if item.publish_ns < at:
            if item.depth is not None:
                kept = latched.setdefault(item.topic, [])
                kept.append(item)
                del kept[:-item.depth]
            continue
        log = max(last_log.get(item.topic, 0), item.publish_ns + int(rng.integers(1, S // 500)))
        last_log[item.topic] = log
        end = unsubscribed[item.topic]
        if end is None or log < end:
            logged.append((log, order, item))
    for topic, kept in latched.items():  # delivered on subscribing, before anything newer
        for n, item in enumerate(kept):
            logged.append((subscribed[topic] + n, -len(kept) + n, item))
    logged.sort(key=lambda entry: (entry[0], entry[1]))
    types = {p.topic: (p.msgtype, p.depth) for p in session.published}
    with bags.BagWriter(path, "mcap") as writer:
        for topic, (msgtype, depth) in types.items():
            writer.add_topic(topic, msgtype, None if depth is None else bags.latched_qos(depth))
        for index, (log, _, item) in enumerate(logged):
            if not drop(index, item):
                writer.write(item.topic, item.msgtype, log, item.msg)
    return path
