"""Transition cells (quadmesh.transition): a convex cell whose two opposite sides carry
different point counts, every angle in [60°, 120°].  Checked independently in plain numpy:
angles from the coordinates, conformity by edge counts, areas, the sides' points."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from quadmesh.cells import cell_is_admissible
from quadmesh.transition import (
    TransitionError,
    coarse_rows,
    fermat_point,
    max_pairs,
    pair_rows,
    plan_pairs,
    transition_cascade,
    transition_mesh,
)

TOL = 1e-6  # degrees: float64 rounding of rows down to 1e-6 of the cell, never more


def _angles(z: np.ndarray, quads: np.ndarray) -> np.ndarray:
    p = z[quads]
    nxt = np.roll(p, -1, axis=1) - p
    prv = np.roll(p, 1, axis=1) - p
    return np.degrees(np.angle(prv / nxt)) % 360.0


def _edge_counts(quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    return np.unique(np.sort(e, axis=1), axis=0, return_counts=True)


def _area(poly: np.ndarray) -> float:
    return 0.5 * float(np.imag(np.sum(np.conj(poly) * np.roll(poly, -1))))


def _check_mesh(tm, corners: np.ndarray, p_fine: np.ndarray) -> np.ndarray:
    """Angles in range, quads positive, areas adding up to the cell's, conforming with the
    cell's sides as its only free edges, the fine side's points as given; returns the ids of
    the boundary ring."""
    z, quads = tm.points, tm.quads
    a = _angles(z, quads)
    assert a.min() >= 60.0 - TOL and a.max() <= 120.0 + TOL
    p = z[quads]
    areas = 0.5 * np.imag(np.sum(np.conj(p) * np.roll(p, -1, axis=1), axis=1))
    assert areas.min() > 0
    assert abs(areas.sum() - _area(corners)) <= 1e-12 * abs(_area(corners))
    edges, cnt = _edge_counts(quads)
    assert cnt.max() == 2
    ring = np.concatenate([tm.wall0, tm.fine[1:], tm.wall1[::-1][1:], tm.coarse[::-1][1:-1]])
    bnd = np.sort(np.stack([ring, np.roll(ring, -1)], axis=1), axis=1)
    assert {tuple(e) for e in edges[cnt == 1]} == {tuple(e) for e in bnd}
    c0, c1, c2, c3 = corners
    assert np.allclose(z[tm.fine], c1 + p_fine * (c2 - c1), rtol=0, atol=1e-14)
    assert np.allclose(z[tm.coarse], c0 + tm.p_coarse * (c3 - c0), rtol=0, atol=1e-14)
    return ring


def _check(tm, corners: np.ndarray, p_fine: np.ndarray, pairs: np.ndarray) -> None:
    z, quads = tm.points, tm.quads
    a = _angles(z, quads)
    ring = _check_mesh(tm, corners, p_fine)
    # the coarse side carries the fine parameters without the split rows' middles
    pc, _ = coarse_rows(p_fine, pairs)
    assert np.array_equal(tm.p_coarse, pc)
    # one valence-3 interior vertex per split row, its three angles exactly 120°
    inner = np.setdiff1d(np.arange(z.size), ring)
    val = np.bincount(quads.ravel(), minlength=z.size)
    v3 = inner[val[inner] == 3]
    assert v3.size == 2 * pairs.size
    at_v3 = a[np.isin(quads, v3)]
    assert np.abs(at_v3 - 120.0).max() <= TOL


def test_fermat_point_sees_every_side_at_120_degrees():
    rng = np.random.default_rng(3)
    done = 0
    while done < 300:
        a, b, c = rng.normal(size=3) + 1j * rng.normal(size=3)
        ang = [
            abs(np.degrees(np.angle((y - x) / (w - x))))
            for x, y, w in ((a, b, c), (b, c, a), (c, a, b))
        ]
        if max(ang) >= 115 or min(ang) < 5:
            continue
        q = fermat_point(a, b, c)
        seen = [abs(np.degrees(np.angle((x - q) / (y - q)))) for x, y in ((a, b), (b, c), (c, a))]
        assert np.allclose(seen, 120.0, atol=1e-10)
        done += 1


def test_rectangle_sixteen_to_twenty_two_rows():
    corners = np.array([0, 4, 4 + 2j, 2j])
    p_fine = np.linspace(0.0, 1.0, 23)
    pairs = pair_rows(np.ones(22 - 6), 3)
    tm = transition_mesh(corners, p_fine, pairs, np.linspace(0, 1, 5))
    _check(tm, corners, p_fine, pairs)
    assert tm.margin >= 7.0  # the measured template: every other angle in [67.5°, 112.5°]
    assert tm.coarse.size == 17 and tm.fine.size == 23


def test_pairs_are_planned_apart_and_off_the_sides():
    rng = np.random.default_rng(0)
    for _ in range(50):
        kf = int(rng.integers(6, 90))
        p = np.r_[0.0, np.sort(rng.uniform(0, 1, kf - 1)), 1.0] ** rng.uniform(0.5, 2)
        pairs = plan_pairs(p, int(rng.integers(1, 12)))
        k = kf - 2 * pairs.size
        _, kinds = coarse_rows(p, pairs)
        assert len(kinds) == k and kinds[0] == "P" and kinds[-1] == "P"
        assert kinds.replace("P", "") == "FN" * pairs.size
        # two plain rows between pairs
        assert all(b - a >= 4 for a, b in itertools.pairwise(pairs))
        assert pairs.size <= max_pairs(k)
    with pytest.raises(ValueError):
        pair_rows(np.ones(7), 2)


def _random_cell(rng: np.random.Generator, lo: float, hi: float) -> np.ndarray:
    """A random convex cell of unit width and length in [lo, hi], corners jittered by up to a
    quarter, every corner in [61°, 119°]."""
    while True:
        length = rng.uniform(lo, hi)
        corners = np.array([0, length, length + 1j, 1j]) + (
            rng.uniform(-0.25, 0.25, 4) + 1j * rng.uniform(-0.25, 0.25, 4)
        )
        if cell_is_admissible(corners, 1.0):
            return corners


def test_random_convex_cells_sweep():
    """Random convex cells (corners in [61°, 119°]), 8–80 fine rows with any spacing, 1–6
    pairs: each either meshes with every angle in range or refuses with TransitionError; a
    large majority mesh."""
    rng = np.random.default_rng(7)
    ok = refused = 0
    while ok + refused < 60:
        corners = _random_cell(rng, 0.8, 8.0)
        kf = int(rng.integers(8, 80))
        if rng.random() < 0.3:
            inner = np.sort(rng.uniform(0, 1, kf - 1))
        else:
            inner = np.linspace(0, 1, kf + 1)[1:-1]
        p_fine = np.r_[0.0, inner, 1.0]
        if rng.random() < 0.5:
            p_fine = p_fine ** rng.uniform(0.5, 2.0)
        pairs = plan_pairs(p_fine, int(rng.integers(1, 7)))
        if pairs.size == 0:
            continue
        u = np.linspace(0, 1, int(rng.integers(2, 9)))
        try:
            tm = transition_mesh(corners, p_fine, pairs, u, at=rng.uniform(0.3, 0.7))
        except TransitionError as exc:
            assert "rows" in str(exc)
            refused += 1
            continue
        _check(tm, corners, p_fine, pairs)
        ok += 1
    print(f"transition sweep: {ok} meshed, {refused} refused")
    assert ok >= 45, (ok, refused)


def test_too_short_a_cell_is_refused_with_a_reason():
    corners = np.array([0, 0.5, 0.5 + 1j, 1j])
    p_fine = np.linspace(0, 1, 11)
    with pytest.raises(TransitionError, match="too short"):
        transition_mesh(corners, p_fine, pair_rows(np.ones(8), 1))


@pytest.mark.parametrize(
    ("length", "fine", "coarse", "grading"), [(4.0, 40, 10, 1.0), (4.0, 60, 20, 1.5)]
)
def test_cascade_goes_down_to_the_coarse_count(length, fine, coarse, grading):
    """Stages of pairs, each in its own slice of the cell, from ``fine`` rows down to exactly
    ``coarse``: conforming, areas exact, every angle in range, the sides' points as given."""
    corners = np.array([0, length, length + 1j, 1j])
    p_fine = np.linspace(0.0, 1.0, fine + 1) ** grading
    tm = transition_cascade(corners, p_fine, coarse, n_along=3)
    _check_mesh(tm, corners, p_fine)
    assert tm.coarse.size == coarse + 1 and tm.fine.size == fine + 1


def test_cascade_refuses_a_short_cell():
    corners = np.array([0, 1, 1 + 1j, 1j])
    with pytest.raises(TransitionError):
        transition_cascade(corners, np.linspace(0, 1, 41), 10)
    with pytest.raises(TransitionError, match="odd difference"):
        transition_cascade(np.array([0, 0.2, 0.2 + 1j, 1j]), np.linspace(0, 1, 12), 10)
    # partial: as far as it fits, the coarse side carrying what was reached
    tm = transition_cascade(corners, np.linspace(0, 1, 41), 10, partial=True)
    assert 10 < tm.coarse.size - 1 <= 40 and (40 - (tm.coarse.size - 1)) % 2 == 0


def _check_parity(tm, corners: np.ndarray, p_fine: np.ndarray) -> None:
    """A mesh whose fine side has one row more than its coarse side (odd difference): one
    wall (the one ``tm.parity`` names) carries one point more than the other, every point of
    both walls lies on the cell's straight side, and the rest is as for any transition."""
    _check_mesh(tm, corners, p_fine)
    c0, c1, c2, c3 = corners
    for ids, (a, b) in ((tm.wall0, (c0, c1)), (tm.wall1, (c3, c2))):
        t = (tm.points[ids] - a) / (b - a)
        assert np.abs(t.imag).max() <= 1e-12 and np.all(np.diff(t.real) > 0)
    low = tm.parity.count("low") - tm.parity.count("high")
    assert tm.wall0.size - tm.wall1.size == low and abs(low) == 1


@pytest.mark.parametrize("half", ["low", "high"])
def test_parity_row_in_random_convex_cells(half):
    """One split row whose shared line is a wall: the fine side carries one row more than the
    coarse side — random convex cells, 3–60 fine rows, any spacing; every cell either meshes
    with every angle in range (the valence-3 vertex's three angles exactly 120°) or refuses
    with TransitionError, and a large majority mesh."""
    rng = np.random.default_rng(11 if half == "low" else 12)
    ok = refused = 0
    while ok + refused < 60:
        corners = _random_cell(rng, 0.5, 6.0)
        kf = int(rng.integers(3, 60))
        p_fine = np.linspace(0, 1, kf + 1)
        if rng.random() < 0.5:
            p_fine = p_fine ** rng.uniform(0.7, 1.4)
        try:
            tm = transition_mesh(corners, p_fine, [], at=rng.uniform(0.3, 0.7), half=half)
        except TransitionError as exc:
            assert "rows" in str(exc)
            refused += 1
            continue
        _check_parity(tm, corners, p_fine)
        assert tm.parity == half and tm.coarse.size == kf
        inner = np.setdiff1d(
            np.arange(tm.points.size), np.r_[tm.wall0, tm.wall1, tm.coarse, tm.fine]
        )
        val = np.bincount(tm.quads.ravel(), minlength=tm.points.size)
        v3 = inner[val[inner] == 3]
        assert v3.size == 1
        assert np.abs(_angles(tm.points, tm.quads)[np.isin(tm.quads, v3)] - 120.0).max() <= TOL
        ok += 1
    print(f"parity rows ({half}): {ok} meshed, {refused} refused")
    assert ok >= 45, (ok, refused)


@pytest.mark.parametrize(
    ("length", "fine", "coarse", "grading"),
    [(4.0, 41, 10, 1.0), (4.0, 40, 11, 1.0), (4.0, 61, 20, 1.5), (2.0, 7, 6, 1.0)],
)
def test_cascade_meets_an_odd_difference(length, fine, coarse, grading):
    """A cascade whose two sides differ by an odd number of rows starts with a parity row:
    exactly ``coarse`` rows reached, one wall one point longer, everything else as usual."""
    corners = np.array([0, length, length + 1j, 1j])
    p_fine = np.linspace(0.0, 1.0, fine + 1) ** grading
    tm = transition_cascade(corners, p_fine, coarse, n_along=3)
    _check_parity(tm, corners, p_fine)
    assert tm.coarse.size == coarse + 1 and tm.fine.size == fine + 1


def test_parity_row_beside_irregular_rows_in_a_short_cell():
    """Points a mesh leaves on a cut: 200 rows graded towards both walls (10 times thinner
    there than in the middle) whose heights jump by up to 3× between neighbours, in a cell
    only 0.02–0.08 of its width long. The parity row at a wall is a few of that wall row's
    gaps long; evening out all the other rows within so short a slice folded it, so the row
    is built beside the rows as they are: one row fewer, every angle in range."""
    rng = np.random.default_rng(1)
    i = np.arange(200)
    h = (1.0 + np.minimum(i, 199 - i) / 10.0) * rng.uniform(1.0, 3.0, 200)
    p_fine = np.r_[0.0, np.cumsum(h)[:-1] / h.sum(), 1.0]
    for length in (0.02, 0.04, 0.08):
        corners = np.array([0, length, length + 1j, 1j])
        tm = transition_cascade(corners, p_fine, 199, partial=True)
        _check_parity(tm, corners, p_fine)
        assert tm.coarse.size == 200


def test_clustered_rows_are_evened_towards_equal_rows_on_request() -> None:
    # fine rows clustered as a mesh of the paper's construction puts them on a side: geometric
    # runs towards both ends and towards one point inside (neighbouring rows up to 14 times
    # apart); neighbour averaging leaves them clustered and no pair finds a place, evening
    # them towards equal rows first lets the cascade go down to a few rows in a 5 x 1 cell
    g = 0.002 * 1.35 ** np.arange(14)
    p = np.concatenate([g, 0.45 - g[::-1][:-1], 0.45 + g[1:], 1 - g[::-1]])
    p = np.unique(np.concatenate([[0.0], np.sort(p[(p > 0) & (p < 1)]), [1.0]]))
    cn = np.array([0, 5, 5 + 1j, 1j])
    smooth = transition_cascade(cn, p, 4, partial=True, budget=[16])
    uniform = transition_cascade(cn, p, 4, partial=True, budget=[16], even="uniform")
    assert len(p) - 1 == 55 and len(smooth.coarse) - 1 >= 50
    assert len(uniform.coarse) - 1 <= 10
    for tm in (smooth, uniform):
        a = _angles(tm.points, tm.quads)
        assert a.min() >= 60.0 - 1e-9 and a.max() <= 120.0 + 1e-9
        assert np.allclose(tm.points[tm.fine], cn[1] + p * (cn[2] - cn[1]), atol=1e-12)
    with pytest.raises(ValueError, match="even"):
        transition_cascade(cn, p, 4, even="flat")


def test_pairs_past_the_optimisation_budget_reuse_earlier_offsets_on_request() -> None:
    # a parallelogram skewed by 10°: the template misses the margin there, so every pair needs
    # its offsets optimised; with a budget of one optimisation the cascade stops at once, and
    # with ``reuse`` the later pairs take the first pair's offsets and the rows go on down
    d = np.exp(1j * np.radians(80.0))
    cn = np.array([0, 6, 6 + d, d])
    p = np.linspace(0, 1, 41)
    plain = transition_cascade(cn, p, 4, partial=True, budget=[1])
    reused = transition_cascade(cn, p, 4, partial=True, budget=[1], reuse=True)
    assert len(plain.coarse) - 1 == 40
    assert len(reused.coarse) - 1 <= 30
    a = _angles(reused.points, reused.quads)
    assert a.min() >= 60.0 - 1e-9 and a.max() <= 120.0 + 1e-9


@pytest.mark.parametrize("skew", [15.0, 25.0])
def test_a_skewed_cell_cascades_in_a_straightened_core(skew: float) -> None:
    # rows meeting the rungs 15°-25° off the perpendicular: no pair fits the plain cascade
    # (nor its optimisation); in a core whose rungs are perpendicular to the rows, between two
    # plain slices, the rows go from 40 down to a few; the mesh covers the cell exactly, its
    # sides carry the given points, and every angle is in range
    d = np.exp(1j * np.radians(90.0 - skew))
    cn = np.array([0, 6, 6 + d, d])
    p = np.linspace(0, 1, 41)
    plain = transition_cascade(cn, p, 4, partial=True, budget=[1000])
    tm = transition_cascade(cn, p, 4, partial=True, budget=[1000], straighten=True)
    assert len(plain.coarse) - 1 == 40 and len(tm.coarse) - 1 <= 8
    a = _angles(tm.points, tm.quads)
    assert a.min() >= 60.0 - 1e-9 and a.max() <= 120.0 + 1e-9
    e, cnt = _edge_counts(tm.quads)
    assert cnt.max() == 2
    area = sum(_area(tm.points[q]) for q in tm.quads)
    assert area > 0 and abs(area - _area(cn)) < 1e-12
    assert np.allclose(tm.points[tm.fine], cn[1] + p * (cn[2] - cn[1]), atol=1e-12)
    pc = tm.p_coarse
    assert np.allclose(tm.points[tm.coarse], cn[0] + pc * (cn[3] - cn[0]), atol=1e-12)
    # the boundary: the four sides' points and nothing else (edges in one quad only)
    bnd = set(map(tuple, e[cnt == 1].tolist()))
    ring = [tm.coarse, tm.wall0, tm.fine, tm.wall1]
    sides = {tuple(sorted(x)) for side in ring for x in zip(side[:-1].tolist(), side[1:].tolist())}
    assert bnd == sides
    # the walls run straight from corner to corner, with different points on each
    for w, a0, a1 in ((tm.wall0, cn[0], cn[1]), (tm.wall1, cn[3], cn[2])):
        z = tm.points[w]
        assert np.abs(((z - a0) * np.conj(a1 - a0)).imag).max() < 1e-12
