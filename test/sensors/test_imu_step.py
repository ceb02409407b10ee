"""What the run loop's IMU samples read: the specific force at the mount over the step that
ended at the stamp, every force included, as (v_P(t) - v_P(t - h)) / h less gravity (a body
point's velocity, Eq. 9). A box resting on the floor reads g up; a pendulum's bob reads its
centripetal and tangential acceleration, the rod's pull included; free fall reads zero; the
robot feels its bump into the crate. A keyframe, a restore and the kernel keep the bits."""
from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.outputs import OutputKind
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.ros.session import decode_state
from hecker_dynamics.scene import load_scene
from hecker_dynamics.scene.load import Scene
from hecker_dynamics.scene.sensors import LaserSpec
from hecker_dynamics.sensors.imu import Imu
from hecker_dynamics.sensors.touch import TouchKind

S = 1_000_000_000
MS = 1_000_000
G = 9.81
EPS = sys.float_info.epsilon

#: Per stamp: the reading's yaw, angular velocity and specific force (x, y).
Samples = dict[int, tuple[float, float, tuple[float, float]]]


@pytest.fixture(autouse=True, params=["1", "0"], ids=["kernel", "python"])
def switch(request, monkeypatch):
    """Every run steps in the kernel (where built) and in Python."""
    monkeypatch.setenv(kernel.SWITCH, request.param)


def imu_samples(runner: Runner, until_ns: int) -> dict[str, Samples]:
    """Per IMU topic, its samples up to ``until_ns``, that instant's too (taken on leaving
    it, as a replay ending there does)."""
    found: dict[str, Samples] = {}
    for stamp, output in runner.advance(until_ns).readings + runner.leave():
        if output.kind is OutputKind.IMU:
            fields = output.fields
            _, _, z, w = fields.orientation
            found.setdefault(output.topic, {})[stamp] = (
                2.0 * math.atan2(z, w), fields.angular_velocity[2],
                fields.linear_acceleration[:2])
    return found


def stepped(scene: Scene, until_ns: int) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The states (q, v) of a simulation of ``scene`` after every step, one step a call."""
    sim = Simulation(scene)
    states = {sim.time_ns: (sim.q.copy(), sim.v.copy())}
    while sim.time_ns < until_ns:
        sim.step()
        states[sim.time_ns] = (sim.q.copy(), sim.v.copy())
    return states


def test_a_box_resting_on_the_floor_reads_g_up_in_its_axes_and_zero_while_it_falls():
    # Dropped from 0.4 m at 0.3 rad: it falls freely until about 0.24 s, lands on a corner,
    # bounces and lies flat by 0.5 s. One IMU off the CM and level, one turned by 90 deg.
    scene = make_scene({
        "step": 1e-3, "integrator": "semi_implicit_euler",
        "bodies": {"box": {"shape": "box", "size": [0.4, 0.2], "mass": 2.0,
                           "position": [0.0, 0.4], "angle": 0.3}},
        "forces": {"g": {"type": "gravity"}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.3,
                            "friction": 0.5}},
        "sensors": {"level": {"type": "imu", "body": "box", "position": [0.1, 0.05]},
                    "upright": {"type": "imu", "body": "box", "angle": math.pi / 2}}})
    runner = Runner(scene)
    samples = imu_samples(runner, 2 * S)
    level, upright = samples["box/level/imu"], samples["box/upright/imu"]
    assert len(level) == len(upright) == 200
    # Lying still after 1 s, each reads g up turned into its axes (yaw: the body's angle,
    # 1e-9 rad here, plus the mount's). The contact pass answers each step's g h to the
    # rounding of a velocity near zero, about 1e-14 m/s over 1 ms: 1e-11 m/s^2; before
    # the fix every one of these read 0, 9.81 off.
    for sensor in (level, upright):
        for stamp, (yaw, omega, (along, across)) in sensor.items():
            if stamp > S:
                assert abs(along - G * math.sin(yaw)) < 1e-9 and abs(omega) < 1e-12
                assert abs(across - G * math.cos(yaw)) < 1e-9
    assert upright[2 * S][2] == pytest.approx((G, 0.0), abs=1e-6)
    # Falling freely (no spin, so the mount moves with the CM): the step's change of
    # velocity is g h to the rounding of the velocity, eps |v| / h, and of g.
    states = stepped(scene, 200 * MS)
    for stamp in range(10 * MS, 210 * MS, 10 * MS):
        speed = float(np.hypot(*states[stamp][1][0, :2]))
        bound = 4 * EPS * (speed / 1e-3 + G)
        assert max(map(abs, level[stamp][2] + upright[stamp][2])) < bound, stamp
    # The landing: the floor's impulse stops the fall within steps, far above g.
    assert max(math.hypot(*sample[2]) for sample in level.values()) > 5 * G


def pendulum_error(step: float) -> float:
    """The largest difference over 2 s between the bob's readings (in fixed axes) and its
    exact acceleration less gravity, averaged over the step's two ends: the centripetal
    -omega^2 r and the tangential alpha perp(r), with alpha the torque of gravity about the
    pin over the moment of inertia about it (tau = I alpha, Eq. 14, with the parallel
    axes)."""
    length, mass, radius, start = 1.0, 2.0, 0.1, 1.0  # rad from hanging straight down
    down = (length * math.sin(start), -length * math.cos(start))
    scene = make_scene({
        "step": step, "integrator": "rk4",
        "bodies": {"bob": {"shape": "circle", "radius": radius, "mass": mass,
                           "position": list(down)}},
        "forces": {"g": {"type": "gravity"}},
        "joints": {"pin": {"type": "revolute", "body_b": "bob",
                           "point_b": [-down[0], -down[1]]}},
        "sensors": {"imu": {"type": "imu", "body": "bob"}}})
    runner = Runner(scene)
    samples = imu_samples(runner, 2 * S)["bob/imu/imu"]
    states = stepped(scene, 2 * S)
    assert (states[2 * S][0] == runner.sim.q).all()  # stopping changes no bit
    inertia = mass * radius ** 2 / 2 + mass * length ** 2

    def exact(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        (rx, ry), omega = q[0, :2], v[0, 2]  # the pin is at the origin
        alpha = rx * -mass * G / inertia
        return np.array([-omega ** 2 * rx - alpha * ry, -omega ** 2 * ry + alpha * rx])

    errors = []
    for stamp, (yaw, _, (along, across)) in samples.items():
        c, s = math.cos(yaw), math.sin(yaw)
        measured = np.array([c * along - s * across, s * along + c * across + -G])
        mean = (exact(*states[stamp - scene.step_ns]) + exact(*states[stamp])) / 2
        errors.append(np.max(np.abs(measured - mean)))
    assert len(errors) == 200
    return max(errors)


def test_a_pendulum_bob_reads_its_centripetal_and_tangential_acceleration():
    # The bob swings at up to 7.6 m/s^2 (before the fix it read 0 plus the missing pull of
    # the rod). The mean of the two ends errs by h^2 / 12 times the acceleration's second
    # derivative and RK4's joint pass is second order too: the difference shrinks four
    # times when the step halves (a missing force would leave one that does not).
    coarse, fine = pendulum_error(1e-3), pendulum_error(5e-4)
    assert coarse < 1e-4
    assert coarse / fine == pytest.approx(4.0, rel=0.02)


def test_free_flight_on_a_spring_reads_the_velocity_difference_to_the_bit():
    # A box thrown spinning, on a spring from a corner to a fixed anchor, under gravity;
    # the IMU off its CM, turned 0.7 rad. Each reading is the mount's velocity change over
    # the step (a body point's velocity, Eq. 9, at both ends) over h, less g, in the
    # sensor's axes, recomputed here from two consecutive states, bit for bit; the gyro
    # reads the state at the stamp.
    mount, turn = (0.3, -0.1), 0.7
    scene = make_scene({
        "step": 2e-3, "integrator": "semi_implicit_euler",
        "bodies": {"box": {"shape": "box", "size": [1.0, 0.5], "mass": 1.5,
                           "velocity": [0.5, 2.0], "angular_velocity": 3.0}},
        "forces": {"g": {"type": "gravity"},
                   "pull": {"type": "spring", "body_a": "box", "point_a": [0.5, 0.25],
                            "anchor": [1.0, 2.0], "stiffness": 40.0, "damping": 0.5}},
        "sensors": {"imu": {"type": "imu", "body": "box", "position": list(mount),
                            "angle": turn, "rate": 50.0}}})
    samples = imu_samples(Runner(scene), 2 * S)["box/imu/imu"]
    states = stepped(scene, 2 * S)
    h = scene.step_ns * 1e-9

    def mount_velocity(q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
        theta, omega = float(q[0, 2]), float(v[0, 2])
        c, s = math.cos(theta), math.sin(theta)
        r = (c * mount[0] - s * mount[1], s * mount[0] + c * mount[1])
        return float(v[0, 0]) + omega * -r[1], float(v[0, 1]) + omega * r[0]

    assert len(samples) == 100
    for stamp, (yaw, omega, force) in samples.items():
        (q0, v0), (q1, v1) = states[stamp - scene.step_ns], states[stamp]
        (x0, y0), (x1, y1) = mount_velocity(q0, v0), mount_velocity(q1, v1)
        fx, fy = (x1 - x0) / h, (y1 - y0) / h - -G
        c, s = math.cos(float(q1[0, 2]) + turn), math.sin(float(q1[0, 2]) + turn)
        expected = (c * fx + s * fy, c * fy - s * fx)
        assert np.array(force).tobytes() == np.array(expected).tobytes(), stamp
        assert omega == v1[0, 2] and yaw == pytest.approx(q1[0, 2] + turn, abs=1e-15)
    assert max(math.hypot(*sample[2]) for sample in samples.values()) > 20.0


def test_the_robot_feels_its_bump_into_the_crate():
    # The script drives the robot (8 kg) into the crate: the touch begins at 3.412 s and
    # the impact lands in the step that ends at 3.42 s, an IMU instant. The wheels push it
    # at most 2 x 20 N (5 m/s^2); the crate's impulse stops it by about 0.13 m/s in that
    # step, 67 m/s^2 back. Before the fix the IMU read the wheels only.
    scene = dataclasses.replace(load_scene("robot"), publish_contacts=True)
    runner = Runner(scene)
    tick = runner.advance(3600 * MS)
    touch = [stamp for stamp, output in tick.readings if output.kind is OutputKind.CONTACT_EVENT
             and output.fields.event == TouchKind.BEGIN and "crate" in
             (output.fields.body_a, output.fields.body_b) and "robot" in
             (output.fields.body_a, output.fields.body_b)]
    along = {stamp: output.fields.linear_acceleration[0] for stamp, output in tick.readings
             if output.kind is OutputKind.IMU}
    assert touch == [3412 * MS]
    assert along[3420 * MS] < -40.0
    assert all(abs(a) < 5.0 for stamp, a in along.items() if stamp != 3420 * MS)


def test_kernel_and_python_read_the_same_bits(monkeypatch):
    runs = []
    for switch in ("1", "0"):
        monkeypatch.setenv(kernel.SWITCH, switch)
        runs.append(repr(imu_samples(Runner(load_scene("robot")), 4 * S)))
    assert runs[0] == runs[1]


@pytest.mark.parametrize("stop_ns", [1000 * MS, 998 * MS, 990 * MS])
def test_a_restore_from_a_keyframe_reads_what_the_run_read(stop_ns):
    # Keyframes at an IMU instant (taken on arriving there, holding the specific force
    # measured over the step that led there), one step before one (where the step it
    # measures begins, after the keyframe) and between both; the robot pushes the crate
    # meanwhile.
    scene = load_scene("robot")
    whole = Runner(scene)
    whole.advance(stop_ns)
    keyframe = whole.keyframe()
    held = decode_state(keyframe.state)["runner"]["imu"]
    assert (held[0] == stop_ns and [name for name, _, _ in held[1]] == ["imu"]) \
        if stop_ns == 1000 * MS else held == []
    later = whole.advance(3600 * MS).readings
    restored = Runner(scene)
    restored.restore(keyframe)
    assert repr(restored.advance(3600 * MS).readings) == repr(later)
    # A keyframe of a scene without an IMU holds what it always held.
    laser_only = dataclasses.replace(scene, sensors=tuple(
        spec for spec in scene.sensors if isinstance(spec, LaserSpec)))
    assert "imu" not in decode_state(Runner(laser_only).keyframe().state)["runner"]


def test_a_world_change_at_an_imu_instant_keeps_what_the_step_measured():
    # A body spawned at an IMU instant, and the robot moved there, after the arrival: the
    # reading of that instant is still the step's (the measured force carried into the
    # rebuilt sensors), its gyro and orientation the state the change left.
    scene = load_scene("robot")
    plain, changed = Runner(scene), Runner(scene)
    plain.advance(1000 * MS)
    changed.advance(1000 * MS)
    spawned = changed.spawn_body("ball", "{shape: circle, radius: 0.1, mass: 1.0, "
                                 "position: [5.0, 1.0]}")
    moved = changed.set_body_state("robot", [1.5, 1.0, 0.5, 0.0, 0.0, 0.25])
    assert spawned.accepted and moved.accepted
    quiet, after = imu_samples(plain, 1000 * MS), imu_samples(changed, 1000 * MS)
    yaw, omega, force = after["robot/imu/imu"][1000 * MS]
    assert force == quiet["robot/imu/imu"][1000 * MS][2]
    assert yaw == 0.5 and omega == pytest.approx(0.25, abs=0.01)  # the gyro's noise


def test_an_imu_instant_the_clock_skipped_to_reads_the_force_terms():
    # Paused at 1 s and resumed at 1.5 s, an IMU instant: no step led there, so its
    # sample reads the force terms at its state (Imu.forced), as every sample did before.
    scene = load_scene("robot")
    runner = Runner(scene)
    runner.advance(1000 * MS)
    assert runner.pause().accepted and runner.resume_at(1500 * MS).accepted
    yaw, omega, force = imu_samples(runner, 1500 * MS)["robot/imu/imu"][1500 * MS]
    imu = next(sensor for sensor in runner.sensors.sensors if isinstance(sensor, Imu))
    sim = runner.sim
    expected = imu.read(sim.q, sim.v, imu.forced(sim.q, sim.v, sim.accelerations()), 1500 * MS)
    assert force == expected.linear_acceleration and omega == expected.angular_velocity
    assert yaw == pytest.approx(expected.yaw, abs=1e-15)  # through the quaternion
