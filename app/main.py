"""Entry point of ``quadmesh-app``.

Interactive use: ``quadmesh-app``.  Scripted use (for documentation screenshots and CI)::

    quadmesh-app --open poly.json --mesh --layers polygon,final_mesh \\
                 --screenshot out.png --quit

``--example NAME`` loads a bundled polygon instead of a file; ``--method blocks`` (with
``--block-size 0.05``, a fraction of the polygon's diameter) chooses the block mesher in the
Mesh panel before meshing.  With ``--quit`` the exit status
is 0 when every requested step succeeded, otherwise the reason is printed to stderr and the
status is 1 (2 for bad command-line arguments).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from quadmesh.result import METHODS

__all__ = ["build_parser", "main", "run"]


def build_parser() -> argparse.ArgumentParser:
    """The command-line parser of ``quadmesh-app``."""
    p = argparse.ArgumentParser(
        prog="quadmesh-app",
        description="Viewer for quadrilateral meshes with every new angle in [60°, 120°] "
        "(Bishop's construction).",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--open",
        metavar="FILE",
        help="open a polygon (JSON, CSV, GeoJSON, SVG) or a mesh (JSON with quads, VTK, VTU, "
        "MSH, OBJ, PLY, Medit)",
    )
    src.add_argument("--example", metavar="NAME", help="load a bundled example polygon")
    p.add_argument("--mesh", action="store_true", help="run the mesher to completion")
    p.add_argument(
        "--method",
        choices=METHODS,
        default=None,
        help="meshing method chosen in the Mesh panel (default: the panel's, the paper's)",
    )
    p.add_argument(
        "--block-size",
        type=float,
        metavar="FRACTION",
        help="Block size of the Mesh panel for --method blocks: a fraction of the diameter",
    )
    p.add_argument("--layers", metavar="A,B,…", help="comma-separated layers to show")
    p.add_argument(
        "--color-by",
        choices=("corner", "worst"),
        default="corner",
        help="colouring of the final mesh",
    )
    p.add_argument("--screenshot", metavar="PNG", help="write a screenshot of the window")
    p.add_argument("--size", metavar="WxH", default="1280x860", help="window size")
    p.add_argument("--quit", action="store_true", help="exit after the steps above")
    return p


def run(argv: Sequence[str] | None = None) -> int:
    """Create the application and the window, perform the scripted steps; return the status."""
    args = build_parser().parse_args(argv)
    try:
        w_str, h_str = args.size.lower().split("x")
        size = (int(w_str), int(h_str))
    except ValueError:
        print(f"quadmesh-app: --size must look like 1280x860, got {args.size!r}", file=sys.stderr)
        return 2

    from PySide6.QtWidgets import QApplication
    from threadpoolctl import threadpool_limits

    from quadmesh.errors import QuadmeshError

    from .window import MainWindow

    # the mesher runs in a worker thread, where it leaves the process's BLAS limit alone
    # (MeshOptions.blas_threads): set it here, once, before any thread starts
    threadpool_limits(limits=1, user_api="blas")
    app = QApplication.instance() or QApplication(sys.argv[:1])
    # the views render when something changes, never on a timer (idle = no CPU)
    win = MainWindow(popups=not args.quit)
    win.resize(*size)
    win.show()
    app.processEvents()

    def fail(msg: str) -> int:
        print(f"quadmesh-app: {msg}", file=sys.stderr)
        if args.quit:
            win.shutdown()
            win.close()
            return 1
        win._show_error(msg)
        return 0

    status = 0
    try:
        if args.layers:
            win.set_visible_layers([s.strip() for s in args.layers.split(",") if s.strip()])
        if args.color_by != "corner":
            win.layer_panel.color_mode.setCurrentIndex(1)
        if args.method is not None:
            win.method_combo.setCurrentIndex(win.method_combo.findData(args.method))
        if args.block_size is not None:
            spin = win.block_size_spin
            if not spin.minimum() <= args.block_size <= spin.maximum():
                raise ValueError(
                    f"--block-size must be in [{spin.minimum():g}, {spin.maximum():g}], "
                    f"got {args.block_size:g}"
                )
            spin.setValue(args.block_size)
        if args.open:
            win.open_file(args.open)
        elif args.example:
            win.load_example(args.example)
        if args.mesh:
            if not win.start_mesh():
                status = fail(f"cannot mesh: {win.last_error}")
            else:
                win.wait_for_mesh()
                if win.result is None:
                    status = fail(f"meshing failed: {win.last_error or 'cancelled'}")
        app.processEvents()
        if args.screenshot and status == 0:
            win.save_screenshot(args.screenshot)
    except (QuadmeshError, OSError, ValueError) as exc:
        status = fail(str(exc))
    if status and args.quit:
        return status
    if args.quit:
        win.shutdown()
        win.close()
        return 0
    return app.exec()


def main() -> None:
    """Console entry point (``quadmesh-app``)."""
    sys.exit(run())


if __name__ == "__main__":
    main()
