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
def main_window(qtbot, tmp_path):
    """A shown, active MainWindow as ``quadmesh-app`` builds it (views render only on change),
    without message boxes, remembering folders in a settings file under ``tmp_path``; closed
    at teardown."""
    from PySide6.QtCore import QSettings

    from app.window import MainWindow

    settings = QSettings(str(tmp_path / "quadmesh-app.ini"), QSettings.Format.IniFormat)
    win = MainWindow(popups=False, settings=settings)  # closed and destroyed below
    win.resize(1280, 860)
    win.show()
    qtbot.waitExposed(win)
    win.activateWindow()
    qtbot.waitUntil(win.isActiveWindow, timeout=5000)
    yield win
    win.shutdown()
    win.close()
    _destroy_now(win)


def _destroy_now(win) -> None:
    """Destroy ``win`` and everything it owns before the next test starts: its deferred
    deletions and timers run here, not inside the next test's event loop."""
    import gc

    from PySide6.QtCore import QCoreApplication, QEvent

    win.deleteLater()
    for _ in range(3):
        QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
        QCoreApplication.processEvents()
    gc.collect()
