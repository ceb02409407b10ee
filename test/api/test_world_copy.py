"""A World copied (copy.deepcopy) or pickled mid-run is a branch of the simulation: the copy
steps bit for bit as the original does from then on, with or without the compiled kernel
(whose handles are rebuilt from the plain state), and the two no longer share anything."""
from __future__ import annotations

import copy
import json
import pickle
from collections.abc import Callable

import pytest

import hecker_dynamics as hd
from hecker_dynamics.scene.load import shipped_scenes

COPIES: dict[str, Callable[[hd.World], hd.World]] = {
    "deepcopy": copy.deepcopy,
    "copy": copy.copy,  # a shallow copy sharing the simulation would step both
    "pickle": lambda world: pickle.loads(pickle.dumps(world)),
}


def same_run(a: hd.World, b: hd.World) -> None:
    assert a.simulation.time_ns == b.simulation.time_ns
    assert a.simulation.q.tobytes() == b.simulation.q.tobytes()
    assert a.simulation.v.tobytes() == b.simulation.v.tobytes()
    assert json.dumps(a.state()) == json.dumps(b.state())


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("name", shipped_scenes())
def test_a_copy_of_a_shipped_scene_goes_on_bit_for_bit(name: str, how: str) -> None:
    world = hd.World.from_scene(name)
    world.advance(0.25)
    branch = COPIES[how](world)
    same_run(world, branch)
    for w in (world, branch):
        w.advance(0.5)
    same_run(world, branch)


@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_branch_pushed_apart_leaves_the_original_alone(how: str) -> None:
    world = hd.World(gravity=(0.0, -9.81), step=0.001, integrator="semi_implicit_euler")
    world.add_wall("floor", point=(0, 0), normal=(0, 1), restitution=0.5)
    ball = world.add_body("ball", hd.Circle(0.2), mass=1.0, position=(0, 1))
    unbuilt = COPIES[how](world)  # not started: the copy can still be built on
    unbuilt.add_body("other", hd.Circle(0.1), mass=1.0, position=(1, 1))
    assert "other" not in world and len(unbuilt) == 2
    ball.apply_force((3.0, 0.0), start=0.5, duration=0.2, name="kick")
    world.advance(0.3)
    branch = COPIES[how](world)
    reference = COPIES[how](world)
    branch["ball"].apply_force((0.0, 40.0), name="lift")
    branch.add_body("spawned", hd.Box(0.2, 0.2), mass=2.0, position=(2, 1))
    for w in (world, branch, reference):
        w.advance(1.0)
    same_run(world, reference)
    assert branch["ball"].position != world["ball"].position
    assert "spawned" not in world and branch["spawned"].position[1] < 1
    assert world["ball"] is ball and branch["ball"] is not ball
    assert world.simulation is not branch.simulation


def test_a_copied_simulation_goes_on_bit_for_bit() -> None:
    sim = hd.World.from_scene("chain").simulation
    sim.advance_to(200_000_000)
    other = copy.deepcopy(sim)
    for s in (sim, other):
        s.advance_to(600_000_000)
    assert sim.q.tobytes() == other.q.tobytes() and sim.v.tobytes() == other.v.tobytes()
    assert sim.export_state() == other.export_state()


@pytest.mark.parametrize("option", ["sleep", "events"])
def test_a_copy_keeps_sleeping_islands_and_located_impacts(option: str) -> None:
    """The contact pass's warm starts and sleep timers, and the located wall impacts'
    state, are carried: a copy of a settling stack wakes and lands as the original."""
    world = hd.World(gravity=(0.0, -9.81), step=1 / 240, integrator="semi_implicit_euler",
                     **{option: True})
    world.add_wall("floor", point=(0, 0), normal=(0, 1), restitution=0.3, friction=0.5)
    for i in range(3):
        world.add_body(f"box{i}", hd.Box(0.5, 0.5), mass=1.0 + i, position=(0.1 * i, 0.3 + 0.6 * i))
    world.add_collision_group("stack", restitution=0.1, friction=0.6)
    world.advance(2.0)
    branch = copy.deepcopy(world)
    for w in (world, branch):
        w["box2"].apply_force((30.0, 0.0), point=(0.0, 2.0), duration=0.1)
        w.advance(3.0)
    same_run(world, branch)


@pytest.mark.parametrize("damage", ["NaN q", "inf v", "1e200 v", "time before start",
                                    "negative steps"])
def test_a_state_the_world_could_not_have_is_refused(damage: str) -> None:
    """set_state (and so a copy's or a keyframe's import) refuses a state with a value that
    is not finite, an energy of motion no double holds, or a clock before its start."""
    world = hd.World(gravity=(0.0, -9.81), step=0.001)
    world.add_body("ball", hd.Circle(0.2), mass=1.0, position=(0, 1))
    world.advance(0.1)
    state = world.state()
    before = json.dumps(state)
    simulation = state["simulation"]
    if damage == "NaN q":
        simulation["q"][0][1] = float("nan")
    elif damage == "inf v":
        simulation["v"][0][2] = float("inf")
    elif damage == "1e200 v":
        simulation["v"][0][0] = 1e200
    elif damage == "time before start":
        simulation["time_ns"] = simulation["start_ns"] - 5
    else:
        simulation["steps"] = -1
    with pytest.raises(ValueError, match=r"^state: not what World\.state\(\) returns "
                                         r"\(ValueError: .*\)$"):
        world.set_state(state)
    assert json.dumps(world.state()) == before


def test_a_body_of_another_world_is_refused_not_taken_by_its_name() -> None:
    """After a copy both worlds have a body 'ball': the original's Body given to the branch
    must not stand for the branch's own body of that name."""
    world = hd.World(step=0.001)
    ball = world.add_body("ball", hd.Circle(0.2), mass=1.0)
    world.add_body("post", hd.Circle(0.2), mass=1.0, position=(2, 0))
    branch = copy.deepcopy(world)
    message = r"is a Body of another World \(this world's: world\['ball'\]\)$"
    with pytest.raises(ValueError, match=r"^body_a: body 'ball' " + message):
        branch.add_spring("s", ball, body_b="post", stiffness=1.0)
    branch.step()
    with pytest.raises(ValueError, match=r"^body: body 'ball' " + message):
        branch.remove_body(ball)
    assert "ball" in branch and len(branch) == 2
