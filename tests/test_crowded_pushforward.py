"""Push-forward of disk meshes through crowded Schwarz–Christoffel maps (CONFORMAL.md §1.9–§1.10).

The thick piece of the bundled glyph ``glyph_s`` has prevertex gaps of ~2e-13 rad, so its disk
mesh has cells of ~1e-16 next to the circle that complex128 positions cannot resolve. The
pipeline evaluates f from the disk mesh's exact offsets (``DiskMesh.offsets_from``): these
tests check that values agree with quadrature in local coordinates, that every pushed-forward
angle is in [60°, 120°] (paper §7), and the long double helpers (triangle centres, circle
sides, rotated maps).
"""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import pipeline
from quadmesh.benchmark import smooth_star
from quadmesh.conformal import DiskMap
from quadmesh.decompose import decompose
from quadmesh.disk import disk_mesh
from quadmesh.disk.tessellation import one_minus_abs2
from quadmesh.examples import load_example
from quadmesh.geometry import quad_angles_deg
from quadmesh.polygon import validate_polygon
from quadmesh.result import MeshOptions

OPTS = MeshOptions()


def _disk(intervals: np.ndarray):
    return disk_mesh(
        intervals,
        A=OPTS.lemma_A,
        n=OPTS.n,
        depth_step=OPTS.depth_step,
        inner_height=OPTS.inner_height,
        depth_growth=OPTS.depth_growth,
        depth_max=max(OPTS.depth_max, pipeline._d5(OPTS.inner_height) + 0.5),
    )


@pytest.fixture(scope="module")
def glyph():
    """(piece, map, disk mesh) of glyph_s's thick piece (unrotated: its gaps are tiny)."""
    piece = decompose(validate_polygon(load_example("glyph_s"))).thick[0]
    pd = pipeline._prepare_piece(piece, OPTS, {})
    assert isinstance(pd.fmap, DiskMap)
    assert np.min(pd.fmap.gaps) < 1e-12  # the test is about crowding
    return pd, pd.fmap, _disk(pd.intervals)


@pytest.fixture(scope="module")
def glyph_image(glyph):
    pd, fm, disk = glyph
    return pipeline._push_forward(fm, disk, pd.theta, pd.z)


def test_crowded_disk_mesh_is_below_float64_resolution(glyph) -> None:
    """Sanity: the disk mesh has vertices within 1e-15 of the circle next to gaps of 1e-13,
    i.e. cells that complex128 positions round by a sizeable fraction."""
    _, fm, disk = glyph
    z = disk.vertices
    inner = ~np.asarray(disk.on_circle)
    assert np.min(1.0 - np.abs(z[inner])) < 1e-15
    assert np.min(fm.gaps) < 1e-12


def test_exact_offsets_agree_with_local_quadrature(glyph) -> None:
    """f at disk vertices near the crowded prevertices (series about centres in local
    coordinates) against compound quadrature in local coordinates (``map_near_vertex``) from
    the nearest prevertex or a neighbour of it, relative to |f'|·distance to the prevertex.

    Quadratures from neighbouring prevertices differ among themselves by the solved map's
    side error (≈3e-7 of this local scale at the 2e-13 gaps), so the best of the three is
    compared; the typical error is ≈1e-15."""
    _, fm, disk = glyph
    f, fp = fm.map_clusters(
        disk.vertices,
        disk.vertex_piece,
        disk.piece_center_ld,
        derivative=True,
        offsets=disk.offsets_from,
    )
    k, d = fm._nearest(disk.vertices, disk.offsets_from, np.arange(disk.vertices.size))
    r = np.abs(d)
    sel = np.flatnonzero((r < 1e-11) & (r > 0.6 * fm._cfg.nn[k]))
    assert sel.size > 100
    sel = sel[:: max(1, sel.size // 300)]
    scale = np.abs(fp[sel]) * r[sel]
    errs = []
    for j in (-1, 0, 1):
        kj = np.mod(k[sel] + j, fm.n)
        tj = disk.offsets_from(fm.prevertices_ld[kj], sel)
        errs.append(np.abs(f[sel] - fm.map_near_vertex(kj, tj)) / scale)
    err = np.min(errs, axis=0)
    assert np.median(err) < 1e-13
    assert np.max(err) < 1e-9


def test_float64_points_cannot_do_it(glyph) -> None:
    """Without the exact offsets the same evaluation is visibly wrong at those vertices (this
    is what the exact path fixes)."""
    _, fm, disk = glyph
    exact = fm.map_clusters(
        disk.vertices, disk.vertex_piece, disk.piece_center_ld, offsets=disk.offsets_from
    )
    k, d = fm._nearest(disk.vertices, disk.offsets_from, np.arange(disk.vertices.size))
    sel = np.flatnonzero(np.abs(d) < 1e-11)
    rounded = fm.map_clusters(disk.vertices[sel], np.zeros(sel.size, int), np.zeros(1))
    rel = np.abs(rounded - exact[sel]) / np.abs(exact[sel] - fm.vertices[k[sel]])
    assert np.max(rel) > 1e-4


def test_crowded_piece_pushes_forward_into_angle_range(glyph, glyph_image) -> None:
    """Every pushed-forward angle of every piece kind is in [60°, 120°] (paper §7), within
    the verifier's rounding slack, without any repair."""
    _, _, disk = glyph
    img = glyph_image
    assert np.all(np.isfinite(img))
    ang = quad_angles_deg(img, disk.quads)
    tol = pipeline._angle_tol(img, disk.quads)[:, None]
    for kind in ("pentagon", "carleson_quadrilateral", "carleson_triangle"):
        a = ang[disk.kind == kind]
        assert a.size
        t = tol[disk.kind == kind]
        assert np.all(a >= 60.0 - t) and np.all(a <= 120.0 + t), kind
    # orientation: every image quad keeps the disk quad's counter-clockwise order
    q = img[disk.quads]
    area2 = np.sum((np.conj(q) * np.roll(q, -1, axis=1)).imag, axis=1)
    assert np.all(area2 > 0)


def test_circle_vertices_land_on_their_sides(glyph, glyph_image) -> None:
    """Ideal vertices are projected onto the side of the arc between their prevertices,
    decided from long double angles."""
    pd, fm, disk = glyph
    circ = np.flatnonzero(disk.on_circle)
    w = glyph_image[circ]
    z = pd.z
    e = np.roll(z, -1) - z
    dist = np.min(
        np.abs(((w[:, None] - z[None, :]) * np.conj(e)[None, :]).imag) / np.abs(e)[None, :],
        axis=1,
    )
    assert np.max(dist) < 1e-12 * np.max(np.abs(e))
    ang = np.mod(np.angle(disk.exact_vertices()[circ]), 2 * np.longdouble(np.pi))
    side = np.searchsorted(fm.theta_ld, ang, side="right") - 1
    a, b = z[side % z.size], z[(side + 1) % z.size]
    on = np.abs(((w - a) * np.conj(b - a)).imag) / np.abs(b - a)
    assert np.max(on) < 1e-12 * np.max(np.abs(e))


def test_triangle_centres_in_long_double(glyph) -> None:
    """τ⁻¹(c) = a + offset comes back to τ_local(c) under the apex frame map φ_a, also for
    triangles whose offset from the apex is far below the resolution of their position."""
    _, _, disk = glyph
    tris = disk.triangles
    a, off, dzc = pipeline._triangle_centres(tris)
    assert a.dtype == np.clongdouble
    loc = np.stack([t.tau_local for t in tris])
    c0 = np.array([t.center for t in tris])
    u = (loc[:, 0, 0] * c0 + loc[:, 0, 1]) / (loc[:, 1, 0] * c0 + loc[:, 1, 1])
    # φ_a(a + off) = −off/((1 − |a|²) − ā·off), with off exact
    k = one_minus_abs2(a)
    back = off / (k - np.conj(a.astype(np.complex128)) * off)
    assert np.max(np.abs(back - u) / np.abs(u)) < 1e-12
    assert np.all(np.abs(a + off) < 1)
    assert np.min(np.abs(off)) < 1e-14  # triangles at the crowded prevertices
    assert np.all(np.isfinite(dzc)) and np.all(np.abs(dzc) > 0)


def test_map_clusters_long_double_points_and_rotation() -> None:
    """On an uncrowded map the exact paths agree with the float64 evaluator; clongdouble
    points equal explicit offsets; a rotated map is evaluated through its base map."""
    p = smooth_star(40, seed=4)
    fm = DiskMap.from_polygon(p[:, 0] + 1j * p[:, 1])
    rng = np.random.default_rng(3)
    z = np.sqrt(rng.uniform(0, 0.999, 500)) * np.exp(2j * np.pi * rng.uniform(0, 1, 500))
    plain = fm(z)
    zl = z.astype(np.clongdouble) + np.clongdouble(1e-19)
    got, fp = fm.map_clusters(zl, None, None, derivative=True)
    assert np.max(np.abs(got - plain)) < 1e-13 * fm._diam
    assert np.max(np.abs(fp - fm.derivative(z)) / np.abs(fm.derivative(z))) < 1e-10

    def off(refs, index):
        return (zl[index] - refs).astype(np.complex128)

    cid = np.arange(z.size) // 50
    cen = np.array([z[cid == i].mean() for i in range(cid.max() + 1)])
    a = fm.map_clusters(z, cid, cen, offsets=off)
    b = fm.map_clusters(zl, cid, cen)
    assert np.max(np.abs(a - b)) == 0.0
    assert np.max(np.abs(a - plain)) < 1e-13 * fm._diam
    # rotated normalisation (pipeline._best_rotation): f_ψ(z) = f(z e^{−iψ})
    theta = np.mod(fm.theta, 2 * np.pi)
    disk = _disk(pipeline.vertex_intervals(theta, OPTS))
    rot = pipeline._RotatedMap(fm, 0.4)
    img = pipeline._evaluate_map(rot, disk)
    want = fm(disk.vertices / np.exp(0.4j))
    assert np.max(np.abs(img - want)) < 1e-12 * fm._diam
    gc, dgc = pipeline._evaluate_map(rot, frames=zl[:20], offsets=np.full(20, 1e-17))
    zr = (z[:20] + 1e-17) / np.exp(0.4j)
    assert np.max(np.abs(gc - fm(zr))) < 1e-12 * fm._diam
    want = fm.derivative(zr) / np.exp(0.4j)
    assert np.max(np.abs(dgc - want) / np.abs(want)) < 1e-10


def test_project_to_sides_uses_long_double_angles() -> None:
    """Two prevertices 1e-17 apart (below float64 resolution at θ ≈ 1): a circle point
    between them goes to the side between them only with long double angles."""
    theta = np.array([0.0, 1.0, 1.0, 3.0], dtype=np.longdouble)
    theta[2] += np.longdouble(1e-17)
    zpoly = np.array([0.0, 2.0, 2.0 + 1e-3j, 2.0 + 1j])
    t = np.array([np.longdouble(1.0) + np.longdouble(5e-18)])
    w = np.array([1.9 + 5e-4j])
    got = pipeline._project_to_sides(w, t, theta, zpoly)
    assert abs(got[0] - (2.0 + 5e-4j)) < 1e-15  # side [w_1, w_2]
