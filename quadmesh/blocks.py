"""Block layouts: few quads with every new angle in [60°, 120°], without a conformal map.

A *block layout* cuts the polygon by straight segments into convex faces whose corners all lie
in [60°, 120°] (a polygon corner below 60° may stay as a *tip*), splits every face into quads
about a centre point when the faces are not all quadrilaterals, and refines the resulting cells
by bilinear grids (:func:`quadmesh.cells.refine_layout`): a convex cell with straight sides and
corners in [60°, 120°] keeps every grid angle in [60°, 120°] for any spacing, and one count per
chord keeps the grids conforming.  This gives the same guarantee as the paper's construction
(Theorem 1.1's angle bound) with far fewer quads and no element below the polygon's own
features; the paper's theorem is what promises that *some* O(n) mesh exists.

The cuts:

* every corner with angle θ in (120°, 240°] gets one cut, every corner with θ > 240° two, so
  that all parts of θ lie in [60°, 120°];
* a cut runs straight from its corner until it meets the boundary (never stopping on another
  cut, so no T-junctions arise); where it meets the boundary, and where two cuts cross, the
  angles must lie in [60°, 120°]; a cut may end at another obtuse corner and serve as that
  corner's cut too (a *join*);
* the cuts are chosen together: one binary variable per candidate ray (directions sampled in
  each corner's window, plus joins), exactly one ray per cut slot, no two rays that cross at a
  bad angle or too close to a point; solved by ``scipy.optimize.milp``.  A face that then
  cannot be split about a centre with angles in range is excluded by a new constraint and the
  search runs again.

Where some corner has no cut of its own that meets the boundary well, a cut may also end at a
*junction*: an interior point where three or more cuts meet, all its angles in [60°, 120°]
(three arms: exactly 120° each), its other arms running to corners (serving their cuts) or to
the boundary.  A junction is one candidate of the integer program, covering the cut slots of
all the corners its arms reach (:func:`_junctions`).

A corner below 60° (a *tip*) is first cut off by a *tip kite* about one block size long (the
tip, a point on each of its edges, a point on its bisector; :func:`_tip_kite`): the rest of the
polygon gets a reflex corner of at least 240° there, cut like any other, and no cut may end on
the kite, which is never split, nor are the quads on the chords through it (a split would reach
the kite).  If no layout with kites closes, the tips' blocks
are kept whole instead.

Public functions: :func:`block_layout`, :func:`mesh_blocks`.  Plane points are complex128.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import Bounds, LinearConstraint, milp, minimize
from scipy.sparse import coo_matrix

from .cells import (
    ANGLE_MAX,
    ANGLE_MIN,
    LayoutRefinement,
    cell_angles,
    layout_chords,
    refine_layout,
)
from .errors import QuadmeshError
from .geometry import quad_signed_areas, unpaired_edges
from .mesh import QuadMesh
from .polygon import interior_angles, signed_area
from .progress import checkpoint
from .transition import TransitionMesh

__all__ = [
    "BlockLayout",
    "BlockLayoutError",
    "PartialLayout",
    "block_layout",
    "default_block_size",
    "mesh_blocks",
    "mesh_partial_layout",
]

#: corners of the coarse layout keep this distance (degrees) from 60° and 120°
LAYOUT_MARGIN = 0.5
#: directions sampled in each cut's window (besides joins)
RAY_SAMPLES = 13
#: a cut may not end or cross closer than this fraction of the diameter to another point
POINT_GAP = 2e-3
#: rounds of the search (each excludes the faces that could not be split)
MAX_ROUNDS = 40
#: polygon corners within this of 60° or 120° (degrees; rounding of their coordinates) count
#: as in range
ANGLE_TOL = 1e-7
#: most cut slots (corners above 120°, two for those above 240°) a layout is searched for; the
#: pairwise search grows with the square of the candidates. 200 (was 120): Computer Modern "S"
#: (121 slots) and "3" (144) close, in 13 and 25–34 s (1,029 and 6,147–8,703 quads against
#: 59,741 and 124,891 by the paper's construction), scikit-image page_0 (169, with twin cuts)
#: in 34 s (9,776 quads against 164,833), the pen strokes S_1 and S_3 (173, 182) by cuts with
#: 200 and 202 quads instead of ladders with 720 and 895 (0.5 s more)
MAX_SLOTS = 200
#: T-junction and junction candidates are tried only while the full rays number at most this
MAX_RAYS_FOR_TEES = 1000
#: pairs of crossing cuts (the shortest arms first) tried as four-arm junctions
MAX_JUNCTION_PAIRS = 400
#: most junction candidates one search gets (the cheapest)
MAX_JUNCTIONS = 200
#: free-arm directions sampled in each angle of a junction
ARM_SAMPLES = 7
#: points along each cut tried as hubs of junctions (fractions of its length)
HUB_POSITIONS = (0.2, 0.35, 0.5, 0.65, 0.8)
#: free-arm directions tried at a hub (evenly spread over a turn)
HUB_DIRECTIONS = 48
#: a junction costs this on top of its arms (a layout without one is simpler)
JUNCTION_COST = 0.5
#: wall-clock seconds the search with junction candidates may take
JUNCTION_SECONDS = 2.0
#: wall-clock seconds for the layout with junctions and the tips' blocks kept whole, from the
#: candidates to the last round of its search
JUNCTION_LAYOUT_SECONDS = 6.0
#: junctions are searched for even where every cut slot has a straight cut of its own when
#: the polygon has a reflex corner and at most this many slots
JUNCTION_ANY_SLOTS = 8
#: the search with junctions is started only with at least this many seconds left
MIN_JUNCTION_SECONDS = 0.2
#: relative gap to the cheapest layout at which the search with junctions stops
JUNCTION_GAP = 0.25
#: a search with more conflicting pairs than this is given up at once (the integer program
#: would take minutes to prove that no layout exists, and layouts that close have far fewer)
MAX_CONFLICTS = 150_000
#: candidates beyond which the conflict rows stay pairs (:func:`_conflict_cliques`)
MAX_CLIQUE_CANDIDATES = 6000
#: hanging points are tested against all sides while points × sides stay below this
BRUTE_PAIRS = 20_000_000
#: wall-clock seconds the integer programs of one layout search may take in all
SEARCH_SECONDS = 3.0
#: wall-clock seconds per stage of the second, longer straight-cut search, run only when the
#: first ran out of time and neither a ladder nor a collar closed (measured: cmr10 "H" closes
#: after 7.8 s, "n" after 12.4 s)
LONG_SEARCH_SECONDS = 15.0
#: ... in which T-junction candidates are made while the full and bare rays number at most
#: this (measured: STIX "C" and "s", with 1,072 and 1,091 rays, then close in about a second)
LONG_MAX_RAYS_FOR_TEES = 5000
#: wall-clock seconds each search for a ladder along the polygon as one corridor may take at
#: least
LADDER_SECONDS = 5.0
#: ... and per polygon vertex, where that is longer: the layout search grows with the walls'
#: length (measured: a 1,562-vertex river closes after 15 s on a quiet machine and 22 s under
#: load, rivers of 380-722 vertices in 0.7-4.2 s)
LADDER_SECONDS_PER_VERTEX = 0.02
#: least chord counts of the ladder's sector crosscuts, each searched for in turn (the second
#: only on polygons of at most ``quadmesh.thin.corridor.SECTOR_RETRY_MAX`` vertices)
LADDER_SECTOR_CHORDS = (16, 8)
#: a ladder mesh is used only if no edge is longer than this many times the target size
LADDER_MAX_EDGE = 2.5
#: no ladder is searched for on a polygon whose area is less than this many times that of its
#: largest inscribed disk (:func:`_elongation`): measured, every polygon a ladder closes has
#: at least 4.9 (slit_355deg; strokes, walks and rivers 9–1,000), every round one the collar
#: closes at most 2.0 (regular_64 1.0, star_100 1.2, cmr10 "8" 2.0), and on those the failing
#: ladder searches took most of the time (regular_64 3.3 of 5.1 s, star_100 8.0 of 14.8)
LADDER_MIN_ELONGATION = 2.5
#: cost of a cut slot left without a cut in the relaxed search for a partial layout (a cut
#: costs about its length over the diameter, at most a few units)
UNSERVED_COST = 20.0
#: wall-clock seconds of the relaxed search (:func:`mesh_partial_layout`)
RELAXED_SECONDS = 3.0
#: the relaxed search runs only with at most this many candidate cuts (its integer program
#: overruns its time on glyphs with 1,200-1,300: 4.4 s of 1 s on cmr10 "g")
RELAXED_MAX_RAYS = 1500
#: no further round or face is laid out once this many seconds have gone into laying out
#: rounds (a safety net: each may spend :data:`FACE_RESOLVE_SECONDS` carrying points that never
#: settle, and each face a whole cut search; cmr10 "B" took 90 s to fall back on a busy
#: machine, random stars of 40-120 vertices 30-60 s)
PARTIAL_SECONDS = 20.0
#: rounds of the straight-cut searches kept as partial layouts (fewest unsplit faces first):
#: where one round's faces find no layout of their own, another's may
PARTIAL_KEEP = 3
#: the faces that fall back may have at most this share of the polygon's vertex count in all
#: (corners and points on their sides): the paper's construction costs about a thousand quads
#: per vertex, so larger faces would give as many quads as meshing the whole polygon by it
FALLBACK_SHARE = 0.5
#: faces that fall back whose meshes hold more than this many quads per polygon vertex are
#: given up before the cells around them are meshed (the paper's construction on the whole
#: polygon makes 400-1,100 per vertex on glyphs)
FALLBACK_MAX_PER_VERTEX = 1000
#: rounds (fewest faces left to the paper's construction first) whose faces are meshed by it,
#: until one gives a mesh that passes the strict check (each costs those faces' meshes)
FALLBACK_ROUNDS = 2
#: times the cells of chords between two faces that fall back are joined to those faces
MAX_FALLBACK_MERGES = 6
#: collar spacings tried for a face laid out on its own (:func:`_face_layout`), as fractions
#: of the size: a face is often too narrow for a lattice core at the size itself
FACE_RING_SIZES = (1.0, 0.25)
#: ... and, when the face's own partial layout fails too, these (a fine collar carries its
#: lattice's points across the polygon as grid lines: STIX "l" 3,821 quads, where the paper's
#: construction for the face gave 90,581)
FACE_FINE_RING_SIZES = (1.0 / 16.0,)
#: wall-clock seconds of each collar tried for such a face
FACE_RING_SECONDS = 2.0
#: how many times a face laid out on its own may itself leave faces that are laid out on their
#: own (by the face's relaxed cut search)
FACE_DEPTH = 1
#: wall-clock seconds for carrying the points of the faces laid out on their own through the
#: other cells (a safety net: where two faces' points chase each other round a ring of cells
#: the splits never settle, and each round is slower than the last; cmr10 "B" ran for
#: minutes; cmr10 "c" settles after 1,472 cells and 10 s on a busy machine)
FACE_RESOLVE_SECONDS = 15.0
#: default target edge length, as a fraction of the polygon's diameter
DEFAULT_SIZE_RATIO = 1.0 / 20.0
#: an edge is *undersized* (:func:`undersized_edges`) when it is shorter than this fraction of
#: the smaller of the target size and the polygon's local feature size at its midpoint
UNDERSIZED_FRACTION = 0.25


class BlockLayoutError(QuadmeshError):
    """No block layout was found for the polygon."""

    stage = "blocks"


@dataclass(frozen=True)
class BlockLayout:
    """A coarse layout of cells for a polygon.

    Attributes:
        polygon: (n,) complex polygon vertices (counter-clockwise) the layout is for.
        points: (P,) complex layout points; ``points[:n]`` are the polygon's vertices.
        cuts: (K, 2) complex end points of the straight cuts.
        faces: the faces cut out by the cuts, each an int array of point indices (CCW).
        cells: (C, 4) int cells over ``points`` (CCW), every corner in [60°, 120°] but tips.
        tips: polygon vertices with an angle below 60° (their cells are never split).
        split: True when the faces were split about centre points into the cells.
        rounds: search rounds used.
        tees: cuts that end on another cut (T-junctions made conforming by splitting cells).
        angles: (C, 4) corner angles of the cells, degrees.
        kind: ``"cuts"`` (straight cuts from the corners), ``"ring"`` (a collar of quads
            around a core on a triangular lattice, :mod:`quadmesh.rings`; ``cuts`` are then the
            collar's spokes and ``faces`` is empty) or ``"ladder"`` (the polygon is one
            corridor: a ladder of straight cells between its two ends,
            :func:`quadmesh.thin.corridor.ladder_layout`; ``cuts`` are the rungs across it,
            ``faces`` is empty, and round ends and bends are meshed as vertex sectors outside
            the cells).
        kites: True when the tips were cut off by tip kites (:func:`block_layout`), each
            tip the corner of one small kite cell rather than of a block reaching across.
        junctions: interior points where three or four cuts meet (:func:`_junctions`).
        fallback_faces: faces of a straight-cut layout that could not be split into cells and
            were meshed by the paper's construction instead, each glued to the cells around it
            (:func:`mesh_partial_layout`): (k,) complex polygons, their corners and every
            layout point on their sides.
        fallback_quads: how many quads of the mesh those faces hold (the mesh's last ones).
        fallback_source: per quad of those faces, the stage of the paper's construction that
            made it (the codes of :data:`quadmesh.io.STAGE_KINDS`).
        local_faces: faces of a straight-cut layout that did not split with the other faces'
            cuts and were laid out on their own instead (straight cuts inside the face, a
            collar, or the face's own partial layout: :func:`_face_layout`); their cells are
            part of ``cells``: (k,) complex polygons, their corners and every layout point on
            their sides.
    """

    polygon: NDArray[np.complex128]
    points: NDArray[np.complex128]
    cuts: NDArray[np.complex128]
    faces: tuple[NDArray[np.int64], ...]
    cells: NDArray[np.int64]
    tips: NDArray[np.int64]
    split: bool
    rounds: int = 1
    tees: int = 0
    angles: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 4)))
    kind: str = "cuts"
    kites: bool = False
    junctions: int = 0
    fallback_faces: tuple[NDArray[np.complex128], ...] = ()
    fallback_quads: int = 0
    fallback_source: NDArray[np.int8] = field(default_factory=lambda: np.zeros(0, np.int8))
    local_faces: tuple[NDArray[np.complex128], ...] = ()

    @property
    def n_cells(self) -> int:
        """Number of coarse cells."""
        return len(self.cells)

    @property
    def cut_noun(self) -> str:
        """What one of ``cuts`` is, for a user: "cut", "spoke" or "rung"."""
        return _KIND_WORDS[self.kind][0]

    @property
    def title(self) -> str:
        """What the layout is made of, for a user (e.g. "collar around a lattice core")."""
        return _KIND_WORDS[self.kind][1]


#: per layout kind: the name of one of its cuts and what the layout is made of
_KIND_WORDS = {
    "cuts": ("cut", "straight cuts from the corners"),
    "ring": ("spoke", "collar around a lattice core"),
    "ladder": ("rung", "ladder of straight cells along a corridor"),
}


def _scale(z: NDArray[np.complex128]) -> float:
    """The polygon's size "d": its bounding-box diagonal (as ``Polygon.diameter``, so that
    ``--size 0.05d`` and the app's block size mean the same length)."""
    return float(np.hypot(np.ptp(z.real), np.ptp(z.imag)))


def default_block_size(z: ArrayLike) -> float:
    """Default target edge length for block meshes: d / 20, d the bounding-box diagonal."""
    return _scale(np.asarray(z, dtype=np.complex128)) * DEFAULT_SIZE_RATIO


# --------------------------------------------------------------------------- geometry


def undersized_edges(mesh: QuadMesh, polygon: ArrayLike, size: float) -> tuple[int, int, float]:
    """How many of ``mesh``'s distinct edges are shorter than :data:`UNDERSIZED_FRACTION` of
    min(``size``, local feature size of ``polygon`` at the edge's midpoint) — elements smaller
    than both the size asked for and the polygon's own features there (the mesh and the
    polygon in the same frame).  Returns ``(undersized, edges, smallest ratio)``, the ratio
    being an edge's length over that minimum.

    Measured at the default size (d/20) on the bundled examples: none on layouts of straight
    cuts but next to a tip, which forces them (corner_5deg 9.6 %, right_triangle_10deg 4.0 %);
    0.2–63 % on collars (their spokes bunch towards the core's points; a heavier cost of thin
    collar cells changed nothing) and up to 42 % on ladders whose round ends are vertex sectors
    (stroke_spiral: the sectors' graded points run along the whole stroke).
    """
    _edges, length, lfs = mesh.edge_lfs_ratios(polygon)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = length / np.minimum(float(size), lfs)
    small = int(np.count_nonzero(ratio < UNDERSIZED_FRACTION))
    return small, int(ratio.size), float(ratio.min()) if ratio.size else math.inf


def _angles_deg(z: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Interior angles in degrees of the counter-clockwise polygon ``z``."""
    return np.degrees(interior_angles(z))


def _line_angle(d1: complex, d2: complex) -> float:
    """Angle in [0°, 90°] between the lines of directions d1 and d2 (as undirected lines the
    four angles are this and its supplement)."""
    a = abs(math.degrees(math.atan2((d2 / d1).imag, (d2 / d1).real))) % 180.0
    return min(a, 180.0 - a)


@dataclass
class _Ray:
    start: int  # polygon vertex
    d: complex  # unit direction
    end: complex  # end point
    edge: int  # polygon edge hit (-1: a join)
    u: float  # parameter on that edge
    join: int  # polygon vertex reached (-1: none)
    slots: list[tuple[int, int]]
    cost: float
    base: int = -1  # the full ray this one is cut from (its own index for a full ray)
    stop: int = -1  # base id of the ray this one ends on (a T-junction), else -1
    reach: float = 0.0  # distance from the start to the end
    p0: complex | None = None  # where the segment starts when not at z[start] (a junction arm)
    arms: tuple[_Ray, ...] = ()  # a junction: its arms, each from the hub outwards
    hub: complex | None = None  # a junction's interior point
    exact: bool = False  # the hub's angles are exactly 120° (three arms)


def _p0(z: NDArray[np.complex128], r: _Ray) -> complex:
    """Where the segment ``r`` starts: its corner, or a junction's hub for an arm."""
    return complex(z[r.start]) if r.p0 is None else r.p0


def _segments(rays: list[_Ray]) -> tuple[list[_Ray], NDArray[np.int64]]:
    """The straight segments of candidate cuts (a junction contributes its arms) and, for
    each, the index of the candidate it belongs to."""
    segs: list[_Ray] = []
    owner: list[int] = []
    for k, r in enumerate(rays):
        parts = r.arms if r.arms else (r,)
        segs.extend(parts)
        owner.extend([k] * len(parts))
    return segs, np.asarray(owner, dtype=np.int64)


def _first_hit(z: NDArray[np.complex128], i: int, d: complex) -> tuple[float, int, float] | None:
    """First boundary point on the ray z[i] + t d (t > 0), skipping the two edges at z[i]:
    ``(t, edge, u)`` with the point ``z[e] + u (z[e+1] - z[e])``; None if it leaves (never)."""
    t, j, u = _first_hits(z, i, np.array([d], dtype=np.complex128))
    if j[0] < 0:
        return None
    return float(t[0]), int(j[0]), float(u[0])


def _first_hits(
    z: NDArray[np.complex128], i: int, d: NDArray[np.complex128]
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """:func:`_first_hit` for the rays z[i] + t d[k] (unit directions ``d``, (m,)) at once, the
    same arithmetic element by element: arrays ``(t, edge, u)``, ``edge`` −1 where a ray meets
    no edge."""
    n = len(z)
    e = (np.roll(z, -1) - z)[None, :]
    w = (z - z[i])[None, :]
    dd = np.asarray(d, dtype=np.complex128)[:, None]
    # solve p + t d = a + u e:  t d - u e = a - p
    den = (dd.conjugate() * e).imag  # cross(d, e)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w.conjugate() * e).imag / den  # cross(w, e) / cross(d, e)
        u = (w.conjugate() * dd).imag / den  # cross(w, d) / cross(d, e)
    ok = (np.abs(den) > 1e-15 * np.abs(e)) & (t > 0) & (u >= 0) & (u <= 1)
    ok[:, i] = False
    ok[:, (i - 1) % n] = False
    j = np.argmin(np.where(ok, t, np.inf), axis=1)
    rows = np.arange(len(j))
    hit = ok[rows, j]
    return t[rows, j], np.where(hit, j, -1), u[rows, j]


def _windows(theta: float, exact: bool = False, twin: bool = False) -> list[tuple[float, float]]:
    """Direction windows (degrees from the outgoing edge) of the cut slots of a corner.  An
    ``exact`` corner (240° by construction: a tip kite's inner point with a 120° kite corner)
    has one cut along its bisector, both parts exactly 120°.  A ``twin`` corner of at most 240°
    (one with no single cut of its own: :func:`_twin_corners`) gets two cuts, three parts in
    [60°, 120°], as corners above 240° do: at 225° a single cut must leave 105°–120° on both
    sides, a window of 15°, while two cuts may leave 60°–105° at either side."""
    if exact:
        return [(0.5 * theta, 0.5 * theta)]
    m = LAYOUT_MARGIN
    lo, hi = ANGLE_MIN + m, ANGLE_MAX - m
    if theta <= ANGLE_MAX + ANGLE_TOL:
        return []
    if theta > 2 * ANGLE_MAX:
        return [(max(lo, theta - 2 * hi), min(hi, theta - 2 * lo)), (theta - hi, theta - lo)]
    if twin and theta >= 3 * lo:
        # the second cut at least 60.5° past the first, which is at least 60.5° from the edge
        return [(lo, theta - 2 * lo), (2 * lo, theta - lo)]
    return [(max(lo, theta - hi), min(hi, theta - lo))]


def _candidates(
    z: NDArray[np.complex128],
    theta: NDArray[np.float64],
    diam: float,
    bare: list[_Ray] | None = None,
    rigid: frozenset[int] = frozenset(),
    exact: frozenset[int] = frozenset(),
    twin: frozenset[int] = frozenset(),
) -> list[_Ray]:
    """Candidate cuts of every corner above 120°: ``RAY_SAMPLES`` directions spread over each
    cut's window, each running to the first boundary point it meets, kept when it meets the
    boundary at an angle in [60.5°, 119.5°] away from corners; and joins to other such corners
    in view whose own windows admit them.  Rays whose boundary end is unusable go to ``bare``
    (when given): they can still serve shortened, ending on another cut (:func:`_t_variants`).
    A ray may not end inside a ``rigid`` edge (a side of a tip kite, which is never split);
    ``exact`` and ``twin`` corners as in :func:`_windows`."""
    n = len(z)
    gap = POINT_GAP * diam
    m = LAYOUT_MARGIN
    e_out = np.roll(z, -1) - z
    wins = [_windows(float(t), i in exact, i in twin) for i, t in enumerate(theta)]
    rays: list[_Ray] = []

    def slot_of(i: int, phi: float) -> int | None:
        for k, (a, b) in enumerate(wins[i]):
            if a - 1e-9 <= phi <= b + 1e-9:
                return k
        return None

    def phi_at(i: int, d: complex) -> float:
        ang = math.degrees(math.atan2((d / e_out[i]).imag, (d / e_out[i]).real)) % 360.0
        return ang

    for i in range(n):
        if not wins[i]:
            continue
        u0 = e_out[i] / abs(e_out[i])
        dirs: list[tuple[float, int]] = []
        for k, (a, b) in enumerate(wins[i]):
            if b < a:
                continue
            for phi in np.linspace(a, b, RAY_SAMPLES if b > a else 1):
                dirs.append((float(phi), k))
        # joins: other obtuse corners seen inside a window (the rays' first hits at once)
        joins = []
        for j in range(n):
            if j == i or not wins[j]:
                continue
            d = z[j] - z[i]
            k = slot_of(i, phi_at(i, d))
            if k is not None:
                joins.append((j, d, k))
        if joins:
            jd = np.array([d / abs(d) for _, d, _ in joins], dtype=np.complex128)
            t_hit, e_hit, _u = _first_hits(z, i, jd)
            for (j, d, k), th, eh in zip(joins, t_hit.tolist(), e_hit.tolist()):
                if eh < 0 or th < abs(d) * (1 - 1e-9) - 1e-12 * diam:
                    continue  # something is in the way
                kj = slot_of(j, phi_at(j, -d))
                if kj is None:
                    continue
                cost = 0.5 + 0.2 * abs(d) / diam
                rays.append(_Ray(i, d / abs(d), z[j], -1, 0.0, j, [(i, k), (j, kj)], cost))
        dvec = np.array(
            [
                u0 * complex(math.cos(math.radians(phi)), math.sin(math.radians(phi)))
                for phi, _ in dirs
            ],
            dtype=np.complex128,
        )
        t_all, j_all, u_all = _first_hits(z, i, dvec)
        for (phi, k), d, t, j, u in zip(
            dirs, dvec.tolist(), t_all.tolist(), j_all.tolist(), u_all.tolist()
        ):
            if j < 0:
                continue
            ej = e_out[j]
            end = z[j] + u * ej
            alpha = _line_angle(d, ej)
            # too close to a corner (only joins may end at corners) or at a bad angle
            if u * abs(ej) < gap or (1 - u) * abs(ej) < gap or alpha < ANGLE_MIN + m or j in rigid:
                if bare is not None:
                    bare.append(
                        _Ray(i, d, end, -1, 0.0, -1, [(i, k)], 1.0 + 0.2 * t / diam, -1, -1, t)
                    )
                continue
            cost = 1.0 + 0.5 * (90.0 - alpha) / 30.0 + 0.2 * t / diam
            # prefer the middle of the window (room on both sides)
            a, b = wins[i][k]
            if b > a:
                cost += 0.2 * abs(phi - 0.5 * (a + b)) / (b - a)
            rays.append(_Ray(i, d, end, j, u, -1, [(i, k)], cost))
    for k, r in enumerate(rays):
        r.base = k
        r.reach = abs(r.end - z[r.start])
    return rays


def _t_variants(
    z: NDArray[np.complex128],
    rays: list[_Ray],
    diam: float,
    per_ray: int = 3,
    bare: list[_Ray] = (),
) -> list[_Ray]:
    """Shortened copies of the full rays that end on another full ray (a T-junction), at the
    first ``per_ray`` crossings where the two meet at an angle in [60°, 120°]; the far side
    of the T is made conforming later by splitting cells along grid lines.  Rays of ``bare``
    (whose own boundary end is unusable) are shortened the same way."""
    gap = POINT_GAP * diam
    m = LAYOUT_MARGIN
    out: list[_Ray] = []
    full = [r for r in rays if r.join < 0]
    if not rays:
        return out
    # the segments of ``rays`` at once: a loose numpy test picks the pairs that may cross, the
    # exact test below (as before) decides them
    P = np.array([z[r.start] for r in rays], dtype=np.complex128)
    D = np.array([r.end for r in rays], dtype=np.complex128) - P
    starts = np.array([r.start for r in rays])
    for ra in full + list(bare):
        p1 = complex(z[ra.start])
        d1 = ra.end - p1
        den = (np.conj(d1) * D).imag
        w = P - p1
        with np.errstate(divide="ignore", invalid="ignore"):
            s_ = (np.conj(w) * D).imag / den
            t_ = (np.conj(w) * d1).imag / den
        near = (starts != ra.start) & (s_ > -1e-6) & (s_ < 1 + 1e-6) & (t_ > -1e-6)
        near &= t_ < 1 + 1e-6
        hits = []
        for b in np.flatnonzero(near).tolist():
            rb = rays[b]
            x = _seg_cross(z[ra.start], ra.end, z[rb.start], rb.end)
            if x is None:
                continue
            sa, tb = x
            la, lb = ra.reach, rb.reach
            if min(sa * la, (1 - sa) * la, tb * lb, (1 - tb) * lb) < gap:
                continue
            if _line_angle(ra.d, rb.d) < ANGLE_MIN + m:
                continue
            hits.append((sa, rb.base))
        hits.sort()
        for sa, b in hits[:per_ray]:
            end = z[ra.start] + sa * (ra.end - z[ra.start])
            cost = ra.cost + 0.3  # a T costs a row of split cells
            out.append(
                _Ray(
                    ra.start,
                    ra.d,
                    end,
                    -1,
                    0.0,
                    -1,
                    list(ra.slots),
                    cost,
                    ra.base,
                    b,
                    sa * ra.reach,
                )
            )
    return out


def _slot_of(
    wins: list[list[tuple[float, float]]], e_out: NDArray[np.complex128], i: int, d: complex
) -> int | None:
    """The cut slot of corner ``i`` whose window holds the direction ``d``, or None."""
    phi = math.degrees(math.atan2((d / e_out[i]).imag, (d / e_out[i]).real)) % 360.0
    for k, (a, b) in enumerate(wins[i]):
        if a - 1e-9 <= phi <= b + 1e-9:
            return k
    return None


def _boundary_dist(z: NDArray[np.complex128], p: complex) -> float:
    """Distance from ``p`` to the polygon's boundary."""
    a = z
    e = np.roll(z, -1) - z
    t = np.clip(((p - a) * np.conj(e)).real / np.maximum(np.abs(e) ** 2, 1e-300), 0.0, 1.0)
    return float(np.min(np.abs(p - (a + t * e))))


def _free_arm(
    z: NDArray[np.complex128], p: complex, d: complex, diam: float, rigid: frozenset[int]
) -> _Ray | None:
    """An arm from the interior point ``p`` in the unit direction ``d`` to the first boundary
    point it meets, if it meets it at an angle in [60.5°, 119.5°], away from the corners and
    not on a ``rigid`` edge; None otherwise."""
    gap = POINT_GAP * diam
    e = np.roll(z, -1) - z
    den = (np.conj(d) * e).imag
    w = z - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.conj(w) * e).imag / den
        u = (np.conj(w) * d).imag / den
    ok = (np.abs(den) > 1e-15 * np.abs(e)) & (t > 0) & (u >= 0) & (u <= 1)
    if not np.any(ok):
        return None
    j = int(np.argmin(np.where(ok, t, np.inf)))
    tj, uj, ej = float(t[j]), float(u[j]), complex(e[j])
    alpha = _line_angle(d, ej)
    if (
        j in rigid
        or tj < gap
        or min(uj, 1 - uj) * abs(ej) < gap
        or alpha < ANGLE_MIN + LAYOUT_MARGIN
    ):
        return None
    cost = 0.5 + 0.5 * (90.0 - alpha) / 30.0 + 0.2 * tj / diam
    return _Ray(-1, d, complex(z[j] + uj * ej), j, uj, -1, [], cost, -2, -1, tj, p0=p)


def _corner_arm(
    z: NDArray[np.complex128],
    wins: list[list[tuple[float, float]]],
    e_out: NDArray[np.complex128],
    p: complex,
    i: int,
    diam: float,
) -> _Ray | None:
    """An arm from the interior point ``p`` to the corner ``i``, serving the cut slot of ``i``
    whose window holds the direction from ``i`` to ``p``, if ``p`` is in view of ``i``; None
    otherwise."""
    v = p - z[i]
    dist = abs(v)
    if dist < POINT_GAP * diam:
        return None
    k = _slot_of(wins, e_out, i, v / dist)
    if k is None:
        return None
    hit = _first_hit(z, i, v / dist)
    if hit is None or hit[0] < dist * (1 + 1e-9):
        return None  # the boundary is in the way
    cost = 1.0 + 0.2 * dist / diam
    return _Ray(-1, -v / dist, complex(z[i]), -1, 0.0, i, [(i, k)], cost, -2, -1, dist, p0=p)


def _star(arms: list[_Ray], hub: complex, exact: bool = False) -> _Ray:
    """A junction candidate: the ``arms`` from ``hub`` (to corners or to the boundary), one
    candidate covering the cut slots of the corners they reach; ``exact``: the hub's angles
    are exactly 120°."""
    slots = [s for a in arms for s in a.slots]
    cost = JUNCTION_COST + sum(a.cost for a in arms)
    first = arms[0]
    return _Ray(
        first.start,
        first.d,
        first.end,
        -1,
        0.0,
        -1,
        slots,
        cost,
        -1,
        -1,
        first.reach,
        p0=hub,
        arms=tuple(arms),
        hub=hub,
        exact=exact,
    )


def _arc_arms(
    z: NDArray[np.complex128],
    wins: list[list[tuple[float, float]]],
    e_out: NDArray[np.complex128],
    hub: complex,
    lo: float,
    width: float,
    corners: NDArray[np.int64],
    diam: float,
    rigid: frozenset[int],
    extra: list[complex],
) -> list[_Ray]:
    """Arms that split the angle at ``hub`` from direction ``lo`` (degrees) over ``width``
    degrees into two parts in [60.5°, 119.5°]: to a corner of ``corners`` in view whose own
    window admits the arm, or to the boundary (:data:`ARM_SAMPLES` directions, and the
    directions ``extra`` where they fall in range); the cheapest few, joins first."""
    m = LAYOUT_MARGIN
    a = lo + max(ANGLE_MIN + m, width - ANGLE_MAX + m)
    b = lo + min(ANGLE_MAX - m, width - ANGLE_MIN - m)
    if b < a:
        return []
    out: list[_Ray] = []
    rel = np.degrees(np.angle((z[corners] - hub) * np.exp(-1j * math.radians(lo)))) % 360.0
    for i in corners[(rel >= a - lo) & (rel <= b - lo)].tolist():
        arm = _corner_arm(z, wins, e_out, hub, i, diam)
        if arm is not None:
            out.append(arm)
    joins = sorted(out, key=lambda r: r.cost)[:2]
    free: list[_Ray] = []
    dirs = [complex(np.exp(1j * math.radians(p))) for p in np.linspace(a, b, ARM_SAMPLES)]
    for d in extra:
        phi = (math.degrees(math.atan2(d.imag, d.real)) - lo) % 360.0
        if a - lo - 1e-9 <= phi <= b - lo + 1e-9:
            dirs.append(d)
    for d in dirs:
        arm = _free_arm(z, hub, d, diam, rigid)
        if arm is not None:
            free.append(arm)
    return joins + sorted(free, key=lambda r: r.cost)[: 3 - len(joins)]


def _free_arms(
    z: NDArray[np.complex128],
    p: complex,
    dirs: NDArray[np.complex128],
    diam: float,
    rigid: frozenset[int],
) -> list[_Ray | None]:
    """:func:`_free_arm` for many unit directions ``dirs`` from ``p`` at once."""
    gap = POINT_GAP * diam
    e = np.roll(z, -1) - z
    w = z - p
    den = (np.conj(dirs)[:, None] * e[None, :]).imag
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.conj(w) * e).imag[None, :] / den
        u = (np.conj(w)[None, :] * dirs[:, None]).imag / den
    ok = (np.abs(den) > 1e-15 * np.abs(e)[None, :]) & (t > 0) & (u >= 0) & (u <= 1)
    tt = np.where(ok, t, np.inf)
    j = np.argmin(tt, axis=1)
    rows = np.arange(len(dirs))
    tj, uj, ej = tt[rows, j], u[rows, j], e[j]
    cosang = np.abs((np.conj(dirs) * ej).real) / np.abs(ej)
    good = (
        np.isfinite(tj)
        & (tj >= gap)
        & (np.minimum(uj, 1 - uj) * np.abs(ej) >= gap)
        & (cosang <= math.cos(math.radians(ANGLE_MIN + LAYOUT_MARGIN)))
        & ~np.isin(j, list(rigid))
    )
    out: list[_Ray | None] = []
    for q in range(len(dirs)):
        if not good[q]:
            out.append(None)
            continue
        alpha = 90.0 - math.degrees(math.asin(min(1.0, float(cosang[q]))))
        cost = 0.5 + 0.5 * (90.0 - alpha) / 30.0 + 0.2 * float(tj[q]) / diam
        end = complex(z[j[q]] + uj[q] * ej[q])
        d = complex(dirs[q])
        out.append(
            _Ray(-1, d, end, int(j[q]), float(uj[q]), -1, [], cost, -2, -1, float(tj[q]), p0=p)
        )
    return out


def _cycle(arms: list[tuple[float, _Ray]]) -> list[_Ray] | None:
    """The cheapest choice among ``arms`` (angle in degrees from the first, which is always
    taken, counter-clockwise in [0°, 360°)) whose consecutive angles, the last back to the
    first included, all lie in [60.5°, 119.5°] or are exactly 120° (within rounding); None
    if there is none."""
    lo, hi = ANGLE_MIN + LAYOUT_MARGIN, ANGLE_MAX - LAYOUT_MARGIN

    def fits(g: float) -> bool:
        return lo <= g <= hi or abs(g - ANGLE_MAX) < 1e-9

    arms = sorted(arms, key=lambda x: x[0])
    m = len(arms)
    best = [math.inf] * m
    prev = [-1] * m
    best[0] = arms[0][1].cost
    for i in range(1, m):
        for k in range(i):
            if best[k] + arms[i][1].cost < best[i] and fits(arms[i][0] - arms[k][0]):
                best[i] = best[k] + arms[i][1].cost
                prev[i] = k
    ends = [i for i in range(1, m) if best[i] < math.inf and fits(360.0 - arms[i][0])]
    if not ends:
        return None
    i = min(ends, key=lambda q: best[q])
    out = []
    while i >= 0:
        out.append(arms[i][1])
        i = prev[i]
    return out[::-1]


def _hubs_on_rays(
    z: NDArray[np.complex128],
    wins: list[list[tuple[float, float]]],
    e_out: NDArray[np.complex128],
    corners: NDArray[np.int64],
    diam: float,
    long: list[_Ray],
    rigid: frozenset[int],
    deadline: float = math.inf,
) -> list[_Ray]:
    """Junctions at points sampled along the cuts ``long``: the cut runs from its corner to
    the hub, and further arms leave the hub to corners in view (whose windows admit them) or to
    the boundary (every :data:`HUB_DIRECTIONS`-th of a turn, and at exactly ±120° from the
    cut), chosen by :func:`_cycle` so that every angle at the hub is in range; per hub the
    cheapest choice and the cheapest that favours serving other corners."""
    gap = POINT_GAP * diam
    out: list[_Ray] = []
    base_dirs = np.exp(2j * np.pi * np.arange(HUB_DIRECTIONS) / HUB_DIRECTIONS)
    for r in long:
        if time.perf_counter() > deadline:
            break
        for f in HUB_POSITIONS:
            hub = complex(z[r.start] + f * r.reach * r.d)
            if f * r.reach < gap or _boundary_dist(z, hub) < gap:
                continue
            back = -r.d
            arm0 = _Ray(
                -1,
                back,
                complex(z[r.start]),
                -1,
                0.0,
                r.start,
                list(r.slots),
                1.0 + 0.2 * f * r.reach / diam,
                -2,
                -1,
                f * r.reach,
                p0=hub,
            )
            dirs = np.concatenate(
                [base_dirs * back, back * np.exp(2j * np.pi / 3 * np.array([1, -1]))]
            )
            cand: list[tuple[float, _Ray]] = [(0.0, arm0)]
            for arm in _free_arms(z, hub, dirs, diam, rigid):
                if arm is not None:
                    cand.append((_turn(arm.d, back), arm))
            joins: list[tuple[float, _Ray]] = []
            for i in corners[corners != r.start].tolist():
                arm = _corner_arm(z, wins, e_out, hub, i, diam)
                if arm is not None:
                    joins.append((_turn(arm.d, back), arm))
            cand = [cand[0]] + [c for c in cand[1:] if 1e-9 < c[0] < 360.0 - 1e-9]
            seen: set[tuple[int, ...]] = set()
            for favour in (0.0, 1.5):
                # a join serves another corner's cut: favoured, it makes the cheapest choice
                # the one that reaches most corners
                cheap = [(a, replace(arm, cost=arm.cost - favour), arm) for a, arm in joins]
                cyc = _cycle(cand + [(a, c) for a, c, _ in cheap])
                if cyc is None:
                    continue
                orig = {id(c): arm for _, c, arm in cheap}  # the joins at their own cost
                arms = [orig.get(id(a), a) for a in cyc]
                key = tuple(sorted(id(a) for a in arms))
                if key in seen:
                    continue
                seen.add(key)
                ang = sorted(_turn(a.d, back) for a in arms)
                exact = bool(np.any(np.diff(np.append(ang, 360.0)) > ANGLE_MAX - LAYOUT_MARGIN))
                out.append(_star(arms, hub, exact=exact))
        checkpoint()
    return out


def _turn(d: complex, ref: complex) -> float:
    """Angle in degrees, in [0°, 360°), from direction ``ref`` counter-clockwise to ``d``."""
    q = d / ref
    return math.degrees(math.atan2(q.imag, q.real)) % 360.0


def _arm_back(z: NDArray[np.complex128], r: _Ray, hub: complex, diam: float) -> _Ray:
    """The arm of a junction from ``hub`` back to the corner where the cut ``r`` starts (the
    part of ``r`` before the hub), serving ``r``'s slots."""
    length = abs(hub - z[r.start])
    return _Ray(
        start=-1,
        d=-r.d,
        end=complex(z[r.start]),
        edge=-1,
        u=0.0,
        join=r.start,
        slots=list(r.slots),
        cost=1.0 + 0.2 * length / diam,
        base=-2,
        stop=-1,
        reach=length,
        p0=hub,
    )


def _junctions(
    z: NDArray[np.complex128],
    theta: NDArray[np.float64],
    diam: float,
    long: list[_Ray],
    rigid: frozenset[int] = frozenset(),
    exact: frozenset[int] = frozenset(),
    deadline: float = math.inf,
    needy: frozenset[tuple[int, int]] | None = None,
    twin: frozenset[int] = frozenset(),
) -> list[_Ray]:
    """Junction candidates: interior points where three or more cuts meet, each a single
    candidate covering the cut slots of the corners its arms reach.  With ``needy`` (cut slots
    no straight cut serves) only junctions that serve one of them are built: on a cut of a
    needy slot, or with an arm to a corner that has one.

    * An *X*: two cuts ``long`` (full rays, or rays whose own boundary end is unusable) from
      different corners that cross at an angle ω with ω and 360° - ω both in [121°, 239°]
      stop at the crossing, and each of the two angles is split by one more arm: to a corner in
      view whose window admits it (serving that corner's cut too) or to the boundary at an
      angle in [60.5°, 119.5°].
    * A *Y*: a cut of ``long`` from corner a and a cut from another corner b placed so that
      they meet at exactly 120° (the point on a's cut from which a and b are 120° apart), and a
      third arm along the bisector of the remaining 240° to the boundary; all three angles
      are exactly 120° (three angles at most 120° summing to 360° leave no other choice).

    * A *hub along a cut*: a point of a cut of ``long`` at the fractions :data:`HUB_POSITIONS`
      of its length, the cut running from its corner to the hub, with arms around the hub to
      corners or to the boundary (:func:`_hubs_on_rays`).

    Junction points keep the point gap from the boundary; the cheapest :data:`MAX_JUNCTIONS`
    are returned."""
    n = len(z)
    gap = POINT_GAP * diam
    m = LAYOUT_MARGIN
    e_out = np.roll(z, -1) - z
    wins = [_windows(float(t), i in exact, i in twin) for i, t in enumerate(theta)]
    corners = np.array([i for i in range(n) if wins[i]], dtype=np.int64)
    if len(long) < 1 or len(corners) < 2:
        return []
    if needy is None:
        needy = frozenset(s for r in long for s in r.slots)
    mine = np.array([bool(set(r.slots) & needy) for r in long])  # cuts of needy slots
    short = np.array(sorted({i for i, _ in needy}), dtype=np.int64)  # corners with one
    # hubs along the cuts first: when time runs short they are the most useful
    stars = _hubs_on_rays(
        z, wins, e_out, corners, diam, [r for r, k in zip(long, mine) if k], rigid, deadline
    )
    P = np.array([z[r.start] for r in long], dtype=np.complex128)
    Q = np.array([r.end for r in long], dtype=np.complex128)
    D = Q - P
    L = np.abs(D)
    start = np.array([r.start for r in long])
    # X: pairs of cuts crossing at an angle with both sides splittable by one arm
    den = (np.conj(D[:, None]) * D[None, :]).imag
    w = P[None, :] - P[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (np.conj(w) * D[None, :]).imag / den
        t = (np.conj(w) * D[:, None]).imag / den
        omega = np.degrees(np.angle(D[None, :] / D[:, None])) % 360.0
    lo_w, hi_w = 2 * (ANGLE_MIN + m), 2 * (ANGLE_MAX - m)
    ok = (
        np.triu(np.ones((len(long), len(long)), dtype=bool), 1)
        & (start[:, None] != start[None, :])
        & (np.abs(den) > 1e-12 * L[:, None] * L[None, :])
        & (s * L[:, None] > gap)
        & ((1 - s) * L[:, None] > gap)
        & (t * L[None, :] > gap)
        & ((1 - t) * L[None, :] > gap)
        & (omega >= lo_w)
        & (omega <= hi_w)
        & (mine[:, None] | mine[None, :])
    )
    ia, ib = np.nonzero(ok)
    order = np.argsort(s[ia, ib] * L[ia] + t[ia, ib] * L[ib], kind="stable")
    for k in order[:MAX_JUNCTION_PAIRS].tolist():
        if time.perf_counter() > deadline:
            break
        a, b = int(ia[k]), int(ib[k])
        ra, rb = long[a], long[b]
        hub = complex(P[a] + s[a, b] * D[a])
        if _boundary_dist(z, hub) < gap:
            continue
        arm_a, arm_b = _arm_back(z, ra, hub, diam), _arm_back(z, rb, hub, diam)
        da = math.degrees(math.atan2(-ra.d.imag, -ra.d.real))  # the arm back to a
        om = float(omega[a, b])  # from the arm to a counter-clockwise to the arm to b
        others = corners[(corners != ra.start) & (corners != rb.start)]
        left = _arc_arms(z, wins, e_out, hub, da, om, others, diam, rigid, [ra.d, rb.d])
        right = _arc_arms(
            z, wins, e_out, hub, da + om, 360.0 - om, others, diam, rigid, [ra.d, rb.d]
        )
        for x in left[:2]:
            for y in right[:2]:
                if x.join >= 0 and x.join == y.join:
                    continue
                stars.append(_star([arm_a, x, arm_b, y], hub))
        checkpoint()
    # Y: a cut from a, and a cut from b meeting it at exactly 120°, one of them needy
    for r, own in zip(long, mine.tolist()):
        if time.perf_counter() > deadline:
            break
        cs = corners if own else short
        wv = (z[cs] - z[r.start]) / r.d  # b in the frame of the cut (along +real)
        ss = wv.real - np.abs(wv.imag) / math.sqrt(3.0)
        good = (cs != r.start) & (ss > gap) & (ss < r.reach - gap) & (np.abs(wv.imag) > gap)
        for b, sv in zip(cs[good].tolist(), ss[good].tolist()):
            hub = complex(z[r.start] + sv * r.d)
            if _boundary_dist(z, hub) < gap:
                continue
            arm_b = _corner_arm(z, wins, e_out, hub, b, diam)
            if arm_b is None:
                continue
            ua = -r.d
            third = -(ua + arm_b.d)  # the arms' unit vectors at 120° sum to zero
            third /= abs(third)
            arm_c = _free_arm(z, hub, third, diam, rigid)
            if arm_c is None:
                continue
            arm_a = _Ray(
                -1,
                ua,
                complex(z[r.start]),
                -1,
                0.0,
                r.start,
                list(r.slots),
                1.0 + 0.2 * sv / diam,
                -2,
                -1,
                sv,
                p0=hub,
            )
            stars.append(_star([arm_a, arm_b, arm_c], hub, exact=True))
        checkpoint()
    stars.sort(key=lambda c: c.cost)
    return stars[:MAX_JUNCTIONS]


def _seg_cross(p1: complex, p2: complex, q1: complex, q2: complex) -> tuple[float, float] | None:
    """Parameters (s, t) of the crossing of segments p1p2 and q1q2 (None if they miss or are
    parallel)."""
    d1 = p2 - p1
    d2 = q2 - q1
    den = (d1.conjugate() * d2).imag
    if abs(den) <= 1e-14 * abs(d1) * abs(d2):
        return None
    w = q1 - p1
    s = (w.conjugate() * d2).imag / den
    t = (w.conjugate() * d1).imag / den
    if -1e-12 <= s <= 1 + 1e-12 and -1e-12 <= t <= 1 + 1e-12:
        return s, t
    return None


def _pair_conflicts(z: NDArray[np.complex128], ra: _Ray, rb: _Ray, gap: float) -> bool:
    """Whether rays ``ra`` and ``rb`` may not both be chosen (one pair; :func:`_conflicts`
    decides every pair at once with the same rules)."""
    m = LAYOUT_MARGIN
    if (ra.stop >= 0 and ra.stop == rb.base) or (rb.stop >= 0 and rb.stop == ra.base):
        return False  # one ends on the other: the support rows of _solve decide
    shared = ({ra.start, ra.join} - {-1}) & ({rb.start, rb.join} - {-1})
    if shared:
        if len(shared) == 2:
            return True  # the same segment (a join seen from both ends)
        v = shared.pop()
        e = z[(v + 1) % len(z)] - z[v]
        da = (ra.end - z[v]) if ra.start == v else (_p0(z, ra) - z[v])
        db = (rb.end - z[v]) if rb.start == v else (_p0(z, rb) - z[v])
        pa = math.degrees(math.atan2((da / e).imag, (da / e).real)) % 360
        pb = math.degrees(math.atan2((db / e).imag, (db / e).real)) % 360
        lo, hi = sorted((pa, pb))
        return not ANGLE_MIN + m <= hi - lo <= ANGLE_MAX - m
    pa_, qa, pb_, qb = _p0(z, ra), ra.end, _p0(z, rb), rb.end
    if abs(qa - qb) < gap:
        return True  # end points too close to each other
    x = _seg_cross(pa_, qa, pb_, qb)
    if x is None:  # nearly touching without crossing: a point of one close to the other
        return _point_seg_dist(qa, pb_, qb) < gap or _point_seg_dist(qb, pa_, qa) < gap
    s, t = x
    la, lb = abs(qa - pa_), abs(qb - pb_)
    if min(s * la, (1 - s) * la, t * lb, (1 - t) * lb) < gap:
        return True
    da, db = qa - pa_, qb - pb_
    return abs((np.conj(da) * db).real) / (la * lb) > math.cos(math.radians(ANGLE_MIN + m))


def _conflicts(z: NDArray[np.complex128], cands: list[_Ray], diam: float) -> list[tuple[int, int]]:
    """Pairs ``(a, b)``, a < b, of candidate cuts that may not both be chosen: they cross at an
    angle outside [60.5°, 119.5°] or closer than the point gap to an end, end close together or
    one ends close to the other, or they leave one corner with a part outside that range (the
    rules of :func:`_pair_conflicts`; pairs sharing a corner are decided one by one, all others
    at once in numpy, in blocks of rows).  A junction conflicts with a cut when one of its arms
    does."""
    gap = POINT_GAP * diam
    rays, owner = _segments(cands)
    nr = len(rays)
    if nr < 2:
        return []
    P = np.array([_p0(z, r) for r in rays], dtype=np.complex128)
    Q = np.array([r.end for r in rays], dtype=np.complex128)
    D = Q - P
    L = np.abs(D)
    start = np.array([r.start for r in rays])
    join = np.array([r.join for r in rays])
    base = np.array([r.base for r in rays])
    stop = np.array([r.stop for r in rays])
    cos_lo = math.cos(math.radians(ANGLE_MIN + LAYOUT_MARGIN))  # |cos| above: a bad angle
    cols = np.arange(nr)
    found: list[tuple[NDArray[np.int64], NDArray[np.int64]]] = []
    for lo in range(0, nr, 256):
        checkpoint()
        a = np.arange(lo, min(lo + 256, nr))[:, None]
        upper = (cols[None, :] > a) & (owner[None, :] != owner[a])
        tee = ((stop[a] >= 0) & (stop[a] == base[None, :])) | (
            (stop[None, :] >= 0) & (stop[None, :] == base[a])
        )
        ja, jb = join[a], join[None, :]
        sa, sb = start[a], start[None, :]
        share = (
            ((sa >= 0) & (sa == sb))
            | ((jb >= 0) & (sa == jb))
            | ((ja >= 0) & (ja == sb))
            | ((ja >= 0) & (ja == jb))
        )
        Pa, Qa, Da, La = P[a], Q[a], D[a], L[a]
        Pb, Qb, Db, Lb = P[None, :], Q[None, :], D[None, :], L[None, :]
        close_ends = np.abs(Qa - Qb) < gap
        den = (np.conj(Da) * Db).imag
        w = Pb - Pa
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (np.conj(w) * Db).imag / den
            t = (np.conj(w) * Da).imag / den
        tol = 1e-12
        cross = (
            (np.abs(den) > 1e-14 * La * Lb)
            & (s >= -tol)
            & (s <= 1 + tol)
            & (t >= -tol)
            & (t <= 1 + tol)
        )
        near_x = (
            np.minimum(np.minimum(s * La, (1 - s) * La), np.minimum(t * Lb, (1 - t) * Lb)) < gap
        )
        steep = np.abs((np.conj(Da) * Db).real) / np.maximum(La * Lb, 1e-300) > cos_lo
        # distance of each end point from the other segment (no crossing)
        with np.errstate(divide="ignore", invalid="ignore"):
            ua = np.clip(((Qa - Pb) * np.conj(Db)).real / (Lb * Lb), 0.0, 1.0)
            ub = np.clip(((Qb - Pa) * np.conj(Da)).real / (La * La), 0.0, 1.0)
        touch = (np.abs(Qa - (Pb + ua * Db)) < gap) | (np.abs(Qb - (Pa + ub * Da)) < gap)
        geo = close_ends | np.where(cross, near_x | steep, touch)
        res = upper & ~tee & ~share & geo
        i, j = np.nonzero(res)
        found.append((a[i, 0], j))
        # pairs sharing a corner: one by one for cuts, at once for junction arms (many)
        i, j = np.nonzero(upper & ~tee & share)
        ia = a[i, 0]
        arm = (start[ia] < 0) | (start[j] < 0)
        si, sj = [], []
        for ai, bj in zip(ia[~arm].tolist(), j[~arm].tolist()):
            if _pair_conflicts(z, rays[ai], rays[bj], gap):
                si.append(ai)
                sj.append(bj)
        found.append((np.array(si, dtype=np.int64), np.array(sj, dtype=np.int64)))
        if np.any(arm):
            ia, ja = ia[arm], j[arm]
            hit = _shared_corner_conflicts(z, P, Q, start, join, ia, ja)
            found.append((ia[hit], ja[hit]))
    oa = owner[np.concatenate([f[0] for f in found])]
    ob = owner[np.concatenate([f[1] for f in found])]
    if nr == len(cands):  # no junctions: the pairs as found
        return list(zip(oa.tolist(), ob.tolist()))
    # segments to candidates, each pair once
    lo_, hi_ = np.minimum(oa, ob), np.maximum(oa, ob)
    code = np.unique(lo_ * len(cands) + hi_)
    return list(zip((code // len(cands)).tolist(), (code % len(cands)).tolist()))


def _shared_corner_conflicts(
    z: NDArray[np.complex128],
    P: NDArray[np.complex128],
    Q: NDArray[np.complex128],
    start: NDArray[np.int64],
    join: NDArray[np.int64],
    ia: NDArray[np.int64],
    ib: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """For pairs ``(ia, ib)`` of segments (from ``P`` to ``Q``, leaving corner ``start`` or
    -1, reaching corner ``join`` or -1) that share a corner: whether they conflict by the rule
    of :func:`_pair_conflicts` (the same segment, or a part between them at that corner
    outside [60.5°, 119.5°]), at once."""
    m = LAYOUT_MARGIN
    sa, ja, sb, jb = start[ia], join[ia], start[ib], join[ib]
    ss = (sa >= 0) & (sa == sb)
    sj = (jb >= 0) & (sa == jb)
    js = (ja >= 0) & (ja == sb)
    jj = (ja >= 0) & (ja == jb)
    same = (ss & jj) | (sj & js)
    v = np.where(ss | sj, sa, ja)
    zv = z[v]
    ev = z[(v + 1) % len(z)] - zv
    da = np.where(sa == v, Q[ia] - zv, P[ia] - zv)
    db = np.where(sb == v, Q[ib] - zv, P[ib] - zv)
    diff = np.abs(np.degrees(np.angle(da / ev)) % 360.0 - np.degrees(np.angle(db / ev)) % 360.0)
    return same | ~((diff >= ANGLE_MIN + m) & (diff <= ANGLE_MAX - m))


def _point_seg_dist(p: complex, a: complex, b: complex) -> float:
    d = b - a
    t = ((p - a) * d.conjugate()).real / max(abs(d) ** 2, 1e-300)
    t = min(max(t, 0.0), 1.0)
    return abs(p - (a + t * d))


def _conflict_cliques(rays: list[_Ray], bad: list[tuple[int, int]]) -> list[list[int]]:
    """Sets of candidate cuts of which at most one can be chosen, covering every conflicting
    pair of ``bad``: each becomes one row ``sum <= 1`` of the integer program in place of the
    rows of all its pairs — fewer rows and a tighter relaxation.  Two candidates exclude each
    other when they conflict or share a cut slot (each slot is served exactly once), so a set
    may hold several candidates of one slot.  Greedy: from the candidate with the most
    uncovered conflicts, its uncovered neighbours by number of exclusions, each taken if it
    excludes all taken so far, then any other candidate that does (each set is maximal).
    Above :data:`MAX_CLIQUE_CANDIDATES` candidates (the dense matrices would be large) the
    pairs themselves.

    Measured (HiGHS 1.12 through ``scipy.optimize.milp``, two processes on 2 cores): a 52-vertex
    pixel contour's single round, 675 candidates and 43,247 pairs, is 2,861 rows (6,762 sets
    when not made maximal), solved in 0.41 s instead of 1.15; STIX "A"'s rounds 3.2 → 0.8 s.
    HiGHS stops within its gap tolerance, and the pairwise rows often left it at a dearer
    choice (STIX "A": 44.7 where the optimum is 35.8), so the layouts found change: on the 124
    glyphs of two fonts pure block meshes 103 → 107 and the families' time −20 %."""
    n = len(rays)
    if not bad:
        return []
    if n > MAX_CLIQUE_CANDIDATES:
        return [[int(a), int(b)] for a, b in bad]
    bb = np.asarray(bad, dtype=np.int64)
    left = np.zeros((n, n), dtype=bool)  # conflicts not covered yet
    left[bb[:, 0], bb[:, 1]] = True
    left[bb[:, 1], bb[:, 0]] = True
    excl = left.copy()
    by_slot: dict[tuple[int, int], list[int]] = {}
    for k, r in enumerate(rays):
        for s in r.slots:
            by_slot.setdefault(s, []).append(k)
    for ks in by_slot.values():
        if len(ks) > 1:
            excl[np.ix_(ks, ks)] = True
    np.fill_diagonal(excl, False)
    np.fill_diagonal(left, False)
    deg = excl.sum(axis=1)
    by_degree = np.argsort(-deg, kind="stable")
    cliques: list[list[int]] = []
    for v in np.argsort(-left.sum(axis=1), kind="stable").tolist():
        while True:
            cand = np.flatnonzero(left[v])
            if len(cand) == 0:
                break
            cand = cand[np.argsort(-deg[cand], kind="stable")]
            mask = excl[v].copy()
            clique = [v]
            for u in cand.tolist():
                if mask[u]:
                    clique.append(u)
                    mask &= excl[u]
            # then made maximal: a larger set covers more pairs, so fewer rows are needed
            for u in by_degree[mask[by_degree]].tolist():
                if mask[u]:
                    clique.append(u)
                    mask &= excl[u]
            c = np.asarray(clique)
            left[np.ix_(c, c)] = False
            cliques.append(clique)
    return cliques


def _solve(
    rays: list[_Ray],
    slots: list[tuple[int, int]],
    bad: list[tuple[int, int]],
    nogoods: list[list[int]],
    seconds: float = SEARCH_SECONDS,
    rel_gap: float | None = None,
    unserved_cost: float | None = None,
    cliques: list[list[int]] | None = None,
) -> list[int] | None:
    """The cheapest choice of candidate cuts: one per cut slot, no conflicting pair, every
    T-junction on a chosen cut that reaches past it, no ``nogoods`` set in full; within
    ``rel_gap`` of the optimum when given.  With ``unserved_cost`` a slot may also stay
    without a cut, at that cost.  The conflicts enter as rows over ``cliques`` (default
    :func:`_conflict_cliques` of ``bad``).  None if there is none (or none within
    ``seconds``)."""
    nr = len(rays)
    n_var = nr + (len(slots) if unserved_cost is not None else 0)
    sid = {s: k for k, s in enumerate(slots)}
    rows, cols = [], []
    for c, r in enumerate(rays):
        for s in r.slots:
            rows.append(sid[s])
            cols.append(c)
    if unserved_cost is not None:  # one slack variable per slot
        rows += list(range(len(slots)))
        cols += list(range(nr, n_var))
    A_eq = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(slots), n_var))
    cons = [LinearConstraint(A_eq, 1, 1)]
    if cliques is None:
        cliques = _conflict_cliques(rays, bad)
    if cliques:
        sizes = [len(c) for c in cliques]
        A_b = coo_matrix(
            (
                np.ones(sum(sizes)),
                (np.repeat(np.arange(len(cliques)), sizes), np.concatenate(cliques)),
            ),
            shape=(len(cliques), n_var),
        )
        cons.append(LinearConstraint(A_b, -np.inf, 1))
    # a T-variant needs a chosen version of the ray it stops on that reaches past its end
    tee = np.array([r.stop for r in rays])
    base = np.array([r.base for r in rays])
    ends = np.array([r.end for r in rays], dtype=np.complex128)
    dirs = np.array([r.d for r in rays], dtype=np.complex128)
    reach = np.array([r.reach for r in rays])
    t_rows, t_cols, t_vals = [], [], []
    for k, c in enumerate(np.nonzero(tee >= 0)[0]):
        cand = np.nonzero(base == tee[c])[0]
        along = ((ends[c] - ends[cand]) * np.conj(dirs[cand])).real  # < 0: reaches past it
        past = cand[along < -1e-9 * reach[cand]]
        t_rows += [k] * (1 + len(past))
        t_cols += [int(c), *past.tolist()]
        t_vals += [1.0] + [-1.0] * len(past)
    if t_rows:
        A_t = coo_matrix((t_vals, (t_rows, t_cols)), shape=(max(t_rows) + 1, n_var))
        cons.append(LinearConstraint(A_t, -np.inf, 0))
    for ng in nogoods:
        row = np.zeros(n_var)
        row[ng] = 1
        cons.append(LinearConstraint(row[None, :], -np.inf, len(ng) - 1))
    cost = np.array([r.cost for r in rays])
    if unserved_cost is not None:
        cost = np.concatenate([cost, np.full(len(slots), unserved_cost)])
    with _quiet_stdout():
        res = milp(
            cost,
            constraints=cons,
            integrality=np.ones(n_var),
            bounds=Bounds(0, 1),
            options={"time_limit": max(seconds, 0.1)}
            # (HiGHS's presolve spends a second on the dense rows of the junction search)
            | ({} if rel_gap is None else {"mip_rel_gap": rel_gap, "presolve": False}),
        )
    # with a gap, or where slots may stay without a cut, a layout found before the time ran
    # out will do as well (status 1: the time limit was reached with a feasible solution)
    anytime = rel_gap is not None or unserved_cost is not None
    if res.x is None or not (res.status == 0 or (anytime and res.status == 1)):
        if unserved_cost is not None:
            return _greedy_cuts(rays, bad, nogoods)
        return None
    return [int(c) for c in np.nonzero(res.x[:nr] > 0.5)[0]]


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Send what native code writes to the process's standard output (file descriptor 1) to
    the null device for the duration of the block: HiGHS 1.12 prints a debugging line
    ("HighsMipSolverData::transformNewIntegerFeasibleSolution tmpSolver.run();") whatever its
    output options say, on some glyphs' searches, into the output of ``quadmesh mesh``.
    Python's own ``sys.stdout`` is flushed first; where descriptor 1 cannot be duplicated the
    block runs as it is."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            try:
                yield
            finally:
                os.dup2(saved, 1)
    finally:
        os.close(saved)


def _greedy_cuts(
    rays: list[_Ray], bad: list[tuple[int, int]], nogoods: list[list[int]]
) -> list[int]:
    """A choice of candidate cuts for the relaxed search when the integer program found none
    in its time (STIX "b": its first after 15 s): the cheapest candidates first, each taken if
    its cut slots are still free, it conflicts with no cut taken and completes no ``nogoods``
    set; T-junction variants and junctions are left out. Slots left free stay without a
    cut."""
    conflicts: dict[int, set[int]] = {}
    for a, b in bad:
        conflicts.setdefault(a, set()).add(b)
        conflicts.setdefault(b, set()).add(a)
    sets = [set(ng) for ng in nogoods]
    chosen: set[int] = set()
    served: set[tuple[int, int]] = set()
    for c in sorted(range(len(rays)), key=lambda k: rays[k].cost):
        r = rays[c]
        if r.stop >= 0 or r.arms or served.intersection(r.slots):
            continue
        if conflicts.get(c, set()) & chosen or any(ng <= chosen | {c} for ng in sets):
            continue
        chosen.add(c)
        served.update(r.slots)
    return sorted(chosen)


# --------------------------------------------------------------------------- arrangement


def _arrangement(
    z: NDArray[np.complex128], cands: list[_Ray]
) -> tuple[NDArray[np.complex128], list[NDArray[np.int64]], list[set[int]], list[int]]:
    """Points and faces (CCW point-index cycles) of the polygon cut by the chosen candidate
    cuts, for every face the candidates on its boundary, and the point indices of the hubs
    of the chosen junctions whose three angles are exactly 120°."""
    n = len(z)
    pts: list[complex] = list(z)
    rays, owner = _segments(cands)
    # a junction's hub is a point of its own, where all its arms start
    hub_of: dict[int, int] = {}
    exact_hubs: list[int] = []
    for k, c in enumerate(cands):
        if c.hub is not None:
            hub_of[k] = len(pts)
            pts.append(c.hub)
            if c.exact:
                exact_hubs.append(hub_of[k])
    # points on every polygon edge (parameter, index) and on every ray
    on_edge: dict[int, list[tuple[float, int]]] = {
        j: [(0.0, j), (1.0, (j + 1) % n)] for j in range(n)
    }
    on_ray: list[list[tuple[float, int]]] = []
    for r, k in zip(rays, owner.tolist()):
        if r.join >= 0:
            end = r.join
        else:
            end = len(pts)
            pts.append(r.end)
            if r.edge >= 0:
                on_edge[r.edge].append((r.u, end))
        on_ray.append([(0.0, r.start if r.p0 is None else hub_of[k]), (1.0, end)])
    by_base = {r.base: k for k, r in enumerate(rays) if r.base >= 0}
    for a, r in enumerate(rays):
        if r.stop >= 0:  # a T: the end point lies on the ray it stops at
            b = by_base[r.stop]
            rb = rays[b]
            t = ((r.end - z[rb.start]) * np.conj(rb.end - z[rb.start])).real / abs(
                rb.end - z[rb.start]
            ) ** 2
            on_ray[b].append((t, on_ray[a][1][1]))
    for a in range(len(rays)):
        for b in range(a + 1, len(rays)):
            ra, rb = rays[a], rays[b]
            if owner[a] == owner[b] or {ra.start, ra.join} & {rb.start, rb.join} - {-1}:
                continue
            if ra.stop == rb.base or rb.stop == ra.base:
                continue
            pa, pb = _p0(z, ra), _p0(z, rb)
            x = _seg_cross(pa, ra.end, pb, rb.end)
            if x is None:
                continue
            s, t = x
            if not (0 < s < 1 and 0 < t < 1):
                continue
            k = len(pts)
            pts.append(pa + s * (ra.end - pa))
            on_ray[a].append((s, k))
            on_ray[b].append((t, k))
    edges: set[tuple[int, int]] = set()
    ray_of_edge: dict[tuple[int, int], int] = {}
    for j in range(n):
        seq = [k for _, k in sorted(on_edge[j])]
        for u, v in pairwise(seq):
            edges.add((u, v))
            edges.add((v, u))  # the outer side: its cycle has negative area and is dropped
    for a, lst in enumerate(on_ray):
        seq = [k for _, k in sorted(lst)]
        for u, v in pairwise(seq):
            edges.add((u, v))
            edges.add((v, u))
            ray_of_edge[(u, v)] = ray_of_edge[(v, u)] = int(owner[a])
    P = np.array(pts, dtype=np.complex128)
    out: dict[int, list[int]] = {}
    for u, v in edges:
        out.setdefault(u, []).append(v)
    order: dict[int, list[int]] = {}
    for u, nb in out.items():
        ang = [math.atan2((P[v] - P[u]).imag, (P[v] - P[u]).real) for v in nb]
        order[u] = [nb[k] for k in np.argsort(ang)]
    seen: set[tuple[int, int]] = set()
    faces: list[NDArray[np.int64]] = []
    face_rays: list[set[int]] = []
    for e0 in edges:
        if e0 in seen:
            continue
        cyc = []
        fr: set[int] = set()
        u, v = e0
        while (u, v) not in seen:
            seen.add((u, v))
            cyc.append(u)
            if (u, v) in ray_of_edge:
                fr.add(ray_of_edge[(u, v)])
            nb = order[v]
            k = nb.index(u)
            w = nb[(k - 1) % len(nb)]  # first clockwise from v->u
            u, v = v, w
        c = np.array(cyc, dtype=np.int64)
        w = P[c]
        area = 0.5 * float(
            np.sum(
                (w - w[0]).real * np.roll(w - w[0], -1).imag
                - np.roll(w - w[0], -1).real * (w - w[0]).imag
            )
        )
        if area > 0:
            faces.append(c)
            face_rays.append(fr)
    return P, faces, face_rays, exact_hubs


# --------------------------------------------------------------------------- centre splits


def _split_cells(
    P: NDArray[np.complex128],
    faces: list[NDArray[np.int64]],
    tip_mask: NDArray[np.bool_],
    own_mask: NDArray[np.bool_],
    margin: float = 0.5 * LAYOUT_MARGIN,
    separate: bool = False,
    sample: bool = False,
) -> tuple[NDArray[np.complex128], NDArray[np.int64], list[int]]:
    """Split every face into quads about a centre point, one point on every face side (shared
    by the two faces on it): ``(points, cells, bad_faces)``.  Quadrilateral faces start from
    their 2×2 bilinear split (admissible by the bilinear argument); the centres and side points
    of the other faces are placed to keep every new corner in range (max-min by SLSQP).
    ``tip_mask``: points whose corner only has to be above 0°; ``own_mask``: uncut polygon
    corners (their angle is the polygon's own, in range up to rounding)."""
    nP = len(P)
    side_id: dict[tuple[int, int], int] = {}
    sides: list[tuple[int, int]] = []
    for f in faces:
        for u, v in zip(f, np.roll(f, -1)):
            key = (min(u, v), max(u, v))
            if key not in side_id:
                side_id[key] = len(sides)
                sides.append(key)
    S = np.array(sides, dtype=np.int64)
    nS = len(S)
    t = np.full(nS, 0.5)
    C = np.array([P[f].mean() for f in faces])
    # cells: (face, corner k) -> (corner, side point after, centre, side point before)
    cell_rows = []
    cell_face = []
    for fi, f in enumerate(faces):
        k = len(f)
        for a in range(k):
            u, v, w = f[(a - 1) % k], f[a], f[(a + 1) % k]
            cell_rows.append(
                (v, side_id[(min(v, w), max(v, w))], fi, side_id[(min(u, v), max(u, v))])
            )
            cell_face.append(fi)
    R = np.array(cell_rows, dtype=np.int64)
    cell_face_a = np.array(cell_face)
    corner_is_tip = tip_mask[R[:, 0]]
    need = np.full((len(R), 4), margin)
    need[:, 0] = np.where(own_mask[R[:, 0]] | corner_is_tip, -ANGLE_TOL, need[:, 0])

    def positions(tt: NDArray[np.float64], cc: NDArray[np.complex128]) -> NDArray[np.complex128]:
        sp = P[S[:, 0]] + tt * (P[S[:, 1]] - P[S[:, 0]])
        return np.concatenate([P, sp, cc])

    def cells_idx() -> NDArray[np.int64]:
        return np.stack([R[:, 0], nP + R[:, 1], nP + nS + R[:, 2], nP + R[:, 3]], axis=1)

    Q = cells_idx()

    def slack(X: NDArray[np.complex128]) -> NDArray[np.float64]:
        return _split_slack(cell_angles(X[Q]), corner_is_tip, need)  # (C, 4)

    X = positions(t, C)
    sl = slack(X)
    bad_cells = np.any(sl < 0, axis=1)
    if np.any(bad_cells):
        # optimise the centres of the faces with bad cells and the side points around them
        bad_faces = np.unique(cell_face_a[bad_cells])
        groups = [bad_faces]
        if separate and len(bad_faces) > 1:
            # faces that share no side are optimised apart: smaller programs, each with its
            # own least slack
            parent = {int(f): int(f) for f in bad_faces}

            def root(f: int) -> int:
                while parent[f] != f:
                    f = parent[f]
                return f

            by_side: dict[int, list[int]] = {}
            for c in np.nonzero(np.isin(cell_face_a, bad_faces))[0].tolist():
                for sd in (int(R[c, 1]), int(R[c, 3])):
                    by_side.setdefault(sd, []).append(int(cell_face_a[c]))
            for fl in by_side.values():
                for f in fl[1:]:
                    parent[root(f)] = root(fl[0])
            comp: dict[int, list[int]] = {}
            for f in bad_faces.tolist():
                comp.setdefault(root(int(f)), []).append(int(f))
            groups = [np.array(g) for g in comp.values()]
        for group in groups:
            t, C = _centre_opt(P, R, cell_face_a, faces, group, t, C, slack, positions)
        X = positions(t, C)
        sl = slack(X)
        if sample and np.any(sl < 0):
            # SLSQP stalls from the centroids of skewed faces (a pentagon with one side 1/37
            # of another): a sampled search over centres and side points, then SLSQP again
            bad_faces = np.unique(cell_face_a[np.any(sl < 0, axis=1)])
            t2, C2 = _sampled_split(P, S, R, need, corner_is_tip, cell_face_a, bad_faces, t, C)
            t2, C2 = _centre_opt(P, R, cell_face_a, faces, bad_faces, t2, C2, slack, positions)
            sl2 = slack(positions(t2, C2))
            if sl2.min() > sl.min():
                t, C, sl = t2, C2, sl2
                X = positions(t, C)
    still = np.any(sl < 0, axis=1)
    return X, Q, sorted(set(cell_face_a[still].tolist()))


def _split_slack(
    ang: NDArray[np.float64], corner_is_tip: NDArray[np.bool_], need: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Slack of split cells ``(..., C, 4)`` from their angles: the distance of every corner from
    60° and 120° less its ``need`` (``(C, 4)``), >= 0 where in range; a polygon corner below 60°
    (first corner of a cell, ``corner_is_tip``) only has to be above 0°."""
    lo = ang - ANGLE_MIN
    lo[..., 0] = np.where(corner_is_tip, ang[..., 0], lo[..., 0])
    return np.minimum(lo, ANGLE_MAX - ang) - need


#: candidates per face centre and per side point in each round of :func:`_sampled_split`
SPLIT_SAMPLES = 256
#: rounds of :func:`_sampled_split` (centres, then side points, in each)
SPLIT_ROUNDS = 6


def _sampled_split(
    P: NDArray[np.complex128],
    S: NDArray[np.int64],
    R: NDArray[np.int64],
    need: NDArray[np.float64],
    corner_is_tip: NDArray[np.bool_],
    cell_face_a: NDArray[np.int64],
    bad_faces: NDArray[np.int64],
    t: NDArray[np.float64],
    C: NDArray[np.complex128],
) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """Centres and side points of the faces ``bad_faces`` of :func:`_split_cells` (and of the
    faces sharing their sides) by a sampled coordinate search: in each round every free face's
    centre becomes the best of :data:`SPLIT_SAMPLES` random convex combinations of its corners
    (and the current one) for the least slack of its own cells, then every free side point the
    best of as many parameters in [0.05, 0.95] for the least slack of the cells on that side.
    Seeded, so the same faces give the same split. Returns the new ``t`` and ``C``."""
    rng = np.random.default_rng(len(bad_faces) * 7919 + len(S))
    t = t.copy()
    C = C.copy()
    rows_of = {int(f): np.flatnonzero(cell_face_a == f) for f in np.unique(cell_face_a)}
    free_s = np.unique(np.concatenate([R[rows_of[int(f)]][:, [1, 3]].ravel() for f in bad_faces]))
    free_f = np.unique(cell_face_a[np.isin(R[:, 1], free_s) | np.isin(R[:, 3], free_s)])
    A, B = P[S[:, 0]], P[S[:, 1]] - P[S[:, 0]]

    def least(rows: NDArray[np.int64], tt: NDArray[np.float64], cc: NDArray[np.complex128]):
        """Least slack of the cells ``rows`` for K candidates: ``tt`` (K, nS) or (nS,), ``cc``
        (K, faces) or (faces,)."""
        tt = np.atleast_2d(tt)
        cc = np.atleast_2d(cc)
        r = R[rows]
        corners = np.stack(
            np.broadcast_arrays(
                P[r[:, 0]][None, :],
                A[r[:, 1]] + tt[:, r[:, 1]] * B[r[:, 1]],
                cc[:, r[:, 2]],
                A[r[:, 3]] + tt[:, r[:, 3]] * B[r[:, 3]],
            ),
            axis=-1,
        )
        ang = cell_angles(corners.reshape(-1, 4)).reshape(corners.shape)
        return _split_slack(ang, corner_is_tip[rows], need[rows]).min(axis=(1, 2))

    K = SPLIT_SAMPLES
    for _ in range(SPLIT_ROUNDS):
        for f in free_f.tolist():
            rows = rows_of[f]
            pts = P[R[rows, 0]]
            w = rng.dirichlet(np.ones(len(pts)), K)
            cand = np.concatenate([[C[f]], w @ pts])
            cc = np.repeat(C[None, :], K + 1, axis=0)
            cc[:, f] = cand
            C[f] = cand[int(np.argmax(least(rows, t, cc)))]
        for sd in free_s.tolist():
            rows = np.flatnonzero((R[:, 1] == sd) | (R[:, 3] == sd))
            tt = np.repeat(t[None, :], K + 1, axis=0)
            tt[1:, sd] = rng.uniform(0.05, 0.95, K)
            t[sd] = tt[int(np.argmax(least(rows, tt, C))), sd]
        if min(float(least(rows_of[int(f)], t, C)[0]) for f in free_f) >= 0:
            break
    return t, C


def _centre_opt(
    P: NDArray[np.complex128],
    R: NDArray[np.int64],
    cell_face_a: NDArray[np.int64],
    faces: list[NDArray[np.int64]],
    bad_faces: NDArray[np.int64],
    t: NDArray[np.float64],
    C: NDArray[np.complex128],
    slack: Callable[[NDArray[np.complex128]], NDArray[np.float64]],
    positions: Callable[[NDArray[np.float64], NDArray[np.complex128]], NDArray[np.complex128]],
) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """One max-min program of :func:`_split_cells`: the centres of ``bad_faces`` and of the
    faces touching their sides, and those side points, placed by SLSQP to maximise the least
    slack of their cells; returns the new side parameters ``t`` and centres ``C``."""
    free_f = set(bad_faces.tolist())
    free_s = sorted(
        {int(R[c, 1]) for c in np.nonzero(np.isin(cell_face_a, bad_faces))[0]}
        | {int(R[c, 3]) for c in np.nonzero(np.isin(cell_face_a, bad_faces))[0]}
    )
    # faces touching a free side move their centre too
    touch = np.isin(R[:, 1], free_s) | np.isin(R[:, 3], free_s)
    free_f |= set(cell_face_a[touch].tolist())
    ff = np.array(sorted(free_f))
    fs = np.array(free_s, dtype=np.int64)
    rows = np.nonzero(np.isin(cell_face_a, ff))[0]
    scale = np.array([max(abs(P[faces[f]] - C[f]).max(), 1e-300) for f in ff])
    sl = slack(positions(t, C))

    def unpack(x: NDArray[np.float64]) -> NDArray[np.complex128]:
        tt = t.copy()
        tt[fs] = x[: len(fs)]
        cc = C.copy()
        xy = x[len(fs) :].reshape(-1, 2)
        cc[ff] = C[ff] + scale * (xy[:, 0] + 1j * xy[:, 1])
        return positions(tt, cc)

    def cons(x: NDArray[np.float64]) -> NDArray[np.float64]:
        s = slack(unpack(x[:-1]))[rows].ravel()
        return s - x[-1]

    x0 = np.concatenate([t[fs], np.zeros(2 * len(ff)), [float(sl[rows].min())]])
    lb = np.concatenate([np.full(len(fs), 0.05), np.full(2 * len(ff), -0.9), [-90.0]])
    ub = np.concatenate([np.full(len(fs), 0.95), np.full(2 * len(ff), 0.9), [90.0]])
    res = minimize(
        lambda x: -x[-1],
        x0,
        method="SLSQP",
        constraints=[{"type": "ineq", "fun": cons}],
        bounds=list(zip(lb, ub)),
        options={"maxiter": 200, "ftol": 1e-9},
    )
    x = res.x if res.x is not None else x0
    tt = t.copy()
    tt[fs] = x[: len(fs)]
    t = tt
    xy = x[len(fs) : -1].reshape(-1, 2)
    C = C.copy()
    C[ff] = C[ff] + scale * (xy[:, 0] + 1j * xy[:, 1])
    return t, C


class _PointIndex:
    """Points of a growing list, found again by their position up to rounding (a hash on a
    grid of cells 1e-12 of the list's extent wide, the cell and its neighbours searched)."""

    def __init__(self, pts: list[complex]) -> None:
        P = np.asarray(pts)
        self.pts = pts
        self.tol = 1e-12 * max(float(np.max(np.abs(P - P[0]))), 1e-300)
        self.cells: dict[tuple[int, int], list[int]] = {}
        for i, w in enumerate(pts):
            self.cells.setdefault(self._key(w), []).append(i)

    def _key(self, w: complex) -> tuple[int, int]:
        return (math.floor(w.real / self.tol), math.floor(w.imag / self.tol))

    def add(self, w: complex) -> int:
        """Index of ``w``: an existing point within rounding, else ``w`` appended."""
        kx, ky = self._key(w)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for i in self.cells.get((kx + dx, ky + dy), ()):
                    if abs(self.pts[i] - w) <= self.tol:
                        return i
        self.pts.append(w)
        self.cells.setdefault((kx, ky), []).append(len(self.pts) - 1)
        return len(self.pts) - 1


def _inside_sides(
    a: NDArray[np.complex128],
    d: NDArray[np.complex128],
    L2: NDArray[np.float64],
    pts: NDArray[np.complex128],
    g: NDArray[np.int64],
    j: NDArray[np.int64],
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    """Of the pairs (side ``g``, point ``j``), those whose point lies strictly inside the side
    ``a[g] + t d[g]`` (0 < t < 1, within 1e-9 of its length): ``(g, t, j)`` of the hits."""
    w = pts[j] - a[g]
    t = (w * np.conj(d[g])).real / L2[g]
    L = np.sqrt(L2[g])
    hit = (t > 1e-9) & (t < 1 - 1e-9) & (np.abs((np.conj(d[g]) * w).imag) / L <= 1e-9 * L)
    return g[hit], t[hit], j[hit]


def _resolve_hanging(
    X: NDArray[np.complex128],
    cells: NDArray[np.int64],
    tip_mask: NDArray[np.bool_],
    max_rounds: int = 400,
    deadline: float | None = None,
) -> tuple[NDArray[np.complex128], NDArray[np.int64]] | None:
    """Make a layout with hanging points conforming: a cell with points lying inside one of
    its sides is split along straight lines to the opposite side, at the same parameters (the
    pieces of a bilinear patch cut along its isolines keep their corners in the range of the
    cell's corners and their supplements), which carries the split on to the next cell until it
    reaches the boundary.  None if a cell holding a tip would be split, the splits do not
    settle (a ring of cells whose parameters never close) or ``deadline`` (a
    ``time.perf_counter()`` value) passes."""
    pts = list(X)
    grid = _PointIndex(pts)
    cl = [tuple(int(v) for v in c) for c in cells]
    # only points that are new or were hanging in the last round can hang on a side: a split
    # adds sides inside its cell, where no point lies
    pending = np.arange(len(pts))
    found: dict[int, dict[int, list[tuple[float, int]]]] = {}
    for _ in range(max_rounds):
        if deadline is not None and time.perf_counter() > deadline:
            return None
        P = np.asarray(pts, dtype=np.complex128)
        C = np.asarray(cl, dtype=np.int64)
        a = P[C]  # (nc, 4)
        b = P[C[:, [1, 2, 3, 0]]]
        d = b - a
        L2 = np.abs(d) ** 2
        # parameter and distance of the pending points against every side (chunked numpy)
        found = {}
        flat_a, flat_d, flat_L2 = a.ravel(), d.ravel(), L2.ravel()
        Pp = P[pending]

        # candidate (side, point) pairs: all of them, or with many points those near a side
        pairs: list[tuple[NDArray[np.int64], NDArray[np.int64]]] = []
        if len(Pp) * len(flat_a) <= BRUTE_PAIRS:
            step = max(1, 2_000_000 // max(len(Pp), 1))
            for lo in range(0, len(flat_a), step):
                gg, jj = np.meshgrid(
                    np.arange(lo, min(lo + step, len(flat_a))), np.arange(len(Pp)), indexing="ij"
                )
                pairs.append((gg.ravel(), jj.ravel()))
        else:
            from scipy.spatial import cKDTree

            tree = cKDTree(np.column_stack([Pp.real, Pp.imag]))
            mid = flat_a + 0.5 * flat_d
            near = tree.query_ball_point(
                np.column_stack([mid.real, mid.imag]), 0.5 * np.sqrt(flat_L2) * (1 + 1e-9)
            )
            cnt = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))
            pairs.append(
                (
                    np.repeat(np.arange(len(near)), cnt),
                    np.fromiter((j for c in near for j in c), dtype=np.int64, count=cnt.sum()),
                )
            )
        for g, j in pairs:
            gh, th, jh = _inside_sides(flat_a, flat_d, flat_L2, Pp, g, j)
            for gg, tt, jj in zip(gh.tolist(), th.tolist(), pending[jh].tolist()):
                found.setdefault(gg // 4, {}).setdefault(gg % 4, []).append((tt, jj))
        if not found:
            return P, C
        n_before = len(pts)
        was_hanging = {j for sides in found.values() for lst in sides.values() for _, j in lst}
        added: list[tuple[int, int, int, int]] = []
        for ci in sorted(found):
            c = cl[ci]
            if any(v < len(tip_mask) and tip_mask[v] for v in c):
                return None
            k = min(found[ci])  # split across side k (and its opposite side)
            q = [c[(k + j) % 4] for j in range(4)]  # side k is q0 -> q1, opposite q3 -> q2
            params = {round(t, 12): t for t, _ in found[ci][k]}
            for t, _ in found[ci].get((k + 2) % 4, []):
                params.setdefault(round(1 - t, 12), 1 - t)  # side k+2 runs q2 -> q3
            ts = sorted(params.values())
            on_k = {round(t, 12): j for t, j in found[ci][k]}
            on_o = {round(1 - t, 12): j for t, j in found[ci].get((k + 2) % 4, [])}
            A, B = [q[0]], [q[3]]
            for t in ts:
                key = round(t, 12)
                ja = on_k.get(key)
                if ja is None:
                    ja = grid.add(pts[q[0]] + t * (pts[q[1]] - pts[q[0]]))
                jb = on_o.get(key)
                if jb is None:
                    jb = grid.add(pts[q[3]] + t * (pts[q[2]] - pts[q[3]]))
                A.append(ja)
                B.append(jb)
            A.append(q[1])
            B.append(q[2])
            for i in range(len(A) - 1):
                added.append((A[i], A[i + 1], B[i + 1], B[i]))
        split = set(found)
        cl = [c for ci, c in enumerate(cl) if ci not in split] + added
        pending = np.array(sorted(was_hanging | set(range(n_before, len(pts)))), dtype=np.int64)
    return None


# --------------------------------------------------------------------------- the layout


def block_layout(
    polygon: ArrayLike, size: float | None = None, partial: list[PartialLayout] | None = None
) -> BlockLayout:
    """A coarse layout of admissible cells for a counter-clockwise simple polygon.

    A polygon corner below 60° (a *tip*) is first cut off by a *tip kite* (:func:`_tip_kite`):
    a quad with the tip, two points on its edges at distance about ``size`` and a fourth point
    on its bisector, with new corners in [60°, 120°]; the rest of the polygon then gets a
    reflex corner of more than 240° there and is laid out by straight cuts like any other
    polygon, no cut ending on the kite.  The kite is the only cell that is never split, so the
    tip no longer forces one segment on every chord through a block reaching across the
    polygon.  If no layout with kites closes, the tips' blocks are kept whole instead.

    Only when neither closes are cuts allowed to meet at *junctions* (interior points where
    three or more cuts meet, :func:`_junctions`), with kites first, then with the tips' blocks
    kept whole; the layouts that close without junctions are found as before.  Last, the same
    four searches run again with faces whose split about a centre SLSQP does not find from
    their centroids given a sampled search (:func:`_sampled_split`: pentagons between the
    cuts of a glyph's serif brackets); the layouts found before stay as they were.  Last,
    corners of 181.5°–240° with no single straight cut of their own are cut twice
    (:func:`_twin_corners`).

    Args:
        polygon: (n,) complex vertices, counter-clockwise, no repeated or collinear points.
        size: the block size the layout will be refined to (default
            :func:`default_block_size`); it sets the size of the tip kites.
        partial: when given (a list), the round of the straight-cut searches without tip
            kites that left the fewest faces unsplit is kept in it
            (:class:`PartialLayout`), for :func:`mesh_partial_layout`.

    Returns:
        A :class:`BlockLayout` whose cells are convex, counter-clockwise, conforming, cover the
        polygon exactly and have every corner in [60.25°, 119.75°] except the polygon's own
        corners below 60° (tips) and corners built at exactly 60° or 120° (centres of triangle
        and hexagon faces, the two sides of a kite's axis, three-arm junctions).

    Raises:
        BlockLayoutError: no set of cuts was found (the message says at which corners).
    """
    z = np.asarray(polygon, dtype=np.complex128)
    theta = _angles_deg(z)
    tips = np.nonzero(theta < ANGLE_MIN - ANGLE_TOL)[0].astype(np.int64)
    h = default_block_size(z) if size is None else float(size)
    if len(tips):
        lay = _kite_layout(z, theta, tips, h)
        if lay is not None:
            return lay
    try:
        return _cut_layout(z, partial=partial)
    except BlockLayoutError as exc:
        if "would be needed" in exc.args[0]:
            raise
        error = exc
    # only where nothing else closes: cuts may meet at junctions (the layouts that closed
    # without them stay as they were)
    if len(tips):
        lay = _kite_layout(z, theta, tips, h, junctions=True)
        if lay is not None:
            return lay
    try:
        return _cut_layout(z, seconds=JUNCTION_LAYOUT_SECONDS, junctions=True, partial=partial)
    except BlockLayoutError as exc:
        error_j = exc
    # last: faces whose split about a centre SLSQP did not find from the centroids get a
    # sampled search (the serif brackets of glyphs); a pass of its own, so that the layouts
    # found before stay as they were (an earlier round's cuts may close now, with more cells),
    # and only after searches whose rounds ended on faces (not an integer program without a
    # solution: sampling would not change it)
    if len(tips):
        lay = _kite_layout(z, theta, tips, h, sample=True)
        if lay is not None:
            return lay
    if _rounds_ended_on_faces(error):
        try:
            return _cut_layout(z, sample=True, partial=partial)
        except BlockLayoutError:
            pass
    if len(tips):
        lay = _kite_layout(z, theta, tips, h, junctions=True, sample=True)
        if lay is not None:
            return lay
    if _rounds_ended_on_faces(error_j):
        try:
            return _cut_layout(
                z, seconds=JUNCTION_LAYOUT_SECONDS, junctions=True, sample=True, partial=partial
            )
        except BlockLayoutError:
            pass
    # last: corners of 181.5°–240° that no single straight cut serves cut twice (pixel stairs
    # of traced contours: at 225° a single cut has a window of 15°, two have 44° each)
    if _may_twin(theta):
        try:
            return _cut_layout(z, partial=partial, twins=True)
        except BlockLayoutError:
            pass
    raise error


def _rounds_ended_on_faces(exc: BlockLayoutError) -> bool:
    """Whether the cut search that raised ``exc`` went through rounds whose faces could not
    be split (or ran out of time doing so), rather than finding no set of cuts at all."""
    msg = exc.args[0] if exc.args else ""
    return "could not be split" in msg or "no layout within" in msg


@dataclass(frozen=True)
class _KiteCut:
    """The tip kites a polygon ``z`` was cut by (:func:`_kite_layout`), as the cut search sees
    them: ``cells`` (tip point, then the indices in ``z`` of its kite's other three corners,
    counter-clockwise), the ``rigid`` edges ``j -> j+1`` of ``z`` (kite sides, never split, no
    cut ends inside them) and the ``exact`` corners (a kite's inner point at 240°, cut along
    its bisector only, both parts exactly 120°)."""

    cells: tuple[tuple[complex, int, int, int], ...] = ()
    rigid: frozenset[int] = frozenset()
    exact: frozenset[int] = frozenset()


def _long(rays: list[_Ray], bare: list[_Ray]) -> list[_Ray]:
    """The cuts that run from their corner to the boundary (full rays and ``bare`` ones whose
    boundary end is unusable): the arms of junctions are taken from them."""
    return [r for r in rays if r.join < 0 and r.stop < 0] + bare


def _may_twin(theta: NDArray[np.float64]) -> bool:
    """Whether some corner lies in 181.5°–240°, where two cuts fit (:func:`_twin_corners`)."""
    lo = ANGLE_MIN + LAYOUT_MARGIN
    return bool(np.any((theta >= 3 * lo) & (theta <= 2 * ANGLE_MAX + ANGLE_TOL)))


def _twin_corners(
    theta: NDArray[np.float64], rays: list[_Ray], exact: frozenset[int]
) -> frozenset[int]:
    """The corners of 181.5°–240° (two cuts fit: three parts of at least 60.5°) that no single
    straight cut to the boundary among ``rays`` (the full candidates with one window each)
    serves: they take two cuts (:func:`_windows`).  Pixel-traced outlines have stair corners
    of 225°–239° whose single cut must meet the far side within a window of 15° down to 2°
    (none above 239.5°); scikit-image text_1, text_3 and page_1 close so (7,154–8,175, 6,271
    and 3,897–4,002 quads against 80,192–130,613 by the paper's construction)."""
    lo = ANGLE_MIN + LAYOUT_MARGIN
    served = {i for r in rays for i, _ in r.slots}
    return frozenset(
        i
        for i, t in enumerate(theta.tolist())
        if 3 * lo <= t <= 2 * ANGLE_MAX + ANGLE_TOL and i not in exact and i not in served
    )


def _cut_layout(
    z: NDArray[np.complex128],
    kites: _KiteCut = _KiteCut(),
    seconds: float = SEARCH_SECONDS,
    junctions: bool = False,
    separate: bool = False,
    tee_rays: int = MAX_RAYS_FOR_TEES,
    more_tees: bool = False,
    sample: bool = False,
    partial: list[PartialLayout] | None = None,
    relax: bool = False,
    twins: bool = False,
) -> BlockLayout:
    """The straight-cut layout of :func:`block_layout` for ``z`` (tips kept whole).  With
    ``kites`` the tip points are appended to the layout's points and the kites to its cells,
    no cut ends inside a kite side and no split crosses a kite (:class:`_KiteCut`).

    The search runs in stages: straight cuts, then also cuts ending on other cuts
    (T-junctions), each stage's rounds stopping after ``seconds``.  With ``junctions`` only
    the stage with junctions of three or more cuts runs (:func:`_junctions`; cuts and
    T-junctions are among its candidates), within ``seconds`` in all, and only where some
    corner has no straight cut of its own to the boundary or the polygon has a reflex corner
    and at most :data:`JUNCTION_ANY_SLOTS` cut slots: round outlines with many obtuse corners
    are not helped by junctions in practice, and the search would only delay the collar that
    closes them.  ``separate``: faces that share no side get their centre points placed by
    programs of their own (:func:`_split_cells`), which makes the rounds faster.  T-junction
    (and junction) candidates are made while the full and bare rays number at most
    ``tee_rays``; with ``more_tees`` the search runs only if they number more than
    :data:`MAX_RAYS_FOR_TEES` (else it would repeat the search with the default limit).
    ``sample``: faces whose split about a centre SLSQP does not find from their centroids get
    a sampled search over centres and side points (:func:`_sampled_split`) before they count
    as failed.  ``partial``: a list into which the round that left the fewest faces unsplit
    is kept (:class:`PartialLayout`, one item at most).  ``relax``: a corner may keep a cut
    slot without a cut (at :data:`UNSERVED_COST`; its face then cannot split and is kept as
    a partial layout's face to fall back), no T-junction candidates.  ``twins``: corners of
    181.5°–240° that no single straight cut to the boundary serves are cut twice
    (:func:`_twin_corners`; the search is not run when there are none)."""
    deadline = time.perf_counter() + seconds
    n = len(z)
    theta = _angles_deg(z)
    diam = _scale(z)
    tips = np.nonzero(theta < ANGLE_MIN - ANGLE_TOL)[0].astype(np.int64)
    exact = kites.exact

    def slots_of(twin: frozenset[int]) -> list[tuple[int, int]]:
        slots = [
            (i, k)
            for i in range(n)
            for k in range(len(_windows(float(theta[i]), i in exact, i in twin)))
        ]
        if len(slots) > MAX_SLOTS:
            raise BlockLayoutError(
                f"{len(slots)} cuts would be needed ({len({i for i, _ in slots})} corners above "
                f"120°); block layouts are searched for at most {MAX_SLOTS}. Fewer vertices on "
                "the round parts of the outline would help"
            )
        return slots

    slots = slots_of(frozenset())
    bare: list[_Ray] = []
    rays = _candidates(z, theta, diam, bare, kites.rigid, exact) if slots else []
    # corners that no single straight cut serves take two where two fit
    twin = _twin_corners(theta, rays, exact) if twins else frozenset()
    if twins and not twin:
        raise BlockLayoutError("every corner of at most 240° has a single cut of its own")
    if twin:
        slots = slots_of(twin)
        bare = []
        rays = _candidates(z, theta, diam, bare, kites.rigid, exact, twin)
    checkpoint()
    covered = {s for r in rays for s in r.slots}
    missing = [s for s in slots if s not in covered]
    if relax and len(rays) > RELAXED_MAX_RAYS:
        raise BlockLayoutError(f"{len(rays)} candidate cuts are too many for a relaxed search")
    if more_tees and len(rays) + len(bare) <= MAX_RAYS_FOR_TEES:
        raise BlockLayoutError("the T-junction candidates were made already")
    small = len(rays) + len(bare) <= tee_rays
    # junctions serve the cut slots no straight cut serves; where every slot has one, they are
    # still tried on a polygon with few cuts and a reflex corner (an arrow with swept-back
    # barbs), never on round outlines with many obtuse corners, which the collar closes
    few = len(slots) <= JUNCTION_ANY_SLOTS and bool(np.any(theta > 180.0))
    if junctions and not small:
        raise BlockLayoutError(
            f"{len(rays) + len(bare)} candidate cuts are too many to search for junctions "
            f"(at most {tee_rays})"
        )
    if junctions and not (missing or few):
        raise BlockLayoutError("every corner has a straight cut of its own: no junction searched")
    if junctions and not missing:
        missing = list(slots)
    tee_rays: list[_Ray] | None = None
    stars: list[_Ray] = []
    first = 0
    if missing and small and not relax:
        # corners whose every cut meets the boundary badly may still end a cut on another one
        tee_rays = _t_variants(z, rays, diam, bare=bare)
        covered |= {s for r in tee_rays for s in r.slots}
        first = 1
        if junctions:  # ... or at a junction with other cuts
            stars = _junctions(
                z,
                theta,
                diam,
                _long(rays, bare),
                kites.rigid,
                exact,
                deadline,
                frozenset(missing),
                twin,
            )
            covered |= {s for r in stars for s in r.slots}
            if not stars:  # the search would be the one that already failed
                raise BlockLayoutError("no junction of three or more cuts fits in the polygon")
        missing = [s for s in slots if s not in covered]
    if missing and not relax:
        vs = sorted({i for i, _ in missing})
        raise BlockLayoutError(
            "no straight cut from the corner"
            + ("s" if len(vs) > 1 else "")
            + " at "
            + ", ".join(f"({z[i].real:.6g}, {z[i].imag:.6g}) ({theta[i]:.1f}°)" for i in vs[:6])
            + " meets the boundary at an angle in [60°, 120°]"
        )
    tip_mask = np.zeros(n, dtype=bool)
    tip_mask[tips] = True
    has_slot = np.zeros(n, dtype=bool)
    has_slot[[i for i, _ in slots]] = True
    problems: list[str] = []
    stages = [2] if junctions else [0] if relax else range(first, (1 if small else 0) + 1)
    for stage in stages:
        if stage >= 1 and tee_rays is None:
            tee_rays = _t_variants(z, rays, diam, bare=bare)
        left = deadline - time.perf_counter()
        if stage == 2 and left < MIN_JUNCTION_SECONDS:
            problems.append("no time left for junctions")
            break
        pool = rays + (tee_rays if stage >= 1 else []) + stars
        checkpoint()
        # with junctions the integer program is large: a layout close to the cheapest will do
        lay = _search(
            z,
            pool,
            slots,
            tips,
            tip_mask,
            has_slot,
            diam,
            problems,
            kites,
            min(JUNCTION_SECONDS, left) if stage == 2 else seconds,
            JUNCTION_GAP if stage == 2 else None,
            separate,
            sample,
            partial,
            relax,
        )
        if lay is not None:
            return lay
    raise BlockLayoutError(
        "no set of straight cuts splits the polygon into blocks with every corner in "
        f"[60°, 120°] ({len(rays)} candidate cuts at {len({r.start for r in rays})} obtuse or "
        f"reflex corners{'; ' + problems[-1] if problems else ''})"
    )


#: corner of a tip kite at its inner point, degrees (tried in this order, where admissible);
#: at 120° the rest of the polygon is cut once along the kite's axis, both parts exactly 120°
KITE_INNER = (120.0, 112.0, 96.0, 80.0)
#: a tip kite reaches at most this fraction of each edge at the tip
KITE_EDGE_SHARE = 0.4
#: time for the layout searches with tip kites before the tips are kept whole instead
KITE_SECONDS = 1.5


def _tip_kite(
    z: NDArray[np.complex128], i: int, theta: float, t: float, c: float
) -> tuple[complex, complex, complex]:
    """The kite cutting off the tip ``z[i]`` (angle ``theta`` < 60°): points ``A`` on the edge to
    the next vertex and ``B`` on the edge from the previous one, both at distance ``t`` from the
    tip, and ``C`` on the bisector where the kite's corner is ``c``.  The corners at A and B are
    ``a = 180° - theta/2 - c/2`` each (so ``theta + 2a + c = 360°``); the rest of the polygon
    gets ``180° - a`` at A and B and ``360° - c`` at C.  Returns ``(A, C, B)``."""
    p = z[i]
    e1 = z[(i + 1) % len(z)] - p
    e2 = z[i - 1] - p
    u1, u2 = e1 / abs(e1), e2 / abs(e2)
    a = 180.0 - 0.5 * theta - 0.5 * c
    bis = (u1 + u2) / abs(u1 + u2)
    rho = t * math.sin(math.radians(a)) / math.sin(math.radians(0.5 * c))
    return p + t * u1, p + rho * bis, p + t * u2


def _kite_layout(
    z: NDArray[np.complex128],
    theta: NDArray[np.float64],
    tips: NDArray[np.int64],
    h: float,
    junctions: bool = False,
    sample: bool = False,
) -> BlockLayout | None:
    """The layout of :func:`block_layout` with every tip cut off by a kite (:func:`_tip_kite`):
    the first that closes over the inner angles of :data:`KITE_INNER` and the kite sizes ``h``
    and ``h/2`` (each at most :data:`KITE_EDGE_SHARE` of the edges at the tip), within
    :data:`KITE_SECONDS`; None if none does.  ``points[:n]`` of the layout are ``z``.
    ``junctions``: search with junctions only, ``sample`` with sampled face splits
    (:func:`_cut_layout`)."""
    from shapely.geometry import Polygon as ShapelyPolygon

    n = len(z)
    e_len = np.abs(np.roll(z, -1) - z)
    is_tip = np.zeros(n, dtype=bool)
    is_tip[tips] = True
    outline = ShapelyPolygon(np.column_stack([z.real, z.imag]))
    diam = _scale(z)
    lo_c = np.maximum(ANGLE_MIN + LAYOUT_MARGIN, 2 * (180.0 - ANGLE_MAX + LAYOUT_MARGIN) - theta)
    t_max = KITE_EDGE_SHARE * np.minimum(e_len, np.roll(e_len, 1))
    if np.any(t_max[tips] < 3 * POINT_GAP * diam):
        return None  # a tip between edges too short for a kite the cuts can keep clear of
    deadline = time.perf_counter() + KITE_SECONDS
    for scale in (1.0, 0.5):
        for c_pref in KITE_INNER:
            left = deadline - time.perf_counter()
            if left <= 0:
                return None
            ring: list[complex] = []
            owner: list[int] = []  # original vertex index, or -1 for a kite point
            kites: list[tuple[complex, int, int, int]] = []  # (tip, A, C, B), C's in ring
            rigid: set[int] = set()
            exact: set[int] = set()
            for i in range(n):
                if not is_tip[i]:
                    ring.append(z[i])
                    owner.append(i)
                    continue
                if c_pref == ANGLE_MAX:
                    c = ANGLE_MAX  # one cut along the axis, both parts exactly 120°
                    exact.add(len(ring) + 1)
                else:
                    c = min(max(c_pref, float(lo_c[i])), ANGLE_MAX - LAYOUT_MARGIN)
                t = min(scale * h, float(t_max[i]))
                A, C, B = _tip_kite(z, i, float(theta[i]), t, c)
                k = len(ring)
                ring += [B, C, A]
                owner += [-1, -1, -1]
                rigid |= {k, k + 1}  # edges B -> C and C -> A
                kites.append((complex(z[i]), k + 2, k + 1, k))
            zr = np.asarray(ring, dtype=np.complex128)
            # the kites lie inside the polygon: the cut polygon stays simple and its area is
            # the polygon's less the kites'
            cut = ShapelyPolygon(np.column_stack([zr.real, zr.imag]))
            kite_area = sum(
                ShapelyPolygon([(w.real, w.imag) for w in (p, zr[a], zr[c], zr[b])]).area
                for p, a, c, b in kites
            )
            if not cut.is_valid or abs(cut.area + kite_area - outline.area) > 1e-9 * outline.area:
                continue
            try:
                lay = _cut_layout(
                    zr,
                    _KiteCut(tuple(kites), frozenset(rigid), frozenset(exact)),
                    min(left, SEARCH_SECONDS),
                    junctions,
                    sample=sample,
                )
            except BlockLayoutError as exc:
                if "would be needed" in exc.args[0]:
                    return None  # too many corners for the search, whatever the kites
                continue
            return _renumber(lay, z, np.asarray(owner, dtype=np.int64), tips)
    return None


def _renumber(
    lay: BlockLayout, z: NDArray[np.complex128], owner: NDArray[np.int64], tips: NDArray[np.int64]
) -> BlockLayout:
    """A kite layout (points: the cut polygon's vertices, whose original index is ``owner`` or
    -1 for a kite point, then the other layout points, among them the tip points) renumbered
    so that ``points[:n]`` are ``z``."""
    n, m = len(z), len(owner)
    P = len(lay.points)
    new = np.full(P, -1, dtype=np.int64)
    kept = owner >= 0
    new[:m][kept] = owner[kept]
    for i in tips.tolist():  # the tip points were appended as exact copies of the vertices
        k = m + int(np.flatnonzero(lay.points[m:] == z[i])[0])
        new[k] = i
    rest = np.flatnonzero(new < 0)
    new[rest] = n + np.arange(len(rest))
    pts = np.empty(n + len(rest), dtype=np.complex128)
    pts[new] = lay.points
    pts[:n] = z  # exactly the polygon's vertices
    cells = new[lay.cells]
    return BlockLayout(
        polygon=z,
        points=pts,
        cuts=lay.cuts,
        faces=tuple(new[f] for f in lay.faces),
        cells=cells,
        tips=tips,
        split=lay.split,
        rounds=lay.rounds,
        tees=lay.tees,
        angles=cell_angles(pts[cells]),
        kind=lay.kind,
        kites=True,
        junctions=lay.junctions,
    )


def _search(
    z: NDArray[np.complex128],
    rays: list[_Ray],
    slots: list[tuple[int, int]],
    tips: NDArray[np.int64],
    tip_mask: NDArray[np.bool_],
    has_slot: NDArray[np.bool_],
    diam: float,
    problems: list[str],
    kites: _KiteCut = _KiteCut(),
    seconds: float = SEARCH_SECONDS,
    rel_gap: float | None = None,
    separate: bool = False,
    sample: bool = False,
    partial: list[PartialLayout] | None = None,
    relax: bool = False,
) -> BlockLayout | None:
    """Rounds of the cut search over the candidate ``rays`` (see :func:`block_layout`;
    ``kites``, ``seconds``, ``separate``, ``sample``, ``partial`` and ``relax`` as in
    :func:`_cut_layout`, ``rel_gap`` as in :func:`_solve`)."""
    n = len(z)
    bad = _conflicts(z, rays, diam) if rays else []
    if any(r.arms for r in rays):
        # a junction and a cut for the same slot exclude each other already (one per slot):
        # their conflicts would only make the integer program larger
        sl = [frozenset(r.slots) for r in rays]
        bad = [(a, b) for a, b in bad if not ((rays[a].arms or rays[b].arms) and sl[a] & sl[b])]
    checkpoint()
    if len(bad) > MAX_CONFLICTS:
        problems.append(f"{len(bad):,} pairs of candidate cuts conflict")
        return None
    deadline = time.perf_counter() + seconds
    nogoods: list[list[int]] = []
    cliques = _conflict_cliques(rays, bad)
    for rnd in range(1, MAX_ROUNDS + 1):
        left = deadline - time.perf_counter()
        if left <= 0:
            problems.append(f"no layout within {seconds:.3g} s of search")
            return None
        chosen = (
            _solve(
                rays, slots, bad, nogoods, left, rel_gap, UNSERVED_COST if relax else None, cliques
            )
            if slots
            else []
        )
        checkpoint()
        if chosen is None:
            return None
        sel = [rays[c] for c in chosen]
        P, faces_raw, face_rays, hubs = _arrangement(z, sel)
        pm = np.zeros(len(P), dtype=bool)
        pm[tips] = True
        own = np.zeros(len(P), dtype=bool)
        own[:n] = ~has_slot & ~tip_mask
        own[list(kites.exact)] = True  # a kite's inner point: its two parts are exactly 120°
        own[hubs] = True  # a junction of three arms: its angles are exactly 120°
        faces = []
        wrong = []
        for fi, f in enumerate(faces_raw):
            a = _angles_deg(P[f])
            tee = np.abs(a - 180.0) < 1e-6  # the far side of a T: not a corner
            f, a = f[~tee], a[~tee]
            faces.append(f)
            m = np.where(own[f], -ANGLE_TOL, 0.5 * LAYOUT_MARGIN)
            ok = np.where(pm[f], a > 0, (a >= ANGLE_MIN + m) & (a <= ANGLE_MAX - m))
            if not np.all(ok) or len(f) > 6 or len(f) < 3:
                wrong.append(fi)
        whole: list[int] = []
        if not wrong and kites.rigid:
            # the chords through the kites stay whole: a split would put a point on a kite side
            whole, wrong = _chord_faces(faces, kites.rigid, n)
        if not wrong:
            if all(len(f) == 4 for f in faces):
                cells = np.array(faces, dtype=np.int64)
                X, split = P, False
            else:
                rest = [k for k in range(len(faces)) if k not in whole]
                X, cells, wrong = _split_cells(
                    P, [faces[k] for k in rest], pm, own, separate=separate, sample=sample
                )
                if wrong:  # a triangle or hexagon face: centre angles of exactly 120° or 60°
                    X, cells, wrong = _split_cells(
                        P,
                        [faces[k] for k in rest],
                        pm,
                        own,
                        margin=-ANGLE_TOL,
                        separate=separate,
                        sample=sample,
                    )
                wrong = [rest[k] for k in wrong]
                if whole:
                    cells = np.concatenate([cells, np.array([faces[k] for k in whole])])
                split = True
            if not wrong and kites.cells:
                # the tip points after the layout's points, the kites among its cells
                first = len(X)
                X = np.concatenate([X, np.array([k[0] for k in kites.cells], dtype=np.complex128)])
                kc = [(first + q, a, c, b) for q, (_, a, c, b) in enumerate(kites.cells)]
                cells = np.concatenate([cells, np.array(kc, dtype=np.int64)])
                pm = np.concatenate([pm, np.zeros(len(X) - len(pm), dtype=bool)])
                pm[first:] = True
            if not wrong:
                fixed = _resolve_hanging(X, cells, pm)
                if fixed is None:
                    problems.append("the splits that remove T-junctions did not settle")
                    tees = [c for c in chosen if rays[c].stop >= 0]
                    if not tees:
                        return None
                    nogoods.append(sorted(tees))
                    continue
                X, cells = fixed
                return BlockLayout(
                    polygon=z,
                    points=X,
                    cuts=np.array(
                        [[_p0(z, r), r.end] for r in _segments(sel)[0]], dtype=np.complex128
                    ).reshape(-1, 2),
                    faces=tuple(faces),
                    cells=cells,
                    tips=tips,
                    split=split,
                    rounds=rnd,
                    tees=sum(r.stop >= 0 for r in sel),
                    junctions=sum(bool(r.arms) for r in sel),
                    angles=cell_angles(X[cells]),
                )
        problems.append(f"{len(wrong)} face(s) could not be split into cells")
        if partial is not None and not kites.cells:
            cuts = [[_p0(z, r), r.end] for r in _segments(sel)[0]]
            _keep_partial(partial, z, P, faces, wrong, pm, own, cuts)
        for fi in wrong:
            ng = sorted(chosen[k] for k in face_rays[fi])
            if not ng:
                raise BlockLayoutError(
                    "a part of the polygon bounded only by its own edges cannot be split into "
                    "quads with corners in [60°, 120°]"
                )
            nogoods.append(ng)
    return None


def _chord_faces(
    faces: list[NDArray[np.int64]], rigid: frozenset[int], n: int
) -> tuple[list[int], list[int]]:
    """The faces on the chords through the kites: from each face on a kite side (a ``rigid``
    polygon edge ``j -> j+1``) across the side opposite to the one it was entered by, until
    the boundary.  Returns ``(whole, wrong)``: the quad faces met, which must stay whole (a
    split would put a point on a chord side, and the splits that remove it would reach the
    kite), and the other faces met, which cannot."""
    by_side: dict[tuple[int, int], list[tuple[int, int]]] = {}
    todo: list[tuple[int, int]] = []
    for k, f in enumerate(faces):
        fl = f.tolist()
        for p, (u, v) in enumerate(zip(fl, fl[1:] + fl[:1])):
            by_side.setdefault((min(u, v), max(u, v)), []).append((k, p))
            if u < n and v < n and (v - u) % n == 1 and u in rigid:
                todo.append((k, p))
    whole: set[int] = set()
    wrong: set[int] = set()
    seen: set[tuple[int, int]] = set()
    while todo:
        k, p = todo.pop()
        f = faces[k]
        if len(f) != 4:
            wrong.add(k)
            continue
        if (k, p % 2) in seen:
            continue
        seen.add((k, p % 2))
        whole.add(k)
        u, v = int(f[(p + 2) % 4]), int(f[(p + 3) % 4])
        todo.extend(q for q in by_side.get((min(u, v), max(u, v)), []) if q[0] != k)
    return sorted(whole), sorted(wrong)


# --------------------------------------------------------------------------- faces that fall back


@dataclass(frozen=True)
class PartialLayout:
    """A round of the straight-cut search whose cuts closed but whose faces did not all split
    into cells (:func:`_search`): the faces in ``wrong`` may be meshed by the paper's
    construction and glued to the cells of the others (:func:`mesh_partial_layout`).

    Attributes:
        polygon: (n,) complex polygon vertices.
        points: (P,) complex points of the arrangement of the cuts (``points[:n]`` the polygon's).
        faces: the faces, each an int array of point indices (CCW, the far sides of
            T-junctions left out).
        wrong: indices of the faces that did not split (or had a corner out of range).
        tip_mask: (P,) points whose corner only has to be above 0° (the polygon's tips).
        own: (P,) uncut polygon corners, the far side of T-junctions and the hubs of
            junctions (their angles are in range by construction).
        cuts: (K, 2) complex end points of the round's cuts.
    """

    polygon: NDArray[np.complex128]
    points: NDArray[np.complex128]
    faces: tuple[NDArray[np.int64], ...]
    wrong: frozenset[int]
    tip_mask: NDArray[np.bool_]
    own: NDArray[np.bool_]
    cuts: NDArray[np.complex128] = field(default_factory=lambda: np.zeros((0, 2), complex))

    @property
    def score(self) -> tuple[int, int]:
        """Fewer faces to fall back first (each adds the points of its mesh on its sides to the
        layout), then fewer corners on them."""
        return len(self.wrong), sum(len(self.faces[k]) for k in self.wrong)


def _keep_partial(
    partial: list[PartialLayout],
    z: NDArray[np.complex128],
    P: NDArray[np.complex128],
    faces: list[NDArray[np.int64]],
    wrong: list[int],
    pm: NDArray[np.bool_],
    own: NDArray[np.bool_],
    cuts: list[list[complex]],
) -> None:
    """Keep this round in ``partial`` (at most :data:`PARTIAL_KEEP` rounds, fewest faces left
    unsplit first) if its faces could fall back.  A face can fall back when none of its new
    corners lies below 60° (the paper's construction keeps a corner up to 120° whole and
    splits larger ones into parts in range, but cannot raise one below 60°; a face laid out on
    its own cannot either)."""
    n = len(z)
    if not wrong or len(wrong) == len(faces):
        return
    cut_arr = np.array(cuts, dtype=np.complex128).reshape(-1, 2)
    cand = PartialLayout(z, P, tuple(faces), frozenset(wrong), pm.copy(), own.copy(), cut_arr)
    if len(partial) >= PARTIAL_KEEP and partial[-1].score <= cand.score:
        return
    # a point's corner is new unless it is an uncut polygon corner (or a tip, or in ``own``);
    # the polygon's corners above 120° were cut (or left uncut by the relaxed search)
    uncut = np.zeros(len(P), dtype=bool)
    uncut[:n] = _angles_deg(z) <= ANGLE_MAX + ANGLE_TOL
    for k in wrong:
        f = faces[k]
        new = ~(own[f] | pm[f] | uncut[f])
        if np.any(new & (_angles_deg(P[f]) < ANGLE_MIN - ANGLE_TOL)):
            return
    partial.append(cand)
    partial.sort(key=lambda p: p.score)
    del partial[PARTIAL_KEEP:]


def _points_on_sides(
    X: NDArray[np.complex128], face: NDArray[np.int64], cand: NDArray[np.int64]
) -> list[int]:
    """The face's corners with the points ``cand`` of ``X`` that lie strictly inside its sides
    (within 1e-9 of the side's length), in order around the face."""
    a = X[face]
    d = X[np.roll(face, -1)] - a
    L2 = np.abs(d) ** 2
    g, j = np.meshgrid(np.arange(len(face)), np.arange(len(cand)), indexing="ij")
    gh, th, jh = _inside_sides(a, d, L2, X[cand], g.ravel(), j.ravel())
    out: list[int] = []
    for k in range(len(face)):
        out.append(int(face[k]))
        sel = gh == k
        order = np.argsort(th[sel])
        out.extend(int(c) for c in cand[jh[sel][order]] if c not in out)
    return out


#: a face mesh for :func:`mesh_partial_layout`: polygon in, ``(points, quads, source)`` or None
#: out (``source``: per quad, the stage code of :data:`quadmesh.io.STAGE_KINDS` that made it)
FaceMesher = Callable[
    [NDArray[np.complex128]],
    tuple[NDArray[np.complex128], NDArray[np.int64], NDArray[np.int8]] | None,
]


def _simple_loops(face: NDArray[np.int64]) -> list[NDArray[np.int64]]:
    """The boundary of ``face`` cut into loops at the points it passes twice (a face of the
    cuts' arrangement that touches itself, or two faces traced as one through a shared side):
    each time the walk comes back to a point on it, the loop since that point is split off.
    Loops of fewer than 3 points are dropped."""
    out: list[list[int]] = []
    stack: list[int] = []
    for v in face.tolist():
        if v in stack:
            i = stack.index(v)
            out.append(stack[i:])
            del stack[i + 1 :]
        else:
            stack.append(v)
    out.append(stack)
    return [np.asarray(lp, dtype=np.int64) for lp in out if len(lp) >= 3]


def _is_simple(w: NDArray[np.complex128]) -> bool:
    """Whether the closed polygon ``w`` has distinct points (at 1e-12 of its size) and no two
    sides that meet other than at a shared corner."""
    import shapely

    scale = float(np.max(np.abs(w - w[0])))
    if len(w) < 3 or scale <= 0:
        return False
    key = np.round(w / scale, 12)
    if len(np.unique(key)) < len(w):
        return False
    return bool(shapely.LinearRing(np.column_stack([w.real, w.imag])).is_simple)


def _face_layout(
    w: NDArray[np.complex128], size: float, depth: int, deadline: float = math.inf
) -> tuple[NDArray[np.complex128], NDArray[np.int64], NDArray[np.complex128]] | None:
    """A layout of the face ``w`` (a simple counter-clockwise polygon: a face's corners and
    every layout point on its sides) on its own: straight cuts inside it
    (:func:`block_layout`), else a collar around a lattice core at the spacings of
    :data:`FACE_RING_SIZES`, else (``depth`` > 0) the face's own partial layout with its faces
    that do not split laid out in turn (:func:`_lay_out`), else a finer collar
    (:data:`FACE_FINE_RING_SIZES`); the face's own partial layout is not tried once
    ``deadline`` has passed.  Returns ``(points, cells, cuts)``
    with ``points[:len(w)] == w`` and every new cell corner in [60°, 120°], or None.

    Measured on the glyphs of two fonts: the faces that a glyph's cuts leave unsplit are small
    (a bracket fillet's strip, a stroke's end, a crotch); the cut search on one of them alone
    has far fewer cut slots to serve at once, and the points on its sides are candidate ends
    for joins, so it closes where the glyph's did not."""
    if not _is_simple(w):
        return None
    partial: list[PartialLayout] = []
    try:
        lay = block_layout(w, size, partial)
        return lay.points, lay.cells, lay.cuts
    except BlockLayoutError:
        pass
    from .rings import RingLayoutError, ring_layout

    def collar(sizes: tuple[float, ...]) -> BlockLayout | None:
        for f in sizes:
            try:
                return ring_layout(w, f * size, seconds=FACE_RING_SECONDS)
            except RingLayoutError:
                pass
        return None

    lay = collar(FACE_RING_SIZES)
    if lay is not None:
        return lay.points, lay.cells, lay.cuts
    if depth > 0 and time.perf_counter() < deadline:
        _relaxed_partial(w, partial)
        for part in partial:
            got = _lay_out(part, size, depth - 1, rest_ok=False, deadline=deadline)
            if got is not None:
                return got.points, got.cells, got.cuts
    lay = collar(FACE_FINE_RING_SIZES)
    if lay is not None:
        return lay.points, lay.cells, lay.cuts
    return None


@dataclass(frozen=True)
class _LaidOut:
    """Cells of a partial layout (:func:`_lay_out`): the faces that split, and the faces laid
    out on their own; ``rest`` the faces (point ids, simple loops) left for another mesher."""

    points: NDArray[np.complex128]
    cells: NDArray[np.int64]
    cuts: NDArray[np.complex128]
    local: tuple[NDArray[np.complex128], ...]
    rest: tuple[NDArray[np.int64], ...]


def _lay_out(
    part: PartialLayout,
    size: float,
    depth: int,
    rest_ok: bool,
    deadline: float = math.inf,
) -> _LaidOut | None:
    """The cells of a partial layout: its faces that split (:func:`_split_cells`), and each
    face that did not cut into simple loops (:func:`_simple_loops`), every loop with the
    layout points on its sides laid out on its own (:func:`_face_layout`) and its cells added;
    the points that then lie inside other cells' sides are carried on along grid lines
    (:func:`_resolve_hanging`).  With ``rest_ok`` a loop that finds no layout is returned in
    ``rest`` (for the paper's construction); otherwise None, as when the cells do not settle or
    do not tile the polygon exactly, or ``deadline`` (a ``time.perf_counter()`` value) passes
    before a face is laid out."""
    z = part.polygon
    P = part.points
    good = [k for k in range(len(part.faces)) if k not in part.wrong]
    gf = [part.faces[k] for k in good]
    if not gf:
        X, cells, bad = P, np.zeros((0, 4), dtype=np.int64), []
    elif all(len(f) == 4 for f in gf):
        X, cells, bad = P, np.array(gf, dtype=np.int64).reshape(-1, 4), []
    else:
        X, cells, bad = _split_cells(P, gf, part.tip_mask, part.own, separate=True)
        if bad:
            # each face of k corners gave k consecutive cells
            owner = np.repeat(np.arange(len(gf)), [len(f) for f in gf])
            cells = cells[~np.isin(owner, bad)]
    wrong = sorted(part.wrong | {good[b] for b in bad})
    X = np.asarray(X, dtype=np.complex128)
    used = np.unique(np.concatenate([cells.ravel(), np.arange(len(P))]))
    total = abs(signed_area(z))
    loops: list[NDArray[np.int64]] = []
    for k in wrong:
        face = np.asarray(part.faces[k], dtype=np.int64)
        ls = _simple_loops(face)
        areas = [signed_area(X[lp]) for lp in ls]
        if min(areas) <= 0 or abs(sum(areas) - signed_area(X[face])) > 1e-9 * total:
            if not rest_ok:
                return None
            ls = [face]
        loops.extend(ls)
    all_cells = [cells]
    cuts = [np.asarray(part.cuts, dtype=np.complex128).reshape(-1, 2)]
    local: list[NDArray[np.complex128]] = []
    rest: list[NDArray[np.int64]] = []
    # new points found again by position: two loops of one face, or two faces side by side,
    # may each put a point at the same place on the side they share
    pts_list = X.tolist()
    grid = _PointIndex(pts_list)
    for lp in loops:
        ids = np.asarray(_points_on_sides(X, lp, used), dtype=np.int64)
        checkpoint()
        if time.perf_counter() > deadline:
            return None
        w = np.asarray(pts_list)[ids]
        got = _face_layout(w, size, depth, deadline)
        if got is None:
            if not rest_ok:
                return None
            rest.append(lp)
            continue
        pts, cc, cc_cuts = got
        new_ids = [grid.add(complex(p)) for p in pts[len(ids) :]]
        gmap = np.concatenate([ids, np.asarray(new_ids, dtype=np.int64)])
        local.append(w)
        all_cells.append(gmap[cc])
        cuts.append(np.asarray(cc_cuts, dtype=np.complex128).reshape(-1, 2))
    X = np.asarray(pts_list, dtype=np.complex128)
    cells = np.concatenate(all_cells)
    if len(cells) == 0:
        return None
    pm = np.zeros(len(X), dtype=bool)
    pm[: len(part.tip_mask)] = part.tip_mask
    fixed = _resolve_hanging(
        X, cells, pm, max_rounds=4000, deadline=time.perf_counter() + FACE_RESOLVE_SECONDS
    )
    if fixed is None:
        return None
    X, cells = fixed
    cell_area = quad_signed_areas(X, cells)
    covered = float(cell_area.sum()) + sum(signed_area(X[lp]) for lp in rest)
    if np.any(cell_area <= 0) or abs(covered - total) > 1e-9 * total:
        return None
    return _LaidOut(X, cells, np.concatenate(cuts), tuple(local), tuple(rest))


def _relaxed_partial(
    z: NDArray[np.complex128], partial: list[PartialLayout], twins: bool = False
) -> None:
    """Rounds of a relaxed straight-cut search, in which corners may stay without a cut (their
    faces then do not split), added to ``partial`` when it is empty.  It searches plain cuts
    only, so it runs even where the first search gave up on too many conflicting pairs of
    candidates with T-junction variants among them (STIX "b": 185,457 pairs); where the plain
    cuts conflict too much as well, it gives up by itself.  ``twins``: the corners of
    181.5°–240° that no single straight cut serves are cut twice (:func:`_twin_corners`); no
    rounds where there are none."""
    if not partial and (not twins or _may_twin(_angles_deg(z))):
        try:
            _cut_layout(
                z, seconds=RELAXED_SECONDS, separate=True, partial=partial, relax=True, twins=twins
            )
        except BlockLayoutError:
            pass


def _partial_result(
    part: PartialLayout,
    laid: _LaidOut,
    X: NDArray[np.complex128],
    cells: NDArray[np.int64],
    tips: NDArray[np.int64],
    **fallback: Any,
) -> BlockLayout:
    """The :class:`BlockLayout` of a partial layout meshed by :func:`mesh_partial_layout`:
    its cells (and those of the faces laid out on their own), with ``fallback`` the fields
    that describe the faces meshed by the paper's construction."""
    return BlockLayout(
        polygon=part.polygon,
        points=X,
        cuts=laid.cuts,
        faces=part.faces,
        cells=cells,
        tips=tips,
        split=True,
        angles=cell_angles(X[cells]),
        local_faces=laid.local,
        **fallback,
    )


def mesh_partial_layout(
    part: PartialLayout,
    size: float,
    mesh_face: FaceMesher | None = None,
    laid: _LaidOut | None = None,
) -> tuple[NDArray[np.complex128], NDArray[np.int64], BlockLayout, LayoutRefinement] | None:
    """A block mesh of a partial layout: the faces that did not split laid out on their own,
    or falling back to another mesher.

    The faces that split become cells (:func:`_split_cells`, T-junctions carried to the
    boundary by :func:`_resolve_hanging`); every face of ``part.wrong`` (and any face whose
    split fails now) is first laid out on its own (:func:`_lay_out`, :func:`_face_layout`:
    straight cuts inside the face, a collar, or the face's own partial layout), its cells
    joining the others; only the faces left then are meshed by ``mesh_face`` (the paper's
    construction; without it they make the layout fail), each as the polygon of its corners
    and every layout point on its sides.  The cell next to such a face side
    goes down from the face mesh's points on it to the count the size asks for by a
    transition cascade where it has room (:func:`_transition_cells`, the cells after it along
    the chord going on where it has not); elsewhere the face mesh's points become the side's
    fixed parameters in :func:`quadmesh.cells.refine_layout`, so the chord through the cell
    carries exactly those points across the layout (a grid line per point: every grid angle
    stays in the range of its cell's corners).  The meshes meet by index.

    A chord between two sides with fixed points (a strip of cells from one face to another, or
    back to the same one) or one with fixed points through a tip's block (it must stay whole)
    cannot be refined so: its cells join the faces that fall back (:func:`_merged_faces`) and
    the faces are meshed again, at most :data:`MAX_FALLBACK_MERGES` times.

    ``laid``: the round's cells as :func:`_lay_out` made them already (faces it could not lay
    out in its ``rest``).

    Returns ``(points, quads, layout, refinement)`` as :func:`mesh_blocks` does, the layout's
    ``local_faces`` the faces laid out on their own, its ``fallback_faces`` the faces meshed
    by ``mesh_face``; None when a face's mesh fails, the
    merged faces are no simple polygons or hold more than :data:`FALLBACK_SHARE` of the
    polygon's vertex count, or the merging does not settle.  The caller verifies the mesh."""
    z = part.polygon
    n = len(z)
    if laid is None:
        laid = _lay_out(part, size, FACE_DEPTH, rest_ok=mesh_face is not None)
    if laid is None or (laid.rest and mesh_face is None):
        return None
    X, cells = laid.points, laid.cells
    tips = np.flatnonzero(part.tip_mask[:n]).astype(np.int64)
    if not laid.rest:
        try:
            pts, quads, info = refine_layout(X, cells, size=size, tips=tips.tolist(), check=False)
        except ValueError:
            return None
        return pts, quads, _partial_result(part, laid, X, cells, tips), info
    assert mesh_face is not None  # rest_ok
    used = np.unique(np.concatenate([cells.ravel(), np.arange(len(part.points))]))
    face_ids = _merged_faces([_points_on_sides(X, lp, used) for lp in laid.rest])
    if face_ids is None:
        return None
    meshed: dict[tuple[int, ...], tuple] = {}
    for _ in range(MAX_FALLBACK_MERGES + 1):
        if len(cells) == 0:
            return None
        ch = layout_chords(cells, len(X))
        face_meshes = []
        params: dict[tuple[int, int], NDArray[np.float64]] = {}
        if sum(len(ids) for ids in face_ids) > FALLBACK_SHARE * n:
            return None  # the paper's construction on the faces would cost as much as on all
        for ids in face_ids:
            if tuple(ids) not in meshed:
                got = mesh_face(X[ids])
                checkpoint()
                if got is None:
                    return None
                fz = np.asarray(got[0], dtype=np.complex128)
                fq = np.asarray(got[1], dtype=np.int64)
                chains = _boundary_chains(fz, fq, X[ids])
                if chains is None:
                    return None
                meshed[tuple(ids)] = (fz, fq, chains, np.asarray(got[2], dtype=np.int8))
            fz, fq, chains, _src = meshed[tuple(ids)]
            for (u, v), chain in zip(zip(ids, ids[1:] + ids[:1]), chains):
                try:
                    ch.edge_id(u, v)
                except ValueError:
                    continue  # a side on the polygon's boundary
                t = _side_params(X, u, v, fz[chain])
                if np.any(np.diff(t) <= 0):
                    return None
                params[(u, v)] = t
            face_meshes.append((ids, fz, fq, chains, _src))
        # a chord between two fixed sides (a strip of cells from one fallback face to another,
        # or back to the same one) cannot carry both meshes' points, and one through a tip's
        # block must stay whole: their cells join the faces that fall back
        tip_cells = np.isin(cells, tips).any(axis=1)
        tip_chords = set(np.unique(ch.cell_chords[tip_cells]).tolist())
        on_chord: dict[int, int] = {}
        for u, v in params:
            k = ch.chord_of(u, v)
            on_chord[k] = on_chord.get(k, 0) + 1
        clash = [k for k, c in on_chord.items() if c > 1 or k in tip_chords]
        if not clash:
            break
        merge = np.isin(ch.cell_chords, clash).any(axis=1)
        face_ids = _merged_faces(face_ids + [c.tolist() for c in cells[merge]])
        if face_ids is None:
            return None
        cells = cells[~merge]
    else:
        return None
    if sum(len(m[2]) for m in face_meshes) > FALLBACK_MAX_PER_VERTEX * n:
        return None  # the faces alone hold more quads than the whole polygon would
    all_cells = cells
    cells, params, trans = _transition_cells(X, cells, params, size, tips)
    info: LayoutRefinement | None = None
    if len(cells):
        try:
            pts, quads, info = refine_layout(
                X, cells, size=size, edge_params=params, tips=tips.tolist(), check=False
            )
        except ValueError:
            return None
        pts = pts.copy()
        lay_edges = {tuple(e) for e in info.chords.edges.tolist()}
    else:  # every cell became a transition
        pts, quads, lay_edges = X.copy(), np.zeros((0, 4), dtype=np.int64), set()
    all_quads = [quads]

    def edge_ids(a: int, b: int) -> NDArray[np.int64] | None:
        """Refined points along the layout edge a -> b (None if no cell has it)."""
        if info is None or (min(a, b), max(a, b)) not in lay_edges:
            return None
        return info.edge_points(a, b)

    fine_ids: dict[tuple[int, int], NDArray[np.int64]] = {}  # F side (u, v) -> ids, u to v
    coarse_ids: dict[tuple[int, int], NDArray[np.int64]] = {}  # coarse side c0 -> c3 -> ids
    for tr in trans:
        tm = tr.mesh
        c0, c1, c2, c3 = tr.corners
        gid = np.full(len(tm.points), -1, dtype=np.int64)
        for side, a, b in ((tm.coarse, c0, c3), (tm.wall0, c0, c1), (tm.wall1, c3, c2)):
            ids = edge_ids(a, b)
            if ids is not None:
                if len(ids) != len(side):
                    return None
                gid[side] = ids
            else:
                gid[side[0]], gid[side[-1]] = a, b
        prev = None
        if tr.parent >= 0:  # continues the transition whose coarse side is its fine side
            prev = coarse_ids[(c1, c2)]
        elif tr.parent == -2:  # after a cell that carried the rows on
            prev = edge_ids(c1, c2)
            if prev is None:
                return None
        if prev is not None:
            if len(prev) != len(tm.fine):
                return None
            gid[tm.fine] = prev
        gid[tm.fine[0]], gid[tm.fine[-1]] = c1, c2
        new = gid < 0
        gid[new] = len(pts) + np.arange(int(new.sum()))
        pts = np.concatenate([pts, tm.points[new]])
        all_quads.append(gid[tm.quads])
        coarse_ids[(c0, c3)] = gid[tm.coarse]
        if tr.parent == -1:
            fine_ids[(c2, c1)] = gid[tm.fine][::-1]
    n_block_quads = sum(len(q) for q in all_quads)
    for ids, fz, fq, chains, _src in face_meshes:
        gid = np.full(len(fz), -1, dtype=np.int64)
        for (u, v), chain in zip(zip(ids, ids[1:] + ids[:1]), chains):
            if (u, v) in fine_ids:  # the fine side of a transition cell
                t_ids = fine_ids[(u, v)]
                if len(t_ids) != len(chain):
                    return None
                gid[chain] = t_ids
                pts[t_ids[1:-1]] = fz[chain[1:-1]]
            elif (u, v) in params:
                lay_ids = info.edge_points(u, v)
                if len(lay_ids) != len(chain):
                    return None
                gid[chain] = lay_ids
                pts[lay_ids[1:-1]] = fz[chain[1:-1]]  # the face mesh's own coordinates
            else:
                gid[chain[0]], gid[chain[-1]] = u, v
        new = gid < 0
        gid[new] = len(pts) + np.arange(int(new.sum()))
        pts = np.concatenate([pts, fz[new]])
        all_quads.append(gid[fq])
    quads = np.concatenate(all_quads)
    # points left unused (centres of faces whose split failed) are dropped
    keep = np.zeros(len(pts), dtype=bool)
    keep[quads.ravel()] = True
    keep[:n] = True
    remap = np.cumsum(keep) - 1
    lay = _partial_result(
        part,
        laid,
        X,
        all_cells,
        tips,
        fallback_faces=tuple(X[ids] for ids in face_ids),
        fallback_quads=len(quads) - n_block_quads,
        fallback_source=np.concatenate([m[4] for m in face_meshes]),
    )
    return pts[keep], remap[quads], lay, info


@dataclass(frozen=True)
class _Transition:
    """A transition cell of :func:`_transition_cells`: its corners ``(c0, c1, c2, c3)`` (fine
    side c1 -> c2, coarse side c0 -> c3), its mesh, the transition whose coarse side is its
    fine side (``parent``; -1: its fine side is a face's, -2: a side of a cell that carries the
    rows on unchanged), and the transition whose rows it goes on from (``after``, directly or
    through such cells; -1: a face's)."""

    corners: tuple[int, int, int, int]
    mesh: TransitionMesh
    parent: int
    after: int


#: rounds of transition cells along a chord away from a face that falls back (each continues
#: from the coarse side of the one before, while rows are still to be removed)
TRANSITION_ROUNDS = 12
#: pairs of split rows all the cascades of one layout may optimise (the rest are placed by the
#: template alone: the optimisation is what takes the time)
TRANSITION_POLISH_BUDGET = 16
#: a cell shorter along the rows than this share of its width carries them on without trying a
#: cascade (measured on glyphs: cells below 0.45 never held one)
TRANSITION_MIN_ASPECT = 0.5


def _transition_cells(
    X: NDArray[np.complex128],
    cells: NDArray[np.int64],
    params: dict[tuple[int, int], NDArray[np.float64]],
    size: float,
    tips: NDArray[np.int64],
) -> tuple[NDArray[np.int64], dict[tuple[int, int], NDArray[np.float64]], list[_Transition]]:
    """Cells next to a face that falls back, meshed by transition cascades
    (:func:`quadmesh.transition.transition_cascade`) from the face mesh's points on their side
    (``params``: fixed parameters of the face sides ``(u, v)``, counter-clockwise around the
    face) towards the count the size asks for on the opposite side, so that the graded points
    of the paper's construction do not run along the whole chord.  Where one cell is too short
    for the whole cascade, the next cell along the chord continues from its coarse side (up to
    :data:`TRANSITION_ROUNDS` cells).

    A cell is taken when it has one such side and holds no tip, and the cascades' coarse sides
    and walls (which become fixed parameters of the chords of the cells left) agree with every
    other fixed parameter on their chords (a cell whose cascade disagrees is left as a cell,
    with the cells that continue from it); a cascade that does not lower the count is not
    used.  Returns ``(cells left, fixed parameters, transitions)`` (the transitions in the
    order they continue one another)."""
    from .transition import TransitionError, transition_cascade

    # sides a transition may start from, as the cell beyond runs along them: fine parameters
    # from c1 to c2, and the transition that made the side (-1: a face)
    start = {(v, u): (1.0 - t[::-1], -1, -1) for (u, v), t in params.items()}
    budget = [TRANSITION_POLISH_BUDGET]  # pair optimisations, shared by all cascades
    tip_cell = np.isin(cells, tips).any(axis=1)
    cand: dict[int, _Transition] = {}
    seen: set[int] = set()
    for _round in range(TRANSITION_ROUNDS):
        new_sides = {}
        for c, q in enumerate(cells.tolist()):
            if c in seen or tip_cell[c]:
                continue
            ks = [k for k in range(4) if (q[k], q[(k + 1) % 4]) in start]
            if len(ks) != 1:
                continue
            seen.add(c)
            k = ks[0]
            corners = (q[(k - 1) % 4], q[k], q[(k + 1) % 4], q[(k + 2) % 4])
            p_fine, parent, after = start[(corners[1], corners[2])]
            cn = X[list(corners)]
            n_coarse = max(1, math.ceil(abs(cn[3] - cn[0]) / size))
            if (len(p_fine) - 1 - n_coarse) % 2:
                n_coarse += 1
            if len(p_fine) - 1 - n_coarse < 2:
                continue
            tm = None
            along = min(abs(cn[1] - cn[0]), abs(cn[2] - cn[3]))
            if along >= TRANSITION_MIN_ASPECT * max(abs(cn[3] - cn[0]), abs(cn[2] - cn[1])):
                # the face mesh's points come in clusters: evened towards equal rows first,
                # else by neighbour averaging; the cascade that leaves fewer rows is kept
                for even in ("uniform", "smooth"):
                    try:
                        got = transition_cascade(
                            cn,
                            p_fine,
                            n_coarse,
                            partial=True,
                            budget=budget,
                            even=even,
                            reuse=True,
                            straighten=True,
                        )
                    except TransitionError:
                        continue
                    if got.margin >= 0 and (tm is None or len(got.coarse) < len(tm.coarse)):
                        tm = got
            checkpoint()
            if tm is None or len(tm.coarse) >= len(p_fine) or tm.margin < 0:
                # too short a cell (or no room): it carries the rows on to the next cell
                new_sides[(corners[0], corners[3])] = (p_fine, -2, after)
                continue
            cand[c] = _Transition(corners, tm, parent, after)
            if len(tm.coarse) - 1 > n_coarse:
                new_sides[(corners[0], corners[3])] = (tm.p_coarse, c, c)
        if not new_sides:
            break
        start = new_sides
    while cand:
        # two transitions (or a transition and a face) on one side would each put their own
        # points on it: only a face's side with its first transition's fine side, and a
        # transition's coarse side with the fine side of the one continuing from it, may meet
        on_side: dict[tuple[int, int], list[tuple[int, str]]] = {}
        for u, v in params:
            on_side.setdefault((min(u, v), max(u, v)), []).append((-1, "face"))
        for c, tr in cand.items():
            c0, c1, c2, c3 = tr.corners
            for a, b, role in ((c1, c2, "fine"), (c0, c3, "coarse"), (c0, c1, "w"), (c3, c2, "w")):
                if role == "fine" and tr.parent == -2:
                    continue  # the side of a cell left as it is
                on_side.setdefault((min(a, b), max(a, b)), []).append((c, role))
        clash: set[int] = set()
        for users in on_side.values():
            if len(users) < 2:
                continue
            if len(users) == 2:
                (ca, ra), (cb, rb) = sorted(users, key=lambda x: x[1])
                pair = {ra: ca, rb: cb}
                if ra == "face" and rb == "fine" and cand[cb].parent == -1:
                    continue
                if (ra, rb) == ("coarse", "fine") and cand[pair["fine"]].parent == pair["coarse"]:
                    continue
            clash.add(max(c for c, _r in users))
        if clash:
            while clash:  # with every transition continuing from a dropped one
                for c in clash & set(cand):
                    del cand[c]
                clash = {c for c, tr in cand.items() if tr.after >= 0 and tr.after not in cand}
            continue
        keep = np.ones(len(cells), dtype=bool)
        keep[list(cand)] = False
        rest = cells[keep]
        if len(rest) == 0:  # every cell is a transition: no chords left to agree on
            return rest, {}, list(cand.values())
        ch = layout_chords(rest, len(X))
        edges = {tuple(e) for e in ch.edges.tolist()}
        fixed: dict[tuple[int, int], tuple[NDArray[np.float64], int]] = {}
        for (u, v), t in params.items():
            fixed[(u, v)] = (t, -1)
        for c, tr in cand.items():
            c0, c1, c2, c3 = tr.corners
            fixed[(c0, c3)] = (tr.mesh.p_coarse, c)
            fixed[(c0, c1)] = (_side_params(X, c0, c1, tr.mesh.points[tr.mesh.wall0]), c)
            fixed[(c3, c2)] = (_side_params(X, c3, c2, tr.mesh.points[tr.mesh.wall1]), c)
        tip_chords = set(np.unique(ch.cell_chords[np.isin(rest, tips).any(axis=1)]).tolist())
        by_chord: dict[int, list[int]] = {}
        for u, v in list(fixed):
            if (min(u, v), max(u, v)) not in edges:
                del fixed[(u, v)]  # on the polygon's boundary, a face or another transition
                continue
            by_chord.setdefault(ch.chord_of(u, v), []).append(fixed[(u, v)][1])
        drop = {
            c for k, cs in by_chord.items() if len(cs) > 1 or k in tip_chords for c in cs if c >= 0
        }
        if not drop:
            return rest, {uv: t for uv, (t, _c) in fixed.items()}, list(cand.values())
        while drop:  # with every transition continuing from a dropped one
            for c in drop & set(cand):
                del cand[c]
            drop = {c for c, tr in cand.items() if tr.after >= 0 and tr.after not in cand}
    return cells, params, []


def _side_params(
    X: NDArray[np.complex128], a: int, b: int, w: NDArray[np.complex128]
) -> NDArray[np.float64]:
    """Parameters of the points ``w`` (in order from ``X[a]`` to ``X[b]``) along the segment
    a -> b, exactly 0 and 1 at its ends (a transition's walls may carry different ones)."""
    d = X[b] - X[a]
    t = ((w - X[a]) * np.conj(d)).real / abs(d) ** 2
    t[0], t[-1] = 0.0, 1.0
    return t


def _merged_faces(faces: list[list[int]]) -> list[list[int]] | None:
    """Faces (point ids, counter-clockwise) that share sides merged into one polygon each (the
    sides they share cancel); None where a merged region is no simple polygon (a point where
    its boundary meets itself, or a hole)."""
    parent = list(range(len(faces)))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    owner: dict[tuple[int, int], int] = {}
    for k, ids in enumerate(faces):
        for u, v in zip(ids, ids[1:] + ids[:1]):
            other = owner.get((v, u))
            if other is not None:
                parent[root(k)] = root(other)
            owner[(u, v)] = k
    groups: dict[int, list[int]] = {}
    for k in range(len(faces)):
        groups.setdefault(root(k), []).append(k)
    out = []
    for members in groups.values():
        if len(members) == 1:
            out.append(faces[members[0]])
            continue
        edges = {(u, v) for k in members for u, v in zip(faces[k], faces[k][1:] + faces[k][:1])}
        nxt: dict[int, int] = {}
        for u, v in edges:
            if (v, u) in edges:
                continue
            if u in nxt:
                return None  # the region touches itself at u
            nxt[u] = v
        if not nxt:
            return None
        start = next(iter(nxt))
        cyc = [start]
        while nxt[cyc[-1]] != start:
            cyc.append(nxt[cyc[-1]])
            if len(cyc) > len(nxt):
                return None
        if len(cyc) != len(nxt):
            return None  # more than one boundary loop: a hole
        out.append(cyc)
    return out


def _boundary_chains(
    fz: NDArray[np.complex128], fq: NDArray[np.int64], corners: NDArray[np.complex128]
) -> list[NDArray[np.int64]] | None:
    """The boundary points of a mesh ``(fz, fq)`` of the polygon ``corners`` from each corner
    to the next (both included, counter-clockwise), or None if a corner is not a mesh point or
    the boundary does not run through the corners in order."""
    scale = float(np.max(np.abs(corners - corners[0])))
    at = np.empty(len(corners), dtype=np.int64)
    for k, w in enumerate(corners):
        d = np.abs(fz - w)
        j = int(np.argmin(d))
        if d[j] > 1e-12 * scale:
            return None
        at[k] = j
    bnd, _consistent = unpaired_edges(fq)
    nxt = np.full(len(fz), -1, dtype=np.int64)
    nxt[bnd[:, 0]] = bnd[:, 1]
    chains = []
    for k in range(len(at)):
        a, b = int(at[k]), int(at[(k + 1) % len(at)])
        chain = [a]
        while chain[-1] != b:
            c = int(nxt[chain[-1]])
            if c < 0 or len(chain) > len(fz):
                return None
            chain.append(c)
        chains.append(np.array(chain, dtype=np.int64))
    return chains


def mesh_blocks(
    polygon: ArrayLike, size: float | None = None, mesh_face: FaceMesher | None = None
) -> tuple[NDArray[np.complex128], NDArray[np.int64], BlockLayout, LayoutRefinement | None]:
    """Quad mesh of a polygon from its block layout, refined to edge length about ``size``.

    Args:
        polygon: (n,) complex vertices, counter-clockwise.
        size: target edge length (default :func:`default_block_size`); every chord of the layout
            gets ``ceil(longest edge / size)`` segments, chords through a tip cell stay whole.

    The layout is the first of: straight cuts (:func:`block_layout`); a ladder of straight
    cells along the polygon as one corridor (:func:`_ladder_mesh`); a collar around a lattice
    core (:func:`quadmesh.rings.ring_layout`); straight cuts again with a longer search when
    the first ran out of time (:func:`_long_cut_layout`); last, the straight cuts of the search
    round that left the fewest faces unsplit, each such face laid out on its own (its
    ``local_faces``) or, with ``mesh_face`` (a mesher for one face, the paper's construction),
    meshed by it and glued to the cells (:func:`mesh_partial_layout`; the layout's
    ``fallback_faces`` name them).

    Returns:
        ``(points, quads, layout, refinement)``; ``points[:n]`` are the polygon's vertices;
        ``refinement`` is None for a ladder (its cells are refined by runs of rungs, its ends
        and bends are vertex sectors).

    Raises:
        BlockLayoutError: none of the three layouts closes.
    """
    z = np.asarray(polygon, dtype=np.complex128)
    h = default_block_size(z) if size is None else float(size)
    if not (h > 0 and math.isfinite(h)):
        raise ValueError(f"size must be a positive finite length, got {size!r}")
    partial: list[PartialLayout] = []
    try:
        lay = block_layout(z, h, partial)
    except BlockLayoutError as exc:
        # no straight cuts close: the polygon as one corridor (strokes, round shapes with two
        # ends), else a collar around a lattice core (round and dense outlines)
        why: list[str] = []
        ladder = _ladder_mesh(z, h, why)
        if ladder is not None:
            return ladder
        from .rings import RingLayoutError, ring_layout

        try:
            lay = ring_layout(z, h)
        except RingLayoutError as ring_exc:
            lay = _long_cut_layout(z, exc.args[0], partial)
            if lay is None:
                got = _fallback_faces(z, h, partial, mesh_face)
                if got is not None:
                    return got
            if lay is None:
                raise BlockLayoutError(
                    f"{exc.args[0]}; nor does a ladder of straight cells along the polygon "
                    f"({why[-1]}) or a collar around a lattice core close ({ring_exc.args[0]})"
                ) from exc
    # the layout's corners were checked when it was built, up to ANGLE_TOL for corners that
    # sit exactly on 60° or 120° (triangle and hexagon faces); the final mesh is verified by
    # the caller with the strict fixed tolerance
    pts, quads, info = refine_layout(
        lay.points, lay.cells, size=h, tips=lay.tips.tolist(), check=False
    )
    return pts, quads, lay, info


def _fallback_faces(
    z: NDArray[np.complex128],
    size: float,
    partial: list[PartialLayout],
    mesh_face: FaceMesher | None,
) -> tuple[NDArray[np.complex128], NDArray[np.int64], BlockLayout, LayoutRefinement] | None:
    """The mesh of a partial layout whose unsplit faces are all laid out on their own: the
    searches' kept rounds in turn, then those of a relaxed search (:func:`_relaxed_partial`),
    then those of a relaxed search with twin cuts (:func:`_twin_corners`); failing that, with
    ``mesh_face``, the round with the fewest faces left without a layout of
    their own, those faces meshed by ``mesh_face`` (:func:`mesh_partial_layout`), or, when
    that mesh fails the strict check (:meth:`quadmesh.mesh.QuadMesh.verify`), the next such
    round (:data:`FALLBACK_ROUNDS` in all)."""
    tried: list[tuple[PartialLayout, _LaidOut]] = []
    deadline = time.perf_counter() + PARTIAL_SECONDS

    def pure(
        rounds: list[PartialLayout],
    ) -> tuple[NDArray[np.complex128], NDArray[np.int64], BlockLayout, LayoutRefinement] | None:
        for part in rounds:
            if time.perf_counter() > deadline:
                return None
            laid = _lay_out(
                part, size, FACE_DEPTH, rest_ok=mesh_face is not None, deadline=deadline
            )
            if laid is not None and laid.rest:
                tried.append((part, laid))
            elif laid is not None:
                got = mesh_partial_layout(part, size, laid=laid)
                if got is not None:
                    return got
        return None

    got = pure(partial)
    if got is None:
        relaxed: list[PartialLayout] = []
        _relaxed_partial(z, relaxed)
        got = pure(relaxed)
    if got is None:
        # last: rounds with the corners that no single cut serves cut twice (pixel stairs),
        # with time of their own (scikit-image text_3: 16 faces laid out on their own)
        twin: list[PartialLayout] = []
        _relaxed_partial(z, twin, twins=True)
        if twin:
            deadline = time.perf_counter() + PARTIAL_SECONDS
            got = pure(twin)
    if got is not None or mesh_face is None or not tried:
        return got
    for part, laid in sorted(tried, key=lambda t: (len(t[1].rest), t[0].score))[:FALLBACK_ROUNDS]:
        got = mesh_partial_layout(part, size, mesh_face, laid=laid)
        # the face meshes' graded points carried along chords can come within rounding of
        # each other (cmr10 "W": rows 1e-9 apart, a vertex inside a neighbour's edge): such a
        # mesh would fail the final check, so the next round is tried instead
        if got is not None and QuadMesh.from_complex(got[0], got[1]).verify(z).ok:
            return got
    return None


def _long_cut_layout(
    z: NDArray[np.complex128], why: str, partial: list[PartialLayout] | None = None
) -> BlockLayout | None:
    """The straight-cut layout searched for again when neither a ladder nor a collar closed,
    for :data:`LONG_SEARCH_SECONDS` per stage with faster rounds (faces apart,
    :func:`_split_cells`): when the first search ran out of time (``why``: its message), or
    when a corner had no straight cut of its own and the candidates were too many for
    T-junction candidates (more than :data:`MAX_RAYS_FOR_TEES`; now up to
    :data:`LONG_MAX_RAYS_FOR_TEES`); then, where a corner had no cut, once more with the
    corners of 181.5°–240° that no single straight cut serves cut twice
    (:func:`_twin_corners`).  None if it fails too, or if neither applies (the search would
    give the same answer)."""
    timed_out = "no layout within" in why
    if not timed_out and not why.startswith("no straight cut from the corner"):
        return None
    for twins in (False, True) if not timed_out and _may_twin(_angles_deg(z)) else (False,):
        try:
            return _cut_layout(
                z,
                seconds=LONG_SEARCH_SECONDS,
                separate=True,
                tee_rays=LONG_MAX_RAYS_FOR_TEES,
                more_tees=not timed_out and not twins,
                partial=partial,
                twins=twins,
            )
        except BlockLayoutError:
            pass
    return None


def _elongation(z: NDArray[np.complex128]) -> float:
    """The polygon's area over that of its largest inscribed disk (1 for a disk, about
    4 L / (π w) for a corridor of length L and width w)."""
    import shapely

    poly = shapely.Polygon(np.column_stack([z.real, z.imag]))
    area = float(poly.area)
    radius = float(shapely.maximum_inscribed_circle(poly, 1e-3 * math.sqrt(area)).length)
    return area / (math.pi * radius * radius) if radius > 0 else math.inf


def _ladder_mesh(
    z: NDArray[np.complex128], size: float, why: list[str] | None = None
) -> tuple[NDArray[np.complex128], NDArray[np.int64], BlockLayout, None] | None:
    """The polygon meshed as one corridor (:func:`quadmesh.thin.corridor.mesh_corridor`): a
    ladder of convex straight cells with corners in [60°, 120°] between its two ends, refined
    with about four quads across and none longer than ``size``; round ends and bends are
    vertex sectors.

    The ladder is searched for with sector crosscuts of at least 16 chords and, on polygons of
    at most :data:`quadmesh.thin.corridor.SECTOR_RETRY_MAX` vertices, again with at least 8
    (:data:`LADDER_SECTOR_CHORDS`), each search within :data:`LADDER_SECONDS` or
    :data:`LADDER_SECONDS_PER_VERTEX` per polygon vertex, the longer; of the meshes
    whose edges are all at most :data:`LADDER_MAX_EDGE` times ``size`` the one with fewer quads
    is kept (the coarser sectors put fewer points across the corridor, but their layout may
    need more cells). Where neither search gives one, both are repeated with sectors whose
    connection rows turn to meet their crosscut at right angles, or with round bends about
    the centre of their outer arc (``turn=True`` of
    :func:`quadmesh.thin.corridor.ladder_layout`: sharp bends of zigzags and walks), except
    where the plain search ran out of its time (the search with turning rows does all it did,
    and more: a round outline of a thousand vertices that is no corridor at all). None
    when no search gives such a mesh: the polygon has no ladder, or the sectors' spokes would
    be long needles (the polygon is too wide for a ladder at this size); each search's reason
    is then appended to ``why`` when given (a list). Not searched for at all on a round
    polygon (area below :data:`LADDER_MIN_ELONGATION` times its largest inscribed disk's,
    :func:`_elongation`), which is no corridor."""
    from .errors import ThinPartError
    from .thin.corridor import SECTOR_RETRY_MAX, ladder_layout, mesh_corridor

    elongation = _elongation(z)
    if elongation < LADDER_MIN_ELONGATION:
        if why is not None:
            why.append(
                f"the polygon is no corridor: its largest inscribed disk covers "
                f"{100.0 / elongation:.0f} % of its area"
            )
        return None
    chords = LADDER_SECTOR_CHORDS if len(z) <= SECTOR_RETRY_MAX else LADDER_SECTOR_CHORDS[:1]
    seconds = max(LADDER_SECONDS, LADDER_SECONDS_PER_VERTEX * len(z))
    best = None
    # straight connection rows first; where no ladder has them, rows that turn at sharp bends
    tries = [(least, False) for least in chords] + [(least, True) for least in chords]
    timed_out: set[int] = set()
    for least, turn in tries:
        if turn and (best is not None or least in timed_out):
            # (a search with turning rows does all the plain one did, and more)
            continue
        deadline = time.perf_counter() + seconds
        try:
            lad = ladder_layout(z, deadline=deadline, sector_chords=least, turn=turn)
            cm = mesh_corridor(z, size=size, lay=lad)
        except ThinPartError as exc:
            if time.perf_counter() > deadline:
                timed_out.add(least)
            if why is not None:
                why.append(str(exc.args[0]) if exc.args else type(exc).__name__)
            continue
        checkpoint()
        # round ends and bends are sectors with a fixed number of spokes: on a polygon that is
        # wide for the size (a disk, say) their spokes would be long needles, not quads of the
        # size
        q = cm.vertices[cm.quads]
        longest = float(np.abs(np.roll(q, -1, axis=1) - q).max())
        if longest > LADDER_MAX_EDGE * size:
            if why is not None:
                why.append(f"its sectors' longest edge is {longest / size:.3g} × the size")
            continue
        if best is None or len(cm.quads) < len(best[1].quads):
            best = (lad, cm)
    if best is None:
        return None
    lad, cm = best
    pts = np.asarray(lad.vertices, dtype=np.complex128)
    cells = np.asarray(lad.cells, dtype=np.int64).reshape(-1, 4)
    lay = BlockLayout(
        polygon=z,
        points=pts,
        cuts=pts[np.asarray(lad.rungs, dtype=np.int64).reshape(-1, 2)],
        faces=(),
        cells=cells,
        tips=np.flatnonzero(_angles_deg(z) < ANGLE_MIN - ANGLE_TOL).astype(np.int64),
        split=False,
        angles=cell_angles(pts[cells]),
        kind="ladder",
    )
    return np.asarray(cm.vertices, dtype=np.complex128), np.asarray(cm.quads, np.int64), lay, None
