"""The right-pentagon tessellation T5 and its arc family I5 (paper §3, Lemma 2.1; DISK.md §2).

A tile is stored as the isometry ``g`` with ``tile = g(P0)``, where ``P0`` is the regular right
pentagon centred at 0 with vertices ``V_k = R·e^{2πik/5}``.  The neighbour of tile ``g`` across
its edge ``k`` is ``g∘σ_k`` (``σ_k`` = reflection in P0's edge ``k``), and the reflection group acts
simply transitively on tiles, so every tile has exactly one isometry.

Arcs of the unit circle T are ``(start angle, counter-clockwise length)`` in radians.  For every
edge ``k`` of a tile ``g`` the *far arc* is the arc of T cut off by the edge's geodesic on the side
that does not contain the tile; I5 is the set of all far arcs and their complements.

Everything that can be is done in the canonical frame of P0 and moved by the tile isometries,
so that tiny tiles near T (intervals of 1e-8 rad and less from conformal maps) are handled with
relative, not absolute, accuracy as far as float64 disk coordinates allow: a tile of Euclidean
size ``s`` is a product of ~log(1/s) reflections with entries ~``s^{-1/2}``, so its vertices carry
relative errors ~30·eps/s (see ``POSITION_RTOL`` and ``region.MIN_EXPANDED_ARC``).  All searches
are *local*: their cost depends on the hyperbolic distance from 0 and on the number of pieces,
never on the size of the tessellation.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DiskConstructionError
from ..hyperbolic import Isometry

__all__ = [
    "EDGE_CENTERS",
    "EDGE_FAR_END",
    "EDGE_FAR_START",
    "EDGE_MIDPOINTS",
    "EDGE_RADIUS",
    "GROUP11",
    "P0_VERTICES",
    "POSITION_RTOL",
    "REFLECTIONS",
    "TWO_PI",
    "L",
    "TileSet",
    "arc_contains_arc",
    "arc_contains_point",
    "arcs_match",
    "brute_force_i5_arcs",
    "generate_tiles",
    "grow_tiles",
    "locate",
    "minimal_containing_arc",
    "one_minus_abs2",
    "phi_accurate",
    "tile_edge_far_arcs",
    "top_point",
]

TWO_PI = 2.0 * math.pi

POSITION_RTOL = 1e-3
"""Relative tolerance of the consistency checks between positions computed twice (relative to
the local scale ``1−|z|``).  Tile isometries are products of ~log(1/s) reflections with entries
~``s^{-1/2}`` for tiles of Euclidean size ``s``, so their vertices carry relative errors of about
``30·eps/s`` — 3e-4 at ``s = 1e-11``; a mismatch of the pieces would be of order 1."""

L: float = math.acosh(1.0 + 2.0 * math.cos(2.0 * math.pi / 5.0))
"""Side length of the right regular pentagon, ``arccosh(1+2cos(2π/5)) = 1.0612750619``."""

_RV = math.acosh(1.0 / math.tan(math.pi / 5.0))  # centre-vertex distance: cosh R_V = cot(π/5)
_RM = math.acosh(math.cos(math.pi / 4.0) / math.sin(math.pi / 5.0))  # centre-edge midpoint
_EV = math.tanh(_RV / 2.0)  # Euclidean radius of the vertices, 0.397975
_EM = math.tanh(_RM / 2.0)  # Euclidean radius of the edge midpoints, 0.303559

_K = np.arange(5)
P0_VERTICES: NDArray[np.complex128] = _EV * np.exp(2j * np.pi * _K / 5.0)
"""Vertices ``V_k`` of the central pentagon P0 (edge ``k`` runs from ``V_k`` to ``V_{k+1}``)."""
_DIR = np.exp(1j * (2.0 * np.pi * _K / 5.0 + np.pi / 5.0))
EDGE_MIDPOINTS: NDArray[np.complex128] = _EM * _DIR
"""Hyperbolic midpoints of P0's edges."""
EDGE_CENTERS: NDArray[np.complex128] = (1.0 + _EM**2) / (2.0 * _EM) * _DIR
"""Euclidean centres of the circles carrying P0's edges."""
EDGE_RADIUS: float = float(math.sqrt(abs(EDGE_CENTERS[0]) ** 2 - 1.0))
"""Common Euclidean radius of those circles."""
_HALF = math.acos(1.0 / abs(EDGE_CENTERS[0]))  # angular half-width of an edge's far arc
EDGE_FAR_START: NDArray[np.complex128] = _DIR * np.exp(-1j * _HALF)
"""Ideal endpoint of edge ``k``'s geodesic where its far arc (side away from P0) starts (CCW)."""
EDGE_FAR_END: NDArray[np.complex128] = _DIR * np.exp(1j * _HALF)
"""Ideal endpoint where edge ``k``'s far arc ends."""

_RM_MAT = np.empty((5, 2, 2), dtype=np.complex128)
_RM_MAT[:, 0, 0] = EDGE_CENTERS
_RM_MAT[:, 0, 1] = EDGE_RADIUS**2 - np.abs(EDGE_CENTERS) ** 2
_RM_MAT[:, 1, 0] = 1.0
_RM_MAT[:, 1, 1] = -np.conj(EDGE_CENTERS)
_RM_MAT /= np.sqrt(_RM_MAT[:, 0, 0] * _RM_MAT[:, 1, 1] - _RM_MAT[:, 0, 1] * _RM_MAT[:, 1, 0])[
    :, None, None
]
REFLECTIONS = Isometry(_RM_MAT, np.ones(5, dtype=bool))
"""Stack of the 5 reflections ``σ_k`` in the edges of P0 (orientation reversing)."""

_G11 = [Isometry.identity()] + [REFLECTIONS[k] for k in range(5)]
_G11 += [REFLECTIONS[k] @ REFLECTIONS[(k + 1) % 5] for k in range(5)]
GROUP11 = Isometry.stack(_G11)
"""P0 and the 10 tiles touching it (5 across edges, 5 sharing only the vertex ``V_{k+1}``)."""


# --------------------------------------------------------------------------- arcs
def arc_contains_point(start: ArrayLike, length: ArrayLike, x: ArrayLike) -> NDArray[np.bool_]:
    """True where the open arc ``(start, length)`` contains the angle ``x`` (broadcast)."""
    rel = np.mod(np.asarray(x, float) - np.asarray(start, float), TWO_PI)
    return (rel > 0.0) & (rel < np.asarray(length, float))


def arc_contains_arc(
    start: ArrayLike, length: ArrayLike, s: ArrayLike, ell: ArrayLike
) -> NDArray[np.bool_]:
    """True where the closed arc ``(s, ell)`` lies inside the closed arc ``(start, length)``."""
    rel = np.mod(np.asarray(s, float) - np.asarray(start, float), TWO_PI)
    return rel + np.asarray(ell, float) <= np.asarray(length, float)


def arcs_match(
    s1: ArrayLike, l1: ArrayLike, s2: ArrayLike, l2: ArrayLike, rtol: float = 1e-3
) -> NDArray[np.bool_]:
    """True where two arcs are the same I5 arc up to rounding (relative to their length).

    Distinct T5 geodesics never share an endpoint and are a bounded-below hyperbolic distance
    apart when disjoint, so a relative tolerance of 1e-3 cannot confuse two distinct arcs (it
    leaves room for the ~30·eps/|arc| rounding of arcs of 1e-11 rad near T).
    """
    s1, l1, s2, l2 = (np.asarray(a, float) for a in (s1, l1, s2, l2))
    ds = np.mod(s1 - s2 + math.pi, TWO_PI) - math.pi
    tol = np.maximum(rtol * np.minimum(l1, l2), 4e-15)
    return (np.abs(ds) <= tol) & (np.abs(l1 - l2) <= tol)


def top_point(start: ArrayLike, length: ArrayLike) -> NDArray[np.complex128]:
    """Top point (point nearest 0) of the geodesic spanning the arc ``(start, length)``.

    Computed from angles, ``e^{i(s+ℓ/2)}·tan(π/4 − ℓ/4)``, so that ``1−|z| ≈ ℓ/2`` keeps full
    relative accuracy for tiny arcs.  For arcs longer than π this is the point nearest 0 on the
    geodesic measured on the arc's side (it lies on the far side of 0).
    """
    s = np.asarray(start, float)
    ell = np.asarray(length, float)
    return np.exp(1j * (s + ell / 2.0)) * np.tan(math.pi / 4.0 - ell / 4.0)


def _angle(z: NDArray[np.complex128]) -> NDArray[np.float64]:
    return np.mod(np.angle(z), TWO_PI)


def tile_edge_far_arcs(
    tiles: Isometry,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Far arcs of the 5 edges of each tile in a stack: ``(start, length)`` arrays of shape (k, 5).

    The far arc of edge ``k`` of tile ``g`` is ``g`` of P0's far arc; an orientation-reversing
    ``g`` swaps its ends.
    """
    a = tiles.apply_rows(EDGE_FAR_START)
    b = tiles.apply_rows(EDGE_FAR_END)
    rev = tiles.sigma[:, None]
    first = np.where(rev, b, a)
    last = np.where(rev, a, b)
    s = _angle(first)
    ell = np.mod(_angle(last) - s, TWO_PI)
    return s, ell


def _two_square(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``x² = hi + lo`` exactly (Dekker's splitting; no FMA needed)."""
    hi = x * x
    c = 134217729.0 * x  # 2^27 + 1
    xh = c - (c - x)
    xl = x - xh
    lo = ((xh * xh - hi) + 2.0 * xh * xl) + xl * xl
    return hi, lo


def one_minus_abs2(a: ArrayLike) -> NDArray[np.float64]:
    """``1 − |a|²`` with full relative accuracy also for points very close to T.

    The naive ``1 − (x² + y²)`` loses ``log10(1/(1−|a|))`` digits; here the squares are split
    into exact double-double parts and the large one is subtracted from 1 first (exact by
    Sterbenz's lemma), so the result is correct to a few ulps *of itself*.
    """
    a = np.asarray(a, dtype=np.complex128)
    x, y = np.abs(a.real), np.abs(a.imag)
    big, small = np.maximum(x, y), np.minimum(x, y)
    bh, bl = _two_square(big)
    sh, sl = _two_square(small)
    return ((1.0 - bh) - sh) - (bl + sl)


def phi_accurate(a: ArrayLike, z: ArrayLike) -> NDArray[np.complex128]:
    """``φ_a(z) = (z − a)/(1 − āz)`` for ``a`` and ``z`` both near T and near each other.

    The denominator is evaluated as ``(1 − |a|²) + ā(a − z)``: ``a − z`` is exact for nearby
    points and ``1 − |a|²`` is computed with :func:`one_minus_abs2`, so the frame map of a tiny
    piece near T keeps relative accuracy (the naive form loses it all at ``1−|a| ≈ 1e-12``).
    """
    a = np.asarray(a, dtype=np.complex128)
    z = np.asarray(z, dtype=np.complex128)
    d = a - z
    return -d / (one_minus_abs2(a) + np.conj(a) * d)


# --------------------------------------------------------------------------- point location
def locate(z: ArrayLike, max_steps: int = 400) -> Isometry:
    """Tiles containing the points ``z`` (1-d array, |z| < 1), as a stack of isometries.

    Starting from the identity, reflect across the most violated edge of P0 in the current
    frame until ``g⁻¹(z)`` lies in P0 (DISK.md §2, "point location"); the number of steps is
    proportional to the hyperbolic distance of ``z`` from 0.  Vectorised over the points.
    """
    z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
    if np.any(~np.isfinite(z)) or np.any(np.abs(z) >= 1.0):
        raise DiskConstructionError("point location needs points inside the unit disk")
    g = Isometry.identity(z.shape[0])
    M, sig = g.M.copy(), g.sigma.copy()
    active = np.arange(z.shape[0])
    for _ in range(max_steps):
        if active.size == 0:
            break
        ga = Isometry(M[active], sig[active])
        w = ga.inverse().apply_rows(z[active][:, None])[:, 0]
        viol = EDGE_RADIUS - np.abs(w[:, None] - EDGE_CENTERS[None, :])
        k = np.argmax(viol, axis=1)
        move = viol[np.arange(active.size), k] > 1e-13
        if not np.any(move):
            break
        idx = active[move]
        step = Isometry(M[idx], sig[idx]) @ REFLECTIONS[k[move]]
        M[idx] = step.M
        sig[idx] = step.sigma
        active = idx
    else:
        raise DiskConstructionError("point location did not converge (point too close to T)")
    return Isometry(M, sig)


# --------------------------------------------------------------------------- tile sets
class TileSet:
    """A growing set of distinct tiles with vectorised lookup by tile centre ``g(0)``.

    Centres of distinct tiles are at least ``2·R_M ≈ 1.25`` apart hyperbolically.  Centres are
    binned by ``(level, angle)`` with ``level ≈ 2·log(1−|z|)`` and angular bins proportional to
    ``1−|z|`` (hyperbolic cells of size ~0.5), and by Cartesian bins near 0 (where the angle of
    a centre is meaningless); a lookup checks the neighbouring bins and confirms by hyperbolic
    distance, so deduplication is scale invariant (works for tiles of any size).  Bins are
    encoded as int64 keys held in a sorted array, and :meth:`add_batch` deduplicates a whole
    batch of candidate tiles (against the stored ones and among themselves) with numpy.
    """

    _R_SWITCH = 0.6  # Cartesian bins inside this radius, (level, angle) bins outside
    _CART = np.int64(127) << np.int64(56)  # key prefix of the Cartesian bins
    _AI_OFF = np.int64(1) << np.int64(55)  # offset making angular bin numbers non-negative

    def __init__(self) -> None:
        self._M = np.zeros((0, 2, 2), dtype=np.complex128)
        self._sigma = np.zeros(0, dtype=bool)
        self._centers = np.zeros(0, dtype=np.complex128)
        self._keys_sorted = np.zeros(0, dtype=np.int64)
        self._key_owner = np.zeros(0, dtype=np.int64)

    def __len__(self) -> int:
        return int(self._centers.size)

    @property
    def centers(self) -> NDArray[np.complex128]:
        """Stored tile centres ``g(0)`` in insertion order."""
        return self._centers

    @staticmethod
    def _level(z: NDArray[np.complex128]) -> NDArray[np.float64]:
        r = np.abs(z)
        if np.any(~(r < 1.0 - 4e-16)):
            raise DiskConstructionError(
                "a tile is too close to T for double precision: the intervals are too small "
                "for the disk construction"
            )
        return 2.0 * np.log((1.0 - r * r) / (1.0 + r))

    @classmethod
    def _polar(cls, lv: NDArray[np.int64], ai: NDArray[np.int64]) -> NDArray[np.int64]:
        return ((lv + 100) << np.int64(56)) + ai + cls._AI_OFF

    @classmethod
    def _cart(cls, xi: NDArray[np.int64], yi: NDArray[np.int64]) -> NDArray[np.int64]:
        return cls._CART + (xi + 64) * 256 + (yi + 64)

    @classmethod
    def _own_keys(cls, z: NDArray[np.complex128]) -> NDArray[np.int64]:
        out = np.empty(z.shape, dtype=np.int64)
        near = np.abs(z) < cls._R_SWITCH
        zn = z[near]
        out[near] = cls._cart(
            np.floor(zn.real * 10.0).astype(np.int64), np.floor(zn.imag * 10.0).astype(np.int64)
        )
        zf = z[~near]
        lv = np.floor(cls._level(zf))
        width = np.exp(lv / 2.0) * 0.5
        out[~near] = cls._polar(
            lv.astype(np.int64), np.floor(np.angle(zf) / width).astype(np.int64)
        )
        return out

    @classmethod
    def _query_keys(cls, z: NDArray[np.complex128]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """All bins a match of each point can lie in: ``(point index, key)`` pairs."""
        r = np.abs(z)
        pts: list[NDArray[np.int64]] = []
        keys: list[NDArray[np.int64]] = []
        near = np.flatnonzero(r < cls._R_SWITCH + 0.05)
        if near.size:
            xi = np.floor(z[near].real * 10.0).astype(np.int64)
            yi = np.floor(z[near].imag * 10.0).astype(np.int64)
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    pts.append(near)
                    keys.append(cls._cart(xi + dx, yi + dy))
        far = np.flatnonzero(r > cls._R_SWITCH - 0.05)
        if far.size:
            zf = z[far]
            base = np.floor(cls._level(zf)).astype(np.int64)
            ang = np.angle(zf)
            for dl in (-1, 0, 1):
                lv = base + dl
                width = np.exp(lv / 2.0) * 0.5
                wrap = math.pi - np.abs(ang) < 4.0 * width
                for sh, sel in ((0.0, slice(None)), (None, wrap)):
                    idx = far[sel]
                    if idx.size == 0:
                        continue
                    a = ang[sel]
                    shift = 0.0 if sh is not None else -np.copysign(TWO_PI, a)
                    ai = np.floor((a + shift) / width[sel]).astype(np.int64)
                    for da in (-1, 0, 1):
                        pts.append(idx)
                        keys.append(cls._polar(lv[sel], ai + da))
        if not pts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(pts), np.concatenate(keys)

    @staticmethod
    def _close(c: NDArray[np.complex128], z: NDArray[np.complex128]) -> NDArray[np.bool_]:
        """Hyperbolic distance below ``2·artanh(0.3)``: the same tile."""
        return np.abs(c - z) <= 0.3 * np.abs(1.0 - np.conj(c) * z)

    @staticmethod
    def _pairs(
        sorted_keys: NDArray[np.int64], qpt: NDArray[np.int64], qkey: NDArray[np.int64]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Pairs (query point, position in ``sorted_keys``) with equal keys."""
        lo = np.searchsorted(sorted_keys, qkey, side="left")
        hi = np.searchsorted(sorted_keys, qkey, side="right")
        cnt = hi - lo
        qp = np.repeat(qpt, cnt)
        first = np.repeat(lo, cnt)
        within = np.arange(qp.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        return qp, first + within

    def lookup(self, z: ArrayLike) -> NDArray[np.int64]:
        """Index of the stored tile with centre ``z`` (to 0.3 hyperbolically) for each point,
        or -1 (vectorised)."""
        z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
        out = np.full(z.shape, -1, dtype=np.int64)
        if z.size == 0 or len(self) == 0:
            return out
        qpt, qkey = self._query_keys(z)
        qp, pos = self._pairs(self._keys_sorted, qpt, qkey)
        cand = self._key_owner[pos]
        ok = self._close(self._centers[cand], z[qp])
        qp, cand = qp[ok], cand[ok]
        # several candidates (only possible for numerically dubious input): take the smallest
        o = np.lexsort((cand, qp))
        qp, cand = qp[o], cand[o]
        first = np.ones(qp.size, dtype=bool)
        first[1:] = qp[1:] != qp[:-1]
        out[qp[first]] = cand[first]
        return out

    def find(self, z: complex) -> int:
        """Index of the stored tile whose centre is ``z`` (to 0.3 hyperbolically), or -1."""
        return int(self.lookup(np.array([z]))[0])

    def _append(self, M: NDArray, sigma: NDArray, z: NDArray) -> NDArray[np.int64]:
        n0 = len(self)
        idx = n0 + np.arange(z.size, dtype=np.int64)
        self._M = np.concatenate([self._M, np.asarray(M, np.complex128).reshape(-1, 2, 2)])
        self._sigma = np.concatenate([self._sigma, np.asarray(sigma, bool).reshape(-1)])
        self._centers = np.concatenate([self._centers, z])
        keys = np.concatenate([self._keys_sorted, self._own_keys(z)])
        owner = np.concatenate([self._key_owner, idx])
        o = np.argsort(keys, kind="stable")
        self._keys_sorted, self._key_owner = keys[o], owner[o]
        return idx

    def add(self, M: NDArray[np.complex128], sigma: bool, z: complex) -> int:
        """Store a new tile (no duplicate check; use :meth:`find` first) and return its index."""
        return int(self._append(M[None], np.array([sigma]), np.array([z], np.complex128))[0])

    def add_batch(
        self, M: NDArray[np.complex128], sigma: NDArray[np.bool_], z: NDArray[np.complex128]
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Insert a batch of tiles with centres ``z``, skipping the ones already stored and the
        repeats within the batch (the first occurrence wins, as in a sequential loop).

        Returns ``(index, new)``: the tile index of every batch entry and whether it was added.
        """
        z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
        k = z.size
        index = self.lookup(z)
        todo = np.flatnonzero(index < 0)
        new = np.zeros(k, dtype=bool)
        if todo.size == 0:
            return index, new
        zt = z[todo]
        # dedup within the batch: representative = smallest batch position among equals
        own = self._own_keys(zt)
        o = np.argsort(own, kind="stable")
        qpt, qkey = self._query_keys(zt)
        qp, pos = self._pairs(own[o], qpt, qkey)
        other = o[pos]
        ok = (other < qp) & self._close(zt[other], zt[qp])
        rep = np.arange(todo.size)
        np.minimum.at(rep, qp[ok], other[ok])
        rep = rep[rep]  # near-identical duplicates: one hop reaches the first occurrence
        is_first = rep == np.arange(todo.size)
        firsts = np.flatnonzero(is_first)
        ids = self._append(M[todo[firsts]], sigma[todo[firsts]], zt[firsts])
        slot = np.full(todo.size, -1, dtype=np.int64)
        slot[firsts] = ids
        index[todo] = slot[rep]
        new[todo[firsts]] = True
        return index, new

    def isometries(self) -> Isometry:
        """All stored tiles as one stacked :class:`Isometry`."""
        return Isometry(self._M.copy(), self._sigma.copy())


def _add_tiles(ts: TileSet, g: Isometry) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Store the tiles ``g`` (stacked) in ``ts`` keyed by their centres ``g(0)``; returns
    :meth:`TileSet.add_batch`'s ``(index, new)``."""
    return ts.add_batch(g.M, g.sigma, g.apply_rows(np.zeros(1))[:, 0])


def _reflect_across_edges(
    ts: TileSet, g: Isometry, rows: NDArray[np.int64], ks: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Reflect tile ``g[rows[i]]`` across its edge ``ks[i]`` (the neighbour across that edge of
    the T5 tessellation, §2) and store the images in ``ts``.

    Returns ``neighbour`` (len(g), 5): the tile index across each reflected edge, -1 elsewhere;
    and the indices of the tiles that were new.
    """
    nbr = np.full((len(g), 5), -1, dtype=np.int64)
    if rows.size == 0:
        return nbr, np.zeros(0, dtype=np.int64)
    t, is_new = _add_tiles(ts, g[rows] @ REFLECTIONS[ks])
    nbr[rows, ks] = t
    return nbr, t[is_new]


StopRule = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.int64]]


def grow_tiles(
    seeds: Isometry, stop: StopRule, max_tiles: int = 2_000_000
) -> tuple[Isometry, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Breadth-first growth of a region of tiles by reflection (DISK.md §2 "Generation").

    ``stop(start, length)`` receives the far arcs of a batch of edges and returns, per edge, a
    label ``>= 0`` if the growth must not cross that edge (the label is recorded) and ``-1``
    if it may.  Returns the tiles (stacked isometries), ``neighbour`` (T, 5): the index of the
    tile across each edge or -1, ``label`` (T, 5): the stop label of each edge or -1, and
    ``seed_index`` (len(seeds),): the tile index of every seed.
    """
    ts = TileSet()
    seed_index, is_new = _add_tiles(ts, seeds)
    frontier = np.unique(seed_index[is_new])
    nbr_rows: list[NDArray[np.int64]] = []
    lab_rows: list[NDArray[np.int64]] = []
    row_of: list[NDArray[np.int64]] = []
    while frontier.size:
        g = Isometry(ts._M[frontier], ts._sigma[frontier])
        s, ell = tile_edge_far_arcs(g)
        lab = stop(s.ravel(), ell.ravel()).reshape(-1, 5)
        rows, ks = np.nonzero(lab < 0)
        nbr, new_frontier = _reflect_across_edges(ts, g, rows, ks)
        nbr_rows.append(nbr)
        lab_rows.append(lab)
        row_of.append(frontier)
        frontier = new_frontier
        if len(ts) > max_tiles:
            raise DiskConstructionError(
                f"tile region grew beyond {max_tiles} tiles; the intervals are too close "
                "together or too small for the construction"
            )
    n = len(ts)
    neighbour = np.empty((n, 5), dtype=np.int64)
    label = np.empty((n, 5), dtype=np.int64)
    rows_all = np.concatenate(row_of)
    neighbour[rows_all] = np.concatenate(nbr_rows)
    label[rows_all] = np.concatenate(lab_rows)
    return ts.isometries(), neighbour, label, seed_index


def generate_tiles(
    depth: int | None = None, min_diameter: float | None = None
) -> tuple[Isometry, NDArray[np.int64]]:
    """Global T5 generation (for tests and pictures): all tiles within ``depth`` reflections of
    P0 and/or of Euclidean diameter at least ``min_diameter``.  Returns tiles and neighbours.
    """
    if depth is None and min_diameter is None:
        raise ValueError("give depth or min_diameter")
    ts = TileSet()
    ts.add(np.eye(2, dtype=np.complex128), False, 0j)
    frontier = np.zeros(1, dtype=np.int64)
    level = 0
    nbr_rows: list[NDArray[np.int64]] = []
    row_of: list[NDArray[np.int64]] = []
    while frontier.size:
        g = Isometry(ts._M[frontier], ts._sigma[frontier])
        allowed = np.ones(frontier.size, dtype=bool)
        if depth is not None and level >= depth:
            allowed[:] = False
        if min_diameter is not None:
            v = g.apply_rows(P0_VERTICES)
            diam = np.max(np.abs(v[:, :, None] - v[:, None, :]), axis=(1, 2))
            allowed &= diam >= min_diameter
        rows = np.repeat(np.nonzero(allowed)[0], 5)
        ks = np.tile(np.arange(5), int(allowed.sum()))
        nbr, new = _reflect_across_edges(ts, g, rows, ks)
        nbr_rows.append(nbr)
        row_of.append(frontier)
        frontier = new
        level += 1
    n = len(ts)
    neighbour = np.empty((n, 5), dtype=np.int64)
    neighbour[np.concatenate(row_of)] = np.concatenate(nbr_rows)
    return ts.isometries(), neighbour


def brute_force_i5_arcs(tiles: Isometry) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """All distinct I5 arcs (both sides of every distinct edge geodesic) of a tile set."""
    s, ell = tile_edge_far_arcs(tiles)
    s, ell = s.ravel(), ell.ravel()
    key = np.round(np.stack([s, np.mod(s + ell, TWO_PI)], axis=1) * 1e10)
    key.sort(axis=1)
    _, first = np.unique(key, axis=0, return_index=True)
    s, ell = s[first], ell[first]
    return np.concatenate([s, np.mod(s + ell, TWO_PI)]), np.concatenate([ell, TWO_PI - ell])


# --------------------------------------------------------------------------- Lemma 2.1
def _min_arc_through_radius(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Shortest arc of a geodesic passing through a point of modulus ``r``: 2θ with
    ``tan(π/4 − θ/2) = r``."""
    return 2.0 * (math.pi / 2.0 - 2.0 * np.arctan(r))


def _group11_geodesics() -> tuple[
    NDArray[np.complex128], NDArray[np.complex128], NDArray[np.int64], NDArray[np.int64]
]:
    """The distinct edge geodesics of the 11 tiles of GROUP11, in P0's frame.

    Returns ``(start, end, tile, edge)``: for every distinct geodesic the ideal endpoints where
    the far arc of ``(GROUP11[tile], edge)`` starts and ends (counter-clockwise).  The opposite
    arc is the far arc of the same edge of the tile ``GROUP11[tile]∘σ_edge``.
    """
    a = GROUP11.apply_rows(EDGE_FAR_START)
    b = GROUP11.apply_rows(EDGE_FAR_END)
    rev = GROUP11.sigma[:, None]
    first = np.where(rev, b, a).ravel()
    last = np.where(rev, a, b).ravel()
    key = np.round(np.sort(np.stack([_angle(first), _angle(last)], axis=1), axis=1) * 1e9)
    _, idx = np.unique(key, axis=0, return_index=True)
    idx = np.sort(idx)
    return first[idx], last[idx], idx // 5, idx % 5


_G11_START, _G11_END, _G11_TILE, _G11_EDGE = _group11_geodesics()


def minimal_containing_arc(
    start: ArrayLike, length: ArrayLike, step: float = 0.5, chunk: float = 4.0
) -> tuple[NDArray[np.float64], NDArray[np.float64], Isometry, NDArray[np.int64]]:
    """Minimal-length I5 arc containing each given arc (Lemma 2.1 / proof of Lemma 2.2).

    Local search: any I5 arc shorter than π that contains J has its geodesic crossing the
    hyperbolic segment from the top point of J's geodesic to 0.  The segment is sampled every
    ``step`` (hyperbolic); every crossing point is within ``step/2`` of a sample, hence lies in
    the sample's tile or one of the 10 tiles touching it (these cover the 0.6-neighbourhood of
    the tile: checked on 20000 random points, so ``step`` up to 1.2 is safe; default 0.5), and
    the crossing geodesic carries an edge of that tile.  The candidates are both arcs of every
    edge geodesic of those 11 tiles (the 20 distinct geodesics of GROUP11 are tabulated once in
    P0's frame, so a sample costs only the images of their endpoints).  Sampling proceeds
    upward in chunks and stops once the shortest arc of any geodesic through the next sample
    exceeds the best arc found, so the cost is O(log(1/best/|J|)) tiles per arc, independent
    of |J|.

    Returns ``(start, length, tile, edge)``: the minimal arcs and the tile/edge carrying their
    geodesic on the tile's far side.  Raises :class:`DiskConstructionError` if no I5 arc
    shorter than π contains J.
    """
    s = np.atleast_1d(np.asarray(start, float))
    ell = np.atleast_1d(np.asarray(length, float))
    n = s.size
    top = top_point(s, ell)
    dtop = 2.0 * np.arctanh(np.abs(top))
    u = np.exp(1j * (s + ell / 2.0))
    ng = _G11_START.size
    best_s = np.full(n, np.nan)
    best_l = np.full(n, np.inf)
    best_M = np.zeros((n, 2, 2), np.complex128)
    best_sig = np.zeros(n, bool)
    best_c = np.zeros(n, np.int64)  # candidate index: geodesic * 2 + (1 for the opposite arc)
    todo = np.arange(n)
    t0 = 0.0
    while todo.size:
        ts = np.arange(t0, t0 + chunk, step)
        dist = np.clip(dtop[todo, None] - ts[None, :], 0.0, None)  # distance of samples from 0
        pts = u[todo, None] * np.tanh(dist / 2.0)
        g = locate(pts.ravel())
        a = g.apply_rows(_G11_START)  # (P, ng)
        b = g.apply_rows(_G11_END)
        rev = g.sigma[:, None]
        fa = _angle(np.where(rev, b, a))  # far arc of the group tile's edge: fa -> fb
        fb = _angle(np.where(rev, a, b))
        far_l = np.mod(fb - fa, TWO_PI)
        cs = np.stack([fa, fb], axis=2).reshape(len(g), -1)  # (P, 2·ng): far arc, opposite
        cl = np.stack([far_l, TWO_PI - far_l], axis=2).reshape(len(g), -1)
        owner = np.repeat(todo, ts.size)
        ok = arc_contains_arc(cs, cl, s[owner, None], ell[owner, None]) & (cl < math.pi)
        score = np.where(ok, cl, np.inf).reshape(todo.size, -1)
        j = np.argmin(score, axis=1)
        val = score[np.arange(todo.size), j]
        better = val < best_l[todo]
        if np.any(better):
            w = todo[better]
            sample, cand = np.divmod(
                np.arange(todo.size)[better] * (ts.size * 2 * ng) + j[better], 2 * ng
            )
            best_l[w] = val[better]
            best_s[w] = cs[sample, cand]
            best_M[w] = g.M[sample]
            best_sig[w] = g.sigma[sample]
            best_c[w] = cand
        # stop where even the shortest geodesic through the next sample is no better
        nxt = np.tanh(np.clip(dtop[todo] - (t0 + chunk), 0.0, None) / 2.0)
        done = (_min_arc_through_radius(nxt) >= best_l[todo]) | (dtop[todo] - t0 - chunk <= 0)
        todo = todo[~done]
        t0 += chunk
    if np.any(~np.isfinite(best_l)):
        bad = int(np.nonzero(~np.isfinite(best_l))[0][0])
        raise DiskConstructionError(
            f"no arc of I5 shorter than π contains arc {bad} (length {ell[bad]:.3g} rad); "
            "the expansion factor A is too large for this interval"
        )
    geo, opposite = np.divmod(best_c, 2)
    k = _G11_EDGE[geo]
    tile = Isometry(best_M, best_sig) @ GROUP11[_G11_TILE[geo]]
    if np.any(opposite == 1):
        o = opposite == 1
        flipped = tile[np.flatnonzero(o)] @ REFLECTIONS[k[o]]
        M = tile.M.copy()
        sig = tile.sigma.copy()
        M[o] = flipped.M
        sig[o] = flipped.sigma
        tile = Isometry(M, sig)
    return best_s, best_l, tile, k
