"""Bodies spawned into and deleted from a running world, through the run loop the node
drives: the scene each change makes, the carry-over of the state, the refusals, the
records and the keyframes.

The references are independent of the carry-over: a spawned body must move as the same body
declared in the scene file does, and a deleted body's neighbours as a simulation of the
file without it, started from the same state, does; both bit for bit.
"""
from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics.ros.markers import MARKER_ADD, MARKER_COLORS, MARKER_DELETE, color_slot
from hecker_dynamics.ros.names import MARKERS_TOPIC
from hecker_dynamics.ros.outputs import OutputKind, SnapshotOutputs
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.ros.session import KeyframeFields, WorldChange
from hecker_dynamics.scene import load_scene
from hecker_dynamics.scene.commands import WrenchCommand
from hecker_dynamics.scene.load import ConstantTorqueSpec, Gravity, SceneError, scene_parameters
from hecker_dynamics.scene.world import EditKind, WorldEdit, deleted, spawned

S = 1_000_000_000
BALL = "{shape: circle, radius: 0.2, mass: 2.0, position: [0.3, 4.0], velocity: [0.5, 0.0]}"
BALL_PARAMS = {"shape": "circle", "radius": 0.2, "mass": 2.0, "position": [0.3, 4.0],
               "velocity": [0.5, 0.0]}


def _file_params(name: str) -> dict[str, Any]:
    return copy.deepcopy(dict(scene_parameters(name)[1]))


def _bits(runner: Runner) -> tuple[bytes, bytes]:
    return runner.sim.q.tobytes(), runner.sim.v.tobytes()


def _same_run(a: Runner, b: Runner, until_ns: int) -> int:
    """Advance both to ``until_ns``; assert every snapshot and the final state agree bit
    for bit; return how many snapshots were compared."""
    snaps_a, snaps_b = a.advance(until_ns).snapshots, b.advance(until_ns).snapshots
    assert len(snaps_a) == len(snaps_b) > 0
    for x, y in zip(snaps_a, snaps_b):
        assert x.time_ns == y.time_ns
        assert np.array_equal(np.array(x.bodies, dtype=object), np.array(y.bodies, dtype=object))
        assert repr(x.bodies) == repr(y.bodies)  # repr tells -0.0 from 0.0
    assert _bits(a) == _bits(b)
    return len(snaps_a)


# ----------------------------------------------------------------------------- spawn

@pytest.mark.parametrize("name,collisions", [("sample", ()), ("seesaw", ("everything",))])
def test_a_body_spawned_at_the_start_moves_as_the_same_body_declared_in_the_file(
        name, collisions):
    params = _file_params(name)
    params["bodies"]["ball"] = BALL_PARAMS
    for group in collisions:
        params["collisions"][group]["bodies"].append("ball")
    declared = Runner(make_scene(params))
    spawning = Runner(load_scene(name))
    assert spawning.spawn_body("ball", BALL, collisions).accepted
    assert spawning.scene == dataclasses.replace(declared.scene, source=spawning.scene.source)
    # Long enough for the scripted kick (sample, 3 s) and the ball's landing.
    assert _same_run(spawning, declared, 4 * S) == 200


def test_a_late_spawn_carries_every_body_and_what_the_steps_carry(tmp_path):
    """Spawned at 1.5 s into the seesaw (contacts resting, warm starts held), the world
    goes on as a simulation of the file with the body, given the same state, does."""
    base = load_scene("seesaw")
    params = _file_params("seesaw")
    params["bodies"]["ball"] = BALL_PARAMS
    params["collisions"]["everything"]["bodies"].append("ball")
    runner = Runner(base)
    runner.advance(1_500_000_000)
    state = runner.sim.export_state()
    assert state["contacts"], "the seesaw rests on contacts: warm starts to carry"
    assert runner.spawn_body("ball", BALL, ["everything"]).accepted
    reference = Runner(make_scene(params))
    # The file's body order: ball first, so every index moves up by one.
    names = reference.sim.model.names
    assert names == ("ball", *(body.name for body in base.bodies))
    q, v = reference.sim.q.tolist(), reference.sim.v.tolist()
    state["q"] = [q[0]] + state["q"]
    state["v"] = [v[0]] + state["v"]
    state["contacts"] = [[[a if a < 0 else a + 1, b + 1, pa, pb], contacts]
                         for (a, b, pa, pb), contacts in state["contacts"]]
    state["divergence"].update(checked_q=state["q"], checked_v=state["v"])
    reference.sim.import_state(state)
    _same_run(runner, reference, 3 * S)


def test_a_spawn_joins_what_holds_every_body_and_nothing_else():
    door = load_scene("door")  # its forces and its wall list some bodies only
    world = spawned(door, "crate", "{shape: box, size: [0.2, 0.2], mass: 1.0}")
    assert [b.name for b in world.bodies] == ["block", "crate", "door"]
    assert world.forces == door.forces and world.walls == door.walls
    assert world.collisions == door.collisions
    sample = spawned(load_scene("sample"), "ball", BALL)
    gravity = next(f for f in sample.forces if isinstance(f, Gravity))
    assert gravity.bodies == ("ball", "left", "right")
    assert all(w.bodies == ("ball", "left", "right") for w in sample.walls)
    joined = spawned(door, "crate", "{shape: box, size: [0.2, 0.2], mass: 1.0}",
                     ["door_and_block"])
    assert joined.collisions[0].bodies == ("door", "block", "crate")


@pytest.mark.parametrize("name,spec,collisions,message", [
    ("ball", "{shape: circle, radius: -0.1, mass: 1.0}", (),
     "spawn_body: parameter 'bodies.ball.radius': must be positive, not -0.1"),
    ("ball", "{shape: circle, radius: 0.1, mass: 1.0, colour: red}", (),
     "spawn_body: parameter 'bodies.ball.colour': is not a known parameter here"),
    ("ball", "{shape: circle, radius: 0.1}", (),
     "spawn_body: parameter 'bodies.ball.mass': is required"),
    ("ball", "{shape: circle, radius: 0.1, mass: 1.0, position: [1, 0.0]}", (),
     "mixes integers and doubles"),
    ("ball", "{shape: circle, radius: 0.1, mass: 1.0", (), "spawn_body: cannot read the text"),
    ("ball", "[1.0, 2.0]", (), "expected body 'ball' as a mapping"),
    ("plank", BALL, (), "spawn_body: parameter 'name': 'plank' is already a body"),
    ("world", BALL, (), "'world' is the fixed frame"),
    ("a b", BALL, (), "spawn_body: parameter 'name': 'a b' is not a valid name"),
    ("ball", BALL, ("walls",), "names no collision group 'walls' (groups: everything)"),
    ("ball", BALL, ("everything", "everything"), "more than once"),
    ("hook", "{shape: polygon, vertices: [0.0, 0.0, 2.0, 0.0, 2.0, 2.0, 1.0, 0.5, 0.0, 2.0], "
             "mass: 1.0}", ("everything",), "a polygon that collides must be convex"),
])
def test_a_bad_spawn_is_refused_in_one_line_as_a_scene_file_is(name, spec, collisions,
                                                                message):
    runner = Runner(load_scene("seesaw"), record=True)
    runner.advance(S // 2)
    runner.take_records()
    before = runner.sim.export_state()
    record = runner.spawn_body(name, spec, collisions)
    assert not record.accepted and message in record.reason
    assert "\n" not in record.reason
    assert runner.sim.export_state() == before and runner.scene is runner.base_scene
    assert runner.take_records() == [record] and record.kind is WorldChange.SPAWN
    assert record.spec == spec and record.collisions == tuple(collisions)


def test_a_pair_in_two_groups_is_refused():
    params = {"bodies": {"a": {"shape": "circle", "radius": 0.1, "mass": 1.0},
                         "b": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                               "position": [1.0, 0.0]},
                         "d": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                               "position": [2.0, 0.0]}},
              "collisions": {"one": {"bodies": ["a", "b"]}, "two": {"bodies": ["d", "a"]}}}
    with pytest.raises(SceneError, match="bodies 'c' and 'a' would be in collision groups "
                                         "'one' and 'two'"):
        spawned(make_scene(params), "c", "{shape: circle, radius: 0.1, mass: 1.0}",
                ["one", "two"])


# ----------------------------------------------------------------------------- delete

def test_a_deleted_bodys_neighbours_move_as_if_it_never_existed():
    """The seesaw's load deleted at 0.3 s, while it rests on the plank: the plank, the
    weight and the wall block go on as a simulation of the file without the load, started
    from the same state (the warm starts of the contacts that stay, renumbered), does."""
    runner = Runner(load_scene("seesaw"))
    runner.advance(300_000_000)
    state = runner.sim.export_state()
    load = runner.sim.model.index["load"]
    assert load == 0 and any(0 in pair[:2] for pair, _ in state["contacts"])
    assert runner.delete_body("load").accepted
    params = _file_params("seesaw")
    del params["bodies"]["load"]
    params["collisions"]["everything"]["bodies"].remove("load")
    reference = Runner(make_scene(params))
    state["q"], state["v"] = state["q"][1:], state["v"][1:]
    state["contacts"] = [[[a if a < 0 else a - 1, b - 1, pa, pb], contacts]
                         for (a, b, pa, pb), contacts in state["contacts"]
                         if a != 0 and b != 0]
    assert state["contacts"], "warm starts of the other bodies stay"
    state["divergence"].update(checked_q=state["q"], checked_v=state["v"])
    reference.sim.import_state(state)
    _same_run(runner, reference, 2 * S)


def test_delete_removes_the_body_from_every_list_and_what_acts_on_it_alone():
    params = _file_params("door")
    params["forces"]["spin"] = {"type": "constant_torque", "body": "block", "torque": 1.0}
    del params["script"]
    world = deleted(make_scene(params), "block")
    assert [b.name for b in world.bodies] == ["door"]
    assert not any(isinstance(f, ConstantTorqueSpec) for f in world.forces)
    assert [f.name for f in world.forces] == ["hinge_friction"]  # drag: no bodies
    assert world.walls[0].bodies == ()  # the wall stays, stopping nothing
    assert [(c.name, c.bodies) for c in world.collisions] == [("door_and_block", ("door",))]


def _pair_on_a_line(walls: bool) -> dict[str, Any]:
    """Ball 'a' rolling at 1 m/s towards 'b', both in group 'pile' (and in a box of walls)."""
    ball = {"shape": "circle", "radius": 0.1, "mass": 1.0}
    params: dict[str, Any] = {
        "bodies": {"a": {**ball, "velocity": [1.0, 0.0]}, "b": {**ball, "position": [1.0, 0.0]}},
        "collisions": {"pile": {"bodies": ["a", "b"], "restitution": 1.0}}}
    if walls:
        params["walls"] = {"right": {"point": [3.0, 0.0], "normal": [-1.0, 0.0]}}
    return params


@pytest.mark.parametrize("walls", [False, True])
def test_a_group_left_with_one_body_stays_inert_and_takes_a_later_spawn(walls):
    """'b' deleted at 0.2 s leaves group 'pile' with 'a' alone: the group stays, 'a' goes
    on bit for bit as in the file without 'b' (and the group, which a file refuses with one
    body), from the same state; a body spawned into the group later collides with 'a'."""
    runner = Runner(make_scene(_pair_on_a_line(walls)))
    runner.advance(S // 5)
    state = runner.sim.export_state()
    assert runner.delete_body("b").accepted
    assert [(c.name, c.bodies) for c in runner.scene.collisions] == [("pile", ("a",))]
    params = _pair_on_a_line(walls)
    del params["bodies"]["b"], params["collisions"]
    reference = Runner(make_scene(params))
    state["q"], state["v"] = state["q"][:1], state["v"][:1]
    state["contacts"] = [] if walls else None
    state["divergence"].update(checked_q=state["q"], checked_v=state["v"])
    reference.sim.import_state(state)
    assert (runner.sim.model.contacts is None) is not walls
    _same_run(runner, reference, S // 2)
    assert runner.spawn_body("c", "{shape: circle, radius: 0.1, mass: 1.0, "
                                  "position: [1.0, 0.0]}", ["pile"]).accepted
    runner.advance(S)
    assert runner.sim.v[0, 0] < 0.5 < runner.sim.v[1, 0]  # 'a' struck 'c'


def test_a_group_left_with_no_body_stays_and_pairs_its_next_two():
    params = _pair_on_a_line(walls=True)
    params["bodies"]["rock"] = {"shape": "circle", "radius": 0.1, "mass": 1.0,
                                "position": [-2.0, 0.0]}
    runner = Runner(make_scene(params))
    runner.advance(S // 5)
    assert runner.delete_body("a").accepted and runner.delete_body("b").accepted
    assert [(c.name, c.bodies) for c in runner.scene.collisions] == [("pile", ())]
    runner.advance(S // 2)
    for name, x, vx in (("d", 0.0, 1.0), ("e", 1.0, 0.0)):
        spec = (f"{{shape: circle, radius: 0.1, mass: 1.0, position: [{x}, 0.0], "
                f"velocity: [{vx}, 0.0]}}")
        assert runner.spawn_body(name, spec, ["pile"]).accepted
    runner.advance(2 * S)
    assert runner.sim.model.names == ("d", "e", "rock")
    assert runner.sim.v[0, 0] < 0.5 < runner.sim.v[1, 0]  # 'd' struck 'e'


@pytest.mark.parametrize("scene,body,message", [
    ("sample", "left", "body 'left' is named by spring 'link', scripted input 'kick'"),
    ("seesaw", "plank", "joint 'pin'"),
    ("ship", "ship", "the last body"),
    ("seesaw", "ghost", "no body 'ghost' (bodies: load, plank, wall_block, weight)"),
])
def test_a_delete_is_refused_while_something_ties_the_body(scene, body, message):
    runner = Runner(load_scene(scene), record=True)
    runner.take_records()
    before = runner.sim.export_state()
    record = runner.delete_body(body)
    assert not record.accepted and message in record.reason and "\n" not in record.reason
    assert runner.sim.export_state() == before and runner.take_records() == [record]


def test_a_joint_and_a_wrench_topic_refuse_the_delete():
    params = {"bodies": {"a": {"shape": "circle", "radius": 0.1, "mass": 1.0},
                         "b": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                               "position": [1.0, 0.0]},
                         "c": {"shape": "circle", "radius": 0.1, "mass": 1.0}},
              "joints": {"pin": {"type": "revolute", "body_a": "a", "body_b": "b",
                                 "point_a": [1.0, 0.0]}},
              "wrench_topics": {"push": {"body": "a", "frame_id": "c"}}}
    scene = make_scene(params)
    with pytest.raises(SceneError, match="'b' is named by joint 'pin'"):
        deleted(scene, "b")
    with pytest.raises(SceneError, match="'c' is named by wrench topic 'push'"):
        deleted(scene, "c")


def test_commands_on_a_deleted_body_or_in_its_frame_are_dropped():
    runner = Runner(load_scene("seesaw"), play_script=False)
    for body, frame in (("load", "world"), ("plank", "load"), ("weight", "world")):
        runner.sim.push(WrenchCommand(0, body, "src", frame, (0.0, 0.0), (1.0, 2.0), 0.5, 0))
        runner.sim.push(WrenchCommand(S, body, "later", frame, (0.0, 0.0), (1.0, 0.0), 0.0, 0))
    runner.advance(S // 10)
    assert runner.delete_body("load").accepted
    inputs = runner.sim.export_state()["inputs"]
    assert [c["body"] for c in inputs["active"]] == ["weight"]
    assert [entry[2]["body"] for entry in inputs["pending"]] == ["weight"]


# ----------------------------------------------------------------------------- both

def test_a_spawn_undone_at_once_changes_nothing():
    plain, edited = Runner(load_scene("seesaw")), Runner(load_scene("seesaw"))
    plain.advance(S)
    edited.advance(S)
    assert edited.spawn_body("ball", BALL, ["everything"]).accepted
    assert edited.delete_body("ball").accepted
    assert edited.sim.model.names == plain.sim.model.names
    _same_run(plain, edited, 3 * S)


def test_the_same_change_at_the_same_instant_gives_the_same_bits():
    runs = []
    for _ in range(2):
        runner = Runner(load_scene("seesaw"))
        runner.advance(700_000_000)
        runner.spawn_body("ball", BALL, ["everything"])
        runner.advance(S)
        runner.delete_body("load")
        runner.advance(2 * S)
        runs.append(_bits(runner))
    assert runs[0] == runs[1]


def test_a_keyframe_after_a_spawn_restores_that_world_and_goes_on_alike():
    runner = Runner(load_scene("sample"), record=True, keyframe_period_ns=S // 2)
    runner.advance(S // 4)
    runner.spawn_body("ball", BALL)
    runner.advance(S)
    runner.delete_body("ball")
    runner.spawn_body("dart", "{shape: box, size: [0.3, 0.05], mass: 0.5, position: [0.0, 3.0]}")
    runner.advance(2 * S)
    keyframes = [r for r in runner.take_records() if isinstance(r, KeyframeFields)]
    assert [k.bodies for k in keyframes] == [("left", "right"), ("ball", "left", "right"),
                                             ("ball", "left", "right"),
                                             ("dart", "left", "right"),
                                             ("dart", "left", "right")]
    assert "world" not in keyframes[0].state
    for keyframe in keyframes:
        replay = Runner(load_scene("sample"), record=True, keyframe_period_ns=S // 2)
        replay.restore(keyframe)
        assert replay.sim.model.names == keyframe.bodies
        assert replay.keyframe() == keyframe
    replay.advance(3 * S)
    runner.advance(3 * S)
    assert _bits(replay) == _bits(runner)
    assert replay.edits == runner.edits == [
        WorldEdit(EditKind.SPAWN, "ball", BALL), WorldEdit(EditKind.DELETE, "ball"),
        WorldEdit(EditKind.SPAWN, "dart", "{shape: box, size: [0.3, 0.05], mass: 0.5, "
                                          "position: [0.0, 3.0]}")]


def test_a_body_deleted_and_spawned_again_at_one_instant_is_a_new_body():
    """delete_body then spawn_body of 'ball' at one instant (a held 5 N tug on the old
    ball, sliding on a frictionless floor, its contact warm-started): the new ball starts
    where its YAML puts it, at rest, without the tug; a keyframe after the edits, and one
    before them with the edits made again, go on bit for bit alike."""
    ball = {"shape": "circle", "radius": 0.1, "mass": 1.0, "position": [0.0, 0.1],
            "velocity": [0.5, 0.0]}
    scene = make_scene({"bodies": {"ball": ball, "box": {**ball, "position": [1.0, 0.1],
                                                         "velocity": [0.0, 0.0]}},
                        "forces": {"g": {"type": "gravity"}},
                        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                                            "friction": 0.0}}})
    again = "{shape: circle, radius: 0.1, mass: 1.0, position: [-2.0, 0.1]}"
    runner = Runner(scene, play_script=False)
    runner.sim.push(WrenchCommand(0, "ball", "tug", "world", (0.0, 0.0), (5.0, 0.0), 0.0, 0))
    runner.advance(S // 20)
    before = runner.keyframe()
    assert runner.sim.export_state()["contacts"], "the old ball rests on the floor"
    assert runner.delete_body("ball").accepted and runner.spawn_body("ball", again).accepted
    assert runner.sim.q[0].tolist() == [-2.0, 0.1, 0.0] and not runner.sim.v[0].any()
    assert runner.sim.export_state()["inputs"]["active"] == []
    after = runner.keyframe()
    restored, replayed = Runner(scene, play_script=False), Runner(scene, play_script=False)
    restored.restore(after)
    replayed.restore(before)
    assert replayed.delete_body("ball").accepted and replayed.spawn_body("ball", again).accepted
    assert replayed.keyframe() == after
    for run in (runner, restored, replayed):
        run.advance(S)
    assert _bits(runner) == _bits(restored) == _bits(replayed)
    assert runner.sim.v[0, 0] == 0.0  # no tug on the new ball


def test_a_restart_returns_to_the_scene_given():
    runner = Runner(load_scene("seesaw"), record=True)
    runner.advance(S)
    runner.spawn_body("ball", BALL)
    runner.delete_body("load")
    runner.restart(5 * S)
    fresh = Runner(load_scene("seesaw"), start_ns=5 * S)
    assert runner.scene is runner.base_scene and runner.edits == []
    assert runner.sim.model.names == ("load", "plank", "wall_block", "weight")
    _same_run(runner, fresh, 6 * S)


def test_changes_are_refused_before_the_start():
    runner = Runner(load_scene("sample"), started=False, record=True)
    assert "has not started" in runner.spawn_body("ball", BALL).reason
    assert "has not started" in runner.delete_body("left").reason


# ----------------------------------------------------------------------------- RViz markers

def _with_markers(name: str) -> Any:
    params = _file_params(name)
    params.setdefault("publish", {})["markers"] = True
    return make_scene(params)


def _markers_of(outputs: SnapshotOutputs, runner: Runner) -> dict[tuple[str, int], Any]:
    """The ADD markers the outputs publish for the runner's state, by namespace and id."""
    (array,) = [o.fields for o in outputs(runner.sim.snapshot()) if o.topic == MARKERS_TOPIC]
    assert {m.action for m in array} == {MARKER_ADD}
    return {(m.ns, m.id): m for m in array}


def test_a_deleted_body_gets_a_delete_marker_once_and_the_others_keep_theirs():
    """The seesaw's load deleted: one MarkerArray of DELETE markers, one per marker the
    load had (ns "load"), and none for the bodies that stay; the next world change that
    leaves the load gone sends nothing for it again."""
    runner = Runner(_with_markers("seesaw"))
    runner.advance(300_000_000)
    before = SnapshotOutputs(runner.scene)
    shown = _markers_of(before, runner)
    assert runner.delete_body("load").accepted
    after = SnapshotOutputs(runner.scene, base=runner.base_scene)
    (gone,) = after.markers_gone(before, runner.sim.time_ns)
    assert gone.topic == MARKERS_TOPIC and gone.kind is OutputKind.MARKERS
    load_keys = {key for key in shown if key[0] == "load"}
    assert load_keys and [(m.ns, m.id) for m in gone.fields] == sorted(load_keys)
    assert {m.action for m in gone.fields} == {MARKER_DELETE}
    assert {m.header for m in gone.fields} == {(0, 300_000_000, runner.scene.frame_id)}
    kept = _markers_of(after, runner)
    assert set(kept) == set(shown) - load_keys
    # The same shapes, poses, points and colours as before the delete: colours come from
    # the scene the world started as, where numbering the bodies of the world left (the
    # seesaw's first body gone) would shift every other body's colour.
    for key, marker in kept.items():
        assert marker == shown[key], key
    renumbered = _markers_of(SnapshotOutputs(runner.scene), runner)
    assert all(renumbered[key].color != shown[key].color for key in kept)
    assert after.markers_gone(after, runner.sim.time_ns) == []
    assert runner.spawn_body("ball", BALL).accepted
    spawned_outputs = SnapshotOutputs(runner.scene, base=runner.base_scene)
    assert spawned_outputs.markers_gone(after, runner.sim.time_ns) == []
    ball = [m for key, m in _markers_of(spawned_outputs, runner).items() if key[0] == "ball"]
    assert {m.color for m in ball} == {
        MARKER_COLORS[color_slot("ball", runner.base_scene) % len(MARKER_COLORS)][:3] + (0.5,),
        MARKER_COLORS[color_slot("ball", runner.base_scene) % len(MARKER_COLORS)]}


def test_a_restart_deletes_the_markers_of_the_spawned_bodies_alone():
    runner = Runner(_with_markers("seesaw"), record=True)
    runner.advance(S)
    assert runner.spawn_body("ball", BALL).accepted
    spawned = SnapshotOutputs(runner.scene)
    runner.restart(5 * S)
    (gone,) = SnapshotOutputs(runner.scene).markers_gone(spawned, runner.sim.time_ns)
    assert {(m.ns, m.action) for m in gone.fields} == {("ball", MARKER_DELETE)}
    assert len(gone.fields) == 2  # a circle's disc and its radius line


def test_no_delete_markers_where_the_scene_publishes_none():
    runner = Runner(load_scene("seesaw"))
    runner.advance(S)
    before = SnapshotOutputs(runner.scene)
    assert runner.delete_body("load").accepted
    assert SnapshotOutputs(runner.scene).markers_gone(before, runner.sim.time_ns) == []
