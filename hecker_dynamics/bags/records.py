"""The node's session records in a recorded bag, read and cross-checked.

A recording of the node holds its records (:mod:`hecker_dynamics.ros.session`): the session
records (``~/session``), the input and world events (``~/input_events``,
``~/world_events``, one sequence) and the keyframes (``~/keyframe``). They are read here
into one :class:`RecordedSession` per session, and what contradicts goes to the coverage's
failures (:mod:`.coverage`): two different records of one session, event number or
keyframe; a record outside its session (an event numbered before its session's first or
after the next session's; a keyframe before its session's start); records logged out of
the order the node publishes them in; a session record missing between two recorded ones,
or records of a session whose record is missing; a keyframe or event naming a frame; an
input event holding a message in a slot its kind leaves empty; a record that cannot be
read. Records recorded twice with the same content count once;
records of sessions before the first recorded one (received latched by a recorder that
started late) are noted and left out.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Optional, Union

from ..ros.session import (
    APPLIED_WRENCH_EVENT,
    CMD_VEL_EVENT,
    MOTOR_SPEED_EVENT,
    WRENCH_STAMPED_EVENT,
    InputEventFields,
    KeyframeFields,
    SessionFields,
    WorldChange,
    WorldEventFields,
    decode_state,
)
from ..scene.world import EditKind, WorldEdit
from . import io as bags
from .coverage import Coverage, seconds
from .io import INPUT_EVENT, KEYFRAME, SESSION_INFO, WORLD_EVENT, BagContents, BagError, BagMessage
from .replay import ReplayError

#: What a session's event sequence holds.
Event = Union[InputEventFields, WorldEventFields]
Record = Union[SessionFields, KeyframeFields, InputEventFields, WorldEventFields]
#: The message types of the records.
RECORD_TYPES = (SESSION_INFO, KEYFRAME, INPUT_EVENT, WORLD_EVENT)

__all__ = ["Event", "Record", "RECORD_TYPES", "RecordedSession", "is_live_recording",
           "recorded_sessions", "record_name", "input_bytes", "spawned_bodies", "gaps",
           "ranges_text"]


@dataclass
class RecordedSession:
    """What a bag holds of one session of the node, with the log time of each record."""

    info: SessionFields
    info_log_ns: int
    keyframes: list[KeyframeFields] = field(default_factory=list)
    keyframe_logs: dict[int, int] = field(default_factory=dict)   # stamp -> log time
    #: Input events and world changes by their shared sequence number.
    events: dict[int, Event] = field(default_factory=dict)
    event_logs: dict[int, int] = field(default_factory=dict)      # sequence -> log time

    @property
    def number(self) -> int:
        return self.info.session


def is_live_recording(bag: BagContents) -> bool:
    """Whether the bag holds the node's session records (a live recording): a topic of any
    of their types."""
    return any(msgtype in RECORD_TYPES for msgtype in bag.topics.values())


def _decode_record(message: BagMessage, msgtype: str, coverage: Coverage) -> Optional[Record]:
    """The record a message holds, or None (and a failure) if it cannot be read."""
    try:
        msg = message.decode()
        if msgtype == SESSION_INFO:
            return bags.session_fields(msg)
        if msg.header.frame_id:
            coverage.fail(f"record {message.index} on '{message.topic}' logged at "
                          f"{seconds(message.log_ns)} s names a frame "
                          f"({msg.header.frame_id!r}), which the node never does")
            return None
        if msgtype == KEYFRAME:
            return bags.keyframe_fields(msg)
        if msgtype == INPUT_EVENT:
            unused = bags.input_event_unused_slots(msg)
            if unused:
                coverage.fail(f"record {message.index} on '{message.topic}' logged at "
                              f"{seconds(message.log_ns)} s holds a message in "
                              f"{', '.join(unused)}, which its kind ({msg.kind}) leaves "
                              "empty and the node never fills")
                return None
            return bags.input_event_fields(msg)
        return bags.world_event_fields(msg)
    except BagError as error:
        coverage.fail(f"{error}")
    except (ValueError, TypeError, AttributeError, OverflowError) as error:
        coverage.fail(f"record {message.index} on '{message.topic}' logged at "
                      f"{seconds(message.log_ns)} s cannot be read: {error}")
    return None


def _order_key(record: Record) -> tuple[int, int]:
    """The order the node publishes records of one kind in."""
    if isinstance(record, SessionFields):
        return record.session, 0
    if isinstance(record, KeyframeFields):
        return record.session, record.stamp_ns
    return record.session, record.sequence


def recorded_sessions(bag: BagContents, coverage: Optional[Coverage] = None
                      ) -> dict[int, RecordedSession]:
    """The sessions of the node recorded in ``bag``, by session number; what contradicts
    goes to ``coverage.failures`` (see the module docstring)."""
    coverage = coverage if coverage is not None else Coverage()
    read: list[tuple[BagMessage, Record]] = []
    last: dict[str, tuple[tuple[int, int], Record]] = {}
    for message in bag.messages:
        msgtype = bag.topics[message.topic]
        if msgtype not in RECORD_TYPES:
            continue
        record = _decode_record(message, msgtype, coverage)
        if record is None:
            continue
        key = _order_key(record)
        previous = last.get(message.topic)
        if previous is not None and key < previous[0]:
            coverage.fail(f"{message.topic}: the record logged at {seconds(message.log_ns)} s "
                          f"({record_name(record)}) comes after {record_name(previous[1])}: "
                          "out of place")
        last[message.topic] = (key, record)
        read.append((message, record))
    sessions: dict[int, RecordedSession] = {}
    for message, record in read:
        if isinstance(record, SessionFields):
            known = sessions.get(record.session)
            if known is None:
                sessions[record.session] = RecordedSession(record, message.log_ns)
            elif known.info != record:
                coverage.fail(f"two different records of session {record.session}")
    numbers = sorted(sessions)
    absent = gaps(numbers, numbers[0], numbers[-1] + 1) if numbers else []
    if absent:
        coverage.fail(f"the record(s) of session(s) {ranges_text(absent)} missing (sessions "
                      f"{numbers[0]} to {numbers[-1]} are recorded)")
    earlier = 0
    for message, record in read:
        if isinstance(record, SessionFields):
            continue
        session = sessions.get(record.session)
        if session is None:
            if numbers and record.session < numbers[0]:
                earlier += 1  # latched records of a session before the recording
            else:
                coverage.fail(f"{record_name(record)} belongs to session {record.session}, whose "
                              "session record is missing")
            continue
        if isinstance(record, KeyframeFields):
            _add_keyframe(session, record, message.log_ns, coverage)
        else:
            _add_event(session, record, message.log_ns, sessions, coverage)
    if earlier:
        coverage.notes.append(f"{earlier} record(s) of sessions before the first recorded one "
                              "(received latched by a recorder that started late) not used")
    for session in sessions.values():
        session.keyframes.sort(key=lambda k: k.stamp_ns)
    return sessions


def record_name(record: Record) -> str:
    if isinstance(record, SessionFields):
        return f"the record of session {record.session}"
    if isinstance(record, KeyframeFields):
        return f"the keyframe of session {record.session} at {seconds(record.stamp_ns)} s"
    kind = "input" if isinstance(record, InputEventFields) else "world"
    return f"{kind} event record {record.sequence} of session {record.session}"


def _add_keyframe(session: RecordedSession, keyframe: KeyframeFields, log_ns: int,
                  coverage: Coverage) -> None:
    known = next((k for k in session.keyframes if k.stamp_ns == keyframe.stamp_ns), None)
    if known is not None:
        if known != keyframe:
            coverage.fail(f"two different keyframes of session {session.number} at "
                          f"{seconds(keyframe.stamp_ns)} s")
        return
    if keyframe.stamp_ns < session.info.start_ns or keyframe.next_event < session.info.next_event:
        coverage.fail(f"{record_name(keyframe)} (next event {keyframe.next_event}) is outside its "
                      f"session, which starts at {seconds(session.info.start_ns)} s with event "
                      f"{session.info.next_event}")
        return
    session.keyframes.append(keyframe)
    session.keyframe_logs[keyframe.stamp_ns] = log_ns


def _add_event(session: RecordedSession, event: Event, log_ns: int,
               sessions: dict[int, RecordedSession], coverage: Coverage) -> None:
    known = session.events.get(event.sequence)
    if known is not None:
        if not _same_event(known, event):
            coverage.fail(f"two different event records numbered {event.sequence} in session "
                          f"{session.number}")
        return
    following = sessions.get(session.number + 1)
    if event.sequence < session.info.next_event:
        # The node numbers the inputs it refuses before its first tick in session 0.
        if session.number == 0 and not event.accepted:
            return
        coverage.fail(f"{record_name(event)} comes before its session, which starts with event "
                      f"{session.info.next_event}: out of place")
    elif following is not None and event.sequence >= following.info.next_event:
        coverage.fail(f"{record_name(event)} comes after its session, which ends before event "
                      f"{following.info.next_event}: out of place")
    else:
        session.events[event.sequence] = event
        session.event_logs[event.sequence] = log_ns


def _same_event(a: Event, b: Event) -> bool:
    """Equal records (an input event's message compared by its serialized bytes)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, InputEventFields) and isinstance(b, InputEventFields):
        return a._replace(message=None) == b._replace(message=None) and \
            input_bytes(a) == input_bytes(b)
    return a == b


def input_bytes(event: InputEventFields) -> bytes:
    kind = {APPLIED_WRENCH_EVENT: bags.APPLIED_WRENCH, WRENCH_STAMPED_EVENT: bags.WRENCH_STAMPED,
            MOTOR_SPEED_EVENT: bags.FLOAT64, CMD_VEL_EVENT: bags.TWIST}.get(event.kind,
                                                                           bags.APPLIED_WRENCH)
    try:
        return bytes(bags.typestore().serialize_cdr(event.message, kind))
    except Exception:  # a message the kind does not fit: compared as unequal to any other
        return repr(event.message).encode()


def spawned_bodies(sessions: Iterable[RecordedSession]) -> dict[str, Optional[int]]:
    """The bodies spawned in ``sessions``, by their records (the world events and the edits
    the keyframes hold), with the log time of the first spawn record of each (None when
    only a keyframe tells of it)."""
    names: dict[str, Optional[int]] = {}
    for session in sessions:
        for sequence, event in sorted(session.events.items()):
            if isinstance(event, WorldEventFields) and event.kind is WorldChange.SPAWN \
                    and event.accepted:
                names.setdefault(event.body, session.event_logs[sequence])
        for keyframe in session.keyframes:
            for edit in _keyframe_edits(keyframe):
                if edit.kind is EditKind.SPAWN:
                    names.setdefault(edit.body, None)
    return names


def _keyframe_edits(keyframe: KeyframeFields) -> list[WorldEdit]:
    try:
        return [WorldEdit.from_data(data)
                for data in decode_state(keyframe.state).get("world", [])]
    except (ValueError, TypeError, AttributeError, KeyError) as error:
        raise ReplayError(f"the keyframe of session {keyframe.session} at "
                          f"{seconds(keyframe.stamp_ns)} s has a bad world: {error}") from None


def gaps(held: list[int], first: int, end: int) -> list[tuple[int, int]]:
    """The runs (first, last) of numbers from ``first`` to before ``end`` that the sorted
    ``held`` lacks (without counting them one by one: a record may claim any number)."""
    gaps = []
    expected = first
    for number in held + [end]:
        if number > expected:
            gaps.append((expected, min(number, end) - 1))
        expected = max(expected, number + 1)
        if expected >= end:
            break
    return [(a, b) for a, b in gaps if a <= b]


def ranges_text(found: list[tuple[int, int]]) -> str:
    shown = [str(first) if first == last else f"{first} to {last}" for first, last in found]
    return ", ".join(shown[:4]) + (f" and {len(shown) - 4} more runs" if len(shown) > 4 else "")
