"""Inertial measurement units read from the dynamics themselves.

An accelerometer reads the specific force at its mount: the mount's acceleration less
gravity (held at rest by the floor, a pin or a spring it reads -g, 9.81 m/s^2 up; in free
fall zero), in the sensor's axes. It reads what the body did over the step that ended at
the sample's stamp t, every force included (the force terms and inputs, the drives, the
contact impulses and the joints' constraint forces, whatever sub-steps the method took):
the mount's mean acceleration over [t - h, t],

    a_P = (v_P(t) - v_P(t - h)) / h

from a body point's velocity v_P = v_CM + omega perp(r) (Eq. 9), r the mount's offset
from the CM turned by the body's angle at each end. Differencing the point's velocities,
not the CM's plus the tangential and centripetal terms (a_CM + alpha perp(r) - omega^2 r,
a body point's velocity of Eq. 9 differentiated), is exact for the point whatever the
body turned through in the step: the terms would need an omega and an r somewhere inside
the step, and the mean of omega^2 r is no product of ends. Gravity is constant, so its
mean is itself. The result is turned into the sensor's axes at t (the body's angle plus
the mount's); the gyro reads omega and the orientation that angle, both of the state at t.

The velocities at t - h are those the step from t - h started with, which the simulation
keeps for it, in Python and in the kernel's runs alike
(:meth:`~..dynamics.simulation.Simulation.step_start`); the velocities at t are the
step's own, taken on arriving at t, before anything made at t (a moved body, a spawn)
changes them. Where no step led to the instant (the clock skipped there on a resume after
a pause), the reading falls back to the force terms at the state at t
(:meth:`Imu.forced`: the force over the mass and the angular acceleration, Eq. 5 and
Eq. 14, with the inputs the next step takes, contacts and joints left out).
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

    def point_velocity(self, q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
        """The mount's velocity at CM state (q, v), both (N, 3): v_CM + omega perp(r)
        (Eq. 9), r the mount's offset turned by the body's angle."""
        body = self.body
        theta, omega = float(q[body, 2]), float(v[body, 2])
        mx, my = self.mount
        c, s = math.cos(theta), math.sin(theta)
        return (float(v[body, 0]) - omega * (s * mx + c * my),
                float(v[body, 1]) + omega * (c * mx - s * my))

    def measured(self, before: tuple[float, float], q: np.ndarray, v: np.ndarray,
                 h: float) -> tuple[float, float]:
        """The specific force in the sensor's axes over the step of ``h`` seconds that
        ended at CM state (q, v), the mount moving at ``before`` when it began
        (:meth:`point_velocity`)."""
        (vx, vy), (bx, by), (gx, gy) = self.point_velocity(q, v), before, self.gravity
        return self._turned(float(q[self.body, 2]), (vx - bx) / h - gx, (vy - by) / h - gy)

    def forced(self, q: np.ndarray, v: np.ndarray,
               accelerations: np.ndarray) -> tuple[float, float]:
        """The specific force in the sensor's axes from the force terms at CM state (q, v)
        whose accelerations (Model.accelerations) are ``accelerations``, all (N, 3):
        a_P = a_CM + alpha perp(r) - omega^2 r (a body point's velocity, Eq. 9,
        differentiated) less gravity: what a sample reads where no step led to its instant
        (:meth:`~..dynamics.simulation.Simulation.step_start` knows none)."""
        body = self.body
        theta, omega = float(q[body, 2]), float(v[body, 2])
        ax, ay, alpha = accelerations[body].tolist()
        (mx, my), (gx, gy) = self.mount, self.gravity
        c, s = math.cos(theta), math.sin(theta)
        rx = c * mx - s * my
        ry = s * mx + c * my
        return self._turned(theta, ax - alpha * ry - omega * omega * rx - gx,
                            ay + alpha * rx - omega * omega * ry - gy)

    def _turned(self, theta: float, fx: float, fy: float) -> tuple[float, float]:
        """(fx, fy) in fixed axes, in the axes of the sensor on a body at angle ``theta``."""
        yaw = theta + self.spec.angle
        cy, sy = math.cos(yaw), math.sin(yaw)
        return cy * fx + sy * fy, -sy * fx + cy * fy

    def read(self, q: np.ndarray, v: np.ndarray, specific_force: tuple[float, float],
             stamp_ns: int) -> ImuReading:
        """The sample stamped ``stamp_ns`` at CM state (q, v), both (N, 3), whose
        accelerometer measured ``specific_force`` (:meth:`measured` or :meth:`forced`)."""
        body = self.body
        yaw, omega = float(q[body, 2]) + self.spec.angle, float(v[body, 2])
        along, across = specific_force
        if self._noisy:
            d_yaw, d_omega, d_x, d_y = self.deviations
            n_yaw, n_omega, n_x, n_y = self.noise.normals(stamp_ns, 4).tolist()
            return ImuReading(stamp_ns, yaw + d_yaw * n_yaw, omega + d_omega * n_omega,
                              (along + d_x * n_x, across + d_y * n_y))
        return ImuReading(stamp_ns, yaw, omega, (along, across))
