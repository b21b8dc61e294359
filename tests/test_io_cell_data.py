"""Per-quad cell data in written meshes (:func:`quadmesh.io.result_cell_data`,
``write_mesh(..., cell_data=...)``): values match the result, JSON keeps them, refined meshes
keep the part of each sub-quad, wrong lengths are refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from quadmesh.errors import InputFormatError
from quadmesh.io import quad_part_index, result_cell_data, write_mesh
from tests.helpers import L_SHAPE, require_pipeline


@pytest.fixture(scope="module")
def results():
    require_pipeline()
    from quadmesh import MeshOptions, mesh_polygon

    return mesh_polygon(L_SHAPE), mesh_polygon(L_SHAPE, MeshOptions(refine=2))


def test_cell_data_values_and_parts(results):
    r, _ = results
    cd = result_cell_data(r)
    ang = r.mesh.angles()
    assert set(cd) == {
        "angle_0",
        "angle_1",
        "angle_2",
        "angle_3",
        "min_angle",
        "max_angle",
        "worst_deviation",
        "stage",
        "piece",
    }
    for v in cd.values():
        assert v.shape == (r.mesh.n_quads,)
    np.testing.assert_array_equal(cd["worst_deviation"], np.abs(ang - 90).max(axis=1))
    np.testing.assert_array_equal(cd["stage"], r.quad_source)
    counts = np.bincount(cd["piece"], minlength=len(r.pieces) + len(r.thin))
    assert counts.tolist() == [len(p.disk.quads) for p in r.pieces] + [
        len(t.mesh.quads) for t in r.thin
    ]
    # the stage of a part's quads is its kind
    kind_code = {"parabolic": 1, "hyperbolic": 2, "corridor": 3}
    for j, t in enumerate(r.thin):
        sel = cd["piece"] == len(r.pieces) + j
        assert np.all(cd["stage"][sel] == kind_code[t.kind])


def test_refined_mesh_keeps_each_sub_quad_part(results):
    r, r2 = results
    assert r2.mesh.n_quads == 4 * r.mesh.n_quads
    part2 = quad_part_index(r2)
    np.testing.assert_array_equal(part2, np.repeat(quad_part_index(r), 4))
    # each sub-quad lies inside its parent's part: its centroid is within the parent quad
    c2 = r2.mesh.z[r2.mesh.quads].mean(axis=1)
    parent = r.mesh.z[r.mesh.quads]
    for k in range(0, r.mesh.n_quads, max(r.mesh.n_quads // 25, 1)):
        sub = c2[4 * k : 4 * k + 4]
        d = np.abs(sub[:, None] - parent[k][None, :]).max()
        assert d <= np.abs(parent[k][:, None] - parent[k][None, :]).max()


def test_json_and_errors(results, tmp_path):
    r, _ = results
    cd = result_cell_data(r)
    p = tmp_path / "m.json"
    write_mesh(p, r.mesh, cell_data=cd)
    data = json.loads(p.read_text())
    assert data["cell_data"]["piece"] == cd["piece"].tolist()
    np.testing.assert_allclose(data["cell_data"]["angle_2"], cd["angle_2"])
    with pytest.raises(InputFormatError, match="one value per quad"):
        write_mesh(tmp_path / "bad.vtu", r.mesh, cell_data={"x": np.zeros(3)})
    # formats without cell data still write the mesh
    write_mesh(tmp_path / "m.obj", r.mesh, cell_data=cd)
    assert (tmp_path / "m.obj").stat().st_size > 0
