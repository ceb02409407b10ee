"""The World API against closed forms (force: Eq. 5, torque: Eq. 11, moment of inertia:
Eq. 13, angular acceleration: Eq. 14), against the scene loader (a World built in Python
and the same scene file step bit for bit alike), its state round trip, and its one-line
errors."""
from __future__ import annotations

import dataclasses
import json
import math
import re
import sys
import threading

import numpy as np
import pytest
from scene_builders import EVERY_FORCE, make_scene, write_scene
from test_docs import EVERY_FEATURE

import hecker_dynamics as hd
from hecker_dynamics.geometry.shapes import Circle as Disc
from hecker_dynamics.geometry.shapes import box as box_polygon
from hecker_dynamics.geometry.shapes import mass_properties
from hecker_dynamics.scene.world import EditKind, WorldEdit, deleted, spawned

# Velocity Verlet integrates a constant acceleration exactly, so what is left is round-off:
# a few ulps of the largest term per step, over a few thousand steps.
ROUND_OFF = 1e-11


def free_world(**options: object) -> hd.World:
    return hd.World(step=1 / 256, integrator="velocity_verlet", **options)  # type: ignore[arg-type]


def test_mass_properties_are_the_integrated_ones() -> None:
    world = free_world()
    plank = world.add_body("plank", hd.Box(2.0, 0.5), mass=3.0)
    disc = world.add_body("disc", hd.Circle(0.4), density=10.0)
    assert plank.mass == mass_properties([box_polygon(2.0, 0.5)], [3.0]).mass == 3.0
    assert plank.moment_of_inertia == pytest.approx(3.0 * (4.0 + 0.25) / 12, rel=1e-15)
    assert disc.mass == pytest.approx(10.0 * math.pi * 0.16, rel=1e-15)
    assert disc.moment_of_inertia == pytest.approx(disc.mass * 0.16 / 2, rel=1e-15)
    compound = world.add_body("hammer", [hd.Box(1.0, 0.1, center=(0.5, 0.0)),
                                         hd.Circle(0.2, center=(1.0, 0.0), density=5.0)],
                              density=1.0)
    parts = mass_properties([box_polygon(1.0, 0.1, (0.5, 0.0)), Disc((1.0, 0.0), 0.2)],
                            [1.0, 5.0])
    assert (compound.mass, compound.center_of_mass, compound.moment_of_inertia) == \
        (parts.mass, parts.center_of_mass, parts.moment_of_inertia)


def test_constant_force_at_the_cm_is_uniform_acceleration() -> None:
    """x = x0 + v0 t + F t^2 / (2 m) (Eq. 5); a force through the CM along its path makes
    no torque (Eq. 11), so the body does not turn at all."""
    world = free_world()
    body = world.add_body("puck", hd.Circle(0.5), mass=2.0, position=[1, 2],
                          velocity=np.array([0.5, 0.0]))
    body.apply_force((3.0, 0.0))
    world.advance(4.0)
    t = world.time
    assert t == 4.0
    assert body.position[0] == pytest.approx(1.0 + 0.5 * t + 3.0 * t * t / 4.0, rel=ROUND_OFF)
    assert body.position[1] == 2.0
    assert body.velocity[0] == pytest.approx(0.5 + 1.5 * t, rel=ROUND_OFF)
    assert body.angle == 0.0 and body.angular_velocity == 0.0


def test_torque_at_a_point_turns_as_tau_over_i() -> None:
    """A thruster fixed to the body (frame="body") off the CM: tau = perp(r) . F (Eq. 11)
    is constant, angular acceleration tau / I (Eq. 14): omega = tau t / I,
    theta = tau t^2 / (2 I)."""
    world = free_world()
    body = world.add_body("plate", hd.Box(1.0, 0.5), mass=4.0)
    body.apply_force((0.0, 2.0), point=(0.5, 0.0), frame="body")
    world.advance(1.0)
    tau, inertia = 0.5 * 2.0, 4.0 * (1.0 + 0.25) / 12
    assert body.angular_velocity == pytest.approx(tau / inertia, rel=ROUND_OFF)
    assert body.angle == pytest.approx(tau / (2 * inertia), rel=ROUND_OFF)


def test_torque_free_spin_keeps_the_cm_and_omega() -> None:
    """No force: no angular acceleration (Eq. 14), so omega stays; the CM moves uniformly,
    the body frame's origin, off the CM, circles it, and velocity_at(CM) is the CM's (a body
    point's velocity, Eq. 9)."""
    world = free_world()
    body = world.add_body("arm", hd.Box(1.0, 0.2, center=(0.3, 0.0)), mass=1.0,
                          velocity=(1.0, -2.0), angular_velocity=3.0)
    cm0 = body.world_point(body.center_of_mass)
    cm_velocity = body.velocity_at(body.center_of_mass)
    assert cm_velocity == pytest.approx((1.0, -2.0 + 3.0 * 0.3), rel=1e-15)
    world.advance(2.0)
    assert body.angular_velocity == 3.0
    cm = body.world_point(body.center_of_mass)
    for axis in (0, 1):
        assert cm[axis] == pytest.approx(cm0[axis] + cm_velocity[axis] * 2.0, abs=ROUND_OFF)
    theta = math.remainder(6.0, 2 * math.pi)
    assert body.angle == pytest.approx(theta, abs=ROUND_OFF)


def test_timed_held_cleared_and_scheduled_forces() -> None:
    world = free_world()
    a = world.add_body("a", hd.Circle(0.1), mass=2.0)
    b = world.add_body("b", hd.Circle(0.1), mass=2.0, position=(5.0, 0.0))
    a.apply_force((4.0, 0.0), duration=0.25)  # an impulse of 1 N s
    b.apply_force((4.0, 0.0), start=0.5)  # held from t = 0.5 s
    world.advance(1.0)
    assert a.velocity == (0.5, 0.0)
    assert b.velocity[0] == pytest.approx(2.0 * 0.5, rel=ROUND_OFF)
    b.clear_forces()
    speed = b.velocity[0]
    world.step(0.5)
    assert b.velocity[0] == speed


@pytest.mark.parametrize("python", [False, True], ids=["kernel", "python"])
def test_a_force_without_a_name_replaces_no_force_of_any_name(python) -> None:
    """A force applied without a name adds to what acts, whatever the others are named:
    it took the name force1, force2, ... by a count of its own, so after a force the user
    named "force1" (or pushed from a source "force2", or scheduled as "force3") the next
    one replaced it and a puck pushed by (1, 0) and (0, 1) N for 1 s went at (0, 1) m/s.
    Now it takes the count's first name that no force on the body holds. Constant forces
    on a free 1 kg puck: v = F t (Eq. 5), exact under velocity Verlet but for round-off."""
    world = free_world()
    puck = world.add_body("puck", hd.Circle(0.1), mass=1.0)
    if python:
        world.simulation.model.use_python()
    puck.apply_force((1.0, 0.0), name="force1")  # held
    world.push(hd.WrenchCommand(0, "puck", "force2", "world", (0.0, 0.0), (0.0, 2.0), 0.0, 0))
    puck.apply_force((0.0, 4.0), start=0.5, duration=0.5, name="force3")
    puck.apply_force((0.0, 1.0))  # force4
    puck.apply_force((2.0, 0.0), duration=1.0)  # force5
    assert sorted(world._applied["puck"]) == [f"force{n}" for n in (1, 3, 4, 5)]
    world.advance(1.0)
    assert puck.velocity == pytest.approx((1.0 + 2.0, 2.0 + 4.0 * 0.5 + 1.0), rel=ROUND_OFF)
    puck.apply_force((0.0, -1.0), name="force4")  # a name given replaces what holds it
    world.step(1.0)
    assert puck.velocity == pytest.approx((3.0 + 1.0, 5.0 + 2.0 - 1.0), rel=ROUND_OFF)


def sample_in_python(integrator: str = "semi_implicit_euler") -> hd.World:
    """config/sample.yaml, written with the API (with ``integrator``)."""
    world = hd.World(gravity=(0.0, -9.81), step=0.001, integrator=integrator)
    for name, point, normal in (("floor", (0, 0), (0, 1)), ("ceiling", (0, 5), (0, -1)),
                                ("left_wall", (-3, 0), (1, 0)), ("right_wall", (3, 0), (-1, 0))):
        world.add_wall(name, point=point, normal=normal, restitution=0.8, friction=0.2)
    left = world.add_body("left", hd.Box(0.8, 0.4), mass=1.0, position=(-1.0, 2.5), angle=0.3,
                          velocity=(1.5, 0.0), angular_velocity=2.0, points={"hook": (0.4, 0)})
    right = world.add_body("right", hd.Box(0.6, 0.6), mass=1.5, position=(1.0, 3.0),
                           angle=-0.2, velocity=(-0.5, 1.0), points={"hook": (-0.3, 0.3)})
    world.add_spring("link", left, "hook", right, "hook", stiffness=50, rest_length=1,
                     damping=0.2)
    left.apply_force((0.0, 60.0), point=(0.4, 0.2), frame="body", duration=0.1, start=3.0)
    return world


def door_in_python() -> hd.World:
    """config/door.yaml (a revolute joint, a wall, a collision group, drag, damping and
    forces at a named point), written with the API."""
    world = hd.World(step=0.001, integrator="semi_implicit_euler")
    door = world.add_body("door", hd.Box(1.0, 0.06), mass=20.0, position=(0.0, 0.5),
                          angle=1.5708, points={"hinge": (-0.5, 0.0), "handle": (0.45, 0.0)})
    block = world.add_body("block", hd.Box(0.4, 0.4), mass=300.0, position=(0.75, -0.26))
    world.add_angular_damping("hinge_friction", 2.0, [door])
    world.add_drag("floor_friction", 3000.0, [block])
    world.add_revolute_joint("hinge", None, door, point_b="hinge")
    world.add_wall("room_wall", point=(0.0, -0.46), normal=(0.0, 1.0), restitution=0.0,
                   friction=0.6, bodies=[block])
    world.add_collision_group("door_and_block", [door, block], restitution=0.2, friction=0.5)
    door.apply_force((0.0, -40.0), point="handle", frame="body", duration=1.5, start=0.5)
    door.apply_force((0.0, -200.0), point="handle", frame="body", duration=2.0, start=3.0)
    return world


@pytest.mark.parametrize("name, build", [("sample", sample_in_python),
                                         ("door", door_in_python)])
def test_python_and_yaml_are_one_scene_and_one_trajectory(name, build) -> None:
    world = build()
    loaded = hd.load_scene(name)
    same = dataclasses.replace(world.scene, source=loaded.source, script=loaded.script,
                               input_timeout_ns=loaded.input_timeout_ns,
                               duration_ns=loaded.duration_ns)
    assert same == loaded
    end = loaded.duration_ns
    reference = hd.Simulation(loaded)
    reference.play(loaded.script, end, keep=False)
    from_file = hd.World.from_scene(name)
    for built in (world, from_file):
        built.advance(end * 1e-9)
        assert built.simulation.time_ns == reference.time_ns
        assert built.simulation.q.tobytes() == reference.q.tobytes()
        assert built.simulation.v.tobytes() == reference.v.tobytes()


def test_state_round_trip_is_bit_exact() -> None:
    world = sample_in_python()
    world.advance(2.9)  # the kick is still scheduled
    state = json.loads(json.dumps(world.state()))
    other = sample_in_python()
    other.set_state(state)
    assert other.state() == state
    for w in (world, other):
        w.advance(4.0)
    assert world.simulation.q.tobytes() == other.simulation.q.tobytes()
    assert world.simulation.v.tobytes() == other.simulation.v.tobytes()
    assert world["left"].position == other["left"].position
    later = world.state()
    world.set_state(state)  # back to before the kick, which acts again
    world.advance(4.0)
    assert world.state() == later


DAMAGES = {
    "no q": lambda sim: sim.pop("q"),
    "a body short": lambda sim: sim.__setitem__("v", sim["v"][:-1]),
    "q of text": lambda sim: sim["q"][0].__setitem__(0, "far"),
    # numpy reads the text '1' and the boolean True as 1.0
    "q of digits": lambda sim: sim["q"][0].__setitem__(0, "1"),
    "v of a boolean": lambda sim: sim["v"][1].__setitem__(2, True),
    # a clock off the instants its steps reach
    "a clock between steps": lambda sim: sim.__setitem__("time_ns", sim["time_ns"] + 1),
    "steps the clock never took": lambda sim: sim.__setitem__("steps", sim["steps"] + 5),
    "a clock in floats": lambda sim: sim.__setitem__("time_ns", float(sim["time_ns"])),
    # dopri5's next sub-step size: NaN was taken, 0 failed the next step
    "a sub-step size of NaN": lambda sim: sim["integrator"].__setitem__("substep_size",
                                                                         float("nan")),
    "a sub-step size of 0": lambda sim: sim["integrator"].__setitem__("substep_size", 0.0),
    # the divergence guard's budget and last checked state: NaN bounded nothing (the next
    # step reported a divergence "over nan J"), and a halt would have kept a NaN state
    "a budget of NaN": lambda sim: sim["divergence"]["bound"].__setitem__(
        "root", [float("nan")] * len(sim["divergence"]["bound"]["root"])),
    "a worst ratio of NaN": lambda sim: sim["divergence"]["bound"].__setitem__(
        "worst_ratio", float("nan")),
    "a checked state of NaN": lambda sim: sim["divergence"]["checked_v"][0].__setitem__(
        1, float("nan")),
}


@pytest.mark.parametrize("damage", [*DAMAGES, "a bad schedule", "a negative count"])
def test_a_damaged_state_is_refused_in_one_line_and_changes_nothing(damage) -> None:
    world = sample_in_python(integrator="dopri5") if "sub-step" in damage \
        else sample_in_python()
    world.advance(2.9)
    state = json.loads(json.dumps(world.state()))
    before = json.dumps(world.state())
    if damage == "a bad schedule":
        state["schedule"] = [[0, 0, {"body": "left"}]]
    elif damage == "a negative count":  # of the forces applied without a name
        state["count"] = -1
    else:
        DAMAGES[damage](state["simulation"])
    with pytest.raises(ValueError, match=r"^state: ") as caught:
        world.set_state(state)
    assert "\n" not in str(caught.value)
    assert json.dumps(world.state()) == before


def test_a_state_of_another_scene_is_refused() -> None:
    """Two bodies' q and v fit any two-body world: the scene itself must match."""
    world = sample_in_python()
    other = sample_in_python()
    other["right"].position = (0.5, 3.0)  # moving a body changes the state, not the scene
    world.set_state(other.state())
    heavier = free_world()
    for name in ("left", "right"):
        heavier.add_body(name, hd.Circle(0.3), mass=2.0, position=(0, 1 if name == "left" else 3))
    heavier.step()
    before = json.dumps(world.state())
    with pytest.raises(ValueError, match=r"^state: taken in a world of another scene "
                                         r"\(fingerprint [0-9a-f]+; this world's [0-9a-f]+\)$"):
        world.set_state(heavier.state())
    assert json.dumps(world.state()) == before


def test_moving_a_body_and_names() -> None:
    world = free_world(gravity=(0, -9.81))
    ball = world.add_body("ball", hd.Circle(0.5), mass=1.0)
    assert world["ball"] is ball and "ball" in world and len(world) == 1
    assert list(world) == [ball]
    ball.position, ball.velocity, ball.angle = (1.0, 2.0), (0.0, 3.0), 0.25
    assert (ball.position, ball.velocity, ball.angle) == ((1.0, 2.0), (0.0, 3.0), 0.25)
    world.step(0.5)
    assert ball.velocity[1] == pytest.approx(3.0 - 9.81 * 0.5, rel=ROUND_OFF)


def test_step_sizes() -> None:
    world = hd.World(step=1 / 240)
    world.add_body("b", hd.Circle(1.0), mass=1.0)
    world.step(1 / 60)
    assert world.simulation.steps == 4
    world.step()
    world.advance(1.0)
    assert world.simulation.steps == 240
    # The step as the nanoseconds it was rounded to, not their product with 1e-9
    # (0.004166667000000001).
    with pytest.raises(ValueError, match=r"^dt: 0\.005 s is not a whole number of steps "
                                         r"of 0\.004166667 s$"):
        world.step(0.005)


def test_the_longest_step_is_the_longest_duration() -> None:
    """A step of 1e9 s, the most a duration may be, was refused as 1000000000.0000001 s:
    the scene took the nanoseconds times 1e-9, one ulp past what was given, as the
    world's time and step still read. Flags take numpy's booleans as Python's."""
    world = hd.World(step=1e9, gravity=(0.0, -1.0), sleep=np.bool_(False))
    ball = world.add_body("ball", hd.Circle(1.0), mass=1.0)
    world.step()
    assert (world.time_step, world.time) == (1e9, 1e9)
    assert ball.velocity == pytest.approx((0.0, -1e9), rel=1e-15)  # g h, h of the clock's ns


def built() -> hd.World:
    world = free_world()
    world.add_body("box", hd.Box(1.0, 0.5), mass=1.0)
    return world


ERRORS = [
    (lambda w: w["crate"], ValueError, r"^name: no body called 'crate' \(bodies: box\)$"),
    (lambda w: w.add_body("b", hd.Circle(1.0), mass=-2.0), ValueError,
     r"^mass: must be positive, not -2\.0$"),
    (lambda w: w.add_body("b", hd.Circle(1.0)), ValueError, r"^mass: give the body's mass"),
    (lambda w: w.add_body("b", hd.Circle(1.0), mass=1.0, position=(1, 2, 3)), ValueError,
     r"^position: expected two numbers \(x, y\), not 3$"),
    (lambda w: w.add_body("b", hd.Circle(1.0), mass=1.0, position="up"), TypeError,
     r"^position: expected two numbers"),
    (lambda w: w.add_body("box", hd.Circle(1.0), mass=1.0), ValueError,
     r"^name: the world already has a body called 'box'$"),
    (lambda w: w.add_body("my box", hd.Circle(1.0), mass=1.0), ValueError,
     r"^name: 'my box' is not a valid name"),
    (lambda w: w.add_body("b", "circle", mass=1.0), TypeError, r"^shape: expected hd\.Box"),
    (lambda w: hd.Box(-1.0, 1.0), ValueError, r"^width: must be positive, not -1\.0$"),
    (lambda w: w["box"].apply_force((1, 0), frame="local"), ValueError,
     r"^frame: must be 'world' or 'body', not 'local'$"),
    (lambda w: w["box"].apply_force((1, 0), duration=0.0), ValueError,
     r"^duration: must be positive, not 0\.0$"),
    # 4e-10 s rounded to 0 ns, which held the force until clear_forces(); 1e-5 s acted
    # over a whole step of 3.9 ms, 390 times the impulse asked for.
    (lambda w: w["box"].apply_force((1, 0), duration=4e-10), ValueError,
     r"^duration: 4e-10 s is shorter than one step \(0\.00390625 s\), over which a force acts "
     r"whole$"),
    (lambda w: w["box"].apply_torque(1.0, duration=1e-5), ValueError,
     r"^duration: 1e-05 s is shorter than one step \(0\.00390625 s\)"),
    (lambda w: w["box"].apply_force((1, 0), point="tip", frame="body"), ValueError,
     r"^point: body 'box' has no point 'tip' \(points: none\)$"),
    (lambda w: w["box"].apply_force((float("nan"), 0)), ValueError, r"^force: must be finite"),
    (lambda w: w.step(0.0), ValueError, r"^dt: must be positive, not 0\.0$"),
    (lambda w: w.step(-1.0), ValueError, r"^dt: must be positive, not -1\.0$"),
    (lambda w: w.add_spring("s", "box", stiffness=1.0), ValueError,
     r"^anchor: a spring needs exactly one of body_b or anchor$"),
    (lambda w: w.add_wall("w", point=(0, 0), normal=(0, 1), bodies=["ghost"]), ValueError,
     r"^bodies\[0\]: no body called 'ghost'"),
    (lambda w: hd.World(integrator="leapfrog"), ValueError, r"^integrator: must be one of"),
    (lambda w: hd.World(step=0.0), ValueError, r"^step: must be positive"),
    (lambda w: w.set_state({}), ValueError, r"^state: expected what World\.state\(\) returns$"),
    (lambda w: w.joint_state("hinge"), ValueError, r"^name: no revolute or prismatic joint"),
    # Times beyond what a scene file holds (1e9 s) overflowed into tracebacks.
    (lambda w: w.step(1e300), ValueError, r"^dt: must be at most 1000000000\.0, not 1e\+300$"),
    (lambda w: w.advance(1e300), ValueError, r"^t: must be at most 1000000000\.0"),
    (lambda w: w["box"].apply_force((1, 0), duration=1e300), ValueError,
     r"^duration: must be at most 1000000000\.0"),
    (lambda w: w["box"].apply_force((1, 0), start=1e10), ValueError,
     r"^start: must be at most 1000000000\.0 s past the world's time \(0 s\), "
     r"not 10000000000$"),
    # -1e300 s is -inf ns, which round() raised OverflowError on.
    (lambda w: w.advance(-1e300), ValueError, r"^t: -1e\+300 s is behind the world's time "
     r"\(0 s\)$"),
    (lambda w: w["box"].apply_force((1, 0), start=-1.7e308), ValueError,
     r"^start: -1\.7e\+308 s is behind the world's time \(0 s\)$"),
    (lambda w: hd.World(step=1e20), ValueError, r"^step: must be at most 1000000000\.0"),
    # A string's truth is whether it is empty: "false" switched the events on.
    (lambda w: hd.World(events="false"), TypeError, r"^events: expected True or False, not str$"),
    (lambda w: hd.World(sleep=1), TypeError, r"^sleep: expected True or False, not int$"),
    (lambda w: w.add_drag("d", 1.0, quadratic="no"), TypeError,
     r"^quadratic: expected True or False, not str$"),
    (lambda w: w.add_revolute_joint("pin", None, "box", collide_connected="False"), TypeError,
     r"^collide_connected: expected True or False, not str$"),
    (lambda w: hd.World.from_scene("sample", script="no"), TypeError,
     r"^script: expected True or False, not str$"),
    # A complex number or an array of another shape is not two real numbers.
    (lambda w: w["box"].apply_force(np.array([1.0, 2.0j])), TypeError,
     r"^force: expected a real number, not complex"),
    (lambda w: w["box"].apply_force(np.ones((2, 1))), ValueError,
     r"^force: expected two numbers \(x, y\), not an array of shape \(2, 1\)$"),
    (lambda w: hd.World(gravity=np.zeros((1, 2))), ValueError,
     r"^gravity: expected two numbers \(x, y\), not an array of shape \(1, 2\)$"),
    (lambda w: w.add_body("b", hd.Circle(1.0), mass=np.complex128(1.0)), TypeError,
     r"^mass: expected a real number, not complex"),
    # An integer past the largest double would raise float()'s OverflowError.
    (lambda w: w["box"].apply_force((10**400, 0)), ValueError,
     r"^force: must be finite, not an integer of 401 digits$"),
    (lambda w: setattr(w["box"], "velocity", (0, -10**309)), ValueError,
     r"^velocity: must be finite, not an integer of 310 digits$"),
    (lambda w: w.add_body("b", None, mass=1.0), TypeError, r"^shape: expected hd\.Box"),
    (lambda w: hd.World.from_scene(5), TypeError,
     r"^scene: expected a scene file's path, a shipped scene's name or an hd\.Scene, not int$"),
    (lambda w: w.add_body("b" * 101, hd.Circle(1.0), mass=1.0), ValueError,
     r"^name: 'b{59}\.\.\. \(103 characters\) is not a valid name \(letters, digits and "
     r"underscores, starting with a "
     r"letter, at most 100\)$"),
    # A force's name is its source, a string, as a message's id is.
    (lambda w: w["box"].apply_force((1, 0), name=123), TypeError,
     r"^name: expected a string, not int$"),
    (lambda w: w["box"].apply_torque(1.0, name=b"spin"), TypeError,
     r"^name: expected a string, not bytes$"),
]


@pytest.mark.parametrize("call, kind, message", ERRORS)
def test_errors_name_the_argument(call, kind, message) -> None:
    world = built()
    before = world.scene
    with pytest.raises(kind, match=message) as caught:
        call(world)
    assert "\n" not in str(caught.value)
    assert world.scene == before  # a refused call changes nothing


def test_edits_after_start_and_of_a_scene_file_are_refused() -> None:
    world = built()
    world.advance(3.0)
    with pytest.raises(ValueError, match=r"^cannot add wall 'w' after the world has started"):
        world.add_wall("w", point=(0, 0), normal=(0, 1))
    with pytest.raises(ValueError, match=r"^t: 1 s is behind the world's time "
                                         r"\(3 s\)$"):
        world.advance(1.0)
    with pytest.raises(ValueError, match=r"^cannot add wall 'floor': a world read from a scene"):
        hd.World.from_scene("sample").add_wall("floor", point=(0, 0), normal=(0, 1))


ENTRY_ERRORS = [
    (lambda w: w.add_wall("w", point=(0, 0), normal=(0, 0)),
     r"^World: parameter 'walls\.w\.normal': must not be the zero vector$"),
    (lambda w: w.add_spring("s", "box", body_b="box", stiffness=1.0),
     r"^World: parameter 'forces\.s\.body_b': a spring cannot join a body to itself$"),
    (lambda w: w.add_revolute_joint("j", "box", "box"),
     r"^World: parameter 'joints\.j\.body_b': a joint cannot join a body to itself$"),
    (lambda w: w.add_gear_joint("g", "pin", "nope", 2.0),
     r"^World: parameter 'joints\.g\.joint_b': 'nope' is not a revolute joint"),
    (lambda w: w.add_collision_group("all"),
     r"^World: body 'bow': a polygon that collides must be convex"),
]


@pytest.mark.parametrize(("call", "message"), ENTRY_ERRORS)
def test_an_entry_the_scene_reader_refuses_is_refused_when_added(call, message) -> None:
    """What the loader refuses of a file's wall, spring, joint, gear or group is refused by
    the add_* call, not at the first step, and the world goes on without it."""
    world = built()
    world.add_body("bow", hd.Polygon([(0, 0), (2, 0), (2, 2), (1, 0.5), (0, 2)]), mass=1.0,
                   position=(3.0, 0.0))
    world.add_revolute_joint("pin", None, "box")
    before = world.scene
    with pytest.raises(hd.SceneError, match=message):
        call(world)
    assert world.scene == before
    world.step()


def test_a_bad_body_is_refused_by_the_scene_reader_at_once() -> None:
    world = built()
    with pytest.raises(hd.SceneError, match=r"^World: body 'bow': the polygon's edges cross"):
        world.add_body("bow", hd.Polygon([(0, 0), (1, 1), (1, 0), (0, 1)]), mass=1.0)
    assert "bow" not in world and world.add_body("bow", hd.Circle(1.0), mass=1.0)


def test_every_joint_kind_and_force_is_the_scene_files() -> None:
    """Bodies of every shape, springs, drag and every joint kind built in Python are the
    Scene the same parameters give through the loader."""
    params = {
        "step": 0.001, "publish_rate": 50.0, "bodies": EVERY_FORCE["bodies"],
        "forces": {"gravity": {"type": "gravity", "acceleration": [0.3, -9.81]},
                   **{key: EVERY_FORCE["forces"][key]
                      for key in ("anchored", "link", "tie", "air", "wake", "fin", "spin")}},
        "joints": EVERY_FEATURE["joints"],
        "walls": EVERY_FEATURE["walls"], "collisions": EVERY_FEATURE["collisions"],
    }
    world = hd.World(gravity=(0.3, -9.81), step=0.001)
    a = world.add_body("a", hd.Box(1.0, 0.4, center=(0.2, 0.1)), mass=2.0,
                       points={"tip": (0.5, 0.2)})
    b = world.add_body("b", hd.Circle(0.3), mass=1.5, position=(2.0, 1.0))
    # The file's parts in the order of their names, ball before hull.
    c = world.add_body("c", [hd.Circle(0.2, center=(0.0, -0.8)),
                             hd.Polygon([(-1.0, -0.5), (1.0, -0.5), (0.0, 1.0)])],
                       density=3.0, position=(-2.0, 0.5))
    world.add_spring("anchored", a, "tip", anchor=(0.0, 3.0), stiffness=40.0,
                     rest_length=0.5, damping=0.7)
    world.add_spring("link", a, (-0.3, 0.1), b, (0.1, -0.2), stiffness=25.0, rest_length=1.0,
                     damping=0.3)
    world.add_spring("tie", b, body_b=c, stiffness=10.0)
    world.add_drag("air", 0.4)
    world.add_drag("wake", 0.2, [c], quadratic=True, point=(0.5, 0.5))
    world.add_drag("fin", 0.9, [a], point="tip")
    world.add_angular_damping("spin", 0.05, [a, b])
    world.add_revolute_joint("pin", a, c, point_a=(0.0, 0.0), point_b=(2.0, -0.5), lower=-1.0,
                             upper=1.0, motor_speed=1.0, max_torque=2.0, spring_stiffness=1.0,
                             spring_damping=0.1, rest_angle=0.0, collide_connected=True)
    world.add_prismatic_joint("rail", None, b, axis=(1.0, 0.0), lower=-1.0, upper=1.0,
                              motor_speed=0.0, max_force=1.0)
    world.add_weld_joint("glue", b, c, frequency=2.0, damping_ratio=0.5)
    world.add_distance_joint("rod", a, b, length=1.0)
    world.add_distance_joint("rope", a, c, max_length=9.0)
    world.add_revolute_joint("hinge", None, b)
    world.add_gear_joint("mesh", "pin", "hinge", 2.0)
    world.add_wall("floor", point=(0.0, -3.0), normal=(0.0, 1.0), restitution=0.5,
                   friction=0.2, bodies=["a", b])
    world.add_collision_group("all", [a, "b"], restitution=0.1, friction=0.4)
    loaded = make_scene(params)
    assert world.scene == dataclasses.replace(loaded, source="World", input_timeout_ns=0)


def test_from_scene_takes_a_name_a_path_or_a_scene() -> None:
    by_name = hd.World.from_scene("door")
    path = hd.World.from_scene(by_name.scene.source)
    scene = hd.World.from_scene(hd.load_scene("door"), script=False)
    assert by_name.scene == path.scene == scene.scene
    assert [body.name for body in by_name] == ["block", "door"]
    for world in (by_name, scene):
        world.advance(1.0)
    assert by_name["door"].angle != scene["door"].angle  # the push at 0.5 s, or not


@pytest.mark.parametrize("from_file", [True, False])
def test_a_held_force_of_a_scene_file_stops_after_its_input_timeout(from_file) -> None:
    """As the node's commands do (sample: input_timeout 0.5 s), a held force of a world
    read from a file acts as one timed at 0.5 s; a World built in Python has no timeout."""
    ends = []
    for duration in (None, 0.5):
        world = hd.World.from_scene("sample") if from_file else sample_in_python()
        world["right"].apply_force((0.0, 20.0), duration=duration)
        world.advance(2.0)
        ends.append(world["right"].position)
    assert (ends[0] == ends[1]) is from_file


# ----------------------------------------------------------------- bodies added and removed

def two_balls(extra: bool) -> hd.World:
    """Two balls falling onto a floor in a collision group, with a third in the group (as
    a Python world takes it before it starts) when ``extra``."""
    world = hd.World(gravity=(0, -9.81), step=1 / 250, integrator="semi_implicit_euler")
    world.add_body("a", hd.Circle(0.3), mass=1.0, position=(0.0, 1.0))
    world.add_body("b", hd.Box(0.5, 0.5), mass=2.0, position=(0.2, 2.0), angle=0.4)
    world.add_wall("floor", point=(0, 0), normal=(0, 1), friction=0.5)
    world.add_collision_group("pile", ["a", "b"])
    if extra:
        world.add_body("c", hd.Circle(0.2), mass=0.5, position=(-0.1, 3.0), collisions=["pile"])
    return world


def poses(world: hd.World) -> list[tuple[object, ...]]:
    return [(b.name, b.position, b.angle, b.velocity, b.angular_velocity) for b in world]


def test_a_body_added_before_the_first_step_is_the_one_declared_with_the_rest() -> None:
    """Spawned into a world that has not stepped (one read from its scene, so the node's
    spawn path), the body makes the world it makes when declared with the others, bit for
    bit, collision group and all."""
    declared = two_balls(extra=True)
    spawned = hd.World.from_scene(two_balls(extra=False).scene)
    spawned.add_body("c", hd.Circle(0.2), mass=0.5, position=(-0.1, 3.0), collisions=["pile"])
    assert spawned.scene == declared.scene
    declared.advance(2.0)
    spawned.advance(2.0)
    assert poses(spawned) == poses(declared)
    assert declared["c"].position[1] > 0.19  # it landed on the pile, not through it


def test_a_body_added_while_running_is_the_node_services_spawn() -> None:
    """Spawned at 0.5 s, the body goes through the same path as the node's spawn_body
    (read from the same parameters as YAML): the same bits at 1.5 s; the bodies already
    there keep their state through the spawn exactly."""
    world = two_balls(extra=False)
    sim = hd.Simulation(world.scene)
    world.advance(0.5)
    sim.advance_to(500_000_000, keep=False)
    before = poses(world)
    world.add_body("c", hd.Box(0.3, 0.2), mass=0.5, position=(-0.1, 3.0), angle=0.2,
                   velocity=(0.5, 0.0), collisions=["pile"])
    assert [p for p in poses(world) if p[0] != "c"] == before
    yaml = ("{shape: box, size: [0.3, 0.2], mass: 0.5, position: [-0.1, 3.0], angle: 0.2, "
            "velocity: [0.5, 0.0]}")
    sim = sim.with_world(spawned(sim.scene, "c", yaml, ["pile"]))
    world.advance(1.5)
    sim.advance_to(1_500_000_000, keep=False)
    assert poses(world) == [(b.name, b.position, b.angle, b.linear_velocity,
                             b.angular_velocity) for b in sim.snapshot().bodies]


def test_a_removed_body_leaves_the_others_as_the_node_services_delete() -> None:
    world = two_balls(extra=True)
    world.add_spring("tether", "a", anchor=(0, 1), stiffness=10.0)
    world.advance(0.5)
    with pytest.raises(hd.SceneError, match=r"^World: body 'a' is named by spring 'tether'; "
                       r"a world keeps those: remove them from its scene file, or build the "
                       r"world without them$"):
        world.remove_body("a")  # no World call removes a spring
    c = world["c"]
    sim = hd.Simulation(world.scene)
    sim.advance_to(500_000_000, keep=False)
    world.remove_body(c)
    sim = sim.with_world(deleted(sim.scene, "c"))
    assert "c" not in world and [b.name for b in world] == ["a", "b"]
    with pytest.raises(ValueError, match=r"^body 'c' was removed from the world$"):
        _ = c.position
    world.advance(1.0)
    sim.advance_to(1_000_000_000, keep=False)
    assert poses(world) == [(b.name, b.position, b.angle, b.linear_velocity,
                             b.angular_velocity) for b in sim.snapshot().bodies]
    world.add_body("c", hd.Circle(0.1), mass=0.1, position=(3.0, 1.0))  # the name is free again
    assert world["c"].mass == 0.1


def test_a_group_left_with_one_body_by_removals_takes_bodies_added_later() -> None:
    """'a' and 'b' removed leave group 'pile' with 'c' alone: a body added into it later
    is taken, and once 'c' is removed too, the next one collides with that body."""
    world = two_balls(extra=True)
    world.advance(0.1)
    world.remove_body("a")
    world.remove_body("b")
    world.add_body("d", hd.Circle(0.2), mass=0.5, position=(-0.1, 1.0), collisions=["pile"])
    world.remove_body("c")
    assert [(g.name, g.bodies) for g in world.scene.collisions] == [("pile", ("d",))]
    world.add_body("e", hd.Circle(0.2), mass=0.5, position=(-0.1, 2.0), collisions=["pile"])
    world.advance(2.0)
    assert world["e"].position[1] > 0.5  # resting on 'd', not through it


STALE = r"body 'c' was removed from the world; the body called so now is another: world\['c'\]$"


def test_a_removed_body_s_handle_does_not_stand_for_a_new_body_of_its_name() -> None:
    """The name of a removed body is free again, but the old handle is not the new body's:
    reading it, moving it, pushing it or removing by it raises, and the new body keeps its
    mass, its pose and no force."""
    world = two_balls(extra=True)
    old = world["c"]
    world.advance(0.2)
    world.remove_body(old)
    new = world.add_body("c", hd.Circle(0.1), mass=3.0, position=(3.0, 1.0))
    assert repr(old) == "Body('c', removed from its world)" and world["c"] is new
    for use in (lambda: old.mass, lambda: old.position, lambda: old.points,
                lambda: setattr(old, "velocity", (1.0, 0.0)),
                lambda: old.apply_force((0.0, 50.0), (0.0, 0.0)),
                lambda: old.apply_torque(1.0), old.clear_forces):
        with pytest.raises(ValueError, match="^" + STALE):
            use()
    with pytest.raises(ValueError, match="^body: " + STALE):
        world.remove_body(old)
    world.step()
    assert (new.mass, new.velocity[0], new.angular_velocity) == (3.0, 0.0, 0.0)
    assert math.isclose(new.velocity[1], -9.81 * 0.004)  # gravity alone: the push refused


def test_a_body_deleted_and_spawned_again_in_one_edit_is_a_new_body() -> None:
    """edit_bodies deleting 'c' and spawning another 'c' in one call: the old handle is
    stale and the force scheduled on the old body does not fall on the new one."""
    world = two_balls(extra=True)
    old = world["c"]
    world.step()
    old.apply_force((0.0, 100.0), start=0.5, duration=0.1)
    world.edit_bodies(WorldEdit(EditKind.DELETE, "c"),
                      WorldEdit(EditKind.SPAWN, "c", "{shape: circle, radius: 0.1, mass: 0.2, "
                                "position: [3.0, 4.5]}", ()))
    with pytest.raises(ValueError, match="^" + STALE):
        _ = old.position
    world.advance(0.6)
    # Falling freely, still in the air: no 100 N upwards.
    assert world["c"].position[1] > 0.1 and world["c"].velocity[1] < 0.0


BALL_AGAIN = "{shape: circle, radius: 0.1, mass: 1.0, position: [-2.0, 0.1]}"


def ball_on_a_floor() -> hd.World:
    """A ball sliding on a floor (a resting contact: warm starts held) beside a box, pulled
    by a held 5 N tug."""
    world = hd.World(gravity=(0, -9.81), step=1 / 200, integrator="semi_implicit_euler")
    world.add_body("ball", hd.Circle(0.1), mass=1.0, position=(0.0, 0.1), velocity=(0.5, 0.0))
    world.add_body("box", hd.Box(0.2, 0.2), mass=1.0, position=(1.0, 0.1))
    world.add_wall("floor", point=(0, 0), normal=(0, 1), friction=0.0)
    world["ball"].apply_force((5.0, 0.0), name="tug")
    world.advance(0.05)
    assert world.simulation.export_state()["contacts"], "the ball rests on the floor"
    return world


def test_a_body_deleted_and_spawned_again_in_one_edit_takes_nothing_of_the_old_one() -> None:
    """Delete 'ball' and spawn another 'ball' in one edit_bodies: the new ball starts where
    its YAML puts it, at rest, and the old ball's held tug and warm starts do not carry to
    it; the world goes on bit for bit as after the node's delete_body then spawn_body (two
    calls), and the box keeps its state."""
    world, services = ball_on_a_floor(), ball_on_a_floor()
    box = world["box"].position, world["box"].velocity
    world.edit_bodies(WorldEdit(EditKind.DELETE, "ball"),
                      WorldEdit(EditKind.SPAWN, "ball", BALL_AGAIN))
    services.edit_bodies(WorldEdit(EditKind.DELETE, "ball"))
    services.edit_bodies(WorldEdit(EditKind.SPAWN, "ball", BALL_AGAIN))
    assert (world["ball"].position, world["ball"].velocity) == ((-2.0, 0.1), (0.0, 0.0))
    assert (world["box"].position, world["box"].velocity) == box
    assert world.simulation.export_state()["inputs"]["active"] == []
    world.advance(0.5)
    services.advance(0.5)
    assert poses(world) == poses(services)
    assert world["ball"].velocity[0] == 0.0  # no tug, a floor without friction


#: A ROS time as the node starts at: more nanoseconds than a float's seconds hold exactly.
ROS_START_NS = 1_765_000_000_123_456_789


def test_the_node_s_calls_on_a_world_are_the_simulation_s() -> None:
    """What the node's run loop does through a World (started at a ROS time): a command
    pushed, a body moved, a body spawned and one deleted by the services' YAML, a restart
    at another time, gives bit for bit what the same calls on a bare Simulation give, the
    spawned and deleted bodies following in the World's names."""
    scene = two_balls(extra=True).scene
    world = hd.World.from_scene(scene, script=False, start_ns=ROS_START_NS)
    sim = hd.Simulation(scene, start_ns=ROS_START_NS)
    step = scene.step_ns
    push = hd.WrenchCommand(ROS_START_NS + 3 * step, "b", "kick", "b", (0.25, 0.0),
                            (0.0, 40.0), 0.0, 30 * step)
    spawn = WorldEdit(EditKind.SPAWN, "d", "{shape: circle, radius: 0.1, mass: 0.2, "
                      "position: [0.5, 1.5]}", ("pile",))
    for target in (world, sim):
        target.push(push)
    world.simulation.advance_to(ROS_START_NS + 50 * step, keep=False)
    sim.advance_to(ROS_START_NS + 50 * step, keep=False)
    world.set_body_state("a", (0.1, 1.2), 0.3, (0.5, -0.2), 1.5)
    sim.set_body_state("a", (0.1, 1.2), 0.3, (0.5, -0.2), 1.5)
    world.edit_bodies(spawn, WorldEdit(EditKind.DELETE, "c"))
    sim = sim.with_world(deleted(spawned(sim.scene, "d", spawn.spec, spawn.collisions), "c"))
    assert [b.name for b in world] == ["a", "b", "d"] and world.scene.bodies == sim.scene.bodies
    for start in (None, ROS_START_NS + 7):
        world.simulation.advance_to(world.simulation.time_ns + 200 * step, keep=False)
        sim.advance_to(sim.time_ns + 200 * step, keep=False)
        assert poses(world) == [(b.name, b.position, b.angle, b.linear_velocity,
                                 b.angular_velocity) for b in sim.snapshot().bodies]
        world.reset(start)
        sim.reset(start)
        assert world.simulation.time_ns == sim.time_ns == (start or ROS_START_NS)
    with pytest.raises(hd.InputError, match=r"^unknown body 'c'"):
        world.set_body_state("c", (0.0, 0.0), 0.0, (0.0, 0.0), 0.0)
    with pytest.raises(hd.SceneError, match=r"'a' is already a body"):
        world.edit_bodies(WorldEdit(EditKind.DELETE, "d"),
                          WorldEdit(EditKind.SPAWN, "a", "{shape: circle, radius: 0.1, "
                                                        "mass: 0.2}"))
    assert [b.name for b in world] == ["a", "b", "d"]  # the refused edits changed nothing


def test_a_world_started_at_a_ros_time_takes_times_of_its_clock() -> None:
    """A world started at a ROS time (1.765e9 s, past the 1e9 s a duration may last) takes
    the times its own clock gives: advance to 1 s past ``time``, a force from 0.5 s past
    it, as a world started at 0 does, bit for bit. Both were refused as past 1e9 s. (The
    start is whole seconds, which a double holds, and the sums with it exactly.)"""
    start = ROS_START_NS - ROS_START_NS % 10**9
    worlds = [hd.World.from_scene("sample", script=False, start_ns=start)
              for start in (0, start)]
    for world in worlds:
        world.advance(world.time + 1.0)
        world["left"].apply_force((0.0, 30.0), point="hook", frame="body", duration=0.1,
                                  start=world.time + 0.5)
        world.advance(world.time + 1.0)
        with pytest.raises(ValueError, match=r"^t: must be at most 1000000000\.0 s past "):
            world.advance(world.time + 2e9)
    assert [world.simulation.time_ns - begun for world, begun in
            zip(worlds, (0, start))] == [2 * 10**9] * 2
    assert [repr(body) for body in worlds[0]] == [repr(body) for body in worlds[1]]
    unpushed = hd.World.from_scene("sample", script=False)
    unpushed.advance(2.0)
    assert worlds[1]["left"].velocity != unpushed["left"].velocity  # the force acted


def test_a_world_s_bodies_follow_its_simulation_stepped_directly() -> None:
    """A body's pose read, then the simulation under the world stepped by itself (as the
    node's run loop steps it): the pose read again is the new one, not the one read
    before."""
    world = two_balls(extra=False)
    before = world["b"].position
    world.simulation.advance_to(100 * world.simulation.step_ns, keep=False)
    after = world.simulation.snapshot().bodies[1]
    assert world["b"].position == after.position != before
    assert world["b"].angular_velocity == after.angular_velocity


def test_a_scene_s_script_starts_with_the_world_and_again_at_a_reset() -> None:
    """The sample scene (its kick scripted at 3 s) started at a ROS time, or reset to one,
    steps bit for bit as from 0: the script's stamps count from the start."""
    from_zero = hd.World.from_scene("sample")
    from_zero.step(4.0)
    later = hd.World.from_scene("sample", start_ns=ROS_START_NS)
    later.step(4.0)
    assert poses(later) == poses(from_zero)
    later.reset(start_ns=ROS_START_NS + 999)
    later.step(4.0)
    assert poses(later) == poses(from_zero)
    assert later.simulation.time_ns == ROS_START_NS + 999 + 4 * 10**9
    with pytest.raises(TypeError, match=r"^start_ns: expected a whole number of nanoseconds"):
        hd.World.from_scene("sample", start_ns=1.5)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"^start_ns: expected a whole number of nanoseconds"):
        later.reset(start_ns=True)
    later.reset(start_ns=np.int64(5))  # a numpy integer is a whole number too
    assert later.simulation.time_ns == 5 and type(later.simulation.start_ns) is int


@pytest.mark.parametrize("start_ns,words", [
    (2 ** 70, "1180591620717.411303424 s is after 2147483647 s, the latest time a ROS stamp "
              "(int32 seconds) holds"),
    (2 ** 31 * 10 ** 9, "2147483648 s is after 2147483647 s"),
    (-1, "-0.000000001 s is before 0")])
def test_a_start_no_ros_stamp_holds_is_refused_in_one_line(start_ns, words) -> None:
    """A world, a reset or a simulation started where the node's messages could not be
    stamped (int32 seconds, from 0) is refused before it steps, in one line; the latest
    instant a stamp holds is taken. (2**70 was accepted, and stepped.)"""
    latest = (2 ** 31 - 1) * 10 ** 9 + 999_999_999
    assert hd.World.from_scene("sample", start_ns=latest).simulation.time_ns == latest
    with pytest.raises(ValueError) as refused:
        hd.World.from_scene("sample", start_ns=start_ns)
    assert str(refused.value).startswith(f"start_ns: {words}")
    assert "\n" not in str(refused.value)
    world = hd.World.from_scene("sample", start_ns=5)
    with pytest.raises(ValueError, match=r"^start_ns: "):
        world.reset(start_ns=start_ns)
    world.step()
    assert world.simulation.time_ns == 5 + world.simulation.step_ns  # the reset changed nothing
    with pytest.raises(ValueError, match=r"^start_ns: "):
        hd.Simulation(hd.load_scene("sample"), start_ns=start_ns)


@pytest.mark.parametrize("frame", ["my world", "w\u00f6rld", "9world", "", "w" * 101,
                                   "world/x", "world-1", "world "])
def test_a_fixed_frame_s_name_is_one_rule_in_a_scene_file_and_a_world(tmp_path, frame):
    """A scene file's frame_id took any name without '/' (a space, a non-ASCII letter, 101
    characters), which World(frame=...) refuses: both now refuse it, in the same words."""
    with pytest.raises(ValueError) as in_world:
        hd.World(frame=frame)
    path = write_scene(tmp_path, {"frame_id": frame, "bodies": {
        "a": {"shape": "circle", "radius": 1.0, "mass": 1.0}}})
    with pytest.raises(hd.SceneError) as in_file:
        hd.load_scene(path)
    words = str(in_world.value).removeprefix("frame: ")
    assert words.endswith("is not a valid name (letters, digits and underscores, starting "
                          "with a letter, at most 100)")
    assert str(in_file.value).endswith(f"parameter 'frame_id': {words}")


@pytest.mark.parametrize("python", [False, True], ids=["kernel", "python"])
def test_forces_applied_from_another_thread_act_whole_at_the_instant_taken(python):
    """A controller thread applies 1000 named forces of 2 ms (two steps) to a puck while
    the main thread steps the world one step at a time. Each call holds the world's lock,
    so each force is taken at a step instant and acts over its two steps, all of it (before
    the lock, a force taken while a step ran acted over one step or none, or was refused
    as already over: "stamped 0.512 s ago"). The run equals, bit for bit, one thread
    applying the same forces at the instants they were taken (read back from when each
    ends)."""
    def puck_world():
        world = hd.World(step=0.001, integrator="semi_implicit_euler")
        world.add_body("puck", hd.Circle(0.1), mass=1.0)
        if python:
            world.simulation.model.use_python()
        return world

    world, count = puck_world(), 1000
    puck = world["puck"]
    done = threading.Event()
    refused: list[BaseException] = []

    def controller():
        try:
            for i in range(count):
                puck.apply_force((1.0, 0.5), duration=0.002, name=f"f{i}")
        except BaseException as error:  # raised in the main thread below
            refused.append(error)
        finally:
            done.set()

    thread = threading.Thread(target=controller)
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # the threads take turns between every few bytecodes
    try:
        thread.start()
        while not done.is_set():
            world.step()
        thread.join()
    finally:
        sys.setswitchinterval(interval)
    assert not refused, refused
    world.step(0.002)
    ends = world._applied["puck"]
    assert sorted(ends) == sorted(f"f{i}" for i in range(count))
    taken = sorted((ends[f"f{i}"] - 2_000_000, i) for i in range(count))
    assert taken == sorted(taken, key=lambda entry: entry[1])  # in the order applied
    assert world["puck"].velocity == pytest.approx((0.002 * count, 0.001 * count), rel=1e-12)

    again = puck_world()
    for stamp, i in taken:
        again.advance((stamp - again.simulation.start_ns) * 1e-9)
        assert again.simulation.time_ns == stamp
        again["puck"].apply_force((1.0, 0.5), duration=0.002, name=f"f{i}")
    again.advance(world.time)
    assert again.simulation.time_ns == world.simulation.time_ns
    assert np.array_equal(again.simulation.q, world.simulation.q)
    assert np.array_equal(again.simulation.v, world.simulation.v)


def test_zero_dimensional_arrays_are_numbers_everywhere_numpy_scalars_are():
    """``np.array(2.0)`` (what ``np.asarray`` makes of a number) was refused as "expected
    a number, not ndarray" wherever a number goes, while ``np.float64(2.0)`` was taken. A
    world built and driven with 0-d arrays (switches and nanoseconds too) steps with the
    bits of the one built with floats."""
    def build(n):
        world = hd.World(gravity=(n(0.0), n(-9.81)), step=n(0.001), tolerance=n(1e-6),
                         sleep=n(False), integrator="semi_implicit_euler")
        world.add_wall("floor", point=(0, 0), normal=(0, 1), restitution=n(0.5),
                       friction=n(0.3))
        box = world.add_body("box", hd.Box(n(1.0), n(0.5), angle=n(0.0)), mass=n(2.0),
                             position=(n(0.0), n(2.0)), angle=n(0.2),
                             angular_velocity=n(1.0), velocity=[n(1.0), n(0.0)])
        disc = world.add_body("disc", hd.Circle(n(0.25)), density=n(3.0),
                              position=(n(2.0), n(1.0)))
        world.add_spring("s", box, (n(0.5), n(0.0)), disc, stiffness=n(20.0),
                         rest_length=n(1.0), damping=n(0.1))
        world.add_drag("d", n(0.05), quadratic=n(True))
        world.add_revolute_joint("pin", None, disc, point_b=(n(0.0), n(0.0)),
                                 motor_speed=n(1.0), max_torque=n(0.5))
        box.apply_force((n(0.0), n(5.0)), point=(n(0.1), n(0.0)), duration=n(0.1),
                        start=n(0.01), torque=n(0.2))
        world.step(n(0.05))
        world.push(hd.WrenchCommand(n(world.simulation.time_ns), "box", "cmd", "box",
                                    (n(0.0), n(0.0)), (n(1.0), n(0.0)), n(0.0),
                                    n(10_000_000)))
        box.angular_velocity = n(2.0)
        world.set_body_state("disc", (n(2.0), n(1.0)), n(0.1), (n(0.0), n(0.0)), n(0.0))
        world.advance(n(0.5))
        return world

    plain = build(lambda value: value)
    zero_d = build(np.array)
    assert zero_d.state() == plain.state()
    assert zero_d.time == plain.time == 0.5
    later = hd.World.from_scene("sample", start_ns=np.array(5))
    assert later.simulation.time_ns == 5
    with pytest.raises(TypeError, match=r"^mass: expected a number, not ndarray$"):
        plain.add_body("bad", hd.Circle(1.0), mass=np.array([1.0]))  # one number in 1-D
    with pytest.raises(TypeError, match=r"^radius: expected a real number, not complex128$"):
        hd.Circle(np.array(1.0 + 2.0j))


def test_a_hand_made_command_s_fields_are_checked_as_arguments_are():
    """``World.push`` took any fields: a float stamp or duration (1000000.5 ns) went into
    the clock's nanoseconds, a stamp of True acted at 1 ns, and a force of text or three
    numbers failed deep in the input buffer (a traceback). Each is now refused naming the
    field, changing nothing; numpy integers and 0-d arrays are whole numbers."""
    world = hd.World(integrator="semi_implicit_euler")
    puck = world.add_body("puck", hd.Circle(0.5), mass=1.0)
    made = {"stamp_ns": 0, "body": "puck", "source": "s", "frame_id": "world",
            "point": (0.0, 0.0), "force": (1.0, 0.0), "torque": 0.0,
            "duration_ns": 1_000_000}
    for field, value, error, words in [
            ("stamp_ns", 0.0, TypeError, "expected a whole number of nanoseconds, not float"),
            ("stamp_ns", True, TypeError, "expected a whole number of nanoseconds, not bool"),
            ("duration_ns", 1_000_000.5, TypeError,
             "expected a whole number of nanoseconds, not float"),
            ("duration_ns", None, TypeError,
             "expected a whole number of nanoseconds, not NoneType"),
            ("force", ("1", 0.0), TypeError, "expected a number, not str"),
            ("force", (1.0, 0.0, 0.0), hd.InputError, "expected two numbers (x, y), not 3"),
            ("torque", math.nan, hd.InputError, "must be finite, not nan"),
            ("body", None, TypeError, "expected text, not NoneType")]:
        with pytest.raises(error, match=f"^command.{field}: {re.escape(words)}$"):
            world.push(hd.WrenchCommand(**{**made, field: value}))
    world.step()
    assert puck.velocity == (0.0, 0.0)
    world.push(hd.WrenchCommand(**{**made, "stamp_ns": np.int64(world.simulation.time_ns),
                                   "duration_ns": np.array(1_000_000)}))
    world.step()
    assert puck.velocity == (0.001, 0.0)
    assert type(world.simulation.time_ns) is int
