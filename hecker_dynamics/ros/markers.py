"""RViz markers of the bodies' shapes (``visualization_msgs/MarkerArray`` fields), without ROS."""
from __future__ import annotations

from typing import Any, NamedTuple

from ..geometry.shapes import Circle, Polygon
from ..scene.load import BodySpec
from .fields import Header, Pose, Vec3, _rotate, body_pose, header

# visualization_msgs/msg/Marker constants.
MARKER_CYLINDER = 3
MARKER_LINE_STRIP = 4
MARKER_ADD = 0
#: Thickness of shape outlines and of circle discs in RViz, in metres.
MARKER_LINE_WIDTH = 0.02
MARKER_DISC_HEIGHT = 0.01
#: Body colors (r, g, b, a), cycled by body index.
MARKER_COLORS = (
    (0.12, 0.47, 0.71, 1.0), (1.0, 0.5, 0.05, 1.0), (0.17, 0.63, 0.17, 1.0),
    (0.84, 0.15, 0.16, 1.0), (0.58, 0.4, 0.74, 1.0), (0.55, 0.34, 0.29, 1.0),
)

# diagnostic_msgs/msg/DiagnosticStatus levels (a ``byte`` field: rclpy wants

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
    line that shows the spin. ``index`` picks the body's color.
    """
    head = header(frame_id, stamp_ns)
    pose = body_pose(state)
    color = MARKER_COLORS[index % len(MARKER_COLORS)]
    markers: list[MarkerFields] = []
    for shape in body.shapes:
        markers.extend(_shape_markers(shape, pose, float(state.angle), head, body.name,
                                      len(markers), color))
    return markers
