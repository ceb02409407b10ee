"""Walls: impulses at the contact point (with rotation), restitution, resting contact, friction.

References: the collision impulse j = -(1+e) v_rel.n / K, K = 1/M + (perp(r).n)^2 / I, from
the article series ("Physics, Part 2: Angular Effects" cites it for its sample program),
and Coulomb friction's closed forms for a block on a floor or an incline.

All scenes here use semi-implicit Euler and no force other than those declared, so between
contacts the free motion is exact in floating point (zero acceleration: v stays bit for bit,
q += h v), and every difference from the closed forms comes from the contact pass alone.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import box_body, box_inertia, make_scene, rotation

import hecker_dynamics as hd
from hecker_dynamics import Simulation

G = 9.81
H_STEP = 0.001
W, HGT, MASS = 1.0, 0.5, 2.0
CORNERS = np.array([[-W, -HGT], [W, -HGT], [W, HGT], [-W, HGT]]) / 2


def _sim(bodies, walls, forces=None, **top):
    params = {"step": H_STEP, "integrator": "semi_implicit_euler", "bodies": bodies,
              "walls": walls, **top}
    if forces:
        params["forces"] = forces
    return Simulation(make_scene(params))


def _kinetic(sim):
    m = sim.model
    return 0.5 * float(np.sum(m.mass * (sim.v[:, 0] ** 2 + sim.v[:, 1] ** 2))
                       + np.sum(m.inertia * sim.v[:, 2] ** 2))


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.hypot(*v)


# ------------------------------------------------------------------ single-point impacts

@pytest.mark.parametrize("normal", [(0.0, 1.0), (1.0, 2.0), (-1.0, 0.3)])
def test_elastic_corner_impact_conserves_kinetic_energy(normal):
    """e = 1, no gravity, spinning box hitting a wall on one corner: KE is conserved.

    Tolerance 1e-13 relative: free flight changes nothing (zero acceleration), and the
    impulse is a handful of flops on O(1) numbers, so only rounding (~1e-16 each) remains.
    """
    n = _unit(normal)
    start = 1.2 * n  # 1.2 m from the wall along its normal: clear of it
    velocity = -2.0 * n + 0.3 * np.array([-n[1], n[0]])
    sim = _sim({"b": box_body((W, HGT), MASS, position=start.tolist(), angle=0.4,
                              velocity=velocity.tolist(), angular_velocity=1.5)},
               {"wall": {"point": [0.0, 0.0], "normal": list(normal), "restitution": 1.0}})
    before = _kinetic(sim)
    impacts = 0
    for _ in range(2000):
        v = sim.v.copy()
        sim.step()
        impacts += not np.array_equal(v, sim.v)
    assert impacts >= 1, "the box never reached the wall: the test proves nothing"
    assert sim.v[0, :2] @ n > 0.0, "the box must move away from the wall after the bounce"
    assert abs(sim.v[0, 2] - 1.5) > 1e-3, "an off-center impact must change the spin"
    assert _kinetic(sim) == pytest.approx(before, rel=1e-13)


def _step_to_single_contact(sim, n, offset=0.0):
    """Step until the next step will put exactly one corner through the wall; return the
    predicted post-integration state (q + h v, v: exact for force-free semi-implicit Euler)."""
    h = sim.step_seconds
    for _ in range(5000):
        q1 = sim.q + h * sim.v
        R = rotation(q1[0, 2])
        local = CORNERS - sim.model.cm_local[0]
        corners = q1[0, :2] + local @ R.T
        depth = offset - corners @ n
        if (depth > 0).any():
            assert (depth > 0).sum() == 1, "need a single-point contact for the formula"
            r = corners[np.argmax(depth)] - q1[0, :2]
            return q1, sim.v.copy(), r
        sim.step()
    raise AssertionError("no contact")


@pytest.mark.parametrize("e", [0.0, 0.3, 0.75])
@pytest.mark.parametrize("normal", [(0.0, 1.0), (1.0, 1.0)])
def test_inelastic_corner_impact_matches_impulse_formula(e, normal):
    """One corner hits: the new velocity and spin are v + j n / M and w + j perp(r).n / I
    with j = -(1+e) v_n / K, and the KE lost is (1 - e^2) v_n^2 / (2 K).

    The expected values are computed here from the closed form (not from walls.py);
    tolerance 1e-12 relative: a few flops of rounding on O(1) numbers.
    """
    n = _unit(normal)
    sim = _sim({"b": box_body((W, HGT), MASS, position=(1.0 * n).tolist(), angle=0.3,
                              velocity=(-3.0 * n + 0.5 * np.array([-n[1], n[0]])).tolist(),
                              angular_velocity=-2.0)},
               {"wall": {"point": [0.0, 0.0], "normal": list(normal), "restitution": e}})
    q1, v1, r = _step_to_single_contact(sim, n)
    M, inertia = MASS, box_inertia(MASS, W, HGT)
    assert sim.model.inertia[0] == pytest.approx(inertia, rel=1e-14)
    perp_r = np.array([-r[1], r[0]])
    vn = float((v1[0, :2] + v1[0, 2] * perp_r) @ n)
    assert vn < -0.5, "the corner must approach faster than the restitution threshold"
    K = 1.0 / M + float(perp_r @ n) ** 2 / inertia
    j = -(1.0 + e) * vn / K
    expected_v = v1[0, :2] + j * n / M
    expected_w = v1[0, 2] + j * float(perp_r @ n) / inertia
    ke_before = _kinetic(sim)
    sim.step()
    assert sim.v[0, :2] == pytest.approx(expected_v, rel=1e-12, abs=1e-12)
    assert sim.v[0, 2] == pytest.approx(expected_w, rel=1e-12, abs=1e-12)
    loss = (1.0 - e * e) * vn * vn / (2.0 * K)
    assert ke_before - _kinetic(sim) == pytest.approx(loss, rel=1e-11, abs=1e-12)
    # the contact point now leaves at -e times its approach speed
    vn_after = float((sim.v[0, :2] + sim.v[0, 2] * perp_r) @ n)
    assert vn_after == pytest.approx(-e * vn, rel=1e-12, abs=1e-12)


def test_disc_hits_wall_without_changing_spin():
    """A frictionless disc's contact arm is -R n, so perp(r).n = 0: the spin is untouched
    (bit for bit) and the normal velocity reverses with factor e (rel 1e-13)."""
    e = 0.6
    sim = _sim({"d": {"shape": "circle", "radius": 0.3, "mass": 1.0, "position": [0.0, 1.0],
                      "velocity": [0.7, -2.0], "angular_velocity": 5.0}},
               {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": e}})
    sim.advance_to(600_000_000)
    assert sim.v[0, 2] == 5.0
    assert sim.v[0, 0] == 0.7
    assert sim.v[0, 1] == pytest.approx(2.0 * e, rel=1e-13)


def _bouncing_ball(step, e, drop, radius=0.1, bounces=4):
    """A ball dropped from ``drop`` (its bottom above the floor) with restitution e, no
    friction, under gravity (semi-implicit Euler at ``step``): the times of its first
    bounces (the step its vertical velocity turns upwards) and the heights of its bottom at
    the apexes after them."""
    sim = _sim({"ball": {"shape": "circle", "radius": radius, "mass": 1.0,
                         "position": [0.0, drop + radius]}},
               {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": e,
                          "friction": 0.0}},
               {"g": {"type": "gravity"}}, step=step)
    heights, velocities = [], []
    for _ in range(round(4.0 / step)):
        sim.step()
        heights.append(sim.q[0, 1] - radius)
        velocities.append(sim.v[0, 1])
    y, v = np.array(heights), np.array(velocities)
    turns = np.flatnonzero((v[:-1] < 0.0) & (v[1:] > 0.0)) + 1
    assert len(turns) > bounces
    apexes = [y[a:b].max() for a, b in zip(turns[:bounces], turns[1:bounces + 1])]
    return (turns[:bounces] + 1) * step, np.array(apexes)


def test_bouncing_ball_matches_the_closed_form_to_first_order():
    """A ball dropped from 1 m with e = 0.8: it hits at t_1 = sqrt(2 d / g) with speed
    v_1 = sqrt(2 g d), then at t_(k+1) = t_k + 2 e^k v_1 / g, and rises to e^(2k) d after the
    k-th bounce (free flight between frictionless bounces that keep e of the speed).

    The contact pass works at the end of a step, so each bounce is off by O(h): it keeps e
    of the speed the ball had when the step began, up to g h short of the impact speed, so
    after k bounces the speed is short by up to e g h (1 - e^k) / (1 - e) <= 23 h m/s
    (k <= 4, h in s); that shifts an apex by up to v_1 23 h / g = 10 h m and a flight by up
    to 2 x 23 h / g = 4.7 h s; the bounce also starts up to v_1 h (4.4 h m, h s) from the
    surface, and semi-implicit Euler's apex is off by v h / 2 (2.2 h m). So each apex within
    20 h m and each bounce time within 20 h s (three flights of 5.7 h and the first impact
    within its step). And first order: the largest apex error falls at least 4 times from
    h = 2 ms to 0.25 ms (8 for first order, 1 if it did not converge)."""
    e, drop = 0.8, 1.0
    v1 = math.sqrt(2.0 * G * drop)
    times = [math.sqrt(2.0 * drop / G)]
    for k in range(1, 4):
        times.append(times[-1] + 2.0 * e ** k * v1 / G)
    apexes = [e ** (2 * k) * drop for k in range(1, 5)]
    errors = {}
    for step in (0.002, 0.00025):
        t, y = _bouncing_ball(step, e, drop)
        assert np.abs(t - times).max() <= 20 * step
        errors[step] = np.abs(y - apexes).max()
        assert errors[step] <= 20 * step
    assert errors[0.00025] <= errors[0.002] / 4


def test_wall_applies_only_to_listed_bodies():
    """A body not in the wall's list passes through it; the listed one bounces."""
    bodies = {name: box_body((0.2, 0.2), 1.0, position=[x, 0.5], velocity=[0.0, -2.0])
              for name, x in (("ghost", -1.0), ("solid", 1.0))}
    sim = _sim(bodies, {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                                  "restitution": 1.0, "bodies": ["solid"]}})
    sim.advance_to(1_000_000_000)
    ghost, solid = sim.model.index["ghost"], sim.model.index["solid"]
    assert sim.v[ghost, 1] == -2.0 and sim.q[ghost, 1] < -1.0
    assert sim.v[solid, 1] == pytest.approx(2.0, rel=1e-13)
    assert list(sim.model.can_turn()) == [name == "solid" for name in sim.model.names]


# ------------------------------------------------------------------ resting contact

def _drop(restitution, seconds=10.0):
    sim = _sim({"b": box_body((W, HGT), MASS, position=[0.0, 1.0])},
               {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0],
                          "restitution": restitution, "friction": 0.3}},
               forces={"g": {"type": "gravity"}})
    steps = round(seconds / H_STEP)
    y, w, energy = np.empty(steps), np.empty(steps), np.empty(steps)
    for k in range(steps):
        sim.step()
        y[k], w[k] = sim.q[0, 1], sim.v[0, 2]
        energy[k] = sim.model.energy(sim.q, sim.v)
    return sim, y, w, energy


# Rest-height bound. A contact solver may leave a resting overlap up to its slop (1e-4 m in
# contacts.py: overlap it deliberately keeps so resting contacts persist without jitter)
# plus what one step at the restitution threshold travels (4 g h * h ~ 4e-5 m); 2e-4 m
# covers both. Sinking fails it fast: with no push-out the box would sink g h^2 per step,
# 2e-4 m in 20 steps, and ~0.1 m over the 10 s checked here.
REST_TOLERANCE = 2e-4


def test_box_dropped_flat_rests_at_half_height_and_never_sinks():
    """Dropped flat from 0.75 m (e = 0.5), the box bounces, comes to rest with its CM at
    HGT/2 and level, and stays there for the remaining 7 s of the 10 s run."""
    sim, y, w, _ = _drop(0.5)
    settled = slice(3000, None)  # bounces end after ~1.2 s (v_k = 3.8 m/s * 0.5^k < 4 g h)
    assert np.all(np.abs(y[settled] - HGT / 2) <= REST_TOLERANCE)
    assert y[settled].max() - y[settled].min() <= 1e-9, "a resting box must not move"
    assert np.all(np.abs(w[settled]) <= 1e-9), "at rest it must not spin"
    # level to within the slop across its width: both corners within the slop of the floor
    assert abs(sim.q[0, 2]) <= 2 * REST_TOLERANCE / W
    assert np.abs(sim.v[0]).max() <= 1e-9


def test_elastic_box_dropped_flat_never_sinks():
    """e = 1: it keeps bouncing, but never goes through the floor by more than the rest
    tolerance, and it keeps bouncing (it is not damped to rest by the contact pass).

    (Its energy is not asserted: the bounce reverses the velocity after this step's
    gravity was added, an O(h) gain of about (1 + e) m g h |v| per bounce, ~5% over these
    10 s at h = 1 ms; see the report.)"""
    sim, y, _, _ = _drop(1.0)
    assert y.min() >= HGT / 2 - REST_TOLERANCE
    assert y[-2000:].max() > HGT / 2 + 0.5, "an elastic box must keep bouncing"


def test_resting_box_energy_never_increases():
    """After it has come to rest, the total energy never rises from one step to the next.

    At rest each step loses m g^2 h^2 / 2 in the integrator and the contact pass restores
    exactly the height, so energy is constant up to rounding of m g y ~ 5 J (1e-15
    relative): 1e-12 J per step and 1e-11 J over 7 s leave room for that, and any real
    energy gain from jitter (at least ~m g * g h^2 ~ 2e-4 J) would fail.
    """
    _, _, _, energy = _drop(0.5)
    rest = energy[3000:]
    assert np.diff(rest).max() <= 1e-12
    assert rest.max() - rest[0] <= 1e-11
    # and over the whole drop with e = 0.5 the energy never rose by more than rounding
    assert np.diff(energy).max() <= 1e-12


def test_box_placed_on_floor_with_elastic_wall_stays_put():
    """e = 1 but the per-step approach g h is below the threshold: no bouncing in place."""
    sim = _sim({"b": box_body((W, HGT), MASS, position=[0.0, HGT / 2])},
               {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 1.0}},
               forces={"g": {"type": "gravity"}})
    e0 = sim.model.energy(sim.q, sim.v)
    sim.advance_to(2_000_000_000)
    assert abs(sim.q[0, 1] - HGT / 2) <= 1e-12
    assert np.abs(sim.v[0]).max() <= 1e-12
    assert sim.model.energy(sim.q, sim.v) <= e0 + 1e-12


# ------------------------------------------------------------------ friction

def test_sliding_box_decelerates_at_mu_g():
    """A box sliding on a floor with Coulomb friction mu: v(t) = v0 - mu g t, then stops.

    Each step the floor's normal impulse cancels the g h gained, and friction takes
    mu times it: exactly mu g h per step. Tolerance 1e-9 m/s: the sequential-impulse
    solver stops at 1e-14 relative per step (walls.CONVERGED), i.e. < 1e-11 after 500 steps.
    """
    mu, v0 = 0.3, 2.0
    sim = _sim({"b": box_body((W, HGT), MASS, position=[0.0, HGT / 2], velocity=[v0, 0.0])},
               {"floor": {"point": [0.0, 0.0], "normal": [0.0, 1.0], "restitution": 0.0,
                          "friction": mu}},
               forces={"g": {"type": "gravity"}})
    for t_ms in (100, 300, 500):
        sim.advance_to(t_ms * 1_000_000)
        assert sim.v[0, 0] == pytest.approx(v0 - mu * G * t_ms / 1000, abs=1e-9)
        assert abs(sim.v[0, 1]) <= 1e-12 and abs(sim.v[0, 2]) <= 1e-9
    stop = v0 / (mu * G)  # 0.68 s
    sim.advance_to(round((stop + 0.5) * 1e9))
    assert abs(sim.v[0, 0]) <= 1e-12, "friction must hold the box once it stops"
    # distance: the continuous v0^2 / (2 mu g) within one step of travel at most
    assert sim.q[0, 0] == pytest.approx(v0 ** 2 / (2 * mu * G), abs=v0 * H_STEP)


def _slope(angle_deg, mu):
    a = math.radians(angle_deg)
    n = np.array([-math.sin(a), math.cos(a)])
    sim = _sim({"b": box_body((W, HGT), MASS, position=(HGT / 2 * n).tolist(), angle=a)},
               {"slope": {"point": [0.0, 0.0], "normal": n.tolist(), "restitution": 0.0,
                          "friction": mu}},
               forces={"g": {"type": "gravity"}})
    return sim, a, np.array([math.cos(a), math.sin(a)])


def test_box_sticks_on_incline_below_friction_angle():
    """tan(a) < mu: friction holds the box (velocity and spin ~0, stays flat on the slope).

    1e-12: each step's gravity gain (g h ~ 0.01 m/s) is cancelled by the solver to 1e-14
    relative.
    """
    mu = 0.5  # friction angle 26.6 degrees
    sim, a, _ = _slope(20.0, mu)
    for t_ms in (200, 1000, 2000):
        sim.advance_to(t_ms * 1_000_000)
        assert np.abs(sim.v[0]).max() <= 1e-12
    assert sim.q[0, 2] == pytest.approx(a, abs=1e-12)


def test_box_stuck_on_incline_does_not_creep():
    """A box held by static friction must not move: its displacement along the slope over
    2 s must stay below 1e-6 m. A contact pass that lets the integrator move the body with
    its pre-impulse velocity (as the first walls.py did) creeps at g sin(a) h: 6.7 mm here."""
    sim, _, t_hat = _slope(20.0, 0.5)
    start = sim.q[0, :2].copy()
    sim.advance_to(2_000_000_000)
    assert abs(float((sim.q[0, :2] - start) @ t_hat)) <= 1e-6


@pytest.mark.parametrize("angle_deg", [30.0, 45.0])
def test_box_slides_on_incline_above_friction_angle(angle_deg):
    """tan(a) > mu: it slides down with acceleration g (sin a - mu cos a), per step exactly
    (same argument as on the flat floor), and does not turn. Tolerance 1e-9 m/s."""
    mu = 0.3
    sim, a, t_hat = _slope(angle_deg, mu)
    accel = G * (math.sin(a) - mu * math.cos(a))
    for t_ms in (250, 1000):
        sim.advance_to(t_ms * 1_000_000)
        v = sim.v[0, :2]
        assert float(v @ t_hat) == pytest.approx(-accel * t_ms / 1000, abs=1e-9)
        assert float(v @ np.array([-t_hat[1], t_hat[0]])) == pytest.approx(0.0, abs=1e-12)
        assert abs(sim.v[0, 2]) <= 1e-9


def test_single_shape_box_turned_by_its_body_angle_lies_flat_on_the_incline():
    """The plain ``shape: box`` form with the body's ``angle`` = slope angle sits flat on
    the slope and stays (before the scene fix it was turned twice and toppled ~0.35 rad)."""
    a = math.radians(20.0)
    n = np.array([-math.sin(a), math.cos(a)])
    sim = _sim({"b": {"shape": "box", "size": [W, HGT], "mass": MASS,
                      "position": (HGT / 2 * n).tolist(), "angle": a}},
               {"slope": {"point": [0.0, 0.0], "normal": n.tolist(), "restitution": 0.0,
                          "friction": 0.5}},
               forces={"g": {"type": "gravity"}})
    sim.advance_to(500_000_000)
    assert sim.q[0, 2] == pytest.approx(a, abs=1e-9)
    assert np.abs(sim.v[0]).max() <= 1e-12


@pytest.mark.parametrize("mode", ["walls only", "events", "collision group"])
def test_a_disc_faster_than_its_room_is_wide_stays_in_it_only_when_swept(mode):
    """A disc of radius 0.1 m at 5000 m/s between walls 2 m apart, h = 1 ms (5 m a step).
    Meeting only walls it is not split into sub-steps, and each bounce sends it back from
    where its step began: it reads x = -5 m, past the left wall, every other step (the
    limit docs/scenes.md states). With events located, or in a collision group (sub-steps
    of at most 0.1 m), it stays between the walls, its speed kept at e = 1."""
    world = hd.World(integrator="semi_implicit_euler", events=mode == "events")
    world.add_wall("left", point=(-1, 0), normal=(1, 0), restitution=1.0)
    world.add_wall("right", point=(1, 0), normal=(-1, 0), restitution=1.0)
    disc = world.add_body("disc", hd.Circle(0.1), mass=1.0, velocity=(5000.0, 0.0))
    if mode == "collision group":
        world.add_body("other", hd.Circle(0.1), mass=1.0, position=(0.0, 5.0))
        world.add_collision_group("pair")
    places = []
    for _ in range(8):
        world.step()
        places.append(disc.position[0])
        assert abs(disc.velocity[0]) == pytest.approx(5000.0, rel=1e-12)
    if mode == "walls only":
        assert places[0::2] == [-5.0] * 4
    else:
        assert all(-0.9 - 1e-9 <= x <= 0.9 + 1e-9 for x in places)


@pytest.mark.parametrize("method, reported", [
    ("semi_implicit_euler", 0.0), ("backward_euler", 0.0), ("explicit_euler", -G * 1e-3),
    ("velocity_verlet", -0.5 * G * 1e-3), ("rk4", -0.5 * G * 1e-3),
    ("dopri5", -0.5 * G * 1e-3), ("implicit_midpoint", -0.5 * G * 1e-3)])
def test_a_resting_box_keeps_its_place_and_reports_its_methods_velocity(method, reported):
    """A 2 kg box resting on a floor for 2 s at h = 1 ms keeps its height exactly under every
    method; what it reports as its velocity is the one the contact pass leaves at the
    step's end: zero where positions move with the whole step's change of velocity, g h / 2
    into the floor where they move with half of it (docs/scenes.md), the velocity that
    cancels gravity's half step, and g h where they move with none of it (explicit
    Euler). Rounding over 2000 steps: 1e-12 m/s."""
    world = hd.World(gravity=(0.0, -G), step=1e-3, integrator=method)
    world.add_wall("floor", point=(0, 0), normal=(0, 1), friction=0.5)
    box = world.add_body("box", hd.Box(1.0, 0.5), mass=2.0, position=(0, 0.25))
    world.advance(2.0)
    assert box.position == (0.0, 0.25)
    assert box.velocity[0] == 0.0
    assert box.velocity[1] == pytest.approx(reported, abs=1e-12)
