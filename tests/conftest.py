"""Shared pytest setup: GUI tests (marked ``gui``) run only where an X display exists.

Qt aborts the whole process when it cannot open a display (GUI-STACK.md), so GUI tests are
skipped *before* any QApplication is made.  CI runs them under ``xvfb-run``.
"""

from __future__ import annotations

import os

import pytest

HAS_DISPLAY = bool(os.environ.get("DISPLAY"))
if HAS_DISPLAY:
    # the 3-D views render only through xcb (offscreen leaves them blank)
    os.environ.setdefault("QT_QPA_PLATFORM", "xcb")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if HAS_DISPLAY:
        return
    skip = pytest.mark.skip(reason="GUI test: no DISPLAY (run under xvfb-run)")
    for item in items:
        if "gui" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def main_window(qtbot):
    """A shown MainWindow with explicit rendering (auto_update=False); closed at teardown."""
    from app.window import MainWindow

    win = MainWindow(auto_update=False, popups=False)
    qtbot.addWidget(win)
    win.resize(1280, 860)
    win.show()
    qtbot.waitExposed(win)
    yield win
    win.shutdown()
    win.close()
