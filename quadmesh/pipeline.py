"""The mesher: :func:`mesh_polygon` runs every stage of Bishop's construction.

Stages (ARCHITECTURE.md, "The pipeline"):

1. validate the polygon (:func:`quadmesh.polygon.validate_polygon`);
2. thick/thin decomposition (:func:`quadmesh.decompose.decompose`, paper §7);
3. for each thick piece: the Schwarz–Christoffel map f: D → piece
   (:class:`quadmesh.conformal.DiskMap`), the arcs I_j around its prevertices, the
   region W of Lemma 2.2 and its mesh (Lemmas 4.1, 5.1, 6.1, :func:`quadmesh.disk.disk_mesh`),
   pushed forward through f, with the linear map h(ζ) = g(c) + (ζ − c) g'(c),
   g = f∘τ⁻¹, inside every inner triangle T_i (paper §7);
4. the thin parts meshed explicitly and glued onto the pushed-forward crosscut vertices: a
   vertex sector at every polygon vertex (paper §8, parabolic case) and a log-spiral
   connector across every narrow channel (paper §8, hyperbolic case);
5. one :class:`~quadmesh.mesh.QuadMesh`, verified (:meth:`QuadMesh.check`). A mesh that
   fails verification is never returned: a :class:`~quadmesh.errors.QuadmeshError`
   subclass naming the stage is raised instead.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import (
    Cancelled,
    ConformalMapError,
    DiskConstructionError,
    ThinPartError,
)
from .geometry import quad_angles_deg
from .polygon import Polygon, validate_polygon
from .result import MeshOptions, MeshResult, ThickPieceResult, ThinPartResult

__all__ = ["MeshOptions", "MeshResult", "mesh_polygon"]

ProgressCallback = Callable[[str, float], None]
CancelCallback = Callable[[], bool]

#: n values tried by the adaptive loop, in order (MeshOptions.adaptive).
ADAPTIVE_N = (2, 3, 4, 6, 8)
#: The adaptive loop halves the Carleson depth step down to this value.
MIN_DEPTH_STEP = 0.125
ANGLE_MIN, ANGLE_MAX = 60.0, 120.0
#: Slack on the angle bounds for rounding: angles that are exactly 60° or 120° by
#: construction (Mesh 1, Mesh 2, the spokes of T_i) come out within ~1e-10 of them.
ANGLE_TOL = 1e-6


@dataclass
class _Assembler:
    """Collects vertices and quads of all stages into one global numbering.

    Shared vertices are glued by index (ARCHITECTURE.md rule 6): a thin part receives
    the global ids of the crosscut vertices it was built on, never a merge by distance.
    """

    chunks: list[np.ndarray] = field(default_factory=list)
    quads: list[np.ndarray] = field(default_factory=list)
    source: list[np.ndarray] = field(default_factory=list)
    count: int = 0

    def add_vertices(self, z: np.ndarray) -> np.ndarray:
        ids = np.arange(self.count, self.count + z.size)
        self.chunks.append(np.asarray(z, dtype=np.complex128))
        self.count += z.size
        return ids

    def add_quads(self, quads: np.ndarray, source: int) -> None:
        self.quads.append(np.asarray(quads, dtype=np.int64))
        self.source.append(np.full(len(quads), source, dtype=np.int8))

    def vertices(self) -> np.ndarray:
        return np.concatenate(self.chunks) if self.chunks else np.zeros(0, complex)

    def all_quads(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.quads:
            return np.zeros((0, 4), np.int64), np.zeros(0, np.int8)
        return np.concatenate(self.quads), np.concatenate(self.source)


def _arc_gaps(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gaps to the previous and the next prevertex (radians), for sorted angles θ_k."""
    two_pi = 2 * np.pi
    nxt = np.mod(np.roll(theta, -1) - theta, two_pi)
    prv = np.mod(theta - np.roll(theta, 1), two_pi)
    return prv, nxt


def _choose_arcs(
    centre: np.ndarray, half: np.ndarray, gap: np.ndarray, options: MeshOptions
) -> np.ndarray:
    """Arcs I_j for the cores [centre ± half] (a prevertex, or a crosscut's prevertex arc).

    The boundary of W over J_j is the geodesic γ_j whose image is the crosscut of the thin
    part around the core (paper §7). Its image is round about the vertex only when J_j is
    nearly symmetric about the core: for J_j from −a to b about a prevertex, the power map
    sends γ_j to a curve whose distance from the vertex varies by (b/a)^α. Lemma 2.1's
    minimal containing arc of a concentric √A·I_j can be very lopsided (|J|/|√A I| was
    measured up to 13), so J_j is chosen first: among the tessellation (I5) arcs that
    contain the core with half-width φ near max(g/A_eff, 1.2·√A·half) (g the gap to the
    neighbouring prevertices; CONFORMAL.md §3.2: the crosscut is round to ≈ 1.1·φ/g), the
    one whose centre is closest to the core's centre relative to φ. I_j is then the arc
    concentric with J_j of half-width φ/(1.02·√A): √A·I_j ⊂ J_j, so Lemma 2.2 selects J_j (or
    a slightly shorter arc with the same centre up to 2 %), and the A-fold expansion
    (half-width ≈ √A·φ ≤ g/2) stays clear of the neighbours. Where the residual offset is
    large the conformal collar (:mod:`quadmesh.thin.collar`) straightens the crosscut.
    """
    two_pi = 2 * np.pi
    sq = np.sqrt(options.lemma_A)
    target = np.maximum(gap / options.crosscut_ratio, 1.2 * sq * half)
    # a cheap first pass (3 sizes, centred), then the full candidate set where it is poor
    quick = _candidate_arcs(centre, half, gap, target, options, np.array([0.25, 0.5, 1.0]), [0.0])
    redo = np.flatnonzero(quick[2] > 0.35)
    if redo.size:
        full = _candidate_arcs(
            centre[redo],
            half[redo],
            gap[redo],
            target[redo],
            options,
            np.geomspace(1.0 / 16.0, 4.0, 13),
            [-0.4, 0.0, 0.4],
        )
        better = full[2] < quick[2][redo]
        for q, f in zip(quick, full):
            q[redo[better]] = f[better]
    jc, phi, score = quick
    if np.any(score >= 10.0):
        j = int(np.flatnonzero(score >= 10.0)[0])
        raise DiskConstructionError(
            f"no tessellation arc fits around prevertex cluster {j} (core half-width "
            f"{half[j]:.3g} rad, gap to its neighbours {gap[j]:.3g} rad): the thick piece is "
            "too crowded there"
        )
    half_i = phi / (1.02 * sq)
    return np.column_stack([np.mod(jc - half_i, two_pi), 2 * half_i])


def _candidate_arcs(
    centre: np.ndarray,
    half: np.ndarray,
    gap: np.ndarray,
    target: np.ndarray,
    options: MeshOptions,
    sizes: np.ndarray,
    offsets: list[float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best I5 arc per core among the minimal containing arcs of trial arcs (sizes × target
    half-widths, shifted by offsets): returns its centre, half-width and score (relative
    offset of its centre from the core's centre, +10 when inadmissible)."""
    from .disk.tessellation import minimal_containing_arc

    ss, oo = np.meshgrid(sizes, np.asarray(offsets, dtype=float), indexing="ij")
    ss, oo = ss.ravel(), oo.ravel()
    hw = np.minimum(target[:, None] * ss[None, :], gap[:, None] / 10.0)
    hw = np.maximum(hw, 1.05 * half[:, None])
    mid = centre[:, None] + oo[None, :] * (hw - half[:, None])
    js, jl, _, _ = minimal_containing_arc(np.mod(mid - hw, 2 * np.pi).ravel(), (2 * hw).ravel())
    phi = jl.reshape(hw.shape) / 2
    jc = js.reshape(hw.shape) + phi
    dist = np.abs(np.angle(np.exp(1j * (jc - centre[:, None]))))
    ratio = phi / gap[:, None]
    # J's A-fold expansion reaches (√A/1.02 + 0.9)·φ from the core (centre offset ≤ 0.9φ):
    # keeping that below g/2 keeps two neighbours' expansions inside the gap between them
    ratio_max = 0.5 / (np.sqrt(options.lemma_A) / 1.02 + 0.9)
    bad = (ratio > ratio_max) | (dist + half[:, None] > 0.9 * phi)
    score = dist / phi + 0.01 * np.abs(np.log(ratio * options.crosscut_ratio)) + 10.0 * bad
    best = np.argmin(score, axis=1)
    rows = np.arange(centre.size)
    return jc[rows, best], phi[rows, best], score[rows, best]


def vertex_intervals(theta: np.ndarray, options: MeshOptions) -> np.ndarray:
    """Arcs I_k for a thick piece without crosscuts: one core per prevertex θ_k
    (see :func:`_choose_arcs`)."""
    prv, nxt = _arc_gaps(theta)
    return _choose_arcs(theta, np.zeros_like(theta), np.minimum(prv, nxt), options)


def piece_intervals(
    theta: np.ndarray, stretches: list[tuple[int, int]], options: MeshOptions
) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """Arcs I_j of a thick piece: one per vertex outside the crosscut stretches and one per
    stretch (piece vertices ``start..stop`` modulo the piece size, counter-clockwise).

    Returns the (m, 2) arcs in boundary order and, per arc, ("vertex", piece vertex) or
    ("crosscut", stretch index).
    """
    k = theta.size
    two_pi = 2 * np.pi
    owner = np.full(k, -1)
    for si, (a, b) in enumerate(stretches):
        idx = np.arange(a, a + (b - a) % k + 1) % k
        owner[idx] = si
    cores: list[tuple[int, int, tuple[str, int]]] = []  # (first, last) vertex indices
    done = set()
    for i in range(k):
        if owner[i] < 0:
            cores.append((i, i, ("vertex", i)))
        elif owner[i] not in done:
            a, b = stretches[owner[i]]
            cores.append((a, b, ("crosscut", int(owner[i]))))
            done.add(owner[i])
    first = np.array([c[0] for c in cores])
    last = np.array([c[1] for c in cores])
    lo, hi = theta[first], theta[last]
    span = np.mod(hi - lo, two_pi)
    half = span / 2
    centre = lo + half
    order = np.argsort(np.mod(lo, two_pi))
    lo_s, hi_s = lo[order], hi[order]
    before = np.mod(lo_s - np.roll(hi_s, 1), two_pi)
    after = np.mod(np.roll(lo_s, -1) - hi_s, two_pi)
    gap = np.empty_like(before)
    gap[order] = np.minimum(before, after)
    arcs = _choose_arcs(centre, half, gap, options)
    return arcs, [c[2] for c in cores]


def _project_to_sides(
    w: np.ndarray, t: np.ndarray, theta: np.ndarray, zpoly: np.ndarray
) -> np.ndarray:
    """Put images of circle points exactly on their polygon side.

    A point e^{it} of the circle between prevertices θ_k and θ_{k+1} maps to side
    [w_k, w_{k+1}]; the computed value carries quadrature error, so it is replaced by its
    orthogonal projection onto that segment. ``t`` and ``theta`` may be long double (the
    side of a circle vertex next to a crowded prevertex is then decided at ~1e-19).
    """
    order = np.argsort(theta)
    ts = theta[order]
    two_pi = 2 * np.pi if ts.dtype != np.longdouble else 2 * np.longdouble(np.pi)
    pos = np.searchsorted(ts, np.mod(t, two_pi), side="right") - 1
    k = order[np.mod(pos, theta.size)]
    a = zpoly[k]
    b = zpoly[(k + 1) % zpoly.size]
    d = b - a
    s = np.clip(((w - a) * np.conj(d)).real / np.abs(d) ** 2, 0.0, 1.0)
    return a + s * d


def _push_forward(fmap, disk, theta: np.ndarray, zpoly: np.ndarray) -> np.ndarray:
    """Images in the plane of the disk-mesh vertices (paper §7).

    f at every vertex (by per-piece power series where they converge, CONFORMAL.md
    §1.10), circle vertices projected onto their side, and inside each inner triangle T_i
    the linear map h(ζ) = g(c) + (ζ − c)·g'(c) with g = f∘τ⁻¹ (a similarity, so the model
    angles of the T_i quads survive exactly).

    Every evaluation uses exact offsets (the disk mesh's extended-precision frames,
    :meth:`~quadmesh.disk.DiskMesh.offsets_from`), not the complex128 vertices: cells of
    1e-15 next to prevertex gaps of 1e-13 (crowded pieces) keep their shape; circle vertices
    find their side from their long double angle, the triangle centres τ⁻¹(c) come in long
    double from the apex frames.
    """
    image = _evaluate_map(fmap, disk)
    circ = np.flatnonzero(np.asarray(disk.on_circle, dtype=bool))
    if circ.size:
        ang = np.angle(disk.exact_vertices()[circ])
        th = getattr(fmap, "theta_ld", None)
        if th is None:  # a rotated map (gaps ≥ ROTATION_MIN_GAP): float64 angles suffice
            th, ang = theta, ang.astype(float)
        image[circ] = _project_to_sides(image[circ], ang, th, zpoly)
    tris = disk.triangles
    if len(tris):
        idx = np.concatenate([np.asarray(t.inner_vertices) for t in tris])
        zeta = np.concatenate([np.asarray(t.inner_model) for t in tris])
        tid = np.repeat(np.arange(len(tris)), [len(t.inner_vertices) for t in tris])
        apex, off, dzc = _triangle_centres(tris)
        gc, fpc = _evaluate_map(fmap, frames=apex, offsets=off)
        dgc = fpc * dzc
        c0 = np.array([t.center for t in tris], dtype=complex)
        image[idx] = gc[tid] + (zeta - c0[tid]) * dgc[tid]
    return image


def _triangle_centres(tris) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """τ⁻¹(c) and (τ⁻¹)'(c) for every Carleson triangle, c the model centre of T_i.

    τ⁻¹ = φ_a⁻¹ ∘ τ_local (a = the triangle's apex frame, in long double) is evaluated in this
    factored form: ``τ⁻¹(c) − a = u(1 − |a|²)/(1 + āu)`` with ``u = τ_local(c)`` and
    ``1 − |a|²`` from the long double apex, which keeps relative accuracy for tiny triangles
    near the circle (a centre that neither complex128 nor long double resolves). Returns the
    apices ``a`` (clongdouble), the offsets ``τ⁻¹(c) − a`` (complex128) and ``(τ⁻¹)'(c)``.
    """
    from .disk.tessellation import frame_offsets, one_minus_abs2

    loc = np.stack([np.asarray(t.tau_local) for t in tris])
    a = np.array([t.frame_ld for t in tris], dtype=np.clongdouble)
    c0 = np.array([t.center for t in tris], dtype=complex)
    p, q, r, s = loc[:, 0, 0], loc[:, 0, 1], loc[:, 1, 0], loc[:, 1, 1]
    u = (p * c0 + q) / (r * c0 + s)
    du = (p * s - q * r) / (r * c0 + s) ** 2
    off = frame_offsets(a, u)
    a64 = a.astype(np.complex128)
    dphi = one_minus_abs2(a) / (1.0 + np.conj(a64) * u) ** 2
    return a, off, dphi * du


def _evaluate_map(fmap, disk=None, *, frames=None, offsets=None):
    """f at all disk-mesh vertices (``disk``), grouped by piece for the power-series
    evaluator, with the exact offsets of the disk mesh (``DiskMesh.offsets_from``); or
    ``(f, f')`` at the points ``frames + offsets`` (long double frame points, complex128
    offsets with full relative accuracy; grouped in cells as by ``DiskMap.__call__``).

    A map rotated by :func:`_best_rotation` is evaluated through its base map, with the
    points and offsets rotated back (``f_ψ(z) = f(z/r)``, ``r = e^{iψ}``)."""
    rotated = isinstance(fmap, _RotatedMap)
    base = fmap.base if rotated else fmap
    r = fmap._r if rotated else 1.0
    r_ld = np.clongdouble(r)
    if frames is not None:
        fr = np.asarray(frames, dtype=np.clongdouble).ravel()
        of = np.asarray(offsets, dtype=np.complex128).ravel()

        def point_offsets(refs: np.ndarray, index: np.ndarray) -> np.ndarray:
            return ((fr[index] - refs * r_ld).astype(np.complex128) + of[index]) / r

        approx = (fr.astype(np.complex128) + of) / r
        f, fp = base.map_clusters(approx, None, None, derivative=True, offsets=point_offsets)
        return f, fp / r
    if rotated:

        def vertex_offsets(refs: np.ndarray, index: np.ndarray) -> np.ndarray:
            return disk.offsets_from(refs * r_ld, index) / r

    else:
        vertex_offsets = disk.offsets_from
    return np.asarray(
        base.map_clusters(
            disk.vertices / r,
            disk.vertex_piece,
            disk.piece_center_ld / r_ld,
            offsets=vertex_offsets,
        )
    )


#: A polygon whose bounding-box centre lies beyond this many diameters from 0 is meshed
#: translated to the origin (see :func:`_working_origin`).
FAR_FROM_ORIGIN = 4.0


def _working_origin(poly: Polygon) -> complex:
    """Exact translation that brings a polygon far from 0 to the origin (0 if it is near).

    Every stage evaluates plane points as vertex + offset; with coordinates ~1e6 and features
    ~1 a float64 vertex carries an absolute error ~1e-10, which the conformal map's accuracy
    checks (§1.7: boundary deviation, round trip) and the pushed-forward Carleson cells near
    the vertices (sizes down to ~1e-8 of the diameter) cannot absorb: a random 40-gon of
    diameter 1.7 at (1e6, −3e6) failed its map checks (round trip 1.1e-9) and, with the
    checks off, gave Carleson triangle angles in [0.55°, 359°]. Per coordinate, the centre c
    of the bounding box is used when |c| > FAR_FROM_ORIGIN · diameter: then every coordinate x
    lies in [c/2, 2c], so x − c is exact (Sterbenz) and (x − c) + c gives x back bit for bit.
    """
    v = poly.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    c = (lo + hi) / 2
    c = np.where(np.abs(c) > FAR_FROM_ORIGIN * poly.diameter, c, 0.0)
    return complex(c[0], c[1])


def _check_cancel(cancel: CancelCallback | None, stage: str) -> None:
    if cancel is not None and cancel():
        raise Cancelled(f"cancelled before {stage}")


@dataclass
class _Piece:
    """Work data of one thick piece: its map, its arcs and what each arc belongs to."""

    index: int
    z: np.ndarray
    fmap: object
    theta: np.ndarray
    intervals: np.ndarray
    owners: list[tuple[str, int]]
    stretches: list
    repair: object = None
    lemma_A: float | None = None  # set when the piece fell back to FALLBACK_A


def _prepare_piece(piece, options: MeshOptions, timings: dict[str, float]) -> _Piece:
    """Solve the Schwarz–Christoffel map of a thick piece and choose its arcs I_j."""
    from .conformal import DiskMap

    t0 = time.perf_counter()
    try:
        fmap = DiskMap.from_polygon(piece.z, center=piece.center, tol=options.conformal_tol)
    except ConformalMapError as exc:
        raise ConformalMapError(f"thick piece {piece.index}: {exc.args[0]}") from exc
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        raise ConformalMapError(
            f"thick piece {piece.index} ({len(piece.z)} vertices): the parameter problem broke "
            f"down numerically ({exc}); the piece is too crowded for a disk map"
        ) from exc
    timings["conformal"] = timings.get("conformal", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    theta = np.mod(np.asarray(fmap.theta, dtype=float), 2 * np.pi)
    stretches = [(int(c.start), int(c.stop)) for c in piece.crosscuts]
    try:
        psi, intervals, owners = _best_rotation(theta, stretches, options)
    except DiskConstructionError as exc:
        raise DiskConstructionError(f"thick piece {piece.index}: {exc.args[0]}") from exc
    if psi != 0.0:
        fmap = _RotatedMap(fmap, psi)
        theta = np.asarray(fmap.theta)
    timings["intervals"] = timings.get("intervals", 0.0) + time.perf_counter() - t0
    return _Piece(piece.index, np.asarray(piece.z), fmap, theta, intervals, owners, stretches)


#: Largest number of arcs I_j for which :func:`_best_rotation` tries several rotations: each
#: trial chooses the arcs and builds W again (~30–60 ms for m ≤ 16), and the gain shrinks as m
#: grows (the J_j's fits average out: −1 to −4 % for m = 30); and the smallest prevertex gap
#: (radians) for which it rotates at all (a rotated point carries a ~1e-16 rounding error).
ROTATION_MAX_ARCS = 16
ROTATION_MIN_GAP = 1e-6
#: Offset of J_j's centre from its core's centre, relative to J_j's half-width φ, above which the
#: crosscut around the core is measured to need a conformal collar, and a collar's cost in
#: cover arcs (~285 against ~60 quads per cover arc at n = 2).
ROTATION_COLLAR_OFFSET = 0.38
ROTATION_COLLAR_COST = 5


def _off_centre_cores(
    theta: np.ndarray,
    stretches: list[tuple[int, int]],
    arcs: np.ndarray,
    owners: list[tuple[str, int]],
    options: MeshOptions,
) -> int:
    """How many arcs J_j (concentric with the I_j of :func:`piece_intervals`, half-width
    φ = 1.02·√A·|I_j|/2) are off their core's centre (a prevertex, or the middle of a
    crosscut's prevertex stretch) by more than ROTATION_COLLAR_OFFSET·φ."""
    first = np.array([i if kind == "vertex" else stretches[i][0] for kind, i in owners])
    last = np.array([i if kind == "vertex" else stretches[i][1] for kind, i in owners])
    centre = theta[first] + np.mod(theta[last] - theta[first], 2 * np.pi) / 2
    phi = arcs[:, 1] / 2 * 1.02 * np.sqrt(options.lemma_A)
    off = np.abs(np.angle(np.exp(1j * (arcs[:, 0] + arcs[:, 1] / 2 - centre))))
    return int(np.count_nonzero(off > ROTATION_COLLAR_OFFSET * phi))


def _best_rotation(
    theta: np.ndarray, stretches: list[tuple[int, int]], options: MeshOptions
) -> tuple[float, np.ndarray, list[tuple[str, int]]]:
    """The normalisation of a thick piece's map among ``options.rotations`` rotations of D.

    The Schwarz–Christoffel map is fixed up to a rotation once f(0) is chosen, and any
    rotation ψ gives an equally valid map f(e^{−iψ}z) with prevertices θ_k + ψ. The
    tessellation T5 is not rotation invariant (only by 2π/5), so the I5 arcs J_j that Lemma 2.2
    finds around the prevertices, and with them the cover of T and the number of Carleson
    pieces and pentagons of W, depend on ψ (measured: up to ±20 % of the disk quads, tracking
    the number of cover arcs with correlation 0.99). So does the thin side: a J_j whose centre
    is off its core by more than ROTATION_COLLAR_OFFSET·φ gives a crosscut that needs a
    conformal collar (measured on the triangle and the L-shape: 22 of 22 cores predicted),
    which costs about as many quads as ROTATION_COLLAR_COST cover arcs. ψ = 2π/5·k/R
    (k < R = options.rotations) are tried and the one with the smallest cover arcs +
    ROTATION_COLLAR_COST × off-centre cores is kept (ties: the smallest ψ). Returns ψ, the arcs
    I_j and their owners for θ + ψ (:func:`piece_intervals`).
    """
    from .disk import build_region

    two_pi = 2 * np.pi
    first = piece_intervals(theta, stretches, options)
    count = max(1, int(options.rotations))
    if count == 1 or first[0].shape[0] > ROTATION_MAX_ARCS:
        return 0.0, *first
    prv, _ = _arc_gaps(np.sort(theta))
    if prv.min() < ROTATION_MIN_GAP:
        return 0.0, *first
    best: tuple[int, float, tuple] | None = None
    for k in range(count):
        psi = two_pi / 5 * k / count
        try:
            got = (
                first
                if k == 0
                else piece_intervals(np.mod(theta + psi, two_pi), stretches, options)
            )
            cover = len(build_region(got[0], A=options.lemma_A).cover)
        except DiskConstructionError:
            continue
        th = np.mod(theta + psi, two_pi)
        cost = cover + ROTATION_COLLAR_COST * _off_centre_cores(th, stretches, *got, options)
        if best is None or cost < best[0]:
            best = (cost, psi, got)
    if best is None:  # no rotation builds W: let the caller report the unrotated failure
        return 0.0, *first
    return best[1], *best[2]


class _RotatedMap:
    """The map z ↦ f(e^{−iψ}z) of a :class:`~quadmesh.conformal.DiskMap` f: the same thick
    piece with the same f(0), prevertices rotated by ψ (see :func:`_best_rotation`).

    Provides what the pipeline and the viewer use: ``theta``, ``prevertices``, evaluation
    (``__call__``, ``derivative``, ``map_clusters``, ``direct``), ``inverse``; rotation-free
    data (vertices, angles, accuracy, …) are those of ``base``.
    """

    _SHARED = frozenset(
        (
            "vertices n center angles beta gaps residual iterations continuation_steps "
            "solve_time accuracy"
        ).split()
    )

    def __init__(self, base, psi: float) -> None:
        self.base = base
        self.rotation = float(psi)
        self._r = complex(np.exp(1j * psi))
        self.theta = np.mod(np.asarray(base.theta, dtype=float) + psi, 2 * np.pi)
        self.prevertices = np.asarray(base.prevertices) * self._r

    prevertex_angles = property(lambda self: self.theta, doc="Alias of ``theta``.")

    def __getattr__(self, name: str):
        if name in _RotatedMap._SHARED:
            return getattr(self.base, name)
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")

    def __call__(self, z: np.ndarray) -> np.ndarray:
        return self.base(np.asarray(z, dtype=np.complex128) / self._r)

    def direct(self, z: np.ndarray) -> np.ndarray:
        return self.base.direct(np.asarray(z, dtype=np.complex128) / self._r)

    def derivative(self, z: np.ndarray) -> np.ndarray:
        return self.base.derivative(np.asarray(z, dtype=np.complex128) / self._r) / self._r

    def map_clusters(self, points, cluster_ids, centers, derivative: bool = False):
        r = self._r
        got = self.base.map_clusters(
            np.asarray(points, dtype=np.complex128) / r,
            cluster_ids,
            np.asarray(centers, dtype=np.complex128) / r,
            derivative,
        )
        return (got[0], got[1] / r) if derivative else got

    def inverse(self, w: np.ndarray, tol: float = 1e-14) -> np.ndarray:
        return self.base.inverse(w, tol) * self._r


def _d5(inner_height: float) -> float:
    """The deepest triangle landmark D5 (DISK.md §6); the depth sequence must go beyond it."""
    from .disk.carleson_triangle import triangle_landmarks

    return float(triangle_landmarks(inner_height).D5)


def _disk_and_image(
    pd: _Piece,
    n: int,
    step: float,
    dmax: float | None,
    options: MeshOptions,
    timings: dict[str, float],
):
    """Lemma 2.2 region and its mesh for one piece, pushed forward (paper §7)."""
    from .disk import disk_mesh

    t0 = time.perf_counter()

    def build(intervals: np.ndarray, A: float):
        return disk_mesh(
            intervals,
            A=A,
            n=n,
            depth_step=step,
            inner_height=options.inner_height,
            depth_growth=options.depth_growth,
            depth_max=None if dmax is None else max(dmax, _d5(options.inner_height) + 0.5),
        )

    try:
        disk = build(pd.intervals, pd.lemma_A or options.lemma_A)
    except DiskConstructionError as exc:
        # Lemma 2.2's chains of neighbouring arcs can interlock when A is small (a
        # scale-free ~3/40 of random arc sets at A = 4): this piece falls back to the
        # paper-sized A = 16 with arcs of 1/16 of the neighbouring gap (same cores, same
        # crosscut vertex counts, so the channels still match)
        if pd.lemma_A is not None or options.lemma_A >= FALLBACK_A:
            raise DiskConstructionError(f"thick piece {pd.index}: {exc.args[0]}") from exc
        fallback = replace(options, lemma_A=FALLBACK_A, crosscut_ratio=FALLBACK_A)
        try:
            intervals, owners = piece_intervals(pd.theta, pd.stretches, fallback)
            disk = build(intervals, FALLBACK_A)
        except DiskConstructionError as exc2:
            raise DiskConstructionError(
                f"thick piece {pd.index}: {exc.args[0]} (and with A = {FALLBACK_A:g}: "
                f"{exc2.args[0]})"
            ) from exc2
        if owners != pd.owners:
            raise DiskConstructionError(
                f"thick piece {pd.index}: {exc.args[0]} (the A = {FALLBACK_A:g} fallback "
                "changed the arcs' owners)"
            ) from exc
        pd.intervals, pd.lemma_A = intervals, FALLBACK_A
    timings["disk"] = timings.get("disk", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        image = _push_forward(pd.fmap, disk, pd.theta, pd.z)
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        raise ConformalMapError(
            f"thick piece {pd.index}: evaluating the map at the disk mesh failed ({exc})"
        ) from exc
    if not np.all(np.isfinite(image)):
        raise ConformalMapError(f"thick piece {pd.index}: the map gave non-finite mesh vertices")
    timings["push_forward"] = timings.get("push_forward", 0.0) + time.perf_counter() - t0
    pd.repair = None
    if options.repair:
        image = _repair_image(pd, disk, image, timings)
    return disk, image


#: A (and crosscut ratio) of the per-piece fallback when Lemma 2.2's arcs interlock.
FALLBACK_A = 16.0

#: Pushed-forward angles this far outside [60°, 120°] are not the O(1/n) distortion that the
#: adaptive loop cures but numerical breakdown (inverted or collapsed quads).
DEGENERATE_ANGLES = (20.0, 200.0)
#: Prevertex gap (radians) below which such a breakdown is attributed to crowding.
CROWDED_GAP = 1e-10


def _refuse_degenerate(pd: _Piece, ang: np.ndarray) -> None:
    """Raise at once when a crowded piece's pushed-forward mesh is numerically degenerate.

    Raising n or lowering the depth step makes such a mesh larger, never valid (glyph_s took
    37 s to fail that way), so the loop is not entered.
    """
    lo, hi = DEGENERATE_ANGLES
    if not np.any((ang < lo) | (ang > hi)):
        return
    th = np.sort(np.mod(np.asarray(pd.theta, dtype=float), 2 * np.pi))
    gap = float(np.min(np.diff(np.r_[th, th[0] + 2 * np.pi])))
    if gap >= CROWDED_GAP:
        return
    raise DiskConstructionError(
        f"thick piece {pd.index}: its prevertices crowd to gaps of {gap:.2g} rad and the "
        f"pushed-forward disk mesh is numerically degenerate there (angles "
        f"[{float(ang.min()):.1f}°, {float(ang.max()):.1f}°]): double precision cannot resolve "
        "the map of this piece (typically a long curved corridor whose walls are chains of "
        "short edges); a larger n cannot help"
    )


def _angle_tol(image: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(Q,) slack (degrees) on the angle bounds per quad: ANGLE_TOL plus what float64 storage
    of the vertices can put on the angles of that quad (as the final verifier allows)."""
    from .geometry import angle_rounding_slack_deg

    return ANGLE_TOL + angle_rounding_slack_deg(image, quads)


def _repair_note(pd: _Piece) -> tuple[str, ...]:
    """Fix notes of a piece (A fallback, local repair of its pushed-forward mesh) for
    ThickPieceResult.fixes."""
    notes: tuple[str, ...] = ()
    if pd.lemma_A is not None:
        notes = (f"Lemma 2.2 arcs interlocked at the default A: A = {pd.lemma_A:g} used",)
    rep = pd.repair
    if rep is None or rep.moved.size == 0:
        return notes
    return (
        *notes,
        f"angles [{rep.before[0]:.2f}, {rep.before[1]:.2f}] repaired locally: "
        f"{rep.moved.size} interior vertices moved by at most {100 * rep.max_shift:.2g}% of "
        f"their shortest edge, now [{rep.after[0]:.2f}, {rep.after[1]:.2f}]",
    )


def _repair_image(pd: _Piece, disk, image: np.ndarray, timings: dict[str, float]) -> np.ndarray:
    """Local angle repair of a pushed-forward disk mesh (:mod:`quadmesh.repair`): only
    vertices off the boundary of W (not on the circle, not on the geodesics over the J_j
    whose images the thin parts are built on) move. Returns the image, repaired if needed
    and possible; ``pd.repair`` keeps the report."""
    from .geometry import unpaired_edges
    from .repair import repair_angles

    ang = quad_angles_deg(image, disk.quads)
    tol = _angle_tol(image, disk.quads)[:, None]
    if not np.any((ang < ANGLE_MIN - tol) | (ang > ANGLE_MAX + tol)):
        return image
    t0 = time.perf_counter()
    edges, _ = unpaired_edges(disk.quads)
    movable = np.ones(image.size, dtype=bool)
    movable[np.unique(edges)] = False
    movable[np.asarray(disk.on_circle, dtype=bool)] = False
    for g in disk.gamma:
        movable[np.asarray(g)] = False
    got = repair_angles(image, disk.quads, movable, tol=_angle_tol(image, disk.quads))
    timings["repair"] = timings.get("repair", 0.0) + time.perf_counter() - t0
    if got is None:
        return image
    pd.repair = got[1]
    return got[0]


def _orient_to_walls(gamma_ids: np.ndarray, pts: np.ndarray, frame) -> np.ndarray:
    """Order a channel-side crosscut from wall 1 to wall 2 (wall 1 = the frame's real axis)."""
    w = (pts[[0, -1]] - frame.origin) / frame.direction
    d1 = np.abs(np.angle(w)) if frame.kind == "angled" else np.abs(w.imag)
    return gamma_ids if d1[0] <= d1[1] else gamma_ids[::-1]


def _walls_of(frame):
    from .thin.channel import Walls

    if frame.kind == "angled":
        return Walls.wedge(frame.origin, frame.direction, frame.beta)
    return Walls.parallel(frame.origin, frame.direction, frame.width)


def _glue(asm: _Assembler, verts: np.ndarray, quads: np.ndarray, fixed: dict, source: int):
    """Add a thin-part mesh: vertices listed in ``fixed`` (local index -> global id) are
    the crosscut vertices it was built on; all others are new. Returns the global ids."""
    gl = np.full(verts.size, -1, dtype=np.int64)
    loc = np.fromiter(fixed.keys(), dtype=np.int64, count=len(fixed))
    gl[loc] = np.fromiter(fixed.values(), dtype=np.int64, count=len(fixed))
    own = gl < 0
    gl[own] = asm.add_vertices(verts[own])
    asm.add_quads(gl[np.asarray(quads)], source=source)
    return gl


def _collar(asm, thin, gamma, gamma_gl, walls, toward, part, what):
    """Conformal collar between a crosscut image and a straight (round) crosscut, glued
    onto the crosscut's global vertices; returns the straight crosscut's points and ids.
    ``part`` is the (kind, owner, source) of the thin part it belongs to."""
    from .thin.collar import conformal_collar

    try:
        col = conformal_collar(gamma, walls, toward=toward)
    except ThinPartError as exc:
        raise ThinPartError(f"{what}; collar: {exc.args[0]}") from exc
    kind, owner, source = part
    fixed = dict(zip(np.asarray(col.gamma_index).tolist(), gamma_gl.tolist()))
    cgl = _glue(asm, np.asarray(col.vertices), col.quads, fixed, source)
    thin.append(ThinPartResult(kind, owner, col, cgl))
    si = np.asarray(col.straight_index)
    return np.asarray(col.vertices)[si], cgl[si]


def _sector(corner, gamma: np.ndarray, gamma_gl: np.ndarray, options, asm, thin):
    """Vertex sector (paper §8, parabolic case), through a conformal collar when the
    crosscut is not round about the vertex."""
    from .thin.collar import vertex_walls
    from .thin.parabolic import mesh_vertex_sector

    args = (corner.apex, corner.dir_out, float(corner.angle))
    try:
        sec = mesh_vertex_sector(*args, gamma, lam=options.sector_ratio)
    except ThinPartError as first:
        walls = vertex_walls(*args)
        what = f"vertex {corner.index}: {first.args[0]}"
        part = ("parabolic", corner.index, 1)
        gamma, gamma_gl = _collar(asm, thin, gamma, gamma_gl, walls, "inner", part, what)
        try:
            sec = mesh_vertex_sector(*args, gamma, lam=options.sector_ratio)
        except ThinPartError as exc:
            raise ThinPartError(f"vertex {corner.index}: {exc.args[0]}") from exc
    fixed = dict(zip(np.asarray(sec.gamma_index).tolist(), gamma_gl.tolist()))
    gl = _glue(asm, np.asarray(sec.vertices), sec.quads, fixed, 1)
    thin.append(ThinPartResult("parabolic", corner.index, sec, gl))


def _channel(ch, ga, ga_gl, gb, gb_gl, asm, thin):
    """Channel connector (paper §8, hyperbolic case) between the two thick pieces'
    crosscut images, each first straightened by a conformal collar if needed."""
    from .thin.channel import mesh_channel

    walls = _walls_of(ch.frame)
    try:
        cm = mesh_channel(ga, gb, walls=walls)
    except ThinPartError as first:
        what = f"channel {ch.id}: {first.args[0]}"
        part = ("hyperbolic", ch.id, 2)
        ga, ga_gl = _collar(asm, thin, ga, ga_gl, walls, "outer", part, what)
        gb, gb_gl = _collar(asm, thin, gb, gb_gl, walls, "inner", part, what)
        try:
            cm = mesh_channel(ga, gb, walls=walls)
        except ThinPartError as exc:
            raise ThinPartError(f"channel {ch.id}: {exc.args[0]}") from exc
    fixed = dict(zip(np.asarray(cm.gamma1_index).tolist(), ga_gl.tolist()))
    fixed.update(zip(np.asarray(cm.gamma2_index).tolist(), gb_gl.tolist()))
    gl = _glue(asm, np.asarray(cm.vertices), cm.quads, fixed, 2)
    thin.append(ThinPartResult("hyperbolic", ch.id, cm, gl))


def mesh_polygon(
    polygon: object,
    options: MeshOptions | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelCallback | None = None,
) -> MeshResult:
    """Mesh a simple polygon by quadrilaterals with every new angle in [60°, 120°].

    Args:
        polygon: an (n, 2) float array, a complex array or a :class:`~quadmesh.Polygon`.
        options: the knobs (:class:`MeshOptions`); defaults from the design notes.
        progress: optional callback ``progress(stage, fraction)``.
        cancel: optional callable polled between stages; returning True raises
            :class:`~quadmesh.errors.Cancelled`.

    Returns:
        A :class:`MeshResult` whose ``mesh`` passed :meth:`QuadMesh.verify`.

    Raises:
        PolygonError: invalid input. ConformalMapError, DiskConstructionError,
        ThinPartError, DecompositionError: a stage could not handle the input.
        MeshVerificationError: the assembled mesh failed verification (never returned).
    """
    from .decompose import DecomposeOptions, decompose
    from .mesh import finalize_mesh
    from .refine import refine_quads

    options = options or MeshOptions()
    timings: dict[str, float] = {}

    def report(stage: str, fraction: float) -> None:
        _check_cancel(cancel, stage)
        if progress is not None:
            progress(stage, fraction)

    report("validate", 0.0)
    t0 = time.perf_counter()
    poly: Polygon = validate_polygon(polygon)
    origin = _working_origin(poly)
    work_poly = validate_polygon(poly.z - origin) if origin else poly
    timings["validate"] = time.perf_counter() - t0

    report("decompose", 0.05)
    t0 = time.perf_counter()
    dec = decompose(work_poly, DecomposeOptions(delta=options.channel_delta))
    timings["decompose"] = time.perf_counter() - t0

    work: list[_Piece] = []
    for i, piece in enumerate(dec.thick):
        report("conformal map", 0.1 + 0.3 * i / len(dec.thick))
        work.append(_prepare_piece(piece, options, timings))

    # One (n, depth step) for all pieces: both sides of a channel must carry the same
    # crosscut vertex count. Pentagon images out of range -> raise n (Lemma 4.1's angles
    # converge like O(1/n)); Carleson images out of range -> halve the depth step.
    n, step, dmax = options.n, options.depth_step, options.depth_max
    fixes: list[str] = []
    while True:  # thin parts failing -> raise n and rebuild
        while True:
            disks = []
            bad_kind: dict[str, tuple[float, float, int]] = {}
            for i, pd in enumerate(work):
                report("disk mesh", 0.4 + 0.3 * i / len(work))
                disk, image = _disk_and_image(pd, n, step, dmax, options, timings)
                disks.append((disk, image))
                ang = quad_angles_deg(image, disk.quads)
                tol = _angle_tol(image, disk.quads)[:, None]
                out = (ang < ANGLE_MIN - tol) | (ang > ANGLE_MAX + tol)
                _refuse_degenerate(pd, ang)
                for kind in np.unique(disk.kind[out.any(axis=1)]):
                    sel = ang[disk.kind == kind]
                    lo, hi = float(sel.min()), float(sel.max())
                    old = bad_kind.get(str(kind), (ANGLE_MIN, ANGLE_MAX, pd.index))
                    bad_kind[str(kind)] = (min(lo, old[0]), max(hi, old[1]), pd.index)
            if not bad_kind:
                break
            what = ", ".join(
                f"{k} [{v[0]:.2f}, {v[1]:.2f}] in piece {v[2]}" for k, v in bad_kind.items()
            )
            if "pentagon" in bad_kind and options.adaptive and n < options.max_n:
                n = next(m for m in (*ADAPTIVE_N, options.max_n) if m > n)
                fixes.append(f"{what}: n raised to {n}")
            elif options.adaptive and step > MIN_DEPTH_STEP:
                step = max(step / 2, MIN_DEPTH_STEP)
                dmax = None  # and the notes' full depth log(8/step) + 2
                fixes.append(f"{what}: depth step lowered to {step:g}")
            elif options.adaptive and n < options.max_n:
                n = next(m for m in (*ADAPTIVE_N, options.max_n) if m > n)
                fixes.append(f"{what}: n raised to {n}")
            else:
                raise DiskConstructionError(
                    f"pushed-forward disk mesh angles out of [60°, 120°]: {what} (n = {n}, depth "
                    f"step {step:g}); the conformal map distorts the disk mesh too much"
                )

        asm = _Assembler()
        pieces: list[ThickPieceResult] = []
        gam: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        for pd, (disk, image) in zip(work, disks):
            ids = asm.add_vertices(image)
            asm.add_quads(ids[disk.quads], source=0)
            src = np.asarray(dec.thick[pd.index].source)
            owners = []
            for j, (kind, idx) in enumerate(pd.owners):
                g = np.asarray(disk.gamma[j])
                if kind == "vertex":
                    owners.append(("vertex", int(src[idx])))
                    gam[("vertex", int(src[idx]))] = (image[g], ids[g])
                else:
                    cc = dec.thick[pd.index].crosscuts[idx]
                    ch = dec.channels[cc.channel]
                    g = _orient_to_walls(g, image[g], ch.frame)
                    owners.append(("channel", int(cc.channel), int(cc.end)))
                    gam[("channel", int(cc.channel), int(cc.end))] = (image[g], ids[g])
            pieces.append(
                ThickPieceResult(
                    index=pd.index,
                    vertices=pd.z,
                    map=pd.fmap,
                    intervals=pd.intervals,
                    interval_owner=tuple(owners),
                    disk=disk,
                    image=image,
                    n_used=n,
                    fixes=tuple(fixes) + _repair_note(pd),
                    depth_step_used=step,
                )
            )

        thin: list[ThinPartResult] = []
        t0 = time.perf_counter()
        try:
            for corner in dec.corners:
                report("vertex sectors", 0.7 + 0.1 * corner.index / len(dec.corners))
                pts, gl = gam[("vertex", int(corner.index))]
                _sector(corner, pts, gl, options, asm, thin)
            for ch in dec.channels:
                report("channels", 0.8)
                (ga, ga_gl), (gb, gb_gl) = gam[("channel", ch.id, 0)], gam[("channel", ch.id, 1)]
                _channel(ch, ga, ga_gl, gb, gb_gl, asm, thin)
        except ThinPartError as exc:
            # a larger n puts more vertices on every crosscut (3·2n + 1 on its pentagon
            # edges), so the thin parts' chords get shorter and flatter
            timings["thin"] = timings.get("thin", 0.0) + time.perf_counter() - t0
            # Near a reflex vertex one hyperbolic unit of a crosscut's Carleson part spans up
            # to ~1 rad of polar angle about the vertex (quasi-hyperbolic metric |dz|/r), so
            # only a finer depth sequence puts more crosscut vertices there; n refines only
            # the pentagon part (measured on a 331° stroke end and a 1:100 V-slit).
            if not options.adaptive:
                raise
            if step > MIN_DEPTH_STEP:
                step = max(step / 2, MIN_DEPTH_STEP)
                fixes.append(f"{exc.args[0]}: depth step lowered to {step:g}")
            elif n < options.max_n:
                n = next(m for m in (*ADAPTIVE_N, options.max_n) if m > n)
                fixes.append(f"{exc.args[0]}: n raised to {n}")
            else:
                raise
            continue
        timings["thin"] = timings.get("thin", 0.0) + time.perf_counter() - t0
        break

    report("verify", 0.9)
    t0 = time.perf_counter()
    z = asm.vertices()  # relative to the working origin
    quads, source = asm.all_quads()
    if options.refine > 1:
        z, quads, parent = refine_quads(z, quads, options.refine, origin=origin)
        source = source[parent]
    # verified as it will be stored: absolute coordinates, or relative to origin when far
    # from (0, 0) float64 cannot hold the angles (MeshResult.mesh_origin)
    mesh, mesh_origin, verification = finalize_mesh(poly, z, quads, origin)
    timings["verify"] = time.perf_counter() - t0
    quality = verification.quality
    report("done", 1.0)
    return MeshResult(
        polygon=poly,
        options=options,
        decomposition=dec,
        pieces=tuple(pieces),
        thin=tuple(thin),
        mesh=mesh,
        quality=quality,
        verification=verification,
        timings=timings,
        quad_source=source,
        origin=origin,
        mesh_origin=mesh_origin,
    )
