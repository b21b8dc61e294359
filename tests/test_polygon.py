"""Validation and normalisation of input polygons (quadmesh.polygon)."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import Polygon, PolygonError, validate_polygon

SQUARE = [[0, 0], [1, 0], [1, 1], [0, 1]]


def test_square_angles_area_orientation() -> None:
    p = validate_polygon(SQUARE)
    assert p.n == 4
    assert p.area == pytest.approx(1.0)
    np.testing.assert_allclose(p.angles, np.full(4, np.pi / 2))
    assert not p.reversed_input


def test_clockwise_is_reversed_and_angles_sum() -> None:
    p = validate_polygon(SQUARE[::-1])
    assert p.reversed_input
    assert p.area == pytest.approx(1.0)
    lshape = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]
    q = validate_polygon(lshape)
    assert np.sum(q.angles) == pytest.approx((q.n - 2) * np.pi)
    assert np.degrees(q.angles[3]) == pytest.approx(270.0)


def test_complex_and_polygon_inputs() -> None:
    z = np.array([0, 1, 1 + 1j, 1j])
    p = validate_polygon(z)
    assert isinstance(p, Polygon)
    assert validate_polygon(p) is p
    np.testing.assert_allclose(p.vertices, np.array(SQUARE, dtype=float))


def test_closing_point_and_consecutive_duplicates_are_dropped() -> None:
    p = validate_polygon([*SQUARE, [0, 0]])
    assert p.n == 4
    p = validate_polygon([[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]])
    assert p.n == 4


@pytest.mark.parametrize(
    ("points", "message"),
    [
        ([[0, 0], [1, 0]], "at least 3"),
        ([[0, 0], [1, np.nan], [0, 1]], "not finite"),
        ([[0, 0], [1, np.inf], [0, 1]], "not finite"),
        ([[0, 0], [1, 0], [2, 0]], "zero area"),
        ([[0, 0], [1, 1], [1, 0], [0, 1]], "not simple"),
        ([[0, 0], [2, 0], [1, 1], [2, 2], [0, 2], [1, 1]], "coincide"),
        ([[0, 0], [0, 0], [0, 0]], "coincide"),
        ([[0, 0], [1e200, 0], [0, 1e200]], "representable"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "(n, 2)"),
        ([[0, 0], [2, 0], [1, 0], [1, 1]], "not simple"),
    ],
)
def test_bad_input_raises_clear_error(points: list, message: str) -> None:
    with pytest.raises(PolygonError, match=message.replace("(", r"\(").replace(")", r"\)")):
        validate_polygon(points)


def test_scale_invariance_huge_and_tiny() -> None:
    base = np.array([[0, 0], [3, 0], [3, 1], [0, 2]], dtype=float)
    for s in (1e-9, 1e9):
        p = validate_polygon(base * s + 1e3 * s)
        assert p.area == pytest.approx(4.5 * s * s, rel=1e-12)


def test_collinear_vertices_kept_or_dropped() -> None:
    pts = [[0, 0], [1, 0], [2, 0], [2, 2], [0, 2]]
    p = validate_polygon(pts)
    assert p.n == 5
    assert np.degrees(p.angles[1]) == pytest.approx(180.0)
    q = validate_polygon(pts, drop_collinear=True)
    assert q.n == 4
