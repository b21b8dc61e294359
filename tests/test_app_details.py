"""GUI tests of the app's detail features (issue 12), driven like a user: per-quad cell data in
exported files, clicking a quad, the cursor readout, tooltips, the legend, the shortcut help,
recent files and the marker at the place a failed run names.  Run under ``xvfb-run``."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from tests.helpers import require_pipeline
from tests.test_app import _pos, answer_file_dialog, click, keys, mesh_l_shape, press, tick, wheel

pytestmark = pytest.mark.gui


@pytest.fixture
def meshed(main_window, qtbot):
    """The window showing the meshed L-shape (meshed by clicking Mesh once per session)."""
    return mesh_l_shape(main_window, qtbot)


def _thin_quad_corners(t) -> np.ndarray:
    v = np.asarray(t.mesh.vertices)
    z = v if np.iscomplexobj(v) else v[:, 0] + 1j * v[:, 1]
    return z[np.asarray(t.mesh.quads, dtype=np.int64)]


def test_export_carries_cell_data(meshed, qtbot, tmp_path):
    """File ▸ Export (Ctrl+E) to VTU, VTK and MSH: meshio reads back, per quad, the four
    corner angles, min/max, the worst |angle − 90°|, the stage kind (= quad_source) and the
    piece; each piece's quads are exactly the quads that piece made."""
    import meshio

    win = meshed
    r = win.result
    mesh = r.mesh
    ang = mesh.angles()
    for ext, filt in (
        ("vtu", "VTK XML (*.vtu)"),
        ("vtk", "VTK (*.vtk)"),
        ("msh", "Gmsh 2.2 (*.msh)"),
    ):
        path = tmp_path / f"cells.{ext}"
        ans = answer_file_dialog(qtbot, str(path), filt)
        keys(qtbot, win, "Ctrl+E")
        ans.check()
        assert path.is_file()
        m = meshio.read(path)
        cd = {k: np.concatenate([np.asarray(b).ravel() for b in v]) for k, v in m.cell_data.items()}
        for name in ("angle_0", "angle_1", "angle_2", "angle_3", "min_angle", "max_angle"):
            assert cd[name].shape == (mesh.n_quads,), (ext, name)
        for k in range(4):
            np.testing.assert_allclose(cd[f"angle_{k}"], ang[:, k], atol=1e-9)
        np.testing.assert_allclose(cd["min_angle"], ang.min(axis=1), atol=1e-9)
        np.testing.assert_allclose(cd["max_angle"], ang.max(axis=1), atol=1e-9)
        np.testing.assert_allclose(cd["worst_deviation"], np.abs(ang - 90).max(axis=1), atol=1e-9)
        assert cd["worst_deviation"].max() <= 30.0 + 1e-6  # every quad in [60°, 120°]
        np.testing.assert_array_equal(cd["stage"], np.asarray(r.quad_source))
        piece = cd["piece"].astype(int)
        assert piece.shape == (mesh.n_quads,)
        # the L-shape has thick pieces (stage 0) and vertex sectors (stage 1)
        assert set(np.unique(cd["stage"]).astype(int)) >= {0, 1}
        corners = mesh.z[mesh.quads]
        for k, p in enumerate(r.pieces):
            sel = piece == k
            assert np.all(cd["stage"][sel] == 0)
            np.testing.assert_allclose(
                corners[sel], np.asarray(p.image)[np.asarray(p.disk.quads)], atol=1e-12
            )
        for j, t in enumerate(r.thin):
            sel = piece == len(r.pieces) + j
            np.testing.assert_allclose(corners[sel], _thin_quad_corners(t), atol=1e-12)
        assert np.unique(piece).size == len(r.pieces) + len(r.thin)


def test_click_quad_shows_angles_stage_piece_and_cursor_readout(meshed, qtbot):
    """Moving the mouse over the plane view shows the cursor's coordinates in the status bar;
    clicking inside a quad (not in draw mode) shows its four angles, stage kind and piece and
    outlines it; clicking outside the mesh says so."""
    win = meshed
    r = win.result
    mesh = r.mesh
    view = win.plane
    assert not win.draw_check.isChecked()
    # pick a sector quad and a thick-piece quad: centroid of each
    src = np.asarray(r.quad_source)
    for stage in (1, 0):
        k = int(np.flatnonzero(src == stage)[len(np.flatnonzero(src == stage)) // 2])
        c = mesh.z[mesh.quads[k]].mean()
        qtbot.mouseMove(view.plotter, _pos(view, c))
        qtbot.waitUntil(lambda: win.coord_label.text().startswith("x = "))
        x, y = (float(v.split("=")[1]) for v in win.coord_label.text().split(","))
        px = view.pixel_size()
        assert abs(x - c.real) < 2 * px and abs(y - c.imag) < 2 * px
        click(qtbot, view, c)
        info = win.picked_quad
        assert info is not None
        got = info["quad"]
        # the click landed in quad k, or (within a pixel) in a neighbour sharing its centroid
        corners = mesh.z[mesh.quads[got]]
        assert win.quad_at(c) in (k, got)
        np.testing.assert_allclose(info["angles"], mesh.angles()[got], atol=1e-12)
        assert info["stage"] == {0: "disk", 1: "sector"}[int(src[got])]
        text = win.quad_label.text()
        for a in mesh.angles()[got]:
            assert f"{a:.2f}°" in text
        assert f"stage: {info['stage']}" in text and f"piece {info['piece']}" in text
        if stage == 1:
            assert "vertex sector at vertex" in text
        else:
            assert "thick piece" in text
        assert text in win.statusBar().currentMessage()
        outline = win.plane.overlays["picked_quad"]
        assert len(outline) == 1
        pts = np.asarray(outline[0].GetMapper().GetInput().GetPoints().GetData())
        zz = pts[:, 0] + 1j * pts[:, 1]
        assert min(np.abs(zz - w).min() for w in corners) < 1e-9
    # outside the L-shape: no quad
    outside = complex(1.5, 1.5)
    click(qtbot, view, outside)
    assert win.picked_quad is None and "no quad at" in win.quad_label.text()
    assert "picked_quad" not in win.plane.overlays


def test_mesh_panel_tooltips_legend_and_shortcut_help(meshed, qtbot):
    """Every input of the Mesh panel explains itself; the legend lists the colours of the
    thin-part kinds drawn; Help ▸ Keyboard shortcuts (through the real menu) lists every
    action shortcut of the window."""
    from PySide6.QtWidgets import (
        QAbstractSpinBox,
        QCheckBox,
        QLabel,
        QLineEdit,
        QTableWidget,
    )

    from quadmesh.render import PIECE_PALETTE, THIN_COLORS

    win = meshed
    panel = win.mesh_button.parentWidget()
    inputs = [
        w for cls in (QAbstractSpinBox, QCheckBox, QLineEdit) for w in panel.findChildren(cls)
    ]
    inputs = [w for w in inputs if not isinstance(w.parentWidget(), QAbstractSpinBox)]
    assert len(inputs) == len(win.option_widgets) >= 10
    for w in inputs:
        assert len(w.toolTip()) > 40, f"{w} has no useful tooltip"
    assert len({w.toolTip() for w in inputs}) == len(inputs)  # one per setting
    assert "quads" in win.option_widgets["n"].toolTip()

    # legend: thin parts and thick pieces, as drawn
    r = win.result
    want = {"polygon", "thin_parts", "thick_pieces", "final_mesh"}
    for name, cb in win.layer_panel.checkboxes.items():  # ticked and unticked by mouse
        if cb.isChecked() != (name in want):
            tick(qtbot, cb)
    assert set(win.layer_panel.visible_layers()) == want
    assert win.legend.isVisible()
    kinds = {t.kind for t in r.thin}
    titles = {"parabolic": "vertex sector", "hyperbolic": "channel", "corridor": "corridor"}
    assert win.legend.labels("thin_parts") == [t for k, t in titles.items() if k in kinds]
    assert "vertex sector" in win.legend.labels("thin_parts")
    for lay, label, color in win.legend.entries:
        if lay == "thin_parts":
            kind = next(k for k, t in titles.items() if t == label)
            assert color == THIN_COLORS[kind]
    assert win.legend.labels("thick_pieces") == [
        f"thick piece {k}" for k in range(len(r.decomposition.thick))
    ]
    assert [c for lay, _, c in win.legend.entries if lay == "thick_pieces"] == list(
        PIECE_PALETTE[: len(r.decomposition.thick)]
    )
    # unticking the thin-parts layer removes its entries (and their widgets at once)
    press(qtbot, win.layer_panel.checkboxes["thin_parts"], QPoint(7, 8))
    assert win.legend.labels("thin_parts") == []

    def shown() -> list[str]:
        return sorted(w.text() for w in win.legend.findChildren(QLabel) if w.isVisible())

    qtbot.waitUntil(lambda: [t for t in shown() if t] == sorted(win.legend.labels()))

    # Help menu, clicked
    mb = win.menuBar()
    press(qtbot, mb, mb.actionGeometry(win.help_menu.menuAction()).center())
    qtbot.waitUntil(win.help_menu.isVisible)
    act = next(a for a in win.help_menu.actions() if "shortcuts" in a.text())
    qtbot.mouseClick(
        win.help_menu, Qt.MouseButton.LeftButton, pos=win.help_menu.actionGeometry(act).center()
    )
    qtbot.waitUntil(lambda: win.shortcuts_dialog is not None and win.shortcuts_dialog.isVisible())
    table = win.shortcuts_dialog.findChild(QTableWidget, "shortcuts_table")
    listed = {table.item(i, 0).text() for i in range(table.rowCount())}
    from PySide6.QtGui import QAction, QKeySequence

    expected = {
        a.shortcut().toString(QKeySequence.NativeText)
        for a in win.findChildren(QAction)
        if not a.shortcut().isEmpty()
    }
    assert expected <= listed
    assert {"Ctrl+M", "Ctrl+E", "Esc"} <= listed or {"Ctrl+M", "Ctrl+E", "Escape"} <= listed
    win.shortcuts_dialog.reject()


def _pick_recent(win, qtbot, k: int) -> None:
    """File ▸ Open recent ▸ entry ``k``, clicked with the mouse."""
    mb = win.menuBar()
    file_menu = win.recent_menu.menuAction().associatedObjects()[0]
    press(qtbot, mb, mb.actionGeometry(file_menu.menuAction()).center())
    qtbot.waitUntil(file_menu.isVisible)
    qtbot.mouseClick(
        file_menu,
        Qt.MouseButton.LeftButton,
        pos=file_menu.actionGeometry(win.recent_menu.menuAction()).center(),
    )
    qtbot.waitUntil(win.recent_menu.isVisible)
    target = win.recent_menu.actions()[k]
    qtbot.mouseClick(
        win.recent_menu,
        Qt.MouseButton.LeftButton,
        pos=win.recent_menu.actionGeometry(target).center(),
    )


def test_recent_files_menu(main_window, qtbot, tmp_path):
    """Files opened through File ▸ Open enter File ▸ Open recent (newest first, at most 8,
    kept in the settings); choosing an entry opens that file."""
    from quadmesh.io import write_polygon

    win = main_window
    assert not win.recent_menu.isEnabled()
    tri = np.array([[0, 0], [2, 0], [1, 1.5]], dtype=float)
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    a, b = tmp_path / "tri.json", tmp_path / "square.json"
    write_polygon(a, tri)
    write_polygon(b, sq)
    for p in (a, b):
        ans = answer_file_dialog(qtbot, str(p))
        keys(qtbot, win, "Ctrl+O")
        ans.check()
    assert win.editor.z.size == 4
    acts = win.recent_menu.actions()
    assert [x.data() for x in acts] == [str(b.resolve()), str(a.resolve())]
    assert win.settings.value("recent_files") == [str(b.resolve()), str(a.resolve())]
    # open the triangle again from the menu, as clicked
    _pick_recent(win, qtbot, 1)
    qtbot.waitUntil(lambda: win.editor.z.size == 3)
    np.testing.assert_allclose(
        np.sort_complex(win.editor.z), np.sort_complex(tri[:, 0] + 1j * tri[:, 1])
    )
    assert win.recent_menu.actions()[0].data() == str(a.resolve())
    # at most 8, newest first
    names = []
    for i in range(9):
        p = tmp_path / f"p{i}.json"
        write_polygon(p, tri + i)
        win.open_file(p)
        names.append(str(p.resolve()))
    assert [x.data() for x in win.recent_menu.actions()] == names[::-1][:8]
    # a file that disappeared leaves the list with a message
    gone = names[-1]
    (tmp_path / "p8.json").unlink()
    _pick_recent(win, qtbot, 0)
    assert gone not in win.recent_files() and "no longer exists" in win.last_error


def test_failed_run_marks_the_place_it_names(main_window, qtbot):
    """A traced contour whose meshing fails (scikit-image "coins", contour 0: a background
    region with a long wavy wedge, crowded, no ladder): the message names points "(x, y)"; red
    markers appear there in the plane view, and editing clears them."""
    require_pipeline()
    from quadmesh.families import images

    coins = next(m for m in images(0) if m.name == "coins_0").vertices
    win = main_window
    win.set_polygon(coins)
    assert win.editor.closed and win.mesh_button.isEnabled()
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
    assert win.result is None and win.progress_bar.format() == "failed"
    msg = win.last_error
    assert "(" in msg
    from app.window import message_points

    pts = message_points(msg)
    assert pts.size >= 1
    # the numbers as printed in the message
    import re

    first = re.search(r"\(([-\d.e+]+), ([-\d.e+]+)\)", msg)
    assert abs(pts[0] - complex(float(first.group(1)), float(first.group(2)))) == 0
    actors = win.plane.overlays["problem"]
    assert len(actors) == 1 and actors[0].GetVisibility()
    drawn = np.asarray(actors[0].GetMapper().GetInput().GetPoints().GetData())
    np.testing.assert_allclose(drawn[:, 0] + 1j * drawn[:, 1], pts, atol=1e-9)
    assert np.allclose(actors[0].prop.color.float_rgb, (224 / 255, 0, 0), atol=0.01)
    # the marked places lie at the polygon (within its bounding box, grown by its width)
    z = win.editor.z
    assert np.all((pts.real > z.real.min() - 1) & (pts.real < z.real.max() + 1))
    assert np.all((pts.imag > z.imag.min() - 1) & (pts.imag < z.imag.max() + 1))
    # what the run computed before it failed — its thick piece — is drawn too
    assert win.partial is not None and len(win.partial.decomposition.thick) >= 1
    part_actors = win.plane.overlays["partial"]
    assert part_actors and all(a.GetVisibility() for a in part_actors)
    bounds = np.asarray(part_actors[0].GetMapper().GetInput().bounds)
    assert bounds[0] >= z.real.min() - 1e-9 and bounds[1] <= z.real.max() + 1e-9
    # an edit forgets the failure, its markers and its partial stages
    win.set_polygon(coins[:-1])
    assert "problem" not in win.plane.overlays and win.problem_points.size == 0
    assert "partial" not in win.plane.overlays and win.partial is None


def test_the_wheel_zooms_about_the_cursor(meshed, qtbot):
    """A real wheel event over the plane view zooms in by 1.2 per notch and keeps the world
    point under the cursor where it was (zoom about the cursor, not the view's centre)."""
    win = meshed
    view = win.plane
    w, h = view.plotter.width(), view.plotter.height()
    x, y = 0.25 * w, 0.7 * h  # off-centre
    before = view.to_world(x, y)
    scale = view.plotter.camera.parallel_scale
    wheel(view, x, y, 2)
    assert view.plotter.camera.parallel_scale == pytest.approx(scale / 1.44, rel=1e-9)
    assert abs(view.to_world(x, y) - before) < 1e-9 * max(1.0, abs(before)) + 1e-6 * scale
