"""The simulation: sim clock, input buffer and state, advanced in fixed steps.

One step is the article's loop ("Physics, Part 2: Angular Effects", steps 3 to 8): the
active inputs join the scene's forces, the integrator turns accelerations into a new state,
walls respond with impulses, and the angle is wrapped. Time is kept in integer nanoseconds
(as ROS stamps are), so steps never drift and the same scene with the same inputs in the
same order gives bit-identical states.

Where the compiled kernel is built (:mod:`.kernel`) and the method is explicit, the steps
between one publish instant or input change and the next run in the kernel in one call,
joint and contact passes included, with the results of Python's plain-float path (:mod:`.kernel` and
:mod:`..contact.compiled` say how far they agree). Without a joint pass, and while the
energy bound's check needs nothing but the state (:meth:`.EnergyBound.kernel_ready`), one
call goes on through the publish instants up to the next input change, making each
instant's check between its steps: the same bits at one call's cost.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import nullcontext
from dataclasses import replace
from itertools import repeat
from types import MappingProxyType
from typing import Any, NamedTuple, NoReturn, Optional

import numpy as np

from ..contact.events import Impact, WallEvents
from ..contact.joints import (
    MAX_RING,
    MOST_SUBSTEPS,
    UNSOLVED,
    JointsUnsolved,
    ringing_advice,
    unsolved_advice,
)
from ..geometry.planar import wrap_angles_in_place
from ..geometry.shapes import energy_of_motion
from ..integrators.methods import (
    EmbeddedRungeKutta,
    ExplicitEuler,
    ImplicitTheta,
    IntegrationError,
    RungeKutta4,
    SemiImplicitEuler,
    VelocityVerlet,
    choose_method,
    make_integrator,
)
from ..scene.commands import InputError, WrenchCommand, shorter_than_a_step
from ..scene.load import Scene, check_followed
from ..scene.parameters import seconds_text, stamp_time
from .divergence import EnergyBound
from .forces import ConstantWrenchTerm, WrenchRow, lever_arm
from .inputs import InputBuffer
from .kernel import Advanced, DriveColumns, DriveInt, DriveReal, Runs, compiled_steps
from .model import FrameRow, Model, wrench_term

__all__ = ["PROGRESS_UPDATES", "DivergenceError", "BodyState", "Snapshot", "DrivenWheels",
           "Simulation"]

#: How many times :meth:`Simulation.play` reports its progress over a run, at most: often
#: enough for a smooth bar, seldom enough that chunking costs nothing measurable.
PROGRESS_UPDATES = 200
#: The methods whose step depends on the state alone (no sub-step size, no Newton guess
#: carried over), which is what lets a step of a scene fully asleep be skipped.
FIXED_STEP = (ExplicitEuler, SemiImplicitEuler, VelocityVerlet, RungeKutta4)
#: The most values (q and v of every body, at each publish instant) one kernel call of
#: :meth:`Simulation.advance_to` writes: memory in step with its state, not its length.
RUN_VALUES = 1 << 16
#: The most places of commands (body, frame and point) a simulation keeps resolved.
PLACES = 1024
#: The joint states of a snapshot of a scene without joints (read-only, so shared).
NO_JOINTS: Mapping[str, tuple[float, float, float]] = MappingProxyType({})


class Place(NamedTuple):
    """Where a command acts (:meth:`Simulation._place`), kept for its body, frame and point."""

    body: int  # the body's row
    axes_body: int  # the body whose axes its force is in; -1: the fixed frame's
    point_body: int  # the body its point is relative to; -1: the fixed frame
    point: tuple[float, float]
    lever: Optional[float]  # the point's distance from the CM where it is the body's own


class DrivenWheels(NamedTuple):
    """Differential drives whose control instants the kernel's run takes
    (:meth:`Simulation.run_drives`): the keys (body, source) of their wheels' commands, the
    left and the right wheel of each drive in turn, their columns, a row a drive
    (:class:`.kernel.DriveInt`, :class:`.kernel.DriveReal`: the drives' own, which the run
    writes; the simulation fills in the wheels' rows and reach), and each drive's next
    control instant (ns), which its wheels' commands end at."""

    keys: list[tuple[str, str]]
    ints: np.ndarray
    reals: np.ndarray
    next_ns: list[int]


class DivergenceError(RuntimeError):
    """The state stopped being finite, or its energy went past what the scene's forces
    allow (:mod:`.divergence`); the simulation kept its last good state."""


class BodyState(NamedTuple):
    """A body's published state: its frame's pose and velocity in the fixed frame.

    A named tuple: a snapshot of ten thousand bodies builds in milliseconds."""

    name: str
    position: tuple[float, float]  # origin of the body frame
    angle: float  # radians, counter-clockwise, in [-pi, pi)
    linear_velocity: tuple[float, float]  # of the body-frame origin, fixed-frame axes
    angular_velocity: float


class Snapshot:
    """All bodies at one instant, with the total mechanical energy.

    Taking one copies the state and nothing more: the energy and the per-body states are
    computed on first use, so a run that publishes little pays little, which matters with
    thousands of bodies and with long steps.
    """

    __slots__ = ("time_ns", "steps", "_model", "_q", "_v", "_row", "_energy", "_bodies",
                 "joints")

    def __init__(self, time_ns: int, steps: int, model: Model, q: np.ndarray,
                 v: np.ndarray, copy: bool = True, row: int = -1) -> None:
        """``copy`` false: (q, v) are the snapshot's own, never changed in place (passed
        by position where snapshots are taken often: a keyword costs a third of a
        snapshot). ``row`` >= 0: (q, v) are blocks of states, never changed in place, and
        the snapshot's is their row ``row``, taken on first use (a run through many
        instants makes no arrays per instant)."""
        self.time_ns = time_ns
        self.steps = steps
        joints = model.joints
        #: (position, velocity, effort) per revolute and prismatic joint, taken now: the
        #: joint pass counts turns and keeps its efforts from step to step.
        self.joints: Mapping[str, tuple[float, float, float]] = (
            NO_JOINTS if joints is None else
            joints.joint_state(q, v) if row < 0 else joints.joint_state(q[row], v[row]))
        if copy:
            q, v = q.copy(), v.copy()
        self._model = model
        self._q = q
        self._v = v
        self._row = row
        self._energy: Optional[float] = None
        self._bodies: Optional[tuple[BodyState, ...]] = None

    def _state(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at this instant."""
        row = self._row
        return (self._q, self._v) if row < 0 else (self._q[row], self._v[row])

    @property
    def energy(self) -> float:
        """Kinetic energy plus the potential energy of gravity and springs (J)."""
        if self._energy is None:
            with np.errstate(all="ignore"):  # as in the step: a huge state gives inf, quietly
                self._energy = self._model.energy(*self._state())
        return self._energy

    @property
    def bodies(self) -> tuple[BodyState, ...]:
        if self._bodies is None:
            model = self._model
            q, v = self._state()
            if model.lean:
                frames: Iterable[FrameRow] = model.body_frame_rows(q.tolist(), v.tolist())
            else:
                with np.errstate(all="ignore"):
                    origin, velocity = model.body_frames(q, v)
                frames = zip(map(tuple, origin.tolist()), q[:, 2].tolist(),
                             map(tuple, velocity.tolist()), v[:, 2].tolist())
            self._bodies = tuple(BodyState(name, *frame)
                                 for name, frame in zip(model.names, frames))
        return self._bodies

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Snapshot):
            return NotImplemented
        return (self.time_ns, self.energy, self.steps, self.bodies) == \
            (other.time_ns, other.energy, other.steps, other.bodies)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (f"Snapshot(time_ns={self.time_ns}, energy={self.energy!r}, "
                f"steps={self.steps}, bodies={self.bodies!r})")


def _numbers(rows: Any, what: str) -> np.ndarray:
    """``rows`` of numbers (export_state's lists, or an array) as floats; text and
    booleans, which numpy would take for numbers ('1' as 1.0, True as 1.0), are refused."""
    values = np.array(rows, dtype=float)  # refuses rows of two lengths, and other text
    for item in np.asarray(rows, dtype=object).ravel():
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, numbers.Real):
            raise ValueError(f"'{what}' holds {item!r}, not a number")
    return values


def _whole(value: Any, what: str) -> int:
    """A count or a time in nanoseconds, as export_state writes it: an int."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"'{what}' is {value!r}, not a whole number")
    return int(value)


class Simulation:
    """A deterministic, fixed-step simulation of one scene."""

    def __init__(self, scene: Scene, *, start_ns: int = 0) -> None:
        self.scene = scene
        self.model = Model(scene)
        self.step_ns = scene.step_ns
        self.step_seconds = scene.step_ns * 1e-9
        method = scene.integrator
        if method == "auto":
            method = choose_method(self.model.stiffness(), self.step_seconds, self.model.size,
                                   self.model.contacts is not None)
        check_followed(scene, method)  # auto's pick, or a command line's --integrator
        self.integrator = make_integrator(method, scene.tolerance)
        # Steps from one publish instant to the next; 0 where the period is not a whole
        # number of steps, and a run stops after every step to look.
        self._per_publish = (0 if scene.publish_period_ns % scene.step_ns
                             else scene.publish_period_ns // scene.step_ns)
        if isinstance(self.integrator, ImplicitTheta):  # Jacobians by colored differences
            self.integrator.coloring_source = self.model.jacobian_coloring
        contacts = self.model.contacts
        if contacts is not None:
            contacts.follow(self.integrator.position_share)
        #: Wall impacts located inside the step (``contacts.events``), or None.
        self._events = (WallEvents(contacts, scene.tolerance)
                        if scene.events and contacts is not None and contacts.wall_bodies
                        else None)
        # Whole steps in the compiled kernel, used while the model's forces are compiled;
        # the kernel locates no events, so a scene that asks for them steps in Python.
        self._compiled = None if self._events is not None else compiled_steps(
            self.model.compiled, self.integrator, contacts, self.model.joints)
        self._embedded = (self.integrator if isinstance(self.integrator, EmbeddedRungeKutta)
                          else None)
        self._inputs = InputBuffer(scene.input_timeout_ns)
        #: Where the commands pushed so far act (:meth:`_resolved`), by body, frame and
        #: point: the body's row, the axes' and the point's bodies, the point, and the lever
        #: arm the reach check takes where the point is its own body's (else None).
        self._places: dict[tuple[Any, ...], Place] = {}
        #: Each body's mass and moment of inertia, as the reach check takes them.
        self._inertias = [(float(body.mass.mass), float(body.mass.moment_of_inertia))
                          for body in scene.bodies]
        #: Where the drives' wheels of the kernel's runs stand among the inputs
        #: (:meth:`_lay_out`), with the inputs' places it holds for; None: not yet.
        self._wheel_layout: Optional[tuple[Any, ...]] = None
        #: Whether the state each step begins from is kept (:meth:`keep_step_starts`).
        self._keeps_starts = False
        self.reset(start_ns)

    # ----------------------------------------------------------------- state

    def reset(self, start_ns: Optional[int] = None) -> None:
        """Return to the scene's initial state, drop all inputs, restart the clock."""
        if start_ns is not None:
            self.start_ns = stamp_time(int(start_ns), "start_ns")
        self._time_ns = self.start_ns
        self._steps = 0
        self.q, self.v = self.model.initial_state()
        self._inputs.clear()
        self.model.inputs = None
        self.integrator.reset()
        if self.model.contacts is not None:
            self.model.contacts.reset()
        if self.model.joints is not None:
            self.model.joints.reset(self.q)
        if self._events is not None:
            self._events.reset()
        self._bound = EnergyBound(self.model, self.q, self.v)
        if self._compiled is not None:  # its runs check this bound
            bound = self._bound.kernel_data()
            per = self._per_publish
            self._compiled.start(None if bound is None or not per else Runs(
                self.step_seconds, per, per * self.step_ns * 1e-9, bound))
        self._halted: Optional[str] = None  # why the energy bound stopped the run
        if isinstance(self.integrator, ImplicitTheta):
            self.integrator.step_check = self._bound.step_ok
        self._checked = (self.q.copy(), self.v.copy(), self._time_ns, self._steps)
        #: Where the last step began, while kept: the step count it ended at and the state
        #: (q, v), which None leaves in the kernel's stepper until asked for; None before
        #: a step or after the state was set.
        self._start: Optional[tuple[int, Optional[np.ndarray], Optional[np.ndarray]]] = None

    def keep_step_starts(self) -> None:
        """From now on, keep the state each step begins from (:meth:`step_start`)."""
        self._keeps_starts = True
        if self._compiled is not None:
            self._compiled.keep_starts()

    def step_start(self) -> Optional[tuple[np.ndarray, np.ndarray]]:
        """The state (q, v) the step that ended at the present instant began from, or None
        where it is not known: no step ended here since the state was set (a start, a
        reset, an import, a move or a clock skipped), or :meth:`keep_step_starts` came
        after it. What an IMU's accelerometer differences (:mod:`..sensors.imu`)."""
        start = self._start
        if start is None or start[0] != self._steps:
            return None
        q, v = start[1], start[2]
        if q is None or v is None:  # the kernel's: fetched once, where it is asked for
            assert self._compiled is not None
            q, v = self._compiled.step_start()
            self._start = (start[0], q, v)
        return q, v

    @property
    def time_ns(self) -> int:
        """Sim time of the current state."""
        return self._time_ns

    @property
    def steps(self) -> int:
        return self._steps

    def snapshot(self) -> Snapshot:
        """The published state of every body now, with the total energy."""
        return Snapshot(self._time_ns, self._steps, self.model, self.q, self.v)

    def export_state(self) -> dict[str, Any]:
        """Everything a continuation depends on, as plain data (float64 values exact, as
        Python floats): clock, step count, the state q and v, the input buffer, and what the
        integrator and the contact pass carry from step to step. A simulation of the same
        scene given it by :meth:`import_state` continues bit for bit as this one does."""
        return {
            "start_ns": self.start_ns, "time_ns": self._time_ns, "steps": self._steps,
            "q": self.q.tolist(), "v": self.v.tolist(),
            "inputs": self._inputs.export_state(),
            "integrator": self.integrator.export_state(),
            "contacts": None if self.model.contacts is None else self.model.contacts.export_state(),
            "joints": None if self.model.joints is None else self.model.joints.export_state(),
            "divergence": self._export_divergence(),
        }

    def _export_divergence(self) -> dict[str, Any]:
        """The energy bound's budget, the state a refused check goes back to, and why the
        bound stopped the run (None while it runs)."""
        q, v, time_ns, steps = self._checked
        return {"bound": self._bound.export_state(), "checked_q": q.tolist(),
                "checked_v": v.tolist(), "checked_time_ns": time_ns, "checked_steps": steps,
                "halted": self._halted}

    def import_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`export_state`'s data (of a simulation of the same scene)."""
        q, v = _numbers(state["q"], "q"), _numbers(state["v"], "v")
        if q.shape != self.q.shape or v.shape != self.v.shape:
            raise ValueError(f"a state of {len(q)} bodies does not fit a scene of "
                             f"{self.model.size}")
        start_ns, time_ns, steps = (_whole(state[key], key)
                                    for key in ("start_ns", "time_ns", "steps"))
        stamp_time(start_ns, "start_ns")
        # The clock stands at a step instant: a pause moves the start with it (skip_to).
        if steps < 0 or time_ns != start_ns + steps * self.step_ns:
            raise ValueError(f"a clock at {time_ns} ns after {steps} steps of "
                             f"{self.step_ns} ns from a start at {start_ns} ns")
        for spec, qi, vi in zip(self.scene.bodies, q.tolist(), v.tolist()):
            energy = spec.mass.energy_of_motion(math.hypot(vi[0], vi[1]), vi[2])
            if not (all(map(math.isfinite, qi)) and math.isfinite(energy)):
                raise ValueError(f"the state of '{spec.name}' ({qi}, {vi}) is not finite or "
                                 "moves it with an energy of motion past what a double holds")
        self.start_ns, self._time_ns, self._steps = start_ns, time_ns, steps
        self.q, self.v = q, v
        self._inputs.import_state(state["inputs"], self._row)
        rows = [held.row for held in self._inputs.active()]
        self.model.inputs = wrench_term(rows) if rows else None
        self.integrator.reset()
        self.integrator.import_state(state["integrator"])
        if self.model.contacts is not None:
            self.model.contacts.import_state(state["contacts"] or [])
        self._hold(rows)
        if self.model.joints is not None and state.get("joints") is not None:
            self.model.joints.import_state(state["joints"])
        divergence = state["divergence"]
        self._bound.import_state(divergence["bound"])
        checked_q, checked_v = (_numbers(divergence[key], key).reshape(shape) for key, shape
                                in (("checked_q", q.shape), ("checked_v", v.shape)))
        if not (np.isfinite(checked_q).all() and np.isfinite(checked_v).all()):
            raise ValueError("the last checked state (checked_q, checked_v) is not finite")
        self._checked = (checked_q, checked_v, int(divergence["checked_time_ns"]),
                         int(divergence["checked_steps"]))
        self._halted = divergence["halted"]
        self._start = None

    def __getstate__(self) -> dict[str, Any]:
        """What :mod:`pickle` and :func:`copy.deepcopy` keep: the scene and
        :meth:`export_state`'s plain data, not the compiled kernel's handles (capsules),
        which :meth:`__setstate__` builds anew, so a copy steps bit for bit as this does."""
        return {"scene": self.scene, "state": self.export_state()}

    def __setstate__(self, saved: dict[str, Any]) -> None:
        state = saved["state"]
        self.__init__(saved["scene"], start_ns=int(state["start_ns"]))  # type: ignore[misc]
        self.import_state(state)

    def _hold(self, rows: list[WrenchRow]) -> None:
        """Keep the bodies the inputs push awake (where resting islands sleep)."""
        contacts = self.model.contacts
        if contacts is not None and contacts.sleep:
            contacts.hold(row.body for row in rows)

    def set_body_state(self, name: str, position: tuple[float, float], angle: float,
                       linear_velocity: tuple[float, float], angular_velocity: float) -> None:
        """Move body ``name`` now: its frame to ``position`` and ``angle``, the frame's origin
        moving at ``linear_velocity``, turning at ``angular_velocity`` (what its pose and a
        world-frame twist publish). The contact pass forgets its warm starts, which belonged
        to the old positions, and every body wakes. Raises :class:`InputError` for an
        unknown body or a number that is not finite."""
        index = self.model.index.get(name)
        if index is None:
            raise InputError(f"unknown body '{name}' (bodies: {', '.join(self.model.names)})")
        numbers = (*position, angle, *linear_velocity, angular_velocity)
        if not all(math.isfinite(x) for x in numbers):
            raise InputError(f"the state for '{name}' has a non-finite value {numbers}")
        q, v = self.model.cm_states(np.array([index]), np.array([position], dtype=float),
                                    np.array([angle], dtype=float),
                                    np.array([linear_velocity], dtype=float),
                                    np.array([angular_velocity], dtype=float))
        energy = self.scene.bodies[index].mass.energy_of_motion(math.hypot(*v[0, :2]), v[0, 2])
        if not math.isfinite(energy):  # a state the energy bound could not judge
            raise InputError(f"the state for '{name}' moves it with an energy of motion past "
                             f"what a double holds ({numbers})")
        self.q, self.v = self.q.copy(), self.v.copy()
        self.q[index], self.v[index] = q[0], v[0]
        wrap_angles_in_place(self.q[:, 2])
        if self.model.contacts is not None:
            self.model.contacts.reset()
            self._hold([held.row for held in self._inputs.active()])
        if self.model.joints is not None:  # the next step moves it back onto its joints
            self.model.joints.forget()
        # The new state is where a refused check returns to, its energy within the budget.
        self._bound.moved(self.q, self.v, (self._time_ns - self._checked[2]) * 1e-9, (index,))
        self._checked = (self.q.copy(), self.v.copy(), self._time_ns, self._steps)
        self._start = None

    def with_world(self, scene: Scene, renewed: Iterable[str] = ()) -> Simulation:
        """A simulation of ``scene``, this one's world with bodies spawned or deleted (by
        name: :mod:`hecker_dynamics.scene.world`), going on from this one's state now.

        The bodies that stay keep their state; a spawned body starts in its scene's initial
        state, and so does each body named in ``renewed``: a body of this world deleted and
        spawned again under its name in the change, a new body that takes nothing of the
        old one's. The clock and step count, the integrator (the same method, whatever
        ``scene.integrator`` would pick) and what it carries, the joints' state and the
        commands held and pending carry over, the contacts' warm starts too where both
        bodies stay; commands on a deleted body, or given in its frame, are dropped. The
        energy bound goes on as after a moved body: the new energy joins its budget. The
        same change at the same state gives the same bits, and a spawn into a simulation
        that has not stepped gives the simulation of ``scene`` from its start. Every body
        is awake afterwards.
        """
        state = self.export_state()
        sim = Simulation(replace(scene, integrator=self.integrator.name), start_ns=self.start_ns)
        # The bodies that stay, by name in this world: a renewed body's name stands for
        # another body, which carries nothing (state, commands, warm starts, budget).
        gone = set(renewed)
        old = {name: i for name, i in self.model.index.items() if name not in gone}
        new = {name: i for name, i in sim.model.index.items() if name not in gone}
        q, v = sim.q.tolist(), sim.v.tolist()
        for name, i in new.items():
            if name in old:
                q[i], v[i] = state["q"][old[name]], state["v"][old[name]]
        state["q"], state["v"] = q, v
        fixed = scene.frame_id

        def kept(command: dict[str, Any]) -> bool:
            owner = str(command["frame_id"]).partition("/")[0]
            return command["body"] in new and (command["frame_id"] == fixed or owner in new)

        inputs = state["inputs"]
        inputs["pending"] = [entry for entry in inputs["pending"] if kept(entry[2])]
        inputs["active"] = [command for command in inputs["active"] if kept(command)]
        remap = {old[name]: i for name, i in new.items() if name in old}

        def key(a: int, b: int, *parts: int) -> Optional[list[int]]:
            if (a >= 0 and a not in remap) or b not in remap:
                return None
            return [remap[a] if a >= 0 else a, remap[b], *parts]

        if sim.model.contacts is not None:
            carried = state["contacts"] or []
            if isinstance(carried, dict):  # sleeping: only the warm starts carry over
                carried = carried["warm"]
            warm = [(key(*pair), contacts) for pair, contacts in carried]
            state["contacts"] = [[pair, contacts] for pair, contacts in warm if pair is not None]
        else:
            state["contacts"] = None
        # The new state is where a refused check returns to, as after a moved body.
        divergence = state["divergence"]
        divergence.update(checked_q=q, checked_v=v, checked_time_ns=self._time_ns,
                          checked_steps=self._steps,
                          bound=sim._bound.carried(divergence["bound"],
                                                   [old.get(name) for name in sim.model.names]))
        sim.import_state(state)
        sim._bound.moved(sim.q, sim.v, (self._time_ns - self._checked[2]) * 1e-9)
        return sim

    def skip_to(self, time_ns: int) -> None:
        """Move the clock forward to ``time_ns`` without stepping (a resume after a pause):
        the start moves with it, so publish instants and scripted times keep their places
        relative to it; commands keep their absolute stamps."""
        shift = int(time_ns) - self._time_ns
        if shift < 0 or shift % self.step_ns:
            raise ValueError(f"cannot skip by {shift} ns: not a whole number of steps forward")
        self._time_ns += shift
        self.start_ns += shift
        self._start = None

    # ----------------------------------------------------------------- inputs

    def holds_input(self, body: str, source: str) -> bool:
        """Whether a command on ``body`` from ``source`` is held or waits for its stamp (a
        new command from that source replaces it)."""
        return self._inputs.holds((body, source))

    def push(self, command: WrenchCommand) -> None:
        """Queue a command; raises :class:`InputError` (and changes nothing) if it is bad."""
        command.check_finite()
        if command.body not in self.model.index:
            raise InputError(f"unknown body '{command.body}' (bodies: "
                             f"{', '.join(self.model.names)})")
        short = shorter_than_a_step(command.duration_ns, self.step_ns)
        if short is not None:
            raise InputError(f"duration of the command for '{command.body}' from "
                             f"'{command.source}': {short}")
        if command.stamp_ns > self._time_ns + self.scene.input_max_lead_ns:
            raise InputError(
                f"command for '{command.body}' from '{command.source}' is stamped "
                f"{seconds_text(command.stamp_ns - self._time_ns)} s ahead of sim time "
                f"(limit {seconds_text(self.scene.input_max_lead_ns)} s)")
        end = self._inputs.end_of(command)
        if end is not None and end <= self._time_ns:
            raise InputError(
                f"command for '{command.body}' from '{command.source}' ended before the "
                f"current sim time (stamped {seconds_text(self._time_ns - command.stamp_ns)} "
                "s ago)")
        self._inputs.add(command, self.check_reach(command))

    def check_reach(self, command: WrenchCommand) -> WrenchRow:
        """``command``'s row (:meth:`_row`), or :class:`InputError` if its wrench, acting
        alone for one step from its body's motion now, would give the body an energy of
        motion no double holds: 1/2 m (|v| + |F| h / m)^2 + 1/2 I (|omega| + (|tau| +
        |r| |F|) h / I)^2, with the force over the mass (Eq. 5), the torque of the force at
        the lever arm r (Eq. 11) and the angular acceleration, torque over I (Eq. 14).
        1e308 N on 1 kg is 1e305 m/s a millisecond later, a finite state the energy bound
        could not judge. A drive's wheels push at points of their own body, whose lever
        arm their place keeps (:meth:`_resolved`)."""
        i, axes, owner, point, own_lever = self._resolved(command)
        fx, fy = command.force
        force = math.hypot(fx, fy)
        lever = 0.0
        if force:
            lever = own_lever if own_lever is not None else lever_arm(i, owner, point, self.q)
        mass, inertia = self._inertias[i]
        vx, vy, spin = self.v[i].tolist()
        h = self.step_seconds
        speed = math.hypot(vx, vy) + force * h / mass
        turn = abs(spin) + (abs(command.torque) + lever * force) * h / inertia
        if not math.isfinite(energy_of_motion(mass, inertia, speed, turn)):
            raise InputError(
                f"wrench for body '{command.body}' from '{command.source}' would give it an "
                f"energy of motion past what a double holds after one step of {h:g} s "
                f"({speed:.3g} m/s, {turn:.3g} rad/s; force={command.force}, "
                f"point={command.point}, torque={command.torque})")
        return WrenchRow(i, command.force, command.torque, axes, owner, point, True)

    def push_replacements(self, commands: Sequence[WrenchCommand]) -> None:
        """:meth:`push` each of ``commands``, stamped now, from bodies and sources whose
        commands act now (a drive's wheels at its control instant): where nothing else is
        pending, they skip the checks that cannot fail for them and the buffer's heap
        (:meth:`.InputBuffer.replace`), with the same bits and the same errors. The reach
        check (:meth:`check_reach`) can fail for them, so it stays."""
        try:
            for command in commands:
                command.check_finite()
            rows = [self.check_reach(command) for command in commands]
        except (InputError, KeyError):  # refused by push, as the same commands would be
            rows = None
        if rows is None or not self._inputs.replace(commands, rows, self._time_ns):
            for command in commands:
                self.push(command)

    def _row(self, command: WrenchCommand) -> WrenchRow:
        """The command as a constant-wrench row: its frame resolved to a body or the world.

        Where a command acts (its body, frame and point) is resolved once and kept, so the
        commands a drive sends from its wheels every control period share one resolved
        point, which lets the input set take their new values in place (:func:`.inputs.same_place`).
        """
        target, axes, owner, resolved, _ = self._resolved(command)
        return WrenchRow(target, command.force, command.torque, axes, owner, resolved, True)

    def _resolved(self, command: WrenchCommand) -> Place:
        """Where ``command`` acts (:meth:`_place`), resolved once for its body, frame and
        point and kept."""
        px, py = command.point
        # The signs tell 0.0 from -0.0, which compare equal but need not give the same bits.
        key = (command.body, command.frame_id, px, py, math.copysign(1.0, px),
               math.copysign(1.0, py))
        place = self._places.get(key)
        if place is None:
            if len(self._places) >= PLACES:  # bounded whatever points the inputs name
                self._places.clear()
            place = self._places[key] = self._place(command)
        return place

    def _place(self, command: WrenchCommand) -> Place:
        """Where ``command`` acts: its body's row, the body whose axes its force is in and
        the body its point is relative to (-1: the fixed frame), that point, and its
        distance from the CM where it is a point of the body itself, the lever arm a force
        there has whatever the state (None elsewhere)."""
        target = self.model.index[command.body]
        if command.frame_id == self.scene.frame_id:
            return Place(target, -1, -1, command.point, None)
        name, _, point_name = command.frame_id.partition("/")
        owner = self.model.index.get(name)
        if owner is None:
            raise InputError(f"unknown frame '{command.frame_id}' for a command on "
                             f"'{command.body}' (frames: '{self.scene.frame_id}', a body, "
                             "or '<body>/<point>')")
        origin = (0.0, 0.0)
        if point_name:
            points = self.scene.bodies[owner].points
            if point_name not in points:
                raise InputError(f"unknown frame '{command.frame_id}': body '{name}' has no "
                                 f"point '{point_name}' (points: {', '.join(points) or 'none'})")
            origin = points[point_name]
        point = (origin[0] + command.point[0], origin[1] + command.point[1])
        resolved = tuple(self.model.local(owner, point))
        return Place(target, owner, owner, resolved,
                     math.hypot(*resolved) if owner == target else None)

    # ----------------------------------------------------------------- stepping

    def step(self) -> None:
        """Advance one fixed step; raises :class:`DivergenceError` if the state blows up."""
        with np.errstate(all="ignore"):
            self._advance(1)

    def _advance(self, limit: int) -> int:
        """Take from 1 to ``limit`` steps (the floating-point error settings are the
        caller's) and return how many: in the compiled kernel as many as the inputs allow
        before they next change, else one in Python."""
        if self._halted is not None:  # refused again, as a non-finite step would be
            raise DivergenceError(self._halted)
        self._update_inputs()
        if self._compiled is None or not self._in_kernel():
            self._step()
            return 1
        limit = self._before_change(limit)
        q, v = self.q.copy(), self.v.copy()
        done = self._compiled.advance(q, v, self.step_seconds, limit, self.model.oriented,
                                      self._substep_size())
        self.q, self.v = q, v
        self._account(done)
        if self._keeps_starts and done[1]:
            self._start = (self._steps, None, None)
        return done[1]

    def _in_kernel(self) -> bool:
        """Whether the next steps run in the compiled kernel: the forces, contact pass and
        joint pass are all compiled."""
        contacts, joints = self.model.contacts, self.model.joints
        return self.model.compiled is not None and \
            (contacts is None or contacts.compiled) and (joints is None or joints.compiled)

    def _numpy_steps(self) -> bool:
        """Whether steps may do numpy arithmetic, which then needs quiet floating-point
        error settings (16 us to enter and leave with numpy 1.26, more than a few kernel
        steps): not where the kernel takes every step without a joint pass, and the energy
        bound's checks are plain floats or C."""
        return self._compiled is None or not self._in_kernel() or self.model.joints is not None

    def _before_change(self, limit: int) -> int:
        """``limit`` steps, or fewer so that the steps end where the inputs next change."""
        change = self._inputs.next_change()
        if change is None:
            return limit
        # The first step that starts at or after it sees the change.
        return min(limit, -(-(change - self._time_ns) // self.step_ns))

    def _substep_size(self) -> float:
        embedded = self._embedded
        return 0.0 if embedded is None else embedded.substep_size

    def _account(self, done: Advanced) -> None:
        """Count the steps the kernel took (the clock, the steps, the integrator's work,
        with an embedded pair's sub-step size carried over, as its steps in Python would),
        and raise where one failed; the state is the caller's to set first."""
        status, taken, evaluations, substeps, rejected, size = done  # a plain tuple
        counters = self.integrator.counters
        counters.evaluations += evaluations
        if self._embedded is not None:
            counters.substeps += substeps
            counters.rejected += rejected
            self._embedded.substep_size = size
        self._steps += taken
        self._time_ns += taken * self.step_ns
        if status != self._compiled.advanced:  # type: ignore[union-attr]
            failed, diverged = self._compiled.failure(status)  # type: ignore[union-attr]
            if diverged is not None:
                raise self._diverged(*diverged)
            if status == self._compiled.unsolved:  # type: ignore[union-attr]
                failed = f"{self._compiled.name}: {self._unsolved()}"  # type: ignore[union-attr]
            error = IntegrationError(failed)
            raise self._failed(error) from error

    def _run_checked(self, limit: int, snapshots: Optional[list[Snapshot]],
                     wheels: Optional[DrivenWheels] = None) -> int:
        """Up to ``limit`` steps in one kernel call, with the energy bound's checks at the
        publish instants passed (every publish period from the start) made in the kernel too
        (:meth:`.kernel.CompiledSteps.run`), and a snapshot of each instant appended to
        ``snapshots`` (None: none): what :meth:`advance_to` does one instant at a time,
        with the same bits, at one call's cost. Returns the steps taken; 0 where the
        kernel cannot take them so (a joint pass, whose joint states each snapshot takes
        from its pass, or a check that takes the rates of work again after it passes):
        then :meth:`advance_to` goes one instant at a time. With ``wheels``, the run takes
        their drives' control instants too (:meth:`run_drives`)."""
        compiled = self._compiled
        if self._halted is not None or compiled is None or self.model.joints is not None or \
                not self._in_kernel():
            return 0
        self._update_inputs()
        drives = None
        if wheels is None:
            if not self._bound.kernel_ready():  # inputs held: advance_to goes instant by instant
                return 0
            limit = self._before_change(limit)
        elif (drives := self._drive_columns(wheels)) is None:
            return 0
        if limit < 1:
            return 0
        step, per = self.step_ns, self._per_publish
        first = per - (self._time_ns - self.start_ns) // step % per  # steps to the next instant
        rows = max(1, RUN_VALUES // (6 * self.model.size))
        limit = min(limit, first + (rows - 1) * per)
        rows = 1 if limit <= first else 1 + -(-(limit - first) // per)
        qs, vs = np.empty((2, rows, *self.q.shape))
        start_ns, start_steps = self._time_ns, self._steps
        done, checked, worst = compiled.run(
            self.q, self.v, qs, vs, first, limit, self.model.oriented, self._substep_size(),
            (start_ns + first * step - self._checked[2]) * 1e-9, drives)
        if wheels is not None:
            self._take_wheels(wheels, start_ns + (first + (checked - 1) * per) * step
                              if checked else -1)
        taken = done[1]
        row = min(rows - 1, 0 if taken < first else 1 + (taken - first) // per)
        self.q, self.v = qs[row], vs[row]
        problem = self._bound.kernel_checked(worst) if checked else None
        passed = checked - (problem is not None)  # the instants whose check passed
        if passed:
            last = first + (passed - 1) * per
            self._checked = (qs[passed - 1], vs[passed - 1], start_ns + last * step,
                             start_steps + last)
            if snapshots is not None:  # rows of their own, never changed in place
                snapshots += map(Snapshot, range(start_ns + first * step, start_ns + last * step
                                                 + 1, per * step),
                                 range(start_steps + first, start_steps + last + 1, per),
                                 repeat(self.model), repeat(qs), repeat(vs), repeat(False),
                                 range(passed))
        self._account(done)
        if problem is not None:
            self._refuse(problem)
        if self._keeps_starts and taken:
            self._start = (self._steps, None, None)
        return taken

    def run_drives(self, t_ns: int, max_steps: Optional[int], keep: bool,
                   wheels: DrivenWheels) -> Optional[list[Snapshot]]:
        """:meth:`advance_to` ``t_ns`` (at most ``max_steps``) in one run of the kernel that
        also takes the control instants of the differential drives of ``wheels`` between its
        steps, their PI law and wheel forces, the reach check of the wheels' commands and
        the energy bound's rates of them in C (src/kernel/drive.h), with the bits of the
        drives' Python path (:func:`~..drives.control.advance_with_drives`), where every
        input is a wheel of theirs; the snapshots at the publish instants passed. The run
        ends early at an instant whose commands the simulation would refuse, which is the
        Python path's. None, with nothing done, where the kernel cannot take the run."""
        if self._compiled is None or not self._per_publish or self._halted is not None or \
                self.model.joints is not None or not self._in_kernel():
            return None
        left = self._steps_left(t_ns, max_steps, 0)
        snapshots: list[Snapshot] = []
        if not left or not self._run_checked(left, snapshots if keep else None, wheels):
            return None
        return snapshots

    def _drive_columns(self, wheels: DrivenWheels) -> Optional[DriveColumns]:
        """The run's data of ``wheels`` (:meth:`run_drives`), with the rows of their commands
        and the reach check's constants filled in (once for the inputs' places); None where
        the run cannot take them: other inputs, inputs whose rates of work the kernel cannot
        take (:meth:`.EnergyBound.kernel_inputs`), sleeping islands (which inputs keep
        awake), or a wheel whose command does not end at its drive's next instant."""
        term, contacts, inputs = self.model.inputs, self.model.contacts, self._inputs
        if term is None or (contacts is not None and contacts.sleep) or \
                not inputs.only_active(len(wheels.keys)):
            return None
        layout = self._wheel_layout
        if layout is None or layout[0] is not term.places or layout[1] is not wheels:
            layout = self._lay_out(term, wheels)
            if layout is None:
                return None
        keys, next_ns = wheels.keys, wheels.next_ns
        for k, key in enumerate(keys):
            if inputs.end(key) != next_ns[k // 2]:
                return None
        _, _, row_unit, row_rates, steady = layout
        return (wheels.ints, wheels.reals, row_unit, row_rates, steady, self._time_ns,
                self.step_ns, math.hypot)

    def _lay_out(self, term: ConstantWrenchTerm, wheels: DrivenWheels
                 ) -> Optional[tuple[Any, ...]]:
        """Where ``wheels``' commands stand among the inputs of ``term`` (all of them), into
        their columns with their bodies' masses and moments of inertia and their lever arms,
        and the energy bound's constants of the rows; kept (:attr:`_wheel_layout`) while
        the term keeps its places. None where the run cannot take them."""
        rows = self._inputs.wheels(wheels.keys)
        rates = None if rows is None else self._bound.kernel_inputs(term)
        if rows is None or rates is None:
            return None
        active = self._inputs.active()
        ints, reals = wheels.ints, wheels.reals
        for k, row in enumerate(rows):
            body, _, _, _, lever = self._resolved(active[row].command)
            if lever is None:
                return None
            drive = k // 2
            ints[drive, DriveInt.ROW_RIGHT if k % 2 else DriveInt.ROW_LEFT] = row
            reals[drive, DriveReal.MASS], reals[drive, DriveReal.INERTIA] = self._inertias[body]
            reals[drive, DriveReal.LEVER_RIGHT if k % 2 else DriveReal.LEVER_LEFT] = lever
        self._wheel_layout = (term.places, wheels, *rates)
        return self._wheel_layout

    def _take_wheels(self, wheels: DrivenWheels, last_check: int) -> None:
        """Take into the inputs what the kernel's run made of ``wheels``' commands (the run
        started now; its last check was at sim time ``last_check``, -1: none): each renewed
        wheel's command and row as the drives' Python path would have left them, the
        inputs' term with their new values, and whether the energy bound's input rates
        changed after its last check."""
        ints, reals = wheels.ints.tolist(), wheels.reals.tolist()
        renewed = []
        last = commands = 0
        for k, (drive_ints, drive_reals) in enumerate(zip(ints, reals)):
            instants = drive_ints[DriveInt.INSTANTS]
            if not instants:
                continue
            commands += 2 * instants
            stamp = drive_ints[DriveInt.LAST_NS]
            last = max(last, stamp)
            fx, fy, gx, gy = drive_reals[DriveReal.LEFT_X:DriveReal.RIGHT_Y + 1]
            renewed += [(wheels.keys[2 * k], stamp, (fx, fy)),
                        (wheels.keys[2 * k + 1], stamp, (gx, gy))]
        if not commands:
            if last_check >= 0:
                self._bound.kernel_inputs_taken(False)
            return
        self._inputs.renew(renewed, commands)
        rows = [held.row for held in self._inputs.active()]
        assert self.model.inputs is not None  # the wheels' term, its places kept
        self.model.inputs = self.model.inputs.with_values(rows)
        self._bound.kernel_inputs_taken(last >= last_check)
        self._hold(rows)

    def _update_inputs(self) -> None:
        """Make the inputs active now the model's (what the step from now sees)."""
        if self._inputs.update(self._time_ns):
            rows = [held.row for held in self._inputs.active()]
            term = self.model.inputs
            if term is not None and self._inputs.values_only:
                # A drive's control instant replaces its commands by ones at the same
                # points: the term keeps its places and takes the new values.
                self.model.inputs = term.with_values(rows)
            else:
                self.model.inputs = wrench_term(rows) if rows else None
            self._bound.inputs_changed(self.q, self.model.inputs)
            self._hold(rows)

    def accelerations(self) -> np.ndarray:
        """(ax, ay, alpha) per body at the present state with the inputs the next step
        takes: the summed forces over the mass (Eq. 5) and the angular acceleration, the
        summed torques over inertia (Eq. 14), as Model.accelerations gives them; what an
        IMU reads now."""
        self._update_inputs()
        if self.model.compiled is not None:  # the kernel's sums: no numpy arithmetic
            return self.model.accelerations(self.q, self.v)
        with np.errstate(all="ignore"):
            return self.model.accelerations(self.q, self.v)

    def _step(self) -> None:
        """One step in Python, the inputs already updated."""
        try:
            q, v = self._integrate(self.q, self.v, self.step_seconds)
        except (ArithmeticError, np.linalg.LinAlgError) as error:  # IntegrationError too
            raise self._failed(error) from error
        if not self._settle(q, v):
            raise self._diverged(q, v)
        if self._keeps_starts:  # a step's state is never changed in place
            self._start = (self._steps + 1, self.q, self.v)
        self.q, self.v = q, v
        self._steps += 1
        self._time_ns += self.step_ns

    def _unsolved(self, detail: str = "") -> str:
        """Why the joints gave up on a step whose parts ran out (``detail``: what the last
        part's pass said): the ring of their loads (those of the last part solved, the
        bodies at the step's start: :meth:`~..contact.joints.JointPass.ringing`) where even
        a step's shortest part cannot follow it, else what else it can be."""
        joints = self.model.joints
        assert joints is not None  # only joints give up so
        omega = joints.ring(self.q)
        if self.step_seconds / MOST_SUBSTEPS * omega > MAX_RING:
            return f"{UNSOLVED}: {ringing_advice(omega)}"
        return f"{UNSOLVED}{detail}: {unsolved_advice(self.scene)}"

    def _failed(self, error: Exception) -> DivergenceError:
        return DivergenceError(f"step at t = {seconds_text(self._time_ns)} s failed: {error}; "
                               "kept the last finite state")

    def _diverged(self, q: np.ndarray, v: np.ndarray) -> DivergenceError:
        """The error for a new state (q, v) that is not finite, naming its bodies."""
        bad = ~(np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1))
        names = ", ".join(np.array(self.model.names)[bad]) or "the bodies"
        return DivergenceError(f"state of {names} diverged at t = {seconds_text(self._time_ns)} s; "
                               "kept the last finite state")

    def _settle(self, q: np.ndarray, v: np.ndarray) -> bool:
        """Wrap the angles of a new state into [-pi, pi) in place; False if it is not finite.

        A few bodies are checked in plain floats, where numpy's cost per call would
        dominate.
        """
        if self.model.lean:
            rows = q.tolist()
            if not all(map(math.isfinite, (x for row in rows + v.tolist() for x in row))):
                return False
            if all(-math.pi <= row[2] < math.pi for row in rows):
                return True
        elif not (np.isfinite(q).all() and np.isfinite(v).all()):
            return False
        wrap_angles_in_place(q[:, 2])
        return True

    def _integrate(self, q: np.ndarray, v: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """One integrator step (with the wall impacts inside it located, where the scene
        asks), the joint pass and the contact pass; split into sub-steps when a colliding
        body would otherwise move more than half the thinnest colliding part. Joints go
        first so that the contacts have the last word on overlap; the contact pass solves
        the joints' velocity rows with the contacts of their islands, and what that leaves
        in the positions the next step's joint pass corrects, positions only."""
        contacts, joints = self.model.contacts, self.model.joints
        if contacts is not None and joints is None and self._events is None and \
                isinstance(self.integrator, FIXED_STEP) and contacts.everything_asleep():
            # Each body would be put back where it started (as the kernel skips it too);
            # the methods of FIXED_STEP carry nothing to the next step.
            return q.copy(), v.copy()
        f = self.model.accelerations
        start = self._time_ns * 1e-9
        q1, v1 = self._constrained_step(f, q, v, h, start)
        if contacts is None:
            return q1, v1
        parts = contacts.substeps(q, q1)
        if parts == 1:
            contacts.resolve(q1, v1, q, v, h)
            return q1, v1
        for part in range(parts):
            q1, v1 = self._constrained_step(f, q, v, h / parts, start + part * (h / parts))
            contacts.resolve(q1, v1, q, v, h / parts)
            q, v = q1, v1
        return q, v

    def _constrained_step(self, f: Callable[[np.ndarray, np.ndarray], np.ndarray],
                          q: np.ndarray, v: np.ndarray, h: float, start: float,
                          room: int = MOST_SUBSTEPS, pieces: int = 1
                          ) -> tuple[np.ndarray, np.ndarray]:
        """One integrator step of ``h`` and the joint pass, taken in equal parts when a
        joint's arm would turn further in it than the pass allows
        (:meth:`~..contact.joints.JointPass.parts`), in halves when the pass finds no
        solution near its end (:class:`~..contact.joints.JointsUnsolved`), each part the
        same way; ``room``: how many parts this step may still be cut into, in all (a
        step in :data:`~..contact.joints.MOST_SUBSTEPS` at most); ``pieces``: how many
        parts of the whole step this one is. A whole step starts in the parts the pass
        remembers from the last steps' halves (:meth:`~..contact.joints.JointPass.remember`).
        Soft joints (:mod:`~..contact.soft_joints`) take every step in their equal
        sub-steps instead, each a free step and their pass."""
        joints = self.model.joints
        if joints is not None and joints.substeps:
            part = h / joints.substeps
            for k in range(joints.substeps):
                q1, v1 = self._free_step(f, q, v, part, start + k * part)
                joints.resolve(q, q1, v1, part)
                q, v = q1, v1
            return q, v
        q1, v1 = self._free_step(f, q, v, h, start)
        if joints is None:
            return q1, v1
        whole = room == MOST_SUBSTEPS
        parts = min(max(joints.parts(q, q1), joints.remembered if whole else 1), room)
        if parts == 1:
            try:
                joints.resolve(q, q1, v1, h)
                if whole:
                    joints.remember()
                return q1, v1
            except JointsUnsolved as error:
                if room < 2:  # the kernel's words (_account): a replay's diagnostics alike
                    raise IntegrationError(f"{self.integrator.name}: "
                                           f"{self._unsolved()}") from error
            parts = 2
            joints.needed = max(joints.needed, 2 * pieces)
        part = h / parts
        for k in range(parts):
            q, v = self._constrained_step(f, q, v, part, start + k * part, room // parts,
                                          pieces * parts)
        if whole:
            joints.remember()
        return q, v

    def _free_step(self, f: Callable[[np.ndarray, np.ndarray], np.ndarray], q: np.ndarray,
                   v: np.ndarray, h: float, start: float) -> tuple[np.ndarray, np.ndarray]:
        """One integrator step of ``h`` from time ``start`` (s), with the wall impacts
        inside it located and answered where the scene asks (:mod:`..contact.events`)."""
        if self._events is None:
            return self.integrator.step(f, q, v, h)
        return self._events.step(self.integrator.step, f, q, v, h, start)

    @property
    def impacts(self) -> list[Impact]:
        """The latest wall impacts located inside steps, oldest first (empty without
        ``contacts.events``)."""
        return [] if self._events is None else list(self._events.impacts)

    def advance_to(self, t_ns: int, max_steps: Optional[int] = None, *,
                   keep: bool = True) -> list[Snapshot]:
        """Step while a whole step fits before ``t_ns`` (at most ``max_steps``).

        Returns the snapshots at the publish instants passed: every ``publish_period_ns``
        after the start time (none with ``keep`` false: a long run in bounded memory).
        """
        snapshots: list[Snapshot] = []
        kept = snapshots if keep else None
        period, step, start = self.scene.publish_period_ns, self.step_ns, self.start_ns
        per_publish = self._per_publish
        taken = 0
        left = self._steps_left(t_ns, max_steps, taken)
        # The kernel's runs first: they need no floating-point error settings, which cost
        # a smooth run more than its steps.
        refused = None  # the instant the kernel's run was refused at, not asked again there
        while per_publish and left:
            ran = self._run_checked(left, kept)
            if not ran:
                refused = self._time_ns
                break
            taken += ran
            left = self._steps_left(t_ns, max_steps, taken)
        if not left:
            return snapshots
        with np.errstate(all="ignore") if self._numpy_steps() else nullcontext():
            while left:
                ran = per_publish and self._time_ns != refused and \
                    self._run_checked(left, kept)
                if not ran:
                    ran = self._advance(min(left, per_publish - (self._time_ns - start) // step
                                            % per_publish if per_publish else 1))
                    if (self._time_ns - start) % period == 0:
                        self._check_energy()
                        if keep:  # the state just checked, never changed in place
                            snapshots.append(Snapshot(self._time_ns, self._steps, self.model,
                                                      self.q, self.v, False))
                taken += ran
                left = self._steps_left(t_ns, max_steps, taken)
        return snapshots

    def _steps_left(self, t_ns: int, max_steps: Optional[int], taken: int) -> int:
        """How many whole steps still fit before ``t_ns``, ``taken`` of ``max_steps``
        (None: no limit) taken."""
        left = max((t_ns - self._time_ns) // self.step_ns, 0)
        return left if max_steps is None else min(left, max_steps - taken)

    def _check_energy(self) -> None:
        """At a publish instant: refuse a state past the energy bound, going back to the
        state of the last check that passed."""
        problem = self._bound.check(self.q, self.v, (self._time_ns - self._checked[2]) * 1e-9)
        if problem is not None:
            self._refuse(problem)
        # The state is never changed in place (each step, move or import makes new arrays),
        # so the check keeps it, and the publish snapshots share it, without copies.
        self._checked = (self.q, self.v, self._time_ns, self._steps)

    def _refuse(self, problem: str) -> NoReturn:
        """The state now failed the energy bound's check (``problem``): go back to the
        state of the last check that passed, and stop the run."""
        q, v, time_ns, steps = self._checked
        now = self._time_ns
        self.q, self.v, self._time_ns, self._steps = q.copy(), v.copy(), time_ns, steps
        self._start = None
        over = [self.model.names[body] for body in self._bound.over]
        names = ", ".join(over[:5]) + (", ..." if len(over) > 5 else "")
        self._halted = (f"state of {names} diverged by t = {seconds_text(now)} s: {problem}; "
                        f"kept the state at t = {seconds_text(time_ns)} s")
        raise DivergenceError(self._halted)

    def play(self, commands: tuple[WrenchCommand, ...], until_ns: int, *,
             keep: bool = True,
             progress: Optional[Callable[[float], None]] = None,
             advance: Optional[Callable[[int], list[Snapshot]]] = None) -> list[Snapshot]:
        """Push ``commands`` (stamps relative to the start time) as sim time reaches each
        stamp, and advance to ``until_ns`` after the start; returns the snapshots passed
        (none with ``keep`` false). Commands stamped at or after ``until_ns`` are not
        pushed. ``progress`` is called with the fraction of ``until_ns`` done, about
        ``PROGRESS_UPDATES`` times, always at publish instants, so a run that reports its
        progress takes the same steps as one that does not. ``advance``, if given, takes the
        simulation to a sim time instead (a loop that acts on the way, such as drives)."""
        snapshots = []
        end_ns = self.start_ns + until_ns
        for command in sorted(commands, key=lambda c: c.stamp_ns):
            if command.stamp_ns >= until_ns:
                break
            stamp = self.start_ns + command.stamp_ns
            snapshots += (self._advance_reporting(stamp, end_ns, keep, progress)
                          if advance is None else advance(stamp))
            self.push(replace(command, stamp_ns=stamp))
        return snapshots + (self._advance_reporting(end_ns, end_ns, keep, progress)
                            if advance is None else advance(end_ns))

    def _advance_reporting(self, t_ns: int, end_ns: int, keep: bool,
                           progress: Optional[Callable[[float], None]]) -> list[Snapshot]:
        """:meth:`advance_to` ``t_ns``, in chunks of whole publish periods when ``progress``
        is given, calling it after each chunk with the fraction of the span to ``end_ns``."""
        if progress is None:
            return self.advance_to(t_ns, keep=keep)
        span = max(end_ns - self.start_ns, 1)
        period = self.scene.publish_period_ns
        chunk = period * max(1, span // (PROGRESS_UPDATES * period))
        snapshots = []
        boundary = (self._time_ns - self.start_ns) // chunk + 1  # in chunks from the start
        while True:
            target = min(t_ns, self.start_ns + boundary * chunk)
            snapshots += self.advance_to(target, keep=keep)
            progress(min((self._time_ns - self.start_ns) / span, 1.0))
            if target == t_ns:
                return snapshots
            boundary += 1
