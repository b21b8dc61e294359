"""Power series of the Schwarz–Christoffel map about interior centres and about prevertices.

CONFORMAL.md §1.10. About an interior centre ``c`` with ``R = min_k |z_k − c|``:

* ``log f'(c+t) = log f'(c) + Σ_{m≥1} b_m t^m`` with ``b_m = −(1/m) Σ_k β_k (z_k − c)^{−m}``;
* ``f'(c+t) = Σ g_m t^m`` from ``g = exp(log f')`` by ``m g_m = Σ_{j=1..m} j b_j g_{m−j}``;
* ``f(c+t) = f(c) + Σ g_m t^{m+1}/(m+1)``, evaluated by Horner's rule.

About a prevertex ``z_k`` (radius ``R_k`` = distance to the nearest other prevertex), with
``u = 1 − z/z_k`` and ``G_k(s) = Π_{j≠k}(1 − s/z_j)^{β_j} = Σ g_m (s − z_k)^m``:
``f(z) = w_k + C(−z_k) u^{α_k} Σ_m g_m (−z_k u)^m/(α_k + m)`` and
``f'(z) = C u^{β_k} G_k(z)``. The coefficients of ``log G_k`` use the local differences
``z_j − z_k`` (accurate under crowding). Everything is scaled by ``R`` (``τ = t/R``) so the
coefficients stay O(1). The error behaves like ``(|t|/R)^order``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["exp_series", "horner", "log_coefficients"]


def log_coefficients(q: np.ndarray, beta: np.ndarray, order: int) -> np.ndarray:
    """Scaled coefficients ``b̃_m = −(1/m) Σ_k β_k q_k^m`` for m = 1..order.

    ``q`` has shape (K, n) with ``q_k = R/(z_k − c)``; returns (K, order+1), column 0 zero.
    """
    K = q.shape[0]
    b = np.zeros((K, order + 1), dtype=np.complex128)
    P = np.ones_like(q)
    for m in range(1, order + 1):
        P *= q
        b[:, m] = -(P.real @ beta + 1j * (P.imag @ beta)) / m
    return b


def exp_series(b: np.ndarray, g0: np.ndarray) -> np.ndarray:
    """Coefficients ``g`` of ``exp(Σ b_m τ^m)·g0`` by the recurrence ``m g_m = Σ j b_j g_{m−j}``."""
    K, M1 = b.shape
    g = np.zeros((K, M1), dtype=np.complex128)
    g[:, 0] = g0
    jb = b * np.arange(M1)[None, :]
    for m in range(1, M1):
        g[:, m] = np.sum(jb[:, 1 : m + 1] * g[:, m - 1 :: -1][:, :m], axis=1) / m
    return g


def horner(coef: np.ndarray, rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Evaluate ``Σ_m coef[rows, m] τ^m`` for every point (one cluster row per point)."""
    M1 = coef.shape[1]
    acc = coef[rows, M1 - 1].copy()
    for m in range(M1 - 2, -1, -1):
        acc = acc * tau + coef[rows, m]
    return acc
