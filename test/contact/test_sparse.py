"""The joint rows' factorizations (contact/sparse.py) on Box2D's joint grid, whose loops
make about a quarter of its rows dependent: references are a dense elimination in the
same order (every entry's updates in ascending k, structural zeros included), the rows
the grid's coordinates leave independent, and the fill of nested dissection."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hecker_dynamics.bench.joints import grid
from hecker_dynamics.contact.joint_solve import directions, matrix
from hecker_dynamics.contact.joints import JointPass
from hecker_dynamics.contact.sparse import Pattern, factor, lu
from hecker_dynamics.dynamics import Simulation


def _grid_pass(size: int) -> tuple[JointPass, list[float]]:
    sim = Simulation(grid(size, 1.0 / 60.0, 1.0))
    joints = sim.model.joints
    assert joints is not None
    joints.reset(sim.q)
    return joints, sim.q[joints.bodies].reshape(-1).tolist()


def _dense(pattern: Pattern, values: list[float]) -> np.ndarray:
    """The strict lower triangle given by the pattern's slots, dense."""
    out = np.zeros((pattern.size, pattern.size))
    for i in range(pattern.size):
        for slot in range(pattern.start[i], pattern.start[i + 1]):
            out[i, pattern.columns[slot]] = values[slot]
    return out


def test_dropped_rows_change_no_entry_of_the_factors():
    """L D L^T and L U of an 8 x 8 grid's rows, which skip the updates through dropped rows
    (their columns are zero), equal a dense elimination that takes every k < j in
    ascending order, zeros included, dropping rows by the same bound: entry for entry."""
    joints, q = _grid_pass(8)
    pattern = joints.pattern
    assert pattern is not None
    rows = joints.rows(q, 1.0 / 60.0)
    direction = directions(rows, joints.inverse_mass)
    diagonal, lower = matrix(pattern, rows, direction)
    low, diag, out = factor(pattern, diagonal, lower)
    n, bounds = pattern.size, pattern.bounds
    k_full = _dense(pattern, lower)
    ref_l, ref_d = np.zeros((n, n)), np.zeros(n)
    dropped = [False] * n
    for i in range(n):
        for j in range(i):
            if dropped[j]:
                continue
            s = k_full[i, j]
            for k in range(j):
                s -= ref_l[i, k] * ref_d[k] * ref_l[j, k]
            ref_l[i, j] = s / ref_d[j]
        s = diagonal[i]
        for k in range(i):
            s -= ref_l[i, k] * ref_d[k] * ref_l[i, k]
        if s > bounds[i] * diagonal[i]:
            ref_d[i] = s
        else:
            dropped[i] = True
    assert out == dropped and sum(out) >= n // 6  # the loops: 40 of 210 rows
    assert np.array_equal(_dense(pattern, low), ref_l) and diag == ref_d.tolist()
    # L U of the same (symmetric) matrix: U = D L^T, so its pivots are D's.
    upper = list(lower)
    low_u, inverse, dropped_u = lu(pattern, diagonal, lower, upper)
    assert dropped_u == out
    kept = [i for i in range(n) if not out[i]]
    assert np.allclose([1.0 / inverse[i] for i in kept], [diag[i] for i in kept], rtol=1e-9)


@pytest.mark.parametrize("size", [10, 20, 30])
def test_a_grid_of_pins_fills_in_n_log_n(size):
    """Nested dissection on a size x size grid of pins: the factors' non-zeros stay within
    5 n log2 n of its n rows (measured 2.2, 3.2, 3.4 and 3.6 n log2 n at 10, 30, 50 and
    100), and the pins' rows outnumber the bodies' coordinates by the grid's loops, which
    the factorization drops: what is left holds each body in x, y and angle."""
    joints, q = _grid_pass(size)
    pattern = joints.pattern
    assert pattern is not None
    n = pattern.size
    assert pattern.slots() <= 5.0 * n * math.log2(n)
    rows = joints.rows(q, 1.0 / 60.0)
    diagonal, lower = matrix(pattern, rows, directions(rows, joints.inverse_mass))
    _, _, out = factor(pattern, diagonal, lower)
    assert n - sum(out) == 3 * len(joints.bodies)  # each body held in x, y and angle
