"""Replay of a live session recorded with ``ros2 bag record``: bit for bit, from the records.

The node publishes what its outputs depend on beyond the inputs themselves
(:mod:`hecker_dynamics.ros.session`): which scene and options run (``~/session``), the sim
time each input message was pushed at (``~/input_events``) and the whole state every
keyframe period (``~/keyframe``). A replay of a recorded session

1. checks that the scene given has the recorded fingerprint;
2. for each session (the node's start and each restart) with recorded outputs, starts from
   the latest keyframe at or before the first recorded output whose later input events are
   all in the bag (or from the session's start), in a :class:`~hecker_dynamics.ros.runner.Runner`
   with the recorded options;
3. pushes each recorded input event's message at its recorded sim time, with its recorded
   arrival time, makes each recorded world change (a body moved, spawned or deleted, a
   pause, resume or step) again at its sim time, in the node's order, and steps on to the
   last recorded output; the same runner takes keyframes at the same instants, and each
   must equal the recorded one. A keyframe holds the bodies spawned and deleted before it,
   so a replay that starts there starts in the world the node had;
4. compares every recorded output, spawned bodies' included, with the replayed one of the
   same stamp (``Twist``, which has no header, by its place in the sequence of snapshots).

``/diagnostics`` is not compared: it holds wall times and the node publishes it at timer
ticks; nor is ``/tf_static``, published once at the node's start, which the scene fixes;
nor a ``markers`` array of ``DELETE`` markers alone, which the node sends when bodies are
gone (:meth:`~hecker_dynamics.ros.outputs.SnapshotOutputs.markers_gone`): it follows from the
world events compared above, and after a restart from the world before it, which the new
session's records do not hold.
Recorded outputs before the replay's start (a recorder that subscribed to them before
it received a keyframe) are counted as not checked. Input messages recorded on the input
topics are checked against the events: an event whose message is missing in the middle of
the recorded span of its topic means the bag was changed or the recorder dropped it.
"""
from __future__ import annotations

import bisect
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

from ..ros.markers import MARKER_DELETE
from ..ros.names import MARKERS_TOPIC, TF_STATIC_TOPIC
from ..ros.joint_states import MotorTopic
from ..ros.outputs import DIAGNOSTICS_TOPIC, body_topics
from ..ros.runner import InputSource, Runner
from ..ros.session import (InputEventFields, KeyframeFields, SessionFields, WorldChange,
                           WorldEventFields, decode_state)
from ..scene.fingerprint import scene_fingerprint
from ..scene.load import Scene
from ..scene.world import EditKind, WorldEdit
from . import io as bags
from .compare import CompareReport, Tolerances, compare_contents
from .io import (INPUT_EVENT, KEYFRAME, SESSION_INFO, WORLD_EVENT, BagContents, BagMessage,
                 resolve_topic)
from .replay import Output, ReplayError, input_topics, output_types, snapshot_messages

#: What a session's event sequence holds.
Event = Union[InputEventFields, WorldEventFields]
#: Most twists in a row a recorder may have lost where the check still finds the next one:
#: ten publish periods, 0.2 s at the default rate.
LOST_TWISTS = 10

__all__ = ["RecordedSession", "LiveCheck", "recorded_sessions", "is_live_recording",
           "check_live"]


@dataclass
class RecordedSession:
    """What a bag holds of one session of the node."""

    info: SessionFields
    info_log_ns: int
    keyframes: list[KeyframeFields] = field(default_factory=list)
    #: Input events and world changes by their shared sequence number.
    events: dict[int, Event] = field(default_factory=dict)


@dataclass
class LiveCheck:
    """The outcome of :func:`check_live`."""

    report: CompareReport
    sessions: int = 0
    events: int = 0
    keyframes_checked: int = 0
    unchecked: int = 0                     # recorded outputs before the replay's start
    problems: list[str] = field(default_factory=list)   # decisions or states that differ
    notes: list[str] = field(default_factory=list)
    outputs: list[Output] = field(default_factory=list)
    halted: Optional[str] = None

    @property
    def ok(self) -> bool:
        return self.report.ok and not self.problems


def is_live_recording(bag: BagContents) -> bool:
    """Whether the bag holds a session record of the node (a live recording)."""
    return SESSION_INFO in bag.topics.values()


def recorded_sessions(bag: BagContents) -> dict[int, RecordedSession]:
    """The sessions of the node recorded in ``bag``, by session number."""
    sessions: dict[int, RecordedSession] = {}
    keyframes: list[KeyframeFields] = []
    events: list[Event] = []
    for message in bag.messages:
        msgtype = bag.topics[message.topic]
        if msgtype == SESSION_INFO:
            info = bags.session_fields(message.decode())
            sessions.setdefault(info.session, RecordedSession(info, message.log_ns))
        elif msgtype == KEYFRAME:
            keyframes.append(bags.keyframe_fields(message.decode()))
        elif msgtype == INPUT_EVENT:
            events.append(bags.input_event_fields(message.decode()))
        elif msgtype == WORLD_EVENT:
            events.append(bags.world_event_fields(message.decode()))
    for keyframe in keyframes:
        if keyframe.session in sessions and all(
                k.stamp_ns != keyframe.stamp_ns for k in sessions[keyframe.session].keyframes):
            sessions[keyframe.session].keyframes.append(keyframe)
    for event in events:
        if event.session in sessions:
            sessions[event.session].events.setdefault(event.sequence, event)
    for session in sessions.values():
        session.keyframes.sort(key=lambda k: k.stamp_ns)
    return sessions


# ----------------------------------------------------------------------------- outputs

def _session_of(sessions: Sequence[RecordedSession], message: BagMessage,
                stamp: int) -> RecordedSession:
    """The session a recorded stamped output belongs to: the latest whose start is not
    after its stamp. Where a later session starts before an earlier one (the ROS clock
    jumped back), the latest of those whose record the recorder had by then."""
    fits = [s for s in sessions if s.info.start_ns <= stamp] or list(sessions[:1])
    starts = [s.info.start_ns for s in sessions]
    if starts == sorted(starts):
        return fits[-1]
    received = [s for s in fits if s.info_log_ns <= message.log_ns]
    return (received or fits)[-1]


Recorded = dict[str, list[tuple[BagMessage, Optional[int]]]]


def _recorded_outputs(scene: Scene, bag: BagContents, sessions: Sequence[RecordedSession]
                      ) -> tuple[dict[int, Recorded], Recorded]:
    """The recorded outputs in log order: per session and topic those with a header stamp
    (with it), and per topic those without (``Twist``, with None), which are placed in the
    sequence of all sessions' snapshots instead (see :func:`_align`)."""
    compared = (set(output_types(scene, tf=True)) | _spawned_topics(scene, sessions)) - {
        resolve_topic(DIAGNOSTICS_TOPIC), TF_STATIC_TOPIC}
    stamped: dict[int, Recorded] = defaultdict(lambda: defaultdict(list))
    unstamped: Recorded = defaultdict(list)
    markers = resolve_topic(MARKERS_TOPIC)
    for message in bag.messages:
        if message.topic not in compared:
            continue
        msg = message.decode()
        if message.topic == markers and _deletes_only(msg):
            continue
        stamp = bags.stamp_ns_of(msg)
        if stamp is None:
            unstamped[message.topic].append((message, None))
        else:
            session = _session_of(sessions, message, stamp)
            stamped[session.info.session][message.topic].append((message, stamp))
    return stamped, unstamped


def _deletes_only(msg: object) -> bool:
    """Whether ``msg``, a ``MarkerArray``, holds ``DELETE`` markers alone (see the module
    docstring)."""
    items = getattr(msg, "markers", ())
    return bool(items) and all(m.action == MARKER_DELETE for m in items)


def _spawned_topics(scene: Scene, sessions: Sequence[RecordedSession]) -> set[str]:
    """The output topics of the bodies spawned in ``sessions``, by their records: the
    world events and the edits the keyframes hold."""
    names = {event.body for session in sessions for event in session.events.values()
             if isinstance(event, WorldEventFields) and event.kind is WorldChange.SPAWN}
    for session in sessions:
        for keyframe in session.keyframes:
            names.update(edit.body for edit in _keyframe_edits(keyframe)
                         if edit.kind is EditKind.SPAWN)
    return {resolve_topic(topic) for name in names for topic in body_topics(scene, name)}


def _keyframe_edits(keyframe: KeyframeFields) -> list[WorldEdit]:
    try:
        return [WorldEdit.from_data(data)
                for data in decode_state(keyframe.state).get("world", [])]
    except (ValueError, TypeError, AttributeError) as error:
        raise ReplayError(f"the keyframe of session {keyframe.session} at "
                          f"{keyframe.stamp_ns * 1e-9:.9f} s has a bad world: {error}") from None


def _sibling(topic: str) -> Optional[str]:
    return topic[: -len("/twist")] + "/pose" if topic.endswith("/twist") else None


def _align(recorded: Recorded, produced: dict[str, list[Output]], raw: dict[int, bytes],
           start_ns: int, poses: Optional[Recorded] = None
           ) -> tuple[list[BagMessage], list[BagMessage], int]:
    """The recorded messages and their replayed counterparts, both logged at the snapshot's
    stamp, and how many recorded messages were not checked (before ``start_ns``).

    A stamped message's counterpart has its stamp. A ``Twist`` is placed in the sequence of
    replayed twists (one per replayed snapshot) where the recorded ones match bit for bit,
    searched from where the sibling pose received just before it (in ``poses``, else in
    ``recorded``) puts it; where none matches, that place stands, so the comparison reports
    the difference. Where no one place fits them all, a recorded twist that differs from
    its place looks for its match among the next :data:`LOST_TWISTS` (the recorder lost
    the ones before it), so one lost twist moves none of the others."""
    expected: list[BagMessage] = []
    actual: list[BagMessage] = []
    unchecked = 0
    for topic, messages in recorded.items():
        replayed = produced.get(topic, [])
        if messages and messages[0][1] is None:
            pose_topic = _sibling(topic)
            sibling = (poses or recorded).get(pose_topic, []) if pose_topic else []
            twists = [m for m, _ in messages]
            places = _twist_places(twists, replayed, raw,
                                   _twist_offset(twists, replayed, raw, sibling))
            for message, index in zip(twists, places):
                if index < 0:
                    unchecked += 1
                elif index < len(replayed):
                    expected.append(_relogged(message, replayed[index].log_ns))
                    actual.append(_as_message(replayed[index], raw))
                else:  # after the last replayed snapshot: missing from the replay
                    expected.append(_relogged(message, message.log_ns))
            continue
        by_stamp = {o.log_ns: o for o in replayed}
        for message, stamp in messages:
            if stamp is None or stamp < start_ns:
                unchecked += 1
                continue
            expected.append(_relogged(message, stamp))
            if stamp in by_stamp:
                actual.append(_as_message(by_stamp[stamp], raw))
    return expected, actual, unchecked


def _twist_offset(messages: list[BagMessage], replayed: list[Output], raw: dict[int, bytes],
                  poses: list[tuple[BagMessage, Optional[int]]]) -> int:
    """Where the recorded twists start in the replayed sequence (see :func:`_align`); negative
    when the recording began before the replay's first snapshot. The place nearest the
    sibling poses' guess where all of them match, else where the most of them in a row
    from the first do (a twist lost later breaks that row), else the guess."""
    stamps = [o.log_ns for o in replayed]
    guess = 0
    if poses and messages and stamps:
        first = messages[0].log_ns
        before = [stamp for message, stamp in poses if message.log_ns <= first and stamp]
        stamp = before[-1] if before else poses[0][1]
        if stamp is not None and stamp >= stamps[0]:
            guess = bisect.bisect_left(stamps, stamp)
        elif stamp is not None:  # count the recorded snapshots the replay does not have
            guess = -sum(1 for _, s in poses if s is not None and stamp <= s < stamps[0])
    count = len(messages)

    def matching(offset: int) -> int:
        """How many twists in a row match from the first the replay has at ``offset``."""
        checked = range(max(0, -offset), min(count, len(replayed) - offset))
        for row, j in enumerate(checked):
            if messages[j].raw != raw[id(replayed[offset + j])]:
                return row
        return count

    best, longest = guess, 0
    for distance in range(len(replayed) + count + 1):
        for offset in (guess - distance, guess + distance):
            if -count < offset < len(replayed):
                row = matching(offset)
                if row == count:
                    return offset
                if row > longest:
                    best, longest = offset, row
    return best


def _twist_places(messages: list[BagMessage], replayed: list[Output], raw: dict[int, bytes],
                  offset: int) -> list[int]:
    """The index in ``replayed`` of each recorded twist, the first at ``offset``, each next
    one after the last, at the first of :data:`LOST_TWISTS` + 1 places on that matches it
    bit for bit, else right after the last (see :func:`_align`)."""
    places = []
    place = offset
    for message in messages:
        if place >= 0:  # before the replay's first snapshot a twist stays unchecked
            for later in range(place, min(place + LOST_TWISTS + 1, len(replayed))):
                if raw[id(replayed[later])] == message.raw:
                    place = later
                    break
        places.append(place)
        place += 1
    return places


def _relogged(message: BagMessage, log_ns: int) -> BagMessage:
    return bags.BagMessage(message.index, message.topic, message.msgtype, log_ns, message.raw)


def _as_message(output: Output, raw: dict[int, bytes]) -> BagMessage:
    return bags.BagMessage(0, output.topic, output.msgtype, output.log_ns, raw[id(output)])


# ----------------------------------------------------------------------------- replay

def _wrench_topics(scene: Scene) -> dict[str, Optional[InputSource]]:
    return {topic: wrench_topic for topic, (_, wrench_topic) in input_topics(scene).items()}


def _starting_point(session: RecordedSession, first_ns: int
                    ) -> tuple[Optional[KeyframeFields], list[InputEventFields], list[str]]:
    """The keyframe to start from (None: the session's start), the events to push from
    there, and notes. The latest start at or before ``first_ns`` whose later events are all
    recorded; else the earliest later one whose events are."""
    events = session.events
    last_needed = max([k.next_event for k in session.keyframes] + [max(events, default=-1) + 1])

    def complete(first_event: int) -> bool:
        return all(sequence in events for sequence in range(first_event, last_needed))

    starts: list[tuple[int, Optional[KeyframeFields]]] = [
        (k.stamp_ns, k) for k in session.keyframes]
    if not any(k.steps == 0 for k in session.keyframes):
        starts.insert(0, (session.info.start_ns, None))
    usable = [(stamp, k) for stamp, k in starts
              if complete(session.info.next_event if k is None else k.next_event)]
    if not usable:
        missing = [s for s in range(session.info.next_event, last_needed) if s not in events]
        raise ReplayError(
            f"session {session.info.session}: the bag lacks input events "
            f"{_ranges(missing)} and has no keyframe after them to start from (the recorder "
            "missed them; record ~/input_events from the node's start)")
    before = [(stamp, k) for stamp, k in usable if stamp <= first_ns]
    stamp, keyframe = before[-1] if before else usable[0]
    notes = [] if before else [
        f"session {session.info.session}: replayed from the keyframe at "
        f"{stamp * 1e-9:.9f} s, the first whose later input events are all in the bag"]
    first_event = session.info.next_event if keyframe is None else keyframe.next_event
    pushed = [events[s] for s in sorted(events) if s >= first_event]
    return keyframe, pushed, notes


def _ranges(numbers: list[int]) -> str:
    shown = ", ".join(str(n) for n in numbers[:5])
    return shown + (f" and {len(numbers) - 5} more" if len(numbers) > 5 else "")


def _check_inputs(bag: BagContents, events: list[InputEventFields],
                  topics: dict[str, Optional[InputSource]]) -> list[str]:
    """Events whose message is missing from the middle of its topic's recorded span."""
    store = bags.typestore()
    recorded: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    for message in bag.messages:
        if message.topic in topics:
            recorded[message.topic].append((message.log_ns, message.raw))
    problems = []
    for topic, messages in recorded.items():
        if not messages:
            continue
        first, last = messages[0][0], messages[-1][0]
        available = defaultdict(int)
        for _, raw in messages:
            available[raw] += 1
        for event in events:
            if event.topic != topic or not first <= event.arrival_ns <= last:
                continue
            source = topics[topic]
            msgtype = (bags.APPLIED_WRENCH if source is None else bags.FLOAT64
                       if isinstance(source, MotorTopic) else bags.WRENCH_STAMPED)
            raw = bytes(store.serialize_cdr(event.message, msgtype))
            if available[raw]:
                available[raw] -= 1
            else:
                problems.append(f"input event {event.sequence} ({topic}, arrived "
                                f"{event.arrival_ns * 1e-9:.9f} s) has no recorded message "
                                f"on {topic}, which was recorded from {first * 1e-9:.9f} to "
                                f"{last * 1e-9:.9f} s: the bag lost or changed it")
    return problems


def check_live(scene: Scene, bag: BagContents, *, tolerances: Optional[Tolerances] = None,
               progress: Optional[Callable[[float], None]] = None) -> LiveCheck:
    """Replay every recorded session of ``bag`` on ``scene`` and compare the recorded outputs
    (see the module docstring). Raises :class:`~hecker_dynamics.bags.replay.ReplayError`
    when the bag belongs to another scene or lacks what a replay needs."""
    sessions = recorded_sessions(bag)
    if not sessions:
        raise ReplayError(f"{bag.path}: no session record (~/session, {SESSION_INFO})")
    fingerprint = scene_fingerprint(scene)
    for session in sessions.values():
        if session.info.fingerprint != fingerprint:
            raise ReplayError(
                f"{bag.path}: recorded with scene '{session.info.scene}' (fingerprint "
                f"{session.info.fingerprint}), but {scene.source} has fingerprint "
                f"{fingerprint}")
    ordered = [sessions[n] for n in sorted(sessions)]
    recorded, unstamped = _recorded_outputs(scene, bag, ordered)
    if not any(recorded.values()):
        raise ReplayError(f"{bag.path}: the bag has no recorded outputs of the scene's bodies "
                          f"({', '.join(t for t in output_types(scene) if t.endswith('/pose'))})")
    topics = _wrench_topics(scene)
    store = bags.typestore()
    expected: list[BagMessage] = []
    actual: list[BagMessage] = []
    check = LiveCheck(report=CompareReport(str(bag.path), "<replay>", tolerances or Tolerances()))
    with_outputs = [s for s in ordered if recorded.get(s.info.session)]
    raw: dict[int, bytes] = {}
    by_topic: dict[str, list[Output]] = defaultdict(list)  # all sessions, in session order
    for done, session in enumerate(with_outputs):
        outputs = recorded[session.info.session]
        stamps = [stamp for messages in outputs.values() for _, stamp in messages
                  if stamp is not None]
        produced, start_ns = _replay_session(scene, session, min(stamps), max(stamps), topics,
                                             check)
        check.outputs.extend(produced)
        raw.update((id(o), bytes(store.serialize_cdr(o.msg, o.msgtype))) for o in produced)
        session_topics: dict[str, list[Output]] = defaultdict(list)
        for output in produced:
            session_topics[output.topic].append(output)
            by_topic[output.topic].append(output)
        e, a, unchecked = _align(outputs, session_topics, raw, start_ns)
        expected += e
        actual += a
        check.unchecked += unchecked
        check.problems += _check_inputs(bag, [e for e in session.events.values()
                                              if isinstance(e, InputEventFields)], topics)
        check.sessions += 1
        if progress is not None:
            progress((done + 1) / len(with_outputs))
    if with_outputs:
        every_pose: Recorded = defaultdict(list)
        for outputs in recorded.values():
            for topic, messages in outputs.items():
                every_pose[topic] += messages
        for messages in every_pose.values():
            messages.sort(key=lambda item: item[0].log_ns)
        e, a, unchecked = _align(dict(unstamped), by_topic, raw, 0, every_pose)
        expected += e
        actual += a
        check.unchecked += unchecked
    compared = sorted({m.topic for m in expected})
    types = {t: bag.topics[t] for t in compared}
    report, _ = compare_contents(
        BagContents(path=Path(str(bag.path)), storage="memory", topics=types, messages=expected),
        BagContents(path=Path("<replay>"), storage="memory", topics=types, messages=actual),
        tolerances=tolerances, topics=compared)
    check.report = report
    if resolve_topic(DIAGNOSTICS_TOPIC) in bag.topics:
        check.notes.append(f"{resolve_topic(DIAGNOSTICS_TOPIC)} not compared: it holds wall "
                           "times and is published at the node's timer ticks")
    if check.unchecked:
        check.notes.append(f"{check.unchecked} recorded output(s) before the replay's start "
                           "not checked")
    return check


def _replay_session(scene: Scene, session: RecordedSession, first_ns: int, last_ns: int,
                    topics: dict[str, Optional[InputSource]], check: LiveCheck
                    ) -> tuple[list[Output], int]:
    """Replay one session up to ``last_ns``; returns the outputs and the replay's start."""
    info = session.info
    keyframe, events, notes = _starting_point(session, first_ns)
    check.notes += notes
    runner = Runner(scene, start_ns=info.start_ns, play_script=info.play_script,
                    record=True, keyframe_period_ns=info.keyframe_period_ns,
                    wall_clock=lambda: 0, lockstep=info.lockstep)
    if runner.sim.integrator.name != info.integrator or runner.sim.step_ns != info.step_ns:
        raise ReplayError(f"session {info.session} ran {info.integrator} at a "
                          f"{info.step_ns} ns step; {scene.source} gives "
                          f"{runner.sim.integrator.name} at {runner.sim.step_ns} ns")
    runner.session = info.session
    produced: list[Output] = []
    if keyframe is not None:
        try:
            runner.restore(keyframe)
        except ValueError as error:  # a scene error too: a world that does not rebuild
            raise ReplayError(f"session {info.session}: cannot start at the keyframe at "
                              f"{keyframe.stamp_ns * 1e-9:.9f} s: {error}") from None
        if keyframe.steps and (keyframe.stamp_ns - info.start_ns) % scene.publish_period_ns == 0:
            # The node published this instant on arriving there, before the keyframe.
            produced.extend(snapshot_messages(runner.scene, runner.sim.snapshot(), tf=True,
                                              base=runner.base_scene))
    runner.take_records()
    start_ns = runner.sim.time_ns
    recorded_keyframes = {k.stamp_ns: k for k in session.keyframes}

    def advance(target_ns: int) -> None:
        tick = runner.advance(target_ns)
        for snapshot in tick.snapshots:
            produced.extend(snapshot_messages(runner.scene, snapshot, tf=True,
                                              base=runner.base_scene))
        if tick.diverged is not None:
            check.halted = tick.diverged
        for record in runner.take_records():
            if isinstance(record, KeyframeFields) and record.stamp_ns in recorded_keyframes:
                check.keyframes_checked += 1
                if record != recorded_keyframes[record.stamp_ns]:
                    check.problems.append(f"session {info.session}: the state at "
                                          f"{record.stamp_ns * 1e-9:.9f} s differs from the "
                                          "recorded keyframe")

    for event in events:
        if event.stamp_ns > last_ns:
            break
        if event.stamp_ns < runner.sim.time_ns:
            raise ReplayError(f"session {info.session}: input event {event.sequence} was "
                              f"pushed at {event.stamp_ns * 1e-9:.9f} s, before the one "
                              "before it; the records are inconsistent")
        advance(event.stamp_ns)
        check.events += 1
        if isinstance(event, WorldEventFields):
            accepted = _change(runner, event, produced).accepted
        else:
            if event.topic not in topics:
                raise ReplayError(f"session {info.session}: input event {event.sequence} is "
                                  f"on {event.topic}, which is not an input of {scene.source}")
            lines = runner.accept(event.topic, event.message, event.arrival_ns,
                                  topics[event.topic])
            accepted = not any(line.dropped for line in lines)
        if accepted != event.accepted:
            check.problems.append(
                f"session {info.session}: event {event.sequence} was "
                f"{'accepted' if event.accepted else 'rejected'} by the node but "
                f"{'accepted' if accepted else 'rejected'} now"
                + (f" ({event.reason})" if event.reason else ""))
        runner.take_records()
    advance(last_ns)
    return produced, start_ns


def _change(runner: Runner, event: WorldEventFields,
            produced: list[Output]) -> WorldEventFields:
    """Make the recorded world change again; a step's snapshots join the outputs."""
    if event.kind is WorldChange.SET_STATE:
        return runner.set_body_state(event.body, event.values)
    if event.kind is WorldChange.SPAWN:
        return runner.spawn_body(event.body, event.spec, event.collisions)
    if event.kind is WorldChange.DELETE:
        return runner.delete_body(event.body)
    if event.kind is WorldChange.PAUSE:
        return runner.pause()
    if event.kind is WorldChange.RESUME:
        return runner.resume_at(event.time_ns)
    record, tick = runner.step(int(event.values[0]) if event.values else 0)
    for snapshot in tick.snapshots:
        produced.extend(snapshot_messages(runner.scene, snapshot, tf=True,
                                          base=runner.base_scene))
    return record
