"""Tests of the right-pentagon tessellation T5 and the arc family I5 (paper §3, Lemma 2.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadmesh.disk.tessellation import (
    EDGE_CENTERS,
    EDGE_RADIUS,
    GROUP11,
    P0_VERTICES,
    REFLECTIONS,
    TWO_PI,
    L,
    arc_contains_arc,
    brute_force_i5_arcs,
    generate_tiles,
    locate,
    minimal_containing_arc,
    tile_edge_far_arcs,
)
from quadmesh.errors import DiskConstructionError
from quadmesh.hyperbolic import distance


def test_constants_of_p0() -> None:
    assert L == pytest.approx(1.0612750619, abs=1e-10)
    assert abs(P0_VERTICES[0]) == pytest.approx(0.397975, abs=1e-6)
    # the edge circle is orthogonal to T through the edge midpoint at Euclidean radius t:
    # |c| = (t + 1/t)/2, r = sqrt(|c|^2 - 1) = 1.49535 (DISK.md's 1.49863 is slightly off)
    assert EDGE_RADIUS == pytest.approx(1.495349, abs=1e-6)
    # each vertex lies on the circles of its two edges; sides have length L
    for k in range(5):
        for v in (P0_VERTICES[k], P0_VERTICES[(k + 1) % 5]):
            assert abs(abs(v - EDGE_CENTERS[k]) - EDGE_RADIUS) < 1e-14
        assert distance(P0_VERTICES[k], P0_VERTICES[(k + 1) % 5]) == pytest.approx(L, abs=1e-12)
    # the reflections are involutions fixing their edge pointwise
    for k in range(5):
        s = REFLECTIONS[k]
        z = np.array([0.1 + 0.2j, -0.3j])
        assert np.allclose(s(s(z)), z, atol=1e-14)
        assert np.allclose(s(P0_VERTICES[[k, (k + 1) % 5]]), P0_VERTICES[[k, (k + 1) % 5]])


def test_tile_counts_match_spec() -> None:
    assert len(generate_tiles(depth=1)[0]) == 6
    assert len(generate_tiles(depth=2)[0]) == 21  # P0, 5 + 15 tiles two reflections away
    tiles, nbr = generate_tiles(depth=6)
    assert len(tiles) == 1161  # DISK.md §2
    t_i, k_i = np.nonzero(nbr >= 0)
    back = nbr[nbr[t_i, k_i], k_i]
    expanded = back >= 0  # the outermost level is not expanded
    assert expanded.sum() > 1000
    assert np.all(back[expanded] == t_i[expanded])  # symmetric neighbour relation
    tiles, _ = generate_tiles(min_diameter=0.01)
    assert len(tiles) == 1996
    # distinct centres (deduplication works at every scale)
    c = tiles.apply_rows(np.zeros(1))[:, 0]
    d = distance(c[:, None], c[None, :]) + np.eye(c.size) * 10
    assert d.min() > 1.2


def test_group11_touches_p0() -> None:
    c = GROUP11.apply_rows(np.zeros(1))[:, 0]
    d = distance(0.0, c[1:])
    assert np.all(d < 2.0 * 0.842483 + 1e-6)
    assert len(np.unique(np.round(c, 9))) == 11


def test_point_location() -> None:
    rng = np.random.default_rng(3)
    r = 1.0 - 10.0 ** rng.uniform(-9, 0, 400)
    z = r * np.exp(1j * rng.uniform(0, TWO_PI, r.size))
    g = locate(z)
    w = g.inverse().apply_rows(z[:, None])[:, 0]
    assert np.all(np.abs(w[:, None] - EDGE_CENTERS[None, :]) >= EDGE_RADIUS - 1e-9)


def test_far_arcs_do_not_contain_the_tile() -> None:
    tiles, _ = generate_tiles(depth=3)
    s, ell = tile_edge_far_arcs(tiles)
    cen = tiles.apply_rows(np.zeros(1))[:, 0]
    # the far arc's midpoint direction and the tile centre are on opposite sides of the edge
    mid = np.exp(1j * (s + ell / 2))
    k = 2 * cen[:, None] / (1 + np.abs(cen[:, None]) ** 2)
    a, b = np.exp(1j * s), np.exp(1j * (s + ell))
    side_c = np.sign((np.conj(b - a) * (k - a)).imag)
    side_m = np.sign((np.conj(b - a) * (mid - a)).imag)
    assert np.all(side_c * side_m < 0)


def test_local_minimal_arc_equals_brute_force() -> None:
    tiles, _ = generate_tiles(min_diameter=0.01)
    bs, bl = brute_force_i5_arcs(tiles)
    rng = np.random.default_rng(0)
    s = rng.uniform(0, TWO_PI, 150)
    ell = np.exp(rng.uniform(math.log(0.03), math.log(0.5), 150))
    ms, ml, g, k = minimal_containing_arc(s, ell)
    ok = arc_contains_arc(bs[None, :], bl[None, :], s[:, None], ell[:, None])
    best = np.where(ok, bl[None, :], np.inf).min(axis=1)
    assert np.max(np.abs(best - ml)) < 1e-12
    assert np.all(arc_contains_arc(ms, ml, s, ell))
    # the returned tile edge carries the arc
    _fs, fl = tile_edge_far_arcs(g)
    assert np.allclose(fl[np.arange(150), k], ml, rtol=1e-9)


def test_minimal_arc_for_tiny_arcs() -> None:
    rng = np.random.default_rng(5)
    s = rng.uniform(0, TWO_PI, 40)
    ell = 10.0 ** rng.uniform(-11, -3, 40)
    ms, ml, _, _ = minimal_containing_arc(s, ell)
    assert np.all(arc_contains_arc(ms, ml, s, ell))
    ratio = ml / ell
    assert np.all(ratio >= 1.0) and np.all(ratio < 16.0)  # Lemma 2.1's constant c (13.5 measured)


def test_fast_minimal_arc_matches_long_double() -> None:
    """fast=True searches arcs of at least FAST_MIN_ARC in float64 and the shorter ones in long
    double: the minimal lengths agree with the long-double search to 1e-9 (relative), every
    result contains its arc, and the short arcs' results are the long double ones exactly."""
    from quadmesh.disk.tessellation import FAST_MIN_ARC

    rng = np.random.default_rng(11)
    s = rng.uniform(0, TWO_PI, 3000)
    ell = 10.0 ** rng.uniform(-9, -0.5, 3000)
    ms, ml, _, _ = minimal_containing_arc(s, ell)
    fs, fl, g, k = minimal_containing_arc(s, ell, fast=True)
    assert fs.dtype == np.float64 and fl.dtype == np.float64
    assert np.all(arc_contains_arc(fs, fl, s, ell))
    assert np.max(np.abs(fl - ml) / ml) < 1e-9
    short = ell < FAST_MIN_ARC
    assert 0 < short.sum() < len(ell)
    np.testing.assert_array_equal(fs[short], ms[short])
    np.testing.assert_array_equal(fl[short], ml[short])
    # the returned tile edge carries the arc
    _fs, far = tile_edge_far_arcs(g)
    np.testing.assert_allclose(far[np.arange(len(ell)), k], fl, rtol=1e-8)


def test_minimal_arc_rejects_huge_arc() -> None:
    with pytest.raises(DiskConstructionError):
        minimal_containing_arc(np.array([0.0]), np.array([3.0]))


@pytest.mark.parametrize("all_pairs", [0, 4096])
def test_tileset_batch_dedup_is_scale_invariant(
    all_pairs: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """add_batch merges repeats (within the batch and against stored tiles) at any scale and
    keeps distinct tiles apart, also for tiles of Euclidean size 1e-11 near T (through the
    bins, and comparing all pairs)."""
    from quadmesh.disk.tessellation import TileSet

    monkeypatch.setattr(TileSet, "_ALL_PAIRS", all_pairs)
    for r in (0.0, 0.9, 1.0 - 1e-11):
        c = r * np.exp(0.7j)
        g = locate(np.array([c]))
        nb = g[np.zeros(5, dtype=np.int64)] @ REFLECTIONS[np.arange(5)]
        z = nb.apply_rows(np.zeros(1))[:, 0]
        ts = TileSet()
        idx0, new0 = ts.add_batch(nb.M[:2], nb.sigma[:2], z[:2])
        assert new0.tolist() == [True, True] and idx0.tolist() == [0, 1]
        # the batch repeats tile 1 (perturbed relative to its size) and tile 3
        scale = 1.0 - abs(z[3])
        zz = np.array([z[1] + 1e-9 * scale, z[2], z[3], z[3] * (1 - 1e-9 * scale), z[4]])
        MM = nb.M[[1, 2, 3, 3, 4]]
        idx, new = ts.add_batch(MM, nb.sigma[[1, 2, 3, 3, 4]], zz)
        assert idx.tolist() == [1, 2, 3, 3, 4]
        assert new.tolist() == [False, True, True, False, True]
        assert len(ts) == 5
        assert ts.find(complex(z[4])) == 4


def test_tileset_all_pairs_same_tiles_as_bins(monkeypatch: pytest.MonkeyPatch) -> None:
    """Comparing every pair of tiles (small sets) and looking them up in the bins (large ones)
    store the same tiles in the same order with the same neighbours."""
    from quadmesh.disk.tessellation import TileSet

    out = []
    for all_pairs in (0, 10**9):
        monkeypatch.setattr(TileSet, "_ALL_PAIRS", all_pairs)
        out.append(generate_tiles(depth=6))
    (t0, n0), (t1, n1) = out
    assert len(t0) > 1000
    assert np.array_equal(t0.M, t1.M) and np.array_equal(t0.sigma, t1.sigma)
    assert np.array_equal(n0, n1)


def test_generate_tiles_neighbours_are_mutual() -> None:
    tiles, nbr = generate_tiles(depth=4)
    t, k = np.nonzero(nbr >= 0)
    back = nbr[nbr[t, k], k]
    expanded = back >= 0  # tiles of the last generation are not expanded
    assert expanded.sum() > 0.5 * t.size
    assert np.all(back[expanded] == t[expanded])  # σ_k fixes edge k: the relation is symmetric
    c = tiles.apply_rows(np.zeros(1))[:, 0]
    d = distance(c[:, None], c[None, :])
    np.fill_diagonal(d, np.inf)
    assert d.min() > 1.2  # no duplicate tiles (distinct centres are 2·R_M = 1.254 apart)


@pytest.mark.parametrize("dtype", [np.float64, np.longdouble])
def test_reduce_angle_is_np_mod_bit_for_bit(dtype: type) -> None:
    """_reduce_angle replaces np.mod(x, 2π) on (−2π, 2π): the same bits (also −0 → +0)."""
    from quadmesh.disk.tessellation import TWO_PI, TWO_PI_LD, _reduce_angle

    rng = np.random.default_rng(4)
    for two_pi in (TWO_PI, TWO_PI_LD):
        x = np.concatenate(
            [rng.uniform(-1, 1, 100_000) * TWO_PI, [-0.0, 0.0, -1e-300, 1e-300, -5e-324]]
        ).astype(dtype)
        x = np.append(x, np.nextafter(-two_pi, 0).astype(dtype))
        a, b = np.mod(x, two_pi), _reduce_angle(x, two_pi)
        assert a.dtype == b.dtype
        assert np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))


@pytest.mark.parametrize("fast", [False, True])
def test_minimal_containing_arc_of_a_batch_is_that_of_each_arc(fast: bool) -> None:
    """Every arc's search depends on that arc alone (the arc choice batches the rotations' and
    the cores' arcs, the cover batches the rotations' arcs): a batch gives each arc, bit for
    bit, what it gets alone (tiles shared by several arcs' samples included)."""
    rng = np.random.default_rng(12)
    s = rng.uniform(0, 2 * np.pi, 120)
    ell = np.exp(rng.uniform(np.log(1e-9), np.log(0.3), 120))
    bs, bl, bt, bk = minimal_containing_arc(s, ell, fast=fast)
    for i in range(0, 120, 7):
        one = minimal_containing_arc(s[i : i + 1], ell[i : i + 1], fast=fast)
        assert one[0][0] == bs[i] and one[1][0] == bl[i] and one[3][0] == bk[i]
        assert np.array_equal(one[2].M[0], bt.M[i]) and one[2].sigma[0] == bt.sigma[i]
