"""The joint rows' linear algebra: an order of the rows from the joint graph, where their
factors can be non-zero, and the factorizations themselves.

Every stage of the joint pass (:mod:`.joints`) solves a matrix whose entry (i, j) can be
non-zero only where rows i and j act on a common body: K = J M^-1 J^T (symmetric positive
semi-definite) and Newton's G(q) M^-1 G(q0)^T (not symmetric, the same pattern). Their
factors fill in wherever eliminating a row joins two rows that did not share a body, so the
order of the rows decides the cost, never the result's accuracy:

- :func:`joint_order` orders the joints on the joint graph (two joints are neighbours when
  their rows share a body): by minimum degree, each time the joint with the fewest
  neighbours left, counting those that elimination joins, where bodies and joints form
  no loop (a chain or a tree is then eliminated from its leaves inward and fills nothing
  in: its factorization costs O(rows)); by nested dissection on the joints' anchors where
  they do (a grid of pins). Ties go to the joint whose anchor lies first in x, then y, at
  the start pose: the order (and so every bit of the results) does not depend on the
  joints' names or the order they were declared in, only on the scene's geometry; only
  joints anchored at the very same point fall back to their names.
- :class:`Pattern` is the symbolic factorization of the rows in that order (the
  elimination tree's row patterns, Liu 1986): where L can be non-zero. It is computed once
  per scene; the kernel (``src/kernel/sparse.c``) receives it and repeats the numerical
  routines below operation for operation.
- :func:`factor` (L D L^T) and :func:`lu` (L U, for the Newton matrix) go row by row
  ("up-looking"), without pivoting, summing each entry's updates in ascending order. A
  row whose pivot vanishes (below :data:`DEPENDENT` of its lightest body's share of its
  diagonal, :attr:`Pattern.dependent`) repeats what earlier rows hold: it is dropped, its
  impulse is zero and the others carry the load, as a pseudo-inverse would (two pins at
  one point, the loops of a grid of pins). Its column of L (and row of U) stays +0.0, so
  the updates through it would subtract +0.0, which changes no bit: they are skipped
  (on Box2D's 100 x 100 joint grid, whose 39,586 rows hold 9,600 dependent ones, two
  thirds of the updates).
- Rows can be left out of a solve (``active``): their impulses are zero.
"""
from __future__ import annotations

import heapq
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Optional

__all__ = ["DEPENDENT", "DISSECT_ABOVE", "Pattern", "Factors", "joint_order",
           "minimum_degree", "factor", "substitute", "lu", "lu_solve"]

#: A pivot at most this fraction of its row's diagonal (of its lightest body's share of it,
#: :meth:`Pattern.lightest`) marks the row as dependent on the rows before it. Independent
#: rows of the stiffest chains measured (200 links: condition numbers near 1e6) keep pivots
#: above 1e-7 of their diagonal; rounding leaves dependent rows' pivots near 1e-16 of
#: theirs (at most 5e-14 in a 10 x 10 grid of pins).
DEPENDENT = 1e-10


#: Parts of a joint graph with loops at most this large are ordered by minimum degree
#: whole; larger ones are cut in two first (:func:`joint_order`).
DISSECT_ABOVE = 64


def joint_order(neighbours: Sequence[set[int]], keys: Sequence[tuple[Any, ...]],
                loops: bool = False) -> list[int]:
    """An elimination order of a graph of ``len(neighbours)`` nodes (joints) whose
    ``keys`` (a total order) begin with each node's position (x, y): by minimum degree
    (:func:`minimum_degree`) where the bodies and joints form no ``loops`` (a chain, a
    tree: no fill at all), else by geometric nested dissection (George 1973): a part of
    more than :data:`DISSECT_ABOVE` nodes is halved at the median of its longer extent,
    its halves come first (each the same way) and the separator last: the nodes of one
    half that touch the other, of the half where they are fewer (the first on a tie).
    On a grid of pins one half's touching nodes can be two rows of pins where the
    other's are one (Box2D's 100 x 100 joint grid, its second cut: 98 against 51 pins),
    as the median falls between or inside them; taking the fewer cuts its factorizations'
    updates through independent rows from 58M to 37M. Minimum degree alone, on a grid,
    sweeps it front by front (the x-then-y ties) and fills in O(n^1.5); the dissection
    fills O(n log n)."""
    nodes = list(range(len(neighbours)))
    return _dissect(neighbours, keys, nodes) if loops else minimum_degree(neighbours, keys,
                                                                           nodes)


def _dissect(neighbours: Sequence[set[int]], keys: Sequence[tuple[Any, ...]],
             nodes: list[int]) -> list[int]:
    if len(nodes) <= DISSECT_ABOVE:
        return minimum_degree(neighbours, keys, nodes)
    spans = [max(keys[i][axis] for i in nodes) - min(keys[i][axis] for i in nodes)
             for axis in (0, 1)]
    axis = 0 if spans[0] >= spans[1] else 1
    ordered = sorted(nodes, key=lambda i: (keys[i][axis], keys[i][1 - axis], keys[i]))
    half = len(ordered) // 2
    halves = ordered[:half], ordered[half:]
    # Either half's nodes that touch the other separate them: the fewer, the less fill.
    touching = [[i for i in side if not neighbours[i].isdisjoint(other)]
                for side, other in zip(halves, (set(halves[1]), set(halves[0])))]
    which = 1 if len(touching[1]) < len(touching[0]) else 0
    separator = touching[which]
    cut = set(separator)
    first, second = ([i for i in side if i not in cut] if k == which else side
                     for k, side in enumerate(halves))
    return (_dissect(neighbours, keys, first) + _dissect(neighbours, keys, second)
            + minimum_degree(neighbours, keys, separator))


def minimum_degree(neighbours: Sequence[set[int]], keys: Sequence[tuple[Any, ...]],
                   nodes: Sequence[int]) -> list[int]:
    """Minimum-degree elimination order of the graph's ``nodes`` (the subgraph they
    induce): at each step the node with the fewest neighbours left, edges added by the
    eliminations so far included; ties to the smallest ``keys`` entry."""
    inside = set(nodes)
    graph = {i: neighbours[i] & inside for i in nodes}
    heap = [(len(graph[i]), keys[i], i) for i in nodes]
    heapq.heapify(heap)
    done: set[int] = set()
    order = []
    while heap:
        degree, _, node = heapq.heappop(heap)
        if node in done or degree != len(graph[node]):
            continue  # eliminated already, or its degree changed since it was pushed
        done.add(node)
        order.append(node)
        joined = graph[node]
        for other in joined:
            adjacent = graph[other]
            adjacent.discard(node)
            adjacent |= joined
            adjacent.discard(other)
        for other in joined:
            heapq.heappush(heap, (len(graph[other]), keys[other], other))
        graph[node] = set()
    return order


@dataclass(frozen=True)
class Pattern:
    """Where the strict lower triangle of the rows' factors can be non-zero: row i's
    columns are ``columns[start[i]:start[i + 1]]`` (ascending), each a *slot* of the
    factors' arrays; ``above[i]`` lists the slots of column i, (row, slot) by ascending
    row, for the upper triangle's access; ``dependent[i]``: the fraction of row i's diagonal
    at or below which its pivot drops it (:data:`DEPENDENT` unless :meth:`lightest` set
    it; empty: :data:`DEPENDENT` for every row)."""

    start: tuple[int, ...]
    columns: tuple[int, ...]
    above: tuple[tuple[tuple[int, int], ...], ...]
    dependent: tuple[float, ...] = ()

    def lightest(self, shares: Sequence[Sequence[float]]) -> Pattern:
        """This pattern with each row's bound scaled by its lightest body's share of its
        diagonal over the mean share (``shares[i]``: J_b M_b^-1 J_b^T of each body b of
        row i). A row between a heavy and a light body is independent of the rows before
        it through the heavy body alone: its pivot is about the heavy body's share, which
        is 1e-12 of the diagonal between 1 kg and 1e-12 kg, where a dependent row's pivot
        is rounding of the whole diagonal. A row on one body, or on bodies of equal
        shares, keeps :data:`DEPENDENT`."""
        bounds = []
        for row in shares:
            positive = [s for s in row if s > 0.0]
            if len(positive) < 2:
                bounds.append(DEPENDENT)
                continue
            mean = sum(positive) / len(positive)
            bounds.append(DEPENDENT * (min(positive) / mean))
        return Pattern(self.start, self.columns, self.above, tuple(bounds))

    @property
    def bounds(self) -> tuple[float, ...]:
        """Each row's fraction of its diagonal at or below which its pivot drops it."""
        return self.dependent or (DEPENDENT,) * (len(self.start) - 1)

    @classmethod
    def of(cls, row_bodies: Sequence[Sequence[int]]) -> Pattern:
        """The pattern of rows acting on the bodies ``row_bodies[i]`` (each row's bodies;
        two rows sharing one are coupled), by the elimination tree: the non-zeros of
        row i are the tree's paths up from the earlier rows i shares a body with."""
        n = len(row_bodies)
        parent = [-1] * n
        mark = [-1] * n
        rows_of: dict[int, list[int]] = {}
        start, columns = [0], []
        for i in range(n):
            mark[i] = i
            reached = []
            for body in row_bodies[i]:
                for j in rows_of.get(body, ()):
                    while j >= 0 and mark[j] != i:
                        reached.append(j)
                        mark[j] = i
                        if parent[j] < 0:
                            parent[j] = i
                        j = parent[j]
            for body in row_bodies[i]:
                rows_of.setdefault(body, []).append(i)
            columns += sorted(reached)
            start.append(len(columns))
        above: list[list[tuple[int, int]]] = [[] for _ in range(n)]
        for i in range(n):
            for slot in range(start[i], start[i + 1]):
                above[columns[slot]].append((i, slot))
        return cls(tuple(start), tuple(columns), tuple(tuple(a) for a in above))

    @property
    def size(self) -> int:
        """The number of rows."""
        return len(self.start) - 1

    def slots(self) -> int:
        """The number of entries of the strict lower triangle."""
        return self.start[-1]

    def updates(self) -> int:
        """The multiply-subtracts of one :func:`factor` with no row dropped: a pair of
        column k's rows for each k (its entries' count c_k, c_k (c_k - 1) / 2); a solve
        (:func:`substitute`, :func:`lu_solve`) costs two per slot."""
        counts = [0] * self.size
        for k in self.columns:
            counts[k] += 1
        return sum(c * (c - 1) // 2 for c in counts)


#: (L by the pattern's slots, D or U's diagonal, which rows are left out of the solve).
Factors = tuple[list[float], list[float], list[bool]]


def factor(pattern: Pattern, diagonal: list[float], lower: list[float],
           active: Optional[Sequence[bool]] = None) -> Factors:
    """K = L D L^T of the symmetric K given by its ``diagonal`` and its strict ``lower``
    triangle (by the pattern's slots), for the ``active`` rows (default: all); a row
    whose pivot is at most its :attr:`Pattern.bounds` of its diagonal is dropped."""
    start, columns, bounds = pattern.start, pattern.columns, pattern.bounds
    n = len(diagonal)
    low = [0.0] * len(lower)
    diag = [0.0] * n
    out = [False] * n if active is None else [not a for a in active]
    for i in range(n):
        if out[i]:
            continue
        first, end = start[i], start[i + 1]
        for slot in range(first, end):
            j = columns[slot]
            if out[j]:
                continue
            s = lower[slot]
            a, b, end_j = first, start[j], start[j + 1]
            while a < slot and b < end_j:  # k < j in both rows' patterns
                ka, kb = columns[a], columns[b]
                if ka == kb:
                    if not out[ka]:  # a row left out or dropped: +0.0 * 0.0 * 0.0
                        s -= low[a] * diag[ka] * low[b]
                    a += 1
                    b += 1
                elif ka < kb:
                    a += 1
                else:
                    b += 1
            low[slot] = s / diag[j]
        s = diagonal[i]
        for slot in range(first, end):
            s -= low[slot] * diag[columns[slot]] * low[slot]
        if s > bounds[i] * diagonal[i]:
            diag[i] = s
        else:
            out[i] = True
    return low, diag, out


def substitute(pattern: Pattern, factors: Factors, rhs: list[float]) -> list[float]:
    """x with L D L^T x = rhs (:func:`factor`'s factors); zero for rows left out."""
    start, columns, above = pattern.start, pattern.columns, pattern.above
    low, diag, out = factors
    n = len(rhs)
    x = list(rhs)
    for i in range(n):
        if out[i]:
            x[i] = 0.0
            continue
        s = x[i]
        for slot in range(start[i], start[i + 1]):
            s -= low[slot] * x[columns[slot]]
        x[i] = s
    for i in range(n):
        if not out[i]:
            x[i] = x[i] / diag[i]
    for i in range(n - 1, -1, -1):
        if out[i]:
            continue
        s = x[i]
        for j, slot in above[i]:
            s -= low[slot] * x[j]
        x[i] = s
    return x


def lu(pattern: Pattern, diagonal: list[float], lower: list[float],
       upper: list[float]) -> Factors:
    """A = L U of the matrix A with the pattern's structure (symmetric), given by its
    ``diagonal``, its strict ``lower`` triangle and the transpose of its strict upper one
    (``upper[slot]`` = A[j, i] for the slot of (i, j)), without pivoting: the Newton
    matrix is K changed by the step's motion. Returns (L by slots, the reciprocals of U's
    diagonal, rows dropped), U's strict upper triangle taking the place of ``upper``; the
    reciprocals keep divisions, whose latency chains, out of the repeated solves."""
    start, columns, bounds = pattern.start, pattern.columns, pattern.bounds
    n = len(diagonal)
    low = [0.0] * len(lower)
    diag = [0.0] * n
    out = [False] * n
    for i in range(n):
        first, end = start[i], start[i + 1]
        for slot in range(first, end):
            j = columns[slot]
            if out[j]:
                upper[slot] = 0.0
                continue
            s, t = lower[slot], upper[slot]
            a, b, end_j = first, start[j], start[j + 1]
            while a < slot and b < end_j:
                ka, kb = columns[a], columns[b]
                if ka == kb:
                    if not out[ka]:  # a row dropped: +0.0 * 0.0
                        s -= low[a] * upper[b]  # L[i, k] U[k, j]
                        t -= low[b] * upper[a]  # L[j, k] U[k, i]
                    a += 1
                    b += 1
                elif ka < kb:
                    a += 1
                else:
                    b += 1
            low[slot] = s * diag[j]
            upper[slot] = t
        s = diagonal[i]
        for slot in range(first, end):
            s -= low[slot] * upper[slot]
        if abs(s) > bounds[i] * abs(diagonal[i]):
            diag[i] = 1.0 / s
        else:
            out[i] = True
    return low, diag, out


def lu_solve(pattern: Pattern, factors: Factors, upper: list[float],
             rhs: list[float]) -> list[float]:
    """x with L U x = rhs (:func:`lu`'s factors and U's strict upper triangle
    ``upper``); zero for rows dropped."""
    start, columns, above = pattern.start, pattern.columns, pattern.above
    low, diag, out = factors
    n = len(rhs)
    x = list(rhs)
    for i in range(n):
        s = x[i]
        for slot in range(start[i], start[i + 1]):
            s -= low[slot] * x[columns[slot]]
        x[i] = s
    for i in range(n - 1, -1, -1):
        if out[i]:
            x[i] = 0.0
            continue
        s = x[i]
        for j, slot in above[i]:
            s -= upper[slot] * x[j]
        x[i] = s * diag[i]
    return x
