"""Transition cells: a convex cell whose two opposite sides carry different point counts.

A strip of quads keeps its count across: every row of a bilinear grid runs from one side of
the cell to the opposite side.  Changing the count needs irregular vertices (Euler: a quad mesh
of a disk with every boundary point straight has as many valence-3 as valence-5 interior
vertices, boundary vertices with three quads counting like valence 5).  In a quad mesh whose
every angle lies in [60°, 120°] a valence-3 vertex has exactly three 120° angles, and a
straight boundary point with three quads exactly three 60° angles, so a transition must be
built around exact 120° vertices and *bent* interior lines.

The template used here splits coarse rows two at a time.  In the ruled (bilinear) frame of a
cell, coarse rows are the strips between consecutive ``p``-isolines ("lines"); one interior
``u``-isoline, the *split column*, carries a point ``O`` on every line.  A *pair* is two
adjacent coarse rows, the lower one split "flipped" (F) and the upper one split "normal" (N):

* the line between them gets one extra point ``W`` just before the column and its ``O`` just
  after it;
* each split row gets a valence-3 vertex ``Q`` at the Fermat point of its row's three
  neighbours (its ``O`` on the shared line, its ``O`` on the far line and the first point of
  the row's new middle line), so its three angles are exactly 120°;
* the far ``O`` of each split row (a point with three quads of that row) is moved into the row
  by about 0.62 of the row's height, so the far line bends there: its three angles are 60° plus
  a share of the bend, the plain row on the other side takes the rest.

Per pair, four quads in each split row replace two (coarse rows to the left of the column,
fine rows to the right of it).  Pairs are separated by at least two plain rows and never touch
a side of the cell, so each pair's four free points (the two far ``O``, the shared ``W`` and
``O``) are placed independently: first by the measured template (in a rectangle, columns 1.5
row heights away: every other angle within [67.5°, 112.5°]), then, if that leaves less than
:data:`MIN_MARGIN` inside [60°, 120°] (graded rows, skewed cells), by a small optimisation
(soft minimum, then SLSQP) of the smallest margin of the quads around the pair.  Everything
outside the split column's two neighbouring columns is the bilinear grid of the cell (coarse
rows before the column, fine rows after it), so those angles keep the bilinear guarantee of
:mod:`quadmesh.cells`.

Plane points are complex128.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize

from .errors import QuadmeshError
from .geometry import quad_angles_deg

__all__ = [
    "COLUMN_GAP",
    "FERMAT_ROOM",
    "MIN_MARGIN",
    "UNEVEN",
    "TransitionError",
    "TransitionMesh",
    "coarse_rows",
    "fermat_point",
    "max_pairs",
    "pair_rows",
    "plan_pairs",
    "transition_cascade",
    "transition_mesh",
]

#: Distance of the split column's neighbouring columns, in units of the largest height of a
#: split row (the measured template has them 1.5 heights away; much farther, the middle lines
#: leave the valence-3 vertices too flat and the angles at the shared line reach 60°/120°).
COLUMN_GAP = 1.5

#: Largest ratio of row heights among a pair's four fine rows and the plain row on each side
#: that :func:`plan_pairs` accepts.
UNEVEN = 1.6

#: Smallest distance of a valence-3 vertex from its three neighbours, relative to the shortest
#: side of their triangle.
FERMAT_ROOM = 0.2

#: A pair whose template placement misses [60°, 120°] by more than this (degrees) is not
#: polished: the placement is folded, no local move repairs it.
HOPELESS = 30.0

#: Smallest margin (degrees) inside [60°, 120°] accepted for the angles a pair places (the
#: exact 120° angles at the valence-3 vertices excepted).
MIN_MARGIN = 1.0

#: How many of the latest offsets found in a cascade :func:`_polish` tries before optimising.
POLISH_HINTS = 8

# Measured template of a pair in a rectangle with rows of height 1 and the neighbouring
# columns 1.5 away (SLSQP optimum of the smallest margin: 7.5°): the far O of each split row
# moves into its row by _BEND of the row's height; on the shared line W sits _W_BACK before
# the column and O _O_AHEAD after it, in units of the mean height of the two rows.
_BEND = 0.6213
_W_BACK = 0.1569
_O_AHEAD = 0.1791


class TransitionError(QuadmeshError):
    """A transition cell cannot be built with every angle in [60°, 120°]."""

    stage = "cells"


def fermat_point(
    a: ArrayLike, b: ArrayLike, c: ArrayLike, refine: bool = True
) -> NDArray[np.complex128]:
    """Fermat (Torricelli) point of each triangle (a, b, c): the point seeing every side at
    exactly 120°, for triangles with every angle below 120°.  It is the intersection of the
    lines from a and b to the apexes of the equilateral triangles erected outwards on bc and ca,
    then (``refine``) polished by Newton steps on the sum of the unit vectors from a, b, c."""
    a, b, c = (np.asarray(x, dtype=np.complex128) for x in (a, b, c))
    orient = np.sign(np.imag(np.conj(b - a) * (c - a)))
    rot = np.exp(-1j * np.pi / 3 * orient)
    e = b + (c - b) * rot
    g = c + (a - c) * rot
    d1, d2 = e - a, g - b
    t = np.imag(np.conj(d2) * (b - a)) / np.imag(np.conj(d2) * d1)
    q = a + t * d1
    if not refine:
        return q

    # Newton steps on the sum of unit vectors (zero at the Fermat point), each kept only where
    # it reduces that sum: the construction above loses digits in thin triangles, and the
    # angles must read 120° to ~1e-12°
    def resid(p: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], list]:
        g = np.zeros_like(p)
        parts = []
        for v in (a, b, c):
            d = p - v
            r = np.abs(d)
            w = d / r
            g = g + w
            parts.append((w, r))
        return g, parts

    for _ in range(3):
        g, parts = resid(q)
        hxx = sum((1.0 - w.real**2) / r for w, r in parts)
        hxy = sum(-(w.real * w.imag) / r for w, r in parts)
        hyy = sum((1.0 - w.imag**2) / r for w, r in parts)
        det = hxx * hyy - hxy**2
        step = ((hyy * g.real - hxy * g.imag) + 1j * (hxx * g.imag - hxy * g.real)) / det
        cand = q - step
        better = np.abs(resid(cand)[0]) < np.abs(g)
        q = np.where(better & np.isfinite(cand), cand, q)
    return q


def max_pairs(k: int) -> int:
    """Largest number of pairs a cell with ``k`` coarse rows can split: rows
    P (F N P P)* … F N P, i.e. ``k // 4``."""
    return max(0, int(k) // 4)


def pair_rows(heights: ArrayLike, n_pairs: int) -> NDArray[np.int64]:
    """The lower coarse row of each of ``n_pairs`` pairs among coarse rows of the given
    ``heights`` (any positive weights), ascending: pairs never include the first or last row
    and are separated by at least two plain rows; among the admissible choices the pairs go
    where the two rows are thinnest (a dynamic programme over the rows: exact, O(k·n_pairs))."""
    h = np.asarray(heights, dtype=np.float64)
    k = h.size
    if n_pairs < 0 or n_pairs > max_pairs(k):
        raise ValueError(f"{n_pairs} pairs do not fit in {k} rows (at most {max_pairs(k)})")
    if n_pairs == 0:
        return np.zeros(0, dtype=np.int64)
    # candidate pair at rows (i, i+1), i in 1..k-3; cost = the larger of the two heights
    cand = np.full(k, np.inf)
    cand[1 : k - 2] = np.maximum(h[1 : k - 2], h[2 : k - 1])
    # best[p][i]: least total cost of p pairs whose last pair starts at row <= i
    inf = np.inf
    best = np.full((n_pairs + 1, k), inf)
    best[0, :] = 0.0
    take = np.zeros((n_pairs + 1, k), dtype=bool)
    for p in range(1, n_pairs + 1):
        for i in range(k):
            prev = best[p, i - 1] if i > 0 else inf
            # a pair at (i, i+1) needs the previous pair to start at row <= i - 4
            before = best[p - 1, i - 4] if i >= 4 else (0.0 if p == 1 else inf)
            here = before + cand[i]
            if here < prev:
                best[p, i], take[p, i] = here, True
            else:
                best[p, i] = prev
    if not np.isfinite(best[n_pairs, k - 1]):
        raise ValueError(f"{n_pairs} pairs do not fit in {k} rows")
    out = []
    p, i = n_pairs, k - 1
    while p > 0:
        if take[p, i]:
            out.append(i)
            p, i = p - 1, i - 4
        else:
            i -= 1
    return np.array(out[::-1], dtype=np.int64)


def coarse_rows(
    p_fine: ArrayLike, pairs: ArrayLike, half: str | None = None
) -> tuple[NDArray[np.float64], str]:
    """The coarse parameters and row kinds of a transition whose fine side carries
    ``p_fine`` (k + 2·len(pairs) + 1 increasing values from 0 to 1, one more with ``half``)
    and whose pairs start at the coarse rows ``pairs`` (from :func:`pair_rows` on the coarse
    rows).  ``half`` ("low" or "high", no pairs then): a *parity row* instead, the first
    coarse row split as the upper row of a pair ("N", its shared line being the wall p = 0) or
    the last one as the lower row ("F", shared line p = 1): :func:`transition_mesh`.

    Each split coarse row covers two fine rows; the fine value between them is dropped on the
    coarse side (it starts the row's new middle line).  Returns ``(p_coarse, kinds)`` with
    ``kinds[i]`` one of "P" (plain), "F", "N"."""
    pf = np.asarray(p_fine, dtype=np.float64)
    pairs = np.asarray(pairs, dtype=np.int64)
    if half not in (None, "low", "high"):
        raise ValueError(f"half must be None, 'low' or 'high', not {half!r}")
    if half is not None and pairs.size:
        raise ValueError("a parity row is built on its own, without pairs")
    k = pf.size - 1 - 2 * pairs.size - (half is not None)
    if k < 1:
        raise ValueError(f"{pf.size - 1} fine rows leave no coarse row")
    kinds = ["P"] * k
    for i in pairs:
        kinds[i], kinds[i + 1] = "F", "N"
    if half == "low":
        kinds[0] = "N"
    elif half == "high":
        kinds[-1] = "F"
    keep, f = [0], 0
    for c in kinds:
        f += 2 if c != "P" else 1
        keep.append(f)
    return pf[np.array(keep)], "".join(kinds)


@dataclass(frozen=True)
class TransitionMesh:
    """The mesh of one transition cell.

    Attributes:
        points: (N,) complex points.
        quads: (Q, 4) counter-clockwise point indices.
        coarse: point indices on the coarse side (rung u = 0), p ascending.
        fine: point indices on the fine side (rung u = 1), p ascending.
        wall0: point indices along the side p = 0, u ascending (from the coarse side).
        wall1: point indices along the side p = 1, u ascending.
        u: the wall parameters of ``wall0`` and ``wall1`` (both walls carry the same, except
            that the wall of a parity row (``parity``) carries its point ``W`` too, and that
            after ``transition_cascade(straighten=True)`` they are ``wall0``'s: ``wall1``'s
            differ and are read from its points).
        p_coarse: the coarse side's parameters (from c0 to c3).
        margin: smallest distance (degrees) of the placed angles from 60° and 120° (the exact
            120° angles at the valence-3 vertices excepted).
        polished: how many pairs needed the optimisation (the template left them too close to
            60° or 120°).
    """

    points: NDArray[np.complex128]
    quads: NDArray[np.int64]
    coarse: NDArray[np.int64]
    fine: NDArray[np.int64]
    wall0: NDArray[np.int64]
    wall1: NDArray[np.int64]
    u: NDArray[np.float64]
    p_coarse: NDArray[np.float64]
    margin: float
    polished: int = 0
    parity: str = ""


def _ruled(corners: NDArray[np.complex128], u: ArrayLike, p: ArrayLike) -> NDArray[np.complex128]:
    """Points X(u, p) of the ruled cell with rungs c0 -> c3 (u = 0) and c1 -> c2 (u = 1), with
    broadcasting of ``u`` and ``p``; evaluated relative to c0."""
    c0, c1, c2, c3 = corners
    u = np.asarray(u, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    return c0 + u * (c1 - c0) + p * (c3 - c0) + (u * p) * (c0 - c1 + c2 - c3)


def _margin(z: NDArray[np.complex128], quads: NDArray[np.int64], exact: NDArray[np.bool_]) -> float:
    """Smallest distance (degrees) of the angles of ``quads`` from 60° and 120°, the angles
    flagged ``exact`` (at valence-3 vertices) left out."""
    a = quad_angles_deg(z, quads)[~exact]
    if a.size == 0:
        return 90.0
    return float(min((a - 60.0).min(), (120.0 - a).min()))


def _fermat_room(z: NDArray[np.complex128], spec: NDArray[np.int64]) -> NDArray[np.float64]:
    """Per valence-3 vertex (rows of ``spec``: Q and its three neighbours), its distance to the
    nearest neighbour over the shortest side of the neighbours' triangle, less
    :data:`FERMAT_ROOM`, times 100 (so that it reads like a margin in degrees).  A Fermat point
    crowding a neighbour makes a sliver whose 120° angles float64 cannot hold.  ``z`` may be
    stacked (B, V): one row of values per copy."""
    if spec.size == 0:
        return np.zeros((*z.shape[:-1], 0))
    q, x = z[..., spec[:, 0]], z[..., spec[:, 1:]]
    near = np.abs(x - q[..., None]).min(axis=-1)
    side = np.abs(x - z[..., spec[:, [3, 1, 2]]]).min(axis=-1)  # each neighbour to the one before
    return 100.0 * (near / side - FERMAT_ROOM)


def transition_mesh(
    corners: ArrayLike,
    p_fine: ArrayLike,
    pairs: ArrayLike,
    u: ArrayLike | None = None,
    at: float = 0.5,
    p_coarse: ArrayLike | None = None,
    polish: list[int] | None = None,
    half: str | None = None,
    hints: list[NDArray[np.float64]] | None = None,
    reuse: bool = False,
) -> TransitionMesh:
    """Mesh the convex cell ``corners`` (c0, c1, c2, c3 counter-clockwise, every corner in
    [60°, 120°]) with coarse rows on its side c0 -> c3 and fine rows on its side c1 -> c2.

    ``p_fine``: the fine side's parameters (from c1 to c2, increasing from 0 to 1);
    ``pairs``: lower coarse row of every pair (:func:`pair_rows`), which fixes the coarse
    side's parameters (:func:`coarse_rows`); ``half`` ("low" or "high", without pairs): one
    *parity row* instead, the fine side carrying one row more than the coarse side.  A pair's
    two split rows share a straight line on which the pair puts its extra point ``W`` and its
    moved ``O``, each with angles adding up to 180° on either side; the parity row is one of
    them with that line being a wall of the cell (p = 0 for "low", p = 1 for "high"), so the
    wall carries ``W`` as one more point than the other wall (a quad mesh of a disk has an even
    number of boundary edges: the count across can change by one only so) and ``W`` and ``O``
    stay on the wall.  ``u``: wall parameters wanted on both walls
    c0 -> c1 and c3 -> c2 (increasing from 0 to 1; default none inside); ``at``: where along
    the cell (a wall parameter) the rows split.

    The split column's two neighbouring columns are placed :data:`COLUMN_GAP` times the pairs'
    largest row height before and after it (wanted wall parameters closer to it than that are
    dropped), so the walls carry ``u`` plus these three values: the walls' actual points are
    returned in :attr:`TransitionMesh.wall0` and :attr:`TransitionMesh.wall1`.

    ``polish``: a one-item budget of pair optimisations (shared with the caller); ``hints``:
    the offsets optimised for earlier pairs (:func:`_polish`), shared by the stages of a
    cascade (by default the pairs of this call share theirs); ``reuse``: once the budget is
    spent, pairs still try the hints (no optimisation) instead of keeping the template.

    Raises :class:`TransitionError` if some angle cannot be kept in [60°, 120°] with at least
    :data:`MIN_MARGIN` to spare (the exact 120° angles at the valence-3 vertices excepted)."""
    cn = np.asarray(corners, dtype=np.complex128)
    pf = np.asarray(p_fine, dtype=np.float64)
    pairs = np.asarray(pairs, dtype=np.int64)
    hints = [] if hints is None else hints
    pc, kinds = coarse_rows(pf, pairs, half)
    k = pc.size - 1
    if not 0.0 < at < 1.0:
        raise ValueError("the split must lie inside the cell (0 < at < 1)")
    # the split column and its neighbours, COLUMN_GAP pair heights away
    lines = _ruled(cn, at, pc)
    gap = 0.0
    h = np.abs(np.diff(lines))
    if pairs.size:
        gap = COLUMN_GAP * float(np.maximum(h[pairs], h[pairs + 1]).max())
    elif half is not None:
        gap = COLUMN_GAP * float(h[0] if half == "low" else h[-1])
    du_len = float(np.abs(_ruled(cn, 1.0, pc) - _ruled(cn, 0.0, pc)).min())
    du = gap / du_len
    want = np.array([0.0, 1.0]) if u is None else np.asarray(u, dtype=np.float64)
    if want[0] != 0.0 or want[-1] != 1.0 or np.any(np.diff(want) <= 0):
        raise ValueError("u must increase from 0 to 1")
    lo, hi = at - du, at + du
    if lo <= 0.0 or hi >= 1.0:
        raise TransitionError(
            f"a transition cell from {k} to {pf.size - 1} rows needs {2 * gap:.3g} of length "
            f"along the cell around its split; the cell is too short"
        )
    keep = want[(want < lo - 0.25 * du) | (want > hi + 0.25 * du)]
    u = np.unique(np.concatenate([keep, [lo, at, hi]]))
    column = int(np.flatnonzero(u == at)[0])
    # fine index of every coarse line and of every split row's middle line
    line_f = np.zeros(k + 1, dtype=np.int64)
    mid_f = np.full(k, -1, dtype=np.int64)
    f = 0
    for i, c in enumerate(kinds):
        if c != "P":
            mid_f[i] = f + 1
            f += 2
        else:
            f += 1
        line_f[i + 1] = f

    pts: list[NDArray[np.complex128]] = []
    count = 0

    def new(z: NDArray[np.complex128]) -> NDArray[np.int64]:
        nonlocal count
        z = np.asarray(z, dtype=np.complex128)
        ids = np.arange(count, count + z.size).reshape(z.shape)
        pts.append(z.ravel())
        count += z.size
        return ids

    # coarse grid: columns 0..column-1 on the coarse lines; fine grid: columns column+1..m
    p_side = pc if p_coarse is None else np.asarray(p_coarse, dtype=np.float64)
    if p_side.shape != pc.shape or p_side[0] != 0.0 or p_side[-1] != 1.0:
        raise ValueError("p_coarse must have one value per coarse line, from 0 to 1")
    w_u = u[:column] / u[column - 1]  # 0 on the coarse side, 1 at the split column's neighbour
    p_grid = p_side[:, None] + (pc - p_side)[:, None] * w_u[None, :]
    coarse_ids = new(_ruled(cn, u[None, :column], p_grid))  # (k+1, column)
    fine_ids = new(_ruled(cn, u[None, column + 1 :], pf[:, None]))  # (kf+1, m-column)
    # split column: O on every coarse line (moved below), W on the lines shared by a pair
    o_base = _ruled(cn, u[column], pc)
    o_ids = new(o_base.copy())
    w_line = pairs + 1
    if half is not None:
        w_line = np.array([0 if half == "low" else k], dtype=np.int64)
    w_ids = new(_ruled(cn, u[column], pc[w_line]))
    z = np.concatenate(pts)
    # corners of the cell exactly
    z[coarse_ids[0, 0]], z[coarse_ids[-1, 0]] = cn[0], cn[3]
    z[fine_ids[0, -1]], z[fine_ids[-1, -1]] = cn[1], cn[2]

    # valence-3 vertices, one per split row
    split = np.flatnonzero(np.array([c != "P" for c in kinds], dtype=bool))
    q_ids = np.arange(count, count + split.size)
    z = np.concatenate([z, np.zeros(split.size, dtype=np.complex128)])
    count += split.size
    q_of = dict(zip(split.tolist(), q_ids.tolist()))

    a_col = coarse_ids[:, -1]  # column - 1 on the coarse lines
    r_col = fine_ids[:, 0]  # column + 1 on the fine lines
    w_of = dict(zip(w_line.tolist(), w_ids.tolist()))
    quads: list[tuple[int, int, int, int]] = []
    # per split row: (Q, shared O, middle M, far O)
    fermat_spec: list[tuple[int, int, int, int]] = []
    for i, c in enumerate(kinds):
        ab, at = a_col[i], a_col[i + 1]
        ob, ot = o_ids[i], o_ids[i + 1]
        if c == "P":  # W lines lie inside pairs, never on a plain row
            quads.append((ab, ob, ot, at))
            quads.append((ob, r_col[line_f[i]], r_col[line_f[i + 1]], ot))
            continue
        q, mm = q_of[i], r_col[mid_f[i]]
        rb, rt = r_col[line_f[i]], r_col[line_f[i + 1]]
        if c == "N":
            w = w_of[i]
            quads += [(ab, w, ot, at), (w, ob, q, ot), (ob, rb, mm, q), (q, mm, rt, ot)]
            fermat_spec.append((q, ob, mm, ot))
        else:
            w = w_of[i + 1]
            quads += [(ab, ob, w, at), (ob, q, ot, w), (q, mm, rt, ot), (ob, rb, mm, q)]
            fermat_spec.append((q, ot, mm, ob))

    # bilinear parts
    def grid(ids: NDArray[np.int64]) -> NDArray[np.int64]:
        return np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1).reshape(
            -1, 4
        )

    quad_arr = np.concatenate(
        [
            grid(coarse_ids).reshape(-1, 4),
            np.array(quads, dtype=np.int64).reshape(-1, 4),
            grid(fine_ids).reshape(-1, 4),
        ]
    )
    spec = np.array(fermat_spec, dtype=np.int64).reshape(-1, 4)

    # template placement of every pair; |dX/du| on each line, exactly (X is bilinear)
    c0, c1, c2, c3 = cn
    speed = np.abs((c1 - c0) + pc * (c0 - c1 + c2 - c3))
    i0 = pairs
    i1, i2 = pairs + 1, pairs + 2
    h_lo = np.abs(o_base[i1] - o_base[i0])
    h_hi = np.abs(o_base[i2] - o_base[i1])
    h_mid = 0.5 * (h_lo + h_hi)
    z[o_ids[i0]] = _ruled(cn, u[column], pc[i0] + _BEND * (pc[i1] - pc[i0]))
    z[o_ids[i2]] = _ruled(cn, u[column], pc[i2] - _BEND * (pc[i2] - pc[i1]))
    if pairs.size:
        z[w_ids] = _ruled(cn, u[column] - _W_BACK * h_mid / speed[i1], pc[i1])
        z[o_ids[i1]] = _ruled(cn, u[column] + _O_AHEAD * h_mid / speed[i1], pc[i1])
    free_sets = np.stack([o_ids[i0], w_ids[: pairs.size], o_ids[i1], o_ids[i2]], axis=1)
    free_along = np.zeros(free_sets.shape, dtype=np.complex128)  # 0: free in the plane
    groups = [np.array([2 * g, 2 * g + 1]) for g in range(pairs.size)]  # rows in ``spec``
    if half is not None:
        # the parity row: its shared line is the wall (W and its O stay on it), its far O
        # bends the line on the other side, as in a pair
        s_line, f_line = (0, 1) if half == "low" else (k, k - 1)
        hh = float(np.abs(o_base[f_line] - o_base[s_line]))
        z[o_ids[f_line]] = _ruled(cn, u[column], pc[f_line] + _BEND * (pc[s_line] - pc[f_line]))
        z[w_ids[0]] = _ruled(cn, u[column] - _W_BACK * hh / speed[s_line], pc[s_line])
        z[o_ids[s_line]] = _ruled(cn, u[column] + _O_AHEAD * hh / speed[s_line], pc[s_line])
        d = (c1 - c0) + pc[s_line] * (c0 - c1 + c2 - c3)
        free_sets = np.array([[o_ids[f_line], w_ids[0], o_ids[s_line]]], dtype=np.int64)
        free_along = np.array([[0.0, d / abs(d), d / abs(d)]], dtype=np.complex128)
        groups = [np.array([0])]
    z[spec[:, 0]] = fermat_point(z[spec[:, 1]], z[spec[:, 2]], z[spec[:, 3]])

    exact_all = np.isin(quad_arr, q_ids)
    # per pair: the quads around its free points; polish the pairs that miss MIN_MARGIN
    polished = 0
    for g, rows in enumerate(groups):
        free = free_sets[g]
        qs = spec[rows, 0]
        near = np.isin(quad_arr, np.concatenate([free, qs])).any(axis=1)
        lq, ex = quad_arr[near], exact_all[near]
        if min(_margin(z, lq, ex), _fermat_room(z, spec[rows]).min()) >= MIN_MARGIN:
            continue
        if polish is not None:
            if polish[0] <= 0:
                if not reuse:
                    break
                z = _polish(z, lq, ex, free, spec[rows], free_along[g], hints, optimise=False)
                continue
            polish[0] -= 1
        z = _polish(z, lq, ex, free, spec[rows], free_along[g], hints)
        polished += 1
    margin = _margin(z, quad_arr, exact_all)
    room = _fermat_room(z, spec)
    if room.size and room.min() < MIN_MARGIN:
        raise TransitionError(
            f"a transition cell from {k} to {pf.size - 1} rows leaves a valence-3 vertex too "
            "close to a neighbour; it needs more room along the cell for its rows"
        )
    if not margin >= MIN_MARGIN:
        raise TransitionError(
            f"a transition cell from {k} to {pf.size - 1} rows keeps its angles only within "
            f"{margin:.3g}° of [60°, 120°]; it needs more room along the cell for its rows"
        )
    wall0 = np.concatenate([coarse_ids[0], [o_ids[0]], fine_ids[0]])
    wall1 = np.concatenate([coarse_ids[-1], [o_ids[-1]], fine_ids[-1]])
    if half == "low":
        wall0 = np.concatenate([coarse_ids[0], w_ids, [o_ids[0]], fine_ids[0]])
    elif half == "high":
        wall1 = np.concatenate([coarse_ids[-1], w_ids, [o_ids[-1]], fine_ids[-1]])
    return TransitionMesh(
        points=z,
        quads=quad_arr,
        coarse=coarse_ids[:, 0].copy(),
        fine=fine_ids[:, -1].copy(),
        wall0=wall0,
        wall1=wall1,
        u=u,
        p_coarse=p_side,
        margin=margin,
        polished=polished,
        parity=half or "",
    )


def _forward(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The points of scipy's forward differences at ``x`` with the absolute step
    :data:`FD_STEP` (BFGS's and SLSQP's default): row 0 is ``x``, row i + 1 has ``x[i]`` moved
    by ``step[i]``; returns (rows, step)."""
    step = np.full(x.size, FD_STEP)
    sign = (x >= 0).astype(float) * 2 - 1
    step = np.where((x + step) - x == 0, FD_STEP * sign * np.maximum(1.0, np.abs(x)), step)
    xs = np.repeat(x[None, :], x.size + 1, axis=0)
    idx = np.arange(x.size)
    xs[idx + 1, idx] = x + step
    return xs, step


def _polish(
    z: NDArray[np.complex128],
    quads: NDArray[np.int64],
    exact: NDArray[np.bool_],
    free: NDArray[np.int64],
    spec: NDArray[np.int64],
    along: NDArray[np.complex128] | None = None,
    hints: list[NDArray[np.float64]] | None = None,
    optimise: bool = True,
) -> NDArray[np.complex128]:
    """Move the ``free`` points (the Fermat points of ``spec`` following them) to maximise the
    smallest margin of the angles of ``quads`` inside [60°, 120°].  ``along``: per free
    point 0 (it moves in the plane) or the unit direction of the straight wall it stays on.
    ``hints``: the offsets found for earlier pairs of the same cascade, most recent last;
    the pairs of one cascade are nearly alike, so an offset that gives this pair the margin
    the optimisation stops at is taken without optimising (measured: 37 of 68 pairs on STIX
    "A", 75 of 128 on a random walk), and the offsets found here are added to them.

    A soft minimum of the margins (log-sum-exp at temperatures 3°, 1°, 0.3°, BFGS) leads to
    the neighbourhood of the best placement, then SLSQP on the epigraph form (maximise t with
    every margin ≥ t) finishes it; the template start is tried first, then one jittered
    start.  Offsets are measured in the pair's row height.  Without ``optimise`` only the
    hints are tried (``z`` comes back unchanged when none reaches the margin)."""
    # work on the few points involved, not on the whole cell's
    local = np.unique(np.concatenate([quads.ravel(), free, spec.ravel()]))
    pos = {int(v): i for i, v in enumerate(local)}
    remap = np.vectorize(pos.__getitem__, otypes=[np.int64])
    z_all = z
    z = z_all[local].copy()
    quads, free, spec = remap(quads), remap(free), remap(spec)
    base = z[free].copy()
    h = float(np.abs(z[spec[:, 1]] - z[spec[:, 3]]).max())
    nf = free.size
    dirs = np.zeros(nf, dtype=np.complex128) if along is None else np.asarray(along)
    on_wall = dirs != 0

    def at(x: NDArray[np.float64]) -> NDArray[np.complex128]:
        """The local points for the offsets ``x`` (2·nf,) or for each row of ``x`` (B, 2·nf)."""
        xs = np.atleast_2d(x)
        zz = np.repeat(z[None, :], xs.shape[0], axis=0)
        step = np.where(on_wall, xs[:, :nf] * dirs, xs[:, :nf] + 1j * xs[:, nf : 2 * nf])
        zz[:, free] = base + h * step
        zz[:, spec[:, 0]] = fermat_point(
            zz[:, spec[:, 1]], zz[:, spec[:, 2]], zz[:, spec[:, 3]], refine=False
        )
        return zz if x.ndim == 2 else zz[0]

    # the corners whose angles count (as :func:`quad_angles_deg` measures them: from the edge
    # to the next corner to the edge to the previous one), indexed once: margins() runs a few
    # hundred times per pair
    counted = ~exact
    k_at = quads[counted]
    k_next, k_prev = quads[:, [1, 2, 3, 0]][counted], quads[:, [3, 0, 1, 2]][counted]

    def margins(x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The margins for the offsets ``x`` (2·nf,), or per row of ``x`` (B, 2·nf)."""
        zz = np.atleast_2d(at(x))
        za = zz[:, k_at]
        ang = np.angle(-(za - zz[:, k_prev]) * np.conj(zz[:, k_next] - za))
        ang[ang < 0] += 2 * np.pi
        a = np.degrees(ang, out=ang)
        m = np.concatenate([a - 60.0, 120.0 - a, _fermat_room(zz, spec)], axis=1)
        m = np.where(np.isfinite(m), m, -180.0)
        return m if x.ndim == 2 else m[0]

    def soft(x: NDArray[np.float64], tau: float) -> float:
        m = margins(x)
        lo = m.min()
        return -(lo - tau * np.log(np.sum(np.exp(-(m - lo) / tau))))

    def soft_grad(x: NDArray[np.float64], tau: float) -> NDArray[np.float64]:
        """Forward differences of :func:`soft` with BFGS's own absolute step (the gradient it
        would take without ``jac``), all offsets evaluated in one batch."""
        xs, step = _forward(x)
        ms = margins(xs)
        f = np.empty(x.size + 1)
        for i, m in enumerate(ms):
            lo = m.min()
            f[i] = -(lo - tau * np.log(np.sum(np.exp(-(m - lo) / tau))))
        return (f[1:] - f[0]) / ((x + step) - x)

    def room(v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Forward differences of SLSQP's constraints (margins less the bound ``v[-1]``) with
        SLSQP's own absolute step, every offset in one batch: (constraints, variables)."""
        vs, step = _forward(v)
        f = margins(vs[:, :-1]) - vs[:, -1:]
        return ((f[1:] - f[0]) / ((v + step) - v)[:, None]).T

    rng = np.random.default_rng(0)
    best_x, best_m = np.zeros(2 * nf), float(margins(np.zeros(2 * nf)).min())
    if best_m < -HOPELESS:
        return z_all  # the template is far off (a folded pair): no local repair reaches it
    enough = 2 * MIN_MARGIN

    def stop(xk: NDArray[np.float64]) -> None:
        if margins(xk).min() >= enough:
            raise StopIteration  # good enough: the pair is accepted above MIN_MARGIN

    hinted = False
    for xh in reversed((hints or [])[-POLISH_HINTS:]):
        if xh.size == best_x.size:
            m = float(margins(xh).min())
            if m >= enough:
                best_x, best_m, hinted = xh, m, True
                break
    if not optimise and not hinted:
        return z_all
    for trial in range(0 if hinted else 2):
        x = np.zeros(2 * nf) if trial == 0 else 0.1 * rng.standard_normal(2 * nf)
        opts = {"maxiter": 40}
        x = minimize(
            soft, x, args=(2.0,), jac=soft_grad, method="BFGS", options=opts, callback=stop
        ).x
        if margins(x).min() >= enough:
            best_x, best_m = x, float(margins(x).min())
            break
        x = minimize(
            soft, x, args=(0.5,), jac=soft_grad, method="BFGS", options=opts, callback=stop
        ).x
        x0 = np.concatenate([x, [margins(x).min()]])
        res = minimize(
            lambda v: -v[-1],
            x0,
            jac=lambda v: np.concatenate([np.zeros(v.size - 1), [-1.0]]),
            constraints=[{"type": "ineq", "fun": lambda v: margins(v[:-1]) - v[-1], "jac": room}],
            method="SLSQP",
            options={"maxiter": 40, "ftol": 1e-10},
        )
        for cand in (x, res.x[:-1]):
            m = float(margins(cand).min())
            if m > best_m:
                best_x, best_m = cand, m
        if best_m >= enough:
            break
    if hints is not None and not hinted and best_m >= MIN_MARGIN:
        hints.append(best_x)
    loc = at(best_x)
    loc[spec[:, 0]] = fermat_point(loc[spec[:, 1]], loc[spec[:, 2]], loc[spec[:, 3]])
    out = z_all.copy()
    out[local] = loc
    return out


def plan_pairs(p_fine: ArrayLike, n_pairs: int, spread: float = 1.8) -> NDArray[np.int64]:
    """Lower coarse row of each of at most ``n_pairs`` pairs for a transition whose fine side
    carries ``p_fine``: pairs go where the fine rows are thinnest, all within a factor
    ``spread`` of the thickest one chosen (their split column's neighbours are placed by the
    thickest, and a pair much thinner than that leaves its middle lines too flat).

    In fine rows a pair covers four consecutive rows; at least one plain row lies below the
    first pair and above the last, and two between pairs.  Returns coarse row indices
    (:func:`coarse_rows` order), possibly fewer than ``n_pairs``."""
    pf = np.asarray(p_fine, dtype=np.float64)
    h = np.diff(pf)
    kf = h.size
    if kf < 6 or n_pairs <= 0:
        return np.zeros(0, dtype=np.int64)
    # candidate pair starting at fine row f covers f..f+3; needs f >= 1 and f + 4 <= kf - 1
    starts = np.arange(1, kf - 4)
    if starts.size == 0:
        return np.zeros(0, dtype=np.int64)
    around = np.stack([h[starts + j] for j in range(-1, 5)])  # the pair and a plain row each side
    cost = around[1:5].max(axis=0)
    # the template is measured on rows of equal height: keep to places graded by at most UNEVEN
    cost = np.where(around.max(axis=0) <= UNEVEN * around.min(axis=0), cost, np.inf)
    order = np.argsort(cost, kind="stable")
    chosen: list[int] = []
    taken = np.zeros(kf + 8, dtype=bool)
    top = None
    for o in order:
        f = int(starts[o])
        if not np.isfinite(cost[o]) or (top is not None and cost[o] > spread * top):
            break
        # rows f-2 .. f+5 must be free of other pairs (two plain rows between pairs)
        if taken[max(0, f - 2) : f + 6].any():
            continue
        chosen.append(f)
        taken[f : f + 4] = True
        if top is None:
            top = float(cost[o])
        if len(chosen) == n_pairs:
            break
    chosen.sort()
    # fine start -> coarse row index: every earlier pair takes 4 fine rows for 2 coarse rows
    return np.array([f - 2 * j for j, f in enumerate(chosen)], dtype=np.int64)


def _even_out(p: NDArray[np.float64], passes: int = 3) -> NDArray[np.float64]:
    """``p`` (increasing from 0 to 1) with its inner values averaged with their neighbours
    (weights 1/4, 1/2, 1/4) ``passes`` times: a stage's coarse rows alternate between one and
    two fine rows, and the next stage's pairs want rows of nearly equal height."""
    q = p.copy()
    for _ in range(passes):
        q[1:-1] = 0.25 * q[:-2] + 0.5 * q[1:-1] + 0.25 * q[2:]
    return q


def _tilted(
    p: NDArray[np.float64], p_even: NDArray[np.float64], sub: NDArray[np.complex128]
) -> NDArray[np.float64]:
    """``p`` moved towards ``p_even`` only as far as the slice ``sub`` (a ruled cell, rows
    along c0 -> c3) allows with its row lines tilted by at most :data:`EVEN_TILT`: on strongly
    graded rows (a mesh's points on a cut, neighbouring rows up to 40 times apart) a stage only
    a few thin rows long cannot even out the thick ones.  A convex combination of two
    increasing lists, so still increasing."""
    width = float(np.abs(sub[3] - sub[0]))
    along = float(min(abs(sub[1] - sub[0]), abs(sub[2] - sub[3])))
    shift = float(np.abs(p_even - p).max()) * width
    # the stage's coarse grid (where the rows move) ends a column gap before its split column
    # in the middle of the slice: 1/2 - 1/STAGE_LENGTH of its length
    room = along * (0.5 - 1.0 / STAGE_LENGTH) * np.tan(np.radians(EVEN_TILT))
    return p if shift <= 0.0 else p + (p_even - p) * min(1.0, room / shift)


#: Absolute step of the forward differences in :func:`_polish` (BFGS's default, the square
#: root of float64's epsilon).
FD_STEP = float(np.sqrt(np.finfo(float).eps))

#: Passes of neighbour averaging that even out a cascade's fine rows first, and the largest
#: tilt (degrees) of a row line in the slice that does it.
EVEN_PASSES = 40
EVEN_TILT = 12.0

#: Length of a cascade stage along the cell, in units of its split column's gap (the split
#: column in the middle, its neighbours a gap away, room to spare on both sides).
STAGE_LENGTH = 3.0


def transition_cascade(
    corners: ArrayLike,
    p_fine: ArrayLike,
    n_coarse: int,
    partial: bool = False,
    n_along: int = 1,
    budget: list[int] | None = None,
    tilt: bool = False,
    even: str = "smooth",
    reuse: bool = False,
    straighten: bool = False,
) -> TransitionMesh:
    """Mesh the convex cell ``corners`` (as in :func:`transition_mesh`) from ``n_coarse`` rows
    on its side c0 -> c3 to the rows of ``p_fine`` on its side c1 -> c2 by successive
    transition stages, each a :func:`transition_mesh` of a slice of the cell along its walls
    (the slices are bilinear sub-cells, so their corners stay in [60°, 120°]): from the fine
    side, every stage splits as many pairs as :func:`plan_pairs` finds (never more than are
    still needed) in a slice :data:`STAGE_LENGTH` gaps long; the rest of the cell towards the
    coarse side is a bilinear grid of the coarse rows, ``n_along`` segments long (at least
    one).  ``len(p_fine) - 1 - n_coarse`` must be non-negative; when it is odd, the first
    stage is a *parity row* (:func:`transition_mesh` with ``half``: one of the cell's walls
    carries one point more than the other), tried at the wall p = 0, then at p = 1.

    With ``partial``, the cascade stops at the first stage that does not fit (or finds no
    place to split) and the coarse side carries the rows reached so far
    (:attr:`TransitionMesh.p_coarse`), possibly still more than ``n_coarse``.  ``budget``
    (a one-item list, shared by the caller's cascades and decreased here) bounds how many pairs
    may be optimised; when it is spent, stages are built from the template alone.  ``tilt``:
    a stage that fails with its coarse rows evened out is tried again with them evened only as
    far as its grid allows (:func:`_tilted`) before fewer pairs are tried.  ``even``: how the
    first slice evens out unevenly spaced fine rows: ``"smooth"`` (neighbour averaging,
    :func:`_even_out`) or ``"uniform"`` (towards equal rows, for the strongly clustered points
    of a mesh of the paper's construction on a side, which averaging leaves clustered).
    ``reuse``: as in :func:`transition_mesh`, for every stage.  ``straighten``: in a cell whose
    rows meet its rungs more than :data:`STRAIGHTEN_MIN_SKEW` degrees off the perpendicular
    (the pairs' template and their optimisation fail from about 15°), the stages run in a
    core cell whose rungs are perpendicular to the rows, between two plain slices that turn
    the rungs (:func:`_straightened`); the two walls then carry different parameters.

    Raises :class:`TransitionError` when the counts cannot be met or the stages do not fit in
    the cell (without ``partial``)."""
    cn = np.asarray(corners, dtype=np.complex128)
    pf = np.asarray(p_fine, dtype=np.float64)
    if even not in ("smooth", "uniform"):
        raise ValueError(f"even must be 'smooth' or 'uniform', got {even!r}")
    if straighten:
        got = _straightened(cn, pf, n_coarse, partial, n_along, budget, tilt, even, reuse)
        if got is not None:
            return got
    need = pf.size - 1 - int(n_coarse)
    if need < 0:
        raise TransitionError(
            f"a cell cannot go from {pf.size - 1} to {n_coarse} rows by splitting rows"
        )
    stages: list[tuple[float, float, TransitionMesh]] = []
    hints: list[NDArray[np.float64]] = []  # the pairs' polished offsets (:func:`_polish`)
    u_hi, q = 1.0, pf
    want = (q.size - 1 - int(n_coarse)) // 2
    # unevenly spaced fine rows (a mesh's points on a cut) are first evened out by a ruled
    # slice that tilts every row line by at most EVEN_TILT degrees
    h = np.diff(pf)
    ratio = np.maximum(h[1:] / h[:-1], h[:-1] / h[1:]) if h.size > 1 else np.ones(1)
    if want > 0 and ratio.max() > UNEVEN:
        if even == "uniform":
            q_even = np.linspace(0.0, 1.0, pf.size)
        else:
            q_even = _even_out(pf, EVEN_PASSES)
        width = float(np.abs(cn[2] - cn[1]))
        along = float(min(abs(cn[1] - cn[0]), abs(cn[2] - cn[3])))
        du = float(np.abs(q_even - pf).max()) * width / np.tan(np.radians(EVEN_TILT)) / along
        if du >= 0.5 and partial:
            # too uneven for this cell: it evens the rows only part of the way (a convex
            # combination of two increasing lists, so still increasing); the next cell goes on
            q_even = pf + (q_even - pf) * (0.5 / du)
            du = 0.5
        if 0.0 < du <= 0.5:
            sub = _ruled(cn, np.array([1.0 - du, 1.0, 1.0, 1.0 - du]), np.array([0, 0, 1.0, 1]))
            grid = _ruled(sub, np.array([0.0, 1.0])[None, :], np.stack([q_even, pf], axis=1))
            zz = grid.ravel()
            gid = np.arange(zz.size).reshape(grid.shape)
            qd = np.stack([gid[:-1, 0], gid[:-1, 1], gid[1:, 1], gid[1:, 0]], axis=-1)
            m = _margin(zz, qd, np.zeros(qd.shape, dtype=bool))
            if m >= MIN_MARGIN:
                tm = TransitionMesh(
                    points=zz,
                    quads=qd,
                    coarse=gid[:, 0].copy(),
                    fine=gid[:, 1].copy(),
                    wall0=gid[0].copy(),
                    wall1=gid[-1].copy(),
                    u=np.array([0.0, 1.0]),
                    p_coarse=q_even,
                    margin=m,
                )
                stages.append((1.0 - du, 1.0, tm))
                u_hi, q = 1.0 - du, q_even
    if need % 2:
        tm_par = None
        for half in ("low", "high"):
            pc, _ = coarse_rows(q, [], half)
            h = np.abs(np.diff(_ruled(cn, u_hi, pc)))
            gap = COLUMN_GAP * float(h[0] if half == "low" else h[-1])
            along = float(np.abs(_ruled(cn, 1.0, pc) - _ruled(cn, 0.0, pc)).min())
            du = STAGE_LENGTH * gap / along
            if du >= u_hi:
                continue
            lo = u_hi - du
            sub = _ruled(cn, np.array([lo, u_hi, u_hi, lo]), np.array([0.0, 0.0, 1.0, 1.0]))
            # the coarse rows evened out, else as they are: the stage is a few of the wall
            # row's gaps long, and evening rows that vary by a factor of 3 between
            # neighbours (a mesh's points on a cut) in so short a slice folds it
            for pe in (_even_out(pc), pc):
                try:
                    tm_par = transition_mesh(
                        sub,
                        q,
                        [],
                        p_coarse=pe,
                        polish=budget,
                        half=half,
                        hints=hints,
                        reuse=reuse,
                    )
                except TransitionError:
                    continue
                break
            if tm_par is not None:
                break
        if tm_par is None:
            if not partial:
                raise TransitionError(
                    f"a cell has no room to go from {pf.size - 1} to {n_coarse} rows across "
                    "(an odd difference needs a row split at one of its walls)"
                )
        else:
            stages.append((lo, u_hi, tm_par))
            u_hi, q = lo, tm_par.p_coarse
            want = (q.size - 1 - int(n_coarse)) // 2
    while q.size - 1 > n_coarse:
        pairs = plan_pairs(q, min(want, (q.size - 1 - int(n_coarse)) // 2))
        if pairs.size == 0:
            if partial:
                break
            raise TransitionError(
                f"no place to split rows between {q.size - 1} and {n_coarse} rows across "
                "(rows too unevenly spaced)"
            )
        pc, _ = coarse_rows(q, pairs)
        h = np.abs(np.diff(_ruled(cn, u_hi, pc)))
        gap = COLUMN_GAP * float(np.maximum(h[pairs], h[pairs + 1]).max())
        along = float(np.abs(_ruled(cn, 1.0, pc) - _ruled(cn, 0.0, pc)).min())
        du = STAGE_LENGTH * gap / along
        if du >= u_hi:
            if partial:
                break
            raise TransitionError(
                f"a cell is too short to go from {pf.size - 1} to {n_coarse} rows across"
            )
        lo = u_hi - du
        sub = _ruled(cn, np.array([lo, u_hi, u_hi, lo]), np.array([0.0, 0.0, 1.0, 1.0]))
        tm = None
        evened = _even_out(pc)
        for pe in (evened, _tilted(pc, evened, sub), pc) if tilt else (evened,):
            try:
                tm = transition_mesh(
                    sub, q, pairs, p_coarse=pe, polish=budget, hints=hints, reuse=reuse
                )
            except TransitionError:
                if not partial:
                    raise
                continue
            break
        if tm is None:
            if pairs.size == 1:
                break
            want = pairs.size // 2  # fewer pairs at a time: the thinnest, most even rows
            continue
        stages.append((lo, u_hi, tm))
        u_hi, q = lo, tm.p_coarse
    # assemble: the coarse bilinear part, then the stages towards the fine side
    pts: list[NDArray[np.complex128]] = []
    quads: list[NDArray[np.int64]] = []
    count = 0
    margin = 90.0
    # coarse part: u in [0, u_hi] with rows q
    sub = _ruled(cn, np.array([0.0, u_hi, u_hi, 0.0]), np.array([0.0, 0.0, 1.0, 1.0]))
    grid = _ruled(sub, np.linspace(0.0, 1.0, max(1, int(n_along)) + 1)[None, :], q[:, None])
    gid = np.arange(grid.size).reshape(grid.shape)
    pts.append(grid.ravel())
    count = grid.size
    quads.append(
        np.stack([gid[:-1, :-1], gid[:-1, 1:], gid[1:, 1:], gid[1:, :-1]], axis=-1).reshape(-1, 4)
    )
    coarse = gid[:, 0].copy()
    prev_side = gid[:, -1].copy()  # ids on u = u_hi
    wall0 = gid[0].tolist()
    wall1 = gid[-1].tolist()
    u_walls = np.linspace(0.0, u_hi, gid.shape[1]).tolist()
    p_coarse = q
    for lo, hi, tm in reversed(stages):
        margin = min(margin, tm.margin)
        ids = np.full(tm.points.size, -1, dtype=np.int64)
        ids[tm.coarse] = prev_side
        own = ids < 0
        ids[own] = count + np.arange(int(own.sum()))
        pts.append(tm.points[own])
        count += int(own.sum())
        quads.append(ids[tm.quads])
        prev_side = ids[tm.fine]
        wall0 += ids[tm.wall0[1:]].tolist()
        wall1 += ids[tm.wall1[1:]].tolist()
        u_walls += (lo + (hi - lo) * tm.u[1:]).tolist()
    z = np.concatenate(pts)
    z[coarse[0]], z[coarse[-1]] = cn[0], cn[3]
    z[prev_side[0]], z[prev_side[-1]] = cn[1], cn[2]
    return TransitionMesh(
        points=z,
        quads=np.concatenate(quads),
        coarse=coarse,
        fine=prev_side,
        wall0=np.array(wall0, dtype=np.int64),
        wall1=np.array(wall1, dtype=np.int64),
        u=np.array(u_walls),
        p_coarse=p_coarse,
        margin=margin,
        parity="".join(tm.parity for _, _, tm in stages),
    )


#: skew (degrees off the perpendicular between a cell's rows and rungs) above which
#: ``transition_cascade(straighten=True)`` runs its stages in a straightened core
STRAIGHTEN_MIN_SKEW = 5.0
#: the straightening slices take at least this share of the cell's length each
STRAIGHTEN_GAP = 0.02


def _straightened(
    cn: NDArray[np.complex128],
    pf: NDArray[np.float64],
    n_coarse: int,
    partial: bool,
    n_along: int,
    budget: list[int] | None,
    tilt: bool,
    even: str,
    reuse: bool,
) -> TransitionMesh | None:
    """:func:`transition_cascade` of a skewed cell in a straightened core: with ``e_u`` and
    ``e_p`` the cell's mean row and rung directions, a rung from wall parameter ``a`` on the
    wall p = 0 to ``a + s`` on the wall p = 1, ``s = -Re(e_p conj(e_u)) / |e_u|²``, is
    perpendicular to the rows (exactly so in a parallelogram).  The core between two such rungs
    holds the cascade; the slices between them and the cell's own rungs are plain ruled strips
    of the fine and of the coarse rows (their angles lie between the cell's corners and 90°).
    None when the cell is skewed by less than :data:`STRAIGHTEN_MIN_SKEW` degrees or too short
    for the core; the plain cascade is then the one to run."""
    e_u = 0.5 * ((cn[1] - cn[0]) + (cn[2] - cn[3]))
    e_p = 0.5 * ((cn[3] - cn[0]) + (cn[2] - cn[1]))
    skew = abs(90.0 - np.degrees(abs(np.angle(e_p / e_u))))
    if skew < STRAIGHTEN_MIN_SKEW:
        return None
    s = -float((e_p * np.conj(e_u)).real / abs(e_u) ** 2)
    g = max(STRAIGHTEN_GAP, 0.25 * abs(s))
    hi0, hi1 = (1.0 - g - s, 1.0 - g) if s > 0 else (1.0 - g, 1.0 - g + s)
    lo0, lo1 = (g, g + s) if s > 0 else (g - s, g)
    if hi0 - lo0 < 2.0 * g:
        return None
    core = np.array(
        [_ruled(cn, lo0, 0.0), _ruled(cn, hi0, 0.0), _ruled(cn, hi1, 1.0), _ruled(cn, lo1, 1.0)]
    )
    inner = transition_cascade(
        core,
        pf,
        n_coarse,
        partial=partial,
        n_along=n_along,
        budget=budget,
        tilt=tilt,
        even=even,
        reuse=reuse,
    )
    pts = [inner.points]
    count = inner.points.size
    # the fine slice: the core's fine rung to the cell's fine side, the fine rows straight
    fine_side = cn[1] + pf * (cn[2] - cn[1])
    fine_ids = count + np.arange(pf.size)
    pts.append(fine_side)
    count += pf.size
    q_fine = np.stack([inner.fine[:-1], fine_ids[:-1], fine_ids[1:], inner.fine[1:]], axis=1)
    # the coarse slice: the cell's coarse side to the core's coarse rung
    pc = inner.p_coarse
    coarse_side = cn[0] + pc * (cn[3] - cn[0])
    coarse_ids = count + np.arange(pc.size)
    pts.append(coarse_side)
    q_coarse = np.stack(
        [coarse_ids[:-1], inner.coarse[:-1], inner.coarse[1:], coarse_ids[1:]], axis=1
    )
    z = np.concatenate(pts)
    quads = np.concatenate([inner.quads, q_fine, q_coarse])
    plain = np.concatenate([q_fine, q_coarse])
    m = _margin(z, plain, np.zeros(plain.shape, dtype=bool))
    if m < MIN_MARGIN:
        return None
    wall0 = np.concatenate([[coarse_ids[0]], inner.wall0, [fine_ids[0]]])
    wall1 = np.concatenate([[coarse_ids[-1]], inner.wall1, [fine_ids[-1]]])
    d0 = cn[1] - cn[0]
    u0 = ((z[wall0] - cn[0]) * np.conj(d0)).real / abs(d0) ** 2
    u0[0], u0[-1] = 0.0, 1.0
    return TransitionMesh(
        points=z,
        quads=quads,
        coarse=coarse_ids,
        fine=fine_ids,
        wall0=wall0,
        wall1=wall1,
        u=u0,
        p_coarse=pc,
        margin=min(inner.margin, m),
        polished=inner.polished,
        parity=inner.parity,
    )
