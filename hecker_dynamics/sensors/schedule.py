"""When a scene's sensors sample: every sensor at ``start + k * period`` for k >= 1, as the
snapshots are published, each instant once.

The node's run loop (:class:`~hecker_dynamics.ros.runner.Runner`) stops the simulation at
every instant a sensor is due (:meth:`SensorSet.next_stop`) and samples there
(:meth:`SensorSet.sample`) as it steps on from it: after every command, input message and
world change made at that instant. A laser scans the state it leaves the instant with; an
IMU's gyro and orientation read that state too, and its accelerometer what the step that
ended at the instant did (:mod:`.imu`): on arriving at the IMU's instant, before anything
is made there, :meth:`SensorSet.arrive` turns the state that step began from (kept by the
simulation, in Python or in the kernel's run: :meth:`Simulation.step_start`) and the
step's own into the specific force the sample reads. What a world change, a restore or a
keyframe meets between the two is at most the measured specific forces waiting for their
sample (:meth:`SensorSet.export_state`). What a reading holds then depends on the states,
the inputs and the stamp (the noise), not on when the loop's ticks fell: a replay gives
the same readings.
"""
from __future__ import annotations

import math
from typing import Any, Optional, Union

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
        self._h = sim.step_seconds
        self._periods = [sensor.spec.period_ns for sensor in self.sensors]
        #: Every sample instant is a multiple of this after the start (the periods' gcd),
        #: so the next one after any instant in a cell of this length is the same.
        self._grid = math.gcd(*self._periods) or 1
        #: The cell (``(now - start) // grid``) :attr:`_next_ns` was worked out for.
        self._cell: Optional[int] = None
        self._next_ns: Optional[int] = None
        self._imus = [(index, sensor) for index, sensor in enumerate(self.sensors)
                      if isinstance(sensor, Imu)]
        #: Every IMU instant is a multiple of this after the start (0: no IMU).
        self._imu_grid = math.gcd(*(sensor.spec.period_ns for _, sensor in self._imus))
        if self._imus:
            sim.keep_step_starts()
        #: Measured on arriving at an IMU instant, until the sample there: the instant and
        #: per IMU due, its index and specific force in its axes (:meth:`Imu.measured`).
        self._measured: tuple[int, dict[int, tuple[float, float]]] = (0, {})

    def __bool__(self) -> bool:
        return bool(self.sensors)

    @property
    def has_imu(self) -> bool:
        """Whether an IMU is among the sensors (its keyframe state is then kept)."""
        return bool(self._imus)

    def next_stop(self, now_ns: int) -> Optional[int]:
        """The first instant after ``now_ns`` a sensor samples at (None without sensors)."""
        cell = (now_ns - self.start_ns) // self._grid
        if cell != self._cell:
            self._cell = cell
            self._next_ns = min((self.start_ns + max(1, (now_ns - self.start_ns) // period + 1)
                                 * period for period in self._periods), default=None)
        return self._next_ns

    def arrive(self, sim: Simulation) -> None:
        """On arriving at the simulation's present instant, before anything is made there:
        measure the specific force of each IMU due here over the step that led here, from
        the state it began with (:meth:`Simulation.step_start`), once an instant."""
        now = sim.time_ns
        since = now - self.start_ns
        if not self._imus or since <= 0 or since % self._imu_grid or self._measured[0] == now:
            return
        start = sim.step_start()
        if start is None:  # no step led here: the sample reads the force terms
            return
        (q0, v0), q, v, h = start, sim.q, sim.v, self._h
        self._measured = (now, {index: imu.measured(imu.point_velocity(q0, v0), q, v, h)
                                for index, imu in self._imus if since % imu.spec.period_ns == 0})

    def sample(self, sim: Simulation) -> list[Reading]:
        """The readings of the sensors due at the simulation's present instant, in the
        scene's order of sensors (none when none is due or they sampled here already)."""
        now = sim.time_ns
        since = now - self.start_ns
        if now == self.sampled_ns or since <= 0 or since % self._grid:
            return []
        due = [(index, sensor) for index, (sensor, period)
               in enumerate(zip(self.sensors, self._periods)) if since % period == 0]
        if not due:
            return []
        self.sampled_ns = now
        readings: list[Reading] = []
        at, measured = self._measured
        accelerations = None
        for index, sensor in due:
            if isinstance(sensor, Laser):
                readings.append((sensor.spec, sensor.scan(sim.q, now)))
                continue
            specific_force = measured.get(index) if at == now else None
            if specific_force is None:  # no step led here (see Imu.forced)
                if accelerations is None:
                    accelerations = sim.accelerations()
                specific_force = sensor.forced(sim.q, sim.v, accelerations)
            readings.append((sensor.spec, sensor.read(sim.q, sim.v, specific_force, now)))
        return readings

    def export_state(self, now_ns: int) -> list[Any]:
        """The specific forces measured on arriving at ``now_ns`` and not yet sampled, as
        plain data for a keyframe (float64 values exact): the instant and per IMU its name
        and the force's x and y; empty when none waits."""
        at, measured = self._measured
        if not measured or at != now_ns or at == self.sampled_ns:
            return []
        return [at, [[self.sensors[index].spec.name, *force]
                     for index, force in sorted(measured.items())]]

    def import_state(self, data: list[Any]) -> None:
        """Take :meth:`export_state`'s data (of this scene's sensors) back."""
        if not data:
            self._measured = (0, {})
            return
        index = {sensor.spec.name: i for i, sensor in enumerate(self.sensors)}
        self._measured = (int(data[0]), {index[str(name)]: (float(x), float(y))
                                         for name, x, y in data[1]})
