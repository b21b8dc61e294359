"""Canonical piece meshes and quad-mesh checks shared by the disk construction (paper §§4–6).

A :class:`CanonicalMesh` is the mesh of one model piece (the central right pentagon P0 of
Lemma 4.1, the model Carleson quadrilateral of Lemma 5.1, ...).  Every piece of the disk
decomposition is an isometric (or Möbius) image of its model, so the model mesh is built once
and moved by stacked isometries (:func:`place_mesh`).

Also here: :func:`check_conformity` (each interior edge in exactly two quads, with opposite
orientations; returns the boundary edges), :func:`chord_angles` (interior angles of the
straight-edged quadrilaterals, in degrees) and :func:`quad_signed_areas`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import MeshVerificationError
from ..hyperbolic import Isometry

__all__ = [
    "CanonicalMesh",
    "check_conformity",
    "chord_angles",
    "orient_quads",
    "place_mesh",
    "quad_signed_areas",
]

IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class CanonicalMesh:
    """Quad mesh of one model piece.

    Attributes:
        vertices: complex array ``(V,)`` of vertex positions.
        quads: int array ``(Q, 4)`` of vertex indices, each quad counter-clockwise.
        sides: named boundary sides, each an int array of vertex indices in order along the side
            (both end corners included).
    """

    vertices: NDArray[np.complex128]
    quads: IntArray
    sides: dict[str, IntArray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=np.complex128)
        q = np.asarray(self.quads, dtype=np.int64)
        if q.ndim != 2 or q.shape[1] != 4:
            raise ValueError(f"quads must have shape (Q, 4), got {q.shape}")
        if q.size and (q.min() < 0 or q.max() >= v.shape[0]):
            raise ValueError("quad vertex index out of range")
        v.setflags(write=False)
        q.setflags(write=False)
        sides = {}
        for name, idx in self.sides.items():
            a = np.asarray(idx, dtype=np.int64)
            a.setflags(write=False)
            sides[name] = a
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "quads", q)
        object.__setattr__(self, "sides", sides)

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return int(self.vertices.shape[0])

    @property
    def n_quads(self) -> int:
        """Number of quads."""
        return int(self.quads.shape[0])

    def side_points(self, name: str) -> NDArray[np.complex128]:
        """Positions of the vertices of side ``name``, in order."""
        return self.vertices[self.sides[name]]


def _edges(quads: IntArray) -> IntArray:
    """Directed edges ``(4Q, 2)`` of the quads, quad by quad, in the order 01, 12, 23, 30."""
    q = np.asarray(quads, dtype=np.int64)
    return np.stack([q, np.roll(q, -1, axis=1)], axis=-1).reshape(-1, 2)


def check_conformity(quads: ArrayLike, n_vertices: int | None = None) -> IntArray:
    """Check that a quad mesh is conforming and consistently oriented; return its boundary edges.

    Conditions: no quad repeats a vertex; no directed edge occurs twice (which would mean two quads
    with the same orientation across an edge, or a duplicated quad); every undirected edge belongs
    to one quad (boundary) or two quads (interior, then with opposite orientations); every vertex
    index is used (if ``n_vertices`` is given).

    Returns:
        int array ``(B, 2)`` of the boundary edges, directed as in their quad (so for a CCW mesh of
        a disk-like region they run counter-clockwise around the boundary).

    Raises:
        MeshVerificationError: naming the first violated condition.
    """
    q = np.asarray(quads, dtype=np.int64)
    if q.ndim != 2 or q.shape[1] != 4:
        raise MeshVerificationError(f"quads must have shape (Q, 4), got {q.shape}")
    srt = np.sort(q, axis=1)
    if np.any(srt[:, 1:] == srt[:, :-1]):
        bad = int(np.nonzero(np.any(srt[:, 1:] == srt[:, :-1], axis=1))[0][0])
        raise MeshVerificationError(f"quad {bad} repeats a vertex: {q[bad].tolist()}")
    e = _edges(q)
    nv = int(q.max()) + 1 if n_vertices is None else int(n_vertices)
    directed = e[:, 0] * nv + e[:, 1]
    uniq, cnt = np.unique(directed, return_counts=True)
    if np.any(cnt > 1):
        k = int(uniq[cnt > 1][0])
        raise MeshVerificationError(
            f"directed edge ({k // nv}, {k % nv}) occurs {int(cnt[cnt > 1][0])} times: "
            "quads overlap or are inconsistently oriented"
        )
    lo = np.minimum(e[:, 0], e[:, 1])
    hi = np.maximum(e[:, 0], e[:, 1])
    und = lo * nv + hi
    uniq, inv, cnt = np.unique(und, return_inverse=True, return_counts=True)
    if np.any(cnt > 2):
        k = int(uniq[cnt > 2][0])
        raise MeshVerificationError(
            f"edge ({k // nv}, {k % nv}) is shared by {int(cnt[cnt > 2][0])} quads"
        )
    if n_vertices is not None:
        used = np.zeros(nv, dtype=bool)
        used[q.ravel()] = True
        if not np.all(used):
            raise MeshVerificationError(
                f"{int((~used).sum())} vertices are not used by any quad "
                f"(first: {int(np.nonzero(~used)[0][0])})"
            )
    return e[cnt[inv] == 1]


def _corners(vertices: ArrayLike, quads: ArrayLike) -> NDArray[np.complex128]:
    """Corner positions ``(..., Q, 4)``: ``vertices (V,)`` or ``(k, V)`` with ``quads (Q, 4)`` or
    stacked ``(k, Q, 4)`` (copy ``i`` of the quads indexes copy ``i`` of the vertices)."""
    v = np.asarray(vertices, dtype=np.complex128)
    q = np.asarray(quads, dtype=np.int64)
    if q.ndim == 3:
        if v.ndim != 2 or v.shape[0] != q.shape[0]:
            raise ValueError("stacked quads (k, Q, 4) need stacked vertices (k, V)")
        return np.take_along_axis(v, q.reshape(q.shape[0], -1), axis=1).reshape(q.shape)
    return v[..., q]


def quad_signed_areas(vertices: ArrayLike, quads: ArrayLike) -> NDArray[np.float64]:
    """Signed Euclidean areas of the straight-edged quads (positive = counter-clockwise).

    ``vertices`` may be ``(V,)`` or stacked ``(k, V)`` (with ``quads`` ``(Q, 4)`` or stacked
    ``(k, Q, 4)``); the result is ``(Q,)`` or ``(k, Q)``.
    """
    z = _corners(vertices, quads)
    w = np.roll(z, -1, axis=-1)
    return 0.5 * np.sum((np.conj(z) * w).imag, axis=-1)


def chord_angles(vertices: ArrayLike, quads: ArrayLike) -> NDArray[np.float64]:
    """Interior angles (degrees) of the straight-edged quads on the mesh vertices.

    The angle at corner ``b`` with predecessor ``a`` and successor ``c`` is the counter-clockwise
    turn from ``c−b`` to ``a−b``, in ``[0, 360)``; a convex CCW quad has all four in (0, 180).
    ``quads`` may be ``(Q, 4)`` or stacked ``(k, Q, 4)`` matching stacked ``vertices (k, V)``.
    Returns an array of shape ``quads.shape``.
    """
    z = _corners(vertices, quads)
    a = np.roll(z, 1, axis=-1)
    c = np.roll(z, -1, axis=-1)
    ang = np.angle((a - z) / (c - z))
    return np.degrees(np.mod(ang, 2.0 * np.pi))


def orient_quads(quads: ArrayLike, reverse: ArrayLike) -> IntArray:
    """Stack the quads once per copy, reversing the vertex order where ``reverse`` is True.

    An orientation-reversing placement turns CCW quads clockwise; reversing the order
    ``(0,1,2,3) → (0,3,2,1)`` (same first vertex) restores counter-clockwise order.
    Returns ``(k, Q, 4)`` for ``reverse`` of shape ``(k,)``.
    """
    q = np.asarray(quads, dtype=np.int64)
    rev = np.asarray(reverse, dtype=bool)
    flipped = q[:, [0, 3, 2, 1]]
    return np.where(rev[:, None, None], flipped[None], q[None])


def place_mesh(mesh: CanonicalMesh, g: Isometry) -> tuple[NDArray[np.complex128], IntArray]:
    """Move a canonical mesh by a stack of ``k`` isometries (or Möbius pairs) at once.

    Returns ``(vertices (k, V), quads (k, Q, 4))`` with every copy's quads counter-clockwise
    (vertex order reversed for the copies with ``sigma`` True).  A single isometry is treated
    as a stack of one.
    """
    if not g.is_stack:
        g = Isometry(g.M[None], g.sigma[None])
    verts = g.apply_rows(mesh.vertices)
    return verts, orient_quads(mesh.quads, g.sigma)
