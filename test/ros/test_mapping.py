"""Message mapping and rate limiting, without ROS: hand-computed values for every case.

Input messages are built twice, as plain ``SimpleNamespace`` objects and as rosbags
messages of the package's own ``AppliedWrench`` type (the rosbags cases skip where rosbags
is not installed), since the mapping must read both the same way.
"""
from __future__ import annotations

import array
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import push_unchecked

from hecker_dynamics.dynamics.simulation import BodyState, Simulation
from hecker_dynamics.geometry.shapes import Circle, Polygon, box
from hecker_dynamics.ros.diagnostics import (
    DIAGNOSTIC_ERROR,
    DIAGNOSTIC_OK,
    DIAGNOSTIC_WARN,
    diagnostic_fields,
    diagnostics_due,
    simulation_diagnostics,
)
from hecker_dynamics.ros.fields import (
    applied_wrench_fields,
    applied_wrench_to_command,
    ns_from_stamp,
    odometry_fields,
    pose_fields,
    quaternion_from_yaw,
    stamp_from_ns,
    twist_fields,
    wrench_stamped_to_command,
)
from hecker_dynamics.ros.markers import (
    MARKER_ADD,
    MARKER_CYLINDER,
    MARKER_LINE_STRIP,
    marker_fields,
)
from hecker_dynamics.ros.outputs import OutputKind, output_topics, snapshot_outputs
from hecker_dynamics.ros.ratelimit import RateLimiter
from hecker_dynamics.ros.runner import (
    NodeOptions,
    Runner,
    TickAction,
    catch_up_cap,
    due_script,
    lag_ns,
    node_options,
    node_setup,
    plain_parameters,
    plan_tick,
    scene_for_node,
)
from hecker_dynamics.scene.commands import InputError, WrenchCommand
from hecker_dynamics.scene.load import SceneError, WrenchTopic, load_scene

MSG_FILE = Path(__file__).resolve().parents[2] / "msg" / "AppliedWrench.msg"
SQRT_HALF = math.sqrt(0.5)
S = 1_000_000_000


# ----------------------------------------------------------------------------- builders

def _vec(x: float, y: float, z: float) -> SimpleNamespace:
    return SimpleNamespace(x=x, y=y, z=z)


def _namespace_applied(stamp, frame_id, body, source, point, force, torque, duration):
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=stamp[0], nanosec=stamp[1]),
                               frame_id=frame_id),
        body=body, id=source, point=_vec(*point),
        wrench=SimpleNamespace(force=_vec(*force), torque=_vec(*torque)),
        duration=SimpleNamespace(sec=duration[0], nanosec=duration[1]))


def _rosbags_store():
    typesys = pytest.importorskip("rosbags.typesys", reason="rosbags is not installed")
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    store.register(typesys.get_types_from_msg(MSG_FILE.read_text(),
                                              "hecker_dynamics/msg/AppliedWrench"))
    return store


def _rosbags_applied(stamp, frame_id, body, source, point, force, torque, duration):
    store = _rosbags_store()
    t = store.types
    vector3 = t["geometry_msgs/msg/Vector3"]
    msg = t["hecker_dynamics/msg/AppliedWrench"](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=stamp[0], nanosec=stamp[1]),
            frame_id=frame_id),
        body=body, id=source, point=t["geometry_msgs/msg/Point"](*point),
        wrench=t["geometry_msgs/msg/Wrench"](force=vector3(*force), torque=vector3(*torque)),
        duration=t["builtin_interfaces/msg/Duration"](sec=duration[0], nanosec=duration[1]))
    # Through CDR and back, as a recorded message would come out of a bag.
    raw = store.serialize_cdr(msg, "hecker_dynamics/msg/AppliedWrench")
    return store.deserialize_cdr(raw, "hecker_dynamics/msg/AppliedWrench")


@pytest.fixture(params=["namespace", "rosbags"])
def applied(request):
    """A builder of AppliedWrench messages with defaults, in both representations."""
    build = _namespace_applied if request.param == "namespace" else _rosbags_applied

    def make(stamp=(0, 0), frame_id="", body="left", source="kick", point=(0.0, 0.0, 0.0),
             force=(0.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0), duration=(0, 0)):
        return build(stamp, frame_id, body, source, point, force, torque, duration)
    return make


def _wrench_stamped(stamp=(0, 0), frame_id="", force=(0.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0)):
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=stamp[0], nanosec=stamp[1]),
                               frame_id=frame_id),
        wrench=SimpleNamespace(force=_vec(*force), torque=_vec(*torque)))


def _state(position=(1.0, 2.0), angle=0.0, velocity=(0.0, 0.0), omega=0.0, name="left"):
    return BodyState(name, position, angle, velocity, omega)


# ----------------------------------------------------------------------------- time

@pytest.mark.parametrize("sec, nanosec, ns", [
    (0, 0, 0), (1, 500_000_000, 1_500_000_000), (1_700_000_000, 999_999_999,
                                                 1_700_000_000_999_999_999),
    (-1, 999_999_999, -1)])
def test_stamps_convert_both_ways(sec, nanosec, ns):
    assert ns_from_stamp(sec, nanosec) == ns
    assert stamp_from_ns(ns) == (sec, nanosec)


def test_stamp_carries_whole_seconds_out_of_nanosec():
    assert stamp_from_ns(1_999_999_999) == (1, 999_999_999)
    assert stamp_from_ns(2_000_000_000) == (2, 0)
    assert stamp_from_ns(2_000_000_001) == (2, 1)


# ----------------------------------------------------------------------------- inputs

def test_applied_wrench_in_body_frame(applied):
    msg = applied(stamp=(3, 250_000_000), frame_id="left", point=(0.4, 0.2, 0.0),
                  force=(1.0, -2.0, 0.0), torque=(0.0, 0.0, 0.5), duration=(0, 100_000_000))
    command, warnings = applied_wrench_to_command(msg, receive_ns=99 * S)
    assert command == WrenchCommand(stamp_ns=3_250_000_000, body="left", source="kick",
                                    frame_id="left", point=(0.4, 0.2), force=(1.0, -2.0),
                                    torque=0.5, duration_ns=100_000_000)
    assert warnings == []


@pytest.mark.parametrize("frame_id, expected", [
    ("world", "world"), ("right", "right"), ("left/hook", "left/hook"), ("", "left")])
def test_applied_wrench_frame_cases(applied, frame_id, expected):
    command, _ = applied_wrench_to_command(applied(frame_id=frame_id, force=(1.0, 0.0, 0.0)),
                                           receive_ns=0)
    assert command.frame_id == expected
    assert command.body == "left"


def test_zero_stamp_means_arrival_time(applied):
    command, _ = applied_wrench_to_command(applied(), receive_ns=7 * S + 3)
    assert command.stamp_ns == 7 * S + 3
    command, _ = applied_wrench_to_command(applied(stamp=(0, 1)), receive_ns=7 * S)
    assert command.stamp_ns == 1


def test_out_of_plane_parts_warn_and_are_dropped(applied):
    msg = applied(point=(0.1, 0.2, 0.3), force=(1.0, 2.0, 3.0), torque=(4.0, 5.0, 6.0))
    command, warnings = applied_wrench_to_command(msg, receive_ns=0)
    assert (command.point, command.force, command.torque) == ((0.1, 0.2), (1.0, 2.0), 6.0)
    assert len(warnings) == 1
    for part in ("force.z=3", "torque.x=4", "torque.y=5", "point.z=0.3"):
        assert part in warnings[0]
    assert "body 'left'" in warnings[0] and "'kick'" in warnings[0]


@pytest.mark.parametrize("field", ["force", "torque", "point"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_numbers_are_input_errors(applied, field, bad):
    values = {"force": (1.0, 0.0, 0.0), "torque": (0.0, 0.0, 0.0), "point": (0.0, 0.0, 0.0)}
    values[field] = (0.0, 0.0, bad) if field != "point" else (bad, 0.0, 0.0)
    with pytest.raises(InputError, match="non-finite"):
        applied_wrench_to_command(applied(**values), receive_ns=0)


def test_negative_duration_and_empty_body_are_input_errors(applied):
    with pytest.raises(InputError, match="negative duration"):
        applied_wrench_to_command(applied(duration=(-1, 0)), receive_ns=0)
    with pytest.raises(InputError, match="empty 'body'"):
        applied_wrench_to_command(applied(body=""), receive_ns=0)


def test_wrench_stamped_acts_at_the_origin_of_its_frame():
    topic = WrenchTopic(name="thruster", topic="ship/thruster", body="ship",
                        frame_id="ship/engine")
    msg = _wrench_stamped(stamp=(2, 5), force=(10.0, 0.5, 0.0), torque=(0.0, 0.0, -1.5))
    command, warnings = wrench_stamped_to_command(msg, topic, receive_ns=S)
    assert command == WrenchCommand(stamp_ns=2 * S + 5, body="ship", source="thruster",
                                    frame_id="ship/engine", point=(0.0, 0.0),
                                    force=(10.0, 0.5), torque=-1.5, duration_ns=0)
    assert warnings == []
    command, _ = wrench_stamped_to_command(_wrench_stamped(frame_id="world"), topic, S)
    assert (command.frame_id, command.stamp_ns) == ("world", S)


def test_wrench_stamped_out_of_plane_and_non_finite():
    topic = WrenchTopic("thruster", "thruster", "ship", "ship")
    _, warnings = wrench_stamped_to_command(
        _wrench_stamped(force=(0.0, 0.0, 2.0), torque=(1.0, 0.0, 0.0)), topic, 0)
    assert len(warnings) == 1 and "force.z=2" in warnings[0] and "torque.x=1" in warnings[0]
    with pytest.raises(InputError, match="torque.z=nan"):
        wrench_stamped_to_command(_wrench_stamped(torque=(0.0, 0.0, math.nan)), topic, 0)


def test_rosbags_message_type_has_the_documented_fields():
    store = _rosbags_store()
    fields = store.types["hecker_dynamics/msg/AppliedWrench"].__dataclass_fields__
    assert [name for name in fields if name != "__msgtype__"] == [
        "header", "body", "id", "point", "wrench", "duration"]


# ----------------------------------------------------------------------------- outputs

@pytest.mark.parametrize("angle, expected", [
    (0.0, (0.0, 0.0, 0.0, 1.0)),
    (math.pi / 2, (0.0, 0.0, SQRT_HALF, SQRT_HALF)),
    (-math.pi / 2, (0.0, 0.0, -SQRT_HALF, SQRT_HALF)),
    (math.pi, (0.0, 0.0, 1.0, 0.0)),
    (-math.pi, (0.0, 0.0, -1.0, 0.0)),
    (math.pi / 3, (0.0, 0.0, 0.5, math.sqrt(3) / 2)),
])
def test_quaternion_from_yaw(angle, expected):
    q = quaternion_from_yaw(angle)
    assert q == pytest.approx(expected, abs=1e-15)
    assert math.fsum(c * c for c in q) == pytest.approx(1.0, abs=1e-15)
    assert q[3] >= 0.0


def test_pose_fields():
    fields = pose_fields(_state(position=(1.5, -2.0), angle=math.pi / 2), "world",
                         12 * S + 34)
    assert (fields.header.sec, fields.header.nanosec, fields.header.frame_id) == (
        12, 34, "world")
    assert fields.pose.position == (1.5, -2.0, 0.0)
    assert fields.pose.orientation == pytest.approx((0.0, 0.0, SQRT_HALF, SQRT_HALF))


@pytest.mark.parametrize("angle, velocity, body_axes", [
    (0.0, (1.0, 2.0), (1.0, 2.0)),
    (math.pi / 2, (1.0, 0.0), (0.0, -1.0)),   # moving along world x = along body -y
    (math.pi / 2, (0.0, 3.0), (3.0, 0.0)),
    (math.pi, (1.0, 2.0), (-1.0, -2.0)),
    (-math.pi / 4, (1.0, 1.0), (0.0, math.sqrt(2))),
])
def test_twist_frames(angle, velocity, body_axes):
    state = _state(angle=angle, velocity=velocity, omega=-0.75)
    body = twist_fields(state, "body")
    world = twist_fields(state, "world")
    assert body.linear == pytest.approx((*body_axes, 0.0), abs=1e-15)
    assert world.linear == (velocity[0], velocity[1], 0.0)
    assert body.angular == world.angular == (0.0, 0.0, -0.75)
    with pytest.raises(ValueError):
        twist_fields(state, "odom")


def test_odometry_twist_is_in_the_child_frame():
    state = _state(position=(3.0, 4.0), angle=math.pi / 2, velocity=(2.0, 0.0), omega=1.0)
    fields = odometry_fields(state, "world", 5 * S)
    assert fields.header == (5, 0, "world")
    assert fields.child_frame_id == "left"
    assert fields.pose.position == (3.0, 4.0, 0.0)
    assert fields.twist.linear == pytest.approx((0.0, -2.0, 0.0), abs=1e-15)
    assert fields.twist.angular == (0.0, 0.0, 1.0)


def _body(shapes, name="left"):
    return SimpleNamespace(name=name, shapes=tuple(shapes))


def test_polygon_marker_is_a_closed_outline_in_the_body_frame():
    square = box(2.0, 1.0)
    markers = marker_fields(_body([square]), _state(angle=0.5), 1, "world", S)
    assert len(markers) == 1
    marker = markers[0]
    assert (marker.ns, marker.id, marker.type, marker.action) == (
        "left", 0, MARKER_LINE_STRIP, MARKER_ADD)
    assert marker.header == (1, 0, "world")
    assert marker.pose.position == (1.0, 2.0, 0.0)
    assert marker.pose.orientation == pytest.approx(quaternion_from_yaw(0.5))
    corners = [(x, y, 0.0) for x, y in np.asarray(square.vertices)]
    np.testing.assert_array_equal(np.array(marker.points), np.array(corners + [corners[0]]))
    # rclpy's Point checks its fields are Python floats.
    assert all(type(c) is float for point in marker.points for c in point)
    assert {(abs(x), abs(y)) for x, y, _ in marker.points} == {(1.0, 0.5)}
    assert marker.scale[0] > 0.0


def test_circle_marker_is_a_disc_at_the_rotated_center_and_a_radius_line():
    wheel = Circle((0.5, 0.0), 0.25)
    triangle = Polygon([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)])
    markers = marker_fields(_body([triangle, wheel]), _state(angle=math.pi / 2), 0,
                            "world", 0)
    assert [(m.id, m.type) for m in markers] == [
        (0, MARKER_LINE_STRIP), (1, MARKER_CYLINDER), (2, MARKER_LINE_STRIP)]
    disc, spoke = markers[1], markers[2]
    # Body at (1, 2) turned a quarter: the center (0.5, 0) of the body frame is at (1, 2.5).
    assert disc.pose.position == pytest.approx((1.0, 2.5, 0.0))
    assert disc.scale[:2] == (0.5, 0.5)
    assert spoke.pose.position == (1.0, 2.0, 0.0)
    assert spoke.points == ((0.5, 0.0, 0.0), (0.75, 0.0, 0.0))
    assert disc.color[:3] == spoke.color[:3]


def test_markers_of_different_bodies_differ_in_color():
    shape = box(1.0, 1.0)
    first = marker_fields(_body([shape], "a"), _state(), 0, "world", 0)[0]
    second = marker_fields(_body([shape], "b"), _state(), 1, "world", 0)[0]
    assert first.color != second.color and first.ns != second.ns


def test_diagnostic_fields_format_values_as_strings():
    fields = diagnostic_fields(DIAGNOSTIC_WARN, "behind", {
        "energy": 1.0 / 3.0, "steps": 42, "integrator": "rk4"}, hardware_id="/dynamics_node")
    assert fields.level == DIAGNOSTIC_WARN
    assert fields.hardware_id == "/dynamics_node"
    assert fields.values == (("energy", "0.333333333"), ("steps", "42"),
                             ("integrator", "rk4"))


def test_outputs_accept_a_real_snapshot():
    scene = load_scene("sample")
    sim = Simulation(scene, start_ns=5 * S)
    sim.advance_to(5 * S + scene.publish_period_ns)
    snapshot = sim.snapshot()
    for body, state in zip(scene.bodies, snapshot.bodies):
        pose = pose_fields(state, scene.frame_id, snapshot.time_ns)
        assert pose.header == (5, scene.publish_period_ns, "world")
        assert pose.pose.orientation == pytest.approx(quaternion_from_yaw(state.angle))
        assert marker_fields(body, state, 0, "world", snapshot.time_ns)


# ----------------------------------------------------------------------------- node logic

def test_plan_tick():
    assert plan_tick(0, None)[0] is TickAction.WAIT
    assert plan_tick(0, 5 * S)[0] is TickAction.WAIT
    assert plan_tick(5 * S, None)[0] is TickAction.START
    assert plan_tick(5 * S + 20_000_000, 5 * S) == (TickAction.ADVANCE, "")
    # A small step back (less than a jump) waits for the clock to pass the sim again.
    assert plan_tick(5 * S - 1000, 5 * S)[0] is TickAction.ADVANCE
    action, reason = plan_tick(2 * S, 5 * S)
    assert action is TickAction.RESTART and "back by 3 s" in reason
    action, reason = plan_tick(9 * S, 5 * S)
    assert action is TickAction.RESTART and "ahead by 4 s" in reason
    assert plan_tick(6 * S, 5 * S)[0] is TickAction.ADVANCE  # exactly the threshold


def test_plan_tick_names_ros_times_to_the_nanosecond():
    """A ROS time of 1.7e9 s is held by a double only to 256 ns: the log names the exact
    time (a user copies it into --start), 1700000000.750000001 s, not
    1700000000.750000238."""
    now = 1_700_000_000_750_000_001
    assert plan_tick(now, None)[1] == "starting the simulation at 1700000000.750000001 s"
    action, reason = plan_tick(now, now + 2 * S + 250_000_000)
    assert action is TickAction.RESTART
    assert reason == ("the ROS clock jumped back by 2.25 s; restarting the scene at "
                      "1700000000.750000001 s")
    assert plan_tick(now, now - 3 * S - 1)[1].startswith("the ROS clock jumped ahead by "
                                                         "3.000000001 s;")


def test_lag_counts_only_whole_steps():
    step = 1_000_000
    assert lag_ns(100 * step, 100 * step, step) == 0
    assert lag_ns(100 * step + step - 1, 100 * step, step) == 0
    assert lag_ns(100 * step + step, 100 * step, step) == step
    assert lag_ns(3 * S, S, step) == 2 * S


def _command(stamp_ns, source):
    return WrenchCommand(stamp_ns, "left", source, "world", (0.0, 0.0), (1.0, 0.0))


def test_due_script_shifts_to_the_start_and_keeps_its_place():
    script = (_command(0, "a"), _command(S, "b"), _command(S, "c"), _command(3 * S, "d"))
    due, index = due_script(script, 10 * S, 0, 10 * S)
    assert [(c.source, c.stamp_ns) for c in due] == [("a", 10 * S)]
    due, index = due_script(script, 10 * S, index, 11 * S - 1)
    assert (due, index) == ([], 1)
    due, index = due_script(script, 10 * S, index, 12 * S)
    assert [(c.source, c.stamp_ns) for c in due] == [("b", 11 * S), ("c", 11 * S)]
    due, index = due_script(script, 10 * S, index, 100 * S)
    assert [c.source for c in due] == ["d"] and index == 4
    assert due_script(script, 10 * S, index, 200 * S) == ([], 4)


def test_due_script_matches_simulation_play():
    scene = load_scene("sample")
    played = Simulation(scene, start_ns=S)
    expected = played.play(scene.script, until_ns=scene.duration_ns)
    stepped = Simulation(scene, start_ns=S)
    index, snapshots = 0, []
    for tick in range(1, scene.duration_ns // scene.publish_period_ns + 1):
        target = S + tick * scene.publish_period_ns
        due, index = due_script(scene.script, S, index, target)
        for command in due:
            stepped.push(command)
        snapshots += stepped.advance_to(target)
    assert scene.script and index == len(scene.script)
    assert snapshots == expected


def test_node_options_defaults_and_types():
    assert node_options({}, "test") == NodeOptions()
    assert node_options({"lockstep": True, "max_catch_up_steps": 5, "use_sim_time": True},
                        "test") == NodeOptions(lockstep=True, max_catch_up_steps=5)
    with pytest.raises(SceneError, match="test: parameter 'lockstep' must be a bool"):
        node_options({"lockstep": 1}, "test")
    with pytest.raises(SceneError, match="'max_catch_up_steps' must be an? int"):
        node_options({"max_catch_up_steps": 2.5}, "test")
    with pytest.raises(SceneError, match="at least 1"):
        node_options({"max_catch_up_steps": 0}, "test")


def test_catch_up_cap_covers_a_publish_period():
    scene = load_scene("sample")
    per_period = scene.publish_period_ns // scene.step_ns
    assert catch_up_cap(per_period, scene) == (per_period, [])
    cap, warnings = catch_up_cap(1, scene)
    assert cap == per_period and "max_catch_up_steps=1" in warnings[0]


ONE_BODY = {"step": 0.01, "publish_rate": 10.0, "bodies.puck.shape": "circle",
            "bodies.puck.radius": 0.5, "bodies.puck.mass": 2.0}


def test_scene_for_node_sources():
    ros = {"use_sim_time": False, "start_type_description_service": True,
           "qos_overrides./parameter_events.publisher.depth": 1000}
    default = scene_for_node({**ros, "scene": "", "lockstep": False}, "test")
    assert [b.name for b in default.bodies] == [b.name for b in load_scene(None).bodies]
    assert scene_for_node({"scene": "sample"}, "test").source.endswith("sample.yaml")
    from_params = scene_for_node({**ros, **ONE_BODY, "lockstep": True}, "params")
    assert [b.name for b in from_params.bodies] == ["puck"]
    assert from_params.step_ns == 10_000_000 and from_params.source == "params"
    with pytest.raises(SceneError, match="not both"):
        scene_for_node({**ONE_BODY, "scene": "sample"}, "params")
    with pytest.raises(SceneError, match="params"):
        scene_for_node({**ONE_BODY, "bodies.puck.radius": -1.0}, "params")


def test_scene_for_node_reads_a_file(tmp_path):
    path = tmp_path / "one.yaml"
    path.write_text("dynamics_node:\n  ros__parameters:\n    bodies:\n      puck:\n"
                    "        shape: circle\n        radius: 0.5\n        mass: 2.0\n")
    assert [b.name for b in scene_for_node({"scene": str(path)}, "test").bodies] == ["puck"]


def test_node_setup_takes_arrays_as_rclpy_holds_them():
    # Overrides from the command line or a parameters file come as lists; values that went
    # through a ParameterValue message (rclpy's Parameter.from_parameter_msg) as array.array.
    params = {**ONE_BODY, "bodies.puck.position": array.array("d", [1.0, 2.0]),
              "bodies.puck.velocity": (0.5, 0.0), "use_sim_time": True,
              "start_type_description_service": True, "max_catch_up_steps": 7}
    assert plain_parameters(params)["bodies.puck.position"] == [1.0, 2.0]
    assert plain_parameters({"ids": array.array("q", [1, 2])}) == {"ids": [1, 2]}
    options, scene = node_setup(params, "test")
    assert options == NodeOptions(max_catch_up_steps=7)
    assert scene.bodies[0].position == (1.0, 2.0) and scene.bodies[0].velocity == (0.5, 0.0)


def test_applied_wrench_fields_invert_the_mapping():
    command = WrenchCommand(12 * S + 345, "left", "kick", "left/hook", (0.4, 0.2),
                            (0.0, 60.0), -1.5, 100_000_000)
    fields = applied_wrench_fields(command)
    assert fields.header == (12, 345, "left/hook")
    assert (fields.body, fields.id, fields.duration) == ("left", "kick", (0, 100_000_000))
    assert (fields.point, fields.force, fields.torque) == (
        (0.4, 0.2, 0.0), (0.0, 60.0, 0.0), (0.0, 0.0, -1.5))
    msg = _namespace_applied((fields.header.sec, fields.header.nanosec),
                             fields.header.frame_id, fields.body, fields.id, fields.point,
                             fields.force, fields.torque, fields.duration)
    assert applied_wrench_to_command(msg, receive_ns=99 * S) == (command, [])


def _sim_at(step_count: int) -> Simulation:
    sim = Simulation(load_scene("sample"), start_ns=2 * S)
    sim.advance_to(2 * S + step_count * sim.step_ns)
    return sim


def test_simulation_diagnostics_levels_and_values():
    sim = _sim_at(20)
    ok = simulation_diagnostics(sim, halted=None, lag=0, substeps=20, wall_ns=4_000_000,
                                accepted=3, rejected=1, hardware_id="/ns/dynamics_node")
    assert (ok.level, ok.message, ok.hardware_id) == (DIAGNOSTIC_OK, "running",
                                                      "/ns/dynamics_node")
    values = dict(ok.values)
    assert values["sim_time"] == "2.02" and values["start_time"] == "2"
    assert values["steps"] == "20" and values["substeps"] == "20"
    assert values["step_wall_time"] == "0.0002"  # 4 ms over 20 steps
    assert values["energy"] == f"{sim.snapshot().energy:.9g}"
    assert (values["commands_accepted"], values["commands_rejected"]) == ("3", "1")
    behind = simulation_diagnostics(sim, halted=None, lag=250_000_000, substeps=0, wall_ns=0,
                                    accepted=0, rejected=0, hardware_id="x")
    assert behind.level == DIAGNOSTIC_WARN and behind.message == "0.250 s behind the clock"
    assert dict(behind.values)["step_wall_time"] == "0"  # no steps: no division by zero
    halted = simulation_diagnostics(sim, halted="state diverged", lag=5, substeps=0,
                                    wall_ns=0, accepted=0, rejected=0, hardware_id="x")
    assert (halted.level, halted.message) == (DIAGNOSTIC_ERROR, "state diverged")


def test_diagnostics_due_once_per_second_of_sim_time():
    assert diagnostics_due(None, 0)
    assert not diagnostics_due(5 * S, 6 * S - 1)
    assert diagnostics_due(5 * S, 6 * S)


def test_output_topics_and_snapshot_outputs_follow_the_scene():
    scene = scene_for_node({**ONE_BODY, "bodies.ball.shape": "circle",
                            "bodies.ball.radius": 0.2, "bodies.ball.mass": 1.0,
                            "bodies.ball.position": [3.0, 0.0]}, "test")
    assert output_topics(scene, tf=False) == {
        "puck/pose": OutputKind.POSE, "puck/twist": OutputKind.TWIST,
        "ball/pose": OutputKind.POSE, "ball/twist": OutputKind.TWIST}
    everything = scene_for_node({**ONE_BODY, "publish.odometry": True,
                                 "publish.markers": True, "publish.diagnostics": True}, "test")
    assert list(output_topics(everything).items()) == [
        ("puck/pose", OutputKind.POSE), ("puck/twist", OutputKind.TWIST),
        ("puck/odom", OutputKind.ODOMETRY), ("markers", OutputKind.MARKERS),
        ("/tf", OutputKind.TF), ("/tf_static", OutputKind.TF),
        ("diagnostics", OutputKind.DIAGNOSTICS)]
    sim = Simulation(everything, start_ns=S)
    snapshot = sim.advance_to(S + everything.publish_period_ns)[-1]
    state = snapshot.bodies[0]
    outputs = snapshot_outputs(everything, snapshot)
    # Every topic but the latched /tf_static and the diagnostics (due once a second).
    assert [(o.topic, o.kind) for o in outputs] == list(output_topics(everything).items())[:-2]
    assert outputs[0].fields == pose_fields(state, "world", snapshot.time_ns)
    assert outputs[1].fields == twist_fields(state, everything.twist_frame)
    assert outputs[2].fields == odometry_fields(state, "world", snapshot.time_ns)
    assert outputs[3].fields == tuple(marker_fields(everything.bodies[0], state, 0, "world",
                                                    snapshot.time_ns))


# ----------------------------------------------------------------------------- run loop

def _push_left(runner, arrival_ns, stamp=(0, 0), **fields):
    msg = _namespace_applied(stamp, fields.pop("frame_id", "world"), fields.pop("body", "left"),
                             "test", (0.0, 0.0, 0.0), fields.pop("force", (1.0, 0.0, 0.0)),
                             (0.0, 0.0, 0.0), (0, 0))
    return runner.accept("/applied_wrench", msg, arrival_ns)


def test_runner_refuses_input_before_the_start_and_counts_bad_input():
    runner = Runner(load_scene("sample"), started=False)
    lines = _push_left(runner, 0)
    assert [line.key for line in lines] == ["/applied_wrench:early"] and lines[0].dropped
    runner.restart(3 * S)
    assert runner.started and runner.sim.time_ns == 3 * S
    assert _push_left(runner, 3 * S) == []
    nan = _push_left(runner, 3 * S, force=(math.nan, 0.0, 0.0))
    ghost = _push_left(runner, 3 * S, body="ghost")
    frame = _push_left(runner, 3 * S, frame_id="left/nowhere")
    ahead = _push_left(runner, 3 * S, stamp=(3600, 0))
    assert [lines[0].key for lines in (nan, ghost, frame, ahead)] == [
        "/applied_wrench:message", "/applied_wrench:scene", "/applied_wrench:scene",
        "/applied_wrench:scene"]
    assert "unknown body 'ghost'" in ghost[0].message
    assert "unknown frame 'left/nowhere'" in frame[0].message
    tilted = _push_left(runner, 3 * S, force=(1.0, 0.0, 2.0))
    assert [(line.key, line.dropped) for line in tilted] == [
        ("/applied_wrench:out_of_plane", False)]
    assert (runner.accepted, runner.rejected) == (2, 5)


@pytest.mark.parametrize("duration, seconds", [((0, 1), "0.000000001"),
                                               ((0, 999_999), "0.000999999")])
def test_runner_refuses_a_wrench_shorter_than_one_step(duration, seconds):
    """A force acts over whole steps: 1 ns gave the impulse of a whole 1 ms step, a
    million times the one asked for; a wrench of one step or more is taken."""
    runner = Runner(load_scene("sample"))
    short = _namespace_applied((0, 0), "world", "left", "kick", (0.0, 0.0, 0.0),
                               (1.0, 0.0, 0.0), (0.0, 0.0, 0.0), duration)
    lines = runner.accept("/applied_wrench", short, 0)
    assert [(line.key, line.dropped) for line in lines] == [("/applied_wrench:scene", True)]
    assert lines[0].message.endswith(
        f"duration of the command for 'left' from 'kick': {seconds} s is shorter than one step "
        "(0.001 s), over which a force acts whole")
    step = _namespace_applied((0, 0), "world", "left", "kick", (0.0, 0.0, 0.0),
                              (1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0, 1_000_000))
    assert runner.accept("/applied_wrench", step, 0) == []
    assert (runner.accepted, runner.rejected) == (1, 1)


def test_runner_plays_the_script_like_simulation_play():
    scene = load_scene("sample")
    expected = Simulation(scene, start_ns=S).play(scene.script, until_ns=scene.duration_ns)
    runner = Runner(scene, start_ns=S)
    snapshots = runner.advance(S).snapshots  # the first tick: no step
    period = scene.publish_period_ns
    while not runner.done():
        tick = runner.advance(runner.sim.time_ns + period)
        assert tick.lag == 0 and tick.diagnostics is None  # diagnostics are off
        snapshots += tick.snapshots
    assert snapshots == expected
    without = Runner(scene, start_ns=S, play_script=False)
    without.advance(S + scene.duration_ns)
    assert without.sim.snapshot() != expected[-1]


def test_runner_caps_catch_up_and_reports_the_lag():
    scene = load_scene("sample")
    runner = Runner(scene, max_steps=50, wall_clock=iter(range(0, 10**9, 10**6)).__next__)
    tick = runner.advance(S)
    assert runner.sim.time_ns == 50 * scene.step_ns and tick.lag == S - runner.sim.time_ns
    assert [s.time_ns for s in tick.snapshots] == [20_000_000, 40_000_000]


def test_runner_diagnostics_schedule_and_divergence():
    scene = scene_for_node({**ONE_BODY, "step": 0.001, "publish.diagnostics": True,
                            "input_timeout": 0.0, "bodies.tiny.shape": "circle",
                            "bodies.tiny.radius": 0.1, "bodies.tiny.mass": 1e-3,
                            "bodies.tiny.position": [2.0, 0.0]}, "test")
    runner = Runner(scene, wall_clock=iter(range(0, 10**12, 10**6)).__next__)
    first = runner.advance(0)
    assert first.diagnostics.level == DIAGNOSTIC_OK and dict(first.diagnostics.values)[
        "substeps"] == "0"
    assert runner.advance(S // 2).diagnostics is None  # at most once a second of sim time
    assert dict(runner.advance(S).diagnostics.values)["substeps"] == "500"
    push_unchecked(runner.sim, WrenchCommand(S + 5_000_000, "tiny", "boom", "world",
                                             (2.0, 0.1), (1e308, 1e308), 0.0, 0))
    tick = runner.advance(2 * S)
    assert tick.diverged and runner.halted == tick.diverged and runner.done()
    assert (tick.diagnostics.level, tick.diagnostics.message) == (DIAGNOSTIC_ERROR, tick.diverged)
    assert runner.advance(3 * S).snapshots == [] and runner.sim.time_ns < 2 * S
    runner.restart(10 * S)
    assert runner.halted is None and not runner.done()
    assert runner.advance(11 * S).snapshots[-1].time_ns == 11 * S


# ----------------------------------------------------------------------------- rate limiter

class FakeClock:
    def __init__(self) -> None:
        self.ns = 0

    def __call__(self) -> int:
        return self.ns


def test_rate_limiter_lets_one_line_per_key_and_period_through():
    clock = FakeClock()
    limiter = RateLimiter(period_ns=S, clock=clock)
    assert limiter.line("nan", "bad wrench") == "bad wrench"
    assert limiter.line("nan", "bad wrench") is None
    assert limiter.line("unknown", "no such body") == "no such body"
    clock.ns = S - 1
    assert limiter.line("nan", "bad wrench") is None
    clock.ns = S
    assert limiter.line("nan", "bad wrench") == "bad wrench (2 similar lines suppressed)"
    clock.ns = 2 * S
    assert limiter.line("nan", "bad wrench") == "bad wrench"
    assert limiter.line("unknown", "x") == "x"
    assert limiter.line("unknown", "x") is None
    clock.ns = 3 * S
    assert limiter.line("unknown", "x") == "x (1 similar line suppressed)"


def test_rate_limiter_bounds_a_flood():
    clock = FakeClock()
    limiter = RateLimiter(period_ns=S, clock=clock)
    lines = []
    for i in range(10_000):
        clock.ns = i * 1_000_000  # 1 kHz flood for 10 s
        line = limiter.line("flood", "bad")
        if line is not None:
            lines.append(line)
    assert len(lines) == 10
    assert lines[1] == "bad (999 similar lines suppressed)"


def test_rate_limiter_rejects_a_negative_period():
    with pytest.raises(ValueError):
        RateLimiter(period_ns=-1)
