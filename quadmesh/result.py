"""Plain data of the pipeline: options in, every stage out.

:class:`MeshOptions` holds every knob of :func:`quadmesh.mesh_polygon` with its default and
the design note that justifies it. :class:`MeshResult` keeps every stage so that the
viewer, the command line and the tests read one object.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .mesh import QuadMesh, QualityReport, VerificationReport
    from .polygon import Polygon

#: meshing methods of :class:`MeshOptions`
METHODS = ("bishop", "blocks")

__all__ = ["METHODS", "MeshOptions", "MeshResult", "ThickPieceResult", "ThinPartResult"]


@dataclass(frozen=True)
class MeshOptions:
    """Every knob of the mesher, with its default.

    Attributes:
        n: steps per half pentagon side (Lemma 4.1: N_side = 2n on every
            pentagon side and Carleson top edge). n = 2 is the smallest value whose disk
            chord angles stay in [60°, 120°]; the adaptive loop raises it per thick piece.
        depth_step: spacing of the global depth sequence d_k shared by Carleson
            quadrilaterals and triangles (Lemmas 5.1, 6.1§6). 1.0 keeps the
            pushed-forward angles in range on the bundled examples at a third of the quads of
            the notes' 0.25; where a Carleson image angle leaves [60°, 120°] the adaptive loop
            halves it (down to 0.125).
        depth_growth: ratio of consecutive depth steps below the triangle landmark D5
            (1 = uniform). The deep rows are thin strips near 90°, so 2 halves their
            number at no measurable cost in angle (measured in the model triangle).
        depth_max: depth d_M of the last Carleson row above the circle; None uses
            the full depth log(8/depth_step) + 2. The last row's cells deviate from 90° by about
            e^{−d_M} rad (4.7° at 2.5), so it trades quads (and crosscut vertices) for margin:
            2.5 saves ~12 % of the quads on the examples; when the adaptive loop lowers the
            depth step it also returns to the full depth. It is raised to D5 + 0.5 when the
            inner triangle's deepest landmark D5 (which grows as inner_height shrinks) needs it.
        inner_height: height h of the inner triangle T_i in the model Carleson triangle.
        crosscut_ratio: A_eff = g/φ, prevertex gap over the half-width of the arc J_k whose
            geodesic image is the crosscut around a vertex. 6 (the notes suggest 64): larger J_k
            leave fewer cover arcs
            and so fewer Carleson pieces and pentagons (−8 to −25 % quads against 16 on the
            examples); the conformal collar straightens the less round crosscut. φ is capped
            so that the A-fold expansions of the I_j stay disjoint (Lemma 2.2's hypothesis).
        arc_choice: how the arcs J_k are ranked: ``"centred"`` (the default) prefers the
            arc whose centre is closest to the prevertex, then the size nearest g/φ =
            ``crosscut_ratio``; ``"sized"`` counts offsets up to 0.15 φ as centred and
            weighs size more, so crosscuts near reflex corners are larger. When the paper's
            construction fails on the user's polygon with centred arcs (a stage refuses it, or
            its mesh fails the final check: quads too small for float64 where they are),
            :func:`~quadmesh.mesh_polygon` meshes it once more with ``"sized"`` arcs (not
            with ``adaptive=False``) and ``MeshResult.options`` says so.
        lemma_A: the expansion factor A of Lemma 2.2 handed to the disk construction. Any
            A > 1 satisfies the lemma; a smaller A lets the arcs J_k ⊃ √A·I_k grow closer to
            their neighbours (φ ≤ g/(2(√A/1.02 + 0.9))), 4: φ up to g/5.7 (16: g/9.6).
        rotations: normalisations of each thick piece's map tried, f(e^{−iψ}z) with
            ψ = 2π/5·k/rotations (f(0) is kept); the one whose Lemma 2.2 region has the fewest
            cover arcs is used (0 to −19 % disk quads on the examples, one region build per
            trial, ~0.3 s per piece). Only for pieces with at most 16 arcs and prevertex gaps
            ≥ 1e-6; 1 = off.
        channel_delta: extremal-distance threshold δ below which a channel is a hyperbolic
            thin part; below 3/4, so that the overlap depth 1/(4δ) + 1
            stays below 1/δ.
        sector_ratio: λ, radius of the vertex sector over the crosscut's distance from the
            vertex.
        conformal_tol: target residual of the Schwarz–Christoffel parameter problem, in
            [1e-14, 1e-4].
        adaptive: raise n (2 → 3 → 4 → 6) for a thick piece whose pushed-forward quads
            leave [60°, 120°], and redo it.
        max_n: largest n the adaptive loop tries.
        repair: before the adaptive loop changes anything, move the interior vertices near
            pushed-forward quads that leave [60°, 120°] by a small fraction of their edges
            (:func:`quadmesh.repair.repair_angles`; topology, boundary and the crosscut
            vertices shared with thin parts are untouched). Off: the paper's remedy only.
        refine: split every quad of the verified construction into a refine × refine grid
            of bilinear sub-quads (:func:`quadmesh.refine.refine_quads`; 1 = off). The grid
            points on an edge shared by two quads are made once, so the mesh stays
            conforming, and a convex quad's bilinear sub-quads have their angles within the
            range of its corner angles and their supplements, so [60°, 120°] survives. Not
            available when the polygon has a corner below 60° (the quad keeping it would give
            new angles of about that angle).
        method: ``"bishop"`` (the paper's construction, every stage kept: the default) or
            ``"blocks"``: straight cuts from the obtuse and reflex corners split the polygon
            into convex blocks with every corner in [60°, 120°], refined by bilinear grids
            (:mod:`quadmesh.blocks`) — the same angle guarantee with far fewer quads. A polygon
            for which no block layout is found is meshed by the paper's construction instead
            (``MeshResult.fallback`` says why).
        size: target edge length of ``method="blocks"`` (None: d / 20, d the polygon's
            bounding-box diagonal, ``Polygon.diameter``).
            Every chord of blocks gets ceil(its longest edge / size) segments; blocks holding
            a corner below 60° stay whole.
        jobs: worker processes for the thick pieces' own stages (map, arcs, disk mesh,
            push-forward, repair) of ``method="bishop"``; 1 = all in this process. Used only
            when the decomposition has at least two thick pieces; the mesh is the same bit for
            bit (:mod:`quadmesh.parallel`). Each call starts its pool, so it pays only when the
            pieces take seconds each (measured in the README).
        blas_threads: threads the BLAS/LAPACK libraries under numpy and scipy (OpenBLAS,
            MKL) may use during a call made from the main thread, restored afterwards; None
            leaves them as they are. The mesher's matrix work is small per call, and a
            multi-threaded BLAS on a busy machine spins its threads against the other
            processes: on a 2-core machine with one other busy process, the harmonic measure
            of a 1010-vertex river took 10.9 s with the default two threads and 0.67 s with
            one. Parallel work belongs in ``jobs``. The limit is process-wide, so a call from
            another thread leaves it alone (set it once for the process instead, e.g. with
            ``threadpoolctl.threadpool_limits(1, "blas")`` before starting threads).
    """

    n: int = 2
    depth_step: float = 1.0
    depth_growth: float = 2.0
    depth_max: float | None = 2.5
    inner_height: float = 1.0
    crosscut_ratio: float = 6.0
    arc_choice: str = "centred"
    lemma_A: float = 4.0
    rotations: int = 8
    channel_delta: float = 0.15
    sector_ratio: float = 0.25
    conformal_tol: float = 1e-10
    adaptive: bool = True
    max_n: int = 6
    repair: bool = True
    refine: int = 1
    method: str = "bishop"
    size: float | None = None
    jobs: int = 1
    blas_threads: int | None = 1

    def __post_init__(self) -> None:
        def real(name: str) -> float:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
            return float(v)

        def integer(name: str, low: int) -> int:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or v != int(v) or v < low:
                rule = "a positive integer" if low == 1 else f"an integer of at least {low}"
                raise ValueError(f"{name} must be {rule}, got {v!r}")
            return int(v)

        integer("n", 1)
        if not 0 < real("depth_step") <= 1:
            raise ValueError(f"depth_step must be in (0, 1], got {self.depth_step}")
        if self.depth_max is not None and not 1.0 <= real("depth_max") <= 12.0:
            raise ValueError(f"depth_max must be in [1, 12], got {self.depth_max}")
        if not 1.0 <= real("depth_growth") <= 4.0:
            raise ValueError(f"depth_growth must be in [1, 4], got {self.depth_growth}")
        if not 0 < real("inner_height") <= 2:
            raise ValueError(f"inner_height must be in (0, 2], got {self.inner_height}")
        if real("crosscut_ratio") < 4:
            raise ValueError(f"crosscut_ratio must be at least 4, got {self.crosscut_ratio}")
        if self.arc_choice not in ("centred", "sized"):
            raise ValueError(f"arc_choice must be 'centred' or 'sized', got {self.arc_choice!r}")
        if real("lemma_A") <= 1:
            raise ValueError(f"lemma_A must exceed 1, got {self.lemma_A}")
        integer("rotations", 1)
        # the decomposition's overlap depth 1/(4δ) + 1 must stay below 1/δ: δ < 3/4
        if not 0 < real("channel_delta") < 0.75:
            raise ValueError(f"channel_delta must be in (0, 0.75), got {self.channel_delta}")
        if not 0 < real("sector_ratio") < 1:
            raise ValueError(f"sector_ratio must be in (0, 1), got {self.sector_ratio}")
        if not 1e-14 <= real("conformal_tol") <= 1e-4:
            raise ValueError(f"conformal_tol must be in [1e-14, 1e-4], got {self.conformal_tol}")
        for name in ("adaptive", "repair"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if integer("max_n", 1) < self.n:
            raise ValueError(f"max_n must be at least n = {self.n}, got {self.max_n}")
        if integer("refine", 1) > 64:
            raise ValueError(f"refine must be an integer in [1, 64], got {self.refine}")
        if self.method not in METHODS:
            raise ValueError(
                f"method must be one of {', '.join(repr(m) for m in METHODS)}, got {self.method!r}"
            )
        integer("jobs", 1)
        if self.blas_threads is not None:
            integer("blas_threads", 1)
        if self.size is not None and not real("size") > 0:
            raise ValueError(f"size must be a positive length, got {self.size!r}")


@dataclass(frozen=True)
class ThickPieceResult:
    """One thick piece: its conformal map, intervals, disk mesh and the image of that mesh.

    Attributes:
        index: position in ``Decomposition.thick``.
        vertices: complex vertices of the piece (CCW).
        map: the Schwarz–Christoffel map f: D → piece (``quadmesh.conformal.DiskMap``), or
            its rotation z ↦ f(e^{−iψ}z) (``rotation`` = ψ, ``base`` = f) when
            ``MeshOptions.rotations`` found a cheaper normalisation.
        intervals: (m, 2) arcs I_j (start angle, ccw length) handed to Lemma 2.2.
        interval_owner: per interval, ("vertex", polygon vertex index) or ("channel", id, end).
        disk: the disk mesh of W (``quadmesh.disk.DiskMesh``), in disk coordinates.
        image: complex positions in the plane of ``disk.vertices`` (f, and the linear map h
            inside inner triangles).
        n_used: steps per half pentagon side finally used for this piece.
        depth_step_used: Carleson depth step finally used.
        fixes: what the adaptive loop changed, in order.
    """

    index: int
    vertices: np.ndarray
    map: Any
    intervals: np.ndarray
    interval_owner: tuple[tuple[Any, ...], ...]
    disk: Any
    image: np.ndarray
    n_used: int
    fixes: tuple[str, ...] = ()
    depth_step_used: float = 1.0


@dataclass(frozen=True)
class ThinPartResult:
    """An explicitly meshed thin part: a vertex sector ("parabolic") or a channel
    ("hyperbolic"). ``owner`` is the polygon vertex index or the channel index;
    ``global_index`` maps the part's mesh vertices to the final mesh's vertices."""

    kind: str
    owner: int
    mesh: Any
    global_index: np.ndarray


@dataclass(frozen=True)
class MeshResult:
    """Every stage of one run of :func:`quadmesh.mesh_polygon`."""

    polygon: Polygon
    options: MeshOptions
    decomposition: Any
    pieces: tuple[ThickPieceResult, ...]
    thin: tuple[ThinPartResult, ...]
    mesh: QuadMesh
    quality: QualityReport
    verification: VerificationReport
    timings: dict[str, float] = field(default_factory=dict)
    quad_source: np.ndarray | None = None
    """Per final quad: 0 = disk mesh of a thick piece, 1 = vertex sector, 2 = channel."""
    origin: complex = 0j
    """Working origin: for a polygon far from 0 (centre beyond 1 diameter; a part cut off it,
    beyond 4 of its own) the stages run on
    the polygon translated exactly by −origin, so ``decomposition``, ``pieces`` and ``thin``
    hold plane points relative to ``origin``; ``polygon`` is always in the input's
    coordinates. 0 for every other polygon."""
    blocks: Any = None
    """The :class:`~quadmesh.blocks.BlockLayout` when the mesh was made by
    ``method="blocks"`` (its points relative to ``origin``), else None."""
    fallback: str | None = None
    """Why ``method="blocks"`` fell back to the paper's construction (None otherwise)."""
    mesh_origin: complex = 0j
    """The ``mesh``'s vertices are relative to this point: a vertex's position in the input's
    coordinates is vertex + mesh_origin. 0 (the mesh is in the input's coordinates) unless the
    polygon is far from (0, 0) and its absolute float64 coordinates cannot hold the angles
    within ``quadmesh.mesh.ANGLE_TOL_DEG`` (e.g. a 10 m parcel at 5e6 m northing); then it is
    ``origin`` (translated exactly) and ``verification`` is of the mesh as stored. Either way
    the guarantee holds on ``mesh.vertices`` as they are."""
