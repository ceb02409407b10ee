"""The bouncing ball's exact solution, the benchmark's contact case with a closed form.

A circle of radius r, its center dropped from rest at height h0 above a horizontal wall
(the floor, normal up) under gravity g, bounces without friction or spin with restitution
e: each impact keeps e of the normal speed (the article series' collision impulse
j = -(1 + e) v_rel.n / (1/M), a wall having no mass). With d = h0 - r the first fall,

- the first impact at t_1 = sqrt(2 d / g), speed v_1 = sqrt(2 g d);
- after the k-th impact (k >= 1) the ball leaves upwards at u_k = e^k v_1, flies
  2 u_k / g, so t_(k+1) = t_k + 2 e^k v_1 / g, i.e. t_k = t_1 + 2 v_1 e (1 - e^(k-1)) /
  (g (1 - e));
- the apex after the k-th impact: center height r + e^(2k) d at t_k + u_k / g;
- between impacts the free flight y(t) = r + u_k (t - t_k) - g (t - t_k)^2 / 2,
  v(t) = u_k - g (t - t_k) (before t_1: y = h0 - g t^2 / 2).

For e < 1 the impacts accumulate at the Zeno time t_inf = t_1 + 2 v_1 e / (g (1 - e)),
after which the ball rests on the floor (y = r, v = 0): :meth:`BallDrop.state` says so.
A simulation stops bouncing earlier, when the approach speed falls below its restitution
threshold, so comparisons use the first few impacts only, well before t_inf.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..scene.load import Scene, scene_from_parameters
from ..scene.parameters import flatten

__all__ = ["BallDrop", "ball_drop_scene"]


@dataclass(frozen=True)
class BallDrop:
    """The closed form of a ball of radius ``radius`` whose center starts at rest at
    ``height`` above the floor, under ``gravity`` (m/s^2, > 0), with ``restitution`` e in
    [0, 1)."""

    height: float
    radius: float
    gravity: float
    restitution: float

    @property
    def first_fall(self) -> float:
        """d = h0 - r, the height the ball's bottom falls before the first impact (m)."""
        return self.height - self.radius

    @property
    def impact_speed(self) -> float:
        """v_1 = sqrt(2 g d), the speed of the first impact."""
        return math.sqrt(2.0 * self.gravity * self.first_fall)

    def impact_time(self, k: int) -> float:
        """t_k, the time of the k-th impact (k >= 1)."""
        e, g, v1 = self.restitution, self.gravity, self.impact_speed
        t1 = math.sqrt(2.0 * self.first_fall / g)
        return t1 + 2.0 * v1 / g * sum(e ** j for j in range(1, k))

    def apex_height(self, k: int) -> float:
        """The center's height at the apex after the k-th impact: r + e^(2k) d (k = 0:
        the drop height)."""
        return self.radius + self.restitution ** (2 * k) * self.first_fall

    def apex_time(self, k: int) -> float:
        """When the ball reaches :meth:`apex_height` ``k`` (k = 0: the start)."""
        if k == 0:
            return 0.0
        return self.impact_time(k) + self.restitution ** k * self.impact_speed / self.gravity

    @property
    def zeno_time(self) -> float:
        """t_inf, where the impacts accumulate (inf for e = 1)."""
        e = self.restitution
        if e >= 1.0:
            return math.inf
        return self.impact_time(1) + 2.0 * self.impact_speed * e / (self.gravity * (1.0 - e))

    def state(self, t: float) -> tuple[float, float]:
        """The center's height and vertical velocity at time ``t`` >= 0 (at an impact
        instant, the velocity after it); at rest on the floor from :attr:`zeno_time`."""
        g = self.gravity
        t1 = self.impact_time(1)
        if t < t1:
            return self.height - 0.5 * g * t * t, -g * t
        if t >= self.zeno_time:
            return self.radius, 0.0
        # The k-th flight starts at t_k; k from the geometric sum, then checked against
        # rounding at the ends of the flight.
        k, start = 1, t1
        while True:
            flight = 2.0 * self.restitution ** k * self.impact_speed / g
            if t < start + flight or flight == 0.0:
                break
            k, start = k + 1, start + flight
        u = self.restitution ** k * self.impact_speed
        s = t - start
        return self.radius + u * s - 0.5 * g * s * s, u - g * s

    def energy_ratio(self) -> float:
        """The mechanical energy (above the resting height) after an impact over that
        before: e^2."""
        return self.restitution ** 2


def ball_drop_scene(drop: BallDrop, step: float, integrator: str, *, tolerance: float = 1e-6,
                    events: bool = False, duration: float = 2.0,
                    extra: dict[str, Any] | None = None) -> Scene:
    """``drop`` as a scene: one ball of 1 kg on a frictionless floor with restitution e,
    gravity along -y, stepped by ``integrator`` at ``step`` (``tolerance`` for the adaptive
    methods), with the floor's impacts located inside the step where ``events`` is on
    (``contacts.events``)."""
    params: dict[str, Any] = {
        "step": step, "integrator": integrator, "tolerance": tolerance,
        "duration": duration, "publish_rate": 1.0 / step,
        "contacts": {"events": events},
        "bodies": {"ball": {"shape": "circle", "radius": drop.radius, "mass": 1.0,
                            "position": [0.0, drop.height]}},
        "forces": {"g": {"type": "gravity", "acceleration": [0.0, -drop.gravity]}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                            "restitution": drop.restitution, "friction": 0.0}},
        **(extra or {}),
    }
    return scene_from_parameters(flatten(params), "ball_drop")
