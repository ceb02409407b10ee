"""The node's own cost without rclpy: the Python work of its timer ticks.

Each 50 Hz tick of the node runs :meth:`Runner.advance` (the scene's script, 20 physics
steps at 1 kHz, the diagnostics when due), then serializes every output of the snapshot
it passed (:class:`~hecker_dynamics.ros.cdr.SnapshotSerializer`: pose, twist and odometry
per body, the markers and ``/tf``) and the sensors' readings it took, the bytes it hands to
rclpy's ``publish``. Both are timed here on rings of 1, 10 and 100 bodies
(:func:`~hecker_dynamics.bench.scenes.ring`) with every output on; their sum per second
of sim time is the share of one core the node needs to keep up with the clock, before
rclpy publishes and its executor wakes.
"""
from __future__ import annotations

import dataclasses
import functools
import statistics
import time
from typing import NamedTuple, Optional

import numpy as np

from ..ros.cdr import SnapshotSerializer, serialize_output
from ..ros.outputs import SnapshotOutputs
from ..ros.runner import Runner, tick_target
from ..scene.load import Scene
from ..viz.progress import BarFactory, run_parts
from .scenes import ring

__all__ = ["NODE_BODIES", "NodeCost", "node_scene", "tick_targets", "node_run", "node_cost",
           "node_table"]

NODE_BODIES = (1, 10, 100)
#: The node's default timing: 1 kHz physics, 50 Hz publishing.
STEP_NS = 1_000_000
PUBLISH_PERIOD_NS = 20_000_000
#: The target share of one core for 10 bodies: 1 ms of CPU per 20 ms tick.
TARGET_SHARE = 0.05


class NodeCost(NamedTuple):
    """Median CPU seconds of node work per second of sim time (a share of one core)."""

    bodies: int
    advance: float    # Runner.advance: script, physics steps, diagnostics
    outputs: float    # every output of every snapshot, built and serialized
    repeats: int

    @property
    def total(self) -> float:
        return self.advance + self.outputs


def node_scene(bodies: int, floor: bool = False) -> Scene:
    """A ring of ``bodies`` boxes stepped at 1 kHz, published at 50 Hz, every output on;
    with ``floor``, falling onto a floor and resting on it (:func:`~.scenes.ring`)."""
    return dataclasses.replace(ring(bodies, floor=floor), step_ns=STEP_NS,
                               publish_period_ns=PUBLISH_PERIOD_NS,
                               publish_odometry=True, publish_markers=True,
                               publish_diagnostics=True, publish_tf=True)


def tick_targets(scene: Scene, seconds: float, spread_ns: int = 0,
                 seed: int = 0) -> list[int]:
    """The times of the node's 50 Hz ticks over ``seconds``, in sim time from the start:
    each a publish period after the last, moved by up to ``spread_ns`` either way (drawn
    from ``seed``) as a live tick's wake moves on the wall clock; the last ends the run
    at ``seconds``."""
    period = scene.publish_period_ns
    count = round(seconds * 1e9 / period)
    shifts = np.random.default_rng(seed).integers(-spread_ns, spread_ns, count,
                                                  endpoint=True).tolist()
    shifts[-1] = 0
    return [k * period + shift for k, shift in zip(range(1, count + 1), shifts)]


def node_run(scene: Scene, seconds: float, pause: float = 0.0,
             spread_ns: int = 0) -> tuple[float, float]:
    """CPU seconds per sim second of :meth:`Runner.advance` and of serializing what it
    gave (the snapshots' messages and the sensors' readings), over ``seconds`` of
    ``scene`` in the node's 50 Hz ticks (moved by up to ``spread_ns``:
    :func:`tick_targets`), each stepping to the last publish instant at or before its
    time as the node's do (:func:`~..ros.runner.tick_target`). ``pause``: seconds slept
    after each tick, as the node sleeps between its ticks (a core that ran other work
    meanwhile leaves the tick colder caches; the sleep itself is not CPU time)."""
    runner = Runner(scene)
    period = scene.publish_period_ns
    serialize = SnapshotSerializer(SnapshotOutputs(scene))
    # CPU time of this process, not wall time: on a loaded machine the wall clock also
    # counts the time other processes held the core.
    clock = time.process_time
    advance = outputs = 0.0
    for target in tick_targets(scene, seconds, spread_ns):
        start = clock()
        tick = runner.advance(tick_target(target, runner.sim.start_ns, period))
        middle = clock()
        for snapshot in tick.snapshots:
            serialize(snapshot)
        for _, reading in tick.readings:
            serialize_output(reading)
        end = clock()
        advance += middle - start
        outputs += end - middle
        if pause:
            time.sleep(pause)
    return advance / seconds, outputs / seconds


def node_cost(bodies_list: tuple[int, ...] = NODE_BODIES, seconds: float = 2.0,
              repeats: int = 5, floor: bool = False,
              bar: Optional[BarFactory] = None) -> list[NodeCost]:
    """The node's work per sim second on each ring size (``floor``: on a floor): medians of
    ``repeats`` runs of ``seconds`` of sim time, the sizes interleaved in every round (so
    the machine's load falls on all of them alike)."""
    scenes = {n: node_scene(n, floor) for n in bodies_list}
    samples: dict[int, list[tuple[float, float]]] = {n: [] for n in bodies_list}
    def sample(n: int, scene: Scene) -> None:
        samples[n].append(node_run(scene, seconds))

    run_parts([(f"{n} bodies", functools.partial(sample, n, scene))
               for _ in range(repeats) for n, scene in scenes.items()], bar, "bench node")
    return [NodeCost(n, statistics.median(a for a, _ in samples[n]),
                     statistics.median(o for _, o in samples[n]), repeats)
            for n in bodies_list]


def node_table(costs: list[NodeCost]) -> str:
    """A Markdown table of the costs, in percent of one core."""
    lines = ["| bodies | Runner.advance | output messages | total | per tick |",
             "| ---: | ---: | ---: | ---: | ---: |"]
    ticks_per_s = 1e9 / PUBLISH_PERIOD_NS
    for cost in costs:
        lines.append(f"| {cost.bodies} | {100 * cost.advance:.2f} % | {100 * cost.outputs:.2f} % "
                     f"| {100 * cost.total:.2f} % | {1e6 * cost.total / ticks_per_s:.0f} us |")
    return "\n".join(lines)
