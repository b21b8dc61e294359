"""The right-pentagon tessellation T5 and its arc family I5 (paper §3, Lemma 2.1).

A tile is stored as the isometry ``g`` with ``tile = g(P0)``, where ``P0`` is the regular right
pentagon centred at 0 with vertices ``V_k = R·e^{2πik/5}``.  The neighbour of tile ``g`` across
its edge ``k`` is ``g∘σ_k`` (``σ_k`` = reflection in P0's edge ``k``), and the reflection group acts
simply transitively on tiles, so every tile has exactly one isometry.

Arcs of the unit circle T are ``(start angle, counter-clockwise length)`` in radians.  For every
edge ``k`` of a tile ``g`` the *far arc* is the arc of T cut off by the edge's geodesic on the side
that does not contain the tile; I5 is the set of all far arcs and their complements.

Everything that can be is done in the canonical frame of P0 and moved by the tile isometries,
so that tiny tiles near T (intervals of 1e-8 rad and less from conformal maps) are handled with
relative, not absolute, accuracy.  A tile of Euclidean size ``s`` is a product of ~log(1/s)
reflections with entries ~``s^{-1/2}``, so its vertices carry relative errors ~30·eps/s (see
``POSITION_RTOL`` and ``region.MIN_EXPANDED_ARC``).  Therefore the reflections, the tile
isometries, point location and all arcs (angles modulo :data:`TWO_PI_LD`) are kept in extended
precision (np.longdouble / np.clongdouble: 80-bit on x86-64, eps 1.1e-19, so 3e-4 relative at
``s = 1e-14`` instead of 3e-4 at 1e-11 in float64).  Bulk evaluations stay float64: a mesh vertex
is a long double frame point (tile centre, piece corner) plus a float64 offset computed without
cancellation (:func:`tile_offsets`, :func:`frame_offsets`), and tile deduplication bins float64
``hi + lo`` splits of the centres.  All searches are *local*: their cost depends on the hyperbolic
distance from 0 and on the number of pieces, never on the size of the tessellation.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DiskConstructionError
from ..hyperbolic import Isometry
from ..hyperbolic.isometry import normalize_matrix
from ..progress import checkpoint

__all__ = [
    "EDGE_CENTERS",
    "EDGE_FAR_END",
    "EDGE_FAR_START",
    "EDGE_MIDPOINTS",
    "EDGE_RADIUS",
    "GROUP11",
    "P0_VERTICES",
    "PI_LD",
    "POSITION_RTOL",
    "REFLECTIONS",
    "TWO_PI",
    "TWO_PI_LD",
    "L",
    "TileSet",
    "arc_contains_arc",
    "arc_contains_point",
    "arcs_match",
    "brute_force_i5_arcs",
    "frame_offsets",
    "generate_tiles",
    "grow_tiles",
    "locate",
    "minimal_containing_arc",
    "one_minus_abs2",
    "phi_accurate",
    "phi_inv_accurate",
    "tile_edge_far_arcs",
    "tile_offsets",
    "tile_points",
    "top_point",
]

TWO_PI = 2.0 * math.pi

PI_LD: np.longdouble = np.longdouble(4) * np.arctan(np.longdouble(1))
"""π in extended precision (np.longdouble, 80-bit on x86-64: eps 1.1e-19)."""
TWO_PI_LD: np.longdouble = 2 * PI_LD
"""2π in extended precision: all arc arithmetic of the construction is done modulo this."""

POSITION_RTOL = 1e-3
"""Relative tolerance of the consistency checks between positions computed twice (relative to
the local scale ``1−|z|``).  Tile isometries are products of ~log(1/s) reflections with entries
~``s^{-1/2}`` for tiles of Euclidean size ``s``, so their vertices carry relative errors of about
``30·eps/s``: 3e-4 at ``s = 1e-11`` in float64, hence the tiles and the arcs are kept in extended
precision (``eps = 1.1e-19``: 3e-4 at ``s = 1e-14``); a mismatch of the pieces would be of
order 1."""

_LD = np.longdouble
L: float = math.acosh(1.0 + 2.0 * math.cos(2.0 * math.pi / 5.0))
"""Side length of the right regular pentagon, ``arccosh(1+2cos(2π/5)) = 1.0612750619``."""

# P0's geometry in extended precision (the reflections must be exact to long double accuracy:
# an error δ in σ_k moves a tile ``n`` reflections deep by ~δ·e^n relative to its size)
_RV = np.arccosh(1 / np.tan(PI_LD / 5))  # centre-vertex distance: cosh R_V = cot(π/5)
_RM = np.arccosh(np.cos(PI_LD / 4) / np.sin(PI_LD / 5))  # centre-edge midpoint
_EV = np.tanh(_RV / 2)  # Euclidean radius of the vertices, 0.397975
_EM = np.tanh(_RM / 2)  # Euclidean radius of the edge midpoints, 0.303559

_K = np.arange(5)
_ROT_V = np.exp(1j * (2 * PI_LD * _K.astype(_LD) / 5))
_DIR_LD = np.exp(1j * (2 * PI_LD * _K.astype(_LD) / 5 + PI_LD / 5))
P0_VERTICES_LD: NDArray[np.clongdouble] = _EV * _ROT_V
"""Vertices ``V_k`` of P0 in extended precision."""
EDGE_MIDPOINTS_LD: NDArray[np.clongdouble] = _EM * _DIR_LD
"""Edge midpoints of P0 in extended precision."""
EDGE_CENTERS_LD: NDArray[np.clongdouble] = (1 + _EM**2) / (2 * _EM) * _DIR_LD
"""Centres of the circles carrying P0's edges, in extended precision."""
_EC_ABS = (1 + _EM**2) / (2 * _EM)
EDGE_RADIUS_LD: np.longdouble = np.sqrt(_EC_ABS**2 - 1)
_HALF = np.arccos(1 / _EC_ABS)  # angular half-width of an edge's far arc
EDGE_FAR_START_LD: NDArray[np.clongdouble] = _DIR_LD * np.exp(-1j * _HALF)
"""Ideal endpoints where the far arcs of P0's edges start (CCW), extended precision."""
EDGE_FAR_END_LD: NDArray[np.clongdouble] = _DIR_LD * np.exp(1j * _HALF)
"""Ideal endpoints where the far arcs of P0's edges end, extended precision."""

_EDGE_FAR_ENDS_LD = np.concatenate([EDGE_FAR_START_LD, EDGE_FAR_END_LD])

P0_VERTICES: NDArray[np.complex128] = P0_VERTICES_LD.astype(np.complex128)
"""Vertices ``V_k`` of the central pentagon P0 (edge ``k`` runs from ``V_k`` to ``V_{k+1}``)."""
EDGE_MIDPOINTS: NDArray[np.complex128] = EDGE_MIDPOINTS_LD.astype(np.complex128)
"""Hyperbolic midpoints of P0's edges."""
EDGE_CENTERS: NDArray[np.complex128] = EDGE_CENTERS_LD.astype(np.complex128)
"""Euclidean centres of the circles carrying P0's edges."""
EDGE_RADIUS: float = float(EDGE_RADIUS_LD)
"""Common Euclidean radius of those circles."""
EDGE_FAR_START: NDArray[np.complex128] = EDGE_FAR_START_LD.astype(np.complex128)
"""Ideal endpoint of edge ``k``'s geodesic where its far arc (side away from P0) starts (CCW)."""
EDGE_FAR_END: NDArray[np.complex128] = EDGE_FAR_END_LD.astype(np.complex128)
"""Ideal endpoint where edge ``k``'s far arc ends."""

# reflection in the circle |z − C| = r orthogonal to T: z ↦ (C·z̄ − 1)/(z̄ − C̄), det = r²
_RM_MAT = np.empty((5, 2, 2), dtype=np.clongdouble)
_RM_MAT[:, 0, 0] = EDGE_CENTERS_LD
_RM_MAT[:, 0, 1] = -1
_RM_MAT[:, 1, 0] = 1
_RM_MAT[:, 1, 1] = -np.conj(EDGE_CENTERS_LD)
_RM_MAT /= 1j * EDGE_RADIUS_LD
REFLECTIONS = Isometry(_RM_MAT, np.ones(5, dtype=bool))
"""Stack of the 5 reflections ``σ_k`` in the edges of P0 (orientation reversing), with
extended-precision (clongdouble) matrices of determinant 1."""

_G11 = [Isometry.identity(dtype=np.clongdouble)] + [REFLECTIONS[k] for k in range(5)]
_G11 += [REFLECTIONS[k] @ REFLECTIONS[(k + 1) % 5] for k in range(5)]
GROUP11 = Isometry.stack(_G11)
"""P0 and the 10 tiles touching it (5 across edges, 5 sharing only the vertex ``V_{k+1}``)."""


# --------------------------------------------------------------------------- arcs
def _real(a: ArrayLike) -> NDArray:
    """``a`` as a float64 array, or as a longdouble array if it is extended precision."""
    a = np.asarray(a)
    return a if a.dtype == np.longdouble else a.astype(float)


def arc_contains_point(start: ArrayLike, length: ArrayLike, x: ArrayLike) -> NDArray[np.bool_]:
    """True where the open arc ``(start, length)`` contains the angle ``x`` (broadcast; angles
    in float64 or longdouble, reduced modulo the extended-precision 2π)."""
    rel = np.mod(_real(x) - _real(start), TWO_PI_LD)
    return (rel > 0.0) & (rel < _real(length))


def arc_contains_arc(
    start: ArrayLike, length: ArrayLike, s: ArrayLike, ell: ArrayLike
) -> NDArray[np.bool_]:
    """True where the closed arc ``(s, ell)`` lies inside the closed arc ``(start, length)``."""
    rel = np.mod(_real(s) - _real(start), TWO_PI_LD)
    return rel + _real(ell) <= _real(length)


def arcs_match(
    s1: ArrayLike, l1: ArrayLike, s2: ArrayLike, l2: ArrayLike, rtol: float = 1e-3
) -> NDArray[np.bool_]:
    """True where two arcs are the same I5 arc up to rounding (relative to their length).

    Distinct T5 geodesics never share an endpoint and are a bounded-below hyperbolic distance
    apart when disjoint, so a relative tolerance of 1e-3 cannot confuse two distinct arcs (it
    leaves room for the ~30·eps/|arc| rounding of arcs near T: 1e-11 rad in float64, 1e-14 rad
    in long double).  The absolute floor is a few ulps of 2π in the inputs' precision.
    """
    s1, l1, s2, l2 = (_real(a) for a in (s1, l1, s2, l2))
    ld = any(a.dtype == np.longdouble for a in (s1, l1, s2, l2))
    ds = np.mod(s1 - s2 + PI_LD, TWO_PI_LD) - PI_LD
    tol = np.maximum(rtol * np.minimum(l1, l2), 1e-17 if ld else 4e-15)
    return (np.abs(ds) <= tol) & (np.abs(l1 - l2) <= tol)


def top_point(start: ArrayLike, length: ArrayLike) -> NDArray[np.complex128]:
    """Top point (point nearest 0) of the geodesic spanning the arc ``(start, length)``.

    Computed from angles, ``e^{i(s+ℓ/2)}·tan(π/4 − ℓ/4)``, so that ``1−|z| ≈ ℓ/2`` keeps full
    relative accuracy for tiny arcs.  For arcs longer than π this is the point nearest 0 on the
    geodesic measured on the arc's side (it lies on the far side of 0).  Longdouble arcs give a
    clongdouble point.
    """
    s = _real(start)
    ell = _real(length)
    return np.exp(1j * (s + ell / 2)) * np.tan(PI_LD / 4 - ell / 4)


def _reduce_angle(x: NDArray, two_pi: float | np.longdouble = TWO_PI_LD) -> NDArray:
    """``np.mod(x, two_pi)`` bit for bit for ``x`` in ``(−two_pi, two_pi)`` (arguments of
    points, differences of reduced angles): there np.mod's floating remainder is exact and
    only adds ``two_pi`` to negative ``x``, so one comparison and one addition do the same
    (3–4 times faster; ``+ 0.0`` turns −0 into +0 as np.mod does)."""
    return np.where(x < 0, x + two_pi, x) + 0.0


def _angle(z: NDArray) -> NDArray:
    """Argument in ``[0, 2π)`` (longdouble for clongdouble input)."""
    return _reduce_angle(np.angle(z))


def tile_edge_far_arcs(
    tiles: Isometry,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Far arcs of the 5 edges of each tile in a stack: ``(start, length)`` arrays of shape (k, 5).

    The far arc of edge ``k`` of tile ``g`` is ``g`` of P0's far arc; an orientation-reversing
    ``g`` swaps its ends.  Extended-precision tiles give longdouble arcs.
    """
    a, b = np.split(tiles.apply_rows(_EDGE_FAR_ENDS_LD), 2, axis=1)  # starts, ends
    rev = tiles.sigma[:, None]
    first = np.where(rev, b, a)
    last = np.where(rev, a, b)
    s = _angle(first)
    ell = _reduce_angle(_angle(last) - s)
    return s, ell


def _two_square(x: NDArray) -> tuple[NDArray, NDArray]:
    """``x² = hi + lo`` exactly (Dekker's splitting; no FMA needed), float64 or longdouble."""
    hi = x * x
    split = 4294967297.0 if x.dtype == np.longdouble else 134217729.0  # 2^32+1 / 2^27+1
    c = split * x
    xh = c - (c - x)
    xl = x - xh
    lo = ((xh * xh - hi) + 2.0 * xh * xl) + xl * xl
    return hi, lo


def one_minus_abs2(a: ArrayLike) -> NDArray[np.float64]:
    """``1 − |a|²`` with full relative accuracy also for points very close to T.

    The naive ``1 − (x² + y²)`` loses ``log10(1/(1−|a|))`` digits; here the squares are split
    into exact double-double parts and the large one is subtracted from 1 first (exact by
    Sterbenz's lemma), so the result is correct to a few ulps *of itself* (float64 or
    longdouble, following the input).
    """
    a = np.asarray(a)
    a = a if a.dtype == np.clongdouble else a.astype(np.complex128)
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
    clongdouble if either input is.
    """
    ld = np.asarray(a).dtype == np.clongdouble or np.asarray(z).dtype == np.clongdouble
    dt = np.clongdouble if ld else np.complex128
    a = np.asarray(a, dtype=dt)
    z = np.asarray(z, dtype=dt)
    d = a - z
    return -d / (one_minus_abs2(a) + np.conj(a) * d)


def _split(a: NDArray) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """``a = hi + lo`` with complex128 parts (``lo`` is the rounding error of ``hi``)."""
    hi = a.astype(np.complex128)
    return hi, (a - hi).astype(np.complex128)


def phi_inv_accurate(a: ArrayLike, w: ArrayLike) -> NDArray[np.complex128]:
    """``φ_a⁻¹(w) = (w + a)/(1 + āw)`` rounded once to complex128, for a frame point ``a``
    given in extended precision and local coordinates ``w`` (complex128; broadcast).

    Evaluated as ``a + w(1 − |a|²)/(1 + āw)``: the offset from ``a`` is computed in float64 with
    full relative accuracy (``1 − |a|²`` from :func:`one_minus_abs2` in long double; ``1 + āw``
    does not cancel for points of a piece seen from its own corner), then added to ``a`` split
    into float64 ``hi + lo``.  The result is within about one ulp of the exact point, i.e. as
    accurate as a complex128 position can be, whatever the size of the piece.
    """
    a = np.asarray(a).astype(np.clongdouble)
    hi, lo = _split(a)
    return hi + (lo + frame_offsets(a, w))


def frame_offsets(a: ArrayLike, w: ArrayLike) -> NDArray[np.complex128]:
    """``φ_a⁻¹(w) − a = w(1 − |a|²)/(1 + āw)`` in float64 with full relative accuracy, for a
    frame point ``a`` in extended precision and local coordinates ``w`` (broadcast); see
    :func:`phi_inv_accurate`."""
    a = np.asarray(a).astype(np.clongdouble)
    w = np.asarray(w, dtype=np.complex128)
    k = one_minus_abs2(a).astype(float)
    return w * k / (1.0 + np.conj(a.astype(np.complex128)) * w)


def tile_offsets(
    tiles: Isometry, z: ArrayLike
) -> tuple[NDArray[np.clongdouble], NDArray[np.complex128]]:
    """Centres ``g(0)`` (k,) in extended precision and offsets ``g(z) − g(0)`` (k, p) in float64
    with full relative accuracy, for a stack of tile isometries and points ``z`` (p,) of P0's
    frame; see :func:`tile_points`."""
    M = tiles.M.astype(np.clongdouble)
    a, b, c, d = M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1]
    det = (a * d - b * c).astype(np.complex128)
    c64, d64 = c.astype(np.complex128), d.astype(np.complex128)
    z = np.asarray(z, dtype=np.complex128)
    w = np.where(tiles.sigma[:, None], np.conj(z)[None, :], z[None, :])
    return b / d, w * (det / d64)[:, None] / (c64[:, None] * w + d64[:, None])


def tile_points(tiles: Isometry, z: ArrayLike) -> NDArray[np.complex128]:
    """Images ``g(z)`` of points ``z`` (p,) of P0's frame under a stack of tile isometries
    (k), rounded once to complex128: shape (k, p).

    With ``g = (a·w + b)/(c·w + d)`` (``w = z`` or ``z̄``), ``g(w) − g(0) = w·det/(d(c·w + d))``
    has no cancellation (``|c| < |d|`` for isometries of D and ``|w| < 1``), so it is evaluated in
    float64 from the rounded entries and added to the centre ``g(0) = b/d`` (long double, split
    into ``hi + lo``).  This is as accurate as :meth:`Isometry.apply_rows` in long double but
    runs at float64 speed on the many mesh vertices.
    """
    centre, off = tile_offsets(tiles, z)
    hi, lo = _split(centre)
    return hi[:, None] + (lo[:, None] + off)


# --------------------------------------------------------------------------- point location
def locate(z: ArrayLike, max_steps: int = 400, dtype: type = np.clongdouble) -> Isometry:
    """Tiles containing the points ``z`` (1-d array, |z| < 1), as a stack of isometries.

    Starting from the identity, reflect across the most violated edge of P0 in the current
    frame until ``g⁻¹(z)`` lies in P0; the number of steps is
    proportional to the hyperbolic distance of ``z`` from 0.  Vectorised over the points; the
    tiles are extended-precision (clongdouble) isometries, or complex128 ones with
    ``dtype=np.complex128`` (for points whose tiles are not tiny: see
    :func:`minimal_containing_arc`).
    """
    z = np.atleast_1d(np.asarray(z)).astype(dtype)
    centres = EDGE_CENTERS_LD.astype(dtype)
    radius = EDGE_RADIUS_LD.astype(z.real.dtype)
    reflections = REFLECTIONS.M.astype(dtype)
    if np.any(~np.isfinite(z)) or np.any(np.abs(z) >= 1.0):
        raise DiskConstructionError("point location needs points inside the unit disk")
    g = Isometry.identity(z.shape[0], dtype=dtype)
    M, sig = g.M.copy(), g.sigma.copy()
    active = np.arange(z.shape[0])
    w = z.copy()  # g⁻¹(z) of the active points, updated by w ← σ_k(w) as g ← g∘σ_k
    for _ in range(max_steps):
        if active.size == 0:
            break
        checkpoint()
        viol = radius - np.abs(w[:, None] - centres[None, :])
        k = np.argmax(viol, axis=1)
        move = viol[np.arange(active.size), k] > 1e-13
        if not np.any(move):
            break
        idx = active[move]
        km = k[move]
        M[idx], sig[idx] = _times_reflections(M[idx], sig[idx], km, reflections)
        c = centres[km]
        wc = np.conj(w[move])
        w = (c * wc - 1) / (wc - np.conj(c))
        active = idx
    else:
        raise DiskConstructionError("point location did not converge (point too close to T)")
    return Isometry(normalize_matrix(M), sig)


def _times_reflections(
    M: NDArray, sigma: NDArray[np.bool_], k: NDArray[np.int64], reflections: NDArray | None = None
) -> tuple[NDArray, NDArray[np.bool_]]:
    """``(M, σ)∘σ_k`` row by row without renormalising (the σ_k have determinant 1 to long
    double accuracy, so products of a few hundred stay normalised to ~1e-17); ``reflections``:
    the matrices of the σ_k in the precision wanted (default: REFLECTIONS', long double)."""
    R = (REFLECTIONS.M if reflections is None else reflections)[k]
    R = np.where(sigma[:, None, None], np.conj(R), R)
    if M.dtype != np.complex128:
        return M @ R, ~sigma
    # stacked 2×2 products entry by entry: numpy's matmul on (k, 2, 2) complex128 stacks
    # goes through a per-matrix BLAS call (~450 ns a product against ~80 ns here)
    out = np.empty_like(M)
    m00, m01, m10, m11 = M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1]
    r00, r01, r10, r11 = R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1]
    out[:, 0, 0] = m00 * r00 + m01 * r10
    out[:, 0, 1] = m00 * r01 + m01 * r11
    out[:, 1, 0] = m10 * r00 + m11 * r10
    out[:, 1, 1] = m10 * r01 + m11 * r11
    return out, ~sigma


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

    Isometries and centres are stored in extended precision (clongdouble); the bins and the
    distance test use a float64 form of each centre (``hi + lo`` and ``1−|z|²``), which resolves
    tiles down to ~1e-15 at float64 speed.
    """

    _R_SWITCH = 0.6  # Cartesian bins inside this radius, (level, angle) bins outside
    #: Up to this many (stored or earlier tile, queried tile) pairs a lookup tests every pair
    #: with :meth:`_close` instead of going through the bins: the same answer (the bins only
    #: narrow the pairs down), and for the few dozen tiles of a small region W the distances
    #: cost less than the bins' numpy bookkeeping.
    _ALL_PAIRS = 4096
    _CART = np.int64(127) << np.int64(56)  # key prefix of the Cartesian bins
    _AI_OFF = np.int64(1) << np.int64(55)  # offset making angular bin numbers non-negative

    def __init__(self) -> None:
        self._M = np.zeros((0, 2, 2), dtype=np.clongdouble)
        self._sigma = np.zeros(0, dtype=bool)
        self._centers = np.zeros(0, dtype=np.clongdouble)
        self._hi = np.zeros(0, dtype=np.complex128)
        self._lo = np.zeros(0, dtype=np.complex128)
        self._q = np.zeros(0, dtype=np.float64)
        self._keys_sorted = np.zeros(0, dtype=np.int64)
        self._key_owner = np.zeros(0, dtype=np.int64)
        self._n_keyed = 0  # the bins hold tiles 0.._n_keyed-1 (filled when first needed)
        self._group = np.zeros(0, dtype=np.int64)  # tiles of different groups never merge

    def __len__(self) -> int:
        return int(self._centers.size)

    @property
    def centers(self) -> NDArray[np.clongdouble]:
        """Stored tile centres ``g(0)`` in insertion order."""
        return self._centers

    @staticmethod
    def _prep(
        z: ArrayLike,
    ) -> tuple[NDArray[np.clongdouble], NDArray[np.complex128], NDArray[np.complex128], NDArray]:
        """Centres as clongdouble, their float64 split ``hi + lo`` and ``q = 1−|z|²``."""
        z = np.atleast_1d(np.asarray(z)).astype(np.clongdouble)
        hi, lo = _split(z)
        x, y = z.real, z.imag
        q = ((1 - x * x) - y * y).astype(float)
        if np.any(~(q > 1e-17)):
            raise DiskConstructionError(
                "a tile is too close to T for extended precision: the intervals are too small "
                "for the disk construction"
            )
        return z, hi, lo, q

    @staticmethod
    def _level(hi: NDArray[np.complex128], q: NDArray[np.float64]) -> NDArray[np.float64]:
        """``2·log((1−|z|²)/(1+|z|)) = 2·log(1−|z|)``."""
        return 2.0 * np.log(q / (1.0 + np.abs(hi)))

    @classmethod
    def _polar(cls, lv: NDArray[np.int64], ai: NDArray[np.int64]) -> NDArray[np.int64]:
        return ((lv + 100) << np.int64(56)) + ai + cls._AI_OFF

    @classmethod
    def _cart(cls, xi: NDArray[np.int64], yi: NDArray[np.int64]) -> NDArray[np.int64]:
        return cls._CART + (xi + 64) * 256 + (yi + 64)

    @classmethod
    def _own_keys(cls, hi: NDArray[np.complex128], q: NDArray[np.float64]) -> NDArray[np.int64]:
        out = np.empty(hi.shape, dtype=np.int64)
        near = np.abs(hi) < cls._R_SWITCH
        zn = hi[near]
        out[near] = cls._cart(
            np.floor(zn.real * 10.0).astype(np.int64), np.floor(zn.imag * 10.0).astype(np.int64)
        )
        zf = hi[~near]
        lv = np.floor(cls._level(zf, q[~near]))
        width = np.exp(lv / 2.0) * 0.5
        out[~near] = cls._polar(
            lv.astype(np.int64), np.floor(np.angle(zf) / width).astype(np.int64)
        )
        return out

    @classmethod
    def _query_keys(
        cls, hi: NDArray[np.complex128], q: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """All bins a match of each point can lie in: ``(point index, key)`` pairs."""
        r = np.abs(hi)
        pts: list[NDArray[np.int64]] = []
        keys: list[NDArray[np.int64]] = []
        near = np.flatnonzero(r < cls._R_SWITCH + 0.05)
        if near.size:
            xi = np.floor(hi[near].real * 10.0).astype(np.int64)
            yi = np.floor(hi[near].imag * 10.0).astype(np.int64)
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    pts.append(near)
                    keys.append(cls._cart(xi + dx, yi + dy))
        far = np.flatnonzero(r > cls._R_SWITCH - 0.05)
        if far.size:
            zf = hi[far]
            base = np.floor(cls._level(zf, q[far])).astype(np.int64)
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
    def _close(
        hi1: NDArray[np.complex128],
        lo1: NDArray[np.complex128],
        q1: NDArray[np.float64],
        hi2: NDArray[np.complex128],
        lo2: NDArray[np.complex128],
    ) -> NDArray[np.bool_]:
        """Hyperbolic distance below ``2·artanh(0.3)``: the same tile.  With ``d = c1 − c2``,
        ``|1 − c̄1·c2| = |(1−|c1|²) + c̄1·d|`` keeps its accuracy for centres near T."""
        d = (hi1 - hi2) + (lo1 - lo2)
        return np.abs(d) <= 0.3 * np.abs(q1 + np.conj(hi1) * d)

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

    def _bin_all(self) -> None:
        """Put the tiles not yet in the bins into them."""
        n = len(self)
        if self._n_keyed == n:
            return
        keys = np.concatenate(
            [self._keys_sorted, self._own_keys(self._hi[self._n_keyed :], self._q[self._n_keyed :])]
        )
        owner = np.concatenate([self._key_owner, np.arange(self._n_keyed, n, dtype=np.int64)])
        o = np.argsort(keys, kind="stable")
        self._keys_sorted, self._key_owner = keys[o], owner[o]
        self._n_keyed = n

    def _lookup(
        self,
        hi: NDArray[np.complex128],
        lo: NDArray[np.complex128],
        q: NDArray[np.float64],
        group: NDArray[np.int64],
    ) -> NDArray[np.int64]:
        out = np.full(hi.shape, -1, dtype=np.int64)
        if hi.size == 0 or len(self) == 0:
            return out
        if len(self) * hi.size <= self._ALL_PAIRS:
            ok = self._close(
                self._hi[:, None], self._lo[:, None], self._q[:, None], hi[None, :], lo[None, :]
            )
            ok &= self._group[:, None] == group[None, :]
            found = ok.any(axis=0)
            out[found] = np.argmax(ok, axis=0)[found]  # the smallest stored index, as below
            return out
        self._bin_all()
        qpt, qkey = self._query_keys(hi, q)
        qp, pos = self._pairs(self._keys_sorted, qpt, qkey)
        cand = self._key_owner[pos]
        ok = self._close(self._hi[cand], self._lo[cand], self._q[cand], hi[qp], lo[qp])
        ok &= self._group[cand] == group[qp]
        qp, cand = qp[ok], cand[ok]
        # several candidates (only possible for numerically dubious input): take the smallest
        o = np.lexsort((cand, qp))
        qp, cand = qp[o], cand[o]
        first = np.ones(qp.size, dtype=bool)
        first[1:] = qp[1:] != qp[:-1]
        out[qp[first]] = cand[first]
        return out

    def lookup(self, z: ArrayLike) -> NDArray[np.int64]:
        """Index of the stored tile with centre ``z`` (to 0.3 hyperbolically) for each point,
        or -1 (vectorised)."""
        _, hi, lo, q = self._prep(z)
        return self._lookup(hi, lo, q, np.zeros(hi.shape, dtype=np.int64))

    def find(self, z: complex) -> int:
        """Index of the stored tile whose centre is ``z`` (to 0.3 hyperbolically), or -1."""
        return int(self.lookup(np.array([z]))[0])

    def _append(
        self,
        M: NDArray,
        sigma: NDArray,
        z: NDArray[np.clongdouble],
        hi: NDArray[np.complex128],
        lo: NDArray[np.complex128],
        q: NDArray[np.float64],
        group: NDArray[np.int64],
    ) -> NDArray[np.int64]:
        n0 = len(self)
        idx = n0 + np.arange(z.size, dtype=np.int64)
        self._M = np.concatenate([self._M, np.asarray(M, np.clongdouble).reshape(-1, 2, 2)])
        self._sigma = np.concatenate([self._sigma, np.asarray(sigma, bool).reshape(-1)])
        self._centers = np.concatenate([self._centers, z])
        self._hi = np.concatenate([self._hi, hi])
        self._lo = np.concatenate([self._lo, lo])
        self._q = np.concatenate([self._q, q])
        self._group = np.concatenate([self._group, group])
        return idx

    def add(self, M: NDArray[np.complex128], sigma: bool, z: complex) -> int:
        """Store a new tile (no duplicate check; use :meth:`find` first) and return its index."""
        zz, hi, lo, q = self._prep(np.array([z]))
        return int(
            self._append(M[None], np.array([sigma]), zz, hi, lo, q, np.zeros(1, np.int64))[0]
        )

    def add_batch(
        self,
        M: NDArray,
        sigma: NDArray[np.bool_],
        z: ArrayLike,
        group: NDArray[np.int64] | None = None,
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Insert a batch of tiles with centres ``z``, skipping the ones already stored and the
        repeats within the batch (the first occurrence wins, as in a sequential loop).
        ``group``: per tile, the group it belongs to (default 0); a tile is a repeat only of
        tiles of its own group, so that several independent regions grow in one set.

        Returns ``(index, new)``: the tile index of every batch entry and whether it was added.
        """
        z, hi, lo, q = self._prep(z)
        k = z.size
        group = np.zeros(k, dtype=np.int64) if group is None else np.asarray(group, np.int64)
        index = self._lookup(hi, lo, q, group)
        todo = np.flatnonzero(index < 0)
        new = np.zeros(k, dtype=bool)
        if todo.size == 0:
            return index, new
        ht, lt, qt, gt = hi[todo], lo[todo], q[todo], group[todo]
        # dedup within the batch: representative = smallest batch position among equals
        rep = np.arange(todo.size)
        if todo.size**2 <= self._ALL_PAIRS:
            ok = self._close(ht[:, None], lt[:, None], qt[:, None], ht[None, :], lt[None, :])
            ok &= (rep[:, None] < rep[None, :]) & (gt[:, None] == gt[None, :])  # ok[other, qp]
            found = ok.any(axis=0)
            rep[found] = np.argmax(ok, axis=0)[found]
        else:
            own = self._own_keys(ht, qt)
            o = np.argsort(own, kind="stable")
            qpt, qkey = self._query_keys(ht, qt)
            qp, pos = self._pairs(own[o], qpt, qkey)
            other = o[pos]
            ok = (other < qp) & self._close(ht[other], lt[other], qt[other], ht[qp], lt[qp])
            ok &= gt[other] == gt[qp]
            np.minimum.at(rep, qp[ok], other[ok])
        rep = rep[rep]  # near-identical duplicates: one hop reaches the first occurrence
        is_first = rep == np.arange(todo.size)
        firsts = np.flatnonzero(is_first)
        sel = todo[firsts]
        ids = self._append(M[sel], sigma[sel], z[sel], hi[sel], lo[sel], q[sel], group[sel])
        slot = np.full(todo.size, -1, dtype=np.int64)
        slot[firsts] = ids
        index[todo] = slot[rep]
        new[todo[firsts]] = True
        return index, new

    def isometries(self) -> Isometry:
        """All stored tiles as one stacked :class:`Isometry`."""
        return Isometry(self._M.copy(), self._sigma.copy())


def _add_tiles(
    ts: TileSet, g: Isometry, group: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Store the tiles ``g`` (stacked; of the groups ``group``) in ``ts`` keyed by their centres
    ``g(0)``; returns :meth:`TileSet.add_batch`'s ``(index, new)``."""
    return ts.add_batch(g.M, g.sigma, g.apply_rows(np.zeros(1))[:, 0], group)


def _reflect_across_edges(
    ts: TileSet,
    g: Isometry,
    rows: NDArray[np.int64],
    ks: NDArray[np.int64],
    group: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Reflect tile ``g[rows[i]]`` across its edge ``ks[i]`` (the neighbour across that edge of
    the T5 tessellation, §2) and store the images in ``ts`` (in the groups ``group[rows]``).

    Returns ``neighbour`` (len(g), 5): the tile index across each reflected edge, -1 elsewhere;
    and the indices of the tiles that were new.
    """
    nbr = np.full((len(g), 5), -1, dtype=np.int64)
    if rows.size == 0:
        return nbr, np.zeros(0, dtype=np.int64)
    t, is_new = _add_tiles(
        ts,
        Isometry(*_times_reflections(g.M[rows], g.sigma[rows], ks)),
        None if group is None else group[rows],
    )
    nbr[rows, ks] = t
    return nbr, t[is_new]


StopRule = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.int64]]
GroupStopRule = Callable[
    [NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]], NDArray[np.int64]
]


def grow_tiles(
    seeds: Isometry,
    stop: StopRule | GroupStopRule,
    max_tiles: int = 2_000_000,
    groups: NDArray[np.int64] | None = None,
) -> tuple[Isometry, NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Breadth-first growth of a region of tiles by reflection.

    ``stop(start, length)`` receives the far arcs of a batch of edges and returns, per edge, a
    label ``>= 0`` if the growth must not cross that edge (the label is recorded) and ``-1``
    if it may.  Returns the tiles (stacked isometries), ``neighbour`` (T, 5): the index of the
    tile across each edge or -1, ``label`` (T, 5): the stop label of each edge or -1, and
    ``seed_index`` (len(seeds),): the tile index of every seed.

    With ``groups`` (per seed), independent regions grow together, level by level: a tile
    belongs to the group of the seed it grew from, tiles of different groups are never merged,
    and ``stop(start, length, group)`` also receives the group of every edge.  Each region
    gets the tiles, in the same order, and the stop calls on its edges, in the same order, as
    when grown alone (``max_tiles`` then bounds all groups together).
    """
    ts = TileSet()
    seed_index, is_new = _add_tiles(ts, seeds, groups)
    frontier = np.unique(seed_index[is_new])
    nbr_rows: list[NDArray[np.int64]] = []
    lab_rows: list[NDArray[np.int64]] = []
    row_of: list[NDArray[np.int64]] = []
    while frontier.size:
        checkpoint()
        g = Isometry(ts._M[frontier], ts._sigma[frontier])
        s, ell = tile_edge_far_arcs(g)
        if groups is None:
            lab = stop(s.ravel(), ell.ravel()).reshape(-1, 5)
        else:
            lab = stop(s.ravel(), ell.ravel(), np.repeat(ts._group[frontier], 5)).reshape(-1, 5)
        rows, ks = np.nonzero(lab < 0)
        nbr, new_frontier = _reflect_across_edges(
            ts, g, rows, ks, None if groups is None else ts._group[frontier]
        )
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
    s, ell = s.ravel().astype(float), ell.ravel().astype(float)
    key = np.round(np.stack([s, np.mod(s + ell, TWO_PI)], axis=1) * 1e10)
    key.sort(axis=1)
    _, first = np.unique(key, axis=0, return_index=True)
    s, ell = s[first], ell[first]
    return np.concatenate([s, np.mod(s + ell, TWO_PI)]), np.concatenate([ell, TWO_PI - ell])


# --------------------------------------------------------------------------- Lemma 2.1
def _min_arc_through_radius(r: NDArray, pi: float | np.longdouble = PI_LD) -> NDArray:
    """Shortest arc of a geodesic passing through a point of modulus ``r``: 2θ with
    ``tan(π/4 − θ/2) = r`` (``pi``: π in the precision wanted)."""
    return 2 * (pi / 2 - 2 * np.arctan(r))


def _group11_geodesics() -> tuple[
    NDArray[np.complex128], NDArray[np.complex128], NDArray[np.int64], NDArray[np.int64]
]:
    """The distinct edge geodesics of the 11 tiles of GROUP11, in P0's frame.

    Returns ``(start, end, tile, edge)``: for every distinct geodesic the ideal endpoints where
    the far arc of ``(GROUP11[tile], edge)`` starts and ends (counter-clockwise).  The opposite
    arc is the far arc of the same edge of the tile ``GROUP11[tile]∘σ_edge``.
    """
    a = GROUP11.apply_rows(EDGE_FAR_START_LD)
    b = GROUP11.apply_rows(EDGE_FAR_END_LD)
    rev = GROUP11.sigma[:, None]
    first = np.where(rev, b, a).ravel()
    last = np.where(rev, a, b).ravel()
    ends = np.stack([_angle(first), _angle(last)], axis=1).astype(float)
    key = np.round(np.sort(ends, axis=1) * 1e9)
    _, idx = np.unique(key, axis=0, return_index=True)
    idx = np.sort(idx)
    return first[idx], last[idx], idx // 5, idx % 5


_G11_START, _G11_END, _G11_TILE, _G11_EDGE = _group11_geodesics()


def _distinct_isometries(g: Isometry) -> tuple[Isometry, NDArray[np.int64]]:
    """The distinct rows of a stack of isometries (equal matrix and orientation bits) and, per
    row, the index of its distinct row: ``g`` is ``tile[back]`` exactly."""
    n = len(g)
    raw = np.concatenate(
        [g.M.reshape(n, -1).view(np.uint8).reshape(n, -1), g.sigma.reshape(n, 1).view(np.uint8)],
        axis=1,
    )
    key = np.ascontiguousarray(raw).view(np.dtype((np.void, raw.shape[1]))).ravel()
    _, first, back = np.unique(key, return_index=True, return_inverse=True)
    return g[first], back.reshape(n)


#: Arcs searched together by :func:`minimal_containing_arc`: a cancellation point every ~0.05 s;
#: blocks also run faster than one batch of all arcs (6.2 s against 9.7 s for 39000 arcs).
_ARC_BLOCK = 1024


#: With ``fast=True``, :func:`minimal_containing_arc` searches in float64 when every given arc
#: is at least this long (radians): the tiles its search visits are then at least ~1e-8 of
#: the disk wide, where float64 isometries place them to ~1e-8 of their size (POSITION_RTOL's
#: ``30·eps/s``), far below what separates two candidate arcs.
FAST_MIN_ARC = 1e-6


def minimal_containing_arc(
    start: ArrayLike,
    length: ArrayLike,
    step: float = 0.5,
    chunk: float = 4.0,
    fast: bool = False,
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

    Returns ``(start, length, tile, edge)``: the minimal arcs (longdouble if the input arcs
    are, else rounded to float64) and the tile (clongdouble isometries) / edge carrying their
    geodesic on the tile's far side.  The search runs in extended precision throughout, or
    with ``fast=True`` in float64 for the arcs no shorter than :data:`FAST_MIN_ARC` (2–3 times
    faster; the arc choice, which only needs the arcs, uses it).
    Raises :class:`DiskConstructionError` if no I5 arc shorter than π contains J.
    """
    ld_in = np.asarray(start).dtype == np.longdouble or np.asarray(length).dtype == np.longdouble
    s = np.atleast_1d(np.asarray(start)).astype(_LD)
    ell = np.atleast_1d(np.asarray(length)).astype(_LD)
    if fast and not ld_in and s.size > 1:
        big = ell >= FAST_MIN_ARC
        if big.any() and not big.all():  # the long arcs in float64, the short ones not
            s64 = np.atleast_1d(np.asarray(start, dtype=float))
            l64 = np.atleast_1d(np.asarray(length, dtype=float))
            parts = [
                (idx, minimal_containing_arc(s64[idx], l64[idx], step, chunk, fast=True))
                for idx in (np.flatnonzero(big), np.flatnonzero(~big))
            ]
            out_s, out_l = np.empty(s.size), np.empty(s.size)
            out_M = np.empty((s.size, 2, 2), np.clongdouble)
            out_sig = np.empty(s.size, bool)
            out_k = np.empty(s.size, np.int64)
            for idx, (ps, pl, pt, pk) in parts:
                out_s[idx], out_l[idx], out_k[idx] = ps, pl, pk
                out_M[idx], out_sig[idx] = pt.M, pt.sigma
            return out_s, out_l, Isometry(out_M, out_sig), out_k
    f64 = fast and not ld_in and s.size > 0 and bool(np.min(ell) >= FAST_MIN_ARC)
    real, cplx = (np.float64, np.complex128) if f64 else (_LD, np.clongdouble)
    two_pi, pi = (TWO_PI, math.pi) if f64 else (TWO_PI_LD, PI_LD)
    s, ell = s.astype(real), ell.astype(real)
    g11_start, g11_end = _G11_START.astype(cplx), _G11_END.astype(cplx)
    n = s.size
    t_ = np.tan(ell / 4)  # 1 − |top| = 2t/(1+t): the distance of the top point keeps accuracy
    q_ = 2 * t_ / (1 + t_)
    dtop = np.log((2 - q_) / q_)
    u = np.exp(1j * (s + ell / 2))
    ng = _G11_START.size
    best_s = np.full(n, np.nan, dtype=real)
    best_l = np.full(n, np.inf, dtype=real)
    best_M = np.zeros((n, 2, 2), cplx)
    best_sig = np.zeros(n, bool)
    best_c = np.zeros(n, np.int64)  # candidate index: geodesic * 2 + (1 for the opposite arc)
    todo = np.arange(n)
    t0 = 0.0
    rounds = 0
    s_reduced = bool(np.all((s >= 0) & (s < two_pi)))  # then s − cs lies in (−2π, 2π)
    while todo.size:
        ts = np.arange(t0, t0 + chunk, step)
        # blocks of arcs (each arc's search is independent of the others): bounded memory and
        # a cancellation point every block
        left = []
        for b0 in range(0, todo.size, _ARC_BLOCK):
            checkpoint(1.0 - 0.6**rounds * (1.0 - 0.4 * b0 / todo.size))
            blk = todo[b0 : b0 + _ARC_BLOCK]
            dist = np.clip(dtop[blk, None] - ts[None, :], 0.0, None)  # distance of samples from 0
            pts = u[blk, None] * np.tanh(dist / 2.0)
            g = locate(pts.ravel(), dtype=cplx)
            # the samples lie in few distinct tiles (~1 in 12: near 0 the arcs' segments
            # share them): the candidate arcs of each distinct isometry (same bits) once
            tile, back = _distinct_isometries(g)
            a = tile.apply_rows(g11_start)  # (U, ng)
            b = tile.apply_rows(g11_end)
            rev = tile.sigma[:, None]
            fa = _reduce_angle(np.angle(np.where(rev, b, a)), two_pi)  # far arc: fa -> fb
            fb = _reduce_angle(np.angle(np.where(rev, a, b)), two_pi)
            far_l = _reduce_angle(fb - fa, two_pi)
            # (P, 2·ng): far arc, opposite
            cs = np.stack([fa, fb], axis=2).reshape(len(tile), -1)[back]
            cl = np.stack([far_l, two_pi - far_l], axis=2).reshape(len(tile), -1)[back]
            owner = np.repeat(blk, ts.size)
            # arc_contains_arc in the search's precision
            rel = s[owner, None] - cs
            rel = _reduce_angle(rel, two_pi) if s_reduced else np.mod(rel, two_pi)
            ok = (rel + ell[owner, None] <= cl) & (cl < math.pi)
            score = np.where(ok, cl, np.inf).reshape(blk.size, -1)
            j = np.argmin(score, axis=1)
            val = score[np.arange(blk.size), j]
            better = val < best_l[blk]
            if np.any(better):
                w = blk[better]
                sample, cand = np.divmod(
                    np.arange(blk.size)[better] * (ts.size * 2 * ng) + j[better], 2 * ng
                )
                best_l[w] = val[better]
                best_s[w] = cs[sample, cand]
                best_M[w] = g.M[sample]
                best_sig[w] = g.sigma[sample]
                best_c[w] = cand
            # stop where even the shortest geodesic through the next sample is no better
            nxt = np.tanh(np.clip(dtop[blk] - (t0 + chunk), 0.0, None) / 2)
            done = (_min_arc_through_radius(nxt, pi) >= best_l[blk]) | (dtop[blk] - t0 - chunk <= 0)
            left.append(blk[~done])
        todo = np.concatenate(left)
        t0 += chunk
        rounds += 1
    if np.any(~np.isfinite(best_l)):
        bad = int(np.nonzero(~np.isfinite(best_l))[0][0])
        raise DiskConstructionError(
            f"no arc of I5 shorter than π contains arc {bad} (length {ell[bad]:.3g} rad); "
            "the expansion factor A is too large for this interval"
        )
    geo, opposite = np.divmod(best_c, 2)
    k = _G11_EDGE[geo]
    tile = Isometry(best_M.astype(np.clongdouble), best_sig) @ GROUP11[_G11_TILE[geo]]
    if np.any(opposite == 1):
        o = opposite == 1
        flipped = tile[np.flatnonzero(o)] @ REFLECTIONS[k[o]]
        M = tile.M.copy()
        sig = tile.sigma.copy()
        M[o] = flipped.M
        sig[o] = flipped.sigma
        tile = Isometry(M, sig)
    if not ld_in:
        best_s, best_l = best_s.astype(float), best_l.astype(float)
    return best_s, best_l, tile, k
