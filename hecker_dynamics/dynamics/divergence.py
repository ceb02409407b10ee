"""Bounds on the energy each part of a scene can reach, to tell a blown-up state from motion.

**Units.** Bodies pass energy to each other only through what joins them: a spring
between two bodies, a joint (a gear joins the bodies of its two pins), and contacts
between the bodies of a collision group. The scene's bodies fall into *units*, the
connected groups of that graph (walls and joints to the fixed frame join nothing); a
body alone is a unit of its own. No energy crosses from one unit to another, so each is
bounded by itself, and a heavy body in one unit cannot hide a light body's blow-up in
another.

**The bound of a unit.** Its energy of motion and of its springs, B = K + U_springs,
changes only by the work of the forces (K's rates follow from the force by F = M a,
Eq. 5, and from the torque by tau = I alpha, Eq. 14). Springs, joints' springs and soft
welds exchange energy with K, and dampers, drag, angular damping, limits, walls and
collisions (restitution at most 1) take it away; rigid joints do no work. Work comes in
from two kinds of source:

- gravity, constant forces and torques and inputs: a force F on body i acting at a point
  r from its CM, with a torque tau, works at the rate
  F . v_i + (r x F + tau) omega_i <= (|F| sqrt(2 / m_i) + (|r| |F| + |tau|) sqrt(2 / I_i))
  sqrt(B), since K_i = m_i |v_i|^2 / 2 + I_i omega_i^2 / 2 <= B. With c the sum of those
  coefficients over the unit's bodies, dB/dt <= c sqrt(B);
- joint motors: a motor holds its joint's speed at its target s with at most its
  largest torque or force tau_max, which pushes toward s: its power tau w, w the joint's
  speed (J v, the rate of the joint's coordinate), is at most tau_max |s| (it is
  negative whenever the joint turns the other way or faster than s) and at most
  tau_max |w|. Both bound it at every instant, so two bounds follow, each valid alone:

  - with P the sum of tau_max |s| over the unit's motors, dB/dt <= c sqrt(B) + P;
  - with w bounded by the energy: a revolute joint's w = omega_b - omega_a, and
    I_a omega_a^2 / 2 + I_b omega_b^2 / 2 <= B (a body of the fixed frame has no
    term), so by Cauchy-Schwarz |w| <= sqrt(2 (1 / I_a + 1 / I_b)) sqrt(B). A
    slider on the fixed frame moves its body's point r_b from the CM along the axis u:
    w = u . v_b + (perp(r_b) . u) omega_b, so |w| <= sqrt(2 (1 / m_b + |r_b|^2 / I_b))
    sqrt(B). Between two bodies the axis turns with body_a about body_b's point P_B, and
    w = u . v_b + (perp(r_b) . u) omega_b - u . v_a - (perp(s) . u) omega_a, s = P_B - x_a
    (the motor row's Jacobian, ``contact/joint_rows.py: line_entries``): by
    Cauchy-Schwarz over the six velocities weighted by the masses and inertias,
    |w| <= sqrt(2 (1 / m_a + 1 / m_b + |r_b|^2 / I_b + |s|^2 / I_a)) sqrt(B), since
    |perp(r) . u| <= |r| for the unit axis u; |s| <= |r_b| + |x_b - x_a|
    (``forces.lever_arm``) follows the state. With c_m the sum over the unit's motors of
    tau_max times that coefficient, dB/dt <= (c + c_m) sqrt(B).

So sqrt(B(t)) <= R(t) + min(sqrt(W(t)), M(t)), with R(t) = sqrt(B(0)) + int c dt / 2,
W(t) = int P dt and M(t) = int c_m dt / 2: the right side squared, G, grows by
dG/dt >= c sqrt(G) + P with sqrt(W), by dG/dt = (c + c_m) sqrt(G) with M, each the
bound's own rate, and both start at or above sqrt(B(0)). From rest under a constant
force, R is met with equality; so is M under a motor at its full effort on a wheel. P
counts the target speed however slowly the joint turns (a motor of 20 N m aiming at
1e12 rad/s is 2e13 W), c_m counts the wheel's energy however fast the target: the bound
takes the smaller. The potential energy of joints' springs and soft welds is not in B
(it is never negative, so leaving it out only lowers B); what they hold at the start, a
wound rotary spring's, joins B(0).

:class:`EnergyBound` keeps R, W and M per unit as the simulation runs (c from the state
at each check, the largest input set since the last one; P from the motors' target
speeds at the last check and now; c_m from the masses and the motors' efforts, and for
a slider between two bodies its lever at the last check or now, the larger) and
at each check refuses a unit whose B exceeds :data:`GROWTH` times G, leaving out of B
each body's kinetic energy up to its *floor*, that of moving at 1 m/s and turning at
1 rad/s (ROS units are SI, REP 103): slow motion is never a blow-up, and a floor per
body lets no heavy body's floor cover a light one. Integration error of the explicit
methods grows energy, by far less than that factor on any run they are stable on.

The checks are plain float arithmetic, O(bodies + springs), in the compiled kernel
(``src/kernel/bound.c``) where it is on and in :meth:`EnergyBound._check_python`
otherwise, with the same operations in the same order: the same bits, so the same
verdict either way.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from ..contact.joint_rows import SOFT
from ..geometry.planar import LARGEST_SQUARE, SMALLEST_SQUARE
from ..scene.joints import GearJoint, JointEnds, PrismaticJoint, RevoluteJoint
from ..scene.load import SpringSpec
from . import kernel
from .forces import (
    AnchorSpringTerm,
    BodySpringTerm,
    ConstantWrenchTerm,
    GravityTerm,
    ScalarKinematics,
    lever_arm,
    spring_energy_scalar,
)

if TYPE_CHECKING:
    from ..scene.load import Scene
    from .model import Model

__all__ = ["GROWTH", "STEP_GROWTH", "FLOOR_SPEED", "energy_units", "EnergyBound"]

#: How many times its bound's energy a unit may reach before it counts as blown up.
GROWTH = 1000.0
#: How many times the bound's energy one implicit step may reach (:meth:`step_ok`): a
#: resolved implicit midpoint step keeps it (1.7 at most over test_stability's stiffest
#: run, omega h = 100); Newton iterations that land on a wrong root give 4 to 60.
STEP_GROWTH = 2.0
#: The floor's speed (m/s) and turning rate (rad/s): kinetic energy below that of a body
#: moving this fast is left out of the check.
FLOOR_SPEED = 1.0

# The rows of the budget array, one column per unit (``src/kernel/bound.c`` reads the same):
# R, W, c, the inputs' c, P, B, B's excess over the floors, the limit, M and c_m.
ROOT, WORK, RATE, INPUT_RATE, POWER, ENERGY, EXCESS, LIMIT, MOTOR_ROOT, MOTOR_RATE = range(10)
BUDGET_ROWS = 10


def energy_units(scene: Scene) -> list[int]:
    """The unit of each body of ``scene`` (see the module): bodies joined by a spring
    between them, a joint or a collision group share one. Units are numbered in the
    order of their first body."""
    index = {body.name: i for i, body in enumerate(scene.bodies)}
    parent = list(range(len(index)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def join(names: Iterable[Optional[str]]) -> None:
        members = [root(index[name]) for name in names if name is not None]
        for other in members[1:]:
            a, b = sorted((members[0], other))
            parent[b] = a
            members[0] = a

    pins = {spec.name: (spec.body_a, spec.body_b) for spec in scene.joints
            if isinstance(spec, JointEnds)}
    for spec in scene.joints:
        if isinstance(spec, GearJoint):  # the bodies of both its pins
            join((*pins[spec.joint_a], *pins[spec.joint_b]))
        else:
            join(pins[spec.name])
    for force in scene.forces:
        if isinstance(force, SpringSpec) and force.body_b is not None:
            join((force.body_a, force.body_b))
    for group in scene.collisions:
        join(group.bodies)
    numbers: dict[int, int] = {}
    return [numbers.setdefault(root(i), len(numbers)) for i in range(len(index))]


class EnergyBound:
    """The running bound of each unit's B = K + U_springs for one simulation (see the
    module)."""

    def __init__(self, model: Model, q: np.ndarray, v: np.ndarray) -> None:
        self.model = model
        #: The unit of each body, and the bodies of each unit.
        self.units = energy_units(model.scene)
        self.members: list[list[int]] = [[] for _ in range(max(self.units, default=-1) + 1)]
        for body, unit in enumerate(self.units):
            self.members[unit].append(body)
        count = len(self.members)
        self._mass, self._inertia = model.mass.tolist(), model.inertia.tolist()
        floor = [0.5 * (m + i) * FLOOR_SPEED * FLOOR_SPEED
                 for m, i in zip(self._mass, self._inertia)]
        self._floor = floor
        self._roots = [(math.sqrt(2.0 / m), math.sqrt(2.0 / i))
                       for m, i in zip(self._mass, self._inertia)]
        springs = [term for term in model.terms
                   if isinstance(term, (AnchorSpringTerm, BodySpringTerm))]
        self._springs = _spring_rows(springs)
        # Python sums in plain floats up to Model.lean's size, as the forces do.
        self._lean = model.lean
        if not self._lean:  # the same as arrays, for numpy
            self._arrays = (model.mass, model.inertia, np.array(floor))
            a, la, b, lb, k, rest = zip(*self._springs) if springs else ((),) * 6
            self._spring_columns = (np.array(a, dtype=int), np.array(la).reshape(-1, 2),
                                    np.array(b, dtype=int), np.array(lb).reshape(-1, 2),
                                    np.array(k), np.array(rest))
            self._spring_units = np.array([self.units[i] for i in a], dtype=int)
        self._compiled = kernel.enabled()
        if self._compiled:
            self._statics = np.ascontiguousarray([self._mass, self._inertia, floor], dtype=float)
            self._unit_array = np.array(self.units, dtype=np.int64)
            self._program = (kernel.CompiledForces(model.inverse_mass, springs).program
                             if springs else None)
        # The budget: rows ROOT ... LIMIT of a value per unit (see the module), an array
        # for the kernel, else lists, whose floats Python reads cheaply.
        self._budget: Any = (np.zeros((BUDGET_ROWS, count)) if self._compiled
                             else [[0.0] * count for _ in range(BUDGET_ROWS)])
        self._wrenches = [term for term in model.terms if isinstance(term, ConstantWrenchTerm)]
        # Only a force at a point of another frame than its body's has a rate of work that
        # follows the state (its lever arm); the inputs' are taken at every check.
        self._moving = any(at_point and owner != body for term in self._wrenches
                           for body, _, _, _, owner, _, at_point in term.rows)
        self._steady = [0.0] * count  # the rate of gravity, which does not depend on the state
        for term in model.terms:
            if isinstance(term, GravityTerm):
                for body, (wx, wy) in zip(term.bodies.tolist(), term.weights.tolist()):
                    self._steady[self.units[body]] += math.hypot(wx, wy) * self._roots[body][0]
        joints = model.joints
        self._joints = joints
        #: (unit, largest effort, joint name) of each motor.
        self._motors: list[tuple[int, float, str]] = []
        if joints is not None:
            index = model.index
            for spec in model.scene.joints:
                if isinstance(spec, (RevoluteJoint, PrismaticJoint)) and spec.motor is not None:
                    self._motors.append((self.units[index[spec.body_b]], spec.motor.max_effort,
                                         spec.name))
        #: Whether a motor's c_m follows the state: a slider between two bodies (its lever).
        self._levered = any(isinstance(spec, PrismaticJoint) and spec.motor is not None and
                            spec.body_a is not None for spec in model.scene.joints)
        self._set(MOTOR_RATE, self._motor_rates(q))
        self._set(MOTOR_ROOT, [0.0] * count)
        self._speeds: dict[str, float] = {}
        self._inputs_set = self._motors_moved = self._stale = False
        #: The largest ratio of a unit's excess to its limit seen, for tests and reports.
        self.worst_ratio = 0.0
        #: The bodies of the unit a failed check refused.
        self.over: tuple[int, ...] = ()
        energy = self._energies(q, v)
        joint = self._joint_potentials(q)
        self._set(ROOT, [math.sqrt(max(e + j, 0.0)) for e, j in zip(energy, joint)])
        self._refresh(q)

    # ------------------------------------------------------------------ sums

    def _energies(self, q: np.ndarray, v: np.ndarray) -> list[float]:
        """B of each unit at (q, v) (inf where it overflows), with each unit's excess over
        the bodies' floors, into the budget's ENERGY and EXCESS rows."""
        if self._compiled:
            kernel.unit_energy(self._program, np.ascontiguousarray(q),
                               np.ascontiguousarray(v), self._statics, self._unit_array,
                               self._budget)
        else:
            energy, excess = self._sums(q, v)
            self._set(ENERGY, energy)
            self._set(EXCESS, excess)
        return self.row(ENERGY)

    def _sums(self, q: np.ndarray, v: np.ndarray) -> tuple[list[float], list[float]]:
        """Each unit's B and excess in Python, body by body and then spring by spring, as
        ``hd_unit_energy`` adds them: in plain floats up to Model.lean's size, above it
        with numpy's elementwise operations and in-order ``np.add.at`` (the same
        operations in the same order, so the same bits)."""
        if not self._lean:
            return self._sums_arrays(q, v)
        count = len(self.members)
        energy, excess = [0.0] * count, [0.0] * count
        for unit, (vx, vy, omega), m, i, floor in zip(self.units, v.tolist(), self._mass,
                                                      self._inertia, self._floor):
            kinetic = 0.5 * (m * (vx * vx + vy * vy) + i * (omega * omega))
            energy[unit] += kinetic
            excess[unit] += kinetic - floor if not kinetic <= floor else 0.0
        if self._springs:
            rows = q.tolist()
            state = ScalarKinematics.of(rows, [], True)
            for a, (lax, lay), b, (lbx, lby), k, rest in self._springs:
                rax, ray = state.offset(a, lax, lay)
                if b < 0:  # an anchor: (lbx, lby) in the fixed frame
                    dx, dy = rows[a][0] + rax - lbx, rows[a][1] + ray - lby
                else:
                    rbx, rby = state.offset(b, lbx, lby)
                    dx = rows[a][0] + rax - rows[b][0] - rbx
                    dy = rows[a][1] + ray - rows[b][1] - rby
                spring = spring_energy_scalar(dx, dy, k, rest)
                energy[self.units[a]] += spring
                excess[self.units[a]] += spring
        return energy, excess

    def _sums_arrays(self, q: np.ndarray, v: np.ndarray) -> tuple[list[float], list[float]]:
        """:meth:`_sums` with numpy, for many bodies."""
        count = len(self.members)
        energy, excess = np.zeros(count), np.zeros(count)
        mass, inertia, floor = self._arrays
        with np.errstate(all="ignore"):
            vx, vy, omega = v[:, 0], v[:, 1], v[:, 2]
            kinetic = 0.5 * (mass * (vx * vx + vy * vy) + inertia * (omega * omega))
            np.add.at(energy, self.units, kinetic)
            np.add.at(excess, self.units, np.where(kinetic <= floor, 0.0, kinetic - floor))
            if self._springs:
                a, la, b, lb, k, rest = self._spring_columns
                cos, sin = np.cos(q[:, 2]), np.sin(q[:, 2])
                anchored, other = b < 0, np.maximum(b, 0)
                rax, ray = _turned(cos[a], sin[a], la)
                rbx, rby = _turned(cos[other], sin[other], lb)
                dx = np.where(anchored, q[a, 0] + rax - lb[:, 0],
                              q[a, 0] + rax - q[other, 0] - rbx)
                dy = np.where(anchored, q[a, 1] + ray - lb[:, 1],
                              q[a, 1] + ray - q[other, 1] - rby)
                square = dx * dx + dy * dy
                length = np.where((square >= SMALLEST_SQUARE) & (square <= LARGEST_SQUARE),
                                  np.sqrt(square), np.hypot(dx, dy))
                stretch = length - rest
                spring = 0.5 * k * (stretch * stretch)
                np.add.at(energy, self._spring_units, spring)
                np.add.at(excess, self._spring_units, spring)
        return energy.tolist(), excess.tolist()

    def _joint_potentials(self, q: np.ndarray) -> list[float]:
        """The potential energy of each unit's joint springs and soft welds at ``q``:
        k c^2 / 2 per soft row, k per unit effective mass for a weld's rows."""
        potentials = [0.0] * len(self.members)
        joints = self._joints
        if joints is None or SOFT not in joints.kinds:
            return potentials
        inverse = joints.inverse_mass
        bodies = joints.bodies.tolist()
        for row in joints.rows(q[joints.bodies].reshape(-1).tolist(), 1.0):
            if row.kind != SOFT:
                continue
            stiffness = row.stiffness
            if row.scaled:
                mobility = sum((jx * jx + jy * jy) * inverse[3 * b] + jw * jw * inverse[3 * b + 2]
                               for b, jx, jy, jw in row.entries)
                stiffness = stiffness / mobility if mobility > 0.0 else 0.0
            potentials[self.units[bodies[row.entries[0][0]]]] += 0.5 * stiffness * row.c * row.c
        return potentials

    # ------------------------------------------------------------------ rates

    def _unit_rates(self, q: np.ndarray, terms: Sequence[ConstantWrenchTerm]) -> list[float]:
        """c of each unit: the coefficient of sqrt(B) in the rate of work of ``terms`` at
        positions ``q`` (see the module)."""
        rates = [0.0] * len(self.members)
        rows = None
        for term in terms:
            for (unit, root_mass, root_inertia, lever), (body, (fx, fy), torque, _, owner,
                                                         point, _) in zip(
                    self._places(term), term.rows):
                if lever is None:  # it follows the state
                    rows = q.tolist() if rows is None else rows
                    lever = lever_arm(body, owner, point, rows)
                force = math.hypot(fx, fy)
                rates[unit] += force * root_mass + (lever * force + abs(torque)) * root_inertia
        return rates

    def _places(self, term: ConstantWrenchTerm) -> list[tuple[int, float, float, Optional[float]]]:
        """Per row of ``term``: its body's unit, sqrt(2 / m) and sqrt(2 / I) of its body,
        and its lever arm where that does not follow the state (None where it does): 0 at
        the CM, |r| at a point of the body itself (the distance of the body's CM from
        itself is 0 in a state, which is always finite)."""
        places = []
        for body, _, _, _, owner, (px, py), at_point in term.rows:
            lever = (None if owner != body else math.hypot(px, py)) if at_point else 0.0
            places.append((self.units[body], *self._roots[body], lever))
        return places

    def _refresh(self, q: np.ndarray) -> None:
        """Take the rates of work from the state ``q`` and the inputs and motors now."""
        terms = self._wrenches if self.model.inputs is None else [*self._wrenches,
                                                                  self.model.inputs]
        # Plain floats, whose overflow numpy has no say in (as in inputs_changed).
        rates = self._unit_rates(q, terms) if terms else [0.0] * len(self.members)
        self._set(RATE, [steady + rate for steady, rate in zip(self._steady, rates)])
        self._set(INPUT_RATE, [0.0] * len(rates))
        self._inputs_set = self._motors_moved = False
        # To take again where a lever moves, or to drop inputs that ended.
        self._stale = self._moving or self._levered or self.model.inputs is not None
        if self._levered:
            self._set(MOTOR_RATE, self._motor_rates(q))
        if self._motors:
            self._speeds = dict(self._joints.motor_speed)  # type: ignore[union-attr]
            self._set(POWER, self._powers(self._speeds))

    def _powers(self, speeds: dict[str, float]) -> list[float]:
        """P of each unit: the motors' largest power, effort times target speed."""
        powers = [0.0] * len(self.members)
        for unit, effort, name in self._motors:
            powers[unit] += effort * abs(speeds[name])
        return powers

    def _motor_rates(self, q: np.ndarray) -> list[float]:
        """c_m of each unit at positions ``q``: its motors' largest efforts times the
        coefficients of sqrt(B) that bound their joints' speeds (see the module)."""
        rates = [0.0] * len(self.members)
        model = self.model
        index = model.index
        rows = None
        for spec in model.scene.joints:
            if not isinstance(spec, (RevoluteJoint, PrismaticJoint)) or spec.motor is None:
                continue
            b = index[spec.body_b]
            a = None if spec.body_a is None else index[spec.body_a]
            if isinstance(spec, RevoluteJoint):
                mobility = 1.0 / self._inertia[b] + (0.0 if a is None else 1.0 / self._inertia[a])
            else:
                rx, ry = model.local(b, spec.point_b).tolist()
                mobility = 1.0 / self._mass[b] + (rx * rx + ry * ry) / self._inertia[b]
                if a is not None:  # the axis turns with body_a, about P_B
                    rows = q.tolist() if rows is None else rows
                    lever = lever_arm(a, b, (rx, ry), rows)
                    mobility += 1.0 / self._mass[a] + lever * lever / self._inertia[a]
            rates[self.units[b]] += spec.motor.max_effort * math.sqrt(2.0 * mobility)
        return rates

    def inputs_changed(self, q: np.ndarray, inputs: Optional[ConstantWrenchTerm]) -> None:
        """Count the rate of a new input set until the next check."""
        if inputs is not None:
            # A term's rows are plain floats, whose overflow numpy has no say in.
            rates = self._unit_rates(q, (inputs,))
            self._set(INPUT_RATE, list(map(max, self.row(INPUT_RATE), rates)))
            self._inputs_set = True

    def _motors_changed(self) -> None:
        """A motor's target speed changed since the last check: the interval counts the
        larger power of the two."""
        speeds = self._joints.motor_speed  # type: ignore[union-attr]
        if speeds != self._speeds:
            self._set(POWER, list(map(max, self.row(POWER), self._powers(speeds))))
            self._speeds = dict(speeds)
            self._motors_moved = True

    # ------------------------------------------------------------------ checks

    def _check(self, q: np.ndarray, v: np.ndarray, seconds: float) -> float:
        """Advance every unit's budget by ``seconds``, take its B and excess at (q, v) and
        its limit; the largest ratio of excess to limit (inf for a state that is not
        finite)."""
        if self._motors:
            self._motors_changed()
        if self._levered:  # the interval counts the larger lever of the two
            self._set(MOTOR_RATE, list(map(max, self.row(MOTOR_RATE), self._motor_rates(q))))
        if self._compiled:
            return kernel.bound_check(self._program, np.ascontiguousarray(q),
                                      np.ascontiguousarray(v), self._statics,
                                      self._unit_array, self._budget, seconds, GROWTH)
        return self._check_python(q, v, seconds)

    def _check_python(self, q: np.ndarray, v: np.ndarray, seconds: float) -> float:
        """:meth:`_check` in Python: ``hd_bound_check``'s operations in its order."""
        budget = self._budget
        budget[ENERGY], budget[EXCESS] = energy, excess = self._sums(q, v)
        root, work, limits = budget[ROOT], budget[WORK], budget[LIMIT]
        turned = budget[MOTOR_ROOT]
        worst = 0.0
        for u, (rate, input_rate, power, motor_rate) in enumerate(zip(
                budget[RATE], budget[INPUT_RATE], budget[POWER], budget[MOTOR_RATE])):
            root[u] += 0.5 * seconds * (rate + input_rate)
            work[u] += seconds * power
            turned[u] += 0.5 * seconds * motor_rate
            reach = root[u] + _motors_share(work[u], turned[u])
            limits[u] = GROWTH * (reach * reach)
            ratio = _over(energy[u], excess[u], limits[u])
            worst = ratio if ratio > worst else worst
        return worst

    def check(self, q: np.ndarray, v: np.ndarray, seconds: float) -> Optional[str]:
        """Advance the budgets by ``seconds`` and check the state (q, v): None if every
        unit is within its bound, else why not (and :attr:`over` names the unit)."""
        worst = self._check(q, v, seconds)
        self.worst_ratio = max(self.worst_ratio, worst)
        if not worst <= 1.0:
            return self._problem()
        # The rates follow the state where constant wrenches or inputs act.
        if self._stale or self.model.inputs is not None or self._inputs_set or \
                self._motors_moved:
            self._refresh(q)
        return None

    def kernel_data(self) -> Optional[kernel.BoundData]:
        """What the kernel needs to make checks in a row between its steps
        (:meth:`.kernel.CompiledSteps.run`), the same arrays for the bound's lifetime; None
        without the kernel."""
        if not self._compiled:
            return None
        return (self._program, self._statics, self._unit_array, self._budget, GROWTH)

    def kernel_ready(self) -> bool:
        """Whether the kernel may make the checks on :meth:`kernel_data` now: a check
        passed needs nothing more than the state, no rate of work to take again after it
        (no inputs, none just ended, no lever arm that moves, no motors)."""
        return self._compiled and not (self._motors or self._stale or self._inputs_set or
                                       self.model.inputs is not None)

    def kernel_inputs(self, inputs: ConstantWrenchTerm
                      ) -> Optional[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """What the kernel's run needs to take the rates of work of ``inputs`` itself, as
        :meth:`inputs_changed` and :meth:`check` do, while a drive's control instants renew
        their values (:mod:`.kernel`: ``DriveColumns``): per row its body's unit and
        sqrt(2 / m), sqrt(2 / I) and lever arm, and each unit's steady rate. None where the
        rates need more than that: no kernel, motors, a lever arm that follows the state, or
        constant wrenches of the scene."""
        if not self._compiled or self._motors or self._moving or self._wrenches:
            return None
        places = self._places(inputs)
        if any(lever is None for *_, lever in places):
            return None
        return (np.array([unit for unit, *_ in places], dtype=np.int64),
                np.array([rates for _, *rates in places], dtype=float).reshape(-1),
                np.array(self._steady, dtype=float))

    def kernel_inputs_taken(self, changed: bool) -> None:
        """The kernel's run took the rates of the inputs (:meth:`kernel_inputs`): ``changed``,
        whether they changed after its last check."""
        self._inputs_set = changed

    def kernel_checked(self, worst: float) -> Optional[str]:
        """The kernel made checks on :meth:`kernel_data` whose largest ratio was
        ``worst``, stopping after the first failing one: :meth:`check`'s verdict."""
        self.worst_ratio = max(self.worst_ratio, worst)
        return None if worst <= 1.0 else self._problem()

    def _problem(self) -> str:
        """Why the last check failed, naming the first unit over its bound."""
        energy, excess, limit = (self.row(row) for row in (ENERGY, EXCESS, LIMIT))
        for unit, members in enumerate(self.members):
            if _over(energy[unit], excess[unit], limit[unit]) <= 1.0:
                continue
            self.over = tuple(members)
            joined = (f" (with {len(members) - 1} bodies joined to it)" if len(members) > 1
                      else "")
            return (f"the energy of motion and springs of {self.model.names[members[0]]}"
                    f"{joined} grew to {energy[unit]:.3g} J, over {limit[unit]:.3g} J "
                    f"({GROWTH:g} times what its initial energy and the work of gravity, "
                    "constant forces, inputs and motors allow)")
        raise AssertionError("a failed check names a unit")  # pragma: no cover

    def step_ok(self, q0: np.ndarray, v0: np.ndarray, q1: np.ndarray, v1: np.ndarray,
                h: float) -> bool:
        """Whether one integrator step from (q0, v0) to (q1, v1) keeps every unit's B
        within :data:`STEP_GROWTH` times its bound over the step (an implicit method's
        check of its root)."""
        saved = self.row(ENERGY), self.row(EXCESS)  # a check's results, for its message
        with np.errstate(all="ignore"):
            before = self._energies(q0, v0)
            inputs = () if self.model.inputs is None else (self.model.inputs,)
            rates = self._unit_rates(q0, [*self._wrenches, *inputs])
            after = self._energies(q1, v1)
        self._set(ENERGY, saved[0])
        self._set(EXCESS, saved[1])
        for unit, members in enumerate(self.members):
            root = math.sqrt(max(before[unit], 0.0)) + 0.5 * h * (self._steady[unit] + rates[unit])
            floor = sum(self._floor[body] for body in members)
            if not after[unit] <= STEP_GROWTH * root * root + 1e-12 * floor:
                return False
        return True

    def moved(self, q: np.ndarray, v: np.ndarray, seconds: float,
              bodies: Optional[Iterable[int]] = None) -> None:
        """Bodies (``bodies``, default all) were set to a new state (q, v) from outside,
        ``seconds`` after the last check: the budgets are advanced as a check would, and
        the new energy of their units joins them, so only growth beyond it counts."""
        with np.errstate(all="ignore"):
            self._check(q, v, seconds)
            energy = self.row(ENERGY)
            joint = self._joint_potentials(q)
        units = (range(len(self.members)) if bodies is None
                 else sorted({self.units[body] for body in bodies}))
        root = self.row(ROOT)
        for unit in units:
            root[unit] = max(root[unit], math.sqrt(max(energy[unit] + joint[unit], 0.0)))
        self._set(ROOT, root)
        self._refresh(q)

    def limits(self) -> list[float]:
        """The largest B, less the floors, that each unit may have now."""
        return [GROWTH * (reach * reach)
                for reach in (root + _motors_share(work, turned) for root, work, turned
                              in zip(self.row(ROOT), self.row(WORK), self.row(MOTOR_ROOT)))]

    def row(self, row: int) -> list[float]:
        """Row ``row`` of the budget (ROOT ... MOTOR_RATE), a value per unit."""
        return self._budget[row].tolist() if self._compiled else list(self._budget[row])

    def _set(self, row: int, values: list[float]) -> None:
        """Make row ``row`` of the budget ``values`` (a list the caller gives up)."""
        self._budget[row] = values

    # ------------------------------------------------------------------ state

    def export_state(self) -> dict[str, Any]:
        """The running budgets, as plain floats (exact), for :meth:`import_state`, with
        the unit of each body (for :meth:`carried`)."""
        state = {"units": list(self.units), "root": self.row(ROOT), "work": self.row(WORK),
                 "rate": self.row(RATE), "input_rate": self.row(INPUT_RATE),
                 "power": self.row(POWER), "speeds": dict(self._speeds),
                 "worst_ratio": self.worst_ratio}
        turned = self.row(MOTOR_ROOT)
        if any(turned):  # M is all 0 without motors: their budgets are saved as before M
            state["motor_root"] = turned
        return state

    def import_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`export_state`'s budgets. A budget of other units (another
        world's, or one kept as one number for the whole scene) is pooled: every unit
        gets the whole of it, which no unit's energy can exceed. A budget saved without
        M takes it from W (:func:`_saved`)."""
        count = len(self.members)
        pooled = state.get("units") != self.units
        for row, key in ((ROOT, "root"), (WORK, "work"), (RATE, "rate"),
                         (INPUT_RATE, "input_rate"), (POWER, "power"),
                         (MOTOR_ROOT, "motor_root")):
            values = _saved(state, key)
            if any(map(math.isnan, values)):  # a budget never is; it would bound nothing
                raise ValueError(f"the energy budget's '{key}' holds nan")
            if pooled:
                whole = (math.sqrt(math.fsum(x * x for x in values))
                         if row in (ROOT, MOTOR_ROOT) else math.fsum(values))
                values = [whole] * count
            self._set(row, values)
        self._speeds = {str(k): float(x) for k, x in state.get("speeds", {}).items()}
        if self._motors and not self._speeds:
            self._speeds = dict(self._joints.motor_speed)  # type: ignore[union-attr]
            self._set(POWER, self._powers(self._speeds))
        self._inputs_set = any(self.row(INPUT_RATE))
        self._stale = True
        self.worst_ratio = float(state["worst_ratio"])
        if math.isnan(self.worst_ratio):
            raise ValueError("the energy budget's 'worst_ratio' is nan")

    def carried(self, state: dict[str, Any], sources: Sequence[Optional[int]]) -> dict[str, Any]:
        """:meth:`export_state`'s budgets of another world's bound, ``state``, carried onto
        this bound's units: ``sources`` gives, for each of this world's bodies, its index
        in the other world (None for a new body). A unit's budget is the sum of the
        budgets of the units its bodies came from (sqrt of the sum of squares for R and M):
        what they could hold together; a unit of new bodies only keeps its own."""
        carried = self.export_state()
        old_units = state["units"]
        saved, turned = _saved(state, "motor_root"), self.row(MOTOR_ROOT)
        for unit, members in enumerate(self.members):
            came = sorted({old_units[i] for i in (sources[body] for body in members)
                           if i is not None})
            if came:
                carried["root"][unit] = math.sqrt(sum(state["root"][u] ** 2 for u in came))
                turned[unit] = math.sqrt(sum(saved[u] ** 2 for u in came))
                for key in ("work", "input_rate"):
                    carried[key][unit] = math.fsum(state[key][u] for u in came)
        carried["worst_ratio"] = state["worst_ratio"]
        if any(turned):
            carried["motor_root"] = turned
        return carried


def _over(energy: float, excess: float, limit: float) -> float:
    """How far a unit is over its limit: excess / limit, 0 without excess, inf for an
    energy that is not finite or an excess over a limit of zero (``over`` in bound.c)."""
    if not math.isfinite(energy):
        return math.inf
    if excess <= 0.0:
        return 0.0
    ratio = excess / limit if limit > 0.0 else math.inf
    return math.inf if math.isnan(ratio) else ratio


def _saved(state: dict[str, Any], key: str) -> list[float]:
    """Row ``key`` of an exported budget (:meth:`EnergyBound.export_state`) as floats, a
    unit's each or one for the whole scene (a keyframe recorded before units). M, where
    it was not saved (all 0, or a budget saved before motors had it), is 0 for a unit
    without W, which no motor has worked on, so that 0 bounds as sqrt(W) did, and inf,
    unknown, for one with: its motors count by W alone."""
    if key == "motor_root" and key not in state:
        return [0.0 if work == 0.0 else math.inf for work in _saved(state, "work")]
    saved = state.get(key, 0.0)
    return [float(x) for x in saved] if isinstance(saved, list) else [float(saved)]


def _motors_share(work: float, turned: float) -> float:
    """What a unit's motors add to R: the smaller of sqrt(W) and M (``hd_motors_share``
    in bound.c); sqrt(W) where they are equal, as with no motor (both 0)."""
    swept = math.sqrt(work)
    return turned if turned < swept else swept


def _turned(cos: np.ndarray, sin: np.ndarray, local: np.ndarray) -> tuple[np.ndarray, ...]:
    """World offsets R(angle) l of the points ``local`` (ScalarKinematics.offset's
    operations)."""
    return cos * local[:, 0] - sin * local[:, 1], sin * local[:, 0] + cos * local[:, 1]


def _spring_rows(springs: Sequence[AnchorSpringTerm | BodySpringTerm]) -> list[tuple[Any, ...]]:
    """Each spring as (body a, its point, body b or -1, its point or the anchor,
    stiffness, rest length), in the terms' order and in each term's order."""
    rows: list[tuple[Any, ...]] = []
    for term in springs:
        stiffness, rest = term.law.stiffness.tolist(), term.law.rest_length.tolist()
        if isinstance(term, AnchorSpringTerm):
            ends = zip(term.body.tolist(), term.local.tolist(), [-1] * len(stiffness),
                       term.anchor.tolist())
        else:
            ends = zip(term.body_a.tolist(), term.local_a.tolist(), term.body_b.tolist(),
                       term.local_b.tolist())
        rows += [(a, tuple(pa), b, tuple(pb), k, r)
                 for (a, pa, b, pb), k, r in zip(ends, stiffness, rest)]
    return rows
