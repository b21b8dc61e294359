"""Centre of the largest inscribed disk of a simple polygon (CONFORMAL.md §2.4).

The Schwarz–Christoffel map of a thick piece is normalised by ``f(0) = c`` with ``c`` a point
deep inside the piece: the harmonic measure seen from ``c`` is then spread over the boundary and
the prevertex gaps stay as large as possible (less crowding, §1.8).

The largest inscribed disk is often not unique (a rectangle has a whole segment of centres).
Among the near-optimal centres we take the most central one: the point of the ridge
``{x : dist(x, ∂Ω) ≥ (1 − ε) r_max}`` closest to the ridge's centroid. For a rectangle this is
the centre of the rectangle, for a regular polygon its centre.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.ops import nearest_points

from ..errors import PolygonError

__all__ = ["inscribed_center"]


def inscribed_center(z: np.ndarray, *, rel_tol: float = 1e-4) -> tuple[complex, float]:
    """Return ``(center, radius)`` of a largest inscribed disk of the polygon ``z``.

    ``z`` is a complex array (or an (n, 2) float array) of vertices. The radius of the
    maximum inscribed circle is found with GEOS (``shapely.maximum_inscribed_circle``, a
    certified grid refinement of the distance function) to ``rel_tol`` times the polygon's
    size; ties are broken by the ridge rule of the module docstring (ε = 10 ``rel_tol``).
    ``radius`` is the exact distance from the returned centre to the boundary.
    """
    zz = np.asarray(z)
    if not np.iscomplexobj(zz):
        zz = np.asarray(zz, dtype=float)
        if zz.ndim != 2 or zz.shape[1] != 2:
            raise PolygonError(f"expected complex vertices or an (n, 2) array, got {zz.shape}")
        zz = zz[:, 0] + 1j * zz[:, 1]
    zz = zz.astype(np.complex128).ravel()
    poly = shapely.Polygon(np.column_stack([zz.real, zz.imag]))
    if not poly.is_valid or poly.area <= 0:
        raise PolygonError("inscribed_center needs a simple polygon with positive area")
    size = float(np.sqrt(poly.area))
    mic = shapely.maximum_inscribed_circle(poly, tolerance=rel_tol * size)
    (cx, cy), _ = shapely.get_coordinates(mic)
    boundary = poly.exterior
    r_max = float(shapely.distance(shapely.Point(cx, cy), boundary))
    center = shapely.Point(cx, cy)
    ridge = shapely.buffer(poly, -(1.0 - 10.0 * rel_tol) * r_max, quad_segs=16)
    if not ridge.is_empty:
        parts = list(getattr(ridge, "geoms", [ridge]))
        # the component holding the best centre found by GEOS (or the largest one)
        holding = [p for p in parts if p.covers(center)]
        comp = holding[0] if holding else max(parts, key=lambda p: p.area)
        cen = comp.centroid
        cand = cen if comp.covers(cen) else nearest_points(comp, cen)[0]
        r_cand = float(shapely.distance(cand, boundary))
        if poly.contains(cand) and r_cand >= (1.0 - 20.0 * rel_tol) * r_max:
            center, r_max = cand, r_cand
    return complex(center.x, center.y), r_max
