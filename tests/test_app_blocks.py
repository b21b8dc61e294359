"""Blocks in the app (issue 14): the Mesh panel's method selector and Block size control, the
plane view's "Block layout" layer, the stage "block" of a picked quad, the note when Blocks falls
back to the paper's construction — pressed on the real widgets (run under ``xvfb-run``).  The
layer builders of :mod:`quadmesh.render` on a block result are checked without a display."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt

from quadmesh import MeshOptions, mesh_polygon, render
from quadmesh.examples import load_example
from quadmesh.polygon import validate_polygon
from tests.helpers import L_SHAPE, require_pipeline
from tests.test_app import assert_angles_ok, click, keys, load_example_by_menu, press, tick
from tests.test_blocks import NO_LAYOUT


def _segments(part) -> np.ndarray:
    """(K, 2) complex end points of a part made of 2-point line cells."""
    pts = np.asarray(part.mesh.points)[:, :2]
    z = pts[:, 0] + 1j * pts[:, 1]
    lines = np.asarray(part.mesh.lines).reshape(-1, 3)
    assert np.all(lines[:, 0] == 2)
    return z[lines[:, 1:]]


def _same_segments(got: np.ndarray, want: np.ndarray, tol: float) -> bool:
    """The same set of undirected segments (any order) up to ``tol``."""
    if got.shape != want.shape:
        return False
    used = np.zeros(len(want), dtype=bool)
    for a, b in got:
        d = np.minimum(
            np.abs(want[:, 0] - a) + np.abs(want[:, 1] - b),
            np.abs(want[:, 0] - b) + np.abs(want[:, 1] - a),
        )
        d[used] = np.inf
        j = int(np.argmin(d))
        if d[j] > tol:
            return False
        used[j] = True
    return True


# ------------------------------------------------------------------------- render (no display)
def test_block_layout_layer_far_polygon_and_other_layers() -> None:
    """The layer draws every cut once, at the input's coordinates for a polygon far from (0, 0)
    (its layout is relative to ``result.origin``); every other plane layer and the disk layers
    cope with a block result; the angle colour range is [60°, 120°] although all are 90°."""
    far = L_SHAPE * 10.0 + complex(5e6, 3e6)  # complex vertices
    r = mesh_polygon(far, MeshOptions(method="blocks"))
    assert r.blocks is not None and r.origin != 0 and r.decomposition is None
    geo = render.build_layer(r, "block_layout")
    cuts = geo.part("cuts")
    assert cuts.n_cells == len(r.blocks.cuts) == 2
    want = np.asarray(r.blocks.cuts) + r.origin
    assert _same_segments(_segments(cuts), want, tol=1e-6)
    # the cuts end on the polygon's boundary, in the input's coordinates
    edges = np.column_stack([far, np.roll(far, -1)])
    for p in _segments(cuts).ravel():
        d = edges[:, 1] - edges[:, 0]
        t = np.clip(((p - edges[:, 0]) * np.conj(d)).real / np.abs(d) ** 2, 0, 1)
        assert np.min(np.abs(p - (edges[:, 0] + t * d))) < 1e-6
    # no spokes: the L-shape's three blocks are not split
    with pytest.raises(KeyError):
        geo.part("cell edges")
    for name in render.layer_names("plane"):
        g = render.build_layer(r, name)
        if name in ("thick_pieces", "thin_parts", "crosscuts", "conformal_images", "bad_quads"):
            assert g.n_cells == 0, name
    for name in render.layer_names("disk"):
        g = render.build_layer(r, name)
        assert (g.n_cells > 0) == (name == "tessellation"), name
    fm = render.build_layer(r, "final_mesh")
    assert fm.part("quads").clim == (60.0, 120.0)
    assert fm.part("quads").n_cells == r.mesh.n_quads == 3 * 8 * 8
    worst = render.build_layer(r, "final_mesh", color_by="worst").part("quads")
    assert worst.clim == (0.0, 30.0)


def test_split_layout_draws_its_spokes() -> None:
    """A layout whose faces are split about centre points (the pentagon: one face, five cells)
    draws the spokes from the centre as "cell edges": with the outline they bound every cell."""
    r = mesh_polygon(load_example("pentagon"), MeshOptions(method="blocks"))
    lay = r.blocks
    assert lay.split and len(lay.cuts) == 0 and lay.n_cells == 5
    geo = render.build_layer(r, "block_layout")
    spokes = _segments(geo.part("cell edges"))
    assert len(spokes) == 5
    # each spoke joins the centre (the one point shared by all cells) to a boundary point
    centre = [i for i in range(len(lay.points)) if np.all(np.any(lay.cells == i, axis=1))]
    assert len(centre) == 1
    c = lay.points[centre[0]] + r.origin
    assert np.all(np.min(np.abs(spokes - c), axis=1) < 1e-9)
    with pytest.raises(KeyError):
        geo.part("cuts")


# ------------------------------------------------------------------------------- GUI tests
def _load_example(win, qtbot, name: str) -> np.ndarray:
    """Examples ▸ name, picked from the menu with the mouse; returns the polygon's vertices."""
    load_example_by_menu(qtbot, win, name)
    verts = load_example(name)
    assert len(win.editor.points) == len(verts) and win.editor.closed
    return verts


def _type_polygon(win, qtbot, verts: np.ndarray) -> None:
    """Edit ▸ Enter coordinates… (Ctrl+K): type one "x y" line per vertex and press OK."""
    keys(qtbot, win, "Ctrl+K")
    dlg = win.coordinates_dialog
    qtbot.waitUntil(dlg.isVisible, timeout=3000)
    dlg.edit.selectAll()
    qtbot.keyClick(dlg.edit, Qt.Key.Key_Delete)
    for k, (x, y) in enumerate(verts):
        if k:
            qtbot.keyClick(dlg.edit, Qt.Key.Key_Return)
        qtbot.keyClicks(dlg.edit, f"{float(x)!r} {float(y)!r}")
    press(qtbot, dlg.buttons.button(dlg.buttons.StandardButton.Ok))
    qtbot.waitUntil(lambda: not dlg.isVisible(), timeout=3000)
    assert win.editor.closed and len(win.editor.points) == len(verts)


def _choose_blocks_by_mouse(win, qtbot) -> None:
    """Open the Method combo with the mouse and click "Blocks" in its popup."""
    combo = win.method_combo
    press(qtbot, combo)
    view = combo.view()
    qtbot.waitUntil(view.isVisible)
    qtbot.wait(400)  # a popup ignores a release that comes right after it opened
    idx = combo.model().index(combo.findData("blocks"), 0)
    qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=view.visualRect(idx).center())
    qtbot.waitUntil(lambda: combo.currentData() == "blocks")


def _mesh_by_click(win, qtbot) -> None:
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
        assert win.last_error is None, win.last_error
    assert win.last_error is None, win.last_error
    assert win.progress_bar.format().startswith("done in")


@pytest.mark.gui
def test_blocks_chosen_with_the_keyboard_mesh_layer_and_pick(main_window, qtbot):
    require_pipeline()
    win = main_window
    verts = _load_example(win, qtbot, "t_shape")
    combo, spin = win.method_combo, win.block_size_spin
    # the paper's construction is the default; Block size is off until Blocks is chosen
    assert combo.currentData() == "bishop" and win.mesh_options().method == "bishop"
    assert not spin.isEnabled() and win.option_widgets["depth_step"].isEnabled()
    combo.setFocus()
    qtbot.keyClick(combo, Qt.Key.Key_Down)
    assert combo.currentData() == "blocks" and combo.currentText() == "Blocks (few quads)"
    assert spin.isEnabled()
    for name in ("n", "depth_step", "rotations", "conformal_tol", "adaptive", "repair"):
        assert not win.option_widgets[name].isEnabled(), name
    assert spin.value() == pytest.approx(0.05)
    spin.setFocus()
    spin.selectAll()
    qtbot.keyClicks(spin, "0.1")
    qtbot.keyClick(spin, Qt.Key.Key_Return)
    assert spin.value() == pytest.approx(0.1)
    _mesh_by_click(win, qtbot)

    r = win.result
    d = validate_polygon(verts).diameter
    assert r.options.method == "blocks" and r.options.size == pytest.approx(0.1 * d, rel=1e-12)
    assert r.blocks is not None and r.fallback is None
    assert r.verification.ok
    assert_angles_ok(r.mesh, r.quality)
    want = mesh_polygon(verts, MeshOptions(method="blocks", size=0.1 * d))
    assert r.mesh.n_quads == want.mesh.n_quads
    assert r.blocks.n_cells == 4 and len(r.blocks.cuts) == 3
    assert np.all(np.asarray(r.quad_source) == 4)
    assert not win.note_label.isVisible()
    info = win.info_label.text()
    assert "blocks" in info and "coarse cells" in info and "layers not drawn" not in info

    # the block layout layer: one line per cut, in the cuts' colour, over the final mesh
    st = win.plane.layers["block_layout"]
    cuts = st.geometry.part("cuts")
    assert cuts.n_cells == len(r.blocks.cuts)
    assert _same_segments(_segments(cuts), np.asarray(r.blocks.cuts) + r.origin, 1e-12)
    actors = win.plane.layer_actors("block_layout")
    assert actors and all(a.GetVisibility() for a in actors)
    # drawn after (over) the final mesh: later in the renderer's actor list
    coll = win.plane.plotter.renderer.GetActors()
    order = [coll.GetItemAsObject(i) for i in range(coll.GetNumberOfItems())]
    fm = win.plane.layer_actors("final_mesh")
    assert min(order.index(a) for a in actors) > max(order.index(a) for a in fm)
    assert win.legend.labels("block_layout") == ["cut"]
    cb = win.layer_panel.checkboxes["block_layout"]
    assert cb.text() == "Block layout" and cb.isChecked()
    tick(qtbot, cb)
    assert not cb.isChecked() and not any(a.GetVisibility() for a in actors)
    assert win.legend.labels("block_layout") == []
    tick(qtbot, cb)
    assert cb.isChecked() and all(a.GetVisibility() for a in actors)
    assert win.legend.labels("block_layout") == ["cut"]

    # the Bishop-only layers are empty, the disk view shows only the tessellation
    for name in ("thick_pieces", "thin_parts", "crosscuts", "conformal_images"):
        assert not win.plane.layer_actors(name), name
    for name in ("region_w", "disk_mesh", "prevertices"):
        assert not win.disk.layer_actors(name), name
    assert win.disk.layer_actors("tessellation")
    assert win.piece_spin.maximum() == 0 and not win.piece_spin.isEnabled()

    # clicking a quad says it came from a block, and which coarse cell
    mesh = r.mesh
    k = mesh.n_quads // 3
    c = mesh.z[mesh.quads[k]].mean()
    click(qtbot, win.plane, c)
    got = win.picked_quad
    assert got is not None and got["stage"] == "block"
    text = win.quad_label.text()
    assert "stage: block" in text and "coarse cell" in text
    cell = r.blocks.points[r.blocks.cells[got["piece"]]]
    e = np.roll(cell, -1) - cell
    w = mesh.z[mesh.quads[got["quad"]]].mean() - r.origin
    assert np.all((e.real * (w - cell).imag - e.imag * (w - cell).real) >= -1e-12)

    # back to the paper's construction: Block size off again, the paper's options on
    combo.setFocus()
    qtbot.keyClick(combo, Qt.Key.Key_Up)
    assert combo.currentData() == "bishop" and not spin.isEnabled()
    assert win.option_widgets["depth_step"].isEnabled()
    assert win.mesh_options().method == "bishop" and win.mesh_options().size is None


@pytest.mark.gui
def test_no_layout_falls_back_and_says_why(main_window, qtbot):
    """Blocks chosen with the mouse on a typed triangle with a 120.2° apex (no straight cuts,
    ladder or collar close around it): the run falls back to the paper's construction, the
    Mesh panel and the status bar say why, and the paper's stages are drawn as usual."""
    require_pipeline()
    win = main_window
    verts = NO_LAYOUT
    _type_polygon(win, qtbot, verts)
    _choose_blocks_by_mouse(win, qtbot)
    assert win.block_size_spin.isEnabled()
    _mesh_by_click(win, qtbot)

    r = win.result
    assert r.blocks is None and r.fallback and "paper's construction" in r.fallback
    assert r.verification.ok and r.pieces
    assert_angles_ok(r.mesh, r.quality)
    want = mesh_polygon(
        verts, MeshOptions(method="blocks", size=0.05 * validate_polygon(verts).diameter)
    )
    assert want.fallback == r.fallback and want.mesh.n_quads == r.mesh.n_quads
    assert win.note_label.isVisible() and r.fallback in win.note_label.text()
    assert r.fallback in win.statusBar().currentMessage()
    assert "fell back" in win.info_label.text()
    assert win.error_box.isHidden()  # not a failure
    assert not win.plane.layer_actors("block_layout")
    assert win.disk.layer_actors("disk_mesh")  # the paper's disk construction is shown
    assert win.piece_spin.isEnabled()
    # a picked quad names its stage from the paper's construction
    src = np.asarray(r.quad_source)
    k = int(np.flatnonzero(src == 0)[0])
    click(qtbot, win.plane, r.mesh.z[r.mesh.quads[k]].mean())
    assert win.picked_quad is not None and win.picked_quad["stage"] in ("disk", "sector")
    # an edit drops the result and its note
    win.set_polygon(L_SHAPE)
    assert win.result is None and not win.note_label.isVisible()


@pytest.mark.gui
def test_spiral_blocks_by_a_ladder_show_rungs_and_sectors(main_window, qtbot):
    """Blocks chosen with the mouse on the 3-turn pen spiral (no straight cuts close): the layout
    is a ladder of straight cells along the corridor; the legend calls its lines rungs, the
    information panel names the ladder, and a clicked quad names its coarse cell or, at a
    round end, the vertex sector it belongs to."""
    import shapely

    require_pipeline()
    win = main_window
    verts = _load_example(win, qtbot, "stroke_spiral")
    _choose_blocks_by_mouse(win, qtbot)
    _mesh_by_click(win, qtbot)

    r = win.result
    assert r.fallback is None and r.blocks.kind == "ladder"
    assert r.verification.ok
    assert_angles_ok(r.mesh, r.quality)
    want = mesh_polygon(
        verts, MeshOptions(method="blocks", size=0.05 * validate_polygon(verts).diameter)
    )
    assert want.mesh.n_quads == r.mesh.n_quads
    assert (
        win.legend.labels("block_layout")[0] == "rung (ladder of straight cells along a corridor)"
    )
    info = win.info_label.text()
    assert "ladder" in info and "rungs" in info
    # quads inside a coarse cell and quads in a round end (outside every cell)
    lay = r.blocks
    cells = shapely.MultiPolygon(
        [shapely.Polygon(np.column_stack([c.real, c.imag])) for c in lay.points[lay.cells]]
    )
    cent = r.mesh.z[r.mesh.quads].mean(axis=1)
    shift = complex(r.origin or 0j) - complex(r.mesh_origin or 0j)
    inside = shapely.contains_xy(cells.buffer(-1e-9), (cent + shift).real, (cent + shift).imag)
    assert inside.any() and (~inside).any()
    for k, part in (
        (int(np.flatnonzero(inside)[0]), "coarse cell"),
        (int(np.flatnonzero(~inside)[0]), "round end"),
    ):
        click(qtbot, win.plane, r.mesh.z[r.mesh.quads[k]].mean())
        assert win.picked_quad is not None and part in win.picked_quad["part"], k
        assert part in win.quad_label.text()


@pytest.mark.gui
def test_octagon_blocks_by_a_collar_show_spokes(main_window, qtbot):
    """Blocks chosen with the mouse on the octagon (no straight cuts close there): the layout
    is a collar around a lattice core, the legend calls its lines spokes and the information
    panel names the collar; the mesh is verified."""
    require_pipeline()
    win = main_window
    verts = _load_example(win, qtbot, "octagon")
    _choose_blocks_by_mouse(win, qtbot)
    _mesh_by_click(win, qtbot)

    r = win.result
    assert r.fallback is None and r.blocks.kind == "ring"
    assert r.verification.ok
    assert_angles_ok(r.mesh, r.quality)
    want = mesh_polygon(
        verts, MeshOptions(method="blocks", size=0.05 * validate_polygon(verts).diameter)
    )
    assert want.mesh.n_quads == r.mesh.n_quads
    assert win.legend.labels("block_layout")[0] == "spoke (collar around a lattice core)"
    assert "collar" in win.info_label.text()
    assert win.plane.layer_actors("block_layout")


@pytest.mark.parametrize(
    ("alone", "label", "part", "key"),
    [
        (True, "face laid out on its own", "faces laid out on their own", "local faces"),
        (
            False,
            "face meshed by the paper's construction",
            "faces meshed by the paper's construction",
            "fallback faces",
        ),
    ],
)
def test_faces_that_did_not_split_have_a_legend_entry_and_a_filled_part(
    monkeypatch, alone: bool, label: str, part: str, key: str
) -> None:
    """A block layout with a face that did not split with the others (the middle of three
    unit squares): laid out on its own, or (as if that failed) meshed by the paper's
    construction. The legend of the block layer names it in the fill's colour, and the layer
    fills exactly that face."""
    from types import SimpleNamespace

    import quadmesh.blocks as blocks
    from app.legend import legend_entries
    from quadmesh.blocks import PartialLayout, mesh_partial_layout
    from quadmesh.pipeline import _face_mesher
    from quadmesh.render import BLOCK_COLORS

    if not alone:
        monkeypatch.setattr(blocks, "_face_layout", lambda w, size, depth, deadline=None: None)
    z = np.array([0, 1, 2, 3, 3 + 1j, 2 + 1j, 1 + 1j, 1j], dtype=np.complex128)
    faces = tuple(np.array(f) for f in ([0, 1, 6, 7], [1, 2, 5, 6], [2, 3, 4, 5]))
    strip = PartialLayout(
        z, z.copy(), faces, frozenset({1}), np.zeros(8, dtype=bool), np.ones(8, dtype=bool)
    )
    _pts, _quads, lay, _info = mesh_partial_layout(
        strip, 0.25, _face_mesher(MeshOptions(), None, None)
    )
    r = SimpleNamespace(blocks=lay, decomposition=None, origin=0j)
    got = legend_entries(r, {"block_layout"})
    assert ("block_layout", label, BLOCK_COLORS[key]) in got
    other = "face meshed by the paper's construction" if alone else "face laid out on its own"
    assert other not in [e[1] for e in got]
    assert legend_entries(r, set()) == []
    fill = render.build_layer(r, "block_layout").part(part)
    assert fill.color == BLOCK_COLORS[key]
    assert abs(fill.mesh.area - 1.0) < 1e-12
