"""Simple polygons: validation, orientation, interior angles, normalisation.

The pipeline accepts an (n, 2) float array, a complex array or a :class:`Polygon`.
:func:`validate_polygon` turns any of them into a :class:`Polygon` whose vertices are
finite, pairwise distinct, counter-clockwise and form a simple closed curve.

Normalisations (documented, silent):

* a closing point equal to the first point is dropped;
* consecutive exactly repeated points are merged;
* a clockwise polygon is reversed.

Everything else that is wrong raises :class:`~quadmesh.errors.PolygonError`.
Collinear runs are kept: a vertex with interior angle 180° is a legitimate vertex of the
mesh boundary (it is meshed by a bisected sector), unless ``drop_collinear=True``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import PolygonError

__all__ = ["Polygon", "as_complex", "interior_angles", "signed_area", "validate_polygon"]


def as_complex(points: object) -> np.ndarray:
    """Return ``points`` as a 1-D complex128 array (accepts (n, 2) reals or complex)."""
    if isinstance(points, Polygon):
        return points.z.copy()
    arr = np.asarray(points)
    if np.iscomplexobj(arr):
        return arr.astype(np.complex128).ravel()
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise PolygonError(
            f"expected an (n, 2) array of points or a complex array, got shape {arr.shape}"
        )
    z = np.empty(arr.shape[0], dtype=np.complex128)
    z.real, z.imag = arr[:, 0], arr[:, 1]  # no arithmetic: inf stays inf, no NaN warnings
    return z


def signed_area(z: np.ndarray) -> float:
    """Shoelace signed area of the closed polygon with complex vertices ``z`` (CCW > 0)."""
    z = z - z[0]  # translate first: the shoelace sum loses digits far from the origin
    zn = np.roll(z, -1)
    return 0.5 * float(np.sum(z.real * zn.imag - zn.real * z.imag))


def interior_angles(z: np.ndarray) -> np.ndarray:
    """Interior angles (radians, in (0, 2π)) of the CCW polygon ``z`` at each vertex."""
    e_in = z - np.roll(z, 1)
    e_out = np.roll(z, -1) - z
    turn = np.angle(e_out / e_in)  # exterior turning angle in (-π, π]
    return np.pi - turn


@dataclass(frozen=True)
class Polygon:
    """A validated simple polygon, counter-clockwise, as complex vertices.

    Attributes:
        z: complex vertices (n,), counter-clockwise, no repeats.
        reversed_input: True when the input was clockwise and has been reversed.
    """

    z: np.ndarray
    reversed_input: bool = False
    _angles: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        z = np.asarray(self.z, dtype=np.complex128)
        z.setflags(write=False)
        object.__setattr__(self, "z", z)
        a = interior_angles(z)
        a.setflags(write=False)
        object.__setattr__(self, "_angles", a)

    @property
    def n(self) -> int:
        """Number of vertices."""
        return int(self.z.shape[0])

    @property
    def vertices(self) -> np.ndarray:
        """Vertices as an (n, 2) float64 array."""
        return np.column_stack([self.z.real, self.z.imag])

    @property
    def angles(self) -> np.ndarray:
        """Interior angles in radians."""
        return self._angles

    @property
    def area(self) -> float:
        """Area (positive)."""
        return signed_area(self.z)

    @property
    def edge_lengths(self) -> np.ndarray:
        """Length of edge k = [z_k, z_{k+1}]."""
        return np.abs(np.roll(self.z, -1) - self.z)

    @property
    def diameter(self) -> float:
        """Euclidean diameter of the bounding box diagonal (a cheap scale)."""
        return float(np.hypot(np.ptp(self.z.real), np.ptp(self.z.imag)))

    def __len__(self) -> int:
        return self.n


def validate_polygon(points: object, *, drop_collinear: bool = False) -> Polygon:
    """Validate ``points`` and return a counter-clockwise simple :class:`Polygon`.

    Raises :class:`PolygonError` for fewer than 3 distinct points, NaN/inf, coordinates
    whose magnitude makes double precision meaningless, repeated (non-consecutive)
    vertices, self-intersection or zero area.
    """
    if isinstance(points, Polygon):
        return points
    try:
        z = as_complex(points)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, PolygonError):
            raise
        raise PolygonError(f"cannot read polygon points: {exc}") from exc
    if z.size < 3:
        raise PolygonError(f"a polygon needs at least 3 points, got {z.size}")
    if not np.all(np.isfinite(z)):
        bad = int(np.flatnonzero(~np.isfinite(z))[0])
        raise PolygonError(f"point {bad} is not finite ({z[bad]})")
    scale = float(np.max(np.abs(z - z[0])))
    if scale == 0.0:
        raise PolygonError("all points coincide")
    if np.max(np.abs(z)) > 1e150 or scale < 1e-150:
        raise PolygonError(
            "coordinates out of the representable range "
            "(magnitude above 1e150 or extent below 1e-150)"
        )
    # closing point, consecutive duplicates
    if z.size > 1 and z[-1] == z[0]:
        z = z[:-1]
    keep = z != np.roll(z, 1)
    z = z[keep]
    if z.size < 3:
        raise PolygonError(f"a polygon needs at least 3 distinct points, got {z.size}")
    # relative resolution: points closer than 1e-12 of the extent are treated as repeated
    tol = 1e-12 * scale
    order = np.lexsort((z.imag, z.real))
    zs = z[order]
    close = np.abs(np.diff(zs)) <= tol
    if np.any(close):
        i = int(np.flatnonzero(close)[0])
        a, b = sorted((int(order[i]), int(order[i + 1])))
        raise PolygonError(f"points {a} and {b} coincide ({z[a]}); the boundary would touch itself")
    area = signed_area(z)
    if abs(area) <= 1e-14 * scale * scale:
        w = (z - z[0]) / scale
        if np.max(np.abs((w * np.conj(w[np.argmax(np.abs(w))])).imag)) <= 1e-12:
            raise PolygonError("the polygon has zero area (all points are collinear)")
        _check_simple(z)
        raise PolygonError("the polygon has zero area")
    reversed_input = False
    if area < 0:
        z = z[::-1].copy()
        reversed_input = True
    _check_simple(z)
    ang = interior_angles(z)
    if np.any((ang < 1e-12) | (ang > 2 * np.pi - 1e-12)):
        k = int(np.flatnonzero((ang < 1e-12) | (ang > 2 * np.pi - 1e-12))[0])
        raise PolygonError(
            f"the boundary turns back on itself at vertex {k} (a spike of angle 0 or 360°)"
        )
    if drop_collinear:
        straight = np.abs(ang - np.pi) < 1e-9
        if np.any(straight):
            z = z[~straight]
    return Polygon(z, reversed_input=reversed_input)


def _check_simple(z: np.ndarray) -> None:
    """Raise PolygonError if the closed polyline ``z`` self-intersects (shapely, O(n log n))."""
    import shapely

    ring = shapely.linearrings(np.column_stack([z.real, z.imag]))
    if shapely.is_simple(ring):
        return
    # locate a crossing for the message
    from shapely import STRtree

    n = z.size
    segs = shapely.linestrings(
        np.stack(
            [
                np.column_stack([z.real, z.imag]),
                np.roll(np.column_stack([z.real, z.imag]), -1, axis=0),
            ],
            axis=1,
        )
    )
    tree = STRtree(segs)
    left, right = tree.query(segs, predicate="intersects")
    mask = (left < right) & ((right - left) % n != 1) & ((left - right) % n != 1)
    if np.any(mask):
        i, j = int(left[mask][0]), int(right[mask][0])
        raise PolygonError(f"the polygon is not simple: edge {i} intersects edge {j}")
    raise PolygonError("the polygon is not simple (its boundary touches itself)")
