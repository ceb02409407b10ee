"""Sweep variants, metrics and the summary row: parsing, seeding, checking, physics."""
from __future__ import annotations

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scene_builders import write_scene

import hecker_dynamics
from hecker_dynamics.batch.metrics import MAX_DEPTH, parse_metric, summarize
from hecker_dynamics.batch.run import check_metrics
from hecker_dynamics.batch.variants import MAX_VARIANTS, grid, make_variants, parse_setting, sample
from hecker_dynamics.cli import main
from hecker_dynamics.scene import SceneError


def test_grid_is_every_combination_last_fastest():
    settings = [parse_setting("bodies.left.mass=1,2"),
                parse_setting("bodies.left.position[0]=-1:1:3")]
    assert settings[1].values == (-1.0, 0.0, 1.0)
    assert grid(settings) == [(1, -1.0), (1, 0.0), (1, 1.0), (2, -1.0), (2, 0.0), (2, 1.0)]
    variants = make_variants("sample", settings, duration_ns=10**8)
    # Each variant's scene holds its values; the rest of the scene is the file's.
    assert [(v.scene.bodies[0].mass.mass, v.scene.bodies[0].position[0]) for v in variants] == \
        [(1.0, -1.0), (1.0, 0.0), (1.0, 1.0), (2.0, -1.0), (2.0, 0.0), (2.0, 1.0)]
    assert {v.scene.bodies[0].position[1] for v in variants} == {2.5}
    assert {v.scene.duration_ns for v in variants} == {10**8}


def test_sampling_is_the_seeded_generator():
    settings = [parse_setting("a.b=0.5:2"), parse_setting("c=x,y,z")]
    draws = sample(settings, 20, seed=7)
    assert draws == sample(settings, 20, seed=7)
    assert draws != sample(settings, 20, seed=8)
    generator = np.random.default_rng(7)  # the documented order: variant by variant
    expected = []
    for _ in range(20):
        expected.append((float(generator.uniform(0.5, 2)),
                         ("x", "y", "z")[int(generator.integers(3))]))
    assert draws == expected
    assert all(0.5 <= a < 2 for a, _ in draws)


@pytest.mark.parametrize("text, problem", [
    ("bodies.left.mass", "expected NAME=VALUES"),
    ("bodies.left.mass=1,,2", "empty value"),
    ("bodies.left.mass=1:x:3", "is not a number"),
    ("bodies.left.mass=1:2:0", "not a positive whole number"),
    ("bodies.left.mass=1:2:3:4", "start:stop:count or start:stop"),
    # linspace's one value is the start: the stop, "both included", was silently dropped.
    ("bodies.left.mass=1:2:1", "one value cannot include both ends; give a count of 2"),
    ("bodies.left.mass=nan", "not a finite number"),
    # A whole array, cut at its commas into "[1" and "2]": YAML's parser error was a
    # traceback.
    ("bodies.left.position=[1,2]", r"'\[1' is not a finite number, a boolean or a name "
                                   r"\(set one element of an array: NAME\[i\]=VALUES\)"),
    ("bodies.left.name={a", "'{a' is not a finite number, a boolean or a name$"),
])
def test_malformed_settings_are_refused(text, problem):
    with pytest.raises(SceneError, match=problem):
        parse_setting(text)


def test_a_range_of_one_value_is_its_start_equal_to_its_stop():
    assert parse_setting("bodies.left.mass=1.5:1.5:1").values == (1.5,)


@pytest.mark.parametrize("setting, problem", [
    ("bodies.lefft.mass=1,2", "no parameter 'bodies.lefft.mass' (and no group 'bodies.lefft')"),
    ("bodies.left.masss=1", "'bodies.left.masss': is not a known parameter here"),
    ("bodies.left.mass=0", "'bodies.left.mass': must be positive"),
    ("bodies.left.size[2]=1", "'bodies.left.size' has 2 element(s)"),
    ("bodies.left.mass[0]=1", "'bodies.left.mass' is not an array"),
    ("bodies.left.mass=1:2", "needs --samples"),
])
def test_bad_sweep_fails_before_any_work_with_one_line(tmp_path, capsys, setting, problem):
    output = tmp_path / "results.csv"
    code = main(["sweep", "sample", "--set", "bodies.right.mass=1", "--set", setting,
                 "-o", str(output), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("hecker-dynamics: error: ") and problem in err
    assert list(tmp_path.iterdir()) == []  # no table, no partial rows: nothing ran


def test_metric_evaluator_computes_and_refuses():
    row = {"left.x": 1.5, "right.x": 4.0, "left.vy": -2.0, "energy": 10.0, "none": None}
    assert parse_metric("gap=right.x - left.x").evaluate(row) == 2.5
    assert parse_metric("hypot(3, 4) + abs(left.vy) ** 2").evaluate(row) == 9.0
    assert parse_metric("energy > 5 and left.x < 2").evaluate(row) == 1.0
    assert parse_metric("left.x if left.vy > 0 else -left.x").evaluate(row) == -1.5
    metric = parse_metric("right.x / (left.x - 1.5)")
    assert metric.name == "right.x / (left.x - 1.5)" and metric.evaluate(row) is None
    assert parse_metric("log(left.vy)").evaluate(row) is None  # a domain error
    assert parse_metric("none + 1").evaluate(row) is None
    assert parse_metric("10 ** 10 ** 10").evaluate(row) is None  # overflows, in floats
    for text in ("__import__('os')", "left.x.__class__()", "open('f')", "[1][0]", "'a'",
                 "(lambda: 1)()", "hypot(*left)"):
        with pytest.raises(SceneError, match="not allowed|not an expression"):
            parse_metric(text)


def test_metric_names_are_checked_against_the_columns():
    variants = make_variants("sample", [parse_setting("bodies.left.mass=1")])
    check_metrics([parse_metric("d=right.speed_max - left.x + energy + bodies.left.mass")],
                  variants)
    with pytest.raises(SceneError, match="unknown name.* lft.x"):
        check_metrics([parse_metric("d=lft.x")], variants)
    with pytest.raises(SceneError, match="unknown name.* abs"):  # a function, not called
        check_metrics([parse_metric("d=abs + 1")], variants)
    with pytest.raises(SceneError, match="already a column"):
        check_metrics([parse_metric("energy=1")], variants)


def test_metric_evaluation_stays_real_and_bounded():
    """``**`` is math.pow: a negative number to a fractional power is undefined (an empty
    cell), not the complex number Python's ** makes, which no column can hold."""
    row = {"left.x": -8.0}
    assert parse_metric("x=(-8)**(1/3)").evaluate(row) is None
    assert parse_metric("x=left.x ** (1/3)").evaluate(row) is None
    assert parse_metric("x=left.x ** 2").evaluate(row) == 64.0
    assert parse_metric("x=(-8) ** 3").evaluate(row) == -512.0
    assert parse_metric("x=0 ** -1").evaluate(row) is None
    # Chains as deep as the bound allows evaluate exactly (the tree's levels: the
    # expression, the operations, the number).
    assert parse_metric("x=" + "+".join(["1"] * (MAX_DEPTH - 1))).evaluate(row) == \
        MAX_DEPTH - 1
    assert parse_metric("x=" + "-" * (MAX_DEPTH - 2) + "1").evaluate(row) == 1.0


@pytest.mark.parametrize("text, problem", [
    ("x=" + "+".join(["1"] * 2000), "longer than 1000 characters"),
    ("x=" + "+".join(["1"] * 400), "nested deeper than"),
    ("x=" + "-" * 900 + "1", "nested deeper than"),
    ("x=" + "(" * 250 + "1" + ")" * 250, "too many nested parentheses"),
    ("x=min(left.x)", r"min\(\) takes 2 or more argument\(s\), not 1"),
    ("x=max()", r"max\(\) takes 2 or more"),
    ("x=atan2(1)", r"atan2\(\) takes 2 argument"),
    ("x=sqrt(1, 2)", r"sqrt\(\) takes 1 argument"),
    ("x=log(1, 2, 3)", r"log\(\) takes 1 to 2 argument"),
    ("x=hypot()", r"hypot\(\) takes 1 or more"),
])
def test_metric_size_and_calls_are_checked_before_any_work(text, problem):
    with pytest.raises(SceneError, match=problem) as caught:
        parse_metric(text)
    assert "\n" not in str(caught.value)


def test_a_metric_cannot_take_a_columns_name_or_anothers():
    """A metric named ``status`` would hide a divergence; two of one name would lose one."""
    variants = make_variants("sample", [parse_setting("bodies.left.mass=1")])
    for name in ("status", "message", "variant", "left.x", "bodies.left.mass", "energy"):
        metric = parse_metric(f"{name}=0" if name.isidentifier() else name)
        with pytest.raises(SceneError, match="already a column"):
            check_metrics([metric], variants)
    with pytest.raises(SceneError, match="'a' is the name of --metric a=1 too"):
        check_metrics([parse_metric("a=1"), parse_metric("a=2")], variants)
    with pytest.raises(SceneError, match="is the name of --metric left.x-right.x too"):
        check_metrics([parse_metric("left.x-right.x"), parse_metric("left.x-right.x")],
                      variants)


def test_a_parameter_is_set_once():
    with pytest.raises(SceneError, match="'bodies.left.mass' is set by --set "
                                         "bodies.left.mass=1,2 too"):
        make_variants("sample", [parse_setting("bodies.left.mass=1,2"),
                                 parse_setting("bodies.left.mass=3")])
    with pytest.raises(SceneError, match="set by --set"):
        make_variants("sample", [parse_setting("bodies.left.mass=1:2"),
                                 parse_setting("bodies.left.mass=1,2")], samples=2)
    # One element of an array and another are two parameters.
    variants = make_variants("sample", [parse_setting("bodies.left.position[0]=1"),
                                        parse_setting("bodies.left.position[1]=2")])
    assert variants[0].values == (("bodies.left.position[0]", 1), ("bodies.left.position[1]", 2))


def test_grids_and_samples_are_bounded_before_any_variant_is_made():
    settings = [parse_setting(f"bodies.left.mass=1:2:{MAX_VARIANTS}"),
                parse_setting("bodies.right.mass=1,2")]
    with pytest.raises(SceneError, match=f"{MAX_VARIANTS} x 2 values is 2e\\+05 variants"):
        grid(settings)
    huge = [parse_setting(f"bodies.{b}.mass=1:2:1000") for b in ("left", "right")] + \
        [parse_setting("bodies.left.angle=0:1:1000")]
    with pytest.raises(SceneError, match="1e\\+09 variants"):
        grid(huge)
    with pytest.raises(SceneError, match="count 1000000000000 is over"):
        parse_setting("bodies.left.mass=1:2:1000000000000")
    interval = [parse_setting("bodies.left.mass=1:2")]
    with pytest.raises(SceneError, match="--samples"):
        sample(interval, MAX_VARIANTS + 1, 0)
    with pytest.raises(SceneError, match="--seed -1"):
        sample(interval, 2, -1)
    assert len(grid([parse_setting(f"bodies.left.mass=1:2:{MAX_VARIANTS}")])) == MAX_VARIANTS


@pytest.mark.parametrize("option, value", [
    ("--samples", "0"), ("--samples", str(MAX_VARIANTS + 1)), ("--samples", "1e7"),
    ("--seed", "-1"), ("--seed", str(2 ** 64)), ("--seed", "1.5"), ("--seed", "9" * 5000),
    ("--workers", "0"), ("--workers", "100000")])
def test_sweep_numbers_out_of_range_exit_2_with_usage(tmp_path, capsys, option, value):
    argv = ["sweep", "sample", "--set", "bodies.left.mass=1:2", "-o", str(tmp_path / "t.csv"),
            option, value]
    if option == "--seed":
        argv += ["--samples", "2"]
    with pytest.raises(SystemExit) as caught:
        main(argv)
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}:" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_summary_of_free_flight_is_exact(tmp_path):
    """No force: the velocities never change (F = m a, Eq. 5, with no force, and no angular
    acceleration, Eq. 14, without torque), so the kinetic energy 1/2 m v^2 + 1/2 I omega^2
    (a disc's moment of inertia I = m r^2 / 2, Eq. 13) is the same double at every instant,
    the speed is constant and x grows monotonically, so its extrema are its start and end."""
    path = write_scene(tmp_path, {"step": 0.01, "publish_rate": 10.0, "duration": 1.0,
                                  "integrator": "semi_implicit_euler",
                                  "bodies": {"puck": {"shape": "circle", "radius": 0.5,
                                                      "mass": 2.0, "velocity": [3.0, 4.0]}}})
    variant, = make_variants(str(path), [parse_setting("bodies.puck.angular_velocity=0.5")])
    row = summarize(variant.scene)
    assert row["status"] == "ok" and row["message"] == ""
    assert row["steps"] == 100 and row["time"] == 1.0
    assert row["energy_start"] == row["energy_end"] == row["energy_max"] == 25.0 + 0.03125
    assert row["puck.speed"] == row["puck.speed_max"] == 5.0
    assert row["puck.x_min"] == 0.0 and row["puck.x_max"] == row["puck.x"]
    assert row["puck.x"] == pytest.approx(3.0, abs=1e-12)
    assert row["puck.omega"] == 0.5
    assert row["contacts_end"] is None and row["contacts_max"] is None


def test_summary_reports_a_divergence_and_keeps_the_last_finite_state(tmp_path):
    path = write_scene(tmp_path, {
        "step": 0.001, "duration": 0.2, "integrator": "explicit_euler",
        "bodies": {"tiny": {"shape": "circle", "radius": 0.1, "mass": 1e-3,
                            "position": [1.0, 0.0]}},
        "forces": {"pin": {"type": "spring", "body_a": "tiny", "anchor": [0.0, 0.0],
                           "stiffness": 1e4}}})
    variant, = make_variants(str(path), [parse_setting("bodies.tiny.mass=1e-3")])
    row = summarize(variant.scene)  # h sqrt(k / m) = 3.2: explicit Euler's spiral outward
    assert row["status"] == "diverged" and "tiny diverged" in row["message"]
    assert row["time"] < 0.2 and all(math.isfinite(row[f"tiny.{f}"]) for f in ("x", "y", "vx"))


def test_summary_reports_a_refused_scripted_input(tmp_path):
    """1e308 N on 1 g: refused as it is pushed, so the row must not read ``ok``."""
    path = write_scene(tmp_path, {
        "step": 0.001, "duration": 0.2, "integrator": "semi_implicit_euler",
        "bodies": {"tiny": {"shape": "circle", "radius": 0.1, "mass": 1e-3}},
        "script": {"boom": {"time": 0.05, "body": "tiny", "frame_id": "world",
                            "force": [1e308, 1e308], "duration": 0.1}}})
    variant, = make_variants(str(path), [parse_setting("bodies.tiny.mass=1e-3")])
    row = summarize(variant.scene)
    assert row["status"] == "rejected"
    assert row["message"].startswith("scripted input rejected: wrench for body 'tiny' from "
                                     "'boom' would give it an energy of motion past")
    assert row["time"] == 0.2 and row["tiny.x"] == row["tiny.vx"] == 0.0


def test_summary_counts_contacts_of_a_resting_box(tmp_path):
    """A box resting on a floor touches it at its two bottom corners."""
    path = write_scene(tmp_path, {
        "step": 0.001, "duration": 0.5, "integrator": "semi_implicit_euler",
        "bodies": {"box": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                           "position": [0.0, 0.5]}},
        "forces": {"g": {"type": "gravity"}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}}})
    variant, = make_variants(str(path), [parse_setting("bodies.box.mass=1")])
    row = summarize(variant.scene)
    assert row["contacts_end"] == row["contacts_max"] == 2
    assert row["box.y_min"] == pytest.approx(0.5, abs=1e-3)


def test_the_core_the_node_and_the_cli_do_not_import_an_engine():
    """Dask is the optional cluster extra: importing the package, the command line, the
    run loop or the batch code must not pull it in; node.py imports no batch module."""
    code = ("import sys, hecker_dynamics, hecker_dynamics.cli, hecker_dynamics.ros.runner, "
            "hecker_dynamics.batch.run, hecker_dynamics.batch.engines; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed', 'ray')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
    node = Path(hecker_dynamics.__file__).parent / "ros" / "node.py"
    imported = {alias.name if isinstance(n, ast.Import) else n.module or ""
                for n in ast.walk(ast.parse(node.read_text()))
                if isinstance(n, (ast.Import, ast.ImportFrom)) for alias in n.names}
    assert "rclpy" in imported  # the node's imports were read
    assert not any("batch" in name or "dask" in name for name in imported)
