"""Joint states and motor speeds as plain fields (hecker_dynamics.ros.joint_states)."""
from __future__ import annotations

import math

import pytest
from scene_builders import make_scene

from hecker_dynamics.dynamics import DivergenceError, Simulation
from hecker_dynamics.ros.joint_states import joint_state_fields, set_motor_speed
from hecker_dynamics.scene import InputError

SCENE = {
    "step": 0.001, "integrator": "velocity_verlet", "publish_rate": 10.0,
    "bodies": {"wheel": {"shape": "circle", "radius": 0.2, "mass": 1.0},
               "cart": {"shape": "box", "size": [0.2, 0.1], "mass": 2.0}},
    "joints": {"axle": {"type": "revolute", "body_b": "wheel",
                        "motor": {"speed": 2.0, "max_torque": 100.0}},
               "rail": {"type": "prismatic", "body_b": "cart", "axis": [1.0, 0.0]}},
}


def test_joint_state_fields_name_each_joint_with_its_state():
    sim = Simulation(make_scene(SCENE))
    for _ in range(100):
        sim.step()
    fields = joint_state_fields(sim, sim.time_ns)
    assert fields.name == ("axle", "rail")
    assert fields.header.frame_id == "world"
    assert fields.velocity[0] == pytest.approx(2.0, abs=1e-12)  # the motor holds its speed
    # A motor acts on velocities after the step's positions: the angle lags one step.
    assert fields.position[0] == pytest.approx(2.0 * (sim.time_ns * 1e-9 - 0.001), rel=1e-12)
    assert fields.position[1] == 0.0 and fields.velocity[1] == 0.0
    assert fields.effort == (0.0, 0.0)  # nothing resists: the motor gives no torque


def test_a_scene_without_joints_has_no_joint_state():
    scene = {"bodies": {"ball": {"shape": "circle", "radius": 0.1, "mass": 1.0}}}
    assert joint_state_fields(Simulation(make_scene(scene)), 0) is None


def test_a_motor_speed_command_is_held_and_bad_ones_are_refused():
    sim = Simulation(make_scene(SCENE))
    set_motor_speed(sim, "axle", -3.0)
    sim.step()
    assert joint_state_fields(sim, sim.time_ns).velocity[0] == pytest.approx(-3.0, abs=1e-12)
    with pytest.raises(InputError, match="no motor on joint 'rail'.*axle"):
        set_motor_speed(sim, "rail", 1.0)
    with pytest.raises(InputError, match="finite"):
        set_motor_speed(sim, "axle", math.nan)


def test_a_motor_speed_past_what_the_energy_bound_takes_is_refused():
    """The bound takes a motor's work at its largest effort times its target speed: 1e308
    rad/s at 20 N m made that power inf, and a spring blowing up beside the wheel ran 10 s
    to 1e151 m unseen, until no number was finite."""
    scene = make_scene({
        "step": 0.01, "integrator": "explicit_euler",
        "bodies": {"wheel": {"shape": "circle", "radius": 0.5, "mass": 1.0},
                   "bob": {"shape": "circle", "radius": 0.1, "mass": 1.0,
                           "position": [2.0, 0.0], "velocity": [0.0, 1.0]}},
        "joints": {"axle": {"type": "revolute", "body_b": "wheel",
                            "motor": {"speed": 0.0, "max_torque": 20.0}}},
        "forces": {"s": {"type": "spring", "body_a": "wheel", "point_a": [0.5, 0.0],
                         "body_b": "bob", "stiffness": 1e4, "rest_length": 1.0}}})
    sim = Simulation(scene)
    with pytest.raises(InputError, match=r"^motor speed for joint 'axle': 1e\+308 times the "
                                         r"motor's largest effort 20 is a power past what a "
                                         r"double holds$"):
        set_motor_speed(sim, "axle", 1e308)
    with pytest.raises(DivergenceError, match=r"bob, wheel diverged by t = 0\.12"):
        sim.advance_to(10_000_000_000, keep=False)  # its motor holds 0 rad/s


def test_each_publish_instant_carries_the_joint_states_of_its_own_time():
    """The node's outputs for a snapshot end with ``joint_states``: the joints' state when
    the snapshot was taken, not when it is published (the kernel steps past several
    publish instants in one call, and the pass keeps its efforts and turn counts)."""
    from hecker_dynamics.ros.outputs import OutputKind, SnapshotOutputs, output_topics
    scene = make_scene(SCENE)
    sim = Simulation(scene)
    snapshots = sim.advance_to(300_000_000)
    assert len(snapshots) == 3
    assert output_topics(scene)["joint_states"] is OutputKind.JOINT_STATE
    outputs = SnapshotOutputs(scene)
    angles = []
    for snapshot in snapshots:
        last = outputs(snapshot)[-1]
        assert (last.topic, last.kind) == ("joint_states", OutputKind.JOINT_STATE)
        assert (last.fields.header.sec, last.fields.header.nanosec) == \
            divmod(snapshot.time_ns, 1_000_000_000)
        angles.append(last.fields.position[0])
    # the motor turns the wheel at 2 rad/s: 0.2 rad between instants (less the lag's step)
    assert angles[1] - angles[0] == pytest.approx(0.2, abs=1e-9)
    assert angles[2] - angles[1] == pytest.approx(0.2, abs=1e-9)


def test_a_scene_without_joints_publishes_no_joint_states():
    from hecker_dynamics.ros.outputs import output_topics
    scene = make_scene({k: v for k, v in SCENE.items() if k != "joints"})
    assert "joint_states" not in output_topics(scene)
