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

from hecker_dynamics.scene.parameters import flatten
from hecker_dynamics.scene.load import Scene, scene_from_parameters


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
    """Closed form for a uniform rectangle about its centre: m (w^2 + h^2) / 12."""
    return mass * (width ** 2 + height ** 2) / 12.0


def rotation(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])
