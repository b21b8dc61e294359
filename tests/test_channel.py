"""Tests of the hyperbolic thin-part mesh (quadmesh.thin.channel; THIN.md §B)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadmesh.errors import ThinPartError
from quadmesh.thin import Walls, default_crosscut_count, mesh_channel
from quadmesh.thin.mesh import polygon_area, quad_angles_deg, quad_signed_areas, unpaired_edges
from tests.helpers import chain_edges, graded_u, uneven_u

ORIGIN = 0.5 - 0.2j
DIR = complex(np.exp(0.4j))


def wedge_crosscuts(
    beta: float, ratio: float, u1: np.ndarray, u2: np.ndarray, wobble: float = 0.02
) -> tuple[np.ndarray, np.ndarray]:
    """Two near-circular crosscuts about ORIGIN at radii 1 and ``ratio``."""

    def arc(u: np.ndarray, r: float, phase: float) -> np.ndarray:
        a = wobble * min(1.0, beta / (np.pi / 2))
        z = ORIGIN + DIR * r * (1 + a * np.sin(2 * np.pi * u + phase)) * np.exp(1j * beta * u)
        z[-1] = ORIGIN + DIR * np.exp(1j * beta) * abs(z[-1] - ORIGIN)
        return z

    return arc(u1, 1.0, 0.3), arc(u2, ratio, 1.1)


def check_channel(mesh, g1: np.ndarray, g2: np.ndarray) -> tuple[float, float]:
    """Assert conformity, exact area and positive quads; return (min, max) angle."""
    z, q = mesh.vertices, mesh.quads
    assert np.all(z[mesh.gamma1_index] == g1) and np.all(z[mesh.gamma2_index] == g2)
    free, ok = unpaired_edges(q)
    assert ok
    allowed = chain_edges(mesh.wall1, mesh.wall2, mesh.gamma1_index, mesh.gamma2_index)
    assert {tuple(e) for e in free.tolist()} <= allowed
    assert len(free) == 2 * (len(g1) - 1) + 2 * (mesh.n_intermediate + 1)
    areas = quad_signed_areas(z, q)
    assert areas.min() > 0
    region = abs(polygon_area(np.concatenate([g1, g2[::-1]])))
    assert abs(areas.sum() - region) / region < 1e-12
    ang = quad_angles_deg(z, q)
    return float(ang.min()), float(ang.max())


@pytest.mark.parametrize("beta_deg", [5, 20, 45, 90, 135, 170])
def test_wedge_sweep(beta_deg: int) -> None:
    beta = math.radians(beta_deg)
    for ratio in (3.0, 10.0, 100.0):
        for n_pts in (5, 13, 40, 80):
            g1, g2 = wedge_crosscuts(beta, ratio, uneven_u(n_pts), uneven_u(n_pts, 1.0))
            gap = math.degrees(beta * max(np.diff(uneven_u(n_pts)).max(), 0))
            try:
                mesh = mesh_channel(g1, g2)
            except ThinPartError:
                # THIN.md §B: the bound needs crosscut gaps <~ 40 deg (P = 5, beta >= 135)
                assert gap > 40.0
                continue
            lo, hi = check_channel(mesh, g1, g2)
            assert 60.0 <= lo and hi <= 120.0
            if gap <= 25.0:
                assert 75.0 < lo and hi < 105.0


@pytest.mark.parametrize("width_ratio", [2.0, 5.0, 20.0])
def test_parallel_walls(width_ratio: float) -> None:
    origin, direction = 1 + 1j, complex(np.exp(0.3j))
    for n_pts in (5, 13, 40):
        y1, y2 = uneven_u(n_pts), uneven_u(n_pts, 1.0)
        g1 = origin + direction * (0.02 * np.sin(3 * y1) + 1j * y1)
        g2 = origin + direction * (width_ratio + 0.02 * np.cos(2 * y2) + 1j * y2)
        walls = Walls.parallel(origin, direction, 1.0)
        mesh = mesh_channel(g1, g2, walls=walls)
        lo, hi = check_channel(mesh, g1, g2)
        assert 80.0 < lo and hi < 100.0
        inferred = Walls.from_crosscuts(g1, g2)
        assert inferred.is_parallel and abs(inferred.width - 1.0) < 1e-12


def test_inferred_walls_match_explicit() -> None:
    beta = math.radians(70)
    g1, g2 = wedge_crosscuts(beta, 10.0, uneven_u(13), uneven_u(13, 1.0))
    walls = Walls.from_crosscuts(g1, g2)
    assert abs(walls.origin - ORIGIN) < 1e-12 and abs(walls.beta - beta) < 1e-12
    assert abs(walls.direction - DIR) < 1e-12
    a = mesh_channel(g1, g2)
    b = mesh_channel(g1, g2, walls=Walls.wedge(ORIGIN, DIR, beta))
    np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-12)


@pytest.mark.parametrize(
    ("beta_deg", "ratio", "j_default"), [(60, 10.0, 5), (90, 100.0, 8), (120, 100.0, 11)]
)
def test_intermediate_crosscuts_fix_skewed_distributions(
    beta_deg: int, ratio: float, j_default: int
) -> None:
    # gamma1 crowds towards wall 1, gamma2 towards wall 2: dy = beta/2 in the middle.
    beta = math.radians(beta_deg)
    u = np.linspace(0.0, 1.0, 21)
    g1, g2 = wedge_crosscuts(beta, ratio, u**2, 1 - (1 - u) ** 2)
    with pytest.raises(ThinPartError, match="outside"):
        mesh_channel(g1, g2, n_intermediate=0)
    mesh = mesh_channel(g1, g2)
    assert mesh.n_intermediate == j_default == default_crosscut_count(beta / 2)
    lo, hi = check_channel(mesh, g1, g2)
    assert 66.0 < lo and hi < 115.0


def test_graded_crosscuts() -> None:
    u = graded_u()
    for beta_deg in (5, 45, 90, 170):
        beta = math.radians(beta_deg)
        for ratio in (3.0, 10.0, 100.0):
            u1 = u + 0.01 * np.sin(np.pi * u)
            u2 = u - 0.01 * np.sin(np.pi * u)
            g1, g2 = wedge_crosscuts(beta, ratio, u1, u2)
            lo, hi = check_channel(mesh_channel(g1, g2), g1, g2)
            assert 79.0 < lo and hi < 105.0


def test_graded_against_uniform() -> None:
    # one crosscut graded, the other uniform: dy up to 0.25 beta
    beta = math.radians(45)
    u = graded_u()
    g1, g2 = wedge_crosscuts(beta, 100.0, u, np.linspace(0, 1, len(u)))
    mesh = mesh_channel(g1, g2)
    assert mesh.n_intermediate >= 1
    lo, hi = check_channel(mesh, g1, g2)
    assert 60.0 <= lo and hi <= 120.0


def test_bounded_geometry() -> None:
    beta = math.radians(45)
    g1, g2 = wedge_crosscuts(beta, 100.0, uneven_u(13), uneven_u(13, 1.0))
    mesh = mesh_channel(g1, g2, bounded_geometry=True)
    lo, hi = check_channel(mesh, g1, g2)
    assert 80.0 < lo and hi < 100.0
    z = mesh.vertices[mesh.quads]
    edges = np.abs(np.roll(z, -1, axis=1) - z)
    assert (edges.max(axis=1) / edges.min(axis=1)).max() < 2.5
    assert mesh.n_intermediate > 60


def test_refusals() -> None:
    beta = math.radians(45)
    g1, g2 = wedge_crosscuts(beta, 10.0, uneven_u(13), uneven_u(13, 1.0))
    with pytest.raises(ThinPartError, match="same number"):
        mesh_channel(g1, g2[:-1])
    with pytest.raises(ThinPartError, match="wall"):
        mesh_channel(g1, g2, walls=Walls.wedge(ORIGIN, DIR, beta * 1.01))
    with pytest.raises(ThinPartError, match="overlap"):
        mesh_channel(g1, g1 * 1.0000001 + 0 * g1)
    with pytest.raises(ThinPartError, match="limit"):
        mesh_channel(g1, g2, n_intermediate=10, max_intermediate=5)
