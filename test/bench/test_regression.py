"""The regression guard of ``bench --quick`` on synthetic runs (no timing): a ratio that
moved beyond its noise is flagged, one within it passes, and the ratios come from the
rounds of the rows measured side by side."""
from __future__ import annotations

import math

import pytest

from hecker_dynamics.bench.measure import Row
from hecker_dynamics.bench.regression import (
    FLOOR,
    Ratio,
    compare,
    quick_ratios,
    read_reference,
    verdict_lines,
    write_reference,
)
from hecker_dynamics.bench.run import Results


def test_a_ratio_beyond_its_noise_moved_one_within_it_held():
    reference = {"a": Ratio(0.50, 0.20), "b": Ratio(0.50, 0.20), "c": Ratio(1.0, 0.0),
                 "d": Ratio(1.0, 0.0), "gone": Ratio(2.0, 0.0)}
    now = {"a": Ratio(0.72, 0.10),    # +44 %, beyond the noise of both, 30 %
           "b": Ratio(0.62, 0.10),    # +24 %, within it
           "c": Ratio(0.80, 0.0),     # -20 %, beyond the floor of 15 %
           "d": Ratio(1.10, 0.0),     # +10 %, within the floor
           "new": Ratio(0.3, 0.0)}
    verdicts = {v.name: v for v in compare(now, reference)}
    assert {name: v.status for name, v in verdicts.items()} == {
        "a": "moved", "b": "held", "c": "moved", "d": "held", "gone": "gone", "new": "new"}
    assert verdicts["a"].change == pytest.approx(0.44)
    assert verdicts["a"].allowed == pytest.approx(0.30) and verdicts["c"].allowed == FLOOR
    lines = verdict_lines(list(verdicts.values()))
    assert "moved: a: 0.5 -> 0.72 (+44%, noise allowed 30%)" in lines
    assert "moved: c: 1 -> 0.8 (-20%, noise allowed 15%)" in lines
    assert "new (not in the reference): new: 0.3" in lines
    assert "not measured (in the reference): gone: 2" in lines
    assert lines[-1] == "held within their noise: 2 of 4 ratios"


def test_a_drop_moves_as_far_as_the_rise_it_undoes():
    """Moves are judged on the log of the ratio: halving and doubling are alike."""
    reference = {"x": Ratio(1.0, 0.0)}
    for value in (1.0 / 1.2, 1.2):
        assert compare({"x": Ratio(value, 0.0)}, reference, floor=0.19)[0].status == "moved"
        assert compare({"x": Ratio(value, 0.0)}, reference, floor=0.21)[0].status == "held"


def _row(scene, engine, method, step, walls, duration=1.0, **fields):
    row = Row(scene, engine, method, step, math.nan, duration, **fields)
    row.walls = list(walls)
    row.cost = sorted(walls)[len(walls) // 2] / duration
    return row


def test_the_ratios_come_from_rounds_side_by_side(tmp_path):
    """Ring: ours costs 1.0, 1.2, 1.1 s in the rounds where the C loop costs 1.0, 1.0, 1.0
    (its runs twice as long): ratio 2 x 1.1 / 1.0, spread (2.4 - 2.0) / 2.2. Equal steps
    of RK4 against MuJoCo's, and the headline at 1e-3 m, the same way; the file keeps
    them exactly."""
    results = Results("quick")
    results.ring = [_row("ring10", "hecker_dynamics", "semi_implicit_euler", 1e-3,
                         [1.0, 1.2, 1.1], omega_dt=10.0),
                    _row("ring10", "c", "semi_implicit_euler", 1e-3, [1.0, 1.0, 1.0],
                         duration=2.0, omega_dt=10.0)]
    results.rows = [_row("harmonic", "hecker_dynamics", "rk4", 0.01, [3.0, 3.0],
                         position_error=1e-4),
                    _row("harmonic", "mujoco", "rk4", 0.01, [4.0, 6.0], position_error=1e-4)]
    ratios = quick_ratios(results)
    assert ratios["ring N=10 / c"].value == pytest.approx(2.2)
    assert ratios["ring N=10 / c"].noise == pytest.approx(0.4 / 2.2)
    assert ratios["harmonic rk4 h=0.01 / mujoco rk4"].value == pytest.approx(0.5)
    assert ratios["harmonic rk4 h=0.01 / mujoco rk4"].noise == pytest.approx(0.25 / 0.625)
    assert ratios["harmonic error <= 0.001 / mujoco"] == \
        ratios["harmonic rk4 h=0.01 / mujoco rk4"]
    assert "harmonic error <= 1e-06 / mujoco" not in ratios  # neither reaches it
    results.ring_pairs = {10: [1.3, 1.1, 1.2, 1.6]}  # the target's figure, where made
    paired = quick_ratios(results)["ring N=10 / c"]
    assert (paired.value, paired.noise) == (pytest.approx(1.25), pytest.approx(0.5 / 1.25))
    path = tmp_path / "reference.json"
    write_reference(path, ratios, {"command": "test"})
    assert read_reference(path) == ratios


def test_the_reference_is_a_quick_runs(capsys):
    from hecker_dynamics.cli import main

    assert main(["bench", "--full", "--save-reference", "--out", "/nonexistent"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hecker-dynamics: error: --save-reference:") and err.count("\n") == 1
