"""hecker_dynamics: 2D rigid bodies with linear and angular effects.

The core follows Chris Hecker's "Physics, Part 2: Angular Effects" (Game Developer, 1997):
the center of mass and moment of inertia from the shape (Eq. 3 and Eq. 13), forces with
points of application, perp-dot torques (Eq. 11), and integration of linear and angular
motion (F = M a, Eq. 5; tau = I alpha, Eq. 14). :class:`World` is the Python API
(``docs/api.md``). Nothing here imports rclpy; the ROS node in ``hecker_dynamics.ros.node``
is thin glue over a :class:`World` (``hecker_dynamics.ros.runner.Runner``).
"""
from ._version import __version__
from .dynamics.simulation import BodyState, DivergenceError, Simulation, Snapshot
from .scene.commands import InputError, WrenchCommand
from .scene.load import Scene, SceneError, load_scene, scene_from_parameters
from .world import Body, Box, Circle, Polygon, World

__all__ = ["__version__", "InputError", "WrenchCommand", "Scene", "SceneError", "load_scene",
           "scene_from_parameters", "BodyState", "DivergenceError", "Simulation", "Snapshot",
           "World", "Body", "Box", "Circle", "Polygon"]
