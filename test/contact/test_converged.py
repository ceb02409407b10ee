"""The contact passes' tolerance, ``contacts.converged``: the default keeps today's bits, a
looser one stops the passes of a settling pile sooner with the same bits in the kernel
and in Python, and the pile still stands."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hecker_dynamics.bench.pyramid import pyramid
from hecker_dynamics.contact import compiled
from hecker_dynamics.contact.solve import CONVERGED
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.dynamics.simulation import Simulation
from hecker_dynamics.scene.fingerprint import scene_fingerprint

needs_kernel = pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not "
                                  "built or HECKER_DYNAMICS_KERNEL=0")

#: A tolerance at which the pyramid of 6 rows stops its passes sooner than by default.
LOOSE = 1e-5


def test_the_default_tolerance_is_the_solver_s_and_out_of_the_fingerprint():
    scene = pyramid(3)
    assert scene.converged is None
    assert Simulation(scene).model.contacts.converged == CONVERGED
    assert scene_fingerprint(dataclasses.replace(scene, converged=None)) == \
        scene_fingerprint(scene)
    assert scene_fingerprint(dataclasses.replace(scene, converged=LOOSE)) != \
        scene_fingerprint(scene)


@needs_kernel
def test_a_loose_tolerance_keeps_the_bits_of_python_and_changes_the_run():
    """1 s of the pyramid of 6 rows settling: the kernel and Python agree bit for bit at
    the loose tolerance, and the run differs from the default's."""
    scene = dataclasses.replace(pyramid(6), converged=LOOSE)
    fast, slow, default = Simulation(scene), Simulation(scene), Simulation(pyramid(6))
    slow.model.use_python()
    for sim in (fast, slow, default):
        sim.advance_to(1_000_000_000)
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    assert fast.model.contacts.export_state() == slow.model.contacts.export_state()
    assert not np.array_equal(fast.q, default.q)
    assert np.abs(fast.q - default.q).max() < 1e-5


@pytest.mark.parametrize("rows", [6, 10])
def test_a_pile_stands_at_the_loose_tolerance(rows):
    """Issue 37's standing test after 2 s: no box tilted more than 0.1 rad or moving faster
    than 1 cm/s, and none more than 1 mm from where the default puts it."""
    loose = Simulation(dataclasses.replace(pyramid(rows), converged=LOOSE))
    default = Simulation(pyramid(rows))
    for sim in (loose, default):
        sim.advance_to(2_000_000_000)
    tilt = np.abs((loose.q[:, 2] + np.pi / 4) % (np.pi / 2) - np.pi / 4)
    assert tilt.max() < 0.1
    assert np.hypot(loose.v[:, 0], loose.v[:, 1]).max() < 0.01
    assert np.abs(loose.q[:, :2] - default.q[:, :2]).max() < 1e-3


@needs_kernel
def test_the_kernel_refuses_a_tolerance_that_is_not_positive():
    contacts = Simulation(pyramid(3)).model.contacts
    contacts.converged = 0.0
    with pytest.raises(ValueError, match="converged must be positive"):
        compiled.CompiledContacts(contacts)
