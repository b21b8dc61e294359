"""method="blocks": straight cuts into convex blocks with corners in [60°, 120°], refined by
bilinear grids.  Written meshes are checked by the independent reader of test_strict."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from quadmesh import MeshOptions, mesh_polygon
from quadmesh.blocks import (
    LADDER_MAX_EDGE,
    BlockLayoutError,
    _ladder_mesh,
    _resolve_hanging,
    block_layout,
    default_block_size,
    mesh_blocks,
)
from quadmesh.cells import cell_angles
from quadmesh.cli import main as cli_main
from quadmesh.examples import load_example
from quadmesh.io import write_mesh
from quadmesh.polygon import validate_polygon
from quadmesh.thin.corridor import mesh_corridor
from tests.test_strict import independent_check

L_SHAPE = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
#: an isosceles triangle with two 10° corners and a 160° apex: the axes of the two tip kites
#: and the apex's cut meet at one interior point (a junction of four cuts)
TWO_TIPS = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.5 * np.tan(np.radians(10.0))]])
#: an arrow: a shaft 0.6 x 0.3 and a triangular head with a 55° tip and a straight back (two
#: 270° corners where the shaft meets it, the head's back corners 62.5°); the 270° corners'
#: cuts into the head meet its slanted sides at less than 60°, so they end at junctions
ARROW = np.array(
    [
        [0.0, 0.35],
        [0.6, 0.35],
        [0.6, 0.0],
        [0.6 + 0.5 / np.tan(np.radians(27.5)), 0.5],
        [0.6, 1.0],
        [0.6, 0.65],
        [0.0, 0.65],
    ]
)
#: the arrow with its barbs swept back (46.6° barbs, 286° corners at the shaft): closes only
#: with a junction, although every corner has a straight cut of its own
BARBED_ARROW = np.array(
    [
        [0.0, 0.35],
        [0.6, 0.35],
        [0.5, 0.0],
        [0.5 + 0.5 / np.tan(np.radians(27.5)), 0.5],
        [0.5, 1.0],
        [0.6, 0.65],
        [0.0, 0.65],
    ]
)

#: bundled examples whose block layout closes (no fallback), with their coarse block counts
CLOSING = {
    "square": 1,
    "rectangle_2x1": 1,
    "l_shape": 3,
    "t_shape": 4,
    "u_shape": 5,
    "cross": 5,
    "comb": 17,
    "dumbbell": 7,
    "square_spiral": 17,
    "pentagon": 5,
    "hexagon": 6,
    "triangle": 3,
    "equilateral_triangle": 3,
    "right_triangle_10deg": 3,
    "corner_5deg": 7,
    "bent_channel": 3,
    "channel_20": 1,
    "glyph_s": 45,
}


def _z(a: np.ndarray) -> np.ndarray:
    return a[:, 0] + 1j * a[:, 1]


def test_l_shape_three_blocks_all_right_angles() -> None:
    lay = block_layout(_z(L_SHAPE))
    assert lay.n_cells == 3 and not lay.split and len(lay.cuts) == 2
    np.testing.assert_allclose(lay.angles, 90.0, atol=1e-9)
    pts, quads, _lay, _info = mesh_blocks(_z(L_SHAPE))
    # default size d/20 = 0.1414: 8 segments per unit side -> 3 blocks of 8x8
    assert len(quads) == 3 * 8 * 8
    np.testing.assert_array_equal(pts[:6], _z(L_SHAPE))


@pytest.mark.parametrize("name", sorted(CLOSING))
def test_examples_close_and_verify(name: str, tmp_path: Path) -> None:
    verts = load_example(name)
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks is not None
    assert res.blocks.n_cells == CLOSING[name]
    assert res.verification.ok
    # every coarse cell corner in [60°, 120°] (tips: the polygon's own corner below 60°)
    ang = cell_angles(res.blocks.points[res.blocks.cells])
    is_tip = np.isin(res.blocks.cells, res.blocks.tips)
    assert np.all(ang[~is_tip] >= 60.0 - 1e-7) and np.all(ang <= 120.0 + 1e-7)
    # few quads: at most 100 per polygon vertex at the default size (the paper's construction
    # makes ~1,000)
    assert res.mesh.n_quads <= 100 * len(verts)
    out = tmp_path / f"{name}.json"
    assert cli_main(["mesh", str(example_file(name)), "-o", str(out), "--method", "blocks"]) == 0
    got = independent_check(out, verts, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads


def example_file(name: str) -> Path:
    from quadmesh.examples import example_path

    return example_path(name)


def test_size_controls_the_count_and_edge_lengths(tmp_path: Path) -> None:
    z = _z(L_SHAPE)
    counts = []
    for h in (0.5, 0.25, 0.1):
        pts, quads, _lay, _ = mesh_blocks(z, size=h)
        e = np.abs(pts[quads] - pts[np.roll(quads, -1, axis=1)])
        assert e.max() <= h * (1 + 1e-12)
        assert e.min() >= h / 2  # one count per chord: no sliver rows
        counts.append(len(quads))
    assert counts == [3 * 2 * 2, 3 * 4 * 4, 3 * 10 * 10]
    # the CLI's relative size: 0.02d on the L-shape (d = 2.828) -> 18 segments per unit
    out = tmp_path / "l.json"
    src = tmp_path / "l_in.json"
    src.write_text(json.dumps({"vertices": L_SHAPE.tolist()}))
    assert (
        cli_main(["mesh", str(src), "-o", str(out), "--method", "blocks", "--size", "0.02d"]) == 0
    )
    got = independent_check(out, L_SHAPE, angle_tol=1e-9)
    assert got["n_quads"] == 3 * 18 * 18


@pytest.mark.parametrize("name", ["triangle", "right_triangle_10deg", "corner_5deg"])
def test_tip_stays_whole_in_a_small_kite(name: str) -> None:
    """A corner below 60° is cut off by a kite about one block size long: the tip's corner in
    the final mesh is the polygon's own angle, in one quad about the block size long,
    whose other three corners are new and in [60°, 120°]."""
    verts = load_example(name)  # corners of 48.8°, 10°, 5°
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    lay = res.blocks
    assert len(lay.tips) == 1 and lay.kites and res.verification.ok
    tip = lay.polygon[lay.tips[0]]
    v = res.mesh.vertices[:, 0] + 1j * res.mesh.vertices[:, 1]
    k = int(np.argmin(np.abs(v - tip)))
    (row,) = np.nonzero(np.any(res.mesh.quads == k, axis=1))[0]
    q = v[res.mesh.quads[row]]
    h = default_block_size(lay.polygon)
    # its edge points are h from the tip, its inner point at most 1.2 h (ρ = h sin a / sin(c/2))
    assert np.abs(q - tip).max() <= 1.2 * h
    ang = cell_angles(q[None, :])[0]
    j = int(np.argmin(np.abs(q - tip)))
    others = np.delete(ang, j)
    assert ang[j] < 60.0 and np.all(others >= 60.0) and np.all(others <= 120.0 + 1e-9)


def test_cli_says_the_tip_is_kept_in_a_kite(tmp_path: Path, capsys) -> None:
    out = tmp_path / "tri.json"
    args = ["mesh", str(example_file("right_triangle_10deg")), "-o", str(out), "--method", "blocks"]
    assert cli_main(args) == 0
    said = capsys.readouterr().out
    assert "1 corner below 60° kept whole in a tip kite" in said and "39 quads" in said
    independent_check(out, load_example("right_triangle_10deg"), angle_tol=1e-9)


@pytest.mark.parametrize("theta", np.linspace(0.5, 59.5, 60))
def test_tip_kite_corners_for_every_tip_angle(theta: float) -> None:
    """The kite cut off a tip of angle θ < 60° at each admissible inner corner c has corners
    θ, a, c, a with a = 180° − θ/2 − c/2, and leaves the rest of the polygon the corners
    180° − a at its two edge points and 360° − c inside: all new corners in [60°, 120°]."""
    from quadmesh.blocks import KITE_INNER, _tip_kite

    t = np.radians(theta)
    z = np.array([0.0, 3.0, 3.0 + 3.0j * np.tan(t) * 1.0])  # corner θ at 0, 90° at 3
    z[2] = 3.0 * np.exp(1j * t)
    lo = max(60.5, 121.0 - theta)
    for c in KITE_INNER:
        c_used = c if c == 120.0 else min(max(c, lo), 119.5)
        A, C, B = _tip_kite(z, 0, theta, 0.5, c_used)
        ang = cell_angles(np.array([[z[0], A, C, B]]))[0]
        a = 180.0 - theta / 2 - c_used / 2
        np.testing.assert_allclose(ang, [theta, a, c_used, a], atol=1e-9)
        assert 60.0 <= a <= 120.0 and 60.0 <= 180.0 - a <= 120.0
        assert 60.0 <= c_used <= 120.0 and 240.0 <= 360.0 - c_used <= 300.0
        assert abs(A - 0.5) < 1e-12 and abs(B - 0.5 * np.exp(1j * t)) < 1e-12


#: a four-pointed star (30.1° points, 239.9° corners between them): no single cut fits a 239.9°
#: corner, so no block layout, ladder or collar closed it before twin cuts (now 32 quads)
FOUR_STAR = np.column_stack(
    [
        np.where(np.arange(8) % 2 == 0, 1.0, 0.3) * np.cos(np.pi / 2 + np.pi * np.arange(8) / 4),
        np.where(np.arange(8) % 2 == 0, 1.0, 0.3) * np.sin(np.pi / 2 + np.pi * np.arange(8) / 4),
    ]
)


#: a triangle with a 120.2° apex: no cut fits the apex (both parts would need at least 60.5°)
#: and two cuts do not either, and no ladder or collar closes: blocks fall back
NO_LAYOUT = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, np.tan(np.radians(29.9))]])


def _plain_angles(v: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(Q, 4) corner angles in degrees of quads ``q`` over (V, 2) points ``v``, in plain numpy
    (each corner from its two edge vectors), and whether every quad turns left at every
    corner."""
    c = v[q]
    into = c - np.roll(c, 1, axis=1)  # edge arriving at each corner
    out = np.roll(c, -1, axis=1) - c  # edge leaving it
    cross = into[..., 0] * out[..., 1] - into[..., 1] * out[..., 0]
    dot = into[..., 0] * out[..., 0] + into[..., 1] * out[..., 1]
    assert np.all(cross > 0), "a quad is clockwise or not strictly convex"
    return 180.0 - np.degrees(np.arctan2(cross, dot))


@pytest.mark.parametrize(
    ("name", "verts"), [("arrow", ARROW), ("barbed_arrow", BARBED_ARROW), ("two_tips", TWO_TIPS)]
)
def test_junctions_close_the_arrow_and_the_two_tip_triangle(name, verts, tmp_path) -> None:
    """Layouts that need an interior point where three or four cuts meet: the arrow (the cuts
    from the 270° corners end at junctions in the head), the arrow with swept-back barbs, and
    the isosceles triangle with two 10° tips (both kites' axes and the apex's cut meet at one
    point).  All close without the
    paper's construction; every angle of the mesh, computed here from the returned
    coordinates, is in [60°, 120°] but the polygon's own corners below 60°, each in one quad
    with its own angle; the written file passes the independent check."""
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks is not None and res.blocks.kind == "cuts"
    assert res.blocks.junctions >= 1 and res.verification.ok
    v, q = res.mesh.vertices, res.mesh.quads
    ang = _plain_angles(v, q)
    # the polygon's corners below 60°: each in exactly one quad, with the polygon's angle
    pv = np.asarray(verts, dtype=float)
    e_in = pv - np.roll(pv, 1, axis=0)
    e_out = np.roll(pv, -1, axis=0) - pv
    own = 180.0 - np.degrees(
        np.arctan2(
            e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0],
            e_in[:, 0] * e_out[:, 0] + e_in[:, 1] * e_out[:, 1],
        )
    )
    tips = np.nonzero(own < 60.0)[0]
    at_tip = np.zeros(q.shape, dtype=bool)
    for i in tips:
        k = int(np.argmin(np.linalg.norm(v - pv[i], axis=1)))
        assert np.linalg.norm(v[k] - pv[i]) < 1e-12
        hit = q == k
        assert hit.sum() == 1
        np.testing.assert_allclose(ang[hit], own[i], atol=1e-9)
        at_tip |= hit
    assert np.all(ang[~at_tip] >= 60.0 - 1e-9) and np.all(ang[~at_tip] <= 120.0 + 1e-9)
    # few quads at the default size
    assert res.mesh.n_quads <= 40 * len(verts)
    src = tmp_path / f"{name}_in.json"
    src.write_text(json.dumps({"vertices": pv.tolist()}))
    out = tmp_path / f"{name}.json"
    assert cli_main(["mesh", str(src), "-o", str(out), "--method", "blocks"]) == 0
    got = independent_check(out, pv, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads


def test_hub_arms_are_chosen_with_every_angle_in_range() -> None:
    """Around a hub the cheapest choice of arms has every angle between neighbours in
    [60.5°, 119.5°] (or exactly 120°), the first arm always taken; with no such choice there is
    none."""
    from quadmesh.blocks import _cycle, _Ray

    def arm(cost: float) -> _Ray:
        return _Ray(-1, 1 + 0j, 1 + 0j, -1, 0.0, -1, [], cost)

    rng = np.random.default_rng(7)
    found = 0
    for _ in range(200):
        angles = np.sort(rng.uniform(1.0, 359.0, rng.integers(2, 12)))
        arms = [(0.0, arm(1.0))] + [
            (float(a), arm(float(c))) for a, c in zip(angles, rng.uniform(0.1, 2, len(angles)))
        ]
        got = _cycle(arms)
        by_id = {id(r): a for a, r in arms}
        if got is None:
            continue
        assert got[0] is arms[0][1]
        chosen = np.array([by_id[id(r)] for r in got])
        gaps = np.diff(np.append(chosen, 360.0))
        ok = ((gaps >= 60.5) & (gaps <= 119.5)) | (np.abs(gaps - 120.0) < 1e-9)
        assert np.all(ok) and len(got) >= 3
        found += 1
    assert found >= 20  # the random turns do leave choices (48 of 200 with this seed)
    # exactly 120° apart: a Y; 130° apart leaves no choice
    y = [(0.0, arm(1.0)), (120.0, arm(1.0)), (240.0, arm(1.0)), (200.0, arm(0.1))]
    assert [id(r) for r in _cycle(y)] == [id(y[k][1]) for k in range(3)]
    assert _cycle([(0.0, arm(1.0)), (130.0, arm(1.0)), (260.0, arm(1.0))]) is None


def test_two_tip_triangle_kites_meet_at_one_junction() -> None:
    """The two-tip triangle's layout: both tips in kites, the kites' axes and the apex's cut
    meeting at one interior point with the fourth cut running to the base; all six cells have
    their new corners in [60°, 120°]."""
    lay = block_layout(_z(TWO_TIPS))
    assert lay.kites and lay.junctions == 1 and lay.n_cells == 6
    is_tip = np.isin(lay.cells, lay.tips)
    assert np.all(lay.angles[~is_tip] >= 60.0 - 1e-9) and np.all(lay.angles <= 120.0 + 1e-9)
    # the junction: the one layout point inside the triangle shared by four cells
    cnt = np.bincount(lay.cells.ravel(), minlength=len(lay.points))
    inner = [
        k
        for k in np.nonzero(cnt == 4)[0]
        if lay.points[k].imag > 1e-9 and abs(lay.points[k] - lay.polygon[2]) > 1e-9
    ]
    assert len(inner) == 1
    # on both tips' bisectors (5° from the base at each end)
    p = lay.points[inner[0]]
    assert abs(np.degrees(np.angle(p)) - 5.0) < 1e-6
    assert abs(np.degrees(np.angle(1.0 - p.conjugate())) - 5.0) < 1e-6


def test_no_layout_falls_back_to_the_paper_and_says_why(capsys) -> None:
    """The fallback message names each route's reason: the cuts', the ladder's (in brackets
    after it) and the collar's."""
    res = mesh_polygon(NO_LAYOUT, MeshOptions(method="blocks"))  # no cuts, ladder, collar
    assert res.blocks is None and res.fallback and "paper's construction" in res.fallback
    assert "collar" in res.fallback
    ladder = res.fallback.split("nor does a ladder of straight cells along the polygon (")[1]
    assert ladder.split(")")[0].strip()  # the ladder's own reason
    assert res.pieces and res.verification.ok


def test_a_block_mesh_failing_verification_falls_back(monkeypatch) -> None:
    """A block mesh that fails the strict check is never returned: the run falls back to the
    paper's construction and says so (a broken mesh is injected: one quad turned over)."""
    import quadmesh.blocks as blocks

    real = blocks.mesh_blocks

    def broken(z, size=None, mesh_face=None):
        pts, quads, lay, info = real(z, size, mesh_face)
        quads = quads.copy()
        quads[0] = quads[0][::-1]
        return pts, quads, lay, info

    monkeypatch.setattr(blocks, "mesh_blocks", broken)
    res = mesh_polygon(L_SHAPE, MeshOptions(method="blocks"))
    assert res.blocks is None and res.pieces and res.verification.ok
    assert "failed verification" in res.fallback and "paper's construction" in res.fallback


def test_octagon_closes_by_a_collar_around_a_lattice_core(tmp_path) -> None:
    """Eight 135° corners: no set of straight cuts works, a collar of spokes around a core of
    lattice kites does; the written mesh passes the independent check."""
    verts = load_example("octagon")
    with pytest.raises(BlockLayoutError, match="straight cuts"):
        block_layout(_z(verts))
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks.kind == "ring"
    assert len(res.blocks.cuts) >= 8  # a spoke at every 135° corner at least
    out = tmp_path / "octagon.json"
    write_mesh(out, res.mesh)
    got = independent_check(out, verts, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads < 1500


def test_options_validate_method_and_size() -> None:
    with pytest.raises(ValueError, match="method"):
        MeshOptions(method="paving")
    with pytest.raises(ValueError, match="size"):
        MeshOptions(method="blocks", size=0.0)
    with pytest.raises(ValueError, match="size"):
        MeshOptions(method="blocks", size=float("nan"))


def test_far_polygon_blocks_verified_in_place() -> None:
    far = L_SHAPE * 10.0 + [5e6, 3e6]
    res = mesh_polygon(far, MeshOptions(method="blocks"))
    assert res.blocks is not None and res.verification.ok
    assert res.mesh.n_quads == 3 * 8 * 8


def test_hanging_points_are_carried_to_the_boundary() -> None:
    """Two cells on top of one long cell (a T-junction at (1, 1)): the long cell is split at
    the T's parameter down to the boundary; the result is conforming, covers the same area and
    refines with every angle in range."""
    from quadmesh.cells import layout_chords, refine_layout

    pts = np.array([0, 2, 2 + 1j, 1j, 1 + 1j, 1 + 2j, 2j, 2 + 2j], dtype=complex)
    cells = np.array([[0, 1, 2, 3], [3, 4, 5, 6], [4, 2, 7, 5]])
    fixed = _resolve_hanging(pts, cells, np.zeros(len(pts), bool))
    assert fixed is not None
    P, C = fixed
    assert len(C) == 4  # the long cell in two
    np.testing.assert_allclose(P[C].real.min(), 0.0)
    ch = layout_chords(C, len(P))  # raises unless conforming (each edge in at most two cells)
    assert len(ch.boundary_edges) == 8
    area = 0.5 * np.sum((np.conj(P[C]) * P[C][:, [1, 2, 3, 0]]).imag)
    assert abs(area - 4.0) < 1e-12
    pts2, quads, _ = refine_layout(P, C, size=0.25)
    ang = cell_angles(pts2[quads])
    assert ang.min() > 90 - 1e-9 and ang.max() < 90 + 1e-9
    # a T on a cell holding a tip cannot be removed: None
    tip = np.zeros(len(pts), bool)
    tip[1] = True
    assert _resolve_hanging(pts, cells, tip) is None


def test_right_angles_fill_one_histogram_bin() -> None:
    """A block mesh of the L-shape has only right angles: the quality histogram puts all of
    them in the 90°–95° bin (rounding noise of ±1e-14° does not split them)."""
    res = mesh_polygon(L_SHAPE, MeshOptions(method="blocks"))
    h = res.quality.histogram
    assert h[18] == h.sum() and h.sum() > 0


def test_benchmark_reports_block_closure() -> None:
    """bench --families --method blocks counts the polygons whose layout closed; a fallback
    still counts as meshed."""
    from quadmesh.benchmark import _mesh_vertices, format_family_table, summarise_families

    ok = _mesh_vertices(L_SHAPE, MeshOptions(method="blocks"))
    fb = _mesh_vertices(NO_LAYOUT, MeshOptions(method="blocks"))
    assert ok["status"] == fb["status"] == "meshed"
    assert ok["blocks"] is True and fb["blocks"] is False and ok["quads"] == 192
    base = {"family": "f", "nominal_aspect": None, "aspect": 2.0, "min_edge_over_width": 0.5}
    rows = [{**base, "name": "a", "n": 6, **ok}, {**base, "name": "b", "n": 3, **fb}]
    (s,) = summarise_families(rows)
    assert s["meshed"] == 2 and s["blocks_closed"] == 1
    table = format_family_table([s])
    assert "blocks closed" in table.splitlines()[0] and "1/2" in table.splitlines()[1]
    # without method="blocks" there is no such column
    plain = _mesh_vertices(L_SHAPE, None)
    (s2,) = summarise_families([{**base, "name": "a", "n": 6, **plain}])
    assert s2["blocks_closed"] is None
    assert "blocks closed" not in format_family_table([s2])


@pytest.mark.parametrize("name", ["comb", "octagon", "star_30"])
def test_vectorised_conflicts_match_the_pair_rule(name: str) -> None:
    """The all-pairs numpy test of conflicting cuts agrees with the one-pair rule on every pair
    (full rays, joins and T-variants)."""
    from quadmesh.blocks import (
        POINT_GAP,
        _angles_deg,
        _candidates,
        _conflicts,
        _pair_conflicts,
        _scale,
        _t_variants,
    )

    z = _z(load_example(name))
    d = _scale(z)
    rays = _candidates(z, _angles_deg(z), d)
    rays = rays + _t_variants(z, rays, d)
    rays = rays[:: max(1, len(rays) // 300)]  # a spread of at most ~300 rays
    got = set(_conflicts(z, rays, d))
    want = {
        (a, b)
        for a in range(len(rays))
        for b in range(a + 1, len(rays))
        if _pair_conflicts(z, rays[a], rays[b], POINT_GAP * d)
    }
    assert got == want and len(want) > 0


def test_vectorised_conflicts_of_junctions_match_the_pair_rule() -> None:
    """With junction candidates (several arms each) the all-pairs numpy test agrees with the
    one-pair rule applied to every pair of their segments: two candidates conflict when any
    arm of one conflicts with any arm (or the cut) of the other."""
    from quadmesh.blocks import (
        POINT_GAP,
        _angles_deg,
        _candidates,
        _conflicts,
        _junctions,
        _long,
        _p0,
        _pair_conflicts,
        _scale,
    )

    z = _z(ARROW)
    d = _scale(z)
    theta = _angles_deg(z)
    bare: list = []
    rays = _candidates(z, theta, d, bare)
    stars = _junctions(z, theta, d, _long(rays, bare))
    assert len(stars) > 10 and {len(s.arms) for s in stars} >= {3, 4}
    cands = rays[::4] + stars[:: max(1, len(stars) // 60)]
    got = set(_conflicts(z, cands, d))

    def segs(c):
        return c.arms if c.arms else (c,)

    want = {
        (a, b)
        for a in range(len(cands))
        for b in range(a + 1, len(cands))
        if any(
            _pair_conflicts(z, sa, sb, POINT_GAP * d)
            for sa in segs(cands[a])
            for sb in segs(cands[b])
        )
    }
    assert len(want) > 0

    def on_the_limit(a: int, b: int) -> bool:
        """Two segments cross at 60.5° up to the last bit (an arm of a junction built at
        exactly 120° from a cut sampled at its window's edge): both answers are right."""
        lim = np.cos(np.radians(60.5))
        for sa in segs(cands[a]):
            for sb in segs(cands[b]):
                da, db = sa.end - _p0(z, sa), sb.end - _p0(z, sb)
                if abs(abs((np.conj(da) * db).real) / abs(da) / abs(db) - lim) < 1e-12:
                    return True
        return False

    assert all(on_the_limit(a, b) for a, b in got ^ want)


@pytest.mark.parametrize(
    ("name", "most_per_vertex"), [("slit_355deg", 40), ("river", 10), ("stroke_spiral", 25)]
)
def test_corridors_close_by_a_ladder_of_straight_cells(name: str, most_per_vertex: int, tmp_path):
    """Where straight cuts do not close, a polygon that is one corridor (a 355° slit, a ragged
    river, a 3-turn pen spiral) gets a ladder of convex straight cells: coarse corners in
    [60°, 120°] (the polygon's own corners kept whole), every rung from boundary to boundary,
    no edge longer than LADDER_MAX_EDGE × size; the written mesh passes the independent check
    at 1e-9°."""
    verts = load_example(name)
    z = validate_polygon(verts).z
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks.kind == "ladder"
    lay = res.blocks
    assert lay.cut_noun == "rung" and "ladder" in lay.title
    ang = cell_angles(lay.points[lay.cells])
    own = lay.cells < len(z)
    assert np.all(ang[~own] >= 60.0) and np.all(ang[~own] <= 120.0)
    assert np.all((ang > 0) & (ang < 180))
    # rungs end on the polygon's boundary
    e = np.roll(z, -1) - z
    for end in lay.cuts.ravel():
        u = np.clip(((end - z) * np.conj(e)).real / np.abs(e) ** 2, 0, 1)
        assert np.min(np.abs(z + u * e - end)) <= 1e-9 * np.abs(z).max()
    q = res.mesh.z[res.mesh.quads]
    longest = np.abs(np.roll(q, -1, axis=1) - q).max()
    assert longest <= LADDER_MAX_EDGE * default_block_size(z) * (1 + 1e-12)
    out = tmp_path / f"{name}.json"
    write_mesh(out, res.mesh)
    got = independent_check(out, verts, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads <= most_per_vertex * len(z)


@pytest.mark.parametrize("turn", [100.0, 140.0])
def test_a_sharp_bend_closes_by_a_ladder_whose_sector_rows_turn(turn: float, tmp_path) -> None:
    """A pen stroke bent by 100° or 140°: no straight cuts and no ladder with straight sector
    rows close it (it fell back to the paper's construction: 11,091 quads at 100°); the ladder
    is then searched again with sectors whose rows turn (100°: 621 quads) or a round bend,
    a sector about its outer arc's centre (140°); the written mesh passes the independent
    check at 1e-9°."""
    import shapely

    a = np.radians(turn)
    centre = [[0.0, 0.0], [4.0, 0.0], [4.0 + 4.0 * np.cos(a), 4.0 * np.sin(a)]]
    g = shapely.LineString(centre).buffer(0.5, cap_style="flat", join_style="round", quad_segs=4)
    verts = np.asarray(shapely.geometry.polygon.orient(g, 1.0).exterior.coords)[:-1]
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks.kind == "ladder"
    out = tmp_path / "bend.json"
    write_mesh(out, res.mesh)
    got = independent_check(out, verts, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads < 1500


def test_a_ladder_is_refused_where_its_ends_would_be_needles() -> None:
    """The octagon is a corridor of one rung between two round ends, but the ends' sectors
    would have spokes of several target sizes: the ladder is refused for blocks (a collar
    closes instead), although the corridor mesher itself accepts it."""
    z = validate_polygon(load_example("octagon")).z
    h = default_block_size(z)
    cm = mesh_corridor(z, size=h)
    q = cm.vertices[cm.quads]
    assert np.abs(np.roll(q, -1, axis=1) - q).max() > LADDER_MAX_EDGE * h
    assert _ladder_mesh(z, h) is None
    assert mesh_polygon(load_example("octagon"), MeshOptions(method="blocks")).blocks.kind == "ring"


def _corner_angles_deg(xy: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Every corner angle of every quad, in degrees, from the coordinates alone."""
    q = xy[quads]  # (Q, 4, 2)
    a = np.roll(q, 1, axis=1) - q
    b = np.roll(q, -1, axis=1) - q
    cos = (a * b).sum(axis=2) / (np.linalg.norm(a, axis=2) * np.linalg.norm(b, axis=2))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


@pytest.mark.parametrize("index", [1, 4, 9])
def test_walk_ladders_keep_the_coarser_sectors_when_they_give_fewer_quads(index: int) -> None:
    """A buffered random walk of the corridor families closes by a ladder; its layout is
    searched for with sector crosscuts of at least 16 and of at least 8 chords, and the mesh
    with fewer quads is kept: never more quads than the 16-chord ladder alone, at most 55 per
    polygon vertex, every corner angle (recomputed from the coordinates) in [60°, 120°]."""
    from quadmesh.families import family_members
    from quadmesh.thin.corridor import ladder_layout

    m = family_members("walks")[index]
    res = mesh_polygon(m.vertices, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks.kind == "ladder"
    zz = res.mesh.z + res.mesh_origin
    ang = _corner_angles_deg(np.column_stack([zz.real, zz.imag]), res.mesh.quads)
    assert ang.min() >= 60.0 - 1e-7 and ang.max() <= 120.0 + 1e-7
    n = len(validate_polygon(m.vertices).z)
    assert res.mesh.n_quads <= 55 * n
    z = validate_polygon(m.vertices).z - res.origin
    h = default_block_size(z)
    only16 = mesh_corridor(z, size=h, lay=ladder_layout(z, sector_chords=16))
    assert res.mesh.n_quads <= len(only16.quads)
    if index in (1, 9):  # measured: 8,732 -> 5,910 and 8,475 -> 4,425 quads
        assert res.mesh.n_quads < 0.8 * len(only16.quads)


def test_long_cut_search_lays_out_a_glyph_the_first_search_ran_out_of_time_on(monkeypatch) -> None:
    """Computer Modern "H" (68 vertices, 44 cut slots): the first straight-cut search runs out
    of its 3 s after a round or two, and neither a ladder nor a collar closes; the longer search
    with faster rounds (faces apart) closes it.  Its mesh passes the strict check: every angle
    in [60°, 120°] (recomputed from the coordinates), conforming, the polygon's area."""
    from quadmesh.blocks import LONG_SEARCH_SECONDS, _long_cut_layout
    from quadmesh.cells import refine_layout
    from quadmesh.families import family_members
    from quadmesh.mesh import finalize_mesh

    m = next(x for x in family_members("glyphs_cm") if x.name == "cmr10_H")
    poly = validate_polygon(m.vertices)
    z = poly.z
    assert LONG_SEARCH_SECONDS >= 10.0
    # the search stops at the first layout (about 10 s here); a machine busy with other jobs
    # must not turn a wall-clock budget into a failure
    monkeypatch.setattr("quadmesh.blocks.LONG_SEARCH_SECONDS", 120.0)
    # only a search that ran out of time is repeated
    assert _long_cut_layout(z, "no set of straight cuts ... (4 face(s) could not be split)") is None
    lay = _long_cut_layout(z, "no set of straight cuts ... (no layout within 3 s of search)")
    assert lay is not None and lay.kind == "cuts"
    assert np.all(lay.points[: len(z)] == z)
    h = default_block_size(z)
    pts, quads, _ = refine_layout(lay.points, lay.cells, size=h, tips=lay.tips.tolist())
    _mesh, _, report = finalize_mesh(poly, pts, quads)
    assert report.ok
    ang = _corner_angles_deg(np.column_stack([pts.real, pts.imag]), quads)
    assert ang.min() >= 60.0 - 1e-7 and ang.max() <= 120.0 + 1e-7
    q = pts[quads]
    area = 0.5 * np.sum((np.conj(q) * np.roll(q, -1, axis=1)).imag)
    assert area == pytest.approx(poly.area, rel=1e-9)


def test_glyph_with_many_candidates_closes_with_t_junctions_on_the_long_search() -> None:
    """STIX "C" (82 vertices): 1,072 full and bare candidate rays, more than the first search
    makes T-junction candidates for, and a corner whose every straight cut meets the boundary
    at less than 60°; no ladder or collar closes.  The second search makes them and closes:
    ``mesh_polygon`` with ``method="blocks"`` returns the block mesh (no fallback), every
    angle in [60°, 120°] recomputed from the coordinates, the polygon's area, conforming
    (the strict check of ``finalize_mesh`` passed)."""
    from quadmesh.blocks import MAX_RAYS_FOR_TEES, _long_cut_layout
    from quadmesh.families import family_members

    m = next(x for x in family_members("glyphs_stix") if x.name == "STIXGeneral_C")
    poly = validate_polygon(m.vertices)
    assert MAX_RAYS_FOR_TEES < 1072
    # a search that had its T-junction candidates already is not repeated (the L-shape has a
    # layout, but few candidates), nor one that failed for another reason
    el = L_SHAPE[:, 0] + 1j * L_SHAPE[:, 1]
    assert _long_cut_layout(el, "no straight cut from the corner at (1, 1)") is None
    assert _long_cut_layout(poly.z, "121 cuts would be needed") is None
    _assert_cut_layout_mesh(m.vertices, poly)


def _assert_cut_layout_mesh(vertices: np.ndarray, poly) -> int:
    """``mesh_polygon`` with ``method="blocks"`` returns the mesh of a straight-cut layout (no
    fallback), the strict check passed, every angle in [60°, 120°] recomputed from the
    coordinates, the polygon's area; returns its quad count."""
    res = mesh_polygon(vertices, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks is not None and res.blocks.kind == "cuts"
    assert res.verification.ok
    zz = res.mesh.z + res.mesh_origin
    ang = _corner_angles_deg(np.column_stack([zz.real, zz.imag]), res.mesh.quads)
    assert ang.min() >= 60.0 - 1e-7 and ang.max() <= 120.0 + 1e-7
    q = zz[res.mesh.quads]
    area = 0.5 * np.sum((np.conj(q) * np.roll(q, -1, axis=1)).imag)
    assert area == pytest.approx(poly.area, rel=1e-9)
    return res.mesh.n_quads


def test_serif_brackets_close_when_face_splits_are_searched_by_sampling() -> None:
    """Computer Modern "I": the cut search finds cut sets whose faces all have corners in
    range (the cuts from the bracket fillets cross and leave pentagons, one side 1/37 of
    another), but SLSQP started from the faces' centroids finds no split about a centre, and
    round after round of excluded cut sets ends without a layout. A sampled search over the
    centres and side points (then SLSQP again) splits them: the glyph closes by straight cuts
    (before: the paper's construction, about 40,000 quads). ``mesh_polygon`` returns the block
    mesh (no fallback), every angle in [60°, 120°] recomputed from the coordinates, the
    polygon's area, the strict check passed."""
    from quadmesh.blocks import _cut_layout
    from quadmesh.families import family_members

    m = next(x for x in family_members("glyphs_cm") if x.name == "cmr10_I")
    poly = validate_polygon(m.vertices)
    with pytest.raises(BlockLayoutError):
        _cut_layout(poly.z)
    assert _cut_layout(poly.z, sample=True).kind == "cuts"
    assert _assert_cut_layout_mesh(m.vertices, poly) < 1000


def _square_mesher(calls: list[np.ndarray]):
    """The paper's construction as the face mesher of :func:`mesh_partial_layout`, recording
    the polygons it is given."""
    from quadmesh.pipeline import _face_mesher

    inner = _face_mesher(MeshOptions(), None, None)

    def mesh_face(w: np.ndarray):
        calls.append(np.asarray(w))
        return inner(w)

    return mesh_face


def _strip_partial():
    """A 3 x 1 strip of three unit squares, the middle one marked as a face that did not
    split."""
    from quadmesh.blocks import PartialLayout

    z = np.array([0, 1, 2, 3, 3 + 1j, 2 + 1j, 1 + 1j, 1j], dtype=np.complex128)
    faces = tuple(np.array(f) for f in ([0, 1, 6, 7], [1, 2, 5, 6], [2, 3, 4, 5]))
    part = PartialLayout(
        z, z.copy(), faces, frozenset({1}), np.zeros(8, dtype=bool), np.ones(8, dtype=bool)
    )
    return z, part


def test_a_face_that_does_not_split_is_laid_out_on_its_own(tmp_path: Path) -> None:
    # the strip's middle square, laid out on its own (one cell: a square needs no cut), joins
    # the other cells: one block mesh, no face for the paper's construction, the face mesher
    # never called
    from quadmesh.blocks import mesh_partial_layout
    from quadmesh.mesh import finalize_mesh

    z, part = _strip_partial()
    calls: list[np.ndarray] = []
    pts, quads, lay, _info = mesh_partial_layout(part, 0.25, _square_mesher(calls))
    assert calls == [] and lay.fallback_faces == () and lay.fallback_quads == 0
    assert len(lay.local_faces) == 1
    assert np.allclose(np.sort_complex(lay.local_faces[0]), [1, 1 + 1j, 2, 2 + 1j])
    assert len(lay.cells) == 3 and len(quads) == 3 * 4 * 4  # a 4 x 4 grid per unit square
    poly = np.column_stack([z.real, z.imag])
    mesh, _origin, report = finalize_mesh(poly, pts, quads)
    assert report.ok
    out = tmp_path / "strip_local.json"
    write_mesh(out, mesh)
    assert independent_check(out, poly, angle_tol=1e-9)["n_quads"] == 48
    # without a face mesher the same layout closes too
    assert len(mesh_partial_layout(part, 0.25)[1]) == 48


def test_greedy_cuts_serve_slots_cheapest_first_without_conflicts_or_nogoods() -> None:
    # the relaxed search's choice when its integer program finds none in time: cheapest first,
    # one cut per slot, no conflicting pair, no nogood set completed, no T-junction variant
    from quadmesh.blocks import _greedy_cuts, _Ray

    def ray(slot: tuple[int, int], cost: float, stop: int = -1) -> _Ray:
        return _Ray(0, 1 + 0j, 0j, 0, 0.5, -1, [slot], cost, stop=stop)

    rays = [ray((0, 0), 1.0), ray((0, 0), 0.5), ray((1, 0), 0.7), ray((1, 0), 2.0)]
    rays.append(ray((2, 0), 0.1, stop=1))  # a T-junction variant: never chosen greedily
    assert _greedy_cuts(rays, [(1, 2)], []) == [1, 3]
    assert _greedy_cuts(rays, [(1, 2)], [[1, 3]]) == [1]  # slot (1, 0) stays without a cut
    assert _greedy_cuts(rays, [], []) == [1, 2]


def test_simple_loops_split_a_face_traced_through_a_shared_side() -> None:
    # a face of a glyph's cut arrangement (STIX "E") traced as one walk through two faces that
    # share the side 134-82, coming back to 129 and to 23: two simple loops
    from quadmesh.blocks import _simple_loops

    face = np.array([129, 128, 134, 82, 132, 105, 129, 23, 24, 82, 134, 22, 23])
    got = [lp.tolist() for lp in _simple_loops(face)]
    assert got == [[129, 128, 134, 82, 132, 105], [23, 24, 82, 134, 22]]
    assert [lp.tolist() for lp in _simple_loops(np.arange(5))] == [[0, 1, 2, 3, 4]]


def test_a_face_that_does_not_split_falls_back_glued_by_transition_cells(
    tmp_path: Path, monkeypatch
) -> None:
    # the strip's middle square, as if no layout of its own closed: it is meshed by the paper's
    # construction (about a hundred graded points on each side it shares), and each outer
    # square goes from those points down to the size's count on its far side by a transition
    # cascade, so the graded rows stop there
    import quadmesh.blocks as blocks
    from quadmesh.blocks import mesh_partial_layout
    from quadmesh.mesh import finalize_mesh

    monkeypatch.setattr(blocks, "_face_layout", lambda w, size, depth, deadline=None: None)

    z, part = _strip_partial()
    calls: list[np.ndarray] = []
    pts, quads, lay, _info = mesh_partial_layout(part, 0.25, _square_mesher(calls))
    assert len(calls) == 1 and np.allclose(np.sort_complex(calls[0]), [1, 1 + 1j, 2, 2 + 1j])
    assert [len(f) for f in lay.fallback_faces] == [4]
    assert len(lay.cells) == 2
    on = {x: int(np.sum(np.abs(pts.real - x) < 1e-12)) - 1 for x in (0, 1, 2, 3)}
    assert on[1] > 20 and on[2] > 20  # the face mesh's graded points on its sides
    assert on[0] < on[1] / 2 and on[3] < on[2] / 2  # the far sides: fewer rows
    face_quads = lay.fallback_quads
    assert 0 < face_quads < len(quads)
    # the face's quads keep the stages of the paper's construction that made them
    assert len(lay.fallback_source) == face_quads and set(lay.fallback_source) <= {0, 1, 2, 3}
    inside = np.abs(pts[quads].mean(axis=1).real - 1.5) < 0.5
    assert inside.sum() == face_quads  # the face's quads are the last ones, all in the face
    assert np.all(inside[len(quads) - face_quads :])
    poly = np.column_stack([z.real, z.imag])
    mesh, _origin, report = finalize_mesh(poly, pts, quads)
    assert report.ok
    # the block layer fills the face that fell back (the unit square in the middle)
    from types import SimpleNamespace

    from quadmesh.render import _layer_block_layout

    parts = {p.label: p for p in _layer_block_layout(SimpleNamespace(blocks=lay))}
    fill = parts["faces meshed by the paper's construction"].mesh
    assert abs(fill.area - 1.0) < 1e-12 and np.allclose(fill.bounds[:4], [1, 2, 0, 1])
    out = tmp_path / "strip.json"
    write_mesh(out, mesh)
    got = independent_check(out, poly, angle_tol=1e-9)
    assert got["n_quads"] == len(quads)


def test_faces_that_fall_back_side_by_side_are_merged_into_one_polygon() -> None:
    from quadmesh.blocks import _merged_faces

    # two squares sharing the side 1-4 (with a point 6 on it), and a third apart
    a = [0, 1, 6, 4, 5]
    b = [1, 2, 3, 4, 6]
    c = [10, 11, 12, 13]
    got = _merged_faces([a, b, c])
    assert got is not None and len(got) == 2
    merged = next(f for f in got if len(f) != 4)
    k = merged.index(0)
    assert merged[k:] + merged[:k] == [0, 1, 2, 3, 4, 5]
    # a ring of four faces around a hole is no simple polygon
    ring = [[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    assert _merged_faces(ring) is None


def test_relaxed_search_leaves_uncut_corners_in_faces_that_fall_back() -> None:
    # Computer Modern "A": no set of straight cuts serves every corner (the integer program has
    # no solution); with corners allowed to stay uncut, a round's faces tile the glyph, the
    # faces that split have every corner in range, and every obtuse corner without a cut lies
    # in a face that falls back
    from quadmesh.blocks import _angles_deg, _cut_layout
    from quadmesh.families import family_members
    from quadmesh.polygon import signed_area

    glyph = next(m for m in family_members("glyphs_cm") if m.name == "cmr10_A")
    z = validate_polygon(glyph.vertices).z
    with pytest.raises(BlockLayoutError, match="no set of straight cuts"):
        block_layout(z)
    part: list = []
    with pytest.raises(BlockLayoutError):
        _cut_layout(z, seconds=1.0, separate=True, partial=part, relax=True)
    assert 1 <= len(part) <= 3  # the rounds kept, fewest unsplit faces first
    assert [p.score for p in part] == sorted(p.score for p in part)
    lay = part[0]
    assert 0 < len(lay.wrong) < len(lay.faces)
    areas = [signed_area(lay.points[f]) for f in lay.faces]
    assert min(areas) > 0 and abs(sum(areas) - signed_area(z)) < 1e-12 * abs(signed_area(z))
    theta = _angles_deg(z)
    starts = np.abs(lay.cuts[:, 0][:, None] - z[None, :]).min(axis=0) < 1e-12
    in_wrong = np.zeros(len(z), dtype=bool)
    for k in lay.wrong:
        f = lay.faces[k]
        in_wrong[f[f < len(z)]] = True
    uncut = (theta > 120.0 + 1e-7) & ~starts
    assert uncut.any() and np.all(in_wrong[uncut])
    for k in set(range(len(lay.faces))) - set(lay.wrong):
        f = lay.faces[k]
        a = _angles_deg(lay.points[f])
        tip = lay.tip_mask[f]
        assert np.all(a[~tip] >= 60.0 - 1e-7) and np.all(a[~tip] <= 120.0 + 1e-7)


def _stix(name: str) -> np.ndarray:
    from quadmesh.families import family_members

    return next(m for m in family_members("glyphs_stix") if m.name == name).vertices


def test_glyph_faces_that_do_not_split_are_laid_out_on_their_own(tmp_path: Path, capsys) -> None:
    # STIX "2": no layout closes (the relaxed search leaves its foot's corner uncut); the face
    # there, laid out on its own by straight cuts, joins the cells: a block mesh of a few
    # hundred quads (22,576 by the paper's construction), no face left for the paper's
    # construction, every new angle in [60°, 120°] by the outsider's check on the file that
    # `quadmesh mesh --method blocks` wrote, which says how the faces were meshed
    glyph = _stix("STIXGeneral_2")
    res = mesh_polygon(glyph, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks is not None
    k = len(res.blocks.local_faces)
    assert k >= 1 and res.blocks.fallback_faces == ()
    assert np.all(res.quad_source == 4)
    assert res.mesh.n_quads < 1000
    src = tmp_path / "two_in.json"
    src.write_text(json.dumps({"vertices": glyph.tolist()}))
    out = tmp_path / "two.json"
    capsys.readouterr()
    assert cli_main(["mesh", str(src), "-o", str(out), "--method", "blocks"]) == 0
    said = capsys.readouterr().out
    assert f"faces that did not split with the others: {k} laid out on their own\n" in said
    assert "note:" not in said
    got = independent_check(out, glyph, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads


def test_a_face_falls_back_when_that_saves_quads_else_the_whole_glyph_does(
    monkeypatch, tmp_path: Path
) -> None:
    # STIX "4": no layout closes, and the face its cuts leave unsplit finds no layout of its
    # own; with that face meshed by the paper's construction the mesh has fewer quads than the
    # paper's construction on the whole glyph, and is kept.  STIX "2", as if its face found no
    # layout of its own either: the face's points carried along chords give more (26,355
    # against 22,576), so the whole glyph is meshed by the paper's construction and the result
    # says why.  (A longer relaxed search than the default:
    # it ends by running out of rounds, not of time, on a busy machine too.)
    import quadmesh.blocks as blocks

    monkeypatch.setattr(blocks, "RELAXED_SECONDS", 10.0)
    four = _stix("STIXGeneral_4")
    res = mesh_polygon(four, MeshOptions(method="blocks"))
    whole = mesh_polygon(four)
    assert res.fallback is None and res.blocks is not None
    assert len(res.blocks.fallback_faces) == 1
    assert 0 < res.blocks.fallback_quads < res.mesh.n_quads < whole.mesh.n_quads
    assert np.sum(res.quad_source != 4) == res.blocks.fallback_quads
    out = tmp_path / "four.json"
    write_mesh(out, res.mesh)
    # the face's quads are the paper's construction's: its exact 60° and 120° corners are
    # stored in float64 (the contract's fixed tolerance, not the blocks' 1e-9)
    from quadmesh.mesh import ANGLE_TOL_DEG

    got = independent_check(out, four, angle_tol=ANGLE_TOL_DEG)
    assert got["n_quads"] == res.mesh.n_quads
    monkeypatch.setattr(blocks, "_face_layout", lambda w, size, depth, deadline=None: None)
    two = mesh_polygon(_stix("STIXGeneral_2"), MeshOptions(method="blocks"))
    assert two.blocks is None and two.pieces
    assert "meshed by the paper's construction had" in two.fallback
    assert f"({two.mesh.n_quads:,})" in two.fallback


def test_what_the_integer_program_prints_natively_does_not_reach_the_output(capfd) -> None:
    # HiGHS 1.12 prints a debugging line on standard output whatever its options say; the
    # searches' solves run with descriptor 1 sent to the null device, and put it back after
    import os

    from quadmesh.blocks import _quiet_stdout

    with _quiet_stdout():
        os.write(1, b"HighsMipSolverData::transformNewIntegerFeasibleSolution\n")
    os.write(1, b"after\n")
    assert capfd.readouterr().out == "after\n"


def test_a_round_whose_face_meshes_leave_a_hanging_vertex_gives_way_to_the_next(
    monkeypatch,
) -> None:
    # the faces left to the paper's construction are meshed round by round (fewest first)
    # until the glued mesh passes the strict check: here the first round's mesh has a vertex
    # inside its neighbour's edge (as carried rows 1e-9 apart gave on cmr10 "W"), the second
    # round's is conforming and is the one returned
    from types import SimpleNamespace

    import quadmesh.blocks as blocks
    from quadmesh.blocks import PartialLayout, _fallback_faces

    z = np.array([0, 1, 1 + 1j, 1j], dtype=np.complex128)
    face = (np.arange(4),)
    rounds = [
        PartialLayout(z, z, face, frozenset({0}), np.zeros(4, bool), np.ones(4, bool))
        for _ in range(2)
    ]
    pts = np.array([0, 0.5, 1, 1 + 0.5j, 1 + 1j, 0.5 + 1j, 1j, 0.5 + 0.5j])
    hanging = np.array([[0, 1, 5, 6], [1, 2, 3, 7], [7, 3, 4, 5]])
    conforming = np.array([[0, 1, 5, 6], [1, 2, 4, 5]])
    meshes = iter([hanging, conforming])
    calls = []

    def fake_mesh(part, size, mesh_face=None, laid=None):
        calls.append(part)
        return pts, next(meshes), None, None

    monkeypatch.setattr(blocks, "_lay_out", lambda *a, **k: SimpleNamespace(rest=(face[0],)))
    monkeypatch.setattr(blocks, "_relaxed_partial", lambda z, partial, twins=False: None)
    monkeypatch.setattr(blocks, "mesh_partial_layout", fake_mesh)
    got = _fallback_faces(z, 0.5, rounds, mesh_face=lambda w: None)
    assert [c is r for c, r in zip(calls, rounds)] == [True, True]
    assert got is not None and np.array_equal(got[1], conforming)


def test_undersized_edges_are_those_below_a_quarter_of_size_and_feature_size() -> None:
    # a unit square in 2 × 2 cells whose bottom row is 0.01 high: its three vertical edges
    # there are 0.01 long where the size (0.5) and the local feature size (about 0.5 and more
    # at their midpoints) are far larger; every other edge is 0.5 or 0.99 long
    from quadmesh.blocks import undersized_edges
    from quadmesh.mesh import QuadMesh

    x, y = np.meshgrid([0.0, 0.5, 1.0], [0.0, 0.01, 1.0])
    pts = (x + 1j * y).ravel()
    g = np.arange(9).reshape(3, 3)
    quads = np.stack([g[:-1, :-1], g[:-1, 1:], g[1:, 1:], g[1:, :-1]], -1).reshape(-1, 4)
    mesh = QuadMesh.from_complex(pts, quads)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    small, n_edges, least = undersized_edges(mesh, square, 0.5)
    assert (small, n_edges) == (3, 12)
    assert least == pytest.approx(0.01 / 0.5)
    assert undersized_edges(mesh, square, 0.02)[0] == 0  # a size of 0.02: 0.01 is half of it


def test_cli_reports_undersized_edges_of_a_block_mesh(tmp_path: Path, capsys) -> None:
    # straight cuts give none (the L's smallest edge is 0.88 of the size); the spiral stroke's
    # round ends are vertex sectors whose graded points run along the whole ladder
    for name, share in (("l_shape", (0.0, 0.0)), ("stroke_spiral", (30.0, 50.0))):
        out = tmp_path / f"{name}.json"
        assert (
            cli_main(["mesh", str(example_file(name)), "-o", str(out), "--method", "blocks"]) == 0
        )
        line = next(s for s in capsys.readouterr().out.splitlines() if s.startswith("element"))
        pct = float(line.split("(")[1].split(" %")[0])
        assert share[0] <= pct <= share[1], line
        assert "shorter than 0.25 × the smaller of the size" in line


def test_a_layout_is_searched_for_more_than_120_cut_slots() -> None:
    """A 10 × 1 rectangle whose top is a shallow wavy line of 125 vertices (125 cut slots,
    more than the former limit of 120; Computer Modern "S" has 121 and "3" 144): the straight
    cuts close (126 blocks, one cut down from every top vertex), and ``mesh_polygon`` returns
    the block mesh with every angle in [60°, 120°] recomputed from the coordinates."""
    from quadmesh.blocks import MAX_SLOTS

    m = 125
    x = np.linspace(10, 0, m + 2)[1:-1]
    top = x + 1j * (1 + 0.05 * np.sin(np.pi * x / 10))
    z = np.r_[0, 10, 10 + 1j, top, 1j]
    assert m <= MAX_SLOTS
    assert len(block_layout(z, 0.5).cells) == m + 1
    poly = validate_polygon(np.column_stack([z.real, z.imag]))
    _assert_cut_layout_mesh(np.column_stack([z.real, z.imag]), poly)


def test_twin_cut_windows_split_a_corner_of_at_most_240_degrees_into_three_parts_in_range() -> None:
    """A corner of 181.5°–240° cut twice: every pair of directions from its two windows that
    are 60.5°–119.5° apart leaves three parts in [60.5°, 119.5°]; below 181.5° two cuts do not
    fit and the corner keeps its one window; above 240° the windows are those of before."""
    from quadmesh.blocks import _windows

    rng = np.random.default_rng(4)
    for theta in rng.uniform(181.6, 240.0, 200):
        (a0, a1), (b0, b1) = _windows(float(theta), twin=True)
        a = rng.uniform(a0, a1, 400)
        b = rng.uniform(b0, b1, 400)
        ok = (b - a >= 60.5) & (b - a <= 119.5)
        parts = np.stack([a, b - a, theta - b])[:, ok]
        assert ok.any()
        assert parts.min() >= 60.5 - 1e-9 and parts.max() <= 119.5 + 1e-9
    assert len(_windows(181.0, twin=True)) == 1
    assert _windows(250.0, twin=True) == _windows(250.0)


def test_a_corner_with_no_single_cut_is_cut_twice() -> None:
    """A chamfered staircase whose 239.3° corner has no single straight cut (both parts would
    be 119.65°, above the 119.5° a cut may leave): no layout without twin cuts; with them the
    corner's two cuts leave three parts in range, and ``mesh_polygon`` returns the block mesh
    with every angle in [60°, 120°] recomputed from the coordinates."""
    import quadmesh.blocks as qb

    z = np.array(
        [
            -0.007 - 0.007j,
            3.0014 + 0.0014j,
            2.9971 + 0.9971j,
            2.4544 + 1.0144j,
            2.0 + 1.2874j,
            2.0032 + 2.0032j,
            1.0095 + 2.0095j,
            0.997 + 2.997j,
            0.0144 + 3.0144j,
        ]
    )
    theta = qb._angles_deg(z)
    rays = qb._candidates(z, theta, qb._scale(z), [], frozenset(), frozenset())
    (corner,) = qb._twin_corners(theta, rays, frozenset())
    assert 239.0 < theta[corner] < 240.0
    may = qb._may_twin
    try:
        qb._may_twin = lambda th: False
        with pytest.raises(BlockLayoutError):
            block_layout(z)
    finally:
        qb._may_twin = may
    lay = block_layout(z)
    assert sum(corner in c for c in lay.cells.tolist()) == 3  # three parts: two cuts
    xy = np.column_stack([z.real, z.imag])
    _assert_cut_layout_mesh(xy, validate_polygon(xy))


def test_the_four_pointed_star_closes_by_twin_cuts() -> None:
    """The four-pointed star's 239.9° corners have no single cut (both parts would need
    119.95°); each is cut twice, and the star, which fell back to the paper's construction
    before, is a block mesh of a few dozen quads with every angle in [60°, 120°] recomputed
    from the coordinates (its 30.1° points kept whole in tip kites)."""
    res = mesh_polygon(FOUR_STAR, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks is not None and res.verification.ok
    assert res.mesh.n_quads < 100
    zz = res.mesh.z + res.mesh_origin
    ang = _corner_angles_deg(np.column_stack([zz.real, zz.imag]), res.mesh.quads)
    new = ang[ang > 31.0]  # the four tips' original 30.1° angles stay whole
    assert (ang <= 31.0).sum() == 4
    assert new.min() >= 60.0 - 1e-7 and new.max() <= 120.0 + 1e-7


@pytest.mark.parametrize("seed", range(6))
def test_conflict_cliques_cover_every_pair_and_keep_the_optimum(seed: int) -> None:
    """The conflict rows of the cut search are rows over sets of candidates that exclude each
    other (they conflict, or share a cut slot): every conflicting pair lies in some set, and
    the cheapest choice is the one the pairwise rows give (random instances: slots served by
    candidates of one or two slots, random conflicts, exact optimum)."""
    from itertools import combinations

    from quadmesh.blocks import _conflict_cliques, _Ray, _solve

    rng = np.random.default_rng(seed)
    n_slots = 12
    slots = [(i, 0) for i in range(n_slots)]
    rays = []
    for _ in range(60):
        own = [int(rng.integers(n_slots))]
        if rng.random() < 0.3:
            own.append(int(rng.integers(n_slots)))
        own = sorted(set(own))
        rays.append(_Ray(own[0], 1.0 + 0j, 0j, 0, 0.5, -1, [(i, 0) for i in own], rng.random()))
    pairs = [(a, b) for a, b in combinations(range(len(rays)), 2) if rng.random() < 0.15]
    cliques = _conflict_cliques(rays, pairs)
    adj = {(min(a, b), max(a, b)) for a, b in pairs}
    shared = {
        (a, b)
        for a, b in combinations(range(len(rays)), 2)
        if set(rays[a].slots) & set(rays[b].slots)
    }
    covered = {(min(a, b), max(a, b)) for c in cliques for a, b in combinations(c, 2)}
    assert adj <= covered  # every conflicting pair lies in a set
    assert covered <= adj | shared  # and a set holds only candidates that exclude each other
    cost = np.array([r.cost for r in rays])
    by_pairs = _solve(rays, slots, pairs, [], 30.0, rel_gap=0.0, cliques=[list(p) for p in pairs])
    by_cliques = _solve(rays, slots, pairs, [], 30.0, rel_gap=0.0, cliques=cliques)
    assert (by_pairs is None) == (by_cliques is None)
    if by_pairs is not None:
        assert cost[by_cliques].sum() == pytest.approx(cost[by_pairs].sum(), abs=1e-9)
        chosen = set(by_cliques)
        assert not any(a in chosen and b in chosen for a, b in pairs)


def test_round_polygons_skip_the_ladder_search() -> None:
    """The ladder (a corridor's cells) is not searched for on a polygon whose area is less
    than 2.5 times that of its largest inscribed disk; the elongation is the area ratio."""
    import math

    from quadmesh.blocks import LADDER_MIN_ELONGATION, _elongation

    t = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)
    disk = np.exp(1j * t)
    area = 32.0 * math.sin(2.0 * math.pi / 64)  # the 64-gon's; its inscribed disk: the apothem
    inscribed = math.pi * math.cos(math.pi / 64) ** 2
    assert _elongation(disk) == pytest.approx(area / inscribed, rel=1e-3)
    rect = np.array([0, 20, 20 + 1j, 1j], dtype=np.complex128)
    assert _elongation(rect) == pytest.approx(20.0 / (math.pi * 0.25), rel=2e-3)
    why: list[str] = []
    assert _ladder_mesh(disk, 0.1, why) is None
    assert "no corridor" in why[-1] and "%" in why[-1]
    assert _elongation(rect) > LADDER_MIN_ELONGATION > _elongation(disk)
