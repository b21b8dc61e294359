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
relative, not absolute, accuracy.  All searches are *local*: their cost depends on the
hyperbolic distance from 0 and on the number of pieces, never on the size of the tessellation.
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
    "tile_edge_far_arcs",
    "top_point",
]

TWO_PI = 2.0 * math.pi

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
    s1: ArrayLike, l1: ArrayLike, s2: ArrayLike, l2: ArrayLike, rtol: float = 1e-4
) -> NDArray[np.bool_]:
    """True where two arcs are the same I5 arc up to rounding (relative to their length).

    Distinct T5 geodesics never share an endpoint and are a bounded-below hyperbolic distance
    apart when disjoint, so a relative tolerance of 1e-4 cannot confuse two distinct arcs (it
    leaves room for the ~eps/|arc| rounding of arcs of 1e-10 rad near T).
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
    """A growing set of distinct tiles with lookup by tile centre ``g(0)``.

    Centres of distinct tiles are at least ``2·R_M ≈ 1.25`` apart hyperbolically.  Centres are
    binned by ``(level, angle)`` with ``level ≈ 2·log(1−|z|)`` and angular bins proportional to
    ``1−|z|`` (hyperbolic cells of size ~0.5), and by Cartesian bins near 0 (where the angle of
    a centre is meaningless); a lookup checks the neighbouring bins and confirms
    by hyperbolic distance, so deduplication is scale invariant (works for tiles of any size).
    """

    def __init__(self) -> None:
        self.M: list[NDArray[np.complex128]] = []
        self.sigma: list[bool] = []
        self.centers: list[complex] = []
        self._bins: dict[tuple[int, int], list[int]] = {}

    def __len__(self) -> int:
        return len(self.centers)

    _R_SWITCH = 0.6  # Cartesian bins inside this radius, (level, angle) bins outside

    @staticmethod
    def _polar_key(z: complex, lv: int, ai_shift: float = 0.0) -> tuple[int, int]:
        width = math.exp(lv / 2.0) * 0.5
        return lv, math.floor((math.atan2(z.imag, z.real) + ai_shift) / width)

    @staticmethod
    def _level(z: complex) -> float:
        r = abs(z)
        if not r < 1.0 - 4e-16:
            raise DiskConstructionError(
                "a tile is too close to T for double precision: the intervals are too small "
                "(below about 1e-10 rad) for the disk construction"
            )
        return 2.0 * math.log((1.0 - r * r) / (1.0 + r))

    def _own_key(self, z: complex) -> tuple[int, int, int]:
        if abs(z) < self._R_SWITCH:
            return (0, math.floor(z.real * 10.0), math.floor(z.imag * 10.0))
        lv = math.floor(self._level(z))
        return (1, *self._polar_key(z, lv))

    def _keys(self, z: complex) -> list[tuple[int, int, int]]:
        r = abs(z)
        keys: list[tuple[int, int, int]] = []
        if r < self._R_SWITCH + 0.05:
            xi, yi = math.floor(z.real * 10.0), math.floor(z.imag * 10.0)
            keys.extend((0, xi + dx, yi + dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1))
        if r > self._R_SWITCH - 0.05:
            base = math.floor(self._level(z))
            ang = math.atan2(z.imag, z.real)
            for lv in (base - 1, base, base + 1):
                width = math.exp(lv / 2.0) * 0.5
                shifts = [0.0]
                if math.pi - abs(ang) < 4.0 * width:
                    shifts.append(-math.copysign(TWO_PI, ang))
                for sh in shifts:
                    ai = math.floor((ang + sh) / width)
                    keys.extend([(1, lv, ai - 1), (1, lv, ai), (1, lv, ai + 1)])
        return keys

    def find(self, z: complex) -> int:
        """Index of the stored tile whose centre is ``z`` (to 0.3 hyperbolically), or -1."""
        for key in self._keys(z):
            for i in self._bins.get(key, ()):
                c = self.centers[i]
                if abs(c - z) <= 0.3 * abs(1.0 - c.conjugate() * z):
                    return i
        return -1

    def add(self, M: NDArray[np.complex128], sigma: bool, z: complex) -> int:
        """Store a new tile (no duplicate check; use :meth:`find` first) and return its index."""
        i = len(self.centers)
        self.M.append(M)
        self.sigma.append(bool(sigma))
        self.centers.append(z)
        self._bins.setdefault(self._own_key(z), []).append(i)
        return i

    def isometries(self) -> Isometry:
        """All stored tiles as one stacked :class:`Isometry`."""
        if not self.M:
            return Isometry(np.zeros((0, 2, 2), np.complex128), np.zeros(0, bool))
        return Isometry(np.array(self.M), np.array(self.sigma))


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
    seed_c = seeds.apply_rows(np.zeros(1))[:, 0]
    frontier: list[int] = []
    seed_index = np.empty(len(seeds), dtype=np.int64)
    for i in range(len(seeds)):
        t = ts.find(seed_c[i])
        if t < 0:
            t = ts.add(seeds.M[i], bool(seeds.sigma[i]), seed_c[i])
            frontier.append(t)
        seed_index[i] = t
    nbr_rows: dict[int, NDArray[np.int64]] = {}
    lab_rows: dict[int, NDArray[np.int64]] = {}
    while frontier:
        idx = np.array(frontier)
        g = Isometry(np.array([ts.M[i] for i in idx]), np.array([ts.sigma[i] for i in idx]))
        s, ell = tile_edge_far_arcs(g)
        lab = stop(s.ravel(), ell.ravel()).reshape(-1, 5)
        cross = lab < 0
        rows, ks = np.nonzero(cross)
        nb = g[rows] @ REFLECTIONS[ks]
        nc = nb.apply_rows(np.zeros(1))[:, 0]
        new_frontier: list[int] = []
        nbr = np.full((idx.size, 5), -1, dtype=np.int64)
        for j in range(rows.size):
            c = complex(nc[j])
            t = ts.find(c)
            if t < 0:
                t = ts.add(nb.M[j], bool(nb.sigma[j]), c)
                new_frontier.append(t)
            nbr[rows[j], ks[j]] = t
        for r, i in enumerate(idx):
            nbr_rows[int(i)] = nbr[r]
            lab_rows[int(i)] = lab[r]
        frontier = new_frontier
        if len(ts) > max_tiles:
            raise DiskConstructionError(
                f"tile region grew beyond {max_tiles} tiles; the intervals are too close "
                "together or too small for the construction"
            )
    n = len(ts)
    neighbour = np.array([nbr_rows[i] for i in range(n)]).reshape(n, 5)
    label = np.array([lab_rows[i] for i in range(n)]).reshape(n, 5)
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
    frontier = [0]
    level = 0
    nbrs: dict[int, NDArray[np.int64]] = {}
    while frontier:
        idx = np.array(frontier)
        g = Isometry(np.array([ts.M[i] for i in idx]), np.array([ts.sigma[i] for i in idx]))
        allowed = np.ones(idx.size, dtype=bool)
        if depth is not None and level >= depth:
            allowed[:] = False
        if min_diameter is not None:
            v = g.apply_rows(P0_VERTICES)
            diam = np.max(np.abs(v[:, :, None] - v[:, None, :]), axis=(1, 2))
            allowed &= diam >= min_diameter
        rows = np.repeat(np.nonzero(allowed)[0], 5)
        ks = np.tile(np.arange(5), int(allowed.sum()))
        new: list[int] = []
        nbr = np.full((idx.size, 5), -1, dtype=np.int64)
        if rows.size:
            nb = g[rows] @ REFLECTIONS[ks]
            nc = nb.apply_rows(np.zeros(1))[:, 0]
            for j in range(rows.size):
                c = complex(nc[j])
                t = ts.find(c)
                if t < 0:
                    t = ts.add(nb.M[j], bool(nb.sigma[j]), c)
                    new.append(t)
                nbr[rows[j], ks[j]] = t
        for r, i in enumerate(idx):
            nbrs[int(i)] = nbr[r]
        frontier = new
        level += 1
    n = len(ts)
    return ts.isometries(), np.array([nbrs[i] for i in range(n)]).reshape(n, 5)


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


def minimal_containing_arc(
    start: ArrayLike, length: ArrayLike, step: float = 0.2, chunk: float = 4.0
) -> tuple[NDArray[np.float64], NDArray[np.float64], Isometry, NDArray[np.int64]]:
    """Minimal-length I5 arc containing each given arc (Lemma 2.1 / proof of Lemma 2.2).

    Local search: any I5 arc shorter than π that contains J has its geodesic crossing the
    hyperbolic segment from the top point of J's geodesic to 0.  The segment is sampled every
    ``step`` (hyperbolic); every crossing point is within ``step/2`` of a sample, hence lies in
    the sample's tile or one of the 10 tiles touching it, and the crossing geodesic carries an
    edge of that tile.  The candidates are the edges of those tiles.  Sampling proceeds upward
    in chunks and stops once the shortest arc of any geodesic through the next sample exceeds
    the best arc found, so the cost is O(log(1/best/|J|)) tiles per arc, independent of |J|.

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
    best_s = np.full(n, np.nan)
    best_l = np.full(n, np.inf)
    best_M = np.zeros((n, 2, 2), np.complex128)
    best_sig = np.zeros(n, bool)
    best_k = np.full(n, -1, np.int64)
    todo = np.arange(n)
    t0 = 0.0
    while todo.size:
        ts = np.arange(t0, t0 + chunk, step)
        dist = np.clip(dtop[todo, None] - ts[None, :], 0.0, None)  # distance of samples from 0
        pts = u[todo, None] * np.tanh(dist / 2.0)
        g = locate(pts.ravel())
        cand = g[np.repeat(np.arange(len(g)), 11)] @ GROUP11[np.tile(np.arange(11), len(g))]
        cs, cl = tile_edge_far_arcs(cand)  # (P*11, 5)
        owner = np.repeat(todo, ts.size * 11)
        ok = arc_contains_arc(cs, cl, s[owner, None], ell[owner, None]) & (cl < math.pi)
        score = np.where(ok, cl, np.inf).reshape(todo.size, -1)
        j = np.argmin(score, axis=1)
        val = score[np.arange(todo.size), j]
        better = val < best_l[todo]
        if np.any(better):
            w = todo[better]
            jb = j[better]
            flat = np.arange(todo.size)[better] * (ts.size * 55) + jb
            tile_i, kk = np.divmod(flat, 5)
            best_l[w] = val[better]
            best_s[w] = cs.ravel()[flat]
            best_M[w] = cand.M[tile_i]
            best_sig[w] = cand.sigma[tile_i]
            best_k[w] = kk
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
    return best_s, best_l, Isometry(best_M, best_sig), best_k
