"""Scenes: a validated description of bodies, forces, walls and inputs.

A scene is a ROS 2 parameters file (``dynamics_node: ros__parameters: ...``), so the same
file serves ``ros2 run hecker_dynamics dynamics_node --ros-args --params-file`` and the
offline tools. :func:`load_scene` reads a file or a shipped scene by name;
:func:`scene_from_parameters` reads the flat parameters a node holds. Every error names
the source, the parameter and what is wrong. ``docs/scenes.md`` lists every parameter.
"""
from __future__ import annotations

import math
import os
import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Optional, Union, overload

import numpy as np

from ..geometry.shapes import (
    Circle,
    GeometryError,
    MassProperties,
    Polygon,
    Shape,
    area_properties,
    box,
    is_convex,
    mass_properties,
)
from ..integrators.methods import METHODS, EmbeddedRungeKutta, fastest_rate
from .commands import WrenchCommand, shorter_than_a_step
from .drives import DriveSpec, read_drive
from .joints import (
    DistanceJoint,
    GearJoint,
    JointEnds,
    JointSpec,
    Motor,
    PrismaticJoint,
    RevoluteJoint,
    RotarySpring,
    SoftJoints,
    WeldJoint,
    motor_overflow,
    soft_refusal,
    softness,
)
from .maps import MapSpec, read_map
from .names import NODE_NAME
from .parameters import (
    MAX_SECONDS,
    NAME_MAX,
    NAME_PATTERN,
    NAME_RULE,
    REQUIRED,
    ParameterReader,
    SceneError,
    flatten,
    quoted,
    seconds_text,
    unflatten,
)
from .rosyaml import merge_parameters, read_parameters_file
from .sensors import SensorSpec, read_sensor

__all__ = [
    "SceneError", "Scene", "BodySpec", "Gravity", "SpringSpec", "DragSpec",
    "AngularDampingSpec", "ConstantForceSpec", "ConstantTorqueSpec", "WallSpec", "CollisionGroup",
    "WrenchTopic", "load_scene", "scene_parameters", "scene_from_parameters", "scene_path",
    "shipped_scenes", "scene_summary", "check_scene_request", "read_body", "read_force",
    "check_force", "unfollowed_force", "check_followed", "read_wall", "read_collisions",
    "read_joint", "read_gear", "check_collidable",
    "INTEGRATORS", "NODE_PARAMETERS", "DEFAULT_SCENE", "with_map", "check_takes_a_step",
    "check_soft_joints",
    "MAX_SECONDS", "MAP_SURFACE",
]

DEFAULT_SCENE = "sample"
INTEGRATORS = (*METHODS, "auto")
#: Parameters that belong to the node, not the scene; the scene reader lets them pass.
NODE_PARAMETERS = frozenset({"use_sim_time", "scene", "lockstep", "play_script",
                             "max_catch_up_steps", "record_session", "keyframe_period",
                             "start_type_description_service", "qos_overrides"})
Vec2 = tuple[float, float]
#: Most vertices of one polygon: its simplicity check is quadratic (about 0.1 s at the
#: bound); a finer outline is a compound body.
MAX_VERTICES = 1024
#: A relative or absolute ROS topic name (letters, digits, underscores, '/' between tokens).
TOPIC_PATTERN = re.compile(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


@dataclass(frozen=True)
class BodySpec:
    """A rigid body: its shapes (body frame), mass properties and initial state.

    ``position`` and ``angle`` place the body frame in the fixed frame; ``velocity`` is the
    velocity of the body frame's origin (fixed-frame axes), as the published twist reports it.
    """

    name: str
    shapes: tuple[Shape, ...]
    mass: MassProperties
    position: Vec2
    angle: float
    velocity: Vec2
    angular_velocity: float
    points: Mapping[str, Vec2] = field(default_factory=dict)


@dataclass(frozen=True)
class Gravity:
    """Uniform gravity acting at the CM of each listed body (no torque)."""

    name: str
    acceleration: Vec2
    bodies: tuple[str, ...]


@dataclass(frozen=True)
class SpringSpec:
    """A damped spring from a point of ``body_a`` to a point of ``body_b`` or a fixed anchor."""

    name: str
    body_a: str
    point_a: Vec2
    body_b: Optional[str]
    point_b: Vec2  # a point of body_b (body frame) or the anchor (fixed frame)
    stiffness: float
    rest_length: float
    damping: float


@dataclass(frozen=True)
class DragSpec:
    """Drag -c v_P (linear) or -c |v_P| v_P (quadratic) at the CM or at a body point."""

    name: str
    bodies: tuple[str, ...]
    coefficient: float
    quadratic: bool
    point: Optional[Vec2]  # body frame; None = at the CM


@dataclass(frozen=True)
class AngularDampingSpec:
    """A torque -c omega on each listed body."""

    name: str
    bodies: tuple[str, ...]
    coefficient: float


@dataclass(frozen=True)
class ConstantForceSpec:
    """A constant force in world or body axes, at the CM or at a body point."""

    name: str
    body: str
    force: Vec2
    body_axes: bool
    point: Optional[Vec2]


@dataclass(frozen=True)
class ConstantTorqueSpec:
    """A constant torque about the CM."""

    name: str
    body: str
    torque: float


ForceSpec = Union[Gravity, SpringSpec, DragSpec, AngularDampingSpec, ConstantForceSpec,
                  ConstantTorqueSpec]


@dataclass(frozen=True)
class WallSpec:
    """A fixed half-plane ``normal . (x - point) >= 0`` that the listed bodies stay inside."""

    name: str
    point: Vec2
    normal: Vec2  # unit, pointing into the free side
    restitution: float
    friction: float
    bodies: tuple[str, ...]


@dataclass(frozen=True)
class CollisionGroup:
    """Bodies that collide with each other (every pair), with the pairs' material."""

    name: str
    bodies: tuple[str, ...]
    restitution: float
    friction: float


@dataclass(frozen=True)
class WrenchTopic:
    """A ``geometry_msgs/WrenchStamped`` input topic that pushes ``body``.

    The wrench acts at the origin of the message's frame, in that frame's axes; an empty
    ``header.frame_id`` means ``frame_id``.
    """

    name: str
    topic: str
    body: str
    frame_id: str


@dataclass(frozen=True)
class Scene:
    """Everything a simulation needs, checked."""

    source: str
    frame_id: str
    step_ns: int
    integrator: str
    tolerance: float
    publish_period_ns: int
    duration_ns: int
    input_timeout_ns: int
    input_max_lead_ns: int
    twist_frame: str
    publish_odometry: bool
    publish_markers: bool
    publish_diagnostics: bool
    publish_tf: bool                        # /tf per body, /tf_static per named point
    restitution_threshold: Optional[float]  # None: chosen from gravity and step
    bodies: tuple[BodySpec, ...]
    forces: tuple[ForceSpec, ...]
    walls: tuple[WallSpec, ...]
    collisions: tuple[CollisionGroup, ...]
    wrench_topics: tuple[WrenchTopic, ...]
    script: tuple[WrenchCommand, ...]
    joints: tuple[JointSpec, ...] = ()
    sleep: bool = False  # resting islands of the contact pass sleep
    events: bool = False  # wall impacts located inside the step (contact/events.py)
    sensors: tuple[SensorSpec, ...] = ()  # lasers and IMUs (scene/sensors.py)
    drives: tuple[DriveSpec, ...] = ()  # cmd_vel drives (scene/drives.py)
    map: Optional[MapSpec] = None  # a nav2 map's occupied cells as static boxes (scene/maps.py)
    publish_contacts: bool = False  # touches beginning and ending (sensors/touch.py)
    threads: int = 1  # the kernel's threads for big islands (contacts.threads): same bits
    # The contact passes' tolerance (contacts.converged); None: contact/solve.py's CONVERGED.
    converged: Optional[float] = None
    soft_joints: Optional[SoftJoints] = None  # joint_solver.type soft; None: exact
    # The exact pass's pin gap (joint_solver.pin_gap, m); None: contact/joints.py's TOLERANCE
    # a row.
    pin_gap: Optional[float] = None

    def has_frame(self, frame_id: str) -> bool:
        """True if ``frame_id`` is the fixed frame, a body's, or a declared body point's."""
        return frame_known(frame_id, self.frame_id, {b.name: b.points for b in self.bodies})


# ----------------------------------------------------------------------------- files

def config_directories() -> list[Path]:
    """Where shipped scenes live: the source tree, the pip install, the ROS share dir."""
    package = Path(__file__).resolve().parents[1]
    candidates = [package.parent / "config", package / "config"]
    share = os.environ.get("AMENT_PREFIX_PATH", "")
    for prefix in share.split(os.pathsep):
        if prefix:
            candidates.append(Path(prefix) / "share" / "hecker_dynamics" / "config")
    return [c for c in candidates if c.is_dir()]


def shipped_scenes() -> list[str]:
    """Names of the scenes shipped with the package."""
    names: set[str] = set()
    for directory in config_directories():
        names.update(p.stem for p in directory.glob("*.yaml"))
    return sorted(names)


def scene_path(name_or_path: Union[str, os.PathLike[str], None]) -> Path:
    """Resolve a shipped scene name (``sample``) or a path to a parameters file."""
    if name_or_path is None:
        name_or_path = DEFAULT_SCENE
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.is_file() or os.sep in str(name_or_path) or \
            path.is_symlink():
        if not path.is_file():
            what = ("is a directory, not a scene file" if path.is_dir()
                    else "is not a regular file" if path.exists()
                    else "is a broken symlink or a symlink loop" if path.is_symlink()
                    else "no such scene file")
            raise SceneError(f"{path}: {what}")
        return path
    for directory in config_directories():
        candidate = directory / f"{name_or_path}.yaml"
        if candidate.is_file():
            return candidate
    shipped = f"(shipped: {', '.join(shipped_scenes()) or 'none found'})"
    if path.is_dir():
        raise SceneError(f"{path}: is a directory, not a scene file, and no shipped scene is "
                         f"called so {shipped}")
    raise SceneError(f"no shipped scene called '{name_or_path}' {shipped}")


def scene_summary(name_or_path: Union[str, os.PathLike[str], None]) -> str:
    """The first line of a scene file's header comment, which says in one line what the
    scene shows ("" for a file that starts otherwise)."""
    with scene_path(name_or_path).open(encoding="utf-8") as stream:
        first = stream.readline().rstrip("\n")
    return first[2:].strip() if first.startswith("# ") else ""


def load_scene(name_or_path: Union[str, os.PathLike[str], None] = None, *,
               step_ns: Optional[int] = None) -> Scene:
    """Load a scene from a ROS 2 parameters file, or a shipped scene by name.

    A file whose only scene parameter is ``scene`` runs the scene that names, as the node
    does; ``scene`` together with scene parameters is refused, as the node refuses it.
    ``step_ns``: the physics step in place of the file's ``step`` (as the node's
    ``-p step:=`` gives it), from which every rate's period is made anew.
    """
    return _load_file(scene_path(name_or_path), redirected=False, step_ns=step_ns)


def _load_file(path: Path, *, redirected: bool, step_ns: Optional[int]) -> Scene:
    source, params = scene_parameters(path)
    requested = params.get("scene")
    if requested:
        check_scene_request(flatten(params), source)
        if redirected:
            raise SceneError(f"{source}: names another scene ('{requested}') and is itself "
                             "named by one; give the scene file itself")
        return _load_file(scene_path(requested), redirected=True, step_ns=step_ns)
    return _read_scene(ParameterReader(params, source), step_ns)


def scene_parameters(name_or_path: Union[str, os.PathLike[str], None] = None
                     ) -> tuple[str, Mapping[str, Any]]:
    """The source and the nested ``ros__parameters`` of a scene file, not yet checked.

    The file is read as ROS 2 reads it (:mod:`.rosyaml`), and the node's parameters are
    its ``/**`` section with its ``dynamics_node`` section over it, as ROS 2 applies them.
    """
    path = scene_path(name_or_path)
    source = str(path)
    document = read_parameters_file(path)
    sections = [(str(key).rsplit("/", 1)[-1] == NODE_NAME, section)
                for key, section in document.items()
                if str(key).rsplit("/", 1)[-1] == NODE_NAME or str(key).strip("/") == "**"]
    params: dict[str, Any] = {}
    # Sorted with the wildcards first: the node's own section wins where both give a value.
    for _, section in sorted(sections, key=lambda pair: pair[0]):
        values = section.get("ros__parameters") if isinstance(section, Mapping) else None
        if not isinstance(values, Mapping):
            raise SceneError(f"{source}: expected '{NODE_NAME}: ros__parameters: ...'")
        try:
            merge_parameters(params, dict(values))
        except SceneError as error:
            raise SceneError(f"{source}: {error}") from None
    if not sections:
        raise SceneError(f"{source}: expected '{NODE_NAME}: ros__parameters: ...' at the top")
    return source, params


def check_scene_request(params: Mapping[str, Any], source: str) -> None:
    """Refuse a ``scene`` parameter given with scene parameters (flat dotted names):
    one of the two would silently win over the other."""
    scene_names = sorted(name for name in params
                         if name.split(".", 1)[0] not in NODE_PARAMETERS)
    requested = params.get("scene") or None
    if scene_names and requested:
        raise SceneError(f"{source}: give the 'scene' parameter ('{requested}') or scene "
                         f"parameters ({', '.join(scene_names[:3])}, ...), not both")


def scene_from_parameters(params: Mapping[str, Any], source: str) -> Scene:
    """Build a scene from flat dotted parameter names, as a node holds them."""
    try:
        nested = unflatten(params)
    except SceneError as error:
        raise SceneError(f"{source}: {error}") from error
    return _read_scene(ParameterReader(nested, source))


# ----------------------------------------------------------------------------- reading

def _seconds_to_ns(reader: ParameterReader, key: str, default: float, *,
                   positive: bool = False) -> int:
    seconds = reader.number(key, default, minimum=0.0, maximum=MAX_SECONDS, positive=positive)
    ns = round(seconds * 1e9)
    if positive and ns < 1:
        reader.fail(key, f"must be at least one nanosecond, not {seconds}")
    return ns


def _read_scene(root: ParameterReader, step_ns: Optional[int] = None) -> Scene:
    """The scene of the parameters in ``root``; ``step_ns``: see :func:`load_scene`."""
    frame_id = root.name("frame_id", "world")
    written = _seconds_to_ns(root, "step", 0.001, positive=True)
    step_ns = written if step_ns is None else step_ns
    publish_period_ns = root.period_ns("publish_rate", step_ns, 50.0)
    bodies = tuple(read_body(name, r) for name, r in root.named_children("bodies"))
    if not bodies:
        root.fail("bodies", "a scene needs at least one body")
    body_names = {b.name for b in bodies}
    if frame_id in body_names:
        root.fail("frame_id", f"'{frame_id}' is also a body's name")
    points = {b.name: b.points for b in bodies}
    by_name = {b.name: b for b in bodies}
    integrator = root.string("integrator", "auto", choices=INTEGRATORS)
    forces = tuple(check_force(read_force(name, r, points), r, by_name, step_ns, integrator)
                   for name, r in root.named_children("forces"))
    walls = tuple(read_wall(name, r, body_names) for name, r in root.named_children("walls"))
    if any(wall.name == MAP_SURFACE for wall in walls):  # a map may come with --map too
        root.fail(f"walls.{MAP_SURFACE}", f"'{MAP_SURFACE}' names the map's boxes in contact "
                                          "events; give the wall another name")
    collisions = read_collisions(root, {b.name: b for b in bodies})
    joints = _read_joints(root, {b.name: b for b in bodies}, frame_id)
    publish = root.child("publish")
    contacts = root.child("contacts")
    joint_solver = root.child("joint_solver")
    scene = Scene(
        source=root.source,
        frame_id=frame_id,
        step_ns=step_ns,
        integrator=integrator,
        tolerance=root.number("tolerance", 1e-6, positive=True),
        publish_period_ns=publish_period_ns,
        duration_ns=_seconds_to_ns(root, "duration", 10.0),
        input_timeout_ns=_seconds_to_ns(root, "input_timeout", 0.5),
        input_max_lead_ns=_seconds_to_ns(root, "input_max_lead", 10.0),
        twist_frame=root.string("twist_frame", "body", choices=("body", "world")),
        publish_odometry=publish.boolean("odometry", False),
        publish_markers=publish.boolean("markers", False),
        publish_diagnostics=publish.boolean("diagnostics", False),
        publish_tf=publish.boolean("tf", True),
        publish_contacts=publish.boolean("contacts", False),
        restitution_threshold=(root.number("restitution_threshold", minimum=0.0)
                               if root.has("restitution_threshold") else None),
        bodies=bodies,
        forces=forces,
        walls=walls,
        collisions=collisions,
        wrench_topics=tuple(_read_wrench_topic(name, r, frame_id, points)
                            for name, r in root.named_children("wrench_topics")),
        script=tuple(sorted((_read_command(name, r, frame_id, points, step_ns)
                             for name, r in root.named_children("script")),
                            key=lambda c: (c.stamp_ns, c.source))),
        joints=joints,
        sleep=contacts.boolean("sleep", False),
        events=contacts.boolean("events", False),
        threads=_read_threads(contacts),
        converged=(contacts.number("converged", positive=True) if contacts.has("converged")
                   else None),
        soft_joints=_read_joint_solver(root, joint_solver, step_ns),
        pin_gap=(joint_solver.number("pin_gap", positive=True) if joint_solver.has("pin_gap")
                 else None),
        sensors=tuple(read_sensor(name, r, points, step_ns)
                      for name, r in root.named_children("sensors")),
        drives=tuple(read_drive(name, r, points, step_ns)
                     for name, r in root.named_children("drives")),
        map=_read_map(root.child("map"), {b.name: b for b in bodies}) if root.has("map")
        else None,
    )
    root.check_all_read(ignore=NODE_PARAMETERS)
    return scene


#: The most sub-steps ``joint_solver.substeps`` takes.
MOST_SOFT_SUBSTEPS = 64


def _read_joint_solver(root: ParameterReader, solver: ParameterReader,
                       step_ns: int) -> Optional[SoftJoints]:
    """``joint_solver`` (``solver``): ``type`` exact (None) or soft, with its sub-steps and
    softness; soft joints step as Box2D v3 does, so only with semi-implicit Euler and no
    contacts, and hold no ``pin_gap`` (an exact pass's)."""
    if solver.string("type", "exact", choices=("exact", "soft")) == "exact":
        for key in ("substeps", "hertz", "damping_ratio"):
            if solver.has(key):
                solver.fail(key, "is a setting of joint_solver.type soft, not exact")
        return None
    if solver.has("pin_gap"):
        solver.fail("pin_gap", "is a setting of joint_solver.type exact, not soft (soft "
                               "joints hold no gap)")
    substeps = solver.raw("substeps", 4)
    if isinstance(substeps, bool) or not isinstance(substeps, int) or \
            not 1 <= substeps <= MOST_SOFT_SUBSTEPS:
        solver.fail("substeps", f"must be an integer from 1 to {MOST_SOFT_SUBSTEPS}, "
                                f"not {quoted(substeps)}")
    soft = SoftJoints(substeps, solver.number("hertz", 60.0, positive=True),
                      solver.number("damping_ratio", 2.0, minimum=0.0))
    h = step_ns * 1e-9 / substeps
    if not all(map(math.isfinite, softness(soft.hertz, soft.damping_ratio, h))):
        # hertz 1e308 or damping_ratio 1e308: the spring's implicit terms overflow, and the
        # first sub-step's impulses would be NaN.
        stiff = not all(map(math.isfinite, softness(soft.hertz, 0.0, h)))
        solver.fail("hertz" if stiff else "damping_ratio",
                    f"hertz {soft.hertz:g} with damping_ratio {soft.damping_ratio:g} over "
                    f"sub-steps of {h:g} s is a spring too stiff for a double")
    problem = soft_refusal(root.raw("integrator", "auto"),
                           [what for what, key in (("walls", "walls"),
                                                   ("collision groups", "collisions"),
                                                   ("a map", "map")) if root.has(key)])
    if problem is not None:
        solver.fail("type", problem)
    return soft


def _read_threads(contacts: ParameterReader) -> int:
    """``contacts.threads``: 1 or 2 (the kernel's velocity passes of big islands)."""
    value = contacts.raw("threads", 1)
    if isinstance(value, bool) or value not in (1, 2) or not isinstance(value, int):
        contacts.fail("threads", f"must be 1 or 2, not {quoted(value)}")
    return value


def _read_shape(reader: ParameterReader, *, part: bool) -> Shape:
    """A shape in the body frame. A box or polygon part of a compound body may be turned
    about its ``center`` (``angle``); a single-shape body's ``angle`` is the body's own."""
    kind = reader.string("shape", REQUIRED, choices=("box", "circle", "polygon"))
    center = reader.vector("center", [0.0, 0.0])
    if kind == "circle":
        return Circle(center, reader.number("radius", REQUIRED, positive=True))
    turn = reader.number("angle", 0.0) if part else 0.0
    if kind == "box":
        width, height = reader.numbers("size", REQUIRED, length=2)
        return box(width, height, center, turn)
    flat = reader.numbers("vertices", REQUIRED, multiple_of=2)
    if not 6 <= len(flat) <= 2 * MAX_VERTICES:
        reader.fail("vertices", f"a polygon needs 3 to {MAX_VERTICES} vertices "
                                f"(6 to {2 * MAX_VERTICES} numbers), not {len(flat)} numbers")
    c, s = math.cos(turn), math.sin(turn)
    return Polygon(np.array([(center[0] + c * x - s * y, center[1] + s * x + c * y)
                             for x, y in zip(flat[0::2], flat[1::2])]))


def read_body(name: str, reader: ParameterReader) -> BodySpec:
    try:
        if reader.has("parts"):
            parts = list(reader.named_children("parts"))
            if not parts:
                reader.fail("parts", "a compound body needs at least one part")
            shapes = [_read_shape(r, part=True) for _, r in parts]
            own = [r.number("density", None) if r.has("density") else None for _, r in parts]
        else:
            shapes = [_read_shape(reader, part=False)]
            own = [None]
        has_mass, has_density = reader.has("mass"), reader.has("density")
        if has_mass and has_density:
            reader.fail("mass", "give mass or density, not both")
        if has_density:
            density = reader.number("density", positive=True)
            densities = [d if d is not None else density for d in own]
        elif has_mass:
            relative = [d if d is not None else 1.0 for d in own]
            mass = reader.number("mass", positive=True)
            with np.errstate(all="ignore"):
                try:
                    unit = mass_properties(shapes, relative)
                except GeometryError:
                    # Not its figures, which are the shape's at unit density: the mass
                    # they quote is not the one given.
                    area = sum(area_properties(shape).area for shape in shapes)
                    raise GeometryError(
                        f"its shape (area {area:.4g} m^2) is too small or too large to "
                        "integrate in double precision, so its mass of "
                        f"{mass:g} kg cannot be spread over it (sizes from about 1e-150 to "
                        "1e150 m can)") from None
            densities = [d * mass / unit.mass for d in relative]
        elif all(d is not None for d in own):
            densities = [d for d in own if d is not None]
        else:
            reader.fail("mass", "is required (or 'density', or a density on every part)")
        if any(d <= 0.0 for d in densities):
            reader.fail("parts", "every density must be positive")
        with np.errstate(all="ignore"):  # an overflow is refused below, not printed
            properties = mass_properties(shapes, densities)
    except GeometryError as error:
        raise SceneError(f"{reader.source}: body '{name}': {error}") from error
    points = dict(_read_points(reader))
    angle, velocity = reader.number("angle", 0.0), reader.vector("velocity", [0.0, 0.0])
    spin = reader.number("angular_velocity", 0.0)
    # The CM's velocity, v_O + omega perp(r_OC) (Eq. 9), and the spin: a state whose energy
    # of motion no double holds is one the energy bound cannot judge.
    cx, cy = properties.center_of_mass
    c, s = math.cos(angle), math.sin(angle)
    speed = math.hypot(velocity[0] - spin * (s * cx + c * cy),
                       velocity[1] + spin * (c * cx - s * cy))
    if not math.isfinite(properties.energy_of_motion(speed, spin)):
        spinning = not math.isfinite(properties.energy_of_motion(0.0, spin))
        reader.fail("angular_velocity" if spinning else "velocity",
                    f"moves the body so fast ({speed:.3g} m/s, {abs(spin):.3g} rad/s) that "
                    "its energy of motion is past what a double holds")
    return BodySpec(
        name=name, shapes=tuple(shapes), mass=properties,
        position=reader.vector("position", [0.0, 0.0]), angle=angle, velocity=velocity,
        angular_velocity=spin, points=points,
    )


def _read_points(reader: ParameterReader) -> list[tuple[str, Vec2]]:
    group = reader.child("points")
    for pname in group.names():
        if not NAME_PATTERN.fullmatch(pname):
            group.fail(pname, f"is not a valid point name ({NAME_RULE})")
    return [(pname, group.vector(pname)) for pname in group.names()]


def _body_list(reader: ParameterReader, key: str, known: Mapping[str, Any]) -> tuple[str, ...]:
    names = reader.strings(key, list(known))
    for body in names:
        if body not in known:
            reader.fail(key, f"names an unknown body '{body}'")
    if len(set(names)) != len(names):
        reader.fail(key, "names a body more than once")
    return tuple(names)


def _body(reader: ParameterReader, key: str, points: Mapping[str, Mapping[str, Vec2]]) -> str:
    body = reader.string(key, REQUIRED)
    if body not in points:
        reader.fail(key, f"names an unknown body '{body}'")
    return body


@overload
def _point(reader: ParameterReader, key: str, points: Mapping[str, Vec2],
           default: None = None) -> Optional[Vec2]: ...


@overload
def _point(reader: ParameterReader, key: str, points: Mapping[str, Vec2],
           default: list[float]) -> Vec2: ...


def _point(reader: ParameterReader, key: str, points: Mapping[str, Vec2],
           default: Optional[list[float]] = None) -> Optional[Vec2]:
    """A body point given as [x, y] in the body frame or as the name of a declared point."""
    value = reader.raw(key, default)
    if value is None:
        return None
    if isinstance(value, str):
        if value not in points:
            reader.fail(key, f"names no declared point of the body (declared: "
                             f"{', '.join(points) or 'none'})")
        return points[value]
    x, y = reader.check_numbers(key, value, length=2)
    return (x, y)


def read_force(name: str, reader: ParameterReader,
                points: Mapping[str, Mapping[str, Vec2]]) -> ForceSpec:
    kind = reader.string("type", REQUIRED, choices=(
        "gravity", "spring", "linear_drag", "quadratic_drag", "angular_damping",
        "constant_force", "constant_torque"))
    if kind == "gravity":
        return Gravity(name, reader.vector("acceleration", [0.0, -9.81]),
                       _body_list(reader, "bodies", points))
    if kind == "spring":
        body_a = _body(reader, "body_a", points)
        point_a = _point(reader, "point_a", points[body_a], [0.0, 0.0])
        if reader.has("anchor") == reader.has("body_b"):
            reader.fail("anchor", "a spring needs exactly one of 'body_b' or 'anchor'")
        if reader.has("anchor"):
            body_b, point_b = None, reader.vector("anchor")
        else:
            body_b = _body(reader, "body_b", points)
            point_b = _point(reader, "point_b", points[body_b], [0.0, 0.0])
            if body_b == body_a:
                reader.fail("body_b", "a spring cannot join a body to itself")
        return SpringSpec(name, body_a, point_a, body_b, point_b,
                          stiffness=reader.number("stiffness", REQUIRED, minimum=0.0),
                          rest_length=reader.number("rest_length", 0.0, minimum=0.0),
                          damping=reader.number("damping", 0.0, minimum=0.0))
    if kind in ("linear_drag", "quadratic_drag"):
        bodies = _body_list(reader, "bodies", points)
        point = None
        if reader.has("point"):
            if len(bodies) != 1:
                reader.fail("point", "a drag point needs exactly one body in 'bodies'")
            point = _point(reader, "point", points[bodies[0]])
        return DragSpec(name, bodies, reader.number("coefficient", REQUIRED, minimum=0.0),
                        quadratic=kind == "quadratic_drag", point=point)
    if kind == "angular_damping":
        return AngularDampingSpec(name, _body_list(reader, "bodies", points),
                                  reader.number("coefficient", REQUIRED, minimum=0.0))
    body = _body(reader, "body", points)
    if kind == "constant_torque":
        return ConstantTorqueSpec(name, body, reader.number("torque", REQUIRED))
    return ConstantForceSpec(
        name, body, reader.vector("force", REQUIRED),
        body_axes=reader.string("axes", "world", choices=("world", "body")) == "body",
        point=_point(reader, "point", points[body]))


def check_force(force: ForceSpec, reader: ParameterReader, bodies: Mapping[str, BodySpec],
                step_ns: int, method: str = "auto") -> ForceSpec:
    """Refuse gravity or a constant force that gives a body, from rest, in one step, an
    energy of motion no double holds (``acceleration: [0, -1e308]``), or such a spring
    (:func:`_check_spring`): the run's energy bound would stop it at its first step, but
    the masses say so already. Refuse too a force faster than the integrator ``method``
    can follow (:func:`unfollowed_force`)."""
    if isinstance(force, SpringSpec):
        _check_spring(force, reader, bodies, step_ns)
    else:
        _check_push(force, reader, bodies, step_ns)
    unfollowed = unfollowed_force(force, bodies, step_ns, method)
    if unfollowed is not None:
        reader.fail(*unfollowed)
    return force


def unfollowed_force(force: ForceSpec, bodies: Mapping[str, BodySpec], step_ns: int,
                     method: str) -> Optional[tuple[str, str]]:
    """The parameter of ``force`` and why, if the adaptive ``method`` cannot follow it
    through a step of ``step_ns`` (:func:`~..integrators.methods.fastest_rate`), else None.

    The rates are the least the force makes (the real ones may be faster): a spring
    between bodies of inverse masses summing to mu, pulled or pushed along its line alone,
    is an oscillator of stiffness k and damping c on the mass 1/mu, whose fastest root has
    a size of at least sqrt(k mu) (the roots' product) and c mu / 2 (half their sum);
    linear drag decays a body's velocity at c / m, angular damping its spin at c / I.
    dopri5 or dop853 would fail at the first step (too many sub-steps, or their size
    underflowing: a spring of 1e150 N/m)."""
    fastest = fastest_rate(method, step_ns * 1e-9)
    if fastest is None:
        return None
    rates: list[tuple[str, str, float]] = []
    if isinstance(force, SpringSpec):
        mu = sum(1.0 / bodies[name].mass.mass for name in (force.body_a, force.body_b)
                 if name is not None)
        rates = [("stiffness", "a frequency", math.sqrt(force.stiffness * mu)),
                 ("damping", "a decay rate", 0.5 * force.damping * mu)]
    elif isinstance(force, DragSpec) and not force.quadratic:
        rates = [("coefficient", "a decay rate",
                  max((force.coefficient / bodies[name].mass.mass for name in force.bodies),
                      default=0.0))]
    elif isinstance(force, AngularDampingSpec):
        rates = [("coefficient", "a decay rate",
                  max((force.coefficient / bodies[name].mass.moment_of_inertia
                       for name in force.bodies), default=0.0))]
    for key, what, rate in rates:
        if rate > fastest:
            return key, (f"makes {what} of at least {rate:.3g} /s, past the {fastest:.3g} /s "
                         f"{method} can follow in the {EmbeddedRungeKutta.MAX_SUBSTEPS} "
                         f"sub-steps it takes a step of {seconds_text(step_ns)} s at most: use "
                         f"implicit_midpoint or backward_euler, a shorter step, or a smaller "
                         f"{key}")
    return None


def check_followed(scene: Scene, method: str) -> None:
    """Refuse a force of ``scene`` that ``method``, the integrator ``auto`` or a command
    line's ``--integrator`` picked for it, cannot follow (:func:`unfollowed_force`), with
    the loader's message."""
    bodies = {body.name: body for body in scene.bodies}
    for force in scene.forces:
        unfollowed = unfollowed_force(force, bodies, scene.step_ns, method)
        if unfollowed is not None:
            key, problem = unfollowed
            picked = f" (integrator {scene.integrator} picks {method} here)" if \
                scene.integrator == "auto" else ""
            raise SceneError(f"{scene.source}: parameter 'forces.{force.name}.{key}': "
                             f"{problem}{picked}")


def _check_push(force: ForceSpec, reader: ParameterReader, bodies: Mapping[str, BodySpec],
                step_ns: int) -> None:
    """Refuse gravity or a constant force that gives a body, from rest, in one step, an
    energy of motion no double holds."""
    if isinstance(force, Gravity):
        key, pushed = "acceleration", [(bodies[n], math.hypot(*force.acceleration))
                                       for n in force.bodies]
    elif isinstance(force, ConstantForceSpec):
        body = bodies[force.body]
        key, pushed = "force", [(body, math.hypot(*force.force) / body.mass.mass)]
    else:
        return
    for body, acceleration in pushed:
        speed = acceleration * (step_ns * 1e-9)
        if not math.isfinite(body.mass.energy_of_motion(speed, 0.0)):
            reader.fail(key, f"would give body '{body.name}' ({body.mass.mass:.4g} kg), from "
                             f"rest, in one step of {seconds_text(step_ns)} s, a speed of "
                             f"{speed:.3g} m/s: an energy of motion past what a double holds")


def _check_spring(spring: SpringSpec, reader: ParameterReader, bodies: Mapping[str, BodySpec],
                  step_ns: int) -> None:
    """Refuse a spring that gives a body, in its first step, an energy of motion no double
    holds (``stiffness: 1e308`` or ``damping: 1e308``): its pull at the start (Hooke's law
    and the dashpot at the ends' velocities along it), then the dashpot's pull at the speed
    that gives. The run's energy bound would stop it at its first step (or an adaptive
    step's size underflow), but the masses and the start say so already."""
    h = step_ns * 1e-9
    ends = [(bodies[spring.body_a], spring.point_a)]
    if spring.body_b is not None:
        ends.append((bodies[spring.body_b], spring.point_b))
    places, velocities = [], []
    for body, point in ends:
        (x, y), (cx, cy) = _place(body, point), body.position
        omega = body.angular_velocity
        places.append((x, y))
        velocities.append((body.velocity[0] - omega * (y - cy),
                           body.velocity[1] + omega * (x - cx)))
    if spring.body_b is None:
        places.append(spring.point_b)
        velocities.append((0.0, 0.0))
    dx, dy = places[0][0] - places[1][0], places[0][1] - places[1][1]
    dvx, dvy = velocities[0][0] - velocities[1][0], velocities[0][1] - velocities[1][1]
    length = math.hypot(dx, dy)
    closing = abs(dvx * dx + dvy * dy) / length if length else math.hypot(dvx, dvy)
    for body, _ in ends:
        over = h / body.mass.mass  # speed per newton over a step
        stretched = spring.stiffness * abs(length - spring.rest_length) * over
        speed = stretched + spring.damping * (closing + stretched) * over
        for key, reached in (("stiffness", stretched), ("damping", speed)):
            if not math.isfinite(body.mass.energy_of_motion(reached, 0.0)):
                reader.fail(key, f"would give body '{body.name}' ({body.mass.mass:.4g} kg), in "
                                 f"its first step of {seconds_text(step_ns)} s, a speed of "
                                 f"{reached:.3g} m/s: an energy of motion past what a double "
                                 "holds")


def _direction(reader: ParameterReader, key: str) -> Vec2:
    """The vector ``key`` (required, not zero) divided by its length. One of subnormal
    numbers is scaled up first: its length keeps too few digits (hypot(5e-324, 5e-324) is
    5e-324, which made (1, 1) a wall's "unit" normal and the wall let bodies through)."""
    x, y = reader.vector(key, REQUIRED)
    length = math.hypot(x, y)
    if length == 0.0:
        reader.fail(key, "must not be the zero vector")
    if length < sys.float_info.min:
        scale = max(abs(x), abs(y))
        x, y = x / scale, y / scale
        length = math.hypot(x, y)
    return (x / length, y / length)


def read_wall(name: str, reader: ParameterReader, bodies: set[str]) -> WallSpec:
    known = {b: None for b in sorted(bodies)}
    return WallSpec(name, reader.vector("point", REQUIRED), _direction(reader, "normal"),
                    restitution=reader.number("restitution", 0.5, minimum=0.0, maximum=1.0),
                    friction=reader.number("friction", 0.0, minimum=0.0),
                    bodies=_body_list(reader, "bodies", known))


def read_collisions(root: ParameterReader,
                     bodies: Mapping[str, BodySpec]) -> tuple[CollisionGroup, ...]:
    """Collision groups; every pair of bodies may be in one group at most, and the bodies'
    polygon parts must be convex (split a concave shape into convex parts)."""
    groups: list[CollisionGroup] = []
    # Each body's earlier groups, so that a pair in two groups is found without listing every
    # pair: a pyramid of 5050 boxes in one group has 12.7 million.
    joined: dict[str, list[int]] = {}
    for name, reader in root.named_children("collisions"):
        members = _body_list(reader, "bodies", bodies)
        if len(members) < 2:
            reader.fail("bodies", "a collision group needs at least two bodies")
        _refuse_a_pair_grouped_twice(reader, members, joined, groups)
        for member in members:
            joined.setdefault(member, []).append(len(groups))
        for member in members:
            check_collidable(bodies[member], name, reader.source)
        groups.append(CollisionGroup(name, members,
                                     reader.number("restitution", 0.2, minimum=0.0, maximum=1.0),
                                     reader.number("friction", 0.5, minimum=0.0)))
    return tuple(groups)


def _refuse_a_pair_grouped_twice(reader: ParameterReader, members: tuple[str, ...],
                                 joined: Mapping[str, list[int]],
                                 groups: list[CollisionGroup]) -> None:
    """Refuse ``members`` if two of them are in one earlier group, naming the first such pair
    in their order and the first group holding it."""
    shared: dict[int, int] = {}
    for member in members:
        for index in joined.get(member, ()):
            shared[index] = shared.get(index, 0) + 1
    if all(count < 2 for count in shared.values()):
        return
    twice = [m for m in members if any(shared[index] > 1 for index in joined.get(m, ()))]
    for i, a in enumerate(twice):
        for b in twice[i + 1:]:
            common = sorted(set(joined[a]) & set(joined[b]))
            if common:
                reader.fail("bodies", f"bodies '{a}' and '{b}' are already in collision "
                                      f"group '{groups[common[0]].name}'")


def check_collidable(body: BodySpec, group: str, source: str,
                     kind: str = "collision group") -> None:
    """Refuse a body of collision group (or map) ``group`` with a concave polygon part."""
    for shape in body.shapes:
        if isinstance(shape, Polygon) and not is_convex(shape.vertices):
            raise SceneError(f"{source}: body '{body.name}': a polygon that collides must be "
                             f"convex ({kind} '{group}'); make it a compound body "
                             "of convex parts")


def _read_map(reader: ParameterReader, bodies: Mapping[str, BodySpec]) -> MapSpec:
    """The scene's map: a nav2 map file (relative to the scene file's directory) whose
    occupied cells the listed bodies (default: all) collide with."""
    file = reader.string("file", REQUIRED)
    path = Path(file)
    if not path.is_absolute() and Path(reader.source).is_file():
        path = Path(reader.source).parent / path
    try:
        occupancy = read_map(path)
    except SceneError as error:
        reader.fail("file", str(error))
    members = _body_list(reader, "bodies", bodies)
    for name in members:
        check_collidable(bodies[name], file, reader.source, kind="map")
    return MapSpec(file, occupancy,
                   restitution=reader.number("restitution", 0.5, minimum=0.0, maximum=1.0),
                   friction=reader.number("friction", 0.0, minimum=0.0), bodies=members)


def with_map(scene: Scene, file: str, source: str = "--map") -> Scene:
    """``scene`` with its map read from ``file`` (relative to the working directory),
    keeping the scene's map's material and bodies, or the defaults of ``map`` without one."""
    values: dict[str, Any] = {"file": file}
    if scene.map is not None:
        values.update(restitution=scene.map.restitution, friction=scene.map.friction,
                      bodies=list(scene.map.bodies))
    reader = ParameterReader({"map": values}, source)
    return replace(scene, map=_read_map(reader.child("map"), {b.name: b for b in scene.bodies}))


def check_soft_joints(scene: Scene) -> None:
    """Refuse soft joints that cannot step (:func:`~.joints.soft_refusal`) with the
    loader's message: for a scene changed after loading, by a command line's
    ``--integrator`` or ``--map``, with joints or without, as its file would be."""
    if scene.soft_joints is None:
        return
    problem = soft_refusal(scene.integrator, [
        what for what, there in (("walls", scene.walls), ("collision groups", scene.collisions),
                                 ("a map", scene.map is not None)) if there])
    if problem is not None:
        raise SceneError(f"{scene.source}: parameter 'joint_solver.type': {problem}")


def check_takes_a_step(duration_ns: int, step_ns: int, what: str,
                       given: Optional[str] = None) -> None:
    """Refuse a run or session (``what`` names its duration, quoted as ``given`` if the
    seconds were written) shorter than one step: the fixed-step clock takes the whole
    steps that fit (1.5 steps take one), so it would take none and report its start as its
    end."""
    if duration_ns < step_ns:
        seconds = seconds_text(duration_ns) if given is None else given
        raise SceneError(f"{what} {seconds} s is shorter than one step "
                         f"({seconds_text(step_ns)} s): no step would be taken")


#: The surface a contact event names for the map's boxes (a wall's name for a wall's):
#: no wall may take it, or its touches and the map's would be one.
MAP_SURFACE = "map"

JOINT_TYPES = ("revolute", "prismatic", "weld", "distance", "gear")


def _read_joints(root: ParameterReader, bodies: Mapping[str, BodySpec],
                 fixed: str) -> tuple[JointSpec, ...]:
    """Joints; a gear names two revolute joints of the same scene."""
    joints: list[JointSpec] = []
    gears = []
    points = {b: spec.points for b, spec in bodies.items()}  # once: a grid has 20,000 joints
    readers = {}
    for name, reader in root.named_children("joints"):
        kind = reader.string("type", REQUIRED, choices=JOINT_TYPES)
        if kind == "gear":
            gears.append((name, reader))
            continue
        joints.append(read_joint(name, kind, reader, bodies, points, fixed))
        readers[name] = reader
    _check_rods(joints, bodies, readers)
    _check_loops(joints, bodies, readers)
    revolute = [joint.name for joint in joints if isinstance(joint, RevoluteJoint)]
    joints += [read_gear(name, reader, revolute) for name, reader in gears]
    return tuple(sorted(joints, key=lambda j: j.name))


def _start(joint: JointEnds, bodies: Mapping[str, BodySpec]) -> tuple[Vec2, Vec2]:
    """Where a joint's two points are at the start, in the fixed frame."""
    start_a = joint.point_a if joint.body_a is None else _place(bodies[joint.body_a],
                                                                 joint.point_a)
    return start_a, _place(bodies[joint.body_b], joint.point_b)


def _check_rods(joints: Sequence[JointSpec], bodies: Mapping[str, BodySpec],
                readers: Mapping[str, ParameterReader]) -> None:
    """Refuse a rod whose length the other joints of its two bodies never let it reach.

    Pins and welds join points that coincide at the start (:func:`read_joint`), and a
    slider starts at 0 within its limits, so every set of them holds at the start: two
    pins of one pair at different points, or a pin beside a weld or a slider, hold the
    pair as a weld does (redundant rows, which the joint pass solves). A rod may start at
    another length and pull to its own; beside a weld (or what holds as one) its points
    stay as far apart as they start, and beside one pin they stay between |d_a - d_b| and
    d_a + d_b apart, d_a and d_b their distances from the pin: a rod outside that range
    fights the pin for ever, and its pull tore the pin open."""
    pairs: dict[frozenset[Optional[str]], list[JointEnds]] = {}
    for joint in joints:
        if isinstance(joint, JointEnds):
            pairs.setdefault(frozenset((joint.body_a, joint.body_b)), []).append(joint)
    for group in pairs.values():
        pins = [j for j in group if isinstance(j, RevoluteJoint)]
        holding: list[JointEnds] = [j for j in group if isinstance(j, PrismaticJoint)
                   or (isinstance(j, WeldJoint) and j.frequency == 0.0)]
        anchors = [_start(pin, bodies)[1] for pin in pins]
        if any(math.dist(anchors[0], other) > 1e-6 for other in anchors[1:]):
            holding += pins[1:]
        if not pins and not holding:
            continue
        for rod in (j for j in group if isinstance(j, DistanceJoint) and not j.rope):
            end_a, end_b = _start(rod, bodies)
            gap = math.dist(end_a, end_b)
            if holding:
                low = high = gap
                held = f"'{holding[0].name}' holds its bodies rigidly beside it"
            else:
                d_a, d_b = math.dist(end_a, anchors[0]), math.dist(end_b, anchors[0])
                low, high = abs(d_a - d_b), d_a + d_b
                held = f"pin '{pins[0].name}' joins its bodies"
            if not low - 1e-6 <= rod.length <= high + 1e-6:
                span = f"{low:.6g} m apart" if low == high else \
                    f"{low:.6g} to {high:.6g} m apart"
                readers[rod.name].fail("length", f"{rod.length:g} m is out of reach: {held}, "
                                                 f"so the rod's points stay {span}")


#: A point of a body in its frame (None: a fixed-frame point), as a node of the joints' graph.
_Node = tuple[Optional[str], Vec2]


def _check_loops(joints: Sequence[JointSpec], bodies: Mapping[str, BodySpec],
                 readers: Mapping[str, ParameterReader]) -> None:
    """Refuse a rod that a loop of other joints never lets reach its length (a four-bar
    linkage whose coupler rod is too long, a triangle of rods 1, 1 and 5 m): loaded, the
    joint pass tore the loop's pins open by metres without a word.

    Along a path of joints from one of the rod's points to the other, each body holds the
    points where the path enters and leaves it a fixed distance apart, a pin joins its
    points, a rigid weld holds them as far apart as they start and another rod at its
    length (sliders, ropes and soft welds give no bound). However the path turns, its ends
    stay between 2 m - s and s apart, s the sum of those distances and m the longest: the
    rod's length must lie there for the shortest such path."""
    rods = [j for j in joints if isinstance(j, DistanceJoint) and not j.rope]
    if not rods:
        return
    links: dict[_Node, list[tuple[_Node, float, str]]] = {}
    on_body: dict[Optional[str], set[Vec2]] = {}
    for joint in joints:
        if isinstance(joint, RevoluteJoint):
            gap = 0.0
        elif isinstance(joint, WeldJoint) and joint.frequency == 0.0:
            gap = math.dist(*_start(joint, bodies))
        elif isinstance(joint, DistanceJoint) and not joint.rope:
            gap = joint.length
        else:
            continue
        end_a, end_b = (joint.body_a, joint.point_a), (joint.body_b, joint.point_b)
        links.setdefault(end_a, []).append((end_b, gap, joint.name))
        links.setdefault(end_b, []).append((end_a, gap, joint.name))
        for body, point in (end_a, end_b):
            on_body.setdefault(body, set()).add(point)
    for rod in rods:
        path = _shortest_path(links, on_body, (rod.body_a, rod.point_a),
                              (rod.body_b, rod.point_b), rod.name)
        if path is None:
            continue
        lengths = [length for length, _ in path]
        high = sum(lengths)
        low = max(0.0, 2.0 * max(lengths) - high)
        if not low - 1e-6 <= rod.length <= high + 1e-6:
            names = ", ".join(f"'{name}'" for _, name in path if name is not None)
            span = f"{high:.6g} m apart" if high - low <= 1e-6 else \
                f"{low:.6g} to {high:.6g} m apart"
            readers[rod.name].fail("length", f"{rod.length:g} m is out of reach: the loop "
                                             f"through {names} holds the rod's points {span}")


def _shortest_path(links: Mapping[_Node, list[tuple[_Node, float, str]]],
                   on_body: Mapping[Optional[str], set[Vec2]], start: _Node, end: _Node,
                   without: str) -> Optional[list[tuple[float, Optional[str]]]]:
    """The shortest path of joints (all but ``without``) and bodies from ``start`` to
    ``end`` as its lengths, each with its joint's name (None: across a body); None when
    no path joins them (Dijkstra's)."""
    import heapq

    best: dict[_Node, float] = {start: 0.0}
    came: dict[_Node, tuple[_Node, float, Optional[str]]] = {}
    queue: list[tuple[float, int, _Node]] = [(0.0, 0, start)]
    pushed = 1
    while queue:
        distance, _, node = heapq.heappop(queue)
        if node == end:
            path: list[tuple[float, Optional[str]]] = []
            while node != start:
                node, length, name = came[node]
                path.append((length, name))
            return path[::-1]
        if distance > best[node]:
            continue
        body, point = node
        steps: list[tuple[_Node, float, Optional[str]]] = [
            (other, length, name) for other, length, name in links.get(node, [])
            if name != without]
        across = set(on_body.get(body, ()))
        if body == end[0]:
            across.add(end[1])
        steps += [((body, other), math.dist(point, other), None) for other in across]
        for target, length, name in steps:
            if target != node and distance + length < best.get(target, math.inf):
                best[target] = distance + length
                came[target] = (node, length, name)
                heapq.heappush(queue, (distance + length, pushed, target))
                pushed += 1
    return None


def read_gear(name: str, reader: ParameterReader, revolute: Sequence[str]) -> GearJoint:
    """A gear of two different joints among the scene's ``revolute`` joints."""
    gear = GearJoint(name, reader.string("joint_a", REQUIRED), reader.string("joint_b", REQUIRED),
                     reader.number("ratio", REQUIRED))
    for key in ("joint_a", "joint_b"):
        if getattr(gear, key) not in revolute:
            reader.fail(key, f"'{getattr(gear, key)}' is not a revolute joint of this "
                             f"scene (revolute joints: {', '.join(revolute) or 'none'})")
    if gear.joint_a == gear.joint_b:
        reader.fail("joint_b", "a gear needs two different joints")
    if gear.ratio == 0.0:
        reader.fail("ratio", "must not be zero")
    return gear


def _place(body: BodySpec, point: Vec2) -> Vec2:
    """A body-frame point in the fixed frame at the body's initial pose."""
    c, s = math.cos(body.angle), math.sin(body.angle)
    return (body.position[0] + c * point[0] - s * point[1],
            body.position[1] + s * point[0] + c * point[1])


def read_joint(name: str, kind: str, reader: ParameterReader, bodies: Mapping[str, BodySpec],
                points: Mapping[str, Mapping[str, Vec2]], fixed: str) -> JointSpec:
    """A joint between ``body_a`` (default: the fixed frame) and ``body_b``. ``point_b``
    (default the body frame's origin) is a point of body_b; ``point_a`` one of body_a, or
    fixed-frame coordinates, by default where point_b is at the start (a distance joint:
    body_a's origin); ``points``: each body's named points."""
    name_a = reader.string("body_a", fixed)
    if name_a != fixed and name_a not in bodies:
        reader.fail("body_a", f"names an unknown body '{name_a}' (nor the fixed frame '{fixed}')")
    body_b = _body(reader, "body_b", points)
    if body_b == name_a:
        reader.fail("body_b", "a joint cannot join a body to itself")
    point_b = _point(reader, "point_b", points[body_b], [0.0, 0.0])
    start_b = _place(bodies[body_b], point_b)
    world = name_a == fixed
    body_a = None if world else name_a
    default_a = (None if kind != "distance" else [0.0, 0.0])
    given = (reader.vector("point_a", default_a) if world and reader.has("point_a")
             else _point(reader, "point_a", {} if world else points[name_a], default_a))
    if given is None:  # where point_b starts, in body_a's frame
        point_a = start_b if world else _local_point(bodies[name_a], start_b)
    else:
        point_a = given
    start_a = point_a if world else _place(bodies[name_a], point_a)
    gap = math.hypot(start_b[0] - start_a[0], start_b[1] - start_a[1])
    common: dict[str, Any] = dict(name=name, body_a=body_a, body_b=body_b, point_a=point_a,
                                  point_b=point_b,
                                  collide_connected=reader.boolean("collide_connected", False))
    if kind in ("revolute", "weld") and gap > 1e-6:
        reader.fail("point_a", f"is {gap:.6g} m from point_b at the start; a {kind} joint "
                               "joins one point of both bodies")
    if kind == "weld":
        return WeldJoint(**common, frequency=reader.number("frequency", 0.0, minimum=0.0),
                         damping_ratio=reader.number("damping_ratio", 1.0, minimum=0.0))
    if kind == "distance":
        if reader.has("length") and reader.has("max_length"):
            reader.fail("max_length", "a distance joint is a rod ('length') or a rope "
                                      "('max_length'), not both")
        rope = reader.has("max_length")
        length = reader.number("max_length" if rope else "length", gap, positive=True)
        if rope and gap > length:
            reader.fail("max_length", f"the points start {gap:.6g} m apart, beyond {length}")
        return DistanceJoint(**common, length=length, rope=rope)
    lower = reader.number("lower") if reader.has("lower") else None
    upper = reader.number("upper") if reader.has("upper") else None
    if lower is not None and upper is not None and lower > upper:
        reader.fail("upper", f"must be at least lower ({lower}), not {upper}")
    if (lower is not None and lower > 0.0) or (upper is not None and upper < 0.0):
        reader.fail("lower" if lower is not None and lower > 0.0 else "upper",
                    "the joint starts at 0, which must lie between lower and upper")
    effort = "max_torque" if kind == "revolute" else "max_force"
    motor = None
    if reader.has("motor"):
        settings = reader.child("motor")
        motor = Motor(settings.number("speed", 0.0),
                      settings.number(effort, REQUIRED, minimum=0.0))
        overflow = motor_overflow(motor.speed, motor.max_effort)
        if overflow is not None:
            settings.fail("speed", overflow)
    if kind == "prismatic":
        return PrismaticJoint(**common, axis=_direction(reader, "axis"), lower=lower,
                              upper=upper, motor=motor)
    spring = None
    if reader.has("spring"):
        settings = reader.child("spring")
        spring = RotarySpring(settings.number("stiffness", REQUIRED, minimum=0.0),
                              settings.number("damping", 0.0, minimum=0.0),
                              settings.number("rest_angle", 0.0))
    return RevoluteJoint(**common, lower=lower, upper=upper, motor=motor, spring=spring)


def _local_point(body: BodySpec, point: Vec2) -> Vec2:
    """A fixed-frame point in the body frame at the body's initial pose."""
    c, s = math.cos(body.angle), math.sin(body.angle)
    dx, dy = point[0] - body.position[0], point[1] - body.position[1]
    return (c * dx + s * dy, -s * dx + c * dy)


def frame_known(frame: str, fixed: str, points: Mapping[str, Mapping[str, Vec2]]) -> bool:
    """True if ``frame`` is ``fixed``, a body of ``points`` (body -> named points), or
    ``<body>/<point>`` of one of its named points."""
    body, _, point = frame.partition("/")
    return frame == fixed or (body in points and (not point or point in points[body]))


def _check_frame(reader: ParameterReader, key: str, frame: str, fixed: str,
                 points: Mapping[str, Mapping[str, Vec2]]) -> None:
    if frame_known(frame, fixed, points):
        return
    reader.fail(key, f"'{frame}' is not the fixed frame '{fixed}', a body, or a "
                     "declared '<body>/<point>'")


def _read_wrench_topic(name: str, reader: ParameterReader, fixed: str,
                       points: Mapping[str, Mapping[str, Vec2]]) -> WrenchTopic:
    body = _body(reader, "body", points)
    frame = reader.string("frame_id", body)
    _check_frame(reader, "frame_id", frame, fixed, points)
    topic = reader.string("topic", name)
    if not TOPIC_PATTERN.fullmatch(topic) or "//" in topic or topic.endswith("/"):
        reader.fail("topic", f"'{topic}' is not a valid ROS topic name")
    if len(topic) > 2 * NAME_MAX:
        reader.fail("topic", f"is {len(topic)} characters long, over {2 * NAME_MAX} (ROS 2 "
                             "takes 247 with the namespace)")
    return WrenchTopic(name, topic, body, frame)


def _read_command(name: str, reader: ParameterReader, fixed: str,
                  points: Mapping[str, Mapping[str, Vec2]], step_ns: int) -> WrenchCommand:
    body = _body(reader, "body", points)
    frame = reader.string("frame_id", fixed)
    _check_frame(reader, "frame_id", frame, fixed, points)
    duration_ns = _seconds_to_ns(reader, "duration", 0.0)
    short = shorter_than_a_step(duration_ns, step_ns, reader.number("duration", 0.0))
    if short is not None:
        reader.fail("duration", short)
    return WrenchCommand(
        stamp_ns=_seconds_to_ns(reader, "time", REQUIRED),
        body=body, source=reader.string("id", name), frame_id=frame,
        point=reader.vector("point", [0.0, 0.0]), force=reader.vector("force", [0.0, 0.0]),
        torque=reader.number("torque", 0.0), duration_ns=duration_ns)
