"""The benchmark run: sweeps, references, peers, ring, default-scene step, profiles.

``run_bench(mode, out, scenes, peers)`` does it all and writes the report (see
:mod:`.report`). Modes: ``quick`` (a small sweep, about a minute or two, for a smoke test)
and ``full`` (the documented run, up to about 20 minutes on a 2-core machine).
"""
from __future__ import annotations

import cProfile
import dataclasses
import functools
import io
import math
import os
import platform
import pstats
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from ..dynamics import kernel
from ..dynamics.model import Model
from ..dynamics.simulation import DivergenceError, Simulation
from ..integrators.methods import ADAPTIVE, METHODS, make_integrator
from ..scene.load import Scene
from ..viz.progress import BarFactory, run_parts
from . import peers as peer_mod
from .bounce import BounceRow, bounce_bench
from .measure import Budget, Case, Outcome, Row, interleaved_runs, measure
from .reference import PlainModel, Reference, core_reference, reference
from .ring import c_loop_flags, c_run, compiler_version, load_c_loop
from .scene_peers import SCENE_PEERS
from .scenes import BENCH_SCENES, STIFF_SEESAW, bench_scene, configure, declared_variants, ring

__all__ = ["Mode", "Results", "PYTHON_PATH", "core_run", "core_case", "core_cases", "bench_scenes",
           "shipped", "ring_part", "sample_step", "bounce_part", "declared_part", "peer_checks",
           "profiles", "guard", "run_bench"]

#: Where a part of the bench says what it is doing, a line at a time.
Log = Callable[[str], None]


@dataclass
class Mode:
    name: str
    steps: dict[str, list[float]]
    tolerances: list[float]
    adaptive_steps: list[float]  # steps (the longest sub-step) of the adaptive methods
    budget: Budget
    ring_sizes: list[int]
    ring_wall: float  # target timed seconds per ring run
    shipped_duration: float
    shipped_steps: list[float]  # multiples of the scene's own step
    shipped_ref_divisor: float
    profile_steps: int
    sample_duration: Optional[float] = None  # s of the default scene's step; None: all
    # The ball drop (:mod:`.bounce`): tolerances of the adaptive methods, steps of the rest.
    bounce_tolerances: list[float] = field(default_factory=lambda: [1e-6, 1e-10])
    bounce_steps: list[float] = field(default_factory=lambda: [0.004, 0.001])


#: The fixed steps of the full sweep, for our fixed-step methods and every peer: from the
#: longest step the adaptive methods take (their ``adaptive_steps``), so that a scene one
#: coarse step integrates exactly (free_spin) compares every engine at it.
FULL_STEPS = [0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001, 0.0005, 0.0002]
STIFF_STEPS = [0.1, 0.01, 0.002, 0.001, 0.0005, 0.0002, 0.0001, 0.00005, 0.00002, 0.00001]

MODES = {
    "quick": Mode(
        "quick",
        steps={s: [0.1, 0.02, 0.005, 0.001] for s in BENCH_SCENES} | {
            "stiff": [0.1, 0.01, 0.001, 0.0001]},
        tolerances=[1e-4, 1e-8], adaptive_steps=[0.1], budget=Budget(0.25, 3, 1.0, 10),
        ring_sizes=[1, 10, 100, 1000], ring_wall=0.05, shipped_duration=0.5,
        shipped_steps=[1.0], shipped_ref_divisor=2.0, profile_steps=300,
        sample_duration=2.0),
    "full": Mode(
        "full",
        steps={s: FULL_STEPS for s in BENCH_SCENES} | {"stiff": STIFF_STEPS},
        tolerances=[10.0 ** -k for k in range(3, 13)],
        adaptive_steps=[0.5, 0.1, 0.02], budget=Budget(1.0, 3, 1.0, 20),
        ring_sizes=[1, 10, 100, 1000, 10000], ring_wall=0.2,
        shipped_duration=4.0, shipped_steps=[4.0, 2.0, 1.0, 0.5], shipped_ref_divisor=4.0,
        profile_steps=3000, bounce_tolerances=[10.0 ** -k for k in range(4, 13, 2)],
        bounce_steps=[0.004, 0.001, 0.00025]),
}


@dataclass
class Results:
    mode: str
    rows: list[Row] = field(default_factory=list)
    references: dict[str, Reference] = field(default_factory=dict)
    checks: list[peer_mod.Check] = field(default_factory=list)
    ring: list[Row] = field(default_factory=list)
    #: N -> our semi-implicit Euler's cost over the C loop's, one ratio per pair of runs
    #: made back to back (:data:`RING_PAIRS`); the ring target's figure.
    ring_pairs: dict[int, list[float]] = field(default_factory=dict)
    sample: dict[str, float] = field(default_factory=dict)  # engine -> s per step
    sample_rows: list[Row] = field(default_factory=list)  # the rows behind ``sample``
    sample_duration: float = 0.0  # s of sim time it was measured over
    declared: dict[str, float] = field(default_factory=dict)  # variant -> s per step
    profiles: dict[str, str] = field(default_factory=dict)
    bounce: list[BounceRow] = field(default_factory=list)  # the ball drop's rows
    lean: dict[str, tuple[float, float]] = field(default_factory=dict)
    cross_check: dict[str, float] = field(default_factory=dict)
    environment: dict[str, str] = field(default_factory=dict)
    guard: list[str] = field(default_factory=list)  # the regression guard's lines
    seconds: float = 0.0
    command: str = ""


# ----------------------------------------------------------------------------- core cases

#: The engine name of runs made in Python with the compiled kernel built (for comparison).
PYTHON_PATH = "hecker_dynamics (python)"


def core_run(scene: Scene, duration: float, python: bool = False) -> Outcome:
    """Build a Simulation (untimed), then ``play`` its script over ``duration`` (timed);
    ``python``: with the forces and steps in Python even where the kernel is built."""
    sim = Simulation(scene)
    if python:
        sim.model.use_python()
    until = round(duration * 1e9)
    failed = ""
    start = time.perf_counter()
    try:
        sim.play(scene.script, until)
    except DivergenceError as error:
        failed = str(error)
    wall = time.perf_counter() - start
    c = sim.integrator.counters
    if failed:
        return Outcome(wall, sim.q * math.nan, sim.v * math.nan, sim.steps, c.evaluations,
                       failed)
    return Outcome(wall, sim.q.copy(), sim.v.copy(), sim.steps, c.evaluations)


def core_case(name: str, scene: Scene, method: str, step: float, tolerance: float = 1e-6,
              duration: Optional[float] = None, python: bool = False) -> Case:
    duration = scene.duration_ns * 1e-9 if duration is None else duration
    configured = configure(scene, method, step, tolerance)
    return Case(name, PYTHON_PATH if python else "hecker_dynamics", method, step,
                tolerance if method in ADAPTIVE else math.nan, duration,
                lambda d: core_run(configured, d, python))


def core_cases(name: str, scene: Scene, mode: Mode, duration: float,
               steps: list[float]) -> list[Case]:
    cases = []
    for method in METHODS:
        if method in ADAPTIVE:
            for h in mode.adaptive_steps:
                if _divides(h, duration):
                    cases += [core_case(name, scene, method, h, tol, duration)
                              for tol in mode.tolerances]
        else:
            cases += [core_case(name, scene, method, h, 1e-6, duration)
                      for h in steps if _divides(h, duration)]
    return cases


def _divides(h: float, duration: float) -> bool:
    n = duration / h
    return abs(n - round(n)) < 1e-9 * n and round(n) >= 1


def _dividing_step(target: float, duration: float) -> Optional[float]:
    """The step nearest ``target`` (within -30 %/+40 %) that divides ``duration`` into a
    whole number of whole-nanosecond steps, or None."""
    total_ns = round(duration * 1e9)
    ideal = duration / target
    counts = [n for n in range(max(1, math.floor(ideal * 0.7)), math.ceil(ideal * 1.45) + 1)
              if total_ns % n == 0]
    if not counts:
        return None
    return total_ns // min(counts, key=lambda n: abs(n - ideal)) * 1e-9


# ----------------------------------------------------------------------------- parts

def bench_scenes(results: Results, mode: Mode, names: list[str], peers: list[str],
                 log: Callable[[str], None]) -> None:
    for name in names:
        scene = bench_scene(name)
        duration = scene.duration_ns * 1e-9
        started = time.perf_counter()
        ref = reference(scene)
        results.references[name] = ref
        log(f"{name}: reference {ref.kind}, own error {ref.error:.2g} m "
            f"({time.perf_counter() - started:.1f} s)")
        if ref.kind != "exact":  # cross-check against the core's tightest dopri5
            sim = Simulation(configure(scene, "dopri5", 0.02, 1e-13))
            sim.advance_to(scene.duration_ns)
            results.cross_check[name] = float(np.max(np.hypot(*(sim.q[:, :2] - ref.q[:, :2]).T)))
        plain = PlainModel(scene)
        steps = mode.steps[name]
        cases = core_cases(name, scene, mode, duration, steps)
        for peer in peers:
            for method in peer_mod.PEER_METHODS[peer]:
                cases += [peer_mod.peer_case(peer, name, scene, method, h, duration)
                          for h in steps if _divides(h, duration)]
        omega = Model(scene).stiffness()
        rows = measure(cases, mode.budget, ref, plain, log, omega=omega)
        results.rows += rows
        log(f"{name}: {len(rows)} configurations in {time.perf_counter() - started:.1f} s")


def shipped(results: Results, mode: Mode, names: list[str], log: Log) -> None:
    for name in names:
        started = time.perf_counter()
        scene = bench_scene(name)
        duration = min(mode.shipped_duration, scene.duration_ns * 1e-9)
        scene = configure(scene, scene.integrator, scene.step_ns * 1e-9, scene.tolerance,
                          duration=duration)
        own = scene.step_ns * 1e-9
        ref = core_reference(scene, own / mode.shipped_ref_divisor)
        results.references[name] = ref
        log(f"{name}: reference {ref.kind}, own error {ref.error:.2g} m "
            f"({time.perf_counter() - started:.1f} s)")
        steps = [own * f for f in mode.shipped_steps]
        omega = Model(scene).stiffness()
        stiff: list[float] = []
        if omega > 0 and (name == STIFF_SEESAW or mode.name == "full"):  # to omega*dt = 100
            stiff = [h for h in (_dividing_step(x / omega, duration) for x in (10.0, 30.0, 100.0))
                     if h is not None and h > max(steps)]
        steps = [h for h in steps if _divides(h, duration)] or [own]
        cases = core_cases(name, scene, mode, duration, sorted(set(steps), reverse=True))
        results.rows += measure(cases, mode.budget, ref, None, log, omega=omega)
        if stiff:  # target 4's stability runs: never skipped for their cost, timed once
            cases = core_cases(name, scene, mode, duration, sorted(stiff, reverse=True))
            results.rows += measure([c for c in cases if c.method not in ADAPTIVE],
                                    dataclasses.replace(mode.budget, per_run=math.inf,
                                                        repeats=1), ref, None, log, omega=omega)
        log(f"{name}: done in {time.perf_counter() - started:.1f} s")


#: Pairs of back-to-back whole runs (ours, the C loop) per ring size: the machine's speed
#: drifts by up to half over the minutes one size's sweep takes, and a run next to its pair
#: sees the same speed.
RING_PAIRS = 9


def ring_part(results: Results, mode: Mode, peers: list[str], log: Log,
              sizes: Optional[list[int]] = None) -> None:
    h = 1e-3
    have_c = load_c_loop() is not None
    for n in sizes or mode.ring_sizes:
        started = time.perf_counter()
        scene = ring(n)
        cases = []
        for method in METHODS:
            if method in ("implicit_midpoint", "backward_euler") and n > 30:
                continue  # dense Newton with a finite-difference Jacobian: O(N^3), O(N) evals
            cases.append(core_case(f"ring{n}", scene, method, h, 1e-6, 1.0))
        if kernel.enabled():  # the line of a machine without the kernel
            cases.append(core_case(f"ring{n}", scene, "semi_implicit_euler", h, 1e-6, 1.0,
                                   python=True))
        if have_c:
            cases.append(Case(f"ring{n}", "c", "semi_implicit_euler", h, math.nan, 1.0,
                              functools.partial(c_run, n, h)))
        for peer, method in (("pymunk", "native"), ("mujoco", "euler"), ("box2d", "python")):
            if peer in peers:
                cases.append(peer_mod.peer_case(peer, f"ring{n}", scene, method, h, 1.0))
        # Pick each case's duration so one timed run lasts about ring_wall seconds.
        for case in cases:
            try:
                pilot = case.run(5 * h)
                per_step = max(pilot.wall / 5, 1e-9)
            except Exception:
                per_step = 1.0
            steps = int(min(20000, max(10, mode.ring_wall / per_step)))
            case.duration = steps * h
        # Ours and the C loop take the same steps: a whole run's fixed cost then weighs alike.
        paired = [case for case in cases if case.engine in ("hecker_dynamics", "c")
                  and case.method == "semi_implicit_euler"]
        longest = max((case.duration for case in paired), default=0.0)
        for case in paired:
            case.duration = longest
        budget = Budget(per_run=max(mode.ring_wall * 6, 1.0), repeats=mode.budget.repeats,
                        per_case=mode.ring_wall * 4, pilot_steps=5)
        rows = measure(cases, budget, None, None)
        for row in rows:
            row.note = (row.note + "; " if row.note else "") + f"N = {n}"
            row.omega_dt = float(n)  # reused: N
        results.ring += rows
        if len(paired) == 2:
            results.ring_pairs[n] = ring_pairs(paired[0], paired[1])
        log(f"ring N = {n}: {time.perf_counter() - started:.1f} s")


def ring_pairs(ours: Case, c_loop: Case) -> list[float]:
    """Our cost per step over the C loop's, from :data:`RING_PAIRS` rounds of whole runs
    made back to back (:func:`.measure.interleaved_runs`: A B, B A, ...)."""
    def per_step(case: Case) -> Callable[[], float]:
        def run() -> float:
            outcome = case.run(case.duration)
            return outcome.wall / max(1, outcome.steps)
        return run

    walls = interleaved_runs({"ours": per_step(ours), "c": per_step(c_loop)}, RING_PAIRS)
    return [a / b for a, b in zip(walls["ours"], walls["c"])]


def sample_step(results: Results, mode: Mode, peers: list[str], log: Log) -> None:
    """The default scene's cost per step against the scene peers ``peers`` (target 2),
    over the scene's full duration in the full mode, from :func:`.contacts.scene_rows`."""
    from ..scene.load import load_scene
    from .contacts import scene_rows

    scene = load_scene("sample")
    if mode.sample_duration is not None:
        scene = dataclasses.replace(scene, duration_ns=round(mode.sample_duration * 1e9))
    rows = scene_rows("sample", scene, peers, python_path=True, rounds=mode.budget.repeats)
    results.sample_rows = rows
    results.sample = {(row.engine if row.engine.startswith("hecker_dynamics")
                       and not row.method.endswith(", sleeping")
                       else f"{row.engine} ({row.method})"): row.cost * row.step
                      for row in rows if row.status == "ok"}
    results.sample_duration = scene.duration_ns * 1e-9
    log("default scene, s per step: " + ", ".join(f"{k} {v * 1e6:.1f} us"
                                                   for k, v in results.sample.items()))


def bounce_part(results: Results, mode: Mode, peers: list[str], log: Log) -> None:
    """The ball drop against its closed form, with and without event location, and the
    scene peers ``peers`` with their own restitution."""
    results.bounce = bounce_bench(mode.bounce_tolerances, mode.bounce_steps, peers,
                                  mode.budget, log)


def declared_part(results: Results, mode: Mode, log: Log) -> None:
    """Cost per step of one scene with and without a (never used) contact pass declared."""
    variants = declared_variants()
    runs: dict[str, list[float]] = {k: [] for k in variants}
    for r in range(mode.budget.repeats):
        for key in (list(variants) if r % 2 == 0 else list(variants)[::-1]):
            scene = configure(variants[key], "semi_implicit_euler", 0.001)
            outcome = core_run(scene, 1.0)
            runs[key].append(outcome.wall / outcome.steps)
    results.declared = {k: float(np.median(v)) for k, v in runs.items()}
    log("declared contact passes, s per step: " + ", ".join(
        f"{k} {v * 1e6:.1f} us" for k, v in results.declared.items()))


def peer_checks(results: Results, peers: list[str]) -> None:
    for peer in peers:
        for method in peer_mod.PEER_METHODS[peer]:
            for name in ("harmonic", "spring_pendulum", "two_bodies"):
                results.checks.append(peer_mod.check_peer(peer, method, name, bench_scene(name)))
        if peer == "pymunk":  # the trap: forces set before step() give explicit Euler
            scene = bench_scene("spring_pendulum")
            for scheme in ("position_first_euler", "explicit_euler"):
                results.checks.append(peer_mod.check_peer(
                    "pymunk", "python", "spring_pendulum", scene, scheme=scheme,
                    forces_before_step=True))


def profiles(results: Results, mode: Mode) -> None:
    """cProfile summaries (top functions by own time) and the lean loop comparison."""
    from ..scene.load import load_scene
    targets = {"sample": load_scene("sample"), "two_bodies": bench_scene("two_bodies"),
               "ring1000": ring(1000)}
    for name, scene in targets.items():
        steps = mode.profile_steps if not name.startswith("ring") else mode.profile_steps // 30
        h = scene.step_ns * 1e-9
        cfg = configure(scene, "semi_implicit_euler", h)
        sim = Simulation(cfg)
        profiler = cProfile.Profile()
        profiler.enable()
        sim.play(cfg.script, round(steps * h * 1e9))
        profiler.disable()
        out = io.StringIO()
        pstats.Stats(profiler, stream=out).sort_stats("tottime").print_stats(12)
        results.profiles[name] = _trim_profile(out.getvalue())
        # The integrator stepped from Python on model.accelerations, versus advance_to.
        sim = Simulation(cfg)
        start = time.perf_counter()
        sim.advance_to(round(steps * h * 1e9))
        full = (time.perf_counter() - start) / steps
        model = Model(cfg)
        integrator = make_integrator("semi_implicit_euler")
        q, v = model.initial_state()
        start = time.perf_counter()
        for _ in range(steps):
            q, v = integrator.step(model.accelerations, q, v, h)
        lean = (time.perf_counter() - start) / steps
        results.lean[name] = (full, lean)


def _trim_profile(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    start = next((i for i, line in enumerate(lines) if "ncalls" in line), 0)
    head = [line for line in lines[:start] if "function calls" in line]
    return "\n".join(head + lines[start:start + 13])


def guard(results: Results, reference: Path, save: bool, log: Callable[[str], None]) -> None:
    """Compare the run's ratios with the reference's (:mod:`.regression`), or, with
    ``save``, make them the reference."""
    from .regression import compare, quick_ratios, read_reference, verdict_lines, write_reference

    ratios = quick_ratios(results)
    if save:
        write_reference(reference, ratios, {"command": results.command, **results.environment})
        results.guard = [f"wrote {len(ratios)} ratios to {reference} as the reference"]
    elif not reference.exists():
        results.guard = [f"no reference at {reference}: nothing compared"]
    else:
        results.guard = verdict_lines(compare(ratios, read_reference(reference)))
    for line in results.guard:
        log(f"guard: {line}")


def run_bench(mode_name: str = "quick", out: Optional[Path] = None,
              scenes: Optional[list[str]] = None, peers: Optional[bool] = True,
              log: Callable[[str], None] = print, command: str = "",
              parts: tuple[str, ...] = ("scenes", "shipped", "ring", "sample", "declared",
                                        "bounce", "checks", "profiles"),
              bar: Optional[BarFactory] = None, reference: Optional[Path] = None,
              save_reference: bool = False) -> Results:
    """Run the benchmark's ``parts`` in ``mode_name`` and write the report into ``out``
    (by default a new folder, :func:`~hecker_dynamics.bench.report.new_report_folder`);
    with ``reference`` (a file of :mod:`.regression`), compare its ratios with the
    reference's (``save_reference``: write them there instead)."""
    from ..scene.load import shipped_scenes
    from .report import new_report_folder, write_report

    out = new_report_folder() if out is None else out
    mode = MODES[mode_name]
    started = time.perf_counter()
    results = Results(mode_name, command=command)
    chosen = scenes or [*BENCH_SCENES, *shipped_scenes(), STIFF_SEESAW]
    peer_names = [p for p in peer_mod.PEERS if peers and peer_mod.available(p)]
    # The peers of the scenes with contacts (pymunk, Box2D 2.3, Box2D v3).
    scene_peer_names = [p for p in SCENE_PEERS if peers and peer_mod.available(p)]
    results.environment = {
        "python": sys.version.split()[0], "numpy": np.__version__,
        "machine": f"{platform.machine()}, {platform.system()} {platform.release()}",
        "c compiler": compiler_version(),
        "C loop flags": c_loop_flags(),
        "load average at start": "{:.2f}, {:.2f}, {:.2f}".format(*os.getloadavg()),
        "kernel": ("compiled" if kernel.enabled() else
                   f"python ({'switched off' if kernel.built() else 'not built'})"),
        **{p: peer_mod.version(p) for p in (*peer_mod.PEERS, "box2d_v3")},
    }
    log(f"bench {mode_name}: scenes {', '.join(chosen)}; peers {', '.join(peer_names) or 'none'}")
    work: list[tuple[str, Callable[[], None]]] = []
    if "checks" in parts:
        work.append(("checks", lambda: peer_checks(results, peer_names)))
    if "scenes" in parts:
        work += [(name, functools.partial(bench_scenes, results, mode, [name], peer_names, log))
                 for name in chosen if name in BENCH_SCENES]
    if "shipped" in parts:
        work += [(name, functools.partial(shipped, results, mode, [name], log))
                 for name in chosen if name not in BENCH_SCENES]
    if "sample" in parts:
        work.append(("sample", lambda: sample_step(results, mode, scene_peer_names, log)))
    if "declared" in parts:
        work.append(("declared", lambda: declared_part(results, mode, log)))
    if "bounce" in parts:
        work.append(("ball_drop", lambda: bounce_part(results, mode, scene_peer_names, log)))
    if "ring" in parts:
        work += [(f"ring{n}", functools.partial(ring_part, results, mode, peer_names, log, [n]))
                 for n in mode.ring_sizes]
    if "profiles" in parts:
        work.append(("profiles", lambda: profiles(results, mode)))
    run_parts(work, bar, f"bench {mode_name}")
    results.seconds = time.perf_counter() - started
    results.environment["load average at end"] = "{:.2f}, {:.2f}, {:.2f}".format(
        *os.getloadavg())
    if reference is not None:
        guard(results, Path(reference), save_reference, log)
    write_report(results, out)
    log(f"wrote {out} in {results.seconds:.0f} s")
    return results
