"""The solver's units and islands (C twin: ``src/kernel/islands.c``; the colours of a big
island: ``src/kernel/wide.c``): the rows of a two-point manifold made one :class:`~.rows.Block`,
then the units grouped by the bodies they join, which share no body with another island.
"""
from __future__ import annotations

from typing import Optional

from .coupled import JointUnit
from .rows import Block, ContactRow

__all__ = ["COLOURS", "MAX_CONDITION", "WIDE_UNITS", "coloured", "islands", "join",
           "make_block", "root", "schedule", "unit_bodies"]

#: An island of at least :data:`WIDE_UNITS` units and no joint rows is swept in colour
#: order (:func:`coloured`, :data:`COLOURS` colours at most), in which the compiled kernel
#: solves four blocks of one colour at once (``src/kernel/wide.h``) with these same bits.
WIDE_UNITS = 64
COLOURS = 64
#: Largest condition number of a two-point manifold's 2 x 2 effective-mass matrix that is
#: still solved as one block.
MAX_CONDITION = 1000.0


def make_block(one: ContactRow, two: ContactRow) -> Optional[Block]:
    """The block of two points of a manifold, or None where K is too ill-conditioned
    (condition number above :data:`MAX_CONDITION`: points almost on one line through the
    bodies' CMs), which are then solved point by point."""
    nx, ny = one.nx, one.ny
    rna1, rnb1 = one.rax * ny - one.ray * nx, one.rbx * ny - one.rby * nx
    rna2, rnb2 = two.rax * ny - two.ray * nx, two.rbx * ny - two.rby * nx
    mass = one.im_a + one.im_b
    k11 = mass + rna1 * rna1 * one.ii_a + rnb1 * rnb1 * one.ii_b
    k22 = mass + rna2 * rna2 * one.ii_a + rnb2 * rnb2 * one.ii_b
    k12 = mass + rna1 * rna2 * one.ii_a + rnb1 * rnb2 * one.ii_b
    determinant = k11 * k22 - k12 * k12
    if not k11 * k11 < MAX_CONDITION * determinant:
        return None
    inverse = 1.0 / determinant
    return Block(one, two, k11, k12, k22, k22 * inverse, -k12 * inverse, k11 * inverse)


def schedule(rows: list[ContactRow]) -> list[ContactRow | Block]:
    """The solver's units in row order: a :class:`~.rows.Block` for each manifold of exactly two
    points (consecutive rows of one pair of parts with one normal), else single rows."""
    units: list[ContactRow | Block] = []
    count, k = len(rows), 0
    while k < count:
        row = rows[k]
        end = k + 1
        while end < count and rows[end].key == row.key:
            end += 1
        block = (make_block(row, rows[k + 1]) if end - k == 2 and row.nx == rows[k + 1].nx
                 and row.ny == rows[k + 1].ny else None)
        if block is None:
            units.extend(rows[k:end])
        else:
            units.append(block)
        k = end
    return units


def unit_bodies(unit: ContactRow | Block) -> tuple[int, int]:
    """The two bodies of a solver unit (the first -1 for a wall)."""
    row = unit.first if isinstance(unit, Block) else unit
    return row.a, row.b


def islands(units: list[ContactRow | Block], joints: list[JointUnit]
             ) -> list[tuple[list[ContactRow | Block], list[JointUnit]]]:
    """The units grouped by island (union-find over the bodies they join, contacts and
    joints; walls and the fixed frame join nothing), in order of each island's first
    unit, each island's units in their order, with the joint rows of that island (in the
    joint pass's order); joint rows of islands without a contact are left out."""
    parent: dict[int, int] = {}
    for unit in units:
        a, b = unit_bodies(unit)
        parent.setdefault(b, b)
        if a >= 0:
            parent.setdefault(a, a)
            join(parent, a, b)
    for joint in joints:
        first, *others = joint.bodies()
        parent.setdefault(first, first)
        for body in others:
            parent.setdefault(body, body)
            join(parent, first, body)
    islands: dict[int, tuple[list[ContactRow | Block], list[JointUnit]]] = {}
    for unit in units:
        islands.setdefault(root(parent, unit_bodies(unit)[1]), ([], []))[0].append(unit)
    for joint in joints:
        island = islands.get(root(parent, joint.entries[0][0]))
        if island is not None:
            island[1].append(joint)
    return list(islands.values())


def coloured(island: list[ContactRow | Block]) -> list[ContactRow | Block]:
    """The island's units by colour, greedy first fit in their order: each unit takes the
    lowest of :data:`COLOURS` colours that neither of its bodies has yet (a wall has none),
    and the units that fit none make one more colour, in their order. Units of one colour
    share no body, so they could be solved in any order, or at once, with the same result:
    a wall's velocity stays zero (Box2D v3's graph colouring, ``src/constraint_graph.c``).
    The colours come last first: so swept, a deep pile settles in about 0.6 of the passes
    (measured: the benchmark's 100-row pyramid moves at 0.004 m/s after 2 s with 16 passes
    a step, where first colour first took 25 for as much; :data:`~.solve.SETTLE`)."""
    taken: dict[int, int] = {}
    colours: list[list[ContactRow | Block]] = [[] for _ in range(COLOURS + 1)]
    for unit in island:
        a, b = unit_bodies(unit)
        free = ~(taken.get(a, 0) | taken.get(b, 0)) & ((1 << COLOURS) - 1)
        colour = (free & -free).bit_length() - 1 if free else COLOURS
        if free:
            if a >= 0:
                taken[a] = taken.get(a, 0) | 1 << colour
            taken[b] = taken.get(b, 0) | 1 << colour
        colours[colour].append(unit)
    return [unit for units in reversed(colours) for unit in units]


def root(parent: dict[int, int], body: int) -> int:
    """The root of ``body``'s set in the union-find forest ``parent`` (halving the path)."""
    while parent[body] != body:
        parent[body] = parent[parent[body]]
        body = parent[body]
    return body


def join(parent: dict[int, int], a: int, b: int) -> None:
    """Join the sets of bodies a and b under the lower root."""
    ra, rb = root(parent, a), root(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)
