"""quadmesh.render: layers of a MeshResult as pyvista geometry, off-screen PNGs (no display)."""

from __future__ import annotations

import os

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

from quadmesh import render  # noqa: E402
from tests.helpers import L_SHAPE, require_pipeline  # noqa: E402

INTERVALS = np.array([[0.3, 0.02], [2.0, 0.05], [4.0, 0.01]])


def _png_variance(path) -> float:
    from PIL import Image

    return float(np.asarray(Image.open(path).convert("RGB"), dtype=float).var())


@pytest.fixture(scope="module")
def result():
    require_pipeline()
    from quadmesh.pipeline import mesh_polygon

    return mesh_polygon(L_SHAPE)


def test_layer_names() -> None:
    assert render.layer_names("plane") == [
        "polygon",
        "thick_pieces",
        "thin_parts",
        "crosscuts",
        "conformal_images",
        "final_mesh",
        "block_layout",
        "bad_quads",
    ]
    assert render.layer_names("disk") == ["tessellation", "region_w", "disk_mesh", "prevertices"]
    with pytest.raises(ValueError, match="unknown view"):
        render.layer_names("sphere")


def test_polygon_layer_fill_area_and_outline() -> None:
    geo = render.polygon_layer(L_SHAPE)
    fill = geo.part("fill").mesh
    tri = np.asarray(fill.points)[:, :2]
    t = tri[:, 0] + 1j * tri[:, 1]
    a, b, c = t[0::3], t[1::3], t[2::3]
    area = 0.5 * np.abs(np.imag(np.conj(b - a) * (c - a))).sum()
    assert area == pytest.approx(3.0, rel=1e-12)  # L-shape area, non-convex fill is correct
    outline = geo.part("outline").mesh
    assert outline.n_cells == 1 and outline.n_points == 6
    assert outline.lines[0] == 7  # closed: 6 vertices + the first again
    open_geo = render.polygon_layer(L_SHAPE[:3], closed=False)
    assert [p.label for p in open_geo.parts] == ["outline", "vertices"]


def test_tessellation_layer_counts_each_edge_once() -> None:
    from quadmesh.disk.tessellation import P0_VERTICES, generate_tiles
    from quadmesh.hyperbolic.geodesic import distance

    tiles, _ = generate_tiles(depth=3)
    # Euler: the tiles form a topological disk, V - E + F = 1
    v = tiles.apply_rows(P0_VERTICES).ravel()
    n_vertices = np.unique(np.round(np.column_stack([v.real, v.imag]) * 1e8), axis=0).shape[0]
    n_edges = n_vertices + len(tiles) - 1
    geo = render.build_disk_layer("tessellation", tessellation_depth=3)
    part = geo.parts[0]
    assert part.n_cells == n_edges
    assert np.all(np.abs(part.disk_z) < 1)
    # every edge is a geodesic segment of length L (T5 side, DISK.md §2)
    arcs = part.disk_z.reshape(n_edges, -1)
    assert np.allclose(distance(arcs[:, 0], arcs[:, -1]), 1.0612750619, atol=1e-8)
    # re-centred: the tile containing the centre is drawn (some edge passes close to it)
    c = 0.9 + 0.3j
    geo_c = render.build_disk_layer("tessellation", tessellation_depth=2, tessellation_center=c)
    assert np.min(distance(geo_c.parts[0].disk_z, c)) < 1.0


@pytest.fixture(scope="module")
def disk():
    from quadmesh.disk.assembly import disk_mesh

    return disk_mesh(INTERVALS, A=16.0, n=2)


def test_disk_layers_from_disk_mesh(disk, tmp_path) -> None:
    w = render.build_disk_layer("region_w", disk)
    kinds = [p for p in w.parts if p.label in render.KIND_COLORS]
    for part in kinds:
        assert part.n_cells == int(np.sum(disk.kind == part.label)) > 0
    assert sum(p.n_cells for p in kinds) == disk.quads.shape[0]
    # piece outlines: every edge on T or on a γ_j is a piece boundary, interior edges of a
    # pentagon mesh are not
    outl = w.part("piece outlines")
    assert 0 < outl.n_cells < 2 * disk.quads.shape[0]
    mesh = render.build_disk_layer("disk_mesh", disk).parts[0]
    a = disk.quads.ravel()
    b = np.roll(disk.quads, -1, axis=1).ravel()
    n_edges = np.unique(np.minimum(a, b) * disk.vertices.size + np.maximum(a, b)).size
    assert mesh.n_cells == n_edges
    pre = render.build_disk_layer("prevertices", disk, intervals=INTERVALS)
    assert pre.part("J arcs").n_cells == len(INTERVALS)
    assert pre.part("I arcs").n_cells == len(INTERVALS)
    # J_j ⊇ √A·I_j ⊇ I_j: every drawn point of I_j lies in the angular range of J_j
    for (js, jl), (i_s, i_l) in zip(disk.pieces.J, INTERVALS, strict=True):
        t = i_s + np.linspace(0, i_l, 9)
        assert np.all(np.mod(t - js, 2 * np.pi) <= jl)
    jarcs = pre.part("J arcs")
    np.testing.assert_allclose(np.abs(jarcs.disk_z), 1.0, atol=1e-12)  # points on T ...
    pts = np.asarray(jarcs.mesh.points)
    assert np.all(np.hypot(pts[:, 0], pts[:, 1]) > 1.0)  # ... drawn just outside it
    out = render.render_disk_png(disk, tmp_path / "disk.png", intervals=INTERVALS, size=(300, 300))
    assert _png_variance(out) > 10.0


def test_final_mesh_layer(result) -> None:
    q = result.quality
    geo = render.build_layer(result, "final_mesh")
    quads = geo.part("quads")
    assert quads.n_cells == result.mesh.quads.shape[0] == q.n_quads
    # the colour range is [60°, 120°] (widened only by new angles outside it)
    assert quads.clim == pytest.approx((min(q.min_angle, 60.0), max(q.max_angle, 120.0)))
    vals = np.asarray(quads.mesh.point_data["corner_angle"])
    assert vals.min() == pytest.approx(q.min_angle) and vals.max() == pytest.approx(q.max_angle)
    assert geo.scalar_bar_titles == [render.CORNER_TITLE]
    worst = render.build_layer(result, "final_mesh", color_by="worst").part("quads")
    dev = np.asarray(worst.mesh.cell_data["worst_deviation"])
    assert dev.max() == pytest.approx(max(90 - q.min_angle, q.max_angle - 90))


def test_plane_layers_match_result(result) -> None:
    disk_q = sum(p.disk.quads.shape[0] for p in result.pieces)
    conf = render.build_layer(result, "conformal_images")
    kinds = [p for p in conf.parts if p.label in render.KIND_COLORS]
    assert sum(p.n_cells for p in kinds) == disk_q
    thin = render.build_layer(result, "thin_parts")
    thin_q = sum(np.asarray(t.mesh.quads).shape[0] for t in result.thin)
    assert sum(p.n_cells for p in thin.parts if p.label in render.THIN_COLORS) == thin_q
    bad = render.build_layer(result, "bad_quads")
    assert int(render.bad_quad_mask(result).sum()) == result.quality.n_quads_outside
    assert bad.n_cells >= 0
    thick = render.build_layer(result, "thick_pieces")
    assert thick.n_cells > 0
    assert render.build_layer(result, "crosscuts").view == "plane"


def test_disk_layers_match_result(result) -> None:
    p = result.pieces[0]
    w = render.build_layer(result, "region_w")
    kinds = [part for part in w.parts if part.label in render.KIND_COLORS]
    for part in kinds:
        assert part.n_cells == int(np.sum(np.asarray(p.disk.kind) == part.label))
    assert sum(part.n_cells for part in kinds) == p.disk.quads.shape[0]
    pre = render.build_layer(result, "prevertices").part("prevertices")
    assert pre.n_cells == len(p.map.prevertices)
    np.testing.assert_allclose(np.abs(pre.disk_z), 1.0, atol=1e-12)


def test_render_png_not_blank(result, tmp_path) -> None:
    out = render.render_png(result, tmp_path / "plane.png", size=(400, 300))
    assert _png_variance(out) > 10.0
    out = render.render_png(result, tmp_path / "disk.png", view="disk", size=(300, 300))
    assert _png_variance(out) > 10.0
    with pytest.raises(ValueError, match="unknown plane layers"):
        render.render_png(result, tmp_path / "x.png", layers=["region_w"])
