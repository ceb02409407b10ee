"""The bench's whole-run measurement (never a speed): the runs are interleaved in
alternating order, the cost is the median of the runs' costs with their spread, a ratio's
noise is the spread of the rounds' ratios, and an engine that times itself is taken at
its word."""
from __future__ import annotations

import pytest

from hecker_dynamics.bench.measure import interleaved_runs, ratio_noise, timed_steps, whole_cost


def test_runs_alternate_direction_round_by_round():
    order: list[str] = []

    def run(name: str):
        def once() -> int:
            order.append(name)
            return len(order)
        return once

    results = interleaved_runs({name: run(name) for name in "abc"}, 3)
    assert "".join(order) == "abccbaabc"
    assert results == {"a": [1, 6, 7], "b": [2, 5, 8], "c": [3, 4, 9]}


def test_whole_cost_is_the_median_run_with_its_spread():
    cost = whole_cost([3.0, 1.0, 2.0, 10.0, 2.0])
    assert cost.per_step == 2.0 and cost.spread == pytest.approx((10.0 - 1.0) / 2.0)
    assert cost.repeats == [3.0, 1.0, 2.0, 10.0, 2.0]


def test_ratio_noise_is_the_spread_of_the_rounds_ratios():
    # Ratios 0.5, 0.4, 0.6: median 0.5, spread 0.2 / 0.5.
    assert ratio_noise([1.0, 2.0, 3.0], [2.0, 5.0, 5.0]) == pytest.approx(0.4)
    assert ratio_noise([1.0, 1.0], [2.0, 2.0]) == 0.0


def test_an_engine_that_times_itself_is_taken_at_its_word():
    assert timed_steps(lambda count: 0.25 * count, 4) == 1.0
    assert 0.0 <= timed_steps(lambda count: None, 4) < 1.0
