"""Names and QoS defined once (hecker_dynamics.ros.names), and used from there."""
from __future__ import annotations

import ast
from pathlib import Path

from hecker_dynamics.ros import names
from hecker_dynamics.ros.names import (
    COMMAND_QOS,
    INPUT_EVENTS_QOS,
    KEYFRAME_QOS,
    SESSION_QOS,
    STATE_QOS,
    TF_QOS,
    TF_STATIC_QOS,
    WORLD_EVENTS_QOS,
    Durability,
    Reliability,
    output_qos,
)
from hecker_dynamics.ros.outputs import output_topics
from hecker_dynamics.scene.load import load_scene, shipped_scenes

ROOT = Path(__file__).resolve().parents[2]
NODE = ROOT / "hecker_dynamics" / "ros" / "node.py"


def test_qos_of_each_kind_of_topic():
    # Commands and state: reliable keep-last 10, volatile (what a bag of the node records).
    for spec in (COMMAND_QOS, STATE_QOS):
        assert spec == (10, Reliability.RELIABLE, Durability.VOLATILE)
    # Latched: kept for late joiners; /tf_static one message, as tf2_ros's static
    # broadcaster; the session records as deep as a late recorder needs them.
    assert TF_STATIC_QOS == SESSION_QOS == (1, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL)
    for spec in (KEYFRAME_QOS, INPUT_EVENTS_QOS, WORLD_EVENTS_QOS):
        assert (spec.reliability, spec.durability) == (Reliability.RELIABLE,
                                                       Durability.TRANSIENT_LOCAL)
    assert KEYFRAME_QOS.depth == 2 and INPUT_EVENTS_QOS.depth == WORLD_EVENTS_QOS.depth == 1000
    assert TF_QOS == (100, Reliability.RELIABLE, Durability.VOLATILE)
    for topic in (names.SESSION_TOPIC, names.KEYFRAME_TOPIC, names.INPUT_EVENTS_TOPIC,
                  names.WORLD_EVENTS_TOPIC):
        assert topic.startswith("~/")   # in the node's own namespace


def test_every_output_has_its_qos():
    for scene_name in shipped_scenes():
        for topic in output_topics(load_scene(scene_name)):
            spec = output_qos(topic)
            latched = topic in (names.TF_STATIC_TOPIC, names.MAP_TOPIC)
            assert (spec.durability is Durability.TRANSIENT_LOCAL) == latched, topic
            assert spec.reliability is Reliability.RELIABLE


def _calls(tree: ast.AST, method: str) -> list[ast.Call]:
    return [node for node in ast.walk(tree) if isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute) and node.func.attr == method]


def test_the_node_takes_every_name_and_profile_from_names():
    tree = ast.parse(NODE.read_text())
    entities = [call for method in ("create_publisher", "create_subscription",
                                    "create_service") for call in _calls(tree, method)]
    assert len(entities) >= 5
    for call in entities:
        topic = call.args[1]
        assert not isinstance(topic, ast.Constant), \
            f"line {call.lineno}: a literal name {topic.value!r}; define it in ros/names.py"
        if call.func.attr != "create_service":
            qos = call.args[-1]
            assert not isinstance(qos, ast.Constant), f"line {call.lineno}: a bare depth"
    # One conversion to rclpy's QoSProfile, in one function.
    profiles = [call for call in ast.walk(tree) if isinstance(call, ast.Call)
                and getattr(call.func, "id", "") == "QoSProfile"]
    assert len(profiles) == 1
    assert NODE.read_text().count("NODE_NAME") >= 2   # the node's name and its logger's
    # The scene reader takes the node's name (the parameters file's top key) from names.
    assert "from .names import NODE_NAME" in \
        (ROOT / "hecker_dynamics" / "scene" / "load.py").read_text()
