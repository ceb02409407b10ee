"""The process pool's workers start without forking this (threaded) process."""
from __future__ import annotations

import threading
import warnings

from hecker_dynamics.batch.engines import ProcessPool


def test_the_pool_does_not_fork_a_threaded_process():
    """Forking a process that runs threads can copy a lock a thread holds into the child,
    which then waits on it forever; Python 3.12 warns of it (a DeprecationWarning per
    fork) and 3.14 no longer forks by default. The pool starts its workers from a fork
    server (or spawns them) and runs tasks as before, with a thread running meanwhile."""
    pool = ProcessPool(2)
    assert pool._executor._mp_context.get_start_method() in ("forkserver", "spawn")
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait)
    thread.start()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            results = sorted(pool.run(abs, [-3, 4, -5]))
    finally:
        stop.set()
        thread.join()
        pool.close()
    assert results == [(0, 3), (1, 4), (2, 5)]
    assert not [w for w in caught if "fork" in str(w.message)], [str(w.message) for w in caught]
