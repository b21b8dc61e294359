"""The layer panel: one row per layer with a visibility checkbox, a colour button and an
opacity slider, grouped by view."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QCheckBox,
    QColorDialog,
    QComboBox,
    QGridLayout,
    QGroupBox,
    QLabel,
    QSlider,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from quadmesh.render import LAYER_TITLES, layer_names

__all__ = ["DEFAULT_VISIBLE", "LayerPanel"]

#: Layers shown when the app starts.
DEFAULT_VISIBLE: dict[str, bool] = {
    "polygon": True,
    "thick_pieces": False,
    "thin_parts": False,
    "crosscuts": True,
    "conformal_images": False,
    "final_mesh": True,
    "block_layout": True,
    "bad_quads": True,
    "tessellation": True,
    "region_w": True,
    "disk_mesh": True,
    "prevertices": True,
}

#: Layers whose parts are all coloured by data (no flat colour to choose).
_NO_COLOR = {"final_mesh", "conformal_images", "region_w", "thick_pieces", "thin_parts"}


class LayerPanel(QWidget):
    """Checkboxes, colour buttons and opacity sliders for the layers of both views.

    Signals:
        toggled(view, name, visible), color_changed(view, name, "#rrggbb"),
        opacity_changed(view, name, opacity 0..1), color_mode_changed("corner" | "worst").
    """

    toggled = Signal(str, str, bool)
    color_changed = Signal(str, str, str)
    opacity_changed = Signal(str, str, float)
    color_mode_changed = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.checkboxes: dict[str, QCheckBox] = {}
        self.sliders: dict[str, QSlider] = {}
        self.color_buttons: dict[str, QToolButton] = {}
        outer = QVBoxLayout(self)
        for view, title in (("plane", "Plane view"), ("disk", "Disk view")):
            box = QGroupBox(title)
            grid = QGridLayout(box)
            grid.setContentsMargins(6, 4, 6, 4)
            for row, name in enumerate(layer_names(view)):
                cb = QCheckBox(LAYER_TITLES[name])
                cb.setObjectName(f"layer_{name}")
                cb.setChecked(DEFAULT_VISIBLE[name])
                cb.toggled.connect(lambda on, v=view, n=name: self.toggled.emit(v, n, on))
                grid.addWidget(cb, row, 0)
                if name not in _NO_COLOR:
                    btn = QToolButton()
                    btn.setToolTip(f"colour of {LAYER_TITLES[name]}")
                    btn.setFixedSize(22, 18)
                    btn.clicked.connect(lambda _=False, v=view, n=name: self._pick_color(v, n))
                    self.color_buttons[name] = btn
                    grid.addWidget(btn, row, 1)
                sl = QSlider(Qt.Horizontal)
                sl.setRange(5, 100)
                sl.setValue(100)
                sl.setFixedWidth(56)
                sl.setToolTip(f"opacity of {LAYER_TITLES[name]}")
                sl.valueChanged.connect(
                    lambda val, v=view, n=name: self.opacity_changed.emit(v, n, val / 100.0)
                )
                grid.addWidget(sl, row, 2)
                self.checkboxes[name] = cb
                self.sliders[name] = sl
            outer.addWidget(box)
        mode_row = QWidget()
        g = QGridLayout(mode_row)
        g.setContentsMargins(0, 0, 0, 0)
        g.addWidget(QLabel("Final mesh colour:"), 0, 0)
        self.color_mode = QComboBox()
        self.color_mode.addItem("corner angle", "corner")
        self.color_mode.addItem("worst |θ − 90°|", "worst")
        self.color_mode.currentIndexChanged.connect(
            lambda _i: self.color_mode_changed.emit(self.color_mode.currentData())
        )
        g.addWidget(self.color_mode, 0, 1)
        outer.addWidget(mode_row)
        outer.addStretch(1)

    def set_swatch(self, name: str, color: str) -> None:
        """Show ``color`` on the colour button of layer ``name``."""
        btn = self.color_buttons.get(name)
        if btn is not None:
            btn.setStyleSheet(f"background-color: {QColor(color).name()}; border: 1px solid #555")

    def _pick_color(self, view: str, name: str) -> None:
        c = QColorDialog.getColor(parent=self, title=f"Colour of {LAYER_TITLES[name]}")
        if c.isValid():
            self.set_swatch(name, c.name())
            self.color_changed.emit(view, name, c.name())

    def visible_layers(self) -> list[str]:
        """Names of the checked layers."""
        return [n for n, cb in self.checkboxes.items() if cb.isChecked()]

    def set_visible_layers(self, names: list[str]) -> None:
        """Check exactly the given layers (unknown names raise ValueError)."""
        unknown = [n for n in names if n not in self.checkboxes]
        if unknown:
            raise ValueError(f"unknown layers {unknown}; known: {list(self.checkboxes)}")
        for n, cb in self.checkboxes.items():
            cb.setChecked(n in names)
