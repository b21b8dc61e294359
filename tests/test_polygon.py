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


# --------------------------------------------------------------------------------------
# messages name the user's own points (input numbering, coordinates)


def _clockwise_octagon_with_crossing() -> np.ndarray:
    """A clockwise 8-gon whose user edges 1 (p1→p2) and 3 (p3→p4) cross."""
    t = -2 * np.pi * np.arange(8) / 8
    p = np.column_stack([np.cos(t), np.sin(t)]).round(3)
    p[[2, 3]] = p[[3, 2]]
    return p


def test_source_index_maps_back_to_the_input() -> None:
    # clockwise square with a repeated point and a closing point: input indices survive
    pts = [[0, 0], [0, 1], [0, 1], [1, 1], [1, 0], [0, 0]]
    p = validate_polygon(pts)
    assert p.reversed_input and p.n == 4
    for i in range(p.n):
        k = p.user_vertex(i)
        assert tuple(pts[k]) == (p.z[i].real, p.z[i].imag)
    assert sorted(p.source_index.tolist()) == [0, 1, 3, 4]
    assert p.describe_vertex(int(np.flatnonzero(p.source_index == 3)[0])) == "vertex 3 at (1, 1)"
    # edges are numbered and oriented as the user walks them
    i = int(np.flatnonzero(p.source_index == 3)[0])  # normalised edge i runs 3 → 1 (user 1 → 3)
    assert p.user_edge(i) == (1, 3)
    assert p.describe_edge(i) == "edge 1 (from vertex 1 at (0, 1) to vertex 3 at (1, 1))"
    # a plain Polygon numbers its vertices 0..n-1; drop_collinear keeps the input numbers
    assert Polygon(np.array([0, 1, 1j])).source_index.tolist() == [0, 1, 2]
    q = validate_polygon([[0, 0], [1, 0], [2, 0], [2, 2], [0, 2]], drop_collinear=True)
    assert q.source_index.tolist() == [0, 2, 3, 4]


def test_translated_polygon_keeps_user_numbering_and_coordinates() -> None:
    p = validate_polygon(np.array(SQUARE[::-1], dtype=float) + 1e6)
    t = p.translated(-1e6)
    np.testing.assert_array_equal(t.source_index, p.source_index)
    assert t.reversed_input
    assert t.describe_vertex(0) == p.describe_vertex(0)
    np.testing.assert_allclose(t.z, p.z - 1e6)


def test_crossing_edges_of_a_clockwise_octagon_use_the_users_edge_numbers() -> None:
    pts = _clockwise_octagon_with_crossing()
    with pytest.raises(PolygonError) as err:
        validate_polygon(pts)
    msg = str(err.value)
    assert "not simple" in msg
    assert "edge 1 (from vertex 1 at (0.707, -0.707) to vertex 2 at (-0.707, -0.707))" in msg
    assert "edge 3 (from vertex 3 at (0, -1) to vertex 4 at (-1, 0))" in msg
    assert "edge 5" not in msg
    # the same outline given counter-clockwise: the crossing edges are its edges 3 and 5
    with pytest.raises(PolygonError) as err:
        validate_polygon(pts[::-1])
    msg = str(err.value)
    assert "edge 3 (from vertex 3 at (-1, 0) to vertex 4 at (0, -1))" in msg
    assert "edge 5 (from vertex 5" in msg


@pytest.mark.parametrize(
    ("points", "fragments"),
    [
        # repeated (non-consecutive) point, after a dropped duplicate: input numbers 3 and 6
        (
            [[0, 0], [2, 0], [2, 0], [1, 1], [2, 2], [0, 2], [1, 1]],
            ["points 3 and 6 coincide at (1, 1)"],
        ),
        # the same, clockwise: still the input numbers
        (
            [[1, 1], [0, 2], [2, 2], [1, 1], [2, 0], [2, 0], [0, 0]],
            ["points 0 and 3 coincide at (1, 1)"],
        ),
        ([[0, 0], [1, 0], [2, np.nan], [0, 1]], ["point 2 is not finite: (2, nan)"]),
        ([[0, 0], [1, 0], [3, np.inf], [0, 1]], ["point 2 is not finite: (3, inf)"]),
        # all collinear: the two extreme input points
        (
            [[1, 1], [3, 3], [2, 2], [0, 0]],
            ["zero area", "point 3 at (0, 0)", "point 1 at (3, 3)"],
        ),
        # a spike (collinear back-and-forth) at input point 2, found as overlapping edges
        (
            [[0, 0], [4, 0], [6, 0], [5, 0], [5, 3], [0, 3]],
            ["not simple", "vertex 2 at (6, 0)", "overlaps"],
        ),
        ([[0, 0], [1, 0]], ["at least 3 points", "point 0 at (0, 0)", "point 1 at (1, 0)"]),
        (
            [[0, 0], [1, 0], [1, 0], [0, 0]],
            ["at least 3 distinct points", "point 0 at (0, 0)", "point 1 at (1, 0)"],
        ),
        ([[5, 5], [5, 5], [5, 5]], ["all 3 points coincide at (5, 5)"]),
        ([[0, 0], [1e200, 0], [0, 1]], ["point 1 is at (1e+200, 0)"]),
    ],
)
def test_messages_name_the_users_points(points: list, fragments: list[str]) -> None:
    with pytest.raises(PolygonError) as err:
        validate_polygon(points)
    msg = str(err.value)
    for f in fragments:
        assert f in msg, (f, msg)
