"""Reading polygons and reading/writing quad meshes.

Polygons (:func:`read_polygon`), chosen by the file's extension (and, for ``.json``, by its
content):

* JSON ``{"vertices": [[x, y], ...]}`` (other keys ignored) or a bare list of pairs;
* CSV/TXT with two numeric columns separated by commas, semicolons, spaces or tabs (a header
  line and ``#`` comments are allowed);
* GeoJSON Polygon / MultiPolygon / Feature / FeatureCollection: the largest exterior ring;
* SVG: the first closed ``<path>`` (commands M L H V C S Q T Z, absolute and relative; curves
  flattened), or else the first ``<polygon>``; the y axis is flipped so the outline looks as
  drawn.

Meshes (:func:`write_mesh`, :func:`read_mesh`): JSON ``{"vertices": ..., "quads": ...}`` with
0-based indices (and ``"origin": [x, y]`` when the vertices are relative to it), and
through meshio VTK, VTU, MSH, OBJ, PLY and Medit (:data:`MESH_FORMATS`).
Every failure raises :class:`~quadmesh.errors.InputFormatError` naming the file.

Per-quad data (:func:`result_cell_data`: corner angles, worst deviation from 90°, the part
each quad came from and its stage kind) goes into VTK/VTU/MSH files as cell data and into
JSON as ``"cell_data"``, so that ParaView (or a script) can colour and threshold by it.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from .errors import InputFormatError, MeshVerificationError
from .mesh import QuadMesh

__all__ = [
    "MESH_FORMATS",
    "read_mesh",
    "read_mesh_with_origin",
    "read_polygon",
    "result_cell_data",
    "write_mesh",
    "write_polygon",
]

CURVE_SEGMENTS = 8
"""Number of straight segments that replace one SVG Bézier curve."""

_CSV_EXT = {".csv", ".txt", ".dat", ".xy", ".tsv"}
MESH_FORMATS = (".json", ".vtk", ".vtu", ".msh", ".obj", ".ply", ".mesh")
"""Mesh file extensions :func:`write_mesh` and :func:`read_mesh` handle (all keep quads)."""


def _err(path: Path, message: str) -> InputFormatError:
    return InputFormatError(f"{path}: {message}")


def _pairs(data: object, path: Path, what: str) -> np.ndarray:
    """(n, 2) float array from a nested list of pairs, or InputFormatError."""
    try:
        arr = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise _err(path, f"{what} must be a list of [x, y] number pairs ({exc})") from exc
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise _err(
            path, f"{what} must be a list of [x, y] pairs, got an array of shape {arr.shape}"
        )
    if arr.shape[0] < 3:
        raise _err(path, f"{what} has {arr.shape[0]} points; a polygon needs at least 3")
    if not np.all(np.isfinite(arr)):
        raise _err(path, f"{what} contains a non-finite coordinate")
    return arr


def _drop_closing(arr: np.ndarray) -> np.ndarray:
    if arr.shape[0] > 3 and np.array_equal(arr[0], arr[-1]):
        return arr[:-1]
    return arr


def read_polygon(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """Read polygon vertices from ``path``.

    Returns:
        ``(vertices, notes)``: an (n, 2) float64 array (closing point dropped; orientation as
        in the file, :func:`quadmesh.polygon.validate_polygon` makes it counter-clockwise) and
        human-readable notes about choices made while reading.

    Raises:
        InputFormatError: the file is missing or cannot be understood.
    """
    path = Path(path)
    if not path.is_file():
        raise _err(path, "no such file")
    ext = path.suffix.lower()
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise _err(path, f"cannot read the file as text ({exc})") from exc
    if ext in (".json", ".geojson"):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise _err(path, f"invalid JSON ({exc})") from exc
        if ext == ".geojson" or (
            isinstance(data, dict) and "type" in data and "vertices" not in data
        ):
            return _read_geojson(data, path)
        if isinstance(data, dict):
            if "vertices" not in data:
                raise _err(path, 'expected a JSON object with a "vertices" key')
            data = data["vertices"]
        return _drop_closing(_pairs(data, path, "vertices")), []
    if ext in _CSV_EXT:
        return _read_columns(text, path)
    if ext == ".svg":
        return _read_svg(text, path)
    raise _err(
        path,
        f"unknown polygon file type {ext!r} (use .json, .geojson, .csv, .txt or .svg)",
    )


# ----------------------------------------------------------------------------- CSV / TXT
def _read_columns(text: str, path: Path) -> tuple[np.ndarray, list[str]]:
    notes: list[str] = []
    rows: list[tuple[float, float]] = []
    seen_data = False
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f for f in re.split(r"[,;\s]+", line) if f]
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if not seen_data and not rows and not notes:
                notes.append(f"skipped header line {lineno}: {line[:60]!r}")
                continue
            raise _err(path, f"line {lineno}: not two numbers: {line[:60]!r}") from None
        if len(values) != 2:
            raise _err(path, f"line {lineno}: expected 2 columns, found {len(values)}")
        seen_data = True
        rows.append((values[0], values[1]))
    if not rows:
        raise _err(path, "no coordinate lines found")
    return _drop_closing(_pairs(rows, path, "the coordinates")), notes


# ----------------------------------------------------------------------------- GeoJSON
def _ring_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))


def _read_geojson(data: object, path: Path) -> tuple[np.ndarray, list[str]]:
    polygons: list[list] = []  # each: list of rings (exterior first)

    def collect(obj: object) -> None:
        if not isinstance(obj, dict):
            raise _err(path, "GeoJSON object expected")
        kind = obj.get("type")
        if kind == "FeatureCollection":
            for feat in obj.get("features") or []:
                collect(feat)
        elif kind == "Feature":
            if obj.get("geometry") is not None:
                collect(obj["geometry"])
        elif kind == "GeometryCollection":
            for geom in obj.get("geometries") or []:
                collect(geom)
        elif kind == "Polygon":
            polygons.append(obj.get("coordinates") or [])
        elif kind == "MultiPolygon":
            polygons.extend(obj.get("coordinates") or [])
        elif kind in ("Point", "MultiPoint", "LineString", "MultiLineString"):
            pass
        else:
            raise _err(path, f"unknown GeoJSON type {kind!r}")

    collect(data)
    rings = []
    n_holes = 0
    for poly in polygons:
        if not poly:
            continue
        try:
            ring = np.asarray([p[:2] for p in poly[0]], dtype=np.float64)
        except (TypeError, ValueError, IndexError) as exc:
            raise _err(path, f"malformed GeoJSON polygon coordinates ({exc})") from exc
        rings.append(ring)
        n_holes += len(poly) - 1
    if not rings:
        raise _err(path, "the GeoJSON holds no Polygon or MultiPolygon")
    areas = [(_ring_area(r) if r.ndim == 2 and r.shape[0] >= 3 else -1.0) for r in rings]
    k = int(np.argmax(areas))
    ring = _drop_closing(_pairs(rings[k], path, "the GeoJSON exterior ring"))
    notes = []
    if len(rings) > 1:
        notes.append(f"GeoJSON: used the largest of {len(rings)} polygons (number {k + 1})")
    else:
        notes.append("GeoJSON: used the polygon's exterior ring")
    if n_holes:
        notes.append(f"GeoJSON: ignored {n_holes} interior ring(s) (holes)")
    return ring, notes


# ----------------------------------------------------------------------------- SVG
_SVG_TOKEN = re.compile(r"([MmLlHhVvCcSsQqTtZzAa])|([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_SVG_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "Z": 0, "A": 7}


def _bezier(ctrl: list[complex], m: int) -> list[complex]:
    """Points at t = 1/m, ..., 1 of the Bézier curve with control points ``ctrl``."""
    t = np.arange(1, m + 1) / m
    if len(ctrl) == 3:
        p0, p1, p2 = ctrl
        pts = (1 - t) ** 2 * p0 + 2 * (1 - t) * t * p1 + t**2 * p2
    else:
        p0, p1, p2, p3 = ctrl
        pts = (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3
    return list(pts)


def _parse_path(d: str, path: Path) -> tuple[list[complex] | None, int]:
    """Points of the first closed subpath of the path data ``d`` (None if none is closed)
    and the number of curves flattened."""
    tokens = []
    pos = 0
    for m in _SVG_TOKEN.finditer(d):
        gap = d[pos : m.start()]
        if gap.strip(" \t\r\n,"):
            raise _err(path, f"cannot parse SVG path data near {d[pos : pos + 20]!r}")
        tokens.append(m.group(1) or float(m.group(2)))
        pos = m.end()
    if d[pos:].strip(" \t\r\n,"):
        raise _err(path, f"cannot parse SVG path data near {d[pos : pos + 20]!r}")
    cur = 0j
    start = 0j
    pts: list[complex] = []
    last_ctrl: complex | None = None
    last_cmd = ""
    curves = 0
    i = 0
    cmd = ""
    while i < len(tokens):
        tok = tokens[i]
        if isinstance(tok, str):
            cmd = tok
            i += 1
            if cmd in "Zz":
                if len(pts) >= 3:
                    return pts, curves
                pts, cur = [], start
                last_cmd = "Z"
                continue
        elif not cmd or cmd in "Zz":
            raise _err(path, "SVG path data must start with a command")
        up = cmd.upper()
        if up == "A":
            raise _err(path, "SVG arcs (A/a) are not supported; convert them to curves")
        nargs = _SVG_ARGS[up]
        args = tokens[i : i + nargs]
        if len(args) < nargs or any(isinstance(a, str) for a in args):
            raise _err(path, f"SVG command {cmd!r} needs {nargs} numbers")
        i += nargs
        rel = cmd.islower()
        base = cur if rel else 0j

        def pt(k: int, base: complex = base, args: list = args) -> complex:
            return base + complex(args[k], args[k + 1])

        if up == "M":
            cur = pt(0)
            start = cur
            pts = [cur]
            cmd = "l" if rel else "L"  # further pairs are line-tos
            last_ctrl = None
        elif up == "L":
            cur = pt(0)
            pts.append(cur)
        elif up == "H":
            cur = complex(args[0] + (cur.real if rel else 0.0), cur.imag)
            pts.append(cur)
        elif up == "V":
            cur = complex(cur.real, args[0] + (cur.imag if rel else 0.0))
            pts.append(cur)
        elif up in "CS":
            if up == "C":
                c1, c2, end = pt(0), pt(2), pt(4)
            else:
                c1 = 2 * cur - last_ctrl if last_cmd in "CS" and last_ctrl is not None else cur
                c2, end = pt(0), pt(2)
            pts.extend(_bezier([cur, c1, c2, end], CURVE_SEGMENTS))
            last_ctrl, cur = c2, end
            curves += 1
        elif up in "QT":
            if up == "Q":
                c1, end = pt(0), pt(2)
            else:
                c1 = 2 * cur - last_ctrl if last_cmd in "QT" and last_ctrl is not None else cur
                end = pt(0)
            pts.extend(_bezier([cur, c1, end], CURVE_SEGMENTS))
            last_ctrl, cur = c1, end
            curves += 1
        last_cmd = up
    return None, curves


def _read_svg(text: str, path: Path) -> tuple[np.ndarray, list[str]]:
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise _err(path, f"invalid SVG/XML ({exc})") from exc
    notes: list[str] = []
    transformed = False
    for el in root.iter():
        tag = el.tag.rsplit("}", 1)[-1]
        if el.get("transform"):
            transformed = True
        if tag == "path" and el.get("d"):
            pts, curves = _parse_path(el.get("d", ""), path)
            if pts is None:
                continue
            notes.append(f"SVG: used the first closed path (id={el.get('id', '-')!s})")
            if curves:
                notes.append(
                    f"SVG: flattened {curves} curve(s) into {CURVE_SEGMENTS} segments each"
                )
            break
        if tag == "polygon" and el.get("points"):
            nums = [float(v) for v in re.split(r"[\s,]+", el.get("points", "").strip()) if v]
            if len(nums) % 2:
                raise _err(path, "SVG polygon points must come in x,y pairs")
            pts = [complex(nums[k], nums[k + 1]) for k in range(0, len(nums), 2)]
            notes.append("SVG: used the first <polygon> element")
            break
    else:
        raise _err(path, "no closed path (a <path> whose data ends with Z) or <polygon> found")
    z = np.asarray(pts, dtype=np.complex128)
    keep = np.r_[True, z[1:] != z[:-1]]
    z = z[keep]
    arr = np.column_stack([z.real, -z.imag])
    notes.append("SVG: flipped the y axis (SVG y points down)")
    if transformed:
        notes.append("SVG: transform attributes were ignored")
    return _drop_closing(_pairs(arr, path, "the SVG outline")), notes


# ----------------------------------------------------------------------------- writing
def write_polygon(
    path: str | Path, vertices: object, *, name: str | None = None, description: str | None = None
) -> None:
    """Write polygon vertices as JSON ``{"name": ..., "description": ..., "vertices": ...}``."""
    path = Path(path)
    arr = np.asarray(vertices)
    if np.iscomplexobj(arr):
        arr = np.column_stack([arr.real, arr.imag])
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputFormatError(f"{path}: vertices must have shape (n, 2), got {arr.shape}")
    data: dict = {}
    if name is not None:
        data["name"] = name
    if description is not None:
        data["description"] = description
    data["vertices"] = arr.tolist()
    path.write_text(json.dumps(data, separators=(",", ":")) + "\n", encoding="utf-8")


STAGE_KINDS: dict[int, str] = {
    0: "disk",
    1: "sector",
    2: "channel",
    3: "corridor",
    4: "block",
}
"""Codes of the ``stage`` cell array (:attr:`quadmesh.result.MeshResult.quad_source`): the
disk mesh of a thick piece, a vertex sector, a channel connector, a corridor ladder, a block of
``method="blocks"``."""

_CELL_DATA_FORMATS = (".json", ".vtk", ".vtu", ".msh")


def quad_part_index(result: object) -> np.ndarray | None:
    """Per final quad, the index of the part it came from: thick pieces first (``k`` for
    ``result.pieces[k]``), then thin parts (``len(pieces) + j`` for ``result.thin[j]``;
    a conformal collar is a thin part of its own), in the order the mesh was assembled.
    None when the counts do not add up to the mesh's quads (then nothing can be told)."""
    pieces = tuple(getattr(result, "pieces", ()) or ())
    thin = tuple(getattr(result, "thin", ()) or ())
    mesh = getattr(result, "mesh", None)
    if mesh is None:
        return None
    counts = [len(np.asarray(p.disk.quads)) for p in pieces]
    counts += [len(np.asarray(t.mesh.quads)) for t in thin]
    total = sum(counts)
    if total == 0 or mesh.n_quads % total:
        return None
    per = mesh.n_quads // total  # refine × refine sub-quads per assembled quad, consecutive
    refine = int(getattr(getattr(result, "options", None), "refine", 1) or 1)
    if per != refine * refine:
        return None
    part = np.repeat(np.arange(len(counts), dtype=np.int32), counts)
    return np.repeat(part, per)


def result_cell_data(result: object) -> dict[str, np.ndarray]:
    """Per-quad arrays of a :class:`~quadmesh.result.MeshResult` (or of anything with a
    ``mesh``), for :func:`write_mesh`'s ``cell_data``:

    * ``angle_0`` … ``angle_3``: the corner angles in degrees at ``quads[:, k]``;
    * ``min_angle``, ``max_angle``: the smallest and largest of the four;
    * ``worst_deviation``: max |angle − 90°| (0 for a rectangle; 30 at the [60°, 120°] limits);
    * ``stage``: the stage kind (:data:`STAGE_KINDS`: 0 disk/thick piece, 1 vertex sector,
      2 channel, 3 corridor, 4 block), when the result has ``quad_source``;
    * ``piece``: the part index (:func:`quad_part_index`), when it can be told.
    """
    mesh = result.mesh  # type: ignore[attr-defined]
    ang = np.asarray(mesh.angles(), dtype=np.float64).reshape(-1, 4)
    data: dict[str, np.ndarray] = {f"angle_{k}": ang[:, k].copy() for k in range(4)}
    data["min_angle"] = ang.min(axis=1)
    data["max_angle"] = ang.max(axis=1)
    data["worst_deviation"] = np.abs(ang - 90.0).max(axis=1)
    src = getattr(result, "quad_source", None)
    if src is not None and len(src) == mesh.n_quads:
        data["stage"] = np.asarray(src, dtype=np.int32)
    part = quad_part_index(result)
    if part is not None:
        data["piece"] = part
    return data


def _check_cell_data(path: Path, n_quads: int, cell_data: dict | None) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name, values in (cell_data or {}).items():
        arr = np.asarray(values)
        if arr.ndim != 1 or arr.shape[0] != n_quads:
            raise InputFormatError(
                f"{path}: cell data {name!r} has shape {arr.shape}; it needs one value per "
                f"quad ({n_quads})"
            )
        if not np.issubdtype(arr.dtype, np.number):
            raise InputFormatError(f"{path}: cell data {name!r} must be numbers")
        out[str(name)] = arr
    return out


def write_mesh(
    path: str | Path,
    mesh: QuadMesh,
    origin: complex = 0j,
    cell_data: dict[str, np.ndarray] | None = None,
) -> None:
    """Write ``mesh``: ``.json`` as ``{"vertices": [[x, y], ...], "quads": [[i, j, k, l], ...]}``
    (0-based); ``.vtk``, ``.vtu``, ``.msh`` (Gmsh 2.2), ``.obj``, ``.ply``, ``.mesh`` (Medit)
    through meshio with z = 0. Other extensions raise :class:`InputFormatError`.

    ``origin``: the vertices are relative to this point (a mesh far from (0, 0), see
    :attr:`quadmesh.result.MeshResult.mesh_origin`). JSON then also holds
    ``"origin": [x, y]``; the other formats have no place for it and store the relative
    coordinates only (the caller tells the user the origin).

    ``cell_data``: optional per-quad arrays (name -> one number per quad, e.g.
    :func:`result_cell_data`), written as cell data in ``.vtk``, ``.vtu`` and ``.msh`` and as
    ``"cell_data": {name: [...]}`` in JSON; OBJ, PLY and Medit files get the mesh only. An
    array of the wrong length raises :class:`InputFormatError`."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in MESH_FORMATS:
        raise InputFormatError(
            f"{path}: unsupported mesh format {ext!r} (use {', '.join(MESH_FORMATS)})"
        )
    cells = _check_cell_data(path, mesh.n_quads, cell_data)
    if ext not in _CELL_DATA_FORMATS:
        cells = {}
    if ext == ".json":
        data: dict = {}
        if origin:
            data["origin"] = [complex(origin).real, complex(origin).imag]
        data["vertices"] = mesh.vertices.tolist()
        data["quads"] = mesh.quads.tolist()
        if cells:
            data["cell_data"] = {k: v.tolist() for k, v in cells.items()}
        path.write_text(json.dumps(data, separators=(",", ":")) + "\n", encoding="utf-8")
        return
    import meshio

    points = np.column_stack([mesh.vertices, np.zeros(mesh.n_vertices)])
    if ext == ".msh" and cells:
        # meshio's ASCII Gmsh writer prints each value's repr: numpy scalars would come out
        # as "np.float64(1.5)", which no reader parses; Python floats print plainly
        cells = {k: np.array(v.astype(np.float64).tolist(), dtype=object) for k, v in cells.items()}
    m = meshio.Mesh(
        points,
        [("quad", np.asarray(mesh.quads, dtype=np.int64))],
        cell_data={k: [v] for k, v in cells.items()},
    )
    try:
        if ext == ".msh":
            meshio.write(path, m, file_format="gmsh22", binary=False)
        else:
            meshio.write(path, m)
    except Exception as exc:  # meshio's writers raise assorted errors
        raise InputFormatError(f"{path}: cannot write a mesh in this format ({exc})") from exc


def read_mesh(path: str | Path) -> QuadMesh:
    """Read a quad mesh written by :func:`write_mesh` (JSON or any meshio format), with its
    vertices as stored (relative to the file's ``"origin"`` when a JSON file has one; see
    :func:`read_mesh_with_origin`).

    Only quad cells are kept; a file without quads raises :class:`InputFormatError`."""
    return read_mesh_with_origin(path)[0]


def read_mesh_with_origin(path: str | Path) -> tuple[QuadMesh, complex]:
    """Read a quad mesh and the origin its vertices are relative to (JSON ``"origin"``,
    0 when absent or for the other formats)."""
    path = Path(path)
    origin = 0j
    if not path.is_file():
        raise _err(path, "no such file")
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(path.read_text(encoding="utf-8-sig"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise _err(path, f"invalid JSON ({exc})") from exc
        if not isinstance(data, dict) or "vertices" not in data or "quads" not in data:
            raise _err(path, 'expected a JSON object with "vertices" and "quads"')
        if data.get("origin") is not None:
            try:
                ox, oy = (float(c) for c in data["origin"])
            except (TypeError, ValueError) as exc:
                raise _err(path, f'"origin" must be an [x, y] pair ({exc})') from exc
            if not (np.isfinite(ox) and np.isfinite(oy)):
                raise _err(path, '"origin" must be finite')
            origin = complex(ox, oy)
        try:
            verts = np.asarray(data["vertices"], dtype=np.float64).reshape(-1, 2)
            quads = np.asarray(data["quads"], dtype=np.int64).reshape(-1, 4)
        except (TypeError, ValueError) as exc:
            raise _err(path, f"vertices must be [x, y] pairs and quads 4 indices ({exc})") from exc
    else:
        import meshio

        try:
            m = meshio.read(path)
        except (Exception, SystemExit) as exc:  # meshio raises many kinds (even exits)
            raise _err(path, f"meshio cannot read it ({type(exc).__name__}: {exc})") from exc
        blocks = [c.data for c in m.cells if c.type == "quad"]
        if not blocks:
            raise _err(path, "the file holds no quad cells")
        verts = np.asarray(m.points[:, :2], dtype=np.float64)
        quads = np.vstack(blocks).astype(np.int64)
    try:
        return QuadMesh(verts, quads), origin
    except MeshVerificationError as exc:
        raise _err(path, str(exc)) from exc
