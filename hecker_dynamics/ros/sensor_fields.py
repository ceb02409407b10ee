"""Sensor readings as message fields (no ROS import): ``sensor_msgs/LaserScan`` and
``sensor_msgs/Imu`` of :mod:`hecker_dynamics.sensors`' readings, and the static transforms
from each body frame to its sensors' frames (``<body>/<sensor>``), for the node to publish
on :func:`~.names.scan_topic`, :func:`~.names.imu_topic` and ``/tf_static``."""
from __future__ import annotations

import functools
import math
from typing import NamedTuple

from ..scene.load import Scene
from ..scene.sensors import ImuSpec, LaserSpec
from ..sensors.imu import ImuReading
from ..sensors.laser import LaserScan
from .fields import Header, header, quaternion_from_yaw
from .tf import TransformFields

__all__ = ["LaserScanFields", "ImuFields", "laser_scan_fields", "imu_fields",
           "sensor_transforms"]

Vec3 = tuple[float, float, float]
Covariance = tuple[float, ...]  # 9 values, row-major


class LaserScanFields(NamedTuple):
    """``sensor_msgs/LaserScan`` (no intensities)."""

    header: Header
    angle_min: float
    angle_max: float
    angle_increment: float
    time_increment: float
    scan_time: float
    range_min: float
    range_max: float
    ranges: tuple[float, ...]


class ImuFields(NamedTuple):
    """``sensor_msgs/Imu``: each covariance the noise's variance on the planar components
    (x and y of the acceleration, z of the rest), zero elsewhere: the out-of-plane
    components are exactly zero."""

    header: Header
    orientation: tuple[float, float, float, float]
    orientation_covariance: Covariance
    angular_velocity: Vec3
    angular_velocity_covariance: Covariance
    linear_acceleration: Vec3
    linear_acceleration_covariance: Covariance


def laser_scan_fields(spec: LaserSpec, scan: LaserScan) -> LaserScanFields:
    """The scan in the laser's frame; all rays are cast at one instant (time_increment 0)."""
    return LaserScanFields(
        header(spec.frame_id, scan.stamp_ns), spec.angle_min, spec.angle_max,
        spec.angle_increment, 0.0, spec.period_ns * 1e-9, spec.range_min, spec.range_max,
        tuple(scan.ranges.tolist()))


def _diagonal(*variances: float) -> Covariance:
    return (variances[0], 0.0, 0.0, 0.0, variances[1], 0.0, 0.0, 0.0, variances[2])


@functools.lru_cache(maxsize=64)
def _imu_covariances(spec: ImuSpec) -> tuple[Covariance, Covariance, Covariance]:
    """An IMU's covariances of orientation, angular velocity and linear acceleration: the
    same in each of its readings."""
    heading = spec.orientation_noise ** 2
    spin = spec.angular_velocity_noise ** 2
    push = spec.linear_acceleration_noise ** 2
    return _diagonal(0.0, 0.0, heading), _diagonal(0.0, 0.0, spin), _diagonal(push, push, 0.0)


def imu_fields(spec: ImuSpec, reading: ImuReading) -> ImuFields:
    """The reading in the IMU's frame; its orientation is the sensor frame's in the fixed
    frame (a rotation about z)."""
    ax, ay = reading.linear_acceleration
    orientation, angular_velocity, linear_acceleration = _imu_covariances(spec)
    return ImuFields(
        header(spec.frame_id, reading.stamp_ns), quaternion_from_yaw(reading.yaw),
        orientation, (0.0, 0.0, reading.angular_velocity), angular_velocity,
        (ax, ay, 0.0), linear_acceleration)


def sensor_transforms(scene: Scene, stamp_ns: int) -> tuple[TransformFields, ...]:
    """``/tf_static``: each body frame to each of its sensors' frames, in the scene's
    order of sensors."""
    return tuple(TransformFields(header(spec.body, stamp_ns), spec.frame_id,
                                 (float(spec.position[0]), float(spec.position[1]), 0.0),
                                 quaternion_from_yaw(math.remainder(spec.angle, 2 * math.pi)))
                 for spec in scene.sensors)
