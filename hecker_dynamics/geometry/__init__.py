"""Vector algebra in the plane and shapes with their mass properties (the article's step 1).

``planar`` has the perp operator and the perp-dot product; ``shapes`` integrates polygons,
circles, boxes and their unions over the area for the center of mass (Eq. 3) and the moment
of inertia (Eq. 13).
"""
from .planar import perp, perp_dot, rotate, wrap_angle
from .shapes import (
                     Circle,
                     GeometryError,
                     MassProperties,
                     Polygon,
                     area_properties,
                     box,
                     mass_properties,
)

__all__ = ["perp", "perp_dot", "rotate", "wrap_angle", "Circle", "GeometryError",
           "MassProperties", "Polygon", "area_properties", "box", "mass_properties"]
