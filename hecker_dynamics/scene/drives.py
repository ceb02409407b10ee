"""Drive descriptions of a scene: ``drives.<name>`` (differential drives).

A drive turns velocity commands (a body-frame twist, as ``geometry_msgs/Twist`` on
``/<body>/cmd_vel`` carries) into forces at its wheels' contact points, through a PI
velocity controller sampled every control period (a whole number of physics steps).
``docs/scenes.md`` lists every parameter; :mod:`hecker_dynamics.drives` runs them.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .parameters import REQUIRED, ParameterReader
from .sensors import sample_period_ns

__all__ = ["DiffDriveSpec", "DRIVE_TYPES", "read_drive"]

DRIVE_TYPES = ("diff_drive",)
Vec2 = tuple[float, float]


@dataclass(frozen=True)
class DiffDriveSpec:
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

    name: str
    body: str
    center: Vec2
    separation: float
    max_force: float
    traction: float
    lateral_damping: float
    linear_kp: float
    linear_ki: float
    angular_kp: float
    angular_ki: float
    period_ns: int
    cmd_vel_timeout_ns: int
    script: tuple[tuple[int, float, float], ...] = ()


def read_drive(name: str, reader: ParameterReader, points: Mapping[str, Mapping[str, Vec2]],
               step_ns: int) -> DiffDriveSpec:
    """One ``drives.<name>`` entry."""
    reader.string("type", REQUIRED, choices=DRIVE_TYPES)
    body = reader.string("body", REQUIRED)
    if body not in points:
        reader.fail("body", f"names an unknown body '{body}'")
    timeout = reader.number("cmd_vel_timeout", 0.5, minimum=0.0, maximum=1e9)
    flat = reader.numbers("script", [], multiple_of=3)
    script = tuple((round(t * 1e9), x, z) for t, x, z in zip(flat[0::3], flat[1::3], flat[2::3]))
    times = [t for t, _, _ in script]
    if any(t < 0 for t in times) or times != sorted(times):
        reader.fail("script", "times (every third number from the first) must be at least "
                              "0 and in order")
    return DiffDriveSpec(
        name, body, center=reader.vector("center", [0.0, 0.0]),
        separation=reader.number("separation", REQUIRED, positive=True),
        max_force=reader.number("max_force", REQUIRED, positive=True),
        traction=(reader.number("traction", positive=True) if reader.has("traction")
                  else float("inf")),
        lateral_damping=reader.number("lateral_damping", 0.0, minimum=0.0),
        linear_kp=reader.number("linear_kp", REQUIRED, minimum=0.0),
        linear_ki=reader.number("linear_ki", 0.0, minimum=0.0),
        angular_kp=reader.number("angular_kp", REQUIRED, minimum=0.0),
        angular_ki=reader.number("angular_ki", 0.0, minimum=0.0),
        period_ns=sample_period_ns(reader, step_ns, 100.0),
        cmd_vel_timeout_ns=round(timeout * 1e9), script=script)
