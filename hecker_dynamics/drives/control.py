"""Running drives with a simulation: every control period each drive reads the state and
pushes its wheel forces as wrench commands, then the simulation steps to the next control
instant. The instants are whole control periods after the simulation's start, so a replay
computes the same forces at the same steps."""
from __future__ import annotations

from ..dynamics.simulation import Simulation, Snapshot
from .diff_drive import DiffDrive

__all__ = ["drives_of", "advance_with_drives"]


def drives_of(sim: Simulation) -> list[DiffDrive]:
    """A controller for each of the scene's drives."""
    model = sim.model
    return [DiffDrive(spec, model.index[spec.body], model.cm_local[model.index[spec.body]])
            for spec in sim.scene.drives]


def advance_with_drives(sim: Simulation, drives: list[DiffDrive], t_ns: int) -> list[Snapshot]:
    """:meth:`Simulation.advance_to` ``t_ns``, pushing each drive's wheel forces at every
    one of its control instants on the way; the snapshots at the publish instants."""
    snapshots: list[Snapshot] = []
    while sim.time_ns + sim.step_ns <= t_ns:
        now = sim.time_ns - sim.start_ns
        for drive in drives:
            if now % drive.spec.period_ns == 0:
                for command in drive.wrenches(sim.q, sim.v, sim.time_ns):
                    sim.push(command)
        periods = [d.spec.period_ns for d in drives]
        following = min((now // p + 1) * p for p in periods) if periods else t_ns
        snapshots += sim.advance_to(min(t_ns, sim.start_ns + following))
    return snapshots
