"""When the run loop samples the sensors: each at start + k / rate (k >= 1), once, as the
simulation steps on from the instant, so a reading holds every input pushed at its
instant (an IMU's, every input of the step that ended there), however the loop's ticks fell
around it."""
from __future__ import annotations

import dataclasses

from hecker_dynamics.bags import io as bags
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.outputs import OutputKind
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.scene.load import load_scene
from hecker_dynamics.sensors.schedule import SensorSet

MS = 1_000_000


def _imu(runner: Runner, until_ns: int) -> dict[int, tuple[float, float, float]]:
    return {stamp: output.fields.linear_acceleration
            for stamp, output in runner.advance(until_ns).readings
            if output.kind is OutputKind.IMU}


def test_a_push_in_the_step_before_a_sample_instant_is_in_the_reading_of_that_instant():
    # The robot stands still until its script drives it at 0.5 s. A wrench pushed at
    # 0.118 s for one step, the step before the IMU instant 0.12 s, acts over the
    # step the reading stamped 0.12 s measures: it holds its F / m (the noise is the
    # stamp's, the same in both); the drives answer it only at their next control instant
    # (0.12 s), so nothing else differs. The reading of 0.1 s, before it, does not change.
    scene = load_scene("robot")
    robot = next(body for body in scene.bodies if body.name == "robot")
    plain, pushed = Runner(scene), Runner(scene)
    before = _imu(plain, 118 * MS), _imu(pushed, 118 * MS)
    assert before[0] == before[1] and sorted(before[0]) == [20 * MS * k for k in range(1, 6)]
    assert pushed.sim.time_ns == 118 * MS
    push = bags.applied_wrench_message(0, "", "robot", "test", (0.0, 0.0), (8.0, 0.0), 0.0,
                                       2 * MS)
    assert pushed.accept("/applied_wrench", push, 118 * MS) == []
    quiet, moved = _imu(plain, 200 * MS), _imu(pushed, 200 * MS)
    assert sorted(quiet) == sorted(moved) == [120 * MS, 140 * MS, 160 * MS, 180 * MS]
    ax, ay, _ = moved[120 * MS]
    bx, by, _ = quiet[120 * MS]
    assert abs((ax - bx) - 8.0 / robot.mass.mass) < 1e-12 and abs(ay - by) < 1e-12


def test_every_sensor_samples_each_of_its_instants_once_whatever_the_ticks():
    # Ticks of 7 ms, a tick that ends on every instant, and one long tick give the same
    # readings, byte for byte.
    scene = load_scene("robot")
    runs = []
    for tick_ns in (7 * MS, 20 * MS, 1000 * MS):
        runner = Runner(scene)
        readings = []
        target = 0
        while target < 1000 * MS:
            target = min(target + tick_ns, 1000 * MS)
            readings += runner.advance(target).readings
        runs.append(readings)
    assert runs[0] == runs[1] == runs[2]
    stamps = [(stamp, output.kind) for stamp, output in runs[0]]
    assert len(stamps) == len(set(stamps)) == 49 + 9


def test_next_sample_instant_for_periods_that_do_not_divide_each_other():
    # Periods of 30 and 20 ms (grid 10 ms) from a start off zero: the next instant after
    # every ns-scale offset around each grid line is the nearest multiple of either
    # period ahead, the first ones a whole period after the start; the sensors due at an
    # instant are those whose period divides its time since the start.
    scene = load_scene("robot")
    periods = {"laser": 30 * MS, "imu": 20 * MS}
    scene = dataclasses.replace(scene, sensors=tuple(
        dataclasses.replace(spec, period_ns=periods[spec.name]) for spec in scene.sensors))
    start = 7 * MS + 3
    sim = Simulation(scene, start_ns=start)
    sensors = SensorSet(scene, sim)
    for now in sorted({start + k * MS + d for k in range(-25, 130) for d in (-1, 0, 1)}):
        expected = min(start + max(1, (now - start) // p + 1) * p for p in periods.values())
        assert sensors.next_stop(now) == expected, now
    for k in range(1, 13):
        sim = Simulation(scene, start_ns=start)
        sim.advance_to(start + k * 10 * MS)
        due = [spec.name for spec, _ in SensorSet(scene, sim).sample(sim)]
        assert due == [spec.name for spec in scene.sensors
                       if k * 10 * MS % periods[spec.name] == 0], k
