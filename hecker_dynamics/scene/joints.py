"""Joints as a scene declares them: pins, sliders, welds, rods, ropes and gears, with their
limits, motors and springs (``joints.<name>`` in a parameters file, docs/scenes.md).

These are the specs only; :mod:`hecker_dynamics.contact.joints` solves them.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Optional, Union

from .parameters import number_text, quoted

__all__ = ["Motor", "RotarySpring", "JointEnds", "RevoluteJoint", "PrismaticJoint", "WeldJoint",
           "DistanceJoint", "GearJoint", "JointSpec", "SoftJoints", "motor_overflow",
           "soft_refusal", "softness"]

Vec2 = tuple[float, float]


@dataclass(frozen=True)
class Motor:
    """Drives a joint's coordinate at ``speed`` (rad/s or m/s) with at most ``max_effort``
    (N m or N)."""

    speed: float
    max_effort: float


def motor_overflow(speed: float, max_effort: float) -> Optional[str]:
    """Why a motor cannot drive at ``speed`` with at most ``max_effort``, or None if it
    can: the energy bound counts a motor's power as at most its effort times its target
    speed (:mod:`hecker_dynamics.dynamics.divergence`), which must be a double. Each caller
    names the speed before this text (a scene parameter, a joint's command)."""
    if math.isfinite(speed * max_effort):
        return None
    return (f"{number_text(speed)} times the motor's largest effort "
            f"{number_text(max_effort)} is a power past what a double holds")


@dataclass(frozen=True)
class RotarySpring:
    """A torque -k (angle - rest_angle) - c (angular velocity) about a revolute joint."""

    stiffness: float
    damping: float
    rest_angle: float


@dataclass(frozen=True, kw_only=True)
class JointEnds:
    """What every joint but a gear has: ``body_a`` (None: the fixed frame) and ``body_b``,
    a point of each (fixed-frame coordinates for the fixed frame), and whether the two
    bodies still collide."""

    name: str
    body_a: Optional[str]
    body_b: str
    point_a: Vec2
    point_b: Vec2
    collide_connected: bool = False


@dataclass(frozen=True, kw_only=True)
class RevoluteJoint(JointEnds):
    """A pin: point ``point_a`` of ``body_a`` (fixed-frame coordinates when ``body_a`` is
    None, the world) and ``point_b`` of ``body_b`` (body frame) stay together. The joint
    angle is body_b's angle relative to body_a's, zero at the start; ``lower`` and
    ``upper`` bound it."""

    lower: Optional[float] = None
    upper: Optional[float] = None
    motor: Optional[Motor] = None
    spring: Optional[RotarySpring] = None


@dataclass(frozen=True, kw_only=True)
class PrismaticJoint(JointEnds):
    """A slider: ``point_b`` moves along the line through ``point_a`` with direction
    ``axis`` (unit, in body_a's frame or the fixed frame), and the bodies keep their
    relative angle. The translation along the axis is zero at the start."""

    axis: Vec2
    lower: Optional[float] = None
    upper: Optional[float] = None
    motor: Optional[Motor] = None


@dataclass(frozen=True, kw_only=True)
class WeldJoint(JointEnds):
    """The two bodies hold their relative pose at the start; with ``frequency`` > 0 (Hz)
    a spring-damper of that frequency and ``damping_ratio`` holds it instead."""

    frequency: float = 0.0
    damping_ratio: float = 1.0


@dataclass(frozen=True, kw_only=True)
class DistanceJoint(JointEnds):
    """A rod keeps the points ``length`` apart; a rope (``rope``) at most ``length``."""

    length: float
    rope: bool = False


@dataclass(frozen=True)
class GearJoint:
    """Two revolute joints' angles tied: angle_a + ratio angle_b stays zero (meshing gears
    of radii r_a and r_b turn opposite ways: ratio = r_b / r_a)."""

    name: str
    joint_a: str
    joint_b: str
    ratio: float


JointSpec = Union[RevoluteJoint, PrismaticJoint, WeldJoint, DistanceJoint, GearJoint]


@dataclass(frozen=True)
class SoftJoints:
    """``joint_solver.type: soft``: the joints solved as Box2D v3 solves them, in
    ``substeps`` equal sub-steps of sequential impulses on soft rows, whose position error
    a spring-damper of ``hertz`` (Hz) and ``damping_ratio`` removes
    (:mod:`hecker_dynamics.contact.soft_joints`)."""

    substeps: int = 4
    hertz: float = 60.0
    damping_ratio: float = 2.0


def softness(hertz: float, damping_ratio: float, h: float) -> tuple[float, float, float]:
    """(bias rate 1/s, mass scale, impulse scale) of a spring-damper of ``hertz`` and
    ``damping_ratio`` per unit effective mass, integrated implicitly over ``h``: Box2D v3's
    b2MakeSoft."""
    omega = 2.0 * math.pi * hertz
    a1 = 2.0 * damping_ratio + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return omega / a1, a2 * a3, a3


def soft_refusal(integrator: str, contacts: Sequence[str]) -> Optional[str]:
    """Why soft joints cannot step with ``integrator`` in a scene that has ``contacts``
    (what it has of walls, collision groups and a map), or None: their sub-steps are
    Box2D's semi-implicit Euler, and the contact solve sweeps the exact pass's rows."""
    if integrator != "semi_implicit_euler":
        return ("soft joints take semi-implicit Euler sub-steps as Box2D v3 does: set "
                f"integrator to semi_implicit_euler, not {quoted(integrator)}")
    if contacts:
        return (f"soft joints are not solved with contacts, and this scene has "
                f"{' and '.join(contacts)}: use joint_solver.type exact")
    return None
