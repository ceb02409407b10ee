"""What the node publishes for a snapshot: its output topics, kinds and message fields."""
from __future__ import annotations

import enum
from typing import Any, NamedTuple

from ..dynamics.simulation import Snapshot
from ..scene.load import Scene
from .fields import odometry_fields, pose_fields, twist_fields
from .markers import MarkerFields, marker_fields

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
