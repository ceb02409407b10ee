"""Box2D v3 as a peer of the contact and joint benchmarks, run in its own interpreter.

Box2D v3's Python binding, ``box2d-python`` (Box2D 3.1 through cffi), has wheels for
Python 3.12 and later only, so it cannot join this package's ``bench`` extra where the
package runs on 3.11. The bench finds an interpreter that imports it
(:func:`interpreter`), starts :mod:`.box2d_v3_worker` there once per process, and talks
to it in JSON lines: a scene goes over as a description (:func:`describe`), is built and
stepped there, and the worker times its own stepping loop, so no pipe round trip is in a
cost. How to get the binding (docs/benchmark.md): ``python3.12 -m venv
~/.cache/hecker_dynamics/box2d-v3 && ~/.cache/hecker_dynamics/box2d-v3/bin/pip install
box2d-python``, or any interpreter with it named in ``HECKER_DYNAMICS_BOX2D_V3_PYTHON``.

The scene is built as :mod:`.scene_peers` builds it in pymunk and Box2D 2.3, with Box2D's
rules where they meet v3's:

- Bodies at their CMs with the scene's mass and moment of inertia (the mass data set,
  not computed from the shapes); circles and polygons in the CM frame, a polygon of more
  than 8 vertices (v3's most) as a fan of convex pieces. Walls as 200 m static segments.
  Collision groups and walls as category and mask bits.
- Materials as in Box2D 2.3 (v3 mixes them the same way: the square root of the product
  of the frictions, the larger restitution).
- Gravity in the peer; every other force of the scene and the scripted wrenches from
  plain Python in the worker (:mod:`.force_law`), each body's wrench one force along its
  line of action before each step (Box2D v3's soft springs set a frequency relative to the
  joint's effective mass, another force law).
- Joints: each revolute joint as v3's revolute joint at the same two points, with its
  limits (v3 holds limits within half a turn of the start: one missing bound is taken as
  that) and its motor (``maxMotorTorque``); each weld as v3's weld joint, soft where the
  scene's is (its frequency and damping ratio, the law of v3's soft step). v3 has no gear
  joint: a scene with gears is refused, as are the joints :mod:`.scene_peers` refuses.
- Its best honest configuration: 4 sub-steps a step (its manual's), continuous collision
  and warm starting on (its defaults), one thread unless asked; sleeping as the
  comparison says (on: v3's default, off: every body awake, so every engine does the
  same work each step).

:func:`scene_engine` gives the same ``(step(count), poses())`` as
:func:`.scene_peers.scene_engine`; ``step`` returns the seconds the worker's loop took.
:func:`cast_rays` times closest-hit ray casts against a scene's shapes.
"""
from __future__ import annotations

import atexit
import glob
import json
import math
import os
import shutil
import subprocess
import sys
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any, Optional

import numpy as np

from ..geometry.shapes import Circle
from ..scene.load import Scene
from .scene_peers import _layout, _over_root

__all__ = ["PYTHON_VARIABLE", "SUBSTEPS", "VENV", "available", "cast_rays", "describe",
           "interpreter", "scene_engine", "version"]

#: The environment variable naming an interpreter that imports ``box2d`` (box2d-python).
PYTHON_VARIABLE = "HECKER_DYNAMICS_BOX2D_V3_PYTHON"
#: Where docs/benchmark.md tells users to make a venv with the binding.
VENV = Path("~/.cache/hecker_dynamics/box2d-v3").expanduser()
#: Sub-steps a step (Box2D v3's manual's recommendation).
SUBSTEPS = 4
WORKER = Path(__file__).with_name("box2d_v3_worker.py")
#: Seconds to wait for an interpreter to answer whether it imports the binding.
PROBE_TIMEOUT = 60.0

_FOUND: dict[str, Optional[str]] = {}


def _candidates() -> list[str]:
    """Where to look, in order: the variable alone where it is set; else this interpreter,
    the venv of :data:`VENV`, ``python3.12`` and ``python3.13`` on the PATH, and pyenv's
    3.12 and 3.13 (under ``$PYENV_ROOT`` or ``~/.pyenv``)."""
    named = os.environ.get(PYTHON_VARIABLE)
    if named:
        return [named]
    pyenv = Path(os.environ.get("PYENV_ROOT", "~/.pyenv")).expanduser()
    found = [sys.executable, str(VENV / "bin" / "python")]
    found += [path for name in ("python3.12", "python3.13") if (path := shutil.which(name))]
    for minor in ("3.12", "3.13"):
        found += sorted(glob.glob(str(pyenv / "versions" / f"{minor}*" / "bin" / "python")))
    return list(dict.fromkeys(found))


def interpreter() -> Optional[str]:
    """The first of the candidates that imports Box2D v3's binding, or None (once per
    process)."""
    if "python" not in _FOUND:
        _FOUND["python"] = None
        for python in _candidates():
            try:
                probe = subprocess.run([python, "-I", "-c", "import box2d._box2d"],
                                       capture_output=True, timeout=PROBE_TIMEOUT)
            except (OSError, subprocess.SubprocessError):
                continue
            if probe.returncode == 0:
                _FOUND["python"] = python
                break
    return _FOUND["python"]


def available() -> bool:
    return interpreter() is not None


class _Worker:
    """The worker process, started on first use and closed at exit."""

    def __init__(self, python: str) -> None:
        self.process = subprocess.Popen([python, "-I", str(WORKER)], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, text=True, bufsize=1)

    def ask(self, **request: Any) -> dict[str, Any]:
        stdin: IO[str] = self.process.stdin  # type: ignore[assignment]
        stdout: IO[str] = self.process.stdout  # type: ignore[assignment]
        stdin.write(json.dumps(request) + "\n")
        stdin.flush()
        line = stdout.readline()
        if not line:
            raise RuntimeError(f"the Box2D v3 worker ended (exit {self.process.poll()})")
        reply = json.loads(line)
        if "error" in reply:
            raise ValueError(f"Box2D v3: {reply['error']}")
        return reply

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.stdin.close()  # type: ignore[union-attr]
            self.process.wait(timeout=10)


_WORKERS: dict[str, _Worker] = {}


def _worker() -> _Worker:
    python = interpreter()
    if python is None:
        raise ImportError("Box2D v3's binding (box2d-python) imports in no interpreter found; "
                          f"see docs/benchmark.md or set {PYTHON_VARIABLE}")
    if "worker" not in _WORKERS:
        _WORKERS["worker"] = _Worker(python)
        atexit.register(_WORKERS["worker"].close)
    return _WORKERS["worker"]


def version() -> str:
    return _worker().ask(op="version")["version"] if available() else "not installed"


# ----------------------------------------------------------------------------- the scene

def _pairs(points: Any) -> list[list[float]]:
    return [[float(x), float(y)] for x, y in points]


def describe(scene: Scene) -> dict[str, Any]:
    """The scene as the worker builds it (plain JSON): gravity; per body its CM pose and
    velocity, mass, moment of inertia, shapes in the CM frame (``circles`` as (x, y, r),
    ``polygons`` as vertex lists), filter bits and (restitution, friction); the walls as
    segments with their bits and materials; the joints (``kind`` "revolute" or "weld"
    with the fields of :class:`.scene_peers._Pin` or :class:`.scene_peers._Weld`); the
    Python force terms (:func:`.force_law.make_wrenches`'s arguments, gravity out); the
    script (body, start ns, end ns, frame body or -1, point, force, torque)."""
    layout = _layout(scene)
    if layout.gears:
        raise ValueError(f"{scene.source}: Box2D v3 has no gear joint")
    model = layout.model
    q, v = model.start()
    bodies = []
    for i, parts in enumerate(layout.shapes):
        category, mask = layout.body_bits[i]
        restitution, friction = layout.materials[i] or (0.0, 1.0)
        bodies.append({
            "position": [float(q[i, 0]), float(q[i, 1])], "angle": float(q[i, 2]),
            "velocity": [float(v[i, 0]), float(v[i, 1])], "omega": float(v[i, 2]),
            "mass": model.mass[i], "inertia": model.inertia[i],
            "circles": [[*map(float, p.center), float(p.radius)] for p in parts
                        if isinstance(p, Circle)],
            "polygons": [_pairs(p) for p in parts if not isinstance(p, Circle)],
            "category": category, "mask": mask, "material": [restitution, friction]})
    walls = [{"start": _pairs([w.start])[0], "end": _pairs([w.end])[0],
              "category": w.category, "mask": w.mask,
              "material": [w.restitution,
                           _over_root(w.friction, (w.stops or (0.0, 1.0))[1]) ** 2]}
             for w in layout.walls]
    joints: list[dict[str, Any]] = []
    for pin in layout.pins:
        limits = None if pin.limits is None else [max(pin.limits[0], -math.pi),
                                                  min(pin.limits[1], math.pi)]
        joints.append({"kind": "revolute", "a": pin.a, "anchor_a": list(pin.anchor_a),
                       "b": pin.b, "anchor_b": list(pin.anchor_b), "reference": pin.reference,
                       "limits": limits, "motor": None if pin.motor is None else
                       list(pin.motor), "collide": pin.collide})
    for weld in layout.welds:
        joints.append({"kind": "weld", **weld._asdict(), "anchor_a": list(weld.anchor_a),
                       "anchor_b": list(weld.anchor_b)})
    forces = {"springs": model.springs, "drags": model.drags, "angular": model.angular,
              "forces": model.forces, "constant": model.constant}
    script = [[c.body, c.start, c.end, c.frame, list(c.point), list(c.force), c.torque]
              for c in layout.script]
    return json.loads(json.dumps({"gravity": list(layout.gravity), "bodies": bodies,
                                  "walls": walls, "joints": joints, "forces": forces,
                                  "script": script}))


# ----------------------------------------------------------------------------- running

Engine = tuple[Callable[[int], float], Callable[[], np.ndarray]]


def _destroy(worker: _Worker, world: int) -> None:
    if worker.process.poll() is None:
        worker.ask(op="destroy", world=world)


def scene_engine(scene: Scene, h: float, sleep: bool = True, threads: int = 1,
                 blocks: Optional[list[float]] = None) -> Engine:
    """``scene`` built in Box2D v3 at the step ``h``: ``step(count)`` steps it in the
    worker and returns the seconds its loop took there; ``poses()`` are (x, y, angle) of
    every CM. ``blocks``: a list that each ``step`` extends with the seconds per step of
    its blocks of 25 steps (block statistics, to explain a whole run's cost)."""
    worker = _worker()
    world = worker.ask(op="build", scene=describe(scene), step=h, substeps=SUBSTEPS,
                       sleep=sleep, threads=threads)["world"]

    def step(count: int) -> float:
        reply = worker.ask(op="step", world=world, count=count,
                           block=0 if blocks is None else 25)
        if blocks is not None:
            blocks.extend(reply["blocks"])
        return float(reply["wall"])

    def poses() -> np.ndarray:
        return np.array(worker.ask(op="poses", world=world)["poses"])

    weakref.finalize(step, _destroy, worker, world).atexit = False
    return step, poses


def cast_rays(scene: Scene, rays: list[tuple[float, float, float, float]], repeats: int = 1,
              steps: int = 0, h: Optional[float] = None) -> tuple[float, list[tuple[Any, ...]]]:
    """Closest hits of ``rays`` ((x, y, dx, dy): from (x, y) along (dx, dy)) against
    ``scene``'s shapes after ``steps`` steps of ``h`` (default the scene's): the seconds per
    ray (over ``repeats`` passes, timed in the worker) and, per ray, (body index, -1 for a
    wall, None for no hit; fraction of the ray; hit point x, y)."""
    worker = _worker()
    h = scene.step_ns * 1e-9 if h is None else h
    world = worker.ask(op="build", scene=describe(scene), step=h, substeps=SUBSTEPS,
                       sleep=True, threads=1)["world"]
    try:
        if steps:
            worker.ask(op="step", world=world, count=steps)
        reply = worker.ask(op="rays", world=world, rays=[list(map(float, r)) for r in rays],
                           repeats=repeats)
    finally:
        worker.ask(op="destroy", world=world)
    return reply["wall"] / max(1, len(rays) * repeats), [tuple(hit) for hit in reply["hits"]]
