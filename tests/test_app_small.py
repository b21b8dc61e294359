"""The app at 1024×700 (a small laptop screen): docks scroll instead of cutting controls off
(run under ``xvfb-run``)."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QRectF
from PySide6.QtWidgets import QDockWidget, QWidget

from tests.helpers import L_SHAPE

pytestmark = pytest.mark.gui


def _reachable(win, scroll, w: QWidget) -> bool:
    """Scroll ``scroll`` to ``w``; then ``w`` must be shown, inside the dock's viewport and
    inside the window."""
    # scroll the whole widget into view (ensureWidgetVisible would only bring a line edit's
    # text cursor into view)
    c = w.mapTo(scroll.widget(), w.rect().center())
    scroll.ensureVisible(c.x(), c.y(), w.width() // 2 + 1, w.height() // 2 + 1)
    if not w.isVisibleTo(win) or w.visibleRegion().isEmpty():
        return False
    top_left = w.mapTo(win, w.rect().topLeft())
    bottom_right = w.mapTo(win, w.rect().bottomRight())
    vp = scroll.viewport()
    vp_tl = vp.mapTo(win, vp.rect().topLeft())
    vp_br = vp.mapTo(win, vp.rect().bottomRight())
    return (
        win.rect().contains(top_left)
        and win.rect().contains(bottom_right)
        and vp_tl.y() <= top_left.y()
        and bottom_right.y() <= vp_br.y()
    )


def test_every_mesh_control_reachable_at_1024x700(main_window, qtbot):
    win = main_window
    win.resize(1024, 700)
    qtbot.waitUntil(lambda: win.width() == 1024 and win.height() == 700, timeout=3000)
    qtbot.wait(50)
    controls = [
        win.method_combo,
        *win.option_widgets.values(),
        win.mesh_button,
        win.cancel_button,
        win.progress_bar,
    ]
    # the Mesh panel's contents are taller than its share of 700 px: it scrolls
    assert win.mesh_scroll.verticalScrollBar().maximum() > 0
    for c in controls:
        assert _reachable(win, win.mesh_scroll, c), f"{c.objectName() or c} not reachable"
        label = win.mesh_scroll.widget().layout().labelForField(c)
        if label is not None:
            assert _reachable(win, win.mesh_scroll, label)
    # the Mesh button is usable after scrolling to it
    win.set_polygon(L_SHAPE)
    assert win.mesh_button.isEnabled()
    # every layer checkbox and the draw controls too
    for cb in win.layer_panel.checkboxes.values():
        assert _reachable(win, win.layer_scroll, cb), cb.text()
    assert _reachable(win, win.layer_scroll, win.layer_panel.color_mode)
    for b in (win.draw_check, win.snap_check, *win.draw_buttons.values()):
        assert _reachable(win, win.draw_scroll, b), b.text()
    assert _reachable(win, win.info_scroll, win.histogram)
    # no dock wider than the window; the two views keep a usable size
    docks = win.findChildren(QDockWidget)
    assert len(docks) == 4
    for d in docks:
        assert d.isVisible() and d.width() < win.width() // 3, (d.windowTitle(), d.width())
    for view in (win.plane, win.disk):
        assert view.plotter.width() >= 180 and view.plotter.height() >= 300
    # nothing squeezed sideways: a control is as wide as it asks to be at least
    for c in controls:
        assert c.width() >= c.minimumSizeHint().width()


def _fill_actor(win):
    st = win.plane.layers["polygon"]
    parts = [p for p in st.geometry.parts if p.mesh.n_points > 0]
    return next(a for p, a in zip(parts, st.actors, strict=True) if p.label == "fill")


def test_fill_never_covers_the_mesh_and_histogram_labels_every_bin(main_window, qtbot):
    """The polygon's fill is hidden while the final mesh is on screen (it would wash out the
    angle colours) and back when the mesh layer is off; the histogram, at 1024×700, is in view
    without scrolling and labels every non-empty bin with its count, all inside the widget."""
    from tests.test_app import mesh_l_shape, tick

    win = main_window
    win.resize(1024, 700)
    qtbot.waitUntil(lambda: win.height() == 700, timeout=3000)
    win.set_polygon(L_SHAPE)
    assert _fill_actor(win).GetVisibility()  # a polygon alone: filled
    win.mesh_scroll.ensureWidgetVisible(win.mesh_button)  # the user scrolls to Mesh
    mesh_l_shape(win, qtbot)
    assert win.plane.layers["final_mesh"].visible
    assert not _fill_actor(win).GetVisibility()
    cb = win.layer_panel.checkboxes["final_mesh"]
    win.layer_scroll.ensureWidgetVisible(cb)
    tick(qtbot, cb)
    assert not win.plane.layers["final_mesh"].visible and _fill_actor(win).GetVisibility()
    tick(qtbot, cb)
    assert not _fill_actor(win).GetVisibility()
    # histogram: visible without scrolling, one count label per non-empty bin
    h = win.histogram
    assert win.info_scroll.verticalScrollBar().value() == 0
    top = h.mapTo(win.info_scroll.viewport(), h.rect().topLeft())
    assert top.y() >= 0 and top.y() + h.height() <= win.info_scroll.viewport().height()
    counts = win.result.quality.histogram
    nonzero = np.flatnonzero(counts)
    assert nonzero.size >= 3 and np.array_equal(h.counts, counts)
    labels = h.labels()
    count_texts = [t for t, _ in labels if not t.endswith("°")]
    assert count_texts == [str(int(counts[k])) for k in nonzero]
    assert {t for t, _ in labels if t.endswith("°")} == {"0°", "60°", "90°", "120°", "180°"}
    box = QRectF(h.rect())
    for text, r in labels:
        assert box.contains(r), f"label {text!r} at {r} is cut off ({h.width()}×{h.height()})"
    bars = dict(h.bars())
    for (_text, r), k in zip(
        [lb for lb in labels if not lb[0].endswith("°")], nonzero, strict=True
    ):
        assert r.bottom() <= bars[k].top() + 1e-9  # above its own bar
        assert abs(r.center().x() - bars[k].center().x()) < 1e-6
