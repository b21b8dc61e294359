"""The Carleson-quadrilateral mesh (paper §5, Lemma 5.1).

A Carleson quadrilateral has a geodesic top edge of length L (a pentagon side), two geodesic
sides perpendicular to the top running down to T, and an arc of T as base.  In the upper
half-plane frame H its top is the segment ``[i, i·e^L]`` of the geodesic ``iℝ₊`` and the quad is
``{e^t·e^{iθ} : 0 ≤ t ≤ L, 0 ≤ θ ≤ π/2}`` (the side ``Re ζ > 0``).  The two orthogonal foliations
are the vertical geodesics ``|ζ| = e^t`` (perpendicular to the top) and the hypercycles
``arg ζ = π/2 − ψ`` at distance ``d`` from the top, ``ψ = arctan(sinh d)``.

Mesh vertices ``ζ_{k,m} = e^{t_k}·e^{i(π/2−ψ_m)}``, ``t_k = k·L/N_side``, for the global depth
sequence ``0 = d_0 < … < d_M`` plus a final row of ideal points ``e^{t_k}`` on ℝ.  The curvilinear
angles are exactly 90°; the side vertex at depth ``d_m`` is at hyperbolic distance ``d_m`` from
the top corner, so neighbouring quads and Carleson triangles match iff they use the same depth
sequence.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DiskConstructionError
from ..hyperbolic import distance, distance_h, tangent_direction
from .canonical import CanonicalMesh, orient_quads
from .pentagon import SIDE_LENGTH_L

__all__ = ["carleson_quad_mesh", "carleson_quad_to_disk"]


def carleson_quad_mesh(
    n_side: int, depths: ArrayLike, length: float = SIDE_LENGTH_L
) -> CanonicalMesh:
    """Mesh of the model Carleson quadrilateral in H (Lemma 5.1).

    Args:
        n_side: number of steps on the top edge (``N_side = 2n`` to match pentagon meshes with
            ``n`` steps per half side).
        depths: the depth sequence ``0 = d_0 < d_1 < … < d_M`` (must start with exactly 0).
        length: hyperbolic length of the top edge (default: the pentagon side L).

    Returns:
        A :class:`CanonicalMesh` in the H frame with ``(N_side+1)·(M+2)`` vertices and
        ``N_side·(M+1)`` counter-clockwise quads; vertex ``(k, m)`` has index
        ``m·(N_side+1) + k`` (``m = M+1`` is the base row on ℝ).  Sides: ``"top"`` (``i`` to
        ``i·e^L``), ``"left"`` (on ``|ζ| = 1`` from ``i`` down to 1, the m-th at distance ``d_m``
        from ``i``), ``"right"`` (on ``|ζ| = e^L`` from ``i·e^L`` down to ``e^L``), ``"base"``
        (on ℝ from 1 to ``e^L``).

    Raises:
        DiskConstructionError: for ``n_side < 1``, a depth sequence not starting at 0, not
            strictly increasing or not finite, or a non-positive length.
    """
    if int(n_side) != n_side or n_side < 1:
        raise DiskConstructionError(
            f"carleson_quad_mesh needs an integer n_side >= 1, got {n_side!r}"
        )
    n_side = int(n_side)
    d = np.asarray(depths, dtype=float).ravel()
    if d.size < 1 or d[0] != 0.0:
        raise DiskConstructionError("depth sequence must start with d_0 = 0")
    if not np.all(np.isfinite(d)) or np.any(np.diff(d) <= 0):
        raise DiskConstructionError("depth sequence must be finite and strictly increasing")
    if not (np.isfinite(length) and length > 0):
        raise DiskConstructionError(f"top length must be positive, got {length!r}")
    M = d.size - 1
    t = np.arange(n_side + 1) * (length / n_side)
    psi = np.arctan(np.sinh(d))
    r = np.exp(t)
    rows = r[None, :] * np.exp(1j * (0.5 * np.pi - psi))[:, None]  # (M+1, N+1)
    verts = np.concatenate([rows, r[None, :].astype(np.complex128)], axis=0).ravel()

    ncol = n_side + 1
    k, m = np.meshgrid(np.arange(n_side), np.arange(M + 1), indexing="xy")
    k, m = k.ravel(), m.ravel()
    v00 = m * ncol + k
    quads = np.stack([v00, v00 + ncol, v00 + ncol + 1, v00 + 1], axis=1)
    nrow = M + 2
    sides = {
        "top": np.arange(ncol),
        "left": np.arange(nrow) * ncol,
        "right": np.arange(nrow) * ncol + n_side,
        "base": (nrow - 1) * ncol + np.arange(ncol),
    }
    return CanonicalMesh(vertices=verts, quads=quads, sides=sides)


def carleson_quad_to_disk(
    mesh: CanonicalMesh,
    u0: ArrayLike,
    u1: ArrayLike,
    p: ArrayLike,
    q: ArrayLike,
    side: ArrayLike,
    tol: float = 1e-7,
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Place ``k`` copies of a model Carleson-quad mesh into the disk at once (Lemma 5.1).

    Copy ``j`` has its top edge on the geodesic with ideal endpoints ``{p[j], q[j]}`` (either
    order), from ``u0[j]`` (image of ``i``) to ``u1[j]`` (image of ``i·e^L``), and lies on the
    side ``side[j]`` of the geodesic *oriented from u0 to u1*: ``+1`` = left, ``−1`` = right
    (the convention of :func:`quadmesh.hyperbolic.side_of_geodesic`; e.g. pass
    ``side_of_geodesic(u0, u1-direction endpoints, arc midpoint)``).

    The map is the Möbius map ``F: H → D`` with ``0 ↦ a``, ``∞ ↦ b``, ``i ↦ u0`` (``a, b`` the
    endpoints ordered so that ``a, u0, u1, b`` lie in this order); ``Re ζ > 0`` goes to the
    right of ``a→b``.  For ``side = +1`` the model is first reflected by ``ζ ↦ −conj(ζ)`` and the
    quad vertex order is reversed to stay counter-clockwise.  Base points are renormalised to
    ``|z| = 1``.  Sides keep their meaning: ``"left"`` is the ray at ``u0``, ``"right"`` at ``u1``.

    Returns:
        ``(vertices (k, V), quads (k, Q, 4))``.

    Raises:
        DiskConstructionError: if ``ρ(u0, u1)`` differs from the model's top length by more than
            ``tol``, or ``u0``/``u1`` are not inside D.
    """
    u0 = np.atleast_1d(np.asarray(u0, dtype=np.complex128))
    u1 = np.atleast_1d(np.asarray(u1, dtype=np.complex128))
    p = np.atleast_1d(np.asarray(p, dtype=np.complex128))
    q = np.atleast_1d(np.asarray(q, dtype=np.complex128))
    side = np.atleast_1d(np.asarray(side))
    u0, u1, p, q, side = np.broadcast_arrays(u0, u1, p, q, side)
    p = p / np.abs(p)
    q = q / np.abs(q)
    if np.any(np.abs(u0) >= 1) or np.any(np.abs(u1) >= 1):
        raise DiskConstructionError("Carleson quad top endpoints must lie inside the disk")
    top = mesh.side_points("top")
    length = float(distance_h(top[0], top[-1]))
    rho = distance(u0, u1)
    bad = np.abs(rho - length) > tol
    if np.any(bad):
        j = int(np.nonzero(bad)[0][0])
        raise DiskConstructionError(
            f"Carleson quad {j}: top length {rho[j]:.12g} differs from the model's {length:.12g}"
        )
    if np.any((side != 1) & (side != -1)):
        raise DiskConstructionError("side flags must be +1 (left) or -1 (right)")

    # order the endpoints: a behind u0, b beyond u1
    forward = tangent_direction(u0, u1)
    towards_p = tangent_direction(u0, p)
    p_is_a = (towards_p * np.conj(forward)).real < 0
    a = np.where(p_is_a, p, q)
    b = np.where(p_is_a, q, p)
    # F(ζ) = (b λ ζ + a)/(λ ζ + 1),  F(i) = u0
    lam = (u0 - a) / (1j * (b - u0))

    left = side == 1
    zeta = mesh.vertices[None, :]
    zeta = np.where(left[:, None], -np.conj(zeta), zeta)
    lz = lam[:, None] * zeta
    verts = (b[:, None] * lz + a[:, None]) / (lz + 1.0)
    base = mesh.sides["base"]
    verts[:, base] /= np.abs(verts[:, base])
    return verts, orient_quads(mesh.quads, left)
