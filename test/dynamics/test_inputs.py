"""Inputs (inputs.py, Simulation.push): hold / replace / duration / timeout, bad commands.

One free box (no forces, no walls), semi-implicit Euler, 1 ms steps: a constant force F
acting for n steps changes the velocity by exactly n h F / m up to the rounding of n
additions (n <= 1000 here, so 1e-12 relative is a safe bound and any missing or extra step,
1e-3 relative at least, fails it).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import make_scene, rotation

from hecker_dynamics import InputError, Simulation, WrenchCommand

MS = 1_000_000
MASS = 2.0
W, H = 1.0, 0.5
INERTIA = MASS * (W * W + H * H) / 12.0
REL = 1e-12


def _sim(timeout=0.5, lead=1.0, start_ns=0, **body):
    scene = make_scene({
        "step": 0.001, "integrator": "semi_implicit_euler", "input_timeout": timeout,
        "input_max_lead": lead,
        "bodies": {"b": {"parts": {"hull": {"shape": "box", "size": [W, H]}}, "mass": MASS,
                         "points": {"tip": [0.5, 0.0]}, **body},
                   "other": {"shape": "circle", "radius": 0.2, "mass": 1.0,
                             "position": [5.0, 0.0]}}})
    return Simulation(scene, start_ns=start_ns)


def cmd(stamp_ns, force=(1.0, 0.0), source="joy", frame="world", point=None, torque=0.0,
        duration_ns=0, body="b"):
    return WrenchCommand(stamp_ns=stamp_ns, body=body, source=source, frame_id=frame,
                         point=point if point is not None else (0.0, 0.0),
                         force=force, torque=torque, duration_ns=duration_ns)


def _world_point_at_cm(sim):
    return tuple(float(x) for x in sim.q[0, :2])


def _vx(sim):
    return float(sim.v[0, 0])


# ------------------------------------------------------------------ hold, replace, duration

def test_command_holds_until_replaced_by_same_body_and_id():
    sim = _sim(timeout=0.0)
    sim.push(cmd(0, (2.0, 0.0)))
    sim.advance_to(100 * MS)
    assert _vx(sim) == pytest.approx(2.0 * 0.1 / MASS, rel=REL)
    sim.push(cmd(100 * MS, (1.0, 0.0)))  # same (body, id): replaces
    sim.advance_to(300 * MS)
    assert _vx(sim) == pytest.approx((2.0 * 0.1 + 1.0 * 0.2) / MASS, rel=REL)


def test_different_id_or_body_does_not_replace():
    sim = _sim(timeout=0.0)
    sim.push(cmd(0, (2.0, 0.0), source="a"))
    sim.push(cmd(0, (0.0, 4.0), source="b"))  # another id: acts too
    sim.push(cmd(0, (3.0, 0.0), source="a", body="other"))  # same id, other body
    sim.advance_to(100 * MS)
    assert sim.v[0, :2] == pytest.approx([2.0 * 0.1 / MASS, 4.0 * 0.1 / MASS], rel=REL)
    assert sim.v[1, 0] == pytest.approx(3.0 * 0.1 / 1.0, rel=REL)


def test_duration_gives_impulse_f_times_duration_exactly_when_aligned():
    sim = _sim(timeout=0.0)
    sim.push(cmd(10 * MS, (4.0, -1.0), duration_ns=50 * MS))
    sim.advance_to(200 * MS)
    assert sim.v[0, :2] == pytest.approx(np.array([4.0, -1.0]) * 0.05 / MASS, rel=REL)


def test_duration_misaligned_stamp_is_within_one_step():
    """Stamp 0.4 ms into a step: starts at the next step (1 ms), ends at 50.4 ms: 50 steps,
    so the impulse is F * duration again (within one step F h in general)."""
    sim = _sim(timeout=0.0)
    sim.push(cmd(400_000, (4.0, 0.0), duration_ns=50 * MS))
    sim.advance_to(200 * MS)
    assert _vx(sim) == pytest.approx(4.0 * 0.05 / MASS, rel=REL)


def test_duration_command_is_not_cut_by_the_timeout():
    sim = _sim(timeout=0.5)
    sim.push(cmd(0, (1.0, 0.0), duration_ns=800 * MS))
    sim.advance_to(1000 * MS)
    assert _vx(sim) == pytest.approx(0.8 / MASS, rel=REL)


def test_input_timeout_stops_a_held_command():
    sim = _sim(timeout=0.5)
    sim.push(cmd(0, (1.0, 0.0)))
    sim.advance_to(1000 * MS)
    assert _vx(sim) == pytest.approx(0.5 / MASS, rel=REL)


def test_new_message_renews_the_timeout():
    sim = _sim(timeout=0.5)
    sim.push(cmd(0, (1.0, 0.0)))
    sim.advance_to(400 * MS)
    sim.push(cmd(400 * MS, (1.0, 0.0)))
    sim.advance_to(1500 * MS)
    assert _vx(sim) == pytest.approx(0.9 / MASS, rel=REL)


def test_timeout_zero_holds_forever():
    sim = _sim(timeout=0.0)
    sim.push(cmd(0, (1.0, 0.0)))
    sim.advance_to(1000 * MS)
    assert _vx(sim) == pytest.approx(1.0 / MASS, rel=REL)


def test_late_command_starts_at_the_next_step_and_keeps_its_end():
    """Stamped 5 ms in the past with a 20 ms duration: it acts from now (100 ms) until
    stamp + duration (115 ms): 15 steps."""
    sim = _sim(timeout=0.0)
    sim.advance_to(100 * MS)
    sim.push(cmd(95 * MS, (2.0, 0.0), duration_ns=20 * MS))
    sim.advance_to(300 * MS)
    assert _vx(sim) == pytest.approx(2.0 * 0.015 / MASS, rel=REL)


def test_command_stamped_between_steps_starts_at_the_following_step():
    sim = _sim(timeout=0.0)
    sim.advance_to(100 * MS)
    sim.push(cmd(100 * MS + 500_000, (2.0, 0.0)))
    sim.step()  # the step starting at 100 ms: not yet
    assert _vx(sim) == 0.0
    sim.step()  # starting at 101 ms: acts
    assert _vx(sim) == pytest.approx(2.0 * 0.001 / MASS, rel=REL)


def test_stamps_are_relative_to_a_large_start_time():
    """ROS stamps are ~1.7e18 ns; integer time keeps the 1 ms alignment exact there."""
    start = 1_700_000_000_123_000_000
    sim = _sim(timeout=0.0, start_ns=start)
    sim.push(cmd(start + 10 * MS, (4.0, 0.0), duration_ns=50 * MS))
    sim.advance_to(start + 200 * MS)
    assert _vx(sim) == pytest.approx(4.0 * 0.05 / MASS, rel=REL)


# ------------------------------------------------------------------ frames

def _one_step_acceleration(sim, command):
    sim.push(command)
    sim.step()
    return sim.v[0] / sim.step_seconds


@pytest.fixture
def turned():
    """Box with CM 0.2, 0.1 off its frame origin, origin at (1, 2), turned 0.6 rad."""
    def make():
        scene = make_scene({
            "step": 0.001, "integrator": "semi_implicit_euler", "input_timeout": 0.0,
            "bodies": {"b": {"parts": {"hull": {"shape": "box", "size": [W, H],
                                                "center": [0.2, 0.1]}},
                             "mass": MASS, "position": [1.0, 2.0], "angle": 0.6,
                             "points": {"tip": [0.7, 0.1]}}}})
        return Simulation(scene)
    return make


def _hand(force_world, point_world, torque=0.0):
    R = rotation(0.6)
    cm = np.array([1.0, 2.0]) + R @ np.array([0.2, 0.1])
    r = np.asarray(point_world) - cm
    f = np.asarray(force_world)
    alpha = (r[0] * f[1] - r[1] * f[0] + torque) / INERTIA
    return np.array([f[0] / MASS, f[1] / MASS, alpha])


def test_world_frame_force_and_point(turned):
    """Point and force in world coordinates: a = F/m, alpha = (perp(P - CM).F + tau)/I.
    Tolerance 1e-12 relative: one step from rest, a few flops of rounding."""
    a = _one_step_acceleration(turned(), cmd(0, (0.0, 2.0), point=(3.0, 1.0), torque=0.5))
    assert a == pytest.approx(_hand((0.0, 2.0), (3.0, 1.0), 0.5), rel=1e-12)


def test_body_frame_force_and_point_are_turned(turned):
    R = rotation(0.6)
    a = _one_step_acceleration(turned(), cmd(0, (1.0, 0.5), frame="b", point=(0.5, -0.25)))
    expected = _hand(R @ [1.0, 0.5], np.array([1.0, 2.0]) + R @ [0.5, -0.25])
    assert a == pytest.approx(expected, rel=1e-12)


def test_named_point_frame_has_origin_at_the_point_and_body_axes(turned):
    R = rotation(0.6)
    a = _one_step_acceleration(turned(), cmd(0, (0.0, 1.0), frame="b/tip", point=(0.1, 0.0),
                                             torque=-0.25))
    expected = _hand(R @ [0.0, 1.0], np.array([1.0, 2.0]) + R @ [0.8, 0.1], -0.25)
    assert a == pytest.approx(expected, rel=1e-12)


def test_force_at_the_cm_does_not_turn(turned):
    sim = turned()
    a = _one_step_acceleration(sim, cmd(0, (3.0, -1.0), point=_world_point_at_cm(sim)))
    assert a[:2] == pytest.approx([1.5, -0.5], rel=1e-12)
    assert abs(a[2]) <= 1e-12


# ------------------------------------------------------------------ refused commands

def _refusals(sim):
    """Bad commands at sim time ``sim.time_ns`` (timeout 0.5 s, lead 1 s)."""
    now = sim.time_ns
    return {
        "nan_force": cmd(now, (math.nan, 0.0)),
        "inf_force": cmd(now, (0.0, math.inf)),
        "nan_point": cmd(now, point=(0.0, math.nan)),
        "inf_torque": cmd(now, torque=-math.inf),
        "negative_duration": cmd(now, duration_ns=-1),
        "unknown_body": cmd(now, body="ghost"),
        "unknown_frame": cmd(now, frame="odom"),
        "unknown_point": cmd(now, frame="b/nowhere"),
        "unknown_frame_body": cmd(now, frame="ghost/tip"),
        "far_future": cmd(now + 1_000_000_001),
        "stale_duration": cmd(now - 300 * MS, duration_ns=200 * MS),
        "stale_timeout": cmd(now - 500 * MS),
        "ended_exactly_now": cmd(now - 100 * MS, duration_ns=100 * MS),
    }


@pytest.mark.parametrize("case", sorted(_refusals(_sim())))
def test_bad_command_is_refused_with_input_error(case):
    sim = _sim()
    sim.advance_to(1000 * MS)
    with pytest.raises(InputError) as caught:
        sim.push(_refusals(sim)[case])
    assert str(caught.value)


def test_limits_are_inclusive_where_they_should_be():
    sim = _sim()
    sim.advance_to(1000 * MS)
    sim.push(cmd(sim.time_ns + 1_000_000_000, source="lead"))  # exactly the lead: accepted
    sim.push(cmd(sim.time_ns - 499 * MS, source="late"))  # still within its timeout
    sim.push(cmd(sim.time_ns - 100 * MS, duration_ns=100 * MS + 1, source="just"))


def test_refused_commands_change_nothing():
    """Interleaving every refused command with good ones leaves the run bit-identical to
    the run with only the good ones."""
    def run(with_bad):
        sim = _sim(timeout=0.3)
        snapshots = []
        for k in range(5):
            now = sim.time_ns
            if with_bad:
                for bad in _refusals(sim).values():
                    with pytest.raises(InputError):
                        sim.push(bad)
            sim.push(cmd(now, (1.0, float(k)), frame="b/tip", point=(0.0, 0.1), torque=0.1))
            snapshots += sim.advance_to(now + 150 * MS)
        return sim.q.tobytes() + sim.v.tobytes(), snapshots
    assert run(True) == run(False)


def test_flood_of_pending_commands_is_refused_beyond_the_limit():
    sim = _sim(timeout=0.0)
    for k in range(10_000):
        sim.push(cmd(1 + k, (1.0, 0.0)))
    with pytest.raises(InputError, match="full"):
        sim.push(cmd(20_000, (1.0, 0.0)))
    # nothing was corrupted: the last accepted command (same id) is the one that acts
    sim.advance_to(100 * MS)
    assert _vx(sim) == pytest.approx(1.0 * 0.099 / MASS, rel=REL)


def test_flood_of_sources_is_refused_beyond_the_limit():
    sim = _sim(timeout=0.0)
    for k in range(1000):
        sim.push(cmd(0, (0.001, 0.0), source=f"s{k}"))
    with pytest.raises(InputError, match="sources"):
        sim.push(cmd(0, (1.0, 0.0), source="one_too_many"))
    sim.push(cmd(0, (0.002, 0.0), source="s7"))  # an existing source may still update
    sim.advance_to(10 * MS)
    assert _vx(sim) == pytest.approx((999 * 0.001 + 0.002) * 0.01 / MASS, rel=1e-10)


def _pushed_and_replaced(commands_at, late=()):
    """Two simulations fed the same commands: at each instant in ``commands_at`` (time in
    steps, commands), one pushes them and the other hands them to
    Simulation.push_replacements; ``late`` are pushed to both after the last instant's.
    Their buffers' exported states and next changes, and the states, after each instant
    and after a step from it."""
    runs = []
    for use_replace in (False, True):
        sim, seen = _sim(timeout=0.0), []
        for steps, commands in commands_at:
            while sim.steps < steps:
                sim.step()
            if use_replace:
                sim.push_replacements(commands)
            else:
                for command in commands:
                    sim.push(command)
            for command in late if steps == commands_at[-1][0] else ():
                sim.push(command)
            seen.append((sim.export_state()["inputs"], sim._inputs.next_change(),
                         len(sim._inputs)))
            sim.step()
            seen.append((sim.export_state(), sim.q.tobytes(), sim.v.tobytes()))
        runs.append(seen)
    return runs


def wheels(stamp_ns, force):
    return [cmd(stamp_ns, (force, 0.5), source="left", frame="b", point=(0.0, 0.2),
                duration_ns=2 * MS),
            cmd(stamp_ns, (force, -0.5), source="right", frame="b", point=(0.0, -0.2),
                duration_ns=2 * MS)]


def test_replaced_commands_queue_and_act_as_pushed_ones():
    """A drive's wheels replaced at each control instant (Simulation.push_replacements)
    leave the buffer, its keyframe data (the order numbers too) and the states as pushing
    them does:
    the first instant's (nothing active yet) and those after another command was pushed
    go through push; a command pushed after a replace queues behind the replaced ones."""
    instants = [(0, wheels(0, 1.0)), (2, wheels(2 * MS, 2.0)), (4, wheels(4 * MS, -3.0)),
                (6, wheels(6 * MS, 0.25)), (8, wheels(8 * MS, 4.0))]
    extra = cmd(8 * MS, (0.0, 1.0), source="joy", duration_ns=5 * MS)
    pushed, replaced = _pushed_and_replaced(instants, late=[extra])
    assert pushed == replaced
    # The buffer held the replaced commands as pending ones, with their order numbers.
    exported = pushed[2][0]
    assert [entry[:2] for entry in exported["pending"]] == [[2 * MS, 2], [2 * MS, 3]]
    assert pushed[2][1] == 2 * MS and pushed[2][2] == 4


def test_replace_takes_only_commands_stamped_now_of_active_sources():
    sim = _sim(timeout=0.0)
    buffer = sim._inputs
    for command in wheels(0, 1.0):
        sim.push(command)
    sim.step()
    sim.step()
    now = sim.time_ns
    rows = [sim._row(command) for command in wheels(now, 2.0)]
    assert not buffer.replace(wheels(now + MS, 2.0), rows, now)  # not stamped now
    assert not buffer.replace([cmd(now, source="new")], rows[:1], now)  # not active
    sim.push(cmd(now + MS, source="new"))
    assert not buffer.replace(wheels(now, 2.0), rows, now)  # another command is pending
    assert len(buffer) == 3


def test_next_change_and_update_follow_the_commands_held():
    """The buffer keeps the first end of its active commands as they change: at every
    point of a random run of pushes, replacements and updates, next_change is the first
    pending stamp or active end, and update changes something exactly when one of them
    has come (the active set compared with the buffer's exported state)."""
    rng = np.random.default_rng(7)
    sim = _sim(timeout=0.02)
    buffer = sim._inputs
    now = 0
    for _ in range(400):
        if rng.random() < 0.4:
            stamp = now + int(rng.integers(0, 5)) * MS
            sim.push(cmd(stamp, source=f"s{rng.integers(4)}",
                         duration_ns=int(rng.integers(0, 3)) * 3 * MS))
        state = buffer.export_state()
        ends = [buffer.end_of(held.command) for held in buffer.active()]
        expected = min([end for end in ends if end is not None] +
                       [entry[0] for entry in state["pending"]], default=None)
        assert buffer.next_change() == expected
        before = [held.command for held in buffer.active()]
        due = expected is not None and expected <= now
        assert buffer.update(now) == due
        if not due:
            assert [held.command for held in buffer.active()] == before
        now += int(rng.integers(0, 3)) * MS
