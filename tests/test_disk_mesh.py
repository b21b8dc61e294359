"""Tests of the conforming quad mesh of W (Lemma 2.2 with Lemmas 4.1, 5.1, 6.1)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from quadmesh.disk.assembly import DiskMesh, disk_mesh
from quadmesh.disk.canonical import check_conformity, chord_angles, quad_signed_areas
from quadmesh.disk.carleson_triangle import model_triangle_mesh
from quadmesh.disk.demo import EXAMPLES
from quadmesh.errors import DiskConstructionError
from quadmesh.hyperbolic import mobius_apply, phi_inv


@pytest.fixture(scope="module", params=sorted(EXAMPLES))
def mesh(request: pytest.FixtureRequest) -> DiskMesh:
    iv, A = EXAMPLES[request.param]
    return disk_mesh(iv, A=A, n=2)


def _undirected_edges(quads: np.ndarray) -> np.ndarray:
    e = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    return np.unique(np.sort(e, axis=1), axis=0)


def test_conforming_and_euler(mesh: DiskMesh) -> None:
    V = mesh.vertices.size
    B = check_conformity(mesh.quads, V)  # interior edges in exactly 2 quads, opposite orientation
    E = _undirected_edges(mesh.quads).shape[0]
    assert V - E + mesh.quads.shape[0] == 1  # W is a closed topological disk
    gam = {tuple(sorted(p)) for g in mesh.gamma for p in itertools.pairwise(g)}
    on_t = mesh.on_circle[B[:, 0]] & mesh.on_circle[B[:, 1]]
    on_g = np.array([tuple(sorted(p)) in gam for p in B.tolist()])
    assert np.all(on_t | on_g)  # unpaired edges only on T or on the γ_j
    assert on_g.sum() == len(gam)  # every γ_j edge is a boundary edge


def test_orientation_and_ideal_points(mesh: DiskMesh) -> None:
    assert np.all(quad_signed_areas(mesh.vertices, mesh.quads) > 0)
    assert np.allclose(np.abs(mesh.vertices[mesh.on_circle]), 1.0, atol=1e-15)
    assert np.all(np.abs(mesh.vertices[~mesh.on_circle]) < 1.0)


def test_chord_angles(mesh: DiskMesh) -> None:
    ang = chord_angles(mesh.vertices, mesh.quads)
    outer = ~mesh.inner
    assert ang[outer].min() >= 60.0 and ang[outer].max() <= 120.0
    pent = mesh.kind == "pentagon"
    assert ang[pent].min() > 62.0 and ang[pent].max() < 113.0  # DISK.md §4: [62.5, 112.8]
    # inner triangles are placed linearly by the pipeline; the exact Möbius placement exceeds
    # 120° a little (DISK.md §7: up to 124°)
    assert ang[mesh.inner].max() < 135.0


def test_gamma_lists(mesh: DiskMesh) -> None:
    M = mesh.depths.size - 1
    R = mesh.pieces
    for j, g in enumerate(mesh.gamma):
        assert g.size == 3 * mesh.n_side + 1 + 2 * M + 2
        assert len(np.unique(g)) == g.size
        s, ell = R.J[j]
        assert mesh.vertices[g[0]] == pytest.approx(np.exp(1j * (s + ell)), abs=1e-12)
        assert mesh.vertices[g[-1]] == pytest.approx(np.exp(1j * s), abs=1e-12)
        assert mesh.on_circle[g[0]] and mesh.on_circle[g[-1]]
        assert not np.any(mesh.on_circle[g[1:-1]])
        # the vertices lie on γ_j: |z - c| = r for its circle
        a, b = np.exp(1j * s), np.exp(1j * (s + ell))
        c = 2 * (a + b) / abs(a + b) ** 2
        r = np.sqrt(abs(c) ** 2 - 1)
        assert np.allclose(np.abs(mesh.vertices[g] - c), r, atol=1e-9)


def test_quad_counts(mesh: DiskMesh) -> None:
    R = mesh.pieces
    n, M = mesh.n, mesh.depths.size - 1
    tri_q = model_triangle_mesh(mesh.depths, 1.0).quads.shape[0]
    assert np.sum(mesh.kind == "pentagon") == R.n_pentagons * 5 * n * n
    assert np.sum(mesh.kind == "carleson_quadrilateral") == len(R.quads) * 2 * n * (M + 1)
    assert np.sum(mesh.kind == "carleson_triangle") == len(R.triangles) * tri_q
    assert np.all(np.bincount(mesh.piece) > 0)
    # one byte per quad is stored; the names are decoded from it
    assert mesh.kind_code.dtype == np.uint8 and mesh.kind_code.shape == (len(mesh.quads),)


def test_triangle_maps(mesh: DiskMesh) -> None:
    for t in mesh.triangles[:5]:
        z1 = mobius_apply(t.tau_inv, t.inner_model)
        z2 = phi_inv(t.frame, mobius_apply(t.tau_local, t.inner_model))
        assert np.allclose(z1, mesh.vertices[t.inner_vertices], atol=1e-10)
        assert np.allclose(z2, mesh.vertices[t.inner_vertices], atol=1e-12)
        assert np.all(np.isin(t.inner_vertices, mesh.quads[mesh.inner]))


def _check_disk_mesh(D: DiskMesh) -> None:
    """Conforming, every quad positive (areas relative to each quad's first corner, so tiny
    quads near T keep their precision), every angle outside the inner triangles in [60, 120]."""
    check_conformity(D.quads, D.vertices.size)
    assert np.all(quad_signed_areas(D.vertices, D.quads) > 0)
    ang = chord_angles(D.vertices, D.quads)
    assert ang[~D.inner].min() >= 60.0 and ang[~D.inner].max() <= 120.0


def test_tiny_and_many_intervals() -> None:
    iv = np.array([[0.5, 3e-9], [0.5 + 2e-6, 1e-9], [3.0, 1e-7], [4.0, 0.01]])
    D = disk_mesh(iv, A=100.0, n=2)
    _check_disk_mesh(D)


def test_bad_arguments() -> None:
    with pytest.raises(DiskConstructionError):
        disk_mesh([[0.0, 0.1]])  # no A
    with pytest.raises(DiskConstructionError):
        disk_mesh([[0.0, 0.01]], A=16.0, n=0)


def _crowded_intervals(kmax: int, A: float = 16.0) -> np.ndarray:
    """Intervals like the thick piece of the example ``glyph_s``: prevertices accumulating
    geometrically (ratio 4) at 0 and at π from both sides, and arcs chosen as the pipeline does:
    J a tessellation arc around the prevertex of half-width about gap/200, I_j concentric with J of
    half-width |J|/(2·1.02·√A)."""
    from quadmesh.disk.tessellation import minimal_containing_arc

    k = np.arange(kmax + 1)
    off = 0.4 * 4.0 ** (-k)
    c = np.sort(np.concatenate([off, -off, np.pi + off, np.pi - off]))
    gap = np.minimum(np.diff(c, prepend=c[-1] - 2 * np.pi), np.diff(c, append=c[0] + 2 * np.pi))
    half = gap / 200.0
    js, jl, _, _ = minimal_containing_arc(np.mod(c - half, 2 * np.pi), 2 * half)
    hi = jl / (2.0 * 1.02 * np.sqrt(A))
    return np.column_stack([np.mod(js + jl / 2 - hi, 2 * np.pi), 2 * hi])


def test_crowded_intervals_regression_glyph_s() -> None:
    """Regression for glyph_s (``no pentagon edge found on γ_48``): its piece had 27 arcs of
    5e-16 … 2.5e-12 rad at angles 0 and π, below what float64 disk coordinates resolve.  Down to
    the resolution limit the construction works; below it fails with a clear message."""
    from quadmesh.disk.region import MIN_EXPANDED_ARC

    iv = _crowded_intervals(15)
    assert 4.0 * iv[:, 1].min() > MIN_EXPANDED_ARC and iv[:, 1].min() < 1e-10
    D = disk_mesh(iv, A=16.0, n=2, depth_step=0.25, inner_height=1.0, depth_growth=2.0)
    _check_disk_mesh(D)
    iv = _crowded_intervals(21)  # 4·min|I| = 3.5e-15 (kmax = 20 works: test_disk_precision)
    with pytest.raises(DiskConstructionError, match="resolution limit"):
        disk_mesh(iv, A=16.0, n=2)
