"""Benchmark of the whole mesher: time and quad count against the number of vertices n.

Run ``python -m quadmesh.benchmark [--max-n 256] [--repeat 1]``. It meshes smooth random
star-shaped polygons (the family of the bundled ``star_*`` examples) with n = 8 … max-n,
prints the time of every stage, the quad count, quads per vertex and the measured scaling
exponents (slope of log time and log quads against log n). A benchmark, not a test: the
numbers depend on the machine and its load.
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


def run(max_n: int = 256, repeat: int = 1, options: MeshOptions | None = None) -> list[dict]:
    """Mesh stars of n = 8, 16, … max_n vertices; return one row of measurements per n."""
    rows = []
    n = 8
    while n <= max_n:
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
        n *= 2
    return rows


def _slope(x: list[float], y: list[float]) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def main(argv: list[str] | None = None) -> int:
    """Print the benchmark table and the scaling exponents."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--max-n", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args(argv)
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
