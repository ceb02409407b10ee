"""Inputs whose values alone change (Simulation._update_inputs, InputBuffer.values_only,
ConstantWrenchTerm.with_values): at a drive's control instant its wheel commands replace
the previous ones at the same points, and the input set takes the new forces in place
instead of being built again. That must give the bits a rebuild gives.

Each run is the node's loop (:class:`Runner`) over a shipped driven scene, its steps,
snapshots, sensor readings and keyframes, once as it runs and once with every change of
the inputs rebuilt from the active rows (``same_place`` never true: the input set as it
was built before the in-place path), on the kernel, the plain-float and the numpy paths.
The scenes add scripted wrenches on other bodies, with durations, so that the input set
also grows, shrinks and takes the drive's values between those changes. Bits are compared
as bytes: any difference in any output fails.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hecker_dynamics.dynamics import inputs, kernel
from hecker_dynamics.dynamics.forces import ConstantWrenchTerm, WrenchRow
from hecker_dynamics.dynamics.inputs import same_place
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.scene.commands import WrenchCommand
from hecker_dynamics.scene.load import load_scene

MS = 1_000_000
#: Wrenches on the scenes' other bodies: one held past the drive's instants, one ending
#: between them, a torque, and one in the fixed frame, so the set changes around them.
EXTRA = {"robot": "crate", "kiwi": "crate_a"}
PATHS = ("kernel", "lean", "numpy")


def with_extra_inputs(name: str):
    scene = load_scene(name)
    other = EXTRA[name]
    script = (
        WrenchCommand(300 * MS, other, "push", other, (0.1, 0.05), (2.0, -1.0),
                      duration_ns=700 * MS),
        WrenchCommand(505 * MS, other, "kick", "world", (0.0, 0.0), (0.0, 3.0), 0.2,
                      duration_ns=33 * MS),
        WrenchCommand(640 * MS, other, "push", other, (-0.1, 0.0), (1.0, 0.0),
                      duration_ns=150 * MS),
        WrenchCommand(900 * MS, scene.drives[0].body, "bump", "world", (0.5, 0.5),
                      (0.0, -4.0), duration_ns=7 * MS),
    )
    return dataclasses.replace(scene, script=tuple(sorted(scene.script + script,
                                                          key=lambda c: c.stamp_ns)))


def run_outputs(scene, path: str, seconds: float) -> list[bytes]:
    """Every output of the node's loop over ``seconds`` in 20 ms ticks, as bytes."""
    runner = Runner(scene, record=True, keyframe_period_ns=250 * MS)
    if path != "kernel":
        runner.sim.model.use_python(lean=path == "lean")
    out: list[bytes] = []
    for k in range(1, round(seconds * 50) + 1):
        tick = runner.advance(runner.sim.start_ns + k * 20 * MS)
        assert tick.diverged is None and not tick.script_errors
        for snapshot in tick.snapshots:
            out.append(np.concatenate([*snapshot._state(), [[snapshot.energy] * 3]]).tobytes())
        out += [repr(reading).encode() for _, reading in tick.readings]
        out += [repr(record).encode() for record in runner.take_records()]
        out.append(np.concatenate([runner.sim.q, runner.sim.v,
                                   runner.sim.accelerations()]).tobytes())
    return out


@pytest.fixture(params=PATHS)
def path(request, monkeypatch):
    if request.param == "kernel":
        pytest.importorskip("hecker_dynamics._kernel", reason="the kernel is not built")
        monkeypatch.delenv(kernel.SWITCH, raising=False)
    return request.param


@pytest.mark.parametrize("name", ["robot", "kiwi"])
def test_drive_values_taken_in_place_give_the_bits_of_a_rebuilt_input_set(name, path,
                                                                          monkeypatch):
    scene = with_extra_inputs(name)
    taken = []
    in_place = ConstantWrenchTerm.with_values

    def counted(term, rows):
        taken.append(len(rows))
        return in_place(term, rows)

    monkeypatch.setattr(ConstantWrenchTerm, "with_values", counted)
    fast = run_outputs(scene, path, 1.2)
    monkeypatch.setattr(inputs, "same_place", lambda a, b: False)
    rebuilt = run_outputs(scene, path, 1.2)
    # The in-place path ran at nearly every control instant (100 or 50 a second)...
    period_ms = scene.drives[0].period_ns // MS
    assert len(taken) >= 1200 // period_ms - 20
    # ... and with the other wrenches acting too.
    assert max(taken) > len(getattr(scene.drives[0], "actuators", (1, 2)))
    assert len(fast) == len(rebuilt)
    for k, (a, b) in enumerate(zip(fast, rebuilt)):
        assert a == b, f"output {k} differs"


def row(point, body=0, axes=0, owner=0, at_point=True, force=(1.0, 2.0)):
    return WrenchRow(body, force, 0.0, axes, owner, point, at_point)


def point(x: float, y: float) -> tuple[float, float]:
    """A tuple of its own (a literal's would be shared by the compiler)."""
    return tuple([x, y])  # type: ignore[return-value]


def test_same_place_tells_a_zero_from_a_negative_zero_unless_the_point_is_shared():
    shared = point(0.0, 0.25)
    assert same_place(row(shared), row(shared, force=(3.0, -1.0)))
    assert same_place(row(point(0.5, 0.25)), row(point(0.5, 0.25)))  # no zero: the same bits
    assert not same_place(row(point(0.0, 0.25)), row(point(0.0, 0.25)))  # a zero's sign
    assert not same_place(row(point(0.0, 0.25)), row(point(-0.0, 0.25)))
    assert not same_place(row(point(0.5, 0.25)), row(point(0.5, 0.2500000000000001)))
    assert not same_place(row(shared), row(shared, body=1))
    assert not same_place(row(shared), row(shared, axes=-1))
    assert not same_place(row(shared), row(shared, owner=-1))
    assert not same_place(row(shared), row(shared, at_point=False))


def test_a_command_s_place_is_resolved_once_and_keeps_the_sign_of_a_zero():
    sim = Simulation(load_scene("robot"))
    first = sim._row(WrenchCommand(0, "robot", "a", "world", (0.0, 0.5), (1.0, 0.0)))
    again = sim._row(WrenchCommand(0, "robot", "b", "world", (0.0, 0.5), (0.0, 2.0)))
    negative = sim._row(WrenchCommand(0, "robot", "c", "world", (-0.0, 0.5), (1.0, 0.0)))
    assert again.point is first.point and again.force == (0.0, 2.0)
    assert negative.point is not first.point
    assert math.copysign(1.0, negative.point[0]) == -1.0
