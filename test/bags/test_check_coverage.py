"""``replay --check`` and ``regress`` compare everything a recording holds, and say so.

Each case is a live session of the node's loop (``live_session.py``) recorded as
``ros2 bag record -a`` would, then changed the way a hostile user or a lossy recorder
changes it: records removed (world events, one input event), topics removed, the second
half of every output cut, a stamp moved by a bit flip, a spawned body's outputs removed,
every motor command removed. Each must fail with exit 1 and one line saying what is
missing, extra or out of place; the honest recordings beside them (a recorder started
late, stopped early, that lost one output) pass and report what they did not check.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from live_session import S, record, run_live

from hecker_dynamics.bags import io as bags
from hecker_dynamics.bags.io import BagWriter, read_bag
from hecker_dynamics.cli import main
from hecker_dynamics.scene import load_scene

BALL = "{shape: circle, radius: 0.15, mass: 1.0, position: [0.5, 4.0], velocity: [0.3, 0.0]}"


@pytest.fixture(scope="module")
def sample_session():
    """Four seconds of the sample scene: 25 inputs, three rounds of world services."""
    return run_live(load_scene("sample"), 14, world=3)


@pytest.fixture(scope="module")
def ball_session():
    """The sample scene with a ball spawned after 1 s."""
    return run_live(load_scene("sample"), 40, bodies=[(S, ("spawn", "ball", BALL, ()))])


@pytest.fixture(scope="module")
def gears_session():
    return run_live(load_scene("gears"), 27, motors=8)


def _check(capsys, path: Path, scene: str = "sample", *options: str) -> tuple[int, str, str]:
    code = main(["replay", scene, str(path), "--check", "--atol", "0", *options])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _verdict(out: str) -> str:
    """The check's one-line verdict: the last line of its output."""
    last = out.strip().splitlines()[-1]
    assert last.startswith("check against the recording "), out
    return last


def _mismatch(capsys, path: Path, *needles: str, scene: str = "sample") -> str:
    code, out, err = _check(capsys, path, scene)
    verdict = _verdict(out)
    assert code == 1 and ": mismatch: " in verdict, out + err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in verdict, verdict
    return verdict


def _is_output(topic: str) -> bool:
    return topic == "/tf" or topic.startswith(("/left/", "/right/", "/ball/"))


# ----------------------------------------------------------------------------- honest

def test_an_honest_recording_reports_every_output_checked(tmp_path, capsys, sample_session):
    path = record(sample_session, tmp_path / "live", 14)
    bag = read_bag(path)
    outputs = sum(_is_output(m.topic) for m in bag.messages)
    inputs = len(bag.on("/applied_wrench"))
    events = len(bag.on("/dynamics_node/input_events"))
    changes = len(bag.on("/dynamics_node/world_events"))
    code, out, _ = _check(capsys, path)
    verdict = _verdict(out)
    assert code == 0, out
    assert f"match: checked {outputs} of {outputs} recorded outputs on 5 topics" in verdict
    assert f"{events} input events, {changes} world events" in verdict
    assert f"{inputs} recorded inputs" in verdict
    # The per-topic lines name each compared topic with its count.
    for topic in ("/left/pose", "/left/twist", "/right/pose", "/right/twist", "/tf"):
        line = next(line for line in out.splitlines() if line.split()[:1] == [topic])
        assert f"{len(bag.on(topic))} checked" in line, line


def test_a_recorder_started_late_and_stopped_early_passes(tmp_path, capsys, sample_session):
    path = record(sample_session, tmp_path / "live", 14, late_ns=1_300_000_000,
                  stop_ns=3_200_000_000)
    code, out, err = _check(capsys, path)
    assert code == 0, out + err
    assert "match: checked" in _verdict(out)


def test_one_output_the_recorder_lost_is_reported(tmp_path, capsys, sample_session):
    lost = [p for p in sample_session.published if p.topic == "/right/pose"][90]
    path = record(sample_session, tmp_path / "live", 14, drop=lambda _, item: item is lost)
    code, out, _ = _check(capsys, path)
    verdict = _verdict(out)
    assert code == 0 and "1 lost by the recorder (/right/pose at " in verdict, out


def test_a_stretch_of_lost_outputs_fails(tmp_path, capsys, sample_session):
    poses = [p for p in sample_session.published if p.topic == "/right/pose"]
    lost = {id(p) for p in poses[60:90]}
    path = record(sample_session, tmp_path / "live", 14, drop=lambda _, item: id(item) in lost)
    _mismatch(capsys, path, "/right/pose", "30 outputs", "missing")


# ----------------------------------------------------------------------------- records

def test_world_event_records_removed_fail(tmp_path, capsys, sample_session):
    path = record(sample_session, tmp_path / "live", 14,
                  drop=lambda _, item: item.topic.endswith("/world_events"))
    _mismatch(capsys, path, "world event", "missing")


def test_one_world_event_record_removed_fails(tmp_path, capsys, sample_session):
    changes = [p for p in sample_session.published if p.topic.endswith("/world_events")]
    gone = changes[len(changes) // 2]
    path = record(sample_session, tmp_path / "live", 14, drop=lambda _, item: item is gone)
    _mismatch(capsys, path, f"event record {gone.msg.sequence} ", "missing")


def test_one_input_event_record_removed_fails(tmp_path, capsys, sample_session):
    events = [p for p in sample_session.published if p.topic.endswith("/input_events")]
    gone = events[len(events) // 2]
    path = record(sample_session, tmp_path / "live", 14, drop=lambda _, item: item is gone)
    _mismatch(capsys, path, f"event record {gone.msg.sequence} ", "missing")


def test_partial_accepts_missing_records_and_names_what_it_did_not_check(tmp_path, capsys,
                                                                        sample_session):
    path = record(sample_session, tmp_path / "live", 14,
                  drop=lambda _, item: item.topic.endswith("/world_events"))
    code, out, err = _check(capsys, path, "sample", "--partial")
    verdict = _verdict(out)
    assert code == 0 and "match: checked" in verdict, out + err
    assert "not checked:" in verdict and "before the keyframe at" in verdict


# ----------------------------------------------------------------------------- topics

def test_one_bodys_topics_removed_fail(tmp_path, capsys, sample_session):
    path = record(sample_session, tmp_path / "live", 14,
                  drop=lambda _, item: item.topic in ("/left/pose", "/left/twist"))
    _mismatch(capsys, path, "/left/pose", "/left/twist", "not recorded")


def test_only_tf_left_fails(tmp_path, capsys, sample_session):
    path = record(sample_session, tmp_path / "live", 14,
                  drop=lambda _, item: _is_output(item.topic) and item.topic != "/tf")
    _mismatch(capsys, path, "/left/pose", "not recorded")


def test_the_second_half_of_every_output_cut_fails(tmp_path, capsys, sample_session):
    middle = sample_session.start_ns + 2 * S
    path = record(sample_session, tmp_path / "live", 14,
                  drop=lambda _, item: _is_output(item.topic) and item.publish_ns > middle)
    _mismatch(capsys, path, "missing")


def test_a_spawned_bodys_outputs_removed_fail(tmp_path, capsys, ball_session):
    assert any(p.topic == "/ball/pose" for p in ball_session.published)
    path = record(ball_session, tmp_path / "live", 40,
                  drop=lambda _, item: item.topic.startswith("/ball/"))
    _mismatch(capsys, path, "/ball/pose", "not recorded")


def test_every_motor_command_removed_fails(tmp_path, capsys, gears_session):
    path = record(gears_session, tmp_path / "live", 27,
                  drop=lambda _, item: item.topic.endswith("/motor_speed"))
    _mismatch(capsys, path, "/small_axle/motor_speed", scene="gears")


def test_topics_named_on_purpose_are_checked_and_the_rest_named(tmp_path, capsys,
                                                               sample_session):
    """``ros2 bag record /right/pose /applied_wrench <records>``: fails by default, passes
    with ``--topic /right/pose``, whose report names the topics it did not check."""
    kept = {"/right/pose"}
    path = record(sample_session, tmp_path / "live", 14,
                  drop=lambda _, item: _is_output(item.topic) and item.topic not in kept)
    _mismatch(capsys, path, "/left/pose")
    code, out, err = _check(capsys, path, "sample", "--topic", "/right/pose")
    verdict = _verdict(out)
    assert code == 0, out + err
    assert "on 1 topics" in verdict and "/left/pose (not named by --topic)" in verdict
    # A topic named but not recorded fails.
    code, out, _ = _check(capsys, path, "sample", "--topic", "/left/pose")
    assert code == 1 and "/left/pose" in _verdict(out)


# ----------------------------------------------------------------------------- stamps

def _rewrite(source: Path, target: Path, change) -> Path:
    """Copy a bag message by message; ``change(message)`` returns the raw bytes to write
    (None: leave it out)."""
    bag = read_bag(source)
    with BagWriter(target, "mcap") as writer:
        for topic, msgtype in bag.topics.items():
            writer.add_topic(topic, msgtype)
        for message in bag.messages:
            raw = change(message)
            if raw is not None:
                writer.write_raw(message.topic, message.log_ns, raw)
    return target


def _with_foreign_topics(source: Path, target: Path) -> Path:
    """A copy with what a recorder may hold besides the node: another node's topic and a
    topic named like an output the scene does not publish, of another type."""
    bag = read_bag(source)
    string = "std_msgs/msg/String"
    with BagWriter(target, "mcap") as writer:
        for topic, msgtype in bag.topics.items():
            writer.add_topic(topic, msgtype)
        for message in bag.messages:
            writer.write_raw(message.topic, message.log_ns, message.raw)
        for topic in ("/chatter", "/left/odom"):
            writer.write(topic, string, bag.messages[0].log_ns,
                         bags.typestore().types[string](data="hello"))
    return target


@pytest.mark.parametrize("live", [True, False])
def test_topics_not_of_the_node_are_named_as_not_compared(tmp_path, capsys, sample_session,
                                                           live):
    """A match must say what the recording holds that it did not compare."""
    if live:
        source = record(sample_session, tmp_path / "live", 14)
    else:
        assert main(["script", "sample", "-o", str(tmp_path / "in"), "--duration", "1"]) == 0
        assert main(["replay", "sample", str(tmp_path / "in"), "-o", str(tmp_path / "out"),
                     "--with-inputs"]) == 0
        source = tmp_path / "out"
    code, out, _ = _check(capsys, _with_foreign_topics(source, tmp_path / "more"))
    verdict = _verdict(out)
    assert code == 0, out
    for topic in ("/chatter", "/left/odom"):
        assert f"{topic} (not a topic of the node for this scene)" in verdict, verdict
        line = next(line for line in out.splitlines() if line.split()[:1] == [topic])
        assert line.endswith("not compared: not a topic of the node for this scene"), line


def test_a_pose_stamp_moved_by_a_bit_flip_fails(tmp_path, capsys, sample_session):
    path = record(sample_session, tmp_path / "live", 14)
    poses = read_bag(path).on("/left/pose")
    target = poses[len(poses) // 2]

    def flip(message):
        if message is not target and message.index != target.index:
            return message.raw
        msg = message.decode()
        msg.header.stamp.sec ^= 1 << 24  # 1.70e9 s -> 1.68e9 s: a stamp in 2023
        return bags.typestore().serialize_cdr(msg, message.msgtype)

    flipped = _rewrite(path, tmp_path / "flipped", flip)
    _mismatch(capsys, flipped, "/left/pose", "not one the node published")


# ----------------------------------------------------------------------------- regress

def _named_bag(tmp_path: Path, session, name: str, scene: str) -> Path:
    path = record(session, tmp_path / name, 14)
    meta = path / "metadata.yaml"
    info = yaml.safe_load(meta.read_text())
    info["rosbag2_bagfile_information"]["custom_data"] = {"hecker_dynamics.scene": scene}
    meta.write_text(yaml.safe_dump(info))
    return path


def test_regress_resolves_scene_names_only_where_it_may(tmp_path, capsys, sample_session):
    """A bag's metadata names its scene: a path out of the bags' directory, or a name too
    long for a file, is a one-line error for that bag; the other bags are still checked."""
    suite = tmp_path / "suite" / "bags"
    suite.mkdir(parents=True)
    planted = tmp_path / "x.yaml"  # what '../../x' would reach from the bag
    planted.write_text(Path(load_scene("sample").source).read_text())
    _named_bag(suite, sample_session, "a_absolute", str(planted.with_suffix("")))
    _named_bag(suite, sample_session, "b_relative", "../../x")
    _named_bag(suite, sample_session, "c_long", "s" * 300)
    _named_bag(suite, sample_session, "d_shipped", "sample")
    code = main(["regress", str(suite), "--workers", "1", "--no-progress", "--atol", "0"])
    lines = capsys.readouterr().out.splitlines()
    assert code == 2
    status = {line.split()[1].rsplit("/", 1)[-1]: line for line in lines[:-1]}
    for name in ("a_absolute", "b_relative", "c_long"):
        assert status[name].startswith("ERROR") and "not a scene name" in status[name], lines
    assert status["d_shipped"].startswith("OK") and "checked" in status["d_shipped"]
    assert lines[-1] == "4 bag(s): 1 ok, 0 mismatch, 3 error"


def test_regress_checks_a_live_recording_as_replay_does(tmp_path, capsys, sample_session):
    changes = [p for p in sample_session.published if p.topic.endswith("/world_events")]
    gone = changes[1]
    good = record(sample_session, tmp_path / "good", 14)
    bad = record(sample_session, tmp_path / "bad", 14, drop=lambda _, item: item is gone)
    code = main(["regress", str(good), str(bad), "--scene", "sample", "--workers", "1",
                 "--no-progress", "--atol", "0"])
    lines = capsys.readouterr().out.splitlines()
    assert code == 1
    assert lines[0].startswith("OK") and "checked" in lines[0]
    assert lines[1].startswith("MISMATCH") and "missing" in lines[1]


# ----------------------------------------------------------------------------- diverging

def test_a_replay_that_diverges_writes_no_bag_and_claims_no_span(tmp_path, capsys):
    """Explicit Euler on a stiff spring gains energy every step, by a factor 1 + (w h)^2:
    e^80 in 10 s here, which no bound lets pass."""
    scene = tmp_path / "stiff.yaml"
    scene.write_text(yaml.safe_dump({"dynamics_node": {"ros__parameters": {
        "step": 0.01, "integrator": "explicit_euler", "publish_rate": 50.0, "duration": 10.0,
        "bodies": {"b": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                         "position": [1.0, 0.0]}},
        "forces": {"spring": {"type": "spring", "body_a": "b", "anchor": [0.0, 0.0],
                              "stiffness": 800.0}}}}}))
    assert math.log(1 + 800.0 * 0.01 ** 2) * 1000 > 60  # the energy's growth over 10 s
    assert main(["script", str(scene), "-o", str(tmp_path / "in")]) == 0
    capsys.readouterr()
    code = main(["replay", str(scene), str(tmp_path / "in"), "-o", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "diverged" in err
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))
    assert "to 10.000000000 s" not in out and "diverged after" in out


# ----------------------------------------------------------------------------- more honest

@pytest.mark.parametrize("name,seed,options,recorder", [
    ("sample", 30, {"reset_at": 1_500_000_000}, {"stop_ns": 3_200_000_000}),
    ("sample", 31, {"lockstep": True, "world": 2}, {"late_ns": 1_100_000_000,
                                                    "stop_ns": 3_000_000_000}),
    ("gears", 32, {"motors": 8, "world": 1}, {"discovery_ns": 300_000_000}),
    ("sample", 33, {"bodies": [(700_000_000, ("spawn", "ball", BALL, ())),
                               (2_500_000_000, ("delete", "ball"))]},
     {"late_ns": 500_000_000, "stop_ns": 3_500_000_000, "discovery_ns": 200_000_000}),
])
def test_honest_recordings_of_every_kind_pass_with_every_output_checked(
        tmp_path, capsys, name, seed, options, recorder):
    """Recorders that start late, stop early and discover topics slowly (each topic within
    0.3 s): every recorded output is checked, and what they did not record is named."""
    path = record(run_live(load_scene(name), seed, **options), tmp_path / "live", seed,
                  **recorder)
    bag = read_bag(path)
    outputs = sum(m.topic == "/tf" or m.topic.endswith(("/pose", "/twist"))
                  or m.topic == "/joint_states" for m in bag.messages)
    code, out, err = _check(capsys, path, name)
    verdict = _verdict(out)
    assert code == 0, out + err
    assert f"match: checked {outputs} of {outputs} recorded outputs" in verdict


# ----------------------------------------------------------------------------- other bags

def test_a_script_bag_must_hold_every_output_topic(tmp_path, capsys):
    """A bag made by ``replay -o --with-inputs`` (no session records): a topic removed
    fails, ``--topic`` checks the rest, and the verdict says what was checked."""
    assert main(["script", "sample", "-o", str(tmp_path / "in"), "--duration", "1"]) == 0
    assert main(["replay", "sample", str(tmp_path / "in"), "-o", str(tmp_path / "out"),
                 "--with-inputs"]) == 0
    capsys.readouterr()
    code, out, _ = _check(capsys, tmp_path / "out")
    assert code == 0 and "match: checked 200 of 200 recorded outputs on 4 topics" in \
        _verdict(out)
    cut = _rewrite(tmp_path / "out", tmp_path / "cut",
                   lambda m: None if m.topic == "/right/twist" else m.raw)
    code, out, _ = _check(capsys, cut)
    assert code == 1 and "/right/twist not recorded" in _verdict(out)
    code, out, _ = _check(capsys, cut, "sample", *[a for t in ("/left/pose", "/left/twist",
                                                                "/right/pose")
                                                   for a in ("--topic", t)])
    verdict = _verdict(out)
    assert code == 0 and "checked 150 of 150 recorded outputs on 3 topics" in verdict


def test_regress_finds_scene_files_in_the_directory_named(tmp_path, capsys, sample_session):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "my_sample.yaml").write_text(Path(load_scene("sample").source).read_text())
    bag = _named_bag(tmp_path, sample_session, "live", "my_sample")
    assert main(["regress", str(bag), "--workers", "1", "--no-progress"]) == 2
    assert "neither" in capsys.readouterr().out
    assert main(["regress", str(bag), "--scene-dir", str(scenes), "--workers", "1",
                 "--no-progress"]) == 0
    assert "OK" in capsys.readouterr().out
    # A --scene-dir that is a file, or missing, is said to be which.
    for given, words in ((scenes / "my_sample.yaml", "not a folder"),
                         (tmp_path / "none", "no such folder")):
        assert main(["regress", str(bag), "--scene-dir", str(given), "--no-progress"]) == 2
        assert capsys.readouterr().err == f"hecker-dynamics: error: --scene-dir {given}: {words}\n"


def test_a_sessions_first_keyframe_is_checked_too(tmp_path, capsys):
    """The keyframe a session starts with is compared with a replay from the session's
    start (it was the replay's trusted starting point), after a reset too."""
    session = run_live(load_scene("sample"), 2, reset_at=3_100_000_000)
    firsts = [p for p in session.published if p.topic.endswith("/keyframe") and p.msg.steps == 0]
    assert len(firsts) == 2
    firsts[1].msg.q[0] = math.nextafter(float(firsts[1].msg.q[0]), math.inf)
    _mismatch(capsys, record(session, tmp_path / "live", 2), "session 1: the state at",
              "differs from the recorded keyframe")


def test_coverage_options_are_refused_where_they_mean_nothing(tmp_path, capsys,
                                                              sample_session):
    path = record(sample_session, tmp_path / "live", 14)
    for argv, needle in ((["-o", str(tmp_path / "out"), "--partial"], "give --check"),
                         (["--check", "--topic", "/applied_wrench"], "not an output"),
                         (["--check", "--topic", "/tf_static"], "not an output")):
        code = main(["replay", "sample", str(path), *argv])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and needle in err, err
    assert not (tmp_path / "out").exists()
