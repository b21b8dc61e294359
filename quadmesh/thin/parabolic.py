"""Quad mesh of a parabolic thin part: the region between a polygon vertex and a crosscut.

Paper: Bishop, "Optimal angle bounds for quadrilateral meshes", section "Meshing the thin
parts" (figures "compose-split", "Mesh 1", "Mesh 2", "Same-Sector", "big angle").

Construction (all in a unit frame with the apex at 0 and side 1 along the positive axis):

1. The angle theta is split into m = 1, 2 or 3 subsectors of angle alpha = theta/m <= 120°.
2. Mesh 1 fills the disk sector of radius r0 = 1 of each subsector (two chords of span alpha/2).
3. Levels: level j is the annulus [r_j, r_{j+1}]; every chord of span phi_j = alpha/2^j that is
   refined in this level gets Mesh 2 (one inner chord -> two outer chords; reconstructed in
   reconstructed: exact angles th1..th5, 60, 90, 120, 60 + phi), every other chord crosses the
   level as a plain strip cut by concentric chords. Mesh 2's radial vertices form a "3-set" on
   one side and a "2-set" on the other; walking in increasing angle, each Mesh 2 piece is
   reflected or not so that its smaller-angle ray carries the set the previous piece left there,
   and plain strips carry the current set. All refined chords of a level have the
   same span and inner radius, so the level's radii are common.
4. The chords form a binary refinement tree: it is chosen top-down so that its P-1 leaves end at
   the polar angles of the crosscut vertices g_k as closely as the dyadic angles allow (each tree
   boundary is matched with the nearest crosscut vertex that leaves room for the minimum
   refinement on both sides). This handles crosscuts whose vertices are strongly graded towards
   the sides (geodesic images), where a single greedy partial level cannot.
   Every chord is refined at least once after Mesh 1, so the outer spans are <= alpha/4 <= 30°.
   Because every level is crossed by all chords (plain strips), the depth of the deepest leaf
   sets the quad count; the tree is therefore capped at the smallest depth whose outer vertices
   stay within 0.15 * log(1/lam) radians of the g_k's polar angles (the connection chains below
   absorb that mismatch with slope <= 0.15 in log-polar coordinates), with the uncapped tree as
   the fallback. On the pipeline's crosscuts this gives ~9 quads per crosscut vertex (~15
   uncapped) and keeps the smallest Mesh 1 / Mesh 2 pieces larger.
5. The tree is scaled to the sector radius lam * min|g_k - v| and the k-th outer vertex s_k is
   joined to g_k by the connection quads (figure "Same-Sector"). When the straight segments
   s_k g_k give angles too far from 90° (the dyadic tree cannot always put s_k at g_k's angle,
   e.g. when P = 4m + 1 leaves no choice), the segments are replaced by log-spiral chains through
   J intermediate rings, i.e. the channel construction (hyperbolic thin part) on the annulus between
   the
   sector and the crosscut; if needed the sector is also shrunk (lam * 0.4, 0.16, 0.064), which
   lengthens that annulus in log coordinates and flattens the spirals. The first (lam, J) with
   all connection angles in [65°, 115°] is used, else the best one within [60°, 120°].
6. Checks use coordinates relative to the apex, so a sector that is tiny
   compared with its distance from the origin is not misjudged by cancellation in the shoelace
   sum. Exact 60°/120° angles of Mesh 1 / Mesh 2 (degree-3 vertices with three 120° angles admit
   no slack) are still perturbed by rounding of the absolute coordinates, about
   4 ulp(|apex|) / (edge length) radians; when that alone exceeds the 1e-6° tolerance the error
   says the crosscut is too close to the vertex for double precision.
7. Speed: the vertex numbering, quads and kinds of Mesh 1 and the levels depend only on the
   tree's shape (and on which radii coincide as floats), so they are made once per shape
   (:class:`_Template`, cached) and each sector only places the vertices (rho e^{i angle} on the
   rays, Mesh 2's points Y and X rotated onto their piece) with array operations; the same
   floats result as from building the sector vertex by vertex.
"""

from __future__ import annotations

import bisect
import functools
import math
from collections.abc import Iterator

import numpy as np

from ..errors import ThinPartError
from ..progress import checkpoint
from .mesh import (
    KIND_CONNECTION,
    KIND_MESH1,
    KIND_MESH2,
    KIND_STRIP,
    ThinMesh,
    quad_angles_deg,
    require_angles,
    unpaired_edges,
)

__all__ = ["mesh2_local", "mesh_vertex_sector", "split_count"]

_K = 64  # tree boundaries are integers n: angle = alpha * n / 2**_K
_ONE = 1 << _K
_MAX_DEPTH = 56
# Largest slope of the connection chains in log-polar coordinates accepted for a depth-capped
# refinement tree (see _trees): |angle(s_k) - angle(g_k)| <= _MISMATCH * log(1 / lam).
_MISMATCH = 0.15

# Shape constants of Mesh 2; the angles do not depend on them.
_KR = 1.0 / math.sqrt(3.0) + 0.25
_KT = 0.30
_KTOP = 0.40


def split_count(theta: float) -> int:
    """Number m of subsectors: 1 for theta < 120°, 2 for theta < 240°, else 3."""
    deg = math.degrees(theta)
    if deg < 120.0 - 1e-9:
        return 1
    if deg < 240.0 - 1e-9:
        return 2
    return 3


def _e(deg: float) -> complex:
    return complex(math.cos(math.radians(deg)), math.sin(math.radians(deg)))


def _ray_hit(p: complex, d: complex, u: complex) -> complex:
    """Intersection of the ray p + t d with the line through 0 in direction u."""
    # p + t d = s u; the cross product with u eliminates s: t = -cross(u, p) / cross(u, d)
    den = u.real * d.imag - u.imag * d.real
    if den == 0.0:
        raise ThinPartError("internal: Mesh 2 construction ray parallel to the side")
    t = -(u.real * p.imag - u.imag * p.real) / den
    return p + t * d


# The six quads of Mesh 2 by point name (counter-clockwise).
_MESH2_QUADS = (
    ("A_L", "A_R", "P", "R"),
    ("R", "P", "P1", "Y"),
    ("R", "Y", "X", "R2"),
    ("Y", "P1", "P2", "X"),
    ("R2", "X", "B_M", "B_L"),
    ("X", "P2", "B_R", "B_M"),
)


def mesh2_local(phi: float) -> dict[str, object]:
    """Mesh 2 (the paper's figure "Mesh 2", reconstructed here) for inner radius 1.

    Local frame: apex at 0, bisector along +i, piece angle ``phi`` (radians, 0 < phi <= 60°).
    Returns the named points (complex), the radii of the radial-side vertices
    (``set3`` on the right side u_R = e(90° - phi/2), ``set2`` on the left side), the outer
    radius ``r2`` and the six quads as tuples of point names (counter-clockwise).
    """
    h = math.degrees(phi) / 2.0
    c = 2.0 * math.sin(math.radians(h))
    u_l, u_r = _e(90.0 + h), _e(90.0 - h)
    a_l, a_r = u_l, u_r
    r_r = 1.0 + _KR * c
    pt_r = r_r * u_l
    t = _KT * c
    sh = math.sin(math.radians(h))
    s = (t * sh + r_r * sh) / math.cos(math.radians(30.0 + h))
    pt_y = pt_r + s * _e(30.0 + h)
    pt_x = pt_y + t * u_l
    pt_p = _ray_hit(pt_r, _e(h - 30.0), u_r)
    pt_p1 = _ray_hit(pt_y, _e(h - 30.0), u_r)
    rho2 = pt_x.imag / math.cos(math.radians(h))
    r2 = rho2 + _KTOP * c
    r_p, r_p1 = abs(pt_p), abs(pt_p1)
    if not (1.0 < r_p < r_p1 < rho2 < r2 and 1.0 < r_r < rho2):
        raise ThinPartError(f"Mesh 2 degenerate for phi = {math.degrees(phi):.4g} deg")
    pts = {
        "A_L": a_l,
        "A_R": a_r,
        "R": pt_r,
        "P": r_p * u_r,
        "P1": r_p1 * u_r,
        "Y": pt_y,
        "X": pt_x,
        "R2": rho2 * u_l,
        "P2": rho2 * u_r,
        "B_L": r2 * u_l,
        "B_R": r2 * u_r,
        "B_M": complex(0.0, r2),
    }
    return {
        "points": pts,
        "set3": (r_p, r_p1, rho2),
        "set2": (r_r, rho2),
        "r2": r2,
        "quads": _MESH2_QUADS,
    }


class _Node:
    __slots__ = ("depth", "hi", "ia", "ib", "kids", "lo")

    def __init__(self, depth: int, lo: int, hi: int, ia: int, ib: int) -> None:
        self.depth, self.lo, self.hi, self.ia, self.ib = depth, lo, hi, ia, ib
        self.kids: tuple[_Node, _Node] | None = None


def _nearest(psi: list[float], ang: float, lo_i: int, hi_i: int) -> int:
    """Index in [lo_i, hi_i] whose crosscut angle psi (ascending) is nearest to ``ang``; the
    lower one of two equally near."""
    k = bisect.bisect_left(psi, ang)
    # j0 = min(max(k - 1, lo_i), hi_i), j1 = min(max(k, lo_i), hi_i)
    j0 = k - 1 if k > lo_i else lo_i
    j1 = k if k > lo_i else lo_i
    if j0 > hi_i:
        j0 = hi_i
    if j1 > hi_i:
        j1 = hi_i
    return j0 if abs(psi[j0] - ang) <= abs(psi[j1] - ang) else j1


def _build_tree(
    psi: list[float], m: int, alpha: float, depth_cap: int | None
) -> tuple[list[_Node], bool]:
    """Refinement tree (roots = the m subsectors) whose leaves match the crosscut angles.

    Each node is split at its dyadic mid-angle; the crosscut vertex assigned to that boundary is
    the one nearest in polar angle that leaves room on both sides: at least the minimum
    refinement (every Mesh 1 chord is refined at least once) and, with ``depth_cap`` = D, at most
    2**(D - depth) leaves under a node of the given depth, so that no leaf is deeper than D.
    Returns the roots and whether the cap changed any choice (else the tree is the uncapped one).
    ``psi`` is a list (scalar look-ups in a list are much faster than in an array).
    """
    p1 = len(psi) - 1
    cap = _MAX_DEPTH if depth_cap is None else depth_cap
    changed = False
    bounds = [0]
    for j in range(1, m):
        lo_i, hi_i = bounds[-1] + 4, p1 - 4 * (m - j)
        pick = _nearest(psi, j * alpha, lo_i, hi_i)
        if depth_cap is not None:
            lo_c = max(lo_i, p1 - (m - j) * (1 << cap))
            hi_c = min(hi_i, bounds[-1] + (1 << cap))
            capped = _nearest(psi, j * alpha, lo_c, hi_c)
            changed |= capped != pick
            pick = capped
        bounds.append(pick)
    bounds.append(p1)
    roots = [_Node(0, q * _ONE, (q + 1) * _ONE, bounds[q], bounds[q + 1]) for q in range(m)]
    stack = list(roots)
    while stack:
        nd = stack.pop()
        n = nd.ib - nd.ia
        if nd.depth >= 2 and n == 1:
            continue
        if nd.depth >= cap:
            raise ThinPartError("crosscut vertices are too strongly clustered towards a side")
        min_child = 2 if nd.depth == 0 else 1
        mid = (nd.lo + nd.hi) // 2
        ang = alpha * (mid / _ONE)
        ic = _nearest(psi, ang, nd.ia + min_child, nd.ib - min_child)
        if depth_cap is not None:
            room = n - (1 << (cap - nd.depth - 1))  # if above min_child
            if room > min_child:
                capped = _nearest(psi, ang, nd.ia + room, nd.ib - room)
                changed |= capped != ic
                ic = capped
        left = _Node(nd.depth + 1, nd.lo, mid, nd.ia, ic)
        right = _Node(nd.depth + 1, mid, nd.hi, ic, nd.ib)
        nd.kids = (left, right)
        stack.extend((left, right))
    return roots, changed


def _leaves(roots: list[_Node]) -> tuple[list[int], int]:
    """Dyadic angles (units alpha / 2**_K) of the leaf boundaries, from side 1 to side 2, and
    the depth of the deepest leaf."""
    out: list[int] = []
    depth = 0
    stack = list(reversed(roots))
    while stack:
        nd = stack.pop()
        if nd.kids is None:
            out.append(nd.lo)
            if nd.depth > depth:
                depth = nd.depth
        else:
            stack.extend((nd.kids[1], nd.kids[0]))
    out.append(roots[-1].hi)
    return out, depth


def _leaf_bounds(roots: list[_Node]) -> list[int]:
    """Dyadic angles (units alpha / 2**_K) of the leaf boundaries, from side 1 to side 2."""
    return _leaves(roots)[0]


def _trees(psi: np.ndarray, m: int, alpha: float, lam: float) -> Iterator[list[_Node]]:
    """Candidate refinement trees, best first.

    Every level of the sector is crossed by all chords (plain strips), so the quad count grows
    with the depth of the deepest leaf, and deep levels also shrink the smallest Mesh 2 pieces.
    The first candidate is the shallowest depth-capped tree whose outer vertices lie within
    ``_MISMATCH * log(1/lam)`` radians of the polar angles of the g_k: the connection chains
    then have slope <= _MISMATCH in log-polar coordinates (angle change <= ~9°).
    When even the uncapped tree (leaves follow the crosscut as closely as the dyadic angles and
    the minimum refinement allow) misses by more, the bound is its mismatch + 1°. The uncapped
    tree is the fallback (the only candidate when no cap changes anything).
    """
    psi_l = np.asarray(psi, dtype=float).tolist()
    full = _build_tree(psi_l, m, alpha, None)[0]
    # The uncapped tree cannot always follow the crosscut either (every chord needs at least
    # one refinement): a capped tree within 1° of its mismatch is as good for the connection.
    limit = max(_MISMATCH * math.log(1.0 / lam), _mismatch(full, psi_l, alpha) + math.radians(1.0))
    depth = max(2, math.ceil(math.log2((len(psi) - 1) / m)))
    while True:
        roots, changed = _build_tree(psi_l, m, alpha, depth)
        if not changed:
            break
        if _mismatch(roots, psi_l, alpha) <= limit:
            yield roots
            break
        depth += 1
    yield full


def _mismatch(roots: list[_Node], psi: list[float], alpha: float) -> float:
    """Largest |polar angle of s_k - polar angle of g_k| (radians) of a tree's outer vertices."""
    bounds = _leaf_bounds(roots)
    return max(abs(alpha * (n / _ONE) - p) for n, p in zip(bounds[:-1], psi))


# Radius ids of a sector template (unit frame, r0 = 1): r0, the Mesh 1 radii s and r0 / 2, then
# five per level j >= 1 (see _level_radius_ids). Vertices are keyed by (ray, radius); two ids
# whose radii are the same float are one radius (see _canonical), as for keys by value.
_R0, _RS, _RH = 0, 1, 2


def _level_radius_ids(j: int) -> tuple[int, tuple[int, int, int], tuple[int, int], int]:
    """Radius ids of level j >= 1: r_j, the 3-set (P, P1, rho2), the 2-set (R, rho2), r_{j+1}."""
    base = 3 + 5 * (j - 1)
    inner = _R0 if j == 1 else base - 1
    return inner, (base, base + 1, base + 2), (base + 3, base + 2), base + 4


def _radii(
    alpha: float, n_levels: int
) -> tuple[list[float], list[float], list[dict[str, complex]]]:
    """Radii of a sector by radius id, each level's inner radius r_j (j = 1..n_levels, then the
    outer radius) and each level's Mesh 2 points (inner radius 1); raises ThinPartError when a
    level's Mesh 2 degenerates."""
    r0 = 1.0
    th1 = 120.0 - math.degrees(alpha) / 2.0
    s_rad = 0.5 * r0 * math.sin(math.radians(60.0)) / math.sin(math.radians(th1))
    vals = [r0, s_rad, 0.5 * r0]
    inner = [r0]
    pts: list[dict[str, complex]] = []
    r_j = r0
    for j in range(1, n_levels + 1):
        loc = mesh2_local(alpha / (1 << j))
        s3, s2 = loc["set3"], loc["set2"]
        r_next = r_j * loc["r2"]  # type: ignore[operator]
        vals += [r_j * s3[0], r_j * s3[1], r_j * s3[2], r_j * s2[0], r_next]  # type: ignore[index]
        pts.append(loc["points"])  # type: ignore[arg-type]
        r_j = r_next
        inner.append(r_j)
    return vals, inner, pts


def _canonical(vals: list[float]) -> tuple[int, ...] | None:
    """For every radius id the first id with the same float radius; None when all differ."""
    first: dict[float, int] = {}
    canon = tuple(first.setdefault(x, i) for i, x in enumerate(vals))
    return None if len(first) == len(vals) else canon


class _Template:
    """Vertex numbering, quads and kinds of Mesh 1 and the levels of Mesh 2 / plain strips.

    They depend only on the refinement tree's shape (its leaf bounds and m) and on which radius
    ids coincide as floats, so one template serves every sector with that shape. Vertex 0 is the
    apex; ray vertex ``ray_vertex[i]`` lies at radius id ``ray_r[i]`` on the ray of dyadic angle
    ``ns[ray_n[i]]``; ``points`` are the Mesh 2 points Y and X as (vertex, level, ray id of the
    piece's bisector, name, reflected). ``side1``/``side2`` hold (radius id, vertex) of the
    vertices on the sides in the order made, ``outer`` the P outer vertices (the leaf bounds at
    the last radius), ``leaf_frac`` the leaf bounds in units of alpha. ``conformity`` caches
    the check of :func:`_verify` (unpaired edges, duplicate edge) per connection ring count.
    """

    __slots__ = (
        "conformity",
        "kind",
        "leaf_frac",
        "n_leaves",
        "n_vertices",
        "ns",
        "outer",
        "points",
        "quads",
        "ray_n",
        "ray_r",
        "ray_vertex",
        "side1",
        "side2",
    )


_TEMPLATES: dict[tuple, _Template] = {}
_TEMPLATE_CACHE_SIZE = 512


def _template(
    roots: list[_Node], bounds: list[int], m: int, n_levels: int, canon: tuple[int, ...] | None
) -> _Template:
    """The template of a tree with leaf bounds ``bounds`` (cached by them, m and ``canon``)."""
    key = (m, tuple(bounds), canon)
    tpl = _TEMPLATES.get(key)
    if tpl is None:
        tpl = _build_template(roots, m, n_levels, canon)
        if len(_TEMPLATES) >= _TEMPLATE_CACHE_SIZE:
            _TEMPLATES.clear()  # one step, also with meshes in other threads
        _TEMPLATES[key] = tpl
    return tpl


def _build_template(
    roots: list[_Node], m: int, n_levels: int, canon: tuple[int, ...] | None
) -> _Template:
    """Mesh 1 in each subsector, then level by level a Mesh 2 piece on every refined chord and
    a plain strip on every other one (see the module docstring), on radius ids."""
    n_top = m * _ONE
    keys: dict[tuple[int, int], int] = {}
    n_ids: dict[int, int] = {}
    ray_vertex: list[int] = []
    ray_n: list[int] = []
    ray_r: list[int] = []
    sides: dict[int, list[tuple[int, int]]] = {0: [], n_top: []}
    points: list[tuple[int, int, int, str, bool]] = []
    quads: list[tuple[int, ...]] = []
    kind: list[int] = []
    count = 1  # vertex 0 is the apex

    def ray(n: int, rid: int) -> int:
        nonlocal count
        key = (n, rid if canon is None else canon[rid])
        idx = keys.get(key)
        if idx is None:
            idx = keys[key] = count
            count += 1
            ray_vertex.append(idx)
            ray_n.append(n_ids.setdefault(n, len(n_ids)))
            ray_r.append(rid)
            side = sides.get(n)
            if side is not None:
                side.append((rid, idx))
        return idx

    # Mesh 1 (paper figure "Mesh 1") in each subsector.
    for root in roots:
        lo, hi = root.lo, root.hi
        mid_n = (lo + hi) // 2
        a_p, b_p = ray(lo, _RS), ray(hi, _RS)
        c_p = ray(mid_n, _RH)
        a_o, m_o, b_o = ray(lo, _R0), ray(mid_n, _R0), ray(hi, _R0)
        quads += [(0, a_p, c_p, b_p), (a_p, a_o, m_o, c_p), (c_p, m_o, b_o, b_p)]
        kind += [KIND_MESH1] * 3

    # Levels of Mesh 2 / plain strips.
    frontier: list[_Node] = []
    for root in roots:
        assert root.kids is not None
        frontier.extend(root.kids)
    j = 1
    while any(nd.kids is not None for nd in frontier):
        r_in, set3, set2, r_out = _level_radius_ids(j)
        set_r = {3: set3, 2: set2}
        # The set carried before the first Mesh 2 piece is free (the whole orientation pattern
        # may be mirrored); pick the one that gives the plain strips fewer cells.
        plain = [0, 0]  # plain strips after an even / odd number of Mesh 2 pieces
        n_refined = 0
        for nd in frontier:
            if nd.kids is None:
                plain[n_refined % 2] += 1
            else:
                n_refined += 1
        cur = 2 if plain[0] >= plain[1] else 3
        nxt: list[_Node] = []
        for nd in frontier:
            if nd.kids is None:
                # a plain strip: quads (lo r_k, lo r_k+1, hi r_k+1, hi r_k), its vertices made
                # in that order (a quad's first and last are the previous quad's second and
                # third)
                radii = (r_in, *set_r[cur], r_out)
                lo_n, hi_n = nd.lo, nd.hi
                a0 = ray(lo_n, radii[0])
                b0 = -1
                for k in range(1, len(radii)):
                    a1 = ray(lo_n, radii[k])
                    b1 = ray(hi_n, radii[k])
                    if b0 < 0:
                        b0 = ray(hi_n, radii[0])
                    quads.append((a0, a1, b1, b0))
                    a0, b0 = a1, b1
                kind.extend([KIND_STRIP] * (len(radii) - 1))
                nxt.append(nd)
                continue
            if nd.depth != j:
                raise ThinPartError("internal: refinement tree level mismatch")
            reflected = cur == 2
            ray_r_n, ray_l_n = (nd.hi, nd.lo) if reflected else (nd.lo, nd.hi)
            mid_n = (nd.lo + nd.hi) // 2
            ids = {
                "A_L": ray(ray_l_n, r_in),
                "A_R": ray(ray_r_n, r_in),
                "R": ray(ray_l_n, set2[0]),
                "R2": ray(ray_l_n, set2[1]),
                "P": ray(ray_r_n, set3[0]),
                "P1": ray(ray_r_n, set3[1]),
                "P2": ray(ray_r_n, set3[2]),
                "B_L": ray(ray_l_n, r_out),
                "B_R": ray(ray_r_n, r_out),
                "B_M": ray(mid_n, r_out),
            }
            for name in ("Y", "X"):
                ids[name] = count
                points.append((count, j, n_ids.setdefault(mid_n, len(n_ids)), name, reflected))
                count += 1
            for q in _MESH2_QUADS:
                idx = tuple(ids[p] for p in q)
                quads.append(idx[::-1] if reflected else idx)
                kind.append(KIND_MESH2)
            cur = 5 - cur
            nxt.extend(nd.kids)
        frontier = nxt
        j += 1
    assert j - 1 == n_levels

    bounds = [nd.lo for nd in frontier] + [frontier[-1].hi]
    r_last = _R0 if n_levels == 0 else _level_radius_ids(n_levels)[3]
    outer = [ray(n, r_last) for n in bounds]
    tpl = _Template()
    tpl.n_vertices = count
    tpl.n_leaves = len(bounds) - 1
    tpl.quads = np.array(quads, dtype=np.int64).reshape(-1, 4)
    tpl.kind = np.array(kind, dtype=np.uint8)
    tpl.ray_vertex = np.array(ray_vertex, dtype=np.int64)
    tpl.ray_n = np.array(ray_n, dtype=np.int64)
    tpl.ray_r = np.array(ray_r, dtype=np.int64)
    tpl.ns = tuple(n_ids)
    tpl.points = tuple(points)
    tpl.side1 = tuple(sides[0])
    tpl.side2 = tuple(sides[n_top])
    tpl.outer = np.array(outer, dtype=np.int64)
    tpl.leaf_frac = np.array(bounds, dtype=float) / _ONE
    for arr in (
        tpl.quads,
        tpl.kind,
        tpl.ray_vertex,
        tpl.ray_n,
        tpl.ray_r,
        tpl.outer,
        tpl.leaf_frac,
    ):
        arr.flags.writeable = False
    tpl.conformity = {}
    return tpl


def _polar_angles(gamma: np.ndarray, v: complex, u1: complex) -> np.ndarray:
    ang = np.angle((gamma - v) / u1)
    ang = np.where(ang < -1e-6, ang + 2.0 * np.pi, ang)
    ang[0] = 0.0
    return ang


def mesh_vertex_sector(
    apex: complex,
    side1_dir: complex,
    theta: float,
    gamma: np.ndarray,
    *,
    lam: float = 0.25,
    max_tilt_deg: float = 20.0,
    grow: bool = True,
) -> ThinMesh:
    """Quad-mesh the region between polygon vertex ``apex`` and the crosscut ``gamma``.

    The region lies counter-clockwise from side 1 (direction ``side1_dir``, the polygon's outgoing
    edge at the apex) through the interior angle ``theta`` (radians, in (0, 2π)) to side 2;
    ``gamma`` holds the crosscut vertices g_0..g_{P-1} from side 1 to side 2 (g_0 on side 1,
    g_{P-1} on side 2). Every g_k is used unchanged; new vertices lie inside the region or on the
    two sides. All new angles are in [60°, 120°] (the apex angle is the original one when
    theta < 120°). ``lam`` is the sector radius relative to min|g_k - v| (shrunk automatically
    when the connection zone needs it); ``max_tilt_deg`` bounds the angle between a crosscut
    chord and the circle about the apex (measured: 20° still meshes fine sweep used
    <= 9°). ``grow``: a sector accepted at ``lam`` is built larger where its connection
    allows it with no more quads (:data:`_LAM_GROW`); off where the radius must be ``lam``
    exactly (a corridor's cores, whose points other cells carry). Paper: section "Meshing the
    thin parts" with the refinement-tree schedule and connection rings described in this
    module's docstring.

    Raises:
        ThinPartError: P < 4m + 1, gamma not ordered around the apex or not ending on the sides,
            a gamma chord tilted by more than ``max_tilt_deg`` from the circle direction, or a
            produced angle outside [60°, 120°].
    """
    g = np.asarray(gamma, dtype=np.complex128).ravel()
    v = complex(apex)
    n_pts = len(g)
    if not (0.0 < theta < 2.0 * math.pi):
        raise ThinPartError(f"vertex angle {theta!r} is not in (0, 2π)")
    if not (0.0 < lam < 1.0):
        raise ThinPartError(f"sector ratio lam = {lam} must lie in (0, 1)")
    m = split_count(theta)
    if n_pts < 4 * m + 1:
        raise ThinPartError(
            f"crosscut has {n_pts} vertices; a vertex angle of {math.degrees(theta):.1f} deg "
            f"(m = {m}) needs at least {4 * m + 1}"
        )
    if not np.all(np.isfinite(g)):
        raise ThinPartError("crosscut has non-finite vertices")
    d0, d1 = g[0] - v, g[-1] - v
    if abs(d0) == 0.0 or abs(d1) == 0.0 or abs(side1_dir) == 0.0:
        raise ThinPartError("crosscut endpoint at the apex or zero side direction")
    u1 = d0 / abs(d0)
    u2 = d1 / abs(d1)
    if abs(np.angle(u1 / (side1_dir / abs(side1_dir)))) > 1e-6:
        raise ThinPartError("g_0 does not lie on side 1")
    psi = _polar_angles(g, v, u1)
    theta_eff = float(psi[-1])
    if abs(theta_eff - theta) > 1e-6:
        raise ThinPartError(
            f"g_{{P-1}} does not lie on side 2 (its angle is {math.degrees(theta_eff):.6f} deg, "
            f"theta is {math.degrees(theta):.6f} deg)"
        )
    if np.any(np.diff(psi) <= 0.0):
        raise ThinPartError("crosscut vertices are not in increasing polar angle about the apex")
    rad = np.abs(g - v)
    mid = 0.5 * (g[1:] + g[:-1]) - v
    tilt = np.degrees(np.abs(np.angle(np.diff(g) / (1j * mid))))
    if tilt.max() > max_tilt_deg:
        k = int(np.argmax(tilt))
        raise ThinPartError(
            f"crosscut chord {k} is tilted {tilt[k]:.1f} deg from the circle direction "
            f"(limit {max_tilt_deg:g}); the crosscut is not round enough at the scale of its chords"
        )

    alpha = theta_eff / m
    first: ThinPartError | None = None
    for roots in _trees(psi, m, alpha, lam):
        try:
            return _sector_from_tree(roots, v, u1, u2, g, psi, rad, m, alpha, theta_eff, lam, grow)
        except ThinPartError as exc:
            first = first or exc
    assert first is not None
    raise first


def _sector_from_tree(
    roots: list[_Node],
    v: complex,
    u1: complex,
    u2: complex,
    g: np.ndarray,
    psi: np.ndarray,
    rad: np.ndarray,
    m: int,
    alpha: float,
    theta_eff: float,
    lam: float,
    grow: bool = True,
) -> ThinMesh:
    """Mesh 1, the levels of Mesh 2 / plain strips of the tree, and the connection zone.

    The tree part comes from the tree's :class:`_Template` (the vertex numbering and quads of
    its shape); here its vertices are placed: ray vertex rho * e^{i angle} in the unit frame
    (r0 = 1), Mesh 2 points Y, X rotated onto their piece's bisector.
    """
    n_pts = len(g)
    n_top = m * _ONE
    bounds, depth = _leaves(roots)
    vals, inner, level_pts = _radii(alpha, depth - 1)
    tpl = _template(roots, bounds, m, depth - 1, _canonical(vals))
    if tpl.n_leaves != n_pts - 1:
        raise ThinPartError("internal: refinement tree does not have P - 1 leaves")
    dirs = [
        complex(math.cos(a), math.sin(a))
        for a in (theta_eff if n == n_top else alpha * (n / _ONE) for n in tpl.ns)
    ]
    zu = np.empty(tpl.n_vertices, dtype=np.complex128)
    zu[0] = 0j  # the apex
    zu[tpl.ray_vertex] = np.array(vals)[tpl.ray_r] * np.array(dirs)[tpl.ray_n]
    if tpl.points:
        pz = []
        for _, j, mid, name, reflected in tpl.points:
            zl = level_pts[j - 1][name]
            if reflected:
                zl = -zl.conjugate()
            pz.append(inner[j - 1] * zl * (dirs[mid] * (-1j)))
        zu[[p[0] for p in tpl.points]] = pz
    apex_i = 0
    r_j = inner[-1]
    outer = tpl.outer
    side1_r = sorted((vals[rid], i) for rid, i in tpl.side1)
    side2_r = sorted((vals[rid], i) for rid, i in tpl.side2)
    n_base = len(zu)
    g_idx = np.arange(n_base, n_base + n_pts)
    y_s = alpha * tpl.leaf_frac
    y_s[-1] = theta_eff
    w_g = np.log(rad) + 1j * psi

    # Connection zone (figure "Same-Sector"): chains from s_k to g_k, straight (J = 0) or, when
    # the angular mismatch between s_k and g_k is too large for straight segments, log-spiral
    # chains through J intermediate rings (the channel construction of the hyperbolic thin part
    # applied to
    # the annular sector). If no J works, the sector is shrunk (smaller lam), which lengthens
    # the annulus in log coordinates and flattens the spirals.
    attempts: list[str] = []
    found = None
    best_dev = math.inf
    side1_i = [i for _, i in side1_r]
    side1_rho = np.array([r for r, _ in side1_r])
    side2_i = [i for _, i in side2_r]
    side2_rho = np.array([r for r, _ in side2_r])
    rad_min = float(rad.min())
    g_rel = (g - v)[None, :]

    def place(lam_try: float) -> tuple[np.ndarray, np.ndarray]:
        scale = lam_try * rad_min / r_j
        base = v + scale * u1 * zu
        # Put the side vertices exactly on the segments v-g_0 and v-g_{P-1}.
        base[side1_i] = v + scale * side1_rho * u1
        base[side2_i] = v + scale * side2_rho * u2
        base[apex_i] = v
        return base, math.log(scale * r_j) + 1j * y_s

    def candidates(base: np.ndarray, w_s: np.ndarray):
        outer_rel = (base[outer] - v)[None, :]
        return _connection_candidates(v, u1, u2, w_s, w_g, outer_rel, g_rel)

    rings_used = -1
    for lam_try in lam * _LAM_FACTORS:
        checkpoint()
        base, w_s = place(lam_try)
        lam_dev = math.inf
        for ring, dev in candidates(base, w_s):
            lam_dev = min(lam_dev, dev)
            if dev < best_dev:
                best_dev = dev
                found = (base, ring)
            if dev <= _GOOD_DEVIATION:
                break
        if best_dev <= _GOOD_DEVIATION:
            rings_used = len(found[1]) if lam_try == lam else -1
            break
        attempts.append(f"lam {lam_try:.3g}: max |angle - 90| = {lam_dev:.1f}")
    # a sector accepted at ``lam`` grows while its connection needs no more rings (so no more
    # quads): every tree quad, the smallest ones at the apex included, grows with it
    grown = None
    for factor in _LAM_GROW if grow and rings_used >= 0 else ():
        if lam * factor > _LAM_GROWN_MAX:
            continue
        base, w_s = place(lam * factor)
        for ring, dev in candidates(base, w_s):
            if len(ring) > rings_used:
                break
            if dev <= _GOOD_DEVIATION:
                grown = (base, ring)
                break
        if grown is not None:
            break
    if grown is not None:
        try:
            return _sector_mesh(grown, tpl, g, g_idx, outer, side1_i, side2_i, m, n_pts, v)
        except ThinPartError:  # the sector at ``lam`` below (never measured to happen)
            pass
    if best_dev > 30.0:
        found = None
    if found is None:
        gap = math.degrees(float(np.diff(psi).max()))
        raise ThinPartError(
            "connection quads between the sector and the crosscut leave [60, 120] degrees "
            f"(up to {_CONNECTION_RINGS[-1]} rings; {'; '.join(attempts)}); the largest "
            f"angular gap of the crosscut is {gap:.1f} deg against outer sector chords of at "
            f"most {math.degrees(alpha) / 4:.1f} deg: the crosscut needs more vertices"
        )
    return _sector_mesh(found, tpl, g, g_idx, outer, side1_i, side2_i, m, n_pts, v)


def _sector_mesh(
    found: tuple[np.ndarray, np.ndarray],
    tpl: _Template,
    g: np.ndarray,
    g_idx: np.ndarray,
    outer: np.ndarray,
    side1_i: list[int],
    side2_i: list[int],
    m: int,
    n_pts: int,
    v: complex,
) -> ThinMesh:
    """The sector of :func:`_sector_from_tree` from its placed tree vertices and connection
    rings ``found``: the tree's quads, the connection quads, checked (:func:`_verify`)."""
    apex_i = 0
    base, ring = found
    verts = np.concatenate([base, g, ring.ravel()])
    cq, grid = _connection_quads(outer, g_idx, len(ring))

    s1 = np.concatenate([[apex_i], side1_i, grid[1:, 0]]).astype(np.int64)
    s2 = np.concatenate([[apex_i], side2_i, grid[1:, -1]]).astype(np.int64)
    mesh = ThinMesh(
        vertices=verts,
        quads=np.concatenate([tpl.quads, cq]),
        kind=np.concatenate([tpl.kind, np.full(len(cq), KIND_CONNECTION, np.uint8)]),
        gamma_index=g_idx,
        apex_index=apex_i,
        side1=s1,
        side2=s2,
        exempt_apex=(m == 1),
    )
    _verify(mesh, n_pts, v, tpl.conformity, len(ring))
    return mesh


_CONNECTION_RINGS = (0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32)
_LAM_FACTORS = np.array([1.0, 0.4, 0.16, 0.064])
#: Factors of ``lam`` tried, largest first, for a sector accepted at ``lam`` itself: the first
#: whose connection quads stay in [65°, 115°] (as at ``lam``) with no more rings is used. A
#: larger sector shortens the connection in log-polar coordinates, so its chains tilt more
#: than the depth-capped tree's slope bound allows at ``lam`` (connection angles measured in
#: [69°, 111°] instead of [75°, 105°] on a graded crosscut), for every tree quad larger by the
#: factor: on the bundled examples the smallest edge / local feature size up to 2.4× larger
#: and 10–90 % fewer edges below 1/1000 of it, with the same or fewer quads.
_LAM_GROW = (2.4, 1.6)
#: ... never beyond this sector ratio (the largest the sweeps measured with good connections)
_LAM_GROWN_MAX = 0.6
_GOOD_DEVIATION = 25.0  # accept the first ring count with connection angles in [65, 115]


def _rings(
    v: complex, u1: complex, u2: complex, w_s: np.ndarray, w_g: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """Ring vertices of the connection zone at the parameters ``t`` (a column).

    ``w_s``/``w_g`` are log-polar coordinates (log radius + i angle from side 1) of the outer
    sector vertices and of the crosscut vertices; chain k is the segment from w_s[k] to w_g[k]
    in these coordinates; J rings sample it at t = 1/(J+1), ..., J/(J+1) (a log spiral).
    """
    w = (1.0 - t) * w_s[None, :] + t * w_g[None, :]
    ring = v + u1 * np.exp(w)
    ring[:, 0] = v + u1 * np.exp(w[:, 0].real)
    ring[:, -1] = v + u2 * np.exp(w[:, -1].real)
    return ring


@functools.lru_cache(maxsize=16)
def _ring_batch(n_pts: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, ...]]:
    """All ring counts J > 0 of ``_CONNECTION_RINGS`` at once: the ring parameters t (a
    column, J by J), the corners (4, Q) of the quads of every J's grid as flat indices into
    the rows [outer sector vertices, crosscut, rings of every J] (as in
    :func:`_connection_quads`), the first quad of every grid and the first ring row of every J.
    """
    t, corners, first_quad, first_ring = [], [], [], []
    quad, row = 0, 2
    for n_rings in _CONNECTION_RINGS[1:]:
        t.append(np.arange(1, n_rings + 1)[:, None] / (n_rings + 1))
        rows = np.array([0, *range(row, row + n_rings), 1])
        k = rows[:, None] * n_pts + np.arange(n_pts)[None, :]
        corners.append(np.stack([k[:-1, :-1], k[1:, :-1], k[1:, 1:], k[:-1, 1:]]).reshape(4, -1))
        first_quad.append(quad)
        first_ring.append(row - 2)
        quad += (n_rings + 1) * (n_pts - 1)
        row += n_rings
    out = (np.concatenate(t), np.concatenate(corners, axis=1), np.array(first_quad))
    for arr in out:
        arr.flags.writeable = False
    return (*out, tuple(first_ring))


def _connection_candidates(
    v: complex,
    u1: complex,
    u2: complex,
    w_s: np.ndarray,
    w_g: np.ndarray,
    outer_rel: np.ndarray,
    g_rel: np.ndarray,
) -> Iterator[tuple[np.ndarray, float]]:
    """The (J, P) rings and the largest |angle - 90°| of the connection quads for J =
    ``_CONNECTION_RINGS`` in turn: straight chains (J = 0) first, then, if asked for more,
    every J > 0 computed in one pass. Angles are taken about the apex: ``outer_rel`` and
    ``g_rel`` are the outer sector vertices and the crosscut minus v (rows of one)."""
    n_pts = g_rel.shape[1]
    straight = np.concatenate([outer_rel, g_rel])
    yield (
        np.empty((0, n_pts), np.complex128),
        _grid_deviations(straight, _grid_corners(2, n_pts))[0],
    )
    t, corners, first_quad, first_ring = _ring_batch(n_pts)
    ring = _rings(v, u1, u2, w_s, w_g, t)
    devs = _grid_deviations(np.concatenate([outer_rel, g_rel, ring - v]), corners, first_quad)
    for n_rings, row, dev in zip(_CONNECTION_RINGS[1:], first_ring, devs):
        yield ring[row : row + n_rings], dev


def _connection_quads(
    outer: np.ndarray, g_idx: np.ndarray, n_rings: int
) -> tuple[np.ndarray, np.ndarray]:
    """Quads and the (J+2, P) index grid of the connection zone: rows the outer sector
    vertices, the J rings (numbered after the crosscut vertices) and the crosscut."""
    n_pts = len(g_idx)
    first = int(g_idx[-1]) + 1
    ring_idx = first + np.arange(n_rings * n_pts).reshape(n_rings, n_pts)
    grid = np.vstack([outer[None, :], ring_idx, g_idx[None, :]])
    quads = np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1)
    return quads.reshape(-1, 4), grid


@functools.lru_cache(maxsize=64)
def _grid_corners(rows: int, cols: int) -> np.ndarray:
    """(4, Q) flat indices of the corners a, b, c, d of the quads of a (rows, cols) grid,
    quad (z[j,k], z[j+1,k], z[j+1,k+1], z[j,k+1]) as in :func:`_connection_quads`."""
    k = np.arange(rows * cols).reshape(rows, cols)
    idx = np.stack([k[:-1, :-1], k[1:, :-1], k[1:, 1:], k[:-1, 1:]]).reshape(4, -1)
    idx.flags.writeable = False
    return idx


_NEXT4 = [1, 2, 3, 0]
_PREV4 = [3, 0, 1, 2]


def _grid_deviations(
    z: np.ndarray, corners: np.ndarray, first_quad: np.ndarray | None = None
) -> list[float]:
    """Largest |angle - 90°| (degrees) over the quads of vertex grids, one per grid.

    ``corners`` (4, Q) are the flat indices into ``z`` of the quads' corners a, b, c, d, quad
    (z[j,k], z[j+1,k], z[j+1,k+1], z[j,k+1]) of a grid as in :func:`_connection_quads`; the
    grids' quads start at ``first_quad`` (one grid when None). Corner angles are taken in
    [0°, 360°); a result <= 90° means every quad is convex and counter-clockwise (four angles
    below 180° sum to 360° only for a simple convex counter-clockwise quad), so no separate
    area test is needed. (A NaN angle, of a degenerate quad, drops the corners of its kind out
    of its grid's maximum, as Python's ``max`` skips NaN.)
    """
    c = z.ravel()[corners]
    e = c[_NEXT4] - c  # edges ab, bc, cd, da
    # at corner a the angle from ab to -da, at b from bc to -ab, and so on
    dev = np.abs(np.mod(np.angle(-e[_PREV4] / e), 2.0 * math.pi) - 0.5 * math.pi)
    if first_quad is None:
        per_grid = dev.max(axis=1)[:, None]
    else:
        per_grid = np.maximum.reduceat(dev, first_quad, axis=1)
    out = []
    for grid in per_grid.T.tolist():
        worst = 0.0
        for corner in grid:
            worst = max(worst, corner)
        out.append(math.degrees(worst))
    return out


def _verify(
    mesh: ThinMesh,
    n_pts: int,
    v: complex,
    conformity: dict[int, tuple[int, bool]] | None = None,
    n_rings: int = 0,
) -> None:
    """Conformity and angle checks before returning.

    Areas and angles are computed from the returned coordinates taken relative to the apex
    (an exact translation for nearby floats), so a sector that is tiny compared with its
    distance from the origin is judged by its own geometry, not by cancellation in the
    shoelace sum. The angle check has the pipeline's tolerance (1e-6°); when it fails only
    because of the rounding of the absolute coordinates, the message says so.
    """
    found = None if conformity is None else conformity.get(n_rings)
    if found is None:
        free, ok = unpaired_edges(mesh.quads)
        found = (len(free), ok)
        if conformity is not None:
            conformity[n_rings] = found
    n_free, ok = found
    expected = (len(mesh.side1) - 1) + (len(mesh.side2) - 1) + (n_pts - 1)
    if not ok or n_free != expected:
        raise ThinPartError(
            f"internal: sector mesh not conforming ({n_free} boundary edges, {expected} expected)"
        )
    rel = mesh.vertices - v
    try:
        require_angles(
            rel,
            mesh.quads,
            mesh.new_angle_mask(),
            60.0,
            120.0,
            "vertex sector mesh",
            coord_scale=abs(v),
        )
    except ThinPartError as exc:
        # Rounding of v + offset perturbs the exact 60°/120° angles of Mesh 1 / Mesh 2 by about
        # 4 ulp(|v|) / (shortest edge of the quad) radians; say so when that explains the miss.
        ang = quad_angles_deg(rel, mesh.quads)
        excess = np.maximum(60.0 - ang, ang - 120.0).max(axis=1)
        worst = int(np.argmax(excess))
        z = rel[mesh.quads[worst]]
        h = float(np.abs(z - np.roll(z, -1)).min())
        ulp = float(np.spacing(max(abs(v.real), abs(v.imag), 1e-300)))
        noise = math.degrees(4.0 * ulp / h) if h > 0.0 else math.inf
        if not 1e-6 < excess[worst] <= noise:
            raise
        raise ThinPartError(
            f"{exc.args[0]}; the worst quad's shortest edge is {h:.3g} at coordinates of size "
            f"{abs(v):.3g}, where rounding alone moves its exact 60/120 degree angles by up to "
            f"~{noise:.1g} degrees: the crosscut is too close to the vertex for double precision"
        ) from exc
