"""The ball drop's closed form (bench/bounce.py) and its benchmark rows.

The closed form is checked against itself where its pieces must meet: the state is
continuous in height across each impact, reverses e of the speed there, peaks at the apex
height at the apex time, and rests from the Zeno time on."""
from __future__ import annotations

import math

import pytest

from hecker_dynamics.bench import bounce
from hecker_dynamics.bench.bounce import BallDrop
from hecker_dynamics.bench.measure import Budget

DROP = BallDrop(height=1.1, radius=0.1, gravity=9.81, restitution=0.8)


@pytest.mark.parametrize("k", [1, 2, 3, 6])
def test_the_state_meets_the_floor_at_each_impact_and_keeps_e_of_the_speed(k):
    t = DROP.impact_time(k)
    before_y, before_v = DROP.state(t - 1e-9)
    after_y, after_v = DROP.state(t)
    assert before_y == pytest.approx(DROP.radius, abs=1e-8)
    assert after_y == pytest.approx(DROP.radius, abs=1e-12)
    assert after_v == pytest.approx(-DROP.restitution * before_v, rel=1e-7)


@pytest.mark.parametrize("k", [0, 1, 4])
def test_the_apex_is_at_its_time_and_height(k):
    y, v = DROP.state(DROP.apex_time(k))
    assert y == pytest.approx(DROP.apex_height(k), abs=1e-12)
    assert v == pytest.approx(0.0, abs=1e-12)


def test_the_impacts_accumulate_at_the_zeno_time_and_the_ball_rests_after():
    assert DROP.impact_time(200) == pytest.approx(DROP.zeno_time, abs=1e-12)
    assert DROP.state(DROP.zeno_time + 1.0) == (DROP.radius, 0.0)
    assert math.isinf(BallDrop(1.1, 0.1, 9.81, 1.0).zeno_time)


def test_bench_rows_show_events_at_the_tolerance_and_the_contact_pass_at_order_h():
    """dopri5 at tol 1e-10 with events: impact times to 1e-8 s; without, the contact pass's
    bounce at a step's end is off by far more than 1e-3 s at h = 10 ms."""
    rows = bounce.bounce_bench([1e-10], [0.004], [], Budget(10.0, 1, 10.0, 5))
    by = {(r.engine, r.method, r.step): r for r in rows}
    located = by[(bounce.EVENTS, "dopri5", bounce.ADAPTIVE_STEP)]
    late = by[(bounce.CORE, "dopri5", bounce.ADAPTIVE_STEP)]
    assert located.impacts >= bounce.BOUNCES and located.impact_error <= 1e-8
    assert located.height_error <= 1e-8
    assert late.impact_error > 1e-3 and late.height_error > 1e-3
    assert all(r.status == "ok" and r.cost > 0.0 for r in rows)
    table = bounce.bounce_table(rows)
    assert len({line.count("|") for line in table if line.startswith("|")}) == 1
