"""Drive descriptions of a scene: ``drives.<name>`` (differential drives, omnidirectional
bases and thrusters).

A drive turns velocity commands (a body-frame twist, as ``geometry_msgs/Twist`` on
``/<body>/cmd_vel`` carries) into forces at its wheels' contact points or its thrusters,
through a PI velocity controller sampled every control period (a whole number of physics
steps).
``docs/scenes.md`` lists every parameter; :mod:`hecker_dynamics.drives` runs them.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Union

import numpy as np

from .parameters import MAX_SECONDS, REQUIRED, ParameterReader

__all__ = ["DiffDriveSpec", "WrenchDriveSpec", "DriveSpec", "DRIVE_TYPES", "read_drive"]

DRIVE_TYPES = ("diff_drive", "omni", "thrusters")
Vec2 = tuple[float, float]


@dataclass(frozen=True)
class _ControlledSpec:
    """What every drive has: its name and body, the motors' cap, the PI gains, the control
    period and the cmd_vel timeout."""

    name: str
    body: str
    center: Vec2
    max_force: float
    linear_kp: float
    linear_ki: float
    angular_kp: float
    angular_ki: float
    period_ns: int
    cmd_vel_timeout_ns: int


@dataclass(frozen=True)
class DiffDriveSpec(_ControlledSpec):
    """Two wheels on the body's y axis through ``center`` (body frame), ``separation``
    apart, each pushing along the body's x axis at its contact point.

    The PI controller asks for a total forward force ``linear_kp e_v + linear_ki
    integral(e_v)`` and a torque ``angular_kp e_w + angular_ki integral(e_w)`` from the
    errors of the forward speed at ``center`` and of the angular velocity; the wheels share
    them, each capped at ``max_force``. A wheel also grips sideways (``lateral_damping``
    times its sideways slip speed), and its whole force is capped at ``traction`` (the
    friction circle). A command older than ``cmd_vel_timeout`` stops the push. ``script``
    holds (time from the start in ns, linear x, angular z) commands, each repeated at every
    control instant until the next one (when the scripted inputs play)."""

    separation: float
    traction: float
    lateral_damping: float
    script: tuple[tuple[int, float, float], ...] = ()


@dataclass(frozen=True)
class WrenchDriveSpec(_ControlledSpec):
    """An omnidirectional base (``omni``: wheels that push either way along their
    directions) or a set of thrusters (``thrusters``: each pushes forward only), each
    actuator a point (body frame) and the angle of its push direction in body axes.

    The PI controller asks for a body-frame force ``linear_kp e + linear_ki integral(e)``
    from the error of the twist's linear part (measured at ``center``) and a torque
    ``angular_kp e_w + angular_ki integral(e_w)``; the actuators make that wrench as
    closely as they can (least squares; least total force among the exact solutions), all
    scaled down together so none exceeds ``max_force``. ``script`` holds (time from the
    start in ns, linear x, linear y, angular z) commands; the rest is as for
    :class:`DiffDriveSpec`."""

    kind: str
    actuators: tuple[tuple[float, float, float], ...]  # x, y, push angle
    script: tuple[tuple[int, float, float, float], ...] = ()


DriveSpec = Union[DiffDriveSpec, WrenchDriveSpec]


def _script(reader: ParameterReader, width: int) -> list[tuple[float, ...]]:
    """The drive's scripted commands, ``width`` numbers each, times at least 0 and in order,
    and at most a scene's longest time (their nanoseconds stay within an int64)."""
    flat = reader.numbers("script", [], multiple_of=width)
    script = [tuple(flat[i:i + width]) for i in range(0, len(flat), width)]
    times = [entry[0] for entry in script]
    if any(not 0 <= t <= MAX_SECONDS for t in times) or times != sorted(times):
        reader.fail("script", f"times (every {('', '', '', 'third', 'fourth')[width]} number "
                              f"from the first) must be from 0 to {MAX_SECONDS:g} s and in "
                              "order")
    return script


def read_drive(name: str, reader: ParameterReader, points: Mapping[str, Mapping[str, Vec2]],
               step_ns: int) -> DriveSpec:
    """One ``drives.<name>`` entry."""
    kind = reader.string("type", REQUIRED, choices=DRIVE_TYPES)
    body = reader.string("body", REQUIRED)
    if body not in points:
        reader.fail("body", f"names an unknown body '{body}'")
    timeout = reader.number("cmd_vel_timeout", 0.5, minimum=0.0, maximum=1e9)
    controller = _read_controller(name, body, reader, step_ns, timeout)
    if kind != "diff_drive":
        return _read_wrench_drive(kind, reader, controller)
    script = tuple((round(t * 1e9), x, z) for t, x, z in _script(reader, 3))
    return DiffDriveSpec(
        **controller, separation=reader.number("separation", REQUIRED, positive=True),
        traction=(reader.number("traction", positive=True) if reader.has("traction")
                  else float("inf")),
        lateral_damping=reader.number("lateral_damping", 0.0, minimum=0.0), script=script)


def _read_controller(name: str, body: str, reader: ParameterReader, step_ns: int,
                     timeout: float) -> dict[str, Any]:
    """The parameters every drive has (:class:`_ControlledSpec`)."""
    return dict(
        name=name, body=body, center=reader.vector("center", [0.0, 0.0]),
        max_force=reader.number("max_force", REQUIRED, positive=True),
        linear_kp=reader.number("linear_kp", REQUIRED, minimum=0.0),
        linear_ki=reader.number("linear_ki", 0.0, minimum=0.0),
        angular_kp=reader.number("angular_kp", REQUIRED, minimum=0.0),
        angular_ki=reader.number("angular_ki", 0.0, minimum=0.0),
        period_ns=reader.period_ns("rate", step_ns, 100.0),
        cmd_vel_timeout_ns=round(timeout * 1e9))


def _read_wrench_drive(kind: str, reader: ParameterReader,
                       controller: dict[str, Any]) -> WrenchDriveSpec:
    key = "wheels" if kind == "omni" else "thrusters"
    flat = reader.numbers(key, REQUIRED, multiple_of=3)
    actuators = tuple((x, y, angle) for x, y, angle in zip(flat[0::3], flat[1::3], flat[2::3]))
    if not actuators:
        reader.fail(key, "needs at least one [x, y, angle]")
    if kind == "omni" and np.linalg.matrix_rank(actuation(actuators, (0.0, 0.0))) < 3:
        reader.fail(key, "cannot push every way and turn: an omnidirectional base needs "
                         "wheels whose pushes span forces in x and y and a torque")
    script = tuple((round(t * 1e9), x, y, z) for t, x, y, z in _script(reader, 4))
    return WrenchDriveSpec(**controller, kind=kind, actuators=actuators, script=script)


def actuation(actuators: tuple[tuple[float, float, float], ...], about: Vec2) -> np.ndarray:
    """The 3 x N matrix from the actuators' push magnitudes to the body-frame force and
    the torque about ``about``: column i is (d_i, perp_dot(p_i - about, d_i)) with d_i the
    unit push direction (Eq. 11)."""
    columns = []
    for x, y, angle in actuators:
        dx, dy = np.cos(angle), np.sin(angle)
        rx, ry = x - about[0], y - about[1]
        columns.append((dx, dy, rx * dy - ry * dx))
    return np.array(columns, dtype=float).T.reshape(3, len(actuators))
