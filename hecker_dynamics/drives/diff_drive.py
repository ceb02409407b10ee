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

from ..scene.commands import WrenchCommand
from ..scene.drives import DiffDriveSpec
from .command import CommandedDrive, VelocityCommand

__all__ = ["DiffDrive", "VelocityCommand"]


class DiffDrive(CommandedDrive):
    """The controller of one ``diff_drive``: its last command and its integrals."""

    def __init__(self, spec: DiffDriveSpec, body_index: int, cm_local: np.ndarray) -> None:
        """``body_index`` is the driven body's row in the state, ``cm_local`` its CM in its
        body frame."""
        super().__init__(spec, body_index, 2)
        self.spec = spec
        cx, cy = spec.center
        half = spec.separation / 2.0
        #: Contact points (body frame) of the left and right wheels.
        self.wheels = ((cx, cy + half), (cx, cy - half))
        self._sources = (f"drive/{spec.name}/left", f"drive/{spec.name}/right")
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
        period = spec.period_ns * 1e-9
        if self.active(time_ns):
            assert self.command is not None
            # The axle centre's velocity, a body point's velocity (Eq. 9), in body axes:
            # v_C = v_CM + omega perp(r_C), turned back by -theta.
            u = c * vx + s * vy - omega * self._axle[1]
            errors = (self.command.linear_x - u, self.command.angular_z - omega)
            force = spec.linear_kp * errors[0] + spec.linear_ki * (
                self.integrals[0] + errors[0] * period)
            torque = spec.angular_kp * errors[1] + spec.angular_ki * (
                self.integrals[1] + errors[1] * period)
            wanted = (force / 2.0 - torque / spec.separation,
                      force / 2.0 + torque / spec.separation)
            pushes = [min(max(f, -spec.max_force), spec.max_force) for f in wanted]
            if pushes == list(wanted):  # conditional integration: no wind-up while capped
                self.integrals = [i + e * period for i, e in zip(self.integrals, errors)]
        else:
            pushes = [0.0, 0.0]
            self.integrals = [0.0, 0.0]
        commands = []
        for source, wheel, offset, push in zip(self._sources, self.wheels, self._offsets,
                                               pushes):
            # The sideways slip: the body-y component of the wheel's point's velocity (Eq. 9).
            slip = -s * vx + c * vy + omega * offset[0]
            grip = -spec.lateral_damping * slip
            scale = min(1.0, spec.traction / math.hypot(push, grip)) if (push or grip) else 1.0
            commands.append(WrenchCommand(
                stamp_ns=time_ns, body=spec.body, source=source,
                frame_id=spec.body, point=wheel, force=(push * scale, grip * scale),
                duration_ns=spec.period_ns))
        return commands
