"""The joint pass in the compiled kernel (``src/kernel/joint.h``), when built.

:class:`CompiledJoints` packs a :class:`~.joints.JointPass`'s joints once into the kernel's
layout; its :meth:`~CompiledJoints.resolve` is ``JointPass.resolve`` in C, operation for
operation, so the two give the same bits. The pass's state (start pose, counted angles,
motor speeds, warm starts) stays in the kernel from call to call: it is loaded from the
Python object only after the object changed it (else only the motor speeds and the parts
the object keeps go in, :meth:`~CompiledJoints.begin`), and read back into the object only
when the object's attributes are read (:data:`~.joints.CARRIED`); moving it costs O(joints)
in Python, more than a soft step of the kernel on a large grid.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..scene.joints import DistanceJoint, GearJoint, PrismaticJoint, RevoluteJoint, WeldJoint
from .joint_rows import weld_law
from .joints import CARRIED, PARTS, JointsUnsolved
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
            free_turn=np.array(joint_pass.free_turn, dtype=np.float64),
            tolerance=joint_pass.tolerance, max_turn=joint_pass.max_turn,
            share=joint_pass.share, **_softness(joint_pass))
        self._pass = joint_pass
        rigid = sum(1 for kind in joint_pass.kinds if kind == "rigid")
        self._state = np.zeros(_kernel.JOINT_STATE * len(joint_pass.specs)
                               + 2 * len(joint_pass.keys) + rigid + 4)
        #: Whether the kernel holds the pass's state (else :meth:`begin` loads it).
        self.loaded = False
        #: Whether the kernel's state is newer than the pass's :data:`~.joints.CARRIED`
        #: attributes, which are absent then (:meth:`take_back` reads them back).
        self.ahead = False
        #: Where each motor's speed lies in the state.
        self._motors = [(_kernel.JOINT_STATE * i + 4, spec.name)
                        for i, spec in enumerate(joint_pass.specs)
                        if isinstance(spec, (RevoluteJoint, PrismaticJoint)) and spec.motor]
        #: Where each joint's counted angle lies in the state (its unwrapped one next), in
        #: the order of the pass's own (its frames').
        solved = {spec.name: i for i, spec in enumerate(joint_pass.specs)}
        self._angles = [(name, _kernel.JOINT_STATE * solved[name] + 2)
                        for name in joint_pass.frames]

    def begin(self) -> None:
        """Before a call of the kernel: load the pass's state if the kernel does not hold
        it; else pass the kernel's own state through :attr:`_state` (copies in C, no
        Python per joint) with what Python keeps of it: the motor speeds commanded
        (O(motors)) and, unless the kernel's whole steps changed them since, the parts
        remembered (:data:`~.joints.PARTS`). Loading resets what the kernel keeps within
        a call alone, as loading the pass's state at every call did."""
        if not self.loaded:
            self.load()
            self.loaded = True
            return
        _kernel.joint_state(self.kernel, state=self._state, load=False)
        for at, name in self._motors:
            self._state[at] = self._pass.motor_speed[name]
        if PARTS[0] in self._pass.__dict__:
            self._state[-2:] = [self._pass.remembered, self._pass.settled_steps]
        _kernel.joint_state(self.kernel, state=self._state, load=True)

    def end(self, whole: bool = False) -> None:
        """After a call of the kernel: its state is the newer; the pass's copy is dropped
        until read, and the parts remembered too after ``whole`` steps (which change
        them; a resolve alone does not, the simulation keeps them then)."""
        for name in CARRIED + PARTS if whole else CARRIED:
            self._pass.__dict__.pop(name, None)
        self.ahead = True

    def take_back(self) -> None:
        """The kernel's state into the pass, if it is the newer."""
        if self.ahead:
            self.ahead = False
            self.save()

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
        p.angle = {name: values[at] for name, at in self._angles}
        p.raw = {name: values[at + 1] for name, at in self._angles}
        at = _kernel.JOINT_STATE * len(p.specs)
        rows, rigid = len(p.keys), len(p.rigid)
        newton = values[at + rows: at + rows + rigid]
        p.extra = values[at + rows + rigid: at + 2 * rows + rigid]
        if PARTS[0] not in p.__dict__:  # else the simulation's, newer (see end)
            p.remembered, p.settled_steps = int(values[-2]), int(values[-1])
        p.restore(values[at: at + rows], newton if values[-4] != 0.0 else None, values[-3])

    def resolve(self, q0: np.ndarray, q1: np.ndarray, v1: np.ndarray, h: float) -> None:
        """``JointPass.resolve`` in the kernel; raises :class:`.JointsUnsolved` as it does,
        the kernel's state left as it was before the call (the step is retried in halves)."""
        self.begin()  # leaves the state it loaded in _state
        if not _kernel.joints_resolve(self.kernel, bodies=len(q0), q0=q0, q1=q1, v1=v1, h=h):
            _kernel.joint_state(self.kernel, state=self._state, load=True)
            raise JointsUnsolved(f"the joints have no solution near the end of a step of "
                                 f"{h:g} s")
        self.end()
