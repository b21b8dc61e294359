"""Batch meshing: every polygon file of a folder, one mesh file each, in parallel processes.

:func:`mesh_files` meshes a list of polygon files (:func:`polygon_files` lists those of a
folder) and writes one mesh per input into an output folder. Each file is handled by
:func:`mesh_file` — read (:func:`quadmesh.io.read_polygon`), validate, mesh
(:func:`quadmesh.pipeline.mesh_polygon`), write (:func:`quadmesh.io.write_mesh`) and read
back (:func:`check_written`) — which never raises for a bad polygon: a refusal
(:class:`~quadmesh.errors.PolygonError`, :class:`~quadmesh.errors.InputFormatError`, a stage's
:class:`~quadmesh.errors.QuadmeshError`, an unreadable file) comes back as a
:class:`BatchResult` with ``status="failed"``, the error's class and message.

Where the work runs:

* ``executor``: any :class:`concurrent.futures.Executor` (a ``ThreadPoolExecutor``, a
  ``ProcessPoolExecutor``, the executor of a ``dask.distributed`` Client, ...) receives one
  ``submit(mesh_file, ...)`` per file;
* else ``jobs`` > 1: a :class:`~concurrent.futures.ProcessPoolExecutor` of ``jobs`` workers;
* else the files are meshed one after the other in this process.

In parallel the files are started largest first (file size as the guess of the work), so
that a long polygon does not start last; the results keep the order of the inputs.

``timeout``: a polygon still being meshed ``timeout`` seconds after its start is stopped at
the pipeline's next cancellation checkpoint (polled every 0.05 s inside the long loops) and
reported with ``status="timeout"``; this works in any executor. Without a user executor,
each polygon then runs in its own worker process (at most ``jobs`` at a time) which is also
killed :data:`KILL_GRACE` seconds past the limit should a step run on without reaching a
checkpoint.

The meshes do not depend on where they were computed: the same input gives the same vertex
coordinates (bit for bit) and quads serially, in worker processes or in threads.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import Cancelled, InputFormatError, MeshVerificationError, QuadmeshError
from .result import MeshOptions

__all__ = [
    "KILL_GRACE",
    "POLYGON_SUFFIXES",
    "BatchResult",
    "check_written",
    "format_table",
    "mesh_file",
    "mesh_files",
    "output_paths",
    "polygon_files",
]

POLYGON_SUFFIXES = (".json", ".geojson", ".svg", ".csv", ".txt", ".dat", ".xy", ".tsv")
"""File extensions :func:`polygon_files` picks up (those :func:`quadmesh.io.read_polygon`
reads)."""

KILL_GRACE = 2.0
"""Seconds past ``timeout`` after which quadmesh's own worker process of a polygon is killed
(the polygon normally stops at a checkpoint right at ``timeout``)."""

STATUSES = ("meshed", "failed", "timeout", "crashed")


@dataclass(frozen=True)
class BatchResult:
    """The outcome of meshing one polygon file.

    ``status``: ``"meshed"`` (mesh written and checked), ``"failed"`` (the file or polygon was
    refused, or a stage could not mesh it: ``error`` is the exception's class name, ``stage``
    the pipeline stage, ``message`` the reason), ``"timeout"`` or ``"crashed"`` (an
    unexpected exception or a worker process that died). ``time``: seconds spent on the file
    (read, mesh, write, read back); ``mesh_time``: in :func:`~quadmesh.pipeline.mesh_polygon`
    alone. ``n``: the polygon's vertex count after validation; ``quads``, ``vertices``,
    ``min_angle``, ``max_angle``: of the written mesh (new angles in degrees). ``origin``: the
    written vertices are relative to this point (0 unless the polygon is far from (0, 0));
    ``notes``: what reading and validation changed (dropped points, reversed orientation).
    ``timings``: seconds per pipeline stage."""

    path: Path
    output: Path | None
    status: str
    time: float
    mesh_time: float | None = None
    n: int | None = None
    quads: int | None = None
    vertices: int | None = None
    min_angle: float | None = None
    max_angle: float | None = None
    origin: complex = 0j
    error: str | None = None
    stage: str | None = None
    message: str | None = None
    notes: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when the mesh was written and checked."""
        return self.status == "meshed"


def polygon_files(folder: str | Path) -> list[Path]:
    """The polygon files directly inside ``folder`` (extensions :data:`POLYGON_SUFFIXES`,
    hidden files skipped), sorted by name. Raises :class:`InputFormatError` if ``folder`` is
    not a directory."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputFormatError(f"{folder}: not a folder")
    return sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in POLYGON_SUFFIXES
    )


def _normalise_format(fmt: str) -> str:
    """``fmt`` as a mesh file extension with its dot (``"vtk"`` -> ``".vtk"``)."""
    from .io import MESH_FORMATS

    ext = "." + fmt.lower().lstrip(".")
    if ext not in MESH_FORMATS:
        raise InputFormatError(
            f"unsupported mesh format {fmt!r} (use " + ", ".join(f[1:] for f in MESH_FORMATS) + ")"
        )
    return ext


def output_paths(paths: Sequence[Path], outdir: Path, fmt: str) -> list[Path]:
    """The mesh file of each input: ``outdir/<stem>.<fmt>``; inputs sharing a stem (``a.json``
    and ``a.csv``) get ``<stem>_<extension>.<fmt>``, and any remaining clash a running number.
    Raises :class:`InputFormatError` if an output would overwrite one of the inputs."""
    ext = _normalise_format(fmt)
    stems = [p.stem for p in paths]
    names = [
        f"{p.stem}_{p.suffix.lstrip('.').lower()}" if stems.count(p.stem) > 1 else p.stem
        for p in paths
    ]
    seen: dict[str, int] = {}
    out = []
    for name in names:
        k = seen.get(name, 0)
        seen[name] = k + 1
        out.append(outdir / (f"{name}{ext}" if k == 0 else f"{name}_{k + 1}{ext}"))
    inputs = {p.resolve() for p in paths}
    for p, o in zip(paths, out):
        if o.resolve() in inputs:
            raise InputFormatError(
                f"{o}: the mesh of {p} would overwrite an input polygon file; "
                "choose another output folder or format"
            )
    return out


def check_written(path: Path, result, poly) -> None:
    """Read the mesh file ``path`` back; unless it holds exactly ``result.mesh`` (vertex
    coordinates bit for bit, quads, origin), verify what it holds against ``poly``.
    Raises :class:`MeshVerificationError` if that fails."""
    from .io import read_mesh_with_origin

    back, origin = read_mesh_with_origin(path)
    if path.suffix.lower() != ".json":
        origin = result.mesh_origin
    mesh = result.mesh
    if (
        origin == result.mesh_origin
        and np.array_equal(back.vertices, mesh.vertices)
        and np.array_equal(back.quads, mesh.quads)
    ):
        return
    report = back.verify(poly, origin=origin)
    if not report.ok:
        raise MeshVerificationError(
            f"{path}: the coordinates as written fail verification: "
            + "; ".join(report.problems[:5])
        )


def _message(exc: BaseException) -> str:
    """An exception's message without the ``[stage]`` prefix of :class:`QuadmeshError`."""
    return str(exc.args[0]) if isinstance(exc, QuadmeshError) and exc.args else str(exc)


def mesh_file(
    path: str | Path,
    output: str | Path,
    options: MeshOptions | None = None,
    timeout: float | None = None,
    relative_size: float | None = None,
) -> BatchResult:
    """Mesh the polygon file ``path`` with ``options`` and write the mesh to ``output`` (format
    from its extension; written under a temporary name and renamed, so ``output`` never holds
    half a mesh). Never raises for a bad file or polygon: every outcome is a
    :class:`BatchResult`.

    ``timeout``: seconds after which the meshing stops at its next cancellation checkpoint
    (``status="timeout"``). ``relative_size``: the blocks' target edge as a fraction of this
    polygon's diameter (overrides ``options.size``). A top-level function, so executors can
    pickle it."""
    from dataclasses import replace

    from .io import read_polygon, write_mesh
    from .pipeline import mesh_polygon
    from .polygon import validate_polygon

    path, output = Path(path), Path(output)
    t0 = time.perf_counter()
    partial = output.with_name(f".{output.stem}.partial-{os.getpid()}{output.suffix}")
    fields: dict = {}
    try:
        verts, notes = read_polygon(path)
        poly = validate_polygon(verts)
        notes = list(notes)
        if poly.reversed_input:
            notes.append("the polygon was clockwise and has been reversed")
        fields.update(n=poly.n, notes=tuple(notes))
        if relative_size is not None:
            options = replace(options or MeshOptions(), size=relative_size * poly.diameter)
        deadline = None if timeout is None else time.perf_counter() + timeout
        t1 = time.perf_counter()
        result = mesh_polygon(
            poly,
            options,
            cancel=None if deadline is None else lambda: time.perf_counter() > deadline,
        )
        fields["mesh_time"] = time.perf_counter() - t1
        if result.fallback:
            fields["notes"] = (*fields["notes"], result.fallback)
        write_mesh(partial, result.mesh, origin=result.mesh_origin)
        check_written(partial, result, poly)
        os.replace(partial, output)
    except Cancelled as exc:
        where = _message(exc).replace("meshing cancelled", "stopped")
        return BatchResult(
            path,
            None,
            "timeout",
            time.perf_counter() - t0,
            error="Timeout",
            stage=exc.stage,
            message=f"no mesh within {timeout:g} s ({where})",
            **fields,
        )
    except (QuadmeshError, OSError, ValueError) as exc:
        stage = exc.stage if isinstance(exc, QuadmeshError) else "io"
        return BatchResult(
            path,
            None,
            "failed",
            time.perf_counter() - t0,
            error=type(exc).__name__,
            stage=stage,
            message=_message(exc),
            **fields,
        )
    except Exception as exc:  # a bug, not a refusal: reported as such, the batch goes on
        return BatchResult(
            path,
            None,
            "crashed",
            time.perf_counter() - t0,
            error=type(exc).__name__,
            stage="-",
            message=f"{type(exc).__name__}: {exc}",
            **fields,
        )
    finally:
        partial.unlink(missing_ok=True)
    q = result.quality
    return BatchResult(
        path,
        output,
        "meshed",
        time.perf_counter() - t0,
        quads=int(q.n_quads),
        vertices=int(q.n_vertices),
        min_angle=float(q.min_angle),
        max_angle=float(q.max_angle),
        origin=complex(result.mesh_origin),
        timings=dict(result.timings),
        **fields,
    )


def _lost(path: Path, status: str, error: str, message: str, seconds: float) -> BatchResult:
    """The result of a file whose worker gave no answer (died, or killed on timeout)."""
    return BatchResult(path, None, status, seconds, error=error, stage="-", message=message)


def _run_executor(
    executor: Executor,
    jobs: list[tuple[Path, Path]],
    options: MeshOptions | None,
    timeout: float | None,
    on_result: Callable[[int, BatchResult], None] | None,
    relative_size: float | None = None,
) -> list[BatchResult]:
    """Submit :func:`mesh_file` for every (path, output) to ``executor``; results in order."""
    t0 = time.perf_counter()
    futures: dict[Future, int] = {
        executor.submit(mesh_file, p, o, options, timeout, relative_size): i
        for i, (p, o) in enumerate(jobs)
    }
    results: list[BatchResult | None] = [None] * len(jobs)
    for fut in as_completed(futures):
        i = futures[fut]
        try:
            res = fut.result()
        except Exception as exc:  # the executor lost the task (a worker process died, ...)
            res = _lost(
                jobs[i][0],
                "crashed",
                type(exc).__name__,
                f"the worker gave no result ({type(exc).__name__}: {exc})",
                time.perf_counter() - t0,
            )
        results[i] = res
        if on_result is not None:
            on_result(i, res)
    return [r for r in results if r is not None]


def _run_own_processes(
    jobs: list[tuple[Path, Path]],
    workers: int,
    options: MeshOptions | None,
    timeout: float,
    on_result: Callable[[int, BatchResult], None] | None,
    relative_size: float | None = None,
) -> list[BatchResult]:
    """Every file in its own worker process (at most ``workers`` at a time), killed
    :data:`KILL_GRACE` seconds past ``timeout`` (:func:`quadmesh.benchmark.run_in_processes`)."""
    from .benchmark import run_in_processes

    def killed(i: int, seconds: float) -> BatchResult:
        return _lost(
            jobs[i][0],
            "timeout",
            "Timeout",
            f"no mesh within {timeout:g} s (the worker was stopped)",
            seconds,
        )

    def died(i: int, seconds: float) -> BatchResult:
        return _lost(
            jobs[i][0],
            "crashed",
            "WorkerDied",
            "the worker process died (out of memory?)",
            seconds,
        )

    return run_in_processes(
        mesh_file,
        [(p, o, options, timeout, relative_size) for p, o in jobs],
        timeout=timeout + KILL_GRACE,
        workers=workers,
        on_timeout=killed,
        on_died=died,
        on_result=on_result,
    )


def mesh_files(
    paths: Iterable[str | Path],
    outdir: str | Path,
    *,
    executor: Executor | None = None,
    jobs: int = 1,
    fmt: str = "json",
    timeout: float | None = None,
    options: MeshOptions | None = None,
    relative_size: float | None = None,
    on_result: Callable[[int, BatchResult], None] | None = None,
) -> list[BatchResult]:
    """Mesh every polygon file of ``paths`` into ``outdir`` (created if missing) as
    ``<stem>.<fmt>`` (:func:`output_paths`); one :class:`BatchResult` per file, in the order
    of ``paths``. A bad file never stops the batch: it comes back with ``status="failed"``.

    Args:
        executor: runs the files (``submit(mesh_file, ...)``); any
            :class:`concurrent.futures.Executor`. Default: see ``jobs``.
        jobs: without ``executor``, the number of worker processes (1: this process, unless
            ``timeout`` is set).
        fmt: mesh format, one of ``json vtk vtu msh obj ply mesh``.
        timeout: seconds per polygon (see the module's docstring); None: no limit.
        options: :class:`MeshOptions` for every polygon (default: the defaults).
        relative_size: for ``method="blocks"``, the target edge as a fraction of each
            polygon's own diameter (overrides ``options.size``).
        on_result: ``on_result(i, result)`` called as the i-th file finishes.

    Raises:
        InputFormatError: unknown format, or an output would overwrite an input.
        ValueError: ``jobs`` < 1 or ``timeout`` <= 0.
    """
    paths = [Path(p) for p in paths]
    outdir = Path(outdir)
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    if timeout is not None and not timeout > 0:
        raise ValueError(f"timeout must be positive, got {timeout}")
    work = list(zip(paths, output_paths(paths, outdir, fmt)))
    outdir.mkdir(parents=True, exist_ok=True)
    if executor is None and timeout is None and (jobs == 1 or len(work) <= 1):
        results = []
        for i, (p, o) in enumerate(work):
            results.append(mesh_file(p, o, options, None, relative_size))
            if on_result is not None:
                on_result(i, results[-1])
        return results
    # in parallel, the largest files first: a long polygon started last would leave the other
    # workers idle at the end (longest-first keeps the wall time near sum / workers)
    order = sorted(range(len(work)), key=lambda i: -_size(work[i][0]))
    queued = [work[i] for i in order]

    def back(k: int, r: BatchResult) -> None:
        if on_result is not None:
            on_result(order[k], r)

    if executor is not None:
        done = _run_executor(executor, queued, options, timeout, back, relative_size)
    elif timeout is not None:
        done = _run_own_processes(queued, jobs, options, timeout, back, relative_size)
    else:
        from .benchmark import process_context

        with ProcessPoolExecutor(min(jobs, len(work)), mp_context=process_context()) as pool:
            done = _run_executor(pool, queued, options, None, back, relative_size)
    results: list[BatchResult] = list(done)
    for k, i in enumerate(order):
        results[i] = done[k]
    return results


def _size(path: Path) -> int:
    """Bytes of ``path`` (0 when it cannot be read): the cost guess for scheduling."""
    try:
        return path.stat().st_size
    except OSError:
        return 0


def format_table(results: Sequence[BatchResult], *, stats: bool = False) -> str:
    """One line per file: name, n, quads, min and max new angle, seconds, and the status or
    the error class and message; with ``stats`` also the seconds in the mesher and per stage."""
    name_w = max([4, *(len(r.path.name) for r in results)])
    stages: list[str] = []
    if stats:
        for r in results:
            stages += [s for s in r.timings if s not in stages]
    head = (
        f"{'file':{name_w}s} {'n':>5} {'quads':>9} {'min °':>8} {'max °':>8} {'time s':>7}"
        + ("".join(f" {s[:9]:>9}" for s in ["mesher", *stages]) if stats else "")
        + "  status"
    )
    lines = [head]

    def num(x, fmt: str, w: int) -> str:
        return f"{'-':>{w}}" if x is None else f"{x:{w}{fmt}}"

    for r in results:
        cells = (
            f"{r.path.name:{name_w}s} {num(r.n, 'd', 5)} {num(r.quads, 'd', 9)} "
            f"{num(r.min_angle, '.3f', 8)} {num(r.max_angle, '.3f', 8)} {r.time:7.2f}"
        )
        if stats:
            cells += num(r.mesh_time, ".2f", 10)
            cells += "".join(num(r.timings.get(s), ".2f", 10) for s in stages)
        status = "meshed" if r.ok else f"{r.status}: {r.error} [{r.stage}] {r.message}"
        lines.append(cells + "  " + status)
    return "\n".join(lines)
