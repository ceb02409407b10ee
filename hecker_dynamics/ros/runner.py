"""The node's run loop without ROS: options, clock decisions and the :class:`Runner`.

The clock decisions of the node (when to start, when the ROS clock jumped so far that the
simulation restarts, how far it lags) live here as plain functions of nanoseconds, and the
:class:`Runner` is the loop that both the rclpy node and the offline replay drive.
"""
from __future__ import annotations

import array
import dataclasses
import enum
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple, Optional, Union

from .._version import __version__
from ..drives.control import DriveSet, advance_with_drives
from ..dynamics.simulation import DivergenceError, Simulation, Snapshot
from ..scene.commands import InputError, WrenchCommand
from ..scene.fingerprint import scene_fingerprint
from ..scene.load import (
    NODE_PARAMETERS,
    Scene,
    SceneError,
    WrenchTopic,
    check_scene_request,
    load_scene,
    scene_from_parameters,
)
from ..scene.parameters import seconds_text
from ..scene.world import EditKind, WorldEdit
from ..sensors.schedule import SensorSet
from ..sensors.touch import Touches
from ..world import World
from .cmd_vel import CmdVelTopic, cmd_vel_topics, take_cmd_vel
from .diagnostics import DiagnosticFields, diagnostics_due, simulation_diagnostics
from .fields import NS_PER_S, applied_wrench_to_command, wrench_stamped_to_command
from .joint_states import MotorTopic, motor_topics, set_motor_speed
from .names import APPLIED_WRENCH_TOPIC, CLOCK_TOPIC
from .outputs import OutputFields, output_topics, reading_output, touch_output
from .session import (
    APPLIED_WRENCH_EVENT,
    CMD_VEL_EVENT,
    MOTOR_SPEED_EVENT,
    WRENCH_STAMPED_EVENT,
    InputEventFields,
    KeyframeFields,
    SessionFields,
    WorldChange,
    WorldEventFields,
    decode_state,
    encode_state,
)

__all__ = ["InputSource", "NodeOptions", "node_options", "scene_for_node", "due_script",
           "catch_up_cap", "TickAction", "plan_tick", "tick_target",
           "next_tick_in", "TICK_MARGIN_NS", "lag_ns", "plain_parameters", "node_setup",
           "refused_change", "check_wrench_topics", "LogLine", "Tick", "Runner"]

#: A change of the ROS clock between two timer ticks larger than this, forwards or
#: backwards, is a jump: the simulation restarts at the new time instead of stepping there.
CLOCK_JUMP_NS = NS_PER_S
#: How long after a publish instant the node's tick thread wakes (ns): the node reads its
#: clock a little after the thread's own reading (the lock, the calls), so a wake due at
#: the instant itself could read a time just before it.
TICK_MARGIN_NS = 100_000
#: The longest keyframe period accepted (a day of sim time).
MAX_KEYFRAME_PERIOD_S = 86400.0
#: The most steps one call of the step service takes.
MAX_SERVICE_STEPS = 1_000_000
#: A sim time no session reaches (about 292 years).
FAR_FUTURE_NS = 2 ** 63 - 1

#: What the runner records for the node to publish.
Record = Union[SessionFields, InputEventFields, WorldEventFields, KeyframeFields]
#: Where an input message other than an ``AppliedWrench`` came from.
InputSource = Union[WrenchTopic, MotorTopic, CmdVelTopic]

# ----------------------------------------------------------------------------- node setup

@dataclasses.dataclass(frozen=True)
class NodeOptions:
    """The node's own parameters (the scene reader lets these names pass)."""

    scene: str = ""                   # shipped scene name or parameters file; "" = default
    lockstep: bool = False            # step as fast as possible and publish /clock
    play_script: bool = True          # push the scene's scripted inputs
    max_catch_up_steps: int = 1000    # physics steps one timer tick may take at most
    record_session: bool = True       # publish ~/session, ~/input_events and ~/keyframe
    keyframe_period: float = 1.0      # sim seconds between keyframes; 0: none


def node_options(params: Mapping[str, Any], source: str) -> NodeOptions:
    """Read and type-check the node's own parameters; missing ones keep their defaults."""
    values: dict[str, Any] = {}
    for option in dataclasses.fields(NodeOptions):
        value = params.get(option.name, option.default)
        kind = type(option.default)
        if kind is float and type(value) is int:  # ROS 2 reads `1` as an integer
            value = float(value)
        if type(value) is not kind:
            raise SceneError(f"{source}: parameter '{option.name}' must be a {kind.__name__}, "
                             f"not {value!r}")
        values[option.name] = value
    options = NodeOptions(**values)
    if options.max_catch_up_steps < 1:
        raise SceneError(f"{source}: parameter 'max_catch_up_steps' must be at least 1, "
                         f"not {options.max_catch_up_steps}")
    if not 0.0 <= options.keyframe_period <= MAX_KEYFRAME_PERIOD_S:
        raise SceneError(f"{source}: parameter 'keyframe_period' must be from 0 (no "
                         f"keyframes) to {MAX_KEYFRAME_PERIOD_S:g} s, not "
                         f"{options.keyframe_period!r}")
    return options


def scene_for_node(params: Mapping[str, Any], source: str) -> Scene:
    """The scene a node runs, from its parameters (flat dotted names and their values).

    Scene parameters (from ``--params-file`` or ``-p``) build the scene; otherwise the
    ``scene`` parameter names a shipped scene or a parameters file; with neither, the
    default scene runs. Giving both is a :class:`SceneError`, since one would silently
    win over the other.
    """
    check_scene_request(params, source)
    requested = params.get("scene") or None
    if any(name.split(".", 1)[0] not in NODE_PARAMETERS for name in params):
        return scene_from_parameters(params, source)
    return load_scene(requested)


def due_script(script: Sequence[WrenchCommand], start_ns: int, next_index: int,
               until_ns: int) -> tuple[list[WrenchCommand], int]:
    """The scene's scripted commands from ``next_index`` on that start by ``until_ns``.

    Script stamps count from the start of the run; the returned commands are shifted to
    ``start_ns``. Returns them and the index of the first command not yet due. The node
    pushes each command before the step that reaches its stamp, which gives the forces of
    :meth:`Simulation.play`.
    """
    due = []
    index = next_index
    while index < len(script) and start_ns + script[index].stamp_ns <= until_ns:
        command = script[index]
        due.append(dataclasses.replace(command, stamp_ns=start_ns + command.stamp_ns))
        index += 1
    return due, index


def catch_up_cap(max_catch_up_steps: int, scene: Scene) -> tuple[int, list[str]]:
    """Steps a timer tick may take, and warnings if the requested cap had to change.

    A cap below one publish period's worth of steps could never keep up with the clock,
    so it is raised to that.
    """
    needed = scene.publish_period_ns // scene.step_ns
    if max_catch_up_steps >= needed:
        return max_catch_up_steps, []
    return needed, [f"max_catch_up_steps={max_catch_up_steps} is less than the {needed} steps "
                    f"of one publish period; using {needed}"]


class TickAction(enum.Enum):
    """What a timer tick does with the simulation."""

    WAIT = "wait"          # the ROS clock is not running yet (zero): do nothing
    START = "start"        # first tick with a running clock: start the simulation now
    ADVANCE = "advance"    # step the simulation up to now
    RESTART = "restart"    # the clock jumped: restart the simulation at now


def plan_tick(now_ns: int, last_now_ns: int | None,
              jump_ns: int = CLOCK_JUMP_NS) -> tuple[TickAction, str]:
    """Decide what a timer tick at ROS time ``now_ns`` does, and why (for the log).

    ``last_now_ns`` is the ROS time of the previous tick that ran (None before the start).
    A zero time means the clock is not running (``use_sim_time`` before the first
    ``/clock`` message). A clock that moved by more than ``jump_ns`` since the last tick,
    backwards (a bag played again) or forwards (a bag skipped ahead), restarts the
    simulation: stepping back is impossible and stepping across the gap would stall.
    """
    if now_ns == 0:
        return TickAction.WAIT, "the ROS clock is not running yet (waiting for /clock)"
    if last_now_ns is None:
        return TickAction.START, f"starting the simulation at {seconds_text(now_ns)} s"
    delta_ns = now_ns - last_now_ns
    if delta_ns < -jump_ns:
        return TickAction.RESTART, (f"the ROS clock jumped back by {seconds_text(-delta_ns)} s; "
                                    f"restarting the scene at {seconds_text(now_ns)} s")
    if delta_ns > jump_ns:
        return TickAction.RESTART, (f"the ROS clock jumped ahead by {seconds_text(delta_ns)} s; "
                                    f"restarting the scene at {seconds_text(now_ns)} s")
    return TickAction.ADVANCE, ""


def tick_target(now_ns: int, start_ns: int, period_ns: int) -> int:
    """The sim time a clock tick at ``now_ns`` steps to: the last publish instant (``start_ns``
    and every ``period_ns`` after it) at or before ``now_ns``. A tick that went on past the
    instant would stop there (the sensors and the drives act at it) and run again for the
    few steps beyond, two runs a tick where one publishes the same snapshots: a tick lands a
    little before or after an instant as its wake-up varies. ``now_ns`` before the start:
    the start."""
    return start_ns + max(0, now_ns - start_ns) // period_ns * period_ns


def next_tick_in(now_ns: int, start_ns: int, period_ns: int) -> int:
    """How long (ns) after a tick at ``now_ns`` the next one is due: at the next publish
    instant after it (:func:`tick_target`), and :data:`TICK_MARGIN_NS` later, so that a
    tick lands just after its instant and publishes the instant's snapshot at once (a tick
    just before it steps to the instant before, and leaves it to the next tick)."""
    return tick_target(now_ns, start_ns, period_ns) + period_ns - now_ns + TICK_MARGIN_NS


def lag_ns(now_ns: int, sim_time_ns: int, step_ns: int) -> int:
    """How far the simulation is behind ``now_ns`` after a tick: 0 when it is less than a step."""
    behind = now_ns - sim_time_ns
    return behind if behind >= step_ns else 0


def plain_parameters(params: Mapping[str, Any]) -> dict[str, Any]:
    """Parameter values as the scene reader takes them: every array as a list.

    rclpy hands parameter overrides from the command line and parameters files over as
    lists, but a value that went through a ``rcl_interfaces/ParameterValue`` message
    (``Parameter.from_parameter_msg``, the parameter services) holds integer and double
    arrays as ``array.array``.
    """
    return {name: list(value) if isinstance(value, (array.array, tuple)) else value
            for name, value in params.items()}


def node_setup(params: Mapping[str, Any], source: str) -> tuple[NodeOptions, Scene]:
    """The node's options and scene from all its parameters (names and values)."""
    params = plain_parameters(params)
    return node_options(params, source), scene_for_node(params, source)


def check_wrench_topics(scene: Scene) -> None:
    """Refuse a ``wrench_topics`` topic (named freely) that is another topic of the node's
    (in the root namespace): an output, where ROS 2 would not match a WrenchStamped
    subscriber to the node's own publisher of another type and a replay wrote both types
    on the topic; an input, where a replay took it as only one of them (the AppliedWrench
    input, or the other wrench topic, lost); or ``/clock``."""
    def qualified(topic: str) -> str:
        return "/" + topic.lstrip("/")

    taken = {qualified(topic): f"an output of the node ({kind.value})"
             for topic, kind in output_topics(scene, tf=True).items()}
    taken[qualified(CLOCK_TOPIC)] = "the clock's topic"
    taken[qualified(APPLIED_WRENCH_TOPIC)] = "the AppliedWrench input"
    taken.update({qualified(m.topic): f"the motor input of joint '{m.joint}'"
                  for m in motor_topics(scene)})
    taken.update({qualified(d.topic): f"the cmd_vel input of body '{d.body}'"
                  for d in cmd_vel_topics(scene)})
    for wrench in scene.wrench_topics:
        topic = qualified(wrench.topic)
        if topic in taken:
            raise SceneError(f"{scene.source}: parameter 'wrench_topics.{wrench.name}.topic': "
                             f"'{wrench.topic}' is already {taken[topic]}")
        taken[topic] = f"the topic of wrench_topics.{wrench.name}"


def refused_change(names: Sequence[str]) -> str:
    """Why the node refuses to change its parameters ``names`` while it runs: it reads
    every one once, at start (the scene, its options, ``use_sim_time``, which picks how it
    ticks), so a change accepted would not take effect."""
    return (f"{', '.join(names)}: read at start only; change the world with the node's "
            "services (spawn_body, delete_body, set_body_state, reset) or restart the node")


# ----------------------------------------------------------------------------- run loop

class LogLine(NamedTuple):
    """A line for the node's log: the rate-limiting key, the text, and whether the input
    it is about was dropped (else it is a warning about an accepted input)."""

    key: str
    message: str
    dropped: bool = True


@dataclasses.dataclass
class Tick:
    """What one call of :meth:`Runner.advance` did."""

    snapshots: list[Snapshot]
    lag: int = 0                                       # ns behind the target (0: caught up)
    diagnostics: Optional[DiagnosticFields] = None     # to publish, when due and enabled
    diverged: Optional[str] = None                     # the divergence that halted the run
    script_errors: list[str] = dataclasses.field(default_factory=list)
    #: The sensors' readings as messages, each with its stamp, in the order they were taken.
    readings: list[tuple[int, OutputFields]] = dataclasses.field(default_factory=list)

    def in_order(self) -> list[tuple[int, Union[Snapshot, OutputFields]]]:
        """The snapshots and readings with their stamps in the order the node publishes
        them: by stamp, a snapshot before the readings of its instant (they are taken on
        leaving it)."""
        merged: list[tuple[int, int, Union[Snapshot, OutputFields]]] = \
            [(snapshot.time_ns, 0, snapshot) for snapshot in self.snapshots]
        merged += [(stamp, 1, output) for stamp, output in self.readings]
        merged.sort(key=lambda item: item[:2])  # stable: readings keep their order
        return [(stamp, item) for stamp, _, item in merged]


class Runner:
    """The node's run loop without ROS: a :class:`~hecker_dynamics.World` of the scene, its
    script, the input counters, the diagnostics schedule and the session records. The
    rclpy node and the offline replay both drive one, so a replayed session gives the
    node's outputs. Commands, moved and spawned or deleted bodies and restarts go through
    the World's methods (call the runner's, which keep :attr:`sim` and :attr:`scene` in
    step with it); stepping and reading go to the simulation under it (:attr:`sim`), as
    the World's own stepping does, so that a tick costs what it did.

    ``max_steps`` caps the physics steps of one :meth:`advance` (the node's catch-up cap;
    None: no cap). ``wall_clock`` times the steps for the diagnostics (the replay passes a
    clock that stands still, since wall time is not reproducible). Until ``started``, inputs
    are refused (the node waits for a running ROS clock).

    Every decision that the inputs alone do not fix is made at a sim instant, never at a
    timer tick, so that ticks at other times give the same states: a scripted command is
    pushed when the simulation arrives at the last step before its stamp, a keyframe is
    taken when it arrives at the keyframe's step, and an input message is pushed at the sim
    time it arrives at, which its :class:`~.session.InputEventFields` record holds. With
    ``record`` the records pile up in :attr:`records` for the node to publish
    (:meth:`take_records`).

    :attr:`scene` is the world's scene now: the scene given (:attr:`base_scene`) with the
    bodies spawned and deleted since the session's start (:attr:`edits`); a restart
    returns to the scene given.
    """

    world: World
    sim: Simulation  # the simulation under world (see _follow)
    scene: Scene  # world's scene

    def __init__(self, scene: Scene, *, start_ns: int = 0, play_script: bool = True,
                 max_steps: Optional[int] = None, started: bool = True,
                 hardware_id: str = "/dynamics_node",
                 wall_clock: Callable[[], int] = time.perf_counter_ns,
                 record: bool = False, keyframe_period_ns: int = 0,
                 lockstep: bool = False) -> None:
        check_wrench_topics(scene)
        self.base_scene = scene
        self.edits: list[WorldEdit] = []
        # The runner plays the script itself (_arrive), at the node's instants.
        self._follow(World.from_scene(scene, script=False, start_ns=start_ns))
        self.drives = DriveSet(self.sim)
        self.sensors = SensorSet(scene, self.sim)
        self.touches = Touches(scene)
        self.play_script = play_script
        self.max_steps = max_steps
        self.started = False
        self.hardware_id = hardware_id
        self.wall_clock = wall_clock
        self.record = record
        self.lockstep = lockstep
        #: Steps between keyframes (0: none): the period rounded up to whole steps.
        self.keyframe_steps = -(-keyframe_period_ns // scene.step_ns) if keyframe_period_ns else 0
        self.fingerprint = scene_fingerprint(scene)
        self.records: list[Record] = []
        self.accepted = 0
        self.rejected = 0
        self.halted: Optional[str] = None
        #: Paused by the pause service: the clock's ticks do not step it.
        self.paused = False
        self._stepping = False
        #: Restarts so far (-1 before the first start) and input messages taken so far.
        self.session = -1
        self.sequence = 0
        self._script_index = 0
        self._last_diagnostics_ns: Optional[int] = None
        self._next_keyframe_step = 0
        if started:
            self.restart(start_ns, "start")

    def _follow(self, world: World) -> None:
        """Run ``world``, or go on with :attr:`world` after a change of its bodies.
        :attr:`sim` (the simulation under it) and :attr:`scene` (its scene) are plain
        attributes that follow it here, since every stop of :meth:`advance` reads them
        about ten times: as the World's properties they cost a tick of the 1-body ring
        (bench/node.py) about 2 % more."""
        self.world, self.sim, self.scene = world, world.simulation, world.scene

    def restart(self, start_ns: int, reason: str = "reset") -> None:
        """Restart the scene at ``start_ns`` (first tick, reset service, clock jump)."""
        if self.edits:  # back to the scene given, without the bodies spawned or deleted
            self.edits = []
            self._follow(World.from_scene(self.base_scene, script=False, start_ns=start_ns))
        else:
            self.world.reset(start_ns)
        self.drives = DriveSet(self.sim)
        self.sensors = SensorSet(self.scene, self.sim)
        self.touches = Touches(self.scene)
        self._script_index = 0
        self.halted = None
        self.paused = False
        self._last_diagnostics_ns = None
        self._next_keyframe_step = 0
        self.started = True
        self.session += 1
        if self.record:
            self.records.append(self.session_fields(reason))

    def session_fields(self, reason: str) -> SessionFields:
        """The record of the session that runs now."""
        sim, scene = self.sim, self.base_scene
        return SessionFields(
            sim.start_ns, scene.frame_id, self.session, reason,
            Path(scene.source).stem, self.fingerprint, sim.integrator.name, sim.step_ns,
            scene.publish_period_ns, self.play_script, self.lockstep,
            self.max_steps or 0, self.keyframe_steps * sim.step_ns, self.sequence, __version__)

    def take_records(self) -> list[Record]:
        """The records made since the last call, in the order they were made."""
        records, self.records = self.records, []
        return records

    # ----------------------------------------------------------------- inputs

    def accept(self, topic: str, msg: Any, arrival_ns: int,
               wrench_topic: Optional[InputSource] = None) -> list[LogLine]:
        """Map one input message that arrived at ROS time ``arrival_ns`` and push it.

        ``msg`` is an ``AppliedWrench`` (``wrench_topic`` None), a ``WrenchStamped`` from
        the scene's input topic ``wrench_topic``, a ``Float64`` from a motor's topic (a
        :class:`MotorTopic`: the motor holds that speed from the next step on) or a
        ``Twist`` from a driven body's (a :class:`CmdVelTopic`: its drives follow it from
        their next control instant on). Bad input
        is counted in ``rejected`` and reported in the returned lines, never raised;
        warnings about an accepted message are returned too. With ``record``, an input
        event records the message, the sim time it was pushed at and the outcome.
        """
        lines = self._push_message(topic, msg, arrival_ns, wrench_topic)
        if self.record:
            rejected = next((line.message for line in lines if line.dropped), "")
            kind = (APPLIED_WRENCH_EVENT if wrench_topic is None else MOTOR_SPEED_EVENT
                    if isinstance(wrench_topic, MotorTopic) else CMD_VEL_EVENT
                    if isinstance(wrench_topic, CmdVelTopic) else WRENCH_STAMPED_EVENT)
            self.records.append(InputEventFields(
                self.sim.time_ns, self.session, self.sequence, topic, arrival_ns, kind, msg,
                not rejected, rejected))
        self.sequence += 1
        return lines

    def _push_message(self, topic: str, msg: Any, arrival_ns: int,
                      wrench_topic: Optional[InputSource]) -> list[LogLine]:
        if not self.started:
            self.rejected += 1
            return [LogLine(f"{topic}:early", f"input on '{topic}' ignored: the simulation "
                                              "has not started (it starts at the first tick of "
                                              "the ROS clock; under use_sim_time, the first "
                                              "/clock)")]
        if isinstance(wrench_topic, MotorTopic):
            try:
                set_motor_speed(self.sim, wrench_topic.joint, float(msg.data))
            except InputError as error:
                self.rejected += 1
                return [LogLine(f"{topic}:message", f"input on '{topic}' rejected: {error}")]
            self.accepted += 1
            return []
        if isinstance(wrench_topic, CmdVelTopic):
            try:
                warnings = take_cmd_vel(self.drives, wrench_topic, msg, self.sim.time_ns)
            except InputError as error:
                self.rejected += 1
                return [LogLine(f"{topic}:message", f"input on '{topic}' rejected: {error}")]
            self.accepted += 1
            return [LogLine(f"{topic}:ignored", warning, dropped=False) for warning in warnings]
        try:
            if wrench_topic is None:
                command, warnings = applied_wrench_to_command(msg, arrival_ns)
            else:
                command, warnings = wrench_stamped_to_command(msg, wrench_topic, arrival_ns)
        except InputError as error:  # the message itself is bad (NaN, empty body, ...)
            self.rejected += 1
            return [LogLine(f"{topic}:message", f"input on '{topic}' rejected: {error}")]
        lines = [LogLine(f"{topic}:out_of_plane", warning, dropped=False)
                 for warning in warnings]
        try:
            self.world.push(command)
        except InputError as error:  # the scene refuses it (unknown body or frame, stamp...)
            self.rejected += 1
            return lines + [LogLine(f"{topic}:scene", f"input on '{topic}' rejected: {error}")]
        self.accepted += 1
        return lines

    # ----------------------------------------------------------------- world changes

    def set_body_state(self, body: str, values: Sequence[float]) -> WorldEventFields:
        """Move ``body`` now (``values``: x, y, angle of its frame, vx, vy of the frame's
        origin, omega; see :meth:`Simulation.set_body_state`)."""
        def move() -> None:
            if len(values) != 6:
                raise InputError(f"a body state has 6 values, not {len(values)}")
            x, y, angle, vx, vy, omega = (float(value) for value in values)
            self.world.set_body_state(body, (x, y), angle, (vx, vy), omega)
        return self._change(WorldChange.SET_STATE, move, body, tuple(float(v) for v in values))

    def pause(self) -> WorldEventFields:
        """Stop stepping with the clock (until :meth:`resume`)."""
        def stop() -> None:
            if self.paused:
                raise InputError("the simulation is paused already")
            self.paused = True
        return self._change(WorldChange.PAUSE, stop)

    def resume(self, now_ns: int) -> WorldEventFields:
        """Go on stepping with the clock. Following the ROS clock, the simulation skips the
        time it stood still, to the first publish instant at or after ``now_ns``; in
        lockstep (and for a ``now_ns`` not ahead of it) it goes on from where it stands."""
        sim = self.sim
        target = sim.time_ns
        if not self.lockstep and now_ns > sim.time_ns:
            period = self.scene.publish_period_ns
            target = sim.time_ns + -(-(now_ns - sim.time_ns) // period) * period
        return self.resume_at(target)

    def resume_at(self, time_ns: int) -> WorldEventFields:
        """:meth:`resume` from sim time ``time_ns`` (what a replay repeats)."""
        def go_on() -> None:
            if not self.paused:
                raise InputError("the simulation is not paused")
            self.sim.skip_to(time_ns)  # the World has no pause: only the clock moves
            self.paused = False
        return self._change(WorldChange.RESUME, go_on, time_ns=time_ns)

    def step(self, steps: int) -> tuple[WorldEventFields, Tick]:
        """Take ``steps`` steps of a paused simulation; returns the record and what the
        steps passed (their snapshots)."""
        tick = Tick([])

        def take() -> None:
            if not self.paused:
                raise InputError("step needs a paused simulation (call pause first)")
            if not 1 <= steps <= MAX_SERVICE_STEPS:
                raise InputError(f"steps must be from 1 to {MAX_SERVICE_STEPS}, not {steps}")
            # No keyframe inside the call: a replay could not start in its middle. All the
            # steps asked for, whatever the catch-up cap of a tick.
            cap, self.max_steps = self.max_steps, None
            self.paused, self._stepping = False, True
            try:
                done = self.advance(self.sim.time_ns + steps * self.sim.step_ns)
            finally:
                self.paused, self._stepping, self.max_steps = True, False, cap
            tick.snapshots, tick.diverged = done.snapshots, done.diverged
            tick.script_errors = done.script_errors
            tick.readings = done.readings
        return self._change(WorldChange.STEP, take, values=(float(steps),)), tick

    def spawn_body(self, name: str, spec: str,
                   collisions: Sequence[str] = ()) -> WorldEventFields:
        """Add body ``name`` now, read from ``spec`` (the YAML of a scene's
        ``bodies.<name>``), joining the collision groups ``collisions``; the rules are
        :mod:`hecker_dynamics.scene.world`'s, the carry-over :meth:`World.edit_bodies`'s."""
        edit = WorldEdit(EditKind.SPAWN, name, spec, tuple(collisions))
        return self._change(WorldChange.SPAWN, lambda: self._edit(edit), name, spec=spec,
                            collisions=edit.collisions)

    def delete_body(self, name: str) -> WorldEventFields:
        """Remove body ``name`` now (refused while a spring, joint or input names it)."""
        return self._change(WorldChange.DELETE,
                            lambda: self._edit(WorldEdit(EditKind.DELETE, name)), name)

    def _edit(self, edit: WorldEdit) -> None:
        try:
            self.world.edit_bodies(edit)
        except SceneError as error:
            raise InputError(str(error)) from None
        self._follow(self.world)
        self.edits.append(edit)
        drives, self.drives = self.drives, DriveSet(self.sim)  # the bodies' rows moved
        self.drives.import_state(drives.export_state())
        sensors = self.sensors
        self.sensors = SensorSet(self.scene, self.sim, sensors.sampled_ns)
        self.sensors.import_state(sensors.export_state(self.sim.time_ns))

    def _change(self, kind: WorldChange, apply: Callable[[], None], body: str = "",
                values: tuple[float, ...] = (), time_ns: int = 0, spec: str = "",
                collisions: tuple[str, ...] = ()) -> WorldEventFields:
        """Apply one change (``apply`` raises :class:`InputError` to refuse it) and record
        it at the sim time it was made, in the input events' sequence."""
        stamp, sequence = self.sim.time_ns, self.sequence
        self.sequence += 1  # before the change: keyframes it takes count it as done
        reason = ""
        if not self.started:
            reason = "the simulation has not started yet (waiting for the ROS clock)"
        elif self.halted is not None:
            reason = f"the simulation is halted ({self.halted}); reset it first"
        else:
            try:
                apply()
            except InputError as error:
                reason = str(error)
        record = WorldEventFields(stamp, self.session, sequence, kind, body, values, time_ns,
                                  not reason, reason, spec, collisions)
        if self.record:
            self.records.append(record)
        return record

    # ----------------------------------------------------------------- stepping

    def advance(self, target_ns: int, keep: bool = True) -> Tick:
        """Step towards ``target_ns`` (at most ``max_steps``), pushing the scripted
        commands and taking the keyframes as their instants come; return the snapshots
        passed (none without ``keep``), the lag and the diagnostics due.

        After a divergence the simulation stands still until :meth:`restart`.
        """
        if self.halted is not None or self.paused:
            return Tick([])
        # The hot path steps the simulation under the World itself: World.step takes
        # seconds and checks them, and keeps neither snapshots nor a catch-up cap.
        sim = self.sim
        tick = Tick([])
        steps_before = sim.steps
        wall_start_ns = self.wall_clock()
        try:
            while True:
                self._arrive(tick)
                taken = sim.steps - steps_before
                if self.max_steps is not None and taken >= self.max_steps:
                    break
                stop = min(target_ns, self._next_stop())
                if sim.time_ns + sim.step_ns > stop:
                    break
                tick.readings += self.leave()
                tick.snapshots += advance_with_drives(
                    sim, self.drives, stop, self.play_script,
                    None if self.max_steps is None else self.max_steps - taken, keep,
                    tick.script_errors)
        except DivergenceError as error:
            self.halted = tick.diverged = str(error)
            tick.diagnostics = self._diagnostics(0, 0, 0)
            return tick
        wall_ns = self.wall_clock() - wall_start_ns
        tick.lag = lag_ns(target_ns, sim.time_ns, sim.step_ns)
        if diagnostics_due(self._last_diagnostics_ns, sim.time_ns):
            tick.diagnostics = self._diagnostics(sim.steps - steps_before, wall_ns, tick.lag)
        return tick

    def _arrive(self, tick: Tick) -> None:
        """At the simulation's present instant: measure what the step that led here did
        for the IMUs due here (:meth:`SensorSet.arrive`), push the scripted commands due
        by the end of the next step, then take the keyframe due at this step."""
        sim = self.sim
        self.sensors.arrive(sim)
        if self.play_script and self._script_index < len(self.scene.script):  # else none due
            due, self._script_index = due_script(self.scene.script, sim.start_ns,
                                                 self._script_index, sim.time_ns + sim.step_ns)
            for command in due:
                try:
                    self.world.push(command)
                except InputError as error:
                    tick.script_errors.append(f"scripted input rejected: {error}")
        self.drives.arrive(sim, self.play_script, tick.script_errors)
        if self.keyframe_steps and sim.steps >= self._next_keyframe_step and not self._stepping:
            if self.record:
                self.records.append(self.keyframe())
            self._next_keyframe_step = sim.steps + self.keyframe_steps

    def leave(self) -> list[tuple[int, OutputFields]]:
        """The readings of the sensors due at the present instant, with everything made at
        it in place (:mod:`~..sensors.schedule`), then the contact events of the step that
        ended there (:mod:`~..sensors.touch`), each instant once: what :meth:`advance`
        takes as it steps on from the instant, and a replay that ends at an instant the
        node stepped on from takes there."""
        now, frame_id = self.sim.time_ns, self.scene.frame_id
        readings, events = self.sensors.sample(self.sim), self.touches.sample(self.sim)
        if not readings and not events:  # most stops: nothing to build
            return []
        return [(now, reading_output(reading)) for reading in readings] + \
            [(now, touch_output(frame_id, event)) for event in events]

    def _next_stop(self) -> int:
        """The next instant :meth:`_arrive` has work at: the push of the next scripted
        command or the next keyframe (far in the future when there is neither)."""
        sim = self.sim
        stop = FAR_FUTURE_NS
        if self.play_script and self._script_index < len(self.scene.script):
            stamp = sim.start_ns + self.scene.script[self._script_index].stamp_ns
            stop = sim.start_ns + (-(-(stamp - sim.start_ns) // sim.step_ns) - 1) * sim.step_ns
        if self.keyframe_steps and not self._stepping:
            stop = min(stop, sim.start_ns + self._next_keyframe_step * sim.step_ns)
        for next_stop in (self.sensors.next_stop(sim.time_ns), self.touches.next_stop(sim)):
            if next_stop is not None:
                stop = min(stop, next_stop)
        return stop

    # ----------------------------------------------------------------- keyframes

    def keyframe(self) -> KeyframeFields:
        """The whole state now, at full precision (see :meth:`restore`)."""
        sim = self.sim
        state = sim.export_state()
        q, v = state.pop("q"), state.pop("v")
        state["runner"] = {"script_index": self._script_index, "accepted": self.accepted,
                           "rejected": self.rejected, "paused": self.paused,
                           "last_diagnostics_ns": self._last_diagnostics_ns}
        if self.drives:  # a keyframe of a scene without drives holds what it always held
            state["runner"]["drives"] = self.drives.export_state()
        if self.touches.enabled:  # likewise without contact events
            state["runner"]["touches"] = self.touches.export_state()
        if self.sensors.has_imu:  # likewise without IMUs
            state["runner"]["imu"] = self.sensors.export_state(sim.time_ns)
        if self.edits:  # a keyframe of the scene given holds what it always held
            state["world"] = [edit.as_data() for edit in self.edits]
        return KeyframeFields(sim.time_ns, self.session, sim.steps, self.sequence,
                              sim.model.names, tuple(x for row in q for x in row),
                              tuple(x for row in v for x in row), encode_state(state))

    def restore(self, keyframe: KeyframeFields) -> None:
        """Continue from ``keyframe`` (of a session of this scene) as the node did, in the
        world it had then (the scene with the bodies spawned and deleted it records)."""
        state = decode_state(keyframe.state)
        edits = [WorldEdit.from_data(data) for data in state.pop("world", [])]
        world = None
        scene = self.base_scene
        if edits or self.edits:  # the world it had then, built once
            world = World.from_scene(self.base_scene, script=False, start_ns=self.sim.start_ns)
            world.edit_bodies(*edits)
            scene = world.scene
        names = tuple(body.name for body in scene.bodies)
        if tuple(keyframe.bodies) != names:
            raise ValueError(f"a keyframe of bodies {', '.join(keyframe.bodies)} does not fit "
                             f"the scene's {', '.join(names)}")
        if world is not None:
            self.edits = edits
            self._follow(world)
        runner = state.pop("runner")
        size = len(keyframe.bodies)
        state["q"] = [list(keyframe.q[3 * i:3 * i + 3]) for i in range(size)]
        state["v"] = [list(keyframe.v[3 * i:3 * i + 3]) for i in range(size)]
        # The keyframe holds the simulation's own state (Simulation.export_state), which
        # goes to it whole; the World's forces are none of the runner's.
        self.sim.import_state(state)
        self.drives = DriveSet(self.sim)
        self.drives.import_state(runner.get("drives", []))
        self.sensors = SensorSet(self.scene, self.sim)
        self.sensors.import_state(runner.get("imu", []))
        self.touches = Touches(self.scene)
        self.touches.import_state(runner.get("touches", []))
        self._script_index = int(runner["script_index"])
        self.accepted, self.rejected = int(runner["accepted"]), int(runner["rejected"])
        self._last_diagnostics_ns = runner["last_diagnostics_ns"]
        self.paused = bool(runner["paused"])
        self.halted = None
        self.started = True
        self.session, self.sequence = keyframe.session, keyframe.next_event
        self._next_keyframe_step = keyframe.steps + self.keyframe_steps

    # ----------------------------------------------------------------- diagnostics

    def _diagnostics(self, substeps: int, wall_ns: int, lag: int) -> Optional[DiagnosticFields]:
        if not self.scene.publish_diagnostics:
            return None
        self._last_diagnostics_ns = self.sim.time_ns
        return simulation_diagnostics(
            self.sim, halted=self.halted, lag=lag, substeps=substeps, wall_ns=wall_ns,
            accepted=self.accepted, rejected=self.rejected, hardware_id=self.hardware_id)

    def done(self) -> bool:
        """Whether a lockstep run is over: halted, or the scene's duration (if any) ran."""
        duration_ns = self.scene.duration_ns
        return self.halted is not None or (
            duration_ns > 0 and self.sim.time_ns - self.sim.start_ns >= duration_ns)
