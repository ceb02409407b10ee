"""Message mapping: ROS messages to core commands, core states to message fields.

Nothing here imports ROS. The input functions read any object with the ROS field names
(``msg.header.stamp.sec``, ``msg.wrench.force.x``, ...), so rclpy messages, rosbags messages
and plain ``SimpleNamespace`` objects all fit. The output functions return plain named
tuples that the rclpy node and a rosbags bag writer both copy into their own message types.

Frames follow REP 103: the fixed frame (``Scene.frame_id``, default ``world``) has z out of
the plane; a body's pose is that of its body frame, whose yaw ``angle`` is a rotation about
z, counter-clockwise positive.

The clock decisions of the node (when to start, when the ROS clock jumped so far that the
simulation restarts, how far it lags) live here too, as plain functions of nanoseconds.
"""
from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from .commands import InputError, WrenchCommand
from .geometry import Circle, Polygon
from .scene import NODE_PARAMETERS, BodySpec, Scene, SceneError, WrenchTopic, load_scene, \
    scene_from_parameters

NS_PER_S = 1_000_000_000
#: A change of the ROS clock between two timer ticks larger than this, forwards or
#: backwards, is a jump: the simulation restarts at the new time instead of stepping there.
CLOCK_JUMP_NS = NS_PER_S

# visualization_msgs/msg/Marker constants.
MARKER_CYLINDER = 3
MARKER_LINE_STRIP = 4
MARKER_ADD = 0
#: Thickness of shape outlines and of circle discs in RViz, in metres.
MARKER_LINE_WIDTH = 0.02
MARKER_DISC_HEIGHT = 0.01
#: Body colours (r, g, b, a), cycled by body index.
MARKER_COLORS = (
    (0.12, 0.47, 0.71, 1.0), (1.0, 0.5, 0.05, 1.0), (0.17, 0.63, 0.17, 1.0),
    (0.84, 0.15, 0.16, 1.0), (0.58, 0.4, 0.74, 1.0), (0.55, 0.34, 0.29, 1.0),
)

# diagnostic_msgs/msg/DiagnosticStatus levels.
DIAGNOSTIC_OK = 0
DIAGNOSTIC_WARN = 1
DIAGNOSTIC_ERROR = 2

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


def _wrench_numbers(wrench: Any) -> dict[str, float]:
    return {
        "force.x": float(wrench.force.x), "force.y": float(wrench.force.y),
        "force.z": float(wrench.force.z), "torque.x": float(wrench.torque.x),
        "torque.y": float(wrench.torque.y), "torque.z": float(wrench.torque.z),
    }


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
    what = f"AppliedWrench for body '{body}' from '{msg.id}'"
    if not body:
        raise InputError("AppliedWrench with an empty 'body' field; the message is ignored")
    numbers = _wrench_numbers(msg.wrench)
    numbers.update({"point.x": float(msg.point.x), "point.y": float(msg.point.y),
                    "point.z": float(msg.point.z)})
    _require_finite(what, numbers)
    duration_ns = ns_from_stamp(msg.duration.sec, msg.duration.nanosec)
    if duration_ns < 0:
        raise InputError(f"{what}: negative duration {duration_ns * 1e-9:g} s; "
                         "the message is ignored")
    command = WrenchCommand(
        stamp_ns=_start_ns(msg.header.stamp, receive_ns),
        body=body,
        source=str(msg.id),
        frame_id=str(msg.header.frame_id) or body,
        point=(numbers["point.x"], numbers["point.y"]),
        force=(numbers["force.x"], numbers["force.y"]),
        torque=numbers["torque.z"],
        duration_ns=duration_ns,
    )
    warnings = _out_of_plane_warnings(what, {
        k: numbers[k] for k in ("force.z", "torque.x", "torque.y", "point.z")})
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
    numbers = _wrench_numbers(msg.wrench)
    _require_finite(what, numbers)
    command = WrenchCommand(
        stamp_ns=_start_ns(msg.header.stamp, receive_ns),
        body=topic.body,
        source=topic.name,
        frame_id=str(msg.header.frame_id) or topic.frame_id,
        point=(0.0, 0.0),
        force=(numbers["force.x"], numbers["force.y"]),
        torque=numbers["torque.z"],
    )
    warnings = _out_of_plane_warnings(what, {
        k: numbers[k] for k in ("force.z", "torque.x", "torque.y")})
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


class MarkerFields(NamedTuple):
    """The ``visualization_msgs/Marker`` fields a shape sets; the others keep defaults."""

    header: Header
    ns: str
    id: int
    type: int
    action: int
    pose: Pose
    scale: Vec3
    color: tuple[float, float, float, float]
    points: tuple[Vec3, ...]


class DiagnosticFields(NamedTuple):
    """``diagnostic_msgs/DiagnosticStatus``; ``values`` are (key, value) string pairs."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...]


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


def odometry_fields(state: Any, frame_id: str, stamp_ns: int) -> OdometryFields:
    """``<body>/odom``: pose in ``frame_id``, twist in the body's axes (child frame)."""
    return OdometryFields(header(frame_id, stamp_ns), state.name, body_pose(state),
                          twist_fields(state, "body"))


def _shape_markers(shape: Any, pose: Pose, angle: float, head: Header, ns: str,
                   first_id: int, color: tuple[float, float, float, float]) -> list[MarkerFields]:
    """Markers of one shape: a closed outline for a polygon; a disc and a radius for a circle."""
    line_scale = (MARKER_LINE_WIDTH, 0.0, 0.0)
    if isinstance(shape, Polygon):
        outline = [(float(x), float(y), 0.0) for x, y in shape.vertices]
        outline.append(outline[0])
        return [MarkerFields(head, ns, first_id, MARKER_LINE_STRIP, MARKER_ADD, pose,
                             line_scale, color, tuple(outline))]
    if isinstance(shape, Circle):
        cx, cy = float(shape.center[0]), float(shape.center[1])
        ox, oy = _rotate((cx, cy), angle)
        disc_pose = Pose((pose.position[0] + ox, pose.position[1] + oy, 0.0), pose.orientation)
        diameter = 2.0 * float(shape.radius)
        disc_color = (color[0], color[1], color[2], 0.5 * color[3])
        radius_line = ((cx, cy, 0.0), (cx + float(shape.radius), cy, 0.0))
        return [
            MarkerFields(head, ns, first_id, MARKER_CYLINDER, MARKER_ADD, disc_pose,
                         (diameter, diameter, MARKER_DISC_HEIGHT), disc_color, ()),
            MarkerFields(head, ns, first_id + 1, MARKER_LINE_STRIP, MARKER_ADD, pose,
                         line_scale, color, radius_line),
        ]
    raise TypeError(f"no marker for a shape of type {type(shape).__name__}")


def marker_fields(body: BodySpec, state: Any, index: int, frame_id: str,
                  stamp_ns: int) -> list[MarkerFields]:
    """RViz markers of ``body``'s shapes at ``state``, in namespace ``body.name``.

    Outlines are ``LINE_STRIP`` markers whose pose is the body pose and whose points are
    the shape's vertices in the body frame; circles are ``CYLINDER`` discs plus a radius
    line that shows the spin. ``index`` picks the body's colour.
    """
    head = header(frame_id, stamp_ns)
    pose = body_pose(state)
    color = MARKER_COLORS[index % len(MARKER_COLORS)]
    markers: list[MarkerFields] = []
    for shape in body.shapes:
        markers.extend(_shape_markers(shape, pose, float(state.angle), head, body.name,
                                      len(markers), color))
    return markers


def diagnostic_fields(level: int, message: str, values: Mapping[str, Any],
                      name: str = "hecker_dynamics: simulation",
                      hardware_id: str = "dynamics_node") -> DiagnosticFields:
    """A diagnostic status; floats in ``values`` are written with 9 significant digits."""
    pairs = tuple((key, f"{value:.9g}" if isinstance(value, float) else str(value))
                  for key, value in values.items())
    return DiagnosticFields(level, name, message, hardware_id, pairs)


# ----------------------------------------------------------------------------- node setup

@dataclasses.dataclass(frozen=True)
class NodeOptions:
    """The node's own parameters (the scene reader lets these names pass)."""

    scene: str = ""                   # shipped scene name or parameters file; "" = default
    lockstep: bool = False            # step as fast as possible and publish /clock
    play_script: bool = True          # push the scene's scripted inputs
    max_catch_up_steps: int = 1000    # physics steps one timer tick may take at most


def node_options(params: Mapping[str, Any], source: str) -> NodeOptions:
    """Read and type-check the node's own parameters; missing ones keep their defaults."""
    values = {}
    for option in dataclasses.fields(NodeOptions):
        value = params.get(option.name, option.default)
        kind = type(option.default)
        if type(value) is not kind:
            raise SceneError(f"{source}: parameter '{option.name}' must be a {kind.__name__}, "
                             f"not {value!r}")
        values[option.name] = value
    options = NodeOptions(**values)
    if options.max_catch_up_steps < 1:
        raise SceneError(f"{source}: parameter 'max_catch_up_steps' must be at least 1, "
                         f"not {options.max_catch_up_steps}")
    return options


def scene_for_node(params: Mapping[str, Any], source: str) -> Scene:
    """The scene a node runs, from its parameters (flat dotted names and their values).

    Scene parameters (from ``--params-file`` or ``-p``) build the scene; otherwise the
    ``scene`` parameter names a shipped scene or a parameters file; with neither, the
    default scene runs. Giving both is a :class:`SceneError`, since one would silently
    win over the other.
    """
    scene_names = sorted(name for name in params
                         if name.split(".", 1)[0] not in NODE_PARAMETERS)
    requested = params.get("scene") or None
    if scene_names and requested:
        raise SceneError(f"{source}: give the 'scene' parameter ('{requested}') or scene "
                         f"parameters ({', '.join(scene_names[:3])}, ...), not both")
    if scene_names:
        return scene_from_parameters(params, source)
    return load_scene(requested)


def due_script(script: Sequence[WrenchCommand], start_ns: int, next_index: int,
               until_ns: int) -> tuple[list[WrenchCommand], int]:
    """The scene's scripted commands from ``next_index`` on that start by ``until_ns``.

    Script stamps count from the start of the run; the returned commands are shifted to
    ``start_ns``. Returns them and the index of the first command not yet due. The node
    pushes each command before the step that reaches its stamp, which gives the forces of
    :meth:`Simulation.play`.
    """
    due = []
    index = next_index
    while index < len(script) and start_ns + script[index].stamp_ns <= until_ns:
        command = script[index]
        due.append(dataclasses.replace(command, stamp_ns=start_ns + command.stamp_ns))
        index += 1
    return due, index


def catch_up_cap(max_catch_up_steps: int, scene: Scene) -> tuple[int, list[str]]:
    """Steps a timer tick may take, and warnings if the requested cap had to change.

    A cap below one publish period's worth of steps could never keep up with the clock,
    so it is raised to that.
    """
    needed = scene.publish_period_ns // scene.step_ns
    if max_catch_up_steps >= needed:
        return max_catch_up_steps, []
    return needed, [f"max_catch_up_steps={max_catch_up_steps} is less than the {needed} steps "
                    f"of one publish period; using {needed}"]


class TickAction(enum.Enum):
    """What a timer tick does with the simulation."""

    WAIT = "wait"          # the ROS clock is not running yet (zero): do nothing
    START = "start"        # first tick with a running clock: start the simulation now
    ADVANCE = "advance"    # step the simulation up to now
    RESTART = "restart"    # the clock jumped: restart the simulation at now


def plan_tick(now_ns: int, last_now_ns: int | None,
              jump_ns: int = CLOCK_JUMP_NS) -> tuple[TickAction, str]:
    """Decide what a timer tick at ROS time ``now_ns`` does, and why (for the log).

    ``last_now_ns`` is the ROS time of the previous tick that ran (None before the start).
    A zero time means the clock is not running (``use_sim_time`` before the first
    ``/clock`` message). A clock that moved by more than ``jump_ns`` since the last tick,
    backwards (a bag played again) or forwards (a bag skipped ahead), restarts the
    simulation: stepping back is impossible and stepping across the gap would stall.
    """
    if now_ns == 0:
        return TickAction.WAIT, "the ROS clock is not running yet (waiting for /clock)"
    if last_now_ns is None:
        return TickAction.START, f"starting the simulation at {now_ns * 1e-9:.9f} s"
    delta_ns = now_ns - last_now_ns
    if delta_ns < -jump_ns:
        return TickAction.RESTART, (f"the ROS clock jumped back by {-delta_ns * 1e-9:.3f} s; "
                                    f"restarting the scene at {now_ns * 1e-9:.9f} s")
    if delta_ns > jump_ns:
        return TickAction.RESTART, (f"the ROS clock jumped ahead by {delta_ns * 1e-9:.3f} s; "
                                    f"restarting the scene at {now_ns * 1e-9:.9f} s")
    return TickAction.ADVANCE, ""


def lag_ns(now_ns: int, sim_time_ns: int, step_ns: int) -> int:
    """How far the simulation is behind ``now_ns`` after a tick: 0 when it is less than a step."""
    behind = now_ns - sim_time_ns
    return behind if behind >= step_ns else 0
