"""Event location: wall impacts found inside the step, at the instant of touch.

The contact pass (:mod:`.solver`) works at the end of a step: a bounce found there is late
by up to a step, so a dropped ball's impact times and apex heights carry O(h) errors
whatever the integrator's accuracy. With the scene's ``contacts.events`` on, each
integrator step from (q0, v0) over h is taken by :meth:`WallEvents.step` instead:

1. take the step; a (wall, body) pair whose gap, the smallest signed distance of the
   body's shape from the wall (a circle: n . c - offset - r; a polygon: its lowest vertex,
   n . p - offset), is positive at the start and negative at the end has crossed the wall
   inside the step;
2. find the first time of touch tau in (0, h) of the earliest of the crossing pairs, the
   zero of the smallest gap G(t), by regula falsi with the Illinois modification on states
   re-integrated from (q0, v0) by the scene's own method over t (the adaptive methods to
   their tolerance: their sub-steps then end on tau), until |G| is within the scene's
   ``tolerance`` times (1 + the bodies' distance from the origin), the scale of the
   adaptive methods' error control;
3. at tau apply the collision impulse of the contact points that touch (those within that
   tolerance of the wall), by the contact pass's own law (:meth:`.ContactPass.impact`:
   restitution and Coulomb friction, two points of a manifold solved as one block), to
   the contacts approaching faster than the restitution threshold;
4. finish the step from tau with the new velocities, looking for the next crossing in what
   is left (at most :data:`MAX_EVENTS` impacts per step; after those the contact pass
   handles what remains).

A crossing that approaches slower than the threshold does not bounce: it is left to the
contact pass at the end of the step (resting contact, friction while resting), as without
events; one slower than the threshold at both ends of the step (a resting body sinking by
a step's gravity) is left to it without a root find. Pairs already touching or
overlapping at the start, sleeping bodies and body pairs are the contact pass's too. The
contact pass runs at the end of every step as before. A shape point that passes the
wall and is back out by the step's end (a corner of a fast-turning body) is not seen, by
this or by the contact pass.

Deterministic: the root find is a fixed sequence of floating-point operations. The kernel
has no event location: scenes with ``contacts.events`` on take the Python path of the
simulation (forces and the contact pass may still run compiled), in every build, so a
build with the kernel and one without give the same bits.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from .collision import CirclePart, half_plane_circle, half_plane_polygon
from .solver import Contact, ContactPass

__all__ = ["IMPACT_LOG", "Impact", "MAX_EVENTS", "MAX_ITERATIONS", "WallEvents"]

#: Most impacts located in one step; beyond them (a body trapped between walls, or the
#: accumulating bounces of a ball coming to rest) the contact pass answers the rest.
MAX_EVENTS = 64
#: Most re-integrations of the root find per impact: the Illinois method converges
#: superlinearly, a free fall's gap (a parabola) in 5 to 10.
MAX_ITERATIONS = 60
#: Impacts kept in :attr:`WallEvents.impacts`, the latest.
IMPACT_LOG = 4096

Step = Callable[..., tuple[np.ndarray, np.ndarray]]


class Impact(NamedTuple):
    """A located impact: its time (s), the wall's index and the body's, and the body's
    state (x, y, angle of the CM; vx, vy, omega) right after the impulse."""

    time: float
    wall: int
    body: int
    q: tuple[float, float, float]
    v: tuple[float, float, float]


class WallEvents:
    """Wall impacts located inside the steps of one scene's integrator (see the module)."""

    def __init__(self, contacts: ContactPass, tolerance: float) -> None:
        self.contacts = contacts
        self.tolerance = tolerance
        self.pairs = [(w, b) for w, bodies in enumerate(contacts.wall_bodies) for b in bodies]
        #: The latest impacts located, oldest first (a log, not part of the saved state).
        self.impacts: deque[Impact] = deque(maxlen=IMPACT_LOG)

    def reset(self) -> None:
        self.impacts.clear()

    def gaps(self, q: np.ndarray, pairs: list[tuple[int, int]]) -> list[float]:
        """Each pair's gap at ``q``: the signed distance of the body's shape from the
        wall (negative when it overlaps)."""
        return [gap for gap, _ in self._nearest(q, pairs)]

    def _nearest(self, q: np.ndarray,
                 pairs: list[tuple[int, int]]) -> list[tuple[float, tuple[float, float]]]:
        """Each pair's gap at ``q`` and the body's shape point nearest the wall."""
        contacts = self.contacts
        poses = q.tolist()
        out = []
        for w, b in pairs:
            (nx, ny), offset = contacts.wall_normal[w], contacts.wall_offset[w]
            gap, nearest = math.inf, (0.0, 0.0)
            for part in contacts._world_parts(poses[b], b):
                if isinstance(part, CirclePart):
                    (x, y), radius = part
                    points = [(x - nx * radius, y - ny * radius)]
                else:
                    points = part.vertices
                for x, y in points:
                    distance = nx * x + ny * y - offset
                    if distance < gap:
                        gap, nearest = distance, (x, y)
            out.append((gap, nearest))
        return out

    def _fast(self, q: np.ndarray, v: np.ndarray, pairs: list[tuple[int, int]]) -> list[bool]:
        """Per pair, whether the body's point nearest the wall approaches it faster than
        the restitution threshold, v_P = v + omega perp(r) (Eq. 9) along the normal."""
        contacts = self.contacts
        poses, velocities = q.tolist(), v.tolist()
        out = []
        for (w, b), (_, (px, py)) in zip(pairs, self._nearest(q, pairs)):
            nx, ny = contacts.wall_normal[w]
            x, y, _ = poses[b]
            vx, vy, omega = velocities[b]
            normal = (vx - omega * (py - y)) * nx + (vy + omega * (px - x)) * ny
            out.append(normal < -contacts.threshold)
        return out

    def step(self, step: Step, f: Callable[..., Any], q: np.ndarray, v: np.ndarray, h: float,
             start: float) -> tuple[np.ndarray, np.ndarray]:
        """``step(f, q, v, h)`` (an integrator's step) from time ``start`` (s), with the
        wall impacts inside it located and answered (see the module). The log of impacts
        forgets those after ``start``: they belonged to a step taken again (split into
        sub-steps, or refused by the energy bound). None can be at ``start`` itself: a
        pair touching at the start is not watched."""
        while self.impacts and self.impacts[-1].time > start:
            self.impacts.pop()
        contacts = self.contacts
        asleep = set(contacts.sleeping()) if contacts.sleep else set()
        watched = [pair for pair in self.pairs if pair[1] not in asleep]
        q1, v1 = step(f, q, v, h)
        slow: set[tuple[int, int]] = set()  # crossings too slow to bounce: the pass's
        for _ in range(MAX_EVENTS):
            if not (np.isfinite(q1).all() and np.isfinite(v1).all()):
                break  # the simulation's divergence check reports it
            candidates = [pair for pair in watched if pair not in slow]
            before = self.gaps(q, candidates)
            crossing = [(pair, gap) for pair, gap in zip(candidates, before) if gap > 0.0]
            after = self.gaps(q1, [pair for pair, _ in crossing])
            crossing = [(pair, gap) for (pair, gap), end in zip(crossing, after) if end < 0.0]
            # A crossing slower than the threshold at both ends (a resting body sinking by
            # a step's gravity) will not bounce: the contact pass's, with no root find.
            pairs = [pair for pair, _ in crossing]
            fast = [start_fast or end_fast for start_fast, end_fast in
                    zip(self._fast(q, v, pairs), self._fast(q1, v1, pairs))]
            slow.update(pair for pair, quick in zip(pairs, fast) if not quick)
            crossing = [entry for entry, quick in zip(crossing, fast) if quick]
            if not crossing:
                break
            pairs = [pair for pair, _ in crossing]
            delta = self.tolerance * (1.0 + max(math.hypot(q[b, 0], q[b, 1]) for _, b in pairs))
            tau, qt, vt = self._locate(step, f, q, v, h, pairs,
                                       min(gap for _, gap in crossing), q1, v1, delta)
            touching = [pair for pair, gap in zip(pairs, self.gaps(qt, pairs)) if gap <= delta]
            found = self._contacts(qt, touching, 2.0 * delta)
            if not contacts.impact(qt, vt, found):
                slow.update(touching)
                continue
            now = start + tau
            for w, b in touching:
                self.impacts.append(Impact(now, w, b, tuple(qt[b].tolist()),
                                           tuple(vt[b].tolist())))
            q, v, h, start = qt, vt, h - tau, now
            q1, v1 = (step(f, q, v, h) if h > 0.0 else (q.copy(), v.copy()))
        return q1, v1

    def _locate(self, step: Step, f: Callable[..., Any], q: np.ndarray, v: np.ndarray, h: float,
                pairs: list[tuple[int, int]], g0: float, q1: np.ndarray, v1: np.ndarray,
                delta: float) -> tuple[float, np.ndarray, np.ndarray]:
        """The first time in (0, h] at which the smallest gap of ``pairs`` (``g0`` > 0 at
        the start, negative at the end state (``q1``, ``v1``)) is within ``delta`` of zero,
        and the state there, by the Illinois method on re-integrated states."""
        a, ga = 0.0, g0
        b, gb, qb, vb = h, min(self.gaps(q1, pairs)), q1, v1
        side = 0  # which end moved last: +1 b, -1 a; twice the same end halves the other's G
        for _ in range(MAX_ITERATIONS):
            t = b - gb * (b - a) / (gb - ga)
            if not a < t < b:  # rounding at a bracket that has shrunk to a few ulps
                break
            qt, vt = step(f, q, v, t)
            gt = min(self.gaps(qt, pairs))
            if abs(gt) <= delta:
                return t, qt, vt
            if gt < 0.0:
                b, gb, qb, vb = t, gt, qt, vt
                if side == 1:
                    ga *= 0.5
                side = 1
            else:
                a, ga = t, gt
                if side == -1:
                    gb *= 0.5
                side = -1
        return b, qb, vb

    def _contacts(self, q: np.ndarray, pairs: list[tuple[int, int]],
                  margin: float) -> list[Contact]:
        """The contact points of ``pairs`` at ``q`` closer than ``margin`` to their walls,
        as the contact pass's detection gives them (points halfway between the surfaces)."""
        contacts = self.contacts
        poses = q.tolist()
        found = []
        for w, b in pairs:
            nx, ny = contacts.wall_normal[w]
            normal, offset = (nx, ny), contacts.wall_offset[w]
            e, mu = contacts.wall_material[w]
            for p, part in enumerate(contacts._world_parts(poses[b], b)):
                points = (half_plane_circle(normal, offset, *part, margin)
                          if isinstance(part, CirclePart)
                          else half_plane_polygon(normal, offset, part.vertices, margin))
                for point, n, depth in points:
                    found.append(Contact(-1, b, point, n, depth, e, mu, (-1 - w, b, 0, p)))
        return found
