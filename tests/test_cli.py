"""The ``quadmesh`` command line: check, info, error paths and exit codes; mesh and disk-demo."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from quadmesh.cli import EXIT_INPUT, EXIT_INVALID, EXIT_OK, main
from quadmesh.io import read_mesh, write_mesh, write_polygon
from quadmesh.mesh import QuadMesh
from tests.helpers import LSHAPE, lshape_mesh


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    poly = tmp_path / "l.json"
    write_polygon(poly, LSHAPE)
    good = tmp_path / "good.vtu"
    write_mesh(good, lshape_mesh())
    m = lshape_mesh()
    verts = m.vertices.copy()
    verts[1] = [0.3, 0.0]  # slide along the bottom side: angles 55° and 125° appear
    bad = tmp_path / "bad.json"
    write_mesh(bad, QuadMesh(verts, m.quads))
    holed = tmp_path / "holed.json"
    write_mesh(holed, QuadMesh(m.vertices, m.quads[:2]))
    return {"poly": poly, "good": good, "bad": bad, "holed": holed, "dir": tmp_path}


def test_check_valid(files, capsys):
    assert main(["check", str(files["good"]), "--polygon", str(files["poly"])]) == EXIT_OK
    out = capsys.readouterr().out
    assert out.startswith("mesh OK")
    assert "quads: 3" in out and "polygon vertices: 6" in out


def test_check_bad_angles(files, capsys):
    assert main(["check", str(files["bad"]), "--polygon", str(files["poly"])]) == EXIT_INVALID
    out = capsys.readouterr().out
    assert "mesh INVALID" in out
    assert "problem: angle:" in out
    # a generous tolerance accepts it
    rc = main(["check", str(files["bad"]), "--polygon", str(files["poly"]), "--angle-tol", "40"])
    assert rc == EXIT_OK


def test_check_hole(files, capsys):
    assert main(["check", str(files["holed"]), "--polygon", str(files["poly"])]) == EXIT_INVALID
    out = capsys.readouterr().out
    assert "problem: area" in out
    assert "boundary gap" in out


def test_check_input_errors(files, capsys):
    rc = main(["check", str(files["dir"] / "missing.json"), "--polygon", str(files["poly"])])
    assert rc == EXIT_INPUT
    assert "no such file" in capsys.readouterr().err
    selfcross = files["dir"] / "bow.json"
    write_polygon(selfcross, [[0, 0], [1, 1], [1, 0], [0, 1]])
    assert main(["check", str(files["good"]), "--polygon", str(selfcross)]) == EXIT_INPUT
    assert "not simple" in capsys.readouterr().err
    broken = files["dir"] / "broken.json"
    broken.write_text("{")
    assert main(["info", str(broken)]) == EXIT_INPUT
    assert "invalid JSON" in capsys.readouterr().err


def test_usage_errors(capsys):
    assert main([]) == EXIT_INPUT
    assert main(["frobnicate"]) == EXIT_INPUT
    assert main(["check", "m.json"]) == EXIT_INPUT  # --polygon missing
    capsys.readouterr()
    assert main(["--help"]) == EXIT_OK
    out = capsys.readouterr().out
    assert "exit codes:" in out and "3  a mesher stage failed" in out


def test_info(files, capsys):
    cw = files["dir"] / "cw.csv"
    cw.write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in LSHAPE[::-1]) + "\n")
    assert main(["info", str(cw)]) == EXIT_OK
    out = capsys.readouterr().out
    assert "vertices: 6" in out
    assert "area: 3 " in out
    assert "reflex: 1" in out
    assert "note: skipped header line 1" in out
    assert "clockwise and has been reversed" in out
    assert "interior angles: min 90.0000°  max 270.0000°" in out


def test_entry_point_subprocess(files):
    cmd = [sys.executable, "-m", "quadmesh.cli", "check", str(files["good"])]
    proc = subprocess.run(
        [*cmd, "--polygon", str(files["poly"])], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("mesh OK")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "quadmesh.cli",
            "check",
            str(files["holed"]),
            "--polygon",
            str(files["poly"]),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 1


def _mesher_available(rc: int, err: str) -> None:
    if rc == EXIT_INPUT and "a required module is missing" in err:
        pytest.skip(f"the mesher is not complete yet: {err.strip()}")


def test_mesh_command(files, capsys):
    square = files["dir"] / "square.json"
    write_polygon(square, [[0, 0], [1, 0], [1, 1], [0, 1]])
    out_mesh = files["dir"] / "square_mesh.json"
    rc = main(["mesh", str(square), "-o", str(out_mesh), "--stats"])
    captured = capsys.readouterr()
    _mesher_available(rc, captured.err)
    assert rc == EXIT_OK, captured.err
    assert "quads" in captured.out and "timings:" in captured.out
    mesh = read_mesh(out_mesh)
    report = mesh.verify([[0, 0], [1, 0], [1, 1], [0, 1]])
    assert report.ok, report.problems
    assert main(["check", str(out_mesh), "--polygon", str(square)]) == EXIT_OK
    data = json.loads(out_mesh.read_text())
    assert len(data["quads"]) == mesh.n_quads


def test_mesh_bad_output_format(files, capsys):
    rc = main(["mesh", str(files["poly"]), "-o", str(files["dir"] / "x.stl")])
    assert rc == EXIT_INPUT
    assert "unsupported mesh format" in capsys.readouterr().err


def test_mesh_bad_option(files, capsys):
    rc = main(["mesh", str(files["poly"]), "-o", str(files["dir"] / "x.json"), "--n", "0"])
    err = capsys.readouterr().err
    _mesher_available(rc, err)
    assert rc == EXIT_INPUT
    assert "n must be a positive integer" in err


def test_disk_demo(files, capsys):
    pytest.importorskip("quadmesh.disk.demo")
    png = files["dir"] / "disk.png"
    assert main(["disk-demo", "-o", str(png)]) == EXIT_OK
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bench_command_prints_rows(capsys) -> None:
    from quadmesh.cli import main

    assert main(["bench", "--max-n", "10"]) == 0
    out = capsys.readouterr().out
    row = [line for line in out.splitlines() if line.strip().startswith("10 ")]
    assert row, out
    fields = row[0].split()
    quads, per_vertex = int(fields[8]), float(fields[9])
    assert quads > 0 and per_vertex == pytest.approx(quads / 10, abs=1)
    # the last column: the process's peak resident memory in MB (an interpreter with numpy,
    # scipy and shapely loaded holds tens of MB at least)
    assert "peak MB" in out and 20 < float(fields[-1]) < 100_000


def test_info_lists_corridors(capsys):
    """`quadmesh info` says when a polygon is meshed as a corridor (ladder of straight cells)."""
    from quadmesh.examples import example_path

    assert main(["info", str(example_path("glyph_s"))]) == 0
    out = capsys.readouterr().out
    assert "corridor: yes" in out and "cells" in out
    assert main(["info", str(example_path("l_shape"))]) == 0
    assert "corridor" not in capsys.readouterr().out
