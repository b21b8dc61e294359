"""Benchmark of the Schwarz–Christoffel disk map: ``python -m quadmesh.conformal.benchmark``.

Prints (1) solve time, Newton iterations and the §1.7 checks for star-shaped polygons with
n = 10, 30, 100, 300, 1000; (2) evaluation throughput (forward map, derivative, clustered
series, inverse) for n = 100; (3) with ``--crowding``, the rectangle aspect ratios that solve
to 1e-8 from a cold start and with continuation, in local and in absolute coordinates.
Options: ``--sizes 10 30 ...``, ``--skip-solve``, ``--skip-eval``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ..errors import ConformalMapError
from .diskmap import DiskMap


def bench_star(n: int, seed: int = 0) -> np.ndarray:
    """Star with a smooth random radius (7 Fourier modes) plus vertex noise of size 1/n."""
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(n) / n
    r = 1 + sum(0.15 / k * np.cos(k * t + rng.uniform(0, 6.3)) for k in range(1, 8))
    r = r + rng.uniform(-1, 1, n) / n
    return r * np.exp(1j * t)


def spiky_star(n: int, seed: int = 0) -> np.ndarray:
    """Star with iid radii in [0.5, 1.5] (strongly crowded for large n)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(0.5, 1.5, n) * np.exp(2j * np.pi * np.arange(n) / n)


def _row(name: str, n: int, dm: DiskMap, t: float) -> str:
    a = dm.accuracy()
    return (
        f"{name:>7} {n:5d} {t:8.2f} {dm.iterations:4d} {dm._prob.nfev:4d} "
        f"{dm.continuation_steps:4d} {a.residual:8.1e} {a.side_error:8.1e} "
        f"{a.center_error:8.1e} {a.boundary_deviation:8.1e} {a.round_trip:8.1e} "
        f"{a.min_gap:8.1e}"
    )


def solve_table(sizes: list[int]) -> None:
    print("solve (one core, time includes the accuracy checks only in column 'check'):")
    print(
        "polygon     n  solve_s  its nfev cont    resid  side_err  ctr_err bdry_dev "
        "roundtrip  min_gap  check_s"
    )
    cases = [("smooth", n, bench_star(n)) for n in sizes]
    cases += [("spiky", n, spiky_star(n)) for n in (30, 100) if n <= max(sizes)]
    for name, n, w in cases:
        t0 = time.perf_counter()
        try:
            dm = DiskMap.from_polygon(w, 0.0, check=False)
        except ConformalMapError as exc:
            print(f"{name:>7} {n:5d} failed: {exc}")
            continue
        t = time.perf_counter() - t0
        t1 = time.perf_counter()
        dm.accuracy()
        print(_row(name, n, dm, t), f"{time.perf_counter() - t1:7.2f}")


def eval_table(n: int = 100, M: int = 100_000) -> None:
    dm = DiskMap.from_polygon(bench_star(n), 0.0, check=False)
    rng = np.random.default_rng(1)
    z = np.sqrt(rng.uniform(0, 1, M)) * np.exp(2j * np.pi * rng.uniform(0, 1, M))
    print(f"\nevaluation, n = {n}, {M} random points in the closed unit disk:")
    t0 = time.perf_counter()
    f = dm(z)
    t_f = time.perf_counter() - t0
    t0 = time.perf_counter()
    dm.derivative(z)
    t_d = time.perf_counter() - t0
    sample = z[:500]
    err = float(np.max(np.abs(f[:500] - dm.direct(sample))))
    t0 = time.perf_counter()
    dm.direct(sample)
    t_q = (time.perf_counter() - t0) / sample.size * M
    # clustered points (mesh-like): 1000 clusters of 100 points inside R/2 of their centre
    K = 1000
    c = 0.9 * np.sqrt(rng.uniform(0, 1, K)) * np.exp(2j * np.pi * rng.uniform(0, 1, K))
    R = np.min(np.abs(dm.prevertices[None, :] - c[:, None]), axis=1)
    ids = np.repeat(np.arange(K), M // K)
    rad = 0.45 * R[ids] * np.sqrt(rng.uniform(0, 1, ids.size))
    p = c[ids] + rad * np.exp(2j * np.pi * rng.uniform(0, 1, ids.size))
    t0 = time.perf_counter()
    fc = dm.map_clusters(p, ids, c)
    t_c = time.perf_counter() - t0
    err_c = float(np.max(np.abs(fc[::200] - dm.direct(p[::200]))))
    wq = f[: M // 10]
    t0 = time.perf_counter()
    zi = dm.inverse(wq)
    t_i = time.perf_counter() - t0
    err_i = float(np.max(np.abs(zi - z[: M // 10])))
    print(
        f"  forward  __call__      {t_f:7.2f} s  ({M / t_f:9.0f} pts/s)  "
        f"max|f - quadrature| {err:.1e}"
    )
    print(f"  derivative (closed)    {t_d:7.2f} s  ({M / t_d:9.0f} pts/s)")
    print(f"  map_clusters (series)  {t_c:7.2f} s  ({M / t_c:9.0f} pts/s)  max err {err_c:.1e}")
    print(f"  direct quadrature      {t_q:7.2f} s  (extrapolated from 500 points)")
    print(f"  inverse ({M // 10} pts)     {t_i:7.2f} s  round trip {err_i:.1e}")


def crowding_table(ars: list[float]) -> None:
    print("\nrectangles 1×AR, f(0) at the centre, acceptance 1e-8 (min_gap check off):")
    print("   AR   min_gap   cold/local  cont/local  cold/absolute  cont/absolute")
    for ar in ars:
        w = np.array([0, ar, ar + 1j, 1j])
        cells = []
        gap = float("nan")
        for local in (True, False):
            for cont in (False, True):
                try:
                    dm = DiskMap.from_polygon(
                        w, tol=1e-8, min_gap=0.0, continuation=cont, local=local
                    )
                    gap = float(np.min(dm.gaps))
                    cells.append(f"ok {dm.accuracy().worst:7.1e}")
                except ConformalMapError:
                    cells.append("   fail   ")
        print(f"{ar:5.0f}  {gap:8.1e}   " + "  ".join(f"{c:>11}" for c in cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="*", default=[10, 30, 100, 300, 1000])
    ap.add_argument("--skip-solve", action="store_true")
    ap.add_argument("--skip-eval", action="store_true")
    ap.add_argument("--crowding", action="store_true")
    args = ap.parse_args()
    if not args.skip_solve:
        solve_table(args.sizes)
    if not args.skip_eval:
        eval_table()
    if args.crowding:
        crowding_table([10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30, 40, 60, 80, 100, 150])


if __name__ == "__main__":
    main()
