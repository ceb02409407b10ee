"""Offline replay: drive :class:`Simulation` from the commands in a bag, as the node would.

The rules are the node's (``hecker_dynamics.ros.node``, non-lockstep):

- The simulation starts at ``start_ns`` and ticks every publish period; each tick pushes the
  scene's scripted commands that are due (only with ``play_script``), steps up to the tick
  and publishes the snapshots it passed (at the publish instants ``start + k * period``).
- A message that arrives between two ticks (its bag log time is the arrival time) is
  mapped by :mod:`hecker_dynamics.ros.fields` with its log time as receive time (a zero header
  stamp means "on arrival") and pushed while the simulation stands at the earlier tick.
  Stamps decide when a command acts; the input buffer applies them to the step.
- Rejected inputs (NaN, expired, too far ahead) are counted and skipped, as the node logs
  and drops them. Inputs that do not fit the scene at all (unknown body or frame) make the
  replay fail with :class:`ReplayError` unless ``skip_rejected`` is set: the bag most likely
  belongs to another scene.

Outputs are the node's: ``/<body>/pose`` (PoseStamped), ``/<body>/twist`` (Twist), and when
the scene enables them ``/<body>/odom``, ``/markers`` and ``/diagnostics``, and each sensor's
``/<body>/<sensor>/scan`` (LaserScan) or ``.../imu`` (Imu); every message is logged at its
sim time. The sensors sample an instant as the simulation steps on from it, so the replay's
last instant has readings only when the bag holds one stamped there (the node went on).
``/tf`` and ``/tf_static`` (TFMessage, when the scene publishes TF) are written only when
asked for (``tf=True``, ``replay --tf``), so that bags replayed before
the node published TF, the golden bags among them, keep their bytes. Diagnostics carry a
zero ``step_wall_time`` (wall time is not reproducible). Everything is deterministic: same
scene and bag, same bytes.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Optional

from ..dynamics.simulation import Snapshot
from ..ros.cmd_vel import CmdVelTopic, cmd_vel_topics
from ..ros.fields import (
    applied_wrench_fields,
    applied_wrench_to_command,
    header,
    wrench_stamped_to_command,
)
from ..ros.joint_states import MotorTopic, motor_topics
from ..ros.names import APPLIED_WRENCH_TOPIC as APPLIED_WRENCH_NAME
from ..ros.names import NODE_NAME
from ..ros.outputs import (
    DIAGNOSTICS_TOPIC,
    OutputFields,
    OutputKind,
    SnapshotOutputs,
    output_topics,
    sensor_topic,
)
from ..ros.runner import InputSource, Runner, check_wrench_topics
from ..scene.commands import InputError
from ..scene.load import Scene, check_takes_a_step
from ..scene.parameters import seconds_text
from . import io as bags
from .io import (
    APPLIED_WRENCH,
    POSE_STAMPED,
    WRENCH_STAMPED,
    BagContents,
    BagError,
    BagWriter,
    resolve_topic,
)

__all__ = ["ReplayError", "ReplayResult", "Output", "APPLIED_WRENCH_TOPIC", "input_topics",
           "output_types", "output_message", "replay", "replay_to_bag", "replay_outputs",
           "serialize_outputs",
           "outputs_as_bag", "script_to_bag", "session_times", "check_bag_for_scene",
           "recorded_output_topics", "check_named_outputs", "check_session", "check_distinct"]

APPLIED_WRENCH_TOPIC = resolve_topic(APPLIED_WRENCH_NAME)
#: The node's fully qualified name, its diagnostics' hardware_id.
NODE_FQN = resolve_topic(NODE_NAME)
#: The most input messages a replay keeps decoded from its fit check to their push (about
#: 1.3 kB each, 130 MB at this count); a bag with more decodes each again when it is pushed
#: (about 50 us a message), so that a flood's memory stays bounded by its bytes.
HELD_DECODED = 100_000


class ReplayError(BagError):
    """A bag that does not fit the scene, or a replay that cannot go on."""


@dataclass(frozen=True)
class Output:
    """One message the node would publish: topic, type, log time (= sim time), message."""

    topic: str
    msgtype: str
    log_ns: int
    msg: Any


@dataclass
class ReplayResult:
    """What a replay did."""

    start_ns: int
    end_ns: int
    inputs: int = 0
    accepted: int = 0
    rejected: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    ignored_after_end: int = 0
    outputs: int = 0
    steps: int = 0
    halted: Optional[str] = None  # the divergence that stopped the simulation
    reached_ns: int = 0           # the sim time the replay reached (end_ns unless halted)


# ----------------------------------------------------------------------------- topics

def input_topics(scene: Scene) -> dict[str, tuple[str, Optional[InputSource]]]:
    """Input topics of the node for ``scene``: topic -> (message type, source), the source
    None for ``applied_wrench``, else the scene's WrenchTopic, a motor's MotorTopic or a
    driven body's CmdVelTopic."""
    topics: dict[str, tuple[str, Optional[InputSource]]] = {
        APPLIED_WRENCH_TOPIC: (APPLIED_WRENCH, None)}
    for wrench_topic in scene.wrench_topics:
        topics[resolve_topic(wrench_topic.topic)] = (WRENCH_STAMPED, wrench_topic)
    for motor in motor_topics(scene):
        topics[resolve_topic(motor.topic)] = (bags.FLOAT64, motor)
    for driven in cmd_vel_topics(scene):
        topics[resolve_topic(driven.topic)] = (bags.TWIST, driven)
    return topics


def output_types(scene: Scene, *, tf: bool = False) -> dict[str, str]:
    """The node's output topics for ``scene`` as a bag names them, with their message
    types (topic -> type), in publishing order; with ``tf``, ``/tf`` and ``/tf_static``
    too if the scene publishes TF."""
    return {resolve_topic(topic): kind.value
            for topic, kind in output_topics(scene, tf=tf and scene.publish_tf).items()}


def check_bag_for_scene(scene: Scene, bag: BagContents, *, need_inputs: bool = True) -> None:
    """Raise :class:`ReplayError` if the bag's topics do not fit the scene.

    The input topics present must have the node's types, at least one must be present
    (with ``need_inputs``), and output topics of bodies the scene does not have mean the bag
    was recorded with another scene. First the scene's own topics (its wrench topics
    named like another topic: the bag is not to blame).
    """
    check_wrench_topics(scene)
    inputs = input_topics(scene)
    _check_types(bag, {topic: msgtype for topic, (msgtype, _) in inputs.items()})
    if need_inputs and not any(topic in bag.topics for topic in inputs):
        raise ReplayError(f"{bag.path}: none of the scene's input topics is in the bag "
                          f"(expected {', '.join(inputs)}; the bag has "
                          f"{', '.join(sorted(bag.topics)) or 'no topics'})")
    bodies = {body.name for body in scene.bodies}
    foreign = sorted({topic.split("/")[1] for topic, msgtype in bag.topics.items()
                      if msgtype == POSE_STAMPED and topic.count("/") == 2
                      and topic.endswith("/pose") and topic.split("/")[1] not in bodies})
    if foreign:
        raise ReplayError(f"{bag.path}: the bag has poses of bodies the scene "
                          f"{scene.source} does not have ({', '.join(foreign)}; the scene's "
                          f"bodies: {', '.join(sorted(bodies))})")
    _check_types(bag, output_types(scene))


def check_named_outputs(scene: Scene, topics: Optional[Sequence[str]], tf: bool) -> None:
    """Raise :class:`ReplayError` for a topic of ``topics`` (``--topic``) that is no output
    of ``scene`` (with ``tf``, TF's too)."""
    wanted = output_types(scene, tf=tf)
    unknown = [t for t in topics or () if t not in wanted]
    if unknown:
        raise ReplayError(f"--topic {unknown[0]}: not an output the node publishes for "
                          f"{scene.source} (its outputs: {', '.join(wanted)})")


def recorded_output_topics(scene: Scene, bag: BagContents, *, need_inputs: bool = True,
                           tf: bool = False,
                           topics: Optional[Sequence[str]] = None) -> list[str]:
    """The scene's output topics recorded in ``bag`` (with ``tf``, TF's too), to check a
    replay against.

    Raises :class:`ReplayError` if ``topics`` (``--topic``) names no output of the scene
    (:func:`check_named_outputs`: before the replay, not after it), if the bag does not
    fit the scene (:func:`check_bag_for_scene`) or holds no recorded pose to compare with.
    """
    check_named_outputs(scene, topics, tf)
    check_bag_for_scene(scene, bag, need_inputs=need_inputs)
    outputs = output_types(scene, tf=tf)
    recorded = [topic for topic in outputs if topic in bag.topics]
    if not any(bag.topics[topic] == POSE_STAMPED for topic in recorded):
        raise ReplayError(f"{bag.path}: --check needs recorded outputs in the bag, but it "
                          f"has none of {', '.join(t for t in outputs if t.endswith('/pose'))}")
    return recorded


def _check_types(bag: BagContents, topics: dict[str, str]) -> None:
    """Raise :class:`ReplayError` if one of ``topics`` (topic -> type) in the bag has another
    type or definition."""
    for topic, msgtype in topics.items():
        if topic in bag.topics:
            try:
                bag.check_type(topic, msgtype)
            except BagError as error:
                raise ReplayError(str(error)) from None


def _recorded_poses(scene: Scene, bag: BagContents) -> list[int]:
    """Header stamps of the recorded ``/<body>/pose`` messages of the scene's bodies."""
    topics = {f"/{body.name}/pose" for body in scene.bodies}
    return [stamp for m in bag.messages if m.topic in topics
            if (stamp := bags.stamp_ns_of(m.decode())) is not None]  # always: PoseStamped


def session_times(scene: Scene, bag: BagContents, start_ns: Optional[int] = None,
                  duration_ns: Optional[int] = None) -> tuple[int, int]:
    """The start and end (sim time, ns) of the session in ``bag``.

    Start: ``start_ns``; else the bag's ``hecker_dynamics.start_ns`` custom data (bags from
    ``script``/``replay``); else one publish period before the first recorded pose (a bag
    recorded from the node); else the bag's first log time. End: start plus ``duration_ns``;
    else plus the bag's ``hecker_dynamics.duration_ns``; else the last recorded pose; else
    plus the scene's duration.
    """
    poses: Optional[list[int]] = None
    if start_ns is not None:
        _check_start_in_bag(bag, start_ns)
    if start_ns is None:
        start_ns = bag.custom_int("start_ns")
    if start_ns is None:
        poses = _recorded_poses(scene, bag)
        if poses:
            start_ns = min(poses) - scene.publish_period_ns
    if start_ns is None:
        start_ns = bag.messages[0].log_ns if bag.messages else 0
    if duration_ns is None:
        duration_ns = bag.custom_int("duration_ns")
    if duration_ns is None:
        poses = _recorded_poses(scene, bag) if poses is None else poses
        if poses:
            duration_ns = max(poses) - start_ns
    if duration_ns is None:
        duration_ns = scene.duration_ns
    if duration_ns < 0:
        raise ReplayError(f"{bag.path}: the session would end before it starts "
                          f"(start {seconds_text(start_ns)} s, "
                          f"duration {seconds_text(duration_ns)} s)")
    # A session the bag records (its custom data, its poses) as shorter than one step would
    # replay no step, and a check would report every output as missing.
    check_takes_a_step(duration_ns, scene.step_ns, f"{bag.path}: the session's duration")
    check_session(start_ns, duration_ns, f"{bag.path}: the session")
    return start_ns, start_ns + duration_ns


def _check_start_in_bag(bag: BagContents, start_ns: int) -> None:
    """Refuse a start given past the end of ``bag`` (its last message, or the end of the
    session it records, whichever is later): the replay would take none of it."""
    ends = [bag.messages[-1].log_ns] if bag.messages else []
    recorded_start, recorded_duration = bag.custom_int("start_ns"), bag.custom_int("duration_ns")
    if recorded_start is not None and recorded_duration is not None:
        ends.append(recorded_start + recorded_duration)
    if ends and start_ns > max(ends):
        raise ReplayError(f"{bag.path}: --start {seconds_text(start_ns)} s is after the end "
                          f"of the bag, at {seconds_text(max(ends))} s: none of it would be "
                          "replayed")


def check_session(start_ns: int, duration_ns: int, what: str,
                  names: tuple[str, str] = ("start", "duration")) -> None:
    """Refuse a session (``what``, its start and duration named by ``names``) that starts
    before 0 (a bag's log times are unsigned) or ends after :data:`~.io.MAX_STAMP_NS`, the
    latest time a ROS stamp holds: its messages could not be stamped."""
    latest = f"{bags.MAX_STAMP_NS // 1_000_000_000} s, the latest time a ROS stamp " \
             "(int32 seconds) holds"
    if start_ns < 0:
        raise ReplayError(f"{what} {names[0]} {seconds_text(start_ns)} s is before 0 "
                          "(bag log times cannot be negative)")
    if start_ns > bags.MAX_STAMP_NS:
        raise ReplayError(f"{what} {names[0]} {seconds_text(start_ns)} s is after {latest}")
    if start_ns + duration_ns > bags.MAX_STAMP_NS:
        raise ReplayError(f"{what} {names[1]} {seconds_text(duration_ns)} s ends it after {latest}")


def check_distinct(output: Path, inputs: Sequence[Path]) -> None:
    """Refuse an output bag that is, holds or lies inside one of ``inputs``: writing it
    would replace the input it reads."""
    out = Path(output).resolve()
    for given in inputs:
        source = Path(given).resolve()
        if out == source or out in source.parents or source in out.parents:
            raise ReplayError(f"{output}: the output bag would write over the input bag "
                              f"{given}; give another output")


# ----------------------------------------------------------------------------- inputs

@dataclass(frozen=True, slots=True)
class _Input:
    """An input message of the bag, at its log time (the node's arrival time), with its
    decoded message when the replay holds them (:data:`HELD_DECODED`)."""

    message: bags.BagMessage
    wrench_topic: Optional[InputSource]
    held: Any

    def decoded(self) -> Any:
        """The message as the node receives it."""
        return self.message.decode() if self.held is None else self.held

    @property
    def log_ns(self) -> int:
        return self.message.log_ns

    @property
    def topic(self) -> str:
        return self.message.topic


def _commands(scene: Scene, bag: BagContents, skip_rejected: bool,
              result: ReplayResult) -> list[_Input]:
    """The bag's input messages in log-time order, checked against the scene.

    Unless ``skip_rejected``, commands for bodies or frames the scene does not have make
    the replay fail: the bag most likely belongs to another scene. With it, they go on to
    the simulation, which rejects them as the node does.
    """
    topics = input_topics(scene)
    bodies = {body.name for body in scene.bodies}
    inputs = []
    unfit: list[str] = []
    hold = sum(message.topic in topics for message in bag.messages) <= HELD_DECODED
    for message in bag.messages:
        if message.topic not in topics:
            continue
        msgtype, wrench_topic = topics[message.topic]
        msg = message.decode()
        result.inputs += 1
        inputs.append(_Input(message, wrench_topic, msg if hold else None))
        if skip_rejected or isinstance(wrench_topic, (MotorTopic, CmdVelTopic)):  # not a wrench
            continue
        try:
            if wrench_topic is None:
                command, _ = applied_wrench_to_command(msg, message.log_ns)
            else:
                command, _ = wrench_stamped_to_command(msg, wrench_topic, message.log_ns)
        except InputError:
            continue  # the node rejects it too, and the replay counts it
        if command.body not in bodies:
            unfit.append(f"unknown body '{command.body}'")
        elif not scene.has_frame(command.frame_id):
            unfit.append(f"unknown frame '{command.frame_id}'")
    if unfit:
        distinct = sorted(set(unfit))
        raise ReplayError(
            f"{bag.path}: {len(unfit)} input message(s) do not fit the scene {scene.source}: "
            f"{'; '.join(distinct[:3])}{'; ...' if len(distinct) > 3 else ''} (scene bodies: "
            f"{', '.join(sorted(bodies))}; wrong scene? --skip-rejected drops them)")
    return inputs


# ----------------------------------------------------------------------------- outputs

_MESSAGE_BUILDERS: dict[OutputKind, Callable[[Any], Any]] = {
    OutputKind.POSE: bags.pose_stamped_message, OutputKind.TWIST: bags.twist_message,
    OutputKind.ODOMETRY: bags.odometry_message, OutputKind.MARKERS: bags.marker_array_message,
    OutputKind.TF: bags.tf_message, OutputKind.JOINT_STATE: bags.joint_state_message,
    OutputKind.LASER_SCAN: bags.laser_scan_message, OutputKind.IMU: bags.imu_message,
    OutputKind.OCCUPANCY_GRID: bags.occupancy_grid_message,
    OutputKind.CONTACT_EVENT: bags.contact_event_message,
}


def output_message(fields: OutputFields, log_ns: int) -> Output:
    """The bag message of one output, logged at ``log_ns``."""
    return Output(resolve_topic(fields.topic), fields.kind.value, log_ns,
                  _MESSAGE_BUILDERS[fields.kind](fields.fields))


def snapshot_messages(scene: Scene, snapshot: Snapshot, *, tf: bool = False,
                      base: Optional[Scene] = None) -> list[Output]:
    """The messages the node publishes for one snapshot, in its publishing order, in the
    world ``scene`` that started as ``base`` (default ``scene``)."""
    fields = SnapshotOutputs(scene, tf=tf and scene.publish_tf, base=base)(snapshot)
    return [output_message(output, snapshot.time_ns) for output in fields]


# ----------------------------------------------------------------------------- replay

def _sampled_at(scene: Scene, bag: BagContents, stamp_ns: int) -> bool:
    """Whether ``bag`` holds a sensor reading of ``scene`` stamped ``stamp_ns`` (the
    sensors sample an instant as the simulation steps on from it)."""
    for spec in scene.sensors:
        recorded = bag.on(resolve_topic(sensor_topic(spec)))
        if recorded and bags.stamp_ns_of(recorded[-1].decode()) == stamp_ns:
            return True
    return False



def replay(scene: Scene, bag: BagContents, emit: Callable[[Output], None], *,
           start_ns: Optional[int] = None, duration_ns: Optional[int] = None,
           play_script: bool = False, skip_rejected: bool = False, tf: bool = False,
           progress: Optional[Callable[[float], None]] = None) -> ReplayResult:
    """Replay the inputs of ``bag`` on ``scene``; ``emit`` receives every output in order.

    See the module docstring for the rules and :func:`session_times` for the start and
    end. Raises :class:`ReplayError` when the bag does not fit the scene.
    """
    check_bag_for_scene(scene, bag, need_inputs=not play_script)
    start, end = session_times(scene, bag, start_ns, duration_ns)
    result = ReplayResult(start_ns=start, end_ns=end)
    inputs = _commands(scene, bag, skip_rejected, result)
    # The node's loop, with a wall clock that stands still: diagnostics show no wall time.
    runner = Runner(scene, start_ns=start, play_script=play_script, hardware_id=NODE_FQN,
                    wall_clock=lambda: 0)
    sim = runner.sim
    outputs_of = SnapshotOutputs(scene, tf=tf and scene.publish_tf)
    # The node latches the named points' transforms once, before its first tick.
    for fields in outputs_of.static(start):
        emit(output_message(fields, start))
        result.outputs += 1

    def run_tick(target_ns: int) -> None:
        tick = runner.advance(target_ns)
        result.rejected.extend(tick.script_errors)
        for stamp, item in tick.in_order():
            for fields in outputs_of(item) if isinstance(item, Snapshot) else [item]:
                emit(output_message(fields, stamp))
                result.outputs += 1
        if tick.diagnostics is not None:
            emit(Output(resolve_topic(DIAGNOSTICS_TOPIC), OutputKind.DIAGNOSTICS.value,
                        sim.time_ns, bags.diagnostic_array_message(
                            tick.diagnostics, header("", sim.time_ns))))
            result.outputs += 1
        result.halted = tick.diverged

    # The node's first tick starts the simulation: scripted commands due at the start,
    # no step, diagnostics.
    run_tick(start)
    period = scene.publish_period_ns
    next_input = 0
    tick = start
    while tick + period <= end and result.halted is None:
        target = tick + period
        # Messages that arrive before the next tick are pushed while the sim stands at tick.
        while next_input < len(inputs) and inputs[next_input].log_ns < target:
            item = inputs[next_input]
            next_input += 1
            for line in runner.accept(item.topic, item.decoded(), item.log_ns,
                                      item.wrench_topic):
                if line.dropped:
                    result.rejected.append(f"at {seconds_text(item.log_ns)} s: {line.message}")
                else:
                    result.warnings.append(line.message)
        run_tick(target)
        tick = target
        if progress is not None:
            progress((tick - start) / (end - start) if end > start else 1.0)
    if result.halted is None and _sampled_at(scene, bag, sim.time_ns):
        # The node stepped on from the end, which took the sensors' readings there.
        for stamp, fields in runner.leave():
            emit(output_message(fields, stamp))
            result.outputs += 1
    result.accepted = runner.accepted
    result.steps = sim.steps
    result.reached_ns = sim.time_ns
    result.ignored_after_end = len(inputs) - next_input
    return result


def replay_to_bag(scene: Scene, bag: BagContents, output: Path, *, storage: str = "mcap",
                  overwrite: bool = False, with_inputs: bool = False, compress: bool = False,
                  **options: Any) -> ReplayResult:
    """Replay ``bag`` on ``scene`` and write the outputs into a new bag at ``output``.

    Every output topic of the scene is declared (even if no message is published). With
    ``with_inputs`` the input messages are copied too, as ``ros2 bag record -a`` would
    hold them. ``options`` go to :func:`replay`. A replay that diverges (``halted``)
    writes no bag: its custom data would claim a session it did not reach.
    """
    check_distinct(output, [bag.path])
    start, end = session_times(scene, bag, options.get("start_ns"), options.get("duration_ns"))
    custom = {"scene": Path(scene.source).stem, "start_ns": str(start),
              "duration_ns": str(end - start)}
    writer = BagWriter(output, storage, overwrite=overwrite, custom_data=custom,
                       compress=compress)
    writer.open()
    try:
        inputs = input_topics(scene)
        pending = []
        if with_inputs:
            for topic, (msgtype, _) in inputs.items():
                if topic in bag.topics:
                    writer.add_topic(topic, msgtype)
            pending = [m for m in bag.messages if m.topic in inputs]
        for topic, msgtype in output_types(scene, tf=options.get("tf", False)).items():
            writer.add_topic(topic, msgtype)
        position = 0

        def emit(out: Output) -> None:
            nonlocal position
            while position < len(pending) and pending[position].log_ns <= out.log_ns:
                writer.write_raw(pending[position].topic, pending[position].log_ns,
                                 pending[position].raw)
                position += 1
            writer.write(out.topic, out.msgtype, out.log_ns, out.msg)

        result = replay(scene, bag, emit, **options)
        for message in pending[position:]:
            writer.write_raw(message.topic, message.log_ns, message.raw)
    except BaseException:
        writer.abort()
        raise
    if result.halted is not None:
        writer.abort()
    else:
        writer.close()
    return result


def replay_outputs(scene: Scene, bag: BagContents, **options: Any) -> tuple[list[Output],
                                                                           ReplayResult]:
    """Replay into a list of outputs (for tests and comparisons in memory)."""
    outputs: list[Output] = []
    result = replay(scene, bag, outputs.append, **options)
    return outputs, result


def serialize_outputs(outputs: Sequence[Output]) -> list[tuple[str, int, bytes]]:
    """``(topic, log time, CDR bytes)`` of each output, as a bag would store them."""
    store = bags.typestore()
    return [(o.topic, o.log_ns, bytes(store.serialize_cdr(o.msg, o.msgtype))) for o in outputs]


def outputs_as_bag(scene: Scene, outputs: Sequence[Output], name: str = "<replay>", *,
                   tf: bool = False) -> BagContents:
    """The outputs as an in-memory :class:`BagContents` (every output topic declared; TF's
    with ``tf``)."""
    raw = serialize_outputs(outputs)
    messages = [bags.BagMessage(i, o.topic, o.msgtype, o.log_ns, data)
                for i, (o, (_, _, data)) in enumerate(zip(outputs, raw))]
    return BagContents(path=Path(name), storage="memory", topics=output_types(scene, tf=tf),
                       messages=messages)


# ----------------------------------------------------------------------------- script

def script_to_bag(scene: Scene, output: Path, *, storage: str = "mcap", start_ns: int = 0,
                  duration_ns: Optional[int] = None, overwrite: bool = False,
                  compress: bool = False) -> int:
    """Write the scene's scripted inputs as ``AppliedWrench`` messages on ``/applied_wrench``.

    Each message is stamped (and logged) at ``start_ns`` plus its script time; commands at
    or after the duration (default: the scene's) are left out, as :meth:`Simulation.play`
    leaves them. The scene's ``WrenchStamped`` topics are declared too (without messages),
    so the bag shows every input the scene takes. Returns the number of messages.
    """
    duration = scene.duration_ns if duration_ns is None else duration_ns
    check_session(start_ns, duration, "the session")
    custom = {"scene": Path(scene.source).stem, "start_ns": str(int(start_ns)),
              "duration_ns": str(int(duration))}
    count = 0
    with BagWriter(output, storage, overwrite=overwrite, custom_data=custom,
                   compress=compress) as writer:
        for topic, (msgtype, _) in input_topics(scene).items():
            writer.add_topic(topic, msgtype)
        for command in sorted(scene.script, key=lambda c: c.stamp_ns):
            if command.stamp_ns >= duration:
                continue
            # Logged at its stamp. A zero stamp reads as "on arrival", which is the same
            # instant here since the log time is zero too.
            stamp = start_ns + command.stamp_ns
            writer.write(APPLIED_WRENCH_TOPIC, APPLIED_WRENCH, stamp, bags.applied_wrench_msg(
                applied_wrench_fields(replace(command, stamp_ns=stamp))))
            count += 1
    return count
