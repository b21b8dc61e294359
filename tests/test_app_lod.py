"""Interaction-time level of detail of the app's views (run under ``xvfb-run``): parts with
more than ``app.views.LOD_CELLS`` cells are drawn light while the user drags, zooms or toggles
and in full detail afterwards, except their sub-pixel cells while zoomed out.  The threshold is
lowered here so that the meshed L-shape counts as heavy."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers import require_pipeline
from tests.test_app import _pos, mesh_l_shape, tick, wheel

pytestmark = pytest.mark.gui


@pytest.fixture
def heavy(main_window, qtbot, monkeypatch):
    """The meshed L-shape, shown again with LOD_CELLS = 40 and 12 clustering divisions."""
    require_pipeline()
    import app.views

    monkeypatch.setattr(app.views, "LOD_CELLS", 40)
    monkeypatch.setattr(app.views, "LOD_DIVISIONS", 12)
    monkeypatch.setattr(app.views, "LOD_SUBPIXEL", 0.0)  # settled frames: true geometry
    win = mesh_l_shape(main_window, qtbot)
    win.set_result(win.result)
    return win


def _visible(actors) -> list[bool]:
    return [bool(a.GetVisibility()) for a in actors]


def test_light_stand_in_of_the_final_mesh(heavy):
    """The stand-in of the coloured quads is a vertex clustering: far fewer cells over the
    same extent, colour values (per cell) within the colour range of the full part."""
    st = heavy.plane.layers["final_mesh"]
    quads = st.geometry.part("quads")
    assert st.heavy == [True, True]  # quads and edges
    assert len(st.light_parts) == 1  # wireframes get no stand-in
    light = st.light_parts[0]
    assert 0 < light.n_cells <= 2 * 12 * 12 < quads.n_cells
    np.testing.assert_allclose(light.mesh.bounds[:4], quads.mesh.bounds[:4], atol=0.1)
    vals = np.asarray(light.mesh.cell_data[quads.scalars])
    full = np.asarray(quads.mesh[quads.scalars])
    assert full.min() - 1e-9 <= vals.min() and vals.max() <= full.max() + 1e-9


def test_interaction_swaps_heavy_parts_for_light_ones(heavy, qtbot):
    """begin/end_interaction show the stand-ins (without multisampling) instead of the heavy
    parts and back; a layer toggle draws light at once and full detail after LOD_SETTLE_MS."""
    import app.views

    v = heavy.plane
    st = v.layers["final_mesh"]
    assert _visible(st.actors) == [True, True] and _visible(st.light_actors) == [False]
    samples = v.plotter.ren_win.GetMultiSamples()
    assert samples > 0  # full-detail frames are anti-aliased
    v.begin_interaction()
    assert _visible(st.actors) == [False, False] and _visible(st.light_actors) == [True]
    assert v.plotter.ren_win.GetMultiSamples() == 0  # light frames are not
    v.end_interaction()
    assert not v.interacting and _visible(st.actors) == [True, True]
    assert v.plotter.ren_win.GetMultiSamples() == samples
    tick(qtbot, heavy.layer_panel.checkboxes["crosscuts"])  # unticked by mouse
    assert v.interacting and _visible(st.light_actors) == [True]
    qtbot.waitUntil(lambda: not v.interacting, timeout=app.views.LOD_SETTLE_MS + 2000)
    assert _visible(st.actors) == [True, True] and _visible(st.light_actors) == [False]
    # hiding the layer while light hides its stand-in too
    v.begin_interaction()
    tick(qtbot, heavy.layer_panel.checkboxes["final_mesh"])
    assert _visible(st.actors + st.light_actors) == [False, False, False]
    v.end_interaction()
    assert _visible(st.actors + st.light_actors) == [False, False, False]


def test_colour_switch_reuses_parked_actors(heavy, qtbot):
    """Switching corner → worst → corner shows the first colouring's own actors again, with
    exactly one colour bar on screen, the one of the colouring shown."""
    from quadmesh.render import CORNER_TITLE, WORST_TITLE

    v = heavy.plane
    first = list(v.layer_actors("final_mesh"))
    from PySide6.QtCore import Qt

    combo = heavy.layer_panel.color_mode
    combo.setFocus()
    qtbot.keyClick(combo, Qt.Key.Key_Down)  # corner angle -> worst deviation
    assert combo.currentData() == "worst"
    assert v.layers["final_mesh"].geometry.part("quads").scalars == "worst_deviation"
    bars = v.plotter.scalar_bars
    assert bars[WORST_TITLE].GetVisibility() and not bars[CORNER_TITLE].GetVisibility()
    assert not any(a is b for a in v.layer_actors("final_mesh") for b in first)
    qtbot.keyClick(combo, Qt.Key.Key_Up)
    assert combo.currentData() == "corner"
    again = v.layer_actors("final_mesh")
    assert len(again) == len(first) and all(a is b for a, b in zip(again, first, strict=True))
    assert bars[CORNER_TITLE].GetVisibility() and not bars[WORST_TITLE].GetVisibility()
    v.end_interaction()
    st = v.layers["final_mesh"]
    assert _visible(st.actors) == [True, True]
    parked = v._parked["final_mesh"][1]
    assert _visible(parked.actors + parked.light_actors) == [False, False, False]


def test_disk_drag_moves_light_parts_and_catches_up_on_release(heavy, qtbot):
    """During a mouse drag in the disk view only the light parts follow the automorphism; on
    the release every disk part sits at g(disk_z)."""
    from PySide6.QtCore import Qt

    win = heavy
    d = win.disk
    st = d.layers["region_w"]
    assert any(st.heavy) and st.light_parts
    qtbot.mousePress(d.plotter, Qt.MouseButton.LeftButton, pos=_pos(d, 0.1 + 0.05j))
    qtbot.mouseMove(d.plotter, _pos(d, 0.25 + 0.2j))
    qtbot.mouseMove(d.plotter, _pos(d, 0.4 + 0.3j))
    g = d.transform
    assert g is not None and d.interacting
    for part in st.light_parts:
        pts = np.asarray(part.mesh.points)
        np.testing.assert_allclose(pts[:, 0] + 1j * pts[:, 1], g(part.disk_z), atol=1e-9)
    big = [p for p, h in zip(d._drawn_parts(st), st.heavy, strict=True) if h]
    pts = np.asarray(big[0].mesh.points)
    assert not np.allclose(pts[:, 0] + 1j * pts[:, 1], g(big[0].disk_z) * big[0].disk_scale)
    qtbot.mouseRelease(d.plotter, Qt.MouseButton.LeftButton, pos=_pos(d, 0.4 + 0.3j))
    assert not d.interacting
    g = d.transform
    for part in d._drawn_parts(st):
        if part.disk_z is not None:
            pts = np.asarray(part.mesh.points)
            w = g(part.disk_z) * part.disk_scale
            np.testing.assert_allclose(pts[:, 0] + 1j * pts[:, 1], w, atol=1e-9)


def test_pan_in_the_plane_is_light_until_the_release(heavy, qtbot):
    """A left-button pan in the plane view (not drawing) draws the mesh light while the button
    is down and in full detail once the release has been handled."""
    from PySide6.QtCore import QPoint, Qt

    v = heavy.plane
    st = v.layers["final_mesh"]
    w = v.plotter
    qtbot.mousePress(w, Qt.MouseButton.LeftButton, pos=QPoint(200, 200))
    assert v.interacting and _visible(st.light_actors) == [True]
    qtbot.mouseMove(w, QPoint(240, 230))
    qtbot.mouseRelease(w, Qt.MouseButton.LeftButton, pos=QPoint(240, 230))
    qtbot.waitUntil(lambda: not v.interacting, timeout=2000)
    assert _visible(st.actors) == [True, True] and _visible(st.light_actors) == [False]


# ---------------------------------------------------------------- settled frames, sub-pixel cells


@pytest.fixture
def graded(main_window, qtbot, monkeypatch):
    """The meshed L-shape with LOD_CELLS = 40, the whole mesh in view: a graded mesh whose
    cells at the corners are far below pixel size while its largest ones are many pixels."""
    require_pipeline()
    import app.views

    monkeypatch.setattr(app.views, "LOD_CELLS", 40)
    monkeypatch.setattr(app.views, "LOD_DIVISIONS", 12)
    win = mesh_l_shape(main_window, qtbot)
    win.set_result(win.result)
    win.plane.reset_view()
    return win


def _wheel(view, z: complex, notches: int) -> None:
    """A real wheel event of ``notches`` notches over the view at world point ``z``."""
    wheel(view, *view.to_widget(z), notches)


def _check_pick(win, qtbot, k: int) -> None:
    """Click the centroid of quad k: the window reports quad k and its angles."""
    from tests.test_app import click

    mesh = win.result.mesh
    c = mesh.z[mesh.quads[k]].mean()
    click(qtbot, win.plane, c)
    info = win.picked_quad
    assert info is not None and info["quad"] == k
    np.testing.assert_allclose(info["angles"], mesh.angles()[k], atol=1e-12)


def test_settled_frame_keeps_sub_pixel_cells_light_until_zoomed_in(graded, qtbot):
    """Zoomed out, the settled frame draws the cells at least half a clustering step wide (all
    cells a pixel wide or more, with their edges) as they are and only the narrower ones by
    their clustering; after real wheel events zoom in until a step is over LOD_SUBPIXEL pixels,
    the true geometry is back.  Picking works on the true quads either way."""
    import app.views
    from app.views import cell_widths

    win = graded
    v = win.plane
    st = v.layers["final_mesh"]
    quads = st.geometry.part("quads")
    assert not v.interacting and v.subpixel(st)
    assert _visible(st.actors) == [False, False] and _visible(st.light_actors) == [False]
    assert [p.label for p in st.fine_parts] == [
        "quads (large cells)",
        "quads (sub-pixel cells)",
        "edges (large cells)",
    ]
    assert _visible(st.fine_actors) == [True, True, True]
    px = v.device_pixel_size()
    assert st.fine_step <= app.views.LOD_SUBPIXEL * px
    w = cell_widths(quads)
    big = w >= 0.5 * st.fine_step
    assert 0 < big.sum() < quads.n_cells and st.fine_parts[0].n_cells == big.sum()
    assert w[~big].max() < px  # only sub-pixel cells are replaced ...
    assert np.all(big | (w < px))  # ... and every cell a pixel wide or more is drawn as it is
    edges = st.geometry.part("edges")
    kept = cell_widths(edges) >= 0.5 * st.fine_step
    assert st.fine_parts[2].n_cells == kept.sum() < edges.n_cells
    # the stand-in's colours (per cell) stay within the colour range of the quads
    light = st.fine_parts[1]
    vals = np.asarray(light.mesh.cell_data[quads.scalars])
    full = np.asarray(quads.mesh[quads.scalars])
    assert full.min() - 1e-9 <= vals.min() and vals.max() <= full.max() + 1e-9
    # picking a large quad while the settled frame is split
    mesh = win.result.mesh
    k_big = int(np.argmax(w))
    _check_pick(win, qtbot, k_big)

    # zoom in (wheel over the finest quad) until a clustering step is over LOD_SUBPIXEL pixels
    k_small = int(np.argmin(w))
    at = complex(mesh.z[mesh.quads[k_small]].mean())
    notches = int(np.ceil(np.log(app.views.LOD_SUBPIXEL * px / st.fine_step) / np.log(1.2))) + 1
    _wheel(v, at, notches)
    assert v.interacting and _visible(st.light_actors) == [True]  # the zoom step is light
    qtbot.waitUntil(lambda: not v.interacting, timeout=app.views.LOD_SETTLE_MS + 3000)
    assert not v.subpixel(st)
    assert _visible(st.actors) == [True, True] and _visible(st.fine_actors) == [False] * 3
    # a quad a few pixels wide near the cursor, on the true geometry
    c = mesh.z[mesh.quads].mean(axis=1)
    near = np.flatnonzero((w > 4 * v.device_pixel_size()) & (np.abs(c - at) < 20 * px))
    assert near.size
    _check_pick(win, qtbot, int(near[np.argmin(np.abs(c[near] - at))]))

    # and back out: the split again
    _wheel(v, at, -notches)
    qtbot.waitUntil(lambda: not v.interacting, timeout=app.views.LOD_SETTLE_MS + 3000)
    assert v.subpixel(st) and _visible(st.fine_actors) == [True, True, True]


def test_screenshot_draws_the_true_geometry(graded, tmp_path):
    """A screenshot at the zoom where the settled frame is split renders the true parts (every
    cell and edge) for the picture, then goes back to the split."""
    v = graded.plane
    st = v.layers["final_mesh"]
    assert v.subpixel(st)
    frames: list[list[bool]] = []
    tag = v.plotter.ren_win.AddObserver(
        "EndEvent", lambda *_: frames.append(_visible(st.actors + st.fine_actors))
    )
    try:
        graded.save_screenshot(tmp_path / "shot.png")
    finally:
        v.plotter.ren_win.RemoveObserver(tag)
    assert (tmp_path / "shot.png").stat().st_size > 0
    assert [True, True, False, False, False] in frames
    assert frames[-1] == [False, False, True, True, True]
    assert not v.full_detail


def test_disk_split_is_remade_for_the_automorphism_on_release(graded, qtbot):
    """After a mouse drag in the disk view the split follows the automorphism: it is made for
    the moved cells (those small on screen now), and every part sits at g(disk_z)."""
    from PySide6.QtCore import Qt

    from app.views import cell_widths

    d = graded.disk
    st = d.layers["region_w"]
    assert st.fine_disk and d.subpixel(st) and st.fine_key is None
    w = d.plotter
    qtbot.mousePress(w, Qt.MouseButton.LeftButton, pos=_pos(d, 0.1 + 0.05j))
    qtbot.mouseMove(w, _pos(d, 0.3 + 0.2j))
    qtbot.mouseMove(w, _pos(d, 0.5 + 0.4j))
    assert d.interacting and not d.subpixel(st)  # the light stand-ins while dragging
    qtbot.mouseRelease(w, Qt.MouseButton.LeftButton, pos=_pos(d, 0.5 + 0.4j))
    assert not d.interacting
    g = d.transform
    assert g is not None and st.fine_key is g and d.subpixel(st)
    heavy = [p for p, h in zip(d._drawn_parts(st), st.heavy, strict=True) if h]
    large = [p for p in st.fine_parts if p.label.endswith("(large cells)")]
    for part in heavy:
        n_big = int((cell_widths(part) >= 0.5 * st.fine_step).sum())
        got = [p.n_cells for p in large if p.label == f"{part.label} (large cells)"]
        assert got == ([n_big] if n_big else [])
    for part in st.fine_parts:
        pts = np.asarray(part.mesh.points)
        w_ = np.asarray(g(part.disk_z)) * part.disk_scale
        np.testing.assert_allclose(pts[:, 0] + 1j * pts[:, 1], w_, atol=1e-9)
    assert _visible(st.fine_actors) == [True] * len(st.fine_actors)
