"""Tests of the Schwarz–Christoffel disk map (CONFORMAL.md §1) and the inscribed centre."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.special as sp

from quadmesh.conformal import DiskMap, inscribed_center
from quadmesh.conformal.diskmap import _Problem
from quadmesh.conformal.quadrature import gauss_jacobi
from quadmesh.errors import ConformalMapError, PolygonError
from tests.helpers import assert_map_checks

TOL = 1e-10


def rect(ar: float) -> np.ndarray:
    return np.array([0, ar, ar + 1j, 1j])


def random_star(n: int, lo: float, hi: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(lo, hi, n) * np.exp(2j * np.pi * np.arange(n) / n)


L_SHAPE = np.array([0, 2, 2 + 1j, 1 + 1j, 1 + 2j, 2j])


def corner5() -> np.ndarray:
    """A polygon with a 5° corner at the origin whose wedge opens into a wide region."""
    a = np.deg2rad(5.0)
    return np.array([0, 1, 2 - 1j, 3.5 + 1j, 2 + 3j, np.exp(1j * a)])


def reflex355() -> np.ndarray:
    """A square with a thin notch whose tip has interior angle 355°."""
    e = np.tan(np.deg2rad(2.5))
    return np.array([0, 2, 2 + 2j, 1 + e + 2j, 1 + 1j, 1 - e + 2j, 2j])


def assert_checks(dm: DiskMap, tol: float = TOL) -> None:
    assert_map_checks(dm, tol)
    assert dm.accuracy().passed(tol)


def test_gauss_jacobi_matches_scipy() -> None:
    betas = np.array([-0.97, -0.5, 0.0, 0.5, 0.97])
    xp1, w = gauss_jacobi(betas, 12)
    for i, b in enumerate(betas):
        x, ww = sp.roots_jacobi(12, 0.0, b)
        assert np.max(np.abs(xp1[i] - 1.0 - x)) < 1e-14
        assert np.max(np.abs(w[i] - ww) / ww) < 1e-12


def test_analytic_jacobian_matches_finite_differences() -> None:
    w = random_star(9, 0.6, 1.4, 3)
    prob = _Problem(w, 0.05 + 0.02j, 12)
    x = np.random.default_rng(1).normal(0, 0.2, 8)
    x[2] -= 20.0  # one crowded gap (≈ 1e-9): the rotation-identity columns are exercised
    _, J, *_ = prob.evaluate(x)
    Jf = np.zeros_like(J)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = 1e-6
        Jf[:, i] = (prob.evaluate(x + e, False)[0] - prob.evaluate(x - e, False)[0]) / 2e-6
    assert np.max(np.abs(J - Jf)) < 1e-7


@pytest.mark.parametrize("n", range(3, 65))
def test_regular_ngon_has_equally_spaced_prevertices(n: int) -> None:
    w = np.exp(2j * np.pi * np.arange(n) / n)
    dm = DiskMap.from_polygon(w, 0.0, check=False)
    assert np.max(np.abs(dm.gaps - 2 * np.pi / n)) < 1e-12
    assert dm.residual < 1e-12
    assert np.allclose(np.abs(dm.prevertices), 1.0)


def test_square_default_center_is_its_centre() -> None:
    dm = DiskMap.from_polygon(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))
    assert abs(dm.center - (0.5 + 0.5j)) < 1e-12
    assert abs(dm(np.array([0j]))[0] - (0.5 + 0.5j)) < 1e-14
    assert np.max(np.abs(dm.gaps - np.pi / 2)) < 1e-13
    assert_checks(dm)


@pytest.mark.parametrize("ar", [2, 5, 10])
def test_rectangle_prevertex_pattern_and_checks(ar: float) -> None:
    dm = DiskMap.from_polygon(rect(ar))
    assert abs(dm.center - (ar / 2 + 0.5j)) < 1e-9
    g = dm.gaps  # g[k] is the arc mapped onto side k
    assert abs(g[0] - g[2]) < 1e-12 * g[0] + 1e-15
    assert abs(g[1] - g[3]) < 1e-12 * g[1] + 1e-15
    assert g[1] < g[0]  # the short sides get the short arcs
    if ar >= 5:  # crowding law 8 exp(-π AR/2) (CONFORMAL.md §1.8)
        assert abs(g[1] / (8 * np.exp(-np.pi * ar / 2)) - 1) < 1e-3
    assert_checks(dm)


def test_l_shape() -> None:
    dm = DiskMap.from_polygon(L_SHAPE, 0.5 + 0.5j)
    assert_checks(dm)
    assert np.allclose(dm.angles, [0.5, 0.5, 0.5, 1.5, 0.5, 0.5])
    assert abs(dm(np.array([0j]))[0] - (0.5 + 0.5j)) < 1e-13
    # prevertices map to the vertices
    assert np.max(np.abs(dm(dm.prevertices) - L_SHAPE)) < 1e-12
    # the default centre is the inscribed-disk centre on the diagonal
    c, r = inscribed_center(L_SHAPE)
    assert abs(c.real - c.imag) < 1e-6 and abs(r - np.sqrt(2) / (1 + np.sqrt(2))) < 1e-3
    assert_checks(DiskMap.from_polygon(L_SHAPE))


def test_regular_12gon() -> None:
    dm = DiskMap.from_polygon(np.exp(2j * np.pi * np.arange(12) / 12))
    assert_checks(dm)
    assert np.max(np.abs(np.diff(dm.theta) - np.pi / 6)) < 1e-13


def test_random_star_30() -> None:
    dm = DiskMap.from_polygon(random_star(30, 0.5, 1.5, 0), 0.0)
    assert_checks(dm)
    assert np.allclose(np.diff(dm.theta), dm.gaps[:-1], rtol=0, atol=1e-15)


def test_random_star_100_crowded() -> None:
    """iid radii in [0.5, 1.5]: the smallest gap is about 1e-10, below the prototype's reach."""
    dm = DiskMap.from_polygon(random_star(100, 0.5, 1.5, 0), 0.0)
    assert dm.accuracy().min_gap < 1e-9
    assert_checks(dm)


@pytest.mark.slow
def test_random_star_300() -> None:
    dm = DiskMap.from_polygon(random_star(300, 0.8, 1.2, 0), 0.0)
    assert_checks(dm)


def test_five_degree_corner() -> None:
    w = corner5()
    dm = DiskMap.from_polygon(w)
    assert abs(dm.angles[0] - 5 / 180) < 1e-12
    assert_checks(dm)


def test_reflex_355_degree_corner() -> None:
    dm = DiskMap.from_polygon(reflex355(), 0.5 + 0.5j)
    assert abs(dm.angles[4] - 355 / 180) < 1e-12
    assert_checks(dm)


def test_round_trips_on_interior_grids() -> None:
    dm = DiskMap.from_polygon(L_SHAPE, 0.5 + 0.5j)
    r, t = np.meshgrid(np.linspace(0, 0.97, 12), np.linspace(0, 2 * np.pi, 24, endpoint=False))
    z = (r * np.exp(1j * t)).ravel()
    assert np.max(np.abs(dm.inverse(dm(z)) - z)) < 1e-10
    x, y = np.meshgrid(np.linspace(0.025, 1.975, 14), np.linspace(0.025, 1.975, 14))
    w = (x + 1j * y).ravel()
    w = w[(w.real < 0.99) | (w.imag < 0.99)]
    zw = dm.inverse(w)
    assert np.all(np.abs(zw) < 1)
    assert np.max(np.abs(dm(zw) - w)) < 1e-10
    assert np.max(np.abs(dm.direct(zw) - w)) < 1e-10


def test_inverse_non_star_shaped_about_center() -> None:
    """The L-shape about its lower-arm point: starts come from the image table."""
    dm = DiskMap.from_polygon(L_SHAPE, 1.5 + 0.5j)
    assert not dm._star
    w = np.array([0.5 + 1.5j, 0.1 + 1.9j, 1.9 + 0.1j, 0.9 + 0.9j])
    z = dm.inverse(w)
    assert np.max(np.abs(dm(z) - w)) < 1e-10


def test_inverse_rejects_outside_points() -> None:
    dm = DiskMap.from_polygon(L_SHAPE, 0.5 + 0.5j)
    with pytest.raises(ConformalMapError, match="outside"):
        dm.inverse(np.array([0.5 + 0.5j, 1.5 + 1.5j]))


def test_fast_forward_matches_quadrature_everywhere() -> None:
    dm = DiskMap.from_polygon(random_star(30, 0.5, 1.5, 0), 0.0)
    rng = np.random.default_rng(7)
    z = np.sqrt(rng.uniform(0, 1, 400)) * np.exp(2j * np.pi * rng.uniform(0, 1, 400))
    # points very close to prevertices and to the circle as well
    near = dm.prevertices[:, None] * (1 - np.array([1e-9, 1e-5, 1e-3])[None, :])
    z = np.r_[z, near.ravel(), 0.999999 * np.exp(1j * (dm.theta + 0.3 * dm.gaps))]
    scale = np.max(np.abs(dm.vertices))
    assert np.max(np.abs(dm(z) - dm.direct(z))) < 1e-12 * scale


def test_derivative_closed_form() -> None:
    dm = DiskMap.from_polygon(L_SHAPE, 0.5 + 0.5j)
    z = np.array([0.1 + 0.2j, -0.5 + 0.3j, 0.7j, 0.8])
    h = 1e-5
    fd = (dm.direct(z + h) - dm.direct(z - h)) / (2 * h)
    assert np.max(np.abs(dm.derivative(z) - fd)) < 1e-8
    # series derivative through map_clusters agrees with the closed form
    f, fp = dm.map_clusters(z, np.arange(4), z * 0.99, derivative=True)
    assert np.max(np.abs(fp - dm.derivative(z))) < 1e-12
    assert np.max(np.abs(f - dm.direct(z))) < 1e-12


def test_taylor_series_matches_quadrature() -> None:
    dm = DiskMap.from_polygon(random_star(30, 0.5, 1.5, 0), 0.0)
    rng = np.random.default_rng(3)
    for c in (0.0, 0.4 + 0.3j, -0.7j, 0.9 * np.exp(1j * (dm.theta[5] + 0.5 * dm.gaps[5]))):
        ts = dm.taylor(c, order=40)
        R = ts.radius
        assert abs(R - np.min(np.abs(dm.prevertices - c))) < 1e-15
        t = 0.5 * R * np.sqrt(rng.uniform(0, 1, 200)) * np.exp(2j * np.pi * rng.uniform(0, 1, 200))
        t = t[np.abs(c + t) <= 1]
        direct = dm.direct(c + t)
        assert np.max(np.abs(ts(t) - direct)) < 1e-12
        assert np.max(np.abs(ts.derivative(t) - dm.derivative(c + t))) < 1e-12 * np.max(
            np.abs(dm.derivative(c + t))
        )


def test_map_clusters_uses_series_and_falls_back() -> None:
    dm = DiskMap.from_polygon(L_SHAPE, 0.5 + 0.5j)
    rng = np.random.default_rng(5)
    centers = np.array([0.2 + 0.1j, -0.3 + 0.4j, 0.95 * dm.prevertices[3]])
    pts, ids = [], []
    for i, c in enumerate(centers):
        R = np.min(np.abs(dm.prevertices - c))
        rad = 0.45 * R if i < 2 else 3 * R  # the last cluster is too wide: fallback
        p = c + rad * np.sqrt(rng.uniform(0, 1, 300)) * np.exp(2j * np.pi * rng.uniform(0, 1, 300))
        p = p[np.abs(p) < 1]
        pts.append(p)
        ids.append(np.full(p.size, i))
    z = np.concatenate(pts)
    f = dm.map_clusters(z, np.concatenate(ids), centers)
    assert np.max(np.abs(f - dm.direct(z))) < 1e-12


def test_crowded_rectangle_raises() -> None:
    with pytest.raises(ConformalMapError, match="crowding"):
        DiskMap.from_polygon(rect(30))


def test_local_coordinates_beyond_double_resolution() -> None:
    """AR 26: the short-side gaps (1.5e-17) are below the resolution of exp(iθ); the map is
    still solved to 1e-12 in local coordinates when the gap floor is switched off."""
    dm = DiskMap.from_polygon(rect(26), min_gap=0.0)
    g = dm.gaps
    assert g[1] < 1e-16 and abs(g[1] / (8 * np.exp(-np.pi * 13)) - 1) < 1e-3
    assert dm.accuracy().worst < 1e-12
    # the short side (vertex 1 → 2) is reached through local offsets from prevertex 1
    t = dm.prevertices[1] * np.expm1(1j * g[1] * np.array([0.0, 0.1, 0.3, 0.5, 0.8]))
    f = dm.map_near_vertex(1, t)
    assert abs(f[0] - 26) < 1e-12
    assert np.max(np.abs(f.real - 26)) < 1e-9
    assert np.all(np.diff(f.imag) > 0.05) and 0.5 < f[-1].imag < 1


def test_bad_input() -> None:
    with pytest.raises(PolygonError):
        DiskMap.from_polygon(rect(2)[::-1])  # clockwise
    with pytest.raises(PolygonError):
        DiskMap.from_polygon(rect(2), center=5 + 5j)


def test_inscribed_center() -> None:
    c, r = inscribed_center(rect(10))
    assert abs(c - (5 + 0.5j)) < 1e-6 and abs(r - 0.5) < 1e-12
    c, r = inscribed_center(np.exp(2j * np.pi * np.arange(7) / 7))
    assert abs(c) < 1e-6 and abs(r - np.cos(np.pi / 7)) < 1e-6
    c, r = inscribed_center(np.column_stack([L_SHAPE.real, L_SHAPE.imag]))
    assert abs(r - np.sqrt(2) / (1 + np.sqrt(2))) < 1e-3


def test_chord_newton_matches_full_newton(monkeypatch: pytest.MonkeyPatch) -> None:
    """Near the root Newton switches to residual-only evaluations with a reused Jacobian
    (chord steps); the converged gaps agree with Newton forming the Jacobian at every
    iterate, and the default never forms the Jacobian at the converged point."""
    from quadmesh.benchmark import smooth_star
    from quadmesh.conformal import diskmap

    w = smooth_star(150, seed=150) @ np.array([1, 1j])
    c = complex(inscribed_center(w)[0])
    x0 = diskmap._x_from_gaps(diskmap._harmonic_gaps(w, c))

    def solve(chord_below: float) -> tuple[np.ndarray, list[bool], float]:
        monkeypatch.setattr(diskmap, "CHORD_BELOW", chord_below)
        prob = _Problem(w, c, 12)
        flags: list[bool] = []
        inner = prob.evaluate_gaps

        def recording(gaps: np.ndarray, jacobian: bool = True):
            flags.append(jacobian)
            return inner(gaps, jacobian)

        prob.evaluate_gaps = recording
        x, res, _, ok = diskmap._newton(prob, x0, TOL)
        assert ok and res < 5e-14
        return _Problem.gaps(x), flags, res

    default = diskmap.CHORD_BELOW
    g_full, flags_full, _ = solve(0.0)
    g_chord, flags_chord, _ = solve(0.1)  # one Jacobian (at x0), then chord steps only
    g_def, flags_def, _ = solve(default)
    assert all(flags_full)
    assert flags_chord.count(True) == 1 and len(flags_chord) > len(flags_full)
    assert not flags_def[-1] and flags_def.count(True) < flags_full.count(True)
    for g in (g_chord, g_def):
        assert np.max(np.abs(g - g_full) / g_full) < 1e-11


def test_coarse_jacobians_reach_the_same_root() -> None:
    """Far from the root Newton forms its Jacobians with the coarse rule; the root, and the
    residual it reports, are those of the full rule (as when every evaluation uses it)."""
    from quadmesh.benchmark import smooth_star
    from quadmesh.conformal import diskmap

    w = smooth_star(150, seed=150) @ np.array([1, 1j])
    c = complex(inscribed_center(w)[0])
    x0 = diskmap._x_from_gaps(diskmap._harmonic_gaps(w, c))

    def solve(coarse: bool) -> tuple[np.ndarray, list[tuple[bool, bool]], _Problem]:
        prob = _Problem(w, c, 12)
        if not coarse:
            prob.rules_coarse = None
        flags: list[tuple[bool, bool]] = []
        inner = prob.evaluate_gaps

        def recording(gaps: np.ndarray, jacobian: bool = True):
            flags.append((jacobian, prob.coarse(jacobian)))
            return inner(gaps, jacobian)

        prob.evaluate_gaps = recording
        x, res, _, ok = diskmap._newton(prob, x0, TOL)
        assert ok and res < 5e-14
        assert not prob.coarse_jacobian  # restored
        # the reported residual is the full rule's
        full = _Problem(w, c, 12).evaluate(x, jacobian=False)[0]
        assert np.max(np.abs(full)) < 5e-14
        return _Problem.gaps(x), flags, prob

    g_full, flags_full, _ = solve(False)
    g_coarse, flags_coarse, prob = solve(True)
    assert not any(co for _, co in flags_full)
    assert any(co for _, co in flags_coarse)
    # only Jacobian evaluations use the coarse rule, and the last evaluation is a full one
    assert all(jac for jac, co in flags_coarse if co) and not flags_coarse[-1][1]
    assert np.max(np.abs(g_coarse - g_full) / g_full) < 1e-11
    assert prob.rules_coarse[0].shape[1] == diskmap.COARSE_NODES


def test_solved_map_reuses_the_rotated_integrals() -> None:
    """The solved map takes its side integrals from the solve (rotated to the polygon's own
    vertex order): they agree with integrals computed afresh at its prevertices."""
    from quadmesh.benchmark import smooth_star

    w = smooth_star(60, seed=3) @ np.array([1, 1j])
    w = np.roll(w, 17)  # the solve rolls the longest side to the end
    dm = DiskMap.from_polygon(w)
    _, _, _, S, Ic = dm._prob.evaluate_gaps(dm.gaps, jacobian=False)
    assert np.max(np.abs(dm._S / S - 1)) < 1e-13
    assert abs(dm._Ic / Ic - 1) < 1e-13
    assert dm.residual < 5e-14
    assert_map_checks(dm)


def _random_configuration(n: int, seed: int, crowd: bool):
    from quadmesh.conformal.quadrature import Configuration, plan_integrals

    rng = np.random.default_rng(seed)
    gaps = rng.uniform(0.2, 1.8, n)
    if crowd:  # a tenth of the gaps 1e-6 of the others: clusters of near prevertices
        gaps[rng.integers(0, n, n // 10)] *= 1e-6
    gaps *= 2 * np.pi / gaps.sum()
    beta = rng.uniform(-0.6, 0.6, n)
    beta -= (beta.sum() + 2.0) / n
    cfg = Configuration(gaps, beta)
    k = np.arange(n)
    h1, h2 = cfg.half_offsets()
    # the parameter problem's integrals: half sides from both ends, and z_0 → 0 (long: direct)
    base = np.r_[k, (k + 1) % n, 0]
    end = np.r_[h1, h2, -cfg.z[0]]
    plan = plan_integrals(cfg, base, np.zeros(2 * n + 1, complex), end, np.ones(2 * n + 1, bool))
    return cfg, plan, beta


@pytest.mark.parametrize(("n", "crowd"), [(150, False), (400, False), (400, True)])
def test_far_field_sums_match_direct_sums(n: int, crowd: bool) -> None:
    """The far-field route (one Taylor expansion per integral for the prevertices far from its
    nodes) gives the side integrals and their θ-derivatives of the direct sums."""
    from quadmesh.conformal.quadrature import _far_split, _nodes, integrate, make_rules

    cfg, plan, beta = _random_configuration(n, n, crowd)
    owner, base, d, _, _ = _nodes(cfg, plan, make_rules(beta, 6), 6)
    o = np.argsort(owner, kind="stable")
    _, ok, *_ = _far_split(cfg, owner[o], base[o], d[o])
    assert ok.mean() > 0.9 and not ok[-1]  # the centre integral crosses the disk: direct
    for m, jac in ((12, False), (6, True)):
        rules = make_rules(beta, m)
        H0, J0 = integrate(cfg, plan, rules, jacobian=jac, far=False)
        H1, J1 = integrate(cfg, plan, rules, jacobian=jac, far=True)
        assert np.max(np.abs(H1 - H0) / np.abs(H0)) < 1e-13
        if jac:
            row = np.abs(J0).max(axis=1)
            assert np.max(np.abs(J1 - J0).max(axis=1) / row) < 1e-11


def test_far_field_sums_match_long_double_integrands() -> None:
    """An independent reference: the same quadrature nodes and weights with the integrand
    Π (1 − s/z_j)^{β_j} summed in long double; both routes agree with it to ~1e-14."""
    from quadmesh.conformal.quadrature import _nodes, integrate, make_rules

    cfg, plan, beta = _random_configuration(300, 3, False)
    rules = make_rules(beta, 12)
    H0, _ = integrate(cfg, plan, rules, far=False)
    H1, _ = integrate(cfg, plan, rules, far=True)
    owner, base, d, W, _ = _nodes(cfg, plan, rules, 12)
    th = np.concatenate([[0.0], np.cumsum(cfg.gaps[:-1].astype(np.longdouble))])
    z = (np.cos(th) + 1j * np.sin(th)).astype(np.clongdouble)
    bl = beta.astype(np.clongdouble)
    for i in np.random.default_rng(5).choice(2 * cfg.n, 20, replace=False):
        sel = np.flatnonzero(owner == i)
        b = base[sel[0]]
        s = z[b] + d[sel].astype(np.clongdouble)
        L = np.log(1 - s[:, None] / z[None, :])
        L[:, b] = 0
        ref = complex((W[sel].astype(np.clongdouble) * np.exp(L @ bl)).sum())
        assert abs(H0[i] - ref) < 1e-13 * abs(ref)
        assert abs(H1[i] - ref) < 1e-13 * abs(ref)


def test_a_map_that_would_not_fit_in_memory_is_refused_before_it_is_solved(monkeypatch) -> None:
    # the parameter problem's dense arrays take ~80 bytes per squared vertex count at their
    # peak: with 0.5 GB available a 3,000-gon (0.72 GB) is refused at once, naming how many
    # vertices would fit, and a 2,000-gon (0.32 GB of 0.375 allowed) is not
    import time

    from quadmesh.conformal import diskmap

    monkeypatch.setattr(diskmap, "available_memory", lambda: 0.5e9)
    t0 = time.perf_counter()
    with pytest.raises(ConformalMapError) as info:
        DiskMap.from_polygon(random_star(3000, 0.9, 1.1, 0))
    assert time.perf_counter() - t0 < 2.0
    assert info.value.too_large
    msg = str(info.value)
    assert "about 0.72 GB for 3000 vertices" in msg and "about 2165 vertices fit" in msg
    assert "Simplify the outline" in msg
    diskmap._memory_check(2000)  # no error


def test_the_jacobian_made_a_block_of_rows_at_a_time_is_the_dense_one() -> None:
    # the parameter problem's Jacobian is assembled from gap_jacobian on blocks of rows (and
    # the chain rule applied in place); against the whole-matrix formula it was built from,
    # on a smooth star (far-field sums, 3 blocks of rows when the block is lowered to 40,000
    # entries) and the L-shape (direct sums): the same entries to rounding
    from quadmesh.conformal import diskmap
    from quadmesh.conformal.quadrature import gap_jacobian, integrate, plan_integrals

    rng = np.random.default_rng(0)
    for w in (random_star(300, 0.95, 1.05, 3), np.array([0, 2, 2 + 1j, 1 + 1j, 1 + 2j, 2j])):
        dm = DiskMap.from_polygon(w)
        prob = dm._prob
        n = prob.n
        gaps = dm.gaps * np.exp(rng.uniform(-0.01, 0.01, n))
        gaps *= 2 * np.pi / gaps.sum()
        cfg = diskmap.Configuration(gaps, prob.beta)
        k = np.arange(n)
        h1, h2 = cfg.half_offsets()
        base = np.r_[k, (k + 1) % n, 0]
        end = np.r_[h1, h2, -cfg.z[0]]
        plan = plan_integrals(
            cfg, base, np.zeros(2 * n + 1, complex), end, np.ones(2 * n + 1, bool)
        )
        H, J = integrate(cfg, plan, prob.rules, jacobian=True)
        S, Ic = H[:n] - H[n : 2 * n], H[2 * n]
        G = gap_jacobian(cfg, plan, H, J)
        dlogS = (G[:n] - G[n : 2 * n]) / S[:, None]
        r = prob.ref
        dcen = G[2 * n] / Ic - dlogS[r]
        dense = np.vstack([(dlogS[prob.eqs] - dlogS[r]).real, dcen.real, dcen.imag])
        chained = dense * gaps - np.outer(dense @ gaps, gaps) / (2 * np.pi)
        old = diskmap._GAP_ROWS_ENTRIES
        try:
            diskmap._GAP_ROWS_ENTRIES = 40_000
            _, Jx, *_ = prob.evaluate_gaps(gaps)
        finally:
            diskmap._GAP_ROWS_ENTRIES = old
        assert np.max(np.abs(Jx - chained[:, :-1])) < 1e-12 * np.max(np.abs(chained))


def test_a_crowded_map_solved_with_small_blocks_of_jacobian_rows_is_the_same_map() -> None:
    # under crowding the Jacobian's entries come from differences of large terms, and a block
    # of rows rounds them differently from the whole matrix (1e-16 of terms of 1e6); Newton's
    # solution does not depend on it
    from quadmesh.conformal import diskmap

    w = random_star(300, 0.8, 1.2, 3)
    dm = DiskMap.from_polygon(w)
    assert dm.gaps.min() < 1e-10
    old = diskmap._GAP_ROWS_ENTRIES
    try:
        diskmap._GAP_ROWS_ENTRIES = 1_000
        dm2 = DiskMap.from_polygon(w)
    finally:
        diskmap._GAP_ROWS_ENTRIES = old
    assert np.max(np.abs(dm2.gaps / dm.gaps - 1)) < 1e-9
    assert dm2.residual < 1e-12


def test_a_configuration_releases_its_differences_and_makes_them_again_the_same() -> None:
    # an evaluation leaves no n × n array behind: the differences are made again, bit for bit,
    # where the configuration is used later (the solved map's evaluations)
    from quadmesh.conformal.quadrature import Configuration

    rng = np.random.default_rng(5)
    gaps = rng.uniform(0.1, 1.0, 400)
    gaps[100:110] *= 1e-12  # crowded: local differences matter
    gaps *= 2 * np.pi / gaps.sum()
    cfg = Configuration(gaps, rng.uniform(-0.5, 0.5, 400))
    E = cfg.E.copy()
    cfg.release()
    assert cfg._E is None
    assert np.array_equal(cfg.E, E)
    # z_j − z_b against exact sums of the gaps (math.fsum, the shorter way round), relative
    # to their own size: z_b (e^{iΔ} − 1) = z_b 2i sin(Δ/2) e^{iΔ/2}
    import math

    for b in (0, 105, 399):
        for j in (1, 100, 104, 106, 109, 110, 250, 398):
            if j == b:
                continue
            fwd = math.fsum(np.roll(gaps, -b)[: (j - b) % 400])
            d = fwd if fwd <= math.pi else -math.fsum(np.roll(gaps, -j)[: (b - j) % 400])
            ref = cfg.z[b] * 2j * math.sin(d / 2) * np.exp(0.5j * d)
            assert abs(E[b, j] - ref) < 1e-14 * abs(ref)


def test_the_pipeline_refuses_a_polygon_too_large_for_memory_without_other_routes(
    monkeypatch,
) -> None:
    # no arm, bridge or chain is tried for such a part: the message comes at once
    import time

    from quadmesh import MeshOptions, mesh_polygon
    from quadmesh.conformal import diskmap

    monkeypatch.setattr(diskmap, "available_memory", lambda: 1e6)
    t0 = time.perf_counter()
    with pytest.raises(ConformalMapError) as info:
        mesh_polygon(random_star(200, 0.8, 1.2, 1), MeshOptions())
    assert time.perf_counter() - t0 < 10.0
    assert info.value.too_large and "this machine has available" in str(info.value)
    assert str(info.value).startswith("[conformal] the part of the polygon through vertices")
