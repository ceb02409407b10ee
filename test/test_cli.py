"""The ``hecker-dynamics`` command line: summary values, errors, help.

The run summary is compared as text with the same formatting applied to a direct
Simulation run: the runs are bit-identical, so the formatted strings must be identical.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import weakref
from pathlib import Path

import pytest
from scene_builders import write_scene

from hecker_dynamics import Simulation, load_scene
from hecker_dynamics.cli import main, parser
from hecker_dynamics.scene.load import scene_path, scene_summary, shipped_scenes
from hecker_dynamics.stops import Terminated

ROOT = Path(__file__).resolve().parent.parent


def _direct(scene_name=None, duration_s=1.0, **changes):
    import dataclasses
    scene = dataclasses.replace(load_scene(scene_name), duration_ns=round(duration_s * 1e9),
                                **changes)
    sim = Simulation(scene)
    first = sim.snapshot()
    sim.play(scene.script, scene.duration_ns)
    return scene, sim, first, sim.snapshot()


def _body_line(body):
    return (f"{body.name:<12}{body.position[0]:>12.5f}{body.position[1]:>12.5f}"
            f"{body.angle:>12.5f}{body.linear_velocity[0]:>12.5f}"
            f"{body.linear_velocity[1]:>12.5f}{body.angular_velocity:>12.5f}")


def _check_summary(out, scene, sim, first, last):
    lines = out.splitlines()
    assert lines[0].split(None, 1) == ["scene", scene.source]
    assert lines[1].split()[:2] == ["integrator", sim.integrator.name]
    assert f"{last.steps} steps" in lines[2]
    assert f"{sim.integrator.counters.evaluations} force evaluations" in lines[2]
    assert lines[3].startswith(f"sim time    {(last.time_ns - first.time_ns) * 1e-9:g} s")
    assert lines[4] == f"energy      {first.energy:.6g} J -> {last.energy:.6g} J"
    assert lines[6:] == [_body_line(b) for b in last.bodies]


def test_run_default_scene_prints_summary_matching_a_direct_run(capsys):
    assert main(["run", "--duration", "1"]) == 0
    out = capsys.readouterr().out
    scene, sim, first, last = _direct(None, 1.0)
    assert last.steps == 1000
    _check_summary(out, scene, sim, first, last)


def test_run_with_overrides_matches_a_direct_run(capsys):
    sample = str(ROOT / "config" / "sample.yaml")
    assert main(["run", sample, "--duration", "0.5", "--integrator", "rk4",
                 "--step", "0.002"]) == 0
    out = capsys.readouterr().out
    scene, sim, first, last = _direct(sample, 0.5, integrator="rk4", step_ns=2_000_000)
    assert last.steps == 250 and sim.integrator.name == "rk4"
    _check_summary(out, scene, sim, first, last)


def test_run_drives_and_senses_the_robot_as_render_and_replay_do(capsys):
    """The robot's drive pushes it from x = 1 m into the crate (render's
    play_with_drives reaches the same states, to the printed digits), and its IMU and
    laser read at 50 and 10 Hz (an instant reads on leaving it: not the last one)."""
    import dataclasses

    from hecker_dynamics.drives.control import play_with_drives
    assert main(["run", "robot", "--duration", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    scene = dataclasses.replace(load_scene("robot"), duration_ns=2_000_000_000)
    sim = Simulation(scene)
    first = sim.snapshot()
    play_with_drives(sim, scene.script, scene.duration_ns)
    last = sim.snapshot()
    assert lines[4] == f"energy      {first.energy:.6g} J -> {last.energy:.6g} J"
    assert lines[5] == "sensors     robot/imu/imu 99, robot/laser/scan 19"
    assert lines[7:] == [_body_line(b) for b in last.bodies]
    assert next(b for b in last.bodies if b.name == "robot").position[0] > 1.5


def _assert_clean_error(capsys, code, *fragments):
    captured = capsys.readouterr()
    assert code == 2
    assert captured.err.startswith("hecker-dynamics: error: ")
    assert "Traceback" not in captured.err + captured.out
    for fragment in fragments:
        assert fragment in captured.err


def test_bad_scene_file_exits_2_naming_file_and_parameter(tmp_path, capsys):
    path = write_scene(tmp_path, {"bodies": {"a": {"shape": "box", "size": [1.0, 1.0],
                                                   "mass": 1.0, "color": "red"}}},
                       "bad.yaml")
    _assert_clean_error(capsys, main(["run", str(path)]), str(path), "bodies.a.color")


def test_unknown_scene_name_exits_2(capsys):
    _assert_clean_error(capsys, main(["run", "nonesuch"]), "nonesuch", "sample")


def test_missing_scene_file_exits_2(tmp_path, capsys):
    _assert_clean_error(capsys, main(["run", str(tmp_path / "gone.yaml")]), "gone.yaml")


def test_step_that_does_not_divide_the_publish_period_exits_2(capsys):
    _assert_clean_error(capsys, main(["run", "--step", "0.0007", "--duration", "0.1"]),
                        "--step 0.0007:")
    _assert_clean_error(capsys, main(["run", "--step", "1.0000001", "--duration", "0.1"]),
                        "--step 1.0000001:")
    # The robot's drive runs at 100 Hz, 10 ms, which steps of 4 ms do not divide: refused,
    # naming the rate (its control loop waited for an instant no step reaches, for ever).
    _assert_clean_error(capsys, main(["run", "robot", "--step", "0.004", "--duration", "0.1"]),
                        "--step 0.004:", "'drives.base.rate': 100 Hz is not a whole number of "
                                         "physics steps of 0.004 s")


@pytest.mark.parametrize("argv, fragment", [
    (["run", "--duration", "0.0005"], "--duration 0.0005 s is shorter than one step (0.001 s)"),
    (["run", "--duration", "0"], "--duration 0 s is shorter than one step (0.001 s)"),
    (["run", "--duration", "0.01", "--step", "0.02"],
     "--duration 0.01 s is shorter than one step (0.02 s)"),
    (["sweep", "sample", "--set", "bodies.left.mass=1,2", "--duration", "0.0005", "-o", "t.csv"],
     "sample.yaml (variant 0): --duration 0.0005 s is shorter than one step (0.001 s)"),
    (["sweep", "sample", "--set", "step=0.001,0.01", "--duration", "0.005", "-o", "t.csv"],
     "sample.yaml (variant 1): --duration 0.005 s is shorter than one step (0.01 s)"),
    (["replay", "sample", "in", "--check", "--duration", "0.0005"],
     "--duration 0.0005 s is shorter than one step (0.001 s)"),
    (["script", "sample", "-o", "in", "--duration", "0.0005"],
     "--duration 0.0005 s is shorter than one step (0.001 s)"),
    # Seconds that round to whole nanoseconds are quoted as given: 1e-10 read "0 s".
    (["run", "--duration", "1e-10"], "--duration 1e-10 s is shorter than one step (0.001 s)"),
    (["run", "--duration", "0.00000000149"], "--duration 0.00000000149 s is shorter than"),
    (["sweep", "sample", "--set", "bodies.left.mass=1,2", "--duration", "1e-10", "-o", "t.csv"],
     "sample.yaml (variant 0): --duration 1e-10 s is shorter than one step (0.001 s)"),
    (["replay", "sample", "in", "--check", "--duration", "1e-10"],
     "--duration 1e-10 s is shorter than one step (0.001 s)"),
    (["script", "sample", "-o", "in", "--duration", "1e-10"],
     "--duration 1e-10 s is shorter than one step (0.001 s)")])
def test_a_duration_shorter_than_one_step_is_refused(tmp_path, capsys, monkeypatch, argv,
                                                      fragment):
    """The clock takes the whole steps that fit in a duration (1.5 steps take one): a
    duration under one step took none, and run, sweep and replay exited 0 with the start
    reported as the end, and script wrote a session no replay could take a step of. Each
    now refuses it in one line, before any work."""
    monkeypatch.chdir(tmp_path)
    _assert_clean_error(capsys, main(argv), fragment, "no step would be taken")
    assert list(tmp_path.iterdir()) == []


def test_a_scene_shorter_than_one_step_is_refused_by_run_and_sweep(tmp_path, capsys):
    path = write_scene(tmp_path, {"duration": 0.0005, "bodies": {
        "a": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0}}}, "short.yaml")
    _assert_clean_error(capsys, main(["run", str(path)]),
                        f"{path}: duration 0.0005 s is shorter than one step (0.001 s)")
    _assert_clean_error(capsys, main(["sweep", str(path), "--set", "bodies.a.mass=1,2", "-o",
                                      str(tmp_path / "t.csv")]),
                        f"{path} (variant 0): duration 0.0005 s is shorter than one step")


def _configured(scene_name: str, step: str):
    from hecker_dynamics.cli import configure
    args = parser().parse_args(["run", scene_name, "--step", step])
    return configure(load_scene(scene_name), args)


def test_step_keeps_every_rate_of_the_scene():
    """--step makes the periods anew from the scene's rates, as the node's
    ``-p step:=`` does: the publish, sensor and drive periods stay what the rates say (they
    were kept as whole steps of the file's step, which the new step need not divide)."""
    robot = _configured("robot", "0.0005")
    assert robot.step_ns == 500_000
    assert robot.publish_period_ns == 20_000_000  # 50 Hz
    assert {s.name: s.period_ns for s in robot.sensors} == {"imu": 20_000_000,
                                                            "laser": 100_000_000}
    assert [d.period_ns for d in robot.drives] == [10_000_000]  # 100 Hz
    assert robot == load_scene_with_step("robot", "0.0005")
    # The chain's 10 Hz over its steps of 1/240 s (4166667 ns) is 24 steps, 100000008 ns;
    # over steps of 0.05 s it is 2 steps, 0.1 s, as the scene says: not refused.
    assert _configured("chain", "0.05").publish_period_ns == 100_000_000


def load_scene_with_step(scene_name: str, step: str):
    """The scene as the node reads it with ``-p step:=STEP``: the file with its step
    replaced."""
    from hecker_dynamics.scene.load import scene_from_parameters, scene_parameters
    from hecker_dynamics.scene.parameters import flatten
    source, params = scene_parameters(scene_name)
    return scene_from_parameters(dict(flatten(params), step=float(step)), source)


def test_diverging_scene_exits_2(tmp_path, capsys):
    """A spring of 1e15 N/m between two 1 kg bodies at h = 1 ms (omega h = 4.5e4, far
    past semi-implicit Euler's bound of 2) passes every check at load and blows up within
    tens of steps: one line naming the bodies, exit 2. (A force no double holds one step
    of, the case this test used before, is refused at load: test_bad_files.py.)"""
    path = write_scene(tmp_path, {
        "integrator": "semi_implicit_euler",
        "bodies": {"a": {"shape": "circle", "radius": 0.1, "mass": 1.0},
                   "b": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                         "position": [1.0, 0.0]}},
        "forces": {"s": {"type": "spring", "body_a": "a", "body_b": "b",
                         "stiffness": 1e15, "rest_length": 0.5}}}, "boom.yaml")
    _assert_clean_error(capsys, main(["run", str(path), "--duration", "0.1"]),
                        "state of a, b diverged", "kept the state at t = 0 s")


@pytest.mark.parametrize("option, value", [("--duration", "-1"), ("--duration", "nan"),
                                           ("--duration", "2e9"), ("--duration", "1e999999"),
                                           ("--step", "1e-10"), ("--step", "0"),
                                           ("--step", "fast"), ("--step", "1e999999")])
def test_bad_argument_exits_2_in_one_line(capsys, option, value):
    """argparse's refusal is one line, as every other error, naming the command, the
    option and where the help is: no usage block before it."""
    with pytest.raises(SystemExit) as caught:
        main(["run", option, value])
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hecker-dynamics: error: run: argument {option}: ")
    assert err.endswith("(see 'hecker-dynamics run --help')\n") and err.count("\n") == 1


@pytest.mark.parametrize("argv, start", [
    ([], "hecker-dynamics: error: the following arguments are required: COMMAND"),
    (["bogus"], "hecker-dynamics: error: argument COMMAND: invalid choice: 'bogus'"),
    (["run", "--nope"], "hecker-dynamics: error: run: unrecognized arguments: --nope"),
    (["compare", "a", "b", "c"], "hecker-dynamics: error: compare: unrecognized arguments: c"),
    (["compare", "a"], "hecker-dynamics: error: compare: the following arguments are required"),
    (["replay", "sample", "b", "--atol"], "hecker-dynamics: error: replay: argument --atol:")])
def test_argparse_refusals_are_one_line(capsys, argv, start):
    with pytest.raises(SystemExit) as caught:
        main(argv)
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(start) and err.count("\n") == 1, err


@pytest.mark.parametrize("command", [["compare", "a", "b"], ["replay", "sample", "b", "--check"]])
@pytest.mark.parametrize("option", ["--atol", "--atol-position", "--atol-angle",
                                    "--atol-velocity"])
@pytest.mark.parametrize("value", ["-1", "nan", "inf"])
def test_a_tolerance_that_compares_nothing_exits_2(capsys, command, option, value):
    """An infinite tolerance would let any finite difference "match"."""
    with pytest.raises(SystemExit) as caught:
        main([*command, option, value])
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: must be a finite non-negative number, not {value}" in err


@pytest.mark.parametrize("argv, dest, value", [
    (["render", "sample", "--view", "-3,0,3,5"], "view", "-3,0,3,5"),
    (["render", "sample", "--view", "-.5,-1,3,5"], "view", "-.5,-1,3,5"),
    (["sweep", "sample", "--set", "x=1", "--metric", "-2*left.x", "-o", "t.csv"], "metric",
     ["-2*left.x"])])
def test_a_value_that_starts_with_a_minus_and_a_digit_is_a_value(argv, dest, value):
    """docs/cli.md's ``--view X0,Y0,X1,Y1`` with a negative corner, as the default scene's
    walls need: Python before 3.13 took ``-3,0,3,5`` for an option and refused the view."""
    assert getattr(parser().parse_args(argv), dest) == value


def test_a_negative_tolerance_in_exponent_form_gets_its_own_refusal(capsys):
    with pytest.raises(SystemExit) as caught:
        main(["compare", "a", "b", "--atol", "-1e-9"])
    assert caught.value.code == 2
    assert ("argument --atol: must be a finite non-negative number, not -1e-9"
            in capsys.readouterr().err)


def _dropped_by_python(stop: BaseException) -> None:
    """Raise ``stop`` where Python drops it: in a weakref callback (matplotlib runs many
    while it draws), which Python reports as "Exception ignored in ..." and goes on."""

    class Referent:
        pass

    def callback(_: object) -> None:
        raise stop

    referent = Referent()
    reference = weakref.ref(referent, callback)
    del referent
    assert reference() is None


@pytest.mark.parametrize("stop, status, line", [
    (KeyboardInterrupt(), 130, "hecker-dynamics: interrupted\n"),
    (Terminated(), 143, "hecker-dynamics: terminated\n")])
@pytest.mark.parametrize("where", ["while it works", "at its end"])
def test_a_stop_python_drops_in_a_callback_still_stops_the_command(
        tmp_path, monkeypatch, capsys, stop, status, line, where):
    """docs/cli.md: Ctrl-C ends a command with one line and status 130 (SIGTERM: 143),
    what it was writing removed. A render stopped so used to go on and write its file."""
    import hecker_dynamics.cli as cli

    if where == "while it works":  # before the run: its first progress step stops it
        load = cli.load_scene
        monkeypatch.setattr(cli, "load_scene",
                            lambda *a, **k: (_dropped_by_python(stop), load(*a, **k))[1])
    else:  # after the last progress step: the command's end stops it
        summary = cli.scene_summary
        monkeypatch.setattr(cli, "scene_summary",
                            lambda name: (_dropped_by_python(stop), summary(name))[1])
    argv = ["run", "sample", "--duration", "0.1"] if where == "while it works" else ["scenes"]
    assert main(argv) == status
    captured = capsys.readouterr()
    assert captured.err == line
    assert where == "at its end" or captured.out == ""


def test_run_reads_seconds_exactly_as_the_bag_commands_do(capsys):
    """--step and --duration are decimal seconds made whole nanoseconds, as --start and
    --duration of `script` and `replay` are: 1.0000000015 s is exactly 1000000001.5 ns,
    rounded half to even to 1000000002 ns (read as a binary float first, it would be just
    below the half and give 1000000001 ns)."""
    args = parser().parse_args(["run", "--step", "0.0015", "--duration", "1.0000000015"])
    assert args.step == 1_500_000 and args.duration == 1_000_000_002


def _subcommands():
    actions = [a for a in parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return sorted(actions[0].choices)


@pytest.mark.parametrize("argv", [["--help"]] + [[name, "--help"] for name in _subcommands()])
def test_help_exits_0(argv, capsys):
    with pytest.raises(SystemExit) as caught:
        main(argv)
    assert caught.value.code == 0
    assert capsys.readouterr().out.startswith("usage: hecker-dynamics")


def test_run_and_scenes_subcommands_exist():
    assert {"run", "scenes"} <= set(_subcommands())


def test_scenes_lists_the_default_scene(capsys):
    assert main(["scenes"]) == 0
    assert "sample" in capsys.readouterr().out.split()


def test_scenes_gives_each_scene_its_files_first_line(capsys):
    """One line per shipped scene: its name, then the first line of its file's header."""
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = shipped_scenes()
    assert [line.split()[0] for line in lines] == names
    for name, line in zip(names, lines):
        first = scene_path(name).read_text().splitlines()[0]
        assert first.startswith("# ") and len(first) <= 100, f"{name}: {first!r}"
        summary = first[2:].strip()
        assert summary and line.split(None, 1)[1] == summary
    # The summaries start at one column, after the longest name.
    assert len({len(line) - len(line.split(None, 1)[1]) for line in lines}) == 1


def test_a_scene_file_without_a_header_has_no_summary(tmp_path):
    path = tmp_path / "bare.yaml"
    path.write_text("dynamics_node:\n  ros__parameters: {}\n")
    assert scene_summary(path) == ""
    path.write_text("# Two boxes.\n#\n# More.\ndynamics_node:\n  ros__parameters: {}\n")
    assert scene_summary(path) == "Two boxes."


def test_as_a_process_exit_codes_and_no_traceback(tmp_path):
    """The real entry point: exit 0 on success, 2 on a bad scene, no traceback."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    good = subprocess.run([sys.executable, "-m", "hecker_dynamics.cli", "run", "--duration",
                           "0.2"], capture_output=True, text=True, env=env, timeout=120)
    assert good.returncode == 0, good.stderr
    assert "left" in good.stdout and "200 steps" in good.stdout
    path = write_scene(tmp_path, {"step": "fast", "bodies": {}}, "bad.yaml")
    bad = subprocess.run([sys.executable, "-m", "hecker_dynamics.cli", "run", str(path)],
                         capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode == 2
    assert "Traceback" not in bad.stderr and "'step'" in bad.stderr and str(path) in bad.stderr


def test_a_reader_that_stops_reading_gets_no_traceback():
    """``hecker-dynamics run | head -1``: the pipe closes before the report is written; the
    run ends quietly with the shell's status for a broken pipe, 128 + SIGPIPE."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    process = subprocess.Popen([sys.executable, "-m", "hecker_dynamics.cli", "run",
                                "--duration", "0.2"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, env=env)
    assert process.stdout is not None and process.stderr is not None
    process.stdout.close()  # no reader left: the first line written breaks the pipe
    err = process.stderr.read().decode()
    assert process.wait(timeout=120) == 141
    assert err == ""


#: The console script as installed, with the signal ``sys.argv[1]`` sent to itself as it
#: first imports numpy (its command line's imports take most of a second; a signal in them
#: comes at some import): the same moment on every run.
_SIGNAL_IN_IMPORTS = """
import os, signal, sys
from importlib.metadata import entry_points

class SignalAtNumpy:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), int(sys.argv[1]))
        return None

script = entry_points(group="console_scripts", name="hecker-dynamics")
if not script:
    sys.exit(99)
signal.signal(signal.SIGINT, signal.default_int_handler)  # as a terminal starts it
sys.meta_path.insert(0, SignalAtNumpy())
sys.exit(next(iter(script)).load()(sys.argv[2:]))
"""


@pytest.mark.parametrize("signum, line", [(signal.SIGTERM, "hecker-dynamics: terminated"),
                                          (signal.SIGINT, "hecker-dynamics: interrupted")])
def test_a_signal_while_the_command_imports_ends_it_in_one_line(signum, line):
    """SIGTERM while the console script imported the command line (before ``main`` took
    it) ended the process without a word, killed by the signal; Ctrl-C then printed a
    traceback. Both now end it with a command's line and status, 128 + the signal."""
    process = subprocess.run(
        [sys.executable, "-c", _SIGNAL_IN_IMPORTS, str(int(signum)), "run", "--duration", "1"],
        capture_output=True, text=True, timeout=120)
    if process.returncode == 99:
        pytest.skip("the package is not installed (no hecker-dynamics console script)")
    assert (process.returncode, process.stderr, process.stdout) == (128 + signum, line + "\n",
                                                                   "")


def test_bag_commands_refuse_absurd_times_without_a_traceback(tmp_path, capsys):
    with pytest.raises(SystemExit) as caught:
        main(["script", "sample", "-o", str(tmp_path / "in"), "--start", "1e999999"])
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert "argument --start:" in err and "Traceback" not in err


def test_ctrl_c_mid_write_ends_in_one_line_and_leaves_no_bag(tmp_path, capsys, monkeypatch):
    """Ctrl-C while ``replay`` writes its bag: no traceback but one line, the shell's
    status for SIGINT (128 + 2), and neither the bag nor its scratch directory left."""
    from hecker_dynamics.bags.io import BagWriter

    assert main(["script", "sample", "-o", str(tmp_path / "in")]) == 0
    written = BagWriter.write_raw

    def interrupted(self, topic, log_ns, raw):
        if self.count == 100:
            raise KeyboardInterrupt
        written(self, topic, log_ns, raw)

    monkeypatch.setattr(BagWriter, "write_raw", interrupted)
    capsys.readouterr()
    code = main(["replay", "sample", str(tmp_path / "in"), "-o", str(tmp_path / "out")])
    assert code == 130
    assert capsys.readouterr().err == "hecker-dynamics: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]
