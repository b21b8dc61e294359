"""Canonical piece meshes and quad-mesh checks shared by the disk construction (paper §§4–6).

A :class:`CanonicalMesh` is the mesh of one model piece (the central right pentagon P0 of
Lemma 4.1, the model Carleson quadrilateral of Lemma 5.1, ...).  Every piece of the disk
decomposition is an isometric (or Möbius) image of its model, so the model mesh is built once
and moved by stacked isometries (:func:`place_mesh`).

Re-exported here from :mod:`quadmesh.geometry`: :func:`check_conformity` (each interior edge in
exactly two quads, with opposite orientations; returns the boundary edges), :func:`chord_angles`
(= :func:`quadmesh.geometry.quad_angles_deg`, interior angles of the straight-edged
quadrilaterals, in degrees) and :func:`quad_signed_areas`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import check_conformity, quad_signed_areas
from ..geometry import quad_angles_deg as chord_angles
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
