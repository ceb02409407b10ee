"""What the node publishes for a snapshot: its output topics, kinds and message fields."""
from __future__ import annotations

import enum
from typing import Any, NamedTuple, Optional

from ..dynamics.simulation import Snapshot
from ..scene.load import Scene
from ..scene.sensors import LaserSpec, SensorSpec
from ..sensors.imu import ImuReading
from ..sensors.laser import LaserScan
from ..sensors.schedule import Reading
from ..sensors.touch import TouchEvent
from .contact_fields import contact_event_fields
from .fields import (
    OdometryFields,
    PoseStampedFields,
    body_pose,
    header,
    odometry_twist,
    twist_fields,
)
from .joint_states import has_joint_states, snapshot_joint_states
from .map_fields import occupancy_grid_fields
from .markers import (
    MarkerFields,
    MarkerKey,
    color_slot,
    delete_markers,
    marker_keys,
    marker_templates,
    place_markers,
)
from .names import (
    CONTACT_EVENTS_TOPIC,
    DIAGNOSTICS_TOPIC,
    JOINT_STATES_TOPIC,
    MAP_TOPIC,
    MARKERS_TOPIC,
    TF_STATIC_TOPIC,
    TF_TOPIC,
    imu_topic,
    odometry_topic,
    pose_topic,
    scan_topic,
    twist_topic,
)
from .sensor_fields import imu_fields, laser_scan_fields, sensor_transforms
from .tf import body_transforms, point_transforms

__all__ = ["OutputKind", "DIAGNOSTICS_TOPIC", "output_topics", "body_topics", "OutputFields",
           "SnapshotOutputs", "snapshot_outputs", "sensor_topic", "reading_output",
           "touch_output"]


class OutputKind(enum.Enum):
    """The kinds of message the node publishes."""

    POSE = "geometry_msgs/msg/PoseStamped"
    TWIST = "geometry_msgs/msg/Twist"
    ODOMETRY = "nav_msgs/msg/Odometry"
    MARKERS = "visualization_msgs/msg/MarkerArray"
    DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
    TF = "tf2_msgs/msg/TFMessage"
    JOINT_STATE = "sensor_msgs/msg/JointState"
    LASER_SCAN = "sensor_msgs/msg/LaserScan"
    IMU = "sensor_msgs/msg/Imu"
    OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
    CONTACT_EVENT = "hecker_dynamics/msg/ContactEvent"


def _with_tf(scene: Scene, tf: Optional[bool]) -> bool:
    return scene.publish_tf if tf is None else tf


def body_topics(scene: Scene, body: str) -> dict[str, OutputKind]:
    """The output topics of one body of ``scene`` (a spawned one too) and their kinds."""
    topics = {pose_topic(body): OutputKind.POSE, twist_topic(body): OutputKind.TWIST}
    if scene.publish_odometry:
        topics[odometry_topic(body)] = OutputKind.ODOMETRY
    return topics


def output_topics(scene: Scene, *, tf: Optional[bool] = None) -> dict[str, OutputKind]:
    """The node's output topics for ``scene`` and their kinds, in publishing order: per
    body ``<body>/pose``, ``<body>/twist`` and (if enabled) ``<body>/odom``, then
    ``markers``, ``/tf`` and ``/tf_static``, each if enabled, ``/map`` if the scene has a
    map, ``joint_states`` if the scene
    has revolute or prismatic joints, each sensor's scan or IMU topic, ``contact_events``
    and ``diagnostics`` if enabled.

    ``tf`` overrides the scene's ``publish.tf`` (the offline replay leaves TF out unless
    asked, so bags replayed before TF existed keep their bytes).
    """
    topics: dict[str, OutputKind] = {}
    for body in scene.bodies:
        topics.update(body_topics(scene, body.name))
    if scene.publish_markers:
        topics[MARKERS_TOPIC] = OutputKind.MARKERS
    if _with_tf(scene, tf):
        topics[TF_TOPIC] = OutputKind.TF
        topics[TF_STATIC_TOPIC] = OutputKind.TF
    if scene.map is not None:
        topics[MAP_TOPIC] = OutputKind.OCCUPANCY_GRID
    if has_joint_states(scene):
        topics[JOINT_STATES_TOPIC] = OutputKind.JOINT_STATE
    for spec in scene.sensors:
        topics[sensor_topic(spec)] = OutputKind.LASER_SCAN if isinstance(spec, LaserSpec) \
            else OutputKind.IMU
    if scene.publish_contacts:
        topics[CONTACT_EVENTS_TOPIC] = OutputKind.CONTACT_EVENT
    if scene.publish_diagnostics:
        topics[DIAGNOSTICS_TOPIC] = OutputKind.DIAGNOSTICS
    return topics


def sensor_topic(spec: SensorSpec) -> str:
    """The topic a sensor's readings go out on: ``<body>/<name>/scan`` or ``.../imu``."""
    topic = scan_topic if isinstance(spec, LaserSpec) else imu_topic
    return topic(spec.body, spec.name)


class OutputFields(NamedTuple):
    """One message to publish: topic, kind, and the fields (the kind's ``*Fields`` tuple;
    for markers a tuple of :class:`MarkerFields`, for TF a tuple of ``TransformFields``)."""

    topic: str
    kind: OutputKind
    fields: Any


class SnapshotOutputs:
    """The messages the node publishes for each snapshot of ``scene``, in publishing order.

    Everything that does not change between snapshots (topic names, which outputs are on
    and the markers' shapes) is worked out once here; per snapshot one header serves every
    message of the fixed frame and each body's pose is computed once for its pose,
    odometry, markers and transform.
    """

    def __init__(self, scene: Scene, *, tf: Optional[bool] = None,
                 base: Optional[Scene] = None) -> None:
        """``base``: the scene the world started as (default ``scene``), which fixes the
        bodies' marker colours (:func:`~.markers.color_slot`)."""
        self.scene = scene
        self.tf = _with_tf(scene, tf)
        #: Per body: its pose, twist and odometry topics.
        self.topics = tuple((pose_topic(b.name), twist_topic(b.name), odometry_topic(b.name))
                            for b in scene.bodies)
        #: Per body: its markers' templates (none with markers off).
        self.templates = tuple(marker_templates(b, color_slot(b.name, base or scene))
                               for b in scene.bodies) if scene.publish_markers else ()
        #: The namespace and id of every marker these outputs publish.
        self.marker_keys: frozenset[MarkerKey] = frozenset().union(
            *(marker_keys(templates) for templates in self.templates))

    def __call__(self, snapshot: Snapshot) -> list[OutputFields]:
        scene = self.scene
        frame_id = scene.frame_id
        stamp = snapshot.time_ns
        head = header(frame_id, stamp)
        outputs = []
        markers: list[MarkerFields] = []
        poses = []
        for index, state in enumerate(snapshot.bodies):
            pose, twist, odom = self.topics[index]
            body_pose_fields = body_pose(state)
            poses.append(body_pose_fields)
            twist_fields_ = twist_fields(state, scene.twist_frame)
            outputs.append(OutputFields(pose, OutputKind.POSE,
                                        PoseStampedFields(head, body_pose_fields)))
            outputs.append(OutputFields(twist, OutputKind.TWIST, twist_fields_))
            if scene.publish_odometry:
                outputs.append(OutputFields(odom, OutputKind.ODOMETRY, OdometryFields(
                    head, state.name, body_pose_fields,
                    odometry_twist(state, twist_fields_, scene.twist_frame))))
            if scene.publish_markers:
                markers.extend(place_markers(self.templates[index], head, state,
                                             body_pose_fields))
        if scene.publish_markers:
            outputs.append(OutputFields(MARKERS_TOPIC, OutputKind.MARKERS, tuple(markers)))
        if self.tf:
            outputs.append(OutputFields(TF_TOPIC, OutputKind.TF,
                                        body_transforms(head, snapshot.bodies, poses)))
        joint_states = snapshot_joint_states(frame_id, snapshot)
        if joint_states is not None:
            outputs.append(OutputFields(JOINT_STATES_TOPIC, OutputKind.JOINT_STATE,
                                        joint_states))
        return outputs

    def markers_gone(self, previous: SnapshotOutputs, stamp_ns: int) -> list[OutputFields]:
        """After a world change (a delete, or a spawn undone by a restart): one
        ``MarkerArray`` of ``DELETE`` markers for what ``previous`` published and these
        outputs do not, so RViz drops a body that is gone; empty when nothing is."""
        gone = previous.marker_keys - self.marker_keys
        if not gone or not self.scene.publish_markers:
            return []
        head = header(self.scene.frame_id, stamp_ns)
        return [OutputFields(MARKERS_TOPIC, OutputKind.MARKERS, delete_markers(gone, head))]

    def static(self, stamp_ns: int) -> list[OutputFields]:
        """What is published once, latched: ``/tf_static`` (each body frame to its named
        points' frames and its sensors' frames; none without TF or any of them) and
        ``/map`` (if the scene has a map)."""
        transforms = point_transforms(self.scene, stamp_ns) + \
            sensor_transforms(self.scene, stamp_ns) if self.tf else ()
        static = [OutputFields(TF_STATIC_TOPIC, OutputKind.TF, transforms)] if transforms else []
        grid = occupancy_grid_fields(self.scene, stamp_ns)
        if grid is not None:
            static.append(OutputFields(MAP_TOPIC, OutputKind.OCCUPANCY_GRID, grid))
        return static


def snapshot_outputs(scene: Scene, snapshot: Snapshot, *,
                     tf: Optional[bool] = None) -> list[OutputFields]:
    """The messages the node publishes for one snapshot (see :class:`SnapshotOutputs`,
    which makes the per-scene constants once for many snapshots)."""
    return SnapshotOutputs(scene, tf=tf)(snapshot)


def reading_output(reading: Reading) -> OutputFields:
    """The message of one sensor reading (:class:`~..sensors.schedule.SensorSet`)."""
    spec, sample = reading
    if isinstance(sample, LaserScan):
        assert isinstance(spec, LaserSpec)
        return OutputFields(sensor_topic(spec), OutputKind.LASER_SCAN,
                            laser_scan_fields(spec, sample))
    assert isinstance(sample, ImuReading) and not isinstance(spec, LaserSpec)
    return OutputFields(sensor_topic(spec), OutputKind.IMU, imu_fields(spec, sample))


def touch_output(frame_id: str, event: TouchEvent) -> OutputFields:
    """The message of one contact event (:class:`~..sensors.touch.Touches`)."""
    return OutputFields(CONTACT_EVENTS_TOPIC, OutputKind.CONTACT_EVENT,
                        contact_event_fields(frame_id, event))
