"""The thick pieces of one :func:`~quadmesh.pipeline.mesh_polygon` call in parallel processes.

Once the decomposition is known, each thick piece's own work — its Schwarz–Christoffel map and
arcs I_j (:func:`quadmesh.thick.prepare_piece`), and at a given (n, depth step) its disk mesh,
push-forward and local angle repair (:func:`quadmesh.thick.disk_and_image`) — reads nothing
of the other pieces. What couples the pieces stays in the calling process, in piece order:
the adaptive loop's choice of one (n, depth step) for all pieces (both sides of a channel must
carry the same crosscut vertex count), the angle checks that drive it, the numbering of the
assembled mesh and the thin parts glued onto the pieces' crosscuts (a few per cent of the time
on the bundled examples, so not worth shipping). The tasks are plain functions of their
arguments, so the mesh is the same, bit for bit, wherever they run.

:class:`PieceRunner` runs those tasks either inline (one after the other, as without it) or on
a :class:`concurrent.futures.Executor`: a :class:`~concurrent.futures.ProcessPoolExecutor` of
``MeshOptions.jobs`` workers that it makes itself (:func:`make_pool`), or any executor the
caller gives (the executor of a ``dask.distributed`` Client, ...). Either way the results are
taken in piece order and the first failure in piece order is raised — the error the serial run
raises, with the same class and message — after the pieces before it were kept for the
partial result, as serially. Only a decomposition with at least two thick pieces is shipped:
one piece gains nothing from a second process and would pay its start-up. A polygon meshed
as one corridor of straight cells, or by ``method="blocks"``, has no thick piece to ship (an
arm's body is meshed by a nested call, whose pieces are shipped again).

``MeshResult.timings`` then adds up the seconds the workers spent per stage (work, not the
wall time of the stage). A worker process that dies (killed, out of memory) fails the call
with the executor's own error (:class:`concurrent.futures.process.BrokenProcessPool`).

Progress is reported as pieces finish; cancellation is polled every
:data:`quadmesh.progress.INTERVAL` seconds while the pieces run: it cancels the tasks not yet
started and raises :class:`~quadmesh.errors.Cancelled` at once; the worker processes of the
runner's own pool are then stopped (a caller's executor keeps running the tasks it had
started, their results are dropped).
"""

from __future__ import annotations

import contextlib
import contextvars
import multiprocessing as mp
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from dataclasses import replace
from typing import Any

from .errors import ConformalMapError
from .progress import INTERVAL, checkpoint
from .result import MeshOptions
from .thick import PieceWork, disk_and_image, owner_namer, prepare_piece

__all__ = [
    "PieceRunner",
    "apply_disk",
    "attach_piece",
    "blas_threads",
    "disk_task",
    "make_pool",
    "prepare_task",
    "process_context",
]

#: Modules a ``forkserver`` imports once, so that its workers start with them loaded.
PRELOAD = [
    "quadmesh.thick",
    "quadmesh.conformal",
    "quadmesh.disk.assembly",
    "quadmesh.disk.region",
    "quadmesh.pushforward",
    "quadmesh.repair",
]
#: Loaded, these mean a Qt application, whose own threads rule out ``fork``.
QT_MODULES = ("PySide6.QtCore", "PyQt6.QtCore", "PySide2.QtCore", "PyQt5.QtCore")


def process_context() -> Any:
    """The multiprocessing context of the piece workers.

    On Linux, ``fork`` when the caller is the main thread and the only thread of the process
    (the command line): a worker starts in milliseconds with quadmesh loaded. Forking a process
    in which other threads run (the app meshes in a Qt worker thread, and Qt runs threads of
    its own that Python does not see) can copy a lock another thread holds, so there
    ``forkserver`` is used: a clean server process, started once per process, that imports
    quadmesh once (:data:`PRELOAD`) and forks the workers. Other platforms: ``spawn``. As for
    every ``forkserver`` or ``spawn`` pool, a script run as ``python script.py`` that meshes
    with jobs from a thread must keep its top-level code under ``if __name__ == "__main__":``
    (the workers import the main module).
    """
    methods = mp.get_all_start_methods()
    if sys.platform.startswith("linux") and "fork" in methods:
        main = threading.current_thread() is threading.main_thread()
        alone = main and threading.active_count() == 1
        if alone and not any(m in sys.modules for m in QT_MODULES):
            return mp.get_context("fork")
        if "forkserver" in methods:
            ctx = mp.get_context("forkserver")
            ctx.set_forkserver_preload(PRELOAD)
            return ctx
    return mp.get_context("spawn")


#: The BLAS limiter of the outermost :func:`blas_threads` in this process, and how deep the
#: nesting is (arms and bridges mesh their parts by nested calls).
_blas_limiter: Any = None
_blas_depth = 0


@contextlib.contextmanager
def blas_threads(threads: int | None) -> Iterator[None]:
    """A context in which the BLAS/LAPACK libraries loaded by numpy and scipy use at most
    ``threads`` threads (``MeshOptions.blas_threads``); their settings are restored when the
    outermost such context ends. None: nothing changes.

    The limit is process-wide state that other threads may be using, and changing it while
    another thread runs a BLAS call or sets it too is not safe (OpenBLAS keeps one global
    thread count; threadpoolctl's save-and-restore races). So only the main thread sets it:
    a call from any other thread (the app's mesher thread, a thread pool) runs with the
    process's limits as they are — the app sets its limit once at start-up."""
    global _blas_limiter, _blas_depth
    if threads is None or threading.current_thread() is not threading.main_thread():
        yield
        return
    if _blas_depth == 0:
        from threadpoolctl import threadpool_limits

        _blas_limiter = threadpool_limits(limits=int(threads), user_api="blas")
    _blas_depth += 1
    try:
        yield
    finally:
        _blas_depth -= 1
        if _blas_depth == 0:
            _blas_limiter.restore_original_limits()
            _blas_limiter = None


def make_pool(jobs: int) -> ProcessPoolExecutor:
    """A pool of ``jobs`` worker processes for the pieces (:func:`process_context`)."""
    # what the tasks and their results need, loaded before a fork so no worker imports it again
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)

    return ProcessPoolExecutor(jobs, mp_context=process_context())


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel what ``pool`` has not started and terminate its worker processes."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(1.0)


def prepare_task(
    piece: Any, options: MeshOptions, dec: Any
) -> tuple[PieceWork | ConformalMapError, dict[str, float]]:
    """Task: :func:`~quadmesh.thick.prepare_piece` of one thick piece; returns its
    :class:`~quadmesh.thick.PieceWork` without the back references to the decomposition
    (``name``, ``piece``; :func:`attach_piece` restores them), or the
    :class:`~quadmesh.errors.ConformalMapError` its map failed with, and the seconds it spent
    per stage."""
    timings: dict[str, float] = {}
    try:
        with blas_threads(options.blas_threads):
            pd = prepare_piece(piece, options, timings, dec)
    except ConformalMapError as exc:
        return exc, timings  # the caller names every piece without a map at once
    return replace(pd, name=None, piece=None), timings


def attach_piece(pd: PieceWork, dec: Any) -> PieceWork:
    """``pd`` of :func:`prepare_task` with its back references to ``dec`` restored."""
    piece = dec.thick[pd.index]
    pd.name, pd.piece = owner_namer(dec, piece), piece
    return pd


def disk_task(
    pd: PieceWork, n: int, step: float, dmax: float | None, options: MeshOptions
) -> tuple[Any, Any, Any, float | None, Any, dict[str, float]]:
    """Task: :func:`~quadmesh.thick.disk_and_image` of one piece at (n, step, dmax), on a copy
    of ``pd``. Returns (disk mesh, image, and what the stage changed in ``pd``: its intervals,
    lemma_A and repair report, then the seconds per stage); :func:`apply_disk` makes the
    changes."""
    pd = replace(pd)
    timings: dict[str, float] = {}
    with blas_threads(options.blas_threads):
        disk, image = disk_and_image(pd, n, step, dmax, options, timings)
    return disk, image, pd.intervals, pd.lemma_A, pd.repair, timings


def apply_disk(pd: PieceWork, out: tuple) -> tuple[Any, Any]:
    """Make the changes a :func:`disk_task` result ``out`` reports in ``pd``; returns (disk
    mesh, image)."""
    disk, image, pd.intervals, pd.lemma_A, pd.repair, _ = out
    return disk, image


def _isolated(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)`` outside any meshing run: a forked worker would otherwise inherit the
    calling thread's run and report progress through (a copy of) its callbacks."""
    return contextvars.Context().run(fn, *args)


def _merge(timings: dict[str, float], more: dict[str, float]) -> None:
    for k, v in more.items():
        timings[k] = timings.get(k, 0.0) + v


class PieceRunner:
    """Runs per-piece tasks inline or on an executor (module docstring); results in order.

    ``executor``: the caller's executor (used as it is, never shut down); else ``jobs`` > 1
    makes a process pool on first use, which :meth:`close` shuts down.
    """

    def __init__(self, jobs: int = 1, executor: Executor | None = None) -> None:
        self.jobs = int(jobs)
        self.given = executor
        self.pool: ProcessPoolExecutor | None = None

    @property
    def executor(self) -> Executor | None:
        """The executor in use so far (the caller's, or the pool once made), else None."""
        return self.given if self.given is not None else self.pool

    def _executor_for(self, count: int) -> Executor | None:
        """Where ``count`` tasks run: None (inline) for fewer than two, or without an executor
        and ``jobs`` = 1."""
        if count < 2:
            return None
        if self.given is not None:
            return self.given
        if self.jobs < 2:
            return None
        if self.pool is None:
            self.pool = make_pool(min(self.jobs, count))
        return self.pool

    def run(
        self,
        fn: Callable[..., Any],
        tasks: Sequence[tuple],
        timings: dict[str, float],
        report: Callable[[float, float], None],
        cost: Sequence[float] | None = None,
    ) -> Iterator[Any]:
        """Yield ``fn(*task)`` for every task, in order; the last item of each result (the
        task's seconds per stage) is added to ``timings``. ``report(lo, hi)``: the share
        [lo, hi] of the tasks' stage now covered (inline: task i's share; in parallel: the
        finished tasks'). ``cost``: a guess of each task's work; in parallel the costliest
        tasks are submitted first, so that a large piece does not start last while the other
        workers idle. A task's exception is raised when its turn comes (the tasks after
        it are then cancelled, as they are when the caller closes the generator early: use
        it in :func:`contextlib.closing`)."""
        m = len(tasks)
        executor = self._executor_for(m)
        if executor is None:
            for i, args in enumerate(tasks):
                report(i / m, (i + 1) / m)
                out = fn(*args)
                _merge(timings, out[-1])
                yield out
            return
        order = sorted(range(m), key=lambda i: -cost[i]) if cost is not None else range(m)
        submitted = {i: executor.submit(_isolated, fn, *tasks[i]) for i in order}
        futures: list[Future] = [submitted[i] for i in range(m)]
        finished = 0
        report(0.0, 1.0 / m)
        try:
            for fut in futures:
                while not fut.done():
                    running = [f for f in futures if not f.done()]
                    wait(running, timeout=INTERVAL, return_when=FIRST_COMPLETED)
                    checkpoint()  # polls cancel()
                    finished = self._advance(futures, finished, report)
                # also when ``fut`` was already done: the stage's end (every task finished)
                # is reported whatever order the workers finished in
                finished = self._advance(futures, finished, report)
                out = fut.result()
                _merge(timings, out[-1])
                yield out
        finally:
            for fut in futures:
                fut.cancel()  # those not started: the run failed or was cancelled

    @staticmethod
    def _advance(
        futures: Sequence[Future], finished: int, report: Callable[[float, float], None]
    ) -> int:
        """Report the share of finished tasks if it grew; returns the new count."""
        m = len(futures)
        now = sum(f.done() for f in futures)
        if now > finished:
            report(now / m, min(now + 1, m) / m)
        return max(now, finished)

    def close(self, failed: bool = False) -> None:
        """Shut the runner's own pool down (``failed``: at once, stopping its workers)."""
        pool, self.pool = self.pool, None
        if pool is None:
            return
        if failed:
            _stop_workers(pool)
        else:
            pool.shutdown(wait=True)
