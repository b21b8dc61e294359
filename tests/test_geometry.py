"""Tests of the shared plane-geometry helpers quadmesh.geometry (angles, areas, conformity)."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.errors import MeshVerificationError
from quadmesh.geometry import (
    angle_rounding_slack_deg,
    check_conformity,
    quad_angles_deg,
    quad_corners,
    quad_edges,
    quad_signed_areas,
    unpaired_edges,
)

# a 2 x 1 strip of unit squares and a kite with a reflex corner (dart), both counter-clockwise
STRIP_V = np.array([0, 1, 2, 1j, 1 + 1j, 2 + 1j])
STRIP_Q = np.array([[0, 1, 4, 3], [1, 2, 5, 4]])
DART_V = np.array([0, 2 + 1j, 0.5 + 0j, 2 - 1j])  # reflex corner at vertex 2
DART_Q = np.array([[0, 3, 2, 1]])


def test_square_angles_and_areas() -> None:
    np.testing.assert_allclose(quad_angles_deg(STRIP_V, STRIP_Q), 90.0, atol=1e-12)
    np.testing.assert_allclose(quad_signed_areas(STRIP_V, STRIP_Q), [1.0, 1.0])
    # reversed order: clockwise, negative area, angles 360 - 90
    rev = STRIP_Q[:, ::-1]
    np.testing.assert_allclose(quad_signed_areas(STRIP_V, rev), [-1.0, -1.0])
    np.testing.assert_allclose(quad_angles_deg(STRIP_V, rev), 270.0, atol=1e-12)


def test_reflex_corner_reads_above_180() -> None:
    ang = quad_angles_deg(DART_V, DART_Q)[0]
    assert ang[2] > 180.0 and np.all(ang[[0, 1, 3]] < 180.0)
    assert abs(ang.sum() - 360.0) < 1e-9
    # shoelace area of the dart: triangle 0,(2-1j),(2+1j) minus triangle 0.5,(2-1j),(2+1j)
    assert abs(quad_signed_areas(DART_V, DART_Q)[0] - (2.0 - 1.5)) < 1e-12


def test_stacked_copies_match_single_copies() -> None:
    rng = np.random.default_rng(1)
    shift = rng.normal(size=(3, 1)) + 1j * rng.normal(size=(3, 1))
    vs = STRIP_V[None] * np.exp(1j * np.array([[0.1], [1.0], [2.0]])) + shift
    qs = np.stack([STRIP_Q, STRIP_Q[:, [1, 2, 3, 0]], STRIP_Q])
    assert quad_corners(vs, qs).shape == (3, 2, 4)
    a3, s3 = quad_angles_deg(vs, qs), quad_signed_areas(vs, qs)
    for k in range(3):
        np.testing.assert_array_equal(a3[k], quad_angles_deg(vs[k], qs[k]))
        np.testing.assert_array_equal(s3[k], quad_signed_areas(vs[k], qs[k]))
    np.testing.assert_allclose(s3, 1.0, rtol=1e-12)
    with pytest.raises(ValueError, match="stacked"):
        quad_corners(STRIP_V, qs)


def test_area_keeps_precision_far_from_the_origin() -> None:
    """A quad of side 1e-6 at distance 1e6: relative to the first corner the area is exact to
    a few ulps of the offsets; the plain shoelace sum of absolute coordinates loses it all."""
    far = 1e6 + 1e6j
    v = far + 1e-6 * STRIP_V
    area = quad_signed_areas(v, STRIP_Q)
    np.testing.assert_allclose(area, 1e-12, rtol=1e-4)
    z = v[STRIP_Q]
    naive = 0.5 * np.sum((np.conj(z) * np.roll(z, -1, axis=1)).imag, axis=1)
    assert np.max(np.abs(naive - 1e-12)) > 1e-3 * 1e-12  # the naive sum is visibly off


def test_rounding_slack_scales_with_size_over_edge() -> None:
    s_near = angle_rounding_slack_deg(STRIP_V, STRIP_Q)
    s_far = angle_rounding_slack_deg(STRIP_V + 1e6, STRIP_Q)
    eps = np.finfo(float).eps
    np.testing.assert_allclose(s_near, np.degrees(8 * eps * np.abs(STRIP_V[[4, 5]])))
    assert np.all(s_far > 1e5 * s_near)
    np.testing.assert_allclose(
        angle_rounding_slack_deg(STRIP_V, STRIP_Q, 1e3), np.degrees(8e3 * eps)
    )


def test_edges_and_conformity() -> None:
    e = quad_edges(STRIP_Q)
    assert e.shape == (8, 2) and e[:4].tolist() == [[0, 1], [1, 4], [4, 3], [3, 0]]
    free, ok = unpaired_edges(STRIP_Q)
    assert ok and len(free) == 6 and [1, 4] not in free.tolist() and [4, 1] not in free.tolist()
    bnd = check_conformity(STRIP_Q, 6)
    assert sorted(map(tuple, bnd.tolist())) == sorted(map(tuple, free.tolist()))
    # same orientation on the shared edge: not a consistently oriented surface
    bad = np.array([[0, 1, 4, 3], [1, 4, 5, 2]])
    assert not unpaired_edges(bad)[1]
    with pytest.raises(MeshVerificationError, match="occurs 2 times"):
        check_conformity(bad)
    with pytest.raises(MeshVerificationError, match="not used"):
        check_conformity(STRIP_Q, 7)
