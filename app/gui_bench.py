"""Interactivity of quadmesh-app on big meshes: wall-clock time of the GUI operations a user
repeats (run under an X server, e.g. ``xvfb-run``; not a test)::

    PYTHONPATH=. xvfb-run -a -s "-screen 0 1280x1024x24" python -m app.gui_bench \\
        --example dodecagon --example star_100 --example noisy_circle_1000

For each polygon (meshed here first, the time is printed) it shows the result in the real
window and times, each as the median of ``--repeat`` runs including the render:
hiding + showing the final-mesh layer (one toggle), switching the mesh colour between corner
angle and worst deviation (one switch), one zoom step, and one mouse-move step of a drag in
the disk view (an automorphism applied to the disk layers).  Toggles, colour switches, zoom
steps and drags draw layers with more than ``app.views.LOD_CELLS`` cells light (surfaces
vertex-clustered, dense wireframes left out) and full detail once the user stops (the release
of the drag; 0.25 s after the last toggle or zoom step): "full ms" is that full-detail frame
of the plane view at the zoom the operations left (the whole mesh in view, where the cells of
heavy layers that are under a pixel are drawn by a clustering, see ``app.views.fine_split``),
"true ms" the same frame with
the true geometry (as a screenshot draws it), "zoomed ms" the settled frame after zooming in
by the factor shown, the first power of 2 at which the final mesh's cells are no longer
sub-pixel (the true geometry, most of it off screen). "load" is the 1-minute load average
after the row's operations (the benchmark itself counts about 1): Mesa's software OpenGL
renders on every core, so other processes slow each frame down.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable

__all__ = ["main", "time_operations"]


def _median_ms(fn: Callable[[], object], repeat: int, app: object) -> float:
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        app.processEvents()  # type: ignore[attr-defined]
        out.append((time.perf_counter() - t) * 1000.0)
    return statistics.median(out)


def time_operations(win: object, app: object, repeat: int = 5) -> dict[str, float]:
    """Median milliseconds of a layer toggle, a colour switch, a zoom step and a disk-drag
    step in ``win`` (a MainWindow showing a result)."""

    cb = win.layer_panel.checkboxes["final_mesh"]  # type: ignore[attr-defined]
    res: dict[str, float] = {}
    res["toggle"] = _median_ms(lambda: cb.setChecked(not cb.isChecked()), 2 * repeat, app)
    cb.setChecked(True)
    combo = win.layer_panel.color_mode  # type: ignore[attr-defined]
    res["colour"] = _median_ms(lambda: combo.setCurrentIndex(1 - combo.currentIndex()), repeat, app)
    plane = win.plane  # type: ignore[attr-defined]
    zooms = iter([1.1, 1 / 1.1] * (repeat + 1))

    def zoom() -> None:
        plane.zoom(next(zooms))

    res["zoom"] = _median_ms(zoom, repeat, app)
    plane.end_interaction(render=False)
    res["full"] = _median_ms(plane.render, repeat, app)
    # the same frame with the true geometry whatever the zoom (what a screenshot draws)
    plane.set_full_detail(True)
    res["true"] = _median_ms(plane.render, repeat, app)
    plane.set_full_detail(False)
    # zoomed in (about the view's centre) until the final mesh's cells are no longer
    # sub-pixel, so that its settled frame draws the true geometry of the part on screen
    st = plane.layers.get("final_mesh")
    cam = plane.plotter.camera
    factor = 1
    while st is not None and plane.subpixel(st) and factor < 1024:
        cam.zoom(2.0)
        factor *= 2
    res["zoomed"] = _median_ms(plane.render, repeat, app)
    res["factor"] = factor
    cam.zoom(1.0 / factor)
    plane.render()

    win._on_disk_mouse("press", 0.1 + 0.05j, 0)  # type: ignore[attr-defined]
    steps = iter([0.1 + 0.05j + 0.01 * k * (1 + 1j) for k in range(1, 4 * repeat + 3)])
    res["drag"] = _median_ms(
        lambda: win._on_disk_mouse("drag", next(steps), 0),  # type: ignore[attr-defined]
        repeat,
        app,
    )
    t = time.perf_counter()
    win._on_disk_mouse("release", 0.3 + 0.25j, 0)  # type: ignore[attr-defined]
    app.processEvents()  # type: ignore[attr-defined]
    res["release"] = (time.perf_counter() - t) * 1000.0
    win.set_disk_transform(None)  # type: ignore[attr-defined]
    return res


def main(argv: list[str] | None = None) -> int:
    """Mesh each polygon, show it in the app and print a table of the operation times."""
    p = argparse.ArgumentParser(prog="python -m app.gui_bench", description=__doc__)
    p.add_argument("--example", action="append", default=[], help="bundled example name")
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args(argv)
    names = args.example or ["dodecagon", "star_100", "noisy_circle_1000"]

    from PySide6.QtWidgets import QApplication

    from app.window import MainWindow
    from quadmesh.examples import load_example
    from quadmesh.pipeline import mesh_polygon

    app = QApplication.instance() or QApplication(sys.argv[:1])
    win = MainWindow(popups=False)
    win.resize(1280, 860)
    win.show()
    for _ in range(10):
        app.processEvents()
    print(
        f"{'polygon':<20} {'quads':>9} {'mesh s':>7} {'show s':>7} "
        f"{'toggle ms':>10} {'colour ms':>10} {'zoom ms':>8} {'drag ms':>8} {'release ms':>10} "
        f"{'full ms':>8} {'true ms':>8} {'zoomed ms':>12} {'load':>5}"
    )
    for name in names:
        t = time.perf_counter()
        r = mesh_polygon(load_example(name))
        t_mesh = time.perf_counter() - t
        win.load_example(name)
        t = time.perf_counter()
        win.set_result(r)
        app.processEvents()
        t_show = time.perf_counter() - t
        ms = time_operations(win, app, args.repeat)
        load = os.getloadavg()[0]  # other processes slow software OpenGL down: say how busy
        print(
            f"{name:<20} {r.mesh.n_quads:>9} {t_mesh:>7.1f} {t_show:>7.2f} {ms['toggle']:>10.1f} "
            f"{ms['colour']:>10.1f} {ms['zoom']:>8.1f} {ms['drag']:>8.1f} {ms['release']:>10.1f} "
            f"{ms['full']:>8.1f} {ms['true']:>8.1f} {ms['zoomed']:>7.1f} ×{ms['factor']:<4.0f} "
            f"{load:>5.2f}",
            flush=True,
        )
    win.shutdown()
    win.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
