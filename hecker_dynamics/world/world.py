"""The World: bodies, walls, springs and joints built in Python, stepped in seconds.

A World writes what it is given as the parameters a scene file holds and reads them with
the scene loader (:func:`~hecker_dynamics.scene.load.scene_from_parameters`), so a World
built in Python and the same scene in a YAML file are the same :class:`Scene` and step
bit for bit alike; :meth:`World.from_scene` wraps what :func:`load_scene` returns. Under
it is the project's :class:`Simulation`: the article's loop (steps 3 to 8) with fixed steps
kept in integer nanoseconds, and the compiled kernel where it is built.

Each step sums the forces at the CM, F = M a (Eq. 5), their torques about the CM,
tau = perp(r) . F (Eq. 11), and turns those into the angular acceleration tau / I
(Eq. 14), with the mass, the center of mass and the moment of inertia integrated over each
body's shape (Eq. 3 and Eq. 13).
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import numbers
import os
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any, Optional, ParamSpec, TypeVar, Union

# The input buffer's own form of a command as plain data, so a World's state and a
# Simulation's hold scheduled and held commands alike.
from ..dynamics.inputs import _command_data, _command_from_data
from ..dynamics.simulation import BodyState, Simulation
from ..scene.commands import InputError, WrenchCommand, shorter_than_a_step
from ..scene.fingerprint import scene_fingerprint
from ..scene.load import (
    INTEGRATORS,
    MAX_SECONDS,
    BodySpec,
    Scene,
    check_force,
    load_scene,
    read_body,
    read_collisions,
    read_force,
    read_gear,
    read_joint,
    read_wall,
    scene_from_parameters,
)
from ..scene.parameters import (
    ParameterReader,
    bad_name,
    flatten,
    number_text,
    seconds_text,
    stamp_time,
)
from ..scene.world import EditKind, WorldEdit, apply_edits, deleted, spawned
from .body import Body, PointLike
from .shapes import ShapeLike, shape_parameters
from .vectors import VectorLike, flag, number, scalar, vector

__all__ = ["World"]

#: The name errors from the scene reader give as the source of a World built in Python.
SOURCE = "World"
#: How often the energy bound checks the state (:mod:`hecker_dynamics.dynamics.divergence`):
#: every whole number of steps nearest this (ns), as a scene's publish rate sets it.
CHECK_PERIOD_NS = 20_000_000
BodyLike = Union[Body, str]
P = ParamSpec("P")
R = TypeVar("R")


def _locked(method: Callable[P, R]) -> Callable[P, R]:
    """A method of :class:`World` that holds the world's lock while it runs, so that calls
    from several threads take turns, each whole (a force applied from one thread while
    another steps acts from the step instant it is taken at, all of it)."""
    @functools.wraps(method)
    def call(*args: P.args, **kwargs: P.kwargs) -> R:
        with args[0]._lock:  # type: ignore[attr-defined]
            return method(*args, **kwargs)
    return call


def _adding(method: Callable[P, R]) -> Callable[P, R]:
    """An ``add_*`` method of :class:`World` that leaves nothing behind when it refuses."""
    @functools.wraps(method)
    def add(*args: P.args, **kwargs: P.kwargs) -> R:
        world = args[0]
        assert isinstance(world, World)
        with world._lock:
            try:
                result = method(*args, **kwargs)
                world._read_added()
                return result
            except BaseException:
                if world._added is not None and world._params is not None:
                    section, key = world._added
                    del world._params[section][key]
                raise
            finally:
                world._added = None
    return add


def _name(value: object, argument: str) -> str:
    problem = bad_name(value)
    if problem is not None:
        raise ValueError(f"{argument}: {problem}")
    return str(value)


def _nanoseconds(value: object, argument: str) -> int:
    value = scalar(value)
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{argument}: expected a whole number of nanoseconds, "
                        f"not {type(value).__name__}")
    return int(value)


def _text(value: object, argument: str) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{argument}: expected text, not {type(value).__name__}")
    return value


def _checked_command(command: object) -> WrenchCommand:
    """``command``, a :class:`WrenchCommand` built by hand, with its fields checked and
    made plain (a float stamp or duration would make the clock's nanoseconds floats, a
    string force failed deep in the input buffer)."""
    if not isinstance(command, WrenchCommand):
        raise TypeError(f"command: expected a WrenchCommand, not {type(command).__name__}")
    try:
        return WrenchCommand(
            _nanoseconds(command.stamp_ns, "command.stamp_ns"),
            _text(command.body, "command.body"), _text(command.source, "command.source"),
            _text(command.frame_id, "command.frame_id"),
            vector(command.point, "command.point"), vector(command.force, "command.force"),
            number(command.torque, "command.torque"),
            _nanoseconds(command.duration_ns, "command.duration_ns"))
    except ValueError as error:  # a value refused (NaN, three numbers): the push's error
        raise InputError(str(error)) from None


def _optional(values: dict[str, Any], key: str, value: Optional[float], *,
              minimum: Optional[float] = None) -> None:
    if value is not None:
        values[key] = number(value, key, minimum=minimum)


class World:
    """A 2D world of rigid bodies (SI units, seconds, radians counter-clockwise).

    ``gravity`` (m/s^2) acts at every body's CM, so it makes no torque; ``step`` (s) is
    the fixed step, kept in whole nanoseconds as the node's clock keeps it; ``integrator``
    is one of :data:`~hecker_dynamics.scene.load.INTEGRATORS` (``auto`` picks from the
    stiffness); ``sleep`` lets resting islands of the contact pass sleep, ``events``
    locates wall impacts inside the step; ``frame`` names the fixed frame.

    The world's structure (walls, forces, joints) is fixed once it has stepped, had a
    force applied or a body moved, and in a world read from a scene file; bodies can still
    be added and removed then, by the rules and with the carry-over of the node's
    ``spawn_body`` and ``delete_body`` services (:mod:`hecker_dynamics.scene.world`).
    :meth:`state` and :meth:`set_state` carry the rest, bit for bit.
    """

    def __init__(self, *, gravity: Optional[VectorLike] = None, step: float = 0.001,
                 integrator: str = "auto", tolerance: float = 1e-6, frame: str = "world",
                 restitution_threshold: Optional[float] = None, sleep: bool = False,
                 events: bool = False) -> None:
        step_ns = round(number(step, "step", positive=True, maximum=MAX_SECONDS) * 1e9)
        if step_ns < 1:
            raise ValueError(f"step: must be at least one nanosecond, not {step}")
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator: must be one of {', '.join(INTEGRATORS)}; "
                             f"not {integrator!r}")
        per_check = max(1, round(CHECK_PERIOD_NS / step_ns))
        params: dict[str, Any] = {
            "frame_id": _name(frame, "frame"), "step": step_ns / 1e9,  # 1e9 s: not 1e9 + 1 ulp
            "integrator": integrator, "tolerance": number(tolerance, "tolerance", positive=True),
            "publish_rate": 1e9 / (per_check * step_ns),
            "input_timeout": 0.0,  # a held force holds until cleared
            "contacts": {"sleep": flag(sleep, "sleep"), "events": flag(events, "events")},
        }
        _optional(params, "restitution_threshold", restitution_threshold, minimum=0.0)
        if gravity is not None:
            params["forces"] = {"gravity": {"type": "gravity",
                                            "acceleration": list(vector(gravity, "gravity"))}}
        self._setup(params, None)

    def _setup(self, params: Optional[dict[str, Any]], scene: Optional[Scene]) -> None:
        self._lock = threading.RLock()
        self._params = params  # None: a world read from a scene file, whose shape is fixed
        self._scene = scene
        self._sim: Optional[Simulation] = None
        self._start_ns = 0
        self._frames: Optional[tuple[BodyState, ...]] = None
        self._frames_of: tuple[Any, Any] = (None, None)  # the state (q, v) they were read from
        self._started = False
        self._bodies: dict[str, Body] = {}
        self._schedule: list[tuple[int, int, WrenchCommand]] = []  # (stamp, order, command)
        self._script: tuple[WrenchCommand, ...] = ()  # played: stamps from the start
        self._applied: dict[str, dict[str, Optional[int]]] = {}  # body: source: end (ns)
        self._count = 0
        self._added: Optional[tuple[str, str]] = None  # the entry an add_* call is making
        self._specs: dict[str, BodySpec] = {}  # each body added, as the loader read it
        if scene is not None:
            self._bodies = {b.name: Body(self, b.name) for b in scene.bodies}

    @classmethod
    def from_scene(cls, scene: Union[str, os.PathLike[str], Scene, None] = None, *,
                   script: bool = True, start_ns: int = 0) -> World:
        """The world of a scene file (a path or a shipped scene's name, default ``sample``)
        or of a :class:`Scene`; ``script``: its scripted inputs act at their times, as
        ``hecker-dynamics run`` plays them. A held force stops after the scene's
        ``input_timeout``, as the node's commands do. ``start_ns``: the sim time it starts
        at, in whole nanoseconds (a ROS time, as the node starts at, needs more digits than
        a float's seconds hold)."""
        if not isinstance(scene, (str, os.PathLike, Scene, type(None))):
            raise TypeError("scene: expected a scene file's path, a shipped scene's name or an "
                            f"hd.Scene, not {type(scene).__name__}")
        start_ns = stamp_time(_nanoseconds(start_ns, "start_ns"), "start_ns")
        play = flag(script, "script")
        world = cls.__new__(cls)
        loaded = scene if isinstance(scene, Scene) else load_scene(scene)
        world._setup(None, loaded)
        world._start_ns = start_ns
        if play:
            world._script = loaded.script
            world._schedule = world._scripted(start_ns)
        return world

    def _scripted(self, start_ns: int) -> list[tuple[int, int, WrenchCommand]]:
        """The script's commands scheduled from ``start_ns``: their stamps count from the
        start, as :meth:`Simulation.play`'s do."""
        return [(start_ns + c.stamp_ns, i, dataclasses.replace(c, stamp_ns=start_ns + c.stamp_ns))
                for i, c in enumerate(self._script)]

    @_locked
    def __getstate__(self) -> dict[str, Any]:
        """The world for :func:`copy.deepcopy` and :mod:`pickle`, but for its lock (a copy
        gets one of its own)."""
        state = dict(self.__dict__)
        del state["_lock"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.RLock()

    def __copy__(self) -> World:
        """A branch, as :func:`copy.deepcopy` makes it: a shallow copy would share the
        simulation and its bodies, so stepping one world would step the other."""
        return copy.deepcopy(self)

    # ----------------------------------------------------------------- building

    def _edit(self, what: str) -> dict[str, Any]:
        """The parameters to change, after checking that the world may still change."""
        if self._params is None:
            raise ValueError(f"cannot {what}: a world read from a scene file, or one that "
                             "has spawned or removed a body, keeps its scene but for its "
                             "bodies; add it to the file, or build the world in Python")
        if self._started:
            raise ValueError(f"cannot {what} after the world has started (stepped, pushed "
                             "or moved): only bodies can be added and removed then; build "
                             "the rest of the world first")
        self._scene, self._sim, self._frames = None, None, None
        return self._params

    def _section(self, section: str, name: object, what: str) -> dict[str, Any]:
        key = _name(name, "name")
        entries = self._edit(f"add {what} '{key}'").setdefault(section, {})
        if key in entries:
            raise ValueError(f"name: the world already has a {what} called '{key}'")
        values: dict[str, Any] = {}
        entries[key] = values
        self._added = (section, key)
        return values

    def _read_added(self) -> None:
        """Read the wall, force, collision group or joint just added as the loader reads a
        file's, so that what it breaks fails now, not at the first step (a body is read by
        :meth:`add_body` itself)."""
        if self._added is None or self._added[0] == "bodies" or self._params is None:
            return
        section, key = self._added
        params, specs = self._params, self._specs
        values = params[section][key]
        reader = ParameterReader(values, SOURCE, f"{section}.{key}")
        points = {name: spec.points for name, spec in specs.items()}
        if section == "walls":
            read_wall(key, reader, set(specs))
        elif section == "forces":
            check_force(read_force(key, reader, points), reader, specs,
                        round(params["step"] * 1e9), params["integrator"])
        elif section == "collisions":
            read_collisions(ParameterReader({"collisions": params[section]}, SOURCE), specs)
        elif values["type"] == "gear":
            read_gear(key, reader, [name for name, joint in params[section].items()
                                    if joint["type"] == "revolute"])
        else:
            read_joint(key, values["type"], reader, specs, points, params["frame_id"])

    def _holds(self, body: Body) -> bool:
        """Whether ``body`` is a body of this world now (not one removed since)."""
        return self._bodies.get(body.name) is body

    def _live(self, body: Body, argument: str = "") -> str:
        """The name of ``body``, a Body of this world; ValueError if it was removed (a
        body given the name since is another: its handle must not stand for it)."""
        if not self._holds(body):
            raise ValueError(f"{argument}{': ' if argument else ''}body '{body.name}' was "
                             "removed from the world" + (
                                 f"; the body called so now is another: world['{body.name}']"
                                 if body.name in self._bodies else ""))
        return body.name

    def _body_name(self, body: BodyLike, argument: str) -> str:
        if isinstance(body, Body) and body._world is not self:  # a copy's has the same name
            raise ValueError(f"{argument}: body '{body.name}' is a Body of another World "
                             f"(this world's: world['{body.name}'])")
        if isinstance(body, Body) and body.name in self._bodies:
            return self._live(body, argument)
        name = body.name if isinstance(body, Body) else body
        if not isinstance(name, str):
            raise TypeError(f"{argument}: expected a Body or a body's name, "
                            f"not {type(body).__name__}")
        if name not in self._bodies:
            raise ValueError(f"{argument}: no body called {name!r} (bodies: "
                             f"{', '.join(self._bodies) or 'none'})")
        return name

    def _body_names(self, bodies: Optional[Sequence[BodyLike]], argument: str) -> list[str]:
        if bodies is None:
            return list(self._bodies)
        return [self._body_name(body, f"{argument}[{i}]") for i, body in enumerate(bodies)]

    @staticmethod
    def _point(point: PointLike, argument: str) -> Union[list[float], str]:
        return point if isinstance(point, str) else list(vector(point, argument))

    @_adding
    def add_body(self, name: str, shape: Union[ShapeLike, Sequence[ShapeLike]], *,
                 mass: Optional[float] = None, density: Optional[float] = None,
                 position: VectorLike = (0.0, 0.0), angle: float = 0.0,
                 velocity: VectorLike = (0.0, 0.0), angular_velocity: float = 0.0,
                 points: Optional[Mapping[str, VectorLike]] = None,
                 collisions: Sequence[str] = ()) -> Body:
        """Add a rigid body of ``shape`` (one shape or a list: a compound body) with its
        ``mass`` (kg) or ``density`` (kg/m^2); the center of mass and the moment of
        inertia follow from the shape (Eq. 3 and Eq. 13). ``position`` and ``angle`` place
        the body frame; ``velocity`` is that of its origin; ``points`` names body points
        (body frame).

        The body joins the collision groups named in ``collisions``, besides those added
        after it that hold it. Once the world has started, or in a world read from a scene
        file, it is spawned as the node's ``spawn_body`` spawns it: it joins the groups
        named (and no other), gravity and walls that hold every body, and the other bodies
        keep their state bit for bit."""
        if (mass is None) == (density is None):
            raise ValueError("mass: give the body's mass or its density, one of the two")
        params = None if self._started else self._params  # None: the body is spawned
        if params is None:
            values: dict[str, Any] = {}
        else:
            if name == params.get("frame_id"):
                raise ValueError(f"name: '{name}' is the fixed frame's name")
            values = self._section("bodies", name, "body")
        values.update(shape_parameters(shape))
        for key, argument in (("mass", mass), ("density", density)):
            if argument is not None:
                values[key] = number(argument, key, positive=True)
        values.update(position=list(vector(position, "position")),
                      angle=number(angle, "angle"),
                      velocity=list(vector(velocity, "velocity")),
                      angular_velocity=number(angular_velocity, "angular_velocity"))
        if points:
            values["points"] = {_name(key, "points"): list(vector(p, f"points[{key!r}]"))
                                for key, p in points.items()}
        if params is None:
            self._change_bodies(spawned, name, values, tuple(collisions), SOURCE)
        else:  # read now, as the loader reads a file's body: a bad shape fails here
            self._specs[name] = read_body(name, ParameterReader(values, SOURCE, f"bodies.{name}"))
            self._join(name, collisions)
        body = Body(self, name)
        self._bodies[name] = body
        return body

    def _join(self, name: str, collisions: Sequence[str]) -> None:
        """Body ``name`` into the collision groups named (those added already)."""
        assert self._params is not None
        groups = self._params.get("collisions", {})
        for group in collisions:
            if group not in groups:
                raise ValueError(f"collisions: no collision group {group!r} (groups: "
                                 f"{', '.join(groups) or 'none'})")
        for group in collisions:
            members = groups[group].get("bodies")
            if members is not None and name not in members:  # None: every body already
                members.append(name)

    @_adding
    def add_wall(self, name: str, *, point: VectorLike, normal: VectorLike,
                 restitution: float = 0.5, friction: float = 0.0,
                 bodies: Optional[Sequence[BodyLike]] = None) -> None:
        """A fixed half-plane ``normal . (x - point) >= 0`` that ``bodies`` (default all,
        those added later too) stay inside, answering with impulses."""
        values = self._section("walls", name, "wall")
        values.update(point=list(vector(point, "point")), normal=list(vector(normal, "normal")),
                      restitution=number(restitution, "restitution", minimum=0.0),
                      friction=number(friction, "friction", minimum=0.0))
        if bodies is not None:
            values["bodies"] = self._body_names(bodies, "bodies")

    @_adding
    def add_collision_group(self, name: str, bodies: Optional[Sequence[BodyLike]] = None, *,
                            restitution: float = 0.2, friction: float = 0.5) -> None:
        """Contacts on between every pair of ``bodies`` (default all); bodies in no common
        group pass through each other. Colliding polygons must be convex."""
        values = self._section("collisions", name, "collision group")
        values.update(restitution=number(restitution, "restitution", minimum=0.0),
                      friction=number(friction, "friction", minimum=0.0))
        if bodies is not None:
            values["bodies"] = self._body_names(bodies, "bodies")

    @_adding
    def add_spring(self, name: str, body_a: BodyLike, point_a: PointLike = (0.0, 0.0),
                   body_b: Optional[BodyLike] = None, point_b: PointLike = (0.0, 0.0), *,
                   anchor: Optional[VectorLike] = None, stiffness: float,
                   rest_length: float = 0.0, damping: float = 0.0) -> None:
        """A damped spring from ``point_a`` of ``body_a`` to ``point_b`` of ``body_b`` or to
        a fixed ``anchor`` (world frame); points in body frames or named. Its force acts at
        both points, so it has a torque about each CM (Eq. 11); damping acts on the relative
        velocity of the points, each a body point's velocity (Eq. 9)."""
        values = self._section("forces", name, "force")
        values.update(type="spring", body_a=self._body_name(body_a, "body_a"),
                      point_a=self._point(point_a, "point_a"),
                      stiffness=number(stiffness, "stiffness", minimum=0.0),
                      rest_length=number(rest_length, "rest_length", minimum=0.0),
                      damping=number(damping, "damping", minimum=0.0))
        if (anchor is None) == (body_b is None):
            raise ValueError("anchor: a spring needs exactly one of body_b or anchor")
        if anchor is not None:
            values["anchor"] = list(vector(anchor, "anchor"))
        else:
            assert body_b is not None
            values.update(body_b=self._body_name(body_b, "body_b"),
                          point_b=self._point(point_b, "point_b"))

    @_adding
    def add_drag(self, name: str, coefficient: float, bodies: Optional[Sequence[BodyLike]] = None,
                 *, quadratic: bool = False, point: Optional[PointLike] = None) -> None:
        """Drag -c v_P (``quadratic``: -c |v_P| v_P) at the CM of each of ``bodies`` (default
        all), or at a ``point`` of a single body: drag of that body point's velocity
        (Eq. 9), with a torque (Eq. 11)."""
        values = self._section("forces", name, "force")
        values.update(type="quadratic_drag" if flag(quadratic, "quadratic") else "linear_drag",
                      coefficient=number(coefficient, "coefficient", minimum=0.0))
        if bodies is not None:
            values["bodies"] = self._body_names(bodies, "bodies")
        if point is not None:
            values["point"] = self._point(point, "point")

    @_adding
    def add_angular_damping(self, name: str, coefficient: float,
                            bodies: Optional[Sequence[BodyLike]] = None) -> None:
        """A torque -c omega on each of ``bodies`` (default all)."""
        values = self._section("forces", name, "force")
        values.update(type="angular_damping",
                      coefficient=number(coefficient, "coefficient", minimum=0.0))
        if bodies is not None:
            values["bodies"] = self._body_names(bodies, "bodies")

    # ----------------------------------------------------------------- joints

    def _joint(self, name: str, kind: str, body_a: Optional[BodyLike], body_b: BodyLike,
               point_a: Optional[PointLike], point_b: PointLike,
               collide_connected: bool) -> dict[str, Any]:
        values = self._section("joints", name, "joint")
        values.update(type=kind, body_b=self._body_name(body_b, "body_b"),
                      point_b=self._point(point_b, "point_b"),
                      collide_connected=flag(collide_connected, "collide_connected"))
        if body_a is not None:
            values["body_a"] = self._body_name(body_a, "body_a")
        if point_a is not None:
            values["point_a"] = self._point(point_a, "point_a")
        return values

    @_adding
    def add_revolute_joint(self, name: str, body_a: Optional[BodyLike], body_b: BodyLike, *,
                           point_a: Optional[PointLike] = None,
                           point_b: PointLike = (0.0, 0.0), lower: Optional[float] = None,
                           upper: Optional[float] = None, motor_speed: float = 0.0,
                           max_torque: Optional[float] = None,
                           spring_stiffness: Optional[float] = None,
                           spring_damping: float = 0.0, rest_angle: float = 0.0,
                           collide_connected: bool = False) -> None:
        """A pin: ``point_b`` of ``body_b`` (body frame) held on ``point_a`` of ``body_a``
        (``None``: the fixed frame, ``point_a`` in world coordinates), by default where
        ``point_b`` starts. Optional angle limits (rad, relative to the start), a motor
        (``max_torque`` given) and a rotary spring (``spring_stiffness`` given)."""
        values = self._joint(name, "revolute", body_a, body_b, point_a, point_b,
                             collide_connected)
        _optional(values, "lower", lower)
        _optional(values, "upper", upper)
        if max_torque is not None:
            values["motor"] = {"speed": number(motor_speed, "motor_speed"),
                               "max_torque": number(max_torque, "max_torque", minimum=0.0)}
        if spring_stiffness is not None:
            values["spring"] = {
                "stiffness": number(spring_stiffness, "spring_stiffness", minimum=0.0),
                "damping": number(spring_damping, "spring_damping", minimum=0.0),
                "rest_angle": number(rest_angle, "rest_angle")}

    @_adding
    def add_prismatic_joint(self, name: str, body_a: Optional[BodyLike], body_b: BodyLike, *,
                            axis: VectorLike, point_a: Optional[PointLike] = None,
                            point_b: PointLike = (0.0, 0.0), lower: Optional[float] = None,
                            upper: Optional[float] = None, motor_speed: float = 0.0,
                            max_force: Optional[float] = None,
                            collide_connected: bool = False) -> None:
        """A slider: ``point_b`` of ``body_b`` moves along ``axis`` (body_a's frame, or the
        world's) through ``point_a``, the bodies turning together; optional travel limits
        (m, from the start) and a motor (``max_force`` given)."""
        values = self._joint(name, "prismatic", body_a, body_b, point_a, point_b,
                             collide_connected)
        values["axis"] = list(vector(axis, "axis"))
        _optional(values, "lower", lower)
        _optional(values, "upper", upper)
        if max_force is not None:
            values["motor"] = {"speed": number(motor_speed, "motor_speed"),
                               "max_force": number(max_force, "max_force", minimum=0.0)}

    @_adding
    def add_distance_joint(self, name: str, body_a: Optional[BodyLike], body_b: BodyLike, *,
                           point_a: Optional[PointLike] = None,
                           point_b: PointLike = (0.0, 0.0), length: Optional[float] = None,
                           max_length: Optional[float] = None,
                           collide_connected: bool = False) -> None:
        """A rod (``length``, default the points' distance at the start) or a rope
        (``max_length``) between ``point_a`` (default body_a's origin) and ``point_b``."""
        values = self._joint(name, "distance", body_a, body_b, point_a, point_b,
                             collide_connected)
        _optional(values, "length", length)
        _optional(values, "max_length", max_length)

    @_adding
    def add_weld_joint(self, name: str, body_a: Optional[BodyLike], body_b: BodyLike, *,
                       point_a: Optional[PointLike] = None, point_b: PointLike = (0.0, 0.0),
                       frequency: float = 0.0, damping_ratio: float = 1.0,
                       collide_connected: bool = False) -> None:
        """The bodies held together at one point, not turning relative to each other
        (``frequency`` > 0: a soft weld of that natural frequency, Hz)."""
        values = self._joint(name, "weld", body_a, body_b, point_a, point_b, collide_connected)
        values.update(frequency=number(frequency, "frequency", minimum=0.0),
                      damping_ratio=number(damping_ratio, "damping_ratio", minimum=0.0))

    @_adding
    def add_gear_joint(self, name: str, joint_a: str, joint_b: str, ratio: float) -> None:
        """Two revolute joints of this world geared at ``ratio``."""
        values = self._section("joints", name, "joint")
        values.update(type="gear", joint_a=_name(joint_a, "joint_a"),
                      joint_b=_name(joint_b, "joint_b"), ratio=number(ratio, "ratio"))

    @_locked
    def remove_body(self, body: BodyLike) -> None:
        """Remove ``body`` (a Body or its name), as the node's ``delete_body`` removes it:
        refused while a spring, joint, sensor, drive or scripted force names it; what acted
        on it alone goes with it, and the others keep their state bit for bit."""
        name = self._body_name(body, "body")
        # A World has no call that removes a joint, spring, sensor or drive.
        self._change_bodies(deleted, name, SOURCE, "a world keeps those: remove them from "
                            "its scene file, or build the world without them")
        self._forget(name)

    @_locked
    def edit_bodies(self, *edits: WorldEdit) -> None:
        """Spawn and delete bodies as the node's ``spawn_body`` and ``delete_body`` services
        do, ``edits`` made in order (each a :class:`~hecker_dynamics.scene.world.WorldEdit`:
        a spawned body's YAML and collision groups, or a deleted body's name), going on
        from the state now in one :meth:`Simulation.with_world`. Refused (nothing changes)
        with the one-line :class:`SceneError` of the first edit the rules refuse."""
        before = set(self._bodies)
        # A body deleted and spawned again in these edits is a new body under the old name:
        # nothing of the old one's carries to it, in the simulation or here.
        removed = {edit.body for edit in edits if edit.kind is EditKind.DELETE} & before
        self._change_bodies(apply_edits, edits, renewed=removed)
        names = {spec.name for spec in self.scene.bodies}
        for name in (before - names) | removed:
            self._forget(name)
        for name in names - set(self._bodies):
            self._bodies[name] = Body(self, name)

    def _forget(self, name: str) -> None:
        """Drop what the world keeps for body ``name``, deleted from its scene."""
        del self._bodies[name]
        self._applied.pop(name, None)
        # As the simulation drops its held commands: those on the body or in its axes.
        self._schedule = [entry for entry in self._schedule if name not in (
            entry[2].body, entry[2].frame_id.partition("/")[0])]

    def _change_bodies(self, change: Callable[..., Scene], *args: Any,
                       renewed: Iterable[str] = ()) -> None:
        """The world after ``change(scene, *args)`` (:func:`spawned`, :func:`deleted` or
        :func:`apply_edits`), going on from its state now (:meth:`Simulation.with_world`;
        ``renewed``: bodies it deleted, so that one spawned under their names is new)."""
        scene = change(self.scene, *args)  # SceneError, one line, if it is refused
        self._sim = self.simulation.with_world(scene, renewed)
        self._scene, self._params, self._frames = scene, None, None

    # ----------------------------------------------------------------- the scene

    @property
    def scene(self) -> Scene:
        """The :class:`Scene` this world is: the loader's reading of its parameters."""
        scene = self._scene
        if scene is None:  # read under the lock, once: the methods use it unlocked
            with self._lock:
                if self._scene is None:
                    assert self._params is not None
                    self._scene = scene_from_parameters(flatten(self._params), SOURCE)
                scene = self._scene
        return scene

    @property
    def simulation(self) -> Simulation:
        """The :class:`Simulation` under this world (for the node's and bags' tools)."""
        sim = self._sim
        if sim is None:  # made under the lock, once: the methods use it unlocked
            with self._lock:
                if self._sim is None:
                    self._sim = Simulation(self.scene, start_ns=self._start_ns)
                sim = self._sim
        return sim

    def _index(self, name: str) -> int:
        index = self.simulation.model.index
        if name not in index:
            raise ValueError(f"body '{name}' was removed from the world")
        return index[name]

    def _spec(self, name: str) -> BodySpec:
        return self.scene.bodies[self._index(name)]

    @_locked
    def _body_state(self, name: str) -> BodyState:
        sim = self.simulation
        # Read again once the state moved on, also where a node stepped the simulation
        # itself (ros/runner.py): each step, move or restore replaces the arrays q and v.
        if self._frames is None or self._frames_of[0] is not sim.q or \
                self._frames_of[1] is not sim.v:
            self._frames, self._frames_of = sim.snapshot().bodies, (sim.q, sim.v)
        return self._frames[self._index(name)]

    @_locked
    def __getitem__(self, name: str) -> Body:
        """The body called ``name``."""
        return self._bodies[self._body_name(name, "name")]

    @_locked
    def __contains__(self, name: object) -> bool:
        return name in self._bodies

    @_locked
    def __iter__(self) -> Iterator[Body]:
        return iter(self.bodies)

    @_locked
    def __len__(self) -> int:
        return len(self._bodies)

    @property
    @_locked
    def bodies(self) -> tuple[Body, ...]:
        """The bodies in the scene's order: by name, as the loader reads them."""
        return tuple(self._bodies[name] for name in sorted(self._bodies))

    @property
    @_locked
    def time(self) -> float:
        """Sim time (s)."""
        return self.simulation.time_ns / 1e9

    @property
    @_locked
    def time_step(self) -> float:
        """The fixed step (s), a whole number of nanoseconds."""
        return self.simulation.step_ns / 1e9

    @property
    @_locked
    def energy(self) -> float:
        """Kinetic energy plus the potential energy of gravity and springs (J)."""
        return self.simulation.snapshot().energy

    @_locked
    def joint_state(self, name: str) -> tuple[float, float, float]:
        """(position, velocity, effort) of a revolute or prismatic joint (rad or m,
        per second, N m or N)."""
        joints = self.simulation.snapshot().joints
        if name not in joints:
            raise ValueError(f"name: no revolute or prismatic joint called {name!r} "
                             f"(joints: {', '.join(joints) or 'none'})")
        return joints[name]

    # ----------------------------------------------------------------- stepping

    @_locked
    def step(self, dt: Optional[float] = None) -> None:
        """Advance by ``dt`` seconds, a whole number of steps (default one step)."""
        steps = 1
        if dt is not None:
            span = number(dt, "dt", positive=True, maximum=MAX_SECONDS) * 1e9
            step_ns = self.simulation.step_ns
            steps = round(span / step_ns)
            # Each step was rounded to whole nanoseconds, by half a nanosecond at most.
            if steps < 1 or abs(span - steps * step_ns) > 0.5 * steps + 0.5:
                raise ValueError(f"dt: {number_text(dt)} s is not a whole number of steps "
                                 f"of {seconds_text(step_ns)} s")
        self._run_to(self.simulation.time_ns + steps * self.simulation.step_ns)

    @_locked
    def advance(self, t: float) -> None:
        """Step to the step instant nearest ``t`` (s), which must not be behind the world."""
        sim = self.simulation
        steps = round((self._instant(t, "t") - sim.time_ns) / sim.step_ns)
        if steps < 0:
            raise self._behind(t, "t")
        self._run_to(sim.time_ns + steps * sim.step_ns)

    def _instant(self, seconds: float, argument: str) -> float:
        """The sim time ``seconds`` (s) in nanoseconds, as a float, at most ``MAX_SECONDS``
        ahead of the world's time, as a duration is (the world's time itself may be a ROS
        time, past 1e9 s); a time that far behind it is refused here, a nearer one by the
        caller, which rounds it to its instant first."""
        now = self.simulation.time_ns
        ns = number(seconds, argument) * 1e9
        # Compared as floats: -1e300 s is -inf ns, which round() cannot take.
        if ns - now > MAX_SECONDS * 1e9:
            raise ValueError(f"{argument}: must be at most {MAX_SECONDS} s past the world's "
                             f"time ({seconds_text(now)} s), not {number_text(float(seconds))}")
        if ns - now < -MAX_SECONDS * 1e9:
            raise self._behind(seconds, argument)
        return ns

    def _behind(self, seconds: float, argument: str) -> ValueError:
        return ValueError(f"{argument}: {number_text(float(seconds))} s is behind the "
                          f"world's time ({seconds_text(self.simulation.time_ns)} s)")

    @_locked
    def reset(self, start_ns: Optional[int] = None) -> None:
        """Back to the initial state of the world's scene (with the bodies spawned and
        removed so far), at sim time ``start_ns`` (whole nanoseconds; default the start it
        had): the forces applied are dropped, a scene's script is scheduled again, and the
        steps that follow are those of a new world of that scene (:meth:`Simulation.reset`)."""
        if start_ns is not None:
            self._start_ns = stamp_time(_nanoseconds(start_ns, "start_ns"), "start_ns")
        sim = self.simulation
        sim.reset(start_ns)
        self._schedule, self._applied, self._count = self._scripted(sim.start_ns), {}, 0
        self._frames = None

    def _run_to(self, end_ns: int) -> None:
        """Advance to ``end_ns``, pushing each scheduled force as sim time reaches its
        start, as :meth:`Simulation.play` pushes a script."""
        sim = self.simulation
        self._started, self._frames = True, None
        while self._schedule and self._schedule[0][0] < end_ns:
            stamp, _, command = self._schedule.pop(0)
            sim.advance_to(stamp, keep=False)
            sim.push(command)
        sim.advance_to(end_ns, keep=False)

    # ----------------------------------------------------------------- forces

    @_locked
    def _apply(self, body: Body, force: VectorLike, point: Optional[PointLike], frame: str,
               duration: Optional[float], start: Optional[float], torque: float,
               name: Optional[str]) -> None:
        self._live(body)
        sim = self.simulation
        fixed = sim.scene.frame_id
        if frame not in ("world", "body", fixed):
            raise ValueError(f"frame: must be 'world' or 'body', not {frame!r}")
        in_body = frame == "body"
        if point is None:
            at: tuple[float, float] = (body.center_of_mass if in_body
                                       else body.world_point(body.center_of_mass))
        elif isinstance(point, str) and not in_body:
            raise ValueError(f"point: a named point ({point!r}) needs frame='body'")
        else:
            at = body._local(point, "point")
        duration_ns = 0
        if duration is not None:
            seconds = number(duration, "duration", positive=True, maximum=MAX_SECONDS)
            duration_ns = round(seconds * 1e9)
            short = shorter_than_a_step(duration_ns, sim.step_ns, seconds)
            if short is not None:
                raise ValueError(f"duration: {short}")
        now = sim.time_ns
        stamp = now
        if start is not None:
            stamp = round(self._instant(start, "start"))
            if stamp < now:
                raise self._behind(start, "start")
        count = self._count
        if name is None:  # the first name of the count's that no force on the body holds
            count += 1
            while self._names_a_force(body.name, f"force{count}"):
                count += 1
            source = f"force{count}"
        elif isinstance(name, str):
            source = name
        else:
            raise TypeError(f"name: expected a string, not {type(name).__name__}")
        command = WrenchCommand(stamp, body.name, source, body.name if in_body else fixed,
                                at, vector(force, "force"), number(torque, "torque"),
                                duration_ns)
        command.check_finite()
        if stamp == now:
            sim.push(command)  # checks its reach (Simulation.check_reach)
        else:  # a scheduled force too: refused now, not mid-advance
            sim.check_reach(command)
        self._count = count  # counted once taken, so a refused force changes nothing
        self._started = True
        if stamp != now:
            order = max((entry[1] for entry in self._schedule), default=-1) + 1
            self._schedule.append((stamp, order, command))
            self._schedule.sort(key=lambda entry: entry[:2])
        self._applied.setdefault(body.name, {})[source] = (
            stamp + duration_ns if duration_ns else None)

    def _names_a_force(self, body: str, source: str) -> bool:
        """Whether a force on ``body`` applied, scheduled, pushed or scripted is ``source``'s."""
        return (source in self._applied.get(body, {}) or self.simulation.holds_input(body, source)
                or any(entry[2].body == body and entry[2].source == source
                       for entry in self._schedule))

    @_locked
    def push(self, command: WrenchCommand) -> None:
        """Queue ``command`` as the node queues its inputs (:meth:`Simulation.push`): stamped
        in sim-time nanoseconds, held for its ``duration_ns`` or until the scene's input
        timeout, replacing the one of the same body and source. Raises :class:`InputError`
        (and changes nothing) if the simulation refuses it. A force pushed so is the
        caller's: :meth:`Body.clear_forces` does not know it. Its fields are checked as
        every argument is (whole nanoseconds, two numbers a vector, text the names) and
        taken as Python's ints and floats."""
        self.simulation.push(_checked_command(command))
        self._started = True

    @_locked
    def _clear(self, name: str) -> None:
        """Replace what acts on body ``name`` by a zero force for one step (the input
        buffer's way to end a held command) and drop what is scheduled for it."""
        sim = self.simulation
        self._schedule = [entry for entry in self._schedule if entry[2].body != name]
        for source, end in self._applied.pop(name, {}).items():
            if end is None or end > sim.time_ns:
                sim.push(WrenchCommand(sim.time_ns, name, source, sim.scene.frame_id,
                                       (0.0, 0.0), (0.0, 0.0), 0.0, sim.step_ns))

    @_locked
    def _move(self, name: str, *, position: Optional[tuple[float, float]] = None,
              angle: Optional[float] = None, velocity: Optional[tuple[float, float]] = None,
              angular_velocity: Optional[float] = None) -> None:
        now = self._body_state(name)
        self.set_body_state(
            name, now.position if position is None else position,
            now.angle if angle is None else number(angle, "angle"),
            now.linear_velocity if velocity is None else velocity,
            now.angular_velocity if angular_velocity is None
            else number(angular_velocity, "angular_velocity"))

    @_locked
    def set_body_state(self, name: str, position: tuple[float, float], angle: float,
                       velocity: tuple[float, float], angular_velocity: float) -> None:
        """Move body ``name`` now, as the node's ``set_body_state`` service does
        (:meth:`Simulation.set_body_state`): its frame to ``position`` and ``angle``, the
        frame's origin moving at ``velocity``, turning at ``angular_velocity``; the contacts
        forget their warm starts and every body wakes. Raises :class:`InputError` (and
        changes nothing) for an unknown body or a value that is not finite."""
        self.simulation.set_body_state(name, position, angle, velocity, angular_velocity)
        self._started, self._frames = True, None

    # ----------------------------------------------------------------- state

    @_locked
    def state(self) -> dict[str, Any]:
        """Everything the world's future depends on, as plain data (JSON-able; floats
        exact): :meth:`Simulation.export_state` and the forces scheduled and applied."""
        return {"scene": scene_fingerprint(self.simulation.scene),
                "simulation": self.simulation.export_state(),
                "schedule": [[stamp, order, _command_data(command)]
                             for stamp, order, command in self._schedule],
                "applied": copy.deepcopy(self._applied), "count": self._count}

    @_locked
    def set_state(self, state: Mapping[str, Any]) -> None:
        """Go on from :meth:`state`'s data, of this world or one of the same scene: the
        steps that follow are bit for bit those that followed the state taken."""
        if not isinstance(state, Mapping) or set(state) != {"scene", "simulation", "schedule",
                                                             "applied", "count"}:
            raise ValueError("state: expected what World.state() returns")
        # A state of another scene with as many bodies would fit q and v: compare the scenes.
        own = scene_fingerprint(self.simulation.scene)
        if state["scene"] != own:
            raise ValueError(f"state: taken in a world of another scene (fingerprint "
                             f"{state['scene']}; this world's {own})")
        saved = self.simulation.export_state()
        try:
            self.simulation.import_state(copy.deepcopy(dict(state["simulation"])))
            schedule = [(int(stamp), int(order), _command_from_data(data))
                        for stamp, order, data in state["schedule"]]
            applied = {str(body): dict(sources) for body, sources in state["applied"].items()}
            count = int(state["count"])
            if count < 0:
                raise ValueError(f"'count' is {count}, not a count of forces")
        except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
            self.simulation.import_state(saved)  # a refused state changes nothing
            raise ValueError(f"state: not what World.state() returns "
                             f"({type(error).__name__}: {error})") from None
        self._schedule, self._applied, self._count = schedule, applied, count
        self._started, self._frames = True, None
