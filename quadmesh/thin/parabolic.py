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
"""

from __future__ import annotations

import bisect
import math
import operator
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
    quads = (
        ("A_L", "A_R", "P", "R"),
        ("R", "P", "P1", "Y"),
        ("R", "Y", "X", "R2"),
        ("Y", "P1", "P2", "X"),
        ("R2", "X", "B_M", "B_L"),
        ("X", "P2", "B_R", "B_M"),
    )
    return {
        "points": pts,
        "set3": (r_p, r_p1, rho2),
        "set2": (r_r, rho2),
        "r2": r2,
        "quads": quads,
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
    j0 = min(max(k - 1, lo_i), hi_i)
    j1 = min(max(k, lo_i), hi_i)
    return j0 if abs(psi[j0] - ang) <= abs(psi[j1] - ang) else j1


def _build_tree(
    psi: np.ndarray, m: int, alpha: float, depth_cap: int | None
) -> tuple[list[_Node], bool]:
    """Refinement tree (roots = the m subsectors) whose leaves match the crosscut angles.

    Each node is split at its dyadic mid-angle; the crosscut vertex assigned to that boundary is
    the one nearest in polar angle that leaves room on both sides: at least the minimum
    refinement (every Mesh 1 chord is refined at least once) and, with ``depth_cap`` = D, at most
    2**(D - depth) leaves under a node of the given depth, so that no leaf is deeper than D.
    Returns the roots and whether the cap changed any choice (else the tree is the uncapped one).
    """
    p1 = len(psi) - 1
    psi = np.asarray(psi, dtype=float).tolist()  # scalar look-ups: a list is much faster
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
            room = max(min_child, n - (1 << (cap - nd.depth - 1)))
            if room > min_child:
                capped = _nearest(psi, ang, nd.ia + room, nd.ib - room)
                changed |= capped != ic
                ic = capped
        left = _Node(nd.depth + 1, nd.lo, mid, nd.ia, ic)
        right = _Node(nd.depth + 1, mid, nd.hi, ic, nd.ib)
        nd.kids = (left, right)
        stack.extend((left, right))
    return roots, changed


def _leaf_bounds(roots: list[_Node]) -> list[int]:
    """Dyadic angles (units alpha / 2**_K) of the leaf boundaries, from side 1 to side 2."""
    out: list[int] = []
    stack = list(reversed(roots))
    while stack:
        nd = stack.pop()
        if nd.kids is None:
            out.append(nd.lo)
        else:
            stack.extend((nd.kids[1], nd.kids[0]))
    out.append(roots[-1].hi)
    return out


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
    full = _build_tree(psi, m, alpha, None)[0]
    # The uncapped tree cannot always follow the crosscut either (every chord needs at least
    # one refinement): a capped tree within 1° of its mismatch is as good for the connection.
    limit = max(_MISMATCH * math.log(1.0 / lam), _mismatch(full, psi, alpha) + math.radians(1.0))
    depth = max(2, math.ceil(math.log2((len(psi) - 1) / m)))
    while True:
        roots, changed = _build_tree(psi, m, alpha, depth)
        if not changed:
            break
        if _mismatch(roots, psi, alpha) <= limit:
            yield roots
            break
        depth += 1
    yield full


def _mismatch(roots: list[_Node], psi: np.ndarray, alpha: float) -> float:
    """Largest |polar angle of s_k - polar angle of g_k| (radians) of a tree's outer vertices."""
    y = alpha * (np.array(_leaf_bounds(roots), dtype=float) / _ONE)
    return float(np.abs(y[:-1] - psi[:-1]).max())


class _Builder:
    """Vertex registry (exact sharing by key) and quad list in the unit frame."""

    def __init__(self, alpha: float, n_top: int, theta: float) -> None:
        self.alpha, self.n_top, self.theta = alpha, n_top, theta
        self.keys: dict[tuple, int] = {}
        self.rays: dict[tuple[int, float], int] = {}  # (n, rho) -> index
        self.z: list[complex] = []
        self.quads: list[tuple[int, int, int, int]] = []
        self.kind: list[int] = []
        self.dirs: dict[int, complex] = {}
        # (radius, index) of the vertices on side 1 (n = 0) and side 2 (n = n_top)
        self.sides: dict[int, list[tuple[float, int]]] = {0: [], n_top: []}

    def ray_dir(self, n: int) -> complex:
        u = self.dirs.get(n)
        if u is None:
            a = self.theta if n == self.n_top else self.alpha * (n / _ONE)
            u = self.dirs[n] = complex(math.cos(a), math.sin(a))
        return u

    def ray(self, n: int, rho: float) -> int:
        key = (n, rho)
        idx = self.rays.get(key)
        if idx is None:
            idx = len(self.z)
            self.rays[key] = idx
            self.z.append(rho * self.ray_dir(n))
            side = self.sides.get(n)
            if side is not None:
                side.append((rho, idx))
        return idx

    def point(self, key: tuple, z: complex) -> int:
        idx = len(self.z)
        self.keys[key] = idx
        self.z.append(z)
        return idx

    def quad(self, q: tuple[int, int, int, int], kind: int) -> None:
        self.quads.append(q)
        self.kind.append(kind)


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
    <= 9°). Paper: section "Meshing the thin parts" with the refinement-tree
    schedule and connection rings described in this module's docstring.

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
            return _sector_from_tree(roots, v, u1, u2, g, psi, rad, m, alpha, theta_eff, lam)
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
) -> ThinMesh:
    """Mesh 1, the levels of Mesh 2 / plain strips of the tree, and the connection zone."""
    n_pts = len(g)
    n_top = m * _ONE
    b = _Builder(alpha, n_top, theta_eff)

    # Mesh 1 (paper figure "Mesh 1") in each subsector, r0 = 1.
    r0 = 1.0
    alpha_deg = math.degrees(alpha)
    th1 = 120.0 - alpha_deg / 2.0
    s_rad = 0.5 * r0 * math.sin(math.radians(60.0)) / math.sin(math.radians(th1))
    apex_i = b.point(("apex",), 0j)
    for root in roots:
        lo, hi = root.lo, root.hi
        mid_n = (lo + hi) // 2
        a_p, b_p = b.ray(lo, s_rad), b.ray(hi, s_rad)
        c_p = b.ray(mid_n, 0.5 * r0)
        a_o, m_o, b_o = b.ray(lo, r0), b.ray(mid_n, r0), b.ray(hi, r0)
        b.quad((apex_i, a_p, c_p, b_p), KIND_MESH1)
        b.quad((a_p, a_o, m_o, c_p), KIND_MESH1)
        b.quad((c_p, m_o, b_o, b_p), KIND_MESH1)

    # Levels of Mesh 2 / plain strips.
    frontier: list[_Node] = []
    for root in roots:
        assert root.kids is not None
        frontier.extend(root.kids)
    r_j = r0
    j = 1
    piece = 0
    while any(nd.kids is not None for nd in frontier):
        phi = alpha / (1 << j)
        loc = mesh2_local(phi)
        set_r = {3: tuple(r_j * x for x in loc["set3"]), 2: tuple(r_j * x for x in loc["set2"])}
        r_next = r_j * loc["r2"]
        pts_loc: dict[str, complex] = loc["points"]  # type: ignore[assignment]
        # the vertex ids of each Mesh 2 quad from the piece's name -> id map
        corners_of = [operator.itemgetter(*q) for q in loc["quads"]]  # type: ignore[union-attr]
        # The set carried before the first Mesh 2 piece is free (the whole orientation pattern
        # may be mirrored); pick the one that gives the plain strips fewer cells.
        refined = np.array([nd.kids is not None for nd in frontier])
        parity = (np.cumsum(refined) - refined) % 2
        plain_even = int(np.sum(~refined & (parity == 0)))
        plain_odd = int(np.sum(~refined & (parity == 1)))
        cur = 2 if plain_even >= plain_odd else 3
        nxt: list[_Node] = []
        ray = b.ray
        for nd in frontier:
            if nd.kids is None:
                # a plain strip: quads (lo r_k, lo r_k+1, hi r_k+1, hi r_k), its vertices made
                # in that order (a quad's first and last are the previous quad's second and
                # third)
                radii = (r_j, *set_r[cur], r_next)
                lo_n, hi_n = nd.lo, nd.hi
                a0 = ray(lo_n, radii[0])
                b0 = -1
                for k in range(1, len(radii)):
                    a1 = ray(lo_n, radii[k])
                    b1 = ray(hi_n, radii[k])
                    if b0 < 0:
                        b0 = ray(hi_n, radii[0])
                    b.quads.append((a0, a1, b1, b0))
                    a0, b0 = a1, b1
                b.kind.extend([KIND_STRIP] * (len(radii) - 1))
                nxt.append(nd)
                continue
            if nd.depth != j:
                raise ThinPartError("internal: refinement tree level mismatch")
            reflected = cur == 2
            ray_r, ray_l = (nd.hi, nd.lo) if reflected else (nd.lo, nd.hi)
            s3, s2 = set_r[3], set_r[2]
            mid_n = (nd.lo + nd.hi) // 2
            rot = b.ray_dir(mid_n) * (-1j)
            ids = {
                "A_L": b.ray(ray_l, r_j),
                "A_R": b.ray(ray_r, r_j),
                "R": b.ray(ray_l, s2[0]),
                "R2": b.ray(ray_l, s2[1]),
                "P": b.ray(ray_r, s3[0]),
                "P1": b.ray(ray_r, s3[1]),
                "P2": b.ray(ray_r, s3[2]),
                "B_L": b.ray(ray_l, r_next),
                "B_R": b.ray(ray_r, r_next),
                "B_M": b.ray(mid_n, r_next),
            }
            for name in ("Y", "X"):
                zl = pts_loc[name]
                if reflected:
                    zl = -zl.conjugate()
                ids[name] = b.point(("p", piece, name), r_j * zl * rot)
            for get in corners_of:
                idx = get(ids)
                b.quad(idx[::-1] if reflected else idx, KIND_MESH2)
            piece += 1
            cur = 5 - cur
            nxt.extend(nd.kids)
        frontier = nxt
        r_j = r_next
        j += 1

    # Outer arc: the P leaf boundaries at radius r_j, scaled to the sector radius.
    bounds = [nd.lo for nd in frontier] + [frontier[-1].hi]
    if len(bounds) != n_pts:
        raise ThinPartError("internal: refinement tree does not have P - 1 leaves")
    outer = np.array([b.ray(n, r_j) for n in bounds], dtype=np.int64)
    side1_r = sorted(b.sides[0])
    side2_r = sorted(b.sides[n_top])
    zu = np.array(b.z, dtype=np.complex128)
    n_base = len(zu)
    g_idx = np.arange(n_base, n_base + n_pts)
    y_s = alpha * (np.array(bounds, dtype=float) / _ONE)
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
    for lam_try in lam * _LAM_FACTORS:
        checkpoint()
        scale = lam_try * float(rad.min()) / r_j
        base = v + scale * u1 * zu
        # Put the side vertices exactly on the segments v-g_0 and v-g_{P-1}.
        base[[i for _, i in side1_r]] = v + scale * np.array([r for r, _ in side1_r]) * u1
        base[[i for _, i in side2_r]] = v + scale * np.array([r for r, _ in side2_r]) * u2
        base[apex_i] = v
        head = np.concatenate([base, g])
        w_s = math.log(scale * r_j) + 1j * y_s
        lam_dev = math.inf
        for n_rings in _CONNECTION_RINGS:
            ring_z, cq, grid = _connection(v, u1, u2, w_s, w_g, outer, g_idx, n_rings)
            verts = np.concatenate([head, ring_z])
            # Angles about the apex (exact translation; see _verify).
            dev = _grid_deviation(verts[grid] - v)
            lam_dev = min(lam_dev, dev)
            if dev < best_dev:
                best_dev = dev
                found = (verts, cq, grid)
            if dev <= _GOOD_DEVIATION:
                break
        if best_dev <= _GOOD_DEVIATION:
            break
        attempts.append(f"lam {lam_try:.3g}: max |angle - 90| = {lam_dev:.1f}")
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
    verts, cq, grid = found

    s1 = np.concatenate([[apex_i], [i for _, i in side1_r], grid[1:, 0]]).astype(np.int64)
    s2 = np.concatenate([[apex_i], [i for _, i in side2_r], grid[1:, -1]]).astype(np.int64)
    mesh = ThinMesh(
        vertices=verts,
        quads=np.concatenate([np.array(b.quads, dtype=np.int64).reshape(-1, 4), cq]),
        kind=np.concatenate(
            [np.array(b.kind, dtype=np.uint8), np.full(len(cq), KIND_CONNECTION, np.uint8)]
        ),
        gamma_index=g_idx,
        apex_index=apex_i,
        side1=s1,
        side2=s2,
        exempt_apex=(m == 1),
    )
    _verify(mesh, n_pts, v)
    return mesh


_CONNECTION_RINGS = (0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32)
_LAM_FACTORS = np.array([1.0, 0.4, 0.16, 0.064])
_GOOD_DEVIATION = 25.0  # accept the first ring count with connection angles in [65, 115]


def _connection(
    v: complex,
    u1: complex,
    u2: complex,
    w_s: np.ndarray,
    w_g: np.ndarray,
    outer: np.ndarray,
    g_idx: np.ndarray,
    n_rings: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ring vertices, quads and the (J+2, P) index grid of the connection zone.

    ``w_s``/``w_g`` are log-polar coordinates (log radius + i angle from side 1) of the outer
    sector vertices and of the crosscut vertices; chain k is the segment from w_s[k] to w_g[k]
    in these coordinates, sampled at J equally spaced intermediate rings (a log spiral).
    """
    n_pts = len(w_s)
    t = np.arange(1, n_rings + 1)[:, None] / (n_rings + 1)
    w = (1.0 - t) * w_s[None, :] + t * w_g[None, :]
    ring = v + u1 * np.exp(w)
    ring[:, 0] = v + u1 * np.exp(w[:, 0].real)
    ring[:, -1] = v + u2 * np.exp(w[:, -1].real)
    first = int(g_idx[-1]) + 1
    ring_idx = first + np.arange(n_rings * n_pts).reshape(n_rings, n_pts)
    grid = np.vstack([outer[None, :], ring_idx, g_idx[None, :]])
    quads = np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1)
    return ring.ravel(), quads.reshape(-1, 4), grid


def _grid_deviation(z: np.ndarray) -> float:
    """Largest |angle - 90°| over the quads of a (rows, P) vertex grid (degrees).

    Quad (z[j,k], z[j+1,k], z[j+1,k+1], z[j,k+1]) as in :func:`_connection`. Corner angles are
    taken in [0°, 360°); a result <= 90° means every quad is convex and counter-clockwise (four
    angles below 180° sum to 360° only for a simple convex counter-clockwise quad), so no
    separate area test is needed.
    """
    a, b, c, d = z[:-1, :-1], z[1:, :-1], z[1:, 1:], z[:-1, 1:]
    ab, bc, cd, da = b - a, c - b, d - c, a - d
    dev = 0.0
    for num, den in ((-da, ab), (-ab, bc), (-bc, cd), (-cd, da)):
        ang = np.mod(np.angle(num / den), 2.0 * math.pi)
        dev = max(dev, float(np.abs(ang - 0.5 * math.pi).max()))
    return math.degrees(dev)


def _verify(mesh: ThinMesh, n_pts: int, v: complex) -> None:
    """Conformity and angle checks before returning.

    Areas and angles are computed from the returned coordinates taken relative to the apex
    (an exact translation for nearby floats), so a sector that is tiny compared with its
    distance from the origin is judged by its own geometry, not by cancellation in the
    shoelace sum. The angle check has the pipeline's tolerance (1e-6°); when it fails only
    because of the rounding of the absolute coordinates, the message says so.
    """
    free, ok = unpaired_edges(mesh.quads)
    expected = (len(mesh.side1) - 1) + (len(mesh.side2) - 1) + (n_pts - 1)
    if not ok or len(free) != expected:
        raise ThinPartError(
            f"internal: sector mesh not conforming ({len(free)} boundary edges, "
            f"{expected} expected)"
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
