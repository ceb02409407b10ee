"""The compiled kernel: the force model and the explicit integrators in C, when built.

``hecker_dynamics._kernel`` (sources in ``src/kernel/``) is built by pip when a C compiler
and Python's headers are present, and always by colcon. It evaluates the same force terms
as :mod:`.forces` (and the energy bound's checks of :mod:`.divergence`, unit by unit of
bodies) and steps the explicit methods of :mod:`.integrators` (with the
joint pass of :mod:`..contact.joints_kernel` and the contact pass of
:mod:`..contact.compiled` after each step in scenes with joints and contacts, and in its
runs the control instants of differential drives, src/kernel/drive.c), repeating
the plain-float path operation for operation: the accelerations and the fixed-step methods
give the same bits as Python's plain-float path, and the adaptive methods (whose stage
sums Python leaves to numpy's matrix products) agree with Python to rounding per step.
(Spring lengths whose squares under- or overflow, below 1e-154 m or above 1e154 m, use
C's and Python's hypot, which may differ in the last bit.) Without it, or with the
environment variable ``HECKER_DYNAMICS_KERNEL=0``, everything runs in Python.

This module only translates: each force term is packed into the kernel's layout (integer
and real columns per instance, see ``src/kernel/kernel.h``) once, and the inputs' term
again whenever the active inputs change. It is handed what it needs (the bodies' inverse
masses and the terms; an integrator's settings and state) and reads nothing back: what a
run of steps did comes back in :class:`Advanced`, for the caller to account.
"""
from __future__ import annotations

import enum
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from typing import TYPE_CHECKING, Any, NamedTuple, Optional

import numpy as np

from ..contact.joints import UNSOLVED, UNSOLVED_ADVICE
from ..integrators.methods import EmbeddedRungeKutta, Integrator
from .forces import (
    AnchorSpringTerm,
    AngularDampingTerm,
    BodySpringTerm,
    CenterDragTerm,
    ConstantWrenchTerm,
    ForceTerm,
    GravityTerm,
    PointDragTerm,
)

if TYPE_CHECKING:
    from ..contact.joints import JointPass
    from ..contact.solver import ContactPass

try:
    from .. import _kernel  # type: ignore[attr-defined]
except ImportError:  # not built: no compiler or headers when installed
    _kernel = None

__all__ = ["built", "enabled", "chosen", "unit_energy", "bound_check", "pack", "BoundData", "Runs",
           "DriveInt", "DriveReal", "DriveColumns", "CompiledForces", "Advanced", "CompiledSteps",
           "compiled_steps"]

#: The environment variable that switches the kernel off when set to "0".
SWITCH = "HECKER_DYNAMICS_KERNEL"


def built() -> bool:
    """True if the compiled kernel was built and imports."""
    return _kernel is not None


#: The path :func:`chosen` sets for the models its caller makes (None: the environment's).
_CHOSEN: ContextVar[Optional[bool]] = ContextVar("hecker_dynamics_kernel", default=None)


def enabled() -> bool:
    """True if new models use the kernel: it is built and not switched off (by
    :func:`chosen`, else by the environment)."""
    choice = _CHOSEN.get()
    return built() and (os.environ.get(SWITCH, "1") != "0" if choice is None else choice)


@contextmanager
def chosen(compiled: bool) -> Iterator[None]:
    """Within it, the models this thread makes use the kernel (``compiled``, where it is
    built) or the Python path, whatever the environment says: a check replays a recording
    on the path the node ran. A :class:`~hecker_dynamics.World` makes its model at its
    first step, so step it within the block; threads started in it do not inherit it."""
    token = _CHOSEN.set(compiled)
    try:
        yield
    finally:
        _CHOSEN.reset(token)


def unit_energy(springs: Any, q: np.ndarray, v: np.ndarray, statics: np.ndarray,
                unit: np.ndarray, budget: np.ndarray) -> None:
    """Each unit's energy and excess over the floors into rows ENERGY and EXCESS of the
    energy bound's ``budget``, in the kernel, as :class:`~.divergence.EnergyBound`'s
    plain-float loop sums them (``springs``: :attr:`CompiledForces.program` of the
    springs, or None)."""
    _kernel.bound(springs, q=q, v=v, statics=statics, unit=unit, budget=budget)


def bound_check(springs: Any, q: np.ndarray, v: np.ndarray, statics: np.ndarray,
                unit: np.ndarray, budget: np.ndarray, seconds: float, growth: float) -> float:
    """One check of the energy bound in the kernel, as
    :meth:`~.divergence.EnergyBound._check_python` does it: the largest ratio of a unit's
    excess to its limit."""
    return float(_kernel.bound(springs, q=q, v=v, statics=statics, unit=unit, budget=budget,
                               seconds=seconds, growth=growth))


Packed = tuple[int, np.ndarray, np.ndarray]  # (kind, ints, reals) as in kernel.h
#: An energy bound's data for the kernel's checks: the springs' program (or None), the
#: statics, the unit of each body, the budget (written in place) and the growth factor.
BoundData = tuple[Any, np.ndarray, np.ndarray, np.ndarray, float]


#: The integer columns of a differential drive the kernel's run takes (src/kernel/drive.h,
#: enum hd_drive_int), and its real columns (enum hd_drive_real).
DriveInt = enum.IntEnum("DriveInt", "BODY PERIOD_NS ROW_LEFT ROW_RIGHT COMMANDED RESTAMP "
                        "STAMP_NS TIMEOUT_NS NEXT_NS INSTANTS LAST_NS", start=0)
DriveReal = enum.IntEnum("DriveReal", "PERIOD LINEAR_KP LINEAR_KI ANGULAR_KP ANGULAR_KI "
                         "SEPARATION MAX_FORCE TRACTION LATERAL_DAMPING AXLE_Y OFFSET_LEFT "
                         "OFFSET_RIGHT MASS INERTIA LEVER_LEFT LEVER_RIGHT LINEAR_X "
                         "ANGULAR_Z INTEGRAL_V INTEGRAL_W LEFT_X LEFT_Y RIGHT_X RIGHT_Y",
                         start=0)


#: The most drives one run takes, and the columns of each (src/kernel/drive.h).
DRIVE_MOST = 0 if _kernel is None else _kernel.DRIVE_MOST
DRIVE_INTS, DRIVE_REALS = len(DriveInt), len(DriveReal)

#: What a run takes of its differential drives (src/kernel/drive.h): the ints and reals of
#: each (written by the run), per row of the inputs (every one a drive's wheel) its body's
#: unit and sqrt(2 / m), sqrt(2 / I) and lever arm, each unit's steady rate, the run's start
#: and step (ns), and the length it takes (math.hypot).
DriveColumns = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int,
                     Callable[[float, float], float]]


class Runs(NamedTuple):
    """What the kernel's runs (:meth:`CompiledSteps.run`) share from call to call: the
    step ``h`` (s), the steps ``per`` from one publish instant to the next and their
    ``period_seconds``, and the energy bound's data ``bound`` it checks."""

    h: float
    per: int
    period_seconds: float
    bound: BoundData


def _packed(kind: int, ints: list[np.ndarray], reals: list[np.ndarray]) -> Packed:
    """A term's columns, one row per instance: C-contiguous int64 and float64."""
    return (kind, np.ascontiguousarray(np.column_stack(ints), dtype=np.int64),
            np.ascontiguousarray(np.column_stack(reals), dtype=np.float64))


def _law(term: AnchorSpringTerm | BodySpringTerm) -> list[np.ndarray]:
    return [term.law.stiffness, term.law.rest_length, term.law.damping]


def _packed_wrenches(term: ConstantWrenchTerm) -> Packed:
    """The wrenches' columns (body, axes, point body, at point; force, torque, point) read
    off their rows: the inputs pack a new term whenever they change."""
    reals = [(f[0], f[1], torque, p[0], p[1]) for _, f, torque, _, _, p, _ in term.rows]
    return (_kernel.WRENCH, term.places, np.array(reals, dtype=np.float64).reshape(-1, 5))


#: Per kind of term: its columns in the kernel's layout (kernel.h, enum TermKind; the kind
#: codes are the module's constants).
_PACKERS: dict[type, Callable[..., Packed]] = {
    GravityTerm: lambda t: _packed(_kernel.GRAVITY, [t.bodies], [t.weights]),
    AnchorSpringTerm: lambda t: _packed(_kernel.ANCHOR_SPRING, [t.body],
                                        [t.local, t.anchor, *_law(t)]),
    BodySpringTerm: lambda t: _packed(_kernel.BODY_SPRING, [t.body_a, t.body_b],
                                      [t.local_a, t.local_b, *_law(t)]),
    CenterDragTerm: lambda t: _packed(_kernel.CENTER_DRAG, [t.body, t.quadratic],
                                      [t.coefficient]),
    PointDragTerm: lambda t: _packed(_kernel.POINT_DRAG, [t.body, t.quadratic],
                                     [t.local, t.coefficient]),
    AngularDampingTerm: lambda t: _packed(_kernel.ANGULAR_DAMPING, [t.body], [t.coefficient]),
    ConstantWrenchTerm: _packed_wrenches,
}


def pack(term: ForceTerm) -> Packed:
    """A force term in the kernel's layout."""
    return _PACKERS[type(term)](term)


class CompiledForces:
    """A model's forces as a kernel program, with the active inputs as a second one."""

    def __init__(self, inverse_mass: np.ndarray, terms: Sequence[ForceTerm]) -> None:
        """``inverse_mass``: (N, 3) rows (1/m, 1/m, 1/I) of the N bodies; ``terms``: the
        scene's force terms."""
        self.bodies = len(inverse_mass)
        self.program = _kernel.program(bodies=self.bodies,
                                       inverse_mass=np.ascontiguousarray(inverse_mass),
                                       terms=[pack(term) for term in terms])
        self.inputs = None
        self._places: Optional[np.ndarray] = None  # where the inputs' program acts

    def set_inputs(self, term: Optional[ConstantWrenchTerm]) -> None:
        """The wrenches of the inputs active from now on (None: none). A term that shares
        the places of the last one (:meth:`.ConstantWrenchTerm.with_values`: a drive's
        control instant) gives the program its new forces and torques in place."""
        if term is None:
            self.inputs = None
        elif self.inputs is not None and term.places is self._places:
            _kernel.wrench_values(self.inputs, values=[
                value for _, (fx, fy), torque, *_ in term.rows for value in (fx, fy, torque)])
        else:
            packed = pack(term)
            self._places = packed[1]
            self.inputs = _kernel.program(bodies=self.bodies, inverse_mass=None,
                                          terms=[packed])

    def accelerations(self, q: np.ndarray, v: np.ndarray, oriented: bool) -> np.ndarray:
        """(ax, ay, alpha) per body, as :meth:`.Model.accelerations`."""
        out = np.empty((self.bodies, 3))
        _kernel.accelerations(self.program, inputs=self.inputs, oriented=oriented,
                              q=np.ascontiguousarray(q), v=np.ascontiguousarray(v), out=out)
        return out


#: The integrators the kernel steps, by name, with the name of the kernel's code for each.
KERNEL_METHODS = {"explicit_euler": "EXPLICIT_EULER",
                  "semi_implicit_euler": "SEMI_IMPLICIT_EULER",
                  "velocity_verlet": "VELOCITY_VERLET", "rk4": "RK4", "dopri5": "EMBEDDED",
                  "dop853": "EMBEDDED"}

#: The kernel's failures of an integrator, by the name of their status code.
_FAILURES = {"SUBSTEP_UNDERFLOW": "the sub-step size underflowed",
             "TOO_MANY_SUBSTEPS": f"more than {EmbeddedRungeKutta.MAX_SUBSTEPS} sub-steps in "
                                  "one step",
             "JOINTS_UNSOLVED": f"{UNSOLVED}: {UNSOLVED_ADVICE}"}


class Advanced(NamedTuple):
    """What :meth:`CompiledSteps.advance` did: whether it went through (``status``: the
    kernel's ADVANCED, else why it stopped early, which :meth:`CompiledSteps.failure`
    explains), steps completed, and the work done (force evaluations; accepted and rejected
    sub-steps and the sub-step size to carry on with, for an embedded pair). A plain tuple
    in this order is what the kernel returns; this names its fields."""

    status: int
    taken: int
    evaluations: int
    substeps: int
    rejected: int
    substep_size: float


class CompiledSteps:
    """Whole steps of an explicit integrator on compiled forces."""

    def __init__(self, forces: CompiledForces, integrator: Integrator,
                 contacts: Optional[ContactPass] = None,
                 joints: Optional[JointPass] = None) -> None:
        """Steps of the method ``integrator`` names, with its embedded pair and tolerance,
        and the compiled joint pass of ``joints`` and contact pass of ``contacts`` after
        each step."""
        self.forces, self.name, self.contacts = forces, integrator.name, contacts
        self.joints = joints
        self.method = getattr(_kernel, KERNEL_METHODS[integrator.name])
        self._failures = {getattr(_kernel, name): text for name, text in _FAILURES.items()}
        #: The status of a call whose joints had no solution in a step's last parts.
        self.unsolved = _kernel.JOINTS_UNSOLVED
        self.pair = None
        self.tolerance = 0.0
        if isinstance(integrator, EmbeddedRungeKutta):
            pair = integrator.pair
            self.pair = _kernel.pair(slopes=pair.slopes, a=np.ascontiguousarray(pair.a),
                                     error=np.ascontiguousarray(pair.error),
                                     error_order=pair.error_order)
            self.tolerance = integrator.tolerance
        self.stepper: Any = None
        #: Whether the stepper keeps where each call's last step began (:meth:`keep_starts`).
        self.keeps_starts = False
        self.start(None)
        #: The status of a call that took all its steps.
        self.advanced = _kernel.ADVANCED

    def start(self, runs: Optional[Runs]) -> None:
        """Build the kernel's stepper: the method bound to the program and the contact
        pass, with the memory its steps need, kept from call to call, and what the runs of
        :meth:`run` share (None: no runs), packed once so that each run passes only what
        changes: a new energy bound (a reset) needs a new stepper."""
        contacts = self.contacts
        fixed: dict[str, Any] = {}
        if runs is not None:
            springs, statics, unit, budget, growth = runs.bound
            fixed = dict(h=runs.h, per=runs.per, period_seconds=runs.period_seconds,
                         springs=springs, statics=statics, unit=unit, budget=budget,
                         growth=growth)
        self.stepper = _kernel.stepper(
            program=self.forces.program, method=self.method, pair=self.pair,
            tolerance=self.tolerance,
            contacts=None if contacts is None else contacts.kernel_pass(), **fixed)
        if self.keeps_starts:
            _kernel.keep_starts(self.stepper)

    def keep_starts(self) -> None:
        """From now on, keep the state each call's last step began from
        (:meth:`step_start`)."""
        self.keeps_starts = True
        _kernel.keep_starts(self.stepper)

    def step_start(self) -> tuple[np.ndarray, np.ndarray]:
        """The state, (q, v) (N, 3) each, the last step of the last call of :meth:`advance`
        or :meth:`run` that took one began from (:meth:`keep_starts` before it)."""
        bodies = self.forces.bodies
        q, v = np.empty((bodies, 3)), np.empty((bodies, 3))
        _kernel.step_start(self.stepper, q=q, v=v)
        return q, v

    def advance(self, q: np.ndarray, v: np.ndarray, h: float, steps: int, oriented: bool,
                substep_size: float = 0.0) -> Advanced:
        """Advance (q, v), C-contiguous (N, 3) arrays, in place by up to ``steps`` steps of
        ``h`` seconds, wrapping angles after each; stop at the first failing step, leaving
        the last good state in (q, v). ``oriented``: some active force needs the angles;
        ``substep_size``: an embedded pair's sub-step size to start from. The kernel's
        tuple, as :class:`Advanced` names it (plain, at each publish instant's cost)."""
        joints = self.joints
        if joints is None:
            return _kernel.step(self.stepper, inputs=self.forces.inputs, oriented=oriented, q=q,
                                v=v, h=h, steps=steps, size=substep_size, joints=None)
        done = _kernel.step(self.stepper, inputs=self.forces.inputs, oriented=oriented, q=q,
                            v=v, h=h, steps=steps, size=substep_size,
                            joints=joints.kernel_pass())
        joints.kernel_done()
        return done

    def run(self, q: np.ndarray, v: np.ndarray, qs: np.ndarray, vs: np.ndarray, first: int,
            steps: int, oriented: bool, substep_size: float, first_seconds: float,
            drives: Optional[DriveColumns] = None) -> tuple[Advanced, int, float]:
        """Take ``steps`` steps of the :class:`Runs` given to :meth:`start` from (q, v),
        left as they are, as :meth:`advance` takes them (no joint pass), and check its
        energy bound at each publish instant: after ``first`` steps, over
        ``first_seconds``, and every ``per`` steps after it, over ``period_seconds``, as
        :meth:`~.divergence.EnergyBound.check` does. The steps from one instant to the next
        go into the next row of (qs, vs), (segments, N, 3) arrays; the run stops at the
        first failing step or after the first check over 1. ``drives``: the differential
        drives whose wheels are all the inputs, their control instants taken inside the run
        (:data:`DriveColumns`; the run ends at one they leave to Python). Returns what
        :meth:`advance` does (a plain tuple too), the checks made and their largest ratio."""
        done = _kernel.run(self.stepper, inputs=self.forces.inputs, oriented=oriented, q=q,
                           v=v, qs=qs, vs=vs, first=first, steps=steps, size=substep_size,
                           first_seconds=first_seconds, drives=drives)
        return done[:6], done[6], done[7]

    def failure(self, status: int) -> tuple[Optional[str], Optional[tuple[np.ndarray,
                                                                          np.ndarray]]]:
        """Why a call of :meth:`advance` with ``status`` stopped early: the integrator's
        failure, or the new state that was not finite (N, 3 each)."""
        if status == _kernel.NOT_FINITE:
            bodies = self.forces.bodies
            q_new, v_new = np.empty((bodies, 3)), np.empty((bodies, 3))
            _kernel.failed_state(self.stepper, q=q_new, v=v_new)
            return None, (q_new, v_new)
        return f"{self.name}: {self._failures[status]}", None


def compiled_steps(forces: Optional[CompiledForces], integrator: Integrator,
                   contacts: Optional[ContactPass],
                   joints: Optional[JointPass] = None) -> Optional[CompiledSteps]:
    """The kernel's stepping of ``integrator`` on ``forces``, if it can take whole steps:
    the forces (and the contact and joint passes, if any) are compiled and the method is
    explicit."""
    if forces is None or integrator.name not in KERNEL_METHODS or \
            (contacts is not None and not contacts.compiled) or \
            (joints is not None and not joints.compiled):
        return None
    return CompiledSteps(forces, integrator, contacts, joints)
