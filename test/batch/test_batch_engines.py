"""Sweeps and regression suites on the process pool and on a real Dask cluster (a
scheduler and two worker processes on loopback): the same bytes as one process, a worker
killed mid-sweep survived, a tampered bag found."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from dataclasses import replace
from functools import partial
from pathlib import Path

import pytest

from hecker_dynamics.bags import read_bag
from hecker_dynamics.bags.compare import Tolerances
from hecker_dynamics.bags.replay import replay_to_bag, script_to_bag
from hecker_dynamics.batch.engines import DaskCluster, ProcessPool
from hecker_dynamics.batch.metrics import parse_metric
from hecker_dynamics.batch.run import SweepTask, find_bags, regress, run_variant, sweep
from hecker_dynamics.batch.variants import make_variants, parse_setting
from hecker_dynamics.cli import main
from hecker_dynamics.scene import load_scene

distributed = pytest.importorskip("distributed", reason="the cluster extra is not installed")
import cloudpickle  # noqa: E402  (a dependency of distributed)

# The tasks below live in this test module, which the workers cannot import: ship them.
cloudpickle.register_pickle_by_value(sys.modules[__name__])

SEC = 1_000_000_000
SETTINGS = ("bodies.left.mass=0.5,1,2", "bodies.right.velocity[0]=-1:1:3")
METRICS = ("gap=right.x - left.x", "spin=abs(left.omega) + abs(right.omega)")


@pytest.fixture(scope="module")
def cluster():
    """A scheduler and two single-threaded worker processes on 127.0.0.1."""
    local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=None)
    yield local
    local.close()


def _variants(**options):
    return make_variants("sample", [parse_setting(s) for s in SETTINGS],
                         duration_ns=SEC // 2, **options)


def _sweep(tmp_path: Path, name: str, engine, **options) -> bytes:
    try:
        path = sweep(_variants(**options.pop("variants", {})), engine, tmp_path / f"{name}.csv",
                     metrics=[parse_metric(m) for m in METRICS], progress=False, **options)
    finally:
        engine.close()
    assert not list(tmp_path.glob("*.partial.csv"))  # removed once the table is written
    return path.read_bytes()


def test_cluster_sweep_equals_one_process_bit_for_bit(tmp_path, cluster):
    one = _sweep(tmp_path, "one", ProcessPool(1))
    dask = _sweep(tmp_path, "dask", DaskCluster(cluster.scheduler_address))
    assert dask == one
    lines = one.decode().splitlines()
    assert len(lines) == 1 + 9 and [line.split(",")[0] for line in lines[1:]] == \
        [str(i) for i in range(9)]
    # Each row is the summary of the variant's own scene, run here in this process.
    variant = _variants()[4]
    row = run_variant(SweepTask(variant, tuple(parse_metric(m) for m in METRICS)))
    header = lines[0].split(",")
    cells = dict(zip(header, lines[1 + 4].split(",")))
    assert float(cells["left.x"]) == row["left.x"] and float(cells["energy_max"]) == \
        row["energy_max"]
    assert float(cells["gap"]) == row["gap"] == row["right.x"] - row["left.x"]


def test_same_seed_same_table_with_one_and_two_workers(tmp_path):
    sampled = {"samples": 6, "seed": 11}
    one = _sweep(tmp_path, "one", ProcessPool(1), variants=sampled)
    two = _sweep(tmp_path, "two", ProcessPool(2), variants=sampled)
    other = _sweep(tmp_path, "other", ProcessPool(2), variants={"samples": 6, "seed": 12})
    assert one == two
    assert other != one


def _kill_once(marker: Path, task):
    """Kill this worker process the first time variant 3 runs, then run it as usual."""
    if task.variant.index == 3 and not marker.exists():
        marker.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return run_variant(task)


def test_a_worker_killed_mid_sweep_loses_only_its_variant(tmp_path, cluster):
    reference = _sweep(tmp_path, "reference", ProcessPool(1))
    marker = tmp_path / "killed"
    survived = _sweep(tmp_path, "survived", DaskCluster(cluster.scheduler_address),
                      function=partial(_kill_once, marker))
    assert marker.exists()  # a worker did die
    assert survived == reference


def test_a_dead_pool_worker_keeps_the_finished_rows(tmp_path):
    from hecker_dynamics.batch.engines import EngineError

    engine = ProcessPool(1)
    with pytest.raises(EngineError, match="worker process died"):
        sweep(_variants(), engine, tmp_path / "t.csv", progress=False,
              function=partial(_kill_once, tmp_path / "killed"))
    engine.close()
    partial_rows = (tmp_path / "t.csv.partial.csv").read_text().splitlines()
    assert [line.split(",")[0] for line in partial_rows[1:]] == ["0", "1", "2"]
    assert not (tmp_path / "t.csv").exists()


def test_a_warning_of_the_workers_is_one_line_once(tmp_path):
    """A load 4e11 times lighter than the wall block it may rest on: the contact pass warns
    as each variant's scene is built in a worker. The warning reached stderr as Python
    prints it in the worker (two lines: the source file and line, the code), once a worker;
    it is the command's one line, once for the sweep."""
    result = subprocess.run(
        [sys.executable, "-m", "hecker_dynamics.cli", "sweep", "seesaw", "--set",
         "bodies.load.mass=1e-9,1e-9,1e-9", "--duration", "0.01", "--workers", "2",
         "--no-progress", "-o", str(tmp_path / "t.csv")],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines() == [
        "hecker-dynamics: warning: collision group 'everything': 'wall_block' (400 kg) is "
        "4e+11 times as heavy as 'load' (1e-09 kg); a body resting on one more than 1000 "
        "times lighter presses it into what it lies on or squeezes it out (docs/scenes.md: "
        "Contacts)"], result.stderr


# ----------------------------------------------------------------------------- regress

@pytest.fixture(scope="module")
def bag_suite(tmp_path_factory):
    """Three recorded sessions (inputs and outputs) of two shipped scenes, and one whose
    outputs came from a heavier left body: its recorded outputs no longer match its scene."""
    root = tmp_path_factory.mktemp("suite")
    (root / "inputs").mkdir()
    (root / "bags").mkdir()
    for name, scene_name, tamper in (("a_sample", "sample", False), ("b_door", "door", False),
                                     ("c_tampered", "sample", True), ("d_seesaw", "seesaw", False)):
        scene = replace(load_scene(scene_name), duration_ns=SEC // 2)
        script_to_bag(scene, root / "inputs" / name)
        recorded = scene
        if tamper:
            left = replace(scene.bodies[0], mass=replace(scene.bodies[0].mass,
                                                         mass=scene.bodies[0].mass.mass * 1.01))
            recorded = replace(scene, bodies=(left, *scene.bodies[1:]))
        replay_to_bag(recorded, read_bag(root / "inputs" / name), root / "bags" / name,
                      with_inputs=True)
    return root / "bags"


def _regress(engine, bags):
    lines = []
    try:
        results = regress(find_bags([bags]), engine, scene=None, tolerances=Tolerances(),
                          emit=lines.append, progress=False)
    finally:
        engine.close()
    return [(r.bag.name, r.status, r.detail) for r in results]


def test_cluster_regress_equals_one_process_and_finds_the_tampered_bag(bag_suite, cluster):
    one = _regress(ProcessPool(1), bag_suite)
    assert [(name, status) for name, status, _ in one] == [
        ("a_sample", "ok"), ("b_door", "ok"), ("c_tampered", "mismatch"), ("d_seesaw", "ok")]
    assert _regress(DaskCluster(cluster.scheduler_address), bag_suite) == one


def test_regress_command_exits_1_on_a_mismatch_and_2_on_bad_input(bag_suite, tmp_path, capsys):
    code = main(["regress", str(bag_suite), "--workers", "2", "--no-progress"])
    out = capsys.readouterr().out.splitlines()
    assert code == 1
    assert sorted(line.split()[0] for line in out[:-1]) == ["MISMATCH", "OK", "OK", "OK"]
    assert out[-1] == "4 bag(s): 3 ok, 1 mismatch, 0 error"
    assert main(["regress", str(bag_suite / "a_sample"), "--no-progress"]) == 0
    capsys.readouterr()
    # The wrong scene for a bag: it cannot be checked (exit 2), with the reason on its line.
    assert main(["regress", str(bag_suite / "b_door"), "--scene", "ship",
                 "--no-progress"]) == 2
    assert "ERROR" in capsys.readouterr().out
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["regress", str(empty)]) == 2
    assert "not a bag directory and holds none" in capsys.readouterr().err


def test_a_bag_cut_off_before_its_metadata_is_an_error_not_skipped(bag_suite, tmp_path,
                                                                   capsys):
    """A recording cut off before rosbag2 wrote its metadata.yaml (a killed recorder, a
    full disk) beside good bags was silently left out of the folder's bags: "1 bag(s):
    1 ok", exit 0. A folder holding a bag's storage file is a bag: its line is an error
    that says how to rebuild the metadata, and the exit is 2."""
    suite = tmp_path / "suite"
    suite.mkdir()
    shutil.copytree(bag_suite / "a_sample", suite / "a_sample")
    shutil.copytree(bag_suite / "a_sample", suite / "b_cut")
    (suite / "b_cut" / "metadata.yaml").unlink()
    assert main(["regress", str(suite), "--workers", "1", "--no-progress"]) == 2
    out = capsys.readouterr().out.splitlines()
    assert [line.split()[:2] for line in out[:-1]] == [
        ["OK", str(suite / "a_sample")], ["ERROR", str(suite / "b_cut")]], out
    assert "no metadata.yaml" in out[1] and "ros2 bag reindex" in out[1]
    assert out[-1] == "2 bag(s): 1 ok, 0 mismatch, 1 error"
    assert main(["regress", str(suite / "b_cut"), "--no-progress"]) == 2
    assert "no metadata.yaml" in capsys.readouterr().out


def test_bags_in_folders_of_the_folder_are_checked_too(bag_suite, tmp_path, capsys):
    """A suite kept in folders beside a bag (one per scene, say): only the top folder's bag
    was checked, "1 bag(s): 1 ok", exit 0, the tampered bag one folder down never read.
    Every bag at any depth is checked; hidden folders (a writer's temporary ones) and a
    symlink back up are not searched."""
    suite = tmp_path / "suite"
    (suite / "sample" / "more").mkdir(parents=True)
    shutil.copytree(bag_suite / "a_sample", suite / "a_sample")
    shutil.copytree(bag_suite / "c_tampered", suite / "sample" / "more" / "c_tampered")
    shutil.copytree(bag_suite / "b_door", suite / ".out.partial-x" / "out")
    (suite / "sample" / "loop").symlink_to(suite)
    assert main(["regress", str(suite), "--workers", "1", "--no-progress"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert [line.split()[:2] for line in out[:-1]] == [
        ["OK", str(suite / "a_sample")],
        ["MISMATCH", str(suite / "sample" / "more" / "c_tampered")]], out
    assert out[-1] == "2 bag(s): 1 ok, 1 mismatch, 0 error"


def test_a_bag_inside_a_bag_s_folder_is_checked_too(bag_suite, tmp_path, capsys):
    """``cp -r c_tampered suite/a_sample`` where ``suite/a_sample`` is a bag already puts
    the tampered bag inside it, where regress never looked: "1 bag(s): 1 ok", exit 0,
    whether given the suite or the bag. Both bags are checked."""
    suite = tmp_path / "suite"
    shutil.copytree(bag_suite / "a_sample", suite / "a_sample")
    shutil.copytree(bag_suite / "c_tampered", suite / "a_sample" / "c_tampered")
    for given in (suite, suite / "a_sample"):
        assert main(["regress", str(given), "--workers", "1", "--no-progress"]) == 1
        out = capsys.readouterr().out.splitlines()
        assert [line.split()[:2] for line in out[:-1]] == [
            ["OK", str(suite / "a_sample")],
            ["MISMATCH", str(suite / "a_sample" / "c_tampered")]], out
        assert out[-1] == "2 bag(s): 1 ok, 1 mismatch, 0 error"


def test_a_folder_that_cannot_be_listed_is_an_error_naming_it(bag_suite, tmp_path,
                                                             monkeypatch, capsys):
    """A subfolder regress cannot list (no read permission: root reads all, so its listing
    is made to fail) held bags that would go unchecked: one line naming it, exit 2."""
    suite = tmp_path / "suite"
    (suite / "locked").mkdir(parents=True)
    shutil.copytree(bag_suite / "a_sample", suite / "a_sample")
    listing = Path.iterdir

    def iterdir(self: Path):
        if self.name == "locked":
            raise PermissionError(13, "Permission denied", str(self))
        return listing(self)

    monkeypatch.setattr(Path, "iterdir", iterdir)
    assert main(["regress", str(suite), "--workers", "1", "--no-progress"]) == 2
    assert f"{suite / 'locked'}: cannot be listed (Permission denied)" in capsys.readouterr().err


def test_a_bag_given_twice_is_checked_once_saying_so(bag_suite, tmp_path, capsys):
    """The same bag named twice, as a folder holding it and by itself, or through a symlink,
    was checked and counted twice ("2 bag(s): 2 ok"): each bag is checked once, and a
    warning names the duplicate."""
    one = str(bag_suite / "a_sample")
    (tmp_path / "link").symlink_to(bag_suite / "a_sample")
    for argv, count in (([one, one], 1), ([one, str(bag_suite / ".." / "bags" / "a_sample")], 1),
                        ([one, str(tmp_path / "link")], 1), ([str(bag_suite), one], 4)):
        assert main(["regress", *argv, "--workers", "1", "--no-progress"]) in (0, 1)
        captured = capsys.readouterr()
        out = captured.out.splitlines()
        assert len(out) == count + 1 and out[-1].startswith(f"{count} bag(s): "), out
        assert captured.err.count("\n") == 1 and "given twice" in captured.err, captured.err
        assert "checked once" in captured.err


def test_a_bag_that_cannot_be_checked_is_named_once_on_its_line(bag_suite, tmp_path, capsys):
    """An ERROR line names its bag once: it repeated the path in the reason after it."""
    cut = tmp_path / "cut"
    shutil.copytree(bag_suite / "a_sample", cut)
    (cut / "metadata.yaml").unlink()
    assert main(["regress", str(cut), "--no-progress"]) == 2
    line = capsys.readouterr().out.splitlines()[0]
    assert line.startswith(f"ERROR    {cut}  no metadata.yaml "), line


def test_a_bag_named_with_a_line_break_keeps_to_its_one_line(bag_suite, tmp_path, capsys):
    """A bag whose name holds a line break: its line and the summary are two lines, the
    break written as an escape, as in an error (the line was split in two); so is the
    verdict of replay --check."""
    odd = tmp_path / "new\nline"
    shutil.copytree(bag_suite / "a_sample", odd)
    assert main(["regress", str(odd), "--no-progress"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and out[0].startswith(f"OK       {tmp_path}/new\\nline  match: "), out
    assert main(["replay", "sample", str(odd), "--check", "--no-progress"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith(
        f"check against the recording {tmp_path}/new\\nline: match: ")


def _dask_process(role: str, scheduler_file: Path, *, without_package: bool,
                  log: Path) -> subprocess.Popen[bytes]:
    """A ``dask scheduler`` or ``dask worker`` process on loopback; ``without_package``: one
    to which hecker_dynamics cannot be imported (a machine where it is not installed). The
    worker runs without a nanny, in this very process, where the import is blocked."""
    options = {"scheduler": ["--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                             "--scheduler-file", str(scheduler_file)],
               "worker": ["--scheduler-file", str(scheduler_file), "--nthreads", "1",
                          "--no-nanny", "--host", "127.0.0.1", "--no-dashboard"]}[role]
    code = ("import runpy, sys\n"
            + ("sys.modules['hecker_dynamics'] = None\n" if without_package else "")
            + f"sys.argv = ['dask-{role}', *{options!r}]\n"
            + f"runpy.run_module('distributed.cli.dask_{role}', run_name='__main__')\n")
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL,
                            stderr=log.open("wb"))


def _wait_for(scheduler_file: Path, workers: int) -> str:
    """The scheduler's address, once ``workers`` workers have joined (at most 120 s)."""
    import json
    import time

    deadline = time.monotonic() + 120
    # The scheduler creates the file before it writes it: wait for a whole document.
    while True:
        try:
            address = json.loads(scheduler_file.read_text())["address"]
            break
        except (FileNotFoundError, json.JSONDecodeError, KeyError):
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.2)
    if workers:
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(workers, timeout=120)
    return address


@pytest.mark.parametrize("without", ["worker", "scheduler"])
def test_a_cluster_that_cannot_import_the_package_is_one_line(tmp_path, capsys, without):
    """Workers (or a scheduler, which unpickles the tasks) without hecker_dynamics: one
    line naming what is missing where, before any variant is sent; nothing written."""
    scheduler_file = tmp_path / "scheduler.json"
    processes = [_dask_process("scheduler", scheduler_file, without_package=without ==
                               "scheduler", log=tmp_path / "scheduler.log")]
    try:
        if without == "worker":
            processes.append(_dask_process("worker", scheduler_file, without_package=True,
                                           log=tmp_path / "worker.log"))
        address = _wait_for(scheduler_file, 1 if without == "worker" else 0)
        output = tmp_path / "t.csv"
        code = main(["sweep", "sample", "--set", "bodies.left.mass=1,2", "--duration", "0.02",
                     "-o", str(output), "--cluster", address, "--no-progress"])
    finally:
        for process in processes:
            process.terminate()
            process.wait(timeout=60)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "warning: " not in line]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    where = "1 of 1 Dask worker(s)" if without == "worker" else "the Dask scheduler"
    assert lines[0].startswith(f"hecker-dynamics: error: {where}")
    assert "cannot import hecker_dynamics.batch.run (ModuleNotFoundError" in lines[0]
    assert not output.exists() and not list(tmp_path.glob("*.partial.csv"))
