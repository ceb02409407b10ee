"""hecker_dynamics: 2D rigid bodies with linear and angular effects.

The core follows Chris Hecker's "Physics, Part 2: Angular Effects" (Game Developer, 1997):
the center of mass and moment of inertia from the shape (Eq. 3 and Eq. 13), forces with
points of application, perp-dot torques (Eq. 11), and integration of linear and angular
motion (F = M a, Eq. 5; tau = I alpha, Eq. 14). :class:`World` is the Python API
(``docs/api.md``). Nothing here imports rclpy; the ROS node in ``hecker_dynamics.ros.node``
is thin glue over a :class:`World` (``hecker_dynamics.ros.runner.Runner``).

The API's names are imported on first use (``hd.World``, ``from hecker_dynamics import
World``), so that importing a submodule, as the console script does before it takes
SIGTERM (``hecker_dynamics.console``), does not load numpy and the core first.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

if TYPE_CHECKING:
    from .dynamics.simulation import BodyState, DivergenceError, Simulation, Snapshot
    from .scene.commands import InputError, WrenchCommand
    from .scene.load import Scene, SceneError, load_scene, scene_from_parameters
    from .world import Body, Box, Circle, Polygon, World

__all__ = ["__version__", "InputError", "WrenchCommand", "Scene", "SceneError", "load_scene",
           "scene_from_parameters", "BodyState", "DivergenceError", "Simulation", "Snapshot",
           "World", "Body", "Box", "Circle", "Polygon"]

#: Where each name of the API is defined, by module below the package.
_HOMES = {
    **dict.fromkeys(("BodyState", "DivergenceError", "Simulation", "Snapshot"),
                    ".dynamics.simulation"),
    **dict.fromkeys(("InputError", "WrenchCommand"), ".scene.commands"),
    **dict.fromkeys(("Scene", "SceneError", "load_scene", "scene_from_parameters"),
                    ".scene.load"),
    **dict.fromkeys(("Body", "Box", "Circle", "Polygon", "World"), ".world"),
}


if not TYPE_CHECKING:  # mypy sees the names imported above; a module __getattr__ would
    # also answer for the compiled kernel, which has no stub, as Any.
    def __getattr__(name: str) -> Any:
        home = _HOMES.get(name)
        if home is None:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(home, __name__), name)
        globals()[name] = value  # once: later lookups find it without this function
        return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
