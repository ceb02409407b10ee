"""Every command that writes (``sweep``, ``render``, ``plot``, ``bench``) checks its output
paths before any work, with one rule (:mod:`hecker_dynamics.files`): one line and exit 2
for a path that cannot or may not be written, with nothing written or changed; an
existing file replaced only with ``--overwrite``."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from hecker_dynamics.cli import main

GOLDEN = Path(__file__).resolve().parent / "golden"
SWEEP = ["sweep", "sample", "--set", "bodies.left.mass=1,2", "--duration", "0.02",
         "--workers", "1", "--no-progress"]


def _sweep(path: str) -> list[str]:
    return [*SWEEP, "-o", path]


def _sweep_bags(path: str) -> list[str]:
    return [*SWEEP, "-o", "table.csv", "--bags", path]


def _render(path: str) -> list[str]:
    return ["render", "sample", "--duration", "0.1", "--fps", "10", "--size", "64x48",
            "-o", path]


def _plot(path: str) -> list[str]:
    return ["plot", str(GOLDEN / "sample" / "output"), "-o", path]


def _bench(path: str) -> list[str]:
    return ["bench", "--joints", "--no-progress", "--out", path]


FILE_COMMANDS = {"sweep": (_sweep, ".csv"), "render": (_render, ".gif"),
                 "plot": (_plot, ".png")}


@pytest.fixture
def place(tmp_path, monkeypatch):
    """The current folder, with an existing file of each kind and a folder named as one."""
    for suffix in (".csv", ".gif", ".png"):
        (tmp_path / f"old{suffix}").write_text("old")
        (tmp_path / f"folder{suffix}").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _listing(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"<dir>"
            for p in sorted(folder.rglob("*"))}


def _refused(capsys, argv: list[str], *fragments: str) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("hecker-dynamics: error: "), err
    for fragment in fragments:
        assert fragment in err, err
    return err


def _bad_paths(suffix: str) -> list[tuple[str, str]]:
    """(path, what the error says) for every kind of path that must be refused."""
    return [("", "give a file name"), ("-", "-o -: cannot write to standard output"),
            (".", "names a folder"), ("folder/", "names a folder"),
            (f"folder{suffix}", "is a folder"), ("/dev/null", "not a regular file"),
            (f"/proc/x{suffix}", "cannot create a file in /proc"),
            (f"missing/x{suffix}", "does not exist"), (f"old{suffix}/x{suffix}", "not a folder"),
            (f"old{suffix}", "exists; give --overwrite"),
            ("x" * 300 + suffix, "too long")]


@pytest.mark.parametrize("command", sorted(FILE_COMMANDS))
def test_a_bad_output_path_is_one_line_and_changes_nothing(place, capsys, command):
    build, suffix = FILE_COMMANDS[command]
    before = _listing(place)
    for path, problem in _bad_paths(suffix):
        _refused(capsys, build(path), problem)
        assert _listing(place) == before, path


@pytest.mark.parametrize("command", sorted(FILE_COMMANDS))
def test_an_existing_file_is_replaced_only_with_overwrite(place, capsys, command):
    build, suffix = FILE_COMMANDS[command]
    _refused(capsys, build(f"old{suffix}"), "exists; give --overwrite")
    assert (place / f"old{suffix}").read_text() == "old"
    assert main(build(f"old{suffix}") + ["--overwrite"]) == 0
    written = (place / f"old{suffix}").read_bytes()
    assert written != b"old" and len(written) > 40
    assert not [p for p in place.iterdir() if p.name.startswith(".hd-")]  # no scratch left


def test_sweep_refuses_the_partial_rows_of_an_earlier_sweep(place, capsys):
    (place / "t.csv.partial.csv").write_text("variant\n0\n")
    _refused(capsys, _sweep("t.csv"), "t.csv.partial.csv (the rows of a sweep that stopped)")
    assert (place / "t.csv.partial.csv").read_text() == "variant\n0\n"
    assert not (place / "t.csv").exists()


def test_sweep_adds_the_suffix_before_it_checks(place, capsys, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # so -o t means t.csv
    (place / "t.csv").write_text("old")
    _refused(capsys, _sweep("t"), "-o t.csv: exists")
    (place / "t").mkdir()
    _refused(capsys, _sweep("t"), "-o t: is a folder")
    assert (place / "t.csv").read_text() == "old"


@pytest.mark.parametrize("path, problem", [
    ("old.csv", "is not a folder"), ("", "give a folder name"),
    ("-", "--bags -: cannot write to standard output; give a folder name"),
    ("/proc/bags", "cannot create a folder in /proc"),
    ("old.csv/bags", "is inside old.csv, which is not a folder"),
    ("table.csv", "is where -o writes the table")])
def test_sweep_bags_folder_is_checked_before_any_work(place, capsys, path, problem):
    before = _listing(place)
    _refused(capsys, _sweep_bags(path), problem)
    assert _listing(place) == before


@pytest.mark.parametrize("command", [["script", "sample"],
                                     ["replay", "sample", str(GOLDEN / "sample" / "input")]])
def test_a_bag_is_not_written_to_standard_output_nor_to_a_folder_named_dash(place, capsys,
                                                                          command):
    """-o -, the shell's standard output, made a bag folder named '-': refused as every
    command refuses it, nothing written."""
    before = _listing(place)
    _refused(capsys, [*command, "-o", "-"], "'-' does not name a new bag directory")
    assert _listing(place) == before


@pytest.mark.parametrize("command", [["script", "sample"],
                                     ["replay", "sample", str(GOLDEN / "sample" / "input")]])
@pytest.mark.parametrize("path, problem", [
    ("missing/out", "out: the folder missing does not exist"),
    ("old.csv/out", "out: old.csv is not a folder")])
def test_a_bag_in_a_folder_that_is_missing_or_a_file_is_refused_as_files_are(
        place, capsys, command, path, problem):
    """A bag's -o inside a file was refused as 'old.csv: no such directory', where every
    other command says the path is in no folder ('-o old.csv/x.gif: old.csv is not a
    folder'): the bag commands say so too, naming the bag."""
    before = _listing(place)
    _refused(capsys, [*command, "-o", path], problem)
    assert _listing(place) == before


def test_sweep_table_inside_a_bag_it_writes_is_refused(place, capsys):
    """-o inside a bag folder of --bags (left by an earlier sweep): the sweep wrote the
    table there, and the next sweep --overwrite, replacing the bag whole, deleted it (and
    its partial rows, had the bag come after them)."""
    assert main([*_sweep_bags("bags")]) == 0
    before = _listing(place)
    for table in ("bags/variant-000001/t.csv", "bags/../bags/variant-000000/t.csv"):
        _refused(capsys, [*SWEEP, "-o", table, "--bags", "bags", "--overwrite"],
                 f"-o {table}: is inside bags/variant-00000", "a bag --bags writes over")
    assert _listing(place) == before


def test_sweep_bags_are_replaced_only_with_overwrite(place, capsys):
    (place / "bags").mkdir()
    (place / "bags" / "variant-000001.yaml").write_text("old")
    _refused(capsys, _sweep_bags("bags"), "variant-000001.yaml exists; give --overwrite")
    assert (place / "bags" / "variant-000001.yaml").read_text() == "old"
    assert not (place / "table.csv").exists()


def test_parquet_without_pyarrow_fails_before_any_variant_runs(place, capsys, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # not importable
    _refused(capsys, _sweep("t.parquet"), "Parquet needs pyarrow")
    assert sorted(p.name for p in place.iterdir() if p.name.startswith("t.")) == []


@pytest.mark.parametrize("path, problem", [
    ("old.csv", "is not a folder"), ("/proc/bench", "cannot create a folder in /proc"),
    ("", "give a folder name")])
def test_bench_out_is_checked_before_any_work(place, capsys, path, problem):
    before = _listing(place)
    _refused(capsys, _bench(path), f"--out {path}" if path else "--out ''", problem)
    assert _listing(place) == before


def _fake_contact_bench(calls: list):
    """contact_bench's interface and files, without measuring anything."""
    from hecker_dynamics.bench.contacts import ContactResults

    def contact_bench(rows, peers, out, command, scenes=None, bar=None):
        calls.append(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "contacts.md").write_text("new report\n")
        return ContactResults(load=[(0.0, 0.0, 0.0)])
    return contact_bench


def test_bench_replaces_a_report_only_with_overwrite(place, capsys, monkeypatch):
    from hecker_dynamics.bench import contacts

    calls: list = []
    monkeypatch.setattr(contacts, "contact_bench", _fake_contact_bench(calls))
    monkeypatch.setattr(contacts, "targets", lambda results: [])
    (place / "report").mkdir()
    (place / "report" / "contacts.md").write_text("tracked report\n")
    argv = ["bench", "--contacts", "2", "--no-progress", "--out", "report"]
    _refused(capsys, argv, "contacts.md exists; give --overwrite")
    assert calls == [] and (place / "report" / "contacts.md").read_text() == "tracked report\n"
    assert main(argv + ["--overwrite"]) == 0
    assert (place / "report" / "contacts.md").read_text() == "new report\n"


def test_bench_writes_nowhere_in_the_current_folder_unless_told(place, capsys, monkeypatch,
                                                               tmp_path_factory):
    """A bench run in a clone: its tracked docs/bench stays as it is; the report goes to a
    new folder under the temporary folder, named on stdout."""
    import tempfile

    from hecker_dynamics.bench import contacts

    calls: list = []
    monkeypatch.setattr(contacts, "contact_bench", _fake_contact_bench(calls))
    monkeypatch.setattr(contacts, "targets", lambda results: [])
    scratch = tmp_path_factory.mktemp("system-tmp")
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    (place / "docs" / "bench").mkdir(parents=True)
    (place / "docs" / "bench" / "contacts.md").write_text("tracked report\n")
    before = _listing(place)
    assert main(["bench", "--contacts", "2", "--no-progress"]) == 0
    assert _listing(place) == before
    [out] = calls
    assert out.parent == scratch and (out / "contacts.md").read_text() == "new report\n"
    assert f"wrote {out}" in capsys.readouterr().out
    from hecker_dynamics.cli import parser
    assert parser().parse_args(["bench"]).out is None


def test_render_and_plot_check_the_path_before_they_draw(place, capsys, monkeypatch):
    from hecker_dynamics.viz import frames

    def no_run(*args, **kwargs):
        raise AssertionError("ran the scene before checking -o")
    monkeypatch.setattr(frames, "run_timeline", no_run)
    _refused(capsys, _render("folder.gif"), "is a folder")
    _refused(capsys, _render("old.gif"), "exists")
    assert os.path.exists("old.gif")


def test_a_sweep_on_a_full_disk_ends_in_one_line_with_whole_rows(place):
    """A file size limit (RLIMIT_FSIZE: writes past it fail, as on a full disk) cuts the
    partial rows in the middle of the second row: the sweep ends with one line, exit 2, and
    the partial file keeps the header and the first row, whole."""
    import resource
    import signal
    import subprocess
    import sys

    command = [sys.executable, "-m", "hecker_dynamics.cli", *SWEEP[:3], "bodies.left.mass=1:2:4",
               *SWEEP[4:]]
    subprocess.run([*command, "-o", "whole.csv"], check=True, capture_output=True)
    lines = (place / "whole.csv").read_text().splitlines(keepends=True)
    limit = len(lines[0]) + len(lines[1]) + len(lines[2]) // 2

    def full_disk() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past it fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = dict(os.environ, PYTHONPATH=str(GOLDEN.parent.parent))
    result = subprocess.run([*command, "-o", "t.csv"], preexec_fn=full_disk, env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert result.stderr == ("hecker-dynamics: error: cannot write the sweep's output: "
                             "[Errno 27] File too large\n")
    assert (place / "t.csv.partial.csv").read_text() == lines[0] + lines[1]
    assert not (place / "t.csv").exists()


def test_sweep_bags_on_a_full_disk_leave_no_cut_parameters_file(place):
    """A file size limit below a variant's parameters file: the sweep ends with one line,
    exit 2, and leaves no part of that file (``regress`` would read it as the scene)."""
    import resource
    import signal
    import subprocess
    import sys

    def full_disk() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))

    env = dict(os.environ, PYTHONPATH=str(GOLDEN.parent.parent))
    result = subprocess.run([sys.executable, "-m", "hecker_dynamics.cli",
                             *_sweep_bags("bags")], preexec_fn=full_disk, env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("hecker-dynamics: error: ")
    assert result.stderr.count("\n") == 1 and "File too large" in result.stderr
    assert list((place / "bags").iterdir()) == []


@pytest.mark.parametrize("command", [
    ["script", "sample"], ["replay", "sample", str(GOLDEN / "sample" / "input")]])
def test_a_bag_name_too_long_for_the_file_system_is_one_line(place, capsys, command):
    """``replay -o`` and ``script -o`` with a name longer than the file system takes
    printed a traceback of the OSError from the bag writer's first look at the path."""
    before = _listing(place)
    _refused(capsys, [*command, "-o", "x" * 300], "cannot create the bag (File name too long)")
    assert _listing(place) == before


GOLDEN_INPUT, GOLDEN_OUTPUT = str(GOLDEN / "sample" / "input"), str(GOLDEN / "sample" / "output")


@pytest.mark.parametrize("argv, argument", [
    (["run", ""], "scene"), (["run", "sample", "--map", ""], "--map"),
    (["script", "", "-o", "in"], "scene"), (["script", "sample", "-o", ""], "-o/--output"),
    (["replay", "sample", "", "-o", "out"], "INPUT_BAG"),
    (["replay", "sample", GOLDEN_INPUT, "-o", ""], "-o/--output"),
    (["compare", "", GOLDEN_OUTPUT], "EXPECTED_BAG"), (["compare", GOLDEN_OUTPUT, ""],
                                                       "ACTUAL_BAG"),
    (["regress", ""], "BAG_DIR"), (["regress", GOLDEN_OUTPUT, "--scene-dir", ""], "--scene-dir"),
    (["render", "sample", "--bag", "", "--size", "64x48"], "--bag"),
    (["plot", ""], "BAG"), (["plot", GOLDEN_OUTPUT, "--scene", ""], "--scene"),
    (["sweep", "", "--set", "integrator=rk4", "-o", "t.csv"], "scene"),
])
def test_an_empty_path_is_refused_naming_its_argument(place, capsys, argv, argument):
    """An empty path (an unset shell variable) read as the working folder: 'replay -o ""'
    said it would write over its input bag, 'compare ""' that '.' has no metadata.yaml,
    'regress ""' checked every bag under the working folder and 'render --bag ""' drew
    the scene's run instead of a bag. Each is now refused in one line before any work."""
    before = _listing(place)
    with pytest.raises(SystemExit) as refused:  # argparse's refusal, as of every argument
        main(argv)
    err = capsys.readouterr().err
    assert refused.value.code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"hecker-dynamics: error: {argv[0]}: argument {argument}: an empty "
                          "path names no file or folder"), err
    assert _listing(place) == before
