"""The joint rows' factorizations (contact/sparse.py) on Box2D's joint grid, whose loops
make about a quarter of its rows dependent: references are a dense elimination in the
same order (every entry's updates in ascending k, structural zeros included), the rows
the grid's coordinates leave independent, and the fill of nested dissection; and the
velocity stage's refinement on the Newton matrix's L U, which meets the rows' velocities as
the direct solve does."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.bench.joints import chain, grid, pin_gap
from hecker_dynamics.contact import joints as joint_pass
from hecker_dynamics.contact.joint_solve import apply, directions, matrix, rate, refine, solve
from hecker_dynamics.contact.joints import SHARE_ABOVE, JointPass
from hecker_dynamics.contact.sparse import Pattern, factor, lu
from hecker_dynamics.dynamics import Simulation, kernel
from hecker_dynamics.scene.load import Scene


def _grid_pass(size: int) -> tuple[JointPass, list[float]]:
    sim = Simulation(grid(size, 1.0 / 60.0, 1.0))
    joints = sim.model.joints
    assert joints is not None
    joints.reset(sim.q)
    return joints, sim.q[joints.bodies].reshape(-1).tolist()


def spinning_grid(size: int, omega: float, step: float = 1.0 / 60.0,
                  motor: float = 0.0) -> Scene:
    """A size x size grid of circles 1 m apart pinned to their neighbours (Box2D's
    joint_grid without its fixed row or gravity), spinning as one rigid body at ``omega``
    rad/s about its centre: its loops make it rigid, so each step turns every pin's arm by
    omega h while every pin holds. ``motor``: the first column's vertical pins drive their
    links at 1 rad/s with at most that torque (N m), rows with bounds."""
    centre = 0.5 * (size - 1)
    bodies, joints = {}, {}
    for k in range(size):
        for i in range(size):
            x, y = k - centre, i - centre
            bodies[f"b{k:02d}_{i:02d}"] = {
                "shape": "circle", "radius": 0.4, "density": 1.0, "position": [x, y],
                "velocity": [-omega * y, omega * x], "angular_velocity": omega}
            if i:
                joints[f"v{k:02d}_{i:02d}"] = {
                    "type": "revolute", "body_a": f"b{k:02d}_{i - 1:02d}", "point_a": [0.0, 0.5],
                    "body_b": f"b{k:02d}_{i:02d}", "point_b": [0.0, -0.5]}
                if motor and not k:
                    joints[f"v{k:02d}_{i:02d}"]["motor"] = {"speed": 1.0, "max_torque": motor}
            if k:
                joints[f"h{k:02d}_{i:02d}"] = {
                    "type": "revolute", "body_a": f"b{k - 1:02d}_{i:02d}", "point_a": [0.5, 0.0],
                    "body_b": f"b{k:02d}_{i:02d}", "point_b": [-0.5, 0.0]}
    return make_scene({"step": step, "duration": 1.0, "integrator": "velocity_verlet",
                       "publish_rate": 10.0, "bodies": bodies, "joints": joints})


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


def test_updates_count_the_pairs_of_each_column():
    """A row's entries in column k are updated by each earlier row of that column: on rows
    0-3 all sharing one body (a dense 4 x 4), column 0 has 3 entries below the diagonal,
    column 1 two, column 2 one: 3 + 1 + 0 updates, against 6 slots; a chain's blocks
    (each row on its link and the next) update nothing twice."""
    dense = Pattern.of([[0]] * 4)
    assert dense.slots() == 6 and dense.updates() == 3 + 1 + 0
    chain = Pattern.of([[0], [0, 1], [1, 2], [2, 3]])
    assert chain.updates() == 0


def test_grids_share_the_newton_matrix_and_chains_do_not():
    """The pass refines on the Newton matrix's L U where a factorization costs more than
    SHARE_ABOVE multiply-subtracts a slot: a grid of pins (12 a slot at 10 x 10), not a
    chain of pins (under 1 a slot), whose bits stay those of the direct solve."""
    joints, _ = _grid_pass(10)
    assert joints.pattern is not None
    assert joints.pattern.updates() > SHARE_ABOVE * joints.pattern.slots() and joints.share
    sim = Simulation(chain(20))
    links = sim.model.joints
    assert links is not None
    links.reset(sim.q)
    assert not links.share


def _near_and_k(angle: float, spread: float) -> tuple[Any, ...]:
    """The spinning 10 x 10 grid's pass, its pose turned rigidly by ``angle`` about its
    centre (every pin still holds), the Newton matrix G(q) M^-1 G(q0)^T's L U between the
    two poses, K = G(q) M^-1 G(q)^T at the turned one, its rows' directions and their
    rates b = -J v for the spin's velocities (turned) plus ``spread`` m/s of a pattern."""
    sim = Simulation(spinning_grid(10, 1.0))
    joints = sim.model.joints
    assert joints is not None
    joints.reset(sim.q)
    pattern = joints.pattern
    assert pattern is not None
    c, s = math.cos(angle), math.sin(angle)

    def turned(x: list[float], turn: float) -> list[float]:
        out = []
        for k in range(0, len(x), 3):
            out += [c * x[k] - s * x[k + 1], s * x[k] + c * x[k + 1], x[k + 2] + turn]
        return out

    q0 = sim.q[joints.bodies].reshape(-1).tolist()
    q = turned(q0, angle)
    v = [x + spread * math.cos(3.0 * k)
         for k, x in enumerate(turned(sim.v[joints.bodies].reshape(-1).tolist(), 0.0))]
    h = 1.0 / 60.0
    rows0, rows = joints.rows(q0, h), joints.rows(q, h)
    upper = [0.0] * pattern.slots()
    diagonal, lower = matrix(pattern, rows, directions(rows0, joints.inverse_mass), upper=upper)
    near = (lu(pattern, diagonal, lower, upper), upper)
    direction = directions(rows, joints.inverse_mass)
    diagonal, lower = matrix(pattern, rows, direction)
    return pattern, rows, direction, diagonal, lower, [-rate(row, v) for row in rows], near, v


@pytest.mark.parametrize("angle", [1e-4, 1e-3, 1e-2])
def test_refining_on_a_near_matrix_meets_the_rows_velocities(angle):
    """On a spinning 10 x 10 grid turned by a step's ``angle`` from where the Newton matrix
    was factored, refining K x = b on that L U to 1e-12 m/s leaves every row's velocity,
    recomputed from the rows themselves and the dropped (dependent) rows' included, within
    2e-12 m/s (rounding of the rates' sums): no worse than the direct solve of K, which
    leaves 6e-10 m/s at 1e-4 rad (its own dropped rows, decided by rounding, differ)."""
    pattern, rows, direction, diagonal, lower, b, near, v = _near_and_k(angle, 0.01)
    x = refine(pattern, diagonal, lower, b, near, 1e-12)
    assert x is not None
    n = len(rows)
    direct = solve(pattern, diagonal, lower, b, ([-math.inf] * n, [math.inf] * n), [0.0] * n)
    worst = []
    for impulse in (x, direct):
        after = list(v)
        apply(after, direction, impulse)
        worst.append(max(abs(rate(row, after)) for row in rows))
    assert worst[0] <= 2e-12 and worst[0] <= max(worst[1], 1e-12)


def test_refining_on_a_far_matrix_gives_up():
    """A Newton matrix from a pose turned by 0.5 rad is no start for K: the first solve
    leaves residuals above b's own and the corrections do not halve them every time, and
    refine says so (the pass then factors K)."""
    pattern, _, _, diagonal, lower, b, near, _ = _near_and_k(0.5, 0.01)
    assert refine(pattern, diagonal, lower, b, near, 1e-12) is None


def test_the_pass_refines_where_it_can_and_holds_the_pins_as_without(monkeypatch):
    """A 10 x 10 grid spinning at 1 rad/s, 30 steps of h = 1/60 s in Python: its velocity
    stage refines on the Newton matrix where that gets every row to tolerance / h and
    factors K where not (both happen), the pins hold within the tolerance, and the run
    stays within 1e-9 m and 1e-9 m/s of the same run solving K directly every step."""
    outcomes = []

    def counted(*args: Any) -> Any:
        x = refine(*args)
        outcomes.append(x is not None)
        return x

    monkeypatch.setattr(joint_pass, "refine", counted)
    runs = []
    for share in (True, False):
        scene = spinning_grid(10, 1.0)
        sim = Simulation(scene)
        sim.model.use_python()
        assert sim.model.joints is not None and sim.model.joints.share
        sim.model.joints.share = share
        sim.advance_to(30 * sim.step_ns)
        assert pin_gap(scene, sim.model, sim.q) <= joint_pass.TOLERANCE
        runs.append((sim.q.copy(), sim.v.copy()))
    assert any(outcomes) and not all(outcomes)
    assert np.abs(runs[0][0] - runs[1][0]).max() <= 1e-9
    assert np.abs(runs[0][1] - runs[1][1]).max() <= 1e-9


@pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not built or "
                    "HECKER_DYNAMICS_KERNEL=0")
def test_a_grid_too_big_to_list_with_bounded_rows_has_the_bits_of_python():
    """The spinning 33 x 33 grid with a motor on its first column's pins: its factors take
    more updates than the kernel lists (HD_MOST_UPDATES, 4M), so the kernel factors them by
    supernodes (runs of columns whose rows below are nested: the dissection's separators);
    the motors' rows, bounded, leave rows out of the velocity stage's L D L^T, and the
    loops drop rows in both factorizations: each entry still takes Python's subtractions
    in Python's order, so two steps give the same bits."""
    ends = []
    for python in (False, True):
        sim = Simulation(spinning_grid(33, 1.0, motor=1e-3))
        if python:
            sim.model.use_python()
        sim.advance_to(2 * sim.step_ns, keep=False)
        ends.append(sim)
    joints = ends[0].model.joints
    assert joints is not None and joints.pattern is not None
    assert joints.pattern.updates() > 4_000_000 and len(joints.rigid) < joints.pattern.size
    assert np.array_equal(ends[0].q, ends[1].q) and np.array_equal(ends[0].v, ends[1].v)
