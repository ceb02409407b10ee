"""The regression guard of ``hecker-dynamics bench --quick``: ratios against a reference.

Times move with the machine; a ratio of two costs measured side by side in one run (our
cost over a peer's or the C loop's, interleaved round by round) moves far less. So the
guard keeps ratios, never times, in a committed reference (``reference_ratios.json``
beside this module, installed with the package), each with its noise: the spread of the
rounds' ratios (:func:`.measure.ratio_noise`), (max - min) over their median. A quick
run's ratio has *moved* when it differs from the reference's by more than the noise of both
added, and at least :data:`FLOOR`; the guard lists what moved, what held, and ratios only
one of the two has.

The ratios (:func:`quick_ratios`), each our cost over another engine's:

- ``ring N=<n> / <engine>``: the ring's semi-implicit Euler per body-step against the C
  loop, pymunk (``DampedSpring``) and MuJoCo (``euler``); against the C loop from the
  back-to-back pairs of whole runs (``Results.ring_pairs``) where the run made them, as the
  ring's target reads it (their median, their spread as the noise);
- ``sample / <engine> (<configuration>)``: the default scene's step against each peer;
- ``<scene> rk4 h=<h> / mujoco rk4``: RK4 against MuJoCo's RK4 at equal steps;
- ``<scene> error <= <e> / <peer>``: the cheapest configuration reaching a final position
  error against the peer's cheapest (the work-precision headline).
"""
from __future__ import annotations

import json
import math
import statistics
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from .measure import Row, ratio_noise
from .report import THRESHOLDS, cheapest

__all__ = ["FLOOR", "REFERENCE", "Ratio", "Verdict", "compare", "quick_ratios",
           "read_reference", "verdict_lines", "write_reference"]

#: Where the committed reference lives.
REFERENCE = Path(__file__).with_name("reference_ratios.json")
#: The least relative change that counts as a move, whatever the noise (a quick run's
#: rounds are few, so their spread can understate it).
FLOOR = 0.15


@dataclass(frozen=True)
class Ratio:
    """Our cost over another engine's, and the relative spread of the rounds' ratios."""

    value: float
    noise: float


@dataclass(frozen=True)
class Verdict:
    """One ratio's fate: ``moved``, ``held``, ``new`` (not in the reference) or ``gone``
    (only in the reference); ``change`` is now / reference - 1, ``allowed`` the noise."""

    name: str
    status: str
    reference: Optional[Ratio]
    now: Optional[Ratio]
    change: float = math.nan
    allowed: float = math.nan


def _costs(row: Row) -> list[float]:
    """Each round's cost per simulated second of ``row`` (its runs' walls over its span)."""
    return [wall / row.duration for wall in row.walls]


def _ratio(ours: Optional[Row], theirs: Optional[Row]) -> Optional[Ratio]:
    if ours is None or theirs is None or ours.status != "ok" or theirs.status != "ok" or \
            not ours.cost > 0.0 or not theirs.cost > 0.0:
        return None
    noise = ratio_noise(_costs(ours), _costs(theirs))
    return Ratio(ours.cost / theirs.cost, 0.0 if math.isnan(noise) else noise)


def _paired(ratios: list[float]) -> Ratio:
    """The median of ratios of runs made back to back, and their spread over it."""
    median = statistics.median(ratios)
    return Ratio(median, (max(ratios) - min(ratios)) / median)


def _find(rows: Iterable[Row], scene: str, engine: str, method: str,
          step: Optional[float] = None) -> Optional[Row]:
    return next((r for r in rows if r.scene == scene and r.engine == engine and
                 r.method == method and (step is None or r.step == step)), None)


def quick_ratios(results: Any) -> dict[str, Ratio]:
    """The guard's ratios from a bench run's :class:`~.run.Results` (see the module)."""
    ratios: dict[str, Optional[Ratio]] = {}
    for row in results.ring:
        if row.engine == "hecker_dynamics" and row.method == "semi_implicit_euler":
            n = int(row.omega_dt)
            pairs = results.ring_pairs.get(n)
            for engine, method in (("c", "semi_implicit_euler"), ("pymunk", "native"),
                                   ("mujoco", "euler")):
                ratios[f"ring N={n} / {engine}"] = (
                    _paired(pairs) if engine == "c" and pairs
                    else _ratio(row, _find(results.ring, row.scene, engine, method)))
    ours = _find(results.sample_rows, "sample", "hecker_dynamics", "semi_implicit_euler")
    for row in results.sample_rows:
        if not row.engine.startswith("hecker_dynamics"):
            ratios[f"sample / {row.engine} ({row.method})"] = _ratio(ours, row)
    for row in results.rows:
        if row.engine == "mujoco" and row.method == "rk4":
            ratios[f"{row.scene} rk4 h={row.step:g} / mujoco rk4"] = _ratio(
                _find(results.rows, row.scene, "hecker_dynamics", "rk4", row.step), row)
    scenes = dict.fromkeys(r.scene for r in results.rows)
    for scene in scenes:
        for threshold in THRESHOLDS:
            best = cheapest(results.rows, scene, "hecker_dynamics", threshold)
            for peer in ("pymunk", "box2d", "mujoco"):
                other = cheapest(results.rows, scene, peer, threshold)
                ratios[f"{scene} error <= {threshold:g} / {peer}"] = _ratio(best, other)
    return {name: ratio for name, ratio in ratios.items() if ratio is not None}


def compare(now: dict[str, Ratio], reference: dict[str, Ratio],
            floor: float = FLOOR) -> list[Verdict]:
    """Each ratio of either against the other: moved where |now / reference - 1| exceeds
    both noises added, and ``floor``."""
    verdicts = []
    for name in sorted(reference.keys() | now.keys()):
        old, new = reference.get(name), now.get(name)
        if old is None or new is None:
            verdicts.append(Verdict(name, "new" if old is None else "gone", old, new))
            continue
        allowed = max(floor, old.noise + new.noise)
        change = new.value / old.value - 1.0
        moved = abs(math.log(new.value / old.value)) > math.log1p(allowed)
        verdicts.append(Verdict(name, "moved" if moved else "held", old, new, change, allowed))
    return verdicts


def verdict_lines(verdicts: list[Verdict]) -> list[str]:
    """One line per ratio that moved, appeared or went, then a count of those that held."""
    lines = []
    for v in verdicts:
        old = "-" if v.reference is None else f"{v.reference.value:.3g}"
        new = "-" if v.now is None else f"{v.now.value:.3g}"
        if v.status == "moved":
            lines.append(f"moved: {v.name}: {old} -> {new} ({v.change:+.0%}, noise allowed "
                         f"{v.allowed:.0%})")
        elif v.status == "new":
            lines.append(f"new (not in the reference): {v.name}: {new}")
        elif v.status == "gone":
            lines.append(f"not measured (in the reference): {v.name}: {old}")
    held = sum(v.status == "held" for v in verdicts)
    lines.append(f"held within their noise: {held} of "
                 f"{sum(v.status in ('held', 'moved') for v in verdicts)} ratios")
    return lines


def read_reference(path: Path) -> dict[str, Ratio]:
    data = json.loads(Path(path).read_text())
    return {name: Ratio(float(entry["value"]), float(entry["noise"]))
            for name, entry in data["ratios"].items()}


def write_reference(path: Path, ratios: dict[str, Ratio], about: dict[str, str]) -> None:
    """The ratios as the reference, with ``about`` (command, machine, load) beside them."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"about": about,
            "ratios": {name: {"value": r.value, "noise": r.noise}
                       for name, r in sorted(ratios.items())}}
    path.write_text(json.dumps(data, indent=1) + "\n")
