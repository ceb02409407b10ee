"""Large piles settle: the benchmark's pyramids stand still after 2 s.

A pyramid whose velocity passes cannot converge in a step leans on its warm starts; a
friction impulse carried whole from step to step made piles of 40 rows and more sway as a
whole (0.08 m/s at 40 rows, 0.2 m/s at 50 after 2 s), and the pass budget of big islands
(:func:`~hecker_dynamics.contact.solve.passes`) decides how deep a pile settles.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from hecker_dynamics import Simulation
from hecker_dynamics.bench.pyramid import BOX, pyramid
from hecker_dynamics.contact import warm
from hecker_dynamics.dynamics import kernel

SECOND = 1_000_000_000
#: Issue 37's settling limits: no box turned more than 0.1 rad from upright, none of its
#: points moving faster than 1 cm/s.
MOST_TILT = 0.1
MOST_SPEED = 0.01


def _settled(rows: int) -> tuple[float, float]:
    """The largest tilt (rad) and point speed (m/s) of the pyramid's boxes after 2 s."""
    sim = Simulation(pyramid(rows))
    sim.advance_to(2 * SECOND)
    q, v = sim.q, sim.v
    quarter = math.pi / 2
    tilt = np.abs(q[:, 2] - np.round(q[:, 2] / quarter) * quarter)
    reach = BOX / math.sqrt(2.0)  # a box's corner from its CM
    speed = np.hypot(v[:, 0], v[:, 1]) + reach * np.abs(v[:, 2])
    return float(tilt.max()), float(speed.max())


@pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not built or "
                    "HECKER_DYNAMICS_KERNEL=0 (the Python path gives the same bits: "
                    "test_compiled.py; 40 rows take it minutes)")
def test_a_pyramid_of_40_rows_stands_still_after_2_s():
    tilt, speed = _settled(40)
    assert tilt <= MOST_TILT
    assert speed <= MOST_SPEED


def test_friction_is_warm_started_with_a_fraction_of_its_impulse():
    """The impulses a contact starts the next step from are the ones kept for it, the
    tangent one times FRICTION_CARRY, exactly."""
    class Kept(warm.WarmStarts):
        sleep = False
        island: list[int] = []
        _kernel = None

    kept = Kept()
    kept._warm = {(-1, 0, 0, 0): [(0.25, -0.25, 0.75, -0.3), (-0.25, -0.25, 0.5, 0.1)]}
    assert kept._recall((-1, 0, 0, 0), -0.25, -0.25, 0.0) == (0.5, 0.1 * warm.FRICTION_CARRY)
    assert kept._recall((-1, 0, 0, 0), 0.25, -0.25, 0.0) == (0.75, -0.3 * warm.FRICTION_CARRY)
    assert kept._recall((-1, 0, 0, 0), 0.25, -0.25, 0.0) == (0.0, 0.0)  # each used once
