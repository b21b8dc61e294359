"""A small angle histogram drawn with QPainter (QtCharts is not in PySide6-Essentials)."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt
from PySide6.QtGui import QColor, QFontMetricsF, QPainter, QPen
from PySide6.QtWidgets import QWidget

__all__ = ["AngleHistogram"]

_TICKS = (0, 60, 90, 120, 180)


class AngleHistogram(QWidget):
    """Bars of a histogram of corner angles with the [60°, 120°] band marked.

    Every non-empty bin carries its count (written upwards over its bar, so narrow bars keep
    readable labels); the axis is labelled at 0°, 60°, 90°, 120° and 180°.  All labels are laid
    out inside the widget (:meth:`labels`).
    """

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._counts = np.zeros(0)
        self._edges = np.zeros(0)
        self.setMinimumSize(220, 170)

    def sizeHint(self) -> QSize:
        return QSize(280, 190)

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

    # ------------------------------------------------------------------ layout
    def _frame(self) -> tuple[float, float, float, float, float]:
        """Plot area (left, top, width, height) and the height reserved for count labels."""
        fm = QFontMetricsF(self.font())
        top = int(self._counts.max()) if self._counts.size else 0
        label_h = fm.horizontalAdvance(f"{top}") + 4 if top > 0 else 0.0
        m_l = 10.0
        m_r = fm.horizontalAdvance("180°") / 2 + 4
        m_t = 4.0 + label_h
        m_b = fm.height() + 6
        return m_l, m_t, self.width() - m_l - m_r, self.height() - m_t - m_b, label_h

    def _x(self, a: float) -> float:
        m_l, _, w, _, _ = self._frame()
        return m_l + a / 180.0 * w

    def bars(self) -> list[tuple[int, QRectF]]:
        """The non-empty bins and their bars (widget coordinates)."""
        if self._counts.size == 0 or self._counts.max() <= 0:
            return []
        _, m_t, _, h, _ = self._frame()
        top = float(self._counts.max())
        out = []
        for k, (c, a, b) in enumerate(zip(self._counts, self._edges[:-1], self._edges[1:])):
            if c <= 0:
                continue
            bh = max(1.0, c / top * h)
            xa, xb = self._x(a), self._x(b)
            out.append((k, QRectF(xa + 0.5, m_t + h - bh, max(1.0, xb - xa - 1), bh)))
        return out

    def labels(self) -> list[tuple[str, QRectF]]:
        """Every text drawn and its box: the axis labels, then one count per non-empty bin
        (the box of the upward text, just above its bar)."""
        fm = QFontMetricsF(self.font())
        _, m_t, _, h, _ = self._frame()
        out = []
        for a in _TICKS:
            text = f"{a}°"
            tw = fm.horizontalAdvance(text)
            out.append((text, QRectF(self._x(a) - tw / 2, m_t + h + 4, tw, fm.height())))
        for k, bar in self.bars():
            text = f"{int(self._counts[k])}"
            tw = fm.horizontalAdvance(text)
            cx = bar.center().x()
            out.append((text, QRectF(cx - fm.height() / 2, bar.top() - 2 - tw, fm.height(), tw)))
        return out

    # ------------------------------------------------------------------ painting
    def paintEvent(self, event: object) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.Antialiasing)
        p.fillRect(self.rect(), QColor("white"))
        m_l, m_t, w, h, _ = self._frame()
        p.fillRect(QRectF(self._x(60), m_t, self._x(120) - self._x(60), h), QColor(220, 240, 220))
        p.setPen(QPen(QColor("black")))
        p.drawLine(QPointF(m_l, m_t + h), QPointF(m_l + w, m_t + h))
        for a in _TICKS:
            x = self._x(a)
            p.drawLine(QPointF(x, m_t + h), QPointF(x, m_t + h + 3))
        bars = self.bars()
        if not bars:
            for text, r in self.labels():
                p.drawText(r, Qt.AlignCenter, text)
            p.drawText(QRectF(m_l, m_t, w, h), Qt.AlignCenter, "no mesh yet")
            p.end()
            return
        p.setPen(Qt.NoPen)
        for k, r in bars:
            a, b = self._edges[k], self._edges[k + 1]
            inside = a >= 60 - 1e-9 and b <= 120 + 1e-9
            p.setBrush(QColor("#4a7ab5") if inside else QColor("#d9534f"))
            p.drawRect(r)
        p.setPen(QPen(QColor("black")))
        fm = QFontMetricsF(self.font())
        for text, r in self.labels():
            if text.endswith("°"):
                p.drawText(r, Qt.AlignCenter, text)
                continue
            # counts: upwards, bottom of the text at the top of the bar
            p.save()
            p.translate(r.center())
            p.rotate(-90)
            tw = fm.horizontalAdvance(text)
            p.drawText(QRectF(-tw / 2, -fm.height() / 2, tw, fm.height()), Qt.AlignCenter, text)
            p.restore()
        p.end()
