"""The "Enter coordinates" dialog: vertices typed or pasted as text."""

from __future__ import annotations

import numpy as np
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QLabel,
    QPlainTextEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from .drawing import parse_coordinates

__all__ = ["CoordinatesDialog"]

_HELP = (
    "One vertex per line as <tt>x y</tt> or <tt>x, y</tt>, or a JSON list "
    "<tt>[[x, y], …]</tt>. The polygon is closed after the last vertex."
)


class CoordinatesDialog(QDialog):
    """A text box for vertex coordinates with Paste, OK and Cancel.

    OK is refused (with the reason shown under the text) until the text parses; after
    acceptance :attr:`vertices` holds the parsed vertices (complex).
    """

    def __init__(self, text: str = "", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Enter coordinates")
        self.vertices: np.ndarray | None = None
        lay = QVBoxLayout(self)
        help_label = QLabel(_HELP)
        help_label.setWordWrap(True)
        lay.addWidget(help_label)
        self.edit = QPlainTextEdit(text)
        self.edit.setObjectName("coordinates_text")
        self.edit.setPlaceholderText("0 0\n2 0\n2 1\n1 1\n1 2\n0 2")
        lay.addWidget(self.edit, 1)
        self.error_label = QLabel("")
        self.error_label.setObjectName("coordinates_error")
        self.error_label.setStyleSheet("color: #c00000")
        self.error_label.setWordWrap(True)
        lay.addWidget(self.error_label)
        self.buttons = QDialogButtonBox(QDialogButtonBox.Ok | QDialogButtonBox.Cancel)
        self.paste_button = QPushButton("Paste")
        self.paste_button.setObjectName("paste_button")
        self.paste_button.setToolTip("replace the text by the clipboard's")
        self.paste_button.clicked.connect(lambda _checked=False: self.paste())
        self.buttons.addButton(self.paste_button, QDialogButtonBox.ActionRole)
        self.buttons.accepted.connect(self.accept)
        self.buttons.rejected.connect(self.reject)
        lay.addWidget(self.buttons)
        self.resize(380, 360)

    def paste(self) -> None:
        """Replace the text by the clipboard's text."""
        self.edit.setPlainText(QGuiApplication.clipboard().text())

    def accept(self) -> None:
        """Close with the parsed vertices, or stay open and say what is wrong."""
        try:
            self.vertices = parse_coordinates(self.edit.toPlainText())
        except ValueError as exc:
            self.error_label.setText(str(exc))
            return
        self.error_label.setText("")
        super().accept()
