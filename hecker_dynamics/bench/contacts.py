"""The contact section of ``hecker-dynamics bench``: pyramids of boxes against the peers.

Each engine builds the pyramid of :mod:`.pyramid` (0.5 m boxes of 1 kg, friction 0.6,
restitution 0, gravity, h = 4 ms) and takes 2 s of steps in blocks of 25; the blocks of
all engines are interleaved (one block each in turn), so that the machine's load falls on
all alike, and each engine's cost per step is the median over its blocks. The peers, in
their usual configurations with sleeping off (hecker_dynamics has none, so every engine
does the same work every step):

- ``pymunk``: 10 iterations (its default), boxes of ``Poly.create_box`` on a static
  segment floor;
- ``box2d``: Box2D 2.3 (pybox2d), 8 velocity and 3 position iterations (its manual's
  recommendation), boxes on an edge floor.

Target 1 of issue 13: per step at most 0.5 of pymunk's cost (and at most Box2D v3's, whose
bindings are not installable here). Also reported: how far the farthest box moved from
its start (m), for every engine.
"""
from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .pyramid import BOX, FRICTION, STEP, pyramid, pyramid_positions
from ..dynamics.simulation import Simulation

__all__ = ["BLOCK", "DURATION", "contact_bench", "pyramid_engines"]

BLOCK = 25
DURATION = 2.0
TARGET = 0.5

Engine = tuple[Callable[[int], None], Callable[[], np.ndarray]]  # step(n), positions()


def _ours(rows: int) -> Engine:
    sim = Simulation(pyramid(rows))

    def step(count: int) -> None:
        sim.advance_to(sim.time_ns + count * sim.step_ns)

    return step, lambda: sim.q[:, :2].copy()


def _pymunk(rows: int) -> Engine:
    import pymunk

    space = pymunk.Space()
    space.iterations = 10
    space.gravity = (0.0, -9.81)
    floor = pymunk.Segment(space.static_body, (-1e3, 0.0), (1e3, 0.0), 0.0)
    floor.friction, floor.elasticity = FRICTION, 0.0
    space.add(floor)
    bodies = []
    for x, y in pyramid_positions(rows):
        body = pymunk.Body(1.0, pymunk.moment_for_box(1.0, (BOX, BOX)))
        body.position = (x, y)
        shape = pymunk.Poly.create_box(body, (BOX, BOX), 0.0)
        shape.friction, shape.elasticity = FRICTION, 0.0
        space.add(body, shape)
        bodies.append(body)

    def step(count: int) -> None:
        for _ in range(count):
            space.step(STEP)

    return step, lambda: np.array([tuple(b.position) for b in bodies])


def _box2d(rows: int) -> Engine:
    import Box2D

    world = Box2D.b2World(gravity=(0.0, -9.81), doSleep=False)
    ground = world.CreateStaticBody()
    ground.CreateEdgeFixture(vertices=[(-1e3, 0.0), (1e3, 0.0)], friction=FRICTION)
    bodies = []
    for x, y in pyramid_positions(rows):
        body = world.CreateDynamicBody(position=(x, y), allowSleep=False)
        body.CreatePolygonFixture(box=(BOX / 2, BOX / 2), density=1.0 / (BOX * BOX),
                                  friction=FRICTION, restitution=0.0)
        bodies.append(body)

    def step(count: int) -> None:
        for _ in range(count):
            world.Step(STEP, 8, 3)

    return step, lambda: np.array([tuple(b.position) for b in bodies])


PEERS = {"pymunk": _pymunk, "box2d": _box2d}


def pyramid_engines(rows: int, peers: list[str]) -> dict[str, Engine]:
    """hecker_dynamics and each installed peer of ``peers`` on the pyramid of ``rows``."""
    engines = {"hecker_dynamics": _ours(rows)}
    for name in peers:
        try:
            engines[name] = PEERS[name](rows)
        except ImportError:
            continue
    return engines


def measure_pyramid(rows: int, peers: list[str]) -> dict[str, tuple[float, float]]:
    """Per engine: (median cost per step in s, largest displacement of a box in m)."""
    engines = pyramid_engines(rows, peers)
    start = {name: positions() for name, (_, positions) in engines.items()}
    costs: dict[str, list[float]] = {name: [] for name in engines}
    for _ in range(round(DURATION / STEP) // BLOCK):
        for name, (step, _) in engines.items():
            begin = time.perf_counter()
            step(BLOCK)
            costs[name].append((time.perf_counter() - begin) / BLOCK)
    return {name: (statistics.median(costs[name]),
                   float(np.abs(engines[name][1]() - start[name]).max()))
            for name in engines}


def contact_bench(rows_list: list[int], peers: list[str], out: Path, command: str,
                  log: Callable[[str], None] = print) -> list[dict]:
    """Measure every pyramid of ``rows_list`` and write ``contacts.md`` and ``contacts.csv``
    to ``out``; returns the rows of the table."""
    table = []
    for rows in rows_list:
        result = measure_pyramid(rows, peers)
        ours = result["hecker_dynamics"][0]
        row = {"rows": rows, "boxes": rows * (rows + 1) // 2}
        for name, (cost, drift) in result.items():
            row[f"{name}_us"] = cost * 1e6
            row[f"{name}_drift_m"] = drift
        for name in peers:
            if name in result:
                row[f"ratio_{name}"] = ours / result[name][0]
        row["target"] = ("met" if row.get("ratio_pymunk", float("inf")) <= TARGET
                         else "missed") if "pymunk" in result else "no pymunk"
        log(f"pyramid {rows} rows: " + ", ".join(
            f"{name} {cost * 1e6:.1f} us (moved {drift:.2g} m)"
            for name, (cost, drift) in result.items()) + f"; target 1 {row['target']}")
        table.append(row)
    out.mkdir(parents=True, exist_ok=True)
    names = ["hecker_dynamics"] + [p for p in peers if f"{p}_us" in table[0]]
    lines = [f"Command: `{command}`", "",
             "| rows (boxes) | " + " | ".join(f"{n} us/step (moved m)" for n in names)
             + " | " + " | ".join(f"ratio to {n}" for n in names[1:]) + " | target 1 |",
             "|---" * (2 + 2 * (len(names) - 1)) + "|"]
    for row in table:
        cells = [f"{row[f'{n}_us']:.1f} ({row[f'{n}_drift_m']:.1g})" for n in names]
        ratios = [f"{row[f'ratio_{n}']:.2f}" for n in names[1:]]
        lines.append(f"| {row['rows']} ({row['boxes']}) | " + " | ".join(cells + ratios)
                     + f" | {row['target']} |")
    (out / "contacts.md").write_text("\n".join(lines) + "\n")
    keys = list(table[0])
    (out / "contacts.csv").write_text(",".join(keys) + "\n" + "\n".join(
        ",".join(str(row.get(k, "")) for k in keys) for row in table) + "\n")
    return table
