"""The joint pass in the compiled kernel (``src/kernel/joint.h``), when built.

:class:`CompiledJoints` packs a :class:`~.joints.JointPass`'s joints once into the kernel's
layout; its :meth:`~CompiledJoints.resolve` is ``JointPass.resolve`` in C, operation for
operation, so the two give the same bits. The pass's state (start pose, counted angles,
motor speeds, warm starts) stays the Python object's: it is loaded into the kernel before
each call and read back after it.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..scene.joints import DistanceJoint, GearJoint, PrismaticJoint, RevoluteJoint, WeldJoint
from .joint_rows import weld_law
from .joints import JointsUnsolved
from .soft_joints import SoftJointPass

try:
    from .. import _kernel  # type: ignore[attr-defined]
except ImportError:  # not built: no compiler or headers when installed
    _kernel = None

if TYPE_CHECKING:
    from .joints import JointPass
    from .sparse import Pattern

__all__ = ["CompiledJoints"]


def _columns(joint_pass: JointPass) -> tuple[list[list[int]], list[list[float]]]:
    """Per joint, the ints and reals of joint.h (hd_joint)."""
    index = {spec.name: i for i, spec in enumerate(joint_pass.specs)}
    ints, reals = [], []
    for spec in joint_pass.specs:
        row = [0.0] * 14
        if isinstance(spec, GearJoint):
            ints.append([_kernel.GEAR, -1, 0, 0, 0, 0, 0, index[spec.joint_a],
                         index[spec.joint_b]])
            row[13] = spec.ratio
            reals.append(row)
            continue
        a, b = joint_pass.frames[spec.name]
        row[0:4] = [*a.local, *b.local]
        flags = [0, 0, 0, 0]
        if isinstance(spec, (RevoluteJoint, PrismaticJoint)):
            flags[:3] = [spec.lower is not None, spec.upper is not None, spec.motor is not None]
            row[6] = 0.0 if spec.lower is None else spec.lower
            row[7] = 0.0 if spec.upper is None else spec.upper
            row[8] = 0.0 if spec.motor is None else spec.motor.max_effort
        if isinstance(spec, RevoluteJoint):
            kind = _kernel.REVOLUTE
            if spec.spring is not None:
                flags[3] = 1
                row[9:12] = [spec.spring.stiffness, spec.spring.damping, spec.spring.rest_angle]
        elif isinstance(spec, PrismaticJoint):
            kind = _kernel.PRISMATIC
            row[4:6] = list(spec.axis)
        elif isinstance(spec, WeldJoint):
            kind = _kernel.WELD
            flags[3] = spec.frequency > 0.0
            row[9:11] = list(weld_law(spec))
        else:
            assert isinstance(spec, DistanceJoint)
            kind = _kernel.ROPE if spec.rope else _kernel.ROD
            row[12] = spec.length
        ints.append([kind, a.body, b.body, *map(int, flags), 0, 0])
        reals.append(row)
    return ints, reals


def _softness(joint_pass: JointPass) -> dict[str, Any]:
    """The soft joints' settings of :class:`~.soft_joints.SoftJointPass` (none: exact)."""
    if not isinstance(joint_pass, SoftJointPass):
        return {}
    soft = joint_pass.soft
    return {"substeps": soft.substeps, "hertz": soft.hertz, "damping_ratio": soft.damping_ratio}


class CompiledJoints:
    """A scene's joint pass as a kernel object."""

    def __init__(self, joint_pass: JointPass) -> None:
        ints, reals = _columns(joint_pass)
        assert joint_pass.pattern is not None  # the start pose has fixed the rows

        def arrays(pattern: Pattern) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return (np.array(pattern.start, dtype=np.int64),
                    np.array(pattern.columns, dtype=np.int64),
                    np.array(pattern.bounds, dtype=np.float64))

        self.kernel: Any = _kernel.joints(
            bodies=np.ascontiguousarray(joint_pass.bodies, dtype=np.int64),
            inverse_mass=np.array(joint_pass.inverse_mass, dtype=np.float64),
            ints=np.array(ints, dtype=np.int64).reshape(-1),
            reals=np.array(reals, dtype=np.float64).reshape(-1), rows=len(joint_pass.keys),
            pattern=arrays(joint_pass.pattern), rigid_pattern=arrays(joint_pass.rigid_pattern),
            turning=np.ascontiguousarray(joint_pass.turning, dtype=np.int64),
            tolerance=joint_pass.tolerance, max_turn=joint_pass.max_turn,
            **_softness(joint_pass))
        self._pass = joint_pass
        rigid = sum(1 for kind in joint_pass.kinds if kind == "rigid")
        self._state = np.zeros(_kernel.JOINT_STATE * len(joint_pass.specs)
                               + 2 * len(joint_pass.keys) + rigid + 4)

    def load(self) -> None:
        """The Python pass's state into the kernel."""
        values = []
        p = self._pass
        for spec in p.specs:
            name = spec.name
            if isinstance(spec, GearJoint):
                values += [0.0] * 5
                continue
            reference = p.reference[name]
            values += [reference[0], reference[1], p.angle[name], p.raw[name],
                       p.motor_speed.get(name, 0.0)]
        newton = p.newton
        values += p.warm + (newton if newton is not None else [0.0] * len(p.rigid)) + p.extra
        values += [0.0 if newton is None else 1.0, p.step_h, p.remembered, p.settled_steps]
        self._state[:] = values
        _kernel.joint_state(self.kernel, state=self._state, load=True)

    def save(self) -> None:
        """The kernel's state back into the Python pass."""
        _kernel.joint_state(self.kernel, state=self._state, load=False)
        values = self._state.tolist()
        p = self._pass
        stride = _kernel.JOINT_STATE
        for i, spec in enumerate(p.specs):
            if not isinstance(spec, GearJoint):
                p.angle[spec.name], p.raw[spec.name] = values[stride * i + 2: stride * i + 4]
        at = stride * len(p.specs)
        rows, rigid = len(p.keys), len(p.rigid)
        newton = values[at + rows: at + rows + rigid]
        p.extra = values[at + rows + rigid: at + 2 * rows + rigid]
        p.remembered, p.settled_steps = int(values[-2]), int(values[-1])
        p.restore(values[at: at + rows], newton if values[-4] != 0.0 else None, values[-3])

    def resolve(self, q0: np.ndarray, q1: np.ndarray, v1: np.ndarray, h: float) -> None:
        """``JointPass.resolve`` in the kernel; raises :class:`.JointsUnsolved` as it does."""
        self.load()
        if not _kernel.joints_resolve(self.kernel, bodies=len(q0), q0=q0, q1=q1, v1=v1, h=h):
            raise JointsUnsolved(f"the joints have no solution near the end of a step of "
                                 f"{h:g} s")
        self.save()
