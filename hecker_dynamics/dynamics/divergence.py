"""A bound on the energy a scene can reach, to tell a blown-up state from motion.

The energy of motion and of the springs, B = K + U_springs, changes only by the work of
the forces (K's rates follow from the force by F = M a, Eq. 5, and from the torque by
tau = I alpha, Eq. 14). Springs exchange energy with K and
their dampers, drag, angular damping, walls and collisions (restitution at most 1) take
it away; only gravity, constant forces and torques and inputs put work in. A force F on
body i acting at a point r from its CM, with a torque tau, does work at the rate
F . v_i + (r x F + tau) omega_i <= (|F| sqrt(2 / m_i) + (|r| |F| + |tau|) sqrt(2 / I_i))
sqrt(B), since K_i = m_i |v_i|^2 / 2 + I_i omega_i^2 / 2 <= B. With c the sum of those
coefficients, dB/dt <= c sqrt(B), so sqrt(B(t)) <= sqrt(B(0)) + int c dt / 2: from rest
under a constant force, with equality.

:class:`EnergyBound` keeps that budget as the simulation runs (c from the state at each
check, the largest input set since the last one) and refuses a state whose B exceeds
:data:`GROWTH` times the bound's square, and the floor of every body moving at 1 m/s and
turning at 1 rad/s (ROS units are SI, REP 103): integration error of the explicit
methods grows energy, by far less than that on any scene they are stable on.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Optional

import numpy as np

from . import kernel
from .forces import (AnchorSpringTerm, BodySpringTerm, ConstantWrenchTerm, GravityTerm,
                     ScalarKinematics)

if TYPE_CHECKING:
    from .model import Model

__all__ = ["GROWTH", "STEP_GROWTH", "EnergyBound"]

#: How many times the bound's energy a state may reach before it counts as blown up.
GROWTH = 1000.0
#: How many times the bound's energy one implicit step may reach (:meth:`step_ok`): a
#: resolved implicit midpoint step keeps it (1.7 at most over test_stability's stiffest
#: run, omega h = 100); Newton iterations that land on a wrong root give 4 to 60.
STEP_GROWTH = 2.0


class EnergyBound:
    """The running bound of B = K + U_springs for one simulation (see the module)."""

    def __init__(self, model: Model, q: np.ndarray, v: np.ndarray) -> None:
        self.model = model
        self._root_inverse_mass = np.sqrt(2.0 / model.mass)
        self._root_inverse_inertia = np.sqrt(2.0 / model.inertia)
        self.floor = 0.5 * float(np.sum(model.mass) + np.sum(model.inertia))
        self._springs = [term for term in model.terms
                         if isinstance(term, (AnchorSpringTerm, BodySpringTerm))]
        self._wrenches = [term for term in model.terms if isinstance(term, ConstantWrenchTerm)]
        with np.errstate(all="ignore"):  # gravity's rate does not depend on the state
            self._gravity_rate = sum(
                float(np.sum(np.hypot(term.weights[:, 0], term.weights[:, 1])
                             * self._root_inverse_mass[term.bodies]))
                for term in model.terms if isinstance(term, GravityTerm))
        # Up to Model.lean's size the checks run in plain floats, as the forces do: numpy's
        # per-call cost would be most of a small scene's work at each publish instant.
        self._lean = model.lean
        self._mass, self._inertia = model.mass.tolist(), model.inertia.tolist()
        self._compiled = kernel.enabled()
        self._roots = list(zip(self._root_inverse_mass.tolist(),
                               self._root_inverse_inertia.tolist()))
        self._root = math.sqrt(max(self.energy(q, v), 0.0))
        self._rate = self.rate(q, model.inputs)
        self._input_rate = 0.0
        #: The largest B / limit seen, for tests and reports.
        self.worst_ratio = 0.0

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """B: kinetic energy plus the springs' potential energy (inf where it overflows)."""
        if self._compiled and not self._lean:
            # The kernel's sum body by body costs a fraction of numpy's per publish
            # instant; above the lean size Python's numpy sum agrees with it to rounding,
            # as the forces do. Without springs nothing here needs numpy's error state,
            # whose setting cost most of a small scene's check.
            if not self._springs:
                return self._kinetic(v)
            with np.errstate(all="ignore"):
                return self._kinetic(v) + sum(term.potential(q) for term in self._springs)
        if self._lean:
            half = self._kinetic(v)
            if not self._springs:
                return half
            compiled = self.model.compiled
            if self._compiled and compiled is not None:
                # The same sum in the kernel: at each publish instant, a ring of 10 springs
                # spent 50 us of the running node's tick in the plain-float loop.
                return half + kernel.spring_potential(compiled, np.ascontiguousarray(q))
            state = ScalarKinematics.of(q.tolist(), [], True)
            return half + sum(term.potential_scalar(state) for term in self._springs)
        model = self.model
        with np.errstate(all="ignore"):
            kinetic = 0.5 * float(np.sum(model.mass * (v[:, 0] ** 2 + v[:, 1] ** 2))
                                  + np.sum(model.inertia * v[:, 2] ** 2))
            return kinetic + sum(term.potential(q) for term in self._springs)

    def _kinetic(self, v: np.ndarray) -> float:
        """K in plain floats, body by body (the kernel's loop where it is on: the same
        operations in the same order, so the same bits at a fraction of the cost per
        publish instant)."""
        if self._compiled:
            return kernel.kinetic(np.ascontiguousarray(v), self.model.mass, self.model.inertia)
        kinetic = 0.0
        for (vx, vy, omega), m, i in zip(v.tolist(), self._mass, self._inertia):
            kinetic += m * (vx * vx + vy * vy) + i * (omega * omega)
        return 0.5 * kinetic

    def _wrench_rate(self, term: ConstantWrenchTerm, q: np.ndarray) -> float:
        if self._lean:
            return self._wrench_rate_scalar(term, q.tolist())
        force = np.hypot(term.force[:, 0], term.force[:, 1])
        target = q[term.body, :2]
        owner = np.where(term.point_body >= 0, term.point_body, 0)
        # The point is relative to its owner's CM, or fixed-frame coordinates (owner -1).
        origin = np.where((term.point_body >= 0)[:, None], q[owner, :2], 0.0)
        lever = np.where(term.at_point, np.hypot(*(origin - target).T) +
                         np.hypot(term.point[:, 0], term.point[:, 1]), 0.0)
        return float(np.sum(force * self._root_inverse_mass[term.body]
                            + (lever * force + np.abs(term.torque))
                            * self._root_inverse_inertia[term.body]))

    def rate(self, q: np.ndarray, inputs: Optional[ConstantWrenchTerm]) -> float:
        """c: the coefficient of sqrt(B) in the rate of work of gravity, the constant
        wrenches and ``inputs`` at positions ``q``."""
        if self._lean or (not self._wrenches and inputs is None):
            return self._rate_of(q, inputs)
        with np.errstate(all="ignore"):
            return self._rate_of(q, inputs)

    def _wrench_rate_scalar(self, term: ConstantWrenchTerm, q: list[list[float]]) -> float:
        """:meth:`_wrench_rate` in plain floats, row by row."""
        total = 0.0
        for body, (fx, fy), torque, _, owner, (px, py), at_point in term.rows:
            force = math.hypot(fx, fy)
            root_mass, root_inertia = self._roots[body]
            lever = 0.0
            if at_point:
                ox, oy = (q[owner][0], q[owner][1]) if owner >= 0 else (0.0, 0.0)
                lever = math.hypot(ox - q[body][0], oy - q[body][1]) + math.hypot(px, py)
            total += force * root_mass + (lever * force + abs(torque)) * root_inertia
        return total

    def _rate_of(self, q: np.ndarray, inputs: Optional[ConstantWrenchTerm]) -> float:
        total = self._gravity_rate
        for term in self._wrenches:
            total += self._wrench_rate(term, q)
        return total + (self._wrench_rate(inputs, q) if inputs is not None else 0.0)

    def inputs_changed(self, q: np.ndarray, inputs: Optional[ConstantWrenchTerm]) -> None:
        """Count the rate of a new input set until the next check."""
        if inputs is not None:
            with np.errstate(all="ignore"):
                self._input_rate = max(self._input_rate, self._wrench_rate(inputs, q))

    def step_ok(self, q0: np.ndarray, v0: np.ndarray, q1: np.ndarray, v1: np.ndarray,
                h: float) -> bool:
        """Whether one integrator step from (q0, v0) to (q1, v1) keeps B within
        :data:`STEP_GROWTH` times the bound over the step (an implicit method's check
        of its root)."""
        with np.errstate(all="ignore"):
            root = math.sqrt(max(self.energy(q0, v0), 0.0)) + \
                0.5 * h * self.rate(q0, self.model.inputs)
            return bool(self.energy(q1, v1) <= STEP_GROWTH * root * root + 1e-12 * self.floor)

    def moved(self, q: np.ndarray, v: np.ndarray, seconds: float) -> None:
        """A body was set to a new state (q, v) from outside, ``seconds`` after the last
        check: the budget is advanced as a check would, and the new energy joins it, so
        only growth beyond it counts."""
        self._root += 0.5 * seconds * (self._rate + self._input_rate)
        with np.errstate(all="ignore"):
            self._root = max(self._root, math.sqrt(max(self.energy(q, v), 0.0)))
        self._rate = self.rate(q, self.model.inputs)
        self._input_rate = 0.0

    def export_state(self) -> dict[str, float]:
        """The running budget, as plain floats (exact), for :meth:`import_state`."""
        return {"root": self._root, "rate": self._rate, "input_rate": self._input_rate,
                "worst_ratio": self.worst_ratio}

    def import_state(self, state: dict[str, float]) -> None:
        """Continue from :meth:`export_state`'s budget (of a bound of the same scene)."""
        self._root, self._rate = float(state["root"]), float(state["rate"])
        self._input_rate = float(state["input_rate"])
        self.worst_ratio = float(state["worst_ratio"])

    def limit(self) -> float:
        """The largest B allowed now."""
        return max(GROWTH * self._root ** 2, self.floor)

    def check(self, q: np.ndarray, v: np.ndarray, seconds: float) -> Optional[str]:
        """Advance the budget by ``seconds`` and check the state (q, v): None if it is
        within the bound, else why not."""
        self._root += 0.5 * seconds * (self._rate + self._input_rate)
        energy = self.energy(q, v)
        limit = self.limit()
        self.worst_ratio = max(self.worst_ratio, energy / limit)
        if not (energy <= limit and math.isfinite(energy)):
            return (f"the energy of motion and springs grew to {energy:.3g} J, over "
                    f"{limit:.3g} J ({GROWTH:g} times what the initial energy and the work "
                    "of gravity, constant forces and inputs allow)")
        self._rate = self.rate(q, self.model.inputs)
        self._input_rate = 0.0
        return None
