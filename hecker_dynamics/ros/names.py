"""The node's name, its topic and service names, and the QoS of each, as plain data.

Everything the node offers on the ROS graph is listed here; the rclpy node turns the
:class:`QosSpec` values into ``rclpy.qos.QoSProfile`` in one place, and the bag writer
records the same profiles in a bag's metadata. Relative names resolve in the node's
namespace, ``~/`` names in the node's own (``/dynamics_node/session``), absolute names are
global (``/tf``, ``/clock``). The node's own name and its services' names, which scenes
and their records need too, are defined in :mod:`hecker_dynamics.scene.names`. No ROS import.
"""
from __future__ import annotations

import enum
from typing import NamedTuple

from ..scene.names import (
    DELETE_BODY_SERVICE,
    NODE_NAME,
    PAUSE_SERVICE,
    RESET_SERVICE,
    RESUME_SERVICE,
    SET_BODY_STATE_SERVICE,
    SPAWN_BODY_SERVICE,
    STEP_SERVICE,
)

__all__ = ["NODE_NAME", "Reliability", "Durability", "QosSpec", "COMMAND_QOS", "STATE_QOS",
           "CLOCK_QOS", "TF_QOS", "TF_STATIC_QOS", "SESSION_QOS", "KEYFRAME_QOS",
           "INPUT_EVENTS_QOS", "WORLD_EVENTS_QOS", "MAP_QOS", "MAP_TOPIC",
           "CONTACT_EVENTS_QOS", "CONTACT_EVENTS_TOPIC", "WORLD_EVENTS_TOPIC",
           "APPLIED_WRENCH_TOPIC",
           "CLOCK_TOPIC", "TF_TOPIC", "TF_STATIC_TOPIC", "MARKERS_TOPIC", "DIAGNOSTICS_TOPIC",
           "JOINT_STATES_TOPIC", "motor_topic", "cmd_vel_topic", "scan_topic", "imu_topic",
           "SESSION_TOPIC", "KEYFRAME_TOPIC", "INPUT_EVENTS_TOPIC", "RESET_SERVICE",
           "PAUSE_SERVICE", "RESUME_SERVICE", "STEP_SERVICE", "SET_BODY_STATE_SERVICE",
           "SPAWN_BODY_SERVICE", "DELETE_BODY_SERVICE",
           "pose_topic", "twist_topic", "odometry_topic", "output_qos"]


class Reliability(enum.Enum):
    """``rmw`` reliability; the values are rosbag2's metadata spelling."""

    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class Durability(enum.Enum):
    """``rmw`` durability; the values are rosbag2's metadata spelling."""

    VOLATILE = "volatile"
    TRANSIENT_LOCAL = "transient_local"


class QosSpec(NamedTuple):
    """A keep-last QoS profile: queue depth, reliability and durability (the rest default)."""

    depth: int
    reliability: Reliability
    durability: Durability


# Commands (AppliedWrench, the scene's WrenchStamped topics): reliable, so a command sent
# once (a kick, a hold with a duration) is not silently lost; keep-last 10 so a burst
# between two executor turns queues instead of overwriting, and a flood is dropped by the
# middleware at a fixed depth instead of growing a queue.
COMMAND_QOS = QosSpec(10, Reliability.RELIABLE, Durability.VOLATILE)
# State (poses, twists, odometry, markers, diagnostics): only the newest sample matters,
# so keep-last and volatile; reliable (rclpy's default) because a reliable publisher also
# serves best-effort subscribers, while a best-effort one would refuse RViz's and
# ros2 bag's reliable default subscriptions.
STATE_QOS = QosSpec(10, Reliability.RELIABLE, Durability.VOLATILE)
# /clock in lockstep: what rosgraph's clock publishers offer (reliable, keep-last 10).
CLOCK_QOS = QosSpec(10, Reliability.RELIABLE, Durability.VOLATILE)
# /tf: tf2_ros's TransformBroadcaster profile (DynamicBroadcasterQoS: keep-last 100).
TF_QOS = QosSpec(100, Reliability.RELIABLE, Durability.VOLATILE)
# /tf_static: tf2_ros's StaticTransformBroadcaster profile (StaticBroadcasterQoS): one
# message, kept for late joiners (transient_local), since it is sent only once.
TF_STATIC_QOS = QosSpec(1, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
# Latched session records: reliable and transient_local, so a recorder that starts after
# them still receives them. One session record is all a late recorder needs; two
# keyframes cover a recorder that subscribes to the outputs up to a keyframe period
# before the keyframes; the input and world events since the latest keyframe must all
# reach it, so their depth is large.
SESSION_QOS = QosSpec(1, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
KEYFRAME_QOS = QosSpec(2, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
INPUT_EVENTS_QOS = QosSpec(1000, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
WORLD_EVENTS_QOS = QosSpec(1000, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
# /map: nav2 map_server's profile (reliable, transient_local, keep-last 1): the map is
# published once and every later subscriber (RViz, Nav2's costmaps) still receives it.
MAP_QOS = QosSpec(1, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
# Contact events: every one matters (a missed END leaves a bumper pressed), and a tick may
# hold many (a pile settling), so a deeper queue than the state's.
CONTACT_EVENTS_QOS = QosSpec(100, Reliability.RELIABLE, Durability.VOLATILE)

APPLIED_WRENCH_TOPIC = "applied_wrench"
CLOCK_TOPIC = "/clock"
TF_TOPIC = "/tf"
TF_STATIC_TOPIC = "/tf_static"
#: ``nav_msgs/OccupancyGrid`` of the scene's map, where Nav2 expects it.
MAP_TOPIC = "/map"
#: ``hecker_dynamics/msg/ContactEvent``: touches beginning and ending.
CONTACT_EVENTS_TOPIC = "contact_events"
MARKERS_TOPIC = "markers"
DIAGNOSTICS_TOPIC = "diagnostics"
#: ``sensor_msgs/JointState`` of the scene's revolute and prismatic joints, as robots publish.
JOINT_STATES_TOPIC = "joint_states"
SESSION_TOPIC = "~/session"
KEYFRAME_TOPIC = "~/keyframe"
INPUT_EVENTS_TOPIC = "~/input_events"
WORLD_EVENTS_TOPIC = "~/world_events"


def pose_topic(body: str) -> str:
    """``<body>/pose`` (``geometry_msgs/PoseStamped``)."""
    return f"{body}/pose"


def twist_topic(body: str) -> str:
    """``<body>/twist`` (``geometry_msgs/Twist``)."""
    return f"{body}/twist"


def odometry_topic(body: str) -> str:
    """``<body>/odom`` (``nav_msgs/Odometry``)."""
    return f"{body}/odom"


def motor_topic(joint: str) -> str:
    """A motor's command topic (``std_msgs/Float64``: its target speed, rad/s or m/s)."""
    return f"{joint}/motor_speed"


def cmd_vel_topic(body: str) -> str:
    """A driven body's velocity command topic (``geometry_msgs/Twist``, body frame)."""
    return f"{body}/cmd_vel"


def scan_topic(body: str, sensor: str) -> str:
    """A laser's topic (``sensor_msgs/LaserScan``)."""
    return f"{body}/{sensor}/scan"


def imu_topic(body: str, sensor: str) -> str:
    """An IMU's topic (``sensor_msgs/Imu``)."""
    return f"{body}/{sensor}/imu"


def output_qos(topic: str) -> QosSpec:
    """The QoS of the node's publisher on ``topic`` (any of its outputs but ``/clock``)."""
    return {TF_TOPIC: TF_QOS, TF_STATIC_TOPIC: TF_STATIC_QOS, MAP_TOPIC: MAP_QOS,
            CONTACT_EVENTS_TOPIC: CONTACT_EVENTS_QOS}.get(topic, STATE_QOS)
