"""Möbius maps and isometries of the hyperbolic disk (paper §2§1).

An isometry (or any Möbius / anti-Möbius map) is stored as a pair ``(M, sigma)`` acting by
``z ↦ M·(conj(z) if sigma else z)``, where ``M·w = (M00 w + M01)/(M10 w + M11)``.

:class:`Isometry` holds either one pair (``M.shape == (2, 2)``) or a *stack* of pairs
(``M.shape == (k, 2, 2)``, ``sigma.shape == (k,)``), so that one canonical mesh can be moved by
thousands of isometries at once with :meth:`Isometry.apply_rows`.

Composition: ``(M1,σ1)∘(M2,σ2) = (M1·(σ1 ? conj(M2) : M2), σ1 xor σ2)``;
inverse: ``(σ ? conj(M⁻¹) : M⁻¹, σ)``.  Matrices are kept normalised to determinant 1 so that
long products (deep tessellation tiles) neither overflow nor underflow.

Precision: everything is complex128 unless a matrix is given as ``clongdouble`` (80-bit extended
precision on x86-64, eps 1.1e-19); then the maps, their compositions and their images of points
stay ``clongdouble``.  The disk construction stores deep tessellation tiles that way (their
entries grow like ``s^{-1/2}`` for tiles of Euclidean size ``s``, so float64 products lose
``log10(1/s)`` digits of the tile positions; see ``quadmesh.disk.tessellation``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

ComplexArray = NDArray[np.complex128]


_COMPLEX_DTYPES = (np.dtype(np.complex128), np.dtype(np.clongdouble))


def _cdtype(*arrays: ArrayLike) -> type:
    """``clongdouble`` if any input is extended precision, else ``complex128``."""
    for a in arrays:
        if np.asarray(a).dtype in (np.longdouble, np.clongdouble):
            return np.clongdouble
    return np.complex128


__all__ = [
    "CAYLEY_D_TO_H",
    "CAYLEY_H_TO_D",
    "Isometry",
    "apply_isometries",
    "cayley_d_to_h",
    "cayley_h_to_d",
    "disk_automorphism",
    "disk_automorphism_inverse",
    "mobius_apply",
    "mobius_from_points",
    "normalize_matrix",
    "phi",
    "phi_inv",
]


def normalize_matrix(M: ArrayLike) -> ComplexArray:
    """Scale a (stack of) 2×2 complex matrix to determinant 1 (same Möbius map)."""
    M = np.asarray(M, dtype=_cdtype(M))
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    if np.any(det == 0) or not np.all(np.isfinite(det)):
        raise ValueError("singular or non-finite Möbius matrix")
    return M / np.sqrt(det)[..., None, None]


def mobius_apply(M: ArrayLike, z: ArrayLike) -> ComplexArray:
    """Apply one Möbius matrix ``M`` (2×2) to points ``z`` (any shape): ``(a z + b)/(c z + d)``.

    ``z = inf`` is mapped to ``a/c``; a pole gives ``inf``.
    """
    dt = _cdtype(M, z)
    M = np.asarray(M, dtype=dt)
    z = np.asarray(z, dtype=dt)
    a, b, c, d = M[0, 0], M[0, 1], M[1, 0], M[1, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (a * z + b) / (c * z + d)
        inf = np.isinf(z)
        if np.any(inf):
            out = np.where(inf, a / c if c != 0 else np.inf, out)
        pole = (c * z + d) == 0
        if np.any(pole):
            out = np.where(pole & ~inf, dt(np.inf), out)
    return out


def _mobius_apply_batched(M: ComplexArray, z: ComplexArray) -> ComplexArray:
    """Apply matrices ``M`` (..., 2, 2) to points ``z`` broadcast against M's batch shape."""
    a, b, c, d = (M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return (a * z + b) / (c * z + d)


@dataclass(frozen=True, eq=False)
class Isometry:
    """Isometry / Möbius pair ``z ↦ M·(conj z if sigma else z)``, single or stacked.

    Attributes:
        M: complex array of shape ``(2, 2)`` (single) or ``(k, 2, 2)`` (stack); complex128, or
            clongdouble if given in extended precision.
        sigma: bool array of shape ``()`` or ``(k,)``; True means the map reverses orientation.
    """

    M: ComplexArray
    sigma: NDArray[np.bool_]

    def __post_init__(self) -> None:
        M = self.M
        if not (isinstance(M, np.ndarray) and M.dtype in _COMPLEX_DTYPES):
            M = np.asarray(M, dtype=_cdtype(M))
        if M.shape[-2:] != (2, 2):
            raise ValueError(f"Isometry matrix must have shape (...,2,2), got {M.shape}")
        sigma = self.sigma
        if isinstance(sigma, np.ndarray) and sigma.dtype == bool and sigma.shape == M.shape[:-2]:
            sigma = sigma.copy()  # the common case, without broadcast_to's overhead
        else:
            sigma = np.broadcast_to(np.asarray(sigma, dtype=bool), M.shape[:-2]).copy()
        object.__setattr__(self, "M", M)
        object.__setattr__(self, "sigma", sigma)

    # ----------------------------------------------------------------- constructors
    @staticmethod
    def identity(k: int | None = None, dtype: type = np.complex128) -> Isometry:
        """The identity (one pair if ``k`` is None, else a stack of ``k`` identities), with
        matrices of ``dtype`` (complex128 or clongdouble)."""
        if k is None:
            return Isometry(np.eye(2, dtype=dtype), np.False_)
        return Isometry(np.tile(np.eye(2, dtype=dtype), (k, 1, 1)), np.zeros(k, bool))

    @staticmethod
    def stack(isometries: list[Isometry]) -> Isometry:
        """Stack single isometries into one stacked :class:`Isometry` of length ``k``."""
        if not isometries:
            raise ValueError("cannot stack an empty list of isometries")
        M = np.stack([g.M for g in isometries])
        sigma = np.stack([g.sigma for g in isometries])
        return Isometry(M, sigma)

    # ----------------------------------------------------------------- structure
    @property
    def is_stack(self) -> bool:
        """True if this holds a stack of pairs (``M.ndim == 3``)."""
        return self.M.ndim == 3

    def __len__(self) -> int:
        if not self.is_stack:
            raise TypeError("a single Isometry has no length")
        return self.M.shape[0]

    def __getitem__(self, idx: int | slice | NDArray) -> Isometry:
        if not self.is_stack:
            raise TypeError("a single Isometry cannot be indexed")
        return Isometry(self.M[idx], self.sigma[idx])

    # ----------------------------------------------------------------- algebra
    def compose(self, other: Isometry) -> Isometry:
        """``self ∘ other`` (apply ``other`` first); stacks broadcast elementwise."""
        M2 = np.where(self.sigma[..., None, None], np.conj(other.M), other.M)
        M = normalize_matrix(self.M @ M2)
        return Isometry(M, np.logical_xor(self.sigma, other.sigma))

    def __matmul__(self, other: Isometry) -> Isometry:
        return self.compose(other)

    def inverse(self) -> Isometry:
        """The inverse map ``(σ ? conj(M⁻¹) : M⁻¹, σ)``."""
        M = self.M
        inv = np.empty_like(M)
        inv[..., 0, 0] = M[..., 1, 1]
        inv[..., 0, 1] = -M[..., 0, 1]
        inv[..., 1, 0] = -M[..., 1, 0]
        inv[..., 1, 1] = M[..., 0, 0]
        inv = normalize_matrix(inv)
        inv = np.where(self.sigma[..., None, None], np.conj(inv), inv)
        return Isometry(inv, self.sigma.copy())

    # ----------------------------------------------------------------- action
    def __call__(self, z: ArrayLike) -> ComplexArray:
        """Apply a *single* pair to points ``z`` of any shape."""
        if self.is_stack:
            raise TypeError("use apply_rows() to apply a stack of isometries")
        z = np.asarray(z, dtype=_cdtype(self.M, z))
        return mobius_apply(self.M, np.conj(z) if bool(self.sigma) else z)

    def apply_rows(self, z: ArrayLike) -> ComplexArray:
        """Apply a stack of ``k`` pairs: ``z`` of shape ``(p,)`` → ``(k, p)`` (every map on all
        points) or ``(k, p)`` → ``(k, p)`` (row ``i`` mapped by isometry ``i``).
        A single pair accepts ``(p,)`` and returns ``(p,)``.
        """
        if not self.is_stack:
            return self(z)
        return apply_isometries(self.M, self.sigma, z)

    def reverses_orientation(self) -> NDArray[np.bool_]:
        """Alias of ``sigma``: True where the map is orientation reversing."""
        return self.sigma


def apply_isometries(M: ArrayLike, sigma: ArrayLike, z: ArrayLike) -> ComplexArray:
    """Apply stacked pairs ``(M[i], sigma[i])`` (``M`` of shape ``(k,2,2)``) to points.

    ``z`` of shape ``(p,)`` is mapped by every isometry (result ``(k, p)``); ``z`` of shape
    ``(k, p)`` is mapped row by row.  Vectorised; no Python loop.  The result is clongdouble if
    ``M`` or ``z`` is extended precision, else complex128.
    """
    dt = _cdtype(M, z)
    M = np.asarray(M, dtype=dt)
    sigma = np.asarray(sigma, dtype=bool)
    z = np.asarray(z, dtype=dt)
    if z.ndim == 1:
        z = z[None, :]  # np.where broadcasts it to (k, p)
    w = np.where(sigma[:, None], np.conj(z), z)
    return _mobius_apply_batched(M[:, None, :, :], w)


# --------------------------------------------------------------------- standard maps
def disk_automorphism(a: complex, lam: complex = 1.0) -> Isometry:
    """The disk automorphism ``φ_a(z) = λ(z−a)/(1−ā z)`` (sends ``a`` to 0), as an Isometry."""
    a = complex(a)
    lam = complex(lam)
    if abs(a) >= 1.0:
        raise ValueError(f"disk automorphism needs |a| < 1, got |a| = {abs(a)}")
    M = np.array([[lam, -lam * a], [-np.conj(a), 1.0]], dtype=np.complex128)
    return Isometry(normalize_matrix(M), np.False_)


def disk_automorphism_inverse(a: complex, lam: complex = 1.0) -> Isometry:
    """Inverse of ``φ_a``: ``w ↦ (λ̄w + a)/(1 + āλ̄w)`` (sends 0 to ``a``)."""
    return disk_automorphism(a, lam).inverse()


def phi(a: ArrayLike, z: ArrayLike) -> ComplexArray:
    """Vectorised ``φ_a(z) = (z−a)/(1−ā z)`` (``a`` and ``z`` broadcast; clongdouble in, out)."""
    dt = _cdtype(a, z)
    a = np.asarray(a, dtype=dt)
    z = np.asarray(z, dtype=dt)
    return (z - a) / (1.0 - np.conj(a) * z)


def phi_inv(a: ArrayLike, w: ArrayLike) -> ComplexArray:
    """Vectorised ``φ_a⁻¹(w) = (w + a)/(1 + ā w)`` (``a`` and ``w`` broadcast; clongdouble in,
    out)."""
    dt = _cdtype(a, w)
    a = np.asarray(a, dtype=dt)
    w = np.asarray(w, dtype=dt)
    return (w + a) / (1.0 + np.conj(a) * w)


def _to_zero_inf_one(z0: complex, z1: complex, z2: complex) -> ComplexArray:
    """Matrix sending z0, z1, z2 ↦ 0, ∞, 1 (finite points)."""
    return np.array(
        [[z2 - z1, -z0 * (z2 - z1)], [z2 - z0, -z1 * (z2 - z0)]],
        dtype=np.complex128,
    )


def mobius_from_points(z: ArrayLike, w: ArrayLike) -> Isometry:
    """The Möbius map sending ``z[k] ↦ w[k]`` (k = 0, 1, 2; finite distinct points).

    Built as ``S_w⁻¹·S_z`` where ``S_z`` sends ``z0, z1, z2 ↦ 0, ∞, 1``.  Returned as
    an orientation-preserving :class:`Isometry` pair (it is an isometry only if it maps D to D).
    """
    z = np.asarray(z, dtype=np.complex128).ravel()
    w = np.asarray(w, dtype=np.complex128).ravel()
    if z.size != 3 or w.size != 3:
        raise ValueError("mobius_from_points needs exactly 3 source and 3 target points")
    Sz = normalize_matrix(_to_zero_inf_one(*z))
    Sw = Isometry(normalize_matrix(_to_zero_inf_one(*w)), np.False_)
    return Sw.inverse().compose(Isometry(Sz, np.False_))


CAYLEY_D_TO_H = np.array([[1j, 1j], [-1.0, 1.0]], dtype=np.complex128)
"""Matrix of the Cayley map D→H, ``w = i(1+z)/(1−z)``."""
CAYLEY_H_TO_D = np.array([[1.0, -1j], [1.0, 1j]], dtype=np.complex128)
"""Matrix of the Cayley map H→D, ``z = (w−i)/(w+i)``."""


def cayley_d_to_h(z: ArrayLike) -> ComplexArray:
    """Cayley map D→H: ``w = i(1+z)/(1−z)`` (``z = 1`` ↦ ∞)."""
    return mobius_apply(CAYLEY_D_TO_H, z)


def cayley_h_to_d(w: ArrayLike) -> ComplexArray:
    """Cayley map H→D: ``z = (w−i)/(w+i)`` (``w = ∞`` ↦ 1)."""
    return mobius_apply(CAYLEY_H_TO_D, w)
