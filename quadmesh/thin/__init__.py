"""Meshes of the thin parts (paper, section "Meshing the thin parts"; THIN.md).

* :func:`mesh_vertex_sector`: parabolic thin part between a polygon vertex and a crosscut.
* :func:`mesh_channel`: hyperbolic thin part between two walls and two crosscuts.
"""

from .channel import Walls, default_crosscut_count, mesh_channel
from .collar import CollarMesh, conformal_collar, vertex_walls  # noqa: F401
from .mesh import KIND_NAMES, ChannelMesh, ThinMesh, quad_angles_deg
from .parabolic import mesh2_local, mesh_vertex_sector, split_count

__all__ = [
    "KIND_NAMES",
    "ChannelMesh",
    "ThinMesh",
    "Walls",
    "default_crosscut_count",
    "mesh2_local",
    "mesh_channel",
    "mesh_vertex_sector",
    "quad_angles_deg",
    "split_count",
]
