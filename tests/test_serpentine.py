"""Serpentine corridors: straight single-edge walls, 90° turns, legs of 3.5–5 widths.

The straight stretch of an interior leg between the vertex discs of its inner corners is
only ``leg − 1.5`` widths (inner wall ``leg − 1``, two discs of a quarter width), so legs of
4 widths leave 2.5 widths: too short for the relaxed channel pass at overlap depth 1.5
(2·1.5 + 0.25 = 3.25), long enough for the retries at 1.25 and 1.0
(``DecomposeOptions.refine_retry``).  Without channels such a corridor stays one thick
piece whose prevertex gaps fall to 1e-20…1e-31 and the conformal map is refused.
"""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import mesh_polygon
from quadmesh.conformal.center import harmonic_measure
from quadmesh.decompose import DecomposeOptions, decompose


def serpentine(leg: float, legs: int, width: float = 1.0, kind: str = "meander") -> np.ndarray:
    """Counter-clockwise outline (k, 2) of a corridor of ``width`` whose centre line has
    ``legs`` straight legs of ``leg`` widths each joined by 90° turns: ``"meander"`` goes
    east, north, west, north, east, … (turns left, left, right, right, …), ``"staircase"``
    east, north, east, … .  Walls are single straight edges with mitred corners; the two
    ends are closed by straight caps.  The outline has ``2·(legs + 1)`` vertices."""
    dirs = [1, 1j, -1, 1j] if kind == "meander" else [1, 1j]
    d = np.array([dirs[k % len(dirs)] for k in range(legs)], dtype=complex)
    c = np.concatenate([[0], np.cumsum(leg * width * d)])
    n_in = np.concatenate([[d[0]], d]) * 1j  # left normal of the leg arriving at c_k
    n_out = np.concatenate([d, [d[-1]]]) * 1j  # left normal of the leg leaving c_k
    off = 0.5 * width * np.where(n_in == n_out, n_in, n_in + n_out)  # mitre at 90° turns
    z = np.concatenate([c - off, (c + off)[::-1]])  # right wall out, left wall back
    return np.column_stack([z.real, z.imag])


def _piece_gaps(dec) -> np.ndarray:
    """Smallest prevertex gap ``2π·min ω`` of every thick piece, seen from its centre."""
    return np.array([2 * np.pi * np.min(harmonic_measure(p.z, p.center)) for p in dec.thick])


def test_generator_shape() -> None:
    z = serpentine(4.0, 6)
    assert z.shape == (14, 2)
    x, y = z[:, 0], z[:, 1]
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert area == pytest.approx(6 * 4.0)  # legs·leg·width: mitred corners add and remove alike
    e = np.diff(np.vstack([z, z[:1]]), axis=0)
    # every edge is axis-parallel, every corner 90° or 270°
    assert np.all((np.abs(e[:, 0]) < 1e-12) | (np.abs(e[:, 1]) < 1e-12))


@pytest.mark.parametrize("kind", ["meander", "staircase"])
@pytest.mark.parametrize("leg", [4.0, 4.5, 5.0])
@pytest.mark.parametrize("legs", [4, 6, 8])
def test_serpentine_is_cut_into_channels_and_uncrowded_pieces(
    kind: str, leg: float, legs: int
) -> None:
    z = serpentine(leg, legs, kind=kind)
    dec = decompose(z)
    opt = dec.options
    assert len(dec.channels) >= legs // 2
    assert all(c.relaxed for c in dec.channels)
    for c in dec.channels:
        w1, w2 = c.walls
        assert abs(np.angle(c.frame.direction)) % (np.pi / 2) < 1e-9  # a leg's straight walls
        assert 1 / c.extremal_distance >= 2 * min(opt.refine_retry) + opt.refine_core - 1e-9
        assert w1 != w2
    assert len(dec.thick) == len(dec.channels) + 1
    # every piece can be mapped: its smallest prevertex gap is above the refinement target
    assert _piece_gaps(dec).min() >= opt.crowding_gap
    if leg == 4.0:
        # no stretch reaches 3.25 widths (interior 2.5, end legs 3.0): without the retries the
        # relaxed pass finds nothing and the corridor crowds
        plain = decompose(z, DecomposeOptions(refine_retry=()))
        assert len(plain.channels) < len(dec.channels)
        assert _piece_gaps(plain).min() < opt.crowding_gap


def test_short_legs_of_three_and_a_half_widths_stay_crowded_beyond_four_legs() -> None:
    """Interior legs of 3.5 widths leave 2 widths between the corner discs, below the
    2.25 of the shortest retry: only the end legs are cut (a documented limit). The middle
    piece, seen from its largest inscribed disk, crowds below what a map resolves (1e-14); its
    map starts from the least crowded centre instead (2e-12), and the polygon meshes."""
    z = serpentine(3.5, 6)
    dec = decompose(z)
    assert len(dec.channels) == 2
    inscribed = np.array([p.inscribed_gap for p in dec.thick])
    assert np.nanmin(inscribed) < 1e-14
    assert _piece_gaps(dec).min() > 1e-13
    res = mesh_polygon(z)
    res.mesh.check(res.polygon)
    assert res.quality.min_angle >= 60 - 1e-6 and res.quality.max_angle <= 120 + 1e-6


@pytest.mark.parametrize(
    ("kind", "leg", "legs"),
    [("meander", 4.0, 4), ("meander", 4.5, 6), ("meander", 5.0, 6), ("staircase", 3.5, 4)],
)
def test_serpentine_meshes(kind: str, leg: float, legs: int) -> None:
    res = mesh_polygon(serpentine(leg, legs, kind=kind))
    res.mesh.check(res.polygon)
    assert len(res.decomposition.channels) >= 1
    assert res.quality.min_angle >= 60 - 1e-6 and res.quality.max_angle <= 120 + 1e-6
    assert np.sum(res.quad_source == 2) > 0  # channel quads are present
