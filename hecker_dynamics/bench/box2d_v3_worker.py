"""The Box2D v3 peer's worker: builds scenes in Box2D v3 and steps them, in its own
interpreter.

Box2D v3's Python binding (``box2d-python``) installs where this package may not (Python
3.12), so :mod:`.box2d_v3` runs this file there (``python -I box2d_v3_worker.py``) and
talks to it in JSON lines: one request a line on stdin, one reply a line on stdout (an
error as ``{"error": "..."}``). It needs the standard library, the binding and the file
``force_law.py`` beside it (loaded by its path), nothing else of this package.

Requests (``op``):

- ``build``: ``scene`` (the description :func:`.box2d_v3.describe` writes), ``step`` (s),
  ``substeps``, ``sleep``, ``threads``; replies ``world`` (a handle) and ``version``.
- ``step``: ``world``, ``count``, ``block`` (0 or a number of steps); steps ``count``
  times, the Python forces and the scripted wrenches before each step, and replies
  ``wall`` (seconds of the whole loop, timed here) and, where ``block`` > 0, ``blocks``
  (seconds per step of each block of that many steps, timed within the same loop).
- ``poses``: ``world``; replies ``poses``, (x, y, angle) of every body's CM. Box2D v3 keeps
  a rotation, not an angle: each angle is unwrapped next to the one this request last
  replied (the start's at first), so it is right where no body turned half a turn since.
- ``rays``: ``world``, ``rays`` ((x, y, dx, dy) each: from (x, y) along (dx, dy), its
  length the ray's), ``repeats``; casts each ray for its closest hit ``repeats`` times and
  replies ``wall`` (seconds of all casts) and ``hits`` ((body or -1 for a wall or none
  hit, fraction, x, y) per ray, of the last pass; body None where nothing is hit).
- ``destroy``: ``world``.

The builders are tables keyed by the description's kinds (:data:`JOINTS`), so a new joint
kind is one function here and one case in :func:`.box2d_v3.describe`.
"""
from __future__ import annotations

import functools
import importlib.util
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable
from types import ModuleType
from typing import Any

from box2d._box2d import ffi, lib

__all__ = ["version", "World", "serve"]

#: The most vertices of a polygon in Box2D v3 (B2_MAX_POLYGON_VERTICES).
MOST_VERTICES = 8
#: Every category and mask bit of a filter.
ALL_BITS = (1 << 64) - 1

#: A value of the binding's C types (cffi's CData: ids, definitions, vectors); untyped.
CData = Any
#: A part of a request or of the scene's description, as JSON gives it.
Spec = dict[str, Any]
#: A polygon's vertices, (x, y) each.
Vertices = list[list[float]]


def _load_force_law() -> ModuleType:
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "force_law.py")
    spec = importlib.util.spec_from_file_location("hecker_dynamics_force_law", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


LAW = _load_force_law()


def version() -> str:
    v = lib.b2GetVersion()
    return f"{v.major}.{v.minor}.{v.revision}"


def _fan(vertices: Vertices) -> list[Vertices]:
    """A convex polygon as convex pieces of at most :data:`MOST_VERTICES` vertices (fans
    from its first vertex, each piece sharing its last vertex with the next)."""
    if len(vertices) <= MOST_VERTICES:
        return [vertices]
    step = MOST_VERTICES - 2
    return [[vertices[0], *vertices[k:k + step + 1]] for k in range(1, len(vertices) - 1, step)]


def _shape_def(material: list[float], category: int, mask: int) -> CData:
    """A shape of the given (restitution, friction) and filter. Each shape updates its
    body's mass data, as v3's users have it: that is also where v3 finds the body's extent,
    which its sleep test multiplies the spin by (the mass is set afterwards)."""
    shape = lib.b2DefaultShapeDef()
    shape.restitution, shape.friction = material
    shape.filter.categoryBits, shape.filter.maskBits = category, mask
    return shape


def _body(world: CData, spec: Spec, sleep: bool) -> CData:
    body_def = lib.b2DefaultBodyDef()
    body_def.type = lib.b2_dynamicBody
    body_def.position.x, body_def.position.y = spec["position"]
    body_def.rotation.c, body_def.rotation.s = math.cos(spec["angle"]), math.sin(spec["angle"])
    body_def.linearVelocity.x, body_def.linearVelocity.y = spec["velocity"]
    body_def.angularVelocity = spec["omega"]
    body_def.enableSleep = sleep
    body = lib.b2CreateBody(world, ffi.addressof(body_def))
    shape = _shape_def(spec["material"], spec["category"], spec["mask"])
    for cx, cy, radius in spec["circles"]:
        circle = ffi.new("b2Circle*", {"center": (cx, cy), "radius": radius})
        lib.b2CreateCircleShape(body, ffi.addressof(shape), circle)
    for vertices in spec["polygons"]:
        for piece in _fan(vertices):
            points = ffi.new("b2Vec2[]", [tuple(p) for p in piece])
            hull = lib.b2ComputeHull(points, len(piece))
            if hull.count == 0:
                raise ValueError(f"Box2D v3 refuses the polygon {piece}")
            polygon = lib.b2MakePolygon(ffi.addressof(hull), 0.0)
            lib.b2CreatePolygonShape(body, ffi.addressof(shape), ffi.addressof(polygon))
    mass = ffi.new("b2MassData*")
    mass.mass, mass.rotationalInertia = spec["mass"], spec["inertia"]
    mass.center.x = mass.center.y = 0.0  # the body's origin is its CM
    lib.b2Body_SetMassData(body, mass[0])
    return body


def _joined(joint: CData, ends: tuple[CData, CData], spec: Spec) -> CData:
    """``joint`` (a joint definition) between ``ends`` at the description's anchors, with
    its reference angle and whether the two bodies collide."""
    joint.bodyIdA, joint.bodyIdB = ends
    joint.localAnchorA.x, joint.localAnchorA.y = spec["anchor_a"]
    joint.localAnchorB.x, joint.localAnchorB.y = spec["anchor_b"]
    joint.referenceAngle = spec["reference"]
    joint.collideConnected = spec["collide"]
    return ffi.addressof(joint)


def _revolute(world: CData, ends: tuple[CData, CData], spec: Spec) -> None:
    joint = lib.b2DefaultRevoluteJointDef()
    if spec["limits"] is not None:
        joint.enableLimit = True
        joint.lowerAngle, joint.upperAngle = spec["limits"]
    if spec["motor"] is not None:
        joint.enableMotor = True
        joint.motorSpeed, joint.maxMotorTorque = spec["motor"]
    lib.b2CreateRevoluteJoint(world, _joined(joint, ends, spec))


def _weld(world: CData, ends: tuple[CData, CData], spec: Spec) -> None:
    joint = lib.b2DefaultWeldJointDef()
    joint.linearHertz = joint.angularHertz = spec["frequency"]
    joint.linearDampingRatio = joint.angularDampingRatio = spec["damping_ratio"]
    lib.b2CreateWeldJoint(world, _joined(joint, ends, spec))


def _calls(body: CData) -> Any:
    """A Box2D v3 body's calls for the force loop (force_law.BodyCalls); a force does not
    wake a sleeping body (a scripted push does, through the stepper's ``wake``)."""
    get_point, get_velocity = lib.b2Body_GetWorldPoint, lib.b2Body_GetWorldPointVelocity
    apply_force, apply_torque = lib.b2Body_ApplyForce, lib.b2Body_ApplyTorque
    position, rotation = lib.b2Body_GetPosition, lib.b2Body_GetRotation
    velocity, spin = lib.b2Body_GetLinearVelocity, lib.b2Body_GetAngularVelocity

    def point(local: tuple[float, float]) -> tuple[float, float]:
        p = get_point(body, local)
        return p.x, p.y

    def point_velocity(world: tuple[float, float]) -> tuple[float, float]:
        v = get_velocity(body, world)
        return v.x, v.y

    def state() -> tuple[float, float, float, float, float, float]:
        p, q, v = position(body), rotation(body), velocity(body)
        return p.x, p.y, math.atan2(q.s, q.c), v.x, v.y, spin(body)

    return LAW.BodyCalls(point, point_velocity,
                         lambda force, at: apply_force(body, force, at, False), state,
                         lambda tau: apply_torque(body, tau, False))


#: Joint builders by the description's ``kind``: builder(world, (body A, body B), spec).
JOINTS: dict[str, Callable[[CData, tuple[CData, CData], Spec], None]] = {
    "revolute": _revolute, "weld": _weld}


class World:
    """One scene built in Box2D v3, its bodies, and its Python forces."""

    def __init__(self, request: Spec) -> None:
        scene = request["scene"]
        self.h, self.substeps = request["step"], request.get("substeps", 4)
        sleep = request.get("sleep", True)
        threads = request.get("threads", 1)
        world_def = lib.b2DefaultWorldDef()
        world_def.gravity.x, world_def.gravity.y = scene["gravity"]
        world_def.enableSleep = sleep
        if threads > 1:  # the binding's own task scheduler
            lib.setup_threadpool(threads)
            world_def.workerCount = threads
            world_def.enqueueTask = lib.c_enqueue_tasks
            world_def.finishTask = lib.c_finish_tasks
        self.threads = threads
        self.id = lib.b2CreateWorld(ffi.addressof(world_def))
        self.bodies = [_body(self.id, spec, sleep) for spec in scene["bodies"]]
        ground_def = lib.b2DefaultBodyDef()
        ground = lib.b2CreateBody(self.id, ffi.addressof(ground_def))
        for wall in scene["walls"]:
            shape = _shape_def(wall["material"], wall["category"], wall["mask"])
            segment = ffi.new("b2Segment*", {"point1": wall["start"], "point2": wall["end"]})
            lib.b2CreateSegmentShape(ground, ffi.addressof(shape), segment)
        for spec in scene["joints"]:
            a = ground if spec["a"] < 0 else self.bodies[spec["a"]]
            JOINTS[spec["kind"]](self.id, (a, self.bodies[spec["b"]]), spec)
        self.index = {body.index1: i for i, body in enumerate(self.bodies)}
        self.angles = [spec["angle"] for spec in scene["bodies"]]
        calls = [_calls(body) for body in self.bodies]
        forces = scene["forces"]
        program = LAW.make_program(forces["springs"], forces["drags"], forces["angular"],
                                   forces["forces"], forces["constant"], calls)
        world, h, substeps, step = self.id, self.h, self.substeps, lib.b2World_Step
        self.step = LAW.make_stepper(program, scene["script"], calls,
                                     lambda i: lib.b2Body_SetAwake(self.bodies[i], True),
                                     functools.partial(step, world, h, substeps),
                                     round(self.h * 1e9))

    def run(self, count: int, block: int) -> Spec:
        """``count`` steps, timed whole, and, where ``block`` > 0, block by block within
        the same loop."""
        if block <= 0:
            return {"wall": self.step(count)}
        blocks = [self.step(block) / block for _ in range(count // block)]
        wall = sum(blocks) * block + (self.step(count % block) if count % block else 0.0)
        return {"wall": wall, "blocks": blocks}

    def poses(self) -> list[tuple[float, float, float]]:
        out = []
        for i, body in enumerate(self.bodies):
            p, q = lib.b2Body_GetPosition(body), lib.b2Body_GetRotation(body)
            angle = math.atan2(q.s, q.c)
            angle += 2.0 * math.pi * round((self.angles[i] - angle) / (2.0 * math.pi))
            self.angles[i] = angle
            out.append((p.x, p.y, angle))
        return out

    def rays(self, rays: list[list[float]], repeats: int) -> Spec:
        world, cast = self.id, lib.b2World_CastRayClosest
        query = lib.b2DefaultQueryFilter()
        query.categoryBits = query.maskBits = ALL_BITS  # rays see every shape
        pairs = [((x, y), (dx, dy)) for x, y, dx, dy in rays]
        results: list[CData] = []
        start = time.perf_counter()
        for _ in range(repeats):
            results = [cast(world, origin, translation, query) for origin, translation in pairs]
        wall = time.perf_counter() - start
        hits: list[tuple[int | None, float, float, float]] = []
        for result in results:
            if not result.hit:
                hits.append((None, 1.0, math.nan, math.nan))
                continue
            body = lib.b2Shape_GetBody(result.shapeId)
            hits.append((self.index.get(body.index1, -1), result.fraction, result.point.x,
                         result.point.y))
        return {"wall": wall, "hits": hits}

    def destroy(self) -> None:
        lib.b2DestroyWorld(self.id)
        if self.threads > 1:
            lib.cleanup_threadpool()


def serve(lines: Iterable[str], write: Callable[[str], object]) -> None:
    """Answer each request line of ``lines`` with ``write(reply line)``."""
    worlds: dict[int, World] = {}
    handles = iter(range(1, 1 << 62))
    for line in lines:
        try:
            request = json.loads(line)
            op = request["op"]
            if op == "build":
                handle = next(handles)
                worlds[handle] = World(request)
                reply: Spec = {"world": handle, "version": version()}
            elif op == "step":
                reply = worlds[request["world"]].run(request["count"], request.get("block", 0))
            elif op == "poses":
                reply = {"poses": worlds[request["world"]].poses()}
            elif op == "rays":
                reply = worlds[request["world"]].rays(request["rays"], request.get("repeats", 1))
            elif op == "destroy":
                worlds.pop(request["world"]).destroy()
                reply = {}
            elif op == "version":
                reply = {"version": version()}
            else:
                raise ValueError(f"unknown request '{op}'")
        except Exception as error:  # the parent raises it
            reply = {"error": f"{type(error).__name__}: {error}"}
        write(json.dumps(reply) + "\n")


if __name__ == "__main__":
    def _write(text: str) -> None:
        sys.stdout.write(text)
        sys.stdout.flush()

    serve(sys.stdin, _write)
