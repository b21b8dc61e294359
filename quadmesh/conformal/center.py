"""Centre of the largest inscribed disk and the harmonic measure seen from it.

:func:`harmonic_measure` estimates ``ω(c, side_k, Ω)`` for every side by finite elements; for
the disk map with ``f(0) = c`` the prevertex gaps are exactly ``2π ω`` (§1.5 initial guess).

The Schwarz–Christoffel map of a thick piece is normalised by ``f(0) = c`` with ``c`` a point
deep inside the piece: the harmonic measure seen from ``c`` is then spread over the boundary and
the prevertex gaps stay as large as possible (less crowding, §1.8).

The largest inscribed disk is often not unique (a rectangle has a whole segment of centres).
Among the near-optimal centres we take the most central one: the point of the ridge
``{x : dist(x, ∂Ω) ≥ (1 − ε) r_max}`` closest to the ridge's centroid. For a rectangle this is
the centre of the rectangle, for a regular polygon its centre.
"""

from __future__ import annotations

import collections
import threading

import numpy as np
import scipy.sparse as sp
import shapely
from scipy.sparse.linalg import spsolve
from scipy.spatial import Delaunay, cKDTree
from shapely.ops import nearest_points

from ..errors import PolygonError
from ..progress import checkpoint

__all__ = ["harmonic_measure", "inscribed_center"]


def inscribed_center(z: np.ndarray, *, rel_tol: float = 1e-4) -> tuple[complex, float]:
    """Return ``(center, radius)`` of a largest inscribed disk of the polygon ``z``.

    ``z`` is a complex array (or an (n, 2) float array) of vertices. The radius of the
    maximum inscribed circle is found with GEOS (``shapely.maximum_inscribed_circle``, a
    certified grid refinement of the distance function) to ``rel_tol`` times the polygon's
    size; ties are broken by the ridge rule of the module docstring (ε = 10 ``rel_tol``).
    ``radius`` is the exact distance from the returned centre to the boundary.
    """
    zz = np.asarray(z)
    if not np.iscomplexobj(zz):
        zz = np.asarray(zz, dtype=float)
        if zz.ndim != 2 or zz.shape[1] != 2:
            raise PolygonError(f"expected complex vertices or an (n, 2) array, got {zz.shape}")
        zz = zz[:, 0] + 1j * zz[:, 1]
    zz = zz.astype(np.complex128).ravel()
    poly = shapely.Polygon(np.column_stack([zz.real, zz.imag]))
    if not poly.is_valid or poly.area <= 0:
        raise PolygonError("inscribed_center needs a simple polygon with positive area")
    size = float(np.sqrt(poly.area))
    mic = shapely.maximum_inscribed_circle(poly, tolerance=rel_tol * size)
    (cx, cy), _ = shapely.get_coordinates(mic)
    boundary = poly.exterior
    r_max = float(shapely.distance(shapely.Point(cx, cy), boundary))
    center = shapely.Point(cx, cy)
    ridge = shapely.buffer(poly, -(1.0 - 10.0 * rel_tol) * r_max, quad_segs=16)
    if not ridge.is_empty:
        parts = list(getattr(ridge, "geoms", [ridge]))
        # the component holding the best centre found by GEOS (or the largest one)
        holding = [p for p in parts if p.covers(center)]
        comp = holding[0] if holding else max(parts, key=lambda p: p.area)
        cen = comp.centroid
        cand = cen if comp.covers(cen) else nearest_points(comp, cen)[0]
        r_cand = float(shapely.distance(cand, boundary))
        if poly.contains(cand) and r_cand >= (1.0 - 20.0 * rel_tol) * r_max:
            center, r_max = cand, r_cand
    return complex(center.x, center.y), r_max


def _feature_sizes(w: np.ndarray, diam: float) -> np.ndarray:
    """Distance from each side to the nearest non-adjacent side (capped at ``diam``)."""
    n = w.size
    a = np.column_stack([w.real, w.imag])
    lines = shapely.linestrings(np.stack([a, np.roll(a, -1, axis=0)], axis=1))
    tree = shapely.STRtree(lines)
    out = np.full(n, np.inf)
    r = np.minimum(np.abs(np.roll(w, -1) - w), diam)
    todo = np.arange(n)
    while todo.size:
        ii, jj = tree.query(lines[todo], predicate="dwithin", distance=r[todo])
        ii = todo[ii]
        far = ((jj - ii) % n > 1) & ((ii - jj) % n > 1)
        ii, jj = ii[far], jj[far]
        if ii.size:
            np.minimum.at(out, ii, shapely.distance(lines[ii], lines[jj]))
        todo = todo[~np.isfinite(out[todo]) & (r[todo] < diam)]
        r[todo] *= 2.0
    return np.minimum(out, diam)


def _graded_points(
    poly: shapely.Polygon, bp: np.ndarray, bh: np.ndarray, hmax: float, grade: float
) -> np.ndarray:
    """Interior points of a graded quadtree: a cell of size s emits its centre when the
    target size ``min_j (bh_j + grade·|x − b_j|)`` (over the nearest boundary samples b_j)
    is at least s, and is split into four otherwise."""
    tree = cKDTree(np.column_stack([bp.real, bp.imag]))
    k = min(12, bp.size)
    x0, y0, x1, y1 = poly.bounds
    s = hmax
    xs = np.arange(x0 + s / 2, x1 + s / 2, s)
    ys = np.arange(y0 + s / 2, y1 + s / 2, s)
    cells = (xs[None, :] + 1j * ys[:, None]).ravel()
    out = []
    smin = 0.5 * float(bh.min())
    while cells.size and s >= smin:
        dd, ii = tree.query(np.column_stack([cells.real, cells.imag]), k=k)
        dd = dd.reshape(cells.size, -1)
        ii = ii.reshape(cells.size, -1)
        target = np.minimum(np.min(bh[ii] + grade * dd, axis=1), hmax)
        emit = (target >= 0.999 * s) & (dd[:, 0] > 0.8 * s)
        q = cells[emit]
        out.append(q[shapely.contains_xy(poly, q.real, q.imag)])
        # split the rest unless the cell lies far outside the polygon
        rest = cells[(target < 0.999 * s)]
        s *= 0.5
        off = 0.5 * s * np.array([-1 - 1j, 1 - 1j, -1 + 1j, 1 + 1j])
        cells = (rest[:, None] + off[None, :]).ravel()
        if cells.size:
            near = shapely.intersects_xy(poly.buffer(s), cells.real, cells.imag)
            cells = cells[near]
    return np.concatenate(out) if out else np.zeros(0, complex)


#: The last few harmonic measures computed: the decomposition estimates a piece's crowding
#: from the same polygon and centre the piece's disk map then starts from.
_MEASURES: collections.OrderedDict[tuple, np.ndarray] = collections.OrderedDict()
_MEASURES_KEPT = 32
_MEASURES_LOCK = threading.Lock()


def harmonic_measure(
    z: np.ndarray, c: complex, *, per_width: float = 4.0, grade: float = 0.4
) -> np.ndarray:
    """Harmonic measure ``ω_k = ω(c, side_k, Ω)`` of every side (``z_k → z_{k+1}``) seen from c
    (:func:`_harmonic_measure`), remembered for the last few polygons and centres."""
    w = np.ascontiguousarray(np.asarray(z, dtype=np.complex128).ravel())
    key = (w.tobytes(), complex(c), float(per_width), float(grade))
    with _MEASURES_LOCK:
        om = _MEASURES.get(key)
        if om is not None:
            _MEASURES.move_to_end(key)
            return om.copy()
    om = _harmonic_measure(w, c, per_width=per_width, grade=grade)
    with _MEASURES_LOCK:
        _MEASURES[key] = om.copy()
        while len(_MEASURES) > _MEASURES_KEPT:
            _MEASURES.popitem(last=False)
    return om


def _harmonic_measure(
    z: np.ndarray, c: complex, *, per_width: float = 4.0, grade: float = 0.4
) -> np.ndarray:
    """Harmonic measure ``ω_k = ω(c, side_k, Ω)`` of every side (``z_k → z_{k+1}``) seen from c.

    For the disk map with ``f(0) = c`` the prevertex gap of side k is exactly ``2π ω_k``
    (conformal invariance of harmonic measure, paper §2 / Lemma 2.2), so this is the initial
    guess of the Schwarz–Christoffel parameter problem. Computed as the
    boundary flux of the discrete Green's function with pole c: P1 finite elements on a
    Delaunay triangulation of boundary samples (spacing ≤ side/2 and ≤ local width /
    ``per_width``) and graded quadtree points. The Delaunay cotangent Laplacian is an
    M-matrix, so the discrete Green's function is positive and its fluxes carry relative
    accuracy even where ω decays exponentially along channels (measured: within a factor
    1.2 of the true ω down to ω ≈ 1e-36). Accuracy is a few percent, ample for Newton.
    Returns ω (non-negative, summing to 1). Raises :class:`PolygonError` when the mesh
    cannot be built.
    """
    w = np.asarray(z, dtype=np.complex128).ravel()
    c = complex(c)
    diam = 2.0 * float(np.max(np.abs(w - c)))
    samples = _boundary_samples(w, diam, per_width)
    bp = samples[0]
    poly = shapely.Polygon(np.column_stack([w.real, w.imag]))
    ip = _graded_points(poly, bp, samples[1], diam / 12.0, grade)
    checkpoint(0.2)
    near_c = np.abs(ip - c) < 0.5 * float(np.min(np.abs(bp - c)))
    ip = ip[~near_c]
    P = np.concatenate([bp, ip, [c]])
    A, inner = _laplacian(P, poly, bp.size)
    if inner[-1] != P.size - 1:
        raise PolygonError("harmonic measure: the triangulation missed the centre")
    checkpoint(0.7)
    rhs = np.zeros(inner.size)
    rhs[-1] = 1.0
    with np.errstate(all="ignore"):
        g = spsolve(A[inner][:, inner].tocsc(), rhs)
    if not np.all(np.isfinite(g)):
        raise PolygonError("harmonic measure: singular finite-element system")
    checkpoint(0.9)
    return _side_measure(A, inner, g[:, None], samples, w.size)[0]


def harmonic_measures(
    z: np.ndarray, poles: np.ndarray, *, per_width: float = 4.0, grade: float = 0.4
) -> np.ndarray:
    """Harmonic measure of every side seen from each of several interior points ``poles``
    (K, complex): a (K, n) array, row k as :func:`harmonic_measure` would give for
    ``poles[k]`` (rows of poles outside the polygon or missed by the triangulation are NaN).
    One finite-element mesh holds every pole as a node and one factorisation serves them all,
    so choosing the centre least crowded for a conformal map costs about one estimate."""
    from scipy.sparse.linalg import splu

    w = np.asarray(z, dtype=np.complex128).ravel()
    poles = np.asarray(poles, dtype=np.complex128).ravel()
    poly = shapely.Polygon(np.column_stack([w.real, w.imag]))
    out = np.full((poles.size, w.size), np.nan)
    keep = np.flatnonzero(shapely.contains_xy(poly, poles.real, poles.imag))
    if keep.size == 0:
        return out
    diam = 2.0 * float(np.max(np.abs(w[:, None] - poles[keep][None, :])))
    samples = _boundary_samples(w, diam, per_width)
    bp = samples[0]
    ip = _graded_points(poly, bp, samples[1], diam / 12.0, grade)
    # graded points closer to a pole than a quarter of its distance to the boundary go
    d_b = cKDTree(np.column_stack([bp.real, bp.imag])).query(
        np.column_stack([poles[keep].real, poles[keep].imag])
    )[0]
    hits = cKDTree(np.column_stack([poles[keep].real, poles[keep].imag])).query(
        np.column_stack([ip.real, ip.imag])
    )
    ip = ip[hits[0] >= 0.25 * d_b[hits[1]]]
    P = np.concatenate([bp, ip, poles[keep]])
    A, inner = _laplacian(P, poly, bp.size)
    pos = np.full(P.size, -1)
    pos[inner] = np.arange(inner.size)
    node = pos[bp.size + ip.size + np.arange(keep.size)]
    ok = node >= 0
    if not np.any(ok):
        return out
    rhs = np.zeros((inner.size, int(ok.sum())))
    rhs[node[ok], np.arange(int(ok.sum()))] = 1.0
    with np.errstate(all="ignore"):
        g = splu(A[inner][:, inner].tocsc()).solve(rhs)
    om = _side_measure(A, inner, g, samples, w.size)
    out[keep[ok]] = om
    return out


def _boundary_samples(w: np.ndarray, diam: float, per_width: float):
    """Boundary samples of the polygon ``w`` for the finite-element harmonic measure: spacing at
    most half a side, a ``per_width``-th of the local feature size and a twelfth of ``diam``
    (at most 200 per side). Returns (points, spacing per point, side per point, fraction along
    the side, samples per side, side lengths)."""
    n = w.size
    e = np.roll(w, -1) - w
    L = np.abs(e)
    lfs = _feature_sizes(w, diam)
    hs = np.minimum(np.minimum(L / 2.0, lfs / per_width), diam / 12.0)
    # at most 200 samples per side (a long side beside a narrow feature stays affordable)
    m = np.clip(np.ceil(L / hs - 1e-9).astype(np.int64), 1, 200)
    side = np.repeat(np.arange(n), m)
    first = np.repeat(np.cumsum(m) - m, m)
    frac = (np.arange(side.size) - first) / m[side]
    bp = w[side] + frac * e[side]
    return bp, (L / m)[side], side, frac, m, L


def _laplacian(P: np.ndarray, poly: shapely.Polygon, nb: int):
    """The cotangent Laplacian of a Delaunay triangulation of the nodes ``P`` (the first ``nb``
    on the boundary) restricted to triangles inside ``poly``, and the indices of the interior
    nodes it uses. The Delaunay cotangent Laplacian is an M-matrix."""
    tri = Delaunay(np.column_stack([P.real, P.imag])).simplices
    checkpoint(0.5)
    cen = P[tri].mean(axis=1)
    u = P[tri[:, 1]] - P[tri[:, 0]]
    v = P[tri[:, 2]] - P[tri[:, 0]]
    area2 = (np.conj(u) * v).imag
    h2 = np.max(np.abs(np.stack([u, v, v - u])), axis=0) ** 2
    ok = shapely.contains_xy(poly, cen.real, cen.imag) & (area2 > 1e-10 * h2)
    tri = tri[ok]
    area2 = area2[ok]
    # cotangent Laplacian: edge (a, b) opposite corner o gets cot(o)/2
    rows, cols, vals = [], [], []
    for a, b, o in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        pa, pb, po = P[tri[:, a]], P[tri[:, b]], P[tri[:, o]]
        cot = (np.conj(pa - po) * (pb - po)).real / area2
        rows += [tri[:, a], tri[:, b]]
        cols += [tri[:, b], tri[:, a]]
        vals += [-0.5 * cot, -0.5 * cot]
    N = P.size
    A = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N)
    )
    A = A - sp.diags(np.asarray(A.sum(axis=1)).ravel())
    used = np.zeros(N, bool)
    used[tri.ravel()] = True
    inner = np.flatnonzero(used[nb:]) + nb
    if inner.size == 0:
        raise PolygonError("harmonic measure: the triangulation has no interior node")
    return A, inner


def _side_measure(A, inner: np.ndarray, g: np.ndarray, samples, n: int) -> np.ndarray:
    """Per side, the boundary flux of the discrete Green's functions ``g`` (one per column),
    normalised to sum to 1: a (columns, n) array. A node inside a side belongs to it; a
    vertex node is shared by its two sides in proportion to the adjacent sample spacings."""
    _bp, _bh, side, frac, m, L = samples
    nb = side.size
    flux = np.maximum(-(A[:nb][:, inner] @ g), 0.0)  # (nb, K)
    K = flux.shape[1]
    inside = frac > 0
    vk = side[~inside]
    hn = (L / m)[vk]
    hp = (L / m)[(vk - 1) % n]
    row = (np.arange(K) * n)[:, None]  # bins k·n + side, one block of n per column

    def add(at: np.ndarray, f: np.ndarray) -> np.ndarray:
        return np.bincount((row + at).ravel(), weights=f.ravel(), minlength=K * n)

    fi, fv = flux[inside].T, flux[~inside].T
    om = add(side[inside], fi)
    om += add(vk, fv * hn / (hn + hp))
    om += add((vk - 1) % n, fv * hp / (hn + hp))
    om = om.reshape(K, n)
    total = om.sum(axis=1)
    if not np.all(total > 0):
        raise PolygonError("harmonic measure: no flux reached the boundary")
    return om / total[:, None]
