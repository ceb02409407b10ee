"""Small scene builders and integration loops shared by the physics tests.

Scenes are written as nested dicts (as in a parameters file) and go through the same
loader as a node's flat parameters (``scene_from_parameters``), so the tests exercise the
real validation and mass-property code.
"""
from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
import scene_builders

from hecker_dynamics.dynamics.model import Model
from hecker_dynamics.integrators.methods import make_integrator
from hecker_dynamics.scene.load import Scene

# pi to 50 digits, for exact references of wrapped angles.
PI = Fraction("3.14159265358979323846264338327950288419716939937510")


def make_scene(params: dict[str, Any], source: str = "test-scene") -> Scene:
    """:func:`scene_builders.make_scene`, with ``publish_rate`` defaulting to once per step."""
    return scene_builders.make_scene(
        {"publish_rate": 1.0 / params.get("step", 0.001), **params}, source)


def oscillator(stiffness: float = 100.0, *, damping: float = 0.0, position=(1.0, 0.0),
               velocity=(0.0, 0.0), **extra: Any) -> Scene:
    """A 1 kg unit box on a zero-length spring from its CM to a fixed anchor at the origin.

    Each of x and y is the oscillator x'' = -(k/m) x - (c/m) x'; the spring acts at the CM,
    so it makes no torque.
    """
    return make_scene({
        "bodies": {"b": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                         "position": list(position), "velocity": list(velocity)}},
        "forces": {"spring": {"type": "spring", "body_a": "b", "anchor": [0.0, 0.0],
                              "stiffness": stiffness, "damping": damping}},
        **extra,
    })


def integrate(model: Model, method: str, duration: float, steps: int,
              tolerance: float = 1e-6, state=None) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` fixed steps of ``method`` over ``duration`` on ``model``; final (q, v)."""
    integrator = make_integrator(method, tolerance)
    q, v = model.initial_state() if state is None else state
    h = duration / steps
    for _ in range(steps):
        q, v = integrator.step(model.accelerations, q, v, h)
    return q, v


def observed_order(steps: list[float], errors: list[float]) -> float:
    """Least-squares slope of log(error) against log(step)."""
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def exact_wrapped_angle(angle0: float, omega: float, step: float, n: int) -> float:
    """angle0 + omega * n * step wrapped to [-pi, pi), in exact rational arithmetic on the
    given doubles (pi to 50 digits), rounded once at the end."""
    theta = Fraction(angle0) + Fraction(omega) * n * Fraction(step)
    turns = math.floor((theta + PI) / (2 * PI))
    return float(theta - 2 * PI * turns)


def angle_difference(a: float, b: float) -> float:
    """|a - b| taken the short way round the circle."""
    return abs(math.remainder(a - b, 2.0 * math.pi))


def push_unchecked(sim: Any, command: Any) -> None:
    """Queue ``command`` on ``sim`` past the push's check that refuses a wrench running its
    body away within one step (:meth:`Simulation.check_reach`): for the tests of what a
    state overflowing inside a step does."""
    sim._inputs.add(command, sim._row(command))
