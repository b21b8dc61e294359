"""Batch meshing (quadmesh.batch, ``quadmesh batch``) and the ``bench --vs-gmsh`` helpers.

Every written mesh is re-read from its file with the json module and checked with plain numpy
(angles, orientation, conformity, area) independently of quadmesh.mesh, and with
QuadMesh.verify; parallel and threaded runs must give the same bytes as the serial run.
"""

from __future__ import annotations

import json
import shutil
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from quadmesh.batch import BatchResult, mesh_files, output_paths, polygon_files
from quadmesh.cli import EXIT_INPUT, EXIT_INVALID, main
from quadmesh.errors import InputFormatError
from quadmesh.examples import polygons_dir
from quadmesh.io import read_mesh_with_origin, read_polygon
from tests.helpers import require_pipeline

GOOD = ("square", "l_shape", "triangle")
BOW_TIE = [[0, 0], [1, 1], [1, 0], [0, 1]]  # edges 0 and 2 cross at (0.5, 0.5)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three good polygon files from resources/polygons and one self-intersecting one."""
    require_pipeline()
    d = tmp_path_factory.mktemp("polys")
    for name in GOOD:
        shutil.copy(polygons_dir() / f"{name}.json", d / f"{name}.json")
    (d / "bow_tie.json").write_text(json.dumps({"vertices": BOW_TIE}))
    (d / "readme.md").write_text("not a polygon file: skipped by polygon_files")
    return d


@pytest.fixture(scope="module")
def serial(folder: Path, tmp_path_factory: pytest.TempPathFactory) -> list[BatchResult]:
    """The batch run one file after the other in this process."""
    return mesh_files(polygon_files(folder), tmp_path_factory.mktemp("out1"), jobs=1)


def _polygon_angles(p: np.ndarray) -> np.ndarray:
    """Interior angles (degrees) of a counter-clockwise polygon p (n, 2)."""
    a = np.roll(p, 1, axis=0) - p
    b = np.roll(p, -1, axis=0) - p
    return np.degrees(np.arctan2(b[:, 0] * a[:, 1] - b[:, 1] * a[:, 0], (a * b).sum(1))) % 360


def _independent_check(mesh_file: Path, polygon_file: Path) -> int:
    """Check a written JSON mesh with plain numpy against its polygon: every quad
    counter-clockwise and convex; every new angle in [60°, 120°] (a polygon corner below 60°
    in a single quad is exempt); every edge in one or two quads, inner edges once in each
    direction; the boundary edges lie on the polygon's sides and add up to its perimeter;
    the quad areas add up to its area. Returns the number of quads."""
    data = json.loads(mesh_file.read_text())
    v = np.asarray(data["vertices"], float) + np.asarray(data.get("origin", [0.0, 0.0]))
    q = np.asarray(data["quads"], np.int64)
    poly = np.asarray(json.loads(polygon_file.read_text())["vertices"], float)
    assert q.ndim == 2 and q.shape[1] == 4 and q.min() >= 0 and q.max() < len(v)
    p = v[q]  # (Q, 4, 2)
    prev = np.roll(p, 1, axis=1) - p
    nxt = np.roll(p, -1, axis=1) - p
    cross = nxt[..., 0] * prev[..., 1] - nxt[..., 1] * prev[..., 0]
    ang = np.degrees(np.arctan2(cross, (prev * nxt).sum(-1)))
    assert np.all(cross > 0), "a quad is not convex and counter-clockwise"
    # exempt: an original polygon corner below 60° that lies in one quad only
    uses = np.bincount(q.ravel(), minlength=len(v))
    small = poly[_polygon_angles(poly) < 60.0]
    at_small = np.zeros(len(v), bool)
    for c in small:
        at_small |= np.hypot(*(v - c).T) < 1e-12
    exempt = at_small[q] & (uses[q] == 1)
    new = ang[~exempt]
    assert new.min() >= 60.0 - 1e-5 and new.max() <= 120.0 + 1e-5, (new.min(), new.max())
    # conformity
    e = np.stack([q, np.roll(q, -1, axis=1)], axis=-1).reshape(-1, 2)
    directed = {tuple(x) for x in e.tolist()}
    assert len(directed) == len(e), "an edge is used twice in the same direction"
    key = np.sort(e, axis=1)
    uniq, count = np.unique(key, axis=0, return_counts=True)
    assert count.max() <= 2
    boundary = uniq[count == 1]
    a, b = v[boundary[:, 0]], v[boundary[:, 1]]
    side_a, side_b = poly, np.roll(poly, -1, axis=0)
    diam = np.ptp(poly, axis=0).max()

    def dist_to_sides(x: np.ndarray) -> np.ndarray:
        d = side_b - side_a
        t = np.clip(((x[:, None] - side_a) * d).sum(-1) / (d * d).sum(-1), 0, 1)
        return np.hypot(*(x[:, None] - side_a - t[..., None] * d).transpose(2, 0, 1)).min(1)

    for x in (a, b, (a + b) / 2):
        assert dist_to_sides(x).max() < 1e-9 * diam
    perimeter = np.hypot(*(side_b - side_a).T).sum()
    assert np.hypot(*(b - a).T).sum() == pytest.approx(perimeter, rel=1e-12)
    x, y = p[..., 0], p[..., 1]
    quad_area = 0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum()
    px, py = poly.T
    area = 0.5 * (px * np.roll(py, -1) - np.roll(px, -1) * py).sum()
    assert quad_area == pytest.approx(area, rel=1e-9)
    return len(q)


def test_serial_batch_meshes_good_files_and_reports_the_bad_one(folder, serial) -> None:
    names = [r.path.name for r in serial]
    assert names == ["bow_tie.json", "l_shape.json", "square.json", "triangle.json"]
    bad, *good = serial
    assert bad.status == "failed" and bad.error == "PolygonError" and bad.stage == "validate"
    assert "not simple" in bad.message and bad.output is None
    assert not list(bad.path.parent.glob("*.partial*"))
    for r in good:
        assert r.ok and r.output.is_file() and r.output.suffix == ".json"
        assert r.output.stem == r.path.stem
        assert _independent_check(r.output, r.path) == r.quads
        mesh, origin = read_mesh_with_origin(r.output)
        report = mesh.verify(read_polygon(r.path)[0], origin=origin)
        assert report.ok, report.problems
        assert r.n == len(read_polygon(r.path)[0]) and r.quads == mesh.n_quads
        assert 60.0 - 1e-5 <= r.min_angle <= r.max_angle <= 120.0 + 1e-5
    assert sorted(p.name for p in good[0].output.parent.iterdir()) == [
        "l_shape.json",
        "square.json",
        "triangle.json",
    ]


def _same(a: list[BatchResult], b: list[BatchResult]) -> None:
    """The two runs wrote the same meshes (bytes, vertex arrays, quads) and statuses."""
    assert [r.status for r in a] == [r.status for r in b]
    assert [r.error for r in a] == [r.error for r in b]
    for ra, rb in zip(a, b):
        if not ra.ok:
            continue
        assert ra.output.read_bytes() == rb.output.read_bytes()
        ma, mb = read_mesh_with_origin(ra.output)[0], read_mesh_with_origin(rb.output)[0]
        assert ma.vertices.tobytes() == mb.vertices.tobytes()
        assert np.array_equal(ma.quads, mb.quads)
        assert (ra.quads, ra.min_angle, ra.max_angle) == (rb.quads, rb.min_angle, rb.max_angle)


def test_two_jobs_give_the_serial_meshes(folder, serial, tmp_path) -> None:
    files = polygon_files(folder)
    done: list[tuple[int, Path]] = []
    parallel = mesh_files(files, tmp_path, jobs=2, on_result=lambda i, r: done.append((i, r.path)))
    assert sorted(done) == list(enumerate(files))  # on_result gets the input's index
    assert [r.path for r in parallel] == files
    _same(serial, parallel)


def test_user_executor_threads(folder, serial, tmp_path) -> None:
    with ThreadPoolExecutor(2) as pool:
        threaded = mesh_files(polygon_files(folder), tmp_path, executor=pool, fmt=".json")
    _same(serial, threaded)


def test_timeout_stops_the_polygon_in_a_worker_process_and_in_a_thread(folder, tmp_path) -> None:
    lshape = [folder / "l_shape.json", folder / "bow_tie.json"]
    res = mesh_files(lshape, tmp_path / "p", jobs=1, timeout=0.01)
    assert [r.status for r in res] == ["timeout", "failed"]
    assert res[0].error == "Timeout" and "0.01 s" in res[0].message and res[0].output is None
    assert res[0].time < 5.0
    with ThreadPoolExecutor(1) as pool:
        (r,) = mesh_files(lshape[:1], tmp_path / "t", executor=pool, timeout=0.01)
    assert r.status == "timeout" and r.n == 6
    assert not any((tmp_path / "p").iterdir()) and not any((tmp_path / "t").iterdir())


def test_output_names_never_clash_nor_overwrite_inputs(tmp_path) -> None:
    paths = [tmp_path / "a.json", tmp_path / "a.csv", tmp_path / "sub" / "a.json"]
    outs = output_paths(paths, tmp_path / "out", "vtk")
    assert [o.name for o in outs] == ["a_json.vtk", "a_csv.vtk", "a_json_2.vtk"]
    with pytest.raises(InputFormatError, match="overwrite an input"):
        output_paths([tmp_path / "a.json"], tmp_path, "json")
    with pytest.raises(InputFormatError, match="unsupported mesh format"):
        output_paths([tmp_path / "a.json"], tmp_path / "out", "stl")


def test_cli_batch_end_to_end(folder, serial, tmp_path, capsys) -> None:
    src = tmp_path / "in"
    shutil.copytree(folder, src)
    (src / "garbage.csv").write_text("x,y\n1,2\nthree,four\n")
    out = tmp_path / "meshes"
    rc = main(["batch", str(src), "-o", str(out), "--jobs", "2", "--format", "vtk", "--stats"])
    cap = capsys.readouterr()
    assert rc == EXIT_INVALID
    assert sorted(p.name for p in out.iterdir()) == ["l_shape.vtk", "square.vtk", "triangle.vtk"]
    rows = {line.split()[0]: line for line in cap.out.splitlines() if ".json" in line[:20]}
    for r in serial[1:]:
        fields = rows[r.path.name].split()
        assert int(fields[1]) == r.n and int(fields[2]) == r.quads and fields[-1] == "meshed"
        mesh, _ = read_mesh_with_origin(out / f"{r.path.stem}.vtk")
        assert mesh.n_quads == r.quads
        assert mesh.verify(read_polygon(r.path)[0]).ok
    assert "failed: PolygonError [validate]" in rows["bow_tie.json"]
    assert "meshed 3 of 5 files" in cap.out and "mesher" in cap.out
    assert "bow_tie.json: PolygonError: the polygon is not simple" in cap.err
    assert "garbage.csv: InputFormatError" in cap.err

    assert main(["batch", str(src), "-o", str(src)]) == EXIT_INPUT  # would overwrite inputs
    assert "overwrite an input" in capsys.readouterr().err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["batch", str(empty), "-o", str(out)]) == EXIT_INPUT
    assert "no polygon files" in capsys.readouterr().err
    assert main(["batch", str(src), "-o", str(out), "--jobs", "0"]) == EXIT_INPUT


def test_cli_batch_all_good_exits_0_subprocess(folder, tmp_path) -> None:
    import subprocess

    cmd = [sys.executable, "-m", "quadmesh.cli", "batch", str(folder / "triangle.json")]
    proc = subprocess.run(
        [*cmd, "-o", str(tmp_path), "--timeout", "60"], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert "meshed 1 of 1 files" in proc.stdout
    assert _independent_check(tmp_path / "triangle.json", folder / "triangle.json") > 0


# ----------------------------------------------------------------------------- bench --vs-gmsh
def test_vs_gmsh_without_gmsh_prints_one_line_and_exits_0(monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "gmsh", None)  # import gmsh raises ImportError
    assert main(["bench", "--vs-gmsh", "--limit", "2"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and "Gmsh is not available" in out[0] and "quadmesh[gmsh]" in out[0]


def test_angle_stats_of_a_mixed_mesh() -> None:
    from quadmesh.benchmark import element_angles, quad_angle_stats

    # a 2 x 1 rectangle split into a square (kept clockwise), a 45° rhombus-like quad and a
    # triangle: angles computed whatever the element's orientation
    nodes = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1], [1.5, 1]], float)
    square_cw = np.array([[0, 5, 4, 1]])
    np.testing.assert_allclose(element_angles(nodes, square_cw), [[90, 90, 90, 90]])
    quads = np.array([[0, 1, 4, 5], [1, 2, 6, 4]])
    tris = np.array([[2, 3, 6]])
    ang = element_angles(nodes, quads)
    np.testing.assert_allclose(ang[1], [90, 63.434948822922, 116.565051177078, 90])
    np.testing.assert_allclose(ang.sum(1), 360)
    poly = np.array([[0, 0], [2, 0], [2, 1], [0, 1]], float)
    st = quad_angle_stats(nodes, quads, tris, poly)
    assert st["quads"] == 2 and st["triangles"] == 1 and st["share_ok"] == 1.0
    assert st["min"] == pytest.approx(63.434948822922) and st["max"] == pytest.approx(116.5650512)
    # a reflex quad corner is measured above 180°
    dart = np.array([[0, 0], [2, 1], [0, 2], [0.5, 1]], float)
    assert element_angles(dart, np.array([[0, 1, 2, 3]]))[0, 3] > 180
    # a 30° polygon corner left whole in one quad is original, not new
    t = np.array([[0, 0], [1, 0], [np.cos(np.pi / 6), np.sin(np.pi / 6)]], float)
    kite = np.vstack([t, [[0.9, 0.2]]])
    st = quad_angle_stats(kite, np.array([[0, 1, 3, 2]]), np.empty((0, 3), int), t)
    assert st["min"] > 30.0


def test_gmsh_quad_mesh_of_the_l_shape() -> None:
    pytest.importorskip("gmsh")
    from quadmesh.benchmark import gmsh_quad_mesh, quad_angle_stats

    poly = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], float)
    g = gmsh_quad_mesh(poly, 0.25)
    assert g["quads"].shape[1] == 4 and len(g["quads"]) > 20 and g["time"] > 0
    x, y = g["nodes"][g["quads"]].transpose(2, 0, 1)
    tx, ty = g["nodes"][g["triangles"]].transpose(2, 0, 1) if len(g["triangles"]) else (0, 0)
    area = 0.5 * np.abs((x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y).sum(1)).sum()
    if len(g["triangles"]):
        area += 0.5 * np.abs((tx * np.roll(ty, -1, 1) - np.roll(tx, -1, 1) * ty).sum(1)).sum()
    assert area == pytest.approx(3.0, rel=1e-9)
    st = quad_angle_stats(g["nodes"], g["quads"], g["triangles"], poly)
    assert 0 < st["share_ok"] <= 1 and st["min"] < 90 < st["max"]


def test_gmsh_leaves_a_broken_pipe_an_error_not_a_kill() -> None:
    """Gmsh's start-up sets SIGPIPE to its default action; after ``gmsh_quad_mesh`` a write to
    a closed pipe (a process pool's queue once its workers stopped) must raise BrokenPipeError
    as in any Python process, not kill it (this killed the test process, exit status 141).
    Run in a child process, so that a regression cannot take the test run with it."""
    pytest.importorskip("gmsh")
    import subprocess

    code = (
        "import os, numpy as np\n"
        "from quadmesh.benchmark import gmsh_quad_mesh\n"
        "gmsh_quad_mesh(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), 0.25)\n"
        "r, w = os.pipe()\n"
        "os.close(r)\n"
        "try:\n"
        "    os.write(w, b'x')\n"
        "except BrokenPipeError:\n"
        "    print('broken pipe')\n"
    )
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=root
    )
    assert done.returncode == 0 and done.stdout.strip() == "broken pipe", done.stderr


def test_cli_batch_blocks_with_a_size_relative_to_each_polygon(folder, tmp_path, capsys) -> None:
    """``--method blocks --size 0.1d``: every file is meshed by blocks at a tenth of its own
    diameter (the same quads as mesh_polygon with that absolute size), in two worker processes;
    the written meshes pass the independent check. An absolute ``--size`` is the same length
    for every file."""
    from quadmesh import MeshOptions, mesh_polygon
    from quadmesh.polygon import validate_polygon

    src = tmp_path / "in"
    src.mkdir()
    for name in ("l_shape", "octagon"):
        shutil.copy(polygons_dir() / f"{name}.json", src / f"{name}.json")
    out = tmp_path / "out"
    rc = main(
        ["batch", str(src), "-o", str(out), "-j", "2", "--method", "blocks", "--size", "0.1d"]
    )
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    for name in ("l_shape", "octagon"):
        verts = read_polygon(src / f"{name}.json")[0]
        d = validate_polygon(verts).diameter
        want = mesh_polygon(verts, MeshOptions(method="blocks", size=0.1 * d))
        assert want.blocks is not None and want.fallback is None
        assert _independent_check(out / f"{name}.json", src / f"{name}.json") == want.mesh.n_quads
    # an absolute size, serially: the options reach the mesher
    res = mesh_files(
        [src / "l_shape.json"], tmp_path / "abs", options=MeshOptions(method="blocks", size=0.25)
    )
    verts = read_polygon(src / "l_shape.json")[0]
    want = mesh_polygon(verts, MeshOptions(method="blocks", size=0.25))
    assert res[0].ok and res[0].quads == want.mesh.n_quads
    assert res[0].quads < mesh_polygon(verts).mesh.n_quads / 10  # not the paper's construction
