"""The contact pass in the compiled kernel against the Python pass, and its saved state.

The kernel repeats solver.py (and its parts detect, warm, islands, solve, sleep) and
collision.py operation for operation, so the two give the same bits: positions, velocities
and the warm-start impulses, compared exactly. The state a ContactPass carries from step
to step is its warm-start impulses; a simulation given the positions, velocities and that
state continues bit for bit.
"""
from __future__ import annotations

import numpy as np
import pytest
from scene_builders import make_scene

from hecker_dynamics import Simulation
from hecker_dynamics.bench.pyramid import BOX, ball_box, pyramid
from hecker_dynamics.contact import detect, islands, sleep, solve, warm
from hecker_dynamics.dynamics import kernel
from hecker_dynamics.scene.load import load_scene

SECOND = 1_000_000_000

needs_kernel = pytest.mark.skipif(not kernel.enabled(), reason="the compiled kernel is not "
                                  "built or HECKER_DYNAMICS_KERNEL=0")


def _scene(name):
    if name == "balls":  # small islands of one-point contacts, with walls and without
        return ball_box(grid=4)
    if name == "pile":  # 36 blocks, one island below WIDE_UNITS, that settles for a while
        return pyramid(6)
    return pyramid(4) if name == "pyramid" else load_scene(name)


@needs_kernel
def test_kernel_has_the_solver_constants():
    k = kernel._kernel
    assert (k.MAX_ITERATIONS, k.MIN_ITERATIONS, k.WORK, k.SETTLE, k.POSITION_ITERATIONS,
            k.MAX_CONTACT_SUBSTEPS) == \
        (solve.MAX_ITERATIONS, solve.MIN_ITERATIONS, solve.WORK, solve.SETTLE,
         solve.POSITION_ITERATIONS, detect.MAX_SUBSTEPS)
    assert (k.CONVERGED, k.MARGIN, k.MATCH, k.SLOP, k.CORRECTION, k.MAX_CORRECTION,
            k.MAX_CONDITION) == \
        (solve.CONVERGED, detect.MARGIN, warm.MATCH, solve.SLOP, solve.CORRECTION,
         solve.MAX_CORRECTION, islands.MAX_CONDITION)
    assert (k.SLEEP_SPEED, k.TIME_TO_SLEEP) == (sleep.SLEEP_SPEED, sleep.TIME_TO_SLEEP)
    assert k.FRICTION_CARRY == warm.FRICTION_CARRY
    assert (k.WIDE_UNITS, k.COLOURS) == (islands.WIDE_UNITS, islands.COLOURS)


@needs_kernel
@pytest.mark.parametrize("name", ["pyramid", "pile", "balls", "seesaw", "door", "car_flip"])
def test_kernel_steps_contact_scenes_with_the_bits_of_python(name):
    """1 s of each scene (2.5 s of the pyramids settling): whole steps in the kernel and
    steps in Python with the Python contact pass give identical states and impulses. The
    kernel sweeps the small islands of the pyramids and of the balls in another order than
    Python (solve.c: hd_level_order), one that must give the same bits, and while the pile
    of 6 rows settles (all of its passes a step) it solves its blocks a level at a time in
    SIMD lanes (src/kernel/wide.h: HD_LEVEL_UNITS, HD_LEVEL_PASSES), one by one again once
    it has settled."""
    scene = _scene(name)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast._compiled is not None and fast.model.contacts.compiled
    assert not slow.model.contacts.compiled
    until = 2_500_000_000 if name in ("pyramid", "pile") else 1_000_000_000
    fast.advance_to(until)
    slow.advance_to(until)
    assert fast.steps == slow.steps
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    state = fast.model.contacts.export_state()
    assert state, "the scene has contacts at the end"
    assert state == slow.model.contacts.export_state()


@needs_kernel
def test_kernel_solves_a_large_pyramid_with_the_bits_of_python():
    """A pyramid of 16 rows (136 boxes, more than WORK / MIN_ITERATIONS blocks and
    contacts, so every step takes the minimum of passes rather than converging) for 0.2 s:
    kernel and Python give identical states and impulses."""
    scene = pyramid(16)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    fast.advance_to(200_000_000)
    slow.advance_to(200_000_000)
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    state = fast.model.contacts.export_state()
    assert state == slow.model.contacts.export_state()
    contacts = sum(len(remembered) for _, remembered in state)
    assert solve.passes(contacts // 2) == solve.MIN_ITERATIONS  # at most 2 per manifold


@needs_kernel
def test_kernel_sweeps_a_tall_pyramid_in_bands_with_the_bits_of_python():
    """A pyramid of 22 rows (253 boxes) is tall enough that the kernel's broad phase sweeps
    its boxes band by band in y (src/kernel/contact.c: plan_bands takes bands at 64 boxes
    and room for 16 bands as tall as a box's extent with margins), where the Python pass
    sweeps them all in x: for 0.2 s both give identical states and impulses, so the bands
    find the same pairs in the same order."""
    scene = pyramid(22)
    fast, slow = Simulation(scene), Simulation(scene)
    reach, margin = BOX / 2 ** 0.5, detect.MARGIN  # a box's reach: half its diagonal
    extent = 2 * reach + 2 * margin  # a band: a box's extent in y with both margins
    heights = fast.q[:, 1]
    room = (heights.max() - heights.min() + 2 * reach + margin + extent) / extent
    assert len(fast.q) >= 64 and room >= 16, room
    slow.model.use_python()
    fast.advance_to(200_000_000)
    slow.advance_to(200_000_000)
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    assert fast.model.contacts.export_state() == slow.model.contacts.export_state()


@needs_kernel
@pytest.mark.parametrize("rows", [4, 8])
def test_kernel_sleeps_a_pyramid_with_the_bits_of_python(rows):
    """Pyramids of 4 and 8 rows with sleeping on, 3 s: they fall asleep (at the same step)
    and kernel and Python give identical states, impulses, rest times and islands at every
    publish."""
    scene = pyramid(rows, sleep=True)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    for k in range(1, 151):
        fast.advance_to(k * 20_000_000)
        slow.advance_to(k * 20_000_000)
        assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
        assert fast.model.contacts.sleeping() == slow.model.contacts.sleeping()
    assert fast.model.contacts.sleeping() == list(range(rows * (rows + 1) // 2))
    assert fast.model.contacts.export_state() == slow.model.contacts.export_state()


@needs_kernel
def test_kernel_sleeps_a_small_ball_box_as_python():
    """The ball box with 16 balls and sleeping on, 4 s: circles' distances are taken as
    the square root of the sum of squares on both paths (C's hypot and CPython's
    math.hypot round apart now and then: before, the paths differed by 1.4e-17 m from
    step 153 on), so the states are the same bits, and the same balls sleep."""
    scene = ball_box(sleep=True, grid=4)
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    fast.advance_to(4 * SECOND)
    slow.advance_to(4 * SECOND)
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    asleep = fast.model.contacts.sleeping()
    assert asleep == slow.model.contacts.sleeping() and len(asleep) >= 8


@needs_kernel
def test_kernel_leaves_joined_bodies_apart():
    """Two overlapping boxes pinned together in one collision group (joined bodies do not
    collide by default) under gravity on a floor: the kernel's contact pass leaves the pair
    alone as the Python pass does, so the two give the same bits over 1 s (a kernel pass
    that collided them would push the 0.1 m overlap apart)."""
    scene = make_scene({
        "integrator": "semi_implicit_euler",
        "bodies": {"a": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0,
                         "position": [0.0, 0.5]},
                   "b": {"shape": "box", "size": [1.0, 0.2], "mass": 1.0,
                         "position": [0.9, 0.5]}},
        "forces": {"g": {"type": "gravity"}},
        "walls": {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}},
        "collisions": {"all": {"bodies": ["a", "b"]}},
        "joints": {"pin": {"type": "revolute", "body_a": "a", "point_a": [0.45, 0.0],
                           "body_b": "b", "point_b": [-0.45, 0.0]}}})
    fast, slow = Simulation(scene), Simulation(scene)
    slow.model.use_python()
    assert fast.model.contacts.compiled and not fast.model.contacts.colliding
    fast.advance_to(SECOND)
    slow.advance_to(SECOND)
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
    assert fast.model.contacts.export_state(), "the boxes rest on the floor"


@needs_kernel
def test_kernel_sleep_state_is_set_whole_or_not_at_all():
    """The contact binding's sleep() sets enabled, calm, rested and island together, by
    keyword: given some of them it is refused, changing nothing; given all four, it reads
    back what it was given; warm() and threads() take their settings by keyword too, and
    a keyword unknown, missing or given twice is refused by name."""
    from hecker_dynamics import _kernel

    sim = Simulation(pyramid(4, sleep=True))
    sim.advance_to(SECOND)  # some boxes at rest a while
    capsule = sim.model.contacts._kernel.kernel
    before = _kernel.sleep(capsule)
    bodies = len(before[0])
    calm, island = np.ones(bodies, dtype=np.int64), np.full(bodies, -1, dtype=np.int64)
    rested = np.arange(bodies, dtype=np.float64) * 0.125
    with pytest.raises(TypeError, match="together"):
        _kernel.sleep(capsule, enabled=True, calm=calm, rested=rested)
    with pytest.raises(TypeError):  # the settings are keywords only
        _kernel.sleep(capsule, True, calm, rested, island)
    assert _kernel.sleep(capsule) == before
    assert _kernel.sleep(capsule, enabled=True, calm=calm, rested=rested,
                         island=island) == (rested.tolist(), island.tolist())
    impulses = _kernel.warm(capsule)
    assert impulses and _kernel.warm(capsule, impulses=impulses[:3]) == impulses[:3]
    with pytest.raises(ValueError, match="1 or 2, not 3"):
        _kernel.threads(capsule, count=3)
    assert _kernel.threads(capsule, count=1) == (1, False)
    with pytest.raises(TypeError, match="unexpected keyword argument 'impulse'"):
        _kernel.warm(capsule, impulse=[])
    q, v = sim.q.copy(), sim.v.copy()
    with pytest.raises(TypeError, match="missing required argument 'h'"):
        _kernel.resolve(capsule, q1=q, v1=v, q0=q, v0=v)
    with pytest.raises(TypeError, match="multiple values for argument 'q1'"):
        _kernel.resolve(capsule, q, v, q, v, 0.004, q1=q)


@needs_kernel
def test_kernel_recalls_restored_and_reordered_warm_starts_as_python():
    """A pyramid of 12 rows restored mid-fall from its exported state: the warm starts
    come back sorted by key, not in the order detection finds the contacts (walls first,
    then the sweep's order, which also swaps boxes of one column from step to step), so the
    kernel finds most of them away from where the last key's ended, some past its near
    search, through its table. Kernel and Python give the same bits at every step."""
    scene = pyramid(12)
    original = Simulation(scene)
    original.advance_to(300_000_000)
    saved = {"q": original.q.tolist(), "v": original.v.tolist(),
             "contacts": original.model.contacts.export_state()}
    assert sum(len(contacts) for _, contacts in saved["contacts"]) > 200
    sims = [Simulation(scene), Simulation(scene)]
    sims[1].model.use_python()
    for sim in sims:
        sim.q, sim.v = np.array(saved["q"]), np.array(saved["v"])
        sim.model.contacts.import_state(saved["contacts"])
    fast, slow = sims
    for _ in range(20):
        fast.step()
        slow.step()
        assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)
        assert fast.model.contacts.export_state() == slow.model.contacts.export_state()


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("name", ["pyramid", "seesaw"])
def test_restored_simulation_continues_bit_for_bit(name, compiled):
    """Run 0.6 s, hand (q, v) and the contact (and joint) passes' exported state (through
    plain lists, as a checkpoint would) to a new simulation, and step both 0.4 s on: the same bits.
    Without the warm starts (the contacts', and the joints' impulses, from which the contact
    solve starts the joint rows it sweeps with the contacts) the new one differs (warm
    starting matters), so the test can fail."""
    if compiled and not kernel.enabled():
        pytest.skip("the compiled kernel is not built or HECKER_DYNAMICS_KERNEL=0")
    scene = _scene(name)
    original = Simulation(scene)
    if not compiled:
        original.model.use_python()
    original.advance_to(600_000_000)
    joints = original.model.joints  # the seesaw's pin carries its own state
    saved = {"q": original.q.tolist(), "v": original.v.tolist(),
             "contacts": original.model.contacts.export_state(),
             "joints": None if joints is None else joints.export_state()}
    assert all(type(k) is int for key, _ in saved["contacts"] for k in key)
    assert all(type(x) is float for _, contacts in saved["contacts"] for contact in contacts
               for x in contact)

    def restored(with_contacts):
        sim = Simulation(scene)
        if not compiled:
            sim.model.use_python()
        sim.q, sim.v = np.array(saved["q"]), np.array(saved["v"])
        if saved["joints"] is not None:
            cold = {"warm": [], "extra": [], "newton": None}
            sim.model.joints.import_state(saved["joints"] if with_contacts
                                          else {**saved["joints"], **cold})
        if with_contacts:
            sim.model.contacts.import_state(saved["contacts"])
        for _ in range(100):
            sim.step()
        return sim

    for _ in range(100):
        original.step()
    again, cold = restored(True), restored(False)
    assert np.array_equal(again.q, original.q) and np.array_equal(again.v, original.v)
    assert again.model.contacts.export_state() == original.model.contacts.export_state()
    assert not np.array_equal(cold.q, original.q)


def test_colours_share_no_body_and_come_last_first_after_the_overflow():
    """A body touched by 70 units (more than COLOURS) and a ring of units between walls
    and pairs: every colour's units share no body but the walls', each unit appears once,
    each colour keeps the island's order, the colours come last first (body 0's k-th unit
    has colour k), and the 6 units of body 0 that fit no colour, the overflow, come first
    in their order."""
    from types import SimpleNamespace

    spokes = [SimpleNamespace(a=0, b=k) for k in range(1, 71)]
    ring = [SimpleNamespace(a=-1 if k % 3 == 0 else k, b=k + 1) for k in range(71, 140)]
    island = [unit for pair in zip(spokes, ring) for unit in pair] + spokes[len(ring):]
    order = islands.coloured(island)
    assert sorted(map(id, order)) == sorted(map(id, island))
    assert order[:6] == spokes[-6:]
    groups, used = [[]], set()
    for unit in order[6:]:  # split where a unit shares a body with its colour
        bodies = {unit.a, unit.b} - {-1}
        if bodies & used or (groups[-1] and island.index(unit) < island.index(groups[-1][-1])):
            groups.append([])
            used = set()
        groups[-1].append(unit)
        used |= bodies
    assert len(groups) == islands.COLOURS
    assert [next(unit for unit in group if unit.a == 0) for group in groups] == \
        spokes[islands.COLOURS - 1::-1]
    assert all(sum(unit.a == 0 for unit in group) == 1 for group in groups)
