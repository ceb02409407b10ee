"""Mass properties from shape (article step 1): closed forms, the parallel-axis theorem by
hand, either winding, body frames whose origin is not the CM, and refused degenerate shapes.

Tolerances: the polygon integrals are sums of a few products of O(1) numbers, so they agree
with the closed forms to a few ulps; 1e-12 relative leaves a wide margin for that and still
catches any wrong factor or sign (which would be O(1)).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scene_builders import make_scene, rotation, write_scene

from hecker_dynamics import Simulation
from hecker_dynamics.geometry.shapes import (
    Circle,
    GeometryError,
    Polygon,
    area_properties,
    box,
    mass_properties,
)
from hecker_dynamics.scene.load import SceneError, load_scene

REL = 1e-12


def props(shapes, densities):
    return mass_properties(list(shapes), list(densities))


# ------------------------------------------------------------------ closed forms

@pytest.mark.parametrize("w,h,rho", [(1.0, 1.0, 1.0), (2.0, 0.5, 3.0), (0.01, 7.0, 0.2)])
def test_box_inertia_is_m_w2_plus_h2_over_12(w, h, rho):
    p = props([box(w, h)], [rho])
    m = rho * w * h
    assert p.mass == pytest.approx(m, rel=REL)
    assert p.center_of_mass == pytest.approx([0.0, 0.0], abs=1e-15 * (w + h))
    assert p.moment_of_inertia == pytest.approx(m * (w * w + h * h) / 12.0, rel=REL)


@pytest.mark.parametrize("r", [0.1, 1.0, 3.5])
def test_disc_inertia_is_m_r2_over_2(r):
    p = props([Circle((0.3, -0.2), r)], [2.0])
    m = 2.0 * math.pi * r * r
    assert p.mass == pytest.approx(m, rel=REL)
    assert p.center_of_mass == pytest.approx([0.3, -0.2], rel=REL)
    assert p.moment_of_inertia == pytest.approx(m * r * r / 2.0, rel=REL)


@pytest.mark.parametrize("tri", [
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)],
    [(-1.0, 2.0), (4.0, 0.5), (2.0, 3.0)],
    [(10.0, 10.0), (10.1, 10.0), (10.0, 13.0)],  # thin and far from the origin
])
def test_triangle_matches_closed_form_about_centroid(tri):
    """Polar moment of a uniform triangle about its centroid: m (a^2 + b^2 + c^2) / 36 with
    a, b, c the side lengths; centroid = mean of the vertices; area = |cross| / 2.

    The far-off triangle integrates about the origin and shifts back by m d^2 with
    d ~ 14 m, which cancels ~2 digits: 1e-10 relative there."""
    v = np.array(tri)
    a, b, c = (np.hypot(*(v[i] - v[(i + 1) % 3])) for i in range(3))
    area = abs(np.cross(np.append(v[1] - v[0], 0), np.append(v[2] - v[0], 0))[2]) / 2
    rho = 1.7
    p = props([Polygon(v)], [rho])
    m = rho * area
    assert p.mass == pytest.approx(m, rel=REL)
    assert p.center_of_mass == pytest.approx(v.mean(axis=0), rel=REL)
    assert p.moment_of_inertia == pytest.approx(m * (a * a + b * b + c * c) / 36.0, rel=1e-10)


L_SHAPE = [(0.0, 0.0), (3.0, 0.0), (3.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)]


def test_l_shape_vs_parallel_axis_theorem_by_hand():
    """L = [0,3]x[0,1] + [0,1]x[1,2]. By hand: areas 3 and 1, centroids (1.5, 0.5) and
    (0.5, 1.5), CM (1.25, 0.75); I/rho = 3 (9+1)/12 + 3 (0.25^2+0.25^2)
    + 1 (1+1)/12 + 1 (0.75^2+0.75^2) = 25/6."""
    rho = 2.0
    expected_cm, expected_i = (1.25, 0.75), rho * 25.0 / 6.0
    polygon = props([Polygon(L_SHAPE)], [rho])
    compound = props([box(3.0, 1.0, (1.5, 0.5)), box(1.0, 1.0, (0.5, 1.5))], [rho, rho])
    for p in (polygon, compound):
        assert p.mass == pytest.approx(4.0 * rho, rel=REL)
        assert p.center_of_mass == pytest.approx(expected_cm, rel=REL)
        assert p.moment_of_inertia == pytest.approx(expected_i, rel=REL)


@pytest.mark.parametrize("vertices", [L_SHAPE, [(0.0, 0.0), (2.0, 0.3), (1.0, 2.0)],
                                      [(0, 0), (4, 0), (4, 3), (2, 1), (0, 3)]])
def test_either_winding_gives_the_same_result(vertices):
    cw = props([Polygon(vertices[::-1])], [1.3])
    ccw = props([Polygon(vertices)], [1.3])
    assert cw.mass == pytest.approx(ccw.mass, rel=1e-14)
    assert cw.center_of_mass == pytest.approx(ccw.center_of_mass, rel=1e-14)
    assert cw.moment_of_inertia == pytest.approx(ccw.moment_of_inertia, rel=1e-14)
    assert cw.mass > 0 and cw.moment_of_inertia > 0


def test_offset_rotated_box_keeps_its_inertia_about_its_center():
    """A box moved to (3, -1) and turned 0.7 rad: CM at its center, same I as unturned."""
    p = props([box(2.0, 1.0, (3.0, -1.0), 0.7)], [1.5])
    m = 1.5 * 2.0
    assert p.mass == pytest.approx(m, rel=REL)
    assert p.center_of_mass == pytest.approx([3.0, -1.0], rel=REL)
    assert p.moment_of_inertia == pytest.approx(m * 5.0 / 12.0, rel=1e-11)
    # the turned corners really are turned
    corner = rotation(0.7) @ np.array([1.0, 0.5]) + [3.0, -1.0]
    vertices = box(2.0, 1.0, (3.0, -1.0), 0.7).vertices
    assert any(np.allclose(v, corner, atol=1e-14) for v in vertices)


def test_compound_box_and_circle_by_hand():
    """Box 2 x 1 at the origin (density 1, m1 = 2) + disc r = 0.5 at (2, 0) (density 2,
    m2 = pi/2): CM x = m2 * 2 / (m1 + m2); I = sum of own I + m d^2 (parallel axis)."""
    m1, m2 = 2.0, 2.0 * math.pi * 0.25
    cx = m2 * 2.0 / (m1 + m2)
    inertia = m1 * 5.0 / 12.0 + m1 * cx ** 2 + m2 * 0.25 / 2.0 + m2 * (2.0 - cx) ** 2
    p = props([box(2.0, 1.0), Circle((2.0, 0.0), 0.5)], [1.0, 2.0])
    assert p.mass == pytest.approx(m1 + m2, rel=REL)
    assert p.center_of_mass == pytest.approx([cx, 0.0], rel=REL, abs=1e-15)
    assert p.moment_of_inertia == pytest.approx(inertia, rel=REL)


def test_area_properties_second_moment_of_square_about_centroid():
    a = area_properties(box(2.0, 2.0, (5.0, 5.0)))
    assert a.area == pytest.approx(4.0, rel=REL)
    assert a.second_moment == pytest.approx(4.0 * 8.0 / 12.0, rel=1e-11)


# ------------------------------------------------------------------ bodies in scenes

def test_scene_compound_body_with_mass_keeps_density_ratios():
    """A body of a box (density 1) and a disc (density 2) scaled to mass 3: the shapes'
    masses keep their 1:2-density proportion and CM / I scale with the hand values."""
    scene = make_scene({"bodies": {"b": {
        "mass": 3.0,
        "parts": {"hull": {"shape": "box", "size": [2.0, 1.0], "density": 1.0},
                  "ball": {"shape": "circle", "center": [2.0, 0.0], "radius": 0.5,
                           "density": 2.0}}}}})
    m1, m2 = 2.0, 2.0 * math.pi * 0.25
    scale = 3.0 / (m1 + m2)
    cx = m2 * 2.0 / (m1 + m2)
    inertia = m1 * 5.0 / 12.0 + m1 * cx ** 2 + m2 * 0.25 / 2.0 + m2 * (2.0 - cx) ** 2
    mp = scene.bodies[0].mass
    assert mp.mass == pytest.approx(3.0, rel=REL)
    assert mp.center_of_mass == pytest.approx([cx, 0.0], rel=REL, abs=1e-15)
    assert mp.moment_of_inertia == pytest.approx(scale * inertia, rel=REL)


def test_body_frame_origin_not_at_cm():
    """Shape offset from the body frame origin: cm_local is the offset, the CM state is
    origin + R(angle) cm_local with v_CM = v_origin + w perp(R cm_local), and snapshots
    report the body frame (origin) again. 1e-14: a rotation and an add of O(1) numbers."""
    scene = make_scene({"bodies": {"b": {
        "shape": "circle", "center": [0.5, 0.2], "radius": 0.3, "mass": 2.0,
        "position": [1.0, 2.0], "angle": 0.9, "velocity": [1.0, -0.5],
        "angular_velocity": 2.0}}})
    sim = Simulation(scene)
    assert sim.model.cm_local[0] == pytest.approx([0.5, 0.2], rel=REL)
    r = rotation(0.9) @ np.array([0.5, 0.2])
    assert sim.q[0] == pytest.approx([1.0 + r[0], 2.0 + r[1], 0.9], rel=1e-14)
    assert sim.v[0] == pytest.approx([1.0 - 2.0 * r[1], -0.5 + 2.0 * r[0], 2.0], rel=1e-14)
    body = sim.snapshot().bodies[0]
    assert body.position == pytest.approx((1.0, 2.0), rel=1e-14)
    assert body.linear_velocity == pytest.approx((1.0, -0.5), rel=1e-14, abs=1e-15)
    assert sim.model.inertia[0] == pytest.approx(2.0 * 0.09 / 2.0, rel=REL)


def test_polygon_body_vertices_and_center_in_body_frame():
    """``vertices`` are shifted by ``center``; the CM is the triangle's centroid."""
    scene = make_scene({"bodies": {"t": {
        "shape": "polygon", "vertices": [0.0, 0.0, 3.0, 0.0, 0.0, 3.0], "center": [1.0, 1.0],
        "mass": 1.0}}})
    assert scene.bodies[0].mass.center_of_mass == pytest.approx([2.0, 2.0], rel=REL)


# ------------------------------------------------------------------ degenerate shapes

DEGENERATE = {
    "collinear": ({"shape": "polygon", "vertices": [0.0, 0.0, 1.0, 1.0, 2.0, 2.0], "mass": 1.0},
                  None),
    "collinear4": ({"shape": "polygon", "vertices": [0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 3.0, 0.0],
                    "mass": 1.0}, None),
    "point": ({"shape": "polygon", "vertices": [1.0, 1.0, 1.0, 1.0, 1.0, 1.0], "density": 1.0},
              None),
    "bowtie": ({"shape": "polygon", "vertices": [0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0],
                "mass": 1.0}, None),
    "nan_vertex": ({"shape": "polygon", "vertices": [0.0, 0.0, float("nan"), 0.0, 0.0, 1.0],
                    "mass": 1.0}, "vertices"),
    "inf_size": ({"shape": "box", "size": [float("inf"), 1.0], "mass": 1.0}, "size"),
    "nan_mass": ({"shape": "box", "size": [1.0, 1.0], "mass": float("nan")}, "mass"),
    "nan_radius": ({"shape": "circle", "radius": float("nan"), "mass": 1.0}, "radius"),
    "nan_density": ({"shape": "circle", "radius": 1.0, "density": float("nan")}, "density"),
    "negative_mass": ({"shape": "box", "size": [1.0, 1.0], "mass": -1.0}, "mass"),
    "zero_mass": ({"shape": "box", "size": [1.0, 1.0], "mass": 0.0}, "mass"),
    "negative_density": ({"shape": "box", "size": [1.0, 1.0], "density": -2.0}, "density"),
    "zero_density": ({"shape": "circle", "radius": 1.0, "density": 0.0}, "density"),
    "negative_radius": ({"shape": "circle", "radius": -0.5, "mass": 1.0}, "radius"),
    "zero_size_box": ({"shape": "box", "size": [0.0, 1.0], "mass": 1.0}, None),
    "negative_part_density": ({"mass": 1.0, "parts": {
        "a": {"shape": "box", "size": [1.0, 1.0], "density": 1.0},
        "b": {"shape": "box", "size": [1.0, 1.0], "center": [2.0, 0.0], "density": -1.0}}},
        None),
}


@pytest.mark.parametrize("case", sorted(DEGENERATE))
@pytest.mark.parametrize("form", ["file", "parameters"])
def test_degenerate_shape_is_refused_naming_the_body(case, form, tmp_path):
    body, parameter = DEGENERATE[case]
    params = {"bodies": {"fine": {"shape": "circle", "radius": 1.0, "mass": 1.0},
                         "bad_body": body}}
    with pytest.raises(SceneError) as caught:
        if form == "file":
            load_scene(write_scene(tmp_path, params, "degenerate.yaml"))
        else:
            make_scene(params, source="param-source")
    message = str(caught.value)
    assert "bad_body" in message
    assert ("degenerate.yaml" if form == "file" else "param-source") in message
    if parameter is not None:
        assert f"bodies.bad_body.{parameter}" in message


@pytest.mark.parametrize("vertices, message", [
    # A closed ring, as GeoJSON writes one, and a corner given twice: they were refused as
    # polygons whose "edges cross each other".
    ([(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)], "vertices 4 and 0 are the same point"),
    ([(0, 0), (1, 0), (1, 0), (1, 1)], "vertices 1 and 2 are the same point"),
])
def test_a_corner_given_twice_is_named(vertices, message):
    with pytest.raises(GeometryError, match=message + r" \(give each corner once: the last "
                       r"does not repeat the first\)$"):
        props([Polygon(vertices)], [1.0])


def test_geometry_refuses_bad_shapes_directly():
    with pytest.raises(GeometryError):
        Polygon([(0.0, 0.0), (1.0, float("nan")), (0.0, 1.0)])
    with pytest.raises(GeometryError):
        Polygon([(0.0, 0.0), (1.0, 0.0)])
    with pytest.raises(GeometryError):
        Circle((0.0, 0.0), -1.0)
    with pytest.raises(GeometryError):
        Circle((0.0, float("inf")), 1.0)
    with pytest.raises(GeometryError):
        box(-1.0, 1.0)
    with pytest.raises(GeometryError):
        props([box(1.0, 1.0)], [-1.0])
    with pytest.raises(GeometryError):
        props([box(1.0, 1.0)], [float("nan")])
    with pytest.raises(GeometryError):
        props([Polygon([(0, 0), (1, 1), (1, 0), (0, 1)])], [1.0])  # bow-tie
    with pytest.raises(GeometryError):
        props([], [])


@pytest.mark.parametrize("offset", [1e2, 1e3, 1e4])
def test_small_polygon_far_from_its_frame_origin_keeps_its_inertia(offset):
    """A 1 cm box centered 100 m to 10 km from its frame's origin: integrating about the
    frame origin and moving back to the centroid would cancel every digit (the old code gave
    a negative inertia at 100 m). Fanned from the mean vertex, the only error left is the
    rounding of the vertices themselves: ulp(offset) / 0.01 relative, at most 2e-10 here."""
    size = 0.01
    props = mass_properties([box(size, size, (offset, offset))], [1.0])
    exact = size ** 2 * (2.0 * size ** 2) / 12.0
    assert props.moment_of_inertia == pytest.approx(exact, rel=1e-8)
    assert props.center_of_mass == pytest.approx((offset, offset), abs=1e-9)


@pytest.mark.parametrize("size, mass", [(1.0, 1e-310), (0.01, 1e-307), (1.0, 1e-320)])
def test_a_mass_or_inertia_whose_inverse_overflows_is_refused(tmp_path, size, mass):
    """A body so light that 1/m or 1/I is inf (below 1/DBL_MAX, 5.6e-309): the scene ran to
    its first step and failed there as "dopri5: the sub-step size underflowed", and the
    World API took the body with numpy's overflow warning and stepped it. Refused when the
    body is made, naming it; 1e-300 kg (inverses 1e300 and 6e300) is still a body."""
    import hecker_dynamics as hd

    with pytest.raises(GeometryError, match="so small that its inverse overflows a double"):
        mass_properties([box(size, size)], [mass / (size * size)])
    world = hd.World()
    with pytest.raises(SceneError, match="body 'a': the mass .* inverse overflows"):
        world.add_body("a", hd.Box(size, size), mass=mass)
    world.add_body("a", hd.Box(1.0, 1.0), mass=1e-300)
    if mass >= 1e-308:  # a scene file reads a number below that as a string, as rcl does
        path = write_scene(tmp_path, {"bodies": {"a": {
            "shape": "box", "size": [size, size], "mass": mass}}}, "light.yaml")
        with pytest.raises(SceneError, match="light.yaml: body 'a': the mass"):
            load_scene(path)
