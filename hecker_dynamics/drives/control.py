"""Running drives with a simulation: at each control instant every drive reads the state
and pushes its wheel forces as wrench commands, and the simulation steps on. The instants
are whole control periods after the simulation's start, so a replay computes the same
forces at the same steps; a velocity command takes effect at the next control instant.
Where the compiled kernel steps and every input is a differential drive's wheel, its runs
take the instants between their steps (:meth:`DriveSet.run_in_kernel`), with the same
bits."""
from __future__ import annotations

import bisect
from typing import Any, Optional, Union

import numpy as np

from ..dynamics.kernel import DRIVE_INTS, DRIVE_MOST, DRIVE_REALS, DriveInt, DriveReal
from ..dynamics.simulation import DrivenWheels, Simulation, Snapshot
from ..scene.commands import InputError, WrenchCommand
from ..scene.drives import DiffDriveSpec
from .command import VelocityCommand
from .diff_drive import DiffDrive
from .wrench_drive import WrenchDrive

__all__ = ["DriveSet", "advance_with_drives", "play_with_drives"]


class DriveSet:
    """The controllers of a simulation's drives and the step of each one's next control
    instant."""

    def __init__(self, sim: Simulation) -> None:
        model, bodies = sim.model, sim.scene.bodies
        self.drives: list[Union[DiffDrive, WrenchDrive]] = []
        for spec in sim.scene.drives:
            i = model.index[spec.body]
            self.drives.append(DiffDrive(spec, i, model.cm_local[i], bodies[i].mass)
                               if isinstance(spec, DiffDriveSpec) else
                               WrenchDrive(spec, i, model.cm_local[i], bodies[i].mass))
        self._next_ns = [sim.time_ns] * len(self.drives)
        #: Per drive, its script's times (from the start) and commands (linear x, angular
        #: z, linear y): a diff drive's entries are (t, x, z), the others' (t, x, y, z).
        self._script_times = [[entry[0] for entry in drive.spec.script] for drive in self.drives]
        self._script_commands = [[(x, rest[-1], rest[0] if len(rest) == 2 else 0.0)
                                  for _, x, *rest in drive.spec.script]
                                 for drive in self.drives]
        for drive, commands in zip(self.drives, self._script_commands):
            for command in commands:
                drive.check(VelocityCommand(0, *command))
        #: The drives' columns for the kernel's run (:meth:`run_in_kernel`), built when
        #: first asked for (None: not yet, or not for these drives), and per drive what of
        #: it they hold: its script's command due, its own command, integrals and next
        #: instant when last written.
        self._wheels: Optional[DrivenWheels] = None
        self._written: list[Any] = []

    def __bool__(self) -> bool:
        return bool(self.drives)

    def receive(self, body: str, command: VelocityCommand) -> None:
        """Give ``command`` to every drive of ``body`` (:class:`InputError` where a drive
        refuses it: :meth:`.CommandedDrive.check`)."""
        for drive in self.drives:
            if drive.spec.body == body:
                drive.receive(command)

    def arrive(self, sim: Simulation, play_script: bool = True,
               rejected: Optional[list[str]] = None) -> None:
        """Push the wheel forces of the drives whose control instant is now, each after the
        scripted command that holds now (with ``play_script``). ``rejected``: where wheel
        forces the simulation refuses are told (else its :class:`InputError` is raised)."""
        now = sim.time_ns
        for index, drive in enumerate(self.drives):
            if now >= self._next_ns[index]:
                due = bisect.bisect_right(self._script_times[index], now - sim.start_ns) \
                    if play_script else 0
                if due:  # a script's commands were checked when the set was built
                    drive.command = VelocityCommand(now, *self._script_commands[index][due - 1])
                try:
                    sim.push_replacements(drive.wrenches(sim.q, sim.v, now))
                except InputError as error:
                    if rejected is None:
                        raise
                    rejected.append(f"drive force rejected: {error}")
                self._next_ns[index] = now + drive.spec.period_ns

    def run_in_kernel(self, sim: Simulation, t_ns: int, play_script: bool,
                      max_steps: Optional[int], keep: bool) -> Optional[list[Snapshot]]:
        """:meth:`Simulation.run_drives` towards ``t_ns``: one run of the kernel that takes
        the differential drives' control instants after now between its steps, with the
        bits of :meth:`arrive` (``play_script`` as it takes it), up to the next instant at
        which a drive's script changes its command; the snapshots it passed, or None where
        the kernel cannot take them (drives of other kinds, an instant off the step grid,
        other inputs than the wheels: :meth:`Simulation.run_drives`)."""
        wheels = self._wheels if self._wheels is not None else self._columns(sim)
        if wheels is None:
            return None
        now, step, start = sim.time_ns, sim.step_ns, sim.start_ns
        end = t_ns
        for k, drive in enumerate(self.drives):
            next_ns = self._next_ns[k]
            if next_ns <= now or (next_ns - now) % step:
                return None
            times = self._script_times[k]
            due = 0
            if play_script and times:  # the script's next command is Python's
                due = bisect.bisect_right(times, now - start)
                if due < len(times):
                    end = min(end, start + times[due])
            state = (due, None if due else drive.command, drive.integrals, next_ns)
            if state != self._written[k]:
                self._write(k, due, next_ns)
                self._written[k] = state
        try:
            return sim.run_drives(end, max_steps, keep, wheels)
        finally:  # a run that diverged took its instants too
            self._take(wheels, now)

    def _columns(self, sim: Simulation) -> Optional[DrivenWheels]:
        """The drives' columns for the kernel's run (:class:`.DrivenWheels`), their
        constants filled in, kept for the set's lifetime; None where it cannot take them."""
        drives, step = self.drives, sim.step_ns
        if self._written or not drives or len(drives) > DRIVE_MOST or \
                not all(isinstance(drive, DiffDrive) and drive.spec.period_ns % step == 0
                        for drive in drives):
            self._written = [None] * len(drives)  # asked once
            return None
        ints = np.zeros((len(drives), DRIVE_INTS), dtype=np.int64)
        reals = np.zeros((len(drives), DRIVE_REALS))
        keys: list[tuple[str, str]] = []
        for k, drive in enumerate(drives):
            assert isinstance(drive, DiffDrive)
            spec = drive.spec
            ints[k, DriveInt.BODY], ints[k, DriveInt.PERIOD_NS] = drive.body, spec.period_ns
            reals[k, DriveReal.PERIOD:DriveReal.MASS] = (
                spec.period_ns * 1e-9, spec.linear_kp, spec.linear_ki, spec.angular_kp,
                spec.angular_ki, spec.separation, spec.max_force, spec.traction,
                spec.lateral_damping, *drive.kernel_offsets())
            keys += [(spec.body, source) for source in drive.sources]
        self._written = [None] * len(drives)
        self._wheels = DrivenWheels(keys, ints, reals, self._next_ns)
        return self._wheels

    def _write(self, index: int, due: int, next_ns: int) -> None:
        """Write what drive ``index`` holds now into its columns: its command (the script's
        ``due``-th, stamped anew at each instant, where ``due``), integrals and next instant."""
        assert self._wheels is not None
        drive = self.drives[index]
        command = drive.command
        x = z = 0.0
        if due:
            x, z, _ = self._script_commands[index][due - 1]
        elif command is not None:
            x, z = command.linear_x, command.angular_z
        stamp = 0 if command is None else command.stamp_ns
        self._wheels.ints[index, DriveInt.COMMANDED:DriveInt.NEXT_NS + 1] = (
            due > 0 or command is not None, due > 0, stamp, drive.timeout_ns, next_ns)
        self._wheels.reals[index, DriveReal.LINEAR_X:DriveReal.INTEGRAL_W + 1] = (
            x, z, *drive.integrals)

    def _take(self, wheels: DrivenWheels, start_ns: int) -> None:
        """Take back what a kernel's run from sim time ``start_ns`` made of the drives (none
        where it did not run): their integrals, next instants and, where a script's command
        was stamped anew, that command with its last stamp."""
        for k, (i, r) in enumerate(zip(wheels.ints.tolist(), wheels.reals.tolist())):
            if not i[DriveInt.INSTANTS] or i[DriveInt.LAST_NS] <= start_ns:
                continue
            drive = self.drives[k]
            drive.integrals = r[DriveReal.INTEGRAL_V:DriveReal.LEFT_X]
            self._next_ns[k] = i[DriveInt.NEXT_NS]
            due, command, _, _ = self._written[k]
            if due:
                drive.command = VelocityCommand(i[DriveInt.STAMP_NS],
                                                *self._script_commands[k][due - 1])
            self._written[k] = (due, command, drive.integrals, self._next_ns[k])

    def next_stop(self) -> int | None:
        """The next control instant (None without drives)."""
        return min(self._next_ns) if self._next_ns else None

    def export_state(self) -> list[dict[str, Any]]:
        return [dict(drive.export_state(), next_ns=next_ns)
                for drive, next_ns in zip(self.drives, self._next_ns)]

    def import_state(self, state: list[dict[str, Any]]) -> None:
        for index, (drive, data) in enumerate(zip(self.drives, state)):
            drive.import_state(data)
            self._next_ns[index] = int(data["next_ns"])


def advance_with_drives(sim: Simulation, drives: DriveSet, t_ns: int,
                        play_script: bool = True, max_steps: Optional[int] = None,
                        keep: bool = True, rejected: Optional[list[str]] = None
                        ) -> list[Snapshot]:
    """:meth:`Simulation.advance_to` ``t_ns`` (at most ``max_steps``; snapshots kept as
    ``keep`` says), pushing the drives' wheel forces at their control instants on the way
    (after their scripted commands, with ``play_script``); the snapshots at the publish
    instants. ``rejected``: as :meth:`DriveSet.arrive` takes it."""
    snapshots: list[Snapshot] = []
    start = sim.steps
    while sim.time_ns + sim.step_ns <= t_ns:
        taken = sim.steps - start
        if max_steps is not None and taken >= max_steps:
            break
        drives.arrive(sim, play_script, rejected)
        ran = drives.run_in_kernel(sim, t_ns, play_script,
                                   None if max_steps is None else max_steps - taken, keep)
        if ran is not None:
            snapshots += ran
            continue
        following = drives.next_stop()
        snapshots += sim.advance_to(t_ns if following is None else min(t_ns, following),
                                    None if max_steps is None else max_steps - taken,
                                    keep=keep)
    return snapshots


def play_with_drives(sim: Simulation, commands: tuple[WrenchCommand, ...],
                     until_ns: int) -> list[Snapshot]:
    """:meth:`Simulation.play` with the scene's drives (and their scripts) running: push
    ``commands`` (stamps relative to the start) as sim time reaches each stamp and advance
    to ``until_ns`` after the start; the snapshots at the publish instants."""
    drives = DriveSet(sim)
    return sim.play(commands, until_ns,
                    advance=lambda t_ns: advance_with_drives(sim, drives, t_ns))
