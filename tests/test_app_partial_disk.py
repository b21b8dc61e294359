"""GUI tests: after a failed run the disk view shows the failing thick piece's disk — its
prevertices on the unit circle, its arcs I_j and its disk mesh — the piece spin box steps
through the pieces the run computed, and an edit or a new run clears them. Driven by clicks
on the real Mesh button and checkboxes; run under ``xvfb-run``."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt

from tests.helpers import LSHAPE, require_pipeline
from tests.test_app import press, tick

pytestmark = pytest.mark.gui


def _fail_strictly(win, qtbot, polygon: np.ndarray) -> None:
    """Untick local repair and the adaptive loop, click Mesh and wait until the run ends; it
    must fail (pushed-forward pentagon angles below 60° with n = 2)."""
    require_pipeline()
    win.set_polygon(polygon)
    tick(qtbot, win.repair_check)
    tick(qtbot, win.adaptive_check)
    opts = win.mesh_options()
    assert not opts.adaptive and not opts.repair
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
    assert win.result is None and win.progress_bar.format() == "failed"
    assert win.last_error.startswith("[disk] mapped disk mesh angles out of [60°, 120°]")


def _disk_part(win, layer: str, label: str):
    geo = win.disk.layers[layer].geometry
    assert geo is not None, layer
    return geo.part(label)


def _points(part) -> np.ndarray:
    p = np.asarray(part.mesh.points)[:, :2]
    return p[:, 0] + 1j * p[:, 1]


def test_failed_piece_shown_in_disk_view_and_cleared(main_window, qtbot):
    """The L-shape fails in its only thick piece: the disk view shows its 6 prevertices on
    T, its 6 arcs I_j and its disk mesh, the spin box says "(failed)", the plane view
    outlines the piece in red; a new (adaptive) run replaces them by the result's piece,
    and an edit clears the disk view."""
    win = main_window
    _fail_strictly(win, qtbot, LSHAPE)
    partial = win.partial
    assert partial.failed_piece == 0 and len(partial.pieces) == 1
    assert win.piece_spin.maximum() == 0 and win.piece_spin.suffix() == " (failed)"
    pre = _disk_part(win, "prevertices", "prevertices")
    z = _points(pre)
    assert z.size == 6
    np.testing.assert_allclose(np.abs(z), 1.0, atol=1e-6)
    np.testing.assert_allclose(
        np.sort(np.angle(z)), np.sort(np.angle(partial.pieces[0].map.prevertices)), atol=1e-6
    )
    assert _disk_part(win, "prevertices", "I arcs").mesh.n_lines == 6
    edges = _disk_part(win, "disk_mesh", "edges")
    assert edges.mesh.n_cells > 100
    assert np.all(np.abs(_points(edges)) <= 1 + 1e-6)  # the disk mesh lies in D (float32)
    for name in ("prevertices", "disk_mesh", "region_w"):
        st = win.disk.layers[name]
        assert st.visible and st.actors and all(a.GetVisibility() for a in st.actors)
    # the plane view outlines the failing piece in red, last over the partial stages
    red = win.plane.overlays["partial"][-1]
    assert np.allclose(red.prop.color.float_rgb, (224 / 255, 0, 0), atol=0.01)
    outline = np.asarray(red.GetMapper().GetInput().GetPoints().GetData())[:, :2]
    np.testing.assert_allclose(np.sort(outline[:, 0]), np.sort(LSHAPE[:, 0]), atol=1e-12)

    # a new run (adaptive again) clears the failure; its result's piece takes the disk view
    tick(qtbot, win.adaptive_check)
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
    assert win.last_error is None and win.partial is None and win.result is not None
    assert win.piece_spin.suffix() == ""
    z = _points(_disk_part(win, "prevertices", "prevertices"))
    np.testing.assert_allclose(
        np.sort(np.angle(z)), np.sort(np.angle(win.result.pieces[0].map.prevertices)), atol=1e-6
    )
    # a failure again, then an edit: the disk view is empty, the spin box back to 0
    tick(qtbot, win.adaptive_check)
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
    assert win.partial is not None and win.disk.layers["prevertices"].geometry is not None
    win.set_polygon(LSHAPE * 1.5)
    assert win.partial is None and win.result is None
    for name in ("prevertices", "disk_mesh", "region_w"):
        assert win.disk.layers[name].geometry is None
    assert win.piece_spin.maximum() == 0 and win.piece_spin.suffix() == ""
    assert "partial" not in win.plane.overlays


def test_spin_box_steps_through_the_partial_pieces(main_window, qtbot):
    """The dumbbell fails in thick piece 1; the spin box starts there and the Down key shows
    piece 0 (which passed): other prevertices, and no "(failed)"."""
    from quadmesh.examples import load_example

    win = main_window
    _fail_strictly(win, qtbot, np.asarray(load_example("dumbbell")))
    partial = win.partial
    assert partial.failed_piece == 1 and [p.index for p in partial.pieces] == [0, 1]
    assert win.piece_spin.maximum() == 1 and win.piece_spin.value() == 1
    assert win.piece_spin.suffix() == " (failed)"
    z1 = _points(_disk_part(win, "prevertices", "prevertices"))
    win.piece_spin.setFocus()
    qtbot.keyClick(win.piece_spin, Qt.Key.Key_Down)
    assert win.piece_spin.value() == 0 and win.disk_piece == 0
    assert win.piece_spin.suffix() == ""
    z0 = _points(_disk_part(win, "prevertices", "prevertices"))
    want = np.asarray(partial.pieces[0].map.prevertices)
    assert z0.size == want.size == len(partial.decomposition.thick[0].z)
    np.testing.assert_allclose(np.sort(np.angle(z0)), np.sort(np.angle(want)), atol=1e-6)
    assert z0.size != z1.size or not np.allclose(np.sort(np.angle(z0)), np.sort(np.angle(z1)))
    assert _disk_part(win, "disk_mesh", "edges").mesh.n_cells > 100


def test_unsolved_map_shows_the_estimate_it_judged(main_window, qtbot):
    """A traced background region with a long wavy wedge (scikit-image "coins", contour 0): no
    straight-cell layout, and the conformal map of its one thick piece is refused as crowded,
    so there is no map.  The plane view outlines
    that piece in red; the disk view shows what the crowding check judged — the
    harmonic-measure estimate of its prevertices, labelled so in the legend, with "(failed, no
    map)" in the spin box and no region or disk mesh; a drag in the disk view moves the
    estimate with the tessellation; an edit of the polygon with the mouse clears it all."""
    from quadmesh.families import FAMILIES
    from tests.test_app import drag

    require_pipeline()
    win = main_window
    poly = np.asarray(next(m for m in FAMILIES["images"](0) if m.name == "coins_0").vertices)
    win.set_polygon(poly)
    with qtbot.waitSignal(win.runner.idle, timeout=120000):
        press(qtbot, win.mesh_button)
    assert win.result is None and win.progress_bar.format() == "failed"
    assert win.last_error.startswith("[conformal]") and "crowding" in win.last_error
    assert win.error_box.toPlainText() == win.last_error
    assert not win.error_box.visibleRegion().isEmpty()  # scrolled into view, not covered
    partial = win.partial
    assert partial.failed_piece == 0 and partial.pieces == ()
    assert win.piece_spin.suffix() == " (failed, no map)" and win.piece_spin.maximum() == 0
    pre = _disk_part(win, "prevertices", partial.failed_prevertices_kind)
    z = _points(pre)
    want = np.asarray(partial.failed_prevertices)
    assert z.size == want.size == len(partial.decomposition.thick[0].z)
    np.testing.assert_allclose(z, want, atol=1e-6)  # float32 points
    assert "harmonic-measure estimate" in partial.failed_prevertices_kind
    st = win.disk.layers["prevertices"]
    assert st.visible and st.actors and all(a.GetVisibility() for a in st.actors)
    for name in ("region_w", "disk_mesh"):
        assert win.disk.layers[name].geometry is None
    assert any("harmonic-measure estimate" in lab for lab in win.legend.labels("prevertices"))
    red = win.plane.overlays["partial"][-1]
    outline = np.asarray(red.GetMapper().GetInput().GetPoints().GetData())[:, :2]
    piece = np.asarray(partial.decomposition.thick[0].z) + partial.origin
    np.testing.assert_allclose(np.sort(outline[:, 0]), np.sort(piece.real), atol=1e-4)

    # a drag in the disk view moves the estimate by the automorphism (it stays on T)
    drag(qtbot, win.disk, 0.4 + 0.1j, 0.0j)
    moved = _points(_disk_part(win, "prevertices", partial.failed_prevertices_kind))
    np.testing.assert_allclose(np.abs(moved), 1.0, atol=1e-5)
    assert np.max(np.abs(moved - want)) > 0.1

    # moving a vertex with the mouse clears the failure, the estimate and the red outline
    tick(qtbot, win.draw_check)
    a = complex(win.editor.z[0])
    win.reset_plane_view()
    win.plane.render()
    drag(qtbot, win.plane, a, a + 0.02 * (win.editor.z.mean() - a))
    assert win.partial is None and win.last_error is None
    assert win.disk.layers["prevertices"].geometry is None
    assert win.piece_spin.suffix() == "" and "partial" not in win.plane.overlays
