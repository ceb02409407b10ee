"""Scenes with walls, collisions and scripts in pymunk and Box2D 2.3, for timing (and in
Box2D v3 through :mod:`.box2d_v3`, which builds the same layout in its own interpreter).

:func:`scene_engine` builds a scene (its bodies with their shapes, walls, collision groups,
forces and scripted wrenches) in a peer and returns ``step(count)``, which returns the
seconds its steps took, and ``poses()`` (x, y and angle of every CM). The contact solvers
differ, so the runs are compared by cost, not by state. How each peer is set up, in what
its users would call its best honest configuration:

- Bodies at their CMs with the scene's mass and moment of inertia; each shape of a body
  (polygons, circles) as the peer's shape in the CM frame.
- Walls: long static segments along the wall lines (200 m), colliding with the bodies the
  wall lists. Collision groups: bodies collide only with the bodies they share a group
  with (collision filters of category and mask bits, one bit per wall and per set of
  groups a body is in).
- Materials: pymunk multiplies the two shapes' restitutions and frictions, so a body's
  shapes carry the square roots of its group's values and each wall its own values over
  those; Box2D 2.3 takes the square root of the product of the frictions (set the same
  way) and the larger of the restitutions, so where a wall's restitution is below the
  group's of the bodies it stops, Box2D uses the group's (the door's block on its wall:
  0.2 instead of 0).
- Gravity in the peer; every other force of the scene (springs, drags, angular damping,
  constant forces) and the scripted wrenches, each over its stamp and duration, from plain
  Python (:func:`~.force_law.make_wrenches`) set on the bodies before each step
  (``springs="python"``), or, for pymunk with ``springs="native"``, the springs as
  Chipmunk ``DampedSpring`` constraints (Box2D 2.3 has no spring element with a given
  stiffness: its soft distance joint sets a frequency relative to the joint's effective
  mass, another force law). With neither forces nor a script (the pyramids), the timed
  loop calls the peer's own step and nothing else, as its users write it.
- Joints: each revolute joint as the peer's pin (pymunk ``PivotJoint``, Box2D
  ``RevoluteJoint``) at the same two points, with its limits (pymunk ``RotaryLimitJoint``,
  Box2D's limit; one missing bound taken as a full turn beyond the start) and its motor
  (pymunk ``SimpleMotor`` with ``max_force`` the maximum torque, Box2D's motor with
  ``maxMotorTorque``); each gear joint as the peer's gear (pymunk ``GearJoint`` of the two
  bodies' angles, so only between two pins to the world; Box2D ``GearJoint`` of the two
  revolute joints, whose ``coordinate_a + ratio coordinate_b`` is the core's). Joined bodies
  do not collide unless the joint says so. Welds are laid out for Box2D v3 only; other
  joint types (sliders, rods, ropes) and rotary springs are not built: such a scene is
  refused.
- Iterations: pymunk 10 (its default), Box2D 8 velocity and 3 position (its manual's).
  Sleeping as the peers' users have it for scenes that come to rest: Box2D's default
  (on), and pymunk's ``sleep_time_threshold`` of 0.5 s (off by default); with ``sleep``
  false, off in both (the pyramid, where every engine does the same work each step).
"""
from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple, Optional

import numpy as np

from ..geometry.shapes import Circle
from ..scene.joints import GearJoint, RevoluteJoint, WeldJoint
from ..scene.load import Gravity, Scene
from .force_law import BodyCalls, make_program, make_stepper
from .reference import PlainModel

__all__ = ["SCENE_PEERS", "box2d_calls", "pymunk_calls", "scene_engine"]

SCENE_PEERS = ("pymunk", "box2d", "box2d_v3")
#: Half the length of the segment that stands for a wall, m.
WALL_HALF_LENGTH = 100.0
#: pymunk's sleep threshold where sleeping is on (its users' usual half second).
PYMUNK_SLEEP_S = 0.5

#: step(count) -> the seconds it took, poses()
Engine = tuple[Callable[[int], float], Callable[[], np.ndarray]]
Material = Optional[tuple[float, float]]  # (restitution, friction)


class _Pin(NamedTuple):
    """A revolute joint: bodies ``a`` (-1: the world) and ``b``, the anchors in their CM
    frames (the world's: fixed-frame coordinates), b's angle relative to a's at the start,
    the limits on the joint angle (zero at the start), the motor (speed, maximum torque)
    and whether the two bodies collide."""

    a: int
    anchor_a: tuple[float, float]
    b: int
    anchor_b: tuple[float, float]
    reference: float
    limits: Optional[tuple[float, float]]
    motor: Optional[tuple[float, float]]
    collide: bool


class _Gear(NamedTuple):
    """A gear joint: angle of pin ``first`` + ``ratio`` angle of pin ``second`` = 0."""

    first: int
    second: int
    ratio: float


class _Command(NamedTuple):
    """A scripted command: it pushes ``body`` from ``start`` (ns) to ``end`` with ``force``
    at ``point`` and ``torque``, in the axes of body ``frame`` (``point`` in its CM frame)
    or, for ``frame`` -1, of the fixed frame."""

    body: int
    start: int
    end: int
    frame: int
    point: tuple[float, float]
    force: tuple[float, float]
    torque: float


class _Weld(NamedTuple):
    """A weld joint: bodies ``a`` (-1: the world) and ``b`` hold their relative pose at the
    start (anchors and reference angle as a pin's); a spring-damper of ``frequency`` (Hz,
    0: rigid) and ``damping_ratio`` where the scene softens it."""

    a: int
    anchor_a: tuple[float, float]
    b: int
    anchor_b: tuple[float, float]
    reference: float
    frequency: float
    damping_ratio: float
    collide: bool


class _Wall(NamedTuple):
    start: tuple[float, float]
    end: tuple[float, float]
    category: int
    mask: int
    restitution: float
    friction: float
    stops: Material  # the material of the bodies it stops


@dataclasses.dataclass
class _Layout:
    """What both peers need: CM-frame shapes, filters, materials, forces and the script."""

    model: PlainModel           # forces from Python (gravity taken out)
    springs: PlainModel         # the same, also without springs (native springs)
    gravity: tuple[float, float]
    shapes: list[list[Any]]     # per body: Circle (CM frame) or vertex lists (CM frame)
    body_bits: list[tuple[int, int]]   # (category, mask) per body
    walls: list[_Wall]
    materials: list[Material]          # per body: its group's, None outside every group
    script: list[_Command]
    pins: list[_Pin]
    gears: list[_Gear]
    welds: list[_Weld]


def _group_material(scene: Scene, name: str) -> Material:
    groups = {(g.restitution, g.friction) for g in scene.collisions if name in g.bodies}
    if len(groups) > 1:
        raise ValueError(f"{scene.source}: body '{name}' is in groups of different materials")
    return next(iter(groups), None)


def _layout(scene: Scene) -> _Layout:
    plain = PlainModel(dataclasses.replace(scene, walls=(), collisions=(), script=()))
    model = plain.without(gravity=True)
    gravity = next((f.acceleration for f in scene.forces if isinstance(f, Gravity)), (0.0, 0.0))
    if any(f.acceleration != gravity for f in scene.forces if isinstance(f, Gravity)) or \
            any(len(f.bodies) != len(scene.bodies) for f in scene.forces
                if isinstance(f, Gravity)):
        raise ValueError(f"{scene.source}: the peers take one gravity acting on every body")
    shapes = []
    for body, (cx, cy) in zip(scene.bodies, plain.cm):
        parts: list[Any] = []
        for shape in body.shapes:
            if isinstance(shape, Circle):
                parts.append(Circle((shape.center[0] - cx, shape.center[1] - cy), shape.radius))
            else:
                parts.append([(float(x) - cx, float(y) - cy) for x, y in shape.vertices])
        shapes.append(parts)
    # Collision filters: one category bit per wall, then one per set of groups.
    names = [b.name for b in scene.bodies]
    memberships = [frozenset(g.name for g in scene.collisions if n in g.bodies) for n in names]
    kinds = list(dict.fromkeys(memberships))
    if len(scene.walls) + len(kinds) > 16:  # Box2D's filter bits
        raise ValueError(f"{scene.source}: too many walls and group sets for the peers' filters")
    wall_bit = [1 << k for k in range(len(scene.walls))]
    kind_bit = [1 << (len(scene.walls) + k) for k in range(len(kinds))]
    body_bits = []
    for name, member in zip(names, memberships):
        mask = sum(bit for bit, wall in zip(wall_bit, scene.walls) if name in wall.bodies)
        mask |= sum(bit for bit, other in zip(kind_bit, kinds) if member & other)
        body_bits.append((kind_bit[kinds.index(member)], mask))
    materials = [_group_material(scene, n) for n in names]
    walls = []
    for bit, wall in zip(wall_bit, scene.walls):
        stopped = {materials[names.index(n)] for n in wall.bodies}
        if len(stopped) > 1:
            raise ValueError(f"{scene.source}: wall '{wall.name}' stops bodies of different "
                             "materials")
        (px, py), (nx, ny) = wall.point, wall.normal
        ends = ((px - WALL_HALF_LENGTH * ny, py + WALL_HALF_LENGTH * nx),
                (px + WALL_HALF_LENGTH * ny, py - WALL_HALF_LENGTH * nx))
        mask = sum({kind_bit[kinds.index(m)] for n, m in zip(names, memberships)
                    if n in wall.bodies})
        walls.append(_Wall(*ends, bit, mask, wall.restitution, wall.friction,
                           next(iter(stopped), None)))
    pins, gears, welds = _joints(scene, plain)
    return _Layout(model, plain.without(springs=True, gravity=True), gravity, shapes,
                   body_bits, walls, materials, _script(scene, plain), pins, gears, welds)


def _joints(scene: Scene, plain: PlainModel) -> tuple[list[_Pin], list[_Gear], list[_Weld]]:
    """The scene's revolute, gear and weld joints for the peers (others refused)."""
    index = {b.name: i for i, b in enumerate(scene.bodies)}
    angle = [b.angle for b in scene.bodies]
    order = {spec.name: k for k, spec in
             enumerate(s for s in scene.joints if isinstance(s, RevoluteJoint))}
    pins, gears, welds = [], [], []
    for spec in scene.joints:
        if isinstance(spec, GearJoint):
            gears.append(_Gear(order[spec.joint_a], order[spec.joint_b], spec.ratio))
            continue
        if not isinstance(spec, (RevoluteJoint, WeldJoint)) or \
                (isinstance(spec, RevoluteJoint) and spec.spring is not None):
            raise ValueError(f"{scene.source}: joint '{spec.name}': the peers build revolute "
                             "joints (without springs), welds and gears only")
        b = index[spec.body_b]
        a = -1 if spec.body_a is None else index[spec.body_a]
        anchor_a = ((spec.point_a[0], spec.point_a[1]) if a < 0
                    else plain.local(a, spec.point_a))
        anchor_b = plain.local(b, spec.point_b)
        reference = angle[b] - (0.0 if a < 0 else angle[a])
        if isinstance(spec, WeldJoint):
            welds.append(_Weld(a, anchor_a, b, anchor_b, reference, spec.frequency,
                               spec.damping_ratio, spec.collide_connected))
            continue
        limits = None
        if spec.lower is not None or spec.upper is not None:
            limits = (-2.0 * math.pi if spec.lower is None else spec.lower,
                      2.0 * math.pi if spec.upper is None else spec.upper)
        motor = None if spec.motor is None else (spec.motor.speed, spec.motor.max_effort)
        pins.append(_Pin(a, anchor_a, b, anchor_b, reference, limits, motor,
                         spec.collide_connected))
    return pins, gears, welds


def _script(scene: Scene, plain: PlainModel) -> list[_Command]:
    index = {b.name: i for i, b in enumerate(scene.bodies)}
    points = {b.name: b.points for b in scene.bodies}
    out = []
    for command in scene.script:
        frame, _, point_name = command.frame_id.partition("/")
        end = command.stamp_ns + (command.duration_ns or scene.input_timeout_ns)
        j, point = -1, (command.point[0], command.point[1])
        if frame in index:  # body axes, from the body's origin or one of its points
            j = index[frame]
            origin = points[frame][point_name] if point_name else (0.0, 0.0)
            point = plain.local(j, (origin[0] + command.point[0], origin[1] + command.point[1]))
        out.append(_Command(index[command.body], command.stamp_ns, end, j, point,
                            (command.force[0], command.force[1]), command.torque))
    return out


def _over_root(value: float, own: float) -> float:
    """The value a wall's shape carries so that, combined with a body's ``sqrt(own)``
    (pymunk: the product; Box2D: the square root of the product of the squares), the
    contact gets ``value``."""
    return value / math.sqrt(own) if own else 0.0


def _stepper(layout: _Layout, model: PlainModel, h: float, calls: list[BodyCalls],
             wake: Callable[[int], object], advance: Callable[[], object]
             ) -> Callable[[int], float]:
    """step(count) -> the seconds it took: before each step, the Python forces of ``model``
    and the scripted wrenches go on the bodies through their ``calls`` (a pushed body
    woken by ``wake(index)``), then ``advance`` takes the peer's step."""
    program = make_program(model.springs, model.drags, model.angular, model.forces,
                           model.constant, calls)
    return make_stepper(program, layout.script, calls, wake, advance, round(h * 1e9))


def pymunk_calls(body: Any) -> BodyCalls:
    """A pymunk body's calls for the force loop (:class:`.force_law.BodyCalls`)."""
    def add_torque(tau: float) -> None:
        body.torque += tau

    return BodyCalls(body.local_to_world, body.velocity_at_world_point,
                     body.apply_force_at_world_point,
                     lambda: (*body.position, body.angle, *body.velocity,
                              body.angular_velocity), add_torque)


def box2d_calls(body: Any) -> BodyCalls:
    """A Box2D 2.3 body's calls for the force loop; a force does not wake a sleeping body
    (only a scripted push does, through the stepper's ``wake``)."""
    apply_force, apply_torque = body.ApplyForce, body.ApplyTorque
    return BodyCalls(body.GetWorldPoint, body.GetLinearVelocityFromWorldPoint,
                     lambda force, point: apply_force(force, point, False),
                     lambda: (*body.position, body.angle, *body.linearVelocity,
                              body.angularVelocity),
                     lambda tau: apply_torque(tau, False))


def _without_welds(layout: _Layout, peer: str) -> _Layout:
    if layout.welds:
        raise ValueError(f"{peer}: the bench builds no weld joints in this peer")
    return layout


def _pymunk(scene: Scene, h: float, springs: str, sleep: bool) -> Engine:
    import pymunk

    layout = _without_welds(_layout(scene), "pymunk")
    model = layout.springs if springs == "native" else layout.model
    space = pymunk.Space()
    space.iterations = 10
    space.gravity = layout.gravity
    if sleep:
        space.sleep_time_threshold = PYMUNK_SLEEP_S
    q, v = layout.model.start()
    bodies = []
    for i, parts in enumerate(layout.shapes):
        body = pymunk.Body(model.mass[i], model.inertia[i])
        body.position, body.angle = (q[i, 0], q[i, 1]), q[i, 2]
        body.velocity, body.angular_velocity = (v[i, 0], v[i, 1]), v[i, 2]
        restitution, friction = layout.materials[i] or (1.0, 1.0)
        category, mask = layout.body_bits[i]
        space.add(body)
        for part in parts:
            shape = (pymunk.Circle(body, part.radius, part.center) if isinstance(part, Circle)
                     else pymunk.Poly(body, part))
            shape.elasticity, shape.friction = math.sqrt(restitution), math.sqrt(friction)
            shape.filter = pymunk.ShapeFilter(categories=category, mask=mask)
            space.add(shape)
        bodies.append(body)
    for wall in layout.walls:
        own_restitution, own_friction = wall.stops or (1.0, 1.0)
        segment = pymunk.Segment(space.static_body, wall.start, wall.end, 0.0)
        segment.elasticity = _over_root(wall.restitution, own_restitution)
        segment.friction = _over_root(wall.friction, own_friction)
        segment.filter = pymunk.ShapeFilter(categories=wall.category, mask=wall.mask)
        space.add(segment)
    if springs == "native":
        for a, la, b, lb, k, rest, damp in layout.model.springs:
            other = space.static_body if b < 0 else bodies[b]
            space.add(pymunk.DampedSpring(bodies[a], other, la, lb, rest, k, damp))
    _pymunk_joints(pymunk, space, layout, bodies)
    # A push wakes a sleeping body, as in the core.
    step = _stepper(layout, model, h, [pymunk_calls(b) for b in bodies],
                    lambda i: bodies[i].activate(), functools.partial(space.step, h))
    return step, lambda: np.array([(*b.position, b.angle) for b in bodies])


def _pymunk_joints(pymunk: Any, space: Any, layout: _Layout, bodies: list[Any]) -> None:
    """The pins, their limits and motors, and the gears (see the module docstring)."""
    for pin in layout.pins:
        a = space.static_body if pin.a < 0 else bodies[pin.a]
        b = bodies[pin.b]
        parts = [pymunk.PivotJoint(a, b, pin.anchor_a, pin.anchor_b)]
        if pin.limits is not None:  # pymunk limits b.angle - a.angle
            parts.append(pymunk.RotaryLimitJoint(a, b, pin.reference + pin.limits[0],
                                                 pin.reference + pin.limits[1]))
        if pin.motor is not None:  # Chipmunk drives b.w - a.w to -rate
            motor = pymunk.SimpleMotor(a, b, -pin.motor[0])
            motor.max_force = pin.motor[1]
            parts.append(motor)
        for part in parts:
            part.collide_bodies = pin.collide
            space.add(part)
    for gear in layout.gears:
        first, second = layout.pins[gear.first], layout.pins[gear.second]
        if first.a >= 0 or second.a >= 0:
            raise ValueError("pymunk's GearJoint ties two bodies' angles: gears between "
                             "pins to the world only")
        # Chipmunk holds ratio angle_B - angle_A = phase; the core angle_A + r angle_B = 0
        # (from the start): ratio -r, phase -r angle_B0 - angle_A0.
        ratio = -gear.ratio
        space.add(pymunk.GearJoint(bodies[first.b], bodies[second.b],
                                   ratio * second.reference - first.reference, ratio))


#: The most vertices pybox2d takes in one polygon (b2_maxPolygonVertices is 16, exclusive).
BOX2D_MOST_VERTICES = 15


def _fan(vertices: list[Any]) -> list[list[Any]]:
    """A convex polygon as convex pieces of at most :data:`BOX2D_MOST_VERTICES` vertices
    (the gears' 24-sided rims): fans from its first vertex, each piece sharing its last
    vertex with the next. The mass is set apart, so only the outline matters."""
    if len(vertices) <= BOX2D_MOST_VERTICES:
        return [vertices]
    step = BOX2D_MOST_VERTICES - 2
    return [[vertices[0], *vertices[k:k + step + 1]]
            for k in range(1, len(vertices) - 1, step)]


def _box2d(scene: Scene, h: float, springs: str, sleep: bool) -> Engine:
    import Box2D

    if springs != "python":
        raise ValueError("Box2D 2.3 has no spring element of a given stiffness")
    layout = _without_welds(_layout(scene), "Box2D 2.3")
    model = layout.model
    world = Box2D.b2World(gravity=layout.gravity, doSleep=sleep)
    q, v = model.start()
    bodies = []
    for i, parts in enumerate(layout.shapes):
        body = world.CreateDynamicBody(position=(q[i, 0], q[i, 1]), angle=q[i, 2],
                                       linearVelocity=(v[i, 0], v[i, 1]),
                                       angularVelocity=v[i, 2], allowSleep=sleep)
        # Outside every group: restitution 0 and friction 1, so a wall's own values hold.
        restitution, friction = layout.materials[i] or (0.0, 1.0)
        category, mask = layout.body_bits[i]
        for part in parts:
            shapes = ([Box2D.b2CircleShape(pos=part.center, radius=part.radius)]
                      if isinstance(part, Circle)
                      else [Box2D.b2PolygonShape(vertices=piece) for piece in _fan(part)])
            for shape in shapes:
                body.CreateFixture(shape=shape, density=1.0, friction=friction,
                                   restitution=restitution, categoryBits=category,
                                   maskBits=mask)
        mass = Box2D.b2MassData()
        mass.mass, mass.center, mass.I = model.mass[i], (0.0, 0.0), model.inertia[i]
        body.massData = mass
        bodies.append(body)
    ground = world.CreateStaticBody()
    for wall in layout.walls:
        own_friction = (wall.stops or (0.0, 1.0))[1]
        ground.CreateEdgeFixture(vertices=[wall.start, wall.end], restitution=wall.restitution,
                                 friction=_over_root(wall.friction, own_friction) ** 2,
                                 categoryBits=wall.category, maskBits=wall.mask)
    pins = []
    for pin in layout.pins:  # Box2D's joint angle: angle_B - angle_A - referenceAngle
        lower, upper = pin.limits or (0.0, 0.0)
        speed, torque = pin.motor or (0.0, 0.0)
        pins.append(world.CreateRevoluteJoint(
            bodyA=ground if pin.a < 0 else bodies[pin.a], bodyB=bodies[pin.b],
            localAnchorA=pin.anchor_a, localAnchorB=pin.anchor_b,
            referenceAngle=pin.reference, enableLimit=pin.limits is not None,
            lowerAngle=lower, upperAngle=upper, enableMotor=pin.motor is not None,
            motorSpeed=speed, maxMotorTorque=torque, collideConnected=pin.collide))
    for gear in layout.gears:  # Box2D's coordinate_1 + ratio coordinate_2, as the core's
        first, second = pins[gear.first], pins[gear.second]
        world.CreateGearJoint(bodyA=first.bodyB, bodyB=second.bodyB, joint1=first,
                              joint2=second, ratio=gear.ratio)
    def wake(i: int) -> None:
        bodies[i].awake = True

    step = _stepper(layout, model, h, [box2d_calls(b) for b in bodies], wake,
                    functools.partial(world.Step, h, 8, 3))
    return step, lambda: np.array([(*b.position, b.angle) for b in bodies])


def scene_engine(peer: str, scene: Scene, h: float, springs: str = "python",
                 sleep: bool = True) -> Engine:
    """``scene`` built in ``peer`` (``pymunk``, ``box2d`` or ``box2d_v3``, the last in its
    own interpreter: :mod:`.box2d_v3`) at the step ``h``."""
    if peer == "box2d_v3":
        from . import box2d_v3

        if springs != "python":
            raise ValueError("Box2D v3 has no spring element of a given stiffness")
        return box2d_v3.scene_engine(scene, h, sleep)
    builder = {"pymunk": _pymunk, "box2d": _box2d}[peer]
    return builder(scene, h, springs, sleep)
