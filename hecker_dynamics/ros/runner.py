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
from typing import Any, NamedTuple, Optional

from ..dynamics.commands import InputError, WrenchCommand
from ..dynamics.simulation import DivergenceError, Simulation, Snapshot
from ..scene.load import NODE_PARAMETERS, Scene, SceneError, load_scene, scene_from_parameters
from .diagnostics import DiagnosticFields, diagnostics_due, simulation_diagnostics
from .fields import NS_PER_S

#: A change of the ROS clock between two timer ticks larger than this, forwards or
#: backwards, is a jump: the simulation restarts at the new time instead of stepping there.
CLOCK_JUMP_NS = NS_PER_S

# ----------------------------------------------------------------------------- node setup

@dataclasses.dataclass(frozen=True)
class NodeOptions:
    """The node's own parameters (the scene reader lets these names pass)."""

    scene: str = ""                   # shipped scene name or parameters file; "" = default
    lockstep: bool = False            # step as fast as possible and publish /clock
    play_script: bool = True          # push the scene's scripted inputs
    max_catch_up_steps: int = 1000    # physics steps one timer tick may take at most


def node_options(params: Mapping[str, Any], source: str) -> NodeOptions:
    """Read and type-check the node's own parameters; missing ones keep their defaults."""
    values = {}
    for option in dataclasses.fields(NodeOptions):
        value = params.get(option.name, option.default)
        kind = type(option.default)
        if type(value) is not kind:
            raise SceneError(f"{source}: parameter '{option.name}' must be a {kind.__name__}, "
                             f"not {value!r}")
        values[option.name] = value
    options = NodeOptions(**values)
    if options.max_catch_up_steps < 1:
        raise SceneError(f"{source}: parameter 'max_catch_up_steps' must be at least 1, "
                         f"not {options.max_catch_up_steps}")
    return options


def scene_for_node(params: Mapping[str, Any], source: str) -> Scene:
    """The scene a node runs, from its parameters (flat dotted names and their values).

    Scene parameters (from ``--params-file`` or ``-p``) build the scene; otherwise the
    ``scene`` parameter names a shipped scene or a parameters file; with neither, the
    default scene runs. Giving both is a :class:`SceneError`, since one would silently
    win over the other.
    """
    scene_names = sorted(name for name in params
                         if name.split(".", 1)[0] not in NODE_PARAMETERS)
    requested = params.get("scene") or None
    if scene_names and requested:
        raise SceneError(f"{source}: give the 'scene' parameter ('{requested}') or scene "
                         f"parameters ({', '.join(scene_names[:3])}, ...), not both")
    if scene_names:
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
        return TickAction.START, f"starting the simulation at {now_ns * 1e-9:.9f} s"
    delta_ns = now_ns - last_now_ns
    if delta_ns < -jump_ns:
        return TickAction.RESTART, (f"the ROS clock jumped back by {-delta_ns * 1e-9:.3f} s; "
                                    f"restarting the scene at {now_ns * 1e-9:.9f} s")
    if delta_ns > jump_ns:
        return TickAction.RESTART, (f"the ROS clock jumped ahead by {delta_ns * 1e-9:.3f} s; "
                                    f"restarting the scene at {now_ns * 1e-9:.9f} s")
    return TickAction.ADVANCE, ""


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


class Runner:
    """The node's run loop without ROS: a :class:`Simulation`, the scene's script, the
    input counters and the diagnostics schedule. The rclpy node and the offline replay
    both drive one, so a replayed session gives the node's outputs.

    ``max_steps`` caps the physics steps of one :meth:`advance` (the node's catch-up cap;
    None: no cap). ``wall_clock`` times the steps for the diagnostics (the replay passes a
    clock that stands still, since wall time is not reproducible). Until ``started``, inputs
    are refused (the node waits for a running ROS clock).
    """

    def __init__(self, scene: Scene, *, start_ns: int = 0, play_script: bool = True,
                 max_steps: Optional[int] = None, started: bool = True,
                 hardware_id: str = "/dynamics_node",
                 wall_clock: Callable[[], int] = time.perf_counter_ns) -> None:
        self.scene = scene
        self.sim = Simulation(scene, start_ns=start_ns)
        self.play_script = play_script
        self.max_steps = max_steps
        self.started = started
        self.hardware_id = hardware_id
        self.wall_clock = wall_clock
        self.accepted = 0
        self.rejected = 0
        self.halted: Optional[str] = None
        self._script_index = 0
        self._last_diagnostics_ns: Optional[int] = None

    def restart(self, start_ns: int) -> None:
        """Restart the scene at ``start_ns`` (reset service, clock jump, first tick)."""
        self.sim.reset(start_ns)
        self._script_index = 0
        self.halted = None
        self._last_diagnostics_ns = None
        self.started = True

    def accept(self, topic: str,
               convert: Callable[[int], tuple[WrenchCommand, list[str]]],
               arrival_ns: int) -> list[LogLine]:
        """Convert one input message that arrived at ``arrival_ns`` and push it.

        ``convert`` is a :func:`applied_wrench_to_command` or
        :func:`wrench_stamped_to_command` call waiting for the arrival time. Bad input is
        counted in ``rejected`` and reported in the returned lines, never raised; warnings
        about an accepted message are returned too.
        """
        if not self.started:
            self.rejected += 1
            return [LogLine(f"{topic}:early", f"input on '{topic}' ignored: the simulation "
                                              "starts with the ROS clock (waiting for /clock)")]
        try:
            command, warnings = convert(arrival_ns)
        except InputError as error:  # the message itself is bad (NaN, empty body, ...)
            self.rejected += 1
            return [LogLine(f"{topic}:message", f"input on '{topic}' rejected: {error}")]
        lines = [LogLine(f"{topic}:out_of_plane", warning, dropped=False)
                 for warning in warnings]
        try:
            self.sim.push(command)
        except InputError as error:  # the scene refuses it (unknown body or frame, stamp...)
            self.rejected += 1
            return lines + [LogLine(f"{topic}:scene", f"input on '{topic}' rejected: {error}")]
        self.accepted += 1
        return lines

    def advance(self, target_ns: int) -> Tick:
        """Push the scripted commands due, step towards ``target_ns`` (at most
        ``max_steps``) and return the snapshots passed, the lag and the diagnostics due.

        After a divergence the simulation stands still until :meth:`restart`.
        """
        if self.halted is not None:
            return Tick([])
        sim = self.sim
        tick = Tick([])
        if self.play_script:
            reach = target_ns if self.max_steps is None else min(
                target_ns, sim.time_ns + self.max_steps * sim.step_ns)
            due, self._script_index = due_script(self.scene.script, sim.start_ns,
                                                 self._script_index, reach)
            for command in due:
                try:
                    sim.push(command)
                except InputError as error:
                    tick.script_errors.append(f"scripted input rejected: {error}")
        steps_before = sim.steps
        wall_start_ns = self.wall_clock()
        try:
            tick.snapshots = sim.advance_to(target_ns, max_steps=self.max_steps)
        except DivergenceError as error:
            self.halted = tick.diverged = str(error)
            tick.diagnostics = self._diagnostics(0, 0, 0)
            return tick
        wall_ns = self.wall_clock() - wall_start_ns
        tick.lag = lag_ns(target_ns, sim.time_ns, sim.step_ns)
        if diagnostics_due(self._last_diagnostics_ns, sim.time_ns):
            tick.diagnostics = self._diagnostics(sim.steps - steps_before, wall_ns, tick.lag)
        return tick

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
