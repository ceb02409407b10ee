"""The velocity solve and the position correction (C twin: ``src/kernel/solve.c``):
sequential impulses island by island over the units of :mod:`.islands` with the rows'
arithmetic of :mod:`.rows`, then the overlap beyond each contact's slop (:func:`slop`)
pushed apart by moving positions only.
"""
from __future__ import annotations

from .coupled import JointUnit
from .islands import WIDE_UNITS, coloured, islands, schedule, unit_bodies
from .rows import Block, ContactRow, States, Velocities, solve_point
from .warm import FRICTION_CARRY

__all__ = ["CONVERGED", "CORRECTION", "MAX_CORRECTION", "MAX_ITERATIONS", "MIN_ITERATIONS",
           "POSITION_ITERATIONS", "SETTLE", "SLOP", "SLOP_FRACTION", "WORK", "correct_positions",
           "passes", "slop", "solve_velocities"]

#: The velocity solver's passes over the contacts per step: as many as fit in
#: :data:`WORK` solves of a contact or two-point manifold, but at least
#: :data:`MIN_ITERATIONS` and at most :data:`MAX_ITERATIONS`, and fewer when converged
#: (no impulse changes a velocity by more than :data:`CONVERGED` relative to the fastest
#: body). So a scene's cost per step is bounded by its number of contacts alone: small
#: scenes converge to rounding, large ones take the fixed minimum, as game engines do.
#: An island of n units also gets n // :data:`SETTLE` passes: a pass carries a change
#: across a contact or two, so the slowest sway of a pile d contacts deep fades by about
#: 1/d^2 a pass, and d^2 grows as the pile's contacts; with fewer, the weight of a deep
#: pile never settles into its warm starts and the pile sways. Fastest box of the
#: benchmark's pyramids (rows^2 units) after 2 s, 1 cm/s allowed, with the colours swept
#: last first (:func:`~.islands.coloured`): 60 rows 0.003 m/s with 6 passes; 80 rows
#: 0.003 with 10; 100 rows 0.009 with 12, 0.004 with 16 (first colour first it took 25
#: for 0.004, and 14 left 0.05).
WORK = 600
MIN_ITERATIONS = 6
MAX_ITERATIONS = 40
SETTLE = 625
CONVERGED = 1e-13
#: Overlap left alone (m) by the position correction: at most :data:`SLOP`, and at most
#: :data:`SLOP_FRACTION` of the thinner body's size (:func:`slop`), so that a body smaller
#: than the fixed slop (a 1e-6 m box) cannot rest sunk wholly into what it lies on. Bodies
#: from 1 cm up all get :data:`SLOP` itself.
SLOP = 1e-4
SLOP_FRACTION = 0.01
#: Fraction of the remaining overlap removed per step, and the most removed per step (m).
CORRECTION = 0.2
MAX_CORRECTION = 0.05
POSITION_ITERATIONS = 4


def passes(units: int) -> int:
    """The most passes of the velocity solver over ``units`` contacts and blocks."""
    return min(max(WORK // units, MIN_ITERATIONS, units // SETTLE), MAX_ITERATIONS)


def slop(size: float) -> float:
    """The overlap (m) the position correction leaves to a body ``size`` thick (its thinnest
    part, at most twice its reach): :data:`SLOP`, or :data:`SLOP_FRACTION` of its size
    where that is less; a contact takes the smaller of its two bodies'."""
    return min(SLOP, SLOP_FRACTION * size)


def solve_velocities(rows: list[ContactRow], velocity: Velocities,
                      joint_units: list[JointUnit],
                      converged: float = CONVERGED) -> list[list[ContactRow | Block]]:
    """Gauss-Seidel passes over the rows, each two-point manifold as one block
    (:class:`~.rows.Block`), every other contact point by point, then the velocity rows of the
    joints in the island (:mod:`.coupled`), island by island (bodies that touch,
    through contacts or joints, share no body with another island; a joint's rows are
    swept only in an island that has a contact): each until no impulse changes a
    velocity by more than ``converged`` (the scene's ``contacts.converged``, by default
    :data:`CONVERGED`) relative to its fastest body, or
    :func:`passes` passes for its own number of units. Islands are independent, so
    each gets the bits it would get alone; a big island without joint rows is swept in
    colour order (:func:`~.islands.coloured`), and keeps :data:`~.warm.FRICTION_CARRY` of
    its rows' tangent impulses for the next warm start (``carry``) when its passes run
    out. (The kernel sweeps a smaller island level by level, ``src/kernel/solve.c``:
    ``hd_level_order``, trading only units that share no body, with the same bits.)
    Returns each island's units in the order swept."""
    swept = []
    for island, coupled in islands(schedule(rows), joint_units):
        wide = len(island) >= WIDE_UNITS and not coupled
        if wide:
            island = coloured(island)
        swept.append(island)
        for joint in coupled:
            joint.warm_start(velocity)
        fastest = max(abs(x) for unit in island for body in unit_bodies(unit)
                      for x in velocity[body])
        for joint in coupled:
            fastest = max(fastest, max(abs(x) for body in joint.bodies()
                                       for x in velocity[body]))
        scale = 1.0 + fastest
        for _ in range(passes(len(island) + len(coupled))):
            largest = 0.0
            for unit in island:
                change = (unit.solve(velocity) if isinstance(unit, Block)
                          else solve_point(unit, velocity))
                largest = max(largest, change)
            for joint in coupled:
                largest = max(largest, joint.solve(velocity))
            if largest <= converged * scale:
                break
        else:  # a small island, or one with joint rows, keeps its friction whole (a jam)
            if wide:
                _carry_friction(island)
    return swept


def _carry_friction(island: list[ContactRow | Block]) -> None:
    """The rows of a big island whose passes ran out keep :data:`~.warm.FRICTION_CARRY` of
    their tangent impulses for the next warm start."""
    for unit in island:
        for row in (unit.first, unit.second) if isinstance(unit, Block) else (unit,):
            row.carry = FRICTION_CARRY


def correct_positions(islands: list[list[ContactRow | Block]], velocity: Velocities,
                       q1: States, h: float) -> None:
    """Remove overlap beyond each row's ``slop`` by moving positions only, island by island,
    each in the order its velocities were swept; an island with no contact that deep
    moves nothing (islands share no body, so each gets the bits it would get alone).

    A contact's depth after the velocity change is depth - h (v_n' - v_n), linear in the
    arms; each pass moves the two bodies apart along the normal by a fraction of the
    excess, weighted by their inverse masses and inertias.
    """
    shift = {b: [0.0, 0.0, 0.0] for b in velocity}
    for island in islands:
        rows = [row for unit in island
                for row in ((unit.first, unit.second) if isinstance(unit, Block)
                            else (unit,))]
        # The depth beyond the slop: x - slop <= 0 exactly when x <= slop.
        base = [row.depth - h * (row.normal_velocity(velocity) - row.approach) - row.slop
                for row in rows]
        if max(base) <= 0.0:
            continue
        for _ in range(POSITION_ITERATIONS):
            for row, beyond in zip(rows, base):
                excess = beyond - row.normal_velocity(shift)
                if excess <= 0.0:
                    continue
                push = min(CORRECTION * excess, MAX_CORRECTION) * row.mass_n
                row.push(shift, push * row.nx, push * row.ny)
    for b, s in shift.items():
        if b >= 0 and any(s):
            q1[b] += s
