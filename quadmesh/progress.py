"""Progress and cancellation inside a running :func:`quadmesh.pipeline.mesh_polygon`.

:func:`mesh_polygon` opens a *run* (:func:`running`) holding the caller's ``progress(stage,
fraction)`` and ``cancel() -> bool`` callbacks in a context variable, so the long loops deep in
the stages (the Schwarz–Christoffel solve, the arc choice, the disk construction, the
push-forward, the repair, the thin parts) reach them without passing callbacks through every
signature:

* :func:`checkpoint` — called inside loops; outside a run it returns at once. Within a run it
  looks at the clock on every call and, at most every :data:`INTERVAL` seconds, polls
  ``cancel()`` (raising :class:`~quadmesh.errors.Cancelled`) and forwards the loop's fraction.
* :func:`span` — maps the fraction [0, 1] of the code inside it into a sub-range of the
  enclosing range (optionally under another stage name), so nested loops report honest
  overall fractions; reported fractions never decrease.

The context variable is per thread: the thread that calls :func:`mesh_polygon` (the app's
worker thread) carries the run; other threads see no run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from contextvars import ContextVar

from .errors import Cancelled

__all__ = ["INTERVAL", "Run", "Steps", "active", "checkpoint", "running", "span"]

#: Seconds between two polls of ``cancel()`` (and two progress reports) from :func:`checkpoint`.
INTERVAL = 0.05

ProgressCallback = Callable[[str, float], None]
CancelCallback = Callable[[], bool]


class Run:
    """The callbacks of one :func:`mesh_polygon` call, the current stage name and the range
    ``[lo, hi]`` of overall fractions that the code running now maps its own fraction into."""

    __slots__ = ("cancel", "due", "hi", "interval", "last", "lo", "pending", "progress", "stage")

    def __init__(
        self,
        progress: ProgressCallback | None,
        cancel: CancelCallback | None,
        interval: float | None = None,
    ) -> None:
        self.progress = progress
        self.cancel = cancel
        self.stage = ""
        self.lo = self.hi = 0.0
        self.last = 0.0  # last fraction reported (reports never go back)
        self.pending = 0.0  # latest fraction given to checkpoint(), reported when due
        self.due = 0.0  # monotonic time of the next poll
        self.interval = INTERVAL if interval is None else float(interval)

    def poll(self) -> None:
        """Raise :class:`Cancelled` when ``cancel()`` says so."""
        if self.cancel is not None and self.cancel():
            where = f" during {self.stage}" if self.stage else ""
            raise Cancelled(f"meshing cancelled{where}")

    def emit(self, fraction: float) -> None:
        """Report ``fraction`` (clamped to [last reported, 1]) under the current stage name."""
        f = min(max(fraction, self.last), 1.0)
        self.last = f
        if self.progress is not None:
            self.progress(self.stage, f)

    def enter(self, stage: str, start: float, end: float | None = None) -> None:
        """A pipeline stage begins: poll ``cancel()``, then report ``start`` at once; inner
        fractions of the stage map to ``[start, end]`` (``end`` None: no inner progress)."""
        self.stage = stage
        self.lo = float(start)
        self.hi = self.lo if end is None else float(end)
        self.poll()
        self.emit(self.lo)
        self.pending = self.last
        self.due = time.monotonic() + self.interval


_RUN: ContextVar[Run | None] = ContextVar("quadmesh_run", default=None)


def active() -> Run | None:
    """The run of the :func:`mesh_polygon` call in progress in this thread, if any."""
    return _RUN.get()


def checkpoint(fraction: float | None = None) -> None:
    """A cancellation point inside a long loop; ``fraction`` (0..1) is how far the loop is
    within the innermost :func:`span` or stage. Costs one context-variable read and one clock
    read unless :data:`INTERVAL` has passed since the last poll; does nothing outside a run.
    The latest fraction is remembered, and reported by the first checkpoint (with or without
    a fraction) that polls after it if it moved the bar.

    Raises:
        Cancelled: the run's ``cancel()`` returned True.
    """
    run = _RUN.get()
    if run is None:
        return
    if fraction is not None:
        f = 0.0 if fraction < 0.0 else 1.0 if fraction > 1.0 else fraction
        run.pending = run.lo + (run.hi - run.lo) * f
    now = time.monotonic()
    if now < run.due:
        return
    run.due = now + run.interval
    run.poll()
    if run.pending > run.last:
        run.emit(run.pending)


@contextmanager
def span(start: float, end: float, stage: str | None = None) -> Iterator[None]:
    """Map the fractions reported inside the block to ``[start, end]`` of the enclosing range
    (both in 0..1), under the stage name ``stage`` if given. On normal exit the block's end
    fraction is reported (rate limited like :func:`checkpoint`)."""
    run = _RUN.get()
    if run is None:
        yield
        return
    saved = run.lo, run.hi, run.stage
    width = run.hi - run.lo
    run.lo, run.hi = run.lo + width * start, run.lo + width * end
    if stage is not None and stage != run.stage:
        run.stage = stage
        run.emit(run.lo)  # show the new name at once
        run.pending = run.last
    try:
        yield
        checkpoint(1.0)
    finally:
        run.lo, run.hi, run.stage = saved


@contextmanager
def running(
    progress: ProgressCallback | None, cancel: CancelCallback | None
) -> Iterator[Run | None]:
    """Make ``(progress, cancel)`` the current run of this thread for the block.

    Without callbacks, a run already open in this thread (a mesher called from inside another
    meshing job) keeps being polled for cancellation but receives no progress from the block;
    with no run at all, nothing is installed and :func:`checkpoint` stays a no-op.
    """
    outer = _RUN.get()
    if progress is None and cancel is None:
        if outer is None:
            yield None
            return
        cancel = outer.cancel
    run = Run(progress, cancel)
    token = _RUN.set(run)
    try:
        yield run
    finally:
        _RUN.reset(token)


class Steps:
    """A sequence of steps whose count is not known in advance (Newton iterations, function
    evaluations): step k (0, 1, …) covers ``[1 − q^k, 1 − q^(k+1)]`` of ``[start, 1]`` of the
    enclosing range, so every step moves the bar and the sequence never claims to be done
    before it is."""

    __slots__ = ("k", "q", "start")

    def __init__(self, q: float = 0.8, start: float = 0.0) -> None:
        self.k = 0
        self.q = float(q)
        self.start = float(start)

    def next(self) -> AbstractContextManager[None]:
        """The :func:`span` of the next step."""
        a = 1.0 - self.q**self.k
        self.k += 1
        b = 1.0 - self.q**self.k
        w = 1.0 - self.start
        return span(self.start + w * a, self.start + w * b)
