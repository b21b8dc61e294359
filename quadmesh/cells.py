"""Coarse layouts of admissible cells, refined into conforming bilinear grids.

A *cell* is a convex planar quadrilateral with straight sides whose four corners all lie in
[60°, 120°].  Any k×m bilinear grid of such a cell, with any spacing of the two parameters,
has every grid angle in [60°, 120°]: in the bilinear patch

    P(s, t) = (1-s)(1-t) c0 + s(1-t) c1 + s t c2 + (1-s) t c3

the isolines s = const and t = const are straight segments whose directions turn
monotonically from one side of the cell to the opposite side, so every grid angle (the angle
between one s-isoline and one t-isoline) lies in the range spanned by the four corner angles and
their supplements.

A *layout* is a small conforming quad mesh of cells.  Its *chords* are the sheets of cells joined
through opposite sides; giving every chord one subdivision count (and one list of parameters)
refines every cell into a bilinear grid whose sides match the neighbours' exactly
(:func:`refine_layout`).  Points on a coarse edge are generated once and shared by index by
both cells on that edge.

Public functions:

* :func:`bilinear_points`: the grid points of one cell (or a stack of cells);
* :func:`cell_angles`, :func:`cell_is_admissible`: corner angles and the admissibility test;
* :func:`layout_chords`: the chord structure of a layout;
* :func:`layout_problems`, :func:`check_layout`: what makes a layout unfit for refinement;
* :func:`refine_layout`: the refined mesh.

Plane points are complex128 throughout.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .geometry import angle_rounding_slack_deg, quad_angles_deg

__all__ = [
    "ANGLE_MAX",
    "ANGLE_MIN",
    "LayoutChords",
    "LayoutRefinement",
    "bilinear_points",
    "cell_angles",
    "cell_is_admissible",
    "check_layout",
    "layout_chords",
    "layout_problems",
    "refine_layout",
]

ANGLE_MIN = 60.0
ANGLE_MAX = 120.0

_NEXT = np.array([1, 2, 3, 0])
_MAX_LISTED = 10  # problems listed in one error message


# --------------------------------------------------------------------------- single cells


def _check_params(p: NDArray[np.float64], name: str) -> None:
    if p.shape[-1] < 2:
        raise ValueError(f"{name} needs at least the two values 0 and 1, got {p.shape[-1]}")
    if np.any(p[..., 0] != 0.0) or np.any(p[..., -1] != 1.0):
        raise ValueError(f"{name} must start at exactly 0 and end at exactly 1")
    if np.any(np.diff(p, axis=-1) <= 0.0):
        raise ValueError(f"{name} must be strictly increasing")


def bilinear_points(corners: ArrayLike, s: ArrayLike, t: ArrayLike) -> NDArray[np.complex128]:
    """Points ``P(s_i, t_j)`` of the bilinear patch on ``corners``, shape ``(len(t), len(s))``.

    ``corners`` are c0, c1, c2, c3 counter-clockwise; ``s`` runs from c0 to c1 (and from c3 to
    c2), ``t`` from c0 to c3 (and from c1 to c2); both strictly increasing from exactly 0 to
    exactly 1.  Row ``j`` of the result is the isoline ``t = t[j]``.

    Stacks are allowed: ``corners (..., 4)``, ``s (..., ks)``, ``t (..., mt)`` broadcast to a
    result ``(..., mt, ks)``.

    The patch is evaluated as ``c0 + s(c1-c0) + t(c3-c0) + s t (c0-c1+c2-c3)`` so that rounding
    scales with the cell's size rather than its distance from the origin; the four corners of
    the result are set to the given corners exactly.
    """
    c = np.asarray(corners, dtype=np.complex128)
    if c.shape[-1:] != (4,):
        raise ValueError(f"corners must have shape (..., 4), got {c.shape}")
    s = np.asarray(s, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    _check_params(s, "s")
    _check_params(t, "t")
    c0, c1, c2, c3 = (c[..., j, None, None] for j in range(4))
    ss = s[..., None, :]
    tt = t[..., :, None]
    p = c0 + ss * (c1 - c0) + tt * (c3 - c0) + (ss * tt) * (c0 - c1 + c2 - c3)
    p[..., 0, 0] = c[..., 0]
    p[..., 0, -1] = c[..., 1]
    p[..., -1, -1] = c[..., 2]
    p[..., -1, 0] = c[..., 3]
    return p


def cell_angles(corners: ArrayLike) -> NDArray[np.float64]:
    """Corner angles in degrees, shape ``(..., 4)``, of cells ``corners (..., 4)``.

    Angle k is measured counter-clockwise at corner k from the side to corner k+1 to the side to
    corner k-1, in [0°, 360°): the interior angle of a counter-clockwise cell; a clockwise or
    reflex corner reads above 180°.
    """
    c = np.asarray(corners, dtype=np.complex128)
    if c.shape[-1:] != (4,):
        raise ValueError(f"corners must have shape (..., 4), got {c.shape}")
    flat = c.reshape(-1)
    ang = quad_angles_deg(flat, np.arange(flat.size).reshape(-1, 4))
    return ang.reshape(c.shape)


def _cell_slack(corners: NDArray[np.complex128]) -> NDArray[np.float64]:
    """(...,) float64 rounding slack of the cells' angles (degrees); 0 for degenerate cells."""
    flat = corners.reshape(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        sl = angle_rounding_slack_deg(flat, np.arange(flat.size).reshape(-1, 4))
    sl = np.where(np.isfinite(sl), sl, 0.0)
    return sl.reshape(corners.shape[:-1])


def _nondegenerate(corners: NDArray[np.complex128]) -> NDArray[np.bool_]:
    return np.all(corners[..., _NEXT] != corners, axis=-1)


def cell_is_admissible(corners: ArrayLike, margin_deg: float = 0.0) -> NDArray[np.bool_]:
    """Whether each cell ``corners (..., 4)`` is convex, counter-clockwise and has every corner in
    ``[60° + margin_deg, 120° - margin_deg]``; boolean array of shape ``(...)``.

    Corners are compared up to the float64 rounding slack of their positions (8ε·|z|/ℓ, about
    1e-13° for a unit cell), so a corner built at exactly 60° or 120° is accepted.  All four
    counter-clockwise angles below 180° already make the cell convex, simple and
    counter-clockwise (the exterior turns are positive and add up to a whole number of turns,
    below two).
    """
    c = np.asarray(corners, dtype=np.complex128)
    ang = cell_angles(c)
    slack = _cell_slack(c)[..., None]
    ok = (ang >= ANGLE_MIN + margin_deg - slack) & (ang <= ANGLE_MAX - margin_deg + slack)
    return np.all(ok, axis=-1) & _nondegenerate(c)


# --------------------------------------------------------------------------- layouts


@dataclass(frozen=True)
class LayoutChords:
    """Edges and chords of a coarse layout.

    Attributes:
        n_vertices: number of coarse vertices indexed by the cells.
        cells: (C, 4) coarse cells, counter-clockwise.
        edges: (E, 2) undirected coarse edges ``(lo, hi)`` with ``lo < hi``, sorted.
        cell_edges: (C, 4) edge id of side k of each cell (from corner k to corner k+1).
        edge_cells: (E, 2) the cells on each edge (-1 where there is none: a boundary edge).
        edge_chord: (E,) chord id of each edge.
        edge_forward: (E,) True when the chord's reference direction runs along the edge from
            ``lo`` to ``hi``.  In cell (c0, c1, c2, c3) the directions c0→c1 and c3→c2 agree (and
            c1→c2 with c0→c3), so one parameter list in the reference direction serves every
            edge of the chord.
        n_chords: number of chords.
    """

    n_vertices: int
    cells: NDArray[np.int64]
    edges: NDArray[np.int64]
    cell_edges: NDArray[np.int64]
    edge_cells: NDArray[np.int64]
    edge_chord: NDArray[np.int64]
    edge_forward: NDArray[np.bool_]
    n_chords: int

    @property
    def cell_chords(self) -> NDArray[np.int64]:
        """(C, 2) chord of sides 0/2 (the s direction) and of sides 1/3 (the t direction)."""
        return self.edge_chord[self.cell_edges[:, :2]]

    @property
    def boundary_edges(self) -> NDArray[np.int64]:
        """Ids of the edges that belong to one cell only."""
        return np.nonzero(self.edge_cells[:, 1] < 0)[0]

    def edge_id(self, u: int, v: int) -> int:
        """Id of the coarse edge joining vertices ``u`` and ``v`` (either order)."""
        lo, hi = (int(u), int(v)) if u < v else (int(v), int(u))
        n = self.n_vertices
        code = self.edges[:, 0] * n + self.edges[:, 1]
        i = int(np.searchsorted(code, lo * n + hi))
        if lo == hi or lo < 0 or hi >= n or i >= len(code) or code[i] != lo * n + hi:
            raise ValueError(f"({u}, {v}) is not a side of any cell of the layout")
        return i

    def chord_of(self, u: int, v: int) -> int:
        """Chord id of the coarse edge joining vertices ``u`` and ``v``."""
        return int(self.edge_chord[self.edge_id(u, v)])

    def along_reference(self, u: int, v: int) -> bool:
        """Whether going from ``u`` to ``v`` follows the reference direction of its chord."""
        e = self.edge_id(u, v)
        return bool((u < v) == self.edge_forward[e])

    def chord_edges(self, chord: int) -> NDArray[np.int64]:
        """Ids of the edges in ``chord``."""
        return np.nonzero(self.edge_chord == chord)[0]

    def describe_chord(self, chord: int) -> str:
        """A short user-facing name: the chord and its first few edges."""
        ed = self.edges[self.chord_edges(chord)]
        shown = ", ".join(f"({a}, {b})" for a, b in ed[:4].tolist())
        more = f" and {len(ed) - 4} more" if len(ed) > 4 else ""
        return f"chord {chord} (the strip of cells across edges {shown}{more})"


def layout_chords(cells: ArrayLike, n_vertices: int | None = None) -> LayoutChords:
    """Edges and chords of a layout of counter-clockwise cells ``(C, 4)``.

    The two opposite sides of every cell belong to one chord (union over all cells, by connected
    components of a graph on the directed edges, so the reference direction of each chord comes
    out at the same time).

    Raises:
        ValueError: when a cell repeats a vertex, an index is out of range, an edge is shared by
            more than two cells or by two cells running along it in the same direction (cells
            not consistently counter-clockwise), or a chord closes up twisted.
    """
    q = np.asarray(cells, dtype=np.int64)
    if q.ndim != 2 or q.shape[1] != 4 or len(q) == 0:
        raise ValueError(f"cells must be a non-empty (C, 4) integer array, got shape {q.shape}")
    n = int(q.max()) + 1 if n_vertices is None else int(n_vertices)
    if q.min() < 0 or q.max() >= n:
        raise ValueError(f"cell vertex indices must lie in 0..{n - 1}")
    srt = np.sort(q, axis=1)
    rep = np.any(srt[:, 1:] == srt[:, :-1], axis=1)
    if np.any(rep):
        c = int(np.nonzero(rep)[0][0])
        raise ValueError(f"cell {c} repeats a vertex: {q[c].tolist()}")
    a = q
    b = q[:, _NEXT]
    directed = (a * n + b).ravel()
    du, dcnt = np.unique(directed, return_counts=True)
    if np.any(dcnt > 1):
        k = int(du[dcnt > 1][0])
        who = np.nonzero(np.any((a == k // n) & (b == k % n), axis=1))[0].tolist()
        raise ValueError(
            f"cells {who} all run along edge ({k // n}, {k % n}) in the same direction: "
            "cells must be counter-clockwise and may not overlap"
        )
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    code = (lo * n + hi).ravel()
    uniq, inv, cnt = np.unique(code, return_inverse=True, return_counts=True)
    if np.any(cnt > 2):
        k = int(uniq[cnt > 2][0])
        raise ValueError(f"edge ({k // n}, {k % n}) is a side of {int(cnt[cnt > 2][0])} cells")
    n_edges = len(uniq)
    edges = np.stack([uniq // n, uniq % n], axis=1)
    cell_edges = inv.reshape(q.shape)

    edge_cells = np.full((n_edges, 2), -1, dtype=np.int64)
    order = np.argsort(inv, kind="stable")
    owner = order // 4
    first = np.ones(len(order), dtype=bool)
    first[1:] = inv[order][1:] != inv[order][:-1]
    edge_cells[inv[order][first], 0] = owner[first]
    edge_cells[inv[order][~first], 1] = owner[~first]

    # node 2e + 0: edge e traversed lo -> hi; node 2e + 1: traversed hi -> lo
    trav = 2 * cell_edges + (a > b)
    flip = trav ^ 1
    # c0->c1 agrees with c3->c2 (the reverse of side 2); c1->c2 agrees with c0->c3
    rows = np.concatenate([trav[:, 0], flip[:, 0], trav[:, 1], flip[:, 1]])
    cols = np.concatenate([flip[:, 2], trav[:, 2], flip[:, 3], trav[:, 3]])
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * n_edges, 2 * n_edges))
    _ncomp, lab = connected_components(g, directed=False)
    l0 = lab[0::2]
    l1 = lab[1::2]
    if np.any(l0 == l1):
        e = int(np.nonzero(l0 == l1)[0][0])
        raise ValueError(
            f"the strip of cells through edge ({edges[e, 0]}, {edges[e, 1]}) closes up twisted "
            "(a Möbius strip): cells are not consistently oriented"
        )
    _u, edge_chord = np.unique(np.minimum(l0, l1), return_inverse=True)
    return LayoutChords(
        n_vertices=n,
        cells=q,
        edges=edges,
        cell_edges=cell_edges,
        edge_cells=edge_cells,
        edge_chord=edge_chord.astype(np.int64),
        edge_forward=l0 < l1,
        n_chords=len(_u),
    )


def _fmt_vertex(vertices: NDArray[np.complex128], j: int) -> str:
    z = vertices[j]
    return f"vertex {j} ({z.real:.6g}, {z.imag:.6g})"


def layout_problems(
    vertices: ArrayLike,
    cells: ArrayLike,
    *,
    tips: Iterable[int] = (),
    chord_counts: ArrayLike | None = None,
    margin_deg: float = 0.0,
    chords: LayoutChords | None = None,
) -> list[str]:
    """Everything that makes a layout unfit for :func:`refine_layout`, as user-facing sentences.

    Conditions:

    * every cell is convex and counter-clockwise (no side of zero length);
    * every corner lies in [60° + margin_deg, 120° - margin_deg] (up to float64 rounding slack,
      see :func:`cell_is_admissible`), except at a *tip*: a coarse vertex listed in ``tips``
      whose polygon angle is below 60°; a corner there only has to be above 0° and at most
      120° - margin_deg;
    * a cell holding a tip has count 1 on both of its chords (checked when ``chord_counts``,
      one count per chord of :func:`layout_chords`, is given).

    Why tip cells must stay whole: the bilinear argument bounds every grid angle of a cell by its
    corner angles *and their supplements*.  With a tip of angle α < 60° the grid points next to
    the tip form new quads with angles close to α and to 180° − α > 120°, and those angles are
    new (only the tip corner itself is an angle of the polygon).  A cell with count 1 on both
    chords is emitted as it is, so the tip angle stays the polygon's own.
    """
    v = np.asarray(vertices, dtype=np.complex128)
    ch = layout_chords(cells, len(v)) if chords is None else chords
    q = ch.cells
    corners = v[q]
    ang = cell_angles(corners)
    slack = _cell_slack(corners)[:, None]
    tip_set = np.zeros(len(v), dtype=bool)
    tip_list = [int(j) for j in tips]
    for j in tip_list:
        if not 0 <= j < len(v):
            raise ValueError(f"tip vertex {j} is not a vertex of the layout (0..{len(v) - 1})")
    tip_set[tip_list] = True
    is_tip = tip_set[q]
    lo = np.where(is_tip, 0.0, ANGLE_MIN + margin_deg - slack)
    hi = ANGLE_MAX - margin_deg + slack
    problems: list[str] = []
    degenerate = ~_nondegenerate(corners)
    for c in np.nonzero(degenerate)[0].tolist():
        problems.append(f"cell {c} (vertices {q[c].tolist()}) has a side of zero length")
    bent = np.any(ang >= 180.0, axis=1) & ~degenerate
    for c in np.nonzero(bent)[0].tolist():
        problems.append(
            f"cell {c} (vertices {q[c].tolist()}) is not convex and counter-clockwise: its "
            f"corners read {', '.join(f'{x:.2f}°' for x in ang[c])}"
        )
    bad = ((ang < lo) | (ang > hi) | ((ang <= 0.0) & is_tip)) & ~(bent | degenerate)[:, None]
    for c, k in zip(*np.nonzero(bad)):
        what = "a tip corner" if is_tip[c, k] else "a corner"
        rng = (
            f"(0°, {ANGLE_MAX - margin_deg:g}°]"
            if is_tip[c, k]
            else f"[{ANGLE_MIN + margin_deg:g}°, {ANGLE_MAX - margin_deg:g}°]"
        )
        problems.append(
            f"cell {c} (vertices {q[c].tolist()}) has {what} of {ang[c, k]:.4f}° at "
            f"{_fmt_vertex(v, int(q[c, k]))}, outside {rng}"
        )
    if chord_counts is not None:
        cc = np.asarray(chord_counts, dtype=np.int64)
        if cc.shape != (ch.n_chords,):
            raise ValueError(f"chord_counts needs {ch.n_chords} entries, got {cc.shape}")
        cell_counts = cc[ch.cell_chords]
        for c in np.nonzero(is_tip.any(axis=1) & np.any(cell_counts != 1, axis=1))[0].tolist():
            k = int(np.nonzero(is_tip[c])[0][0])
            problems.append(
                f"cell {c} holds the {ang[c, k]:.2f}° tip at {_fmt_vertex(v, int(q[c, k]))} and "
                f"would be split {cell_counts[c, 0]}×{cell_counts[c, 1]}; it must stay whole "
                "(splitting it creates angles near the tip angle and its supplement)"
            )
    return problems


def check_layout(
    vertices: ArrayLike,
    cells: ArrayLike,
    *,
    tips: Iterable[int] = (),
    chord_counts: ArrayLike | None = None,
    margin_deg: float = 0.0,
) -> LayoutChords:
    """Check a layout before refining it (conditions and reasons: :func:`layout_problems`).

    Returns:
        The layout's :class:`LayoutChords`.

    Raises:
        ValueError: listing the problems found.
    """
    v = np.asarray(vertices, dtype=np.complex128)
    ch = layout_chords(cells, len(v))
    problems = layout_problems(
        v, cells, tips=tips, chord_counts=chord_counts, margin_deg=margin_deg, chords=ch
    )
    if problems:
        shown = problems[:_MAX_LISTED]
        more = len(problems) - len(shown)
        tail = f"\n  ... and {more} more" if more else ""
        raise ValueError(
            f"the layout of {len(ch.cells)} cells cannot be refined:\n  "
            + "\n  ".join(shown)
            + tail
        )
    return ch


# --------------------------------------------------------------------------- refinement


@dataclass(frozen=True)
class LayoutRefinement:
    """How a refined mesh relates to its coarse layout.

    Attributes:
        chords: the layout's :class:`LayoutChords` (``chords.edges`` with ``chords.edge_chord``
            give the chord of every coarse edge).
        chord_counts: (K,) segments per chord.
        chord_params: K parameter lists (each from 0 to 1, ``chord_counts[k] + 1`` values) in the
            chord's reference direction (``chords.along_reference``).
        quad_cell: (Q,) coarse cell of every output quad.
        cell_shape: (C, 2) segments ``(k, m)`` of every cell along s (c0→c1) and t (c0→c3).
        edge_offsets: (E + 1,) the interior points of coarse edge e are
            ``points[edge_offsets[e]:edge_offsets[e + 1]]``, ordered from ``lo`` to ``hi``.
        node_offsets: (C + 1,) cell c's grid is ``node_ids[node_offsets[c]:node_offsets[c+1]]``,
            row by row (rows are t = const, from c0 towards c3).
        node_ids: point index of every grid node of every cell.
    """

    chords: LayoutChords
    chord_counts: NDArray[np.int64]
    chord_params: tuple[NDArray[np.float64], ...]
    quad_cell: NDArray[np.int64]
    cell_shape: NDArray[np.int64]
    edge_offsets: NDArray[np.int64]
    node_offsets: NDArray[np.int64]
    node_ids: NDArray[np.int64]

    @property
    def edge_chord(self) -> NDArray[np.int64]:
        """(E,) chord id of every coarse edge (``chords.edges``)."""
        return self.chords.edge_chord

    def edge_points(self, u: int, v: int) -> NDArray[np.int64]:
        """Point indices along coarse edge (u, v), from ``u`` to ``v``, both ends included."""
        e = self.chords.edge_id(u, v)
        inner = np.arange(self.edge_offsets[e], self.edge_offsets[e + 1])
        ids = np.concatenate([[min(u, v)], inner, [max(u, v)]]).astype(np.int64)
        return ids if u < v else ids[::-1]

    def cell_grid(self, c: int) -> NDArray[np.int64]:
        """Point indices ``(m + 1, k + 1)`` of cell c's grid; row j is t = t_j, column i is
        s = s_i, so ``[0, 0]`` is corner c0, ``[0, -1]`` c1, ``[-1, -1]`` c2, ``[-1, 0]`` c3."""
        k, m = self.cell_shape[c]
        return self.node_ids[self.node_offsets[c] : self.node_offsets[c + 1]].reshape(m + 1, k + 1)


def _ragged(lengths: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Owner and local index of every item of consecutive blocks of the given lengths."""
    owner = np.repeat(np.arange(len(lengths)), lengths)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    return owner, np.arange(int(lengths.sum())) - starts[owner]


def _fixed_chord_params(
    ch: LayoutChords, edge_params: Mapping[tuple[int, int], ArrayLike]
) -> dict[int, tuple[NDArray[np.float64], NDArray[np.float64], bool, tuple[int, int]]]:
    """Per chord: (params along the reference, params against it, whether the reference list is
    the one given exactly, the edge they came from)."""
    fixed: dict[int, tuple[NDArray[np.float64], NDArray[np.float64], bool, tuple[int, int]]] = {}
    for (u, w), arr in edge_params.items():
        u, w = int(u), int(w)
        k = ch.chord_of(u, w)
        p = np.array(arr, dtype=np.float64).ravel()
        try:
            _check_params(p, f"the parameters given for edge ({u}, {w})")
        except ValueError as exc:
            raise ValueError(f"{exc} (got {len(p)} values from {p[:1]} to {p[-1:]})") from None
        comp = 1.0 - p[::-1]
        along = ch.along_reference(u, w)
        ref, rev = (p, comp) if along else (comp, p)
        if k in fixed:
            ref0, _rev0, _exact0, (u0, w0) = fixed[k]
            if len(ref0) != len(ref) or not np.allclose(ref0, ref, rtol=0.0, atol=1e-12):
                raise ValueError(
                    f"edges ({u0}, {w0}) and ({u}, {w}) lie on {ch.describe_chord(k)} and were "
                    f"given different parameters ({len(ref0) - 1} and {len(ref) - 1} segments"
                    f"{'' if len(ref0) != len(ref) else ', different spacing'}); opposite sides of "
                    "every cell must carry the same parameters"
                )
            continue
        fixed[k] = (ref, rev, along, (u, w))
    return fixed


def _chord_counts(
    v: NDArray[np.complex128],
    ch: LayoutChords,
    size: float | None,
    counts: Mapping[int | tuple[int, int], int] | None,
    fixed: Mapping[int, tuple[NDArray[np.float64], NDArray[np.float64], bool, tuple[int, int]]],
    min_count: int,
    tip_cells: NDArray[np.bool_],
) -> NDArray[np.int64]:
    """One segment count per chord: fixed parameters, then ``counts``, then ``size``."""
    n_ch = ch.n_chords
    if min_count < 1:
        raise ValueError(f"min_count must be at least 1, got {min_count}")
    base = np.full(n_ch, int(min_count), dtype=np.int64)
    if size is not None:
        if not size > 0:
            raise ValueError(f"size must be positive, got {size}")
        length = np.abs(v[ch.edges[:, 1]] - v[ch.edges[:, 0]])
        need = np.ceil(length / size).astype(np.int64)
        per = np.zeros(n_ch, dtype=np.int64)
        np.maximum.at(per, ch.edge_chord, need)
        base = np.maximum(per, base)
    # a tip cell stays whole unless the caller insists (then check_layout objects)
    base[np.unique(ch.cell_chords[tip_cells])] = 1
    explicit: dict[int, tuple[int, str]] = {}
    for key, n in (counts or {}).items():
        if isinstance(key, tuple):
            k = ch.chord_of(*key)
            src = f"edge ({key[0]}, {key[1]})"
        else:
            k = int(key)
            if not 0 <= k < n_ch:
                raise ValueError(f"chord {k} does not exist (the layout has {n_ch} chords)")
            src = f"chord {k}"
        if int(n) != n or n < 1:
            raise ValueError(f"the count requested for {src} must be a positive integer, got {n}")
        if k in explicit and explicit[k][0] != int(n):
            raise ValueError(
                f"{explicit[k][1]} and {src} lie on {ch.describe_chord(k)} but were given "
                f"different counts ({explicit[k][0]} and {int(n)})"
            )
        explicit[k] = (int(n), src)
    for k, (ref, _rev, _exact, (u, w)) in fixed.items():
        if k in explicit and explicit[k][0] != len(ref) - 1:
            raise ValueError(
                f"edge ({u}, {w}) has {len(ref) - 1} fixed segments but {explicit[k][1]} on the "
                f"same {ch.describe_chord(k)} asks for {explicit[k][0]}"
            )
    for k, (n, _src) in explicit.items():
        base[k] = n
    for k, (ref, *_rest) in fixed.items():
        base[k] = len(ref) - 1
    return base


def refine_layout(
    vertices: ArrayLike,
    cells: ArrayLike,
    *,
    size: float | None = None,
    counts: Mapping[int | tuple[int, int], int] | None = None,
    edge_params: Mapping[tuple[int, int], ArrayLike] | None = None,
    min_count: int = 1,
    tips: Iterable[int] = (),
    margin_deg: float = 0.0,
    check: bool = True,
) -> tuple[NDArray[np.complex128], NDArray[np.int64], LayoutRefinement]:
    """Refine a coarse layout of admissible cells into a conforming quad mesh.

    Every chord (:func:`layout_chords`) gets one segment count and one parameter list, so both
    opposite sides of every cell, and every cell along the chord, are split the same way; each
    cell becomes the bilinear k×m grid on those parameters (:func:`bilinear_points`), with every
    grid angle in the range of its corner angles and their supplements, hence in [60°, 120°].

    Args:
        vertices: (V,) complex coarse vertices.
        cells: (C, 4) counter-clockwise cells; an undirected edge belongs to at most two cells.
        size: target edge length; a chord's count is the largest ``ceil(length / size)`` over its
            edges (at least ``min_count``).  Without ``size`` (and ``counts``) a chord has
            ``min_count`` segments.  Chords through a cell holding a tip get 1.
        counts: exact counts, keyed by chord id (:func:`layout_chords`) or by a coarse edge
            ``(u, v)`` standing for its chord; two keys on one chord must agree.
        edge_params: fixed parameters ``{(u, v): p}`` for coarse edges, ``p`` strictly increasing
            from exactly 0 at ``u`` to exactly 1 at ``v``; the point at parameter p is
            ``u + p (v - u)``.  They carry over to every edge of the chord with the orientation
            of the cells (side c0→c1 at parameter s matches side c3→c2 at parameter s); edges
            of the chord that run the same way as (u, v) reproduce ``p`` bit for bit, the
            others get ``1 - p`` reversed.  A chord without fixed parameters is uniform.
        min_count: smallest count of a chord set from ``size`` (or of every chord without
            ``size``).
        tips: coarse vertices whose polygon angle is below 60° (see :func:`layout_problems`).
        margin_deg: required distance of every non-tip corner from 60° and 120°.
        check: run :func:`check_layout` (with the final counts) first.

    Returns:
        ``(points, quads, info)``: ``points (N,)`` complex with ``points[:V] == vertices``, then
        the interior points of every coarse edge (edge by edge, each generated once and shared
        by index by the two cells on it), then the interior points of every cell;
        ``quads (Q, 4)`` counter-clockwise; ``info`` a :class:`LayoutRefinement`.

    Raises:
        ValueError: for a layout that fails :func:`check_layout`, fixed parameters or counts that
            disagree within one chord, or an edge key that is not a side of any cell.
    """
    v = np.asarray(vertices, dtype=np.complex128)
    if v.ndim != 1:
        raise ValueError(f"vertices must be a 1-D complex array, got shape {v.shape}")
    ch = layout_chords(cells, len(v))
    q = ch.cells
    tip_list = [int(j) for j in tips]
    tip_mask = np.zeros(len(v), dtype=bool)
    tip_mask[[j for j in tip_list if 0 <= j < len(v)]] = True
    tip_cells = tip_mask[q].any(axis=1)
    fixed = _fixed_chord_params(ch, edge_params or {})
    cnt = _chord_counts(v, ch, size, counts, fixed, min_count, tip_cells)
    if check:
        check_layout(v, q, tips=tip_list, chord_counts=cnt, margin_deg=margin_deg)

    # parameter lists per chord, along (ref) and against (rev) the reference direction
    n_v = len(v)
    n_ch = ch.n_chords
    ref_list: list[NDArray[np.float64]] = []
    rev_list: list[NDArray[np.float64]] = []
    exact_ref = np.ones(n_ch, dtype=bool)
    for k in range(n_ch):
        if k in fixed:
            ref, rev, along, _uw = fixed[k]
            exact_ref[k] = along
        else:
            ref = np.arange(cnt[k] + 1, dtype=np.float64) / cnt[k]
            rev = ref
        ref_list.append(ref)
        rev_list.append(rev)
    ref_flat = np.concatenate(ref_list)
    rev_flat = np.concatenate(rev_list)
    ch_off = np.concatenate([[0], np.cumsum(cnt + 1)[:-1]])

    # ---- points on coarse edges, generated once each
    e_lo, e_hi = ch.edges[:, 0], ch.edges[:, 1]
    e_n = cnt[ch.edge_chord]
    e_inner = e_n - 1
    edge_offsets = n_v + np.concatenate([[0], np.cumsum(e_inner)])
    owner, loc = _ragged(e_inner)
    pos = loc + 1  # position from lo, 1..n-1
    chd = ch.edge_chord[owner]
    # evaluate along the direction in which the chord's parameters are exact
    go_ref = exact_ref[chd]
    ref_is_lo_hi = ch.edge_forward[owner]
    from_lo = ref_is_lo_hi == go_ref
    a = np.where(from_lo, e_lo[owner], e_hi[owner])
    b = np.where(from_lo, e_hi[owner], e_lo[owner])
    idx = np.where(from_lo, pos, e_n[owner] - pos)
    par = np.where(go_ref, ref_flat[ch_off[chd] + idx], rev_flat[ch_off[chd] + idx])
    edge_pts = v[a] + par * (v[b] - v[a])

    # ---- grid nodes of the cells
    cc = ch.cell_chords
    k_c = cnt[cc[:, 0]]
    m_c = cnt[cc[:, 1]]
    n_nodes = (k_c + 1) * (m_c + 1)
    node_offsets = np.concatenate([[0], np.cumsum(n_nodes)])
    cell, loc = _ragged(n_nodes)
    kk = k_c[cell]
    mm = m_c[cell]
    i = loc % (kk + 1)
    j = loc // (kk + 1)
    qc = q[cell]
    ce = ch.cell_edges[cell]
    node_ids = np.full(len(cell), -1, dtype=np.int64)

    def side(
        edge: NDArray[np.int64],
        a_lt_b: NDArray[np.bool_],
        p: NDArray[np.int64],
        n: NDArray[np.int64],
    ) -> NDArray[np.int64]:
        return edge_offsets[edge] + np.where(a_lt_b, p, n - p) - 1

    inner_i = (i > 0) & (i < kk)
    inner_j = (j > 0) & (j < mm)
    sel = (j == 0) & inner_i  # side c0 -> c1 at position i
    node_ids[sel] = side(ce[sel, 0], qc[sel, 0] < qc[sel, 1], i[sel], kk[sel])
    sel = (j == mm) & inner_i  # side c3 -> c2 at position i
    node_ids[sel] = side(ce[sel, 2], qc[sel, 3] < qc[sel, 2], i[sel], kk[sel])
    sel = (i == 0) & inner_j  # side c0 -> c3 at position j
    node_ids[sel] = side(ce[sel, 3], qc[sel, 0] < qc[sel, 3], j[sel], mm[sel])
    sel = (i == kk) & inner_j  # side c1 -> c2 at position j
    node_ids[sel] = side(ce[sel, 1], qc[sel, 1] < qc[sel, 2], j[sel], mm[sel])
    for corner, sel in enumerate(
        [(i == 0) & (j == 0), (i == kk) & (j == 0), (i == kk) & (j == mm), (i == 0) & (j == mm)]
    ):
        node_ids[sel] = qc[sel, corner]
    inner = inner_i & inner_j
    n_inner = int(inner.sum())
    node_ids[inner] = edge_offsets[-1] + np.arange(n_inner)

    # interior points: s along c0 -> c1, t along c0 -> c3 (the direction of side c1 -> c2)
    ci = cell[inner]
    s_ref = (q[:, 0] < q[:, 1]) == ch.edge_forward[ch.cell_edges[:, 0]]
    t_ref = (q[:, 1] < q[:, 2]) == ch.edge_forward[ch.cell_edges[:, 1]]
    si = ch_off[cc[ci, 0]] + i[inner]
    tj = ch_off[cc[ci, 1]] + j[inner]
    s = np.where(s_ref[ci], ref_flat[si], rev_flat[si])
    t = np.where(t_ref[ci], ref_flat[tj], rev_flat[tj])
    c0, c1, c2, c3 = (v[q[ci, r]] for r in range(4))
    inner_pts = c0 + s * (c1 - c0) + t * (c3 - c0) + (s * t) * (c0 - c1 + c2 - c3)

    points = np.concatenate([v, edge_pts, inner_pts])

    # ---- quads
    n_quads = k_c * m_c
    qcell, loc = _ragged(n_quads)
    kq = k_c[qcell]
    n00 = node_offsets[qcell] + (loc // kq) * (kq + 1) + loc % kq
    quads = node_ids[np.stack([n00, n00 + 1, n00 + kq + 2, n00 + kq + 1], axis=1)]

    info = LayoutRefinement(
        chords=ch,
        chord_counts=cnt,
        chord_params=tuple(ref_list),
        quad_cell=qcell,
        cell_shape=np.stack([k_c, m_c], axis=1),
        edge_offsets=edge_offsets,
        node_offsets=node_offsets,
        node_ids=node_ids,
    )
    return points, quads, info
