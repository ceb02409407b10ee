"""The node's outputs as serialized ROS 2 messages (little-endian CDR), without ROS.

rclpy's ``Publisher.publish`` takes the bytes of a serialized message as well as a message
object and hands them to rmw as they are (``rcl_publish_serialized_message``). Building a
rosidl message in Python and converting it to C cost the node more than its simulation:
on Jazzy 14 us for a ``PoseStamped`` and 330 us for a ``MarkerArray`` of 20 markers, where
publishing their bytes takes 2.5 and 1.5 us. The bytes here are the ones rosbag2 stores
for the same message and rosbags writes; the tests hold them to rosbags' serializer for
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

from .fields import Header, OdometryFields, PoseStampedFields, TwistFields
from .joint_states import JointStateFields
from .markers import MarkerFields
from .outputs import OutputFields, OutputKind
from .tf import TransformFields

__all__ = ["ENCAPSULATION", "Part", "layout", "serialize_output", "SERIALIZERS"]

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


def _pose_stamped(fields: PoseStampedFields) -> bytes:
    """``geometry_msgs/PoseStamped``: header, position (x, y, z), orientation (x, y, z, w)."""
    head, head_values = _header(fields.header)
    pose = fields.pose
    return ENCAPSULATION + layout((head, ("d", 7))).pack(
        *head_values, *pose.position, *pose.orientation)


_TWIST = struct.Struct("<6d")


def _twist(fields: TwistFields) -> bytes:
    """``geometry_msgs/Twist``: linear, angular (six float64 need no padding)."""
    return ENCAPSULATION + _TWIST.pack(*fields.linear, *fields.angular)


def _odometry(fields: OdometryFields) -> bytes:
    """``nav_msgs/Odometry``, both covariances zero (unknown)."""
    head, head_values = _header(fields.header)
    child, child_values = _string(fields.child_frame_id)
    pose, twist = fields.pose, fields.twist
    return ENCAPSULATION + layout(
        (head, child, ("d", 7), ("zeros", 36), ("d", 6), ("zeros", 36))).pack(
        *head_values, *child_values, *pose.position, *pose.orientation, *twist.linear,
        *twist.angular)


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


def _marker(parts: list[Part], values: list[Any], fields: MarkerFields) -> None:
    """``visualization_msgs/Marker``: header, ns, id, type, action, pose, scale, color
    (float32 r, g, b, a), no lifetime (int32 sec, uint32 nanosec), not frame_locked
    (uint8), points, then :func:`_marker_defaults`."""
    head, head_values = _header(fields.header)
    ns, ns_values = _string(fields.ns)
    points = fields.points
    parts += (head, ns, ("i", 3), ("d", 10), ("f", 4), ("i", 1), ("I", 1), ("B", 1),
              ("I", 1), ("d", 3 * len(points)), _MARKER_TAIL)
    pose = fields.pose
    values += (*head_values, *ns_values, fields.id, fields.type, fields.action,
               *pose.position, *pose.orientation, *fields.scale, *fields.color, 0, 0, 0,
               len(points))
    for point in points:
        values += point
    values.append(_MARKER_DEFAULTS)


def _marker_array(markers: Iterable[MarkerFields]) -> bytes:
    """``visualization_msgs/MarkerArray``."""
    markers = tuple(markers)
    parts: list[Part] = [("I", 1)]
    values: list[Any] = [len(markers)]
    for marker in markers:
        _marker(parts, values, marker)
    return _pack(parts, values)


def _tf_message(transforms: Iterable[TransformFields]) -> bytes:
    """``tf2_msgs/TFMessage``: a ``geometry_msgs/TransformStamped`` each (header,
    child_frame_id, translation, rotation)."""
    transforms = tuple(transforms)
    parts: list[Part] = [("I", 1)]
    values: list[Any] = [len(transforms)]
    for transform in transforms:
        head, head_values = _header(transform.header)
        child, child_values = _string(transform.child_frame_id)
        parts += (head, child, ("d", 7))
        values += (*head_values, *child_values, *transform.translation, *transform.rotation)
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


#: The serializer of each output kind's fields (:class:`~.outputs.OutputFields`).
SERIALIZERS: dict[OutputKind, Callable[[Any], bytes]] = {
    OutputKind.POSE: _pose_stamped, OutputKind.TWIST: _twist,
    OutputKind.ODOMETRY: _odometry, OutputKind.MARKERS: _marker_array,
    OutputKind.TF: _tf_message, OutputKind.JOINT_STATE: _joint_state,
}


#: :data:`SERIALIZERS` by the identity of the kind: an Enum member hashes in Python code,
#: and the node looks a serializer up for every message it publishes.
_SERIALIZER_OF = {id(kind): serialize for kind, serialize in SERIALIZERS.items()}


def serialize_output(output: OutputFields) -> bytes:
    """The serialized message of one output, as rclpy's ``publish`` takes it."""
    return _SERIALIZER_OF[id(output.kind)](output.fields)
