"""The ROS 2 node ``dynamics_node``: thin rclpy glue over the :class:`~hecker_dynamics.World`
that its :class:`~.runner.Runner` drives.

Inputs are turned into commands by :mod:`.fields`, the simulation steps in fixed steps up
to the ROS clock (or, in lockstep, as fast as it can while publishing ``/clock``), and every
publish instant it passes becomes ``<body>/pose`` and ``<body>/twist`` messages stamped with
its sim time. Every decision (what a message means, when the clock jumped, how far the
simulation lags) is made in the other modules of :mod:`hecker_dynamics.ros`; this module
only moves data between them and rclpy.
"""
from __future__ import annotations

import dataclasses
import functools
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Optional

import rclpy
import rclpy.logging
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, Twist, WrenchStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.executors import (
    ConditionReachedException,
    ExternalShutdownException,
    ShutdownException,
    SingleThreadedExecutor,
)
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMessage
from sensor_msgs.msg import Imu, JointState, LaserScan
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from ..dynamics.simulation import Snapshot
from ..msg import AppliedWrench, ContactEvent, InputEvent, Keyframe, SessionInfo, WorldEvent
from ..scene.load import SceneError, WrenchTopic
from ..srv import DeleteBody, SetBodyState, SpawnBody, Step
from .cdr import SnapshotSerializer, serialize_output
from .cmd_vel import CmdVelTopic, cmd_vel_topics
from .diagnostics import DiagnosticFields
from .fields import NS_PER_S, Header, header, stamp_from_ns
from .joint_states import MotorTopic, motor_topics
from .lifecycle import HANDLED_SIGNALS, Shutdown, serve, tick_every
from .names import (
    APPLIED_WRENCH_TOPIC,
    CLOCK_QOS,
    CLOCK_TOPIC,
    COMMAND_QOS,
    DELETE_BODY_SERVICE,
    DIAGNOSTICS_TOPIC,
    INPUT_EVENTS_QOS,
    INPUT_EVENTS_TOPIC,
    KEYFRAME_QOS,
    KEYFRAME_TOPIC,
    NODE_NAME,
    PAUSE_SERVICE,
    RESET_SERVICE,
    RESUME_SERVICE,
    SESSION_QOS,
    SESSION_TOPIC,
    SET_BODY_STATE_SERVICE,
    SPAWN_BODY_SERVICE,
    STEP_SERVICE,
    WORLD_EVENTS_QOS,
    WORLD_EVENTS_TOPIC,
    Durability,
    QosSpec,
    Reliability,
    output_qos,
)
from .outputs import OutputFields, OutputKind, SnapshotOutputs, output_topics
from .ratelimit import RateLimiter
from .runner import (
    LogLine,
    NodeOptions,
    Runner,
    Tick,
    TickAction,
    catch_up_cap,
    next_tick_in,
    node_setup,
    plan_tick,
    refused_change,
    tick_target,
)
from .session import (
    APPLIED_WRENCH_EVENT,
    CMD_VEL_EVENT,
    MOTOR_SPEED_EVENT,
    InputEventFields,
    KeyframeFields,
    SessionFields,
    WorldEventFields,
)

__all__ = ["MESSAGE_TYPES", "qos_profile", "DynamicsNode", "run_callbacks", "main"]

MESSAGE_TYPES = {
    OutputKind.POSE: PoseStamped, OutputKind.TWIST: Twist, OutputKind.ODOMETRY: Odometry,
    OutputKind.MARKERS: MarkerArray, OutputKind.DIAGNOSTICS: DiagnosticArray,
    OutputKind.TF: TFMessage, OutputKind.JOINT_STATE: JointState,
    OutputKind.LASER_SCAN: LaserScan, OutputKind.IMU: Imu,
    OutputKind.OCCUPANCY_GRID: OccupancyGrid, OutputKind.CONTACT_EVENT: ContactEvent,
}


def qos_profile(spec: QosSpec) -> QoSProfile:
    """The rclpy profile of a :class:`QosSpec`: keep-last, the rest rmw's defaults."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=spec.depth,
        reliability={Reliability.RELIABLE: ReliabilityPolicy.RELIABLE,
                     Reliability.BEST_EFFORT: ReliabilityPolicy.BEST_EFFORT}[spec.reliability],
        durability={Durability.VOLATILE: DurabilityPolicy.VOLATILE,
                    Durability.TRANSIENT_LOCAL: DurabilityPolicy.TRANSIENT_LOCAL}[spec.durability])


# ----------------------------------------------------------------------------- messages
# The outputs are published as CDR bytes (:mod:`.cdr`); what is built here are the
# messages published now and then: the session records and the diagnostics. rosidl's
# Python setters check types: floats for float64 fields, ints for integer fields, and
# bytes of length one for ``byte`` fields (DiagnosticStatus.level).

def _fill_header(msg: Any, fields: Header) -> None:
    msg.stamp.sec = fields.sec
    msg.stamp.nanosec = fields.nanosec
    msg.frame_id = fields.frame_id


def _diagnostic_array(fields: DiagnosticFields, head: Header) -> DiagnosticArray:
    status = DiagnosticStatus(
        level=bytes([fields.level]), name=fields.name, message=fields.message,
        hardware_id=fields.hardware_id,
        values=[KeyValue(key=key, value=value) for key, value in fields.values])
    array = DiagnosticArray(status=[status])
    _fill_header(array.header, head)
    return array


def _session_info(fields: SessionFields) -> SessionInfo:
    msg = SessionInfo(**fields.message_values())
    _fill_header(msg.header, header(fields.frame_id, fields.start_ns))
    return msg


def _keyframe(fields: KeyframeFields) -> Keyframe:
    msg = Keyframe(session=fields.session, steps=fields.steps, next_event=fields.next_event,
                   bodies=list(fields.bodies), q=list(fields.q), v=list(fields.v),
                   state=fields.state)
    _fill_header(msg.header, header("", fields.stamp_ns))
    return msg


def _input_event(fields: InputEventFields) -> InputEvent:
    msg = InputEvent(session=max(fields.session, 0), sequence=fields.sequence,
                     topic=fields.topic, kind=fields.kind, accepted=fields.accepted,
                     reason=fields.reason)
    _fill_header(msg.header, header("", fields.stamp_ns))
    msg.arrival.sec, msg.arrival.nanosec = stamp_from_ns(fields.arrival_ns)
    if fields.kind == APPLIED_WRENCH_EVENT:
        msg.applied_wrench = fields.message
    elif fields.kind == MOTOR_SPEED_EVENT:
        msg.motor_speed = fields.message
    elif fields.kind == CMD_VEL_EVENT:
        msg.cmd_vel = fields.message
    else:
        msg.wrench_stamped = fields.message
    return msg


def _world_event(fields: WorldEventFields) -> WorldEvent:
    msg = WorldEvent(session=max(fields.session, 0), sequence=fields.sequence,
                     kind=int(fields.kind), body=fields.body, values=list(fields.values),
                     time_ns=fields.time_ns, accepted=fields.accepted, reason=fields.reason,
                     spec=fields.spec, collisions=list(fields.collisions))
    _fill_header(msg.header, header("", fields.stamp_ns))
    return msg


#: Session records: their topic, message builder, type and QoS (reliable and
#: transient_local, so a recorder that starts after them still receives the latest).
RECORD_TOPICS: dict[type, tuple[str, Callable[[Any], Any], type, QosSpec]] = {
    SessionFields: (SESSION_TOPIC, _session_info, SessionInfo, SESSION_QOS),
    KeyframeFields: (KEYFRAME_TOPIC, _keyframe, Keyframe, KEYFRAME_QOS),
    InputEventFields: (INPUT_EVENTS_TOPIC, _input_event, InputEvent, INPUT_EVENTS_QOS),
    WorldEventFields: (WORLD_EVENTS_TOPIC, _world_event, WorldEvent, WORLD_EVENTS_QOS),
}


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
        for option in dataclasses.fields(NodeOptions):  # so that `ros2 param` shows them
            if not self.has_parameter(option.name):
                self.declare_parameter(option.name, option.default)
        # Every parameter the node holds: the overrides (declared above), the options,
        # use_sim_time and start_type_description_service (declared by rclpy); the scene
        # reader skips the node's own (scene.NODE_PARAMETERS).
        params = {name: parameter.value
                  for name, parameter in self.get_parameters_by_prefix("").items()}
        self.options, self.scene = node_setup(params, f"parameters of {self.get_name()}")
        self.add_on_set_parameters_callback(self._refuse_parameter_change)
        cap, cap_warnings = catch_up_cap(self.options.max_catch_up_steps, self.scene)
        for line in cap_warnings:
            self.get_logger().warning(line)
        #: Held by each callback and tick where they run in threads of their own
        #: (:meth:`tick_thread`), so that one never sees the other half done.
        self.lock = threading.Lock()
        self._record_publishers: dict[type, Any] = {}
        if self.options.record_session:
            for kind, (topic, _, msgtype, qos) in RECORD_TOPICS.items():
                self._record_publishers[kind] = self._publisher(msgtype, topic, qos)
        self.runner = Runner(self.scene, play_script=self.options.play_script, max_steps=cap,
                             started=self.options.lockstep,
                             hardware_id=self.get_fully_qualified_name(),
                             record=self.options.record_session,
                             keyframe_period_ns=round(self.options.keyframe_period * NS_PER_S),
                             lockstep=self.options.lockstep)
        self._limiter = RateLimiter()
        #: The node clock's time in ns (the ROS clock; the system's in the tick thread).
        self._clock_ns: Callable[[], int] = self._ros_clock_ns
        self._last_tick_ns: Optional[int] = None
        self._wrench_topic_names: dict[str, str] = {}
        #: Done (with True, or False after a divergence) when a lockstep run reaches the
        #: scene's duration; never done otherwise.
        self.finished = Future()
        self._outputs = SnapshotOutputs(self.scene, base=self.runner.base_scene)
        self._serialize = SnapshotSerializer(self._outputs)
        self._publishers_by_topic: dict[str, Any] = {}
        #: Per output topic, its publisher's publish of serialized bytes (_add_output).
        self._publish_bytes: dict[str, Callable[[bytes], None]] = {}
        for topic, output in output_topics(self.scene).items():
            self._add_output(output, topic)
        self._applied_wrench = self._command_subscription(
            AppliedWrench, APPLIED_WRENCH_TOPIC, self._on_applied_wrench)
        for wrench_topic in self.scene.wrench_topics:
            subscription = self._command_subscription(
                WrenchStamped, wrench_topic.topic,
                functools.partial(self._on_wrench_stamped, topic=wrench_topic))
            self._wrench_topic_names[wrench_topic.name] = subscription.topic_name
        for motor in motor_topics(self.scene):
            subscription = self._command_subscription(
                Float64, motor.topic, functools.partial(self._on_motor_speed, motor=motor))
            self._wrench_topic_names[motor.topic] = subscription.topic_name
        for driven in cmd_vel_topics(self.scene):
            subscription = self._command_subscription(
                Twist, driven.topic, functools.partial(self._on_cmd_vel, driven=driven))
            self._wrench_topic_names[driven.topic] = subscription.topic_name
        self.create_service(Trigger, RESET_SERVICE, self._on_reset)
        self.create_service(Trigger, PAUSE_SERVICE, self._on_pause)
        self.create_service(Trigger, RESUME_SERVICE, self._on_resume)
        self.create_service(Step, STEP_SERVICE, self._on_step)
        self.create_service(SetBodyState, SET_BODY_STATE_SERVICE, self._on_set_body_state)
        self.create_service(SpawnBody, SPAWN_BODY_SERVICE, self._on_spawn_body)
        self.create_service(DeleteBody, DELETE_BODY_SERVICE, self._on_delete_body)
        if self.options.lockstep:
            self._publish_static()
            self._clock_publisher = self._publisher(ClockMessage, CLOCK_TOPIC, CLOCK_QOS)
            # A zero period: the timer is always ready, so the run goes as fast as it can
            # while the executor still serves subscriptions and the reset service.
            self._timer = self.create_timer(
                0.0, self._on_lockstep_tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
            self._publish_clock()
            self._publish_records()  # the lockstep session starts now
        else:
            self._timer = self.create_timer(self.scene.publish_period_ns / NS_PER_S,
                                            self._on_tick)
        self.get_logger().info(
            f"scene {self.scene.source}: bodies "
            f"{', '.join(b.name for b in self.scene.bodies)}; step "
            f"{self.scene.step_ns / NS_PER_S:g} s, publishing every "
            f"{self.scene.publish_period_ns / NS_PER_S:g} s"
            + (", lockstep" if self.options.lockstep else ""))

    @property
    def sim(self) -> Any:
        """The simulation under the runner's World now (a spawn, a delete or a restart
        replaces it)."""
        return self.runner.sim

    # ----------------------------------------------------------------- logging

    def _warn(self, key: str, message: str) -> None:
        line = self._limiter.line(key, message)
        if line is not None:
            self.get_logger().warning(line)

    def _log(self, lines: list[LogLine]) -> None:
        for line in lines:
            self._warn(line.key, line.message)

    # ----------------------------------------------------------------- inputs

    def _now_ns(self) -> int:
        """The time a message arrives at: sim time in lockstep, else the ROS clock."""
        return self.sim.time_ns if self.options.lockstep else self._clock_ns()

    def _ros_clock_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_applied_wrench(self, msg: AppliedWrench) -> None:
        self._log(self.runner.accept(self._applied_wrench.topic_name, msg, self._now_ns()))
        self._publish_records()

    def _on_wrench_stamped(self, msg: WrenchStamped, topic: WrenchTopic) -> None:
        self._log(self.runner.accept(self._wrench_topic_names[topic.name], msg, self._now_ns(),
                                     topic))
        self._publish_records()

    def _on_motor_speed(self, msg: Float64, motor: MotorTopic) -> None:
        self._log(self.runner.accept(self._wrench_topic_names[motor.topic], msg,
                                     self._now_ns(), motor))
        self._publish_records()

    def _on_cmd_vel(self, msg: Twist, driven: CmdVelTopic) -> None:
        self._log(self.runner.accept(self._wrench_topic_names[driven.topic], msg,
                                     self._now_ns(), driven))
        self._publish_records()

    # ----------------------------------------------------------------- stepping

    def _on_tick(self) -> None:
        """Each publish period on the node clock (ROS time): step the simulation up to now."""
        now_ns = self._clock_ns()
        action, reason = plan_tick(now_ns, self._last_tick_ns)
        if action is TickAction.WAIT:
            self._warn("clock", reason)
            return
        if action is TickAction.START:
            self.get_logger().info(reason)
            self.runner.restart(now_ns, "start")
            self._publish_static()
        elif action is TickAction.RESTART:
            self._warn("clock_jump", reason)
            self.runner.restart(now_ns, "clock jump")
        self._last_tick_ns = now_ns
        self._advance(tick_target(now_ns, self.sim.start_ns, self.scene.publish_period_ns))

    def tick_thread(self, stopped: Callable[[], bool],
                    woken: threading.Event) -> Optional[Callable[[], None]]:
        """Take the ticks off the executor, to a thread of their own that runs the returned
        function (:func:`tick_every` until ``stopped()``; ``woken`` ends its wait), each
        tick holding :attr:`lock`; destroys the node's timer. An rclpy timer costs a tick
        two turns of the executor (:mod:`.lifecycle`). None, and the timer stays, in
        lockstep and on ROS time (``use_sim_time``), whose timer follows ``/clock``."""
        if self.options.lockstep or self.get_clock().ros_time_is_active:
            return None
        self.destroy_timer(self._timer)
        # The ROS clock without ROS time reads the system time, CLOCK_REALTIME
        # (rcl_get_ros_time, rcutils_system_time_now), as time.time_ns does, which spares
        # the Time object that Clock.now builds (30 us a tick in the running node); a
        # change of use_sim_time is refused (_refuse_parameter_change).
        self._clock_ns = time.time_ns

        def tick() -> Optional[float]:
            with self.lock:
                self._on_tick()
                return self._until_next_tick()

        def ticks() -> None:
            tick_every(self.scene.publish_period_ns / NS_PER_S, tick, stopped, woken)
        return ticks

    def _until_next_tick(self) -> Optional[float]:
        """Seconds from the last tick's clock reading to the next tick's (:func:`next_tick_in`),
        None before the start."""
        if self._last_tick_ns is None:
            return None
        return next_tick_in(self._last_tick_ns, self.sim.start_ns,
                            self.scene.publish_period_ns) / NS_PER_S

    def _on_lockstep_tick(self) -> None:
        """Steady timer in lockstep: one publish period per tick, then ``/clock``."""
        if self.finished.done() or not self.context.ok():
            return
        self._advance(self.sim.time_ns + self.scene.publish_period_ns)
        self._publish_clock()
        if self.runner.done():
            self._timer.cancel()
            self.get_logger().info(
                f"lockstep run ended at {self.sim.time_ns / NS_PER_S:.9f} s")
            self.finished.set_result(self.runner.halted is None)

    def _advance(self, target_ns: int) -> None:
        """Step towards ``target_ns`` (at most the catch-up cap) and publish what was passed.

        Nothing is published once the context is shut down (by another owner of it: this
        node's own signal handlers only end the callbacks after the one that runs).
        """
        tick = self.runner.advance(target_ns)
        if not self.context.ok():
            return
        self._publish_records()
        for line in tick.script_errors:
            self._warn("script", line)
        if tick.diverged is not None:
            self.get_logger().error(
                f"{tick.diverged}; halted until the 'reset' service is called")
        self._publish_tick(tick)
        if tick.lag:
            self._warn("behind", f"the simulation is {tick.lag / NS_PER_S:.3f} s behind the "
                                 f"clock (a tick takes at most {self.runner.max_steps} steps: "
                                 "max_catch_up_steps)")
        if tick.diagnostics is not None:
            self._publishers_by_topic[DIAGNOSTICS_TOPIC].publish(
                _diagnostic_array(tick.diagnostics, header("", self.sim.time_ns)))

    def _refuse_parameter_change(self, parameters: list[Parameter]) -> SetParametersResult:
        """Every change, with the reason ``ros2 param set`` prints (:func:`refused_change`)."""
        return SetParametersResult(successful=False,
                                   reason=refused_change([p.name for p in parameters]))

    # ----------------------------------------------------------------- outputs

    def _publish_records(self) -> None:
        """Publish the session records the runner made (dropped with record_session off)."""
        for record in self.runner.take_records():
            _, build, _, _ = RECORD_TOPICS[type(record)]
            self._record_publishers[type(record)].publish(build(record))
        if self._outputs.scene is not self.runner.scene:
            self._follow_world()

    def _follow_world(self) -> None:
        """Outputs for the world that runs now, after a spawn, a delete, or a restart that
        undid them: publishers of the bodies gone are destroyed, the new bodies' created,
        ``DELETE`` markers take the bodies gone out of RViz, and ``/tf_static`` is sent
        again with the named points of every body there is."""
        scene = self.runner.scene
        previous, self._outputs = self._outputs, SnapshotOutputs(
            scene, base=self.runner.base_scene)
        self._serialize = SnapshotSerializer(self._outputs)
        topics = output_topics(scene)
        for topic in [t for t in self._publishers_by_topic if t not in topics]:
            del self._publish_bytes[topic]
            self.destroy_publisher(self._publishers_by_topic.pop(topic))
        for topic, kind in topics.items():
            if topic not in self._publishers_by_topic:
                self._add_output(kind, topic)
        for output in self._outputs.markers_gone(previous, self.sim.time_ns):
            self._publish(output)
        self._publish_static()

    # rclpy gives every publisher and subscription default QoS-event handlers unless told
    # otherwise. Each is a waitable that the executor adds to its wait set, counts and
    # checks on every wake; with three topics a body they cost more than the publishing
    # itself (py-spy on Jazzy). The peer with an incompatible profile is still warned by
    # its own handlers.

    def _publisher(self, msgtype: type, topic: str, qos: QosSpec) -> Any:
        """A publisher without rclpy's default QoS-event handlers."""
        return self.create_publisher(
            msgtype, topic, qos_profile(qos),
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

    def _command_subscription(self, msgtype: type, topic: str,
                              callback: Callable[[Any], None]) -> Any:
        """A subscription to commands, without rclpy's default QoS-event handlers."""
        return self.create_subscription(
            msgtype, topic, callback, qos_profile(COMMAND_QOS),
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))

    def _add_output(self, kind: OutputKind, topic: str) -> None:
        """The publisher of an output topic, and its publish of bytes: what rclpy's
        ``Publisher.publish`` calls for bytes (``handle.publish_raw``) without the type
        checks and the handle's context that ``publish`` wraps it in, about 3 of the 7 us
        a message took in the running node. The node's lock keeps a publisher from being
        destroyed while it publishes, as the handle's context would."""
        publisher = self._publisher(MESSAGE_TYPES[kind], topic, output_qos(topic))
        self._publishers_by_topic[topic] = publisher
        self._publish_bytes[topic] = publisher.handle.publish_raw

    def _publish(self, output: OutputFields) -> None:
        self._publish_bytes[output.topic](serialize_output(output))

    def _publish_tick(self, tick: Tick) -> None:
        """The snapshots and sensor readings the tick passed, in stamp order."""
        publish = self._publish_bytes
        for _, item in tick.in_order():
            if isinstance(item, Snapshot):
                for topic, data in self._serialize(item):
                    publish[topic](data)
            else:
                self._publish(item)

    def _publish_static(self) -> None:
        """``/tf_static`` at the start of the run, stamped with it as the replay stamps it;
        latched (transient_local), so once is enough for every later subscriber."""
        for output in self._outputs.static(self.sim.time_ns):
            self._publish(output)

    def _publish_clock(self) -> None:
        msg = ClockMessage()
        msg.clock.sec, msg.clock.nanosec = stamp_from_ns(self.sim.time_ns)
        self._clock_publisher.publish(msg)

    # ----------------------------------------------------------------- reset service

    def _on_reset(self, request: Trigger.Request,
                  response: Trigger.Response) -> Trigger.Response:
        """Restart the scene at the current time (sim time in lockstep, else the ROS clock)."""
        start_ns = self._now_ns()
        if not self.options.lockstep and start_ns == 0:
            response.success = False
            response.message = "the ROS clock is not running yet (waiting for /clock)"
            return response
        self.runner.restart(start_ns, "reset")
        self._publish_records()
        if not self.options.lockstep:
            self._last_tick_ns = start_ns
        response.success = True
        response.message = f"scene restarted at {start_ns / NS_PER_S:.9f} s"
        self.get_logger().info(response.message)
        return response


    # ----------------------------------------------------------------- world services

    def _answer(self, record: WorldEventFields, response: Any, done: str) -> Any:
        """Publish the change's record and answer the call with its outcome."""
        self._publish_records()
        response.success = record.accepted
        response.message = done if record.accepted else record.reason
        # rclpy keys a logger's per-call-site context on the calling line and refuses a
        # second severity there, so each severity gets its own line.
        if record.accepted:
            self.get_logger().info(response.message)
        else:
            self.get_logger().warning(response.message)
        return response

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        return self._answer(self.runner.pause(), response,
                            f"paused at {self.sim.time_ns / NS_PER_S:.9f} s")

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        return self._answer(self.runner.resume(self._now_ns()), response,
                            f"resumed at {self.sim.time_ns / NS_PER_S:.9f} s")

    def _on_step(self, request: Step.Request, response: Step.Response) -> Any:
        record, tick = self.runner.step(int(request.steps))
        self._publish_tick(tick)
        return self._answer(record, response, f"stepped {request.steps} step(s) to "
                                              f"{self.sim.time_ns / NS_PER_S:.9f} s")

    def _on_set_body_state(self, request: SetBodyState.Request,
                           response: SetBodyState.Response) -> Any:
        record = self.runner.set_body_state(request.body, (
            request.x, request.y, request.angle, request.vx, request.vy, request.omega))
        return self._answer(record, response, f"moved '{request.body}' at "
                                              f"{self.sim.time_ns / NS_PER_S:.9f} s")

    def _on_spawn_body(self, request: SpawnBody.Request, response: SpawnBody.Response) -> Any:
        record = self.runner.spawn_body(request.name, request.body, list(request.collisions))
        return self._answer(record, response, f"spawned '{request.name}' at "
                                              f"{self.sim.time_ns / NS_PER_S:.9f} s")

    def _on_delete_body(self, request: DeleteBody.Request,
                        response: DeleteBody.Response) -> Any:
        record = self.runner.delete_body(request.name)
        return self._answer(record, response, f"deleted '{request.name}' at "
                                              f"{self.sim.time_ns / NS_PER_S:.9f} s")


def run_callbacks(executor: SingleThreadedExecutor, stopped: Callable[[], bool],
                  lock: threading.Lock) -> None:
    """Run the executor's callbacks one by one, each holding ``lock``, until ``stopped()``,
    which is checked before each wait and whenever a wait returns (``wake`` ends a wait).
    Waits without a timeout: ``spin_once(timeout_sec)`` would create a timer for it at
    every turn."""
    while True:
        try:
            handler, _, _ = executor.wait_for_ready_callbacks(None, None, stopped)
        except (ConditionReachedException, ShutdownException):
            return
        with lock:
            handler()
        handler.result()  # raises what the callback raised, as spin_once does


def main(args: Optional[list[str]] = None) -> int:
    """Entry point of ``ros2 run hecker_dynamics dynamics_node``; returns the exit status.

    The callbacks, and on the system clock the ticks, run in worker threads (:func:`serve`);
    SIGINT and SIGTERM end them after the callback or tick that runs (:class:`Shutdown`),
    then the node is destroyed and the context shut down: exit status 0 and one info line. A
    lockstep run that diverged ends with 1, a scene that does not load with 1 and its error.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = Shutdown()
    previous = {signum: signal.signal(signum, stop.request) for signum in HANDLED_SIGNALS}
    logger = rclpy.logging.get_logger(NODE_NAME)
    node = None
    try:
        node = DynamicsNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        context = node.context
        woken = threading.Event()

        def stopped() -> bool:
            return stop.requested or node.finished.done() or not context.ok()

        def callbacks() -> None:
            run_callbacks(executor, stopped, node.lock)
        ticks = node.tick_thread(stopped, woken)

        def wake() -> None:
            executor.wake()
            woken.set()
        stop.wake = wake
        try:
            serve([callbacks] if ticks is None else [callbacks, ticks], stop)
        except ExternalShutdownException:
            pass
        except rclpy_implementation.RCLError:
            if context.ok():  # a real failure, not a publish racing a shutdown
                raise
        finished = node.finished.result() if node.finished.done() else None
        status, message = stop.outcome(stop.reason(lockstep_result=finished,
                                                   context_ok=context.ok()))
        if message:
            logger.info(message)
        return status
    except SceneError as error:
        logger.fatal(str(error))
        return 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for signum, handler in previous.items():
            signal.signal(signum, handler)


if __name__ == "__main__":
    sys.exit(main())
