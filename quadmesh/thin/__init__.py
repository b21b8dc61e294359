"""Meshes of the thin parts (paper, section "Meshing the thin parts").

* :func:`mesh_vertex_sector` / :func:`parabolic_mesh`: parabolic thin part between a polygon
  vertex and a crosscut.
* :func:`mesh_channel` / :func:`channel_mesh`: hyperbolic thin part between two walls and two
  crosscuts.
* :func:`conformal_collar`: straightens a crosscut that is not round about its vertex (or not
  straight across its channel) before either of the above.
"""

from __future__ import annotations

import numpy as np

from .channel import Walls, default_crosscut_count, mesh_channel
from .collar import CollarMesh, conformal_collar, vertex_walls
from .mesh import KIND_NAMES, ChannelMesh, ThinMesh, quad_angles_deg
from .parabolic import mesh2_local, mesh_vertex_sector, split_count

__all__ = [
    "KIND_NAMES",
    "ChannelMesh",
    "CollarMesh",
    "ThinMesh",
    "Walls",
    "channel_mesh",
    "conformal_collar",
    "default_crosscut_count",
    "mesh2_local",
    "mesh_channel",
    "mesh_vertex_sector",
    "parabolic_mesh",
    "quad_angles_deg",
    "split_count",
    "vertex_walls",
]


def parabolic_mesh(
    vertex: complex, gamma: np.ndarray, theta: float
) -> tuple[np.ndarray, np.ndarray]:
    """Quad mesh of the region between ``vertex`` and the crosscut ``gamma`` (paper §8,
    parabolic case): ``gamma`` (P,) complex, ordered from side 1 to side 2, so the sides are
    the rays from ``vertex`` through ``gamma[0]`` and ``gamma[-1]``; ``theta`` the interior
    angle (radians) counter-clockwise from side 1 to side 2. Returns complex vertices
    (containing every gamma point exactly) and (q, 4) counter-clockwise quads. Uses the
    conformal collar first when the crosscut is not round enough about the vertex.
    """
    from ..errors import ThinPartError

    g = np.asarray(gamma, dtype=np.complex128).ravel()
    side1 = (g[0] - vertex) / abs(g[0] - vertex)
    try:
        m = mesh_vertex_sector(vertex, side1, theta, g)
        return m.vertices.copy(), m.quads.copy()
    except ThinPartError:
        col = conformal_collar(g, vertex_walls(vertex, side1, theta), toward="inner")
    straight = col.vertices[col.straight_index]
    sec = mesh_vertex_sector(vertex, side1, theta, straight)
    return _union(col.vertices, col.quads, col.straight_index, sec)


def channel_mesh(gamma1: np.ndarray, gamma2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quad mesh of a hyperbolic thin part between two crosscuts with the same number of
    vertices, both ordered from wall 1 to wall 2 (wall 1 joins ``gamma1[0]`` to
    ``gamma2[0]``, wall 2 joins ``gamma1[-1]`` to ``gamma2[-1]``); the walls are inferred
    from the crosscut endpoints (:meth:`Walls.from_crosscuts`). Returns complex vertices
    (containing every crosscut point exactly) and (q, 4) counter-clockwise quads.
    """
    m = mesh_channel(np.asarray(gamma1), np.asarray(gamma2))
    return m.vertices.copy(), m.quads.copy()


def _union(
    cv: np.ndarray, cq: np.ndarray, straight: np.ndarray, sec: ThinMesh
) -> tuple[np.ndarray, np.ndarray]:
    """Glue a sector built on a collar's straight crosscut onto the collar, by index."""
    ids = np.full(sec.vertices.size, -1, dtype=np.int64)
    ids[np.asarray(sec.gamma_index)] = np.asarray(straight)
    own = ids < 0
    ids[own] = cv.size + np.arange(int(own.sum()))
    verts = np.concatenate([cv, sec.vertices[own]])
    return verts, np.concatenate([cq, ids[sec.quads]])
