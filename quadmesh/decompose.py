"""Thick/thin decomposition of a simple polygon (Bishop, §7 "Meshing the thick parts").

A polygonal domain Ω is δ-thick when any two non-adjacent sides have extremal distance at
least δ in Ω.  Where two non-adjacent sides come closer than that, Ω contains a *thin part*:

* **parabolic** thin parts, one per polygon vertex v_k (the two sides S_1, S_2 are the
  adjacent edges).  Their outer boundary is fixed later by the conformal map of the thick
  piece that contains v_k (the image of the hyperbolic geodesic over the interval J_k of
  Lemma 2.2), so here we only record the vertex, its angle, its sides and the size hint
  ``r_k = κ·d_k``, where ``d_k`` is the distance from v_k to every
  non-adjacent edge and to the far ends of its own edges.
* **hyperbolic** thin parts (:class:`Channel`): narrow channels between two non-adjacent
  straight edges (the *walls*) whose extremal distance is below δ.  The extremal distance is
  estimated in the channel's strip coordinate: ``width / length`` for
  parallel walls and ``β / log(r_b / r_a)`` for walls on two lines meeting at O with angle β
  (``log(z - O)`` maps the annular sector to a β-wide strip).

**Crosscuts and overlaps (paper, Figure "Overlap").**  Following the text of §7 we call
Ω_1 a thick piece and Ω_2 the thin part (the figure's caption swaps the two names).  For a
channel with walls over the common range ``[x_a, x_b]`` (``x`` = distance along the walls for
parallel walls, radius about O otherwise) the thin part Ω_2 is the whole band between the two
*outer crosscuts* γ' at the mouths ``x_a`` and ``x_b`` (the paper's γ_1 = ∂Ω_2 ∩ Ω_1).  Each
adjacent thick piece Ω_1 reaches deep into the channel, up to its *crosscut* γ (the paper's
γ_2 = ∂Ω_1 ∩ Ω_2), at strip depth ``D = overlap`` channel widths past the mouth:

    x_A = x_a + D·w(x_a)        (parallel)       r_A = r_a·exp(D·β)     (angled)
    x_B = x_b − D·w(x_b)                         r_B = r_b·exp(−D·β)

The overlap Ω_3 = Ω_1 ∩ Ω_2 is the band between γ' and γ; its middle section is Ω_4, where
the thick piece's map is close to a power function (Lemma "approx map") and where the image of
the disk geodesic over J_j (√A·I_j ⊂ J_j) lands, away from both γ and γ'.  The *core* of the
channel is the band between the two crosscuts γ_A and γ_B; it belongs to no thick piece and is
what the channel mesh fills (together with the parts of Ω_3 beyond the geodesic images).

Choice of the depth.  In a strip, harmonic measure decays like ``exp(−π·depth/width)``, so a
depth of ``1/(4δ)`` widths would give the paper's expansion ``A ≈ exp(π/(4δ))`` between
I_j = f⁻¹(γ) and the preimage I'_j of γ' in an infinite strip.  Measured with the SC map of
the thick pieces (δ = 0.15, D = 2.67): ``|I'_j|/|I_j|`` = 1750 (rectangle, tapered spike) to
2240 (dumbbell, comb), i.e. about ``exp(πD)/2.2`` because the piece ends near the mouth; with
D = 1/(4δ) alone it would be ≈ 76 < exp(π/(4δ)) ≈ 188.  Hence the default ``D = 1/(4δ) + 1``
widths, which also keeps every I'_j shorter than π.  Since ``D < 1/δ`` the walls inside a
thick piece have extremal distance ``1/D > δ``: thick pieces stay δ-thick (the tests decompose
every thick piece again and find no channel).  The price is a small I_j: a single channel stub
seen from the piece's centre has ``|I_j|`` ≈ 7e-4 (rectangle), 1e-5 (dumbbell), and the
prevertex gaps inside the crosscut are about |I_j|/4.

Crosscuts are straight segments perpendicular to wall 1 for parallel walls and circular arcs
about O otherwise (circles about O are orthogonal to both lines), polygonised with
``crosscut_vertices`` vertices each, ordered from wall 1 to wall 2.  Wall 1 is the wall
along which the counter-clockwise boundary moves away from O (increasing ``x``); wall 2
runs back.  No crosscut comes within ``r_k`` of a vertex v_k: vertex regions are never cut.

**Thick pieces** are the components of Ω minus the channel cores, built combinatorially by
walking the boundary and jumping across each core along its crosscuts, so that a crosscut's
vertex array is the same array in the thick piece and in the channel core.

**Crowding-driven refinement**.  A corridor whose straight legs are each too short for ED < δ
(square_spiral: seven legs of 1.5–6 widths, ~35 widths in all) stays inside one thick piece,
whose prevertex gaps then fall far below double precision (1e-36).  After the ordinary pass,
every thick piece that holds a *relaxed* candidate (ED < ``refine_delta`` = 0.5, overlap
depth ≥ ``refine_overlap`` = 1.5 and core ≥ ``refine_core`` = 1/4 widths) has its smallest
prevertex gap estimated as ``2π·min ω`` by the finite-element harmonic measure from its centre;
while one is below ``crowding_gap`` the most crowded piece gets its smallest-ED candidate, and
the pieces are rebuilt and re-estimated (:func:`_refine`).  The depth bound 1.5 keeps the
crosscut's prevertex arc small (|I_j| ≈ 7e-3 rad; the arc choice of the disk construction
failed for ~13 % of positions at |I_j| = 0.023, depth 1.25).  The A-expansion of a relaxed
channel is ≈ exp(πD)/2 (83 at D = 1.625) instead of ≥ 188; the meshes still verify.

Limitations: a wall is a single polygon edge; channels whose walls consist of several
collinear or nearly collinear edges, or bend (glyph_s: a curved corridor of ~20 widths made
of edges half a width long), are not detected as one channel, ordinary or relaxed, so such a
corridor stays inside a thick piece and makes its SC map crowd (glyph_s: 1.4e-13).  A channel
whose walls are partly blocked by other edges keeps its longest unblocked stretch.
Overlapping candidate channels are resolved greedily by increasing extremal distance.

Complexity: candidate wall pairs and vertex distances come from shapely ``STRtree`` queries
(edges within ``δ·length`` of each other, vertices within their adjacent edge lengths), so
the decomposition costs O(n log n) for polygons without pathological clustering.  The
refinement adds one relaxed candidate search (same cost) and one finite-element harmonic
measure (~0.01–0.1 s) per thick piece that holds a relaxed candidate, per added channel; a
polygon without relaxed candidates (the 1004-vertex comb) pays nothing more.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
from typing import ClassVar

import numpy as np
import shapely

from .errors import DecompositionError
from .polygon import Polygon, signed_area, validate_polygon
from .progress import checkpoint

__all__ = [
    "Channel",
    "ChannelFrame",
    "Corner",
    "DecomposeOptions",
    "Decomposition",
    "PieceCrosscut",
    "ThickPiece",
    "decompose",
]


# --------------------------------------------------------------------------------------
# options and results


@dataclass(frozen=True)
class DecomposeOptions:
    """Parameters of the thick/thin decomposition.

    Attributes:
        delta: channel threshold δ; a pair of facing non-adjacent edges whose estimated
            extremal distance is below δ is cut out as a hyperbolic thin part.
        kappa: vertex-sector factor κ, ``r_k = κ·d_k``.
        crosscut_vertices: number of vertices of each polygonised crosscut (endpoints
            included, at least 2).
        overlap: depth (in channel widths, i.e. strip units) by which each thick piece
            reaches past the channel mouth; ``None`` means ``1/(4δ) + 1``.  Must stay below
            ``1/δ`` so that thick pieces remain δ-thick.
        min_overlap: smallest admissible overlap depth; a channel too short to give both
            thick pieces this depth plus a core of ``min_core`` widths is left uncut.
        min_core: smallest core length, in channel widths.
        parallel_tol: walls whose directions differ by less than this angle (radians) are
            treated as parallel (perpendicular crosscuts) instead of meeting at O.  Keep it
            tiny: nearly parallel walls are handled exactly as a wedge with a far-away O
            (arcs of radius ~ width/β), so that both walls are exactly the frame's lines.
        center_tol: tolerance of the largest inscribed disk computation giving each thick
            piece's centre, relative to ``sqrt(area)`` of the piece.
        crowding_gap: crowding-driven refinement: while
            a thick piece's smallest prevertex gap, estimated as ``2π·min ω`` from its centre
            (:func:`quadmesh.conformal.center.harmonic_measure`), is below this value, one
            more channel with ED < ``refine_delta`` is cut inside it.  ``0`` disables it.
        refine_delta: the relaxed extremal-distance threshold of those extra channels, in
            (0, 1); the relaxed pass uses ``max(delta, refine_delta)``.
        refine_overlap: smallest overlap depth (widths) of those extra channels.  The
            crosscut's prevertex arc I_j shrinks like ``exp(−π·depth)``; the disk construction
            downstream needs it small against the neighbouring gaps (measured on
            square_spiral: depth 1.25 gives |I_j| ≈ 0.023 rad, and the arc choice then fails
            for ~13 % of positions; below |I_j| ≈ 6e-3 it never failed), hence 1.5.
        refine_core: smallest core length (widths) of those extra channels.  The channel
            mesh spans the whole band between the two geodesic images in the overlaps, so a
            short core is enough; a short core leaves deeper overlaps.  With the defaults a
            channel needs a strip length ≥ 3.25 (ED ≤ 0.31).
        refine_retry: shorter overlap depths (widths) tried, in decreasing order, when the
            relaxed pass at ``refine_overlap`` leaves a piece crowded or finds nothing in it:
            a serpentine corridor of legs 4 widths long has straight stretches of only 2.5
            widths between the vertex discs of its corners, too short for 2·1.5 + 0.25 but
            enough for 2·1.0 + 0.25.  ``()`` disables the retries.
    """

    delta: float = 0.15
    kappa: float = 0.25
    crosscut_vertices: int = 5
    overlap: float | None = None
    min_overlap: float = 1.0
    min_core: float = 1.0
    parallel_tol: float = 1e-8
    center_tol: float = 1e-2
    crowding_gap: float = 1e-9
    refine_delta: float = 0.5
    refine_overlap: float = 1.5
    refine_core: float = 0.25
    refine_retry: tuple[float, ...] = (1.25, 1.0)

    def __post_init__(self) -> None:
        def bad(name: str, rule: str) -> ValueError:
            return ValueError(f"DecomposeOptions.{name} must {rule}, got {getattr(self, name)!r}")

        for name in (
            "delta", "kappa", "min_overlap", "min_core", "parallel_tol", "center_tol",
            "crowding_gap", "refine_delta", "refine_overlap", "refine_core",
        ):  # fmt: skip
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not np.isfinite(v):
                raise bad(name, "be a finite number")
        if not (0.0 < self.delta < 1.0):
            raise bad("delta", "lie in (0, 1)")
        if not (0.0 < self.kappa <= 0.25):
            raise bad("kappa", "lie in (0, 1/4]")
        cv = self.crosscut_vertices
        if isinstance(cv, bool) or not isinstance(cv, numbers.Real) or int(cv) != cv or cv < 2:
            raise bad("crosscut_vertices", "be an integer of at least 2")
        for name in ("min_overlap", "min_core", "refine_overlap", "refine_core", "center_tol"):
            if getattr(self, name) <= 0:
                raise bad(name, "be positive")
        if not (0.0 < self.parallel_tol < 0.5):
            raise bad("parallel_tol", "lie in (0, 0.5) radians")
        if not (self.crowding_gap >= 0.0):
            raise bad("crowding_gap", "be >= 0")
        if not (0.0 < self.refine_delta < 1.0):
            raise bad("refine_delta", "lie in (0, 1)")
        if self.overlap is not None and (
            isinstance(self.overlap, bool)
            or not isinstance(self.overlap, numbers.Real)
            or not np.isfinite(self.overlap)
        ):
            raise bad("overlap", "be None or a finite number")
        retry = self.refine_retry
        if not isinstance(retry, tuple) or not all(
            isinstance(x, numbers.Real) and not isinstance(x, bool) and 0 < x <= self.refine_overlap
            for x in retry
        ):
            raise bad("refine_retry", "be a tuple of depths in (0, refine_overlap]")
        d = self.overlap_depth
        if not (self.min_overlap <= d < 1.0 / self.delta):
            raise ValueError(
                f"DecomposeOptions: the overlap depth {d:.3g} must lie in [min_overlap, 1/delta)"
                f" = [{self.min_overlap:.3g}, {1.0 / self.delta:.3g})"
                + ("" if self.overlap is not None else " (it is 1/(4·delta) + 1 by default)")
            )

    @property
    def overlap_depth(self) -> float:
        """The overlap depth D in channel widths (``1/(4δ) + 1`` unless set)."""
        return 1.0 / (4.0 * self.delta) + 1.0 if self.overlap is None else float(self.overlap)


@dataclass(frozen=True)
class Corner:
    """Parabolic thin part at polygon vertex ``index`` (paper §7).

    Attributes:
        index: polygon vertex index k.
        apex: the vertex v_k.
        angle: interior angle at v_k (radians).
        dir_out: unit direction of the outgoing side, from v_k towards v_{k+1}.
        dir_in: unit direction of the incoming side as a ray from v_k, towards v_{k-1}.
        d: distance from v_k to every non-adjacent edge and to the far ends of its sides.
        radius: size hint ``r_k = κ·d_k``; B(v_k, r_k) ∩ Ω is a true circular sector.
        piece: index of the thick piece containing v_k.
        piece_vertex: index of v_k among that piece's vertices.
    """

    kind: ClassVar[str] = "parabolic"
    index: int
    apex: complex
    angle: float
    dir_out: complex
    dir_in: complex
    d: float
    radius: float
    piece: int
    piece_vertex: int


@dataclass(frozen=True)
class ChannelFrame:
    """Coordinates of a channel's walls.

    ``kind == "angled"``: the walls lie on two lines meeting at ``origin`` = O; wall 1 lies on
    the ray ``O + t·direction`` (t > 0) and wall 2 on the ray at angle ``beta`` (0 < β < π)
    counter-clockwise from it.  The channel coordinate of a point is its radius ``|z − O|``.

    ``kind == "parallel"``: ``origin`` is the start of wall 1, ``direction`` its unit
    direction; wall 2 lies on the left at distance ``width``.  The coordinate is the abscissa
    along ``direction``.

    These are the data of :class:`quadmesh.thin.channel.Walls`: ``Walls.wedge(origin,
    direction, beta)`` or ``Walls.parallel(origin, direction, width)``.
    """

    kind: str
    origin: complex
    direction: complex
    beta: float
    width: float = 0.0

    def coordinate(self, z: np.ndarray | complex) -> np.ndarray:
        """The channel coordinate x of points z (abscissa, or radius about O)."""
        w = np.asarray(z, dtype=np.complex128) - self.origin
        if self.kind == "angled":
            return np.abs(w)
        return (w * np.conj(self.direction)).real

    def strip(self, z: np.ndarray | complex) -> np.ndarray:
        """Strip coordinates: ``log((z − O)/direction)`` (angled) or ``(z − origin)/direction``.

        Wall 1 maps to the real axis, wall 2 to ``Im = β`` (angled) or ``Im = width``.
        """
        w = (np.asarray(z, dtype=np.complex128) - self.origin) / self.direction
        if self.kind == "angled":
            return np.log(w)
        return w


@dataclass(frozen=True)
class Channel:
    """Hyperbolic thin part: a narrow channel between two non-adjacent edges.

    Attributes:
        id: index in :attr:`Decomposition.channels`.
        walls: (wall 1, wall 2) polygon edge indices (edge k = [v_k, v_{k+1}]).
        frame: the walls' frame (:class:`ChannelFrame`).
        extremal_distance: estimate of the extremal distance between the walls across the
            thin part Ω_2 (between the mouths): ``1 / strip length``.
        mouths: channel coordinates (x_a, x_b) of the outer crosscuts γ' (thin part ends).
        cuts: channel coordinates (x_A, x_B) of the crosscuts γ_A, γ_B that bound the core.
        crosscuts: (γ_A, γ_B), complex vertex arrays ordered from wall 1 to wall 2; γ_A is
            the thick piece ``pieces[0]``'s boundary, γ_B that of ``pieces[1]``.
        outer_crosscuts: (γ'_a, γ'_b) at the mouths, same ordering.
        widths: channel width (parallel) or angle β (angled) at the two mouths, the strip
            width in which ``overlap`` is measured.
        pieces: thick piece indices on the a-side and the b-side.
        relaxed: True for a channel cut by the crowding refinement (its extremal distance
            lies in ``[delta, refine_delta)``, so its overlaps may be shallower than
            ``overlap_depth``: ``min(overlap_depth, (strip length − min_core)/2)``).
    """

    kind: ClassVar[str] = "hyperbolic"
    id: int
    walls: tuple[int, int]
    frame: ChannelFrame
    extremal_distance: float
    mouths: tuple[float, float]
    cuts: tuple[float, float]
    crosscuts: tuple[np.ndarray, np.ndarray]
    outer_crosscuts: tuple[np.ndarray, np.ndarray]
    widths: tuple[float, float]
    pieces: tuple[int, int] = (-1, -1)
    relaxed: bool = False

    @property
    def core_z(self) -> np.ndarray:
        """Counter-clockwise complex vertices of the core (γ_A, wall 1, γ_B, wall 2)."""
        ga, gb = self.crosscuts
        return np.concatenate([gb, ga[::-1]])

    @property
    def core(self) -> np.ndarray:
        """The core as an (k, 2) array, counter-clockwise."""
        return _xy(self.core_z)

    @property
    def core_area(self) -> float:
        """Area of the polygonised core."""
        return signed_area(self.core_z)


@dataclass(frozen=True)
class PieceCrosscut:
    """A crosscut stretch of a thick piece's boundary.

    The piece vertices ``start, start+1, …, stop`` (indices modulo the piece size) are the
    crosscut ``channel.crosscuts[end]`` (``end`` 0 = γ_A, 1 = γ_B), in stored order (wall 1 →
    wall 2) or, when ``reversed``, from wall 2 to wall 1.
    """

    start: int
    stop: int
    channel: int
    end: int
    reversed: bool


@dataclass(frozen=True)
class ThickPiece:
    """A δ-thick piece Ω_1 of the decomposition.

    Attributes:
        index: index in :attr:`Decomposition.thick`.
        z: complex vertices, counter-clockwise.
        source: polygon vertex index of each piece vertex, −1 for crosscut vertices.
        crosscuts: the crosscut stretches of the boundary (:class:`PieceCrosscut`).
        center: centre of the largest inscribed disk (the point f(0) of its SC map).
        radius: radius of that disk.
        min_gap: estimate of the smallest prevertex gap (radians) of the piece's disk map
            with f(0) = ``center``: ``2π·min_k ω(center, side_k)``.  Estimated only where the
            crowding refinement could split the piece further (it held a relaxed channel
            candidate at some overlap depth); NaN otherwise, when the refinement is off
            (``crowding_gap = 0``) or when the estimate failed.
        inscribed_gap: the same estimate with f(0) at the centre of the largest inscribed
            disk, when ``center`` was moved away from there because that point crowded the
            map (:func:`_least_crowded`); NaN otherwise. It says how crowded the piece's shape
            is (whether it is a corridor), whatever centre its map uses.
    """

    index: int
    z: np.ndarray
    source: np.ndarray
    crosscuts: tuple[PieceCrosscut, ...]
    center: complex
    radius: float
    min_gap: float = float("nan")
    inscribed_gap: float = float("nan")

    @property
    def vertices(self) -> np.ndarray:
        """Vertices as an (k, 2) float array."""
        return _xy(self.z)

    @property
    def area(self) -> float:
        """Area of the piece."""
        return signed_area(self.z)


@dataclass(frozen=True)
class Decomposition:
    """Result of :func:`decompose`: thick pieces, hyperbolic and parabolic thin parts.

    Attributes:
        polygon: the validated polygon (counter-clockwise).
        options: the options used.
        thick: the δ-thick pieces Ω_1 (:class:`ThickPiece`); with the channel cores they
            tile the polygon.
        channels: the hyperbolic thin parts (:class:`Channel`), ``channels[k].id == k``.
        corners: the parabolic thin parts, one per polygon vertex (:class:`Corner`).
        candidates: number of facing wall pairs examined after the cheap prefilters (a
            measure of the work; O(n) for ordinary polygons).
    """

    polygon: Polygon
    options: DecomposeOptions
    thick: tuple[ThickPiece, ...]
    channels: tuple[Channel, ...]
    corners: tuple[Corner, ...]
    candidates: int = field(default=0)

    @property
    def thin_parts(self) -> tuple[Corner | Channel, ...]:
        """All thin parts: the parabolic corners, then the hyperbolic channels."""
        return (*self.corners, *self.channels)

    def describe_piece(self, k: int) -> str:
        """Thick piece ``k`` said in the user's terms, for messages.

        E.g. ``"the part of the polygon through vertices 12 to 17 and 3 to 5 (around
        (2.5, 1))"``: the runs of polygon vertices on the piece's boundary in the user's
        numbering (:meth:`quadmesh.polygon.Polygon.user_vertex`, in the user's order) and
        the centre of its largest inscribed disk in the user's coordinates.
        """
        piece = self.thick[int(k)]
        return (
            f"the part of the polygon through {_describe_runs(self.polygon, piece.source)} "
            f"(around {self.polygon.user_point(piece.center)})"
        )

    def describe_channel(self, k: int) -> str:
        """Channel ``k`` said in the user's terms: the narrow passage between its two wall
        edges, in the user's numbering and coordinates."""
        c = self.channels[int(k)]
        poly = self.polygon
        return (
            f"the narrow passage between {poly.describe_edge(c.walls[0])} and "
            f"{poly.describe_edge(c.walls[1])}"
        )


# --------------------------------------------------------------------------------------
# helpers


def _xy(z: np.ndarray) -> np.ndarray:
    return np.column_stack([z.real, z.imag])


def _describe_runs(poly: Polygon, source: np.ndarray, max_runs: int = 4) -> str:
    """``"vertices 12 to 17 and 3 to 5"``: maximal runs of consecutive polygon vertices among
    ``source`` (piece order, −1 = not a polygon vertex) in the user's numbering and order."""
    src = np.asarray(source)
    runs: list[list[int]] = []
    prev = -2
    for v in src.tolist():
        if v < 0:
            prev = -2
            continue
        if runs and prev >= 0 and v == (prev + 1) % poly.n:
            runs[-1].append(v)
        else:
            runs.append([v])
        prev = v
    if len(runs) > 1 and runs[0][0] == (runs[-1][-1] + 1) % poly.n and src[0] >= 0 and src[-1] >= 0:
        runs[0] = runs.pop() + runs[0]  # the piece's vertex list started inside a run
    if not runs:
        return "no polygon vertex"
    parts = []
    for run in runs:
        a, b = poly.user_vertex(run[0]), poly.user_vertex(run[-1])
        if poly.reversed_input:
            a, b = b, a
        through = " (through 0)" if b < a else ""  # the run wraps past the user's vertex 0
        parts.append(f"vertex {a}" if len(run) == 1 else f"vertices {a} to {b}{through}")
    more = f" and {len(parts) - max_runs} more stretches" if len(parts) > max_runs else ""
    parts = parts[:max_runs]
    body = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
    return body + more


def _vertex_distances(z: np.ndarray, segs: np.ndarray, tree: shapely.STRtree) -> np.ndarray:
    """d_k = min(|e_{k-1}|, |e_k|, dist(v_k, non-adjacent edges)) by an STRtree query."""
    n = z.size
    length = np.abs(np.roll(z, -1) - z)
    d = np.minimum(length, np.roll(length, 1))
    pts = shapely.points(_xy(z))
    vi, ei = tree.query(pts, predicate="dwithin", distance=d)
    keep = (ei != vi) & (ei != (vi - 1) % n)
    vi, ei = vi[keep], ei[keep]
    if vi.size:
        dist = shapely.distance(pts[vi], segs[ei])
        np.minimum.at(d, vi, dist)
    return d


@dataclass
class _Candidate:
    """A channel found for one wall pair before conflicts are resolved."""

    wall1: int
    wall2: int
    frame: ChannelFrame
    ed: float
    mouths: tuple[float, float]
    cuts: tuple[float, float]
    widths: tuple[float, float]
    lam: tuple[tuple[float, float], tuple[float, float]]  # edge parameters of γ_A, γ_B on walls
    core: shapely.Polygon | None = None
    relaxed: bool = False


def _wall_point(z: np.ndarray, edge: int, x: float, xa: float, xb: float) -> tuple[float, complex]:
    """Edge parameter and point on ``edge`` at channel coordinate x (x linear along the edge)."""
    n = z.size
    lam = (x - xa) / (xb - xa)
    p, q = z[edge], z[(edge + 1) % n]
    return lam, p + lam * (q - p)


def _crosscut(frame: ChannelFrame, p1: complex, p2: complex, m: int) -> np.ndarray:
    """Polygonised crosscut from p1 (wall 1) to p2 (wall 2) with m vertices."""
    t = np.linspace(0.0, 1.0, m)
    if frame.kind == "angled":
        a1 = np.log(p1 - frame.origin)
        a2 = np.log(p2 - frame.origin)
        # same radius up to rounding; interpolate log-radius and angle along the arc
        da = np.angle(np.exp(a2 - a1))
        w = a1 + t * (a2.real - a1.real + 1j * da)
        c = frame.origin + np.exp(w)
    else:
        c = p1 + t * (p2 - p1)
    c[0], c[-1] = p1, p2
    return c


# --------------------------------------------------------------------------------------
# channel detection


def _find_channels(
    z: np.ndarray,
    segs: np.ndarray,
    tree: shapely.STRtree,
    r: np.ndarray,
    opt: DecomposeOptions,
    delta: float,
    min_overlap: float,
    min_core: float,
) -> tuple[list[_Candidate], int]:
    """Candidate channels for all facing wall pairs with ED < delta: overlap depth
    ``min(opt.overlap_depth, (strip length − min_core)/2)``, at least
    ``min_overlap``."""
    n = z.size
    zn = np.roll(z, -1)
    edge = zn - z
    length = np.abs(edge)
    u = edge / length
    mid = 0.5 * (z + zn)

    # 1. pairs of non-adjacent edges within δ·length of each other, facing each other
    a, b = tree.query(segs, predicate="dwithin", distance=delta * length)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keep = (lo != hi) & ((hi - lo) % n != 1) & ((lo - hi) % n != 1)
    pairs = np.unique(np.stack([lo[keep], hi[keep]], axis=1), axis=0)
    if pairs.size == 0:
        return [], 0
    a, b = pairs[:, 0], pairs[:, 1]
    opposite = (u[a] * np.conj(u[b])).real < 0
    a, b = a[opposite], b[opposite]
    sin_ab = (np.conj(u[a]) * u[b]).imag
    parallel = np.abs(sin_ab) < np.sin(opt.parallel_tol)

    frames: list[tuple[int, int, ChannelFrame, float, float]] = []

    # parallel walls: wall 1 = a, x along u_a from z_a
    pa, pb = a[parallel], b[parallel]
    if pa.size:
        t = u[pa]
        y_mid = ((mid[pb] - z[pa]) * np.conj(t)).imag
        x_b0 = ((zn[pb] - z[pa]) * np.conj(t)).real  # wall 2 runs backwards: start at v_{b+1}
        x_b1 = ((z[pb] - z[pa]) * np.conj(t)).real
        xlo = np.maximum(0.0, x_b0)
        xhi = np.minimum(length[pa], x_b1)
        ok = (y_mid > 0) & (xhi > xlo)
        for i, j, o, xl, xh, y in zip(
            pa[ok], pb[ok], t[ok], xlo[ok], xhi[ok], y_mid[ok], strict=True
        ):
            fr = ChannelFrame("parallel", complex(z[i]), complex(o), 0.0, float(y))
            frames.append((int(i), int(j), fr, xl, xh))

    # walls meeting at O
    na, nb = a[~parallel], b[~parallel]
    if na.size:
        s = ((z[nb] - z[na]) * np.conj(u[nb])).imag / (u[na] * np.conj(u[nb])).imag
        O = z[na] + s * u[na]
        ga = ((mid[na] - O) * np.conj(u[na])).real  # > 0: moving away from O
        gb = ((mid[nb] - O) * np.conj(u[nb])).real
        w1 = np.where(ga > 0, na, nb)
        w2 = np.where(ga > 0, nb, na)
        ok = (ga > 0) != (gb > 0)
        # O must not lie on either wall
        r10, r11 = np.abs(z[w1] - O), np.abs(zn[w1] - O)
        r20, r21 = np.abs(zn[w2] - O), np.abs(z[w2] - O)
        ok &= (r11 > r10) & (r21 > r20)
        ok &= (np.abs(z[w1] + zn[w1] - 2 * O) > np.abs(edge[w1]) * (1 + 1e-12)) & (
            np.abs(z[w2] + zn[w2] - 2 * O) > np.abs(edge[w2]) * (1 + 1e-12)
        )
        # (nearly parallel walls put O at infinity, or a wall's midpoint on O: such rows come
        # out NaN and are dropped by the comparisons)
        with np.errstate(divide="ignore", invalid="ignore"):
            e1 = (mid[w1] - O) / np.abs(mid[w1] - O)
            e2 = (mid[w2] - O) / np.abs(mid[w2] - O)
            beta = np.angle(e2 / e1)
            ok &= (beta > 0) & (beta < np.pi)
            xlo = np.maximum(r10, r20)
            xhi = np.minimum(r11, r21)
            ok &= xhi > xlo
            # prefilter: extremal distance over the whole common range
            ok &= beta / np.log(xhi / xlo) < delta
        for i, j, o, e, bb, xl, xh in zip(
            w1[ok], w2[ok], O[ok], e1[ok], beta[ok], xlo[ok], xhi[ok], strict=True
        ):
            frames.append(
                (int(i), int(j), ChannelFrame("angled", complex(o), complex(e), float(bb)), xl, xh)
            )

    if not frames:
        return [], 0

    # width along a parallel channel: y of wall 2 as a linear function of x
    def width_fn(fr: ChannelFrame, j: int) -> tuple[float, float, float, float]:
        w0 = ((zn[j] - fr.origin) * np.conj(fr.direction)).imag
        w1_ = ((z[j] - fr.origin) * np.conj(fr.direction)).imag
        x0 = fr.coordinate(zn[j]).item()
        x1 = fr.coordinate(z[j]).item()
        return x0, w0, x1, w1_

    def strip_len(
        fr: ChannelFrame, wf: tuple[float, float, float, float], xl: float, xh: float
    ) -> float:
        if fr.kind == "angled":
            return float(np.log(xh / xl) / fr.beta)
        x0, w0, x1, w1_ = wf
        k = (w1_ - w0) / (x1 - x0)
        yl, yh = w0 + k * (xl - x0), w0 + k * (xh - x0)
        if abs(yh - yl) <= 1e-12 * max(yl, yh):
            return float((xh - xl) * 2.0 / (yl + yh))
        return float((xh - xl) * np.log(yh / yl) / (yh - yl))

    def width_at(fr: ChannelFrame, wf: tuple[float, float, float, float], x: float) -> float:
        if fr.kind == "angled":
            return fr.beta
        x0, w0, x1, w1_ = wf
        return float(w0 + (w1_ - w0) * (x - x0) / (x1 - x0))

    # prefilter parallel pairs by extremal distance over the whole common range
    wfs = [
        width_fn(f[2], f[1]) if f[2].kind == "parallel" else (0.0, 0.0, 0.0, 0.0) for f in frames
    ]
    keep_f = []
    for f, wf in zip(frames, wfs, strict=True):
        if f[2].kind == "parallel":
            if min(width_at(f[2], wf, f[3]), width_at(f[2], wf, f[4])) <= 0:
                continue
            if 1.0 / strip_len(f[2], wf, f[3], f[4]) >= delta:
                continue
        keep_f.append((f, wf))
    if not keep_f:
        return [], 0
    frames = [f for f, _ in keep_f]
    wfs = [wf for _, wf in keep_f]

    # 2. the region Q between the walls over the common range; obstructions and vertex regions
    m_arc = 9
    qs = []
    for (i, j, fr, xl, xh), _wf in zip(frames, wfs, strict=True):
        p1l = _wall_point(z, i, xl, fr.coordinate(z[i]).item(), fr.coordinate(zn[i]).item())[1]
        p1h = _wall_point(z, i, xh, fr.coordinate(z[i]).item(), fr.coordinate(zn[i]).item())[1]
        p2l = _wall_point(z, j, xl, fr.coordinate(z[j]).item(), fr.coordinate(zn[j]).item())[1]
        p2h = _wall_point(z, j, xh, fr.coordinate(z[j]).item(), fr.coordinate(zn[j]).item())[1]
        if fr.kind == "angled":
            ring = np.concatenate(
                [_crosscut(fr, p1h, p2h, m_arc), _crosscut(fr, p1l, p2l, m_arc)[::-1]]
            )
        else:
            ring = np.array([p1l, p1h, p2h, p2l])
        qs.append(shapely.Polygon(_xy(ring)))
    qs_arr = np.array(qs, dtype=object)
    # shrink Q a little so that the walls themselves (and edges touching its corners) don't hit
    wid = np.array(
        [
            width_at(f[2], wf, f[3]) * (f[3] if f[2].kind == "angled" else 1.0)
            for f, wf in zip(frames, wfs, strict=True)
        ]
    )
    q_in = shapely.buffer(qs_arr, -1e-7 * wid, join_style="mitre")

    # blocked stretches of the channel coordinate: other edges inside Q, and vertex regions
    # B(v_k, r_k) near Q (a crosscut at coordinate x is at distance ≥ |x − x(v_k)| from v_k)
    f_ang = np.array([f[2].kind == "angled" for f in frames])
    f_org = np.array([f[2].origin for f in frames])
    f_dir = np.array([f[2].direction for f in frames])

    def coord(rows: np.ndarray, pts: np.ndarray) -> np.ndarray:
        w = pts - f_org[rows]
        return np.where(f_ang[rows], np.abs(w), (w * np.conj(f_dir[rows])).real)

    blk_row: list[np.ndarray] = []
    blk_lo: list[np.ndarray] = []
    blk_hi: list[np.ndarray] = []
    qi, ei = tree.query(q_in, predicate="intersects")
    own = np.array([(f[0], f[1]) for f in frames])
    sel = (ei != own[qi, 0]) & (ei != own[qi, 1])
    qi, ei = qi[sel], ei[sel]
    if qi.size:
        inter = shapely.intersection(segs[ei], qs_arr[qi])
        coords, idx = shapely.get_coordinates(inter, return_index=True)
        if idx.size:
            xs = coord(qi[idx], coords[:, 0] + 1j * coords[:, 1])
            rows, first = np.unique(idx, return_index=True)  # idx is sorted
            blk_row.append(qi[rows])
            blk_lo.append(np.minimum.reduceat(xs, first))
            blk_hi.append(np.maximum.reduceat(xs, first))
    boxes = shapely.box(z.real - r, z.imag - r, z.real + r, z.imag + r)
    qv, vv = shapely.STRtree(boxes).query(qs_arr, predicate="intersects")
    if qv.size:
        dist = shapely.distance(qs_arr[qv], shapely.points(_xy(z[vv])))
        near = dist < r[vv]
        qv, vv = qv[near], vv[near]
        xv = coord(qv, z[vv])
        blk_row.append(qv)
        blk_lo.append(xv - r[vv])
        blk_hi.append(xv + r[vv])
    blocked: list[list[tuple[float, float]]] = [[] for _ in frames]
    if blk_row:
        for row, bl, bh in zip(
            np.concatenate(blk_row), np.concatenate(blk_lo), np.concatenate(blk_hi), strict=True
        ):
            blocked[row].append((float(bl), float(bh)))

    # 3. longest free stretch, extremal distance, crosscut positions
    depth = opt.overlap_depth
    out: list[_Candidate] = []
    for k, ((i, j, fr, xl, xh), wf) in enumerate(zip(frames, wfs, strict=True)):
        cuts = sorted(blocked[k])
        free: list[tuple[float, float]] = []
        cur = xl
        for bl, bh in cuts:
            if bl > cur:
                free.append((cur, min(bl, xh)))
            cur = max(cur, bh)
            if cur >= xh:
                break
        if cur < xh:
            free.append((cur, xh))
        free = [(p, q) for p, q in free if q > p and (fr.kind == "parallel" or p > 0)]
        if not free:
            continue
        lens = [strip_len(fr, wf, p, q) for p, q in free]
        best = int(np.argmax(lens))
        xa, xb = free[best]
        total = lens[best]
        if 1.0 / total >= delta:
            continue
        dd = min(depth, 0.5 * (total - min_core))
        if dd < min_overlap:
            continue
        wa, wb = width_at(fr, wf, xa), width_at(fr, wf, xb)
        if fr.kind == "angled":
            xA, xB = xa * np.exp(dd * fr.beta), xb * np.exp(-dd * fr.beta)
        else:
            xA, xB = xa + dd * wa, xb - dd * wb
        if not (xa < xA < xB < xb) or strip_len(fr, wf, xA, xB) < min_core * (1 - 1e-9):
            continue
        c1 = (fr.coordinate(z[i]).item(), fr.coordinate(zn[i]).item())
        c2 = (fr.coordinate(z[j]).item(), fr.coordinate(zn[j]).item())
        lam = (
            (_wall_point(z, i, xA, *c1)[0], _wall_point(z, j, xA, *c2)[0]),
            (_wall_point(z, i, xB, *c1)[0], _wall_point(z, j, xB, *c2)[0]),
        )
        out.append(
            _Candidate(
                i, j, fr, 1.0 / total, (float(xa), float(xb)), (float(xA), float(xB)), (wa, wb), lam
            )
        )
    return out, len(frames)


# --------------------------------------------------------------------------------------
# thick pieces


def _build_pieces(
    z: np.ndarray,
    channels: list[Channel],
    lams: list[tuple[tuple[float, float], tuple[float, float]]],
) -> list[tuple[np.ndarray, np.ndarray, list[tuple[int, int, int, int, bool]]]]:
    """Walk ∂Ω, jumping across each channel core along its crosscuts.

    Each core removes the stretch [γ_A, γ_B] of wall 1 and [γ_B, γ_A] of wall 2 from the
    boundary.  Walking counter-clockwise we reach a removed stretch at its start, cross the
    crosscut there and continue from the end of the removed stretch on the other wall.
    Returns, per piece, (vertices, source, [(start, stop, channel, end, reversed)]).
    """
    n = z.size
    if not channels:
        return [(z.copy(), np.arange(n), [])]
    # removed stretches: (tau_start, tau_end, channel, end, reversed, partner stretch)
    starts, ends, info = [], [], []
    for c, (la, lb) in zip(channels, lams, strict=True):
        i, j = c.walls
        # wall 1: from γ_A (start, crossing γ_A forwards) to γ_B
        starts.append(i + la[0])
        ends.append(i + lb[0])
        info.append((c.id, 0, False))
        # wall 2: from γ_B (start, crossing γ_B backwards) to γ_A
        starts.append(j + lb[1])
        ends.append(j + la[1])
        info.append((c.id, 1, True))
    starts_a = np.array(starts)
    ends_a = np.array(ends)
    order = np.argsort(starts_a)
    # crossing at the start of stretch k (on one wall) lands at the end of its partner
    partner = np.arange(len(starts)) ^ 1
    visited = np.zeros(len(starts), dtype=bool)
    pieces = []
    chmap = {c.id: c for c in channels}
    for k0 in order:
        if visited[k0]:
            continue
        verts: list[np.ndarray] = []
        src: list[np.ndarray] = []
        cuts: list[tuple[int, int, int, int, bool]] = []
        count = 0
        k = int(k0)
        while not visited[k]:
            visited[k] = True
            cid, end, rev = info[k]
            g = chmap[cid].crosscuts[end]
            g = g[::-1] if rev else g
            cuts.append((count, count + g.size - 1, cid, end, rev))
            verts.append(g)
            src.append(np.full(g.size, -1))
            count += g.size
            p = int(partner[k])
            te = ends_a[p]
            nxt = _next_start(starts_a, order, te)
            ts = starts_a[nxt]
            a0 = int(np.floor(te)) + 1
            b0 = int(np.floor(ts))
            if ts > te:
                idx = np.arange(a0, b0 + 1)
            else:
                idx = np.concatenate([np.arange(a0, n), np.arange(0, b0 + 1)])
            idx = idx % n
            verts.append(z[idx])
            src.append(idx)
            count += idx.size
            k = nxt
        if k != k0:
            raise DecompositionError("the cuts across the narrow passages cross each other")
        pieces.append((np.concatenate(verts), np.concatenate(src), cuts))
    return pieces


def _next_start(starts: np.ndarray, order: np.ndarray, t: float) -> int:
    """Index of the first removed stretch starting after boundary parameter t (cyclic)."""
    s_sorted = starts[order]
    pos = int(np.searchsorted(s_sorted, t, side="right"))
    return int(order[pos % order.size])


# --------------------------------------------------------------------------------------
# main entry


def decompose(polygon: object, options: DecomposeOptions | None = None) -> Decomposition:
    """Thick/thin decomposition of a simple polygon (Bishop §7).

    Args:
        polygon: anything :func:`quadmesh.polygon.validate_polygon` accepts.
        options: :class:`DecomposeOptions` (defaults: δ = 0.15, κ = 1/4, 5 crosscut vertices).

    Returns:
        :class:`Decomposition` with the thick pieces (simple CCW polygons whose crosscut
        stretches are recorded), the hyperbolic thin parts (channels with walls, frame,
        crosscuts, core and extremal-distance estimate) and one parabolic thin part per
        polygon vertex.  The thick pieces and the channel cores tile the polygon.

    Raises:
        PolygonError: invalid polygon.
        DecompositionError: the pieces could not be assembled consistently.

    Example:
        >>> d = decompose([(0, 0), (20, 0), (20, 1), (0, 1)])
        >>> len(d.channels), len(d.thick)
        (1, 2)
    """
    opt = DecomposeOptions() if options is None else options
    poly = validate_polygon(polygon)
    z = poly.z
    n = z.size
    segs = shapely.linestrings(np.stack([_xy(z), _xy(np.roll(z, -1))], axis=1))
    tree = shapely.STRtree(segs)

    d = _vertex_distances(z, segs, tree)
    checkpoint(0.2)
    r = opt.kappa * d

    cands, n_pairs = _find_channels(z, segs, tree, r, opt, opt.delta, opt.min_overlap, opt.min_core)
    checkpoint(0.5)

    # resolve overlapping candidates greedily by extremal distance
    m = int(opt.crosscut_vertices)
    chosen: list[_Candidate] = []
    if cands:
        cores = []
        for c in cands:
            ga, gb = _candidate_crosscuts(z, c, m)
            cores.append(shapely.Polygon(_xy(np.concatenate([gb, ga[::-1]]))))
        ctree = shapely.STRtree(cores)
        taken = np.zeros(len(cands), dtype=bool)
        for k in np.argsort([c.ed for c in cands], kind="stable"):
            hits = ctree.query(cores[k], predicate="intersects")
            if np.any(taken[hits]):
                continue
            taken[k] = True
        chosen = [cands[k] for k in np.flatnonzero(taken)]

    try:
        built = _assemble(z, chosen, m, opt)
    except DecompositionError as exc:
        walls = "; ".join(
            f"{poly.describe_edge(c.wall1)} and {poly.describe_edge(c.wall2)}" for c in chosen[:3]
        )
        more = f" (and {len(chosen) - 3} more)" if len(chosen) > 3 else ""
        raise DecompositionError(
            f"{exc.args[0]}; the narrow passages lie between {walls}{more}: widening one of "
            "them, or moving vertices away from its walls, avoids the cut"
        ) from exc
    channels, raw, centres = built
    checkpoint(0.7)
    gaps = [float("nan")] * len(raw)
    if opt.crowding_gap > 0:
        channels, raw, centres, gaps = _refine(z, segs, tree, r, opt, chosen, built, m)
    centres = _uncrowd(raw, channels, centres)

    thick: list[ThickPiece] = []
    piece_of_end: dict[tuple[int, int], int] = {}
    for k, ((v, s, cuts), (ctr, rad, g_in), gap) in enumerate(zip(raw, centres, gaps, strict=True)):
        pcs = tuple(PieceCrosscut(a, b, cid, e, rev) for a, b, cid, e, rev in cuts)
        for pc in pcs:
            piece_of_end[(pc.channel, pc.end)] = k
        thick.append(
            ThickPiece(
                index=k,
                z=_frozen(v),
                source=_frozen(s.astype(np.int64)),
                crosscuts=pcs,
                center=ctr,
                radius=rad,
                # the refinement's estimate holds for the inscribed centre only
                min_gap=float(gap) if np.isnan(g_in) else float("nan"),
                inscribed_gap=float(g_in),
            )
        )
    channels = [
        Channel(**{**c.__dict__, "pieces": (piece_of_end[(c.id, 0)], piece_of_end[(c.id, 1)])})
        for c in channels
    ]

    # tiling check: thick pieces and cores add up to the polygon
    total = sum(p.area for p in thick) + sum(c.core_area for c in channels)
    if abs(total - poly.area) > 1e-9 * poly.area or any(p.area <= 0 for p in thick):
        raise DecompositionError(
            f"the cut-off narrow passages and the remaining parts do not add up to the polygon "
            f"(area {total:.9g} against {poly.area:.9g}); a narrow passage between "
            + " and ".join(
                f"{poly.describe_edge(c.walls[0])} / {poly.describe_edge(c.walls[1])}"
                for c in channels[:3]
            )
            + " was cut inconsistently"
        )

    # parabolic thin parts
    where = np.full((n, 2), -1, dtype=np.int64)
    for p in thick:
        idx = np.flatnonzero(p.source >= 0)
        where[p.source[idx], 0] = p.index
        where[p.source[idx], 1] = idx
    if np.any(where[:, 0] < 0):
        k = int(np.flatnonzero(where[:, 0] < 0)[0])
        raise DecompositionError(
            f"{poly.describe_vertex(k)} fell inside a narrow passage that was cut off; "
            "the passage's walls pass too close to it"
        )
    zn = np.roll(z, -1)
    zp = np.roll(z, 1)
    u_out = (zn - z) / np.abs(zn - z)
    u_in = (zp - z) / np.abs(zp - z)
    corners = tuple(
        Corner(
            index=k,
            apex=complex(z[k]),
            angle=float(poly.angles[k]),
            dir_out=complex(u_out[k]),
            dir_in=complex(u_in[k]),
            d=float(d[k]),
            radius=float(r[k]),
            piece=int(where[k, 0]),
            piece_vertex=int(where[k, 1]),
        )
        for k in range(n)
    )
    return Decomposition(
        polygon=poly,
        options=opt,
        thick=tuple(thick),
        channels=tuple(channels),
        corners=corners,
        candidates=n_pairs,
    )


_Raw = list[tuple[np.ndarray, np.ndarray, list[tuple[int, int, int, int, bool]]]]


def _assemble(
    z: np.ndarray, chosen: list[_Candidate], m: int, opt: DecomposeOptions
) -> tuple[list[Channel], _Raw, list[tuple[complex, float]]]:
    """Channels (numbered by their walls), thick pieces and piece centres for a set of
    non-overlapping candidates.  Raises DecompositionError when a piece is not simple."""
    chosen = sorted(chosen, key=lambda c: (min(c.wall1, c.wall2), c.wall1))
    channels: list[Channel] = []
    lams = []
    for cid, c in enumerate(chosen):
        ga, gb = _candidate_crosscuts(z, c, m)
        oa = _outer_crosscut(z, c, c.mouths[0], m)
        ob = _outer_crosscut(z, c, c.mouths[1], m)
        channels.append(
            Channel(
                id=cid,
                walls=(c.wall1, c.wall2),
                frame=c.frame,
                extremal_distance=float(c.ed),
                mouths=c.mouths,
                cuts=c.cuts,
                crosscuts=(_frozen(ga), _frozen(gb)),
                outer_crosscuts=(_frozen(oa), _frozen(ob)),
                widths=(float(c.widths[0]), float(c.widths[1])),
                relaxed=c.relaxed,
            )
        )
        lams.append(c.lam)
    raw = _build_pieces(z, channels, lams)
    polys = [shapely.Polygon(_xy(v)) for v, _, _ in raw]
    if not all(p.is_valid for p in polys):
        bad = [k for k, p in enumerate(polys) if not p.is_valid]
        raise DecompositionError(
            f"{len(bad)} of the parts left after cutting off the narrow passages would not be "
            "simple polygons"
        )
    centres = _centres(raw, channels, polys, opt.center_tol)
    return channels, raw, centres


def _band(z: np.ndarray, c: _Candidate, m: int) -> shapely.Polygon:
    """The thin part Ω_2 of a candidate: the band between its outer crosscuts γ'_a, γ'_b."""
    oa = _outer_crosscut(z, c, c.mouths[0], m)
    ob = _outer_crosscut(z, c, c.mouths[1], m)
    return shapely.Polygon(_xy(np.concatenate([ob, oa[::-1]])))


def _min_gap(v: np.ndarray, centre: complex) -> float:
    """Estimated smallest prevertex gap ``2π·min ω`` of a piece seen from its centre; NaN when the
    finite-element estimate cannot be built."""
    from .conformal.center import harmonic_measure
    from .errors import PolygonError

    try:
        om = harmonic_measure(v, centre)
    except (PolygonError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return float("nan")
    return float(2.0 * np.pi * np.min(om))


def _refine(
    z: np.ndarray,
    segs: np.ndarray,
    tree: shapely.STRtree,
    r: np.ndarray,
    opt: DecomposeOptions,
    chosen: list[_Candidate],
    built: tuple[list[Channel], _Raw, list[tuple[complex, float]]],
    m: int,
) -> tuple[list[Channel], _Raw, list[tuple[complex, float]], list[float]]:
    """Crowding-driven refinement.

    The extra channels come from a relaxed pass: facing single-edge walls with
    ED < ``max(delta, refine_delta)``, found and trimmed by the rules of the ordinary pass
    (crosscuts outside the vertex regions B(v_k, r_k), straight walls in a parallel or wedge
    frame),
    with overlap depth ``min(overlap_depth, (strip length − refine_core)/2) ≥
    refine_overlap``; wall pairs already cut and candidates whose thin part Ω_2 (the band
    between the mouths) meets another channel's Ω_2 are dropped.  Such a band meets no core,
    so it lies in exactly one thick piece.

    Only pieces that hold a candidate can be split, so only those are estimated: their
    smallest prevertex gap ``2π·min ω`` from the piece's centre (:func:`_min_gap`).  While one
    is below ``opt.crowding_gap``, the most crowded such piece gets the candidate with the
    smallest ED inside it (the longest straight stretch, hence the deepest overlaps), the
    pieces are rebuilt and re-estimated.  Each step adds one channel, so the loop ends.
    Returns channels, pieces, centres and the gap estimates (NaN for pieces not estimated).
    """
    channels, raw, centres = built
    nan = float("nan")
    cache: dict[tuple[bytes, complex], float] = {}
    delta = max(opt.delta, opt.refine_delta)
    depths = [opt.refine_overlap, *sorted((d for d in opt.refine_retry if d < opt.refine_overlap),
                                          reverse=True)]  # fmt: skip
    gaps = [nan] * len(raw)
    for level, depth in enumerate(depths):
        if level and all(
            cache.get((v.tobytes(), centres[k][0]), nan) >= opt.crowding_gap
            for k, (v, _, _) in enumerate(raw)
        ):
            break  # every piece was estimated and none is crowded: nothing to retry
        # relaxed candidates at this overlap depth: a shorter depth admits shorter straight
        # stretches (strip length ≥ 2·depth + refine_core); it is tried only after the deeper
        # ones left a piece crowded or could not be estimated (no candidate inside it)
        used = {(c.wall1, c.wall2) for c in chosen}
        found, _ = _find_channels(z, segs, tree, r, opt, delta, depth, opt.refine_core)
        pool = [c for c in found if (c.wall1, c.wall2) not in used]
        bands = [_band(z, c, m) for c in pool]
        taken = [_band(z, c, m) for c in chosen]
        keep = [
            i for i, b in enumerate(bands) if b.is_valid and not any(_overlaps(b, t) for t in taken)
        ]
        pool = [pool[i] for i in keep]
        bands = [bands[i] for i in keep]
        for c in pool:
            c.relaxed = True
        hopeless: set[bytes] = set()
        while True:
            gaps = [nan] * len(raw)
            if not pool:
                break
            polys = [shapely.Polygon(_xy(v)) for v, _, _ in raw]
            pts = shapely.points(
                [shapely.get_coordinates(b.representative_point())[0] for b in bands]
            )
            bi, pk = shapely.STRtree(polys).query(pts, predicate="within")
            members: dict[int, list[int]] = {}
            for i, k in zip(bi.tolist(), pk.tolist(), strict=True):
                members.setdefault(k, []).append(i)
            for k in members:
                v, ctr = raw[k][0], centres[k][0]
                key = (v.tobytes(), ctr)
                if key not in cache:
                    cache[key] = _min_gap(v, ctr)
                gaps[k] = cache[key]
            crowded = [
                k
                for k in members
                if gaps[k] < opt.crowding_gap and raw[k][0].tobytes() not in hopeless
            ]
            if not crowded:
                break
            k = min(crowded, key=lambda i: gaps[i])
            for i in sorted(members[k], key=lambda i: pool[i].ed):
                try:
                    channels, raw, centres = _assemble(z, [*chosen, pool[i]], m, opt)
                except DecompositionError:
                    continue
                chosen = [*chosen, pool[i]]
                rest = [j for j in range(len(pool)) if j != i and not _overlaps(bands[j], bands[i])]
                pool = [pool[j] for j in rest]
                bands = [bands[j] for j in rest]
                break
            else:
                hopeless.add(raw[k][0].tobytes())
    # the gap estimate of every piece that was estimated (the last pass may not have looked
    # at a piece that an earlier pass found uncrowded)
    for k, (v, _, _) in enumerate(raw):
        if np.isnan(gaps[k]):
            gaps[k] = cache.get((v.tobytes(), centres[k][0]), nan)
    return channels, raw, centres, gaps


def _overlaps(a: shapely.Polygon, b: shapely.Polygon) -> bool:
    """True when two polygons share interior (more than a touching boundary)."""
    if not a.intersects(b):
        return False
    scale = min(a.area, b.area)
    return shapely.intersection(a, b).area > 1e-9 * scale


def _centres(
    raw: list[tuple[np.ndarray, np.ndarray, list[tuple[int, int, int, int, bool]]]],
    channels: list[Channel],
    polys: list[shapely.Polygon],
    tol: float,
) -> list[tuple[complex, float, float]]:
    """Centre f(0) of each thick piece: the largest inscribed disk outside the thin parts.

    The paper (§7) maps 0 to "a point outside of all the thin parts hitting Ω_1", so that the
    expanded intervals (preimages of the outer crosscuts γ') have length < π.  We remove the
    overlap bands Ω_3 (between γ' and γ) from the piece (:func:`_free_region`) and take the
    centre of the largest inscribed disk of the largest remaining component; the returned
    radius is that disk's radius (the third value, NaN, is filled by :func:`_uncrowd`).
    """
    return [
        (*_ridge_centre(_free_region(poly, cuts, channels), tol), float("nan"))
        for (_, _, cuts), poly in zip(raw, polys, strict=True)
    ]


def _free_region(
    poly: shapely.Polygon, cuts: list[tuple[int, int, int, int, bool]], channels: list[Channel]
) -> shapely.Polygon:
    """A piece without the overlap bands Ω_3 of its thin parts (the largest component left)."""
    if not cuts:
        return poly
    bands = []
    for _, _, cid, end, _ in cuts:
        c = channels[cid]
        g, go = c.crosscuts[end], c.outer_crosscuts[end]
        bands.append(shapely.Polygon(_xy(np.concatenate([go, g[::-1]]))))
    region = shapely.difference(poly, shapely.union_all(bands))
    if region.geom_type != "Polygon":
        parts = list(getattr(region, "geoms", []))
        parts = [p for p in parts if p.geom_type == "Polygon"]
        region = max(parts, key=lambda p: p.area) if parts else poly
    if region.is_empty or region.area <= 1e-12 * poly.area:
        region = poly
    return region


def _uncrowd(
    raw: list[tuple[np.ndarray, np.ndarray, list[tuple[int, int, int, int, bool]]]],
    channels: list[Channel],
    centres: list[tuple[complex, float, float]],
) -> list[tuple[complex, float, float]]:
    """The centres of the final pieces, each moved where its map is least crowded when its
    largest inscribed disk crowds it below :data:`CENTRE_GAP` (:func:`_least_crowded`). Run
    after the crowding refinement, which cuts relaxed channels by the inscribed centres'
    estimates: only what it could not cut is mapped from elsewhere."""
    out = []
    for (v, _, cuts), (c, r, _g) in zip(raw, centres, strict=True):
        poly = shapely.Polygon(_xy(v))
        out.append(
            _least_crowded(np.asarray(v), poly, partial(_free_region, poly, cuts, channels), c, r)
        )
    return out


#: A piece whose disk map, with f(0) at its largest inscribed disk's centre, would squeeze
#: some side to a prevertex gap below this (estimated by harmonic measure) gets the centre
#: that is least crowded instead (:func:`_least_crowded`): ten times the smallest gap the
#: Schwarz–Christoffel solve accepts (1e-14), so only maps that would be refused or nearly
#: are moved (a map solved at 6e-13 from its inscribed centre and moved to 2e-11 gave quads
#: a float64 check could not hold at 1e-9 of the polygon's size).
CENTRE_GAP = 1e-13
#: ... examined only for pieces whose area is at least this many squared inscribed radii (a
#: disk has π, a square 4, a 3:2 rectangle 6; the bowl of a glyph "a" with its thin hook 10).
CENTRE_ELONGATION = 6.0


def _least_crowded(
    w: np.ndarray,
    piece: shapely.Polygon,
    region: Callable[[], shapely.Polygon],
    centre: complex,
    radius: float,
    force: bool = False,
) -> tuple[complex, float, float]:
    """The centre f(0) of a piece's disk map that keeps its smallest prevertex gap largest.

    The largest inscribed disk sits in the widest place, which in a piece with long arms
    (the legs of an "A", the stem of a "K") can be at one end: every side at the far end is
    then squeezed by the whole length, exponentially (harmonic measure decays like
    exp(−π·length/width) along a passage). For an elongated piece (area ≥ CENTRE_ELONGATION·r²)
    whose estimated gap 2π·min ω is below :data:`CENTRE_GAP`, the centroids of a constrained
    Delaunay triangulation of the piece lying in ``region()`` (the piece outside its thin
    parts' bands, built only when needed) are tried as poles of one finite-element harmonic
    measure, and the one with the largest smallest gap is returned (with its distance to the
    region's boundary) when it gains at least a factor 10, with the estimate from ``centre``
    as a third value; otherwise ``(centre, radius, nan)``. ``w``: the piece's vertices
    (complex, counter-clockwise), ``piece`` the same as a polygon. ``force``: whatever the
    piece's elongation and estimated gap (a piece whose map or disk mesh failed from
    ``centre``, :func:`recentred`)."""
    from scipy.spatial import QhullError

    from .conformal.center import harmonic_measure, harmonic_measures

    keep = (centre, radius, float("nan"))
    if radius <= 0 or (not force and piece.area < CENTRE_ELONGATION * radius * radius):
        return keep
    try:  # the estimate the conformal stage starts from (remembered for it)
        g0 = 2.0 * np.pi * float(np.min(harmonic_measure(w, centre)))
        if not (g0 < CENTRE_GAP or force):
            return keep
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, QhullError):
        return keep
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(piece))
    cand = shapely.get_coordinates(shapely.centroid(tris))
    free = region()
    cand = cand[shapely.contains_xy(free, cand[:, 0], cand[:, 1])]
    if cand.shape[0] > 160:
        cand = cand[np.linspace(0, cand.shape[0] - 1, 160).round().astype(np.int64)]
    poles = np.r_[centre, cand[:, 0] + 1j * cand[:, 1]]
    try:
        om = harmonic_measures(w, poles)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, QhullError):
        return keep
    gap = np.min(om, axis=1)
    gap = np.where(np.isfinite(gap), gap, -1.0)
    k = int(np.argmax(gap))
    if k == 0 or not gap[k] >= 10.0 * gap[0]:
        return keep
    c = complex(poles[k])
    return c, float(shapely.distance(shapely.Point(c.real, c.imag), free.exterior)), g0


def recentred(dec: Decomposition, index: int) -> Decomposition | None:
    """``dec`` with thick piece ``index``'s map centre f(0) moved where its map is least
    crowded (:func:`_least_crowded`, whatever the piece's elongation and estimated gap), for a
    piece whose map or disk construction failed from its centre (:func:`_uncrowd` examines
    only elongated pieces: the cmr10 "6", a bowl with a long hook of area below
    :data:`CENTRE_ELONGATION` inscribed radii squared, is crowded to 1e-20 rad from its
    inscribed centre and to 4e-11 from the least crowded one); None when the centre was moved
    already or no other centre gains a factor 10."""
    piece = dec.thick[index]
    if np.isfinite(piece.inscribed_gap):
        return None
    poly = shapely.Polygon(_xy(piece.z))
    cuts = [(c.start, c.stop, c.channel, c.end, c.reversed) for c in piece.crosscuts]
    region = partial(_free_region, poly, cuts, list(dec.channels))
    ctr, rad, g_in = _least_crowded(
        np.asarray(piece.z), poly, region, piece.center, piece.radius, force=True
    )
    if np.isnan(g_in):
        return None
    moved = replace(piece, center=ctr, radius=rad, min_gap=float("nan"), inscribed_gap=g_in)
    thick = tuple(moved if p.index == index else p for p in dec.thick)
    return replace(dec, thick=thick)


def _ridge_centre(
    region: shapely.Polygon, tol: float, max_samples: int = 4000
) -> tuple[complex, float]:
    """Centre and radius of a largest inscribed disk, ties broken towards the ridge's middle.

    GEOS gives one maximal disk (radius r, to ``tol·sqrt(area)``).  The largest inscribed disk
    is often not unique (a rectangle has a whole segment of centres); an off-middle centre
    makes the far end of the piece crowd in the SC map.  So we sample the distance to the
    boundary on a grid of spacing h ≈ r/4 through the GEOS centre (at most ``max_samples``
    points), keep the grid component of ``{dist ≥ r − 0.6h}`` that holds the GEOS centre (the
    near-maximal ridge) and return its sample nearest to the component's centroid; its radius
    is at least ``r − 0.6h`` (≥ 0.85 r).  Cost O(max_samples·n), no polygon buffering.
    """
    from scipy import ndimage

    scale = float(np.sqrt(region.area))
    circ = shapely.maximum_inscribed_circle(region, tol * scale)
    c0, c1 = shapely.get_coordinates(circ)
    r0 = float(np.hypot(*(c1 - c0)))
    best = (complex(c0[0], c0[1]), r0)
    x0, y0, x1, y1 = region.bounds
    h = max(0.25 * r0, float(np.sqrt((x1 - x0) * (y1 - y0) / max_samples)))
    if r0 <= 0 or h >= r0:
        return best
    # grid through the GEOS centre: for axis-aligned ridges the ridge row is sampled exactly
    xs = c0[0] + h * np.arange(np.floor((x0 - c0[0]) / h), np.ceil((x1 - c0[0]) / h) + 1)
    ys = c0[1] + h * np.arange(np.floor((y0 - c0[1]) / h), np.ceil((y1 - c0[1]) / h) + 1)
    gx, gy = np.meshgrid(xs, ys)
    inside = shapely.contains_xy(region, gx, gy)
    dist = np.zeros(gx.shape)
    pts = shapely.points(gx[inside], gy[inside])
    dist[inside] = shapely.distance(pts, region.exterior)
    ridge = inside & (dist >= r0 - 0.6 * h)
    labels, _ = ndimage.label(ridge, structure=np.ones((3, 3)))
    i0 = int(np.argmin(np.abs(ys - c0[1])))
    j0 = int(np.argmin(np.abs(xs - c0[0])))
    if labels[i0, j0] == 0:
        return best
    comp = labels == labels[i0, j0]
    cx, cy = gx[comp].mean(), gy[comp].mean()
    k = int(np.argmin((gx[comp] - cx) ** 2 + (gy[comp] - cy) ** 2))
    cand = complex(gx[comp][k], gy[comp][k])
    r_c = float(shapely.distance(shapely.Point(cand.real, cand.imag), region.exterior))
    # keep GEOS's centre unless the central sample is (nearly) as good
    if r_c >= r0 - 0.6 * h:
        return cand, r_c
    return best


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


def _candidate_crosscuts(z: np.ndarray, c: _Candidate, m: int) -> tuple[np.ndarray, np.ndarray]:
    """γ_A and γ_B of a candidate, endpoints exactly on the wall edges."""
    n = z.size
    out = []
    for la1, la2 in c.lam:
        p1 = z[c.wall1] + la1 * (z[(c.wall1 + 1) % n] - z[c.wall1])
        p2 = z[c.wall2] + la2 * (z[(c.wall2 + 1) % n] - z[c.wall2])
        out.append(_crosscut(c.frame, p1, p2, m))
    return out[0], out[1]


def _outer_crosscut(z: np.ndarray, c: _Candidate, x: float, m: int) -> np.ndarray:
    """The thin part's outer crosscut γ' at channel coordinate x (a mouth)."""
    n = z.size
    fr = c.frame
    pts = []
    for e in (c.wall1, c.wall2):
        xa, xb = fr.coordinate(z[e]).item(), fr.coordinate(z[(e + 1) % n]).item()
        pts.append(_wall_point(z, e, x, xa, xb)[1])
    return _crosscut(fr, pts[0], pts[1], m)
