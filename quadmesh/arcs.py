"""The arcs I_j of a thick piece: one around each prevertex outside the crosscuts and one
around each crosscut's prevertex stretch, chosen so that Lemma 2.2's region W exists and its
boundary geodesics map to crosscuts that are round about their vertex (paper §7, "Meshing the
thick parts", with Lemmas 2.1 and 2.2); and the rotation of the disk that normalises the
Schwarz–Christoffel map for the fewest cover arcs and conformal collars.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .errors import DiskConstructionError
from .progress import span
from .result import MeshOptions

__all__ = ["best_rotation", "piece_intervals", "vertex_intervals"]

#: ``MeshOptions.arc_choice`` → (offset of J's centre from the core, relative to J's
#: half-width, below which centring does not count; weight of |log(size / target size)|).
#: "centred" ranks centring before size; "sized" lets offsets up to 0.15 count as centred
#: and weighs size ten times more: larger crosscuts near reflex corners (cmr10 "g"'s ear,
#: 323°: a vertex sector 3e-11 wide with centred arcs rounds its 120° to 120.00008° in
#: float64); no better as a default (on 10 examples the comb's smallest edge 32× larger
#: with 1.5× the quads, the dumbbell's 0.6×, seven unchanged).
ARC_CHOICE = {"centred": (0.0, 0.01), "sized": (0.15, 0.1)}


def _arc_gaps(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gaps to the previous and the next prevertex (radians), for sorted angles θ_k."""
    two_pi = 2 * np.pi
    nxt = np.mod(np.roll(theta, -1) - theta, two_pi)
    prv = np.mod(theta - np.roll(theta, 1), two_pi)
    return prv, nxt


def _choose_arcs(
    centre: np.ndarray,
    half: np.ndarray,
    gap: np.ndarray,
    options: MeshOptions,
    where: Callable[[int], str] | None = None,
) -> np.ndarray:
    """Arcs I_j for the cores [centre ± half] (:func:`_fit_arcs`), raising
    DiskConstructionError when no arc fits around some core (``where(j)`` names core j in the
    user's terms in the message)."""
    arcs, bad = _fit_arcs(centre, half, gap, options)
    if np.any(bad):
        j = int(np.flatnonzero(bad)[0])
        place = f"the point at {centre[j]:.6f} rad of the circle" if where is None else where(j)
        raise DiskConstructionError(
            f"no arc of the disk construction fits around {place} (the conformal map leaves "
            f"only {gap[j]:.3g} rad of the circle between it and its neighbours): this part of "
            "the polygon is too crowded there; use fewer, longer edges near it, or widen the "
            "polygon there"
        )
    return arcs


def _fit_arcs(
    centre: np.ndarray, half: np.ndarray, gap: np.ndarray, options: MeshOptions
) -> tuple[np.ndarray, np.ndarray]:
    """Arcs I_j for the cores [centre ± half] (a prevertex, or a crosscut's prevertex arc),
    (m, 2) ``(start, length)``, and where no admissible arc fits (bool (m,); those rows are
    meaningless). Every core's arc depends on its own centre, half-width and gap only.

    The boundary of W over J_j is the geodesic γ_j whose image is the crosscut of the thin
    part around the core (paper §7). Its image is round about the vertex only when J_j is
    nearly symmetric about the core: for J_j from −a to b about a prevertex, the power map
    sends γ_j to a curve whose distance from the vertex varies by (b/a)^α. Lemma 2.1's
    minimal containing arc of a concentric √A·I_j can be very lopsided (|J|/|√A I| was
    measured up to 13), so J_j is chosen first: among the tessellation (I5) arcs that
    contain the core with half-width φ near max(g/A_eff, 1.2·√A·half) (g the gap to the
    neighbouring prevertices: the crosscut is round to ≈ 1.1·φ/g), the
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
    with span(0.0, 0.25):
        quick = _candidate_arcs(
            centre, half, gap, target, options, np.array([0.25, 0.5, 1.0]), [0.0]
        )
    redo = np.flatnonzero(quick[2] > 0.35)
    if redo.size:
        with span(0.25, 1.0):
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
    half_i = phi / (1.02 * sq)
    return np.column_stack([np.mod(jc - half_i, two_pi), 2 * half_i]), score >= 10.0


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
    # trial sizes clipped to the gap repeat (about a third of the trials): each distinct arc
    # is searched once
    trial, back = np.unique(
        np.column_stack([np.mod(mid - hw, 2 * np.pi).ravel(), (2 * hw).ravel()]),
        axis=0,
        return_inverse=True,
    )
    js, jl, _, _ = minimal_containing_arc(trial[:, 0], trial[:, 1], fast=True)
    back = back.reshape(hw.shape)
    phi = jl[back] / 2
    jc = js[back] + phi
    dist = np.abs(np.angle(np.exp(1j * (jc - centre[:, None]))))
    ratio = phi / gap[:, None]
    # J's A-fold expansion reaches (√A/1.02 + 0.9)·φ from the core (centre offset ≤ 0.9φ):
    # keeping that below g/2 keeps two neighbours' expansions inside the gap between them
    ratio_max = 0.5 / (np.sqrt(options.lemma_A) / 1.02 + 0.9)
    bad = (ratio > ratio_max) | (dist + half[:, None] > 0.9 * phi)
    free, weight = ARC_CHOICE[options.arc_choice]
    score = (
        np.maximum(dist / phi, free)
        + weight * np.abs(np.log(ratio * options.crosscut_ratio))
        + 10.0 * bad
    )
    best = np.argmin(score, axis=1)
    rows = np.arange(centre.size)
    return jc[rows, best], phi[rows, best], score[rows, best]


def vertex_intervals(theta: np.ndarray, options: MeshOptions) -> np.ndarray:
    """Arcs I_k for a thick piece without crosscuts: one core per prevertex θ_k
    (see :func:`_choose_arcs`)."""
    prv, nxt = _arc_gaps(theta)
    return _choose_arcs(theta, np.zeros_like(theta), np.minimum(prv, nxt), options)


def piece_intervals(
    theta: np.ndarray,
    stretches: list[tuple[int, int]],
    options: MeshOptions,
    name: Callable[[tuple[str, int]], str] | None = None,
) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """Arcs I_j of a thick piece: one per vertex outside the crosscut stretches and one per
    stretch (piece vertices ``start..stop`` modulo the piece size, counter-clockwise).

    Returns the (m, 2) arcs in boundary order and, per arc, ("vertex", piece vertex) or
    ("crosscut", stretch index). ``name(owner)`` says such an owner in the user's terms (for
    the message raised when no arc fits around it).
    """
    centre, half, gap, owners = _piece_cores(theta, stretches)
    where = None if name is None else (lambda j: name(owners[j]))
    return _choose_arcs(centre, half, gap, options, where), owners


def _piece_cores(
    theta: np.ndarray, stretches: list[tuple[int, int]]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[str, int]]]:
    """The cores of :func:`piece_intervals`' arcs in boundary order: centre, half-width and gap
    to the neighbouring cores (radians), and the owners."""
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
    return centre, half, gap, [c[2] for c in cores]


def _rotated_intervals(
    theta: np.ndarray,
    stretches: list[tuple[int, int]],
    options: MeshOptions,
    psis: np.ndarray,
) -> list[tuple[np.ndarray, list[tuple[str, int]]] | None]:
    """:func:`piece_intervals` for the prevertices θ + ψ of every rotation ψ, None where no arc
    fits. The cores of all rotations go through one :func:`_fit_arcs` (one arc search instead
    of one per rotation: the same arcs, since each core's arc depends on that core alone)."""
    two_pi = 2 * np.pi
    cores = [_piece_cores(np.mod(theta + psi, two_pi), stretches) for psi in psis]
    try:
        arcs, bad = _fit_arcs(*(np.concatenate([c[i] for c in cores]) for i in range(3)), options)
    except DiskConstructionError:  # one rotation's search failed: try them one by one
        out: list[tuple[np.ndarray, list[tuple[str, int]]] | None] = []
        for psi in psis:
            try:
                out.append(piece_intervals(np.mod(theta + psi, two_pi), stretches, options))
            except DiskConstructionError:
                out.append(None)
        return out
    ends = np.cumsum([c[0].size for c in cores])
    return [
        None if b.any() else (a, c[3])
        for a, b, c in zip(np.split(arcs, ends[:-1]), np.split(bad, ends[:-1]), cores)
    ]


#: Largest number of arcs I_j for which :func:`best_rotation` tries several rotations: each
#: trial chooses the arcs and finds Lemma 2.2's cover again (~5–10 ms a rotation for m ≤ 16,
#: all rotations together), and the gain shrinks as m grows (the J_j's fits average out: −1
#: to −4 % for m = 30); and the smallest prevertex gap (radians) for which it rotates at all
#: (a rotated point carries a ~1e-16 rounding error).
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


def best_rotation(
    theta: np.ndarray,
    stretches: list[tuple[int, int]],
    options: MeshOptions,
    name: Callable[[tuple[str, int]], str] | None = None,
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
    ROTATION_COLLAR_COST × off-centre cores is kept (ties: the smallest ψ) among those for which
    the arcs fit and W builds (:func:`quadmesh.disk.build_region` raises no
    DiskConstructionError); if none does, ψ = 0. The costs come from
    :func:`quadmesh.disk.region.cover_stages` (Lemma 2.2's cover without W's pieces, all
    rotations at once), and W is completed only for the cheapest rotations, in order of cost,
    until one builds. Returns ψ, the arcs I_j and their owners for θ + ψ
    (:func:`piece_intervals`; ``name`` as there).
    """
    from .disk.region import CoverStage, build_region, cover_stages

    two_pi = 2 * np.pi
    count = max(1, int(options.rotations))
    try:
        with span(0.0, 1.0 / count):
            first = piece_intervals(theta, stretches, options, name)
    except DiskConstructionError:
        # no arc fits around some core at ψ = 0 (measured: a crosscut's prevertex stretch that
        # starts at θ_0 = 0, where the tessellation's arcs all end, on the STIX "n" and "i"):
        # every rotation is tried, whatever the piece's size or crowding
        if count == 1:
            raise
        return _any_rotation(theta, stretches, options, name)
    if count == 1 or first[0].shape[0] > ROTATION_MAX_ARCS:
        return 0.0, *first
    prv, _ = _arc_gaps(np.sort(theta))
    if prv.min() < ROTATION_MIN_GAP:
        return 0.0, *first
    # the cost of every rotation from Lemma 2.2's cover alone (cover_stages: W's pentagons and
    # Carleson pieces do not change it) ...
    psis = two_pi / 5 * np.arange(count) / count
    with span(1.0 / count, 0.3):
        rotated = [first, *_rotated_intervals(theta, stretches, options, psis[1:])]
    fits = [k for k, got in enumerate(rotated) if got is not None]
    with span(0.3, 0.9):
        covers = cover_stages([rotated[k][0] for k in fits], A=options.lemma_A)
    trials: list[tuple[int, int, float, tuple, CoverStage]] = []
    for k, cover in zip(fits, covers):
        if isinstance(cover, DiskConstructionError):
            continue
        psi, got = psis[k], rotated[k]
        th = np.mod(theta + psi, two_pi)
        off = _off_centre_cores(th, stretches, *got, options)
        trials.append((cover.count + ROTATION_COLLAR_COST * off, k, psi, got, cover))
    # ... then the cheapest one (ties: the smallest ψ) whose W builds completely
    trials.sort(key=lambda t: t[:2])
    with span(0.9, 1.0):
        for _, _, psi, got, cover in trials:
            try:
                build_region(got[0], A=options.lemma_A, cover=cover)
            except DiskConstructionError:
                continue
            return float(psi), *got
    return 0.0, *first  # no rotation builds W: let the caller report the unrotated failure


def _any_rotation(
    theta: np.ndarray,
    stretches: list[tuple[int, int]],
    options: MeshOptions,
    name: Callable[[tuple[str, int]], str] | None,
) -> tuple[float, np.ndarray, list[tuple[str, int]]]:
    """The first rotation ψ = 2π/5·k/R (k = 1 … R − 1, R = ``options.rotations``) whose arcs
    fit and whose Lemma 2.2 region W builds, for a piece whose arcs do not fit at ψ = 0; the
    unrotated failure is raised again when none does."""
    from .disk.region import build_region

    count = max(1, int(options.rotations))
    psis = 2 * np.pi / 5 * np.arange(1, count) / count
    for psi, got in zip(psis, _rotated_intervals(theta, stretches, options, psis)):
        if got is None:
            continue
        try:
            build_region(got[0], A=options.lemma_A)
        except DiskConstructionError:
            continue
        return float(psi), *got
    piece_intervals(theta, stretches, options, name)  # raises the unrotated failure
    raise AssertionError("unreachable")  # pragma: no cover
