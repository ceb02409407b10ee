"""Omnidirectional bases and thrusters under PI control: they reach the commanded twist
(sideways too), capped pushes accelerate the body at exactly the capped wrench over the
mass (a kiwi base strafing: sqrt(3) max_force / m; two rear thrusters: 2 max_force / m),
thrusters never pull, and a stale cmd_vel stops the push."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import body_speeds, driven_robot

from hecker_dynamics.drives.command import VelocityCommand
from hecker_dynamics.drives.control import DriveSet, advance_with_drives
from hecker_dynamics.drives.wrench_drive import nonnegative_least_squares
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.cmd_vel import CmdVelTopic, take_cmd_vel
from hecker_dynamics.scene.parameters import SceneError

MASS = 10.0
S = 1_000_000_000
# Three omni wheels 0.2 m from the centre at 90, 210 and 330 degrees, each pushing along
# its tangent (a "kiwi" base).
KIWI = [v for phi in (90.0, 210.0, 330.0) for v in (
    0.2 * math.cos(math.radians(phi)), 0.2 * math.sin(math.radians(phi)),
    math.radians(phi) + math.pi / 2)]
# A ship: two engines at the stern pushing forward, two bow thrusters pushing sideways.
SHIP = [-1.0, 0.5, 0.0, -1.0, -0.5, 0.0, 1.0, 0.0, math.pi / 2, 1.0, 0.0, -math.pi / 2]


def drive_sim(kind: str, actuators: list[float], drag: float = 0.0,
              integrator: str = "rk4", **drive) -> Simulation:
    key = "wheels" if kind == "omni" else "thrusters"
    spec = {"type": kind, key: actuators, "max_force": 50.0,
            "linear_kp": 40.0, "linear_ki": 80.0, "angular_kp": 4.0, "angular_ki": 8.0,
            "cmd_vel_timeout": 0.0, **drive}
    return Simulation(driven_robot(spec, {"shape": "box", "size": [0.6, 0.4], "mass": MASS,
                                          "angle": 0.3}, drag=drag, integrator=integrator))


def run(sim: Simulation, command: VelocityCommand, until_ns: int) -> DriveSet:
    drives = DriveSet(sim)
    drives.drives[0].receive(command)
    advance_with_drives(sim, drives, until_ns)
    return drives


def test_an_omni_base_reaches_a_twist_with_a_sideways_part_against_drag():
    sim = drive_sim("omni", KIWI, drag=5.0)
    run(sim, VelocityCommand(0, 0.4, 0.5, -0.3), 15 * S)
    forward, sideways, omega = body_speeds(sim.q, sim.v)
    assert (forward, sideways, omega) == pytest.approx((0.4, -0.3, 0.5), abs=1e-5)


def test_a_capped_kiwi_base_strafes_at_sqrt_three_max_force_over_the_mass():
    cap = 2.0
    sim = drive_sim("omni", KIWI, max_force=cap, integrator="semi_implicit_euler")
    run(sim, VelocityCommand(0, 0.0, 0.0, 10.0), S)
    # Sideways only: the wheel at 90 degrees idles, the others push -+F / sqrt(3), capped.
    forward, sideways, omega = body_speeds(sim.q, sim.v)
    assert sideways == pytest.approx(math.sqrt(3.0) * cap / MASS * 1.0, rel=1e-12)
    assert abs(forward) < 1e-12 and abs(omega) < 1e-12


def test_capped_stern_engines_accelerate_at_twice_the_cap_over_the_mass():
    cap = 3.0
    sim = drive_sim("thrusters", SHIP, max_force=cap, integrator="semi_implicit_euler")
    drives = DriveSet(sim)
    drives.drives[0].receive(VelocityCommand(0, 10.0, 0.0))
    pushes = []
    original = drives.drives[0].wrenches

    def spy(q, v, time_ns):
        commands = original(q, v, time_ns)
        pushes.append([c.force for c in commands])
        return commands

    drives.drives[0].wrenches = spy
    advance_with_drives(sim, drives, S)
    # The capped engines and the idle bow thrusters, to the rounding of the least-squares
    # solve (a few ulps, which the engines' small imbalance leaves).
    assert len(pushes) == 100
    assert np.allclose([p[:2] for p in pushes], [[(cap, 0.0)] * 2] * 100, rtol=1e-14, atol=1e-14)
    assert np.max(np.abs([p[2:] for p in pushes])) < 1e-12 * cap
    forward, sideways, omega = body_speeds(sim.q, sim.v)
    assert forward == pytest.approx(2 * cap / MASS, rel=1e-12)
    assert abs(sideways) < 1e-12 and abs(omega) < 1e-12


def test_thrusters_never_pull():
    sim = drive_sim("thrusters", SHIP)
    drive = DriveSet(sim).drives[0]
    rng = np.random.default_rng(3)
    for _ in range(50):
        drive.receive(VelocityCommand(0, *rng.uniform(-2.0, 2.0, size=3)))
        sim.v[0] = rng.uniform(-1.0, 1.0, size=3)
        for command, (_, _, angle) in zip(drive.wrenches(sim.q, sim.v, 0),
                                          np.reshape(SHIP, (-1, 3))):
            along = command.force[0] * math.cos(angle) + command.force[1] * math.sin(angle)
            assert along >= 0.0 and math.hypot(*command.force) == pytest.approx(along)
    # Backwards is out of their reach: the stern engines stay off.
    drive.receive(VelocityCommand(0, -1.0, 0.0))
    sim.v[0] = 0.0
    assert [c.force for c in drive.wrenches(sim.q, sim.v, 0)][:2] == [(0.0, 0.0)] * 2


def test_nonnegative_least_squares_matches_the_exact_solution_when_it_is_nonnegative():
    rng = np.random.default_rng(5)
    for _ in range(20):
        a = rng.normal(size=(3, 5))
        x = rng.uniform(0.1, 2.0, size=5) * (rng.random(5) < 0.6)
        found = nonnegative_least_squares(a, a @ x)
        assert (found >= 0.0).all()
        assert np.allclose(a @ found, a @ x, atol=1e-10)


def test_a_stale_cmd_vel_stops_the_push():
    sim = drive_sim("omni", KIWI, cmd_vel_timeout=0.5)
    drives = run(sim, VelocityCommand(0, 1.0, 0.0, 0.5), S // 2)
    assert not drives.drives[0].active(sim.time_ns)
    assert all(c.force == (0.0, 0.0) for c in drives.drives[0].wrenches(sim.q, sim.v,
                                                                       sim.time_ns))


def test_the_sideways_command_round_trips_a_keyframe_and_cmd_vel_takes_linear_y():
    sim = drive_sim("omni", KIWI)
    drives = DriveSet(sim)

    class Twist:
        class linear:  # noqa: N801 - the message's field names
            x, y, z = 0.2, -0.4, 0.0

        class angular:  # noqa: N801
            x, y, z = 0.0, 0.0, 0.1

    assert take_cmd_vel(drives, CmdVelTopic("robot", "robot/cmd_vel"), Twist, 7) == []
    drive = drives.drives[0]
    assert drive.command == VelocityCommand(7, 0.2, 0.1, -0.4)
    drive.wrenches(sim.q, sim.v, 10_000_000)
    copy = DriveSet(sim).drives[0]
    copy.import_state(drive.export_state())
    assert copy.export_state() == drive.export_state()
    assert copy.wrenches(sim.q, sim.v, 20_000_000) == drive.wrenches(sim.q, sim.v, 20_000_000)


def test_a_scripted_omni_command_holds_x_y_and_z():
    sim = drive_sim("omni", KIWI, script=[0.1, 0.3, -0.2, 0.5])
    drives = DriveSet(sim)
    advance_with_drives(sim, drives, S // 5)
    command = drives.drives[0].command
    assert (command.linear_x, command.linear_y, command.angular_z) == (0.3, -0.2, 0.5)


@pytest.mark.parametrize("kind, drive, problem", [
    ("omni", {"wheels": [0.0, 0.0, 0.0, 0.1, 0.0, 0.0]}, "cannot push every way and turn"),
    ("omni", {"wheels": [0.0, 0.0]}, "multiple of 3"),
    ("thrusters", {"thrusters": []}, "at least one"),
    ("thrusters", {"script": [0.0, 1.0, 0.0]}, "multiple of 4"),
])
def test_bad_drive_parameters_are_refused_by_name(kind, drive, problem):
    actuators = KIWI if kind == "omni" else SHIP
    with pytest.raises(SceneError, match=problem):
        drive_sim(kind, actuators, **drive)
