"""What every drive keeps between control instants: its last velocity command (a
body-frame twist with its arrival time, which the cmd_vel timeout measures from) and the
integrals of its PI controller's errors."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..geometry.shapes import MassProperties
from ..scene.commands import InputError
from ..scene.drives import DriveSpec

__all__ = ["VelocityCommand", "CommandedDrive"]


@dataclass(frozen=True)
class VelocityCommand:
    """A body-frame twist command: forward speed (m/s), angular velocity (rad/s) and
    sideways speed (m/s; only an omnidirectional base or thrusters follow it), received at
    sim time ``stamp_ns``."""

    stamp_ns: int
    linear_x: float
    angular_z: float
    linear_y: float = 0.0


class CommandedDrive:
    """A drive's command and its controller's integrals (``axes`` of them); ``body_index``
    is the driven body's row in the state, ``properties`` its mass and inertia."""

    def __init__(self, spec: DriveSpec, body_index: int, axes: int,
                 properties: MassProperties) -> None:
        self.name = spec.name
        self.timeout_ns = spec.cmd_vel_timeout_ns
        self.body = body_index
        self._properties = properties
        self.command: VelocityCommand | None = None
        self.integrals = [0.0] * axes

    def receive(self, command: VelocityCommand) -> None:
        """Take a new twist command (:meth:`check` first); it replaces the previous one."""
        self.check(command)
        self.command = command

    def check(self, command: VelocityCommand) -> None:
        """:class:`InputError` for a value that is not finite, or a twist whose energy of
        motion on the driven body (1/2 m v^2 + 1/2 I omega^2) no double holds: the
        controller's errors would overflow, and the wheel forces mixed from them would be
        inf - inf."""
        values = (command.linear_x, command.linear_y, command.angular_z)
        if not all(map(math.isfinite, values)):
            raise InputError(f"drive '{self.name}': a cmd_vel with a non-finite value "
                             f"{values}")
        speed = math.hypot(command.linear_x, command.linear_y)
        if not math.isfinite(self._properties.energy_of_motion(speed, command.angular_z)):
            raise InputError(f"drive '{self.name}': a cmd_vel of {values} asks its body for "
                             "an energy of motion past what a double holds")

    def export_state(self) -> dict[str, Any]:
        """The controller's state, for keyframes (a command's sideways speed only when it
        is not zero, so a differential drive's keyframes keep their form)."""
        c = self.command
        command = None if c is None else [c.stamp_ns, c.linear_x, c.angular_z] + (
            [c.linear_y] if c.linear_y else [])
        return {"integrals": list(self.integrals), "command": command}

    def import_state(self, state: dict[str, Any]) -> None:
        self.integrals = [float(x) for x in state["integrals"]]
        c = state["command"]
        command = None if c is None else VelocityCommand(
            int(c[0]), float(c[1]), float(c[2]), float(c[3]) if len(c) > 3 else 0.0)
        if command is not None:
            self.check(command)
        self.command = command

    def active(self, time_ns: int) -> bool:
        """Whether a command younger than the cmd_vel timeout holds at ``time_ns``."""
        c, timeout = self.command, self.timeout_ns
        return c is not None and (timeout == 0 or time_ns - c.stamp_ns < timeout)
