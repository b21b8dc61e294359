"""The quad mesh of the model Carleson triangle (Bishop, §6 "Meshing the triangles", Lemma 6.1).

Model, in the upper half-plane H with the metric |dz|/y:

* The Carleson triangle ``T`` has vertices ``−1``, ``1`` and the top point ``w = i(1+√2)``.
  Its **left side** runs from ``w`` down to ``−1`` on the circle with centre ``+(1+√2)`` and radius
  ``2+√2``; its **right side** runs from ``w`` to ``+1`` on the circle with centre ``−(1+√2)``.
  The base ``[−1, 1]`` is ideal.  The left-side point at hyperbolic distance ``d`` from ``w`` is
  ``(1+√2) + (2+√2)e^{iθ}``, ``θ = 2 arctan(tan(3π/8)·e^d)``; the right side is its mirror image
  ``−conj(·)`` in the imaginary axis.
* The inner right circular triangle ``T_i`` has top point ``v = ih`` and vertices
  ``b_L = hs(−1+i)``, ``b_R = hs(1+i)``, ``s = (√3−1)/2``.  It is cut by the three straight
  spokes from its centre ``c = ih/√3`` to its edge midpoints into ``Q_v, Q_L, Q_R``; each is
  meshed by two of the three circle pencils ``F_x`` (circles through ``x`` and its inversion
  ``x*`` in the opposite side).
* Nine right circular quadrilaterals ``R1…R9`` surround ``T_i``; each carries its pair of
  orthogonal foliations (Lemma 5.2): in a chart ``χ`` it is an axis-parallel rectangle.  ``R1``
  (the corner at ``w``) is *parabolic*: all four of its side circles pass through ``conj(w)``
  (forced by its mirror symmetry, which swaps its two pairs of opposite sides), so its chart is
  ``1/(z − conj w)``.  The other eight use ``log((z−p)/(z−q))`` with ``p, q`` the two common
  points of a pair of opposite side circles.
* Leaves start on the left and right sides at the depths ``d_k`` of one global sequence and are
  continued from region to region (the "leaf routes") until they reach the base, the
  centre ``c`` or the opposite side, where by symmetry they end at the same depth.

Conformity is built in: every region boundary arc carries **one** shared list of vertices, computed
once by transferring the points of its source side across one region; each region's tensor grid
takes its four sides from these lists and only computes its interior vertices.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..errors import DiskConstructionError
from ..geometry import quad_angles_deg as chord_angles
from . import circles as gc

__all__ = [
    "REGION_NAMES",
    "ModelTriangleMesh",
    "TriangleLandmarks",
    "chord_angles",
    "depth_sequence",
    "left_side_depth",
    "left_side_point",
    "model_triangle_mesh",
    "right_side_depth",
    "right_side_point",
    "trace_leaf",
    "triangle_landmarks",
]

SQRT2 = math.sqrt(2.0)
SQRT3 = math.sqrt(3.0)
W_TOP = 1j * (1.0 + SQRT2)
_OUTER_CENTER = 1.0 + SQRT2
_OUTER_RADIUS = 2.0 + SQRT2
_TAN_3PI8 = math.tan(3.0 * math.pi / 8.0)

OUTER_LEFT = gc.circle_from_center(_OUTER_CENTER, _OUTER_RADIUS)
OUTER_RIGHT = gc.circle_from_center(-_OUTER_CENTER, _OUTER_RADIUS)
REAL_AXIS = gc.line_through(0.0, 1.0)
IMAG_AXIS = gc.line_through(0.0, 1j)


# ---------------------------------------------------------------------------------------------
# The sides of T parametrised by depth
# ---------------------------------------------------------------------------------------------


def left_side_point(d) -> np.ndarray:
    """Point(s) of the left side of ``T`` (``w`` to ``−1``) at hyperbolic distance ``d`` from ``w``.

    ``(1+√2) + (2+√2)e^{iθ}`` with ``θ = 2 arctan(tan(3π/8)·e^d)``; ``d = ∞`` gives ``−1``.
    """
    d = np.asarray(d, dtype=np.float64)
    theta = 2.0 * np.arctan(_TAN_3PI8 * np.exp(d))
    return _OUTER_CENTER + _OUTER_RADIUS * np.exp(1j * theta)


def right_side_point(d) -> np.ndarray:
    """Point(s) of the right side of ``T`` (from ``w`` to ``+1``) at distance ``d`` from ``w``."""
    return -np.conj(left_side_point(d))


def left_side_depth(z) -> np.ndarray:
    """Hyperbolic distance from ``w`` of point(s) ``z`` on the left side circle of ``T``."""
    theta = np.angle(np.asarray(z, dtype=np.complex128) - _OUTER_CENTER)
    return np.log(np.tan(theta / 2.0) / _TAN_3PI8)


def right_side_depth(z) -> np.ndarray:
    """Hyperbolic distance from ``w`` of point(s) ``z`` on the right side circle of ``T``."""
    return left_side_depth(-np.conj(np.asarray(z, dtype=np.complex128)))


# ---------------------------------------------------------------------------------------------
# Landmarks
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TriangleLandmarks:
    """Landmark points of the model triangle for inner-triangle height ``h``.

    ``v1, v3, v5`` lie on the left side, ``v2, v4, v6`` are their mirror images on the right side,
    ``v7 = −h(√2−1)`` and ``v8 = h(√2−1)`` on the base.  ``D1, D3, D5`` are the hyperbolic distances
    of ``v1, v3, v5`` from ``w``.
    """

    h: float
    w: complex
    v: complex
    b_L: complex
    b_R: complex
    c: complex
    m_L: complex
    m_R: complex
    m_B: complex
    v1: complex
    v2: complex
    v3: complex
    v4: complex
    v5: complex
    v6: complex
    v7: complex
    v8: complex
    D1: float
    D3: float
    D5: float


def _mirror(z):
    return -np.conj(z)


def _land_on_left_side(p: complex, tau: complex) -> tuple[complex, gc.GCircle]:
    """Arc from ``p`` with tangent ``tau``, orthogonal to the left side of ``T``; landing point."""
    circ = gc.orthogonal_circle_with_tangent(p, tau, OUTER_LEFT)
    za, zb = gc.intersect(circ, OUTER_LEFT)
    hits = []
    for z in (complex(za), complex(zb)):
        if np.isfinite(z):
            th = math.atan2(z.imag, z.real - _OUTER_CENTER)
            if 3.0 * math.pi / 4.0 < th < math.pi:
                hits.append(z)
    if len(hits) != 1:
        raise DiskConstructionError(
            f"the arc from {p:.6g} does not land once on the left side of the model triangle"
        )
    return hits[0], circ


def _bottom_tangent_left(h: float) -> complex:
    """Unit tangent of T_i's bottom circle at ``b_L``, pointing away from ``b_R``."""
    s = (SQRT3 - 1.0) / 2.0
    b_l = h * s * (-1.0 + 1j)
    t = 1j * (b_l - 1j * SQRT3 * h)
    t /= abs(t)
    return -t if t.real > 0 else t


def _check_h(h: float) -> None:
    if not (isinstance(h, (int, float)) and math.isfinite(h) and 0.0 < h < 1.0 + SQRT2):
        raise DiskConstructionError(
            f"inner-triangle height h must lie in (0, 1+√2) = (0, {1 + SQRT2:.6f}), got {h!r}"
        )


def triangle_landmarks(h: float = 1.0) -> TriangleLandmarks:
    """Landmarks of the model Carleson triangle with inner triangle of top point ``ih`` (§6).

    The arcs to ``v1, v3, v5`` leave ``v`` (tangent ``e^{3πi/4}``), ``m_L`` (normal
    ``e^{5πi/6}``) and ``b_L`` (tangent of the bottom circle) and are orthogonal to the left side
    of ``T``.  For ``h = 1``: ``D1 = 0.6035, D3 = 1.0390, D5 = 1.7497``; ``D3−D1`` and ``D5−D3``
    do not depend on ``h``.

    Raises :class:`DiskConstructionError` if ``h`` is outside ``(0, 1+√2)`` or the landmarks
    degenerate.
    """
    _check_h(h)
    h = float(h)
    s = (SQRT3 - 1.0) / 2.0
    v = 1j * h
    b_l = h * s * (-1.0 + 1j)
    m_l = h * (1.0 - math.sqrt(6.0) / 2.0) + 1j * h / SQRT2
    v1, _ = _land_on_left_side(v, np.exp(3j * math.pi / 4.0))
    v3, _ = _land_on_left_side(m_l, np.exp(5j * math.pi / 6.0))
    v5, _ = _land_on_left_side(b_l, _bottom_tangent_left(h))
    d1, d3, d5 = (float(left_side_depth(z)) for z in (v1, v3, v5))
    if not (0.0 < d1 < d3 < d5 < math.inf):
        raise DiskConstructionError(f"degenerate landmark depths D1={d1}, D3={d3}, D5={d5} (h={h})")
    return TriangleLandmarks(
        h=h,
        w=complex(W_TOP),
        v=complex(v),
        b_L=complex(b_l),
        b_R=complex(_mirror(b_l)),
        c=complex(1j * h / SQRT3),
        m_L=complex(m_l),
        m_R=complex(_mirror(m_l)),
        m_B=complex(1j * h * (SQRT3 - SQRT2)),
        v1=complex(v1),
        v2=complex(_mirror(v1)),
        v3=complex(v3),
        v4=complex(_mirror(v3)),
        v5=complex(v5),
        v6=complex(_mirror(v5)),
        v7=complex(-h * (SQRT2 - 1.0)),
        v8=complex(h * (SQRT2 - 1.0)),
        D1=d1,
        D3=d3,
        D5=d5,
    )


# ---------------------------------------------------------------------------------------------
# Depth sequence
# ---------------------------------------------------------------------------------------------


def depth_sequence(
    h: float = 1.0, step: float = 0.25, d_max: float | None = None, growth: float = 1.0
) -> np.ndarray:
    """The global depth sequence ``0 = d_0 < d_1 < … < d_M = d_max``.

    It contains the landmark depths ``D1, D3, D5`` of :func:`triangle_landmarks` exactly; each of
    the knot intervals ``[0,D1], [D1,D3], [D3,D5]`` is split into ``⌈len/step⌉`` equal steps, so
    every spacing above ``D5`` is ``≤ step``.  With the default ``growth = 1`` the interval
    ``[D5, d_max]`` is split the same way; with ``growth > 1`` its steps grow geometrically,
    ``step·growth^k`` (k = 0, 1, …, scaled down uniformly to end exactly at ``d_max``).  Rows below
    ``D5`` deviate from 90° by about ``Δd·sech(d)/2`` rad only, so this coarsening keeps the chord
    angles of the triangle unchanged (its worst cells are in the corner region at ``w``).
    The default ``d_max = log(8/step) + 2`` makes the last row of every Carleson piece deviate
    from 90° by about ``e^{−d_max}`` (§5).  Every Carleson quadrilateral and triangle must use this
    one sequence so that their side rays match (Lemma 6.1's ``d_k``).

    Raises :class:`DiskConstructionError` if ``step ≤ 0``, ``growth < 1`` or ``d_max ≤ D5``.
    """
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0):
        raise DiskConstructionError(f"depth step must be a positive number, got {step!r}")
    if not (isinstance(growth, (int, float)) and math.isfinite(growth) and growth >= 1.0):
        raise DiskConstructionError(f"depth growth must be a number ≥ 1, got {growth!r}")
    lm = triangle_landmarks(h)
    if d_max is None:
        d_max = math.log(8.0 / step) + 2.0
    if not (math.isfinite(d_max) and d_max > lm.D5):
        raise DiskConstructionError(
            f"d_max = {d_max:.6g} must exceed the landmark depth D5 = {lm.D5:.6g} (h = {h}); "
            "use a larger d_max or a larger inner triangle"
        )
    knots = [0.0, lm.D1, lm.D3, lm.D5, float(d_max)]
    parts = []
    for a, b in itertools.pairwise(knots):
        if b == knots[-1] and growth > 1.0:
            steps = [step]
            while sum(steps) < (b - a) * (1.0 - 1e-9):
                steps.append(steps[-1] * growth)
            cum = np.cumsum(steps)
            seg = a + (b - a) * np.concatenate([[0.0], cum[:-1] / cum[-1]])
        else:
            n = max(1, math.ceil((b - a) / step - 1e-9))
            seg = a + (b - a) * np.arange(n) / n
        seg[0] = a
        parts.append(seg)
    parts.append(np.array([float(d_max)]))
    return np.concatenate(parts)


# ---------------------------------------------------------------------------------------------
# Region charts
# ---------------------------------------------------------------------------------------------

_RECT_TOL = 1e-8


class _RightCircularQuad:
    """A right circular quadrilateral with its two orthogonal foliations (Lemma 5.2).

    ``corners`` are in cyclic order (either orientation); side ``k`` runs from corner ``k`` to
    corner ``k+1`` on the generalised circle ``circles[k]``.  The chart ``χ`` maps the quad onto an
    axis-parallel rectangle with sides 0 and 2 horizontal (``Im χ`` constant) and sides 1 and 3
    vertical.  Leaves crossing sides 0↔2 are the vertical lines ``Re χ = const``, leaves crossing
    1↔3 the horizontal lines.
    """

    def __init__(self, name: str, corners: list[complex], circles: list[gc.GCircle]) -> None:
        self.name = name
        self.corners = np.asarray(corners, dtype=np.complex128)
        self.circles = circles
        d02 = abs(float(gc.inversive_distance(circles[0], circles[2])))
        d13 = abs(float(gc.inversive_distance(circles[1], circles[3])))
        self.inversive = (d02, d13)
        if min(d02, d13) < 1.0 - 1e-7:
            a, b = (circles[0], circles[2]) if d02 < d13 else (circles[1], circles[3])
            za, zb = gc.intersect(a, b)
            self.kind = "log"
            self.p, self.q = complex(za), complex(zb)
            if not (np.isfinite(self.p) and np.isfinite(self.q)):
                raise DiskConstructionError(f"region {name}: opposite sides do not meet twice")
            self.ref = 1.0 + 0j
            self.ref = complex(self._omega(np.mean(self.corners)))
        elif abs(d02 - 1.0) < 1e-7 and abs(d13 - 1.0) < 1e-7:
            # Parabolic: all four side circles pass through one point p (the second intersection
            # of the orthogonal circles of sides 0 and 1); 1/(z−p) maps the quad to a rectangle.
            za, zb = gc.intersect(circles[0], circles[1])
            za, zb = complex(za), complex(zb)
            c1 = self.corners[1]
            self.kind = "parabolic"
            self.p = za if abs(za - c1) > abs(zb - c1) else zb
            self.q = complex(np.inf)
            self.ref = 1.0 + 0j
        else:
            raise DiskConstructionError(
                f"region {name}: no pair of opposite sides meets (inversive distances {d02}, {d13})"
            )
        self.rot = 1.0 + 0j
        cc = self.chart(self.corners)
        e = cc[1] - cc[0]
        if self.kind == "parabolic":
            self.rot = complex(np.conj(e) / abs(e))
        else:
            self.rot = max((1.0 + 0j, 1j, -1.0 + 0j, -1j), key=lambda r: (r * e).real)
        cc = self.chart(self.corners)
        self.y02 = (cc[0].imag + cc[1].imag) / 2.0, (cc[2].imag + cc[3].imag) / 2.0
        self.x13 = (cc[1].real + cc[2].real) / 2.0, (cc[3].real + cc[0].real) / 2.0
        size = float(np.max(np.abs(cc - cc.mean())))
        err = max(
            abs(cc[0].imag - cc[1].imag),
            abs(cc[2].imag - cc[3].imag),
            abs(cc[1].real - cc[2].real),
            abs(cc[3].real - cc[0].real),
        )
        if not (err <= _RECT_TOL * max(size, 1.0)) or not (
            cc[1].real > cc[0].real and abs(cc[2].imag - cc[1].imag) > 0
        ):
            raise DiskConstructionError(
                f"region {name}: chart does not map the corners to a positive rectangle "
                f"(error {err:.3g})"
            )

    def _omega(self, z):
        z = np.asarray(z, dtype=np.complex128)
        if self.kind == "parabolic":
            return 1.0 / (z - self.p)
        return (z - self.p) / (z - self.q) / self.ref

    def chart(self, z) -> np.ndarray:
        """The rectangle chart χ (conformal, orientation preserving)."""
        om = self._omega(z)
        if self.kind == "parabolic":
            return self.rot * om
        return self.rot * np.log(om)

    def chart_inv(self, x) -> np.ndarray:
        """Inverse of :meth:`chart`."""
        x = np.asarray(x, dtype=np.complex128) / self.rot
        if self.kind == "parabolic":
            return self.p + 1.0 / x
        om = self.ref * np.exp(x)
        return (self.p - self.q * om) / (1.0 - om)

    def transfer(self, pts, from_side: int) -> np.ndarray:
        """End points on the opposite side of the leaves through ``pts`` on side ``from_side``."""
        x = self.chart(pts)
        if from_side in (0, 2):
            y = self.y02[1] if from_side == 0 else self.y02[0]
            return self.chart_inv(x.real + 1j * y)
        xx = self.x13[1] if from_side == 1 else self.x13[0]
        return self.chart_inv(xx + 1j * x.imag)

    def interior(self, side0, side1, side2, side3) -> np.ndarray:
        """Interior grid vertices (i, j): leaf i (crossing sides 0↔2) ∩ leaf j (crossing 1↔3)."""
        xs = self.chart(side0[1:-1]).real
        ys = self.chart(side1[1:-1]).imag
        return self.chart_inv(xs[:, None] + 1j * ys[None, :])


class _PencilQuad:
    """One of the three quadrilaterals of ``T_i`` meshed by two circle pencils (§6, Fig. 3).

    ``pencil02 = (x, x*)``: the pencil containing sides 0 and 2, whose leaves cross sides 1↔3;
    ``pencil13 = (y, y*)``: the pencil containing sides 1 and 3, whose leaves cross sides 0↔2.
    A leaf is the generalised circle through the two base points and one point.
    """

    def __init__(
        self,
        name: str,
        corners: list[complex],
        circles: list[gc.GCircle],
        pencil02: tuple[complex, complex],
        pencil13: tuple[complex, complex],
    ) -> None:
        self.name = name
        self.corners = np.asarray(corners, dtype=np.complex128)
        self.circles = circles
        self.pencil02 = pencil02
        self.pencil13 = pencil13

    def _pencil_of_side(self, k: int) -> tuple[complex, complex]:
        return self.pencil02 if k % 2 == 0 else self.pencil13

    def transfer(self, pts, from_side: int) -> np.ndarray:
        """End points on the opposite side of the leaves through ``pts`` on side ``from_side``."""
        pts = np.asarray(pts, dtype=np.complex128)
        x, xs = self._pencil_of_side(from_side + 1)
        leaves = gc.circle_through(x, xs, pts)
        tgt = (from_side + 2) % 4
        za, zb = gc.intersect(leaves, self.circles[tgt])
        a, b = self.corners[tgt], self.corners[(tgt + 1) % 4]
        base = self._pencil_of_side(tgt)[0]
        sa = _separation(za, base, a, b)
        sb = _separation(zb, base, a, b)
        out = np.where(sa <= sb, za, zb)
        if not np.all(np.minimum(sa, sb) < -0.5):
            raise DiskConstructionError(f"region {self.name}: a leaf misses its opposite side")
        return out

    def interior(self, side0, side1, side2, side3) -> np.ndarray:
        """Grid vertices ``(i, j)`` as intersections of the two pencils' leaves."""
        n0, n1 = len(side0), len(side1)
        y, ys = self.pencil13
        x, xs = self.pencil02
        p0, p2 = side0[1:-1], side2[::-1][1:-1]
        q1, q3 = side1[1:-1], side3[::-1][1:-1]
        li = gc.circle_through(y, ys, p0)
        lj = gc.circle_through(x, xs, q1)
        li_b = gc.GCircle(li.A[:, None], li.B[:, None], li.C[:, None])
        lj_b = gc.GCircle(lj.A[None, :], lj.B[None, :], lj.C[None, :])
        za, zb = gc.intersect(li_b, lj_b)
        score = []
        for z in (za, zb):
            s = _separation(z, y, p0[:, None], p2[:, None]) + _separation(
                z, x, q1[None, :], q3[None, :]
            )
            score.append(np.where(np.isfinite(s), s, np.inf))
        out = np.where(score[0] <= score[1], za, zb)
        best = np.minimum(score[0], score[1])
        if out.shape != (n0 - 2, n1 - 2) or not np.all(best < -1.0):
            raise DiskConstructionError(f"region {self.name}: leaves do not intersect inside")
        return out


def _separation(z, base, a, b) -> np.ndarray:
    """Normalised real part of the cross-ratio (z, base; a, b): −1 iff z lies on the arc a–b
    of their common circle that does not contain ``base``."""
    cr = gc.cross_ratio(z, base, a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.real(cr) / np.abs(cr)


# ---------------------------------------------------------------------------------------------
# The twelve regions
# ---------------------------------------------------------------------------------------------

REGION_NAMES = ("R1", "R2", "R3", "R4", "R5", "R6", "R7", "R8", "R9", "Q_v", "Q_L", "Q_R")


class _Geometry:
    """Circles, the nine right circular quads and the three pencil quads of ``T_i`` for ``h``."""

    def __init__(self, h: float) -> None:
        lm = triangle_landmarks(h)
        self.lm = lm
        h = lm.h
        r_i = SQRT2 * h
        til = gc.circle_from_center(h, r_i)  # left side of T_i, continues to v7
        tir = gc.circle_from_center(-h, r_i)  # right side of T_i, continues to v8
        bot = gc.circle_from_center(1j * SQRT3 * h, r_i)  # bottom of T_i
        tb = _bottom_tangent_left(h)
        a_v1 = gc.orthogonal_circle_with_tangent(lm.v, np.exp(3j * math.pi / 4), OUTER_LEFT)
        a_v2 = gc.orthogonal_circle_with_tangent(lm.v, np.exp(1j * math.pi / 4), OUTER_RIGHT)
        a_ml = gc.orthogonal_circle_with_tangent(lm.m_L, np.exp(5j * math.pi / 6), OUTER_LEFT)
        a_mr = gc.orthogonal_circle_with_tangent(lm.m_R, np.exp(1j * math.pi / 6), OUTER_RIGHT)
        a_bl = gc.orthogonal_circle_with_tangent(lm.b_L, tb, OUTER_LEFT)
        a_br = gc.orthogonal_circle_with_tangent(lm.b_R, -np.conj(tb), OUTER_RIGHT)
        s_l = gc.line_through(lm.c, lm.m_L)
        s_r = gc.line_through(lm.c, lm.m_R)
        ol, orr, base, ax = OUTER_LEFT, OUTER_RIGHT, REAL_AXIS, IMAG_AXIS
        v_star = complex(gc.invert(lm.v, bot))
        bl_star = complex(gc.invert(lm.b_L, tir))
        br_star = complex(gc.invert(lm.b_R, til))
        self.pencils = {"v": (lm.v, v_star), "b_L": (lm.b_L, bl_star), "b_R": (lm.b_R, br_star)}
        rq = _RightCircularQuad
        pq = _PencilQuad
        self.regions = {
            "R1": rq("R1", [lm.v, lm.v1, lm.w, lm.v2], [a_v1, ol, orr, a_v2]),
            "R2": rq("R2", [lm.v, lm.m_L, lm.v3, lm.v1], [til, a_ml, ol, a_v1]),
            "R3": rq("R3", [lm.m_L, lm.b_L, lm.v5, lm.v3], [til, a_bl, ol, a_ml]),
            "R4": rq("R4", [lm.b_L, lm.v5, -1.0, lm.v7], [a_bl, ol, base, til]),
            "R5": rq("R5", [lm.b_L, lm.v7, 0.0, lm.m_B], [til, base, ax, bot]),
            "R6": rq("R6", [lm.b_R, lm.m_B, 0.0, lm.v8], [bot, ax, base, tir]),
            "R7": rq("R7", [lm.b_R, lm.v8, 1.0, lm.v6], [tir, base, orr, a_br]),
            "R8": rq("R8", [lm.m_R, lm.v4, lm.v6, lm.b_R], [a_mr, orr, a_br, tir]),
            "R9": rq("R9", [lm.v, lm.v2, lm.v4, lm.m_R], [a_v2, orr, a_mr, tir]),
            "Q_v": pq(
                "Q_v",
                [lm.v, lm.m_L, lm.c, lm.m_R],
                [til, s_l, s_r, tir],
                self.pencils["b_L"],
                self.pencils["b_R"],
            ),
            "Q_L": pq(
                "Q_L",
                [lm.b_L, lm.m_B, lm.c, lm.m_L],
                [bot, ax, s_l, til],
                self.pencils["b_R"],
                self.pencils["v"],
            ),
            "Q_R": pq(
                "Q_R",
                [lm.b_R, lm.m_R, lm.c, lm.m_B],
                [tir, s_r, ax, bot],
                self.pencils["v"],
                self.pencils["b_L"],
            ),
        }


# Leaf routes for a leaf starting on the LEFT side: (region, entry side) pairs.
_ROUTES = (
    ("0<d<D1", (("R1", 1), ("R9", 0), ("R8", 0), ("R7", 3))),
    ("D1<d<D3", (("R2", 2), ("Q_v", 0), ("Q_R", 1), ("R6", 0))),
    ("D3<d<D5", (("R3", 2), ("Q_L", 3), ("Q_R", 2), ("R8", 3))),
    ("d>D5", (("R4", 1), ("R5", 0), ("R6", 1), ("R7", 0))),
)


def trace_leaf(d: float, h: float = 1.0, side: str = "left") -> np.ndarray:
    """Follow the leaf that starts on the left (or right) side of ``T`` at depth ``d``.

    Returns the points where it crosses region boundaries, from its start on ``∂T`` to its end: on
    the base ``ℝ`` for ``d < D3``, on the opposite side of ``T`` for ``d > D3`` (by symmetry at the
    same depth ``d``, Lemma 6.1).  ``d`` must not be one of the landmark depths (those are region
    boundaries, not leaves).  Uses the region foliations directly, independently of any mesh.
    """
    if side not in ("left", "right"):
        raise DiskConstructionError(f"side must be 'left' or 'right', got {side!r}")
    geo = _Geometry(h)
    lm = geo.lm
    if not (0.0 < d < math.inf) or min(abs(d - lm.D1), abs(d - lm.D3), abs(d - lm.D5)) < 1e-12:
        raise DiskConstructionError(f"depth {d} is not inside one of the leaf bands")
    band = 0 if d < lm.D1 else 1 if d < lm.D3 else 2 if d < lm.D5 else 3
    z = complex(left_side_point(d))
    pts = [z]
    for name, entry in _ROUTES[band][1]:
        z = complex(geo.regions[name].transfer(np.array([z]), entry)[0])
        pts.append(z)
    out = np.array(pts)
    return out if side == "left" else -np.conj(out)


# ---------------------------------------------------------------------------------------------
# The mesh
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ModelTriangleMesh:
    """Conforming quad mesh of the model Carleson triangle ``T`` in H (Lemma 6.1).

    * ``vertices`` (V,) complex; ``quads`` (Q, 4) int, counter-clockwise.
    * ``inner`` (Q,) bool: quad inside ``T_i``; ``inner_vertex`` (V,) bool: vertex in/on ``∂T_i``.
    * ``center``: the centre ``c = ih/√3`` of ``T_i`` (where three quads meet at 120°).
    * ``left``: vertex indices along the left side (centre ``+(1+√2)``) from ``w`` down to ``−1``:
      ``w``, the vertices at distance ``d_1, …, d_M`` from ``w``, then ``−1`` (length ``M+2``).
      ``right``: the same along the right side from ``w`` to ``+1``.
    * ``base``: the vertices on ℝ, increasing from ``−1`` to ``1`` (including both).
    * ``region`` (Q,) int: index into :data:`REGION_NAMES` (R1…R9, Q_v, Q_L, Q_R).
    """

    vertices: np.ndarray
    quads: np.ndarray
    inner: np.ndarray
    inner_vertex: np.ndarray
    center: complex
    left: np.ndarray
    right: np.ndarray
    base: np.ndarray
    region: np.ndarray
    depths: np.ndarray
    landmarks: TriangleLandmarks


class _VertexStore:
    def __init__(self) -> None:
        self._chunks: list[np.ndarray] = []
        self.n = 0

    def add(self, z) -> np.ndarray:
        z = np.atleast_1d(np.asarray(z, dtype=np.complex128)).ravel()
        idx = np.arange(self.n, self.n + z.size)
        self._chunks.append(z)
        self.n += z.size
        return idx

    def array(self) -> np.ndarray:
        return np.concatenate(self._chunks) if self._chunks else np.zeros(0, np.complex128)


def _locate(depths: np.ndarray, value: float, name: str) -> int:
    hits = np.flatnonzero(np.abs(depths - value) <= 1e-9 * max(1.0, value))
    if hits.size != 1:
        raise DiskConstructionError(
            f"the depth sequence must contain the landmark depth {name} = {value:.12g} exactly once"
        )
    return int(hits[0])


def model_triangle_mesh(depths: np.ndarray, h: float = 1.0) -> ModelTriangleMesh:
    """Quad mesh of the model Carleson triangle ``T`` (vertices ``−1, 1, i(1+√2)``) in H (§6).

    ``depths`` is the global sequence of :func:`depth_sequence` (``0 = d_0 < … < d_M``, containing
    ``D1, D3, D5`` of ``h``, ``d_M > D5``).  The left/right side vertices are at hyperbolic distance
    ``d_k`` from ``w``; leaves are continued through the nine right circular quadrilaterals and the
    three pencil quadrilaterals of ``T_i`` along the leaf routes; every region is a
    tensor grid of its two leaf families whose sides are shared vertex lists (conforming by
    construction).  Below the last leaf ``d_M`` one row of cells reaches the base ℝ.

    Curvilinear angles are 90° outside ``T_i`` and in ``[60°, 120°]`` inside; the chord angles are
    90 ± O(step) outside ``T_i`` and in ``[60°, 120°]`` inside (maximum exactly 120° at ``c``).
    """
    geo = _Geometry(h)
    lm = geo.lm
    d = np.asarray(depths, dtype=np.float64).ravel()
    if d.size < 5 or d[0] != 0.0 or not np.all(np.diff(d) > 0) or not np.all(np.isfinite(d)):
        raise DiskConstructionError("depths must start at 0, be finite and strictly increasing")
    k1 = _locate(d, lm.D1, "D1")
    k3 = _locate(d, lm.D3, "D3")
    k5 = _locate(d, lm.D5, "D5")
    if k5 == d.size - 1:
        raise DiskConstructionError("the depth sequence must go beyond D5 (d_max > D5)")
    R = geo.regions
    vs = _VertexStore()

    def pts(idx: np.ndarray) -> np.ndarray:
        return vs.array()[idx]

    # Landmark vertices (shared corners).
    iw, iv, ic = vs.add([lm.w, lm.v, lm.c])
    iml, imr, ibl, ibr, imb = vs.add([lm.m_L, lm.m_R, lm.b_L, lm.b_R, lm.m_B])
    iv7, iv8, i0, im1, ip1 = vs.add([lm.v7, lm.v8, 0.0, -1.0, 1.0])
    # Outer sides at the prescribed depths; the corner vertices v1, v3, v5 (v2, v4, v6) are the
    # depth points D1, D3, D5.
    dl = d[1:]
    left_mid = vs.add(left_side_point(dl))
    right_mid = vs.add(right_side_point(dl))
    left = np.concatenate([[iw], left_mid, [im1]])
    right = np.concatenate([[iw], right_mid, [ip1]])
    ol_a, ol_b, ol_c, ol_d = left[: k1 + 1], left[k1 : k3 + 1], left[k3 : k5 + 1], left[k5:]
    or_a, or_b, or_c, or_d = right[: k1 + 1], right[k1 : k3 + 1], right[k3 : k5 + 1], right[k5:]
    iv1, iv3, iv5 = left[k1], left[k3], left[k5]
    iv2, iv4, iv6 = right[k1], right[k3], right[k5]

    def rev(a: np.ndarray) -> np.ndarray:
        return a[::-1]

    def carry(
        region: str, src: np.ndarray, from_side: int, a: int, b: int, real: bool = False
    ) -> np.ndarray:
        """Side list (from corner a to corner b) of the side opposite ``from_side``."""
        new = R[region].transfer(pts(src[1:-1]), from_side)[::-1]
        if real:  # ideal points on the base: exactly on ℝ
            new = new.real + 0j
        return np.concatenate([[a], vs.add(new), [b]])

    # Propagation order: every side list is computed once, from its source side.
    a_v1 = carry("R1", or_a, 2, iv, iv1)  # right leaves 0<d<D1
    a_v2 = rev(carry("R1", rev(ol_a), 1, iv2, iv))  # left leaves 0<d<D1
    til_t = carry("R2", rev(ol_b), 2, iv, iml)  # left leaves D1<d<D3
    a_ml = carry("R2", rev(a_v1), 3, iml, iv3)  # right leaves 0<d<D1
    a_mr = rev(carry("R9", a_v2, 0, iv4, imr))  # left leaves 0<d<D1
    tir_t = rev(carry("R9", or_b, 1, imr, iv))  # right leaves D1<d<D3
    til_b = carry("R3", rev(ol_c), 2, iml, ibl)  # left leaves D3<d<D5
    a_bl = carry("R3", rev(a_ml), 3, ibl, iv5)  # right leaves 0<d<D1
    a_br = rev(carry("R8", a_mr, 0, iv6, ibr))  # left leaves 0<d<D1
    tir_b = rev(carry("R8", or_c, 1, ibr, imr))  # right leaves D3<d<D5 (m_R -> b_R)
    b1 = carry("R4", a_bl, 0, im1, iv7, real=True)  # right leaves 0<d<D1 reach the base
    g_l = rev(carry("R4", ol_d, 1, iv7, ibl))  # left leaves d>D5
    b4 = carry("R7", rev(a_br), 3, iv8, ip1, real=True)  # left leaves 0<d<D1 reach the base
    g_r = carry("R7", rev(or_d), 2, ibr, iv8)  # right leaves d>D5
    s_r = carry("Q_v", til_t, 0, ic, imr)  # left leaves D1<d<D3
    s_l = carry("Q_v", rev(tir_t), 3, iml, ic)  # right leaves D1<d<D3
    tib_l = carry("Q_L", rev(s_l), 2, ibl, imb)  # right leaves D1<d<D3
    s_b = carry("Q_L", til_b, 3, imb, ic)  # left leaves D3<d<D5
    tib_r = carry("Q_R", rev(s_r), 1, imb, ibr)  # left leaves D1<d<D3
    ax = carry("R5", g_l, 0, i0, imb)  # left leaves d>D5
    b2 = carry("R5", rev(tib_l), 3, iv7, i0, real=True)  # right leaves D1<d<D3 reach the base
    b3 = carry("R6", rev(tib_r), 0, i0, iv8, real=True)  # left leaves D1<d<D3 reach the base

    sides = {
        "R1": (a_v1, rev(ol_a), or_a, rev(a_v2)),
        "R2": (til_t, a_ml, rev(ol_b), rev(a_v1)),
        "R3": (til_b, a_bl, rev(ol_c), rev(a_ml)),
        "R4": (a_bl, ol_d, b1, rev(g_l)),
        "R5": (g_l, b2, ax, rev(tib_l)),
        "R6": (rev(tib_r), rev(ax), b3, rev(g_r)),
        "R7": (g_r, b4, rev(or_d), rev(a_br)),
        "R8": (a_mr, or_c, rev(a_br), rev(tir_b)),
        "R9": (a_v2, or_b, rev(a_mr), rev(tir_t)),
        "Q_v": (til_t, s_l, s_r, rev(tir_t)),
        "Q_L": (tib_l, s_b, rev(s_l), til_b),
        "Q_R": (rev(tir_b), rev(s_r), rev(s_b), tib_r),
    }
    quads, region, inner_v = [], [], []
    for k, name in enumerate(REGION_NAMES):
        s0, s1, s2, s3 = sides[name]
        n0, n1 = len(s0), len(s1)
        if len(s2) != n0 or len(s3) != n1:
            raise DiskConstructionError(f"region {name}: opposite sides have different lengths")
        if s0[-1] != s1[0] or s1[-1] != s2[0] or s2[-1] != s3[0] or s3[-1] != s0[0]:
            raise DiskConstructionError(f"region {name}: side lists do not close up")
        g = np.empty((n0, n1), dtype=np.int64)
        g[:, 0] = s0
        g[n0 - 1, :] = s1
        g[:, n1 - 1] = s2[::-1]
        g[0, :] = s3[::-1]
        if n0 > 2 and n1 > 2:
            inside = R[name].interior(pts(s0), pts(s1), pts(s2), pts(s3))
            g[1:-1, 1:-1] = vs.add(inside.ravel()).reshape(n0 - 2, n1 - 2)
        a, b, c_, e = g[:-1, :-1], g[1:, :-1], g[1:, 1:], g[:-1, 1:]
        cz = R[name].corners
        ccw = np.sum(np.imag(np.conj(cz) * np.roll(cz, -1))) > 0
        q = np.stack([a, b, c_, e] if ccw else [a, e, c_, b], axis=-1).reshape(-1, 4)
        quads.append(q)
        region.append(np.full(len(q), k, dtype=np.int8))
        if name.startswith("Q_"):
            inner_v.append(g.ravel())

    verts = vs.array()
    quads_a = np.concatenate(quads)
    region_a = np.concatenate(region)
    inner_vertex = np.zeros(verts.size, dtype=bool)
    inner_vertex[np.concatenate(inner_v)] = True
    base = np.concatenate([b1, b2[1:], b3[1:], b4[1:]])
    return ModelTriangleMesh(
        vertices=verts,
        quads=quads_a,
        inner=region_a >= 9,
        inner_vertex=inner_vertex,
        center=lm.c,
        left=left,
        right=right,
        base=base,
        region=region_a,
        depths=d.copy(),
        landmarks=lm,
    )
