"""Regressions found by the robustness sweep of ``mesh_polygon`` on generated outlines."""

from __future__ import annotations

import numpy as np

from quadmesh import mesh_polygon
from quadmesh.outlines import random_star
from quadmesh.pipeline import _working_origin
from quadmesh.polygon import validate_polygon


def test_working_origin_is_exact_and_only_for_far_polygons() -> None:
    """The translation to the working origin is undone bit for bit (Sterbenz), and polygons
    near 0 (centre within 4 diameters) are not translated at all."""
    star = random_star(np.random.default_rng(5), 30)
    near = validate_polygon(star + np.array([3.0, -2.0]))
    assert _working_origin(near) == 0j
    for shift in ([1e6, -3e6], [1e6, 0.25], [-7.5e12, 1e9]):
        poly = validate_polygon(star + np.array(shift))
        o = _working_origin(poly)
        assert o != 0j
        local = poly.z - o
        assert np.array_equal(local + o, poly.z)
        assert np.abs(local).max() < poly.diameter
    # a coordinate whose centre is near 0 stays untranslated
    assert _working_origin(validate_polygon(star + np.array([1e6, 0.25]))).imag == 0.0


def test_star_far_from_origin_meshes() -> None:
    """A random 24-gon of diameter ~1.8 centred at (1e6, −3e6): its conformal map used to fail
    the accuracy checks (boundary deviation 1.2e-10, round trip ~1e-9: float64 vertices at 1e6
    carry 1.2e-10 absolute error). Meshed at the working origin it is verified, with the same
    quad count as the polygon at the origin and every mesh vertex within the polygon's box."""
    star = random_star(np.random.default_rng(2), 24)
    shift = np.array([1e6, -3e6])
    far = mesh_polygon(star + shift)
    o = far.origin
    near = mesh_polygon(far.polygon.z - o)  # the same polygon, translated exactly
    assert far.verification.ok
    assert o != 0j and near.origin == 0j
    assert far.quality.n_quads == near.quality.n_quads
    # the stages ran on the translated polygon; the mesh is stored relative to mesh_origin when
    # float64 at 1e6 cannot hold its angles (then mesh_origin is the working origin)
    mo = far.mesh_origin
    assert mo in (0j, o)
    local = far.mesh.vertices + np.array([mo.real - o.real, mo.imag - o.imag])
    assert np.abs(local - near.mesh.vertices).max() < 1e-9
    # the polygon's own vertices (translated exactly, Sterbenz) are mesh vertices, bit for bit
    v = far.mesh.vertices
    corners = (far.polygon.z - mo) if mo else far.polygon.z
    cxy = np.column_stack([corners.real, corners.imag])
    hits = (v[None, :, :] == cxy[:, None, :]).all(axis=2).any(axis=1)
    assert hits.all()
    # every new angle within the bounds on the stored coordinates, to the verifier's fixed
    # tolerance
    assert 60.0 - 1e-5 <= far.quality.min_angle and far.quality.max_angle <= 120.0 + 1e-5
    assert abs(far.mesh.areas().sum() - far.polygon.area) < 1e-8 * far.polygon.area


def test_polygon_two_diameters_from_origin_is_meshed_at_its_centre() -> None:
    """The user's polygon is meshed at its bounding-box centre from 1 diameter away from (0, 0)
    (parts cut off it only from 4, where they can no longer be matched by position): the
    translation is exact, every stage's data is relative to ``result.origin``, and the mesh
    verifies as stored."""
    from quadmesh.pipeline import FAR_FROM_ORIGIN, FAR_FROM_ORIGIN_TOP

    star = random_star(np.random.default_rng(3), 20)
    d = validate_polygon(star).diameter
    poly = validate_polygon(star + np.array([2.0 * d, -2.5 * d]))
    assert _working_origin(poly, FAR_FROM_ORIGIN) == 0j
    o = _working_origin(poly, FAR_FROM_ORIGIN_TOP)
    assert o != 0j and np.array_equal((poly.z - o) + o, poly.z)
    r = mesh_polygon(poly.vertices)
    assert r.origin == o and r.verification.ok
    v = r.mesh.vertices + np.array([r.mesh_origin.real, r.mesh_origin.imag])
    lo, hi = poly.vertices.min(axis=0), poly.vertices.max(axis=0)
    assert np.all(v >= lo - 1e-12 * d) and np.all(v <= hi + 1e-12 * d)
