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

A polygon that is one long corridor (a pen stroke) is meshed by a ladder of straight cells
instead of stages 3–4; one whose thick piece cannot be mapped in floating point (a corridor
crowds its prevertices) is cut into parts by the corridor routes of :mod:`quadmesh.routes`
(arms, knotted arms, bridges, chains), each part meshed by :func:`mesh_polygon` again.
``MeshOptions(method="blocks")`` first tries a block layout (:mod:`quadmesh.blocks`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor
from contextlib import closing
from dataclasses import replace
from typing import Any

import numpy as np

from . import routes
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
from .polygon import Polygon, validate_polygon
from .progress import Run, running
from .result import MeshOptions, MeshResult, ThinPartResult
from .routes import (
    _mesh_arm_and_body,
    _mesh_bridge,
    _mesh_chain,
    _mesh_knotted_arm,
    _mesh_part,
    _nesting,
)
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
        _nesting.knot_meshes, _nesting.knot_failures = routes.KNOT_MESHES, routes.KNOT_FAILED_BODIES
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
