"""Sensor descriptions of a scene: ``sensors.<name>`` (laser scanners and IMUs).

A sensor is mounted on a body at a pose in the body frame and samples at a rate that is a
whole number of physics steps. Its noise is seeded: the same scene and inputs give the same
readings, so a recorded session replays bit for bit. ``docs/scenes.md`` lists every
parameter; :mod:`hecker_dynamics.sensors` computes the readings.
"""
from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Union

from .parameters import REQUIRED, ParameterReader, number_text

__all__ = ["LaserSpec", "ImuSpec", "SensorSpec", "SENSOR_TYPES", "MAX_RAYS",
           "MAX_IMU_NOISE", "read_sensor"]

SENSOR_TYPES = ("laser", "imu")
#: Most rays of one scan: a scan costs rays x edges in memory.
MAX_RAYS = 100_000
#: Largest standard deviation of an IMU's noise: ``sensor_msgs/Imu`` carries its square
#: (the covariance), which must be a double too.
MAX_IMU_NOISE = math.sqrt(sys.float_info.max)
Vec2 = tuple[float, float]


@dataclass(frozen=True)
class LaserSpec:
    """A 2D laser scanner: ``count`` rays from ``angle_min`` to ``angle_max`` (both cast),
    in the sensor frame, whose origin and x axis are ``position`` and ``angle`` in the body
    frame of ``body``. Ranges outside [range_min, range_max] read -inf / +inf (REP 117)."""

    name: str
    body: str
    position: Vec2
    angle: float
    angle_min: float
    angle_max: float
    count: int
    range_min: float
    range_max: float
    period_ns: int
    noise: float  # standard deviation of the Gaussian noise on each range (m)
    seed: int

    @property
    def frame_id(self) -> str:
        """The sensor's TF frame, a child of its body's."""
        return f"{self.body}/{self.name}"

    @property
    def angle_increment(self) -> float:
        """The angle between successive rays (zero for a single ray)."""
        return (self.angle_max - self.angle_min) / (self.count - 1) if self.count > 1 else 0.0


@dataclass(frozen=True)
class ImuSpec:
    """An inertial measurement unit at ``position``, x axis at ``angle``, in the body frame
    of ``body``: orientation, angular velocity and the specific force (acceleration less
    gravity) at that point, with seeded Gaussian noise of the given standard deviations."""

    name: str
    body: str
    position: Vec2
    angle: float
    period_ns: int
    orientation_noise: float  # rad
    angular_velocity_noise: float  # rad/s
    linear_acceleration_noise: float  # m/s^2
    seed: int

    @property
    def frame_id(self) -> str:
        """The sensor's TF frame, a child of its body's."""
        return f"{self.body}/{self.name}"


SensorSpec = Union[LaserSpec, ImuSpec]


def _seed(reader: ParameterReader) -> int:
    seed = reader.number("seed", 0, minimum=0.0, maximum=2.0 ** 63)
    if not float(seed).is_integer():
        reader.fail("seed", f"must be a whole number, not {seed}")
    return int(seed)


def _imu_noise(reader: ParameterReader, key: str) -> float:
    return reader.number(key, 0.0, minimum=0.0, maximum=MAX_IMU_NOISE)


def read_sensor(name: str, reader: ParameterReader, points: Mapping[str, Mapping[str, Vec2]],
                step_ns: int) -> SensorSpec:
    """One ``sensors.<name>`` entry; ``points`` holds each body's declared points (a
    sensor's frame must not shadow one)."""
    kind = reader.string("type", REQUIRED, choices=SENSOR_TYPES)
    body = reader.string("body", REQUIRED)
    if body not in points:
        reader.fail("body", f"names an unknown body '{body}'")
    if name in points[body]:
        reader.fail("body", f"'{body}' declares a point '{name}': the sensor's frame "
                            f"'{body}/{name}' would be both")
    position = reader.vector("position", [0.0, 0.0])
    angle = reader.number("angle", 0.0)
    if kind == "imu":
        return ImuSpec(name, body, position, angle, reader.period_ns("rate", step_ns, 100.0),
                       orientation_noise=_imu_noise(reader, "orientation_noise"),
                       angular_velocity_noise=_imu_noise(reader, "angular_velocity_noise"),
                       linear_acceleration_noise=_imu_noise(reader,
                                                            "linear_acceleration_noise"),
                       seed=_seed(reader))
    angle_min = reader.number("angle_min", -math.pi)
    angle_max = reader.number("angle_max", math.pi)
    if angle_max < angle_min:
        reader.fail("angle_max", f"must be at least angle_min ({angle_min}), not {angle_max}")
    if angle_max - angle_min > 2.0 * math.pi:
        # Rays past a full turn only cast again the first ones; such a span is degrees
        # (-135 to 135) far more often than a scan meant to wrap.
        reader.fail("angle_max", f"must be at most a full turn (2 pi rad) past angle_min "
                                 f"({number_text(angle_min)}), not {number_text(angle_max)}: "
                                 f"angles are in radians")
    count = reader.number("count", 360, minimum=1.0, maximum=MAX_RAYS)
    if not count.is_integer():
        reader.fail("count", f"must be a whole number, not {count}")
    if count == 1.0 and angle_max != angle_min:
        # A scan of it would claim angle_max, which no ray reaches (angle_increment 0).
        reader.fail("count", f"one ray is cast at angle_min ({angle_min}); give angle_max "
                             f"equal to it, not {angle_max}, or count 2 or more")
    range_min = reader.number("range_min", 0.0, minimum=0.0)
    range_max = reader.number("range_max", 10.0, positive=True)
    if range_max <= range_min:
        reader.fail("range_max", f"must exceed range_min ({range_min}), not {range_max}")
    return LaserSpec(name, body, position, angle, angle_min, angle_max, int(count),
                     range_min, range_max, reader.period_ns("rate", step_ns, 10.0),
                     noise=reader.number("noise", 0.0, minimum=0.0), seed=_seed(reader))
