"""The disk side of Bishop's construction (paper §§2–6).

* :mod:`.tessellation` — the right-pentagon tessellation T5, point location, the arc family I5
  and Lemma 2.1's minimal containing arc (local search).
* :mod:`.region` — Lemma 2.2: the region W and its right pentagons, Carleson quadrilaterals and
  Carleson triangles (:func:`build_region`).
* :mod:`.pentagon`, :mod:`.carleson_quad`, :mod:`.carleson_triangle` — the piece meshes
  (Lemmas 4.1, 5.1, 6.1).
* :mod:`.assembly` — the conforming mesh of W (:func:`disk_mesh`).
* :mod:`.demo` — pictures of the construction (matplotlib, imported lazily).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "DiskMesh": "assembly",
    "TriangleMap": "assembly",
    "disk_mesh": "assembly",
    "CarlesonQuadrilateral": "region",
    "CarlesonTriangle": "region",
    "CoverArc": "region",
    "RegionW": "region",
    "RightPentagon": "region",
    "build_region": "region",
    "L": "tessellation",
    "locate": "tessellation",
    "minimal_containing_arc": "tessellation",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """Import the public names lazily, so that importing one piece module (e.g.
    ``quadmesh.disk.pentagon``) does not import the whole construction."""
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
