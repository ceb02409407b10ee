"""The rclpy node, in-process, against the core's own offline result for the same inputs.

Needs a ROS 2 Jazzy install with this package built and sourced (``colcon build``, then
``source install/setup.bash``); skips with that reason elsewhere. The tests drive the
node's clock themselves (``use_sim_time`` and a ``/clock`` publisher, or lockstep), so
what they compare does not depend on how fast the machine is; the time limits in
:func:`spin_until` only stop a hung test.
"""
from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable
from types import SimpleNamespace

import pytest
from jazzy import require_jazzy

rclpy = require_jazzy()

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import PoseStamped, Twist, WrenchStamped  # noqa: E402
from hecker_dynamics.msg import AppliedWrench  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from hecker_dynamics.dynamics.simulation import Simulation  # noqa: E402
from hecker_dynamics.ros.cdr import SnapshotSerializer, serialize_output  # noqa: E402
from hecker_dynamics.ros.fields import (  # noqa: E402
    applied_wrench_to_command,
    ns_from_stamp,
    pose_fields,
    stamp_from_ns,
    twist_fields,
    wrench_stamped_to_command,
)
from hecker_dynamics.ros.node import MESSAGE_TYPES, DynamicsNode  # noqa: E402
from hecker_dynamics.ros.outputs import SnapshotOutputs, output_topics  # noqa: E402
from hecker_dynamics.ros.runner import Runner, refused_change  # noqa: E402
from hecker_dynamics.scene.load import load_scene, scene_from_parameters, shipped_scenes  # noqa: E402

S = 1_000_000_000
T0 = 1000 * S  # the test's sim-time origin, a multiple of every publish period used here
NAMESPACE = f"/hecker_dynamics_test_{os.getpid()}"
#: A domain of its own, so the test's /clock reaches no other ROS process on the machine.
DOMAIN_ID = 40 + os.getpid() % 50

#: One box with a named point, a thruster topic, a scripted nudge and every output on.
PUCK = {
    "step": 0.001, "publish_rate": 50.0, "input_timeout": 0.25, "twist_frame": "body",
    "bodies.puck.shape": "box", "bodies.puck.size": [1.0, 0.5], "bodies.puck.mass": 2.0,
    "bodies.puck.angle": 0.3, "bodies.puck.angular_velocity": 0.5,
    "bodies.puck.points.nose": [0.5, 0.0],
    "forces.drag.type": "linear_drag", "forces.drag.coefficient": 0.1,
    "wrench_topics.thruster.body": "puck", "wrench_topics.thruster.frame_id": "puck/nose",
    "script.nudge.time": 0.05, "script.nudge.body": "puck",
    "script.nudge.force": [0.0, -1.0], "script.nudge.duration": 0.1,
    "publish.odometry": True, "publish.markers": True, "publish.diagnostics": True,
}


@pytest.fixture
def ros():
    """An initialised context, an executor and a helper node that plays the outside world."""
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    executor = SingleThreadedExecutor(context=context)
    helper = rclpy.create_node("hecker_dynamics_test", context=context, namespace=NAMESPACE)
    executor.add_node(helper)
    nodes = []

    def start(overrides: dict) -> DynamicsNode:
        node = DynamicsNode(context=context, namespace=NAMESPACE, parameter_overrides=[
            Parameter(name, value=value) for name, value in overrides.items()])
        executor.add_node(node)
        nodes.append(node)
        return node

    yield SimpleNamespace(context=context, executor=executor, helper=helper, start=start)
    for node in nodes:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    helper.destroy_node()
    rclpy.shutdown(context=context)


def spin_until(ros, condition: Callable[[], bool], what: str, limit_s: float = 20.0) -> None:
    """Spin until ``condition()`` holds; fail (not hang) if it never does."""
    deadline = time.monotonic() + limit_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        ros.executor.spin_once(timeout_sec=0.01)


def spin_while(ros, condition: Callable[[], bool], spins: int) -> bool:
    """Spin at most ``spins`` times while ``condition()`` holds; True if it stopped holding."""
    for _ in range(spins):
        if not condition():
            return True
        ros.executor.spin_once(timeout_sec=0.01)
    return not condition()


def collect(ros, msg_type, topic: str, depth: int = 1000) -> list:
    received: list = []
    ros.helper.create_subscription(msg_type, topic, received.append, depth)
    return received


def set_clock(ros, publisher, node: DynamicsNode, t_ns: int) -> None:
    """Publish /clock = ``t_ns`` until the node's clock reads it."""
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = stamp_from_ns(t_ns)

    def arrived() -> bool:
        publisher.publish(msg)
        return node.get_clock().now().nanoseconds == t_ns
    spin_until(ros, arrived, f"the node's clock to read {t_ns / S} s")


def applied_wrench(stamp_ns, frame_id, body, source, point, force, torque, duration_ns):
    msg = AppliedWrench()
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_from_ns(stamp_ns)
    msg.header.frame_id = frame_id
    msg.body, msg.id = body, source
    msg.point.x, msg.point.y, msg.point.z = point
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = force
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = torque
    msg.duration.sec, msg.duration.nanosec = stamp_from_ns(duration_ns)
    return msg


def assert_pose_matches(msg: PoseStamped, state, frame_id: str) -> None:
    expected = pose_fields(state, frame_id, ns_from_stamp(msg.header.stamp.sec,
                                                          msg.header.stamp.nanosec))
    assert msg.header.frame_id == frame_id
    p, q = msg.pose.position, msg.pose.orientation
    assert (p.x, p.y, p.z) == pytest.approx(expected.pose.position, rel=1e-12, abs=1e-12)
    assert (q.x, q.y, q.z, q.w) == pytest.approx(expected.pose.orientation,
                                                 rel=1e-12, abs=1e-12)


def test_node_follows_sim_time_and_matches_the_offline_simulation(ros):
    node = ros.start({**PUCK, "use_sim_time": True})
    scene = scene_from_parameters(PUCK, "test")
    assert [b.name for b in node.scene.bodies] == ["puck"]
    clock = ros.helper.create_publisher(Clock, "/clock", 10)
    poses = collect(ros, PoseStamped, "puck/pose")
    twists = collect(ros, Twist, "puck/twist")
    odometry = collect(ros, Odometry, "puck/odom")
    markers = collect(ros, MarkerArray, "markers")
    diagnostics = collect(ros, DiagnosticArray, "diagnostics")
    wrench_out = ros.helper.create_publisher(AppliedWrench, "applied_wrench", 10)
    thruster_out = ros.helper.create_publisher(WrenchStamped, "thruster", 10)

    assert not node.runner.started
    # Every message counts below, so the node must know the test's subscriptions before it
    # publishes its first one (it publishes nothing until the clock runs).
    outputs = ("puck/pose", "puck/twist", "puck/odom", "markers", "diagnostics")
    spin_until(ros, lambda: all(node.count_subscribers(t) >= 1 for t in outputs),
               "the node to see the test's subscriptions")
    set_clock(ros, clock, node, T0)
    spin_until(ros, lambda: node.runner.started, "the simulation to start with the clock")
    assert node.sim.time_ns == T0

    good = [
        applied_wrench(T0 + 100_000_000, "puck", "puck", "kick", (0.5, 0.25, 0.0),
                       (0.0, 4.0, 0.0), (0.0, 0.0, 0.5), 200_000_000),
        applied_wrench(T0 + 600_000_000, "world", "puck", "tilted", (0.0, 0.0, 0.0),
                       (-1.0, 0.0, 5.0), (0.0, 0.0, 0.0), 100_000_000),  # force.z warns
    ]
    bad = [
        applied_wrench(T0, "puck", "puck", "nan", (0.0, 0.0, 0.0), (math.nan, 0.0, 0.0),
                       (0.0, 0.0, 0.0), 0),
        applied_wrench(T0, "world", "ghost", "x", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0), 0),
    ]
    thrust = WrenchStamped()
    thrust.header.stamp.sec, thrust.header.stamp.nanosec = stamp_from_ns(T0 + 300_000_000)
    thrust.wrench.force.x = 2.0
    spin_until(ros, lambda: wrench_out.get_subscription_count() >= 1
               and thruster_out.get_subscription_count() >= 1, "the node's subscriptions")
    for msg in good + bad:
        wrench_out.publish(msg)
    thruster_out.publish(thrust)
    spin_until(ros, lambda: node.runner.accepted + node.runner.rejected == 5,
               "the node to take the five inputs")
    assert (node.runner.accepted, node.runner.rejected) == (3, 2)

    periods = 50
    period = scene.publish_period_ns
    for k in range(1, periods + 1):
        set_clock(ros, clock, node, T0 + k * period)
        spin_until(ros, lambda k=k: node.sim.time_ns >= T0 + (k - 1) * period,
                   "the simulation to follow the clock")
    # The node's timer runs on the ROS clock from time 0, every publish period, so it
    # fires at T0 + periods * period too.
    spin_until(ros, lambda: node.sim.time_ns == T0 + periods * period,
               "the simulation to reach the clock")

    offline = Simulation(scene, start_ns=T0)
    for msg in good:
        offline.push(applied_wrench_to_command(msg, T0)[0])
    offline.push(wrench_stamped_to_command(thrust, scene.wrench_topics[0], T0)[0])
    expected = offline.play(scene.script, until_ns=periods * period)
    assert len(expected) == periods
    spin_until(ros, lambda: len(poses) >= len(expected) and len(twists) >= len(expected),
               "every pose and twist")
    assert [ns_from_stamp(m.header.stamp.sec, m.header.stamp.nanosec) for m in poses] == [
        s.time_ns for s in expected]
    # The node and the offline run take the same inputs but push them in another order
    # (the node gets the messages before the scripted nudge is due; offline they are pushed
    # first and the script as sim time reaches it), so the held forces may be summed in
    # another order: equal up to rounding, not to the bit.
    for pose, twist, snapshot in zip(poses, twists, expected):
        state = snapshot.bodies[0]
        assert_pose_matches(pose, state, "world")
        linear, angular = twist_fields(state, "body")
        assert (twist.linear.x, twist.linear.y, twist.linear.z) == pytest.approx(
            linear, rel=1e-12, abs=1e-12)
        assert twist.angular.z == pytest.approx(angular[2], rel=1e-12, abs=1e-12)
    # The messages acted: the scene's script alone ends elsewhere.
    script_only = Simulation(scene, start_ns=T0).play(scene.script, until_ns=periods * period)
    assert expected[-1].bodies[0].position != pytest.approx(
        script_only[-1].bodies[0].position)

    # Diagnostics come once a second of sim time: at the start and at T0 + 1 s.
    spin_until(ros, lambda: odometry and markers and len(diagnostics) >= 2,
               "odometry, markers, diagnostics")
    pose_at = {ns_from_stamp(p.header.stamp.sec, p.header.stamp.nanosec): p for p in poses}
    odom = odometry[0]
    assert odom.child_frame_id == "puck" and odom.header.frame_id == "world"
    same = pose_at[ns_from_stamp(odom.header.stamp.sec, odom.header.stamp.nanosec)]
    assert odom.pose.pose == same.pose
    assert {m.ns for m in markers[0].markers} == {"puck"}
    status = diagnostics[1].status[0]
    assert ns_from_stamp(diagnostics[1].header.stamp.sec,
                         diagnostics[1].header.stamp.nanosec) == T0 + S
    assert status.level == DiagnosticStatus.OK  # a byte field: bytes in rclpy
    values = {kv.key: kv.value for kv in status.values}
    assert {"sim_time", "steps", "energy", "step_wall_time"} <= set(values)
    assert values["commands_accepted"] == "3" and values["commands_rejected"] == "2"

    # The reset service restarts the scene at the current time.
    client = ros.helper.create_client(Trigger, "reset")
    assert client.wait_for_service(timeout_sec=10.0)
    future = client.call_async(Trigger.Request())
    spin_until(ros, future.done, "the reset service")
    now = T0 + periods * period
    assert future.result().success, future.result().message
    assert (node.sim.start_ns, node.sim.time_ns) == (now, now)

    # A clock that jumps back by more than a second restarts the scene at the new time.
    # The timer may need the clock to move on by a period after the jump before it fires.
    back = T0 - 10 * S
    for k in range(5):
        set_clock(ros, clock, node, back + k * period)
        if spin_while(ros, lambda k=k: node.sim.start_ns > back + k * period, spins=50):
            break
    assert back <= node.sim.start_ns <= back + 4 * period
    assert node.sim.time_ns >= node.sim.start_ns


def test_node_without_parameters_runs_the_default_scene(ros):
    node = ros.start({})
    default = load_scene(None)
    assert [b.name for b in node.scene.bodies] == [b.name for b in default.bodies]
    assert not node.options.lockstep
    poses = {body.name: collect(ros, PoseStamped, f"{body.name}/pose")
             for body in default.bodies}
    spin_until(ros, lambda: all(poses.values()), "a pose of every body (system clock)")
    for received in poses.values():
        assert received[0].header.frame_id == default.frame_id
        stamp = ns_from_stamp(received[0].header.stamp.sec, received[0].header.stamp.nanosec)
        assert (stamp - node.sim.start_ns) % default.publish_period_ns == 0


def test_the_node_refuses_parameter_changes_it_would_not_follow(ros):
    # Everything is read at start: a change accepted would leave the running world and the
    # way the node ticks as they were, so `ros2 param set` is told so instead.
    node = ros.start({"scene": "sample"})
    for name, value in (("scene", "ship"), ("use_sim_time", True), ("lockstep", True)):
        before = node.get_parameter(name).value
        result, = node.set_parameters([Parameter(name, value=value)])
        assert not result.successful and result.reason == refused_change([name])
        assert node.get_parameter(name).value == before
    assert not node.get_clock().ros_time_is_active
    assert [b.name for b in node.scene.bodies] == [b.name for b in load_scene("sample").bodies]


def test_lockstep_runs_the_scripted_duration_and_publishes_clock(ros):
    clocks = collect(ros, Clock, "/clock")
    node = ros.start({"lockstep": True})
    scene = node.scene
    poses = collect(ros, PoseStamped, f"{scene.bodies[0].name}/pose")
    spin_until(ros, node.finished.done, "the lockstep run to end", limit_s=120.0)
    assert node.finished.result() is True
    assert node.sim.time_ns == scene.duration_ns
    spin_until(ros, lambda: poses and ns_from_stamp(poses[-1].header.stamp.sec,
                                                    poses[-1].header.stamp.nanosec)
               == scene.duration_ns, "the last pose")
    spin_until(ros, lambda: clocks and ns_from_stamp(clocks[-1].clock.sec,
                                                     clocks[-1].clock.nanosec)
               == scene.duration_ns, "the last /clock")
    times = [ns_from_stamp(c.clock.sec, c.clock.nanosec) for c in clocks]
    assert times == sorted(times)

    offline = Simulation(scene, start_ns=0)
    by_time = {s.time_ns: s for s in offline.play(scene.script, until_ns=scene.duration_ns)}
    for pose in poses:
        snapshot = by_time[ns_from_stamp(pose.header.stamp.sec, pose.header.stamp.nanosec)]
        assert_pose_matches(pose, snapshot.bodies[0], scene.frame_id)


def _call(ros, srv_type, service: str, /, **fields):
    client = ros.helper.create_client(srv_type, service)
    assert client.wait_for_service(timeout_sec=10.0), service
    future = client.call_async(srv_type.Request(**fields))
    spin_until(ros, future.done, f"the {service} service")
    return future.result()


def test_spawn_body_and_delete_body_change_the_world_and_its_publishers(ros):
    """On the default scene with the test's /clock: a ball spawned gets its pose and twist
    publishers and moves as the run loop moves it; deleted, its publishers go. Bad calls
    answer with one line and change nothing."""
    from hecker_dynamics.srv import DeleteBody, SpawnBody

    from hecker_dynamics.ros.runner import Runner

    node = ros.start({"use_sim_time": True, "play_script": False})
    clock = ros.helper.create_publisher(Clock, "/clock", 10)
    set_clock(ros, clock, node, T0)
    spin_until(ros, lambda: node.runner.started, "the simulation to start with the clock")
    ball = "{shape: circle, radius: 0.15, mass: 1.0, position: [0.5, 4.0]}"
    answer = _call(ros, SpawnBody, "spawn_body", name="ball", body=ball)
    assert answer.success, answer.message
    assert [b.name for b in node.runner.scene.bodies] == ["ball", "left", "right"]
    ball_topic = f"{NAMESPACE}/ball/pose"
    spin_until(ros, lambda: node.count_publishers(ball_topic) == 1, "the ball's publisher")
    poses = collect(ros, PoseStamped, "ball/pose")
    spin_until(ros, lambda: node.count_subscribers(ball_topic) >= 1, "the subscription")
    period = node.scene.publish_period_ns
    for k in range(1, 11):
        set_clock(ros, clock, node, T0 + k * period)
        spin_until(ros, lambda k=k: node.sim.time_ns >= T0 + (k - 1) * period,
                   "the simulation to follow the clock")
    spin_until(ros, lambda: len(poses) >= 5, "the ball's poses")
    offline = Runner(load_scene(None), start_ns=T0, play_script=False)
    offline.spawn_body("ball", ball)
    by_time = {s.time_ns: s for s in offline.advance(T0 + 10 * period).snapshots}
    for pose in poses:
        stamp = ns_from_stamp(pose.header.stamp.sec, pose.header.stamp.nanosec)
        assert_pose_matches(pose, by_time[stamp].bodies[0], "world")

    for fields, reason in ((dict(name="ball", body=ball), "already a body"),
                           (dict(name="x", body="{shape: circle, radius: -1.0, mass: 1.0}"),
                            "parameter 'bodies.x.radius': must be positive")):
        answer = _call(ros, SpawnBody, "spawn_body", **fields)
        assert not answer.success and reason in answer.message and "\n" not in answer.message
    answer = _call(ros, DeleteBody, "delete_body", name="left")
    assert not answer.success and "spring 'link'" in answer.message
    answer = _call(ros, DeleteBody, "delete_body", name="ball")
    assert answer.success, answer.message
    spin_until(ros, lambda: node.count_publishers(ball_topic) == 0, "the ball's publisher to go")
    assert node.runner.sim.model.names == ("left", "right")


def test_joint_states_and_motor_commands_on_the_gears(ros):
    """The gears in lockstep: ``joint_states`` carries the offline run's joint states at
    each publish instant until the first motor command, and a ``std_msgs/Float64`` on
    ``small_axle/motor_speed`` sets the motor's speed and is recorded as an input event of
    kind MOTOR_SPEED."""
    from hecker_dynamics.msg import InputEvent
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from hecker_dynamics.ros.session import MOTOR_SPEED_EVENT

    states = collect(ros, JointState, "joint_states")
    events = collect(ros, InputEvent, "dynamics_node/input_events")
    node = ros.start({"scene": "gears", "lockstep": True})
    command = ros.helper.create_publisher(Float64, "small_axle/motor_speed", 10)

    def commanded() -> bool:
        command.publish(Float64(data=-1.0))
        return node.sim.model.joints.motor_speed["small_axle"] == -1.0
    spin_until(ros, commanded, "the motor command to arrive")
    spin_until(ros, node.finished.done, "the lockstep run to end", limit_s=120.0)
    spin_until(ros, lambda: any(e.kind == MOTOR_SPEED_EVENT for e in events),
               "the motor command's input event")
    event = next(e for e in events if e.kind == MOTOR_SPEED_EVENT)
    assert event.accepted and event.motor_speed.data == -1.0
    pushed = ns_from_stamp(event.header.stamp.sec, event.header.stamp.nanosec)
    scene = node.scene
    offline = Simulation(scene, start_ns=0)
    by_time = {s.time_ns: s for s in offline.play(scene.script, until_ns=pushed)}
    compared = 0
    for msg in states:
        stamp = ns_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        if stamp in by_time:
            joints = by_time[stamp].joints
            assert list(msg.name) == sorted(joints)
            assert list(msg.position) == [joints[n][0] for n in msg.name]
            assert list(msg.effort) == [joints[n][2] for n in msg.name]
            compared += 1
    assert compared > 0


def test_the_published_bytes_are_what_rclpy_serializes():
    # The node publishes its outputs as CDR bytes (hecker_dynamics.ros.cdr): rclpy's own
    # typesupport reads each as its message type and writes exactly those bytes again.
    kinds = set()
    for name in shipped_scenes():
        scene = dataclasses.replace(load_scene(name), publish_markers=True,
                                    publish_odometry=True, publish_tf=True,
                                    publish_contacts=True)
        outputs = SnapshotOutputs(scene, tf=True)
        snapshot = Simulation(scene).advance_to(S // 4)[-1]
        kind_of = output_topics(scene, tf=True)
        packed = SnapshotSerializer(outputs)(snapshot) + [
            (output.topic, serialize_output(output))
            for output in outputs.static(snapshot.time_ns)]
        # The sensors' readings go out beside the snapshots, at their own rates.
        readings = [output for _, output in Runner(scene).advance(S // 4).readings]
        packed += [(output.topic, serialize_output(output)) for output in readings]
        kind_of = {**kind_of, **{output.topic: output.kind for output in readings}}
        for topic, raw in packed:
            message = deserialize_message(raw, MESSAGE_TYPES[kind_of[topic]])
            assert serialize_message(message) == raw, (name, topic)
            kinds.add(kind_of[topic])
    assert len(kinds) == len(MESSAGE_TYPES) - 1  # all but the diagnostics


def test_cmd_vel_drives_the_robot_and_is_recorded(ros):
    """The robot without its script: a ``geometry_msgs/Twist`` on
    ``robot/cmd_vel`` reaches its drive and is recorded as an input event of kind CMD_VEL,
    and the drive's wheel forces move the robot forward."""
    from geometry_msgs.msg import Twist, Vector3
    from hecker_dynamics.msg import InputEvent

    from hecker_dynamics.ros.session import CMD_VEL_EVENT

    events = collect(ros, InputEvent, "dynamics_node/input_events")
    node = ros.start({"scene": "robot", "play_script": False})
    command = ros.helper.create_publisher(Twist, "robot/cmd_vel", 10)
    spin_until(ros, lambda: node.runner.started, "the simulation to start with the clock")

    def commanded() -> bool:
        command.publish(Twist(linear=Vector3(x=0.5)))
        drive = node.runner.drives.drives[0]
        return drive.command is not None and drive.command.linear_x == 0.5
    spin_until(ros, commanded, "the cmd_vel to arrive")
    spin_until(ros, lambda: any(e.kind == CMD_VEL_EVENT for e in events),
               "the cmd_vel's input event")
    event = next(e for e in events if e.kind == CMD_VEL_EVENT)
    assert event.accepted and event.cmd_vel.linear.x == 0.5
    assert event.topic == f"{NAMESPACE}/robot/cmd_vel"
    spin_until(ros, lambda: node.runner.sim.v[node.runner.sim.model.index["robot"], 0] > 0.1,
               "the robot to move forward")
