"""Velocity commands in, as plain fields (no ROS import): the ``geometry_msgs/Twist``
topic of each driven body (:func:`~.names.cmd_vel_topic`) and what a message does."""
from __future__ import annotations

import math
from typing import Any, NamedTuple

from ..drives.command import VelocityCommand
from ..drives.control import DriveSet
from ..drives.wrench_drive import WrenchDrive
from ..scene.commands import InputError
from ..scene.load import Scene
from .names import cmd_vel_topic

__all__ = ["CmdVelTopic", "cmd_vel_topics", "take_cmd_vel"]


class CmdVelTopic(NamedTuple):
    """A driven body's command topic: ``geometry_msgs/Twist`` messages (body frame) whose
    ``linear.x`` and ``angular.z`` every drive of ``body`` follows, and ``linear.y`` its
    omnidirectional bases and thrusters."""

    body: str
    topic: str


def cmd_vel_topics(scene: Scene) -> tuple[CmdVelTopic, ...]:
    """The command topic of each driven body, in the order of the scene's drives."""
    bodies = dict.fromkeys(drive.body for drive in scene.drives)
    return tuple(CmdVelTopic(body, cmd_vel_topic(body)) for body in bodies)


def take_cmd_vel(drives: DriveSet, source: CmdVelTopic, msg: Any, time_ns: int) -> list[str]:
    """Give the twist ``msg`` to the drives of its body at sim time ``time_ns``; returns
    warnings about the parts a planar drive ignores. Raises :class:`InputError` for a
    value that is not finite."""
    linear, angular = msg.linear, msg.angular
    values = (linear.x, linear.y, linear.z, angular.x, angular.y, angular.z)
    if not all(math.isfinite(float(x)) for x in values):
        raise InputError(f"a cmd_vel for '{source.body}' has a non-finite value {values}")
    drives.receive(source.body, VelocityCommand(time_ns, float(linear.x), float(angular.z),
                                                float(linear.y)))
    sideways = any(isinstance(drive, WrenchDrive) and drive.spec.body == source.body
                   for drive in drives.drives)
    ignored = [name for name, x in zip(("linear.y", "linear.z", "angular.x", "angular.y"),
                                       values[1:5]) if x != 0.0 and not (sideways and
                                                                          name == "linear.y")]
    drive = "its drives ignore" if sideways else "a differential drive ignores"
    return ([f"cmd_vel for '{source.body}': {drive} {', '.join(ignored)}"] if ignored else [])
