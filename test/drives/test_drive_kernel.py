"""The differential drives' control instants inside the kernel's run (src/kernel/drive.c,
drives/control.py: DriveSet.run_in_kernel): the PI law, the wheel forces with their force
and traction caps, the cmd_vel timeout, the reach check of the wheel commands and the
energy bound's rates of them, taken between the run's steps. That must give the bits of
the drives' Python path, which pushes the wheel commands at every instant: every snapshot,
reading, keyframe, refused command and the state after each tick are compared as bytes,
on ticks that end on and off the drives' instants. Without the kernel both are the Python
path."""
from __future__ import annotations

import dataclasses
from typing import Optional

import numpy as np
import pytest

from hecker_dynamics.bench.sensors import robot_at_1khz
from hecker_dynamics.drives.command import VelocityCommand
from hecker_dynamics.drives.control import DriveSet
from hecker_dynamics.drives.diff_drive import DiffDrive
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.ros.runner import Runner
from hecker_dynamics.scene.load import Scene, load_scene

MS = 1_000_000

#: Twists given between ticks (tick index: forward speed, angular velocity).
Commands = dict[int, tuple[float, float]]


def run_outputs(scene: Scene, ticks: list[int], commands: Optional[Commands] = None,
                play_script: bool = True) -> tuple[list[bytes], list[str]]:
    """Every output of the node's loop ticking to each of ``ticks`` (from the start), with
    the twists of ``commands`` given before the ticks they name, as bytes (with the drives'
    and the inputs' state after each tick), and the refused commands."""
    runner = Runner(scene, record=True, keyframe_period_ns=250 * MS, play_script=play_script)
    out: list[bytes] = []
    errors: list[str] = []
    for index, target in enumerate(ticks):
        if commands and index in commands:
            runner.drives.receive("robot", VelocityCommand(runner.sim.time_ns,
                                                           *commands[index]))
        tick = runner.advance(runner.sim.start_ns + target)
        assert tick.diverged is None
        errors += tick.script_errors
        for snapshot in tick.snapshots:
            out.append(np.concatenate([*snapshot._state(), [[snapshot.energy] * 3]]).tobytes())
        out += [repr(reading).encode() for _, reading in tick.readings]
        out += [repr(record).encode() for record in runner.take_records()]
        out.append(np.concatenate([runner.sim.q, runner.sim.v]).tobytes())
        out.append(repr((runner.drives.export_state(),
                         runner.sim.export_state())).encode())
    return out, errors


def compare(scene: Scene, ticks: list[int], monkeypatch: pytest.MonkeyPatch,
            commands: Optional[Commands] = None, play_script: bool = True,
            python_share: float = 0.6) -> list[str]:
    """Run ``scene`` with the drives' instants in the kernel's run (where it takes them)
    and on the Python path alone; assert every output equal, and, with the kernel, that
    its runs took the instants between the loop's stops: less than ``python_share`` of
    them left to Python. The refused commands."""
    taken: list[int] = []
    wrenches = DiffDrive.wrenches

    def counted(self, q, v, time_ns):  # type: ignore[no-untyped-def]
        taken.append(time_ns)
        return wrenches(self, q, v, time_ns)

    monkeypatch.setattr(DiffDrive, "wrenches", counted)
    inside, inside_errors = run_outputs(scene, ticks, commands, play_script)
    inside_calls = len(taken)
    monkeypatch.setattr(DriveSet, "run_in_kernel", lambda *args: None)
    taken.clear()
    python, python_errors = run_outputs(scene, ticks, commands, play_script)
    assert len(inside) == len(python) > 2 * len(ticks)
    for k, (a, b) in enumerate(zip(inside, python)):
        assert a == b, f"output {k} differs"
    assert inside_errors == python_errors
    instants = len(taken)
    assert instants >= ticks[-1] // (10 * MS)  # one a control period on the Python path
    if kernel.enabled():
        # The instants the loop stops at anyway (the IMU's, every 20 ms) stay Python's.
        assert inside_calls < python_share * instants
    else:
        assert inside_calls == instants
    return python_errors


@pytest.mark.parametrize("shift_ms", [0, 7])
def test_the_robot_scene_gives_the_bits_of_the_python_path(shift_ms, monkeypatch):
    ticks = [k * 20 * MS + (shift_ms * MS if k % 3 else 0) for k in range(1, 301)]
    assert compare(robot_at_1khz(), ticks, monkeypatch) == []


def test_the_robot_scene_at_its_own_step_gives_the_bits_of_the_python_path(monkeypatch):
    scene = load_scene("robot")
    ticks = [k * 20 * MS + (2 * MS if k % 2 else 0) for k in range(1, 201)]
    assert compare(scene, ticks, monkeypatch) == []


def capped(scene: Scene, **changes: float) -> Scene:
    """``scene`` with its drive's parameters changed."""
    drive = dataclasses.replace(scene.drives[0], **changes)
    return dataclasses.replace(scene, drives=(drive,))


def test_force_and_traction_caps_and_the_timeout_give_the_bits_of_the_python_path(
        monkeypatch):
    # Caps that bind (the integrals stop, the wheels slip), twists from cmd_vel whose
    # 50 ms timeout runs out inside the kernel's runs, and no script.
    scene = capped(robot_at_1khz(), max_force=3.0, traction=3.5,
                   cmd_vel_timeout_ns=50 * MS)
    ticks = [k * 20 * MS + (3 * MS if k % 2 else 0) for k in range(1, 151)]
    commands = {5: (0.8, 0.0), 20: (0.4, 1.0), 60: (-0.5, -2.0), 61: (0.0, 0.0),
                100: (1.0, 0.5)}
    assert compare(scene, ticks, monkeypatch, commands, play_script=False) == []


def test_refused_wheel_commands_give_the_bits_of_the_python_path(monkeypatch):
    # Gains and caps so large that a wheel's force would give the robot an energy of
    # motion past a double's range in one step: the simulation refuses the commands at
    # that instant (Simulation.check_reach), which the kernel's run leaves to Python.
    scene = capped(robot_at_1khz(), max_force=1e300, traction=1e300, linear_kp=1e305)
    ticks = [k * 20 * MS for k in range(1, 41)]
    errors = compare(scene, ticks, monkeypatch, python_share=0.9)  # none between refusals
    assert errors and all(error.startswith("drive force rejected: wrench for body 'robot'")
                          for error in errors)


@pytest.mark.skipif(not kernel.built(), reason="the kernel is not built")
def test_the_drive_columns_are_the_kernels():
    compiled = kernel._kernel
    assert (compiled.DRIVE_INTS, compiled.DRIVE_REALS) == (kernel.DRIVE_INTS, kernel.DRIVE_REALS)
    assert kernel.DRIVE_MOST == compiled.DRIVE_MOST >= 1
