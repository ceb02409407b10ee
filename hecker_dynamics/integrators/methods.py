"""Integrators: step 7 of the article's algorithm, from accelerations to a new state.

Every method advances the state ``(q, v)`` (positions and angles, velocities and angular
velocities, each (N, 3)) by a step ``h`` given ``f(q, v) -> accelerations``:

- ``explicit_euler``: the article's own scheme, position and angle stepped through their
  derivatives (Eq. 1 and Eq. 6); order 1, gains energy on oscillators.
- ``semi_implicit_euler``: velocity first, then position with the new velocity; order 1,
  symplectic, bounded energy error.
- ``velocity_verlet``: order 2, symplectic for position-dependent forces; velocity-dependent
  forces are evaluated at a predicted velocity to keep order 2.
- ``rk4``: classical Runge-Kutta, order 4.
- ``dopri5``: Dormand-Prince 5(4) with error control; sub-steps each step to meet the
  tolerance.
- ``dop853``: Dormand-Prince order 8 with Hairer's error estimate, the same way: 12
  evaluations a sub-step, far fewer sub-steps at tight tolerances.
- ``implicit_midpoint`` (order 2, A-stable, symplectic) and ``backward_euler`` (order 1,
  L-stable): solved by Newton's method, stable for stiff springs at any step. Given the
  bodies' coupling (a :class:`~.coloring.Coloring`), their Jacobian takes colored
  differences: 6 evaluations per group of bodies instead of 6 per body.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Optional

import numpy as np

from .coloring import Coloring
from .tableaux import DOP853, DOPRI5, EmbeddedPair

__all__ = ["IntegrationError", "Counters", "Integrator", "ExplicitEuler", "SemiImplicitEuler",
           "VelocityVerlet", "RungeKutta4", "EmbeddedRungeKutta", "ImplicitTheta", "METHODS",
           "ADAPTIVE", "AUTO_IMPLICIT_BODIES", "make_integrator", "choose_method",
           "fastest_rate"]

Accelerations = Callable[[np.ndarray, np.ndarray], np.ndarray]
#: (q0, v0, q1, v1, h) -> whether the step from (q0, v0) to (q1, v1) is physically possible.
StepCheck = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float], bool]


class IntegrationError(ArithmeticError):
    """An integrator could not complete a step (no convergence, step size underflow)."""


@dataclass
class Counters:
    """Work done, for the benchmark: force evaluations, sub-steps (and refused trial
    sub-steps of the adaptive methods), Newton iterations."""

    evaluations: int = 0
    substeps: int = 0
    rejected: int = 0
    newton_iterations: int = 0


@dataclass
class Integrator:
    """Base class: a named method of a given order with work counters.

    :attr:`position_share`: the share s of a step's change of velocity that its positions
    move with, under a constant acceleration a: q1 = q0 + h (v0 + s a h). The contact pass
    needs it to keep the method's energy through an elastic bounce
    (:attr:`~..contact.solver.ContactPass.lead`).
    """

    name: str = ""
    order: int = 0
    counters: Counters = field(default_factory=Counters)
    position_share = 0.5

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget any state carried from step to step."""

    def export_state(self) -> dict[str, Any]:
        """The state carried from step to step, as plain data (none for most methods)."""
        return {}

    def import_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`export_state`'s data."""

    def _f(self, f: Accelerations, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        self.counters.evaluations += 1
        return f(q, v)


class ExplicitEuler(Integrator):
    """x += h v; v += h a, both from the state at the start of the step."""

    position_share = 0.0

    def __init__(self) -> None:
        super().__init__("explicit_euler", 1)

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
        a = self._f(f, q, v)
        return q + h * v, v + h * a


class SemiImplicitEuler(Integrator):
    """v += h a(q, v); then x += h v with the new velocity (symplectic Euler)."""

    position_share = 1.0

    def __init__(self) -> None:
        super().__init__("semi_implicit_euler", 1)

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
        v1 = v + h * self._f(f, q, v)
        return q + h * v1, v1


class VelocityVerlet(Integrator):
    """x1 = x + h v + h^2/2 a0; v1 = v + h/2 (a0 + a(x1, v + h a0))."""

    def __init__(self) -> None:
        super().__init__("velocity_verlet", 2)

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
        a0 = self._f(f, q, v)
        q1 = q + h * v + (0.5 * h * h) * a0
        a1 = self._f(f, q1, v + h * a0)
        return q1, v + (0.5 * h) * (a0 + a1)


class RungeKutta4(Integrator):
    """Classical fourth-order Runge-Kutta on the first-order system (q' = v, v' = a)."""

    def __init__(self) -> None:
        super().__init__("rk4", 4)

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
        k1q, k1v = v, self._f(f, q, v)
        k2q = v + 0.5 * h * k1v
        k2v = self._f(f, q + 0.5 * h * k1q, k2q)
        k3q = v + 0.5 * h * k2v
        k3v = self._f(f, q + 0.5 * h * k2q, k3q)
        k4q = v + h * k3v
        k4v = self._f(f, q + h * k3q, k4q)
        return (q + (h / 6.0) * (k1q + 2.0 * k2q + 2.0 * k3q + k4q),
                v + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v))


class EmbeddedRungeKutta(Integrator):
    """An adaptive embedded pair (:mod:`.tableaux`): sub-steps each step so the local error
    meets ``tolerance``.

    The error of each sub-step, scaled component-wise by ``tolerance * (1 + |y|)`` (the
    larger |y| of the sub-step's start and end), must have a norm
    (:meth:`~.tableaux.EmbeddedPair.error_norm`) of at most 1; the next sub-step size
    follows from the usual controller (safety 0.9, growth between 0.2x and 5x, exponent
    -1 / (error order + 1)). The last sub-step is shortened to land on the end of the step;
    the sub-step size carries over from step to step.
    """

    MAX_SUBSTEPS = 100_000

    def __init__(self, pair: EmbeddedPair, tolerance: float) -> None:
        super().__init__(pair.name, pair.order)
        self.pair = pair
        self.tolerance = tolerance
        self._exponent = -1.0 / (pair.error_order + 1)
        # The slopes the error estimate reads: all S, or the first S - 1 when it skips k_S
        # (which is then evaluated only for an accepted sub-step).
        self._estimate_needs_new_state = pair.error_uses_new_state
        self._error_slopes = pair.slopes if self._estimate_needs_new_state else pair.slopes - 1
        self._error = pair.error[:, :self._error_slopes]
        #: The sub-step size, carried from step to step (inf: none taken yet).
        self.substep_size = math.inf

    def reset(self) -> None:
        self.substep_size = math.inf

    def export_state(self) -> dict[str, Any]:
        """The sub-step size the controller chose last: the next step starts with it."""
        return {"substep_size": self.substep_size}

    def import_state(self, state: dict[str, Any]) -> None:
        size = float(state["substep_size"])
        if not size > 0.0:  # NaN too: no controller chooses it, and 0 fails the next step
            raise ValueError(f"'substep_size' is {size}, not a positive size")
        self.substep_size = size

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
        y = np.concatenate([q.ravel(), v.ravel()])
        n = q.size
        shape = q.shape
        slopes = np.empty((self.pair.slopes, y.size))  # k_1..k_S, one row each
        # Stage states are built in one buffer, whose q and v views serve every stage.
        stage, increment = np.empty(y.size), np.empty(y.size)
        stage_q, stage_v = stage[:n].reshape(shape), stage[n:].reshape(shape)

        def rhs(q_now: np.ndarray, v_now: np.ndarray, out: np.ndarray) -> None:
            """Write (q', v') = (v, a(q, v)) into the flat ``out``."""
            out[:n] = v_now.ravel()
            out[n:] = self._f(f, q_now, v_now).ravel()

        def rhs_flat(state: np.ndarray, out: np.ndarray) -> None:
            rhs(state[:n].reshape(shape), state[n:].reshape(shape), out)

        rhs(q, v, slopes[0])
        size = min(self.substep_size, h)
        done = 0.0
        last_row = self.pair.slopes - 1
        for _ in range(self.MAX_SUBSTEPS):
            remaining = h - done
            last = size >= remaining * (1.0 - 1e-12)
            trial = remaining if last else size
            a = trial * self.pair.a  # the stage coefficients times the sub-step, once a trial
            for s in range(1, last_row):
                np.matmul(a[s, :s], slopes[:s], out=increment)
                np.add(y, increment, out=stage)
                rhs(stage_q, stage_v, slopes[s])
            y_new = y + a[last_row] @ slopes[:-1]
            if self._estimate_needs_new_state:
                rhs_flat(y_new, slopes[-1])
            scale = self.tolerance * (1.0 + np.maximum(np.abs(y), np.abs(y_new)))
            estimate = trial * (self._error @ slopes[:self._error_slopes])
            norm = self.pair.error_norm(estimate / scale)
            if not math.isfinite(norm):
                norm = math.inf  # an overshooting trial: reject it and shrink the sub-step
            factor = 5.0 if norm == 0.0 else min(5.0, max(0.2, 0.9 * norm ** self._exponent))
            if norm <= 1.0:
                if not self._estimate_needs_new_state:
                    rhs_flat(y_new, slopes[-1])
                self.counters.substeps += 1
                y, done = y_new, done + trial
                slopes[0] = slopes[-1]  # first same as last: k_S is the next k_1
                if last:
                    # A sub-step shortened to land on the end says little about the next size.
                    self.substep_size = trial * factor if trial >= size else size
                    return y[:n].reshape(shape), y[n:].reshape(shape)
            else:
                self.counters.rejected += 1
            size = trial * factor
            if size < 1e-14 * h:
                raise IntegrationError(f"{self.name}: the sub-step size underflowed")
        raise IntegrationError(f"{self.name}: more than {self.MAX_SUBSTEPS} sub-steps in one step")


class ImplicitTheta(Integrator):
    """Implicit midpoint (theta = 1/2) or backward Euler (theta = 1), by Newton's method.

    With v* = v0 + theta (v1 - v0) and q* = q0 + theta h v*, the step solves
    v* = v0 + theta h a(q*, v*), then sets v1 = v0 + (v* - v0) / theta and q1 = q0 + h v*.
    The Newton matrix I - theta h (theta h da/dq + da/dv) uses a Jacobian by forward
    differences at the start of the step, refreshed if convergence is slow. Where Newton's
    method fails (a step so long that the bodies turn far within it), the step is taken as
    two halves, recursively, up to :attr:`MAX_HALVINGS` times.

    :attr:`coloring_source`, if set, is called at each Jacobian for the current
    :class:`~.coloring.Coloring` of the bodies (a Simulation sets it to its model's);
    with fewer groups than bodies the Jacobian is taken by colored differences, equal bit
    for bit to the dense one for finite states (where the acceleration is already NaN the
    dense one spreads NaN through more entries; Newton's method refuses either). Unset,
    every column costs one evaluation.

    :attr:`step_check`, if set, is called with (q0, v0, q1, v1, h) for each solved step
    and refuses a root Newton's method reached on the wrong branch of the forces (a stiff
    spring with a rest length carried through zero length gains energy by orders of
    magnitude in a step); the step is then halved like one that did not converge.
    """

    MAX_ITERATIONS = 50
    MAX_HALVINGS = 8

    def __init__(self, theta: float) -> None:
        name, order = ("implicit_midpoint", 2) if theta == 0.5 else ("backward_euler", 1)
        super().__init__(name, order)
        self.theta = theta
        self.position_share = theta  # q1 = q0 + h v*, v* = v0 + theta (v1 - v0)
        self.coloring_source: Optional[Callable[[], Coloring]] = None
        self.step_check: Optional[StepCheck] = None

    def jacobians(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
                  a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """da/dq and da/dv as (3N, 3N) matrices, by forward differences: colored when a
        coloring with fewer groups than bodies is given, else one column at a time."""
        coloring = None if self.coloring_source is None else self.coloring_source()
        if coloring is not None and len(coloring.groups) < coloring.size:
            jacobian = partial(self._colored_jacobian, a=a, coloring=coloring)
        else:
            jacobian = partial(self._dense_jacobian, a=a)
        return (jacobian(lambda bumped: self._f(f, bumped, v), q),
                jacobian(lambda bumped: self._f(f, q, bumped), v))

    @staticmethod
    def _dense_jacobian(f: Callable[[np.ndarray], np.ndarray], state: np.ndarray,
                        a: np.ndarray) -> np.ndarray:
        """da/dstate, one evaluation per component of ``state`` (``a`` = f(state))."""
        m = state.size
        jac = np.empty((m, m))
        flat = state.ravel()
        for j in range(m):
            delta = 1.5e-8 * max(1.0, abs(flat[j]))
            bumped = flat.copy()
            bumped[j] += delta
            moved = f(bumped.reshape(state.shape))
            jac[:, j] = ((moved - a) / delta).ravel()
        return jac

    @staticmethod
    def _colored_jacobian(f: Callable[[np.ndarray], np.ndarray], state: np.ndarray,
                           a: np.ndarray, coloring: Coloring) -> np.ndarray:
        """da/dstate by colored differences: one evaluation per state component (x, y,
        angle or their rates) and group, bumping that component of every body of the group
        by the dense method's step; each body's column is read from the rows of the bodies
        it influences, the rest of it is zero. The same arithmetic as the dense method."""
        m = state.size
        jac = np.zeros((m, m))
        delta = 1.5e-8 * np.fmax(1.0, np.abs(state))  # fmax: a NaN reads as 1, as max() does
        flat_delta = delta.ravel()
        for component in range(3):  # x, y, angle (or their rates): the flat index 3 k + c
            for group, rows, bodies in zip(coloring.groups, coloring.rows, coloring.columns):
                bumped = state.copy()
                bumped[group, component] += delta[group, component]
                change = (f(bumped) - a).ravel()
                columns = 3 * bodies + component
                jac[rows, columns] = change[rows] / flat_delta[columns]
        return jac

    def step(self, f: Accelerations, q: np.ndarray, v: np.ndarray, h: float,
             halvings: int = 0) -> tuple[np.ndarray, np.ndarray]:
        try:
            q1, v1 = self._solve(f, q, v, h)
            if self.step_check is not None and not self.step_check(q, v, q1, v1, h):
                raise IntegrationError(f"{self.name}: Newton's method converged on a state "
                                       f"with more energy than the forces can give in "
                                       f"{h:g} s")
            return q1, v1
        except IntegrationError:
            if halvings >= self.MAX_HALVINGS:
                raise
        self.counters.substeps += 1
        q, v = self.step(f, q, v, h / 2.0, halvings + 1)
        return self.step(f, q, v, h / 2.0, halvings + 1)

    def _solve(self, f: Accelerations, q: np.ndarray, v: np.ndarray,
               h: float) -> tuple[np.ndarray, np.ndarray]:
        """One step by Newton's method; raises :class:`IntegrationError` if it fails."""
        th = self.theta * h
        v_star = v.copy()
        matrix = None
        # Rounding of the positions q + theta h v* (about eps |q|) moves v* by up to about
        # eps |q| / (theta h) through a stiff force: no update can be trusted below that.
        floor = 16.0 * np.finfo(float).eps * (float(np.max(np.abs(q))) / th
                                              + float(np.max(np.abs(v))))
        for iteration in range(self.MAX_ITERATIONS):
            q_star = q + th * v_star
            a = self._f(f, q_star, v_star)
            residual = (v_star - v - th * a).ravel()
            if matrix is None or iteration % 8 == 7:
                jq, jv = self.jacobians(f, q_star, v_star, a)
                matrix = np.eye(q.size) - th * (th * jq + jv)
            try:
                delta = np.linalg.solve(matrix, -residual).reshape(v.shape)
            except np.linalg.LinAlgError:  # numpy's "Singular matrix" told the user nothing
                raise IntegrationError(
                    f"{self.name}: Newton's method met a singular Jacobian at step {h:g} s (a "
                    "force's stiffness times the step squared past what doubles resolve)"
                ) from None
            v_star = v_star + delta
            self.counters.newton_iterations += 1
            if not np.all(np.isfinite(v_star)):
                raise IntegrationError(f"{self.name}: Newton's method diverged at step {h:g} s")
            if np.max(np.abs(delta)) <= 1e-13 * (1.0 + np.max(np.abs(v_star))) + floor:
                return q + h * v_star, v + (v_star - v) / self.theta
        raise IntegrationError(f"{self.name}: Newton's method did not converge in "
                               f"{self.MAX_ITERATIONS} iterations at step {h:g} s")


METHODS = ("explicit_euler", "semi_implicit_euler", "velocity_verlet", "rk4", "dopri5", "dop853",
           "implicit_midpoint", "backward_euler")
#: The adaptive methods: their ``tolerance`` matters, their step is only the longest sub-step.
ADAPTIVE = ("dopri5", "dop853")
#: Largest stiffness rate x step at which ``auto`` keeps an explicit method.
AUTO_STIFF_LIMIT = 0.5
#: Most bodies for which ``auto`` picks an implicit method, in a scene with contacts: above
#: it Newton's dense solve costs more than dopri5's short sub-steps (docs/scenes.md has the
#: measurements). The rule reads the scene only, never whether the kernel was built, so
#: both builds pick the same method.
AUTO_IMPLICIT_BODIES = 4


def make_integrator(name: str, tolerance: float = 1e-6) -> Integrator:
    """Create the integrator called ``name`` (one of :data:`METHODS`)."""
    factories: dict[str, Callable[[], Integrator]] = {
        "explicit_euler": ExplicitEuler,
        "semi_implicit_euler": SemiImplicitEuler,
        "velocity_verlet": VelocityVerlet,
        "rk4": RungeKutta4,
        "dopri5": lambda: EmbeddedRungeKutta(DOPRI5, tolerance),
        "dop853": lambda: EmbeddedRungeKutta(DOP853, tolerance),
        "implicit_midpoint": lambda: ImplicitTheta(0.5),
        "backward_euler": lambda: ImplicitTheta(1.0),
    }
    if name not in factories:
        raise ValueError(f"unknown integrator '{name}' (known: {', '.join(METHODS)})")
    return factories[name]()


def fastest_rate(method: str, step: float) -> Optional[float]:
    """The fastest rate (1/s: a spring's frequency, a damper's decay rate) that ``method``
    can follow through a step of ``step`` s, if it is adaptive (None for the others, which
    take the step whole): a sub-step dt keeps a mode of rate r from growing only where
    r dt is at most the pair's :attr:`~.tableaux.EmbeddedPair.reach`, so a faster rate needs
    more than :attr:`EmbeddedRungeKutta.MAX_SUBSTEPS` sub-steps (the step fails) or lets the
    mode grow. dopri5 follows at most 4e8 rad/s over a step of 1 ms (a spring of 1.6e17 N/m
    on 1 kg); its tolerance asks for shorter sub-steps, so it may fail sooner."""
    pairs = {"dopri5": DOPRI5, "dop853": DOP853}
    if method not in pairs:
        return None
    return EmbeddedRungeKutta.MAX_SUBSTEPS * pairs[method].reach / step


def choose_method(stiffness: float, step: float, bodies: int, contacts: bool) -> str:
    """The method ``auto`` picks: implicit midpoint when the forces are stiff for the step
    (stiffness rate x step above :data:`AUTO_STIFF_LIMIT`), there are at most
    :data:`AUTO_IMPLICIT_BODIES` bodies and the scene has ``contacts`` (walls or
    collisions), else adaptive Dormand-Prince, which stays stable on stiff forces by taking
    short sub-steps and meets the scene's tolerance."""
    stiff = stiffness * step > AUTO_STIFF_LIMIT
    implicit = stiff and bodies <= AUTO_IMPLICIT_BODIES and contacts
    return "implicit_midpoint" if implicit else "dopri5"
