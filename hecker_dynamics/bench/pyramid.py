"""The contact benchmark's own scenes: a pyramid of boxes on a floor, a box of balls.

:func:`pyramid`: ``rows`` rows of 0.5 m boxes (1 kg), the bottom row of ``rows`` boxes
resting on the floor y = 0 and each row above one box shorter and offset by half a box,
spaced 5 % of a box apart so that no two boxes start touching side by side; friction 0.6
and restitution 0 everywhere, gravity, semi-implicit Euler at h = 4 ms.

:func:`ball_box`: 100 balls of radius 0.1 m (0.5 kg) in a 10 x 10 grid, 0.25 m apart,
thrown about at up to 2 m/s (a fixed pattern, so every run is the same) inside a box 3 m
wide and 4 m tall; restitution 0.5 and friction 0.4 everywhere, gravity, semi-implicit
Euler at h = 2 ms, 5 s: they collide, settle and rest in a heap.
"""
from __future__ import annotations

import math

from ..scene.load import Scene, scene_from_parameters
from ..scene.parameters import flatten

__all__ = ["BALLS", "BOX", "FRICTION", "GAP", "STEP", "ball_box", "pyramid", "pyramid_positions"]

BOX = 0.5
GAP = 0.05 * BOX
FRICTION = 0.6
STEP = 0.004


def pyramid_positions(rows: int) -> list[tuple[float, float]]:
    """Box centers, bottom row first, each row left to right."""
    pitch = BOX + GAP
    return [((column - 0.5 * (rows - 1 - row)) * pitch, 0.5 * BOX + row * BOX)
            for row in range(rows) for column in range(rows - row)]


def pyramid(rows: int, duration: float = 2.0, integrator: str = "semi_implicit_euler",
            sleep: bool = False) -> Scene:
    """The pyramid of ``rows`` rows (rows (rows + 1) / 2 boxes) at the benchmark's settings;
    ``sleep``: resting islands sleep (the scene's ``contacts.sleep``)."""
    names = [f"box{k}" for k in range(rows * (rows + 1) // 2)]
    bodies = {name: {"shape": "box", "size": [BOX, BOX], "mass": 1.0, "position": list(p)}
              for name, p in zip(names, pyramid_positions(rows))}
    params = {
        "step": STEP, "integrator": integrator, "duration": duration, "publish_rate": 50.0,
        "bodies": bodies,
        "forces": {"gravity": {"type": "gravity"}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.0,
                            "friction": FRICTION}},
        "collisions": {"boxes": {"bodies": names, "restitution": 0.0, "friction": FRICTION}},
        "contacts": {"sleep": sleep},
    }
    return scene_from_parameters(flatten(params), f"bench:pyramid{rows}")


#: The ball box's balls: a side of the square grid, radius, mass, step (s), duration (s).
BALLS = {"grid": 10, "radius": 0.1, "mass": 0.5, "step": 0.002, "duration": 5.0}


def ball_box(sleep: bool = False, grid: int = int(BALLS["grid"])) -> Scene:
    """The box of 100 balls with friction (see the module's docstring); ``sleep``: resting
    islands sleep; ``grid``: balls per side of the starting grid."""
    radius = BALLS["radius"]
    names = [f"ball{k:03d}" for k in range(grid * grid)]
    bodies = {}
    for k, name in enumerate(names):
        row, column = divmod(k, grid)
        phase = 0.7 * k
        bodies[name] = {"shape": "circle", "radius": radius, "mass": BALLS["mass"],
                        "position": [(column - 0.5 * (grid - 1)) * 0.25, 0.3 + row * 0.25],
                        "velocity": [2.0 * math.sin(phase), 2.0 * math.cos(1.3 * phase)]}
    material = {"restitution": 0.5, "friction": 0.4}
    walls = {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]},
             "ceiling": {"point": [0.0, 4.0], "normal": [0.0, -1.0]},
             "left": {"point": [-1.5, 0.0], "normal": [1.0, 0.0]},
             "right": {"point": [1.5, 0.0], "normal": [-1.0, 0.0]}}
    params = {
        "step": BALLS["step"], "integrator": "semi_implicit_euler",
        "duration": BALLS["duration"], "publish_rate": 50.0, "bodies": bodies,
        "forces": {"gravity": {"type": "gravity"}},
        "walls": {name: {**wall, **material} for name, wall in walls.items()},
        "collisions": {"balls": {"bodies": names, **material}},
        "contacts": {"sleep": sleep},
    }
    return scene_from_parameters(flatten(params), "bench:ball_box")
