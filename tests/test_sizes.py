"""Local feature size of a polygon and the edge-size measurement of QuadMesh.verify, the
command line (check, mesh --stats) and the benchmark tables."""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path

import numpy as np
import pytest
import shapely

from quadmesh import mesh as mesh_module
from quadmesh.benchmark import format_family_table, smooth_star, summarise_families
from quadmesh.cli import EXIT_OK, main
from quadmesh.io import write_mesh, write_polygon
from quadmesh.mesh import SIZE_FLOOR, QuadMesh, local_feature_size
from quadmesh.polygon import validate_polygon

SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
NOTCHED = np.array(
    [[0, 0], [1, 0], [1, 1], [0.5, 1], [0.5, 0.1], [0.45, 0.1], [0.45, 1], [0, 1]], dtype=float
)


def brute_lfs(vertices: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Radius of the smallest disk about each point that meets two non-incident features
    (corners and sides), by trying every pair: the definition, O(n²) per point."""
    z = vertices[:, 0] + 1j * vertices[:, 1]
    n = z.size
    feats = [("v", k) for k in range(n)] + [("s", k) for k in range(n)]

    def incident(f, g) -> bool:
        if f == g:
            return True
        if f[0] == g[0] == "v":
            return False
        if f[0] == g[0] == "s":
            return (f[1] - g[1]) % n in (1, n - 1)
        v, s = (f[1], g[1]) if f[0] == "v" else (g[1], f[1])
        return v in (s, (s + 1) % n)

    pairs = [(f, g) for f, g in itertools.combinations(feats, 2) if not incident(f, g)]
    out = []
    for p in x:
        d = {}
        for k in range(n):
            d["v", k] = abs(p - z[k])
            a, b = z[k], z[(k + 1) % n]
            t = np.clip(((p - a) * np.conj(b - a)).real / abs(b - a) ** 2, 0, 1)
            d["s", k] = abs(p - a - t * (b - a))
        out.append(min(max(d[f], d[g]) for f, g in pairs))
    return np.array(out)


def sample_points(vertices: np.ndarray, rng: np.random.Generator, k: int) -> np.ndarray:
    """k interior points, k points on the sides and every corner (complex)."""
    poly = shapely.Polygon(vertices)
    x0, y0, x1, y1 = poly.bounds
    inside: list[complex] = []
    while len(inside) < k:
        p = complex(rng.uniform(x0, x1), rng.uniform(y0, y1))
        if poly.contains(shapely.Point(p.real, p.imag)):
            inside.append(p)
    z = vertices[:, 0] + 1j * vertices[:, 1]
    s = rng.integers(0, z.size, k)
    on = z[s] + rng.uniform(size=k) * (np.roll(z, -1)[s] - z[s])
    return np.r_[np.array(inside), on, z]


# ----------------------------------------------------------------------------- lfs
@pytest.mark.parametrize(
    "vertices",
    [
        SQUARE,
        NOTCHED,
        smooth_star(14, seed=3, amplitude=0.9),
        np.array([[0, 0], [1, 0], [0.3, 0.5]]),
        np.array([[0, 0], [1, 0], [1, 1], [0.5, 1], [0, 1]]),  # a straight corner
    ],
    ids=["square", "notched", "star", "triangle", "straight_corner"],
)
def test_lfs_matches_the_definition(vertices):
    x = sample_points(vertices, np.random.default_rng(0), 60)
    got = local_feature_size(vertices, x)
    want = brute_lfs(np.asarray(vertices, dtype=float), x)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # (N, 2) reals and complex points give the same
    np.testing.assert_array_equal(local_feature_size(vertices, np.c_[x.real, x.imag]), got)


def feature_distances(vertices: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(P, 2n) distances from the points to every corner, then to every side."""
    z = vertices[:, 0] + 1j * vertices[:, 1]
    a, b = z[None, :], np.roll(z, -1)[None, :]
    p = x[:, None]
    t = np.clip(((p - a) * np.conj(b - a)).real / np.abs(b - a) ** 2, 0, 1)
    return np.c_[np.abs(p - a), np.abs(p - a - t * (b - a))]


def brute_lfs_vectorised(vertices: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The definition again, for larger cases: over every pair of non-incident features
    (corner i with corner j ≠ i, corner i with a side not ending at i, sides that share no
    corner), the smallest of the larger distance."""
    n = vertices.shape[0]
    k = np.arange(n)
    cc = k[:, None] != k[None, :]
    cs = (k[None, :] != k[:, None]) & ((k[None, :] + 1) % n != k[:, None])  # corner i, side j
    gap = (k[:, None] - k[None, :]) % n
    ss = (gap != 0) & (gap != 1) & (gap != n - 1)
    ok = np.block([[cc, cs], [cs.T, ss]])
    out = np.empty(x.size)
    for i in range(0, x.size, 200):
        d = feature_distances(vertices, x[i : i + 200])
        pair = np.maximum(d[:, :, None], d[:, None, :])
        out[i : i + 200] = np.where(ok, pair, np.inf).min(axis=(1, 2))
    return out


def random_star(rng: np.random.Generator, n: int, slits: int, tiny: int) -> np.ndarray:
    """A polygon star-shaped about (0, 0) (vertices at increasing angles: always simple) with
    random radii (reflex corners), ``slits`` notches of width ~1e-4 reaching near the middle
    and ``tiny`` edges of length ~1e-7."""
    theta = np.sort(rng.uniform(0, 2 * np.pi, n))
    rad = rng.uniform(0.3, 1.0, n)
    extra_t, extra_r = [], []
    for s in rng.choice(n - 1, slits, replace=False):
        gap = theta[s + 1] - theta[s]
        mid = theta[s] + gap / 2
        w = min(1e-4, gap / 4)
        extra_t += [mid - w, mid - w / 2, mid + w / 2, mid + w]
        extra_r += [1.0, 0.05, 0.05, 1.0]
    for s in rng.choice(n - 1, tiny, replace=False):
        extra_t.append(theta[s] + 1e-7)
        extra_r.append(rad[s])
    theta = np.r_[theta, extra_t]
    rad = np.r_[rad, extra_r]
    order = np.argsort(theta, kind="stable")
    z = rad[order] * np.exp(1j * theta[order])
    return np.c_[z.real, z.imag]


def sample_everywhere(vertices: np.ndarray, rng: np.random.Generator, k: int) -> np.ndarray:
    """Points inside and outside, on the sides, at the corners and a hair off the corners."""
    z = vertices[:, 0] + 1j * vertices[:, 1]
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    box = rng.uniform(lo - 0.2, hi + 0.2, (k, 2))
    s = rng.integers(0, z.size, k)
    on = z[s] + rng.uniform(size=k) * (np.roll(z, -1)[s] - z[s])
    near = z + 1e-9 * np.exp(2j * np.pi * rng.uniform(size=z.size))
    return np.r_[box[:, 0] + 1j * box[:, 1], on, z, near]


@pytest.mark.parametrize("seed", range(6))
def test_lfs_matches_the_definition_on_random_polygons(seed):
    """Random polygons with reflex corners, slits and tiny edges; many points anywhere,
    on the sides and at the corners: the quadtree search equals the definition to float64
    rounding."""
    rng = np.random.default_rng(seed)
    v = random_star(rng, int(rng.integers(5, 60)), slits=seed % 3, tiny=seed % 4)
    validate_polygon(v)  # a simple polygon
    x = sample_everywhere(v, rng, 400)
    np.testing.assert_allclose(
        local_feature_size(v, x), brute_lfs_vectorised(v, x), rtol=1e-12, atol=1e-15
    )


@pytest.mark.parametrize(
    ("ratio", "max_features", "few"),
    [(0.35, 16, 2), (0.05, 16, 2), (2.0, 16, 0), (0.35, 2, 2), (0.35, 1000, 50)],
    ids=["default", "fine_cells", "coarse_cells", "all_exact", "cells_only"],
)
def test_lfs_paths_match_the_definition(monkeypatch, ratio, max_features, few):
    """Whatever the quadtree's cell size and whichever points go to the exact search (the
    middle of a regular 200-gon, where every side is about as far, a random polygon with a
    slit and a tiny edge, points anywhere), the value is the definition's."""
    monkeypatch.setattr(mesh_module, "_LFS_CELL_RATIO", ratio)
    monkeypatch.setattr(mesh_module, "_LFS_MAX_FEATURES", max_features)
    monkeypatch.setattr(mesh_module, "_LFS_FEW", few)
    t = np.exp(2j * np.pi * np.arange(200) / 200)
    v = np.c_[t.real, t.imag]
    rng = np.random.default_rng(7)
    x = np.r_[0j, 1e-3 * (rng.uniform(-1, 1, 100) + 1j * rng.uniform(-1, 1, 100))]
    x = np.r_[x, sample_everywhere(v, rng, 100)]
    want = brute_lfs_vectorised(v, x)
    np.testing.assert_allclose(local_feature_size(v, x), want, rtol=1e-12, atol=1e-15)
    w = random_star(rng, 30, slits=1, tiny=1)
    x = np.r_[sample_everywhere(w, rng, 300), 0.01 * rng.uniform(-1, 1, 300)]
    np.testing.assert_allclose(
        local_feature_size(w, x), brute_lfs_vectorised(w, x), rtol=1e-12, atol=1e-15
    )


def test_lfs_dense_mesh_points_match_the_definition():
    """Many points crowded near the boundary, as a mesh's edge midpoints are (the quadtree
    cells settle them; a cell meets a handful of features): the definition's values."""
    rng = np.random.default_rng(11)
    v = random_star(rng, 40, slits=1, tiny=2)
    z = v[:, 0] + 1j * v[:, 1]
    s = rng.integers(0, z.size, 3000)
    on = z[s] + rng.uniform(size=s.size) * (np.roll(z, -1)[s] - z[s])
    x = on * (1 - 10.0 ** rng.uniform(-6, -1, s.size))  # just inside (star-shaped about 0)
    np.testing.assert_allclose(
        local_feature_size(v, x), brute_lfs_vectorised(v, x), rtol=1e-12, atol=1e-15
    )


def test_lfs_non_finite_points_give_nan():
    got = local_feature_size(SQUARE, [0.5 + 0.5j, complex(np.nan, 0), 0j])
    np.testing.assert_allclose(got, [0.5, np.nan, 1.0])


def test_lfs_known_values():
    # centre of the unit square: the two opposite sides at 1/2; its corners: the next corner
    np.testing.assert_allclose(local_feature_size(SQUARE, [0.5 + 0.5j, 0j, 1 + 1j]), [0.5, 1, 1])
    # a corridor 10 × 0.1: the width on its walls and on its axis half of it
    rect = np.array([[0, 0], [10, 0], [10, 0.1], [0, 0.1]])
    np.testing.assert_allclose(local_feature_size(rect, [5 + 0j, 5 + 0.05j]), [0.1, 0.05])
    # the notch of width 0.05: its walls are 0.05 apart
    np.testing.assert_allclose(local_feature_size(NOTCHED, [0.5 + 0.5j]), [0.05])
    # a straight corner (180°) makes the sides on either side features: lfs = shorter side
    pent = np.array([[0, 0], [1, 0], [1, 1], [0.5, 1], [0, 1]])
    np.testing.assert_allclose(local_feature_size(pent, [0.5 + 1j]), [0.5])


def test_lfs_is_positive_and_lipschitz():
    v = smooth_star(40, seed=5, amplitude=0.8)
    rng = np.random.default_rng(1)
    x = sample_points(v, rng, 400)
    f = local_feature_size(v, x)
    assert np.all(f > 0)
    i, j = rng.integers(0, x.size, (2, 4000))
    assert np.all(np.abs(f[i] - f[j]) <= np.abs(x[i] - x[j]) * (1 + 1e-9) + 1e-15)


def test_lfs_scale_and_translation_covariant():
    x = sample_points(NOTCHED, np.random.default_rng(2), 40)
    f = local_feature_size(NOTCHED, x)
    # a millimetre-sized polygon a million diameters from (0, 0): float64 keeps ~7 digits
    s, t = 1e-3, 3e3 - 2e3j
    g = local_feature_size(np.add(NOTCHED * s, (t.real, t.imag)), x * s + t)
    np.testing.assert_allclose(g, f * s, rtol=1e-7)


def test_lfs_million_points_fast():
    """A million points against a 1000-gon (interior and boundary) in seconds."""
    v = smooth_star(1000, seed=3)
    z = v[:, 0] + 1j * v[:, 1]
    rng = np.random.default_rng(0)
    s = rng.integers(0, z.size, 500_000)
    x = np.r_[
        z[s] + rng.uniform(size=s.size) * (np.roll(z, -1)[s] - z[s]),
        0.5 * (rng.uniform(-1, 1, 500_000) + 1j * rng.uniform(-1, 1, 500_000)),
    ]
    t0 = time.perf_counter()
    f = local_feature_size(v, x)
    dt = time.perf_counter() - t0
    assert np.all(f > 0) and np.all(np.isfinite(f))
    assert dt < 30.0, f"{dt:.1f} s for a million points"  # ~5 s on a quiet 2-core machine


# ----------------------------------------------------------------------------- report
def graded_grid(ys: list[float]) -> QuadMesh:
    """The unit square split at x = 0, 1/2, 1 and at the heights ``ys`` (0 … 1)."""
    xs = [0.0, 0.5, 1.0]
    verts = np.array([[x, y] for y in ys for x in xs])
    quads = []
    for j in range(len(ys) - 1):
        for i in range(2):
            v0 = j * 3 + i
            quads.append([v0, v0 + 1, v0 + 4, v0 + 3])
    return QuadMesh(verts, np.array(quads))


def test_report_sizes_of_a_grid():
    mesh = graded_grid([0.0, 0.5, 1.0])
    q = mesh.verify(SQUARE).quality
    edges, _ = mesh.edges()
    za, zb = mesh.z[edges[:, 0]], mesh.z[edges[:, 1]]
    ratio = np.abs(zb - za) / brute_lfs(SQUARE, 0.5 * (za + zb))
    assert q.n_edges == edges.shape[0] == 12
    assert q.min_edge_lfs == pytest.approx(ratio.min(), rel=1e-12)
    assert q.median_edge_lfs == pytest.approx(np.median(ratio), rel=1e-12)
    assert q.share_below_floor == 0.0 and q.share_below_warn == 0.0
    assert q.size_floor_met is True
    a, b = q.min_edge_lfs_edge
    assert q.min_edge_lfs_at == pytest.approx(tuple(0.5 * (mesh.vertices[a] + mesh.vertices[b])))
    assert q.min_edge_lfs_length == pytest.approx(0.5)
    # the round trip through JSON keeps the fields
    d = json.loads(json.dumps(q.as_dict()))
    assert d["min_edge_lfs"] == pytest.approx(q.min_edge_lfs)
    assert d["min_edge_lfs_at"] == pytest.approx(list(q.min_edge_lfs_at))


def test_tiny_edges_are_measured_not_refused():
    """A row of height 1e-5 along the bottom: edges 1e-5 of the local feature size, counted
    below the floor, and the mesh is still valid (the measurement refuses nothing)."""
    mesh = graded_grid([0.0, 1e-5, 1.0])
    report = mesh.verify(SQUARE)
    assert report.ok
    q = report.quality
    assert q.min_edge_lfs == pytest.approx(1e-5, rel=1e-4)
    assert q.min_edge_lfs_size == pytest.approx(1.0, rel=1e-4)
    assert q.min_edge_lfs_at[1] == pytest.approx(5e-6)
    assert q.size_floor_met is False
    # the three short vertical edges (on the left and right sides and in the middle): 3 of 12
    assert q.share_below_floor == pytest.approx(3 / 12)
    assert q.share_below_warn == pytest.approx(3 / 12)
    assert "edge / local feature size: min 1e-05" in report.summary()
    assert "below 1/1000" in report.summary() and "NOT met" in report.summary()


def test_sizes_in_the_stored_frame_with_origin():
    """A mesh stored relative to an origin: measured against the polygon moved by −origin;
    the reported place is in the polygon's coordinates."""
    origin = complex(4e6, -3e6)
    mesh = graded_grid([0.0, 1e-5, 1.0])
    far = np.add(SQUARE, (origin.real, origin.imag))
    q0 = mesh.verify(SQUARE).quality
    q = mesh.verify(far, origin=origin).quality
    assert q.min_edge_lfs == pytest.approx(q0.min_edge_lfs, rel=1e-9)
    assert q.min_edge_lfs_at[0] == pytest.approx(q0.min_edge_lfs_at[0] + origin.real)
    assert q.min_edge_lfs_at[1] == pytest.approx(q0.min_edge_lfs_at[1] + origin.imag)


def test_no_polygon_no_sizes():
    q = graded_grid([0.0, 0.5, 1.0]).quality()
    assert q.min_edge_lfs is None and q.size_floor_met is None
    assert "local feature size" not in q.summary()
    q = graded_grid([0.0, 0.5, 1.0]).quality(SQUARE)
    assert q.min_edge_lfs == pytest.approx(0.5 / 0.75)  # a half side, lfs 3/4 at its middle


def test_pipeline_result_reports_sizes():
    from quadmesh import mesh_polygon

    r = mesh_polygon(SQUARE)
    q = r.quality
    assert q.min_edge_lfs is not None and 0 < q.min_edge_lfs <= q.median_edge_lfs
    _, length, lfs = r.mesh.edge_lfs_ratios(validate_polygon(SQUARE))
    ratio = length / lfs
    assert q.min_edge_lfs == pytest.approx(ratio.min())
    assert q.share_below_floor == pytest.approx(np.mean(ratio < SIZE_FLOOR))


# ----------------------------------------------------------------------------- CLI, bench
def test_cli_check_and_mesh_stats_print_sizes(tmp_path: Path, capsys):
    poly = tmp_path / "sq.json"
    write_polygon(poly, SQUARE)
    mesh = tmp_path / "m.json"
    write_mesh(mesh, graded_grid([0.0, 1e-5, 1.0]))
    assert main(["check", str(mesh), "--polygon", str(poly)]) == EXIT_OK
    out = capsys.readouterr().out
    assert "edge / local feature size: min 1e-05 at (0, 5e-06)" in out
    assert "edges below 1/1000 of the local feature size: 25 % of 12" in out
    out_mesh = tmp_path / "out.json"
    assert main(["mesh", str(poly), "-o", str(out_mesh), "--stats"]) == EXIT_OK
    out = capsys.readouterr().out
    assert "edge / local feature size: min" in out and "below 1/50" in out


def test_bench_family_table_has_size_column():
    rows = [
        {
            "family": "f",
            "name": "a",
            "n": 10,
            "status": "meshed",
            "quads": 100,
            "time": 1.0,
            "min_edge_over_width": 0.5,
            "nominal_aspect": None,
            "aspect": 3.0,
            "min_edge_lfs": 2e-4,
            "share_below_floor": 0.01,
        },
        {
            "family": "f",
            "name": "b",
            "n": 12,
            "status": "failed",
            "error": "DiskConstructionError",
            "stage": "disk",
            "message": "too crowded",
            "time": 2.0,
            "min_edge_over_width": 0.4,
            "nominal_aspect": None,
            "aspect": 4.0,
        },
    ]
    summary = summarise_families(rows)
    assert summary[0]["edge_lfs_min"] == pytest.approx(2e-4)
    assert summary[0]["below_floor_max"] == pytest.approx(0.01)
    table = format_family_table(summary)
    assert "min edge/lfs" in table.splitlines()[0]
    assert "0.0002/0.0002" in table and "1%" in table
