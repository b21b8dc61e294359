"""The main window of ``quadmesh-app``: a view over :class:`quadmesh.result.MeshResult`.

Plane view (left): the polygon being drawn and the layers of the last result.  Disk view
(right): the tessellation T5 and one thick piece's disk construction; dragging there moves the
picked point to the centre by a disk automorphism, clicks pick two points whose hyperbolic
distance and geodesic are shown.  Docks: layers, drawing, mesh parameters and progress,
information (counts, angles, timings, histogram).  All computing happens in ``quadmesh``.
"""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Callable
from html import escape as html_escape
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QEventLoop, QSettings, Qt, QTimer
from PySide6.QtGui import QAction, QDoubleValidator, QKeySequence, QTextDocument
from PySide6.QtWidgets import (
    QAbstractButton,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDockWidget,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMainWindow,
    QMessageBox,
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QSpinBox,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from quadmesh.errors import PolygonError, QuadmeshError
from quadmesh.hyperbolic.geodesic import distance
from quadmesh.hyperbolic.isometry import Isometry, disk_automorphism, disk_automorphism_inverse
from quadmesh.mesh import QuadMesh
from quadmesh.polygon import validate_polygon
from quadmesh.render import (
    LAYER_COLORS,
    LAYER_TITLES,
    LayerGeometry,
    LayerPart,
    build_disk_layer,
    build_layer,
    geodesic_arc,
    layer_names,
    line_part,
    points_part,
    polygon_layer,
    unit_circle_part,
)
from quadmesh.result import METHODS, MeshOptions

from .drawing import PolygonEditor
from .histogram import AngleHistogram
from .layers import DEFAULT_VISIBLE, LayerPanel
from .legend import THIN_KIND_TITLES, LegendPanel, legend_entries
from .views import LayerState, View2D
from .worker import JobRunner

__all__ = ["MainWindow"]

_RESULT_PLANE = [n for n in layer_names("plane") if n != "polygon"]
_RESULT_DISK = [n for n in layer_names("disk") if n != "tessellation"]

# option name -> (label, kind, min, max, step, decimals)
_OPTION_SPECS: dict[str, tuple[str, str, float, float, float, int]] = {
    "n": ("n (half-side steps)", "int", 1, 12, 1, 0),
    "max_n": ("max n (adaptive)", "int", 1, 16, 1, 0),
    "depth_step": ("depth step δ", "float", 0.01, 1.0, 0.05, 3),
    "inner_height": ("inner triangle h", "float", 0.05, 2.0, 0.05, 3),
    "crosscut_ratio": ("crosscut ratio", "float", 4.0, 1e4, 4.0, 1),
    "lemma_A": ("Lemma 2.2 factor A", "float", 1.01, 1e4, 1.0, 2),
    "channel_delta": ("channel δ", "float", 0.001, 0.74, 0.01, 3),
    "sector_ratio": ("sector ratio λ", "float", 0.01, 0.99, 0.05, 3),
    "rotations": ("disk rotations tried", "int", 1, 40, 1, 0),
}


#: Tooltip of every Mesh setting: what it does and what it costs in quads and time.
OPTION_TIPS: dict[str, str] = {
    "n": "Steps per half side of every pentagon in the disk construction (start value). "
    "Larger n: straighter pushed-forward angles (closer to 90°) but about n² times more quads "
    "per thick piece and a longer disk stage. 2 is the smallest value that keeps the disk "
    "angles in [60°, 120°].",
    "max_n": "Largest n the adaptive loop may raise a thick piece to when its quads leave "
    "[60°, 120°]. Higher: more polygons succeed, at the cost of many more quads and time on "
    "the hard ones; it never adds quads where n already works.",
    "depth_step": "Spacing δ of the Carleson rows toward the boundary of the disk. Smaller: "
    "more rows, so more quads (about 1/δ) and more time, with angles closer to 90° near the "
    "polygon's sides. The adaptive loop halves it where a Carleson quad leaves the range.",
    "inner_height": "Height h of the inner triangle of each Carleson triangle. Smaller: "
    "deeper triangle landmarks, hence more rows (quads, time) near polygon vertices; larger: "
    "fewer quads but flatter triangles.",
    "crosscut_ratio": "Prevertex gap over half-width of the arc whose image cuts a vertex "
    "sector off a thick piece. Larger: smaller, rounder sectors and more cover arcs (more "
    "Carleson pieces and quads); smaller: fewer quads, less round crosscuts (the conformal "
    "collar straightens them).",
    "lemma_A": "Expansion factor A of Lemma 2.2 (any A > 1 is valid). Smaller A lets the arcs "
    "around the prevertices grow closer together: fewer cover arcs, fewer quads and less "
    "time; larger A separates them more.",
    "channel_delta": "Extremal-distance threshold δ below which a narrow passage is cut off "
    "as a channel (thin part meshed by a log-spiral connector). Larger: more passages become "
    "channels (fewer crowded conformal maps, faster); smaller: more of the polygon is meshed "
    "through the conformal map.",
    "sector_ratio": "λ: radius of each vertex sector over the crosscut's distance from the "
    "vertex. Smaller: tighter sectors with fewer quads around each vertex; larger: wider "
    "sectors (more quads there).",
    "rotations": "Normalisations of each thick piece's conformal map tried; the one with the "
    "fewest cover arcs is used. More: often fewer quads (0 to −19 %), about 0.3 s per try "
    "and piece. 1 turns it off.",
    "conformal_tol": "Target residual of the Schwarz–Christoffel parameter problem "
    "(1e-14 … 1e-4). Smaller: a more accurate map (angles closer to what the disk mesh "
    "promises) and a slower conformal stage; does not change the quad count much.",
    "adaptive": "When a thick piece's quads leave [60°, 120°], raise n (2 → 3 → 4 → 6, up "
    "to max n) and lower the depth step, and mesh it again. Off: a failure is reported "
    "instead (faster, fewer quads, may fail).",
    "repair": "Before the adaptive loop changes n, move interior vertices near quads that "
    "leave [60°, 120°] by a small fraction of their edges. Keeps the quad count; off: only "
    "raising n (more quads, more time) fixes bad angles.",
    "size": "Blocks only: target edge length of the quads, as a fraction of d, the polygon's "
    "diameter (its bounding box diagonal). Every chord of blocks gets ceil(its longest edge / "
    "size) segments, so halving it gives about four times the quads; blocks holding a corner "
    "below 60° stay whole.",
}

#: The meshing methods of the Mesh panel's selector: (MeshOptions.method, what the user reads).
METHOD_TITLES: dict[str, str] = {"bishop": "Bishop (paper)", "blocks": "Blocks (few quads)"}
METHOD_TIP = (
    "How the polygon is meshed. Bishop (paper): the paper's construction (conformal maps, "
    "thick and thin parts), every stage shown in both views. Blocks (few quads): straight cuts "
    "from the obtuse and reflex corners split the polygon into convex blocks with every corner "
    "in [60°, 120°], refined by grids: the same angle guarantee with far fewer quads; when no "
    "such cuts exist the paper's construction is used instead and the Mesh panel says why."
)
#: Default of the Block size control: the fraction of the diameter MeshOptions(size=None) uses.
DEFAULT_BLOCK_FRACTION = 0.05
#: Mesh-panel settings that only the paper's construction reads (disabled for Blocks).
BISHOP_ONLY = (*_OPTION_SPECS, "conformal_tol", "adaptive", "repair")

_DISK_HINT = "drag: point → centre · click: pick 2 points"
_RECENT_MAX = 8
_POINT_RE = re.compile(
    r"\(\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*,"
    r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*\)"
)


def message_points(message: str) -> np.ndarray:
    """The points "(x, y)" that an error message names, in order, without repeats (complex)."""
    pts = [complex(float(a), float(b)) for a, b in _POINT_RE.findall(message)]
    return np.array(list(dict.fromkeys(pts)), dtype=np.complex128)


def _on_click(button: QAbstractButton, slot: Callable[[], Any]) -> None:
    """Connect a button's ``clicked`` to a slot called with NO arguments.

    ``clicked`` carries Qt's ``checked`` flag; connected directly, a slot with an optional
    first parameter (``start_mesh(job=None)``) would receive ``False`` as that argument."""
    button.clicked.connect(lambda _checked=False: slot())


def _drag_threshold(view: View2D) -> float:
    return 4.0 * view.pixel_size()


class ErrorBox(QPlainTextEdit):
    """The whole message of the last failure: read-only red text, wrapped at the widget's
    width, as tall as the wrapped text up to ``max_lines`` lines (then it scrolls); hidden
    while there is no message."""

    def __init__(self, max_lines: int = 20, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.max_lines = max_lines
        self.setObjectName("error_box")
        self.setReadOnly(True)
        self.setLineWrapMode(QPlainTextEdit.WidgetWidth)
        self.setStyleSheet("QPlainTextEdit { color: #c00000; }")
        self.setSizePolicy(QSizePolicy.Preferred, QSizePolicy.Fixed)
        self._fitted_width = -1
        self.hide()

    def set_message(self, text: str) -> None:
        """Show ``text`` (all of it) and resize to fit."""
        self.setPlainText(text)
        self.show()
        self._fit()

    def clear_message(self) -> None:
        """Empty and hide the box."""
        self.clear()
        self.hide()

    def _fit(self) -> None:
        # lay the text out as the box will (same font, width and margins) to learn its height
        doc = QTextDocument()
        doc.setDefaultFont(self.font())
        doc.setDocumentMargin(self.document().documentMargin())
        doc.setPlainText(self.toPlainText())
        # (as wrapped beside a vertical scroll bar: once the height fits, the bar goes away)
        sb = self.verticalScrollBar().sizeHint().width()
        doc.setTextWidth(max(self.width() - 2 * self.frameWidth() - sb, 80))
        line = self.fontMetrics().lineSpacing()
        body = min(max(doc.size().height(), 2 * line), self.max_lines * line)
        self._fitted_width = self.width()
        self.setFixedHeight(int(np.ceil(body)) + 2 * self.frameWidth() + line // 2)

    def resizeEvent(self, event: Any) -> None:  # Qt API: a new width rewraps the text
        super().resizeEvent(event)
        if self.isVisible() and self.width() != self._fitted_width:
            self._fit()


class MainWindow(QMainWindow):
    """quadmesh's desktop viewer.

    Both views render only when something in them changed (every change is followed by an
    explicit ``render()``); nothing redraws while the app is idle.

    Args:
        auto_update: passed to the pyvistaqt interactors: a number re-renders both views that
            many times a second whether or not anything changed (costly with big meshes; only
            for debugging).  Default False.
        popups: show error message boxes (tests and scripted runs turn them off; the message
            is always in the Mesh dock and the status bar as well).
        settings: where the last used folder is remembered (default: the user's
            ``quadmesh/quadmesh-app`` settings).
    """

    def __init__(
        self,
        *,
        auto_update: bool | float = False,
        popups: bool = True,
        settings: QSettings | None = None,
    ) -> None:
        super().__init__()
        self.setWindowTitle("quadmesh — quadrilateral meshes with angles in [60°, 120°]")
        self.resize(1280, 860)
        self.popups = popups
        self.settings = settings if settings is not None else QSettings("quadmesh", "quadmesh-app")
        self.editor = PolygonEditor()
        self.result: Any = None
        self.loaded_mesh: QuadMesh | None = None
        self._loaded: Any = None  # result-like view of loaded_mesh for quadmesh.render
        self.last_error: str | None = None
        self.color_mode = "corner"
        self.disk_piece = 0
        self.picked: list[complex] = []
        self._drag_vertex: int | None = None
        self._selected: int | None = None
        self._disk_press: tuple[complex, Isometry] | None = None
        self._disk_dragged = False
        self._job_polygon: tuple[complex, ...] | None = None
        self.picked_quad: dict[str, Any] | None = None
        self.problem_points = np.zeros(0, dtype=np.complex128)
        self.shortcuts_dialog: QDialog | None = None
        self.coordinates_dialog: QDialog | None = None
        self._clean_state: tuple[tuple[complex, ...], bool] = ((), False)
        self._mesh_layer_cache: dict[Any, Any] = {}
        self.runner = JobRunner(self)
        self.runner.progress.connect(self._on_progress)
        self.runner.finished.connect(self._on_finished)
        self.runner.failed.connect(self._on_failed)
        self.runner.partial.connect(self._on_partial)
        self.partial: Any = None
        self.runner.cancelled.connect(self._on_cancelled)
        self.runner.idle.connect(self._on_idle)

        # central views
        self.plane = View2D("plane", auto_update=auto_update)
        self.disk = View2D("disk", auto_update=auto_update)
        disk_box = QWidget()
        dl = QVBoxLayout(disk_box)
        dl.setContentsMargins(0, 0, 0, 0)
        bar = QHBoxLayout()
        bar.addWidget(QLabel("thick piece"))
        self.piece_spin = QSpinBox()
        self.piece_spin.setRange(0, 0)
        self.piece_spin.setEnabled(False)  # until a result (or a failed run) has thick pieces
        self.piece_spin.valueChanged.connect(self._on_piece_changed)
        bar.addWidget(self.piece_spin)
        self.reset_disk_btn = QPushButton("Centre 0")
        self.reset_disk_btn.setToolTip("undo the disk automorphism and clear picked points")
        _on_click(self.reset_disk_btn, self.reset_disk_transform)
        bar.addWidget(self.reset_disk_btn)
        self.distance_label = QLabel(_DISK_HINT)
        self.distance_label.setObjectName("distance_label")
        self.distance_label.setWordWrap(True)
        self.distance_label.setMinimumWidth(80)
        bar.addWidget(self.distance_label, 1)
        dl.addLayout(bar)
        dl.addWidget(self.disk, 1)
        split = QSplitter(Qt.Horizontal)
        split.addWidget(self.plane)
        split.addWidget(disk_box)
        split.setStretchFactor(0, 1)
        split.setStretchFactor(1, 1)
        split.setSizes([500, 500])
        self.setCentralWidget(split)

        self._build_docks()
        self._build_menus()
        self.warning_label = QLabel("")
        self.warning_label.setObjectName("warning_label")
        self.warning_label.setStyleSheet("color: #c00000; font-weight: bold")
        self.statusBar().addPermanentWidget(self.warning_label)
        self.coord_label = QLabel("")
        self.coord_label.setObjectName("coord_label")
        self.coord_label.setMinimumWidth(190)
        self.statusBar().addPermanentWidget(self.coord_label)

        self.plane.mouse.connect(self._on_plane_mouse)
        self.disk.mouse.connect(self._on_disk_mouse)
        self.disk.capture_left = True
        self.disk.set_overlay("circle", LayerGeometry("unit_circle", "disk", [unit_circle_part()]))
        self._draw_tessellation()
        self.disk.reset_view((-1.08, 1.08, -1.08, 1.08), keep=True)
        self.reset_plane_view()
        self._refresh_polygon()

    # ================================================================== UI construction
    def _build_docks(self) -> None:
        self.layer_panel = LayerPanel()
        self.layer_panel.toggled.connect(self._on_layer_toggled)
        self.layer_panel.color_changed.connect(
            lambda v, n, c: (self._view(v).set_color(n, c), self._view(v).render())
        )
        self.layer_panel.opacity_changed.connect(
            lambda v, n, o: (self._view(v).set_opacity(n, o), self._view(v).render())
        )
        self.layer_panel.color_mode_changed.connect(self.set_color_mode)
        for view in (self.plane, self.disk):
            for name in layer_names(view.view):
                view.layers.setdefault(name, LayerState()).visible = DEFAULT_VISIBLE[name]
        for name, color in LAYER_COLORS.items():
            self.layer_panel.set_swatch(name, color)
        self.legend = LegendPanel()
        self.layer_panel.layout().insertWidget(self.layer_panel.layout().count() - 1, self.legend)
        self.layer_scroll = _scrolled(self.layer_panel, 270)
        self._add_dock("Layers", self.layer_scroll, Qt.LeftDockWidgetArea)

        # drawing
        draw = QWidget()
        f = QFormLayout(draw)
        self.draw_check = QCheckBox("Draw / edit polygon")
        self.draw_check.setToolTip(
            "click: add a vertex · click the first vertex or double-click: close · "
            "drag a vertex: move it · Delete: remove the selected vertex"
        )
        self.draw_check.toggled.connect(self.set_draw_mode)
        f.addRow(self.draw_check)
        self.snap_check = QCheckBox("Snap to grid")
        self.snap_check.toggled.connect(self.set_snap)
        self.grid_spin = QDoubleSpinBox()
        self.grid_spin.setRange(0.001, 1000.0)
        self.grid_spin.setDecimals(3)
        self.grid_spin.setValue(self.editor.grid)
        self.grid_spin.valueChanged.connect(lambda g: self.set_snap(self.editor.snap, g))
        f.addRow(self.snap_check, self.grid_spin)
        row = QGridLayout()
        self.draw_buttons: dict[str, QPushButton] = {}
        for k, (text, slot) in enumerate(
            (
                ("Undo", self.undo),
                ("Redo", self.redo),
                ("Delete", self.delete_selected),
                ("Clear", self.clear_polygon),
            )
        ):
            b = QPushButton(text)
            b.setObjectName(f"{text.lower()}_button")
            _on_click(b, slot)
            self.draw_buttons[text.lower()] = b
            row.addWidget(b, k // 2, k % 2)
        f.addRow(row)
        self.draw_scroll = _scrolled(draw, 270)
        self._add_dock("Draw", self.draw_scroll, Qt.LeftDockWidgetArea)

        # mesh parameters and progress
        mesh = QWidget()
        mf = QFormLayout(mesh)
        self.option_widgets: dict[str, QSpinBox | QDoubleSpinBox | QCheckBox | QLineEdit] = {}
        defaults = MeshOptions()
        self.method_combo = QComboBox()
        self.method_combo.setObjectName("method_combo")
        for method in METHODS:
            self.method_combo.addItem(METHOD_TITLES.get(method, method), method)
        self.method_combo.setCurrentIndex(METHODS.index(defaults.method))
        self.method_combo.setToolTip(METHOD_TIP)
        # a row of its own across the panel: its longest item would widen the field column
        mrow = QHBoxLayout()
        method_label = QLabel("Method")
        method_label.setToolTip(METHOD_TIP)
        mrow.addWidget(method_label)
        mrow.addWidget(self.method_combo, 1)
        mf.addRow(mrow)
        self.block_size_spin = QDoubleSpinBox()
        self.block_size_spin.setObjectName("block_size_spin")
        self.block_size_spin.setDecimals(3)
        self.block_size_spin.setRange(0.005, 1.0)
        self.block_size_spin.setSingleStep(0.01)
        self.block_size_spin.setValue(DEFAULT_BLOCK_FRACTION)
        self.block_size_spin.setSuffix(" d")  # as in quadmesh mesh --size 0.05d
        self.option_widgets["size"] = self.block_size_spin
        mf.addRow("Block size", self.block_size_spin)
        mf.labelForField(self.block_size_spin).setToolTip(OPTION_TIPS["size"])
        # a note on the last run that is not a failure (why Blocks fell back to the paper's
        # construction), under the method it is about; hidden when there is none
        self.note_label = QLabel("")
        self.note_label.setObjectName("note_label")
        self.note_label.setWordWrap(True)
        self.note_label.setStyleSheet("color: #8a4b00")
        self.note_label.setTextInteractionFlags(Qt.TextSelectableByMouse)
        self.note_label.hide()
        mf.addRow(self.note_label)
        for name, (label, kind, lo, hi, step, dec) in _OPTION_SPECS.items():
            if not hasattr(defaults, name):
                continue
            if kind == "int":
                w: QSpinBox | QDoubleSpinBox = QSpinBox()
                w.setRange(int(lo), int(hi))
            else:
                w = QDoubleSpinBox()
                w.setDecimals(dec)
                w.setRange(lo, hi)
                w.setSingleStep(step)
            w.setValue(getattr(defaults, name))
            self.option_widgets[name] = w
            mf.addRow(label, w)
            mf.labelForField(w).setToolTip(OPTION_TIPS[name])
        self.tol_edit = QLineEdit(f"{defaults.conformal_tol:g}")
        self.tol_edit.setValidator(QDoubleValidator(1e-16, 1e-2, 20))
        self.option_widgets["conformal_tol"] = self.tol_edit
        mf.addRow("conformal tolerance", self.tol_edit)
        mf.labelForField(self.tol_edit).setToolTip(OPTION_TIPS["conformal_tol"])
        self.adaptive_check = QCheckBox("adaptive n")
        self.adaptive_check.setChecked(defaults.adaptive)
        self.option_widgets["adaptive"] = self.adaptive_check
        mf.addRow(self.adaptive_check)
        self.repair_check = QCheckBox("local angle repair (off: raise n)")
        self.repair_check.setChecked(defaults.repair)
        self.option_widgets["repair"] = self.repair_check
        mf.addRow(self.repair_check)
        for name, w in self.option_widgets.items():
            w.setToolTip(OPTION_TIPS[name])
        self.method_combo.currentIndexChanged.connect(lambda _i: self._method_changed())
        self._method_changed()
        brow = QHBoxLayout()
        self.mesh_button = QPushButton("Mesh")
        self.mesh_button.setObjectName("mesh_button")
        self.mesh_button.setToolTip("mesh the closed polygon with these settings (Ctrl+M)")
        _on_click(self.mesh_button, self.start_mesh)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.setObjectName("cancel_button")
        self.cancel_button.setToolTip("stop the running mesher (Escape)")
        _on_click(self.cancel_button, self.cancel_mesh)
        brow.addWidget(self.mesh_button)
        brow.addWidget(self.cancel_button)
        mf.addRow(brow)
        self.progress_bar = QProgressBar()
        self.progress_bar.setRange(0, 1000)
        self.progress_bar.setValue(0)
        self.progress_bar.setFormat("idle")
        self.progress_bar.setToolTip("the stage running and the fraction of the run done")
        mf.addRow(self.progress_bar)
        # the whole message of the last failure, wrapped and scrollable (hidden when none)
        self.error_box = ErrorBox()
        mf.addRow(self.error_box)
        self.mesh_scroll = _scrolled(mesh, 290)
        mesh_dock = self.mesh_dock = self._add_dock(
            "Mesh", self.mesh_scroll, Qt.RightDockWidgetArea
        )

        # information
        info = QWidget()
        il = QVBoxLayout(info)
        # the histogram first: it stays in view without scrolling however long the table is
        il.addWidget(QLabel("new angles (green band: [60°, 120°])"))
        self.histogram = AngleHistogram()
        il.addWidget(self.histogram)
        self.info_label = QLabel("no mesh yet")
        self.info_label.setObjectName("info_label")
        self.info_label.setTextFormat(Qt.RichText)
        self.info_label.setWordWrap(True)
        self.info_label.setAlignment(Qt.AlignTop | Qt.AlignLeft)
        self.info_label.setTextInteractionFlags(Qt.TextSelectableByMouse)
        il.addWidget(self.info_label)
        self.quad_label = QLabel("click a quad of the mesh to see its angles")
        self.quad_label.setObjectName("quad_label")
        self.quad_label.setWordWrap(True)
        self.quad_label.setTextInteractionFlags(Qt.TextSelectableByMouse)
        il.addWidget(self.quad_label)
        il.addStretch(1)
        scroll = self.info_scroll = _scrolled(info, 300)
        info_dock = self.info_dock = self._add_dock("Information", scroll, Qt.RightDockWidgetArea)
        self.resizeDocks([mesh_dock, info_dock], [mesh.sizeHint().height(), 400], Qt.Vertical)

    def _add_dock(self, title: str, widget: QWidget, area: Qt.DockWidgetArea) -> QDockWidget:
        d = QDockWidget(title, self)
        d.setObjectName(f"dock_{title.lower()}")
        d.setWidget(widget)
        d.setFeatures(QDockWidget.DockWidgetMovable | QDockWidget.DockWidgetFloatable)
        self.addDockWidget(area, d)
        return d

    def _build_menus(self) -> None:
        mb = self.menuBar()
        fm = mb.addMenu("&File")
        self._action(fm, "&New polygon", self.new_polygon, QKeySequence.New)
        self._action(fm, "&Open polygon or mesh…", self._open_dialog, QKeySequence.Open)
        self.recent_menu = fm.addMenu("Open &recent")
        self._fill_recent_menu()
        self._action(fm, "&Save polygon…", self._save_dialog, QKeySequence.Save)
        self._action(fm, "&Export mesh…", self._export_dialog, "Ctrl+E")
        self._action(fm, "Save &window screenshot…", self._screenshot_dialog, "Ctrl+P")
        fm.addSeparator()
        self._action(fm, "&Quit", self.close, QKeySequence.Quit)
        em = mb.addMenu("&Edit")
        self._action(em, "&Undo", self.undo, QKeySequence.Undo)
        self._action(em, "&Redo", self.redo, QKeySequence.Redo)
        self._action(em, "&Delete vertex", self.delete_selected, QKeySequence.Delete)
        self._action(em, "&Clear polygon", self.clear_polygon)
        em.addSeparator()
        self._action(em, "&Enter coordinates…", self.enter_coordinates, "Ctrl+K")
        self.examples_menu = mb.addMenu("E&xamples")
        self._fill_examples_menu()
        vm = mb.addMenu("&View")
        self._action(vm, "&Reset plane view", self.reset_plane_view, "R")
        self._action(vm, "Reset &disk view", self.reset_disk_transform)
        mm = mb.addMenu("&Mesh")
        self._action(mm, "&Mesh polygon", self.start_mesh, "Ctrl+M")
        self._action(mm, "&Cancel", self.cancel_mesh, "Escape")
        hm = mb.addMenu("&Help")
        self.help_menu = hm
        self._action(hm, "&Keyboard shortcuts…", self.show_shortcuts, QKeySequence.HelpContents)

    def _action(self, menu: Any, text: str, slot: Any, shortcut: Any = None) -> QAction:
        a = QAction(text, self)
        if shortcut is not None:
            a.setShortcut(QKeySequence(shortcut))
        a.triggered.connect(lambda _=False: slot())
        menu.addAction(a)
        return a

    def _fill_examples_menu(self) -> None:
        try:
            from quadmesh.examples import example_names
        except ImportError as exc:
            a = self.examples_menu.addAction(f"(bundled examples unavailable: {exc})")
            a.setEnabled(False)
            return
        for name in example_names():
            a = QAction(name, self)
            a.triggered.connect(lambda _=False, n=name: self._example_chosen(n))
            self.examples_menu.addAction(a)

    # ------------------------------------------------------------------ recent files
    def recent_files(self) -> list[str]:
        """Files opened lately, newest first (at most 8, remembered across sessions)."""
        value = self.settings.value("recent_files", [])
        if isinstance(value, str):  # QSettings gives a lone string for a one-item list
            value = [value]
        return [str(v) for v in (value or []) if v][:_RECENT_MAX]

    def _add_recent(self, path: str | Path) -> None:
        p = str(Path(path).resolve())
        files = [p] + [f for f in self.recent_files() if f != p]
        self.settings.setValue("recent_files", files[:_RECENT_MAX])
        self.settings.sync()
        self._fill_recent_menu()

    def _fill_recent_menu(self) -> None:
        self.recent_menu.clear()
        files = self.recent_files()
        for k, f in enumerate(files, start=1):
            a = QAction(f"&{k} {Path(f).name}", self)
            a.setToolTip(f)
            a.setStatusTip(f)
            a.setData(f)
            a.triggered.connect(lambda _=False, f=f: self.open_recent(f))
            self.recent_menu.addAction(a)
        self.recent_menu.setEnabled(bool(files))

    def open_recent(self, path: str) -> None:
        """Open a file of the Open recent menu; a file that is gone leaves the list."""
        if not Path(path).is_file():
            files = [f for f in self.recent_files() if f != path]
            self.settings.setValue("recent_files", files)
            self.settings.sync()
            self._fill_recent_menu()
            self._show_error(f"{path} no longer exists; removed it from the recent files")
            return
        if self.confirm_discard(f"open {Path(path).name}"):
            self._guarded(f"opening {Path(path).name}", self.open_file, path)

    # ------------------------------------------------------------------ help
    def shortcut_table(self) -> list[tuple[str, str]]:
        """(shortcut, what it does) for every action of the window that has a shortcut,
        read from the actions themselves, in menu order."""
        rows: list[tuple[str, str]] = []
        seen: set[int] = set()

        def walk(actions: list[QAction]) -> None:
            for a in actions:
                if id(a) in seen:
                    continue
                seen.add(id(a))
                if a.menu() is not None:
                    walk(a.menu().actions())
                elif not a.shortcut().isEmpty():
                    keys = a.shortcut().toString(QKeySequence.NativeText)
                    rows.append((keys, a.text().replace("&", "").rstrip("…")))

        walk(self.menuBar().actions())
        walk(self.actions())
        return rows

    def show_shortcuts(self) -> None:
        """Help ▸ Keyboard shortcuts: a dialog listing :meth:`shortcut_table` and the mouse
        gestures of the two views."""
        rows = [
            *self.shortcut_table(),
            ("Delete / Backspace", "delete the selected vertex (draw mode)"),
            ("left click (plane)", "draw mode: add a vertex; otherwise: show the quad's angles"),
            ("left drag (plane)", "draw mode: move a vertex; otherwise: pan"),
            ("middle drag / wheel", "pan / zoom"),
            ("left drag (disk)", "move the point to the centre by a disk automorphism"),
            ("left click (disk)", "pick two points: hyperbolic distance and geodesic"),
        ]
        dlg = QDialog(self)
        dlg.setObjectName("shortcuts_dialog")
        dlg.setWindowTitle("Keyboard shortcuts and mouse")
        dlg.setAttribute(Qt.WA_DeleteOnClose)
        lay = QVBoxLayout(dlg)
        table = QTableWidget(len(rows), 2, dlg)
        table.setObjectName("shortcuts_table")
        table.setHorizontalHeaderLabels(["keys", "action"])
        table.verticalHeader().hide()
        table.setEditTriggers(QTableWidget.NoEditTriggers)
        for r, (k, what) in enumerate(rows):
            table.setItem(r, 0, QTableWidgetItem(k))
            table.setItem(r, 1, QTableWidgetItem(what))
        table.resizeColumnsToContents()
        table.horizontalHeader().setStretchLastSection(True)
        lay.addWidget(table)
        buttons = QDialogButtonBox(QDialogButtonBox.Close, parent=dlg)
        buttons.rejected.connect(dlg.reject)
        lay.addWidget(buttons)
        dlg.resize(520, 420)
        self.shortcuts_dialog = dlg
        dlg.open()

    def _put(
        self, view: View2D, name: str, geometry: LayerGeometry | None, *, park: bool = False
    ) -> None:
        """Set a layer's geometry and show its flat colour on the layer panel's swatch
        (``park``: see :meth:`View2D.set_layer`)."""
        view.set_layer(name, geometry, park=park)
        if view is self.plane and name in ("polygon", "final_mesh"):
            self._update_fill()
        st = view.layers[name]
        if geometry is not None and st.color is None:
            flat = [p.color for p in geometry.parts if p.scalars is None and p.color]
            if flat and name in LAYER_COLORS:
                self.layer_panel.set_swatch(name, LAYER_COLORS[name])

    def _update_fill(self) -> None:
        """Show the polygon's light fill only while no final mesh (nor a failed run's partial
        stages) is on screen: drawn over them it would wash out their colours."""
        st = self.plane.layers.get("polygon")
        fm = self.plane.layers.get("final_mesh")
        if st is None or st.geometry is None:
            return
        mesh_on = fm is not None and fm.visible and fm.geometry is not None
        mesh_on = mesh_on or "partial" in self.plane.overlays
        st.hidden = frozenset({"fill"}) if mesh_on else frozenset()
        self.plane.show_layer_parts("polygon")

    def _view(self, view: str) -> View2D:
        return self.plane if view == "plane" else self.disk

    # ================================================================== polygon input
    def set_polygon(self, z: np.ndarray) -> None:
        """Replace the drawing by a polygon and fit the view to it.  A valid polygon is taken
        in its normalised (counter-clockwise) form; an invalid one is kept as it is, with the
        warning shown, so that it can be repaired by editing."""
        try:
            z = validate_polygon(z).z
        except PolygonError:
            z = np.asarray(z, dtype=np.complex128).ravel()
        self.editor.set_polygon(z)
        self._polygon_changed()
        self.reset_plane_view()

    def load_example(self, name: str) -> None:
        """Load a bundled example polygon (Examples menu)."""
        from quadmesh.examples import load_example

        self.set_polygon(_points_of(load_example(name)))
        self._mark_clean()
        self.statusBar().showMessage(f"example {name!r} loaded", 5000)

    def _example_chosen(self, name: str) -> None:
        if self.confirm_discard(f"load the example {name!r}"):
            self.load_example(name)

    # ------------------------------------------------------------------ unsaved drawings
    def _mark_clean(self) -> None:
        """Remember the drawing as saved (or freshly loaded): nothing to lose yet."""
        self._clean_state = (tuple(self.editor.points), self.editor.closed)

    def has_unsaved_polygon(self) -> bool:
        """True when the drawing has vertices that were drawn, edited or typed in since the
        polygon was last loaded or saved."""
        ed = self.editor
        return bool(ed.points) and (tuple(ed.points), ed.closed) != self._clean_state

    def confirm_discard(self, action: str) -> bool:
        """Ask before ``action`` throws away an unsaved drawn polygon; True to go on.
        Without popups (tests, scripted runs) the answer is yes."""
        if not self.popups or not self.has_unsaved_polygon():
            return True
        n = len(self.editor.points)
        answer = QMessageBox.question(
            self,
            "Discard the drawn polygon?",
            f"The polygon you drew ({n} vertices) is not saved.\nDiscard it and {action}?",
            QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel,
            QMessageBox.StandardButton.Cancel,
        )
        return answer == QMessageBox.StandardButton.Discard

    def new_polygon(self) -> None:
        """Start an empty drawing in draw mode (asks first over an unsaved drawing)."""
        if not self.confirm_discard("start a new polygon"):
            return
        self.clear_polygon()
        self._mark_clean()
        self.set_draw_mode(True)

    def enter_coordinates(self) -> None:
        """Open the Enter coordinates dialog (typed or pasted vertices); on OK the polygon
        is replaced by them (asks first over an unsaved drawing)."""
        from .coords import CoordinatesDialog

        text = "\n".join(f"{p.real:.17g} {p.imag:.17g}" for p in self.editor.points)
        dlg = CoordinatesDialog(text, parent=self)
        self.coordinates_dialog = dlg

        def done() -> None:
            if dlg.vertices is not None and self.confirm_discard("use the typed coordinates"):
                self.set_coordinates(dlg.vertices)

        dlg.accepted.connect(done)
        dlg.open()

    def set_coordinates(self, z: np.ndarray) -> None:
        """Replace the drawing by typed vertices (closed; undoable; unsaved)."""
        self.set_polygon(np.asarray(z, dtype=np.complex128))
        self.statusBar().showMessage(f"{len(self.editor.points)} vertices entered", 5000)

    def open_polygon(self, path: str | Path) -> None:
        """Read a polygon file (JSON, CSV/TXT, GeoJSON, SVG path) with quadmesh.io."""
        from quadmesh.io import read_polygon

        vertices, notes = read_polygon(path)
        self.set_polygon(_points_of(vertices))
        self._mark_clean()
        self.statusBar().showMessage("; ".join([f"opened {path}", *notes]), 8000)

    def open_file(self, path: str | Path) -> None:
        """Open a polygon or a mesh file: meshes (JSON with "quads", VTK, VTU, Gmsh, OBJ, PLY,
        Medit) are shown as meshes (:meth:`open_mesh`), anything else is read as a polygon."""
        if is_mesh_file(path):
            self.open_mesh(path)
        else:
            self.open_polygon(path)
        self._add_recent(path)

    def open_mesh(self, path: str | Path) -> None:
        """Read a quad mesh file with quadmesh.io and show it (:meth:`show_mesh`)."""
        from quadmesh.io import read_mesh

        self.show_mesh(read_mesh(path), Path(path).name)
        m = self.loaded_mesh
        self.statusBar().showMessage(
            f"opened mesh {path}: {m.n_quads} quads, {m.n_vertices} vertices", 8000
        )

    def show_mesh(self, mesh: QuadMesh, name: str = "mesh") -> None:
        """Show a quad mesh that did not come from meshing here (no polygon, no pieces): the
        final-mesh and bad-quad layers, its angle statistics and histogram.  The drawing is
        cleared (undoable); drawing a new polygon removes the mesh again."""
        from types import SimpleNamespace

        if self.editor.points:
            self.editor.clear()
            self._selected = None
        self._drop_result("")
        self._clear_error()
        self._refresh_polygon()
        self._mark_clean()
        quality = mesh.quality()
        # the result-like object the layer builders of quadmesh.render need
        loaded = SimpleNamespace(mesh=mesh, polygon=None, quality=quality, origin=0j)
        self.loaded_mesh, self._loaded = mesh, loaded
        self._forget_picked_quad()
        self._put(self.plane, "final_mesh", self._mesh_layer(loaded, self.color_mode))
        self._put(self.plane, "bad_quads", build_layer(loaded, "bad_quads"))
        q = quality
        rows = [
            ("mesh file", html_escape(name)),
            ("quads", f"{q.n_quads}"),
            ("vertices", f"{q.n_vertices}"),
            ("min angle", f"{q.min_angle:.3f}°"),
            ("max angle", f"{q.max_angle:.3f}°"),
            ("outside [60°,120°]", f"{q.n_angles_outside}"),
        ]
        if q.n_original:
            rows.append(("corners < 60° in one quad (kept)", f"{q.n_original}"))
        html = "<table>" + "".join(f"<tr><td>{k}</td><td><b>{v}</b></td></tr>" for k, v in rows)
        html += "</table><p>opened from a file: no polygon, pieces or timings</p>"
        self.info_label.setText(html)
        self.histogram.set_data(q.histogram, q.bin_edges)
        self.reset_plane_view()
        self.plane.render()

    def save_polygon(self, path: str | Path) -> None:
        """Write the current (closed, valid) polygon with quadmesh.io."""
        from quadmesh.io import write_polygon

        if not self.editor.closed:
            raise QuadmeshError("close the polygon before saving it", stage="io")
        write_polygon(path, validate_polygon(self.editor.z).vertices)

    # ================================================================== drawing
    def set_draw_mode(self, on: bool) -> None:
        """In draw mode the left button draws and edits; otherwise it pans."""
        if self.draw_check.isChecked() != on:
            self.draw_check.setChecked(on)
            return
        self.plane.capture_left = on
        if on:
            self.statusBar().showMessage(self.draw_check.toolTip(), 15000)
        self._rubber_band(None)
        self._refresh_polygon()

    def set_snap(self, on: bool, grid: float | None = None) -> None:
        """Snap new and moved vertices to a grid of the given spacing; show the grid lines
        (at most 200 of them, over the visible part of the plane) while snapping is on."""
        self.editor.snap = on
        if grid is not None:
            self.editor.grid = grid
        geo = None
        if on:
            g = self.editor.grid
            cam = self.plane.plotter.camera
            cx, cy, _ = cam.focal_point
            hh = cam.parallel_scale
            hw = hh * self.plane.plotter.width() / max(self.plane.plotter.height(), 1)
            i0, i1 = int(np.floor((cx - hw) / g)), int(np.ceil((cx + hw) / g))
            j0, j1 = int(np.floor((cy - hh) / g)), int(np.ceil((cy + hh) / g))
            if (i1 - i0) + (j1 - j0) <= 200:
                xs, ys = np.arange(i0, i1 + 1) * g, np.arange(j0, j1 + 1) * g
                lines = [np.array([x + 1j * ys[0], x + 1j * ys[-1]]) for x in xs]
                lines += [np.array([xs[0] + 1j * y, xs[-1] + 1j * y]) for y in ys]
                geo = LayerGeometry(
                    "grid", "plane", [line_part(lines, color="#d8d8d8", label="grid")]
                )
        self.plane.set_overlay("grid", geo)
        self.plane.render()

    def _on_plane_mouse(self, kind: str, w: complex, modifiers: int) -> None:
        if kind == "hover":
            self.coord_label.setText(f"x = {w.real:.6g}, y = {w.imag:.6g}")
        if kind == "click":
            self.pick_quad(w)
            return
        tol = 8.0 * self.plane.pixel_size()
        ed = self.editor
        if kind == "press":
            i = ed.nearest(w, tol)
            if i == 0 and not ed.closed and len(ed.points) >= 3:
                ed.close()
                self._selected = None
            elif i is not None:
                self._selected = i
                self._drag_vertex = i
                ed.begin_move()
            elif ed.add(w):
                self._selected = len(ed.points) - 1
            else:
                return
            self._polygon_changed()
        elif kind == "drag" and self._drag_vertex is not None:
            ed.move(self._drag_vertex, w)
            self._polygon_changed(light=True)
        elif kind == "release" and self._drag_vertex is not None:
            ed.end_move()
            self._drag_vertex = None
            self._polygon_changed()
        elif kind == "dblclick":
            if ed.close():
                self._selected = None
                self._polygon_changed()
        elif kind == "hover":
            self._rubber_band(w)

    # ------------------------------------------------------------------ quad picking
    def _shown_shift(self) -> complex:
        """Where the shown mesh's vertex coordinates are relative to (MeshResult.mesh_origin)."""
        if self.result is not None:
            return complex(getattr(self.result, "mesh_origin", 0j) or 0j)
        return 0j

    def quad_at(self, w: complex) -> int | None:
        """Index of the quad of the mesh on screen that contains the plane point ``w`` (the
        first one when ``w`` is on a shared edge), None outside the mesh."""
        mesh = self.shown_mesh()
        if mesh is None or mesh.n_quads == 0:
            return None
        c = mesh.z[mesh.quads]  # (Q, 4) corners, counter-clockwise
        p = complex(w) - self._shown_shift()
        e = np.roll(c, -1, axis=1) - c
        d = p - c
        cross = e.real * d.imag - e.imag * d.real
        tol = 1e-12 * np.abs(e) * (np.abs(d) + np.abs(e))
        inside = np.flatnonzero(np.all(cross >= -tol, axis=1))
        return int(inside[0]) if inside.size else None

    def quad_info(self, k: int) -> dict[str, Any]:
        """What the app tells about quad ``k`` of the mesh on screen: its four corner angles
        (degrees, at ``quads[k, 0..3]``), the worst |angle − 90°|, and, for a meshed result,
        its stage kind ("disk", "sector", "channel", "corridor", "block") and the part it came
        from (for a block mesh: the coarse cell of the block layout that holds it)."""
        from quadmesh.io import STAGE_KINDS, quad_part_index

        mesh = self.shown_mesh()
        ang = np.asarray(mesh.angles()[k], dtype=np.float64)
        info: dict[str, Any] = {
            "quad": k,
            "angles": ang,
            "worst": float(np.abs(ang - 90.0).max()),
            "stage": None,
            "piece": None,
            "part": None,
        }
        r = self.result
        if r is None or mesh is not r.mesh:
            return info
        src = getattr(r, "quad_source", None)
        if src is not None and len(src) == mesh.n_quads:
            info["stage"] = STAGE_KINDS.get(int(src[k]), str(int(src[k])))
        if getattr(r, "blocks", None) is not None:
            cell = self._block_cell_of(mesh.z[mesh.quads[k]].mean())
            if cell is not None:
                info["piece"] = cell
                info["part"] = f"coarse cell {cell} of the block layout"
            elif r.blocks.kind == "ladder":
                info["part"] = "a round end or bend of the corridor (a vertex sector)"
            elif src is not None and len(src) == mesh.n_quads and int(src[k]) != 4:
                info["part"] = "a face meshed by the paper's construction (no blocks there)"
            return info
        part = quad_part_index(r)
        if part is not None:
            j = int(part[k])
            info["piece"] = j
            info["part"] = self._describe_part(j)
        return info

    def _block_cell_of(self, w: complex) -> int | None:
        """The coarse cell of the result's block layout that holds the mesh point ``w`` (mesh
        coordinates; the cells are convex and counter-clockwise), None if none does."""
        r = self.result
        lay = r.blocks
        p = complex(w) + complex(r.mesh_origin or 0j) - complex(r.origin or 0j)
        c = np.asarray(lay.points, dtype=np.complex128)[np.asarray(lay.cells, dtype=np.int64)]
        e = np.roll(c, -1, axis=1) - c
        d = p - c
        cross = e.real * d.imag - e.imag * d.real
        inside = np.flatnonzero(np.all(cross >= -1e-9 * np.abs(e) ** 2, axis=1))
        return int(inside[0]) if inside.size else None

    def _describe_part(self, j: int) -> str:
        r = self.result
        if j < len(r.pieces):
            return f"thick piece {r.pieces[j].index}"
        t = r.thin[j - len(r.pieces)]
        title = THIN_KIND_TITLES.get(t.kind, t.kind)
        collar = " (conformal collar)" if type(t.mesh).__name__ == "CollarMesh" else ""
        if t.kind == "parabolic":
            poly = getattr(r.decomposition, "polygon", None) or r.polygon
            try:
                where = poly.describe_vertex(t.owner)
            except (AttributeError, IndexError, TypeError):
                where = f"vertex {t.owner}"
            return f"{title} at {where}{collar}"
        if t.kind == "hyperbolic":
            return f"{title} {t.owner}{collar}"
        return title

    def pick_quad(self, w: complex) -> int | None:
        """Show the angles, stage kind and part of the quad under ``w`` (information panel and
        status bar) and outline it; returns its index (None: no quad there)."""
        k = self.quad_at(w)
        if k is None:
            self.picked_quad = None
            self.plane.set_overlay("picked_quad", None)
            if self.shown_mesh() is not None:
                self.quad_label.setText(f"no quad at ({w.real:.6g}, {w.imag:.6g})")
            self.plane.render()
            return None
        info = self.quad_info(k)
        self.picked_quad = info
        angles = ", ".join(f"{a:.2f}°" for a in info["angles"])
        text = f"quad {k}: angles {angles}; worst |θ − 90°| = {info['worst']:.2f}°"
        if info["stage"] is not None:
            text += f"; stage: {info['stage']}"
        if info["part"] is not None and info["stage"] == "block":
            text += f"; {info['part']}"
        elif info["part"] is not None:
            text += f"; piece {info['piece']}: {info['part']}"
        self.quad_label.setText(text)
        self.statusBar().showMessage(text, 15000)
        mesh = self.shown_mesh()
        corners = mesh.z[mesh.quads[k]] + self._shown_shift()
        part = line_part([corners], color="#ff7f0e", line_width=4.0, closed=True, label="quad")
        self.plane.set_overlay("picked_quad", LayerGeometry("picked_quad", "plane", [part]))
        self.plane.render()
        return k

    def _rubber_band(self, w: complex | None) -> None:
        """Thin line from the last vertex to the cursor while an open polygon is drawn."""
        ed = self.editor
        if w is None or ed.closed or not ed.points or not self.draw_check.isChecked():
            if "rubber" in self.plane.overlays:
                self.plane.set_overlay("rubber", None)
                self.plane.render()
            return
        part = line_part(
            [np.array([ed.points[-1], ed.snapped(w)])], color="#555555", label="rubber"
        )
        self.plane.set_overlay("rubber", LayerGeometry("rubber", "plane", [part]))
        self.plane.render()

    def undo(self) -> None:
        """Undo the last drawing edit."""
        if self.editor.undo():
            self._selected = None
            self._polygon_changed()

    def redo(self) -> None:
        """Redo the last undone drawing edit."""
        if self.editor.redo():
            self._selected = None
            self._polygon_changed()

    def delete_selected(self) -> None:
        """Delete the selected vertex (the last one clicked or added)."""
        if self._selected is not None and self.editor.delete(self._selected):
            self._selected = None
            self._polygon_changed()

    def clear_polygon(self) -> None:
        """Remove the whole drawing (undoable)."""
        self.editor.clear()
        self._selected = None
        self._polygon_changed()

    def _polygon_changed(self, light: bool = False) -> None:
        """After any edit or load: drop a result that no longer matches, forget the last
        failure and the disk view's picked points, redraw the polygon."""
        if (self.result is not None and self._result_polygon_differs()) or (
            self.loaded_mesh is not None and self.editor.points
        ):
            self._drop_result("the polygon changed; mesh again")
        self._clear_error()
        if self.picked:
            self.picked = []
            self._draw_picked()
            self.distance_label.setText(_DISK_HINT)
            self.disk.render()
        self._refresh_polygon()

    def _result_polygon_differs(self) -> bool:
        if not self.editor.closed:
            return True
        rz = np.asarray(self.result.polygon.z)
        z = self.editor.z
        return rz.shape != z.shape or not np.allclose(np.sort_complex(rz), np.sort_complex(z))

    def _refresh_polygon(self) -> None:
        ed = self.editor
        problem = ed.problem()
        self.warning_label.setText(f"⚠ {problem}" if problem else "")
        color = "#c00000" if problem else "black"
        self._put(self.plane, "polygon", polygon_layer(ed.z, closed=ed.closed, color=color))
        sel = None
        if (
            self._selected is not None
            and self._selected < len(ed.points)
            and self.draw_check.isChecked()
        ):
            sel = LayerGeometry(
                "selection",
                "plane",
                [
                    LayerPart(
                        polygon_layer(ed.z[[self._selected]], closed=False).part("vertices").mesh,
                        color="#ff7f0e",
                        style="points",
                        point_size=14.0,
                        label="selected",
                    )
                ],
            )
        self.plane.set_overlay("selection", sel)
        if ed.closed:
            self.plane.set_overlay("rubber", None)
        self.mesh_button.setEnabled(ed.closed and problem is None and not self.runner.busy)
        self.plane.render()

    # ================================================================== meshing
    def mesh_options(self) -> MeshOptions:
        """MeshOptions from the parameter controls (ValueError if they are inconsistent)."""
        kw: dict[str, Any] = {}
        method = self.method
        for name, w in self.option_widgets.items():
            if name == "size":
                continue
            if isinstance(w, QCheckBox):
                kw[name] = w.isChecked()
            elif isinstance(w, QLineEdit):
                kw[name] = float(w.text())
            else:
                kw[name] = w.value()
        kw["n"] = int(kw["n"])
        kw["max_n"] = int(kw["max_n"])
        kw["rotations"] = int(kw["rotations"])
        kw["method"] = method
        if method == "blocks":
            kw["size"] = self.block_size()
        valid = {f.name for f in dataclasses.fields(MeshOptions)}
        return MeshOptions(**{k: v for k, v in kw.items() if k in valid})

    @property
    def method(self) -> str:
        """The meshing method chosen in the Mesh panel (``MeshOptions.method``)."""
        return str(self.method_combo.currentData())

    def block_size(self) -> float | None:
        """``MeshOptions.size`` of the Block size control: its fraction times the diameter of
        the polygon drawn (its bounding box diagonal, the "d" of ``quadmesh mesh --size 0.05d``);
        None while there is no polygon to measure."""
        z = self.editor.z
        if z.size < 2:
            return None
        d = float(np.hypot(np.ptp(z.real), np.ptp(z.imag)))
        return self.block_size_spin.value() * d if d > 0 else None

    def _method_changed(self) -> None:
        """Blocks: the Block size control on, the paper's settings off (and back)."""
        blocks = self.method == "blocks"
        self.block_size_spin.setEnabled(blocks)
        for name in BISHOP_ONLY:
            w = self.option_widgets.get(name)
            if w is not None:
                w.setEnabled(not blocks)

    def start_mesh(self, job: Any = None) -> bool:
        """Start meshing the current polygon in the worker thread (or run ``job(progress,
        cancel)`` instead, which must return a MeshResult).  Returns False if it cannot start."""
        if self.runner.busy:
            return False
        if not self.editor.closed or self.editor.problem():
            why = self.editor.problem() or "close the polygon first"
            if not self.editor.points and self.loaded_mesh is not None:
                why = "the mesh on screen was opened from a file; open or draw a polygon to mesh"
            self._show_error(why)
            return False
        try:
            options = self.mesh_options()
        except ValueError as exc:
            self._show_error(f"invalid parameters: {exc}")
            return False
        z = self.editor.z.copy()
        if job is None:
            from quadmesh.pipeline import mesh_polygon

            def job(progress: Any, cancel: Any) -> Any:
                return mesh_polygon(z, options, progress=progress, cancel=cancel)

        self._job_polygon = tuple(self.editor.points)
        self._clear_error()
        self._set_note(None)
        self.mesh_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.progress_bar.setValue(0)
        self.progress_bar.setFormat("starting… %p%")
        self.runner.start(job)
        return True

    def cancel_mesh(self) -> None:
        """Ask the running mesher to stop."""
        if self.runner.busy:
            self.progress_bar.setFormat("cancelling…")
            self.runner.cancel()

    def wait_for_mesh(self, timeout_ms: int = 600000) -> bool:
        """Process events until the running job ends; True if it ended in time."""
        if not self.runner.busy:
            return True
        loop = QEventLoop()
        self.runner.idle.connect(loop.quit)
        timer = QTimer(loop)  # owned by the loop: never fires after it is gone
        timer.setSingleShot(True)
        timer.timeout.connect(loop.quit)
        timer.start(timeout_ms)
        loop.exec()
        timer.stop()
        self.runner.idle.disconnect(loop.quit)
        return not self.runner.busy

    def _on_progress(self, stage: str, fraction: float) -> None:
        self.progress_bar.setValue(round(1000 * min(max(fraction, 0.0), 1.0)))
        self.progress_bar.setFormat(f"{stage} %p%")

    def _on_finished(self, result: Any, seconds: float) -> None:
        if self._job_polygon is not None and tuple(self.editor.points) != self._job_polygon:
            self.statusBar().showMessage("polygon edited while meshing; result discarded", 8000)
            return
        self.progress_bar.setValue(1000)
        self.progress_bar.setFormat(f"done in {seconds:.2f} s")
        self.set_result(result)

    def _on_partial(self, partial: Any) -> None:
        """Keep what the failed run computed (its decomposition and thick pieces' stages);
        drawn by :meth:`_on_failed`. Dropped when the polygon was edited while meshing."""
        if self._job_polygon is not None and tuple(self.editor.points) != self._job_polygon:
            return
        self.partial = partial

    def _on_failed(self, message: str) -> None:
        self.progress_bar.setFormat("failed")
        self._show_error(message)
        self._show_partial()
        self._show_partial_disk()
        self._mark_problem(message)

    def _partial_pieces(self) -> tuple:
        """The thick pieces of the failed run on screen (empty when there is none)."""
        return tuple(getattr(self.partial, "pieces", ()) or ())

    def _partial_estimate(self) -> tuple[np.ndarray, str] | None:
        """The failing piece's prevertex placement when its conformal map could not be solved
        (unit complex, and what it is), else None."""
        pre = getattr(self.partial, "failed_prevertices", None)
        if pre is None:
            return None
        return np.asarray(pre, dtype=np.complex128), str(self.partial.failed_prevertices_kind)

    def _partial_slots(self) -> int:
        """How many pieces the piece spin box steps through for the failed run on screen: the
        pieces whose map was solved, and last the failing piece without a map when its
        prevertex placement is known."""
        return len(self._partial_pieces()) + (self._partial_estimate() is not None)

    def _estimate_layer(self) -> LayerGeometry:
        """The prevertices layer of a failing piece without a conformal map: the prevertex
        placement its failed solve had (harmonic-measure estimate, last iterate or rejected
        solution, as its label says), on the unit circle."""
        pre, kind = self._partial_estimate()  # type: ignore[misc]
        part = points_part(pre, color="#e00000", point_size=11.0, label=kind, disk=True)
        return LayerGeometry("prevertices", "disk", [part])

    def _show_partial(self) -> None:
        """Draw the stages a failed run computed — its thick pieces, crosscuts and the pieces'
        pushed-forward disk meshes, the failing piece outlined in red — as an overlay of the
        plane view (removed with the error when the polygon changes)."""
        if self.partial is None:
            return
        parts: list = []
        for name in ("thick_pieces", "conformal_images", "crosscuts"):
            try:
                parts.extend(build_layer(self.partial, name).parts)
            except (AttributeError, ValueError, IndexError):  # a stage that did not run
                continue
        failed = getattr(self.partial, "failed_piece", None)
        thick = getattr(self.partial.decomposition, "thick", ())
        others = tuple(getattr(self.partial, "other_failed", ()))
        for k in (failed, *others):  # every piece the message names, outlined in red
            if k is not None and 0 <= k < len(thick):
                z = np.asarray(thick[k].z, dtype=np.complex128) + complex(self.partial.origin)
                parts.append(
                    line_part(
                        [z], color="#e00000", line_width=7.0, closed=True, label="failed piece"
                    )
                )
        geo = LayerGeometry("partial", "plane", parts) if parts else None
        self.plane.set_overlay("partial", geo)
        self._update_fill()

    def _show_partial_disk(self) -> None:
        """Show a failed run's thick pieces in the disk view (prevertices, arcs I_j and, where
        it was built, the disk mesh), starting with the piece that failed; the piece spin box
        then steps through them."""
        pieces = self._partial_pieces()
        slots = self._partial_slots()
        if not slots:
            return
        failed = getattr(self.partial, "failed_piece", None)
        at = [k for k, p in enumerate(pieces) if p.index == failed]
        if not at and slots > len(pieces):  # the failing piece has no map: its estimate
            at = [len(pieces)]
        self.piece_spin.blockSignals(True)
        self.piece_spin.setRange(0, slots - 1)
        self.piece_spin.setValue(at[0] if at else 0)
        self.disk_piece = self.piece_spin.value()
        self.piece_spin.blockSignals(False)
        self._draw_disk_result()
        self._refresh_legend()
        self.disk.render()

    def _disk_source(self) -> Any:
        """What the disk view shows: a failed run's partial stages while they are on screen,
        else the result."""
        return self.partial if self._partial_slots() else self.result

    def _mark_piece_spin(self) -> None:
        """Say in the spin box which piece failed (failed runs only)."""
        pieces = self._partial_pieces()
        failed = getattr(self.partial, "failed_piece", None)
        k = self.disk_piece
        bad = bool(pieces) and 0 <= k < len(pieces) and pieces[k].index == failed
        no_map = k == len(pieces) and self._partial_estimate() is not None
        self.piece_spin.setSuffix(" (failed, no map)" if no_map else " (failed)" if bad else "")

    def _mark_problem(self, message: str) -> None:
        """Red markers on the plane view at every "(x, y)" point the failure message names
        (the mesher's exceptions carry no partial mesh, only the place in the message)."""
        pts = message_points(message)
        self.problem_points = pts
        geo = None
        if pts.size:
            geo = LayerGeometry(
                "problem",
                "plane",
                [points_part(pts, color="#e00000", point_size=18.0, label="problem")],
            )
        self.plane.set_overlay("problem", geo)
        self.plane.render()

    def _on_cancelled(self) -> None:
        self.progress_bar.setValue(0)
        self.progress_bar.setFormat("cancelled")
        self.statusBar().showMessage("meshing cancelled", 5000)

    def _on_idle(self) -> None:
        self.cancel_button.setEnabled(False)
        self._refresh_polygon()

    def _show_error(self, message: str) -> None:
        """Show the whole ``message`` in the Mesh dock (wrapped; scrollable beyond
        ``ErrorBox.max_lines`` lines), its first line in the status bar, and a message box."""
        self.last_error = message
        self.error_box.set_message(message)
        self._make_room_for_error()
        first = message.splitlines()[0] if message else ""
        if first != message:
            first += "  (whole message in the Mesh panel)"
        self.statusBar().showMessage(first, 15000)
        if self.popups:
            box = QMessageBox(QMessageBox.Warning, "quadmesh", message, parent=self)
            box.setAttribute(Qt.WA_DeleteOnClose)
            box.open()

    def _make_room_for_error(self) -> None:
        """Give the Mesh panel the height its contents (now with the error box) ask for, up
        to two thirds of the dock column (the Information panel keeps the rest), and scroll
        the error box into view."""
        inner = self.mesh_scroll.widget()
        inner.adjustSize()
        total = self.mesh_dock.height() + self.info_dock.height()
        want = min(inner.sizeHint().height() + 40, 2 * total // 3)
        if want > self.mesh_dock.height():
            self.resizeDocks([self.mesh_dock, self.info_dock], [want, total - want], Qt.Vertical)
        self.mesh_scroll.ensureWidgetVisible(self.error_box)

    def _clear_error(self) -> None:
        """Forget the last failure: error box, status bar message and a "failed" progress bar."""
        if self.last_error is None and self.error_box.isHidden():
            return
        self.last_error = None
        self.error_box.clear_message()
        had_pieces = bool(self._partial_slots())
        self.partial = None
        if had_pieces:  # the disk view goes back to the result (if any)
            self.piece_spin.blockSignals(True)
            n = len(self.result.pieces) if self.result is not None else 0
            self.piece_spin.setRange(0, max(n - 1, 0))
            self.disk_piece = self.piece_spin.value()
            self.piece_spin.blockSignals(False)
            self._draw_disk_result()
            self._refresh_legend()
            self.disk.render()
        if "partial" in self.plane.overlays:
            self.plane.set_overlay("partial", None)
            self._update_fill()
            self.plane.render()
        if "problem" in self.plane.overlays:
            self.problem_points = np.zeros(0, dtype=np.complex128)
            self.plane.set_overlay("problem", None)
            self.plane.render()
        self.statusBar().clearMessage()
        if self.progress_bar.format() == "failed":
            self.progress_bar.setValue(0)
            self.progress_bar.setFormat("idle")

    # ================================================================== result display
    def _set_note(self, text: str | None) -> None:
        """Show a note on the last run in the Mesh panel (None: hide it)."""
        self.note_label.setText(text or "")
        self.note_label.setVisible(bool(text))

    def set_result(self, result: Any) -> None:
        """Show a MeshResult: build every layer, the information panel and the histogram."""
        self.result = result
        self.loaded_mesh = self._loaded = None
        self.piece_spin.blockSignals(True)
        self.piece_spin.setRange(0, max(len(result.pieces) - 1, 0))
        self.piece_spin.setValue(min(self.disk_piece, max(len(result.pieces) - 1, 0)))
        self.disk_piece = self.piece_spin.value()
        self.piece_spin.blockSignals(False)
        problems = []
        for name in _RESULT_PLANE:
            try:
                if name == "final_mesh":
                    self._put(self.plane, name, self._mesh_layer(result, self.color_mode))
                else:
                    self._put(self.plane, name, build_layer(result, name))
            except (AttributeError, TypeError, ValueError, IndexError, KeyError) as exc:
                self._put(self.plane, name, None)
                problems.append(f"{LAYER_TITLES[name]}: {exc}")
        self._draw_disk_result()
        self._update_info(problems)
        self._refresh_legend()
        self._forget_picked_quad()
        fallback = getattr(result, "fallback", None)
        self._set_note(f"Blocks fell back: {fallback}" if fallback else None)
        if fallback:
            self.statusBar().showMessage(f"Blocks fell back: {fallback}", 30000)
        if self.plane.fit_bounds is not None:
            self.reset_plane_view()  # still fitted: make room for the colour bar
        self.plane.render()
        self.disk.render()

    def _refresh_legend(self) -> None:
        visible = {n for n in self.layer_panel.visible_layers()}
        shown, piece = self._disk_source(), self.disk_piece
        pieces = self._partial_pieces()
        if pieces and not (0 <= piece < len(pieces) and pieces[piece].disk is not None):
            piece = -1  # no disk mesh: no region kinds to explain
        entries = legend_entries(shown, visible, piece)
        est = self._partial_estimate()
        if est is not None and "prevertices" in visible and self.disk_piece == len(pieces):
            failed = self.partial.failed_piece
            entries.append(("prevertices", f"piece {failed} prevertices: {est[1]}", "#e00000"))
        self.legend.set_entries(entries)

    def _draw_disk_result(self) -> None:
        r = self._disk_source()
        self._mark_piece_spin()
        if r is not None and r is self.partial and self.disk_piece >= len(self._partial_pieces()):
            # the failing piece's map was not solved: only its prevertex placement exists
            self.piece_spin.setEnabled(self._partial_slots() > 1)
            for name in _RESULT_DISK:
                self._put(
                    self.disk, name, self._estimate_layer() if name == "prevertices" else None
                )
            return
        # nothing to step through without thick pieces (a block mesh, no result)
        self.piece_spin.setEnabled(r is not None and bool(r.pieces))
        for name in _RESULT_DISK:
            if r is None or not r.pieces:
                self._put(self.disk, name, None)
                continue
            self._put(self.disk, name, build_layer(r, name, piece=self.disk_piece))

    def _forget_picked_quad(self) -> None:
        self.picked_quad = None
        self.plane.set_overlay("picked_quad", None)
        self.quad_label.setText("click a quad of the mesh to see its angles")

    def _drop_result(self, why: str) -> None:
        self.result = None
        self._set_note(None)
        self.loaded_mesh = self._loaded = None
        self._refresh_legend()
        self._forget_picked_quad()
        self.plane.clear_layers(_RESULT_PLANE)
        self.disk.clear_layers(_RESULT_DISK)
        self.piece_spin.setEnabled(bool(self._partial_slots()))
        self._update_fill()
        self.info_label.setText(why)
        self.histogram.clear()
        self.progress_bar.setValue(0)
        self.progress_bar.setFormat("idle")
        self.plane.render()
        self.disk.render()

    def set_color_mode(self, mode: str) -> None:
        """Colour the final mesh by ``"corner"`` angle or by each quad's ``"worst"`` deviation."""
        self.color_mode = mode
        shown = self.result if self.result is not None else self._loaded
        if shown is not None:
            # the other colouring's actors stay parked: switching back only swaps them
            self.plane.interact_briefly()
            self._put(self.plane, "final_mesh", self._mesh_layer(shown, mode), park=True)
            self.plane.render()

    def _mesh_layer(self, shown: Any, mode: str) -> LayerGeometry:
        """The final-mesh layer of ``shown`` coloured by ``mode``, built once per result and
        colouring (the plane view parks the other colouring's actors)."""
        key = (id(shown), mode)
        cache = self._mesh_layer_cache
        if cache.get("owner") is not shown:
            cache.clear()
            cache["owner"] = shown
        if key not in cache:
            cache[key] = build_layer(shown, "final_mesh", color_by=mode)
        return cache[key]

    def _on_piece_changed(self, k: int) -> None:
        self.disk_piece = k
        self._draw_disk_result()
        self._refresh_legend()
        self.disk.render()

    def _update_info(self, problems: list[str]) -> None:
        r = self.result
        q = r.quality
        rows = [
            ("quads", f"{q.n_quads}"),
            ("vertices", f"{q.n_vertices}"),
            ("polygon vertices n", f"{r.polygon.n}"),
            ("quads / n", f"{q.n_quads / max(r.polygon.n, 1):.1f}"),
            ("min new angle", f"{q.min_angle:.3f}°"),
            ("max new angle", f"{q.max_angle:.3f}°"),
            ("outside [60°,120°]", f"{q.n_angles_outside}"),
        ]
        lay = getattr(r, "blocks", None)
        if lay is not None:
            size = getattr(r.options, "size", None)
            split = " (faces split at centres)" if lay.split else ""
            rows += [
                ("method", f"blocks ({lay.title})"),
                ("coarse cells", f"{lay.n_cells}{split}"),
                (f"{lay.cut_noun}s", f"{len(lay.cuts)}"),
                ("block size", "default (d/20)" if size is None else f"{size:.4g}"),
            ]
            if getattr(lay, "local_faces", ()):
                rows.append(("faces laid out alone", f"{len(lay.local_faces)}"))
            if getattr(lay, "fallback_faces", ()):
                rows.append(("faces by the paper", f"{len(lay.fallback_faces)}"))
        else:
            if getattr(r, "fallback", None):
                rows.append(("method", "paper (Blocks fell back)"))
            rows += [
                (
                    "thick pieces (n used)",
                    f"{len(r.pieces)} (" + ", ".join(str(p.n_used) for p in r.pieces) + ")",
                ),
                ("thin parts", f"{len(r.thin)}"),
            ]
            if getattr(r.options, "arc_choice", "centred") == "sized":
                # the mesh on centred arcs failed; mesh_polygon meshed it again
                rows.append(("arcs", "chosen for size (the centred ones failed)"))
        if q.n_original:
            rows.append(
                (
                    "original angles < 60° kept",
                    f"{q.n_original} (smallest {q.min_original_angle:.2f}°)",
                )
            )
        ver = getattr(r.verification, "ok", None)
        if ver is not None:
            rows.append(("verified", "yes" if ver else "NO"))
        total = sum(r.timings.values())
        html = "<table>" + "".join(f"<tr><td>{k}</td><td><b>{v}</b></td></tr>" for k, v in rows)
        html += "</table><p><b>time per stage</b></p><table>"
        html += "".join(
            f"<tr><td>{k}</td><td align='right'>{v:.3f} s</td></tr>" for k, v in r.timings.items()
        )
        html += f"<tr><td><b>total</b></td><td align='right'><b>{total:.3f} s</b></td></tr></table>"
        fixes = list(dict.fromkeys(f for p in r.pieces for f in p.fixes))
        if fixes:
            html += "<p><b>adaptive fixes</b></p><ul>"
            html += "".join(f"<li>{html_escape(f)}</li>" for f in fixes) + "</ul>"
        if getattr(r, "fallback", None):
            html += f"<p style='color:#8a4b00'>{html_escape(r.fallback)}</p>"
        if problems:
            html += (
                "<p style='color:#c00000'>layers not drawn:<br>" + "<br>".join(problems) + "</p>"
            )
        self.info_label.setText(html)
        self.histogram.set_data(q.histogram, q.bin_edges)

    # ================================================================== layers
    def _on_layer_toggled(self, view: str, name: str, on: bool) -> None:
        v = self._view(view)
        v.interact_briefly()  # a light frame now, full detail once the toggling stops
        v.set_visible(name, on)
        if view == "plane" and name in ("polygon", "final_mesh"):
            self._update_fill()
        self._refresh_legend()
        v.render()

    def set_visible_layers(self, names: list[str]) -> None:
        """Show exactly these layers (both views); ValueError for unknown names."""
        self.layer_panel.set_visible_layers(names)

    def reset_plane_view(self) -> None:
        """Fit the plane view to the polygon, else to a mesh opened from a file, else to the
        square [-1, 1]²."""
        z = self.editor.z
        if z.size < 2 and self.loaded_mesh is not None:
            z = self.loaded_mesh.z
        if z.size >= 2:
            pad = 0.05 * max(np.ptp(z.real), np.ptp(z.imag), 1e-9)
            low = pad
            if self.result is not None or self.loaded_mesh is not None:
                # room for the horizontal colour bar at the bottom
                aspect = self.plane.plotter.height() / max(self.plane.plotter.width(), 1)
                low = 0.2 * max(np.ptp(z.imag), np.ptp(z.real) * aspect)
            self.plane.reset_view(
                (z.real.min() - pad, z.real.max() + pad, z.imag.min() - low, z.imag.max() + pad),
                keep=True,
            )
        else:
            self.plane.reset_view((-1.0, 1.0, -1.0, 1.0), keep=True)

    # ================================================================== disk teaching view
    def _draw_tessellation(self, center: complex = 0j) -> None:
        self._put(
            self.disk,
            "tessellation",
            build_disk_layer("tessellation", tessellation_depth=5, tessellation_center=center),
        )

    def _on_disk_mouse(self, kind: str, w: complex, modifiers: int) -> None:
        g = self.disk.transform if self.disk.transform is not None else Isometry.identity()
        if kind == "press":
            if abs(w) >= 0.995:
                return
            self._disk_press = (w, g)
            self._disk_dragged = False
            self.disk.begin_interaction()  # heavy disk layers drawn light while dragging
        elif kind == "drag" and self._disk_press is not None:
            a, g0 = self._disk_press
            if not self._disk_dragged and abs(w - a) < _drag_threshold(self.disk):
                return
            self._disk_dragged = True
            b = w if abs(w) < 0.995 else 0.995 * w / abs(w)
            self.set_disk_transform(disk_automorphism_inverse(b) @ disk_automorphism(a) @ g0)
        elif kind == "release" and self._disk_press is not None:
            a, g0 = self._disk_press
            self._disk_press = None
            if self._disk_dragged:
                # refill the tessellation around the new centre
                self._draw_tessellation(complex(self.disk.transform.inverse()(0j)))
                self.disk.set_transform(self.disk.transform)
                self.disk.render()
            else:
                self.pick_disk_point(complex(g0.inverse()(a)))
            self.disk.end_interaction()
        elif kind == "dblclick" and abs(w) < 0.995:
            self.set_disk_transform(disk_automorphism(w) @ g)

    def set_disk_transform(self, g: Isometry | None) -> None:
        """Show the disk view moved by the isometry ``g`` (None: identity)."""
        self.disk.set_transform(g)
        self._draw_picked()
        self.disk.render()

    def reset_disk_transform(self) -> None:
        """Back to the identity; forget the picked points."""
        self.picked = []
        self._draw_tessellation()
        self.set_disk_transform(None)
        self.distance_label.setText(_DISK_HINT)

    def pick_disk_point(self, z: complex) -> None:
        """Pick a point (disk coordinates before the automorphism); two picks show their
        hyperbolic distance ρ (metric 2|dz|/(1−|z|²)) and the geodesic between them."""
        if len(self.picked) >= 2:
            self.picked = []
        self.picked.append(complex(z))
        if len(self.picked) == 2:
            d = float(distance(self.picked[0], self.picked[1]))
            self.distance_label.setText(f"hyperbolic distance ρ = {d:.6f}")
        else:
            self.distance_label.setText("picked 1 point; click a second one")
        self._draw_picked()
        self.disk.render()

    def _draw_picked(self) -> None:
        if not self.picked:
            self.disk.set_overlay("picked", None)
            return
        g = self.disk.transform
        pts = np.array(self.picked)
        shown = g(pts) if g is not None else pts
        parts = [points_part(shown, color="#ff7f0e", point_size=13.0, label="picked")]
        if len(shown) == 2:
            arc = geodesic_arc(shown[0], shown[1], 64)
            parts.insert(0, line_part([arc], color="#ff7f0e", line_width=3.0, label="geodesic"))
        self.disk.set_overlay("picked", LayerGeometry("picked", "disk", parts))

    # ================================================================== output
    def shown_mesh(self) -> QuadMesh | None:
        """The quad mesh on screen: the last result's, else one opened from a file."""
        if self.result is not None:
            return self.result.mesh
        return self.loaded_mesh

    def export_mesh(self, path: str | Path) -> None:
        """Write the mesh on screen with quadmesh.io (format from the suffix), with its
        per-quad data (:func:`quadmesh.io.result_cell_data`: corner angles, worst deviation,
        stage kind and piece) as cell data in VTK, VTU, MSH and JSON."""
        from quadmesh.io import write_mesh

        mesh = self.shown_mesh()
        if mesh is None:
            raise QuadmeshError("there is no mesh to export; mesh the polygon first", stage="io")
        from types import SimpleNamespace

        from quadmesh.io import result_cell_data

        origin = 0j
        source: Any = SimpleNamespace(mesh=mesh)
        if self.result is not None and mesh is self.result.mesh:
            origin = complex(getattr(self.result, "mesh_origin", 0j) or 0j)
            source = self.result
        write_mesh(path, mesh, origin=origin, cell_data=result_cell_data(source))

    def save_screenshot(self, path: str | Path) -> None:
        """Save a PNG of the whole window (views included, in full detail: the true geometry
        even where the views show a light stand-in for sub-pixel cells)."""
        views = (self.plane, self.disk)
        try:
            for v in views:
                v.end_interaction(render=False)
                v.set_full_detail(True)
                v.render()
            saved = self.grab().save(str(path))
        finally:
            for v in views:
                v.set_full_detail(False)
                v.render()
        if not saved:
            raise OSError(f"could not write {path}")

    def last_folder(self) -> str:
        """The folder of the file last opened or written (remembered across sessions)."""
        folder = str(self.settings.value("last_folder", "") or "")
        return folder if folder and Path(folder).is_dir() else str(Path.home())

    def _file_dialog(self, save: bool, title: str, filt: str) -> str:
        """Ask for a file, starting in the last used folder.  When saving, a name typed
        without a suffix gets the suffix of the chosen filter.  Remembers the folder."""
        fn = QFileDialog.getSaveFileName if save else QFileDialog.getOpenFileName
        path, chosen = fn(self, title, self.last_folder(), filt)
        if not path:
            return ""
        if save:
            path = with_filter_suffix(path, chosen or filt)
        self.settings.setValue("last_folder", str(Path(path).resolve().parent))
        self.settings.sync()
        return path

    def _guarded(self, what: str, fn: Any, *args: Any) -> bool:
        try:
            fn(*args)
        except (QuadmeshError, OSError, ValueError) as exc:
            self._show_error(f"{what} failed: {exc}")
            return False
        return True

    def _open_dialog(self) -> None:
        if not self.confirm_discard("open another file"):
            return
        p = self._file_dialog(False, "Open polygon or mesh", _OPEN_FILTERS)
        if p:
            self._guarded(f"opening {Path(p).name}", self.open_file, p)

    def _save_dialog(self) -> None:
        p = self._file_dialog(True, "Save polygon", "JSON (*.json)")
        if p and self._guarded("saving the polygon", self.save_polygon, p):
            self._mark_clean()
            self.statusBar().showMessage(
                f"polygon saved: {len(self.editor.points)} vertices → {p}", 10000
            )

    def _export_dialog(self) -> None:
        if self.shown_mesh() is None:
            self._show_error("there is no mesh to export; mesh the polygon first")
            return
        p = self._file_dialog(True, "Export mesh", _EXPORT_FILTERS)
        if p and self._guarded("exporting the mesh", self.export_mesh, p):
            m = self.shown_mesh()
            self.statusBar().showMessage(
                f"mesh exported: {m.n_quads} quads, {m.n_vertices} vertices → {p}", 10000
            )

    def _screenshot_dialog(self) -> None:
        p = self._file_dialog(True, "Save screenshot", "PNG (*.png)")
        if p and self._guarded("saving the screenshot", self.save_screenshot, p):
            self.statusBar().showMessage(f"screenshot saved → {p}", 10000)

    # ================================================================== shutdown
    def keyPressEvent(self, event: Any) -> None:
        if event.key() in (Qt.Key_Delete, Qt.Key_Backspace):
            self.delete_selected()
            return
        super().keyPressEvent(event)

    def closeEvent(self, event: Any) -> None:
        self.shutdown()
        super().closeEvent(event)

    def shutdown(self) -> None:
        """Stop the worker and release both render windows (idempotent)."""
        if self.runner.busy:
            self.runner.cancel()
            self.runner.wait(30000)
        for v in (self.plane, self.disk):
            if not getattr(v, "_closed", False):
                v.close_plotter()
                v._closed = True


_MESH_SUFFIXES = (".vtk", ".vtu", ".msh", ".obj", ".ply", ".mesh")
_OPEN_FILTERS = (
    "Polygons and meshes (*.json *.geojson *.csv *.txt *.svg "
    + " ".join(f"*{e}" for e in _MESH_SUFFIXES)
    + ");;Polygons (*.json *.geojson *.csv *.txt *.svg);;Meshes (*.json "
    + " ".join(f"*{e}" for e in _MESH_SUFFIXES)
    + ");;All files (*)"
)
_EXPORT_FILTERS = (
    "JSON (*.json);;VTK (*.vtk);;VTK XML (*.vtu);;Gmsh 2.2 (*.msh);;Wavefront (*.obj)"
    ";;Stanford PLY (*.ply);;Medit (*.mesh)"
)


def _scrolled(widget: QWidget, max_width: int) -> QScrollArea:
    """``widget`` in a frameless vertical scroll area at most ``max_width`` pixels wide, so
    that a dock's contents stay reachable in a small window (they scroll instead of being
    squeezed or cut off)."""
    scroll = QScrollArea()
    scroll.setWidget(widget)
    scroll.setWidgetResizable(True)
    scroll.setFrameShape(QScrollArea.NoFrame)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
    scroll.setMaximumWidth(max_width)
    bar = scroll.verticalScrollBar().sizeHint().width()
    scroll.setMinimumWidth(min(max_width, widget.minimumSizeHint().width() + bar))
    return scroll


def with_filter_suffix(path: str, name_filter: str) -> str:
    """``path`` with the first suffix of a file-dialog filter such as ``"VTK (*.vtk)"``
    appended when the file name has no suffix of its own."""
    if Path(path).suffix:
        return path
    m = re.search(r"\*(\.[A-Za-z0-9]+)", name_filter)
    return path + m.group(1) if m else path


def is_mesh_file(path: str | Path) -> bool:
    """True for a mesh file: a meshio suffix, or JSON whose top-level object has "quads"."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext in _MESH_SUFFIXES:
        return True
    if ext != ".json" or not p.is_file():
        return False
    try:
        data = json.loads(p.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False  # read_polygon reports what is wrong with it
    return isinstance(data, dict) and "quads" in data


def _points_of(obj: Any) -> np.ndarray:
    """Complex vertices of whatever quadmesh.io / quadmesh.examples returned."""
    z = getattr(obj, "z", None)
    if z is not None:
        return np.asarray(z, dtype=np.complex128)
    arr = np.asarray(obj)
    if np.iscomplexobj(arr):
        return arr.astype(np.complex128).ravel()
    arr = np.asarray(arr, dtype=np.float64)
    return arr[:, 0] + 1j * arr[:, 1]
