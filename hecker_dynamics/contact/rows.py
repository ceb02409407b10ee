"""The solver's rows: one contact, or the two points of a manifold as one block, and the
impulses that solve them (C twin: ``src/kernel/rows.h``, operation for operation).

Each impulse is the article series' collision impulse for a contact with both bodies'
mass and moment of inertia, accumulated and clamped (contacts push, never pull), with
Coulomb friction |j_t| <= mu j_n.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Block", "ContactRow", "PartKey", "States", "Velocities", "normal_velocity",
           "solve_friction", "solve_normal", "solve_point"]

#: A contact's pair of parts: bodies a and b (a wall is body -1 - its index) and the
#: parts' indices, by which warm starting knows it.
PartKey = tuple[int, int, int, int]
#: The velocities (vx, vy, omega) by body, -1 the walls' (always zero).
Velocities = dict[int, list[float]]
#: Positions or velocities, (x, y, angle) or (vx, vy, omega) per body: N x 3.
States = NDArray[np.float64]


@dataclass(slots=True)
class ContactRow:
    """One contact in the impulse solver, set up from the positions at the step's end.

    Bodies ``a`` (-1 for a wall) and ``b``; arms r_A = (rax, ray) and r_B = (rbx, rby) from
    their CMs to the contact point; unit normal n = (nx, ny) from A to B; effective masses
    along n and along t = perp(n); the normal velocity the impulses aim for (``target``);
    friction coefficient ``mu``; the accumulated normal and tangent impulses ``jn`` and
    ``jt``, the only fields the solver changes; the overlap at the step's end (``depth``,
    negative for a gap within :data:`~.detect.MARGIN`); inverse masses and inertias (zero for a
    wall); the normal velocity before any impulse (``approach``); the pair of parts
    (``key``), for warm starting; the overlap the position correction leaves (``slop``: the
    smaller of its bodies', :func:`~.solve.slop`); and the fraction of its tangent impulse it
    keeps for that (``carry``: :data:`~.warm.FRICTION_CARRY` where its big island's passes
    ran out, else 1).
    """

    a: int
    b: int
    rax: float
    ray: float
    rbx: float
    rby: float
    nx: float
    ny: float
    mass_n: float
    mass_t: float
    target: float
    mu: float
    jn: float
    jt: float
    depth: float
    im_a: float
    ii_a: float
    im_b: float
    ii_b: float
    approach: float
    key: PartKey
    slop: float
    carry: float = 1.0

    def normal_velocity(self, velocity: Velocities) -> float:
        """The contact's normal velocity for the bodies' ``velocity`` (see
        :func:`normal_velocity`)."""
        return normal_velocity(velocity[self.a], velocity[self.b], self.rax, self.ray,
                                self.rbx, self.rby, self.nx, self.ny)

    def push(self, velocity: Velocities, px: float, py: float) -> None:
        """Apply impulse (px, py) at the contact: +P to body b, -P to body a."""
        va, vb = velocity[self.a], velocity[self.b]
        va[0] -= px * self.im_a
        va[1] -= py * self.im_a
        va[2] -= (self.rax * py - self.ray * px) * self.ii_a
        vb[0] += px * self.im_b
        vb[1] += py * self.im_b
        vb[2] += (self.rbx * py - self.rby * px) * self.ii_b


def normal_velocity(va: list[float], vb: list[float], rax: float, ray: float, rbx: float,
                    rby: float, nx: float, ny: float) -> float:
    """(v_B + omega_B perp(r_B) - v_A - omega_A perp(r_A)) . n: negative when approaching."""
    return ((vb[0] - vb[2] * rby - va[0] + va[2] * ray) * nx
            + (vb[1] + vb[2] * rbx - va[1] - va[2] * rax) * ny)


def solve_normal(row: ContactRow, velocity: Velocities) -> float:
    """One contact's normal impulse: the accumulated total that brings its normal velocity
    to its target, clamped at zero (contacts push, never pull). Returns the change of the
    normal velocity."""
    jn = row.jn
    new_n = max(jn + (row.target - row.normal_velocity(velocity)) * row.mass_n, 0.0)
    row.push(velocity, (new_n - jn) * row.nx, (new_n - jn) * row.ny)
    row.jn = new_n
    return abs(new_n - jn) / row.mass_n


def solve_friction(row: ContactRow, velocity: Velocities) -> float:
    """One contact's tangent impulse: the accumulated total that stops its sliding, within
    Coulomb's cone |j_t| <= mu j_n. Returns the change of the tangent velocity."""
    if not row.mu > 0.0:
        return 0.0
    va, vb = velocity[row.a], velocity[row.b]
    dvx = vb[0] - vb[2] * row.rby - va[0] + va[2] * row.ray
    dvy = vb[1] + vb[2] * row.rbx - va[1] - va[2] * row.rax
    jt, bound = row.jt, row.mu * row.jn
    new_t = min(max(jt - (-dvx * row.ny + dvy * row.nx) * row.mass_t, -bound), bound)
    row.push(velocity, -(new_t - jt) * row.ny, (new_t - jt) * row.nx)
    row.jt = new_t
    return abs(new_t - jt) / row.mass_t


def solve_point(row: ContactRow, velocity: Velocities) -> float:
    """A contact solved on its own: normal impulse, then friction. Returns the larger
    velocity change."""
    change = solve_normal(row, velocity)
    return max(change, solve_friction(row, velocity))


@dataclass(slots=True)
class Block:
    """The two points of one manifold (same bodies, same normal), whose normal impulses
    are solved together: the 2 x 2 linear complementarity problem
    K x + b >= 0, x >= 0, x . (K x + b) = 0, by trying which points are active (Box2D's
    block solver). K's entries k11, k12, k22 are the two points' effective inverse masses
    along n and their coupling; (inv11, inv12, inv22) is K's inverse."""

    first: ContactRow
    second: ContactRow
    k11: float
    k12: float
    k22: float
    inv11: float
    inv12: float
    inv22: float

    def solve(self, velocity: Velocities) -> float:
        """Both normal impulses at once, then each point's friction. Returns the largest
        velocity change."""
        one, two = self.first, self.second
        old1, old2 = one.jn, two.jn
        b1 = one.normal_velocity(velocity) - one.target - (self.k11 * old1 + self.k12 * old2)
        b2 = two.normal_velocity(velocity) - two.target - (self.k12 * old1 + self.k22 * old2)
        x1 = -(self.inv11 * b1 + self.inv12 * b2)
        x2 = -(self.inv12 * b1 + self.inv22 * b2)
        if not (x1 >= 0.0 and x2 >= 0.0):  # both pushing failed: only the first
            x1, x2 = -one.mass_n * b1, 0.0
            if not (x1 >= 0.0 and self.k12 * x1 + b2 >= 0.0):  # only the second
                x1, x2 = 0.0, -two.mass_n * b2
                if not (x2 >= 0.0 and self.k12 * x2 + b1 >= 0.0):  # neither
                    x1, x2 = 0.0, 0.0
                    if not (b1 >= 0.0 and b2 >= 0.0):
                        x1, x2 = old1, old2  # no solution (degenerate): leave them
        one.push(velocity, (x1 - old1) * one.nx, (x1 - old1) * one.ny)
        two.push(velocity, (x2 - old2) * two.nx, (x2 - old2) * two.ny)
        one.jn, two.jn = x1, x2
        change = max(abs(x1 - old1) / one.mass_n, abs(x2 - old2) / two.mass_n)
        change = max(change, solve_friction(one, velocity))
        return max(change, solve_friction(two, velocity))
