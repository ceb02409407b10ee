"""The public Python API: a :class:`World` of named :class:`Body` objects made of
:class:`Box`, :class:`Circle` and :class:`Polygon` shapes, pushed by forces at points
and stepped in seconds. ``docs/api.md`` describes it with examples."""
from .body import Body
from .shapes import Box, Circle, Polygon
from .world import World

__all__ = ["Body", "Box", "Circle", "Polygon", "World"]
