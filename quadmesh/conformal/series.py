"""Power series of the Schwarz–Christoffel map about interior centres and about prevertices.

About an interior centre ``c`` with ``R = min_k |z_k − c|``:

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

import functools
import math

import numpy as np

from ..progress import checkpoint
from .quadrature import beta_log_sum

#: Rows of :func:`exp_series` per block (two (M+1)×block complex arrays stay in cache).
_EXP_BLOCK = 2048

__all__ = [
    "direct_expansions",
    "exp_series",
    "horner",
    "horner_t",
    "log_coefficients",
    "log_expansions",
    "log_series",
    "match_rows",
    "unique_rows",
    "window_pairs",
]


def log_coefficients(q: np.ndarray, beta: np.ndarray, order: int) -> np.ndarray:
    """Scaled coefficients ``b̃_m = −(1/m) Σ_k β_k q_k^m`` for m = 1..order.

    ``q`` has shape (K, n) with ``q_k = R/(z_k − c)`` (a zero entry leaves its prevertex out);
    returns (K, order+1), column 0 zero. One complex matrix-vector product per order (zgemv
    with β as complex: ~5× faster than two real products on the strided real and imaginary
    parts of the powers).
    """
    K = q.shape[0]
    b = np.zeros((K, order + 1), dtype=np.complex128)
    if order < 1:
        return b
    beta_c = np.asarray(beta, dtype=np.complex128)
    P = np.array(q, dtype=np.complex128)
    b[:, 1] = -(P @ beta_c)
    for m in range(2, order + 1):
        P *= q
        b[:, m] = -(P @ beta_c) / m
    return b


def log_series(
    d: np.ndarray, zc: np.ndarray, beta: np.ndarray, scale: np.ndarray, order: int
) -> np.ndarray:
    """Coefficients of ``Σ_k β_k Log(1 − (c + scale·τ)/z_k)`` in τ, one row per centre c, from
    the differences ``d = z_k − c`` (K, n) — as they come, so that local-coordinate differences
    keep their accuracy: ``a_0 = Σ_k β_k Log(d_k z̄_k)`` (``1 − c/z_k = (z_k − c) z̄_k``) and
    ``a_m`` of :func:`log_coefficients` with ``q_k = scale/d_k``. Returns (K, order + 1)."""
    a = log_coefficients(scale[:, None] / d, beta, order)
    a[:, 0] = beta_log_sum(d * zc[None, :], beta)
    return a


def exp_series(b: np.ndarray, g0: np.ndarray) -> np.ndarray:
    """Coefficients ``g`` of ``exp(Σ b_m τ^m)·g0`` by the recurrence ``m g_m = Σ j b_j g_{m−j}``.

    ``b`` has shape (K, M+1) (column 0 ignored), ``g0`` shape (K,); returns (K, M+1). The
    recurrence runs over the orders with the rows as the vector dimension: coefficients are
    stored order-major (each order's K values contiguous, one ``einsum`` per order) in blocks
    of :data:`_EXP_BLOCK` rows that stay in cache.
    """
    K, M1 = b.shape
    out = np.empty((K, M1), dtype=np.complex128)
    jb_all = b * np.arange(M1)[None, :]
    for i0 in range(0, K, _EXP_BLOCK):
        jb = np.ascontiguousarray(jb_all[i0 : i0 + _EXP_BLOCK].T)  # (M1, k): j b_j per row
        g = np.empty_like(jb)
        g[0] = g0[i0 : i0 + _EXP_BLOCK]
        for m in range(1, M1):
            # Σ_{j=1..m} j b_j g_{m−j}: rows j of jb against rows m−1, …, 0 of g
            np.einsum("jk,jk->k", jb[1 : m + 1], g[m - 1 :: -1], out=g[m])
            g[m] /= m
        out[i0 : i0 + _EXP_BLOCK] = g.T
    return out


def horner(coef: np.ndarray, rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Evaluate ``Σ_m coef[rows, m] τ^m`` for every point (one cluster row per point)."""
    return horner_t(np.ascontiguousarray(coef.T), rows, tau)


def horner_t(coef_t: np.ndarray, rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """:func:`horner` with the coefficients order-major: ``Σ_m coef_t[m, rows] τ^m``.

    Horner's rule in place, each order's coefficients gathered from its contiguous row.
    """
    M1 = coef_t.shape[0]
    acc = coef_t[M1 - 1].take(rows).astype(np.result_type(coef_t, tau), copy=False)
    for m in range(M1 - 2, -1, -1):
        acc *= tau
        acc += coef_t[m].take(rows)
    return acc


# ---------------------------------------------------------------------------------------------
# Far-field tree: expansions of Λ(z) = Σ_k β_k log(1 − z/z_k) about many centres at once.
#
# A direct sum over all n prevertices for every series centre costs O(n·order) per centre,
# which makes the push-forward of a disk mesh quadratic in n. The tree
# below is the downward pass of a fast multipole method with point-to-local translations:
# a dyadic box B of side h carries the expansion of the prevertices farther than F·h from its
# centre (they are smooth on B); a child inherits its parent's expansion by an exact
# polynomial shift and adds the prevertices that are far for the child but were near for the
# parent. A target centre finally shifts its box's expansion to itself and adds its near
# prevertices directly. Every prevertex enters O(1) boxes per level, so the total work is
# O((n log(1/h_min) + boxes)·order + targets·order²).

#: :func:`log_expansions` sums directly over all prevertices (:func:`direct_expansions`) when
#: n ≤ DIRECT_N or n·targets ≤ DIRECT_PAIRS: measured on the expansions of the pipeline's
#: evaluations (comb, blob, smooth stars n = 100, 300), the direct sums cost ≈ 0.2 µs per
#: (target, prevertex) pair against ≈ 50 µs per target for the tree, and the tree has a fixed
#: cost of ~5 ms per call (n = 42, 5381 targets: 63 ms direct, 590 ms tree; n = 100, 11614
#: targets: 205 vs 580 ms; n = 300, 302 targets: 22 vs 22 ms).
DIRECT_N = 200
DIRECT_PAIRS = 100_000
FAR = 7.0  # box far threshold in box sides: targets' regions sit within 2.71 h → ratio 0.39
TREE_ORDER = 40  # 0.39^40 ≈ 4e-17


def window_pairs(theta: np.ndarray, c: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All pairs (i, k) with ``|e^{iθ_k} − c_i| ≤ D_i`` as candidate index arrays.

    The prevertices lie on the unit circle with sorted angles ``theta``; the disk of radius
    D about c meets the circle in one arc, found by bisection. The caller applies the exact
    distance test (the arc is widened slightly, so no pair is missed).
    """
    n = theta.size
    rho = np.abs(c)
    arg = np.mod(np.angle(c), 2 * np.pi)
    e = np.abs(1.0 - rho)
    # |e^{i(arg+φ)} − c|² = (1 − ρ)² + 4ρ sin²(φ/2): no cancellation for small D
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (D - e) * (D + e) / (4.0 * rho)
    phi = np.where(x >= 1.0, 4.0, 2.0 * np.arcsin(np.sqrt(np.clip(x, 0.0, 1.0))))
    phi = np.where(x < 0.0, -1.0, phi)
    phi = np.where(rho == 0.0, np.where(D >= 1.0, 4.0, -1.0), phi)
    phi = np.where(phi >= 0.0, phi * (1.0 + 1e-9) + 1e-15, phi)
    ext = np.concatenate([theta - 2 * np.pi, theta, theta + 2 * np.pi])
    i0 = np.searchsorted(ext, arg - phi, side="left")
    i1 = np.searchsorted(ext, arg + phi, side="right")
    cnt = np.clip(i1 - i0, 0, n)
    rows = np.repeat(np.arange(c.size), cnt)
    start = np.repeat(i0 - np.cumsum(cnt) + cnt, cnt)
    k = np.mod(start + np.arange(rows.size), n)
    return rows, k


def p2l(
    rows: np.ndarray,
    k: np.ndarray,
    zk: np.ndarray,
    beta: np.ndarray,
    c: np.ndarray,
    scale: np.ndarray,
    order: int,
    out: np.ndarray,
) -> None:
    """Add ``β_k log(1 − z/z_k)`` about ``c[rows]`` in ``u = (z − c)/scale`` to ``out[rows]``.

    ``log(1 − (c + s)/z_k) = log((z_k − c)/z_k) − Σ_m (s/(z_k − c))^m/m``; the principal
    branch is kept because the segment from c to any point of the target region avoids the
    ray ``z_k·[1, ∞)``.
    """
    if rows.size == 0:
        return
    K = out.shape[0]
    d = zk[k] - c[rows]
    b = beta[k]
    l0 = np.log(d * np.conj(zk[k]))
    out[:, 0] += np.bincount(rows, b * l0.real, K) + 1j * np.bincount(rows, b * l0.imag, K)
    q = scale[rows] / d
    srt = np.argsort(rows, kind="stable")
    rs, qs, bs = rows[srt], q[srt], b[srt]
    inv_m = -1.0 / np.arange(1, order + 1)
    step = 16384
    for i0 in range(0, rs.size, step):
        checkpoint()
        r = rs[i0 : i0 + step]
        qc = qs[i0 : i0 + step]
        first = np.flatnonzero(np.r_[True, r[1:] != r[:-1]])
        # the terms β_k q_k^m one order at a time, each order's per-target sums by one
        # reduceat over the pairs (sorted by target): a block of pairs stays in cache (the
        # former (order × pairs) array of all powers did not; n = 1000: 1.4 -> 0.9 s)
        sums = np.empty((first.size, order), dtype=np.complex128)
        cur = qc * bs[i0 : i0 + step]
        sums[:, 0] = np.add.reduceat(cur, first)
        for m in range(1, order):
            cur *= qc
            sums[:, m] = np.add.reduceat(cur, first)
        out[r[first], 1:] += sums * inv_m[None, :]


def shift_matrix(s: complex, sigma: float, order: int) -> np.ndarray:
    """Matrix M with ``a' = a @ M`` for ``Σ a_m τ^m = Σ a'_j u^j`` when ``τ = s + σ u``."""
    M = np.zeros((order + 1, order + 1), dtype=np.complex128)
    for m in range(order + 1):
        for j in range(m + 1):
            M[m, j] = math.comb(m, j) * s ** (m - j) * sigma**j
    return M


@functools.lru_cache(maxsize=8)
def _child_shifts(order: int) -> dict[tuple[int, int], np.ndarray]:
    """The :func:`shift_matrix` from a box's expansion (scale ``F·h``) to each of its four
    children's (scale ``F·h/2``), keyed by the child's quadrant ``(qx, qy)`` (computed once:
    the matrices do not depend on the box)."""
    mats = {}
    for qx in (0, 1):
        for qy in (0, 1):
            s = ((qx - 0.5) + 1j * (qy - 0.5)) / (2.0 * FAR)
            mats[(qx, qy)] = shift_matrix(s, 0.5, order)
            mats[(qx, qy)].flags.writeable = False
    return mats


@functools.lru_cache(maxsize=64)
def _pascal(rows: int, cols: int) -> np.ndarray:
    m = np.arange(rows)[:, None]
    j = np.arange(cols)[None, :]
    return np.where(j <= m, np.vectorize(math.comb)(m, np.minimum(j, m)), 0).astype(float)


def shift(a: np.ndarray, s: np.ndarray, sigma: np.ndarray, order: int) -> np.ndarray:
    """Coefficients of ``Σ_m a_m (s + σ u)^m`` in u up to ``order``.

    ``b_j = σ^j s^{−j} Σ_m C(m, j) (a_m s^m)``: one matrix product with the Pascal matrix for
    all rows with ``|s| ≥ 1e-3`` (powers of s stay far from under/overflow); Horner on
    polynomials for the others.
    """
    K, M1 = a.shape
    out = np.empty((K, order + 1), dtype=np.complex128)
    big = np.abs(s) >= 1e-3
    i = np.flatnonzero(big)
    if i.size:
        L = max(M1, order + 1)
        sp = np.empty((i.size, L), dtype=np.complex128)
        sp[:, 0] = 1.0
        sp[:, 1:] = s[i, None]
        np.cumprod(sp, axis=1, out=sp)
        y = a[i] * sp[:, :M1]
        Pm = _pascal(M1, order + 1)
        # real and imaginary parts through the real Pascal matrix as one stacked product
        # ((k, 2, M1) @ (M1, order+1)) on the float view: 3x faster than y.real @ Pm and
        # y.imag @ Pm on the strided parts
        yf = y.view(np.float64).reshape(i.size, M1, 2).transpose(0, 2, 1)
        c = (yf @ Pm).transpose(0, 2, 1).copy().view(np.complex128).reshape(i.size, order + 1)
        r = np.empty((i.size, order + 1), dtype=np.complex128)
        r[:, 0] = 1.0
        r[:, 1:] = (sigma[i] / s[i])[:, None]
        np.cumprod(r, axis=1, out=r)
        out[i] = c * r
    i = np.flatnonzero(~big)
    if i.size:
        P = np.zeros((i.size, order + 1), dtype=np.complex128)
        ss = s[i, None]
        sg = sigma[i, None]
        for m in range(M1 - 1, -1, -1):
            Q = ss * P
            Q[:, 1:] += sg * P[:, :-1]
            Q[:, 0] += a[i, m]
            P = Q
        out[i] = P
    return out


def direct_expansions(
    zk: np.ndarray, beta: np.ndarray, c: np.ndarray, rho: np.ndarray, orders: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The expansions of :func:`log_expansions` by direct sums over all prevertices.

    ``a_0 = Σ_k β_k Log(1 − c/z_k)`` and ``a_m = −(1/m) Σ_k β_k q_k^m`` with
    ``q_k = 2ρ/(z_k − c)`` (:func:`log_coefficients`; ``|q_k| ≤ 1`` since ``2ρ`` is at most
    the distance to the prevertices): O(n·order) per target, in blocks of ≈ 32768 pairs.
    """
    n = zk.size
    zc = np.conj(zk)
    step = max(1, 32768 // max(n, 1))
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for o in np.unique(orders):
        t = np.flatnonzero(orders == o)
        a = np.empty((t.size, int(o) + 1), dtype=np.complex128)
        for i in range(0, t.size, step):
            checkpoint()
            ti = t[i : i + step]
            a[i : i + step] = log_series(zk[None, :] - c[ti, None], zc, beta, 2.0 * rho[ti], int(o))
        out.append((t, a))
    return out


def log_expansions(
    zk: np.ndarray,
    theta: np.ndarray,
    beta: np.ndarray,
    c: np.ndarray,
    rho: np.ndarray,
    orders: np.ndarray,
    direct: bool | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Coefficients of ``Λ(c_i + 2ρ_i u) = Σ_j a_j u^j``, ``Λ(z) = Σ_k β_k log(1 − z/z_k)``.

    ``rho_i`` is the radius of the region where target i will be evaluated (``|u| ≤ ½``); it
    must not exceed half the distance from ``c_i`` to the prevertices. ``orders`` gives each
    target's number of terms; returns groups ``(targets, coefficients)`` of equal order
    (coefficients of shape (len(targets), order + 1)), computed with the far-field tree
    described above (error ≈ 1e-16·Σ|β_k| at ``|u| ≤ ½``), or by direct sums
    (:func:`direct_expansions`): ``direct`` True or False forces either, None (default)
    takes the direct sums when they are cheaper (see :data:`DIRECT_N`).
    """
    K = c.size
    if direct is None:
        direct = zk.size <= DIRECT_N or zk.size * K <= DIRECT_PAIRS
    if direct:
        return direct_expansions(zk, beta, c, rho, orders)
    p = TREE_ORDER
    lev_t = np.minimum(np.floor(np.log2(np.maximum(rho, 1e-300))).astype(np.int64), 1)
    top = 1
    lo = int(lev_t.min()) if K else top
    # keys of each target's box at its own level
    h_t = np.ldexp(1.0, lev_t)
    kx = np.floor(c.real / h_t).astype(np.int64)
    ky = np.floor(c.imag / h_t).astype(np.int64)
    quad_mats = _child_shifts(p)
    # the boxes of every level, fine to coarse: a level's own targets' boxes and the parents
    # of the finer level's boxes (unique keys in lexicographic order), with each target's box
    # at its own level and each box's parent (one unique_rows over the boxes per level, not
    # over all the targets below it)
    box_of_target = np.full(K, -1, dtype=np.int64)
    level_keys: dict[int, np.ndarray] = {}
    parent_of: dict[int, np.ndarray] = {}
    finer = None
    for lev in range(lo, top + 1):
        own = np.flatnonzero(lev_t == lev)
        cand = np.stack([kx[own], ky[own]], axis=1)
        if finer is not None:
            cand = np.concatenate([cand, finer >> 1])
        keys, inv = unique_rows(cand)
        box_of_target[own] = inv[: own.size]
        if finer is not None:
            parent_of[lev - 1] = inv[own.size :]
        level_keys[lev] = finer = keys
    prev_keys = None
    prev_exp = None
    cen_prev = None
    level_exp: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for lev in range(top, lo - 1, -1):
        checkpoint(0.5 * (top - lev) / max(top - lo + 1, 1))
        keys = level_keys[lev]
        h = math.ldexp(1.0, lev)
        cen = (keys[:, 0] + 0.5) * h + 1j * (keys[:, 1] + 0.5) * h
        exp = np.zeros((keys.shape[0], p + 1), dtype=np.complex128)
        scale = np.full(keys.shape[0], FAR * h)
        if prev_keys is None:
            # top level: the far set (distance > F·h ≥ 14) is empty
            pass
        else:
            pk = keys >> 1
            pidx = parent_of[lev]
            qx = keys[:, 0] - 2 * pk[:, 0]
            qy = keys[:, 1] - 2 * pk[:, 1]
            for (a, b_), M in quad_mats.items():
                m = np.flatnonzero((qx == a) & (qy == b_))
                if m.size:
                    exp[m] = prev_exp[pidx[m]] @ M
            pc = cen_prev[pidx]
            rows, k = window_pairs(theta, pc, np.full(pc.size, 2.0 * FAR * h))
            dp = np.abs(zk[k] - pc[rows])
            dc = np.abs(zk[k] - cen[rows])
            keep = (dp <= 2.0 * FAR * h) & (dc > FAR * h)
            p2l(rows[keep], k[keep], zk, beta, cen, scale, p, exp)
        level_exp[lev] = (cen, exp)
        prev_keys, prev_exp, cen_prev = keys, exp, cen
    out: list[tuple[np.ndarray, np.ndarray]] = []
    done, total = 0, max(K, 1)
    for o in np.unique(orders):
        for lev in np.unique(lev_t):
            checkpoint(0.5 + 0.5 * done / total)
            t = np.flatnonzero((orders == o) & (lev_t == lev))
            done += t.size
            if t.size == 0:
                continue
            cen, exp = level_exp[int(lev)]
            h = math.ldexp(1.0, int(lev))
            bi = box_of_target[t]
            S = 2.0 * rho[t]
            a = shift(exp[bi], (c[t] - cen[bi]) / (FAR * h), S / (FAR * h), int(o))
            rows, k = window_pairs(theta, cen[bi], np.full(t.size, FAR * h))
            near = np.abs(zk[k] - cen[bi][rows]) <= FAR * h
            p2l(rows[near], k[near], zk, beta, c[t], S, int(o), a)
            out.append((t, a))
    return out


def _codes(keys: np.ndarray, lo: np.ndarray, span: np.ndarray) -> np.ndarray:
    return (keys[:, 0] - lo[0]) * span[1] + (keys[:, 1] - lo[1])


def unique_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of an (N, 2) int64 array in lexicographic order, and the inverse index
    (one 1-D sort of packed codes when they fit in int64, else a lexsort)."""
    if keys.shape[0] == 0:
        return keys.copy(), np.empty(0, dtype=np.intp)
    lo = keys.min(axis=0)
    span = keys.max(axis=0) - lo + 1
    if float(span[0]) * float(span[1]) < 2.0**62:
        _, first, inv = np.unique(_codes(keys, lo, span), return_index=True, return_inverse=True)
        return keys[first], inv.ravel()
    order = np.lexsort(keys.T[::-1])
    sk = keys[order]
    new = np.r_[True, np.any(sk[1:] != sk[:-1], axis=1)]
    inv = np.empty(keys.shape[0], dtype=np.intp)
    inv[order] = np.cumsum(new) - 1
    return sk[new], inv


def match_rows(keys: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Row index in ``keys`` (unique rows in lexicographic order, as from :func:`unique_rows`)
    of each row of ``query`` (every query row must occur in ``keys``)."""
    lo = keys.min(axis=0)
    span = keys.max(axis=0) - lo + 1
    if float(span[0]) * float(span[1]) < 2.0**62:
        return np.searchsorted(_codes(keys, lo, span), _codes(query, lo, span))
    _, inv = unique_rows(np.concatenate([keys, query]))
    return inv[keys.shape[0] :]
