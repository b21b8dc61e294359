"""Local angle repair (quadmesh.repair) and its use by mesh_polygon."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import MeshOptions, mesh_polygon
from quadmesh.examples import load_example
from quadmesh.geometry import quad_angles_deg, quad_signed_areas, unpaired_edges
from quadmesh.repair import repair_angles


def _grid(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit square split into m×m squares, counter-clockwise quads."""
    x, y = np.meshgrid(np.arange(m + 1) / m, np.arange(m + 1) / m, indexing="ij")
    z = (x + 1j * y).ravel()
    idx = np.arange((m + 1) ** 2).reshape(m + 1, m + 1)
    q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1).reshape(-1, 4)
    return z, q


def _interior(z: np.ndarray, q: np.ndarray) -> np.ndarray:
    edges, _ = unpaired_edges(q)
    mov = np.ones(z.size, dtype=bool)
    mov[np.unique(edges)] = False
    return mov


def test_repair_fixes_a_distorted_vertex_and_keeps_the_rest():
    z, q = _grid(8)
    mov = _interior(z, q)
    k = 4 * 9 + 4  # centre vertex
    z = z.copy()
    z[k] += 0.06 + 0.04j  # pushes neighbouring angles below 58° and above 122°
    ang = quad_angles_deg(z, q)
    assert ang.min() < 58.0 and ang.max() > 122.0
    got = repair_angles(z, q, mov)
    assert got is not None
    new, rep = got
    a = quad_angles_deg(new, q)
    assert a.min() >= 60.0 - 1e-9 and a.max() <= 120.0 + 1e-9
    assert np.all(quad_signed_areas(new, q) > 0)
    # boundary vertices never move, the total area is unchanged, shifts are small
    assert np.array_equal(new[~mov], z[~mov])
    assert quad_signed_areas(new, q).sum() == pytest.approx(1.0, rel=1e-12)
    assert rep.moved.size > 0 and np.all(mov[rep.moved])
    assert rep.max_shift < 0.5
    assert rep.before[0] < 58.0 and rep.after[0] >= 60.0


def test_repair_only_moves_vertices_near_the_bad_quads():
    z, q = _grid(12)
    mov = _interior(z, q)
    z = z.copy()
    k = 3 * 13 + 3
    z[k] += 0.02 + 0.015j
    new, _ = repair_angles(z, q, mov, rings=1)
    far = np.abs(z - z[k]) > 0.35
    assert np.array_equal(new[far], z[far])


def test_repair_returns_none_when_nothing_may_move():
    z, q = _grid(4)
    z = z.copy()
    k = 2 * 5 + 2
    z[k] += 0.2
    assert quad_angles_deg(z, q).max() > 125.0
    assert repair_angles(z, q, np.zeros(z.size, dtype=bool)) is None


def test_repair_leaves_a_good_mesh_unchanged():
    z, q = _grid(5)
    new, rep = repair_angles(z, q, _interior(z, q))
    assert np.array_equal(new, z) and rep.moved.size == 0


def test_l_shape_keeps_n2_with_repair_and_needs_n3_without():
    poly = load_example("l_shape")
    r = mesh_polygon(poly)
    assert r.verification.ok if hasattr(r.verification, "ok") else True
    q = r.mesh.quality()
    assert q.min_angle >= 60.0 - 1e-6 and q.max_angle <= 120.0 + 1e-6
    assert all(p.n_used == 2 for p in r.pieces)
    assert any("repaired locally" in f for p in r.pieces for f in p.fixes)
    r0 = mesh_polygon(poly, MeshOptions(repair=False))
    assert max(p.n_used for p in r0.pieces) >= 3
    # n = 2 costs fewer quads than the paper's remedy (raise n)
    assert len(r.mesh.quads) < 0.8 * len(r0.mesh.quads)


def test_degenerate_crowded_piece_is_refused_at_once():
    """Numerically degenerate pushed-forward quads (inverted, collapsed) in a crowded piece
    raise at once instead of entering the adaptive loop; a non-crowded piece is left to it."""
    from types import SimpleNamespace

    from quadmesh.errors import DiskConstructionError
    from quadmesh.pipeline import _refuse_degenerate

    bad = np.array([[90.0, 90.0, 90.0, 90.0], [5.0, 175.0, 90.0, 90.0]])
    good = np.array([[90.0, 90.0, 90.0, 90.0], [58.0, 122.0, 90.0, 90.0]])
    crowded = SimpleNamespace(index=3, theta=np.array([0.0, 1e-13, 2.0, 4.0]))
    spread = SimpleNamespace(index=1, theta=np.array([0.0, 1.0, 2.0, 4.0]))
    with pytest.raises(DiskConstructionError, match="crowd"):
        _refuse_degenerate(crowded, bad)
    _refuse_degenerate(crowded, good)  # ordinary distortion: the loop's business
    _refuse_degenerate(spread, bad)  # not crowded: the loop's business


def test_repair_refuses_large_moves():
    """A distortion that needs vertices to move by more than max_shift of an edge is not a
    small correction: None, so that the caller raises n instead."""
    z, q = _grid(8)
    mov = _interior(z, q)
    z = z.copy()
    z[4 * 9 + 4] += 0.06 + 0.04j
    got = repair_angles(z, q, mov)
    assert got is not None
    assert repair_angles(z, q, mov, max_shift=0.5 * got[1].max_shift) is None


def test_separate_spots_are_repaired_in_one_solve_with_an_exact_jacobian(monkeypatch):
    """Two distorted vertices far apart are two independent groups; they are solved together
    (one least-squares call, block-diagonal Jacobian), every angle ends in range and each
    group keeps to its own neighbourhood. The analytic Jacobian (a fixed sparsity pattern
    refilled per call) agrees with central differences of the residuals."""
    import quadmesh.repair as rep_mod

    z, q = _grid(16)
    mov = _interior(z, q)
    z = z.copy()
    a, b = 3 * 17 + 3, 13 * 17 + 12
    z[a] += 0.02 + 0.015j
    z[b] -= 0.015 + 0.02j
    calls = []
    solve = rep_mod._solve_region

    def counted(*args, **kw):
        calls.append(args[3].size)
        return solve(*args, **kw)

    monkeypatch.setattr(rep_mod, "_solve_region", counted)
    new, report = repair_angles(z, q, mov, rings=1)
    assert len(calls) == 1  # both groups in one solve
    ang = quad_angles_deg(new, q)
    assert ang.min() >= 60.0 - 1e-9 and ang.max() <= 120.0 + 1e-9
    assert np.all(quad_signed_areas(new, q) > 0)
    near = (np.abs(z - z[a]) < 0.2) | (np.abs(z - z[b]) < 0.2)
    assert np.array_equal(new[~near], z[~near])
    assert np.all(near[report.moved])
    for k in (a, b):  # each spot was repaired where it is
        around = np.abs(z - z[k]) < 0.2
        assert np.any(new[around] != z[around])

    # the Jacobian against central differences, at a point where constraints are active
    captured = {}
    import scipy.optimize

    real = scipy.optimize.least_squares

    def spy(fun, x0, jac, **kw):
        captured["f"], captured["j"], captured["n"] = fun, jac, x0.size
        return real(fun, x0, jac=jac, **kw)

    monkeypatch.setattr(rep_mod, "least_squares", spy)
    repair_angles(z, q, mov, rings=1)
    f, jac, n = captured["f"], captured["j"], captured["n"]
    x = np.random.default_rng(1).normal(scale=0.03, size=n)
    jx = jac(x).toarray()
    eps = 1e-7
    num = np.column_stack([(f(x + eps * e) - f(x - eps * e)) / (2 * eps) for e in np.eye(n)])
    assert np.abs(jx - num).max() <= 1e-5 * max(1.0, np.abs(num).max())
