"""Quadrilateral meshes: corner angles, areas, quality report and verification.

:class:`QuadMesh` is the output of the pipeline. :meth:`QuadMesh.verify` checks what the main
theorem of the
paper promises (Bishop, "Optimal angle bounds for quadrilateral meshes", Theorem 1.1):

* the quads form a conforming mesh: every interior edge lies in exactly two quads, with
  opposite orientations, and the edges that lie in one quad exactly cover the polygon's sides
  (no hole, no overlap, no hanging vertex);
* every polygon corner is a mesh vertex;
* every quad is positively oriented, strictly convex and non-degenerate;
* the quads' areas add up to the polygon's area;
* no two distinct vertices coincide or lie closer than :data:`COINCIDENT_RTOL` of the
  polygon's diameter;
* every *new* angle lies in [60°, 120°] up to the fixed :data:`ANGLE_TOL_DEG`.  An *original*
  angle is the angle of a polygon corner that the mesh leaves unsplit (the corner lies in a
  single quad); Theorem 1.1 keeps original angles below 60° as they are, so those are exempt.
  A corner split between several quads consists of new angles only.

Besides, it measures (and reports, without refusing anything for it) how small the elements
are against the polygon: every edge's length over the polygon's local feature size at its
midpoint (:func:`local_feature_size`), with the smallest ratio, where it is, the median and
the share of edges below 1/1000 (:data:`SIZE_FLOOR`) and 1/50 (:data:`SIZE_WARN`).

Angles, orientation and convexity are computed per quad relative to the quad's own first
vertex, in float64, from the stored coordinates, with fixed tolerances: the verdict is about
the numbers a reader of the mesh gets, whatever the quad's size or its distance from (0, 0).
A mesh stored relative to an origin (:attr:`quadmesh.result.MeshResult.mesh_origin`) is
verified as stored, against the polygon translated by −origin (``verify(..., origin=...)``).

Everything is vectorised: edges are matched by one sort of integer keys, candidate
coincident vertices and the polygon side of each free edge come from grids (with the k-d tree
and the STRtree for the few that a grid leaves open), so the 937,355 quads of a 1000-vertex
star verify in about 1.3 s on one core, the local feature sizes included.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import MeshVerificationError
from .geometry import angle_rounding_slack_deg, local_signed_areas, quad_signed_areas
from .polygon import Polygon, validate_polygon
from .progress import checkpoint, span

__all__ = [
    "ANGLE_TOL_DEG",
    "COINCIDENT_RTOL",
    "SIZE_FLOOR",
    "SIZE_WARN",
    "QuadMesh",
    "QualityReport",
    "VerificationReport",
    "finalize_mesh",
    "local_feature_size",
    "local_quad_angles_deg",
]

#: Fixed slack (degrees) on the bounds 60° and 120°, the same for every quad whatever its size
#: or position. Corners that are exactly 60° or 120° by construction (Mesh 1 and Mesh 2 of the
#: vertex sectors, the spokes of the inner triangles; typically three quads at 120° around a
#: vertex) cannot be stored exactly: float64 coordinates ~|z| move the angle of a quad with
#: shortest edge ℓ by up to about ε·|z|/ℓ rad, and no choice of rounding helps when the angles
#: around a vertex are all at the bound. On the 29 bundled examples that reads up to 3.7e-6°
#: off (quads down to ~1e-9 of the diameter); 1e-5° accepts all of them, while a polygon with
#: features below ~1e-9 of its diameter is refused.
ANGLE_TOL_DEG = 1e-5

#: Two distinct vertices closer than this fraction of the polygon's diameter are reported.
COINCIDENT_RTOL = 1e-12

ANGLE_MIN = 60.0
ANGLE_MAX = 120.0
_MAX_EXAMPLES = 5
_NEXT = np.array([1, 2, 3, 0])
_PREV = np.array([3, 0, 1, 2])


def _fmt_pt(p: complex, origin: complex = 0j) -> str:
    """Readable point; ``origin`` is added first (points of a mesh stored relative to it).
    Far from (0, 0) (a coordinate of 1e4 or more) with 15 digits, so that points tell apart."""
    p = complex(p) + origin
    if max(abs(p.real), abs(p.imag)) >= 1e4:
        return f"({p.real:.15g}, {p.imag:.15g})"
    return f"({p.real:.6g}, {p.imag:.6g})"


def local_quad_angles_deg(z: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(Q, 4) corner angles in degrees of the quads of complex vertices ``z``, each quad
    taken relative to its own first vertex (subtracted before the edge vectors are formed).

    Corner k is at ``quads[:, k]``; the angle is measured counter-clockwise from the edge to
    the next corner to the edge to the previous one, in [0°, 360°): the interior angle of a
    counter-clockwise quad (a reflex or clockwise corner reads above 180°)."""
    c = z[quads]
    c = c - c[:, :1]
    return _angles_from_edges(c[:, _NEXT] - c)


def _nearest_sides(tree: object, pz: np.ndarray, p: np.ndarray, tol: float) -> np.ndarray:
    """Index of the polygon side (``tree``: shapely STRtree of the sides ``pz[k] → pz[k+1]``)
    nearest to each point of ``p`` (complex).

    One bulk ``dwithin`` query finds the sides within ``tol`` of each point: a point with a
    single one takes it (every other side is farther than ``tol``); a point with several
    takes the nearest of them by the exact point–segment distance; only points farther than
    ``tol`` from every side (free edges off the boundary: a broken mesh) ask the tree for
    their nearest side one by one. Points whose answer is certain from a grid of the sides
    (:func:`_sure_sides`: one side clearly within ``tol``, every other clearly farther) take
    it without the tree; the answer is the same.
    """
    side = _sure_sides(pz, p, tol)
    rest = np.flatnonzero(side < 0)
    if rest.size:
        side[rest] = _nearest_sides_by_tree(tree, pz, p[rest], tol)
    return side


def _sure_sides(pz: np.ndarray, p: np.ndarray, tol: float) -> np.ndarray:
    """The side of the polygon with corners ``pz`` that :func:`_nearest_sides` gives each
    point of ``p``, where it is certain without the tree; -1 elsewhere.

    The sides are put in the cells of a grid (each in the cells its bounding box, grown by
    tol + μ, meets), and each point is measured against the sides of its cell only; μ =
    64 ε (s + ℓ) (s the largest coordinate magnitude, ℓ the longest side) bounds the
    rounding of both this point–segment distance and the tree's (GEOS). A point gets its side
    when exactly one is within tol − μ and no other within tol + μ: then the tree's
    ``dwithin`` query finds that side alone. Points with none, several or a distance within
    μ of tol are left to the tree (-1), as are all points when the grid would be large
    (sides much longer than the typical one)."""
    m, n = p.size, pz.size
    out = np.full(m, -1, dtype=np.intp)
    if m == 0 or n < 3:
        return out
    a = pz
    b = np.roll(pz, -1)
    d = b - a
    length = np.abs(d)
    s = max(float(np.abs(pz).max()), float(np.abs(p).max()))
    mu = 64.0 * np.finfo(float).eps * (s + float(length.max()))
    grow = tol + mu
    lo_x = min(float(pz.real.min()), float(p.real.min())) - 2 * grow
    lo_y = min(float(pz.imag.min()), float(p.imag.min())) - 2 * grow
    span = max(float(pz.real.max()), float(p.real.max())) - lo_x + 2 * grow
    span = max(span, max(float(pz.imag.max()), float(p.imag.max())) - lo_y + 2 * grow)
    cell = max(float(np.median(length)), span / 4096.0)
    if not (np.isfinite(cell) and cell > 0 and np.isfinite(mu)):
        return out
    inv = 1.0 / cell

    def index(v: np.ndarray, lo: float) -> np.ndarray:  # monotone in v
        i = v - lo
        i *= inv
        return np.floor(i).astype(np.int64)

    ny = int(span * inv) + 2
    x0 = index(np.minimum(a.real, b.real) - grow, lo_x)
    x1 = index(np.maximum(a.real, b.real) + grow, lo_x)
    y0 = index(np.minimum(a.imag, b.imag) - grow, lo_y)
    y1 = index(np.maximum(a.imag, b.imag) + grow, lo_y)
    nx_s, ny_s = x1 - x0 + 1, y1 - y0 + 1
    cnt = nx_s * ny_s
    total = int(cnt.sum())
    if total > 8 * (n + m):
        return out
    # the (cell, side) entries, sorted by cell
    sid = np.repeat(np.arange(n), cnt)
    o = np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    key = (x0[sid] + o % nx_s[sid]) * ny + (y0[sid] + o // nx_s[sid])
    srt = np.argsort(key, kind="stable")
    key, sid = key[srt], sid[srt]
    pk = index(p.real, lo_x) * ny + index(p.imag, lo_y)
    first = np.searchsorted(key, pk, side="left")
    last = np.searchsorted(key, pk, side="right")
    pi = np.repeat(np.arange(m), last - first)
    js = sid[_ranges(first, last)]
    # point–segment distances
    w = p[pi] - a[js]
    dj = d[js]
    t = np.clip((w * np.conj(dj)).real / (dj * np.conj(dj)).real, 0.0, 1.0)
    dist = np.abs(w - t * dj)
    within = dist <= tol - mu
    unsure = ~within & (dist <= tol + mu)
    n_within = np.bincount(pi[within], minlength=m)
    n_unsure = np.bincount(pi[unsure], minlength=m)
    ok = within & ((n_within == 1) & (n_unsure == 0))[pi]
    out[pi[ok]] = js[ok]
    return out


def _nearest_sides_by_tree(tree: object, pz: np.ndarray, p: np.ndarray, tol: float) -> np.ndarray:
    """:func:`_nearest_sides` by the tree's queries (see there)."""
    import shapely

    pts = shapely.points(p.real, p.imag)
    ip, js = tree.query(pts, predicate="dwithin", distance=tol)
    cnt = np.bincount(ip, minlength=p.size)
    side = np.full(p.size, -1, dtype=np.intp)
    one = cnt[ip] == 1
    side[ip[one]] = js[one]
    if not one.all():
        pi, sj = ip[~one], js[~one]
        p0 = pz[sj]
        d = np.roll(pz, -1)[sj] - p0
        t = np.clip(((p[pi] - p0) * np.conj(d)).real / (d * np.conj(d)).real, 0.0, 1.0)
        dist = np.abs(p[pi] - p0 - t * d)
        o = np.lexsort((dist, pi))
        first = np.r_[True, pi[o][1:] != pi[o][:-1]]
        side[pi[o][first]] = sj[o][first]
    none = np.flatnonzero(cnt == 0)
    if none.size:
        side[none] = tree.query_nearest(pts[none], all_matches=False)[1]
    return side


def _close_candidates(xy: np.ndarray, r: float) -> np.ndarray:
    """Ascending indices of the points ``xy`` (N, 2) (finite) that may lie within ``r`` of
    another point; every point that does is among them.

    Three square grids of cell h = 3 (2r + 16 ε s) (s the largest coordinate magnitude),
    shifted by 0, h/3 and 2h/3 along both axes: a computed cell index
    ``floor((x − lo) · (1/h) + shift)`` is a non-decreasing function of the coordinate
    (rounded subtraction, product, sum and floor are monotone) whose steps lie within a few
    ε (s + h) of the exact grid lines, so along each axis the steps of the
    three grids are at least h/3 − 8 ε (s + h) > r apart, and two points within r of each
    other (in either coordinate) are separated by the steps of at most one grid in x and of
    one grid in y: they share a cell of at least one grid. A point is kept when its cell (a
    hash of the two indices, equal for equal cells) holds another point in some grid. Three
    sorts of N integers instead of a k-d tree of all the points.
    """
    n = xy.shape[0]
    everything = np.arange(n)
    if n < 2:
        return everything
    # column by column (a reduction over the rows of an (N, 2) array is slow)
    x, y = xy[:, 0], xy[:, 1]
    lo_x, hi_x, lo_y, hi_y = float(x.min()), float(x.max()), float(y.min()), float(y.max())
    s = max(abs(lo_x), abs(hi_x), abs(lo_y), abs(hi_y))
    h = 3.0 * (2.0 * r + 16.0 * np.finfo(float).eps * s)
    span = max(hi_x - lo_x, hi_y - lo_y)
    if not (np.isfinite(h) and h > 0 and (span + h) / h < 2.0**60):
        return everything
    near = np.zeros(n, dtype=bool)
    # coordinates in cells, >= 0 (so that the integer conversion is the floor)
    ux = x - lo_x
    ux *= 1.0 / h
    uy = y - lo_y
    uy *= 1.0 / h
    for shift in (0.0, 1.0 / 3.0, 2.0 / 3.0):
        ix = (ux + shift).astype(np.int64)
        iy = (uy + shift).astype(np.int64)
        ix *= np.int64(-7046029254386353131)  # wraps: equal cells give equal keys
        ix += iy
        key = np.sort(ix)
        shared = key[1:][key[1:] == key[:-1]]
        if shared.size:
            shared = np.unique(shared)
            at = np.minimum(np.searchsorted(shared, ix), shared.size - 1)
            near |= shared[at] == ix
    return np.flatnonzero(near)


def _angles_from_edges(e: np.ndarray) -> np.ndarray:
    """(Q, 4) corner angles in degrees from the (Q, 4) edge vectors (edge k from corner k to
    corner k + 1), as :func:`local_quad_angles_deg` measures them."""
    # column by column into a Fortran-ordered array (its reductions over the four corners
    # of each quad are fast)
    ang = np.empty(e.shape, order="F")
    for k in range(4):
        z = -e[:, k - 1] * np.conj(e[:, k])
        np.arctan2(z.imag, z.real, out=ang[:, k])  # np.angle(z)
    np.add(ang, 2 * np.pi, out=ang, where=ang < 0)
    return np.degrees(ang, out=ang)


#: Size floor of the guarantee's size measurement: an edge shorter than this fraction of the
#: local feature size at its midpoint (:func:`local_feature_size`) is counted in
#: :attr:`QualityReport.share_edge_lfs_below_floor`. A measurement only: :meth:`QuadMesh.verify`
#: does not refuse a mesh for it.
SIZE_FLOOR = 1e-3

#: Second, looser size threshold reported alongside :data:`SIZE_FLOOR` (edges below 1/50 of
#: their local feature size).
SIZE_WARN = 1.0 / 50.0


#: Points per slice of :func:`local_feature_size`'s evaluation (a progress checkpoint each;
#: a slice's temporaries, up to 120 feature pairs per point, stay a few tens of megabytes).
_LFS_CHUNK = 50_000

#: Points per slice of the exact search (deep inside a polygon of many sides a point can
#: have hundreds of sides within its second-nearest corner distance).
_LFS_EXACT_CHUNK = 5_000

#: A quadtree cell of :func:`_lfs_cells` is kept once its half-diagonal is at most this
#: fraction of the local feature size at its centre.
_LFS_CELL_RATIO = 0.35

#: Cells that meet more features than this (deep inside, where many sides are about equally
#: far) and cells of at most :data:`_LFS_FEW` points leave their points to
#: :meth:`_Features.exact`.
_LFS_MAX_FEATURES = 16
_LFS_FEW = 2

#: Quadtree depth: points are binned on a 2**20 × 2**20 grid over their bounding square.
_LFS_BITS = 20


def _sorted_unique(a: np.ndarray) -> np.ndarray:
    """The distinct values of the 1-D integer array ``a`` in ascending order (as
    :func:`numpy.unique`, by one sort)."""
    a = np.sort(a)
    return a[np.r_[True, a[1:] != a[:-1]]] if a.size else a


def _spread_table(bits: int) -> np.ndarray:
    """The integers below 2**bits with their bits moved to the even positions."""
    v = np.arange(1 << bits, dtype=np.int64)
    out = np.zeros_like(v)
    for i in range(bits):
        out |= ((v >> i) & 1) << (2 * i)
    return out


_SPREAD10 = _spread_table(10)


def _morton(ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
    """Z-order codes: the bits of ``ix`` and ``iy`` (int64, non-negative, below
    2**_LFS_BITS = 2**20) interleaved, x in the even bits; ten bits at a time from a table
    (``ix`` and ``iy`` are overwritten)."""

    def spread(v: np.ndarray) -> np.ndarray:
        high = _SPREAD10[v >> 10]
        high <<= 20
        v &= 1023
        high |= _SPREAD10[v]
        return high

    code = spread(iy)
    code <<= 1
    code |= spread(ix)
    return code


def _ranges(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The integers of the ranges [start, end), concatenated."""
    cnt = end - start
    return np.repeat(start - np.cumsum(cnt) + cnt, cnt) + np.arange(int(cnt.sum()))


class _Features:
    """The features of a polygon (feature f < n is corner f, n + j side j) with the searches
    of :func:`local_feature_size`."""

    def __init__(self, poly: Polygon) -> None:
        import shapely
        from scipy.spatial import cKDTree

        v = poly.vertices
        self.n = n = poly.n
        self.p0 = pz = poly.z
        d = np.roll(pz, -1) - pz
        self.corners = cKDTree(v)
        lines = shapely.linestrings(np.stack([v, np.roll(v, -1, axis=0)], axis=1))
        self.sides = shapely.STRtree(lines)
        self.features = shapely.STRtree(np.r_[shapely.points(v), lines])
        # every feature as a segment from (fx, fy) along (fdx, fdy): a corner has length 0
        # (and fdd = 1, so that its parameter is 0 and its distance exactly |x - corner|)
        self.fx = np.r_[pz.real, pz.real]
        self.fy = np.r_[pz.imag, pz.imag]
        self.fdx = np.r_[np.zeros(n), d.real]
        self.fdy = np.r_[np.zeros(n), d.imag]
        self.fdd = np.r_[np.ones(n), d.real * d.real + d.imag * d.imag]
        # absolute slack for the rounding of coordinates and distances
        self.slack = 1e-12 * (float(np.abs(pz).max()) + float(np.abs(d).max()))

    def distance(self, x: np.ndarray, f: np.ndarray) -> np.ndarray:
        """(m, k) distances from the points ``x`` (m,) to the features ``f`` (m, k)."""
        wx = x.real[:, None] - self.fx[f]
        wy = x.imag[:, None] - self.fy[f]
        sx, sy = self.fdx[f], self.fdy[f]
        # the parameter of the nearest point of the side's line, clipped to the side
        t = wx * sx
        t += wy * sy
        t /= self.fdd[f]
        np.clip(t, 0.0, 1.0, out=t)
        sx *= t
        sy *= t
        wx -= sx
        wy -= sy
        return np.hypot(wx, wy, out=wx)

    def non_incident(self, f: np.ndarray) -> np.ndarray:
        """(C, F(F−1)/2) mask of the non-incident pairs among the features of each row of
        ``f`` (C, F), the pairs in :func:`numpy.triu_indices` order."""
        n = self.n
        iu, ju = np.triu_indices(f.shape[1], 1)
        a, b = f[:, iu], f[:, ju]
        ca, cb = a < n, b < n
        gap = (a - b) % n
        sides = ~ca & ~cb & (gap != 0) & (gap != 1) & (gap != n - 1)
        corners = ca & cb & (a != b)
        # a corner and a side: incident when the corner ends the side
        c, s = np.where(ca, a, b), np.where(ca, b, a) - n
        mixed = (ca != cb) & (c != s) & (c != (s + 1) % n)
        return corners | mixed | sides

    def exact(self, x: np.ndarray) -> np.ndarray:
        """Local feature size at the points ``x`` from their three nearest corners and the
        three nearest sides within the second-nearest corner distance r (lfs ≤ r, so farther
        sides do not matter; a :class:`shapely.STRtree` query)."""
        import shapely

        n, m = self.n, x.size
        if m == 0:
            return np.zeros(0)
        xy = np.column_stack([x.real, x.imag])
        dv, iv = self.corners.query(xy, k=3)
        ii, jj = self.sides.query(
            shapely.points(xy[:, 0], xy[:, 1]), predicate="dwithin", distance=dv[:, 1]
        )
        # the two sides at the nearest corner are within r whatever the rounding
        ar = np.arange(m)
        key = _sorted_unique(np.r_[ii * n + jj, ar * n + iv[:, 0], ar * n + (iv[:, 0] - 1) % n])
        ii, jj = key // n, key % n
        dist = self.distance(x[ii], (n + jj)[:, None])[:, 0]
        order = np.lexsort((dist, ii))
        ii, jj, dist = ii[order], jj[order], dist[order]
        rank = np.arange(ii.size) - np.searchsorted(ii, ar)[ii]
        top = rank < 3
        sid = np.full((m, 3), -1, dtype=np.int64)
        sd = np.full((m, 3), np.inf)
        sid[ii[top], rank[top]] = jj[top]
        sd[ii[top], rank[top]] = dist[top]
        return _lfs_from_features(x, self.p0, dv, iv, sid, sd)


def _lfs_from_features(
    x: np.ndarray,
    pz: np.ndarray,
    dv: np.ndarray,
    iv: np.ndarray,
    sid: np.ndarray,
    sd: np.ndarray,
) -> np.ndarray:
    """Local feature size from the three nearest corners (distances ``dv``, indices ``iv``)
    and the three nearest sides (``sid``, ``sd``, ascending; a slot with ``sd`` = inf is
    empty) of each point ``x`` of the polygon with corners ``pz``.

    The smallest disk about x meeting two non-incident features meets them at its boundary;
    a disk meeting no non-incident pair meets at most one corner and two sides, so the pairs
    that matter are: the two nearest corners; a corner and the nearest side s1 when the
    corner is not an end of s1; two non-adjacent sides among the three nearest; an end e of
    s1 and the nearest of the three sides that does not end at e (every other corner-side
    pair is dominated by one of these)."""
    n = pz.size
    ok = np.isfinite(sd)

    def adjacent(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = (a - b) % n
        return (k == 0) | (k == 1) | (k == n - 1)

    s1 = sid[:, 0]  # the nearest side (the first slot is never empty)
    # (corner v, s1) with v not an end of s1: max(|x - v|, d1) = |x - v|
    ends1 = (iv == s1[:, None]) | (iv == ((s1 + 1) % n)[:, None])
    out = np.minimum(dv[:, 1], np.where(ends1, np.inf, dv).min(axis=1))
    # side-side pairs: the best is among the three nearest sides
    for a, b in ((0, 1), (0, 2), (1, 2)):
        pair = ok[:, a] & ok[:, b] & ~adjacent(sid[:, a], sid[:, b])
        out = np.where(pair, np.minimum(out, sd[:, b]), out)
    # (corner e at an end of s1, side not ending at e): the nearest such side is among the
    # three nearest sides; other corner-side pairs are dominated by the ones above
    for e in (s1, (s1 + 1) % n):
        on_e = (sid == e[:, None]) | (sid == ((e - 1) % n)[:, None])
        t = np.where(ok & ~on_e, sd, np.inf).min(axis=1)
        out = np.minimum(out, np.maximum(np.abs(x - pz[e]), t))
    return out


def _lfs_cells(
    feat: _Features, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A quadtree over the points ``x`` whose cells are small against the local feature size.

    The points are sorted by their Z-order code on a grid over their bounding square, so that
    every quadtree cell holds a contiguous range of them. From the whole square down, a cell
    is kept when its half-diagonal ρ is at most :data:`_LFS_CELL_RATIO` times lfs at its
    centre c (:meth:`_Features.exact`), and split otherwise; a cell of at most
    :data:`_LFS_FEW` points is set aside for :meth:`_Features.exact`. A kept cell's
    ``reach`` is ``lfs(c) + 2ρ`` (and a little slack): for a point x of the cell,
    ``lfs(x) ≤ lfs(c) + ρ`` (lfs is 1-Lipschitz) and every feature within ``reach − ρ`` of x
    lies within ``reach`` of c.

    Returns:
        ``(order, start, end, centre, reach, loose)``: the sort order of the points, the
        kept cells as ranges [start, end) of sorted positions with their centres and reaches,
        and the sorted positions left to the exact search.
    """
    lo_x, lo_y = float(x.real.min()), float(x.imag.min())
    size = max(float(x.real.max()) - lo_x, float(x.imag.max()) - lo_y)
    if not size > 0:
        size = 1.0
    g = 1 << _LFS_BITS

    def grid(c: np.ndarray, lo: float) -> np.ndarray:
        c = c - lo
        c *= g / size
        i = c.astype(np.int64)
        return np.clip(i, 0, g - 1, out=i)

    code = _morton(grid(x.real, lo_x), grid(x.imag, lo_y))
    ibits = max(int(x.size - 1).bit_length(), 1)
    if 2 * _LFS_BITS + ibits <= 63:
        # a plain sort of (code, index) packed in one integer: the stable argsort's order
        code <<= ibits
        code |= np.arange(x.size, dtype=np.int64)
        code.sort()
        order = code & ((1 << ibits) - 1)
        code >>= ibits
    else:
        order = np.argsort(code, kind="stable")
        code = code[order]
    slack = 2 * feat.slack + 1e-12 * (abs(lo_x) + abs(lo_y) + size)
    # the cells to split: Z-order prefix and integer position at the current level
    pre = np.zeros(1, dtype=np.int64)
    cx = np.zeros(1, dtype=np.int64)
    cy = np.zeros(1, dtype=np.int64)
    quarter = np.arange(4)
    kept, loose = [], []
    for level in range(1, _LFS_BITS + 1):
        checkpoint(level / _LFS_BITS)
        shift = 2 * (_LFS_BITS - level)
        kids = (4 * pre[:, None] + quarter).ravel()
        lo = np.searchsorted(code, kids << shift)
        hi = np.searchsorted(code, (kids + 1) << shift)
        cx = (2 * cx[:, None] + (quarter & 1)).ravel()
        cy = (2 * cy[:, None] + (quarter >> 1)).ravel()
        few = hi - lo <= _LFS_FEW if level < _LFS_BITS else hi > lo
        loose.append(_ranges(lo[few], hi[few]))
        split = (hi - lo > _LFS_FEW) & ~few
        pre, lo, hi, cx, cy = kids[split], lo[split], hi[split], cx[split], cy[split]
        if pre.size == 0:
            break
        side = size / (1 << level)
        cen = (lo_x + (cx + 0.5) * side) + 1j * (lo_y + (cy + 0.5) * side)
        rho = 0.5 * np.sqrt(2.0) * side
        # lfs(c) <= the distance to the second-nearest corner (exact() takes the minimum
        # with it), so a cell with rho above the ratio times that distance is split without
        # computing lfs(c)
        lfs = np.full(cen.size, np.inf)
        near2 = feat.corners.query(np.column_stack([cen.real, cen.imag]), k=3)[0][:, 1]
        maybe = np.flatnonzero(rho <= _LFS_CELL_RATIO * near2)
        lfs[maybe] = feat.exact(cen[maybe])
        ok = np.zeros(cen.size, dtype=bool)
        ok[maybe] = rho <= _LFS_CELL_RATIO * lfs[maybe]
        kept.append((lo[ok], hi[ok], cen[ok], (lfs[ok] + 2 * rho) * (1 + 1e-9) + slack))
        pre, cx, cy = pre[~ok], cx[~ok], cy[~ok]
    if kept:
        start, end, cen, reach = (np.concatenate(a) for a in zip(*kept, strict=True))
    else:
        start = end = np.zeros(0, dtype=np.int64)
        cen, reach = np.zeros(0, dtype=np.complex128), np.zeros(0)
    return order, start, end, cen, reach, np.concatenate(loose)


def local_feature_size(polygon: object, points: np.ndarray) -> np.ndarray:
    """Local feature size of ``polygon`` at each of ``points`` (complex, or (N, 2) reals).

    The features of the polygon are its corners and its sides. Two features are *incident*
    when one contains the other (a corner and a side ending there) or they share a corner
    (consecutive sides); a feature is incident to itself. ``lfs(x)`` is the radius of the
    smallest closed disk centred at ``x`` that meets two non-incident features (Ruppert's
    local feature size of the polygon's boundary): at a point near a side it is about the
    distance to the nearest other part of the boundary that does not touch that side, in a
    corridor it is about the width, and near a corner it is at most the shorter of the two
    sides there (two distinct corners are never incident). It is positive at every point of
    the closed polygon, including its corners and sides, and 1-Lipschitz.

    Computed exactly (up to float64 rounding of the distances). The points are put in the
    cells of a quadtree that are small against lfs (:func:`_lfs_cells`); every feature within
    lfs(x) of a point x of a cell is among the features that one :class:`shapely.STRtree`
    query finds within the cell's reach of its centre, so lfs(x) is the smallest
    ``max(|x − f|, |x − g|)`` over the non-incident pairs (f, g) of those few features
    (typically 5 to 7). Points of cells that meet many features (deep inside, where many
    sides are about equally far) or that hold one or two points take the exact search of
    :meth:`_Features.exact`: the three nearest corners and the three nearest sides within
    the second-nearest corner distance (a disk that meets no non-incident pair meets at most
    one corner and two sides). Vectorised, the cells grouped by their features' incidence
    pattern (:func:`_lfs_pattern`): about 0.3 s per million points on one core.

    Args:
        polygon: anything :func:`~quadmesh.polygon.validate_polygon` accepts.
        points: query points.

    Returns:
        (N,) float64 array of local feature sizes.
    """
    import shapely

    poly = polygon if isinstance(polygon, Polygon) else validate_polygon(polygon)
    pts = np.asarray(points)
    if np.iscomplexobj(pts):
        x = np.asarray(pts, dtype=np.complex128).ravel()
    else:
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        x = pts[:, 0] + 1j * pts[:, 1]
    m = x.size
    if m == 0:
        return np.zeros(0)
    finite = np.isfinite(x)
    if not finite.all():  # nan where a point is not finite
        out = np.full(m, np.nan)
        out[finite] = local_feature_size(poly, x[finite])
        return out
    feat = _Features(poly)
    with span(0.0, 0.3):
        order, start, end, cen, reach, loose = _lfs_cells(feat, x)
    xs = x[order]
    out = np.empty(m)
    with span(0.3, 0.4):
        cell, f = feat.features.query(
            shapely.points(cen.real, cen.imag), predicate="dwithin", distance=reach
        )
    nf = np.bincount(cell, minlength=start.size)
    over = nf > _LFS_MAX_FEATURES
    exact = np.r_[loose, _ranges(start[over], end[over])]
    done = 0
    for i in range(0, exact.size, _LFS_EXACT_CHUNK):
        j = exact[i : i + _LFS_EXACT_CHUNK]
        out[order[j]] = feat.exact(xs[j])
        done += j.size
        checkpoint(0.4 + 0.6 * done / m)
    # the features of every cell in ascending order of index (corners first), a row per cell
    # for each number of features; the cells of one incidence pattern are evaluated together
    nf2 = 2 * feat.n
    key = np.sort(cell * nf2 + f)
    cell, f = key // nf2, key % nf2
    rank = np.arange(cell.size) - np.searchsorted(cell, np.arange(start.size))[cell]
    for k in np.unique(nf[~over]):
        cl = np.flatnonzero(nf == k)
        table = np.empty((start.size, k), dtype=np.int64)
        sel = nf[cell] == k
        table[cell[sel], rank[sel]] = f[sel]
        table = table[cl]
        n_corners = np.count_nonzero(table < feat.n, axis=1)
        pattern = np.column_stack([n_corners, feat.non_incident(table)])
        for rows in _equal_rows(pattern):
            done = _lfs_pattern(
                feat,
                xs,
                order,
                out,
                start[cl[rows]],
                end[cl[rows]],
                table[rows],
                pattern[rows[0]],
                done,
                m,
            )
    return out


def _equal_rows(a: np.ndarray) -> list[np.ndarray]:
    """The groups of equal rows of the 2-D array ``a`` of small non-negative integers (below
    256), each as the ascending indices of its rows; groups in lexicographic order."""
    if a.shape[0] == 0:
        return []
    b = np.zeros((a.shape[0], -(-a.shape[1] // 8) * 8), dtype=np.uint8)
    b[:, : a.shape[1]] = a
    w = b.view(np.uint64)  # 8 entries per word: equal words iff equal entries
    o = np.lexsort(w.T[::-1])
    ws = w[o]
    cut = np.flatnonzero((ws[1:] != ws[:-1]).any(axis=1)) + 1
    return [np.sort(g) for g in np.split(o, cut)]


def _lfs_pattern(
    feat: _Features,
    xs: np.ndarray,
    order: np.ndarray,
    out: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    table: np.ndarray,
    pattern: np.ndarray,
    done: int,
    m: int,
) -> int:
    """Local feature size at the points of quadtree cells that share an incidence pattern.

    The cells (sorted positions [start, end) of the points ``xs``) have the features of the
    rows of ``table`` (C, k), in ascending order of index; ``pattern`` is the number c of
    corners among them (the first c columns) followed by the :meth:`_Features.non_incident`
    mask of the pairs, the same for every row. For each point x the result
    ``min over non-incident pairs (f, g) of max(|x − f|, |x − g|)`` is written to
    ``out[order[positions]]``: per feature f the minimum of |x − g| over the later features
    g not incident to f, its maximum with |x − f|, and the minimum of those (a rearrangement
    of exact minima and maxima of the same distances, so the same value as over all pairs).
    The distances are :meth:`_Features.distance`'s, feature by feature; a corner's is
    ``hypot`` of the coordinate differences, which is what that formula gives for a
    zero-length segment. Returns ``done`` plus the number of points.
    """
    k = table.shape[1]
    nc = int(pattern[0])
    iu, ju = np.triu_indices(k, 1)
    ni = pattern[1:].astype(bool)
    later = [ju[ni & (iu == i)] for i in range(k)]
    used = np.unique(np.r_[iu[ni], ju[ni]])
    # per-cell feature data, one contiguous array per column
    fx, fy = feat.fx[table], feat.fy[table]
    fdx, fdy, fdd = feat.fdx[table], feat.fdy[table], feat.fdd[table]
    cols = {
        j: (fx[:, j].copy(), fy[:, j].copy(), fdx[:, j].copy(), fdy[:, j].copy(), fdd[:, j].copy())
        for j in used
    }
    pos = _ranges(start, end)
    row = np.repeat(np.arange(start.size), end - start)
    for i in range(0, pos.size, _LFS_CHUNK):
        p, r = pos[i : i + _LFS_CHUNK], row[i : i + _LFS_CHUNK]
        x = xs[p]
        xr, xi = x.real.copy(), x.imag.copy()
        d: dict[int, np.ndarray] = {}
        for j in used:
            cx, cy, cdx, cdy, cdd = cols[j]
            wx = xr - cx[r]
            wy = xi - cy[r]
            if j >= nc:  # a side: the nearest point of the segment, as _Features.distance
                sx, sy = cdx[r], cdy[r]
                t = wx * sx
                t += wy * sy
                t /= cdd[r]
                np.clip(t, 0.0, 1.0, out=t)
                sx *= t
                sy *= t
                wx -= sx
                wy -= sy
            d[j] = np.hypot(wx, wy, out=wx)
        best = np.full(p.size, np.inf)
        for f, gs in enumerate(later):
            if gs.size == 0:
                continue
            near = d[gs[0]].copy()
            for g in gs[1:]:
                np.minimum(near, d[g], out=near)
            np.maximum(near, d[f], out=near)
            np.minimum(best, near, out=best)
        out[order[p]] = best
        done += p.size
        checkpoint(0.4 + 0.6 * done / m)
    return done


@dataclass(frozen=True, eq=False)
class QualityReport:
    """Angle and size statistics of a :class:`QuadMesh`.

    Attributes:
        n_quads, n_vertices: sizes of the mesh.
        n_polygon_vertices: n of the polygon, when one was given (else None).
        quads_per_vertex: n_quads / n_polygon_vertices (the O(n) constant of Theorem 1.1).
        min_angle, max_angle: extreme *new* corner angles in degrees.
        min_original_angle: smallest original (unsplit polygon corner, below 60°) angle, or None.
        n_original: number of exempt original angles.
        histogram: counts of new angles per 5° bin of [0°, 180°] (36 bins).
        bin_edges: the 37 bin edges in degrees.
        n_angles_outside: number of new angles outside [60°, 120°].
        n_quads_outside: number of quads with a new angle outside [60°, 120°].
        worst_quads: indices of the (up to 10) quads whose new angles are farthest from 90°.
        worst_angles: their four corner angles in degrees, shape (k, 4).
        min_area, max_area: extreme quad areas.

    Size against the polygon's local feature size (:func:`local_feature_size`), when the
    report was made against a polygon (else None). For every mesh edge the ratio is its
    length over the local feature size of the polygon at its midpoint: a ratio far below 1
    is an element much smaller than any feature of the polygon there. Measured and reported
    only; it does not decide whether a mesh is valid.

        n_edges: number of distinct mesh edges measured.
        min_edge_lfs: smallest edge length / local feature size ratio.
        min_edge_lfs_at: (x, y) midpoint of that edge, in the polygon's coordinates (the mesh
            origin added for a mesh stored relative to one).
        min_edge_lfs_edge: its two mesh vertex indices.
        min_edge_lfs_length, min_edge_lfs_size: its length and the local feature size there.
        median_edge_lfs: median ratio over all edges.
        share_below_floor: fraction of the edges whose ratio is below :data:`SIZE_FLOOR`
            (1/1000).
        share_below_warn: fraction of the edges whose ratio is below :data:`SIZE_WARN` (1/50).
    """

    n_quads: int
    n_vertices: int
    n_polygon_vertices: int | None
    quads_per_vertex: float | None
    min_angle: float
    max_angle: float
    min_original_angle: float | None
    n_original: int
    histogram: np.ndarray
    bin_edges: np.ndarray
    n_angles_outside: int
    n_quads_outside: int
    worst_quads: np.ndarray
    worst_angles: np.ndarray
    min_area: float
    max_area: float
    n_edges: int | None = None
    min_edge_lfs: float | None = None
    min_edge_lfs_at: tuple[float, float] | None = None
    min_edge_lfs_edge: tuple[int, int] | None = None
    min_edge_lfs_length: float | None = None
    min_edge_lfs_size: float | None = None
    median_edge_lfs: float | None = None
    share_below_floor: float | None = None
    share_below_warn: float | None = None

    @property
    def angles_ok(self) -> bool:
        """True when every new angle lies in [60°, 120°]."""
        return self.n_angles_outside == 0

    @property
    def size_floor_met(self) -> bool | None:
        """True when every edge is at least :data:`SIZE_FLOOR` (1/1000) of the local feature
        size at its midpoint; None when the sizes were not measured (no polygon)."""
        if self.min_edge_lfs is None:
            return None
        return self.min_edge_lfs >= SIZE_FLOOR

    def as_dict(self) -> dict:
        """Plain-Python (JSON-ready) version of the report."""
        return {
            "n_quads": self.n_quads,
            "n_vertices": self.n_vertices,
            "n_polygon_vertices": self.n_polygon_vertices,
            "quads_per_vertex": self.quads_per_vertex,
            "min_angle": self.min_angle,
            "max_angle": self.max_angle,
            "min_original_angle": self.min_original_angle,
            "n_original": self.n_original,
            "histogram": self.histogram.tolist(),
            "bin_edges": self.bin_edges.tolist(),
            "n_angles_outside": self.n_angles_outside,
            "n_quads_outside": self.n_quads_outside,
            "worst_quads": self.worst_quads.tolist(),
            "worst_angles": self.worst_angles.tolist(),
            "min_area": self.min_area,
            "max_area": self.max_area,
            "n_edges": self.n_edges,
            "min_edge_lfs": self.min_edge_lfs,
            "min_edge_lfs_at": None if self.min_edge_lfs_at is None else list(self.min_edge_lfs_at),
            "min_edge_lfs_edge": (
                None if self.min_edge_lfs_edge is None else list(self.min_edge_lfs_edge)
            ),
            "min_edge_lfs_length": self.min_edge_lfs_length,
            "min_edge_lfs_size": self.min_edge_lfs_size,
            "median_edge_lfs": self.median_edge_lfs,
            "share_below_floor": self.share_below_floor,
            "share_below_warn": self.share_below_warn,
        }

    def size_lines(self) -> list[str]:
        """Readable lines on edge length / local feature size (empty when not measured)."""
        if self.min_edge_lfs is None or self.min_edge_lfs_at is None:
            return []
        x, y = self.min_edge_lfs_at
        at = _fmt_pt(complex(x, y))
        verdict = "met" if self.size_floor_met else "NOT met"
        return [
            f"edge / local feature size: min {self.min_edge_lfs:.3g} at {at} (edge "
            f"{self.min_edge_lfs_edge[0]}–{self.min_edge_lfs_edge[1]}, length "
            f"{self.min_edge_lfs_length:.3g}, local feature size {self.min_edge_lfs_size:.3g}); "
            f"median {self.median_edge_lfs:.3g}",
            f"  edges below 1/1000 of the local feature size: "
            f"{100 * self.share_below_floor:.3g} % of {self.n_edges} (size floor {verdict}); "
            f"below 1/50: {100 * self.share_below_warn:.3g} %",
        ]

    def summary(self) -> str:
        """A few readable lines: counts, angle range, sizes against the polygon's local
        feature size, histogram of the occupied bins."""
        lines = [f"quads: {self.n_quads}   vertices: {self.n_vertices}"]
        if self.n_polygon_vertices is not None:
            lines[0] += (
                f"   polygon vertices: {self.n_polygon_vertices}"
                f"   quads per polygon vertex: {self.quads_per_vertex:.2f}"
            )
        lines.append(
            f"new angles: min {self.min_angle:.4f}°  max {self.max_angle:.4f}°  "
            f"outside [60°, 120°]: {self.n_angles_outside} (in {self.n_quads_outside} quads)"
        )
        if self.n_original:
            lines.append(
                f"original polygon angles below 60° left unsplit: {self.n_original} "
                f"(smallest {self.min_original_angle:.4f}°)"
            )
        lines.append(f"quad areas: min {self.min_area:.4g}  max {self.max_area:.4g}")
        lines += self.size_lines()
        occupied = np.flatnonzero(self.histogram)
        if occupied.size:
            peak = int(self.histogram.max())
            lines.append("angle histogram (5° bins):")
            for b in occupied:
                bar = "#" * max(1, round(40 * int(self.histogram[b]) / peak))
                lines.append(
                    f"  {self.bin_edges[b]:5.0f}–{self.bin_edges[b + 1]:3.0f}°"
                    f" {int(self.histogram[b]):9d} {bar}"
                )
        return "\n".join(lines)


@dataclass(frozen=True, eq=False)
class VerificationReport:
    """Outcome of :meth:`QuadMesh.verify`.

    Attributes:
        ok: True when ``problems`` is empty.
        problems: readable descriptions of everything that is wrong.
        warnings: harmless oddities (unused vertices).
        quality: the :class:`QualityReport` of the mesh against the polygon.
        n_interior_edges, n_boundary_edges: edge counts.
        area_error: relative difference between the quads' total area and the polygon's.
    """

    ok: bool
    problems: tuple[str, ...]
    warnings: tuple[str, ...]
    quality: QualityReport
    n_interior_edges: int
    n_boundary_edges: int
    area_error: float

    def summary(self) -> str:
        """Readable report: verdict, problems, warnings and the quality summary."""
        head = "mesh OK" if self.ok else f"mesh INVALID ({len(self.problems)} problems)"
        lines = [head]
        lines += [f"  problem: {p}" for p in self.problems]
        lines += [f"  warning: {w}" for w in self.warnings]
        lines.append(
            f"edges: {self.n_interior_edges} interior, {self.n_boundary_edges} boundary; "
            f"relative area error {self.area_error:.2e}"
        )
        lines.append(self.quality.summary())
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


@dataclass(frozen=True, eq=False)
class QuadMesh:
    """A quadrilateral mesh.

    Attributes:
        vertices: (V, 2) float64 coordinates.
        quads: (Q, 4) int64 vertex indices, each quad counter-clockwise.
    """

    vertices: np.ndarray
    quads: np.ndarray
    _z: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2:
            raise MeshVerificationError(f"mesh vertices must have shape (V, 2), got {v.shape}")
        q = np.ascontiguousarray(self.quads)
        if q.size == 0:
            q = q.reshape(0, 4).astype(np.int64)
        if q.ndim != 2 or q.shape[1] != 4:
            raise MeshVerificationError(f"mesh quads must have shape (Q, 4), got {q.shape}")
        if not np.issubdtype(q.dtype, np.integer):
            qi = q.astype(np.int64)
            if not np.array_equal(qi, q):
                raise MeshVerificationError("mesh quads must hold integer vertex indices")
            q = qi
        q = q.astype(np.int64, copy=False)
        if q.size and (q.min() < 0 or q.max() >= v.shape[0]):
            raise MeshVerificationError(
                f"quad vertex indices must lie in [0, {v.shape[0] - 1}], "
                f"found {int(q.min())}..{int(q.max())}"
            )
        if v is self.vertices:
            v = v.copy()
        if q is self.quads:
            q = q.copy()
        v.setflags(write=False)
        q.setflags(write=False)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "quads", q)
        object.__setattr__(self, "_z", v.view(np.complex128)[:, 0])

    def __reduce__(self) -> tuple:
        # rebuild through __init__ so that the arrays are read-only and z is a view again
        return (type(self), (np.array(self.vertices), np.array(self.quads)))

    # ------------------------------------------------------------------ basics
    @classmethod
    def from_complex(cls, z: np.ndarray, quads: np.ndarray) -> QuadMesh:
        """Build a mesh from complex vertices."""
        z = np.asarray(z, dtype=np.complex128).ravel()
        return cls(np.column_stack([z.real, z.imag]), quads)

    @property
    def z(self) -> np.ndarray:
        """Vertices as a complex128 array (a read-only view of ``vertices``)."""
        return self._z

    @property
    def n_vertices(self) -> int:
        """Number of vertices V."""
        return int(self.vertices.shape[0])

    @property
    def n_quads(self) -> int:
        """Number of quads Q."""
        return int(self.quads.shape[0])

    def _corners(self) -> np.ndarray:
        return self._z[self.quads]

    def angles(self) -> np.ndarray:
        """Corner angles in degrees, shape (Q, 4); corner k is at vertex ``quads[:, k]``.

        The angle at corner k is measured counter-clockwise from the edge to the next corner
        to the edge to the previous one, so it lies in (0°, 360°) and is the interior angle
        of a counter-clockwise quad (a reflex or clockwise corner gives an angle above 180°).
        Each quad is taken relative to its own first vertex (:func:`local_quad_angles_deg`).
        """
        return local_quad_angles_deg(self._z, self.quads)

    def _edge_vectors(self) -> np.ndarray:
        """(Q, 4) complex edge vectors: edge k goes from corner k to corner k + 1 (each quad
        relative to its first corner)."""
        c = self._corners()
        c = c - c[:, :1]
        return c[:, _NEXT] - c

    def areas(self) -> np.ndarray:
        """Signed areas of the quads (shoelace formula; positive when counter-clockwise).

        Each quad is taken relative to its first corner, so a quad that is tiny compared
        with its distance from the origin keeps its area's relative precision.
        """
        return quad_signed_areas(self._z, self.quads)

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Unique undirected edges (E, 2) (smaller index first) and the number of quads of each."""
        a = self.quads.ravel()
        b = self.quads[:, _NEXT].ravel()
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        keys, counts = np.unique(lo * self.n_vertices + hi, return_counts=True)
        return np.column_stack([keys // self.n_vertices, keys % self.n_vertices]), counts

    # ------------------------------------------------------------------ quality
    def _exempt_mask(
        self,
        ang: np.ndarray,
        corner_vertices: np.ndarray | None,
        valence: np.ndarray | None = None,
    ) -> np.ndarray:
        """(Q, 4) mask of original angles: unsplit corners (vertex in one quad; with
        ``corner_vertices``, one of those) below 60°. ``valence``: the number of quad corners
        at each vertex, when already counted. Only the corners below 60° are looked up."""
        out = ang < ANGLE_MIN
        qi, ki = np.nonzero(out)
        if qi.size:
            if valence is None:
                valence = np.bincount(self.quads.ravel(), minlength=self.n_vertices)
            v = self.quads[qi, ki]
            unsplit = valence[v] == 1
            if corner_vertices is not None:
                is_corner = np.zeros(self.n_vertices, dtype=bool)
                is_corner[corner_vertices[corner_vertices >= 0]] = True
                unsplit &= is_corner[v]
            out[qi[~unsplit], ki[~unsplit]] = False
        return out

    def new_angle_mask(self, polygon: object | None = None) -> np.ndarray:
        """(Q, 4) mask of the *new* corner angles: all corners except an unsplit original
        polygon corner below 60°, which the construction keeps as it is (Theorem 1.1). With
        ``polygon`` the corner must be one of its vertices; without, any vertex in one quad."""
        poly = validate_polygon(polygon) if polygon is not None else None
        corners = None if poly is None else self._match_corners(poly)[0]
        return ~self._exempt_mask(self.angles(), corners)

    def angle_slack(self, angle_tol: float = 0.0) -> np.ndarray:
        """(Q, 1) how far (degrees) float64 storage can move each quad's angles, plus
        ``angle_tol``: a diagnostic, not an allowance (:meth:`verify` uses the fixed
        :data:`ANGLE_TOL_DEG` only).

        A vertex stored in float64 is off by up to ε·|z|, which moves an angle of a quad whose
        shortest edge is ℓ by up to about 2ε·|z|/ℓ radians (ε = machine epsilon); this returns
        8ε·|z|/ℓ (a 4× margin). A corner constructed at exactly 60° or 120° reads up to that
        far outside the bound; :meth:`verify` names it when a refused angle is within it.
        """
        return (angle_tol + angle_rounding_slack_deg(self._z, self.quads))[:, None]

    def quality(
        self, polygon: object | None = None, *, angle_tol: float = ANGLE_TOL_DEG
    ) -> QualityReport:
        """Angle statistics of the mesh (new angles only; see the module docstring) and, with
        ``polygon``, edge sizes against its local feature size.

        Without ``polygon`` an unsplit polygon corner is recognised as a vertex that lies in a
        single quad; with it, the vertex must also be one of the polygon's corners.
        """
        poly = validate_polygon(polygon) if polygon is not None else None
        corners = None if poly is None else self._match_corners(poly)[0]
        return self._quality(self.angles(), self.areas(), poly, corners, angle_tol)

    def edge_lfs_ratios(
        self, polygon: object, ukeys: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Length of every distinct edge over the polygon's local feature size at its midpoint.

        The mesh and ``polygon`` must be in the same frame (for a mesh stored relative to an
        origin, pass the polygon translated by −origin). ``ukeys`` are optional undirected
        edge keys ``a * V + b`` (a < b), as :meth:`verify` computes them.

        Returns:
            ``(edges, length, lfs)``: (E, 2) vertex indices, edge lengths and the local
            feature sizes (:func:`local_feature_size`) at the midpoints.
        """
        poly = polygon if isinstance(polygon, Polygon) else validate_polygon(polygon)
        nv = self.n_vertices
        if ukeys is None:
            a = self.quads.ravel()
            b = self.quads[:, _NEXT].ravel()
            ukeys = np.unique(np.minimum(a, b) * nv + np.maximum(a, b))
        lo, hi = np.divmod(ukeys, nv)
        za, zb = self._z[lo], self._z[hi]
        d = zb - za
        return np.column_stack([lo, hi]), np.abs(d), local_feature_size(poly, za + 0.5 * d)

    def _size_fields(self, poly: Polygon | None, origin: complex, ukeys: np.ndarray | None) -> dict:
        """The edge / local feature size fields of :class:`QualityReport` (empty when there
        is no polygon, no quad, or a non-finite coordinate)."""
        if poly is None or self.n_quads == 0 or not np.all(np.isfinite(self.vertices)):
            return {}
        with span(0.92, 0.99):  # the last stretch of verify (quadmesh.progress)
            edges, length, lfs = self.edge_lfs_ratios(poly, ukeys)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = length / lfs
        k = int(np.argmin(ratio))
        a, b = int(edges[k, 0]), int(edges[k, 1])
        mid = self._z[a] + 0.5 * (self._z[b] - self._z[a]) + origin
        return {
            "n_edges": int(ratio.size),
            "min_edge_lfs": float(ratio[k]),
            "min_edge_lfs_at": (float(mid.real), float(mid.imag)),
            "min_edge_lfs_edge": (a, b),
            "min_edge_lfs_length": float(length[k]),
            "min_edge_lfs_size": float(lfs[k]),
            "median_edge_lfs": float(np.median(ratio)),
            "share_below_floor": float(np.count_nonzero(ratio < SIZE_FLOOR) / ratio.size),
            "share_below_warn": float(np.count_nonzero(ratio < SIZE_WARN) / ratio.size),
        }

    def _quality(
        self,
        ang: np.ndarray,
        areas: np.ndarray,
        poly: Polygon | None,
        corners: np.ndarray | None,
        angle_tol: float,
        origin: complex = 0j,
        ukeys: np.ndarray | None = None,
        exempt: np.ndarray | None = None,
    ) -> QualityReport:
        if exempt is None:
            exempt = self._exempt_mask(ang, corners)
        any_exempt = bool(exempt.any())
        # the new angles (in any order: only their extremes and histogram are taken)
        new = ang[~exempt] if any_exempt else ang
        # an angle within the fixed tolerance of a bin edge counts as on it (a right angle
        # read 89.99999999999° is in the 90° bin with its neighbours), and 60°/120° belong to
        # the bins inside the range
        binned = new / 5.0
        np.round(binned, out=binned)
        binned *= 5.0  # the nearest bin edge
        off = new - binned
        np.abs(off, out=off)
        np.copyto(binned, new, where=~(off <= angle_tol))
        np.subtract(binned, 120.0, out=off)
        np.abs(off, out=off)
        np.copyto(binned, 120.0 - 1e-9, where=off <= angle_tol)
        del off
        hist, edges = np.histogram(binned, bins=36, range=(0.0, 180.0))
        bad = (ang < ANGLE_MIN - angle_tol) | (ang > ANGLE_MAX + angle_tol)
        if any_exempt:
            bad &= ~exempt
        if ang.size:
            dev = ang - 90.0
            np.abs(dev, out=dev)
            if any_exempt:
                dev[exempt] = 0.0
            dev = dev.max(axis=1)
        else:
            dev = ang[:, 0]
        k = min(10, dev.size)
        if k:
            worst = np.argpartition(-dev, k - 1)[:k]
            worst = worst[np.argsort(-dev[worst], kind="stable")]
        else:
            worst = np.zeros(0, dtype=np.int64)
        n_poly = None if poly is None else poly.n
        return QualityReport(
            n_quads=self.n_quads,
            n_vertices=self.n_vertices,
            n_polygon_vertices=n_poly,
            quads_per_vertex=None if n_poly is None else self.n_quads / n_poly,
            min_angle=float(new.min()) if new.size else float("nan"),
            max_angle=float(new.max()) if new.size else float("nan"),
            min_original_angle=float(ang[exempt].min()) if exempt.any() else None,
            n_original=int(exempt.sum()),
            histogram=hist,
            bin_edges=edges,
            n_angles_outside=int(bad.sum()),
            n_quads_outside=int(bad.any(axis=1).sum()),
            worst_quads=worst.astype(np.int64),
            worst_angles=ang[worst],
            min_area=float(areas.min()) if areas.size else float("nan"),
            max_area=float(areas.max()) if areas.size else float("nan"),
            **self._size_fields(poly, origin, ukeys),
        )

    # ------------------------------------------------------------------ verification
    def _edge_analysis(self) -> dict:
        """Undirected edge keys (key = a * V + b with a < b, ascending) with the number of
        quads of each, the free (boundary) half-edges (a, b) oriented as in their quad (in
        the order of their keys), and the directed keys that occur more than once (ascending).

        One plain sort of the undirected keys with the direction in the lowest bit (0 when
        the quad runs from the smaller index to the larger): equal undirected keys are
        adjacent, a directed edge used twice is a repeated value, and a free edge's bit is its
        direction."""
        nv = self.n_vertices
        q = self.quads
        a = q.ravel()
        b = np.empty_like(q)  # q[:, _NEXT], by slices
        b[:, :3] = q[:, 1:]
        b[:, 3] = q[:, 0]
        b = b.ravel()
        if nv < 1 << 31:  # 2 * V**2 fits in int64
            key = np.minimum(a, b) * nv
            key += np.maximum(a, b)
            key <<= 1
            key |= a > b
            key.sort()
            rep = key[1:][key[1:] == key[:-1]]
            rep_u, rep_down = rep >> 1, (rep & 1).astype(bool)
            rep_lo, rep_hi = np.divmod(rep_u, nv)
            rep_d = np.unique(np.where(rep_down, rep_hi * nv + rep_lo, rep_u))
            # a new undirected key where two neighbours differ in more than the last bit
            new = np.bitwise_xor(key[1:], key[:-1]) > 1
            start = np.flatnonzero(np.r_[True, new])
            ukeys = key[start] >> 1
        else:  # the directed keys sorted separately
            su = np.sort(np.minimum(a, b) * nv + np.maximum(a, b))
            sd = np.sort(a * nv + b)
            rep_d = np.unique(sd[1:][sd[1:] == sd[:-1]])
            start = np.flatnonzero(np.r_[True, su[1:] != su[:-1]])
            ukeys = su[start]
        counts = np.diff(np.r_[start, a.size])
        one = counts == 1
        lo, hi = np.divmod(ukeys[one], nv)
        if nv < 1 << 31:
            fwd = (key[start[one]] & 1) == 0
        else:
            single = ukeys[one]
            pos = np.searchsorted(sd, single)
            fwd = sd[np.minimum(pos, sd.size - 1)] == single
        ba = np.where(fwd, lo, hi)
        bb = np.where(fwd, hi, lo)
        return {"ukeys": ukeys, "counts": counts, "ba": ba, "bb": bb, "repeated_directed": rep_d}

    def _free_vertices(self, ba: np.ndarray, bb: np.ndarray) -> np.ndarray:
        """Ascending indices of the vertices of the free edges (a, b) (what
        ``np.unique(np.r_[ba, bb])`` gives, from a mask over the vertices)."""
        mark = np.zeros(self.n_vertices, dtype=bool)
        mark[ba] = True
        mark[bb] = True
        return np.flatnonzero(mark)

    def _match_corners(
        self, poly: Polygon, ba: np.ndarray | None = None, bb: np.ndarray | None = None
    ) -> tuple[np.ndarray, float]:
        """Mesh vertex index of every polygon corner (-1 if none) and the distance tolerance.

        Only vertices on free edges are candidates (a corner must be a boundary vertex)."""
        from scipy.spatial import cKDTree

        tol = 1e-9 * poly.diameter
        if ba is None or bb is None:
            ed = self._edge_analysis()
            ba, bb = ed["ba"], ed["bb"]
        cand = self._free_vertices(ba, bb)
        out = np.full(poly.n, -1, dtype=np.int64)
        if cand.size == 0:
            return out, tol
        tree = cKDTree(self.vertices[cand])
        d, i = tree.query(poly.vertices, k=1)
        hit = d <= tol
        out[hit] = cand[i[hit]]
        return out, tol

    def verify(
        self,
        polygon: object,
        *,
        angle_tol: float = ANGLE_TOL_DEG,
        area_rtol: float = 1e-9,
        dist_rtol: float = 1e-9,
        coincident_rtol: float = COINCIDENT_RTOL,
        origin: complex = 0j,
    ) -> VerificationReport:
        """Check that this mesh is a valid angle-bounded quad mesh of ``polygon``.

        Every quantity is computed from the stored coordinates in float64, each quad relative
        to its own first vertex, with fixed tolerances (none grows as quads shrink or with
        the distance from (0, 0)).

        Args:
            polygon: anything :func:`~quadmesh.polygon.validate_polygon` accepts.
            angle_tol: fixed slack in degrees on the bounds 60° and 120°.
            area_rtol: allowed relative difference of total quad area and polygon area.
            dist_rtol: distance (relative to the polygon's diameter) within which a boundary
                vertex counts as lying on a polygon side, and a polygon corner as a vertex.
            coincident_rtol: distinct vertices closer than this fraction of the diameter are
                a problem.
            origin: the mesh's vertices are relative to this point (the polygon is given in
                absolute coordinates and is translated by −origin); messages print absolute
                coordinates.

        Returns:
            A :class:`VerificationReport`; ``ok`` is True when nothing is wrong.
        """
        poly = validate_polygon(polygon)
        origin = complex(origin)
        if origin:
            poly = validate_polygon(poly.z - origin)
        problems: list[str] = []
        warnings: list[str] = []
        z = self._z
        diam = poly.diameter
        tol = dist_rtol * diam

        if not np.all(np.isfinite(self.vertices)):
            bad = np.flatnonzero(~np.isfinite(self.vertices).all(axis=1))
            problems.append(f"non-finite coordinates at {bad.size} vertices, e.g. vertex {bad[0]}")
            return self._report(problems, warnings, poly, None, 0, 0, float("nan"), angle_tol)
        if self.n_quads == 0:
            problems.append("the mesh has no quads")
            return self._report(problems, warnings, poly, None, 0, 0, 1.0, angle_tol)

        q = self.quads
        checkpoint(0.05)
        # corners relative to each quad's first one and the edge vectors, made once for the
        # angles, the areas and the shortest edges (the same values as angles(), areas() and
        # _edge_vectors() give)
        c = self._corners()
        c = c - c[:, :1]
        e = np.empty_like(c)  # c[:, _NEXT] - c, by slices
        np.subtract(c[:, 1:], c[:, :3], out=e[:, :3])
        np.subtract(c[:, 0], c[:, 3], out=e[:, 3])
        ang = _angles_from_edges(e)
        areas = local_signed_areas(c)
        # quads with an edge of length |e| <= short; |e| = hypot(re, im) (rounded faithfully)
        # is at least max(|re|, |im|), so only edges with both components within short can be
        short = 1e-14 * diam
        small = np.abs(e.real) <= short
        small &= np.abs(e.imag) <= short
        near = np.flatnonzero(small[:, 0] | small[:, 1] | small[:, 2] | small[:, 3])
        short_edge = np.zeros(q.shape[0], dtype=bool)
        short_edge[near] = np.abs(e[near]).min(axis=1) <= short
        del c, e
        checkpoint(0.2)

        # --- repeated indices inside a quad, unused and coincident vertices
        rep = np.flatnonzero(
            (q[:, 0] == q[:, 1])
            | (q[:, 0] == q[:, 2])
            | (q[:, 0] == q[:, 3])
            | (q[:, 1] == q[:, 2])
            | (q[:, 1] == q[:, 3])
            | (q[:, 2] == q[:, 3])
        )
        if rep.size:
            problems.append(
                f"degenerate: {rep.size} quads repeat a vertex, "
                f"e.g. quad {rep[0]} = {q[rep[0]].tolist()}"
            )
        valence = np.bincount(q.ravel(), minlength=self.n_vertices)
        if not valence.all():
            unused = np.flatnonzero(valence == 0)
            warnings.append(f"{unused.size} vertices belong to no quad, e.g. vertex {unused[0]}")
        problems += self._coincident(coincident_rtol * diam, origin)
        checkpoint(0.4)
        # --- orientation, convexity, degeneracy
        degenerate = (np.abs(areas) <= (1e-14 * diam) ** 2) | short_edge
        flipped = (areas < 0) & ~degenerate
        if flipped.any():
            i = np.flatnonzero(flipped)
            problems.append(
                f"flipped: {i.size} quads are clockwise, e.g. quad {i[0]} {q[i[0]].tolist()} "
                f"(signed area {areas[i[0]]:.4g})"
            )
        if degenerate.any():
            i = np.flatnonzero(degenerate)
            problems.append(
                f"degenerate: {i.size} quads have (nearly) zero area or a zero-length edge, "
                f"e.g. quad {i[0]} (area {areas[i[0]]:.3g})"
            )
        eps_deg = 1e-9
        nonconvex = ((ang >= 180.0 - eps_deg) | (ang <= eps_deg)).any(axis=1)
        nonconvex &= ~flipped & ~degenerate
        if nonconvex.any():
            i = np.flatnonzero(nonconvex)
            k = int(np.argmax(ang[i[0]]))
            problems.append(
                f"not strictly convex: {i.size} quads, e.g. quad {i[0]} has an angle of "
                f"{ang[i[0], k]:.4g}° at vertex {q[i[0], k]} {_fmt_pt(z[q[i[0], k]], origin)}"
            )

        # --- conformity: every directed edge once, every undirected edge in at most two quads
        checkpoint(0.5)
        ed = self._edge_analysis()
        checkpoint(0.7)
        nv = self.n_vertices
        ba, bb, counts, ukeys = ed["ba"], ed["bb"], ed["counts"], ed["ukeys"]
        many = np.flatnonzero(counts > 2)
        if many.size:
            k = ukeys[many[0]]
            problems.append(
                f"overlap: {many.size} edges lie in more than two quads, e.g. edge "
                f"({k // nv}, {k % nv}) in {counts[many[0]]} quads"
            )
        rep_d = ed["repeated_directed"]
        directed = None
        if many.size or rep_d.size:
            directed = q.ravel() * nv + q[:, _NEXT].ravel()
        if rep_d.size:
            k = rep_d[0]
            qi = np.flatnonzero(directed == k) // 4
            problems.append(
                f"overlap: {rep_d.size} edges are used twice in the same direction (overlapping "
                f"or flipped quads), e.g. edge ({k // nv}, {k % nv}) in quads "
                + ", ".join(str(x) for x in qi[:4])
            )
        if many.size or rep_d.size:
            # duplicated quads, looked for among the quads of the suspicious edges only
            bad_keys = np.r_[ukeys[many], rep_d]
            a_, b_ = bad_keys // nv, bad_keys % nv
            und = np.r_[bad_keys, b_ * nv + a_]
            sus = np.unique(np.flatnonzero(np.isin(directed, und)) // 4)
            qs = np.sort(q[sus], axis=1)
            _, first_idx, inv_q, cnt_q = np.unique(
                qs, axis=0, return_index=True, return_inverse=True, return_counts=True
            )
            inv_q = inv_q.ravel()
            dq = np.flatnonzero((cnt_q[inv_q] > 1) & (np.arange(sus.size) != first_idx[inv_q]))
            if dq.size:
                j0 = int(sus[dq[0]])
                i0 = int(sus[first_idx[inv_q[dq[0]]]])
                problems.append(
                    f"overlap: {dq.size} duplicated quads, "
                    f"e.g. quad {j0} repeats quad {i0} ({q[i0].tolist()})"
                )
        n_interior = int(np.count_nonzero(counts >= 2))
        n_boundary = int(ba.size)

        # --- cracks: distinct boundary vertices at the same position
        fv = self._free_vertices(ba, bb)
        _, inv, cnt = np.unique(z[fv], return_inverse=True, return_counts=True)
        dup = cnt[inv.ravel()] > 1
        if dup.any():
            i0 = fv[np.flatnonzero(dup)[0]]
            problems.append(
                f"crack: {int(dup.sum())} vertices of free edges share their position with "
                f"another, e.g. vertex {i0} at {_fmt_pt(z[i0], origin)}"
            )

        # --- polygon corners and boundary edges
        checkpoint(0.8)
        corner_v, _ = self._match_corners(poly, ba, bb)
        missing = np.flatnonzero(corner_v < 0)
        if missing.size:
            problems.append(
                f"corner: {missing.size} polygon corners are not mesh boundary vertices, e.g. "
                f"corner {missing[0]} at {_fmt_pt(poly.z[missing[0]], origin)}"
            )
        checkpoint(0.85)
        problems += self._check_boundary(poly, corner_v, ba, bb, tol, origin)

        # --- area
        total = float(areas.sum())
        area_err = abs(total - poly.area) / poly.area
        if not area_err <= area_rtol:
            problems.append(
                f"area: the quads cover {total:.12g}, the polygon has area {poly.area:.12g} "
                f"(relative error {area_err:.3g}; a hole or an overlap)"
            )

        # --- angles
        checkpoint(0.9)
        exempt = self._exempt_mask(ang, corner_v, valence)
        bad = ((ang < ANGLE_MIN - angle_tol) | (ang > ANGLE_MAX + angle_tol)) & ~exempt
        if bad.any():
            bq, bk = np.nonzero(bad)
            miss = np.maximum(ANGLE_MIN - ang[bq, bk], ang[bq, bk] - ANGLE_MAX)
            w = int(np.argmax(miss))
            qw, vw = int(bq[w]), int(q[bq[w], bk[w]])
            edge = float(np.abs(self._edge_vectors()[qw]).min())
            msg = (
                f"angle: {bq.size} new angles outside [60°, 120°] in {np.unique(bq).size} quads "
                f"(by more than {angle_tol:g}°); worst {ang[bq[w], bk[w]]:.12g}° in quad {qw} "
                f"at vertex {vw} {_fmt_pt(z[vw], origin)}, shortest edge {edge:.3g}"
            )
            rounding = float(angle_rounding_slack_deg(z, q[qw : qw + 1])[0])
            if miss[w] <= rounding:
                msg += (
                    f" ({edge / diam:.2g} of the polygon's diameter: float64 coordinates "
                    f"there move its angles by up to {rounding:.2g}°)"
                )
            problems.append(msg)
        return self._report(
            problems,
            warnings,
            poly,
            corner_v,
            n_interior,
            n_boundary,
            area_err,
            angle_tol,
            ang,
            areas,
            origin,
            ukeys,
            exempt,
        )

    def _coincident(self, r: float, origin: complex = 0j) -> list[str]:
        """Problems for distinct vertices closer than ``r`` (coincident or nearly so).

        The pairs are those of :meth:`scipy.spatial.cKDTree.query_pairs` within ``r``, among
        the vertices that :func:`_close_candidates` does not rule out (every vertex within
        ``r`` of another is kept); the example is the closest pair, the first in (i, j)
        order among equally close ones."""
        from scipy.spatial import cKDTree

        if self.n_vertices < 2:
            return []
        cand = _close_candidates(self.vertices, r)
        if cand.size < 2:
            return []
        # an unbalanced tree without shrunk nodes builds faster and finds the same pairs
        tree = cKDTree(self.vertices[cand], balanced_tree=False, compact_nodes=False)
        pairs = tree.query_pairs(r, output_type="ndarray")
        if pairs.size == 0:
            return []
        pairs = cand[pairs]
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        d = np.abs(self._z[pairs[:, 0]] - self._z[pairs[:, 1]])
        k = int(np.argmin(d))
        i, j = int(pairs[k, 0]), int(pairs[k, 1])
        return [
            f"coincident vertices: {pairs.shape[0]} pairs of distinct vertices lie within "
            f"{r:.3g} of each other, e.g. vertices {i} and {j} at {_fmt_pt(self._z[i], origin)} "
            f"(distance {d[k]:.3g})"
        ]

    def _report(
        self,
        problems: list[str],
        warnings: list[str],
        poly: Polygon,
        corner_v: np.ndarray | None,
        n_interior: int,
        n_boundary: int,
        area_err: float,
        angle_tol: float,
        ang: np.ndarray | None = None,
        areas: np.ndarray | None = None,
        origin: complex = 0j,
        ukeys: np.ndarray | None = None,
        exempt: np.ndarray | None = None,
    ) -> VerificationReport:
        if ang is None:
            with np.errstate(invalid="ignore"):
                ang = self.angles()
                areas = self.areas()
        return VerificationReport(
            ok=not problems,
            problems=tuple(problems),
            warnings=tuple(warnings),
            quality=self._quality(ang, areas, poly, corner_v, angle_tol, origin, ukeys, exempt),
            n_interior_edges=n_interior,
            n_boundary_edges=n_boundary,
            area_error=area_err,
        )

    def _check_boundary(
        self,
        poly: Polygon,
        corner_v: np.ndarray,
        ba: np.ndarray,
        bb: np.ndarray,
        tol: float,
        origin: complex = 0j,
    ) -> list[str]:
        """Problems with the free edges (a, b): each must lie on a polygon side, in the side's
        direction, and the free edges of each side must chain from one corner to the next."""
        import shapely

        problems: list[str] = []
        z = self._z
        pz = poly.z
        n = poly.n
        if ba.size == 0:
            return ["boundary: the mesh has no boundary edges"]
        pv = poly.vertices
        sides = shapely.linestrings(np.stack([pv, np.roll(pv, -1, axis=0)], axis=1))
        mid = 0.5 * (z[ba] + z[bb])
        side = _nearest_sides(shapely.STRtree(sides), pz, mid, tol)
        p0 = pz[side]
        d = np.roll(pz, -1)[side] - p0
        dd = (d * np.conj(d)).real

        def param(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            t = ((p - p0) * np.conj(d)).real / dd
            dist = np.abs(p - p0 - np.clip(t, 0.0, 1.0) * d)
            return t, dist

        ta, da = param(z[ba])
        tb, db = param(z[bb])
        on = (da <= tol) & (db <= tol)

        # free edges inside the domain: holes, cracks, hanging vertices
        off = np.flatnonzero(~on)
        if off.size:
            problems += self._describe_inner_free_edges(poly, ba[off], bb[off], tol, origin)

        fwd = on & (tb > ta)
        back = np.flatnonzero(on & ~fwd)
        if back.size:
            e = back[0]
            problems.append(
                f"boundary: {back.size} boundary edges run clockwise along the polygon, e.g. "
                f"edge ({ba[e]}, {bb[e]}) on side {side[e]} (a flipped quad at the boundary)"
            )
        sel = np.flatnonzero(fwd)
        covered = np.zeros(n, dtype=bool)
        if sel.size:
            o = sel[np.lexsort((ta[sel], side[sel]))]
            s, a, b, t0, t1 = side[o], ba[o], bb[o], ta[o], tb[o]
            covered[s] = True
            first = np.r_[True, s[1:] != s[:-1]]
            last = np.r_[s[1:] != s[:-1], True]
            ttol = tol / np.sqrt(dd[o])
            gaps, overlaps, cracks = [], [], []
            # starts and ends of each side
            bad_start = first & (a != corner_v[s])
            for i in np.flatnonzero(bad_start)[:_MAX_EXAMPLES]:
                (gaps if t0[i] > ttol[i] else cracks).append(
                    f"side {s[i]} starts at t={t0[i]:.6g} instead of at its corner "
                    f"{_fmt_pt(pz[s[i]], origin)}"
                )
            nb = np.count_nonzero(bad_start)
            end_v = corner_v[(s + 1) % n]
            bad_end = last & (b != end_v)
            for i in np.flatnonzero(bad_end)[:_MAX_EXAMPLES]:
                (gaps if t1[i] < 1 - ttol[i] else cracks).append(
                    f"side {s[i]} ends at t={t1[i]:.6g} instead of at its corner "
                    f"{_fmt_pt(pz[(s[i] + 1) % n], origin)}"
                )
            nb += np.count_nonzero(bad_end)
            # consecutive edges on one side
            inner = np.flatnonzero(~last)
            brk = inner[b[inner] != a[inner + 1]]
            for i in brk[: _MAX_EXAMPLES * 3]:
                if t1[i] < t0[i + 1] - ttol[i]:
                    gaps.append(f"side {s[i]} has a gap from t={t1[i]:.6g} to t={t0[i + 1]:.6g}")
                elif t1[i] > t0[i + 1] + ttol[i]:
                    overlaps.append(
                        f"side {s[i]} is covered twice between t={t0[i + 1]:.6g} and t={t1[i]:.6g}"
                    )
                else:
                    cracks.append(
                        f"side {s[i]}: vertices {b[i]} and {a[i + 1]} are distinct at the same "
                        f"point {_fmt_pt(z[b[i]], origin)}"
                    )
            nb += brk.size
            for kind, lst in (("gap", gaps), ("overlap", overlaps), ("crack", cracks)):
                if lst:
                    problems.append(
                        f"boundary {kind}: {len(lst)} along the polygon sides, e.g. "
                        + "; ".join(lst[:_MAX_EXAMPLES])
                    )
        uncovered = np.flatnonzero(~covered)
        if uncovered.size:
            k = uncovered[0]
            problems.append(
                f"boundary gap: {uncovered.size} polygon sides carry no mesh edge, e.g. side {k} "
                f"from {_fmt_pt(pz[k], origin)} to {_fmt_pt(pz[(k + 1) % n], origin)}"
            )
        return problems

    def _describe_inner_free_edges(
        self, poly: Polygon, a: np.ndarray, b: np.ndarray, tol: float, origin: complex = 0j
    ) -> list[str]:
        """Explain free edges that are not on a polygon side: hanging vertices (a vertex inside
        the edge of a neighbour), boundary edges off the polygon (an end on the boundary) and
        holes (both ends inside the domain)."""
        import shapely

        z = self._z
        problems: list[str] = []
        m = min(a.size, 20000)  # the explanation looks at the first 20 000 such edges
        more = f" (of the first {m}; {a.size} in all)" if a.size > m else ""
        a, b = a[:m], b[:m]
        segs = shapely.linestrings(
            np.stack(
                [np.column_stack([z[a].real, z[a].imag]), np.column_stack([z[b].real, z[b].imag])],
                axis=1,
            )
        )
        tree = shapely.STRtree(segs)
        verts = np.unique(np.r_[a, b])
        pts = shapely.points(z[verts].real, z[verts].imag)
        vi, ei = tree.query(pts, predicate="dwithin", distance=tol)
        v = verts[vi]
        hanging = (v != a[ei]) & (v != b[ei])
        explained = np.zeros(m, dtype=bool)
        if hanging.any():
            hv, he = v[hanging], ei[hanging]
            explained[he] = True
            is_h = np.zeros(self.n_vertices, dtype=bool)
            is_h[hv] = True
            explained |= is_h[a] | is_h[b]
            problems.append(
                f"hanging vertex (T-junction): {np.unique(hv).size} vertices lie inside an edge of "
                f"a neighbouring quad, e.g. vertex {hv[0]} at {_fmt_pt(z[hv[0]], origin)} on edge "
                f"({a[he[0]]}, {b[he[0]]})"
            )
        ring = shapely.linearrings(poly.vertices)
        dist = np.zeros(self.n_vertices)
        dist[verts] = shapely.distance(pts, ring)
        touches = (dist[a] <= tol) | (dist[b] <= tol)
        rest = np.flatnonzero(~explained & touches)
        if rest.size:
            i = rest[0]
            far = a[i] if dist[a[i]] > dist[b[i]] else b[i]
            problems.append(
                f"boundary edge off the polygon: {rest.size}{more} free edges (in one quad) leave "
                f"the polygon boundary, e.g. edge ({a[i]}, {b[i]}) whose vertex {far} at "
                f"{_fmt_pt(z[far], origin)} is {dist[far]:.3g} away from it"
            )
        rest = np.flatnonzero(~explained & ~touches)
        if rest.size:
            i = rest[0]
            problems.append(
                f"hole: {rest.size}{more} free edges (in one quad) lie inside the domain, e.g. "
                f"edge ({a[i]}, {b[i]}) from {_fmt_pt(z[a[i]], origin)} "
                f"to {_fmt_pt(z[b[i]], origin)}"
            )
        return problems

    def check(self, polygon: object, **kwargs: float) -> VerificationReport:
        """Verify against ``polygon`` and raise :class:`MeshVerificationError` listing every
        problem when the mesh is not valid; return the report when it is."""
        report = self.verify(polygon, **kwargs)
        if not report.ok:
            raise MeshVerificationError(
                "mesh verification failed:\n" + "\n".join(f"- {p}" for p in report.problems)
            )
        return report


def finalize_mesh(
    polygon: object,
    z_local: np.ndarray,
    quads: np.ndarray,
    origin: complex = 0j,
    *,
    angle_tol: float = ANGLE_TOL_DEG,
) -> tuple[QuadMesh, complex, VerificationReport]:
    """The mesh handed to the user, verified as it will be stored.

    ``z_local`` are complex vertices relative to ``origin`` (the exact translation under which
    a polygon far from (0, 0) was meshed). The absolute coordinates ``z_local + origin`` are
    verified first; when they pass, they are returned with mesh origin 0. When they do not
    (far from (0, 0) float64 cannot hold the angles of small quads) and ``origin`` is not 0,
    the relative coordinates are verified against the polygon translated by −origin and, when
    they pass, returned with mesh origin ``origin``: the mesh's absolute positions are its
    vertices plus that origin.

    Returns:
        ``(mesh, mesh_origin, report)`` with ``report.ok`` True.

    Raises:
        MeshVerificationError: neither form passes; the message lists the problems (with
        absolute coordinates).
    """
    poly = validate_polygon(polygon)
    z_local = np.asarray(z_local, dtype=np.complex128)
    origin = complex(origin)
    z = z_local + origin if origin else z_local
    mesh = QuadMesh.from_complex(z, quads)
    report = mesh.verify(poly, angle_tol=angle_tol)
    if report.ok:
        return mesh, 0j, report
    if origin:
        local = QuadMesh.from_complex(z_local, quads)
        local_report = local.verify(poly, angle_tol=angle_tol, origin=origin)
        if local_report.ok:
            return local, origin, local_report
        report = local_report
    raise MeshVerificationError(
        "the assembled mesh failed verification: " + "; ".join(report.problems[:5])
    )
