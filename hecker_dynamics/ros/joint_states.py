"""Joint states out and motor speeds in, as plain fields (no ROS import).

:func:`joint_state_fields` gives the fields of a ``sensor_msgs/JointState`` for the
scene's revolute and prismatic joints (position, velocity and the effort of their motors,
limits and springs over the last step), which the node would publish on ``joint_states``;
:func:`set_motor_speed` holds a new target speed for a joint's motor.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional

from ..dynamics.simulation import Simulation, Snapshot
from ..scene.commands import InputError
from ..scene.joints import PrismaticJoint, RevoluteJoint, motor_overflow
from ..scene.load import Scene
from .fields import Header, header
from .names import motor_topic

__all__ = ["JointStateFields", "MotorTopic", "has_joint_states", "joint_state_fields",
           "motor_topics", "snapshot_joint_states", "set_motor_speed"]


class MotorTopic(NamedTuple):
    """A motor's command topic (:func:`~.names.motor_topic`): ``std_msgs/Float64`` messages
    whose ``data`` is the target speed of ``joint``'s motor, held until the next one."""

    joint: str
    topic: str


def motor_topics(scene: Scene) -> tuple[MotorTopic, ...]:
    """The command topic of each motor of ``scene``, joints sorted by name."""
    return tuple(MotorTopic(j.name, motor_topic(j.name)) for j in scene.joints
                 if isinstance(j, (RevoluteJoint, PrismaticJoint)) and j.motor is not None)


class JointStateFields(NamedTuple):
    header: Header
    name: tuple[str, ...]
    position: tuple[float, ...]  # rad or m
    velocity: tuple[float, ...]  # rad/s or m/s
    effort: tuple[float, ...]  # N m or N


def has_joint_states(scene: Scene) -> bool:
    """True if ``scene`` has revolute or prismatic joints, whose states the node publishes."""
    return any(isinstance(j, (RevoluteJoint, PrismaticJoint)) for j in scene.joints)


def snapshot_joint_states(frame_id: str, snapshot: Snapshot) -> Optional[JointStateFields]:
    """The JointState of a snapshot, joints sorted by name; None for a scene without
    revolute or prismatic joints."""
    state = snapshot.joints
    if not state:
        return None
    names = tuple(sorted(state))
    position, velocity, effort = (tuple(float(state[n][i]) for n in names) for i in range(3))
    return JointStateFields(header(frame_id, snapshot.time_ns), names, position, velocity,
                            effort)


def joint_state_fields(sim: Simulation, stamp_ns: int) -> Optional[JointStateFields]:
    """The JointState of the simulation's current state, stamped ``stamp_ns``."""
    fields = snapshot_joint_states(sim.scene.frame_id, sim.snapshot())
    return None if fields is None else fields._replace(header=header(sim.scene.frame_id,
                                                                      stamp_ns))


def set_motor_speed(sim: Simulation, joint: str, speed: float) -> None:
    """Drive the motor of ``joint`` at ``speed`` from the next step on; raises
    :class:`InputError` (and changes nothing) for a joint without a motor or a speed that
    is not finite or whose power overflows (:func:`.motor_overflow`)."""
    joints = sim.model.joints
    motors = {} if joints is None else joints.motors
    motor = motors.get(joint)
    if joints is None or motor is None:
        raise InputError(f"no motor on joint '{joint}' "
                         f"(motors: {', '.join(sorted(motors)) or 'none'})")
    if not math.isfinite(speed):
        raise InputError(f"motor speed for joint '{joint}' must be finite, not {speed}")
    overflow = motor_overflow(speed, motor.max_effort)
    if overflow is not None:
        raise InputError(f"motor speed for joint '{joint}': {overflow}")
    joints.motor_speed[joint] = float(speed)
