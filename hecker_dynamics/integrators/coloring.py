"""Colored finite differences (Curtis, Powell and Reid): which bodies may be bumped at once.

A body *influences* itself and every body whose acceleration depends on its state (the
other end of a spring, the target of an input whose axes or point are its own). Two bodies
that influence no body in common can have one state component bumped in the same force
evaluation: each body's difference column is read from the rows of the bodies it
influences, and every other row of that column is zero. Grouping the bodies so that no two
in a group share an influenced body is a distance-2 coloring of the coupling graph; a
greedy coloring in body order is used. A chain, or a ring of more than 5 bodies, takes 3
to 5 groups whatever its length, instead of one group per body.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

__all__ = ["Coloring", "color"]


@dataclass(frozen=True)
class Coloring:
    """Groups of bodies whose state components are bumped together, and where to read them.

    ``groups[g]`` holds the bodies of group ``g`` (ascending); ``influenced[k]`` the bodies
    whose accelerations depend on body ``k``'s state (``k`` included, ascending). For each
    group, ``rows[g]`` and ``columns[g]`` list the nonzero entries of one component's
    columns: row ``rows[g][e]`` (a flat index 3 i + r of an influenced body i) of the column
    of body ``columns[g][e]``.
    """

    size: int
    groups: tuple[np.ndarray, ...]
    influenced: tuple[np.ndarray, ...]
    rows: tuple[np.ndarray, ...]
    columns: tuple[np.ndarray, ...]

    def is_valid(self) -> bool:
        """True if no two bodies of a group influence a common body (and each body is in
        exactly one group)."""
        members = np.sort(np.concatenate(self.groups)) if self.groups else np.zeros(0, int)
        if not np.array_equal(members, np.arange(self.size)):
            return False
        for group in self.groups:
            reached = np.concatenate([self.influenced[k] for k in group])
            if len(np.unique(reached)) != len(reached):
                return False
        return True


def color(size: int, couplings: Iterable[tuple[int, int]]) -> Coloring:
    """Color ``size`` bodies given the couplings (source, target): the target's
    acceleration depends on the source's state. Deterministic: greedy, in body order."""
    influenced: list[set[int]] = [{k} for k in range(size)]
    for source, target in couplings:
        influenced[source].add(target)
    influencers: list[list[int]] = [[] for _ in range(size)]  # bodies influencing each body
    for k in range(size):
        for i in influenced[k]:
            influencers[i].append(k)
    colors = [-1] * size
    for k in range(size):
        taken = {colors[j] for i in influenced[k] for j in influencers[i]}
        colors[k] = next(c for c in range(size) if c not in taken)
    members: list[list[int]] = [[] for _ in range(max(colors, default=-1) + 1)]
    for k, c in enumerate(colors):
        members[c].append(k)
    reach = tuple(np.array(sorted(s), dtype=np.intp) for s in influenced)
    rows, columns = [], []
    for group in members:
        pairs = [(3 * i + r, k) for k in group for i in reach[k] for r in range(3)]
        rows.append(np.array([p[0] for p in pairs], dtype=np.intp))
        columns.append(np.array([p[1] for p in pairs], dtype=np.intp))
    return Coloring(size, tuple(np.array(g, dtype=np.intp) for g in members), reach,
                     tuple(rows), tuple(columns))
