"""Euclidean generalised circles (circles and lines) in the complex plane, vectorised.

A generalised circle is stored in *inversive coordinates* ``(A, B, C)``: it is the set

    A|z|² + 2 Re(conj(B) z) + C = 0,        A, C real, B complex,

normalised so that ``|B|² − A C = 1``.  For a circle with centre ``a`` and radius ``r`` this gives
``A = 1/r``, ``B = −a/r``, ``C = (|a|² − r²)/r``; for a line ``A = 0``, ``B`` is a unit normal and
``C/2`` the (signed) offset.  All functions accept numpy arrays (broadcasting) as well as scalars.

These are the Euclidean primitives ("generalised circles") used by the
Carleson-triangle mesh of Bishop's §6 (Lemma 6.1): circle through three points with an exact-line
fallback, the circle through a point with a prescribed tangent orthogonal to another circle,
inversion, circle∩circle via the radical line, line∩line, the inversive distance and the
cross-ratio.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = [
    "GCircle",
    "center_radius",
    "circle_from_center",
    "circle_through",
    "cross_ratio",
    "evaluate",
    "intersect",
    "intersect_lines",
    "inversive_distance",
    "invert",
    "line_through",
    "normalize",
    "orthogonal_circle_with_tangent",
]

# Relative curvature (curvature × size of the defining points) below which a circle is a line.
LINE_TOL = 1e-11


class GCircle(NamedTuple):
    """Generalised circle ``A|z|² + 2Re(conj(B) z) + C = 0`` (arrays broadcast together)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray

    @property
    def is_line(self) -> np.ndarray:
        """True where the generalised circle is a straight line (A == 0)."""
        return np.asarray(self.A) == 0.0

    def take(self, key) -> GCircle:
        """Sub-array selection ``(A[key], B[key], C[key])``."""
        return GCircle(np.asarray(self.A)[key], np.asarray(self.B)[key], np.asarray(self.C)[key])


def _c(z) -> np.ndarray:
    return np.asarray(z, dtype=np.complex128)


def _f(x) -> np.ndarray:
    return np.asarray(x, dtype=np.float64)


def normalize(A, B, C) -> GCircle:
    """Scale ``(A, B, C)`` so that ``|B|² − AC = 1`` (and ``A ≥ 0`` for circles).

    Entries with ``|B|² − AC ≤ 0`` (points or imaginary circles) become NaN.
    """
    A, B, C = np.broadcast_arrays(_f(A), _c(B), _f(C))
    disc = np.abs(B) ** 2 - A * C
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(disc > 0, 1.0 / np.sqrt(np.where(disc > 0, disc, 1.0)), np.nan)
        s = np.where(A < 0, -s, s)
    return GCircle(A * s, B * s, C * s)


def circle_from_center(center, radius) -> GCircle:
    """Circle with the given centre(s) and radius (radii)."""
    a = _c(center)
    r = _f(radius)
    return GCircle(*np.broadcast_arrays(1.0 / r, -a / r, (np.abs(a) ** 2 - r**2) / r))


def line_through(z1, z2) -> GCircle:
    """Straight line through ``z1`` and ``z2`` (distinct)."""
    z1, z2 = np.broadcast_arrays(_c(z1), _c(z2))
    d = z2 - z1
    n = 1j * d / np.abs(d)
    return GCircle(np.zeros(z1.shape), n, -2.0 * np.real(np.conj(n) * z1))


def circle_through(z1, z2, z3, line_tol: float = LINE_TOL) -> GCircle:
    """Generalised circle through three points, vectorised.

    Computed division-free in coordinates centred at ``z1`` (Cramer's rule), then normalised.  If
    the relative curvature ``|A|·size`` is below ``line_tol`` the points are treated as collinear
    and an **exact line** is returned.
    """
    z1, z2, z3 = np.broadcast_arrays(_c(z1), _c(z2), _c(z3))
    a = z2 - z1
    b = z3 - z1
    aa = np.abs(a) ** 2
    bb = np.abs(b) ** 2
    A = np.imag(np.conj(a) * b)  # = ax·by − ay·bx
    Bx = -(aa * b.imag - bb * a.imag) / 2.0
    By = -(a.real * bb - b.real * aa) / 2.0
    B = Bx + 1j * By
    nb = np.abs(B)
    with np.errstate(invalid="ignore", divide="ignore"):
        A = A / nb
        B = B / nb
    size = np.maximum(np.maximum(np.sqrt(aa), np.sqrt(bb)), np.abs(a - b))
    A = np.where(np.abs(A) * size < line_tol, 0.0, A)
    # Exact line through the two farthest points where collinear.
    far = np.where(
        (np.sqrt(aa) >= np.sqrt(bb)) & (np.sqrt(aa) >= np.abs(a - b)),
        0,
        np.where(np.sqrt(bb) >= np.abs(a - b), 1, 2),
    )
    p = np.where(far == 2, z2, z1)
    q = np.where(far == 0, z2, z3)
    with np.errstate(invalid="ignore", divide="ignore"):
        n_line = 1j * (q - p) / np.abs(q - p)
    B = np.where(A == 0.0, n_line, B)
    # Translate back from coordinates centred at z1:  B' = B − A z1,  C' = A|z1|² − 2Re(conj(B) z1).
    C = np.where(
        A == 0.0,
        -2.0 * np.real(np.conj(B) * p),
        A * np.abs(z1) ** 2 - 2.0 * np.real(np.conj(B) * z1),
    )
    B = np.where(A == 0.0, B, B - A * z1)
    s = np.where(A < 0, -1.0, 1.0)
    return GCircle(A * s, B * s, C * s)


def center_radius(c: GCircle) -> tuple[np.ndarray, np.ndarray]:
    """Centre and radius of a circle (NaN / inf for lines)."""
    A = _f(c.A)
    with np.errstate(invalid="ignore", divide="ignore"):
        return -_c(c.B) / A, 1.0 / np.abs(A)


def evaluate(c: GCircle, z) -> np.ndarray:
    """``A|z|² + 2Re(conj(B) z) + C``: zero on the circle; its sign tells the side."""
    z = _c(z)
    return _f(c.A) * np.abs(z) ** 2 + 2.0 * np.real(np.conj(c.B) * z) + _f(c.C)


def invert(z, c: GCircle) -> np.ndarray:
    """Inversion of ``z`` in the generalised circle ``c`` (reflection for a line)."""
    z = _c(z)
    A, B, C = _f(c.A), _c(c.B), _f(c.C)
    line = A == 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        a = -B / np.where(line, 1.0, A)
        r2 = 1.0 / np.where(line, 1.0, A) ** 2
        circ = a + r2 / np.conj(z - a)
    refl = z - 2.0 * (np.real(np.conj(B) * z) + C / 2.0) * B
    return np.where(line, refl, circ)


def inversive_distance(c1: GCircle, c2: GCircle) -> np.ndarray:
    """Inversive distance ``(A1C2 + A2C1)/2 − Re(B1 conj B2)`` of two normalised circles.

    ``|δ| < 1``: they cross (δ = cos of the crossing angle, 0 = orthogonal); ``|δ| = 1``: tangent
    (parallel lines count as tangent at ∞); ``|δ| > 1``: disjoint.
    """
    return (_f(c1.A) * _f(c2.C) + _f(c2.A) * _f(c1.C)) / 2.0 - np.real(_c(c1.B) * np.conj(c2.B))


def orthogonal_circle_with_tangent(p, tau, target: GCircle, tol: float = 1e-14) -> GCircle:
    """Generalised circle through ``p`` with unit tangent ``tau`` there, orthogonal to ``target``.

    It passes through ``p* = invert(p, target)``; its centre is ``p + iτ t`` with
    ``t = −|p−p*|² / (2 Re(conj(iτ)(p−p*)))``.  If ``p*`` lies on the tangent line the
    result is that line.
    """
    p = _c(p)
    tau = _c(tau) / np.abs(tau)
    ps = invert(p, target)
    n = 1j * tau
    d = p - ps
    den = 2.0 * np.real(np.conj(n) * d)
    line = np.abs(den) <= tol * np.abs(d)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = -(np.abs(d) ** 2) / np.where(line, 1.0, den)
    circ = circle_from_center(p + n * t, np.abs(t))
    lin = line_through(p, p + tau)
    return GCircle(
        np.where(line, lin.A, circ.A),
        np.where(line, lin.B, circ.B),
        np.where(line, lin.C, circ.C),
    )


def intersect_lines(l1: GCircle, l2: GCircle) -> np.ndarray:
    """Intersection point of two straight lines (2×2 linear system); NaN if parallel."""
    n1, n2 = _c(l1.B), _c(l2.B)
    k1, k2 = -_f(l1.C) / 2.0, -_f(l2.C) / 2.0  # Re(conj(n) z) = k
    det = n1.real * n2.imag - n1.imag * n2.real
    with np.errstate(invalid="ignore", divide="ignore"):
        x = (k1 * n2.imag - k2 * n1.imag) / det
        y = (n1.real * k2 - n2.real * k1) / det
    return np.where(det == 0.0, np.nan + 0j, x + 1j * y)


def _line_circle(line: GCircle, circ: GCircle) -> tuple[np.ndarray, np.ndarray]:
    """Both intersections of a normalised line with a generalised circle (stable quadratic)."""
    n = _c(line.B)
    z0 = -_f(line.C) / 2.0 * n
    u = 1j * n
    A, B, C = _f(circ.A), _c(circ.B), _f(circ.C)
    a = A
    b = 2.0 * np.real(np.conj(B) * u)
    cc = A * np.abs(z0) ** 2 + 2.0 * np.real(np.conj(B) * z0) + C
    disc = b * b - 4.0 * a * cc
    tiny = 1e-14 * np.maximum(b * b, 1e-300)
    disc = np.where((disc < 0) & (disc > -tiny), 0.0, disc)
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        q = -(b + np.where(b >= 0, 1.0, -1.0) * sq) / 2.0
        t1 = q / a
        t2 = np.where(q == 0, 0.0, cc / q)
    return z0 + t1 * u, z0 + t2 * u


def intersect(c1: GCircle, c2: GCircle) -> tuple[np.ndarray, np.ndarray]:
    """The two intersection points of two generalised circles, via their radical line.

    Returns ``(za, zb)``; entries are NaN (or inf) where there is no intersection, and the second
    point of two lines is NaN (their other common point is ∞).  Tangency gives ``za == zb``.
    """
    A1, B1, C1 = np.broadcast_arrays(_f(c1.A), _c(c1.B), _f(c1.C))
    A2, B2, C2 = np.broadcast_arrays(_f(c2.A), _c(c2.B), _f(c2.C))
    A1, B1, C1, A2, B2, C2 = np.broadcast_arrays(A1, B1, C1, A2, B2, C2)
    both_lines = (A1 == 0) & (A2 == 0)
    # Radical line A2·c1 − A1·c2 (equal to the line itself if one of them is a line).
    rl = normalize(np.zeros(A1.shape), A2 * B1 - A1 * B2, A2 * C1 - A1 * C2)
    # Intersect with the more curved of the two (better conditioned).
    use1 = np.abs(A1) >= np.abs(A2)
    circ = GCircle(np.where(use1, A1, A2), np.where(use1, B1, B2), np.where(use1, C1, C2))
    za, zb = _line_circle(rl, circ)
    zl = intersect_lines(GCircle(A1, B1, C1), GCircle(A2, B2, C2))
    za = np.where(both_lines, zl, za)
    zb = np.where(both_lines, np.nan + 0j, zb)
    return za, zb


def cross_ratio(z1, z2, z3, z4) -> np.ndarray:
    """Cross-ratio ``((z1−z3)(z2−z4)) / ((z1−z4)(z2−z3))``.

    For four concyclic points it is real; it is negative iff the pairs {z1,z2} and {z3,z4} separate
    each other on the circle.
    """
    z1, z2, z3, z4 = (_c(z) for z in (z1, z2, z3, z4))
    with np.errstate(invalid="ignore", divide="ignore"):
        return ((z1 - z3) * (z2 - z4)) / ((z1 - z4) * (z2 - z3))
