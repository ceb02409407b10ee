"""Finite inputs that would run the state away within one step are refused when they are
given, naming the body and the input, and change nothing: a force of 1e308 N on 1 kg
moves the body at 1e305 m/s after one millisecond, whose kinetic energy (5e609 J) a
double cannot hold, so the energy bound could not judge the state and the world would be
stepped, read and published with an infinite energy before any check.

The line drawn is the body's energy of motion after one step of the wrench acting alone,
from its motion now, 1/2 m (|v| + |F| h / m)^2 + 1/2 I (|omega| + (|tau| + |r| |F|) h /
I)^2 (the force over the mass, Eq. 5; the torque at the lever arm r, Eq. 11; the angular
acceleration, Eq. 14): it must be a finite double. Just inside it, the step is the
exact constant-acceleration step, so nothing legitimate is refused."""
from __future__ import annotations

import json
import math

import pytest
from scene_builders import write_scene

import hecker_dynamics as hd
from hecker_dynamics.cli import main
from hecker_dynamics.scene.commands import InputError, WrenchCommand

H = 0.001


def unit_box() -> tuple[hd.World, hd.Body]:
    world = hd.World(step=H, integrator="semi_implicit_euler")
    return world, world.add_body("b", hd.Box(1.0, 1.0), mass=1.0)


@pytest.mark.parametrize("push", [
    {"force": (1e308, 0.0)},
    {"force": (0.0, -1e200)},
    {"force": (1e160, 0.0)},  # 1e157 m/s after a step: 5e313 J
    {"force": (0.0, 0.0), "torque": 1e308},
    {"force": (0.0, 1e100), "point": (1e250, 0.0)},  # a lever past what a double turns
    {"force": (1e308, 0.0), "start": 0.5},  # scheduled: refused now, not mid-advance
    {"force": (1e308, 0.0), "frame": "body", "point": (0.5, 0.5)},
])
def test_a_wrench_that_runs_away_in_one_step_is_refused_and_changes_nothing(push) -> None:
    world, body = unit_box()
    before = json.dumps(world.state())
    with pytest.raises(InputError, match=r"^wrench for body 'b' from 'kick' would give it "
                                         r"an energy of motion past .* after one step"):
        body.apply_force(name="kick", **push)
    assert json.dumps(world.state()) == before
    world.step(0.01)  # nothing of the refused force acts
    assert body.position == (0.0, 0.0) and body.velocity == (0.0, 0.0)


def test_a_huge_force_just_inside_the_line_steps_exactly() -> None:
    """1e150 N on 1 kg for one step of semi-implicit Euler: v = F h / m, x = v h."""
    world, body = unit_box()
    body.apply_force((1e150, 0.0))
    world.step()
    assert body.velocity == (1e150 * H, 0.0)
    assert body.position == (1e150 * H * H, 0.0)
    assert math.isfinite(world.energy)


def test_a_command_pushed_on_a_simulation_is_refused_naming_its_source() -> None:
    sim = hd.World.from_scene("sample").simulation
    before = sim.export_state()
    command = WrenchCommand(0, "left", "thruster", "left", (0.4, 0.0), (0.0, 1e300))
    with pytest.raises(InputError, match=r"^wrench for body 'left' from 'thruster' would"):
        sim.push(command)
    assert sim.export_state() == before


def test_run_refuses_a_scripted_runaway_force_in_one_line(tmp_path, capsys) -> None:
    path = write_scene(tmp_path, {
        "bodies": {"puck": {"shape": "circle", "radius": 0.5, "mass": 1.0}},
        "script": {"blast": {"time": 0.1, "body": "puck", "id": "blast", "frame_id": "world",
                             "force": [1e308, 0.0], "duration": 0.5}}})
    assert main(["run", str(path), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hecker-dynamics: error: scripted input rejected: wrench for body "
                          "'puck' from 'blast' would")
    assert err.count("\n") == 1


@pytest.mark.parametrize("motion", [{"velocity": (1e200, 0.0)}, {"angular_velocity": 1e200},
                                    {"velocity": (0.0, -2e154)}])
def test_a_body_moved_past_what_a_double_holds_is_refused(motion) -> None:
    """Set on a Body (Simulation.set_body_state) or given at the start, a motion whose
    energy overflows is refused naming the body; 1e154 m/s on 1 kg (5e307 J) is not."""
    world, body = unit_box()
    before = json.dumps(world.state())
    with pytest.raises(InputError, match=r"^the state for 'b' moves it with an energy of "
                                         r"motion past what a double holds"):
        for key, value in motion.items():
            setattr(body, key, value)
    assert json.dumps(world.state()) == before
    body.velocity = (1e154, 0.0)
    assert math.isfinite(world.energy)
    other = hd.World(step=H)
    key = next(iter(motion))
    with pytest.raises(hd.SceneError, match=rf"^World: parameter 'bodies\.b\.{key}': moves "
                                            r"the body so fast .* past what a double holds$"):
        other.add_body("b", hd.Box(1.0, 1.0), mass=1.0, **motion)
    assert len(other) == 0


def test_a_scene_file_whose_body_moves_past_what_a_double_holds_is_refused(tmp_path,
                                                                           capsys) -> None:
    path = write_scene(tmp_path, {"bodies": {"puck": {
        "shape": "box", "size": [1.0, 0.5], "mass": 1.0, "angular_velocity": 1e160}}})
    assert main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == (f"hecker-dynamics: error: {path}: parameter 'bodies.puck.angular_velocity': "
                   "moves the body so fast (0 m/s, 1e+160 rad/s) that its energy of motion is "
                   "past what a double holds\n")


@pytest.mark.parametrize("frame_id, lever", [
    ("b", 3.0),  # a point of the body itself: the lever arm its kept place holds
    ("world", 2.0),  # from the state: the body's CM is at (1, 0)
    ("c", 3.0 + 2.0),  # another body's point, 3 m from its CM, which is 2 m away
])
def test_the_reach_check_takes_the_lever_arm_of_each_frame(frame_id, lever) -> None:
    """A force pushed at (3, 0) in ``frame_id`` (a body's own point, whose lever arm the
    simulation keeps with the point, the fixed frame's, another body's) is refused exactly
    where the written-out energy after one step overflows, pushed first and again (the
    kept place), by the torque of its lever arm alone (the force's own speed stays far
    below overflow)."""
    world = hd.World(step=H, integrator="semi_implicit_euler")
    world.add_body("b", hd.Box(1.0, 1.0), mass=1.0, position=(1.0, 0.0))
    world.add_body("c", hd.Box(1.0, 1.0), mass=1.0, position=(3.0, 0.0))
    sim = world.simulation
    inertia = sim.scene.bodies[0].mass.moment_of_inertia
    verdicts = []
    for force in (1e156, 2e156, 3e156, 4e156, 5e156, 1e156, 5e156):
        speed, turn = force * H, lever * force * H / inertia
        refused = not math.isfinite(0.5 * speed * speed + 0.5 * inertia * turn * turn)
        verdicts.append(refused)
        command = WrenchCommand(0, "b", "push", frame_id, (3.0, 0.0), (0.0, force))
        if refused:
            with pytest.raises(InputError, match="past what a double holds"):
                sim.check_reach(command)
        else:
            assert sim.check_reach(command).force == (0.0, force)
    assert verdicts[0] is False and verdicts[-1] is True  # both sides of the line
