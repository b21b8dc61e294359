"""Local angle repair of a pushed-forward quad mesh (paper §7, Lemma "small distortion").

The image under the conformal map f of a disk-mesh quad differs from a similar copy of that
quad by O(ε), ε the non-linearity of f over it (Lemma "small distortion"); the paper drives ε
down by refining every pentagon mesh (a larger N). On real outlines only a handful of
pushed-forward quads — pentagon quads next to reflex corners and spikes — leave [60°, 120°],
typically by 0.2–5°, while a larger N multiplies the quad count of the whole piece by
(N'/N)² (measured: 1.5–2.7× more quads per polygon vertex at n = 3 or 4 instead of 2).

:func:`repair_angles` instead moves the *interior* vertices near the offending quads by a
small fraction of the local edge length, keeping the mesh topology (so conformity, the
boundary and the vertices shared with thin parts are untouched) and every other angle in
range. It minimises, by Levenberg–Marquardt with a sparse Jacobian (scipy ``least_squares``),

    Σ_angles hinge(lo − a)² + hinge(a − hi)²  +  Σ_quads hinge(area_min − area)²
        + μ² Σ_vertices |Δz / h|²,

where ``h`` is the vertex's shortest incident edge and μ = 1e-2 keeps the displacement as
small as possible. Only vertices within ``rings`` quad rings of an offending quad move; the
result is accepted only if every quad touching a moved vertex ends up positively oriented,
convex and with all angles in [lo, hi] (checked with the exact angle function, not the
objective), else ``None`` is returned and the caller falls back to the paper's remedy.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.sparse.csgraph import connected_components

from .geometry import quad_angles_deg, quad_signed_areas
from .progress import checkpoint

__all__ = ["RepairReport", "repair_angles"]


class RepairReport:
    """What :func:`repair_angles` did.

    Attributes:
        moved: indices of the vertices that moved.
        max_shift: largest displacement relative to the vertex's shortest incident edge.
        before: (min, max) angle over the quads touching the moved vertices, before.
        after: (min, max) angle over the same quads, after.
    """

    def __init__(
        self,
        moved: NDArray[np.int64],
        max_shift: float,
        before: tuple[float, float],
        after: tuple[float, float],
    ) -> None:
        self.moved = moved
        self.max_shift = max_shift
        self.before = before
        self.after = after

    def __repr__(self) -> str:
        return (
            f"RepairReport(moved={self.moved.size}, max_shift={self.max_shift:.3g}, "
            f"before=[{self.before[0]:.2f}, {self.before[1]:.2f}], "
            f"after=[{self.after[0]:.2f}, {self.after[1]:.2f}])"
        )


def _angles_rad(z: NDArray[np.complex128], quads: NDArray[np.int64]) -> NDArray[np.float64]:
    """Interior angles (radians) of counter-clockwise quads, signed so that a reflex or
    flipped corner shows as an angle > π."""
    c = z[quads]
    prev = np.roll(c, 1, axis=1) - c
    nxt = np.roll(c, -1, axis=1) - c
    return np.mod(np.angle(prev / nxt), 2 * np.pi)


def repair_angles(
    vertices: ArrayLike,
    quads: ArrayLike,
    movable: ArrayLike,
    *,
    lo: float = 60.0,
    hi: float = 120.0,
    margin: float = 0.05,
    rings: int = 2,
    max_vertices: int = 20000,
    tol: float | ArrayLike = 1e-6,
    xtol: float = 1e-6,
    max_nfev: int = 100,
    max_shift: float = 0.25,
) -> tuple[NDArray[np.complex128], RepairReport] | None:
    """Move interior vertices so that every quad angle lies in [lo, hi] degrees.

    Args:
        vertices: (V,) complex vertex positions.
        quads: (Q, 4) counter-clockwise vertex indices.
        movable: (V,) bool, True for vertices that may move (interior vertices not shared
            with another mesh).
        lo, hi: the admissible angle range (degrees).
        margin: the objective aims at ``[lo + margin, hi − margin]`` for angles outside it
            (angles already inside ``[lo, hi]`` but within the margin keep their value as
            their bound), so that the accepted result has a little slack.
        rings: quad rings around the offending quads whose movable vertices may move.
        max_vertices: refuse (return None) when more vertices would have to move.
        tol: rounding slack (degrees) on [lo, hi], a scalar or one value per quad (e.g.
            :func:`quadmesh.geometry.angle_rounding_slack_deg` plus a constant): angles that
            are exactly lo or hi by construction (the spokes of the inner triangles T_i) and
            read off by float64 rounding are not offending.
        xtol, max_nfev: stopping rules of the least-squares solve (the result is checked
            with the exact angles whatever the solver reports).
        max_shift: largest accepted displacement of a vertex relative to its shortest
            incident edge. A repair that needs more is no longer a small correction of the
            conformal image (measured repairs on the examples and generated outlines move
            vertices by at most 12 %), so None is returned and the caller falls back to the
            paper's remedy.

    Returns:
        ``(new_vertices, report)``, or None when nothing needed repair is impossible here
        (no movable vertex near an offending quad, too many vertices, or the optimum still
        leaves an angle out of range).  When no angle is out of range the input is returned
        unchanged with an empty report.
    """
    z0 = np.asarray(vertices, dtype=np.complex128).ravel()
    q = np.asarray(quads, dtype=np.int64)
    mov = np.asarray(movable, dtype=bool).ravel()
    ang = quad_angles_deg(z0, q)
    tq = np.broadcast_to(np.asarray(tol, dtype=float), (len(q),))[:, None]
    bad_q = np.flatnonzero(((ang < lo - tq) | (ang > hi + tq)).any(axis=1))
    if bad_q.size == 0:
        return z0, RepairReport(np.zeros(0, np.int64), 0.0, (lo, hi), (lo, hi))

    # region: movable vertices within `rings` quad rings of the offending quads
    nv = z0.size
    inc = sp.csr_matrix(
        (np.ones(q.size, dtype=np.int8), (np.repeat(np.arange(len(q)), 4), q.ravel())),
        shape=(len(q), nv),
    )
    vmask = np.zeros(nv, dtype=bool)
    vmask[q[bad_q].ravel()] = True
    for _ in range(rings):
        qmask = (inc @ vmask.astype(np.int8)) > 0
        vmask[q[qmask].ravel()] = True
    region = np.flatnonzero(vmask & mov)
    if region.size == 0 or region.size > max_vertices:
        return None
    # independent problems: connected groups of region vertices (sharing a quad)
    pos = np.full(nv, -1, dtype=np.int64)
    pos[region] = np.arange(region.size)
    qr = pos[q]
    touch = np.flatnonzero((qr >= 0).any(axis=1))
    rr = qr[touch]
    src = np.repeat(rr[:, :1], 4, axis=1)
    pairs = np.stack([src.ravel(), rr.ravel()], axis=1)
    for k in range(1, 4):
        pairs = np.vstack(
            [pairs, np.stack([np.repeat(rr[:, k : k + 1], 4, axis=1).ravel(), rr.ravel()], 1)]
        )
    pairs = pairs[(pairs >= 0).all(axis=1)]
    graph = sp.csr_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(region.size, region.size)
    )
    ncomp, label = connected_components(graph, directed=False)
    order = np.argsort(label, kind="stable")
    bounds = np.searchsorted(label[order], np.arange(ncomp + 1))
    # all groups in one least-squares solve first (its Jacobian is block-diagonal, so the
    # groups stay independent but share the solver's per-iteration overhead); when that
    # leaves any angle out of range or moves a vertex too far, each group on its own
    if ncomp > 1:
        got = _solve_region(z0, q, ang, region, lo, hi, margin, tq, xtol, max_nfev)
        if got is not None and got[1] <= max_shift:
            z = z0.copy()
            z[region] = got[0]
            moved = region[z[region] != z0[region]]
            return z, RepairReport(moved, got[1], got[3], got[2])
    z = z0.copy()
    lo_new, hi_new, shift_max = 180.0, 0.0, 0.0
    before_lo, before_hi = 180.0, 0.0
    for c in range(ncomp):
        checkpoint(c / ncomp)
        sub = region[order[bounds[c] : bounds[c + 1]]]
        got = _solve_region(z0, q, ang, sub, lo, hi, margin, tq, xtol, max_nfev)
        if got is None:
            return None
        z[sub], shift, (a_lo, a_hi), (b_lo, b_hi) = got
        if shift > max_shift:
            return None
        shift_max = max(shift_max, shift)
        lo_new, hi_new = min(lo_new, a_lo), max(hi_new, a_hi)
        before_lo, before_hi = min(before_lo, b_lo), max(before_hi, b_hi)
    moved = region[z[region] != z0[region]]
    return z, RepairReport(moved, shift_max, (before_lo, before_hi), (lo_new, hi_new))


def _solve_region(
    z0: NDArray[np.complex128],
    q: NDArray[np.int64],
    ang: NDArray[np.float64],
    region: NDArray[np.int64],
    lo: float,
    hi: float,
    margin: float,
    tq: NDArray[np.float64],
    xtol: float,
    max_nfev: int,
):
    """Least-squares repair of one connected group of movable vertices (see
    :func:`repair_angles`). Returns (new positions of ``region``, largest relative shift,
    (min, max) angle after, (min, max) angle before) or None when it fails."""
    nv = z0.size
    in_region = np.zeros(nv, dtype=bool)
    in_region[region] = True
    rq = np.flatnonzero(in_region[q].any(axis=1))  # quads whose shape can change
    qq = q[rq]
    a0 = np.radians(ang[rq])
    lo_r, hi_r = np.radians(lo + margin), np.radians(hi - margin)
    tol = tq[rq]
    lo_t = np.where(a0 < np.radians(lo - tol), lo_r, np.minimum(lo_r, a0))
    hi_t = np.where(a0 > np.radians(hi + tol), hi_r, np.maximum(hi_r, a0))
    area0 = quad_signed_areas(z0, qq)

    # local length scale per region vertex: shortest incident edge
    e = z0[qq] - z0[np.roll(qq, -1, axis=1)]
    elen = np.abs(e).ravel()
    if not np.all(elen > 0):
        return None  # a quad with coincident corners (a crowded image): no angles to repair
    h = np.full(nv, np.inf)
    np.minimum.at(h, qq.ravel(), elen)
    np.minimum.at(h, np.roll(qq, -1, axis=1).ravel(), elen)
    hr = h[region]
    h = np.where(np.isfinite(h), h, 0.0)
    area_min = 0.05 * np.minimum(np.abs(area0), np.inf)
    mu = 1e-2
    weight = 1e3  # per radian: a 0.05° violation weighs like a shift of 0.9 h

    pos = np.full(nv, -1, dtype=np.int64)
    pos[region] = np.arange(region.size)

    def unpack(x: NDArray[np.float64]) -> NDArray[np.complex128]:
        z = z0.copy()
        z[region] = z0[region] + hr * (x[0::2] + 1j * x[1::2])
        return z

    def residuals(x: NDArray[np.float64]) -> NDArray[np.float64]:
        checkpoint()
        z = unpack(x)
        a = _angles_rad(z, qq)
        r1 = weight * np.maximum(lo_t - a, 0.0).ravel()
        r2 = weight * np.maximum(a - hi_t, 0.0).ravel()
        r3 = np.maximum(area_min - quad_signed_areas(z, qq), 0.0) / np.maximum(area_min, 1e-300)
        return np.concatenate([r1, r2, r3, mu * x])

    # analytic Jacobian. d arg(w) = Im(dw / w): the gradient of arg(w) in (x, y) is i/conj(w).
    # Its sparsity pattern is fixed (rows: the 4 angles of every quad below lo, the 4 above
    # hi, every quad's area, the displacement penalty; columns: x and y of every region
    # vertex), so it is built once and only the values are recomputed per call.
    nq = len(qq)
    nx = 2 * region.size
    pq = pos[qq]  # (nq, 4) region position of each corner, -1 if fixed
    scale = np.where(pq >= 0, h[qq], 0.0)  # dz = h dx for region vertices
    kprev = np.array([3, 0, 1, 2])
    knext = np.array([1, 2, 3, 0])
    k_all = np.arange(4)
    # blocks of (rows, corner positions): lo angles and hi angles w.r.t. the previous, next
    # and own corner, then the area rows w.r.t. the four corners
    rows4 = np.arange(4 * nq).reshape(nq, 4)
    rows_area = np.repeat((8 * nq + np.arange(nq))[:, None], 4, axis=1)
    blocks = [(rows4 + off, pq[:, k]) for off in (0, 4 * nq) for k in (kprev, knext, k_all)]
    blocks.append((rows_area, pq))
    keep = np.concatenate([(cp >= 0).ravel() for _, cp in blocks])
    r_all = np.concatenate([r.ravel() for r, _ in blocks])[keep]
    c_all = np.concatenate([cp.ravel() for _, cp in blocks])[keep]
    rr = np.concatenate([r_all, r_all, 9 * nq + np.arange(nx)])
    cc = np.concatenate([2 * c_all, 2 * c_all + 1, np.arange(nx)])
    nnz = rr.size
    # where each entry lands in the CSR arrays (entries are distinct: no duplicate sums)
    pattern = sp.csr_matrix((np.arange(1, nnz + 1, dtype=float), (rr, cc)), shape=(9 * nq + nx, nx))
    perm = pattern.data.astype(np.int64) - 1
    scales = [scale[:, k] for k in (kprev, knext, k_all)]

    def jacobian(x: NDArray[np.float64]) -> sp.csr_matrix:
        z = unpack(x)
        c = z[qq]
        prev = c[:, kprev] - c
        nxt = c[:, knext] - c
        gp = 1j / np.conj(prev)
        gn = 1j / np.conj(nxt)
        a = np.mod(np.angle(prev / nxt), 2 * np.pi)
        # d a_k / d z_{k-1} = G(prev), d z_{k+1} = -G(nxt), d z_k = G(nxt) - G(prev)
        grads = (gp, -gn, gn - gp)
        vals = []
        for sgn in (-weight * (lo_t - a > 0), weight * (a - hi_t > 0)):
            vals += [(sgn * g * sc).ravel() for g, sc in zip(grads, scales)]
        area = quad_signed_areas(z, qq)
        act = (area_min - area > 0) / np.maximum(area_min, 1e-300)
        ga = -0.5j * (c[:, knext] - c[:, kprev])  # d area / d z_k
        vals.append((-act[:, None] * ga * scale).ravel())
        g = np.concatenate(vals)[keep]
        data = np.concatenate([g.real, g.imag, np.full(nx, mu)])[perm]
        return sp.csr_matrix((data, pattern.indices, pattern.indptr), shape=pattern.shape)

    x0 = np.zeros(nx)
    sol = least_squares(
        residuals,
        x0,
        jac=jacobian,
        method="trf",
        tr_solver="lsmr",
        x_scale=1.0,
        max_nfev=max_nfev,
        xtol=xtol,
        ftol=xtol,
        gtol=1e-12,
    )
    z = unpack(sol.x)
    new = quad_angles_deg(z, qq)
    area = quad_signed_areas(z, qq)
    if not (np.all(new >= lo - tol) and np.all(new <= hi + tol) and np.all(area > 0)):
        return None
    shift = np.abs(z[region] - z0[region]) / hr
    before = (float(ang[rq].min()), float(ang[rq].max()))
    return z[region], float(shift.max()), (float(new.min()), float(new.max())), before
