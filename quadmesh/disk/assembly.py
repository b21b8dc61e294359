"""The conforming quad mesh of the region W (paper §§3–6: Lemma 2.2 with Lemmas 4.1, 5.1, 6.1).

Every piece of :func:`~quadmesh.disk.region.build_region`'s decomposition is meshed by moving one
canonical mesh:

* right pentagons: ``pentagon_mesh(n)`` moved by each tile's isometry (Lemma 4.1);
* Carleson quadrilaterals: ``carleson_quad_mesh(2n, depths)`` moved by the Möbius map of the
  model quad in H onto the quad (Lemma 5.1);
* Carleson triangles: ``model_triangle_mesh(depths, h)`` moved by ``τ⁻¹``: ``w ↦ apex``,
  ``−1 ↦ left foot``, ``1 ↦ right foot`` (Lemma 6.1).

All pieces share one depth sequence, and the glueing is by construction: global vertex ids are
assigned through the known topology — tile edge ↔ neighbour tile
edge (same canonical index, since ``σ_k`` fixes edge k), quad top ↔ pentagon edge, quad side ↔
the shared ray of the neighbouring quad or triangle.  Positions computed twice for one vertex
are only compared as an assertion.  To keep relative accuracy for tiny pieces near T, each
Carleson piece is placed in the frame ``φ_x`` of its top corner / apex ``x`` and mapped back.

Precision: the frame points ``x`` (tile vertices), the cover arcs and the tile isometries come
in extended precision from :func:`build_region`; frames are built in long double and every
vertex is rounded to complex128 exactly once (:func:`tile_points`, :func:`phi_inv_accurate`),
so the mesh is as accurate as complex128 positions allow also for arcs of 1e-14 rad.  The
consistency checks allow, besides :data:`POSITION_RTOL` of the local scale, that output rounding.
Cells near T smaller than ~1e-14 cannot be told apart in complex128, so every vertex is also
given exactly as ``frames[vertex_frame] + vertex_offset`` (an extended-precision frame point of
its piece plus a float64 offset with full relative accuracy): differences of nearby vertices and
distances to a prevertex on T can be formed from that without cancellation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import DiskConstructionError
from ..progress import checkpoint, span
from .canonical import orient_quads
from .carleson_quad import carleson_quad_mesh, carleson_quad_to_disk
from .carleson_triangle import depth_sequence, model_triangle_mesh
from .pentagon import pentagon_mesh
from .region import KIND_J, RegionW, build_region
from .tessellation import (
    P0_VERTICES_LD,
    POSITION_RTOL,
    frame_offsets,
    phi_accurate,
    tile_offsets,
)

__all__ = ["DiskMesh", "TriangleMap", "disk_mesh"]

KIND_NAMES = ("pentagon", "carleson_quadrilateral", "carleson_triangle")

OUTPUT_SLACK = 8.0 * np.finfo(float).eps
"""Absolute slack of the consistency checks: two complex128 roundings of one point near T
differ by up to ~2 ulps of 1 (each position is rounded once from an extended-precision frame)."""


@dataclass(frozen=True, eq=False)
class TriangleMap:
    """Placement of one Carleson triangle (paper §6–§7).

    ``tau_inv``: 2×2 complex matrix of the Möbius map model-H → D (``w ↦ apex``); it equals
    ``[[1, x], [x̄, 1]] · tau_local`` with ``x = frame`` (the apex) — use the factored form
    (``phi_inv(frame, mobius(tau_local, ζ))``) for accuracy on tiny triangles.
    ``inner_vertices``: global indices of the vertices in or on ∂T_i; ``inner_model`` their model
    coordinates in H; ``center``: the model centre ``c`` of T_i; ``frame_ld``: the apex in
    extended precision (``frame`` is it rounded; ``1 − |frame|²`` loses digits at 1e-14).
    The pipeline replaces ``f`` on these vertices by ``h(ζ) = g(c) + (ζ − c)·g'(c)`` with
    ``g = f∘τ⁻¹`` (§7).
    """

    tau_inv: NDArray[np.complex128]
    tau_local: NDArray[np.complex128]
    frame: complex
    inner_vertices: NDArray[np.int64]
    inner_model: NDArray[np.complex128]
    center: complex
    frame_ld: np.clongdouble


@dataclass(frozen=True, eq=False)
class DiskMesh:
    """Conforming quad mesh of W ⊂ D (Lemma 2.2 + Lemmas 4.1, 5.1, 6.1).

    Attributes:
        vertices: (V,) complex; ideal vertices have ``|z| = 1`` exactly.
        quads: (Q, 4) int, counter-clockwise.
        kind_code: (Q,) uint8, index into :data:`KIND_NAMES` (one byte a quad; the strings
            would take 88).
        kind (property): (Q,) str, ``"pentagon"``, ``"carleson_quadrilateral"`` or
            ``"carleson_triangle"``, decoded from ``kind_code`` on each access.
        inner: (Q,) bool, quad inside an inner triangle ``T_i``.
        piece: (Q,) int, index of the piece: pentagons ``0..T-1``, then the quadrilaterals in
            ``pieces.quads`` order, then the triangles.
        pieces: the :class:`RegionW`.
        on_circle: (V,) bool, ideal vertices (on T).
        gamma: per interval j, the vertex indices along ``γ_j`` from the ideal endpoint at the
            end of ``J_j`` to the one at its start (``3·N_side + 1 + 2M + 2`` vertices).
        triangles: one :class:`TriangleMap` per Carleson triangle.
        piece_center: (P,) complex, a point of each piece (pentagon centre, quad top midpoint,
            triangle apex) — a local centre for power-series evaluation.
        vertex_piece: (V,) int, a piece containing each vertex.
        depths: the global depth sequence ``0 = d_0 < … < d_M``.
        n: steps per half pentagon side (``N_side = 2n``).
        frames: (F,) clongdouble frame points: the tile centres, then the top corners ``u0`` of
            the Carleson quadrilaterals, then the triangle apices.
        vertex_frame (property): (V,) int, the frame of each vertex.
        vertex_offset (property): (V,) complex128, ``vertex − frames[vertex_frame]`` with full
            relative accuracy (``vertices`` is this sum rounded once to complex128; ideal
            vertices are then normalised to ``|z| = 1``).
        piece_center_ld: (P,) clongdouble, ``piece_center`` before rounding.
    """

    vertices: NDArray[np.complex128]
    quads: NDArray[np.int64]
    kind_code: NDArray[np.uint8]
    inner: NDArray[np.bool_]
    piece: NDArray[np.int64]
    pieces: RegionW
    on_circle: NDArray[np.bool_]
    gamma: list[NDArray[np.int64]]
    triangles: list[TriangleMap]
    piece_center: NDArray[np.complex128]
    vertex_piece: NDArray[np.int64]
    depths: NDArray[np.float64]
    n: int
    frames: NDArray[np.clongdouble]
    piece_center_ld: NDArray[np.clongdouble]
    _parts: tuple = field(repr=False)

    @cached_property
    def _frame_offset(self) -> tuple[NDArray[np.int64], NDArray[np.complex128]]:
        V = self.vertices.size
        vf = np.empty(V, dtype=np.int64)
        vo = np.empty(V, dtype=np.complex128)
        for ids, fr, off in self._parts:
            vf[ids] = fr
            vo[ids] = off
        # ideal vertices: normalise |z| = 1 in long double, offsets consistent with it
        on = np.flatnonzero(self.on_circle)
        f = self.frames[vf[on]]
        zc = f + vo[on]
        vo[on] = (zc / np.abs(zc) - f).astype(np.complex128)
        return vf, vo

    @property
    def kind(self) -> NDArray[np.str_]:
        """(Q,) str, the kind of each quad (:data:`KIND_NAMES` decoded from ``kind_code``)."""
        return np.asarray(KIND_NAMES)[self.kind_code]

    @property
    def vertex_frame(self) -> NDArray[np.int64]:
        """(V,) index into :attr:`frames` of each vertex (computed on first use)."""
        return self._frame_offset[0]

    @property
    def vertex_offset(self) -> NDArray[np.complex128]:
        """(V,) ``vertex − frames[vertex_frame]`` in float64 with full relative accuracy."""
        return self._frame_offset[1]

    @property
    def n_side(self) -> int:
        """Steps per pentagon side / Carleson top edge."""
        return 2 * self.n

    def exact_vertices(self) -> NDArray[np.clongdouble]:
        """The vertices in extended precision, ``frames[vertex_frame] + vertex_offset``."""
        return self.frames[self.vertex_frame] + self.vertex_offset

    def offsets_from(self, points: ArrayLike, index: ArrayLike | None = None) -> NDArray:
        """``vertex[index] − point`` (complex128) without cancellation, for reference points
        given in extended precision (e.g. ``piece_center_ld[vertex_piece]`` for series about
        the piece centres, or prevertices ``e^{iθ}`` with θ in long double): the difference of
        the long double frame and the point, plus the float64 offset.  ``index`` defaults to all
        vertices; ``points`` broadcasts against it."""
        idx = np.arange(self.vertices.size) if index is None else np.asarray(index)
        p = np.asarray(points).astype(np.clongdouble)
        return (self.frames[self.vertex_frame[idx]] - p).astype(np.complex128) + (
            self.vertex_offset[idx]
        )


def _check_close(
    a: NDArray[np.complex128], b: NDArray[np.complex128], what: str, ref: ArrayLike
) -> None:
    """Assert that positions computed twice agree relative to the local scale ``1−|ref|``
    (``ref``: a point of the piece, broadcast against the rows of ``a``), up to the complex128
    rounding :data:`OUTPUT_SLACK` of the output positions."""
    ref = np.asarray(ref).astype(np.complex128)
    scale = np.maximum(1.0 - np.abs(ref), 1e-300)
    if a.ndim == 2 and ref.ndim == 1:
        scale = scale[:, None]
    err = np.abs(a - b) / scale
    if err.size and np.max(np.abs(a - b) - POSITION_RTOL * scale) > OUTPUT_SLACK:
        raise DiskConstructionError(
            f"{what}: shared vertices disagree (relative error {np.max(err):.2e}); "
            "the pieces do not fit together"
        )


def _split(a: NDArray) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Extended-precision points as complex128 ``hi + lo``."""
    a = np.asarray(a).astype(np.clongdouble)
    hi = a.astype(np.complex128)
    return hi, (a - hi).astype(np.complex128)


def _mobius_batch(M: NDArray[np.complex128], z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    a, b, c, d = (M[:, None, 0, 0], M[:, None, 0, 1], M[:, None, 1, 0], M[:, None, 1, 1])
    return (a * z + b) / (c * z + d)


def _three_point_maps(
    z: NDArray[np.complex128], w: NDArray[np.complex128]
) -> NDArray[np.complex128]:
    """Matrices (k, 2, 2) of the Möbius maps sending ``z[0..2] ↦ w[:, 0..2]``."""

    def S(p0, p1, p2):
        m = np.empty((*np.broadcast(p0, p1, p2).shape, 2, 2), dtype=np.complex128)
        m[..., 0, 0] = p2 - p1
        m[..., 0, 1] = -p0 * (p2 - p1)
        m[..., 1, 0] = p2 - p0
        m[..., 1, 1] = -p1 * (p2 - p0)
        return m

    sz = S(z[0], z[1], z[2])
    sw = S(w[:, 0], w[:, 1], w[:, 2])
    inv = np.empty_like(sw)
    inv[:, 0, 0] = sw[:, 1, 1]
    inv[:, 0, 1] = -sw[:, 0, 1]
    inv[:, 1, 0] = -sw[:, 1, 0]
    inv[:, 1, 1] = sw[:, 0, 0]
    out = inv @ sz[None]
    det = out[:, 0, 0] * out[:, 1, 1] - out[:, 0, 1] * out[:, 1, 0]
    return out / np.sqrt(det)[:, None, None]


def disk_mesh(
    intervals: ArrayLike | RegionW,
    *,
    A: float | None = None,
    n: int = 2,
    depth_step: float = 0.25,
    inner_height: float = 1.0,
    depth_growth: float = 1.0,
    depth_max: float | None = None,
) -> DiskMesh:
    """Conforming quad mesh of W for arcs ``intervals`` (Lemma 2.2 and §§4–6 of the paper).

    Args:
        intervals: (m, 2) arcs (start angle, CCW length) — or an already built :class:`RegionW`.
        A: expansion factor of Lemma 2.2 (required unless a RegionW is given).
        n: steps per half pentagon side; ``N_side = 2n`` on every pentagon side and Carleson top.
        depth_step: spacing of the global depth sequence (``depth_sequence(inner_height, step)``).
        inner_height: height ``h`` of the inner triangle ``T_i`` of the Carleson-triangle model.
        depth_growth: ratio of consecutive depth steps below the last triangle landmark D5
            (1 = uniform; ``depth_sequence(..., growth=)``). Rows below D5 are thin Euclidean
            strips near 90°, so coarsening them saves quads.
        depth_max: depth d_M of the last row above the circle (default ``log(8/step) + 2``);
            the cells of the last row deviate from 90° by about ``e^{−d_M}`` rad (§5).

    Raises:
        DiskConstructionError: if Lemma 2.2's hypotheses fail or the pieces do not fit.
    """
    if isinstance(intervals, RegionW):
        R = intervals
    else:
        if A is None:
            raise DiskConstructionError("disk_mesh needs the expansion factor A")
        with span(0.0, 0.5):
            R = build_region(intervals, A)
    if int(n) != n or n < 1:
        raise DiskConstructionError(
            f"n (steps per half side) must be a positive integer, got {n!r}"
        )
    n = int(n)
    ns = 2 * n
    depths = depth_sequence(inner_height, depth_step, d_max=depth_max, growth=depth_growth)
    Md = depths.size - 1
    PM = pentagon_mesh(n)
    CQ = carleson_quad_mesh(ns, depths)
    TM = model_triangle_mesh(depths, inner_height)

    # ------------------------------------------------------------------ pentagons
    checkpoint(0.5)
    T = R.n_pentagons
    Vp = PM.n_vertices
    side_idx = np.stack([PM.sides[f"edge{k}"] for k in range(5)])  # (5, ns+1)
    nbr = R.tile_neighbour
    t_i, k_i = np.nonzero(nbr >= 0)
    t_j = nbr[t_i, k_i]
    if np.any(nbr[t_j, k_i] != t_i):
        raise DiskConstructionError("tile neighbour relation is not symmetric")
    a = (t_i[:, None] * Vp + side_idx[k_i]).ravel()
    b = (t_j[:, None] * Vp + side_idx[k_i]).ravel()
    graph = coo_matrix((np.ones(a.size), (a, b)), shape=(T * Vp, T * Vp))
    n_pv, labels = connected_components(graph, directed=False)
    pent_gid = labels.reshape(T, Vp)
    pent_c, pent_off = tile_offsets(R.tiles, PM.vertices)  # centres (T,), offsets (T, Vp)
    ph, pl = _split(pent_c)
    pent_pos = ph[:, None] + (pl[:, None] + pent_off)  # complex128, rounded once
    src = np.empty(n_pv, dtype=np.int64)
    src[labels] = np.arange(labels.size)  # one (tile, vertex) source per glued vertex
    rep = pent_pos.ravel()[src]
    _check_close(rep[labels], pent_pos.ravel(), "pentagon-pentagon edges", rep[labels])
    pent_quads = pent_gid[np.arange(T)[:, None, None], orient_quads(PM.quads, R.tiles.sigma)]

    # ------------------------------------------------------------------ Carleson quadrilaterals
    checkpoint(0.6)
    C = len(R.cover)
    nonj = np.array([c.kind != KIND_J for c in R.cover])
    Qc = len(R.quads)
    q_cover = np.array([q.cover for q in R.quads], dtype=np.int64)
    q_tile = np.array([q.pentagon for q in R.quads], dtype=np.int64)
    q_edge = np.array([q.edge for q in R.quads], dtype=np.int64)
    top_ids = pent_gid[q_tile[:, None], side_idx[q_edge]]  # (Qc, ns+1) from V_k to V_{k+1}
    flip = R.tiles.sigma[q_tile]
    top_ids = np.where(flip[:, None], top_ids[:, ::-1], top_ids)
    # rays under each non-J arc i: positions s = 0..m_i; ray(i, s) index = ray_base[i] + s
    m_i = np.array([len(x) for x in R.quad_of_cover])
    n_rays_i = np.where(nonj, m_i + 1, 0)
    ray_base = np.concatenate([[0], np.cumsum(n_rays_i)[:-1]])
    NR = int(n_rays_i.sum())
    rank = np.cumsum(nonj) - 1  # rank of a non-J arc among non-J arcs
    ray_left = np.arange(Qc) + rank[q_cover]  # quads are numbered consecutively in cover order
    ray_right = ray_left + 1
    # ray apex ids
    ray_apex = np.empty(NR, dtype=np.int64)
    ray_apex[ray_left] = top_ids[:, 0]
    ray_apex[ray_right] = top_ids[:, -1]
    shared = ray_right[:-1] == ray_left[1:]
    if np.any(top_ids[:-1, -1][shared] != top_ids[1:, 0][shared]):
        raise DiskConstructionError("consecutive Carleson quad tops do not share their corner")
    # global ids: pentagon vertices, then rays (M+1 new each), then quad/triangle interiors
    nxt = n_pv
    ray_ids = np.empty((NR, Md + 2), dtype=np.int64)
    ray_ids[:, 0] = ray_apex
    ray_ids[:, 1:] = nxt + np.arange(NR * (Md + 1)).reshape(NR, Md + 1)
    nxt += NR * (Md + 1)
    cq_top, cq_left, cq_right = CQ.sides["top"], CQ.sides["left"], CQ.sides["right"]
    fixed_q = np.zeros(CQ.n_vertices, dtype=bool)
    fixed_q[np.concatenate([cq_top, cq_left, cq_right])] = True
    free_q = np.flatnonzero(~fixed_q)
    q_ids = np.empty((Qc, CQ.n_vertices), dtype=np.int64)
    q_ids[:, free_q] = nxt + np.arange(Qc * free_q.size).reshape(Qc, free_q.size)
    nxt += Qc * free_q.size
    q_ids[:, cq_left] = ray_ids[ray_left]
    q_ids[:, cq_right] = ray_ids[ray_right]
    q_ids[:, cq_top] = top_ids  # corners agree with the rays' apices by construction
    # placement, in the frame of each quad's top corner u0 (tile vertices in long double)
    k0 = np.where(flip, (q_edge + 1) % 5, q_edge)
    k1 = np.where(flip, q_edge, (q_edge + 1) % 5)
    qt = R.tiles[q_tile]
    u0 = qt.apply_rows(P0_VERTICES_LD[k0][:, None])[:, 0]
    u1 = qt.apply_rows(P0_VERTICES_LD[k1][:, None])[:, 0]
    cs, cl = R.cover_ld[:, 0], R.cover_ld[:, 1]
    ea = np.exp(1j * cs[q_cover])
    eb = np.exp(1j * (cs[q_cover] + cl[q_cover]))
    vf, qq = carleson_quad_to_disk(
        CQ,
        np.zeros(Qc, complex),
        phi_accurate(u0, u1).astype(np.complex128),
        phi_accurate(u0, ea).astype(np.complex128),
        phi_accurate(u0, eb).astype(np.complex128),
        -np.ones(Qc),
        tol=POSITION_RTOL,
    )
    q_off = frame_offsets(u0[:, None], vf)
    qh, ql = _split(u0)
    q_pos = qh[:, None] + (ql[:, None] + q_off)
    u0_ld = u0
    base = CQ.sides["base"]
    q_pos[:, base] /= np.abs(q_pos[:, base])
    u0 = u0.astype(np.complex128)
    u1 = u1.astype(np.complex128)
    _check_close(q_pos[:, cq_top], rep[top_ids], "Carleson quad tops on pentagon edges", u0)
    ray_pos = np.empty((NR, Md + 2), dtype=np.complex128)
    ray_off = np.empty((NR, Md + 2), dtype=np.complex128)
    ray_frame = np.empty(NR, dtype=np.int64)
    ray_pos[ray_right] = q_pos[:, cq_right]
    ray_off[ray_right] = q_off[:, cq_right]
    ray_frame[ray_right] = T + np.arange(Qc)
    ray_pos[ray_left] = q_pos[:, cq_left]
    ray_off[ray_left] = q_off[:, cq_left]
    ray_frame[ray_left] = T + np.arange(Qc)
    _check_close(
        q_pos[:-1, cq_right][shared],
        q_pos[1:, cq_left][shared],
        "side rays of neighbouring Carleson quads",
        u1[:-1][shared],
    )
    cq_quads = q_ids[np.arange(Qc)[:, None, None], qq]

    # ------------------------------------------------------------------ Carleson triangles
    checkpoint(0.75)
    Tr = len(R.triangles)
    t_cross = np.array([t.crossing for t in R.triangles], dtype=np.int64)
    t_left_ray = ray_base[t_cross] + m_i[t_cross]  # last ray under X_i
    t_right_ray = ray_base[(t_cross + 1) % C]  # first ray under X_{i+1}
    apex_ids = ray_ids[t_left_ray, 0]
    if np.any(apex_ids != ray_ids[t_right_ray, 0]):
        raise DiskConstructionError("triangle side rays do not share the apex vertex")
    tl, tr_ = np.asarray(TM.left), np.asarray(TM.right)
    fixed_t = np.zeros(TM.vertices.size, dtype=bool)
    fixed_t[np.concatenate([tl, tr_])] = True
    free_t = np.flatnonzero(~fixed_t)
    t_ids = np.empty((Tr, TM.vertices.size), dtype=np.int64)
    t_ids[:, free_t] = nxt + np.arange(Tr * free_t.size).reshape(Tr, free_t.size)
    nxt += Tr * free_t.size
    t_ids[:, tl] = ray_ids[t_left_ray]
    t_ids[:, tr_] = ray_ids[t_right_ray]
    apex_ld = R.crossings_ld[t_cross]
    apex = rep[apex_ids]
    _check_close(apex_ld.astype(np.complex128), apex, "triangle apices at pentagon vertices", apex)
    lf = np.exp(1j * cs[(t_cross + 1) % C])  # start of Y = X_{i+1}
    rf = np.exp(1j * (cs[t_cross] + cl[t_cross]))  # end of X = X_i
    w_model = 1j * (1.0 + math.sqrt(2.0))
    tau_local = (
        _three_point_maps(
            np.array([-1.0, 1.0, w_model], dtype=np.complex128),
            np.stack(
                [
                    phi_accurate(apex_ld, lf).astype(np.complex128),
                    phi_accurate(apex_ld, rf).astype(np.complex128),
                    np.zeros(Tr, complex),
                ],
                axis=1,
            ),
        )
        if Tr
        else np.zeros((0, 2, 2), complex)
    )
    t_off = (
        frame_offsets(apex_ld[:, None], _mobius_batch(tau_local, TM.vertices[None, :]))
        if Tr
        else (np.zeros((0, TM.vertices.size), complex))
    )
    th, tlo = _split(apex_ld)
    t_pos = th[:, None] + (tlo[:, None] + t_off)
    tb = np.asarray(TM.base)
    t_pos[:, tb] /= np.abs(t_pos[:, tb])
    _check_close(t_pos[:, tl], ray_pos[t_left_ray], "triangle left sides", apex)
    _check_close(t_pos[:, tr_], ray_pos[t_right_ray], "triangle right sides", apex)
    tri_quads = t_ids[np.arange(Tr)[:, None, None], np.asarray(TM.quads)[None]]

    # ------------------------------------------------------------------ global arrays
    checkpoint(0.9)
    V = nxt
    verts = np.empty(V, dtype=np.complex128)
    verts[:n_pv] = rep
    verts[ray_ids[:, 1:]] = ray_pos[:, 1:]
    verts[q_ids[:, free_q]] = q_pos[:, free_q]
    verts[t_ids[:, free_t]] = t_pos[:, free_t]
    on_circle = np.zeros(V, dtype=bool)
    on_circle[ray_ids[:, -1]] = True
    on_circle[q_ids[:, base]] = True
    on_circle[t_ids[:, tb]] = True
    verts[on_circle] /= np.abs(verts[on_circle])
    frames = np.concatenate([pent_c, u0_ld, apex_ld]).astype(np.clongdouble)
    # (vertex ids, frame ids, offsets) per source; scattered on first use (DiskMesh.vertex_offset)
    parts = (
        (np.arange(n_pv), src // Vp, pent_off.ravel()[src]),
        (ray_ids[:, 1:], ray_frame[:, None], ray_off[:, 1:]),
        (q_ids[:, free_q], (T + np.arange(Qc))[:, None], q_off[:, free_q]),
        (t_ids[:, free_t], (T + Qc + np.arange(Tr))[:, None], t_off[:, free_t]),
    )

    quads = np.concatenate(
        [pent_quads.reshape(-1, 4), cq_quads.reshape(-1, 4), tri_quads.reshape(-1, 4)]
    )
    nq_p, nq_c, nq_t = PM.n_quads, CQ.n_quads, len(TM.quads)
    kind_code = np.repeat(
        np.arange(len(KIND_NAMES), dtype=np.uint8), [T * nq_p, Qc * nq_c, Tr * nq_t]
    )
    inner = np.concatenate(
        [np.zeros(T * nq_p + Qc * nq_c, bool), np.tile(np.asarray(TM.inner, bool), Tr)]
    )
    piece = np.concatenate(
        [
            np.repeat(np.arange(T), nq_p),
            T + np.repeat(np.arange(Qc), nq_c),
            T + Qc + np.repeat(np.arange(Tr), nq_t),
        ]
    )
    piece_center_ld = np.concatenate([pent_c, u0_ld + q_off[:, cq_top[ns // 2]], apex_ld])
    piece_center = piece_center_ld.astype(np.complex128)
    vertex_piece = np.empty(V, dtype=np.int64)
    vertex_piece[quads.ravel()] = np.repeat(piece, 4)

    # ------------------------------------------------------------------ γ_j vertex lists
    gamma: list[NDArray[np.int64]] = [np.zeros(0, np.int64)] * R.m
    checkpoint(0.92)
    for i, c in enumerate(R.cover):
        if c.kind != KIND_J:
            continue
        checkpoint(0.92)
        e = R.cover_edges[i]
        ids = pent_gid[e[:, 0][:, None], side_idx[e[:, 1]]]
        ids = np.where(R.tiles.sigma[e[:, 0]][:, None], ids[:, ::-1], ids)  # start -> end side
        if np.any(ids[1:, 0] != ids[:-1, -1]):
            raise DiskConstructionError(f"the pentagon edges on γ_{c.interval} do not chain")
        chain = np.concatenate([ids[0], *(x[1:] for x in ids[1:])])
        r_end = ray_ids[ray_base[(i + 1) % C]]  # ray of γ under J^r, towards J's end
        r_start = ray_ids[ray_base[i - 1] + m_i[i - 1]]  # ray of γ under J^l, towards J's start
        if r_end[0] != chain[-1] or r_start[0] != chain[0]:
            raise DiskConstructionError(
                f"the rays of γ_{c.interval} do not meet its pentagon edges"
            )
        gamma[c.interval] = np.concatenate([r_end[::-1], chain[::-1][1:-1], r_start])

    # ------------------------------------------------------------------ triangle maps
    checkpoint(0.95)
    inner_v = np.asarray(TM.inner_vertex, bool)
    inner_idx = np.flatnonzero(inner_v)
    frame_m = np.zeros((Tr, 2, 2), np.complex128)
    frame_m[:, 0, 0] = 1.0
    frame_m[:, 1, 1] = 1.0
    frame_m[:, 0, 1] = apex
    frame_m[:, 1, 0] = np.conj(apex)
    tau_inv = frame_m @ tau_local
    model_c = complex(TM.center)
    tmaps = [
        TriangleMap(
            tau_inv=tau_inv[k],
            tau_local=tau_local[k],
            frame=complex(apex[k]),
            inner_vertices=t_ids[k, inner_idx],
            inner_model=np.asarray(TM.vertices)[inner_idx],
            center=model_c,
            frame_ld=apex_ld[k],
        )
        for k in range(Tr)
    ]
    return DiskMesh(
        vertices=verts,
        quads=quads,
        kind_code=kind_code,
        inner=inner,
        piece=piece,
        pieces=R,
        on_circle=on_circle,
        gamma=gamma,
        triangles=tmaps,
        piece_center=piece_center,
        vertex_piece=vertex_piece,
        depths=depths,
        n=n,
        frames=frames,
        piece_center_ld=piece_center_ld,
        _parts=parts,
    )
