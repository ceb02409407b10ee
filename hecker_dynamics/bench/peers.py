"""Optional peers: pymunk, Box2D (pybox2d) and MuJoCo on the same scenes and force law.

Each adapter builds the scene from its :class:`~hecker_dynamics.scene.load.Scene` (bodies at
their CMs with the scene's mass and moment of inertia, no collision shapes) and returns
:class:`~.measure.Case` objects. Each claims a scheme, checked by :func:`check_peer`
against a plain Python loop of that scheme on the same forces (:class:`~.reference.PlainModel`):

- ``pymunk`` ``python``: every force computed in Python (:func:`.force_law.make_program`,
  the peers' lean loop) in the first body's ``velocity_func`` of each step, which
  Chipmunk calls after it has moved the positions. The scheme is
  position-first symplectic Euler (q += h v; v += h a(q_new, v)). Forces set before
  ``step()`` instead would be evaluated at the old positions: explicit Euler (a trap the
  check shows). ``native``: springs as Chipmunk ``DampedSpring`` constraints and gravity
  as the space's, the rest in ``velocity_func``. The same scheme for undamped springs;
  Chipmunk integrates a spring's damping exactly (exponential decay), another law.
- ``box2d``: forces from Python before ``Step()`` (the same loop, ``ApplyForce`` at points);
  Box2D is semi-implicit Euler in float32, no body may sleep (``allowSleep=False``), and it
  clamps a step's motion to 2 m and 0.5 pi rad (compile-time constants).
- ``mujoco``: slide x, slide y, hinge z joints per body with the CM on the hinge axis;
  springs and dampers in the model (joint stiffness for a zero-length spring at the CM,
  spatial tendons with stiffness, spring length and damping otherwise; linear drag as
  slide-joint damping), gravity in the options, constant wrenches in ``xfrc_applied``
  (constant, so holding them across RK4 stages is exact). Contacts off, auto-reset off.
  ``euler`` with ``eulerdamp`` off is semi-implicit Euler; ``rk4`` is classical RK4;
  ``implicitfast`` treats damping implicitly.
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from collections.abc import Callable
from typing import Any, Optional

import numpy as np

from ..scene.load import Scene
from .force_law import make_program
from .measure import Case, Outcome
from .reference import PlainModel
from .scene_peers import box2d_calls, pymunk_calls

__all__ = ["available", "version", "mujoco_xml", "peer_run", "peer_case", "plain_loop", "Check",
           "check_peer"]

PEERS = ("pymunk", "box2d", "mujoco")
#: The method names of each peer in the sweep, with the scheme each claims.
PEER_METHODS = {
    "pymunk": {"python": "position_first_euler", "native": "position_first_euler"},
    "box2d": {"python": "semi_implicit_euler"},
    "mujoco": {"euler": "semi_implicit_euler", "rk4": "rk4", "implicitfast": "semi_implicit_euler"},
}


def available(peer: str) -> bool:
    """True if the peer's Python package imports (Box2D v3's: in an interpreter
    :mod:`.box2d_v3` finds)."""
    if peer == "box2d_v3":
        from . import box2d_v3

        return box2d_v3.available()
    module = {"pymunk": "pymunk", "box2d": "Box2D", "mujoco": "mujoco"}[peer]
    try:
        __import__(module)
    except Exception:
        return False
    return True


def version(peer: str) -> str:
    try:
        if peer == "box2d_v3":
            from . import box2d_v3

            return box2d_v3.version()
        if peer == "pymunk":
            import pymunk
            return pymunk.version
        if peer == "box2d":
            import Box2D
            return getattr(Box2D, "__version__", "2.3")
        import mujoco
        return mujoco.__version__
    except Exception:
        return "not installed"


#: A peer's run: step(count), and state() -> its CM positions and angles, and velocities.
PeerRun = tuple[Callable[[int], None], Callable[[], tuple[np.ndarray, np.ndarray]]]


def _no_contacts(scene: Scene) -> Scene:
    return dataclasses.replace(scene, walls=(), collisions=(), script=())


# ----------------------------------------------------------------------------- pymunk

def _pymunk_build(scene: Scene, method: str, h: float,
                  forces_before_step: bool = False) -> PeerRun:
    import pymunk

    model = PlainModel(_no_contacts(scene))
    native = method == "native"
    python_model = model.without(springs=native, gravity=native) if native else model
    space = pymunk.Space()
    if native and model.gravity:
        space.gravity = model.gravity[0][1:]
    q, v = model.start()
    bodies = []
    for i in range(model.n):
        body = pymunk.Body(model.mass[i], model.inertia[i])
        body.position = (q[i, 0], q[i, 1])
        body.angle = q[i, 2]
        body.velocity = (v[i, 0], v[i, 1])
        body.angular_velocity = v[i, 2]
        bodies.append(body)
        space.add(body)
    if native:
        for a, la, b, lb, k, rest, damp in model.springs:
            if b < 0:
                static = space.static_body
                space.add(pymunk.DampedSpring(bodies[a], static, la, lb, rest, k, damp))
            else:
                space.add(pymunk.DampedSpring(bodies[a], bodies[b], la, lb, rest, k, damp))
    program = make_program(python_model.springs, python_model.drags, python_model.angular,
                           python_model.forces, python_model.constant,
                           [pymunk_calls(b) for b in bodies])
    applied = [-1]
    counter = [0]

    if program is not None and not forces_before_step:
        apply_forces = program

        def velocity_func(body: Any, gravity: Any, damping: float, dt: float) -> None:
            if applied[0] != counter[0]:  # the first body of this step: every body's forces
                applied[0] = counter[0]
                apply_forces()
            pymunk.Body.update_velocity(body, gravity, damping, dt)

        for body in bodies:
            body.velocity_func = velocity_func

    def step(count: int) -> None:
        for _ in range(count):
            if forces_before_step and program is not None:
                program()
            counter[0] += 1
            space.step(h)

    def state() -> tuple[np.ndarray, np.ndarray]:
        qs = np.array([(b.position[0], b.position[1], b.angle) for b in bodies])
        vs = np.array([(b.velocity[0], b.velocity[1], b.angular_velocity) for b in bodies])
        return qs, vs

    return step, state


# ----------------------------------------------------------------------------- Box2D

def _box2d_build(scene: Scene, method: str, h: float) -> PeerRun:
    import Box2D

    model = PlainModel(_no_contacts(scene))
    forces = model.without(gravity=True)
    world = Box2D.b2World(gravity=model.gravity[0][1:] if model.gravity else (0.0, 0.0),
                          doSleep=False)
    q, v = model.start()
    bodies = []
    for i in range(model.n):
        body = world.CreateDynamicBody(position=(q[i, 0], q[i, 1]), angle=q[i, 2],
                                       linearVelocity=(v[i, 0], v[i, 1]),
                                       angularVelocity=v[i, 2], allowSleep=False, awake=True)
        mass = Box2D.b2MassData()
        mass.mass, mass.center, mass.I = model.mass[i], (0.0, 0.0), model.inertia[i]
        body.massData = mass
        bodies.append(body)
    program = make_program(forces.springs, forces.drags, forces.angular, forces.forces,
                           forces.constant, [box2d_calls(b) for b in bodies])

    def step(count: int) -> None:
        for _ in range(count):
            if program is not None:
                program()
            world.Step(h, 8, 3)

    def state() -> tuple[np.ndarray, np.ndarray]:
        qs = np.array([(b.position[0], b.position[1], b.angle) for b in bodies])
        vs = np.array([(b.linearVelocity[0], b.linearVelocity[1], b.angularVelocity)
                       for b in bodies])
        return qs, vs

    return step, state


# ----------------------------------------------------------------------------- MuJoCo

def mujoco_xml(scene: Scene, method: str, h: float) -> str:
    """The scene as an MJCF model: planar joints, springs and dampers in the model."""
    model = PlainModel(_no_contacts(scene))
    integrator = {"euler": "Euler", "rk4": "RK4", "implicitfast": "implicitfast",
                  "implicit": "implicit"}[method]
    gx, gy = model.gravity[0][1:] if model.gravity else (0.0, 0.0)
    names = [b.name for b in scene.bodies]
    drag = {i: c for i, local, c, quad in model.drags if local is None and not quad}
    if len(drag) != len(model.drags) or model.angular or model.forces:
        raise ValueError("mujoco adapter: only linear drag at the CM is supported")
    joint_springs = {}  # body -> (k, anchor): zero-length undamped springs at the CM
    tendons = []
    sites: dict[int, list[tuple[str, tuple[float, float]]]] = {i: [] for i in range(model.n)}
    world_sites = []
    for s, (a, la, b, lb, k, rest, damp) in enumerate(model.springs):
        if b < 0 and rest == 0.0 and damp == 0.0 and la == (0.0, 0.0) and a not in joint_springs:
            joint_springs[a] = (k, lb)
            continue
        sites[a].append((f"s{s}a", la))
        if b < 0:
            world_sites.append((f"s{s}b", lb))
        else:
            sites[b].append((f"s{s}b", lb))
        tendons.append(f'<spatial name="t{s}" stiffness="{k!r}" springlength="{rest!r}" '
                       f'damping="{damp!r}"><site site="s{s}a"/><site site="s{s}b"/></spatial>')
    lines = ['<mujoco model="bench">',
             f'<option timestep="{h!r}" integrator="{integrator}" gravity="{gx!r} {gy!r} 0">',
             '<flag contact="disable" eulerdamp="disable"/></option>', '<worldbody>']
    lines += [f'<site name="{n}" pos="{p[0]!r} {p[1]!r} 0"/>' for n, p in world_sites]
    for i, name in enumerate(names):
        k, anchor = joint_springs.get(i, (0.0, (0.0, 0.0)))
        c = drag.get(i, 0.0)
        inertia = model.inertia[i]
        lines += [f'<body name="{name}">',
                  f'<joint name="{name}_x" type="slide" axis="1 0 0" stiffness="{k!r}" '
                  f'springref="{anchor[0]!r}" damping="{c!r}"/>',
                  f'<joint name="{name}_y" type="slide" axis="0 1 0" stiffness="{k!r}" '
                  f'springref="{anchor[1]!r}" damping="{c!r}"/>',
                  f'<joint name="{name}_a" type="hinge" axis="0 0 1"/>',
                  f'<inertial pos="0 0 0" mass="{model.mass[i]!r}" '
                  f'diaginertia="{inertia!r} {inertia!r} {inertia!r}"/>']
        lines += [f'<site name="{n}" pos="{p[0]!r} {p[1]!r} 0"/>' for n, p in sites[i]]
        lines.append('</body>')
    lines.append('</worldbody>')
    if tendons:
        lines += ['<tendon>', *tendons, '</tendon>']
    lines.append('</mujoco>')
    return "\n".join(lines)


def _mujoco_build(scene: Scene, method: str, h: float) -> PeerRun:
    import mujoco

    # Diverging runs are expected in the sweep: no MUJOCO_LOG.TXT, no console spam (older
    # bindings have no such hook).
    with contextlib.suppress(AttributeError):
        mujoco.set_mju_user_warning(lambda message: None)
    model = PlainModel(_no_contacts(scene))
    m = mujoco.MjModel.from_xml_string(mujoco_xml(scene, method, h))
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    d = mujoco.MjData(m)
    q, v = model.start()
    d.qpos[:] = q.ravel()
    d.qvel[:] = v.ravel()
    for i in range(model.n):  # constant world forces and torques at the CM
        fx, fy, tau = model.constant[i]
        for gi, gx, gy in model.gravity:
            if gi == i:
                fx -= model.mass[i] * gx
                fy -= model.mass[i] * gy
        d.xfrc_applied[i + 1, :] = (fx, fy, 0.0, 0.0, 0.0, tau)
    mujoco.mj_forward(m, d)

    def step(count: int) -> None:
        mujoco.mj_step(m, d, nstep=count)

    def state() -> tuple[np.ndarray, np.ndarray]:
        return d.qpos.reshape(-1, 3).copy(), d.qvel.reshape(-1, 3).copy()

    return step, state


BUILDERS = {"pymunk": _pymunk_build, "box2d": _box2d_build, "mujoco": _mujoco_build}


def peer_run(peer: str, scene: Scene, method: str, h: float, duration: float) -> Outcome:
    """Build afresh (untimed), then step over ``duration`` (timed)."""
    step, state = BUILDERS[peer](scene, method, h)
    count = max(1, round(duration / h))
    failed = ""
    start = time.perf_counter()
    with np.errstate(all="ignore"):
        try:
            step(count)
        except Exception as error:  # pragma: no cover - a peer blowing up
            failed = f"{type(error).__name__}: {error}"
    wall = time.perf_counter() - start
    q, v = state()
    if not failed and not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        failed = "state not finite"
    return Outcome(wall, q, v, steps=count, failed=failed)


def peer_case(peer: str, name: str, scene: Scene, method: str, h: float,
              duration: float) -> Case:
    return Case(name, peer, method, h, math.nan, duration,
                lambda d: peer_run(peer, scene, method, h, d),
                note=f"scheme {PEER_METHODS[peer][method]}")


# ----------------------------------------------------------------------------- checks

def plain_loop(model: PlainModel, scheme: str, h: float, steps: int,
               float32: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The claimed scheme as a plain loop on the plain model; final (q, v)."""
    n = model.n
    y = model.y0.copy()
    q, v = y[:3 * n].copy(), y[3 * n:].copy()

    def acc(q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.array(model.accelerations(np.concatenate([q, v])))

    for _ in range(steps):
        if scheme == "semi_implicit_euler":
            v = v + h * acc(q, v)
            q = q + h * v
        elif scheme == "position_first_euler":
            q = q + h * v
            v = v + h * acc(q, v)
        elif scheme == "explicit_euler":
            a = acc(q, v)
            q, v = q + h * v, v + h * a
        elif scheme == "rk4":
            y = np.concatenate([q, v])
            f = model.derivative
            k1 = f(y)
            k2 = f(y + 0.5 * h * k1)
            k3 = f(y + 0.5 * h * k2)
            k4 = f(y + h * k3)
            y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            q, v = y[:3 * n], y[3 * n:]
        else:
            raise ValueError(scheme)
        if float32:
            q, v = q.astype(np.float32).astype(float), v.astype(np.float32).astype(float)
    return q.reshape(n, 3), v.reshape(n, 3)


@dataclasses.dataclass
class Check:
    peer: str
    method: str
    scheme: str
    scene: str
    step: float
    steps: int
    difference: float  # largest |q - q_plain| over positions and angles
    scale: float  # largest |q_plain| (for relative size)
    note: str = ""


def check_peer(peer: str, method: str, name: str, scene: Scene, h: float = 1e-3,
               steps: int = 200, scheme: Optional[str] = None,
               forces_before_step: bool = False) -> Check:
    """Run the peer and the plain loop of its claimed scheme; report the difference."""
    scheme = scheme or PEER_METHODS[peer][method]
    if peer == "pymunk":
        step, state = _pymunk_build(scene, method, h, forces_before_step=forces_before_step)
    else:
        step, state = BUILDERS[peer](scene, method, h)
    step(steps)
    q, _ = state()
    qp, _ = plain_loop(PlainModel(_no_contacts(scene)), scheme, h, steps)
    return Check(peer, method + (" (forces before step)" if forces_before_step else ""),
                 scheme, name, h, steps, float(np.max(np.abs(q - qp))),
                 float(np.max(np.abs(qp))))
