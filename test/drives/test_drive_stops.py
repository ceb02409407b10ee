"""The drives' control instants inside the node loop's steps (drives/control.py:
advance_with_drives, called by Runner.advance): the loop stops only where it has other
work (sensors, keyframes, scripted wrenches, the tick's end), and the drives push their
wheel forces at the instants in between as the simulation steps there. That must give the
bits the loop gave when it stopped at every control instant too: every snapshot, reading,
keyframe and the state after each tick are compared as bytes, on ticks that end on and off
the drives' instants."""
from __future__ import annotations

import numpy as np
import pytest

from hecker_dynamics.bench.sensors import robot_at_1khz
from hecker_dynamics.ros.runner import Runner

MS = 1_000_000


def run_outputs(scene, ticks: list[int]) -> tuple[list[bytes], int]:
    """Every output of the node's loop ticking to each of ``ticks`` (from the start), as
    bytes, and how many times the loop stepped on from an instant."""
    runner = Runner(scene, record=True, keyframe_period_ns=250 * MS)
    out: list[bytes] = []
    stops = 0
    leave = runner.leave

    def counted():
        nonlocal stops
        stops += 1
        return leave()

    runner.leave = counted
    for target in ticks:
        tick = runner.advance(runner.sim.start_ns + target)
        assert tick.diverged is None and not tick.script_errors
        for snapshot in tick.snapshots:
            out.append(np.concatenate([*snapshot._state(), [[snapshot.energy] * 3]]).tobytes())
        out += [repr(reading).encode() for _, reading in tick.readings]
        out += [repr(record).encode() for record in runner.take_records()]
        out.append(np.concatenate([runner.sim.q, runner.sim.v]).tobytes())
    return out, stops


@pytest.mark.parametrize("shift_ms", [0, 7])
def test_control_instants_between_stops_give_the_bits_of_stopping_there(shift_ms,
                                                                       monkeypatch):
    scene = robot_at_1khz()
    ticks = [k * 20 * MS + (shift_ms * MS if k % 3 else 0) for k in range(1, 76)]
    inside, inside_stops = run_outputs(scene, ticks)
    next_stop = Runner._next_stop

    def every_control_instant(runner):
        following = runner.drives.next_stop()
        return min(next_stop(runner), following)

    monkeypatch.setattr(Runner, "_next_stop", every_control_instant)
    stopping, stops = run_outputs(scene, ticks)
    assert len(inside) == len(stopping) > 75 * 2
    for k, (a, b) in enumerate(zip(inside, stopping)):
        assert a == b, f"output {k} differs"
    # 1.5 s: 150 control instants, of which the 75 at the IMU's 50 Hz instants stop anyway.
    assert stops - inside_stops >= 70
