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
