"""The honest guarantee: meshes written by ``quadmesh mesh`` checked by an independent reader.

:func:`independent_check` is plain numpy on the file's numbers (it never calls
``QuadMesh.verify``): conformity, boundary = polygon sides, area, orientation, convexity,
distinct vertices and every new angle within a fixed tolerance of [60°, 120°]. It is used on
a handful of bundled examples and on a GIS-sized parcel far from (0, 0); the rest of the file
tests the strict verifier, the far-from-origin contract and ``refine``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from quadmesh.cli import EXIT_INVALID, EXIT_OK, main
from quadmesh.errors import MeshVerificationError
from quadmesh.examples import load_example
from quadmesh.io import write_polygon
from quadmesh.mesh import ANGLE_TOL_DEG, QuadMesh, finalize_mesh
from quadmesh.pipeline import MeshOptions, mesh_polygon
from quadmesh.refine import refine_quads
from tests.helpers import require_pipeline

NEXT = [1, 2, 3, 0]
PREV = [3, 0, 1, 2]
#: a 1 m plot at 5e6 m northing (UTM-like coordinates; a 10 m parcel there is written in
#: absolute coordinates since the vertex sectors grow where they can)
PARCEL = np.array([[0, 0], [1, 0], [1, 0.7], [0.4, 0.9], [0, 0.6]]) + np.array([5e5, 5e6])


def independent_check(mesh_file: Path, polygon: np.ndarray, angle_tol: float) -> dict:
    """Check a JSON mesh file against a counter-clockwise polygon with plain numpy.

    The file's vertices are taken as written (plus its "origin" if any: the polygon is then
    translated by −origin, exactly for a polygon far from 0). Angles, orientation and
    convexity are computed per quad relative to its first vertex. Returns measured numbers;
    fails the test on any violation."""
    data = json.loads(mesh_file.read_text())
    v = np.asarray(data["vertices"], dtype=np.float64)
    q = np.asarray(data["quads"], dtype=np.int64)
    ox, oy = data.get("origin", [0.0, 0.0])
    poly = np.asarray(polygon, dtype=np.float64) - [ox, oy]
    diam = np.max(np.linalg.norm(poly[:, None] - poly[None], axis=-1))
    nv = v.shape[0]

    # conformity: every directed edge once; an undirected edge in one or two quads
    a, b = q.ravel(), q[:, NEXT].ravel()
    directed = a * nv + b
    assert np.unique(directed).size == directed.size, "a directed edge is used twice"
    und, cnt = np.unique(np.minimum(a, b) * nv + np.maximum(a, b), return_counts=True)
    assert cnt.max() <= 2, "an edge lies in more than two quads"
    assert np.all(np.sort(q, axis=1)[:, 1:] != np.sort(q, axis=1)[:, :-1]), "repeated vertex"

    # orientation, convexity, angles: each quad relative to its first vertex
    c = v[q] - v[q][:, :1]
    e = c[:, NEXT] - c
    cross = e[:, PREV, 0] * e[:, :, 1] - e[:, PREV, 1] * e[:, :, 0]
    assert np.all(cross > 0), "a quad is clockwise or not strictly convex"
    dot = -(e[:, PREV] * e).sum(axis=-1)
    ang = np.degrees(np.arctan2(cross, dot))
    area = 0.5 * np.sum(c[..., 0] * c[:, NEXT, 1] - c[:, NEXT, 0] * c[..., 1], axis=1)
    px, py = poly[:, 0], poly[:, 1]
    poly_area = 0.5 * np.sum(px * np.roll(py, -1) - np.roll(px, -1) * py)
    assert abs(area.sum() - poly_area) <= 1e-9 * poly_area

    # boundary: the edges in one quad lie on polygon sides and cover each side exactly once
    single = und[cnt == 1]
    in_dir = np.isin(single, directed)
    ba = np.where(in_dir, single // nv, single % nv)
    bb = np.where(in_dir, single % nv, single // nv)
    p0, p1 = poly, np.roll(poly, -1, axis=0)
    d = p1 - p0
    covered = np.zeros(len(poly))
    assigned = np.zeros(ba.size, dtype=bool)
    for s in range(len(poly)):
        rel_a, rel_b = v[ba] - p0[s], v[bb] - p0[s]
        ln = np.linalg.norm(d[s])
        dist_a = np.abs(rel_a[:, 0] * d[s, 1] - rel_a[:, 1] * d[s, 0]) / ln
        dist_b = np.abs(rel_b[:, 0] * d[s, 1] - rel_b[:, 1] * d[s, 0]) / ln
        ta, tb = rel_a @ d[s] / ln**2, rel_b @ d[s] / ln**2
        on = (dist_a <= 1e-9 * diam) & (dist_b <= 1e-9 * diam)
        on &= (np.minimum(ta, tb) >= -1e-9) & (np.maximum(ta, tb) <= 1 + 1e-9)
        assert np.all(tb[on] > ta[on]), f"a boundary edge runs backwards on side {s}"
        covered[s] = np.sum(tb[on] - ta[on])
        assigned |= on
        ends = np.r_[ta[on], tb[on]]
        assert np.isclose(ends.min(), 0, atol=1e-12) and np.isclose(ends.max(), 1, atol=1e-12)
    np.testing.assert_allclose(covered, 1.0, atol=1e-9)
    assert assigned.all(), f"{np.count_nonzero(~assigned)} boundary edges lie on no side"

    # corners are vertices; distinct vertices are distinct at 1e-12 of the diameter
    from scipy.spatial import cKDTree

    tree = cKDTree(v)
    dc, ic = tree.query(poly)
    assert dc.max() <= 1e-9 * diam, "a polygon corner is not a mesh vertex"
    assert not tree.query_pairs(1e-12 * diam), "two distinct vertices (nearly) coincide"

    # angles: new ones within angle_tol of [60°, 120°]; original = unsplit corner below 60°
    valence = np.bincount(q.ravel(), minlength=nv)
    is_corner = np.zeros(nv, dtype=bool)
    is_corner[ic] = True
    exempt = (valence[q] == 1) & is_corner[q] & (ang < 60.0)
    new = ang[~exempt]
    miss = max(60.0 - new.min(), new.max() - 120.0, 0.0)
    assert miss <= angle_tol, f"a new angle misses [60°, 120°] by {miss:.3g}°"
    return {"n_quads": q.shape[0], "miss": miss, "origin": (ox, oy), "min_edge": e.min()}


def _mesh_cli(tmp_path: Path, verts: np.ndarray, *extra: str) -> tuple[Path, int, str]:
    poly = tmp_path / "poly.json"
    write_polygon(poly, verts)
    out = tmp_path / "mesh.json"
    rc = main(["mesh", str(poly), "-o", str(out), *extra])
    return out, rc, str(poly)


@pytest.mark.parametrize(
    "name", ["square", "hexagon", "l_shape", "right_triangle_10deg", "channel_20"]
)
def test_cli_mesh_passes_independent_check(name: str, tmp_path: Path, capsys) -> None:
    """Written meshes of examples whose quads are all above ~1e-5 of the diameter pass the
    independent check at 1e-9° (measured misses below 2e-10°)."""
    require_pipeline()
    verts = load_example(name)
    out, rc, _ = _mesh_cli(tmp_path, verts)
    assert rc == EXIT_OK, capsys.readouterr().err
    got = independent_check(out, verts, angle_tol=1e-9)
    assert got["origin"] == (0.0, 0.0)


def test_far_parcel_written_relative(tmp_path: Path, capsys) -> None:
    """A 1 m plot at (5e5, 5e6): absolute float64 coordinates there resolve ~1e-9 m,
    too coarse for its smallest quads, so the file holds coordinates relative to an exact
    origin (and says so); the independent check passes on the file at 1e-9°."""
    require_pipeline()
    out, rc, _ = _mesh_cli(tmp_path, PARCEL)
    text = capsys.readouterr().out
    assert rc == EXIT_OK
    assert "relative to the origin" in text and '"origin"' in text
    got = independent_check(out, PARCEL, angle_tol=1e-9)
    ox, oy = got["origin"]
    assert ox == pytest.approx(5e5 + 0.5) and oy == pytest.approx(5e6 + 0.45)
    # the absolute coordinates would not have held the bound
    data = json.loads(out.read_text())
    absolute = QuadMesh(np.asarray(data["vertices"]) + np.array([ox, oy]), data["quads"])
    assert not absolute.verify(PARCEL).ok
    # and `quadmesh check` reads the origin back
    poly = tmp_path / "poly.json"
    assert main(["check", str(out), "--polygon", str(poly)]) == EXIT_OK


def test_far_polygon_mesh_origin_only_when_needed() -> None:
    """A square ten diameters from 0 is meshed at a working origin, but its absolute
    coordinates hold the angles, so the mesh is returned in the input's coordinates."""
    require_pipeline()
    sq = np.array([[20, 0], [21, 0], [21, 1], [20, 1]], dtype=float)
    r = mesh_polygon(sq)
    assert r.origin != 0 and r.mesh_origin == 0
    assert r.mesh.verify(sq).ok
    far = mesh_polygon(PARCEL)
    assert far.mesh_origin == far.origin != 0
    assert far.mesh.verify(PARCEL, origin=far.mesh_origin).ok
    assert far.quality.min_angle >= 60 - 1e-9 and far.quality.max_angle <= 120 + 1e-9


# ----------------------------------------------------------------------------- verifier
def _rhombus(h: float, at: complex) -> QuadMesh:
    z = at + h * np.array([0, 1, 1 + np.exp(1j * np.pi / 3), np.exp(1j * np.pi / 3)])
    return QuadMesh.from_complex(z, np.array([[0, 1, 2, 3]]))


def test_verifier_tolerance_is_fixed() -> None:
    """An exact 60°/120° rhombus 1e-12 in size at |z| ~ 1 cannot be stored with its angles;
    the fixed tolerance refuses it (the old allowance 8ε|z|/ℓ accepted ~1e-1°) and says why;
    the same rhombus at the origin passes."""
    tiny = _rhombus(1e-12, 1.0 + 0.5j)
    poly = tiny.vertices
    ang = tiny.angles()
    miss = np.max(np.maximum(60 - ang, ang - 120))
    assert miss > ANGLE_TOL_DEG
    rep = tiny.verify(poly, coincident_rtol=0.0)
    assert not rep.ok
    msg = next(p for p in rep.problems if p.startswith("angle:"))
    assert "float64 coordinates there move its angles" in msg
    at0 = _rhombus(1e-12, 0j)
    assert at0.verify(at0.vertices).ok


def test_verifier_far_quad_with_real_defect() -> None:
    """The issue's case: angles 56.6°/123.4° a million diameters from (0, 0) are refused."""
    h = 1.0
    z = 1e6 + h * np.array([0, 1, 1 + np.exp(1j * np.radians(56.6)), np.exp(1j * np.radians(56.6))])
    m = QuadMesh.from_complex(z, np.array([[0, 1, 2, 3]]))
    rep = m.verify(m.vertices)
    assert not rep.ok and rep.problems[0].startswith("angle: 2 new angles")
    assert "worst 123.39999" in rep.problems[0] and "(1000001, 0)" in rep.problems[0]


def test_verifier_reports_near_coincident_vertices() -> None:
    """Two distinct vertices 1e-13 apart (diameter 2) are reported with their position."""
    verts = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1], [1 + 1e-13, 1]], dtype=float)
    quads = np.array([[0, 1, 4, 5], [1, 2, 3, 6]])
    m = QuadMesh(verts, quads)
    rep = m.verify([[0, 0], [2, 0], [2, 1], [0, 1]])
    coinc = [p for p in rep.problems if p.startswith("coincident vertices")]
    assert coinc and "vertices 4 and 6" in coinc[0] and "(1, 1)" in coinc[0]


def test_verify_with_origin_prints_absolute_coordinates() -> None:
    quad = np.array([[0, 0], [1, 0], [1.8, 1], [0, 1]])
    bad = QuadMesh(quad - 0.5, [[0, 1, 2, 3]])
    rep = bad.verify(quad + np.array([1e6, 2e6]), origin=complex(1e6 + 0.5, 2e6 + 0.5))
    assert not rep.ok
    assert "at vertex 1 (1000001, 2000000)" in rep.problems[0]


def test_finalize_mesh_raises_with_position() -> None:
    z = np.array([0, 1, 1.8 + 1j, 1j])
    with pytest.raises(MeshVerificationError, match=r"angle: .* at vertex 1 \(1, 0\)"):
        finalize_mesh([[0, 0], [1, 0], [1.8, 1], [0, 1]], z, np.array([[0, 1, 2, 3]]))


# ----------------------------------------------------------------------------- refine
@pytest.mark.parametrize(("name", "k"), [("hexagon", 2), ("l_shape", 3), ("square", 4)])
def test_refine_keeps_the_bound(name: str, k: int) -> None:
    """refine=k: k²·Q quads, conforming, same area, every angle within the fixed tolerance
    of [60°, 120°], each sub-quad's angles within its parent's corner angles and supplements."""
    require_pipeline()
    verts = load_example(name)
    base = mesh_polygon(verts)
    ref = mesh_polygon(verts, MeshOptions(refine=k))
    assert ref.mesh.n_quads == k * k * base.mesh.n_quads
    assert ref.verification.ok and ref.verification.area_error < 1e-12
    q = ref.quality
    assert q.min_angle >= 60 - ANGLE_TOL_DEG and q.max_angle <= 120 + ANGLE_TOL_DEG
    assert np.array_equal(ref.quad_source, np.repeat(base.quad_source, k * k))
    # parent bounds: sub-quad angles lie in [min(a, 180 - a), max(a, 180 - a)] of the parent
    pa = base.mesh.angles()
    lo = np.minimum(pa, 180 - pa).min(axis=1)
    hi = np.maximum(pa, 180 - pa).max(axis=1)
    sub = ref.mesh.angles().reshape(-1, k * k * 4)
    assert np.all(sub.min(axis=1) >= lo - 1e-7) and np.all(sub.max(axis=1) <= hi + 1e-7)


def test_refine_shares_edge_points_by_index() -> None:
    """Two quads sharing an edge: the k − 1 points on it exist once; 2k² conforming quads."""
    z = np.array([0, 1, 2, 2 + 1j, 1 + 1j, 1j])
    quads = np.array([[0, 1, 4, 5], [1, 2, 3, 4]])
    zn, qn, parent = refine_quads(z, quads, 3)
    assert qn.shape == (18, 4) and zn.size == 6 + 7 * 2 + 2 * 4
    m = QuadMesh.from_complex(zn, qn)
    assert m.verify([[0, 0], [2, 0], [2, 1], [0, 1]]).ok
    np.testing.assert_array_equal(parent, np.repeat([0, 1], 9))


def test_refine_refuses_small_corners(tmp_path: Path, capsys) -> None:
    """A corner below 60° stays in one quad; its k × k grid would make new angles of about
    that size (a 30°/110° kite: [39.3°, 140.7°] at k = 2), so refine refuses, naming it."""
    require_pipeline()
    with pytest.raises(MeshVerificationError, match="corners have angles below 60°"):
        mesh_polygon(load_example("triangle"), MeshOptions(refine=2))
    _, rc, _ = _mesh_cli(tmp_path, load_example("triangle"), "--refine", "2")
    assert rc == EXIT_INVALID
    assert "refine=2 is not possible" in capsys.readouterr().err


def test_cli_refine_independent_check(tmp_path: Path, capsys) -> None:
    require_pipeline()
    verts = load_example("l_shape")
    out, rc, _ = _mesh_cli(tmp_path, verts, "--refine", "2")
    assert rc == EXIT_OK, capsys.readouterr().err
    got = independent_check(out, verts, angle_tol=1e-9)
    base = mesh_polygon(verts)
    assert got["n_quads"] == 4 * base.mesh.n_quads
