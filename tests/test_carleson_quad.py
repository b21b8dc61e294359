"""Tests of the Carleson-quadrilateral mesh (Lemma 5.1, DISK.md §5) and its placement in D."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.disk.canonical import check_conformity, chord_angles, quad_signed_areas
from quadmesh.disk.carleson_quad import carleson_quad_mesh, carleson_quad_to_disk
from quadmesh.disk.pentagon import (
    P0_EDGE_GEODESICS,
    P0_VERTICES,
    SIDE_LENGTH_L,
    pentagon_mesh,
)
from quadmesh.errors import DiskConstructionError
from quadmesh.hyperbolic import (
    cayley_h_to_d,
    distance,
    distance_h,
    geodesic_coordinates,
    geodesic_endpoints_through,
    perpendicular_geodesic,
    point_towards,
    side_of_geodesic,
    tangent_direction,
)

L = SIDE_LENGTH_L


def uniform_depths(delta: float, d_max: float) -> np.ndarray:
    return np.linspace(0.0, d_max, int(np.ceil(d_max / delta - 1e-12)) + 1)


@pytest.mark.parametrize(("n_side", "m_rows"), [(1, 0), (2, 3), (4, 16), (8, 20)])
def test_counts_and_conformity(n_side, m_rows):
    d = np.linspace(0.0, 0.3 * m_rows, m_rows + 1)
    mesh = carleson_quad_mesh(n_side, d)
    assert mesh.n_vertices == (n_side + 1) * (m_rows + 2)
    assert mesh.n_quads == n_side * (m_rows + 1)
    bnd = check_conformity(mesh.quads, mesh.n_vertices)
    assert len(bnd) == 2 * n_side + 2 * (m_rows + 1)
    assert np.all(quad_signed_areas(mesh.vertices, mesh.quads) > 0)
    s = mesh.sides
    assert len(s["top"]) == n_side + 1 and len(s["base"]) == n_side + 1
    assert len(s["left"]) == m_rows + 2 and len(s["right"]) == m_rows + 2
    # corners shared between the sides
    assert s["top"][0] == s["left"][0] and s["top"][-1] == s["right"][0]
    assert s["base"][0] == s["left"][-1] and s["base"][-1] == s["right"][-1]
    # the boundary edges are exactly the four sides
    chain = np.concatenate([s["base"], s["right"][::-1][1:], s["top"][::-1][1:], s["left"][1:]])
    ccw = set(zip(chain[:-1].tolist(), chain[1:].tolist(), strict=True))
    assert ccw == set(map(tuple, bnd.tolist()))


def test_curvilinear_structure():
    d = uniform_depths(0.25, 4.0)
    n_side = 6
    mesh = carleson_quad_mesh(n_side, d)
    v = mesh.vertices
    top = mesh.side_points("top")
    assert abs(top[0] - 1j) < 1e-15 and abs(top[-1] - 1j * np.exp(L)) < 1e-13
    assert np.max(np.abs(distance_h(top[:-1], top[1:]) - L / n_side)) < 1e-12
    for name, corner in (("left", top[0]), ("right", top[-1])):
        z = mesh.side_points(name)
        assert np.max(np.abs(distance_h(corner, z[:-1]) - d)) < 1e-12
        assert abs(z[-1].imag) == 0 and z[-1].real > 0
    # horizontal leaves: row m at distance d_m from the top geodesic (the imaginary axis)
    rows = v.reshape(len(d) + 1, n_side + 1)
    dist_axis = np.arcsinh(rows[:-1].real / rows[:-1].imag)
    assert np.max(np.abs(dist_axis - d[:, None])) < 1e-12
    # same via the disk toolkit (Cayley image; the axis iR+ is the geodesic (-1, 1))
    s, dd = geodesic_coordinates(-1.0, 1.0, cayley_h_to_d(rows[:-1]))
    assert np.max(np.abs(np.abs(dd) - d[:, None])) < 1e-11
    assert np.max(np.abs(s - np.log(np.abs(rows[:-1])))) < 1e-11
    # vertical leaves: column k on |zeta| = e^{t_k}
    t = np.arange(n_side + 1) * L / n_side
    assert np.max(np.abs(np.abs(rows) - np.exp(t)[None, :])) < 1e-12


@pytest.mark.parametrize(
    ("n_side", "delta", "d_max", "lo", "hi"),
    [
        (2, L / 2, 2.77, 77.2, 102.8),
        (4, L / 4, 3.47, 82.97, 97.03),
        (4, 0.25, 4.0, 82.91, 97.09),
        (8, 1 / 8, 8.0, 86.43, 93.57),
    ],
)
def test_chord_angle_table(n_side, delta, d_max, lo, hi):
    """DISK.md §5 table of chord angles of the canonical quad."""
    mesh = carleson_quad_mesh(n_side, uniform_depths(delta, d_max))
    a = chord_angles(mesh.vertices, mesh.quads)
    assert abs(a.min() - lo) < 0.03 and abs(a.max() - hi) < 0.03


R_M = 2 * np.arctanh(0.30355865872664684)  # distance from 0 to P0's edge geodesics


def _random_placements(rng: np.random.Generator, k: int, r_lo: float, r_hi: float, zero_side: bool):
    """Quads under random geodesics at distance r in [r_lo, r_hi] from 0, at random positions
    along them, with u1 on either side of u0, on the side of 0 (zero_side) or the far side."""
    c = np.exp(2j * np.pi * rng.random(k))
    top = c * np.tanh(rng.uniform(r_lo, r_hi, k) / 2)
    p, q = perpendicular_geodesic(-c, c, top)
    u0 = point_towards(top, q, rng.normal(0.0, 3.0, k))
    u1 = point_towards(u0, np.where(rng.random(k) < 0.5, p, q), L)
    e0, e1 = geodesic_endpoints_through(u0, u1)
    side = side_of_geodesic(e0, e1, np.zeros(k)).astype(int)
    if not zero_side:
        side = -side
    return u0, u1, p, q, side


@pytest.mark.parametrize(
    ("zero_side", "r_lo", "r_hi", "lo", "hi"),
    [(False, 0.0, 8.0, 80.0, 100.0), (True, 0.0, R_M, 75.5, 104.5)],
)
def test_placement_in_disk(zero_side, r_lo, r_hi, lo, hi):
    """Far-side quads measure about [80.6, 99.4]; quads on the 0-side of geodesics at distance
    <= R_M (the longest I5 arcs, 4.32 rad, DISK.md §3) about [75.9, 104.1] (N_side=4, delta=1/4)."""
    rng = np.random.default_rng(7)
    d = uniform_depths(0.25, np.log(8 / 0.25) + 2)
    mesh = carleson_quad_mesh(4, d)
    k = 400
    u0, u1, a, b, side = _random_placements(rng, k, r_lo, r_hi, zero_side)
    verts, quads = carleson_quad_to_disk(mesh, u0, u1, a, b, side)
    assert verts.shape == (k, mesh.n_vertices) and quads.shape == (k, mesh.n_quads, 4)
    top, left, right, base = (mesh.sides[s] for s in ("top", "left", "right", "base"))
    assert np.max(np.abs(verts[:, top[0]] - u0)) < 1e-11
    assert np.max(np.abs(verts[:, top[-1]] - u1)) < 1e-9
    assert np.max(np.abs(np.abs(verts[:, base]) - 1.0)) < 1e-15
    assert np.all(np.abs(verts[:, : base[0]]) < 1)
    # every copy CCW, on the requested side of u0 -> u1, chord angles within [60, 120]
    assert np.all(quad_signed_areas(verts, quads) > 0)
    e0, e1 = geodesic_endpoints_through(u0, u1)
    mid = verts[:, mesh.n_vertices // 2]  # an interior vertex
    assert np.all(side_of_geodesic(e0, e1, mid) == side)
    ang = chord_angles(verts, quads)
    assert ang.min() >= 60.0 and ang.max() <= 120.0
    assert ang.min() > lo and ang.max() < hi
    # side rays: perpendicular to the top at u0 and u1, vertices at distance d_m
    ok = np.abs(u0) < 1 - 1e-6  # distances near T lose digits
    ld = distance(u0[ok, None], verts[ok][:, left[1:-1]])
    assert np.max(np.abs(ld - d[None, 1:])) < 1e-7
    rd = distance(u1[ok, None], verts[ok][:, right[1:-1]])
    assert np.max(np.abs(rd - d[None, 1:])) < 1e-7
    # horizontal leaves: row m equidistant (d_m) from the top geodesic
    rows = verts[ok][:, : base[0]].reshape(int(ok.sum()), len(d), -1)
    _, dist = geodesic_coordinates(e0[ok, None, None], e1[ok, None, None], rows)
    assert np.max(np.abs(np.abs(dist) - d[None, :, None])) < 1e-7
    perp = np.angle(tangent_direction(u0, verts[:, left[1]]) / tangent_direction(u0, u1))
    assert np.max(np.abs(np.abs(perp)[ok] - np.pi / 2)) < 1e-8


def test_big_quads_leave_the_bound():
    """Quads on the 0-side of a geodesic far from 0 are Euclidean-huge: chord angles fail
    (documented limitation: Bishop's construction only puts quads there for arcs <= 4.32 rad)."""
    mesh = carleson_quad_mesh(4, uniform_depths(0.25, 4.0))
    top = np.tanh(2.0 / 2)
    p, q = perpendicular_geodesic(-1.0, 1.0, top)
    u1 = point_towards(top, q, L / 2)
    u0 = point_towards(top, p, L / 2)
    e0, e1 = geodesic_endpoints_through(u0, u1)
    side = int(side_of_geodesic(e0, e1, 0.0))
    verts, quads = carleson_quad_to_disk(mesh, u0, u1, p, q, side)
    ang = chord_angles(verts, quads)
    assert ang.min() < 60.0


def test_quads_below_pentagon_edges_match_pentagon_mesh():
    n = 2
    pent = pentagon_mesh(n)
    mesh = carleson_quad_mesh(2 * n, uniform_depths(0.25, 4.0))
    u0 = P0_VERTICES
    u1 = np.roll(P0_VERTICES, -1)
    # P0 is on the left of each edge geodesic: put the quads on the right (outside)
    verts, quads = carleson_quad_to_disk(
        mesh, u0, u1, P0_EDGE_GEODESICS[:, 1], P0_EDGE_GEODESICS[:, 0], -1
    )
    for k in range(5):
        top = verts[k][mesh.sides["top"]]
        assert np.max(np.abs(top - pent.side_points(f"edge{k}"))) < 1e-14
        assert np.all(np.abs(verts[k][: mesh.sides["base"][0]]) > 0.3)
    assert np.all(quad_signed_areas(verts, quads) > 0)


def test_bad_input():
    with pytest.raises(DiskConstructionError):
        carleson_quad_mesh(0, [0.0, 1.0])
    with pytest.raises(DiskConstructionError):
        carleson_quad_mesh(2, [0.1, 1.0])
    with pytest.raises(DiskConstructionError):
        carleson_quad_mesh(2, [0.0, 1.0, 1.0])
    mesh = carleson_quad_mesh(2, [0.0, 1.0])
    with pytest.raises(DiskConstructionError, match="top length"):
        carleson_quad_to_disk(mesh, 0.0, 0.2, -1.0, 1.0, 1)
    with pytest.raises(DiskConstructionError, match="side"):
        u1 = point_towards(0.0, 1.0, L)
        carleson_quad_to_disk(mesh, 0.0, u1, -1.0, 1.0, 0)
