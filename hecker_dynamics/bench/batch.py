"""Speed-up of sweeps over one process: ``hecker-dynamics bench --batch``.

Two workloads on the sample scene, a grid over the left body's mass: many short variants
(0.02 s of sim time each, a few ms of CPU: the per-task cost of the engine shows) and
fewer long ones (30 s of sim time, about a second of CPU each: the cores show).
Each runs on one worker process, on all cores' worker processes, and (when Dask is
installed) on a Dask ``LocalCluster`` of as many processes, interleaved round by round;
the wall times include starting the engine, and every table must equal the one-process
table.
"""
from __future__ import annotations

import functools
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Optional

from ..batch.engines import DaskCluster, Engine, ProcessPool, default_workers
from ..batch.run import sweep
from ..batch.variants import Variant, make_variants, parse_setting
from ..viz.progress import BarFactory, run_parts

__all__ = ["WORKLOADS", "bench_batch"]

SEC = 1_000_000_000
#: name -> (variants, sim time of each, ns)
WORKLOADS = {"short": (1000, SEC // 50), "long": (50, 30 * SEC)}


def _engines(workers: int) -> dict[str, Callable[[], Engine]]:
    engines: dict[str, Callable[[], Engine]] = {
        "1 process": lambda: ProcessPool(1), f"{workers} processes": lambda: ProcessPool(workers)}
    try:
        import distributed  # noqa: F401
    except ImportError:
        return engines
    engines[f"dask local, {workers} workers"] = lambda: DaskCluster("local", workers)
    return engines


def bench_batch(rounds: int = 1, workers: int | None = None,
                report: Callable[[str], None] = print,
                bar: Optional[BarFactory] = None) -> dict[tuple[str, str], float]:
    """Median wall time (s) of each (workload, engine); prints a table with the speed-ups."""
    workers = workers or default_workers()
    engines = _engines(workers)
    times: dict[tuple[str, str], list[float]] = {}
    tables: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory() as scratch:
        def one(workload: str, variants: list[Variant], name: str) -> None:
            started = time.perf_counter()
            engine = engines[name]()
            try:
                # Each engine's table replaces the one before: they are compared as they come.
                path = sweep(variants, engine, Path(scratch) / "table.csv", progress=False,
                             overwrite=True)
            finally:
                engine.close()
            times.setdefault((workload, name), []).append(time.perf_counter() - started)
            table = tables.setdefault(workload, path.read_bytes())
            if path.read_bytes() != table:
                raise AssertionError(f"{name}: the {workload} table differs")

        work: list[tuple[str, Callable[[], None]]] = []
        for workload, (count, duration_ns) in WORKLOADS.items():
            masses = f"bodies.left.mass=0.5:2:{count}"
            variants = make_variants("sample", [parse_setting(masses)], duration_ns=duration_ns)
            work += [(name, functools.partial(one, workload, variants, name))
                     for _ in range(rounds) for name in engines]
        run_parts(work, bar, "bench batch")
    medians = {key: statistics.median(values) for key, values in times.items()}
    report(f"{'workload':<34}{'engine':<26}{'wall s':>9}{'speed-up':>10}")
    for workload, (count, duration_ns) in WORKLOADS.items():
        single = medians[(workload, "1 process")]
        label = f"{workload}: {count} x {duration_ns / SEC:g} s sim"
        for name in engines:
            wall = medians[(workload, name)]
            report(f"{label:<34}{name:<26}{wall:>9.2f}{single / wall:>9.2f}x")
    return medians
