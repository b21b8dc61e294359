"""The colour legend of the categorical layers: which colour is which thick piece, which kind
of thin part (vertex sector, channel, corridor) and which kind of Lemma 2.2 disk piece.

The entries are computed from the result on screen and the visible layers
(:func:`legend_entries`), so the legend lists exactly what is drawn."""

from __future__ import annotations

from typing import Any

import numpy as np
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QGridLayout, QGroupBox, QLabel, QWidget

from quadmesh.render import (
    BLOCK_COLORS,
    KIND_COLORS,
    PIECE_PALETTE,
    THIN_COLORS,
    block_layout_edges,
)

__all__ = ["THIN_KIND_TITLES", "LegendPanel", "legend_entries"]

#: What the user calls each kind of thin part.
THIN_KIND_TITLES: dict[str, str] = {
    "parabolic": "vertex sector",
    "hyperbolic": "channel",
    "corridor": "corridor",
}
_DISK_KIND_TITLES: dict[str, str] = {
    "pentagon": "pentagon",
    "carleson_quadrilateral": "Carleson quadrilateral",
    "carleson_triangle": "Carleson triangle",
}


_KINDS_SEEN: list[tuple[Any, set[str]]] = []


def _kinds_present(disk: Any) -> set[str]:
    """The quad kinds of a disk mesh, remembered for the last few disk meshes asked about (a
    layer toggle refreshes the legend; a million-quad piece takes 0.1 s to scan)."""
    for seen, kinds in _KINDS_SEEN:
        if seen is disk:
            return kinds
    kinds = set(np.unique(np.asarray(disk.kind)).tolist())
    _KINDS_SEEN.insert(0, (disk, kinds))
    del _KINDS_SEEN[4:]
    return kinds


def legend_entries(result: Any, visible: set[str], piece: int = 0) -> list[tuple[str, str, str]]:
    """``(layer, label, "#rrggbb")`` for every categorical colour drawn by a visible layer of
    ``result`` (a MeshResult; None gives no entries): thick pieces (one palette colour per
    piece, as drawn), thin part kinds present, and the disk region's piece kinds present in
    thick piece number ``piece`` (the one the disk view shows); for a block mesh, the block
    layout's cuts and its other inner cell edges (where it has them)."""
    if result is None:
        return []
    out: list[tuple[str, str, str]] = []
    layout = getattr(result, "blocks", None)
    if "block_layout" in visible and layout is not None:
        if len(layout.cuts):
            kind = getattr(layout, "kind", "cuts")
            label = "cut" if kind == "cuts" else f"{layout.cut_noun} ({layout.title})"
            out.append(("block_layout", label, BLOCK_COLORS["cuts"]))
        if len(block_layout_edges(layout)[0]):
            out.append(("block_layout", "coarse cell edge", BLOCK_COLORS["cell edges"]))
        if getattr(layout, "local_faces", ()):
            out.append(("block_layout", "face laid out on its own", BLOCK_COLORS["local faces"]))
        if getattr(layout, "fallback_faces", ()):
            out.append(
                (
                    "block_layout",
                    "face meshed by the paper's construction",
                    BLOCK_COLORS["fallback faces"],
                )
            )
    if getattr(result, "decomposition", None) is None:
        return out
    if "thick_pieces" in visible:
        for k in range(len(result.decomposition.thick)):
            out.append(("thick_pieces", f"thick piece {k}", PIECE_PALETTE[k % len(PIECE_PALETTE)]))
    if "thin_parts" in visible:
        kinds = {t.kind for t in result.thin}
        for kind, title in THIN_KIND_TITLES.items():
            if kind in kinds:
                out.append(("thin_parts", title, THIN_COLORS[kind]))
    if "region_w" in visible and 0 <= piece < len(result.pieces):
        present = _kinds_present(result.pieces[piece].disk)
        for kind, title in _DISK_KIND_TITLES.items():
            if kind in present:
                out.append(("region_w", title, KIND_COLORS[kind]))
    return out


class LegendPanel(QGroupBox):
    """A "Legend" box: a colour swatch and a label per entry of :func:`legend_entries`
    (hidden while there is nothing to explain)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Legend", parent)
        self.setObjectName("legend")
        self._grid = QGridLayout(self)
        self._grid.setContentsMargins(6, 4, 6, 4)
        self._grid.setColumnStretch(1, 1)
        self.entries: list[tuple[str, str, str]] = []
        self.hide()

    def set_entries(self, entries: list[tuple[str, str, str]]) -> None:
        """Show these ``(layer, label, colour)`` entries."""
        while self._grid.count():
            item = self._grid.takeAt(0)
            w = item.widget()
            if w is not None:  # gone at once (deleteLater alone leaves it drawn until idle)
                w.hide()
                w.setParent(None)
                w.deleteLater()
        self.entries = list(entries)
        for row, (layer, label, color) in enumerate(self.entries):
            sw = QLabel()
            sw.setFixedSize(16, 12)
            sw.setStyleSheet(f"background-color: {QColor(color).name()}; border: 1px solid #555")
            sw.setToolTip(f"{color} ({layer.replace('_', ' ')} layer)")
            self._grid.addWidget(sw, row, 0)
            text = QLabel(label)
            text.setWordWrap(True)  # a long label wraps inside the narrow Layers dock
            text.setObjectName(f"legend_{layer}_{row}")
            self._grid.addWidget(text, row, 1)
        self.setVisible(bool(self.entries))

    def labels(self, layer: str | None = None) -> list[str]:
        """The labels listed (of one layer when ``layer`` is given)."""
        return [lab for lay, lab, _ in self.entries if layer is None or lay == layer]
