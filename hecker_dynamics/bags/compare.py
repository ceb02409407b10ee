"""Compare two bags: per topic, match messages by stamp and report the largest differences.

:func:`compare_bags` returns a :class:`CompareReport` and a bool (True when the bags match
within the tolerances), so pytest can assert on it and print the report:

    report, ok = compare_bags("expected_bag", "actual_bag", atol=1e-9)
    assert ok, report.text()

Messages are matched by header stamp; messages without a header (``Twist``) by log time
when the bag logs them at sim time (each at a stamp of the sibling ``.../pose`` topic, as
``replay`` writes them), else by the stamp of the same-index message on the sibling topic
when both topics have the same number of messages (a bag recorded from the node logs them
at arrival, not at sim time), else by log time. Several messages with one stamp match in
order. Differences measured:

- position: distance between positions (PoseStamped, Odometry, Marker poses and points,
  TFMessage translations) and the largest difference of a LaserScan's ranges (equal
  infinities differ by 0),
- angle: rotation between orientations (radians, from the quaternions; Imu's too), or the
  difference of the quaternions' lengths where larger (a scaled quaternion turns alike),
- velocity: norm of the linear velocity difference and of the angular one (Twist, Odometry;
  an Imu's linear acceleration and angular velocity, measured with the velocity tolerance).

Every other field (stamps, frames, names, marker types, counts, colours and scales, the
parent and child frames of each transform, ...) must be equal: the message with the
measured fields of the other copied in must have the other's bytes. Diagnostics are
compared by level, name, hardware_id and keys only (their values hold wall times).
Messages of other types are compared byte for byte, and so is every message when all
tolerances are 0 (``--atol 0`` means bit-identical: -0.0 is not 0.0). A message whose
stamp the other bag lacks is missing or extra.
"""
from __future__ import annotations

import math
import os
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Optional, Union

import numpy as np

from ..scene.parameters import seconds_text
from .io import (
    CONTACT_EVENT,
    DIAGNOSTIC_ARRAY,
    IMU,
    JOINT_STATE,
    LASER_SCAN,
    MARKER_ARRAY,
    ODOMETRY,
    POSE_STAMPED,
    TF_MESSAGE,
    TWIST,
    BagContents,
    BagError,
    BagMessage,
    read_bag,
    stamp_ns_of,
)

__all__ = ["Tolerances", "TopicReport", "CompareReport", "compare_bags", "compare_contents",
           "compare_pairs"]

DEFAULT_ATOL = 1e-9
#: How many individual problems a topic report keeps (the counts are always complete).
MAX_DETAILS = 5


@dataclass(frozen=True)
class Tolerances:
    """Absolute tolerances: position (m), angle (rad), velocity (m/s and rad/s)."""

    position: float = DEFAULT_ATOL
    angle: float = DEFAULT_ATOL
    velocity: float = DEFAULT_ATOL

    @classmethod
    def uniform(cls, atol: float) -> Tolerances:
        return cls(atol, atol, atol)

    @property
    def exact(self) -> bool:
        """Whether every tolerance is 0: the messages must be bit-identical."""
        return self.position == self.angle == self.velocity == 0.0


@dataclass
class Worst:
    """The largest difference of one kind, and where it occurred."""

    value: float = 0.0
    stamp_ns: Optional[int] = None

    def update(self, value: float, stamp_ns: int) -> None:
        if value > self.value or (math.isnan(value) and not math.isnan(self.value)):
            self.value = value
            self.stamp_ns = stamp_ns

    def __str__(self) -> str:
        if self.stamp_ns is None:
            return f"{self.value:.3g}"
        return f"{self.value:.3g} (at {seconds_text(self.stamp_ns)} s)"


@dataclass
class TopicReport:
    """The comparison of one topic."""

    topic: str
    msgtype: str
    expected: int = 0
    actual: int = 0
    matched: int = 0
    missing: list[int] = field(default_factory=list)  # stamps only in the expected bag
    extra: list[int] = field(default_factory=list)  # stamps only in the actual bag
    #: Stamps of messages logged after one stamped later, in either bag (the node publishes
    #: in stamp order, so the bag was reordered or tampered with).
    out_of_order: list[int] = field(default_factory=list)
    position: Worst = field(default_factory=Worst)
    angle: Worst = field(default_factory=Worst)
    velocity: Worst = field(default_factory=Worst)
    angular_velocity: Worst = field(default_factory=Worst)
    different: int = 0  # matched messages whose exact fields differ
    details: list[str] = field(default_factory=list)

    def ok(self, tol: Tolerances) -> bool:
        return (not self.missing and not self.extra and not self.different
                and not self.out_of_order and _within(self.position.value, tol.position)
                and _within(self.angle.value, tol.angle)
                and _within(self.velocity.value, tol.velocity)
                and _within(self.angular_velocity.value, tol.velocity))

    def note(self, text: str) -> None:
        self.different += 1
        if len(self.details) < MAX_DETAILS:
            self.details.append(text)


def _within(value: float, atol: float) -> bool:
    return value <= atol  # NaN compares False: a NaN difference fails


@dataclass
class CompareReport:
    """The comparison of two bags: one :class:`TopicReport` per topic compared."""

    expected_path: str
    actual_path: str
    tolerances: Tolerances
    topics: list[TopicReport] = field(default_factory=list)
    missing_topics: list[str] = field(default_factory=list)
    extra_topics: list[str] = field(default_factory=list)
    type_mismatches: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return (not self.missing_topics and not self.extra_topics and not self.type_mismatches
                and all(t.ok(self.tolerances) for t in self.topics))

    def largest(self) -> dict[str, float]:
        """The largest position, angle, velocity and angular velocity difference overall
        (NaN when any topic's is: a NaN difference fails, so it must show)."""
        largest = {}
        for kind in ("position", "angle", "velocity", "angular_velocity"):
            overall = Worst()
            for t in self.topics:
                overall.update(getattr(t, kind).value, 0)
            largest[kind] = overall.value
        return largest

    def text(self) -> str:
        """A readable report, one topic per paragraph."""
        tol = self.tolerances
        lines = [f"expected: {self.expected_path}", f"actual:   {self.actual_path}",
                 f"tolerance: position {tol.position:g} m, angle {tol.angle:g} rad, "
                 f"velocity {tol.velocity:g}"]
        for topic in self.missing_topics:
            lines.append(f"MISSING TOPIC {topic}: in the expected bag only")
        for topic in self.extra_topics:
            lines.append(f"EXTRA TOPIC   {topic}: in the actual bag only")
        for text in self.type_mismatches:
            lines.append(f"TYPE MISMATCH {text}")
        for t in self.topics:
            status = "ok  " if t.ok(tol) else "FAIL"
            lines.append(f"{status} {t.topic} ({t.msgtype}): {t.matched} matched of "
                         f"{t.expected} expected / {t.actual} actual")
            if t.missing:
                lines.append(f"     missing {len(t.missing)}: first at "
                             f"{seconds_text(min(t.missing))} s")
            if t.extra:
                lines.append(f"     extra {len(t.extra)}: first at {seconds_text(min(t.extra))} s")
            if t.out_of_order:
                lines.append(f"     {_disorder(t.out_of_order)}")
            measured = [(name, w) for name, w in (
                ("position", t.position), ("angle", t.angle), ("velocity", t.velocity),
                ("angular velocity", t.angular_velocity)) if w.stamp_ns is not None]
            if measured:
                lines.append("     largest " + ", ".join(f"{n} {w}" for n, w in measured))
            if t.different:
                lines.append(f"     {t.different} message(s) differ in exact fields:")
                lines.extend(f"       {d}" for d in t.details)
        if any(t.matched for t in self.topics):
            big = self.largest()
            lines.append("largest overall: " + ", ".join(f"{k} {v:.3g}" for k, v in big.items()))
        else:
            lines.append("largest overall: none (no message of one bag matched one of the other)")
        lines.append("MATCH" if self.ok else "MISMATCH")
        return "\n".join(lines)

    def summary(self) -> str:
        """One line: match or what mismatched."""
        if self.ok:
            big = self.largest()
            return ("match: " + f"{sum(t.matched for t in self.topics)} messages on "
                    f"{len(self.topics)} topics; largest difference position "
                    f"{big['position']:.3g}, angle {big['angle']:.3g}, velocity "
                    f"{max(big['velocity'], big['angular_velocity']):.3g}")
        problems = []
        if self.missing_topics:
            problems.append(f"missing topics {', '.join(self.missing_topics)}")
        if self.extra_topics:
            problems.append(f"extra topics {', '.join(self.extra_topics)}")
        problems.extend(f"type of {t}" for t in self.type_mismatches)
        for t in self.topics:
            if not t.ok(self.tolerances):
                parts = []
                if t.missing:
                    parts.append(f"{len(t.missing)} missing")
                if t.extra:
                    parts.append(f"{len(t.extra)} extra")
                if t.out_of_order:
                    parts.append(_disorder(t.out_of_order))
                if t.different:
                    parts.append(f"{t.different} differ")
                for kind, tol in (("position", self.tolerances.position),
                                  ("angle", self.tolerances.angle),
                                  ("velocity", self.tolerances.velocity),
                                  ("angular_velocity", self.tolerances.velocity)):
                    worst = getattr(t, kind)
                    if not _within(worst.value, tol):
                        parts.append(f"{kind.replace('_', ' ')} {worst}")
                problems.append(f"{t.topic}: {', '.join(parts)}")
        return "mismatch: " + "; ".join(problems)


def _disorder(stamps: Sequence[int]) -> str:
    return (f"{len(stamps)} logged after a later stamp (out of order), first stamped "
            f"{seconds_text(stamps[0])} s")


# ----------------------------------------------------------------------------- matching

def _late(keys: Sequence[int]) -> list[int]:
    """The stamps that come, in log order, after a later one."""
    late, latest = [], None
    for key in keys:
        if latest is not None and key < latest:
            late.append(key)
        else:
            latest = key
    return late


def _keys(messages: Sequence[BagMessage], decoded: Sequence[Any],
          sibling: Optional[tuple[list[int], bool]]) -> list[int]:
    """Each message's stamp; for messages without a header, see the module docstring
    (``sibling``: the sibling topic's stamps sorted, and whether it is logged at them)."""
    stamps = [stamp_ns_of(msg) for msg in decoded]
    if all(s is not None for s in stamps):
        return stamps  # type: ignore[return-value]
    # A bag logged at sim time (replay's, script's) logs each twist at its instant: that
    # places it even when a twist and a pose of other instants are lost, where the i-th
    # pose's stamp would give every twist between the two its neighbour's.
    if sibling is not None and not sibling[1] and len(sibling[0]) == len(messages):
        return list(sibling[0])
    return [m.log_ns for m in messages]


def _group(keys: Sequence[int]) -> dict[tuple[int, int], int]:
    """Key each message by (stamp, occurrence of that stamp) -> index."""
    seen: dict[int, int] = defaultdict(int)
    out = {}
    for index, key in enumerate(keys):
        out[(key, seen[key])] = index
        seen[key] += 1
    return out


# ----------------------------------------------------------------------------- differences

def _distance(a: Any, b: Any) -> float:
    """|a - b|: exactly 0 only for equal vectors (hypot does not underflow as the sum of
    squares does: 7.3e-304 apart is 7.3e-304, not 0), NaN where a component is NaN."""
    if (a.x, a.y, a.z) == (b.x, b.y, b.z):
        return 0.0
    return math.hypot(a.x - b.x, a.y - b.y, a.z - b.z)


def _rotation_angle(qa: Any, qb: Any) -> float:
    """Angle of the rotation between two quaternions (accurate for tiny angles too).

    The rotation depends on the quaternions' directions only, so their lengths' difference
    counts as an angle too: a quaternion of length 2, or 0, is no orientation a run
    publishes, and must not match a unit one within a tolerance. Only equal quaternions
    give 0: unequal ones too close for the products to resolve give the smallest positive
    double, so that ``--atol 0`` means bit-identical."""
    if (qa.x, qa.y, qa.z, qa.w) == (qb.x, qb.y, qb.z, qb.w):
        return 0.0
    # q_rel = conj(qa) * qb
    w = qa.w * qb.w + qa.x * qb.x + qa.y * qb.y + qa.z * qb.z
    x = qa.w * qb.x - qa.x * qb.w - qa.y * qb.z + qa.z * qb.y
    y = qa.w * qb.y + qa.x * qb.z - qa.y * qb.w - qa.z * qb.x
    z = qa.w * qb.z - qa.x * qb.y + qa.y * qb.x - qa.z * qb.w
    stretch = abs(math.hypot(qa.x, qa.y, qa.z, qa.w) - math.hypot(qb.x, qb.y, qb.z, qb.w))
    angle = max(2.0 * math.atan2(math.hypot(x, y, z), abs(w)), stretch)
    return angle if angle != 0.0 else math.ulp(0.0)


def _pose(report: TopicReport, a: Any, b: Any, stamp: int) -> None:
    report.position.update(_distance(a.position, b.position), stamp)
    report.angle.update(_rotation_angle(a.orientation, b.orientation), stamp)


def _twist(report: TopicReport, a: Any, b: Any, stamp: int) -> None:
    report.velocity.update(_distance(a.linear, b.linear), stamp)
    report.angular_velocity.update(_distance(a.angular, b.angular), stamp)


def _ranges(report: TopicReport, a: Any, b: Any, stamp: int) -> None:
    if len(a.ranges) != len(b.ranges):
        report.note(f"at {seconds_text(stamp)} s: {len(a.ranges)} ranges != {len(b.ranges)}")
        return
    ra, rb = np.asarray(a.ranges, dtype=float), np.asarray(b.ranges, dtype=float)
    with np.errstate(invalid="ignore"):
        differences = np.where(ra == rb, 0.0, np.abs(ra - rb))
    # NaN where a range is NaN, so that it fails; the largest difference otherwise.
    report.position.update(float(np.max(differences, initial=0.0))
                           if not np.isnan(differences).any() else math.nan, stamp)


def _header(report: TopicReport, a: Any, b: Any, stamp: int) -> None:
    if a.header.frame_id != b.header.frame_id:
        report.note(f"at {seconds_text(stamp)} s: frame_id '{a.header.frame_id}' != "
                    f"'{b.header.frame_id}'")


#: Per structured type, where its measured vectors and quaternions are: ``(path, ...)``
#: from the message, ``*`` for every item of a sequence.
_MEASURED: dict[str, tuple[tuple[str, ...], ...]] = {
    POSE_STAMPED: (("pose", "position"), ("pose", "orientation")),
    TWIST: (("linear",), ("angular",)),
    ODOMETRY: (("pose", "pose", "position"), ("pose", "pose", "orientation"),
               ("twist", "twist", "linear"), ("twist", "twist", "angular")),
    MARKER_ARRAY: (("markers", "*", "pose", "position"), ("markers", "*", "pose", "orientation"),
                   ("markers", "*", "points", "*")),
    TF_MESSAGE: (("transforms", "*", "transform", "translation"),
                 ("transforms", "*", "transform", "rotation")),
    IMU: (("orientation",), ("angular_velocity",), ("linear_acceleration",)),
    LASER_SCAN: (),
}
#: Per structured type, its measured arrays (copied whole by :func:`_same_elsewhere`).
_MEASURED_ARRAYS: dict[str, tuple[str, ...]] = {LASER_SCAN: ("ranges",)}
#: Per type compared byte for byte, its numbers, which a run publishes finite only.
_NUMBERS: dict[str, tuple[str, ...]] = {JOINT_STATE: ("position", "velocity", "effort"),
                                        CONTACT_EVENT: ("normal_impulse", "tangent_impulse")}


def _items(msg: Any, path: tuple[str, ...]) -> list[Any]:
    """The objects at ``path`` in ``msg`` (``*``: each item of a sequence)."""
    found = [msg]
    for name in path:
        found = [item for obj in found
                 for item in (list(obj) if name == "*" else [getattr(obj, name)])]
    return found


def _same_elsewhere(msgtype: str, a: Any, b: Any, raw_a: bytes) -> bool:
    """Whether ``b`` with the measured vectors of ``a`` copied in serializes to ``raw_a``:
    every field but the measured ones is equal (``a`` and ``b`` of equal structure)."""
    from .io import typestore

    for path in _MEASURED[msgtype]:
        for source, target in zip(_items(a, path), _items(b, path)):
            for name in ("x", "y", "z", "w"):
                if hasattr(source, name):
                    setattr(target, name, getattr(source, name))
    for name in _MEASURED_ARRAYS.get(msgtype, ()):
        setattr(b, name, getattr(a, name))
    try:
        return bytes(typestore().serialize_cdr(b, msgtype)) == raw_a
    except Exception:  # a field of b the serializer refuses: not equal
        return False


def _finite(msgtype: str, msg: Any) -> bool:
    """Whether the measured fields of ``msg`` hold what a run publishes: finite vectors
    and quaternions, ranges that are not NaN (a ray that hits nothing reads infinity)."""
    for path in _MEASURED.get(msgtype, ()):
        for item in _items(msg, path):
            if not all(math.isfinite(getattr(item, name)) for name in ("x", "y", "z", "w")
                       if hasattr(item, name)):
                return False
    return not any(np.isnan(getattr(msg, name)).any()
                   for name in _MEASURED_ARRAYS.get(msgtype, ())) and \
        all(np.isfinite(getattr(msg, name)).all() for name in _NUMBERS.get(msgtype, ()))


def _compare_message(report: TopicReport, msgtype: str, ea: BagMessage, a: Any,
                     eb: BagMessage, b: Any, stamp: int, exact: bool = False) -> None:
    """Measure the differences of one matched pair into ``report`` and note those in the
    fields that must be equal; ``exact``: the bytes must be equal too. A value that is
    not finite is no state of a run (the divergence check stops one first): equal in both
    bags, it is noted, never a match."""
    what = "number" if msgtype in _NUMBERS else "position, angle or velocity"
    unrun = f"at {seconds_text(stamp)} s: a {what} that is not finite (NaN or infinite) in " \
            "both bags"
    if a is None and msgtype in _NUMBERS:  # compared byte for byte, but read for its numbers
        a = ea.decode()
    if exact and ea.raw == eb.raw:
        if a is not None and not _finite(msgtype, a):
            report.note(unrun)
        return
    pair = TopicReport(report.topic, msgtype)
    _measure(pair, msgtype, ea, a, eb, b, stamp)
    if not pair.different and a is not None and not _finite(msgtype, a):
        pair.note(unrun)  # equal infinities differ by 0
    measured = (pair.position, pair.angle, pair.velocity, pair.angular_velocity)
    if not pair.different and msgtype in _MEASURED and not _same_elsewhere(msgtype, a, b,
                                                                           ea.raw):
        pair.note(f"at {seconds_text(stamp)} s: fields other than positions, angles and "
                  "velocities differ")
    elif exact and not pair.different and msgtype != DIAGNOSTIC_ARRAY \
            and not any(w.value for w in measured):
        pair.note(f"at {seconds_text(stamp)} s: message bytes differ (equal values: a zero's "
                  "sign or a NaN's bits; --atol 0 asks for bit-identical messages)")
    for name in ("position", "angle", "velocity", "angular_velocity"):
        worst = getattr(pair, name)
        if worst.stamp_ns is not None:
            getattr(report, name).update(worst.value, worst.stamp_ns)
    for detail in pair.details:
        report.note(detail)


def _measure(report: TopicReport, msgtype: str, ea: BagMessage, a: Any,
             eb: BagMessage, b: Any, stamp: int) -> None:
    if msgtype == POSE_STAMPED:
        _header(report, a, b, stamp)
        _pose(report, a.pose, b.pose, stamp)
    elif msgtype == TWIST:
        _twist(report, a, b, stamp)
    elif msgtype == ODOMETRY:
        _header(report, a, b, stamp)
        if a.child_frame_id != b.child_frame_id:
            report.note(f"at {seconds_text(stamp)} s: child_frame_id '{a.child_frame_id}' != "
                        f"'{b.child_frame_id}'")
        _pose(report, a.pose.pose, b.pose.pose, stamp)
        _twist(report, a.twist.twist, b.twist.twist, stamp)
    elif msgtype == MARKER_ARRAY:
        if len(a.markers) != len(b.markers):
            report.note(f"at {seconds_text(stamp)} s: {len(a.markers)} markers != "
                        f"{len(b.markers)}")
            return
        for ma, mb in zip(a.markers, b.markers):
            same = (ma.ns, ma.id, ma.type, ma.action, ma.header.frame_id, len(ma.points)) == \
                   (mb.ns, mb.id, mb.type, mb.action, mb.header.frame_id, len(mb.points))
            if not same:
                report.note(f"at {seconds_text(stamp)} s: marker {ma.ns}/{ma.id} differs in "
                            "ns, id, type, action, frame or point count")
                continue
            _pose(report, ma.pose, mb.pose, stamp)
            for pa, pb in zip(ma.points, mb.points):
                report.position.update(_distance(pa, pb), stamp)
    elif msgtype == TF_MESSAGE:
        frames_a = [(t.header.frame_id, t.child_frame_id) for t in a.transforms]
        if frames_a != [(t.header.frame_id, t.child_frame_id) for t in b.transforms]:
            report.note(f"at {seconds_text(stamp)} s: transforms of other frames")
            return
        for ta, tb in zip(a.transforms, b.transforms):
            report.position.update(_distance(ta.transform.translation,
                                             tb.transform.translation), stamp)
            report.angle.update(_rotation_angle(ta.transform.rotation, tb.transform.rotation),
                                stamp)
    elif msgtype == LASER_SCAN:
        _header(report, a, b, stamp)
        _ranges(report, a, b, stamp)
    elif msgtype == IMU:
        _header(report, a, b, stamp)
        report.angle.update(_rotation_angle(a.orientation, b.orientation), stamp)
        report.velocity.update(_distance(a.linear_acceleration, b.linear_acceleration), stamp)
        report.angular_velocity.update(_distance(a.angular_velocity, b.angular_velocity),
                                       stamp)
    elif msgtype == DIAGNOSTIC_ARRAY:
        sa = [(s.level, s.name, s.hardware_id, tuple(v.key for v in s.values)) for s in a.status]
        sb = [(s.level, s.name, s.hardware_id, tuple(v.key for v in s.values)) for s in b.status]
        if sa != sb:
            report.note(f"at {seconds_text(stamp)} s: diagnostic status (level, name, "
                        "hardware_id or keys) differs")
    elif ea.raw != eb.raw:
        report.note(f"at {seconds_text(stamp)} s: message bytes differ")


def _decode_all(messages: Sequence[BagMessage]) -> list[Any]:
    return [m.decode() for m in messages]


#: The types compared field by field (the rest byte for byte).
_STRUCTURED = (POSE_STAMPED, TWIST, ODOMETRY, MARKER_ARRAY, DIAGNOSTIC_ARRAY, TF_MESSAGE,
               LASER_SCAN, IMU)


def compare_pairs(topic: str, msgtype: str,
                  pairs: Sequence[tuple[BagMessage, BagMessage, int]],
                  tolerances: Tolerances) -> TopicReport:
    """The report of ``topic`` whose messages were matched already: each pair is the
    expected message, the actual one and the stamp they share."""
    report = TopicReport(topic, msgtype, expected=len(pairs), actual=len(pairs),
                         matched=len(pairs))
    exact = tolerances.exact
    for ea, eb, stamp in pairs:
        if exact and ea.raw == eb.raw:
            continue
        if msgtype in _STRUCTURED:
            _compare_message(report, msgtype, ea, ea.decode(), eb, eb.decode(), stamp, exact)
        else:
            _compare_message(report, msgtype, ea, None, eb, None, stamp, exact)
    return report


def _compare_topic(topic: str, msgtype: str, expected: BagContents,
                   actual: BagContents, exact: bool) -> TopicReport:
    report = TopicReport(topic, msgtype)
    ea, aa = expected.on(topic), actual.on(topic)
    report.expected, report.actual = len(ea), len(aa)
    structured = msgtype in _STRUCTURED
    if structured:
        da, db = _decode_all(ea), _decode_all(aa)
    else:
        da, db = [None] * len(ea), [None] * len(aa)

    def sibling(bag: BagContents) -> Optional[tuple[list[int], bool]]:
        if not topic.endswith("/twist"):
            return None
        pose_topic = topic[: -len("/twist")] + "/pose"
        if bag.topics.get(pose_topic) != POSE_STAMPED:
            return None
        poses = [(m.log_ns, stamp) for m in bag.on(pose_topic)
                 if (stamp := stamp_ns_of(m.decode())) is not None]  # always: PoseStamped
        # In stamp order: the i-th twist logged is the i-th instant published. A pose
        # logged out of order is the pose topic's fault, said there, not the twist's.
        return sorted(stamp for _, stamp in poses), all(log == stamp for log, stamp in poses)

    if structured:
        ka = _keys(ea, da, sibling(expected))
        kb = _keys(aa, db, sibling(actual))
        report.out_of_order = _late(ka) + _late(kb)
    else:
        ka, kb = [m.log_ns for m in ea], [m.log_ns for m in aa]
    ga, gb = _group(ka), _group(kb)
    for key, ia in ga.items():
        ib = gb.get(key)
        if ib is None:
            report.missing.append(key[0])
            continue
        report.matched += 1
        _compare_message(report, msgtype, ea[ia], da[ia], aa[ib], db[ib], key[0], exact)
    report.extra = [key[0] for key in gb if key not in ga]
    return report


def compare_contents(expected: BagContents, actual: BagContents, *,
                     tolerances: Optional[Tolerances] = None,
                     topics: Optional[Iterable[str]] = None) -> tuple[CompareReport, bool]:
    """Compare two bags already read; ``topics`` limits the comparison (default: all)."""
    tol = tolerances or Tolerances()
    report = CompareReport(str(expected.path), str(actual.path), tol)
    if topics is None:
        names = sorted(set(expected.topics) | set(actual.topics))
    else:
        names = list(dict.fromkeys(topics))
    for topic in names:
        in_a, in_b = topic in expected.topics, topic in actual.topics
        if not in_a and not in_b:
            known = sorted(set(expected.topics) | set(actual.topics))
            raise BagError(f"topic '{topic}' is in neither bag (their topics: "
                           f"{', '.join(known[:6]) or 'none'}{', ...' if len(known) > 6 else ''})")
        if not in_b:
            report.missing_topics.append(topic)
            continue
        if not in_a:
            report.extra_topics.append(topic)
            continue
        if expected.topics[topic] != actual.topics[topic]:
            report.type_mismatches.append(f"{topic}: expected {expected.topics[topic]}, "
                                          f"actual {actual.topics[topic]}")
            continue
        hashes = expected.digests.get(topic, ""), actual.digests.get(topic, "")
        if all(hashes) and hashes[0] != hashes[1]:  # '' where a bag has none (before Jazzy)
            report.type_mismatches.append(f"{topic}: {expected.topics[topic]} of type hash "
                                          f"{hashes[0]} expected, {hashes[1]} actual")
            continue
        report.topics.append(_compare_topic(topic, expected.topics[topic], expected, actual,
                                            tol.exact))
    return report, report.ok


def _topic_list(bag: BagContents) -> str:
    names = sorted(bag.topics)
    return f"{bag.path}: {', '.join(names[:4])}{', ...' if len(names) > 4 else ''}"


def compare_bags(expected: Union[str, os.PathLike[str], BagContents],
                 actual: Union[str, os.PathLike[str], BagContents], *, atol: Optional[float] = None,
                 tolerances: Optional[Tolerances] = None,
                 topics: Optional[Iterable[str]] = None) -> tuple[CompareReport, bool]:
    """Compare the ``expected`` bag with the ``actual`` one (paths or read bags).

    ``atol`` sets one tolerance for positions, angles and velocities; ``tolerances`` sets
    them one by one. Returns the report and whether the bags match. Raises
    :class:`~hecker_dynamics.bags.io.BagError` if a bag cannot be read, or if neither holds
    a message on the topics compared (two emptied bags are no match).
    """
    if tolerances is None:
        tolerances = Tolerances.uniform(atol) if atol is not None else Tolerances()
    wanted = list(topics) if topics is not None else None
    # Twists are matched through their sibling poses, so read those too.
    reading = None if wanted is None else wanted + [
        t[: -len("/twist")] + "/pose" for t in wanted if t.endswith("/twist")]
    a = expected if isinstance(expected, BagContents) else read_bag(expected, reading)
    b = actual if isinstance(actual, BagContents) else read_bag(actual, reading)
    if wanted is None and a.topics and b.topics and not set(a.topics) & set(b.topics):
        raise BagError(f"{a.path} and {b.path} have no topic in common ({_topic_list(a)}; "
                       f"{_topic_list(b)}); nothing to compare")
    report, ok = compare_contents(a, b, tolerances=tolerances, topics=wanted)
    if ok and not any(t.expected or t.actual for t in report.topics):
        raise BagError(f"{a.path} and {b.path}: neither bag holds a message"
                       f"{' on the topics given' if wanted else ''}; nothing to compare")
    return report, ok

