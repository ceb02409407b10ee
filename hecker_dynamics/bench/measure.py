"""Timing and errors: median wall time of interleaved repeats, errors against a reference.

A :class:`Case` is one configuration (scene, engine, method, step, tolerance) with a
``run(duration)`` that builds its simulation afresh (not timed) and advances it over
``duration`` sim seconds, timing only the advancing. :func:`measure` first runs every
case briefly (a pilot of a few steps) to predict its cost and skips those over the budget,
then runs the rest in rounds, each round over all cases in turn (alternating direction),
so that machine drift and other load hit every case alike. The cost reported is the median
wall time per simulated second.

Every cost of the bench is a whole run's (the wall time of all its steps, as a user pays
it), the median over interleaved repeats of whole runs: :func:`measure` for the sweeps,
and :func:`interleaved_runs`, :func:`whole_cost` and :func:`ratio_noise` for the contact
and joint sections. Block statistics, where shown, only explain a cost.
"""
from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Optional, TypeVar

import numpy as np

from .reference import PlainModel, Reference, free_spin_energy

__all__ = ["Outcome", "Case", "Row", "Budget", "wrapped", "errors", "measure", "timed",
           "timed_steps", "interleaved_runs", "WholeCost", "whole_cost", "ratio_noise"]


#: A final position error (m) above which a run counts as diverged though still finite.
BLOWN_UP = 1e6


@dataclass
class Outcome:
    """What one run returns: timed wall seconds, final CM state (N, 3) each, work done."""

    wall: float
    q: np.ndarray
    v: np.ndarray
    steps: int = 0
    evaluations: int = 0
    failed: str = ""


@dataclass
class Case:
    scene: str
    engine: str  # hecker_dynamics, pymunk, box2d, mujoco, c
    method: str
    step: float
    tolerance: float
    duration: float
    run: Callable[[float], Outcome]
    note: str = ""


@dataclass
class Row:
    """One line of the results table."""

    scene: str
    engine: str
    method: str
    step: float
    tolerance: float
    duration: float
    status: str = "ok"  # ok, diverged, skipped, failed
    cost: float = math.nan  # wall s per sim s, median
    cost_spread: float = math.nan  # (max - min) / median over the repeats
    repeats: int = 0
    steps: int = 0
    evaluations: int = 0
    position_error: float = math.nan
    angle_error: float = math.nan
    energy_drift: float = math.nan
    omega_dt: float = math.nan
    note: str = ""
    walls: list[float] = field(default_factory=list, repr=False)

    FIELDS = ("scene", "engine", "method", "step", "tolerance", "duration", "status", "cost",
              "cost_spread", "repeats", "steps", "evaluations", "position_error",
              "angle_error", "energy_drift", "omega_dt", "note")

    def as_dict(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self.FIELDS}


@dataclass
class Budget:
    """Limits: predicted seconds for one run, repeats, and seconds of repeats per case."""

    per_run: float = 1.0
    repeats: int = 3
    per_case: float = 3.0
    pilot_steps: int = 20


def wrapped(a: np.ndarray) -> np.ndarray:
    return np.abs(np.remainder(a + math.pi, 2.0 * math.pi) - math.pi)


def errors(q: np.ndarray, v: np.ndarray, ref: Reference,
           plain: Optional[PlainModel]) -> tuple[float, float, float]:
    """Final position error (largest over bodies, m), angle error (rad, taken the short way
    round) and relative energy drift |E - E0| / |E0| (nan where energy is not conserved)."""
    position = float(np.max(np.hypot(q[:, 0] - ref.q[:, 0], q[:, 1] - ref.q[:, 1])))
    angle = float(np.max(wrapped(q[:, 2] - ref.q[:, 2])))
    drift = math.nan
    if plain is not None and ref.energy0 is not None:
        if plain.conservative:
            conserved = plain.energy(np.concatenate([q.ravel(), v.ravel()]))
            assert conserved is not None  # a conservative model has an energy
            energy = conserved
        else:  # free spin: unwrap the angle next to the exact one, then E = T - F.x - tau.a
            unwrapped = q.copy()
            unwrapped[:, 2] = ref.q[:, 2] + np.remainder(q[:, 2] - ref.q[:, 2] + math.pi,
                                                         2.0 * math.pi) - math.pi
            energy = free_spin_energy(plain, unwrapped, v)
        drift = abs(energy - ref.energy0) / abs(ref.energy0) if ref.energy0 else abs(energy)
    return position, angle, drift


def measure(cases: list[Case], budget: Budget, ref: Optional[Reference] = None,
            plain: Optional[PlainModel] = None, log: Callable[[str], None] = lambda s: None,
            omega: float = math.nan) -> list[Row]:
    """Pilot, then interleaved timed repeats of every case; rows with costs and errors."""
    rows = [Row(c.scene, c.engine, c.method, c.step, c.tolerance, c.duration, note=c.note,
                omega_dt=omega * c.step) for c in cases]
    active = []
    for case, row in zip(cases, rows):
        steps = max(1, round(case.duration / case.step))
        pilot_steps = min(steps, budget.pilot_steps)
        try:
            pilot = case.run(pilot_steps * case.step)
        except Exception as error:  # a peer refusing a configuration, say
            row.status, row.note = "failed", f"{type(error).__name__}: {error}"[:160]
            continue
        predicted = pilot.wall * steps / pilot_steps
        if pilot.failed:
            predicted = pilot.wall
        if predicted > budget.per_run:
            row.status = "skipped"
            row.note = (row.note + "; " if row.note else "") + \
                f"predicted {predicted:.3g} s per run > {budget.per_run:g} s budget"
            continue
        active.append((case, row))
    rounds = max(1, budget.repeats)
    for r in range(rounds):
        order = active if r % 2 == 0 else active[::-1]
        for case, row in order:
            if r > 0 and (row.status != "ok" or
                          (row.walls and sum(row.walls) + row.walls[0] > budget.per_case
                           and len(row.walls) >= 1)):
                continue
            outcome = case.run(case.duration)
            row.walls.append(outcome.wall)
            if r == 0:
                row.steps, row.evaluations = outcome.steps, outcome.evaluations
                if outcome.failed:
                    row.status, row.note = "diverged", outcome.failed[:160]
                elif not (np.all(np.isfinite(outcome.q)) and np.all(np.isfinite(outcome.v))):
                    row.status = "diverged"
                if ref is not None and row.status == "ok":
                    try:
                        with np.errstate(all="ignore"):
                            row.position_error, row.angle_error, row.energy_drift = errors(
                                outcome.q, outcome.v, ref, plain)
                    except (OverflowError, ValueError):
                        row.position_error = row.energy_drift = math.inf
                    if not row.position_error < BLOWN_UP:
                        row.status = "diverged"
                        row.note = (row.note + "; " if row.note else "") + \
                            f"final position error {row.position_error:.3g} m"
        log(f"  round {r + 1}/{rounds} done")
    for case, row in active:
        if row.walls:
            median = statistics.median(row.walls)
            row.cost = median / case.duration
            row.repeats = len(row.walls)
            row.cost_spread = (max(row.walls) - min(row.walls)) / median if median else 0.0
    return rows


def timed(call: Callable[[], object]) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


# ----------------------------------------------------------------------------- whole runs

def timed_steps(step: Callable[[int], Optional[float]], count: int) -> float:
    """Seconds of ``step(count)``: those it returns where it times itself (an engine in
    another process times its own loop, so no pipe round trip is counted), else this
    process's clock around the call."""
    start = time.perf_counter()
    own = step(count)
    wall = time.perf_counter() - start
    return wall if own is None else float(own)


T = TypeVar("T")


def interleaved_runs(runs: dict[str, Callable[[], T]], repeats: int) -> dict[str, list[T]]:
    """Whole runs: ``repeats`` rounds over ``runs``, each of which builds its engine afresh
    (untimed) and returns what its timed whole run gives, one after another in each round
    and in alternating direction (A B C, C B A, A B C, ...), so that the machine's drift
    and other load fall on every engine alike. Per name, its results in round order."""
    results: dict[str, list[T]] = {name: [] for name in runs}
    names = list(runs)
    for r in range(max(1, repeats)):
        for name in names if r % 2 == 0 else names[::-1]:
            results[name].append(runs[name]())
    return results


@dataclass
class WholeCost:
    """A cost per step from whole-run repeats: the median of each run's seconds over its
    steps (the figure of merit: what a user pays), the repeats' spread (max - min) over
    that median, and each repeat's seconds per step."""

    per_step: float
    spread: float
    repeats: list[float]


def whole_cost(per_step: list[float]) -> WholeCost:
    median = statistics.median(per_step)
    return WholeCost(median, (max(per_step) - min(per_step)) / median if median else 0.0,
                     list(per_step))


def ratio_noise(ours: list[float], theirs: list[float]) -> float:
    """The spread of a cost ratio: (max - min) / median of the ratios of the runs made
    side by side in each round (:func:`interleaved_runs`)."""
    ratios = [a / b for a, b in zip(ours, theirs) if b]
    if not ratios:
        return math.nan
    median = statistics.median(ratios)
    return (max(ratios) - min(ratios)) / median if median else math.nan
