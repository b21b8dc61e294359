"""The issue-level thin-part API: quadmesh.thin.parabolic_mesh and channel_mesh."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.mesh import QuadMesh
from quadmesh.polygon import signed_area
from quadmesh.thin import channel_mesh, parabolic_mesh


def _check(verts: np.ndarray, quads: np.ndarray, boundary: np.ndarray, exempt_apex=None):
    mesh = QuadMesh(np.column_stack([verts.real, verts.imag]), quads)
    assert np.all(mesh.areas() > 0)
    assert float(np.sum(mesh.areas())) == pytest.approx(signed_area(boundary), rel=1e-12)
    ang = mesh.angles()
    mask = np.ones_like(ang, dtype=bool)
    if exempt_apex is not None:
        mask &= quads != exempt_apex
    slack = np.broadcast_to(mesh.angle_slack(), ang.shape)
    assert np.all(ang[mask] >= 60 - slack[mask]) and np.all(ang[mask] <= 120 + slack[mask])
    e = np.sort(np.stack([quads, np.roll(quads, -1, 1)], -1).reshape(-1, 2), 1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert set(counts.tolist()) <= {1, 2}


@pytest.mark.parametrize("theta_deg", [45.0, 90.0, 200.0, 300.0])
@pytest.mark.parametrize("offset", [0.0, 0.6])
def test_parabolic_mesh_round_and_tilted(theta_deg: float, offset: float) -> None:
    theta = np.radians(theta_deg)
    v = 2.0 + 1.0j
    # crosscut: image of a semicircle over (-(1-e), 1+e) under z -> z^(theta/pi)
    t = np.linspace(np.pi, 0.0, 41)
    c, r = offset, 1.0
    zeta = c + r * np.exp(1j * t)
    zeta[0], zeta[-1] = c - r, c + r
    w = (zeta.astype(complex)) ** (theta / np.pi)
    gamma = v + 0.1 * w[::-1]  # from side 1 (positive axis) to side 2
    gamma[0] = v + 0.1 * (c + r) ** (theta / np.pi)
    gamma[-1] = v + 0.1 * abs(c - r) ** (theta / np.pi) * np.exp(1j * theta)
    verts, quads = parabolic_mesh(v, gamma, theta)
    assert np.all(np.isin(gamma, verts))
    boundary = np.concatenate([[v], gamma])
    apex = int(np.flatnonzero(verts == v)[0])
    _check(verts, quads, boundary, exempt_apex=apex if theta_deg < 120 else None)


def test_channel_mesh_parallel_walls() -> None:
    y = 0.1 * (1 - np.cos(np.linspace(0, np.pi, 21))) / 2
    g1 = 0.0 + 1j * y
    g2 = 3.0 + 1j * y[::-1][::-1]
    verts, quads = channel_mesh(g1, g2)
    assert np.all(np.isin(g1, verts)) and np.all(np.isin(g2, verts))
    boundary = np.concatenate([g2, g1[::-1]])
    _check(verts, quads, boundary)
