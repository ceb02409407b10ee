"""RViz markers of the bodies' shapes (``visualization_msgs/MarkerArray`` fields), without ROS."""
from __future__ import annotations

import zlib
from collections.abc import Iterable
from typing import Any, NamedTuple, Optional

from ..geometry.shapes import Circle, Polygon
from ..scene.load import BodySpec, Scene
from .fields import Header, Pose, Vec3, _rotate, body_pose, header

__all__ = ["MARKER_CYLINDER", "MARKER_LINE_STRIP", "MARKER_ADD", "MARKER_DELETE", "MARKER_COLORS",
           "MarkerFields", "MarkerTemplate", "MarkerKey", "marker_keys", "color_slot",
           "marker_templates", "marker_pose", "place_markers", "marker_fields", "delete_markers"]

# visualization_msgs/msg/Marker constants.
MARKER_CYLINDER = 3
MARKER_LINE_STRIP = 4
MARKER_ADD = 0
MARKER_DELETE = 2
#: Thickness of shape outlines and of circle discs in RViz, in metres.
MARKER_LINE_WIDTH = 0.02
MARKER_DISC_HEIGHT = 0.01
#: Body colors (r, g, b, a), cycled by :func:`color_slot`.
MARKER_COLORS = (
    (0.12, 0.47, 0.71, 1.0), (1.0, 0.5, 0.05, 1.0), (0.17, 0.63, 0.17, 1.0),
    (0.84, 0.15, 0.16, 1.0), (0.58, 0.4, 0.74, 1.0), (0.55, 0.34, 0.29, 1.0),
)


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


class MarkerTemplate(NamedTuple):
    """One shape's marker before it is placed: every field but the header and the pose
    (left at :data:`UNPLACED`), and ``offset``, the marker's origin in the body frame (a
    circle's center for its disc), or None when the marker sits at the body frame's origin."""

    fields: MarkerFields
    offset: Optional[tuple[float, float]]


#: A marker's identity in RViz: its namespace and id (an ``ADD`` of the same pair replaces it).
MarkerKey = tuple[str, int]


def marker_keys(templates: Iterable[MarkerTemplate]) -> frozenset[MarkerKey]:
    """The namespace and id of each of ``templates``' markers."""
    return frozenset((t.fields.ns, t.fields.id) for t in templates)


#: The header and pose of a marker not yet placed.
UNPLACED = (Header(0, 0, ""), Pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)))


def _shape_templates(shape: Any, ns: str, first_id: int,
                     color: tuple[float, float, float, float]) -> list[MarkerTemplate]:
    """Markers of one shape: a closed outline for a polygon; a disc and a radius for a circle."""
    head, pose = UNPLACED
    line_scale = (MARKER_LINE_WIDTH, 0.0, 0.0)
    if isinstance(shape, Polygon):
        outline = [(float(x), float(y), 0.0) for x, y in shape.vertices]
        outline.append(outline[0])
        return [MarkerTemplate(MarkerFields(head, ns, first_id, MARKER_LINE_STRIP, MARKER_ADD,
                                            pose, line_scale, color, tuple(outline)), None)]
    if isinstance(shape, Circle):
        cx, cy = float(shape.center[0]), float(shape.center[1])
        diameter = 2.0 * float(shape.radius)
        disc_color = (color[0], color[1], color[2], 0.5 * color[3])
        radius_line = ((cx, cy, 0.0), (cx + float(shape.radius), cy, 0.0))
        return [
            MarkerTemplate(MarkerFields(head, ns, first_id, MARKER_CYLINDER, MARKER_ADD, pose,
                                        (diameter, diameter, MARKER_DISC_HEIGHT), disc_color,
                                        ()), (cx, cy)),
            MarkerTemplate(MarkerFields(head, ns, first_id + 1, MARKER_LINE_STRIP, MARKER_ADD,
                                        pose, line_scale, color, radius_line), None),
        ]
    raise TypeError(f"no marker for a shape of type {type(shape).__name__}")


def color_slot(name: str, base: Scene) -> int:
    """The colour of body ``name`` in a world that started as ``base``: its place among
    ``base``'s bodies, else (a spawned body) one picked by a checksum of its name. A world
    change leaves every other body's colour as it was, live and in a replay alike."""
    for index, body in enumerate(base.bodies):
        if body.name == name:
            return index
    return len(base.bodies) + zlib.crc32(name.encode())


def marker_templates(body: BodySpec, index: int) -> tuple[MarkerTemplate, ...]:
    """The fixed parts of ``body``'s markers, in namespace ``body.name``; ``index`` picks
    the body's colour (:func:`color_slot`). Made once per body; :func:`place_markers` adds
    pose and header."""
    color = MARKER_COLORS[index % len(MARKER_COLORS)]
    templates: list[MarkerTemplate] = []
    for shape in body.shapes:
        templates.extend(_shape_templates(shape, body.name, len(templates), color))
    return tuple(templates)


def marker_pose(template: MarkerTemplate, state: Any, pose: Pose) -> Pose:
    """Where ``template``'s marker sits for ``state`` (a ``BodyState``; ``pose`` its body
    pose): the body pose, moved to the marker's offset where it has one."""
    if template.offset is None:
        return pose
    ox, oy = _rotate(template.offset, float(state.angle))
    return Pose((pose.position[0] + ox, pose.position[1] + oy, 0.0), pose.orientation)


def place_markers(templates: tuple[MarkerTemplate, ...], head: Header, state: Any,
                  pose: Pose) -> list[MarkerFields]:
    """The markers of ``templates`` at ``state`` (a ``BodyState``; ``pose`` its body pose)."""
    markers = []
    for template in templates:
        # The constructor, not _replace: this runs for every marker of every tick.
        _, ns, id_, type_, action, _, scale, color, points = template.fields
        markers.append(MarkerFields(head, ns, id_, type_, action,
                                    marker_pose(template, state, pose), scale, color, points))
    return markers


def marker_fields(body: BodySpec, state: Any, index: int, frame_id: str,
                  stamp_ns: int) -> list[MarkerFields]:
    """RViz markers of ``body``'s shapes at ``state``, in namespace ``body.name``.

    Outlines are ``LINE_STRIP`` markers whose pose is the body pose and whose points are
    the shape's vertices in the body frame; circles are ``CYLINDER`` discs plus a radius
    line that shows the spin. ``index`` picks the body's color.
    """
    return place_markers(marker_templates(body, index), header(frame_id, stamp_ns), state,
                         body_pose(state))


def delete_markers(gone: Iterable[MarkerKey], head: Header) -> tuple[MarkerFields, ...]:
    """``DELETE`` markers for ``gone``: RViz keeps a marker until a ``DELETE`` of its
    namespace and id arrives (visualization_msgs/Marker; the other fields are ignored), so a
    deleted body's shapes would stay on screen at their last pose without these."""
    # The type is ignored by a DELETE; the shapes' outline type keeps the field meaningful.
    return tuple(MarkerFields(head, ns, id_, MARKER_LINE_STRIP, MARKER_DELETE, UNPLACED[1],
                              (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), ())
                 for ns, id_ in sorted(gone))
