"""Reading polygons (JSON, CSV/TXT, GeoJSON, SVG) and reading/writing meshes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from quadmesh.errors import InputFormatError
from quadmesh.io import read_mesh, read_polygon, write_mesh, write_polygon
from quadmesh.polygon import validate_polygon
from tests.helpers import LSHAPE, lshape_mesh


# ----------------------------------------------------------------------------- polygons
def test_json_round_trip(tmp_path):
    p = tmp_path / "l.json"
    write_polygon(p, LSHAPE, name="L", description="an L")
    data = json.loads(p.read_text())
    assert data["name"] == "L" and data["description"] == "an L"
    verts, notes = read_polygon(p)
    np.testing.assert_array_equal(verts, LSHAPE)
    assert notes == []


def test_json_complex_input_and_bare_list(tmp_path):
    p = tmp_path / "c.json"
    write_polygon(p, LSHAPE[:, 0] + 1j * LSHAPE[:, 1])
    np.testing.assert_array_equal(read_polygon(p)[0], LSHAPE)
    q = tmp_path / "bare.json"
    q.write_text(json.dumps([*LSHAPE.tolist(), LSHAPE[0].tolist()]))
    verts, _ = read_polygon(q)
    np.testing.assert_array_equal(verts, LSHAPE)  # closing point dropped


@pytest.mark.parametrize(
    ("sep", "header"), [(",", True), (" ", False), ("\t", True), (";", False), (", ", False)]
)
def test_csv_variants(tmp_path, sep, header):
    lines = (["x,y"] if header else []) + ["# a comment"]
    lines += [sep.join(f"{v:.17g}" for v in row) for row in LSHAPE]
    p = tmp_path / "l.csv"
    p.write_text("\n".join(lines) + "\n")
    verts, notes = read_polygon(p)
    np.testing.assert_array_equal(verts, LSHAPE)
    assert bool(notes) == header
    txt = tmp_path / "l.txt"
    txt.write_text("\n".join(lines) + "\n")
    np.testing.assert_array_equal(read_polygon(txt)[0], LSHAPE)


def _geo_ring(arr: np.ndarray, scale: float = 1.0) -> list:
    ring = (arr * scale).tolist()
    return [*ring, ring[0]]


def test_geojson_polygon_feature_collection(tmp_path):
    hole = [[0.2, 0.2], [0.4, 0.2], [0.4, 0.4], [0.2, 0.2]]
    poly = {"type": "Polygon", "coordinates": [_geo_ring(LSHAPE), hole]}
    for obj in (
        poly,
        {"type": "Feature", "properties": {}, "geometry": poly},
        {"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": poly}]},
    ):
        p = tmp_path / "g.geojson"
        p.write_text(json.dumps(obj))
        verts, notes = read_polygon(p)
        np.testing.assert_array_equal(verts, LSHAPE)
        assert any("exterior ring" in n for n in notes)
        assert any("1 interior ring" in n for n in notes)


def test_geojson_multipolygon_largest(tmp_path):
    small = _geo_ring(LSHAPE, 0.5)
    big = _geo_ring(LSHAPE, 3.0)
    obj = {"type": "MultiPolygon", "coordinates": [[small], [big], [_geo_ring(LSHAPE)]]}
    p = tmp_path / "m.json"  # GeoJSON recognised by content in a .json file
    p.write_text(json.dumps(obj))
    verts, notes = read_polygon(p)
    np.testing.assert_allclose(verts, 3.0 * LSHAPE)
    assert any("largest of 3 polygons (number 2)" in n for n in notes)


def _svg(body: str) -> str:
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10">{body}</svg>'


def test_svg_absolute_and_relative(tmp_path):
    # the L-shape drawn with y pointing down: absolute, relative, H/V forms agree
    paths = [
        "M0 0 L2 0 L2 -1 L1 -1 L1 -2 L0 -2 Z",
        "m0,0 l2,0 0,-1 -1,0 0,-1 -1,0 z",
        "M0 0 H2 V-1 H1 V-2 H0 Z",
        "M 0 0 h 2 v -1 h -1 v -1 h -1 z",
    ]
    for d in paths:
        p = tmp_path / "s.svg"
        p.write_text(_svg(f'<path d="M5 5 L6 6" /><path id="outline" d="{d}" />'))
        verts, notes = read_polygon(p)
        np.testing.assert_allclose(verts, LSHAPE, atol=1e-15)
        assert any("flipped the y axis" in n for n in notes)
        assert any("id=outline" in n for n in notes)


def test_svg_curves_flattened(tmp_path):
    # a circle of radius 1 from four cubic Béziers (kappa), and a quadratic bump
    k = 0.5522847498
    d = f"M1 0 C1 {k} {k} 1 0 1 C{-k} 1 -1 {k} -1 0 C-1 {-k} {-k} -1 0 -1 c{k} 0 1 {1 - k} 1 1 Z"
    p = tmp_path / "c.svg"
    p.write_text(_svg(f'<g transform="scale(2)"><path d="{d}"/></g>'))
    verts, notes = read_polygon(p)
    assert verts.shape == (32, 2)
    np.testing.assert_allclose(np.hypot(verts[:, 0], verts[:, 1]), 1.0, atol=3e-4)
    assert any("flattened 4 curve" in n for n in notes)
    assert any("transform" in n for n in notes)
    pol = validate_polygon(verts)
    assert pol.area == pytest.approx(np.pi, rel=2e-2)
    # quadratic cap on a 4 x 2 rectangle: the 8-segment polygon misses 1/8² of the
    # parabolic segment's area 2/3 · 4 · 1 (Archimedes)
    q = tmp_path / "q.svg"
    q.write_text(_svg('<path d="M0 0 L4 0 L4 -2 Q2 -4 0 -2 Z"/>'))
    verts, _ = read_polygon(q)
    assert verts.shape == (3 + 8, 2)
    assert validate_polygon(verts).area == pytest.approx(8 + 8 / 3 * (1 - 1 / 64), rel=1e-12)
    # T reflects the previous control point: (3, 3) about (2, 2) gives (1, 1)
    t = tmp_path / "t.svg"
    t.write_text(_svg('<path d="M0 0 L4 0 L4 -2 Q3 -3 2 -2 T0 -2 Z"/>'))
    verts, _ = read_polygon(t)
    assert verts.shape == (3 + 16, 2)
    np.testing.assert_allclose(verts[3 + 11], [1.0, 1.5], atol=1e-15)  # t = 1/2 of the T curve
    assert validate_polygon(verts).area == pytest.approx(8.0, rel=1e-12)


def test_svg_polygon_element(tmp_path):
    p = tmp_path / "p.svg"
    p.write_text(_svg('<polygon points="0,0 2,0 2,-1 1,-1 1,-2 0,-2"/>'))
    np.testing.assert_allclose(read_polygon(p)[0], LSHAPE)


# ----------------------------------------------------------------------------- polygon errors
@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("bad.json", "{not json", "invalid JSON"),
        ("keys.json", '{"points": [[0, 0]]}', '"vertices" key'),
        ("shape.json", '{"vertices": [[0, 0, 1], [1, 0, 1], [1, 1, 1]]}', "shape"),
        ("two.json", '{"vertices": [[0, 0], [1, 0]]}', "at least 3"),
        ("text.json", '{"vertices": [["a", 0], [1, 0], [1, 1]]}', "number pairs"),
        ("cols.csv", "0 0\n1 0 5\n1 1\n", "line 2: expected 2 columns"),
        ("word.csv", "x y\n0 0\n1 oops\n", "line 3: not two numbers"),
        ("empty.txt", "# nothing\n", "no coordinate lines"),
        ("open.svg", _svg('<path d="M0 0 L1 0 L1 1"/>'), "no closed path"),
        ("arc.svg", _svg('<path d="M0 0 A1 1 0 0 1 1 1 Z"/>'), "arcs"),
        ("xml.svg", "<svg><path></svg>", "invalid SVG"),
        ("pt.geojson", '{"type": "Point", "coordinates": [0, 0]}', "no Polygon"),
        ("odd.geojson", '{"type": "Circle"}', "unknown GeoJSON type"),
        ("poly.dxf", "0\nSECTION\n", "unknown polygon file type"),
    ],
)
def test_polygon_errors(tmp_path, name, content, message):
    p = tmp_path / name
    p.write_text(content)
    with pytest.raises(InputFormatError, match=message) as info:
        read_polygon(p)
    assert name in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputFormatError, match="no such file"):
        read_polygon(tmp_path / "nope.json")
    with pytest.raises(InputFormatError, match="no such file"):
        read_mesh(tmp_path / "nope.vtk")


# ----------------------------------------------------------------------------- meshes
@pytest.mark.parametrize("ext", [".json", ".vtk", ".vtu", ".msh", ".obj", ".ply", ".mesh"])
def test_mesh_round_trip(tmp_path, ext):
    mesh = lshape_mesh()
    p = tmp_path / f"m{ext}"
    write_mesh(p, mesh)
    back = read_mesh(p)
    np.testing.assert_allclose(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.quads, mesh.quads)
    assert back.verify(LSHAPE).ok


def test_mesh_unsupported_format(tmp_path):
    with pytest.raises(InputFormatError, match=r"unsupported mesh format '\.stl'"):
        write_mesh(tmp_path / "m.stl", lshape_mesh())


def test_mesh_json_layout(tmp_path):
    p = tmp_path / "m.json"
    write_mesh(p, lshape_mesh())
    data = json.loads(p.read_text())
    assert data["quads"][0] == [0, 1, 4, 3]
    assert data["vertices"][7] == [1.0, 2.0]


def test_mesh_read_errors(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"vertices": [[0, 0]]}')
    with pytest.raises(InputFormatError, match='"quads"'):
        read_mesh(p)
    p.write_text('{"vertices": [[0, 0], [1, 0], [1, 1]], "quads": [[0, 1, 2, 3]]}')
    with pytest.raises(InputFormatError, match="indices"):
        read_mesh(p)
    v = tmp_path / "garbage.vtk"
    v.write_text("this is not vtk")
    with pytest.raises(InputFormatError, match="meshio cannot read"):
        read_mesh(v)
    import meshio

    tri = tmp_path / "tri.vtu"
    meshio.write(tri, meshio.Mesh(np.eye(3), [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(InputFormatError, match="no quad cells"):
        read_mesh(tri)


# ----------------------------------------------------------------------------- examples
def test_examples_valid():
    from quadmesh.examples import example_info, example_names, load_example

    names = example_names()
    assert len(names) >= 25
    sizes = []
    for name in names:
        info = example_info(name)
        verts = load_example(name)
        poly = validate_polygon(verts)
        assert info["name"] == name and info["description"]
        assert not poly.reversed_input, name  # stored counter-clockwise
        assert poly.n == verts.shape[0] == info["n"], name  # no repeats, nothing dropped
        suffix = name.rsplit("_", 1)[-1]
        if suffix.isdigit() and name.startswith(("star", "regular", "noisy")):
            assert poly.n == int(suffix), name
        sizes.append(poly.n)
    assert min(sizes) == 3 and max(sizes) == 1000


def test_examples_features():
    from quadmesh.examples import load_example

    def angles(name: str) -> np.ndarray:
        return np.degrees(validate_polygon(load_example(name)).angles)

    assert angles("corner_5deg").min() == pytest.approx(5.0)
    assert angles("slit_355deg").max() == pytest.approx(355.0)
    assert angles("right_triangle_10deg").min() == pytest.approx(10.0)
    np.testing.assert_allclose(angles("equilateral_triangle"), 60.0)
    star = validate_polygon(load_example("star_100")).z
    assert 0.6 - 1e-9 <= np.abs(star).min() and np.abs(star).max() <= 1.4 + 1e-9
    comb = load_example("comb")
    assert np.ptp(comb[:, 0]) > 1  # six teeth of width 0.05 and length 1
    with pytest.raises(InputFormatError, match="no example polygon named"):
        load_example("no_such_shape")
