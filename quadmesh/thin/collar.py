"""Conformal collar: a quad mesh that straightens an off-centre crosscut of a thin part.

Paper: Bishop, "Optimal angle bounds for quadrilateral meshes", section "Meshing the thin
parts". The parabolic and hyperbolic constructions there assume that the
crosscut gamma is an approximate circle about the vertex (or an approximate perpendicular segment
of a channel). In the pipeline gamma is the image of a hyperbolic geodesic whose arc is not
centred on the prevertex, so in strip coordinates it is an S-shaped graph x = X(y) that meets both
walls at right angles. The collar is the band between gamma and a straight crosscut, meshed by the
image of a rectangular grid under an exact conformal map; the straight crosscut then feeds
:func:`~quadmesh.thin.mesh_vertex_sector` or :func:`~quadmesh.thin.mesh_channel`.

Strip coordinates zeta = x + iy: ``log((z - O)/wall1_dir)`` for wedge walls (walls y = 0 and
y = beta, beta in (0, 2π)), ``(z - origin)/direction`` for parallel walls (y = 0 and y = width).
With ``toward="outer"`` the x axis is reversed internally so that the straight crosscut always
lies to the left of gamma; a reflection keeps all angles.

The map (beta = strip height, k_m = m π / beta, x0 = straight crosscut, W = collar modulus)::

    F(s) = s + sum_{m=1}^{M} a_m sinh(k_m (s - x0)) / sinh(k_m W)

is analytic, keeps both walls (Im F = 0 on y = 0 and Im F = beta on y = beta), maps the line
Re s = x0 into itself and maps the line Re s = x0 + W onto the curve
``x = x0 + W + sum a_m cos(k_m t), y = t + sum a_m coth(k_m W) sin(k_m t)``. The coefficients
(and W) are found by Levenberg-Marquardt (M = 32, 64, ... modes, warm-started, until the
residual is <= 1e-5 of the strip height) so that this curve is the smooth graph X through the
crosscut vertices (a periodic cubic spline of the even extension of X, so X' = 0 at
the walls, as for an image of a geodesic by the reflection principle). Rows of the grid are the
preimages t_k of the g_k on the far edge, columns are vertical lines, enough of them that every
chain turns by at most ``eta_deg`` per segment; the last column is replaced by the g_k exactly.
The grid of a conformal map is orthogonal, so all quad angles are near 90° once cells are small
relative to the curvature of the grid lines; every angle is checked.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import leastsq

from ..errors import ThinPartError
from ..progress import checkpoint
from .channel import Walls
from .mesh import quad_angles_deg, quad_signed_areas

__all__ = ["CollarMesh", "conformal_collar", "vertex_walls"]


@dataclass(frozen=True)
class CollarMesh:
    """Quad mesh of the band between a crosscut gamma and a straight crosscut.

    Attributes:
        vertices: (V,) complex vertex coordinates.
        quads: (Q, 4) int vertex indices, counter-clockwise.
        gamma_index: (P,) int, ``vertices[gamma_index[k]] == g_k`` exactly.
        straight_index: (P,) int, the straight crosscut's vertices, ordered wall 1 -> wall 2
            (first on wall 1, last on wall 2).
        wall1, wall2: vertex indices on wall 1 / wall 2, from the straight crosscut to gamma.
        straight_coord: strip coordinate x0 of the straight crosscut (log radius about O for a
            wedge, offset along ``walls.direction`` from ``walls.origin`` for parallel walls).
        radius: radius exp(x0) of the straight circular arc about O (wedge), None for parallel
            walls.
        n_columns: number of grid columns (straight crosscut and gamma included).
        n_modes: number M of terms of the conformal map (32, 64, ... until it fits).
        fit_residual: largest |Re F - X| on the far edge (strip units), before gamma was
            substituted exactly.
    """

    vertices: np.ndarray
    quads: np.ndarray
    gamma_index: np.ndarray
    straight_index: np.ndarray
    wall1: np.ndarray
    wall2: np.ndarray
    straight_coord: float
    radius: float | None
    n_columns: int
    n_modes: int
    fit_residual: float

    @property
    def straight(self) -> np.ndarray:
        """(P,) complex vertices of the straight crosscut, wall 1 -> wall 2."""
        return self.vertices[self.straight_index]

    def angles_deg(self) -> np.ndarray:
        """(Q, 4) interior angle at every quad corner, degrees."""
        return quad_angles_deg(self.vertices, self.quads)

    def new_angle_mask(self) -> np.ndarray:
        """(Q, 4) bool: every corner of a collar is a new angle."""
        return np.ones(self.quads.shape, dtype=bool)


def vertex_walls(apex: complex, side1_dir: complex, theta: float) -> Walls:
    """Wedge walls of a polygon vertex: sides at angle 0 and ``theta`` in (0, 2π) about ``apex``.

    Unlike :meth:`Walls.wedge` (channels, beta < π) this allows reflex vertex angles; such walls
    are meant for :func:`conformal_collar` only.
    """
    if not (0.0 < theta < 2.0 * math.pi) or abs(side1_dir) == 0.0:
        raise ThinPartError(f"invalid vertex walls (theta = {theta!r})")
    return Walls(complex(apex), complex(side1_dir) / abs(side1_dir), float(theta), None)


def _ratios(k: np.ndarray, u: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """sinh(k u)/sinh(k W) and cosh(k u)/sinh(k W) for real 0 <= u <= W, without overflow."""
    ku = np.outer(u, k)
    e2 = np.exp(-2.0 * ku)
    base = np.exp(ku - k * width) / (1.0 - np.exp(-2.0 * k * width))
    return base * (1.0 - e2), base * (1.0 + e2)


class _Map:
    """F(s) = s + sum a_m sinh(k_m (s - x0)) / sinh(k_m W) and its derivative on grids.

    With s = sigma + i t, sinh(k (s - x0)) = sinh(k u) cos(k t) + i cosh(k u) sin(k t)
    (u = sigma - x0), so F on a tensor grid is two matrix products.
    """

    def __init__(self, a: np.ndarray, k: np.ndarray, x0: float, width: float) -> None:
        keep = np.abs(a) > 1e-16 * np.abs(a).max(initial=0.0)
        self.a, self.k, self.x0, self.width = a[keep], k[keep], x0, width

    def grid(self, sig: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """F and F' at sig[j] + i t[k], arrays of shape (len(sig), len(t))."""
        sh, ch = _ratios(self.k, np.asarray(sig, dtype=float) - self.x0, self.width)
        ct, st = np.cos(np.outer(self.k, t)), np.sin(np.outer(self.k, t))
        s = sig[:, None] + 1j * t[None, :]
        f = s + (sh * self.a) @ ct + 1j * ((ch * self.a) @ st)
        ak = self.a * self.k
        fp = 1.0 + (ch * ak) @ ct + 1j * ((sh * ak) @ st)
        return f, fp


def _strip_coords(walls: Walls, g: np.ndarray, tol: float) -> np.ndarray:
    """Strip coordinates of the crosscut, with its ends put exactly on y = 0 and y = span."""
    span = walls.span
    rel = (g - walls.origin) / walls.direction
    if walls.is_parallel:
        w = rel.copy()
    else:
        if np.any(rel == 0):
            raise ThinPartError("crosscut vertex at the wedge apex")
        ang = np.mod(np.angle(rel), 2.0 * math.pi)
        if ang[0] > math.pi:
            ang[0] -= 2.0 * math.pi
        w = np.log(np.abs(rel)) + 1j * ang
    scale = max(span, float(np.ptp(w.real)))
    if abs(w[0].imag) > tol * scale or abs(w[-1].imag - span) > tol * scale:
        raise ThinPartError("crosscut does not start on wall 1 and end on wall 2")
    y = w.imag.copy()
    y[0], y[-1] = 0.0, span
    if np.any(np.diff(y) <= 0.0):
        raise ThinPartError(
            "crosscut is not a graph over the wall-to-wall coordinate (its vertices do not "
            "advance monotonically from wall 1 to wall 2)"
        )
    return w.real + 1j * y


def _fit_graph(y: np.ndarray, x: np.ndarray, span: float) -> CubicSpline:
    """Periodic cubic spline through the even extension of x = X(y) (period 2 * span)."""
    yy = np.concatenate([-y[::-1][:-1], y])
    xx = np.concatenate([x[::-1][:-1], x])
    return CubicSpline(yy, xx, bc_type="periodic")


def _remember_last(f: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    """``f`` that returns its last value again for an equal argument (the fit evaluates the
    residuals and the Jacobian at the start more than once). The value must not be changed."""
    last: list[np.ndarray] = []

    def remembered(p: np.ndarray) -> np.ndarray:
        if last and np.array_equal(last[0], p):
            return last[1]
        value = f(p)
        last[:] = [p.copy(), value]
        return value

    return remembered


def _solve_map(
    spl: CubicSpline, span: float, x0: float, p0: np.ndarray
) -> tuple[_Map, float, np.ndarray]:
    """Coefficients a_m and modulus W with F(far edge) on the graph of ``spl``."""
    n_modes = len(p0) - 1
    k = math.pi * np.arange(1, n_modes + 1) / span
    n_col = 4 * n_modes + 1
    t = span * (np.arange(n_col) + 0.5) / n_col
    cos_t = np.cos(np.outer(t, k))
    sin_t = np.sin(np.outer(t, k))
    dspl = spl.derivative()

    def unpack(p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """W, the a_m, coth(k_m W) and q = exp(-2 k_m W)."""
        wid = p[0]
        q = np.exp(-2.0 * k * wid)
        coth = (1.0 + q) / (1.0 - q)
        return wid, p[1:], coth, q

    @_remember_last
    def resid(p: np.ndarray) -> np.ndarray:
        wid, a, coth, _ = unpack(p)
        yv = t + sin_t @ (a * coth)
        return x0 + wid + cos_t @ a - spl(yv)

    @_remember_last
    def jac(p: np.ndarray) -> np.ndarray:
        _wid, a, coth, q = unpack(p)
        dcoth = -4.0 * k * q / (1.0 - q) ** 2  # d coth(kW) / dW
        yv = t + sin_t @ (a * coth)
        xp = dspl(yv)
        jw = 1.0 - xp * (sin_t @ (a * dcoth))
        ja = cos_t - xp[:, None] * (sin_t * coth[None, :])
        return np.column_stack([jw, ja])

    # MINPACK's lmder as least_squares(method="lm", ftol=xtol=1e-15) runs it (gtol 1e-8, at
    # most 100 * len(p0) evaluations, scaling by the Jacobian), without its wrapper's overhead.
    if not np.all(np.isfinite(resid(p0))):
        raise ValueError("Residuals are not finite in the initial point.")
    p, _cov, info, _msg, _status = leastsq(
        resid,
        p0,
        Dfun=jac,
        full_output=True,
        ftol=1e-15,
        xtol=1e-15,
        gtol=1e-8,
        maxfev=100 * len(p0),
    )
    wid, a, _, _ = unpack(p)
    if not wid > 0.0:
        raise ThinPartError("conformal collar map: no positive modulus found")
    return _Map(a, k, x0, float(wid)), float(np.abs(info["fvec"]).max()), p


def _preimages(fmap: _Map, y: np.ndarray, span: float) -> np.ndarray:
    """t_k with Im F(x0 + W + i t_k) = y_k on the far edge (monotone, else ThinPartError)."""
    k, a, wid = fmap.k, fmap.a, fmap.width
    q = np.exp(-2.0 * k * wid)
    b = a * (1.0 + q) / (1.0 - q)
    # Sampled at 8 points per period of the highest mode (a fold narrower than that would
    # still show up as an inverted quad in the final checks); Newton polishes the start.
    tf = np.linspace(0.0, span, 16 * len(k) + 1)
    yf = tf + np.sin(np.outer(tf, k)) @ b
    if np.any(np.diff(yf) <= 0.0):
        raise ThinPartError("collar map folds on the crosscut (the crosscut is too tilted)")
    t = np.interp(y, yf, tf)
    for _ in range(12):
        kt = np.outer(t, k)
        res = t + np.sin(kt) @ b - y
        if np.abs(res).max() <= 1e-15 * span:
            break
        dres = 1.0 + np.cos(kt) @ (b * k)
        t = np.clip(t - res / dres, 0.0, span)
    t[0], t[-1] = 0.0, span
    return t


def _chain_turning(z: np.ndarray) -> float:
    """Largest turning (degrees) between consecutive chords of the chains (columns axis 0)."""
    d = np.diff(z, axis=0)
    if len(d) < 2:
        return 0.0
    return float(np.degrees(np.abs(np.angle(d[1:] / d[:-1]))).max())


def conformal_collar(
    gamma: np.ndarray,
    walls: Walls,
    *,
    toward: str = "inner",
    width: float | None = None,
    eta_deg: float = 5.0,
    max_modes: int = 512,
    max_columns: int = 2000,
    max_slope: float = 4.0,
    tol: float = 1e-9,
) -> CollarMesh:
    """Quad-mesh the band between crosscut ``gamma`` and a new straight crosscut.

    ``gamma`` holds P vertices from wall 1 to wall 2 (first on wall 1, last on wall 2). The
    straight crosscut is the circular arc about O (wedge walls) or the segment perpendicular to
    the walls (parallel walls) at strip distance ``width`` (default 0.3 * strip height) from
    gamma's nearest point, on the side ``toward`` ("inner": smaller x, towards O / the vertex;
    "outer": larger x). It gets exactly P vertices, so it can be handed to
    :func:`~quadmesh.thin.mesh_vertex_sector` (use :func:`vertex_walls`) or
    :func:`~quadmesh.thin.mesh_channel` unchanged. The mesh is the image of a rectangular grid
    under the conformal map described in the module docstring (rows end exactly at the g_k,
    columns dense enough that each chain turns by at most ``eta_deg`` per chord). Paper: section
    "Meshing the thin parts" (crosscuts that are circles about the vertex / perpendicular to a
    channel); this module's docstring.

    Raises:
        ThinPartError: gamma not from wall 1 to wall 2 or not a graph over the wall-to-wall
            coordinate, gamma too steep (|dX/dy| > ``max_slope``), the map cannot be fitted or
            folds, more than ``max_columns`` columns needed, or an angle outside [60°, 120°].
            The rows of the grid spread over the straight arc like harmonic measure seen from
            it, which concentrates where gamma comes closest to the vertex: a gap of gamma's
            vertices there widens on the arc (measured 45.0° -> 62.5° and 46.9° -> 67.8° on
            crosscuts whose radius varies 20-37 fold), and an arc chord spanning D meets the
            rows at 90° ± D/2. No choice of width helps (0.1-3 strip heights measured); gamma
            needs more vertices there, and the message says so.
    """
    g = np.asarray(gamma, dtype=np.complex128).ravel()
    n_pts = len(g)
    if n_pts < 3:
        raise ThinPartError(f"crosscut needs at least 3 vertices, got {n_pts}")
    if not np.all(np.isfinite(g)):
        raise ThinPartError("crosscut has non-finite vertices")
    if toward not in ("inner", "outer"):
        raise ThinPartError(f"toward must be 'inner' or 'outer', got {toward!r}")
    span = walls.span
    if not walls.is_parallel and not (0.0 < span < 2.0 * math.pi):
        raise ThinPartError(f"wedge angle {span!r} is not in (0, 2π)")
    w = _strip_coords(walls, g, tol)
    sgn = 1.0 if toward == "inner" else -1.0
    x, y = sgn * w.real, w.imag
    gap = 0.3 * span if width is None else float(width)
    if not gap > 0.0:
        raise ThinPartError(f"collar width must be positive, got {width!r}")

    spl = _fit_graph(y, x, span)
    yf = np.linspace(0.0, span, 2049)
    slope = float(np.abs(spl.derivative()(yf)).max())
    if slope > max_slope:
        raise ThinPartError(
            f"crosscut is too tilted for a collar: |dx/dy| reaches {slope:.2f} in strip "
            f"coordinates (limit {max_slope:g}, i.e. {math.degrees(math.atan(max_slope)):.0f} deg)"
        )
    xf = spl(yf)
    x_min = float(min(x.min(), xf.min()))
    x0 = x_min - gap
    x_mean = float(np.trapezoid(xf, yf) / span)
    # Modes M = 32, 64, ... (warm-started) until the far edge fits the graph to 1e-5 * span.
    params = np.zeros(33)
    params[0] = x_mean - x0
    while True:
        checkpoint()
        fmap, resid, params = _solve_map(spl, span, x0, params)
        n_modes = len(params) - 1
        if resid <= 1e-5 * span or 2 * n_modes > max_modes:
            break
        params = np.concatenate([params, np.zeros(n_modes)])
    if not np.isfinite(resid) or resid > 1e-3 * span:
        raise ThinPartError(
            f"conformal collar map does not fit the crosscut (residual {resid:.2e} in strip "
            "coordinates); the crosscut is too irregular"
        )
    t = _preimages(fmap, y, span)
    x1 = x0 + fmap.width

    # Columns: the chains' turning rate (arg of d/ds of the plane image along each row) is
    # equidistributed, so each chord turns by about the same amount <= eta; the spacing is
    # capped at span / 4.
    sf = np.linspace(x0, x1, 401)
    ff, dfp = fmap.grid(sf, t)
    if np.abs(dfp).min() <= 1e-3:
        raise ThinPartError("collar map is degenerate (|F'| vanishes)")
    direction = np.angle(dfp)
    if not walls.is_parallel:
        direction = direction + sgn * ff.imag
    direction = np.unwrap(direction, axis=0)
    eta = math.radians(eta_deg)
    rate = np.abs(np.diff(direction, axis=0)).max(axis=1)
    rate = np.maximum(rate, eta * np.diff(sf) / (0.25 * span))
    cum = np.concatenate([[0.0], np.cumsum(rate)])
    n_col = max(2, math.ceil(cum[-1] / (0.8 * eta)))

    while True:
        checkpoint()
        if n_col > max_columns:
            raise ThinPartError(f"collar needs more than {max_columns} columns")
        sig = np.interp(cum[-1] * np.arange(n_col + 1) / n_col, cum, sf)
        sig[0], sig[-1] = x0, x1
        fz, _ = fmap.grid(sig, t)
        xs, ys = sgn * fz.real, fz.imag
        xs[0, :] = sgn * x0
        ys[:, 0], ys[:, -1] = 0.0, span
        if walls.is_parallel:
            z = walls.origin + walls.direction * (xs + 1j * ys)
        else:
            z = walls.origin + walls.direction * np.exp(xs) * np.exp(1j * ys)
            z[:, 0] = walls.origin + walls.direction * np.exp(xs[:, 0])
            z[:, -1] = walls.origin + walls.direction * np.exp(1j * span) * np.exp(xs[:, -1])
        z[-1, :] = g
        if _chain_turning(z) <= eta_deg:
            break
        n_col = math.ceil(1.5 * n_col)

    idx = np.arange((n_col + 1) * n_pts).reshape(n_col + 1, n_pts)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1)
    quads = quads.reshape(-1, 4)
    verts = z.ravel()
    # Areas and angles relative to one vertex of the band: the shoelace sum of absolute
    # coordinates cancels when the collar is tiny compared with its distance from the origin.
    rel = verts - verts[0]
    areas = quad_signed_areas(rel, quads)
    if areas[0] < 0:
        quads = quads[:, ::-1]
        areas = -areas
    if np.any(areas <= 0.0):
        raise ThinPartError(
            f"collar folds: {int(np.sum(areas <= 0))} quads are inverted or degenerate"
        )
    ang = quad_angles_deg(rel, quads)
    if ang.min() < 60.0 - 1e-7 or ang.max() > 120.0 + 1e-7:
        why = "the crosscut's chords are too coarse or too tilted for a collar"
        if not walls.is_parallel and toward == "inner":
            # The rows spread over the straight arc like harmonic measure seen from it, which
            # concentrates where gamma comes closest to the vertex: a gap of gamma's vertices
            # there widens on the arc, and a chord spanning D meets the radial rows at 90 ± D/2.
            wide = int(np.argmax(np.diff(ys[0])))
            arc_gap = math.degrees(float(ys[0, wide + 1] - ys[0, wide]))
            if arc_gap > 50.0:
                why = (
                    f"rows {wide}-{wide + 1} span {arc_gap:.1f} deg on the straight arc "
                    f"({math.degrees(float(y[wide + 1] - y[wide])):.1f} deg between the crosscut "
                    f"vertices at log radius {x[wide]:.2f}, {x[wide + 1]:.2f}; the crosscut's "
                    f"nearest point to the vertex is at {x.min():.2f}): the crosscut needs more "
                    "vertices where it comes close to the vertex"
                )
        raise ThinPartError(
            f"collar angles in [{ang.min():.2f}, {ang.max():.2f}] degrees leave [60, 120]; {why}"
        )
    return CollarMesh(
        vertices=verts,
        quads=quads,
        gamma_index=idx[-1].copy(),
        straight_index=idx[0].copy(),
        wall1=idx[:, 0].copy(),
        wall2=idx[:, -1].copy(),
        straight_coord=float(sgn * x0),
        radius=None if walls.is_parallel else float(math.exp(sgn * x0)),
        n_columns=n_col + 1,
        n_modes=n_modes,
        fit_residual=resid,
    )
