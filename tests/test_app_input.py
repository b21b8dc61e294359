"""GUI tests of typed/pasted coordinates and of the question before an unsaved drawn polygon
is thrown away (run under ``xvfb-run``)."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtGui import QGuiApplication, QKeySequence

from app.drawing import parse_coordinates
from tests.helpers import L_SHAPE
from tests.test_app import (
    DialogAnswer,
    answer_file_dialog,
    click,
    keys,
    load_example_by_menu,
    press,
    tick,
)

pytestmark = pytest.mark.gui


def _same_polygon(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and np.allclose(np.sort_complex(a), np.sort_complex(b))


# ------------------------------------------------------------------------------ parsing
@pytest.mark.parametrize(
    "text",
    [
        "0 0\n2 0\n2 1\n1 1\n1 2\n0 2\n",
        "# L shape\n0, 0\n2,0\n\n2 , 1\n1;1\n1 2\n0 2\n0 0\n",  # closing repeat dropped
        "[[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]",
        '{"vertices": [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2.0]]}',
    ],
)
def test_parse_coordinates_forms(text):
    z = parse_coordinates(text)
    assert z.dtype == np.complex128
    np.testing.assert_allclose(z, L_SHAPE)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("0 0\n1 0\n1 x\n", "line 3"),
        ("0 0\n1 0 5\n1 1\n", "line 2"),
        ("0 0\n1 0\n", "at least 3 vertices; the text gives 2"),
        ("[[0, 0], [1, 0], [1]]", "JSON item 2"),
        ("[[0, 0], [1, 0]", "looks like JSON"),
        ("0 0\n1 inf\n1 1\n", "not finite"),
    ],
)
def test_parse_coordinates_refuses_with_the_place(text, says):
    with pytest.raises(ValueError, match=says.replace("[", r"\[")):
        parse_coordinates(text)


# ------------------------------------------------------------------------------ the dialog
def test_enter_coordinates_pasted_from_clipboard(main_window, qtbot):
    """Ctrl+K opens the dialog; a bad text is refused with its line named and the dialog stays;
    Paste takes the clipboard's text; OK replaces the polygon, which can then be meshed."""
    from app.coords import CoordinatesDialog

    win = main_window
    keys(qtbot, win, "Ctrl+K")
    dlg = win.coordinates_dialog
    assert isinstance(dlg, CoordinatesDialog)
    qtbot.waitUntil(dlg.isVisible, timeout=3000)
    dlg.edit.setFocus()
    for k, line in enumerate(("0 0", "3 0", "3 y")):
        if k:
            qtbot.keyClick(dlg.edit, Qt.Key.Key_Return)
        qtbot.keyClicks(dlg.edit, line)
    assert dlg.edit.toPlainText() == "0 0\n3 0\n3 y"
    press(qtbot, dlg.buttons.button(dlg.buttons.StandardButton.Ok))
    assert dlg.isVisible()
    assert "line 3" in dlg.error_label.text()
    assert win.editor.points == []
    QGuiApplication.clipboard().setText("0, 0\n2, 0\n2, 1\n1, 1\n1, 2\n0, 2\n")
    press(qtbot, dlg.paste_button)
    assert dlg.edit.toPlainText().startswith("0, 0")
    press(qtbot, dlg.buttons.button(dlg.buttons.StandardButton.Ok))
    qtbot.waitUntil(lambda: not dlg.isVisible(), timeout=3000)
    assert win.editor.closed and _same_polygon(win.editor.z, L_SHAPE)
    assert win.mesh_button.isEnabled() and win.warning_label.text() == ""
    outline = win.plane.layers["polygon"].geometry.part("outline")
    assert outline.mesh.n_points == 6
    # typed coordinates are unsaved: they count as a drawing to ask about
    assert win.has_unsaved_polygon()
    # the dialog opens with the current polygon's coordinates, and they parse back
    keys(qtbot, win, "Ctrl+K")
    dlg2 = win.coordinates_dialog
    qtbot.waitUntil(dlg2.isVisible, timeout=3000)
    assert _same_polygon(parse_coordinates(dlg2.edit.toPlainText()), win.editor.z)
    press(qtbot, dlg2.buttons.button(dlg2.buttons.StandardButton.Cancel))
    qtbot.waitUntil(lambda: not dlg2.isVisible(), timeout=3000)
    assert _same_polygon(win.editor.z, L_SHAPE)


# ------------------------------------------------------------------------------ discard question
def _draw_triangle(win, qtbot) -> np.ndarray:
    win.plane.reset_view((-0.5, 2.5, -0.5, 2.5))
    tick(qtbot, win.draw_check)
    for z in (0.0, 2.0, 1 + 2j):
        click(qtbot, win.plane, z)
    click(qtbot, win.plane, 0.0)  # closes
    assert win.editor.closed and len(win.editor.points) == 3
    return win.editor.z.copy()


def _example(win, qtbot, name: str) -> None:
    """Examples ▸ ``name``, picked from the menu with the mouse."""
    load_example_by_menu(qtbot, win, name)


def test_discarding_a_drawn_polygon_asks_first(main_window, qtbot, monkeypatch):
    """Over a drawn, unsaved polygon: an example, New and Open ask; "Cancel" keeps the drawing,
    "Discard" goes on.  A loaded or saved polygon is replaced without a question."""
    from PySide6.QtWidgets import QMessageBox

    win = main_window
    win.popups = True  # the app asks only when it may show boxes
    drawn = _draw_triangle(win, qtbot)
    assert win.has_unsaved_polygon()
    asked: list[str] = []
    answer = [QMessageBox.StandardButton.Cancel]

    def question(parent, title, text, *args, **kwargs):
        asked.append(text)
        return answer[0]

    monkeypatch.setattr(QMessageBox, "question", question)
    _example(win, qtbot, "l_shape")
    assert len(asked) == 1 and "3 vertices" in asked[0] and "l_shape" in asked[0]
    assert np.allclose(win.editor.z, drawn)  # kept
    keys(qtbot, win, QKeySequence.StandardKey.New)
    assert len(asked) == 2 and np.allclose(win.editor.z, drawn)
    keys(qtbot, win, QKeySequence.StandardKey.Open)  # Cancel: no file dialog follows
    assert len(asked) == 3 and np.allclose(win.editor.z, drawn)

    answer[0] = QMessageBox.StandardButton.Discard
    _example(win, qtbot, "l_shape")
    assert len(asked) == 4 and _same_polygon(win.editor.z, L_SHAPE)
    assert not win.has_unsaved_polygon()
    # a loaded example is not "drawn": the next example replaces it without a question
    _example(win, qtbot, "star_100")
    assert len(asked) == 4 and len(win.editor.points) > 6
    # New over an edited polygon, answered Discard: an empty drawing in draw mode
    press(qtbot, win.draw_buttons["undo"])  # back to the L-shape: an edit
    assert win.has_unsaved_polygon()
    keys(qtbot, win, QKeySequence.StandardKey.New)
    assert len(asked) == 5 and win.editor.points == [] and win.draw_check.isChecked()


def test_discard_question_box_driven(main_window, qtbot, tmp_path):
    """The real question box: its Cancel button keeps the drawing, its Discard button loads the
    example; after saving, no question is asked."""
    from PySide6.QtWidgets import QMessageBox

    win = main_window
    win.popups = True
    drawn = _draw_triangle(win, qtbot)

    def click_button(which):
        def act(box) -> None:
            assert "not saved" in box.text()
            qtbot.mouseClick(box.button(which), Qt.MouseButton.LeftButton)

        return act

    ans = DialogAnswer(QMessageBox, click_button(QMessageBox.StandardButton.Cancel))
    _example(win, qtbot, "l_shape")
    ans.check()
    assert np.allclose(win.editor.z, drawn)
    ans = DialogAnswer(QMessageBox, click_button(QMessageBox.StandardButton.Discard))
    _example(win, qtbot, "l_shape")
    ans.check()
    assert _same_polygon(win.editor.z, L_SHAPE)
    # draw again, save it: then an example replaces it without asking
    keys(qtbot, win, QKeySequence.StandardKey.New)  # L-shape was loaded: no question
    assert win.editor.points == []
    for z in (0.0, 2.0, 1 + 2j):
        click(qtbot, win.plane, z)
    click(qtbot, win.plane, 0.0)
    assert win.has_unsaved_polygon()
    ans = answer_file_dialog(qtbot, str(tmp_path / "tri"), "JSON (*.json)")
    keys(qtbot, win, QKeySequence.StandardKey.Save)  # File ▸ Save polygon
    ans.check()
    assert (tmp_path / "tri.json").is_file()
    assert not win.has_unsaved_polygon()
    _example(win, qtbot, "l_shape")  # a box here would block: none is shown
    assert _same_polygon(win.editor.z, L_SHAPE)
