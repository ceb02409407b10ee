"""The joint section of ``hecker-dynamics bench``: a chain of 100 links against the peers,
and the shipped scenes pinned by revolute joints against the same scenes pinned by springs.

Chain: ``LINKS`` rods of 0.1 m x 0.02 m and 0.1 kg laid out horizontally, the first pinned
to the world at its left end, each pinned to the next at their shared end, let go under
gravity, h = 1 ms, 2 s; no collisions. The engines, in their usual configurations:

- ``hecker_dynamics``: revolute joints named ``j000`` to ``j099`` (so that the joint rows
  come in chain order and the band stays narrow), ``velocity_verlet``, the compiled kernel
  when built;
- ``pymunk``: ``PivotJoint`` per pin, 10 iterations (its default);
- ``box2d``: Box2D 2.3 (pybox2d), revolute joints, 8 velocity and 3 position iterations
  (its manual's recommendation);
- ``box2d_v3``: Box2D v3 in its own interpreter (:mod:`.box2d_v3`), the chain scene's
  revolute joints, 4 sub-steps, sleeping off.

Pinned scenes: the shipped ``seesaw`` and ``door`` (revolute joints to the world) and the
same scenes with each such joint a stiff zero-length spring
(:func:`.scenes.pinned_by_springs`, the pins they had before joints; the seesaw's stop
goes with its joint), each at its own step and method, with its script, over its first
2 s.

Every engine runs the whole span ``ROUNDS`` times, built afresh each time, the runs of all
engines of a comparison interleaved (one each in turn), so that the machine's load falls
on all alike; each cost per step is the median over the whole runs. The error is the
largest distance between two points a pin holds together, over the ends of blocks of
``BLOCK`` steps in one more, untimed run.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .measure import interleaved_runs, timed_steps, whole_cost
from .scenes import SPRING_PINS, pinned_by_springs
from ..contact.joints import RevoluteJoint
from ..dynamics.simulation import Simulation
from ..scene.load import Scene, load_scene, scene_from_parameters
from ..scene.parameters import flatten

__all__ = ["BLOCK", "LINKS", "chain", "joint_bench", "chain_engines", "pinned_engines"]

BLOCK = 25
#: Whole runs of each comparison.
ROUNDS = 5
LINKS = 100
LENGTH, WIDTH, MASS = 0.1, 0.02, 0.1
STEP = 0.001
DURATION = 2.0
GRAVITY = 9.81

#: step(n), error(): the largest gap between points a pin holds together (m).
Engine = tuple[Callable[[int], None], Callable[[], float]]


def chain(links: int = LINKS) -> Scene:
    """The chain as a scene (velocity_verlet at h = 1 ms, 2 s)."""
    bodies, joints = {}, {}
    for i in range(links):
        bodies[f"l{i:03d}"] = {"shape": "box", "size": [LENGTH, WIDTH], "mass": MASS,
                               "position": [LENGTH * (0.5 + i), 0.0]}
        joints[f"j{i:03d}"] = {"type": "revolute", "body_b": f"l{i:03d}",
                               "point_b": [-0.5 * LENGTH, 0.0]}
        if i:
            joints[f"j{i:03d}"].update(body_a=f"l{i - 1:03d}", point_a=[0.5 * LENGTH, 0.0])
    return scene_from_parameters(flatten({
        "step": STEP, "integrator": "velocity_verlet", "duration": DURATION,
        "publish_rate": 1.0 / DURATION, "bodies": bodies,
        "forces": {"gravity": {"type": "gravity", "acceleration": [0.0, -GRAVITY]}},
        "joints": joints}),
        "bench:chain")


def _gaps(ends: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """The largest distance between the points of each pair."""
    return max(float(math.hypot(*(a - b))) for a, b in ends)


def _link_ends(x: np.ndarray, y: np.ndarray, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The left and right ends of links with CMs (x, y) at ``angle``: (2, n) arrays."""
    dx, dy = 0.5 * LENGTH * np.cos(angle), 0.5 * LENGTH * np.sin(angle)
    return np.array([x - dx, y - dy]), np.array([x + dx, y + dy])


def _chain_error(x: np.ndarray, y: np.ndarray, angle: np.ndarray) -> float:
    left, right = _link_ends(x, y, angle)
    pins = [(left[:, 0], np.zeros(2))] + [(left[:, i + 1], right[:, i])
                                          for i in range(left.shape[1] - 1)]
    return _gaps(pins)


def _simulation_engine(sim: Simulation, error: Callable[[Simulation], float]) -> Engine:
    """Steps of ``sim``, pushing its scene's script as sim time reaches each command."""
    script = sorted(sim.scene.script, key=lambda c: c.stamp_ns)

    def step(count: int) -> None:
        end = sim.time_ns + count * sim.step_ns
        while script and script[0].stamp_ns < end:
            sim.advance_to(max(sim.time_ns, script[0].stamp_ns), keep=False)
            sim.push(script.pop(0))
        sim.advance_to(end, keep=False)

    return step, lambda: error(sim)


def _ours(links: int) -> Engine:
    def error(sim: Simulation) -> float:
        return _chain_error(sim.q[:, 0], sim.q[:, 1], sim.q[:, 2])  # CM = body origin
    return _simulation_engine(Simulation(chain(links)), error)


def _pymunk(links: int) -> Engine:
    import pymunk

    space = pymunk.Space()
    space.iterations = 10
    space.gravity = (0.0, -GRAVITY)
    bodies, previous = [], space.static_body
    for i in range(links):
        body = pymunk.Body(MASS, MASS * (LENGTH ** 2 + WIDTH ** 2) / 12.0)
        body.position = (LENGTH * (0.5 + i), 0.0)
        space.add(body, pymunk.PivotJoint(previous, body, (LENGTH * i, 0.0)))
        bodies.append(body)
        previous = body

    def step(count: int) -> None:
        for _ in range(count):
            space.step(STEP)

    def error() -> float:
        return _chain_error(np.array([b.position.x for b in bodies]),
                            np.array([b.position.y for b in bodies]),
                            np.array([b.angle for b in bodies]))

    return step, error


def _box2d(links: int) -> Engine:
    import Box2D

    world = Box2D.b2World(gravity=(0.0, -GRAVITY), doSleep=False)
    previous = world.CreateStaticBody()
    bodies = []
    for i in range(links):
        body = world.CreateDynamicBody(position=(LENGTH * (0.5 + i), 0.0), allowSleep=False)
        body.CreatePolygonFixture(box=(0.5 * LENGTH, 0.5 * WIDTH),
                                  density=MASS / (LENGTH * WIDTH), groupIndex=-1)
        world.CreateRevoluteJoint(bodyA=previous, bodyB=body, anchor=(LENGTH * i, 0.0))
        bodies.append(body)
        previous = body

    def step(count: int) -> None:
        for _ in range(count):
            world.Step(STEP, 8, 3)

    def error() -> float:
        return _chain_error(np.array([b.position[0] for b in bodies]),
                            np.array([b.position[1] for b in bodies]),
                            np.array([b.angle for b in bodies]))

    return step, error


def _box2d_v3(links: int) -> Engine:
    from .box2d_v3 import scene_engine

    step, poses = scene_engine(chain(links), STEP, sleep=False)

    def error() -> float:
        q = poses()
        return _chain_error(q[:, 0], q[:, 1], q[:, 2])

    return step, error


PEERS = {"pymunk": _pymunk, "box2d": _box2d, "box2d_v3": _box2d_v3}


def chain_engines(links: int, peers: list[str]) -> dict[str, Engine]:
    """hecker_dynamics and each installed peer of ``peers`` on the chain."""
    engines = {"hecker_dynamics": _ours(links)}
    for name in peers:
        try:
            engines[name] = PEERS[name](links)
        except ImportError:  # not installed
            continue
    return engines


def _pin_error(scene: Scene) -> Callable[[Simulation], float]:
    """The largest distance of a world pin's body point from its anchor (the pins of
    ``scene``, a scene on joints)."""
    pins = [j for j in scene.joints if isinstance(j, RevoluteJoint) and j.body_a is None]

    def error(sim: Simulation) -> float:
        bodies = sim.snapshot().bodies
        ends = []
        for pin in pins:
            body = bodies[sim.model.index[pin.body_b]]
            c, s = math.cos(body.angle), math.sin(body.angle)
            px, py = pin.point_b
            at = np.array([body.position[0] + c * px - s * py, body.position[1] + s * px + c * py])
            ends.append((at, np.array(pin.point_a)))
        return _gaps(ends)

    return error


def pinned_engines(name: str) -> dict[str, Engine]:
    """The shipped scene ``name`` on its revolute joints and pinned by springs."""
    joints, springs = load_scene(name), pinned_by_springs(name)
    return {"joints": _simulation_engine(Simulation(joints), _pin_error(joints)),
            "springs": _simulation_engine(Simulation(springs), _pin_error(joints))}


def interleaved(build: Callable[[], dict[str, Engine]], steps: int,
                rounds: int = ROUNDS) -> dict[str, tuple[float, float]]:
    """Per engine of ``build()``: (median whole-run cost per step in s over ``rounds``
    interleaved whole runs of ``steps`` steps, each engine built afresh for each
    (:func:`.measure.interleaved_runs`); largest error at the ends of the blocks of
    :data:`BLOCK` steps of one more, untimed run)."""
    names = list(build())

    def whole(name: str) -> Callable[[], float]:
        return lambda: timed_steps(build()[name][0], steps) / steps

    costs = interleaved_runs({name: whole(name) for name in names}, rounds)
    worst = {name: 0.0 for name in names}
    engines = build()
    for _ in range(max(1, steps // BLOCK)):
        for name, (step, error) in engines.items():
            step(BLOCK)
            worst[name] = max(worst[name], error())
    return {name: (whole_cost(costs[name]).per_step, worst[name]) for name in names}


def joint_bench(peers: list[str], out: Path, command: str,
                log: Callable[[str], None] = print) -> dict[str, dict[str, tuple[float, float]]]:
    """Measure the chain and the pinned scenes; write ``joints.md`` and ``joints.csv`` to
    ``out``; returns {comparison: {engine: (cost per step s, error m)}}."""
    results = {f"chain of {LINKS}": interleaved(lambda: chain_engines(LINKS, peers),
                                                round(DURATION / STEP))}
    for name in SPRING_PINS:
        scene = load_scene(name)
        steps = round(min(DURATION * 1e9, scene.duration_ns) / scene.step_ns)
        results[f"{name} ({scene.integrator}, h = {scene.step_ns * 1e-9:g} s)"] = \
            interleaved(lambda name=name: pinned_engines(name), steps)
    lines = [f"Command: `{command}`", "",
             "| comparison | engine | us/step | largest pin error (m) | cost ratio |",
             "|---|---|---|---|---|"]
    csv = ["comparison,engine,us_per_step,pin_error_m"]
    for comparison, engines in results.items():
        first = next(iter(engines.values()))[0]
        for engine, (cost, error) in engines.items():
            lines.append(f"| {comparison} | {engine} | {cost * 1e6:.1f} | {error:.2g} | "
                         f"{cost / first:.2f} |")
            csv.append(f"{comparison},{engine},{cost * 1e6},{error}")
            log(f"{comparison}: {engine} {cost * 1e6:.1f} us/step, pin error {error:.2g} m")
    out.mkdir(parents=True, exist_ok=True)
    (out / "joints.md").write_text("\n".join(lines) + "\n")
    (out / "joints.csv").write_text("\n".join(csv) + "\n")
    return results
