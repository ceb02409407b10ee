"""The robot's laser scans and IMU readings are outputs of the replay contract: a replay
publishes the scans a direct cast gives at the same states, bit for bit, and the check
compares them (ranges with the position tolerance, IMU readings with the angle and velocity
tolerances) and fails on a range one bit off or a scan topic the recording lacks."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from live_session import S, record, run_live

from hecker_dynamics.bags import read_bag
from hecker_dynamics.bags.compare import Tolerances
from hecker_dynamics.bags.live import check_live
from hecker_dynamics.bags.replay import replay_outputs, snapshot_messages
from hecker_dynamics.cli import main
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.scene import load_scene
from hecker_dynamics.sensors.laser import Laser

GOLDEN_INPUT = Path(__file__).parents[1] / "golden" / "robot" / "input"
SCAN, IMU = "/robot/laser/scan", "/robot/imu/imu"
EXACT = Tolerances(0.0, 0.0, 0.0)


def test_replayed_scans_equal_a_direct_cast_at_the_states_the_script_reaches():
    scene = load_scene("robot")
    outputs, result = replay_outputs(scene, read_bag(GOLDEN_INPUT), play_script=True)
    assert not result.rejected and result.halted is None
    scans = [o for o in outputs if o.topic == SCAN]
    # 10 Hz from 0.1 s; the sensors sample an instant on leaving it, and the replay ends
    # at 4 s, which a bag of inputs alone does not say the node left.
    assert len(scans) == result.reached_ns // scene.sensors[1].period_ns - 1
    runner = Runner(scene)  # the script's run, driven as the node drives it
    laser = Laser(scene.sensors[1], scene, runner.sim.model.cm_local)
    direct, at = {}, {}
    for stamp in [scan.log_ns for scan in scans]:
        for snapshot in runner.advance(stamp).snapshots:
            at[snapshot.time_ns] = snapshot
        assert runner.sim.time_ns == stamp
        direct[stamp] = laser.scan(runner.sim.q, stamp).ranges.astype(np.float32)
    # The replay reached the states of the scripted run: its poses are the run's.
    poses = [o for o in outputs if o.topic == "/robot/pose" and o.log_ns in at]
    for output in poses:
        expected = {o.topic: o for o in snapshot_messages(scene, at[output.log_ns])}
        assert output.msg.pose == expected[output.topic].msg.pose
    assert poses[-1].msg.pose.position.x > 2.0  # the script drove the robot into the crate
    for scan in scans:
        assert scan.msg.ranges.dtype == np.float32
        assert scan.msg.ranges.tobytes() == direct[scan.log_ns].tobytes()
        assert (scan.msg.header.stamp.sec * S + scan.msg.header.stamp.nanosec) == scan.log_ns


def _robot_session(seed: int):
    return run_live(load_scene("robot"), seed, cmd_vels=10, inputs=3)


def test_a_range_one_bit_off_fails_the_exact_check_and_the_position_tolerance_takes_it(
        tmp_path):
    scene = load_scene("robot")
    session = _robot_session(40)
    scans = [p for p in session.published if p.topic == SCAN]
    ranges = scans[len(scans) // 2].msg.ranges
    ranges.view(np.uint32)[90] ^= 1  # the lowest bit of the middle ray's float32
    path = record(session, tmp_path / "live", 40)
    check = check_live(scene, read_bag(path), tolerances=EXACT)
    assert not check.ok and not check.problems
    largest = check.report.largest()
    assert 0.0 < largest["position"] < 1e-6
    assert largest["angle"] == largest["velocity"] == 0.0
    assert check_live(scene, read_bag(path), tolerances=Tolerances(1e-6, 0.0, 0.0)).ok
    assert main(["replay", "robot", str(path), "--check", "--atol", "0"]) == 1


def test_an_imu_reading_off_fails_by_the_velocity_tolerance(tmp_path):
    scene = load_scene("robot")
    session = _robot_session(41)
    readings = [p for p in session.published if p.topic == IMU]
    readings[len(readings) // 2].msg.linear_acceleration.x += 1e-3
    path = record(session, tmp_path / "live", 41)
    bag = read_bag(path)
    failed = check_live(scene, bag, tolerances=Tolerances(1.0, 1.0, 1e-4))
    assert not failed.ok and 0.9e-3 < failed.report.largest()["velocity"] < 1.1e-3
    assert check_live(scene, bag, tolerances=Tolerances(0.0, 0.0, 2e-3)).ok


def test_a_recording_without_the_scan_topic_fails(tmp_path, capsys):
    scene = load_scene("robot")
    session = _robot_session(42)
    session.published = [item for item in session.published if item.topic != SCAN]
    path = record(session, tmp_path / "live", 42)
    assert SCAN not in read_bag(path).topics
    check = check_live(scene, read_bag(path), tolerances=EXACT)
    assert not check.ok and any(SCAN in p and "not recorded" in p for p in check.problems)
    assert main(["replay", "robot", str(path), "--check", "--atol", "0"]) == 1
    assert main(["replay", "robot", str(path), "--check", "--atol", "0", "--topic",
                 "/robot/pose", "--topic", IMU]) == 0
