"""A body of a :class:`~.world.World`, by name: its mass properties, pose and velocities,
and the forces applied to it."""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Optional, Union

from ..geometry.shapes import MassProperties, Shape
from .vectors import Vec2, VectorLike, vector

if TYPE_CHECKING:
    from .world import World

__all__ = ["Body"]

PointLike = Union[VectorLike, str]


class Body:
    """A rigid body of a :class:`~.world.World`, got from ``world.add_body`` or
    ``world["name"]``.

    The pose is that of the body frame (the frame its shape is given in) in the world
    frame; ``velocity`` is the velocity of the body frame's origin in world axes (a body
    point's velocity, Eq. 9: it differs from the CM's when the CM is off the origin and
    the body turns).
    Setting ``position``, ``angle``, ``velocity`` or ``angular_velocity`` moves the body now.
    """

    __slots__ = ("_world", "name")

    def __init__(self, world: World, name: str) -> None:
        self._world = world
        self.name = name

    def __repr__(self) -> str:
        if not self._world._holds(self):
            return f"Body({self.name!r}, removed from its world)"
        return (f"Body({self.name!r}, position={self.position}, angle={self.angle!r}, "
                f"velocity={self.velocity}, angular_velocity={self.angular_velocity!r})")

    # ----------------------------------------------------------------- mass properties

    @property
    def _key(self) -> str:
        """The body's name, once its world is seen to hold this body still: a removed
        body's name given to a new body is that body's, and a handle of the old one must
        not read or push the new one."""
        return self._world._live(self)

    @property
    def _properties(self) -> MassProperties:
        return self._world._spec(self._key).mass

    @property
    def mass(self) -> float:
        """Total mass (kg), from the shape's area and density."""
        return self._properties.mass

    @property
    def moment_of_inertia(self) -> float:
        """Moment of inertia about the CM (kg m^2), integrated over the shape (Eq. 13)."""
        return self._properties.moment_of_inertia

    @property
    def center_of_mass(self) -> Vec2:
        """The center of mass in the body frame (m), Eq. 3."""
        return self._properties.center_of_mass

    @property
    def shapes(self) -> tuple[Shape, ...]:
        """The shapes in the body frame, as the integration of the mass properties saw them."""
        return self._world._spec(self._key).shapes

    @property
    def points(self) -> Mapping[str, Vec2]:
        """The body's named points (body frame)."""
        return self._world._spec(self._key).points

    # ----------------------------------------------------------------- state

    @property
    def position(self) -> Vec2:
        """Origin of the body frame in the world frame (m)."""
        return self._world._body_state(self._key).position

    @position.setter
    def position(self, value: VectorLike) -> None:
        self._world._move(self._key, position=vector(value, "position"))

    @property
    def angle(self) -> float:
        """Orientation (rad, counter-clockwise), wrapped into [-pi, pi)."""
        return self._world._body_state(self._key).angle

    @angle.setter
    def angle(self, value: float) -> None:
        self._world._move(self._key, angle=value)

    @property
    def velocity(self) -> Vec2:
        """Velocity of the body frame's origin, world axes (m/s)."""
        return self._world._body_state(self._key).linear_velocity

    @velocity.setter
    def velocity(self, value: VectorLike) -> None:
        self._world._move(self._key, velocity=vector(value, "velocity"))

    @property
    def angular_velocity(self) -> float:
        """omega (rad/s, counter-clockwise)."""
        return self._world._body_state(self._key).angular_velocity

    @angular_velocity.setter
    def angular_velocity(self, value: float) -> None:
        self._world._move(self._key, angular_velocity=value)

    def world_point(self, point: PointLike) -> Vec2:
        """A body point (body frame, or a named point) in the world frame now."""
        x, y = self._local(point, "point")
        (ox, oy), c, s = self.position, math.cos(self.angle), math.sin(self.angle)
        return (ox + c * x - s * y, oy + s * x + c * y)

    def local_point(self, point: VectorLike) -> Vec2:
        """A world point in the body frame now."""
        x, y = vector(point, "point")
        (ox, oy), c, s = self.position, math.cos(self.angle), math.sin(self.angle)
        return (c * (x - ox) + s * (y - oy), -s * (x - ox) + c * (y - oy))

    def velocity_at(self, point: PointLike) -> Vec2:
        """Velocity of a body point (body frame, or a named point) in world axes:
        v_P = v_O + omega perp(r_OP) (Eq. 9), O the body frame's origin."""
        px, py = self.world_point(point)
        (ox, oy), (vx, vy), omega = self.position, self.velocity, self.angular_velocity
        return (vx - omega * (py - oy), vy + omega * (px - ox))

    def _local(self, point: PointLike, argument: str) -> Vec2:
        if isinstance(point, str):
            points = self.points
            if point not in points:
                raise ValueError(f"{argument}: body '{self.name}' has no point '{point}' "
                                 f"(points: {', '.join(points) or 'none'})")
            return points[point]
        return vector(point, argument)

    # ----------------------------------------------------------------- forces

    def apply_force(self, force: VectorLike, point: Optional[PointLike] = None, *,
                    frame: str = "world", duration: Optional[float] = None,
                    start: Optional[float] = None, torque: float = 0.0,
                    name: Optional[str] = None) -> None:
        """Push the body with ``force`` (N) at ``point`` (m), plus a pure ``torque`` (N m).

        ``frame="world"``: force and point in world coordinates, the point fixed in space;
        ``frame="body"``: both in the body frame, turning and moving with the body (a
        thruster); a named point of the body is a body point. ``point=None``: the CM where
        it is at the push. The force acts at the CM as F = M a (Eq. 5); its torque about
        the CM, tau = perp(r) . F (Eq. 11), gives the angular acceleration tau / I (Eq. 14).

        It acts from the first step that starts at or after ``start`` (s, default now) for
        ``duration`` seconds, or (``None``) until :meth:`clear_forces` or a force of the
        same ``name`` on this body replaces it. Forces without a name add up.
        """
        self._world._apply(self, force, point, frame, duration, start, torque, name)

    def apply_torque(self, torque: float, *, duration: Optional[float] = None,
                     start: Optional[float] = None, name: Optional[str] = None) -> None:
        """A pure torque (N m) about the CM: angular acceleration tau / I (Eq. 14); held,
        timed and scheduled as :meth:`apply_force`."""
        self._world._apply(self, (0.0, 0.0), None, "world", duration, start, torque, name)

    def clear_forces(self) -> None:
        """Stop every force and torque applied to this body, held, timed or scheduled."""
        self._world._clear(self._key)
