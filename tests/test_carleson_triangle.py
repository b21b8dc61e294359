"""Tests of the model Carleson-triangle mesh (Bishop §6, Lemma 6.1; DISK.md §6) and circles.py."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from quadmesh.disk import circles as gc
from quadmesh.disk.carleson_triangle import (
    REGION_NAMES,
    chord_angles,
    depth_sequence,
    model_triangle_mesh,
    right_side_point,
    trace_leaf,
    triangle_landmarks,
)
from quadmesh.errors import DiskConstructionError

SQ2 = math.sqrt(2.0)
W = 1j * (1 + SQ2)


def _rho_h(z, w):
    """Hyperbolic distance in H (|dz|/y), independent of the module."""
    return 2 * np.arcsinh(np.abs(z - w) / (2 * np.sqrt(np.imag(z) * np.imag(w))))


def _arc_green(a, r, t1, t2):
    """½∮(x dy − y dx) along a + r e^{iθ}, θ: t1 → t2."""
    return 0.5 * (
        r * r * (t2 - t1) + r * np.real(np.conj(a) * (np.exp(1j * t2) - np.exp(1j * t1)) / 1j)
    )


def _area_T():
    """Area of T from its circular-arc boundary: base −1→1, right side 1→w, left side w→−1."""
    c, r = 1 + SQ2, 2 + SQ2
    right = _arc_green(-c, r, 0.0, math.pi / 4)  # centre −(1+√2): 1 at θ=0, w at θ=π/4
    left = _arc_green(c, r, 3 * math.pi / 4, math.pi)  # centre 1+√2: w at 3π/4, −1 at π
    return right + left


def _edges(q):
    e = np.stack([q, np.roll(q, -1, axis=1)], axis=-1).reshape(-1, 2)
    return e


# ------------------------------------------------------------------------------------ landmarks


def test_landmarks_h1_and_h_independence():
    lm = triangle_landmarks(1.0)
    assert (round(lm.D1, 4), round(lm.D3, 4), round(lm.D5, 4)) == (0.6035, 1.0390, 1.7497)
    assert abs(lm.v1 - (-0.6667 + 1.4714j)) < 1e-4
    assert abs(lm.v3 - (-0.8564 + 0.9796j)) < 1e-4
    assert abs(lm.v5 - (-0.9648 + 0.4891j)) < 1e-4
    for h, d1 in [(1.5, 0.333), (0.5, 1.006), (0.25, 1.308)]:
        other = triangle_landmarks(h)
        assert round(other.D1, 3) == d1
        assert abs((other.D3 - other.D1) - (lm.D3 - lm.D1)) < 1e-12
        assert abs((other.D5 - other.D3) - (lm.D5 - lm.D3)) < 1e-12
    # D_k are the hyperbolic distances from w; v2, v4, v6 mirror v1, v3, v5.
    for z, dd in [(lm.v1, lm.D1), (lm.v3, lm.D3), (lm.v5, lm.D5)]:
        assert abs(_rho_h(z, W) - dd) < 1e-12
    assert abs(lm.v2 + np.conj(lm.v1)) < 1e-15
    # T_i: vertices an equilateral triangle of side h(√3−1); spokes c–m_L pass through b_R.
    h = 0.7
    lm = triangle_landmarks(h)
    for a, b in [(lm.v, lm.b_L), (lm.b_L, lm.b_R), (lm.b_R, lm.v)]:
        assert abs(abs(a - b) - h * (math.sqrt(3) - 1)) < 1e-14
    assert abs(np.imag((lm.m_L - lm.c) * np.conj(lm.b_R - lm.c))) < 1e-14


def test_landmarks_reject_bad_h():
    for h in (0.0, -1.0, 1 + SQ2, 3.0, float("nan")):
        with pytest.raises(DiskConstructionError):
            triangle_landmarks(h)


# ------------------------------------------------------------------------------- depth sequence


def test_depth_sequence():
    lm = triangle_landmarks(1.0)
    d = depth_sequence(1.0, 0.25)
    assert d[0] == 0.0 and abs(d[-1] - (math.log(32.0) + 2.0)) < 1e-15
    assert np.all(np.diff(d) > 0) and np.all(np.diff(d) <= 0.25 + 1e-15)
    for D in (lm.D1, lm.D3, lm.D5):
        assert np.count_nonzero(d == D) == 1
    # equal steps within each knot interval: ceil(len/step) of them
    knots = [0.0, lm.D1, lm.D3, lm.D5, d[-1]]
    for a, b in itertools.pairwise(knots):
        seg = d[(d >= a) & (d <= b)]
        assert len(seg) - 1 == math.ceil((b - a) / 0.25)
        assert np.ptp(np.diff(seg)) < 1e-14
    assert len(d) == 24
    d2 = depth_sequence(0.5, 0.5, d_max=4.0)
    assert d2[-1] == 4.0 and triangle_landmarks(0.5).D5 in d2
    with pytest.raises(DiskConstructionError):
        depth_sequence(1.0, 0.25, d_max=1.0)
    with pytest.raises(DiskConstructionError):
        depth_sequence(1.0, 0.0)


# ------------------------------------------------------------------------------ mesh conformity

CASES = [(1.0, 0.25), (0.25, 0.5), (2.3, 0.25), (0.4, 0.125)]


@pytest.mark.parametrize(("h", "step"), CASES)
def test_model_mesh_conformity(h, step):
    m = model_triangle_mesh(depth_sequence(h, step), h)
    V, q = len(m.vertices), m.quads
    assert np.array_equal(np.unique(q), np.arange(V))
    e = _edges(q)
    key = np.sort(e, axis=1)
    uniq, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    assert cnt.max() == 2
    # Interior edges appear twice with opposite orientation.
    inv = inv.ravel()
    for k in np.flatnonzero(cnt == 2)[:: max(1, len(cnt) // 400)]:
        a, b = e[inv == k]
        assert a[0] == b[1] and a[1] == b[0]
    fwd = {tuple(x) for x in e}
    assert all((b, a) in fwd for a, b in e[cnt[inv] == 2])
    # Euler characteristic of a disk.
    assert V - len(uniq) + len(q) == 1
    # Unpaired edges are exactly the consecutive boundary pairs (no hanging vertex on ∂T).
    unpaired = {tuple(x) for x in uniq[cnt == 1]}
    bnd = set()
    for chain in (m.left, m.right, m.base):
        bnd |= {tuple(sorted(p)) for p in zip(chain[:-1].tolist(), chain[1:].tolist())}
    assert unpaired == bnd
    # No vertex in the interior of an unpaired (chord) edge.
    z = m.vertices
    ua = np.array(sorted(unpaired))
    a, b = z[ua[:, 0]], z[ua[:, 1]]
    t = np.real((z[None, :] - a[:, None]) / (b - a)[:, None])
    dist = np.abs(z[None, :] - (a[:, None] + np.clip(t, 0, 1) * (b - a)[:, None]))
    inside = (t > 1e-9) & (t < 1 - 1e-9) & (dist < 1e-9 * np.abs(b - a)[:, None])
    assert not inside.any()
    # Positively oriented quads.
    zq = z[q]
    area = 0.5 * np.sum(np.imag(np.conj(zq) * np.roll(zq, -1, axis=1)), axis=1)
    assert area.min() > 0
    # Area: quads + circular segments of the boundary edges on the two sides = area of T.
    seg = 0.0
    r = 2 + SQ2
    for chain in (m.left, m.right):
        chord = np.abs(np.diff(z[chain]))
        phi = 2 * np.arcsin(chord / (2 * r))
        seg += np.sum(r * r * (phi - np.sin(phi)) / 2)
    assert abs(area.sum() + seg - _area_T()) < 1e-10 * _area_T()
    # Mirror symmetry of the vertex set in the imaginary axis.
    zs = np.sort_complex(np.round(z, 10))
    zm = np.sort_complex(np.round(-np.conj(z), 10))
    assert np.allclose(zs, zm, atol=1e-9)


@pytest.mark.parametrize(("h", "step"), [(1.0, 0.25), (0.25, 0.125)])
def test_sides_base_and_fields(h, step):
    d = depth_sequence(h, step)
    m = model_triangle_mesh(d, h)
    M = len(d) - 1
    assert len(m.left) == len(m.right) == M + 2
    z = m.vertices
    assert z[m.left[0]] == W and z[m.right[0]] == W
    assert z[m.left[-1]] == -1 and z[m.right[-1]] == 1
    for side in (m.left, m.right):
        assert np.max(np.abs(_rho_h(z[side[1:-1]], W) - d[1:])) < 1e-12
    lm = m.landmarks
    assert z[m.left[np.flatnonzero(d == lm.D1)[0]]] == pytest.approx(lm.v1, abs=1e-14)
    b = z[m.base]
    assert np.all(b.imag == 0) and np.all(np.diff(b.real) > 0)
    assert b[0] == -1 and b[-1] == 1
    for p in (lm.v7, lm.v8, 0.0):
        assert np.min(np.abs(b - p)) < 1e-15
    # inner quads lie in T_i and use only inner vertices; c is a vertex
    assert m.inner_vertex[m.quads[m.inner]].all()
    ic = np.flatnonzero(z == m.center)
    assert len(ic) == 1 and m.inner_vertex[ic[0]]
    assert set(np.unique(m.region)) == set(range(len(REGION_NAMES)))
    assert np.array_equal(m.inner, m.region >= 9)


# ---------------------------------------------------------------------------------- leaf routes


@pytest.mark.parametrize("h", [1.0, 0.25, 2.0])
def test_leaf_symmetry(h):
    lm = triangle_landmarks(h)
    # Crossing leaves (d > D3) end on the right side at the same depth.
    for d in np.r_[np.linspace(lm.D3, lm.D5, 6)[1:-1], lm.D5 + np.array([0.1, 1.0, 3.0])]:
        end = trace_leaf(d, h)[-1]
        assert abs(end - right_side_point(d)) < 1e-14
        end_r = trace_leaf(d, h, side="right")[-1]
        assert abs(end_r - (-np.conj(right_side_point(d)))) < 1e-14
    # Leaves with d < D3 reach the base: (v8, 1) for d < D1, (0, v8) for D1 < d < D3.
    for d in np.linspace(0, lm.D1, 5)[1:-1]:
        end = trace_leaf(d, h)[-1]
        assert abs(end.imag) < 1e-14 and lm.v8.real < end.real < 1
    for d in np.linspace(lm.D1, lm.D3, 5)[1:-1]:
        end = trace_leaf(d, h)[-1]
        assert abs(end.imag) < 1e-14 and 0 < end.real < lm.v8.real


def test_axis_vertices_lie_on_axis():
    """Leaves d > D5 cross the imaginary axis below m_B once each, exactly on the axis."""
    h, step = 1.0, 0.25
    m = model_triangle_mesh(depth_sequence(h, step), h)
    lm = m.landmarks
    d = m.depths
    # Vertices on the imaginary axis below m_B (leaves d > D5): symmetric by construction only
    # if the foliations are; they must lie on the axis.
    z = m.vertices
    on_axis = z[(np.abs(z.real) < 1e-9) & (z.imag < lm.m_B.imag) & (z.imag > 0)]
    assert len(on_axis) == np.count_nonzero(d > lm.D5)
    assert np.max(np.abs(on_axis.real)) < 1e-14


# ---------------------------------------------------------------------------------------- angles

# (h, step, cells, cells in T_i, T_i min, outside min, outside max); DISK.md §6 table
TABLE = [
    (1.5, 0.5, 44, 5, 73.05, 78.06, 101.94),
    (1.0, 0.25, 215, 16, 70.61, 82.43, 97.57),
    (0.25, 0.25, 336, 16, 70.61, 81.84, 98.16),
    (1.0, 1 / 16, 3519, 217, 62.99, 87.61, 92.39),
]


@pytest.mark.parametrize(("h", "step", "n", "ni", "imin", "omin", "omax"), TABLE)
def test_chord_angle_table(h, step, n, ni, imin, omin, omax):
    m = model_triangle_mesh(depth_sequence(h, step), h)
    a = chord_angles(m.vertices, m.quads)
    assert len(m.quads) == n and m.inner.sum() == ni
    ai, ao = a[m.inner], a[~m.inner]
    assert ai.min() >= 60 and ai.max() <= 120 + 1e-9
    assert abs(ai.min() - imin) < 0.01 and abs(ai.max() - 120) < 1e-9
    # the 120° angles are at c: three quads meet there with exactly 120°
    ic = np.flatnonzero(m.vertices == m.center)[0]
    at_c = a[m.quads == ic]
    assert len(at_c) == 3 and np.allclose(at_c, 120, atol=1e-9)
    assert abs(ao.min() - omin) < 0.01 and abs(ao.max() - omax) < 0.01
    assert np.allclose(np.sum(a, axis=1), 360)


# ------------------------------------------------------------------------------------ errors


def test_mesh_rejects_bad_depths():
    d = depth_sequence(1.0, 0.25)
    with pytest.raises(DiskConstructionError):
        model_triangle_mesh(d, 0.5)  # landmarks of another h
    with pytest.raises(DiskConstructionError):
        model_triangle_mesh(d[d <= triangle_landmarks(1.0).D5], 1.0)
    with pytest.raises(DiskConstructionError):
        model_triangle_mesh(d[::-1], 1.0)


# ------------------------------------------------------------------------------------ circles.py


def test_circles_primitives():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(3, 50)) + 1j * rng.normal(size=(3, 50))
    c = gc.circle_through(z[0], z[1], z[2])
    for k in range(3):
        assert np.max(np.abs(gc.evaluate(c, z[k]))) < 1e-10
    assert np.allclose(np.abs(c.B) ** 2 - c.A * c.C, 1)
    # collinear → exact line
    ln = gc.circle_through(0.1 + 0.2j, 0.3 + 0.6j, 1.0 + 2.0j * (1 + 1e-16))
    assert ln.A == 0 and abs(gc.evaluate(ln, 2 + 4j)) < 1e-12
    # inversion is an involution and fixes the circle
    cc = gc.circle_from_center(0.3 - 0.1j, 1.7)
    p = rng.normal(size=20) + 1j * rng.normal(size=20)
    assert np.allclose(gc.invert(gc.invert(p, cc), cc), p)
    assert np.allclose(gc.invert(0.3 - 0.1j + 1.7j, cc), 0.3 - 0.1j + 1.7j)
    # circle ∩ circle, line ∩ circle, line ∩ line
    c1, c2 = gc.circle_from_center(0, 1), gc.circle_from_center(1, 1)
    za, zb = gc.intersect(c1, c2)
    assert np.allclose(sorted([za.imag, zb.imag]), [-math.sqrt(3) / 2, math.sqrt(3) / 2])
    assert np.allclose([za.real, zb.real], 0.5)
    za, zb = gc.intersect(gc.line_through(0, 1), c2)
    assert np.allclose(sorted([za.real, zb.real]), [0, 2])
    x = gc.intersect_lines(gc.line_through(0, 1 + 1j), gc.line_through(2, 2 + 1j))
    assert abs(x - (2 + 2j)) < 1e-14
    za, zb = gc.intersect(c1, gc.circle_from_center(5, 1))
    assert np.isnan(za) and np.isnan(zb)
    # orthogonal circle with tangent: through p, tangent τ, orthogonal to the target
    tgt = gc.circle_from_center(1 + SQ2, 2 + SQ2)
    o = gc.orthogonal_circle_with_tangent(1j, np.exp(3j * math.pi / 4), tgt)
    assert abs(gc.evaluate(o, 1j)) < 1e-14 and abs(gc.inversive_distance(o, tgt)) < 1e-14
    cen, _ = gc.center_radius(o)
    assert abs(np.real((1j - cen) * np.conj(np.exp(3j * math.pi / 4)))) < 1e-14
    # cross-ratio separation sign
    u = np.exp(1j * np.array([0.0, 1.0, 2.0, 3.0]))
    assert gc.cross_ratio(u[0], u[2], u[1], u[3]).real < 0
    assert gc.cross_ratio(u[0], u[1], u[2], u[3]).real > 0


def test_depth_growth_below_d5_keeps_angles():
    """Geometric coarsening below D5 (DISK.md §7 open question): same angles, fewer quads."""
    h = 1.0
    lm = triangle_landmarks(h)
    d1 = depth_sequence(h, 0.25)
    d2 = depth_sequence(h, 0.25, growth=2.0)
    assert np.array_equal(d1[d1 <= lm.D5], d2[d2 <= lm.D5]) and d2[-1] == d1[-1]
    steps = np.diff(d2[d2 >= lm.D5])
    assert steps[0] <= 0.25 and np.all(np.diff(steps) > 0)
    a1 = chord_angles(*_vq(model_triangle_mesh(d1, h)))
    m2 = model_triangle_mesh(d2, h)
    a2 = chord_angles(m2.vertices, m2.quads)
    assert len(m2.quads) == 105 and len(a1) == 215
    assert abs(a2[~m2.inner].min() - 82.43) < 0.01 and abs(a2[~m2.inner].max() - 97.57) < 0.01
    with pytest.raises(DiskConstructionError):
        depth_sequence(h, 0.25, growth=0.5)


def _vq(m):
    return m.vertices, m.quads
