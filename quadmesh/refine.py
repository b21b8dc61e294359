"""Uniform refinement of a quad mesh: every quad becomes a k × k grid of bilinear sub-quads.

The grid point (s, t) ∈ {0, 1/k, …, 1}² of a quad with corners c0, c1, c2, c3 (counter-
clockwise) is the bilinear point (1−s)(1−t)c0 + s(1−t)c1 + st·c2 + (1−s)t·c3. The k − 1 points
inside an edge are made once per undirected edge, from its lower-numbered end, and indexed
by the edge, so two quads sharing an edge share its points by index (no merging by distance)
and the refined mesh is conforming exactly when the input is.

Angles: the grid lines of a planar convex quad are segments whose directions move
monotonically between those of opposite sides, so every sub-quad angle lies between the
quad's corner angles and their supplements: a quad with all four angles in [60°, 120°] gives
sub-quads with all angles in [60°, 120°]. A quad holding an original polygon corner of angle
θ < 60° does not: its sub-quads are near-copies of the corner region, with new angles near θ
and 180° − θ at interior grid points (measured on a kite with angles 30°, 110°, 110°, 110°:
new angles in [39.3°, 140.7°] at k = 2, [33.6°, 146.4°] at k = 4). :func:`refine_quads`
refuses such meshes.
"""

from __future__ import annotations

import numpy as np

from .errors import MeshVerificationError

__all__ = ["refine_quads", "small_corner_quads"]

_NEXT = np.array([1, 2, 3, 0])
_PREV = np.array([3, 0, 1, 2])


def small_corner_quads(z: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quads holding an unsplit corner below 60° (a vertex in this quad only, angle < 60°).

    Returns ``(quad indices, corner positions 0..3)``. In a verified mesh these are exactly
    the quads that keep an original polygon angle below 60°."""
    z = np.asarray(z, dtype=np.complex128)
    q = np.asarray(quads, dtype=np.int64)
    c = z[q]
    c = c - c[:, :1]
    e = c[:, _NEXT] - c
    ang = np.degrees(np.angle(-e[:, _PREV] * np.conj(e)))
    ang[ang < 0] += 360.0
    valence = np.bincount(q.ravel(), minlength=z.size)
    return np.nonzero((valence[q] == 1) & (ang < 60.0))


def refine_quads(
    z: np.ndarray, quads: np.ndarray, k: int, *, origin: complex = 0j
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split every quad into a k × k grid of bilinear sub-quads.

    Args:
        z: (V,) complex vertices.
        quads: (Q, 4) counter-clockwise vertex indices.
        k: grid size (1 returns the input).
        origin: added to coordinates in messages (vertices relative to a working origin).

    Returns:
        ``(z_new, quads_new, parent)``: (V + E(k−1) + Q(k−1)², ) vertices (the input's first,
        then the edge points edge by edge, then the interior points quad by quad), the
        (k²Q, 4) sub-quads (quad i's k² sub-quads are rows k²i … k²i + k² − 1, counter-
        clockwise) and the (k²Q,) index of each sub-quad's parent quad.

    Raises:
        MeshVerificationError: a quad holds an unsplit corner below 60° (see the module
            docstring); the message names the corner.
    """
    z = np.asarray(z, dtype=np.complex128).ravel()
    q = np.asarray(quads, dtype=np.int64)
    k = int(k)
    nq = q.shape[0]
    if k < 1:
        raise ValueError(f"refine must be at least 1, got {k}")
    if k == 1:
        return z.copy(), q.copy(), np.arange(nq, dtype=np.int64)
    bad_q, bad_k = small_corner_quads(z, q)
    if bad_q.size:
        v = int(q[bad_q[0], bad_k[0]])
        p = complex(z[v]) + origin
        raise MeshVerificationError(
            f"refine={k} is not possible for this polygon: {bad_q.size} of its corners have "
            f"angles below 60°, which stay in one quad each (e.g. the corner at "
            f"({p.real:.15g}, {p.imag:.15g})), and splitting that quad into a grid would make "
            "new angles of about the same size; use refine=1"
        )
    nv = z.size
    # undirected edges, numbered; each quad side refers to one with a direction flag
    a = q.ravel()
    b = q[:, _NEXT].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keys, inv = np.unique(lo * nv + hi, return_inverse=True)
    inv = inv.reshape(nq, 4)
    elo, ehi = keys // nv, keys % nv
    f = np.arange(1, k) / k  # fractions along an edge from its lower end
    edge_pts = z[elo][:, None] + f[None, :] * (z[ehi] - z[elo])[:, None]
    ne = keys.size
    edge_base = nv
    inner_base = nv + ne * (k - 1)

    # index grid G[quad, i, j] for s = i/k, t = j/k
    g = np.empty((nq, k + 1, k + 1), dtype=np.int64)
    g[:, 0, 0] = q[:, 0]
    g[:, k, 0] = q[:, 1]
    g[:, k, k] = q[:, 2]
    g[:, 0, k] = q[:, 3]
    m = np.arange(1, k)  # interior positions along a side

    def side_ids(side: int) -> np.ndarray:
        """(Q, k−1) ids of the points inside side ``side``, from its corner ``side`` on."""
        e = inv[:, side]
        fwd = q[:, side] == elo[e]
        ids = edge_base + e[:, None] * (k - 1) + (m - 1)[None, :]
        return np.where(fwd[:, None], ids, ids[:, ::-1])

    g[:, 1:k, 0] = side_ids(0)  # c0 -> c1: s = m/k, t = 0
    g[:, k, 1:k] = side_ids(1)  # c1 -> c2: s = 1, t = m/k
    g[:, 1:k, k] = side_ids(2)[:, ::-1]  # c2 -> c3 runs s = 1 -> 0
    g[:, 0, 1:k] = side_ids(3)[:, ::-1]  # c3 -> c0 runs t = 1 -> 0
    n_in = (k - 1) ** 2
    g[:, 1:k, 1:k] = (inner_base + np.arange(nq * n_in)).reshape(nq, k - 1, k - 1)

    c = z[q]
    s = m / k
    ss, tt = np.meshgrid(s, s, indexing="ij")  # (k−1, k−1), [i, j] -> (s_i, t_j)
    w1 = (ss * (1 - tt)).ravel()
    w2 = (ss * tt).ravel()
    w3 = ((1 - ss) * tt).ravel()
    # each quad relative to its first corner, so the weights act on small numbers
    c0 = c[:, :1]
    d = c - c0
    inner = c0 + d[:, 1:2] * w1 + d[:, 2:3] * w2 + d[:, 3:4] * w3
    z_new = np.concatenate([z, edge_pts.ravel(), inner.ravel()])

    i0, j0 = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    i0, j0 = i0.ravel(), j0.ravel()
    sub = np.stack(
        [g[:, i0, j0], g[:, i0 + 1, j0], g[:, i0 + 1, j0 + 1], g[:, i0, j0 + 1]], axis=-1
    ).reshape(-1, 4)
    parent = np.repeat(np.arange(nq, dtype=np.int64), k * k)
    return z_new, sub, parent
