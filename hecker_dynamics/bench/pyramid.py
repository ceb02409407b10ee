"""The contact benchmark's own scenes: a pyramid of boxes on a floor, a box of balls.

:func:`pyramid`: ``rows`` rows of 0.5 m boxes (1 kg), the bottom row of ``rows`` boxes
resting on the floor y = 0 and each row above one box shorter and offset by half a box,
spaced 5 % of a box apart so that no two boxes start touching side by side; friction 0.6
and restitution 0 everywhere, gravity, semi-implicit Euler at h = 4 ms.

:func:`ball_box`: 100 balls of radius 0.1 m (0.5 kg) in a 10 x 10 grid, 0.25 m apart,
thrown about at up to 2 m/s (a fixed pattern, so every run is the same) inside a box 3 m
wide and 4 m tall; restitution 0.5 and friction 0.4 everywhere, gravity, semi-implicit
Euler at h = 2 ms, 5 s: they collide, settle and rest in a heap.

:func:`many_pyramids`: :data:`MANY` pyramids side by side on one floor, 1 m apart, as
Box2D v3's ``many_pyramids`` benchmark sets its small pyramids out (scaled to fit: it
has 20 x 20 pyramids of 10 rows), 2 s. :func:`tumbler`: boxes in a square drum (Box2D
v3's ``tumbler``, scaled to fit) that turns about its pinned centre; the drum is heavy
and starts turning, as every peer can build it (a revolute pin to the world, no motor or
kinematic body), 4 s.
"""
from __future__ import annotations

import math

from ..scene.load import Scene, scene_from_parameters
from ..scene.parameters import flatten

__all__ = ["BALLS", "BOX", "FRICTION", "GAP", "MANY", "STEP", "TUMBLER", "ball_box",
           "many_pyramids", "pyramid", "pyramid_positions", "tumbler"]

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
    return _boxes_on_floor(pyramid_positions(rows), duration, integrator, sleep,
                           f"bench:pyramid{rows}")


#: The many pyramids: how many, and the rows of each.
MANY = {"pyramids": 8, "rows": 10}


def many_pyramids(sleep: bool = False) -> Scene:
    """:data:`MANY` pyramids of the benchmark's boxes side by side, 1 m apart, 2 s."""
    rows = MANY["rows"]
    width = rows * (BOX + GAP) + 1.0
    positions = [(x + k * width, y) for k in range(MANY["pyramids"])
                 for x, y in pyramid_positions(rows)]
    return _boxes_on_floor(positions, 2.0, "semi_implicit_euler", sleep, "bench:many_pyramids")


def _boxes_on_floor(positions: list[tuple[float, float]], duration: float, integrator: str,
                    sleep: bool, source: str) -> Scene:
    names = [f"box{k}" for k in range(len(positions))]
    bodies = {name: {"shape": "box", "size": [BOX, BOX], "mass": 1.0, "position": list(p)}
              for name, p in zip(names, positions)}
    params = {
        "step": STEP, "integrator": integrator, "duration": duration, "publish_rate": 50.0,
        "bodies": bodies,
        "forces": {"gravity": {"type": "gravity"}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.0,
                            "friction": FRICTION}},
        "collisions": {"boxes": {"bodies": names, "restitution": 0.0, "friction": FRICTION}},
        "contacts": {"sleep": sleep},
    }
    return scene_from_parameters(flatten(params), source)


#: The tumbler: the drum's inner side and wall thickness (m), mass (kg) and starting turn
#: rate (rad/s, Box2D v3's 25 degrees a second); its boxes' side (m) and mass (kg), a
#: side of their starting grid, and the run's length (s).
TUMBLER = {"side": 4.0, "wall": 0.25, "drum_mass": 5000.0, "spin": math.radians(25.0),
           "box": 0.2, "box_mass": 0.25, "grid": 14, "duration": 4.0}


def tumbler(sleep: bool = False) -> Scene:
    """:data:`TUMBLER`: a grid of small boxes, 5 % of a box apart, at rest in a square drum
    of four box parts pinned to the world at its centre and turning; gravity, friction 0.6,
    no restitution, semi-implicit Euler at the pyramids' step."""
    side, wall, box, grid = TUMBLER["side"], TUMBLER["wall"], TUMBLER["box"], int(TUMBLER["grid"])
    offset = 0.5 * (side + wall)
    parts = {name: {"shape": "box", "size": size, "center": center} for name, size, center in (
        ("floor", [side + 2 * wall, wall], [0.0, -offset]),
        ("roof", [side + 2 * wall, wall], [0.0, offset]),
        ("left", [wall, side], [-offset, 0.0]),
        ("right", [wall, side], [offset, 0.0]))}
    pitch = 1.05 * box
    bodies: dict[str, dict[str, object]] = {
        "drum": {"parts": parts, "mass": TUMBLER["drum_mass"],
                 "angular_velocity": TUMBLER["spin"]}}
    for k in range(grid * grid):
        row, column = divmod(k, grid)
        bodies[f"box{k:03d}"] = {"shape": "box", "size": [box, box], "mass": TUMBLER["box_mass"],
                                 "position": [(column - 0.5 * (grid - 1)) * pitch,
                                              -0.5 * side + 0.5 * box + row * pitch]}
    params = {
        "step": STEP, "integrator": "semi_implicit_euler", "duration": TUMBLER["duration"],
        "publish_rate": 50.0, "bodies": bodies,
        "forces": {"gravity": {"type": "gravity"}},
        "joints": {"axle": {"type": "revolute", "body_b": "drum", "point_b": [0.0, 0.0]}},
        "collisions": {"tumbler": {"bodies": list(bodies), "restitution": 0.0,
                                   "friction": FRICTION}},
        "contacts": {"sleep": sleep},
    }
    return scene_from_parameters(flatten(params), "bench:tumbler")


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
