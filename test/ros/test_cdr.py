"""The node's output bytes (:mod:`hecker_dynamics.ros.cdr`) against rosbags' serializer.

The node publishes these bytes as they are, so each must be the CDR of the message rosbags
(and rosbag2, and rclpy: test_node.py checks that on Jazzy) makes of the same fields, byte
for byte: every output kind of every shipped scene, and the strings, stamps and sequences
whose lengths move CDR's padding.
"""
from __future__ import annotations

import dataclasses

import pytest

from hecker_dynamics.bags.io import typestore
from hecker_dynamics.bags.replay import _MESSAGE_BUILDERS
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.cdr import ENCAPSULATION, SERIALIZERS, serialize_output
from hecker_dynamics.ros.fields import Header, Pose, PoseStampedFields, TwistFields
from hecker_dynamics.ros.joint_states import JointStateFields
from hecker_dynamics.ros.markers import MARKER_LINE_STRIP, MarkerFields, delete_markers
from hecker_dynamics.ros.outputs import OutputFields, OutputKind, SnapshotOutputs
from hecker_dynamics.ros.tf import TransformFields
from hecker_dynamics.scene.load import load_scene, shipped_scenes

S = 1_000_000_000


def _rosbags_bytes(output: OutputFields) -> bytes:
    message = _MESSAGE_BUILDERS[output.kind](output.fields)
    return bytes(typestore().serialize_cdr(message, output.kind.value))


def _assert_as_rosbags(outputs: list[OutputFields]) -> None:
    for output in outputs:
        assert serialize_output(output) == _rosbags_bytes(output), output.topic


def test_every_output_kind_has_a_serializer():
    # Diagnostics go out once a second as a message object, not through these.
    assert set(SERIALIZERS) == set(OutputKind) - {OutputKind.DIAGNOSTICS}


@pytest.mark.parametrize("name", shipped_scenes())
def test_every_output_of_a_shipped_scene_is_what_rosbags_serializes(name):
    scene = dataclasses.replace(load_scene(name), publish_markers=True,
                                publish_odometry=True, publish_tf=True)
    outputs = SnapshotOutputs(scene, tf=True)
    snapshots = Simulation(scene).advance_to(S // 4)
    assert snapshots
    for snapshot in (snapshots[0], snapshots[-1]):
        produced = outputs(snapshot) + outputs.static(snapshot.time_ns)
        assert {OutputKind.POSE, OutputKind.TWIST, OutputKind.ODOMETRY, OutputKind.MARKERS,
                OutputKind.TF} <= {output.kind for output in produced}
        _assert_as_rosbags(produced)


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
        OutputFields("p", OutputKind.POSE, PoseStampedFields(head, _pose(0.5))),
        OutputFields("m", OutputKind.MARKERS, (marker, marker._replace(ns=name[:1]))),
        OutputFields("m", OutputKind.MARKERS, delete_markers({(name, 1), ("b", 2)}, head)),
        OutputFields("tf", OutputKind.TF, transforms),
        OutputFields("j", OutputKind.JOINT_STATE, JointStateFields(
            head, (name, "x" * length), (0.1, -0.2), (1.5, 2.5), (0.0, 3.0))),
    ])


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
    ])


def test_a_twist_is_the_header_then_six_float64():
    raw = serialize_output(OutputFields("t", OutputKind.TWIST,
                                        TwistFields((1.0, 2.0, 0.0), (0.0, 0.0, -0.5))))
    assert raw[:4] == ENCAPSULATION and len(raw) == 4 + 6 * 8
    assert raw == _rosbags_bytes(OutputFields("t", OutputKind.TWIST,
                                              TwistFields((1.0, 2.0, 0.0), (0.0, 0.0, -0.5))))
