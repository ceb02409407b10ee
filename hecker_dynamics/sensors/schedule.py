"""When a scene's sensors sample: every sensor at ``start + k * period`` for k >= 1, as the
snapshots are published, each instant once.

The node's run loop (:class:`~hecker_dynamics.ros.runner.Runner`) stops the simulation at
every instant a sensor is due (:meth:`SensorSet.next_stop`) and samples there
(:meth:`SensorSet.sample`) as it steps on from it: after every command, input message and
world change made at that instant, so the IMU reads the accelerations with the inputs the
step from there takes (:meth:`Simulation.accelerations`), which are not the ones a
snapshot's state was reached with. What a reading holds then depends on the state and the
inputs the simulation leaves the instant with, and the stamp (the noise), not on when the
loop's ticks fell: a replay gives the same readings.
"""
from __future__ import annotations

import math
from typing import Optional, Union

from ..dynamics.simulation import Simulation
from ..scene.load import Scene
from ..scene.sensors import ImuSpec, LaserSpec
from .imu import Imu, ImuReading
from .laser import Laser, LaserScan

__all__ = ["SensorSet", "Reading"]

#: One sample of one sensor: its description and what it read.
Reading = Union[tuple[LaserSpec, LaserScan], tuple[ImuSpec, ImuReading]]


class SensorSet:
    """The sensors of ``scene`` as they run in ``sim`` (a simulation of it).

    ``sampled_ns``: the last instant sampled already (carried over when the world changes,
    None after a start or a restore: a keyframe is taken on arriving at its instant, before
    the sensors sample on leaving it)."""

    def __init__(self, scene: Scene, sim: Simulation,
                 sampled_ns: Optional[int] = None) -> None:
        cm_local = sim.model.cm_local
        self.sensors = [Laser(spec, scene, cm_local) if isinstance(spec, LaserSpec)
                        else Imu(spec, scene, cm_local) for spec in scene.sensors]
        self.start_ns = sim.start_ns
        self.sampled_ns = sampled_ns
        self._periods = [sensor.spec.period_ns for sensor in self.sensors]
        #: Every sample instant is a multiple of this after the start (the periods' gcd),
        #: so the next one after any instant in a cell of this length is the same.
        self._grid = math.gcd(*self._periods) or 1
        #: The cell (``(now - start) // grid``) :attr:`_next_ns` was worked out for.
        self._cell: Optional[int] = None
        self._next_ns: Optional[int] = None

    def __bool__(self) -> bool:
        return bool(self.sensors)

    def next_stop(self, now_ns: int) -> Optional[int]:
        """The first instant after ``now_ns`` a sensor samples at (None without sensors)."""
        cell = (now_ns - self.start_ns) // self._grid
        if cell != self._cell:
            self._cell = cell
            self._next_ns = min((self.start_ns + max(1, (now_ns - self.start_ns) // period + 1)
                                 * period for period in self._periods), default=None)
        return self._next_ns

    def sample(self, sim: Simulation) -> list[Reading]:
        """The readings of the sensors due at the simulation's present instant, in the
        scene's order of sensors (none when none is due or they sampled here already)."""
        now = sim.time_ns
        since = now - self.start_ns
        if now == self.sampled_ns or since <= 0 or since % self._grid:
            return []
        due = [sensor for sensor, period in zip(self.sensors, self._periods)
               if since % period == 0]
        if not due:
            return []
        self.sampled_ns = now
        readings: list[Reading] = []
        accelerations = None
        for sensor in due:
            if isinstance(sensor, Laser):
                readings.append((sensor.spec, sensor.scan(sim.q, now)))
            else:
                if accelerations is None:
                    accelerations = sim.accelerations()
                readings.append((sensor.spec, sensor.read(sim.q, sim.v, accelerations, now)))
        return readings
