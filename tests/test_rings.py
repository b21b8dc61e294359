"""Ring layouts: a collar of spokes around a core of lattice kites (quadmesh.rings)."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import MeshOptions, mesh_polygon
from quadmesh.blocks import default_block_size
from quadmesh.cells import cell_angles
from quadmesh.examples import load_example
from quadmesh.io import write_mesh
from quadmesh.polygon import interior_angles, validate_polygon
from quadmesh.rings import (
    RingLayoutError,
    _kites,
    _lattice_core,
    _outline,
    ring_cells,
    ring_layout,
)
from tests.test_strict import independent_check


def _z(name: str) -> np.ndarray:
    return validate_polygon(load_example(name)).z


@pytest.mark.parametrize("name", ["octagon", "dodecagon", "regular_64", "blob", "star_30"])
def test_round_outlines_close_by_a_collar(name: str, tmp_path) -> None:
    """Outlines where straight cuts cannot close (many corners of 120°–180°, a 355° slit)
    get a ring layout; the mesh written to disk passes the independent check, with far fewer
    quads than the paper's construction (thousands)."""
    verts = load_example(name)
    res = mesh_polygon(verts, MeshOptions(method="blocks"))
    assert res.fallback is None and res.blocks.kind == "ring"
    lay = res.blocks
    # every coarse corner in range except the polygon's own corners kept whole
    ang = cell_angles(lay.points[lay.cells])
    own = lay.cells < len(lay.polygon)
    assert np.all(ang[~own] >= 60.0 - 1e-7) and np.all(ang[~own] <= 120.0 + 1e-7)
    # every polygon corner above 120° is the end of a spoke
    theta = np.degrees(interior_angles(lay.polygon))
    ends = lay.cuts[:, 0]
    for v in lay.polygon[theta > 120.0 + 1e-7]:
        assert np.min(np.abs(ends - v)) <= 1e-12 * np.abs(lay.polygon).max()
    out = tmp_path / f"{name}.json"
    write_mesh(out, res.mesh)
    got = independent_check(out, verts, angle_tol=1e-9)
    assert got["n_quads"] == res.mesh.n_quads <= 2000


def test_core_outline_turns_by_60_degrees_only() -> None:
    """The cleaned lattice core is one simple region whose outline has corners of 120° and
    240° only; its kites have corners of exactly 60°, 90°, 120°, 90°."""
    z = _z("blob")
    s = 2 * default_block_size(z)
    L, tri = _lattice_core(z, s, 0.3)
    cyc = _outline(tri)
    w = L[cyc]
    turn = np.degrees(np.angle((np.roll(w, -1) - w) / (w - np.roll(w, 1))))
    assert np.all(np.isclose(np.abs(turn), 60.0, atol=1e-9) | np.isclose(turn, 0.0, atol=1e-9))
    # a simple outline: every outline vertex appears once
    assert len(np.unique(cyc)) == len(cyc)
    pts, kites, _mid = _kites(L, tri)
    ang = cell_angles(pts[kites])
    assert np.allclose(np.sort(ang, axis=1), [60.0, 90.0, 90.0, 120.0], atol=1e-9)
    # the core keeps its clearance from the boundary
    import shapely

    poly = shapely.Polygon(np.column_stack([z.real, z.imag]))
    core_pts = shapely.points(L.real, L.imag)
    assert np.all(shapely.contains(poly, core_pts))


def test_collar_cells_and_spoke_rules() -> None:
    """Before the hanging points are resolved: collar cells are counter-clockwise and convex,
    new corners in [60.02°, 119.98°] except at core corners (exactly 60° or 120°), polygon
    corners up to 120° are kept whole in one collar cell."""
    z = _z("regular_64")
    lay = ring_cells(z, 2 * default_block_size(z))
    collar = lay.cells[: lay.n_collar]
    ang = cell_angles(lay.points[collar])
    assert np.all(ang > 0) and np.all(ang < 180)
    exact = np.isclose(ang, 60.0, atol=1e-7) | np.isclose(ang, 120.0, atol=1e-7)
    assert np.all(exact | ((ang >= 60.02) & (ang <= 119.98)))


def test_too_thin_for_a_core_says_so() -> None:
    z = _z("channel_20")  # 20 × 1: no lattice of the default spacing fits inside
    with pytest.raises(RingLayoutError, match="wide enough"):
        ring_cells(z, 2 * default_block_size(z))


def test_random_round_outlines_mesh_or_say_why() -> None:
    """Smooth random outlines (Fourier radii, 24–80 vertices): a ring layout either closes and
    verifies, or fails with a ring-layout error; most close."""
    rng = np.random.default_rng(7)
    closed = 0
    trials = 8
    for _ in range(trials):
        n = int(rng.integers(24, 81))
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        r = 1 + sum(
            rng.normal(0, 0.12 / k) * np.cos(k * t + rng.uniform(0, 2 * np.pi)) for k in range(1, 5)
        )
        z = validate_polygon(np.column_stack([r * np.cos(t), r * np.sin(t)])).z
        try:
            lay = ring_layout(z, default_block_size(z))
        except RingLayoutError:
            continue
        closed += 1
        ang = lay.angles
        own = lay.cells < len(z)
        assert np.all(ang[~own] >= 60.0 - 1e-7) and np.all(ang[~own] <= 120.0 + 1e-7)
    assert closed >= trials - 2


def test_cli_reports_the_collar(tmp_path, capsys) -> None:
    """`quadmesh mesh --method blocks` on the octagon says the layout is a collar, and the file
    it writes passes the independent check."""
    from quadmesh.cli import main as cli_main
    from quadmesh.examples import example_path

    out = tmp_path / "octagon.json"
    assert (
        cli_main(["mesh", str(example_path("octagon")), "-o", str(out), "--method", "blocks"]) == 0
    )
    text = capsys.readouterr().out
    assert "spokes of a collar around a lattice core" in text and "note:" not in text
    got = independent_check(out, load_example("octagon"), angle_tol=1e-9)
    assert got["n_quads"] > 0


def test_hanging_points_found_the_same_with_and_without_the_tree(monkeypatch) -> None:
    """The first round of hanging-point resolution tests every point near every side; with a
    k-d tree of the points (large layouts) it finds the same points as the full test, and the
    result is conforming (every edge in at most two cells, opposite sides paired)."""
    import quadmesh.blocks as blocks
    from quadmesh.cells import layout_chords

    z = _z("regular_64")
    lay = ring_cells(z, 2 * default_block_size(z))
    tips = np.zeros(len(lay.points), dtype=bool)
    monkeypatch.setattr(blocks, "BRUTE_PAIRS", 10**12)
    X1, C1 = blocks._resolve_hanging(lay.points, lay.cells, tips, max_rounds=4000)
    monkeypatch.setattr(blocks, "BRUTE_PAIRS", 0)
    X2, C2 = blocks._resolve_hanging(lay.points, lay.cells, tips, max_rounds=4000)
    assert len(C1) == len(C2) > len(lay.cells)
    assert np.allclose(np.sort_complex(X1), np.sort_complex(X2))
    layout_chords(C2)  # raises on a non-conforming layout
    assert abs(np.sum(_areas(X2[C2])) - _areas(z[None, :])[0]) < 1e-9


def _areas(w: np.ndarray) -> np.ndarray:
    return 0.5 * np.sum(
        w.real * np.roll(w.imag, -1, axis=1) - np.roll(w.real, -1, axis=1) * w.imag, axis=1
    )
