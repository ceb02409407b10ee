"""The joints' solve: the matrices of a stage's rows and their impulses (C twin: the
solve of ``src/kernel/joint.c``, ``hd_directions`` to ``hd_solve``).

An impulse along a row changes a body's velocity by M^-1 J^T lambda: the force part by
Eq. 5, the torque of the impulse, perp(r) . P (Eq. 11), turned into a change of angular
velocity by tau = I alpha (Eq. 14), with the moment of inertia of Eq. 13. K = J M^-1 J^T
is assembled where the rows' :class:`~.sparse.Pattern` has room and factored by
:mod:`.sparse`; rows with bounds are solved by active sets (:func:`solve`).
"""
from __future__ import annotations

import math
from typing import Optional

from .joint_rows import JointRow
from .sparse import Factors, Pattern, factor, lu_solve, substitute

__all__ = ["ACTIVE_SETS", "CONVERGED", "MAX_ITERATIONS", "REFINEMENTS", "Directions", "apply",
           "directions", "dot", "matrix", "rate", "refine", "row_sum", "solve"]

#: The most active sets :func:`solve` tries (each one factorization of K's rows that hold
#: their equations) before it goes on by projected Gauss-Seidel.
ACTIVE_SETS = 8
#: Projected Gauss-Seidel passes over the bounded rows, and the impulse change that ends them.
MAX_ITERATIONS = 200
CONVERGED = 1e-13
#: The most corrections :func:`refine` makes before it gives up (and K is factored).
REFINEMENTS = 8


def rate(row: JointRow, v: list[float]) -> float:
    """The row's velocity J v."""
    rate = 0.0
    for b, jx, jy, jw in row.entries:
        rate += jx * v[3 * b] + jy * v[3 * b + 1] + jw * v[3 * b + 2]
    return rate


Directions = list[list[tuple[int, float, float, float]]]


def directions(rows: list[JointRow], inverse_mass: list[float],
               skip: Optional[list[bool]] = None) -> Directions:
    """Per row, M^-1 J^T: how an impulse along the row changes each body's velocity (the
    force part by Eq. 5, the angular part by tau = I alpha, Eq. 14); none (no entries)
    for the rows ``skip`` marks."""
    return [[] if skip is not None and skip[i] else
            [(b, inverse_mass[3 * b] * jx, inverse_mass[3 * b + 1] * jy,
              inverse_mass[3 * b + 2] * jw) for b, jx, jy, jw in row.entries]
            for i, row in enumerate(rows)]


def apply(x: list[float], direction: Directions, impulse: list[float]) -> None:
    """x += M^-1 J^T impulse, row by row, skipping zero impulses (x: positions or
    velocities, 3 per body)."""
    for entries, amount in zip(direction, impulse):
        if amount == 0.0:
            continue
        for b, dx, dy, dw in entries:
            x[3 * b] += dx * amount
            x[3 * b + 1] += dy * amount
            x[3 * b + 2] += dw * amount


def dot(row: JointRow, entries: list[tuple[int, float, float, float]]) -> float:
    """J_row . (M^-1 J^T)_column: the bodies the two share."""
    s = 0.0
    for b, jx, jy, jw in row.entries:
        for c, dx, dy, dw in entries:
            if b == c:
                s += jx * dx + jy * dy + jw * dw
    return s


def matrix(pattern: Pattern, rows: list[JointRow], direction: Directions,
            active: Optional[list[bool]] = None,
            upper: Optional[list[float]] = None) -> tuple[list[float], list[float]]:
    """The entries of G M^-1 G0^T where the pattern has room, for rows G and the directions
    M^-1 G0^T (of the same rows at other positions, or at the same: K): (diagonal, strict
    lower triangle by slots); with ``upper`` given, the transpose of the strict upper
    triangle by slots into it. Zero where a row is not ``active``."""
    start, columns = pattern.start, pattern.columns
    n = len(rows)
    diagonal, lower = [0.0] * n, [0.0] * pattern.slots()
    for i, row in enumerate(rows):
        if active is not None and not active[i]:
            continue
        diagonal[i] = dot(row, direction[i])
        for slot in range(start[i], start[i + 1]):
            j = columns[slot]
            if active is None or active[j]:
                lower[slot] = dot(row, direction[j])
                if upper is not None:
                    upper[slot] = dot(rows[j], direction[i])
    return diagonal, lower


def row_sum(pattern: Pattern, diagonal: list[float], lower: list[float], i: int,
             x: list[float], skip: Optional[list[bool]] = None) -> float:
    """Row i of the symmetric matrix (its ``diagonal`` and strict ``lower`` triangle) times
    x, in ascending column order, leaving out the columns ``skip`` marks."""
    start, columns = pattern.start, pattern.columns
    s = 0.0
    for slot in range(start[i], start[i + 1]):
        j = columns[slot]
        if skip is None or not skip[j]:
            s += lower[slot] * x[j]
    if skip is None or not skip[i]:
        s += diagonal[i] * x[i]
    for j, slot in pattern.above[i]:
        if skip is None or not skip[j]:
            s += lower[slot] * x[j]
    return s


def solve(pattern: Pattern, diagonal: list[float], lower: list[float], b: list[float],
           bounds: tuple[list[float], list[float]], warm: list[float]) -> list[float]:
    """Impulses x with (K x - b)_i = 0 where lower_i < x_i < upper_i, >= 0 at lower_i and
    <= 0 at upper_i (``bounds``), K by its ``diagonal`` and strict ``lower`` triangle.

    By active sets: each bounded row either holds its equation, solved with the unbounded
    rows as one block (L D L^T of the rows that hold), or sits at a bound; a row whose
    impulse leaves its bounds goes to the bound, a row at a bound whose equation wants
    the impulse further inside holds its equation again, until neither happens (the
    exact solution, one or two factorizations from the last step's impulses ``warm``).
    After :data:`ACTIVE_SETS` sets without an end, projected Gauss-Seidel passes over
    the bounded rows, alternated with the block, go on until no bounded impulse changes
    by more than :data:`CONVERGED` relative to the largest."""
    low_bound, high_bound = bounds
    n = len(b)
    free = [lo == -math.inf and up == math.inf for lo, up in zip(low_bound, high_bound)]
    if all(free):
        return substitute(pattern, factor(pattern, diagonal, lower), b)
    bounded = [i for i in range(n) if not free[i]]
    # -1 at the lower bound, 1 at the upper, 0 holding its equation
    side = [0 if f else -1 if x0 <= lo or lo == up else 1 if x0 >= up else 0
            for f, x0, lo, up in zip(free, warm, low_bound, high_bound)]
    for _ in range(ACTIVE_SETS):
        holds = [at == 0 for at in side]
        x = [0.0 if at == 0 else low_bound[i] if at < 0 else high_bound[i]
             for i, at in enumerate(side)]
        rhs = [b[i] - row_sum(pattern, diagonal, lower, i, x, holds) if holds[i] else 0.0
               for i in range(n)]
        for i, xi in enumerate(substitute(pattern, factor(pattern, diagonal, lower, holds), rhs)):
            if holds[i]:
                x[i] = xi
        settled = True
        for i in bounded:
            if side[i] == 0:
                side[i] = -1 if x[i] < low_bound[i] else 1 if x[i] > high_bound[i] else 0
            elif low_bound[i] < high_bound[i]:
                wanted = b[i] - row_sum(pattern, diagonal, lower, i, x)
                side[i] = 0 if wanted * side[i] < 0.0 else side[i]
            settled = settled and (side[i] == 0) == holds[i]
        if settled:
            return x
    factors = factor(pattern, diagonal, lower, free) if any(free) else None
    for _ in range(MAX_ITERATIONS):
        if factors is not None:
            rhs = [b[i] - row_sum(pattern, diagonal, lower, i, x, free) if free[i] else 0.0
                   for i in range(n)]
            for i, xi in enumerate(substitute(pattern, factors, rhs)):
                if free[i]:
                    x[i] = xi
        largest = 0.0
        for i in bounded:
            s = row_sum(pattern, diagonal, lower, i, x)
            new = min(max(x[i] + (b[i] - s) / diagonal[i], low_bound[i]), high_bound[i])
            change = abs(new - x[i])
            largest = change if change > largest else largest
            x[i] = new
        if largest <= CONVERGED * (1.0 + max(abs(xi) for xi in x)):
            break
    return x


def refine(pattern: Pattern, diagonal: list[float], lower: list[float], b: list[float],
           near: tuple[Factors, list[float]], residual: float) -> Optional[list[float]]:
    """Impulses x with K x = b (K by its ``diagonal`` and strict ``lower`` triangle, no
    bounds) by iterative refinement on the L U of a matrix ``near`` K (:func:`.sparse.lu`'s
    factors and U's strict upper triangle: the Newton matrix G(q) M^-1 G(q0)^T of the
    same rows, which differs from K = G(q) M^-1 G(q)^T by the step's turn of the rows):
    x = A^-1 b, then x += A^-1 (b - K x) until no row's residual (the rate J v it leaves)
    exceeds ``residual``, the dependent rows' included: A's factorization drops those rows
    (their impulses are zero, as :func:`solve` drops them) and the corrections do not aim
    at them, but their rates sum the kept rows' through the loops that make them
    dependent. None when :data:`REFINEMENTS` corrections do not get there or one does not
    halve the largest residual: then K is factored (:func:`solve`). A factorization costs
    about :meth:`.sparse.Pattern.updates` multiply-subtracts, a correction four per slot:
    on a grid of pins, a tenth of it or less."""
    _, _, out = near[0]
    x = lu_solve(pattern, near[0], near[1], b)
    previous = math.inf
    for correction in range(REFINEMENTS + 1):
        r = [b[i] - row_sum(pattern, diagonal, lower, i, x) for i in range(len(b))]
        largest = max(map(abs, r))
        if largest <= residual:
            return x
        if correction == REFINEMENTS or not largest <= 0.5 * previous:
            return None
        previous = largest
        r = [0.0 if dropped else ri for ri, dropped in zip(r, out)]
        x = [a + c for a, c in zip(x, lu_solve(pattern, near[0], near[1], r))]
    return None
