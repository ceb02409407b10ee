"""Where the variants run: a process pool on this machine, or a Dask distributed cluster.

Both take a picklable function and a list of tasks and yield ``(position, result)`` as
the results come, in finishing order; the caller puts them back in order.

- :class:`ProcessPool` (the default): ``concurrent.futures.ProcessPoolExecutor`` over all
  cores. A worker process that dies breaks the pool (the standard library cannot replace
  it); :class:`EngineError` says so and the rows finished until then are kept.
- :class:`DaskCluster` (``--cluster ADDRESS``, or ``--cluster local`` for a
  ``LocalCluster`` of worker processes on this machine): each task is a
  ``client.submit(..., retries=N)``, collected with ``as_completed``. The scheduler
  reschedules the task of a worker that dies (up to its ``allowed-failures``, 3 by
  default); ``retries`` covers a task that raises. Dask is imported only here, only when
  this engine is chosen (the ``cluster`` extra).
"""
from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Optional, Protocol

__all__ = ["Engine", "EngineError", "ProcessPool", "DaskCluster", "make_engine",
           "default_workers"]

#: Extra attempts of a task that raised on a Dask worker.
RETRIES = 2


class EngineError(RuntimeError):
    """The engine cannot start, cannot be reached, or lost its workers."""


class Engine(Protocol):
    """What the sweep and the regression suite need of an engine."""

    workers: int
    dashboard: Optional[str]

    def run(self, function: Callable[[Any], Any],
            tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]: ...

    def close(self) -> None: ...


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class ProcessPool:
    """``workers`` processes on this machine."""

    dashboard: Optional[str] = None

    def __init__(self, workers: Optional[int] = None) -> None:
        self.workers = workers or default_workers()
        self._executor = ProcessPoolExecutor(max_workers=self.workers)

    def run(self, function: Callable[[Any], Any],
            tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        futures = {self._executor.submit(function, task): i for i, task in enumerate(tasks)}
        try:
            for future in as_completed(futures):
                yield futures[future], future.result()
        except BrokenProcessPool:
            raise EngineError("a worker process died and the process pool cannot replace "
                              "it; --cluster local retries a lost task instead") from None
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        self._executor.shutdown(cancel_futures=True)


class DaskCluster:
    """A Dask distributed client: of the scheduler at ``address``, or of a new
    ``LocalCluster`` of ``workers`` single-threaded processes on loopback for ``local``."""

    def __init__(self, address: str, workers: Optional[int] = None,
                 retries: int = RETRIES) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise EngineError("--cluster needs Dask distributed: pip install "
                              "'hecker_dynamics[cluster]'") from None
        self.retries = retries
        self._cluster = None
        try:
            if address == "local":
                self._cluster = LocalCluster(
                    n_workers=workers or default_workers(), threads_per_worker=1,
                    processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0",
                    # Its workers log a failed heartbeat while it shuts down: not news.
                    silence_logs=logging.CRITICAL)
                self.client = Client(self._cluster)
            else:
                self.client = Client(address, timeout="10s")
        except (OSError, TimeoutError, ValueError) as error:
            self.close()
            raise EngineError(f"cannot reach the Dask scheduler at {address}: {error}") \
                from None
        info = self.client.scheduler_info()
        self.workers = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values())
        self.dashboard = self.client.dashboard_link if "dashboard" in info.get("services", {}) \
            else None

    def run(self, function: Callable[[Any], Any],
            tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        from distributed import as_completed as dask_as_completed
        from distributed.scheduler import KilledWorker

        futures = [self.client.submit(function, task, retries=self.retries, pure=False)
                   for task in tasks]
        position = {future.key: i for i, future in enumerate(futures)}
        try:
            for future in dask_as_completed(futures):
                yield position[future.key], future.result()
        except KilledWorker as error:
            raise EngineError(f"the scheduler gave up on a task after it lost a worker each "
                              f"time it ran (allowed-failures): {error}") from None
        finally:
            self.client.cancel(futures)

    def close(self) -> None:
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
        if self._cluster is not None:
            self._cluster.close()


def make_engine(workers: Optional[int], cluster: Optional[str]) -> Engine:
    """The process pool, or the Dask cluster at ``cluster``."""
    if workers is not None and workers < 1:
        raise EngineError(f"--workers must be at least 1, not {workers}")
    if cluster is None:
        return ProcessPool(workers)
    return DaskCluster(cluster, workers)
