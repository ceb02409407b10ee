"""The contact benchmark's scene: a pyramid of boxes on a floor (issue 13).

``rows`` rows of 0.5 m boxes (1 kg), the bottom row of ``rows`` boxes resting on the
floor y = 0 and each row above one box shorter and offset by half a box, spaced 5 % of a
box apart so that no two boxes start touching side by side; friction 0.6 and restitution 0
everywhere, gravity, semi-implicit Euler at h = 4 ms, as the issue measured the peers.
"""
from __future__ import annotations

from ..scene.load import Scene, scene_from_parameters
from ..scene.parameters import flatten

__all__ = ["BOX", "FRICTION", "GAP", "STEP", "pyramid", "pyramid_positions"]

BOX = 0.5
GAP = 0.05 * BOX
FRICTION = 0.6
STEP = 0.004


def pyramid_positions(rows: int) -> list[tuple[float, float]]:
    """Box centers, bottom row first, each row left to right."""
    pitch = BOX + GAP
    return [((column - 0.5 * (rows - 1 - row)) * pitch, 0.5 * BOX + row * BOX)
            for row in range(rows) for column in range(rows - row)]


def pyramid(rows: int, duration: float = 2.0, integrator: str = "semi_implicit_euler") -> Scene:
    """The pyramid of ``rows`` rows (rows (rows + 1) / 2 boxes) at the benchmark's settings."""
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
    }
    return scene_from_parameters(flatten(params), f"bench:pyramid{rows}")
