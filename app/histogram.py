"""A small angle histogram drawn with QPainter (QtCharts is not in PySide6-Essentials)."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QRectF, QSize, Qt
from PySide6.QtGui import QColor, QPainter, QPen
from PySide6.QtWidgets import QWidget

__all__ = ["AngleHistogram"]


class AngleHistogram(QWidget):
    """Bars of a histogram of corner angles with the [60°, 120°] band marked."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._counts = np.zeros(0)
        self._edges = np.zeros(0)
        self.setMinimumSize(220, 140)

    def sizeHint(self) -> QSize:
        return QSize(280, 170)

    def set_data(self, counts: np.ndarray, edges: np.ndarray) -> None:
        """Show ``counts`` over bins ``edges`` (len(edges) == len(counts) + 1, degrees)."""
        counts = np.asarray(counts, dtype=float)
        edges = np.asarray(edges, dtype=float)
        if counts.size and edges.size != counts.size + 1:
            raise ValueError("histogram needs len(edges) == len(counts) + 1")
        self._counts, self._edges = counts, edges
        self.update()

    def clear(self) -> None:
        """Show an empty histogram."""
        self.set_data(np.zeros(0), np.zeros(0))

    @property
    def counts(self) -> np.ndarray:
        """The counts shown."""
        return self._counts

    def paintEvent(self, event: object) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.Antialiasing)
        p.fillRect(self.rect(), QColor("white"))
        m_l, m_r, m_t, m_b = 34, 8, 8, 20
        w = self.width() - m_l - m_r
        h = self.height() - m_t - m_b
        lo, hi = 0.0, 180.0

        def x_of(a: float) -> float:
            return m_l + (a - lo) / (hi - lo) * w

        p.fillRect(QRectF(x_of(60), m_t, x_of(120) - x_of(60), h), QColor(220, 240, 220))
        p.setPen(QPen(QColor("black")))
        p.drawLine(m_l, m_t + h, m_l + w, m_t + h)
        for a in (0, 60, 90, 120, 180):
            x = x_of(a)
            p.drawLine(int(x), m_t + h, int(x), m_t + h + 3)
            p.drawText(QRectF(x - 15, m_t + h + 3, 30, 14), Qt.AlignCenter, f"{a}°")
        if self._counts.size == 0 or self._counts.max() <= 0:
            p.drawText(QRectF(m_l, m_t, w, h), Qt.AlignCenter, "no mesh yet")
            p.end()
            return
        top = float(self._counts.max())
        p.drawText(QRectF(0, m_t - 2, m_l - 4, 14), Qt.AlignRight, f"{int(top)}")
        p.setPen(Qt.NoPen)
        for c, a, b in zip(self._counts, self._edges[:-1], self._edges[1:], strict=True):
            if c <= 0:
                continue
            bh = max(1.0, c / top * h)
            inside = a >= 60 - 1e-9 and b <= 120 + 1e-9
            p.setBrush(QColor("#4a7ab5") if inside else QColor("#d9534f"))
            p.drawRect(QRectF(x_of(a) + 0.5, m_t + h - bh, max(1.0, x_of(b) - x_of(a) - 1), bh))
        p.end()
