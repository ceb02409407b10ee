"""Message fields: ROS messages to core commands, core states to plain message fields.

Nothing here imports ROS. The input functions read any object with the ROS field names
(``msg.header.stamp.sec``, ``msg.wrench.force.x``, ...), so rclpy messages, rosbags messages
and plain ``SimpleNamespace`` objects all fit. The output functions return plain named
tuples that the rclpy node and a rosbags bag writer both copy into their own message types.

Frames follow REP 103: the fixed frame (``Scene.frame_id``, default ``world``) has z out of
the plane; a body's pose is that of its body frame, whose yaw ``angle`` is a rotation about
z, counter-clockwise positive.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from ..scene.commands import InputError, WrenchCommand
from ..scene.load import WrenchTopic
from ..scene.parameters import seconds_text

__all__ = ["NS_PER_S", "Vec3", "Quaternion", "ns_from_stamp", "stamp_from_ns",
           "applied_wrench_to_command", "wrench_stamped_to_command", "Header", "Pose",
           "PoseStampedFields", "TwistFields", "OdometryFields", "header", "quaternion_from_yaw",
           "body_pose", "pose_fields", "twist_fields", "odometry_twist", "odometry_fields",
           "AppliedWrenchFields", "applied_wrench_fields"]

NS_PER_S = 1_000_000_000

Vec3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]


# ----------------------------------------------------------------------------- time

def ns_from_stamp(sec: int, nanosec: int) -> int:
    """Nanoseconds of a ``builtin_interfaces`` Time or Duration (``sec``, ``nanosec``)."""
    return int(sec) * NS_PER_S + int(nanosec)


def stamp_from_ns(ns: int) -> tuple[int, int]:
    """``(sec, nanosec)`` of a time in nanoseconds, with ``0 <= nanosec < 1e9``.

    Negative times keep a non-negative ``nanosec`` (-1 ns is ``(-1, 999999999)``), as
    ``builtin_interfaces/Time`` requires.
    """
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


# ----------------------------------------------------------------------------- inputs

def _require_finite(what: str, values: Mapping[str, float]) -> None:
    bad = [f"{name}={value}" for name, value in values.items() if not math.isfinite(value)]
    if bad:
        raise InputError(f"{what}: non-finite {', '.join(bad)}; the message is ignored")


def _out_of_plane_warnings(what: str, values: Mapping[str, float]) -> list[str]:
    parts = [f"{name}={value:g}" for name, value in values.items() if value != 0.0]
    if not parts:
        return []
    return [f"{what}: ignoring the out-of-plane {', '.join(parts)} (only force x, y, "
            "torque z and point x, y act in the plane)"]


#: The numbers of a ``geometry_msgs/Wrench``, in the order :func:`_wrench_numbers` reads them.
WRENCH_NAMES = ("force.x", "force.y", "force.z", "torque.x", "torque.y", "torque.z")
POINT_NAMES = ("point.x", "point.y", "point.z")


def _wrench_numbers(wrench: Any) -> tuple[float, ...]:
    force, torque = wrench.force, wrench.torque
    return (float(force.x), float(force.y), float(force.z),
            float(torque.x), float(torque.y), float(torque.z))


def _check_numbers(what: str, names: Sequence[str], values: Sequence[float]) -> None:
    """Raise :class:`InputError` naming every non-finite value (the names only on failure:
    this runs for every input message)."""
    if not all(map(math.isfinite, values)):
        _require_finite(what, dict(zip(names, values)))


def _start_ns(stamp: Any, receive_ns: int) -> int:
    """The header stamp in nanoseconds, or ``receive_ns`` when the stamp is zero."""
    stamp_ns = ns_from_stamp(stamp.sec, stamp.nanosec)
    return receive_ns if stamp_ns == 0 else stamp_ns


def applied_wrench_to_command(msg: Any, receive_ns: int) -> tuple[WrenchCommand, list[str]]:
    """Turn a ``hecker_dynamics/msg/AppliedWrench`` into a command and warnings.

    The command starts at the header stamp (``receive_ns`` when it is zero), acts on
    ``msg.body`` for ``msg.duration`` (zero: hold), replaces the previous command with the
    same body and ``msg.id``, and is expressed in ``header.frame_id`` (empty: the body's own
    frame). Raises :class:`InputError` for an empty body, a NaN or infinite number, or a
    negative duration; returns a warning for non-zero out-of-plane components.
    """
    body = str(msg.body)
    if not body:
        raise InputError("AppliedWrench with an empty 'body' field; the message is ignored")
    point = msg.point
    fx, fy, fz, tx, ty, tz, px, py, pz = numbers = _wrench_numbers(msg.wrench) + (
        float(point.x), float(point.y), float(point.z))
    what = f"AppliedWrench for body '{body}' from '{msg.id}'"
    _check_numbers(what, WRENCH_NAMES + POINT_NAMES, numbers)
    duration_ns = ns_from_stamp(msg.duration.sec, msg.duration.nanosec)
    if duration_ns < 0:
        raise InputError(f"{what}: negative duration {seconds_text(duration_ns)} s; "
                         "the message is ignored")
    command = WrenchCommand(
        stamp_ns=_start_ns(msg.header.stamp, receive_ns),
        body=body,
        source=str(msg.id),
        frame_id=str(msg.header.frame_id) or body,
        point=(px, py),
        force=(fx, fy),
        torque=tz,
        duration_ns=duration_ns,
    )
    warnings = _out_of_plane_warnings(what, {
        "force.z": fz, "torque.x": tx, "torque.y": ty, "point.z": pz}) if (
        fz or tx or ty or pz) else []
    return command, warnings


def wrench_stamped_to_command(msg: Any, topic: WrenchTopic,
                              receive_ns: int) -> tuple[WrenchCommand, list[str]]:
    """Turn a ``geometry_msgs/msg/WrenchStamped`` from a scene input topic into a command.

    The wrench acts on ``topic.body`` at the origin of ``header.frame_id`` (empty:
    ``topic.frame_id``), in that frame's axes, from the header stamp (zero: ``receive_ns``)
    until the next message on the topic or the input timeout. Raises :class:`InputError`
    for a NaN or infinite number; returns a warning for non-zero out-of-plane components.
    """
    what = f"WrenchStamped on '{topic.topic}' for body '{topic.body}'"
    fx, fy, fz, tx, ty, tz = numbers = _wrench_numbers(msg.wrench)
    _check_numbers(what, WRENCH_NAMES, numbers)
    command = WrenchCommand(
        stamp_ns=_start_ns(msg.header.stamp, receive_ns),
        body=topic.body,
        source=topic.name,
        frame_id=str(msg.header.frame_id) or topic.frame_id,
        point=(0.0, 0.0),
        force=(fx, fy),
        torque=tz,
    )
    warnings = _out_of_plane_warnings(what, {
        "force.z": fz, "torque.x": tx, "torque.y": ty}) if (fz or tx or ty) else []
    return command, warnings


# ----------------------------------------------------------------------------- outputs

class Header(NamedTuple):
    """``std_msgs/Header``: stamp as ``(sec, nanosec)`` and frame."""

    sec: int
    nanosec: int
    frame_id: str


class Pose(NamedTuple):
    """``geometry_msgs/Pose``: position (x, y, z) and orientation quaternion (x, y, z, w)."""

    position: Vec3
    orientation: Quaternion


class PoseStampedFields(NamedTuple):
    """``geometry_msgs/PoseStamped``."""

    header: Header
    pose: Pose


class TwistFields(NamedTuple):
    """``geometry_msgs/Twist``: linear (x, y, z) and angular (x, y, z) velocity."""

    linear: Vec3
    angular: Vec3


class OdometryFields(NamedTuple):
    """``nav_msgs/Odometry`` without covariances (left zero: unknown)."""

    header: Header
    child_frame_id: str
    pose: Pose
    twist: TwistFields


def header(frame_id: str, stamp_ns: int) -> Header:
    """A header stamped ``stamp_ns`` in ``frame_id``."""
    sec, nanosec = stamp_from_ns(stamp_ns)
    return Header(sec, nanosec, frame_id)


def quaternion_from_yaw(angle: float) -> Quaternion:
    """Unit quaternion (x, y, z, w) of a rotation by ``angle`` about z.

    ``w = cos(angle / 2)`` is non-negative for angles in [-pi, pi].
    """
    half = 0.5 * float(angle)
    return (0.0, 0.0, math.sin(half), math.cos(half))


def _rotate(v: Sequence[float], angle: float) -> tuple[float, float]:
    c, s = math.cos(angle), math.sin(angle)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1])


def body_pose(state: Any) -> Pose:
    """Pose of the body frame of ``state`` (a ``BodyState``) in the fixed frame."""
    x, y = state.position
    return Pose((float(x), float(y), 0.0), quaternion_from_yaw(state.angle))


def pose_fields(state: Any, frame_id: str, stamp_ns: int) -> PoseStampedFields:
    """``<body>/pose``: the body frame's pose in the fixed frame ``frame_id`` at ``stamp_ns``."""
    return PoseStampedFields(header(frame_id, stamp_ns), body_pose(state))


def twist_fields(state: Any, twist_frame: str) -> TwistFields:
    """``<body>/twist``: velocity of the body frame's origin and the angular velocity.

    ``twist_frame`` ``"world"`` gives the linear velocity in fixed-frame axes; ``"body"``
    rotates it into the body's axes (by ``-angle``), as ``nav_msgs/Odometry`` does for its
    child frame. The angular velocity is about z either way.
    """
    if twist_frame == "body":
        vx, vy = _rotate(state.linear_velocity, -state.angle)
    elif twist_frame == "world":
        vx, vy = state.linear_velocity
    else:
        raise ValueError(f"twist_frame must be 'body' or 'world', not '{twist_frame}'")
    return TwistFields((float(vx), float(vy), 0.0), (0.0, 0.0, float(state.angular_velocity)))


def odometry_twist(state: Any, twist: TwistFields, twist_frame: str) -> TwistFields:
    """``<body>/odom``'s twist, in the body's axes (its child frame): ``twist``, the one
    published on ``<body>/twist`` in ``twist_frame``, where that already is the body's."""
    return twist if twist_frame == "body" else twist_fields(state, "body")


def odometry_fields(state: Any, frame_id: str, stamp_ns: int) -> OdometryFields:
    """``<body>/odom``: pose in ``frame_id``, twist in the body's axes (child frame)."""
    return OdometryFields(header(frame_id, stamp_ns), state.name, body_pose(state),
                          twist_fields(state, "body"))

class AppliedWrenchFields(NamedTuple):
    """``hecker_dynamics/AppliedWrench``: ``duration`` as ``(sec, nanosec)``."""

    header: Header
    body: str
    id: str
    point: Vec3
    force: Vec3
    torque: Vec3
    duration: tuple[int, int]


def applied_wrench_fields(command: WrenchCommand) -> AppliedWrenchFields:
    """The ``AppliedWrench`` message of ``command``: the inverse of
    :func:`applied_wrench_to_command` for in-plane wrenches with a non-zero stamp."""
    return AppliedWrenchFields(
        header(command.frame_id, command.stamp_ns), command.body, command.source,
        (float(command.point[0]), float(command.point[1]), 0.0),
        (float(command.force[0]), float(command.force[1]), 0.0),
        (0.0, 0.0, float(command.torque)), stamp_from_ns(command.duration_ns))
