"""A differential drive under PI control: it reaches the commanded speed and turn rate,
its motors never push harder than their cap (and then accelerate the body at exactly
2 max_force / m), the friction circle caps each wheel, and a stale cmd_vel stops the push."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import body_speeds, driven_robot

from hecker_dynamics.drives.control import DriveSet, advance_with_drives
from hecker_dynamics.drives.diff_drive import VelocityCommand
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.scene.commands import InputError
from hecker_dynamics.scene.parameters import SceneError

MASS = 10.0


def robot_sim(drag: float = 0.0, integrator: str = "rk4", **drive) -> Simulation:
    spec = {"type": "diff_drive", "separation": 0.4, "max_force": 50.0,
            "linear_kp": 40.0, "linear_ki": 80.0, "angular_kp": 4.0, "angular_ki": 8.0,
            "cmd_vel_timeout": 0.0, "center": [-0.1, 0.0], **drive}
    return Simulation(driven_robot(spec, {"parts": {"hull": {"shape": "box",
                                                              "size": [0.6, 0.4]}},
                                          "mass": MASS, "angle": 0.3},
                                   drag=drag, integrator=integrator))


def test_a_straight_command_reaches_its_speed_against_drag():
    sim = robot_sim(drag=5.0)
    drives = DriveSet(sim)
    drives.drives[0].receive(VelocityCommand(0, 0.8, 0.0))
    advance_with_drives(sim, drives, 10_000_000_000)
    forward, sideways, omega = body_speeds(sim.q, sim.v)
    # The integral term holds the 4 N against the drag with no error left (PI).
    assert forward == pytest.approx(0.8, abs=1e-6)
    assert abs(sideways) < 1e-12 and abs(omega) < 1e-12
    assert sim.q[0, 2] == pytest.approx(0.3, abs=1e-12)  # went straight along its heading


def test_a_turn_command_reaches_its_rate_about_the_axle():
    sim = robot_sim(drag=5.0, lateral_damping=200.0)
    drives = DriveSet(sim)
    drives.drives[0].receive(VelocityCommand(0, 0.5, 1.0))
    advance_with_drives(sim, drives, 15_000_000_000)
    forward, _, omega = body_speeds(sim.q, sim.v)
    assert omega == pytest.approx(1.0, abs=1e-5)
    # Forward speed of the axle centre, 0.1 m behind the CM: u_C = u_CM (no x offset term).
    assert forward == pytest.approx(0.5, abs=1e-4)


def test_capped_motors_accelerate_at_exactly_twice_the_cap_over_the_mass():
    cap = 2.0
    sim = robot_sim(max_force=cap, integrator="semi_implicit_euler")
    drives = DriveSet(sim)
    drives.drives[0].receive(VelocityCommand(0, 5.0, 0.0))
    pushes = []
    original = drives.drives[0].wrenches

    def spy(q, v, time_ns):
        commands = original(q, v, time_ns)
        pushes.extend(c.force[0] for c in commands)
        return commands

    drives.drives[0].wrenches = spy
    drives.run_in_kernel = lambda *args: None  # every instant on the Python path, spied on
    advance_with_drives(sim, drives, 1_000_000_000)
    assert len(pushes) == 200 and max(pushes) == cap
    forward, _, _ = body_speeds(sim.q, sim.v)
    assert forward == pytest.approx(2 * cap / MASS * 1.0, rel=1e-12)
    # The instants inside the kernel's runs (where it takes them) give the same bits.
    other = robot_sim(max_force=cap, integrator="semi_implicit_euler")
    other_drives = DriveSet(other)
    other_drives.drives[0].receive(VelocityCommand(0, 5.0, 0.0))
    advance_with_drives(other, other_drives, 1_000_000_000)
    assert other.q.tobytes() == sim.q.tobytes() and other.v.tobytes() == sim.v.tobytes()


def test_traction_caps_each_wheel_on_its_friction_circle():
    sim = robot_sim(traction=3.0, lateral_damping=1e3)
    drive = DriveSet(sim).drives[0]
    drive.receive(VelocityCommand(0, 5.0, 0.0))
    sim.v[0, :2] = (-2.0, 1.0)  # sliding sideways as well as backwards
    for command in drive.wrenches(sim.q, sim.v, 0):
        assert math.hypot(*command.force) == pytest.approx(3.0, rel=1e-15)
        assert command.force[0] > 0.0  # still pushing forward, scaled with the grip


def test_a_stale_cmd_vel_stops_the_push_and_the_body_coasts():
    sim = robot_sim(cmd_vel_timeout=0.5)
    drives = DriveSet(sim)
    drives.drives[0].receive(VelocityCommand(0, 1.0, 0.0))
    advance_with_drives(sim, drives, 500_000_000)
    assert not drives.drives[0].active(sim.time_ns)
    assert [c.force for c in drives.drives[0].wrenches(sim.q, sim.v, sim.time_ns)] == \
        [(0.0, 0.0), (0.0, 0.0)]
    advance_with_drives(sim, drives, 510_000_000)  # the last push has ended by now
    coasting = sim.v.copy()
    advance_with_drives(sim, drives, 2_000_000_000)
    assert np.array_equal(sim.v, coasting) and coasting[0, 0] > 0.1
    for _ in range(24):  # new commands, 4 a second for 6 s, brake it
        drives.drives[0].receive(VelocityCommand(sim.time_ns, 0.0, 0.0))
        advance_with_drives(sim, drives, sim.time_ns + 250_000_000)
    assert np.max(np.abs(sim.v)) < 1e-4 * coasting[0, 0]


def test_the_controller_state_round_trips():
    sim = robot_sim()
    drive = DriveSet(sim).drives[0]
    drive.receive(VelocityCommand(7, 0.5, -0.25))
    drive.wrenches(sim.q, sim.v, 10_000_000)
    copy = DriveSet(sim).drives[0]
    copy.import_state(drive.export_state())
    assert copy.export_state() == drive.export_state()
    assert copy.wrenches(sim.q, sim.v, 20_000_000) == drive.wrenches(sim.q, sim.v, 20_000_000)


def test_a_cmd_vel_whose_energy_no_double_holds_is_refused_and_the_last_one_kept():
    """1e308 m/s is finite, but 1/2 m v^2 is not: the PI's errors would overflow and the
    wheels' mix turn inf - inf into NaN forces, refused at every control instant until the
    timeout. The command is refused when it arrives, from a topic, a script or a keyframe;
    the largest speed a double's energy holds on this body is still taken."""
    sim = robot_sim()
    drives = DriveSet(sim)
    drive = drives.drives[0]
    drive.receive(VelocityCommand(0, 0.5, 0.0))
    for linear, angular in ((1e308, 0.0), (0.0, 1e308), (-2e154, 0.0)):
        with pytest.raises(InputError, match="energy of motion past what a double holds"):
            drives.receive("robot", VelocityCommand(1, linear, angular))
        assert drive.command == VelocityCommand(0, 0.5, 0.0)
    state = drive.export_state()
    state["command"] = [0, 1e308, 0.0]
    with pytest.raises(InputError, match="drive 'base'"):
        drive.import_state(state)
    drive.receive(VelocityCommand(2, 1e153, 0.0))  # 1/2 m v^2 of 1e306 J: a double
    assert all(math.isfinite(x) for w in drive.wrenches(sim.q, sim.v, 10_000_000)
               for x in w.force)
    with pytest.raises(InputError, match="energy of motion"):
        DriveSet(robot_sim(script=[0.0, 1e308, 0.0]))


def test_a_runaway_wheel_force_replacing_the_last_is_refused_as_a_push_is():
    """A drive whose wheels push 5e307 N on 10 kg from its second command on: each wheel
    force, given in place of the last one (push_replacements), is refused by the reach
    check as a first push is (one step takes the body past a double's energy), not applied
    and left to the divergence check at the next step."""
    sim = robot_sim(integrator="semi_implicit_euler", max_force=1e308, linear_kp=1e308,
                    linear_ki=0.0, script=[0.0, 0.0, 0.0, 0.1, 1.0, 0.0])
    drives, rejected = DriveSet(sim), []
    advance_with_drives(sim, drives, 100_000_000, rejected=rejected)  # to the first 0.1 s
    assert not rejected and sim.time_ns == 100_000_000
    before = sim.snapshot()
    advance_with_drives(sim, drives, 110_000_000, rejected=rejected)
    assert rejected and all("energy of motion past what a double holds" in line
                            for line in rejected), rejected
    assert np.isfinite(sim.q).all() and np.isfinite(sim.v).all()
    assert sim.time_ns == 110_000_000 and before.time_ns == 100_000_000


@pytest.mark.parametrize("drive, problem", [
    ({"body": "nobody"}, "unknown body"),
    ({"separation": 0.0}, "must be positive"),
    ({"rate": 7.0}, "not a whole number of physics steps"),
    ({"type": "tank"}, "must be one of diff_drive"),
])
def test_bad_drive_parameters_are_refused_by_name(drive, problem):
    with pytest.raises(SceneError, match=problem):
        robot_sim(**drive)


def test_a_scripted_command_holds_from_its_time_until_the_next_one():
    script = [0.25, 0.5, 0.0, 0.5, 0.0, 1.0]
    for play in (True, False):
        sim = robot_sim(script=script, cmd_vel_timeout=0.05)
        drives = DriveSet(sim)
        seen = []
        for t_ns in range(0, 800_000_000, 10_000_000):
            advance_with_drives(sim, drives, t_ns + sim.step_ns, play)  # through t_ns
            command = drives.drives[0].command
            seen.append(None if command is None else (command.linear_x, command.angular_z))
        if not play:
            assert set(seen) == {None}
            continue
        # Repeated at every control instant, so the 0.05 s timeout never stops it.
        assert seen[:25] == [None] * 25 and set(seen[25:50]) == {(0.5, 0.0)}
        assert set(seen[50:]) == {(0.0, 1.0)} and drives.drives[0].active(sim.time_ns)


def test_a_script_out_of_order_is_refused():
    with pytest.raises(SceneError, match="in order"):
        robot_sim(script=[1.0, 0.5, 0.0, 0.5, 0.0, 0.0])


def test_a_run_with_drives_publishes_what_the_node_loop_does():
    """play_with_drives (render's run) and the node's run loop push the drive forces at the
    same instants: the robot scene's published states agree bit for bit."""
    from hecker_dynamics.drives.control import play_with_drives
    from hecker_dynamics.ros.runner import Runner
    from hecker_dynamics.scene.load import load_scene
    scene = load_scene("robot")
    runner = Runner(scene, wall_clock=lambda: 0)
    looped = runner.advance(6_000_000_000).snapshots
    played = play_with_drives(Simulation(scene), scene.script, 6_000_000_000)
    assert len(played) == 300 and [s.bodies for s in played] == [s.bodies for s in looped]
    assert played[-1].bodies[2].position[0] > 3.0  # the robot drove across the room


def _reference_wrenches(drive, q, v, time_ns):
    """The control law of the module's docstring written out as lists, one wheel after
    the other: the oracle of the controller's plain-float form."""
    spec = drive.spec
    theta, (vx, vy, omega) = float(q[drive.body, 2]), v[drive.body].tolist()
    c, s = math.cos(theta), math.sin(theta)
    period = spec.period_ns * 1e-9
    integrals = list(drive.integrals)
    if drive.active(time_ns):
        u = c * vx + s * vy - omega * drive._axle[1]
        errors = (drive.command.linear_x - u, drive.command.angular_z - omega)
        force = spec.linear_kp * errors[0] + spec.linear_ki * (integrals[0] + errors[0] * period)
        torque = spec.angular_kp * errors[1] + spec.angular_ki * (
            integrals[1] + errors[1] * period)
        wanted = (force / 2.0 - torque / spec.separation, force / 2.0 + torque / spec.separation)
        pushes = [min(max(f, -spec.max_force), spec.max_force) for f in wanted]
        if pushes == list(wanted):
            integrals = [i + e * period for i, e in zip(integrals, errors)]
    else:
        pushes, integrals = [0.0, 0.0], [0.0, 0.0]
    forces = []
    for offset, push in zip(drive._offsets, pushes):
        grip = -spec.lateral_damping * (-s * vx + c * vy + omega * offset[0])
        scale = min(1.0, spec.traction / math.hypot(push, grip)) if (push or grip) else 1.0
        forces.append((push * scale, grip * scale))
    return forces, integrals


def _bits(values):
    return np.array(values, dtype=float).tobytes()


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("max_force", [5.0, 500.0])
def test_the_wheel_forces_have_the_bits_of_the_written_out_law(seed, max_force):
    """Random states and commands, capped or not, in traction or slipping, NaN commands
    included: the same wheel forces and integrals to the bit, at every control instant."""
    rng = np.random.default_rng(seed)
    sim = robot_sim(max_force=max_force, traction=8.0 * max_force / 5.0, lateral_damping=30.0,
                    cmd_vel_timeout=0.05)
    drive = DriveSet(sim).drives[0]
    time_ns = 0
    for instant in range(400):
        time_ns += drive.spec.period_ns
        q, v = sim.q.copy(), sim.v.copy()
        q[:, 2] = rng.uniform(-math.pi, math.pi)
        v[:] = rng.normal(0.0, 2.0, v.shape)
        if instant % 7 == 0:
            x, z = rng.normal(0.0, 1.5, 2)
            drive.command = VelocityCommand(time_ns, float(x), float(z))  # as received
        if instant == 200:
            drive.command = VelocityCommand(time_ns, math.nan, 0.5)  # past receive's check
        expected, integrals = _reference_wrenches(drive, q, v, time_ns)
        commands = drive.wrenches(q, v, time_ns)
        assert _bits([c.force for c in commands]) == _bits(expected)
        assert _bits(drive.integrals) == _bits(integrals)
        assert [c.point for c in commands] == list(drive.wheels)
        assert all(c.stamp_ns == time_ns and c.duration_ns == drive.spec.period_ns
                   for c in commands)
