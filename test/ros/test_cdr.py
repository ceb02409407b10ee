"""The node's output bytes (:mod:`hecker_dynamics.ros.cdr`) against rosbags' serializer.

The node publishes these bytes as they are, so each must be the CDR of the message rosbags
(and rosbag2, and rclpy: test_node.py checks that on Jazzy) makes of the same fields, byte
for byte: every output kind of every shipped scene, as a snapshot's serializer packs them
and as the serializers of single outputs do, and the strings, stamps and sequences whose
lengths move CDR's padding.
"""
from __future__ import annotations

import dataclasses
import math
import struct

import pytest

from hecker_dynamics.bags.io import typestore
from hecker_dynamics.bags.replay import _MESSAGE_BUILDERS
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.cdr import ENCAPSULATION, SERIALIZERS, SnapshotSerializer, serialize_output
from hecker_dynamics.ros.fields import Header, Pose
from hecker_dynamics.ros.joint_states import JointStateFields
from hecker_dynamics.ros.map_fields import OccupancyGridFields
from hecker_dynamics.ros.markers import MARKER_LINE_STRIP, MarkerFields, delete_markers
from hecker_dynamics.ros.names import twist_topic
from hecker_dynamics.ros.outputs import OutputFields, OutputKind, SnapshotOutputs, output_topics
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.ros.sensor_fields import ImuFields, LaserScanFields
from hecker_dynamics.ros.tf import TransformFields
from hecker_dynamics.scene.load import Scene, load_scene, scene_from_parameters, shipped_scenes
from hecker_dynamics.scene.parameters import flatten

S = 1_000_000_000


def _rosbags_bytes(output: OutputFields) -> bytes:
    message = _MESSAGE_BUILDERS[output.kind](output.fields)
    return bytes(typestore().serialize_cdr(message, output.kind.value))


def _assert_as_rosbags(outputs: list[OutputFields]) -> None:
    for output in outputs:
        assert serialize_output(output) == _rosbags_bytes(output), output.topic


def _everything(scene: Scene, twist_frame: str = "world") -> Scene:
    return dataclasses.replace(scene, publish_markers=True, publish_odometry=True,
                               publish_tf=True, twist_frame=twist_frame)


def _assert_snapshots_as_rosbags(scene: Scene, count: int = 2) -> list[list[tuple[str, bytes]]]:
    """Serialize ``count`` snapshots (the first and the last of 0.25 s) with one serializer,
    as the node does tick after tick, against rosbags' bytes of the same snapshots' fields."""
    outputs = SnapshotOutputs(scene, tf=True)
    serialize = SnapshotSerializer(outputs)
    snapshots = Simulation(scene).advance_to(S // 4)
    assert len(snapshots) >= count
    packed = []
    for snapshot in (snapshots[0], snapshots[-1])[:count]:
        fields = outputs(snapshot)
        messages = serialize(snapshot)
        assert [topic for topic, _ in messages] == [output.topic for output in fields]
        for (topic, data), output in zip(messages, fields):
            assert data == _rosbags_bytes(output), topic
        packed.append(messages)
    return packed


def test_every_output_kind_is_serialized_by_snapshot_or_on_its_own():
    # Diagnostics go out once a second as a message object, not through these.
    assert set(SERIALIZERS) | {OutputKind.POSE, OutputKind.TWIST, OutputKind.ODOMETRY} == \
        set(OutputKind) - {OutputKind.DIAGNOSTICS}


@pytest.mark.parametrize("twist_frame", ["world", "body"])
@pytest.mark.parametrize("name", shipped_scenes())
def test_every_output_of_a_shipped_scene_is_what_rosbags_serializes(name, twist_frame):
    scene = _everything(load_scene(name), twist_frame)
    kinds = set(output_topics(scene).values())
    assert {OutputKind.POSE, OutputKind.TWIST, OutputKind.ODOMETRY, OutputKind.MARKERS,
            OutputKind.TF} <= kinds
    _assert_snapshots_as_rosbags(scene)
    static = SnapshotOutputs(scene, tf=True).static(S)
    _assert_as_rosbags(static)


@pytest.mark.parametrize("length", range(1, 9))
def test_a_snapshot_keeps_the_padding_right_for_names_of_every_length(length):
    # The fixed frame's name sizes every header, a body's name its odometry's child frame
    # and its markers' namespace: 1 to 8 bytes put the float64 after them at every offset
    # modulo 8.
    bodies = {"abcdefgh"[:length]: {"shape": "box", "size": [0.5, 0.3], "mass": 1.0,
                                    "velocity": [1.0, -0.5], "angular_velocity": 2.0},
              "stuvwxyz"[:length]: {"shape": "circle", "radius": 0.2, "mass": 2.0,
                                    "position": [1.0, 0.0], "angular_velocity": -1.0}}
    params = {"frame_id": "fabcdefgh"[:length], "bodies": bodies,
              "forces": {"gravity": {"type": "gravity"}}, "step": 0.01, "publish_rate": 50.0}
    _assert_snapshots_as_rosbags(_everything(scene_from_parameters(flatten(params), "names")))


def test_a_twist_is_the_header_then_six_float64():
    scene = _everything(load_scene("sample"))
    messages = dict(_assert_snapshots_as_rosbags(scene, count=1)[0])
    snapshot = Simulation(scene).advance_to(S // 4)[0]
    for state in snapshot.bodies:
        (vx, vy), omega = state.linear_velocity, state.angular_velocity
        assert messages[twist_topic(state.name)] == ENCAPSULATION + struct.pack(
            "<6d", vx, vy, 0.0, 0.0, 0.0, omega)


def _pose(x: float) -> Pose:
    return Pose((x, -2.5, 0.0), (0.0, 0.0, 0.6, 0.8))


@pytest.mark.parametrize("length", range(9))
def test_strings_of_every_length_modulo_eight_keep_the_padding_right(length):
    # frame ids, namespaces and child frames of 0 to 8 bytes put the float64 that follow
    # them at every offset modulo 8; "ü" is two bytes of UTF-8, so bytes are counted.
    name = ("ü" + "abcdefgh")[:length] if length else ""
    head = Header(-3, 999_999_999, name)   # a negative time keeps nanosec in [0, 1e9)
    marker = MarkerFields(head, name, 7, MARKER_LINE_STRIP, 0, _pose(1.0), (0.02, 0.0, 0.0),
                          (0.1, 0.2, 0.3, 1.0), ((0.0, 0.0, 0.0), (1.0, 2.0, 0.0)))
    transforms = tuple(TransformFields(head, name[:k], (1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0))
                       for k in range(length + 1))
    _assert_as_rosbags([
        OutputFields("m", OutputKind.MARKERS, (marker, marker._replace(ns=name[:1]))),
        OutputFields("m", OutputKind.MARKERS, delete_markers({(name, 1), ("b", 2)}, head)),
        OutputFields("tf", OutputKind.TF, transforms),
        OutputFields("j", OutputKind.JOINT_STATE, JointStateFields(
            head, (name, "x" * length), (0.1, -0.2), (1.5, 2.5), (0.0, 3.0))),
        OutputFields("s", OutputKind.LASER_SCAN, _scan(head, length)),
        OutputFields("i", OutputKind.IMU, _imu(head)),
    ])


def _scan(head: Header, count: int) -> LaserScanFields:
    """A scan of ``count`` rays: REP 117's infinities and ranges that float32 rounds."""
    ranges = (0.1, math.inf, -math.inf, 1 / 3, 7.25, 2.0 ** -20, 1e6, 0.0)
    return LaserScanFields(head, -2.0, 2.0, 4.0 / 180, 0.0, 0.1, 0.05, 8.0,
                           (ranges * 2)[:count])


def _imu(head: Header) -> ImuFields:
    diagonal = (0.5, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 1e-6)
    return ImuFields(head, (0.0, 0.0, 0.6, 0.8), diagonal, (0.0, 0.0, -1.25), diagonal,
                     (9.81, -0.5, 0.0), diagonal)


def test_the_robot_scene_s_scans_and_imu_readings_are_what_rosbags_serializes():
    # The readings of a second of the shipped robot (noise on): scans of 181 rays (every
    # one hits the room's walls), IMU readings at 50 Hz, and the sensor frames on /tf_static.
    # The sensors sample an instant as the run steps on from it: 1 s is not sampled yet.
    scene = load_scene("robot")
    readings = [output for _, output in Runner(scene).advance(S).readings]
    kinds = [output.kind for output in readings]
    assert kinds.count(OutputKind.LASER_SCAN) == 9 and kinds.count(OutputKind.IMU) == 49
    ranges = [r for o in readings if o.kind is OutputKind.LASER_SCAN for r in o.fields.ranges]
    assert len(ranges) == 9 * 181 and all(0.05 < r < 8.0 for r in ranges)
    _assert_as_rosbags(readings)
    static = SnapshotOutputs(scene, tf=True).static(S)
    assert {t.child_frame_id for o in static for t in o.fields} >= {"robot/laser", "robot/imu"}
    _assert_as_rosbags(static)


def test_empty_sequences_have_their_length_and_no_padding():
    head = Header(0, 0, "world")
    _assert_as_rosbags([
        OutputFields("tf", OutputKind.TF, ()),
        OutputFields("m", OutputKind.MARKERS, ()),
        OutputFields("m", OutputKind.MARKERS, (MarkerFields(
            head, "a", 0, MARKER_LINE_STRIP, 0, _pose(0.0), (0.0, 0.0, 0.0),
            (0.0, 0.0, 0.0, 0.0), ()),)),
        OutputFields("j", OutputKind.JOINT_STATE, JointStateFields(head, (), (), (), ())),
        OutputFields("j", OutputKind.JOINT_STATE, JointStateFields(
            head, ("hinge",), (0.5,), (1.0,), ())),
        OutputFields("s", OutputKind.LASER_SCAN, _scan(head, 0)),
    ])




@pytest.mark.parametrize("cells", range(1, 9))
def test_an_occupancy_grid_of_every_length_is_what_rosbags_serializes(cells):
    # The cells (int8) end the message; 1 to 8 of them, after a frame name of as many
    # bytes, leave every padding before and after them.
    fields = OccupancyGridFields(Header(3, 7, "abcdefgh"[:cells]), (3, 7), 0.05, cells, 1,
                                 Pose((-1.5, 2.0, 0.0), (0.0, 0.0, 0.6, 0.8)),
                                 bytes([100, 0, 255, 37, 1, 100, 0, 255][:cells]))
    _assert_as_rosbags([OutputFields("/map", OutputKind.OCCUPANCY_GRID, fields)])
