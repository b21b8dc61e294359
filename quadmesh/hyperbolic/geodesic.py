"""Distances, geodesics, reflections and the Klein model in the hyperbolic disk (paper §2).

Disk model D with metric ``ds = 2|dz|/(1−|z|²)`` (curvature −1); upper half-plane H with
``ds = |dz|/y``.  A geodesic is stored by its **ideal endpoints** ``(p, q)`` (``|p| = |q| = 1``),
oriented from ``p`` to ``q``.  Every function broadcasts over numpy arrays of complex points.

Orientation convention used throughout this package: **left of the oriented geodesic p→q is
positive** (:func:`side_of_geodesic` returns +1 there, and hypercycles at distance ``d > 0`` lie
there).  The robust forms (Klein intersection, endpoint-based
reflection) avoid the huge centres of near-diameters.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .isometry import ComplexArray, Isometry, phi, phi_inv

FloatArray = NDArray[np.float64]

__all__ = [
    "distance",
    "distance_h",
    "einstein_midpoint",
    "from_klein",
    "geodesic_circle",
    "geodesic_distance",
    "geodesic_endpoints_through",
    "geodesic_top_point",
    "intersect_geodesics",
    "perpendicular_geodesic",
    "point_towards",
    "reflect",
    "reflection",
    "side_of_geodesic",
    "tangent_direction",
    "to_klein",
]


def _c(z: ArrayLike) -> ComplexArray:
    return np.asarray(z, dtype=np.complex128)


def _unit(z: ArrayLike) -> ComplexArray:
    z = _c(z)
    return z / np.abs(z)


# --------------------------------------------------------------------- Klein model
def to_klein(z: ArrayLike) -> ComplexArray:
    """Poincaré disk → Klein disk: ``k = 2z/(1+|z|²)`` (geodesics become straight chords)."""
    z = _c(z)
    return 2.0 * z / (1.0 + np.abs(z) ** 2)


def from_klein(k: ArrayLike) -> ComplexArray:
    """Klein disk → Poincaré disk: ``z = k/(1+√(1−|k|²))``."""
    k = _c(k)
    return k / (1.0 + np.sqrt(np.maximum(1.0 - np.abs(k) ** 2, 0.0)))


# --------------------------------------------------------------------- distances
def distance(z: ArrayLike, w: ArrayLike) -> FloatArray:
    """Hyperbolic distance in D: ``ρ = 2 arcsinh(|z−w| / √((1−|z|²)(1−|w|²)))``.

    Equal to ``2 artanh(|z−w|/|1−w̄z|)`` but better conditioned near the boundary.
    """
    z = _c(z)
    w = _c(w)
    az = np.abs(z)
    aw = np.abs(w)
    den = np.sqrt((1.0 - az) * (1.0 + az) * (1.0 - aw) * (1.0 + aw))
    return 2.0 * np.arcsinh(np.abs(z - w) / den)


def distance_h(z: ArrayLike, w: ArrayLike) -> FloatArray:
    """Hyperbolic distance in H: ``ρ = 2 arcsinh(|z−w| / (2√(Im z · Im w)))``."""
    z = _c(z)
    w = _c(w)
    return 2.0 * np.arcsinh(np.abs(z - w) / (2.0 * np.sqrt(z.imag * w.imag)))


def geodesic_distance(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike) -> FloatArray:
    """Distance between the disjoint geodesics with endpoints ``(a, b)`` and ``(c, d)``.

    Works in D (endpoints on T) or H (finite endpoints on ℝ): with the cross ratio
    ``x = |(c−a)(d−b)/((c−b)(d−a))|`` (replaced by ``1/x`` if ``x > 1``) it is ``2 artanh √x``.
    Concentric semicircles of radii 1 and R in H are at distance ``log R``.
    """
    a, b, c, d = _c(a), _c(b), _c(c), _c(d)
    x = np.abs((c - a) * (d - b) / ((c - b) * (d - a)))
    x = np.where(x > 1.0, 1.0 / x, x)
    return 2.0 * np.arctanh(np.sqrt(x))


# --------------------------------------------------------------------- geodesics
def geodesic_circle(p: ArrayLike, q: ArrayLike) -> tuple[ComplexArray, FloatArray]:
    """Euclidean circle carrying the geodesic with ideal endpoints ``p, q``.

    Centre ``c = 2(p+q)/|p+q|² = 2/conj(p+q)``, radius ``√(|c|²−1)``.  For a diameter
    (``p = −q``) both are ``inf``.  Prefer the endpoint-based functions of this module for
    computations; near-diameters have huge, ill-conditioned centres.
    """
    p, q = _unit(p), _unit(q)
    s = p + q
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 2.0 / np.conj(s)
        r = np.abs(p - q) / np.abs(s)  # = √(|c|²−1) by the parallelogram law
    diam = s == 0
    c = np.where(diam, np.complex128(np.inf), c)
    r = np.where(diam, np.inf, r)
    return c, r


def geodesic_top_point(p: ArrayLike, q: ArrayLike) -> ComplexArray:
    """Point of the geodesic ``(p, q)`` nearest to 0 (the image of the chord midpoint in Klein)."""
    p, q = _unit(p), _unit(q)
    return from_klein(0.5 * (p + q))


def geodesic_endpoints_through(z1: ArrayLike, z2: ArrayLike) -> tuple[ComplexArray, ComplexArray]:
    """Ideal endpoints ``(p, q)`` of the geodesic through interior points ``z1 ≠ z2``.

    Oriented so that ``p, z1, z2, q`` occur in this order: with ``u = φ_{z1}(z2)/|φ_{z1}(z2)|``,
    ``p = φ_{z1}⁻¹(−u)`` and ``q = φ_{z1}⁻¹(u)``.
    """
    z1 = _c(z1)
    u = _unit(phi(z1, z2))
    return _unit(phi_inv(z1, -u)), _unit(phi_inv(z1, u))


def point_towards(z1: ArrayLike, z2: ArrayLike, d: ArrayLike) -> ComplexArray:
    """Point at hyperbolic distance ``d`` from ``z1`` along the geodesic towards ``z2``.

    ``φ_{z1}⁻¹(tanh(d/2)·u)`` with ``u`` the unit direction of ``φ_{z1}(z2)``.  ``z2`` may be an
    ideal point (``|z2| = 1``); negative ``d`` goes the other way.
    """
    z1 = _c(z1)
    u = _unit(phi(z1, z2))
    return phi_inv(z1, np.tanh(0.5 * np.asarray(d, dtype=float)) * u)


def tangent_direction(z: ArrayLike, w: ArrayLike) -> ComplexArray:
    """Unit tangent (complex number of modulus 1) at ``z`` of the geodesic from ``z`` to ``w``.

    Equal to ``φ_z(w)/|φ_z(w)|`` because ``(φ_z⁻¹)'(0) = 1−|z|² > 0``.
    """
    return _unit(phi(z, w))


def perpendicular_geodesic(
    p: ArrayLike, q: ArrayLike, x: ArrayLike
) -> tuple[ComplexArray, ComplexArray]:
    """Endpoints of the geodesic perpendicular to ``(p, q)`` at its point ``x``.

    ``φ_x`` maps the geodesic to a diameter of direction ``u``; the perpendicular is the
    diameter ``±iu`` mapped back.  Oriented from the right side of ``p→q`` to its left side.
    """
    x = _c(x)
    P = phi(x, p)
    Q = phi(x, q)
    u = _unit(Q - P)
    return _unit(phi_inv(x, -1j * u)), _unit(phi_inv(x, 1j * u))


def intersect_geodesics(p1: ArrayLike, q1: ArrayLike, p2: ArrayLike, q2: ArrayLike) -> ComplexArray:
    """Intersection point of the geodesics ``(p1, q1)`` and ``(p2, q2)`` (Klein model).

    The chords are intersected as straight lines and the Klein point mapped back with
    :func:`from_klein`.  Returns ``nan`` where the geodesics do not cross inside D.
    """
    p1, q1, p2, q2 = _unit(p1), _unit(q1), _unit(p2), _unit(q2)
    d1 = q1 - p1
    d2 = q2 - p2
    cross = (np.conj(d1) * d2).imag
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.conj(p2 - p1) * d2).imag / cross
    k = p1 + t * d1
    ok = (np.abs(k) < 1.0) & np.isfinite(k)
    return np.where(ok, from_klein(np.where(ok, k, 0.0)), np.complex128(np.nan + 1j * np.nan))


def side_of_geodesic(p: ArrayLike, q: ArrayLike, z: ArrayLike) -> FloatArray:
    """+1 if ``z`` lies left of the geodesic oriented ``p→q``, −1 if right, 0 on it.

    Evaluated in the Klein model, where the geodesic is the straight chord [p, q]; robust for
    diameters and near-diameters.
    """
    p, q = _unit(p), _unit(q)
    k = to_klein(z)
    return np.sign((np.conj(q - p) * (k - p)).imag)


def reflection(p: ArrayLike, q: ArrayLike) -> Isometry:
    """Reflection in the geodesic ``(p, q)`` as an orientation-reversing :class:`Isometry`.

    Inversion in the geodesic's circle, ``z ↦ c + r²/conj(z−c)``, rewritten in the endpoints:
    ``M = [[−pq, (p+q)/2], [−(p+q)/2, 1]]`` with ``σ = 1``; for a diameter it is ``z ↦ p² z̄``.
    Arrays of endpoints give a stacked Isometry.
    """
    p, q = _unit(p), _unit(q)
    m = 0.5 * (p + q)
    M = np.empty((*p.shape, 2, 2), dtype=np.complex128)
    M[..., 0, 0] = -p * q
    M[..., 0, 1] = m
    M[..., 1, 0] = -m
    M[..., 1, 1] = 1.0
    # det = −pq + m² = (p−q)²/4 ≠ 0 for distinct endpoints
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    M = M / np.sqrt(det)[..., None, None]
    return Isometry(M, np.ones(p.shape, dtype=bool))


def reflect(p: ArrayLike, q: ArrayLike, z: ArrayLike) -> ComplexArray:
    """Reflect points ``z`` in the geodesic ``(p, q)`` (``p, q, z`` broadcast together)."""
    p, q = _unit(p), _unit(q)
    z = _c(z)
    m = 0.5 * (p + q)
    zc = np.conj(z)
    return (m - p * q * zc) / (1.0 - m * zc)


def einstein_midpoint(z: ArrayLike, axis: int = -1) -> ComplexArray:
    """Hyperbolic centre of points ``z`` (Einstein midpoint).

    Map to Klein, average with Lorentz weights ``γ = 1/√(1−|k|²)``, map back.  Exact centre for
    the vertices of a regular polygon.
    """
    k = to_klein(z)
    g = 1.0 / np.sqrt(1.0 - np.abs(k) ** 2)
    return from_klein(np.sum(g * k, axis=axis) / np.sum(g, axis=axis))
