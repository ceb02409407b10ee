"""Sensor readings as message fields: every field is one of sensor_msgs' own (a rosbags
message of the Jazzy types builds from them and survives CDR), the laser's angles are
those its rays were cast at, and the sensor frames hang from their bodies on /tf_static."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hecker_dynamics.bags import io as bags
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.sensor_fields import imu_fields, laser_scan_fields, sensor_transforms
from hecker_dynamics.scene.load import load_scene
from hecker_dynamics.sensors.imu import Imu
from hecker_dynamics.sensors.laser import Laser

LASER_SCAN = "sensor_msgs/msg/LaserScan"
IMU = "sensor_msgs/msg/Imu"


def message(msgtype: str, fields) -> object:
    """A rosbags message of ``msgtype`` from a fields named tuple (nested ones too)."""
    store = bags.typestore()
    _, definitions = store.fielddefs[msgtype]
    values = {}
    for (name, desc), value in zip(definitions, fields):
        if name == "header":
            value = bags.header_message(value)
        elif isinstance(value, tuple) and desc[0] == 2:  # a nested message, e.g. Vector3
            nested = desc[1]
            names = [n for n, _ in store.fielddefs[nested][1]]
            value = bags.default_message(nested, **dict(zip(names, value)))
        elif isinstance(value, tuple):  # float32 ranges, float64 covariances
            value = np.array(value, dtype=np.float32 if "float32" in str(desc) else float)
        values[name] = value
    return bags.default_message(msgtype, **values)


def round_trip(msgtype: str, msg: object) -> object:
    store = bags.typestore()
    return store.deserialize_cdr(store.serialize_cdr(msg, msgtype), msgtype)


def test_robot_sensors_fill_their_messages():
    scene = load_scene("robot")
    sim = Simulation(scene)
    laser_spec, imu_spec = scene.sensors[1], scene.sensors[0]
    assert (laser_spec.name, imu_spec.name) == ("laser", "imu")
    laser = Laser(laser_spec, scene, sim.model.cm_local)
    scan = laser.scan(sim.q, 123_456_789)
    fields = laser_scan_fields(laser_spec, scan)
    back = round_trip(LASER_SCAN, message(LASER_SCAN, fields))
    assert back.header.frame_id == "robot/laser" and back.header.stamp.nanosec == 123_456_789
    # The angles a subscriber computes are the ones the rays were cast at.
    angles = back.angle_min + np.arange(len(back.ranges)) * back.angle_increment
    assert np.array_equal(angles, laser.angles)
    assert back.angle_max == pytest.approx(angles[-1], abs=1e-6)
    assert np.array_equal(back.ranges, scan.ranges.astype(np.float32))  # float32 on the wire
    assert back.scan_time == pytest.approx(0.1)
    imu = Imu(imu_spec, scene, sim.model.cm_local)
    forced = imu.forced(sim.q, sim.v, sim.model.accelerations(sim.q, sim.v))
    reading = imu.read(sim.q, sim.v, forced, 5)
    back = round_trip(IMU, message(IMU, imu_fields(imu_spec, reading)))
    assert back.header.frame_id == "robot/imu"
    assert back.linear_acceleration.x == reading.linear_acceleration[0]
    assert back.angular_velocity.z == reading.angular_velocity
    assert back.linear_acceleration_covariance[0] == pytest.approx(1e-4)
    assert 2 * math.atan2(back.orientation.z, back.orientation.w) == pytest.approx(reading.yaw)


def test_sensor_frames_hang_from_their_bodies():
    scene = load_scene("robot")
    transforms = {t.child_frame_id: t for t in sensor_transforms(scene, 0)}
    assert set(transforms) == {"robot/laser", "robot/imu"}
    laser = transforms["robot/laser"]
    assert laser.header.frame_id == "robot" and laser.translation == (0.2, 0.0, 0.0)
    assert laser.rotation == (0.0, 0.0, 0.0, 1.0)
