"""The thick-piece stage (paper §7): solve a piece's Schwarz–Christoffel map, choose its arcs
I_j (:mod:`quadmesh.arcs`), build Lemma 2.2's region W and its mesh (Lemmas 4.1, 5.1, 6.1,
:func:`quadmesh.disk.disk_mesh`), with the A = 16 fallback of Lemma 2.2, push it forward
(:mod:`quadmesh.pushforward`) and check or locally repair its angles (:mod:`quadmesh.repair`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .arcs import best_rotation, piece_intervals
from .disk.assembly import KIND_NAMES
from .errors import ConformalMapError, DiskConstructionError, QuadmeshError
from .geometry import quad_angles_deg
from .progress import span
from .pushforward import RotatedMap, push_forward
from .result import MeshOptions, ThickPieceResult

__all__ = [
    "ANGLE_MAX",
    "ANGLE_MIN",
    "ANGLE_TOL",
    "KeptStages",
    "OwnerNamer",
    "PieceWork",
    "angle_tol",
    "collect_angle_faults",
    "deepest_landmark",
    "disk_and_image",
    "piece_result",
    "prepare_piece",
    "refuse_degenerate",
    "repair_note",
]

ANGLE_MIN, ANGLE_MAX = 60.0, 120.0
#: Slack on the angle bounds for rounding: angles that are exactly 60° or 120° by
#: construction (Mesh 1, Mesh 2, the spokes of T_i) come out within ~1e-10 of them.
ANGLE_TOL = 1e-6


#: How a piece is named in messages when its decomposition is not at hand.
THIS_PIECE = "this part of the polygon"


@dataclass
class PieceWork:
    """Work data of one thick piece: its map, its arcs and what each arc belongs to.

    ``what`` names the piece in the user's terms for messages (their vertex numbers and
    coordinates, :meth:`quadmesh.decompose.Decomposition.describe_piece`) and ``name(owner)``
    the polygon vertex or narrow passage an arc's owner stands for.
    """

    index: int
    z: np.ndarray
    fmap: object
    theta: np.ndarray
    intervals: np.ndarray
    owners: list[tuple[str, int]]
    stretches: list
    repair: object = None
    lemma_A: float | None = None  # set when the piece fell back to FALLBACK_A
    what: str = THIS_PIECE
    name: Callable[[tuple[str, int]], str] | None = None
    piece: object = None  # the entry of Decomposition.thick (for owners in the user's terms)

    def owner_name(self, j: int) -> str:
        """Arc j's owner (a polygon vertex or a narrow passage) in the user's terms."""
        if self.name is None or not 0 <= j < len(self.owners):
            return f"its boundary point {j}"
        return self.name(self.owners[j])


@dataclass(frozen=True)
class OwnerNamer:
    """``name(owner)`` for the arcs of ``piece`` (an entry of ``dec.thick``): ("vertex", k) ->
    the polygon vertex behind piece vertex k, ("crosscut", s) -> the mouth of the narrow
    passage behind crosscut stretch s, both in the user's numbering and coordinates. A class
    rather than a closure so that a :class:`PieceWork` can be sent to a worker process."""

    dec: Any
    piece: Any

    def __call__(self, owner: tuple[str, int]) -> str:
        poly, piece = self.dec.polygon, self.piece
        kind, k = owner
        source = np.asarray(piece.source)
        if kind == "vertex" and source[k] >= 0:
            return poly.describe_vertex(int(source[k]))
        if kind == "crosscut":
            return "the mouth of " + self.dec.describe_channel(piece.crosscuts[k].channel)
        return f"the point {poly.user_point(piece.z[k])}"


def owner_namer(dec, piece) -> Callable[[tuple[str, int]], str]:
    """``name(owner)`` for the arcs of ``piece`` (an entry of ``dec.thick``): see
    :class:`OwnerNamer`."""
    return OwnerNamer(dec, piece)


def prepare_piece(piece, options: MeshOptions, timings: dict[str, float], dec=None) -> PieceWork:
    """Solve the Schwarz–Christoffel map of a thick piece and choose its arcs I_j.

    ``dec`` (the :class:`~quadmesh.decompose.Decomposition` the piece belongs to) lets the
    messages name the piece and its vertices in the user's terms."""
    from .conformal import DiskMap

    what = THIS_PIECE if dec is None else dec.describe_piece(piece.index)
    name = None if dec is None else owner_namer(dec, piece)
    t0 = time.perf_counter()
    try:
        with span(0.0, 0.6):
            fmap = DiskMap.from_polygon(piece.z, center=piece.center, tol=options.conformal_tol)
    except ConformalMapError as exc:
        err = ConformalMapError(f"{what}: {exc.args[0]}", piece=piece.index)
        err.prevertices, err.prevertices_kind = exc.prevertices, exc.prevertices_kind
        err.too_large = exc.too_large
        raise err from exc
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        raise ConformalMapError(
            f"{what} ({len(piece.z)} vertices): its conformal map broke down numerically "
            f"({exc}); this part is too crowded for a disk map: use fewer, longer edges along "
            "it, or widen its narrow passages",
            piece=piece.index,
        ) from exc
    timings["conformal"] = timings.get("conformal", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    theta = np.mod(np.asarray(fmap.theta, dtype=float), 2 * np.pi)
    stretches = [(int(c.start), int(c.stop)) for c in piece.crosscuts]
    try:
        with span(0.6, 1.0, "choosing arcs"):
            psi, intervals, owners = best_rotation(theta, stretches, options, name)
    except DiskConstructionError as exc:
        # the map was solved: it is kept (without arcs) for the failure's partial result
        solved = PieceWork(
            piece.index, np.asarray(piece.z), fmap, theta, np.zeros((0, 2)), [], stretches
        )
        raise _failed(
            DiskConstructionError(f"{what}: {exc.args[0]}{_spacing_help(options)}"),
            solved,
            None,
            options.n,
            options.depth_step,
        ) from exc
    if psi != 0.0:
        fmap = RotatedMap(fmap, psi)
        theta = np.asarray(fmap.theta)
    timings["intervals"] = timings.get("intervals", 0.0) + time.perf_counter() - t0
    return PieceWork(
        piece.index,
        np.asarray(piece.z),
        fmap,
        theta,
        intervals,
        owners,
        stretches,
        what=what,
        name=name,
        piece=piece,
    )


def deepest_landmark(inner_height: float) -> float:
    """The deepest triangle landmark D5; the depth sequence must go beyond it."""
    from .disk.carleson_triangle import triangle_landmarks

    return float(triangle_landmarks(inner_height).D5)


def disk_and_image(
    pd: PieceWork,
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
            depth_max=None
            if dmax is None
            else max(dmax, deepest_landmark(options.inner_height) + 0.5),
        )

    try:
        with span(0.0, 0.2):
            disk = build(pd.intervals, pd.lemma_A or options.lemma_A)
    except DiskConstructionError as exc:
        # Lemma 2.2's chains of neighbouring arcs can interlock when A is small (a
        # scale-free ~3/40 of random arc sets at A = 4): this piece falls back to the
        # paper-sized A = 16 with arcs of 1/16 of the neighbouring gap (same cores, same
        # crosscut vertex counts, so the channels still match)
        if pd.lemma_A is not None or options.lemma_A >= FALLBACK_A:
            why = _disk_failure(pd, exc) + _spacing_help(options)
            raise _failed(DiskConstructionError(why), pd, None, n, step) from exc
        fallback = replace(options, lemma_A=FALLBACK_A, crosscut_ratio=FALLBACK_A)
        try:
            with span(0.0, 0.2):
                intervals, owners = piece_intervals(pd.theta, pd.stretches, fallback, pd.name)
                disk = build(intervals, FALLBACK_A)
        except DiskConstructionError as exc2:
            why = _disk_failure(pd, exc, exc2)
            raise _failed(DiskConstructionError(why), pd, None, n, step) from exc2
        if owners != pd.owners:
            why = _disk_failure(pd, exc, note="the wider spacing grouped its vertices differently")
            raise _failed(DiskConstructionError(why), pd, None, n, step) from exc
        pd.intervals, pd.lemma_A = intervals, FALLBACK_A
    timings["disk"] = timings.get("disk", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        with span(0.2, 0.95, "push-forward"):
            image = push_forward(pd.fmap, disk, pd.theta, pd.z)
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        err = ConformalMapError(
            f"{pd.what}: evaluating its conformal map at the disk mesh failed ({exc}); this "
            "part is too crowded for the map: use fewer, longer edges along it, or widen its "
            "narrow passages"
        )
        raise _failed(err, pd, disk, n, step) from exc
    if not np.all(np.isfinite(image)):
        err = ConformalMapError(
            f"{pd.what}: its conformal map gave non-finite mesh vertices; this part is too "
            "crowded for the map: use fewer, longer edges along it, or widen its narrow passages"
        )
        raise _failed(err, pd, disk, n, step)
    timings["push_forward"] = timings.get("push_forward", 0.0) + time.perf_counter() - t0
    pd.repair = None
    if options.repair:
        with span(0.95, 1.0, "angle repair"):
            image = _repair_image(pd, disk, image, timings)
    return disk, image


def piece_result(
    pd: PieceWork, disk=None, image: np.ndarray | None = None, n: int = 0, step: float = 0.0
) -> ThickPieceResult:
    """What thick piece ``pd`` computed, as a :class:`~quadmesh.result.ThickPieceResult` for a
    failed run's partial result: its map and arcs I_j, and its disk mesh and pushed-forward
    image where they were built (else None); ``n``, ``step``: the (n, depth step) in use. The
    arcs' owners are named as in a finished run (polygon vertex, or channel and end)."""
    owners: list[tuple] = []
    piece = pd.piece
    if piece is not None:
        source = np.asarray(piece.source)
        for kind, k in pd.owners:
            if kind == "vertex":
                owners.append(("vertex", int(source[k])))
            else:
                cc = piece.crosscuts[k]
                owners.append(("channel", int(cc.channel), int(cc.end)))
    return ThickPieceResult(
        index=pd.index,
        vertices=pd.z,
        map=pd.fmap,
        intervals=np.asarray(pd.intervals, dtype=float).reshape(-1, 2),
        interval_owner=tuple(owners),
        disk=disk,
        image=image,  # type: ignore[arg-type]  # None: not pushed forward
        n_used=int(disk.n) if disk is not None else n,
        depth_step_used=step,
    )


def _failed(exc: QuadmeshError, pd: PieceWork, disk, n: int, step: float) -> QuadmeshError:
    """``exc`` marked as the failure of piece ``pd``, carrying what that piece computed
    (its map, arcs and, if built, disk mesh) for the run's partial result."""
    exc.piece = pd.index
    exc.piece_stages = (piece_result(pd, disk, None, n, step),)
    return exc


@dataclass
class KeptStages:
    """The thick pieces' work of a run in progress (their maps and arcs, and the disk meshes
    and images of the current (n, depth step)), kept by reference at no cost so that a
    failure can report what was computed (:meth:`attach`)."""

    work: list[PieceWork] = field(default_factory=list)
    disks: list = field(default_factory=list)
    n: int = 0
    step: float = 0.0

    def start(self, n: int, step: float) -> list:
        """A new round of disk meshes at (n, step); returns the list to fill."""
        self.n, self.step, self.disks = n, step, []
        return self.disks

    def attach(self, exc: QuadmeshError) -> None:
        """Set ``exc.piece_stages`` to one result per piece whose map was solved (the failing
        piece's own stages, when ``exc`` carries them, take its place)."""
        own = {p.index: p for p in exc.piece_stages}
        out = []
        for k, pd in enumerate(self.work):
            if pd.index in own:
                out.append(own.pop(pd.index))
                continue
            disk, image = self.disks[k] if k < len(self.disks) else (None, None)
            out.append(piece_result(pd, disk, image, self.n, self.step))
        out.extend(own.values())  # a piece that failed while it was being prepared
        exc.piece_stages = tuple(sorted(out, key=lambda p: p.index))


#: A (and crosscut ratio) of the per-piece fallback when Lemma 2.2's arcs interlock.
FALLBACK_A = 16.0


def _spacing_help(options: MeshOptions) -> str:
    """A hint to lower ``lemma_A`` when it is above its default (wider spacing of the disk
    construction's arcs needs more room between a piece's vertices)."""
    default = MeshOptions().lemma_A
    if options.lemma_A <= default:
        return ""
    return f" (or lower MeshOptions(lemma_A={options.lemma_A:g}) towards the default {default:g})"


def _disk_failure(
    pd: PieceWork,
    exc: DiskConstructionError,
    exc2: DiskConstructionError | None = None,
    note: str = "",
) -> str:
    """The message of a disk construction that failed for piece ``pd``: where (the polygon
    vertices or passages behind the arcs the error names), why, and what would help."""
    arcs = getattr(exc2 if exc2 is not None else exc, "arcs", ())
    near = " and ".join(pd.owner_name(j) for j in arcs)
    where = f" near {near}" if near else ""
    why = exc.args[0]
    if exc2 is not None:
        why += f"; with the wider spacing MeshOptions(lemma_A={FALLBACK_A:g}) too: {exc2.args[0]}"
    if note:
        why += f" ({note})"
    return (
        f"{pd.what}: the disk construction cannot place its arcs{where}: {why}. The conformal "
        "map crowds this part's vertices together there: use fewer, longer edges near them, "
        "or widen the polygon there"
    )


#: Pushed-forward angles this far outside [60°, 120°] are not the O(1/n) distortion that the
#: adaptive loop cures but numerical breakdown (inverted or collapsed quads).
DEGENERATE_ANGLES = (20.0, 200.0)
#: Prevertex gap (radians) below which such a breakdown is attributed to crowding.
CROWDED_GAP = 1e-10


def refuse_degenerate(pd: PieceWork, ang: np.ndarray) -> None:
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
    what = getattr(pd, "what", THIS_PIECE)
    raise DiskConstructionError(
        f"{what}: its conformal map crowds boundary points to {gap:.2g} rad apart and the "
        f"mapped disk mesh is numerically degenerate there (angles "
        f"[{float(ang.min()):.1f}°, {float(ang.max()):.1f}°]): double precision cannot resolve "
        "the map of this part (typically a long curved corridor whose walls are chains of "
        "short edges); a larger n cannot help. Widen this passage, or draw its walls as long "
        "straight edges",
        piece=getattr(pd, "index", None),
    )


def angle_tol(image: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """(Q,) slack (degrees) on the angle bounds per quad: ANGLE_TOL plus what float64 storage
    of the vertices can put on the angles of that quad (as the final verifier allows)."""
    from .geometry import angle_rounding_slack_deg

    return ANGLE_TOL + angle_rounding_slack_deg(image, quads)


def repair_note(pd: PieceWork) -> tuple[str, ...]:
    """Fix notes of a piece (A fallback, local repair of its pushed-forward mesh) for
    ThickPieceResult.fixes."""
    notes: tuple[str, ...] = ()
    if pd.lemma_A is not None:
        notes = (
            "the disk construction's arcs were too close together at the default spacing: "
            f"rebuilt with the wider spacing lemma_A = {pd.lemma_A:g}",
        )
    rep = pd.repair
    if rep is None or rep.moved.size == 0:
        return notes
    return (
        *notes,
        f"angles [{rep.before[0]:.2f}, {rep.before[1]:.2f}] repaired locally: "
        f"{rep.moved.size} interior vertices moved by at most {100 * rep.max_shift:.2g}% of "
        f"their shortest edge, now [{rep.after[0]:.2f}, {rep.after[1]:.2f}]",
    )


def _repair_image(pd: PieceWork, disk, image: np.ndarray, timings: dict[str, float]) -> np.ndarray:
    """Local angle repair of a pushed-forward disk mesh (:mod:`quadmesh.repair`): only
    vertices off the boundary of W (not on the circle, not on the geodesics over the J_j
    whose images the thin parts are built on) move. Returns the image, repaired if needed
    and possible; ``pd.repair`` keeps the report."""
    from .geometry import unpaired_edges
    from .repair import repair_angles

    ang = quad_angles_deg(image, disk.quads)
    tol = angle_tol(image, disk.quads)[:, None]
    if not np.any((ang < ANGLE_MIN - tol) | (ang > ANGLE_MAX + tol)):
        return image
    t0 = time.perf_counter()
    edges, _ = unpaired_edges(disk.quads)
    movable = np.ones(image.size, dtype=bool)
    movable[np.unique(edges)] = False
    movable[np.asarray(disk.on_circle, dtype=bool)] = False
    for g in disk.gamma:
        movable[np.asarray(g)] = False
    got = repair_angles(image, disk.quads, movable, tol=angle_tol(image, disk.quads))
    timings["repair"] = timings.get("repair", 0.0) + time.perf_counter() - t0
    if got is None:
        return image
    pd.repair = got[1]
    return got[0]


def collect_angle_faults(
    pd: PieceWork, disk, image: np.ndarray, bad_kind: dict[str, tuple[float, float, int]]
) -> None:
    """Record in ``bad_kind`` (disk quad kind -> (min angle, max angle, piece index)) the
    kinds of disk quads whose pushed-forward angles leave [60°, 120°] beyond
    :func:`angle_tol`, merged with what earlier pieces recorded; raise at once when the
    piece's mesh is numerically degenerate (:func:`refuse_degenerate`)."""
    ang = quad_angles_deg(image, disk.quads)
    tol = angle_tol(image, disk.quads)[:, None]
    out = (ang < ANGLE_MIN - tol) | (ang > ANGLE_MAX + tol)
    refuse_degenerate(pd, ang)
    code = disk.kind_code
    for c in np.unique(code[out.any(axis=1)]):
        kind = KIND_NAMES[c]
        sel = ang[code == c]
        lo, hi = float(sel.min()), float(sel.max())
        old = bad_kind.get(kind, (ANGLE_MIN, ANGLE_MAX, pd.index))
        bad_kind[kind] = (min(lo, old[0]), max(hi, old[1]), pd.index)
