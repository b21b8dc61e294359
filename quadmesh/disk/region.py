"""Lemma 2.2: the region W and its decomposition into right pentagons, Carleson quadrilaterals
and Carleson triangles (paper §3).

Given arcs ``I_j`` of T whose A-fold concentric expansions are disjoint and shorter than π:

1. ``J_j`` = the minimal-length I5 arc containing ``√A·I_j`` (Lemma 2.1, local search);
   ``γ_j`` its geodesic; ``P0`` the tile above the top point of ``γ_j``, ``P1, P2`` its
   neighbours along ``γ_j``; ``J^l_j, J^r_j`` the far arcs of the edges of ``P1, P2`` that are
   perpendicular to ``γ_j`` (labelled by which endpoint of ``J_j`` they contain).
2. ``W`` = hyperbolic convex hull of ``T ∖ ∪J_j``.
3. A cover of T with overlap ≤ 2 in circular order ``…, J^l_k, J_k, J^r_k, K, …, K, J^l_{k+1}, …``.
   The K arcs are chosen greedily (furthest reach) among the *maximal* I5 arcs shorter than π
   compactly inside the gaps of ``F = ∪J_j``, which are found locally: grow tiles from the
   ``P0``'s without crossing an edge whose far arc is a ``J/J^l/J^r`` arc or lies compactly
   inside a gap and is shorter than π; the gap edges where the growth stops are exactly the
   maximal candidates it can see.  (A maximal arc of a long gap can be almost all of T — e.g.
   for one small interval — and the "Carleson quadrilaterals" under it would cover most of D;
   with arcs shorter than π, W always contains 0 and every piece has its canonical shape.)
4. The pentagons are the tiles not below any cover geodesic (grown from the ``P0``'s, stopping
   at cover geodesics); their boundary edges on cover arc ``X_i`` are the tops of the Carleson
   quadrilaterals under ``X_i`` (none under ``J`` arcs, which carry 3 pentagon edges); the
   crossing points ``p_i = γ(X_i) ∩ γ(X_{i+1})`` are where the boundary edges switch arcs.
5. A Carleson triangle sits at every crossing of two non-``J`` cover arcs.

Everything is local: the work is proportional to the number of pieces (Lemma 2.3).

Precision: the tiles (products of reflections) and all arcs are computed in extended precision
(np.longdouble / np.clongdouble, eps 1.1e-19), so that the consistency checks hold for arcs down
to :data:`MIN_EXPANDED_ARC`; the public arrays of :class:`RegionW` are rounded to float64 except
``tiles``, ``cover_ld`` and ``crossings_ld``, which the mesh assembly uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DiskConstructionError
from ..hyperbolic import Isometry, phi
from ..progress import checkpoint, span
from .tessellation import (
    EDGE_MIDPOINTS_LD,
    P0_VERTICES,
    P0_VERTICES_LD,
    PI_LD,
    POSITION_RTOL,
    REFLECTIONS,
    TWO_PI,
    TWO_PI_LD,
    arc_contains_point,
    arcs_match,
    grow_tiles,
    locate,
    minimal_containing_arc,
    phi_accurate,
    tile_edge_far_arcs,
    top_point,
)

__all__ = [
    "MIN_EXPANDED_ARC",
    "CarlesonQuadrilateral",
    "CarlesonTriangle",
    "CoverArc",
    "CoverStage",
    "RegionW",
    "RightPentagon",
    "build_region",
    "cover_count",
    "cover_counts",
    "cover_stages",
    "crossing_check",
    "in_W",
    "piece_membership",
]

KIND_J, KIND_JL, KIND_JR, KIND_K = "J", "Jl", "Jr", "K"

MIN_EXPANDED_ARC = 5e-15
"""Smallest ``√A·|I_j|`` (radians) that :func:`build_region` accepts.  Tiles are isometries of
D stored as 2×2 matrices, so a tile of Euclidean size ``s`` near T has vertices with relative
errors of about ``30·eps/s``.  In float64 that limited the construction to ``√A·|I| ≥ 1e-11``
(all of 40 random single intervals and 3-interval clusters passed at 1e-11, 13/40 at 2e-12,
none at 1e-13); tiles, arcs and frames are now kept in extended precision (eps 1.1e-19) and
the measured pass rate is 40/40 at 1e-11, 1e-12, 1e-13, 3e-14, 1e-14, 5e-15, 3e-15 and 2e-15
and 38/40 at 1e-15 (Carleson top lengths off by 1.2e-3; tests/test_disk_precision.py).
Below ~1e-12 the complex128 ``vertices`` of the mesh no longer resolve the cells near T;
``DiskMesh.frames``/``vertex_offset`` do."""


@dataclass(frozen=True)
class CoverArc:
    """One arc ``X_i`` of the overlap-≤2 cover (Lemma 2.2 proof), in circular order.

    ``kind`` is ``"J"``, ``"Jl"``, ``"Jr"`` or ``"K"``; ``interval`` the index j of the chain for
    J/Jl/Jr arcs (-1 for K).  ``start``/``length``: the arc (radians, CCW).  ``a``/``b``: the
    ideal endpoints of its geodesic at the start and at the end of the arc.  (Rounded to
    float64; the extended-precision arcs are ``RegionW.cover_ld``.)
    """

    kind: str
    interval: int
    start: float
    length: float

    @property
    def end(self) -> float:
        """End angle ``start + length`` reduced mod 2π."""
        return (self.start + self.length) % TWO_PI

    @property
    def a(self) -> complex:
        """Ideal endpoint at the start of the arc."""
        return complex(np.exp(1j * self.start))

    @property
    def b(self) -> complex:
        """Ideal endpoint at the end of the arc."""
        return complex(np.exp(1j * (self.start + self.length)))


@dataclass(frozen=True, eq=False)
class RightPentagon:
    """A kept tile ``g(P0)`` of T5 (a right pentagon of W).

    ``neighbours[k]``: index of the kept pentagon across edge k, or -1; ``edge_cover[k]``: the
    cover arc whose geodesic carries edge k (then edge k is the top of a Carleson
    quadrilateral, or lies on a ``γ_j``), or -1.
    """

    index: int
    isometry: Isometry
    neighbours: tuple[int, ...]
    edge_cover: tuple[int, ...]

    @property
    def center(self) -> complex:
        """Hyperbolic centre ``g(0)``."""
        return complex(self.isometry(0.0))

    @property
    def vertices(self) -> NDArray[np.complex128]:
        """The 5 vertices ``g(V_k)``."""
        return self.isometry(P0_VERTICES)


@dataclass(frozen=True)
class CarlesonQuadrilateral:
    """Carleson quadrilateral number ``s`` under cover arc ``cover`` (Lemma 2.2, Lemma 5.1).

    Its top is the segment ``[u_s, u_{s+1}]`` (length L) of the cover geodesic, oriented from the
    arc's start side to its end side; it is edge ``edge`` of pentagon ``pentagon``.  ``flip``
    is True if that edge runs ``V_{k+1} → V_k`` in this direction.  The sides are the rays
    perpendicular to the top at ``u_s`` ("left") and ``u_{s+1}`` ("right"), down to T on the
    arc's side.  ``left``/``right`` name the neighbour across each side: ``("quad", index)``,
    ``("triangle", index)`` or ``("gamma", j)`` (the side is a ray of ``γ_j`` on ∂W).
    """

    cover: int
    s: int
    u0: complex
    u1: complex
    pentagon: int
    edge: int
    flip: bool
    left: tuple[str, int]
    right: tuple[str, int]


@dataclass(frozen=True)
class CarlesonTriangle:
    """Carleson triangle at the crossing ``p_i`` of cover arcs ``X = X_i`` and ``Y = X_{i+1}``.

    ``apex = p_i``; ``left_foot = Y.start`` and ``right_foot = X.end`` (unit complex numbers);
    its base is the arc ``X ∩ Y``.  The left side (apex to left foot, along Y's geodesic) is
    shared with the last quad under X, the right side (along X's geodesic) with the first quad
    under Y: ``left_quad``/``right_quad``.
    """

    crossing: int
    apex: complex
    left_foot: complex
    right_foot: complex
    X: int
    Y: int
    left_quad: int
    right_quad: int


@dataclass(frozen=True, eq=False)
class RegionW:
    """Output of Lemma 2.2 (see the module docstring).

    Attributes:
        intervals: the input arcs ``I_j`` (m, 2), (start, length).
        A: the expansion factor.
        J, Jl, Jr: (m, 2) arcs ``J_j``, ``J^l_j``, ``J^r_j`` (in input order).
        gamma: (m, 2) complex ideal endpoints of ``γ_j``: (start of J_j, end of J_j).
        cover: the cover arcs ``X_i`` in circular order.
        crossings: (C,) complex, ``p_i = γ(X_i) ∩ γ(X_{i+1})`` (indices mod C).
        tiles: stacked isometries of the pentagons (clongdouble matrices); ``tile_neighbour``
            (T, 5),
            ``tile_edge_cover`` (T, 5) as in :class:`RightPentagon`.
        cover_edges: per cover arc, (m_i, 2) int array of (pentagon, edge) along its geodesic
            from the arc's start side to its end side.
        quads, triangles: the Carleson pieces.
        quad_of_cover: per cover arc, the indices of its quads in order (empty for J).
        chain_tiles: (m, 3) pentagon indices of (P_l, P0, P_r) of every γ_j (P_l next to J^l).
        lemma21_ratio: |J_j| / |√A I_j| (Lemma 2.1's constant, measured).
        cover_ld: (C, 2) longdouble ``(start, length)`` of the cover arcs.
        crossings_ld: (C,) clongdouble crossings ``p_i`` (tile vertices).
    """

    intervals: NDArray[np.float64]
    A: float
    J: NDArray[np.float64]
    Jl: NDArray[np.float64]
    Jr: NDArray[np.float64]
    gamma: NDArray[np.complex128]
    cover: tuple[CoverArc, ...]
    crossings: NDArray[np.complex128]
    tiles: Isometry
    tile_neighbour: NDArray[np.int64]
    tile_edge_cover: NDArray[np.int64]
    cover_edges: tuple[NDArray[np.int64], ...]
    quads: tuple[CarlesonQuadrilateral, ...]
    triangles: tuple[CarlesonTriangle, ...]
    quad_of_cover: tuple[NDArray[np.int64], ...]
    chain_tiles: NDArray[np.int64]
    lemma21_ratio: NDArray[np.float64] = field(repr=False)
    cover_ld: NDArray[np.longdouble] = field(repr=False, default=None)
    crossings_ld: NDArray[np.clongdouble] = field(repr=False, default=None)

    @property
    def m(self) -> int:
        """Number of intervals."""
        return int(self.intervals.shape[0])

    @property
    def n_pentagons(self) -> int:
        """Number of right pentagons."""
        return len(self.tiles)

    @property
    def pentagons(self) -> tuple[RightPentagon, ...]:
        """The pentagons as :class:`RightPentagon` objects."""
        return tuple(
            RightPentagon(
                i,
                self.tiles[i],
                tuple(int(x) for x in self.tile_neighbour[i]),
                tuple(int(x) for x in self.tile_edge_cover[i]),
            )
            for i in range(self.n_pentagons)
        )

    @property
    def n_pieces(self) -> int:
        """Total number of pieces (pentagons + quadrilaterals + triangles)."""
        return self.n_pentagons + len(self.quads) + len(self.triangles)


# --------------------------------------------------------------------------- helpers
def _arc_error(message: str, *arcs: int) -> DiskConstructionError:
    """A DiskConstructionError about the given input arcs (rows of ``intervals``), kept in its
    ``arcs`` attribute so that a caller can say which parts of a polygon they belong to."""
    err = DiskConstructionError(message)
    err.arcs = tuple(int(a) for a in arcs)
    return err


def _validate(intervals: ArrayLike, A: float) -> NDArray[np.longdouble]:
    try:
        iv = np.asarray(intervals)
        iv = iv.astype(np.longdouble if iv.dtype == np.longdouble else float)
    except (TypeError, ValueError) as exc:
        raise DiskConstructionError(f"intervals must be a numeric (m, 2) array: {exc}") from exc
    if iv.ndim != 2 or iv.shape[1] != 2 or iv.shape[0] < 1:
        raise DiskConstructionError(f"intervals must have shape (m, 2), m >= 1; got {iv.shape}")
    if not np.all(np.isfinite(iv)):
        raise DiskConstructionError("intervals must be finite")
    if not (np.isfinite(A) and A > 1.0):
        raise DiskConstructionError(f"the expansion factor must satisfy A > 1, got A = {A!r}")
    if np.any(iv[:, 1] <= 0.0):
        raise DiskConstructionError("interval lengths must be positive")
    if np.any(A * iv[:, 1] >= math.pi):
        j = int(np.argmax(A * iv[:, 1]))
        raise _arc_error(
            f"arc {j} of the circle is too long for the disk construction: expanded {A:g}-fold "
            f"it would span {A * iv[j, 1]:.4g} rad >= π (half the circle); a shorter arc or a "
            "smaller expansion factor is needed",
            j,
        )
    small = math.sqrt(A) * iv[:, 1] < MIN_EXPANDED_ARC
    if np.any(small):
        j = int(np.argmin(iv[:, 1]))
        raise _arc_error(
            f"{int(small.sum())} arc(s) of the circle too small for the disk construction in "
            f"extended precision: arc {j} (length {iv[j, 1]:.3g} rad at angle "
            f"{np.mod(iv[j, 0], TWO_PI):.6f}) expanded {math.sqrt(A):.3g}-fold spans "
            f"{math.sqrt(A) * iv[j, 1]:.3g} rad, below the resolution limit "
            f"{MIN_EXPANDED_ARC:g} rad (tiles of that size near the circle carry relative "
            "position errors of order 1e-3 even in extended precision and no longer fit)",
            j,
        )
    iv = np.column_stack([np.mod(iv[:, 0].astype(np.longdouble), TWO_PI_LD), iv[:, 1]])
    m = iv.shape[0]
    if m > 1:
        c = np.mod(iv[:, 0] + iv[:, 1] / 2, TWO_PI_LD)
        order = np.argsort(c)
        cs, ls = c[order], iv[order, 1]
        gap = np.mod(np.roll(cs, -1) - cs, TWO_PI_LD)
        need = A * (ls + np.roll(ls, -1)) / 2.0
        bad = gap <= need
        if np.any(bad):
            k = int(np.nonzero(bad)[0][0])
            raise _arc_error(
                f"arcs {order[k]} and {order[(k + 1) % m]} of the circle are too close for the "
                f"disk construction: expanded {A:g}-fold they overlap; shorter arcs or a "
                "smaller expansion factor are needed",
                int(order[k]),
                int(order[(k + 1) % m]),
            )
    return iv


def _arcs_intersect(s1: ArrayLike, l1: ArrayLike, s2: ArrayLike, l2: ArrayLike):
    """True where the open arcs ``(s1, l1)`` and ``(s2, l2)`` meet (or start together)."""
    same = np.abs(np.remainder(np.asarray(s1) - s2 + PI_LD, TWO_PI_LD) - PI_LD) < 1e-18
    return arc_contains_point(s1, l1, s2) | arc_contains_point(s2, l2, s1) | same


class _ArcTable:
    """Sorted arcs with vectorised exact-match lookup (``arcs_match``)."""

    def __init__(self, s: NDArray[np.float64], ell: NDArray[np.float64]) -> None:
        self.order = np.argsort(s)
        self.s = s[self.order]
        self.ell = ell[self.order]

    def lookup(self, s: NDArray[np.float64], ell: NDArray[np.float64]) -> NDArray[np.int64]:
        n = self.s.size
        out = np.full(s.shape, -1, dtype=np.int64)
        if n == 0:
            return out
        pos = np.searchsorted(self.s, s)
        for off in (-1, 0):
            j = np.mod(pos + off, n)
            hit = arcs_match(self.s[j], self.ell[j], s, ell) & (out < 0)
            out[hit] = self.order[j[hit]]
        return out


# --------------------------------------------------------------------------- Lemma 2.2
def _greedy_chain(
    rs: NDArray[np.longdouble],
    re: NDArray[np.longdouble],
    ell: NDArray[np.longdouble],
    r0: np.longdouble,
    q: np.longdouble,
    after: int,
) -> list[int]:
    """The K arcs of Lemma 2.2's cover in one gap of F (step 3 of the module docstring), as
    indices into the candidate arcs ``(rs, re)`` (positions relative to the gap, lengths
    ``ell``): from the point ``r0`` on, the candidate that contains the current point (``rs <
    r < re``) and reaches furthest (ties: the longer, then the first) is taken and its end
    becomes the current point, until the point passes ``q``.

    The candidates with ``rs < r`` are a prefix of the candidates sorted by start, so the one
    taken is the best-ranked in that prefix (if it contains ``r`` at all): every candidate's
    successor is found at once (searchsorted on prefix minima of the ranks) and the chain is
    followed from ``r0``. Raises DiskConstructionError (naming the gap ``after`` arc) if no
    candidate contains the current point.
    """
    n = rs.size
    rank_order = np.lexsort((-ell, -re))  # the best candidate first
    rank = np.empty(n, dtype=np.int64)
    rank[rank_order] = np.arange(n)
    by_start = np.argsort(rs, kind="stable")
    pts = np.append(re, r0)  # the points a chain can be at: candidate ends, and r0
    before = np.searchsorted(rs[by_start], pts, side="left")  # how many start before each
    succ = np.full(n + 1, -1, dtype=np.int64)
    has = before > 0
    if n:
        best = rank_order[np.minimum.accumulate(rank[by_start])[before[has] - 1]]
        succ[np.flatnonzero(has)] = np.where(re[best] > pts[has], best, -1)
    chain: list[int] = []
    r, i = r0, succ[n]
    while r <= q:
        if i < 0:
            raise DiskConstructionError(
                f"cover construction failed in the gap after arc {after}: no tessellation arc "
                "inside the gap contains the current point"
            )
        chain.append(int(i))
        r, i = re[i], succ[i]
        if len(chain) > 100000:
            raise DiskConstructionError("cover construction did not terminate")
    return chain


def _tile_cap(m: int) -> int:
    """Most tiles a growth of :func:`build_region` may reach for m arcs (Lemma 2.3: O(m)
    tiles, about 12 per interval measured)."""
    return 20000 + 5000 * m


@dataclass(frozen=True, eq=False)
class CoverStage:
    """Steps 1–3 of Lemma 2.2 (module docstring): the chains about the ``J_j`` and the
    overlap-≤2 cover, i.e. everything :func:`build_region` computes before the pentagons.

    ``iv``: the validated arcs (longdouble); ``J``/``Jl``/``Jr``: (m, 2) longdouble arcs in
    input order; ``ratio``: |J_j| / |√A I_j|; ``g0``/``Pl``/``Pr``: the tiles ``P0``, ``P_l``,
    ``P_r`` of every chain; ``kinds``/``owner``/``cover_ld``: the cover arcs in circular order
    (the ``kind`` and ``interval`` of their :class:`CoverArc`, and their (C, 2) longdouble
    ``(start, length)``).
    """

    iv: NDArray[np.longdouble]
    J: NDArray[np.longdouble]
    Jl: NDArray[np.longdouble]
    Jr: NDArray[np.longdouble]
    ratio: NDArray[np.longdouble]
    g0: Isometry
    Pl: Isometry
    Pr: Isometry
    kinds: list[str]
    owner: list[int]
    cover_ld: NDArray[np.longdouble]

    @property
    def count(self) -> int:
        """Number of cover arcs."""
        return len(self.kinds)


def cover_count(intervals: ArrayLike, A: float) -> int:
    """Number of arcs of Lemma 2.2's overlap-≤2 cover of T for the arcs ``intervals``:
    ``len(build_region(intervals, A).cover)`` without building the pentagons and the Carleson
    pieces (steps 1–3 of the module docstring only, shared with :func:`build_region`).

    Raises DiskConstructionError where :func:`build_region` does in those steps; it can
    still fail afterwards (a cover geodesic carrying no pentagon edge, or the boundary edges
    of consecutive cover arcs not meeting), which this count does not check.
    """
    return _cover_stage(intervals, A).count


def cover_counts(interval_sets: list[ArrayLike], A: float) -> list[int | None]:
    """:func:`cover_count` of several arc sets (None where it raises), computed together: the
    Lemma 2.1 searches, the pentagon chains and the tile growths of all sets run as one
    (vectorised over the sets; each set's cover is the one it has alone)."""
    return [
        None if isinstance(st, DiskConstructionError) else st.count
        for st in cover_stages(interval_sets, A)
    ]


def _cover_stage(intervals: ArrayLike, A: float) -> CoverStage:
    """Steps 1–3 of Lemma 2.2 for one arc set (:func:`cover_stages`), raising its error."""
    st = cover_stages([intervals], A)[0]
    if isinstance(st, DiskConstructionError):
        raise st
    return st


class _GapCandidates:
    """The gaps of F = ∪J_j of one arc set and the growth's stop rule of step 3: stop at the
    J/J^l/J^r arcs (label 0) and at the arcs compactly inside a gap and shorter than π (label
    1, recorded as candidate K arcs)."""

    def __init__(
        self, J: NDArray[np.longdouble], Jl: NDArray[np.longdouble], Jr: NDArray[np.longdouble]
    ) -> None:
        m = J.shape[0]
        self.order = np.argsort(J[:, 0])
        self.chain_table = _ArcTable(
            np.concatenate([J[:, 0], Jl[:, 0], Jr[:, 0]]),
            np.concatenate([J[:, 1], Jl[:, 1], Jr[:, 1]]),
        )
        self.Js, Jls = J[self.order, 0], J[self.order, 1]
        self.Je = self.Js + Jls
        self.gap_len = np.mod(np.roll(self.Js, -1) - self.Je, TWO_PI_LD)
        if m == 1:
            self.gap_len = np.array([TWO_PI_LD - Jls[0]])
        self.cand_s: list[NDArray[np.float64]] = []
        self.cand_l: list[NDArray[np.float64]] = []
        self.edges = 0  # edges seen by the stop rule: 5 per tile grown

    def gap_of(self, s: NDArray[np.float64], ell: NDArray[np.float64]) -> NDArray[np.int64]:
        """Index (in ``order``) of the gap that holds each arc compactly, or -1."""
        i = np.mod(np.searchsorted(self.Js, s, side="right") - 1, self.Js.size)
        rel = np.mod(s - self.Je[i], TWO_PI_LD)
        inside = (rel > 0.0) & (rel + ell < self.gap_len[i])
        return np.where(inside, i, -1)

    def stop(self, s: NDArray[np.float64], ell: NDArray[np.float64]) -> NDArray[np.int64]:
        """The stop labels of a batch of edges (their far arcs), recording the candidates."""
        self.edges += s.size
        lab = np.full(s.shape, -1, dtype=np.int64)
        lab[self.chain_table.lookup(s, ell) >= 0] = 0
        g = self.gap_of(s, ell)
        # K arcs must be shorter than π: a maximal I5 arc of a long gap can be almost all of T
        # (its geodesic then hugs the J's and the "Carleson quadrilaterals" under it cover
        # most of D, far from Lemma 5.1's shape); the growth crosses such edges instead.
        is_c = (g >= 0) & (lab < 0) & (ell < math.pi)
        lab[is_c] = 1
        self.cand_s.append(s[is_c])
        self.cand_l.append(ell[is_c])
        return lab


def cover_stages(
    interval_sets: list[ArrayLike], A: float
) -> list[CoverStage | DiskConstructionError]:
    """Steps 1–3 of Lemma 2.2 for each arc set: validate the arcs, find the ``J_j`` (Lemma
    2.1) and their pentagon chains, grow the candidate K arcs and choose the cover greedily
    (see :class:`CoverStage`); per set, its stage or the DiskConstructionError that
    :func:`build_region` raises for it.

    The sets are processed together (one Lemma 2.1 search, one point location and one tile
    growth with a group per set); every set gets what it gets alone. Should a shared step
    fail (its error could not be told apart by set), the sets are done one at a time.
    """
    n_sets = len(interval_sets)
    out: list[CoverStage | DiskConstructionError | None] = [None] * n_sets
    ivs: dict[int, NDArray[np.longdouble]] = {}
    for g, intervals in enumerate(interval_sets):
        try:
            ivs[g] = _validate(intervals, A)
        except DiskConstructionError as exc:
            out[g] = exc
    live = list(ivs)
    try:
        if live:
            _chains_and_covers(ivs, A, out)
    except DiskConstructionError as exc:
        if len(live) == 1:
            out[live[0]] = exc
        else:
            for g in live:
                out[g] = cover_stages([interval_sets[g]], A)[0]
    return out  # type: ignore[return-value]


def _chain_checks(
    match: NDArray[np.bool_],
    first_is_l: NDArray[np.bool_],
    second_is_l: NDArray[np.bool_],
    J: NDArray[np.longdouble],
    Jl: NDArray[np.longdouble],
    Jr: NDArray[np.longdouble],
    A: float,
) -> _GapCandidates:
    """The checks of one set's pentagon chains (a P0 edge on every γ_j; J^l, J^r each holding
    one end of J_j; the J's disjoint and no chain reaching the next J), raising the
    DiskConstructionError of the first that fails; then its gaps of F."""
    if not np.all(match.any(axis=1)):
        j = int(np.nonzero(~match.any(axis=1))[0][0])
        raise _arc_error(f"no pentagon edge found on the geodesic over arc {j} at its top", j)
    if np.any(first_is_l == second_is_l):
        raise DiskConstructionError(
            "the tessellation arcs beside an arc's containing arc do not each hold one of its "
            "endpoints"
        )
    # ---- order chains, check the J's are disjoint and chains do not reach the next J
    order = np.argsort(J[:, 0])
    if J.shape[0] > 1:
        a_, b_ = order, np.roll(order, -1)
        checks = (
            (
                _arcs_intersect(J[a_, 0], J[a_, 1], J[b_, 0], J[b_, 1]),
                "the tessellation arcs containing arcs {} and {} overlap: the expansion "
                "factor {:g} is too small for these arcs",
            ),
            (
                _arcs_intersect(Jr[a_, 0], Jr[a_, 1], J[b_, 0], J[b_, 1])
                | _arcs_intersect(Jl[b_, 0], Jl[b_, 1], J[a_, 0], J[a_, 1]),
                "the pentagon chains about arcs {} and {} interlock: the expansion factor "
                "{:g} is too small for these arcs",
            ),
            (
                arcs_match(Jr[a_, 0], Jr[a_, 1], Jl[b_, 0], Jl[b_, 1]),
                "the pentagon chains about arcs {} and {} end on the same tessellation "
                "arc: the expansion factor {:g} is too small for these arcs",
            ),
            (
                arc_contains_point(Jl[b_, 0], Jl[b_, 1], Jr[a_, 0]),
                "the pentagon chains about arcs {} and {} overlap three-fold: the "
                "expansion factor {:g} is too small for these arcs",
            ),
        )
        for bad, msg in checks:
            if np.any(bad):
                i = int(np.flatnonzero(bad)[0])
                raise _arc_error(msg.format(a_[i], b_[i], A), int(a_[i]), int(b_[i]))
    return _GapCandidates(J, Jl, Jr)


def _greedy_cover(
    gaps: _GapCandidates,
    J: NDArray[np.longdouble],
    Jl: NDArray[np.longdouble],
    Jr: NDArray[np.longdouble],
) -> tuple[list[str], list[int], NDArray[np.longdouble]]:
    """Step 3's overlap-≤2 cover in circular order from the grown candidates: per J_j in
    circular order J^l_j, J_j, J^r_j and the greedy K arcs of the gap after it
    (:func:`_greedy_chain`); checks that consecutive arcs overlap and no three do. Returns
    the kinds, the owners (j, or -1 for K) and the (C, 2) longdouble arcs."""
    m = J.shape[0]
    order, Je = gaps.order, gaps.Je
    cs = np.concatenate(gaps.cand_s)
    cl = np.concatenate(gaps.cand_l)
    cgap = gaps.gap_of(cs, cl)
    kinds: list[str] = []
    owner: list[int] = []
    cov_ld: list[tuple[np.longdouble, np.longdouble]] = []

    def add_cover(kind: str, j: int, start: np.longdouble, length: np.longdouble) -> None:
        kinds.append(kind)
        owner.append(j)
        cov_ld.append((start, length))

    cg_order = np.argsort(cgap, kind="stable")
    cg_bounds = np.searchsorted(cgap[cg_order], np.arange(m + 1))
    for pos, k in enumerate(order):
        checkpoint(0.7 + 0.1 * pos / m)
        nxt = order[(pos + 1) % m]
        add_cover(KIND_JL, int(k), Jl[k, 0], Jl[k, 1])
        add_cover(KIND_J, int(k), J[k, 0], J[k, 1])
        add_cover(KIND_JR, int(k), Jr[k, 0], Jr[k, 1])
        sel = cg_order[cg_bounds[pos] : cg_bounds[pos + 1]]
        rs = np.mod(cs[sel] - Je[pos], TWO_PI_LD)
        re = rs + cl[sel]
        r_ = (Jr[k, 0] + Jr[k, 1] - Je[pos]) % TWO_PI_LD
        q_ = (Jl[nxt, 0] - Je[pos]) % TWO_PI_LD
        for best in _greedy_chain(rs, re, cl[sel], r_, q_, int(k)):
            add_cover(KIND_K, -1, np.mod(Je[pos] + rs[best], TWO_PI_LD), cl[sel][best])
    C = len(kinds)
    cover_ld = np.array(cov_ld, dtype=np.longdouble).reshape(C, 2)
    cvs, cvl = cover_ld[:, 0], cover_ld[:, 1]
    xs, xl = np.roll(cvs, 1), np.roll(cvl, 1)
    no_overlap = ~arc_contains_point(xs, xl, cvs)
    if np.any(no_overlap):
        i = int(np.flatnonzero(no_overlap)[0])
        raise DiskConstructionError(f"cover arcs {i - 1} and {i} do not overlap")
    if C > 3:
        triple = _arcs_intersect(xs, xl, np.roll(cvs, -1), np.roll(cvl, -1))
        if np.any(triple):
            raise DiskConstructionError(f"triple overlap at cover arc {int(np.argmax(triple))}")
    return kinds, owner, cover_ld


def _chains_and_covers(
    ivs: dict[int, NDArray[np.longdouble]],
    A: float,
    out: list[CoverStage | DiskConstructionError | None],
) -> None:
    """The body of :func:`cover_stages` for the validated sets ``ivs`` (set index → arcs):
    fills ``out``; raises DiskConstructionError from the steps shared by the sets."""
    live = list(ivs)
    iv_all = np.concatenate([ivs[g] for g in live])
    first = np.cumsum([0] + [ivs[g].shape[0] for g in live])
    sq = np.sqrt(np.longdouble(A))
    centre = iv_all[:, 0] + iv_all[:, 1] / 2
    es, el = np.mod(centre - sq * iv_all[:, 1] / 2, TWO_PI_LD), sq * iv_all[:, 1]
    with span(0.0, 0.5):
        js, jl, _, _ = minimal_containing_arc(es, el)
    ratio = jl / el

    # ---- chains: P0 at the top point of γ_j, P1, P2, J^l, J^r
    # a point 0.05 above the top point (any point that close lies in a tile with an edge on
    # γ_j, also next to a tile vertex on γ_j); 1 − |top| = 2t/(1+t), t = tan(|J|/4), is used
    # directly so that the distance to 0 keeps its relative accuracy for tiny J
    t_ = np.tan(jl / 4)
    q_ = 2 * t_ / (1 + t_)
    dtop = np.log((2 - q_) / q_)
    above = np.exp(1j * (js + jl / 2)) * np.tanh(np.maximum(dtop - 0.05, 0.0) / 2)
    g0 = locate(above)
    fs, fl = tile_edge_far_arcs(g0)
    match = arcs_match(fs, fl, js[:, None], jl[:, None])
    k0 = np.argmax(match, axis=1)
    p1 = g0 @ REFLECTIONS[(k0 + 1) % 5]
    p2 = g0 @ REFLECTIONS[(k0 - 1) % 5]
    s1, l1 = tile_edge_far_arcs(p1)
    s2, l2 = tile_edge_far_arcs(p2)
    r = np.arange(iv_all.shape[0])
    a1 = np.stack([s1[r, (k0 - 1) % 5], l1[r, (k0 - 1) % 5]], axis=1)
    a2 = np.stack([s2[r, (k0 + 1) % 5], l2[r, (k0 + 1) % 5]], axis=1)
    first_is_l = arc_contains_point(a1[:, 0], a1[:, 1], js)
    second_is_l = arc_contains_point(a2[:, 0], a2[:, 1], js)
    Jl_all = np.where(first_is_l[:, None], a1, a2)
    Jr_all = np.where(first_is_l[:, None], a2, a1)
    Pl_all = Isometry(
        np.where(first_is_l[:, None, None], p1.M, p2.M), np.where(first_is_l, p1.sigma, p2.sigma)
    )
    Pr_all = Isometry(
        np.where(first_is_l[:, None, None], p2.M, p1.M), np.where(first_is_l, p2.sigma, p1.sigma)
    )
    J_all = np.stack([js, jl], axis=1)

    grow: list[tuple[int, slice, _GapCandidates]] = []
    for i, g in enumerate(live):
        sl = slice(first[i], first[i + 1])
        try:
            gaps = _chain_checks(
                match[sl], first_is_l[sl], second_is_l[sl], J_all[sl], Jl_all[sl], Jr_all[sl], A
            )
        except DiskConstructionError as exc:
            out[g] = exc
            continue
        grow.append((g, sl, gaps))
    if not grow:
        return

    # ---- candidate K arcs: grow tiles, stop at J/Jl/Jr arcs and at arcs inside F-gaps
    parts = [np.arange(sl.start, sl.stop) for _, sl, _ in grow]
    seed_rows = np.concatenate([np.concatenate([p, p, p]) for p in parts])
    which = np.concatenate([np.repeat(np.arange(3), p.size) for p in parts])
    groups = np.concatenate([np.full(3 * p.size, i, dtype=np.int64) for i, p in enumerate(parts)])
    seeds_M = np.stack([g0.M, Pl_all.M, Pr_all.M])[which, seed_rows]
    seeds_sigma = np.stack([g0.sigma, Pl_all.sigma, Pr_all.sigma])[which, seed_rows]

    def stop(s: NDArray[np.float64], ell: NDArray[np.float64], grp: NDArray[np.int64]):
        lab = np.empty(s.shape, dtype=np.int64)
        bounds = np.flatnonzero(np.diff(grp)) + 1  # the edges come group by group
        for sel in np.split(np.arange(s.size), bounds):
            lab[sel] = grow[int(grp[sel[0]])][2].stop(s[sel], ell[sel])
        return lab

    caps = [_tile_cap(sl.stop - sl.start) for _, sl, _ in grow]
    checkpoint(0.6)
    grow_tiles(Isometry(seeds_M, seeds_sigma), stop, max_tiles=sum(caps), groups=groups)
    checkpoint(0.7)
    for (g, sl, gaps), cap in zip(grow, caps):
        if gaps.edges // 5 > cap:  # alone, its growth would have stopped with this error
            out[g] = DiskConstructionError(
                f"tile region grew beyond {cap} tiles; the intervals are too close "
                "together or too small for the construction"
            )
            continue
        try:
            kinds, owner, cover_ld = _greedy_cover(gaps, J_all[sl], Jl_all[sl], Jr_all[sl])
        except DiskConstructionError as exc:
            out[g] = exc
            continue
        out[g] = CoverStage(
            ivs[g],
            J_all[sl],
            Jl_all[sl],
            Jr_all[sl],
            ratio[sl],
            g0[sl],
            Pl_all[sl],
            Pr_all[sl],
            kinds,
            owner,
            cover_ld,
        )


def build_region(intervals: ArrayLike, A: float, cover: CoverStage | None = None) -> RegionW:
    """Lemma 2.2: decompose W into right pentagons, Carleson quadrilaterals and triangles.

    Args:
        intervals: (m, 2) arcs ``(start angle, CCW length)`` in radians.
        A: expansion factor (> 1); the A-fold concentric expansions must be disjoint and
            shorter than π.
        cover: steps 1–3 (the cover) already done for these intervals and A by
            :func:`cover_stages`; they are then not done again.

    Raises:
        DiskConstructionError: naming the violated hypothesis, if some ``√A·|I_j|`` is below
            the float64 resolution limit :data:`MIN_EXPANDED_ARC`, or if the construction
            fails (the ``J_j`` overlap, a chain's ``J^l/J^r`` reaches the next ``J``, ...).
    """
    st = _cover_stage(intervals, A) if cover is None else cover
    iv, J, Jl, Jr, ratio = st.iv, st.J, st.Jl, st.Jr, st.ratio
    g0, Pl, Pr, cover_ld = st.g0, st.Pl, st.Pr, st.cover_ld
    m, C = iv.shape[0], len(st.kinds)
    cvs, cvl = cover_ld[:, 0], cover_ld[:, 1]
    cover = tuple(
        CoverArc(kind, j, float(a), float(b))
        for kind, j, (a, b) in zip(st.kinds, st.owner, cover_ld)
    )

    # ---- pentagons: tiles not below any cover geodesic
    cover_table = _ArcTable(cvs, cvl)

    def stop_cover(s: NDArray[np.float64], ell: NDArray[np.float64]) -> NDArray[np.int64]:
        return cover_table.lookup(s, ell)

    seeds = Isometry(
        np.concatenate([Pl.M, g0.M, Pr.M]), np.concatenate([Pl.sigma, g0.sigma, Pr.sigma])
    )
    checkpoint(0.8)
    tiles, nbr, lab, seed_idx = grow_tiles(seeds, stop_cover, max_tiles=_tile_cap(m))
    checkpoint(0.9)
    chain_tiles = seed_idx.reshape(3, m).T.copy()

    # ---- boundary edges per cover arc, ordered from the arc's start side to its end side
    rows, ks = np.nonzero(lab >= 0)
    cov = lab[rows, ks]
    sig = tiles.sigma[rows]
    mid = tiles[rows].apply_rows(EDGE_MIDPOINTS_LD[ks][:, None])[:, 0]
    b_top = top_point(cvs[cov], cvl[cov])
    direction = np.exp(1j * (cvs[cov] + cvl[cov]))  # endpoint b
    local = phi(b_top, mid) * np.conj(phi(b_top, direction))
    param = local.real
    srt = np.lexsort((param, cov))
    rows, ks, cov, sig, param = rows[srt], ks[srt], cov[srt], sig[srt], param[srt]
    bounds = np.searchsorted(cov, np.arange(C + 1))
    n_edges = np.diff(bounds)
    kinds = np.array([c.kind for c in cover])
    if np.any(n_edges == 0):
        i = int(np.flatnonzero(n_edges == 0)[0])
        raise DiskConstructionError(f"cover arc {i} carries no pentagon edge")
    bad_j = (kinds == KIND_J) & (n_edges != 3)
    if np.any(bad_j):
        i = int(np.flatnonzero(bad_j)[0])
        raise _arc_error(
            f"the geodesic over arc {cover[i].interval} carries {n_edges[i]} pentagon edges, not 3",
            int(cover[i].interval),
        )
    e_all = np.stack([rows, ks], axis=1)
    cover_edges = [e_all[bounds[i] : bounds[i + 1]] for i in range(C)]

    # corners: the first corner (towards the arc's start) of edge k is V_k unless g reverses
    g_e = tiles[rows]
    va = g_e.apply_rows(P0_VERTICES_LD[ks][:, None])[:, 0]
    vb = g_e.apply_rows(P0_VERTICES_LD[(ks + 1) % 5][:, None])[:, 0]
    e_start = np.where(sig, vb, va)
    e_end = np.where(sig, va, vb)
    first_e, last_e = bounds[:-1], bounds[1:] - 1
    p_end = e_end[last_e]
    p_start = e_start[np.roll(first_e, -1)]
    bad_cross = np.abs(p_end - p_start) > POSITION_RTOL * (1.0 - np.abs(p_end))
    inner = np.ones(rows.size, dtype=bool)
    inner[first_e] = False  # edge e and e-1 lie on the same arc
    gap = np.zeros(rows.size)
    gap[inner] = np.abs(e_start[inner] - e_end[np.flatnonzero(inner) - 1]) / (
        1.0 - np.abs(e_end[np.flatnonzero(inner) - 1])
    )
    bad_chain = np.zeros(C, dtype=bool)
    np.logical_or.at(bad_chain, cov, gap > POSITION_RTOL)
    if np.any(bad_cross | bad_chain):
        i = int(np.flatnonzero(bad_cross | bad_chain)[0])
        raise DiskConstructionError(
            f"pentagon boundary edges on cover arcs {i} and {i + 1} do not meet"
        )
    crossings_ld = p_end
    crossings = p_end.astype(np.complex128)
    starts = [e_start[bounds[i] : bounds[i + 1]] for i in range(C)]
    ends = [e_end[bounds[i] : bounds[i + 1]] for i in range(C)]

    # ---- Carleson quadrilaterals and triangles
    nonj = np.array([c.kind != KIND_J for c in cover])
    tri_at = np.full(C, -1, dtype=np.int64)
    n_tri = 0
    for i in range(C):
        if nonj[i] and nonj[(i + 1) % C]:
            tri_at[i] = n_tri
            n_tri += 1
    quad_of_cover: list[NDArray[np.int64]] = []
    q_count = 0
    for i in range(C):
        mi = cover_edges[i].shape[0] if nonj[i] else 0
        quad_of_cover.append(np.arange(q_count, q_count + mi, dtype=np.int64))
        q_count += mi
    quads: list[CarlesonQuadrilateral] = []
    for i in range(C):
        if not nonj[i]:
            continue
        e = cover_edges[i]
        mi = e.shape[0]
        for s_ in range(mi):
            if s_ > 0:
                left = ("quad", int(quad_of_cover[i][s_ - 1]))
            elif tri_at[i - 1] >= 0:
                left = ("triangle", int(tri_at[i - 1]))
            else:
                left = ("gamma", cover[i - 1].interval)
            if s_ < mi - 1:
                right = ("quad", int(quad_of_cover[i][s_ + 1]))
            elif tri_at[i] >= 0:
                right = ("triangle", int(tri_at[i]))
            else:
                right = ("gamma", cover[(i + 1) % C].interval)
            quads.append(
                CarlesonQuadrilateral(
                    cover=i,
                    s=s_,
                    u0=complex(starts[i][s_]),
                    u1=complex(ends[i][s_]),
                    pentagon=int(e[s_, 0]),
                    edge=int(e[s_, 1]),
                    flip=bool(tiles.sigma[e[s_, 0]]),
                    left=left,
                    right=right,
                )
            )
    triangles: list[CarlesonTriangle] = []
    for i in range(C):
        if tri_at[i] < 0:
            continue
        X, Y = cover[i], cover[(i + 1) % C]
        triangles.append(
            CarlesonTriangle(
                crossing=i,
                apex=complex(crossings[i]),
                left_foot=Y.a,
                right_foot=X.b,
                X=i,
                Y=(i + 1) % C,
                left_quad=int(quad_of_cover[i][-1]),
                right_quad=int(quad_of_cover[(i + 1) % C][0]),
            )
        )

    edge_cover = np.where(lab >= 0, lab, -1)
    gamma = np.stack([np.exp(1j * J[:, 0]), np.exp(1j * (J[:, 0] + J[:, 1]))], axis=1)
    return RegionW(
        intervals=iv.astype(float),
        A=float(A),
        J=J.astype(float),
        Jl=Jl.astype(float),
        Jr=Jr.astype(float),
        gamma=gamma.astype(np.complex128),
        cover=cover,
        crossings=crossings,
        tiles=tiles,
        tile_neighbour=nbr,
        tile_edge_cover=edge_cover,
        cover_edges=tuple(cover_edges),
        quads=tuple(quads),
        triangles=tuple(triangles),
        quad_of_cover=tuple(quad_of_cover),
        chain_tiles=chain_tiles,
        lemma21_ratio=ratio.astype(float),
        cover_ld=cover_ld,
        crossings_ld=crossings_ld,
    )


def crossing_check(region: RegionW) -> NDArray[np.float64]:
    """Angles (degrees) at which consecutive cover geodesics cross, computed at ``p_i`` in the
    frame ``φ_{p_i}`` (where geodesics through 0 are diameters).  All should be 90.
    Evaluated in extended precision (``crossings_ld``, ``cover_ld``)."""
    p = region.crossings_ld
    s, ell = region.cover_ld[:, 0], region.cover_ld[:, 1]
    a, b = np.exp(1j * s), np.exp(1j * (s + ell))
    dx = phi_accurate(p, b) - phi_accurate(p, a)
    dy = phi_accurate(p, np.roll(b, -1)) - phi_accurate(p, np.roll(a, -1))
    ang = np.angle(dy / dx).astype(float)
    return np.degrees(np.abs(np.remainder(ang + math.pi / 2, math.pi) - math.pi / 2))


def _below(a: NDArray[np.complex128], b: NDArray[np.complex128], z: NDArray[np.complex128]):
    """True where ``z`` lies on the arc side (right of ``a→b``) of the geodesic ``(a, b)``
    whose arc runs counter-clockwise from ``a`` to ``b`` (Klein-model chord test)."""
    k = 2.0 * z / (1.0 + np.abs(z) ** 2)
    return (np.conj(b - a) * (k - a)).imag < 0.0


def piece_membership(region: RegionW, z: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """For sample points ``z``: how many pieces of W contain each, and the index of one of them.

    Piece indices: pentagons ``0..T-1``, then quads ``T..T+Q-1``, then triangles.  A pentagon
    contains ``z`` if ``g⁻¹(z)`` is inside P0; a quad if ``z`` is below its cover geodesic and
    between the perpendiculars at ``u_s, u_{s+1}`` (``Re ζ > 0``, ``1 < |ζ| < e^L`` in its H
    frame); a triangle if ``z`` is below both of its geodesics.  Used by the partition tests of
    Lemma 2.2(2).  Returns ``(count, piece)`` with ``piece = -1`` where ``count == 0``.
    """
    from .tessellation import EDGE_CENTERS, EDGE_RADIUS, L

    z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
    count = np.zeros(z.shape, dtype=np.int64)
    piece = np.full(z.shape, -1, dtype=np.int64)
    T = region.n_pentagons
    inv = region.tiles.inverse()
    for t in range(T):
        w = inv[t](z)
        inside = np.all(np.abs(w[:, None] - EDGE_CENTERS[None, :]) > EDGE_RADIUS, axis=1)
        count += inside
        piece[inside] = t
    for qi, q in enumerate(region.quads):
        X = region.cover[q.cover]
        a, b = X.a, X.b
        lam = (q.u0 - a) / (1j * (b - q.u0))
        zeta = (z - a) / (lam * (b - z))
        r = np.abs(zeta)
        inside = (zeta.real > 0) & (r > 1.0) & (r < math.exp(L))
        count += inside
        piece[inside] = T + qi
    Q = len(region.quads)
    for ti, tr in enumerate(region.triangles):
        X, Y = region.cover[tr.X], region.cover[tr.Y]
        inside = _below(X.a, X.b, z) & _below(Y.a, Y.b, z)
        count += inside
        piece[inside] = T + Q + ti
    return count, piece


def in_W(region: RegionW, z: ArrayLike) -> NDArray[np.bool_]:
    """True where ``z`` lies in W (above every ``γ_j``)."""
    z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
    out = np.ones(z.shape, dtype=bool)
    for g in region.gamma:
        out &= ~_below(g[0], g[1], z)
    return out
