"""Narrow phase: contact points, normals and depths against hand-computed geometry.

Every function of :mod:`hecker_dynamics.contact.collision` returns ``(point, normal, depth)`` with
the normal from the first shape to the second, the depth positive for overlap, and the
point halfway between the two surfaces. The expected values below are worked out by hand
from the shapes' coordinates (see each docstring); the randomised test checks the same
rules against a brute-force separating-axis computation written here in numpy.

Tolerance: 1e-12 absolute on coordinates and depths of O(1). The functions do a handful of
flops per number (rotations, one projection, one halving), each rounding by ~1e-16; 1e-12
leaves room for that and for the cos/sin of the rotated cases, while any wrong feature
(wrong face, wrong vertex, a point not halved) is off by at least 1e-3 here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import box_body, make_scene, rotation

from hecker_dynamics import Simulation
from hecker_dynamics.contact.collision import (
    CirclePart,
    ConvexPolygon,
    PolygonPart,
    circle_circle,
    half_plane_circle,
    half_plane_polygon,
    polygon_circle,
    polygon_polygon,
)
from hecker_dynamics.contact.solver import MARGIN, _collide

TOL = 1e-12
SQ2 = math.sqrt(2.0)


def polygon(local, center=(0.0, 0.0), angle=0.0):
    """A convex polygon placed in the world: (vertices, normals) as lists of tuples."""
    poly = ConvexPolygon.from_vertices(np.asarray(local, dtype=float))
    R = rotation(angle)
    verts = poly.vertices @ R.T + np.asarray(center, dtype=float)
    normals = poly.normals @ R.T
    return [tuple(v) for v in verts.tolist()], [tuple(n) for n in normals.tolist()]


def box(center, w, h, angle=0.0):
    return polygon([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]],
                   center, angle)


def as_array(contacts):
    """Contacts sorted by point, as (points (k, 2), normals (k, 2), depths (k,))."""
    contacts = sorted(contacts, key=lambda c: (round(c[0][0], 9), round(c[0][1], 9)))
    return (np.array([c[0] for c in contacts]).reshape(-1, 2),
            np.array([c[1] for c in contacts]).reshape(-1, 2),
            np.array([c[2] for c in contacts]))


def check(contacts, points, normal, depths):
    """Assert a manifold: the points (any order), one shared normal, each point's depth."""
    got_p, got_n, got_d = as_array(contacts)
    want = sorted(zip(map(tuple, np.atleast_2d(points)), np.atleast_1d(depths)),
                  key=lambda c: (round(c[0][0], 9), round(c[0][1], 9)))
    assert len(contacts) == len(want), contacts
    np.testing.assert_allclose(got_p, [w[0] for w in want], rtol=0, atol=TOL)
    np.testing.assert_allclose(got_d, [w[1] for w in want], rtol=0, atol=TOL)
    np.testing.assert_allclose(got_n, np.tile(normal, (len(want), 1)), rtol=0, atol=TOL)


def swapped_agrees(forward, backward):
    """The reverse argument order gives the same points and depths and negated normals."""
    f_p, f_n, f_d = as_array(forward)
    b_p, b_n, b_d = as_array(backward)
    assert len(forward) == len(backward)
    np.testing.assert_allclose(b_p, f_p, rtol=0, atol=TOL)
    np.testing.assert_allclose(b_d, f_d, rtol=0, atol=TOL)
    np.testing.assert_allclose(b_n, -f_n, rtol=0, atol=TOL)


# ------------------------------------------------------------------ polygon - polygon

# A: the 2 x 1 box at the origin (top face y = 0.5, right face x = 1).
A = box((0.0, 0.0), 2.0, 1.0)


def test_face_on_face_gives_two_points_halfway_between_the_faces():
    """B (2 x 1) at (1, 0.95): its bottom face y = 0.45 is 0.05 below A's top face y = 0.5,
    and the faces overlap for x in [0, 1]. Two points at the ends of the overlap, halfway
    (y = 0.475), depth 0.05, normal +y (A to B)."""
    B = box((1.0, 0.95), 2.0, 1.0)
    forward = polygon_polygon(*A, *B, MARGIN)
    check(forward, [[0.0, 0.475], [1.0, 0.475]], (0.0, 1.0), [0.05, 0.05])
    swapped_agrees(forward, polygon_polygon(*B, *A, MARGIN))


def test_overhanging_box_is_clipped_at_the_reference_face_end():
    """B (0.4 x 0.4) at (0.9, 0.69) overhangs A's right end: its bottom face x in
    [0.7, 1.1], y = 0.49. Clipped by A's side plane x = 1: points x = 0.7 and 1.0 at
    y = 0.495, depth 0.01."""
    B = box((0.9, 0.69), 0.4, 0.4)
    forward = polygon_polygon(*A, *B, MARGIN)
    check(forward, [[0.7, 0.495], [1.0, 0.495]], (0.0, 1.0), [0.01, 0.01])
    swapped_agrees(forward, polygon_polygon(*B, *A, MARGIN))


def test_corner_into_face_gives_one_point():
    """A unit box turned 45 degrees, its lowest corner at (0.3, 0.48): 0.02 into A's top
    face. One point, halfway: (0.3, 0.49), depth 0.02, normal +y."""
    B = box((0.3, 0.48 + SQ2 / 2), 1.0, 1.0, math.pi / 4)
    forward = polygon_polygon(*A, *B, MARGIN)
    check(forward, [[0.3, 0.49]], (0.0, 1.0), [0.02])
    swapped_agrees(forward, polygon_polygon(*B, *A, MARGIN))


def test_corner_of_first_shape_into_face_of_second():
    """The same corner contact with the turned box given first: B's face is then the
    reference (the normal is still from the first shape to the second: -y)."""
    B = box((0.3, 0.48 + SQ2 / 2), 1.0, 1.0, math.pi / 4)
    check(polygon_polygon(*B, *A, MARGIN), [[0.3, 0.49]], (0.0, -1.0), [0.02])


def test_triangle_tip_into_the_side_face():
    """A triangle pointing -x with its tip at (0.97, 0.1): 0.03 into A's right face x = 1.
    Normal +x, one point at (0.985, 0.1)."""
    tri = polygon([[0.97, 0.1], [1.5, -0.3], [1.5, 0.5]])
    forward = polygon_polygon(*A, *tri, MARGIN)
    check(forward, [[0.985, 0.1]], (1.0, 0.0), [0.03])
    swapped_agrees(forward, polygon_polygon(*tri, *A, MARGIN))


def test_least_penetration_axis_is_chosen():
    """B (1 x 1) at (1.2, 0.9) overlaps A by 0.3 in x and 0.1 in y: the normal is the y
    axis (least depth, 0.1), with B's bottom face x in [0.7, 1.7] clipped to [0.7, 1];
    points at y = 0.45."""
    B = box((1.2, 0.9), 1.0, 1.0)
    check(polygon_polygon(*A, *B, MARGIN), [[0.7, 0.45], [1.0, 0.45]], (0.0, 1.0),
          [0.1, 0.1])


@pytest.mark.parametrize("angle", [0.3, -1.2, 2.5])
def test_manifold_turns_with_the_shapes(angle):
    """Turning and shifting both shapes together turns and shifts the manifold: the
    overhang case, rotated by ``angle`` about the origin and moved by (3, -2)."""
    R, shift = rotation(angle), np.array([3.0, -2.0])
    A2 = box(shift, 2.0, 1.0, angle)
    B2 = box(R @ [0.9, 0.69] + shift, 0.4, 0.4, angle)
    points = np.array([[0.7, 0.495], [1.0, 0.495]]) @ R.T + shift
    check(polygon_polygon(*A2, *B2, MARGIN), points, R @ [0.0, 1.0], [0.01, 0.01])


@pytest.mark.parametrize("gap", [0.001, 0.003, 0.0049])
def test_gap_within_margin_is_reported_with_negative_depth(gap):
    """Shapes apart by less than the margin touch "speculatively": depth = -gap."""
    B = box((1.0, 1.0 + gap), 2.0, 1.0)
    check(polygon_polygon(*A, *B, MARGIN), [[0.0, 0.5 + gap / 2], [1.0, 0.5 + gap / 2]],
          (0.0, 1.0), [-gap, -gap])
    assert polygon_polygon(*A, *B, margin=0.0) == []


@pytest.mark.parametrize("gap", [0.0051, 0.05, 3.0])
def test_gap_beyond_margin_gives_nothing(gap):
    assert polygon_polygon(*A, *box((1.0, 1.0 + gap), 2.0, 1.0), MARGIN) == []
    assert polygon_polygon(*A, *box((2.0 + gap, 0.2), 2.0, 1.0), MARGIN) == []
    # a turned box whose corner is ``gap`` above A's top face
    assert polygon_polygon(*A, *box((0.3, 0.5 + gap + SQ2 / 2), 1.0, 1.0, math.pi / 4),
                           MARGIN) == []


# Brute force, written independently of collision.py: polygons as numpy arrays.

def _brute_overlap(va, na, vb, nb):
    """Least overlap over the face normals of both (normal from A to B), and its axis."""
    best, axis = math.inf, None
    for u in na:  # A's face normals: B must be pushed along +u
        depth = np.max(va @ u) - np.min(vb @ u)
        if depth < best:
            best, axis = depth, u
    for u in nb:  # B's face normals: A lies along +u from B, so the A->B normal is -u
        depth = np.max(va @ -u) - np.min(vb @ -u)
        if depth < best:
            best, axis = depth, -u
    return best, axis


def _distance_to_boundary(p, verts):
    """Distance from p to the polygon's boundary (nearest point on any edge)."""
    best = math.inf
    for a, b in zip(verts, np.roll(verts, -1, axis=0)):
        t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        best = min(best, float(np.hypot(*(p - a - t * (b - a)))))
    return best


def _random_polygon(rng):
    k = int(rng.integers(3, 8))
    angles = np.sort(rng.uniform(0.0, 2 * math.pi, k))
    radius = rng.uniform(0.3, 1.0)
    local = radius * np.column_stack([np.cos(angles), np.sin(angles)])
    local *= rng.uniform(0.5, 1.5, 2)  # squash: a general convex polygon
    return polygon(local, rng.uniform(-0.8, 0.8, 2), rng.uniform(-math.pi, math.pi))


def test_random_pairs_agree_with_brute_force_separating_axes():
    """400 random convex polygon pairs, checked against numpy brute force:

    - contacts exist when the least overlap over all face normals exceeds 1e-3, and none
      when some axis separates the shapes by more than the margin;
    - the normal is the brute-force least-overlap axis whenever that axis wins by more
      than the margin (the narrow phase keeps A's face unless B's is better by a tenth of
      the margin: a deliberate bias for frame-to-frame stability);
    - each point is halfway: point + n d/2 lies on A's boundary and point - n d/2 on B's;
      no point is deeper than the overlap along the normal;
    - swapping the arguments negates the normal and keeps points and depths (when the two
      polygons' best axes differ by more than the margin, so both orders pick one face).

    Tolerance 1e-9 on the boundary distances: the boundary points are computed from
    clipping intersections (a division) of O(1) coordinates.
    """
    rng = np.random.default_rng(20240605)
    overlapping = checked_normals = swapped = 0
    for _ in range(400):
        A_, B_ = _random_polygon(rng), _random_polygon(rng)
        va, na = np.array(A_[0]), np.array(A_[1])
        vb, nb = np.array(B_[0]), np.array(B_[1])
        found = polygon_polygon(*A_, *B_, MARGIN)
        least, axis = _brute_overlap(va, na, vb, nb)
        if least < -MARGIN - 1e-12:
            assert found == []
            continue
        if least > 1e-3:
            assert found, "overlapping polygons must give contacts"
            overlapping += 1
        if not found:
            continue
        normal = np.array(found[0][1])
        assert all(np.array_equal(c[1], found[0][1]) for c in found)
        assert abs(np.hypot(*normal) - 1.0) <= TOL
        along = np.max(va @ normal) - np.min(vb @ normal)
        for point, _, depth in found:
            p = np.array(point)
            assert depth <= along + 1e-9
            assert depth >= -MARGIN
            assert _distance_to_boundary(p + normal * depth / 2, va) <= 1e-9
            assert _distance_to_boundary(p - normal * depth / 2, vb) <= 1e-9
        # runner-up axis: least overlap over axes not parallel to the winner
        others = [np.max(va @ u) - np.min(vb @ u) for u in np.vstack([na, -nb])
                  if u @ axis < 1.0 - 1e-9]
        if min(others) > least + MARGIN:
            np.testing.assert_allclose(normal, axis, rtol=0, atol=1e-12)
            checked_normals += 1
        sep_a = max(min((vb - v) @ n) for v, n in zip(va, na))
        sep_b = max(min((va - v) @ n) for v, n in zip(vb, nb))
        if abs(sep_a - sep_b) > MARGIN:
            swapped_agrees(found, polygon_polygon(*B_, *A_, MARGIN))
            swapped += 1
    # the random set must exercise each branch, or the test proves little
    assert overlapping >= 50 and checked_normals >= 50 and swapped >= 50, \
        (overlapping, checked_normals, swapped)


# ------------------------------------------------------------------ polygon - circle

def test_circle_on_a_face():
    """Circle r = 0.2 at (0.3, 0.65): its bottom y = 0.45 is 0.05 into A's top face.
    One point halfway (0.3, 0.475), depth 0.05, normal +y."""
    forward = polygon_circle(*A, (0.3, 0.65), 0.2, MARGIN)
    check(forward, [[0.3, 0.475]], (0.0, 1.0), [0.05])
    backward = _collide(CirclePart((0.3, 0.65), 0.2), PolygonPart(*A))
    swapped_agrees(forward, backward)


def test_circle_in_a_vertex_region_uses_the_vertex():
    """Circle r = 0.2 at (1.1, 0.6): nearest feature is A's corner (1, 0.5) at distance
    0.1 sqrt 2; normal (1, 1)/sqrt 2, depth 0.2 - 0.1 sqrt 2, the point halfway between the
    corner and the circle's surface: corner - n depth/2."""
    n = np.array([1.0, 1.0]) / SQ2
    depth = 0.2 - 0.1 * SQ2
    forward = polygon_circle(*A, (1.1, 0.6), 0.2, MARGIN)
    check(forward, [np.array([1.0, 0.5]) - n * depth / 2], n, [depth])
    swapped_agrees(forward, _collide(CirclePart((1.1, 0.6), 0.2), PolygonPart(*A)))


@pytest.mark.parametrize("corner, direction", [((1.0, 0.5), (0.6, 0.8)),
                                               ((-1.0, -0.5), (-0.8, -0.6)),
                                               ((-1.0, 0.5), (-SQ2 / 2, SQ2 / 2))])
def test_circle_near_a_corner_within_and_beyond_margin(corner, direction):
    """A circle off a corner along ``direction`` (inside the corner's region): at a gap of
    0.003 it is reported (depth -0.003); at 0.007 it is not, although along each face
    normal alone it is closer than the radius plus the margin (an axis-only test would
    report it)."""
    c, d, r = np.array(corner), np.array(direction), 0.2
    near = polygon_circle(*A, tuple(c + d * (r + 0.003)), r, MARGIN)
    check(near, [c + d * 0.003 / 2], d, [-0.003])
    far_center = c + d * (r + 0.007)
    assert max(abs(far_center[0]) - 1.0, abs(far_center[1]) - 0.5) < r + MARGIN
    assert polygon_circle(*A, tuple(far_center), r, MARGIN) == []


def test_circle_center_inside_the_polygon():
    """Centre (0.9, 0) inside A, 0.1 from its right face: depth r + 0.1 = 0.3, normal +x;
    the point is halfway between the face (x = 1) and the circle's far side (x = 0.7)."""
    check(polygon_circle(*A, (0.9, 0.0), 0.2, MARGIN), [[0.85, 0.0]], (1.0, 0.0), [0.3])


def test_circle_on_a_turned_polygon():
    """A regular hexagon (unit circumradius, apothem sqrt(3)/2) turned 0.7 rad about
    (2, 1); a circle 0.04 into the face from vertex 0 to vertex 1, whose outward normal is
    at pi/6 in the hexagon's frame. Worked out in that frame and turned: normal R n, point
    0.02 inside the face along R n, depth 0.04."""
    angle, center = 0.7, np.array([2.0, 1.0])
    local = [[math.cos(k * math.pi / 3), math.sin(k * math.pi / 3)] for k in range(6)]
    hexagon = polygon(local, center, angle)
    apothem, r = math.sqrt(3) / 2, 0.3
    R = rotation(angle)
    n_local = np.array([math.cos(math.pi / 6), math.sin(math.pi / 6)])  # face 0 -> 1
    circle = R @ (n_local * (apothem + r - 0.04)) + center
    point = R @ (n_local * (apothem - 0.02)) + center
    check(polygon_circle(*hexagon, tuple(circle), r, MARGIN), [point], R @ n_local, [0.04])


@pytest.mark.parametrize("gap, reported", [(0.004, True), (0.006, False)])
def test_circle_near_a_face_margin(gap, reported):
    found = polygon_circle(*A, (0.0, 0.7 + gap), 0.2, MARGIN)
    if reported:
        check(found, [[0.0, 0.5 + gap / 2]], (0.0, 1.0), [-gap])
    else:
        assert found == []


# ------------------------------------------------------------------ circle - circle

def test_circles_overlapping():
    """r = 0.5 at the origin and r = 0.6 at (0.6, 0.8): distance 1, depth 0.1, normal
    (0.6, 0.8); the point 0.45 from the first center (halfway across the overlap)."""
    forward = circle_circle((0.0, 0.0), 0.5, (0.6, 0.8), 0.6, MARGIN)
    check(forward, [[0.27, 0.36]], (0.6, 0.8), [0.1])
    swapped_agrees(forward, circle_circle((0.6, 0.8), 0.6, (0.0, 0.0), 0.5, MARGIN))


@pytest.mark.parametrize("gap, reported", [(0.004, True), (0.006, False)])
def test_circles_margin(gap, reported):
    found = circle_circle((1.0, 1.0), 0.3, (1.0 + 0.7 + gap, 1.0), 0.4, MARGIN)
    if reported:
        check(found, [[1.3 + gap / 2, 1.0]], (1.0, 0.0), [-gap])
    else:
        assert found == []


def test_concentric_circles_get_a_defined_normal():
    """No direction between equal centers: the narrow phase picks +y (documented in
    circle_circle) and reports the full depth r_a + r_b, never a NaN."""
    (point, normal, depth), = circle_circle((1.0, 2.0), 0.3, (1.0, 2.0), 0.2, MARGIN)
    assert normal == (0.0, 1.0) and depth == pytest.approx(0.5, abs=TOL)
    assert np.all(np.isfinite(point))


# ------------------------------------------------------------------ half-planes

def test_tilted_box_behind_a_floor():
    """A's shape turned by 0.1 rad so that its lowest corner is 0.01 below the floor
    y = 0: only that corner is reported (the next one is 2 sin 0.1 = 0.2 higher), halfway
    between the corner and the floor."""
    angle = 0.1
    R = rotation(angle)
    low = R @ [-1.0, -0.5]
    center = np.array([0.4, -low[1] - 0.01])
    verts, _ = box(center, 2.0, 1.0, angle)
    corner = low + center
    check(half_plane_polygon((0.0, 1.0), 0.0, verts, MARGIN),
          [[corner[0], -0.005]], (0.0, 1.0), [0.01])


def test_box_resting_on_a_sloped_wall():
    """A box flat on the wall n . x >= 0.5 (n at 30 degrees from +y), 0.002 into it:
    both bottom corners, depth 0.002, each moved 0.001 along n."""
    a = math.radians(30.0)
    n = np.array([-math.sin(a), math.cos(a)])
    t = np.array([math.cos(a), math.sin(a)])
    center = n * (0.5 + 0.5 - 0.002) + 0.7 * t
    verts, _ = box(center, 2.0, 1.0, a)
    bottom = [center - 0.5 * n + s * t for s in (-1.0, 1.0)]
    check(half_plane_polygon(tuple(n), 0.5, verts, MARGIN),
          [p + n * 0.001 for p in bottom], n, [0.002, 0.002])


@pytest.mark.parametrize("gap, count", [(0.003, 2), (0.006, 0)])
def test_box_above_a_floor_margin(gap, count):
    verts, _ = box((0.0, 0.5 + gap), 2.0, 1.0)
    found = half_plane_polygon((0.0, 1.0), 0.0, verts, MARGIN)
    assert len(found) == count
    if count:
        check(found, [[-1.0, gap / 2], [1.0, gap / 2]], (0.0, 1.0), [-gap, -gap])


def test_circle_behind_a_wall():
    """Wall x >= 2 (normal +x, offset 2); circle r = 0.5 at (2.3, 7): 0.2 deep, the point
    halfway between x = 1.8 and the wall: (1.9, 7)."""
    check(half_plane_circle((1.0, 0.0), 2.0, (2.3, 7.0), 0.5, MARGIN), [[1.9, 7.0]],
          (1.0, 0.0), [0.2])
    check(half_plane_circle((1.0, 0.0), 2.0, (2.503, 7.0), 0.5, MARGIN), [[2.0015, 7.0]],
          (1.0, 0.0), [-0.003])
    assert half_plane_circle((1.0, 0.0), 2.0, (2.506, 7.0), 0.5, MARGIN) == []


# ------------------------------------------------------------------ in the contact pass

def test_compound_body_collides_part_by_part():
    """A T-shaped body (a 2 x 0.2 bar on a 0.2 x 1 stem, two convex parts) stands on a
    box, its stem 0.01 into the box's top face: the only contacts are the stem's two
    bottom corners (the bar is far above), each named by its part."""
    bodies = {
        "base": box_body((3.0, 1.0), 10.0, position=[0.0, 0.0]),
        "tee": {"mass": 1.0, "position": [0.25, 0.99],
                "parts": {"stem": {"shape": "box", "size": [0.2, 1.0], "center": [0.0, 0.0]},
                          "bar": {"shape": "box", "size": [2.0, 0.2], "center": [0.0, 0.6]}}},
    }
    sim = Simulation(make_scene({"bodies": bodies, "collisions": {
        "all": {"bodies": ["base", "tee"], "restitution": 0.0, "friction": 0.5}}}))
    found = sim.model.contacts.detect(sim.q)
    base, tee = sim.model.index["base"], sim.model.index["tee"]
    # the stem is the part centerd at the body-frame origin
    stem = [p for p, shape in enumerate(sim.scene.bodies[tee].shapes)
            if abs(float(np.mean(shape.vertices[:, 1]))) < 1e-12]
    assert len(found) == 2
    points = sorted(tuple(np.round(c[2], 12)) for c in found)
    np.testing.assert_allclose(points, [[0.15, 0.495], [0.35, 0.495]], rtol=0, atol=TOL)
    for a, b, _, normal, depth, e, mu, key in found:
        assert (a, b) == (min(base, tee), max(base, tee))
        sign = 1.0 if a == base else -1.0
        np.testing.assert_allclose(normal, (0.0, sign), rtol=0, atol=TOL)
        assert depth == pytest.approx(0.01, abs=TOL) and (e, mu) == (0.0, 0.5)
        assert key[2 if a == tee else 3] == stem[0]
