"""Tests of the parabolic thin-part mesh (quadmesh.thin.parabolic; THIN.md §A)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from quadmesh.errors import ThinPartError
from quadmesh.thin import KIND_NAMES, mesh2_local, mesh_vertex_sector, split_count
from quadmesh.thin.mesh import polygon_area, quad_angles_deg, quad_signed_areas, unpaired_edges

THETAS = [5, 15, 30, 45, 59, 60, 61, 90, 119, 120, 121, 150, 179, 181, 200, 239, 240, 241, 300, 359]
L_PENT = 1.0613  # side of the pentagon tessellation (hyperbolic length)
CONN = KIND_NAMES.index("connection")


def graded_u(n_side: int = 4, dstep: float = 0.25, dmax: float = math.log(32) + 2) -> np.ndarray:
    """Fractions u of theta of the vertices of a geodesic's image (from side 1).

    3*n_side+1 pentagon-edge vertices at hyperbolic distance s in [-1.5L, 1.5L] from the top
    point, rays at s = ±(1.5L + d_m), and the two ideal endpoints; u = 1/2 - arctan(sinh s)/π.
    """
    s_pent = np.linspace(1.5 * L_PENT, -1.5 * L_PENT, 3 * n_side + 1)
    d = np.arange(dstep, dmax + 1e-9, dstep)
    s = np.concatenate([(1.5 * L_PENT + d)[::-1], s_pent, -(1.5 * L_PENT + d)])
    return np.concatenate([[0.0], 0.5 - np.arctan(np.sinh(s)) / np.pi, [1.0]])


def uneven_u(n_pts: int, seed: float = 0.0) -> np.ndarray:
    """Smoothly uneven spacing (±30 %) of n_pts fractions from 0 to 1 (THIN.md sweep)."""
    k = np.arange(n_pts - 1)
    w = 1.0 + 0.3 * np.sin(2 * np.pi * 3 * k / (n_pts - 1) + 0.7 + seed)
    u = np.concatenate([[0.0], np.cumsum(w)])
    return u / u[-1]


def make_gamma(
    u: np.ndarray,
    theta: float,
    wobble: float = 0.02,
    rot_err: float = 0.01,
    phase: float = 0.3,
    apex: complex = 0.3 + 0.2j,
    d1: complex = complex(np.exp(0.7j)),
) -> np.ndarray:
    """Crosscut at polar fractions u with a smooth radial wobble and a rotation error.

    The wobble of log-radius is ``wobble`` for theta >= 90° and scales with theta below (the
    power map z^(theta/π) scales log-radius and angle alike, so the chord tilt is kept).
    """
    psi = theta * (u + rot_err * np.sin(np.pi * u))
    a = wobble * min(1.0, theta / (np.pi / 2))
    rad = 1.0 + a * np.sin(2 * np.pi * u + phase) + 0.5 * a * np.cos(3 * np.pi * u)
    g = apex + d1 * rad * np.exp(1j * psi)
    g[0] = apex + d1 * rad[0]
    g[-1] = apex + d1 * rad[-1] * np.exp(1j * theta)
    return g


def check_sector(mesh, apex: complex, g: np.ndarray) -> tuple[float, float, float]:
    """Assert the THIN.md mesh checks; return (area error, min new angle, max new angle)."""
    z, q = mesh.vertices, mesh.quads
    assert np.all(z[mesh.gamma_index] == g)
    free, ok = unpaired_edges(q)
    assert ok, "an edge is used twice with the same orientation"
    allowed = set()
    for chain in (mesh.side1, mesh.side2, mesh.gamma_index):
        for a, b in itertools.pairwise(chain):
            allowed |= {(int(a), int(b)), (int(b), int(a))}
    free_set = {tuple(e) for e in free.tolist()}
    assert free_set <= allowed
    assert len(free_set) == len(mesh.side1) + len(mesh.side2) + len(g) - 3
    assert mesh.side1[0] == mesh.apex_index == mesh.side2[0]
    assert mesh.side1[-1] == mesh.gamma_index[0] and mesh.side2[-1] == mesh.gamma_index[-1]
    for chain, end in ((mesh.side1, g[0]), (mesh.side2, g[-1])):
        w = (z[chain] - apex) / (end - apex)
        assert np.all(np.abs(w.imag) < 1e-12) and np.all(np.diff(w.real) > 0)
    areas = quad_signed_areas(z, q)
    assert areas.min() > 0
    region = polygon_area(np.concatenate([[apex], g]))
    err = abs(areas.sum() - region) / region
    assert err < 1e-12
    ang = quad_angles_deg(z, q)[mesh.new_angle_mask()]
    assert ang.min() >= 60.0 - 1e-7 and ang.max() <= 120.0 + 1e-7
    return err, float(ang.min()), float(ang.max())


@pytest.mark.parametrize("phi_deg", [0.5, 5.0, 15.0, 30.0, 45.0, 60.0])
def test_mesh2_angles_match_the_paper(phi_deg: float) -> None:
    phi = math.radians(phi_deg)
    loc = mesh2_local(phi)
    pts = loc["points"]
    names = list(pts)
    z = np.array([pts[n] for n in names])
    quads = np.array([[names.index(n) for n in q] for q in loc["quads"]])
    ang = quad_angles_deg(z, quads)
    th1, th2, th3 = 90 + phi_deg / 2, 120 - phi_deg, 90 - phi_deg / 4
    th4, th5 = 90 - phi_deg / 2, 90 + phi_deg / 2
    expected = [
        [th1, th1, th2, 60],
        [60, 60 + phi_deg, th2, 120],
        [60, 120, th5, th4],
        [120, 60 + phi_deg, th4, th4],
        [th5, 90, th3, th3],
        [90, th5, th3, th3],
    ]
    np.testing.assert_allclose(ang, expected, atol=1e-9)


def test_split_count() -> None:
    assert [split_count(math.radians(t)) for t in (5, 119.9, 120, 239.9, 240, 359)] == [
        1,
        1,
        2,
        2,
        3,
        3,
    ]


@pytest.mark.parametrize("theta_deg", THETAS)
def test_graded_crosscut(theta_deg: int) -> None:
    theta = math.radians(theta_deg)
    u = graded_u()
    g = make_gamma(u, theta)
    mesh = mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)
    check_sector(mesh, 0.3 + 0.2j, g)
    # the crosscut is graded down to ~5e-4 theta, so the tree goes deep near the sides
    assert 900 < len(mesh.quads) < 1600
    conn = mesh.angles_deg()[mesh.kind == CONN]
    assert 70.0 < conn.min() and conn.max() < 115.0


@pytest.mark.parametrize("n_pts", [13, 20, 40, 80])
def test_uneven_sweep(n_pts: int) -> None:
    for theta_deg in THETAS:
        theta = math.radians(theta_deg)
        g = make_gamma(uneven_u(n_pts), theta, rot_err=0.0)
        mesh = mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)
        check_sector(mesh, 0.3 + 0.2j, g)
        assert len(mesh.quads) < 12 * n_pts
        m = split_count(theta)
        # the apex angle is exempt exactly when m = 1
        assert mesh.exempt_apex == (m == 1)
        assert np.sum(mesh.kind == KIND_NAMES.index("mesh1")) == 3 * m


def test_forced_tree_uses_spiral_connection() -> None:
    # P = 4m + 1 leaves no freedom in the tree: the mismatch of ~13 deg between s_k and g_k
    # needs log-spiral chains through intermediate rings (straight segments reach 121.7 deg).
    theta = math.radians(359)
    g = make_gamma(uneven_u(13), theta, rot_err=0.0, apex=0j, d1=1.0)
    mesh = mesh_vertex_sector(0j, 1.0, theta, g)
    check_sector(mesh, 0j, g)
    assert np.sum(mesh.kind == CONN) > 12
    assert len(mesh.side1) > 6


def test_random_graded_crosscuts() -> None:
    rng = np.random.default_rng(7)
    for _ in range(25):
        theta = math.radians(rng.uniform(3.0, 359.5))
        u = graded_u(int(rng.integers(3, 7)), rng.uniform(0.1, 0.5), rng.uniform(4.0, 7.0))
        g = make_gamma(
            u, theta, rng.uniform(0, 0.02), rng.uniform(-0.03, 0.03), rng.uniform(0, 6), 0j, 1.0
        )
        check_sector(mesh_vertex_sector(0j, 1.0, theta, g), 0j, g)


def test_outer_vertices_follow_the_crosscut() -> None:
    theta = math.radians(90)
    g = make_gamma(graded_u(), theta, apex=0j, d1=1.0)
    mesh = mesh_vertex_sector(0j, 1.0, theta, g)
    conn = mesh.quads[mesh.kind == CONN]
    # first column of connection quads: (s_k, ., ., s_k+1); their angles follow g_k's
    s_k = mesh.vertices[conn[: len(g) - 1, 0]]
    mismatch = np.degrees(np.abs(np.angle(s_k) - np.angle(g[:-1])))
    assert mismatch.max() < 8.0
    assert mismatch[:15].max() < 0.5  # near side 1 the crosscut is graded: the tree follows


def test_refuses_too_few_vertices() -> None:
    theta = math.radians(200)
    g = make_gamma(np.linspace(0, 1, 8), theta)
    with pytest.raises(ThinPartError, match="at least 9"):
        mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)


def test_refuses_jagged_crosscut() -> None:
    theta = math.radians(90)
    u = np.linspace(0, 1, 30)
    g = np.exp(1j * theta * u) * (1 + 0.05 * (-1) ** np.arange(30))
    with pytest.raises(ThinPartError, match="tilted"):
        mesh_vertex_sector(0j, 1.0, theta, g)


def test_refuses_crosscut_off_the_side() -> None:
    theta = math.radians(90)
    g = np.exp(1j * theta * np.linspace(0, 1, 20))
    g[-1] *= np.exp(0.01j)
    with pytest.raises(ThinPartError, match="side 2"):
        mesh_vertex_sector(0j, 1.0, theta, g)


def test_refuses_too_coarse_crosscut() -> None:
    # N_side = 2 at theta = 343 deg: the crosscut's vertices are 57 deg apart at its top.
    theta = math.radians(343)
    g = make_gamma(graded_u(2, 0.35, 4.9), theta)
    with pytest.raises(ThinPartError, match="needs more vertices"):
        mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)
