"""Which pairs collide, kept per class of bodies, against the pair-by-pair definition.

The definition: every pair of a collision group collides with the group's material, a
later group's overriding an earlier one's, and the ``apart`` pairs not at all. The
classes must give exactly that for every pair, and the kernel must look up the same
materials as Python does (its steps then have Python's bits).
"""
from __future__ import annotations

import random

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics import Simulation
from hecker_dynamics.bench.pyramid import pyramid
from hecker_dynamics.contact.materials import PairMaterials
from hecker_dynamics.dynamics import kernel

SECOND = 1_000_000_000


def _pairwise(groups, apart):
    """The definition, pair by pair."""
    pairs = {}
    for members, e, mu in groups:
        members = sorted(set(members))
        for n, i in enumerate(members):
            for j in members[n + 1:]:
                pairs[(i, j)] = (e, mu)
    for pair in apart:
        pairs.pop(pair, None)
    return pairs


@pytest.mark.parametrize("seed", range(40))
def test_classes_give_every_pair_the_definitions_material(seed):
    rng = random.Random(seed)
    bodies = rng.randint(2, 14)
    groups = [(rng.sample(range(bodies), rng.randint(2, bodies)), rng.random(), rng.random())
              for _ in range(rng.randint(0, 4))]
    apart = [tuple(sorted(rng.sample(range(bodies), 2))) for _ in range(rng.randint(0, 4))]
    expected = _pairwise(groups, apart)
    materials = PairMaterials(groups, bodies, apart)
    for i in range(bodies):
        for j in range(i + 1, bodies):
            assert materials.get(i, j) == expected.get((i, j)), (i, j)
    assert materials.colliding() == sorted({i for pair in expected for i in pair})
    assert materials.apart == sorted(set(apart) & {(i, j) for i, j in _pairwise(groups, ())})


def test_one_group_is_one_class_however_many_bodies():
    """The pyramid of 30 rows: 465 boxes, 107,880 colliding pairs, one class."""
    contacts = Simulation(pyramid(30)).model.contacts
    assert contacts is not None
    assert contacts.pairs.table == [[0]] and len(contacts.colliding) == 465
    assert contacts.pairs.get(0, 464) == contacts.pairs.materials[0]


@pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not built or "
                    "HECKER_DYNAMICS_KERNEL=0")
def test_kernel_looks_up_the_materials_python_does():
    """Four boxes, two of them side by side and pinned (so apart), two dropped on them,
    in two groups of different friction and bounce with one
    box in both: 1 s in the kernel and in Python give
    the same bits, and swapping the groups' materials changes them."""
    def scene(first, second):
        return make_scene({
            "integrator": "semi_implicit_euler",
            "bodies": {name: {"shape": "box", "size": [0.5, 0.3], "mass": 1.0,
                              "position": [x, y], "angle": angle}
                       for name, x, y, angle in (("a", 0.0, 0.2, 0.0), ("b", 0.5, 0.2, 0.0),
                                                 ("c", -0.2, 1.0, -0.2), ("d", 0.1, 1.4, 0.1))},
            "forces": {"g": {"type": "gravity"}},
            "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}},
            "collisions": {"low": {"bodies": ["a", "b", "c"], **first},
                           "high": {"bodies": ["c", "d"], **second}},
            "joints": {"pin": {"type": "revolute", "body_a": "a", "point_a": [0.25, 0.0],
                               "body_b": "b", "point_b": [-0.25, 0.0]}}})
    slippery, sticky = {"friction": 0.1, "restitution": 0.6}, {"friction": 0.9, "restitution": 0.0}
    runs = []
    for first, second in ((slippery, sticky), (sticky, slippery)):
        fast, slow = Simulation(scene(first, second)), Simulation(scene(first, second))
        slow.model.use_python()
        assert fast.model.contacts.compiled and fast.model.contacts.pairs.apart == [(0, 1)]
        fast.advance_to(SECOND)
        slow.advance_to(SECOND)
        assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
        runs.append(fast.q.copy())
    assert not np.array_equal(runs[0], runs[1])
