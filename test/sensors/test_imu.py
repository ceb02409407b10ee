"""IMU readings from the force terms (:meth:`Imu.forced`, what a sample reads where no step
led to its instant) against the dynamics: the centripetal
acceleration omega^2 r of a body spinning freely, the specific force F / m of a body pushed
while it falls (zero in free fall), and a central difference of a body point's velocity
(Eq. 9) along an RK4 run. What the run loop's samples read over their last step is
test_imu_step.py's."""
from __future__ import annotations

import math
import sys
import zlib

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.sensor_fields import imu_fields
from hecker_dynamics.scene.parameters import SceneError
from hecker_dynamics.sensors.imu import Imu


def imu_on(body: dict, forces: dict | None = None, step: float = 1e-4,
          **imu) -> tuple[Imu, Simulation]:
    scene = make_scene({"step": step, "integrator": "rk4", "bodies": {"robot": body},
                        "forces": forces or {},
                        "sensors": {"imu": {"type": "imu", "body": "robot", **imu}}})
    sim = Simulation(scene)
    return Imu(scene.sensors[0], scene, sim.model.cm_local), sim


def read(imu: Imu, sim: Simulation):
    forced = imu.forced(sim.q, sim.v, sim.model.accelerations(sim.q, sim.v))
    return imu.read(sim.q, sim.v, forced, sim.time_ns)


def test_a_freely_spinning_body_reads_omega_squared_r_towards_its_centre():
    omega, r = 3.0, 0.4
    # The CM is the circle's centre (0.1, 0); the sensor sits r beyond it on the x axis.
    imu, sim = imu_on({"shape": "circle", "radius": 0.5, "center": [0.1, 0.0], "mass": 2.0,
                      "angular_velocity": omega}, position=[0.1 + r, 0.0])
    for _ in range(1234):
        sim.step()
    reading = read(imu, sim)
    assert reading.linear_acceleration == pytest.approx((-omega ** 2 * r, 0.0), abs=1e-12)
    assert reading.angular_velocity == omega
    assert reading.yaw == sim.q[0, 2]
    x, y, z, w = reading.orientation
    assert (x, y) == (0.0, 0.0) and math.atan2(z, w) * 2 == pytest.approx(sim.q[0, 2], abs=1e-15)


def test_specific_force_is_the_push_over_the_mass_and_zero_in_free_fall():
    mass, push = 2.0, (3.0, -1.0)
    body = {"shape": "box", "size": [0.4, 0.2], "mass": mass}
    falling, sim = imu_on(body, {"g": {"type": "gravity"}}, angle=0.5)
    for _ in range(100):
        sim.step()
    assert read(falling, sim).linear_acceleration == (0.0, 0.0)
    pushed, sim = imu_on(body, {"g": {"type": "gravity"},
                               "push": {"type": "constant_force", "body": "robot",
                                        "force": list(push)}}, angle=0.5)
    for _ in range(100):
        sim.step()
    # The push in the sensor's axes, turned by -0.5 rad (the body does not turn).
    c, s = math.cos(0.5), math.sin(0.5)
    expected = (c * push[0] / mass + s * push[1] / mass, -s * push[0] / mass + c * push[1] / mass)
    assert read(pushed, sim).linear_acceleration == pytest.approx(expected, abs=1e-14)


def test_a_body_held_up_by_a_force_reads_minus_g_and_one_resting_on_a_wall_zero():
    """Contact and joint forces are not force terms, so from the force terms a body held
    at rest by a force reads -g (9.81 m/s^2 up) but one resting on the floor zero, as in
    free fall (the run loop's samples read the floor too: test_imu_step.py)."""
    body = {"shape": "box", "size": [0.4, 0.2], "mass": 2.0, "position": [0.0, 0.1]}
    held, sim = imu_on(body, {"g": {"type": "gravity"},
                             "hold": {"type": "constant_force", "body": "robot",
                                      "force": [0.0, 2.0 * 9.81]}})
    for _ in range(100):
        sim.step()
    assert read(held, sim).linear_acceleration == (0.0, 9.81)
    scene = make_scene({"step": 1e-3, "integrator": "semi_implicit_euler",
                        "bodies": {"robot": body},
                        "forces": {"g": {"type": "gravity"}},
                        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}},
                        "sensors": {"imu": {"type": "imu", "body": "robot"}}})
    sim = Simulation(scene)
    for _ in range(500):
        sim.step()
    assert abs(sim.q[0, 1] - 0.1) < 1e-3 and abs(sim.v[0, 1]) < 0.01  # on the floor
    resting = Imu(scene.sensors[0], scene, sim.model.cm_local)
    assert read(resting, sim).linear_acceleration == (0.0, 0.0)


def mount_error(step: float) -> np.ndarray:
    """IMU reading (back in world axes, gravity added back) less a central difference of
    the mount's velocity, a body point's velocity (Eq. 9), over the neighbouring steps, at
    t = 0.3 s. A force at a corner turns the body: both the tangential and the centripetal
    terms count."""
    mount = (0.3, -0.2)
    imu, sim = imu_on({"shape": "box", "size": [1.0, 0.5], "mass": 1.5, "angular_velocity": 2.0},
                     {"g": {"type": "gravity"},
                      "push": {"type": "constant_force", "body": "robot", "force": [0.0, 4.0],
                               "axes": "body", "point": [0.5, 0.25]}},
                     step=step, position=list(mount), angle=0.7)

    def point_velocity() -> np.ndarray:
        theta, omega = sim.q[0, 2], sim.v[0, 2]
        c, s = math.cos(theta), math.sin(theta)
        r = np.array([c * mount[0] - s * mount[1], s * mount[0] + c * mount[1]])
        return sim.v[0, :2] + omega * np.array([-r[1], r[0]])

    for _ in range(round(0.3 / step) - 1):
        sim.step()
    before = point_velocity()
    sim.step()
    reading = read(imu, sim)
    sim.step()
    derivative = (point_velocity() - before) / (2 * sim.step_seconds)
    c, s = math.cos(reading.yaw), math.sin(reading.yaw)
    fx, fy = reading.linear_acceleration
    assert abs(reading.angular_velocity) > 5.0  # the push did turn it
    return np.array([c * fx - s * fy, s * fx + c * fy - 9.81]) - derivative


def test_acceleration_at_the_mount_is_the_derivative_of_its_point_velocity():
    # The central difference errs by h^2 / 6 times the jerk: the difference shrinks four
    # times when the step halves (a missing term would leave an error that does not).
    coarse, fine = mount_error(1e-4), mount_error(5e-5)
    assert np.max(np.abs(coarse)) < 2e-6
    np.testing.assert_allclose(coarse / fine, [4.0, 4.0], rtol=0.02)


def test_noise_is_seeded_by_stamp():
    imu, sim = imu_on({"shape": "circle", "radius": 0.5, "mass": 1.0}, orientation_noise=0.01,
                     angular_velocity_noise=0.02, linear_acceleration_noise=0.1, seed=4)
    a = imu.forced(sim.q, sim.v, sim.model.accelerations(sim.q, sim.v))
    readings = [imu.read(sim.q, sim.v, a, stamp) for stamp in range(2000)]
    assert readings == [imu.read(sim.q, sim.v, a, stamp) for stamp in range(2000)]
    spread = np.std([[r.yaw, r.angular_velocity, *r.linear_acceleration] for r in readings],
                    axis=0)
    np.testing.assert_allclose(spread, [0.01, 0.02, 0.1, 0.1], rtol=0.08)  # 5 sigma: 7.9 %


@pytest.mark.parametrize("deviations", [(0.01, 0.02, 0.1, 0.3), (0.0, 0.02, 0.1, 0.3),
                                        (0.01, 0.0, 0.0, 0.0)])
def test_each_value_adds_its_deviation_times_its_own_draw(deviations):
    """A noisy reading is the clean one plus each deviation times the draw of its place
    (yaw, omega, x, y) from the reading's generator (:class:`~.noise.Noise`), to the bit;
    a zero deviation still adds its zero times the draw, and one noisy value is noise."""
    body = {"shape": "box", "size": [0.4, 0.2], "mass": 3.0, "velocity": [0.3, -0.2],
            "angular_velocity": 1.7}
    forces = {"g": {"type": "gravity"}}
    noisy, sim = imu_on(body, forces, position=[0.15, 0.05], angle=0.4, seed=9,
                       orientation_noise=deviations[0], angular_velocity_noise=deviations[1],
                       linear_acceleration_noise=deviations[2])
    noisy.deviations = deviations  # x and y apart, so that a swap of the two shows
    clean, _ = imu_on(body, forces, position=[0.15, 0.05], angle=0.4)
    for _ in range(321):
        sim.step()
    a = clean.forced(sim.q, sim.v, sim.model.accelerations(sim.q, sim.v))  # noisy's too
    for stamp in (sim.time_ns, 5 * sim.time_ns + 7):
        base, reading = (imu.read(sim.q, sim.v, a, stamp) for imu in (clean, noisy))
        draws = np.random.Generator(np.random.PCG64(np.random.SeedSequence(
            [9, zlib.crc32(noisy.spec.frame_id.encode()), stamp]))).standard_normal(4)
        expected = [value + deviation * draw for value, deviation, draw in
                    zip((base.yaw, base.angular_velocity, *base.linear_acceleration),
                        deviations, draws.tolist())]
        got = [reading.yaw, reading.angular_velocity, *reading.linear_acceleration]
        assert np.array(got).tobytes() == np.array(expected).tobytes()
        assert reading.stamp_ns == stamp


def test_a_bad_imu_rate_is_refused_by_name():
    with pytest.raises(SceneError, match="sensors.imu.rate"):
        imu_on({"shape": "circle", "radius": 0.5, "mass": 1.0}, rate=3000.0)


@pytest.mark.parametrize("key", ["orientation_noise", "angular_velocity_noise",
                                 "linear_acceleration_noise"])
def test_a_noise_whose_variance_is_no_double_is_refused_by_name(key):
    """The Imu message carries each noise's variance: a deviation past sqrt(max double)
    (1.3e154) would overflow it when the reading is published, so the loader refuses it;
    the largest one allowed gives finite covariances."""
    body = {"shape": "circle", "radius": 0.5, "mass": 1.0}
    with pytest.raises(SceneError, match=f"sensors.imu.{key}': must be at most 1.34"):
        imu_on(body, **{key: 1e155})
    imu, sim = imu_on(body, **{key: math.sqrt(sys.float_info.max)})
    fields = imu_fields(imu.spec, read(imu, sim))
    assert all(math.isfinite(v) for covariance in fields[2::2] for v in covariance)
