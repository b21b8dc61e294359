"""Background computation: a QObject worker moved to a QThread.

The job is any callable ``job(progress, cancel) -> result`` with the calling convention of
:func:`quadmesh.pipeline.mesh_polygon` (``progress(stage, fraction)``, ``cancel() -> bool``).
The worker reports through queued signals, so the GUI thread only ever touches widgets.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, QThread, Signal, Slot

from quadmesh.errors import Cancelled, QuadmeshError

__all__ = ["JobRunner", "MeshWorker"]

Job = Callable[[Callable[[str, float], None], Callable[[], bool]], Any]


class MeshWorker(QObject):
    """Runs one job in whatever thread it lives in and reports by signals."""

    progress = Signal(str, float)
    finished = Signal(object, float)
    failed = Signal(str)
    partial = Signal(object)  # what a failed run computed (emitted just before ``failed``)
    cancelled = Signal()
    done = Signal()

    def __init__(self, job: Job) -> None:
        super().__init__()
        self._job = job
        self._cancel = threading.Event()

    def request_cancel(self) -> None:
        """Ask the job to stop at its next cancellation point (thread safe).

        :func:`~quadmesh.pipeline.mesh_polygon` polls the flag between stages and, through
        :mod:`quadmesh.progress` (a per-thread run opened in this worker's thread), at most
        0.05 s apart inside its long loops, so a run stops well within a second."""
        self._cancel.set()

    def _report(self, stage: str, fraction: float) -> None:
        self.progress.emit(str(stage), float(fraction))

    @Slot()
    def run(self) -> None:
        """Run the job; emit ``finished(result, seconds)``, ``failed(message)`` or ``cancelled``."""
        t0 = time.perf_counter()
        try:
            result = self._job(self._report, self._cancel.is_set)
        except Cancelled:
            self.cancelled.emit()
        except QuadmeshError as exc:
            if exc.partial is not None:
                self.partial.emit(exc.partial)
            self.failed.emit(str(exc))
        except Exception as exc:  # the message reaches the user; the app keeps running
            tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
            self.failed.emit(f"unexpected error: {tb}")
        else:
            if self._cancel.is_set():
                self.cancelled.emit()
            else:
                self.finished.emit(result, time.perf_counter() - t0)
        self.done.emit()


class JobRunner(QObject):
    """Owns the thread of the current job; one job at a time."""

    progress = Signal(str, float)
    finished = Signal(object, float)
    failed = Signal(str)
    partial = Signal(object)
    cancelled = Signal()
    idle = Signal()

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._thread: QThread | None = None
        self._worker: MeshWorker | None = None

    @property
    def busy(self) -> bool:
        """True while a job runs."""
        return self._thread is not None

    def start(self, job: Job) -> None:
        """Start ``job`` in a new thread (RuntimeError if one is already running)."""
        if self.busy:
            raise RuntimeError("a computation is already running")
        thread = QThread()
        worker = MeshWorker(job)
        worker.moveToThread(thread)
        worker.progress.connect(self.progress)
        worker.finished.connect(self.finished)
        worker.failed.connect(self.failed)
        worker.partial.connect(self.partial)
        worker.cancelled.connect(self.cancelled)
        worker.done.connect(thread.quit)
        thread.started.connect(worker.run)
        thread.finished.connect(self._cleanup)
        self._thread, self._worker = thread, worker
        thread.start()

    def cancel(self) -> None:
        """Ask the running job to stop."""
        if self._worker is not None:
            self._worker.request_cancel()

    def wait(self, ms: int = 60000) -> bool:
        """Block until the thread ends (used at shutdown); True if it ended."""
        return self._thread.wait(ms) if self._thread is not None else True

    @Slot()
    def _cleanup(self) -> None:
        thread, worker = self._thread, self._worker
        self._thread = self._worker = None
        if worker is not None:
            worker.deleteLater()
        if thread is not None:
            thread.deleteLater()
        self.idle.emit()
