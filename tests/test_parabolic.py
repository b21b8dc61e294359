"""Tests of the parabolic thin-part mesh (quadmesh.thin.parabolic; THIN.md §A)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from quadmesh.errors import ThinPartError
from quadmesh.thin import KIND_NAMES, mesh2_local, mesh_vertex_sector, split_count
from quadmesh.thin.mesh import polygon_area, quad_angles_deg, quad_signed_areas, unpaired_edges
from tests.helpers import chain_edges, graded_u, uneven_u

THETAS = [5, 15, 30, 45, 59, 60, 61, 90, 119, 120, 121, 150, 179, 181, 200, 239, 240, 241, 300, 359]
CONN = KIND_NAMES.index("connection")


def make_gamma(
    u: np.ndarray,
    theta: float,
    wobble: float = 0.02,
    rot_err: float = 0.01,
    phase: float = 0.3,
    apex: complex = 0.3 + 0.2j,
    d1: complex = complex(np.exp(0.7j)),
) -> np.ndarray:
    """Crosscut at polar fractions u with a smooth radial wobble and a rotation error.

    The wobble of log-radius is ``wobble`` for theta >= 90° and scales with theta below (the
    power map z^(theta/π) scales log-radius and angle alike, so the chord tilt is kept).
    """
    psi = theta * (u + rot_err * np.sin(np.pi * u))
    a = wobble * min(1.0, theta / (np.pi / 2))
    rad = 1.0 + a * np.sin(2 * np.pi * u + phase) + 0.5 * a * np.cos(3 * np.pi * u)
    g = apex + d1 * rad * np.exp(1j * psi)
    g[0] = apex + d1 * rad[0]
    g[-1] = apex + d1 * rad[-1] * np.exp(1j * theta)
    return g


def check_sector(mesh, apex: complex, g: np.ndarray) -> tuple[float, float, float]:
    """Assert the THIN.md mesh checks; return (area error, min new angle, max new angle)."""
    z, q = mesh.vertices, mesh.quads
    assert np.all(z[mesh.gamma_index] == g)
    free, ok = unpaired_edges(q)
    assert ok, "an edge is used twice with the same orientation"
    allowed = chain_edges(mesh.side1, mesh.side2, mesh.gamma_index)
    free_set = {tuple(e) for e in free.tolist()}
    assert free_set <= allowed
    assert len(free_set) == len(mesh.side1) + len(mesh.side2) + len(g) - 3
    assert mesh.side1[0] == mesh.apex_index == mesh.side2[0]
    assert mesh.side1[-1] == mesh.gamma_index[0] and mesh.side2[-1] == mesh.gamma_index[-1]
    for chain, end in ((mesh.side1, g[0]), (mesh.side2, g[-1])):
        w = (z[chain] - apex) / (end - apex)
        assert np.all(np.abs(w.imag) < 1e-12) and np.all(np.diff(w.real) > 0)
    # areas about the apex: the shoelace sum of absolute coordinates cancels for tiny sectors
    areas = quad_signed_areas(z - apex, q)
    assert areas.min() > 0
    region = polygon_area(np.concatenate([[0.0], g - apex]))
    err = abs(areas.sum() - region) / region
    assert err < 1e-12
    ang = quad_angles_deg(z - apex, q)[mesh.new_angle_mask()]
    assert ang.min() >= 60.0 - 1e-7 and ang.max() <= 120.0 + 1e-7
    return err, float(ang.min()), float(ang.max())


@pytest.mark.parametrize("phi_deg", [0.5, 5.0, 15.0, 30.0, 45.0, 60.0])
def test_mesh2_angles_match_the_paper(phi_deg: float) -> None:
    phi = math.radians(phi_deg)
    loc = mesh2_local(phi)
    pts = loc["points"]
    names = list(pts)
    z = np.array([pts[n] for n in names])
    quads = np.array([[names.index(n) for n in q] for q in loc["quads"]])
    ang = quad_angles_deg(z, quads)
    th1, th2, th3 = 90 + phi_deg / 2, 120 - phi_deg, 90 - phi_deg / 4
    th4, th5 = 90 - phi_deg / 2, 90 + phi_deg / 2
    expected = [
        [th1, th1, th2, 60],
        [60, 60 + phi_deg, th2, 120],
        [60, 120, th5, th4],
        [120, 60 + phi_deg, th4, th4],
        [th5, 90, th3, th3],
        [90, th5, th3, th3],
    ]
    np.testing.assert_allclose(ang, expected, atol=1e-9)


def test_split_count() -> None:
    assert [split_count(math.radians(t)) for t in (5, 119.9, 120, 239.9, 240, 359)] == [
        1,
        1,
        2,
        2,
        3,
        3,
    ]


@pytest.mark.parametrize("theta_deg", THETAS)
def test_graded_crosscut(theta_deg: int, monkeypatch) -> None:
    import quadmesh.thin.parabolic as par

    monkeypatch.setattr(par, "_LAM_GROW", ())  # the tree's own bounds, at lam = 1/4
    theta = math.radians(theta_deg)
    u = graded_u()
    g = make_gamma(u, theta)
    mesh = mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)
    check_sector(mesh, 0.3 + 0.2j, g)
    # The crosscut is graded down to ~5e-4 theta; the depth-capped tree stops refining where the
    # connection chains can absorb the angular mismatch (the uncapped tree gave 1000-1170 quads).
    assert 350 < len(mesh.quads) < 700
    conn = mesh.angles_deg()[mesh.kind == CONN]
    assert 70.0 < conn.min() and conn.max() < 115.0


@pytest.mark.parametrize("n_pts", [13, 20, 40, 80])
def test_uneven_sweep(n_pts: int) -> None:
    for theta_deg in THETAS:
        theta = math.radians(theta_deg)
        g = make_gamma(uneven_u(n_pts), theta, rot_err=0.0)
        mesh = mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)
        check_sector(mesh, 0.3 + 0.2j, g)
        assert len(mesh.quads) < 12 * n_pts
        m = split_count(theta)
        # the apex angle is exempt exactly when m = 1
        assert mesh.exempt_apex == (m == 1)
        assert np.sum(mesh.kind == KIND_NAMES.index("mesh1")) == 3 * m


def test_forced_tree_uses_spiral_connection() -> None:
    # P = 4m + 1 leaves no freedom in the tree: the mismatch of ~13 deg between s_k and g_k
    # needs log-spiral chains through intermediate rings (straight segments reach 121.7 deg).
    theta = math.radians(359)
    g = make_gamma(uneven_u(13), theta, rot_err=0.0, apex=0j, d1=1.0)
    mesh = mesh_vertex_sector(0j, 1.0, theta, g)
    check_sector(mesh, 0j, g)
    assert np.sum(mesh.kind == CONN) > 12
    assert len(mesh.side1) > 6


def test_random_graded_crosscuts() -> None:
    rng = np.random.default_rng(7)
    for _ in range(25):
        theta = math.radians(rng.uniform(3.0, 359.5))
        u = graded_u(int(rng.integers(3, 7)), rng.uniform(0.1, 0.5), rng.uniform(4.0, 7.0))
        g = make_gamma(
            u, theta, rng.uniform(0, 0.02), rng.uniform(-0.03, 0.03), rng.uniform(0, 6), 0j, 1.0
        )
        check_sector(mesh_vertex_sector(0j, 1.0, theta, g), 0j, g)


def test_outer_vertices_follow_the_crosscut(monkeypatch) -> None:
    import quadmesh.thin.parabolic as par

    monkeypatch.setattr(par, "_LAM_GROW", ())  # the tree's own slope bound, at lam = 1/4
    theta = math.radians(90)
    g = make_gamma(graded_u(), theta, apex=0j, d1=1.0)
    mesh = mesh_vertex_sector(0j, 1.0, theta, g)
    conn = mesh.quads[mesh.kind == CONN]
    # first column of connection quads: (s_k, ., ., s_k+1); their angles follow g_k's
    s_k = mesh.vertices[conn[: len(g) - 1, 0]]
    mismatch = np.degrees(np.abs(np.angle(s_k) - np.angle(g[:-1])))
    # the depth-capped tree keeps s_k within _MISMATCH * log(1 / lam) of g_k's angle
    assert mismatch.max() <= math.degrees(0.15 * math.log(4.0)) + 1e-9
    assert mismatch[:3].max() < 1.5  # the first leaves still follow the grading at side 1
    # connection chains: slope <= 0.15 in log-polar coordinates, so angles stay near 90
    conn_ang = mesh.angles_deg()[mesh.kind == CONN]
    assert 75.0 < conn_ang.min() and conn_ang.max() < 105.0


def test_depth_cap_reduces_levels() -> None:
    # Every level is crossed by all chords, so the count of strip quads follows the depth of
    # the deepest leaf; a graded crosscut used to drive the tree 10+ levels deep.
    theta = math.radians(200)
    g = make_gamma(graded_u(), theta, apex=0j, d1=1.0)
    mesh = mesh_vertex_sector(0j, 1.0, theta, g)
    n_strip = int(np.sum(mesh.kind == KIND_NAMES.index("strip")))
    n_mesh2 = int(np.sum(mesh.kind == KIND_NAMES.index("mesh2")))
    assert n_mesh2 == 6 * (len(g) - 1 - 2 * split_count(theta))  # one Mesh 2 per refinement
    assert n_strip < 8 * len(g)
    assert len(mesh.quads) < 10 * len(g)


def test_refuses_too_few_vertices() -> None:
    theta = math.radians(200)
    g = make_gamma(np.linspace(0, 1, 8), theta)
    with pytest.raises(ThinPartError, match="at least 9"):
        mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)


def test_refuses_jagged_crosscut() -> None:
    theta = math.radians(90)
    u = np.linspace(0, 1, 30)
    g = np.exp(1j * theta * u) * (1 + 0.05 * (-1) ** np.arange(30))
    with pytest.raises(ThinPartError, match="tilted"):
        mesh_vertex_sector(0j, 1.0, theta, g)


def test_refuses_crosscut_off_the_side() -> None:
    theta = math.radians(90)
    g = np.exp(1j * theta * np.linspace(0, 1, 20))
    g[-1] *= np.exp(0.01j)
    with pytest.raises(ThinPartError, match="side 2"):
        mesh_vertex_sector(0j, 1.0, theta, g)


def test_refuses_too_coarse_crosscut() -> None:
    # N_side = 2 at theta = 343 deg: the crosscut's vertices are 57 deg apart at its top.
    theta = math.radians(343)
    g = make_gamma(graded_u(2, 0.35, 4.9), theta)
    with pytest.raises(ThinPartError, match="needs more vertices"):
        mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), theta, g)


# The 355° corner of the bundled example slit_355deg: apex, side-1 direction, angle and the
# crosscut's offsets g_k - apex as the pipeline produced them (P = 39; the crosscut lies at
# distance 7.4e-7 .. 1.2e-6 from the apex; the offsets are exact: apex + offset == g_k).
SLIT_APEX = 0.5 + 0.3j
SLIT_DIR = -0.0436193873653952 + 0.9990482215818552j
SLIT_THETA = 6.195918844579751
SLIT_OFFSETS = np.array(
    [
        (-3.2134884253576246e-08 + 7.360098554509698e-07j),
        (-3.6623749588571286e-08 + 7.358010471469889e-07j),
        (-6.467328683701368e-08 + 7.339142524265263e-07j),
        (-1.1948462236288648e-07 + 7.273042536559693e-07j),
        (-1.747368255644588e-07 + 7.166374353384519e-07j),
        (-2.1391845606011373e-07 + 7.065485032597962e-07j),
        (-2.608194856201784e-07 + 6.91586070522554e-07j),
        (-3.186735977878108e-07 + 6.685209606449583e-07j),
        (-3.8890890524667654e-07 + 6.329819149386573e-07j),
        (-4.648106153859466e-07 + 5.837888308324324e-07j),
        (-5.501515108474742e-07 + 5.116074401345649e-07j),
        (-6.33338358202451e-07 + 4.167757896023083e-07j),
        (-7.125957853792997e-07 + 2.8672695284726046e-07j),
        (-7.738037784976726e-07 + 1.1453731874055961e-07j),
        (-7.893754279675314e-07 - 1.7891978737472058e-07j),
        (-6.713281887060774e-07 - 5.192568596767977e-07j),
        (-3.7078548759117425e-07 - 8.211345454700592e-07j),
        (8.796020245505076e-08 - 9.590853816687783e-07j),
        (5.812646453051684e-07 - 8.477948041374361e-07j),
        (9.549715584977747e-07 - 5.190145997979734e-07j),
        (1.1301936304608518e-06 - 9.597221345414297e-08j),
        (1.1289807319014855e-06 + 3.018122455844541e-07j),
        (1.0210602515714484e-06 + 6.146088422087637e-07j),
        (8.706813379166789e-07 + 8.353067311728246e-07j),
        (7.178086357528812e-07 + 9.812168235145968e-07j),
        (5.812510009972627e-07 + 1.0741232742139672e-06j),
        (4.925461084548388e-07 + 1.1205085613807952e-06j),
        (4.168042810892558e-07 + 1.152754447397708e-06j),
        (3.5304008239034346e-07 + 1.175123146512913e-06j),
        (2.9588737759933537e-07 + 1.1916963282843085e-06j),
        (2.4926580877160376e-07 + 1.2028897676263917e-06j),
        (2.0846100401428203e-07 + 1.211025516534292e-06j),
        (1.7604644408919512e-07 + 1.2164070423148488e-06j),
        (1.5035597744628149e-07 + 1.2200021569097608e-06j),
        (1.292021412080402e-07 + 1.2225220245021262e-06j),
        (9.972472769792518e-08 + 1.22537536889622e-06j),
        (7.075506169851309e-08 + 1.2274379728172136e-06j),
        (5.59901230934301e-08 + 1.2282077386238655e-06j),
        (5.3629314100689385e-08 + 1.2283132358459348e-06j),
    ]
)


def test_slit_355_corner_in_its_own_frame() -> None:
    # The geometry of that corner is fine: in a frame of its own size the sector meshes with
    # every check passing (the uncapped tree gave 639 quads here).
    g = SLIT_OFFSETS / np.abs(SLIT_OFFSETS).min()
    mesh = mesh_vertex_sector(0j, SLIT_DIR, SLIT_THETA, g)
    check_sector(mesh, 0j, g)
    assert not mesh.exempt_apex and np.sum(mesh.kind == KIND_NAMES.index("mesh1")) == 9
    assert len(mesh.quads) < 450


def test_slit_355_corner_far_from_the_origin() -> None:
    # Regression: at apex 0.5 + 0.3i the shoelace sum of absolute coordinates (terms ~0.2)
    # cancelled for quads of area ~1e-20 and the sector was refused as "degenerate or
    # inverted". Areas are now taken about the apex. Scaled to radius 7e-4 the same crosscut
    # meshes at its real place; at its real radius 7e-7 the stored coordinates cannot carry
    # the exact 60/120 degree angles (rounding moves them by ~1e-6 degrees), and the angle
    # check accepts exactly the rounding slack 8 eps |z| / (shortest edge), as the verifier does.
    g = SLIT_APEX + 1e3 * SLIT_OFFSETS
    mesh = mesh_vertex_sector(SLIT_APEX, SLIT_DIR, SLIT_THETA, g)
    check_sector(mesh, SLIT_APEX, g)
    tiny = mesh_vertex_sector(SLIT_APEX, SLIT_DIR, SLIT_THETA, SLIT_APEX + SLIT_OFFSETS)
    from quadmesh.mesh import QuadMesh

    z = tiny.vertices
    qm = QuadMesh(np.column_stack([z.real, z.imag]), tiny.quads)
    ang = qm.angles()[tiny.new_angle_mask()]
    slack = np.broadcast_to(qm.angle_slack(), tiny.quads.shape)[tiny.new_angle_mask()]
    assert np.all(ang >= 60.0 - slack) and np.all(ang <= 120.0 + slack)
    assert np.all(qm.areas() > 0)


def test_sector_template_cache_keeps_the_mesh() -> None:
    # The tree part is numbered once per tree shape (parabolic._Template, cached); a sector
    # meshed from a cached template equals one meshed from a fresh template, field by field.
    from quadmesh.thin import parabolic

    cases = [(math.radians(t), make_gamma(graded_u(), math.radians(t))) for t in (45, 150, 300)]

    def mesh_all():
        return [mesh_vertex_sector(0.3 + 0.2j, complex(np.exp(0.7j)), t, g) for t, g in cases]

    parabolic._TEMPLATES.clear()
    fresh = mesh_all()
    cached = mesh_all()
    for a, b in zip(fresh, cached):
        for name in ("vertices", "quads", "kind", "gamma_index", "side1", "side2"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and np.array_equal(x, y), name
        assert a.apex_index == b.apex_index and a.exempt_apex == b.exempt_apex


def test_sector_template_merges_coinciding_radii() -> None:
    # Vertices are keyed by (ray, radius): radius ids whose radii are the same float are one
    # radius, so a template with such ids merges their vertices like a key by value would.
    from quadmesh.thin import parabolic

    assert parabolic._canonical([1.0, 0.5, 2.0]) is None
    assert parabolic._canonical([1.0, 0.5, 0.5, 2.0, 1.0]) == (0, 1, 1, 3, 0)
    theta = math.radians(150)
    g = make_gamma(graded_u(), theta, apex=0j, d1=1.0)
    psi = np.angle(g)
    psi[-1] = theta
    roots, _ = parabolic._build_tree(psi.tolist(), 2, theta / 2, None)
    _, depth = parabolic._leaves(roots)
    plain = parabolic._build_template(roots, 2, depth - 1, None)
    n_ids = 3 + 5 * (depth - 1)
    same = parabolic._build_template(roots, 2, depth - 1, tuple(range(n_ids)))
    assert same.n_vertices == plain.n_vertices and np.array_equal(same.quads, plain.quads)
    # the Mesh 1 radius s taken equal to r0: the Mesh 1 vertices at s on the sides merge
    merged = parabolic._build_template(roots, 2, depth - 1, (0, 0, *range(2, n_ids)))
    assert merged.n_vertices < plain.n_vertices


def _smallest_edge(mesh) -> float:
    z, q = mesh.vertices, mesh.quads
    return float(np.abs(z[q] - z[np.roll(q, -1, axis=1)]).min())


def test_sectors_grow_where_straight_chains_still_connect_them(monkeypatch) -> None:
    """A sector accepted at lam = 1/4 is built at 2.4 or 1.6 times that radius when its
    connection quads stay in [65°, 115°] with no more rings: the same quads, every tree quad
    larger (the smallest edges, at the apex, by the same factor), every angle in range."""
    import quadmesh.thin.parabolic as par

    apex, d1 = 0.3 + 0.2j, complex(np.exp(0.7j))
    grown = 0
    for theta_deg in THETAS:
        theta = math.radians(theta_deg)
        g = make_gamma(uneven_u(20), theta, rot_err=0.0)
        mesh = mesh_vertex_sector(apex, d1, theta, g)
        check_sector(mesh, apex, g)
        with monkeypatch.context() as mp:
            mp.setattr(par, "_LAM_GROW", ())
            plain = mesh_vertex_sector(apex, d1, theta, g)
        assert np.array_equal(mesh.quads, plain.quads)
        ratio = _smallest_edge(mesh) / _smallest_edge(plain)
        assert ratio >= 1.0 - 1e-12
        grown += ratio > 1.5
    assert grown >= len(THETAS) // 2
