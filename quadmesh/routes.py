"""The corridor routes: a polygon too crowded for the paper's construction, cut into parts.

Bishop's construction (:mod:`quadmesh.pipeline`: the thick/thin decomposition of paper §7, a
conformal map f: D → piece for every thick piece with the disk mesh of Lemmas 2.2, 4.1, 5.1,
6.1 pushed through it, the thin parts of §8) maps every thick piece onto the disk. A thick
piece that is a long corridor of length ℓ and width w (a pen stroke, a letter, a river) is
*crowded*: seen from any centre its prevertex gaps shrink like exp(−π·ℓ/w)
(:mod:`quadmesh.thin.corridor`), and in floating point the map's solve or the disk
construction cannot resolve them. A polygon that is one such corridor as a whole is meshed by
a ladder of straight cells without a conformal map (:func:`~quadmesh.thin.corridor.
whole_corridor`, tried by the pipeline right after the decomposition). The routes of this
module are for the polygons that are not: each cuts the polygon by straight crosscuts into
corridors, meshed by ladders of straight cells (:func:`~quadmesh.thin.corridor.mesh_arm`:
corners in [60°, 120°], refined by bilinear grids), and parts meshed by
:func:`~quadmesh.pipeline.mesh_polygon` recursively (:func:`_mesh_part`: by the paper's
construction, or by a route again), and glues them into one mesh. The routes are not in the
paper; every part that is not a ladder is meshed by its construction.

The routes:

* **arm and body** (:func:`_mesh_arm_and_body`): an *arm*, the stretch from one tip of the
  polygon that a ladder reaches (from either end of its longest stretch, else toward where
  the pieces are crowded: a serif, a spur), cut by a rung before the ladder gets stuck, and
  the *body* behind the cut, meshed by :func:`mesh_polygon` (it may have arms again);
* **knotted arm** (:func:`_mesh_knotted_arm`): an arm whose own tip no ladder leaves (a hoof of
  a traced animal, a ragged end of a contour): the tip cut off a few widths from its end by a
  straight crosscut — the *knot*, small enough for the paper's construction, meshed where it
  lies — a ladder from that cut up the arm to where it gets stuck, and the body behind;
* **bridge** (:func:`_mesh_bridge`): a polygon crowded along a corridor between two bodies
  (the two ends of a "C", a glyph's bowl and its ball terminal), split by a straight crosscut
  across the corridor's middle: the part on one side meshed as a part, the other side entered
  by a ladder from the cut (started from a virtual cap beyond the cut, so that the cut is its
  first rung) up to where it gets stuck, and the far body behind it meshed as a part;
* **chain of knots** (:func:`_mesh_chain`): a corridor whose ladder gets stuck again and again
  (a river whose banks zigzag): an arm, then a knot from the rung where its ladder stopped to
  a straight crosscut a few widths on, a ladder restarted from that crosscut, and so on until
  a ladder reaches the far tip or the rest meshes as one part; where no arm leaves either tip
  the chain starts with a knot at a tip (:func:`_chain_knot_start`).

When the pipeline tries them (:func:`quadmesh.pipeline._run_stages`,
:func:`quadmesh.pipeline._rescue`), for a polygon that is no corridor as a whole: an arm and
its body first if the corridor route gave a reason it failed or a thick piece's map would be
refused from its largest inscribed disk; then (when no arm meshed) the paper's construction,
and when it fails with a :class:`~quadmesh.errors.ConformalMapError` or
:class:`~quadmesh.errors.DiskConstructionError` (not for a polygon too large for the machine's
memory) the other routes in this order, the first that meshes taken: an arm and its body
(unless tried already); then, only where the failure is crowding (not angles the adaptive loop
could not bring into range), a bridge; the failing pieces' maps from their least crowded
centres (:func:`quadmesh.pipeline._recentred`, no route of this module); a knotted arm from
the tip nearest the most crowded place (:func:`~quadmesh.thin.corridor.crowded_place`) and
the ends of the polygon's longest stretch; and last a chain. Every part is meshed by
:func:`~quadmesh.pipeline.mesh_polygon` in the same way, except that a part is bridged again
only within a bridge search (down to :data:`BRIDGE_DEPTH`), a knotted arm's knot has no
knotted arm of its own and a chain is tried for the user's polygon only. In the retry of the
user's polygon with arcs chosen for size (:func:`quadmesh.pipeline._sized_retry`) knotted arms
and chains are not tried again. Every route is bounded by counts, not times, so that what
meshes does not depend on the machine (``BRIDGE_*``, ``KNOT_*``, ``CHAIN_*``).

How parts are glued: by index, not by distance. A part is meshed at its place in the polygon:
one whose stages ran relative to an origin of its own (far from (0, 0) against its size) is
refused, since its points could not be matched by position, so knots are meshed with their
frame kept (``keep_frame``). Each part's mesh is added to one
:class:`~quadmesh.glue.Assembler` with its quads' sources (:func:`_add_mesh`). Its *rung ids*
(:func:`_rung_ids`, :func:`_cut_ids`) are the indices of its mesh's points on the end rung of
a ladder (the cut between the two), in order from the rung's L end; the ladder is meshed with
exactly those points on that rung (:func:`~quadmesh.thin.corridor.mesh_arm`, which finds
them by position; a ladder whose count there differs is refused), its points there take the
part's ids, its other points are new vertices and its quads are corridor quads (source 3).
A ladder between two meshes (a bridge, a knotted arm, a chain's ladder between two knots)
takes both meshes' points on its two end rungs, and *transition cascades*
(:func:`quadmesh.transition.transition_cascade`) inside it change the count from one to the
other, two points at a time; so a bridge whose two counts differ in parity first moves its
far cut one to three rungs back (another body, another count: :func:`_bridge_mesh`), and
only when no split joins so are the odd differences joined by a cascade that starts with a
*parity row* (one wall carries one more point). A route returns (assembler, thick-piece
results, thin-part results, decomposition) of the part it starts from (the body, the near
part, the first knot), its ladders among the thin parts as corridors; the other parts'
quads are in the mesh, their stage results are not kept.

State: ``_nesting`` (thread-local) holds the nesting depth of the part being meshed
(``value``, 0: the user's polygon), whether the sized-arcs retry runs (``retry``), the budgets
of the bridge search (``bridge_meshes``, ``bridge_depth``) and of knotted arms
(``knot_meshes``, ``knot_failures``, set by :func:`mesh_polygon` for the user's polygon and
every part inside it), and whether a knot is meshed (``in_knot``: no knotted arm inside it;
``keep_frame``: meshed where it lies). :mod:`quadmesh.pipeline` imports this module;
:func:`mesh_polygon` is imported here inside :func:`_mesh_part`, so that the two modules do
not import each other when they are loaded.
"""

from __future__ import annotations

import threading
from concurrent.futures import Executor

import numpy as np

from .errors import Cancelled, ThinPartError
from .glue import Assembler
from .polygon import signed_area
from .progress import CancelCallback, active, checkpoint
from .result import MeshOptions, MeshResult, ThinPartResult

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
    from .pipeline import mesh_polygon

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


def _add_mesh(asm: Assembler, r: MeshResult) -> np.ndarray:
    """Add the mesh of ``r`` to ``asm``, each quad with its source; returns its vertices' ids."""
    ids = asm.add_vertices(r.mesh.z)
    src = np.zeros(len(r.mesh.quads), dtype=np.int64)
    if r.quad_source is not None:
        src = np.asarray(r.quad_source, dtype=np.int64)
    for k in np.unique(src):
        asm.add_quads(ids[r.mesh.quads[src == k]], source=int(k))
    return ids


def _with_ladder(asm: Assembler, arm, gl: np.ndarray, part: MeshResult):
    """Add the ladder ``arm`` to ``asm``: its points with an id in ``gl`` (those on the rungs
    it shares with the parts' meshes) take it, the others become new vertices, its quads
    corridor quads (source 3). Returns the route's result for ``part`` (the part it starts
    from): (assembler, its thick-piece results, its thin parts and the ladder, its
    decomposition)."""
    own = gl < 0
    gl[own] = asm.add_vertices(arm.vertices[own])
    asm.add_quads(gl[arm.quads], source=3)
    thin = [*part.thin, ThinPartResult("corridor", len(part.thin), arm, gl)]
    return asm, list(part.pieces), thin, part.decomposition


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
    return _with_ladder(asm, arm, gl, near_r)


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
    return _with_ladder(asm, arm, gl, inner)


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
