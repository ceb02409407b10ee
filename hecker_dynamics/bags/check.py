"""The check of a recording against its replay, as ``replay --check`` and ``regress`` run it.

A live recording (one with the node's session records) is checked by
:func:`~hecker_dynamics.bags.live.check_live`; any other bag by the rules of bags made by
``script`` and ``replay``: its inputs replayed from their log times
(:func:`~hecker_dynamics.bags.replay.replay`) and its outputs compared topic by topic with
the replay's (:func:`~hecker_dynamics.bags.compare.compare_contents`), where a message on
either side only is a mismatch. In both, every output topic the scene publishes must be in
the bag, unless named otherwise by ``topics`` or accepted missing by ``partial``
(:mod:`~hecker_dynamics.bags.coverage`).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Optional, TypeVar

from ..dynamics import kernel
from ..dynamics.model import LEAN_BODIES
from ..integrators.methods import ADAPTIVE
from ..scene.load import Scene
from .compare import CompareReport, Tolerances, compare_contents
from .coverage import Coverage, span
from .io import BagContents
from .live import check_live, is_live_recording
from .replay import (
    check_named_outputs,
    input_topics,
    output_types,
    outputs_as_bag,
    recorded_output_topics,
    replay_outputs,
)

__all__ = ["RecordingCheck", "check_recording", "check_outputs", "paths_round_apart",
           "on_the_recorded_path"]


@dataclass
class RecordingCheck:
    """The outcome of a check: the comparison of the outputs matched, the coverage, and the
    divergence that stopped the replay, if one did."""

    path: str
    report: CompareReport
    coverage: Coverage
    live: bool
    halted: Optional[str] = None
    sessions: int = 0
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        # A match must rest on something compared: a session 0 s long, or output topics
        # that hold nothing (which --partial accepts as missing), would pass on no data.
        if self.halted is None and not self.coverage.checked and not self.coverage.keyframes:
            self.coverage.fail("nothing to check: the recording holds no output of the node "
                               "in the span replayed, nor a keyframe")

    @property
    def ok(self) -> bool:
        return self.halted is None and self.report.ok and self.coverage.ok

    def verdict(self) -> str:
        """One line: ``match:`` and what was checked, or ``mismatch:`` and the first
        reason."""
        if self.ok:
            big = self.report.largest()
            parts = [self.coverage.counts(live=self.live), self.coverage.unchecked(),
                     f"largest difference position {big['position']:.3g}, angle "
                     f"{big['angle']:.3g}, velocity "
                     f"{max(big['velocity'], big['angular_velocity']):.3g}"]
            return "match: " + "; ".join(part for part in parts if part)
        reasons = list(self.coverage.failures)
        if not self.report.ok:
            reasons.append(self.report.summary().removeprefix("mismatch: "))
        more = f" (and {len(reasons) - 1} more problems)" if len(reasons) > 1 else ""
        return f"mismatch: {reasons[0]}{more}"

    def lines(self, verbose: bool = False) -> list[str]:
        """The full report: the coverage per topic, then (on a mismatch, or ``verbose``)
        the comparison."""
        out = self.coverage.lines()
        if verbose or not self.report.ok:
            out.append(self.report.text())
        return out


def check_outputs(scene: Scene, bag: BagContents, actual: BagContents, *,
                  tolerances: Tolerances, tf: bool, topics: Optional[Sequence[str]] = None,
                  partial: bool = False) -> tuple[CompareReport, Coverage]:
    """Compare the outputs recorded in a bag without session records with the replay's
    (``actual``): every output topic of the scene (``tf``: TF's too; ``topics``: those
    named) must be recorded, unless ``partial``."""
    wanted = output_types(scene, tf=tf)
    coverage = Coverage(partial=partial)
    if topics is not None:
        check_named_outputs(scene, topics, tf)
        for topic in wanted:
            if topic not in topics and topic in bag.topics:
                coverage.not_compared[topic] = "not named by --topic"
        wanted = {t: wanted[t] for t in topics}
    held = {m.topic for m in bag.messages}
    absent = [t for t in wanted if t not in held and any(m.topic == t for m in actual.messages)]
    if absent:
        coverage.fail(f"{', '.join(absent)} not recorded: the node publishes them for "
                      f"{scene.source} (--topic names the topics a recording holds on "
                      "purpose; --partial accepts a partial recording)", missing=True)
    report, _ = compare_contents(bag, actual, tolerances=tolerances,
                                 topics=[t for t in wanted if t in held])
    for compared in report.topics:
        coverage.topic(compared.topic).recorded = compared.expected
        coverage.topic(compared.topic).checked = compared.matched
        if compared.extra:
            coverage.fail(f"{compared.topic}: {len(compared.extra)} outputs of the replay not "
                          f"recorded, {span(min(compared.extra), max(compared.extra))}",
                          missing=True)
            if partial:  # accepted: the comparison is of what was recorded
                compared.extra = []
        if compared.missing:
            coverage.fail(f"{compared.topic}: {len(compared.missing)} recorded outputs the "
                          f"replay does not publish, "
                          f"{span(min(compared.missing), max(compared.missing))}")
    inputs = input_topics(scene)
    coverage.inputs = sum(1 for m in bag.messages if m.topic in inputs)
    coverage.name_other_topics(bag.topics, [*output_types(scene, tf=True), *inputs])
    return report, coverage


def paths_round_apart(scene: Scene) -> Optional[str]:
    """Why the compiled kernel and the Python path may publish other bits for ``scene``
    (README: they agree to rounding only above :data:`~..dynamics.model.LEAN_BODIES`
    bodies, where Python sums with numpy, and with the adaptive methods, which ``auto``
    may pick), or None where they give the same bits."""
    if len(scene.bodies) > LEAN_BODIES:
        return f"on its {len(scene.bodies)} bodies (more than {LEAN_BODIES})"
    if scene.integrator in (*ADAPTIVE, "auto"):
        return f"with integrator {scene.integrator}"
    return None


def _path(compiled: bool) -> str:
    return "the compiled kernel" if compiled else \
        f"the Python path ({kernel.SWITCH}=0)"


Attempt = TypeVar("Attempt")


def on_the_recorded_path(scene: Scene, attempt: Callable[[], Attempt],
                         ok: Callable[[Attempt], bool], first: Optional[Attempt] = None
                         ) -> tuple[Attempt, Optional[str]]:
    """``attempt()`` (a replay and its check; ``first``, its result on this process's
    path where made already), again on the other path where its result is not ``ok``,
    the two paths round apart for ``scene`` (:func:`paths_round_apart`) and the kernel is
    built: a node that ran the other path recorded other bits. Returns the result that
    is ok, else the first, and a note of what was replayed, or None."""
    first = attempt() if first is None else first
    why = paths_round_apart(scene)
    if ok(first) or why is None:
        return first, None
    compiled = not kernel.enabled()
    if not kernel.built():
        return first, (f"{_path(True)}, not built here, rounds apart from {_path(False)} "
                       f"{why}: a recording of a node that ran it differs so")
    with kernel.chosen(compiled):
        other = attempt()
    if not ok(other):
        return first, None
    return other, (f"replayed on {_path(compiled)}, which the node that recorded it ran: "
                   f"{_path(not compiled)} rounds apart from it {why}")


def check_recording(scene: Scene, bag: BagContents, *, tolerances: Tolerances,
                    topics: Optional[Sequence[str]] = None,
                    partial: bool = False,
                    progress: Optional[Callable[[float], None]] = None) -> RecordingCheck:
    """``replay SCENE BAG --check``: replay the bag on ``scene`` and check everything it
    holds (see the module docstring), on the path the node ran
    (:func:`on_the_recorded_path`); ``progress`` is told of each publish tick. Raises
    :class:`~hecker_dynamics.bags.replay.ReplayError` for a bag that cannot be checked."""
    check, note = on_the_recorded_path(
        scene, lambda: _check_on_this_path(scene, bag, tolerances=tolerances, topics=topics,
                                           partial=partial, progress=progress),
        lambda check: check.ok or check.halted is not None)
    if note is not None:
        check.coverage.notes.insert(0, note)
    return check


def _check_on_this_path(scene: Scene, bag: BagContents, *, tolerances: Tolerances,
                        topics: Optional[Sequence[str]], partial: bool,
                        progress: Optional[Callable[[float], None]]) -> RecordingCheck:
    if is_live_recording(bag):
        live = check_live(scene, bag, tolerances=tolerances, topics=topics, partial=partial,
                          progress=progress)
        return RecordingCheck(str(bag.path), live.report, live.coverage, True, live.halted,
                              live.sessions)
    tf = "/tf" in bag.topics or "/tf" in (topics or ())
    recorded_output_topics(scene, bag, tf=tf, topics=topics)
    produced, result = replay_outputs(scene, bag, tf=tf, progress=progress)
    report, coverage = check_outputs(scene, bag, outputs_as_bag(scene, produced, tf=tf),
                                     tolerances=tolerances, tf=tf, topics=topics,
                                     partial=partial)
    return RecordingCheck(str(bag.path), report, coverage, False, result.halted)
