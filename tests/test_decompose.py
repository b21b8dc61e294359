"""Tests of the thick/thin decomposition (quadmesh.decompose; Bishop §7, CONFORMAL.md §2)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from quadmesh.decompose import DecomposeOptions, decompose
from quadmesh.errors import PolygonError

# ----------------------------------------------------------------------------------------
# test polygons


def square() -> np.ndarray:
    return np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])


def rectangle(length: float = 20.0, width: float = 1.0) -> np.ndarray:
    return np.array([(0.0, 0.0), (length, 0.0), (length, width), (0.0, width)])


def comb(
    teeth: int = 6, width: float = 0.05, length: float = 1.0, pitch: float = 0.5
) -> np.ndarray:
    """Base [0, teeth·pitch] × [0, 1] with teeth of the given width and length on top."""
    L = teeth * pitch
    pts = [(0.0, 0.0), (L, 0.0), (L, 1.0)]
    for i in reversed(range(teeth)):
        x = (i + 0.5) * pitch - 0.5 * width
        pts += [(x + width, 1.0), (x + width, 1.0 + length), (x, 1.0 + length), (x, 1.0)]
    pts.append((0.0, 1.0))
    return np.array(pts)


def spiral(turns: int = 10, step: float = 0.5, width: float = 0.1) -> np.ndarray:
    """A square spiral corridor: the centre line has legs step·(1, 1, 2, 2, 3, 3, …)."""
    p = np.array([0.0, 0.0])
    d = np.array([1.0, 0.0])
    line = [p.copy()]
    for k in range(turns):
        p = p + d * step * (k // 2 + 1)
        line.append(p.copy())
        d = np.array([-d[1], d[0]])
    poly = shapely.LineString(line).buffer(0.5 * width, cap_style="flat", join_style="mitre")
    xy = np.asarray(poly.exterior.coords)[:-1]
    return xy


def dumbbell(gap: float = 2.0, width: float = 0.05) -> np.ndarray:
    """Two unit squares joined by a corridor of the given length and width."""
    a, b = 0.5 - 0.5 * width, 0.5 + 0.5 * width
    return np.array(
        [
            (0.0, 0.0), (1.0, 0.0), (1.0, a), (1.0 + gap, a), (1.0 + gap, 0.0), (2.0 + gap, 0.0),
            (2.0 + gap, 1.0), (1.0 + gap, 1.0), (1.0 + gap, b), (1.0, b), (1.0, 1.0), (0.0, 1.0),
        ]
    )  # fmt: skip


def tapered(length: float = 5.0, w0: float = 0.2, w1: float = 0.05) -> np.ndarray:
    """A square with a tapering spike: walls on lines meeting beyond the tip (angled channel)."""
    return np.array(
        [
            (-1.0, -0.5), (0.0, -0.5), (0.0, -0.5 * w0), (length, -0.5 * w1), (length, 0.5 * w1),
            (0.0, 0.5 * w0), (0.0, 0.5), (-1.0, 0.5),
        ]
    )  # fmt: skip


def notched(length: float = 20.0) -> np.ndarray:
    """A 20 × 1 rectangle with a small notch in the top side: two channels share the bottom wall."""
    h = 0.5 * length
    return np.array(
        [
            (0.0, 0.0),
            (length, 0.0),
            (length, 1.0),
            (h + 0.1, 1.0),
            (h, 0.9),
            (h - 0.1, 1.0),
            (0.0, 1.0),
        ]
    )


def corridor(line: list[tuple[float, float]], width: float = 0.1) -> np.ndarray:
    """A corridor of the given width along a polyline (flat ends, mitred turns), CCW."""
    poly = shapely.LineString(line).buffer(
        0.5 * width, cap_style="flat", join_style="mitre", mitre_limit=10.0
    )
    return np.asarray(shapely.orient_polygons(poly).exterior.coords)[:-1]


def u_corridor() -> np.ndarray:
    """U-shaped corridor of width 0.1, legs 0.6 (≈ 18 widths, no leg thin for δ = 0.15)."""
    return corridor([(0.0, 0.6), (0.0, 0.0), (0.6, 0.0), (0.6, 0.6)])


def zigzag() -> np.ndarray:
    """Six legs of length 0.6 at ±45°, width 0.1 (≈ 36 widths, gap ≈ 1e-31 uncut)."""
    step = 0.6 * np.exp(1j * np.radians([45, -45] * 3))
    c = np.concatenate([[0], np.cumsum(step)])
    return corridor(list(zip(c.real, c.imag, strict=True)))


def square_spiral() -> np.ndarray:
    from quadmesh.examples import load_example

    return np.asarray(load_example("square_spiral"), dtype=float)


SHAPES = {
    "square": square,
    "rectangle": rectangle,
    "comb": comb,
    "spiral": spiral,
    "dumbbell": dumbbell,
    "tapered": tapered,
    "notched": notched,
    "u_corridor": u_corridor,
    "zigzag": zigzag,
    "square_spiral": square_spiral,
}


def _dec(name: str):
    return decompose(SHAPES[name]())


def _poly(z: np.ndarray) -> shapely.Polygon:
    return shapely.Polygon(np.column_stack([z.real, z.imag]))


D = DecomposeOptions().overlap_depth  # 1/(4δ) + 1 widths


# ----------------------------------------------------------------------------------------
# expected channels


def test_square_is_one_thick_piece() -> None:
    d = _dec("square")
    assert len(d.channels) == 0 and len(d.thick) == 1 and len(d.corners) == 4
    p = d.thick[0]
    np.testing.assert_allclose(p.z, d.polygon.z)
    assert p.crosscuts == ()
    assert abs(p.center - (0.5 + 0.5j)) < 1e-3 and abs(p.radius - 0.5) < 1e-3
    # d_k = 1 (side length), r_k = κ d_k
    np.testing.assert_allclose([c.radius for c in d.corners], 0.25)
    np.testing.assert_allclose([c.angle for c in d.corners], np.pi / 2)


def test_rectangle_20x1_has_one_parallel_channel() -> None:
    d = _dec("rectangle")
    assert len(d.channels) == 1 and len(d.thick) == 2
    c = d.channels[0]
    assert c.walls == (0, 2) and c.frame.kind == "parallel"
    assert c.frame.origin == 0 and c.frame.direction == 1 and c.frame.width == 1.0
    # mouths clear the corner sectors (r = 1/4), thick pieces reach D widths past them
    np.testing.assert_allclose(c.mouths, (0.25, 19.75))
    np.testing.assert_allclose(c.cuts, (0.25 + D, 19.75 - D))
    np.testing.assert_allclose(c.extremal_distance, 1 / 19.5)
    np.testing.assert_allclose(c.widths, (1.0, 1.0))
    ga, gb = c.crosscuts
    np.testing.assert_allclose(ga.real, 0.25 + D)
    np.testing.assert_allclose(ga.imag, np.linspace(0, 1, 5), atol=1e-15)  # wall 1 → wall 2
    np.testing.assert_allclose(gb.real, 19.75 - D)
    np.testing.assert_allclose(c.core_area, 19.5 - 2 * D)
    a, b = c.pieces
    np.testing.assert_allclose([d.thick[a].area, d.thick[b].area], 0.25 + D)
    assert d.thick[a].center.real < 0.25 and d.thick[b].center.real > 19.75  # outside Ω_3


def test_comb_teeth_are_channels() -> None:
    teeth, w = 6, 0.05
    d = decompose(comb(teeth=teeth, width=w, length=1.0))
    assert len(d.channels) == teeth and len(d.thick) == teeth + 1
    xs = sorted((i + 0.5) * 0.5 for i in range(teeth))
    centres = sorted(float(np.mean(c.core[:, 0])) for c in d.channels)
    np.testing.assert_allclose(centres, xs, atol=1e-12)
    r = 0.25 * w  # every tooth corner has d_k = w
    for c in d.channels:
        assert c.frame.kind == "parallel"
        np.testing.assert_allclose(c.extremal_distance, w / (1 - 2 * r))
        y = np.sort(c.core[:, 1])
        np.testing.assert_allclose([y[0], y[-1]], [1 + r + D * w, 2 - r - D * w], atol=1e-12)
    # the base keeps all tooth stubs: one piece with 2·teeth crosscuts
    base = max(d.thick, key=lambda p: p.area)
    assert len(base.crosscuts) == teeth
    assert sum(len(p.crosscuts) for p in d.thick) == 2 * teeth


def test_spiral_legs_are_channels() -> None:
    d = decompose(spiral(), DecomposeOptions(crowding_gap=0.0))
    # legs of length ≥ 1 (centre line) are thin: legs 3..10 of step·(1,1,2,2,3,3,4,4,5,5)
    assert len(d.channels) == 8 and len(d.thick) == 9
    for c in d.channels:
        assert c.frame.kind == "parallel"
        np.testing.assert_allclose(c.widths, 0.1, rtol=1e-9)
        assert c.extremal_distance < 0.15
    # the legs' channels get thinner outwards
    eds = sorted(c.extremal_distance for c in d.channels)
    np.testing.assert_allclose(eds[-2:], [0.1 / 0.85] * 2, rtol=1e-9)
    # each core lies in one straight leg: its axis-parallel bounding box has width 0.1
    for c in d.channels:
        ext = np.ptp(c.core, axis=0)
        assert abs(min(ext) - 0.1) < 1e-9


def test_dumbbell_has_one_channel_in_the_bar() -> None:
    d = _dec("dumbbell")
    assert len(d.channels) == 1 and len(d.thick) == 2
    c = d.channels[0]
    xmin, xmax = c.core[:, 0].min(), c.core[:, 0].max()
    r = 0.25 * 0.05
    np.testing.assert_allclose([xmin, xmax], [1 + r + D * 0.05, 3 - r - D * 0.05])
    np.testing.assert_allclose(c.extremal_distance, 0.05 / (2 - 2 * r))
    a, b = (d.thick[k] for k in c.pieces)
    assert a.center.real < 1 < 3 < b.center.real
    np.testing.assert_allclose([a.radius, b.radius], 0.5, rtol=0.02)  # center_tol = 1e-2


def test_nearly_parallel_walls_are_a_wedge_with_far_origin() -> None:
    """Top wall tilted by 1e-4 rad: exact wedge frame, walls exactly on the frame's rays."""
    tilt = 1e-4
    z = np.array([(0.0, 0.0), (20.0, 0.0), (20.0, 1.0 + 20 * np.tan(tilt)), (0.0, 1.0)])
    d = decompose(z)
    assert len(d.channels) == 1
    c = d.channels[0]
    fr = c.frame
    assert fr.kind == "angled"
    np.testing.assert_allclose(fr.beta, tilt, rtol=1e-9)
    np.testing.assert_allclose(fr.origin, -1.0 / np.tan(tilt), rtol=1e-9)
    for g in c.crosscuts:
        s = fr.strip(g)
        np.testing.assert_allclose([s[0].imag, s[-1].imag], [0.0, fr.beta], atol=1e-12)
        np.testing.assert_allclose(np.abs(g - fr.origin), abs(g[0] - fr.origin), rtol=1e-13)
    np.testing.assert_allclose(c.extremal_distance, 1 / 19.5, rtol=3e-3)  # width grows 0.2%


def test_notched_rectangle_has_two_channels_on_one_wall() -> None:
    d = _dec("notched")
    assert len(d.channels) == 2 and len(d.thick) == 3
    assert sorted(c.walls[0] for c in d.channels) == [0, 0]  # both use the bottom edge as wall 1
    left, right = sorted(d.channels, key=lambda c: c.mouths[0])
    # the notch vertex (10, 0.9) has d = 0.9·sin45°-ish; its region blocks both channels
    assert left.core[:, 0].max() < 10 - 0.1 < 10 + 0.1 < right.core[:, 0].min()
    middle = d.thick[left.pieces[1]]
    assert middle.index == right.pieces[0]
    assert len(middle.crosscuts) == 2
    assert middle.center.real == pytest.approx(10.0, abs=0.05)


def test_tapered_spike_is_an_angled_channel() -> None:
    d = _dec("tapered")
    assert len(d.channels) == 1
    c = d.channels[0]
    fr = c.frame
    assert fr.kind == "angled"
    slope = (0.2 - 0.05) / 2 / 5.0
    np.testing.assert_allclose(fr.beta, 2 * np.arctan(slope), rtol=1e-12)
    np.testing.assert_allclose(fr.origin, 0.1 / slope, rtol=1e-12)
    # crosscuts are arcs about O, orthogonal to both walls; strip coords put the walls at 0, β
    for g in (*c.crosscuts, *c.outer_crosscuts):
        rad = np.abs(g - fr.origin)
        np.testing.assert_allclose(rad, rad[0], rtol=1e-12)
        s = fr.strip(g)
        np.testing.assert_allclose([s[0].imag, s[-1].imag], [0, fr.beta], atol=1e-12)
    ra, rb = c.mouths
    np.testing.assert_allclose(c.cuts, (ra * np.exp(D * fr.beta), rb * np.exp(-D * fr.beta)))
    np.testing.assert_allclose(c.extremal_distance, fr.beta / np.log(rb / ra))


# ----------------------------------------------------------------------------------------
# properties on every shape


@pytest.mark.parametrize("name", list(SHAPES))
def test_pieces_and_cores_tile_the_polygon(name: str) -> None:
    d = _dec(name)
    omega = _poly(d.polygon.z)
    parts = [_poly(p.z) for p in d.thick] + [_poly(c.core_z) for c in d.channels]
    assert all(p.is_valid and p.area > 0 for p in parts)
    # counter-clockwise (positive signed area) pieces and cores
    assert all(p.area > 0 for p in d.thick) and all(c.core_area > 0 for c in d.channels)
    total = sum(p.area for p in parts)
    np.testing.assert_allclose(total, omega.area, rtol=1e-12)
    union = shapely.union_all(parts)
    assert shapely.symmetric_difference(union, omega).area < 1e-12 * omega.area
    tree = shapely.STRtree(parts)
    i, j = tree.query(parts, predicate="intersects")
    for a, b in zip(i[i < j], j[i < j], strict=True):
        assert shapely.intersection(parts[a], parts[b]).area < 1e-12 * omega.area


@pytest.mark.parametrize("name", list(SHAPES))
def test_crosscuts_are_shared_and_clear_of_vertex_regions(name: str) -> None:
    d = _dec(name)
    z = d.polygon.z
    r = np.array([c.radius for c in d.corners])
    for c in d.channels:
        for end, g in enumerate(c.crosscuts):
            assert g.size == d.options.crosscut_vertices
            # endpoints on the two walls
            for e, p in zip(c.walls, (g[0], g[-1]), strict=True):
                a, b = z[e], z[(e + 1) % z.size]
                t = ((p - a) / (b - a)).real
                assert 0 < t < 1 and abs(((p - a) / (b - a)).imag) * abs(b - a) < 1e-12
            seg = shapely.LineString(np.column_stack([g.real, g.imag]))
            dist = shapely.distance(seg, shapely.points(np.column_stack([z.real, z.imag])))
            assert np.all(dist > r)
            # the owning thick piece carries the identical vertex array
            piece = d.thick[c.pieces[end]]
            (pc,) = [q for q in piece.crosscuts if q.channel == c.id and q.end == end]
            stretch = piece.z[pc.start : pc.stop + 1]
            np.testing.assert_array_equal(stretch, g[::-1] if pc.reversed else g)
            assert np.all(piece.source[pc.start : pc.stop + 1] == -1)
        assert c.pieces[0] != c.pieces[1]


@pytest.mark.parametrize("name", list(SHAPES))
def test_corners_record_vertex_sector_and_piece(name: str) -> None:
    d = _dec(name)
    z = d.polygon.z
    n = z.size
    assert [c.index for c in d.corners] == list(range(n))
    for c in d.corners:
        p = d.thick[c.piece]
        assert p.z[c.piece_vertex] == c.apex == z[c.index]
        assert p.source[c.piece_vertex] == c.index
        np.testing.assert_allclose(
            c.dir_out * abs(z[(c.index + 1) % n] - c.apex), z[(c.index + 1) % n] - c.apex
        )
        np.testing.assert_allclose(c.dir_in * abs(z[c.index - 1] - c.apex), z[c.index - 1] - c.apex)
        # the sector B(v, 4 r) meets only the two sides (d_k = 4 r_k)
        assert (
            0
            < c.radius
            <= 0.25 * min(abs(z[c.index - 1] - c.apex), abs(z[(c.index + 1) % n] - c.apex)) + 1e-15
        )


@pytest.mark.parametrize("name", list(SHAPES))
def test_thick_pieces_are_delta_thick(name: str) -> None:
    """Decomposing a thick piece again finds no channel: its walls have ED > δ."""
    d = _dec(name)
    for p in d.thick:
        assert len(decompose(p.z, DecomposeOptions(crowding_gap=0.0)).channels) == 0
        # the centre lies in the piece, outside every overlap band Ω_3
        assert _poly(p.z).contains(shapely.Point(p.center.real, p.center.imag))
        for pc in p.crosscuts:
            c = d.channels[pc.channel]
            x = c.frame.coordinate(p.center).item()
            lo, hi = sorted((c.mouths[pc.end], c.cuts[pc.end]))
            inside_band = lo < x < hi and 0 < c.frame.strip(p.center).imag < (
                c.frame.beta if c.frame.kind == "angled" else c.widths[pc.end]
            )
            assert not inside_band


def test_1000_gon_comb() -> None:
    """n = 1004: 250 channels found with the STRtree (no all-pairs scan)."""
    p = comb(teeth=250)
    d = decompose(p)
    assert len(d.channels) == 250 and len(d.thick) == 251
    assert d.candidates == 250  # facing pairs that survived the cheap prefilter


def test_delta_threshold_controls_detection() -> None:
    # 0.1 × 1 corridor (ED ≈ 0.1/0.95): thin for δ = 0.15, thick for δ = 0.1
    z = rectangle(1.0, 0.1)
    assert len(decompose(z).channels) == 1
    assert len(decompose(z, DecomposeOptions(delta=0.1, overlap=2.0)).channels) == 0


def test_crosscut_vertices_option() -> None:
    d = decompose(dumbbell(), DecomposeOptions(crosscut_vertices=3))
    assert all(g.size == 3 for g in d.channels[0].crosscuts)
    assert len(d.thick[0].z) == 6 + 3


def test_bad_options_and_polygons_raise() -> None:
    with pytest.raises(ValueError):
        DecomposeOptions(delta=0.0)
    with pytest.raises(ValueError):
        DecomposeOptions(overlap=10.0)  # ≥ 1/δ: thick pieces would not be thick
    with pytest.raises(ValueError):
        DecomposeOptions(crosscut_vertices=1)
    with pytest.raises(PolygonError):
        decompose([(0, 0), (1, 1), (1, 0), (0, 1)])


# ----------------------------------------------------------------------------------------
# the thick pieces map with the Schwarz–Christoffel disk map (helper "sc")


def _arc(a: complex, b: complex) -> tuple[float, float]:
    """Counter-clockwise arc from a to b on the unit circle as (start angle, length)."""
    t0 = float(np.angle(a))
    return t0, float(np.angle(b / a)) % (2 * np.pi)


@pytest.mark.parametrize(
    "name",
    ["rectangle", "comb", "spiral", "dumbbell", "tapered", "notched", "zigzag", "square_spiral"],
)
def test_thick_pieces_map_without_crowding(name: str) -> None:
    """Each thick piece gets its SC map with f(0) at its centre (no ConformalMapError), and
    the paper's hypotheses on the intervals hold: the preimage I'_j of the outer crosscut γ'
    contains A·I_j with A ≥ exp(π/(4δ)), and the I'_j are disjoint and shorter than π.  For
    the channels cut by the crowding refinement (shallower overlaps of depth D ≥ 1.5) the
    expansion is measured as ≈ exp(πD)/2 (83 at D = 1.625) and checked to exceed exp(πD)/3."""
    from quadmesh.conformal import DiskMap

    d = _dec(name)
    A = np.exp(np.pi / (4 * d.options.delta))
    for p in d.thick:
        m = DiskMap.from_polygon(p.z, center=p.center, tol=1e-10)
        acc = m.accuracy()
        assert acc.worst < 1e-10
        # spiral: the piece next to the relaxed channel has 4.5e-10 (estimate 1.2e-9)
        assert float(np.min(m.gaps)) > (1e-10 if d.options.crowding_gap > 0 else 1e-13)
        arcs = []
        for pc in p.crosscuts:
            c = d.channels[pc.channel]
            _, len_i = _arc(m.prevertices[pc.start], m.prevertices[pc.stop])
            go = c.outer_crosscuts[pc.end]
            go = go[::-1] if pc.reversed else go
            inward = 1e-9 * (go[-1] - go[0])
            zo = m.inverse(np.array([go[0] + inward, go[-1] - inward]))
            s0, len_o = _arc(zo[0], zo[1])
            assert len_o < np.pi
            if c.relaxed:
                depth = abs(c.cuts[pc.end] - c.mouths[pc.end]) / c.widths[pc.end]
                assert len_o / len_i > np.exp(np.pi * depth) / 3
            else:
                assert len_o / len_i > A
            arcs.append((s0, len_o))
        # expanded intervals are disjoint
        arcs.sort()
        for (s0, l0), (s1, _) in zip(arcs, [*arcs[1:], (arcs[0][0] + 2 * np.pi, 0)]):
            assert s0 + l0 < s1


# ----------------------------------------------------------------------------------------
# crowding-driven refinement (CONFORMAL.md §1.9 "split further")


def _gaps(d) -> np.ndarray:
    """2π·min ω of every thick piece seen from its centre (the SC gap estimate)."""
    from quadmesh.conformal.center import harmonic_measure

    return np.array([2 * np.pi * harmonic_measure(p.z, p.center).min() for p in d.thick])


@pytest.mark.parametrize(
    ("name", "extra"), [("spiral", 1), ("square_spiral", 4), ("u_corridor", 3), ("zigzag", 5)]
)
def test_refinement_removes_crowding(name: str, extra: int) -> None:
    """Corridors whose legs are too short for ED < δ crowd far below double precision; the
    refinement cuts relaxed channels (δ ≤ ED < refine_delta) until every piece's estimated
    gap is ≥ crowding_gap, keeping the ordinary channels."""
    z = SHAPES[name]()
    plain = decompose(z, DecomposeOptions(crowding_gap=0.0))
    d = decompose(z)
    opt = d.options
    # crowded seen from the largest inscribed disks (without the refinement the spiral's map
    # moves its centre to where its gap is 5e-9)
    assert np.fmin(_gaps(plain), [p.inscribed_gap for p in plain.thick]).min() < 1e-11
    gaps = _gaps(d)
    assert gaps.min() >= opt.crowding_gap
    for p, g in zip(d.thick, gaps, strict=True):
        assert np.isnan(p.min_gap) or p.min_gap == pytest.approx(g, rel=1e-9)
    assert all(np.isnan(p.min_gap) for p in plain.thick)
    assert sorted(c.walls for c in plain.channels) == sorted(
        c.walls for c in d.channels if not c.relaxed
    )
    relaxed = [c for c in d.channels if c.relaxed]
    assert len(relaxed) == extra
    bands = []
    for c in d.channels:
        xa, xb = c.mouths
        xA, xB = c.cuts
        wa, wb = c.widths
        assert c.frame.kind == "parallel"
        if c.relaxed:
            assert opt.delta <= c.extremal_distance < opt.refine_delta
            # overlaps and core in widths (strip units; the walls are parallel here)
            assert min((xA - xa) / wa, (xb - xB) / wb) >= opt.refine_overlap - 1e-9
            assert (xB - xA) / wa >= opt.refine_core - 1e-9
        ga, gb = c.outer_crosscuts
        bands.append(_poly(np.concatenate([gb, ga[::-1]])))
    # thin parts Ω_2 (between the mouths) of different channels do not overlap
    for i in range(len(bands)):
        for j in range(i):
            assert shapely.intersection(bands[i], bands[j]).area < 1e-12


def test_square_spiral_refinement_numbers() -> None:
    """square_spiral (width 0.4): the inner piece (gap 1e-36) gets the two 6-width legs
    (ED 1/6, overlap D = 1/(4δ)+1) and two 3.5-width legs (ED 2/7, D = 1.625); all eight
    pieces then have estimated gaps between 5e-6 and 1e-2."""
    d = _dec("square_spiral")
    relaxed = sorted(c.extremal_distance for c in d.channels if c.relaxed)
    np.testing.assert_allclose(relaxed, [1 / 6, 1 / 6, 2 / 7, 2 / 7], rtol=1e-9)
    assert len(d.channels) == 7 and len(d.thick) == 8
    g = _gaps(d)
    assert 5e-6 < g.min() and g.max() < 1e-2
    for c in d.channels:
        if c.relaxed and c.extremal_distance > 0.2:
            np.testing.assert_allclose(np.subtract(c.cuts, c.mouths), [0.65, -0.65], rtol=1e-9)


@pytest.mark.parametrize("name", ["comb", "dumbbell", "leaf", "glyph_s", "u_shape", "island"])
def test_refinement_leaves_other_examples_alone(name: str) -> None:
    """Bundled examples without crowding (or without straight legs to cut, like glyph_s) keep
    exactly the channels of the ordinary pass."""
    from quadmesh.examples import load_example

    z = load_example(name)
    a = decompose(z, DecomposeOptions(crowding_gap=0.0))
    b = decompose(z)
    assert [c.walls for c in a.channels] == [c.walls for c in b.channels]
    assert not any(c.relaxed for c in b.channels)


def test_refinement_options() -> None:
    with pytest.raises(ValueError):
        DecomposeOptions(refine_delta=1.0)
    with pytest.raises(ValueError):
        DecomposeOptions(crowding_gap=-1.0)
    with pytest.raises(ValueError):
        DecomposeOptions(refine_overlap=0.0)
    # the pipeline passes δ = channel_delta alone: a δ above refine_delta stays valid
    assert DecomposeOptions(delta=0.6).delta == 0.6
    # a stricter threshold cuts more (the 3.5-width legs are needed for 1e-9 only)
    loose = decompose(square_spiral(), DecomposeOptions(crowding_gap=1e-12))
    assert sum(c.relaxed for c in loose.channels) == 2


# ----------------------------------------------------------------------------------------
# messages about pieces and channels speak in the user's numbering


def test_pieces_and_channels_are_described_in_the_users_numbering() -> None:
    """A 20×1 rectangle given clockwise, with a closing point and a repeated point: the
    pieces and the channel are named by the input positions of their vertices."""
    pts = [(0, 0), (0, 1), (20, 1), (20, 1), (20, 0), (0, 0)]  # clockwise; 3 repeats 2
    d = decompose(pts)
    assert d.polygon.reversed_input and len(d.channels) == 1
    ends = sorted(d.describe_piece(k) for k in range(2))
    assert ends[0].startswith("the part of the polygon through vertices 0 to 1 (around (0.")
    assert ends[1].startswith("the part of the polygon through vertices 2 to 4 (around (19.")
    walls = d.describe_channel(0)
    assert "edge 1 (from vertex 1 at (0, 1) to vertex 2 at (20, 1))" in walls
    assert "edge 4 (from vertex 4 at (20, 0) to vertex 0 at (0, 0))" in walls
    # a piece whose vertex run wraps past the user's vertex 0
    spiral_ccw = square_spiral()
    d = decompose(spiral_ccw, DecomposeOptions(crowding_gap=0.0))
    text = d.describe_piece(0)
    assert "(through 0)" in text and "vertices" in text


def _hammer() -> np.ndarray:
    """A 4 × 4 head with a wavy handle (width 1, 12 long): the largest inscribed disk is in the
    head, and the handle's walls are chains, so no channel is cut."""
    t = np.linspace(0, 1, 80)
    centre = np.column_stack([2 + 12 * t, 0.6 * np.sin(3 * np.pi * t)])
    g = shapely.LineString(centre).buffer(0.5, cap_style="flat", join_style="round", quad_segs=4)
    g = shapely.union(g, shapely.box(-2, -2, 2.2, 2))
    g = shapely.geometry.polygon.orient(shapely.simplify(g, 1e-3), 1.0)
    return np.asarray(g.exterior.coords)[:-1]


def test_a_crowded_piece_maps_from_its_least_crowded_centre() -> None:
    """Seen from the head, the handle's far end has harmonic measure ~1e-19 (below what a
    float64 map resolves); the piece's map centre moves into the handle, where its smallest
    estimated gap is ~1e-9, and the piece keeps the head's estimate as ``inscribed_gap`` (it is a
    corridor-like shape whatever centre its map uses)."""
    from quadmesh.conformal.center import harmonic_measure

    d = decompose(_hammer())
    assert len(d.thick) == 1 and not d.channels
    p = d.thick[0]
    assert p.inscribed_gap < 1e-16
    gap = 2 * np.pi * harmonic_measure(p.z, p.center).min()
    assert gap > 1e-11 and gap > 1e6 * p.inscribed_gap
    assert p.center.real > 4.0  # in the handle, away from the head
    poly = shapely.Polygon(np.column_stack([p.z.real, p.z.imag]))
    dist = poly.exterior.distance(shapely.Point(p.center.real, p.center.imag))
    assert poly.contains(shapely.Point(p.center.real, p.center.imag))
    assert p.radius == pytest.approx(dist, rel=1e-9)
    # an ordinary piece keeps its inscribed centre
    sq = decompose(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])).thick[0]
    assert np.isnan(sq.inscribed_gap) and sq.center == pytest.approx(0.5 + 0.5j, abs=1e-3)
