"""rosbag2 bags with ``rosbags``: reading, writing and the message types of the package.

Works with or without ROS installed. Bags are written as ROS 2 Jazzy records them
(``rosbag2`` metadata version 9: ``offered_qos_profiles`` as a list of profile dicts, the
message definitions in the storage, RIHS01 type hashes), in ``mcap`` (Jazzy's default) or
``sqlite3`` storage, and read from either.

The custom ``hecker_dynamics/msg/AppliedWrench`` type is registered from its ``.msg`` file,
looked up where each kind of install keeps it (:func:`applied_wrench_msg_path`), so the
definition in a bag is always the package's own.

Message contents come from :mod:`hecker_dynamics.ros` (the ``*_fields`` functions the
node uses too); this module only copies those fields into rosbags message objects.
"""
from __future__ import annotations

import contextlib
import glob
import os
import shutil
import socket
import sqlite3
import stat
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cache, lru_cache
from pathlib import Path
from typing import Any, Literal, Optional, Union

try:
    import fcntl
except ImportError:  # Windows: a killed writer's directory is then left behind
    fcntl = None  # type: ignore[assignment]

import numpy as np

from ..ros.contact_fields import ContactEventFields
from ..ros.diagnostics import DiagnosticFields
from ..ros.fields import (
    AppliedWrenchFields,
    Header,
    OdometryFields,
    Pose,
    PoseStampedFields,
    TwistFields,
    applied_wrench_fields,
    header,
    ns_from_stamp,
    stamp_from_ns,
)
from ..ros.joint_states import JointStateFields
from ..ros.map_fields import OccupancyGridFields
from ..ros.markers import MarkerFields
from ..ros.names import STATE_QOS, Durability, QosSpec, Reliability, output_qos
from ..ros.sensor_fields import ImuFields, LaserScanFields
from ..ros.session import (
    APPLIED_WRENCH_EVENT,
    CMD_VEL_EVENT,
    MOTOR_SPEED_EVENT,
    WRENCH_STAMPED_EVENT,
    InputEventFields,
    KeyframeFields,
    SessionFields,
    WorldChange,
    WorldEventFields,
)
from ..ros.tf import TransformFields
from ..scene.commands import WrenchCommand
from ..scene.names import NODE_NAME
from ..scene.parameters import MAX_STAMP_NS, quoted, seconds_text

__all__ = [
    "APPLIED_WRENCH", "POSE_STAMPED", "TWIST", "ODOMETRY", "MARKER_ARRAY", "DIAGNOSTIC_ARRAY",
    "TF_MESSAGE", "WRENCH_STAMPED", "BagError", "BagMessage", "BagContents", "BagWriter",
    "NODE_QOS", "rosbag_qos", "tf_message",
    "STORAGES", "message_definition_path", "typestore", "read_bag", "resolve_topic",
    "SESSION_INFO", "KEYFRAME", "INPUT_EVENT", "latched_qos", "session_info_message",
    "keyframe_message", "input_event_message", "session_fields", "keyframe_fields",
    "input_event_fields", "input_event_unused_slots", "WORLD_EVENT", "world_event_message",
    "world_event_fields",
    "default_message", "stamp_ns_of", "MAX_STAMP_NS", "LASER_SCAN", "IMU",
    "laser_scan_message", "imu_message", "OCCUPANCY_GRID", "occupancy_grid_message",
    "CONTACT_EVENT", "contact_event_message",
]

APPLIED_WRENCH = "hecker_dynamics/msg/AppliedWrench"
SESSION_INFO = "hecker_dynamics/msg/SessionInfo"
KEYFRAME = "hecker_dynamics/msg/Keyframe"
INPUT_EVENT = "hecker_dynamics/msg/InputEvent"
WORLD_EVENT = "hecker_dynamics/msg/WorldEvent"
#: The package's own interfaces, each defined in ``msg/<Name>.msg``.
CONTACT_EVENT = "hecker_dynamics/msg/ContactEvent"
PACKAGE_MESSAGES = (APPLIED_WRENCH, SESSION_INFO, KEYFRAME, INPUT_EVENT, WORLD_EVENT,
                    CONTACT_EVENT)
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TWIST = "geometry_msgs/msg/Twist"
ODOMETRY = "nav_msgs/msg/Odometry"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
JOINT_STATE = "sensor_msgs/msg/JointState"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
IMU = "sensor_msgs/msg/Imu"
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
FLOAT64 = "std_msgs/msg/Float64"

#: rosbag2 metadata version that ROS 2 Jazzy writes and reads.
BAG_VERSION: Literal[9] = 9
#: Storage formats: name -> rosbags plugin name.
STORAGES = ("mcap", "sqlite3")
#: Prefix of the keys this package stores in a bag's ``custom_data``.
CUSTOM_PREFIX = "hecker_dynamics."

PathLike = Union[str, os.PathLike[str]]


class BagError(Exception):
    """A bag that cannot be read, written or used; the message is one clear line."""


# ----------------------------------------------------------------------------- types

def message_definition_path(msgtype: str = APPLIED_WRENCH) -> Path:
    """The package's ``<Name>.msg`` of ``msgtype``: source tree, pip install, or ament share
    dir."""
    name = msgtype.rsplit("/", 1)[-1] + ".msg"
    package = Path(__file__).resolve().parents[1]
    candidates = [package.parent / "msg", package / "interfaces"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            candidates.append(Path(prefix) / "share" / "hecker_dynamics" / "msg")
    for directory in candidates:
        path = directory / name
        if path.is_file():
            return path
    raise BagError(f"cannot find {name} (looked in "
                   + ", ".join(str(c) for c in candidates) + ")")


@lru_cache(maxsize=1)
def typestore() -> Any:
    """A ROS 2 Jazzy typestore with the package's messages registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for msgtype in PACKAGE_MESSAGES:
        types.update(get_types_from_msg(message_definition_path(msgtype).read_text(), msgtype))
    store.register(types)
    return store


@cache
def rosbag_qos(spec: QosSpec) -> list[Any]:
    """A publisher's QoS (:mod:`hecker_dynamics.ros.names`) as rosbag2 metadata records it."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    default = QosTime(0, 0)  # rmw's "default" durations: deadline, lifespan, lease unset
    reliability = {Reliability.RELIABLE: QosReliability.RELIABLE,
                   Reliability.BEST_EFFORT: QosReliability.BEST_EFFORT}[spec.reliability]
    durability = {Durability.VOLATILE: QosDurability.VOLATILE,
                  Durability.TRANSIENT_LOCAL: QosDurability.TRANSIENT_LOCAL}[spec.durability]
    return [Qos(QosHistory.KEEP_LAST, spec.depth, reliability, durability,
                default, default, QosLiveliness.AUTOMATIC, default, False)]


#: The QoS the node's state publishers offer (reliable, volatile, keep last 10).
NODE_QOS = rosbag_qos(STATE_QOS)


def latched_qos(depth: int) -> list[Any]:
    """The QoS of the node's session records: reliable, transient_local, keep-last ``depth``
    (what ``ros2 bag record`` stores for them, and what ``ros2 bag play`` offers again)."""
    return rosbag_qos(QosSpec(depth, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL))


def resolve_topic(name: str, namespace: str = "/") -> str:
    """Fully qualified topic name, as the node in ``namespace`` resolves a relative name or
    a private one (``~/session``: below the node's name)."""
    if name.startswith("/"):
        return name
    if name.startswith("~/"):
        return resolve_topic(NODE_NAME, namespace) + name[1:]
    namespace = "/" + namespace.strip("/")
    return (namespace.rstrip("/") + "/" + name) if namespace != "/" else "/" + name


_NUMPY_TYPES = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
    "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
    "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64,
}


def _default_value(store: Any, desc: tuple[Any, ...]) -> Any:
    from rosbags.interfaces import Nodetype

    kind, spec = desc
    if kind == Nodetype.BASE:
        name = spec[0]
        if name == "string" or name == "wstring":
            return ""
        if name == "bool":
            return False
        if name.startswith("float"):
            return 0.0
        return 0
    if kind == Nodetype.NAME:
        return default_message(spec)
    sub, length = spec
    if sub[0] == Nodetype.BASE and sub[1][0] in _NUMPY_TYPES:
        return np.zeros(length if kind == Nodetype.ARRAY else 0, dtype=_NUMPY_TYPES[sub[1][0]])
    if kind == Nodetype.ARRAY:
        return [_default_value(store, sub) for _ in range(length)]
    return []


def default_message(msgtype: str, **values: Any) -> Any:
    """A rosbags message of ``msgtype`` with every field at its ROS default, then ``values``."""
    store = typestore()
    try:
        _, fields = store.fielddefs[msgtype]
    except KeyError:
        raise BagError(f"unknown message type '{msgtype}'") from None
    kwargs = {name: _default_value(store, desc) for name, desc in fields}
    kwargs.update(values)
    return store.types[msgtype](**kwargs)


# ----------------------------------------------------------------------------- messages

def header_message(fields: Header) -> Any:
    return default_message("std_msgs/msg/Header",
                           stamp=default_message("builtin_interfaces/msg/Time",
                                                 sec=fields.sec, nanosec=fields.nanosec),
                           frame_id=fields.frame_id)


def joint_state_message(fields: JointStateFields) -> Any:
    """``sensor_msgs/JointState`` from
    :func:`~hecker_dynamics.ros.joint_states.snapshot_joint_states`."""
    return default_message(JOINT_STATE, header=header_message(fields.header),
                           name=list(fields.name),
                           position=np.array(fields.position, dtype=np.float64),
                           velocity=np.array(fields.velocity, dtype=np.float64),
                           effort=np.array(fields.effort, dtype=np.float64))


def _vector(msgtype: str, xyz: Sequence[float]) -> Any:
    return default_message(msgtype, x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


def laser_scan_message(fields: LaserScanFields) -> Any:
    """``sensor_msgs/LaserScan`` from :func:`~hecker_dynamics.ros.sensor_fields.laser_scan_fields`
    (ranges float32 as on the wire, no intensities)."""
    return default_message(
        LASER_SCAN, header=header_message(fields.header), angle_min=fields.angle_min,
        angle_max=fields.angle_max, angle_increment=fields.angle_increment,
        time_increment=fields.time_increment, scan_time=fields.scan_time,
        range_min=fields.range_min, range_max=fields.range_max,
        ranges=np.array(fields.ranges, dtype=np.float32))


def imu_message(fields: ImuFields) -> Any:
    """``sensor_msgs/Imu`` from :func:`~hecker_dynamics.ros.sensor_fields.imu_fields`."""
    x, y, z, w = fields.orientation
    return default_message(
        IMU, header=header_message(fields.header),
        orientation=default_message("geometry_msgs/msg/Quaternion", x=x, y=y, z=z, w=w),
        orientation_covariance=np.array(fields.orientation_covariance, dtype=np.float64),
        angular_velocity=_vector("geometry_msgs/msg/Vector3", fields.angular_velocity),
        angular_velocity_covariance=np.array(fields.angular_velocity_covariance,
                                             dtype=np.float64),
        linear_acceleration=_vector("geometry_msgs/msg/Vector3", fields.linear_acceleration),
        linear_acceleration_covariance=np.array(fields.linear_acceleration_covariance,
                                                dtype=np.float64))


def occupancy_grid_message(fields: OccupancyGridFields) -> Any:
    """``nav_msgs/OccupancyGrid`` from
    :func:`~hecker_dynamics.ros.map_fields.occupancy_grid_fields`."""
    sec, nanosec = fields.map_load_time
    return default_message(
        OCCUPANCY_GRID, header=header_message(fields.header),
        info=default_message(
            "nav_msgs/msg/MapMetaData",
            map_load_time=default_message("builtin_interfaces/msg/Time", sec=sec,
                                          nanosec=nanosec),
            resolution=fields.resolution, width=fields.width, height=fields.height,
            origin=pose_message(fields.origin)),
        data=np.frombuffer(fields.data, dtype=np.int8))


def contact_event_message(fields: ContactEventFields) -> Any:
    """``hecker_dynamics/msg/ContactEvent`` from
    :func:`~hecker_dynamics.ros.contact_fields.contact_event_fields`."""
    return default_message(CONTACT_EVENT, header=header_message(fields.header),
                           event=fields.event, surface=fields.surface, body_a=fields.body_a,
                           body_b=fields.body_b, normal_impulse=fields.normal_impulse,
                           tangent_impulse=fields.tangent_impulse)


def pose_message(fields: Pose) -> Any:
    x, y, z, w = fields.orientation
    return default_message(
        "geometry_msgs/msg/Pose", position=_vector("geometry_msgs/msg/Point", fields.position),
        orientation=default_message("geometry_msgs/msg/Quaternion", x=float(x), y=float(y),
                                    z=float(z), w=float(w)))


def pose_stamped_message(fields: PoseStampedFields) -> Any:
    """``geometry_msgs/PoseStamped`` from :func:`~hecker_dynamics.ros.fields.pose_fields`."""
    return default_message(POSE_STAMPED, header=header_message(fields.header),
                           pose=pose_message(fields.pose))


def twist_message(fields: TwistFields) -> Any:
    """``geometry_msgs/Twist`` from :func:`~hecker_dynamics.ros.fields.twist_fields`."""
    return default_message(TWIST, linear=_vector("geometry_msgs/msg/Vector3", fields.linear),
                           angular=_vector("geometry_msgs/msg/Vector3", fields.angular))


def odometry_message(fields: OdometryFields) -> Any:
    """``nav_msgs/Odometry`` from :func:`~hecker_dynamics.ros.fields.odometry_fields`
    (covariances zero)."""
    return default_message(
        ODOMETRY, header=header_message(fields.header), child_frame_id=fields.child_frame_id,
        pose=default_message("geometry_msgs/msg/PoseWithCovariance",
                             pose=pose_message(fields.pose)),
        twist=default_message("geometry_msgs/msg/TwistWithCovariance",
                              twist=twist_message(fields.twist)))


def marker_message(fields: MarkerFields) -> Any:
    r, g, b, a = fields.color
    return default_message(
        "visualization_msgs/msg/Marker", header=header_message(fields.header), ns=fields.ns,
        id=int(fields.id), type=int(fields.type), action=int(fields.action),
        pose=pose_message(fields.pose), scale=_vector("geometry_msgs/msg/Vector3", fields.scale),
        color=default_message("std_msgs/msg/ColorRGBA", r=float(r), g=float(g), b=float(b),
                              a=float(a)),
        points=[_vector("geometry_msgs/msg/Point", p) for p in fields.points])


def marker_array_message(markers: Iterable[MarkerFields]) -> Any:
    """``visualization_msgs/MarkerArray`` from
    :func:`~hecker_dynamics.ros.markers.marker_fields` results."""
    return default_message(MARKER_ARRAY, markers=[marker_message(m) for m in markers])


def diagnostic_array_message(fields: DiagnosticFields, head: Header) -> Any:
    """``diagnostic_msgs/DiagnosticArray`` with one status from
    :func:`~hecker_dynamics.ros.diagnostics.diagnostic_fields`."""
    status = default_message(
        "diagnostic_msgs/msg/DiagnosticStatus", level=int(fields.level), name=fields.name,
        message=fields.message, hardware_id=fields.hardware_id,
        values=[default_message("diagnostic_msgs/msg/KeyValue", key=k, value=v)
                for k, v in fields.values])
    return default_message(DIAGNOSTIC_ARRAY, header=header_message(head), status=[status])


def tf_message(transforms: Iterable[TransformFields]) -> Any:
    """``tf2_msgs/TFMessage`` from :func:`~hecker_dynamics.ros.tf.body_transforms` or
    :func:`~hecker_dynamics.ros.tf.point_transforms`."""
    return default_message(TF_MESSAGE, transforms=[
        default_message(
            "geometry_msgs/msg/TransformStamped", header=header_message(t.header),
            child_frame_id=t.child_frame_id,
            transform=default_message(
                "geometry_msgs/msg/Transform",
                translation=_vector("geometry_msgs/msg/Vector3", t.translation),
                rotation=default_message("geometry_msgs/msg/Quaternion",
                                         **dict(zip("xyzw", map(float, t.rotation))))))
        for t in transforms])


def applied_wrench_msg(fields: AppliedWrenchFields) -> Any:
    """``hecker_dynamics/msg/AppliedWrench`` from
    :func:`~hecker_dynamics.ros.fields.applied_wrench_fields`."""
    dsec, dnanosec = fields.duration
    return default_message(
        APPLIED_WRENCH, header=header_message(fields.header), body=fields.body, id=fields.id,
        point=_vector("geometry_msgs/msg/Point", fields.point),
        wrench=default_message("geometry_msgs/msg/Wrench",
                               force=_vector("geometry_msgs/msg/Vector3", fields.force),
                               torque=_vector("geometry_msgs/msg/Vector3", fields.torque)),
        duration=default_message("builtin_interfaces/msg/Duration", sec=dsec,
                                  nanosec=dnanosec))


def applied_wrench_message(stamp_ns: int, frame_id: str, body: str, source: str,
                           point: Sequence[float], force: Sequence[float], torque: float,
                           duration_ns: int) -> Any:
    """A ``hecker_dynamics/msg/AppliedWrench`` with an in-plane wrench (the inverse of
    :func:`~hecker_dynamics.ros.fields.applied_wrench_to_command`)."""
    return applied_wrench_msg(applied_wrench_fields(WrenchCommand(
        stamp_ns, body, source, frame_id, (point[0], point[1]), (force[0], force[1]),
        torque, duration_ns)))


def wrench_stamped_message(stamp_ns: int, frame_id: str, force: Sequence[float],
                           torque: float) -> Any:
    """A ``geometry_msgs/WrenchStamped`` with an in-plane wrench."""
    sec, nanosec = stamp_from_ns(stamp_ns)
    return default_message(
        WRENCH_STAMPED, header=header_message(Header(sec, nanosec, frame_id)),
        wrench=default_message(
            "geometry_msgs/msg/Wrench",
            force=_vector("geometry_msgs/msg/Vector3", (force[0], force[1], 0.0)),
            torque=_vector("geometry_msgs/msg/Vector3", (0.0, 0.0, torque))))


def session_info_message(fields: SessionFields) -> Any:
    """``hecker_dynamics/msg/SessionInfo`` of a session record."""
    return default_message(
        SESSION_INFO, header=header_message(header(fields.frame_id, fields.start_ns)),
        **fields.message_values())


def session_fields(msg: Any) -> SessionFields:
    """The session record of a ``SessionInfo`` message (the inverse of
    :func:`session_info_message`)."""
    return SessionFields(
        stamp_ns_of(msg) or 0, msg.header.frame_id, int(msg.session), msg.reason, msg.scene,
        msg.fingerprint, msg.integrator, int(msg.step_ns), int(msg.publish_period_ns),
        bool(msg.play_script), bool(msg.lockstep), int(msg.max_catch_up_steps),
        int(msg.keyframe_period_ns), int(msg.next_event), msg.version)


def keyframe_message(fields: KeyframeFields) -> Any:
    """``hecker_dynamics/msg/Keyframe`` of a keyframe record."""
    return default_message(
        KEYFRAME, header=header_message(header("", fields.stamp_ns)), session=fields.session,
        steps=fields.steps, next_event=fields.next_event, bodies=list(fields.bodies),
        q=np.array(fields.q, dtype=np.float64), v=np.array(fields.v, dtype=np.float64),
        state=fields.state)


def keyframe_fields(msg: Any) -> KeyframeFields:
    """The keyframe record of a ``Keyframe`` message."""
    return KeyframeFields(stamp_ns_of(msg) or 0, int(msg.session), int(msg.steps),
                          int(msg.next_event), tuple(msg.bodies),
                          tuple(float(x) for x in msg.q), tuple(float(x) for x in msg.v),
                          msg.state)


#: The message type an input event of each kind holds.
_EVENT_TYPES = {APPLIED_WRENCH_EVENT: APPLIED_WRENCH, WRENCH_STAMPED_EVENT: WRENCH_STAMPED,
                MOTOR_SPEED_EVENT: FLOAT64, CMD_VEL_EVENT: TWIST}
#: The slot of an ``InputEvent`` that holds a message of each type.
_EVENT_SLOTS = {APPLIED_WRENCH: "applied_wrench", WRENCH_STAMPED: "wrench_stamped",
                FLOAT64: "motor_speed", TWIST: "cmd_vel"}


def input_event_message(fields: InputEventFields) -> Any:
    """``hecker_dynamics/msg/InputEvent`` of an input event record (``fields.message`` a
    rosbags ``AppliedWrench``, ``WrenchStamped``, ``Float64`` or ``Twist``)."""
    held = _EVENT_TYPES[fields.kind]
    messages = {slot: fields.message if msgtype == held else default_message(msgtype)
                for msgtype, slot in _EVENT_SLOTS.items()}
    sec, nanosec = stamp_from_ns(fields.arrival_ns)
    return default_message(
        INPUT_EVENT, header=header_message(header("", fields.stamp_ns)),
        session=max(fields.session, 0), sequence=fields.sequence, topic=fields.topic,
        arrival=default_message("builtin_interfaces/msg/Time", sec=sec, nanosec=nanosec),
        kind=fields.kind, **messages, accepted=fields.accepted, reason=fields.reason)


def input_event_unused_slots(msg: Any) -> list[str]:
    """The slots of an ``InputEvent`` message that its kind leaves unused but that hold
    something other than the default message, which the node always leaves there."""
    store = typestore()
    held = _EVENT_TYPES.get(int(msg.kind))
    return [slot for msgtype, slot in _EVENT_SLOTS.items() if msgtype != held
            and bytes(store.serialize_cdr(getattr(msg, slot), msgtype))
            != bytes(store.serialize_cdr(default_message(msgtype), msgtype))]


def input_event_fields(msg: Any) -> InputEventFields:
    """The input event record of an ``InputEvent`` message; ``message`` is the input."""
    kind = int(msg.kind)
    return InputEventFields(
        stamp_ns_of(msg) or 0, int(msg.session), int(msg.sequence), msg.topic,
        ns_from_stamp(msg.arrival.sec, msg.arrival.nanosec), kind,
        msg.wrench_stamped if kind == WRENCH_STAMPED_EVENT else
        msg.motor_speed if kind == MOTOR_SPEED_EVENT else
        msg.cmd_vel if kind == CMD_VEL_EVENT else msg.applied_wrench,
        bool(msg.accepted), msg.reason)


def world_event_message(fields: WorldEventFields) -> Any:
    """``hecker_dynamics/msg/WorldEvent`` of a world change record."""
    return default_message(
        WORLD_EVENT, header=header_message(header("", fields.stamp_ns)),
        session=max(fields.session, 0), sequence=fields.sequence, kind=int(fields.kind),
        body=fields.body, values=np.array(fields.values, dtype=np.float64),
        time_ns=fields.time_ns, accepted=fields.accepted, reason=fields.reason,
        spec=fields.spec, collisions=list(fields.collisions))


def world_event_fields(msg: Any) -> WorldEventFields:
    """The world change record of a ``WorldEvent`` message."""
    return WorldEventFields(stamp_ns_of(msg) or 0, int(msg.session), int(msg.sequence),
                            WorldChange(int(msg.kind)), msg.body,
                            tuple(float(x) for x in msg.values), int(msg.time_ns),
                            bool(msg.accepted), msg.reason, msg.spec,
                            tuple(str(c) for c in msg.collisions))


def stamp_ns_of(msg: Any) -> Optional[int]:
    """The header stamp of a message in ns, or None for a message without a header.

    A ``MarkerArray`` takes the stamp of its first marker, a ``TFMessage`` that of its
    first transform.
    """
    head = getattr(msg, "header", None)
    if head is None:
        items = getattr(msg, "markers", None) or getattr(msg, "transforms", None)
        if items:
            head = items[0].header
    if head is None:
        return None
    return ns_from_stamp(head.stamp.sec, head.stamp.nanosec)


# ----------------------------------------------------------------------------- reading

@dataclass(frozen=True, slots=True)
class BagMessage:
    """One message of a bag: topic, type, log time and the CDR bytes, and the bag read it
    from (None: made here), which a refusal of its bytes names."""

    index: int  # position in the bag's log-time order
    topic: str
    msgtype: str
    log_ns: int
    raw: bytes
    bag: Optional[Path] = field(default=None, compare=False)

    def decode(self) -> Any:
        """The message as a rosbags object; raises :class:`BagError` if it is malformed."""
        try:
            return typestore().deserialize_cdr(self.raw, self.msgtype)
        except Exception as error:  # rosbags raises several kinds for bad bytes
            where = f"{self.bag}: " if self.bag is not None else ""
            raise BagError(f"{where}message {self.index} on '{self.topic}' at "
                           f"{seconds_text(self.log_ns)} s cannot be decoded as "
                           f"{self.msgtype}: {error}") from None


@dataclass
class BagContents:
    """A bag read into memory: topics with their types, and messages in log-time order."""

    path: Path
    storage: str
    topics: dict[str, str]  # topic -> message type
    messages: list[BagMessage]
    custom_data: dict[str, str] = field(default_factory=dict)
    definitions: dict[str, str] = field(default_factory=dict)  # type -> msgdef in the bag
    digests: dict[str, str] = field(default_factory=dict)  # topic -> RIHS01 hash ('' unknown)

    def check_type(self, topic: str, msgtype: str) -> None:
        """Raise :class:`BagError` unless ``topic`` has ``msgtype`` with the package's
        definition of it (same RIHS01 hash, when the bag records one)."""
        found = self.topics.get(topic)
        if found is None:
            raise BagError(f"{self.path}: no topic '{topic}'")
        if found != msgtype:
            raise BagError(f"{self.path}: topic '{topic}' has type {found}, expected {msgtype}")
        digest = self.digests.get(topic, "")
        if digest:
            ours = typestore().hash_rihs01(msgtype)
            if digest != ours:
                raise BagError(f"{self.path}: topic '{topic}' has another definition of "
                               f"{msgtype} than this package ({digest} != {ours})")

    def on(self, topic: str) -> list[BagMessage]:
        return [m for m in self.messages if m.topic == topic]

    def custom_int(self, key: str) -> Optional[int]:
        """An integer stored under ``hecker_dynamics.<key>`` in the bag's custom data."""
        value = self.custom_data.get(CUSTOM_PREFIX + key)
        if value is None:
            return None
        try:
            return int(value)
        except ValueError:
            raise BagError(f"{self.path}: custom data '{CUSTOM_PREFIX}{key}' is not an "
                           f"integer: {value!r}") from None


def _describe(error: BaseException) -> str:
    lines = str(error).strip().splitlines()
    text = lines[0] if lines else ""
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def read_bag(path: PathLike, topics: Optional[Iterable[str]] = None) -> BagContents:
    """Read a rosbag2 bag (directory with ``metadata.yaml``, or a bare ``.mcap``/``.db3``).

    Only messages on ``topics`` are loaded (all when None). Raises :class:`BagError` with a
    one-line reason for a missing path, a file that is not a bag, bad metadata, or a
    truncated or corrupt storage file.
    """
    from rosbags.rosbag2 import Reader

    path = Path(path)
    if not path.exists():
        raise BagError(f"{path}: " + ("is a broken symlink or a symlink loop"
                                      if path.is_symlink() else "no such bag"))
    if path.is_dir() and not (path / "metadata.yaml").exists():
        raise BagError(f"{path}: no metadata.yaml (a recording cut off before it was closed? "
                       f"'ros2 bag reindex {path}' writes it)")
    wanted = set(topics) if topics is not None else None
    _check_sqlite_logs(path)
    try:
        with Reader(path) as reader:
            connections = reader.connections
            bag_topics: dict[str, str] = {}
            definitions: dict[str, str] = {}
            digests: dict[str, str] = {}
            for conn in connections:
                previous = bag_topics.setdefault(conn.topic, conn.msgtype)
                if previous != conn.msgtype:
                    raise BagError(f"{path}: topic '{conn.topic}' has two types, "
                                   f"{previous} and {conn.msgtype}")
                # A second connection's definition would be decoded, and checked against
                # this package's (check_type), as the first one's: refuse two of them.
                known, digest = digests.get(conn.topic, ""), conn.digest or ""
                if known and digest and known != digest:
                    raise BagError(f"{path}: topic '{conn.topic}' has two definitions of "
                                   f"{conn.msgtype}, type hashes {known} and {digest}")
                digests[conn.topic] = known or digest
                if conn.msgdef.data:
                    definitions.setdefault(conn.msgtype, conn.msgdef.data)
            if path.is_dir() and not getattr(reader, "paths", [None]):
                raise BagError(f"{path}: the metadata lists no storage files "
                               "(relative_file_paths is empty)")
            selected = [c for c in connections if wanted is None or c.topic in wanted]
            messages: list[tuple[int, int, str, str, bytes]] = []
            read: dict[int, int] = {c.id: 0 for c in selected}
            if selected:
                for conn, log_ns, raw in reader.messages(connections=selected):
                    messages.append((log_ns, len(messages), conn.topic, conn.msgtype,
                                     bytes(raw)))
                    read[conn.id] += 1
            _check_counts(path, reader.message_count, connections, read,
                          complete=len(selected) == len(connections))
            _check_times(path, reader.start_time, reader.end_time, messages)
            if path.is_dir():
                _check_files(path, reader.message_count, reader.start_time, reader.end_time)
            custom = dict(reader.storage.metadata.custom or {}) \
                if hasattr(reader.storage, "metadata") else {}
            if path.is_file() and not custom:
                custom = _embedded_custom_data(path)
            storage = _storage_name(path)
    except BagError:
        raise
    except (sqlite3.Error, OSError) as error:
        raise BagError(f"{path}: cannot read the bag ({_describe(error)}); is it truncated "
                       "or corrupt?") from None
    except Exception as error:  # rosbags: ReaderError, struct/zstd/yaml errors on bad files
        raise BagError(f"{path}: cannot read the bag ({_describe(error)}); is it truncated "
                       "or corrupt?") from None
    messages.sort(key=lambda m: (m[0], m[1]))
    # In place, each tuple let go as its message is made: not both lists at once.
    ordered: list[Any] = messages
    for i, (log_ns, _, topic, msgtype, raw) in enumerate(messages):
        ordered[i] = BagMessage(i, topic, msgtype, log_ns, raw, path)
    return BagContents(
        path=path, storage=storage, topics=bag_topics, messages=ordered,
        custom_data={str(k): str(v) for k, v in custom.items()},
        definitions=definitions, digests=digests)


def _embedded_custom_data(path: Path) -> dict[str, str]:
    """The custom data of the bag whose storage file ``path`` is, read from the metadata
    its writer embedded in it (rosbag2 and rosbags write the bag's metadata, which a bag
    folder keeps in ``metadata.yaml``, into an mcap's ``rosbag2`` metadata record and a
    sqlite3 database's ``metadata`` table too): a bag's session given by its file
    alone. {} where it holds none."""
    import yaml

    try:
        text = _mcap_metadata(path) if path.suffix == ".mcap" else _sqlite_metadata(path)
        info = yaml.safe_load(text) if text else None
    except Exception:  # no metadata, or none of a form this reads: as a file without
        return {}
    if isinstance(info, dict):
        info = info.get("rosbag2_bagfile_information", info)
    custom = info.get("custom_data") if isinstance(info, dict) else None
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else {}


def _mcap_metadata(path: Path) -> Optional[str]:
    """The ``serialized_metadata`` of an mcap file's ``rosbag2`` metadata record, found
    among its top-level records (chunks are skipped whole), or None."""
    def number(data: bytes, at: int) -> int:
        return int.from_bytes(data[at:at + 4], "little")

    with path.open("rb") as stream:
        stream.seek(8)  # the magic
        while len(head := stream.read(9)) == 9:
            length = int.from_bytes(head[1:], "little")
            if head[0] == 0x02:  # the footer
                return None
            if head[0] != 0x0C:  # not a metadata record
                stream.seek(length, os.SEEK_CUR)
                continue
            body = stream.read(length)
            name_end = 4 + number(body, 0)
            if body[4:name_end] != b"rosbag2":
                continue
            at, end = name_end + 4, name_end + 4 + number(body, name_end)
            while at < end:
                key_end = at + 4 + number(body, at)
                value_end = key_end + 4 + number(body, key_end)
                if body[at + 4:key_end] == b"serialized_metadata":
                    return body[key_end + 4:value_end].decode()
                at = value_end
    return None


def _sqlite_metadata(path: Path) -> Optional[str]:
    """The latest metadata of a sqlite3 storage file's ``metadata`` table, or None."""
    with contextlib.closing(sqlite3.connect(f"{path.resolve().as_uri()}?immutable=1",
                                            uri=True)) as database:
        row = database.execute("SELECT metadata FROM metadata ORDER BY id DESC LIMIT 1"
                               ).fetchone()
    return str(row[0]) if row else None


#: The first bytes of a rollback journal that still holds a transaction's old pages.
_HOT_JOURNAL = bytes.fromhex("d9d505f920a163d7")


def _check_sqlite_logs(path: Path) -> None:
    """Refuse a sqlite3 bag whose database has a log beside it that SQLite would read and
    ``rosbags`` does not: it opens the file as immutable, so a write-ahead log (``-wal``,
    rosbag2's ``resilient`` preset) left by a writer that did not close it hides the
    changes it holds, and a hot rollback journal (``-journal``) the old pages of a
    transaction cut off half written. The check would compare other messages than
    ``ros2 bag play`` plays."""
    files = [path] if path.is_file() else sorted(path.glob("*.db3"))
    # SQLite keeps a linked database's logs beside the file the link names.
    for database in dict.fromkeys(f for given in files for f in (given, given.resolve())):
        wal = database.with_name(database.name + "-wal")
        journal = database.with_name(database.name + "-journal")
        with contextlib.suppress(OSError):
            if wal.stat().st_size > 0:
                raise BagError(f"{path}: {wal.name} holds changes not yet in {database.name} "
                               "(its writer did not close it, or still writes); when no one "
                               f"writes the bag, merge them: sqlite3 {database} "
                               "'PRAGMA wal_checkpoint(TRUNCATE);'")
        with contextlib.suppress(OSError), journal.open("rb") as stream:
            if stream.read(len(_HOT_JOURNAL)) == _HOT_JOURNAL:
                raise BagError(f"{path}: {journal.name} holds a transaction cut off half "
                               f"written into {database.name}; when no one writes the bag, "
                               f"roll it back: sqlite3 {database} 'PRAGMA quick_check;'")


def _count(path: Path, value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise BagError(f"{path}: {what} in the metadata is {quoted(value)}, not a count of "
                       "messages")
    return value


def _check_counts(path: Path, total: Any, connections: Sequence[Any], read: dict[int, int],
                  *, complete: bool) -> None:
    """Refuse a bag whose storage gave other message counts than its metadata states: a
    truncated or corrupt file read in part, or metadata that is not the storage's."""
    for conn in connections:
        stated = _count(path, conn.msgcount, f"message_count of '{conn.topic}'")
        if conn.id in read and read[conn.id] != stated:
            raise BagError(f"{path}: read {read[conn.id]} messages on '{conn.topic}' but the "
                           f"metadata states message_count {stated}; is the bag truncated "
                           "or corrupt?")
    stated = _count(path, total, "message_count")
    if complete and sum(read.values()) != stated:
        raise BagError(f"{path}: read {sum(read.values())} messages but the metadata states "
                       f"message_count {stated}; is the bag truncated or corrupt?")


def _check_times(path: Path, start: Any, end: Any,
                 messages: list[tuple[int, int, str, str, bytes]]) -> None:
    """Refuse messages logged outside the span the metadata states (a corrupt log time)."""
    if not messages:
        return
    first, last = min(m[0] for m in messages), max(m[0] for m in messages)
    if isinstance(start, int) and isinstance(end, int) and not start <= first <= last < end:
        raise BagError(f"{path}: messages are logged from {first} ns to {last} ns, outside "
                       f"the span the metadata states ({start} ns to {end} ns); is the bag "
                       "corrupt?")


def _check_files(path: Path, total: int, start: Any, end: Any) -> None:
    """Refuse a bag whose metadata's ``files`` (rosbag2's per-file entries, when it has them)
    do not add up to the bag it describes: other storage files than
    ``relative_file_paths``, message counts that do not sum to the bag's (an edited or
    truncated recording), or spans of the files with messages that do not make the bag's."""
    import yaml

    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    files = info.get("files")
    if files is None:
        return
    if not isinstance(files, list) or not all(isinstance(f, dict) for f in files):
        raise BagError(f"{path}: files in the metadata is {quoted(files)}, not a list of "
                       "file entries")
    named = [f.get("path") for f in files]
    if sorted(map(str, named)) != sorted(map(str, info.get("relative_file_paths") or [])):
        raise BagError(f"{path}: the metadata's files ({', '.join(map(str, named))}) are not "
                       "its relative_file_paths; is the metadata edited?")
    counts = [_count(path, f.get("message_count"), f"message_count of file '{f.get('path')}'")
              for f in files]
    if sum(counts) != total:
        held = " + ".join(map(str, counts)) + (f" = {sum(counts)}" if len(counts) > 1 else "")
        raise BagError(f"{path}: the metadata's files hold {held} messages but the bag "
                       f"message_count {total}; is the bag truncated or its metadata edited?")
    spans = [(_span(path, f, "starting_time", "nanoseconds_since_epoch"),
              _span(path, f, "duration", "nanoseconds")) for f, n in zip(files, counts) if n]
    if spans and isinstance(start, int) and isinstance(end, int) and \
            (min(s for s, _ in spans), max(s + d for s, d in spans) + 1) != (start, end):
        raise BagError(f"{path}: the metadata's files span other times than the bag "
                       f"({start} ns to {end - 1} ns); is the metadata edited?")


def _span(path: Path, entry: dict[str, Any], key: str, field_name: str) -> int:
    value = entry.get(key)
    value = value.get(field_name) if isinstance(value, dict) else None
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise BagError(f"{path}: {key} of file '{entry.get('path')}' in the metadata is "
                       f"{quoted(value)}, not a time in nanoseconds")
    return value


def _storage_name(path: Path) -> str:
    if path.is_file():
        return "sqlite3" if path.suffix == ".db3" else path.suffix.lstrip(".")
    try:
        import yaml

        info = yaml.safe_load((path / "metadata.yaml").read_text())
        return str(info["rosbag2_bagfile_information"]["storage_identifier"])
    except Exception:
        return "unknown"


# ----------------------------------------------------------------------------- writing

class BagWriter:
    """Writes a rosbag2 bag atomically: into a temporary directory of its own (two writers
    of one bag never share one) renamed on success.

    Topics are added on first use, in that order, with the QoS profile the node's publisher
    on the topic offers (:func:`~hecker_dynamics.ros.names.output_qos`); the bag
    holds the message definitions and type hashes, and ``custom_data`` entries under
    ``hecker_dynamics.``. Same calls in the same order give the same bytes.

        with BagWriter(path, storage="mcap") as bag:
            bag.write("/left/pose", POSE_STAMPED, stamp_ns, msg)
    """

    def __init__(self, path: PathLike, storage: str = "mcap", *, overwrite: bool = False,
                 custom_data: Optional[dict[str, str]] = None, compress: bool = False) -> None:
        if storage not in STORAGES:
            raise BagError(f"unknown storage '{storage}' (choose from {', '.join(STORAGES)})")
        self.path = Path(path)
        if self.path.name in ("", ".", "..") or os.fspath(path) == "-":  # '-': stdout
            raise BagError(f"'{path}' does not name a new bag directory (give a name such "
                           "as out_bag)")
        self.storage = storage
        self.overwrite = overwrite
        self.compress = compress
        self.custom_data = dict(custom_data or {})
        self._tmp: Optional[Path] = None  # the temporary directory open() makes
        self._lock: Optional[int] = None  # its lock file, held while this writes
        self._writer: Any = None
        self._connections: dict[str, Any] = {}
        self._types: dict[str, str] = {}
        self.count = 0

    def __enter__(self) -> BagWriter:
        self.open()
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def open(self) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

        try:
            exists = self.path.exists()
        except OSError as error:  # a name too long, a loop of links: nothing to write to
            raise BagError(f"{self.path}: cannot create the bag "
                           f"({error.strerror or _describe(error)})") from None
        if not exists and self.path.is_symlink():  # found only at the end, "made meanwhile"
            raise BagError(f"{self.path} is a broken symlink or a symlink loop; remove it "
                           "or give another name")
        if exists and not self.overwrite:
            raise BagError(f"{self.path} exists already (remove it or pass --overwrite)")
        if exists and not _looks_like_bag(self.path):
            raise BagError(f"{self.path} exists and is not a bag; not overwriting it")
        if not self.path.parent.is_dir():
            raise BagError(f"{self.path}: " + (f"{self.path.parent} is not a folder"
                                               if self.path.parent.exists() else
                                               f"the folder {self.path.parent} does not exist"))
        plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
        try:
            _remove_killed_writers(self.path)
            # A name no other writer has: a second command writing this bag meanwhile
            # would otherwise take the first's files for a killed run's and remove them.
            # The storage file is named after the directory, so write to a directory of
            # the final name inside the temporary one and move it out at the end.
            self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.partial-",
                                              dir=self.path.parent))
            self._lock = _hold_writer_lock(self._tmp)
        except OSError as error:
            self._release()  # a directory made before its lock failed is no killed run's
            raise BagError(f"{self.path}: cannot create the bag "
                           f"({error.strerror or _describe(error)})") from None
        try:
            self._writer = Writer(self._tmp / self.path.name, version=BAG_VERSION,
                                  storage_plugin=plugin)
            if self.compress and self.storage == "mcap":
                self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            for key, value in sorted(self.custom_data.items()):
                self._writer.set_custom_data(CUSTOM_PREFIX + key, str(value))
            self._writer.open()
        except Exception as error:
            self._release()
            raise BagError(f"{self.path}: cannot create the bag ({_describe(error)})") from None

    def add_topic(self, topic: str, msgtype: str, qos: Optional[list[Any]] = None) -> None:
        """Declare ``topic`` now (so it appears in the bag even with no messages), offered
        with ``qos`` (default: the QoS of the node's publisher on the topic)."""
        if topic in self._connections:
            if self._types[topic] != msgtype:
                raise BagError(f"topic '{topic}' written with two types, {self._types[topic]} "
                               f"and {msgtype}")
            return
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=typestore(), serialization_format="cdr",
            offered_qos_profiles=rosbag_qos(output_qos(topic)) if qos is None else qos)
        self._types[topic] = msgtype

    def write(self, topic: str, msgtype: str, log_ns: int, msg: Any) -> bytes:
        """Serialize ``msg`` and write it at log time ``log_ns``; returns the bytes."""
        self.add_topic(topic, msgtype)
        raw = bytes(typestore().serialize_cdr(msg, msgtype))
        self.write_raw(topic, log_ns, raw)
        return raw

    def write_raw(self, topic: str, log_ns: int, raw: bytes) -> None:
        if log_ns < 0:
            raise BagError(f"cannot write a message on '{topic}' at negative time {log_ns} ns")
        self._writer.write(self._connections[topic], int(log_ns), raw)
        self.count += 1

    def close(self) -> None:
        try:
            self._writer.close()
        except Exception as error:
            self.abort()
            raise BagError(f"{self.path}: cannot finish the bag ({_describe(error)})") from None
        tmp = self._tmp
        assert tmp is not None  # made by open()
        try:
            if os.path.lexists(self.path):  # made meanwhile, by another command?
                if not self.overwrite or not _looks_like_bag(self.path):
                    self.abort()
                    raise BagError(f"{self.path} exists (made while this ran)"
                                   + ("; remove it or pass --overwrite" if not self.overwrite
                                      else " and is not a bag; not overwriting it"))
                # Moved aside whole, then removed: never a bag half deleted under its name.
                os.replace(self.path, tmp / "replaced")
            os.replace(tmp / self.path.name, self.path)
        except OSError as error:
            replaced = tmp / "replaced"
            if os.path.lexists(replaced) and not os.path.lexists(self.path):
                with contextlib.suppress(OSError):  # the old bag back, not lost with this
                    os.replace(replaced, self.path)
            self.abort()
            raise BagError(f"{self.path}: cannot finish the bag "
                           f"({error.strerror or _describe(error)})") from None
        self._release()

    def abort(self) -> None:
        if self._writer is not None:
            with contextlib.suppress(Exception):
                self._writer.abort()
        self._release()

    def _release(self) -> None:
        """Let go of the temporary directory's lock, then remove the directory. In that
        order: NFS keeps a removed file that is still open as a '.nfs*' file, so the
        directory could not be removed; and a writer that takes the lock meanwhile only
        removes the same directory (nothing in it is wanted any more)."""
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)


#: The file a live writer holds locked in its temporary directory.
_WRITER_LOCK = "writer.lock"


def _hold_writer_lock(directory: Path) -> Optional[int]:
    """Lock a file in ``directory`` for as long as this process keeps it open (the system
    lets go when the process ends, however it ends). It gets its name only once locked, so
    that no other writer finds it unlocked."""
    if fcntl is None:
        return None
    fd, name = tempfile.mkstemp(dir=directory)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        # Whose: a lock taken on another host of a file system whose locks are each host's
        # own (NFS mounted nolock) says nothing of that writer, so only this host's count.
        os.write(fd, socket.gethostname().encode())
    except OSError:  # a file system without locks (NFS without its lock daemon: ENOLCK)
        os.close(fd)
        os.unlink(name)
        return None  # written unlocked, as without fcntl: if killed, its directory stays
    try:
        os.rename(name, directory / _WRITER_LOCK)
    except OSError:
        os.close(fd)
        raise
    return fd


def _remove_killed_writers(path: Path) -> None:
    """Remove what killed writers of the bag ``path`` left: temporary directories whose lock
    no process holds, and the one directory or file of the name earlier versions used."""
    for stale in path.parent.glob(f".{glob.escape(path.name)}.partial*"):
        if stale.name == f".{path.name}.partial":
            if stale.is_dir() and not stale.is_symlink():
                shutil.rmtree(stale, ignore_errors=True)
            else:
                stale.unlink(missing_ok=True)
            continue
        if fcntl is None or not stale.name.startswith(f".{path.name}.partial-"):
            continue
        try:
            fd = os.open(stale / _WRITER_LOCK, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
        except OSError:  # no lock yet (a writer making it now) or not a writer's directory
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            killed = stat.S_ISREG(os.fstat(fd).st_mode) and \
                os.read(fd, 256) == socket.gethostname().encode()
        except OSError:  # held: a live writer's (or no locks on this file system)
            killed = False
        os.close(fd)  # before the removal, for NFS (see BagWriter._release)
        if killed:
            shutil.rmtree(stale, ignore_errors=True)


def _looks_like_bag(path: Path) -> bool:
    return path.is_dir() and (path / "metadata.yaml").is_file()


def iter_decoded(messages: Iterable[BagMessage]) -> Iterator[tuple[BagMessage, Any]]:
    for message in messages:
        yield message, message.decode()
