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

import array
import dataclasses
import enum
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple, Optional

from ..dynamics.commands import InputError, WrenchCommand
from ..geometry.shapes import Circle, Polygon
from ..scene.load import NODE_PARAMETERS, BodySpec, Scene, SceneError, WrenchTopic, load_scene, \
    scene_from_parameters
from ..dynamics.simulation import DivergenceError, Simulation, Snapshot

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

# diagnostic_msgs/msg/DiagnosticStatus levels (a ``byte`` field: rclpy wants
# ``bytes([level])``, rosbags an int).
DIAGNOSTIC_OK = 0
DIAGNOSTIC_WARN = 1
DIAGNOSTIC_ERROR = 2
#: Diagnostics are published at most this often, in sim time.
DIAGNOSTICS_PERIOD_NS = NS_PER_S
#: Name of the diagnostic status the node publishes.
DIAGNOSTIC_NAME = "hecker_dynamics: simulation"

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
                      name: str = DIAGNOSTIC_NAME,
                      hardware_id: str = "dynamics_node") -> DiagnosticFields:
    """A diagnostic status; floats in ``values`` are written with 9 significant digits."""
    pairs = tuple((key, f"{value:.9g}" if isinstance(value, float) else str(value))
                  for key, value in values.items())
    return DiagnosticFields(level, name, message, hardware_id, pairs)


def diagnostics_due(last_ns: Optional[int], now_ns: int) -> bool:
    """Whether diagnostics are due at sim time ``now_ns`` (last published at ``last_ns``)."""
    return last_ns is None or now_ns - last_ns >= DIAGNOSTICS_PERIOD_NS


def simulation_diagnostics(sim: Simulation, *, halted: Optional[str], lag: int, substeps: int,
                           wall_ns: int, accepted: int, rejected: int,
                           hardware_id: str) -> DiagnosticFields:
    """The node's diagnostic status for ``sim`` after a tick of ``substeps`` steps.

    Level ERROR with the divergence message when ``halted``; WARN when the simulation lags
    the clock by ``lag`` ns; OK otherwise. ``wall_ns`` is the wall time the tick's steps
    took (zero where wall time must not show, as in an offline replay).
    """
    if halted is not None:
        level, message = DIAGNOSTIC_ERROR, halted
    elif lag:
        level, message = DIAGNOSTIC_WARN, f"{lag / NS_PER_S:.3f} s behind the clock"
    else:
        level, message = DIAGNOSTIC_OK, "running"
    return diagnostic_fields(level, message, {
        "sim_time": sim.time_ns / NS_PER_S,
        "start_time": sim.start_ns / NS_PER_S,
        "steps": sim.steps,
        "step": sim.step_ns / NS_PER_S,
        "substeps": substeps,
        "step_wall_time": wall_ns / substeps / NS_PER_S if substeps else 0.0,
        "energy": sim.snapshot().energy,
        "lag": lag / NS_PER_S,
        "commands_accepted": accepted,
        "commands_rejected": rejected,
    }, hardware_id=hardware_id)


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


class OutputKind(enum.Enum):
    """The kinds of message the node publishes."""

    POSE = "geometry_msgs/msg/PoseStamped"
    TWIST = "geometry_msgs/msg/Twist"
    ODOMETRY = "nav_msgs/msg/Odometry"
    MARKERS = "visualization_msgs/msg/MarkerArray"
    DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"


#: The node's diagnostics topic (relative: in the node's namespace).
DIAGNOSTICS_TOPIC = "diagnostics"


def output_topics(scene: Scene) -> dict[str, OutputKind]:
    """The node's output topics for ``scene`` (relative names) and kinds, in publishing
    order: per body ``<body>/pose``, ``<body>/twist`` and (if enabled) ``<body>/odom``, then
    ``markers`` and ``diagnostics`` if the scene enables them."""
    topics: dict[str, OutputKind] = {}
    for body in scene.bodies:
        topics[f"{body.name}/pose"] = OutputKind.POSE
        topics[f"{body.name}/twist"] = OutputKind.TWIST
        if scene.publish_odometry:
            topics[f"{body.name}/odom"] = OutputKind.ODOMETRY
    if scene.publish_markers:
        topics["markers"] = OutputKind.MARKERS
    if scene.publish_diagnostics:
        topics[DIAGNOSTICS_TOPIC] = OutputKind.DIAGNOSTICS
    return topics


class OutputFields(NamedTuple):
    """One message to publish: relative topic, kind, and the fields (the kind's ``*Fields``
    tuple; for markers a tuple of :class:`MarkerFields`)."""

    topic: str
    kind: OutputKind
    fields: Any


def snapshot_outputs(scene: Scene, snapshot: Snapshot) -> list[OutputFields]:
    """The messages the node publishes for one snapshot, in publishing order."""
    frame_id = scene.frame_id
    stamp = snapshot.time_ns
    outputs = []
    markers: list[MarkerFields] = []
    for index, state in enumerate(snapshot.bodies):
        name = state.name
        outputs.append(OutputFields(f"{name}/pose", OutputKind.POSE,
                                    pose_fields(state, frame_id, stamp)))
        outputs.append(OutputFields(f"{name}/twist", OutputKind.TWIST,
                                    twist_fields(state, scene.twist_frame)))
        if scene.publish_odometry:
            outputs.append(OutputFields(f"{name}/odom", OutputKind.ODOMETRY,
                                        odometry_fields(state, frame_id, stamp)))
        if scene.publish_markers:
            markers.extend(marker_fields(scene.bodies[index], state, index, frame_id, stamp))
    if scene.publish_markers:
        outputs.append(OutputFields("markers", OutputKind.MARKERS, tuple(markers)))
    return outputs


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


def plain_parameters(params: Mapping[str, Any]) -> dict[str, Any]:
    """Parameter values as the scene reader takes them: every array as a list.

    rclpy hands parameter overrides from the command line and parameters files over as
    lists, but a value that went through a ``rcl_interfaces/ParameterValue`` message
    (``Parameter.from_parameter_msg``, the parameter services) holds integer and double
    arrays as ``array.array``.
    """
    return {name: list(value) if isinstance(value, (array.array, tuple)) else value
            for name, value in params.items()}


def node_setup(params: Mapping[str, Any], source: str) -> tuple[NodeOptions, Scene]:
    """The node's options and scene from all its parameters (names and values)."""
    params = plain_parameters(params)
    return node_options(params, source), scene_for_node(params, source)


# ----------------------------------------------------------------------------- run loop

class LogLine(NamedTuple):
    """A line for the node's log: the rate-limiting key, the text, and whether the input
    it is about was dropped (else it is a warning about an accepted input)."""

    key: str
    message: str
    dropped: bool = True


@dataclasses.dataclass
class Tick:
    """What one call of :meth:`Runner.advance` did."""

    snapshots: list[Snapshot]
    lag: int = 0                                       # ns behind the target (0: caught up)
    diagnostics: Optional[DiagnosticFields] = None     # to publish, when due and enabled
    diverged: Optional[str] = None                     # the divergence that halted the run
    script_errors: list[str] = dataclasses.field(default_factory=list)


class Runner:
    """The node's run loop without ROS: a :class:`Simulation`, the scene's script, the
    input counters and the diagnostics schedule. The rclpy node and the offline replay
    both drive one, so a replayed session gives the node's outputs.

    ``max_steps`` caps the physics steps of one :meth:`advance` (the node's catch-up cap;
    None: no cap). ``wall_clock`` times the steps for the diagnostics (the replay passes a
    clock that stands still, since wall time is not reproducible). Until ``started``, inputs
    are refused (the node waits for a running ROS clock).
    """

    def __init__(self, scene: Scene, *, start_ns: int = 0, play_script: bool = True,
                 max_steps: Optional[int] = None, started: bool = True,
                 hardware_id: str = "/dynamics_node",
                 wall_clock: Callable[[], int] = time.perf_counter_ns) -> None:
        self.scene = scene
        self.sim = Simulation(scene, start_ns=start_ns)
        self.play_script = play_script
        self.max_steps = max_steps
        self.started = started
        self.hardware_id = hardware_id
        self.wall_clock = wall_clock
        self.accepted = 0
        self.rejected = 0
        self.halted: Optional[str] = None
        self._script_index = 0
        self._last_diagnostics_ns: Optional[int] = None

    def restart(self, start_ns: int) -> None:
        """Restart the scene at ``start_ns`` (reset service, clock jump, first tick)."""
        self.sim.reset(start_ns)
        self._script_index = 0
        self.halted = None
        self._last_diagnostics_ns = None
        self.started = True

    def accept(self, topic: str,
               convert: Callable[[int], tuple[WrenchCommand, list[str]]],
               arrival_ns: int) -> list[LogLine]:
        """Convert one input message that arrived at ``arrival_ns`` and push it.

        ``convert`` is a :func:`applied_wrench_to_command` or
        :func:`wrench_stamped_to_command` call waiting for the arrival time. Bad input is
        counted in ``rejected`` and reported in the returned lines, never raised; warnings
        about an accepted message are returned too.
        """
        if not self.started:
            self.rejected += 1
            return [LogLine(f"{topic}:early", f"input on '{topic}' ignored: the simulation "
                                              "starts with the ROS clock (waiting for /clock)")]
        try:
            command, warnings = convert(arrival_ns)
        except InputError as error:  # the message itself is bad (NaN, empty body, ...)
            self.rejected += 1
            return [LogLine(f"{topic}:message", f"input on '{topic}' rejected: {error}")]
        lines = [LogLine(f"{topic}:out_of_plane", warning, dropped=False)
                 for warning in warnings]
        try:
            self.sim.push(command)
        except InputError as error:  # the scene refuses it (unknown body or frame, stamp...)
            self.rejected += 1
            return lines + [LogLine(f"{topic}:scene", f"input on '{topic}' rejected: {error}")]
        self.accepted += 1
        return lines

    def advance(self, target_ns: int) -> Tick:
        """Push the scripted commands due, step towards ``target_ns`` (at most
        ``max_steps``) and return the snapshots passed, the lag and the diagnostics due.

        After a divergence the simulation stands still until :meth:`restart`.
        """
        if self.halted is not None:
            return Tick([])
        sim = self.sim
        tick = Tick([])
        if self.play_script:
            reach = target_ns if self.max_steps is None else min(
                target_ns, sim.time_ns + self.max_steps * sim.step_ns)
            due, self._script_index = due_script(self.scene.script, sim.start_ns,
                                                 self._script_index, reach)
            for command in due:
                try:
                    sim.push(command)
                except InputError as error:
                    tick.script_errors.append(f"scripted input rejected: {error}")
        steps_before = sim.steps
        wall_start_ns = self.wall_clock()
        try:
            tick.snapshots = sim.advance_to(target_ns, max_steps=self.max_steps)
        except DivergenceError as error:
            self.halted = tick.diverged = str(error)
            tick.diagnostics = self._diagnostics(0, 0, 0)
            return tick
        wall_ns = self.wall_clock() - wall_start_ns
        tick.lag = lag_ns(target_ns, sim.time_ns, sim.step_ns)
        if diagnostics_due(self._last_diagnostics_ns, sim.time_ns):
            tick.diagnostics = self._diagnostics(sim.steps - steps_before, wall_ns, tick.lag)
        return tick

    def _diagnostics(self, substeps: int, wall_ns: int, lag: int) -> Optional[DiagnosticFields]:
        if not self.scene.publish_diagnostics:
            return None
        self._last_diagnostics_ns = self.sim.time_ns
        return simulation_diagnostics(
            self.sim, halted=self.halted, lag=lag, substeps=substeps, wall_ns=wall_ns,
            accepted=self.accepted, rejected=self.rejected, hardware_id=self.hardware_id)

    def done(self) -> bool:
        """Whether a lockstep run is over: halted, or the scene's duration (if any) ran."""
        duration_ns = self.scene.duration_ns
        return self.halted is not None or (
            duration_ns > 0 and self.sim.time_ns - self.sim.start_ns >= duration_ns)
