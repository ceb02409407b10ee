"""The bouncing ball's exact solution, the benchmark's contact case with a closed form.

A circle of radius r, its center dropped from rest at height h0 above a horizontal wall
(the floor, normal up) under gravity g, bounces without friction or spin with restitution
e: each impact keeps e of the normal speed (the article series' collision impulse
j = -(1 + e) v_rel.n / (1/M), a wall having no mass). With d = h0 - r the first fall,

- the first impact at t_1 = sqrt(2 d / g), speed v_1 = sqrt(2 g d);
- after the k-th impact (k >= 1) the ball leaves upwards at u_k = e^k v_1, flies
  2 u_k / g, so t_(k+1) = t_k + 2 e^k v_1 / g, i.e. t_k = t_1 + 2 v_1 e (1 - e^(k-1)) /
  (g (1 - e));
- the apex after the k-th impact: center height r + e^(2k) d at t_k + u_k / g;
- between impacts the free flight y(t) = r + u_k (t - t_k) - g (t - t_k)^2 / 2,
  v(t) = u_k - g (t - t_k) (before t_1: y = h0 - g t^2 / 2).

For e < 1 the impacts accumulate at the Zeno time t_inf = t_1 + 2 v_1 e / (g (1 - e)),
after which the ball rests on the floor (y = r, v = 0): :meth:`BallDrop.state` says so.
A simulation stops bouncing earlier, when the approach speed falls below its restitution
threshold, so comparisons use the first few impacts only, well before t_inf.
"""
from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from ..scene.load import Scene, scene_from_parameters
from ..scene.parameters import flatten
from .measure import Case

__all__ = ["BENCH_DROP", "BallDrop", "BounceRow", "ball_drop_scene", "bounce_bench",
           "bounce_table", "write_bounce_csv"]


@dataclass(frozen=True)
class BallDrop:
    """The closed form of a ball of radius ``radius`` whose center starts at rest at
    ``height`` above the floor, under ``gravity`` (m/s^2, > 0), with ``restitution`` e in
    [0, 1)."""

    height: float
    radius: float
    gravity: float
    restitution: float

    @property
    def first_fall(self) -> float:
        """d = h0 - r, the height the ball's bottom falls before the first impact (m)."""
        return self.height - self.radius

    @property
    def impact_speed(self) -> float:
        """v_1 = sqrt(2 g d), the speed of the first impact."""
        return math.sqrt(2.0 * self.gravity * self.first_fall)

    def impact_time(self, k: int) -> float:
        """t_k, the time of the k-th impact (k >= 1)."""
        e, g, v1 = self.restitution, self.gravity, self.impact_speed
        t1 = math.sqrt(2.0 * self.first_fall / g)
        return t1 + 2.0 * v1 / g * sum(e ** j for j in range(1, k))

    def apex_height(self, k: int) -> float:
        """The center's height at the apex after the k-th impact: r + e^(2k) d (k = 0:
        the drop height)."""
        return self.radius + self.restitution ** (2 * k) * self.first_fall

    def apex_time(self, k: int) -> float:
        """When the ball reaches :meth:`apex_height` ``k`` (k = 0: the start)."""
        if k == 0:
            return 0.0
        return self.impact_time(k) + self.restitution ** k * self.impact_speed / self.gravity

    @property
    def zeno_time(self) -> float:
        """t_inf, where the impacts accumulate (inf for e = 1)."""
        e = self.restitution
        if e >= 1.0:
            return math.inf
        return self.impact_time(1) + 2.0 * self.impact_speed * e / (self.gravity * (1.0 - e))

    def state(self, t: float) -> tuple[float, float]:
        """The center's height and vertical velocity at time ``t`` >= 0 (at an impact
        instant, the velocity after it); at rest on the floor from :attr:`zeno_time`."""
        g = self.gravity
        t1 = self.impact_time(1)
        if t < t1:
            return self.height - 0.5 * g * t * t, -g * t
        if t >= self.zeno_time:
            return self.radius, 0.0
        # The k-th flight starts at t_k; k from the geometric sum, then checked against
        # rounding at the ends of the flight.
        k, start = 1, t1
        while True:
            flight = 2.0 * self.restitution ** k * self.impact_speed / g
            if t < start + flight or flight == 0.0:
                break
            k, start = k + 1, start + flight
        u = self.restitution ** k * self.impact_speed
        s = t - start
        return self.radius + u * s - 0.5 * g * s * s, u - g * s

    def energy_ratio(self) -> float:
        """The mechanical energy (above the resting height) after an impact over that
        before: e^2."""
        return self.restitution ** 2


def ball_drop_scene(drop: BallDrop, step: float, integrator: str, *, tolerance: float = 1e-6,
                    events: bool = False, duration: float = 2.0,
                    extra: dict[str, Any] | None = None) -> Scene:
    """``drop`` as a scene: one ball of 1 kg on a frictionless floor with restitution e,
    gravity along -y, stepped by ``integrator`` at ``step`` (``tolerance`` for the adaptive
    methods), with the floor's impacts located inside the step where ``events`` is on
    (``contacts.events``)."""
    params: dict[str, Any] = {
        "step": step, "integrator": integrator, "tolerance": tolerance,
        "duration": duration, "publish_rate": 1.0 / step,
        "contacts": {"events": events},
        "bodies": {"ball": {"shape": "circle", "radius": drop.radius, "mass": 1.0,
                            "position": [0.0, drop.height]}},
        "forces": {"g": {"type": "gravity", "acceleration": [0.0, -drop.gravity]}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                            "restitution": drop.restitution, "friction": 0.0}},
        **(extra or {}),
    }
    return scene_from_parameters(flatten(params), "ball_drop")


# ----------------------------------------------------------------------------- the bench

#: The drop of the benchmark's case: 1 m of fall to the first impact, e = 0.8; its first
#: :data:`BOUNCES` impacts come before :data:`DURATION` (t_5 = 2.58 s, t_6 = 2.88 s).
BENCH_DROP = BallDrop(height=1.1, radius=0.1, gravity=9.81, restitution=0.8)
BOUNCES = 5
DURATION = 2.8
#: The engine names of the case's rows: events on (Python path), events off in the
#: kernel where it is built, and off in Python (the like-for-like cost of the events).
EVENTS = "hecker_dynamics events"
CORE = "hecker_dynamics"
CORE_PYTHON = "hecker_dynamics (python)"
FIXED_METHODS = ("semi_implicit_euler", "velocity_verlet", "rk4")
ADAPTIVE_STEP = 0.01  # the longest sub-step of dopri5 and dop853


@dataclass
class BounceRow:
    """One configuration of the ball drop: cost (wall s per sim s, median of interleaved
    repeats), work, and its errors against :data:`BENCH_DROP`'s closed form over
    [0, :data:`DURATION`]: the largest height error of the center at the step ends (m) and
    the largest error of the first :data:`BOUNCES` impact times (s; nan where fewer were
    seen)."""

    engine: str
    method: str
    step: float
    tolerance: float
    cost: float = math.nan
    evaluations: int = 0
    height_error: float = math.nan
    impact_error: float = math.nan
    impacts: int = 0
    status: str = "ok"  # or skipped (over the run budget: no cost), failed, diverged


def _sampled_impacts(times: list[float], heights: list[float]) -> list[float]:
    """Where a run reports no impact times: the step ends at which the sampled height has
    a local minimum (where the bounce was applied, give or take a step)."""
    return [times[n] for n in range(1, len(heights) - 1)
            if heights[n] < heights[n - 1] and heights[n] <= heights[n + 1]]


def _errors(row: BounceRow, times: list[float], heights: list[float],
            impacts: list[float]) -> None:
    drop = BENCH_DROP
    row.height_error = max(abs(y - drop.state(t)[0]) for t, y in zip(times, heights))
    row.impacts = len(impacts)
    if len(impacts) >= BOUNCES:
        row.impact_error = max(abs(t - drop.impact_time(k + 1))
                               for k, t in enumerate(impacts[:BOUNCES]))


def _core_trace(row: BounceRow, scene: Scene) -> None:
    """Errors of ours, from a run step by step (the same bits as the timed run's)."""
    from ..dynamics.simulation import Simulation

    sim = Simulation(scene)
    if row.engine == CORE_PYTHON:
        sim.model.use_python()
    times, heights = [], []
    for _ in range(round(DURATION / row.step)):
        sim.step()
        times.append(sim.time_ns * 1e-9)
        heights.append(float(sim.q[0, 1]))
    impacts = ([i.time for i in sim.impacts] if row.engine == EVENTS
               else _sampled_impacts(times, heights))
    _errors(row, times, heights, impacts)


def _core_case(row: BounceRow, scene: Scene) -> Case:
    from ..dynamics.simulation import Simulation
    from .measure import Outcome

    def run(duration: float) -> Outcome:
        sim = Simulation(scene)
        if row.engine == CORE_PYTHON:
            sim.model.use_python()
        start = time.perf_counter()
        sim.advance_to(round(duration * 1e9), keep=False)
        wall = time.perf_counter() - start
        return Outcome(wall, sim.q.copy(), sim.v.copy(), sim.steps,
                       sim.integrator.counters.evaluations)

    return Case("ball_drop", row.engine, row.method, row.step, row.tolerance, DURATION, run)


def _peer_case(row: BounceRow, scene: Scene) -> Case:
    from .measure import Outcome, timed_steps
    from .scene_peers import scene_engine

    def run(duration: float) -> Outcome:
        step, poses = scene_engine(row.engine, scene, row.step)
        steps = round(duration / row.step)
        wall = timed_steps(step, steps)
        q = poses()
        return Outcome(wall, q, q * 0.0, steps)

    return Case("ball_drop", row.engine, row.method, row.step, math.nan, DURATION, run)


def _peer_trace(row: BounceRow, scene: Scene) -> None:
    from .scene_peers import scene_engine

    step, poses = scene_engine(row.engine, scene, row.step)
    times, heights = [], []
    for n in range(round(DURATION / row.step)):
        step(1)
        times.append((n + 1) * row.step)
        heights.append(float(poses()[0, 1]))
    _errors(row, times, heights, _sampled_impacts(times, heights))


def bounce_bench(tolerances: list[float], steps: list[float], peers: list[str],
                 budget: Any, log: Callable[[str], None] = lambda s: None) -> list[BounceRow]:
    """The ball drop's rows: ``dopri5`` and ``dop853`` (h = :data:`ADAPTIVE_STEP`) at each
    of ``tolerances``, the fixed-step methods and ``peers`` at each of ``steps``, ours with
    and without event location; errors from a traced run, costs by :func:`.measure.measure`
    (interleaved repeats within ``budget``)."""
    from .measure import measure

    configs: list[tuple[BounceRow, Scene]] = []
    for events in (True, False):
        engines = [EVENTS] if events else [CORE, CORE_PYTHON]
        for engine in engines:
            for method in ("dopri5", "dop853"):
                for tol in tolerances:
                    configs.append((BounceRow(engine, method, ADAPTIVE_STEP, tol),
                                    ball_drop_scene(BENCH_DROP, ADAPTIVE_STEP, method,
                                                    tolerance=tol, events=events,
                                                    duration=DURATION)))
            for method in FIXED_METHODS:
                for h in steps:
                    configs.append((BounceRow(engine, method, h, math.nan),
                                    ball_drop_scene(BENCH_DROP, h, method, events=events,
                                                    duration=DURATION)))
    for peer in peers:
        for h in steps:
            configs.append((BounceRow(peer, "own", h, math.nan),
                            ball_drop_scene(BENCH_DROP, h, "semi_implicit_euler",
                                            duration=DURATION)))
    cases = []
    for row, scene in configs:
        is_peer = row.engine in peers
        (_peer_trace if is_peer else _core_trace)(row, scene)
        cases.append((_peer_case if is_peer else _core_case)(row, scene))
    log(f"ball_drop: {len(configs)} configurations traced")
    for (row, _), measured in zip(configs, measure(cases, budget, log=log)):
        row.cost, row.status = measured.cost, measured.status
        row.evaluations = measured.evaluations
    return [row for row, _ in configs]


def write_bounce_csv(rows: list[BounceRow], path: Path) -> None:
    """The ball drop's rows as CSV, one column per :class:`BounceRow` field."""
    names = [f.name for f in fields(BounceRow)]
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(names)
        writer.writerows([getattr(row, name) for name in names] for row in rows)


def bounce_table(rows: list[BounceRow]) -> list[str]:
    """The report's Markdown section for the ball drop."""
    def g(x: float) -> str:
        return "-" if not math.isfinite(x) else f"{x:.2g}"

    drop = BENCH_DROP
    md = ["## Ball drop: impacts against the closed form", "",
          f"A ball (r = {drop.radius:g} m) dropped from {drop.height:g} m (center) on a "
          f"frictionless floor, e = {drop.restitution:g}, over {DURATION:g} s (the first "
          f"{BOUNCES} impacts; Zeno time {drop.zeno_time:.3f} s). Errors against the closed "
          "form (hecker_dynamics.bench.bounce): largest center-height error at the step "
          f"ends (m) and largest error of the first {BOUNCES} impact times (s: located "
          "impacts with events, else the step ends of the lowest sampled heights). "
          f"`{EVENTS}`: `contacts.events` on (steps in Python); `{CORE}`: off (in the "
          f"kernel where built); `{CORE_PYTHON}`: off, in Python. Peers with their own "
          "restitution (no event location). dopri5 and dop853 at h = "
          f"{ADAPTIVE_STEP:g} s (the longest sub-step). Method: docs/benchmark.md.", "",
          "| engine | method | h | tol | cost (s/s) | evaluations | height err (m) | "
          "impact time err (s) |", "|---|---|---|---|---|---|---|---|"]
    md += [f"| {r.engine} | {r.method} | {r.step:g} | {g(r.tolerance)} | "
           f"{g(r.cost) if r.status == 'ok' else r.status} | "
           f"{r.evaluations} | {g(r.height_error)} | {g(r.impact_error)} |" for r in rows]
    return md
