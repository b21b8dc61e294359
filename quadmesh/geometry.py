"""Plane geometry of straight-edged quad meshes, shared by every stage of the construction.

The quantities that Theorem 1.1 of the paper (Bishop, "Optimal angle bounds for quadrilateral
meshes") is about, computed for many quads at once:

* :func:`quad_angles_deg`: the corner angles (every *new* angle must lie in [60°, 120°]);
* :func:`quad_signed_areas`: signed areas (positive for a counter-clockwise quad);
* :func:`angle_rounding_slack_deg`: how far an exact 60°/120° corner can read off after
  float64 placement;
* :func:`quad_edges`, :func:`unpaired_edges`, :func:`check_conformity`: the edge structure of
  a conforming, consistently oriented mesh (each interior edge in exactly two quads, with
  opposite orientations).

Vertices are complex128 points.  Every function takes ``vertices (V,)`` with ``quads (Q, 4)``;
the angle and area functions also take stacked copies ``vertices (k, V)`` with ``quads (Q, 4)``
or ``(k, Q, 4)`` (copy ``i`` of the quads indexes copy ``i`` of the vertices).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import MeshVerificationError

__all__ = [
    "angle_rounding_slack_deg",
    "check_conformity",
    "local_signed_areas",
    "quad_angles_deg",
    "quad_corners",
    "quad_edges",
    "quad_signed_areas",
    "unpaired_edges",
]

_NEXT = np.array([1, 2, 3, 0])
_PREV = np.array([3, 0, 1, 2])


def quad_corners(vertices: ArrayLike, quads: ArrayLike) -> NDArray[np.complex128]:
    """Corner positions ``(..., Q, 4)``: ``vertices (V,)`` or ``(k, V)`` with ``quads (Q, 4)`` or
    stacked ``(k, Q, 4)`` (copy ``i`` of the quads indexes copy ``i`` of the vertices)."""
    v = np.asarray(vertices, dtype=np.complex128)
    q = np.asarray(quads, dtype=np.int64)
    if q.ndim == 3:
        if v.ndim != 2 or v.shape[0] != q.shape[0]:
            raise ValueError("stacked quads (k, Q, 4) need stacked vertices (k, V)")
        return np.take_along_axis(v, q.reshape(q.shape[0], -1), axis=1).reshape(q.shape)
    return v[..., q]


def quad_angles_deg(vertices: ArrayLike, quads: ArrayLike) -> NDArray[np.float64]:
    """Corner angles in degrees, shape ``(..., Q, 4)``; corner k is at vertex ``quads[..., k]``.

    The angle at corner k is measured counter-clockwise from the edge to the next corner to
    the edge to the previous one, so it lies in [0°, 360°) and is the interior angle of a
    counter-clockwise quad (a reflex or clockwise corner gives an angle above 180°).
    """
    c = quad_corners(vertices, quads)
    e = c[..., _NEXT] - c  # edge k goes from corner k to corner k + 1
    # at corner k: to_prev = -e[k-1], to_next = e[k]
    ang = np.angle(-e[..., _PREV] * np.conj(e))
    ang[ang < 0] += 2 * np.pi
    return np.degrees(ang, out=ang)


def quad_signed_areas(vertices: ArrayLike, quads: ArrayLike) -> NDArray[np.float64]:
    """Signed areas of the quads, shape ``(..., Q)`` (shoelace; positive when counter-clockwise).

    Each quad is taken relative to its first corner, so a quad that is tiny compared with its
    distance from the origin keeps its area's relative precision.
    """
    c = quad_corners(vertices, quads)
    return local_signed_areas(c - c[..., :1])


def local_signed_areas(c: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Signed areas (shoelace) of quads given by their corners ``c`` (..., Q, 4), each quad
    already taken relative to its first corner (as :func:`quad_signed_areas` does)."""
    x, y = c.real, c.imag
    # the terms x_k y_{k+1} - x_{k+1} y_k added in order from 0.0, as np.sum(..., axis=-1)
    # adds them, but column by column (a reduction along a short contiguous axis is slow)
    s = np.zeros(c.shape[:-1])
    for k in range(4):
        j = (k + 1) % 4
        t = x[..., k] * y[..., j]
        t -= x[..., j] * y[..., k]
        s += t
    s *= 0.5
    return s


def angle_rounding_slack_deg(
    vertices: ArrayLike, quads: ArrayLike, coord_scale: float = 0.0
) -> NDArray[np.float64]:
    """(Q,) error (degrees) that float64 storage of the vertices can put on each quad's angles.

    A vertex stored in float64 is off by up to ε·|z|, which moves an angle of a quad whose
    shortest edge is ℓ by up to about 2ε·|z|/ℓ radians (ε = machine epsilon).  Returns
    8ε·|z|/ℓ (a 4× margin), with |z| the larger of the quad's largest vertex magnitude and
    ``coord_scale`` (pass the magnitude of the absolute position when ``vertices`` are relative
    to a local origin).  A corner constructed at exactly 60° or 120° (Mesh 1 and Mesh 2 of the
    vertex sectors, the spokes of T_i) reads outside the bound by up to that much.
    """
    c = quad_corners(vertices, quads)
    edge = np.abs(c[..., _NEXT] - c).min(axis=-1)
    size = np.maximum(np.abs(c).max(axis=-1), coord_scale)
    with np.errstate(divide="ignore"):
        return np.degrees(8.0 * np.finfo(float).eps * size / edge)


def quad_edges(quads: ArrayLike) -> NDArray[np.int64]:
    """Directed edges ``(4Q, 2)`` of the quads, quad by quad, in the order 01, 12, 23, 30."""
    q = np.asarray(quads, dtype=np.int64)
    return np.stack([q, q[:, _NEXT]], axis=-1).reshape(-1, 2)


def unpaired_edges(quads: ArrayLike) -> tuple[NDArray[np.int64], bool]:
    """Directed edges of ``quads`` that have no oppositely oriented partner.

    Returns the (E, 2) array of unpaired directed edges and a flag that is False when some
    directed edge occurs twice (two quads with the same orientation on one edge, or a repeated
    quad), i.e. when the mesh is not a consistently oriented surface.
    """
    e = quad_edges(quads)
    n = int(e.max()) + 1 if len(e) else 1
    code = e[:, 0] * n + e[:, 1]
    rev = e[:, 1] * n + e[:, 0]
    _uniq, counts = np.unique(code, return_counts=True)
    ok = bool(np.all(counts == 1))
    paired = np.isin(code, rev)
    return e[~paired], ok


def check_conformity(quads: ArrayLike, n_vertices: int | None = None) -> NDArray[np.int64]:
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
    e = quad_edges(q)
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
