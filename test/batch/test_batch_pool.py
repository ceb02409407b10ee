"""The process pool's workers start without forking this (threaded) process, and stop
at a safe point when the sweep is stopped."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

from hecker_dynamics.batch.engines import ProcessPool
from hecker_dynamics.dynamics import kernel


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


def _descendants(pid: int, depth: int = 1) -> set[int]:
    """The live processes under ``pid``, from /proc's parent links: its children and
    theirs (``depth`` 1), or those at least ``depth`` generations down only."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if fields[0] != "Z":
            parents[int(stat.parent.name)] = int(fields[1])
    found, frontier, generation = set(), {pid}, 0
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier}
        generation += 1
        if generation >= depth:
            found |= frontier
    return found


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _into_a_variant(process: subprocess.Popen) -> None:
    """Wait until ``process`` has a worker (a child of its fork server, beside which it
    has the resource tracker), and 2 s more."""
    deadline = time.monotonic() + 120.0
    while not _descendants(process.pid, depth=2):
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    time.sleep(2.0)  # into the variant's run


def _sweep(tmp_path: Path, *, sigint: int, group: bool) -> subprocess.Popen:
    """A sweep of two long variants on one worker, started with SIGINT's disposition
    ``sigint``, as a shell starts a command: at its default in the foreground, ignored for
    ``cmd &`` in a script. (Set here, not inherited: pytest itself may run ignoring it.)"""
    arguments = ["sweep", "chain", "--set", "bodies.link00.mass=1,2", "--duration", "3000",
                 "--workers", "1", "--bags", str(tmp_path / "bags"), "-o",
                 str(tmp_path / "rows.csv")]
    start = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.Handlers(int("
             "sys.argv[1]))); os.execv(sys.executable, [sys.executable, '-m', "
             "'hecker_dynamics.cli', *sys.argv[2:]])")
    return subprocess.Popen([sys.executable, "-c", start, str(int(sigint)), *arguments],
                            stderr=subprocess.PIPE, text=True, start_new_session=group)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("signum, status, line", [
    (signal.SIGTERM, 143, "hecker-dynamics: terminated"),
    (signal.SIGINT, 130, "hecker-dynamics: interrupted")])
@pytest.mark.parametrize("group", [False, True], ids=["command", "group"])
def test_a_stopped_sweep_stops_its_running_workers(tmp_path, signum, status, line, group):
    """A sweep stopped mid-variant (SIGTERM from a CI timeout, or Ctrl-C) ends in one line
    with the shell's status, its pool workers and fork server with it: before, Ctrl-C
    waited for the running variant (minutes for a long one), and after SIGTERM the worker
    ran on as an orphan until its variant ended. The worker stops at a publish instant and
    removes what it had begun: the bags folder is left empty, the partial file holds no
    cut row. The signal sent to the whole process group (a terminal's Ctrl-C; a CI runner
    or ``kill -- -PGID`` ending a job) too: SIGTERM killed the fork server with the
    command, the pool then took its worker for dead and neither waited for it nor killed
    it, and the worker, its variant stopped, waited for tasks forever, holding the
    command's stdout and stderr."""
    bags = tmp_path / "bags"
    process = _sweep(tmp_path, sigint=signal.SIG_DFL, group=group)
    try:
        _into_a_variant(process)
        under = _descendants(process.pid)
        if group:
            os.killpg(process.pid, signum)
        else:
            process.send_signal(signum)
        _, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == status, err
    assert err.splitlines() == [line], err
    deadline = time.monotonic() + 10.0
    while any(map(_alive, under)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in under if _alive(pid)]
    assert list(bags.iterdir()) == []
    assert not (tmp_path / "rows.csv").exists()
    partial = tmp_path / "rows.csv.partial.csv"
    assert not partial.exists() or partial.read_text().count("\n") <= 1


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_a_sweep_that_ignores_ctrl_c_keeps_its_workers_running(tmp_path):
    """A sweep started ignoring SIGINT (``cmd &`` in a script) still gets a Ctrl-C in its
    terminal, sent to the whole group: the command ran on as it should, but its worker
    took the signal as a stop, and the sweep then failed with "a worker process was
    stopped by a signal" (rc 2). Its workers ignore it too now; SIGTERM still stops all."""
    process = _sweep(tmp_path, sigint=signal.SIG_IGN, group=True)
    try:
        _into_a_variant(process)
        under = _descendants(process.pid)
        os.killpg(process.pid, signal.SIGINT)
        time.sleep(3.0)  # many publish instants of the variant, each a stop point
        assert process.poll() is None, process.communicate()[1]
        assert all(map(_alive, under))
        os.killpg(process.pid, signal.SIGTERM)
        _, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert (process.returncode, err) == (143, "hecker-dynamics: terminated\n")


def _session(sid: int) -> set[int]:
    """The live processes of session ``sid``, from /proc."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if fields[0] != "Z" and int(fields[3]) == sid:
            found.add(int(stat.parent.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("command", ["sweep", "regress"])
def test_a_killed_command_leaves_no_process_behind(tmp_path, command):
    """SIGKILL of the command alone (a CI runner's hard kill, the OOM killer): before, its
    worker, its variant unwound, waited for tasks forever, and kept the fork server and
    the resource tracker alive with it, all holding the command's stdout and stderr, so a
    CI step reading them never ended. Now every process of its session ends within
    seconds, its output reaches its end, and nothing is left half written."""
    bags = tmp_path / "bags"
    if command == "sweep":
        arguments = ["sweep", "chain", "--set", "bodies.link00.mass=1,2", "--duration",
                     "3000", "--workers", "1", "--bags", str(bags), "-o",
                     str(tmp_path / "rows.csv")]
    else:
        recorded = tmp_path / "recorded"
        # The session must outlast the wait into its replay (the start and 2 s), which the
        # check before the kill makes sure of: 20 s of the chain in the kernel (its replay
        # takes about 13 s on a quiet machine here); 5 s without it, whose Python steps
        # take about as long (2 s, about as long as the wait, ended before the kill on a
        # quiet machine).
        seconds = "20" if kernel.enabled() else "5"
        subprocess.run([sys.executable, "-m", "hecker_dynamics.cli", "sweep", "chain",
                        "--set", "bodies.link00.mass=1", "--duration", seconds, "--workers",
                        "1", "--bags", str(recorded), "-o", str(tmp_path / "recorded.csv")],
                       check=True, capture_output=True)
        arguments = ["regress", str(recorded), "--workers", "1"]
    process = subprocess.Popen([sys.executable, "-m", "hecker_dynamics.cli", *arguments],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               start_new_session=True)
    try:
        _into_a_variant(process)
        assert process.poll() is None, "the command ended before the kill"
        process.kill()
        process.wait()
        ended = threading.Event()
        reader = threading.Thread(target=lambda: (process.stdout.read(), ended.set()),
                                  daemon=True)
        reader.start()
        deadline = time.monotonic() + 15.0
        while _session(process.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = _session(process.pid)
        assert ended.wait(timeout=5.0), "the command's output never reached its end"
    finally:
        for pid in _session(process.pid):
            os.kill(pid, signal.SIGKILL)
    assert not left
    if command == "sweep":
        assert list(bags.iterdir()) == []
    partial = tmp_path / "rows.csv.partial.csv"
    assert not (tmp_path / "rows.csv").exists()
    assert not partial.exists() or partial.read_text().count("\n") <= 1
