"""Bags: golden regression, determinism, storage round trips, node-made sessions, bad bags.

Golden bags live in test/golden/<scene>/{input,output} (see test/golden/README.md); regenerate
them with ``bash scripts/make_golden_bags.sh`` after an intended change of behaviour.
"""
from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
import yaml

from hecker_dynamics.bags import io as bags
from hecker_dynamics.bags.compare import Tolerances, compare_bags, compare_contents
from hecker_dynamics.bags.io import (
    APPLIED_WRENCH,
    POSE_STAMPED,
    TWIST,
    WRENCH_STAMPED,
    BagError,
    BagWriter,
    read_bag,
)
from hecker_dynamics.bags.replay import (
    ReplayError,
    outputs_as_bag,
    replay_outputs,
    replay_to_bag,
    script_to_bag,
    serialize_outputs,
)
from hecker_dynamics.cli import main
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros import fields
from hecker_dynamics.ros.names import output_qos
from hecker_dynamics.scene.load import load_scene, shipped_scenes

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
REGENERATE = "bash scripts/make_golden_bags.sh"
#: Golden outputs were written on one machine; another CPU or numpy may round differently
#: in the last bits, which a bouncing scene can grow over a few seconds.
GOLDEN_ATOL = 1e-6
SEC = 1_000_000_000


def golden(scene: str) -> tuple[Path, Path]:
    return GOLDEN / scene / "input", GOLDEN / scene / "output"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_clean_error(code: int, err: str, *needles: str) -> None:
    """Non-zero exit with one clear line on stderr, no traceback."""
    assert code != 0
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines and lines[-1].startswith("hecker-dynamics: error: "), err
    assert len(lines) == 1, err
    for needle in needles:
        assert needle in err, err


# ----------------------------------------------------------------------------- golden

@pytest.mark.parametrize("scene", shipped_scenes())
def test_golden_replay_matches(scene):
    input_bag, output_bag = golden(scene)
    if not (input_bag / "metadata.yaml").is_file() or not (output_bag / "metadata.yaml").is_file():
        pytest.fail(f"shipped scene '{scene}' has no golden bags in {GOLDEN / scene}; "
                    f"run `{REGENERATE}`")
    loaded = load_scene(scene)
    inputs = read_bag(input_bag)
    expected = read_bag(output_bag)
    produced, result = replay_outputs(loaded, inputs)
    assert not result.rejected and result.halted is None
    actual = outputs_as_bag(loaded, produced)
    report, ok = compare_contents(expected, actual,
                                  tolerances=Tolerances.uniform(GOLDEN_ATOL))
    assert ok, (f"scene '{scene}' no longer reproduces its golden bag; if the change is "
                f"intended, run `{REGENERATE}`\n{report.text()}")
    # The golden bag is not empty: every body published at every publish instant.
    poses = [m for m in expected.messages if m.topic.endswith("/pose")]
    duration = expected.custom_int("duration_ns")
    assert len(poses) == len(loaded.bodies) * (duration // loaded.publish_period_ns)


def test_every_golden_bag_belongs_to_a_shipped_scene():
    scenes = set(shipped_scenes())
    stale = sorted(p.name for p in GOLDEN.iterdir() if p.is_dir() and p.name not in scenes)
    assert not stale, f"golden bags of scenes that are not shipped: {stale}; run `{REGENERATE}`"


def test_golden_bags_are_small_and_in_jazzy_format():
    for directory in sorted(GOLDEN.glob("*/*/")):
        size = sum(f.stat().st_size for f in directory.iterdir())
        info = yaml.safe_load((directory / "metadata.yaml").read_text())
        info = info["rosbag2_bagfile_information"]
        topics = len(info["topics_with_message_count"])
        assert size < 100_000 + 2_000 * topics, f"{directory} is {size} bytes, {topics} topics"
        assert info["version"] == 9 and info["storage_identifier"] == "mcap"
        for topic in info["topics_with_message_count"]:
            meta = topic["topic_metadata"]
            assert meta["type_description_hash"].startswith("RIHS01_")
            qos = meta["offered_qos_profiles"]
            assert isinstance(qos, list) and qos[0]["history"] == "keep_last"
            # keep-last 10, but 1 for the latched /map (names.MAP_QOS)
            depth = output_qos(meta["name"]).depth
            assert qos[0]["reliability"] == "reliable" and qos[0]["depth"] == depth


def test_replay_of_a_script_bag_equals_simulation_play(tmp_path):
    """The stamp rules reproduce the core's own scripted run exactly."""
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", duration_ns=scene.duration_ns)
    produced, _ = replay_outputs(scene, read_bag(tmp_path / "in"), duration_ns=4 * SEC)
    sim = Simulation(scene)
    snapshots = sim.play(scene.script, 4 * SEC)
    poses = [o for o in produced if o.topic == "/left/pose"]
    assert len(poses) == len(snapshots) == 200
    for output, snapshot in zip(poses, snapshots):
        expected = fields.pose_fields(snapshot.bodies[0], "world", snapshot.time_ns)
        assert output.log_ns == snapshot.time_ns
        assert tuple(vars(output.msg.pose.position)[k] for k in "xyz") == expected.pose.position


# ----------------------------------------------------------------------------- determinism

def test_replay_twice_gives_identical_bytes(tmp_path):
    scene_name = "sample" if "sample" in shipped_scenes() else shipped_scenes()[0]
    scene = load_scene(scene_name)
    script_to_bag(scene, tmp_path / "in", duration_ns=2 * SEC)
    bag = read_bag(tmp_path / "in")
    first = serialize_outputs(replay_outputs(scene, bag)[0])
    second = serialize_outputs(replay_outputs(load_scene(scene_name), read_bag(tmp_path / "in"))[0])
    assert first and first == second
    # Written bags hold the same bytes in the same order, and the storage file is identical.
    for run in ("a", "b"):
        (tmp_path / run).mkdir()
        replay_to_bag(scene, bag, tmp_path / run / "out")
    written = [(m.topic, m.log_ns, m.raw) for m in read_bag(tmp_path / "a" / "out").messages]
    assert written == first
    assert (tmp_path / "a" / "out" / "out.mcap").read_bytes() == \
        (tmp_path / "b" / "out" / "out.mcap").read_bytes()


# ----------------------------------------------------------------------------- storages

@pytest.mark.parametrize("write_with,read_with", [("sqlite3", "mcap"), ("mcap", "sqlite3")])
def test_round_trip_between_storages(tmp_path, write_with, read_with):
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", storage=write_with, duration_ns=SEC * 4)
    replay_to_bag(scene, read_bag(tmp_path / "in"), tmp_path / "out", storage=write_with,
                  with_inputs=True, duration_ns=SEC * 4)
    source = read_bag(tmp_path / "out")
    assert source.storage == write_with
    # Copy every message into the other storage and read it back.
    with BagWriter(tmp_path / "copy", read_with) as writer:
        for topic, msgtype in source.topics.items():
            writer.add_topic(topic, msgtype)
        for message in source.messages:
            writer.write_raw(message.topic, message.log_ns, message.raw)
    copy = read_bag(tmp_path / "copy")
    assert copy.storage == read_with
    assert copy.topics == source.topics
    assert [(m.topic, m.log_ns, m.raw) for m in copy.messages] == \
           [(m.topic, m.log_ns, m.raw) for m in source.messages]
    # Both carry the full message definitions and the package's type hash.
    for contents in (source, copy):
        assert "string body" in contents.definitions[APPLIED_WRENCH]
        assert "MSG: geometry_msgs/Pose" in contents.definitions[POSE_STAMPED]
        assert contents.digests["/applied_wrench"] == bags.typestore().hash_rihs01(APPLIED_WRENCH)
    # The copy replays (with --check against its recorded outputs) in the other storage.
    report, ok = compare_bags(tmp_path / "out", tmp_path / "copy", atol=0.0)
    assert ok, report.text()
    assert read_bag(tmp_path / "copy").on("/applied_wrench")[0].decode().body == "left"


# ----------------------------------------------------------------------------- node sessions

PUCK_SCENE = """\
dynamics_node:
  ros__parameters:
    step: 0.002
    integrator: rk4
    publish_rate: 50.0
    duration: 3.0
    input_timeout: 0.3
    twist_frame: body
    bodies:
      puck:
        shape: box
        size: [0.4, 0.2]
        mass: 2.0
        position: [0.5, -0.25]
        angle: 0.4
        points:
          nozzle: [-0.2, 0.05]
      ball:
        shape: circle
        radius: 0.1
        mass: 0.5
        position: [2.0, 0.0]
    forces:
      drag:
        type: linear_drag
        coefficient: 0.3
      spin_damping:
        type: angular_damping
        coefficient: 0.05
    wrench_topics:
      thruster:
        topic: puck/thruster
        body: puck
        frame_id: puck/nozzle
    publish:
      odometry: true
"""


def _node_session(tmp_path: Path, scene, start_ns: int, drop_input: bool = False) -> Path:
    """Record a session the way the node runs one, using hecker_dynamics.ros for every message.

    Inputs arrive between timer ticks at odd times, some with zero stamps (act on arrival)
    and some stamped a little before or after their arrival; the node pushes each one at the
    sim time of the last tick, and the recorder logs outputs a little after they were
    published (so log times are not sim times).
    """
    period = scene.publish_period_ns
    arrivals = []  # (arrival ns, topic, msgtype, msg)
    for k in range(40):
        arrival = start_ns + 37_000_000 * k + 1_234_567
        stamp = 0 if k % 3 == 0 else arrival + (-5_000_000 if k % 3 == 1 else 9_000_000)
        msg = bags.applied_wrench_message(
            stamp, "puck" if k % 2 else "world", "puck", f"src{k % 4}",
            (0.1, -0.05), (3.0 * (-1) ** k, 1.0 + 0.1 * k), 0.2 * (k % 5 - 2),
            60_000_000 if k % 4 == 0 else 0)
        arrivals.append((arrival, "/applied_wrench", APPLIED_WRENCH, msg))
    for k in range(25):
        arrival = start_ns + 53_000_000 * k + 7_654_321
        stamp = 0 if k % 2 else arrival - 2_000_000
        msg = bags.wrench_stamped_message(stamp, "", (4.0, 0.5 * k), -0.3)
        arrivals.append((arrival, "/puck/thruster", WRENCH_STAMPED, msg))
    arrivals.sort(key=lambda a: a[0])
    if drop_input:
        del arrivals[len(arrivals) // 2]
    topic = scene.wrench_topics[0]
    sim = Simulation(scene, start_ns=start_ns)
    records = [(a[0], a[1], a[2], a[3]) for a in arrivals]
    index = 0
    tick = start_ns
    end = start_ns + 2 * SEC
    while tick + period <= end:
        target = tick + period
        while index < len(arrivals) and arrivals[index][0] < target:
            arrival, name, msgtype, msg = arrivals[index]
            index += 1
            if msgtype == APPLIED_WRENCH:
                command, _ = fields.applied_wrench_to_command(msg, arrival)
            else:
                command, _ = fields.wrench_stamped_to_command(msg, topic, arrival)
            sim.push(command)
        for snapshot in sim.advance_to(target):
            for n, state in enumerate(snapshot.bodies):
                delay = 150_000 + 10_000 * n
                stamp = snapshot.time_ns
                records.append((stamp + delay, f"/{state.name}/pose", POSE_STAMPED,
                                bags.pose_stamped_message(fields.pose_fields(state, "world",
                                                                              stamp))))
                records.append((stamp + delay + 40_000, f"/{state.name}/twist", TWIST,
                                bags.twist_message(fields.twist_fields(state, "body"))))
                records.append((stamp + delay + 80_000, f"/{state.name}/odom", bags.ODOMETRY,
                                bags.odometry_message(fields.odometry_fields(state, "world",
                                                                              stamp))))
        tick = target
    path = tmp_path / ("session_dropped" if drop_input else "session")
    records.sort(key=lambda r: r[0])
    with BagWriter(path, "sqlite3") as writer:  # no custom data: as ros2 bag record writes
        for log_ns, name, msgtype, msg in records:
            writer.write(name, msgtype, log_ns, msg)
    return path


def test_session_recorded_through_the_mapping_replays_to_its_outputs(tmp_path, capsys):
    scene_file = tmp_path / "puck.yaml"
    scene_file.write_text(PUCK_SCENE)
    scene = load_scene(scene_file)
    start = 1_700_000_000_123_456_789
    session = _node_session(tmp_path, scene, start)
    recorded = read_bag(session)
    assert recorded.custom_data == {}
    code, out, err = run_cli(capsys, "replay", str(scene_file), str(session), "--check",
                             "--atol", "0", "-o", str(tmp_path / "replayed"))
    assert code == 0, out + err
    assert "match" in out and "65 accepted, 0 rejected" in out
    # The replay found the node's start from the first pose, and its outputs are the same
    # messages byte for byte (only the log times differ: the recorder's are arrival times).
    replayed = read_bag(tmp_path / "replayed")
    assert replayed.custom_int("start_ns") == start
    for name in ("/puck/pose", "/puck/twist", "/puck/odom", "/ball/pose"):
        assert [m.raw for m in replayed.on(name)] == [m.raw for m in recorded.on(name)], name
    # A session whose inputs lost one message no longer matches: the check can fail.
    dropped = _node_session(tmp_path, scene, start, drop_input=True)
    missing_input = read_bag(dropped)
    expected = read_bag(session)
    produced, _ = replay_outputs(scene, missing_input)
    report, ok = compare_contents(expected, outputs_as_bag(scene, produced),
                                  topics=["/puck/pose", "/puck/twist"])
    assert not ok and report.largest()["position"] > 1e-6


# ----------------------------------------------------------------------------- cli

def test_cli_script_replay_compare(tmp_path, capsys):
    code, out, _ = run_cli(capsys, "script", "sample", "-o", str(tmp_path / "in"),
                           "--duration", "1.5", "--storage", "sqlite3")
    assert code == 0 and "wrote 0 AppliedWrench" in out  # the kick at 3 s is after 1.5 s
    code, out, err = run_cli(capsys, "replay", "sample", str(tmp_path / "in"),
                             "-o", str(tmp_path / "out"))
    assert code == 0, err
    assert "\r" not in err  # no progress bar when stderr is not a terminal
    code, out, err = run_cli(capsys, "replay", "sample", str(tmp_path / "in"),
                             "-o", str(tmp_path / "out2"), "--progress")
    assert code == 0 and "100%" in err
    code, out, _ = run_cli(capsys, "compare", str(tmp_path / "out"), str(tmp_path / "out2"),
                           "--atol", "0")
    assert code == 0 and out.startswith("match: 300 messages on 4 topics")
    # A different session (other start) mismatches with missing and extra messages.
    run_cli(capsys, "script", "sample", "-o", str(tmp_path / "late"), "--duration", "1.5",
            "--start", "0.1")
    run_cli(capsys, "replay", "sample", str(tmp_path / "late"), "-o", str(tmp_path / "out3"))
    code, out, _ = run_cli(capsys, "compare", str(tmp_path / "out"), str(tmp_path / "out3"))
    assert code == 1
    assert "MISMATCH" in out and "missing 5" in out and "extra 5" in out
    # Output bags are never overwritten unless asked.
    code, _, err = run_cli(capsys, "replay", "sample", str(tmp_path / "in"),
                           "-o", str(tmp_path / "out"))
    assert_clean_error(code, err, "exists already")
    code, _, err = run_cli(capsys, "replay", "sample", str(tmp_path / "in"),
                           "-o", str(tmp_path / "out"), "--overwrite")
    assert code == 0


@pytest.mark.parametrize("command", ["script", "replay", "compare"])
def test_cli_help(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert "usage: hecker-dynamics " + command in capsys.readouterr().out


def test_compare_reports_largest_differences(tmp_path):
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", duration_ns=SEC)
    bag = read_bag(tmp_path / "in")
    replay_to_bag(scene, bag, tmp_path / "a")
    produced, _ = replay_outputs(scene, bag)
    # Shift one pose by 1 mm and turn one twist by 0.01 rad/s.
    for output in produced:
        if output.topic == "/right/pose" and output.log_ns == 500_000_000:
            output.msg.pose.position.x += 1e-3
        if output.topic == "/left/twist" and output.log_ns == 700_000_000:
            output.msg.angular.z += 1e-2
    report, ok = compare_contents(read_bag(tmp_path / "a"), outputs_as_bag(scene, produced))
    assert not ok
    worst = {t.topic: t for t in report.topics}
    assert worst["/right/pose"].position.value == pytest.approx(1e-3, rel=1e-6)
    assert worst["/right/pose"].position.stamp_ns == 500_000_000
    assert worst["/left/twist"].angular_velocity.value == pytest.approx(1e-2, rel=1e-6)
    assert worst["/left/pose"].ok(report.tolerances)
    report, ok = compare_contents(read_bag(tmp_path / "a"), outputs_as_bag(scene, produced),
                                  tolerances=Tolerances(position=2e-3, angle=1e-9, velocity=0.02))
    assert ok, report.text()



@pytest.mark.parametrize("scale", [2.0, 0.0, 1.0 + 1e-6])
def test_a_quaternion_of_another_length_is_no_match(tmp_path, scale):
    """A pose's or transform's quaternion scaled keeps its rotation's axis and angle, but
    is no orientation a run publishes: its length's change counts as an angle, so the
    default tolerance does not pass it."""
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", duration_ns=SEC)
    bag = read_bag(tmp_path / "in")
    replay_to_bag(scene, bag, tmp_path / "a", tf=True)
    produced, _ = replay_outputs(scene, bag, tf=True)
    for output in produced:
        if output.log_ns == 500_000_000 and output.topic in ("/right/pose", "/tf"):
            for q in ([output.msg.pose.orientation] if output.topic == "/right/pose" else
                      [t.transform.rotation for t in output.msg.transforms]):
                q.x, q.y, q.z, q.w = (scale * c for c in (q.x, q.y, q.z, q.w))
    report, ok = compare_contents(read_bag(tmp_path / "a"),
                                  outputs_as_bag(scene, produced, tf=True))
    assert not ok
    worst = {t.topic: t for t in report.topics}
    for topic in ("/right/pose", "/tf"):
        assert worst[topic].angle.value == pytest.approx(abs(1.0 - scale), rel=1e-9)
        assert worst[topic].angle.stamp_ns == 500_000_000


# ----------------------------------------------------------------------------- bad bags

@pytest.fixture
def sample_bags(tmp_path):
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", duration_ns=SEC)
    replay_to_bag(scene, read_bag(tmp_path / "in"), tmp_path / "out", with_inputs=True)
    script_to_bag(scene, tmp_path / "in_sqlite", storage="sqlite3", duration_ns=SEC)
    return tmp_path


def _truncate(path: Path, keep: float) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


@pytest.mark.parametrize("keep", [0.5, 0.9])
def test_truncated_mcap_gives_clear_error(sample_bags, capsys, keep):
    _truncate(sample_bags / "out" / "out.mcap", keep)
    code, _, err = run_cli(capsys, "replay", "sample", str(sample_bags / "out"), "--check")
    assert_clean_error(code, err, "cannot read the bag", "truncated or corrupt")
    code, _, err = run_cli(capsys, "compare", str(sample_bags / "out"), str(sample_bags / "in"))
    assert_clean_error(code, err, str(sample_bags / "out"))


def test_corrupt_sqlite_and_metadata_give_clear_errors(sample_bags, capsys):
    database = sample_bags / "in_sqlite" / "in_sqlite.db3"
    database.write_bytes(b"not a database at all" * 100)
    code, _, err = run_cli(capsys, "replay", "sample", str(sample_bags / "in_sqlite"),
                           "-o", str(sample_bags / "x"))
    assert_clean_error(code, err, "cannot read the bag")
    assert not (sample_bags / "x").exists()
    (sample_bags / "in" / "metadata.yaml").write_text("rosbag2_bagfile_information: [1, 2\n")
    code, _, err = run_cli(capsys, "replay", "sample", str(sample_bags / "in"),
                           "-o", str(sample_bags / "x"))
    assert_clean_error(code, err, "cannot read the bag")
    code, _, err = run_cli(capsys, "replay", "sample", str(sample_bags / "nothing"), "--check")
    assert_clean_error(code, err, "no such bag")
    (sample_bags / "empty_dir").mkdir()
    code, _, err = run_cli(capsys, "compare", str(sample_bags / "empty_dir"),
                           str(sample_bags / "out"))
    assert_clean_error(code, err, "empty_dir")


def test_missing_topics_give_clear_errors(sample_bags, tmp_path, capsys):
    with BagWriter(tmp_path / "chatter", "mcap") as writer:
        writer.write("/chatter", "std_msgs/msg/String", SEC,
                     bags.default_message("std_msgs/msg/String", data="hello"))
    code, _, err = run_cli(capsys, "replay", "sample", str(tmp_path / "chatter"),
                           "-o", str(tmp_path / "x"))
    assert_clean_error(code, err, "none of the scene's input topics", "/applied_wrench",
                       "/chatter")
    # --check needs recorded outputs; an input-only bag has none.
    code, _, err = run_cli(capsys, "replay", "sample", str(sample_bags / "in"), "--check")
    assert_clean_error(code, err, "--check needs recorded outputs", "/left/pose")
    # compare: bags without a topic in common compare nothing, an error (exit 2); a topic
    # missing from the actual bag beside one in both is a mismatch (exit 1).
    code, _, err = run_cli(capsys, "compare", str(sample_bags / "out"), str(tmp_path / "chatter"))
    assert_clean_error(code, err, "have no topic in common", "/chatter", "/left/pose")
    out_bag = read_bag(sample_bags / "out")
    with BagWriter(tmp_path / "some", "mcap") as writer:
        writer.write("/chatter", "std_msgs/msg/String", SEC,
                     bags.default_message("std_msgs/msg/String", data="hello"))
        writer.add_topic("/right/pose", out_bag.topics["/right/pose"])
        for message in out_bag.on("/right/pose"):
            writer.write_raw("/right/pose", message.log_ns, message.raw)
    code, out, _ = run_cli(capsys, "compare", str(sample_bags / "out"), str(tmp_path / "some"))
    assert code == 1 and "MISSING TOPIC /left/pose" in out and "EXTRA TOPIC   /chatter" in out


def test_unknown_types_give_clear_errors(tmp_path, capsys):
    from rosbags.rosbag2 import Writer

    # A bag whose /applied_wrench carries a type this package does not know.
    with Writer(tmp_path / "foreign", version=9) as writer:
        conn = writer.add_connection("/applied_wrench", "other_pkg/msg/Push",
                                     msgdef="float64 strength\n", rihs01="RIHS01_" + "0" * 64)
        writer.write(conn, SEC, bytes([0, 1, 0, 0]) + bytes(8))
    code, _, err = run_cli(capsys, "replay", "sample", str(tmp_path / "foreign"),
                           "-o", str(tmp_path / "x"))
    assert_clean_error(code, err, "other_pkg/msg/Push", "hecker_dynamics/msg/AppliedWrench")
    # The right name with another definition (a stale AppliedWrench) is caught by its hash.
    with Writer(tmp_path / "stale", version=9) as writer:
        conn = writer.add_connection("/applied_wrench", APPLIED_WRENCH,
                                     msgdef="string body\nfloat64 force\n",
                                     rihs01="RIHS01_" + "1" * 64)
        writer.write(conn, SEC, bytes([0, 1, 0, 0]) + bytes(16))
    code, _, err = run_cli(capsys, "replay", "sample", str(tmp_path / "stale"),
                           "-o", str(tmp_path / "x"))
    assert_clean_error(code, err, "another definition")
    # compare treats an unknown type as bytes: same bag matches itself.
    code, out, _ = run_cli(capsys, "compare", str(tmp_path / "foreign"), str(tmp_path / "foreign"))
    assert code == 0


def test_wrong_body_names_give_clear_errors(sample_bags, tmp_path, capsys):
    with BagWriter(tmp_path / "other_scene", "mcap") as writer:
        for k, body in enumerate(["left", "lefty", "robot"]):
            writer.write("/applied_wrench", APPLIED_WRENCH, SEC // 10 * (k + 1),
                         bags.applied_wrench_message(0, "", body, "x", (0, 0), (1, 0), 0, 0))
    code, _, err = run_cli(capsys, "replay", "sample", str(tmp_path / "other_scene"),
                           "-o", str(tmp_path / "x"))
    assert_clean_error(code, err, "unknown body 'lefty'", "unknown body 'robot'", "wrong scene")
    assert not (tmp_path / "x").exists()
    # As the node does, --skip-rejected drops them and replays the rest.
    code, out, err = run_cli(capsys, "replay", "sample", str(tmp_path / "other_scene"),
                             "-o", str(tmp_path / "x"), "--skip-rejected", "--duration", "0.5")
    assert code == 0 and "1 accepted, 2 rejected" in out and "unknown body" in err
    # Recorded outputs of bodies the scene lacks: the bag belongs to another scene.
    scene_file = tmp_path / "puck.yaml"
    scene_file.write_text(PUCK_SCENE)
    code, _, err = run_cli(capsys, "replay", str(scene_file), str(sample_bags / "out"),
                           "--check")
    assert_clean_error(code, err, "bodies the scene", "left")


def test_reader_errors_are_bag_errors(tmp_path):
    (tmp_path / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 10)
    with pytest.raises(BagError, match="cannot read the bag"):
        read_bag(tmp_path / "junk.mcap")
    with pytest.raises(BagError, match="no such bag"):
        read_bag(tmp_path / "absent")
    cut = tmp_path / "cut"  # what a recorder killed mid-recording leaves
    cut.mkdir()
    (cut / "cut_0.mcap").write_bytes(b"\x89MCAP0\r\n")
    with pytest.raises(BagError, match=r"cut: no metadata\.yaml \(a recording cut off before "
                                       r"it was closed\? 'ros2 bag reindex .*cut' writes it\)$"):
        read_bag(cut)
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    with pytest.raises(BagError, match=r"loop: is a broken symlink or a symlink loop$"):
        read_bag(tmp_path / "loop")
    db = tmp_path / "bare.db3"
    sqlite3.connect(db).close()
    with pytest.raises(BagError):
        read_bag(db)
    with pytest.raises(ReplayError):
        replay_outputs(load_scene("sample"), bags.BagContents(tmp_path, "memory", {}, []))


def test_writer_leaves_nothing_behind_on_failure(tmp_path):
    with pytest.raises(RuntimeError), BagWriter(tmp_path / "bag", "mcap") as writer:
        writer.write("/a", TWIST, 1, bags.default_message(TWIST))
        raise RuntimeError("stop")
    assert list(tmp_path.iterdir()) == []


def test_applied_wrench_type_comes_from_the_msg_file():
    path = bags.message_definition_path()
    assert path.name == "AppliedWrench.msg"
    fields = [name for name, _ in bags.typestore().fielddefs[APPLIED_WRENCH][1]]
    declared = [line.split()[1] for line in path.read_text().splitlines()
                if line.strip() and not line.lstrip().startswith("#")]
    assert fields == declared


def test_golden_readme_gives_the_regenerate_command():
    assert REGENERATE in (GOLDEN / "README.md").read_text()

