"""What a check of a recording compared, what it could not, and why (``replay --check``,
``regress``).

A check compares every recorded output with its replayed counterpart, and every output the
replay publishes with the recording's. What the recording lacks is one of:

- **not recorded**, and the recorder's doing, as ``ros2 bag record`` does it: outputs
  published before it subscribed to their topic (it subscribes to every topic within
  :data:`DISCOVERY_NS` of its start, or of the topic's appearance: a spawned body's), after
  it stopped (its subscriptions end within :data:`STOP_NS` of each other), or lost under
  load (at most :data:`LOST_RUN` in a row on a topic and :data:`LOST_SHARE` of its
  outputs). Reported, never failed;
- **missing**: anything else a recorder running at the time would have written (a topic, a
  stretch of outputs, a record). It fails the check unless the user said the recording is
  partial (``--partial``), or named the topics to check (``--topic``).

Recorded messages that the replay does not publish, that contradict each other or come out
of order, and messages that cannot be read always fail.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from ..scene.parameters import seconds_text
from .io import INPUT_EVENT, KEYFRAME, SESSION_INFO, WORLD_EVENT

__all__ = ["DISCOVERY_NS", "STOP_NS", "INPUT_LAG_NS", "LOST_RUN", "LOST_SHARE", "Stretch",
           "TopicCoverage", "Coverage", "seconds", "span", "runs"]

#: How long ``ros2 bag record -a`` may take to subscribe to a topic after it starts or the
#: topic appears: its polling for new topics (100 ms) and the middleware's discovery.
DISCOVERY_NS = 1_000_000_000
#: How far apart the recorder's subscriptions may end when it stops: it drops them one by
#: one, and each may still deliver what was in flight.
STOP_NS = 500_000_000
#: How much later than the node's record of an input message the recorder may log the
#: message itself: both come from the same publisher, the record by way of the node.
INPUT_LAG_NS = 50_000_000
#: Most outputs in a row that a recorder under load may lose on one topic...
LOST_RUN = 5
#: ... and the largest share of a topic's outputs it may lose (at least one output).
LOST_SHARE = 0.01


def seconds(ns: int) -> str:
    """A stamp or log time in seconds, to the nanosecond, with all nine places, as the
    reports print it (:func:`~..scene.parameters.seconds_text`)."""
    return seconds_text(ns, all_places=True)


def span(first_ns: int, last_ns: int) -> str:
    """``at T s`` or ``from T0 to T1 s``."""
    if first_ns == last_ns:
        return f"at {seconds(first_ns)} s"
    return f"from {seconds(first_ns)} to {seconds(last_ns)} s"


@dataclass(frozen=True)
class Stretch:
    """A run of outputs of one topic in the replayed order: how many, the stamps of the
    first and last, and why they were not compared."""

    topic: str
    count: int
    first_ns: int
    last_ns: int
    why: str

    def text(self) -> str:
        return f"{self.count} {span(self.first_ns, self.last_ns)} ({self.why})"


@dataclass
class TopicCoverage:
    """One output topic: recorded messages, how many were compared, what was not."""

    topic: str
    recorded: int = 0
    checked: int = 0
    #: Recorded but not compared, and allowed: before the replay could start.
    unchecked: list[Stretch] = field(default_factory=list)
    #: Published by the replay, not recorded, and the recorder's doing.
    not_recorded: list[Stretch] = field(default_factory=list)
    #: Published by the replay, not recorded, though the recorder was running.
    missing: list[Stretch] = field(default_factory=list)

    def text(self) -> str:
        parts = [f"{self.checked} checked of {self.recorded} recorded"]
        parts += [f"not checked: {s.text()}" for s in self.unchecked]
        parts += [f"not recorded: {s.text()}" for s in self.not_recorded]
        parts += [f"MISSING: {s.text()}" for s in self.missing]
        return "; ".join(parts)


@dataclass
class Coverage:
    """The coverage of a whole check; ``failures`` (one line each) fail it."""

    topics: dict[str, TopicCoverage] = field(default_factory=dict)
    #: Output topics not compared, and why (wall times, not named by --topic, ...).
    not_compared: dict[str, str] = field(default_factory=dict)
    input_events: int = 0
    world_events: int = 0
    keyframes: int = 0
    inputs: int = 0                 # recorded input messages found in the records
    #: What was not checked and is allowed, one line each.
    notes: list[str] = field(default_factory=list)
    #: What fails the check, one line each; ``missing`` marks those --partial accepts.
    failures: list[str] = field(default_factory=list)
    partial: bool = False

    def topic(self, name: str) -> TopicCoverage:
        return self.topics.setdefault(name, TopicCoverage(name))

    def fail(self, text: str, *, missing: bool = False) -> None:
        """A failure; with ``missing`` (data a partial recording may lack) and --partial,
        a note instead."""
        if missing and self.partial:
            self.notes.insert(0, f"not checked: {text} (accepted: --partial)")
        else:
            self.failures.append(text)

    def name_other_topics(self, recorded: Mapping[str, str], node: Iterable[str]) -> None:
        """Name, as not compared, the ``recorded`` topics (topic -> type) that are not the
        ``node``'s inputs or outputs nor its records: ``ros2 bag record -a`` records every
        node's, and a match says what the recording holds that it did not read."""
        known = set(node) | set(self.topics) | set(self.not_compared)
        for topic, msgtype in recorded.items():
            if topic not in known and msgtype not in (SESSION_INFO, KEYFRAME, INPUT_EVENT,
                                                       WORLD_EVENT):
                self.not_compared[topic] = "not a topic of the node for this scene"

    def add_missing(self, stretch: Stretch) -> None:
        """Outputs the recorder should have written: a failure, or with --partial a note."""
        coverage = self.topic(stretch.topic)
        if self.partial:
            coverage.not_recorded.append(Stretch(stretch.topic, stretch.count,
                                                 stretch.first_ns, stretch.last_ns,
                                                 stretch.why + "; accepted: --partial"))
        else:
            coverage.missing.append(stretch)
            self.failures.append(f"{stretch.topic}: {stretch.count} outputs "
                                 f"{span(stretch.first_ns, stretch.last_ns)} missing "
                                 f"({stretch.why})")

    @property
    def ok(self) -> bool:
        return not self.failures

    @property
    def recorded(self) -> int:
        return sum(t.recorded for t in self.topics.values())

    @property
    def checked(self) -> int:
        return sum(t.checked for t in self.topics.values())

    def counts(self, *, live: bool) -> str:
        """``checked N of M recorded outputs on K topics, ...`` for the verdict."""
        text = (f"checked {self.checked} of {self.recorded} recorded outputs on "
                f"{sum(1 for t in self.topics.values() if t.checked)} topics")
        if live:
            text += (f", {self.input_events} input events, {self.world_events} world events, "
                     f"{self.keyframes} keyframes")
        return text + f", {self.inputs} recorded inputs"

    def unchecked(self, limit: int = 3) -> str:
        """What was compared only in part, in a few words each (empty when nothing)."""
        parts: list[str] = []
        lost = [s for t in self.topics.values() for s in t.not_recorded
                if s.why.startswith("lost")]
        if lost:
            parts.append(f"{sum(s.count for s in lost)} lost by the recorder ("
                         + ", ".join(f"{s.topic} {span(s.first_ns, s.last_ns)}"
                                     for s in lost[:limit])
                         + (", ..." if len(lost) > limit else "") + ")")
        edges = [s for t in self.topics.values() for s in t.not_recorded
                 if not s.why.startswith("lost")]
        if edges:
            parts.append(f"{sum(s.count for s in edges)} not recorded ("
                         + ", ".join(f"{s.topic} {s.why}" for s in edges[:limit])
                         + (", ..." if len(edges) > limit else "") + ")")
        early = [s for t in self.topics.values() for s in t.unchecked]
        if early:
            parts.append(f"{sum(s.count for s in early)} recorded before the replay's start")
        skipped = [f"{topic} ({why})" for topic, why in sorted(self.not_compared.items())]
        if skipped:
            parts.append("not checked: " + ", ".join(skipped[:limit + 2])
                         + (", ..." if len(skipped) > limit + 2 else ""))
        parts += self.notes[:limit]
        if len(self.notes) > limit:
            parts.append(f"and {len(self.notes) - limit} more notes")
        return "; ".join(parts)

    def lines(self) -> list[str]:
        """One line per topic and per note, for the full report."""
        width = max([len(t) for t in self.topics] + [len(t) for t in self.not_compared] + [0])
        out = [f"{name:<{width}}  {self.topics[name].text()}" for name in sorted(self.topics)]
        out += [f"{name:<{width}}  not compared: {why}"
                for name, why in sorted(self.not_compared.items())]
        out += [f"note: {note}" for note in self.notes]
        out += [f"FAIL: {failure}" for failure in self.failures]
        return out


def runs(indices: Sequence[int]) -> list[tuple[int, int]]:
    """Consecutive runs of sorted ``indices``: (first, last) of each."""
    found: list[tuple[int, int]] = []
    for index in indices:
        if found and index == found[-1][1] + 1:
            found[-1] = (found[-1][0], index)
        else:
            found.append((index, index))
    return found
