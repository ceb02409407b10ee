"""Exact solutions and high-accuracy references for the benchmark scenes.

- ``free_spin``, ``harmonic`` and ``stiff`` have closed forms (:func:`exact`):
  constant acceleration x = x0 + v0 t + F t^2 / 2m, angle = a0 + w0 t + tau t^2 / 2I, and
  the oscillator x = x0 cos(w t) + v0/w sin(w t), w = sqrt(k/m).
- ``spring_pendulum``, ``two_bodies`` and the ring use :func:`gbs_reference`: the equations
  of motion written again here from the scene's specs, in plain Python (independent of
  the core's ``model.py``/``forces.py``), integrated by Gragg-Bulirsch-Stoer extrapolation
  (modified midpoint with 2, 4, ..., 2L sub-steps, Neville extrapolation in h^2, order 2L)
  at a fixed macro step H. Its own error is estimated as the difference between the runs
  at H and H/2 (the H/2 run is the reference).
- Shipped scenes (walls, contacts, scripted inputs) use :func:`core_reference`: the core
  itself at a much smaller step; its error is estimated by the same run at twice that step.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..scene.load import (
    AngularDampingSpec,
    ConstantForceSpec,
    ConstantTorqueSpec,
    DragSpec,
    Gravity,
    Scene,
    SpringSpec,
)
from .force_law import State, Wrenches, make_wrenches

__all__ = ["Reference", "PlainModel", "gbs_step", "gbs_integrate", "gbs_reference", "exact",
           "free_spin_energy", "reference", "core_reference"]


@dataclass
class Reference:
    """The state at the end of the run: CM positions and angles ``q`` (N, 3) and velocities
    ``v`` (N, 3), the initial energy (None where it is not conserved), how it was
    obtained and an estimate of its own final position error (m)."""

    q: np.ndarray
    v: np.ndarray
    energy0: float | None
    kind: str
    error: float
    angle_error: float = 0.0


#: y -> dy/dt of the plain model's flattened state (positions then velocities).
Derivative = Callable[[np.ndarray], np.ndarray]


def _rot(c: float, s: float, x: float, y: float) -> tuple[float, float]:
    return c * x - s * y, s * x + c * y


class PlainModel:
    """The scene's forces written out again in plain Python, from its specs.

    Supports bodies, gravity, springs (anchor or body, with rest length and damping),
    linear and quadratic drag at the CM or at a point, angular damping, constant forces
    (world or body axes, at the CM or a point) and torques. Walls, collisions and inputs
    are refused. The state is y = (x_i, y_i, angle_i for each body, then vx_i, vy_i, w_i).
    """

    def __init__(self, scene: Scene) -> None:
        if scene.walls or scene.collisions or scene.script:
            raise ValueError(f"{scene.source}: the plain model has no walls, contacts or inputs")
        self.n = len(scene.bodies)
        self.index = {b.name: i for i, b in enumerate(scene.bodies)}
        self.mass = [b.mass.mass for b in scene.bodies]
        self.inertia = [b.mass.moment_of_inertia for b in scene.bodies]
        self.cm = [b.mass.center_of_mass for b in scene.bodies]
        self.constant = [[0.0, 0.0, 0.0] for _ in range(self.n)]  # gravity, torques
        self.gravity: list[tuple[int, float, float]] = []
        self.springs = []  # (a, local_a, b or -1, local_b or anchor, k, L0, c)
        self.drags = []  # (body, local or None, c, quadratic)
        self.angular = []  # (body, c)
        self.forces = []  # (body, fx, fy, body_axes, local or None)
        for spec in scene.forces:
            if isinstance(spec, Gravity):
                for name in spec.bodies:
                    i = self.index[name]
                    gx, gy = spec.acceleration
                    self.gravity.append((i, gx, gy))
                    self.constant[i][0] += self.mass[i] * gx
                    self.constant[i][1] += self.mass[i] * gy
            elif isinstance(spec, SpringSpec):
                a = self.index[spec.body_a]
                b = -1 if spec.body_b is None else self.index[spec.body_b]
                pb = spec.point_b if b < 0 else self.local(b, spec.point_b)
                self.springs.append((a, self.local(a, spec.point_a), b, pb, spec.stiffness,
                                     spec.rest_length, spec.damping))
            elif isinstance(spec, DragSpec):
                for name in spec.bodies:
                    i = self.index[name]
                    local = None if spec.point is None else self.local(i, spec.point)
                    self.drags.append((i, local, spec.coefficient, spec.quadratic))
            elif isinstance(spec, AngularDampingSpec):
                for name in spec.bodies:
                    self.angular.append((self.index[name], spec.coefficient))
            elif isinstance(spec, ConstantTorqueSpec):
                self.constant[self.index[spec.body]][2] += spec.torque
            elif isinstance(spec, ConstantForceSpec):
                i = self.index[spec.body]
                local = None if spec.point is None else self.local(i, spec.point)
                if not spec.body_axes and local is None:
                    self.constant[i][0] += spec.force[0]
                    self.constant[i][1] += spec.force[1]
                else:
                    self.forces.append((i, spec.force[0], spec.force[1], spec.body_axes, local))
            else:  # pragma: no cover - a new kind of force
                raise ValueError(f"{scene.source}: the plain model lacks {type(spec).__name__}")
        self.conservative = not (self.drags or self.angular or self.forces
                                 or any(s[6] for s in self.springs)
                                 or any(c[2] for c in self.constant)
                                 or any(c[:2] != [0.0, 0.0] for c in self._nongravity()))
        self.y0 = self.initial(scene)
        self._law: Optional[Callable[[Sequence[State]], Wrenches]] = None

    def _nongravity(self) -> list[list[float]]:
        rest = [list(c) for c in self.constant]
        for i, gx, gy in self.gravity:
            rest[i][0] -= self.mass[i] * gx
            rest[i][1] -= self.mass[i] * gy
        return [[round(c[0], 12), round(c[1], 12), c[2]] for c in rest]

    def local(self, body: int, point: Sequence[float]) -> tuple[float, float]:
        return point[0] - self.cm[body][0], point[1] - self.cm[body][1]

    def initial(self, scene: Scene) -> np.ndarray:
        q, v = [], []
        for b, (cx, cy) in zip(scene.bodies, self.cm):
            c, s = math.cos(b.angle), math.sin(b.angle)
            rx, ry = _rot(c, s, cx, cy)
            q += [b.position[0] + rx, b.position[1] + ry, b.angle]
            v += [b.velocity[0] - b.angular_velocity * ry,
                  b.velocity[1] + b.angular_velocity * rx, b.angular_velocity]
        return np.array(q + v)

    def without(self, springs: bool = False, gravity: bool = False) -> PlainModel:
        """A copy without its springs and/or its gravity (for a peer that has its own)."""
        other = object.__new__(PlainModel)
        other.__dict__.update(self.__dict__)
        other.constant = [list(c) for c in self.constant]
        other._law = None
        if springs:
            other.springs = []
        if gravity:
            for i, gx, gy in self.gravity:
                other.constant[i][0] -= self.mass[i] * gx
                other.constant[i][1] -= self.mass[i] * gy
            other.gravity = []
        return other

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """The initial CM positions and angles, and velocities, (N, 3) each (copies)."""
        n = self.n
        return self.y0[:3 * n].reshape(n, 3).copy(), self.y0[3 * n:].reshape(n, 3).copy()

    def accelerations(self, y: np.ndarray) -> list[float]:
        """(ax, ay, alpha) of every body, flattened, at the state ``y``."""
        n = self.n
        states = [(float(y[3 * i]), float(y[3 * i + 1]), float(y[3 * i + 2]),
                   float(y[3 * n + 3 * i]), float(y[3 * n + 3 * i + 1]),
                   float(y[3 * n + 3 * i + 2])) for i in range(n)]
        out = []
        for i, (fx, fy, tau) in enumerate(self.wrenches(states)):
            out += [fx / self.mass[i], fy / self.mass[i], tau / self.inertia[i]]
        return out

    def wrenches(self, states: list[tuple[float, float, float, float, float, float]]
                 ) -> list[list[float]]:
        """Force (fx, fy) and torque about the CM on every body, from each body's CM state
        (x, y, angle, vx, vy, omega) as plain floats: the scene's force law
        (:func:`~.force_law.make_wrenches`), as a user of a peer engine would write it in
        Python."""
        if self._law is None:
            self._law = make_wrenches(self.springs, self.drags, self.angular, self.forces,
                                      self.constant)
        return self._law(states)

    def derivative(self, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[3 * self.n:], self.accelerations(y)])

    def energy(self, y: np.ndarray) -> float | None:
        """Kinetic + gravity + spring energy; None when forces other than these act."""
        if not self.conservative:
            return None
        n = self.n
        e = 0.0
        for i in range(n):
            vx, vy, w = y[3 * n + 3 * i: 3 * n + 3 * i + 3]
            e += 0.5 * self.mass[i] * (vx * vx + vy * vy) + 0.5 * self.inertia[i] * w * w
        for i, gx, gy in self.gravity:
            e -= self.mass[i] * (gx * y[3 * i] + gy * y[3 * i + 1])
        for a, la, b, lb, k, rest, _ in self.springs:
            c, s = math.cos(y[3 * a + 2]), math.sin(y[3 * a + 2])
            rax, ray = _rot(c, s, *la)
            if b < 0:
                pbx, pby = lb
            else:
                cb, sb = math.cos(y[3 * b + 2]), math.sin(y[3 * b + 2])
                rbx, rby = _rot(cb, sb, *lb)
                pbx, pby = y[3 * b] + rbx, y[3 * b + 1] + rby
            length = math.hypot(y[3 * a] + rax - pbx, y[3 * a + 1] + ray - pby)
            e += 0.5 * k * (length - rest) ** 2
        return e


def gbs_step(f: Derivative, y: np.ndarray, big: float, levels: int = 8) -> np.ndarray:
    """One Gragg-Bulirsch-Stoer step of size ``big``: modified midpoint with 2, 4, ..., 2L
    sub-steps, extrapolated to zero step (Neville in h^2); order 2L."""
    sequence = [2 * (j + 1) for j in range(levels)]
    table: list[np.ndarray] = []
    f0 = f(y)
    for j, n in enumerate(sequence):
        h = big / n
        z_prev, z = y, y + h * f0
        for _ in range(n - 1):
            z_prev, z = z, z_prev + 2.0 * h * f(z)
        row = [0.5 * (z + z_prev + h * f(z))]
        for k in range(1, j + 1):
            ratio = (sequence[j] / sequence[j - k]) ** 2
            row.append(row[k - 1] + (row[k - 1] - table[k - 1]) / (ratio - 1.0))
        table = row
    return table[-1]


def gbs_integrate(f: Derivative, y0: np.ndarray, duration: float, big: float,
                  levels: int = 8) -> np.ndarray:
    steps = max(1, round(duration / big))
    h = duration / steps
    y = np.array(y0, dtype=float)
    for _ in range(steps):
        y = gbs_step(f, y, h, levels)
    return y


def _split(y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    return y[:3 * n].reshape(n, 3).copy(), y[3 * n:].reshape(n, 3).copy()


def gbs_reference(scene: Scene, duration: float | None = None, big: float = 0.01,
                  levels: int = 8) -> Reference:
    """The scene's final state by GBS at macro step ``big``/2, with the difference from
    the run at ``big`` as its error estimate."""
    model = PlainModel(scene)
    duration = scene.duration_ns * 1e-9 if duration is None else duration
    coarse = gbs_integrate(model.derivative, model.y0, duration, big, levels)
    fine = gbs_integrate(model.derivative, model.y0, duration, big / 2.0, levels)
    n = model.n
    q, v = _split(fine, n)
    qc, _ = _split(coarse, n)
    error = float(np.max(np.hypot(*(q[:, :2] - qc[:, :2]).T)))
    angle_error = float(np.max(np.abs(q[:, 2] - qc[:, 2])))
    return Reference(q, v, model.energy(model.y0), f"GBS order {2 * levels}, H = {big / 2:g} s",
                     error, angle_error)


def exact(scene: Scene, duration: float | None = None) -> Reference:
    """Closed-form final state of ``free_spin`` (constant wrench at the CM) or of
    ``harmonic``/``stiff`` (zero-length undamped springs from the CM to the origin)."""
    model = PlainModel(scene)
    t = scene.duration_ns * 1e-9 if duration is None else duration
    n = model.n
    q0, v0 = _split(model.y0, n)
    q, v = np.empty_like(q0), np.empty_like(v0)
    name = scene.source.removeprefix("bench:")
    for i in range(n):
        if name == "free_spin":
            fx, fy, tau = model.constant[i]
            a = (fx / model.mass[i], fy / model.mass[i], tau / model.inertia[i])
            for j in range(3):
                q[i, j] = q0[i, j] + v0[i, j] * t + 0.5 * a[j] * t * t
                v[i, j] = v0[i, j] + a[j] * t
        elif name in ("harmonic", "stiff"):
            (_, la, b, anchor, k, rest, damp), = model.springs
            if rest or damp or la != (0.0, 0.0) or b >= 0:
                raise ValueError("the exact oscillator needs one zero-length undamped spring "
                                 "at the CM to an anchor")
            w = math.sqrt(k / model.mass[i])
            c, s = math.cos(w * t), math.sin(w * t)
            for j in range(2):
                x0 = q0[i, j] - anchor[j]
                q[i, j] = anchor[j] + x0 * c + v0[i, j] / w * s
                v[i, j] = -x0 * w * s + v0[i, j] * c
            q[i, 2] = q0[i, 2] + v0[i, 2] * t
            v[i, 2] = v0[i, 2]
        else:
            raise ValueError(f"no exact solution for {scene.source}")
    energy0 = model.energy(model.y0)
    if name == "free_spin":  # kinetic energy less the work potential of the constant wrench
        energy0 = free_spin_energy(model, q0, v0)
    return Reference(q, v, energy0, "exact", 0.0)


def free_spin_energy(model: PlainModel, q: np.ndarray, v: np.ndarray) -> float:
    """Kinetic energy minus F.x minus tau.angle (conserved under a constant wrench); the
    angle must be unwrapped."""
    e = 0.0
    for i in range(model.n):
        fx, fy, tau = model.constant[i]
        e += (0.5 * model.mass[i] * (v[i, 0] ** 2 + v[i, 1] ** 2)
              + 0.5 * model.inertia[i] * v[i, 2] ** 2)
        e -= fx * q[i, 0] + fy * q[i, 1] + tau * q[i, 2]
    return e


def reference(scene: Scene) -> Reference:
    """Exact where there is a closed form, else GBS (scenes without walls/inputs)."""
    if scene.source.removeprefix("bench:") in ("free_spin", "harmonic", "stiff"):
        return exact(scene)
    return gbs_reference(scene)


def core_reference(scene: Scene, step: float, method: str | None = None,
                   tolerance: float = 1e-10) -> Reference:
    """The core itself at ``step`` (and ``method``, default the scene's), with its error
    estimated by the same run at twice the step. For scenes with contacts and inputs."""
    from ..dynamics.simulation import Simulation
    from .scenes import configure

    runs = []
    for h in (2.0 * step, step):
        sim = Simulation(configure(scene, method or scene.integrator, h, tolerance))
        sim.play(scene.script, scene.duration_ns)
        runs.append((sim.q.copy(), sim.v.copy()))
    (qc, _), (q, v) = runs
    error = float(np.max(np.hypot(*(q[:, :2] - qc[:, :2]).T)))
    angle_error = float(np.max(np.abs(np.remainder(q[:, 2] - qc[:, 2] + math.pi, 2 * math.pi)
                                      - math.pi)))
    return Reference(q, v, None, f"core {method or scene.integrator}, h = {step:g} s "
                                 f"(vs {2 * step:g} s)", error, angle_error)
