"""A differential drive: two wheels pushing at their contact points, under PI control.

Every control period the drive measures the body's velocity at its wheel axle's centre C,
v_C = v_CM + omega perp(r_C) (a body point's velocity, Eq. 9), takes its forward
component u along the body's x axis and the angular velocity omega, and asks for a forward
force F = kp_v e_v + ki_v integral(e_v) and a torque T = kp_w e_w + ki_w integral(e_w)
from the errors against the commanded twist. Two wheels s apart on the axle share them:
F_right = F / 2 + T / s and F_left = F / 2 - T / s give the force F and, as their torque
about C, (F_right - F_left) s / 2 = T; each is capped at the motor's ``max_force``, and the
integrals stop growing while a wheel is capped (no wind-up). A wheel grips sideways with
``lateral_damping`` times its sideways slip speed, and its whole force is capped at
``traction``. The wheel forces are wrench commands in the body frame at the contact points,
held for one control period: like every input, each adds its force to the CM's
acceleration (Eq. 5) and its torque, the perp-dot of its offset and force (Eq. 11), to the
angular acceleration (Eq. 14).
"""
from __future__ import annotations

import math

import numpy as np

from ..geometry.shapes import MassProperties
from ..scene.commands import WrenchCommand
from ..scene.drives import DiffDriveSpec
from .command import CommandedDrive, VelocityCommand

__all__ = ["DiffDrive", "VelocityCommand"]


class DiffDrive(CommandedDrive):
    """The controller of one ``diff_drive``: its last command and its integrals."""

    def __init__(self, spec: DiffDriveSpec, body_index: int, cm_local: np.ndarray,
                 properties: MassProperties) -> None:
        """``body_index`` is the driven body's row in the state, ``cm_local`` its CM in its
        body frame, ``properties`` its mass and inertia."""
        super().__init__(spec, body_index, 2, properties)
        self.spec = spec
        cx, cy = spec.center
        half = spec.separation / 2.0
        #: Contact points (body frame) of the left and right wheels.
        self.wheels = ((cx, cy + half), (cx, cy - half))
        #: The sources of the left and right wheels' commands.
        self.sources = (f"drive/{spec.name}/left", f"drive/{spec.name}/right")
        # Plain floats: the controller runs at every control instant, on a few numbers.
        self._offsets = [(np.asarray(w, dtype=float) - cm_local).tolist() for w in self.wheels]
        self._axle = (np.asarray(spec.center, dtype=float) - cm_local).tolist()

    def wrenches(self, q: np.ndarray, v: np.ndarray, time_ns: int) -> list[WrenchCommand]:
        """The wheel forces for the control period starting at ``time_ns``, from the CM
        state (q, v) (N, 3), updating the integrals."""
        spec = self.spec
        theta = float(q[self.body, 2])
        vx, vy, omega = v[self.body].tolist()
        c, s = math.cos(theta), math.sin(theta)
        if self.active(time_ns):
            assert self.command is not None
            period = spec.period_ns * 1e-9
            # The axle centre's velocity, a body point's velocity (Eq. 9), in body axes:
            # v_C = v_CM + omega perp(r_C), turned back by -theta.
            u = c * vx + s * vy - omega * self._axle[1]
            error_v, error_w = self.command.linear_x - u, self.command.angular_z - omega
            integral_v, integral_w = self.integrals
            force = spec.linear_kp * error_v + spec.linear_ki * (integral_v + error_v * period)
            torque = spec.angular_kp * error_w + spec.angular_ki * (
                integral_w + error_w * period)
            wanted_left = force / 2.0 - torque / spec.separation
            wanted_right = force / 2.0 + torque / spec.separation
            limit = spec.max_force
            left = min(max(wanted_left, -limit), limit)
            right = min(max(wanted_right, -limit), limit)
            # Conditional integration: no wind-up while capped. A NaN passes the caps as
            # itself, and counts as uncapped (as the same object compares equal in a list).
            if (left is wanted_left or left == wanted_left) and \
                    (right is wanted_right or right == wanted_right):
                self.integrals = [integral_v + error_v * period, integral_w + error_w * period]
        else:
            left = right = 0.0
            self.integrals = [0.0, 0.0]
        body, duration = spec.body, spec.period_ns
        (left_point, right_point), (left_source, right_source) = self.wheels, self.sources
        # The sideways slip: the body-y component of the wheel's point's velocity (Eq. 9).
        across = -s * vx + c * vy
        return [WrenchCommand(time_ns, body, left_source, body, left_point,
                              self._grip(left, across + omega * self._offsets[0][0]), 0.0,
                              duration),
                WrenchCommand(time_ns, body, right_source, body, right_point,
                              self._grip(right, across + omega * self._offsets[1][0]), 0.0,
                              duration)]

    def kernel_offsets(self) -> tuple[float, float, float]:
        """What the kernel's twin of :meth:`wrenches` takes of the wheels' places (src/kernel/
        drive.h): the axle centre's y and each wheel's x from the CM, body frame."""
        return self._axle[1], self._offsets[0][0], self._offsets[1][0]

    def _grip(self, push: float, slip: float) -> tuple[float, float]:
        """A wheel's force in body axes: its ``push`` forward and the lateral damping's grip
        against its sideways ``slip`` speed, the whole capped at the traction."""
        spec = self.spec
        grip = -spec.lateral_damping * slip
        scale = min(1.0, spec.traction / math.hypot(push, grip)) if (push or grip) else 1.0
        return (push * scale, grip * scale)
