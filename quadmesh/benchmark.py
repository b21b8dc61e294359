"""Benchmarks of the mesher: time and quad count against the number of vertices n.

``quadmesh bench`` (or ``python -m quadmesh.benchmark``):

* default: smooth random star-shaped polygons (the family of the bundled ``star_*``
  examples) with n = 10, 30, 100, 300, 1000 (up to ``--max-n``): time of every stage, quads,
  quads per vertex, and the fitted exponents of time and quads against n;
* ``--examples``: every bundled example, with the same columns (or the reason it failed);
* ``--outlines [--seed S]``: one generated outline of every family of
  :mod:`quadmesh.outlines` (floor plans, pixel contours, multi-scale notches, spiky stars,
  coastlines, keyholes, pen strokes), with the same columns and the adaptive fixes;
* ``--disk``: the disk construction alone (Lemma 2.2 + piece meshes) for m = 10, 100, 1000
  random admissible arcs: time, pieces and quads.

A benchmark, not a test: the numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import time

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


def run(max_n: int = 1000, repeat: int = 1, options: MeshOptions | None = None) -> list[dict]:
    """Mesh stars of n = 10, 30, 100, 300, 1000 (≤ max_n) vertices; one row per n."""
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
                **{f"t_{k}": v for k, v in result.timings.items()},
            }
        )
    return rows


def _slope(x: list[float], y: list[float]) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def run_examples() -> None:
    """Mesh every bundled example and print one line each (or why it failed)."""
    from .errors import QuadmeshError
    from .examples import example_names, load_example

    print(f"{'example':22s} {'n':>5} {'total s':>8} {'quads':>9} {'quads/n':>8} {'n_used':>6}")
    for name in example_names():
        poly = load_example(name)
        t0 = time.perf_counter()
        try:
            r = mesh_polygon(poly)
        except QuadmeshError as exc:
            print(f"{name:22s} {len(poly):5d} {time.perf_counter() - t0:8.2f} failed: {exc}")
            continue
        q = r.quality
        print(
            f"{name:22s} {len(poly):5d} {time.perf_counter() - t0:8.2f} {q.n_quads:9d} "
            f"{q.n_quads / len(poly):8.0f} {r.pieces[0].n_used:6d}"
        )


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
        f"{'outline':22s} {'n':>5} {'total s':>8} {'quads':>9} {'quads/n':>8} {'n_used':>6}  fixes"
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
        print(
            f"{name:22s} {len(poly):5d} {dt:8.2f} {q.n_quads:9d} {q.n_quads / len(poly):8.0f} "
            f"{max(p.n_used for p in r.pieces):6d}  {fixes}"
        )
        rows.append({"name": name, "n": len(poly), "total": dt, "quads": q.n_quads})
    ok = [r for r in rows if "failed" not in r]
    print(f"{len(ok)} of {len(rows)} outlines meshed and verified")
    return rows


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


def main(argv: list[str] | None = None) -> int:
    """Print the benchmark table and the scaling exponents."""
    ap = argparse.ArgumentParser(prog="quadmesh bench", description=__doc__)
    ap.add_argument("--max-n", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--examples", action="store_true", help="mesh every bundled example")
    ap.add_argument("--disk", action="store_true", help="benchmark the disk construction")
    ap.add_argument(
        "--outlines", action="store_true", help="mesh generated outlines (quadmesh.outlines)"
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of --outlines")
    args = ap.parse_args(argv)
    if args.examples:
        run_examples()
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
    print(head + f" {'quads':>9} {'quads/n':>8} {'angles':>16} {'n_used':>6}")
    for r in rows:
        st = " ".join(f"{r.get('t_' + s, 0.0):8.2f}" for s in stages)
        print(
            f"{r['n']:5d} {r['total']:8.2f} {st} {r['quads']:9d} {r['quads'] / r['n']:8.0f} "
            f"[{r['min']:6.2f},{r['max']:6.2f}] {r['n_used']:6d}"
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
