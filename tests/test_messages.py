"""Messages that reach a user speak about their polygon, never about files they do not have.

Every error, warning and printed message of the package (and of the app) is a string literal
somewhere in the source; none may cite a design note (``*.md``) or a section of one (``§``).
Docstrings and comments are for developers and are not checked.  Also: out-of-range options
are rejected when the options object is built (``ValueError``), not by a pipeline stage.
"""

from __future__ import annotations

import ast
import math
import pathlib
import re

import numpy as np
import pytest

from quadmesh.decompose import DecomposeOptions
from quadmesh.result import MeshOptions

ROOT = pathlib.Path(__file__).resolve().parent.parent
FORBIDDEN = re.compile(r"\.md\b|§|\b(?:ARCHITECTURE|CONFORMAL|DISK|THIN|CORRIDOR)\.md")


def _docstring_nodes(tree: ast.AST) -> set[int]:
    """ids of the Constant nodes that are docstrings (module, class, function, attribute)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        for stmt in body:  # first statement docstrings and attribute docstrings alike
            if (
                isinstance(stmt, ast.Expr)
                and isinstance(stmt.value, ast.Constant)
                and isinstance(stmt.value.value, str)
            ):
                out.add(id(stmt.value))
    return out


def _message_strings(path: pathlib.Path) -> list[tuple[int, str]]:
    """Every non-docstring string literal of a source file (f-string parts included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docs = _docstring_nodes(tree)
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs
    ]


def _sources() -> list[pathlib.Path]:
    return sorted([*(ROOT / "quadmesh").rglob("*.py"), *(ROOT / "app").rglob("*.py")])


def test_the_scanner_sees_messages_but_not_docstrings(tmp_path: pathlib.Path) -> None:
    src = tmp_path / "m.py"
    src.write_text(
        '"""Module notes (CONFORMAL.md §1)."""\n'
        "def f(x):\n"
        '    """See DISK.md §4."""\n'
        '    raise ValueError(f"bad {x}: split the polygon (CONFORMAL.md §1.8)")\n'
    )
    found = [s for _, s in _message_strings(src) if FORBIDDEN.search(s)]
    assert found == [": split the polygon (CONFORMAL.md §1.8)"]


def test_no_message_cites_a_design_note() -> None:
    bad = [
        f"{p.relative_to(ROOT)}:{line}: {s!r}"
        for p in _sources()
        for line, s in _message_strings(p)
        if FORBIDDEN.search(s)
    ]
    assert not bad, "messages cite files the user does not have:\n" + "\n".join(bad)


# --------------------------------------------------------------------------------------
# options are checked when they are built


@pytest.mark.parametrize(
    "kwargs",
    [
        {"delta": 0},
        {"delta": 1.0},
        {"delta": math.nan},
        {"kappa": 0.3},
        {"kappa": -1},
        {"crosscut_vertices": 1},
        {"crosscut_vertices": 2.5},
        {"overlap": 10.0},  # ≥ 1/δ: thick pieces would not be thick
        {"overlap": math.inf},
        {"min_overlap": 0},
        {"min_core": -1},
        {"parallel_tol": 0.6},
        {"center_tol": 0},
        {"crowding_gap": -1e-9},
        {"crowding_gap": math.nan},
        {"refine_delta": 1.0},
        {"refine_overlap": 0.0},
        {"refine_core": math.inf},
    ],
)
def test_decompose_options_reject_out_of_range_values(kwargs: dict) -> None:
    name = next(iter(kwargs))
    with pytest.raises(ValueError, match=name):
        DecomposeOptions(**kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"n": 0},
        {"n": 2.5},
        {"depth_step": 0},
        {"depth_step": math.nan},
        {"depth_growth": 0.5},
        {"depth_max": 0.5},
        {"inner_height": 3},
        {"crosscut_ratio": 2},
        {"crosscut_ratio": math.nan},
        {"arc_choice": "round"},
        {"lemma_A": 1},
        {"lemma_A": math.inf},
        {"rotations": 0},
        {"channel_delta": 0.8},  # the decomposition's overlap depth would exceed 1/δ
        {"channel_delta": 0},
        {"sector_ratio": 1},
        {"conformal_tol": 0},
        {"conformal_tol": 0.1},
        {"adaptive": "yes"},
        {"max_n": 1},
        {"max_n": 6.5},
    ],
)
def test_mesh_options_reject_out_of_range_values(kwargs: dict) -> None:
    name = next(iter(kwargs))
    with pytest.raises(ValueError, match=name):
        MeshOptions(**kwargs)


def test_every_accepted_channel_delta_gives_valid_decompose_options() -> None:
    for delta in (0.01, 0.15, 0.5, 0.749):
        opt = MeshOptions(channel_delta=delta)
        assert DecomposeOptions(delta=opt.channel_delta).overlap_depth < 1 / delta


# --------------------------------------------------------------------------------------
# refusals of mesh_polygon speak about the user's polygon and say what would help

#: Words that name the mesher's internals (or files the user does not have), not their polygon.
INTERNAL = re.compile(
    r"thick piece|\bpiece \d|Lemma|\bJ_|\bI_\d|γ_|\bchannel \d|\bvertex \d+:|\bA = \d|\.md\b|§"
)
#: A suggestion of what to change (the polygon or an option).
SUGGESTION = re.compile(r"\b(?:[Tt]ry|use|[Ww]iden|draw|lower|help)\b")
#: "vertex 7 at (1.5, -2)": a polygon vertex in the user's numbering and coordinates.
VERTEX_AT = re.compile(r"vertex (\d+) at \((-?[\d.e+-]+), (-?[\d.e+-]+)\)")
XY = r"\(-?[\d.e+-]+, -?[\d.e+-]+\)"


def _pen_arc(degrees: float, width: float = 0.5) -> np.ndarray:
    """A pen stroke along a circular arc of radius 3 with round caps at both ends (clockwise,
    as shapely writes it): a long curved corridor whose walls are chains of short edges."""
    import shapely

    a = np.radians(np.linspace(0.0, degrees, 60))
    line = shapely.LineString(np.column_stack([3 * np.cos(a), 3 * np.sin(a)]))
    g = line.buffer(width / 2, quad_segs=8).simplify(0.02 * width)
    return np.asarray(g.exterior.coords)[:-1]


def _star(shift: int = 7) -> np.ndarray:
    """A random 30-gon given clockwise and starting at another vertex, so that the user's
    numbering differs from the mesher's counter-clockwise one."""
    from quadmesh.outlines import random_star

    star = random_star(np.random.default_rng(5), 30)
    return np.roll(star[::-1], shift, axis=0)


def _sstroke() -> np.ndarray:
    from test_pipeline_thin import SSTROKE_6

    return np.array(SSTROKE_6)


def _squeezed_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Run the disk construction with a 40 times larger expansion factor than asked for, so
    that it genuinely refuses the arcs the pipeline chose (at A and at the fallback A)."""
    import quadmesh.disk as disk_pkg

    real = disk_pkg.disk_mesh

    def squeezed(intervals, *, A=None, **kw):
        return real(intervals, A=40 * A, **kw)

    monkeypatch.setattr(disk_pkg, "disk_mesh", squeezed)


def _coins_background() -> np.ndarray:
    """scikit-image "coins", contour 0 (303 vertices): a background region with a long tapering
    wedge of wavy walls — no ladder, no arm, too many vertices for a bridge, and crowded."""
    from quadmesh.families import FAMILIES

    return next(m for m in FAMILIES["images"](0) if m.name == "coins_0").vertices


#: name -> (polygon, options, stage of the refusal, what the message must say).
REFUSALS = {
    # a traced outline with a long wavy wedge: the corridor mesher finds no layout of straight
    # cells and the conformal map crowds (random walks with sharp kinks, refused so before,
    # now mesh by bridges)
    "curved_corridor": (
        _coins_background,
        MeshOptions(),
        "conformal",
        r"through vertices \d+ to \d+ \(around " + XY + r"\).*corridor.*would help",
    ),
    # the 331° end of an S stroke needs a finer crosscut than depth step 1 gives
    "thin_no_adaptive": (
        _sstroke,
        MeshOptions(lemma_A=16, crosscut_ratio=16, rotations=1, adaptive=False),
        "thin",
        r"^\[thin\] vertex 0 at \(-1\.1093, -0\.749982\):.*MeshOptions\(adaptive=True\)",
    ),
    # n = 2 pentagons pushed forward leave [60°, 120°] and nothing may raise n
    "disk_angles_no_adaptive": (
        _star,
        MeshOptions(n=2, adaptive=False, repair=False),
        "disk",
        r"pentagon cells \[.*\] in the part of the polygon through vertices .*adaptive=True",
    ),
    # so large an expansion factor that no arc fits between neighbouring vertices
    "no_arc_fits": (
        _star,
        MeshOptions(lemma_A=1e4),
        "disk",
        r"no arc of the disk construction fits around vertex \d+ at .*lower "
        r"MeshOptions\(lemma_A=10000\)",
    ),
    # the disk construction refuses the chosen arcs, also at the fallback spacing
    "disk_refuses_arcs": (
        _star,
        MeshOptions(),
        "disk",
        r"cannot place its arcs near vertex \d+ at .*lemma_A=16.*fewer, longer edges",
    ),
}


@pytest.mark.parametrize("name", list(REFUSALS))
def test_refusal_names_the_users_polygon_and_what_would_help(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each stage's refusal names the user's vertex numbers and coordinates (checked against
    the input points), never the mesher's internal objects, and suggests a change."""
    from quadmesh import QuadmeshError, mesh_polygon

    make, options, stage, must = REFUSALS[name]
    if name == "disk_refuses_arcs":
        _squeezed_disk(monkeypatch)
    points = make()
    with pytest.raises(QuadmeshError) as info:
        mesh_polygon(points, options)
    msg = str(info.value)
    assert info.value.stage == stage, msg
    assert re.search(must, msg, flags=re.S), msg
    assert not INTERNAL.search(msg), msg
    assert SUGGESTION.search(msg), msg
    # every "vertex k at (x, y)" is input point k, in the user's own coordinates
    named = VERTEX_AT.findall(msg)
    assert named or re.search(r"vertices \d+ to \d+", msg), msg
    for k, x, y in named:
        assert np.allclose(points[int(k)], [float(x), float(y)], rtol=1e-5, atol=1e-5), msg


def test_adaptive_fix_notes_name_the_users_polygon() -> None:
    """The adaptive loop's notes (MeshResult pieces' fixes) say where in the user's polygon
    it had to raise n, not which internal piece."""
    from quadmesh import mesh_polygon

    points = _star()
    r = mesh_polygon(points, MeshOptions(n=2, repair=False))
    notes = [f for p in r.pieces for f in p.fixes]
    assert any(
        re.search(r"pentagon cells .* in the part of the polygon through vertices .*: n raised", f)
        for f in notes
    ), notes
    for f in notes:
        assert not INTERNAL.search(f), f
        named = VERTEX_AT.findall(f)
        assert named or re.search(r"through vertices \d+ to \d+", f), f
        for k, x, y in named:
            assert np.allclose(points[int(k)], [float(x), float(y)], rtol=1e-5, atol=1e-5), f


def test_a_failure_carries_what_was_computed():
    """A run that fails after the decomposition attaches a PartialResult (polygon,
    decomposition, origin) to the exception, from which the plane layers that need only these
    can be drawn."""
    from quadmesh import mesh_polygon, validate_polygon
    from quadmesh.errors import PartialResult, QuadmeshError
    from quadmesh.render import build_layer

    with pytest.raises(QuadmeshError) as info:
        mesh_polygon(_star(), MeshOptions(n=2, adaptive=False, repair=False))
    partial = info.value.partial
    assert isinstance(partial, PartialResult) and len(partial.decomposition.thick) >= 1
    assert np.allclose(partial.polygon.z, validate_polygon(_star()).z)
    assert build_layer(partial, "thick_pieces").parts
