"""Evaluation of the Schwarz–Christoffel map at many points (CONFORMAL.md §1.10).

The fast evaluator (far-field tree for the series coefficients, radial anchor chains for the
values at the series centres) is checked against the direct compound quadrature, on the
pipeline's own workload (a disk mesh), next to the circle and next to crowded prevertices.
"""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import pipeline
from quadmesh.benchmark import smooth_star
from quadmesh.conformal import DiskMap
from quadmesh.conformal.series import log_expansions, window_pairs
from quadmesh.disk import disk_mesh
from quadmesh.result import MeshOptions


@pytest.fixture(scope="module")
def star_map() -> DiskMap:
    p = smooth_star(60, seed=2)
    return DiskMap.from_polygon(p[:, 0] + 1j * p[:, 1])


@pytest.fixture(scope="module")
def rect_map() -> DiskMap:
    # aspect ratio 6: prevertex gaps down to ~3e-4
    return DiskMap.from_polygon(np.array([0, 6, 6 + 1j, 1j]))


def _local_error(fm: DiskMap, z: np.ndarray, f: np.ndarray) -> tuple[float, float]:
    """Max |f − direct| / diam and max |f − direct| / (|f'|·dist to nearest prevertex)."""
    fd = fm.direct(z)
    r = np.abs(fm._nearest(z)[1])
    e = np.abs(f - fd)
    return float(e.max() / fm._diam), float(np.max(e / (np.abs(fm.derivative(z)) * r)))


def test_window_pairs_finds_exactly_the_prevertices_in_the_disk() -> None:
    rng = np.random.default_rng(0)
    theta = np.sort(rng.uniform(0, 2 * np.pi, 200))
    zk = np.exp(1j * theta)
    c = (1 - 10 ** rng.uniform(-9, 0, 300)) * np.exp(2j * np.pi * rng.uniform(0, 1, 300))
    D = 10 ** rng.uniform(-9, 0.5, 300)
    rows, k = window_pairs(theta, c, D)
    got = np.zeros((300, 200), bool)
    got[rows, k] = True
    want = np.abs(zk[None, :] - c[:, None]) <= D[:, None]
    assert np.all(got[want])  # nothing missed (extra candidates are filtered by the caller)
    assert np.bincount(rows, minlength=300).max() <= 200  # no prevertex twice


@pytest.mark.parametrize("direct", [False, True], ids=["tree", "direct"])
def test_log_expansions_match_direct_sums(star_map: DiskMap, direct: bool) -> None:
    fm = star_map
    rng = np.random.default_rng(1)
    K = 600
    c = (1 - 10 ** rng.uniform(-5, 0, K)) * np.exp(2j * np.pi * rng.uniform(0, 1, K))
    R = np.min(np.abs(fm.prevertices[None, :] - c[:, None]), axis=1)
    rho = 0.5 * R * rng.uniform(0.2, 1.0, K)
    orders = np.full(K, 64)
    worst = 0.0
    for t, a in log_expansions(fm.prevertices, fm.theta, fm.beta, c, rho, orders, direct):
        u = 0.5 * np.exp(2j * np.pi * rng.uniform(0, 1, t.size))
        z = c[t] + 2 * rho[t] * u
        z = z / np.maximum(np.abs(z), 1.0)
        u = (z - c[t]) / (2 * rho[t])
        exact = np.sum(fm.beta * np.log1p(-z[:, None] * np.conj(fm.prevertices)[None, :]), axis=1)
        approx = np.polynomial.polynomial.polyval(u, a.T, tensor=False)
        # conditioning: z and z_k carry ~1e-16 absolute rounding, so β_k log(z_k − z) is only
        # known to β_k·1e-16/|z_k − z|
        cond = np.sum(np.abs(fm.beta) / np.abs(fm.prevertices[None, :] - z[:, None]), axis=1)
        worst = max(worst, float(np.max(np.abs(exact - approx) / (1.0 + 1e-2 * cond))))
    assert worst < 1e-14


def test_push_forward_workload_matches_direct(star_map: DiskMap) -> None:
    """The pipeline's map_clusters call on a real disk mesh, checked on samples."""
    fm = star_map
    theta = np.mod(fm.theta, 2 * np.pi)
    opts = MeshOptions()
    intervals, _ = pipeline.piece_intervals(theta, [], opts)
    disk = disk_mesh(intervals, A=opts.lemma_A, n=2, depth_step=1.0, depth_growth=2.0)
    zd = disk.vertices
    f, fp = fm.map_clusters(zd, disk.vertex_piece, disk.piece_center, derivative=True)
    assert np.all(np.isfinite(f))
    rng = np.random.default_rng(2)
    r = np.abs(fm._nearest(zd)[1])
    idx = np.unique(
        np.r_[
            rng.choice(zd.size, 1500, replace=False),
            np.argsort(1 - np.abs(zd))[:300],  # on / next to the circle
            np.argsort(r)[:300],  # next to prevertices
        ]
    )
    absd, rel = _local_error(fm, zd[idx], f[idx])
    assert absd < 1e-13
    assert rel < 1e-10
    dd = fm.derivative(zd[idx])
    assert np.max(np.abs(fp[idx] - dd) / np.abs(dd)) < 1e-11
    # circle vertices land on their sides
    circ = np.asarray(disk.on_circle, bool)
    img = pipeline._project_to_sides(f[circ], np.angle(zd[circ]), theta, fm.vertices)
    assert np.max(np.abs(img - f[circ])) < 1e-12 * fm._diam


def test_call_near_circle_and_crowded_prevertices(rect_map: DiskMap) -> None:
    fm = rect_map
    rng = np.random.default_rng(3)
    z1 = np.sqrt(rng.uniform(0, 1, 1500)) * np.exp(2j * np.pi * rng.uniform(0, 1, 1500))
    t = rng.uniform(0, 2 * np.pi, 800)
    z2 = (1 - 10 ** rng.uniform(-12, -1, 800)) * np.exp(1j * t)  # within 1e-12 of the circle
    k = np.argsort(fm.gaps)[:2]
    s = np.tile(np.linspace(-2, 2, 200), 2)
    th = np.repeat(fm.theta[k], 200) + s * np.repeat(fm.gaps[k], 200)
    depth = np.tile(10 ** np.linspace(-9, -1, 200), 2) * np.repeat(fm.gaps[k], 200)
    z3 = (1 - depth) * np.exp(1j * th)  # around the most crowded prevertices
    for z in (z1, z2, z3):
        absd, rel = _local_error(fm, z, fm(z))
        assert absd < 1e-12
        assert rel < 1e-10


def test_map_clusters_with_poor_clusters_equals_call(star_map: DiskMap) -> None:
    """Clusters whose centre series cannot cover their points fall back to the general
    evaluator, with the same values."""
    fm = star_map
    rng = np.random.default_rng(4)
    z = (1 - 10 ** rng.uniform(-8, 0, 2000)) * np.exp(2j * np.pi * rng.uniform(0, 1, 2000))
    cid = rng.integers(0, 5, z.size)  # five huge clusters: never good
    cen = np.zeros(5, complex)
    f = fm.map_clusters(z, cid, cen)
    assert np.max(np.abs(f - fm(z))) < 1e-13 * fm._diam
    absd, rel = _local_error(fm, z, f)
    assert absd < 1e-13 and rel < 1e-10
