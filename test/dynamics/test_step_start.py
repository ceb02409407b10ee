"""Simulation.step_start: the state the step that ended now began from, as the IMU's
accelerometer needs it (sensors/imu.py), kept in Python and in the kernel's runs alike.

Exact properties: the kept state must equal, to the bit, the state a second simulation of
the same scene has one step earlier (the runs are deterministic), whatever way the steps
were taken (one call of many steps, runs checked at publish instants, joint passes,
contacts, sleeping bodies); and it must be unknown wherever no step led to the present
state from it.
"""
from __future__ import annotations

import numpy as np
import pytest

from hecker_dynamics.bench.pyramid import pyramid
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.scene import load_scene
from hecker_dynamics.scene.load import Scene

MS = 1_000_000


@pytest.fixture(autouse=True, params=["1", "0"], ids=["kernel", "python"])
def switch(request, monkeypatch):
    """Every run steps in the kernel (where built) and in Python."""
    monkeypatch.setenv(kernel.SWITCH, request.param)


def _before(scene: Scene, until_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """The state one step before ``until_ns``, reached by a simulation of its own."""
    sim = Simulation(scene)
    sim.advance_to(until_ns - scene.step_ns)
    return sim.q.copy(), sim.v.copy()


# sample: springs and contacts; chain: the joint pass, steps in parts; bridge: joints and
# contacts; ship: free bodies, runs checked in the kernel at the publish instants.
@pytest.mark.parametrize("name", ["sample", "chain", "bridge", "ship", "robot"])
def test_the_kept_start_is_the_state_one_step_before(name):
    scene = load_scene(name)
    sim = Simulation(scene)
    sim.keep_step_starts()
    for until in (7 * scene.step_ns, 1000 * MS + 3 * scene.step_ns, 2000 * MS):
        sim.advance_to(until)
        start = sim.step_start()
        assert start is not None
        q0, v0 = _before(scene, sim.time_ns)
        assert start[0].tobytes() == q0.tobytes() and start[1].tobytes() == v0.tobytes()


def test_a_step_of_sleeping_bodies_began_where_it_ended():
    # The bench's pyramid of 3 rows rests on its floor within a second and, with sleeping
    # on, its island sleeps: a step that skips it leaves the state as it was, and so
    # began from it.
    scene = pyramid(3, duration=2.0, sleep=True)
    sim = Simulation(scene)
    sim.keep_step_starts()
    sim.advance_to(1500 * MS)
    assert sim.model.contacts is not None and sim.model.contacts.everything_asleep()
    start = sim.step_start()
    assert start is not None
    q0, v0 = _before(scene, sim.time_ns)
    assert start[0].tobytes() == q0.tobytes() and start[1].tobytes() == v0.tobytes()


def test_no_start_where_no_step_led_to_the_state():
    scene = load_scene("sample")
    sim = Simulation(scene)
    sim.advance_to(100 * MS)
    assert sim.step_start() is None  # not kept
    sim.keep_step_starts()
    assert sim.step_start() is None  # kept from now on only
    sim.advance_to(200 * MS)
    assert sim.step_start() is not None
    state = sim.export_state()
    sim.set_body_state("left", (0.0, 1.0), 0.0, (0.0, 0.0), 0.0)
    assert sim.step_start() is None  # moved
    sim.advance_to(300 * MS)
    sim.import_state(state)
    assert sim.step_start() is None  # imported
    sim.advance_to(400 * MS)
    sim.skip_to(sim.time_ns + 10 * scene.step_ns)
    assert sim.step_start() is None  # the clock skipped
    sim.advance_to(500 * MS)
    sim.reset()
    assert sim.step_start() is None  # back at the start
