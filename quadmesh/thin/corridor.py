"""Corridors: thin parts whose walls are chains of short edges, meshed by straight cells.

A *corridor* is a strip between two wall chains L and R (any number of edges each) from a
start tip s to an end tip e of the boundary.  Bishop's construction maps it conformally; in
floating point it cannot, because the prevertex gaps of a corridor of length ℓ and width w
shrink like exp(−π·ℓ/w) seen from the centre of any disk map.  Here it is meshed without any
conformal map:

* a *ladder layout* cuts the corridor by straight *rungs* (crosscuts) from the L wall to the R
  wall into convex quadrilateral *cells* with every corner in [60°, 120°];
* every wall vertex whose angle θ exceeds 120° is the end of one rung (θ ≤ 240°: two parts
  in [60°, 120°]) or of a *fan* of two rungs (three parts); a wall vertex with θ ≤ 120° is a
  cell corner (the far corner of a fan cell, or a corner of a cap cell);
* the cells are refined by bilinear grids (:mod:`quadmesh.cells`): for a planar convex
  quadrilateral every bilinear grid angle lies in the range of its corner angles and their
  supplements, so every new angle stays in [60°, 120°].

The layout is a shortest path in a directed acyclic graph whose nodes are candidate rungs
(pairs of points, one on each wall: wall vertices and points sampled along the edges) and
whose arcs are admissible cells between two rungs; the cost of a cell rewards corners near
90° and penalises sliver cells.  Rungs never cross because both ends advance monotonically
along their walls.  A Dijkstra search (scipy) finds the best layout in one pass, not a greedy
sequence of cuts that has to be repaired afterwards.

Cells (each a quadrilateral, corners counter-clockwise):

* *ladder*: rung (a, b) to rung (a', b') with no wall vertex strictly between: (a, a', b', b);
* *fan* at a: two rungs from the same L point a with exactly one R vertex r between their far
  ends: (a, b', r, b) (symmetrically at b, with one L vertex l: (a, l, a', b));
* *cap*: the part of the polygon cut off by the first (last) rung, which must hold exactly two
  polygon vertices besides the rung's ends (a flat or bevelled end).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import time
from dataclasses import dataclass

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ..errors import ThinPartError
from ..geometry import quad_angles_deg
from ..polygon import interior_angles
from ..progress import checkpoint
from ..transition import TransitionError, transition_cascade

__all__ = ["CorridorLayout", "corridor_tips", "ladder_layout"]

#: Margin (degrees) kept inside [60°, 120°] by every cell corner of a layout.
CELL_MARGIN = 0.05


@dataclass(frozen=True)
class CorridorLayout:
    """A ladder layout of a corridor polygon.

    Attributes:
        vertices: (V,) complex coarse vertices; the first ``n`` are the polygon's vertices in
            its own order, the rest are rung ends on the polygon's edges.
        cells: (C, 4) counter-clockwise indices into ``vertices``.
        kind: (C,) "cap", "ladder" or "fan" per cell.
        rungs: (R, 2) vertex indices (L end, R end) of the rungs in order from s to e.
        tips: (s, e) polygon vertex indices where the two walls meet.
        edge_of: (V,) polygon edge index holding each coarse vertex (−1 for polygon vertices).
        round_caps: per round cap, its boundary γ from one end of its rung round to the other
            (coarse vertex indices, counter-clockwise about the rung's midpoint): the cap is a
            half-disk vertex sector whose sides are the two halves of the rung.
        cell_rungs: (C, 2) the rungs (indices into ``rungs``) before and after each cell, −1
            at a cap.
        sectors: per bend, (apex, γ): two rungs from the apex (a wall vertex) with a stretch
            of the other wall between them, meshed as a vertex sector about the apex; γ runs
            from the far end of one rung along the other wall to the far end of the other.
        open_end: True for an *arm* (``partial=True``): the ladder stops at its last rung,
            where the rest of the polygon (the body) begins.
        turn: the layout search admitted round ends and bends whose connection rows turn
            (:func:`_turned_rows`) where plain rows leave [60°, 120°], and round bends
            (:func:`_round_bend`) where turning rows do too; the mesh then builds them in the
            same order.
    """

    vertices: np.ndarray
    cells: np.ndarray
    kind: tuple[str, ...]
    rungs: np.ndarray
    tips: tuple[int, int]
    edge_of: np.ndarray
    round_caps: tuple[tuple[int, ...], ...] = ()
    cell_rungs: np.ndarray | None = None
    sectors: tuple[tuple[int, tuple[int, ...]], ...] = ()
    open_end: bool = False
    turn: bool = False


def _ccw_angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle (degrees, in [0, 360)) from direction u counter-clockwise to direction v."""
    a = np.degrees(np.angle(v * np.conj(u)))
    return np.where(a < 0, a + 360.0, a)


def _dual_tree(z: np.ndarray):
    """The dual tree of a constrained Delaunay triangulation of the polygon ``z``: the
    triangles (T, 3) as polygon vertex indices, the tree as a sparse matrix weighted by the
    distances between triangle centroids, and per triangle its *apex* — the vertex shared by
    its two polygon edges (an ear), else the vertex with the smallest interior angle."""
    n = z.size
    poly = shapely.Polygon(np.column_stack([z.real, z.imag]))
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(poly))
    coords = shapely.get_coordinates(tris).reshape(len(tris), 4, 2)[:, :3]
    key = {complex(x, y): i for i, (x, y) in enumerate(zip(z.real, z.imag))}
    try:
        tri = np.array([[key[complex(x, y)] for x, y in t] for t in coords])
    except KeyError as exc:  # pragma: no cover - the triangulation adds no points
        raise ThinPartError("the corridor's triangulation introduced new points") from exc
    # edges of each triangle, as sorted vertex pairs
    e = np.sort(np.stack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]], axis=1), axis=2)
    ek = e[..., 0] * n + e[..., 1]
    flat = ek.ravel()
    order = np.argsort(flat, kind="stable")
    fs = flat[order]
    same = np.flatnonzero(fs[1:] == fs[:-1])
    t_of = order // 3
    a, b = t_of[same], t_of[same + 1]
    cen = z[tri].mean(axis=1)
    w = np.abs(cen[a] - cen[b])
    m = len(tri)
    g = coo_matrix((np.r_[w, w], (np.r_[a, b], np.r_[b, a])), shape=(m, m)).tocsr()
    # polygon edges of each triangle: consecutive vertex pairs
    d = (np.roll(tri, -1, axis=1) - tri) % n
    bnd = (d == 1) | (d == n - 1)
    ang = interior_angles(z)
    apex = tri[np.arange(m), np.argmin(ang[tri], axis=1)]
    for t in np.flatnonzero(bnd.sum(axis=1) >= 2):
        pairs = [{int(tri[t, i]), int(tri[t, (i + 1) % 3])} for i in range(3) if bnd[t, i]]
        common = pairs[0] & pairs[1]
        if common:
            apex[t] = common.pop()
    return tri, g, apex, bnd.sum(axis=1) >= 2


def corridor_tips(z: np.ndarray) -> tuple[int, int]:
    """The two tips (s, e) of a corridor polygon: the apexes of the two ear triangles at the
    ends of the longest path in the dual tree of a constrained Delaunay triangulation (the
    path follows the corridor's medial axis; its ends are the corridor's two ends)."""
    _tri, g, apex, _ear = _dual_tree(z)
    d0 = dijkstra(g, indices=0)
    t1 = int(np.argmax(d0))
    d1 = dijkstra(g, indices=t1)
    t2 = int(np.argmax(d1))
    theta = np.degrees(interior_angles(np.asarray(z, dtype=np.complex128)))
    return _end_corner(z, theta, int(apex[t1])), _end_corner(z, theta, int(apex[t2]))


#: how many polygon vertices either side of an ear's apex :func:`_end_corner` looks at
END_CORNER_REACH = 3


def _end_corner(z: np.ndarray, theta: np.ndarray, t: int) -> int:
    """The tip of a corridor end near the ear apex ``t``: when the end is cut square — two
    consecutive corners below 120° (a river's or a pen stroke's straight end) within
    :data:`END_CORNER_REACH` vertices of ``t`` — the corner of that end edge nearer ``t``
    (then the start cap is the quadrilateral of the end edge and the first rung, its only
    other corner the end edge's second corner); else ``t``. The ear's apex can be a wall
    vertex next to the end edge, and a tip there leaves both end corners, which only cells'
    corners can take, on one wall: no cap cell exists."""
    n = z.size
    if theta[t] < 120.0 and (theta[(t - 1) % n] < 120.0 or theta[(t + 1) % n] < 120.0):
        return t
    best = t
    for k in sorted(range(-END_CORNER_REACH, END_CORNER_REACH + 1), key=abs):
        u = (t + k) % n
        if theta[u] < 120.0 and (theta[(u - 1) % n] < 120.0 or theta[(u + 1) % n] < 120.0):
            best = u
            break
    return best


def arm_tips(z: np.ndarray, toward: complex, count: int = 4) -> list[tuple[int, int]]:
    """Up to ``count`` tip pairs (s, e) for arms reaching toward the point ``toward`` (where
    a conformal map found the polygon crowded): s the apex of an ear triangle of the dual tree
    of a constrained Delaunay triangulation, nearest ``toward`` first; e the apex of the
    triangle farthest from it along the tree (the other end of the longest path from s)."""
    z = np.asarray(z, dtype=np.complex128)
    _tri, g, apex, ear = _dual_tree(z)
    ears = np.flatnonzero(ear)
    ears = ears[np.argsort(np.abs(z[apex[ears]] - toward), kind="stable")]
    out: list[tuple[int, int]] = []
    for t in ears:
        s = int(apex[t])
        if any(s == p[0] for p in out):
            continue
        e = int(apex[int(np.argmax(dijkstra(g, indices=int(t))))])
        if e != s:
            out.append((s, e))
        if len(out) == count:
            break
    return out


@dataclass
class _Chain:
    """Points of one wall chain, ordered from s to e (tips excluded)."""

    pos: np.ndarray  # complex
    gid: np.ndarray  # coarse vertex id (polygon vertex index or n + sample index)
    is_vertex: np.ndarray  # bool
    theta: np.ndarray  # interior angle (deg), 180 for edge samples
    nxt: np.ndarray  # unit direction toward e along the wall
    sigma: np.ndarray  # arc length from s
    vrank: np.ndarray  # number of polygon vertices among points[0..i]
    width: np.ndarray  # distance to the opposite wall


def _chain(s: int, e: int, forward: bool, n: int) -> list[int]:
    """Vertex sequence of the wall from s to e (forward = counter-clockwise)."""
    step = 1 if forward else -1
    verts = []
    k = s
    while True:
        k = (k + step) % n
        if k == e:
            break
        verts.append(k)
    return verts


#: most candidate rungs a ladder search considers (measured: 423,120 on a 1,562-vertex river
#: that closes in 1 s, 951,776 on a 2,000-vertex round star that is no corridor)
MAX_RUNG_CANDIDATES = 2_000_000


def ladder_layout(
    z: np.ndarray,
    tips: tuple[int, int] | None = None,
    *,
    samples_per_width: float = 4.0,
    margin: float = CELL_MARGIN,
    debug: dict | None = None,
    partial: bool = False,
    deadline: float | None = None,
    sector_chords: int = 16,
    tip_reach: bool = True,
    turn: bool = False,
    own_width: bool = False,
) -> CorridorLayout:
    """Ladder layout of a corridor polygon ``z`` (counter-clockwise complex vertices) between
    its tips (default :func:`corridor_tips`): convex quadrilateral cells with every corner in
    [60° + margin, 120° − margin] (original polygon corners below 60° are kept as they are).

    ``deadline`` (a :func:`time.perf_counter` value) bounds the search for sectors at bends,
    its most expensive part on long ragged walls. ``sector_chords``: the least number of
    chords on the crosscut of a round end's or a bend's sector (:func:`_sector_points`).
    ``tip_reach``: near the tips, rungs reach three times the distance to the other wall even
    where the wall normal meets the corridor's own end sooner (off for a bridge, whose first
    rung must be its cut). ``turn``: round ends and bends may also be sectors whose
    connection rows turn to meet their crosscut at right angles (:func:`_turned_rows`) where
    straight rows leave the range (bends of 90°–100°), and bends whose far wall is a circular
    arc may be round bends about the arc's centre (:func:`_round_bend`: 110°–160°, hairpins).
    ``own_width`` (with ``partial``): where the ladder gets stuck less than one and a half of
    the walls' median widths from its start, it is cut one and a half of its own widths (its
    median rung) before — an arm of a wide body, whose walls' median width is the body's.

    Raises:
        ThinPartError: no admissible layout exists with the sampled rung ends (the message
            names the stretch of the walls where the search got stuck), or none was found
            before ``deadline``.
    """
    z = np.asarray(z, dtype=np.complex128)
    n = z.size
    theta = np.degrees(interior_angles(z))
    s, e = corridor_tips(z) if tips is None else tips
    if s == e:
        raise ThinPartError("the corridor's two tips coincide")
    poly = shapely.Polygon(np.column_stack([z.real, z.imag]))
    shapely.prepare(poly)
    walls = _Walls(z)
    diam = float(np.ptp(z.real) + np.ptp(z.imag))

    # --- walls: vertex sequences, local widths, sampled points -------------------------
    lv = _chain(s, e, True, n)
    rv = _chain(s, e, False, n)
    if not lv or not rv:
        raise ThinPartError("a corridor needs at least one vertex on each wall")

    # dense samples of each wall for width estimates
    def dense(vs):
        pts = z[[s, *vs, e]]
        seg = np.diff(pts)
        k = np.maximum(np.ceil(np.abs(seg) / (np.abs(seg).mean() / 4 + 1e-300)), 1).astype(int)
        out = [pts[i] + seg[i] * np.arange(k[i]) / k[i] for i in range(len(seg))]
        out.append(pts[-1:])
        return np.concatenate(out)

    dl, dr = dense(lv), dense(rv)
    tl = cKDTree(np.column_stack([dl.real, dl.imag]))
    tr = cKDTree(np.column_stack([dr.real, dr.imag]))

    # a floor for the local width: near the tips both walls meet
    wall_d = np.concatenate(
        [
            tr.query(np.column_stack([z[lv].real, z[lv].imag]))[0],
            tl.query(np.column_stack([z[rv].real, z[rv].imag]))[0],
        ]
    )
    wfloor = 0.25 * float(np.median(wall_d))
    cast_first = 4.0 * float(np.median(wall_d))  # rays this long first (_Walls.first_hits)
    samples: list[complex] = []
    sample_edge: list[int] = []

    def build(vs: list[int], forward: bool, other: cKDTree, other_pts: np.ndarray) -> _Chain:
        seq = np.asarray([s, *vs, e])
        P = z[seq]
        seg = np.diff(P)
        seglen = np.abs(seg)
        cum = np.concatenate([[0.0], np.cumsum(seglen)])
        # uniform samples strictly inside every edge, ~ samples_per_width per local width
        q = np.concatenate([P[:-1], P[1:], 0.5 * (P[:-1] + P[1:])])
        wq = other.query(np.column_stack([q.real, q.imag]))[0].reshape(3, -1).min(axis=0)
        w = np.maximum(wq, wfloor)
        k = np.clip(np.ceil(seglen * samples_per_width / w), 1, 400).astype(np.int64)
        cnt = k - 1
        ei = np.repeat(np.arange(seg.size), cnt)
        jj = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + 1
        sig_u = cum[ei] + seglen[ei] * jj / k[ei]
        # where rays from the opposite wall's vertices (along their angle bisectors, and
        # turned by ±20°) first meet this wall
        line = shapely.LineString(np.column_stack([P.real, P.imag]))
        place = np.full(n, -1, dtype=np.int64)  # polygon edge -> segment of this chain
        place[seq[:-1] if forward else seq[1:]] = np.arange(seg.size)
        foot = _ray_hits(other_pts, walls, line, (place, P, cum), diam, cast_first)
        sig = np.concatenate([sig_u, foot])
        tol = 1e-6 * float(np.median(w))
        gap = 0.01 * float(np.median(w))  # no rung end within 1 % of a width of another
        sig = np.sort(sig[(sig > tol) & (sig < cum[-1] - tol)])
        # drop samples on top of a vertex or of each other
        vs_sig = cum[1:-1]
        near_v = np.zeros(sig.size, dtype=bool)
        if vs_sig.size:
            j = np.searchsorted(vs_sig, sig)
            lo = np.abs(sig - vs_sig[np.maximum(j - 1, 0)])
            hi = np.abs(vs_sig[np.minimum(j, vs_sig.size - 1)] - sig)
            near_v = np.minimum(lo, hi) < gap
        sig = sig[~near_v]
        if sig.size:
            sig = sig[np.concatenate([[True], np.diff(sig) > gap])]
        se = np.clip(np.searchsorted(cum, sig, side="right") - 1, 0, seg.size - 1)
        spos = P[se] + (sig - cum[se]) / seglen[se] * seg[se]
        unit = seg / seglen
        # merge vertices (interior of the chain) and samples by arc length
        all_sig = np.concatenate([vs_sig, sig])
        order = np.argsort(all_sig, kind="stable")
        nv = vs_sig.size
        isv = np.concatenate([np.ones(nv, bool), np.zeros(sig.size, bool)])[order]
        pos = np.concatenate([P[1:-1], spos])[order]
        pedge = seq[se] if forward else seq[se + 1]  # polygon edge (i, i + 1) of a sample
        gid = np.concatenate([seq[1:-1], n + len(samples) + np.arange(sig.size)])[order]
        samples.extend(spos.tolist())
        sample_edge.extend(pedge.tolist())
        th = np.concatenate([theta[seq[1:-1]], np.full(sig.size, 180.0)])[order]
        nxt = np.concatenate([unit[1:], unit[se]])[order]
        normal = nxt * (1j if forward else -1j)  # into the corridor
        width = _facing_distance(pos, normal, walls, wfloor, diam, cast_first)
        return _Chain(pos, gid, isv, th, nxt, all_sig[order], np.cumsum(isv), width)

    bis = np.exp(1j * np.radians(theta) / 2) * (np.roll(z, -1) - z)
    bis /= np.abs(bis)
    L = build(lv, True, tr, (z[rv], bis[rv]))
    R = build(rv, False, tl, (z[lv], bis[lv]))
    # at R points the direction toward e runs clockwise along the polygon
    coarse = np.concatenate([z, np.asarray(samples, dtype=np.complex128)])
    edge_of = np.concatenate([np.full(n, -1), np.asarray(sample_edge, dtype=np.int64)])

    # --- candidate rungs ----------------------------------------------------------------
    okL = (~L.is_vertex) | (L.theta > 120.0 + margin)
    okR = (~R.is_vertex) | (R.theta > 120.0 + margin)
    ia = np.flatnonzero(okL)
    # (near a tip the facing distance along the normal can hit the corridor's own end edge:
    # there the distance to the other wall bounds the reach from below)
    across = tr.query(np.column_stack([L.pos[ia].real, L.pos[ia].imag]))[0]
    near_tip = (L.sigma[ia] <= 3.0 * across) | (L.sigma[-1] - L.sigma[ia] <= 3.0 * across)
    near_tip &= tip_reach
    reach = 3.0 * np.where(near_tip, np.maximum(L.width[ia], across), L.width[ia]) + 1e-300
    rxy = np.column_stack([R.pos.real, R.pos.imag])
    rtree = cKDTree(rxy)
    lxy = np.column_stack([L.pos[ia].real, L.pos[ia].imag])
    # counted before the lists are made: on a round outline that is no corridor every point of
    # one wall sees most of the other's, and the arcs between rungs grow faster still (a
    # 10,000-vertex star held 15.5 GB after 3 minutes)
    counts = rtree.query_ball_point(lxy, reach, return_length=True)
    n_cand = int(counts.sum())
    if n_cand > MAX_RUNG_CANDIDATES:
        raise ThinPartError(
            f"the polygon is too wide for a ladder of straight cells: {n_cand:,} candidate "
            f"crosscuts between its walls, at most {MAX_RUNG_CANDIDATES:,} are searched"
        )
    cand = rtree.query_ball_point(lxy, reach)
    pa = np.repeat(ia, counts)
    pb = np.fromiter((j for c in cand for j in c), dtype=np.int64, count=pa.size)
    keep = okR[pb]
    pa, pb = pa[keep], pb[keep]
    za, zb = L.pos[pa], R.pos[pb]
    d = zb - za
    # angle at a after the rung (between the wall toward e and the rung), and before it
    aft_a = _ccw_angle(L.nxt[pa], d)
    bef_a = L.theta[pa] - aft_a
    # at b: from the rung (b -> a) counter-clockwise to the wall toward e
    aft_b = _ccw_angle(-d, R.nxt[pb])
    bef_b = R.theta[pb] - aft_b
    lo = 60.0 + margin
    keep = (aft_a >= lo) & (bef_a >= lo) & (aft_b >= lo) & (bef_b >= lo)
    pa, pb, za, zb = pa[keep], pb[keep], za[keep], zb[keep]
    # inside the polygon (the open segment)
    eps = 1e-9
    p0, p1 = za + eps * (zb - za), zb - eps * (zb - za)
    lines = shapely.linestrings(
        np.stack([np.column_stack([p0.real, p0.imag]), np.column_stack([p1.real, p1.imag])], 1)
    )
    inside = shapely.contains_properly(poly, lines)
    pa, pb = pa[inside], pb[inside]
    if pa.size == 0:
        raise ThinPartError("no straight crosscut fits between the corridor's walls")
    nr = pa.size
    nR = R.pos.size
    rkey = pa * nR + pb
    order = np.argsort(rkey)
    rkey_sorted = rkey[order]

    def rung_id(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = a * nR + b
        i = np.searchsorted(rkey_sorted, k)
        i = np.minimum(i, nr - 1)
        hit = rkey_sorted[i] == k
        return np.where(hit, order[i], -1)

    # --- windows of the next rung end along each wall -------------------------------------
    def windows(C: _Chain) -> tuple[np.ndarray, np.ndarray]:
        """For every point i: the range [i, hi_i] of points a next rung end may use: up to the
        second polygon vertex after i and within ~2 local widths of arc length."""
        m = C.pos.size
        vidx = np.flatnonzero(C.is_vertex)
        # index of the 2nd vertex strictly after i (or m - 1)
        pos_after = np.searchsorted(vidx, np.arange(m), side="right")
        after2 = vidx[np.minimum(pos_after + 1, vidx.size - 1)]
        second = np.where(pos_after + 1 < vidx.size, after2, m - 1)
        limit = np.searchsorted(C.sigma, C.sigma + 1.6 * C.width, side="right") - 1
        nextv = np.where(pos_after < vidx.size, vidx[np.minimum(pos_after, vidx.size - 1)], m - 1)
        hi = np.minimum(second, np.maximum(limit, nextv))
        return hi, nextv

    hiL, nextvL = windows(L)
    hiR, nextvR = windows(R)

    # --- arcs between rungs: all (a', b') in the windows of (a, b) -------------------------
    la = hiL[pa] - pa + 1
    lb = hiR[pb] - pb + 1
    cnt = la * lb
    src = np.repeat(np.arange(nr), cnt)
    off = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    a2 = pa[src] + off // lb[src]
    b2 = pb[src] + off % lb[src]
    a1, b1 = pa[src], pb[src]
    fan_a = a2 == a1
    fan_b = b2 == b1
    nl = np.where(a2 > a1, L.vrank[np.maximum(a2 - 1, 0)] - L.vrank[a1], 0)
    nrr = np.where(b2 > b1, R.vrank[np.maximum(b2 - 1, 0)] - R.vrank[b1], 0)
    valid = ~(fan_a & fan_b)
    valid &= np.where(fan_a, (nrr == 1), True)
    valid &= np.where(fan_b, (nl == 1), True)
    valid &= np.where(~fan_a & ~fan_b, (nl == 0) & (nrr == 0), True)
    dst = rung_id(a2, b2)
    valid &= dst >= 0
    src, dst, a1, b1, a2, b2 = (x[valid] for x in (src, dst, a1, b1, a2, b2))
    fan_a, fan_b = a2 == a1, b2 == b1
    # the 4 corners (counter-clockwise) and their angles
    q0 = L.pos[a1]
    q1 = np.where(fan_a, R.pos[b2], np.where(fan_b, L.pos[nextvL[a1]], L.pos[a2]))
    q2 = np.where(fan_a, R.pos[nextvR[b1]], np.where(fan_b, L.pos[a2], R.pos[b2]))
    q3 = R.pos[b1]
    cost, ok = _cell_cost(q0, q1, q2, q3, margin)
    arcs = [(src[ok], dst[ok], cost[ok])]

    # --- cap cells at both ends --------------------------------------------------------------
    # start: s, [one vertex between s and a on L, or between s and b on R], a, b
    cap_src, cap_dst, cap_cost = [], [], []
    for end in (0, 1):
        if end == 0:
            nl0 = L.vrank[pa] - L.is_vertex[pa]  # vertices strictly before a
            nr0 = R.vrank[pb] - R.is_vertex[pb]
            first_l = np.flatnonzero(L.is_vertex)[:1]
            first_r = np.flatnonzero(R.is_vertex)[:1]
            sel = (nl0 + nr0) == 1
            tipz = z[s]
            # cycle s, (l), a, b, (r)
            c_l = (nl0 == 1) & sel
            q0 = np.full(pa.size, tipz)
            q1 = np.where(c_l, L.pos[first_l[0]] if first_l.size else 0, L.pos[pa])
            q2 = np.where(c_l, L.pos[pa], R.pos[pb])
            q3 = np.where(c_l, R.pos[pb], R.pos[first_r[0]] if first_r.size else 0)
        else:
            nlt = L.vrank[-1] - L.vrank[pa]  # vertices strictly after a
            nrt = R.vrank[-1] - R.vrank[pb]
            last_l = np.flatnonzero(L.is_vertex)[-1:]
            last_r = np.flatnonzero(R.is_vertex)[-1:]
            sel = (nlt + nrt) == 1
            tipz = z[e]
            c_l = (nlt == 1) & sel
            # cycle a, (l), e, (r), b
            q0 = L.pos[pa]
            q1 = np.where(c_l, L.pos[last_l[0]] if last_l.size else 0, np.full(pa.size, tipz))
            q2 = np.where(c_l, np.full(pa.size, tipz), R.pos[last_r[0]] if last_r.size else 0)
            q3 = R.pos[pb]
        cost, ok = _cell_cost(q0, q1, q2, q3, margin)
        ok &= sel
        idx = np.flatnonzero(ok)
        if end == 0:
            cap_src.append(np.full(idx.size, nr))
            cap_dst.append(idx)
        else:
            cap_src.append(idx)
            cap_dst.append(np.full(idx.size, nr + 1))
        cap_cost.append(cost[ok])
    arcs.append((np.concatenate(cap_src), np.concatenate(cap_dst), np.concatenate(cap_cost)))
    # round caps: the part cut off by the rung is meshed as a half-disk vertex sector about
    # the rung's midpoint (its sides are the two halves of the rung)
    round_gamma: dict[tuple[int, int], list[int]] = {}
    wmed = float(np.median(np.r_[L.width, R.width]))
    for end in (0, 1):
        if end == 0:
            nin = (L.vrank[pa] - L.is_vertex[pa]) + (R.vrank[pb] - R.is_vertex[pb])
            near = (L.sigma[pa] <= 4 * wmed) & (R.sigma[pb] <= 4 * wmed)
        else:
            nin = (L.vrank[-1] - L.vrank[pa]) + (R.vrank[-1] - R.vrank[pb])
            near = (L.sigma[-1] - L.sigma[pa] <= 4 * wmed) & (R.sigma[-1] - R.sigma[pb] <= 4 * wmed)
        # a round cap's every point lies within 25 % of the rung's half-length from the
        # rung's midpoint (:func:`_round_cap_cost`): the tip first, for all rungs at once
        mid, half = 0.5 * (L.pos[pa] + R.pos[pb]), 0.5 * np.abs(L.pos[pa] - R.pos[pb])
        with np.errstate(divide="ignore", invalid="ignore"):
            rad = np.abs(z[s if end == 0 else e] - mid) / half
        near &= (rad >= 0.8 * (1 - 1e-9)) & (rad <= 1.25 * (1 + 1e-9))
        for r in np.flatnonzero(near & (nin >= 1) & (nin <= 96)):
            a, b = int(pa[r]), int(pb[r])
            if end == 0:
                lv_ = [int(g) for g in L.gid[:a][L.is_vertex[:a]]]
                rv_ = [int(g) for g in R.gid[:b][R.is_vertex[:b]]]
                ids = [int(R.gid[b]), *rv_[::-1], s, *lv_, int(L.gid[a])]
                pts = np.r_[R.pos[b], z[rv_[::-1]], z[s], z[lv_], L.pos[a]]
            else:
                lv_ = [int(g) for g in L.gid[a + 1 :][L.is_vertex[a + 1 :]]]
                rv_ = [int(g) for g in R.gid[b + 1 :][R.is_vertex[b + 1 :]]]
                ids = [int(L.gid[a]), *lv_, e, *rv_[::-1], int(R.gid[b])]
                pts = np.r_[L.pos[a], z[lv_], z[e], z[rv_[::-1]], R.pos[b]]
            c = _round_cap_cost(pts, sector_chords, turn)
            if c is None:
                continue
            round_gamma[(end, int(r))] = ids
            if end == 0:
                arcs.append((np.array([nr]), np.array([r]), np.array([c])))
            else:
                arcs.append((np.array([r]), np.array([nr + 1]), np.array([c])))

    # bends: two rungs from one wall vertex (the apex, a reflex corner) with any stretch of the
    # other wall between their far ends; that region is a vertex sector about the apex
    sector_gamma: dict[tuple[int, int], tuple[int, list[int]]] = {}
    lo_ang = 60.0 + margin
    # the polygon vertices among the other wall's points, by the apex's wall (L: on_l)
    O_vertices = {True: np.flatnonzero(R.is_vertex), False: np.flatnonzero(L.is_vertex)}
    bends: list[tuple] = []  # per apex: its candidate pairs of rungs (arrays)
    for C, O, pA, pB, on_l in ((L, R, pa, pb, True), (R, L, pb, pa, False)):
        for ap in np.flatnonzero(C.is_vertex & (C.theta >= 200.0)):
            checkpoint()
            if deadline is not None and time.perf_counter() > deadline:
                raise ThinPartError("no ladder of straight cells was found in the time allowed")
            rs = np.flatnonzero(pA == ap)
            if rs.size < 2 or O_vertices[on_l].size == 0:
                continue
            rs = rs[np.argsort(pB[rs], kind="stable")]
            zc = C.pos[ap]
            # every pair of rungs from the apex, in (earlier, later) order; the tests that
            # need only the two far ends run on all pairs at once
            i_, j_ = np.triu_indices(rs.size, 1)
            o0, o1 = pB[rs[i_]], pB[rs[j_]]
            nb = np.where(o1 > o0, O.vrank[np.maximum(o1 - 1, 0)] - O.vrank[o0], 0)
            ok = (nb >= 1) & (o1 - o0 <= 400)
            # a single wall vertex between the far ends, not reflex: a plain fan cell
            first_mid = O_vertices[on_l][np.minimum(O.vrank[o0], O_vertices[on_l].size - 1)]
            ok &= ~((nb == 1) & (O.theta[first_mid] <= 120.0))
            # the sector's angle at the apex: m = 1, or m = 2 subsectors
            th = _ccw_angle(
                np.where(on_l, O.pos[o1], O.pos[o0]) - zc, np.where(on_l, O.pos[o0], O.pos[o1]) - zc
            )
            ok &= ((lo_ang <= th) & (th <= 120.0 - margin)) | (
                (120.0 + margin <= th) & (th <= 240.0 - margin)
            )
            ok &= ~(C.theta[ap] - th < 2 * lo_ang)
            sel = np.flatnonzero(ok)
            r0_, r1_ = rs[i_[sel]], rs[j_[sel]]
            bends.append((on_l, zc, o0[sel], o1[sel], nb[sel], r0_, r1_, int(C.gid[ap])))
    if bends:
        # each candidate's crosscut: a far end, the other wall's vertices between, the other
        # far end (from the later rung's on the left wall); its connection quads' angles, in
        # batches of the same number of points
        on = np.concatenate([np.full(x[2].size, x[0]) for x in bends])
        zc = np.concatenate([np.full(x[2].size, x[1]) for x in bends])
        o0, o1, nb, r0_, r1_ = (np.concatenate([x[k] for x in bends]) for k in range(2, 7))
        apex_id = np.concatenate([np.full(x[2].size, x[7]) for x in bends])
        keep = np.zeros(on.size, dtype=bool)
        cost = np.zeros(on.size)
        gids: list[np.ndarray | None] = [None] * on.size
        for on_l, O in ((True, R), (False, L)):
            for nbv in np.unique(nb[on == on_l]):
                checkpoint()
                if deadline is not None and time.perf_counter() > deadline:
                    # (long far walls make big batches: a round outline that is no corridor
                    # at all has bends with hundreds of vertices between their rungs)
                    raise ThinPartError("no ladder of straight cells was found in the time allowed")
                idx = np.flatnonzero((on == on_l) & (nb == nbv))
                mids = O_vertices[on_l][O.vrank[o0[idx]][:, None] + np.arange(nbv)[None, :]]
                if on_l:
                    seq = np.column_stack([o1[idx], mids[:, ::-1], o0[idx]])
                else:
                    seq = np.column_stack([o0[idx], mids, o1[idx]])
                n_pts = _sector_points(int(nbv) + 1, sector_chords)
                A, good = _connection_angles_many(zc[idx], O.pos[seq], n_pts)
                inside = (A.min(axis=(1, 2)) >= lo_ang) & (A.max(axis=(1, 2)) <= 120.0 - margin)
                keep[idx] = good & inside
                cost[idx] = 4.0 + np.abs(A - 90).max(axis=(1, 2)) / 30
                # where plain rows leave the range, rows that turn (:func:`_turned_rows`)
                redo = np.flatnonzero(good & ~inside) if turn else ()
                if len(redo):
                    A2, _ = _connection_angles_many(
                        zc[idx[redo]], O.pos[seq[redo]], n_pts, turned=True
                    )
                    fine = (A2.min(axis=(1, 2)) >= lo_ang) & (A2.max(axis=(1, 2)) <= 120.0 - margin)
                    keep[idx[redo[fine]]] = True
                    cost[idx[redo[fine]]] = 4.5 + np.abs(A2[fine] - 90).max(axis=(1, 2)) / 30
                # and round bends (:func:`_round_bend`): a far wall round about another centre
                for t in idx[~keep[idx]] if turn and nbv >= 3 else ():
                    row = seq[np.searchsorted(idx, t)]
                    if _round_bend(complex(zc[t]), O.pos[row], sector_chords, margin) is not None:
                        keep[t] = True
                        cost[t] = 4.6
                kept = keep[idx]
                for t, row in zip(idx[kept], O.gid[seq[kept]]):
                    gids[t] = row
        for t in np.flatnonzero(keep):
            sector_gamma[(int(r0_[t]), int(r1_[t]))] = (int(apex_id[t]), gids[t].tolist())
        arcs.append((r0_[keep], r1_[keep], cost[keep]))

    S = np.concatenate([x[0] for x in arcs])
    D = np.concatenate([x[1] for x in arcs])
    W = np.concatenate([x[2] for x in arcs])
    # two sectors may not share a rung (each fixes its points): a rung reached through a sector
    # is a separate node (nr + 2 + r) from which every arc but a sector leaves
    sec = np.zeros(S.size, dtype=bool)
    if sector_gamma:
        skey = np.array([a * (nr + 2) + b for a, b in sector_gamma], dtype=np.int64)
        sec = np.isin(S.astype(np.int64) * (nr + 2) + D, skey)
    copy = nr + 2
    plain = ~sec & (S < nr)  # arcs out of a rung (not out of the source)
    S = np.concatenate([S, S[plain] + copy])
    D = np.concatenate([np.where(sec, D + copy, D), D[plain]])
    W = np.concatenate([W, W[plain]])
    n_nodes = 2 * nr + 2
    # one arc per (from, to): the cheapest (a sparse matrix would add duplicates up)
    key = S.astype(np.int64) * n_nodes + D
    order_ = np.lexsort((W, key))
    first_ = np.r_[True, key[order_][1:] != key[order_][:-1]]
    S, D, W = S[order_][first_], D[order_][first_], W[order_][first_]
    g = coo_matrix((W, (S, D)), shape=(n_nodes, n_nodes)).tocsr()
    dist_all, pred = dijkstra(g, indices=nr, return_predecessors=True)
    dist = np.minimum(dist_all[: nr + 2], np.r_[dist_all[copy:], np.inf, np.inf])
    if debug is not None:
        debug.update(L=L, R=R, pa=pa, pb=pb, dist=dist, S=S, D=D)
    open_end = False
    if not np.isfinite(dist[nr + 1]) and partial:
        # an arm: the ladder from the start tip as far as it goes, cut one and a half widths
        # before it gets stuck (at a rung not fixed by a sector); the rest is the body
        reached = np.flatnonzero(np.isfinite(dist_all[:nr]))
        if reached.size:
            sig = L.sigma[pa[reached]] + R.sigma[pb[reached]]
            wmed_ = float(np.median(np.r_[L.width, R.width]))
            ok_ = sig <= sig.max() - 3.0 * wmed_
            if own_width and not ok_.any():
                # an arm of a wide body (a leg of a traced animal): the walls' median width
                # is the body's; one and a half of the arm's own widths (its median rung)
                rung = np.abs(L.pos[pa[reached]] - R.pos[pb[reached]])
                ok_ = sig <= sig.max() - 3.0 * min(wmed_, float(np.median(rung)))
            if ok_.any():
                cut = int(reached[ok_][np.argmax(sig[ok_])])
                path = []
                k = cut
                while k != nr:
                    path.append(int(k) - copy if k >= copy else int(k))
                    k = pred[k]
                path = path[::-1]
                open_end = True
    if not open_end and not np.isfinite(dist[nr + 1]):
        reached = np.flatnonzero(np.isfinite(dist[:nr]))
        if reached.size:
            far = reached[np.argmax(L.sigma[pa[reached]] + R.sigma[pb[reached]])]
            where = f"near ({L.pos[pa[far]].real:.6g}, {L.pos[pa[far]].imag:.6g})"
        else:
            where = f"at the end near ({z[s].real:.6g}, {z[s].imag:.6g})"
        raise ThinPartError(
            f"no layout of straight cells with corners in [60°, 120°] continues {where}"
        )
    if not open_end:
        path = []
        k = pred[nr + 1]
        while k != nr:
            path.append(int(k) - copy if k >= copy else int(k))
            k = pred[k]
        path = path[::-1]

    # --- the cells of the path ---------------------------------------------------------------
    cells: list[list[int]] = []
    kind: list[str] = []
    gl = lambda C, i: int(C.gid[i])  # noqa: E731
    first_a, first_b = pa[path[0]], pb[path[0]]
    # start cap: a quadrilateral cell, or a round cap when it is cheaper (or the only way)
    rounds: list[tuple[int, ...]] = []
    cell_rungs: list[tuple[int, int]] = []
    ring = [s] + [int(v) for v in L.gid[:first_a][L.is_vertex[:first_a]]] + [gl(L, first_a)]
    ring += [gl(R, first_b), *[int(v) for v in R.gid[:first_b][R.is_vertex[:first_b]]][::-1]]
    if len(ring) == 4 and ((0, path[0]) not in round_gamma or _quad_cap_ok(coarse[ring], margin)):
        cells.append(ring)
        kind.append("cap")
        cell_rungs.append((-1, 0))
    else:
        rounds.append(tuple(round_gamma[(0, path[0])]))
    sectors: list[tuple[int, tuple[int, ...]]] = []
    for k_, (r0, r1) in enumerate(itertools.pairwise(path)):
        a, b, a_, b_ = pa[r0], pb[r0], pa[r1], pb[r1]
        if (r0, r1) in sector_gamma:  # (never also a plain fan: that has one corner between)
            apex, ids = sector_gamma[(r0, r1)]
            sectors.append((apex, tuple(ids)))
            continue
        cell_rungs.append((k_, k_ + 1))
        if a_ == a:
            cells.append([gl(L, a), gl(R, b_), gl(R, nextvR[b]), gl(R, b)])
            kind.append("fan")
        elif b_ == b:
            cells.append([gl(L, a), gl(L, nextvL[a]), gl(L, a_), gl(R, b)])
            kind.append("fan")
        else:
            cells.append([gl(L, a), gl(L, a_), gl(R, b_), gl(R, b)])
            kind.append("ladder")
    la_, lb_ = pa[path[-1]], pb[path[-1]]
    ring = [gl(L, la_)] + [int(v) for v in L.gid[la_ + 1 :][L.is_vertex[la_ + 1 :]]] + [e]
    ring += [*[int(v) for v in R.gid[lb_ + 1 :][R.is_vertex[lb_ + 1 :]]][::-1], gl(R, lb_)]
    if open_end:
        pass  # the last rung is where the arm meets the body
    elif len(ring) == 4 and (
        (1, path[-1]) not in round_gamma or _quad_cap_ok(coarse[ring], margin)
    ):
        cells.append(ring)
        kind.append("cap")
        cell_rungs.append((len(path) - 1, -1))
    else:
        rounds.append(tuple(round_gamma[(1, path[-1])]))
    cell_arr = np.asarray(cells, dtype=np.int64).reshape(-1, 4)
    round_ids = np.asarray(
        [i for g in rounds for i in g] + [i for a, g in sectors for i in (a, *g)], dtype=np.int64
    )
    used = np.unique(np.concatenate([cell_arr.ravel(), round_ids]))
    # keep coarse vertices: all polygon vertices, then the used samples renumbered
    samp_used = used[used >= n]
    remap = np.full(coarse.size, -1, dtype=np.int64)
    remap[:n] = np.arange(n)
    remap[samp_used] = n + np.arange(samp_used.size)
    verts = np.concatenate([z, coarse[samp_used]])
    rung_arr = np.asarray([[gl(L, pa[r]), gl(R, pb[r])] for r in path], dtype=np.int64)
    return CorridorLayout(
        vertices=verts,
        cells=remap[cell_arr],
        kind=tuple(kind),
        rungs=remap[rung_arr],
        tips=(int(s), int(e)),
        edge_of=np.concatenate([np.full(n, -1), edge_of[samp_used]]),
        round_caps=tuple(tuple(int(remap[i]) for i in g) for g in rounds),
        cell_rungs=np.asarray(cell_rungs, dtype=np.int64).reshape(-1, 2),
        sectors=tuple((int(remap[a]), tuple(int(remap[i]) for i in g)) for a, g in sectors),
        open_end=open_end,
        turn=turn,
    )


class _Walls:
    """The polygon's edges for ray casts: the vertices ``z`` and an STR tree of the edges, so
    that each ray is tested against the few edges near it (GEOS's intersection of a ray with
    the whole ring tests every edge: 35 ms per 4,500 rays on a 1,600-vertex river)."""

    def __init__(self, z: np.ndarray) -> None:
        self.z = np.asarray(z, dtype=np.complex128)
        self.e = np.roll(self.z, -1) - self.z  # edge k from z[k] to z[k + 1]
        a, b = self.z, np.roll(self.z, -1)
        self.tree = shapely.STRtree(
            shapely.linestrings(
                np.stack([np.column_stack([a.real, a.imag]), np.column_stack([b.real, b.imag])], 1)
            )
        )

    def first_hits(
        self, p0: np.ndarray, u: np.ndarray, reach: float, near: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per ray p0 + s·u (unit directions ``u``, 0 ≤ s ≤ ``reach``), the distance s of its
        first point on an edge (inf where it meets none) and that edge (−1 where none). Rays
        are cast ``near`` long first (a long ray's box holds most of the polygon's edges),
        then the rest full length."""
        s_first = np.full(p0.size, np.inf)
        edge = np.full(p0.size, -1, dtype=np.int64)
        todo = np.arange(p0.size)
        for length in (near, reach) if near < reach else (reach,):
            if todo.size == 0:
                break
            s_first[todo], edge[todo] = self._cast(p0[todo], length * u[todo])
            todo = todo[edge[todo] < 0]
        return s_first, edge

    def _cast(self, a: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per segment a -> a + d, the distance from a of its first point on an edge (inf where
        it meets none) and that edge (−1)."""
        dist = np.full(a.size, np.inf)
        edge = np.full(a.size, -1, dtype=np.int64)
        if a.size == 0:
            return dist, edge
        b = a + d
        rays = shapely.linestrings(
            np.stack([np.column_stack([a.real, a.imag]), np.column_stack([b.real, b.imag])], 1)
        )
        ri, si = self.tree.query(rays, predicate="intersects")
        if ri.size == 0:
            return dist, edge
        aa, dd = a[ri], d[ri]
        e0, e = self.z[si], self.e[si]
        w = e0 - aa
        den = (np.conj(dd) * e).imag  # cross(d, e)
        flat = np.abs(den) <= 1e-12 * np.abs(dd) * np.abs(e)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(flat, np.inf, (np.conj(w) * e).imag / den)  # cross(w, e) / cross(d, e)
        if np.any(flat):
            # an edge along the segment: its nearer end (or the segment's start, inside it)
            n2 = np.abs(dd[flat]) ** 2
            t0 = (np.conj(dd[flat]) * w[flat]).real / n2
            t1 = (np.conj(dd[flat]) * (w[flat] + e[flat])).real / n2
            t[flat] = np.maximum(np.minimum(t0, t1), 0.0)
        s_hit = np.clip(t, 0.0, 1.0) * np.abs(dd)
        order = np.lexsort((s_hit, ri))
        first = order[np.r_[True, ri[order][1:] != ri[order][:-1]]]
        dist[ri[first]] = s_hit[first]
        edge[ri[first]] = si[first]
        return dist, edge


def _ray_hits(
    origin_dir,
    walls: _Walls,
    line,
    chain: tuple[np.ndarray, np.ndarray, np.ndarray],
    reach: float,
    near: float,
) -> np.ndarray:
    """Arc-length positions on ``line`` (a wall chain) of the first boundary points hit by rays
    from the given points along the given directions turned by 0° and ±20° (cast ``near``
    long first, see :meth:`_Walls.first_hits`). ``chain``: per polygon edge its segment of the
    chain (−1 off it), and the chain's points and their arc lengths; a hit on another edge
    counts where it lies on the line all the same (at a chain's end vertex)."""
    pts, d = origin_dir
    if pts.size == 0:
        return np.zeros(0)
    turns = np.exp(1j * np.radians([0.0, 20.0, -20.0]))
    o = np.repeat(pts, turns.size)
    u = (d[:, None] * turns[None, :]).ravel()
    eps = 1e-9 * reach
    p0 = o + eps * u
    dist, edge = walls.first_hits(p0, u, reach - eps, near)
    ok = edge >= 0
    q, j = p0[ok] + dist[ok] * u[ok], chain[0][edge[ok]]
    on = j >= 0
    along = chain[2][j[on]] + np.abs(q[on] - chain[1][j[on]])
    off = q[~on]
    if off.size:
        qp = shapely.points(off.real, off.imag)
        at_line = shapely.distance(qp, line) < 1e-9 * reach
        along = np.r_[along, np.asarray(shapely.line_locate_point(line, qp[at_line]), float)]
    return along


def _facing_distance(
    pos, normal, walls: _Walls, floor: float, reach: float, near: float
) -> np.ndarray:
    """Width of the corridor at each wall point: the distance along the inward normal to the
    first point of the polygon's boundary (a ray cast, ``near`` long first), at least
    ``floor``."""
    eps = 1e-9 * reach
    p0 = pos + eps * normal
    dist, _edge = walls.first_hits(p0, normal, reach - eps, near)
    with np.errstate(invalid="ignore"):
        d = np.where(np.isfinite(dist), np.abs(p0 + dist * normal - pos), reach)
    return np.maximum(d, floor)


def _quad_cap_ok(q: np.ndarray, margin: float) -> bool:
    """Whether a four-corner cap cell is admissible."""
    _, ok = _cell_cost(q[0:1], q[1:2], q[2:3], q[3:4], margin)
    return bool(ok[0])


def _round_cap_cost(pts: np.ndarray, sector_chords: int = 16, turn: bool = False) -> float | None:
    """Cost of a round cap with boundary ``pts`` (first and last: the rung's ends), or None if
    the cap is not a half-disk about the rung's midpoint: every point within 25 % of the
    rung's half-length from the midpoint, in strictly increasing polar angle from 0° to 180°."""
    o = 0.5 * (pts[0] + pts[-1])
    half = 0.5 * abs(pts[-1] - pts[0])
    if half == 0:
        return None
    w = (pts - o) / (pts[0] - o)
    rad = np.abs(w[1:-1])
    if rad.size == 0 or rad.min() < 0.8 or rad.max() > 1.25:
        return None
    # no chord may pass closer to O than the points do (a flat end is not round)
    d = np.diff(w)
    t = np.clip(-(np.conj(d) * w[:-1]).real / np.abs(d) ** 2, 0.0, 1.0)
    if np.abs(w[:-1] + t * d).min() < 0.8:
        return None
    ang = np.angle(w)
    ang[0], ang[-1] = 0.0, np.pi
    if np.any(ang[1:-1] <= 0) or np.any(np.diff(ang) <= 1e-9):
        return None
    # the connection quads between the sector's core and the cap's points: plain rows, else
    # turned ones (:func:`_turned_rows`)
    for turned in (False, True)[: 1 + turn]:
        try:
            a_ = _connection_angles(
                o, pts, _sector_points(pts.size - 1, sector_chords), turned=turned
            )
        except ThinPartError:
            return None
        if a_.min() >= 60.0 + CELL_MARGIN and a_.max() <= 120.0 - CELL_MARGIN:
            return 3.0 + float(np.abs(a_ - 90.0).max()) / 30.0 + 0.5 * turned
    return None


def _cell_cost(q0, q1, q2, q3, margin):
    """Cost of the quadrilateral cells (q0, q1, q2, q3) and whether each is admissible (convex,
    counter-clockwise, corners in [60° + margin, 120° − margin])."""
    c = np.stack([q0, q1, q2, q3], axis=-1)
    e = np.roll(c, -1, axis=-1) - c
    ang = _ccw_angle(e, -np.roll(e, 1, axis=-1))
    ok = np.all((ang >= 60.0 + margin) & (ang <= 120.0 - margin), axis=-1)
    ok &= np.abs(ang.sum(axis=-1) - 360.0) < 1e-6
    side = np.abs(e)
    dev = np.abs(ang - 90.0).max(axis=-1) / 30.0
    ratio = side.min(axis=-1) / np.maximum(side.max(axis=-1), 1e-300)
    cost = 1.0 + 2.0 * dev**2 + 0.5 * np.maximum(0.0, -np.log(np.maximum(ratio, 1e-12) / 0.2))
    return cost, ok


def mesh_corridor(
    z: np.ndarray,
    *,
    across: int = 4,
    size: float | None = None,
    lay: CorridorLayout | None = None,
    turn: bool = False,
) -> CorridorMesh:
    """Quad mesh of a corridor polygon: its ladder layout (:func:`ladder_layout`, or ``lay``
    when given), its round ends and bends meshed as vertex sectors, and its cells refined by
    runs of rungs (:func:`_refine_ladder`) with about ``across`` quads across the corridor (more
    where ``size``, a largest edge length, asks for it) and roughly square quads along it.

    Every new angle lies in [60°, 120°]: cells are convex with corners in [60.05°, 119.95°] and
    refined as bilinear grids (the bilinear argument), the sectors' angles are exact or checked,
    and the ruled cells of runs that morph between two sectors are checked.

    Sectors are tried with crosscuts of at least 8 chords first (their cores put fewer points
    across the corridor: 30–45 % fewer quads on buffered walks), then of 16 where a round end
    or a bend needs them (:data:`SECTOR_CHORDS`); polygons of more than
    :data:`SECTOR_RETRY_MAX` vertices, whose layout search is long, get 16 at once.
    ``turn``: the layouts are searched for with sectors whose rows turn and with round bends
    (:func:`ladder_layout`).

    Raises:
        ThinPartError: no ladder layout exists, or a sector or morphing run fails its check.
    """
    z = np.asarray(z, dtype=np.complex128)
    tries = SECTOR_CHORDS if z.size <= SECTOR_RETRY_MAX else SECTOR_CHORDS[-1:]
    error: ThinPartError | None = None
    for least in tries:
        try:
            lay_ = ladder_layout(z, sector_chords=least, turn=turn) if lay is None else lay
            return _mesh_layout(lay_, z, across, {}, size, least)
        except ThinPartError as exc:
            error = exc
    assert error is not None
    raise error


#: How many pairs of split rows a corridor's transition cascades may optimise (0.1–0.3 s each);
#: beyond it stages are built from the template alone (fewer succeed, none is slow). A count,
#: not a time, so that the mesh does not depend on the machine's load.
CASCADE_POLISH = 80


#: Polygons with more vertices than this go straight to sectors of 16 chords (a second layout
#: search of a 1,000-vertex river takes minutes).
SECTOR_RETRY_MAX = 400


#: Least crosscut chord counts of corridor sectors, tried in turn by :func:`mesh_corridor`.
SECTOR_CHORDS = (8, 16)


def _mesh_layout(
    lay: CorridorLayout,
    z: np.ndarray,
    across: int,
    extra_fixed: dict[int, np.ndarray],
    max_size: float | None = None,
    sector_chords: int = 16,
    transitions: bool = False,
    tilt: bool = False,
) -> CorridorMesh:
    """Refine a ladder layout of the polygon ``z`` (sectors built, rungs' points fixed by
    them and by ``extra_fixed``, runs refined and glued) into a :class:`CorridorMesh`: about
    ``across`` segments per median rung, segments no longer than ``max_size`` where given.

    ``transitions``: the sectors keep their own counts instead of taking those of the
    ``extra_fixed`` rungs, and a run joining a rung of ``extra_fixed`` to a sector with fewer
    points changes its count by a transition cascade (:func:`_run_params`); ``tilt``: its
    stages may even out rows only part of the way
    (:func:`quadmesh.transition.transition_cascade`)."""
    rung_len = np.abs(lay.vertices[lay.rungs[:, 0]] - lay.vertices[lay.rungs[:, 1]])
    size = float(np.median(rung_len)) / max(int(across), 1)
    if max_size is not None:
        size = min(size, float(max_size))
    tips = np.flatnonzero(np.degrees(interior_angles(z)) < 60.0)
    # sectors first (round ends, bends): they fix the points on their rungs
    rung_of = {(int(a), int(b)): k for k, (a, b) in enumerate(lay.rungs)}

    def rung_index(u: int, v: int) -> tuple[int, bool]:
        """Index of the rung joining u and v, and whether it runs from u to v."""
        if (u, v) in rung_of:
            return rung_of[(u, v)], True
        return rung_of[(v, u)], False

    V = lay.vertices
    structs = []  # (apex, gamma ids, [(rung, from apex to gamma end: 0 or -1)])
    for g in lay.round_caps:
        structs.append((0.5 * (V[g[0]] + V[g[-1]]), list(g), "cap"))
    for apex_id, g in lay.sectors:
        structs.append((V[apex_id], list(g), "bend"))
    fixed: dict[int, np.ndarray] = {}
    built = []
    if structs:
        # each sector's crosscut as coarse as its own boundary allows (2^k + 1 points); a round
        # end puts an odd number of points on its rung with 2^k chords and an even number with
        # 2^k + 1 (its core's two sides then differ by one point): the parity every fixed rung
        # must share when another part (a body behind an arm) fixes a rung
        sizes = {p.size for p in extra_fixed.values()}
        odd = not sizes or max(sizes) % 2 == 1
        n_pts = [
            _sector_points(len(g) - 1, sector_chords) + (kind == "cap" and not odd)
            for _, g, kind in structs
        ]
        # a bend that straight or turning rows cannot make may be a round bend (as the layout
        # search decided, in the same order)
        centres: list[complex | None] = [None] * len(structs)
        for i, ((o, g, kind), n) in enumerate(zip(structs, n_pts)):
            if not (lay.turn and kind == "bend"):
                continue
            fits = False
            for turned in (False, True):
                try:
                    a_ = _connection_angles(o, V[g], n, turned=turned)
                except ThinPartError:
                    break
                if a_.min() >= 60.0 + CELL_MARGIN and a_.max() <= 120.0 - CELL_MARGIN:
                    fits = True
                    break
            if not fits:
                centres[i] = _round_bend(o, V[g], sector_chords)

        def build(i: int, rows=None, turned: float = 0.0):
            o, g, _kind = structs[i]
            if centres[i] is not None:
                return _round_bend_mesh(o, V[g], centres[i], sector_chords, g, rows, size)
            return _sector_mesh(o, V[g], n_pts[i], 0, g, row_fracs=rows, turned=turned)

        base = [build(i) for i in range(len(structs))]
        for (_o, _g, kind), m in zip(structs, base):
            if kind == "bend" and m[5].size != m[6].size:
                raise ThinPartError("a bend of the corridor has sides of unequal refinement")
        apexes = [None] * len(lay.round_caps) + [a for a, _g in lay.sectors]
        sides = [
            _sector_sides(V, o, g, kind, m, rung_index, a)
            for (o, g, kind), m, a in zip(structs, base, apexes)
        ]
        plan = _plan_sector_rows(
            lay, sides, {} if transitions else {k: p.size for k, p in extra_fixed.items()}
        )
        for i, ((o, g, kind), rows) in enumerate(zip(structs, plan)):
            m = build(i, rows)
            a_ = m[4]
            turning = lay.turn and rows[0].size and centres[i] is None
            for share in TURN_SHARES if turning else ():
                if a_.min() >= 60.0 and a_.max() <= 120.0:
                    break
                # a sharp bend or a ragged end: the rows turn (as the layout search checked)
                m2 = build(i, rows, share)
                if m2[4].min() >= 60.0 and m2[4].max() <= 120.0:
                    m, a_ = m2, m2[4]
            if a_.min() < 60.0 or a_.max() > 120.0:
                raise ThinPartError(
                    f"the {'round end' if kind == 'cap' else 'bend'} near ({o.real:.6g}, "
                    f"{o.imag:.6g}) is not round enough about its centre (connection angles "
                    f"[{a_.min():.1f}°, {a_.max():.1f}°])"
                )
            _gp, _ids, allp, _q, _a, side1, side2 = m
            if kind == "cap":
                k, fwd = rung_index(g[0], g[-1])
                u, v = (g[0], g[-1]) if fwd else (g[-1], g[0])
                on = np.r_[side1, side2[1:]]
                par = _param_list(_side_params(allp, on, V[u], V[v]))
                fixed[k] = par
                built.append((m, [(k, u, v, on)]))
            else:
                apex_id = next(a for a, gg in lay.sectors if list(gg) == g)
                entries = []
                for side, end in ((side1, g[0]), (side2, g[-1])):
                    k, fwd = rung_index(apex_id, end)
                    u, v = (apex_id, end) if fwd else (end, apex_id)
                    par = _param_list(_side_params(allp, side, V[u], V[v]))
                    if k in fixed and fixed[k].size != par.size:
                        raise ThinPartError("two sectors share a crosscut of the corridor")
                    fixed[k] = par
                    entries.append((k, u, v, side))
                built.append((m, entries))
    for k, par in extra_fixed.items():
        if k in fixed:
            raise ThinPartError("a sector of the corridor sits where it meets the rest")
        fixed[k] = par
    pts, quads, cell, rung_ids = _refine_ladder(
        lay, size, fixed, set(tips.tolist()), transitions, tilt
    )
    for k_s, (m, entries) in enumerate(built):
        gp, gamma_ids, allp, sq, _a, _s1, _s2 = m
        n_pts = gp.size
        gl = np.full(allp.size, -1, dtype=np.int64)
        gid = np.asarray(gamma_ids)
        gl[:n_pts][gid >= 0] = gid[gid >= 0]
        for k, u, v, side in entries:
            rung = rung_ids[k]  # from u to v
            t = _side_params(allp, side, V[u], V[v])
            inner = side[(t > 1e-12) & (t < 1 - 1e-12) & (gl[side] < 0)]
            inner = inner[np.argsort(_side_params(allp, inner, V[u], V[v]))]
            if inner.size != rung.size - 2:
                raise ThinPartError(
                    f"a sector of the corridor near ({V[u].real:.6g}, {V[u].imag:.6g}) and its "
                    f"cells disagree on the points across it ({inner.size} against "
                    f"{rung.size - 2})"
                )
            gl[inner] = rung[1:-1]
            for end in (u, v):  # the rung's ends that are sector points (its apex)
                hit = side[np.abs(allp[side] - V[end]) <= 1e-12 * abs(V[v] - V[u])]
                gl[hit[gl[hit] < 0]] = end
        own = np.flatnonzero(gl < 0)
        gl[own] = pts.size + np.arange(own.size)
        pts = np.concatenate([pts, allp[own]])
        quads = np.concatenate([quads, gl[sq]])
        cell = np.concatenate([cell, np.full(len(sq), -2 - k_s)])
    _check_ladder_angles(pts, quads, z)
    return CorridorMesh(pts, quads, cell, lay, rung_ids[-1] if lay.open_end else None, rung_ids[0])


@dataclass
class _SectorSide:
    """One straight side of a corridor sector (a round end's half rung, or a bend's rung from
    its apex) in the coordinates of the rung it lies on: the rung ``k`` (parameter 0 at its
    L end, 1 at its R end), the parameters of the sector's core points on it (``core``, the
    sector's centre included), and the map from a parameter beyond the core to the fraction
    of the side's connection segment (core's outer point to the crosscut) where a row must
    cross to put a point there: ``frac(p) = (|p − p_centre|·scale − inner) / (outer − inner)``.
    """

    k: int
    core: np.ndarray
    p_centre: float
    scale: float
    inner: float
    outer: float
    p_end: float

    def frac(self, p: np.ndarray) -> np.ndarray:
        d = np.abs(np.asarray(p) - self.p_centre) * self.scale
        return (d - self.inner) / (self.outer - self.inner)


def _sector_sides(V, o, g, kind, m, rung_index, apex_id) -> list[_SectorSide]:
    """The :class:`_SectorSide` of both sides of a sector (round end: both halves of its rung;
    bend: its two rungs from the apex) built with no connection rows (``m``)."""
    allp, side1, side2 = m[2], m[5], m[6]
    out = []
    if kind == "cap":
        k, fwd = rung_index(g[0], g[-1])
        u, v = (g[0], g[-1]) if fwd else (g[-1], g[0])
        L = abs(V[v] - V[u])
        for side, p_end in ((side1, 0.0 if fwd else 1.0), (side2, 1.0 if fwd else 0.0)):
            d = np.abs(allp[side] - o)
            core = 0.5 + (p_end - 0.5) * 2.0 * d[:-1] / L
            out.append(_SectorSide(k, core, 0.5, L, float(d[-2]), float(d[-1]), p_end))
        return out
    for side, end in ((side1, g[0]), (side2, g[-1])):
        k, fwd = rung_index(apex_id, end)
        L = abs(V[end] - o)
        d = np.abs(allp[side] - o)
        p_c = 0.0 if fwd else 1.0
        core = p_c + (1.0 - 2.0 * p_c) * d[:-1] / L
        out.append(_SectorSide(k, core, p_c, L, float(d[-2]), float(d[-1]), 1.0 - p_c))
    return out


def _runs(lay: CorridorLayout) -> list[np.ndarray]:
    """The runs of a ladder layout: maximal stretches of consecutive rungs joined by ladder
    cells (every rung is in exactly one run)."""
    nr = len(lay.rungs)
    link = np.zeros(max(nr - 1, 0), dtype=bool)
    for c, (k0, _k1) in enumerate(lay.cell_rungs):
        if lay.kind[c] == "ladder":
            link[k0] = True
    cut = np.flatnonzero(~link) + 1
    return [r for r in np.split(np.arange(nr), cut) if r.size]


def _fill(fixed: np.ndarray, count: int, blocked: list[tuple[float, float]]) -> np.ndarray:
    """``fixed`` (sorted parameters) with points added, each time in the middle of the widest
    gap that no ``blocked`` interval covers, until there are ``count`` points. Gaps are
    split evenly: a gap of width w holding j new points is cut into j + 1 equal parts."""
    fixed = np.unique(fixed)
    extra = count - fixed.size
    if extra < 0:
        raise ValueError("more fixed points than the count")
    lo, hi = fixed[:-1], fixed[1:]
    mid = 0.5 * (lo + hi)
    free = np.ones(lo.size, dtype=bool)
    for a, b in blocked:
        free &= ~((mid > a) & (mid < b))
    if extra and not free.any():
        raise ThinPartError("a sector of the corridor has no room for its rows")
    width = np.where(free, hi - lo, 0.0)
    j = np.zeros(lo.size, dtype=np.int64)
    for _ in range(extra):
        i = int(np.argmax(width / (j + 1)))
        j[i] += 1
    new = [lo[i] + (hi[i] - lo[i]) * np.arange(1, j[i] + 1) / (j[i] + 1) for i in np.flatnonzero(j)]
    return np.sort(np.concatenate([fixed, *new]))


#: Two sector cores on the two ends of one run whose parameter ranges are at least this far
#: apart (bends on opposite walls, a round end and a bend) are merged: both ends carry the
#: union of the two cores, so the run needs no morph.
_MERGE_GAP = 0.02


def _plan_sector_rows(
    lay: CorridorLayout, sides: list[list[_SectorSide]], extra_sizes: dict[int, int]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Where the connection rows of every corridor sector cross its two sides.

    Every fixed rung (a sector's side, a rung fixed from outside: ``extra_sizes``) must carry
    the same number N of points, of the parity of the round ends' rungs (their core and twice
    their rows). A run whose two end rungs are sector sides with cores on different parts of
    the rung (bends on opposite walls, a round end facing a bend) gets one list on both ends:
    the union of the two cores, filled evenly: each sector puts the other's core points on its
    side by its rows, and the run's cells are plain bilinear grids. Otherwise every side gets
    its own core, filled evenly beyond it (the run morphs between its two ends, checked
    afterwards). A bend's list also holds its core mirrored to the far wall where no other core
    is, so that its two sides look alike and its rows turn little between them. Returns the
    rows' fractions (f1, f2) per sector, as :func:`_sector_mesh` takes them."""
    is_cap = [abs(ss[0].p_centre - 0.5) < 1e-12 for ss in sides]
    at: dict[int, list[tuple[int, int]]] = {}  # rung -> (sector, side); a round end once
    for i, ss in enumerate(sides):
        for j, sd in enumerate(ss[:1] if is_cap[i] else ss):
            at.setdefault(sd.k, []).append((i, j))

    def rng(sd: _SectorSide) -> tuple[float, float]:
        return float(sd.core.min()), float(sd.core.max())

    # per run: the sector sides at its ends and whether their cores merge
    groups = []
    for run in _runs(lay):
        ends = [e for r in {int(run[0]), int(run[-1])} for e in at.get(r, [])]
        if not ends:
            continue
        merged = False
        if len(ends) == 2:
            (a0, a1), (b0, b1) = (rng(sides[i][j]) for i, j in ends)
            merged = a1 + _MERGE_GAP < b0 or b1 + _MERGE_GAP < a0
        groups.append((ends, merged))

    def clusters(ends, merged) -> list[list[np.ndarray]]:
        """The clusters of fixed parameters of each list of a group (one list if merged): the
        cores at its ends and, for a bend, its core mirrored to the far wall unless another
        core is there, so that every list of a bend looks alike (its rows then turn little
        between its two sides)."""
        cores = [
            np.concatenate([sd.core for sd in sides[i]]) if is_cap[i] else sides[i][j].core
            for i, j in ends
        ]
        lists = [cores] if merged else [[c] for c in cores]
        for lst in lists:
            for i, j in ends:
                if is_cap[i] or (not merged and sides[i][j].core is not lst[0]):
                    continue
                mirror = 1.0 - sides[i][j].core
                lo, hi = mirror.min() - _MERGE_GAP, mirror.max() + _MERGE_GAP
                if not any(np.any((c > lo) & (c < hi)) for c in lst):
                    lst.append(mirror)
        return lists

    def needed(ends, merged) -> list[np.ndarray]:
        """The fixed parameters of each list of a group (one list if merged)."""
        return [np.unique(np.r_[0.0, 1.0, *cl]) for cl in clusters(ends, merged)]

    def blocked_of(ends, merged) -> list[list[tuple[float, float]]]:
        return [[(float(c.min()), float(c.max())) for c in cl] for cl in clusters(ends, merged)]

    def halves(i: int, pts: np.ndarray) -> list[int]:
        """Points of ``pts`` beyond the round end i's core, on each of its halves."""
        out = []
        for sd in sides[i]:
            reach = abs(sd.p_end - 0.5) - sd.inner / sd.scale  # from the end to the core's edge
            out.append(int(np.sum(np.abs(pts - sd.p_end) < reach + 1e-12)))
        return out

    def cap_core(i: int) -> np.ndarray:
        """The round end i's core points on its rung (both sides, the centre once)."""
        return np.unique(np.concatenate([sd.core for sd in sides[i]]))

    n_min = max(extra_sizes.values(), default=0)
    has_cap = False
    for ends, merged in groups:
        for lst in needed(ends, merged):
            n_min = max(n_min, lst.size)
        for i, _j in ends:
            if is_cap[i]:
                has_cap = True
                lst = needed(ends, merged)[0]
                n_min = max(n_min, cap_core(i).size + 2 * max(halves(i, lst)))
    N = n_min
    parity = {cap_core(i).size % 2 for i in range(len(sides)) if is_cap[i]}
    if len(parity) > 1:
        raise ThinPartError("the round ends of the corridor disagree on the points across it")
    if has_cap and N % 2 != parity.pop():  # a round end's rung: its core and twice its rows
        N += 1

    def cap_list(i: int, base: np.ndarray, blocked: list[tuple[float, float]]) -> np.ndarray:
        """The round end i's list: its core, and each half beyond it filled to one count."""
        per = (N - cap_core(i).size) // 2
        parts = [cap_core(i)]
        for sd in sides[i]:
            edge = sd.p_centre + np.sign(sd.p_end - 0.5) * sd.inner / sd.scale
            lo_, hi_ = sorted((edge, sd.p_end))
            mine = base[(base > lo_ + 1e-12) & (base < hi_ + 1e-12)]
            mine = _fill(np.unique(np.r_[edge, mine, sd.p_end]), per + 1, blocked)
            parts.append(mine[np.abs(mine - edge) > 1e-12])
        return np.sort(np.concatenate(parts))

    lists: dict[tuple[int, int], np.ndarray] = {}
    for ends, merged in groups:
        if merged:
            base = needed(ends, merged)[0]
            blocked = blocked_of(ends, merged)[0]
            caps = [i for i, _j in ends if is_cap[i]]
            lst = cap_list(caps[0], base, blocked) if caps else _fill(base, N, blocked)
            for e in ends:
                lists[e] = lst
            continue
        for (i, j), base, blocked in zip(ends, needed(ends, merged), blocked_of(ends, merged)):
            if is_cap[i]:
                lists[(i, j)] = cap_list(i, base, [])
            else:
                lists[(i, j)] = _fill(base, N, blocked)
    plan = []
    for i, ss in enumerate(sides):
        rows = []
        for j, sd in enumerate(ss):
            lst = lists.get((i, 0 if is_cap[i] else j))
            if lst is None:  # a side whose rung is in no run with it at an end (not expected)
                lst = _fill(np.unique(np.r_[0.0, 1.0, sd.core]), N, [rng(sd)])
            if is_cap[i]:  # this half of the round end's rung
                lst = lst[(lst - 0.5) * (sd.p_end - 0.5) > 0]
            f = np.sort(sd.frac(lst))
            f = f[(f > 1e-12) & (f < 1.0 - 1e-12)]
            rows.append(f)
        if rows[0].size != rows[1].size:
            raise ThinPartError("a sector of the corridor gets unequal rows on its two sides")
        plan.append((rows[0], rows[1]))
    return plan


def _run_params(
    lay: CorridorLayout,
    size: float,
    fixed: dict[int, np.ndarray],
    cascades: dict | None = None,
    tilt: bool = False,
) -> list[np.ndarray]:
    """Parameters (0 … 1 from the L end to the R end) of the points on every rung.

    Consecutive rungs joined by a ladder cell form a *run*; the cells of a run are refined
    with the same number of points on every rung. A run without fixed rungs gets uniform
    parameters (segments of about ``size``); a run with one fixed rung (a round end's sector
    puts its points on it) carries that rung's parameters; a run between two fixed rungs with
    the same point count morphs linearly from one to the other along its length, so every
    cell in it is a ruled (not quite bilinear) grid whose angles are checked afterwards."""
    V = lay.vertices
    nr = len(lay.rungs)
    rl = np.abs(V[lay.rungs[:, 1]] - V[lay.rungs[:, 0]])
    budget = [CASCADE_POLISH]
    mid = 0.5 * (V[lay.rungs[:, 1]] + V[lay.rungs[:, 0]])
    params: list[np.ndarray] = [np.zeros(0)] * nr
    for run in _runs(lay):
        ends = [r for r in (run[0], run[-1]) if r in fixed]
        if not ends:
            cnt = max(1, int(np.ceil(rl[run].max() / size)))
            for r in run:
                params[r] = np.linspace(0.0, 1.0, cnt + 1)
            continue
        p0 = fixed[ends[0]]
        p1 = fixed[ends[-1]]
        cnt = max(1, int(np.ceil(rl[run].max() / size)))
        if len(ends) == 1 and cascades is not None and run.size >= 2 and p0.size - 1 > cnt + 1:
            # one fixed end carrying more points than the run needs: transition cascades
            # from it, cell by cell, down to about the run's own count (same parity)
            end = ends[0]
            path = run if end == run[0] else run[::-1]
            target = cnt + 1 + (p0.size - cnt - 1) % 2
            p = p0
            params[end] = p
            for j in range(path.size - 1):
                ra, rb = int(path[j]), int(path[j + 1])
                if p.size > target:
                    cell = _cell_between(lay, min(ra, rb))
                    try:
                        tm, p = _cascade_cell(
                            lay, cell, ra, p, target, _cell_along(lay, cell, size), budget, tilt
                        )
                    except TransitionError:
                        pass  # this cell stays a plain grid
                    else:
                        cascades[cell] = (tm, ra)
                params[rb] = p
            continue
        if p0.size != p1.size and cascades is not None and run.size >= 3 and len(ends) == 2:
            # transition cascades in the cells from the end with more points, each cell taking
            # as many stages as fit, the rest of the run morphing to the other end
            hi, lo = (run[-1], run[0]) if p1.size > p0.size else (run[0], run[-1])
            path = run[::-1] if hi == run[-1] else run
            target = fixed[lo].size
            p = fixed[hi]
            params[hi] = p
            j = 0
            while p.size != target and j < path.size - 2:
                ra, rb = int(path[j]), int(path[j + 1])
                cell = _cell_between(lay, min(ra, rb))
                try:
                    tm, p = _cascade_cell(
                        lay, cell, ra, p, target, _cell_along(lay, cell, size), budget, tilt
                    )
                except TransitionError as exc:
                    raise ThinPartError(
                        f"the corridor cannot change its number of points across near "
                        f"({mid[ra].real:.6g}, {mid[ra].imag:.6g}): {exc.args[0]}"
                    ) from exc
                cascades[cell] = (tm, ra)
                params[rb] = p
                j += 1
            if p.size != target:
                raise ThinPartError(
                    f"the stretch of the corridor between ({mid[run[0]].real:.6g}, "
                    f"{mid[run[0]].imag:.6g}) and ({mid[run[-1]].real:.6g}, "
                    f"{mid[run[-1]].imag:.6g}) cannot change from {fixed[hi].size} to "
                    f"{target} points across (it reached {p.size})"
                )
            sub = path[j:]
            w = _morph_weights(lay, sub, mid, tilt)
            for r, x in zip(sub, w):
                params[r] = (1.0 - x) * p + x * fixed[lo]
            continue
        if p0.size != p1.size:
            raise ThinPartError(
                f"the stretch of the corridor between ({mid[run[0]].real:.6g}, "
                f"{mid[run[0]].imag:.6g}) and ({mid[run[-1]].real:.6g}, {mid[run[-1]].imag:.6g}) "
                f"joins two ends with {p0.size} and {p1.size} points across"
            )
        if run.size == 1 or ends[0] == ends[-1]:
            for r in run:
                params[r] = p0
            continue
        w = _morph_weights(lay, run, mid, tilt)
        if ends[0] != run[0]:
            p0, p1 = p1, p0
        for r, x in zip(run, w):
            params[r] = (1.0 - x) * p0 + x * p1
    return params


def _morph_weights(
    lay: CorridorLayout, path: np.ndarray, mid: np.ndarray, by_slack: bool = False
) -> np.ndarray:
    """How far along a morph (0 at ``path[0]``, 1 at its last rung) each rung of ``path`` is:
    by arc length along the rungs' midpoints, or with ``by_slack`` in proportion to what each
    ladder cell can take: its length times the tangent of the least distance of its corners
    from 60° and 120°. A morph tilts every row line of a cell by about the share of the change
    it carries; in a cell with a corner at 60.5° even a 1° tilt leaves the range, while a
    rectangle takes 30°. Arc length where no cell has room."""
    step = np.abs(np.diff(mid[path]))
    if by_slack and path.size >= 2:
        V = lay.vertices
        room = np.empty(step.size)
        for i in range(step.size):
            cell = _cell_between(lay, int(min(path[i], path[i + 1])))
            k0, k1 = (int(x) for x in lay.cell_rungs[cell])
            (a, b), (a2, b2) = lay.rungs[k0], lay.rungs[k1]
            ang = np.degrees(interior_angles(V[[a, a2, b2, b]]))
            if ang.sum() > 720.0:  # listed clockwise
                ang = 360.0 - ang
            slack = float(np.min(np.minimum(ang - 60.0, 120.0 - ang)))
            room[i] = np.tan(np.radians(min(max(slack, 0.0), 30.0)))
        if (room > 0).any():
            step = step * room
    arc = np.concatenate([[0.0], np.cumsum(step)])
    return arc / arc[-1] if arc[-1] > 0 else np.linspace(0.0, 1.0, arc.size)


def _cell_between(lay: CorridorLayout, r: int) -> int:
    """The ladder cell between rungs r and r + 1."""
    hit = np.flatnonzero((lay.cell_rungs[:, 0] == r) & (lay.cell_rungs[:, 1] == r + 1))
    if hit.size != 1:
        raise ThinPartError("the corridor's layout has no cell between two consecutive rungs")
    return int(hit[0])


def _cell_along(lay: CorridorLayout, cell: int, size: float) -> int:
    """Segments along the walls of a ladder cell for quads of about ``size``."""
    V = lay.vertices
    k0, k1 = (int(x) for x in lay.cell_rungs[cell])
    (a, b), (a2, b2) = lay.rungs[k0], lay.rungs[k1]
    return max(1, int(np.ceil(max(abs(V[a2] - V[a]), abs(V[b2] - V[b])) / size)))


def _cascade_cell(
    lay: CorridorLayout,
    cell: int,
    fine_rung: int,
    p_fine: np.ndarray,
    n_coarse: int,
    n_along: int,
    budget: list[int] | None = None,
    tilt: bool = False,
):
    """As many transition stages as fit (:func:`quadmesh.transition.transition_cascade`) in
    the ladder cell ``cell``, from the ``p_fine`` points of rung ``fine_rung`` (parameters
    from its L end) towards ``n_coarse`` points on the cell's other rung; returns the mesh (in
    its frame: fine side c1 -> c2) and the other rung's parameters (from its L end)."""
    V = lay.vertices
    k0, k1 = (int(x) for x in lay.cell_rungs[cell])
    (a, b), (a2, b2) = lay.rungs[k0], lay.rungs[k1]
    if fine_rung == k1:  # fine side u = 1: the cell as it is
        corners = V[[a, a2, b2, b]]
        tm = transition_cascade(
            corners, p_fine, n_coarse - 1, partial=True, n_along=n_along, budget=budget, tilt=tilt
        )
        return tm, tm.p_coarse
    corners = V[[b2, b, a, a2]]  # turned by 180°: u and p reversed
    tm = transition_cascade(
        corners,
        1.0 - p_fine[::-1],
        n_coarse - 1,
        partial=True,
        n_along=n_along,
        budget=budget,
        tilt=tilt,
    )
    return tm, 1.0 - tm.p_coarse[::-1]


#: Tolerance (degrees) of a corridor mesh's own angle check: a tenth of the final strict check's
#: (:data:`quadmesh.mesh.ANGLE_TOL_DEG`), room for the rounding of a translation. Rows a
#: neighbouring mesh leaves 1e-9 apart on a cut carry exact 120° corners that float64 reads
#: up to 3e-7° off at coordinates around 0.4.
LADDER_ANGLE_TOL = 1e-6


def _check_ladder_angles(pts: np.ndarray, quads: np.ndarray, z: np.ndarray) -> None:
    """Raise ThinPartError if a corridor quad is not convex and counter-clockwise with every
    new angle in [60°, 120°] (morphed runs are ruled, not bilinear, grids: checked here)."""
    c = pts[quads] - pts[quads][:, :1]
    e = np.roll(c, -1, axis=1) - c
    ang = np.degrees(np.angle(-np.roll(e, 1, axis=1) * np.conj(e)))
    ang = np.where(ang < 0, ang + 360.0, ang)
    corner = np.isin(pts[quads], z)
    tol = LADDER_ANGLE_TOL
    bad = ~corner & ((ang < 60.0 - tol) | (ang > 120.0 + tol))
    if bad.any():
        q = int(np.flatnonzero(bad.any(axis=1))[0])
        p = pts[quads[q, 0]]
        raise ThinPartError(
            f"the corridor cells near ({p.real:.6g}, {p.imag:.6g}) cannot change their spacing "
            f"across the corridor fast enough (a quad angle of {ang[bad].min():.1f}°–"
            f"{ang[bad].max():.1f}°)"
        )


def _bilinear(c: np.ndarray, sp: np.ndarray, tp: np.ndarray) -> np.ndarray:
    """Points (len(tp), len(sp)) of the bilinear map of corners c (counter-clockwise)."""
    S, T = sp[None, :], tp[:, None]
    return (1 - S) * (1 - T) * c[0] + S * (1 - T) * c[1] + S * T * c[2] + (1 - S) * T * c[3]


def _refine_ladder(
    lay: CorridorLayout,
    size: float,
    fixed: dict[int, np.ndarray],
    tips: set[int],
    transitions: bool = False,
    tilt: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """Refine a ladder layout: every rung's points generated once (:func:`_run_params`) and
    shared by index by the cells on both sides; ladder cells are ruled grids between their
    two rungs (bilinear when the two carry the same parameters), fan and cap cells bilinear
    grids. Returns points, quads, the cell of every quad and every rung's point indices.
    ``transitions``: runs between fixed rungs of different counts get transition cascades
    (:func:`_run_params`)."""
    V = lay.vertices
    cascades: dict | None = {} if transitions else None
    params = _run_params(lay, size, fixed, cascades, tilt)
    pts: list[np.ndarray] = [V]
    count = V.size

    def new(z: np.ndarray) -> np.ndarray:
        nonlocal count
        z = np.asarray(z, dtype=np.complex128).ravel()
        ids = np.arange(count, count + z.size)
        pts.append(z)
        count += z.size
        return ids

    rung_ids = []
    for (a, b), p in zip(lay.rungs, params):
        inner = new(V[a] + p[1:-1] * (V[b] - V[a]))
        rung_ids.append(np.concatenate([[a], inner, [b]]))
    quads, owner = [], []

    def emit(grid: np.ndarray, c: int) -> None:
        q = np.stack([grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]], axis=-1).reshape(
            -1, 4
        )
        quads.append(q)
        owner.append(np.full(len(q), c))

    def fill(xyz: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Give new ids to the grid nodes still marked −1."""
        free = ids < 0
        ids[free] = new(xyz[free])
        return ids

    def along(u: int, v: int) -> int:
        return max(1, int(np.ceil(abs(V[v] - V[u]) / size)))

    for c, (ring, kind, (k0, k1)) in enumerate(zip(lay.cells, lay.kind, lay.cell_rungs)):
        ring = [int(x) for x in ring]
        if kind == "ladder" and cascades and c in cascades:
            tm, fine_rung = cascades[c]
            fine_ids = rung_ids[fine_rung]
            coarse_ids = rung_ids[k1 if fine_rung == k0 else k0]
            if fine_rung == k0:  # the cascade's frame is the cell turned by 180°
                fine_ids, coarse_ids = fine_ids[::-1], coarse_ids[::-1]
            ids = np.full(tm.points.size, -1, dtype=np.int64)
            ids[tm.fine] = fine_ids
            ids[tm.coarse] = coarse_ids
            quads.append(fill(tm.points, ids)[tm.quads])
            owner.append(np.full(len(tm.quads), c))
            continue
        if kind == "ladder":
            (a, b), (a2, b2) = lay.rungs[k0], lay.rungs[k1]
            m = max(along(a, a2), along(b, b2))
            si = np.linspace(0.0, 1.0, m + 1)[None, :]
            p0, p1 = params[k0][:, None], params[k1][:, None]
            xyz = (1 - si) * (V[a] + p0 * (V[b] - V[a])) + si * (V[a2] + p1 * (V[b2] - V[a2]))
            ids = np.full(xyz.shape, -1, dtype=np.int64)
            ids[:, 0], ids[:, -1] = rung_ids[k0], rung_ids[k1]
            emit(fill(xyz, ids), c)
            continue
        # fan or cap: bilinear; rotate so that a rung is the side c0 -> c1 (s) and, for a fan,
        # the other rung the side c0 -> c3 (t)
        sides = {}
        for k in (k0, k1):
            if k < 0:
                continue
            a, b = (int(x) for x in lay.rungs[k])
            for i in range(4):
                u, v = ring[i], ring[(i + 1) % 4]
                if (u, v) == (a, b):
                    sides[i] = (rung_ids[k], params[k])
                elif (u, v) == (b, a):
                    sides[i] = (rung_ids[k][::-1], 1.0 - params[k][::-1])
        if kind == "fan" and len(sides) == 2:
            i0 = next(i for i in sides if (i + 3) % 4 in sides)  # s side i0, t side i0 - 1
        else:
            i0 = next(iter(sides))
        rot = [ring[(i0 + j) % 4] for j in range(4)]
        s_ids, sp = sides[i0]
        if (i0 + 3) % 4 in sides:
            t_ids, tp = sides[(i0 + 3) % 4]
            t_ids, tp = t_ids[::-1], 1.0 - tp[::-1]  # that side runs c3 -> c0
        else:
            tp = np.linspace(0.0, 1.0, max(along(rot[0], rot[3]), along(rot[1], rot[2])) + 1)
            t_ids = None
        if tips.intersection(rot) and (sp.size > 2 or tp.size > 2):
            raise ThinPartError(
                "a corner below 60° of the corridor at "
                f"({V[sorted(tips.intersection(rot))[0]].real:.6g}, "
                f"{V[sorted(tips.intersection(rot))[0]].imag:.6g}) lies in a cell that must be "
                "refined"
            )
        xyz = _bilinear(V[rot], sp, tp)
        ids = np.full(xyz.shape, -1, dtype=np.int64)
        ids[0, :] = s_ids
        if t_ids is not None:
            ids[:, 0] = t_ids
        ids[0, 0], ids[0, -1], ids[-1, -1], ids[-1, 0] = rot
        emit(fill(xyz, ids), c)
    allp = np.concatenate(pts)
    q = np.concatenate(quads) if quads else np.zeros((0, 4), dtype=np.int64)
    own = np.concatenate(owner) if owner else np.zeros(0, dtype=np.int64)
    return allp, q, own, rung_ids


#: Radius of the Mesh 1 / Mesh 2 core of a sector (round end or bend), relative to its sides.
CAP_CORE = 0.25


@functools.lru_cache(maxsize=64)
def _sector_core(theta_deg: float, n_pts: int):
    """The core of a vertex sector (paper §8, parabolic case: Mesh 1 in m = 1 or 2 subsectors,
    then full Mesh 2 levels) of angle ``theta_deg`` for a crosscut of ``n_pts`` = 2^k + 1
    points: apex 0, side 1 along the positive real axis, outer arc of radius :data:`CAP_CORE`.
    Returns its vertices, quads, outer arc points s_0 … s_{P−1} (by polar angle) and the points
    on side 1 and on side 2 (from the apex outwards). Only full levels: it depends on
    (θ, ``n_pts``) alone."""
    from .mesh import KIND_CONNECTION
    from .parabolic import mesh_vertex_sector

    th = np.radians(theta_deg)
    g = np.exp(1j * th * np.arange(n_pts) / (n_pts - 1))
    sec = mesh_vertex_sector(0j, 1 + 0j, th, g, lam=CAP_CORE, grow=False)
    inner = np.asarray(sec.kind) != KIND_CONNECTION
    q = np.asarray(sec.quads)[inner]
    used = np.unique(q)
    v = np.asarray(sec.vertices)[used]
    q = np.searchsorted(used, q)
    r = np.abs(v)
    ang = np.angle(v)
    ang[ang < -1e-9] += 2 * np.pi
    outer = np.flatnonzero(np.abs(r - r.max()) < 1e-9 * r.max())
    outer = outer[np.argsort(ang[outer])]
    if outer.size != n_pts:
        raise ThinPartError(f"sector core: {outer.size} outer points for {n_pts}")
    tol = 1e-9
    s1 = np.flatnonzero((np.abs(v.imag) < tol) & (v.real > -tol))
    s2 = np.flatnonzero(np.abs((v * np.exp(-1j * th)).imag) < tol)
    s2 = s2[(v[s2] * np.exp(-1j * th)).real > -tol]
    return v, q, outer, s1[np.argsort(r[s1])], s2[np.argsort(r[s2])]


def _sector_points(n_chords: int, least: int = 16) -> int:
    """Crosscut point count 2^k + 1 (at least ``least`` + 1, ``least`` a power of two) of a
    sector whose boundary has ``n_chords``."""
    return 2 ** int(np.ceil(np.log2(max(n_chords, least)))) + 1


#: How far the rows of a sector turn (:func:`_turned_rows`), tried in this order when a
#: layout admits turned sectors: all the way, then part of the way (the rows a corridor's
#: neighbours fix on a bend's sides are not those the layout search checked).
TURN_SHARES = (1.0, 0.6, 0.3)


def _turned_rows(
    apex, low: np.ndarray, gp: np.ndarray, frac: np.ndarray, share: float = 1.0
) -> np.ndarray:
    """Connection rows of a sector that *turn*: on every spoke from the core's outer point
    ``low`` to its crosscut point ``gp`` (arrays (..., P), ``apex`` broadcast against them) the
    cubic Hermite curve that leaves ``low`` along the polar ray from the apex and arrives at
    ``gp`` along the crosscut's outward normal there (the bisector of its two chords; at the
    two sides the polar ray, so the side spokes stay straight, as the rungs they lie on), both
    tangents as long as the spoke; row r crosses spoke j at curve parameter ``frac[..., r, j]``.
    ``share`` scales the curve's departure from the straight spoke (1: the Hermite curve, 0:
    the straight segment). Returns the rows (..., R, P).

    Plain rows (:func:`_sector_mesh` without ``turned``) put every spoke on the straight
    segment low–gp, nearly a polar ray; where the crosscut is far from round about the apex (a
    sharp bend: the rung ends at the foot of the far wall, the wall then turns away) a polar
    ray meets it at 60° or less. Turned spokes meet it at right angles and spread the turn
    over the rows between (the 94° first bend of the pen stroke zigzag_1: connection angles
    [59.7°, 117.2°] plain, [63.3°, 117.2°] with one turned row)."""
    ch = np.diff(gp, axis=-1)
    ch = -1j * ch / np.abs(ch)  # outward normals of the chords (gp runs counter-clockwise)
    d = np.empty_like(gp)
    d[..., 1:-1] = ch[..., :-1] + ch[..., 1:]
    d[..., 0] = gp[..., 0] - low[..., 0]  # the sides: along the rung (a polar ray)
    d[..., -1] = gp[..., -1] - low[..., -1]
    d = d / np.abs(d)
    u0 = low - apex
    u0 = u0 / np.abs(u0)
    span = np.abs(gp - low)
    s = np.asarray(frac, dtype=np.float64)
    s2, s3 = s * s, s * s * s
    low_, gp_ = low[..., None, :], gp[..., None, :]
    t0, t1 = (span * u0)[..., None, :], (span * d)[..., None, :]
    D = gp_ - low_
    rows = low_ + s * D + share * ((s3 - 2 * s2 + s) * (t0 - D) + (s3 - s2) * (t1 - D))
    # the side spokes exactly straight (their rows' ends are points of the rungs)
    lin = low_ + s * (gp_ - low_)
    rows[..., 0] = lin[..., 0]
    rows[..., -1] = lin[..., -1]
    return rows


def _crosscut_points(apex: complex, g: np.ndarray, n_pts: int):
    """The crosscut of a sector about ``apex`` bounded by ``g``: ``g``'s chords split, widest
    polar angle first, into ``n_pts`` − 1 chords. Returns the unit direction of side 1, the
    sector's angle in degrees (rounded to 1e-9, the key of :func:`_sector_core`), the points,
    and for each point but the last its chord j of ``g`` and its index i on that chord."""
    u1 = (g[0] - apex) / abs(g[0] - apex)
    ang = np.unwrap(np.angle((g - apex) / u1))
    theta = round(float(np.degrees(ang[-1])), 9)
    span = np.diff(ang)
    k = np.ones(span.size, dtype=np.int64)
    if k.sum() > n_pts - 1 or np.any(span <= 0):
        raise ThinPartError("a sector of the corridor has more points than it takes")
    while k.sum() < n_pts - 1:
        k[np.argmax(span / k)] += 1
    j = np.repeat(np.arange(g.size - 1), k)
    i = np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)
    gp = np.r_[g[j] + (g[j + 1] - g[j]) * i / k[j], g[-1]]
    return u1, theta, gp, i, j


def _connection_angles(
    apex: complex, g: np.ndarray, n_pts: int, turned: bool = False
) -> np.ndarray:
    """The angles of the connection quads of :func:`_sector_mesh` (no extra rows; with
    ``turned``, one turned row halfway) without building the core: for ``n_pts`` = 2^k + 1
    the core's outer arc is the arc of radius :data:`CAP_CORE` (of the shorter side) through
    evenly spaced polar angles (to rounding, so the angles agree with the built sector's to
    ~1e-12°). What the layout search checks for every candidate round end and bend, thousands
    of times on a long ragged corridor."""
    if (n_pts - 1) & (n_pts - 2):  # not 2^k + 1: the core's arc is not even; build it
        return _sector_mesh(apex, g, n_pts, int(turned), turned=float(turned))[4]
    g = np.asarray(g, dtype=np.complex128)
    if g.size > n_pts:
        raise ThinPartError("a sector of the corridor has more points than it takes")
    a_, ok = _connection_angles_many(
        np.array([apex], dtype=np.complex128), g[None, :], n_pts, turned=turned
    )
    if not ok[0]:
        raise ThinPartError("a sector of the corridor has more points than it takes")
    return a_[0]


def _connection_angles_many(
    apex: np.ndarray, G: np.ndarray, n_pts: int, rows: int = 4096, turned: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_connection_angles` of many sectors at once, number for number: ``apex`` (m,)
    and their crosscuts ``G`` (m, L), all with the same number of points ``n_pts`` = 2^k + 1.
    Returns (angles (m, n_pts − 1, 4), ok (m,)); ``ok`` is False where
    :func:`_crosscut_points` would refuse (polar angles not increasing, too many chords).
    ``turned``: the angles of two rows of connection quads, through one turned row halfway
    (:func:`_turned_rows`), (m, 2·(n_pts − 1), 4).

    The chords are split as :func:`_crosscut_points` splits them — repeatedly the chord with
    the largest polar angle per piece — by the equivalent rule that the pieces' sizes
    span/1, span/2, … taken in decreasing order (ties to the earlier chord) are the first
    ``n_pts − L`` increments."""
    m, L = G.shape
    out = np.zeros((m, (2 if turned else 1) * (n_pts - 1), 4))
    ok = np.zeros(m, dtype=bool)
    extra = n_pts - L
    if (n_pts - 1) & (n_pts - 2) or extra < 0:
        raise ValueError("n_pts must be 2^k + 1 and at least the number of points")
    p = np.arange(n_pts - 1)
    for lo in range(0, m, rows):
        a = apex[lo : lo + rows, None]
        g = G[lo : lo + rows]
        r = g.shape[0]
        u1 = (g[:, :1] - a) / abs(g[:, :1] - a)
        ang = np.unwrap(np.angle((g - a) / u1), axis=1)
        span = np.diff(ang, axis=1)
        good = np.all(span > 0, axis=1)
        k = np.ones((r, L - 1), dtype=np.int64)
        if extra > 0:
            V = span[:, :, None] / np.arange(1, extra + 1)[None, None, :]
            t = -np.partition(-V.reshape(r, -1), extra - 1, axis=1)[:, extra - 1]
            gt = np.sum(V > t[:, None, None], axis=2)
            eq = np.any(V == t[:, None, None], axis=2)
            need = extra - gt.sum(axis=1)
            k += gt + (eq & (np.cumsum(eq, axis=1) <= need[:, None]))
        ck = np.cumsum(k, axis=1)
        # (clipped: a refused row's counts need not add up)
        j = np.minimum(np.sum(ck[:, :, None] <= p[None, None, :], axis=1), L - 2)
        i = p[None, :] - np.take_along_axis(ck - k, j, axis=1)
        kj = np.take_along_axis(k, j, axis=1)
        gj = np.take_along_axis(g, j, axis=1)
        gp = np.empty((r, n_pts), dtype=np.complex128)
        gp[:, :-1] = gj + (np.take_along_axis(g, j + 1, axis=1) - gj) * i / kj
        gp[:, -1] = g[:, -1]
        theta = np.array([round(float(x), 9) for x in np.degrees(ang[:, -1])])
        rho = np.minimum(abs(g[:, 0] - a[:, 0]), abs(g[:, -1] - a[:, 0]))
        arc = np.exp(1j * np.radians(theta)[:, None] * np.arange(n_pts)[None, :] / (n_pts - 1))
        low = a + (rho[:, None] * u1) * (CAP_CORE * arc)
        if turned:
            mid = _turned_rows(a, low, gp, np.full((1, n_pts), 0.5))[:, 0]
            c = np.stack(
                [
                    np.concatenate([low[:, :-1], mid[:, :-1]], axis=1),
                    np.concatenate([mid[:, :-1], gp[:, :-1]], axis=1),
                    np.concatenate([mid[:, 1:], gp[:, 1:]], axis=1),
                    np.concatenate([low[:, 1:], mid[:, 1:]], axis=1),
                ],
                axis=2,
            )
        else:
            c = np.stack([low[:, :-1], gp[:, :-1], gp[:, 1:], low[:, 1:]], axis=2)
        c = c - c[:, :, :1]
        e = np.roll(c, -1, axis=2) - c
        a_ = np.degrees(np.angle(-np.roll(e, 1, axis=2) * np.conj(e)))
        out[lo : lo + rows] = np.where(a_ < 0, a_ + 360.0, a_)
        ok[lo : lo + rows] = good
    return out, ok


def _sector_mesh(
    apex: complex,
    g: np.ndarray,
    n_pts: int,
    rings: int = 0,
    gamma: list[int] | None = None,
    row_fracs: tuple[np.ndarray, np.ndarray] | None = None,
    turned: float = 0.0,
):
    """A vertex sector about ``apex`` bounded by the crosscut ``g`` (from the end of side 1
    round to the end of side 2, counter-clockwise): ``g``'s chords split (widest polar angle
    first; new points lie on the polygon's edges or on rungs) to ``n_pts`` points, the core
    of :func:`_sector_core` scaled to the shorter side, then ``rings`` + 1 rows of connection
    quads to the crosscut (rows at equal fractions of every segment s_k g_k: each row is a
    bilinear subdivision of the previous quads). With ``row_fracs = (f1, f2)`` (increasing
    fractions in (0, 1), one per row) the rows sit at fraction f1 on side 1 and f2 on side 2,
    and in between at the mix of the two by spoke index: every row still crosses every spoke
    once and in order, and the connection angles (returned, checked by the callers) say
    whether the rows turned too fast. ``turned`` > 0: each spoke is the curve of
    :func:`_turned_rows` with that share instead of a straight segment (the rows cross it at
    the same parameters; the sides stay straight). Returns (crosscut points, their coarse ids,
    all points, quads, connection angles, side-1 point indices, side-2 point indices), the
    sides from the apex outwards."""
    u1, theta, gp, i, j = _crosscut_points(apex, g, n_pts)
    ids = None
    if gamma is not None:
        ids = [*np.where(i == 0, np.asarray(gamma)[j], -1).tolist(), int(gamma[-1])]
    tv, tq, outer, s1, s2 = _sector_core(theta, n_pts)
    rho = min(abs(g[0] - apex), abs(g[-1] - apex))
    core = apex + rho * u1 * tv
    nc = core.size
    rows = [outer]  # rows of points from the core's outer arc to the crosscut
    extra = []
    if row_fracs is not None:
        f1, f2 = (np.asarray(f, dtype=np.float64) for f in row_fracs)
        rings = f1.size
        w = np.arange(n_pts) / (n_pts - 1)
        frac = (1.0 - w)[None, :] * f1[:, None] + w[None, :] * f2[:, None]
    else:
        frac = np.repeat((np.arange(1, rings + 1) / (rings + 1))[:, None], n_pts, axis=1)
    bent = _turned_rows(apex, core[outer], gp, frac, turned) if turned and rings else None
    for r in range(1, rings + 1):
        if bent is not None:
            extra.append(bent[r - 1])
        else:
            extra.append(core[outer] + frac[r - 1] * (gp - core[outer]))
        rows.append(nc + (r - 1) * n_pts + np.arange(n_pts))
    gidx = nc + rings * n_pts + np.arange(n_pts)
    rows.append(gidx)
    allp = np.concatenate([core, *extra, gp])
    kk = np.arange(n_pts - 1)
    conn = np.concatenate(
        [
            np.column_stack([lo[kk], hi[kk], hi[kk + 1], lo[kk + 1]])
            for lo, hi in itertools.pairwise(rows)
        ]
    )
    quads = np.concatenate([tq, conn])
    c = allp[conn] - allp[conn][:, :1]
    e = np.roll(c, -1, axis=1) - c
    a_ = np.degrees(np.angle(-np.roll(e, 1, axis=1) * np.conj(e)))
    a_ = np.where(a_ < 0, a_ + 360.0, a_)
    side1 = np.concatenate([s1, [row[0] for row in rows[1:]]])
    side2 = np.concatenate([s2, [row[-1] for row in rows[1:]]])
    # put the crosscut points first (callers glue them by coarse id)
    order = np.r_[gidx, np.setdiff1d(np.arange(allp.size), gidx)]
    inv = np.empty_like(order)
    inv[order] = np.arange(order.size)
    return gp, ids, allp[order], inv[quads], a_, inv[side1], inv[side2]


#: Where the sector of a round bend sits: at the arc's centre C, else moved this share of the
#: distance to the inner corner away from it, towards the arc (the cells' corner at the hub is
#: 180° − τ/2 for a bend of τ at C, out of range below τ = 120°; further out it shrinks, and
#: the arc stays round enough about the hub for its connection quads: a 120° bend of a pen
#: stroke at −0.1: cells [67.6°, 109.1°], connection quads [67.1°, 104.6°]).
ROUND_BEND_SHIFTS = (0.0, -0.05, -0.1, -0.15, -0.2)

#: The two cells of a round bend as indices into (apex, F1, A1, hub, A2, F2).
_ROUND_BEND_CELLS = np.array([[0, 1, 2, 3], [0, 3, 4, 5]])


def _round_bend(
    apex: complex, g: np.ndarray, sector_chords: int = 16, margin: float = CELL_MARGIN
) -> complex | None:
    """The hub of a *round bend* about ``apex`` (the centre of its arc, or a point just beyond
    it, away from ``apex``: :data:`ROUND_BEND_SHIFTS`; where none of these fits, or the arc's
    vertices are not on one circle — a hand-drawn arc, a coarse one — the candidates of
    :func:`_noisy_arc_hubs`), or None where the bend is not one.

    A round bend is a bend sector (two rungs from the reflex corner ``apex`` to the far wall,
    ``g`` the far wall between their ends F1 … F2) whose far wall is a straight piece F1–A1, a
    circular arc A1 … A2 (every vertex of ``g`` but its two ends on one circle, as a pen
    stroke's round join makes it) and a straight piece A2–F2. Seen from the inner corner such a
    wall is far from round (the arc lies up to 1.5 times as far as the feet of the rungs on
    bends of 110°–140°), but about the arc's centre C it is exactly round: the bend is meshed
    as the cells (apex, F1, A1, hub) and (apex, hub, A2, F2), convex with every corner in
    [60° + margin, 120° − margin], and a vertex sector about the hub bounded by the arc
    (:func:`_round_bend_mesh`), whose connection quads are checked as any sector's."""
    if g.size < 5:
        return None
    arc = g[1:-1]
    a, b, c = arc[0], arc[arc.size // 2], arc[-1]
    d = 2.0 * ((b - a).conjugate() * (c - a)).imag
    hubs = []
    if abs(d) > 0:
        # circumcentre of a, b, c
        ba, ca = b - a, c - a
        centre = a - 1j * (abs(ba) ** 2 * ca - abs(ca) ** 2 * ba) / d
        r = abs(a - centre)
        if np.isfinite(r) and np.abs(np.abs(arc - centre) - r).max() <= 1e-6 * r:
            hubs = [centre + shift * (apex - centre) for shift in ROUND_BEND_SHIFTS]
    # three points are always on a circle: a coarse arc may still need a hub off its centre
    for hub in hubs + _noisy_arc_hubs(apex, arc):
        if np.isfinite(hub) and _round_bend_fits(apex, g, hub, sector_chords, margin):
            return complex(hub)
    return None


#: Where the hub of a round bend whose far wall is not one circle (a hand-drawn arc, a coarse
#: one) is looked for, besides about the arc's least-squares circle: these fractions of the
#: way from the inner corner to the arc's middle vertex.
NOISY_HUB_FRACTIONS = tuple(np.linspace(0.3, 0.85, 12).tolist())


def _noisy_arc_hubs(apex: complex, arc: np.ndarray) -> list[complex]:
    """Candidate hubs of a round bend whose arc ``arc`` (its vertices, at least three) is not
    exactly circular: the centre of the least-squares circle through them (Kåsa's fit) moved
    by :data:`ROUND_BEND_SHIFTS` as an exact centre is, then the points
    :data:`NOISY_HUB_FRACTIONS` of the way from ``apex`` to the arc's middle vertex. Each is
    only a candidate: :func:`_round_bend_fits` decides (cells and connection quads in range),
    so a poor fit costs a try, never a bad angle."""
    A = np.column_stack([arc.real, arc.imag, np.ones(arc.size)])
    sol = np.linalg.lstsq(A, np.abs(arc) ** 2, rcond=None)[0]
    centre = 0.5 * complex(sol[0], sol[1])
    mid = arc[arc.size // 2]
    return [centre + shift * (apex - centre) for shift in ROUND_BEND_SHIFTS] + [
        apex + f * (mid - apex) for f in NOISY_HUB_FRACTIONS
    ]


def _round_bend_fits(
    apex: complex, g: np.ndarray, hub: complex, sector_chords: int, margin: float
) -> bool:
    """Whether the cells (apex, F1, A1, hub), (apex, hub, A2, F2) are convex with corners in
    [60° + margin, 120° − margin] and the vertex sector about ``hub`` bounded by the arc
    A1 … A2 has its angle and its connection quads in range."""
    arc = g[1:-1]
    # (a clockwise or reflex corner reads above 180°: convex and counter-clockwise if in range)
    ang = quad_angles_deg(np.array([apex, g[0], g[1], hub, g[-2], g[-1]]), _ROUND_BEND_CELLS)
    if ang.min() < 60.0 + margin or ang.max() > 120.0 - margin:
        return False
    th = float(np.degrees(np.angle((arc[-1] - hub) / (arc[0] - hub))))
    th = th if th > 0 else th + 360.0
    if not (60.0 + margin <= th <= 120.0 - margin or 120.0 + margin <= th <= 240.0 - margin):
        return False
    try:
        a_ = _connection_angles(hub, arc, _sector_points(arc.size - 1, sector_chords))
    except ThinPartError:
        return False
    return bool(a_.min() >= 60.0 + margin and a_.max() <= 120.0 - margin)


def _round_bend_mesh(
    apex: complex,
    g: np.ndarray,
    centre: complex,
    sector_chords: int,
    gamma: list[int] | None = None,
    row_fracs: tuple[np.ndarray, np.ndarray] | None = None,
    size: float | None = None,
):
    """The mesh of a round bend (:func:`_round_bend`, its hub ``centre``) in the form
    :func:`_sector_mesh` returns for a bend sector about ``apex``: a vertex sector about
    ``centre`` bounded by the arc (with ``row_fracs`` its connection rows), and the cells
    (apex, F1, A1, C), (apex, C, A2, F2) as bilinear grids whose lines across continue the
    sector's sides (each rung from the apex carries the points of the sector's side at the
    same fractions) and whose lines along run from the apex–C segment to the straight walls
    F1–A1 and A2–F2, in segments of about the spacing of the sector's side points or, with
    ``size``, of at most ``size`` (as the corridor's runs are cut along; the cells are bilinear
    grids, so any count keeps their angles). Returns (crosscut points:
    F1, the wall points to A1, the arc's points, the wall points from A2, F2; their coarse ids,
    −1 for new points; all points; quads; the angles of every quad but the sector's core;
    side-1 point indices from the apex to F1; side-2 point indices from the apex to F2)."""
    arc = np.asarray(g[1:-1], dtype=np.complex128)
    n_c = _sector_points(arc.size - 1, sector_chords)
    arc_ids = None if gamma is None else list(gamma[1:-1])
    gp_c, ids_c, allp_c, q_c, a_c, s1_c, s2_c = _sector_mesh(
        centre, arc, n_c, 0, arc_ids, row_fracs=row_fracs
    )
    pts = [allp_c]
    count = allp_c.size

    def new(z: np.ndarray) -> np.ndarray:
        nonlocal count
        pts.append(np.asarray(z, dtype=np.complex128))
        ids = count + np.arange(len(z))
        count += len(z)
        return ids

    a1, a2, f1, f2 = arc[0], arc[-1], complex(g[0]), complex(g[-1])
    side_len = max(abs(a1 - centre), abs(a2 - centre))
    n_side = max(len(s1_c), len(s2_c)) - 1
    if size is None:
        m_t = max(1, round(abs(apex - centre) / (side_len / max(n_side, 1))))
    else:
        # not the side points' spacing: their rows may be many (a corridor's neighbours fix
        # them), and each segment here is a line across both cells
        m_t = max(1, math.ceil(abs(apex - centre) / size))
    t = np.arange(1, m_t) / m_t
    mid_rc = new(apex + t * (centre - apex))  # the apex–C segment, shared by both cells
    apex_id = new(np.array([apex]))[0]
    c_id = int(s1_c[0])  # the sector's apex (its sides start there)
    line_rc = np.r_[apex_id, mid_rc, c_id]  # t = 0 … 1
    quads = [q_c]
    angles = [a_c]
    sides = []
    walls = []
    for s_c, far, a_end in ((s1_c, f1, a1), (s2_c, f2, a2)):
        p = np.abs(allp_c[s_c] - centre) / abs(a_end - centre)  # the sector side's fractions
        p[0], p[-1] = 0.0, 1.0
        # grid[t_i, s_j]: t along apex → C (rows 0 … m_t), s across from that line to the wall
        grid = np.empty((m_t + 1, p.size), dtype=np.int64)
        grid[:, 0] = line_rc
        grid[-1, :] = s_c
        tt = np.arange(m_t + 1)[:, None] / m_t
        ss = p[None, :]
        xy = (
            (1 - ss) * (1 - tt) * apex
            + ss * (1 - tt) * far
            + ss * tt * a_end
            + (1 - ss) * tt * centre
        )
        inner = new(xy[:-1, 1:].ravel()).reshape(m_t, p.size - 1)
        grid[:-1, 1:] = inner
        sides.append(grid[0, :])  # the rung: apex … far end
        walls.append(grid[:, -1])  # the wall: far end (t = 0) … A (t = 1)
        q = np.stack([grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]], axis=-1).reshape(
            -1, 4
        )
        quads.append(q)
    allp = np.concatenate(pts)
    conn = np.concatenate(quads[1:])
    # counter-clockwise: flip the cells whose quads come out clockwise
    cz = allp[conn] - allp[conn][:, :1]
    area = 0.5 * np.sum((np.conj(cz) * np.roll(cz, -1, axis=1)).imag, axis=1)
    conn = np.where((area < 0)[:, None], conn[:, ::-1], conn)
    angles.append(quad_angles_deg(allp, conn))
    all_quads = np.concatenate([q_c, conn])
    a_all = np.concatenate([a_c, angles[-1]])
    # the crosscut: F1, wall to A1, the arc (the sector's crosscut), wall from A2, F2
    w1, w2 = walls
    cross = np.r_[w1[:-1], np.arange(gp_c.size), w2[:-1][::-1]]
    cross_ids = None
    if gamma is not None:
        mid = [-1] * (w1.size - 2)
        cross_ids = [int(gamma[0]), *mid, *ids_c, *mid[: w2.size - 2], int(gamma[-1])]
    order = np.r_[cross, np.setdiff1d(np.arange(allp.size), cross)]
    inv = np.empty_like(order)
    inv[order] = np.arange(order.size)
    return (
        allp[cross],
        cross_ids,
        allp[order],
        inv[all_quads],
        a_all,
        inv[sides[0]],
        inv[sides[1]],
    )


def _param_list(t: np.ndarray) -> np.ndarray:
    """Sorted parameters in [0, 1] with 0 and 1 exactly, values within 1e-12 merged."""
    t = np.sort(np.clip(np.r_[0.0, 1.0, t], 0.0, 1.0))
    t = t[np.r_[True, np.diff(t) > 1e-12]]
    t[0] = 0.0
    if t[-1] < 1.0 - 1e-12:
        t = np.r_[t, 1.0]
    t[-1] = 1.0
    return t


def _side_params(pts: np.ndarray, side: np.ndarray, u: complex, v: complex) -> np.ndarray:
    """Parameters along the segment u -> v of the sector points ``side`` lying on it."""
    t = ((pts[side] - u) / (v - u)).real
    return t


def arm_and_body(
    z: np.ndarray, toward: complex | None = None
) -> tuple[CorridorLayout, np.ndarray] | None:
    """Split a polygon that is no corridor as a whole into an *arm* — the stretch from one tip
    that a ladder of straight cells reaches, cut by a rung one and a half widths before the
    ladder gets stuck — and the *body*, the rest (counter-clockwise, the cut as one of its
    edges). None when the whole polygon is a corridor or no arm exists.

    The arm starts at one of the corridor's two tips (:func:`corridor_tips`), or, given
    ``toward`` (a place where the polygon is too crowded for a conformal map: a serif, a spur),
    at the ear tips nearest it (:func:`arm_tips`)."""
    z = np.asarray(z, dtype=np.complex128)
    if toward is None:
        s, e = corridor_tips(z)
        candidates = [(s, e), (e, s)]  # from either tip
    else:
        candidates = arm_tips(z, toward)
    lay = None
    for tips in candidates:
        try:
            lay = ladder_layout(z, tips, partial=True, own_width=True)
        except ThinPartError:
            continue
        if not lay.open_end:
            return None  # the whole polygon is a corridor
        break
    if lay is None:
        return None
    return lay, _body_after(lay, z)


#: Where a bridge's first rung may cross the corridor: fractions of the longest path through
#: the polygon's dual tree, the middle first.
BRIDGE_PLACES = (0.5, 0.4, 0.6, 0.3, 0.7)
#: Depth of a bridge's virtual cap cell, in lengths of its rung: shallow enough that no rung end
#: is sampled on its sides, so the ladder's first rung is the cut itself.
BRIDGE_CAP = 0.05


@dataclass(frozen=True)
class BridgeCut:
    """A straight crosscut across a corridor where a polygon is split for a bridge: from ``a``
    on polygon edge ``ia`` to ``b`` on edge ``ib``; ``first`` runs from ``a`` round the
    boundary to ``b`` (then back along the cut), ``second`` from ``b`` round to ``a``; both
    counter-clockwise, the cut their last edge."""

    a: complex
    b: complex
    ia: int
    ib: int
    first: np.ndarray
    second: np.ndarray


def bridge_cuts(z: np.ndarray, margin: float = CELL_MARGIN) -> list[BridgeCut]:
    """Crosscuts that split the polygon ``z`` across a corridor in its middle (a bridge, the
    corridor between two bodies: a glyph's bowl and its terminal, the two ends of a "C"): at
    the fractions :data:`BRIDGE_PLACES` of the longest path through the dual tree of a
    constrained Delaunay triangulation, from the nearest boundary point through that place
    straight across to the far wall; kept when the segment lies inside the polygon and meets
    both walls at angles in [60° + margin, 120° − margin] on either side."""
    z = np.asarray(z, dtype=np.complex128)
    tri, g, _apex, _ear = _dual_tree(z)
    d0 = dijkstra(g, indices=0)
    t1 = int(np.argmax(d0))
    d1, pred = dijkstra(g, indices=t1, return_predecessors=True)
    path = [int(np.argmax(d1))]
    while path[-1] != t1 and pred[path[-1]] >= 0:
        path.append(int(pred[path[-1]]))
    cen = z[tri].mean(axis=1)[path]
    arc = np.r_[0.0, np.cumsum(np.abs(np.diff(cen)))]
    if arc[-1] <= 0:
        return []
    poly = shapely.Polygon(np.column_stack([z.real, z.imag]))
    lo, hi = 60.0 + margin, 120.0 - margin
    out: list[BridgeCut] = []
    for f in BRIDGE_PLACES:
        p = complex(np.interp(f * arc[-1], arc, cen.real), np.interp(f * arc[-1], arc, cen.imag))
        c = _cut_through(z, p, poly, lo, hi)
        if c is not None:
            out.append(c)
    return out


def _cut_through(
    z: np.ndarray, p: complex, poly, lo: float, hi: float, u: complex | None = None
) -> BridgeCut | None:
    """The straight crosscut of the polygon ``z`` (``poly``: its shapely polygon) through the
    point ``p`` inside it: from the nearest boundary point straight through ``p`` to the far
    wall, or, given a unit direction ``u``, the chord through ``p`` along it. None unless it
    lies inside the polygon, meets both walls at angles in [lo, hi] on either side, joins two
    different edges and keeps clear of their ends."""
    n = z.size
    bnd = poly.exterior
    e = np.roll(z, -1) - z
    diam = float(np.ptp(z.real) + np.ptp(z.imag))

    def first_hit(a: complex, d: complex) -> complex | None:
        far = a + 2.0 * diam * d
        hit = shapely.get_coordinates(
            shapely.intersection(shapely.LineString([(a.real, a.imag), (far.real, far.imag)]), bnd)
        )
        w = hit[:, 0] + 1j * hit[:, 1]
        t = ((w - a) / d).real
        w, t = w[t > 1e-9 * diam], t[t > 1e-9 * diam]
        return None if w.size == 0 else complex(w[np.argmin(t)])

    if u is None:
        q = shapely.get_coordinates(shapely.shortest_line(shapely.Point(p.real, p.imag), bnd))
        a = complex(q[1, 0], q[1, 1])
        if abs(p - a) <= 1e-12 * diam:
            return None
        got = first_hit(a, (p - a) / abs(p - a))
    else:
        a = first_hit(p, -u)
        got = None if a is None else first_hit(p, u)
    if got is None or a is None:
        return None
    b = got
    # the edges holding a and b (the nearest, by distance to the segment)
    te = np.clip((((np.array([a, b])[:, None] - z[None, :]) / e[None, :]).real), 0.0, 1.0)
    dist = np.abs(z[None, :] + te * e[None, :] - np.array([a, b])[:, None])
    ia, ib = (int(k) for k in np.argmin(dist, axis=1))
    if ia == ib:
        return None
    ang = np.degrees(np.angle(np.array([e[ia] / (b - a), e[ib] / (a - b)]))) % 180.0
    if not np.all((ang >= lo) & (ang <= hi)):
        return None
    eps = 1e-9 * (b - a)
    seg = shapely.LineString([((a + eps).real, (a + eps).imag), ((b - eps).real, (b - eps).imag)])
    if not poly.contains_properly(seg):
        return None
    if min(abs(a - z[ia]), abs(a - z[(ia + 1) % n]), abs(b - z[ib]), abs(b - z[(ib + 1) % n])) < (
        1e-6 * abs(b - a)
    ):
        return None  # a cut through a vertex: left to other places
    first = np.array([a, *_walk(z, ia, ib), b])
    second = np.array([b, *_walk(z, ib, ia), a])
    return BridgeCut(a, b, ia, ib, first, second)


#: Where a chain of ladders restarts after a ladder got stuck (:func:`restart_cuts`): distances
#: beyond the stuck rung along the corridor, in widths of that rung.
RESTART_WIDTHS = tuple(np.arange(1.0, 16.0, 0.25).tolist())


@dataclass(frozen=True)
class RestartCut:
    """A crosscut a few widths beyond the cut a ladder stopped at (:func:`restart_cuts`):
    ``knot`` the polygon between the two cuts (both cuts among its edges, the restart cut
    last), ``rest`` the polygon beyond (the restart cut its last edge), both
    counter-clockwise; ``distance`` along the corridor from the stopping cut."""

    distance: float
    cut: BridgeCut
    knot: np.ndarray
    rest: np.ndarray


def restart_cuts(
    z: np.ndarray, distances: np.ndarray | tuple[float, ...], margin: float = CELL_MARGIN
) -> list[RestartCut]:
    """Crosscuts of the polygon ``z`` — a ladder's body, whose last edge ``z[-1] -> z[0]`` is
    the rung the ladder stopped at — across the corridor beyond that rung, at the given
    ``distances`` along the path through the dual tree of a constrained Delaunay triangulation
    from the rung's triangle to the farthest one, each perpendicular to the path there (its
    direction over ±1 width, the rung's length). Kept as :func:`bridge_cuts` keeps its cuts,
    and when neither end lies on the rung itself. A ladder that gets stuck on a ragged stretch
    (a zigzag bank, a notch) restarts from such a cut: the knot between the two cuts is small
    enough for the paper's construction (:func:`quadmesh.routes._mesh_chain`)."""
    z = np.asarray(z, dtype=np.complex128)
    n = z.size
    tri, g, _apex, _ear = _dual_tree(z)
    path = _path_from_edge(tri, g, n - 1, 0)
    if path is None:
        return []
    cen = np.r_[0.5 * (z[0] + z[-1]), z[tri].mean(axis=1)[path]]
    width = abs(z[0] - z[-1])
    places = [(float(d), float(d) * width, width) for d in distances]
    return _cuts_along(z, cen, places, (n - 1, 0), (n - 1,), margin)


def _cuts_along(
    z: np.ndarray,
    cen: np.ndarray,
    places: list[tuple[float, float, float]],
    knot_side: tuple[int, ...],
    keep_off: tuple[int, ...],
    margin: float,
) -> list[RestartCut]:
    """Crosscuts of ``z`` across the path ``cen`` (points along a corridor's middle), one per
    place (label, arc length along the path, width there: the tangent is taken over ±1
    width), each perpendicular to the path, kept as :func:`_cut_through` keeps them and when
    the vertices ``knot_side`` all lie on one side of it (the knot's) and it meets none of the
    edges ``keep_off``."""
    n = z.size
    arc = np.r_[0.0, np.cumsum(np.abs(np.diff(cen)))]
    poly = shapely.Polygon(np.column_stack([z.real, z.imag]))
    lo, hi = 60.0 + margin, 120.0 - margin

    def at(s: float) -> complex:
        return complex(np.interp(s, arc, cen.real), np.interp(s, arc, cen.imag))

    out: list[RestartCut] = []
    for label, s_, width in places:
        if s_ >= arc[-1] - width:
            break
        tangent = at(s_ + width) - at(max(0.0, s_ - width))
        if abs(tangent) == 0.0:
            continue
        c = _cut_through(z, at(s_), poly, lo, hi, 1j * tangent / abs(tangent))
        if c is None or any(k in (c.ia, c.ib) for k in keep_off):
            continue
        first = set((c.ia + 1 + k) % n for k in range((c.ib - c.ia) % n))
        inside = [k in first for k in knot_side]
        if any(inside) and not all(inside):
            continue  # the cut separates the knot's vertices
        knot, rest = (c.first, c.second) if all(inside) else (c.second, c.first)
        out.append(RestartCut(label, c, knot, rest))
    return out


#: Where a tip that no ladder leaves (a hoof, a ragged end of a traced contour) is cut off as a
#: knot (:func:`tip_cuts`): distances from the tip along the corridor, in widths there.
TIP_KNOT_WIDTHS = (2.0, 4.0, 6.0, 8.0, 10.0, 12.0)


def tip_cuts(
    z: np.ndarray,
    tip: int,
    widths: tuple[float, ...] = TIP_KNOT_WIDTHS,
    margin: float = CELL_MARGIN,
) -> list[RestartCut]:
    """Crosscuts of the polygon ``z`` cutting off the end of an arm at the vertex ``tip``
    (a *knot*: the tip's side, holding ``tip`` and its two edges) at the given distances from
    the tip along the path through the dual tree of a constrained Delaunay triangulation from
    the tip's triangle to the farthest one, in local widths (twice the distance from the path
    to the boundary, its largest value up to there, so that a narrowing end does not shrink
    the knot), each perpendicular to the path. For an arm whose own end no ladder starts
    from: the knot small enough for the paper's construction, a ladder leaving its cut."""
    z = np.asarray(z, dtype=np.complex128)
    n = z.size
    tri, g, _apex, _ear = _dual_tree(z)
    path = _path_from_edge(tri, g, (tip - 1) % n, tip)
    if path is None:
        return []
    cen = np.r_[z[tip], z[tri].mean(axis=1)[path]]
    arc = np.r_[0.0, np.cumsum(np.abs(np.diff(cen)))]
    ring = shapely.LinearRing(np.column_stack([z.real, z.imag]))
    clear = 2.0 * shapely.distance(shapely.points(np.column_stack([cen.real, cen.imag])), ring)
    width = np.maximum.accumulate(clear)
    ratio = arc / np.maximum(width, 1e-300)
    places = []
    for w in widths:
        reached = np.flatnonzero(ratio >= w)
        if reached.size:
            k = int(reached[0])
            places.append((float(w), float(arc[k]), float(width[k])))
    tip_edges = ((tip - 1) % n, tip)
    return _cuts_along(z, cen, places, (tip,), tip_edges, margin)


def _path_from_edge(tri: np.ndarray, g, i: int, j: int) -> list[int] | None:
    """The path through the dual tree (:func:`_dual_tree`: triangles ``tri``, tree ``g``)
    from the triangle on the polygon edge between vertices ``i`` and ``j`` to the triangle
    farthest from it, as triangle indices; None when no triangle holds that edge."""
    src = np.flatnonzero(np.isin(tri, [i, j]).sum(axis=1) == 2)
    if src.size == 0:
        return None
    d, pred = dijkstra(g, indices=int(src[0]), return_predecessors=True)
    path = [int(np.argmax(np.where(np.isfinite(d), d, -1.0)))]
    while path[-1] != int(src[0]) and pred[path[-1]] >= 0:
        path.append(int(pred[path[-1]]))
    return path[::-1]


def _walk(z: np.ndarray, i0: int, i1: int) -> list[complex]:
    """The vertices after edge ``i0`` up to the start of edge ``i1``, counter-clockwise."""
    n = z.size
    out = []
    k = (i0 + 1) % n
    for _ in range(n):
        out.append(complex(z[k]))
        if k == i1:
            break
        k = (k + 1) % n
    return out


def capped(part: np.ndarray) -> np.ndarray:
    """``part`` (its last edge, from ``part[-1]`` to ``part[0]``, the cut) with a virtual cap
    cell beyond the cut: a rectangle :data:`BRIDGE_CAP` rung lengths deep, whose far corners are
    appended. The ladder from the first far corner (index ``len(part)``) then starts with the
    cap cell and the cut as its first rung."""
    A, B = part[-1], part[0]
    c = B - A
    out = -1j * c / abs(c)  # outside the part: to the right of A -> B
    d = BRIDGE_CAP * abs(c) * out
    return np.r_[part, A + d, B + d]


def bridge_layout(
    part: np.ndarray, min_rungs: int = 3, own_width: bool = False
) -> tuple[CorridorLayout, np.ndarray, np.ndarray | None] | None:
    """A ladder from the cut of ``part`` (a side of a :class:`BridgeCut`) into it, started from
    a virtual cap (:func:`capped`): the layout (its first rung the cut), the capped polygon, and
    the body where the ladder gets stuck (None when it reaches the far end: the part is a
    corridor), or None when no ladder of at least ``min_rungs`` rungs leaves the cut (two: a
    single cell, as across a straight stem, which only a cell cut along its length can give
    room for its transitions). ``own_width``: as for :func:`ladder_layout` (an arm's ladder
    from a knot, :func:`quadmesh.routes._mesh_knotted_arm`)."""
    q = capped(np.asarray(part, dtype=np.complex128))
    m = q.size
    if not shapely.Polygon(np.column_stack([q.real, q.imag])).is_valid:
        return None
    tips = arm_tips(q, q[m - 2], count=2)
    far = next((e for s, e in tips if s in (m - 2, m - 1)), None)
    if far is None:
        # the cap is no ear of the triangulation (a ragged wall beside the cut reaches its far
        # corners): the end farthest along the dual tree from the cap's own triangle
        tri, g, apex, _ear = _dual_tree(q)
        path = _path_from_edge(tri, g, m - 2, m - 1)
        far = None if path is None else int(apex[path[-1]])
        if far is None or far in (m - 2, m - 1):
            return None
    try:
        lay = ladder_layout(q, (m - 2, far), partial=True, tip_reach=False, own_width=own_width)
    except ThinPartError:
        return None
    cut0 = {int(lay.rungs[0][0]), int(lay.rungs[0][1])}
    if not lay.kind or lay.kind[0] != "cap" or cut0 != {0, m - 3} or len(lay.rungs) < min_rungs:
        return None
    if not lay.open_end:
        return lay, q, None
    body = _bridge_body(lay, q)
    return None if body is None else (lay, q, body)


def _body_after(lay: CorridorLayout, q: np.ndarray) -> np.ndarray:
    """The polygon ``q`` beyond the last rung of the open ladder ``lay``: counter-clockwise,
    from the rung's L end round to its R end (the rung as its last edge)."""
    m = q.size
    a, b = (int(x) for x in lay.rungs[-1])

    def edge(c: int) -> tuple[int, bool]:
        return (c, True) if c < m else (int(lay.edge_of[c]), False)

    ia, _ = edge(a)
    ib, b_vertex = edge(b)
    pts = [lay.vertices[a]]
    k = (ia + 1) % m
    for _ in range(m + 1):
        pts.append(q[k])
        if k == ib:
            break
        k = (k + 1) % m
    if not b_vertex:
        pts.append(lay.vertices[b])
    return np.asarray(pts, dtype=np.complex128)


def _bridge_body(lay: CorridorLayout, q: np.ndarray) -> np.ndarray | None:
    """The far body of a bridge (:func:`_body_after`), or None if it would hold the virtual
    cap (the last two vertices of ``q``)."""
    body = _body_after(lay, q)
    return None if np.any(np.isin(body, q[-2:])) else body


def shorter_bridges(
    lay: CorridorLayout, q: np.ndarray, count: int = 3
) -> list[tuple[CorridorLayout, np.ndarray]]:
    """The open ladder ``lay`` of a bridge ending one, two, … (up to ``count``) rungs earlier,
    each with the body behind its new last rung: other places for the far body's cut, whose
    mesh puts another number of points on it (a bridge's two ends must agree in parity).
    Only ladders without sectors are shortened, and never below three rungs."""
    if lay.sectors or lay.round_caps or not lay.open_end or lay.cell_rungs is None:
        return []
    out = []
    for k in range(len(lay.rungs) - 2, max(len(lay.rungs) - 2 - count, 1), -1):
        keep = lay.cell_rungs[:, 1] <= k
        short = dataclasses.replace(
            lay,
            cells=lay.cells[keep],
            kind=tuple(x for x, kp in zip(lay.kind, keep, strict=True) if kp),
            rungs=lay.rungs[: k + 1],
            cell_rungs=lay.cell_rungs[keep],
        )
        body = _bridge_body(short, q)
        if body is not None:
            out.append((short, body))
    return out


def crowded_place(dec) -> complex | None:
    """Where the decomposition ``dec``'s thick pieces are most crowded for a conformal map:
    the midpoint of the side with the smallest harmonic measure per unit length seen from its
    piece's centre (the deepest place; the smallest measure alone picks short sides anywhere
    along a passage); among sides the estimate cannot tell apart (no flux reaches them), the
    one farthest from the centre. None when no estimate exists."""
    from scipy.spatial import QhullError

    from ..conformal.center import harmonic_measure

    best: tuple[float, float, complex] | None = None
    for piece in dec.thick:
        w = np.asarray(piece.z, dtype=np.complex128)
        try:
            om = harmonic_measure(w, piece.center)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError, QhullError):
            continue
        if om.size != w.size or not np.all(np.isfinite(om)):
            continue
        mid = 0.5 * (w + np.roll(w, -1))
        dens = om / np.maximum(np.abs(np.roll(w, -1) - w), 1e-300)  # per unit length
        k = np.flatnonzero(dens <= dens.min())
        k = int(k[np.argmax(np.abs(mid[k] - piece.center))])
        key = (float(dens[k]), -float(abs(mid[k] - piece.center)), complex(mid[k]))
        if best is None or key[:2] < best[:2]:
            best = key
    return None if best is None else best[2]


def _rung_params(lay: CorridorLayout, k: int, points: np.ndarray) -> np.ndarray:
    """Parameters along rung ``k`` (from its L end to its R end) of the ``points`` lying on it,
    its two ends included (:func:`_param_list`)."""
    a, b = (int(x) for x in lay.rungs[k])
    za, zb = lay.vertices[a], lay.vertices[b]
    t = (np.asarray(points) - za) / (zb - za)
    on = (np.abs(t.imag) < 1e-9) & (t.real > 1e-12) & (t.real < 1 - 1e-12)
    return _param_list(np.sort(t.real[on]))


def mesh_arm(
    lay: CorridorLayout,
    z: np.ndarray,
    body_points: np.ndarray | None,
    *,
    across: int = 4,
    start_points: np.ndarray | None = None,
    split: tuple[int, ...] | None = None,
) -> CorridorMesh:
    """Mesh an arm (:func:`arm_and_body`) whose last rung carries the body mesh's points on
    the cut (``body_points``: every body mesh vertex; those on the cut are found by position),
    so the two meshes share that rung's points. Unused polygon vertices are dropped: the mesh
    holds the arm only.

    A bridge (:func:`bridge_cuts`) starts at a virtual cap cell beyond its first rung: given
    ``start_points`` (the mesh of the part before it), that rung carries their points on it and
    the cap cell's quads are dropped. ``body_points`` None: the ladder reaches the far tip (no
    body after it). ``split``: how many cells a bridge's ladder cells are cut into along their
    length when its whole cells do not join (default :data:`SPLIT_PARTS`; () for none)."""
    if start_points is not None and (
        not lay.kind or lay.kind[0] != "cap" or (body_points is not None and len(lay.rungs) < 2)
    ):
        raise ThinPartError("a bridge needs a cap cell before its first rung")
    try:
        cm = _mesh_fixed(lay, z, across, body_points, start_points)
    except ThinPartError:
        if lay.cell_rungs is None or start_points is None or body_points is None:
            raise
        # a bridge between two meshes: its runs may be too short for the transition cascades
        # and the morph to the far mesh's spacing (a run of one cell has no room for both);
        # its ladder cells cut into 2, then 4 along their length (bilinear sub-cells: their
        # corners stay in [60°, 120°]) give them room — only when the whole cells fail, so
        # that every bridge that joined before keeps its mesh
        for parts in SPLIT_PARTS if split is None else split:
            try:
                cm = _mesh_fixed(
                    split_ladder_cells(lay, z, parts), z, across, body_points, start_points
                )
            except ThinPartError:
                continue
            break
        else:
            raise
    lay = cm.layout
    keep = np.ones(len(cm.quads), dtype=bool)
    if start_points is not None:
        keep = cm.cell != 0  # the virtual cap
    used = np.unique(cm.quads[keep])
    remap = np.full(cm.vertices.size, -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return CorridorMesh(
        cm.vertices[used],
        remap[cm.quads[keep]],
        cm.cell[keep],
        lay,
        None if cm.cut is None else remap[cm.cut],
        remap[cm.start],
    )


def _mesh_fixed(
    lay: CorridorLayout,
    z: np.ndarray,
    across: int,
    body_points: np.ndarray | None,
    start_points: np.ndarray | None,
) -> CorridorMesh:
    """The layout ``lay`` meshed with its last rung on ``body_points`` and its first on
    ``start_points`` (either may be None), with and without transition cascades; the mesh
    with fewer quads of those that close (ThinPartError from the plain one if none does)."""
    fixed = {}
    if body_points is not None:
        fixed[len(lay.rungs) - 1] = _rung_params(lay, len(lay.rungs) - 1, body_points)
    if start_points is not None:
        fixed[0] = _rung_params(lay, 0, start_points)
    try:
        cm_t = _mesh_layout(lay, z, across, fixed, transitions=True)
    except ThinPartError:
        cm_t = None
    try:
        cm = _mesh_layout(lay, z, across, fixed)
    except ThinPartError:
        if cm_t is None:
            # last, cascades whose stages may even out rows only part of the way and runs
            # that morph where their cells have room (their outcome differs: so only where
            # the others fail, and meshes that joined before are kept); also for an arm from
            # a tip, whose round end fixes its first rung
            if body_points is None:
                raise
            try:
                cm_t = _mesh_layout(lay, z, across, fixed, transitions=True, tilt=True)
            except ThinPartError:
                pass
        if cm_t is None:
            raise
        cm = cm_t
    if cm_t is not None and len(cm_t.quads) < len(cm.quads):
        cm = cm_t
    return cm


#: A bridge whose cells do not join its two meshes is tried again with every ladder cell cut
#: into this many cells along its length (STIX "m": a run of one cell between the cut and a
#: bend, 218 points on the cut against 24 on the bend's rung).
SPLIT_PARTS = (2, 4)


def split_ladder_cells(lay: CorridorLayout, z: np.ndarray, parts: int) -> CorridorLayout:
    """``lay`` with every ladder cell cut into ``parts`` cells by rungs at the fractions
    j/parts of its two walls (the bilinear isolines of the cell: every sub-cell's corners are
    angles of its bilinear grid, in [60°, 120°] with the cell's own). Fans, caps and sectors
    are kept; rung and cell indices are renumbered in order (the first cell stays first)."""
    V = np.asarray(lay.vertices, dtype=np.complex128)
    zz = np.asarray(z, dtype=np.complex128)
    e = np.roll(zz, -1) - zz
    verts = [V]
    edge_of = [np.asarray(lay.edge_of)]
    count = V.size

    def add(pts: np.ndarray) -> np.ndarray:
        nonlocal count
        t = np.clip((((pts[:, None] - zz[None, :]) / e[None, :]).real), 0.0, 1.0)
        dist = np.abs(zz[None, :] + t * e[None, :] - pts[:, None])
        verts.append(pts)
        edge_of.append(np.argmin(dist, axis=1))
        ids = np.arange(count, count + pts.size)
        count += pts.size
        return ids

    ladder_after = {}  # old rung k -> the ladder cell from k to k + 1
    for c, (kind, (k0, k1)) in enumerate(zip(lay.kind, lay.cell_rungs)):
        if kind == "ladder" and k1 == k0 + 1:
            (a, b), (a2, b2) = lay.rungs[k0], lay.rungs[k1]
            if a != a2 and b != b2:
                ladder_after[int(k0)] = c
    rungs: list[tuple[int, int]] = []
    new_index = {}
    inner: dict[int, list[tuple[int, int]]] = {}
    frac = np.arange(1, parts) / parts
    for k, (a, b) in enumerate(lay.rungs):
        new_index[k] = len(rungs)
        rungs.append((int(a), int(b)))
        c = ladder_after.get(k)
        if c is not None:
            a2, b2 = lay.rungs[k + 1]
            la = add(V[a] + frac * (V[a2] - V[a]))
            lb = add(V[b] + frac * (V[b2] - V[b]))
            inner[c] = list(zip(la.tolist(), lb.tolist(), strict=True))
            rungs.extend(inner[c])
    cells, kinds, cell_rungs = [], [], []
    for c, (ring, kind, (k0, k1)) in enumerate(zip(lay.cells, lay.kind, lay.cell_rungs)):
        r0 = -1 if k0 < 0 else new_index[int(k0)]
        r1 = -1 if k1 < 0 else new_index[int(k1)]
        if c not in inner:
            cells.append([int(x) for x in ring])
            kinds.append(kind)
            cell_rungs.append((r0, r1))
            continue
        (a, b), (a2, b2) = lay.rungs[k0], lay.rungs[k1]
        chain = [(int(a), int(b)), *inner[c], (int(a2), int(b2))]
        for j in range(parts):
            (u, v), (u2, v2) = chain[j], chain[j + 1]
            swap = {int(a): u, int(b): v, int(a2): u2, int(b2): v2}
            cells.append([swap[int(x)] for x in ring])
            kinds.append("ladder")
            cell_rungs.append((r0 + j, r0 + j + 1))
    return dataclasses.replace(
        lay,
        vertices=np.concatenate(verts),
        cells=np.asarray(cells, dtype=np.int64),
        kind=tuple(kinds),
        rungs=np.asarray(rungs, dtype=np.int64),
        edge_of=np.concatenate(edge_of).astype(np.int64),
        cell_rungs=np.asarray(cell_rungs, dtype=np.int64),
    )


#: A thick piece whose estimated smallest prevertex gap (seen from its centre) is below this is
#: meshed as a corridor when it can be: well above the ~5e-15 the disk construction resolves
#: in extended precision, so that no conformal map is asked to work near its limit.
CORRIDOR_GAP = 1e-10


@dataclass(frozen=True)
class CorridorMesh:
    """The mesh of a corridor: ``vertices`` (complex; the first ``n`` are the polygon's),
    counter-clockwise ``quads``, per quad the ``cell`` of the layout it refines, and the
    ``layout`` itself (cells, rungs, tips). For an arm (``layout.open_end``), ``cut`` holds the
    indices of its points on the rung where it meets the body, from the L wall to the R wall;
    ``start`` those on the first rung (where a bridge meets the part it starts from)."""

    vertices: np.ndarray
    quads: np.ndarray
    cell: np.ndarray
    layout: CorridorLayout
    cut: np.ndarray | None = None
    start: np.ndarray | None = None

    @property
    def kind(self) -> np.ndarray:
        """Region kind per quad (all corridor cells)."""
        return np.zeros(len(self.quads), dtype=np.int8)


def whole_corridor(dec, *, across: int = 4) -> tuple[CorridorMesh | None, str]:
    """The corridor mesh of a polygon that the decomposition leaves as one crowded thick piece.

    Returns ``(mesh, "")`` when the polygon is one thick piece without channels whose estimated
    smallest prevertex gap is below :data:`CORRIDOR_GAP` and a ladder layout exists (with
    straight connection rows, else — on polygons of at most :data:`SECTOR_RETRY_MAX` vertices —
    with rows that turn and round bends: ``mesh_corridor(turn=True)``); otherwise
    ``(None, reason)`` with the reason the corridor route was not taken ("" when the polygon is
    not a crowded single piece).
    """
    from ..decompose import _min_gap

    if len(dec.thick) != 1 or dec.channels:
        return None, ""
    piece = dec.thick[0]
    # how crowded the shape is, seen from its largest inscribed disk (a less crowded centre
    # chosen for its map does not make a corridor any less of one)
    gap = piece.inscribed_gap
    if not np.isfinite(gap):
        gap = piece.min_gap if np.isfinite(piece.min_gap) else _min_gap(piece.z, piece.center)
    if not (gap < CORRIDOR_GAP):
        return None, ""
    z = np.asarray(dec.polygon.z, dtype=np.complex128)
    try:
        return mesh_corridor(z, across=across), ""
    except ThinPartError as exc:
        reason = str(exc.args[0]) if exc.args else type(exc).__name__
    if z.size > SECTOR_RETRY_MAX:
        return None, reason
    # sharp bends (zigzags, walks): sectors whose rows turn, round bends about their arcs;
    # where that fails too the plain reason stands and arms, bridges and knots follow
    try:
        return mesh_corridor(z, across=across, turn=True), ""
    except ThinPartError:
        return None, reason
