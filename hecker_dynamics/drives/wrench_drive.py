"""An omnidirectional base or a set of thrusters: actuators pushing at their points along
fixed directions, under PI control of the whole body-frame twist.

Every control period the drive measures the velocity of its ``center`` C in body axes,
v_C = v_CM + omega perp(r_C) (a body point's velocity, Eq. 9), and asks for a body-frame
force F = kp_v e_v + ki_v integral(e_v) (x and y) and a torque about the CM
T = kp_w e_w + ki_w integral(e_w) from the errors against the commanded twist. Actuator i
at p_i pushing with magnitude f_i along the unit direction d_i gives the force f_i d_i and
the torque perp_dot(p_i - CM, d_i) f_i (Eq. 11), so the pushes f solve A f = (F, T) with
A's columns (d_i, perp_dot(p_i - CM, d_i)):

- ``omni``: wheels push either way; f is the least-norm exact solution (the pseudo-inverse
  of A, which the scene checks has rank 3);
- ``thrusters``: each pushes forward only; f >= 0 is the non-negative least-squares
  solution (Lawson and Hanson's active-set method), the nearest wrench they can make.

If a push exceeds ``max_force`` all of them are scaled down together, which keeps the
wrench's direction, and the integrals stop growing (no wind-up). Each push is a wrench
command in the body frame at its point, held for one control period: its force adds to
the CM's acceleration (Eq. 5), its torque to the angular acceleration (Eq. 14).
"""
from __future__ import annotations

import math

import numpy as np

from ..geometry.shapes import MassProperties
from ..scene.commands import WrenchCommand
from ..scene.drives import WrenchDriveSpec, actuation
from .command import CommandedDrive

__all__ = ["WrenchDrive", "nonnegative_least_squares"]


def nonnegative_least_squares(a: np.ndarray, b: np.ndarray, tolerance: float = 1e-12
                              ) -> np.ndarray:
    """x >= 0 minimising |a x - b| (Lawson and Hanson's active-set method)."""
    n = a.shape[1]
    x = np.zeros(n)
    passive = np.zeros(n, dtype=bool)
    for _ in range(3 * n):
        gradient = a.T @ (b - a @ x)
        if passive.all() or np.max(np.where(passive, -np.inf, gradient)) <= tolerance:
            break
        passive[int(np.argmax(np.where(passive, -np.inf, gradient)))] = True
        while True:
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(a[:, passive], b, rcond=None)[0]
            if (z[passive] > 0.0).all():
                x = z
                break
            blocking = passive & (z <= 0.0)
            step = np.min(x[blocking] / (x[blocking] - z[blocking]))
            x = x + step * (z - x)
            passive &= x > tolerance
            x[~passive] = 0.0
    return x


class WrenchDrive(CommandedDrive):
    """The controller of one ``omni`` or ``thrusters`` drive."""

    def __init__(self, spec: WrenchDriveSpec, body_index: int, cm_local: np.ndarray,
                 properties: MassProperties) -> None:
        """``body_index`` is the driven body's row in the state, ``cm_local`` its CM in its
        body frame, ``properties`` its mass and inertia."""
        super().__init__(spec, body_index, 3, properties)
        self.spec = spec
        cm = (float(cm_local[0]), float(cm_local[1]))
        self._actuation = actuation(spec.actuators, cm)
        self._inverse = np.linalg.pinv(self._actuation) if spec.kind == "omni" else None
        self._center = np.asarray(spec.center, dtype=float) - cm_local
        self._directions = [(math.cos(angle), math.sin(angle)) for _, _, angle in spec.actuators]
        self._sources = [f"drive/{spec.name}/{index}" for index in range(len(spec.actuators))]

    def pushes(self, wrench: np.ndarray) -> np.ndarray:
        """The actuators' push magnitudes that make the body-frame ``wrench`` (Fx, Fy,
        torque about the CM) as closely as they can, before the cap."""
        if self._inverse is not None:
            return self._inverse @ wrench
        return nonnegative_least_squares(self._actuation, wrench)

    def wrenches(self, q: np.ndarray, v: np.ndarray, time_ns: int) -> list[WrenchCommand]:
        """The pushes for the control period starting at ``time_ns``, from the CM state
        (q, v) (N, 3), updating the integrals."""
        spec = self.spec
        pushes = np.zeros(len(spec.actuators))
        if self.active(time_ns):
            assert self.command is not None
            theta, omega = q[self.body, 2], v[self.body, 2]
            c, s = math.cos(theta), math.sin(theta)
            vx, vy = v[self.body, 0], v[self.body, 1]
            rx, ry = self._center
            # The centre's velocity, a body point's velocity (Eq. 9), in body axes: v_CM
            # turned by -theta, plus omega perp(r_C).
            measured = (c * vx + s * vy - omega * ry, -s * vx + c * vy + omega * rx, omega)
            wanted = (self.command.linear_x, self.command.linear_y, self.command.angular_z)
            errors = [w - m for w, m in zip(wanted, measured)]
            period = spec.period_ns * 1e-9
            gains = ((spec.linear_kp, spec.linear_ki),) * 2 + ((spec.angular_kp,
                                                                 spec.angular_ki),)
            wrench = np.array([kp * e + ki * (i + e * period)
                               for (kp, ki), e, i in zip(gains, errors, self.integrals)])
            pushes = self.pushes(wrench)
            largest = float(np.max(np.abs(pushes)))
            if largest > spec.max_force:
                pushes = pushes * (spec.max_force / largest)
            else:  # conditional integration: no wind-up while capped
                self.integrals = [i + e * period for i, e in zip(self.integrals, errors)]
        else:
            self.integrals = [0.0, 0.0, 0.0]
        return [WrenchCommand(stamp_ns=time_ns, body=spec.body, source=source,
                              frame_id=spec.body, point=(x, y), force=(push * dx, push * dy),
                              duration_ns=spec.period_ns)
                for source, (x, y, _), (dx, dy), push in zip(
                    self._sources, spec.actuators, self._directions, pushes.tolist())]
