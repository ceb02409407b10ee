"""Replay of a live session recorded with ``ros2 bag record``: bit for bit, from the records,
and a check of everything the recording holds.

The node publishes what its outputs depend on beyond the inputs themselves
(:mod:`hecker_dynamics.ros.session`): which scene and options run (``~/session``), the sim
time each input message was pushed at (``~/input_events``), each change made through its
services (``~/world_events``, in the same sequence) and the whole state every keyframe
period (``~/keyframe``). A check of a recorded session

1. reads the records and fails on those that contradict each other (:mod:`.records`);
2. for each recorded session, starts from the earliest state record (the session's start,
   else a keyframe) whose later events are all in the bag. Events missing after it fail
   the check (the recorder receives them all: they are latched, and the latest 1000 of
   each kind reach a recorder that starts late), unless ``partial``: then it starts after
   the last gap and names what it did not check;
3. pushes each recorded input event's message at its recorded sim time, which must be one
   the simulation stood at, with its recorded arrival time and makes each recorded world
   change again, in the node's order, in a :class:`~hecker_dynamics.ros.runner.Runner`
   with the recorded options, to the last recorded output, event or keyframe. Each event
   must be accepted or refused as the node did, each recorded keyframe must be one the
   replay takes and equal it (a session's first too: see :func:`_check_first_keyframe`);
4. matches every recorded output with the replayed one of its stamp (``Twist``, which has
   no header, by its place among the replayed twists), and compares them
   (:func:`~hecker_dynamics.bags.compare.compare_pairs`). A recorded output the replay
   does not publish, recorded twice or out of order fails;
5. accounts for every replayed output the recording lacks
   (:mod:`~hecker_dynamics.bags.coverage`): not recorded by the recorder's doing (before
   it subscribed to the topic, after it stopped, a few lost under load), or missing;
6. checks the recorded input messages against the events: each event takes a copy of its
   message logged before the node's record of it (give or take
   :data:`~.coverage.INPUT_LAG_NS`); one without fails the check where the recorder
   recorded the topic, or the node's outputs, before and after it, but for one within
   :data:`~.coverage.DISCOVERY_NS` of the first event after a silence of that long on its
   topic, which is named: a new publisher's first messages reach the node before the
   recorder matches the publisher (seen on Jazzy with ``ros2 topic pub``).

Where a replayed output was published in log time is bounded by what was recorded around
it: a replayed output was published after every recorded output of an earlier snapshot and
before every recorded output of a later one, before every event record with a later sim
time of its session and before every record of a later session.

``/diagnostics`` is not compared: it holds wall times and the node publishes it at timer
ticks; nor are ``/tf_static`` and ``/map``, published once at the node's start, which the
scene fixes (the map's cells are in the scene's fingerprint);
nor ``/clock`` (lockstep ticks), nor a ``markers`` array of ``DELETE`` markers alone,
which the node sends when bodies are gone
(:meth:`~hecker_dynamics.ros.outputs.SnapshotOutputs.markers_gone`): it follows from the
world events compared above, and after a restart from the world before it, which the new
session's records do not hold.
"""
from __future__ import annotations

import bisect
import dataclasses
from collections import defaultdict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Optional, Union

from ..dynamics.simulation import Snapshot
from ..ros.cmd_vel import CmdVelTopic
from ..ros.joint_states import MotorTopic
from ..ros.markers import MARKER_DELETE
from ..ros.names import (
    CLOCK_TOPIC,
    INPUT_EVENTS_TOPIC,
    KEYFRAME_TOPIC,
    MAP_TOPIC,
    MARKERS_TOPIC,
    SESSION_TOPIC,
    TF_STATIC_TOPIC,
    WORLD_EVENTS_TOPIC,
)
from ..ros.outputs import DIAGNOSTICS_TOPIC, OutputFields, body_topics, sensor_topic
from ..ros.runner import InputSource, Runner
from ..ros.session import (
    APPLIED_WRENCH_EVENT,
    CMD_VEL_EVENT,
    INPUT_EVENTS_DEPTH,
    MOTOR_SPEED_EVENT,
    WORLD_EVENTS_DEPTH,
    WRENCH_STAMPED_EVENT,
    InputEventFields,
    KeyframeFields,
    WorldChange,
    WorldEventFields,
    decode_state,
    encode_state,
)
from ..scene.fingerprint import scene_fingerprint
from ..scene.load import Scene
from ..scene.parameters import seconds_text
from . import io as bags
from .compare import CompareReport, Tolerances, compare_pairs
from .coverage import (
    DISCOVERY_NS,
    INPUT_LAG_NS,
    LOST_RUN,
    LOST_SHARE,
    STOP_NS,
    Coverage,
    Stretch,
    runs,
    seconds,
    span,
)
from .io import (
    INPUT_EVENT,
    SESSION_INFO,
    WORLD_EVENT,
    BagContents,
    BagError,
    BagMessage,
    resolve_topic,
)
from .records import (
    RECORD_TYPES,
    Event,
    RecordedSession,
    gaps,
    input_bytes,
    is_live_recording,
    ranges_text,
    record_name,
    recorded_sessions,
    spawned_bodies,
)
from .replay import (
    Output,
    ReplayError,
    input_topics,
    output_message,
    output_types,
    snapshot_messages,
)

#: Most twists in a row a recorder may have lost where the check still finds the next one:
#: ten publish periods, 0.2 s at the default rate.
LOST_TWISTS = 10
#: How many of the first recorded twists of a body place them by their log times.
TIMED_TWISTS = 64

__all__ = ["LiveCheck", "check_live", "is_live_recording", "recorded_sessions"]


@dataclass
class LiveCheck:
    """The outcome of :func:`check_live`."""

    report: CompareReport
    coverage: Coverage
    sessions: int = 0
    events: int = 0
    keyframes_checked: int = 0
    outputs: list[Output] = field(default_factory=list)
    halted: Optional[str] = None

    @property
    def ok(self) -> bool:
        return self.report.ok and self.coverage.ok

    @property
    def unchecked(self) -> int:
        """Recorded outputs not compared: those before the state the replay starts from."""
        return sum(s.count for t in self.coverage.topics.values() for s in t.unchecked)

    @property
    def problems(self) -> list[str]:
        return self.coverage.failures

    @property
    def notes(self) -> list[str]:
        return self.coverage.notes


# ----------------------------------------------------------------------------- records

# ----------------------------------------------------------------------------- outputs

def _session_order(sessions: Sequence[RecordedSession], message: BagMessage,
                   stamp: int) -> list[RecordedSession]:
    """The sessions a recorded stamped output may belong to, likeliest first: the latest
    whose start is not after its stamp (where a later session starts before an earlier one,
    as when the ROS clock jumped back, the latest whose record the recorder had by then),
    then the one before it (whose last snapshot may share the next one's start)."""
    fits = [s for s in sessions if s.info.start_ns <= stamp] or list(sessions[:1])
    starts = [s.info.start_ns for s in sessions]
    if starts != sorted(starts):
        received = [s for s in fits if s.info_log_ns <= message.log_ns]
        fits = received or fits
    return list(reversed(fits))[:2]


def _deletes_only(msg: object) -> bool:
    """Whether ``msg``, a ``MarkerArray``, holds ``DELETE`` markers alone (see the module
    docstring)."""
    items = getattr(msg, "markers", ())
    return bool(items) and all(m.action == MARKER_DELETE for m in items)


def _sibling(topic: str) -> Optional[str]:
    return topic[: -len("/twist")] + "/pose" if topic.endswith("/twist") else None


def _twist_offset(messages: list[BagMessage], replayed: list[Output], raw: dict[int, bytes],
                  poses: list[tuple[BagMessage, int]]) -> int:
    """Where the recorded twists start in the replayed sequence; negative when the
    recording began before the replay's first snapshot. The place nearest the guess (by
    the first sibling pose, then the log times: :func:`_fit_in_time`) where all of them
    match, else where the most of them in a row from the
    first do (a twist lost later breaks that row), else the guess. No place leaves more
    twists before the replay's first snapshot, unchecked, than the poses do (but one, a
    twist that arrived after the next tick's pose): where a body
    rests, its twists are all alike, and a place a few earlier left one changed twist
    unchecked and matched the rest, shifted, until the body moved (reported as outputs
    missing, not as the twist that differs). Places whose rows tie, twists alike up to a
    changed one, are told apart by how many match in all."""
    stamps = [o.log_ns for o in replayed]
    guess = 0
    if poses and messages and stamps:
        first = messages[0].log_ns
        before = [stamp for message, stamp in poses if message.log_ns <= first]
        stamp = before[-1] if before else poses[0][1]
        if stamp >= stamps[0]:
            guess = bisect.bisect_left(stamps, stamp)
        else:  # count the recorded snapshots the replay does not have
            guess = -sum(1 for _, s in poses if stamp <= s < stamps[0])
        if not before:  # twists logged before the first pose are of ticks before its
            guess -= sum(1 for m in messages if m.log_ns < poses[0][0].log_ns)
    count = len(messages)
    lowest = max(-count + 1, min(guess, 0) - 1)  # a twist logged after the next pose
    guess = max(_fit_in_time(messages, stamps, poses, guess), lowest)

    def matching(offset: int) -> int:
        """How many twists in a row match from the first the replay has at ``offset``."""
        checked = range(max(0, -offset), min(count, len(replayed) - offset))
        for row, j in enumerate(checked):
            if messages[j].raw != raw[id(replayed[offset + j])]:
                return row
        # Twists past the replay's last are none it published: not all of them match.
        return count if offset + count <= len(replayed) else len(checked)

    def total(offset: int) -> int:
        """How many twists match at ``offset``, in a row or not."""
        return sum(messages[j].raw == raw[id(replayed[offset + j])]
                   for j in range(max(0, -offset), min(count, len(replayed) - offset)))

    best, longest, ties = guess, 0, [guess]
    for distance in range(len(replayed) + count + 1):
        for offset in (guess - distance, guess + distance):
            if lowest <= offset < len(replayed):
                row = matching(offset)
                if row == count:
                    return offset
                if row > longest:
                    best, longest, ties = offset, row, [offset]
                elif row == longest and abs(offset - guess) <= LOST_TWISTS:
                    ties.append(offset)
    # Alike twists (a body at rest) tie up to a changed one: the place where the most
    # match after it too.
    return max(ties, key=total) if longest and len(ties) > 1 else best


def _fit_in_time(messages: list[BagMessage], stamps: list[int],
                 poses: list[tuple[BagMessage, int]], guess: int) -> int:
    """The place within :data:`LOST_TWISTS` of ``guess`` where the first
    :data:`TIMED_TWISTS` recorded twists were logged nearest the recorded poses of their
    snapshots (``stamps``: the replayed twists'): the node publishes a body's pose and
    twist together and the recorder logs each a moment later. A resting body's twists
    match alike at every place, and the first pose a recorder logged does not place them:
    the twists of a burst of late ticks come in with its poses, some a moment before the
    first one. ``guess`` where places have no pose to go by, or a stamp is replayed twice."""
    logged = {stamp: message.log_ns for message, stamp in poses}
    if len(logged) != len(poses) or len(set(stamps)) != len(stamps):
        return guess
    head = messages[:TIMED_TWISTS]
    fits: dict[int, tuple[int, float]] = {}  # place -> (poses gone by, mean distance)
    for offset in range(guess - LOST_TWISTS, guess + LOST_TWISTS + 1):
        gaps = [abs(message.log_ns - logged[stamps[offset + j]])
                for j, message in enumerate(head)
                if 0 <= offset + j < len(stamps) and stamps[offset + j] in logged]
        if gaps:
            fits[offset] = len(gaps), sum(gaps) / len(gaps)
    if not fits:
        return guess
    # A place that pairs a few twists only, at an end, fits by chance.
    enough = (max(paired for paired, _ in fits.values()) + 1) // 2
    return min((offset for offset, (paired, _) in fits.items() if paired >= enough),
               key=lambda offset: (fits[offset][1], abs(offset - guess)))


def _twist_places(messages: list[BagMessage], replayed: list[Output], raw: dict[int, bytes],
                  offset: int) -> list[tuple[int, str]]:
    """The index in ``replayed`` of each recorded twist, the first at ``offset``, each next
    one after the last, at the first of :data:`LOST_TWISTS` + 1 places on that matches it
    bit for bit, else right after the last; with a fault ("" for none). A twist that matches
    none of those places but one of as many before is out of place, or recorded twice when
    an earlier twist took that place: the next one is sought where it would have been, so
    one twist moved does not shift every later comparison by a place."""
    places: list[tuple[int, str]] = []
    taken: set[int] = set()
    place = offset
    for message in messages:
        if place >= 0:  # before the replay's first snapshot a twist stays unchecked
            ahead = range(place, min(place + LOST_TWISTS + 1, len(replayed)))
            found = next((p for p in ahead if raw[id(replayed[p])] == message.raw), None)
            if found is None:
                behind = range(min(place, len(replayed)) - 1,
                               max(place - LOST_TWISTS - 2, -1), -1)
                back = next((p for p in behind if raw[id(replayed[p])] == message.raw), None)
                if back is not None:
                    places.append((back, "is recorded twice" if back in taken else
                                   "comes after a later one: out of place"))
                    continue
            else:
                place = found
        taken.add(place)
        places.append((place, ""))
        place += 1
    return places


def _relogged(message: BagMessage, log_ns: int) -> BagMessage:
    return dataclasses.replace(message, log_ns=log_ns)


# ----------------------------------------------------------------------------- replay

@dataclass
class _Snapshot:
    """One replayed snapshot: its session, stamp and index among all replayed ones."""

    session: int
    stamp: int
    order: int


@dataclass
class _Replayed:
    """What the replay of every session published, in the node's order."""

    snapshots: list[_Snapshot] = field(default_factory=list)
    #: Per topic, its outputs in order with the index of their snapshot.
    topics: dict[str, list[tuple[int, Output]]] = field(default_factory=lambda:
                                                        defaultdict(list))
    #: Per session, the sim times its replay started and ended at, and its keyframes.
    starts: dict[int, int] = field(default_factory=dict)
    ends: dict[int, int] = field(default_factory=dict)
    keyframes: dict[int, dict[int, KeyframeFields]] = field(default_factory=dict)
    #: The sessions replayed from their start without the counts the node carried into
    #: them (their first keyframe is missing): their keyframes are compared but for those.
    uncounted: set[int] = field(default_factory=set)
    #: Per session and topic: stamp -> place in ``topics[topic]``.
    places: dict[tuple[int, str], dict[int, int]] = field(default_factory=dict)
    outputs: list[Output] = field(default_factory=list)

    def add(self, session: int, outputs: list[Output]) -> None:
        if not outputs:
            return
        snapshot = _Snapshot(session, outputs[0].log_ns, len(self.snapshots))
        self.snapshots.append(snapshot)
        for output in outputs:
            places = self.places.setdefault((session, output.topic), {})
            places[output.log_ns] = len(self.topics[output.topic])
            self.topics[output.topic].append((snapshot.order, output))
        self.outputs.extend(outputs)


def _wrench_topics(scene: Scene) -> dict[str, Optional[InputSource]]:
    return {topic: source for topic, (_, source) in input_topics(scene).items()}


def _starting_point(session: RecordedSession, first_output_ns: Optional[int],
                    coverage: Coverage, latched_full: bool
                    ) -> tuple[Optional[KeyframeFields], list[Event], list[Event]]:
    """The keyframe to start from (None: the session's start), the events to push from
    there and those recorded before it.

    The start is the earliest state record whose later events are all in the bag (a
    session's first keyframe rather than its start: the counts of inputs the node carries
    over restarts are in it), and at most :data:`MAX_PRELUDE_NS` before the first recorded
    output. Missing events fail the check (``missing``: --partial accepts them), but for the
    oldest ones of a recorder that started late, which received as many as the node keeps
    (``latched_full``)."""
    events = session.events
    needed_to = max([k.next_event for k in session.keyframes]
                    + [max(events, default=session.info.next_event - 1) + 1])
    missing = gaps(sorted(events), session.info.next_event, needed_to)
    lowest = min(events, default=needed_to)
    holes = [(a, b) for a, b in missing if b > lowest]
    starts: list[tuple[int, int, Optional[KeyframeFields]]] = [
        (k.stamp_ns, k.next_event, k) for k in session.keyframes]
    if not any(k.steps == 0 for k in session.keyframes) and (
            session.number == 0 or not session.keyframes or first_output_ns is None
            or first_output_ns < min(k.stamp_ns for k in session.keyframes)):
        # A later session's start lacks the counts the node carries over restarts, which
        # its keyframes hold: the replay starts from one unless outputs come before them.
        starts.insert(0, (session.info.start_ns, session.info.next_event, None))
    usable = [(stamp, first, k) for stamp, first, k in starts
              if all(b < first for _, b in missing)]
    if not usable:
        raise ReplayError(
            f"session {session.number}: the bag lacks input or world event records "
            f"{ranges_text(missing)} and "
            "has no keyframe after them to start from (record ~/input_events and "
            "~/world_events from the node's start)")
    if first_output_ns is not None:
        near = [start for start in usable if start[0] >= first_output_ns - MAX_PRELUDE_NS]
        if not near:
            stamp = usable[-1][0]
            raise ReplayError(
                f"session {session.number}: its first recorded output at "
                f"{seconds(first_output_ns)} s comes {seconds_text(first_output_ns - stamp)} s "
                f"after its latest state record to start from (at {seconds(stamp)} s), more "
                f"than the {seconds_text(MAX_PRELUDE_NS)} s a replay goes back (record with "
                "keyframes on, or start the recorder before the node)")
        usable = near
    _, first_event, keyframe = usable[0]
    if holes or (missing and not latched_full):
        where = (f"before the keyframe at {seconds(keyframe.stamp_ns)} s" if keyframe
                 else "before the session's start")
        gone = holes or missing
        many = len(gone) > 1 or gone[0][0] != gone[0][1]
        coverage.fail(f"session {session.number}: input or world event "
                      f"record{'s' if many else ''} {ranges_text(gone)} missing; nothing "
                      f"{where} could be replayed", missing=True)
    pushed = [events[s] for s in sorted(events) if s >= first_event]
    before = [events[s] for s in sorted(events) if s < first_event]
    return keyframe, pushed, before


#: The longest stretch of sim time a replay steps through before the first recorded output
#: of a session: a keyframe's worth with keyframes on (they are latched: a recorder that
#: starts late receives the latest two), more than any honest recording needs otherwise.
MAX_PRELUDE_NS = 60_000_000_000

def _event_kind(source: Optional[InputSource]) -> int:
    if source is None:
        return APPLIED_WRENCH_EVENT
    return (MOTOR_SPEED_EVENT if isinstance(source, MotorTopic) else CMD_VEL_EVENT
            if isinstance(source, CmdVelTopic) else WRENCH_STAMPED_EVENT)


def _world_shape(event: WorldEventFields) -> Optional[str]:
    """What a world event holds that the node never records for its kind, or None."""
    kind = event.kind
    values = {WorldChange.SET_STATE: 6, WorldChange.STEP: 1}.get(kind, 0)
    if len(event.values) != values:
        return f"{len(event.values)} values"
    if kind is WorldChange.STEP and event.values[0] != int(event.values[0]):
        return f"a step count of {event.values[0]!r}"
    if kind is not WorldChange.RESUME and event.time_ns:
        return "a time"
    if kind in (WorldChange.PAUSE, WorldChange.RESUME, WorldChange.STEP) and event.body:
        return "a body"
    if kind is not WorldChange.SPAWN and (event.spec or event.collisions):
        return "a body's description"
    return None


class _Stuck(Exception):
    """A replay that cannot go on from the recorded state (its message says why)."""


class _SessionReplay:
    """The replay of one recorded session into ``replayed`` (see the module docstring)."""

    def __init__(self, scene: Scene, session: RecordedSession, replayed: _Replayed,
                 check: LiveCheck, topics: dict[str, Optional[InputSource]]) -> None:
        self.scene, self.session, self.replayed, self.check = scene, session, replayed, check
        self.topics = topics
        info = session.info
        try:
            self.runner = Runner(scene, start_ns=info.start_ns, play_script=info.play_script,
                                 record=True, keyframe_period_ns=info.keyframe_period_ns,
                                 wall_clock=lambda: 0, lockstep=info.lockstep)
        except ValueError as error:
            raise ReplayError(f"session {info.session} cannot be replayed: {error}") from None
        sim = self.runner.sim
        if sim.integrator.name != info.integrator or sim.step_ns != info.step_ns \
                or scene.publish_period_ns != info.publish_period_ns \
                or scene.frame_id != info.frame_id:
            raise ReplayError(
                f"session {info.session} ran {info.integrator} at a {info.step_ns} ns step, "
                f"publishing every {info.publish_period_ns} ns in frame '{info.frame_id}'; "
                f"{scene.source} gives {sim.integrator.name} at {sim.step_ns} ns, every "
                f"{scene.publish_period_ns} ns in '{scene.frame_id}'")
        self.runner.session, self.runner.sequence = info.session, info.next_event
        self.taken = replayed.keyframes.setdefault(info.session, {})

    def start(self, keyframe: Optional[KeyframeFields]) -> int:
        """Start at ``keyframe`` (None: at the session's start); returns the sim time."""
        runner = self.runner
        if keyframe is not None:
            try:
                runner.restore(keyframe)
            except (ValueError, TypeError, KeyError, IndexError, AttributeError) as error:
                raise ReplayError(f"session {self.session.number}: cannot start at the "
                                  f"keyframe at {seconds(keyframe.stamp_ns)} s: "
                                  f"{type(error).__name__}: {error}") from None
            sim = runner.sim
            if keyframe.steps and (sim.time_ns - sim.start_ns) % self.scene.publish_period_ns == 0:
                # The node published this instant on arriving there, before the keyframe.
                self.publish([(sim.time_ns, sim.snapshot())])
            self.taken[keyframe.stamp_ns] = keyframe
        runner.take_records()
        self.replayed.starts[self.session.number] = runner.sim.time_ns
        return runner.sim.time_ns

    def publish(self, published: Iterable[tuple[int, Union[Snapshot, OutputFields]]]) -> None:
        """Snapshots and sensor readings with their stamps, in the node's order
        (:meth:`~hecker_dynamics.ros.runner.Tick.in_order`)."""
        for stamp, item in published:
            self.replayed.add(self.session.number, snapshot_messages(
                self.runner.scene, item, tf=True, base=self.runner.base_scene)
                if isinstance(item, Snapshot) else [output_message(item, stamp)])

    def leave(self) -> None:
        """Publish the sensors' readings of the instant the replay stands at."""
        self.publish(self.runner.leave())

    def advance(self, target_ns: int) -> None:
        try:
            tick = self.runner.advance(target_ns)
        except (ArithmeticError, ValueError) as error:  # a state no run of the node reaches
            raise _Stuck(f"cannot be replayed on from {seconds(self.runner.sim.time_ns)} s: "
                         f"{type(error).__name__}: {error}") from None
        self.publish(tick.in_order())
        if tick.diverged is not None and self.check.halted is None:
            self.check.halted = tick.diverged
        self.keep_keyframes()

    def keep_keyframes(self) -> None:
        for record in self.runner.take_records():
            if isinstance(record, KeyframeFields):
                self.taken.setdefault(record.stamp_ns, record)

    def run(self, events: Sequence[Event], end_ns: int, coverage: Coverage) -> None:
        """Push ``events`` at their sim times and step on to ``end_ns``; a record that the
        replay cannot follow ends it with a failure."""
        try:
            self._run(events, end_ns, coverage)
        except _Stuck as stuck:
            coverage.fail(f"session {self.session.number}: {stuck}")

    def _run(self, events: Sequence[Event], end_ns: int, coverage: Coverage) -> None:
        number = self.session.number
        for event in events:
            if event.stamp_ns > end_ns:
                break
            if event.stamp_ns < self.runner.sim.time_ns:
                coverage.fail(f"{record_name(event)} was made at {seconds(event.stamp_ns)} s, "
                              f"before the sim time {seconds(self.runner.sim.time_ns)} s the "
                              "events before it had reached: out of place")
                return
            self.advance(event.stamp_ns)
            if self.runner.sim.time_ns != event.stamp_ns:
                coverage.fail(f"{record_name(event)} was made at {seconds(event.stamp_ns)} s, "
                              "where the simulation never stood (it steps from "
                              f"{seconds(self.runner.sim.time_ns)} s): out of place")
                return
            problem = self.apply(event)
            if problem is not None:
                coverage.fail(f"session {number}: {record_name(event)} {problem}")
                if problem.startswith("cannot"):
                    return
            if isinstance(event, WorldEventFields):
                coverage.world_events += 1
            else:
                coverage.input_events += 1
            self.check.events += 1
            self.keep_keyframes()
        self.advance(end_ns)

    def apply(self, event: Event) -> Optional[str]:
        """Make ``event`` again; what does not fit the node's decision, or None."""
        try:
            if isinstance(event, WorldEventFields):
                shape = _world_shape(event)
                if shape is not None:
                    return f"holds {shape}, which the node never records for a " \
                           f"{event.kind.name.lower()}"
                accepted = self.change(event).accepted
            else:
                if event.topic not in self.topics:
                    return f"is on {event.topic}, which is not an input of {self.scene.source}"
                source = self.topics[event.topic]
                if event.kind != _event_kind(source):
                    return f"holds a message of kind {event.kind}, not what {event.topic} takes"
                lines = self.runner.accept(event.topic, event.message, event.arrival_ns, source)
                accepted = not any(line.dropped for line in lines)
        except (ValueError, TypeError, OverflowError, AttributeError) as error:
            return f"cannot be made again: {type(error).__name__}: {error}"
        if accepted != event.accepted:
            return (f"was {'accepted' if event.accepted else 'refused'} by the node but "
                    f"{'accepted' if accepted else 'refused'} now"
                    + (f" ({event.reason})" if event.reason else ""))
        return None

    def change(self, event: WorldEventFields) -> WorldEventFields:
        """Make the recorded world change again; a step's snapshots join the outputs."""
        runner = self.runner
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
        record, tick = runner.step(int(event.values[0]))
        self.publish(tick.in_order())
        if tick.diverged is not None and self.check.halted is None:
            self.check.halted = tick.diverged
        return record


def _check_first_keyframe(scene: Scene, session: RecordedSession, keyframe: KeyframeFields,
                          before: list[Event], check: LiveCheck,
                          topics: dict[str, Optional[InputSource]]) -> list[Event]:
    """Replay the events of a session that came before its first keyframe (between a
    restart and the node's next tick) from the session's start, and compare the keyframe
    the replay then takes with the recorded one, but for the counts the node carries over
    restarts (inputs taken and refused, the order of commands). Returns the events before
    the keyframe that this could not replay (none of the session's, or all of them)."""
    ours = [e for e in before if e.sequence >= session.info.next_event]
    if len(ours) != keyframe.next_event - session.info.next_event \
            or any(e.stamp_ns != session.info.start_ns for e in ours):
        return before
    scratch = _SessionReplay(scene, session, _Replayed(), LiveCheck(
        check.report, Coverage(partial=True)), topics)
    coverage = check.coverage
    for event in ours:
        problem = scratch.apply(event)
        if problem is not None:
            coverage.fail(f"session {session.number}: {record_name(event)} {problem}")
        coverage.input_events += isinstance(event, InputEventFields)
        coverage.world_events += isinstance(event, WorldEventFields)
        check.events += 1
    scratch.runner.take_records()
    try:
        scratch.advance(session.info.start_ns)
    except _Stuck as stuck:
        coverage.fail(f"session {session.number}: {stuck}")
    mine = scratch.taken.get(keyframe.stamp_ns)
    if mine is None or _carried(mine, keyframe) != keyframe:
        why = "" if mine is None else _older_imu(mine, keyframe)
        coverage.fail(f"session {session.number}: the state at {seconds(keyframe.stamp_ns)} s "
                      f"differs from the recorded keyframe{why}")
    else:
        check.keyframes_checked += 1
    return [e for e in before if e.sequence < session.info.next_event]


def _carried(keyframe: KeyframeFields, like: KeyframeFields, *,
             renumber: bool = False) -> KeyframeFields:
    """``keyframe`` with the counts the node carries over restarts taken from ``like``;
    with ``renumber``, its pending commands' order numbers shifted as its next one is
    (a replay that started without the counts numbered them from 0)."""
    try:
        state, other = decode_state(keyframe.state), decode_state(like.state)
        if renumber:
            shift = int(other["inputs"]["next_order"]) - int(state["inputs"]["next_order"])
            for pending in state["inputs"]["pending"]:
                pending[1] += shift
        state["runner"]["accepted"] = other["runner"]["accepted"]
        state["runner"]["rejected"] = other["runner"]["rejected"]
        state["inputs"]["next_order"] = other["inputs"]["next_order"]
    except (ValueError, KeyError, TypeError):
        return keyframe
    return keyframe._replace(state=encode_state(state))


# ----------------------------------------------------------------------------- the check

@dataclass
class _Recorded:
    """The recorded outputs on the compared topics, read: per topic, in log order, each
    message with its stamp (None for a twist)."""

    topics: dict[str, list[tuple[BagMessage, Optional[int]]]] = field(
        default_factory=lambda: defaultdict(list))
    skipped: dict[str, int] = field(default_factory=lambda: defaultdict(int))


def _read_outputs(bag: BagContents, compared: set[str], coverage: Coverage) -> _Recorded:
    recorded = _Recorded()
    markers = resolve_topic(MARKERS_TOPIC)
    for message in bag.messages:
        if message.topic not in compared:
            continue
        coverage.topic(message.topic).recorded += 1
        try:
            msg = message.decode()
        except BagError as error:
            coverage.fail(str(error))
            continue
        if message.topic == markers and _deletes_only(msg):
            recorded.skipped[message.topic] += 1
            continue
        try:
            stamp = bags.stamp_ns_of(msg)
        except (AttributeError, TypeError, OverflowError) as error:
            coverage.fail(f"message {message.index} on '{message.topic}' has no readable "
                          f"stamp: {error}")
            continue
        recorded.topics[message.topic].append((message, stamp))
    return recorded


def check_live(scene: Scene, bag: BagContents, *, tolerances: Optional[Tolerances] = None,
               topics: Optional[Sequence[str]] = None, partial: bool = False,
               progress: Optional[Callable[[float], None]] = None) -> LiveCheck:
    """Replay every recorded session of ``bag`` on ``scene`` and check everything the
    recording holds against it (see the module docstring): ``topics`` limits the outputs
    checked (and required) to those named; ``partial`` accepts a recording that lacks
    outputs or records (named in the coverage). Raises
    :class:`~hecker_dynamics.bags.replay.ReplayError` when the bag belongs to another scene
    or cannot be replayed at all."""
    tolerances = tolerances or Tolerances()
    _check_node_types(scene, bag)
    coverage = Coverage(partial=partial)
    check = LiveCheck(report=CompareReport(str(bag.path), "<replay>", tolerances),
                      coverage=coverage)
    sessions = recorded_sessions(bag, coverage)
    if not sessions:
        coverage.fail(f"no session record (~/session, {SESSION_INFO}): the bag holds other "
                      "records of the node without the one that says what ran")
        return check
    fingerprint = scene_fingerprint(scene)
    for session in sessions.values():
        if session.info.fingerprint != fingerprint:
            raise ReplayError(
                f"{bag.path}: recorded with scene '{session.info.scene}' (fingerprint "
                f"{session.info.fingerprint}), but {scene.source} has fingerprint "
                f"{fingerprint}")
    ordered = [sessions[n] for n in sorted(sessions)]
    spawned = spawned_bodies(ordered)
    produced_topics = (set(output_types(scene, tf=True))
                       | {resolve_topic(t) for name in spawned for t in body_topics(scene, name)})
    skipped = {resolve_topic(DIAGNOSTICS_TOPIC): "wall times, published at timer ticks",
               TF_STATIC_TOPIC: "published once, fixed by the scene",
               MAP_TOPIC: "published once, fixed by the map, whose cells the fingerprint holds",
               CLOCK_TOPIC: "published at lockstep ticks"}
    if topics is not None:
        unknown = [t for t in topics if t not in produced_topics or t in skipped]
        if unknown:
            why = f" ({skipped[unknown[0]]})" if unknown[0] in skipped else ""
            raise ReplayError(f"--topic {unknown[0]}: not an output the check compares for "
                              f"{scene.source}{why}; it compares "
                              f"{', '.join(sorted(produced_topics - set(skipped)))}")
        skipped.update({t: "not named by --topic" for t in produced_topics - set(topics)})
    compared = produced_topics - set(skipped)
    sensor_topics = [resolve_topic(sensor_topic(spec)) for spec in scene.sensors]
    for topic, why in skipped.items():
        if topic in bag.topics:
            coverage.not_compared[topic] = why
    coverage.name_other_topics(bag.topics, [*produced_topics, *input_topics(scene)])
    recorded = _read_outputs(bag, compared, coverage)
    if not any(recorded.topics.values()):
        coverage.fail(f"no recorded outputs of the node on {', '.join(sorted(compared))}",
                      missing=True)
    for topic, count in recorded.skipped.items():
        coverage.notes.append(f"{count} {topic} array(s) of DELETE markers alone not compared "
                              "(they follow from the world events)")
    replayed = _Replayed()
    by_session = _stamped_by_session(ordered, recorded)
    latched_full = _latched_full(bag)
    wrench_topics = _wrench_topics(scene)
    for done, session in enumerate(ordered):
        stamps = sorted(stamp for messages in by_session.get(session.number, {}).values()
                        for _, stamp in messages)
        keyframe, events, before = _starting_point(session, stamps[0] if stamps else None,
                                                   coverage, latched_full)
        if keyframe is not None and keyframe.steps == 0:
            before = _check_first_keyframe(scene, session, keyframe, before, check,
                                           wrench_topics)
        elif keyframe is None and session.number > 0 and session.keyframes:
            coverage.fail(
                f"session {session.number}: its first keyframe (taken at its start, "
                f"{seconds(session.info.start_ns)} s) is missing, and only it holds the counts "
                "the node carried over from the sessions before (inputs taken and refused, "
                "the order of commands): the replay from the session's start compares the "
                "later keyframes without them", missing=True)
            replayed.uncounted.add(session.number)
        if before:
            coverage.notes.append(f"session {session.number}: {len(before)} event record(s) "
                                  "before the state the replay starts from not replayed")
        replay = _SessionReplay(scene, session, replayed, check, wrench_topics)
        start_ns = replay.start(keyframe)
        end_ns = _session_end(scene, session, by_session.get(session.number, {}), start_ns,
                              coverage)
        replay.run(events, end_ns, coverage)
        recorded_here = by_session.get(session.number, {})
        if any(stamp == end_ns for topic in sensor_topics for _, stamp in
               recorded_here.get(topic, [])):
            replay.leave()  # the node stepped on from the end: its readings there are out
        replayed.ends[session.number] = end_ns
        check.sessions += 1
        if progress is not None:
            progress((done + 1) / len(ordered))
    check.outputs = replayed.outputs
    pairs, early = _match(ordered, recorded, replayed, coverage)
    _account(ordered, recorded, replayed, pairs, early, coverage, bag, spawned, compared)
    _check_keyframes(ordered, replayed, coverage, check)
    if check.keyframes_checked and scene.publish_diagnostics:
        coverage.notes.append("keyframes compared but for when the node last published "
                              "/diagnostics (its timer's ticks place them; not compared)")
    _check_inputs(bag, ordered, _output_spans(pairs, replayed), wrench_topics, coverage)
    check.report = CompareReport(str(bag.path), "<replay>", tolerances)
    for topic in sorted(pairs):
        matched = [(message, actual, stamp) for message, actual, stamp, _ in pairs[topic]]
        check.report.topics.append(compare_pairs(topic, bag.topics[topic], matched, tolerances))
    coverage.keyframes = check.keyframes_checked
    return check


def _check_node_types(scene: Scene, bag: BagContents) -> None:
    """Refuse a topic of the node's inputs or records recorded with another type than the
    node's (:class:`~hecker_dynamics.bags.io.BagError`): the node never exchanged such
    messages on it, and the check, which reads records by type and inputs by their bytes,
    would take it for another node's topic or compare bytes of another type. Only the
    type's name is compared here, not the hash of its definition."""
    expected = {topic: msgtype for topic, (msgtype, _) in input_topics(scene).items()}
    expected.update({resolve_topic(SESSION_TOPIC): SESSION_INFO,
                     resolve_topic(KEYFRAME_TOPIC): bags.KEYFRAME,
                     resolve_topic(INPUT_EVENTS_TOPIC): INPUT_EVENT,
                     resolve_topic(WORLD_EVENTS_TOPIC): WORLD_EVENT})
    for topic, msgtype in expected.items():
        if bag.topics.get(topic, msgtype) != msgtype:  # the name only: see check_type
            bag.check_type(topic, msgtype)


def _stamped_by_session(sessions: Sequence[RecordedSession], recorded: _Recorded
                        ) -> dict[int, dict[str, list[tuple[BagMessage, int]]]]:
    """The recorded stamped outputs per likeliest session and topic (to bound each
    session's replay)."""
    found: dict[int, dict[str, list[tuple[BagMessage, int]]]] = defaultdict(
        lambda: defaultdict(list))
    for topic, messages in recorded.topics.items():
        for message, stamp in messages:
            if stamp is not None:
                session = _session_order(sessions, message, stamp)[0]
                found[session.number][topic].append((message, stamp))
    return found


def _latched_full(bag: BagContents) -> bool:
    """Whether the bag holds as many input or world event records as the node keeps for a
    recorder that starts late: only then may the oldest be missing."""
    counts: dict[str, int] = defaultdict(int)
    for message in bag.messages:
        counts[bag.topics[message.topic]] += 1
    return counts[INPUT_EVENT] >= INPUT_EVENTS_DEPTH or counts[WORLD_EVENT] >= WORLD_EVENTS_DEPTH


def _session_end(scene: Scene, session: RecordedSession,
                 outputs: dict[str, list[tuple[BagMessage, int]]], start_ns: int,
                 coverage: Coverage) -> int:
    """How far to replay a session: to its last recorded output, event or keyframe, but no
    further than what a recorder that stopped within :data:`STOP_NS` of its last recorded
    output could still have recorded records of (the replay would otherwise step on
    through time whose outputs are missing)."""
    pairs = sorted(((stamp, message.log_ns) for messages in outputs.values()
                    for message, stamp in messages), key=lambda p: p[0])
    period, step = scene.publish_period_ns, session.info.step_ns
    burst = max(session.info.max_catch_up_steps * step, period)
    rate = 1.0
    if len(pairs) > 1 and pairs[-1][1] - pairs[0][1] > STOP_NS:
        rate = max(1.0, (pairs[-1][0] - pairs[0][0]) / (pairs[-1][1] - pairs[0][1]))
    last = pairs[-1][0] if pairs else start_ns
    limit = last + int(rate * STOP_NS) + burst + period
    records = [e.stamp_ns for e in session.events.values()] + \
        [k.stamp_ns for k in session.keyframes]
    beyond = [stamp for stamp in records if stamp > limit]
    if beyond:
        coverage.fail(f"session {session.number}: its records go on to {seconds(max(beyond))} "
                      f"s, past its last recorded output at {seconds(last)} s: the outputs "
                      "published in between are missing", missing=True)
    return max([start_ns, last] + [stamp for stamp in records if stamp <= limit])


#: A recorded output matched with its replayed counterpart: the recorded message (logged
#: at the stamp), the replayed one, the stamp, and the replayed one's place on its topic.
Pair = tuple[BagMessage, BagMessage, int, int]


class _Bytes(dict[Any, Any]):
    """Serialized replayed outputs, by ``id`` of the output, made on first use."""

    def of(self, output: Output) -> bytes:
        raw = self.get(id(output))
        if raw is None:
            raw = self[id(output)] = bytes(bags.typestore().serialize_cdr(output.msg,
                                                                          output.msgtype))
        return raw


def _match(sessions: Sequence[RecordedSession], recorded: _Recorded, replayed: _Replayed,
           coverage: Coverage) -> tuple[dict[str, list[Pair]],
                                        dict[str, list[BagMessage]]]:
    """Every recorded output matched with the replayed one it must equal, and those recorded
    before the replay's start (by topic). The rest fail: outputs the replay does not
    publish, recorded twice or out of order."""
    pairs: dict[str, list[Pair]] = defaultdict(list)
    early: dict[str, list[BagMessage]] = defaultdict(list)
    raw = _Bytes()
    for topic, messages in recorded.topics.items():
        outputs = replayed.topics.get(topic, [])
        if messages and messages[0][1] is None:
            _match_twists(topic, [m for m, _ in messages], outputs, recorded, raw, pairs,
                          early, coverage)
            continue
        last = -1
        for message, stamp in messages:
            assert stamp is not None
            candidates = _session_order(sessions, message, stamp)
            place = next((p for p in (replayed.places.get((s.number, topic), {}).get(stamp)
                                      for s in candidates) if p is not None), None)
            where = f"{topic}: the output stamped {seconds(stamp)} s (logged at " \
                    f"{seconds(message.log_ns)} s)"
            if place is None:
                start = replayed.starts.get(candidates[0].number)
                if start is not None and candidates[0].info.start_ns <= stamp < start:
                    early[topic].append(message)
                else:
                    coverage.fail(f"{where} is not one the node published")
                continue
            if place <= last:
                coverage.fail(f"{where} is recorded twice" if place == last else
                              f"{where} comes after a later one: out of place")
                continue
            last = place
            output = outputs[place][1]
            pairs[topic].append((_relogged(message, stamp), _as_message(output, raw), stamp,
                                 place))
    return pairs, early


def _as_message(output: Output, raw: _Bytes) -> BagMessage:
    return bags.BagMessage(0, output.topic, output.msgtype, output.log_ns, raw.of(output))


def _match_twists(topic: str, twists: list[BagMessage], outputs: list[tuple[int, Output]],
                  recorded: _Recorded, raw: _Bytes, pairs: dict[str, list[Pair]],
                  early: dict[str, list[BagMessage]], coverage: Coverage) -> None:
    """Place each recorded twist among the replayed ones (see :func:`_twist_places`)."""
    replayed = [output for _, output in outputs]
    for output in replayed:
        raw.of(output)
    pose_topic = _sibling(topic)
    poses = sorted(((m, s) for m, s in recorded.topics.get(pose_topic or "", [])
                    if s is not None), key=lambda item: item[0].log_ns)
    places = _twist_places(twists, replayed, raw,
                           _twist_offset(twists, replayed, raw, poses))
    for message, (place, fault) in zip(twists, places):
        if fault:
            coverage.fail(f"{topic}: the twist logged at {seconds(message.log_ns)} s {fault}")
        elif place < 0:
            early[topic].append(message)
        elif place >= len(replayed):
            coverage.fail(f"{topic}: the twist logged at {seconds(message.log_ns)} s comes "
                          "after the last one the node published")
        else:
            output = replayed[place]
            pairs[topic].append((_relogged(message, output.log_ns), _as_message(output, raw),
                                 output.log_ns, place))


def _node_start(bag: BagContents, topics: set[str]) -> int:
    """The log time of the node's first message in the bag: the recorder and the node both
    ran from then on."""
    return min((m.log_ns for m in bag.messages
                if m.topic in topics or bag.topics[m.topic] in RECORD_TYPES),
               default=bag.messages[0].log_ns if bag.messages else 0)


def _upper_bounds(sessions: Sequence[RecordedSession], replayed: _Replayed,
                  logs: dict[int, int]) -> list[Optional[int]]:
    """Per replayed snapshot, the earliest log time of a recorded message published after
    it (see the module docstring), or None."""
    count = len(replayed.snapshots)
    bound: list[Optional[int]] = [None] * count
    later: Optional[int] = None
    for order in range(count - 1, -1, -1):
        log = logs.get(order)
        if log is not None and (later is None or log < later):
            later = log
        bound[order] = later
    after_session: dict[int, Optional[int]] = {}
    following: Optional[int] = None
    for session in reversed(sessions):
        after_session[session.number] = following
        own = [session.info_log_ns, *session.event_logs.values(),
               *session.keyframe_logs.values()]
        following = min(own + ([following] if following is not None else []))
    events: dict[int, tuple[list[int], list[int]]] = {}
    for session in sessions:
        items = sorted((e.stamp_ns, session.event_logs[seq]) for seq, e in session.events.items())
        stamps = [stamp for stamp, _ in items]
        minima: list[int] = []
        for _, log in reversed(items):
            minima.append(min(log, minima[-1]) if minima else log)
        events[session.number] = (stamps, minima[::-1])
    for snapshot in replayed.snapshots:
        candidates = [b for b in (bound[snapshot.order], after_session.get(snapshot.session))
                      if b is not None]
        stamps, minima = events.get(snapshot.session, ([], []))
        index = bisect.bisect_left(stamps, snapshot.stamp)
        if index < len(stamps):
            candidates.append(minima[index])
        bound[snapshot.order] = min(candidates) if candidates else None
    return bound


def _account(sessions: Sequence[RecordedSession], recorded: _Recorded, replayed: _Replayed,
             pairs: dict[str, list[Pair]], early: dict[str, list[BagMessage]],
             coverage: Coverage, bag: BagContents, spawned: dict[str, Optional[int]],
             compared: set[str]) -> None:
    """Every replayed output the recording lacks: not recorded (the recorder's doing) or
    missing; and the recorded ones before the replay's start (see :mod:`.coverage`)."""
    node_start = _node_start(bag, compared)
    recording_end = max((m.log_ns for m in bag.messages), default=0)
    logs: dict[int, int] = {}   # per snapshot, the earliest log of a recorded output of it
    place_logs: dict[str, dict[int, int]] = {}
    for topic, matched in pairs.items():
        coverage.topic(topic).checked = len(matched)
        outputs = replayed.topics.get(topic, [])
        place_logs[topic] = {}
        for (_, _, _, place), original in zip(matched, _recorded_logs(recorded, topic,
                                                                      matched)):
            order = outputs[place][0]
            place_logs[topic][place] = original
            logs[order] = min(original, logs.get(order, original))
    upper = _upper_bounds(sessions, replayed, logs)
    lower: list[Optional[int]] = []
    latest: Optional[int] = None
    for order in range(len(replayed.snapshots)):
        log = logs.get(order)
        if log is not None and (latest is None or log > latest):
            latest = log
        lower.append(latest)
    unrecorded: list[str] = []
    unrecorded_count = 0
    for topic in sorted(compared):
        outputs = replayed.topics.get(topic, [])
        if not outputs:
            continue
        body = topic.split("/")[1] if topic.count("/") == 2 else ""
        spawn_log = spawned.get(body)
        appear = max(node_start, spawn_log) if spawn_log is not None else node_start
        matched_logs = place_logs.get(topic, {})
        first = min(matched_logs, default=None)
        last = max(matched_logs, default=None)
        last_log = matched_logs[last] if last is not None else None
        required: list[int] = []
        edges: dict[str, list[int]] = {"head": [], "tail": []}
        for place, (order, _) in enumerate(outputs):
            if place in matched_logs:
                continue
            if first is not None and last is not None and first < place < last:
                required.append(place)
            elif first is None or place < first:
                bound = lower[order]
                if bound is not None and bound >= appear + DISCOVERY_NS:
                    required.append(place)
                else:
                    edges["head"].append(place)
            else:
                bound = upper[order]
                limit = max(last_log or 0, recording_end - STOP_NS)
                if bound is not None and bound <= limit:
                    required.append(place)
                else:
                    edges["tail"].append(place)
        coverage_of = coverage.topic(topic)
        if not matched_logs and required:
            unrecorded.append(topic)
            unrecorded_count += len(required)
            why = "none recorded" + ("; accepted: --partial" if coverage.partial else "")
            (coverage_of.not_recorded if coverage.partial else coverage_of.missing).append(
                Stretch(topic, len(outputs), outputs[0][1].log_ns, outputs[-1][1].log_ns, why))
            continue
        for kind, why in (("head", "before the recorder subscribed to it"),
                          ("tail", "after the recorder stopped")):
            for a, b in runs(edges[kind]):
                coverage_of.not_recorded.append(Stretch(topic, b - a + 1, outputs[a][1].log_ns,
                                                        outputs[b][1].log_ns, why))
        _classify(topic, outputs, required, coverage)
    if unrecorded:
        coverage.fail(f"{', '.join(unrecorded)} not recorded: the node published "
                      f"{unrecorded_count} outputs on them while the recorder ran (--topic "
                      "names the topics a recording holds on purpose; --partial accepts a "
                      "partial recording)",
                      missing=True)
    late = [m for messages in early.values() for m in messages
            if m.log_ns > node_start + DISCOVERY_NS]
    if late and not coverage.partial:
        times = sorted(m.log_ns for m in late)
        coverage.fail(f"{len(late)} recorded outputs on "
                      f"{', '.join(sorted({m.topic for m in late}))}, logged "
                      f"{span(times[0], times[-1])}, come before the state the replay starts "
                      "from, though the recorder ran before them")
    else:
        for topic, messages in early.items():
            times = sorted(m.log_ns for m in messages)
            coverage.topic(topic).unchecked.append(Stretch(
                topic, len(messages), times[0], times[-1],
                "logged then; recorded before the first state the replay can start from"))


def _recorded_logs(recorded: _Recorded, topic: str, matched: list[Pair]) -> list[int]:
    """The log times of the matched recorded messages (the pairs hold them re-logged at
    their stamps)."""
    by_index = {m.index: m.log_ns for m, _ in recorded.topics.get(topic, [])}
    return [by_index[message.index] for message, _, _, _ in matched]


def _classify(topic: str, outputs: list[tuple[int, Output]], required: list[int],
              coverage: Coverage) -> None:
    """Outputs a running recorder should have written on ``topic``: short runs, and few,
    are its losses under load; the rest are missing."""
    found = runs(required)
    short = [(a, b) for a, b in found if b - a + 1 <= LOST_RUN]
    allowed = max(1, int(LOST_SHARE * len(outputs)))
    lost = sum(b - a + 1 for a, b in short)
    for a, b in found:
        stretch = Stretch(topic, b - a + 1, outputs[a][1].log_ns, outputs[b][1].log_ns,
                          "lost by the recorder")
        if (a, b) in short and lost <= allowed:
            coverage.topic(topic).not_recorded.append(stretch)
        elif (a, b) in short:
            coverage.add_missing(Stretch(topic, stretch.count, stretch.first_ns,
                                         stretch.last_ns,
                                         f"{lost} of its {len(outputs)} outputs lost, more "
                                         f"than the {LOST_SHARE:.0%} a recorder loses"))
        else:
            coverage.add_missing(Stretch(topic, stretch.count, stretch.first_ns,
                                         stretch.last_ns, "while the recorder ran"))


def _check_keyframes(sessions: Sequence[RecordedSession], replayed: _Replayed,
                     coverage: Coverage, check: LiveCheck) -> None:
    """Every recorded keyframe from the replay's start on must be one the replay took, and
    equal to it; the replay's keyframes between two recorded ones must be recorded."""
    for session in sessions:
        taken = replayed.keyframes.get(session.number, {})
        start = replayed.starts.get(session.number)
        if start is None:
            continue
        end = replayed.ends.get(session.number, start)
        recorded = {k.stamp_ns: k for k in session.keyframes}
        for stamp, keyframe in sorted(recorded.items()):
            if not start <= stamp <= end:
                continue  # before the replay's start, or past its end (failed already)
            mine = taken.get(stamp)
            if mine is not None and session.number in replayed.uncounted:
                mine = _carried(mine, keyframe, renumber=True)
            if mine is None:
                coverage.fail(f"{record_name(keyframe)} is not one the node took (the replay took "
                              "none there)")
            elif mine is keyframe:
                continue  # the keyframe the replay started from
            elif not _same_keyframe(mine, keyframe):
                coverage.fail(f"session {session.number}: the state at {seconds(stamp)} s "
                              f"differs from the recorded keyframe{_older_imu(mine, keyframe)}")
            else:
                check.keyframes_checked += 1
        inside = [stamp for stamp in recorded if stamp >= start]
        first, last = (min(inside), max(inside)) if inside else (None, None)
        if first is not None and last is not None:
            gaps = [stamp for stamp in taken if first < stamp < last
                    and stamp not in recorded]
            if gaps:
                coverage.fail(f"session {session.number}: the keyframe(s) at "
                              + ", ".join(f"{seconds(s)} s" for s in sorted(gaps)[:3])
                              + " missing between recorded ones", missing=True)
        # A recorder stops its subscriptions one by one, so keyframes after the last
        # recorded one may be lost honestly; the outputs around them are still compared.
        after = sorted(stamp for stamp in taken if stamp not in recorded
                       and (last is None or stamp > last))
        if after:
            coverage.notes.append(
                f"session {session.number}: {len(after)} keyframe(s) the replay took from "
                f"{seconds(after[0])} s on are not in the recording (the recorder stopped "
                "before them, or they were removed)")


def _older_imu(mine: KeyframeFields, recorded: KeyframeFields) -> str:
    """Why a keyframe of a scene with an IMU differs when an older version recorded it:
    its IMU read the force terms at the sample's state and kept nothing between stops."""
    try:
        older = "imu" in decode_state(mine.state)["runner"] and \
            "imu" not in decode_state(recorded.state)["runner"]
    except (ValueError, KeyError, TypeError):
        return ""
    return (" (recorded by a version whose IMUs left out contacts and joints: record the "
            "session again)") if older else ""


#: Budget terms of the divergence guard that a later version added (a motor's M): a
#: keyframe recorded before one lacks it, and the replay's is then not compared.
_ADDED_BUDGET_TERMS = ("motor_root",)
#: Where a keyframe's runner state holds the sim time of the node's last diagnostics.
_DIAGNOSTICS_TIME = "last_diagnostics_ns"


def _same_keyframe(mine: KeyframeFields, recorded: KeyframeFields) -> bool:
    """Whether the replay's keyframe holds the recorded one's state: all of it but what the
    divergence guard reports of itself and when the node last published diagnostics. The
    guard's ``worst_ratio`` (how near the run came to the guard's limit) depends on the
    limit's form, and a later version may add a term to the budget (a motor's
    ``motor_root``): neither changes a step, and a session recorded before them must still
    check. The node publishes diagnostics at the end of a timer tick, which a replay does
    not repeat (it stops where the records are), and they change no step and are not
    compared. Every other budget term must be there and equal: a recorded keyframe that
    lacks one, or the guard's budget, differs."""
    if mine == recorded:
        return True
    if mine._replace(state="") != recorded._replace(state=""):
        return False
    try:
        ours, theirs = decode_state(mine.state), decode_state(recorded.state)
        for state in (ours, theirs):
            if isinstance(state.get("runner"), dict):
                state["runner"].pop(_DIAGNOSTICS_TIME, None)
        budgets = ours["divergence"]["bound"], theirs["divergence"]["bound"]
        for budget in budgets:
            budget.pop("worst_ratio", None)
        for key in _ADDED_BUDGET_TERMS:
            if key not in budgets[1]:
                budgets[0].pop(key, None)
    except (ValueError, KeyError, TypeError, AttributeError):
        return False  # no budget where the replay's keyframe has one
    return ours == theirs


def _output_spans(pairs: dict[str, list[Pair]], replayed: _Replayed
                  ) -> dict[int, tuple[int, int]]:
    """Per session, the first and last stamp of its recorded outputs that were checked."""
    stamps: dict[int, list[int]] = defaultdict(list)
    for topic, matched in pairs.items():
        outputs = replayed.topics[topic]
        for _, _, stamp, place in matched:
            stamps[replayed.snapshots[outputs[place][0]].session].append(stamp)
    return {number: (min(found), max(found)) for number, found in stamps.items()}


def _check_inputs(bag: BagContents, sessions: Sequence[RecordedSession],
                  spans: dict[int, tuple[int, int]], topics: dict[str, Optional[InputSource]],
                  coverage: Coverage) -> None:
    """The recorded input messages against the input events (see the module docstring)."""
    recorded: dict[str, list[BagMessage]] = defaultdict(list)
    for message in bag.messages:
        if message.topic in topics:
            recorded[message.topic].append(message)
    # Per topic: the log time of the first event after a silence of DISCOVERY_NS or more
    # (a new publisher, which the recorder matches on its own), and the latest arrival.
    burst: dict[str, int] = {}
    latest: dict[str, int] = {}
    copies: dict[tuple[str, bytes], list[int]] = defaultdict(list)
    unmatched: list[tuple[InputEventFields, int]] = []  # events let pass without a copy
    for topic, messages in recorded.items():
        for message in messages:
            copies[topic, message.raw].append(message.log_ns)
    for session in sessions:
        for sequence, event in sorted(session.events.items()):
            if not isinstance(event, InputEventFields):
                continue
            log = session.event_logs[sequence]
            if event.arrival_ns - latest.get(event.topic, -DISCOVERY_NS) >= DISCOVERY_NS:
                burst[event.topic] = log
            latest[event.topic] = event.arrival_ns
            # Its copy: the latest of the same bytes logged before the node's record of it
            # (give or take INPUT_LAG_NS), which the events before it did not take.
            logs = copies.get((event.topic, input_bytes(event)), [])
            eligible = [t for t in logs if t <= log + INPUT_LAG_NS]
            if eligible:
                logs.remove(max(eligible))
                coverage.inputs += 1
                continue
            messages = recorded.get(event.topic, [])
            within = bool(messages) and messages[0].log_ns <= event.arrival_ns <= \
                messages[-1].log_ns
            first, last = spans.get(session.number, (None, None))
            running = first is not None and last is not None and \
                first <= event.stamp_ns < last
            if (within or running) and log <= burst[event.topic] + DISCOVERY_NS:
                # Its publisher's first messages reach the node before the recorder
                # matches it; equal messages then take each other's copies, so the one
                # found missing is any of that burst's first.
                unmatched.append((event, log))
                coverage.notes.append(
                    f"input event {event.sequence} ({event.topic}, arrived "
                    f"{seconds(event.arrival_ns)} s) not recorded: within "
                    f"{seconds_text(DISCOVERY_NS)} s of the first message after a silence on its "
                    "topic, before the recorder matched a new publisher; its record replayed")
            elif within or running:
                coverage.fail(f"input event {event.sequence} ({event.topic}, arrived "
                              f"{seconds(event.arrival_ns)} s) has no recorded message on "
                              f"{event.topic} logged by the node's record of it, though the "
                              "recorder recorded "
                              + ("that topic" if within else "the node's outputs")
                              + " before and after it: the bag lost, changed or moved it",
                              missing=True)
    left: dict[str, int] = defaultdict(int)
    for (topic, _), logs in copies.items():
        left[topic] += len(logs)
    # A message the recorder logged with an event that has no copy, and that no event
    # took, is that event's message as the node got it, in other bytes than the record's.
    for event, log in unmatched:
        beside = sorted(t for (topic, _), logs in copies.items() if topic == event.topic
                        for t in logs if abs(t - log) <= INPUT_LAG_NS)
        if beside:
            coverage.fail(f"input event {event.sequence} ({event.topic}, arrived "
                          f"{seconds(event.arrival_ns)} s) holds another message than the "
                          f"one recorded on {event.topic} with it, at {seconds(beside[0])} s, "
                          "which no event took")
    for topic, count in sorted(left.items()):
        if count:
            coverage.notes.append(f"{count} message(s) on {topic} that the node did not take "
                                  "(sent before it started, or dropped by its queue)")

