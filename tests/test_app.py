"""GUI tests of quadmesh-app, driven as a user drives it (pytest-qt; run under ``xvfb-run``,
skipped without a display): mouse clicks on the real buttons and checkboxes, keyboard
shortcuts, mouse presses/moves/releases on the views, answers typed into the real file and
colour dialogs.  Assertions are on results: quad counts and angles of the mesh on screen,
actor visibility, files written and read back."""

from __future__ import annotations

import time

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt, QTimer
from PySide6.QtGui import QKeySequence

from quadmesh import MeshOptions
from quadmesh.mesh import ANGLE_TOL_DEG
from tests.helpers import L_SHAPE, require_pipeline

pytestmark = pytest.mark.gui


# ------------------------------------------------------------------------------ user actions
def press(qtbot, widget, pos: QPoint | None = None) -> None:
    """Left click on a widget the user can see and reach."""
    assert widget.isVisible(), f"{widget} is not shown"
    assert widget.isEnabled(), f"{widget} is disabled"
    assert not widget.visibleRegion().isEmpty(), f"{widget} is covered / off screen"
    if pos is None:
        pos = widget.rect().center()
    qtbot.mouseClick(widget, Qt.MouseButton.LeftButton, pos=pos)


def tick(qtbot, checkbox) -> None:
    """Click a checkbox on its indicator (left edge, mid height)."""
    press(qtbot, checkbox, QPoint(7, checkbox.height() // 2))


def keys(qtbot, win, seq) -> None:
    """Type a key sequence into whatever has the keyboard focus (the window if nothing)."""
    from PySide6.QtWidgets import QApplication

    target = QApplication.focusWidget() or win
    qtbot.keySequence(target, QKeySequence(seq))


def _pos(view, z: complex) -> QPoint:
    x, y = view.to_widget(z)
    return QPoint(round(x), round(y))


def click(qtbot, view, z: complex, *, double: bool = False) -> None:
    """Left click (or double click) on the view at world point z."""
    if double:
        qtbot.mouseDClick(view.plotter, Qt.MouseButton.LeftButton, pos=_pos(view, z))
    else:
        qtbot.mouseClick(view.plotter, Qt.MouseButton.LeftButton, pos=_pos(view, z))


def drag(qtbot, view, a: complex, b: complex, steps: int = 4) -> None:
    """Press at a, move to b with the left button held, release."""
    w = view.plotter
    qtbot.mousePress(w, Qt.MouseButton.LeftButton, pos=_pos(view, a))
    for t in np.linspace(0, 1, steps + 1)[1:]:
        qtbot.mouseMove(w, _pos(view, a + t * (b - a)))
    qtbot.mouseRelease(w, Qt.MouseButton.LeftButton, pos=_pos(view, b))


class DialogAnswer:
    """Answers the next modal dialog of type ``cls`` from inside its event loop: ``act(dlg)``
    fills it in.  Failures reject the dialog (the test never hangs) and are re-raised by
    :meth:`check`."""

    def __init__(self, cls, act) -> None:
        self.cls, self.act = cls, act
        self.error: BaseException | None = None
        self.seen = False
        self._tries = 0
        QTimer.singleShot(0, self._poll)

    def _poll(self) -> None:
        from PySide6.QtWidgets import QApplication

        dlg = QApplication.activeModalWidget()
        if not isinstance(dlg, self.cls):
            self._tries += 1
            if self._tries < 200:
                QTimer.singleShot(25, self._poll)
            return
        self.seen = True
        try:
            self.act(dlg)
        except BaseException as exc:  # reported by check()
            self.error = exc
            dlg.reject()

    def check(self) -> None:
        assert self.seen, f"no {self.cls.__name__} was shown"
        if self.error is not None:
            raise self.error


def answer_file_dialog(qtbot, name: str, name_filter: str | None = None, record=None):
    """Type ``name`` into the next file dialog (choosing ``name_filter``) and press Enter;
    ``record`` gets the folder the dialog opened in."""
    from PySide6.QtWidgets import QFileDialog, QLineEdit

    def act(dlg) -> None:
        if record is not None:
            record.append(dlg.directory().absolutePath())
        if name_filter is not None:
            dlg.selectNameFilter(name_filter)
            assert dlg.selectedNameFilter() == name_filter
        edit = dlg.findChild(QLineEdit, "fileNameEdit")
        edit.setText(name)
        qtbot.keyClick(edit, Qt.Key.Key_Return)

    return DialogAnswer(QFileDialog, act)


def pixel_variance(path) -> float:
    from PySide6.QtGui import QImage

    img = QImage(str(path)).convertToFormat(QImage.Format_RGB888)
    assert not img.isNull(), f"cannot read {path}"
    buf = np.frombuffer(img.constBits(), dtype=np.uint8)
    arr = buf[: img.height() * img.bytesPerLine()].reshape(img.height(), img.bytesPerLine())
    return float(arr[:, : 3 * img.width()].astype(float).var())


def assert_angles_ok(mesh, quality) -> None:
    """Every new angle of the mesh on screen lies in [60°, 120°] (report and recomputed)."""
    assert quality.n_quads == mesh.n_quads > 0
    assert quality.n_angles_outside == 0
    assert 60.0 - ANGLE_TOL_DEG <= quality.min_angle <= quality.max_angle <= 120 + ANGLE_TOL_DEG
    ang = mesh.angles()[mesh.new_angle_mask()]
    assert ang.min() >= 60.0 - ANGLE_TOL_DEG and ang.max() <= 120.0 + ANGLE_TOL_DEG


def pick_menu(qtbot, win, menu, entry) -> None:
    """Click ``menu``'s title in the menu bar, then its entry ``entry`` (a QAction or the
    entry's text without '&' and '…'), as a user picks it with the mouse."""
    if isinstance(entry, str):
        entry = next(a for a in menu.actions() if _plain(a.text()) == entry)
    mb = win.menuBar()
    press(qtbot, mb, mb.actionGeometry(menu.menuAction()).center())
    qtbot.waitUntil(menu.isVisible, timeout=3000)
    rect = menu.actionGeometry(entry)
    assert menu.rect().contains(rect), f"{entry.text()} is outside its menu"
    qtbot.mouseClick(menu, Qt.MouseButton.LeftButton, pos=rect.center())
    qtbot.waitUntil(lambda: not menu.isVisible(), timeout=3000)


def _plain(text: str) -> str:
    return text.replace("&", "").replace("…", "").strip()


def load_example_by_menu(qtbot, win, name: str) -> None:
    """Examples ▸ ``name``, picked from the menu with the mouse."""
    pick_menu(qtbot, win, win.examples_menu, name)


def load_l_shape(win, qtbot) -> None:
    """Examples ▸ l_shape, picked from the menu with the mouse."""
    load_example_by_menu(qtbot, win, "l_shape")
    np.testing.assert_allclose(np.sort_complex(win.editor.z), np.sort_complex(L_SHAPE))


_MESHED: dict[str, object] = {}


@pytest.fixture
def meshed(main_window, qtbot):
    """The window after meshing the L-shape by clicking Mesh (:func:`mesh_l_shape`)."""
    return mesh_l_shape(main_window, qtbot)


def mesh_l_shape(win, qtbot):
    """Mesh the L-shape by clicking Mesh (the first time; later calls show the same
    MeshResult again to keep the GUI suite fast); returns the window."""
    require_pipeline()
    load_l_shape(win, qtbot)
    if "result" in _MESHED:
        win.set_result(_MESHED["result"])
        return win
    spin = win.option_widgets["depth_step"]
    spin.selectAll()
    qtbot.keyClicks(spin, "1")  # coarser Carleson rows: a faster test
    qtbot.keyClick(spin, Qt.Key.Key_Return)
    assert spin.value() == 1.0
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(20)
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
        assert win.last_error is None, win.last_error
        assert win.cancel_button.isEnabled() and not win.mesh_button.isEnabled()
    timer.stop()
    assert win.last_error is None, win.last_error
    assert win.result is not None
    assert win.result.options.depth_step == 1.0  # the parameter controls reach the mesher
    assert len(ticks) >= 3, "the GUI event loop did not run while the mesher worked"
    assert win.progress_bar.format().startswith("done in")
    _MESHED["result"] = win.result
    return win


# ------------------------------------------------------------------------------------ tests
def test_mesh_button_click_meshes(meshed):
    """Clicking Mesh runs the mesher (it used to fail with "'bool' object is not callable")."""
    win = meshed
    r = win.result
    assert_angles_ok(r.mesh, r.quality)
    assert win.plane.layers["final_mesh"].geometry.part("quads").n_cells == r.quality.n_quads
    assert "quads" in win.info_label.text()
    assert "repaired locally" in win.info_label.text()  # the L-shape's few sub-60° images
    assert win.histogram.counts.sum() == np.asarray(r.quality.histogram).sum()
    assert win.error_box.isHidden() and win.mesh_button.isEnabled()


def test_shortcut_mesh_and_cancel_buttons(main_window, qtbot):
    """Ctrl+M starts the mesher, the Cancel button stops it; Escape cancels as well."""
    require_pipeline()
    win = main_window
    load_l_shape(win, qtbot)
    keys(qtbot, win, "Ctrl+M")
    assert win.runner.busy and win.last_error is None, win.last_error
    with qtbot.waitSignal(win.runner.cancelled, timeout=60000):  # queued: not missed
        press(qtbot, win.cancel_button)
    qtbot.waitUntil(lambda: not win.runner.busy, timeout=60000)
    assert win.result is None and win.last_error is None
    assert win.progress_bar.format() == "cancelled"
    assert win.mesh_button.isEnabled() and not win.cancel_button.isEnabled()
    press(qtbot, win.mesh_button)
    assert win.runner.busy and win.last_error is None, win.last_error
    with qtbot.waitSignal(win.runner.cancelled, timeout=60000):
        keys(qtbot, win, "Escape")
    qtbot.waitUntil(lambda: not win.runner.busy, timeout=60000)
    assert win.result is None and win.progress_bar.format() == "cancelled"


def test_window_starts_with_tessellation_and_examples(main_window, qtbot):
    win = main_window
    assert win.plane.plotter.camera.parallel_projection
    tess = win.disk.layer_actors("tessellation")
    assert len(tess) == 1 and tess[0].GetVisibility()
    assert win.examples_menu.actions(), "Examples menu is empty"
    pick_menu(qtbot, win, win.examples_menu, win.examples_menu.actions()[0])
    assert win.editor.closed and len(win.editor.points) >= 3
    assert win.editor.problem() is None
    assert win.mesh_button.isEnabled()
    assert len(win.plane.layer_actors("polygon")) >= 2
    # VTK's single-key shortcuts are blocked (w = wireframe everything, q = close the view)
    fill = win.plane.layer_actors("polygon")[0]
    for key in ("w", "q", "j"):
        qtbot.keyClick(win.plane.plotter, key)
    assert fill.prop.style == "Surface"
    assert not win.plane.plotter._closed


def test_draw_with_mouse_keys_and_buttons(main_window, qtbot):
    """Draw a square with clicks, close it on the first vertex, drag a vertex, undo/redo with
    the keyboard and the buttons, delete a vertex with the Delete key and the button, clear,
    then draw with snapping and close with a double click."""
    win = main_window
    win.plane.reset_view((-0.5, 2.5, -0.5, 2.5))
    tick(qtbot, win.draw_check)
    assert win.draw_check.isChecked() and win.plane.capture_left
    targets = [0.0, 2.0, 2 + 2j, 2j]
    for z in targets:
        click(qtbot, win.plane, z)
    px = win.plane.pixel_size()
    assert len(win.editor.points) == 4 and not win.editor.closed
    assert np.max(np.abs(win.editor.z - np.array(targets))) < 3 * px
    click(qtbot, win.plane, targets[0])  # click the first vertex: closes
    assert win.editor.closed and len(win.editor.points) == 4
    assert win.warning_label.text() == ""
    assert win.mesh_button.isEnabled()
    # the polygon actors follow the editor
    outline = win.plane.layers["polygon"].geometry.part("outline")
    assert outline.mesh.n_points == 4
    # drag vertex 2 to (1.5, 1.5)
    drag(qtbot, win.plane, win.editor.points[2], 1.5 + 1.5j)
    assert abs(win.editor.points[2] - (1.5 + 1.5j)) < 3 * px
    pts = np.asarray(win.plane.layers["polygon"].geometry.part("vertices").mesh.points)
    assert np.min(np.hypot(pts[:, 0] - 1.5, pts[:, 1] - 1.5)) < 3 * px  # drawn where dragged
    keys(qtbot, win, QKeySequence.StandardKey.Undo)
    assert abs(win.editor.points[2] - (2 + 2j)) < 3 * px
    keys(qtbot, win, QKeySequence.StandardKey.Redo)
    assert abs(win.editor.points[2] - (1.5 + 1.5j)) < 3 * px
    press(qtbot, win.draw_buttons["undo"])
    assert abs(win.editor.points[2] - (2 + 2j)) < 3 * px
    press(qtbot, win.draw_buttons["redo"])
    assert abs(win.editor.points[2] - (1.5 + 1.5j)) < 3 * px
    # select a vertex with a click, delete it with the Delete key, undo
    click(qtbot, win.plane, win.editor.points[1])
    qtbot.keyClick(win.plane.plotter, Qt.Key.Key_Delete)
    assert len(win.editor.points) == 3
    keys(qtbot, win, QKeySequence.StandardKey.Undo)
    assert len(win.editor.points) == 4
    # ... and with the Delete button
    click(qtbot, win.plane, win.editor.points[3])
    press(qtbot, win.draw_buttons["delete"])
    assert len(win.editor.points) == 3 and abs(win.editor.points[-1] - (1.5 + 1.5j)) < 3 * px
    press(qtbot, win.draw_buttons["clear"])
    assert win.editor.points == [] and not win.mesh_button.isEnabled()
    # snapping: grid lines shown, a new drawing closed with a double click
    tick(qtbot, win.snap_check)
    assert win.snap_check.isChecked() and win.editor.snap
    assert win.plane.overlays["grid"]
    for z in (0.02 + 0.01j, 1.97 + 0.03j, 1.02 + 1.49j):
        click(qtbot, win.plane, z)
    click(qtbot, win.plane, 1.02 + 1.49j, double=True)
    assert win.editor.closed
    np.testing.assert_allclose(win.editor.z, [0, 2, 1 + 1.5j], atol=1e-12)
    tick(qtbot, win.snap_check)
    assert not win.plane.overlays.get("grid")
    # leaving draw mode: the left button pans again, clicks add nothing
    tick(qtbot, win.draw_check)
    assert not win.plane.capture_left
    click(qtbot, win.plane, 0.5 + 0.2j)
    assert len(win.editor.points) == 3


def test_bad_drawing_error_then_good_polygon_clears_it(main_window, qtbot):
    """A self-intersecting drawing cannot be meshed (Ctrl+M shows why); loading a good polygon
    clears the error, the failed status and the disk view's picked points."""
    win = main_window
    win.plane.reset_view((-0.5, 2.5, -0.5, 2.5))
    tick(qtbot, win.draw_check)
    for z in (0, 2 + 2j, 2, 2j):  # a bow tie
        click(qtbot, win.plane, z)
    assert "crosses" in win.warning_label.text()
    click(qtbot, win.plane, 0, double=True)
    assert win.editor.closed
    assert win.warning_label.text().startswith("⚠")
    assert not win.mesh_button.isEnabled()
    keys(qtbot, win, "Ctrl+M")
    assert not win.runner.busy
    msg = win.last_error
    assert msg and win.error_box.isVisible() and win.error_box.toPlainText() == msg
    # pick two points in the disk view as well
    click(qtbot, win.disk, 0.1 + 0.1j)
    click(qtbot, win.disk, -0.4 + 0.3j)
    assert len(win.picked) == 2 and "ρ" in win.distance_label.text()
    load_l_shape(win, qtbot)
    assert win.last_error is None and win.error_box.isHidden()
    assert win.error_box.toPlainText() == ""
    assert msg not in win.statusBar().currentMessage()
    assert win.picked == [] and "picked" not in win.disk.overlays
    assert "ρ" not in win.distance_label.text()
    assert win.mesh_button.isEnabled()


def test_mesh_failure_shows_whole_message_then_edit_clears(main_window, qtbot):
    """A mesher failure: progress "failed", the whole (long, multi-line) message readable in
    the Mesh dock without scrolling; editing the polygon clears both."""
    from quadmesh.errors import QuadmeshError

    win = main_window
    load_l_shape(win, qtbot)
    before = win.editor.z.copy()
    lines = [
        f"vertex {i} at ({i / 7:.4f}, {1 - i / 9:.4f}): the conformal map did not converge "
        f"to the requested tolerance after {40 + i} Newton steps"
        for i in range(3)
    ]
    message = "[conformal] " + "\n".join(lines)

    def job(progress, cancel):
        progress("conformal", 0.5)
        raise QuadmeshError(message.removeprefix("[conformal] "), stage="conformal")

    with qtbot.waitSignal(win.runner.idle, timeout=30000):
        assert win.start_mesh(job)  # a failing mesher has no button: inject the job
    assert win.result is None and win.progress_bar.format() == "failed"
    assert win.last_error == message
    box = win.error_box
    assert box.toPlainText() == message
    # all of it visible: no scrolling needed once the layout settled
    qtbot.waitUntil(lambda: box.isVisible() and box.verticalScrollBar().maximum() == 0)
    assert box.height() > 5 * box.fontMetrics().lineSpacing()  # far more than two lines
    np.testing.assert_array_equal(win.editor.z, before)
    assert win.editor.closed and win.mesh_button.isEnabled()
    # moving a vertex (an edit) forgets the failure
    tick(qtbot, win.draw_check)
    drag(qtbot, win.plane, win.editor.points[2], win.editor.points[2] + 0.1)
    assert win.last_error is None and box.isHidden()
    assert win.progress_bar.format() == "idle"


def test_open_invalid_file_then_good_one(main_window, qtbot, tmp_path):
    """File ▸ Open on a broken file shows why; opening a good polygon clears that."""
    win = main_window
    (tmp_path / "broken.json").write_text('{"vertices": [[0, 0], [1, "x"]]}')
    ans = answer_file_dialog(qtbot, str(tmp_path / "broken.json"))
    keys(qtbot, win, QKeySequence.StandardKey.Open)
    ans.check()
    assert win.last_error and "broken.json" in win.last_error
    assert win.error_box.toPlainText() == win.last_error
    (tmp_path / "bow.json").write_text('{"vertices": [[0,0],[2,2],[2,0],[0,2]]}')
    ans = answer_file_dialog(qtbot, str(tmp_path / "bow.json"))
    keys(qtbot, win, QKeySequence.StandardKey.Open)
    ans.check()
    # an invalid polygon is loaded for repair, with the warning; the old error is gone
    assert win.last_error is None and win.error_box.isHidden()
    assert win.editor.closed and win.warning_label.text().startswith("⚠")
    assert not win.mesh_button.isEnabled()


def test_save_polygon_and_open_again(main_window, qtbot, tmp_path):
    win = main_window
    load_l_shape(win, qtbot)
    z = win.editor.z.copy()
    ans = answer_file_dialog(qtbot, str(tmp_path / "poly"))  # no suffix typed
    keys(qtbot, win, QKeySequence.StandardKey.Save)
    ans.check()
    assert (tmp_path / "poly.json").is_file()
    assert "saved" in win.statusBar().currentMessage()
    press(qtbot, win.draw_buttons["clear"])
    assert not win.editor.points
    seen: list[str] = []
    ans = answer_file_dialog(qtbot, "poly.json", record=seen)  # the remembered folder
    keys(qtbot, win, QKeySequence.StandardKey.Open)
    ans.check()
    assert seen == [str(tmp_path)]
    np.testing.assert_allclose(win.editor.z, z, atol=1e-12)


def test_layer_checkboxes_colours_and_opacity(meshed, qtbot):
    """Clicking each layer's checkbox hides/shows its actors (and colour bars) and renders
    the view; the colour button's dialog, the opacity slider and the colour mode reach the
    actors."""
    from PySide6.QtGui import QColor
    from PySide6.QtWidgets import QColorDialog

    win = meshed
    renders = {"plane": 0, "disk": 0}
    for name, v in (("plane", win.plane), ("disk", win.disk)):
        v.plotter.render_signal.connect(lambda n=name: renders.__setitem__(n, renders[n] + 1))
    checked = 0
    for name, cb in win.layer_panel.checkboxes.items():
        view = win.plane if name in win.plane.layers and name not in win.disk.layers else win.disk
        vname = "plane" if view is win.plane else "disk"
        actors = view.layer_actors(name)
        if name == "polygon":  # its fill stays hidden while the final mesh is shown
            st = view.layers[name]
            parts = [p for p in st.geometry.parts if p.mesh.n_points > 0]
            actors = [a for p, a in zip(parts, actors, strict=True) if p.label != "fill"]
        if not cb.isChecked():
            tick(qtbot, cb)
        assert cb.isChecked()
        if not actors:
            continue
        assert all(a.GetVisibility() for a in actors), name
        n0 = renders[vname]
        tick(qtbot, cb)
        assert not cb.isChecked()
        assert renders[vname] > n0, f"hiding {name} did not redraw the {vname} view"
        assert not any(a.GetVisibility() for a in actors), name
        st = view.layers[name]
        for title in st.geometry.scalar_bar_titles:
            assert not view.plotter.scalar_bars[title].GetVisibility(), title
        tick(qtbot, cb)
        assert all(a.GetVisibility() for a in actors), name
        checked += 1
    assert checked >= 5
    # colour button → colour dialog → the polygon outline takes the colour
    btn = win.layer_panel.color_buttons["polygon"]

    def pick_green(dlg) -> None:
        dlg.setCurrentColor(QColor("#00aa00"))
        dlg.accept()

    ans = DialogAnswer(QColorDialog, pick_green)
    press(qtbot, btn)
    ans.check()
    outline = win.plane.layer_actors("polygon")[1]
    np.testing.assert_allclose(outline.prop.color.float_rgb, (0, 170 / 255, 0), atol=1e-3)
    # opacity slider (keyboard on the slider)
    sl = win.layer_panel.sliders["final_mesh"]
    sl.setFocus()
    qtbot.keyClick(sl, Qt.Key.Key_Home)
    assert sl.value() == sl.minimum()
    for a in win.plane.layer_actors("final_mesh"):
        assert a.prop.opacity == pytest.approx(sl.minimum() / 100.0)
    qtbot.keyClick(sl, Qt.Key.Key_End)
    # colour mode combo: worst deviation from 90°
    combo = win.layer_panel.color_mode
    combo.setFocus()
    qtbot.keyClick(combo, Qt.Key.Key_Down)
    assert combo.currentData() == "worst"
    part = win.plane.layers["final_mesh"].geometry.part("quads")
    assert part.scalars == "worst_deviation"
    dev = np.asarray(part.mesh.cell_data["worst_deviation"])
    assert dev.shape == (win.result.quality.n_quads,) and 0 <= dev.max() <= 30 + ANGLE_TOL_DEG


def test_export_every_format_with_suffix_and_folder(meshed, qtbot, tmp_path):
    """Ctrl+E: a name typed without suffix gets the chosen filter's; the file reads back as
    the mesh on screen; the status bar says so; the dialog reopens in the last folder."""
    from quadmesh.io import read_mesh

    win = meshed
    out = tmp_path / "out"
    out.mkdir()
    mesh = win.result.mesh
    first = True
    for ext, filt in (
        ("json", "JSON (*.json)"),
        ("vtk", "VTK (*.vtk)"),
        ("vtu", "VTK XML (*.vtu)"),
        ("msh", "Gmsh 2.2 (*.msh)"),
        ("obj", "Wavefront (*.obj)"),
    ):
        seen: list[str] = []
        name = str(out / f"mesh_{ext}") if first else f"mesh_{ext}"
        ans = answer_file_dialog(qtbot, name, filt, record=seen)
        keys(qtbot, win, "Ctrl+E")
        ans.check()
        if not first:
            assert seen == [str(out)], "the export dialog forgot the last folder"
        first = False
        p = out / f"mesh_{ext}.{ext}"
        assert p.is_file(), f"{p} not written"
        assert f"{mesh.n_quads} quads" in win.statusBar().currentMessage()
        assert str(p) in win.statusBar().currentMessage()
        back = read_mesh(p)
        assert back.quads.shape == mesh.quads.shape, ext
        np.testing.assert_allclose(back.vertices, mesh.vertices, atol=1e-9)
    assert win.settings.value("last_folder") == str(out)
    # a name with its own suffix keeps it
    ans = answer_file_dialog(qtbot, "kept.obj", "VTK (*.vtk)")
    keys(qtbot, win, "Ctrl+E")
    ans.check()
    assert (out / "kept.obj").is_file() and not (out / "kept.obj.vtk").exists()
    # File ▸ Save window screenshot (Ctrl+P): the PNG suffix is added
    ans = answer_file_dialog(qtbot, "window", "PNG (*.png)")
    keys(qtbot, win, "Ctrl+P")
    ans.check()
    png = out / "window.png"
    assert png.is_file() and pixel_variance(png) > 100.0
    assert str(png) in win.statusBar().currentMessage()


@pytest.mark.parametrize("ext", ["json", "vtk", "vtu", "msh", "obj"])
def test_open_mesh_file_shows_a_mesh(main_window, qtbot, tmp_path, ext):
    """File ▸ Open on a mesh file shows the mesh (final-mesh layer, angle statistics), not a
    polygon of its vertices; drawing a polygon afterwards removes it."""
    from quadmesh.io import write_mesh
    from tests.helpers import lshape_mesh

    win = main_window
    mesh = lshape_mesh()
    p = tmp_path / f"m.{ext}"
    write_mesh(p, mesh)
    ans = answer_file_dialog(qtbot, str(p))
    keys(qtbot, win, QKeySequence.StandardKey.Open)
    ans.check()
    assert win.last_error is None, win.last_error
    assert win.editor.points == [], "the mesh was loaded as a polygon"
    shown = win.loaded_mesh
    assert shown is not None and shown.n_quads == mesh.n_quads
    np.testing.assert_allclose(shown.vertices, mesh.vertices, atol=1e-9)
    quads = win.plane.layers["final_mesh"].geometry.part("quads")
    assert quads.n_cells == mesh.n_quads
    assert all(a.GetVisibility() for a in win.plane.layer_actors("final_mesh"))
    q = mesh.quality()
    assert f"{q.n_quads}" in win.info_label.text() and "m." + ext in win.info_label.text()
    assert win.histogram.counts.sum() == np.asarray(q.histogram).sum()
    assert not win.mesh_button.isEnabled()
    # the camera shows the mesh
    z_left = win.plane.to_world(0, win.plane.plotter.height() / 2)
    z_right = win.plane.to_world(win.plane.plotter.width(), win.plane.plotter.height() / 2)
    assert z_left.real <= mesh.vertices[:, 0].min() and z_right.real >= mesh.vertices[:, 0].max()
    # a loaded mesh can be exported again
    ans = answer_file_dialog(qtbot, "again", "JSON (*.json)")
    keys(qtbot, win, "Ctrl+E")
    ans.check()
    assert (tmp_path / "again.json").is_file()
    # drawing replaces it
    load_l_shape(win, qtbot)
    assert win.loaded_mesh is None and not win.plane.layer_actors("final_mesh")


def test_views_render_only_on_change(main_window, qtbot):
    """Idle: no redraws at all (no auto-update timer); a change redraws its view."""
    win = main_window
    renders = {"plane": 0, "disk": 0}
    for name, v in (("plane", win.plane), ("disk", win.disk)):
        assert not v.plotter.render_timer.isActive()
        v.plotter.render_signal.connect(lambda n=name: renders.__setitem__(n, renders[n] + 1))
    qtbot.wait(1200)  # an auto-update timer would have fired at least once
    assert renders == {"plane": 0, "disk": 0}
    load_l_shape(win, qtbot)
    assert renders["plane"] >= 1
    n0 = renders["disk"]
    press(qtbot, win.reset_disk_btn)
    assert renders["disk"] > n0
    n = dict(renders)
    qtbot.wait(1100)
    assert renders == n


def test_no_render_while_idle_or_hovering_with_a_mesh(meshed, qtbot):
    """With a mesh on screen every render of either view is counted at the renderer (whatever
    starts it): an untick redraws the plane view only (a quick frame, then the full-detail
    one); then 1.2 s idle and the mouse moving over both views (the cursor readout follows
    it) draw nothing."""
    win = meshed
    counts = {"plane": 0, "disk": 0}
    for name, v in (("plane", win.plane), ("disk", win.disk)):
        v.plotter.renderer.AddObserver(
            "StartEvent", lambda *_, n=name: counts.__setitem__(n, counts[n] + 1)
        )
    qtbot.wait(300)
    counts.update(plane=0, disk=0)
    tick(qtbot, win.layer_panel.checkboxes["crosscuts"])
    assert counts["plane"] >= 1 and counts["disk"] == 0
    # the quick frame of the toggle, then one full-detail frame once the toggling stopped
    qtbot.waitUntil(lambda: not win.plane.interacting, timeout=3000)
    assert counts["disk"] == 0
    qtbot.wait(300)  # a frame the toggle queued (under load it can come late) is not idle
    counts.update(plane=0, disk=0)
    qtbot.wait(1200)
    for view in (win.plane, win.disk):
        w, h = view.plotter.width(), view.plotter.height()
        for k in range(5):
            qtbot.mouseMove(view.plotter, QPoint(w // 3 + 20 * k, h // 2 + 10 * k))
            qtbot.wait(20)
    assert win.coord_label.text(), "no cursor readout"
    assert counts == {"plane": 0, "disk": 0}, counts


def test_worker_runs_disk_construction_and_cancels(main_window, qtbot):
    from app.worker import JobRunner
    from quadmesh.disk.region import RegionW, build_region

    runner = JobRunner(main_window)
    stages = []
    runner.progress.connect(lambda s, f: stages.append((s, f)))
    intervals = np.array([[0.3, 0.02], [2.0, 0.05], [4.0, 0.01]])

    def job(progress, cancel):
        progress("region W", 0.0)
        r = build_region(intervals, 16.0)
        progress("region W", 1.0)
        return r

    got = []
    runner.finished.connect(lambda r, t: got.append(r))
    with qtbot.waitSignal(runner.idle, timeout=30000):
        runner.start(job)
    assert isinstance(got[0], RegionW)
    assert got[0].n_pentagons > 0 and len(got[0].quads) > 0
    assert stages == [("region W", 0.0), ("region W", 1.0)]

    # cancellation: the job polls cancel() like mesh_polygon does between stages
    from quadmesh.errors import Cancelled

    def slow(progress, cancel):
        for _ in range(2000):
            if cancel():
                raise Cancelled("stopped", stage="test")
            time.sleep(0.005)
        return None

    cancelled = []
    runner.cancelled.connect(lambda: cancelled.append(True))
    with qtbot.waitSignal(runner.idle, timeout=30000):
        runner.start(slow)
        runner.cancel()
    assert cancelled == [True]


def test_disk_teaching_drag_pick_and_reset(main_window, qtbot):
    from quadmesh.hyperbolic.geodesic import distance

    win = main_window
    part = win.disk.layers["tessellation"].geometry.parts[0]
    before = np.asarray(part.mesh.points)[:, :2].copy()
    drag(qtbot, win.disk, 0.4 + 0.2j, 0.0)
    assert win.disk.transform is not None
    g = win.disk.transform
    assert abs(g(0.4 + 0.2j)) < 5 * win.disk.pixel_size() + 1e-9
    after = win.disk.layers["tessellation"].geometry.parts[0]
    pts = np.asarray(after.mesh.points)[:, :2]
    np.testing.assert_allclose(pts[:, 0] + 1j * pts[:, 1], g(after.disk_z), atol=1e-6)
    assert before.shape != pts.shape or not np.allclose(before, pts)
    press(qtbot, win.reset_disk_btn)
    assert win.disk.transform is None and win.picked == []
    a, b = 0.1 + 0.1j, -0.5 + 0.3j
    click(qtbot, win.disk, a)
    click(qtbot, win.disk, b)
    assert len(win.picked) == 2
    px = win.disk.pixel_size()
    assert abs(win.picked[0] - a) < 3 * px and abs(win.picked[1] - b) < 3 * px
    d = float(distance(win.picked[0], win.picked[1]))
    assert f"{d:.6f}" in win.distance_label.text()
    assert abs(d - float(distance(a, b))) < 0.05
    assert len(win.disk.overlays["picked"]) == 2  # geodesic + points


def test_piece_spin_and_centre_button_on_result(meshed, qtbot):
    """The disk view shows the chosen thick piece's disk mesh and follows a drag; the
    Centre 0 button undoes the automorphism."""
    win = meshed
    n = len(win.result.pieces)
    assert n >= 1 and win.piece_spin.maximum() == n - 1
    disk_mesh = win.disk.layers["disk_mesh"].geometry
    assert disk_mesh is not None and disk_mesh.parts
    pts0 = np.asarray(disk_mesh.parts[0].mesh.points)[:, :2].copy()
    assert np.all(np.hypot(pts0[:, 0], pts0[:, 1]) <= 1.0 + 1e-9)  # inside the unit disk
    drag(qtbot, win.disk, 0.3 + 0.1j, 0.0)
    assert win.disk.transform is not None
    moved = np.asarray(win.disk.layers["disk_mesh"].geometry.parts[0].mesh.points)[:, :2]
    assert not np.allclose(moved, pts0)
    press(qtbot, win.reset_disk_btn)
    assert win.disk.transform is None
    back = np.asarray(win.disk.layers["disk_mesh"].geometry.parts[0].mesh.points)[:, :2]
    np.testing.assert_allclose(back, pts0, atol=1e-9)


def test_scripted_run_writes_screenshot(main_window, tmp_path):
    from app.main import run

    poly = tmp_path / "l.json"
    poly.write_text('{"vertices": [[0,0],[2,0],[2,1],[1,1],[1,2],[0,2]]}')
    png = tmp_path / "shot.png"
    assert (
        run(
            [
                "--open",
                str(poly),
                "--layers",
                "polygon,tessellation",
                "--screenshot",
                str(png),
                "--quit",
            ]
        )
        == 0
    )
    assert pixel_variance(png) > 100.0
    # a mesh file opens as a mesh in the scripted run too
    from quadmesh.io import write_mesh
    from tests.helpers import lshape_mesh

    write_mesh(tmp_path / "m.json", lshape_mesh())
    png2 = tmp_path / "mesh.png"
    assert run(["--open", str(tmp_path / "m.json"), "--screenshot", str(png2), "--quit"]) == 0
    assert pixel_variance(png2) > 100.0
    assert run(["--open", str(tmp_path / "missing.json"), "--quit"]) == 1
    assert run(["--open", str(poly), "--layers", "nonsense", "--quit"]) == 1


def test_option_controls_reach_mesh_options(main_window, qtbot):
    """The parameter controls, used with mouse and keyboard, reach MeshOptions."""
    win = main_window
    opts = win.mesh_options()
    assert opts.repair is True and opts.adaptive is True
    assert opts.rotations == MeshOptions().rotations
    tick(qtbot, win.repair_check)
    tick(qtbot, win.adaptive_check)
    for name, text in (("rotations", "1"), ("lemma_A", "16")):
        w = win.option_widgets[name]
        w.setFocus()
        w.selectAll()
        qtbot.keyClicks(w, text)
        qtbot.keyClick(w, Qt.Key.Key_Tab)
    tol = win.tol_edit
    tol.setFocus()
    tol.selectAll()
    qtbot.keyClicks(tol, "1e-8")
    opts = win.mesh_options()
    assert opts.repair is False and opts.adaptive is False
    assert opts.rotations == 1 and opts.lemma_A == 16.0 and opts.conformal_tol == 1e-8


def wheel(view, x: float, y: float, notches: int) -> None:
    """Turn the mouse wheel ``notches`` notches (120 units each; negative: towards the user)
    over ``view`` at widget pixel (x, y): a real QWheelEvent sent to the view's widget."""
    from PySide6.QtCore import QPointF
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtWidgets import QApplication

    pos = QPointF(x, y)
    ev = QWheelEvent(
        pos,
        view.plotter.mapToGlobal(pos),
        QPoint(0, 0),
        QPoint(0, 120 * notches),
        Qt.MouseButton.NoButton,
        Qt.KeyboardModifier.NoModifier,
        Qt.ScrollPhase.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(view.plotter, ev)


def test_view_and_grid_controls_and_quit_by_mouse_and_keys(main_window, qtbot):
    """The controls no other test reaches: R (View ▸ Reset plane view) undoes a wheel zoom; a
    double click in the disk view moves that point to the centre and View ▸ Reset disk view
    (clicked in the menu) undoes it; the grid size typed into the Draw panel is where a
    snapped click lands; Ctrl+Q closes the window and releases both views."""
    from quadmesh.hyperbolic.isometry import disk_automorphism

    win = main_window
    load_l_shape(win, qtbot)
    view = win.plane
    cam = view.plotter.camera
    fitted = (cam.parallel_scale, tuple(cam.focal_point))
    wheel(view, 0.3 * view.plotter.width(), 0.6 * view.plotter.height(), 3)
    assert cam.parallel_scale < 0.6 * fitted[0]
    view.plotter.setFocus()
    keys(qtbot, win, "R")
    assert cam.parallel_scale == pytest.approx(fitted[0], rel=1e-9)
    np.testing.assert_allclose(cam.focal_point, fitted[1], atol=1e-9 * fitted[0])

    a = 0.35 + 0.2j
    click(qtbot, win.disk, a, double=True)
    g = win.disk.transform
    assert g is not None and abs(complex(g(a))) < 0.02  # a is now (about) the centre
    want = disk_automorphism(complex(g.inverse()(0j)))
    assert abs(complex(want(0.1j)) - complex(g(0.1j))) < 1e-9
    view_menu = next(
        m for m in win.menuBar().findChildren(type(win.help_menu)) if m.title() == "&View"
    )
    pick_menu(qtbot, win, view_menu, "Reset disk view")
    assert win.disk.transform is None

    # draw with snapping on a typed grid size: the click lands on the grid
    tick(qtbot, win.draw_check)
    press(qtbot, win.draw_buttons["clear"])  # a loaded example: no question
    assert win.editor.points == []
    tick(qtbot, win.snap_check)
    win.grid_spin.selectAll()
    qtbot.keyClicks(win.grid_spin, "0.5")
    qtbot.keyClick(win.grid_spin, Qt.Key.Key_Return)
    assert win.editor.grid == 0.5
    click(qtbot, win.plane, 1.2 + 0.7j)
    assert win.editor.points == [1.0 + 0.5j]

    keys(qtbot, win, QKeySequence.StandardKey.Quit)
    qtbot.waitUntil(lambda: not win.isVisible(), timeout=5000)
    assert win.plane._closed and win.disk._closed
