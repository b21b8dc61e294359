"""Tests of the right-pentagon mesh (Lemma 4.1) and the shared canonical-mesh helpers."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.disk.canonical import (
    CanonicalMesh,
    check_conformity,
    chord_angles,
    place_mesh,
    quad_signed_areas,
)
from quadmesh.disk.pentagon import (
    P0_EDGE_GEODESICS,
    P0_EDGE_MIDPOINTS,
    P0_EDGE_REFLECTIONS,
    P0_VERTICES,
    SIDE_LENGTH_L,
    pentagon_mesh,
)
from quadmesh.errors import DiskConstructionError, MeshVerificationError
from quadmesh.hyperbolic import (
    Isometry,
    disk_automorphism,
    distance,
    intersect_geodesics,
    perpendicular_geodesic,
    side_of_geodesic,
    tangent_direction,
)

L = SIDE_LENGTH_L


def test_constants():
    assert abs(L - 1.0612750619) < 1e-10
    assert abs(np.cosh(L / 2) - np.cos(np.pi / 5) / np.sin(np.pi / 4)) < 1e-14
    assert np.allclose(np.abs(P0_VERTICES), 0.397975, atol=1e-6)
    assert np.allclose(np.abs(P0_EDGE_MIDPOINTS), 0.303559, atol=1e-6)
    nxt = np.roll(P0_VERTICES, -1)
    assert np.max(np.abs(distance(P0_VERTICES, nxt) - L)) < 1e-13
    assert np.max(np.abs(distance(P0_VERTICES, P0_EDGE_MIDPOINTS) - L / 2)) < 1e-13
    # right angles at the vertices
    prv = np.roll(P0_VERTICES, 1)
    ang = np.angle(tangent_direction(P0_VERTICES, prv) / tangent_direction(P0_VERTICES, nxt))
    assert np.max(np.abs(ang - np.pi / 2)) < 1e-12
    # P0 lies on the left of every oriented edge geodesic
    p, q = P0_EDGE_GEODESICS[:, 0], P0_EDGE_GEODESICS[:, 1]
    assert np.all(side_of_geodesic(p, q, 0.0) > 0)


def test_edge_reflections():
    S = P0_EDGE_REFLECTIONS
    assert len(S) == 5 and np.all(S.sigma)
    for k in range(5):
        s = S[k]
        ends = P0_VERTICES[[k, (k + 1) % 5]]
        assert np.max(np.abs(s(ends) - ends)) < 1e-14
        assert np.max(np.abs((s @ s)(P0_VERTICES) - P0_VERTICES)) < 1e-13
        # the neighbour's centre is at distance 2 R_M from 0, beyond edge k
        c = s(0.0)
        assert abs(distance(0.0, c) - 2 * distance(0.0, P0_EDGE_MIDPOINTS[k])) < 1e-13
    # reflections in perpendicular edges commute (4 tiles at a vertex)
    z = np.array([0.1 + 0.2j, -0.3j])
    assert np.max(np.abs((S[0] @ S[1])(z) - (S[1] @ S[0])(z))) < 1e-13


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_counts_conformity_orientation(n):
    m = pentagon_mesh(n)
    assert m.n_quads == 5 * n * n
    assert m.n_vertices == 5 * n * n + 5 * n + 1
    bnd = check_conformity(m.quads, m.n_vertices)
    assert len(bnd) == 10 * n
    assert np.all(quad_signed_areas(m.vertices, m.quads) > 0)
    # boundary edges are exactly the consecutive pairs of the 5 sides, in CCW direction
    side_edges = set()
    for k in range(5):
        s = m.sides[f"edge{k}"]
        assert len(s) == 2 * n + 1
        assert s[0] == m.sides[f"edge{(k - 1) % 5}"][-1]
        assert abs(m.vertices[s[0]] - P0_VERTICES[k]) < 1e-15
        side_edges |= set(zip(s[:-1].tolist(), s[1:].tolist(), strict=True))
    assert side_edges == set(map(tuple, bnd.tolist()))
    # exact 5-fold symmetry: the image of the vertex set under rotation is itself
    rot = np.exp(2j * np.pi / 5) * m.vertices
    dmin = np.min(np.abs(rot[:, None] - m.vertices[None, :]), axis=1)
    assert np.max(dmin) < 1e-14


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_side_spacing(n):
    m = pentagon_mesh(n)
    for k in range(5):
        z = m.side_points(f"edge{k}")
        assert np.max(np.abs(distance(z[:-1], z[1:]) - L / (2 * n))) < 1e-12
        assert abs(z[-1] - P0_VERTICES[(k + 1) % 5]) < 1e-15


@pytest.mark.parametrize("n", [2, 3, 4])
def test_lambert_formula(n):
    """Z[i, j] = perpendicular at x_i to edge 0 meets perpendicular at y_j to edge 4; it is a mesh
    vertex and the angle phi there satisfies cos phi = sinh a_i sinh a_j (Lambert quadrilateral)."""
    m = pentagon_mesh(n)
    a = np.arange(n + 1) * L / (2 * n)
    x = m.side_points("edge0")[: n + 1]  # x_i on edge 0 from V_0
    y = m.side_points("edge4")[::-1][: n + 1]  # y_j on edge 4 from V_0
    p0, q0 = P0_EDGE_GEODESICS[0]
    p4, q4 = P0_EDGE_GEODESICS[4]
    ep, eq = perpendicular_geodesic(p0, q0, x[1:])
    fp, fq = perpendicular_geodesic(p4, q4, y[1:])
    Z = intersect_geodesics(ep[:, None], eq[:, None], fp[None, :], fq[None, :])
    dmin = np.min(np.abs(Z[..., None] - m.vertices), axis=-1)
    assert np.max(dmin) < 1e-13
    ii, jj = np.meshgrid(np.arange(1, n + 1), np.arange(1, n + 1), indexing="ij")
    inner = ~((ii == n) & (jj == n))  # Z[n, n] is the centre, where the spokes meet at 72
    t1 = tangent_direction(Z, x[ii])
    t2 = tangent_direction(Z, y[jj])
    phi = np.abs(np.angle(t1 / t2))
    assert np.max(np.abs(np.cos(phi) - np.sinh(a[ii]) * np.sinh(a[jj]))[inner]) < 1e-12
    assert abs(np.abs(Z[-1, -1])) < 1e-15
    assert abs(np.degrees(phi[-1, -1]) - 72.0) < 1e-9  # spokes meet at 2*pi/5


def _moved_angles(m: CanonicalMesh, rng: np.random.Generator, count: int) -> np.ndarray:
    r = np.concatenate([rng.uniform(0, 0.999, count - 8), [0.99, 0.995, 0.999] * 2, [0, 0.5]])
    b = r * np.exp(2j * np.pi * rng.random(r.size))
    g = Isometry.stack([disk_automorphism(-bb) for bb in b])
    v, q = place_mesh(m, g)
    return chord_angles(v, q)


@pytest.mark.parametrize(("n", "lo", "hi"), [(2, 62.5, 112.9), (3, 65.3, 111.3), (4, 66.8, 110.5)])
def test_chord_angles_in_range(n, lo, hi):
    rng = np.random.default_rng(n)
    m = pentagon_mesh(n)
    a0 = chord_angles(m.vertices, m.quads)
    assert a0.min() >= 72.0 - 1e-9 and a0.max() < 108.0
    a = _moved_angles(m, rng, 400)
    assert a.min() > lo and a.max() < hi
    assert a.min() >= 60.0 and a.max() <= 120.0
    # the worst case is the |b| -> 1 limit z -> z/(1 + e^{it} z)
    e = np.exp(1j * np.linspace(0, 2 * np.pi / 5, 145))
    lim = m.vertices[None, :] / (1 + e[:, None] * m.vertices[None, :])
    al = chord_angles(lim, m.quads)
    assert lo < al.min() < lo + 0.1 and hi - 0.1 < al.max() < hi


def test_n1_fails_the_bound():
    m = pentagon_mesh(1)
    e = np.exp(1j * np.linspace(0, 2 * np.pi / 5, 145))
    lim = m.vertices[None, :] / (1 + e[:, None] * m.vertices[None, :])
    a = chord_angles(lim, m.quads)
    assert a.min() < 56.0  # DISK.md §4: 55.7 degrees


def test_neighbour_tiles_match():
    """Tiles P0 and sigma_k(P0) share edge k with identical vertex lists (reversed)."""
    n = 3
    m = pentagon_mesh(n)
    v, q = place_mesh(m, P0_EDGE_REFLECTIONS)
    for k in range(5):
        mine = m.side_points(f"edge{k}")
        theirs = v[k][m.sides[f"edge{k}"]]
        assert np.max(np.abs(mine - theirs)) < 1e-14
        assert np.all(quad_signed_areas(v[k], q[k]) > 0)
    # glue P0 with its 5 neighbours into one mesh and check conformity
    allv = np.concatenate([m.vertices, v.ravel()])
    _, inv = np.unique(np.round(allv * 1e10), return_inverse=True)
    quads = [inv[m.quads]] + [inv[m.n_vertices * (k + 1) + q[k]] for k in range(5)]
    bnd = check_conformity(np.concatenate(quads))
    assert len(bnd) == 6 * 10 * n - 2 * 5 * 2 * n


def test_bad_input():
    with pytest.raises(DiskConstructionError):
        pentagon_mesh(0)
    with pytest.raises(DiskConstructionError):
        pentagon_mesh(1.5)


def test_conformity_checker_detects_errors():
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4]])
    assert len(check_conformity(quads, 6)) == 6
    with pytest.raises(MeshVerificationError, match="directed edge"):
        check_conformity(np.array([[0, 1, 4, 3], [1, 4, 5, 2]]))  # inconsistent orientation
    with pytest.raises(MeshVerificationError, match=r"directed edge|shared by"):
        check_conformity(np.array([[0, 1, 4, 3], [1, 2, 5, 4], [4, 1, 6, 7]]))
    with pytest.raises(MeshVerificationError, match="repeats a vertex"):
        check_conformity(np.array([[0, 1, 1, 3]]))
    with pytest.raises(MeshVerificationError, match="not used"):
        check_conformity(quads, 8)
    # chord angles of a unit square are 90
    sq = np.array([0, 1, 1 + 1j, 1j])
    assert np.allclose(chord_angles(sq, np.array([[0, 1, 2, 3]])), 90.0)
