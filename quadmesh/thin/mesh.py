"""Result types and checks shared by the thin-part meshers (paper, "Meshing the thin parts").

A thin-part mesh is a plain list of quadrilaterals (vertex indices, counter-clockwise) over complex
vertex coordinates, plus the bookkeeping the pipeline needs to glue it onto the neighbouring
thick-piece meshes: which vertices are the crosscut vertices it was given, and which vertices lie
on the polygon sides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ThinPartError
from ..geometry import (
    angle_rounding_slack_deg,
    quad_angles_deg,
    quad_signed_areas,
    unpaired_edges,
)
from ..polygon import signed_area as polygon_area

__all__ = [
    "KIND_CHAIN",
    "KIND_CONNECTION",
    "KIND_MESH1",
    "KIND_MESH2",
    "KIND_NAMES",
    "KIND_STRIP",
    "ChannelMesh",
    "ThinMesh",
    "polygon_area",
    "quad_angles_deg",
    "quad_signed_areas",
    "require_angles",
    "unpaired_edges",
]

#: Region kinds stored per quad (index into :data:`KIND_NAMES`).
KIND_MESH1 = 0
KIND_MESH2 = 1
KIND_STRIP = 2
KIND_CONNECTION = 3
KIND_CHAIN = 4
KIND_NAMES: tuple[str, ...] = ("mesh1", "mesh2", "strip", "connection", "chain")


class _KindedQuads:
    """Methods shared by the thin-part meshes (fields ``vertices``, ``quads``, ``kind``)."""

    vertices: np.ndarray
    quads: np.ndarray
    kind: np.ndarray

    @property
    def kind_names(self) -> list[str]:
        """Region kind of every quad as a string."""
        return [KIND_NAMES[k] for k in self.kind]

    def angles_deg(self) -> np.ndarray:
        """(Q, 4) interior angle at every quad corner, degrees."""
        return quad_angles_deg(self.vertices, self.quads)


@dataclass(frozen=True)
class ThinMesh(_KindedQuads):
    """Quad mesh of a parabolic thin part (vertex sector).

    Attributes:
        vertices: (V,) complex vertex coordinates.
        quads: (Q, 4) int vertex indices, counter-clockwise.
        kind: (Q,) uint8 region kind per quad, see :data:`KIND_NAMES`.
        gamma_index: (P,) int, ``vertices[gamma_index[k]] == g_k`` exactly.
        apex_index: index of the apex v.
        side1: indices of the vertices on side 1, from the apex outwards: starts with
            ``apex_index`` and ends with ``gamma_index[0]``.
        side2: the same for side 2, ending with ``gamma_index[-1]``.
        exempt_apex: True when the apex angle is the original polygon angle (m = 1) and is not
            a new angle.
    """

    vertices: np.ndarray
    quads: np.ndarray
    kind: np.ndarray
    gamma_index: np.ndarray
    apex_index: int
    side1: np.ndarray
    side2: np.ndarray
    exempt_apex: bool

    def new_angle_mask(self) -> np.ndarray:
        """(Q, 4) bool: True for the corners that are new angles (all but the exempt apex)."""
        mask = np.ones(self.quads.shape, dtype=bool)
        if self.exempt_apex:
            mask &= self.quads != self.apex_index
        return mask


@dataclass(frozen=True)
class ChannelMesh(_KindedQuads):
    """Quad mesh of a hyperbolic thin part (channel between two walls).

    Attributes:
        vertices: (V,) complex vertex coordinates.
        quads: (Q, 4) int vertex indices, counter-clockwise.
        kind: (Q,) uint8 region kind per quad (all :data:`KIND_CHAIN`).
        gamma1_index, gamma2_index: (P,) int, the given crosscut vertices (exact copies).
        wall1, wall2: vertex indices on wall 1 / wall 2, ordered from gamma1 to gamma2.
        n_intermediate: number J of intermediate crosscuts used.
    """

    vertices: np.ndarray
    quads: np.ndarray
    kind: np.ndarray
    gamma1_index: np.ndarray
    gamma2_index: np.ndarray
    wall1: np.ndarray
    wall2: np.ndarray
    n_intermediate: int

    def new_angle_mask(self) -> np.ndarray:
        """(Q, 4) bool: every corner of a channel mesh is a new angle."""
        return np.ones(self.quads.shape, dtype=bool)


def require_angles(
    vertices: np.ndarray,
    quads: np.ndarray,
    mask: np.ndarray,
    lo: float,
    hi: float,
    what: str,
    tol: float = 1e-6,
    coord_scale: float = 0.0,
) -> None:
    """Raise :class:`ThinPartError` unless every masked corner angle lies in [lo, hi] degrees.

    The slack is ``tol`` plus the precision the final float64 coordinates allow, as in
    :meth:`quadmesh.mesh.QuadMesh.angle_slack`: 8ε·|z|/ℓ radians for a quad with shortest
    edge ℓ, with |z| the larger of the coordinates' magnitude and ``coord_scale`` (pass the
    magnitude of the absolute position when ``vertices`` are relative to a local origin).
    Exact 60°/120° corners of Mesh 1 / Mesh 2 read outside the bound by up to that much.
    """
    areas = quad_signed_areas(vertices, quads)
    if np.any(areas <= 0.0):
        raise ThinPartError(f"{what}: {int(np.sum(areas <= 0))} quads are degenerate or inverted")
    ang = quad_angles_deg(vertices, quads)
    slack = tol + angle_rounding_slack_deg(vertices, quads, coord_scale)
    slack = np.broadcast_to(slack[:, None], ang.shape)[mask]
    ang = ang[mask]
    if ang.size and (np.any(ang < lo - slack) or np.any(ang > hi + slack)):
        raise ThinPartError(
            f"{what}: produced angles in [{ang.min():.9f}, {ang.max():.9f}] degrees, "
            f"outside [{lo:g}, {hi:g}]"
        )
