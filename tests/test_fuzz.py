"""Seeded fuzz: random polygons either mesh into a mesh that passes an independent check, or
are refused with a :class:`~quadmesh.errors.QuadmeshError`.

Families: random stars with slits (reflex corners up to 359°), orthogonal polygons (unions
of grid boxes), buffered random walks, near-collinear runs, edges of 1e-6 of the diameter,
and all of these scaled by 1e-8 … 1e8 and translated by up to 1e6 diameters.

The check below is written here, in plain float64 numpy, without quadmesh's verifier: the
mesh is checked as returned (``result.mesh.vertices``), in its stored frame (the polygon
translated by −``result.mesh_origin``). Every polygon is meshed in a forked worker process
that is killed after :data:`TIME_GUARD` seconds (the polygon then counts as skipped); any
exception other than a QuadmeshError, and any mesh that fails the check, fails the test.

The default run takes a handful of small polygons per family (about two minutes on a
loaded 2-core machine); ``QUADMESH_FUZZ=long`` runs the longer sweep marked slow.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import time
import traceback
from collections.abc import Callable

import numpy as np
import pytest
import shapely

#: seconds after which a polygon's worker is killed and the polygon skipped
TIME_GUARD = 20.0
#: the verifier's fixed angle tolerance, degrees
ANGLE_TOL = 1e-5
AREA_RTOL = 1e-9
DIST_RTOL = 1e-9


# ----------------------------------------------------------------------------- generators
def _ccw_ring(geom) -> np.ndarray | None:
    """Exterior ring (CCW, no closing point) of ``geom``'s largest polygon, or None."""
    if geom.is_empty:
        return None
    if geom.geom_type == "MultiPolygon":
        geom = max(geom.geoms, key=lambda g: g.area)
    if geom.geom_type != "Polygon":
        return None
    ring = shapely.geometry.polygon.orient(shapely.Polygon(geom.exterior), 1.0)
    return np.asarray(ring.exterior.coords)[:-1].copy()


def _simple(v: np.ndarray) -> bool:
    p = shapely.Polygon(v)
    return bool(len(v) >= 3 and p.is_valid and p.area > 0)


def slit_star(rng: np.random.Generator, n: int = 9) -> np.ndarray:
    """A random star (radii in [0.5, 1]) with 1–2 slits cut towards the centre: each slit's
    tip is a reflex corner of 360° − w with w from 1° to 60°."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(-0.2, 0.2, n)
    r = rng.uniform(0.5, 1.0, n)
    pts = list(r * np.exp(1j * t))
    for _ in range(rng.integers(1, 3)):
        k = int(rng.integers(0, len(pts)))
        a, b = pts[k], pts[(k + 1) % len(pts)]
        phi = np.angle(a + b)
        rad = 0.5 * min(abs(a), abs(b))
        tip = rng.uniform(0.1, 0.6) * rad * np.exp(1j * phi)
        w = np.radians(rng.uniform(1.0, 60.0))  # wedge at the tip
        # the slit's mouth: two points at radius rad around direction phi seen from the tip
        half = 0.5 * w
        m1 = tip + (rad - abs(tip)) * np.exp(1j * (phi - half))
        m2 = tip + (rad - abs(tip)) * np.exp(1j * (phi + half))
        pts[k + 1 : k + 1] = [m1, tip, m2]
    z = np.array(pts)
    return np.column_stack([z.real, z.imag])


def orthogonal(rng: np.random.Generator, boxes: int = 4) -> np.ndarray:
    """Union of axis-parallel boxes on an integer grid (reflex 270° corners, long walls)."""
    geoms = []
    for _ in range(boxes):
        x, y = rng.integers(0, 6, 2)
        w, h = rng.integers(1, 4, 2)
        geoms.append(shapely.box(x, y, x + w, y + h))
    return _ccw_ring(shapely.union_all(geoms).simplify(0))


def buffered_walk(rng: np.random.Generator, steps: int = 4) -> np.ndarray:
    """A random walk of ``steps`` unit steps buffered by a random half-width (mitred or
    coarsely rounded joins), as a thick pen stroke."""
    ang = np.cumsum(rng.uniform(-1.6, 1.6, steps))
    z = np.r_[0, np.cumsum(np.exp(1j * ang))]
    line = shapely.LineString(np.column_stack([z.real, z.imag]))
    join = ["mitre", "round"][int(rng.integers(0, 2))]
    geom = line.buffer(rng.uniform(0.08, 0.3), quad_segs=2, join_style=join, cap_style="flat")
    return _ccw_ring(geom.simplify(1e-9))


def near_collinear(rng: np.random.Generator, per_side: int = 4) -> np.ndarray:
    """A quadrilateral whose sides carry runs of vertices off the straight line by 1e-9 …
    1e-3 of the side (interior angles within a hair of 180°, on both sides of it)."""
    corners = np.array([0, 1, 1 + 1j, 1j]) + rng.uniform(-0.15, 0.15, 4) * np.array([1, 1j, 1, 1j])
    pts = []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        s = np.sort(rng.uniform(0.1, 0.9, per_side))
        off = 10.0 ** rng.uniform(-9, -3, per_side) * rng.choice([-1, 1], per_side)
        normal = 1j * (b - a)
        pts.append(a)
        pts.extend(a + s * (b - a) + off * normal)
    z = np.array(pts)
    return np.column_stack([z.real, z.imag])


def tiny_edge(rng: np.random.Generator, n: int = 7) -> np.ndarray:
    """A random convex-ish star with one edge of 1e-6 of the diameter (a corner cut off, or
    a vertex doubled a hair apart)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(-0.15, 0.15, n)
    z = rng.uniform(0.7, 1.0, n) * np.exp(1j * t)
    k = int(rng.integers(0, n))
    a, b, c = z[k - 1], z[k], z[(k + 1) % n]
    eps = 1e-6 * 2.0
    if rng.uniform() < 0.5:  # chamfer corner k by an edge of length ~eps
        d1, d2 = (a - b) / abs(a - b), (c - b) / abs(c - b)
        cut = eps / abs(d1 - d2)
        new = [b + cut * d1, b + cut * d2]
    else:  # a vertex a hair along the next side
        new = [b, b + eps * (c - b) / abs(c - b) + 1e-7 * 1j * (c - b) / abs(c - b)]
    z = np.r_[z[:k], new, z[k + 1 :]]
    return np.column_stack([z.real, z.imag])


def _small_base(rng: np.random.Generator) -> np.ndarray:
    """A small polygon of one of the families above, for scaling and translating."""
    makers = [slit_star, orthogonal, buffered_walk, near_collinear, tiny_edge]
    return makers[int(rng.integers(0, len(makers)))](rng)


def scaled(rng: np.random.Generator) -> np.ndarray:
    """A small polygon scaled by 10^k, k in [-8, 8]."""
    v = _small_base(rng)
    return v * 10.0 ** rng.integers(-8, 9)


def translated(rng: np.random.Generator) -> np.ndarray:
    """A small polygon scaled by 10^k (k in [-4, 4]) and moved by up to 1e6 diameters."""
    v = _small_base(rng) * 10.0 ** rng.integers(-4, 5)
    diam = float(np.max(np.ptp(v, axis=0)))
    shift = rng.uniform(-1, 1, 2) * 10.0 ** rng.uniform(0, 6) * diam
    return v + shift


FAMILIES: dict[str, Callable[[np.random.Generator], np.ndarray]] = {
    "slit_star": slit_star,
    "orthogonal": orthogonal,
    "buffered_walk": buffered_walk,
    "near_collinear": near_collinear,
    "tiny_edge": tiny_edge,
    "scaled": scaled,
    "translated": translated,
}


def make_polygons(family: str, count: int, seed: int) -> list[np.ndarray]:
    """``count`` valid simple polygons of ``family`` from ``seed`` (invalid draws redrawn)."""
    rng = np.random.default_rng([seed, list(FAMILIES).index(family)])
    out: list[np.ndarray] = []
    tries = 0
    while len(out) < count and tries < 50 * count:
        tries += 1
        v = FAMILIES[family](rng)
        if v is not None and np.all(np.isfinite(v)) and _simple(v):
            out.append(np.asarray(v, dtype=np.float64))
    assert len(out) == count, f"{family}: too few valid polygons drawn"
    return out


# ----------------------------------------------------------------------------- the check
def independent_check(
    vertices: np.ndarray, quads: np.ndarray, polygon: np.ndarray, origin: complex
) -> list[str]:
    """Problems of the mesh ``(vertices, quads)`` (stored coordinates; absolute positions are
    vertices + origin) as a quad mesh of ``polygon`` (absolute, any orientation), in plain
    float64 and without quadmesh. Empty list: the mesh is valid."""
    problems: list[str] = []
    v = np.asarray(vertices, dtype=np.float64)
    q = np.asarray(quads)
    if v.ndim != 2 or v.shape[1] != 2 or q.ndim != 2 or q.shape[1] != 4 or q.shape[0] == 0:
        return [f"bad shapes {v.shape} {q.shape}"]
    if not np.issubdtype(q.dtype, np.integer) or q.min() < 0 or q.max() >= len(v):
        return ["bad quad indices"]
    if not np.all(np.isfinite(v)):
        return ["non-finite vertices"]
    # the polygon in the stored frame, counter-clockwise
    p = np.asarray(polygon, dtype=np.float64) - np.array([origin.real, origin.imag])
    pr = p - p[0]
    parea = 0.5 * float(np.sum(pr[:, 0] * np.roll(pr[:, 1], -1) - np.roll(pr[:, 0], -1) * pr[:, 1]))
    if parea < 0:
        p, parea = p[::-1].copy(), -parea
    n = len(p)
    diam = float(np.max(np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)))
    tol = DIST_RTOL * diam

    # quads: distinct indices, strictly convex, counter-clockwise (relative to corner 0)
    qs = np.sort(q, axis=1)
    if np.any(qs[:, 1:] == qs[:, :-1]):
        problems.append("a quad repeats a vertex")
    c = v[q] - v[q[:, :1]]
    e = np.roll(c, -1, axis=1) - c  # edge k: corner k -> k+1
    e_prev = np.roll(e, 1, axis=1)  # edge into corner k
    cross = e_prev[..., 0] * e[..., 1] - e_prev[..., 1] * e[..., 0]
    area = 0.5 * np.sum(
        c[..., 0] * np.roll(c[..., 1], -1, 1) - np.roll(c[..., 0], -1, 1) * c[..., 1], 1
    )
    if np.any(cross <= 0) or np.any(area <= 0):
        problems.append(f"{int(np.sum(np.any(cross <= 0, 1) | (area <= 0)))} quads not convex CCW")
    # angle at corner k between the edges to the next and to the previous corner
    a1, a2 = e, -e_prev
    ang = np.degrees(
        np.arctan2(
            a1[..., 0] * a2[..., 1] - a1[..., 1] * a2[..., 0],
            a1[..., 0] * a2[..., 0] + a1[..., 1] * a2[..., 1],
        )
    )
    # area
    rel = abs(float(area.sum()) - parea) / parea
    if not rel <= AREA_RTOL:
        problems.append(f"area off by {rel:.3g} (relative)")

    # conformity: each directed edge once; an undirected edge in one or two quads
    nv = len(v)
    a = q.ravel().astype(np.int64)
    b = np.roll(q, -1, axis=1).ravel().astype(np.int64)
    directed = a * nv + b
    if np.unique(directed).size != directed.size:
        problems.append("a directed edge is used twice (overlap or flip)")
    _, cnt = np.unique(np.minimum(a, b) * nv + np.maximum(a, b), return_counts=True)
    if np.any(cnt > 2):
        problems.append("an edge lies in more than two quads")
    rev = b * nv + a
    free = ~np.isin(rev, directed)  # directed edges whose reverse is absent: boundary
    fa, fb = a[free], b[free]

    # boundary edges exactly subdivide the polygon's sides
    p0 = p
    p1 = np.roll(p, -1, axis=0)
    d = p1 - p0
    dd = np.sum(d * d, axis=1)

    def dist_t(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(m, n) distances of points x to every side and their parameters along it."""
        w = x[:, None, :] - p0[None, :, :]
        t = np.sum(w * d[None], axis=2) / dd[None]
        foot = p0[None] + np.clip(t, 0, 1)[..., None] * d[None]
        return np.linalg.norm(x[:, None, :] - foot, axis=2), t

    corner_vertex = np.full(n, -1)
    bverts = np.unique(np.r_[fa, fb])
    for k in range(n):
        dk = np.linalg.norm(v[bverts] - p[k], axis=1)
        j = int(np.argmin(dk))
        if dk[j] <= tol:
            corner_vertex[k] = bverts[j]
    if np.any(corner_vertex < 0):
        problems.append(f"{int(np.sum(corner_vertex < 0))} polygon corners are not mesh vertices")
        return problems
    side_of = np.full(fa.size, -1)
    ta = np.zeros(fa.size)
    tb = np.zeros(fa.size)
    for s0 in range(0, fa.size, 2000):
        sl = slice(s0, s0 + 2000)
        da, tA = dist_t(v[fa[sl]])
        db, tB = dist_t(v[fb[sl]])
        worst = np.maximum(da, db)
        worst[tB <= tA] = np.inf  # must run counter-clockwise along the side
        k = np.argmin(worst, axis=1)
        rows = np.arange(k.size)
        okk = worst[rows, k] <= tol
        side_of[sl] = np.where(okk, k, -1)
        ta[sl], tb[sl] = tA[rows, k], tB[rows, k]
    if np.any(side_of < 0):
        problems.append(f"{int(np.sum(side_of < 0))} boundary edges are not on a polygon side")
        return problems
    for k in range(n):
        sel = np.flatnonzero(side_of == k)
        if sel.size == 0:
            problems.append(f"side {k} carries no boundary edge")
            continue
        sel = sel[np.argsort(ta[sel])]
        chain_ok = (
            fa[sel[0]] == corner_vertex[k]
            and fb[sel[-1]] == corner_vertex[(k + 1) % n]
            and np.all(fb[sel[:-1]] == fa[sel[1:]])
        )
        if not chain_ok:
            problems.append(f"the boundary edges on side {k} do not chain corner to corner")

    # angles: new angles in [60°, 120°]; an unsplit corner keeps the polygon's angle
    is_corner = np.zeros(nv, dtype=bool)
    is_corner[corner_vertex] = True
    valence = np.bincount(q.ravel(), minlength=nv)
    at_corner = is_corner[q]
    unsplit = at_corner & (valence[q] == 1)
    bad = ~unsplit & ((ang < 60.0 - ANGLE_TOL) | (ang > 120.0 + ANGLE_TOL))
    if np.any(bad):
        i = np.argwhere(bad)[0]
        problems.append(
            f"{int(bad.sum())} new angles outside [60°, 120°], e.g. {ang[tuple(i)]:.9f}° "
            f"at vertex {q[tuple(i)]}"
        )
    if np.any(unsplit):
        # the polygon's interior angle at that corner
        pa = np.roll(p, 1, axis=0) - p
        pb = np.roll(p, -1, axis=0) - p
        pang = np.degrees(
            np.arctan2(pb[:, 0] * pa[:, 1] - pb[:, 1] * pa[:, 0], np.sum(pa * pb, axis=1))
        )
        pang = np.mod(pang, 360.0)
        where = {int(cv): k for k, cv in enumerate(corner_vertex)}
        for qi, ki in np.argwhere(unsplit):
            want = pang[where[int(q[qi, ki])]]
            if abs(ang[qi, ki] - want) > 1e-6 * max(1.0, want):
                problems.append(
                    f"unsplit corner {where[int(q[qi, ki])]}: quad angle {ang[qi, ki]:.9f}° "
                    f"but the polygon's angle is {want:.9f}°"
                )
                break
    return problems


# ----------------------------------------------------------------------------- the run
def _worker(conn, vertices: np.ndarray) -> None:
    """Mesh ``vertices`` and check the mesh; send (status, detail) through ``conn``."""
    from quadmesh import QuadmeshError, mesh_polygon

    t0 = time.perf_counter()
    try:
        r = mesh_polygon(vertices)
    except QuadmeshError as exc:
        conn.send(("refused", f"{type(exc).__name__}: {str(exc)[:200]}", time.perf_counter() - t0))
        return
    except Exception:
        conn.send(("crash", traceback.format_exc()[-1500:], time.perf_counter() - t0))
        return
    try:
        problems = independent_check(
            r.mesh.vertices, r.mesh.quads, vertices, complex(r.mesh_origin)
        )
    except Exception:
        problems = ["the check itself raised: " + traceback.format_exc()[-800:]]
    dt = time.perf_counter() - t0
    if problems:
        conn.send(("bad mesh", "; ".join(problems[:4]), dt))
    else:
        conn.send(("meshed", f"{r.mesh.n_quads} quads", dt))


def mesh_and_check(vertices: np.ndarray, guard: float = TIME_GUARD) -> tuple[str, str, float]:
    """Run :func:`_worker` in a forked process; ("skipped", …) when it exceeds ``guard`` s."""
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_worker, args=(send, vertices), daemon=True)
    t0 = time.perf_counter()
    proc.start()
    send.close()
    if recv.poll(guard):
        try:
            out = recv.recv()
        except EOFError:
            out = ("crash", "the worker died without a result", time.perf_counter() - t0)
        proc.join()
    else:
        proc.kill()
        proc.join()
        out = ("skipped", f"no result within {guard:g} s", guard)
    recv.close()
    return out


def run_fuzz(per_family: int, seed: int) -> dict[str, list[tuple[str, str, float]]]:
    """Mesh ``per_family`` polygons of every family; print a line per polygon and the shares
    meshed / refused / skipped per family; return the outcomes."""
    outcomes: dict[str, list[tuple[str, str, float]]] = {}
    for fam in FAMILIES:
        outcomes[fam] = []
        for i, poly in enumerate(make_polygons(fam, per_family, seed)):
            status, detail, dt = mesh_and_check(poly)
            outcomes[fam].append((status, detail, dt))
            print(f"  {fam:15s} #{i} n={len(poly):3d} {dt:6.2f} s {status}: {detail[:150]}")
    print(f"{'family':15s} {'meshed':>7} {'refused':>8} {'skipped':>8}  (share of {per_family})")
    for fam, res in outcomes.items():
        share = {
            s: sum(r[0] == s for r in res) / len(res) for s in ("meshed", "refused", "skipped")
        }
        print(f"{fam:15s} {share['meshed']:7.0%} {share['refused']:8.0%} {share['skipped']:8.0%}")
    return outcomes


def _assert_no_failures(outcomes: dict[str, list[tuple[str, str, float]]]) -> None:
    bad = [
        f"{fam} #{i}: {s}: {detail}"
        for fam, res in outcomes.items()
        for i, (s, detail, _) in enumerate(res)
        if s in ("crash", "bad mesh")
    ]
    assert not bad, "\n".join(bad)


# ----------------------------------------------------------------------------- tests
def test_generators_give_what_they_promise():
    """The families hold what they claim: valid simple polygons, slit tips reflex up to
    359°, rectilinear corners, near-180° runs, 1e-6 edges, extreme scales and offsets."""

    def angles(v: np.ndarray) -> np.ndarray:
        z = v[:, 0] + 1j * v[:, 1]
        if shapely.Polygon(v).exterior.is_ccw is False:
            z = z[::-1]
        a = np.angle((np.roll(z, 1) - z) / (np.roll(z, -1) - z))
        return np.degrees(np.mod(a, 2 * np.pi))

    stars = make_polygons("slit_star", 20, seed=1)
    assert max(angles(v).max() for v in stars) > 355.0
    for v in make_polygons("orthogonal", 5, seed=1):
        a = angles(v)
        assert np.all(np.isclose(a, 90.0) | np.isclose(a, 270.0))
    runs = make_polygons("near_collinear", 5, seed=1)
    assert all(np.sum(np.abs(angles(v) - 180.0) < 1e-3) >= 1 for v in runs)
    for v in make_polygons("tiny_edge", 5, seed=1):
        edge = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
        assert edge.min() / np.ptp(v, axis=0).max() < 1e-5
    sizes = [np.ptp(v, axis=0).max() for v in make_polygons("scaled", 12, seed=1)]
    assert min(sizes) < 1e-4 and max(sizes) > 1e4
    far = [
        np.abs(v).max() / np.ptp(v, axis=0).max() for v in make_polygons("translated", 12, seed=1)
    ]
    assert max(far) > 1e4


def test_independent_check_catches_defects():
    """The check is not vacuous: it accepts a correct grid and rejects a hole, a flipped
    quad, a hanging vertex and a bad angle."""
    x, y = np.meshgrid(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    v = np.column_stack([x.ravel(), y.ravel()])
    q = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    assert independent_check(v, q, square, 0j) == []
    # the same, stored relative to an origin
    far = np.add(square, (1e6, 2e6))  # stored vertices v are relative to (1e6, 2e6)
    assert independent_check(v, q, far, complex(1e6, 2e6)) == []
    assert independent_check(v, q, far, 0j) != []
    assert any("area" in p for p in independent_check(v, q[:3], square, 0j))
    assert any("convex" in p for p in independent_check(v, q[:, ::-1], square, 0j))
    skew = v.copy()
    skew[4] = [0.62, 0.5]  # angles of about 76°/104°: still fine
    assert independent_check(skew, q, square, 0j) == []
    skew[4] = [0.8, 0.5]  # angles of about 59° and 121°
    assert any("new angles" in p for p in independent_check(skew, q, square, 0j))
    # a hanging vertex: the bottom-right quad split in two, vertex 9 inside the edge 1-4 of
    # the bottom-left quad
    v2 = np.vstack([v, [[0.5, 0.25], [1.0, 0.25]]])
    q2 = np.array([[0, 1, 4, 3], [1, 2, 10, 9], [9, 10, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    assert any("not on a polygon side" in p for p in independent_check(v2, q2, square, 0j))


def test_fuzz_default():
    """A handful of small polygons per family: each meshes and passes the independent check,
    or is refused with a QuadmeshError (skipped beyond the time guard)."""
    outcomes = run_fuzz(per_family=5, seed=2024)
    _assert_no_failures(outcomes)
    meshed = sum(s == "meshed" for res in outcomes.values() for s, _, _ in res)
    assert meshed >= len(FAMILIES)  # the run is not all refusals


@pytest.mark.slow
@pytest.mark.skipif(
    os.environ.get("QUADMESH_FUZZ") != "long", reason="long fuzz: set QUADMESH_FUZZ=long"
)
def test_fuzz_long():
    """The longer sweep (several minutes): more polygons per family, other seeds."""
    outcomes = run_fuzz(per_family=int(os.environ.get("QUADMESH_FUZZ_N", "12")), seed=7)
    _assert_no_failures(outcomes)


if __name__ == "__main__":  # pragma: no cover - manual sweeps
    import sys

    per = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 2024
    t0 = time.perf_counter()
    res = run_fuzz(per, seed)
    print(f"{time.perf_counter() - t0:.1f} s")
