"""Tests of the hyperbolic toolkit quadmesh.hyperbolic (paper §2, DISK.md §1)."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.hyperbolic import (
    Isometry,
    apply_isometries,
    cayley_d_to_h,
    cayley_h_to_d,
    disk_automorphism,
    distance,
    distance_h,
    einstein_midpoint,
    geodesic_circle,
    geodesic_coordinates,
    geodesic_distance,
    geodesic_endpoints_through,
    geodesic_top_point,
    hypercycle_circle,
    hypercycle_frame,
    hypercycle_point,
    intersect_geodesics,
    mobius_apply,
    mobius_from_points,
    perpendicular_geodesic,
    point_towards,
    reflect,
    reflection,
    side_of_geodesic,
    tangent_direction,
)

TOL = 1e-12


def rand_disk(rng: np.random.Generator, n: int, rmax: float = 0.9) -> np.ndarray:
    r = rmax * np.sqrt(rng.random(n))
    return r * np.exp(2j * np.pi * rng.random(n))


def rand_unit(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.exp(2j * np.pi * rng.random(n))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def rand_isometry(rng: np.random.Generator, sigma: bool = False) -> Isometry:
    g = disk_automorphism(complex(rand_disk(rng, 1, 0.95)[0]), np.exp(2j * np.pi * rng.random()))
    if sigma:
        return g.compose(Isometry(np.eye(2), True))
    return g


def test_distance_invariant_under_automorphisms(rng):
    z = rand_disk(rng, 200)
    w = rand_disk(rng, 200)
    d0 = distance(z, w)
    for _ in range(5):
        g = rand_isometry(rng, sigma=bool(rng.integers(2)))
        assert np.max(np.abs(distance(g(z), g(w)) - d0) / np.maximum(d0, 1)) < TOL
    # against the artanh formula
    d1 = 2 * np.arctanh(np.abs(z - w) / np.abs(1 - np.conj(w) * z))
    assert np.max(np.abs(d0 - d1)) < 1e-11
    # from 0: log((1+x)/(1-x))
    x = np.linspace(0.0, 0.99, 50)
    assert np.max(np.abs(distance(0, x) - np.log((1 + x) / (1 - x)))) < TOL


def test_cayley_is_isometry(rng):
    z = rand_disk(rng, 100)
    w = rand_disk(rng, 100)
    hz, hw = cayley_d_to_h(z), cayley_d_to_h(w)
    assert np.all(hz.imag > 0)
    assert np.max(np.abs(distance_h(hz, hw) - distance(z, w))) < 1e-11
    assert np.max(np.abs(cayley_h_to_d(hz) - z)) < TOL


def test_composition_and_inverse(rng):
    z = rand_disk(rng, 50)
    for s1 in (False, True):
        for s2 in (False, True):
            f = rand_isometry(rng, s1)
            g = rand_isometry(rng, s2)
            fg = f @ g
            assert np.max(np.abs(fg(z) - f(g(z)))) < TOL
            assert bool(fg.sigma) == (s1 ^ s2)
            assert np.max(np.abs(fg.inverse()(fg(z)) - z)) < TOL
            assert np.max(np.abs(f.inverse()(f(z)) - z)) < TOL


def test_stacked_isometries(rng):
    gs = [rand_isometry(rng, bool(rng.integers(2))) for _ in range(7)]
    st = Isometry.stack(gs)
    z = rand_disk(rng, 11)
    out = st.apply_rows(z)
    assert out.shape == (7, 11)
    for i, g in enumerate(gs):
        assert np.max(np.abs(out[i] - g(z))) < TOL
    zz = rand_disk(rng, 7 * 5).reshape(7, 5)
    out2 = apply_isometries(st.M, st.sigma, zz)
    for i, g in enumerate(gs):
        assert np.max(np.abs(out2[i] - g(zz[i]))) < TOL
    # stacked composition / inverse agree with single ones
    h = rand_isometry(rng, True)
    comp = st @ Isometry(np.broadcast_to(h.M, (7, 2, 2)), np.full(7, True))
    inv = st.inverse()
    for i, g in enumerate(gs):
        assert np.max(np.abs(comp[i](z) - g(h(z)))) < TOL
        assert np.max(np.abs(inv[i](g(z)) - z)) < TOL


def test_automorphism_and_three_point_map(rng):
    a = 0.3 - 0.5j
    g = disk_automorphism(a, 1j)
    assert abs(g(a)) < TOL
    t = rand_unit(rng, 20)
    assert np.max(np.abs(np.abs(g(t)) - 1)) < TOL
    src = rand_disk(rng, 3)
    dst = rand_disk(rng, 3) + 2.0
    m = mobius_from_points(src, dst)
    assert np.max(np.abs(m(src) - dst)) < 1e-11
    assert abs(mobius_apply(np.eye(2), 1 + 2j) - (1 + 2j)) < TOL


def test_geodesics_meet_circle_orthogonally(rng):
    p, q = rand_unit(rng, 100), rand_unit(rng, 100)
    c, r = geodesic_circle(p, q)
    # on the circle, and orthogonal to T: the radius c-p is tangent to T at p
    assert np.max(np.abs(np.abs(p - c) - r) / np.maximum(r, 1)) < 1e-13
    assert np.max(np.abs(np.abs(q - c) - r) / np.maximum(r, 1)) < 1e-13
    for e in (p, q):
        assert np.max(np.abs((np.conj(e) * (c - e)).real) / np.maximum(r, 1)) < 1e-13
    # top point is on the circle and nearest 0
    t = geodesic_top_point(p, q)
    assert np.max(np.abs(np.abs(t - c) - r) / np.maximum(r, 1)) < 1e-13
    assert np.max(np.abs(np.abs(t) - (np.abs(c) - r))) < 1e-11


def test_geodesic_through_points_and_point_towards(rng):
    z1, z2 = rand_disk(rng, 100), rand_disk(rng, 100)
    p, q = geodesic_endpoints_through(z1, z2)
    assert np.max(np.abs(side_of_geodesic(p, q, z1 + 0 * z2) * 0)) == 0
    c, r = geodesic_circle(p, q)
    assert np.max(np.abs(np.abs(z1 - c) - r) / r) < 1e-11
    assert np.max(np.abs(np.abs(z2 - c) - r) / r) < 1e-11
    d = distance(z1, z2)
    # p, z1, z2, q in order: distances add up
    m = point_towards(z1, z2, 0.37 * d)
    assert np.max(np.abs(distance(z1, m) - 0.37 * d)) < 1e-11
    assert np.max(np.abs(distance(m, z2) - 0.63 * d)) < 1e-11
    assert np.max(np.abs(point_towards(z1, z2, d) - z2)) < 1e-11
    # towards the ideal endpoint q goes through z2
    assert np.max(np.abs(point_towards(z1, q, d) - z2)) < 1e-10


def test_perpendicular_and_klein_intersection(rng):
    p = rand_unit(rng, 80)
    q = p * np.exp(1j * rng.uniform(0.5, 2 * np.pi - 0.5, 80))  # keep x away from T
    x = point_towards(geodesic_top_point(p, q), q, rng.normal(size=80))
    pp, qq = perpendicular_geodesic(p, q, x)
    k = intersect_geodesics(p, q, pp, qq)
    assert np.max(np.abs(k - x)) < 1e-11
    # angle at x is 90 degrees
    t1 = tangent_direction(x, q)
    t2 = tangent_direction(x, qq)
    assert np.max(np.abs(np.abs(np.angle(t2 / t1)) - np.pi / 2)) < 1e-10
    # qq lies on the left of p->q
    assert np.all(side_of_geodesic(p, q, point_towards(x, qq, 0.5)) > 0)
    # random crossing geodesics: intersection lies on both
    a, b = rand_unit(rng, 200), rand_unit(rng, 200)
    c, d = rand_unit(rng, 200), rand_unit(rng, 200)
    z = intersect_geodesics(a, b, c, d)
    ok = np.isfinite(z)
    assert ok.sum() > 30 and (~ok).sum() > 30
    for u, v in ((a, b), (c, d)):
        cc, rr = geodesic_circle(u[ok], v[ok])
        assert np.max(np.abs(np.abs(z[ok] - cc) - rr) / np.maximum(rr, 1)) < 1e-10
    # non-crossing ones are separated: c and d on the same side of (a, b)
    s1 = np.sign(((np.conj(b - a)) * (c - a)).imag)
    s2 = np.sign(((np.conj(b - a)) * (d - a)).imag)
    assert np.all((s1 == s2) == ~ok)


def test_reflections(rng):
    p, q = rand_unit(rng, 60), rand_unit(rng, 60)
    z = rand_disk(rng, 60)
    rz = reflect(p, q, z)
    assert np.max(np.abs(reflect(p, q, rz) - z)) < 1e-11
    # agrees with inversion in the circle
    c, r = geodesic_circle(p, q)
    assert np.max(np.abs(rz - (c + r**2 / np.conj(z - c)))) < 1e-9
    # fixes the geodesic pointwise, swaps sides, is an isometry
    x = point_towards(geodesic_top_point(p, q), q, rng.normal(size=60))
    assert np.max(np.abs(reflect(p, q, x) - x)) < 1e-11
    assert np.all(side_of_geodesic(p, q, z) == -side_of_geodesic(p, q, rz))
    w = rand_disk(rng, 60)
    assert np.max(np.abs(distance(rz, reflect(p, q, w)) - distance(z, w))) < 1e-10
    # Isometry form (stacked) agrees; involution via composition
    R = reflection(p, q)
    assert np.all(R.sigma)
    assert np.max(np.abs(R.apply_rows(z[:, None])[:, 0] - rz)) < 1e-11
    RR = R @ R
    assert np.max(np.abs(RR.apply_rows(z[:, None])[:, 0] - z)) < 1e-11
    # diameter: z -> u^2 conj z
    u = np.exp(0.7j)
    assert np.max(np.abs(reflect(u, -u, z) - u**2 * np.conj(z))) < TOL


def test_geodesic_distance():
    for R in (1.5, 3.0, 20.0):
        assert abs(geodesic_distance(-1, 1, -R, R) - np.log(R)) < TOL
        assert abs(geodesic_distance(-1, 1, R, -R) - np.log(R)) < TOL
    # in D: two geodesics symmetric about 0, perpendicular to the real axis at +-x
    x = 0.4
    p1, q1 = perpendicular_geodesic(-1, 1, x)
    p2, q2 = perpendicular_geodesic(-1, 1, -x)
    assert abs(geodesic_distance(p1, q1, p2, q2) - distance(x, -x)) < 1e-12
    # invariance under cayley
    assert (
        abs(
            geodesic_distance(
                cayley_h_to_d(-1), cayley_h_to_d(1), cayley_h_to_d(-3), cayley_h_to_d(3)
            )
            - np.log(3)
        )
        < 1e-12
    )


def test_einstein_midpoint(rng):
    v = 0.4 * np.exp(2j * np.pi * np.arange(5) / 5)
    assert abs(einstein_midpoint(v)) < TOL
    g = rand_isometry(rng)
    assert abs(einstein_midpoint(g(v)) - g(0)) < 1e-12
    z = rand_disk(rng, 2)
    m = einstein_midpoint(z)
    assert abs(distance(m, z[0]) - distance(m, z[1])) < 1e-12
    assert abs(distance(m, z[0]) * 2 - distance(z[0], z[1])) < 1e-12


def test_hypercycles(rng):
    a, b = rand_unit(rng, 30), rand_unit(rng, 30)
    F = hypercycle_frame(a, b)
    Fi = F.inverse()
    t = geodesic_top_point(a, b)
    for i in range(30):
        assert abs(F[i](t[i]) - 1j) < 1e-12
        assert abs(Fi[i](0.0) - a[i]) < 1e-12
        assert np.all(F[i](rand_disk(rng, 20)).imag > 0)
    s = np.linspace(-2, 2, 9)
    for d in (-1.3, -0.2, 0.5, 2.0):
        z = hypercycle_point(a[:, None], b[:, None], s[None, :], d)
        # equidistant from the geodesic: distance to the foot point = |d|, foot at arclength s
        foot = hypercycle_point(a[:, None], b[:, None], s[None, :], 0.0)
        assert np.max(np.abs(distance(z, foot) - abs(d))) < 1e-11
        assert np.max(np.abs(distance(foot[:, :1], foot) - (s - s[0]))) < 1e-11
        # the segment z-foot is perpendicular to the geodesic
        ang = np.angle(tangent_direction(foot, z) / tangent_direction(foot, b[:, None]))
        assert np.max(np.abs(np.abs(ang) - np.pi / 2)) < 1e-10
        # left side is positive
        assert np.all(side_of_geodesic(a[:, None], b[:, None], z) == np.sign(d))
        ss, dd = geodesic_coordinates(a[:, None], b[:, None], z)
        assert np.max(np.abs(ss - s)) < 1e-11 and np.max(np.abs(dd - d)) < 1e-11
        # on the circle through a and b
        c, r = hypercycle_circle(a, b, d)
        assert np.max(np.abs(np.abs(z - c[:, None]) - r[:, None]) / r[:, None]) < 1e-10
        assert np.max(np.abs(np.abs(a - c) - r) / r) < 1e-10
