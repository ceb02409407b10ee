"""A running world changed by name: a body spawned into a scene, or deleted from it.

A spawned body is read from the YAML a scene file holds under ``bodies.<name>`` and
checked as a file's bodies are (:func:`~.load.read_body`, every parameter known, one-line
errors naming the parameter). The scene it makes is the one the same file would give with
the body declared in it:

- the body takes its place among the bodies in order of names, as a file's are read;
- gravity, drag without a point, angular damping, walls and the map whose ``bodies`` hold
  every body of the world hold the new body too (``bodies`` left out of a file means all
  of them); those that list some bodies only do not;
- it joins the collision groups the request names (each pair in one group at most, its
  polygons convex, as a file's), and no other;
- springs, constant forces and torques, joints, gears, wrench topics and scripted inputs
  never name it: a spawn cannot add them.

A deleted body leaves every list of bodies; what acted on it alone goes with it (a force
left without bodies, a constant force or torque on it), while a wall left without bodies
stays, stopping nothing, so the walls keep their places, and a collision group left with
one body or none stays, pairing nothing, so a later spawn can join it again (a file's
group needs two bodies: it would have no other use). The delete is refused, naming them,
while something ties the body to the rest of the world or to the node's inputs: a spring,
a joint (and so a gear of it), a wrench topic, a scripted input. The last body cannot be
deleted.
"""
from __future__ import annotations

import bisect
import dataclasses
import enum
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from .load import (
    AngularDampingSpec,
    CollisionGroup,
    ConstantForceSpec,
    ConstantTorqueSpec,
    DragSpec,
    ForceSpec,
    Gravity,
    Scene,
    SpringSpec,
    check_collidable,
    read_body,
)
from .names import DELETE_BODY_SERVICE, SPAWN_BODY_SERVICE
from .parameters import ParameterReader, SceneError, quoted
from .rosyaml import read_parameters_text

__all__ = ["EditKind", "WorldEdit", "spawned", "deleted", "apply_edits"]


class EditKind(enum.Enum):
    SPAWN = "spawn"
    DELETE = "delete"


class WorldEdit(NamedTuple):
    """One change of the world: a body spawned (``spec``: its YAML; ``collisions``: the
    groups it joins) or deleted."""

    kind: EditKind
    body: str
    spec: str = ""
    collisions: tuple[str, ...] = ()

    def apply(self, scene: Scene) -> Scene:
        """``scene`` with the change made; :class:`SceneError` (one line) if it is refused."""
        if self.kind is EditKind.SPAWN:
            return spawned(scene, self.body, self.spec, self.collisions)
        return deleted(scene, self.body)

    def as_data(self) -> list[Any]:
        """Plain data for a keyframe's JSON (:meth:`from_data` reads it back)."""
        return [self.kind.value, self.body, self.spec, list(self.collisions)]

    @classmethod
    def from_data(cls, data: Sequence[Any]) -> WorldEdit:
        kind, body, spec, collisions = data
        return cls(EditKind(kind), str(body), str(spec), tuple(str(c) for c in collisions))


def apply_edits(scene: Scene, edits: Sequence[WorldEdit]) -> Scene:
    """``scene`` with ``edits`` made in order."""
    for edit in edits:
        scene = edit.apply(scene)
    return scene


# ----------------------------------------------------------------------------- spawn

def _joined(bodies: tuple[str, ...], before: tuple[str, ...], after: tuple[str, ...],
            name: str) -> tuple[str, ...]:
    """A list of bodies after ``name`` was spawned: one that held the whole world (the
    bodies ``before``) holds it too, in the world's order where it had that order."""
    if set(bodies) != set(before):
        return bodies
    return after if bodies == before else (*bodies, name)


def spawned(scene: Scene, name: str, spec: str | Mapping[str, Any],
            collisions: Sequence[str] = (), source: str = SPAWN_BODY_SERVICE) -> Scene:
    """``scene`` with body ``name`` read from ``spec`` (YAML of ``bodies.<name>``, or
    that YAML's mapping read already) joining ``collisions`` (names of its collision
    groups); see the module for the rules."""
    root = ParameterReader({"name": name, "collisions": list(collisions)}, source)
    root.name("name")
    before = tuple(body.name for body in scene.bodies)
    if name in before:
        root.fail("name", f"'{name}' is already a body (bodies: {', '.join(before)})")
    if name == scene.frame_id:
        root.fail("name", f"'{name}' is the fixed frame")
    groups = root.strings("collisions")
    what = f"body '{name}' as a mapping of its parameters ({{shape: circle, ...}})"
    values = dict(spec) if isinstance(spec, Mapping) else read_parameters_text(spec, source,
                                                                               what)
    reader = ParameterReader({"bodies": {name: values}}, source)
    (_, body_reader), = reader.named_children("bodies")
    body = read_body(name, body_reader)
    reader.check_all_read()
    index = bisect.bisect([b.name for b in scene.bodies], name)
    bodies = (*scene.bodies[:index], body, *scene.bodies[index:])
    after = tuple(b.name for b in bodies)
    known = {group.name: group for group in scene.collisions}
    if len(set(groups)) != len(groups):
        root.fail("collisions", "names a collision group more than once")
    partners: dict[str, str] = {}
    for group in groups:
        if group not in known:
            root.fail("collisions", f"names no collision group {quoted(group)} (groups: "
                                    f"{', '.join(known) or 'none'})")
        for member in known[group].bodies:
            if member in partners:
                root.fail("collisions", f"bodies '{name}' and '{member}' would be in "
                                        f"collision groups '{partners[member]}' and "
                                        f"'{group}'; a pair may be in one group only")
            partners[member] = group
        check_collidable(body, group, source)

    def force(spec: ForceSpec) -> ForceSpec:
        if isinstance(spec, (Gravity, AngularDampingSpec)) or (
                isinstance(spec, DragSpec) and spec.point is None):
            return dataclasses.replace(spec, bodies=_joined(spec.bodies, before, after, name))
        return spec

    grid = scene.map
    if grid is not None:
        grid = dataclasses.replace(grid, bodies=_joined(grid.bodies, before, after, name))
        if name in grid.bodies:
            check_collidable(body, grid.file, source, kind="map")
    return dataclasses.replace(
        scene, bodies=bodies, forces=tuple(force(f) for f in scene.forces), map=grid,
        walls=tuple(dataclasses.replace(w, bodies=_joined(w.bodies, before, after, name))
                    for w in scene.walls),
        collisions=tuple(dataclasses.replace(c, bodies=(*c.bodies, name)) if c.name in groups
                         else c for c in scene.collisions))


# ----------------------------------------------------------------------------- delete

def _ties(scene: Scene, name: str) -> list[str]:
    """What holds body ``name`` to the rest of the world or to the inputs."""
    ties = [f"spring '{f.name}'" for f in scene.forces
            if isinstance(f, SpringSpec) and name in (f.body_a, f.body_b)]
    ties += [f"joint '{j.name}'" for j in scene.joints
             if name in (getattr(j, "body_a", None), getattr(j, "body_b", None))]
    ties += [f"wrench topic '{t.name}'" for t in scene.wrench_topics
             if t.body == name or t.frame_id.partition("/")[0] == name]
    ties += [f"scripted input '{c.source}'" for c in scene.script
             if c.body == name or c.frame_id.partition("/")[0] == name]
    ties += [f"sensor '{s.name}'" for s in scene.sensors if s.body == name]
    ties += [f"drive '{d.name}'" for d in scene.drives if d.body == name]
    return ties


def deleted(scene: Scene, name: str, source: str = DELETE_BODY_SERVICE,
            remedy: str = "remove those from the scene file first") -> Scene:
    """``scene`` without body ``name``; see the module for what goes with it and what
    refuses the delete (the refusal ends with ``remedy``: what the caller can do)."""
    names = [body.name for body in scene.bodies]
    if name not in names:
        raise SceneError(f"{source}: no body {quoted(name)} (bodies: {', '.join(names)})")
    if len(names) == 1:
        raise SceneError(f"{source}: '{name}' is the last body; a scene needs at least one")
    ties = _ties(scene, name)
    if ties:
        raise SceneError(f"{source}: body '{name}' is named by {', '.join(ties)}; {remedy}")

    def without(bodies: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(body for body in bodies if body != name)

    forces: list[ForceSpec] = []
    for spec in scene.forces:
        if isinstance(spec, (ConstantForceSpec, ConstantTorqueSpec)):
            if spec.body != name:
                forces.append(spec)
        elif isinstance(spec, (Gravity, DragSpec, AngularDampingSpec)):
            if without(spec.bodies):
                forces.append(dataclasses.replace(spec, bodies=without(spec.bodies)))
        else:
            forces.append(spec)
    groups: list[CollisionGroup] = [dataclasses.replace(c, bodies=without(c.bodies))
                                    for c in scene.collisions]  # each stays: see the module
    grid = scene.map and dataclasses.replace(scene.map, bodies=without(scene.map.bodies))
    return dataclasses.replace(
        scene, bodies=tuple(b for b in scene.bodies if b.name != name), forces=tuple(forces),
        map=grid,
        walls=tuple(dataclasses.replace(w, bodies=without(w.bodies)) for w in scene.walls),
        collisions=tuple(groups))
