"""Corridors (thin parts whose walls are chains of short edges) meshed by ladders of straight
cells, checked from the outside: conformity, boundary, area and every new angle computed here in
plain float64 from the returned coordinates."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from quadmesh import mesh_polygon
from quadmesh.cells import cell_is_admissible
from quadmesh.examples import load_example
from quadmesh.polygon import validate_polygon
from quadmesh.thin.corridor import CELL_MARGIN, ladder_layout


def _stroke(centre: np.ndarray, width: float, cap: str = "flat") -> np.ndarray:
    """A pen stroke along a centreline (round joins), counter-clockwise."""
    g = shapely.LineString(centre).buffer(width / 2, cap_style=cap, join_style="round")
    g = shapely.geometry.polygon.orient(g, 1.0)
    return np.asarray(g.exterior.coords)[:-1]


def _s_centre(n: int = 60) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    return np.column_stack([3.0 * np.sin(2 * np.pi * t), 10.0 * t])


def _spiral_centre(turns: float = 2.5, n: int = 200) -> np.ndarray:
    t = np.linspace(0.5, turns, n) * 2 * np.pi
    r = 1.0 + 2.0 * t / (2 * np.pi)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def independent_check(poly_xy: np.ndarray, v: np.ndarray, q: np.ndarray, tol: float = 1e-9):
    """Plain-float64 check of a quad mesh of a CCW polygon: returns the new-angle range.

    Each interior edge in exactly two quads with opposite orientation; unpaired edges exactly
    subdivide the polygon's sides; quads convex and counter-clockwise; areas sum to the
    polygon's; every angle not at a polygon corner in [60°, 120°] within ``tol`` degrees."""
    z = v[:, 0] + 1j * v[:, 1]
    c = z[q] - z[q][:, :1]  # relative to each quad's first vertex
    e = np.roll(c, -1, axis=1) - c
    cross = (np.conj(e) * np.roll(e, -1, axis=1)).imag
    assert np.all(cross > 0), "a quad is not strictly convex and counter-clockwise"
    ang = np.degrees(np.angle(-np.roll(e, 1, axis=1) * np.conj(e)))
    ang = np.where(ang < 0, ang + 360, ang)
    pz = poly_xy[:, 0] + 1j * poly_xy[:, 1]
    corner = np.isin(z[q], pz)
    new = ang[~corner]
    assert new.min() >= 60 - tol and new.max() <= 120 + tol, (new.min(), new.max())
    # conformity
    he = np.stack([q, np.roll(q, -1, axis=1)], axis=-1).reshape(-1, 2)
    fwd = {tuple(x) for x in he.tolist()}
    assert len(fwd) == len(he), "a directed edge is used twice"
    boundary = [tuple(x) for x in he.tolist() if (x[1], x[0]) not in fwd]
    # every boundary edge lies on a polygon side, and they cover the perimeter exactly
    a, b = z[[x[0] for x in boundary]], z[[x[1] for x in boundary]]
    side = shapely.LineString(np.vstack([poly_xy, poly_xy[:1]]))
    mids = shapely.points(((a + b) / 2).real, ((a + b) / 2).imag)
    diam = np.ptp(pz.real) + np.ptp(pz.imag)
    assert np.all(shapely.distance(mids, side) < 1e-9 * diam)
    perim = np.abs(np.diff(np.r_[pz, pz[:1]])).sum()
    assert np.abs(b - a).sum() == pytest.approx(perim, rel=1e-9)
    area = 0.5 * np.sum((np.conj(c) * np.roll(c, -1, axis=1)).imag)
    poly_area = shapely.Polygon(poly_xy).area
    assert area == pytest.approx(poly_area, rel=1e-9)
    return float(new.min()), float(new.max())


@pytest.mark.parametrize(
    "name, centre, width",
    [("S", _s_centre(), 1.0), ("spiral", _spiral_centre(), 0.8), ("S thin", _s_centre(), 0.25)],
)
def test_flat_capped_strokes_mesh_as_corridors(name, centre, width):
    poly = _stroke(centre, width)
    r = mesh_polygon(poly)
    assert [t.kind for t in r.thin] == ["corridor"]
    assert r.pieces == ()  # no conformal map was needed
    v, q = r.mesh.vertices, r.mesh.quads
    lo, hi = independent_check(validate_polygon(poly).vertices, v, q)
    assert 60 <= lo and hi <= 120
    assert len(q) <= 20 * len(poly), len(q) / len(poly)


def test_glyph_s_is_a_corridor():
    """The bundled letter S crowds a disk map to 1.4e-13; as a corridor it needs no map and
    a few quads per polygon vertex (the disk construction spent ~985)."""
    poly = load_example("glyph_s")
    r = mesh_polygon(poly)
    assert [t.kind for t in r.thin] == ["corridor"]
    independent_check(validate_polygon(poly).vertices, r.mesh.vertices, r.mesh.quads)
    assert len(r.mesh.quads) <= 20 * len(poly)


def _ring(ni: int, no: int) -> np.ndarray:
    ti, to = np.linspace(0, np.pi / 2, ni), np.linspace(0, np.pi / 2, no)
    return np.concatenate([2 * np.exp(1j * to), np.exp(1j * ti)[::-1]])


@pytest.mark.parametrize("ni, no", [(10, 10), (10, 14), (20, 10), (60, 20), (7, 40)])
def test_ladder_cells_are_admissible_on_curved_walls(ni, no):
    """Walls with unrelated vertex spacings (reflex on one side, convex on the other): every
    cell of the ladder is a convex quadrilateral with corners in [60°, 120°] (with the layout's
    margin), and every polygon vertex is a cell vertex."""
    lay = ladder_layout(_ring(ni, no))
    corners = lay.vertices[lay.cells]
    assert np.all(cell_is_admissible(corners, margin_deg=CELL_MARGIN - 1e-9))
    assert set(range(ni + no)) <= set(lay.cells.ravel().tolist())


def test_ordinary_polygons_keep_the_paper_construction():
    """A polygon that does not crowd (an L-shape) is meshed by the disk construction."""
    r = mesh_polygon(load_example("l_shape"))
    assert len(r.pieces) == 1 and all(t.kind != "corridor" for t in r.thin)


@pytest.mark.parametrize(
    "name, centre, width", [("S", _s_centre(), 1.0), ("C", _s_centre()[:30], 0.5)]
)
def test_round_capped_strokes_mesh_as_corridors(name, centre, width):
    """Round ends are half-disk vertex sectors about the midpoint of their rung (Mesh 1 and full
    Mesh 2 levels, then the connection zone to the cap's vertices); both ends are built with the
    same point count and sector radius, so their points across the corridor agree."""
    poly = _stroke(centre, width, cap="round")
    r = mesh_polygon(poly)
    assert [t.kind for t in r.thin] == ["corridor"]
    lay = r.thin[0].mesh.layout
    assert len(lay.round_caps) == 2
    lo, hi = independent_check(validate_polygon(poly).vertices, r.mesh.vertices, r.mesh.quads)
    assert 60 - 1e-9 <= lo and hi <= 120 + 1e-9
    assert len(r.mesh.quads) <= 100 * len(poly), len(r.mesh.quads) / len(poly)


def _bent_stroke(turn_deg: float, quad_segs: int) -> np.ndarray:
    a = np.radians(turn_deg)
    centre = np.array([[0.0, 0.0], [4.0, 0.0], [4.0 + 4.0 * np.cos(a), 4.0 * np.sin(a)]])
    g = shapely.LineString(centre).buffer(
        0.5, cap_style="flat", join_style="round", quad_segs=quad_segs
    )
    return np.asarray(shapely.geometry.polygon.orient(g, 1.0).exterior.coords)[:-1]


@pytest.mark.parametrize("turn", [45.0, 60.0, 90.0])
@pytest.mark.parametrize("quad_segs", [4, 8])
def test_bends_are_vertex_sectors(turn, quad_segs):
    """A bend whose inner corner is too sharp for one crosscut (a 240°–270° reflex vertex facing
    a round outer corner) is a vertex sector about the inner corner between two crosscuts: its
    core is Mesh 1 + full Mesh 2 levels, joined to the outer wall by checked connection quads."""
    from quadmesh.thin.corridor import mesh_corridor

    poly = _bent_stroke(turn, quad_segs)
    cm = mesh_corridor(poly[:, 0] + 1j * poly[:, 1])
    assert len(cm.layout.sectors) == 1
    v = np.column_stack([cm.vertices.real, cm.vertices.imag])
    lo, hi = independent_check(validate_polygon(poly).vertices, v, cm.quads, tol=1e-7)
    assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7


@pytest.mark.parametrize("quad_segs", [4, 8])
def test_a_sharper_bend_is_a_sector_whose_rows_turn(quad_segs):
    """A 100° bend: seen from its inner corner the outer wall is far from round (the rungs end
    at the feet of the straight walls, the round corner lies 1.3 times as far), and straight
    connection quads from the sector's core leave [60°, 120°]; with ``turn=True`` the rows turn
    to meet the outer wall at right angles and the bend meshes."""
    from quadmesh.errors import ThinPartError
    from quadmesh.thin.corridor import mesh_corridor

    poly = _bent_stroke(100.0, quad_segs)
    z = poly[:, 0] + 1j * poly[:, 1]
    with pytest.raises(ThinPartError):
        ladder_layout(z)
    lay = ladder_layout(z, turn=True)
    assert lay.turn and len(lay.sectors) == 1
    cm = mesh_corridor(z, lay=lay)
    v = np.column_stack([cm.vertices.real, cm.vertices.imag])
    lo, hi = independent_check(validate_polygon(poly).vertices, v, cm.quads, tol=1e-7)
    assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7


@pytest.mark.parametrize(("turn", "quad_segs"), [(120.0, 8), (140.0, 4), (160.0, 8)])
def test_a_hairpin_is_a_round_bend_about_its_arc(turn, quad_segs):
    """Bends of 120°–160° (a hairpin): no sector about the inner corner has its connection
    quads in range, straight or turning, but the outer wall is a circular arc between two
    straight pieces: the bend is a sector about (or just beyond) the arc's centre and two
    convex cells from the inner corner, every corner in [60°, 120°]."""
    from quadmesh.errors import ThinPartError
    from quadmesh.thin.corridor import _round_bend, mesh_corridor

    poly = _bent_stroke(turn, quad_segs)
    z = poly[:, 0] + 1j * poly[:, 1]
    with pytest.raises(ThinPartError):
        ladder_layout(z)
    lay = ladder_layout(z, turn=True)
    assert len(lay.sectors) == 1
    apex, g = lay.sectors[0]
    hub = _round_bend(lay.vertices[apex], lay.vertices[list(g)])
    assert hub is not None
    # the arc's centre is the stroke's centreline corner (4, 0); the hub is on the bisector,
    # at most a fifth of the way to the inner corner beyond it
    assert abs(hub - 4.0) <= 0.2 * abs(lay.vertices[apex] - 4.0) + 1e-12
    cm = mesh_corridor(z, lay=lay)
    assert np.min(np.abs(cm.vertices - hub)) < 1e-12  # the sector's apex is a mesh vertex
    v = np.column_stack([cm.vertices.real, cm.vertices.imag])
    lo, hi = independent_check(validate_polygon(poly).vertices, v, cm.quads, tol=1e-7)
    assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7


@pytest.mark.parametrize("turn", [110.0, 130.0, 150.0])
def test_a_hand_drawn_hairpin_is_a_round_bend_about_a_hub_off_any_circle(turn):
    """A hairpin whose round join is drawn by hand (every vertex of the arc 4 % of its radius
    nearer or farther, so no circle holds them): the hub is found off the arc's centre (about
    its least-squares circle, or on the line from the inner corner to the arc), the ladder
    closes and passes the independent check. Before, such bends had no ladder: 0 of 45 such
    strokes (turns 110°, 130°, 150°; joins of 3, 5, 8 segments; 5 seeds), now 44."""
    from quadmesh.errors import ThinPartError
    from quadmesh.thin.corridor import _round_bend, mesh_corridor

    rng = np.random.default_rng(int(turn))
    for _ in range(2):
        poly = _bent_stroke(turn, 5)
        z = poly[:, 0] + 1j * poly[:, 1]
        on = np.abs(np.abs(z - 4.0) - 0.5) < 1e-9  # the join's arc (and its two tangent points)
        z[on] = 4.0 + (z[on] - 4.0) * (1.0 + 0.04 * rng.uniform(-1.0, 1.0, on.sum()))
        with pytest.raises(ThinPartError):
            ladder_layout(z)
        lay = ladder_layout(z, turn=True)
        bends = [
            h
            for a, g in lay.sectors
            if (h := _round_bend(lay.vertices[a], lay.vertices[list(g)])) is not None
        ]
        assert bends
        # no circle holds the arc: the vertices' distances from the hub differ by percents
        r = np.abs(z[on] - bends[0])
        assert r.max() - r.min() > 0.01 * r.mean()
        cm = mesh_corridor(z, lay=lay)
        poly_n = np.column_stack([z.real, z.imag])
        v = np.column_stack([cm.vertices.real, cm.vertices.imag])
        lo, hi = independent_check(validate_polygon(poly_n).vertices, v, cm.quads, tol=1e-7)
        assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7


def test_the_bend_search_stops_at_its_deadline_between_batches(monkeypatch):
    """The connection quads of candidate bends are checked in batches (one per number of far
    wall vertices between the rungs); on a round outline that is no corridor at all the
    batches are many and large (noisy_circle_1000: 103 batches, 49 s). The deadline is
    checked before every batch: here the first batch takes longer than the time allowed, and
    the search stops right after it instead of going through all of them (61 on the island
    outline)."""
    import sys
    import time

    from quadmesh.errors import ThinPartError
    from quadmesh.thin import corridor

    z = load_example("island")
    z = z[:, 0] + 1j * z[:, 1] if np.ndim(z) == 2 else np.asarray(z)
    calls = []
    original = corridor._connection_angles_many

    def slow(*args, **kwargs):
        if sys._getframe(1).f_code.co_name == "ladder_layout":  # a batch of bends (not a cap)
            calls.append(1)
            time.sleep(4.0)
        return original(*args, **kwargs)

    monkeypatch.setattr(corridor, "_connection_angles_many", slow)
    with pytest.raises(ThinPartError, match="time allowed"):
        # (3 s leave the set-up before the bends room on a busy machine; the batch takes 4)
        ladder_layout(z, deadline=time.perf_counter() + 3.0)
    assert len(calls) == 1


def test_a_round_bends_cells_are_cut_along_by_the_size_not_by_its_rows():
    """The two cells of a round bend carry the sector's side points (its core and every
    connection row the corridor's neighbours fix) across to the rungs; along the inner corner's
    line to the hub they are cut in segments of at most the size, as runs are, not as finely as
    those rows: with 30 rows a 140° hairpin's bend has a few hundred quads instead of thousands
    (a pen stroke's zigzag by blocks: 25,996 → 5,164 quads), every angle in range."""
    from quadmesh.geometry import quad_angles_deg
    from quadmesh.thin.corridor import _round_bend, _round_bend_mesh

    poly = _bent_stroke(140.0, 8)
    z = poly[:, 0] + 1j * poly[:, 1]
    lay = ladder_layout(z, turn=True)
    apex, g = lay.sectors[0]
    o, gv = lay.vertices[apex], lay.vertices[list(g)]
    hub = _round_bend(o, gv)
    f = np.linspace(0.0, 1.0, 32)[1:-1] ** 2  # 30 rows, graded towards the core
    size = 0.25
    fine = _round_bend_mesh(o, gv, hub, 16, None, (f, f))
    cut = _round_bend_mesh(o, gv, hub, 16, None, (f, f), size)
    for _gp, _ids, pts, quads, *_ in (fine, cut):
        a = quad_angles_deg(pts, quads)
        assert 60.0 - 1e-9 <= a.min() and a.max() <= 120.0 + 1e-9
    # the inner corner's line to the hub: in segments of at most the size
    pts = cut[2]
    on = pts[np.abs(((pts - o) / (hub - o)).imag) * abs(hub - o) < 1e-12]
    t = np.sort(((on - o) / (hub - o)).real)
    t = t[(t > -1e-12) & (t < 1 + 1e-12)]
    steps = np.diff(t) * abs(hub - o)
    assert steps.max() <= size + 1e-12
    assert t.size - 1 == int(np.ceil(abs(hub - o) / size))
    assert len(cut[3]) < 0.5 * len(fine[3])


def test_bent_strokes_of_any_turn_mesh_with_turning_rows_or_round_bends():
    """12 random pen strokes bent by 60°–170° (round joins of 2–9 segments, flat or round
    ends, widths 0.3–1.5): every ladder that is found, plain or with ``turn=True``, passes the
    independent check; plain ladders exist for 3, the turning rows and round bends add 8 (80
    such strokes, seed 7: plain 34, with them 75; none failing the check)."""
    from quadmesh.errors import ThinPartError
    from quadmesh.thin.corridor import mesh_corridor

    rng = np.random.default_rng(11)
    plain = turned = 0
    for _ in range(12):
        turn = rng.uniform(60.0, 170.0)
        segs, width = int(rng.integers(2, 10)), rng.uniform(0.3, 1.5)
        l1, l2 = rng.uniform(2.0, 6.0, 2)
        a = np.radians(turn)
        centre = np.array([[0.0, 0.0], [l1, 0.0], [l1 + l2 * np.cos(a), l2 * np.sin(a)]])
        cap = str(rng.choice(["flat", "round"]))
        g = shapely.LineString(centre).buffer(
            width / 2, cap_style=cap, join_style="round", quad_segs=segs
        )
        poly = np.asarray(shapely.geometry.polygon.orient(g, 1.0).exterior.coords)[:-1]
        z = poly[:, 0] + 1j * poly[:, 1]
        try:
            cm = mesh_corridor(z, lay=ladder_layout(z))
            plain += 1
        except ThinPartError:
            try:
                cm = mesh_corridor(z, lay=ladder_layout(z, turn=True))
                turned += 1
            except ThinPartError:
                continue
        v = np.column_stack([cm.vertices.real, cm.vertices.imag])
        lo, hi = independent_check(validate_polygon(poly).vertices, v, cm.quads, tol=1e-7)
        assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7
    assert turned >= 8 and plain + turned >= 11


def test_turned_rows_leave_the_core_radially_and_meet_the_crosscut_at_right_angles():
    """``_turned_rows``: on every spoke a curve from the core's point (leaving along the polar
    ray) to the crosscut point (arriving along the crosscut's normal, the bisector of its two
    chords), the two side spokes straight (their points stay on the rungs), and share 0 the
    plain straight rows."""
    from quadmesh.thin.corridor import _turned_rows

    rng = np.random.default_rng(3)
    apex = 0.5 - 0.2j
    ang = np.radians(np.sort(rng.uniform(0.0, 110.0, 9)))
    ang = np.r_[0.0, ang, np.radians(110.0)]
    gp = apex + rng.uniform(0.9, 1.4, ang.size) * np.exp(1j * ang)
    low = apex + 0.25 * np.exp(1j * np.linspace(0.0, np.radians(110.0), ang.size))
    s = np.array([[0.0] * ang.size, [1.0 - 1e-7] * ang.size, [1.0] * ang.size])
    rows = _turned_rows(apex, low, gp, s)
    assert np.allclose(rows[0], low, atol=1e-14) and np.allclose(rows[2], gp, atol=1e-14)
    arrive = (rows[2] - rows[1]) / np.abs(rows[2] - rows[1])
    ch = np.diff(gp) / np.abs(np.diff(gp))
    normal = -1j * (ch[:-1] + ch[1:])
    normal /= np.abs(normal)
    assert np.abs(arrive[1:-1] - normal).max() < 1e-5
    mid = _turned_rows(apex, low, gp, np.full((3, ang.size), [[0.2], [0.5], [0.8]]))
    for j in (0, -1):  # the sides: on the segment low–gp at the row's fraction
        f = np.array([0.2, 0.5, 0.8])
        assert np.allclose(mid[:, j], low[j] + f * (gp[j] - low[j]), atol=1e-14)
    assert (
        np.abs(mid[:, 1:-1] - (low + np.array([[0.2], [0.5], [0.8]]) * (gp - low))[:, 1:-1]).max()
        > 1e-3
    )
    flat = _turned_rows(apex, low, gp, np.full((1, ang.size), 0.5), share=0.0)
    assert np.allclose(flat[0], 0.5 * (low + gp), atol=1e-14)


def _tadpole(length: float) -> np.ndarray:
    """A disk (the head) with a long thin wavy tail: no corridor as a whole, and too crowded
    for one disk map (the tail is 20–40 widths long)."""
    t = np.linspace(0, 1, 80)
    c = np.column_stack([0.5 + length * t, 0.8 * np.sin(3 * np.pi * t)])
    tail = shapely.LineString(c).buffer(0.15, cap_style="flat", join_style="round")
    head = shapely.Point(0, 0).buffer(1.0, quad_segs=8)
    g = shapely.geometry.polygon.orient(shapely.union_all([head, tail]).simplify(0.005), 1.0)
    return np.asarray(g.exterior.coords)[:-1]


@pytest.mark.parametrize("length", [6.0, 12.0])
def test_an_arm_is_a_corridor_glued_to_the_body(length):
    """The tail is an arm: a ladder from its tip up to a rung short of the head; the head (with
    a stub of the tail) is meshed by the disk construction; the arm's last rung takes the head
    mesh's points on that cut, so the two share them by index."""
    poly = _tadpole(length)
    r = mesh_polygon(poly)
    kinds = [t.kind for t in r.thin]
    assert kinds.count("corridor") == 1 and len(r.pieces) >= 1
    arm = next(t for t in r.thin if t.kind == "corridor")
    assert arm.mesh.layout.open_end
    independent_check(validate_polygon(poly).vertices, r.mesh.vertices, r.mesh.quads, tol=1e-5)
    # the cut's points belong to both parts: arm quads and body quads meet there
    cut_ids = arm.global_index[arm.mesh.cut]
    body_quads = r.mesh.quads[np.asarray(r.quad_source) != 3]
    assert np.isin(cut_ids, body_quads).all()
    if length == 6.0:
        # transition cascades next to the cut take the body's ~150 points across down to the
        # arm's own count (measured: 9,464 arm quads; 20,150 carrying the cut's points along)
        assert len(arm.mesh.quads) < 12_000


def _zigzag_stroke(run: float) -> np.ndarray:
    """A stroke of width 1 turning left by 80°, then right by 80° after ``run`` widths: two bends
    whose inner corners lie on opposite walls, close together."""
    a = np.radians(80.0)
    p1 = np.array([4.0, 0.0])
    p2 = p1 + run * np.array([np.cos(a), np.sin(a)])
    p3 = p2 + np.array([4.0, 0.0])
    centre = np.array([[0.0, 0.0], p1, p2, p3])
    g = shapely.LineString(centre).buffer(0.5, cap_style="flat", join_style="round", quad_segs=8)
    return np.asarray(shapely.geometry.polygon.orient(g, 1.0).exterior.coords)[:-1]


@pytest.mark.parametrize("run", [0.6, 1.0, 2.0])
def test_bends_on_opposite_walls_share_their_cores(run):
    """Two bends on opposite walls a short run apart: each bend's core puts its points near its
    own wall, and the run between them cannot morph one set into the other in so short a
    distance. Both ends of the run carry the union of the two cores (each bend's connection
    rows put the other's points on its side), so the run's cells are plain bilinear grids."""
    from quadmesh.thin.corridor import _runs, mesh_corridor

    poly = _zigzag_stroke(run)
    cm = mesh_corridor(poly[:, 0] + 1j * poly[:, 1])
    lay = cm.layout
    assert len(lay.sectors) == 2
    v = np.column_stack([cm.vertices.real, cm.vertices.imag])
    lo, hi = independent_check(validate_polygon(poly).vertices, v, cm.quads, tol=1e-7)
    assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7
    # the run between the two bends: the same parameters across on both of its end rungs
    bend_rungs = [{k for k, (u, w) in enumerate(lay.rungs) if a in (u, w)} for a, _g in lay.sectors]
    between = next(
        r for r in _runs(lay) if {r[0], r[-1]} & bend_rungs[0] and {r[0], r[-1]} & bend_rungs[1]
    )
    V = lay.vertices

    def params(k: int) -> np.ndarray:
        a, b = lay.rungs[k]
        d = V[b] - V[a]
        t = ((cm.vertices - V[a]) / d).real
        off = np.abs(((cm.vertices - V[a]) * np.conj(d)).imag) / abs(d)
        return np.sort(t[(off < 1e-9 * abs(d)) & (t > -1e-12) & (t < 1 + 1e-12)])

    p0, p1 = params(int(between[0])), params(int(between[-1]))
    assert p0.size == p1.size and np.allclose(p0, p1, atol=1e-9)


def test_random_walks_mesh_as_corridors():
    """Buffered random walks (unit width, 10–60 widths long, round caps and joins) whose bends
    alternate between the walls mesh as one corridor; one whose ladder gets stuck (walk_2, at a
    241° kink) meshes as an arm glued to a body: the body's mesh puts an even number of points
    on the cut, and the arm's round end matches it with a sector of 2^k + 1 chords (2^k would
    put an odd number on every rung). walk_0, whose sharp bends have no ladder with straight
    rows, is one corridor by round bends and turned rows (10,820 quads in 1 s; by a bridge
    12,452 in 6.7 s before). Each mesh checked here."""
    from quadmesh.errors import QuadmeshError
    from quadmesh.families import family_members

    kinds = {}
    for m in family_members("walks")[:6]:
        try:
            res = mesh_polygon(m.vertices)
        except QuadmeshError:  # the family's known failures refuse cleanly
            continue
        zz = res.mesh.z + res.mesh_origin
        v = np.column_stack([zz.real, zz.imag])
        lo, hi = independent_check(
            validate_polygon(m.vertices).vertices, v, res.mesh.quads, tol=1e-7
        )
        assert 60 - 1e-7 <= lo and hi <= 120 + 1e-7
        kinds[m.name] = [t.kind for t in res.thin]
    whole = [k for k, v in kinds.items() if v == ["corridor"]]
    assert len(whole) >= 5  # walk_1, 3, 4, 5, and walk_0 by round bends (a bridge before)
    assert "walk_0" in whole
    assert "walk_2" in kinds and "corridor" in kinds["walk_2"]  # the arm and its body


@pytest.mark.parametrize("n_pts", [17, 18, 33, 34])
def test_a_round_end_with_an_odd_number_of_chords_puts_an_even_count_on_its_rung(n_pts):
    """A half-disk sector's core (Mesh 1 and Mesh 2 levels) with 2^k chords has equal sides: its
    rung (both sides, the centre shared) carries an odd number of points, and so does every rung
    a strip of cells reaches. With 2^k + 1 chords one level refines one chord more: the sides
    differ by one point and the count is even, which an arm needs when the body behind it puts
    an even number of points on the cut. Every angle of the core stays in [60°, 120°]."""
    from quadmesh.thin.corridor import _sector_core

    v, q, outer, s1, s2 = _sector_core(180.0, n_pts)
    assert outer.size == n_pts
    rung = s1.size + s2.size - 1
    assert rung % 2 == (1 if (n_pts - 1) % 2 == 0 else 0)
    c = v[q] - v[q][:, :1]
    e = np.roll(c, -1, axis=1) - c
    ang = np.degrees(np.angle(-np.roll(e, 1, axis=1) * np.conj(e)))
    ang = np.where(ang < 0, ang + 360, ang)
    assert ang.min() >= 60 - 1e-7 and ang.max() <= 120 + 1e-7


def test_connection_angles_without_the_core_match_the_built_sector():
    """The layout search checks every candidate round end and bend by the angles of its
    connection quads; it computes them from the core's outer arc alone (an even arc of radius
    CAP_CORE for 2^k + 1 points), without building the core. They agree with the built
    sector's to 1e-9° on random sectors of 60°–230° with 2–11 chords of crosscut."""
    from quadmesh.thin.corridor import _connection_angles, _sector_mesh

    rng = np.random.default_rng(5)
    compared = 0
    for _ in range(120):
        th = rng.uniform(60.0, 230.0)
        m = int(rng.integers(2, 12))
        ang = np.r_[0.0, np.sort(rng.uniform(0.0, np.radians(th), m)), np.radians(th)]
        if np.diff(ang).max() > np.radians(170.0):
            continue  # chords seen under less than 180° from the apex only
        apex = 3.0 + 1.0j
        g = apex + 2.0 * rng.uniform(0.8, 1.2, ang.size) * np.exp(1j * (ang + 0.3))
        for n_pts in (9, 17):
            if ang.size - 1 > n_pts - 1:
                continue
            a = _sector_mesh(apex, g, n_pts)[4]
            b = _connection_angles(apex, g, n_pts)
            assert np.abs(a - b).max() < 1e-9
            compared += 1
    assert compared > 150


def test_connection_angles_of_many_sectors_at_once_match_the_built_sectors():
    """The layout search checks all candidate bends of a corridor in batches of equal shape
    (``_connection_angles_many``): each row agrees with the sector built alone to 1e-9°, and
    exactly the rows whose crosscut turns back (a polar angle not increasing) are refused."""
    from quadmesh.errors import ThinPartError
    from quadmesh.thin.corridor import _connection_angles_many, _crosscut_points, _sector_mesh

    rng = np.random.default_rng(8)
    for chords, n_pts in ((3, 9), (6, 17), (5, 9)):
        m = 40
        th = rng.uniform(60.0, 200.0, m)
        ang = np.sort(rng.uniform(0.0, 1.0, (m, chords + 1)), axis=1)
        ang = np.radians(th)[:, None] * (ang - ang[:, :1]) / (ang[:, -1:] - ang[:, :1])
        ang[:5, 2] = ang[:5, 1] - 0.05  # turns back: refused
        apex = rng.normal(size=m) + 1j * rng.normal(size=m)
        g = apex[:, None] + rng.uniform(0.8, 1.2, ang.shape) * np.exp(1j * (ang + 0.3))
        a, ok = _connection_angles_many(apex, g, n_pts, rows=16)
        for r in range(m):
            try:
                _crosscut_points(apex[r], g[r], n_pts)
            except ThinPartError:
                assert not ok[r]
                continue
            assert ok[r]
            assert np.abs(a[r] - _sector_mesh(apex[r], g[r], n_pts)[4]).max() < 1e-9
        assert ok.sum() >= m - 5


@pytest.mark.parametrize("parts", [2, 4])
@pytest.mark.parametrize("ni, no", [(10, 14), (60, 20), (7, 40)])
def test_ladder_cells_cut_along_their_length_stay_admissible(ni, no, parts):
    """Every ladder cell cut into ``parts`` cells at the fractions j/parts of its walls (a
    bridge's cells, when the two meshes' points do not join otherwise): the sub-cells tile
    each cell, keep their corners in [60°, 120°] (with the layout's margin, as the cells they
    come from), the new rung ends lie on the polygon edge ``edge_of`` names, and rungs and
    cells stay in order along the ladder (each ladder cell between consecutive rungs)."""
    from quadmesh.geometry import quad_signed_areas
    from quadmesh.thin.corridor import split_ladder_cells

    z = _ring(ni, no)
    lay = ladder_layout(z)
    out = split_ladder_cells(lay, z, parts)
    n_ladder = lay.kind.count("ladder")
    assert len(out.rungs) == len(lay.rungs) + (parts - 1) * n_ladder
    assert len(out.cells) == len(lay.cells) + (parts - 1) * n_ladder
    corners = out.vertices[out.cells]
    assert np.all(cell_is_admissible(corners, margin_deg=CELL_MARGIN - 1e-9))
    before = quad_signed_areas(lay.vertices, lay.cells).sum()
    assert quad_signed_areas(out.vertices, out.cells).sum() == pytest.approx(before, rel=1e-12)
    new = np.arange(lay.vertices.size, out.vertices.size)
    e = np.roll(z, -1) - z
    k = out.edge_of[new]
    t = ((out.vertices[new] - z[k]) / e[k]).real
    assert np.all((t > 0) & (t < 1))
    assert np.all(np.abs(z[k] + t * e[k] - out.vertices[new]) < 1e-12)
    for kind, (k0, k1) in zip(out.kind, out.cell_rungs, strict=True):
        if kind == "ladder":
            assert k1 == k0 + 1


def test_a_bridge_whose_single_cell_run_cannot_join_its_meshes_is_cut_along_its_length():
    """STIX "m": every bridge across its stems ends on meshes with 170–218 points on the cut
    and 24–149 on the far rung; the one with an even difference (170 against 136) joined no
    better than the others in whole cells (the morph to the far mesh's spacing had too short a
    cell: angles of 49.8°). With the bridge's cells cut in two the cascades and the morph get
    room: the glyph meshes (refused before), checked from outside."""
    pytest.importorskip("matplotlib")
    from quadmesh.families import glyph_outline

    xy = glyph_outline("m", "STIXGeneral")
    r = mesh_polygon(xy)
    assert any(t.kind == "corridor" and t.mesh.start is not None for t in r.thin)  # a bridge
    lo, hi = independent_check(validate_polygon(xy).vertices, r.mesh.vertices, r.mesh.quads, 1e-5)
    assert lo >= 60 - 1e-5 and hi <= 120 + 1e-5


def _c_with_blobs() -> np.ndarray:
    """A C-shaped stroke (width 0.8, radius 4) with a round blob at each end."""
    t = np.linspace(0.15, 0.85, 60) * 2 * np.pi
    centre = np.column_stack([4 * np.cos(t), 4 * np.sin(t)])
    g = shapely.LineString(centre).buffer(0.4, cap_style="flat", join_style="round")
    for p in (centre[0], centre[-1]):
        g = g.union(shapely.Point(p).buffer(1.0, quad_segs=8))
    g = shapely.geometry.polygon.orient(shapely.simplify(g, 1e-4), 1.0)
    return validate_polygon(np.asarray(g.exterior.coords)[:-1], drop_collinear=True).z


def test_bridge_cuts_split_a_corridor_in_its_middle_and_a_ladder_leaves_the_cut():
    """A C-shaped stroke with a round blob at each end: the cuts cross the stroke inside it at
    angles in [60°, 120°] (with the cells' margin) on both walls; the two sides tile the
    polygon; a ladder started from a virtual cap beyond the cut has the cut as its first rung,
    and shortening it moves the far body's cut back rung by rung (the body growing by the cells
    given up)."""
    from quadmesh.thin.corridor import bridge_cuts, bridge_layout, shorter_bridges

    z = _c_with_blobs()
    cuts = bridge_cuts(z)
    assert cuts
    area = shapely.Polygon(np.column_stack([z.real, z.imag])).area
    for c in cuts:
        e = np.roll(z, -1) - z
        ang = np.degrees(np.angle(np.array([e[c.ia] / (c.b - c.a), e[c.ib] / (c.a - c.b)]))) % 180
        assert np.all((ang >= 60 + CELL_MARGIN - 1e-9) & (ang <= 120 - CELL_MARGIN + 1e-9))
        parts = [shapely.Polygon(np.column_stack([w.real, w.imag])) for w in (c.first, c.second)]
        assert all(p.is_valid and p.area > 0 for p in parts)
        assert sum(p.area for p in parts) == pytest.approx(area, rel=1e-12)
    c = cuts[0]
    got = bridge_layout(c.second) or bridge_layout(c.first)
    assert got is not None
    lay, q, body = got
    assert lay.kind[0] == "cap" and set(lay.rungs[0].tolist()) == {0, q.size - 3}
    assert body is not None  # the blob stops the ladder
    if True:
        shorter = shorter_bridges(lay, q)
        assert [len(s.rungs) for s, _ in shorter] == [
            len(lay.rungs) - k for k in range(1, len(shorter) + 1)
        ]
        areas = [shapely.Polygon(np.column_stack([b.real, b.imag])).area for _, b in shorter]
        assert np.all(
            np.diff([shapely.Polygon(np.column_stack([body.real, body.imag])).area, *areas]) > 0
        )


def test_arm_tips_start_nearest_the_crowded_place():
    """A comb of three teeth (wavy walls, so no channel is cut): the crowded place is at a
    tooth's tip, the arm tips are the ears nearest it, each paired with the far end of the
    longest path from it."""
    from quadmesh.decompose import decompose
    from quadmesh.thin.corridor import arm_tips, crowded_place

    t = np.linspace(0, 1, 40)
    base = shapely.box(0, 0, 12, 3)
    teeth = [
        shapely.LineString(
            np.column_stack([x + 0.5 * np.sin(3 * np.pi * t), 2.5 + 9.5 * t])
        ).buffer(0.4, cap_style="flat", join_style="round", quad_segs=4)
        for x in (2.0, 6.0, 10.0)
    ]
    g = shapely.union_all([base, *teeth])
    g = shapely.geometry.polygon.orient(shapely.simplify(g, 1e-3), 1.0)
    z = validate_polygon(np.asarray(g.exterior.coords)[:-1], drop_collinear=True).z
    place = crowded_place(decompose(np.column_stack([z.real, z.imag])))
    assert place is not None and place.imag > 8.0  # deep in a tooth
    tips = arm_tips(z, place, count=3)
    assert len(tips) == 3
    d = [abs(z[s] - place) for s, _ in tips]
    assert d == sorted(d) and all(s != e for s, e in tips)
    assert abs(z[tips[0][0]] - place) < 1.0


def test_with_blocks_and_no_layout_the_arms_body_is_meshed_by_the_papers_construction(
    monkeypatch,
) -> None:
    """``method="blocks"`` without a layout falls back to the paper's construction, and so do
    the parts it cuts off (an arm's body, a bridge's sides): blocks are searched once, for the
    user's polygon, and the mesh is the one ``method="bishop"`` makes (before, the parts were
    searched for layouts again, and the STIX "G", whose bridge sides then carried layouts'
    points, was refused)."""
    import quadmesh.blocks as blocks
    from quadmesh import MeshOptions

    calls = []

    def no_layout(polygon, size=None, mesh_face=None):
        calls.append(len(polygon))
        raise blocks.BlockLayoutError("no layout (test)")

    monkeypatch.setattr(blocks, "mesh_blocks", no_layout)
    poly = _tadpole(6.0)
    r = mesh_polygon(poly, MeshOptions(method="blocks"))
    assert len(calls) == 1 and r.fallback is not None and r.options.method == "blocks"
    assert [t.kind for t in r.thin].count("corridor") == 1  # the arm
    ref = mesh_polygon(poly)
    assert np.array_equal(r.mesh.quads, ref.mesh.quads)
    assert np.array_equal(r.mesh.vertices, ref.mesh.vertices)


def _check_part_mesh(v: np.ndarray, quads: np.ndarray, q: np.ndarray) -> None:
    """Convex counter-clockwise quads, every angle away from the corners of the part ``q`` in
    [60°, 120°] (plain float64, relative to each quad's first vertex), no edge in more than
    two quads."""
    p = v[quads] - v[quads][:, :1]
    e = np.roll(p, -1, axis=1) - p
    assert np.all((np.conj(e) * np.roll(e, -1, axis=1)).imag > 0)
    ang = np.degrees(np.angle(-np.roll(e, 1, axis=1) * np.conj(e))) % 360.0
    corner = np.isin(v[quads], q)
    assert ang[~corner].min() >= 60 - 1e-9 and ang[~corner].max() <= 120 + 1e-9
    he = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    _, cnt = np.unique(he, axis=0, return_counts=True)
    assert cnt.max() == 2


def _join_on_the_c_bridge(p_start: np.ndarray, p_end: np.ndarray) -> None:
    """Mesh the bridge of the C stroke with ``_c_with_blobs``'s bridge layout, its first rung
    carrying points at the parameters ``p_start`` (0 … 1 along it), its last rung at
    ``p_end``, and check it from outside: both rungs carry exactly those points, then
    :func:`_check_part_mesh`."""
    from quadmesh.thin.corridor import bridge_cuts, bridge_layout, mesh_arm

    z = _c_with_blobs()
    c = bridge_cuts(z)[0]
    lay, q, body = bridge_layout(c.second) or bridge_layout(c.first)
    assert body is not None

    def on_rung(k: int, p: np.ndarray) -> np.ndarray:
        a, b = lay.vertices[lay.rungs[k]]
        return a + p * (b - a)

    start, end = on_rung(0, p_start), on_rung(len(lay.rungs) - 1, p_end)
    cm = mesh_arm(lay, q, end, start_points=start)
    v, quads = cm.vertices, cm.quads
    assert np.allclose(np.sort_complex(v[cm.start]), np.sort_complex(start), atol=1e-12)
    assert np.allclose(np.sort_complex(v[cm.cut]), np.sort_complex(end), atol=1e-12)
    _check_part_mesh(v, quads, q)


@pytest.mark.parametrize(("n_start", "n_end"), [(41, 28), (28, 41), (33, 32)])
def test_a_bridge_joins_point_counts_of_odd_difference(n_start, n_end):
    """A bridge between two meshes whose cuts carry counts differing by an odd number (a quad
    mesh of a disk has an even number of boundary edges, so the pairs of split rows alone
    cannot join them): a cascade starting with a parity row, one wall one point longer. The
    bridge's mesh — the C-shaped stroke of the test above, its first rung carrying ``n_start``
    points graded towards one wall, its last rung ``n_end`` — is checked from outside:
    convex counter-clockwise quads, every angle in [60°, 120°] away from polygon corners,
    conformity, and both rungs carrying exactly the given points."""
    _join_on_the_c_bridge(
        np.linspace(0.0, 1.0, n_start) ** 1.2, np.linspace(0.0, 1.0, n_end) ** 1.2
    )


def test_a_bridge_joins_irregular_points_of_odd_difference():
    """The cuts' points as a mesh leaves them: graded towards both walls and jumping by up to
    6× between neighbours, 61 on one rung and 60 on the other. The parity row sits at a wall,
    a few of the wall row's gaps long; it is built beside the rows as they are when evening
    them out within so short a slice would fold it. Checked from outside as above."""
    rng = np.random.default_rng(0)

    def irregular(n: int) -> np.ndarray:
        i = np.arange(n - 1)
        h = (1.0 + np.minimum(i, n - 2 - i) / 5.0) * rng.uniform(1.0, 6.0, n - 1)
        return np.r_[0.0, np.cumsum(h)[:-1] / h.sum(), 1.0]

    p_start = irregular(61)
    _join_on_the_c_bridge(p_start, irregular(60))


def test_restart_cuts_cross_the_corridor_beyond_the_rung_a_ladder_stopped_at():
    """A straight strip 20 widths long whose last edge (x = 0) is the rung a ladder stopped
    at, its lower wall ragged (teeth a fifth of the width high): the restart cuts lie at about
    the asked distances along it, straight across (perpendicular to the strip within a few
    degrees), between the two walls at angles in [60°, 120°]; the knot holds the stopping rung
    and ends at the cut, the rest begins there, and the two tile the polygon."""
    from quadmesh.thin.corridor import restart_cuts

    x = np.arange(0.25, 20.0, 0.5)  # teeth 0.2 wide between flat stretches
    low = np.column_stack(
        [np.repeat(x, 3) + np.tile([-0.1, 0.0, 0.1], x.size), np.tile([0.0, 0.2, 0.0], x.size)]
    )
    xy = np.vstack([[0.0, 0.0], low, [20.0, 0.0], [20.0, 1.0], [0.0, 1.0]])
    z = validate_polygon(xy).z
    assert z[0] == 0 and z[-1] == 1j  # the stopping rung is the last edge
    cuts = restart_cuts(z, (2.0, 3.0, 5.0, 8.0))
    assert len(cuts) >= 3
    area = shapely.Polygon(np.column_stack([z.real, z.imag])).area
    for rc in cuts:
        a, b = rc.cut.a, rc.cut.b
        mid = 0.5 * (a + b)
        assert abs(mid.real - rc.distance) < 0.6  # along the strip, from the rung's middle
        tilt = np.degrees(np.angle((b - a) / 1j)) % 180.0
        assert min(tilt, 180.0 - tilt) < 5.0  # straight across
        knot = shapely.Polygon(np.column_stack([rc.knot.real, rc.knot.imag]))
        rest = shapely.Polygon(np.column_stack([rc.rest.real, rc.rest.imag]))
        assert knot.is_valid and rest.is_valid
        assert knot.area + rest.area == pytest.approx(area, rel=1e-12)
        assert 0j in rc.knot and 1j in rc.knot
        assert {rc.rest[-1], rc.rest[0]} == {a, b} and {rc.knot[-1], rc.knot[0]} == {a, b}


def test_a_chain_restarts_the_ladder_past_where_it_gets_stuck():
    """A short river with ragged banks (200 vertices, 20 widths long): the ladder from one end
    stops after 10 rungs; a knot of a few widths, meshed by the paper's construction, and a
    ladder restarted beyond it carry on to the far end. The chain's mesh — two ladders glued
    to the knot by index — is checked from outside: convex counter-clockwise quads, every new
    angle in [60°, 120°], conformity, the boundary exactly the river's, the area exact."""
    from types import SimpleNamespace

    from quadmesh.families import river
    from quadmesh.progress import running
    from quadmesh.result import MeshOptions
    from quadmesh.routes import _mesh_chain

    m = river(np.random.default_rng([8, 99]), n_vertices=200, ratio=20)
    poly = validate_polygon(m.vertices)
    seen: list[tuple[str, float]] = []
    with running(lambda stage, f: seen.append((stage, f)), None) as run:
        run.enter("corridor", 0.1)
        got = _mesh_chain(SimpleNamespace(polygon=poly), MeshOptions(), None)
    assert got is not None
    # the progress bar moves as knots are meshed, under the chain's own name
    chain = [f for stage, f in seen if stage == "chain of ladders"]
    assert len(set(chain)) >= 2 and chain == sorted(chain) and 0.1 <= chain[0] < chain[-1] <= 0.88
    asm, _pieces, thin, _dec = got
    assert sum(t.kind == "corridor" for t in thin) >= 2
    quads, _src = asm.all_quads()
    z = asm.vertices()
    lo, hi = independent_check(poly.vertices, np.column_stack([z.real, z.imag]), quads, 1e-5)
    assert lo >= 60 - 1e-5 and hi <= 120 + 1e-5


def test_a_tip_no_ladder_leaves_is_cut_off_as_a_knot():
    """A horse's hind leg traced from scikit-image's "horse" (its walls alternate 166° and 194°
    every pixel; the hoof is a blunt, stepped end) under a rectangular body: no ladder leaves
    the hoof, so no arm starts there. The knotted arm cuts the hoof off a few widths up the
    leg (a knot of at most 80 vertices, meshed by the paper's construction), runs a ladder from
    that cut up the leg and meshes the body behind it; the three meshes share their points on
    the two cuts by index. Checked from outside: convex counter-clockwise quads, every new
    angle in [60°, 120°], conformity, the boundary exactly the polygon's, the area exact."""
    from types import SimpleNamespace

    from quadmesh.errors import ThinPartError
    from quadmesh.families import images
    from quadmesh.result import MeshOptions
    from quadmesh.routes import KNOT_MAX_VERTICES, _mesh_knotted_arm
    from quadmesh.thin.corridor import tip_cuts

    horse = next(m for m in images(0) if m.name == "horse_0").vertices
    leg = horse[491:570, 0] + 1j * horse[491:570, 1]  # down, round the hoof, up (y down)
    w = np.r_[leg, 110 - 228j, 110 - 180j, 30 - 180j, 30 - 222j]
    poly = validate_polygon(np.column_stack([w.real, w.imag]))
    assert np.array_equal(poly.z, w)
    hoof = 47  # (75.18, -311): the ear of the dual tree nearest the hoof's toe
    with pytest.raises(ThinPartError, match="at the end near"):
        ladder_layout(poly.z, (hoof, 82), partial=True)
    cuts = tip_cuts(poly.z, hoof)
    assert cuts and all(rc.knot.size <= KNOT_MAX_VERTICES for rc in cuts)
    assert all(poly.z[hoof] in rc.knot and poly.z[hoof] not in rc.rest for rc in cuts)
    got = _mesh_knotted_arm(
        SimpleNamespace(polygon=poly), MeshOptions(), None, None, complex(75.3, -310.5)
    )
    assert got is not None
    asm, pieces, thin, _dec = got
    assert [t.kind for t in thin].count("corridor") == 1 and pieces
    quads, src = asm.all_quads()
    assert set(np.unique(src)) >= {3}  # the ladder's quads among the two meshes'
    z = asm.vertices()
    lo, hi = independent_check(poly.vertices, np.column_stack([z.real, z.imag]), quads, 1e-5)
    assert lo >= 60 - 1e-5 and hi <= 120 + 1e-5


def test_a_chain_whose_tips_no_ladder_leaves_starts_with_a_knot():
    """Two horse's legs joined at the top, hoof to hoof (156 vertices, both ends blunt and
    stepped): no arm leaves either tip, so a chain cannot start with one. It starts with a
    knot instead: a hoof cut off a few widths up (at most a third of the polygon, meshed by the
    paper's construction), a ladder from that cut up the legs, and the rest behind it meshed
    as one part. Checked from outside: convex counter-clockwise quads, every new angle in
    [60°, 120°], conformity, the boundary exactly the polygon's, the area exact."""
    from types import SimpleNamespace

    from quadmesh.families import images
    from quadmesh.result import MeshOptions
    from quadmesh.routes import CHAIN_KNOT_SHARE, _mesh_chain
    from quadmesh.thin.corridor import arm_and_body, corridor_tips

    horse = next(m for m in images(0) if m.name == "horse_0").vertices
    leg = horse[491:570, 0] + 1j * horse[491:570, 1]  # down, round the hoof, up (y down)
    top = (leg[0] + leg[-1]) / 2
    w = np.r_[leg, 2 * top - leg[1:-1]]  # the leg turned half round about its top's middle
    poly = validate_polygon(np.column_stack([w.real, w.imag]))
    assert np.array_equal(poly.z, w)
    hooves = {47, 125}
    assert set(corridor_tips(poly.z)) == hooves
    assert arm_and_body(poly.z) is None
    got = _mesh_chain(SimpleNamespace(polygon=poly), MeshOptions(), None)
    assert got is not None
    asm, pieces, thin, dec = got
    assert pieces and [t.kind for t in thin].count("corridor") >= 1
    # the first knot is a hoof's end, at most a third of the polygon
    knot = dec.polygon.z
    assert knot.size <= poly.n // CHAIN_KNOT_SHARE + 2
    assert any(np.any(np.isclose(knot, poly.z[h], rtol=0, atol=1e-9)) for h in hooves)
    quads, src = asm.all_quads()
    assert set(np.unique(src)) >= {3}
    z = asm.vertices()
    lo, hi = independent_check(poly.vertices, np.column_stack([z.real, z.imag]), quads, 1e-5)
    assert lo >= 60 - 1e-5 and hi <= 120 + 1e-5


def test_a_morph_between_two_rungs_tilts_rows_where_the_cells_have_room():
    """A run of ladder cells between two rungs whose points are fixed (same count, different
    spacing) moves its rows from one spacing to the other along the run. Two of its cells
    have corners of 61° and 119° (a slanted rung), the others are rectangles: spread evenly
    by length the change tilts the slanted cells' rows out of [60°, 120°]; spread by what
    each cell can take (its length times the tangent of its corners' distance from 60° and
    120°) every angle stays in range."""
    from quadmesh.thin.corridor import CorridorLayout, _run_params

    slant = 1.0 / np.tan(np.radians(61.0))
    xs_lo = np.array([0.0, 1.0, 2.0, 3.0, 5.0, 6.0, 7.0])
    xs_hi = xs_lo + np.where(np.arange(7) == 3, slant, 0.0)
    V = np.r_[xs_lo, xs_hi + 1j].astype(np.complex128)
    nr = xs_lo.size
    rungs = np.stack([np.arange(nr), nr + np.arange(nr)], axis=1)
    cells = np.stack([rungs[:-1, 0], rungs[1:, 0], rungs[1:, 1], rungs[:-1, 1]], axis=1)
    lay = CorridorLayout(
        vertices=V,
        cells=cells,
        kind=("ladder",) * (nr - 1),
        rungs=rungs,
        tips=(0, nr - 1),
        edge_of=np.full(V.size, -1),
        cell_rungs=np.stack([np.arange(nr - 1), np.arange(1, nr)], axis=1),
    )
    fixed = {0: np.linspace(0.0, 1.0, 21), nr - 1: np.linspace(0.0, 1.0, 21) ** 0.6}

    def angles(params: list[np.ndarray]) -> np.ndarray:
        pts = np.stack([V[a] + p * (V[b] - V[a]) for (a, b), p in zip(rungs, params)])
        q = np.stack([pts[:-1, :-1], pts[1:, :-1], pts[1:, 1:], pts[:-1, 1:]], axis=-1)
        e = np.roll(q, -1, axis=-1) - q
        return np.degrees(np.angle(-np.roll(e, 1, axis=-1) * np.conj(e))) % 360.0

    by_length = angles(_run_params(lay, 0.05, dict(fixed)))
    assert by_length.min() < 60.0 - 0.1 or by_length.max() > 120.0 + 0.1
    by_room = angles(_run_params(lay, 0.05, dict(fixed), tilt=True))
    assert by_room.min() >= 60.0 - 1e-9 and by_room.max() <= 120.0 + 1e-9
    assert np.all(by_room[[0, 1, 4, 5]].max(axis=(1, 2)) < 110.0)  # the rectangles carry it


def test_wall_ray_casts_find_the_first_boundary_point_as_geos_does():
    """The ladder's ray casts (an STR tree of the edges, short rays first) give, for rays from
    inside and from the walls of a ragged river and a spiky star, in random directions, the same
    first boundary point as GEOS's intersection of the full ray with the whole ring (the
    nearest intersection point to the ray's start), and no hit exactly where GEOS finds none;
    the edge reported holds that point."""
    from quadmesh.families import river
    from quadmesh.thin.corridor import _Walls

    rng = np.random.default_rng(5)
    m = river(np.random.default_rng([8, 99]), n_vertices=300, ratio=20)
    rv = m.vertices[:, 0] + 1j * m.vertices[:, 1]
    k = np.arange(40)
    star = (1 + 0.6 * (k % 2)) * np.exp(2j * np.pi * k / 40)
    for z in (rv, star):
        diam = float(np.ptp(z.real) + np.ptp(z.imag))
        walls = _Walls(z)
        ring = shapely.LinearRing(np.column_stack([z.real, z.imag]))
        # starts: random points inside, and the midpoints of the edges (rays from a wall)
        bx = rng.uniform(z.real.min(), z.real.max(), 400)
        by = rng.uniform(z.imag.min(), z.imag.max(), 400)
        keep = shapely.contains_xy(shapely.Polygon(ring), bx, by)
        mids = 0.5 * (z + np.roll(z, -1))
        pts = np.r_[bx[keep] + 1j * by[keep], mids + 1e-9 * diam * 1j * (np.roll(z, -1) - z)]
        u = np.exp(2j * np.pi * rng.uniform(size=pts.size))
        near = 0.05 * diam
        dist, edge = walls.first_hits(pts, u, diam, near)
        p1 = pts + diam * u
        rays = shapely.linestrings(
            np.stack(
                [np.column_stack([pts.real, pts.imag]), np.column_stack([p1.real, p1.imag])], 1
            )
        )
        hit = shapely.intersection(rays, ring)
        geos = shapely.distance(shapely.points(pts.real, pts.imag), hit)
        found = ~shapely.is_empty(hit)
        assert np.array_equal(np.isfinite(dist), found)
        assert np.allclose(dist[found], geos[found], rtol=0, atol=1e-12 * diam)
        q = pts[found] + dist[found] * u[found]
        a, b = z[edge[found]], np.roll(z, -1)[edge[found]]
        off = np.abs(((q - a) * np.conj(b - a)).imag) / np.abs(b - a)
        assert off.max() <= 1e-12 * diam


def test_a_ladder_search_with_too_many_candidate_rungs_stops_at_once(monkeypatch) -> None:
    # a round outline that is no corridor gives a ladder search a number of candidate rungs
    # that grows with the square of its vertex count (a 10,000-vertex star held 15.5 GB after
    # 3 minutes); past MAX_RUNG_CANDIDATES the search stops with a reason, before the arcs
    import time

    import quadmesh.thin.corridor as corridor
    from quadmesh.errors import ThinPartError

    z = validate_polygon(load_example("stroke_spiral")).z
    ladder_layout(z)  # 135,680 candidates: searched
    monkeypatch.setattr(corridor, "MAX_RUNG_CANDIDATES", 10_000)
    t0 = time.perf_counter()
    with pytest.raises(ThinPartError, match="too wide for a ladder of straight cells: 135,680"):
        ladder_layout(z)
    assert time.perf_counter() - t0 < 5.0
