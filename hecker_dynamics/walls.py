"""Walls: fixed half-planes that bodies bounce off, with rotation.

After each step, every shape point that has crossed a wall becomes a contact. The response
is the collision impulse of the article series, applied at the contact point so that it
turns the body as well as stopping it:

    j = -(1 + e) v_rel . n / (1/M + (perp(r) . n)^2 / I)

with r the offset from the CM to the contact point. Several contacts of one body are
solved together by sequential impulses with accumulated, clamped totals (the form Box2D
uses), which converges to the simultaneous solution; Coulomb friction bounds the
tangential impulse by mu times the normal one. Approaches slower than the restitution
threshold do not bounce, so a resting body neither jitters nor gains energy. Finally the
body is moved out along the wall normal by its depth: a change of position only, which
adds no kinetic energy.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .geometry import Circle
from .planar import rotate

if TYPE_CHECKING:
    from .model import Model
    from .scene import WallSpec

MAX_ITERATIONS = 50
CONVERGED = 1e-14


class WallContacts:
    """The contact pass between the bodies' shapes and the scene's walls."""

    def __init__(self, model: Model, walls: tuple[WallSpec, ...], threshold: float) -> None:
        self.normal = np.array([w.normal for w in walls])  # (W, 2)
        self.offset = np.einsum("wi,wi->w", self.normal, np.array([w.point for w in walls]))
        self.restitution = np.array([w.restitution for w in walls])
        self.friction = np.array([w.friction for w in walls])
        self.threshold = threshold
        self.inverse_mass = 1.0 / model.mass
        self.inverse_inertia = 1.0 / model.inertia
        applies = np.zeros((len(walls), model.size), dtype=bool)
        for w, wall in enumerate(walls):
            applies[w, [model.index[name] for name in wall.bodies]] = True
        body, local, radius = [], [], []
        for i, spec in enumerate(model.scene.bodies):
            for shape in spec.shapes:
                if isinstance(shape, Circle):
                    points, r = [shape.center], shape.radius
                else:
                    points, r = shape.vertices, 0.0
                for point in points:
                    body.append(i)
                    local.append(model.local(i, point))
                    radius.append(r)
        self.feature_body = np.array(body)
        self.feature_local = np.array(local)
        self.feature_radius = np.array(radius)
        self.applies = applies[:, self.feature_body].T  # (F, W)
        self.bodies = np.unique(self.feature_body[self.applies.any(axis=1)])

    def depths(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World offsets r of the features from their CMs, and penetration depths (F, W)."""
        body = self.feature_body
        r = rotate(self.feature_local, np.cos(q[body, 2]), np.sin(q[body, 2]))
        reach = (q[body, :2] + r) @ self.normal.T - self.feature_radius[:, None]
        return r, np.where(self.applies, self.offset[None, :] - reach, -np.inf)

    def resolve(self, q: np.ndarray, v: np.ndarray) -> None:
        """Apply contact impulses to ``v`` and push bodies out of walls in ``q``, in place."""
        r, depth = self.depths(q)
        touching = np.argwhere(depth > 0.0)
        if len(touching) == 0:
            return
        for body in np.unique(self.feature_body[touching[:, 0]]):
            rows = touching[self.feature_body[touching[:, 0]] == body]
            feature, wall = rows[:, 0], rows[:, 1]
            normal = self.normal[wall]
            arm = r[feature] - self.feature_radius[feature, None] * normal
            self._impulses(body, arm, normal, wall, v)
            for w in np.unique(wall):
                q[body, :2] += depth[feature[wall == w], w].max() * self.normal[w]

    def _impulses(self, body: int, arm: np.ndarray, normal: np.ndarray, wall: np.ndarray,
                  v: np.ndarray) -> None:
        """Sequential impulses for one body's contacts (normal with restitution, friction).

        Plain floats: a body touches walls at a handful of points, where numpy's per-call
        overhead would dominate.
        """
        inv_m, inv_i = float(self.inverse_mass[body]), float(self.inverse_inertia[body])
        vx, vy, w = (float(x) for x in v[body])
        contacts = []
        for (rx, ry), (nx, ny), index in zip(arm.tolist(), normal.tolist(), wall.tolist()):
            rn, rt = rx * ny - ry * nx, -rx * nx - ry * ny  # perp(r).n and perp(r).t, t = perp(n)
            approach = (vx - w * ry) * nx + (vy + w * rx) * ny
            bounce = self.restitution[index] if approach < -self.threshold else 0.0
            contacts.append([rx, ry, nx, ny, 1.0 / (inv_m + rn * rn * inv_i),
                             1.0 / (inv_m + rt * rt * inv_i), -bounce * approach,
                             float(self.friction[index]), 0.0, 0.0])
        for _ in range(MAX_ITERATIONS):
            largest = 0.0
            for c in contacts:
                rx, ry, nx, ny, mass_n, mass_t, target, mu, total_n, total_t = c
                vn = (vx - w * ry) * nx + (vy + w * rx) * ny
                new_n = max(total_n + (target - vn) * mass_n, 0.0)
                jn = new_n - total_n
                jt = 0.0
                if mu > 0.0:
                    # tangent t = perp(n) = (-ny, nx); velocity after the normal impulse
                    ux = vx + jn * nx * inv_m - (w + jn * (rx * ny - ry * nx) * inv_i) * ry
                    uy = vy + jn * ny * inv_m + (w + jn * (rx * ny - ry * nx) * inv_i) * rx
                    bound = mu * new_n
                    new_t = min(max(total_t - (-ux * ny + uy * nx) * mass_t, -bound), bound)
                    jt = new_t - total_t
                    c[9] = new_t
                c[8] = new_n
                px, py = jn * nx - jt * ny, jn * ny + jt * nx
                vx += px * inv_m
                vy += py * inv_m
                w += (rx * py - ry * px) * inv_i
                largest = max(largest, abs(jn), abs(jt))
            if largest * inv_m <= CONVERGED * (1.0 + abs(vx) + abs(vy) + abs(w)):
                break
        v[body] = (vx, vy, w)
