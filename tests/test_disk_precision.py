"""Precision of the disk construction for tiny arcs (Lemma 2.2 with extended-precision tiles).

Tiles are products of ~log(1/s) reflections; they, the I5 arcs and the frames of the Carleson
pieces are kept in long double so that the construction works down to ``√A·|I| = 5e-15``
(``region.MIN_EXPANDED_ARC``).  The complex128 mesh vertices cannot resolve cells of 1e-16 near
T, so the geometry is checked on ``frames[vertex_frame] + vertex_offset``.
"""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.disk.assembly import DiskMesh, disk_mesh
from quadmesh.disk.canonical import check_conformity
from quadmesh.disk.region import MIN_EXPANDED_ARC, build_region, crossing_check
from quadmesh.disk.tessellation import (
    P0_VERTICES,
    P0_VERTICES_LD,
    REFLECTIONS,
    locate,
    phi_accurate,
    tile_points,
)
from quadmesh.errors import DiskConstructionError
from quadmesh.hyperbolic import Isometry

A = 16.0


def _local_differences(D: DiskMesh) -> np.ndarray:
    """(Q, 4) vertex positions of every quad relative to its first corner, formed from the
    frame/offset representation (no cancellation for tiny quads)."""
    F = D.frames[D.vertex_frame[D.quads]]
    O = D.vertex_offset[D.quads]
    return (F - F[:, :1]).astype(np.complex128) + (O - O[:, :1])


def _local_angles(D: DiskMesh) -> np.ndarray:
    rel = _local_differences(D)
    a = np.roll(rel, 1, axis=1) - rel
    b = np.roll(rel, -1, axis=1) - rel
    return np.degrees(np.abs(np.angle(b / a)))


def _local_areas(D: DiskMesh) -> np.ndarray:
    rel = _local_differences(D)
    return 0.5 * np.sum((np.conj(rel) * np.roll(rel, -1, axis=1)).imag, axis=1)


def _euler(D: DiskMesh) -> int:
    e = np.stack([D.quads, np.roll(D.quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    E = np.unique(np.sort(e, axis=1), axis=0).shape[0]
    return D.vertices.size - E + D.quads.shape[0]


def _cluster(rng: np.random.Generator, target: float) -> np.ndarray:
    """Three intervals with ``√A·|I| >= target`` (one exactly), gaps 2.5–8 × the A-expansion."""
    ell = target / np.sqrt(A) * rng.uniform(1.0, 2.0, 3)
    ell[rng.integers(3)] = target / np.sqrt(A)
    c = [rng.uniform(0.0, 2 * np.pi)]
    for i in range(2):
        c.append(c[-1] + A * (ell[i] + ell[i + 1]) / 2 * rng.uniform(2.5, 8.0))
    c = np.array(c)
    return np.column_stack([np.mod(c - ell / 2, 2 * np.pi), ell])


@pytest.mark.parametrize("target", [1e-13, 1e-14, MIN_EXPANDED_ARC])
def test_tiny_arcs_mesh_is_exact_in_frames(target: float) -> None:
    """A single tiny interval next to a normal one, and a cluster of three tiny ones: the mesh
    is conforming, a closed disk, every quad positive, and all angles outside the inner
    triangles in [60°, 120°] (pentagons in DISK.md §4's [62.5°, 112.8°]) — as for large arcs."""
    rng = np.random.default_rng(7)
    for iv in (
        np.array([[rng.uniform(0, 6.0), target / np.sqrt(A)], [1.0, 1e-3]]),
        _cluster(rng, target),
    ):
        D = disk_mesh(iv, A=A, n=2)
        check_conformity(D.quads, D.vertices.size)
        assert _euler(D) == 1
        assert np.all(_local_areas(D) > 0)
        ang = _local_angles(D)
        assert ang[~D.inner].min() >= 60.0 and ang[~D.inner].max() <= 120.0
        pent = D.kind == "pentagon"
        assert ang[pent].min() > 62.0 and ang[pent].max() < 113.0
        # the complex128 vertices are the frame/offset sums rounded once
        exact = D.frames[D.vertex_frame] + D.vertex_offset
        assert np.max(np.abs(exact.astype(np.complex128) - D.vertices)) < 4e-16
        assert np.allclose(crossing_check(D.pieces), 90.0, atol=0.05)


def test_crowded_glyph_like_intervals_at_1e_14() -> None:
    """glyph_s-like prevertex crowding (ratio 4 at 0 and π) down to 4·min|I| = 1.1e-14: the
    region and the mesh are built and exact in the frame representation."""
    from test_disk_mesh import _crowded_intervals

    iv = _crowded_intervals(20)
    assert 4.0 * iv[:, 1].min() < 2e-14
    D = disk_mesh(iv, A=A, n=2, depth_step=0.25, inner_height=1.0, depth_growth=2.0)
    check_conformity(D.quads, D.vertices.size)
    assert _euler(D) == 1
    assert np.all(_local_areas(D) > 0)
    ang = _local_angles(D)
    assert ang[~D.inner].min() >= 60.0 and ang[~D.inner].max() <= 120.0


def test_resolution_limit() -> None:
    with pytest.raises(DiskConstructionError, match="resolution limit"):
        build_region([[1.0, 1e-3], [3.0, 0.5 * MIN_EXPANDED_ARC / 4.0]], A)
    R = build_region([[1.0, 1e-3], [3.0, 1.01 * MIN_EXPANDED_ARC / 4.0]], A)
    assert np.allclose(crossing_check(R), 90.0, atol=0.05)


def test_isometries_keep_extended_precision() -> None:
    """clongdouble matrices stay clongdouble through composition, inversion and application;
    complex128 ones stay complex128."""
    g = REFLECTIONS[0] @ REFLECTIONS[2]
    assert g.M.dtype == np.clongdouble
    assert g.inverse().M.dtype == np.clongdouble
    assert g(np.array([0.1 + 0.1j])).dtype == np.clongdouble
    h = Isometry(np.eye(2), False)
    assert (h @ h).M.dtype == np.complex128
    assert h(np.array([0.1j])).dtype == np.complex128


def test_reflections_exact_to_long_double() -> None:
    """σ_k is an involution fixing edge k's vertices to long double accuracy (an error δ in σ_k
    would move a tile n reflections deep by δ·e^n relative to its size)."""
    z = np.array([0.1 + 0.2j, -0.3, 0.25j], dtype=np.clongdouble)
    for k in range(5):
        s = REFLECTIONS[k]
        assert np.max(np.abs(s(s(z)) - z)) < 1e-18
        for v in (P0_VERTICES_LD[k], P0_VERTICES_LD[(k + 1) % 5]):
            assert abs(s(v) - v) < 1e-18
        det = s.M[0, 0] * s.M[1, 1] - s.M[0, 1] * s.M[1, 0]
        assert abs(det - 1) < 1e-18


def test_deep_tiles_are_accurate() -> None:
    """A point 1e-15 from T: the located tile (≈ 35 reflections deep) contains it, and
    tile_points (float64 offsets from the long double centre) agree with the long double
    isometry to the complex128 rounding, i.e. to ~1e-1 of the tile's own size 1e-15·(const)."""
    z = np.exp(1j * np.array([0.7, 2.0, 3.14159])) * (1 - np.array([1e-15, 3e-15, 1e-14]))
    g = locate(z.astype(np.clongdouble))
    w = g.inverse().apply_rows(z.astype(np.clongdouble)[:, None])[:, 0]
    assert np.all(np.abs(w) < 0.45)  # inside (a neighbourhood of) P0
    ref = g.apply_rows(P0_VERTICES_LD)
    fast = tile_points(g, P0_VERTICES)
    assert np.max(np.abs(fast - ref.astype(np.complex128))) < 3e-16
    # the tile's own geometry is right: its vertices in the frame of its first vertex
    loc = phi_accurate(ref[:, :1], ref).astype(np.complex128)
    side = np.abs(np.diff(loc, axis=1))
    assert np.all(side > 0.05) and np.all(side < 1.0)


def test_offsets_from_piece_centres() -> None:
    """Vertices relative to their piece centre (what a series about the centre needs) are
    accurate at 1e-14 and of the size of the piece (within a few ``1 − |centre|``)."""
    iv = np.array([[2.0, 1e-14 / np.sqrt(A)], [4.0, 1e-3]])
    D = disk_mesh(iv, A=A, n=2)
    c = D.piece_center_ld[D.vertex_piece]
    t = D.offsets_from(c)
    ref = (D.exact_vertices() - c).astype(np.complex128)
    scale = (1 - np.abs(c)).astype(float)
    # float64 offsets are exact to ~eps of the local scale; ref carries long double rounding
    assert np.all(np.abs(t - ref) <= 1e-15 * scale + 1e-18)
    ratio = np.abs(t) / scale
    assert ratio.max() < 10.0
    tiny = scale < 1e-13
    assert tiny.sum() > 100  # many vertices belong to pieces at the 1e-14 scale
    # the rounded complex128 vertices are off by ~1e-16, i.e. up to ~1 % of those pieces
    assert np.all(np.abs(D.vertices - D.piece_center[D.vertex_piece] - t)[tiny] < 1e-15)
