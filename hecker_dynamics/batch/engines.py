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
  A pool stopped while tasks run (Ctrl-C, SIGTERM, an error writing a row) closes the
  write end of a pipe whose read end its workers hold; a task looks at it at its safe
  points (:func:`stop_point`, between publish instants) and unwinds as from any error,
  removing what it had begun, so the worker is free again within one publish period. A
  signal to a worker (one the command does not ignore), or the command killed (which
  closes the pipe too), stops its task the same way; workers still running after
  :data:`STOP_GRACE` are killed. A second pipe,
  which the command never closes, tells a worker the command has gone (killed by SIGKILL,
  say): it exits once its task has unwound (after :data:`STOP_GRACE` at most), and with
  the last worker the fork server and multiprocessing's resource tracker, whose pipes the
  workers hold, end too; else all three waited forever, holding the command's output open.
  (A pipe, not
  shared memory: that is a file, which a full disk refuses. Ending a worker by a signal's
  exception at an arbitrary point cannot promise its cleanup: one stopped between making
  a scratch file and its ``try`` leaves the file.)
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

import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.connection import Connection
from typing import Any, Optional, Protocol

__all__ = ["Engine", "EngineError", "ProcessPool", "DaskCluster", "make_engine",
           "default_workers", "Stopped", "stop_point", "STOP_GRACE"]

#: Extra attempts of a task that raised on a Dask worker.
RETRIES = 2
#: The module of the tasks every worker runs (:mod:`hecker_dynamics.batch.run`), and one of
#: them by name, as ``pkgutil.resolve_name`` reads it.
TASK_MODULE = "hecker_dynamics.batch.run"
TASK_PROBE = f"{TASK_MODULE}:run_variant"
#: Seconds a stopped pool waits for its running tasks to reach a safe point before it
#: kills their workers: many publish periods of any shipped scene, under load.
STOP_GRACE = 10.0


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


class Stopped(Exception):
    """The task's pool is stopping: raised by :func:`stop_point` in a worker."""


class _StoppedTask:
    """What a worker returns for a task it stopped (picklable, by its module's name)."""


#: The read end of the pool's stop pipe (None outside a pool worker): readable (at its
#: end) once the pool stops or the command has gone. Whether a signal reached the worker.
_stop_pipe: Optional[Connection] = None
_signalled = False
#: Held by a pool worker while it runs a task (see :func:`_exit_when_orphaned`).
_in_task = threading.Lock()


#: The signals a worker takes as a stop: Ctrl-C reaches the whole process group, and so
#: does a CI runner's SIGTERM.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _start_worker(pipe: Connection, command: Connection,
                  ignored: tuple[int, ...]) -> None:
    """A pool worker's start: keep the stop pipe, take the :data:`STOP_SIGNALS` the command
    does not ignore (``ignored``) as a stop at the next safe point, and exit once the
    command has gone (``command``, the read end of its pipe of life, at its end). A
    command started ignoring SIGINT (``cmd &`` in a script, which a Ctrl-C in its terminal
    still reaches) runs on through one; its workers must too, else the command ran on
    and reported their stopped tasks as its failure."""
    global _stop_pipe
    _stop_pipe = pipe
    threading.Thread(target=_exit_when_orphaned, args=(command,), daemon=True).start()
    for signum in STOP_SIGNALS:
        if signum not in ignored:
            signal.signal(signum, _on_signal)
    # The fork server started with both blocked (see _start_fork_server).
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)


def _exit_when_orphaned(command: Connection) -> None:
    """End this worker once the command's end of ``command`` has closed, which only its
    death does: the executor that would send the worker its sentinel has gone, and the
    worker holds the write end of its own task queue, so it would wait for a task
    forever. A task running then sees the stop pipe closed too and unwinds at its next
    safe point; the worker exits when it has, or after :data:`STOP_GRACE`."""
    command.poll(None)  # nothing is ever sent: readable means closed
    _in_task.acquire(timeout=STOP_GRACE)
    os._exit(1)


def _on_signal(signum: int, frame: object) -> None:
    global _signalled
    _signalled = True


def stop_point() -> None:
    """Raise :class:`Stopped` in a pool worker whose pool is stopping, which a signal
    reached, or whose fork server has gone (the command was killed); elsewhere nothing.
    A task calls it where it may stop and clean up as after any error."""
    if _stop_pipe is not None and (_signalled or _stop_pipe.poll()):
        raise Stopped


#: A warning a task raised in a pool worker: its category, text, file and line.
_Warned = tuple[type[Warning], str, str, int]


def _stoppable(function: Callable[[Any], Any], task: Any) -> tuple[Any, list[_Warned]]:
    """``function(task)`` in a pool worker, or :class:`_StoppedTask` if it stopped (a task
    queued before the stop stops before it begins), and the warnings it raised: the
    command shows them as it shows its own (a worker would print each in Python's two
    lines, once a worker)."""
    with _in_task, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            stop_point()
            result = function(task)
        except Stopped:
            result = _StoppedTask()
    return result, [(w.category, str(w.message), w.filename, w.lineno) for w in caught]


def _ignored_signals() -> tuple[int, ...]:
    """The :data:`STOP_SIGNALS` this process ignores."""
    return tuple(signum for signum in STOP_SIGNALS
                 if signal.getsignal(signum) == signal.SIG_IGN)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM until the block ends, then take them: a submit starts a
    worker, and one broken off while it starts is one the executor does not know of, so
    shutdown would not wait for it; it reads its arguments after this process removed
    their semaphores and prints a traceback. (In the main thread only, where Python runs
    signal handlers.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = {signum: signal.signal(signum, lambda signum, _: caught.append(signum))
                for signum in STOP_SIGNALS}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
        if caught:
            signal.raise_signal(caught[0])


class ProcessPool:
    """``workers`` processes on this machine."""

    dashboard: Optional[str] = None

    def __init__(self, workers: Optional[int] = None) -> None:
        self.notes: list[str] = []
        self.workers = workers or default_workers()
        context = _start_context()
        #: The stop pipe: its write end closed by :meth:`close` while tasks run, read by
        #: the workers' :func:`stop_point` (no lock: a worker killed holding one would
        #: hold it).
        self._stopping, self._stop = context.Pipe(duplex=False)
        #: The pipe of life: its write end closed only after the workers have ended, or
        #: by this process's death (see :func:`_exit_when_orphaned`).
        self._orphaned, self._alive = context.Pipe(duplex=False)
        #: Every task given to the pool (:meth:`close` stops those running).
        self._futures: list[Future[Any]] = []
        #: The warnings of the tasks shown so far, by category and text.
        self._warned: set[tuple[type[Warning], str]] = set()
        self._executor = ProcessPoolExecutor(max_workers=self.workers, mp_context=context,
                                             initializer=_start_worker,
                                             initargs=(self._stopping, self._orphaned,
                                                       _ignored_signals()))

    def run(self, function: Callable[[Any], Any],
            tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        with _signals_held():
            futures = {self._executor.submit(_stoppable, function, task): i
                       for i, task in enumerate(tasks)}
            self._futures.extend(futures)
        try:
            for future in as_completed(futures):
                result, warned = future.result()
                for category, text, filename, lineno in warned:
                    if (category, text) not in self._warned:  # once, not once a task
                        self._warned.add((category, text))
                        warnings.warn_explicit(text, category, filename, lineno)
                if isinstance(result, _StoppedTask):
                    raise EngineError("a worker process was stopped by a signal before its "
                                      "task ended")
                yield futures[future], result
        except BrokenProcessPool:
            raise EngineError("a worker process died and the process pool cannot replace "
                              "it; --cluster local retries a lost task instead") from None
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        """Cancel the tasks not begun and stop those running: they unwind at their next
        :func:`stop_point`; workers still busy after :data:`STOP_GRACE` are killed (waiting
        for them would hold the command as long as its longest variant)."""
        running = [future for future in self._futures if not future.done()]
        if running:
            self._stop.close()
            try:
                wait(running, timeout=STOP_GRACE)
            finally:
                if not all(future.done() for future in running):
                    for process in list((self._executor._processes or {}).values()):
                        process.kill()
        self._executor.shutdown(cancel_futures=True)
        for end in (self._stop, self._stopping, self._alive, self._orphaned):
            end.close()


def _start_context() -> multiprocessing.context.BaseContext:
    """A fork server where the platform has one (Linux, macOS), else ``spawn``."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload([TASK_MODULE])
        _start_fork_server()
        return context
    return multiprocessing.get_context("spawn")


def _start_fork_server() -> None:
    """Start the fork server with Ctrl-C and SIGTERM ignored, which it keeps through its
    ``exec``: a SIGTERM to the whole process group (a CI runner ending a job, ``kill --
    -PGID``) ended it under its running workers; the pool then took them for dead,
    neither waited for nor killed them, and each, its task stopped, waited for tasks
    forever, holding the command's output open. (It ignores Ctrl-C itself once it has
    imported the task module; before, one printed a traceback of that import.) Both are
    blocked meanwhile, so one sent to the command then is taken after, not lost. In the
    main thread only; elsewhere the fork server starts on first use."""
    from multiprocessing import forkserver

    if threading.current_thread() is not threading.main_thread():
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    previous = {signum: signal.signal(signum, signal.SIG_IGN) for signum in STOP_SIGNALS}
    try:
        forkserver.ensure_running()
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


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
