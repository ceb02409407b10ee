"""TF without ROS: /tf per body and /tf_static per named point, as the node publishes them
and as the offline replay writes them (``replay --tf``)."""
from __future__ import annotations

import math

import pytest
import yaml
from scene_builders import box_body, make_scene

from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.fields import header, odometry_fields, pose_fields, twist_fields
from hecker_dynamics.ros.markers import marker_fields
from hecker_dynamics.ros.outputs import OutputKind, SnapshotOutputs, output_topics
from hecker_dynamics.ros.tf import IDENTITY, body_transforms, point_transforms
from hecker_dynamics.scene.load import load_scene

S = 1_000_000_000


def _rotate(q, v):
    """``v`` rotated by the unit quaternion ``q`` (x, y, z, w): v + 2w (u x v) + 2 u x (u x v)."""
    x, y, z, w = q
    u = (x, y, z)

    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
    t = tuple(2.0 * c for c in cross(u, v))
    ut = cross(u, t)
    return tuple(v[i] + w * t[i] + ut[i] for i in range(3))


def _two_body_snapshot():
    scene = load_scene("sample")
    sim = Simulation(scene, start_ns=3 * S)
    return scene, sim.advance_to(3 * S + 7 * scene.publish_period_ns)[-1]


def test_body_transforms_are_the_published_poses():
    scene, snapshot = _two_body_snapshot()
    transforms = body_transforms(header(scene.frame_id, snapshot.time_ns), snapshot.bodies)
    assert [t.child_frame_id for t in transforms] == [b.name for b in scene.bodies]
    for transform, state in zip(transforms, snapshot.bodies):
        pose = pose_fields(state, scene.frame_id, snapshot.time_ns)
        assert transform.header == pose.header == header("world", snapshot.time_ns)
        assert transform.translation == pose.pose.position
        assert transform.rotation == pose.pose.orientation
        assert math.isclose(sum(c * c for c in transform.rotation), 1.0, rel_tol=1e-15)


def test_point_transforms_put_each_named_point_where_the_body_frame_carries_it():
    scene, snapshot = _two_body_snapshot()
    static = point_transforms(scene, 3 * S)
    expected = [(b.name, f"{b.name}/{p}") for b in scene.bodies for p in b.points]
    assert expected and [(t.header.frame_id, t.child_frame_id) for t in static] == expected
    assert all(scene.has_frame(t.child_frame_id) for t in static)
    dynamic = {t.child_frame_id: t for t in body_transforms(
        header(scene.frame_id, snapshot.time_ns), snapshot.bodies)}
    for transform in static:
        assert transform.rotation == IDENTITY and transform.header.sec == 3
        body = next(b for b in scene.bodies if b.name == transform.header.frame_id)
        point = body.points[transform.child_frame_id.split("/", 1)[1]]
        assert transform.translation == (point[0], point[1], 0.0)
        # world <- body <- point, composed as tf2 does, equals r + R(angle) p.
        state = next(s for s in snapshot.bodies if s.name == body.name)
        parent = dynamic[body.name]
        rotated = _rotate(parent.rotation, transform.translation)
        world = [parent.translation[i] + rotated[i] for i in range(3)]
        c, s = math.cos(state.angle), math.sin(state.angle)
        reference = (state.position[0] + c * point[0] - s * point[1],
                     state.position[1] + s * point[0] + c * point[1], 0.0)
        assert world == pytest.approx(reference, abs=1e-14)


def test_tf_is_on_by_default_and_the_scene_turns_it_off():
    on = make_scene({"bodies": {"puck": box_body(points={"tip": [0.5, 0.0]})}})
    off = make_scene({"bodies": {"puck": box_body(points={"tip": [0.5, 0.0]})},
                      "publish": {"tf": False}})
    assert on.publish_tf and not off.publish_tf
    assert output_topics(on)["/tf"] is output_topics(on)["/tf_static"] is OutputKind.TF
    assert "/tf" not in output_topics(off) and "/tf_static" not in output_topics(off)
    snapshot = Simulation(on).advance_to(on.publish_period_ns)[-1]
    assert SnapshotOutputs(on)(snapshot)[-1].topic == "/tf"
    assert [o.topic for o in SnapshotOutputs(off)(snapshot)] == ["puck/pose", "puck/twist"]
    assert [o.fields for o in SnapshotOutputs(on).static(0)] == [point_transforms(on, 0)]
    assert SnapshotOutputs(off).static(0) == []
    without_points = make_scene({"bodies": {"puck": box_body()}})
    assert SnapshotOutputs(without_points).static(0) == []  # nothing to latch


def test_snapshot_outputs_share_one_header_and_match_the_field_functions():
    scene = load_scene("sample")
    everything = make_scene({"bodies": {"puck": box_body(velocity=[1.0, 2.0], angle=0.5,
                                                        angular_velocity=1.0),
                                        "wheel": {"shape": "circle", "radius": 0.3,
                                                  "mass": 1.0, "position": [2.0, 0.0],
                                                  "angular_velocity": 3.0}},
                             "twist_frame": "world",
                             "publish": {"odometry": True, "markers": True}})
    for sc in (scene, everything):
        snapshot = Simulation(sc).advance_to(2 * sc.publish_period_ns)[-1]
        outputs = SnapshotOutputs(sc)(snapshot)
        by_kind = {}
        for output in outputs:
            by_kind.setdefault(output.kind, []).append(output.fields)
        heads = {id(f.header) for f in by_kind[OutputKind.POSE]}
        heads |= {id(t.header) for t in by_kind[OutputKind.TF][0]}
        assert len(heads) == 1
        for state, pose, twist in zip(snapshot.bodies, by_kind[OutputKind.POSE],
                                      by_kind[OutputKind.TWIST]):
            assert pose == pose_fields(state, sc.frame_id, snapshot.time_ns)
            assert twist == twist_fields(state, sc.twist_frame)
        for state, odom in zip(snapshot.bodies, by_kind.get(OutputKind.ODOMETRY, [])):
            assert odom == odometry_fields(state, sc.frame_id, snapshot.time_ns)
        if sc.publish_markers:
            [markers] = by_kind[OutputKind.MARKERS]
            assert list(markers) == [m for index, (body, state) in enumerate(
                zip(sc.bodies, snapshot.bodies)) for m in marker_fields(
                    body, state, index, sc.frame_id, snapshot.time_ns)]


# ----------------------------------------------------------------------------- replay

rosbags = pytest.importorskip("rosbags", reason="rosbags is not installed")

from hecker_dynamics.bags.compare import compare_contents  # noqa: E402
from hecker_dynamics.bags.io import TF_MESSAGE, read_bag, stamp_ns_of  # noqa: E402
from hecker_dynamics.bags.replay import outputs_as_bag, replay_outputs, replay_to_bag, script_to_bag  # noqa: E402


def test_replay_writes_tf_only_when_asked(tmp_path):
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", duration_ns=S)
    bag = read_bag(tmp_path / "in")
    plain, _ = replay_outputs(scene, bag)
    with_tf, _ = replay_outputs(scene, bag, tf=True)
    assert not any(o.topic.startswith("/tf") for o in plain)
    # Everything else is the same, message for message.
    assert [(o.topic, o.log_ns) for o in with_tf if not o.topic.startswith("/tf")] == \
        [(o.topic, o.log_ns) for o in plain]
    static = [o for o in with_tf if o.topic == "/tf_static"]
    dynamic = [o for o in with_tf if o.topic == "/tf"]
    poses = [o for o in with_tf if o.topic == "/left/pose"]
    assert len(static) == 1 and static[0].log_ns == 0 and with_tf[0] is static[0]
    assert len(dynamic) == len(poses) == S // scene.publish_period_ns
    for tf, pose in zip(dynamic, poses):
        assert stamp_ns_of(tf.msg) == stamp_ns_of(pose.msg) == tf.log_ns
        left = tf.msg.transforms[0]
        assert (left.header.frame_id, left.child_frame_id) == ("world", "left")
        assert (left.transform.translation.x, left.transform.rotation.z) == \
            (pose.msg.pose.position.x, pose.msg.pose.orientation.z)
    # The bag declares both topics with tf2_ros's QoS; a replay checks against itself.
    replay_to_bag(scene, bag, tmp_path / "out", tf=True)
    meta = yaml.safe_load((tmp_path / "out" / "metadata.yaml").read_text())
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"][0]
           for t in meta["rosbag2_bagfile_information"]["topics_with_message_count"]}
    assert (qos["/tf_static"]["durability"], qos["/tf_static"]["depth"]) == ("transient_local", 1)
    assert (qos["/tf"]["durability"], qos["/tf"]["depth"]) == ("volatile", 100)
    assert (qos["/left/pose"]["durability"], qos["/left/pose"]["depth"]) == ("volatile", 10)
    written = read_bag(tmp_path / "out")
    assert written.topics["/tf"] == written.topics["/tf_static"] == TF_MESSAGE
    report, ok = compare_contents(written, outputs_as_bag(scene, with_tf, tf=True))
    assert ok, report.text()
    assert {t.topic: t.matched for t in report.topics}["/tf"] == len(dynamic)


def test_compare_sees_a_moved_transform(tmp_path):
    scene = load_scene("sample")
    script_to_bag(scene, tmp_path / "in", duration_ns=S // 2)
    outputs, _ = replay_outputs(scene, read_bag(tmp_path / "in"), tf=True)
    moved = []
    for output in outputs:
        if output.topic == "/tf" and output.log_ns == 10 * scene.publish_period_ns:
            output.msg.transforms[1].transform.translation.y += 1e-3
        moved.append(output)
    expected, _ = replay_outputs(scene, read_bag(tmp_path / "in"), tf=True)
    report, ok = compare_contents(outputs_as_bag(scene, expected, tf=True),
                                  outputs_as_bag(scene, moved, tf=True))
    assert not ok
    tf_report = next(t for t in report.topics if t.topic == "/tf")
    assert tf_report.position.value == pytest.approx(1e-3, rel=1e-9)
