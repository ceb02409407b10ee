"""Two threads for the velocity passes of big islands (the scene's ``contacts.threads``):
the colours of a big island split between the calling thread and a worker, with the bits
of one thread (src/kernel/wide.c, crew.c).

The Python path has one thread and ignores the parameter; the kernel with one thread gives
the Python path's bits (test_compiled.py, test_piles.py), so both thread counts do.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hecker_dynamics import Simulation, _kernel
from hecker_dynamics.bench.pyramid import pyramid
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.scene.fingerprint import scene_fingerprint

needs_kernel = pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not "
                                  "built or HECKER_DYNAMICS_KERNEL=0")

#: Steps compared: 1.2 s at h = 4 ms, through the pile's settling (and, with sleeping on,
#: the 30-row pile's falling asleep).
STEPS = 300


def _crew(sim: Simulation) -> tuple[int, bool]:
    """The kernel's threads and whether its second one was started."""
    return _kernel.threads(sim.model.contacts._kernel.kernel)


@needs_kernel
@pytest.mark.parametrize("sleep", [False, True], ids=["awake", "sleeping"])
@pytest.mark.parametrize("rows", [30, 50])
def test_two_threads_give_the_bits_of_one(rows, sleep):
    """Pyramids of 30 and 50 rows (465 and 1275 boxes, one island of about 900 and 2500
    blocks, above the crew's threshold) with threads 1 and 2, sleeping off and on: after
    every 25 steps positions and velocities are the same bits, and at the end so are the
    warm-start impulses, rest times and sleeping islands; only threads 2 started the
    second thread."""
    one = Simulation(dataclasses.replace(pyramid(rows, sleep=sleep), threads=1))
    two = Simulation(dataclasses.replace(pyramid(rows, sleep=sleep), threads=2))
    step = one.scene.step_ns
    for k in range(25, STEPS + 1, 25):
        one.advance_to(k * step)
        two.advance_to(k * step)
        assert np.array_equal(one.q, two.q) and np.array_equal(one.v, two.v), k
    assert one.model.contacts.export_state() == two.model.contacts.export_state()
    assert one.model.contacts.sleeping() == two.model.contacts.sleeping()
    assert _crew(one) == (1, False) and _crew(two) == (2, True)
    if sleep and rows == 30:
        assert one.model.contacts.sleeping(), "the 30-row pile should be asleep by 1.2 s"


@needs_kernel
def test_small_islands_keep_one_thread():
    """A 10-row pyramid's island (about 100 blocks) is below the crew's threshold: threads
    2 starts no second thread."""
    sim = Simulation(dataclasses.replace(pyramid(10), threads=2))
    sim.advance_to(10 * sim.scene.step_ns)
    assert _crew(sim) == (2, False)


def test_threads_leave_the_fingerprint_alone():
    """The thread count changes no bit, so recordings made with either replay with either."""
    scene = pyramid(3)
    assert scene.threads == 1
    assert (scene_fingerprint(dataclasses.replace(scene, threads=2))
            == scene_fingerprint(scene))
