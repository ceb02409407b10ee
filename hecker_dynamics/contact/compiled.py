"""The contact pass in the compiled kernel (``src/kernel/contact.h``), when built.

:class:`CompiledContacts` packs a :class:`~.solver.ContactPass`'s bodies, parts, walls,
pairs' materials and map boxes once into the kernel's layout; its
:meth:`~CompiledContacts.resolve` is ``ContactPass.resolve`` in C, operation for operation,
so the two give the same bits (lengths by
:func:`~hecker_dynamics.geometry.planar.magnitude`, as C's ``hd_length``, not by ``hypot``,
which C and CPython may round apart). The warm-start impulses, and with
sleeping on the bodies' rest times and sleeping islands, live in the kernel between steps.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

try:
    from .. import _kernel  # type: ignore[attr-defined]
except ImportError:  # not built: no compiler or headers when installed
    _kernel = None

from .collision import CirclePart

if TYPE_CHECKING:
    from .sleep import Sleep
    from .solver import ContactPass

__all__ = ["CompiledContacts", "WarmImpulse"]

#: One contact's impulses kept for warm starting: the names of its two parts (k0..k3),
#: its point in body b's axes (lx, ly), and its normal and tangent impulses.
WarmImpulse = tuple[int, int, int, int, float, float, float, float]


class CompiledContacts:
    """A scene's contact pass as a kernel object."""

    def __init__(self, contacts: ContactPass) -> None:
        part_ints: list[tuple[int, int, int]] = []
        part_reals: list[float] = []
        for body, parts in enumerate(contacts.parts):
            for part in parts:
                if isinstance(part, CirclePart):
                    part_ints.append((body, _kernel.CIRCLE, 0))
                    part_reals.extend((*part.center, part.radius))
                    continue
                vertices, normals = part
                part_ints.append((body, _kernel.POLYGON if normals else _kernel.OUTLINE,
                                  len(vertices)))
                part_reals.extend(x for point in vertices + normals for x in point)
        wall_first = np.cumsum([0] + [len(b) for b in contacts.wall_bodies])
        walls = [(*n, offset, *material) for n, offset, material in
                 zip(contacts.wall_normal, contacts.wall_offset, contacts.wall_material)]
        pairs = contacts.pairs
        static_ints = [(_kernel.POLYGON, len(part.vertices)) for part in contacts.static_parts]
        static_reals = [x for part in contacts.static_parts
                        for point in part.vertices + part.normals for x in point]
        self.kernel = _kernel.contacts(
            inverse_mass=_doubles(contacts.inverse_mass),
            inverse_inertia=_doubles(contacts.inverse_inertia),
            reach=_doubles(contacts.reach), part_ints=_integers(part_ints),
            part_reals=_doubles(part_reals), walls=_doubles(walls),
            wall_first=_integers(wall_first),
            wall_body=_integers([b for bodies in contacts.wall_bodies for b in bodies]),
            colliding=_integers(contacts.colliding), classes=_integers(pairs.classes),
            class_groups=_integers(pairs.table), materials=_doubles(pairs.materials),
            apart=_integers(pairs.apart), threshold=contacts.threshold,
            thickness=contacts.thickness, static_ints=_integers(static_ints),
            static_reals=_doubles(static_reals), static_bounds=_doubles(contacts.static_bounds),
            static_material=_doubles(contacts.static_material),
            static_bodies=_integers(contacts.static_bodies), swept=_integers(contacts.swept),
            slop=_doubles(contacts.slop), converged=contacts.converged, lead=contacts.lead)
        _kernel.threads(self.kernel, count=contacts.threads)
        if contacts.sleep:
            self.set_sleep(contacts)

    def resolve(self, q1: np.ndarray, v1: np.ndarray, q0: np.ndarray, v0: np.ndarray,
                h: float, joints: Any = None) -> None:
        """``ContactPass.resolve`` in the kernel: (q1, v1) change in place; ``joints``: the
        kernel's joint pass (a capsule) whose last rows the solve sweeps too."""
        _kernel.resolve(self.kernel, q1=q1, v1=v1, q0=np.ascontiguousarray(q0),
                        v0=np.ascontiguousarray(v0), h=h, joints=joints)

    def set_sleep(self, contacts: Sleep) -> None:
        """Take sleeping on or off and each body's calm flag, rest time and sleeping island
        from ``contacts``."""
        _kernel.sleep(self.kernel, enabled=contacts.sleep, calm=_integers(contacts.calm),
                      rested=_doubles(contacts.rested), island=_integers(contacts.island))

    def sleep_state(self) -> tuple[list[float], list[int]]:
        """Each body's rest time and sleeping island (-1: awake)."""
        rested, island = _kernel.sleep(self.kernel)
        return rested, island

    def impulses(self) -> list[WarmImpulse]:
        """The warm-start impulses, those of one pair of parts together and in the order
        the solver met them."""
        return _kernel.warm(self.kernel)

    def set_impulses(self, impulses: list[WarmImpulse]) -> None:
        """Replace the warm-start impulses."""
        _kernel.warm(self.kernel, impulses=impulses)


def _doubles(values: Any) -> np.ndarray:
    return np.ascontiguousarray(np.array(values, dtype=np.float64).reshape(-1))


def _integers(values: Any) -> np.ndarray:
    return np.ascontiguousarray(np.array(values, dtype=np.int64).reshape(-1))
