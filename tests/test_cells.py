"""Cells: bilinear grids of admissible quadrilaterals and the refinement of coarse layouts.

The angle sweep checks the fact the cell framework rests on (every grid angle of a bilinear grid
lies between the corner angles and their supplements); the layout tests check conformity, area,
angles and the chord structure with plain numpy, independent of the module's own helpers.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from quadmesh.cells import (
    bilinear_points,
    cell_angles,
    cell_is_admissible,
    check_layout,
    layout_chords,
    layout_problems,
    refine_layout,
)

# --------------------------------------------------------------------------- independent helpers


def corner_angles(c: np.ndarray) -> np.ndarray:
    """Interior angles (degrees) of counter-clockwise quads ``c (..., 4)`` from real arithmetic:
    the counter-clockwise angle from the side to the next corner to the side to the previous."""
    x, y = c.real, c.imag
    ax = np.roll(x, -1, axis=-1) - x
    ay = np.roll(y, -1, axis=-1) - y
    bx = np.roll(x, 1, axis=-1) - x
    by = np.roll(y, 1, axis=-1) - y
    ang = np.degrees(np.arctan2(ax * by - ay * bx, ax * bx + ay * by))
    return np.where(ang < 0, ang + 360.0, ang)


def shoelace(c: np.ndarray) -> np.ndarray:
    """Signed areas of polygons ``c (..., n)`` (relative to the first corner)."""
    d = c - c[..., :1]
    return 0.5 * np.sum((np.conj(d) * np.roll(d, -1, axis=-1)).imag, axis=-1)


def grid_quads(p: np.ndarray) -> np.ndarray:
    """Quads ``(..., m, k, 4)`` of a point grid ``(..., m + 1, k + 1)``, counter-clockwise."""
    return np.stack([p[..., :-1, :-1], p[..., :-1, 1:], p[..., 1:, 1:], p[..., 1:, :-1]], axis=-1)


def random_admissible_quads(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` random convex counter-clockwise quads (complex, (n, 4)) with corners in [60°, 120°].

    Corner angles 60° + 120°·w (w Dirichlet, rejected above 60° of excess; about a tenth of them
    exact 60/120 rhombi, trapezoids and rectangles), two random side lengths, the other two
    solved for closure; random rotation and scale, centred near the origin."""
    out: list[np.ndarray] = []
    total = 0
    special = np.array(
        [[0, 60, 0, 60], [0, 0, 60, 60], [30, 30, 30, 30], [60, 0, 60, 0], [0, 30, 60, 30]],
        dtype=float,
    )
    while total < n:
        m = 4 * n
        alpha = rng.choice([0.25, 1.0, 4.0], size=m)[:, None]
        w = rng.gamma(alpha, size=(m, 4))
        excess = 120.0 * w / w.sum(axis=1, keepdims=True)
        pick = rng.random(m) < 0.1
        excess[pick] = np.roll(special[rng.integers(0, len(special), pick.sum())], 1, axis=1)
        excess = excess[excess.max(axis=1) <= 60.0]
        theta = np.radians(60.0 + excess)
        turn = np.pi - theta  # exterior turn at corners 1, 2, 3 (corner 0 closes)
        phi = rng.uniform(0, 2 * np.pi, len(theta))[:, None] + np.concatenate(
            [np.zeros((len(theta), 1)), np.cumsum(turn[:, 1:], axis=1)], axis=1
        )
        u = np.exp(1j * phi)
        ln = np.exp(rng.uniform(np.log(0.1), 0.0, size=(len(theta), 2)))
        r = -(ln[:, 0] * u[:, 0] + ln[:, 1] * u[:, 1])

        def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            return (np.conj(a) * b).imag

        det = cross(u[:, 2], u[:, 3])
        l2 = cross(r, u[:, 3]) / det
        l3 = cross(u[:, 2], r) / det
        ok = (l2 > 0.1) & (l3 > 0.1) & (l2 < 3.0) & (l3 < 3.0)
        lens = np.stack([ln[:, 0], ln[:, 1], l2, l3], axis=1)[ok]
        steps = lens * u[ok]
        c = np.concatenate([np.zeros((len(steps), 1)), np.cumsum(steps[:, :3], axis=1)], axis=1)
        c = (c - c.mean(axis=1, keepdims=True)) * np.exp(rng.uniform(-0.7, 0.7, (len(c), 1)))
        out.append(c)
        total += len(c)
    return np.concatenate(out)[:n]


def random_spacings(rng: np.random.Generator, n: int, k: int) -> np.ndarray:
    """``n`` strictly increasing parameter lists ``(n, k + 1)`` from exactly 0 to exactly 1.

    Kinds: uniform; random steps; geometric with a 1e-3 ratio between the extreme steps (either
    end); steps log-uniform in [1e-3, 1]; graded towards both ends (1e-3)."""
    if k == 1:
        return np.tile([0.0, 1.0], (n, 1))
    i = np.arange(k, dtype=float)
    kind = rng.integers(0, 5, n)[:, None]
    geo = (1e-3) ** (i / (k - 1))
    both = (1e-3) ** (np.abs(i - (k - 1) / 2) / ((k - 1) / 2))[::-1] if k > 2 else np.ones(k)
    steps = np.select(
        [kind == 0, kind == 1, kind == 2, kind == 3, kind == 4],
        [
            np.ones((n, k)),
            rng.uniform(0.05, 1.0, (n, k)),
            np.where(rng.random((n, 1)) < 0.5, geo, geo[::-1]),
            np.exp(rng.uniform(np.log(1e-3), 0.0, (n, k))),
            np.broadcast_to(both, (n, k)),
        ],
    )
    x = np.concatenate([np.zeros((n, 1)), np.cumsum(steps, axis=1)], axis=1)
    x /= x[:, -1:]
    x[:, -1] = 1.0
    return x


# --------------------------------------------------------------------------- single cells


def test_bilinear_points_formula_and_orientation() -> None:
    c = np.array([0.0, 2.0, 2.5 + 1.5j, 0.3 + 1.0j])
    s = np.array([0.0, 0.2, 0.7, 1.0])
    t = np.array([0.0, 0.5, 1.0])
    p = bilinear_points(c, s, t)
    assert p.shape == (3, 4)
    S, T = np.meshgrid(s, t)
    ref = (1 - S) * (1 - T) * c[0] + S * (1 - T) * c[1] + S * T * c[2] + (1 - S) * T * c[3]
    assert np.allclose(p, ref, rtol=0, atol=1e-15)
    assert (p[0, 0], p[0, -1], p[-1, -1], p[-1, 0]) == tuple(c)
    assert np.all(shoelace(grid_quads(p)) > 0)
    with pytest.raises(ValueError, match="increasing"):
        bilinear_points(c, [0.0, 0.6, 0.4, 1.0], t)
    with pytest.raises(ValueError, match="exactly 0"):
        bilinear_points(c, [0.1, 1.0], t)


def test_cell_angles_and_admissibility() -> None:
    sq = np.array([0, 1, 1 + 1j, 1j])
    rhombus = np.array([0, 1, 1.5 + np.sqrt(3) / 2 * 1j, 0.5 + np.sqrt(3) / 2 * 1j])
    kite59 = np.array([0, 1, 1 + 1j, np.exp(1j * np.radians(59.0))])  # 59° at corner 0
    cells = np.stack([sq, rhombus, sq[::-1], kite59, np.array([0, 2, 1 + 0.2j, 2j])])
    ang = cell_angles(cells)
    assert np.allclose(ang[0], 90.0) and np.allclose(ang[1], [60, 120, 60, 120])
    assert np.allclose(ang, corner_angles(cells))
    assert cell_is_admissible(cells).tolist() == [True, True, False, False, False]
    assert cell_is_admissible(cells, margin_deg=1.0).tolist() == [True, False, False, False, False]
    assert np.allclose(ang[3, 0], 59.0)
    assert not cell_is_admissible(np.array([0, 1, 1, 1j]))  # zero-length side


def test_grid_angle_sweep() -> None:
    """50,000 random admissible cells, random k, m in 1..12, random graded spacings: every grid
    angle lies in [min, max] of the corner angles and their supplements, hence in [60°, 120°]."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(20240601)
    n = 50_000
    corners = random_admissible_quads(rng, n)
    # the exact 60°/120° shapes come out of the construction within ~1e-13° of their angles
    assert np.all(cell_is_admissible(corners, margin_deg=-1e-11))
    theta = corner_angles(corners)
    assert np.all((theta > 60 - 1e-9) & (theta < 120 + 1e-9))
    both = np.concatenate([theta, 180.0 - theta], axis=1)
    lo_bound, hi_bound = both.min(axis=1), both.max(axis=1)
    km = rng.integers(1, 13, size=(n, 2))
    lo_seen, hi_seen, worst_out, n_angles = 180.0, 0.0, -np.inf, 0
    for k in range(1, 13):
        for m in range(1, 13):
            g = np.nonzero((km[:, 0] == k) & (km[:, 1] == m))[0]
            if len(g) == 0:
                continue
            s = random_spacings(rng, len(g), k)
            t = random_spacings(rng, len(g), m)
            p = bilinear_points(corners[g], s, t)
            assert p.shape == (len(g), m + 1, k + 1)
            ang = corner_angles(grid_quads(p)).reshape(len(g), -1)
            n_angles += ang.size
            lo_seen = min(lo_seen, float(ang.min()))
            hi_seen = max(hi_seen, float(ang.max()))
            out = np.maximum(lo_bound[g, None] - ang, ang - hi_bound[g, None])
            worst_out = max(worst_out, float(out.max()))
    elapsed = time.perf_counter() - t0
    print(
        f"\nsweep: {n} cells, {n_angles} grid angles in [{lo_seen:.12f}, {hi_seen:.12f}] deg, "
        f"largest excursion beyond the corner/supplement range {worst_out:.3g} deg, {elapsed:.2f} s"
    )
    assert lo_seen >= 60.0 - 1e-9 and hi_seen <= 120.0 + 1e-9
    assert worst_out <= 1e-9
    assert n_angles > 8_000_000


# --------------------------------------------------------------------------- layouts


def check_refined(
    vertices: np.ndarray,
    cells: np.ndarray,
    points: np.ndarray,
    quads: np.ndarray,
    angle_range: tuple[float, float] = (60.0, 120.0),
) -> dict[tuple[int, int], int]:
    """Independent checks of a refined layout; returns the segment count of every coarse edge.

    Conformity (each undirected edge in one or two quads, opposite directions when two), every
    point used, quads counter-clockwise convex with angles in range, total area equal to the
    layout's, coarse vertices first, the fine boundary exactly subdividing the coarse boundary,
    and opposite sides of each coarse cell split into the same number of segments."""
    V = len(vertices)
    assert np.array_equal(points[:V], vertices)
    assert np.all(np.isin(np.arange(len(points)), quads))
    # conformity
    d = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    n = len(points)
    _u, dcnt = np.unique(d[:, 0] * n + d[:, 1], return_counts=True)
    assert dcnt.max() == 1, "a directed edge is used twice"
    und = np.sort(d, axis=1)
    uu, ucnt = np.unique(und[:, 0] * n + und[:, 1], return_counts=True)
    assert ucnt.max() <= 2
    # angles, convexity, area
    cq = points[quads]
    ang = corner_angles(cq)
    assert np.all(ang < 180.0)
    assert ang.min() >= angle_range[0] - 1e-9 and ang.max() <= angle_range[1] + 1e-9
    area = shoelace(cq)
    assert np.all(area > 0)
    layout_area = shoelace(vertices[cells]).sum()
    assert abs(area.sum() - layout_area) <= 1e-12 * abs(layout_area)
    # coarse edges: count fine points lying on each coarse segment
    scale = np.abs(vertices - vertices.mean()).max()
    seg_count: dict[tuple[int, int], int] = {}
    for c in cells:
        for a, b in zip(c, np.roll(c, -1)):
            za, zb = vertices[a], vertices[b]
            w = (points - za) / (zb - za)
            on = (np.abs(w.imag) * abs(zb - za) < 1e-12 * scale) & (w.real > -1e-12)
            on &= w.real < 1 + 1e-12
            seg_count[(int(a), int(b))] = int(on.sum()) - 1
    for c in cells:
        e = [seg_count[(int(c[i]), int(c[(i + 1) % 4]))] for i in range(4)]
        assert e[0] == e[2] and e[1] == e[3], f"cell {c.tolist()} sides split {e}"
        assert min(e) >= 1
    # quads per cell
    ks = [seg_count[(int(c[0]), int(c[1]))] * seg_count[(int(c[1]), int(c[2]))] for c in cells]
    assert len(quads) == sum(ks)
    # boundary: fine boundary edges chain along each coarse boundary edge from a to b
    bnd = d[np.isin(und[:, 0] * n + und[:, 1], uu[ucnt == 1])]
    nxt = dict(zip(bnd[:, 0].tolist(), bnd[:, 1].tolist()))
    assert len(nxt) == len(bnd), "boundary passes a vertex twice"
    cd = np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1).reshape(-1, 2)
    cs = np.sort(cd, axis=1)
    _cu, cinv, ccnt = np.unique(cs[:, 0] * V + cs[:, 1], return_inverse=True, return_counts=True)
    coarse_bnd = cd[ccnt[cinv] == 1]
    used = 0
    for a, b in coarse_bnd.tolist():
        cur, steps, last = a, 0, 0.0
        while cur != b:
            cur = nxt[cur]
            steps += 1
            w = (points[cur] - vertices[a]) / (vertices[b] - vertices[a])
            assert abs(w.imag) < 1e-12 and w.real > last, "boundary leaves the coarse edge"
            last = w.real
        assert steps == seg_count[(a, b)]
        used += steps
    assert used == len(bnd), "fine boundary edges off the coarse boundary"
    return seg_count


def l_shape() -> tuple[np.ndarray, np.ndarray]:
    v = np.array([0, 1, 2, 2 + 1j, 1 + 1j, 1j, 1 + 2j, 2j], dtype=complex)
    return v, np.array([[0, 1, 4, 5], [1, 2, 3, 4], [5, 4, 6, 7]])


def hexagon() -> tuple[np.ndarray, np.ndarray]:
    v = np.exp(1j * np.pi / 3 * np.arange(6)) * 3.0 + (1 - 2j)
    return v, np.array([[0, 1, 2, 3], [3, 4, 5, 0]])


def perturbed_grid(seed: int = 7, rows: int = 2, cols: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    r, c = np.mgrid[0 : rows + 1, 0 : cols + 1]
    base = (c * 1.0 + 1j * r * 1.3).ravel()
    corner = np.array([0, 1, cols + 2, cols + 1])
    cells = np.array([i * (cols + 1) + j + corner for i in range(rows) for j in range(cols)])
    for _ in range(1000):
        v = base + 0.22 * (rng.standard_normal(len(base)) + 1j * rng.standard_normal(len(base)))
        if np.all(cell_is_admissible(v[cells], margin_deg=1.0)):
            return v, cells
    raise AssertionError("no admissible perturbation found")


def hex_ring() -> tuple[np.ndarray, np.ndarray]:
    """Six 60°/120° trapezoids between two concentric hexagons: every radial edge is on one
    closed chord."""
    w = np.exp(1j * np.pi / 3 * np.arange(6))
    v = np.concatenate([w, 2.5 * w])
    cells = np.array([[i, 6 + i, 6 + (i + 1) % 6, (i + 1) % 6] for i in range(6)])
    return v, cells


def test_l_shape_three_squares() -> None:
    v, cells = l_shape()
    p, q, info = refine_layout(v, cells, size=0.3)
    seg = check_refined(v, cells, p, q)
    assert set(seg.values()) == {4}
    assert info.chords.n_chords == 4
    assert len(q) == 3 * 16
    assert np.allclose(corner_angles(p[q]), 90.0)
    assert np.bincount(info.quad_cell).tolist() == [16, 16, 16]


def test_hexagon_two_trapezoids_graded() -> None:
    v, cells = hexagon()
    ch = layout_chords(cells)
    assert ch.n_chords == 3
    k = ch.chord_of(0, 3)
    assert ch.chord_of(1, 2) == k == ch.chord_of(4, 5)
    p, q, info = refine_layout(v, cells, counts={(0, 1): 5, k: 7, (3, 4): 2})
    seg = check_refined(v, cells, p, q)
    assert seg[(0, 1)] == seg[(2, 3)] == 5 and seg[(1, 2)] == seg[(0, 3)] == seg[(4, 5)] == 7
    assert seg[(3, 4)] == seg[(5, 0)] == 2
    assert info.chord_counts[k] == 7
    ang = corner_angles(p[q])
    assert ang.min() >= 60 - 1e-9 and ang.max() <= 120 + 1e-9
    # a trapezoid's grid keeps its 60°/120° pairs: the range is attained, not just bounded
    assert ang.min() < 60 + 1e-6 and ang.max() > 120 - 1e-6


def test_perturbed_grid_with_size() -> None:
    v, cells = perturbed_grid()
    p, q, info = refine_layout(v, cells, size=0.15, min_count=2)
    seg = check_refined(v, cells, p, q)
    ch = info.chords
    # every chord's count is the largest ceil(length / size) over its edges
    for k in range(ch.n_chords):
        ed = ch.edges[ch.chord_edges(k)]
        want = max(2, int(np.ceil(np.abs(v[ed[:, 1]] - v[ed[:, 0]]).max() / 0.15)))
        assert info.chord_counts[k] == want
        assert all(seg.get((a, b), seg.get((b, a))) == want for a, b in ed.tolist())
    # the grid angles stay inside each cell's corner/supplement range
    theta = corner_angles(v[cells])
    rng_lo = np.minimum(theta, 180 - theta).min(axis=1)
    rng_hi = np.maximum(theta, 180 - theta).max(axis=1)
    ang = corner_angles(p[q])
    assert np.all(ang >= rng_lo[info.quad_cell, None] - 1e-9)
    assert np.all(ang <= rng_hi[info.quad_cell, None] + 1e-9)


def test_ring_closed_chord() -> None:
    v, cells = hex_ring()
    p, q, info = refine_layout(v, cells, counts={(0, 6): 3, (0, 1): 2})
    seg = check_refined(v, cells, p, q)
    radial = info.chords.chord_of(0, 6)
    assert all(info.chords.chord_of(i, 6 + i) == radial for i in range(6))
    assert all(seg[(i, 6 + i)] == 3 for i in range(6))
    assert seg[(1, 0)] == seg[(6, 7)] == 2 and seg[(2, 1)] == seg[(7, 8)] == 1
    assert len(q) == 3 * (5 * 1 + 2)
    # the two boundary loops (inner and outer hexagon) keep the layout's area: 6·(6.25 - 1)·√3/4
    assert np.isclose(shoelace(p[q]).sum(), 6 * 5.25 * np.sqrt(3) / 4, rtol=1e-12)


def test_fixed_params_propagate_along_chord() -> None:
    v, cells = hexagon()
    ch = layout_chords(cells)
    par = np.array([0.0, 0.01, 0.03, 0.1, 0.3, 0.62, 1.0])
    # given from 1 to 2; with the cells' orientation this matches 0 -> 3 and 5 -> 4
    p, q, info = refine_layout(v, cells, edge_params={(1, 2): par}, size=0.7)
    check_refined(v, cells, p, q)
    for a, b in [(1, 2), (0, 3), (5, 4)]:
        ids = info.edge_points(a, b)
        assert len(ids) == len(par) and ids[0] == a and ids[-1] == b
        # independent: the fine points on segment (a, b), sorted from a
        w = (p - v[a]) / (v[b] - v[a])
        on = np.nonzero((np.abs(w.imag) < 1e-12) & (w.real > -1e-12) & (w.real < 1 + 1e-12))[0]
        on = on[np.argsort(w[on].real)]
        assert np.array_equal(on, ids)
        assert np.array_equal(p[ids[1:-1]], v[a] + par[1:-1] * (v[b] - v[a])), (a, b)
    assert ch.along_reference(1, 2) != ch.along_reference(2, 1)
    assert ch.along_reference(1, 2) == ch.along_reference(0, 3) == ch.along_reference(5, 4)
    # the same parameters given from the other end of the chord (edge 4 -> 5) agree; the edges
    # running 4 -> 5 ways get them bit for bit, the others to rounding
    p2, _q2, info2 = refine_layout(v, cells, edge_params={(4, 5): 1.0 - par[::-1], (1, 2): par})
    ids = info2.edge_points(4, 5)
    assert np.array_equal(p2[ids[1:-1]], v[4] + (1.0 - par[::-1])[1:-1] * (v[5] - v[4]))
    ids = info2.edge_points(1, 2)
    assert np.allclose(p2[ids[1:-1]], v[1] + par[1:-1] * (v[2] - v[1]), rtol=0, atol=1e-14)


def test_fixed_params_in_grid_and_interior_rows() -> None:
    v, cells = perturbed_grid(seed=11, rows=3, cols=3)
    top = (13, 12)  # top edge of the first column, given right to left
    par = np.concatenate([[0.0], np.cumsum(0.05 * 1.6 ** np.arange(8))])
    par /= par[-1]
    par[-1] = 1.0
    left = (0, 4)  # left edge of the bottom row, upwards
    lpar = np.array([0.0, 0.5, 0.75, 0.875, 1.0])
    p, q, info = refine_layout(v, cells, edge_params={top: par, left: lpar}, size=0.25)
    seg = check_refined(v, cells, p, q)
    # the column chord: edges (13, 12), (9, 8), (5, 4), (1, 0) carry par from right to left
    for a, b in [(13, 12), (9, 8), (5, 4), (1, 0)]:
        ids = info.edge_points(a, b)
        assert np.array_equal(p[ids[1:-1]], v[a] + par[1:-1] * (v[b] - v[a]))
        assert seg.get((a, b), seg.get((b, a))) == len(par) - 1
    # the row chord: (0, 4), (1, 5), (2, 6), (3, 7) carry lpar upwards
    for a, b in [(0, 4), (1, 5), (2, 6), (3, 7)]:
        ids = info.edge_points(a, b)
        assert np.array_equal(p[ids[1:-1]], v[a] + lpar[1:-1] * (v[b] - v[a]))
    # inside the cells the grid rows follow the same parameters: interior point (i, j) of the
    # bottom-left cell is the bilinear point at (1 - par[::-1][i], lpar[j])
    g = info.cell_grid(0)
    s = 1.0 - par[::-1]
    ref = bilinear_points(v[cells[0]], s, lpar)
    assert np.allclose(p[g], ref, rtol=0, atol=1e-14)


def test_conflicting_fixed_params_raise() -> None:
    v, cells = hexagon()
    par = np.array([0.0, 0.2, 0.5, 1.0])
    with pytest.raises(ValueError, match=r"chord \d+ .*different parameters"):
        refine_layout(v, cells, edge_params={(1, 2): par, (5, 4): np.array([0, 0.3, 0.5, 1.0])})
    with pytest.raises(ValueError, match="3 and 2 segments"):
        refine_layout(v, cells, edge_params={(1, 2): par, (0, 3): np.array([0, 0.5, 1.0])})
    # consistent, though given from opposite ends: no error
    refine_layout(v, cells, edge_params={(1, 2): par, (4, 5): 1.0 - par[::-1]})
    with pytest.raises(ValueError, match="fixed segments"):
        refine_layout(v, cells, edge_params={(1, 2): par}, counts={(0, 3): 5})
    with pytest.raises(ValueError, match="different counts"):
        refine_layout(v, cells, counts={(1, 2): 4, (5, 4): 5})
    with pytest.raises(ValueError, match="not a side"):
        refine_layout(v, cells, edge_params={(1, 3): par})
    with pytest.raises(ValueError, match="increasing"):
        refine_layout(v, cells, edge_params={(1, 2): np.array([0.0, 0.6, 0.4, 1.0])})


def test_non_admissible_layouts_raise() -> None:
    v, cells = l_shape()
    bad = v.copy()
    bad[4] = 1.7 + 1.0j  # the cells at vertex 4 get corners of 55.0° and 125.0°
    probs = layout_problems(bad, cells)
    assert probs and any("vertex 4 (1.7, 1)" in s for s in probs)
    assert len(layout_problems(v, cells)) == 0
    with pytest.raises(ValueError, match="outside"):
        check_layout(bad, cells)
    with pytest.raises(ValueError, match="outside"):
        refine_layout(bad, cells, size=0.2)
    # clockwise cell
    with pytest.raises(ValueError):
        check_layout(v, cells[:, ::-1])
    # two cells running along an edge in the same direction
    with pytest.raises(ValueError, match="same direction"):
        layout_chords(np.array([[0, 1, 4, 5], [1, 2, 3, 4], [0, 1, 6, 7]]))
    # margin: a 60°/120° trapezoid passes at 0 and fails at 1°
    hv, hc = hexagon()
    check_layout(hv, hc)
    with pytest.raises(ValueError, match=r"outside \[61°, 119°\]"):
        check_layout(hv, hc, margin_deg=1.0)


def tip_layout() -> tuple[np.ndarray, np.ndarray]:
    """A tip cell (40° at vertex 0, then 110°, 100°, 110°) and a rectangle on its side 1 -> 2."""
    th = np.radians([40.0, 110.0, 100.0, 110.0])
    phi = np.concatenate([[0.0], np.cumsum(np.pi - th[1:])])
    u = np.exp(1j * phi)
    l0, l1 = 3.0, 1.0
    r = -(l0 * u[0] + l1 * u[1])
    det = (np.conj(u[2]) * u[3]).imag
    l2 = (np.conj(r) * u[3]).imag / det
    tip = np.concatenate([[0.0], np.cumsum(np.array([l0, l1, l2]) * u[:3])])
    n = -1j * (tip[2] - tip[1]) / abs(tip[2] - tip[1])  # outward normal of side 1 -> 2
    v = np.concatenate([tip, [tip[1] + 0.8 * n, tip[2] + 0.8 * n]])
    return v, np.array([[0, 1, 2, 3], [1, 4, 5, 2]])


def test_tip_cell_stays_whole() -> None:
    v, cells = tip_layout()
    assert np.allclose(corner_angles(v[cells[0]]), [40, 110, 100, 110])
    with pytest.raises(ValueError, match=r"40\.0000° at vertex 0"):
        check_layout(v, cells)
    check_layout(v, cells, tips=[0])
    # size refines the rectangle across, but the tip cell's chords stay at 1
    p, q, info = refine_layout(v, cells, size=0.15, tips=[0])
    ch = info.chords
    assert info.chord_counts[ch.chord_of(0, 1)] == 1 and info.chord_counts[ch.chord_of(1, 2)] == 1
    assert info.chord_counts[ch.chord_of(1, 4)] == 6  # ceil(0.8 / 0.15)
    check_refined(v, cells, p, q, angle_range=(40.0, 120.0))
    assert np.sum(info.quad_cell == 0) == 1
    ang = corner_angles(p[q])
    assert np.sum(ang < 60.0) == 1  # only the polygon's own tip
    with pytest.raises(ValueError, match="must stay whole"):
        refine_layout(v, cells, counts={(0, 1): 2}, tips=[0])
    with pytest.raises(ValueError, match="must stay whole"):
        check_layout(v, cells, tips=[0], chord_counts=np.array([2, 1, 1]))
    # why: splitting the tip cell creates new angles near 40° and 140°
    p2, q2, info2 = refine_layout(v, cells, counts={(0, 1): 3, (1, 2): 3}, check=False)
    a2 = corner_angles(p2[q2])[info2.quad_cell == 0]
    assert np.sum(a2 < 60.0) > 1 and a2.max() > 130.0
