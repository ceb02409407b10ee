"""Inertial measurement units read from the dynamics themselves.

A body point P at offset r from the CM moves at v_P = v_CM + omega perp(r), a body point's
velocity (Eq. 9). Differentiating, with dr/dt = omega perp(r) and perp(perp(r)) = -r:

    a_P = a_CM + alpha perp(r) - omega^2 r

the CM's acceleration (the summed forces over the mass, Eq. 5) plus the tangential term
(the angular acceleration, the summed torques over inertia, Eq. 14) and the centripetal
term. An accelerometer reads the specific force a_P - g (held at rest by a spring or a
force it reads -g; in free fall zero), turned into the sensor's axes; the gyro reads omega
and the orientation is the body's angle plus the mount's. The accelerations are the force
terms' at the sampled state (Model.accelerations, inputs included); contact impulses and
joint constraint forces act inside the step and are not part of them, so a body resting
on the floor or hanging from a pin reads zero, as in free fall.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.load import Gravity, Scene
from ..scene.sensors import ImuSpec
from .noise import Noise

__all__ = ["Imu", "ImuReading"]


@dataclass(frozen=True)
class ImuReading:
    """One IMU sample: the sensor frame's heading in the fixed frame (rad), its angular
    velocity about z (rad/s) and the specific force at the sensor in its own x, y axes
    (m/s^2), noise included."""

    stamp_ns: int
    yaw: float
    angular_velocity: float
    linear_acceleration: tuple[float, float]

    @property
    def orientation(self) -> tuple[float, float, float, float]:
        """The heading as a unit quaternion (x, y, z, w) about z."""
        return (0.0, 0.0, math.sin(self.yaw / 2.0), math.cos(self.yaw / 2.0))


class Imu:
    """An IMU of a scene: its body, its offset from that body's CM (body axes) and the
    gravity acting on that body."""

    def __init__(self, spec: ImuSpec, scene: Scene, cm_local: np.ndarray) -> None:
        """``cm_local`` (N, 2): each body's CM in its body frame (Model.cm_local)."""
        self.spec = spec
        self.body = [b.name for b in scene.bodies].index(spec.body)
        # Plain floats: a reading is a few numbers, taken at the IMU's rate.
        self.mount = (np.asarray(spec.position, dtype=float) - cm_local[self.body]).tolist()
        gravity = [f.acceleration for f in scene.forces
                   if isinstance(f, Gravity) and spec.body in f.bodies]
        self.gravity = np.sum(np.array(gravity, dtype=float).reshape(-1, 2), axis=0).tolist()
        self.noise = Noise(spec.seed, spec.frame_id, spec.period_ns)
        #: The noise's standard deviation on each of yaw, omega and the specific force's x
        #: and y.
        self.deviations = (spec.orientation_noise, spec.angular_velocity_noise,
                           spec.linear_acceleration_noise, spec.linear_acceleration_noise)
        self._noisy = any(deviation > 0.0 for deviation in self.deviations)

    def read(self, q: np.ndarray, v: np.ndarray, accelerations: np.ndarray,
             stamp_ns: int) -> ImuReading:
        """The sample at CM state (q, v) whose accelerations (Model.accelerations) are
        ``accelerations``, all (N, 3), stamped ``stamp_ns``."""
        body = self.body
        theta, omega = float(q[body, 2]), float(v[body, 2])
        ax, ay, alpha = accelerations[body].tolist()
        (mx, my), (gx, gy) = self.mount, self.gravity
        c, s = math.cos(theta), math.sin(theta)
        rx = c * mx - s * my
        ry = s * mx + c * my
        # a_P = a_CM + alpha perp(r) - omega^2 r, less gravity: the specific force.
        fx = ax - alpha * ry - omega * omega * rx - gx
        fy = ay + alpha * rx - omega * omega * ry - gy
        yaw = theta + self.spec.angle
        cy, sy = math.cos(yaw), math.sin(yaw)
        along, across = cy * fx + sy * fy, -sy * fx + cy * fy
        if self._noisy:
            d_yaw, d_omega, d_x, d_y = self.deviations
            n_yaw, n_omega, n_x, n_y = self.noise.normals(stamp_ns, 4).tolist()
            return ImuReading(stamp_ns, yaw + d_yaw * n_yaw, omega + d_omega * n_omega,
                              (along + d_x * n_x, across + d_y * n_y))
        return ImuReading(stamp_ns, yaw, omega, (along, across))
