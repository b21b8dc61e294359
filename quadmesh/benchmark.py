"""Benchmarks of the mesher: time and quad count against the number of vertices n.

``quadmesh bench`` (or ``python -m quadmesh.benchmark``):

* default: smooth random star-shaped polygons (the family of the bundled ``star_*``
  examples) with n = 10, 30, 100, 300, 1000 (up to ``--max-n``): time of every stage, quads,
  quads per vertex, and the fitted exponents of time and quads against n;
* ``--examples``: every bundled example, with the same columns (or the reason it failed);
* ``--outlines [--seed S]``: one generated outline of every family of
  :mod:`quadmesh.outlines` (floor plans, pixel contours, multi-scale notches, spiky stars,
  coastlines, keyholes, pen strokes), with the same columns and the adaptive fixes;
* ``--families [--family NAME] [--limit K] [--timeout S] [--workers W]``: the corridor
  families of :mod:`quadmesh.families` (pen strokes, glyphs, image contours, rivers, coasts,
  random walks), every polygon meshed in a worker process killed after S seconds; one table
  row per family (meshed/total, quads per vertex, time, smallest edge / local width,
  length/width) and a summary of the failure reasons;
* ``--vs-gmsh [--limit K]``: side by side with Gmsh's quad mesher (frontal-Delaunay for quads,
  Blossom recombination, element size diameter / 40) on outlines of 6–100 vertices: times,
  quads, Gmsh's leftover triangles and its share of quads with all new angles in
  [60°, 120°] (the optional ``gmsh`` package; without it a one-line message);
* ``--disk``: the disk construction alone (Lemma 2.2 + piece meshes) for m = 10, 100, 1000
  random admissible arcs: time, pieces and quads.

A benchmark, not a test: the numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Callable, Sequence

import numpy as np

from .pipeline import mesh_polygon
from .result import MeshOptions


def smooth_star(n: int, seed: int = 0, amplitude: float = 0.35) -> np.ndarray:
    """A star-shaped polygon with n vertices whose radius is a smooth random function of
    the angle (a few low Fourier modes), counter-clockwise, as an (n, 2) array."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    t += np.linspace(0, 2 * np.pi, n, endpoint=False) - t  # evenly spaced angles
    modes = np.arange(1, 6)
    a = rng.normal(size=modes.size) / modes
    b = rng.normal(size=modes.size) / modes
    r = 1 + amplitude * (np.cos(np.outer(t, modes)) @ a + np.sin(np.outer(t, modes)) @ b) / 2
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


SIZES = (10, 30, 100, 300, 1000)


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MB; ``getrusage``), NaN where the
    platform does not report it."""
    try:
        import resource
    except ImportError:  # not on Windows
        return float("nan")
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run(max_n: int = 1000, repeat: int = 1, options: MeshOptions | None = None) -> list[dict]:
    """Mesh stars of n = 10, 30, 100, 300, 1000 (≤ max_n) vertices; one row per n, with the
    process's peak resident memory after it (sizes run in increasing order, so the row of the
    largest n holds the peak of the whole benchmark)."""
    rows = []
    for n in (m for m in SIZES if m <= max_n):
        poly = smooth_star(n, seed=n)
        best = None
        for _ in range(repeat):
            t0 = time.perf_counter()
            result = mesh_polygon(poly, options)
            total = time.perf_counter() - t0
            if best is None or total < best[0]:
                best = (total, result)
        total, result = best
        rows.append(
            {
                "n": n,
                "total": total,
                "quads": result.quality.n_quads,
                "min": result.quality.min_angle,
                "max": result.quality.max_angle,
                "n_used": result.pieces[0].n_used,
                "min_edge_lfs": result.quality.min_edge_lfs,
                "peak_mb": peak_rss_mb(),
                **{f"t_{k}": v for k, v in result.timings.items()},
            }
        )
    return rows


def _slope(x: list[float], y: list[float]) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


_SIZE_HEAD = f" {'min edge/lfs':>12} {'<1/1000':>8} {'<1/50':>7}"


def _size_cells(q) -> str:
    """The size columns of a quality report: smallest edge / local feature size, and the
    percentages of edges below 1/1000 and 1/50 of their local feature size."""
    if q.min_edge_lfs is None:
        return f" {'-':>12} {'-':>8} {'-':>7}"
    return (
        f" {q.min_edge_lfs:12.3g} {100 * q.share_below_floor:7.3g}% "
        f"{100 * q.share_below_warn:6.3g}%"
    )


def _size_row(q) -> dict:
    """The size fields of a quality report for a benchmark row."""
    return {
        "min_edge_lfs": q.min_edge_lfs,
        "median_edge_lfs": q.median_edge_lfs,
        "share_below_floor": q.share_below_floor,
        "share_below_warn": q.share_below_warn,
    }


def run_examples(names: list[str] | None = None) -> list[dict]:
    """Mesh every bundled example (or those named) and print one line each (or why it
    failed): time, quads, quads per vertex, n used, smallest edge / local feature size and
    the shares of edges below 1/1000 and 1/50 of it. Returns the rows."""
    from .errors import QuadmeshError
    from .examples import example_names, load_example

    rows = []
    print(
        f"{'example':22s} {'n':>5} {'total s':>8} {'quads':>9} {'quads/n':>8} {'n_used':>6}"
        + _SIZE_HEAD
    )
    for name in names or example_names():
        poly = load_example(name)
        t0 = time.perf_counter()
        try:
            r = mesh_polygon(poly)
        except QuadmeshError as exc:
            dt = time.perf_counter() - t0
            print(f"{name:22s} {len(poly):5d} {dt:8.2f} failed: {exc}")
            rows.append({"name": name, "n": len(poly), "total": dt, "failed": exc.stage})
            continue
        dt = time.perf_counter() - t0
        q = r.quality
        print(
            f"{name:22s} {len(poly):5d} {dt:8.2f} {q.n_quads:9d} "
            f"{q.n_quads / len(poly):8.0f} {r.pieces[0].n_used if r.pieces else 0:6d}"
            + _size_cells(q),
            flush=True,
        )
        rows.append({"name": name, "n": len(poly), "total": dt, "quads": q.n_quads, **_size_row(q)})
    return rows


def _fix_tags(fixes) -> str:
    """Short tags for the adaptive fixes of a result: local repair, depth step, n."""
    tags = []
    for f in fixes:
        if "repaired locally" in f:
            tag = "repaired"
        elif "depth step lowered to" in f:
            tag = "depth step " + f.rsplit("to", 1)[-1].strip()
        elif "n raised to" in f:
            tag = "n " + f.rsplit("to", 1)[-1].strip()
        else:
            tag = f[:30]
        if tag not in tags:
            tags.append(tag)
    return ", ".join(tags)


def run_outlines(seed: int = 0) -> list[dict]:
    """Mesh one outline of every family of :mod:`quadmesh.outlines`; print one line each
    (or the stage and reason of the failure) and return the rows."""
    from .errors import QuadmeshError
    from .outlines import stress_outlines

    rows = []
    print(
        f"{'outline':22s} {'n':>5} {'total s':>8} {'quads':>9} {'quads/n':>8} {'n_used':>6}"
        + _SIZE_HEAD
        + "  fixes"
    )
    for name, poly in stress_outlines(seed).items():
        t0 = time.perf_counter()
        try:
            r = mesh_polygon(poly)
        except QuadmeshError as exc:
            dt = time.perf_counter() - t0
            print(f"{name:22s} {len(poly):5d} {dt:8.2f} failed in {exc.stage}: {exc}")
            rows.append({"name": name, "n": len(poly), "total": dt, "failed": exc.stage})
            continue
        dt = time.perf_counter() - t0
        q = r.quality
        fixes = _fix_tags(f for p in r.pieces for f in p.fixes)
        n_used = max((p.n_used for p in r.pieces), default=0)
        print(
            f"{name:22s} {len(poly):5d} {dt:8.2f} {q.n_quads:9d} {q.n_quads / len(poly):8.0f} "
            f"{n_used:6d}" + _size_cells(q) + f"  {fixes}",
            flush=True,
        )
        rows.append({"name": name, "n": len(poly), "total": dt, "quads": q.n_quads, **_size_row(q)})
    ok = [r for r in rows if "failed" not in r]
    print(f"{len(ok)} of {len(rows)} outlines meshed and verified")
    return rows


def _mesh_vertices(vertices: np.ndarray, options: MeshOptions | None) -> dict:
    """Mesh ``vertices``; a small result dict (status, time, quads and sizes or the error)."""
    from .errors import QuadmeshError

    t0 = time.perf_counter()
    try:
        r = mesh_polygon(vertices, options)
    except QuadmeshError as exc:
        out = {"status": "failed", "error": type(exc).__name__, "stage": exc.stage}
        out["message"] = str(exc)
    except Exception as exc:  # a bug, not a refusal: reported as such
        out = {"status": "crashed", "error": type(exc).__name__, "stage": "-"}
        out["message"] = f"{type(exc).__name__}: {exc}"
    else:
        out = {"status": "meshed", "quads": int(r.quality.n_quads)}
        out["min_angle"], out["max_angle"] = r.quality.min_angle, r.quality.max_angle
        if r.options.method == "blocks":
            out["blocks"] = r.blocks is not None  # False: fell back to the paper's construction
        out.update(_size_row(r.quality))
    out["time"] = time.perf_counter() - t0
    return out


def process_context():
    """The multiprocessing context of the worker processes: ``fork`` where the platform has
    it (a worker starts in milliseconds with quadmesh already imported), else ``spawn``."""
    import multiprocessing as mp

    return mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")


def _call_worker(conn, target, args: tuple) -> None:
    """Worker process body: send ``target(*args)`` through ``conn``."""
    conn.send(target(*args))
    conn.close()


def run_in_processes(
    target: Callable,
    arg_tuples: Sequence[tuple],
    *,
    timeout: float | None,
    workers: int = 1,
    on_timeout: Callable[[int, float], object],
    on_died: Callable[[int, float], object],
    on_result: Callable[[int, object], None] | None = None,
) -> list:
    """Call ``target(*args)`` for every ``args`` of ``arg_tuples`` in its own worker process
    (at most ``workers`` at a time) and return the values in order. A worker still running
    after ``timeout`` seconds (None: no limit) is killed and its value is
    ``on_timeout(i, seconds)``; a worker that dies without answering gets
    ``on_died(i, seconds)``. ``on_result(i, value)`` is called as each call finishes."""
    from multiprocessing.connection import wait

    ctx = process_context()
    pending = list(range(len(arg_tuples)))
    running: dict = {}
    results: list = [None] * len(arg_tuples)
    limit = float("inf") if timeout is None else timeout

    def finish(i: int, res: object) -> None:
        results[i] = res
        if on_result is not None:
            on_result(i, res)

    while pending or running:
        while pending and len(running) < max(1, workers):
            i = pending.pop(0)
            recv, send = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_call_worker, args=(send, target, arg_tuples[i]), daemon=True)
            proc.start()
            send.close()
            running[recv] = (i, proc, time.perf_counter())
        now = time.perf_counter()
        left = min(t0 + limit - now for _, _, t0 in running.values())
        for conn in wait(list(running), timeout=None if left == float("inf") else max(left, 0.0)):
            i, proc, t0 = running.pop(conn)
            try:
                res = conn.recv()
            except EOFError:
                res = on_died(i, time.perf_counter() - t0)
            conn.close()
            proc.join()
            finish(i, res)
        now = time.perf_counter()
        for conn, (i, proc, t0) in list(running.items()):
            if now - t0 >= limit:
                proc.kill()
                proc.join()
                conn.close()
                del running[conn]
                finish(i, on_timeout(i, now - t0))
    return results


def mesh_with_timeout(
    polygons: list[np.ndarray],
    timeout: float = 60.0,
    workers: int = 1,
    options: MeshOptions | None = None,
    on_result=None,
) -> list[dict]:
    """Mesh every polygon in its own worker process (at most ``workers`` at a time); a worker
    still running after ``timeout`` seconds is killed and its polygon reported as
    ``status="timeout"``. Returns one dict per polygon, in order: ``status`` (meshed, failed,
    crashed, timeout), ``time`` and either ``quads`` and the size fields (``min_edge_lfs``,
    ``median_edge_lfs``, ``share_below_floor``, ``share_below_warn``) or
    ``error``/``stage``/``message``.
    ``on_result(i, result)`` is called as each polygon finishes."""

    def killed(i: int, seconds: float) -> dict:
        return {
            "status": "timeout",
            "error": "Timeout",
            "stage": "-",
            "time": timeout,
            "message": "no result within the time limit",
        }

    def died(i: int, seconds: float) -> dict:
        return {
            "status": "crashed",
            "error": "WorkerDied",
            "stage": "-",
            "message": "the worker process died (out of memory?)",
            "time": seconds,
        }

    return run_in_processes(
        _mesh_vertices,
        [(np.asarray(p), options) for p in polygons],
        timeout=timeout,
        workers=workers,
        on_timeout=killed,
        on_died=died,
        on_result=on_result,
    )


def _subset(items: list, limit: int | None) -> list:
    """``limit`` items spread evenly over ``items`` (all of them when limit is None)."""
    if limit is None or limit >= len(items):
        return list(items)
    idx = np.unique(np.round(np.linspace(0, len(items) - 1, max(limit, 1))).astype(int))
    return [items[k] for k in idx]


def _reason(res: dict) -> str:
    """A failure's class, stage and message with the numbers (vertex indices, coordinates)
    replaced by '#', so that failures of the same kind group together."""
    import re

    msg = res.get("message", "")
    msg = re.sub(r"^\[[^\]]*\]\s*", "", msg)
    msg = re.sub(r"\(?-?\d+(\.\d+)?(e[-+]?\d+)?(j|[-+]\d+(\.\d+)?(e[-+]?\d+)?j)?\)?", "#", msg)
    msg = msg[:110] + ("…" if len(msg) > 110 else "")
    return f"{res['error']} [{res['stage']}]: {msg}"


def run_families(
    families: dict | None = None,
    *,
    seed: int = 0,
    limit: int | None = None,
    timeout: float = 60.0,
    workers: int = 1,
    options: MeshOptions | None = None,
    verbose: bool = True,
) -> tuple[list[dict], list[dict]]:
    """Mesh the members of ``families`` (name -> ``f(seed) -> list[Member]``; default
    :data:`quadmesh.families.FAMILIES`), at most ``limit`` per family spread over the list,
    each under ``timeout`` seconds. Returns (rows, summary): one row per polygon (family,
    name, n, corridor metrics of :func:`quadmesh.families.polygon_metrics`, and the mesher's
    result of :func:`mesh_with_timeout`) and one summary dict per family
    (:func:`summarise_families`)."""
    from .families import FAMILIES, polygon_metrics

    families = FAMILIES if families is None else families
    rows: list[dict] = []
    for fam, make in families.items():
        try:
            members = make(seed)
        except ImportError as exc:
            print(f"family {fam} skipped: {exc} (pip install 'quadmesh[families]')")
            continue
        for m in _subset(members, limit):
            met = polygon_metrics(m.vertices)
            rows.append(
                {
                    "family": fam,
                    "name": m.name,
                    "n": len(m.vertices),
                    "vertices": m.vertices,
                    "nominal_aspect": m.aspect,
                    **met,
                }
            )

    def show(i: int, res: dict) -> None:
        if verbose:
            r = rows[i]
            what = f"{res['quads']} quads" if res["status"] == "meshed" else _reason(res)[:100]
            print(
                f"  {r['family']:12s} {r['name']:18s} n={r['n']:5d} {res['time']:7.2f} s  {what}",
                flush=True,
            )

    results = mesh_with_timeout([r["vertices"] for r in rows], timeout, workers, options, show)
    for r, res in zip(rows, results):
        del r["vertices"]
        r.update(res)
    return rows, summarise_families(rows)


def summarise_families(rows: list[dict]) -> list[dict]:
    """Per family: ``meshed``/``total``, median and max quads per polygon vertex (meshed
    polygons), median and max time (all polygons; a timeout counts as the timeout),
    median and min of the smallest edge / local width, median and max length/width (the
    generator's nominal ratio where defined, else area / width²), the median and min over
    the meshed polygons of the smallest mesh edge / local feature size (``edge_lfs_median``,
    ``edge_lfs_min``) and the largest share of edges below 1/1000 of it
    (``below_floor_max``), ``blocks_closed``: with ``method="blocks"`` the number of polygons
    whose block layout closed (no fallback), else None, and ``failures``: reason -> count
    (:func:`_reason`)."""
    from collections import Counter

    out = []
    for fam in dict.fromkeys(r["family"] for r in rows):
        rs = [r for r in rows if r["family"] == fam]
        ok = [r for r in rs if r["status"] == "meshed"]
        qpv = [r["quads"] / r["n"] for r in ok]
        times = [r["time"] for r in rs]
        ew = [r["min_edge_over_width"] for r in rs]
        asp = [r["nominal_aspect"] or r["aspect"] for r in rs]
        lfs = [r["min_edge_lfs"] for r in ok if r.get("min_edge_lfs") is not None]
        below = [r["share_below_floor"] for r in ok if r.get("share_below_floor") is not None]
        out.append(
            {
                "family": fam,
                "meshed": len(ok),
                "total": len(rs),
                "n_median": float(np.median([r["n"] for r in rs])),
                "n_max": max(r["n"] for r in rs),
                "quads_per_vertex_median": float(np.median(qpv)) if qpv else None,
                "quads_per_vertex_max": float(np.max(qpv)) if qpv else None,
                "time_median": float(np.median(times)),
                "time_max": float(np.max(times)),
                "timeouts": sum(r["status"] == "timeout" for r in rs),
                "edge_over_width_median": float(np.median(ew)),
                "edge_over_width_min": float(np.min(ew)),
                "aspect_median": float(np.median(asp)),
                "aspect_max": float(np.max(asp)),
                "edge_lfs_median": float(np.median(lfs)) if lfs else None,
                "edge_lfs_min": float(np.min(lfs)) if lfs else None,
                "below_floor_max": float(np.max(below)) if below else None,
                "blocks_closed": (
                    sum(bool(r.get("blocks")) for r in ok)
                    if any("blocks" in r for r in rs)
                    else None
                ),
                "failures": dict(
                    Counter(_reason(r) for r in rs if r["status"] != "meshed").most_common()
                ),
            }
        )
    return out


def format_family_table(summary: list[dict]) -> str:
    """The per-family table of :func:`summarise_families` and, below it, the failure
    reasons with their counts."""

    def num(x, fmt):
        return "-" if x is None else format(x, fmt)

    def pair(a: str, b: str) -> str:
        return f"{a}/{b}"

    cols = [
        ("meshed", 8),
        ("n med/max", 11),
        ("quads/n med/max", 16),
        ("time s med/max", 15),
        ("edge/width med/min", 19),
        ("L/w med/max", 12),
        ("min edge/lfs med/min", 21),
        ("<1/1000 max", 11),
    ]
    blocks = any(s.get("blocks_closed") is not None for s in summary)
    if blocks:
        cols.append(("blocks closed", 13))
    lines = [f"{'family':12s} " + " ".join(f"{c:>{w}}" for c, w in cols)]
    for s in summary:
        cells = [
            pair(str(s["meshed"]), str(s["total"])),
            pair(f"{s['n_median']:.0f}", str(s["n_max"])),
            pair(num(s["quads_per_vertex_median"], ".0f"), num(s["quads_per_vertex_max"], ".0f")),
            pair(
                f"{s['time_median']:.1f}", f"{s['time_max']:.1f}" + ("+" if s["timeouts"] else "")
            ),
            pair(f"{s['edge_over_width_median']:.3f}", f"{s['edge_over_width_min']:.4f}"),
            pair(f"{s['aspect_median']:.0f}", f"{s['aspect_max']:.0f}"),
            pair(num(s["edge_lfs_median"], ".2g"), num(s["edge_lfs_min"], ".2g")),
            "-" if s["below_floor_max"] is None else f"{100 * s['below_floor_max']:.3g}%",
        ]
        if blocks:
            cells.append(pair(num(s.get("blocks_closed"), "d"), str(s["total"])))
        lines.append(
            f"{s['family']:12s} " + " ".join(f"{c:>{w}}" for c, (_, w) in zip(cells, cols))
        )
    lines.append("")
    lines.append(
        "edge/width: smallest edge length / local width (diameter of the largest inscribed "
        "disk tangent at the edge's midpoint); L/w: nominal corridor length/width, else "
        "area/width²; '+' after a time: timeouts; min edge/lfs: per meshed polygon, the "
        "smallest mesh edge over the polygon's local feature size at its midpoint (median and "
        "min over the family); <1/1000 max: the largest share of a polygon's edges below "
        "1/1000 of their local feature size"
    )
    for s in summary:
        if s["failures"]:
            lines.append(f"{s['family']} failures:")
            lines += [f"  {c:4d} x {why}" for why, c in s["failures"].items()]
    return "\n".join(lines)


def run_disk(sizes: tuple[int, ...] = (10, 100, 1000)) -> None:
    """Time the disk construction (Lemma 2.2 and the piece meshes) on random arcs."""
    from .disk import disk_mesh
    from .disk.demo import spread_intervals

    print(f"{'m':>6} {'time s':>8} {'pentagons':>9} {'C-quads':>8} {'C-tri':>7} {'quads':>9}")
    for m in sizes:
        iv = spread_intervals(m, 1024.0, seed=m)
        t0 = time.perf_counter()
        d = disk_mesh(iv, A=1024.0, n=2, depth_step=1.0, depth_growth=2.0)
        dt = time.perf_counter() - t0
        k = d.kind
        print(
            f"{m:6d} {dt:8.2f} {len(d.pieces.tiles):9d} {len(d.pieces.quads):8d} "
            f"{len(d.pieces.triangles):7d} {k.size:9d}"
        )


# ----------------------------------------------------------------------------- against Gmsh
GMSH_SIZE_FRACTION = 1 / 40
"""Gmsh's target element size as a fraction of the polygon's diameter (``--vs-gmsh``)."""

GMSH_OUTLINES = (
    "floor_plan",
    "pixel_contour",
    "notch_1e-3",
    "spiky_star_20",
    "random_star_40",
    "keyhole",
    "stroke_half_turn",
)
"""Members of :mod:`quadmesh.outlines` in the Gmsh comparison."""

GMSH_FAMILY_MEMBERS = (
    ("strokes", "S_2"),
    ("strokes", "zigzag_0"),
    ("glyphs_stix", "STIXGeneral_A"),
    ("glyphs_cm", "cmr10_B"),
    ("images", "coins_1"),
    ("walks", "walk_2"),
)
"""(family, member) pairs of :mod:`quadmesh.families` in the Gmsh comparison."""


def gmsh_polygons(lo: int = 6, hi: int = 100) -> list[tuple[str, np.ndarray]]:
    """The outlines of the Gmsh comparison with lo ≤ n ≤ hi vertices: every bundled example,
    the :data:`GMSH_OUTLINES` of :func:`quadmesh.outlines.stress_outlines` (seed 0) and the
    :data:`GMSH_FAMILY_MEMBERS` (skipped when the families' optional packages are missing)."""
    from .examples import example_names, load_example
    from .outlines import stress_outlines

    out = [(name, load_example(name)) for name in example_names()]
    outlines = stress_outlines(0)
    out += [(name, outlines[name]) for name in GMSH_OUTLINES]
    try:
        from .families import FAMILIES

        for fam in dict.fromkeys(f for f, _ in GMSH_FAMILY_MEMBERS):
            members = {m.name: m.vertices for m in FAMILIES[fam](0)}
            out += [(f"{fam}/{m}", members[m]) for f, m in GMSH_FAMILY_MEMBERS if f == fam]
    except ImportError as exc:
        print(f"note: family members skipped ({exc})")
    return [(name, np.asarray(v, float)) for name, v in out if lo <= len(v) <= hi]


def gmsh_quad_mesh(vertices: np.ndarray, size: float) -> dict:
    """Mesh the polygon ``vertices`` (n, 2) with Gmsh's quad mesher in this process:
    frontal-Delaunay for quads (``Mesh.Algorithm`` 8) and Blossom recombination
    (``Mesh.RecombineAll`` 1, ``Mesh.RecombinationAlgorithm`` 1), element size ``size`` at
    every polygon vertex and at most ``size`` anywhere. Returns ``nodes`` (N, 2), ``quads``
    (Q, 4) and ``triangles`` (T, 3) as 0-based node indices (the triangles Gmsh left), and
    ``time``: seconds of ``gmsh.model.mesh.generate(2)`` alone."""
    import signal

    import gmsh

    gmsh.initialize(interruptible=False)
    # Gmsh's start-up sets SIGPIPE back to its default action, which kills the process on a
    # write to a closed pipe (a process pool's queue after its workers stopped) where Python
    # raises BrokenPipeError; put back what Python had (from the main thread, which can)
    if hasattr(signal, "SIGPIPE") and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGPIPE, signal.getsignal(signal.SIGPIPE))
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 0)
        gmsh.model.add("polygon")
        geo = gmsh.model.geo
        pts = [geo.addPoint(float(x), float(y), 0.0, size) for x, y in vertices]
        lines = [geo.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
        geo.addPlaneSurface([geo.addCurveLoop(lines)])
        geo.synchronize()
        gmsh.option.setNumber("Mesh.Algorithm", 8)
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        t0 = time.perf_counter()
        gmsh.model.mesh.generate(2)
        seconds = time.perf_counter() - t0
        tags, coords, _ = gmsh.model.mesh.getNodes()
        index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(tags.size)
        nodes = np.asarray(coords, float).reshape(-1, 3)[:, :2]
        found = {3: np.empty((0, 4), np.int64), 2: np.empty((0, 3), np.int64)}
        etypes, _, enodes = gmsh.model.mesh.getElements(2)
        for et, nt in zip(etypes, enodes):
            k = {2: 3, 3: 4}.get(int(et))
            if k is None:
                raise RuntimeError(f"Gmsh produced elements of type {et}")
            found[int(et)] = index[np.asarray(nt, np.int64)].reshape(-1, k)
    finally:
        gmsh.finalize()
    return {"nodes": nodes, "quads": found[3], "triangles": found[2], "time": seconds}


def element_angles(nodes: np.ndarray, elements: np.ndarray) -> np.ndarray:
    """(E, k) interior angles in degrees of the polygonal elements (E, k) over ``nodes``
    (N, 2), each element taken counter-clockwise (reversed when its signed area is negative);
    a reflex corner gets its angle above 180°."""
    p = nodes[elements]
    x, y = p[..., 0], p[..., 1]
    area2 = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    p = np.where((area2 < 0)[:, None, None], p[:, ::-1], p)
    u = np.roll(p, 1, axis=1) - p  # to the previous corner
    v = np.roll(p, -1, axis=1) - p  # to the next corner
    cross = v[..., 0] * u[..., 1] - v[..., 1] * u[..., 0]
    dot = np.sum(u * v, axis=-1)
    ang = np.degrees(np.arctan2(cross, dot)) % 360.0
    return np.where((area2 < 0)[:, None], ang[:, ::-1], ang)


def quad_angle_stats(
    nodes: np.ndarray, quads: np.ndarray, triangles: np.ndarray, polygon: np.ndarray
) -> dict:
    """Angle statistics of a mixed quad/triangle mesh of ``polygon`` (n, 2): ``quads``,
    ``triangles`` (counts), ``share_ok`` (share of quads whose new angles all lie in
    [60°, 120°] within 1e-5°), ``min`` and ``max`` new quad angle. As for quadmesh's own
    meshes, a polygon corner below 60° left whole (its node in one element only) is original,
    not new."""
    from .mesh import ANGLE_TOL_DEG

    if len(quads) == 0:
        return {"quads": 0, "triangles": len(triangles), "share_ok": 0.0, "min": None, "max": None}
    ang = element_angles(nodes, quads)
    poly = np.asarray(polygon, float)
    corner_ang = element_angles(poly, np.arange(len(poly))[None, :])[0]
    diam = float(np.ptp(poly, axis=0).max())
    d = np.linalg.norm(nodes[:, None, :] - poly[None, :, :], axis=2)
    at_corner = np.full(len(nodes), -1)
    near = d.min(axis=1) <= 1e-9 * diam
    at_corner[near] = d[near].argmin(axis=1)
    uses = np.bincount(np.concatenate([quads.ravel(), triangles.ravel()]), minlength=len(nodes))
    c = at_corner[quads]
    exempt = (c >= 0) & (uses[quads] == 1) & (corner_ang[np.maximum(c, 0)] < 60.0)
    new = np.where(exempt, np.nan, ang)
    tol = ANGLE_TOL_DEG
    ok_corner = exempt | ((ang >= 60.0 - tol) & (ang <= 120.0 + tol))
    return {
        "quads": len(quads),
        "triangles": len(triangles),
        "share_ok": float(np.mean(np.all(ok_corner, axis=1))),
        "min": float(np.nanmin(new)),
        "max": float(np.nanmax(new)),
    }


def run_vs_gmsh(limit: int | None = None, method: str = "bishop") -> list[dict] | None:
    """Mesh the outlines of :func:`gmsh_polygons` with :func:`~quadmesh.pipeline.mesh_polygon`
    and with Gmsh (:func:`gmsh_quad_mesh`, element size diameter / 40), at most ``limit`` of
    them spread over the list, and print per polygon: n, both times and their ratio
    (quadmesh / Gmsh's ``generate(2)``), both quad counts, Gmsh's leftover triangles, Gmsh's
    share of quads with every new angle in [60°, 120°], and both meshes' extreme new angles;
    then the median ratio. ``method="blocks"`` meshes with block layouts at Gmsh's element size
    (a polygon whose layout does not close is marked ``fb``: it fell back to the paper's
    construction). Both are run once, untimed, on a unit square first. Returns the rows, or
    None (after a one-line message) when Gmsh is not installed."""
    from .errors import QuadmeshError
    from .polygon import validate_polygon

    try:
        import gmsh  # noqa: F401
    except (ImportError, OSError) as exc:
        print(
            f"quadmesh bench --vs-gmsh: Gmsh is not available ({exc}); "
            "install it with: pip install 'quadmesh[gmsh]'"
        )
        return None
    polys = _subset(gmsh_polygons(), limit)
    # one untimed run of each first: the first polygon's time would otherwise include
    # loading what both mesh with (quadmesh's lazily imported modules, Gmsh's kernel)
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    gmsh_quad_mesh(square, GMSH_SIZE_FRACTION)
    mesh_polygon(
        square, MeshOptions(method=method, size=GMSH_SIZE_FRACTION if method == "blocks" else None)
    )
    print(
        f"{'polygon':24s} {'n':>4} {'qm s':>7} {'gmsh s':>7} {'ratio':>6} {'qm quads':>9} "
        f"{'gmsh quads':>10} {'tris':>5} {'gmsh ok':>8} {'gmsh angles':>17} {'qm angles':>17}"
    )
    rows = []
    for name, verts in polys:
        poly = validate_polygon(verts)
        xy = np.column_stack([poly.z.real, poly.z.imag])
        row: dict = {"name": name, "n": poly.n}
        g = gmsh_quad_mesh(xy, GMSH_SIZE_FRACTION * poly.diameter)
        st = quad_angle_stats(g["nodes"], g["quads"], g["triangles"], xy)
        row.update(gmsh_time=g["time"], gmsh_quads=st["quads"], gmsh_triangles=st["triangles"])
        row.update(gmsh_share_ok=st["share_ok"], gmsh_min=st["min"], gmsh_max=st["max"])
        opts = MeshOptions()
        if method == "blocks":
            opts = MeshOptions(method="blocks", size=GMSH_SIZE_FRACTION * poly.diameter)
        t0 = time.perf_counter()
        try:
            r = mesh_polygon(poly, opts)
        except QuadmeshError as exc:
            row.update(qm_time=time.perf_counter() - t0, qm_failed=f"{type(exc).__name__}")
        else:
            q = r.quality
            row.update(qm_time=time.perf_counter() - t0, qm_quads=q.n_quads)
            row.update(qm_min=q.min_angle, qm_max=q.max_angle, fell_back=bool(r.fallback))
            row["ratio"] = row["qm_time"] / row["gmsh_time"]
        rows.append(row)
        gmin = "-" if st["min"] is None else f"{st['min']:.1f}"
        gmax = "-" if st["max"] is None else f"{st['max']:.1f}"
        qm = (
            f"{row['ratio']:6.0f} {row['qm_quads']:9d}"
            if "ratio" in row
            else f"{'-':>6} {row['qm_failed'][:9]:>9}"
        )
        qa = f"[{row['qm_min']:.1f}, {row['qm_max']:.1f}]" if "ratio" in row else "-"
        if row.get("fell_back"):
            qa += " fb"
        print(
            f"{name[:24]:24s} {poly.n:4d} {row['qm_time']:7.2f} {g['time']:7.3f} {qm} "
            f"{st['quads']:10d} {st['triangles']:5d} {100 * st['share_ok']:7.1f}% "
            f"{'[' + gmin + ', ' + gmax + ']':>17} {qa:>17}",
            flush=True,
        )
    ratios = [r["ratio"] for r in rows if "ratio" in r]
    if ratios:
        share = [r["gmsh_share_ok"] for r in rows]
        quads = [r["qm_quads"] / max(r["gmsh_quads"], 1) for r in rows if "ratio" in r]
        print(
            f"median time ratio quadmesh / Gmsh: {np.median(ratios):.0f} "
            f"(range {min(ratios):.0f}–{max(ratios):.0f}, {len(ratios)} polygons); "
            f"median quads quadmesh / Gmsh: "
            f"{np.median(quads):.1f}; "
            f"Gmsh quads with all new angles in [60°, 120°]: median {100 * np.median(share):.1f}% "
            f"(min {100 * min(share):.1f}%)"
        )
        if method == "blocks":
            closed = [r["ratio"] for r in rows if "ratio" in r and not r["fell_back"]]
            print(
                f"block layouts closed on {len(closed)} of {len(rows)} polygons"
                + (f"; median time ratio on those: {np.median(closed):.1f}" if closed else "")
            )
    return rows


def main(argv: list[str] | None = None) -> int:
    """Print the benchmark table and the scaling exponents."""
    ap = argparse.ArgumentParser(prog="quadmesh bench", description=__doc__)
    ap.add_argument("--max-n", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--examples", action="store_true", help="mesh every bundled example")
    ap.add_argument(
        "--example",
        action="append",
        default=None,
        metavar="NAME",
        help="with --examples: only this example (repeatable)",
    )
    ap.add_argument("--disk", action="store_true", help="benchmark the disk construction")
    ap.add_argument(
        "--outlines", action="store_true", help="mesh generated outlines (quadmesh.outlines)"
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of --outlines and --families")
    ap.add_argument(
        "--families", action="store_true", help="mesh the corridor families (quadmesh.families)"
    )
    ap.add_argument(
        "--family",
        action="append",
        default=None,
        metavar="NAME",
        help="with --families: only this family (repeatable)",
    )
    ap.add_argument(
        "--vs-gmsh",
        action="store_true",
        help="side by side with Gmsh's quad mesher (Blossom recombination) on outlines of "
        "6-100 vertices; needs the optional gmsh package",
    )
    ap.add_argument(
        "--limit",
        type=int,
        default=None,
        help="with --families: K per family; with --vs-gmsh: K polygons",
    )
    ap.add_argument(
        "--method",
        choices=("bishop", "blocks"),
        default="bishop",
        help="with --families and --vs-gmsh: the meshing method (blocks: layouts of convex "
        "blocks, falling back to the paper's construction)",
    )
    ap.add_argument("--timeout", type=float, default=60.0, help="with --families: s per polygon")
    ap.add_argument("--workers", type=int, default=1, help="with --families: worker processes")
    args = ap.parse_args(argv)
    if args.vs_gmsh:
        run_vs_gmsh(args.limit, args.method)
        return 0
    if args.families:
        from .families import FAMILIES

        names = args.family or list(FAMILIES)
        unknown = [f for f in names if f not in FAMILIES]
        if unknown:
            ap.error(f"unknown family {unknown[0]!r} (known: {', '.join(FAMILIES)})")
        _, summary = run_families(
            {f: FAMILIES[f] for f in names},
            seed=args.seed,
            limit=args.limit,
            timeout=args.timeout,
            workers=args.workers,
            options=MeshOptions(method=args.method),
        )
        print(format_family_table(summary))
        return 0
    if args.examples:
        run_examples(args.example)
        return 0
    if args.disk:
        run_disk()
        return 0
    if args.outlines:
        run_outlines(args.seed)
        return 0
    rows = run(args.max_n, args.repeat)
    stages = ["conformal", "intervals", "disk", "push_forward", "thin", "verify"]
    head = f"{'n':>5} {'total s':>8} " + " ".join(f"{s[:8]:>8}" for s in stages)
    print(
        head + f" {'quads':>9} {'quads/n':>8} {'angles':>16} {'n_used':>6} {'min edge/lfs':>12}"
        f" {'peak MB':>8}"
    )
    for r in rows:
        st = " ".join(f"{r.get('t_' + s, 0.0):8.2f}" for s in stages)
        print(
            f"{r['n']:5d} {r['total']:8.2f} {st} {r['quads']:9d} {r['quads'] / r['n']:8.0f} "
            f"[{r['min']:6.2f},{r['max']:6.2f}] {r['n_used']:6d} {r['min_edge_lfs']:12.3g}"
            f" {r['peak_mb']:8.0f}"
        )
    if len(rows) >= 3:
        ns = [r["n"] for r in rows[1:]]
        print(
            f"scaling (n >= {ns[0]}): time ~ n^{_slope(ns, [r['total'] for r in rows[1:]]):.2f}, "
            f"quads ~ n^{_slope(ns, [r['quads'] for r in rows[1:]]):.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
