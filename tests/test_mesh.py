"""QuadMesh: angles, areas, quality report and verification on hand-built meshes."""

from __future__ import annotations

import time

import numpy as np
import pytest

from quadmesh.errors import MeshVerificationError
from quadmesh.mesh import QuadMesh

SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)


def grid_mesh(nx: int, ny: int, w: float = 1.0, h: float = 1.0) -> QuadMesh:
    """[0, w] x [0, h] split into nx * ny rectangles."""
    x, y = np.meshgrid(np.linspace(0, w, nx + 1), np.linspace(0, h, ny + 1))
    verts = np.column_stack([x.ravel(), y.ravel()])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    v0 = (j * (nx + 1) + i).ravel()
    quads = np.column_stack([v0, v0 + 1, v0 + nx + 2, v0 + nx + 1])
    return QuadMesh(verts, quads)


def square4() -> QuadMesh:
    return grid_mesh(2, 2)


def lshape() -> tuple[QuadMesh, np.ndarray]:
    poly = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    verts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1], [0, 2], [1, 2]], dtype=float)
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6]])
    return QuadMesh(verts, quads), poly


def hexagon() -> tuple[QuadMesh, np.ndarray]:
    t = np.arange(6) * np.pi / 3
    poly = np.column_stack([np.cos(t), np.sin(t)])
    verts = np.vstack([[0.0, 0.0], poly])
    quads = np.array([[0, 1, 2, 3], [0, 3, 4, 5], [0, 5, 6, 1]])
    return QuadMesh(verts, quads), poly


def kite50() -> np.ndarray:
    """Kite with angles 50°, 120°, 70°, 120° (the 50° corner at the origin)."""
    # triangle A=(0,0), C=(1,0), B with angles 25° at A, 35° at C, 120° at B
    r = np.sin(np.radians(35)) / np.sin(np.radians(120))
    b = r * np.exp(1j * np.radians(25))
    z = np.array([0, np.conj(b), 1, b])
    return np.column_stack([z.real, z.imag])


def problems_with(report, word: str) -> list[str]:
    return [p for p in report.problems if word in p]


# ----------------------------------------------------------------------------- basics
def test_angles_areas_square():
    m = square4()
    assert m.angles().shape == (4, 4)
    np.testing.assert_allclose(m.angles(), 90.0)
    np.testing.assert_allclose(m.areas(), 0.25)
    assert m.z.dtype == np.complex128
    assert m.z[4] == 0.5 + 0.5j
    assert not m.vertices.flags.writeable


def test_pickle_keeps_view_and_read_only():
    import pickle

    m = pickle.loads(pickle.dumps(square4()))
    assert not m.vertices.flags.writeable and not m.quads.flags.writeable
    assert np.shares_memory(m.z, m.vertices)
    assert m.verify(SQUARE).ok


def test_edges_counts():
    edges, counts = square4().edges()
    assert edges.shape == (12, 2)
    assert np.count_nonzero(counts == 2) == 4
    assert np.count_nonzero(counts == 1) == 8


def test_bad_shapes_rejected():
    with pytest.raises(MeshVerificationError, match="shape"):
        QuadMesh(np.zeros((3, 3)), np.zeros((1, 4), int))
    with pytest.raises(MeshVerificationError, match="indices"):
        QuadMesh(np.zeros((3, 2)), np.array([[0, 1, 2, 3]]))


# ----------------------------------------------------------------------------- valid meshes
@pytest.mark.parametrize("name", ["square", "lshape", "hexagon"])
def test_valid_meshes(name):
    if name == "square":
        mesh, poly = square4(), SQUARE
    elif name == "lshape":
        mesh, poly = lshape()
    else:
        mesh, poly = hexagon()
    report = mesh.verify(poly)
    assert report.ok, report.problems
    assert report.area_error < 1e-12
    mesh.check(poly)
    q = report.quality
    assert q.n_angles_outside == 0
    assert 60 - 1e-9 <= q.min_angle <= q.max_angle <= 120 + 1e-9
    assert q.histogram.sum() == 4 * mesh.n_quads
    assert q.n_polygon_vertices == len(poly)


def test_hexagon_angles_and_edges():
    mesh, poly = hexagon()
    report = mesh.verify(poly)
    assert report.n_interior_edges == 3
    assert report.n_boundary_edges == 6
    ang = np.sort(mesh.angles().ravel())
    np.testing.assert_allclose(ang[:6], 60.0, atol=1e-12)
    np.testing.assert_allclose(ang[6:], 120.0, atol=1e-12)
    q = report.quality
    assert q.quads_per_vertex == pytest.approx(0.5)
    assert q.histogram[12] + q.histogram[11] == 6  # the 60° bin (edge 60 falls in bin 12)


def test_lshape_reflex_corner_split():
    mesh, poly = lshape()
    # the 270° corner at (1, 1) is split into three 90° angles
    ang = mesh.angles()
    at = mesh.quads == 4
    np.testing.assert_allclose(ang[at], 90.0)
    assert mesh.verify(poly).ok


def test_original_small_angle_exempt():
    poly = kite50()
    mesh = QuadMesh(poly, np.array([[0, 1, 2, 3]]))
    report = mesh.verify(poly)
    assert report.ok, report.problems
    q = report.quality
    assert q.n_original == 1
    assert q.min_original_angle == pytest.approx(50.0)
    assert q.min_angle == pytest.approx(70.0)
    # without the polygon the unsplit corner is recognised from the mesh alone
    assert mesh.quality().n_original == 1


def test_equilateral_triangle_three_quads():
    t = np.pi / 2 + np.arange(3) * 2 * np.pi / 3
    corners = np.exp(1j * t)
    mids = 0.5 * (corners + np.roll(corners, -1))
    z = np.r_[0, corners, mids]  # 0 centre, 1..3 corners, 4..6 midpoints
    quads = np.array([[0, 6, 1, 4], [0, 4, 2, 5], [0, 5, 3, 6]])
    mesh = QuadMesh.from_complex(z, quads)
    poly = np.column_stack([corners.real, corners.imag])
    report = mesh.verify(poly)
    assert report.ok, report.problems
    np.testing.assert_allclose(np.sort(np.unique(mesh.angles().round(9))), [60, 90, 120])


# ----------------------------------------------------------------------------- defects
def test_hole_detected():
    mesh = grid_mesh(3, 3)
    holed = QuadMesh(mesh.vertices, np.delete(mesh.quads, 4, axis=0))
    report = holed.verify(SQUARE)
    assert not report.ok
    assert problems_with(report, "hole: 4 free edges")
    assert problems_with(report, "area")
    with pytest.raises(MeshVerificationError, match="hole"):
        holed.check(SQUARE)


def test_overlap_detected():
    mesh = square4()
    dup = QuadMesh(mesh.vertices, np.vstack([mesh.quads, mesh.quads[2]]))
    report = dup.verify(SQUARE)
    assert problems_with(report, "overlap: 1 duplicated quads, e.g. quad 4 repeats quad 2")
    assert problems_with(report, "area")


def test_flipped_quad_detected():
    mesh = square4()
    quads = mesh.quads.copy()
    quads[1] = quads[1, ::-1]
    report = QuadMesh(mesh.vertices, quads).verify(SQUARE)
    assert problems_with(report, "flipped: 1 quads are clockwise, e.g. quad 1")


def test_non_convex_quad_detected():
    # an arrowhead (dart) meshed by its single quad: reflex corner at (1, 1)
    poly = np.array([[0, 0], [2, 1], [0, 2], [1, 1]], dtype=float)
    mesh = QuadMesh(poly, np.array([[0, 1, 2, 3]]))
    report = mesh.verify(poly)
    msgs = problems_with(report, "not strictly convex")
    assert msgs and "angle of 270° at vertex 3" in msgs[0], report.problems
    assert not problems_with(report, "flipped")


def test_angle_50_detected():
    mesh = square4()
    verts = mesh.vertices.copy()
    verts[4] = [0.5 + 0.5 / np.tan(np.radians(50)), 0.5]
    moved = QuadMesh(verts, mesh.quads)
    report = moved.verify(SQUARE)
    assert len(report.problems) == 1, report.problems
    assert report.problems[0].startswith("angle: 8 new angles outside [60°, 120°] in 4 quads")
    q = report.quality
    assert q.min_angle == pytest.approx(50.0)
    assert q.max_angle == pytest.approx(130.0)
    assert q.n_quads_outside == 4
    assert q.n_angles_outside == 8


def test_split_small_corner_not_exempt():
    # a 50° polygon corner at the origin split by the edge (0, a) into two 25° parts
    z = np.array(
        [
            0,  # 0 = O, the 50° corner
            1.2 * np.exp(-1j * np.radians(25)),  # 1
            1.5 - 0.5j,  # 2
            2.0,  # 3
            1.5 + 0.5j,  # 4
            1.2 * np.exp(1j * np.radians(25)),  # 5
            1.0,  # 6 = a, interior
        ]
    )
    quads = np.array([[0, 1, 2, 6], [0, 6, 4, 5], [6, 2, 3, 4]])
    mesh = QuadMesh.from_complex(z, quads)
    poly = np.column_stack([z[:6].real, z[:6].imag])
    report = mesh.verify(poly)
    assert [p.split(":")[0] for p in report.problems] == ["angle"], report.problems
    assert report.quality.n_original == 0
    assert report.quality.min_angle == pytest.approx(25.0)


def test_boundary_edge_off_polygon():
    mesh = square4()
    verts = mesh.vertices.copy()
    verts[1] = [0.5, -0.05]  # the midpoint of the bottom side leaves the side
    report = QuadMesh(verts, mesh.quads).verify(SQUARE)
    assert problems_with(report, "boundary edge off the polygon: 2 free edges")
    assert problems_with(report, "boundary gap")


def test_hanging_vertex_detected():
    verts = np.array(
        [[0, 0], [0.5, 0], [1, 0], [0, 1], [0.5, 1], [1, 1], [0.5, 0.5], [1, 0.5]], dtype=float
    )
    quads = np.array([[0, 1, 4, 3], [1, 2, 7, 6], [6, 7, 5, 4]])
    report = QuadMesh(verts, quads).verify(SQUARE)
    msgs = problems_with(report, "hanging vertex")
    assert msgs and "vertex 6" in msgs[0]
    assert not problems_with(report, "hole")
    assert report.area_error < 1e-12  # area alone does not see it


def test_polygon_corner_missing():
    poly = np.array([[0, 0], [0.25, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    report = square4().verify(poly)
    msgs = problems_with(report, "corner: 1 polygon corners")
    assert msgs and "(0.25, 0)" in msgs[0]


def test_unsplit_obtuse_corner_flagged():
    # a single quad with a 135° corner: original angles above 120° must be split
    poly = np.array([[0, 0], [2, 0], [2, 1], [1, 2], [0, 2]], dtype=float)[[0, 1, 2, 3, 4]]
    poly = np.array([[0, 0], [2, 0], [1, 1], [0, 1]], dtype=float)
    report = QuadMesh(poly, np.array([[0, 1, 2, 3]])).verify(poly)
    assert problems_with(report, "angle")
    assert report.quality.max_angle == pytest.approx(135.0)


def test_summary_readable():
    mesh, poly = hexagon()
    text = mesh.verify(poly).summary()
    assert text.startswith("mesh OK")
    assert "quads per polygon vertex: 0.50" in text
    assert "min 60.0000°" in text


def test_verify_large_mesh_fast():
    mesh = grid_mesh(500, 400, 2.5, 2.0)  # 200 000 quads
    poly = np.array([[0, 0], [2.5, 0], [2.5, 2], [0, 2]], dtype=float)
    t0 = time.perf_counter()
    report = mesh.verify(poly)
    dt = time.perf_counter() - t0
    assert report.ok, report.problems
    assert report.n_boundary_edges == 2 * (500 + 400)
    assert dt < 5.0


def test_rounding_is_measured_not_allowed() -> None:
    """A quad with exact 60°/120° corners, 1e-10 in size, stored at |z| ~ 1: the stored
    coordinates cannot carry the exact angles. ``angle_slack`` measures how far rounding can
    move them; ``verify`` keeps its fixed tolerance and refuses the quad, naming the cause."""
    import numpy as np

    from quadmesh.mesh import ANGLE_TOL_DEG, QuadMesh

    h = 1e-10
    rhombus = np.array([0, 1, 1 + np.exp(1j * np.pi / 3), np.exp(1j * np.pi / 3)]) * h
    z = 1.0 + 0.5j + rhombus
    mesh = QuadMesh(np.column_stack([z.real, z.imag]), np.array([[0, 1, 2, 3]]))
    slack = float(mesh.angle_slack()[0, 0])
    ang = mesh.angles()
    miss = float(np.abs(ang - np.array([60, 120, 60, 120])).max())
    assert ANGLE_TOL_DEG < miss <= slack < 1e-2
    report = mesh.verify(mesh.vertices)
    assert not report.ok
    assert "float64 coordinates there move its angles" in report.problems[0]
    # the same rhombus at the origin keeps its angles to ~1e-14°
    at0 = QuadMesh.from_complex(rhombus, np.array([[0, 1, 2, 3]]))
    assert np.abs(at0.angles() - np.array([60, 120, 60, 120])).max() < 1e-9
    assert at0.verify(at0.vertices).ok


def test_nearest_sides_match_the_tree_query() -> None:
    """The free-edge sides of the verification (one bulk ``dwithin`` query, the nearest of
    several candidates by exact distance, the tree's nearest side for points off every side)
    are the sides ``STRtree.query_nearest`` gives: points on the sides, within 1e-10 of a
    side's length from a corner (two candidates), and anywhere in the bounding box."""
    import shapely

    from quadmesh.examples import load_example
    from quadmesh.mesh import _nearest_sides
    from quadmesh.polygon import validate_polygon

    rng = np.random.default_rng(5)
    for name in ("l_shape", "comb", "slit_355deg", "corner_5deg"):
        poly = validate_polygon(load_example(name))
        pz, pv = poly.z, poly.vertices
        sides = shapely.linestrings(np.stack([pv, np.roll(pv, -1, axis=0)], axis=1))
        tree = shapely.STRtree(sides)
        k = rng.integers(0, pz.size, 3000)
        t = rng.uniform(0.0, 1.0, k.size)
        t[:500] = rng.uniform(0.0, 1e-10, 500)
        on = pz[k] + t * (np.roll(pz, -1)[k] - pz[k])
        box = rng.uniform(pz.real.min(), pz.real.max(), 1000) + 1j * rng.uniform(
            pz.imag.min(), pz.imag.max(), 1000
        )
        p = np.r_[on, box]
        want = tree.query_nearest(shapely.points(p.real, p.imag), all_matches=False)[1]
        got = _nearest_sides(tree, pz, p, 1e-9 * poly.diameter)
        assert np.array_equal(got, want), name


def test_close_candidates_keep_every_close_pair() -> None:
    """The grid filter of the coincident-vertex check keeps both vertices of every pair that
    a k-d tree of all the points finds within r: planted pairs at distances 0, r/2, r and
    r (1 ± 1e-12), exact duplicates, near the origin and 1e6 or 3e8 away from it."""
    from scipy.spatial import cKDTree

    from quadmesh.mesh import _close_candidates

    rng = np.random.default_rng(5)
    for trial in range(60):
        off = (0.0, 1e6, -3e8, 1e-3)[trial % 4]
        scale = (1.0, 1e-6, 1e3)[trial % 3]
        r = 1e-9 * scale * (1.0, 1e-3, 1e3)[trial % 3]
        v = rng.random((2000, 2)) * scale + off
        k = rng.integers(0, v.shape[0], 50)
        a = rng.uniform(0.0, 2 * np.pi, 50)
        d = r * rng.choice([0.0, 0.5, 1 - 1e-12, 1.0, 1 + 1e-12, 2.0], 50)
        v = np.r_[v, v[k] + np.c_[np.cos(a), np.sin(a)] * d[:, None]]
        v[rng.integers(0, v.shape[0], 10)] = v[rng.integers(0, v.shape[0], 10)]
        pairs = cKDTree(v).query_pairs(r, output_type="ndarray")
        kept = _close_candidates(v, r)
        assert np.all(np.diff(kept) > 0)
        assert np.isin(pairs.ravel(), kept).all()


def test_sure_sides_agree_with_the_tree_at_the_tolerance() -> None:
    """The grid shortcut of the free-edge side lookup gives what the tree's ``dwithin``
    query gives, for points on the sides, off them by tol (1 ± 1e-6), tol (1 ± 1e-13) and
    2 tol, near corners, and for the same polygons 1e6 away from the origin."""
    import shapely

    from quadmesh.examples import load_example
    from quadmesh.mesh import _nearest_sides, _nearest_sides_by_tree
    from quadmesh.polygon import validate_polygon

    rng = np.random.default_rng(7)
    for name in ("l_shape", "comb", "star_30", "slit_355deg"):
        for shift in (0j, 1e6 + 1e6j):
            poly = validate_polygon(load_example(name) + np.array([shift.real, shift.imag]))
            pz, pv = poly.z, poly.vertices
            tree = shapely.STRtree(
                shapely.linestrings(np.stack([pv, np.roll(pv, -1, axis=0)], axis=1))
            )
            tol = 1e-9 * poly.diameter
            k = rng.integers(0, pz.size, 4000)
            d = np.roll(pz, -1)[k] - pz[k]
            t = rng.uniform(0.0, 1.0, k.size)
            t[:800] = rng.uniform(0.0, 1e-8, 800)
            off = tol * rng.choice([0.0, 1 - 1e-6, 1 + 1e-6, 1 - 1e-13, 1 + 1e-13, 2.0], k.size)
            p = pz[k] + t * d + off * rng.choice([-1j, 1j], k.size) * d / np.abs(d)
            np.testing.assert_array_equal(
                _nearest_sides(tree, pz, p, tol), _nearest_sides_by_tree(tree, pz, p, tol)
            )
