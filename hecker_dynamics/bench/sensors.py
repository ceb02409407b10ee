"""The sensor section of ``hecker-dynamics bench --sensors``: a laser scan's cost against
Box2D v3's ray casts and a plain numpy caster, and the robot scene's node cost.

Cases:

- ``scan``: a 360-ray scan (one ray a degree, ``range_max`` beyond the room's diagonal)
  from a robot in the middle of a walled room of 200 x 200 cells of a Nav2 map's usual
  5 cm (10 m square), among 100 bodies on a grid of 1 m cells, a third each boxes,
  circles and regular polygons of 3 to 8 corners, jittered and turned
  (:func:`scan_scene`). The four walls stand for the map's border: the scene has no
  occupancy grid. Cast three ways at the same state: the compiled kernel
  (``src/kernel/raycast.c``), the plain numpy caster that is its Python twin
  (:func:`..sensors.laser.cast`, every ray against every surface of the bodies in range)
  and Box2D v3 (``box2d-python``: :func:`.box2d_v3.cast_rays`, one
  ``b2World_CastRayClosest`` a ray through its binding, timed in its worker; the robot left
  out of its world, as a laser does not see its own body). Box2D v3 answers in float32:
  its hits are checked against the kernel's to :data:`PEER_AGREEMENT`.
- ``node``: the robot scene (``config/robot.yaml``) stepped at 1 kHz with its 10 Hz scan
  and 50 Hz IMU, its outputs serialized as the node publishes them
  (:func:`.node.node_run`), and the same without its laser: the share of one core the
  node's Python work needs, and the scan's part of it; then the same work with the
  node's 20 ms sleep after each tick (:data:`TICK_PAUSE`), which the running node pays
  as colder caches. Each tick comes up to a step off its instant (:data:`TICK_SPREAD_NS`)
  and steps to the last publish instant before it, as the live node's do (its live cost,
  taken on ROS 2 as docs/benchmark.md says, is above all three).

Cost is whole-run cost: the time of :data:`SCANS` scans over their number, a median over
:data:`ROUNDS` rounds in which every caster runs once (interleaved, so the machine's load
falls on all alike); the node's cost is CPU time per second of sim time, the median of
its rounds.

Target (docs/benchmark.md): the kernel's scan costs at most Box2D v3's 360 ray casts.
"""
from __future__ import annotations

import dataclasses
import math
import statistics
import time
from collections.abc import Callable
from typing import Any, NamedTuple, Optional

import numpy as np

from ..dynamics import kernel
from ..dynamics.model import Model
from ..scene.load import Scene, load_scene, scene_from_parameters
from ..scene.parameters import flatten
from ..scene.sensors import LaserSpec
from ..sensors.laser import Laser
from ..viz.progress import BarFactory, run_parts
from . import box2d_v3
from .node import STEP_NS, node_run

__all__ = ["CELL", "MAP_CELLS", "NODE_SECONDS", "PEER_AGREEMENT", "RANGE_MAX", "RAYS", "ROUNDS",
           "SCANS", "SCAN_BODIES", "TICK_PAUSE", "TICK_SPREAD_NS", "ScanCosts", "NodeShare",
           "scan_scene", "scan_costs", "node_shares", "sensor_report"]

SCAN_BODIES = 100
#: The room: a map's cells and their size (m).
MAP_CELLS = 200
CELL = 0.05
RAYS = 360
#: Past the room's diagonal (14.1 m), so no body is culled by range.
RANGE_MAX = 20.0
ROUNDS = 7
SCANS = 50
NODE_SECONDS = 2.0
#: The sleep after each tick of the ``node`` case's last row: a 50 Hz tick's period.
TICK_PAUSE = 0.02
#: How far (ns) each tick of the ``node`` case moves off its 50 Hz instant, either way
#: (:func:`.node.tick_targets`): one step, as the live node's tick wakes spread on the
#: wall clock; each steps to the last publish instant at or before it, as the node's do
#: (:func:`~..ros.runner.tick_target`), so about half of them step a period less and the
#: next one a period more.
TICK_SPREAD_NS = STEP_NS
#: Largest difference (m) between Box2D v3's float32 hits and the kernel's that still
#: counts as the same hit: float32's rounding of 10 m coordinates is 1e-6 m.
PEER_AGREEMENT = 1e-4


def _body(rng: np.random.Generator, kind: int, center: tuple[float, float],
          size: float) -> dict[str, Any]:
    """A box, a circle or a regular polygon of about ``size`` across at ``center``."""
    body: dict[str, Any] = {"mass": 1.0, "position": list(center),
                            "angle": float(rng.uniform(-math.pi, math.pi))}
    if kind == 0:
        return {**body, "shape": "box", "size": (size * rng.uniform(0.5, 1.0, 2)).tolist()}
    if kind == 1:
        return {**body, "shape": "circle", "radius": float(size / 2 * rng.uniform(0.5, 1.0))}
    turns = np.linspace(0.0, 2 * math.pi, int(rng.integers(3, 9)), endpoint=False)
    corners = size / 2 * np.column_stack([np.cos(turns), np.sin(turns)])  # regular
    return {**body, "shape": "polygon", "vertices": corners.ravel().tolist()}


def scan_scene(bodies: int = SCAN_BODIES, robot: bool = True, seed: int = 36) -> Scene:
    """The ``scan`` case's room (module docstring); ``robot=False``: without the robot and
    its laser (Box2D v3's world)."""
    rng = np.random.default_rng(seed)
    side = MAP_CELLS * CELL
    per_row = math.ceil(math.sqrt(bodies))
    pitch = side / per_row
    middle = side / 2
    cells = [((i + 0.5) * pitch, (j + 0.5) * pitch) for j in range(per_row)
             for i in range(per_row)]
    # The robot stands in the middle: the cells nearest it stay empty when there are more
    # cells than bodies.
    cells.sort(key=lambda c: -math.hypot(c[0] - middle, c[1] - middle))
    params: dict[str, Any] = {
        "step": 0.001, "duration": 1.0,
        "walls": {"west": {"point": [0.0, 0.0], "normal": [1.0, 0.0]},
                  "east": {"point": [side, 0.0], "normal": [-1.0, 0.0]},
                  "south": {"point": [0.0, 0.0], "normal": [0.0, 1.0]},
                  "north": {"point": [0.0, side], "normal": [0.0, -1.0]}},
        "bodies": {}}
    for k, (x, y) in enumerate(cells[:bodies]):
        jitter = rng.uniform(-0.1, 0.1, 2) * pitch
        params["bodies"][f"body{k:03d}"] = _body(rng, k % 3, (x + jitter[0], y + jitter[1]),
                                                 0.6 * pitch)
    if robot:
        params["bodies"]["robot"] = {"shape": "circle", "radius": 0.15, "mass": 5.0,
                                     "position": [middle, middle]}
        params["sensors"] = {"laser": {
            "type": "laser", "body": "robot", "angle_min": -math.pi,
            "angle_max": math.pi - 2 * math.pi / RAYS, "count": RAYS, "range_max": RANGE_MAX}}
    return scene_from_parameters(flatten(params), f"bench:scan{bodies}")


class ScanCosts(NamedTuple):
    """Median seconds per scan of each caster (None: not measured), and how far Box2D
    v3's hits lie from the kernel's (m; None where not measured)."""

    bodies: int
    kernel: Optional[float]
    numpy: float
    box2d_v3: Optional[float]
    peer_difference: Optional[float]
    peer_misses: int  # rays hit in one and not the other
    rounds: int


def _per_scan(laser: Laser, q: np.ndarray, scans: int) -> float:
    start = time.perf_counter()
    for stamp in range(scans):
        laser.scan(q, stamp)
    return (time.perf_counter() - start) / scans


def scan_costs(bodies: int = SCAN_BODIES, rounds: int = ROUNDS, scans: int = SCANS,
               peer: bool = True, bar: Optional[BarFactory] = None) -> ScanCosts:
    """The ``scan`` case: each caster's whole-run cost, interleaved over ``rounds``."""
    scene = scan_scene(bodies)
    model = Model(scene)
    q, _ = model.initial_state()
    spec = scene.sensors[0]
    assert isinstance(spec, LaserSpec)
    casters = {"numpy": Laser(spec, scene, model.cm_local, compiled=False)}
    if kernel.built():
        casters["kernel"] = Laser(spec, scene, model.cm_local, compiled=True)
    reference = casters.get("kernel", casters["numpy"]).distances(q)
    difference, misses = None, 0
    peer = peer and box2d_v3.available()
    if peer:
        peer_scene = scan_scene(bodies, robot=False)
        origin, heading = casters["numpy"].origin_and_heading(q)
        angles = heading + casters["numpy"].angles
        rays = [(origin[0], origin[1], RANGE_MAX * math.cos(a), RANGE_MAX * math.sin(a))
                for a in angles]
        _, hits = box2d_v3.cast_rays(peer_scene, rays)
        theirs = np.array([RANGE_MAX * fraction if body is not None else math.inf
                           for body, fraction, *_ in hits])
        both = np.isfinite(theirs) & np.isfinite(reference)
        misses = int(np.sum(np.isfinite(theirs) != np.isfinite(reference)))
        difference = float(np.max(np.abs(theirs[both] - reference[both]), initial=0.0))
    samples: dict[str, list[float]] = {name: [] for name in [*casters, "box2d_v3"]}

    def peer_run() -> None:
        per_ray, _ = box2d_v3.cast_rays(peer_scene, rays, repeats=scans)
        samples["box2d_v3"].append(per_ray * len(rays))

    def run(name: str, laser: Laser) -> Callable[[], None]:
        return lambda: samples[name].append(_per_scan(laser, q, scans))

    parts = [(name, run(name, laser)) for name, laser in casters.items()]
    if peer:
        parts.append(("box2d_v3", peer_run))
    run_parts(parts * rounds, bar, "bench sensors")

    def median(name: str) -> Optional[float]:
        return statistics.median(samples[name]) if samples[name] else None

    numpy_cost = median("numpy")
    assert numpy_cost is not None
    return ScanCosts(bodies, median("kernel"), numpy_cost, median("box2d_v3"), difference,
                     misses, rounds)


class NodeShare(NamedTuple):
    """CPU seconds of the node's work per second of sim time (a share of one core)."""

    case: str
    advance: float
    outputs: float
    rounds: int

    @property
    def total(self) -> float:
        return self.advance + self.outputs


def robot_at_1khz(laser: bool = True) -> Scene:
    """The shipped robot scene stepped at 1 kHz (its own step is 2 ms); ``laser=False``:
    without its laser."""
    scene = load_scene("robot")
    sensors = tuple(s for s in scene.sensors if laser or s.name != "laser")
    return dataclasses.replace(scene, step_ns=STEP_NS, sensors=sensors)


def node_shares(rounds: int = ROUNDS, seconds: float = NODE_SECONDS,
                bar: Optional[BarFactory] = None) -> list[NodeShare]:
    """The ``node`` case, with and without the laser, and with the laser and the node's
    sleep between ticks, interleaved over ``rounds``."""
    robot = robot_at_1khz()
    cases = {"robot, 10 Hz scan": (robot, 0.0),
             "robot, no laser": (robot_at_1khz(False), 0.0),
             f"robot, 10 Hz scan, {1e3 * TICK_PAUSE:g} ms asleep after each tick":
             (robot, TICK_PAUSE)}
    samples: dict[str, list[tuple[float, float]]] = {case: [] for case in cases}

    def run(case: str, scene: Scene, pause: float) -> Callable[[], None]:
        return lambda: samples[case].append(node_run(scene, seconds, pause, TICK_SPREAD_NS))

    run_parts([(case, run(case, scene, pause)) for case, (scene, pause) in cases.items()]
              * rounds, bar, "bench node")
    return [NodeShare(case, statistics.median(a for a, _ in runs),
                      statistics.median(o for _, o in runs), rounds)
            for case, runs in samples.items()]


def sensor_report(scan: ScanCosts, shares: list[NodeShare]) -> str:
    """The section's tables and its target's verdict, in Markdown."""
    us = 1e6
    lines = [f"A {RAYS}-ray scan among {scan.bodies} bodies in a {MAP_CELLS} x {MAP_CELLS}-cell "
             f"room (walls), medians of {scan.rounds} interleaved runs of {SCANS} scans:", "",
             "| caster | per scan | kernel / it |", "| --- | ---: | ---: |"]
    rows = [("hecker_dynamics kernel (raycast.c)", scan.kernel),
            ("numpy, every ray against every surface (the Python twin)", scan.numpy),
            (f"Box2D v3, {RAYS} b2World_CastRayClosest", scan.box2d_v3)]
    for name, cost in rows:
        if cost is None:
            lines.append(f"| {name} | not measured | |")
            continue
        ratio = "" if scan.kernel is None else f"{scan.kernel / cost:.3f}"
        lines.append(f"| {name} | {us * cost:.0f} us | {ratio} |")
    if scan.peer_difference is not None:
        lines += ["", f"Box2D v3's hits lie within {scan.peer_difference:.1e} m of the kernel's "
                      f"({scan.peer_misses} rays hit in one and not the other)."]
    if scan.kernel is not None and scan.box2d_v3 is not None:
        met = scan.kernel <= scan.box2d_v3 and scan.peer_misses == 0 and \
            scan.peer_difference is not None and scan.peer_difference <= PEER_AGREEMENT
        lines += ["", f"Target: a scan costs at most Box2D v3's {RAYS} ray casts: "
                      f"{'met' if met else 'missed'} ({scan.kernel / scan.box2d_v3:.3f} x)."]
    lines += ["", "The robot scene at 1 kHz, 50 Hz publishing, its outputs serialized, "
                  f"medians of {shares[0].rounds} interleaved runs of {NODE_SECONDS:g} s "
                  "(share of one core):", "",
              "| case | Runner.advance | output messages | total |", "| --- | ---: | ---: | ---: |"]
    for share in shares:
        lines.append(f"| {share.case} | {100 * share.advance:.2f} % | "
                     f"{100 * share.outputs:.2f} % | {100 * share.total:.2f} % |")
    lines += ["", "The running node costs more than these rows: rclpy's publishes and the tick "
                  "thread's wake come on top (docs/benchmark.md, the robot node on Jazzy)."]
    return "\n".join(lines)
