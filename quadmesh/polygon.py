"""Simple polygons: validation, orientation, interior angles, normalisation.

The pipeline accepts an (n, 2) float array, a complex array or a :class:`Polygon`.
:func:`validate_polygon` turns any of them into a :class:`Polygon` whose vertices are
finite, pairwise distinct, counter-clockwise and form a simple closed curve.

Normalisations (documented, silent):

* a closing point equal to the first point is dropped;
* consecutive exactly repeated points are merged;
* a clockwise polygon is reversed.

Every normalised vertex remembers its position in the input (:attr:`Polygon.source_index`),
so that messages about the polygon (here and in later stages) name vertices and edges in the
user's own numbering: :meth:`Polygon.user_vertex`, :meth:`Polygon.describe_vertex`,
:meth:`Polygon.describe_edge`.

Everything else that is wrong raises :class:`~quadmesh.errors.PolygonError`, whose message
names the offending input points (their index in the input and their coordinates).
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


def _fmt_xy(w: complex) -> str:
    """``(x, y)`` with 6 significant digits, as a user types coordinates."""
    return f"({w.real:.6g}, {w.imag:.6g})"


@dataclass(frozen=True)
class Polygon:
    """A validated simple polygon, counter-clockwise, as complex vertices.

    Attributes:
        z: complex vertices (n,), counter-clockwise, no repeats.
        reversed_input: True when the input was clockwise and has been reversed.
        source_index: int64 array (n,): ``source_index[i]`` is the position, in the points the
            user gave, of vertex ``i`` (after dropping the closing point and repeats and
            after reversing a clockwise input).  Defaults to ``0, 1, …, n−1``.  Messages use
            it to name vertices in the user's numbering (:meth:`describe_vertex`).
        display_offset: added to ``z`` when coordinates are shown to the user (non-zero only
            for a copy translated by :meth:`translated`, whose messages must still quote the
            user's coordinates).
    """

    z: np.ndarray
    reversed_input: bool = False
    source_index: np.ndarray | None = field(default=None, compare=False)
    display_offset: complex = field(default=0j, compare=False)
    _angles: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        z = np.asarray(self.z, dtype=np.complex128)
        z.setflags(write=False)
        object.__setattr__(self, "z", z)
        if self.source_index is None:
            src = np.arange(z.size, dtype=np.int64)
        else:
            src = np.array(self.source_index, dtype=np.int64)
            if src.shape != z.shape:
                raise ValueError(
                    f"source_index must have one entry per vertex ({z.size}), got {src.shape}"
                )
        src.setflags(write=False)
        object.__setattr__(self, "source_index", src)
        object.__setattr__(self, "display_offset", complex(self.display_offset))
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

    # ------------------------------------------------------------------ user numbering

    def user_vertex(self, i: int) -> int:
        """The input position of vertex ``i`` (index modulo n)."""
        return int(self.source_index[int(i) % self.n])

    def user_point(self, w: complex) -> str:
        """The point ``w`` of this polygon's plane as ``(x, y)`` in the user's coordinates."""
        return _fmt_xy(complex(w) + self.display_offset)

    def describe_vertex(self, i: int) -> str:
        """``"vertex 7 at (1.5, 2)"``: vertex ``i`` in the user's numbering and coordinates."""
        i = int(i) % self.n
        return f"vertex {self.user_vertex(i)} at {self.user_point(self.z[i])}"

    def user_edge(self, i: int) -> tuple[int, int]:
        """Edge ``i`` = [z_i, z_{i+1}] as (first, second) input vertex in the user's order.

        For a clockwise input (reversed here) the user walks the edge from ``i + 1`` to ``i``.
        """
        a, b = self.user_vertex(i), self.user_vertex(int(i) + 1)
        return (b, a) if self.reversed_input else (a, b)

    def describe_edge(self, i: int) -> str:
        """``"edge 3 (from vertex 3 at (0, 1) to vertex 4 at (2, 1))"``, user's numbering.

        The edge is numbered by its first vertex in the user's order (edge k joins input
        points k and k + 1 when no repeated point was dropped between them).
        """
        i = int(i) % self.n
        a, b = self.user_edge(i)
        za, zb = self.z[i], self.z[(i + 1) % self.n]
        if self.reversed_input:
            za, zb = zb, za
        return (
            f"edge {a} (from vertex {a} at {self.user_point(za)} "
            f"to vertex {b} at {self.user_point(zb)})"
        )

    def translated(self, shift: complex) -> Polygon:
        """This polygon moved by ``shift`` (re-validated), keeping the user's numbering and
        quoting the user's (untranslated) coordinates in messages."""
        moved = validate_polygon(self.z + complex(shift))
        return Polygon(
            moved.z,
            reversed_input=self.reversed_input != moved.reversed_input,
            source_index=self.source_index[moved.source_index],
            display_offset=self.display_offset - complex(shift),
        )


def validate_polygon(points: object, *, drop_collinear: bool = False) -> Polygon:
    """Validate ``points`` and return a counter-clockwise simple :class:`Polygon`.

    The result's :attr:`Polygon.source_index` maps each of its vertices back to the position
    of that point in ``points``.

    Raises :class:`PolygonError` for fewer than 3 distinct points, NaN/inf, coordinates
    whose magnitude makes double precision meaningless, repeated (non-consecutive)
    vertices, self-intersection or zero area; the message names the offending points by
    their position in ``points`` and their coordinates.
    """
    if isinstance(points, Polygon):
        return points
    try:
        z = as_complex(points)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, PolygonError):
            raise
        raise PolygonError(f"cannot read polygon points: {exc}") from exc
    src = np.arange(z.size, dtype=np.int64)
    if z.size < 3:
        raise PolygonError(f"a polygon needs at least 3 points, got {z.size}{_list_points(z, src)}")
    if not np.all(np.isfinite(z)):
        bad = np.flatnonzero(~np.isfinite(z))
        k = int(bad[0])
        more = f" ({bad.size} points in all)" if bad.size > 1 else ""
        raise PolygonError(
            f"point {k} is not finite: {_fmt_xy(z[k])}{more}; every coordinate must be a number"
        )
    scale = float(np.max(np.abs(z - z[0])))
    if scale == 0.0:
        raise PolygonError(f"all {z.size} points coincide at {_fmt_xy(z[0])}")
    if np.max(np.abs(z)) > 1e150 or scale < 1e-150:
        k = int(np.argmax(np.abs(z)))
        raise PolygonError(
            "coordinates out of the representable range "
            "(magnitude above 1e150 or extent below 1e-150): "
            + (
                f"point {k} is at {_fmt_xy(z[k])}"
                if np.max(np.abs(z)) > 1e150
                else f"all points lie within {scale:.3g} of point 0 at {_fmt_xy(z[0])}"
            )
            + "; rescale the polygon"
        )
    # closing point, consecutive duplicates
    if z.size > 1 and z[-1] == z[0]:
        z, src = z[:-1], src[:-1]
    keep = z != np.roll(z, 1)
    z, src = z[keep], src[keep]
    if z.size < 3:
        raise PolygonError(
            f"a polygon needs at least 3 distinct points, got {z.size} after merging repeated "
            f"points{_list_points(z, src)}"
        )
    # relative resolution: points closer than 1e-12 of the extent are treated as repeated
    tol = 1e-12 * scale
    order = np.lexsort((z.imag, z.real))
    zs = z[order]
    close = np.abs(np.diff(zs)) <= tol
    if np.any(close):
        i = int(np.flatnonzero(close)[0])
        a, b = sorted((int(order[i]), int(order[i + 1])))
        same = "" if z[a] == z[b] else f" and {_fmt_xy(z[b])} (closer than 1e-12 of the extent)"
        raise PolygonError(
            f"points {int(src[a])} and {int(src[b])} coincide at {_fmt_xy(z[a])}{same}: the "
            "boundary would touch itself there; remove one of them or move it apart"
        )
    area = signed_area(z)
    if abs(area) <= 1e-14 * scale * scale:
        w = (z - z[0]) / scale
        if np.max(np.abs((w * np.conj(w[np.argmax(np.abs(w))])).imag)) <= 1e-12:
            d = w[np.argmax(np.abs(w))]
            t = (w * np.conj(d)).real
            a, b = int(np.argmin(t)), int(np.argmax(t))
            raise PolygonError(
                f"the polygon has zero area: all {z.size} points are collinear, on the line from "
                f"point {int(src[a])} at {_fmt_xy(z[a])} to point {int(src[b])} at "
                f"{_fmt_xy(z[b])}"
            )
        _check_simple(z, src, False)
        raise PolygonError(
            f"the polygon has zero area (signed area {area:.3g} for an extent of {scale:.3g}): "
            "its boundary runs back over itself"
        )
    reversed_input = False
    if area < 0:
        z, src = z[::-1].copy(), src[::-1].copy()
        reversed_input = True
    _check_simple(z, src, reversed_input)
    ang = interior_angles(z)
    if np.any((ang < 1e-12) | (ang > 2 * np.pi - 1e-12)):
        k = int(np.flatnonzero((ang < 1e-12) | (ang > 2 * np.pi - 1e-12))[0])
        tmp = Polygon(z, reversed_input, src)
        raise PolygonError(
            f"the boundary turns back on itself at {tmp.describe_vertex(k)} (a spike of angle "
            f"0 or 360°: its edges to {tmp.describe_vertex(k - 1)} and "
            f"{tmp.describe_vertex(k + 1)} overlap); remove that point"
        )
    if drop_collinear:
        straight = np.abs(ang - np.pi) < 1e-9
        if np.any(straight):
            z, src = z[~straight], src[~straight]
    return Polygon(z, reversed_input=reversed_input, source_index=src)


def _list_points(z: np.ndarray, src: np.ndarray) -> str:
    """``": point 0 at (0, 0), point 1 at (1, 0)"`` for a handful of points, else ``""``."""
    if z.size == 0 or z.size > 4:
        return ""
    return ": " + ", ".join(f"point {int(k)} at {_fmt_xy(w)}" for k, w in zip(src, z, strict=True))


def _check_simple(z: np.ndarray, src: np.ndarray, reversed_input: bool) -> None:
    """Raise PolygonError if the closed polyline ``z`` self-intersects (shapely, O(n log n)).

    The message names two offending edges in the user's numbering (``src``, the input
    position of each vertex) and a point where they meet.
    """
    import shapely

    xy = np.column_stack([z.real, z.imag])
    ring = shapely.linearrings(xy)
    if shapely.is_simple(ring):
        return
    # locate a crossing for the message
    from shapely import STRtree

    n = z.size
    segs = shapely.linestrings(np.stack([xy, np.roll(xy, -1, axis=0)], axis=1))
    tree = STRtree(segs)
    left, right = tree.query(segs, predicate="intersects")
    sel = left < right
    left, right = left[sel], right[sel]
    adjacent = ((right - left) % n == 1) | ((left - right) % n == 1)
    where = shapely.intersection(segs[left], segs[right])
    # adjacent edges always share their common vertex; they only clash when they overlap
    bad = ~adjacent | (shapely.get_type_id(where) != 0)
    tmp = Polygon(z, reversed_input, src)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        i, j = int(left[k]), int(right[k])
        if reversed_input:
            i, j = j, i  # list the edges in the user's order
        hit = shapely.get_coordinates(where[k])
        at = _fmt_xy(complex(hit[0, 0], hit[0, 1])) if hit.size else "?"
        verb = "overlaps" if shapely.get_type_id(where[k]) == 1 else "intersects"
        raise PolygonError(
            f"the polygon is not simple: {tmp.describe_edge(i)} {verb} {tmp.describe_edge(j)} "
            f"at {at}; move the points so that the outline does not cross itself"
        )
    raise PolygonError("the polygon is not simple (its boundary touches itself)")
