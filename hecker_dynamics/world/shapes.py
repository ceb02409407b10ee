"""Shapes a :class:`~.world.World` body is made of, as the scene files declare them.

Each shape turns into the parameters a scene file holds under ``bodies.<name>`` (a single
shape) or ``bodies.<name>.parts.<part>`` (a compound body), so a body built in Python goes
through the same reading, and gets the same mass, center of mass and moment of inertia
(Eq. 3 and Eq. 13, integrated over the area by :mod:`hecker_dynamics.geometry.shapes`), as
one read from a file.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Optional, Union

from .vectors import Vec2, VectorLike, number, vector

__all__ = ["Box", "Circle", "Polygon", "ShapeLike", "shape_parameters"]


def _part(kind: str, center: Vec2, angle: float, density: Optional[float]) -> dict[str, Any]:
    values: dict[str, Any] = {"shape": kind, "center": list(center)}
    if angle:
        values["angle"] = angle
    if density is not None:
        values["density"] = number(density, "density", positive=True)
    return values


@dataclass(frozen=True, init=False)
class Box:
    """A ``width`` x ``height`` rectangle centred at ``center`` (body frame), turned by
    ``angle``; ``density`` (kg/m^2) overrides the body's for this part of a compound body."""

    width: float
    height: float
    center: Vec2
    angle: float
    density: Optional[float]

    def __init__(self, width: float, height: float, center: VectorLike = (0.0, 0.0),
                 angle: float = 0.0, density: Optional[float] = None) -> None:
        object.__setattr__(self, "width", number(width, "width", positive=True))
        object.__setattr__(self, "height", number(height, "height", positive=True))
        object.__setattr__(self, "center", vector(center, "center"))
        object.__setattr__(self, "angle", number(angle, "angle"))
        object.__setattr__(self, "density", density)

    def parameters(self) -> dict[str, Any]:
        """The scene parameters of this shape as a part of a body."""
        return {**_part("box", self.center, self.angle, self.density),
                "size": [self.width, self.height]}


@dataclass(frozen=True, init=False)
class Circle:
    """A disc of ``radius`` centred at ``center`` (body frame)."""

    radius: float
    center: Vec2
    density: Optional[float]

    def __init__(self, radius: float, center: VectorLike = (0.0, 0.0),
                 density: Optional[float] = None) -> None:
        object.__setattr__(self, "radius", number(radius, "radius", positive=True))
        object.__setattr__(self, "center", vector(center, "center"))
        object.__setattr__(self, "density", density)

    @property
    def angle(self) -> float:
        return 0.0

    def parameters(self) -> dict[str, Any]:
        return {**_part("circle", self.center, 0.0, self.density), "radius": self.radius}


@dataclass(frozen=True, init=False)
class Polygon:
    """A simple polygon, ``vertices`` in order (either winding) about ``center``, turned by
    ``angle``; the body frame's origin need not be its centroid."""

    vertices: tuple[Vec2, ...]
    center: Vec2
    angle: float
    density: Optional[float]

    def __init__(self, vertices: Sequence[VectorLike], center: VectorLike = (0.0, 0.0),
                 angle: float = 0.0, density: Optional[float] = None) -> None:
        points = tuple(vector(v, f"vertices[{i}]") for i, v in enumerate(vertices))
        if len(points) < 3:
            raise ValueError(f"vertices: a polygon needs at least 3, not {len(points)}")
        object.__setattr__(self, "vertices", points)
        object.__setattr__(self, "center", vector(center, "center"))
        object.__setattr__(self, "angle", number(angle, "angle"))
        object.__setattr__(self, "density", density)

    def parameters(self) -> dict[str, Any]:
        return {**_part("polygon", self.center, self.angle, self.density),
                "vertices": [x for vertex in self.vertices for x in vertex]}


ShapeLike = Union[Box, Circle, Polygon]


def shape_parameters(shape: Union[ShapeLike, Sequence[ShapeLike]]) -> dict[str, Any]:
    """A body's shape parameters: one shape in place, or ``parts`` for a compound body (a
    list of shapes, or one shape placed off the body frame's origin or turned in it)."""
    if isinstance(shape, (Box, Circle, Polygon)):
        shapes: list[Any] = [shape]
    elif isinstance(shape, (list, tuple)):
        shapes = list(shape)
    else:
        raise TypeError("shape: expected hd.Box, hd.Circle, hd.Polygon or a list of them, "
                        f"not {type(shape).__name__}")
    for i, part in enumerate(shapes):
        if not isinstance(part, (Box, Circle, Polygon)):
            raise TypeError(f"shape[{i}]: expected hd.Box, hd.Circle or hd.Polygon, "
                            f"not {type(part).__name__}")
    if not shapes:
        raise ValueError("shape: a compound body needs at least one part")
    single = shapes[0]
    if len(shapes) == 1 and single.center == (0.0, 0.0) and not single.angle and \
            single.density is None:
        values = single.parameters()
        del values["center"]
        return values
    # Zero-padded names: the reader takes parts in order of names, the order given here.
    return {"parts": {f"part{i:05d}": part.parameters() for i, part in enumerate(shapes)}}
