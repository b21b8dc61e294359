"""Helpers shared by several test modules (thin parts, I/O and CLI, rendering and the app)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from quadmesh.mesh import QuadMesh

L_PENT = 1.0613  # side of the pentagon tessellation (hyperbolic length)


def geodesic_arclengths(
    n_side: int = 4, dstep: float = 0.25, dmax: float = math.log(32) + 2
) -> np.ndarray:
    """Signed arclengths s (decreasing) of the finite vertices of a geodesic's image.

    3*n_side+1 pentagon-edge vertices at hyperbolic distance s in [-1.5L, 1.5L] from the top
    point and rays at s = ±(1.5L + d_m), d_m = dstep, 2 dstep, ... <= dmax.
    """
    s_pent = np.linspace(1.5 * L_PENT, -1.5 * L_PENT, 3 * n_side + 1)
    d = np.arange(dstep, dmax + 1e-9, dstep)
    return np.concatenate([(1.5 * L_PENT + d)[::-1], s_pent, -(1.5 * L_PENT + d)])


def graded_u(n_side: int = 4, dstep: float = 0.25, dmax: float = math.log(32) + 2) -> np.ndarray:
    """Fractions u of theta of the vertices of a geodesic's image (from side 1).

    The vertices at :func:`geodesic_arclengths` and the two ideal endpoints;
    u = 1/2 - arctan(sinh s)/π.
    """
    s = geodesic_arclengths(n_side, dstep, dmax)
    return np.concatenate([[0.0], 0.5 - np.arctan(np.sinh(s)) / np.pi, [1.0]])


def uneven_u(n_pts: int, seed: float = 0.0) -> np.ndarray:
    """Smoothly uneven spacing (±30 %) of n_pts fractions from 0 to 1 (THIN.md sweep)."""
    k = np.arange(n_pts - 1)
    w = 1.0 + 0.3 * np.sin(2 * np.pi * 3 * k / (n_pts - 1) + 0.7 + seed)
    u = np.concatenate([[0.0], np.cumsum(w)])
    return u / u[-1]


def chain_edges(*chains: np.ndarray) -> set[tuple[int, int]]:
    """Both orientations of every edge between consecutive vertices of the index chains."""
    allowed: set[tuple[int, int]] = set()
    for chain in chains:
        for a, b in itertools.pairwise(chain):
            allowed |= {(int(a), int(b)), (int(b), int(a))}
    return allowed


# ----------------------------------------------------------------------------- shared inputs
#: The L-shaped hexagon as an (n, 2) array and as complex points (counter-clockwise).
LSHAPE = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
L_SHAPE = np.array([0, 2, 2 + 1j, 1 + 1j, 1 + 2j, 2j])


def lshape_mesh() -> QuadMesh:
    """Three unit squares meshing :data:`LSHAPE`."""
    verts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1], [0, 2], [1, 2]], float)
    return QuadMesh(verts, np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6]]))


def require_pipeline() -> None:
    """Skip the calling test unless the whole pipeline (disk construction included) imports."""
    try:
        import quadmesh.disk as disk

        disk.disk_mesh  # noqa: B018
        from quadmesh.pipeline import mesh_polygon  # noqa: F401
    except (ImportError, AttributeError) as exc:
        pytest.skip(f"pipeline not available yet: {exc}")


def assert_map_checks(dm, tol: float = 1e-10) -> None:
    """The accuracy checks of CONFORMAL.md §1.7 for a solved DiskMap: residual, side error,
    centre error and boundary deviation below ``tol``, round trip below 1e-12."""
    acc = dm.accuracy()
    assert acc.residual < tol
    assert acc.side_error < tol
    assert acc.center_error < tol
    assert acc.boundary_deviation < tol
    assert acc.round_trip < 1e-12
