"""Benchmark scenes, built as Scene objects through ``scene_from_parameters``.

Each builder returns the scene at its benchmark defaults; :func:`configure` sets the
integrator, step and tolerance (and publishes at about 50 Hz, as a node would). The tests
use the same builders (``test/test_bench.py``).

(1) ``free_spin``  2 m x 0.5 m box, 10 kg, constant world force (3, -98.1) N at the CM and
    torque 2 N m, spinning and moving, 10 s (exact solution).
(2) ``harmonic``   1 kg unit box on a zero-length spring k = 100 N/m to a fixed anchor at
    its CM, x0 = 1 m, 20 s (exact).
(3) ``spring_pendulum``  1 m x 0.2 m box, 1 kg, gravity, spring k = 200 N/m, rest 0.5 m
    from a fixed anchor to the body point (0.4, 0), started about 0.1 m from its rest
    point and tilted 0.2 rad, 10 s.
(4) ``two_bodies`` two boxes joined by a spring between points 5 cm off their CMs
    (k = 50 N/m, rest 1 m), linear drag 0.1 N s/m at the CMs, spinning at 3 and -4 rad/s,
    10 s.

Both (3) and (4) were chosen not chaotic over their 10 s: a 1e-8 m change of the start
grows about 20x (3) and 50x (4) by the end. Larger swings or lever arms (e.g. hooks at
0.5 m) make them chaotic (growth 1e5 to 1e9), so that no method, reference included,
could be held to 1e-9 m at 10 s; see docs/benchmark.md.
(5) ``stiff``      as (2) with k = 1e6 N/m, 1 s (exact).
(6) every shipped scene (``config/*.yaml``).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

from ..scene.joints import RevoluteJoint
from ..scene.load import Scene, SpringSpec, load_scene, scene_from_parameters, shipped_scenes
from ..scene.parameters import flatten

__all__ = ["BENCH_SCENES", "RING_SIZE", "RING_SPRING", "free_spin", "harmonic", "stiff",
           "spring_pendulum", "two_bodies", "ring_initial", "ring", "SPRING_PINS",
           "pinned_by_springs", "bench_scene", "STIFF_SEESAW", "all_scene_names", "configure",
           "declared_variants"]

#: The benchmark scenes with closed-form or reference solutions, in the order
#: docs/benchmark.md numbers them.
BENCH_SCENES = ("free_spin", "harmonic", "spring_pendulum", "two_bodies", "stiff")
#: Scenes with an exact solution (the rest use :mod:`.reference`).
EXACT_SCENES = ("free_spin", "harmonic", "stiff")
#: Publish period the benchmark asks for (a node's 50 Hz), rounded to whole steps.
PUBLISH_PERIOD = 0.02

FREE_SPIN_FORCE = (3.0, -98.1)
FREE_SPIN_TORQUE = 2.0
RING_SIZE = (0.2, 0.1)
RING_SPRING = {"stiffness": 100.0, "rest_length": 0.1, "damping": 0.5}


def _scene(name: str, duration: float, params: dict[str, Any]) -> Scene:
    base = {"step": 0.001, "integrator": "rk4", "publish_rate": 1.0 / duration,
            "duration": duration}
    return scene_from_parameters(flatten({**base, **params}), f"bench:{name}")


def free_spin() -> Scene:
    return _scene("free_spin", 10.0, {
        "bodies": {"box": {"shape": "box", "size": [2.0, 0.5], "mass": 10.0,
                           "position": [0.0, 0.0], "angle": 0.0, "velocity": [1.0, 5.0],
                           "angular_velocity": 3.0}},
        "forces": {"push": {"type": "constant_force", "body": "box",
                            "force": list(FREE_SPIN_FORCE)},
                   "twist": {"type": "constant_torque", "body": "box",
                             "torque": FREE_SPIN_TORQUE}},
    })


def _oscillator(name: str, stiffness: float, duration: float) -> Scene:
    return _scene(name, duration, {
        "bodies": {"mass": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                            "position": [1.0, 0.0]}},
        "forces": {"spring": {"type": "spring", "body_a": "mass", "anchor": [0.0, 0.0],
                              "stiffness": stiffness}},
    })


def harmonic() -> Scene:
    return _oscillator("harmonic", 100.0, 20.0)


def stiff() -> Scene:
    return _oscillator("stiff", 1e6, 1.0)


def spring_pendulum() -> Scene:
    return _scene("spring_pendulum", 10.0, {
        "bodies": {"bar": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0,
                           "position": [0.1, -0.95], "angle": 1.37,
                           "points": {"hook": [0.4, 0.0]}}},
        "forces": {"gravity": {"type": "gravity", "acceleration": [0.0, -9.81]},
                   "spring": {"type": "spring", "body_a": "bar", "point_a": "hook",
                              "anchor": [0.0, 0.0], "stiffness": 200.0, "rest_length": 0.5}},
    })


def two_bodies() -> Scene:
    return _scene("two_bodies", 10.0, {
        "bodies": {
            "left": {"shape": "box", "size": [1.0, 0.4], "mass": 2.0, "position": [-1.0, 0.0],
                     "angle": 0.3, "velocity": [0.5, 1.0], "angular_velocity": 3.0,
                     "points": {"hook": [0.05, 0.0]}},
            "right": {"shape": "box", "size": [0.6, 0.6], "mass": 1.5, "position": [1.0, 0.5],
                      "angle": -0.2, "velocity": [-0.5, 0.0], "angular_velocity": -4.0,
                      "points": {"hook": [-0.05, 0.0]}}},
        "forces": {"link": {"type": "spring", "body_a": "left", "point_a": "hook",
                            "body_b": "right", "point_b": "hook", "stiffness": 50.0,
                            "rest_length": 1.0},
                   "drag": {"type": "linear_drag", "coefficient": 0.1}},
    })


def ring_initial(n: int) -> list[tuple[float, float, float, float, float, float]]:
    """(x, y, angle, vx, vy, omega) of each box of the ring: centered on a circle whose
    chords between neighbouring end points are close to the rest length, tangent to it,
    with a small deterministic velocity pattern so the ring moves."""
    width = RING_SIZE[0]
    gap = RING_SPRING["rest_length"]
    radius = n * (width + gap) / (2.0 * math.pi)
    state = []
    for i in range(n):
        phi = 2.0 * math.pi * i / n
        state.append((radius * math.cos(phi), radius * math.sin(phi), phi + 0.5 * math.pi,
                      0.3 * math.sin(3.0 * phi + 0.1 * i), 0.3 * math.cos(2.0 * phi),
                      0.5 * math.sin(5.0 * phi + 0.7)))
    return state


def ring(n: int, duration: float = 1.0, floor: bool = False) -> Scene:
    """N boxes 0.2 m x 0.1 m of 1 kg, each joined to the next by a damped spring between
    end points (k = 100 N/m, rest 0.1 m, c = 0.5 N s/m), the last to the first. With N = 1
    the one spring joins the box's front end to a fixed anchor where its back end starts
    (a scene cannot join a body to itself). With ``floor``, gravity pulls the ring down
    onto a floor (restitution 0.2, friction 0.5) 0.15 m below its lowest box."""
    half = RING_SIZE[0] / 2.0
    bodies = {}
    for i, (x, y, a, vx, vy, w) in enumerate(ring_initial(n)):
        bodies[f"b{i:05d}"] = {"shape": "box", "size": list(RING_SIZE), "mass": 1.0,
                           "position": [x, y], "angle": a, "velocity": [vx, vy],
                           "angular_velocity": w}
    forces = {}
    if n == 1:
        x, y, a = ring_initial(1)[0][:3]
        forces["s0"] = {"type": "spring", "body_a": "b00000", "point_a": [half, 0.0],
                        "anchor": [x - half * math.cos(a), y - half * math.sin(a)],
                        **RING_SPRING}
    else:
        for i in range(n):
            forces[f"s{i:05d}"] = {"type": "spring", "body_a": f"b{i:05d}", "point_a": [half, 0.0],
                               "body_b": f"b{(i + 1) % n:05d}", "point_b": [-half, 0.0],
                               **RING_SPRING}
    params: dict[str, Any] = {"bodies": bodies, "forces": forces}
    if floor:
        lowest = min(y for _, y, *_ in ring_initial(n)) - RING_SIZE[0] / 2.0
        forces["gravity"] = {"type": "gravity"}
        params["walls"] = {"floor": {"point": [0.0, lowest - 0.15], "normal": [0.0, 1.0],
                                     "restitution": 0.2, "friction": 0.5}}
    return _scene(f"ring{n}" + ("_floor" if floor else ""), duration, params)


BUILDERS = {"free_spin": free_spin, "harmonic": harmonic, "spring_pendulum": spring_pendulum,
            "two_bodies": two_bodies, "stiff": stiff}


#: Shipped scenes whose pins are revolute joints to the world, with the stiffness (N/m) and
#: damping (N s/m) of the zero-length springs that pinned them before they had joints.
SPRING_PINS = {"seesaw": (200000.0, 400.0), "door": (100000.0, 200.0)}
#: The name of a shipped scene pinned by springs: ``<scene>`` + SPRINGS.
SPRINGS = "_springs"


def pinned_by_springs(name: str) -> Scene:
    """The shipped scene ``name`` (one of :data:`SPRING_PINS`) with each revolute joint to
    the world replaced by a stiff zero-length spring from the same body point to the same
    anchor: a pin made of a spring, which wobbles and makes the forces stiff. A spring
    cannot stop a turn, so the joints' limits are gone too (the seesaw's stop)."""
    stiffness, damping = SPRING_PINS[name]
    scene = load_scene(name)
    springs = tuple(SpringSpec(f"pin_{joint.name}", joint.body_b, joint.point_b, None,
                               joint.point_a, stiffness, 0.0, damping)
                    for joint in scene.joints
                    if isinstance(joint, RevoluteJoint) and joint.body_a is None)
    kept = tuple(joint for joint in scene.joints
                 if not (isinstance(joint, RevoluteJoint) and joint.body_a is None))
    return dataclasses.replace(scene, forces=scene.forces + springs, joints=kept)


def bench_scene(name: str) -> Scene:
    """A benchmark scene (1)-(5) by name, a shipped scene (6) by its name, or one pinned
    by springs (:func:`pinned_by_springs`) by its name and :data:`SPRINGS`."""
    if name in BUILDERS:
        return BUILDERS[name]()
    if name.endswith(SPRINGS) and name[:-len(SPRINGS)] in SPRING_PINS:
        return pinned_by_springs(name[:-len(SPRINGS)])
    return load_scene(name)


#: The seesaw pinned by its stiff spring: the shipped scene with stiff forces on which the
#: implicit methods' stability runs go to omega*dt = 100.
STIFF_SEESAW = "seesaw" + SPRINGS


def all_scene_names() -> list[str]:
    return [*BENCH_SCENES, *shipped_scenes(), STIFF_SEESAW]


def configure(scene: Scene, integrator: str, step: float, tolerance: float = 1e-6,
              duration: float | None = None) -> Scene:
    """The scene with another integrator, step (s) and tolerance, publishing every
    ``PUBLISH_PERIOD`` rounded to whole steps (at least one step)."""
    step_ns = round(step * 1e9)
    if step_ns < 1:
        raise ValueError(f"step {step} s is below one nanosecond")
    period_ns = step_ns * max(1, round(PUBLISH_PERIOD * 1e9 / step_ns))
    changes: dict[str, Any] = dict(integrator=integrator, step_ns=step_ns, tolerance=tolerance,
                                   publish_period_ns=period_ns)
    if duration is not None:
        changes["duration_ns"] = round(duration * 1e9)
    return dataclasses.replace(scene, **changes)


def declared_variants() -> dict[str, Scene]:
    """One scene four ways, to show that the contact pass costs only where it is declared:
    a mass on a spring and a free ball 50 m away, with nothing more, with a wall neither
    ever reaches, and with the two in a collision group (they never touch)."""
    base = {
        "bodies": {"mass": {"shape": "box", "size": [1.0, 1.0], "mass": 1.0,
                            "position": [1.0, 0.0]},
                   "ball": {"shape": "circle", "radius": 0.5, "mass": 1.0,
                            "position": [50.0, 0.0], "velocity": [0.1, 0.0]}},
        "forces": {"spring": {"type": "spring", "body_a": "mass", "anchor": [0.0, 0.0],
                              "stiffness": 100.0}},
    }
    wall = {"walls": {"floor": {"point": [0.0, -100.0], "normal": [0.0, 1.0]}}}
    group = {"collisions": {"all": {"bodies": ["mass", "ball"]}}}
    return {
        "nothing declared": _scene("declared", 1.0, base),
        "a wall (never reached)": _scene("declared", 1.0, {**base, **wall}),
        "a collision group (never touching)": _scene("declared", 1.0, {**base, **group}),
        "both": _scene("declared", 1.0, {**base, **wall, **group}),
    }
