"""The mesher: :func:`mesh_polygon` runs every stage of Bishop's construction.

Stages:

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

import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor
from contextlib import closing
from dataclasses import replace
from typing import Any

import numpy as np

from .errors import (
    Cancelled,
    ConformalMapError,
    DiskConstructionError,
    MeshVerificationError,
    PartialResult,
    PolygonError,
    QuadmeshError,
    ThinPartError,
)
from .glue import Assembler, glue_thick_pieces, glue_thin_parts
from .parallel import (
    PieceRunner,
    apply_disk,
    attach_piece,
    blas_threads,
    disk_task,
    prepare_task,
)
from .polygon import Polygon, signed_area, validate_polygon
from .progress import Run, active, checkpoint, running
from .result import MeshOptions, MeshResult, ThinPartResult
from .thick import KeptStages, PieceWork, collect_angle_faults
from .thin.corridor import whole_corridor

__all__ = ["MeshOptions", "MeshResult", "mesh_polygon"]

# Backwards-compatible names: the stages' helpers lived here before they moved into
# :mod:`quadmesh.arcs`, :mod:`quadmesh.pushforward`, :mod:`quadmesh.thick` and
# :mod:`quadmesh.glue`; tests and older callers still import them from this module.
from .arcs import best_rotation as _best_rotation  # noqa: F401
from .arcs import piece_intervals as piece_intervals
from .arcs import vertex_intervals as vertex_intervals
from .pushforward import RotatedMap as _RotatedMap  # noqa: F401
from .pushforward import evaluate_map as _evaluate_map  # noqa: F401
from .pushforward import project_to_sides as _project_to_sides  # noqa: F401
from .pushforward import push_forward as _push_forward  # noqa: F401
from .pushforward import triangle_centres as _triangle_centres  # noqa: F401
from .thick import angle_tol as _angle_tol  # noqa: F401
from .thick import deepest_landmark as _d5  # noqa: F401
from .thick import prepare_piece as _prepare_piece  # noqa: F401
from .thick import refuse_degenerate as _refuse_degenerate  # noqa: F401

ProgressCallback = Callable[[str, float], None]
CancelCallback = Callable[[], bool]

#: n values tried by the adaptive loop, in order (MeshOptions.adaptive).
ADAPTIVE_N = (2, 3, 4, 6, 8)
#: The adaptive loop halves the Carleson depth step down to this value.
MIN_DEPTH_STEP = 0.125


#: A polygon whose bounding-box centre lies beyond this many diameters from 0 is meshed
#: translated to the origin (see :func:`_working_origin`): FAR_FROM_ORIGIN for a part cut off
#: the user's polygon (an arm's body, a bridge's sides: such a part, meshed at its own origin,
#: cannot be matched to the rest by position), FAR_FROM_ORIGIN_TOP for the user's polygon
#: itself. At 1 diameter the translation is still exact and halves (or better) the magnitude
#: of every coordinate, so the rounding of the smallest quads' corners shrinks with it: an
#: image contour 3 diameters from (0, 0) (scikit-image page, 56 vertices) had a 120° corner of
#: a quad 3e-9 of its diameter read 120.0000103° in absolute coordinates and is verified
#: relative to its centre.
FAR_FROM_ORIGIN = 4.0
FAR_FROM_ORIGIN_TOP = 1.0


def _working_origin(poly: Polygon, far: float = FAR_FROM_ORIGIN) -> complex:
    """Exact translation that brings a polygon far from 0 to the origin (0 if it is near).

    Every stage evaluates plane points as vertex + offset; with coordinates ~1e6 and features
    ~1 a float64 vertex carries an absolute error ~1e-10, which the conformal map's accuracy
    checks (§1.7: boundary deviation, round trip) and the pushed-forward Carleson cells near
    the vertices (sizes down to ~1e-8 of the diameter) cannot absorb: a random 40-gon of
    diameter 1.7 at (1e6, −3e6) failed its map checks (round trip 1.1e-9) and, with the
    checks off, gave Carleson triangle angles in [0.55°, 359°]. Per coordinate, the centre c
    of the bounding box is used when |c| > far · diameter (far ≥ 1): then every coordinate x
    lies in [c/2, 2c], so x − c is exact (Sterbenz) and (x − c) + c gives x back bit for bit.
    """
    if far < 1.0:
        raise ValueError(f"far must be at least 1 for an exact translation, got {far}")
    v = poly.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    c = (lo + hi) / 2
    c = np.where(np.abs(c) > far * poly.diameter, c, 0.0)
    return complex(c[0], c[1])


def mesh_polygon(
    polygon: object,
    options: MeshOptions | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelCallback | None = None,
    *,
    executor: Executor | None = None,
) -> MeshResult:
    """Mesh a simple polygon by quadrilaterals with every new angle in [60°, 120°].

    Args:
        polygon: an (n, 2) float array, a complex array or a :class:`~quadmesh.Polygon`.
        options: the knobs (:class:`MeshOptions`); defaults from the design notes.
        progress: optional callback ``progress(stage, fraction)``, called at every stage and
            at most every 0.05 s inside the long loops (fractions never decrease).
        cancel: optional callable polled between stages and at most every 0.05 s inside the
            long loops (:mod:`quadmesh.progress`); returning True raises
            :class:`~quadmesh.errors.Cancelled`.
        executor: runs the thick pieces' own stages (map, arcs, disk mesh, push-forward,
            repair) when the decomposition has at least two: any
            :class:`concurrent.futures.Executor` (the executor of a ``dask.distributed``
            Client, ...), used and left open. Without it, ``options.jobs`` > 1 makes a process
            pool of that many workers for the call. The mesh is the same bit for bit as
            the serial run's (:mod:`quadmesh.parallel`).

    Returns:
        A :class:`MeshResult` whose ``mesh`` passed :meth:`QuadMesh.verify`.

    Raises:
        PolygonError: invalid input. ConformalMapError, DiskConstructionError,
        ThinPartError, DecompositionError: a stage could not handle the input.
        MeshVerificationError: the assembled mesh failed verification (never returned).
        Cancelled: ``cancel()`` returned True.
    """
    options = options or MeshOptions()
    runner = PieceRunner(options.jobs, executor)
    failed = True
    top = getattr(_nesting, "value", 0) == 0
    if top:  # the knotted arms' budgets: for the user's polygon and every part inside it
        _nesting.knot_meshes, _nesting.knot_failures = KNOT_MESHES, KNOT_FAILED_BODIES
    try:
        with running(progress, cancel) as run, blas_threads(options.blas_threads):
            first: dict[str, str] = {}
            try:
                result = _run_stages(polygon, options, run, runner, first)
            except QuadmeshError as exc:
                sized = _sized_retry(options, exc)
                if sized is None:
                    raise
                _nesting.retry = True  # a chain (minutes on a river) is not tried again
                try:
                    # with method="blocks" the layout search is not repeated: it failed
                    result = _run_stages(
                        polygon, sized, run, runner, blocks_failed=first.get("fallback")
                    )
                except Cancelled:
                    raise
                except QuadmeshError:
                    raise exc from None
                finally:
                    _nesting.retry = False
        failed = False
        return result
    finally:
        runner.close(failed)
        if top:
            _nesting.knot_meshes = _nesting.knot_failures = None


def _sized_retry(options: MeshOptions, exc: QuadmeshError) -> MeshOptions | None:
    """The options for one more run after the user's polygon failed with ``exc`` in a stage
    of the paper's construction: arcs chosen for size (``arc_choice="sized"``), or None for
    bad input, a cancelled run, sized arcs already, ``adaptive=False`` (the user fixed the
    parameters) and the parts inside an arm or bridge search (the retry is for the user's
    polygon as a whole). Larger crosscuts near reflex corners give quads that float64 can
    hold (Computer Modern "g": a 323° ear's sector of 6e-11 failed the final check) and
    parts that mesh where centred arcs made them fail (Computer Modern "s", 67,217 quads)."""
    if isinstance(exc, (PolygonError, Cancelled)) or options.arc_choice != "centred":
        return None
    if not options.adaptive:
        return None
    if getattr(_nesting, "value", 0) > 0:
        return None
    return replace(options, arc_choice="sized")


def _run_stages(
    polygon: object,
    options: MeshOptions,
    run: Run | None,
    runner: PieceRunner,
    notes: dict[str, str] | None = None,
    blocks_failed: str | None = None,
) -> MeshResult:
    """The stages of :func:`mesh_polygon`, reporting to ``run`` (None: no callbacks) and
    running the thick pieces' own stages through ``runner``. ``notes["fallback"]`` receives
    why ``method="blocks"`` fell back (also when a later stage fails); ``blocks_failed``: that
    reason from an earlier run of the same polygon, whose layout search is then skipped."""
    from .decompose import DecomposeOptions, decompose
    from .mesh import finalize_mesh

    timings: dict[str, float] = {}

    def report(stage: str, fraction: float, end: float | None = None) -> None:
        # a stage starts at ``fraction``; its inner checkpoints move the bar up to ``end``
        if run is not None:
            run.enter(stage, fraction, end)

    report("validate", 0.0)
    t0 = time.perf_counter()
    poly: Polygon = validate_polygon(polygon)
    nested = getattr(_nesting, "value", 0) > 0
    origin = _working_origin(poly, FAR_FROM_ORIGIN if nested else FAR_FROM_ORIGIN_TOP)
    if nested and getattr(_nesting, "keep_frame", False):
        origin = 0j  # a knot of a chain: meshed where it lies, verified there (_mesh_chain)
    work_poly = poly.translated(-origin) if origin else poly
    timings["validate"] = time.perf_counter() - t0

    blocks, fallback = None, blocks_failed
    if options.method == "blocks" and blocks_failed is None:
        from .blocks import BlockLayoutError, mesh_blocks

        report("blocks", 0.05, 0.85)
        t0 = time.perf_counter()
        try:
            z_b, quads_b, blocks, _info = mesh_blocks(
                work_poly.z,
                options.size,
                _face_mesher(options, run.cancel if run is not None else None, runner.executor),
            )
        except BlockLayoutError as exc:
            fallback = f"no block layout: {exc.args[0]}; meshed by the paper's construction"
        timings["blocks"] = time.perf_counter() - t0
        if blocks is not None:
            report("verify", 0.9, 1.0)
            t0 = time.perf_counter()
            try:
                mesh, mesh_origin, verification = finalize_mesh(poly, z_b, quads_b, origin)
            except MeshVerificationError as exc:
                # never expected (every layout is checked as it is built), but a block mesh
                # that fails the strict check is not returned: the paper's construction is
                fallback = (
                    f"the block mesh failed verification ({exc.args[0]}); meshed by the "
                    "paper's construction"
                )
                blocks = None
            timings["verify"] = time.perf_counter() - t0
        if blocks is not None:
            block_result = MeshResult(
                polygon=poly,
                options=options,
                decomposition=None,
                pieces=(),
                thin=(),
                mesh=mesh,
                quality=verification.quality,
                verification=verification,
                timings=timings,
                quad_source=_block_sources(len(quads_b), blocks),
                origin=origin,
                blocks=blocks,
                mesh_origin=mesh_origin,
            )
            if blocks.fallback_faces:
                return _fewer_quads(block_result, polygon, options, run, runner)
            report("done", 1.0)
            return block_result

    if notes is not None and fallback:
        notes["fallback"] = fallback
    # the paper's construction, also for the parts that arms and bridges cut off (with blocks
    # chosen and no layout found, those parts were meshed by blocks again: their cuts carried
    # the layouts' points, which no ladder joined — the STIX "G" was refused after 75 s)
    user_options = options
    if options.method != "bishop":
        options = replace(options, method="bishop")

    report("decompose", 0.05, 0.08)
    t0 = time.perf_counter()
    dec = decompose(work_poly, DecomposeOptions(delta=options.channel_delta))
    timings["decompose"] = time.perf_counter() - t0

    try:
        # A polygon that stays one crowded thick piece (a pen stroke, a letter, a river) is a
        # corridor: meshed by a ladder of straight cells, without a conformal map.
        report("corridor", 0.08, 0.1)
        t0 = time.perf_counter()
        corridor, corridor_why = whole_corridor(dec)
        timings["corridor"] = time.perf_counter() - t0
        armed = None
        # not a corridor as a whole, or a piece whose map would be refused from its largest
        # inscribed disk (its map can start from a less crowded centre, but an arm usually
        # takes fewer quads): an arm (a corridor from one tip) and the body behind it
        arm_first = corridor is None and (
            bool(corridor_why) or any(np.isfinite(p.inscribed_gap) for p in dec.thick)
        )
        if arm_first:
            armed = _mesh_arm_and_body(
                dec, options, run.cancel if run is not None else None, runner.executor
            )
        if corridor is not None:
            asm = Assembler()
            gl = asm.add_vertices(corridor.vertices)
            asm.add_quads(gl[corridor.quads], source=3)
            pieces, thin = [], [ThinPartResult("corridor", 0, corridor, gl)]
            dec = replace(dec, thick=(), corners=())
        elif armed is not None:
            asm, pieces, thin, dec = armed
        else:
            try:
                asm, pieces, thin = _mesh_thick_and_thin(dec, options, report, timings, runner)
            except (ConformalMapError, DiskConstructionError) as exc:
                if getattr(exc, "too_large", False):
                    raise  # more vertices than the machine's memory holds a map for
                # angles out of range after the adaptive loop (or with it off) are no crowding:
                # no bridge, no other centre
                crowded = not getattr(exc, "distortion", False)
                armed = _rescue(dec, options, exc, run, report, timings, runner, arm_first, crowded)
                if armed is None and corridor_why:
                    raise type(exc)(
                        f"{exc.args[0]}; meshing it as a corridor of straight cells failed too: "
                        f"{corridor_why}. A wider passage or longer straight walls there would "
                        "help both ways"
                    ) from exc
                if armed is None:
                    raise
                asm, pieces, thin, dec = armed
    except QuadmeshError as exc:
        if not isinstance(exc, Cancelled) and exc.partial is None:
            exc.partial = PartialResult.of(exc, poly, dec, origin)
        raise

    report("verify", 0.9, 1.0)
    t0 = time.perf_counter()
    mesh, mesh_origin, verification, source = _verified(poly, asm, options, origin)
    timings["verify"] = time.perf_counter() - t0
    quality = verification.quality
    report("done", 1.0)
    return MeshResult(
        polygon=poly,
        options=user_options,
        decomposition=dec,
        pieces=tuple(pieces),
        thin=tuple(thin),
        mesh=mesh,
        quality=quality,
        verification=verification,
        timings=timings,
        quad_source=source,
        origin=origin,
        fallback=fallback,
        mesh_origin=mesh_origin,
    )


def _verified(poly: Polygon, asm: Assembler, options: MeshOptions, origin: complex):
    """The assembled mesh refined (``options.refine``) and verified as it will be stored:
    absolute coordinates, or relative to ``origin`` when far from (0, 0) float64 cannot hold
    the angles (:attr:`MeshResult.mesh_origin`). Returns (mesh, mesh origin, report, quad
    sources); raises MeshVerificationError."""
    from .mesh import finalize_mesh
    from .refine import refine_quads

    z = asm.vertices()  # relative to the working origin
    quads, source = asm.all_quads()
    if options.refine > 1:
        z, quads, parent = refine_quads(z, quads, options.refine, origin=origin)
        source = source[parent]
    mesh, mesh_origin, verification = finalize_mesh(poly, z, quads, origin)
    return mesh, mesh_origin, verification, source


def _rescue(dec, options, exc, run, report, timings, runner, arm_first: bool, crowded: bool):
    """Other routes after the paper's construction on ``dec`` failed with ``exc``: an arm and
    the body behind it (unless ``arm_first``: it was tried), then — where the failure is
    crowding (``crowded``), not a distortion the adaptive loop could not fix — a bridge across
    the middle, then the failing pieces' maps from their least crowded centres (arms and
    bridges first: they take fewer quads, cmr10 "9" 68,552 by a bridge, 86,282 so), then a
    knotted arm (:func:`_mesh_knotted_arm`) and, for the user's polygon, a chain. Returns
    (assembler, pieces, thin parts, decomposition) or None."""
    stop = run.cancel if run is not None else None
    armed = None
    if not arm_first:  # one piece of several too crowded: an arm
        armed = _mesh_arm_and_body(dec, options, stop, runner.executor)
    if armed is None and crowded:
        # crowded beyond what arms relieve: a bridge across the middle (also when the map
        # was solved but the disk construction failed: STIX "h" and cmr10 "2" are crowded to
        # ~1e-14 rad, arcs of 1e-16 rad)
        armed = _mesh_bridge(dec, options, stop, runner.executor)
    if armed is None and crowded:
        moved = _recentred(dec, exc)
        if moved is not None:
            try:
                armed = (*_mesh_thick_and_thin(moved, options, report, timings, runner), moved)
            except (ConformalMapError, DiskConstructionError):
                armed = None
    if armed is None and crowded:
        # an arm whose own tip no ladder leaves (a hoof, a peninsula's ragged end): the tip
        # cut off as a knot (after the routes above, whose meshes glyphs keep)
        from .thin.corridor import crowded_place

        toward = crowded_place(dec)
        if toward is not None:
            armed = _mesh_knotted_arm(dec, options, stop, runner.executor, toward)
    if (
        armed is None
        and crowded
        and getattr(_nesting, "value", 0) == 0
        and not getattr(_nesting, "retry", False)
    ):
        # last: ladders restarted past every place where one gets stuck (rivers, contours);
        # not again in the retry with arcs chosen for size (a chain can take minutes)
        armed = _mesh_chain(dec, options, stop, runner.executor)
    return armed


def _more_help(options: MeshOptions) -> str:
    """What the user can try when the adaptive loop (or its absence) left a part unmeshed."""
    if not options.adaptive:
        return (
            "Try MeshOptions(adaptive=True) (it lowers the depth step and raises n until the "
            "angles fit), or use fewer, longer edges near this place"
        )
    more = max(ADAPTIVE_N[-1], 2 * options.max_n)
    return (
        f"Try MeshOptions(max_n={more}) (slower, more quads), or use fewer, longer edges near "
        "this place"
    )


def _mesh_thick_and_thin(
    dec, options: MeshOptions, report, timings: dict[str, float], runner: PieceRunner
):
    """Bishop's construction proper: every thick piece's map, disk mesh and push-forward, then
    the thin parts glued onto them, in the adaptive loop (one (n, depth step) for all pieces).
    The pieces' own stages run through ``runner`` (in parallel when it has an executor).
    Returns the assembler, the thick-piece results and the thin-part results. A failure
    carries what the thick pieces had computed (:meth:`quadmesh.thick.KeptStages.attach`)."""
    kept = KeptStages()
    try:
        return _thick_and_thin(dec, options, report, timings, kept, runner)
    except QuadmeshError as exc:
        if not isinstance(exc, Cancelled):
            kept.attach(exc)
        raise


def _no_maps(errors: list[ConformalMapError]) -> ConformalMapError:
    """One error for the thick pieces whose conformal map failed: the first one's (and its
    prevertex placement), naming the others too (``other_failed``: their piece indices)."""
    first = errors[0]
    if len(errors) == 1:
        return first
    text = "\n".join(f"{k + 1}. {e.args[0]}" for k, e in enumerate(errors))
    err = ConformalMapError(
        f"{len(errors)} parts of the polygon have no conformal map:\n{text}", piece=first.piece
    )
    err.prevertices, err.prevertices_kind = first.prevertices, first.prevertices_kind
    err.other_failed = tuple(e.piece for e in errors[1:] if e.piece is not None)
    err.too_large = any(e.too_large for e in errors)
    err.__cause__ = first
    return err


def _thick_and_thin(
    dec,
    options: MeshOptions,
    report,
    timings: dict[str, float],
    kept: KeptStages,
    runner: PieceRunner,
):
    """The stages of :func:`_mesh_thick_and_thin`, keeping the pieces' work in ``kept``.
    Every piece's result is taken in piece order, so ``kept`` and the adaptive loop see what
    the serial run sees, wherever the pieces ran."""

    def share(stage: str, lo: float, width: float):
        return lambda a, b: report(stage, lo + width * a, lo + width * b)

    work: list[PieceWork] = kept.work
    tasks = [(piece, options, dec) for piece in dec.thick]
    # a piece's work grows with its arcs I_j: one per polygon vertex it holds, one per crosscut
    cost = [int(np.sum(np.asarray(p.source) >= 0)) + len(p.crosscuts) for p in dec.thick]
    stage = share("conformal map", 0.1, 0.3)
    unmapped: list[ConformalMapError] = []
    with closing(runner.run(prepare_task, tasks, timings, stage, cost)) as it:
        for pd, _ in it:
            if isinstance(pd, ConformalMapError):
                # the other pieces' maps are still solved (a successful run needs them too),
                # so that the failure names every piece without a map, not only the first
                unmapped.append(pd)
            else:
                work.append(attach_piece(pd, dec))
    if unmapped:
        raise _no_maps(unmapped)

    # One (n, depth step) for all pieces: both sides of a channel must carry the same
    # crosscut vertex count. Pentagon images out of range -> raise n (Lemma 4.1's angles
    # converge like O(1/n)); Carleson images out of range -> halve the depth step.
    n, step, dmax = options.n, options.depth_step, options.depth_max
    fixes: list[str] = []
    while True:  # thin parts failing -> raise n and rebuild
        while True:
            disks = kept.start(n, step)
            bad_kind: dict[str, tuple[float, float, int]] = {}
            tasks = [(pd, n, step, dmax, options) for pd in work]
            stage = share("disk mesh", 0.4, 0.3)
            with closing(runner.run(disk_task, tasks, timings, stage, cost)) as it:
                for pd, out in zip(work, it):
                    disk, image = apply_disk(pd, out)
                    disks.append((disk, image))
                    collect_angle_faults(pd, disk, image, bad_kind)
            if not bad_kind:
                break
            what = ", ".join(
                f"{k.replace('_', ' ')} cells [{v[0]:.2f}°, {v[1]:.2f}°] in "
                f"{dec.describe_piece(v[2])}"
                for k, v in bad_kind.items()
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
                err = DiskConstructionError(
                    f"mapped disk mesh angles out of [60°, 120°]: {what} (n = {n}, depth "
                    f"step {step:g}); the conformal map distorts the disk mesh too much there. "
                    f"{_more_help(options)}",
                    piece=next(iter(bad_kind.values()))[2],
                )
                err.distortion = True
                raise err

        asm = Assembler()
        pieces, gam = glue_thick_pieces(asm, work, disks, dec, n, step, tuple(fixes))
        t0 = time.perf_counter()
        try:
            thin = glue_thin_parts(asm, dec, gam, options, report)
        except ThinPartError as exc:
            # a larger n puts more vertices on every crosscut (3·2n + 1 on its pentagon
            # edges), so the thin parts' chords get shorter and flatter
            timings["thin"] = timings.get("thin", 0.0) + time.perf_counter() - t0
            # Near a reflex vertex one hyperbolic unit of a crosscut's Carleson part spans up
            # to ~1 rad of polar angle about the vertex (quasi-hyperbolic metric |dz|/r), so
            # only a finer depth sequence puts more crosscut vertices there; n refines only
            # the pentagon part (measured on a 331° stroke end and a 1:100 V-slit).
            if not options.adaptive:
                raise ThinPartError(f"{exc.args[0]}. {_more_help(options)}") from exc
            if step > MIN_DEPTH_STEP:
                step = max(step / 2, MIN_DEPTH_STEP)
                fixes.append(f"{exc.args[0]}: depth step lowered to {step:g}")
            elif n < options.max_n:
                n = next(m for m in (*ADAPTIVE_N, options.max_n) if m > n)
                fixes.append(f"{exc.args[0]}: n raised to {n}")
            else:
                raise ThinPartError(f"{exc.args[0]}. {_more_help(options)}") from exc
            continue
        timings["thin"] = timings.get("thin", 0.0) + time.perf_counter() - t0
        break
    return asm, pieces, thin


def _recentred(dec, exc: QuadmeshError):
    """``dec`` with the map centre of every thick piece that ``exc`` names (its ``piece`` and
    ``other_failed``) moved where its map is least crowded
    (:func:`quadmesh.decompose.recentred`), or None when none of them moves."""
    from .decompose import recentred

    failed = [exc.piece, *getattr(exc, "other_failed", ())]
    out = None
    for k in dict.fromkeys(int(p) for p in failed if p is not None):
        if 0 <= k < len(dec.thick):
            out = recentred(dec if out is None else out, k) or out
    return out


#: A bridge is tried for the polygon the user gave and, within its search, inside the parts a
#: bridge cuts off (BRIDGE_DEPTH), never inside an arm's body outside such a search (a failing
#: bridge costs several part meshes); at most this many splits (cut and side) are meshed, those
#: whose ladder reaches the far end first.
BRIDGE_TRIES = 4
#: ... and at most this many parts (near parts and far bodies) meshed in all: a count, not a
#: time, so that what meshes does not depend on the machine.
BRIDGE_MESHES = 8
#: ... and only for polygons of at most this many vertices: glyphs have 30–140, buffered
#: random walks 170–300 (walks 0 and 8 of the families, 251 and 248 vertices, mesh by bridges:
#: 12,452 and 146,215 quads, 14–16 s); a failing search on the 299-vertex X of scikit-image's
#: "text" takes 60 s instead of 6 s, and each part of a long river or coast tens of seconds.
BRIDGE_MAX_VERTICES = 300
#: Parts of a bridge (its near side, its far body) may be split by a bridge again, down to this
#: nesting depth (0: only the user's polygon), all from the one budget of BRIDGE_MESHES; for
#: polygons of at most BRIDGE_NESTED_MAX_VERTICES vertices (glyphs: STIX "n", cmr10 "3" and
#: "5" mesh so; a failing nested search on the 299-vertex text_2 contour took 142 s).
BRIDGE_DEPTH = 1
BRIDGE_NESTED_MAX_VERTICES = 160
_nesting = threading.local()


def _mesh_part(
    w: np.ndarray,
    options: MeshOptions,
    cancel: CancelCallback | None,
    executor: Executor | None,
    moved_ok: bool = False,
) -> MeshResult | None:
    """``mesh_polygon`` of a part cut off the user's polygon (an arm's body, a bridge's sides),
    or None when it is refused or meshed relative to an origin (its points could not be
    matched by position); with ``moved_ok`` also a part whose stages ran relative to an
    origin but whose mesh passed in absolute coordinates. Bridges are not tried inside it."""
    from .errors import QuadmeshError

    depth = getattr(_nesting, "value", 0)
    _nesting.value = depth + 1
    try:
        r = mesh_polygon(
            np.column_stack([w.real, w.imag]), options, cancel=cancel, executor=executor
        )
    except Cancelled:
        raise
    except QuadmeshError:
        return None
    finally:
        _nesting.value = depth
    return None if (r.mesh_origin or (r.origin and not moved_ok)) else r


def _fewer_quads(
    block_result: MeshResult,
    polygon: object,
    options: MeshOptions,
    run: Run | None,
    runner: PieceRunner,
) -> MeshResult:
    """A block mesh with faces that fell back to the paper's construction, or the paper's
    construction on the whole polygon, whichever has fewer quads: the face meshes' clustered
    points, carried along chords where no transition cell takes them, can outnumber the
    quads the blocks save (measured on glyphs: STIX "X" 32,949 against 101,036, but STIX "2"
    26,355 against 22,576). The whole polygon's run is the one a layout that did not close
    at all would have had."""
    n_b = block_result.mesh.n_quads
    try:
        whole = _run_stages(
            polygon, options, run, runner, blocks_failed="(blocks with faces falling back)"
        )
    except Cancelled:
        raise
    except QuadmeshError:
        return block_result
    if run is not None:
        run.enter("done", 1.0)
    if n_b <= whole.mesh.n_quads:
        return block_result
    k = len(block_result.blocks.fallback_faces)
    return replace(
        whole,
        fallback=(
            f"a block layout with {k} face{'s' if k > 1 else ''} meshed by the paper's "
            f"construction had {n_b:,} quads, more than the paper's construction on the whole "
            f"polygon ({whole.mesh.n_quads:,}); meshed by the paper's construction"
        ),
    )


def _block_sources(n_quads: int, layout: Any) -> np.ndarray:
    """:attr:`MeshResult.quad_source` of a block mesh: 4 for the quads of the layout, and for
    those of faces that fell back to the paper's construction (the mesh's last
    ``layout.fallback_quads``, :func:`quadmesh.blocks.mesh_partial_layout`) the stage of that
    construction that made them."""
    src = np.full(n_quads, 4, dtype=np.int8)
    k = getattr(layout, "fallback_quads", 0)
    if k:
        src[n_quads - k :] = layout.fallback_source
    return src


def _face_mesher(
    options: MeshOptions, cancel: CancelCallback | None, executor: Executor | None
) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
    """The paper's construction for one face of a block layout that did not split into cells
    (:func:`quadmesh.blocks.mesh_partial_layout`): ``(points, quads, quad sources)`` or
    None."""
    bishop = replace(options, method="bishop")

    def mesh_face(w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        r = _mesh_part(np.asarray(w, dtype=np.complex128), bishop, cancel, executor, True)
        if r is None:
            return None
        src = r.quad_source if r.quad_source is not None else np.zeros(len(r.mesh.quads))
        return r.mesh.z, r.mesh.quads, np.asarray(src, dtype=np.int8)

    return mesh_face


def _add_mesh(asm: Assembler, r: MeshResult) -> np.ndarray:
    """Add the mesh of ``r`` to ``asm``, each quad with its source; returns its vertices' ids."""
    ids = asm.add_vertices(r.mesh.z)
    src = np.zeros(len(r.mesh.quads), dtype=np.int64)
    if r.quad_source is not None:
        src = np.asarray(r.quad_source, dtype=np.int64)
    for k in np.unique(src):
        asm.add_quads(ids[r.mesh.quads[src == k]], source=int(k))
    return ids


def _cut_ids(w: np.ndarray, za: complex, zb: complex) -> np.ndarray | None:
    """Indices of the points of ``w`` on the segment from ``za`` to ``zb`` (both ends, which
    must be points of ``w`` exactly), in order from ``za``; None when an end is missing."""
    t = (w - za) / (zb - za)
    on = np.flatnonzero((np.abs(t.imag) < 1e-9) & (t.real > 1e-12) & (t.real < 1 - 1e-12))
    ends = [np.flatnonzero(w == za), np.flatnonzero(w == zb)]
    if ends[0].size != 1 or ends[1].size != 1:
        return None
    return np.r_[ends[0], on[np.argsort(t.real[on])], ends[1]]


def _rung_ids(lay, r: MeshResult, k: int) -> np.ndarray | None:
    """Indices of the points of ``r``'s mesh on rung ``k`` of the ladder ``lay``, in order from
    its L end (:func:`_cut_ids`); None when an end is missing."""
    a, b = (int(x) for x in lay.rungs[k])
    return _cut_ids(r.mesh.z, lay.vertices[a], lay.vertices[b])


def _mesh_bridge(
    dec, options: MeshOptions, cancel: CancelCallback | None, executor: Executor | None = None
):
    """A polygon crowded along a corridor between two bodies (the two ends of a "C", a glyph's
    bowl and its ball terminal), split by a straight crosscut across the corridor's middle
    (:func:`~quadmesh.thin.corridor.bridge_cuts`): the part on one side meshed by
    :func:`mesh_polygon`, the other side entered by a ladder from the cut — a *bridge*, started
    from a virtual cap beyond the cut so that its first rung is the cut — up to where it gets
    stuck, the rest behind it (the far body) meshed by :func:`mesh_polygon`. The bridge's first
    rung takes the near part's points on the cut and its last rung the far body's; their counts
    meet by transition cascades, which change a count by two at a time, so a far cut whose
    count differs in parity is moved one to three rungs back (:func:`_bridge_mesh`); when no
    cut of any split joins so, the cuts of odd difference already meshed are joined by a
    cascade that starts with a parity row (one wall carries one more point). Splits whose
    far side is one corridor (no far body) are tried first; at most :data:`BRIDGE_TRIES` splits
    and :data:`BRIDGE_MESHES` part meshes, for at most :data:`BRIDGE_MAX_VERTICES` vertices;
    first with parts that are not bridged again, then with parts that may be, down to
    :data:`BRIDGE_DEPTH` (the bridges inside a part draw on the same budget). Returns
    (assembler, the near part's thick-piece results, thin-part results, the near part's
    decomposition) or None; the far body's quads are in the mesh, its stage results are not
    kept."""
    depth = getattr(_nesting, "value", 0)
    if dec.polygon.z.size > BRIDGE_MAX_VERTICES:
        return None
    if depth == 0:
        # first with parts that are not bridged again (fewer quads: walk_0 12,452 against
        # 100,113), then, when none joins, with parts that may be
        nested = BRIDGE_DEPTH if dec.polygon.z.size <= BRIDGE_NESTED_MAX_VERTICES else 0
        try:
            for deepest in range(nested + 1):
                _nesting.bridge_meshes = BRIDGE_MESHES
                _nesting.bridge_depth = deepest
                got = _bridge_search(dec, options, cancel, executor)
                if got is not None:
                    return got
            return None
        finally:  # outside a search no part is bridged (the next call starts afresh)
            _nesting.bridge_meshes = _nesting.bridge_depth = 0
    if depth > getattr(_nesting, "bridge_depth", 0) or getattr(_nesting, "bridge_meshes", 0) <= 0:
        return None
    return _bridge_search(dec, options, cancel, executor)


def _bridge_search(
    dec, options: MeshOptions, cancel: CancelCallback | None, executor: Executor | None
):
    """The splits of :func:`_mesh_bridge` tried in turn, each part meshed from the budget of
    part meshes left (``_nesting.bridge_meshes``)."""
    from .thin.corridor import bridge_cuts, bridge_layout, shorter_bridges

    def part(w: np.ndarray) -> MeshResult | None:
        # one budget of part meshes for the user's polygon and the bridges inside its parts
        if _nesting.bridge_meshes <= 0:
            return None
        _nesting.bridge_meshes -= 1
        return _mesh_part(w, options, cancel, executor)

    splits = []
    for cut in bridge_cuts(dec.polygon.z):
        for near, far in ((cut.first, cut.second), (cut.second, cut.first)):
            got = bridge_layout(far, min_rungs=2)
            if got is not None:
                splits.append((near, *got))
    # a far side that is one corridor first: its bridge has one fixed end only; bridges of a
    # single cell (across a straight stem) after all others
    splits.sort(key=lambda t: t[3] is not None)
    single = [t for t in splits if len(t[1].rungs) < 3]
    splits = [t for t in splits if len(t[1].rungs) >= 3][:BRIDGE_TRIES] + single[:BRIDGE_TRIES]
    odd: list[tuple] = []  # meshed far bodies whose cut count differs in parity
    for near, lay, q, body in splits:
        near_r = part(near)
        if near_r is None:
            continue
        start = _rung_ids(lay, near_r, 0)
        if start is None:
            continue
        # the far body's cut: where the ladder stops, else a rung or three before (its mesh
        # then puts another number of points on the cut; runs keep their parity)
        ends = [(lay, None)] if body is None else [(lay, body), *shorter_bridges(lay, q)]
        for lay_k, body_k in ends:
            got = _bridge_mesh(lay_k, q, near_r, start, body_k, part, odd)
            if got is not None:
                return got
    # only then the cuts of odd difference (every bridge that joined before keeps its mesh)
    for args in odd:
        got = _bridge_join(*args)
        if got is not None:
            return got
    return None


def _bridge_mesh(lay, q: np.ndarray, near_r: MeshResult, start: np.ndarray, body, part, odd: list):
    """The bridge ``lay`` (first rung on the near part's cut, ``start``: the near mesh's points
    there in order) meshed and glued to the near part's mesh and, when ``body`` is given, to
    that body's mesh (``part(body)``): (assembler, pieces, thin parts, decomposition) as in
    :func:`_mesh_bridge`, or None when the body does not mesh, the ladder cannot join the two
    ends, or their point counts differ in parity — then the arguments of :func:`_bridge_join`
    are appended to ``odd`` for a later try."""
    body_r, end = None, None
    if body is not None:
        body_r = part(body)
        if body_r is None:
            return None
        end = _rung_ids(lay, body_r, -1)
        if end is None:
            return None
        if (end.size - start.size) % 2:
            odd.append((lay, q, near_r, start, body_r, end))
            return None
    return _bridge_join(lay, q, near_r, start, body_r, end)


def _bridge_join(lay, q: np.ndarray, near_r: MeshResult, start: np.ndarray, body_r, end):
    """The bridge ``lay`` meshed between the near part's points ``start`` on its first rung and,
    when ``body_r`` is given, that mesh's points ``end`` on its last rung, glued to both
    meshes; None when the ladder cannot join them."""
    from .thin.corridor import mesh_arm

    try:
        arm = mesh_arm(
            lay, q, None if body_r is None else body_r.mesh.z, start_points=near_r.mesh.z
        )
    except ThinPartError:
        return None
    if start.size != arm.start.size or (end is not None and end.size != arm.cut.size):
        return None
    asm = Assembler()
    gl_parts = [_add_mesh(asm, r) for r in (near_r, body_r) if r is not None]
    gl = np.full(arm.vertices.size, -1, dtype=np.int64)
    gl[arm.start] = gl_parts[0][start]
    if end is not None:
        gl[arm.cut] = gl_parts[1][end]
    own = gl < 0
    gl[own] = asm.add_vertices(arm.vertices[own])
    asm.add_quads(gl[arm.quads], source=3)
    thin = [*near_r.thin, ThinPartResult("corridor", len(near_r.thin), arm, gl)]
    return asm, list(near_r.pieces), thin, near_r.decomposition


#: A chain (:func:`_mesh_chain`) has at most this many knots, and tries at most this many
#: knots (restart places) whose mesh its ladder cannot join before meshing the rest as one part
#: (a failing join costs 10–50 s on a river: 300 points on each cut) — only when the rest has
#: at most ``CHAIN_REST_VERTICES`` vertices (a longer ragged rest is as crowded as the whole).
CHAIN_MAX_KNOTS = 60
CHAIN_JOINS = 4
CHAIN_REST_VERTICES = 300


#: Where the progress bar stands when a chain of ladders ends (it starts where the bar was).
CHAIN_PROGRESS_END = 0.88


def _mesh_chain(
    dec, options: MeshOptions, cancel: CancelCallback | None, executor: Executor | None = None
):
    """A corridor whose ladder gets stuck again and again (a river whose banks zigzag, a traced
    contour with ragged stretches) as a *chain*: an arm from one tip up to where its ladder
    gets stuck (:func:`~quadmesh.thin.corridor.arm_and_body`), then a *knot* — the stretch from
    that rung to a straight crosscut a few widths on (:func:`~quadmesh.thin.corridor.
    restart_cuts`), small enough for the paper's construction — and a ladder restarted from
    that crosscut (a bridge's, from a virtual cap), and so on until a ladder reaches the far
    tip or the rest meshes as one part. Where no arm leaves either tip (a river whose bank
    hooks at its end, a tight bend next to it), the chain starts with a knot at a tip instead
    (:func:`_chain_knot_start`). Every ladder takes its knots' points on its end rungs
    by index, transition cascades (with a parity row for odd differences) changing the count
    between them. Each knot takes the nearest restart from which a ladder leaves and whose
    ladder behind joins the knot's mesh. Knots are meshed where they lie (not translated to
    their own origin) and verified there. Returns (assembler, the first knot's thick-piece
    results, thin-part results, its decomposition) or None."""
    from .thin.corridor import (
        RESTART_WIDTHS,
        arm_and_body,
        bridge_layout,
        mesh_arm,
        restart_cuts,
        shorter_bridges,
    )

    def part(w: np.ndarray) -> MeshResult | None:
        keep = getattr(_nesting, "keep_frame", False)
        _nesting.keep_frame = True
        try:
            return _mesh_part(w, options, cancel, executor)
        finally:
            _nesting.keep_frame = keep

    q = dec.polygon.z
    knots: list[MeshResult] = []
    split = arm_and_body(q)
    if split is not None:
        lay, body = split
    else:
        # no arm leaves either tip (a river's end with a hooked bank, a tight bend next to
        # it): the chain starts with a knot at a tip (in polygons of at most
        # KNOT_MAX_POLYGON vertices, as knotted arms: on a 1,817-vertex coast, which is no
        # corridor, the chain's knots and restarts took 9 minutes more to fail)
        start = None if q.size > KNOT_MAX_POLYGON else _chain_knot_start(q, part)
        if start is None:
            return None
        knot_r, (lay, q, body) = start
        knots.append(knot_r)
    run = active()
    if run is not None:
        # a chain takes minutes: the bar follows the share of the polygon's area meshed
        run.enter("chain of ladders", run.last, max(run.last, CHAIN_PROGRESS_END))
    total = abs(signed_area(dec.polygon.z))

    def join(lay, q, start_r: MeshResult | None, end_r: MeshResult | None):
        start = end = None
        if start_r is not None:
            start = _rung_ids(lay, start_r, 0)
            if start is None:
                return None
        if end_r is not None:
            end = _rung_ids(lay, end_r, -1)
            if end is None:
                return None
        try:
            arm = mesh_arm(
                lay,
                q,
                None if end_r is None else end_r.mesh.z,
                start_points=None if start_r is None else start_r.mesh.z,
                split=(2,),  # in two only: each cut costs another 10–50 s on a river
            )
        except ThinPartError:
            return None
        if (start is not None and start.size != arm.start.size) or (
            end is not None and end.size != arm.cut.size
        ):
            return None
        return arm, start, end

    segments = []  # (corridor mesh, ids on its first rung, ids on its last rung, knot before)
    for _ in range(CHAIN_MAX_KNOTS):
        if cancel is not None and cancel():
            raise Cancelled("meshing cancelled during a chain of ladders")
        if body is None:  # the ladder from the last knot reaches the far tip
            seg = join(lay, q, knots[-1], None)
            if seg is None:
                return None
            segments.append((*seg, len(knots) - 1))
            break
        step = None
        tries = CHAIN_JOINS
        for rc in restart_cuts(body, RESTART_WIDTHS):
            nxt = bridge_layout(rc.rest, min_rungs=2)
            if nxt is None:
                continue
            kr = part(rc.knot)
            if kr is None:
                continue
            seg = join(lay, q, knots[-1] if knots else None, kr)
            if seg is not None:
                step = (kr, seg, nxt)
                break
            tries -= 1
            if tries <= 0:
                break
        if step is None:
            # no restart: the rest as one part, behind the ladder's last rung or one to three
            # rungs before it (another count on the cut)
            before = knots[-1] if knots else None
            if body.size > CHAIN_REST_VERTICES:
                return None
            for lay_k, body_k in [(lay, body), *shorter_bridges(lay, q)]:
                kr = part(body_k)
                seg = None if kr is None else join(lay_k, q, before, kr)
                if seg is not None:
                    break
            if seg is None:
                return None
            segments.append((*seg, len(knots) - 1))
            knots.append(kr)
            break
        kr, seg, (lay, q, body) = step
        segments.append((*seg, len(knots) - 1))
        knots.append(kr)
        checkpoint(1.0 if body is None else 1.0 - abs(signed_area(body)) / total)
    else:
        return None
    asm = Assembler()
    ids = [_add_mesh(asm, r) for r in knots]
    thin = list(knots[0].thin)
    for arm, start, end, before in segments:
        gl = np.full(arm.vertices.size, -1, dtype=np.int64)
        if start is not None:
            gl[arm.start] = ids[before][start]
        if end is not None:
            gl[arm.cut] = ids[before + 1][end]
        own = gl < 0
        gl[own] = asm.add_vertices(arm.vertices[own])
        asm.add_quads(gl[arm.quads], source=3)
        thin.append(ThinPartResult("corridor", len(thin), arm, gl))
    return asm, list(knots[0].pieces), thin, knots[0].decomposition


#: Where a chain with no arm at either tip starts (:func:`_chain_knot_start`): knots cut off
#: a tip at these distances along the corridor (in widths), of at most a third of the
#: polygon's vertices.
CHAIN_KNOT_WIDTHS = tuple(float(w) for w in range(2, 31, 2))
CHAIN_KNOT_SHARE = 3


def _chain_knot_start(z: np.ndarray, part):
    """The first knot of a chain whose tips no arm leaves: at either end of the polygon's
    longest stretch, the nearest tip cut (:func:`~quadmesh.thin.corridor.tip_cuts`) from which
    a ladder leaves and whose knot meshes (``part``) with its points on the cut taken by the
    ladder's first rung (at most :data:`KNOT_CUTS` knots meshed per tip). Returns (the knot's
    result, (ladder, capped rest, body behind it)) or None."""
    from .thin.corridor import bridge_layout, corridor_tips, tip_cuts

    limit = z.size // CHAIN_KNOT_SHARE
    for s in dict.fromkeys(corridor_tips(z)):
        meshes = KNOT_CUTS  # knots meshed per tip, as for knotted arms
        for rc in tip_cuts(z, s, widths=CHAIN_KNOT_WIDTHS):
            if rc.knot.size > limit or meshes <= 0:
                break
            got = bridge_layout(rc.rest, min_rungs=KNOT_MIN_RUNGS, own_width=True)
            if got is None:
                continue
            meshes -= 1
            knot_r = part(rc.knot)
            if knot_r is not None and _rung_ids(got[0], knot_r, 0) is not None:
                return knot_r, got
    return None


def _mesh_arm_and_body(
    dec, options: MeshOptions, cancel: CancelCallback | None, executor: Executor | None = None
):
    """An arm of the polygon meshed as a corridor (:func:`~quadmesh.thin.corridor.arm_and_body`)
    and the body behind it meshed by :func:`mesh_polygon` (recursively: the body may have arms
    again), glued along the cut by index: the arm's last rung takes the body mesh's points on
    it. Returns (assembler, thick-piece results, thin-part results, the body's decomposition),
    or None when there is no arm or either part cannot be meshed. ``executor``: for the body's
    thick pieces (:func:`mesh_polygon`)."""
    from .thin.corridor import arm_and_body, crowded_place, mesh_arm

    # an arm from either end of the polygon's longest stretch, else one reaching toward where
    # the pieces are crowded (a serif, a spur)
    split = arm_and_body(dec.polygon.z)
    if split is None:
        toward = crowded_place(dec)
        split = None if toward is None else arm_and_body(dec.polygon.z, toward)
    if split is None:
        return None
    lay, body = split
    inner = _mesh_part(body, options, cancel, executor)
    if inner is None:
        return None
    try:
        arm = mesh_arm(lay, dec.polygon.z, inner.mesh.z)
    except ThinPartError:
        return None
    # the cut: the body's points on it, from the arm's L end to its R end
    cut = _rung_ids(lay, inner, -1)
    if cut is None or cut.size != arm.cut.size:
        return None
    asm = Assembler()
    gl = np.full(arm.vertices.size, -1, dtype=np.int64)
    gl[arm.cut] = _add_mesh(asm, inner)[cut]
    own = gl < 0
    gl[own] = asm.add_vertices(arm.vertices[own])
    asm.add_quads(gl[arm.quads], source=3)
    thin = [*inner.thin, ThinPartResult("corridor", len(inner.thin), arm, gl)]
    return asm, list(inner.pieces), thin, inner.decomposition


#: A knotted arm (:func:`_mesh_knotted_arm`) is tried from at most this many tips nearest the
#: crowded place (and the ends of the polygon's longest stretch), with at most
#: :data:`KNOT_CUTS` knots per tip whose ladder leaves; at most :data:`KNOT_MESHES` part meshes
#: (knots and bodies) are made for the user's polygon and all parts inside it (a horse with four
#: legs and a tail takes 10), and once :data:`KNOT_FAILED_BODIES` bodies behind knotted arms
#: have failed no more are tried (a traced text whose strokes are crowded in their middles took
#: minutes to refuse): counts, not times, so that what meshes does not depend on the machine.
KNOT_TIPS = 1
KNOT_CUTS = 3
KNOT_MESHES = 14
KNOT_FAILED_BODIES = 1
#: ... and only in polygons of at most this many vertices: each body behind a knotted arm is
#: meshed in full, and on a 1,817-vertex coast (coast_5 of the families, still refused) the
#: search took 21 minutes to fail; the horse has 815, coast_1 661.
KNOT_MAX_POLYGON = 1000
#: ... and only where the ladder from the knot has at least this many rungs (an arm, not a
#: spur: a horse's legs take 10–19; a 3-rung ladder from a spur of the camera man's coat left
#: a body as crowded as the whole, 42 s to fail)
KNOT_MIN_RUNGS = 5
#: ... and a knot has at most this many vertices or a quarter of the polygon's (a horse's hoof
#: with its pastern: 23–64 of 571–815).
KNOT_MAX_VERTICES = 80


def _mesh_knotted_arm(
    dec,
    options: MeshOptions,
    cancel: CancelCallback | None,
    executor: Executor | None,
    toward: complex,
):
    """An arm whose own tip no ladder leaves (a hoof of a traced animal, a ragged end of a
    contour) as a *knotted arm*: the tip cut off a few widths from its end by a straight
    crosscut (:func:`~quadmesh.thin.corridor.tip_cuts`) — the *knot*, small enough for the
    paper's construction — then a ladder from that cut up the arm (a bridge's, from a virtual
    cap) to where it gets stuck, and the body behind meshed by :func:`mesh_polygon`
    (recursively: it may have arms again). The ladder's first rung takes the knot mesh's points
    on the cut and its last rung the body mesh's, their counts joined by transition cascades
    (:func:`_bridge_join`). Tips nearest ``toward`` (where the polygon is crowded) first; knots
    are not knotted again. Returns (assembler, the knot's thick-piece results, thin-part
    results, the knot's decomposition) or None."""
    if getattr(_nesting, "in_knot", False) or getattr(_nesting, "retry", False):
        return None  # (not again in the retry with arcs chosen for size: bodies take minutes)
    if dec.polygon.z.size > KNOT_MAX_POLYGON:
        return None
    outer = getattr(_nesting, "knot_meshes", None) is None
    if outer:  # called outside mesh_polygon: budgets of its own
        _nesting.knot_meshes, _nesting.knot_failures = KNOT_MESHES, KNOT_FAILED_BODIES
    try:
        if _nesting.knot_failures <= 0:
            return None
        return _knotted_arm_search(dec, options, cancel, executor, toward)
    finally:
        if outer:
            _nesting.knot_meshes = _nesting.knot_failures = None


def _knotted_arm_search(
    dec,
    options: MeshOptions,
    cancel: CancelCallback | None,
    executor: Executor | None,
    toward: complex,
):
    """The tips and knots of :func:`_mesh_knotted_arm` tried in turn, each part meshed from the
    budget of part meshes left (``_nesting.knot_meshes``)."""
    from .thin.corridor import arm_tips, bridge_layout, corridor_tips, shorter_bridges, tip_cuts

    z = dec.polygon.z

    def part(w: np.ndarray, knot: bool = False) -> MeshResult | None:
        if _nesting.knot_meshes <= 0:
            return None
        _nesting.knot_meshes -= 1
        was = getattr(_nesting, "in_knot", False), getattr(_nesting, "keep_frame", False)
        # a knot is small and far from (0, 0) against its size: meshed where it lies, so that
        # its points on the cut can be matched (as a chain's knots)
        _nesting.in_knot = _nesting.keep_frame = knot
        try:
            return _mesh_part(w, options, cancel, executor)
        finally:
            _nesting.in_knot, _nesting.keep_frame = was

    # the tips nearest the crowded place, then the two ends of the polygon's longest stretch
    # (where the crowding is at the stub an arm's cut left, the other arms are elsewhere)
    tips = [t for t, _e in arm_tips(z, toward, count=KNOT_TIPS)]
    tips = list(dict.fromkeys([*tips, *corridor_tips(z)]))
    for s in tips:
        # the longest ladders first: the knot's and the body's meshes fix many points on the
        # two cuts (199 and 154 on a horse's leg), and cascades between them need cells
        found = []
        for rc in tip_cuts(z, s):
            if rc.knot.size > max(KNOT_MAX_VERTICES, z.size // 4):
                continue  # no knot: much of the polygon, as crowded as the whole
            got = bridge_layout(rc.rest, min_rungs=KNOT_MIN_RUNGS, own_width=True)
            if got is not None:
                found.append((rc, got))
        found.sort(key=lambda t: -len(t[1][0].rungs))
        for rc, (lay, q, body) in found[:KNOT_CUTS]:
            if _nesting.knot_meshes <= 0:
                return None
            knot_r = part(rc.knot, knot=True)
            if knot_r is None:
                continue
            start = _rung_ids(lay, knot_r, 0)
            if start is None:
                continue
            ends = [(lay, None)] if body is None else [(lay, body), *shorter_bridges(lay, q, 1)]
            for lay_k, body_k in ends:
                body_r, end = None, None
                if body_k is not None:
                    body_r = part(body_k)
                    if body_r is None:
                        # the body behind this arm does not mesh: behind another tip's it
                        # would hold the same crowded places (and cost as much again)
                        _nesting.knot_failures -= 1
                        return None
                    end = _rung_ids(lay_k, body_r, -1)
                    if end is None:
                        continue
                joined = _bridge_join(lay_k, q, knot_r, start, body_r, end)
                if joined is not None:
                    return joined
    return None
