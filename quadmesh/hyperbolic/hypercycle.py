"""Hypercycles (equidistant curves) of a geodesic and the frame Φ: D→H (paper §5).

For the geodesic with ideal endpoints ``(a, b)`` the frame ``Φ(z) = λ(z−a)/(z−b)`` sends
``a ↦ 0``, ``b ↦ ∞`` and the geodesic's top point (nearest 0) to ``i``; the geodesic becomes the
positive imaginary axis and its hypercycles become the rays ``arg ζ = π/2 ± ψ`` with
``ψ = arctan(sinh d)`` (so ``sinh d = tan ψ``, ``cosh d = sec ψ``).

Coordinates ``(s, d)``: ``s`` is signed arclength along the geodesic from its top point towards
``b``; ``d`` is signed distance from the geodesic, **positive on the left of a→b** (the same
convention as :func:`quadmesh.hyperbolic.geodesic.side_of_geodesic`), i.e. ``Re Φ < 0``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .geodesic import _unit, geodesic_top_point
from .isometry import ComplexArray, Isometry

FloatArray = NDArray[np.float64]

__all__ = [
    "geodesic_coordinates",
    "hypercycle_circle",
    "hypercycle_frame",
    "hypercycle_point",
]


def _frame_parameters(
    a: ArrayLike, b: ArrayLike
) -> tuple[ComplexArray, ComplexArray, ComplexArray]:
    """Unit endpoints ``a, b`` and the factor ``λ = i(t−b)/(t−a)`` of the frame Φ of ``(a, b)``."""
    a, b = _unit(a), _unit(b)
    t = geodesic_top_point(a, b)
    return a, b, 1j * (t - b) / (t - a)


def hypercycle_frame(a: ArrayLike, b: ArrayLike) -> Isometry:
    """The Möbius frame Φ: D→H of the geodesic ``(a, b)``: ``a ↦ 0``, ``b ↦ ∞``, top point ↦ ``i``.

    Returned as an orientation-preserving :class:`Isometry` pair (a stack if ``a, b`` are arrays);
    ``Φ.inverse()`` maps H back to D.  Matrix ``[[λ, −λa], [1, −b]]``, ``λ = i(t−b)/(t−a)``.
    """
    a, b, lam = _frame_parameters(a, b)
    M = np.empty((*a.shape, 2, 2), dtype=np.complex128)
    M[..., 0, 0] = lam
    M[..., 0, 1] = -lam * a
    M[..., 1, 0] = 1.0
    M[..., 1, 1] = -b
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    M = M / np.sqrt(det)[..., None, None]
    return Isometry(M, np.zeros(a.shape, dtype=bool))


def _frame_inverse_apply(a: ArrayLike, b: ArrayLike, zeta: ArrayLike) -> ComplexArray:
    """Φ⁻¹(ζ) for the frame of ``(a, b)``, all arguments broadcast."""
    a, b, lam = _frame_parameters(a, b)
    zeta = np.asarray(zeta, dtype=np.complex128)
    # ζ = λ(z−a)/(z−b)  ⇔  z = (bζ − λa)/(ζ − λ)
    return (b * zeta - lam * a) / (zeta - lam)


def hypercycle_point(a: ArrayLike, b: ArrayLike, s: ArrayLike, d: ArrayLike) -> ComplexArray:
    """Point at arclength ``s`` along the geodesic ``(a, b)`` (from its top point towards ``b``)
    and signed distance ``d`` from it (``d > 0`` on the left of a→b).

    ``Φ⁻¹(eˢ·e^{i(π/2+ψ)})`` with ``ψ = arctan(sinh d)``.  All arguments broadcast.
    """
    s = np.asarray(s, dtype=float)
    psi = np.arctan(np.sinh(np.asarray(d, dtype=float)))
    zeta = np.exp(s) * np.exp(1j * (0.5 * np.pi + psi))
    return _frame_inverse_apply(a, b, zeta)


def geodesic_coordinates(a: ArrayLike, b: ArrayLike, z: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`hypercycle_point`: the ``(s, d)`` coordinates of ``z`` w.r.t. ``(a, b)``.

    ``s = log|Φ(z)|`` and ``d = arcsinh(tan(arg Φ(z) − π/2))``.
    """
    a, b, lam = _frame_parameters(a, b)
    z = np.asarray(z, dtype=np.complex128)
    zeta = lam * (z - a) / (z - b)
    s = np.log(np.abs(zeta))
    # angle from the positive imaginary axis, in (−π/2, π/2)
    theta = np.angle(zeta * (-1j))
    return s, np.arcsinh(np.tan(theta))


def hypercycle_circle(a: ArrayLike, b: ArrayLike, d: ArrayLike) -> tuple[ComplexArray, FloatArray]:
    """Euclidean circle (centre, radius) carrying the hypercycle at signed distance ``d`` from the
    geodesic ``(a, b)``: the circle through ``a``, ``b`` and the point at ``(s=0, d)``.

    The centre lies on the perpendicular bisector of the chord ``[a, b]``; where the hypercycle is
    the straight chord itself, centre and radius are ``inf``.
    """
    a, b = _unit(a), _unit(b)
    x = hypercycle_point(a, b, 0.0, d)
    # circumcentre of a, b, x: centre = m + t·n with m chord midpoint, n ⊥ chord
    m = 0.5 * (a + b)
    n = 1j * (b - a)
    # |m + t n − a|² = |m + t n − x|²  ⇒  linear in t
    num = np.abs(m - x) ** 2 - np.abs(m - a) ** 2
    den = 2.0 * ((m - a) * np.conj(n)).real - 2.0 * ((m - x) * np.conj(n)).real
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / den
        c = m + t * n
        r = np.abs(c - a)
    line = ~np.isfinite(c) | (np.abs(den) < 1e-15 * np.abs(n) ** 2)
    c = np.where(line, np.complex128(np.inf), c)
    r = np.where(line, np.inf, r)
    return c, r
