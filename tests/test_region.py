"""Tests of Lemma 2.2 (region W and its pieces) and Lemma 2.3 (O(m) pieces)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadmesh.disk.demo import EXAMPLES, spread_intervals
from quadmesh.disk.region import (
    MIN_EXPANDED_ARC,
    RegionW,
    build_region,
    cover_count,
    cover_counts,
    crossing_check,
    in_W,
    piece_membership,
)
from quadmesh.disk.tessellation import TWO_PI, L, arc_contains_arc, arc_contains_point
from quadmesh.errors import DiskConstructionError
from quadmesh.hyperbolic import distance


@pytest.fixture(scope="module", params=sorted(EXAMPLES))
def region(request: pytest.FixtureRequest) -> RegionW:
    iv, A = EXAMPLES[request.param]
    return build_region(iv, A)


def test_hypotheses_are_checked() -> None:
    with pytest.raises(DiskConstructionError, match="A > 1"):
        build_region([[0.0, 0.1]], 1.0)
    with pytest.raises(DiskConstructionError, match="overlap"):
        build_region([[0.0, 0.1], [0.3, 0.1]], 4.0)
    with pytest.raises(DiskConstructionError, match=">= π"):
        build_region([[0.0, 1.0]], 4.0)
    with pytest.raises(DiskConstructionError, match="shape"):
        build_region([0.0, 1.0], 4.0)
    with pytest.raises(DiskConstructionError):  # J's of neighbours collide: A too small
        build_region([[0.0, 0.01], [0.25, 0.01]], 9.0)


def test_conclusion_1_J_contains_sqrtA_I(region: RegionW) -> None:
    iv, A = region.intervals, region.A
    sq = math.sqrt(A)
    c = iv[:, 0] + iv[:, 1] / 2
    assert np.all(
        arc_contains_arc(region.J[:, 0], region.J[:, 1], c - sq * iv[:, 1] / 2, sq * iv[:, 1])
    )
    assert np.all(region.lemma21_ratio >= 1.0) and np.all(region.lemma21_ratio < 16.0)


def test_cover_overlap_at_most_two_and_right_angles(region: RegionW) -> None:
    cov = region.cover
    C = len(cov)
    # every point of T lies in 1 or 2 cover arcs
    x = np.linspace(0, TWO_PI, 20001)[:-1] + 1e-7
    cnt = sum(arc_contains_point(c.start, c.length, x).astype(int) for c in cov)
    assert cnt.min() >= 1 and cnt.max() <= 2
    ang = crossing_check(region)
    assert np.allclose(ang, 90.0, atol=1e-7)
    # K arcs lie compactly in gaps of F = ∪J
    for c in cov:
        if c.kind == "K":
            for j in range(region.m):
                J = region.J[j]
                assert not arc_contains_point(c.start, c.length, J[0])
                assert not arc_contains_point(J[0], J[1], c.start)
    kinds = [c.kind for c in cov]
    assert kinds.count("J") == kinds.count("Jl") == kinds.count("Jr") == region.m
    # top segments are multiples of L
    for i in range(C):
        p, q = region.crossings[i - 1], region.crossings[i]
        d = float(distance(p, q))
        n_edges = len(region.cover_edges[i])
        assert d == pytest.approx(n_edges * L, abs=1e-7)


def test_conclusion_2_partition_of_W(region: RegionW) -> None:
    rng = np.random.default_rng(11)
    n = 20000
    z = np.sqrt(rng.uniform(0, 0.998**2, n)) * np.exp(1j * rng.uniform(0, TWO_PI, n))
    cnt, _ = piece_membership(region, z)
    w = in_W(region, z)
    assert w.sum() > 0.9 * n
    assert np.all(cnt[w] == 1)  # every sample of W in exactly one piece
    assert np.all(cnt[~w] == 0)  # nothing outside W covered


def test_conclusion_2_3_adjacency(region: RegionW) -> None:
    T = region.n_pentagons
    # each quad's top is a pentagon edge on its cover geodesic
    for q in region.quads:
        assert region.tile_edge_cover[q.pentagon, q.edge] == q.cover
        assert distance(q.u0, q.u1) == pytest.approx(L, abs=1e-9)
    # quads' sides: quads, triangles, or a γ_j; triangles only touch quads
    gamma_sides = np.zeros(region.m, int)
    for q in region.quads:
        for kind, idx in (q.left, q.right):
            assert kind in ("quad", "triangle", "gamma")
            if kind == "gamma":
                gamma_sides[idx] += 1
    assert np.all(gamma_sides == 2)  # (3): two quad side rays per γ_j ...
    for j in range(region.m):  # ... and three pentagon edges
        i = next(k for k, c in enumerate(region.cover) if c.kind == "J" and c.interval == j)
        assert len(region.cover_edges[i]) == 3
    for t in region.triangles:
        assert region.quads[t.left_quad].right == ("triangle", region.triangles.index(t))
        assert region.quads[t.right_quad].left == ("triangle", region.triangles.index(t))
    # pentagon neighbours are pentagons; an edge without a pentagon neighbour is on a cover arc
    free = region.tile_neighbour < 0
    assert np.all(region.tile_edge_cover[free] >= 0)
    assert np.all(region.tile_neighbour[~free] < T)


def test_tiny_intervals() -> None:
    iv = np.array([[0.5, 3e-9], [0.5 + 2e-6, 1e-9], [3.0, 1e-7]])
    R = build_region(iv, 100.0)
    assert np.allclose(crossing_check(R), 90.0, atol=1e-5)
    for q in R.quads:
        assert distance(q.u0, q.u1) == pytest.approx(L, abs=1e-6)
    assert R.n_pieces < 100 * R.m


def test_lemma_2_3_pieces_per_interval_bounded() -> None:
    per = []
    for m in (10, 30, 100):
        iv = spread_intervals(m, 1024.0, seed=m)
        R = build_region(iv, 1024.0)
        per.append(R.n_pieces / m)
    print("pieces per interval (m = 10, 30, 100):", per)
    assert max(per) < 60.0
    assert max(per) / min(per) < 1.5


def test_local_K_arcs_equal_brute_force_greedy(region: RegionW) -> None:
    """The K arcs found by the local tile growth are those of DISK.md's greedy run over *all*
    I5 arcs shorter than π of a fine global tessellation (10191 tiles, Euclidean diameter
    >= 0.002)."""
    from quadmesh.disk.tessellation import brute_force_i5_arcs, generate_tiles

    tiles, _ = generate_tiles(min_diameter=0.002)
    bs, bl = brute_force_i5_arcs(tiles)
    J = region.J[np.argsort(region.J[:, 0])]
    je = J[:, 0] + J[:, 1]
    m = J.shape[0]
    gl = np.mod(np.roll(J[:, 0], -1) - je, TWO_PI) if m > 1 else np.array([TWO_PI - J[0, 1]])
    n_k = 0
    for i, c in enumerate(region.cover):
        if c.kind != "K":
            continue
        prev = region.cover[i - 1]
        r = (prev.start + prev.length) % TWO_PI
        k = next(kk for kk in range(m) if 0 < (r - je[kk]) % TWO_PI < gl[kk])
        rel = np.mod(bs - je[k], TWO_PI)
        cont = (rel > 0) & (rel + bl < gl[k]) & (bl < np.pi) & arc_contains_point(bs, bl, r)
        best = np.flatnonzero(cont)[np.lexsort((-bl[cont], -(rel + bl)[cont]))[0]]
        assert bs[best] == pytest.approx(c.start, abs=1e-9)
        assert bl[best] == pytest.approx(c.length, abs=1e-9)
        n_k += 1
    assert n_k >= 4


@pytest.mark.parametrize("ell", [1e-3, 1e-5, 1e-8])
def test_single_small_interval_cover_arcs_shorter_than_pi(ell: float) -> None:
    """Regression: for one small interval the maximal I5 arc in the gap is almost all of T;
    choosing it as a K arc made the pentagon boundary fail to chain (or gave 'Carleson quads'
    covering most of D).  K arcs are now shorter than π and W contains 0."""
    R = build_region([[1.0, ell]], 16.0)
    assert all(c.length < math.pi for c in R.cover)
    assert np.allclose(crossing_check(R), 90.0, atol=1e-5)
    assert in_W(R, np.array([0.0]))[0]
    cnt, _ = piece_membership(R, np.array([0.0, 0.3 + 0.2j]))
    assert np.all(cnt == 1)


def test_resolution_limit_is_a_clear_error() -> None:
    with pytest.raises(DiskConstructionError, match=r"too small .* extended precision"):
        build_region([[1.0, 1e-3], [3.0, 0.5 * MIN_EXPANDED_ARC / 4.0]], 16.0)
    R = build_region([[1.0, 1e-3], [3.0, 1.01 * MIN_EXPANDED_ARC / 4.0]], 16.0)
    # the crossings are tile vertices, placed to ~1e-4 relative at this scale (long double)
    assert np.allclose(crossing_check(R), 90.0, atol=0.05)
    # top lengths from the long double tile vertices (q.u0/q.u1 are rounded to complex128)
    from quadmesh.disk.tessellation import P0_VERTICES_LD, phi_accurate

    p = np.array([q.pentagon for q in R.quads])
    k = np.array([q.edge for q in R.quads])
    g = R.tiles[p]
    u0 = g.apply_rows(P0_VERTICES_LD[k][:, None])[:, 0]
    u1 = g.apply_rows(P0_VERTICES_LD[(k + 1) % 5][:, None])[:, 0]
    rho = 2.0 * np.arctanh(np.abs(phi_accurate(u0, u1)).astype(float))
    assert np.allclose(rho, L, rtol=2e-3)


def test_cover_count_equals_built_cover_on_random_arcs() -> None:
    """cover_count (steps 1–3 of Lemma 2.2 only) is len(build_region(...).cover) on random arc
    sets of 1–16 arcs, sizes from 1e-7 rad up to what A allows; where build_region fails,
    cover_count fails too or build_region failed after the cover."""
    rng = np.random.default_rng(5)
    built = 0
    for trial in range(60):
        m = int(rng.integers(1, 17))
        A = float(rng.choice([4.0, 16.0, 64.0]))
        sp = 2.0 * np.pi / m
        c = np.arange(m) * sp + rng.uniform(-0.15, 0.15, m) * sp + rng.uniform(0, 2 * np.pi)
        ell = np.exp(rng.uniform(np.log(1e-7), np.log(min(sp, np.pi) / (A * 1.2)), m))
        iv = np.column_stack([np.mod(c - ell / 2.0, 2.0 * np.pi), ell])
        try:
            R = build_region(iv, A)
        except DiskConstructionError:
            try:
                cover_count(iv, A)
            except DiskConstructionError:
                continue
            continue  # the pentagons failed after the cover: nothing to compare
        assert cover_count(iv, A) == len(R.cover), trial
        built += 1
    assert built >= 40


def test_cover_counts_of_several_sets_equal_one_at_a_time() -> None:
    """cover_counts (the sets' searches, chains and growths done together) gives every set the
    count it has alone, None where that raises (here one set fails in validation, two in the
    chain checks)."""
    rng = np.random.default_rng(9)
    sets = []
    for _ in range(24):
        m = int(rng.integers(1, 17))
        sp = 2.0 * np.pi / m
        c = np.arange(m) * sp + rng.uniform(-0.3, 0.3, m) * sp + rng.uniform(0, 2 * np.pi)
        ell = np.exp(rng.uniform(np.log(1e-7), np.log(min(sp, np.pi) / 16.0), m))
        sets.append(np.column_stack([np.mod(c - ell / 2.0, 2.0 * np.pi), ell]))
    sets.insert(5, np.array([[1.0, 0.3]]))  # 16-fold longer than π: fails validation
    alone = []
    for iv in sets:
        try:
            alone.append(cover_count(iv, 16.0))
        except DiskConstructionError:
            alone.append(None)
    assert 0 < sum(a is None for a in alone) < len(sets) // 2
    assert cover_counts(sets, 16.0) == alone


def test_cover_stages_fall_back_to_one_set_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """A failure in a step the sets share (here Lemma 2.1's search, made to fail for one set)
    is charged to that set alone: the others get the covers they have alone."""
    import quadmesh.disk.region as region

    sets = [spread_intervals(m, 64.0, seed=m) for m in (3, 5, 8)]
    marker = float(sets[1][0, 0])
    search = region.minimal_containing_arc

    def failing(start: np.ndarray, length: np.ndarray, *args: object, **kwargs: object) -> tuple:
        centre = np.mod(
            np.asarray(start, dtype=float) + np.asarray(length, dtype=float) / 2, TWO_PI
        )
        if np.any(np.abs(centre - (marker + sets[1][0, 1] / 2)) < 1e-9):
            raise DiskConstructionError("no arc of I5 shorter than π contains arc 0")
        return search(start, length, *args, **kwargs)

    monkeypatch.setattr(region, "minimal_containing_arc", failing)
    out = region.cover_stages(sets, 64.0)
    assert isinstance(out[1], DiskConstructionError)
    monkeypatch.setattr(region, "minimal_containing_arc", search)
    for i in (0, 2):
        assert not isinstance(out[i], DiskConstructionError)
        assert out[i].count == cover_count(sets[i], 64.0)
