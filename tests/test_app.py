"""GUI tests of quadmesh-app (pytest-qt; run under ``xvfb-run``, skipped without a display)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from PySide6.QtCore import QTimer

from quadmesh import MeshOptions
from tests.helpers import L_SHAPE, require_pipeline

pytestmark = pytest.mark.gui


def _send(widget, etype, pos, button, buttons):
    from PySide6.QtCore import QPointF
    from PySide6.QtGui import QMouseEvent
    from PySide6.QtWidgets import QApplication

    p = QPointF(*pos)
    ev = QMouseEvent(etype, p, widget.mapToGlobal(p), button, buttons, _no_mod())
    QApplication.sendEvent(widget, ev)


def _no_mod():
    from PySide6.QtCore import Qt

    return Qt.KeyboardModifier.NoModifier


def click(view, z: complex, *, double: bool = False) -> None:
    """Left click (or the second half of a double click) at world point z."""
    from PySide6.QtCore import QEvent, Qt

    pos = view.to_widget(z)
    w = view.plotter
    kind = QEvent.MouseButtonDblClick if double else QEvent.MouseButtonPress
    _send(w, kind, pos, Qt.LeftButton, Qt.LeftButton)
    _send(w, QEvent.MouseButtonRelease, pos, Qt.LeftButton, Qt.NoButton)


def drag(view, a: complex, b: complex, steps: int = 4) -> None:
    """Press at a, move to b with the left button held, release."""
    from PySide6.QtCore import QEvent, Qt

    w = view.plotter
    _send(w, QEvent.MouseButtonPress, view.to_widget(a), Qt.LeftButton, Qt.LeftButton)
    for t in np.linspace(0, 1, steps + 1)[1:]:
        _send(w, QEvent.MouseMove, view.to_widget(a + t * (b - a)), Qt.NoButton, Qt.LeftButton)
    _send(w, QEvent.MouseButtonRelease, view.to_widget(b), Qt.LeftButton, Qt.NoButton)


def pixel_variance(path) -> float:
    from PySide6.QtGui import QImage

    img = QImage(str(path)).convertToFormat(QImage.Format_RGB888)
    assert not img.isNull(), f"cannot read {path}"
    buf = np.frombuffer(img.constBits(), dtype=np.uint8)
    arr = buf[: img.height() * img.bytesPerLine()].reshape(img.height(), img.bytesPerLine())
    return float(arr[:, : 3 * img.width()].astype(float).var())


_MESHED: dict[str, object] = {}


@pytest.fixture
def meshed(main_window, qtbot):
    """The window after meshing the L-shape through the worker thread (the first time; later
    tests show the same MeshResult again to keep the GUI suite fast)."""
    require_pipeline()
    win = main_window
    win.set_polygon(L_SHAPE)
    if "result" in _MESHED:
        win.set_result(_MESHED["result"])
        return win
    win.option_widgets["depth_step"].setValue(1.0)  # coarser Carleson rows: a faster test
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(20)
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        assert win.start_mesh()
        assert win.cancel_button.isEnabled() and not win.mesh_button.isEnabled()
    timer.stop()
    assert win.last_error is None, win.last_error
    assert win.result is not None
    assert win.result.options.depth_step == 1.0  # the parameter controls reach the mesher
    assert len(ticks) >= 3, "the GUI event loop did not run while the mesher worked"
    _MESHED["result"] = win.result
    return win


# ------------------------------------------------------------------------------------ tests
def test_window_starts_with_tessellation_and_examples(main_window, qtbot, tmp_path):
    win = main_window
    assert win.plane.plotter.camera.parallel_projection
    tess = win.disk.layer_actors("tessellation")
    assert len(tess) == 1 and tess[0].GetVisibility()
    assert win.examples_menu.actions(), "Examples menu is empty"
    try:
        from quadmesh.examples import example_names
    except ImportError as exc:
        pytest.skip(f"quadmesh.examples missing: {exc}")
    name = example_names()[0]
    win.load_example(name)
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
    # save and open again: the same polygon
    z = win.editor.z.copy()
    win.save_polygon(tmp_path / "poly.json")
    win.clear_polygon()
    win.open_polygon(tmp_path / "poly.json")
    np.testing.assert_allclose(win.editor.z, z, atol=1e-12)
    # an invalid file polygon is loaded for repair, with the warning
    (tmp_path / "bow.json").write_text('{"vertices": [[0,0],[2,2],[2,0],[0,2]]}')
    win.open_polygon(tmp_path / "bow.json")
    assert win.editor.closed and win.warning_label.text().startswith("⚠")
    assert not win.mesh_button.isEnabled()


def test_clicks_draw_close_move_undo(main_window, qtbot):
    win = main_window
    win.plane.reset_view((-0.5, 2.5, -0.5, 2.5))
    win.set_draw_mode(True)
    targets = [0.0, 2.0, 2 + 2j, 2j]
    for z in targets:
        click(win.plane, z)
    px = win.plane.pixel_size()
    assert len(win.editor.points) == 4 and not win.editor.closed
    assert np.max(np.abs(win.editor.z - np.array(targets))) < 3 * px
    click(win.plane, targets[0])  # click the first vertex: closes
    assert win.editor.closed and len(win.editor.points) == 4
    assert win.warning_label.text() == ""
    assert win.mesh_button.isEnabled()
    # drag vertex 2 to (1.5, 1.5)
    drag(win.plane, win.editor.points[2], 1.5 + 1.5j)
    assert abs(win.editor.points[2] - (1.5 + 1.5j)) < 3 * px
    win.undo()
    assert abs(win.editor.points[2] - (2 + 2j)) < 3 * px
    win.redo()
    assert abs(win.editor.points[2] - (1.5 + 1.5j)) < 3 * px
    # select and delete a vertex, then undo it
    click(win.plane, win.editor.points[1])
    win.delete_selected()
    assert len(win.editor.points) == 3
    win.undo()
    assert len(win.editor.points) == 4
    # snapping: a new drawing with double-click closing
    win.clear_polygon()
    win.snap_check.setChecked(True)
    assert win.plane.overlays["grid"]  # grid lines shown while snapping
    for z in (0.02 + 0.01j, 1.97 + 0.03j, 1.02 + 1.49j):
        click(win.plane, z)
    click(win.plane, 1.02 + 1.49j, double=True)
    assert win.editor.closed
    np.testing.assert_allclose(win.editor.z, [0, 2, 1 + 1.5j], atol=1e-12)


def test_self_intersection_warns_and_blocks_meshing(main_window):
    win = main_window
    win.plane.reset_view((-0.5, 2.5, -0.5, 2.5))
    win.set_draw_mode(True)
    for z in (0, 2 + 2j, 2, 2j):  # a bow tie
        click(win.plane, z)
    assert "crosses" in win.warning_label.text()
    click(win.plane, 0, double=True)
    assert win.editor.closed
    assert win.warning_label.text().startswith("⚠")
    assert not win.mesh_button.isEnabled()
    assert win.start_mesh() is False and win.last_error
    win.undo()  # reopen, the app keeps running
    assert not win.editor.closed


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


def test_mesh_through_worker_layers_toggle(meshed):
    win = meshed
    q = win.result.quality
    assert q.n_quads == win.result.mesh.quads.shape[0] > 0
    assert "quads" in win.info_label.text()
    # the L-shape's few sub-60° pentagon images are repaired locally (n stays 2)
    assert "repaired locally" in win.info_label.text()
    assert win.histogram.counts.sum() == np.asarray(q.histogram).sum()
    for name, cb in win.layer_panel.checkboxes.items():
        view = win.plane if name in win.plane.layers and name not in win.disk.layers else win.disk
        actors = view.layer_actors(name)
        if not actors:
            continue
        cb.setChecked(True)
        assert all(a.GetVisibility() for a in actors), name
        cb.setChecked(False)
        assert not any(a.GetVisibility() for a in actors), name
        st = view.layers[name]
        for title in st.geometry.scalar_bar_titles:
            assert not view.plotter.scalar_bars[title].GetVisibility(), title
        cb.setChecked(True)
    fm = win.plane.layers["final_mesh"].geometry
    assert fm.part("quads").n_cells == q.n_quads
    assert fm.part("quads").clim == pytest.approx((q.min_angle, q.max_angle))


def test_export_and_screenshot(meshed, tmp_path):
    from quadmesh.io import read_mesh

    win = meshed
    for ext in ("json", "vtk", "msh", "obj"):
        p = tmp_path / f"mesh.{ext}"
        win.export_mesh(p)
        back = read_mesh(p)
        assert back.quads.shape == win.result.mesh.quads.shape, ext
        np.testing.assert_allclose(back.vertices, win.result.mesh.vertices, atol=1e-9)
    png = tmp_path / "window.png"
    win.save_screenshot(png)
    assert pixel_variance(png) > 100.0


def test_disk_teaching_drag_and_distance(main_window):
    from quadmesh.hyperbolic.geodesic import distance

    win = main_window
    part = win.disk.layers["tessellation"].geometry.parts[0]
    before = np.asarray(part.mesh.points)[:, :2].copy()
    drag(win.disk, 0.4 + 0.2j, 0.0)
    assert win.disk.transform is not None
    g = win.disk.transform
    assert abs(g(0.4 + 0.2j)) < 5 * win.disk.pixel_size() + 1e-9
    after = win.disk.layers["tessellation"].geometry.parts[0]
    pts = np.asarray(after.mesh.points)[:, :2]
    np.testing.assert_allclose(pts[:, 0] + 1j * pts[:, 1], g(after.disk_z), atol=1e-6)
    assert before.shape != pts.shape or not np.allclose(before, pts)
    win.reset_disk_transform()
    win.pick_disk_point(0.1 + 0.1j)
    win.pick_disk_point(-0.5 + 0.3j)
    d = float(distance(0.1 + 0.1j, -0.5 + 0.3j))
    assert f"{d:.6f}" in win.distance_label.text()
    assert len(win.disk.overlays["picked"]) == 2  # geodesic + points


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
    assert run(["--open", str(tmp_path / "missing.json"), "--quit"]) == 1
    assert run(["--open", str(poly), "--layers", "nonsense", "--quit"]) == 1


def test_mesh_error_is_shown_and_polygon_kept(main_window, qtbot):
    from quadmesh.disk.region import build_region

    win = main_window
    win.set_polygon(L_SHAPE)
    before = win.editor.z.copy()

    def job(progress, cancel):
        progress("disk", 0.5)
        return build_region(np.array([[0.3, 0.5], [0.9, 0.5]]), 16.0)  # violates Lemma 2.2

    with qtbot.waitSignal(win.runner.idle, timeout=30000):
        assert win.start_mesh(job)
    assert win.result is None
    assert "Lemma 2.2" in win.error_label.text() and win.last_error.startswith("[disk]")
    np.testing.assert_array_equal(win.editor.z, before)
    assert win.editor.closed and win.mesh_button.isEnabled()


def test_cancel_real_mesher(main_window, qtbot):
    require_pipeline()
    win = main_window
    win.set_polygon(L_SHAPE)
    with qtbot.waitSignal(win.runner.cancelled, timeout=60000):
        assert win.start_mesh()
        win.cancel_mesh()
    qtbot.waitUntil(lambda: not win.runner.busy, timeout=60000)
    assert win.result is None and win.last_error is None
    assert win.progress_bar.format() == "cancelled"
    assert win.mesh_button.isEnabled()


def test_option_controls_reach_mesh_options(main_window):
    """Every MeshOptions knob shown in the panel reaches the mesher, the new ones included."""
    win = main_window
    opts = win.mesh_options()
    assert opts.repair is True and opts.rotations == MeshOptions().rotations
    win.repair_check.setChecked(False)
    win.option_widgets["rotations"].setValue(1)
    win.option_widgets["lemma_A"].setValue(16.0)
    opts = win.mesh_options()
    assert opts.repair is False and opts.rotations == 1 and opts.lemma_A == 16.0
