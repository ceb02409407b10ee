"""Which pairs of bodies collide, and with which restitution and friction.

A scene's collision groups name the bodies that collide with each other, every pair of a
group with the group's material; the joints' ``apart`` pairs do not collide although a
group names them. :class:`PairMaterials` keeps that per class of bodies (the bodies that
the same groups name), not per pair: memory and set-up grow with the bodies and groups,
not with the square of the bodies (a pyramid of 465 boxes in one group is one class, not
107,880 pairs), and a look-up reads a table small enough to stay in cache.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Optional

__all__ = ["Material", "PairMaterials"]

#: A pair's restitution and friction coefficient.
Material = tuple[float, float]


class PairMaterials:
    """The material of each colliding pair of bodies (i < j): that of the last group that
    names both (the scene loader lets a pair be in one group at most), none for a pair of
    ``apart``."""

    def __init__(self, groups: Sequence[tuple[Iterable[int], float, float]], bodies: int,
                 apart: Iterable[tuple[int, int]] = ()) -> None:
        """``groups``: each collision group's body indices, restitution and friction, in
        the scene's order; ``bodies``: how many the scene has."""
        named: list[list[int]] = [[] for _ in range(bodies)]
        for g, (members, _, _) in enumerate(groups):
            for i in sorted(set(members)):
                named[i].append(g)
        signatures: dict[tuple[int, ...], int] = {}
        for names in named:
            if names:
                signatures.setdefault(tuple(names), len(signatures))
        #: Per body its class (-1: in no group); per pair of classes the index of the last
        #: group naming both (-1: none); per group its material.
        self.classes = [signatures[tuple(names)] if names else -1 for names in named]
        self.table = [[max(set(c) & set(d), default=-1) for d in signatures]
                      for c in signatures]
        self.materials: list[Material] = [(e, mu) for _, e, mu in groups]
        #: The pairs of ``apart`` that a group names, sorted.
        self.apart = sorted({(i, j) for i, j in apart if self._grouped(i, j) >= 0})
        self._apart = frozenset(self.apart)

    def _grouped(self, i: int, j: int) -> int:
        """The last group naming both bodies i < j, or -1."""
        c, d = self.classes[i], self.classes[j]
        return -1 if c < 0 or d < 0 else self.table[c][d]

    def get(self, i: int, j: int) -> Optional[Material]:
        """The material of bodies i < j, or None if they do not collide."""
        g = self._grouped(i, j)
        return None if g < 0 or (i, j) in self._apart else self.materials[g]

    def colliding(self) -> list[int]:
        """The bodies that collide with at least one other, in order."""
        members = Counter(c for c in self.classes if c >= 0)
        partners = [0 if c < 0 else sum(count - (d == c) for d, count in members.items()
                                        if self.table[c][d] >= 0)
                    for c in self.classes]
        for i, j in self.apart:
            partners[i] -= 1
            partners[j] -= 1
        return [i for i, count in enumerate(partners) if count > 0]
