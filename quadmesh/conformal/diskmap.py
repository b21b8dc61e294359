"""The Schwarz–Christoffel disk map ``f : D → Ω`` with ``f(0) = c``.

``f(z) = w_j + C ∫_{z_j}^{z} Π_k (1 − s/z_k)^{β_k} ds`` with interior angles ``α_k π`` and
``β_k = α_k − 1`` (§1.1). This is the map of Lemma 2.2 of Bishop's paper: the disk mesh is
pushed forward by ``f`` and the intervals ``I_j`` are arcs around the prevertices ``z_k``.

Parameter problem (§1.2–§1.3): unknowns ``x ∈ R^{n−1}`` with gaps ``d = 2π softmax([x, 0])``
and ``θ_0 = 0``; equations: ``n − 3`` side-length ratios (log form) and the complex centre
condition ``f(0) = c``. Newton's method with the analytic Jacobian (§1.8 (a)) and a
backtracking line search, started from the subtended angles (star-shaped polygons) or from
the harmonic measure of the sides seen from c (every gap is ``2π ω(c, side)``, estimated by
finite elements, :func:`quadmesh.conformal.center.harmonic_measure`); Levenberg–Marquardt
as the globalised fallback; continuation (affine compression along the principal axis, or
the radial blend of star-shaped polygons, §1.5) as the last resort. Side integrals are
computed in local coordinates (§1.9), see :mod:`quadmesh.conformal.quadrature`.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import asdict, dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
from scipy.spatial import QhullError, cKDTree

from ..errors import ConformalMapError, PolygonError
from ..polygon import as_complex, validate_polygon
from ..progress import Steps, checkpoint, span
from .center import harmonic_measure, inscribed_center
from .quadrature import (
    TWO_PI,
    Configuration,
    QuadratureError,
    beta_log_sum,
    gap_jacobian,
    integrate,
    make_rules,
    plan_integrals,
)
from .series import (
    exp_series,
    horner,
    horner_t,
    log_coefficients,
    log_expansions,
    log_series,
    match_rows,
    unique_rows,
)

__all__ = ["CROWD_RADIUS", "ConformalAccuracy", "DiskMap", "OffsetFunction", "TaylorSeries"]

_SERIES_EPS = 1e-17
#: Reject at once when the harmonic-measure estimate of the smallest gap is below
#: ``min_gap`` times this: the estimate is within a factor ~10 of the truth (measured down
#: to 1e-36), so such a map would be refused after a long solve anyway (a random 120-star
#: with an estimate of 1.7e-19 took 20 s to fail under the former ``min_gap**1.5`` rule).
CROWDING_REJECT = 1e-2
#: What the prevertices a failed solve carries are when they come from the harmonic measure.
ESTIMATE_KIND = "harmonic-measure estimate (the map was not solved)"
#: bytes the parameter problem's dense arrays take per squared vertex count at their peak: the
#: integrals' θ-derivatives (2n + 1 complex rows, 32), the prevertex differences (16), the
#: Jacobian and its LU factors (8 each), the rest made a block of rows at a time. Measured
#: peak growth of :meth:`DiskMap.from_polygon` on smooth stars: 69 at n = 3,000 (107 at
#: n = 2,000, where freed arrays of ≤ 32 MB stay with the allocator); it was 254–290 before
#: the blocks, when a 10,000-vertex star passed 23.8 GB before its solve ended.
DENSE_BYTES_PER_N2 = 80
#: the share of the machine's available memory a solve may plan to take
MEMORY_SHARE = 0.75


def available_memory() -> float | None:
    """Bytes of memory the machine has available now (Linux: ``MemAvailable`` of
    ``/proc/meminfo``; elsewhere the free physical pages), or None where neither is known."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def _memory_check(n: int) -> None:
    """Raise :class:`ConformalMapError` when the parameter problem of an ``n``-gon would need
    more than :data:`MEMORY_SHARE` of the available memory (:data:`DENSE_BYTES_PER_N2` · n²),
    before any of it is allocated: the machine would swap or the process be killed instead."""
    avail = available_memory()
    need = DENSE_BYTES_PER_N2 * float(n) * float(n)
    if avail is None or need <= MEMORY_SHARE * avail:
        return
    fits = int(math.sqrt(MEMORY_SHARE * avail / DENSE_BYTES_PER_N2))
    err = ConformalMapError(
        f"its conformal map needs about {need / 1e9:.3g} GB for {n} vertices (the solve's "
        f"dense arrays grow with the square of the vertex count), more than the "
        f"{avail / 1e9:.3g} GB this machine has available: about {fits} vertices fit. "
        "Simplify the outline (for example shapely's simplify with a tolerance of a small "
        "fraction of its size), or try method='blocks', whose layouts need no conformal map "
        "where one closes"
    )
    err.too_large = True
    raise err


_CHUNK = 262_144
#: entries per block of rows of the parameter problem's Jacobian (:meth:`_Problem.gap_rows`,
#: :func:`_softmax_chain`): the blocks' work arrays stay a few MB whatever n
_GAP_ROWS_ENTRIES = 131_072
#: Series centres closer than this to a prevertex get their coefficients and values in local
#: coordinates (differences from the gaps, values from the nearest prevertex): the far-field
#: tree and the anchor chains work with float64 prevertices, whose ~1e-16 absolute error is a
#: relative error of 1e-16/R in the terms of the nearest prevertices.
CROWD_RADIUS = 1e-8

#: Prevertex series (:meth:`DiskMap._vertex_coefficients`) are kept on the map up to this
#: order (points within half the neighbour distance need at most 64 terms), computed in fixed
#: blocks of this many consecutive prevertices.
_VERTEX_ORDER = 64
_VERTEX_BLOCK = 64

#: Distance to the nearest prevertex below which offsets from it are formed in long double.
_EXACT_NEAR = 1e-6

OffsetFunction = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``off(refs, index) -> points[index] − refs`` (complex128, accurate relative to the result)
for reference points ``refs`` in long double, broadcast against ``index``."""


@dataclass(frozen=True)
class ConformalAccuracy:
    """The accuracy checks of a solved map (all relative, dimensionless).

    ``residual``: max |parameter equations|; ``side_error``: max over all n sides of
    ``|C S_k − (w_{k+1} − w_k)| / max side``; ``center_error``: ``|f(0) − c| / diam``;
    ``boundary_deviation``: max distance of ``f(e^{iθ})`` (5 samples per gap) from its side's
    line / diam; ``round_trip``: max ``|f⁻¹(f(z)) − z|`` at 64 random ``|z| ≤ 0.95``;
    ``min_gap``: the smallest prevertex gap (radians).
    """

    residual: float
    side_error: float
    center_error: float
    boundary_deviation: float
    round_trip: float
    min_gap: float

    def passed(self, tol: float = 1e-10, round_trip_tol: float = 1e-10) -> bool:
        """True when checks 1–4 are below ``tol`` and the round trip below ``round_trip_tol``."""
        return (
            max(self.residual, self.side_error, self.center_error, self.boundary_deviation) < tol
            and self.round_trip < round_trip_tol
        )

    @property
    def worst(self) -> float:
        """Largest of residual, side, centre and boundary errors."""
        return max(self.residual, self.side_error, self.center_error, self.boundary_deviation)

    def as_dict(self) -> dict[str, float]:
        """The checks as a plain dict."""
        return asdict(self)


class _Problem:
    """Polygon data and the residual/Jacobian of the parameter problem."""

    def __init__(
        self, w: np.ndarray, c: complex, m: int, local: bool = True, ref: int | None = None
    ) -> None:
        self.w = w
        self.local = local
        self.c = complex(c)
        n = w.size
        self.n = n
        e_out = np.roll(w, -1) - w
        e_in = w - np.roll(w, 1)
        self.alpha = 1.0 - np.angle(e_out / e_in) / np.pi
        if abs(self.alpha.sum() - (n - 2)) > 1e-8:
            raise PolygonError("vertices are not a counter-clockwise simple polygon (Σα ≠ n−2)")
        self.beta = self.alpha - 1.0
        self.L = np.abs(e_out)
        self.ref = int(np.argmax(self.L)) if ref is None else ref
        drop = {self.ref, *_dropped_sides(e_out, self.ref)}
        self.eqs = np.array([k for k in range(n) if k not in drop], dtype=np.intp)
        self.target = np.log(self.L[self.eqs] / self.L[self.ref])
        self.cref = (w[(self.ref + 1) % n] - w[self.ref]) / (self.c - w[0])
        self.m = m
        self.rules = make_rules(self.beta, m)
        #: the coarse rule of the Jacobian evaluations far from the root (:func:`_newton`)
        self.rules_coarse = make_rules(self.beta, COARSE_NODES) if m > COARSE_NODES else None
        #: when True, evaluations with the Jacobian use ``rules_coarse`` (residual-only
        #: evaluations always use the full rule); set by :func:`_newton` while far from the root
        self.coarse_jacobian = False
        self.nfev = 0
        #: ``(gaps, cfg, S, Ic, half)`` of the last evaluation with the full rule (reused by
        #: :meth:`DiskMap.from_polygon` for the solved map; ``half``: the half-side integrals)
        self.last: tuple[np.ndarray, Configuration, np.ndarray, complex, np.ndarray] | None = None
        #: progress of a solve: each evaluation is one step (:class:`quadmesh.progress.Steps`)
        self.steps: Steps | None = None

    @staticmethod
    def gaps(x: np.ndarray) -> np.ndarray:
        y = np.append(x, 0.0)
        y = y - y.max()
        e = np.exp(y)
        return TWO_PI * e / e.sum()

    def coarse(self, jacobian: bool) -> bool:
        """Whether an evaluation with (or without) the Jacobian uses the coarse rule now."""
        return jacobian and self.coarse_jacobian and self.rules_coarse is not None

    def integrals(self, cfg: Configuration, jacobian: bool):
        """Side integrals S_k (all n), centre integral ∫_{z_0}^0 F, the data of their
        gap-Jacobians ``(plan, H, J)`` for :meth:`gap_rows` (None without the Jacobian; with
        the coarse rule when :meth:`coarse` says so), and the half-side integrals from each
        prevertex z_k to its arc's midpoint."""
        n = self.n
        z = cfg.z
        k = np.arange(n)
        k1 = (k + 1) % n
        h1, h2 = cfg.half_offsets()
        base = np.r_[k, k1, 0]
        end = np.r_[h1, h2, -z[0]]
        plan = plan_integrals(
            cfg, base, np.zeros(2 * n + 1, complex), end, np.ones(2 * n + 1, bool)
        )
        rules = self.rules_coarse if self.coarse(jacobian) else self.rules
        H, J = integrate(cfg, plan, rules, jacobian=jacobian)
        S = H[:n] - H[n : 2 * n]
        return S, H[2 * n], (plan, H, J) if jacobian else None, H[:n]

    def gap_rows(self, cfg: Configuration, jac: tuple, S: np.ndarray, Ic: complex) -> np.ndarray:
        """The parameter equations' Jacobian w.r.t. the gaps, (n − 1) × n: rows ``log|S_k| −
        log|S_ref|`` for the equations' sides, then the real and imaginary parts of the
        centre equation. Made from the integrals' θ-derivatives a block of sides at a time
        (:func:`gap_jacobian` on rows k and n + k: the two half-side integrals of side k), so
        that only the result and one block's work arrays are held besides ``J``."""
        plan, H, J = jac
        n = self.n
        eqs = self.eqs

        def dlog(k: np.ndarray) -> np.ndarray:
            G = gap_jacobian(cfg, plan, H, J, np.r_[k, n + k])
            return (G[: k.size] - G[k.size :]) / S[k, None]

        ref = dlog(np.array([self.ref]))[0]
        gd = np.empty((eqs.size + 2, n))
        step = max(1, _GAP_ROWS_ENTRIES // n)
        for i0 in range(0, eqs.size, step):
            k = eqs[i0 : i0 + step]
            gd[i0 : i0 + k.size] = (dlog(k) - ref[None, :]).real
        dcen = gap_jacobian(cfg, plan, H, J, np.array([2 * n]))[0] / Ic - ref
        gd[-2] = dcen.real
        gd[-1] = dcen.imag
        return gd

    def evaluate(self, x: np.ndarray, jacobian: bool = True):
        """Residual (and Jacobian w.r.t. x) of the n−1 parameter equations."""
        return self.evaluate_gaps(self.gaps(x), jacobian)

    def residual(self, S: np.ndarray, Ic: complex) -> np.ndarray:
        """The n−1 parameter equations from the side integrals ``S`` and the centre integral."""
        r = self.ref
        lS = np.log(np.abs(S))
        cen = np.log(Ic / S[r] * self.cref)
        res = np.r_[lS[self.eqs] - lS[r] - self.target, cen.real, cen.imag]
        if not np.all(np.isfinite(res)):
            raise QuadratureError("non-finite residual")
        return res

    def evaluate_gaps(self, gaps: np.ndarray, jacobian: bool = True):
        """Residual, Jacobian w.r.t. the softmax variables, configuration, S_k, centre integral."""
        self.nfev += 1
        if not np.all(gaps > 0) or not np.all(np.isfinite(gaps)):
            raise QuadratureError("a gap underflowed to zero")
        cfg = Configuration(gaps, self.beta, self.local)
        with self.steps.next() if self.steps is not None else nullcontext():
            S, Ic, jac, half = self.integrals(cfg, jacobian)
        res = self.residual(S, Ic)
        if not self.coarse(jacobian):
            self.last = (gaps.copy(), cfg, S, Ic, half)
        if not jacobian:
            cfg.release()  # (the differences are made again where the configuration is used)
            return res, None, cfg, S, Ic
        gd = self.gap_rows(cfg, jac, S, Ic)
        del jac  # the θ-derivatives (2n + 1 complex rows) go before the chain rule
        cfg.release()
        return res, _softmax_chain(gd, gaps), cfg, S, Ic


def _rotated_solution(
    prob: _Problem, x: np.ndarray, shift: int, final: _Problem, gaps: np.ndarray
) -> tuple[Configuration, np.ndarray, complex, np.ndarray] | None:
    """The configuration, side integrals, centre integral and half-side integrals of
    ``final`` (the polygon in its own vertex order) at ``gaps``, from the last full-rule
    evaluation of ``prob`` (the same polygon rolled by ``shift``) when that was at ``x``;
    None otherwise.

    The two configurations differ by the rotation ``e^{−iφ}`` that takes the rolled problem's
    prevertex of vertex 0 to 1, and ``∫ F ds`` turns with it: ``S_k = e^{−iφ} S'_{k−shift}``.
    Only the centre integral (from the prevertex of vertex 0) is computed anew.
    """
    if prob.last is None or prob.local != final.local:
        return None
    g, cfg_r, S_r, _, half_r = prob.last
    if not np.array_equal(g, _Problem.gaps(x)):
        return None
    n = final.n
    rot = np.conj(cfg_r.z[(n - shift) % n])
    S = np.roll(S_r, shift) * rot
    half = np.roll(half_r, shift) * rot
    cfg = Configuration(gaps, final.beta, final.local)
    plan = plan_integrals(
        cfg, np.zeros(1, np.intp), np.zeros(1, complex), -cfg.z[:1], np.ones(1, bool)
    )
    Ic = complex(integrate(cfg, plan, final.rules)[0][0])
    return cfg, S, Ic, half


def _softmax_chain(gd: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """Derivatives w.r.t. the gaps → w.r.t. x (gaps = 2π softmax([x, 0])), in place in
    ``gd`` (its rows a block at a time: no second n × n array)."""
    s = gd @ gaps
    gd *= gaps[None, :]
    step = max(1, _GAP_ROWS_ENTRIES // max(gaps.size, 1))
    for i0 in range(0, gd.shape[0], step):
        t = np.multiply.outer(s[i0 : i0 + step], gaps)
        t /= TWO_PI
        gd[i0 : i0 + step] -= t
    return gd[:, :-1]


def _dropped_sides(e: np.ndarray, ref: int) -> tuple[int, int]:
    """Two sides whose lengths follow from closure: far from parallel and long.

    Closure ``Σ C S_k = 0`` determines two side lengths only when their directions are
    independent, so the pair maximises ``|sin ∠(e_a, e_b)|·min(|e_a|, |e_b|)`` among the
    longest sides (the reference side excluded).
    """
    n = e.size
    if n == 3:
        return (ref + 1) % 3, (ref + 2) % 3
    L = np.abs(e)
    cand = np.array([k for k in np.argsort(-L)[:24] if k != ref])
    u = e[cand] / L[cand]
    score = np.abs((u[:, None] * np.conj(u[None, :])).imag) * np.minimum(
        L[cand][:, None], L[cand][None, :]
    )
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    return int(cand[i]), int(cand[j])


def _estimated(err: ConformalMapError, gaps: np.ndarray | None, shift: int, kind: str):
    """``err`` carrying the prevertex positions a failed solve had at hand, for a viewer:
    ``err.prevertices`` (unit complex, in the input vertex order, ``θ_0 = 0`` as in a solved
    map) from ``gaps`` (in the solver's rolled order, ``shift`` as in :meth:`DiskMap.from_polygon`)
    and ``err.prevertices_kind`` saying what they are.  Without usable gaps ``err`` is
    returned unchanged."""
    if gaps is None or not np.all(np.isfinite(gaps)) or gaps.size < 3:
        return err
    g = np.roll(np.asarray(gaps, dtype=float), shift)
    g = g * (TWO_PI / g.sum())
    theta = np.concatenate([[0.0], np.cumsum(g[:-1])])
    err.prevertices = np.exp(1j * theta)
    err.prevertices_kind = kind
    return err


def _crowding_message(a: complex, b: complex, center: complex, gap: float, min_gap: float) -> str:
    """Why a polygon is too crowded for its disk map, said in terms of the polygon.

    ``[a, b]`` is the side with the smallest prevertex gap ``gap`` seen from ``center``.
    """
    return (
        f"crowding: seen from the interior point ({center.real:.6g}, {center.imag:.6g}), the "
        f"side from ({a.real:.6g}, {a.imag:.6g}) to ({b.real:.6g}, {b.imag:.6g}) lies so deep "
        f"inside a narrow passage that the conformal map would squeeze it to a gap of about "
        f"{gap:.1e} rad, below the {min_gap:.0e} that double precision resolves.  Narrow "
        "passages are cut off and meshed separately only where their two walls are single "
        "straight edges facing each other; widen or shorten the passage leading to that side, "
        "or draw its walls as long straight edges"
    )


def _initial_gaps(w: np.ndarray, c: complex) -> np.ndarray:
    """Half the angle each side subtends at c plus half uniform (star-shaped), else uniform."""
    n = w.size
    sub = np.angle((np.roll(w, -1) - c) / (w - c))
    if np.all(sub > 0) and abs(sub.sum() - TWO_PI) < 1e-8:
        return 0.5 * sub + 0.5 * TWO_PI / n
    return np.full(n, TWO_PI / n)


def _harmonic_gaps(w: np.ndarray, c: complex) -> np.ndarray | None:
    """Gaps ``2π ω(c, side_k)`` from the finite-element harmonic measure (None if it fails).

    Sides that received no flux get a thousandth of the smallest positive gap; the gaps are
    renormalised to sum to 2π.
    """
    try:
        om = harmonic_measure(w, c)
    except (PolygonError, QhullError, ValueError, ArithmeticError):
        return None
    g = TWO_PI * om
    pos = g[g > 0]
    if pos.size == 0 or not np.all(np.isfinite(g)):
        return None
    g = np.maximum(g, max(1e-3 * float(pos.min()), 1e-300))
    return g * (TWO_PI / g.sum())


def _x_from_gaps(gaps: np.ndarray) -> np.ndarray:
    lg = np.log(gaps)
    return lg[:-1] - lg[-1]


#: Near the root (max |residual| below this) Newton trial points are evaluated without the
#: Jacobian, and the last Jacobian's LU factors are reused (chord steps) while each step
#: shrinks |r| by CHORD_RATE or more: a residual-only evaluation costs ~60 % of one with the
#: Jacobian, and the final Jacobian at the converged point is never formed. Measured at
#: n = 1000 (smooth star): residuals 4e-2, 8e-5, 5e-7, 1e-11, 2e-15 — the last two now
#: residual-only.
CHORD_BELOW = 1e-5
CHORD_RATE = 0.05
#: Far from the root (max |residual| at or above COARSE_BELOW) the evaluations that form the
#: Jacobian use a COARSE_NODES-point rule instead of the full one: its relative error (1e-10
#: on the L-shape, 1e-12 on smooth 1000-gons, against 1e-15 with 12 nodes) is far below the
#: residuals of those iterates, and it halves their quadrature. Every residual-only
#: evaluation, and so every converged residual, uses the full rule.
COARSE_NODES = 6
COARSE_BELOW = 1e-5


def _factor(J: np.ndarray):
    """LU factors of J, or None when J is exactly singular (then least squares is used)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LinAlgWarning)
        lu, piv = lu_factor(J, check_finite=False)
    d = np.diag(lu)
    if not np.all(np.isfinite(lu)) or np.any(d == 0):
        return None, J
    return (lu, piv), None  # (J itself only for the least-squares fallback)


def _solve(fac, rhs: np.ndarray) -> np.ndarray:
    lu, J = fac
    if lu is None:
        return np.linalg.lstsq(J, rhs, rcond=None)[0]
    return lu_solve(lu, rhs, check_finite=False)


def _newton(prob: _Problem, x0: np.ndarray, tol: float, maxit: int = 50):
    """Damped Newton with analytic Jacobian. Returns (x, max|res|, iterations, ok).

    Backtracking (Armijo) line search on |r|. While max|r| ≥ COARSE_BELOW the evaluations
    that form the Jacobian use the coarse rule (residual and Jacobian alike); below it every
    evaluation uses the full rule, and the returned residual always does. Once
    max|r| < CHORD_BELOW the trial points are evaluated without the Jacobian and the
    factored Jacobian is reused (chord iteration) as long as every step contracts |r| by
    CHORD_RATE; otherwise the Jacobian is re-formed at the current point. Near the rounding
    floor (max|r| < 1e-3 tol) only the full step is tried.
    """
    x = x0.copy()
    saved = prob.coarse_jacobian
    prob.coarse_jacobian = True
    try:
        return _newton_loop(prob, x, tol, maxit)
    finally:
        prob.coarse_jacobian = saved


def _newton_loop(prob: _Problem, x: np.ndarray, tol: float, maxit: int):
    try:
        rc = prob.coarse(True)  # r comes from the coarse rule
        r, J, *_ = prob.evaluate(x)
    except QuadratureError:
        return x, math.inf, 0, False
    fac = _factor(J)
    J = None  # (its factors are kept: one n × n array between evaluations)
    fresh = True  # fac holds the Jacobian at x
    nr = float(np.linalg.norm(r))
    it = 0
    for it in range(1, maxit + 1):  # noqa: B007 (it is returned)
        checkpoint()
        rmax = float(np.max(np.abs(r)))
        if rmax < COARSE_BELOW:
            prob.coarse_jacobian = False
        if rmax < 5e-14:
            if not rc:
                break
            try:
                r = prob.evaluate(x, jacobian=False)[0]
            except QuadratureError:
                break
            rc, nr = False, float(np.linalg.norm(r))
            continue
        cheap = rmax < CHORD_BELOW
        dx = _solve(fac, -r)
        big = np.max(np.abs(dx))
        if big > 5.0:
            dx *= 5.0 / big
        if cheap and not fresh:
            # chord step with the Jacobian of an earlier iterate
            try:
                r2 = prob.evaluate(x + dx, jacobian=False)[0]
                n2 = float(np.linalg.norm(r2))
            except QuadratureError:
                n2 = math.inf
            if n2 < CHORD_RATE * nr:
                x = x + dx
                r, nr, rc = r2, n2, False
                continue
            try:
                rc = prob.coarse(True)
                r, J, *_ = prob.evaluate(x)
            except QuadratureError:
                break
            nr = float(np.linalg.norm(r))
            fac = _factor(J)
            J = None
            fresh = True
            dx = _solve(fac, -r)
            big = np.max(np.abs(dx))
            if big > 5.0:
                dx *= 5.0 / big
        t = 1.0
        tmin = 1.0 if rmax < 1e-3 * tol else 1.0 / 1024
        accepted = False
        r2c = prob.coarse(not cheap)
        while t >= tmin:
            J2 = None  # (a rejected trial's Jacobian is not held through the next one)
            try:
                r2, J2, *_ = prob.evaluate(x + t * dx, jacobian=not cheap)
                n2 = float(np.linalg.norm(r2))
                if n2 < (1.0 - 1e-4 * t) * nr:
                    accepted = True
                    break
            except QuadratureError:
                pass
            t *= 0.5
        if not accepted:
            if not rc:
                break
            # |r| came from the coarse rule: start again from the full rule at x
            prob.coarse_jacobian = False
            try:
                r, J, *_ = prob.evaluate(x)
            except QuadratureError:
                break
            rc, nr = False, float(np.linalg.norm(r))
            fac = _factor(J)
            J = None
            fresh = True
            continue
        x = x + t * dx
        r, nr, rc = r2, n2, r2c
        if cheap:
            fresh = False
        else:
            fac = _factor(J2)
            J2 = None
            fresh = True
    res = float(np.max(np.abs(r)))
    if rc and res < tol:
        # the coarse rule's residual is not a converged one
        try:
            res = float(np.max(np.abs(prob.evaluate(x, jacobian=False)[0])))
        except QuadratureError:
            res = math.inf
    return x, res, it, res < tol


def _levenberg_marquardt(prob: _Problem, x0: np.ndarray, tol: float, maxfev: int = 200):
    """Levenberg–Marquardt with the analytic Jacobian: the globalised fallback of :func:`_newton`.

    The step ``dx(λ) = argmin |J dx + r|² + λ|dx|²`` comes from one SVD of J per accepted
    iterate (rejected trials reuse it). λ follows the gain ratio (Nielsen's update); a trial
    point where the quadrature fails counts as a rejected step. As λ → 0 the step becomes
    Newton's, so the final convergence is quadratic. Stops after ``maxfev`` residual
    evaluations, or when 10 accepted steps reduce ``|r|²`` by less than 1 % (a local minimum
    of the merit function). Returns (x, max|res|, accepted steps, ok).
    """
    x = x0.copy()
    try:
        r, J, *_ = prob.evaluate(x)
    except QuadratureError:
        return x, math.inf, 0, False
    f = float(r @ r)
    U, s, Vt = np.linalg.svd(J)
    lam = 1e-3 * float(s[0]) ** 2
    nu = 2.0
    it = 0
    fev = 1
    history = [f]
    while fev < maxfev and np.max(np.abs(r)) >= 5e-14:
        checkpoint()
        g = U.T @ r
        accepted = False
        while not accepted and fev < maxfev:
            q = s / (s * s + lam)
            dx = -(Vt.T @ (q * g))
            big = np.max(np.abs(dx))
            if big > 5.0:
                dx *= 5.0 / big
            pred = f - float(np.sum((g + s * (Vt @ dx)) ** 2))
            rho = -1.0
            if pred > 0:
                fev += 1
                try:
                    r2, J2, *_ = prob.evaluate(x + dx)
                    f2 = float(r2 @ r2)
                    rho = (f - f2) / pred
                except QuadratureError:
                    pass
            if rho > 1e-4:
                accepted = True
                x = x + dx
                r, J, f = r2, J2, f2
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
            else:
                lam *= nu
                nu *= 2.0
                if lam > 1e20 * float(s[0]) ** 2 + 1e-300:
                    break
        if not accepted:
            break
        it += 1
        history.append(f)
        if len(history) > 10 and f > 0.99 * history[-11] and f > tol * tol:
            break
        U, s, Vt = np.linalg.svd(J)
    res = float(np.max(np.abs(r)))
    return x, res, it, res < tol


def _principal_frame(w: np.ndarray) -> tuple[complex, complex, float]:
    """Centroid, unit major axis and elongation sqrt(λ_max/λ_min) of the polygon's area."""
    x, y = w.real, w.imag
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cr = x * yn - xn * y
    A = cr.sum() / 2
    cx = ((x + xn) * cr).sum() / (6 * A)
    cy = ((y + yn) * cr).sum() / (6 * A)
    x, y, xn, yn = x - cx, y - cy, xn - cx, yn - cy
    cr = x * yn - xn * y
    sxx = ((x * x + x * xn + xn * xn) * cr).sum() / 12
    syy = ((y * y + y * yn + yn * yn) * cr).sum() / 12
    sxy = ((x * yn + 2 * x * y + 2 * xn * yn + xn * y) * cr).sum() / 24
    lam, vec = np.linalg.eigh(np.array([[sxx, sxy], [sxy, syy]]))
    u = complex(vec[0, 1], vec[1, 1])
    return complex(cx, cy), u, float(np.sqrt(max(lam[1], 1e-300) / max(lam[0], 1e-300)))


def _compress(w: np.ndarray, c: complex, p0: complex, u: complex, s: float):
    v = (w - p0) * np.conj(u)
    vc = (c - p0) * np.conj(u)
    return p0 + u * (s * v.real + 1j * v.imag), p0 + u * (s * vc.real + 1j * vc.imag)


class TaylorSeries:
    """Taylor series of ``f`` about an interior centre ``c``.

    ``radius`` is ``R = min_k |z_k − c|``; the series converges for ``|t| < R`` with error
    about ``(|t|/R)^order``. Points are passed as offsets ``t = z − c``.
    """

    def __init__(self, center: complex, radius: float, f_center: complex, coef: np.ndarray) -> None:
        self.center = complex(center)
        self.radius = float(radius)
        self.f_center = complex(f_center)
        self.order = coef.size - 1
        self._g = coef  # f'(c + Rτ) = Σ g̃_m τ^m

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """``f(c + t)`` for offsets ``t`` (vectorised, Horner)."""
        t = np.asarray(t, dtype=np.complex128)
        tau = t / self.radius
        m = np.arange(self.order + 1)
        fc = np.r_[0.0, self.radius * self._g / (m + 1)]
        acc = np.full(tau.shape, fc[-1], dtype=np.complex128)
        for k in range(fc.size - 2, -1, -1):
            acc = acc * tau + fc[k]
        return self.f_center + acc

    def derivative(self, t: np.ndarray) -> np.ndarray:
        """``f'(c + t)`` for offsets ``t``."""
        tau = np.asarray(t, dtype=np.complex128) / self.radius
        acc = np.full(tau.shape, self._g[-1], dtype=np.complex128)
        for k in range(self._g.size - 2, -1, -1):
            acc = acc * tau + self._g[k]
        return acc


class DiskMap:
    """A solved Schwarz–Christoffel map of the unit disk onto a polygon, ``f(0) = center``.

    Build with :meth:`from_polygon`. Attributes: ``vertices`` (complex, CCW), ``prevertices``
    (unit complex, same order), ``theta`` (prevertex angles, ``theta[0] = 0``), ``gaps``
    (``θ_{k+1} − θ_k`` with full relative precision), ``angles`` (interior angles / π),
    ``beta``, ``constant`` (C), ``center``, ``residual``, ``iterations``, ``solve_time``,
    ``continuation_steps``.

    Under crowding use ``gaps`` rather than differences of ``theta``/``prevertices`` (which
    carry ~1e-16 absolute error), and :meth:`map_near_vertex` (local offsets from a
    prevertex) for points near a crowded cluster. ``theta_ld``/``prevertices_ld`` are the
    angles summed from the gaps in long double (≈1e-19 absolute error); points that complex128
    cannot resolve are evaluated with :meth:`map_clusters` given exact offsets.
    Evaluation: ``__call__`` (series based, fast), :meth:`direct` (quadrature),
    :meth:`derivative` (closed form), :meth:`taylor`, :meth:`map_clusters`, :meth:`inverse`;
    checks: :meth:`accuracy`.
    """

    def __init__(
        self,
        prob: _Problem,
        gaps: np.ndarray,
        iterations: int,
        steps: int,
        solved: tuple[Configuration, np.ndarray, complex, np.ndarray] | None = None,
    ) -> None:
        self.vertices = prob.w.copy()
        self.n = prob.n
        self.center = prob.c
        self.angles = prob.alpha.copy()
        self.beta = prob.beta.copy()
        self.iterations = iterations
        self.continuation_steps = steps
        self.solve_time = 0.0
        self._prob = prob
        if solved is None:
            res, _, cfg, S, Ic = prob.evaluate_gaps(gaps, jacobian=False)
            half = prob.last[4] if prob.last is not None and prob.last[1] is cfg else None
        else:
            # the configuration and integrals of these gaps, already at hand from the solve
            cfg, S, Ic, half = solved
            res = prob.residual(S, Ic)
        #: ∫ F from each prevertex z_k to the midpoint of its arc (the boundary check's
        #: middle samples), or None
        self._half = half
        self.residual = float(np.max(np.abs(res)))
        self._cfg = cfg
        self.gaps = cfg.gaps.copy()
        self.theta = cfg.theta.copy()
        self.prevertices = cfg.z.copy()
        # the prevertex angles summed from the gaps in extended precision (≈1e-19 absolute):
        # reference points for offsets of points that float64 cannot resolve (map_clusters)
        self.theta_ld = np.concatenate(
            [np.zeros(1, np.longdouble), np.cumsum(cfg.gaps[:-1].astype(np.longdouble))]
        )
        self.prevertices_ld = np.exp(1j * self.theta_ld)
        r = prob.ref
        self.constant = complex((prob.w[(r + 1) % prob.n] - prob.w[r]) / S[r])
        self._S = S
        self._Ic = Ic
        self._table: tuple[cKDTree, np.ndarray, np.ndarray] | None = None
        e = self.vertices - self.center
        self._star = bool(
            np.all((np.conj(np.roll(self.vertices, -1) - self.vertices) * e).imag < 0)
        )
        self._diam = float(np.max(np.abs(self.vertices[:, None] - self.vertices[None, :])))
        self._accuracy: ConformalAccuracy | None = None
        #: prevertex series by blocks (:meth:`_vertex_coefficients`): blocks done, coefficients
        self._vertex_cache: tuple[np.ndarray, np.ndarray] | None = None

    prevertex_angles = property(lambda self: self.theta, doc="Alias of ``theta``.")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_polygon(
        cls,
        vertices: object,
        center: complex | None = None,
        tol: float = 1e-10,
        *,
        min_gap: float = 1e-14,
        nodes: int = 12,
        continuation: bool | None = None,
        check: bool = True,
        local: bool = True,
    ) -> DiskMap:
        """Solve the parameter problem for a CCW polygon with ``f(0) = center``.

        ``vertices``: (n, 2) floats or complex, counter-clockwise, no repeated points.
        ``center``: interior point (default: :func:`inscribed_center`). ``tol``: bound for the
        checks of §1.7 (the round trip must also be < 1e-12). ``min_gap``: prevertex gaps below
        this are rejected as crowding. Solve order: (1) n < 48, star-shaped about the centre
        and elongation ≤ 6: Newton from the subtended angles; (2) otherwise, or if (1) fails:
        the gaps ``2π ω(c, side_k)`` from the finite-element harmonic measure — if its
        smallest gap is below ``min_gap·CROWDING_REJECT`` (1e-2) the polygon is rejected as
        crowded at once (the estimate is within about a decade of the truth even at 1e-36) —
        then Newton
        and, if that stalls, Levenberg–Marquardt from it; (3) continuation: the affine family
        (polygon compressed along its major axis to elongation 1.5, then stretched back)
        and, for star-shaped polygons, the radial blend from a nearly regular polygon.
        ``continuation``: None = automatic as above, True = continuation only, False = never.
        ``local=False`` computes prevertex differences from ``exp(iθ)`` as the prototype did
        (for comparison only; it loses precision under crowding).
        Raises :class:`ConformalMapError` with the reason (crowding with the measured or
        estimated gap, no convergence with the residual and gaps) and :class:`PolygonError`
        for unusable input.
        """
        t0 = time.perf_counter()
        w = as_complex(vertices)
        poly = validate_polygon(w)
        if poly.n != w.size or poly.reversed_input:
            raise PolygonError(
                "DiskMap needs distinct counter-clockwise vertices without a closing point"
            )
        w = poly.z.copy()
        _memory_check(w.size)
        if center is None:
            center = inscribed_center(w)[0]
        center = complex(center)
        import shapely

        if not shapely.Polygon(np.column_stack([w.real, w.imag])).contains(
            shapely.Point(center.real, center.imag)
        ):
            raise PolygonError(f"center {center} is not inside the polygon")
        # Solve with the vertices rolled so that the longest side is the last one: its gap
        # closes the circle and is the softmax reference, and a large closing gap keeps the
        # Jacobian free of cancellation under crowding.
        n = w.size
        shift = (int(np.argmax(np.abs(np.roll(w, -1) - w))) + 1) % n
        wr = np.roll(w, -shift)
        prob = _Problem(wr, center, nodes, local, ref=n - 1)
        prob.steps = Steps(start=0.1)
        p0, u, elong = _principal_frame(w)
        star = _star_shaped(wr, center)
        forced = continuation is True
        ok = False
        its = 0
        steps = 0
        res = math.inf
        x = x1 = _x_from_gaps(_initial_gaps(wr, center))
        if not forced and star and (elong <= 6.0 or continuation is False) and n < 48:
            # small star-shaped polygons: subtended angles about c (for n ≥ 48 the
            # harmonic-measure guess halves the Newton steps, measured 22 s → 10 s at n = 1000)
            x1, res, its, ok = _newton(prob, x, tol)
        est = None
        if not ok:
            # harmonic-measure guess (§1.5): the gap of side k is 2π ω(c, side_k)
            with span(0.0, 0.1):
                # from the polygon in its own order (the decomposition has usually computed
                # the same measure already), rolled like wr
                est = _harmonic_gaps(w, center)
                if est is not None:
                    est = np.roll(est, -shift)
        if est is not None:
            est_gap = float(np.min(est))
            if 0.0 < min_gap < 1.0 and est_gap < min_gap * CROWDING_REJECT:
                k = int(np.argmin(est))
                raise _estimated(
                    ConformalMapError(
                        _crowding_message(wr[k], wr[(k + 1) % n], center, est_gap, min_gap)
                    ),
                    est,
                    shift,
                    ESTIMATE_KIND,
                )
            if not forced:
                xe = _x_from_gaps(est)
                x1, res, k, ok = _newton(prob, xe, tol)
                its += k
                if not ok:
                    x1, res, k, ok = _levenberg_marquardt(prob, xe, tol, maxfev=60)
                    its += k
        elif not ok and not forced:
            x1, res, k, ok = _levenberg_marquardt(prob, x, tol, maxfev=60)
            its += k
        if ok:
            x = x1
        families = []
        if continuation is not False:
            if elong > 1.5:
                s0 = 1.5 / elong
                families.append(lambda t: _compress(wr, center, p0, u, s0 ** (1.0 - t)))
            if star:
                families.append(lambda t: _radial_blend(wr, center, t))
        for family in families:
            if ok:
                break
            x1, res, its2, steps2, ok = _continue(prob, family, tol, min_gap)
            its += its2
            steps += steps2
            if ok:
                x = x1
        if not ok:
            gmin = float(np.min(_Problem.gaps(x1)))
            if est is not None and float(np.min(est)) < min_gap:
                why = (
                    f"crowding: estimated smallest prevertex gap {float(np.min(est)):.1e} "
                    f"< min_gap {min_gap:.0e}; last residual {res:.1e}"
                )
            elif gmin < min_gap:
                why = f"crowding: prevertex gap {gmin:.2e} < min_gap {min_gap:.0e}"
            else:
                why = f"no convergence: residual {res:.2e}, smallest gap {gmin:.1e}"
                if est is not None:
                    why += f", estimated smallest gap {float(np.min(est)):.1e}"
            err = ConformalMapError(
                f"Schwarz–Christoffel parameter problem failed ({why}, n={prob.n})"
            )
            if est is not None:
                raise _estimated(err, est, shift, ESTIMATE_KIND)
            raise _estimated(err, _Problem.gaps(x1), shift, "last solver iterate (not converged)")
        final = _Problem(w, center, nodes, local)
        final.nfev = prob.nfev
        final.steps = prob.steps
        gaps = np.roll(_Problem.gaps(x), shift)
        dm = cls(final, gaps, its, steps, _rotated_solution(prob, x, shift, final, gaps))
        final.steps = None
        gmin = float(np.min(dm.gaps))
        if gmin < min_gap:
            k = int(np.argmin(dm.gaps))
            err = ConformalMapError(_crowding_message(w[k], w[(k + 1) % n], center, gmin, min_gap))
            raise _estimated(err, dm.gaps, 0, "solved map, rejected (gap below resolution)")
        dm.solve_time = time.perf_counter() - t0
        if check:
            with prob.steps.next():
                acc = dm.accuracy()
            if not acc.passed(tol):
                err = ConformalMapError(
                    "the conformal map of this part of the polygon failed its accuracy checks: "
                    + ", ".join(f"{k}={v:.1e}" for k, v in acc.as_dict().items())
                    + (" — crowding" if acc.min_gap < 1e-8 else "")
                )
                raise _estimated(err, dm.gaps, 0, "solved map, failed its accuracy checks")
        return dm

    # ------------------------------------------------------------------ evaluation
    def derivative(self, z: np.ndarray) -> np.ndarray:
        """``f'(z) = C Π_k (1 − z/z_k)^{β_k}`` (closed form, §1.6), vectorised."""
        z = np.asarray(z, dtype=np.complex128)
        flat = z.ravel()
        out = np.empty(flat.shape, dtype=np.complex128)
        step = max(1, _CHUNK // self.n)
        zc = self._cfg.zc
        with np.errstate(divide="ignore"):
            for i in range(0, flat.size, step):
                checkpoint()
                B = 1.0 - flat[i : i + step, None] * zc[None, :]
                out[i : i + step] = self.constant * np.exp(beta_log_sum(B, self.beta))
        return out.reshape(z.shape)

    def _nearest(
        self,
        z: np.ndarray,
        off: OffsetFunction | None = None,
        idx: np.ndarray | None = None,
        ld: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Nearest prevertex ``k`` of every point and ``d = z − z_k``.

        ``z`` (complex128) locates the points. With ``off`` (exact offsets of points that ``z``
        only rounds, see :meth:`map_clusters`) or ``ld``, ``d`` is taken from the long double
        prevertices :attr:`prevertices_ld` (``off(refs, idx)``, or ``z − refs`` in long double)
        with full relative accuracy for points within ``1e-6`` of a prevertex; otherwise from
        the float64 :attr:`prevertices` (so that ``f(prevertices[k]) = w_k`` exactly). Four
        candidates around the float64 position are compared, so a rounding of ``z`` or
        ``theta`` far above a crowded gap cannot pick the wrong prevertex.
        """
        z = np.asarray(z, dtype=np.complex128).ravel()
        n = self.n
        if z.size == 0:
            return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.complex128)
        phi = np.mod(np.angle(z), TWO_PI)
        i = np.searchsorted(self.theta, phi)
        cand = np.mod(i[:, None] + np.arange(-2, 2)[None, :], n)
        D = z[:, None] - self.prevertices[cand]
        rows = np.arange(z.size)
        j = np.argmin(np.abs(D), axis=1)
        k, d = cand[rows, j], D[rows, j]
        if off is None and not ld:
            return k, d
        # long double offsets where the float64 ones lose digits (further away, the two
        # differ by ~1e-16 absolute, i.e. < 1e-10 relative)
        r = np.flatnonzero(np.abs(d) < _EXACT_NEAR)
        if r.size == 0:
            return k, d
        c = cand[r]
        refs = self.prevertices_ld[c]
        if off is None:
            De = (z[r].astype(np.clongdouble)[:, None] - refs).astype(np.complex128)
        else:
            ids = np.arange(z.size) if idx is None else np.asarray(idx)
            De = np.asarray(off(refs, np.broadcast_to(ids[r][:, None], c.shape)))
            De = De.astype(np.complex128).reshape(c.shape)
        je = np.argmin(np.abs(De), axis=1)
        re = np.arange(r.size)
        k[r], d[r] = c[re, je], De[re, je]
        return k, d

    def direct(self, z: np.ndarray) -> np.ndarray:
        """Forward map by compound Gauss–Jacobi quadrature (§1.6), from the nearest
        prevertex or from 0, whichever is closer."""
        z = np.asarray(z, dtype=np.complex128)
        flat = z.ravel()
        k, d = self._nearest(flat)
        from_pv = np.abs(d) < np.abs(flat)
        base = np.where(from_pv, k, self.n)
        end = np.where(from_pv, d, flat)
        plan = plan_integrals(self._cfg, base, np.zeros(flat.size, complex), end, from_pv)
        H, _ = integrate(self._cfg, plan, self._prob.rules)
        start = np.where(from_pv, self.vertices[k], self.center)
        return (start + self.constant * H).reshape(z.shape)

    def _interior_coefficients(self, c: np.ndarray, order: int):
        """Scaled coefficients of f' about centres c (K,), and their radii."""
        K = c.size
        g = np.empty((K, order + 1), dtype=np.complex128)
        R = np.empty(K)
        step = max(1, _CHUNK // self.n)
        zc = self._cfg.zc
        for i in range(0, K, step):
            checkpoint()
            cc = c[i : i + step]
            A = self.prevertices[None, :] - cc[:, None]
            Ri = np.min(np.abs(A), axis=1)
            B = 1.0 - cc[:, None] * zc[None, :]
            fp = self.constant * np.exp(beta_log_sum(B, self.beta))
            b = log_coefficients(Ri[:, None] / A, self.beta, order)
            g[i : i + step] = exp_series(b, fp)
            R[i : i + step] = Ri
        return g, R

    def _vertex_coefficients(self, ks: np.ndarray, order: int) -> np.ndarray:
        """Scaled coefficients ``g_0..g_order`` of G_k(z_k + R_k τ) for prevertices ks.

        Up to :data:`_VERTEX_ORDER` they are computed once per block of
        :data:`_VERTEX_BLOCK` consecutive prevertices at that order and kept on the map (the
        push-forward of the vertices and of the triangle centres, the accuracy check and the
        inverse evaluate the same prevertex series); a series of lower order is a prefix
        (``g_m`` depends on ``b_1..b_m`` only). The blocks are fixed, so the values do not
        depend on which points were evaluated before (the same bits in a worker process
        that receives the map with or without them).
        """
        if order > _VERTEX_ORDER:
            return self._vertex_series(ks, order)
        if self._vertex_cache is None:
            nb = -(-self.n // _VERTEX_BLOCK)
            self._vertex_cache = (
                np.zeros(nb, bool),
                np.empty((self.n, _VERTEX_ORDER + 1), dtype=np.complex128),
            )
        done, coef = self._vertex_cache
        blocks = np.unique(np.asarray(ks) // _VERTEX_BLOCK)
        for b in blocks[~done[blocks]]:
            checkpoint()
            idx = np.arange(b * _VERTEX_BLOCK, min((b + 1) * _VERTEX_BLOCK, self.n))
            coef[idx] = self._vertex_series(idx, _VERTEX_ORDER)
            done[b] = True
        return coef[ks, : order + 1]

    def _vertex_series(self, ks: np.ndarray, order: int) -> np.ndarray:
        """Scaled coefficients of G_k(z_k + R_k τ) for prevertices ks (computed anew)."""
        E = self._cfg.E[ks]
        Rk = self._cfg.nn[ks]
        with np.errstate(divide="ignore", invalid="ignore"):
            q = Rk[:, None] / E
            B = E * self._cfg.zc[None, :]
        rows = np.arange(ks.size)
        q[rows, ks] = 0.0
        B[rows, ks] = 1.0
        g0 = np.exp(beta_log_sum(B, self.beta))
        return exp_series(log_coefficients(q, self.beta, order), g0)

    @staticmethod
    def _order(ratio: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore"):
            o = np.ceil(np.log(_SERIES_EPS) / np.log(np.maximum(ratio, 1e-3)))
        return (np.clip(o, 8, 80).astype(int) + 7) // 8 * 8

    def _eval_vertex(self, k, t, derivative):
        """Vertex series for points z_k + t (|t| ≤ nn_k/2)."""
        out_f = np.empty(t.size, dtype=np.complex128)
        out_d = np.empty(t.size, dtype=np.complex128) if derivative else None
        ks, rows = np.unique(k, return_inverse=True)
        Rk = self._cfg.nn[ks]
        ratio = np.zeros(ks.size)
        np.maximum.at(ratio, rows, np.abs(t) / Rk[rows])
        orders = self._order(ratio)
        zk = self.prevertices
        for o in np.unique(orders):
            checkpoint()
            sel = np.flatnonzero(orders == o)
            g = self._vertex_coefficients(ks[sel], int(o))
            remap = np.full(ks.size, -1)
            remap[sel] = np.arange(sel.size)
            pts = np.flatnonzero(remap[rows] >= 0)
            r2 = remap[rows[pts]]
            kk = ks[sel][r2]
            tau = t[pts] / Rk[sel][r2]
            u = -t[pts] * np.conj(zk[kk])
            al = self.angles[kk]
            m = np.arange(o + 1)
            ga = g / (self.angles[ks[sel]][:, None] + m[None, :])
            with np.errstate(divide="ignore", invalid="ignore"):
                lu = np.log(u)
                ua = np.where(u == 0, 0.0, np.exp(al * lu))
            out_f[pts] = self.vertices[kk] + self.constant * (-zk[kk]) * ua * horner(ga, r2, tau)
            if derivative:
                with np.errstate(divide="ignore", invalid="ignore"):
                    ub = np.exp((al - 1.0) * lu)
                out_d[pts] = self.constant * ub * horner(g, r2, tau)
        return out_f, out_d

    def _evaluate(self, z: np.ndarray, derivative: bool):
        """f (and f') at points of the closed disk: prevertex series within half the
        neighbour distance of a prevertex, Taylor series about small clusters elsewhere."""
        flat = np.asarray(z, dtype=np.complex128).ravel()
        return self._evaluate_grouped(flat, None, None, derivative)

    @staticmethod
    def _offsets(
        flat: np.ndarray, off: OffsetFunction | None, refs: np.ndarray, idx: np.ndarray
    ) -> np.ndarray:
        """``flat[idx] − refs`` (refs: complex128 points), exactly when ``off`` is given."""
        if off is None:
            return flat[idx] - refs
        return np.asarray(off(np.asarray(refs).astype(np.clongdouble), idx), dtype=np.complex128)

    def _evaluate_grouped(self, flat, cid, centers, derivative, off=None):
        """Shared evaluator: points in clusters ``cid`` whose centre series covers them (all
        points within ``R/2`` of the centre, ``R`` the distance to the prevertices) use that
        series; every other point uses a prevertex series or a dyadic cell (§1.10).

        ``off`` (see :meth:`map_clusters`) gives the exact offsets of the points from the
        centres and prevertices; ``flat`` then only locates them."""
        f = np.empty(flat.size, dtype=np.complex128)
        fp = np.empty(flat.size, dtype=np.complex128) if derivative else None
        if flat.size == 0:
            return f, fp
        if cid is None:
            good_pt = np.zeros(flat.size, bool)
            gcen = np.empty(0, complex)
            grho = np.empty(0)
            gid = np.empty(0, np.intp)
            tg = np.empty(0, complex)
        else:
            _, d0 = self._nearest(centers, ld=off is not None)
            R = np.abs(d0)
            checkpoint()
            t_all = self._offsets(flat, off, centers[cid], np.arange(flat.size))
            checkpoint()
            rho = np.zeros(centers.size)
            np.maximum.at(rho, cid, np.abs(t_all))
            good = (rho <= 0.5 * R) & (np.abs(centers) <= 1.0)
            used = np.zeros(centers.size, bool)
            used[cid] = True
            gidx = np.flatnonzero(good & used)
            remap = np.full(centers.size, -1)
            remap[gidx] = np.arange(gidx.size)
            good_pt = good[cid]
            gcen = centers[gidx]
            grho = np.maximum(rho[gidx], 1e-300)
            gid = remap[cid[good_pt]]
            tg = t_all[good_pt]
        rest = np.flatnonzero(~good_pt)
        checkpoint()
        k, d = self._nearest(flat[rest], off, rest)
        vert = np.abs(d) <= 0.5 * self._cfg.nn[k]
        iv = rest[vert]
        checkpoint()
        if iv.size:
            ff, dd = self._eval_vertex(k[vert], d[vert], derivative)
            f[iv] = ff
            if derivative:
                fp[iv] = dd
        ic = rest[~vert]
        checkpoint()
        ccid, ccen, crho = _dyadic_cells(flat[ic], np.abs(d[~vert]), self)
        checkpoint()
        tc = self._offsets(flat, off, ccen[ccid], ic)
        checkpoint()
        pts = np.r_[np.flatnonzero(good_pt), ic]
        allcid = np.r_[gid, ccid + gcen.size]
        ff, dd = self._eval_clusters(
            np.r_[tg, tc], allcid, np.r_[gcen, ccen], np.r_[grho, crho], derivative, off is not None
        )
        f[pts] = ff
        if derivative:
            fp[pts] = dd
        return f, fp

    def _eval_clusters(self, t, cid, cen, rho, derivative, ld=False):
        """f (and f') at the points ``cen[cid] + t`` from the Taylor series about their
        cluster centre (all points of cluster i within ``rho[i] ≤ R_i/2`` of ``cen[i]``).

        Centres within :data:`CROWD_RADIUS` of a prevertex use :meth:`_eval_clusters_local`
        (local coordinates, offsets from the long double prevertices if ``ld``), all others
        :meth:`_eval_clusters_tree`."""
        out_f = np.empty(t.size, dtype=np.complex128)
        out_d = np.empty(t.size, dtype=np.complex128) if derivative else None
        K = cen.size
        if K == 0:
            return out_f, out_d
        kk, s = self._nearest(cen, ld=ld)
        checkpoint()
        R = np.abs(s)
        crowd = (R < CROWD_RADIUS) & (R > 0.0)
        for sel, local in ((np.flatnonzero(~crowd), False), (np.flatnonzero(crowd), True)):
            if sel.size == 0:
                continue
            remap = np.full(K, -1)
            remap[sel] = np.arange(sel.size)
            pts = np.flatnonzero(remap[cid] >= 0)
            if pts.size == 0:
                continue
            if local:
                ff, dd = self._eval_clusters_local(
                    t[pts], remap[cid[pts]], kk[sel], s[sel], rho[sel], derivative
                )
            else:
                ff, dd = self._eval_clusters_tree(
                    t[pts], remap[cid[pts]], cen[sel], rho[sel], derivative
                )
            out_f[pts] = ff
            if derivative:
                out_d[pts] = dd
        return out_f, out_d

    def _eval_clusters_local(self, t, cid, kc, s, rho, derivative):
        """Cluster series about centres ``c = z_kc + s`` next to crowded prevertices, in
        local coordinates: ``z_j − c = (z_j − z_kc) − s`` with the prevertex differences from
        the gaps (Configuration.E), coefficients of log f' by direct sums over all prevertices
        (:func:`~quadmesh.conformal.series.log_coefficients`, O(n·order) per centre), and
        ``f(c)`` from prevertex ``kc`` (:meth:`map_near_vertex`: prevertex series or compound
        quadrature in local coordinates). Everything is accurate relative to the distance
        from the centre to the prevertices, so clusters of 1e-15 next to gaps of 1e-13 keep
        their shape (§1.9, §1.10)."""
        K = s.size
        R = np.abs(s)
        rho = np.maximum(rho, 0.25 * R)
        S = 2.0 * rho
        orders = np.maximum(self._order(rho / R), 32)
        fc = np.asarray(self.map_near_vertex(kc, s))
        out_f = np.empty(t.size, dtype=np.complex128)
        out_d = np.empty(t.size, dtype=np.complex128) if derivative else None
        zc = self._cfg.zc
        step = max(1, _CHUNK // self.n)
        for o in np.unique(orders):
            sel = np.flatnonzero(orders == o)
            G = np.empty((sel.size, int(o) + 1), dtype=np.complex128)
            for i in range(0, sel.size, step):
                checkpoint()
                ch = sel[i : i + step]
                A = self._cfg.E[kc[ch]] - s[ch, None]  # z_j − c
                b = log_series(A, zc, self.beta, S[ch], int(o))
                lam0 = b[:, 0].copy()  # Σ β_j log(1 − c/z_j)
                b[:, 0] = 0.0
                G[i : i + step] = exp_series(b, self.constant * np.exp(lam0))
            remap = np.full(K, -1)
            remap[sel] = np.arange(sel.size)
            pts = np.flatnonzero(remap[cid] >= 0)
            rows = remap[cid[pts]]
            u = t[pts] / S[cid[pts]]
            Gi = G / np.arange(1, G.shape[1] + 1)[None, :]
            out_f[pts] = fc[cid[pts]] + S[cid[pts]] * u * horner(Gi, rows, u)
            if derivative:
                out_d[pts] = horner(G, rows, u)
        return out_f, out_d

    def _eval_clusters_tree(self, toff, cid, cen, rho, derivative):
        """f (and f') at the points ``cen[cid] + t`` from the Taylor series about their
        cluster centre.

        Cluster i has centre ``cen[i]`` (closed disk) and all its points within ``rho[i] ≤
        R_i/2`` of it. The coefficients of log f' about all centres come from the far-field
        tree (:func:`~quadmesh.conformal.series.log_expansions`, O(n log n) instead of O(n)
        per centre). The values f(c) come from radial anchor chains: anchors
        ``(1 − d_s) e^{2πij/N_s}`` with ``d_s = 1.5^{−s}`` and angular spacing ``≤ 0.58 d_s`` lie
        at least ``d_s`` from every prevertex, each anchor is within ``0.442 d_{s−1}`` of its
        parent (one level up, towards 0 where ``f(0) = c``), so one step of the parent's series
        carries the value down; a cluster then takes its value from an anchor through the
        anchor's series (``d_c ≤ d_s < 1.5 d_c``) or its own (``d_s ≈ ρ``, near the circle).
        Next to a prevertex f(c) comes from the prevertex series instead (relative accuracy).
        """
        K = cen.size
        out_f = np.empty(toff.size, dtype=np.complex128)
        out_d = np.empty(toff.size, dtype=np.complex128) if derivative else None
        if K == 0:
            return out_f, out_d
        # a region of radius R/4 costs no more terms than a smaller one (order ≥ 32)
        rho = np.maximum(rho, 0.25 * np.abs(self._nearest(cen)[1]))
        dc = 1.0 - np.abs(cen)
        lg = math.log(1.5)
        caseA = dc > rho / 3.0
        with np.errstate(divide="ignore"):
            sA = np.floor(np.log(1.0 / np.maximum(dc, 1e-300)) / lg)
            sB = np.ceil(np.log(1.045 / rho) / lg)
        s = np.where(caseA, sA, sB).astype(np.int64)
        s = np.maximum(s, 0)
        # anchor keys (s, j) for the clusters, then all their ancestors
        ds = np.power(1.5, -s.astype(float))
        Ns = _anchor_count(ds, s)
        j = np.mod(np.rint(np.mod(np.angle(cen), TWO_PI) / (TWO_PI / Ns)), Ns).astype(np.int64)
        keys = [np.stack([s, j], axis=1)]
        cur = keys[0]
        while True:
            cur = cur[cur[:, 0] > 0]
            if cur.size == 0:
                break
            cur = unique_rows(cur)[0]
            s0 = cur[:, 0]
            ang = cur[:, 1] * (TWO_PI / _anchor_count(np.power(1.5, -s0.astype(float)), s0))
            sp = s0 - 1
            Np = _anchor_count(np.power(1.5, -sp.astype(float)), sp)
            jp = np.mod(np.rint(ang / (TWO_PI / Np)), Np).astype(np.int64)
            cur = np.stack([sp, jp], axis=1)
            keys.append(cur)
        akeys, ainv = unique_rows(np.concatenate(keys))
        a_of_cluster = ainv[:K]
        As = akeys[:, 0]
        Ad = np.power(1.5, -As.astype(float))
        AN = _anchor_count(Ad, As)
        apos = (1.0 - Ad) * np.exp(1j * (akeys[:, 1] * (TWO_PI / AN)))
        apos[As == 0] = 0.0
        arho = 0.4419 * Ad
        # series for clusters and anchors together
        allc = np.r_[cen, apos]
        allrho = np.r_[rho, arho]
        _, dall = self._nearest(allc)
        allR = np.abs(dall)
        orders = np.maximum(self._order(allrho / allR), 32)
        T = allc.size
        with span(0.0, 0.6):
            groups = log_expansions(self.prevertices, self.theta, self.beta, allc, allrho, orders)
        olist = np.unique(orders)
        grp = np.searchsorted(olist, orders)
        row = np.empty(T, dtype=np.intp)
        G = [np.empty((int(np.sum(orders == o)), int(o) + 1), dtype=np.complex128) for o in olist]
        for gi in range(olist.size):
            row[grp == gi] = np.arange(G[gi].shape[0])
        # one exp_series per order (the tree returns a group per order and level)
        by_order: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        for t, a in groups:
            by_order.setdefault(int(grp[t[0]]), []).append((t, a))
        for n_done, (gi, parts) in enumerate(by_order.items()):
            checkpoint(0.6 + 0.2 * n_done / len(by_order))
            t = np.concatenate([p[0] for p in parts])
            b = np.concatenate([p[1] for p in parts])
            g0 = self.constant * np.exp(b[:, 0])
            b[:, 0] = 0.0
            G[gi][row[t]] = exp_series(b, g0)
        # order-major copies for horner_t; F = S u Σ Gi_m u^m
        GT = [np.ascontiguousarray(g.T) for g in G]
        GiT = [np.ascontiguousarray((g / np.arange(1, g.shape[1] + 1)[None, :]).T) for g in G]
        S = 2.0 * allrho

        def series(rows, t, integrate):
            u = t / S[rows]
            out = np.empty(rows.size, dtype=np.complex128)
            gr = grp[rows]
            for gi in range(olist.size):
                sel = np.flatnonzero(gr == gi)
                if sel.size:
                    coef = GiT[gi] if integrate else GT[gi]
                    out[sel] = horner_t(coef, row[rows[sel]], u[sel])
            return S[rows] * u * out if integrate else out

        def integral(rows, t):
            return series(rows, t, True)

        # anchor values, coarse to fine
        fa = np.empty(akeys.shape[0], dtype=np.complex128)
        top = As == 0
        fa[top] = self.center
        parent = np.full(akeys.shape[0], -1)
        ch = np.flatnonzero(~top)
        if ch.size:
            sp = As[ch] - 1
            Np = _anchor_count(np.power(1.5, -sp.astype(float)), sp)
            ang = akeys[ch, 1] * (TWO_PI / AN[ch])
            jp = np.mod(np.rint(ang / (TWO_PI / Np)), Np).astype(np.int64)
            parent[ch] = match_rows(akeys, np.stack([sp, jp], axis=1))
        # the steps from the parents are independent of the values: one series evaluation
        # for all of them, then the sums down the levels
        step = np.empty(akeys.shape[0], dtype=np.complex128)
        if ch.size:
            step[ch] = integral(K + parent[ch], apos[ch] - apos[parent[ch]])
        checkpoint(0.85)
        by_level = np.argsort(As, kind="stable")
        bounds = np.searchsorted(As[by_level], np.arange(1, int(As.max()) + 2))
        for lev in range(1, int(As.max()) + 1):
            idx = by_level[bounds[lev - 1] : bounds[lev]]
            fa[idx] = fa[parent[idx]] + step[idx]
        # cluster values
        a = a_of_cluster
        fc = np.empty(K, dtype=np.complex128)
        iA = np.flatnonzero(caseA)
        fc[iA] = fa[a[iA]] + integral(K + a[iA], cen[iA] - apos[a[iA]])
        iB = np.flatnonzero(~caseA)
        fc[iB] = fa[a[iB]] - integral(iB, apos[a[iB]] - cen[iB])
        # next to a prevertex, f(c) − w_k from the prevertex series keeps relative accuracy
        kk, dkk = self._nearest(cen)
        iv = np.flatnonzero(np.abs(dkk) <= 0.5 * self._cfg.nn[kk])
        if iv.size:
            fc[iv] = self._eval_vertex(kk[iv], dkk[iv], False)[0]
        # the points
        checkpoint(0.9)
        out_f[:] = fc[cid] + integral(cid, toff)
        if derivative:
            out_d[:] = series(cid, toff, False)
        return out_f, out_d

    def __call__(self, z: np.ndarray) -> np.ndarray:
        """Forward map ``f(z)`` for ``|z| ≤ 1`` (vectorised).

        Points within half the neighbour distance of a prevertex use that prevertex's series;
        all others are grouped in dyadic cells of size ≈ dist/8 and use the Taylor series
        about the cell's mean point (§1.10): coefficients from the far-field tree, the value at
        the centre from a radial anchor chain starting at ``f(0) = c`` (see
        :meth:`_eval_clusters`). O((M + n) log) work, no quadrature.
        """
        z = np.asarray(z, dtype=np.complex128)
        return self._evaluate(z, False)[0].reshape(z.shape)

    def map_near_vertex(
        self, k: np.ndarray, t: np.ndarray, derivative: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """``f(z_k + t)`` (and ``f'`` if ``derivative``) with ``t`` a local offset from prevertex k.

        Local coordinates keep full relative precision when prevertex gaps are far below the
        resolution of ``exp(iθ)`` (§1.9): the prevertex series is used for ``|t| ≤ R_k/2``
        (``R_k`` the distance to the neighbouring prevertices, computed from the gaps), and
        compound quadrature from ``z_k`` in local coordinates beyond. ``z_k + t`` must lie in
        the closed disk.
        """
        kk = np.asarray(k, dtype=np.intp).ravel()
        tt = np.asarray(t, dtype=np.complex128).ravel()
        kk = np.broadcast_to(kk, tt.shape) if kk.size == 1 else kk
        f = np.empty(tt.size, dtype=np.complex128)
        fp = np.empty(tt.size, dtype=np.complex128) if derivative else None
        near = np.abs(tt) <= 0.5 * self._cfg.nn[kk]
        i = np.flatnonzero(near)
        if i.size:
            ff, dd = self._eval_vertex(kk[i], tt[i], derivative)
            f[i] = ff
            if derivative:
                fp[i] = dd
        j = np.flatnonzero(~near)
        if j.size:
            plan = plan_integrals(
                self._cfg, kk[j], np.zeros(j.size, complex), tt[j], np.ones(j.size, bool)
            )
            H, _ = integrate(self._cfg, plan, self._prob.rules)
            f[j] = self.vertices[kk[j]] + self.constant * H
            if derivative:
                B = (self._cfg.E[kk[j]] - tt[j, None]) * self._cfg.zc[None, :]
                B[np.arange(j.size), kk[j]] = -tt[j] * self._cfg.zc[kk[j]]
                fp[j] = self.constant * np.exp(beta_log_sum(B, self.beta))
        return (f, fp) if derivative else f

    def taylor(self, center: complex, order: int = 40) -> TaylorSeries:
        """The Taylor series of f about ``center`` (|center| < 1), see :class:`TaylorSeries`."""
        c = np.array([complex(center)])
        if not abs(c[0]) < 1.0:
            raise ValueError("the series centre must lie inside the unit disk")
        g, R = self._interior_coefficients(c, order)
        return TaylorSeries(c[0], R[0], self._evaluate(c, False)[0][0], g[0])

    def map_clusters(
        self,
        points: np.ndarray,
        cluster_ids: np.ndarray | None,
        centers: np.ndarray | None,
        derivative: bool = False,
        offsets: OffsetFunction | None = None,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Evaluate f (and f' if ``derivative``) at ``points``, cluster by cluster.

        Cluster ``i`` (points with ``cluster_ids == i``) uses the Taylor series about
        ``centers[i]`` when all its points lie within ``R/2`` of the centre (``R`` the distance
        from the centre to the prevertices); the points of other clusters are regrouped as in
        ``__call__`` (prevertex series, dyadic cells). Series coefficients come from the
        far-field tree and values at the centres from radial anchor chains (§1.10, see
        :meth:`_eval_clusters_tree`); centres within :data:`CROWD_RADIUS` of a prevertex work
        in local coordinates (:meth:`_eval_clusters_local`). The order is chosen per cluster
        from ``max|t|/R`` for an error ≈ 1e-16 relative to the local scale.
        ``cluster_ids = centers = None``: no given clusters, the points are grouped as in
        ``__call__``.

        Exact offsets (points that complex128 cannot resolve, e.g. disk-mesh vertices 1e-15
        from the circle next to prevertex gaps of 1e-13): every series is evaluated at an
        offset ``t = z − p`` from a float64 centre or a long double prevertex ``p``, so ``f`` is
        as accurate as ``t``. ``offsets(refs, index)`` must return ``points[index] − refs``
        (complex128, accurate relative to the result) for long double ``refs`` broadcast
        against ``index`` — e.g. :meth:`quadmesh.disk.DiskMesh.offsets_from`; ``points`` then
        only locates the points. If ``points`` is clongdouble and ``offsets`` None, the offsets
        are its long double differences. Long double ``centers`` are rounded to complex128 (the
        series centre is that rounded point; the offsets stay exact).
        """
        pts = np.asarray(points)
        if pts.dtype == np.clongdouble and offsets is None:
            zl = pts.ravel()

            def offsets(refs: np.ndarray, index: np.ndarray) -> np.ndarray:
                return (zl[index] - refs).astype(np.complex128)

        z = pts.astype(np.complex128).ravel()
        if cluster_ids is None:
            cid = cen = None
        else:
            cid = np.asarray(cluster_ids, dtype=np.intp).ravel()
            cen = np.asarray(centers).astype(np.complex128).ravel()
        f, fp = self._evaluate_grouped(z, cid, cen, derivative, offsets)
        return (f, fp) if derivative else f

    # ------------------------------------------------------------------ inverse
    def _start_table(self) -> tuple[cKDTree, np.ndarray, np.ndarray]:
        if self._table is None:
            ang = np.linspace(0, TWO_PI, 128, endpoint=False)
            rad = np.r_[np.linspace(0.0, 0.9, 10)[1:], 1.0 - np.logspace(-1.2, -5, 10)]
            pts = [np.array([0j]), (rad[:, None] * np.exp(1j * ang)[None, :]).ravel()]
            mid = self.theta + 0.5 * self.gaps
            for s in (0.1, 0.3, 1.0, 3.0):
                pts.append(np.exp(1j * mid) * (1.0 - np.minimum(s * self.gaps, 0.5)))
            zt = np.concatenate(pts)
            wt = self(zt)
            self._table = (cKDTree(np.column_stack([wt.real, wt.imag])), zt, wt)
        return self._table

    def _starts(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start pairs (z0, f(z0)) whose image segment [f(z0), w] lies in the polygon."""
        import shapely

        poly = shapely.Polygon(np.column_stack([self.vertices.real, self.vertices.imag]))
        shapely.prepare(poly)
        inside = shapely.dwithin(poly, shapely.points(w.real, w.imag), 1e-12 * self._diam)
        if not np.all(inside):
            k = int(np.flatnonzero(~inside)[0])
            raise ConformalMapError(
                f"inverse map: {int(np.sum(~inside))} points are outside the polygon (e.g. {w[k]})"
            )
        if self._star:
            return np.zeros(w.size, complex), np.full(w.size, self.center)
        tree, zt, wt = self._start_table()
        z0 = np.full(w.size, np.nan + 0j)
        w0 = np.full(w.size, np.nan + 0j)
        todo = np.arange(w.size)
        for kq in (8, 64, zt.size):
            if todo.size == 0:
                break
            kq = min(kq, zt.size)
            _, idx = tree.query(np.column_stack([w[todo].real, w[todo].imag]), k=kq)
            idx = idx.reshape(todo.size, kq)
            found = np.zeros(todo.size, bool)
            for j in range(kq):
                cand = np.flatnonzero(~found)
                if cand.size == 0:
                    break
                a = wt[idx[cand, j]]
                b = w[todo[cand]]
                segs = shapely.linestrings(
                    np.stack(
                        [np.column_stack([a.real, a.imag]), np.column_stack([b.real, b.imag])],
                        axis=1,
                    )
                )
                okc = shapely.covers(poly, segs)
                sel = cand[okc]
                z0[todo[sel]] = zt[idx[sel, j]]
                w0[todo[sel]] = wt[idx[sel, j]]
                found[sel] = True
            todo = todo[~found]
        if todo.size:
            raise ConformalMapError(f"inverse map: {todo.size} points are not inside the polygon")
        return z0, w0

    def inverse(self, w: np.ndarray, tol: float = 1e-14) -> np.ndarray:
        """``f⁻¹(w)`` for points of the closed polygon (vectorised, §1.6): the ODE
        ``dz/dt = (w − w0)/f'(z)`` from a visible start pair (RK45), then Newton steps with
        damping inside the disk until ``|f(z) − w| ≤ tol·diam``. Points that end above
        ``1e-10·diam`` are redone with a tighter ODE; if they still fail,
        :class:`ConformalMapError` is raised (no silent bad output)."""
        w = np.asarray(w, dtype=np.complex128)
        flat = w.ravel()
        if flat.size == 0:
            return np.empty(w.shape, complex)
        z, err = self._inverse_pass(flat, 1e-5, tol)
        bad = np.flatnonzero(err > 1e-10 * self._diam)
        if bad.size:
            z[bad], err[bad] = self._inverse_pass(flat[bad], 1e-9, tol)
            bad = np.flatnonzero(err > 1e-10 * self._diam)
            if bad.size:
                raise ConformalMapError(
                    f"inverse map did not converge at {bad.size} points "
                    f"(max |f(z) − w| = {np.max(err[bad]):.1e}, e.g. w = {flat[bad[0]]})"
                )
        return z.reshape(w.shape)

    def _inverse_pass(
        self, flat: np.ndarray, rtol: float, tol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """One ODE + Newton pass; returns the preimages and the final |f(z) − w|."""
        z0, w0 = self._starts(flat)
        dw = flat - w0
        M = flat.size

        def rhs(_t: float, y: np.ndarray) -> np.ndarray:
            checkpoint()
            zz = y[:M] + 1j * y[M:]
            zz = zz / np.maximum(np.abs(zz), 1.0)
            v = dw / self.derivative(zz)
            return np.concatenate([v.real, v.imag])

        sol = solve_ivp(
            rhs, (0.0, 1.0), np.concatenate([z0.real, z0.imag]), rtol=rtol, atol=1e-3 * rtol
        )
        z = sol.y[:M, -1] + 1j * sol.y[M:, -1]
        z = z / np.maximum(np.abs(z), 1.0)
        err_all = np.full(M, np.inf)
        active = np.arange(M)
        for _ in range(12):
            checkpoint()
            fz, fpz = self._evaluate(z[active], True)
            err = fz - flat[active]
            err_all[active] = np.abs(err)
            done = np.abs(err) <= tol * self._diam
            active = active[~done]
            err, fpz = err[~done], fpz[~done]
            if active.size == 0:
                break
            step = err / fpz
            znew = z[active] - step
            for _k in range(30):
                out = np.abs(znew) > 1.0
                if not np.any(out):
                    break
                step[out] *= 0.5
                znew[out] = z[active][out] - step[out]
            z[active] = znew
        if active.size:
            err_all[active] = np.abs(self._evaluate(z[active], False)[0] - flat[active])
        return z, err_all

    # ------------------------------------------------------------------ checks
    def accuracy(self) -> ConformalAccuracy:
        """The accuracy checks (computed once, then cached)."""
        if self._accuracy is not None:
            return self._accuracy
        n = self.n
        w = self.vertices
        C = self.constant
        edges = np.roll(w, -1) - w
        Lmax = float(np.max(np.abs(edges)))
        side_err = float(np.max(np.abs(C * self._S - edges))) / Lmax
        center_err = abs(w[0] + C * self._Ic - self.center) / self._diam
        # boundary: 5 samples per gap, integrated from the nearer prevertex (local coords)
        ts = np.array([0.1, 0.3, 0.5, 0.7, 0.9])
        k = np.repeat(np.arange(n), ts.size)
        t = np.tile(ts, n)
        g = self.gaps[k]
        near0 = t <= 0.5
        k1 = (k + 1) % n
        base = np.where(near0, k, k1)
        zb = self.prevertices[base]
        end = np.where(near0, zb * np.expm1(1j * t * g), zb * np.expm1(-1j * (1 - t) * g))
        # the middle samples are the half-side integrals of the solve when it kept them
        mid = (t == 0.5) if self._half is not None else np.zeros(k.size, bool)
        todo = np.flatnonzero(~mid)
        plan = plan_integrals(
            self._cfg, base[todo], np.zeros(todo.size, complex), end[todo], np.ones(todo.size, bool)
        )
        H = np.empty(k.size, dtype=np.complex128)
        H[todo] = integrate(self._cfg, plan, self._prob.rules)[0]
        if self._half is not None:
            H[mid] = self._half[k[mid]]
        fb = w[base] + C * H
        e = edges[k]
        dev = np.abs(((fb - w[k]) * np.conj(e)).imag) / np.abs(e)
        bdry = float(np.max(dev)) / self._diam
        rng = np.random.default_rng(12345)
        zr = 0.95 * np.sqrt(rng.uniform(0, 1, 64)) * np.exp(1j * rng.uniform(0, TWO_PI, 64))
        rt = float(np.max(np.abs(self.inverse(self(zr)) - zr)))
        self._accuracy = ConformalAccuracy(
            residual=self.residual,
            side_error=side_err,
            center_error=float(center_err),
            boundary_deviation=bdry,
            round_trip=rt,
            min_gap=float(np.min(self.gaps)),
        )
        return self._accuracy


def _unique_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of an int array and the inverse index (lexsort based)."""
    order = np.lexsort(keys.T[::-1])
    sk = keys[order]
    new = np.r_[True, np.any(sk[1:] != sk[:-1], axis=1)]
    grp = np.cumsum(new) - 1
    inv = np.empty(keys.shape[0], dtype=np.intp)
    inv[order] = grp
    return sk[new], inv


def _dyadic_cells(z: np.ndarray, r: np.ndarray, fmap: DiskMap):
    """Group points (distance ``r`` from the nearest prevertex) in dyadic cells of side
    ``h ∈ (r/8, r/4]``. Returns per point its cell, and per cell the centre (mean of its
    points, so inside the closed disk) and radius ``ρ``; a cell whose ``ρ`` exceeds half the
    centre's distance to the prevertices is split one level finer (§1.10)."""
    if z.size == 0:
        return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.complex128), np.empty(0)
    lev = np.floor(np.log2(np.maximum(r, 1e-300) / 4.0)).astype(np.int64)
    for _ in range(6):
        checkpoint()
        h = np.ldexp(1.0, lev)
        keys = np.stack([lev, np.floor(z.real / h), np.floor(z.imag / h)], axis=1)
        ukeys, cid = _unique_rows(keys.astype(np.int64))
        K = ukeys.shape[0]
        cnt = np.bincount(cid, minlength=K)
        cen = (np.bincount(cid, z.real, K) + 1j * np.bincount(cid, z.imag, K)) / np.maximum(cnt, 1)
        a = np.abs(cen)
        cen = np.where(a > 1.0, cen / np.maximum(a, 1e-300), cen)
        rho = np.zeros(K)
        np.maximum.at(rho, cid, np.abs(z - cen[cid]))
        R = np.abs(fmap._nearest(cen)[1])
        bad = rho > 0.5 * R
        if not np.any(bad):
            break
        lev = np.where(bad[cid], lev - 1, lev)
    else:
        raise ConformalMapError(
            "could not group the evaluation points in series cells (the map is too crowded "
            "near the boundary)"
        )
    return cid, cen, np.maximum(rho, 1e-300)


def _anchor_count(ds: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Number of radial anchors on the circle of radius ``1 − d_s`` (1 at s = 0): angular
    spacing ≤ 0.58 d_s."""
    return np.where(s == 0, 1, np.ceil(TWO_PI / (0.58 * ds))).astype(np.int64)


def _star_shaped(w: np.ndarray, c: complex) -> bool:
    """True when c lies strictly inside the kernel (left of every side's line)."""
    e = np.roll(w, -1) - w
    return bool(np.all((np.conj(e) * (c - w)).imag > 0))


def _radial_blend(w: np.ndarray, c: complex, t: float) -> tuple[np.ndarray, complex]:
    """Star-shaped homotopy: vertex radii about c blended geometrically from their mean
    (t = 0, a nearly regular polygon) to their true values (t = 1); every member is
    star-shaped about c, hence simple."""
    v = w - c
    rho = np.abs(v)
    lr = np.log(rho)
    r_t = np.exp((1.0 - t) * lr.mean() + t * lr)
    return c + r_t * (v / rho), c


def _continue(prob: _Problem, family, tol: float, min_gap: float = 0.0, max_steps: int = 30):
    """Continuation along a family of polygons ``family(t) -> (w_t, c_t)``, t ∈ [0, 1],
    ``family(1)`` being the target: solve t = 0 from the initial guess, then advance t in
    adaptive steps, each Newton solve starting from the previous solution (§1.5). Gives up
    after ``max_steps`` steps, or as soon as an intermediate solution crowds below
    ``min_gap`` (the target would be rejected anyway)."""
    its = 0
    steps = 0
    ws, cs = family(0.0)
    sub = _Problem(ws, cs, prob.m, prob.local, prob.ref)
    sub.steps = prob.steps
    g0 = None if _star_shaped(ws, cs) else _harmonic_gaps(ws, cs)
    x, res, k, ok = _newton(sub, _x_from_gaps(_initial_gaps(ws, cs) if g0 is None else g0), tol)
    its += k
    if not ok:
        return x, res, its, steps, False
    h = 0.25
    t = 0.0
    while t < 1.0:
        tn = min(1.0, t + h)
        ws, cs = family(tn)
        if tn < 1.0:
            sub = _Problem(ws, cs, prob.m, prob.local, prob.ref)
            sub.steps = prob.steps
        else:
            sub = prob
        x1, res, k, ok = _newton(sub, x, tol)
        its += k
        steps += 1
        if ok:
            x, t = x1, tn
            h = min(h * 1.5, 0.5)
            if t < 1.0 and np.min(_Problem.gaps(x)) < min_gap:
                return x, res, its, steps, False
        else:
            h *= 0.5
            if h < 1e-3:
                return x1, res, its, steps, False
        if steps >= max_steps and t < 1.0:
            return x, res, its, steps, False
    return x, res, its, steps, True
