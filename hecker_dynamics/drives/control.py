"""Running drives with a simulation: at each control instant every drive reads the state
and pushes its wheel forces as wrench commands, and the simulation steps on. The instants
are whole control periods after the simulation's start, so a replay computes the same
forces at the same steps; a velocity command takes effect at the next control instant."""
from __future__ import annotations

import bisect
from typing import Any, Optional, Union

from ..dynamics.simulation import Simulation, Snapshot
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
