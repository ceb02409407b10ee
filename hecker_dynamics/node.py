"""The ROS 2 node ``dynamics_node``: thin rclpy glue over :class:`Simulation`.

Inputs are turned into commands by :mod:`hecker_dynamics.mapping`, the simulation steps in
fixed steps up to the ROS clock (or, in lockstep, as fast as it can while publishing
``/clock``), and every publish instant it passes becomes ``<body>/pose`` and
``<body>/twist`` messages stamped with its sim time. Every decision (what a message means,
when the clock jumped, how far the simulation lags) is made in ``mapping`` and
``ratelimit``; this module only moves data between them and rclpy.
"""
from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from typing import Any, Optional

import rclpy
import rclpy.logging
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped, Twist, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMessage
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from .commands import InputError, WrenchCommand
from .mapping import (DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN, NS_PER_S, Header,
                      MarkerFields, NodeOptions, Pose, TickAction, TwistFields, applied_wrench_to_command,
                      catch_up_cap, diagnostic_fields, due_script, header, lag_ns,
                      marker_fields, node_options, odometry_fields, plan_tick, pose_fields,
                      scene_for_node, stamp_from_ns, twist_fields, wrench_stamped_to_command)
from .msg import AppliedWrench
from .ratelimit import RateLimiter
from .scene import SceneError, WrenchTopic
from .simulation import DivergenceError, Simulation, Snapshot

NODE_NAME = "dynamics_node"
#: Keep-last depth of every publisher and subscription.
QUEUE_DEPTH = 10
#: Diagnostics are published at most this often, in sim time.
DIAGNOSTICS_PERIOD_NS = NS_PER_S


# ----------------------------------------------------------------------------- messages

def _fill_header(msg: Any, fields: Header) -> None:
    msg.stamp.sec = fields.sec
    msg.stamp.nanosec = fields.nanosec
    msg.frame_id = fields.frame_id


def _fill_pose(msg: Any, fields: Pose) -> None:
    msg.position.x, msg.position.y, msg.position.z = fields.position
    (msg.orientation.x, msg.orientation.y, msg.orientation.z,
     msg.orientation.w) = fields.orientation


def _fill_twist(msg: Any, fields: TwistFields) -> None:
    msg.linear.x, msg.linear.y, msg.linear.z = fields.linear
    msg.angular.x, msg.angular.y, msg.angular.z = fields.angular


def _marker(fields: MarkerFields) -> Marker:
    msg = Marker()
    _fill_header(msg.header, fields.header)
    msg.ns = fields.ns
    msg.id = fields.id
    msg.type = fields.type
    msg.action = fields.action
    _fill_pose(msg.pose, fields.pose)
    msg.scale.x, msg.scale.y, msg.scale.z = fields.scale
    msg.color.r, msg.color.g, msg.color.b, msg.color.a = fields.color
    msg.points = [Point(x=x, y=y, z=z) for x, y, z in fields.points]
    return msg


# ----------------------------------------------------------------------------- node

class DynamicsNode(Node):
    """Simulates a scene and publishes each body's pose and twist.

    ``node_kwargs`` go to :class:`rclpy.node.Node` (``context``, ``namespace``,
    ``parameter_overrides``, ...). Raises :class:`SceneError` when the parameters do not
    describe a valid scene.
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, automatically_declare_parameters_from_overrides=True,
                         **node_kwargs)
        for option in dataclasses.fields(NodeOptions):
            if not self.has_parameter(option.name):
                self.declare_parameter(option.name, option.default)
        params = {name: parameter.value
                  for name, parameter in self.get_parameters_by_prefix("").items()}
        source = f"parameters of {self.get_name()}"
        self.options = node_options(params, source)
        self.scene = scene_for_node(params, source)
        self.sim = Simulation(self.scene)
        self._cap, cap_warnings = catch_up_cap(self.options.max_catch_up_steps, self.scene)
        for line in cap_warnings:
            self.get_logger().warning(line)
        self._limiter = RateLimiter()
        self._bodies = {body.name: (index, body) for index, body in enumerate(self.scene.bodies)}
        self._started = self.options.lockstep
        self._last_tick_ns: Optional[int] = None
        self._script_index = 0
        self._halted: Optional[str] = None
        self._last_diagnostics_ns: Optional[int] = None
        self.commands_accepted = 0
        self.commands_rejected = 0
        #: Done (with True, or False after a divergence) when a lockstep run reaches the
        #: scene's duration; never done otherwise.
        self.finished = Future()
        self._create_publishers()
        self._create_inputs()
        self.create_service(Trigger, "reset", self._on_reset)
        if self.options.lockstep:
            self._clock_publisher = self.create_publisher(ClockMessage, "/clock", QUEUE_DEPTH)
            self._timer = self.create_timer(
                0.0, self._on_lockstep_tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
            self._publish_clock()
        else:
            self._timer = self.create_timer(self.scene.publish_period_ns / NS_PER_S,
                                            self._on_tick)
        self.get_logger().info(
            f"scene {self.scene.source}: bodies {', '.join(self._bodies)}; step "
            f"{self.scene.step_ns / NS_PER_S:g} s, publishing every "
            f"{self.scene.publish_period_ns / NS_PER_S:g} s"
            + (", lockstep" if self.options.lockstep else ""))

    # ----------------------------------------------------------------- wiring

    def _create_publishers(self) -> None:
        scene = self.scene
        self._pose_publishers = {
            name: self.create_publisher(PoseStamped, f"{name}/pose", QUEUE_DEPTH)
            for name in self._bodies}
        self._twist_publishers = {
            name: self.create_publisher(Twist, f"{name}/twist", QUEUE_DEPTH)
            for name in self._bodies}
        self._odometry_publishers = {
            name: self.create_publisher(Odometry, f"{name}/odom", QUEUE_DEPTH)
            for name in self._bodies} if scene.publish_odometry else {}
        self._marker_publisher = (self.create_publisher(MarkerArray, "markers", QUEUE_DEPTH)
                                  if scene.publish_markers else None)
        self._diagnostics_publisher = (
            self.create_publisher(DiagnosticArray, "diagnostics", QUEUE_DEPTH)
            if scene.publish_diagnostics else None)

    def _create_inputs(self) -> None:
        self.create_subscription(AppliedWrench, "applied_wrench", self._on_applied_wrench,
                                 QUEUE_DEPTH)
        for topic in self.scene.wrench_topics:
            self.create_subscription(
                WrenchStamped, topic.topic,
                lambda msg, topic=topic: self._on_wrench_stamped(msg, topic), QUEUE_DEPTH)

    # ----------------------------------------------------------------- state for tests

    @property
    def sim_time_ns(self) -> int:
        """Sim time of the current state."""
        return self.sim.time_ns

    @property
    def started(self) -> bool:
        """Whether the simulation runs (false until the ROS clock does)."""
        return self._started

    # ----------------------------------------------------------------- logging

    def _warn(self, key: str, message: str) -> None:
        line = self._limiter.line(key, message)
        if line is not None:
            self.get_logger().warning(line)

    # ----------------------------------------------------------------- inputs

    def _now_ns(self) -> int:
        """The time a message arrives at: sim time in lockstep, else the ROS clock."""
        return self.sim.time_ns if self.options.lockstep else self.get_clock().now().nanoseconds

    def _on_applied_wrench(self, msg: AppliedWrench) -> None:
        self._accept("applied_wrench",
                     lambda now_ns: applied_wrench_to_command(msg, now_ns))

    def _on_wrench_stamped(self, msg: WrenchStamped, topic: WrenchTopic) -> None:
        self._accept(topic.topic, lambda now_ns: wrench_stamped_to_command(msg, topic, now_ns))

    def _accept(self, topic: str,
                convert: Callable[[int], tuple[WrenchCommand, list[str]]]) -> None:
        """Convert and push one input message; bad input is counted and logged, never raised."""
        if not self._started:
            self.commands_rejected += 1
            self._warn(f"{topic}:early", f"input on '{topic}' ignored: the simulation starts "
                                         "with the ROS clock (waiting for /clock)")
            return
        try:
            command, warnings = convert(self._now_ns())
        except InputError as error:  # the message itself is bad (NaN, empty body, ...)
            self.commands_rejected += 1
            self._warn(f"{topic}:message", f"input on '{topic}' rejected: {error}")
            return
        for warning in warnings:
            self._warn(f"{topic}:out_of_plane", warning)
        try:
            self.sim.push(command)
        except InputError as error:  # the scene refuses it (unknown body or frame, stamp, ...)
            self.commands_rejected += 1
            self._warn(f"{topic}:scene", f"input on '{topic}' rejected: {error}")
            return
        self.commands_accepted += 1

    def _push_script(self, until_ns: int) -> None:
        if not self.options.play_script:
            return
        due, self._script_index = due_script(self.scene.script, self.sim.start_ns,
                                             self._script_index, until_ns)
        for command in due:
            try:
                self.sim.push(command)
            except InputError as error:
                self._warn("script", f"scripted input rejected: {error}")

    # ----------------------------------------------------------------- stepping

    def _restart(self, start_ns: int) -> None:
        self.sim.reset(start_ns)
        self._script_index = 0
        self._halted = None
        self._last_diagnostics_ns = None
        self._started = True

    def _on_tick(self) -> None:
        """Timer on the node clock (ROS time): step the simulation up to now."""
        now_ns = self.get_clock().now().nanoseconds
        action, reason = plan_tick(now_ns, self._last_tick_ns)
        if action is TickAction.WAIT:
            self._warn("clock", reason)
            return
        if action is TickAction.START:
            self.get_logger().info(reason)
        elif action is TickAction.RESTART:
            self._warn("clock_jump", reason)
        if action is not TickAction.ADVANCE:
            self._restart(now_ns)
        self._last_tick_ns = now_ns
        self._advance(now_ns)

    def _on_lockstep_tick(self) -> None:
        """Steady timer in lockstep: one publish period per tick, then ``/clock``."""
        if self.finished.done():
            return
        self._advance(self.sim.time_ns + self.scene.publish_period_ns)
        self._publish_clock()
        duration_ns = self.scene.duration_ns
        if self._halted is not None or (
                duration_ns > 0 and self.sim.time_ns - self.sim.start_ns >= duration_ns):
            self._timer.cancel()
            self.get_logger().info(
                f"lockstep run ended at {self.sim.time_ns / NS_PER_S:.9f} s")
            self.finished.set_result(self._halted is None)

    def _advance(self, target_ns: int) -> None:
        """Step towards ``target_ns`` (at most the catch-up cap) and publish what was passed."""
        if self._halted is not None:
            return
        sim = self.sim
        self._push_script(min(target_ns, sim.time_ns + self._cap * sim.step_ns))
        steps_before = sim.steps
        wall_start_ns = time.perf_counter_ns()
        try:
            snapshots = sim.advance_to(target_ns, max_steps=self._cap)
        except DivergenceError as error:
            self._halted = str(error)
            self.get_logger().error(f"{error}; halted until the 'reset' service is called")
            self._publish_diagnostics(0, 0, 0)
            return
        wall_ns = time.perf_counter_ns() - wall_start_ns
        for snapshot in snapshots:
            self._publish_snapshot(snapshot)
        lag = lag_ns(target_ns, sim.time_ns, sim.step_ns)
        if lag:
            self._warn("behind", f"the simulation is {lag / NS_PER_S:.3f} s behind the clock "
                                 f"(a tick takes at most {self._cap} steps: "
                                 "max_catch_up_steps)")
        last = self._last_diagnostics_ns
        if last is None or sim.time_ns - last >= DIAGNOSTICS_PERIOD_NS:
            self._publish_diagnostics(sim.steps - steps_before, wall_ns, lag)

    # ----------------------------------------------------------------- outputs

    def _publish_snapshot(self, snapshot: Snapshot) -> None:
        frame_id = self.scene.frame_id
        markers = MarkerArray()
        for state in snapshot.bodies:
            pose = PoseStamped()
            fields = pose_fields(state, frame_id, snapshot.time_ns)
            _fill_header(pose.header, fields.header)
            _fill_pose(pose.pose, fields.pose)
            self._pose_publishers[state.name].publish(pose)
            twist = Twist()
            _fill_twist(twist, twist_fields(state, self.scene.twist_frame))
            self._twist_publishers[state.name].publish(twist)
            if self._odometry_publishers:
                self._odometry_publishers[state.name].publish(
                    self._odometry(state, frame_id, snapshot.time_ns))
            if self._marker_publisher is not None:
                index, body = self._bodies[state.name]
                markers.markers.extend(
                    _marker(marker) for marker in
                    marker_fields(body, state, index, frame_id, snapshot.time_ns))
        if self._marker_publisher is not None:
            self._marker_publisher.publish(markers)

    @staticmethod
    def _odometry(state: Any, frame_id: str, stamp_ns: int) -> Odometry:
        fields = odometry_fields(state, frame_id, stamp_ns)
        msg = Odometry()
        _fill_header(msg.header, fields.header)
        msg.child_frame_id = fields.child_frame_id
        _fill_pose(msg.pose.pose, fields.pose)
        _fill_twist(msg.twist.twist, fields.twist)
        return msg

    def _publish_clock(self) -> None:
        msg = ClockMessage()
        msg.clock.sec, msg.clock.nanosec = stamp_from_ns(self.sim.time_ns)
        self._clock_publisher.publish(msg)

    def _publish_diagnostics(self, steps: int, wall_ns: int, lag: int) -> None:
        if self._diagnostics_publisher is None:
            return
        sim = self.sim
        self._last_diagnostics_ns = sim.time_ns
        if self._halted is not None:
            level, message = DIAGNOSTIC_ERROR, self._halted
        elif lag:
            level, message = DIAGNOSTIC_WARN, f"{lag / NS_PER_S:.3f} s behind the clock"
        else:
            level, message = DIAGNOSTIC_OK, "running"
        fields = diagnostic_fields(level, message, {
            "sim_time": sim.time_ns / NS_PER_S,
            "start_time": sim.start_ns / NS_PER_S,
            "steps": sim.steps,
            "step": sim.step_ns / NS_PER_S,
            "substeps": steps,
            "step_wall_time": wall_ns / steps / NS_PER_S if steps else 0.0,
            "energy": sim.snapshot().energy,
            "lag": lag / NS_PER_S,
            "commands_accepted": self.commands_accepted,
            "commands_rejected": self.commands_rejected,
        }, hardware_id=self.get_fully_qualified_name())
        status = DiagnosticStatus(
            level=bytes([fields.level]), name=fields.name, message=fields.message,
            hardware_id=fields.hardware_id,
            values=[KeyValue(key=key, value=value) for key, value in fields.values])
        array = DiagnosticArray(status=[status])
        _fill_header(array.header, header("", sim.time_ns))
        self._diagnostics_publisher.publish(array)

    # ----------------------------------------------------------------- reset service

    def _on_reset(self, request: Trigger.Request,
                  response: Trigger.Response) -> Trigger.Response:
        """Restart the scene at the current time (sim time in lockstep, else the ROS clock)."""
        start_ns = self._now_ns()
        if not self.options.lockstep and start_ns == 0:
            response.success = False
            response.message = "the ROS clock is not running yet (waiting for /clock)"
            return response
        self._restart(start_ns)
        if not self.options.lockstep:
            self._last_tick_ns = start_ns
        response.success = True
        response.message = f"scene restarted at {start_ns / NS_PER_S:.9f} s"
        self.get_logger().info(response.message)
        return response


def main(args: Optional[list[str]] = None) -> int:
    """Entry point of ``ros2 run hecker_dynamics dynamics_node``; returns the exit status."""
    rclpy.init(args=args)
    node = None
    try:
        node = DynamicsNode()
        rclpy.spin_until_future_complete(node, node.finished)
        return 0 if not node.finished.done() or node.finished.result() else 1
    except SceneError as error:
        rclpy.logging.get_logger(NODE_NAME).fatal(str(error))
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
