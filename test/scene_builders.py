"""Small helpers to build scenes for tests: nested dicts -> flat parameters or YAML files.

A scene is written here as the nested mapping under ``dynamics_node: ros__parameters``.
:func:`make_scene` turns it into flat dotted parameters (the form rclpy hands a node) and
loads it with :func:`scene_from_parameters`; :func:`write_scene` writes the YAML file form.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hecker_dynamics.scene.load import Scene, scene_from_parameters
from hecker_dynamics.scene.parameters import flatten


def make_scene(params: dict[str, Any], source: str = "test-scene") -> Scene:
    """Load a scene from a nested parameter mapping through the flat (node) path."""
    return scene_from_parameters(flatten(params), source)


def write_scene(directory: Path, params: dict[str, Any], name: str = "scene.yaml") -> Path:
    """Write ``params`` as a ROS 2 parameters file and return its path."""
    path = Path(directory) / name
    path.write_text(yaml.safe_dump({"dynamics_node": {"ros__parameters": params}}))
    return path


def box_body(size=(1.0, 0.5), mass=2.0, **state: Any) -> dict[str, Any]:
    """Parameters of a box body (extra keys: position, angle, velocity, ...).

    The box is written as a one-part compound (``parts.hull``), which keeps the shape
    unturned in the body frame whatever the body's ``angle`` (the single-shape form read
    the body's angle as the shape's too until that was fixed; see test_scene.py).
    """
    return {"parts": {"hull": {"shape": "box", "size": [float(x) for x in size]}},
            "mass": float(mass), **state}


def box_inertia(mass: float, width: float, height: float) -> float:
    """Closed form for a uniform rectangle about its center: m (w^2 + h^2) / 12."""
    return mass * (width ** 2 + height ** 2) / 12.0


def rotation(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


#: A scene with every kind of force term, for tests that must cover them all.
EVERY_FORCE = {
    "step": 0.001, "publish_rate": 100.0,
    "bodies": {
        "a": {"shape": "box", "size": [1.0, 0.4], "mass": 2.0, "center": [0.2, 0.1],
              "points": {"tip": [0.5, 0.2]}},
        "b": {"shape": "circle", "radius": 0.3, "mass": 1.5, "position": [2.0, 1.0]},
        "c": {"parts": {"hull": {"shape": "polygon", "vertices": [-1.0, -0.5, 1.0, -0.5, 0.0, 1.0]},
                        "ball": {"shape": "circle", "radius": 0.2, "center": [0.0, -0.8]}},
              "density": 3.0, "position": [-2.0, 0.5]},
    },
    "forces": {
        "gravity": {"type": "gravity", "acceleration": [0.3, -9.81], "bodies": ["a", "c"]},
        "anchored": {"type": "spring", "body_a": "a", "point_a": "tip", "anchor": [0.0, 3.0],
                     "stiffness": 40.0, "rest_length": 0.5, "damping": 0.7},
        "pin": {"type": "spring", "body_a": "c", "point_a": [0.3, 0.2], "anchor": [-2.0, 0.0],
                "stiffness": 500.0, "damping": 2.0},
        "link": {"type": "spring", "body_a": "a", "point_a": [-0.3, 0.1], "body_b": "b",
                 "point_b": [0.1, -0.2], "stiffness": 25.0, "rest_length": 1.0, "damping": 0.3},
        "tie": {"type": "spring", "body_a": "b", "body_b": "c", "stiffness": 10.0},
        "air": {"type": "linear_drag", "coefficient": 0.4},
        "wake": {"type": "quadratic_drag", "bodies": ["c"], "coefficient": 0.2,
                 "point": [0.5, 0.5]},
        "fin": {"type": "linear_drag", "bodies": ["a"], "coefficient": 0.9, "point": "tip"},
        "spin": {"type": "angular_damping", "bodies": ["a", "b"], "coefficient": 0.05},
        "thrust": {"type": "constant_force", "body": "c", "force": [3.0, 1.0], "axes": "body",
                   "point": [0.2, -0.4]},
        "wind": {"type": "constant_force", "body": "b", "force": [-1.0, 0.5]},
        "gust": {"type": "constant_force", "body": "a", "force": [0.0, 2.0], "point": [0.4, 0.0]},
        "motor": {"type": "constant_torque", "body": "b", "torque": 1.5},
    },
}


def driven_robot(drive: dict[str, Any], body: dict[str, Any], *, drag: float = 0.0,
                 integrator: str = "rk4") -> Scene:
    """A lone ``robot`` body (its parameters ``body``) under the drive ``base`` (its
    parameters ``drive``, for ``robot``), with linear drag and angular damping of
    coefficient ``drag`` when it is not zero; 1 ms steps."""
    forces = {"drag": {"type": "linear_drag", "coefficient": drag, "bodies": ["robot"]},
              "spin": {"type": "angular_damping", "coefficient": drag, "bodies": ["robot"]}
              } if drag else {}
    return make_scene({"step": 0.001, "integrator": integrator, "duration": 100.0,
                       "bodies": {"robot": body}, "forces": forces,
                       "drives": {"base": {"body": "robot", **drive}}})


def body_speeds(q: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """Forward and sideways speed of the first body's CM in its own axes, and omega."""
    theta = q[0, 2]
    c, s = math.cos(theta), math.sin(theta)
    vx, vy, omega = v[0]
    return c * vx + s * vy, -s * vx + c * vy, omega
