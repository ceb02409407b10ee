"""The robot's laser scans and IMU readings are outputs of the replay contract: a replay
publishes the scans a direct cast gives at the same states, bit for bit, and the check
compares them (ranges with the position tolerance, IMU readings with the angle and velocity
tolerances) and fails on a range one bit off or a scan topic the recording lacks."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from live_session import S, record, run_live

from hecker_dynamics.bags import read_bag
from hecker_dynamics.bags.compare import Tolerances
from hecker_dynamics.bags.live import check_live
from hecker_dynamics.bags.replay import replay_outputs, snapshot_messages
from hecker_dynamics.cli import main
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.ros.session import decode_state, encode_state
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


def test_imu_readings_replay_exactly_from_a_keyframe_at_an_imu_instant(tmp_path,
                                                                       monkeypatch):
    """An input event's record lost: with ``partial`` the replay starts from the next
    keyframe, here one taken on arriving at an IMU instant, which holds the specific
    force measured over the step that led there (sensors/schedule.py), and the readings
    from there on match the live ones to the bit; the robot runs into the crate and pushes
    it meanwhile. Without the loss the replay from the start matches too."""
    scene = load_scene("robot")
    session = run_live(scene, 43, cmd_vels=10, inputs=3, keyframe_period_ns=S // 4)
    def stamp(msg: Any) -> int:
        return msg.header.stamp.sec * S + msg.header.stamp.nanosec

    keyframes = [p.msg for p in session.published if p.topic.endswith("/keyframe")]
    holding = {stamp(k) for k in keyframes if decode_state(k.state)["runner"]["imu"]}
    assert len(holding) >= 5  # every other one is at an IMU instant
    after = {stamp(p.msg): min((stamp(k) for k in keyframes if stamp(k) > stamp(p.msg)),
                               default=None)
             for p in session.published if p.topic.endswith("/input_events")}
    lost = next(p for p in session.published if p.topic.endswith("/input_events")
                and after[stamp(p.msg)] in holding)
    whole = check_live(scene, read_bag(record(session, tmp_path / "whole", 43)),
                       tolerances=EXACT)
    assert whole.ok, whole.report.text() + "\n" + "\n".join(whole.problems)
    restored: list[int] = []
    restore = Runner.restore
    monkeypatch.setattr(Runner, "restore", lambda runner, keyframe: (
        restored.append(keyframe.stamp_ns), restore(runner, keyframe))[1])
    path = record(session, tmp_path / "lossy", 43, drop=lambda _, item: item is lost)
    check = check_live(scene, read_bag(path), tolerances=EXACT, partial=True)
    assert check.ok, check.report.text() + "\n" + "\n".join(check.problems)
    assert restored == [after[stamp(lost.msg)]] and check.unchecked > 0
    assert any(t.topic == IMU and t.matched > 50 for t in check.report.topics)


def test_a_recording_whose_imu_left_out_contacts_fails_naming_it(tmp_path, capsys):
    """A session recorded before the IMU read its last step (its keyframes without the
    measured force, its readings the force terms') fails the check: the IMU topic is the
    one that mismatches and the keyframes say why."""
    scene = load_scene("robot")
    session = run_live(scene, 44, cmd_vels=10, inputs=3)
    for published in session.published:
        if published.topic.endswith("/keyframe"):
            state = decode_state(published.msg.state)
            del state["runner"]["imu"]
            published.msg.state = encode_state(state)
        elif published.topic == IMU:
            published.msg.linear_acceleration.x = 0.0
    assert main(["replay", "robot", str(record(session, tmp_path / "old", 44)),
                 "--check"]) == 1
    out = capsys.readouterr().out
    assert "differs from the recorded keyframe (recorded by a version whose IMUs left out " \
           "contacts and joints: record the session again)" in out
    failed = [line for line in out.splitlines() if line.startswith("FAIL /")]
    assert len(failed) == 1 and failed[0].startswith(f"FAIL {IMU} ")
