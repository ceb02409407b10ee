"""The node's outputs as serialized ROS 2 messages (little-endian CDR), without ROS.

rclpy's ``Publisher.publish`` takes the bytes of a serialized message as well as a message
object and hands them to rmw as they are (``rcl_publish_serialized_message``). Building a
rosidl message in Python and converting it to C cost the node more than its simulation:
on Jazzy 14 us for a ``PoseStamped`` and 330 us for a ``MarkerArray`` of 20 markers, where
publishing their bytes takes 2.5 and 1.5 us. Building the fields tuples of every message
(:class:`~.outputs.SnapshotOutputs`) and packing each still cost 0.2 ms a tick for ten
bodies, so a tick's messages are packed straight from its body states
(:class:`SnapshotSerializer`). The bytes here are the ones rosbag2 stores for the same
message and rosbags writes; the tests hold them to rosbags' serializer of the fields for
every output kind, and on Jazzy to rclpy's.

CDR aligns each primitive to its own size, counted from the start of the payload (after
the four-byte encapsulation header); a string is its byte length with the terminating NUL
(uint32), then its bytes and the NUL; a sequence is its length (uint32), then its
elements, aligned as the first element needs when there is one.
"""
from __future__ import annotations

import functools
import struct
from collections.abc import Callable, Iterable
from typing import Any, Optional

from ..dynamics.simulation import Snapshot
from .contact_fields import ContactEventFields
from .fields import Header, body_pose, header, odometry_twist, twist_fields
from .joint_states import JointStateFields, snapshot_joint_states
from .map_fields import OccupancyGridFields
from .markers import MarkerFields, marker_pose
from .names import JOINT_STATES_TOPIC, MARKERS_TOPIC, TF_TOPIC
from .outputs import OutputFields, OutputKind, SnapshotOutputs
from .sensor_fields import ImuFields, LaserScanFields
from .tf import IDENTITY, TransformFields

__all__ = ["ENCAPSULATION", "Part", "Slots", "layout", "serialize_output", "SERIALIZERS",
           "SnapshotSerializer"]

#: Representation identifier CDR_LE and two bytes of options: what rmw writes.
ENCAPSULATION = b"\x00\x01\x00\x00"

#: One run of fields in a message's layout: a kind and a count. ``"d"``, ``"f"``,
#: ``"i"``, ``"I"``, ``"B"``: that many float64, float32, int32, uint32, uint8 (each packed
#: from a value); ``"zeros"``: that many float64 that are all zero (no values: padding
#: bytes are zero, as +0.0 is); ``"string"``: a string of that many bytes with its NUL
#: (two values: the size, then the bytes); ``"header"``: a ``std_msgs/Header`` whose
#: frame_id is that string (four values: sec, nanosec, size, bytes); ``"raw"``: that many
#: bytes serialized beforehand at a multiple of 4 (one value).
Part = tuple[str, int]

#: Where a message's values of a header and of a pose (7 float64: position, orientation)
#: start, in the values list of the array that holds it.
Slots = tuple[int, int]

_PRIMITIVES = {"d": 8, "f": 4, "i": 4, "I": 4, "B": 1}


@functools.lru_cache(maxsize=4096)
def layout(parts: tuple[Part, ...]) -> struct.Struct:
    """The packer of a message's payload: each part's fields aligned as CDR aligns them.

    A world has few layouts (one per topic, and one per marker and transform shape), so
    they are compiled once and the messages of every later tick are one ``pack`` each.
    """
    codes = ["<"]
    offset = 0

    def run(align: int, code: str, size: int) -> None:
        nonlocal offset
        pad = -offset % align
        codes.append(f"{pad}x{code}" if pad else code)
        offset += pad + size

    for kind, count in parts:
        if kind in _PRIMITIVES:
            if count:   # an empty run is not padded for either
                run(_PRIMITIVES[kind], f"{count}{kind}", _PRIMITIVES[kind] * count)
        elif kind == "zeros":
            run(8, f"{8 * count}x", 8 * count)
        elif kind == "string":
            run(4, f"I{count}s", 4 + count)     # struct pads the NUL
        elif kind == "header":
            run(4, f"iII{count}s", 12 + count)
        elif kind == "raw":
            if offset % 4:
                raise ValueError("raw bytes must start at a multiple of 4")
            run(4, f"{count}s", count)
        else:
            raise ValueError(f"unknown layout part '{kind}'")
    return struct.Struct("".join(codes))


@functools.lru_cache(maxsize=4096)
def _text(text: str) -> tuple[int, bytes]:
    """A string's CDR size (its UTF-8 bytes and the NUL) and its bytes."""
    data = text.encode()
    return len(data) + 1, data


#: The last header serialized with its part and values, one tuple: a tick's messages
#: share one header object (:class:`~.outputs.SnapshotOutputs`), so most look-ups end
#: here. Read and replaced whole, so a serialization in another thread never pairs one
#: header with another's values.
_last_header: Optional[tuple[Header, tuple[Part, tuple[Any, ...]]]] = None


def _header(fields: Header) -> tuple[Part, tuple[Any, ...]]:
    global _last_header
    last = _last_header
    if last is not None and last[0] is fields:
        return last[1]
    size, data = _text(fields.frame_id)
    done = ("header", size), (fields.sec, fields.nanosec, size, data)
    _last_header = (fields, done)
    return done


def _string(text: str) -> tuple[Part, tuple[Any, ...]]:
    size, data = _text(text)
    return ("string", size), (size, data)


def _pack(parts: list[Part], values: list[Any]) -> bytes:
    return ENCAPSULATION + layout(tuple(parts)).pack(*values)


#: ``geometry_msgs/Twist``: linear, angular (six float64 need no padding).
_TWIST = struct.Struct("<6d")


def _marker_defaults() -> bytes:
    """What a ``visualization_msgs/Marker`` (Jazzy's) has after its points and a shape
    leaves at the defaults: no colours (uint32 0), texture_resource, texture (a
    ``sensor_msgs/CompressedImage``: header, format, data), uv_coordinates, text,
    mesh_resource, mesh_file (filename, data), mesh_use_embedded_materials. Every part
    needs at most 4-byte alignment, so these bytes fit at any multiple of 4."""
    empty, empty_values = _string("")
    head, head_values = _header(Header(0, 0, ""))
    return layout((("I", 1), empty, head, empty, ("I", 2), empty, empty, empty, ("I", 1),
                   ("B", 1))).pack(0, *empty_values, *head_values, *empty_values, 0, 0,
                                   *empty_values, *empty_values, *empty_values, 0, 0)


_MARKER_DEFAULTS = _marker_defaults()
_MARKER_TAIL: Part = ("raw", len(_MARKER_DEFAULTS))


def _marker(parts: list[Part], values: list[Any], fields: MarkerFields) -> Slots:
    """``visualization_msgs/Marker``: header, ns, id, type, action, pose, scale, color
    (float32 r, g, b, a), no lifetime (int32 sec, uint32 nanosec), not frame_locked
    (uint8), points, then :func:`_marker_defaults`."""
    head, head_values = _header(fields.header)
    ns, ns_values = _string(fields.ns)
    points = fields.points
    parts += (head, ns, ("i", 3), ("d", 10), ("f", 4), ("i", 1), ("I", 1), ("B", 1),
              ("I", 1), ("d", 3 * len(points)), _MARKER_TAIL)
    pose = fields.pose
    slots = len(values), len(values) + 9
    values += (*head_values, *ns_values, fields.id, fields.type, fields.action,
               *pose.position, *pose.orientation, *fields.scale, *fields.color, 0, 0, 0,
               len(points))
    for point in points:
        values += point
    values.append(_MARKER_DEFAULTS)
    return slots


def _marker_array(markers: Iterable[MarkerFields]) -> bytes:
    """``visualization_msgs/MarkerArray``."""
    markers = tuple(markers)
    parts: list[Part] = [("I", 1)]
    values: list[Any] = [len(markers)]
    for marker in markers:
        _marker(parts, values, marker)
    return _pack(parts, values)


def _transform(parts: list[Part], values: list[Any], transform: TransformFields) -> Slots:
    """``geometry_msgs/TransformStamped``: header, child_frame_id, translation, rotation."""
    head, head_values = _header(transform.header)
    child, child_values = _string(transform.child_frame_id)
    parts += (head, child, ("d", 7))
    slots = len(values), len(values) + 6
    values += (*head_values, *child_values, *transform.translation, *transform.rotation)
    return slots


def _tf_message(transforms: Iterable[TransformFields]) -> bytes:
    """``tf2_msgs/TFMessage``: a ``TransformStamped`` each."""
    transforms = tuple(transforms)
    parts: list[Part] = [("I", 1)]
    values: list[Any] = [len(transforms)]
    for transform in transforms:
        _transform(parts, values, transform)
    return _pack(parts, values)


def _joint_state(fields: JointStateFields) -> bytes:
    """``sensor_msgs/JointState``: header, then the sequences name, position, velocity
    and effort, each its length and its elements."""
    head, head_values = _header(fields.header)
    parts: list[Part] = [head, ("I", 1)]
    values: list[Any] = [*head_values, len(fields.name)]
    for name in fields.name:
        string, string_values = _string(name)
        parts.append(string)
        values += string_values
    for sequence in (fields.position, fields.velocity, fields.effort):
        parts += (("I", 1), ("d", len(sequence)))
        values += (len(sequence), *sequence)
    return _pack(parts, values)


def _laser_scan(fields: LaserScanFields) -> bytes:
    """``sensor_msgs/LaserScan``: header, seven float32 (angles, times, range limits),
    the ranges (float32) and no intensities."""
    head, head_values = _header(fields.header)
    ranges = fields.ranges
    return _pack([head, ("f", 7), ("I", 1), ("f", len(ranges)), ("I", 1)],
                 [*head_values, fields.angle_min, fields.angle_max, fields.angle_increment,
                  fields.time_increment, fields.scan_time, fields.range_min, fields.range_max,
                  len(ranges), *ranges, 0])


def _imu(fields: ImuFields) -> bytes:
    """``sensor_msgs/Imu``: header, then orientation (4) and angular velocity and linear
    acceleration (3 each), each followed by its covariance (9), all float64."""
    head, head_values = _header(fields.header)
    return _pack([head, ("d", 37)],
                 [*head_values, *fields.orientation, *fields.orientation_covariance,
                  *fields.angular_velocity, *fields.angular_velocity_covariance,
                  *fields.linear_acceleration, *fields.linear_acceleration_covariance])


def _occupancy_grid(fields: OccupancyGridFields) -> bytes:
    """``nav_msgs/OccupancyGrid``: header, the map's load time (int32 sec, uint32
    nanosec), resolution (float32), width and height (uint32), origin (a Pose, 7 float64),
    then the cells (int8, their count first)."""
    head, head_values = _header(fields.header)
    origin = fields.origin
    return _pack([head, ("i", 1), ("I", 1), ("f", 1), ("I", 2), ("d", 7), ("I", 1),
                  ("raw", len(fields.data))],
                 [*head_values, *fields.map_load_time, fields.resolution, fields.width,
                  fields.height, *origin.position, *origin.orientation, len(fields.data),
                  fields.data])


def _contact_event(fields: ContactEventFields) -> bytes:
    """``hecker_dynamics/msg/ContactEvent``: header, event (uint8), surface, body_a and
    body_b, then the normal and tangent impulses (float64)."""
    head, head_values = _header(fields.header)
    parts: list[Part] = [head, ("B", 1)]
    values: list[Any] = [*head_values, fields.event]
    for text in (fields.surface, fields.body_a, fields.body_b):
        string, string_values = _string(text)
        parts.append(string)
        values += string_values
    parts.append(("d", 2))
    return _pack(parts, [*values, fields.normal_impulse, fields.tangent_impulse])


#: The serializer of each output kind's fields (:class:`~.outputs.OutputFields`) that the
#: node publishes apart from the snapshots' (:class:`SnapshotSerializer`): markers that
#: delete, ``/tf_static``, ``/map``, the sensors' readings, contact events, and joint
#: states, which a snapshot serializes this way too.
SERIALIZERS: dict[OutputKind, Callable[[Any], bytes]] = {
    OutputKind.MARKERS: _marker_array, OutputKind.TF: _tf_message,
    OutputKind.JOINT_STATE: _joint_state, OutputKind.LASER_SCAN: _laser_scan,
    OutputKind.IMU: _imu, OutputKind.OCCUPANCY_GRID: _occupancy_grid,
    OutputKind.CONTACT_EVENT: _contact_event,
}


def serialize_output(output: OutputFields) -> bytes:
    """The serialized message of one output, as rclpy's ``publish`` takes it."""
    return SERIALIZERS[output.kind](output.fields)


class SnapshotSerializer:
    """The messages of each snapshot serialized: what ``outputs`` (a
    :class:`~.outputs.SnapshotOutputs`) gives for it, in its order, as ``(topic, bytes)``.

    A world's layouts do not change from tick to tick: the fixed frame's name sizes every
    header, a body's name its odometry's child frame, its shapes its markers. So each
    message's packer is compiled here once, and the marker and transform arrays keep their
    values between ticks: a tick packs each message once, after writing the stamp and the
    poses into their slots, and builds none of the fields tuples.
    """

    def __init__(self, outputs: SnapshotOutputs) -> None:
        self.outputs = outputs
        scene = outputs.scene
        head = header(scene.frame_id, 0)
        head_part, _ = _header(head)
        self._pose = layout((head_part, ("d", 7)))
        self._children = tuple(_string(body.name) for body in scene.bodies)
        self._odometry = tuple(
            layout((head_part, child, ("d", 7), ("zeros", 36), ("d", 6), ("zeros", 36)))
            for child, _ in self._children)
        parts: list[Part] = [("I", 1)]
        #: The marker array's values, and per body its markers' templates and slots.
        self._marker_values: list[Any] = [sum(map(len, outputs.templates))]
        self._marker_slots = tuple(
            tuple((template, *_marker(parts, self._marker_values,
                                      template.fields._replace(header=head)))
                  for template in templates)
            for templates in outputs.templates)
        self._markers = layout(tuple(parts))
        parts = [("I", 1)]
        self._tf_values: list[Any] = [len(scene.bodies)]
        self._tf_slots = tuple(
            _transform(parts, self._tf_values, TransformFields(head, body.name,
                                                               (0.0, 0.0, 0.0), IDENTITY))
            for body in scene.bodies)
        self._tf = layout(tuple(parts))

    def __call__(self, snapshot: Snapshot) -> list[tuple[str, bytes]]:
        outputs = self.outputs
        scene = outputs.scene
        head_values = _header(header(scene.frame_id, snapshot.time_ns))[1]
        odometry = scene.publish_odometry
        markers, marker_values = scene.publish_markers, self._marker_values
        tf_values = self._tf_values
        messages = []
        for index, state in enumerate(snapshot.bodies):
            pose_topic, twist_topic, odometry_topic = outputs.topics[index]
            pose = body_pose(state)
            numbers = pose.position + pose.orientation
            twist = twist_fields(state, scene.twist_frame)
            messages.append((pose_topic, ENCAPSULATION + self._pose.pack(*head_values, *numbers)))
            messages.append((twist_topic,
                             ENCAPSULATION + _TWIST.pack(*twist.linear, *twist.angular)))
            if odometry:
                child = odometry_twist(state, twist, scene.twist_frame)
                messages.append((odometry_topic, ENCAPSULATION + self._odometry[index].pack(
                    *head_values, *self._children[index][1], *numbers, *child.linear,
                    *child.angular)))
            if markers:
                for template, at_head, at_pose in self._marker_slots[index]:
                    placed = marker_pose(template, state, pose)
                    marker_values[at_head:at_head + 4] = head_values
                    marker_values[at_pose:at_pose + 7] = placed.position + placed.orientation
            if outputs.tf:
                at_head, at_pose = self._tf_slots[index]
                tf_values[at_head:at_head + 4] = head_values
                tf_values[at_pose:at_pose + 7] = numbers
        if markers:
            messages.append((MARKERS_TOPIC, ENCAPSULATION + self._markers.pack(*marker_values)))
        if outputs.tf:
            messages.append((TF_TOPIC, ENCAPSULATION + self._tf.pack(*tf_values)))
        joint_states = snapshot_joint_states(scene.frame_id, snapshot)
        if joint_states is not None:
            messages.append((JOINT_STATES_TOPIC, _joint_state(joint_states)))
        return messages
