"""Where the variants run: a process pool on this machine, or a Dask distributed cluster.

Both take a picklable function and a list of tasks and yield ``(position, result)`` as
the results come, in finishing order; the caller puts them back in order.

- :class:`ProcessPool` (the default): ``concurrent.futures.ProcessPoolExecutor`` over all
  cores. A worker process that dies breaks the pool (the standard library cannot replace
  it); :class:`EngineError` says so and the rows finished until then are kept. Its workers
  start from a fork server (``spawn`` where there is none): forking this process, which
  runs threads (the pool's own, a progress bar's), could copy a lock some thread holds
  and deadlock the child; Python 3.12 warns of it and 3.14 no longer forks by default.
  The fork server imports the task module once, so a worker starts without importing it;
  a worker imports the main module again, so a script that runs a sweep keeps its top
  level under ``if __name__ == "__main__":`` (the command line's entry points do).
- :class:`DaskCluster` (``--cluster ADDRESS``, or ``--cluster local`` for a
  ``LocalCluster`` of worker processes on this machine): each task is a
  ``client.submit(..., retries=N)``, collected with ``as_completed``. The scheduler
  reschedules the task of a worker that dies (up to its ``allowed-failures``, 3 by
  default); ``retries`` covers a task that raises. Dask is imported only here, only when
  this engine is chosen (the ``cluster`` extra). Before any task, every worker must
  import this package's task module: a cluster whose workers cannot is one line of
  :class:`EngineError`, not a traceback per task.
"""
from __future__ import annotations

import logging
import multiprocessing
import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Optional, Protocol

__all__ = ["Engine", "EngineError", "ProcessPool", "DaskCluster", "make_engine",
           "default_workers"]

#: Extra attempts of a task that raised on a Dask worker.
RETRIES = 2
#: The module of the tasks every worker runs (:mod:`hecker_dynamics.batch.run`), and one of
#: them by name, as ``pkgutil.resolve_name`` reads it.
TASK_MODULE = "hecker_dynamics.batch.run"
TASK_PROBE = f"{TASK_MODULE}:run_variant"


class EngineError(RuntimeError):
    """The engine cannot start, cannot be reached, or lost its workers."""


class Engine(Protocol):
    """What the sweep and the regression suite need of an engine."""

    workers: int
    dashboard: Optional[str]
    #: One-line warnings for the user (a Dask cluster's mismatched versions).
    notes: list[str]

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
        self.notes: list[str] = []
        self.workers = workers or default_workers()
        self._executor = ProcessPoolExecutor(max_workers=self.workers,
                                             mp_context=_start_context())

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


def _start_context() -> multiprocessing.context.BaseContext:
    """A fork server where the platform has one (Linux, macOS), else ``spawn``."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload([TASK_MODULE])
        return context
    return multiprocessing.get_context("spawn")


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
        self.notes: list[str] = []
        self._cluster = None
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                self._connect(address, workers, Client, LocalCluster)
        except (OSError, TimeoutError, ValueError) as error:
            self.close()
            raise EngineError(f"cannot reach the Dask scheduler at {address}: {error}") \
                from None
        self._keep_warnings(caught)
        self._check_workers(address)
        info = self.client.scheduler_info()
        self.workers = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values())
        self.dashboard = self.client.dashboard_link if "dashboard" in info.get("services", {}) \
            else None

    def _connect(self, address: str, workers: Optional[int], client: Any,
                 local_cluster: Any) -> None:
        if address == "local":
            self._cluster = local_cluster(
                n_workers=workers or default_workers(), threads_per_worker=1,
                processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0",
                # Its workers log a failed heartbeat while it shuts down: not news.
                silence_logs=logging.CRITICAL)
            self.client = client(self._cluster)
        else:
            self.client = client(address, timeout="10s")

    def _keep_warnings(self, caught: list[warnings.WarningMessage]) -> None:
        """Dask's table of the versions that differ between the client, the scheduler and
        the workers, as one note naming the packages; other warnings as they were."""
        from distributed.versions import VersionMismatchWarning

        for warning in caught:
            if not issubclass(warning.category, VersionMismatchWarning):
                warnings.warn_explicit(warning.message, warning.category, warning.filename,
                                       warning.lineno)
                continue
            rows = [line.split("|")[1].strip() for line in str(warning.message).splitlines()
                    if line.startswith("|")]
            packages = [name for name in rows if name and name != "Package"]
            self.notes.append("the Dask client, scheduler and workers run different versions "
                              f"of {', '.join(packages) or 'some packages'}")

    def _check_workers(self, address: str) -> None:
        """The scheduler (which unpickles the tasks it is given) and every worker must
        import :data:`TASK_MODULE`. The probe is the standard library's
        ``pkgutil.resolve_name`` of :data:`TASK_PROBE`, not a function of this package,
        which a process without it could not even unpickle; it answers with the task
        function (sent back by name) or the error of importing it."""
        import pkgutil

        def refuse(where: str, error: BaseException) -> EngineError:
            self.close()
            return EngineError(f"{where} at {address} cannot import {TASK_MODULE} "
                               f"({type(error).__name__}: {error}); install the same "
                               "hecker_dynamics and numpy on the scheduler and every worker")

        try:
            self.client.run_on_scheduler(pkgutil.resolve_name, TASK_PROBE)
        except (OSError, TimeoutError) as error:
            self.close()
            raise EngineError(f"cannot reach the Dask scheduler at {address}: {error}") \
                from None
        except Exception as error:  # whatever the import raised there
            raise refuse("the Dask scheduler", error) from None
        try:
            answers = self.client.run(pkgutil.resolve_name, TASK_PROBE, on_error="return")
        except (OSError, TimeoutError) as error:
            self.close()
            raise EngineError(f"cannot reach the Dask workers of {address}: {error}") \
                from None
        failed = sorted((worker, answer) for worker, answer in answers.items()
                        if isinstance(answer, BaseException))
        if failed:
            worker, failure = failed[0]
            raise refuse(f"{len(failed)} of {len(answers)} Dask worker(s) (e.g. {worker})",
                         failure)

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
