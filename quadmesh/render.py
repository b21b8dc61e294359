"""Layers of a :class:`~quadmesh.result.MeshResult` as pyvista geometry.

The command line (off-screen PNGs) and the Qt viewer in ``app/`` both draw through this module,
so a layer looks the same everywhere.  pyvista is imported lazily inside the functions: importing
:mod:`quadmesh.render` costs nothing and the core stays free of VTK.

Two views:

* ``"plane"`` — the polygon and what the pipeline built in the plane: ``polygon``,
  ``thick_pieces``, ``thin_parts`` (parabolic vertex sectors and hyperbolic channels),
  ``crosscuts``, ``conformal_images`` (the disk pieces of Lemma 2.2 pushed forward by the
  conformal map, coloured by kind), ``final_mesh`` (coloured by corner angle or by each quad's
  worst deviation from 90°, with a colour bar), ``block_layout`` (for ``method="blocks"``: the
  straight cuts and the other inner edges of the coarse cells that the final mesh refines —
  with the polygon's outline, every coarse cell edge; empty for the paper's construction) and
  ``bad_quads`` (quads with a new angle outside [60°, 120°]; normally empty).
* ``"disk"`` — one thick piece in the unit disk: ``tessellation`` (the right-pentagon
  tessellation T5 of §2), ``region_w`` (right pentagons, Carleson quadrilaterals and Carleson
  triangles of Lemma 2.2, each in its own colour), ``disk_mesh`` (the quads of Lemmas 4.1, 5.1,
  6.1) and ``prevertices`` (the prevertices of the Schwarz–Christoffel map, the arcs I_j and the
  arcs J_j ⊇ √A·I_j).

Plane points are complex numbers; pyvista gets them as (x, y, 0) points.  A disk-view layer keeps
the complex disk coordinates of its points (:attr:`LayerPart.disk_z`) so that a viewer can move
them by a disk automorphism without rebuilding the geometry.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pyvista as pv

__all__ = [
    "BLOCK_COLORS",
    "DISK_LAYERS",
    "KIND_COLORS",
    "LAYER_COLORS",
    "LAYER_TITLES",
    "PLANE_LAYERS",
    "LayerGeometry",
    "LayerPart",
    "add_layer",
    "bad_quad_mask",
    "block_layout_edges",
    "build_disk_layer",
    "build_layer",
    "fit_camera",
    "geodesic_arc",
    "layer_names",
    "line_part",
    "points_part",
    "polygon_layer",
    "render_disk_png",
    "render_png",
    "unit_circle_part",
]

PLANE_LAYERS: tuple[str, ...] = (
    "polygon",
    "thick_pieces",
    "thin_parts",
    "crosscuts",
    "conformal_images",
    "final_mesh",
    "block_layout",
    "bad_quads",
)
DISK_LAYERS: tuple[str, ...] = ("tessellation", "region_w", "disk_mesh", "prevertices")

LAYER_TITLES: dict[str, str] = {
    "polygon": "Polygon",
    "thick_pieces": "Thick pieces",
    "thin_parts": "Thin parts",
    "crosscuts": "Crosscuts",
    "conformal_images": "Conformal images",
    "final_mesh": "Final mesh",
    "block_layout": "Block layout",
    "bad_quads": "Bad quads",
    "tessellation": "Tessellation T5",
    "region_w": "Region W pieces",
    "disk_mesh": "Disk mesh",
    "prevertices": "Prevertices, I_j, J_j",
}

#: Colours of the three kinds of disk pieces (Lemma 2.2), shared by both views.
KIND_COLORS: dict[str, str] = {
    "pentagon": "#9aa5b1",
    "carleson_quadrilateral": "#5b9bd5",
    "carleson_triangle": "#e06666",
}
#: Flat colour of each layer that has one (the viewer's colour swatches start from these).
LAYER_COLORS: dict[str, str] = {
    "polygon": "#000000",
    "crosscuts": "#d62728",
    "block_layout": "#009e73",
    "bad_quads": "#ff00ff",
    "tessellation": "#7f7f7f",
    "disk_mesh": "#000000",
    "prevertices": "#000000",
}
THIN_COLORS: dict[str, str] = {
    "parabolic": "#f0a030",
    "hyperbolic": "#8e63c7",
    "corridor": "#3aa37a",
}
PIECE_PALETTE: tuple[str, ...] = (
    "#8dd3c7",
    "#bebada",
    "#fb8072",
    "#80b1d3",
    "#fdb462",
    "#b3de69",
    "#fccde5",
    "#bc80bd",
    "#ccebc5",
    "#ffed6f",
)
ANGLE_MIN, ANGLE_MAX = 60.0, 120.0
#: Colours of the block layout's parts: the coarse cells' edges, the cuts on top, the faces
#: meshed by the paper's construction where no block layout closed, and the faces that did not
#: split with the others and were laid out on their own.
BLOCK_COLORS: dict[str, str] = {
    "cuts": LAYER_COLORS["block_layout"],
    "cell edges": "#0b3d91",
    "fallback faces": "#f08c2e",
    "local faces": "#5aae61",
}
CORNER_TITLE = "corner angle (deg)"
WORST_TITLE = "worst deviation from 90 (deg)"


@dataclass
class LayerPart:
    """One pyvista dataset of a layer with the style it is drawn in.

    Attributes:
        mesh: a ``pyvista.PolyData`` (quads/polygons, lines or vertices).
        color: flat colour (ignored when ``scalars`` is set).
        opacity: 0..1.
        style: ``"surface"``, ``"wireframe"`` or ``"points"``.
        line_width: width of lines in pixels.
        point_size: size of points in pixels (``style == "points"``).
        scalars: name of the point/cell array to colour by, or None.
        cmap: colour map for ``scalars``.
        clim: colour range for ``scalars``.
        scalar_bar_title: title of the colour bar (also its key in the plotter), or None.
        label: short human description of the part.
        disk_z: complex disk coordinates of ``mesh.points`` (disk view only), so that a viewer
            can apply a disk automorphism: ``mesh.points[:, :2] = disk_scale · g(disk_z)``.
        disk_scale: radial factor for marks drawn just outside T (arcs on T drawn at radius
            ``disk_scale``; ``disk_z`` then holds their points on T itself).
    """

    mesh: Any
    color: str | None = None
    opacity: float = 1.0
    style: str = "surface"
    line_width: float = 1.0
    point_size: float = 8.0
    scalars: str | None = None
    cmap: str | None = None
    clim: tuple[float, float] | None = None
    scalar_bar_title: str | None = None
    label: str = ""
    disk_z: np.ndarray | None = None
    disk_scale: float = 1.0

    @property
    def n_cells(self) -> int:
        """Number of cells of the dataset."""
        return int(self.mesh.n_cells)


@dataclass
class LayerGeometry:
    """Everything needed to draw one layer: its parts and which view it belongs to."""

    name: str
    view: str
    parts: list[LayerPart] = field(default_factory=list)

    @property
    def title(self) -> str:
        """Human title of the layer."""
        return LAYER_TITLES.get(self.name, self.name)

    @property
    def n_cells(self) -> int:
        """Total number of cells over all parts."""
        return sum(p.n_cells for p in self.parts)

    @property
    def scalar_bar_titles(self) -> list[str]:
        """Titles of the colour bars this layer shows."""
        return [p.scalar_bar_title for p in self.parts if p.scalar_bar_title]

    def part(self, label: str) -> LayerPart:
        """The part with the given label (KeyError if there is none)."""
        for p in self.parts:
            if p.label == label:
                return p
        raise KeyError(f"layer {self.name!r} has no part {label!r}")


# ----------------------------------------------------------------------------- geometry helpers
def _xyz(z: np.ndarray) -> np.ndarray:
    z = np.asarray(z, dtype=np.complex128).ravel()
    return np.column_stack([z.real, z.imag, np.zeros(z.shape[0])])


def _as_complex(points: Any) -> np.ndarray:
    arr = np.asarray(points)
    if np.iscomplexobj(arr):
        return arr.astype(np.complex128).ravel()
    arr = np.asarray(arr, dtype=np.float64)
    return arr[..., 0] + 1j * arr[..., 1]


def _cells(sizes: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """VTK cell array [size, i0, i1, ..] for cells of the given sizes and flat connectivity."""
    sizes = np.asarray(sizes, dtype=np.int64)
    conn = np.asarray(conn, dtype=np.int64)
    out = np.empty(sizes.size + conn.size, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes[:-1] + 1)]) if sizes.size else np.zeros(0, int)
    out[starts] = sizes
    mask = np.ones(out.size, dtype=bool)
    mask[starts] = False
    out[mask] = conn
    return out


def _quads_polydata(z: np.ndarray, quads: np.ndarray) -> pv.PolyData:
    import pyvista as pv

    quads = np.asarray(quads, dtype=np.int64).reshape(-1, 4)
    faces = np.column_stack([np.full(len(quads), 4, dtype=np.int64), quads]).ravel()
    return pv.PolyData(_xyz(z), faces=faces)


def _polylines_polydata(lines: Sequence[np.ndarray], closed: bool = False) -> pv.PolyData:
    """One line cell per complex polyline (closed ones repeat their first point index)."""
    import pyvista as pv

    lines = [np.asarray(l_, dtype=np.complex128).ravel() for l_ in lines]
    lines = [l_ for l_ in lines if l_.size >= 2]
    if not lines:
        return pv.PolyData()
    pts = np.concatenate(lines)
    sizes = np.array([l_.size for l_ in lines])
    offsets = np.concatenate([[0], np.cumsum(sizes[:-1])])
    conn = []
    for off, s in zip(offsets, sizes, strict=True):
        idx = np.arange(off, off + s)
        conn.append(np.append(idx, off) if closed else idx)
    conn_flat = np.concatenate(conn)
    return pv.PolyData(_xyz(pts), lines=_cells(sizes + (1 if closed else 0), conn_flat))


def _segments_polydata(a: np.ndarray, b: np.ndarray) -> pv.PolyData:
    """One line cell per segment a[k]–b[k]."""
    import pyvista as pv

    a = np.asarray(a, dtype=np.complex128).ravel()
    b = np.asarray(b, dtype=np.complex128).ravel()
    k = a.size
    if k == 0:
        return pv.PolyData()
    pts = np.concatenate([a, b])
    conn = np.column_stack([np.arange(k), np.arange(k, 2 * k)]).ravel()
    return pv.PolyData(_xyz(pts), lines=_cells(np.full(k, 2), conn))


def _points_polydata(z: np.ndarray) -> pv.PolyData:
    import pyvista as pv

    z = np.asarray(z, dtype=np.complex128).ravel()
    if z.size == 0:
        return pv.PolyData()
    return pv.PolyData(_xyz(z))


def _filled_polygons(polys: Sequence[np.ndarray]) -> pv.PolyData:
    """Filled simple polygons (possibly non-convex) as triangles, cell array ``"polygon"``.

    Triangulated by shapely's constrained Delaunay triangulation so non-convex pieces are filled
    correctly (VTK's polygon cells are drawn as if convex).
    """
    import pyvista as pv
    import shapely

    tri_pts: list[np.ndarray] = []
    owner: list[np.ndarray] = []
    for k, z in enumerate(polys):
        z = np.asarray(z, dtype=np.complex128).ravel()
        if z.size < 3:
            continue
        shp = shapely.Polygon(np.column_stack([z.real, z.imag]))
        if not shp.is_valid:
            shp = shapely.make_valid(shp)
        tris = shapely.get_parts(shapely.constrained_delaunay_triangles(shp))
        if len(tris) == 0:
            continue
        coords = shapely.get_coordinates(shapely.get_exterior_ring(tris)).reshape(len(tris), 4, 2)
        tri_pts.append(coords[:, :3, 0] + 1j * coords[:, :3, 1])
        owner.append(np.full(len(tris), k))
    if not tri_pts:
        return pv.PolyData()
    t = np.concatenate(tri_pts)
    n = t.shape[0]
    faces = np.column_stack([np.full(n, 3), np.arange(3 * n).reshape(n, 3)]).ravel()
    mesh = pv.PolyData(_xyz(t.ravel()), faces=faces)
    mesh.cell_data["polygon"] = np.concatenate(owner)
    return mesh


def _edges(mesh: pv.PolyData) -> pv.PolyData:
    """All edges of a surface mesh as line cells (avoids show_edges' diagonals)."""
    import pyvista as pv

    if mesh.n_cells == 0:
        return pv.PolyData()
    return mesh.extract_all_edges()


def _arc_points(start: float, length: float, radius: float = 1.0, step: float = 0.01) -> np.ndarray:
    m = max(2, int(np.ceil(abs(length) / step)) + 1)
    t = start + np.linspace(0.0, length, m)
    return radius * np.exp(1j * t)


def geodesic_arc(p: complex, q: complex, m: int = 24) -> np.ndarray:
    """Points along the hyperbolic geodesic segment from ``p`` to ``q`` (both inside D)."""
    from .hyperbolic.geodesic import distance, point_towards

    d = float(distance(p, q))
    if d == 0.0:
        return np.array([p, q], dtype=np.complex128)
    return point_towards(np.full(m, p), np.full(m, q), np.linspace(0.0, d, m))


def line_part(
    lines: Sequence[np.ndarray],
    *,
    color: str,
    line_width: float = 1.0,
    closed: bool = False,
    label: str = "",
    disk: bool = False,
    disk_scale: float = 1.0,
) -> LayerPart:
    """A part drawing complex polylines (``disk``: keep their disk coordinates; lines drawn
    ``disk_scale`` times outside their disk points, as arcs just outside T, keep
    ``points / disk_scale``)."""
    mesh = _polylines_polydata(lines, closed=closed)
    z = None
    if disk and len(lines):
        z = np.concatenate([np.ravel(l_) for l_ in lines])
        if disk_scale != 1.0:
            z = z / disk_scale
    return LayerPart(
        mesh,
        color=color,
        line_width=line_width,
        style="wireframe",
        label=label,
        disk_z=z,
        disk_scale=disk_scale,
    )


def points_part(
    z: np.ndarray, *, color: str, point_size: float = 8.0, label: str = "", disk: bool = False
) -> LayerPart:
    """A part drawing points as small spheres (``disk``: keep their disk coordinates)."""
    z = np.asarray(z, dtype=np.complex128).ravel()
    return LayerPart(
        _points_polydata(z),
        color=color,
        style="points",
        point_size=point_size,
        label=label,
        disk_z=z if disk else None,
    )


def unit_circle_part(radius: float = 1.0) -> LayerPart:
    """The unit circle T = ∂D as a thin black closed line (drawn under every disk view)."""
    ring = _arc_points(0.0, 2 * np.pi, radius)[:-1]
    return line_part(
        [ring], color="black", line_width=1.5, closed=True, label="unit circle", disk=True
    )


# ----------------------------------------------------------------------------- model access
def layer_names(view: str) -> list[str]:
    """Names of the layers of ``view`` (``"plane"`` or ``"disk"``), bottom to top."""
    if view == "plane":
        return list(PLANE_LAYERS)
    if view == "disk":
        return list(DISK_LAYERS)
    raise ValueError(f"unknown view {view!r}; expected 'plane' or 'disk'")


def _complex_vertices(obj: Any) -> np.ndarray:
    """Complex vertices of a piece/polygon-like object (``.z``, complex ``.vertices`` or (k,2))."""
    z = getattr(obj, "z", None)
    if z is not None:
        return _as_complex(z)
    return _as_complex(obj.vertices)


def _new_angle_mask(result: Any, ang: np.ndarray) -> np.ndarray:
    """(Q, 4) mask of the *new* corner angles (:meth:`QuadMesh.new_angle_mask`)."""
    return result.mesh.new_angle_mask(result.polygon)


def _angle_clim(result: Any) -> tuple[float, float]:
    """Colour range of the corner-angle colouring: [60°, 120°], widened to the new angles'
    range when some leave it.  Fixed rather than the data's own range, so that one colour means
    one angle in every result, and a mesh whose angles are all 90° (a block mesh) is drawn in
    one colour instead of noise stretched over a range of width 1e-12."""
    q = result.quality
    return min(float(q.min_angle), ANGLE_MIN), max(float(q.max_angle), ANGLE_MAX)


# ----------------------------------------------------------------------------- plane layers
def _layer_polygon(result: Any) -> list[LayerPart]:
    return polygon_layer(_complex_vertices(result.polygon)).parts


def polygon_layer(z: np.ndarray, closed: bool = True, color: str = "black") -> LayerGeometry:
    """The ``"polygon"`` layer of a polygon given by its vertices: a light fill (closed simple
    polygons only), the outline (open while it is being drawn) and the vertices."""
    z = np.asarray(z, dtype=np.complex128).ravel()
    parts = []
    if closed and z.size >= 3:
        import shapely

        if shapely.Polygon(np.column_stack([z.real, z.imag])).is_valid:
            parts.append(
                LayerPart(_filled_polygons([z]), color="#e8e8e8", opacity=0.6, label="fill")
            )
    parts += [
        line_part([z], color=color, line_width=3.0, closed=closed and z.size >= 3, label="outline"),
        points_part(z, color=color, point_size=8.0, label="vertices"),
    ]
    return LayerGeometry("polygon", "plane", [p for p in parts if p.mesh.n_points > 0])


def _layer_thick_pieces(result: Any) -> list[LayerPart]:
    if result.decomposition is None:  # method="blocks": no thick pieces
        return []
    polys = [_complex_vertices(t) for t in result.decomposition.thick]
    fill = _filled_polygons(polys)
    parts = []
    if fill.n_cells:
        # categorical colours as an RGB cell array
        palette = np.array(
            [[int(c[i : i + 2], 16) for i in (1, 3, 5)] for c in PIECE_PALETTE], dtype=np.uint8
        )
        fill.cell_data["piece_rgb"] = palette[fill.cell_data["polygon"] % len(PIECE_PALETTE)]
        parts.append(LayerPart(fill, scalars="piece_rgb", opacity=0.55, label="fill"))
    parts.append(line_part(polys, color="#2f4f4f", line_width=2.0, closed=True, label="outlines"))
    return parts


def _layer_thin_parts(result: Any) -> list[LayerPart]:
    parts = []
    for kind in ("parabolic", "hyperbolic", "corridor"):
        sel = [t for t in result.thin if t.kind == kind]
        if not sel:
            continue
        zs, qs, off = [], [], 0
        for t in sel:
            z = _complex_vertices(t.mesh)
            zs.append(z)
            qs.append(np.asarray(t.mesh.quads, dtype=np.int64) + off)
            off += z.size
        surf = _quads_polydata(np.concatenate(zs), np.concatenate(qs))
        parts.append(LayerPart(surf, color=THIN_COLORS[kind], opacity=0.8, label=kind))
        parts.append(
            LayerPart(
                _edges(surf),
                color="#333333",
                line_width=1.0,
                style="wireframe",
                label=f"{kind} edges",
            )
        )
    return parts


def _crosscut_lines(result: Any) -> list[np.ndarray]:
    """The crosscuts of the decomposition as complex polylines: the images f(γ_j) of the
    geodesics γ_j that cut the vertex sectors (parabolic thin parts) off each thick piece, and
    the crosscuts γ_A, γ_B that bound each channel core (hyperbolic thin parts)."""
    lines: list[np.ndarray] = []
    for p in _pushed_pieces(result):
        img = np.asarray(p.image, dtype=np.complex128)
        for g in p.disk.gamma:
            g = np.asarray(g, dtype=np.int64)
            if g.size >= 2:
                lines.append(img[g])
    for ch in getattr(result.decomposition, "channels", ()):
        for c in ch.crosscuts:
            lines.append(_as_complex(c))
    return lines


def _pushed_pieces(result: Any) -> list[Any]:
    """The thick pieces of ``result`` whose disk mesh was built and pushed forward (all of a
    finished run's; a failed run's :class:`~quadmesh.errors.PartialResult` may hold pieces
    that stopped earlier)."""
    return [p for p in result.pieces if p.disk is not None and p.image is not None]


def _layer_crosscuts(result: Any) -> list[LayerPart]:
    lines = _crosscut_lines(result)
    return [line_part(lines, color=LAYER_COLORS["crosscuts"], line_width=3.0, label="crosscuts")]


def _kind_parts(z: np.ndarray, quads: np.ndarray, kinds: np.ndarray, opacity: float) -> list:
    parts = []
    for kind, color in KIND_COLORS.items():
        sel = np.asarray(kinds) == kind
        if not np.any(sel):
            continue
        parts.append(
            LayerPart(
                _quads_polydata(z, quads[sel]), color=color, opacity=opacity, label=kind, disk_z=z
            )
        )
    return parts


def _layer_conformal_images(result: Any) -> list[LayerPart]:
    zs, qs, ks, off = [], [], [], 0
    for p in _pushed_pieces(result):
        img = np.asarray(p.image, dtype=np.complex128)
        zs.append(img)
        qs.append(np.asarray(p.disk.quads, dtype=np.int64) + off)
        ks.append(np.asarray(p.disk.kind))
        off += img.size
    if not zs:
        return []
    z, quads, kinds = np.concatenate(zs), np.concatenate(qs), np.concatenate(ks)
    parts = _kind_parts(z, quads, kinds, opacity=0.85)
    for p in parts:
        p.disk_z = None
    parts.append(
        LayerPart(
            _edges(_quads_polydata(z, quads)),
            color="#202020",
            line_width=0.6,
            style="wireframe",
            label="edges",
        )
    )
    return parts


def _layer_final_mesh(result: Any, color_by: str) -> list[LayerPart]:
    import pyvista as pv

    mesh = result.mesh
    z = _as_complex(mesh.vertices)
    quads = np.asarray(mesh.quads, dtype=np.int64)
    ang = np.asarray(mesh.angles(), dtype=np.float64)
    new = _new_angle_mask(result, ang)
    lo, hi = _angle_clim(result)
    if color_by == "corner":
        # unshared corners: point k of quad q carries the angle of quad q at that corner
        q_n = quads.shape[0]
        faces = np.column_stack(
            [np.full(q_n, 4, dtype=np.int64), np.arange(4 * q_n).reshape(q_n, 4)]
        ).ravel()
        surf = pv.PolyData(_xyz(z[quads].ravel()), faces=faces)
        vals = np.where(new, ang, np.clip(ang, lo, hi)).ravel()
        surf.point_data["corner_angle"] = vals
        scal, title, clim, cmap = "corner_angle", CORNER_TITLE, (lo, hi), "coolwarm"
    elif color_by == "worst":
        surf = _quads_polydata(z, quads)
        dev = np.where(new, np.abs(ang - 90.0), 0.0).max(axis=1)
        surf.cell_data["worst_deviation"] = dev
        top = max(abs(lo - 90.0), abs(hi - 90.0))  # at least 30°: see _angle_clim
        scal, title, clim, cmap = "worst_deviation", WORST_TITLE, (0.0, top), "viridis"
    else:
        raise ValueError(f"color_by must be 'corner' or 'worst', got {color_by!r}")
    edges = _edges(_quads_polydata(z, quads))
    return [
        LayerPart(surf, scalars=scal, cmap=cmap, clim=clim, scalar_bar_title=title, label="quads"),
        LayerPart(edges, color="black", line_width=0.8, style="wireframe", label="edges"),
    ]


def block_layout_edges(layout: Any, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Point index pairs (a, b) of the edges of a block layout's coarse cells
    (:class:`quadmesh.blocks.BlockLayout`) that neither lie on the polygon's boundary nor on
    one of its cuts: the spokes from the centre points where faces were split (none when
    ``layout.split`` is False).  With the polygon's outline and the cuts they draw every cell
    edge once.  ``tol`` is relative to the polygon's size."""
    cells = np.asarray(layout.cells, dtype=np.int64).reshape(-1, 4)
    empty = np.zeros(0, dtype=np.int64)
    if cells.size == 0:
        return empty, empty
    pts = np.asarray(layout.points, dtype=np.complex128)
    a, b = cells.ravel(), np.roll(cells, -1, axis=1).ravel()
    m = int(cells.max()) + 1
    key = np.unique(np.minimum(a, b) * m + np.maximum(a, b))
    a, b = key // m, key % m
    poly = np.asarray(layout.polygon, dtype=np.complex128)
    eps = tol * max(float(np.ptp(poly.real)), float(np.ptp(poly.imag)), 1e-300)
    segs = np.asarray(layout.cuts, dtype=np.complex128).reshape(-1, 2)
    segs = np.concatenate([segs, np.column_stack([poly, np.roll(poly, -1)])])
    s0, s1 = segs[:, 0], segs[:, 1]

    def on_segment(z: np.ndarray) -> np.ndarray:
        # (E, S): point z[e] within eps of segment s
        d = s1 - s0
        t = np.clip(
            ((z[:, None] - s0) * np.conj(d)).real / np.maximum(np.abs(d) ** 2, 1e-300), 0.0, 1.0
        )
        return np.abs(z[:, None] - (s0 + t * d)) <= eps

    covered = np.any(on_segment(pts[a]) & on_segment(pts[b]), axis=1)
    return a[~covered], b[~covered]


def _layer_block_layout(result: Any) -> list[LayerPart]:
    layout = getattr(result, "blocks", None)
    if layout is None:
        return []
    pts = np.asarray(layout.points, dtype=np.complex128)
    a, b = block_layout_edges(layout)
    cuts = np.asarray(layout.cuts, dtype=np.complex128).reshape(-1, 2)
    fill = []
    for key, label in (
        ("local faces", "faces laid out on their own"),
        ("fallback faces", "faces meshed by the paper's construction"),
    ):
        faces = list(getattr(layout, key.replace(" ", "_"), ()))
        if faces:
            fill.append(
                LayerPart(
                    _filled_polygons(faces), color=BLOCK_COLORS[key], opacity=0.45, label=label
                )
            )
    return [
        *fill,
        LayerPart(
            _segments_polydata(pts[a], pts[b]),
            color=BLOCK_COLORS["cell edges"],
            line_width=3.0,
            style="wireframe",
            label="cell edges",
        ),
        LayerPart(
            _segments_polydata(cuts[:, 0], cuts[:, 1]),
            color=BLOCK_COLORS["cuts"],
            line_width=4.0,
            style="wireframe",
            label="cuts",
        ),
    ]


def bad_quad_mask(result: Any) -> np.ndarray:
    """Per final quad: True if one of its new angles lies outside [60°, 120°] (with the slack
    ``quadmesh.mesh.ANGLE_TOL_DEG`` that the quality report uses)."""
    ang = np.asarray(result.mesh.angles(), dtype=np.float64)
    new = _new_angle_mask(result, ang)
    from .mesh import ANGLE_TOL_DEG

    bad = new & ((ang < ANGLE_MIN - ANGLE_TOL_DEG) | (ang > ANGLE_MAX + ANGLE_TOL_DEG))
    return bad.any(axis=1)


def _layer_bad_quads(result: Any) -> list[LayerPart]:
    z = _as_complex(result.mesh.vertices)
    quads = np.asarray(result.mesh.quads, dtype=np.int64)[bad_quad_mask(result)]
    surf = _quads_polydata(z, quads) if len(quads) else _points_polydata(np.zeros(0))
    return [
        LayerPart(surf, color=LAYER_COLORS["bad_quads"], opacity=0.9, label="quads"),
        LayerPart(
            _edges(surf) if len(quads) else surf,
            color=LAYER_COLORS["bad_quads"],
            line_width=3.0,
            style="wireframe",
            label="outlines",
        ),
    ]


# ----------------------------------------------------------------------------- disk layers
def _tessellation_lines(depth: int, center: complex = 0j) -> list[np.ndarray]:
    """Edges of the T5 tiles (§2) within ``depth`` reflections of the tile containing
    ``center``, each shared edge once, as sampled geodesic arcs (complex disk points)."""
    from .disk.tessellation import P0_VERTICES, generate_tiles, locate
    from .hyperbolic.geodesic import distance, point_towards

    tiles, _ = generate_tiles(depth=depth)
    if center != 0:
        tiles = locate(np.array([center]))[0] @ tiles
    a = np.asarray(P0_VERTICES, dtype=np.complex128)
    b = np.roll(a, -1)
    t = np.linspace(0.0, 1.0, 12)
    canon = point_towards(a[:, None], b[:, None], distance(a, b)[:, None] * t[None, :])
    pts = tiles.apply_rows(canon.ravel()).reshape(-1, t.size)
    # an edge shared by two tiles appears twice: keep one copy (key: symmetric functions of
    # its endpoints, rounded relative to the distance from T)
    e0, e1 = pts[:, 0], pts[:, -1]
    scale = np.maximum(1.0 - np.abs(e0), 1e-12)
    key = np.column_stack([(e0 + e1).real, (e0 + e1).imag, (e0 * e1).real, (e0 * e1).imag])
    key = np.round(key / scale[:, None] * 1e6)
    _, first = np.unique(key, axis=0, return_index=True)
    return list(pts[np.sort(first)])


def _piece_boundary_edges(quads: np.ndarray, piece: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertex index pairs of the edges that bound a piece: edges in one quad only, or between
    quads of different pieces (``piece`` = piece index per quad)."""
    a = quads.ravel()
    b = np.roll(quads, -1, axis=1).ravel()
    pid = np.repeat(piece, 4)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo.astype(np.int64) * (int(quads.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    ks, ps = key[order], pid[order]
    same_next = np.append(ks[1:] == ks[:-1], False)
    same_prev = np.insert(ks[1:] == ks[:-1], 0, False)
    single = ~same_next & ~same_prev
    differ = same_next & (ps != np.append(ps[1:], -1))
    keep = order[single | differ]
    return a[keep], b[keep]


def build_disk_layer(
    name: str,
    disk: Any = None,
    *,
    prevertices: np.ndarray | None = None,
    intervals: np.ndarray | None = None,
    tessellation_depth: int = 4,
    tessellation_center: complex = 0j,
) -> LayerGeometry:
    """Geometry of a disk-view layer from a ``DiskMesh`` (and, for ``"prevertices"``, the
    prevertices of the conformal map and the arcs I_j).  ``"tessellation"`` needs no disk mesh;
    it shows the tiles within ``tessellation_depth`` reflections of the tile that contains
    ``tessellation_center``. ``"prevertices"`` without a disk mesh (a piece whose disk
    construction failed) shows the prevertices and the arcs I_j without the arcs J_j.
    """
    if name not in DISK_LAYERS:
        raise ValueError(f"unknown disk layer {name!r}; expected one of {DISK_LAYERS}")
    geo = LayerGeometry(name, "disk")
    if name == "tessellation":
        lines = _tessellation_lines(tessellation_depth, tessellation_center)
        geo.parts.append(
            line_part(lines, color=LAYER_COLORS["tessellation"], label="tile edges", disk=True)
        )
        return geo
    if disk is None and name != "prevertices":
        raise ValueError(f"disk layer {name!r} needs a disk mesh")
    if disk is not None:
        z = np.asarray(disk.vertices, dtype=np.complex128)
        quads = np.asarray(disk.quads, dtype=np.int64)
    if name == "region_w":
        geo.parts.extend(_kind_parts(z, quads, np.asarray(disk.kind), opacity=1.0))
        piece = getattr(disk, "piece", None)
        if piece is not None:
            a, b = _piece_boundary_edges(quads, np.asarray(piece))
            geo.parts.append(
                LayerPart(
                    _segments_polydata(z[a], z[b]),
                    color="#1a1a1a",
                    line_width=2.0,
                    style="wireframe",
                    label="piece outlines",
                    disk_z=np.concatenate([z[a], z[b]]),
                )
            )
    elif name == "disk_mesh":
        edges = _edges(_quads_polydata(z, quads))
        e = _as_complex(np.asarray(edges.points)[:, :2])
        geo.parts.append(
            LayerPart(
                edges,
                color=LAYER_COLORS["disk_mesh"],
                line_width=0.7,
                style="wireframe",
                label="edges",
                disk_z=e,
            )
        )
    else:  # prevertices
        if disk is not None:
            arcs_j = [
                _arc_points(s, ln, 1.045) for s, ln in np.asarray(disk.pieces.J).reshape(-1, 2)
            ]
            geo.parts.append(
                line_part(
                    arcs_j,
                    color="#2ca02c",
                    line_width=4.0,
                    label="J arcs",
                    disk=True,
                    disk_scale=1.045,
                )
            )
        if intervals is not None and len(intervals):
            arcs_i = [_arc_points(s, ln, 1.02) for s, ln in np.asarray(intervals).reshape(-1, 2)]
            geo.parts.append(
                line_part(
                    arcs_i,
                    color="#d62728",
                    line_width=5.0,
                    label="I arcs",
                    disk=True,
                    disk_scale=1.02,
                )
            )
        if prevertices is not None and len(prevertices):
            geo.parts.append(
                points_part(
                    prevertices,
                    color=LAYER_COLORS["prevertices"],
                    point_size=9.0,
                    label="prevertices",
                    disk=True,
                )
            )
    geo.parts = [p for p in geo.parts if p.mesh.n_points > 0]
    return geo


def build_layer(
    result: Any,
    name: str,
    *,
    piece: int = 0,
    color_by: str = "corner",
    tessellation_depth: int = 4,
) -> LayerGeometry:
    """Geometry of layer ``name`` of a :class:`~quadmesh.result.MeshResult`.

    Plane layers use the whole result; disk layers show thick piece number ``piece`` (its
    position in ``result.pieces``). ``result`` may be a failed run's
    :class:`~quadmesh.errors.PartialResult`: a piece without a disk mesh has empty
    ``region_w`` and ``disk_mesh`` layers and only its prevertices and arcs I_j, and the plane
    layers show the pieces that got that far.
    ``color_by`` chooses the colouring of ``final_mesh``: ``"corner"`` (each corner's angle,
    colour range [60°, 120°], widened to the new angles' range when some leave it) or
    ``"worst"`` (each quad's largest deviation of a new angle from 90°, range at least
    [0°, 30°]).
    """
    if name in DISK_LAYERS:
        if name == "tessellation":
            return build_disk_layer(name, tessellation_depth=tessellation_depth)
        if not result.pieces:
            return LayerGeometry(name, "disk")
        p = result.pieces[piece]
        if p.disk is None and name != "prevertices":
            return LayerGeometry(name, "disk")
        return build_disk_layer(
            name,
            p.disk,
            prevertices=np.asarray(p.map.prevertices),
            intervals=np.asarray(p.intervals),
        )
    builders: dict[str, Callable[[Any], list[LayerPart]]] = {
        "polygon": _layer_polygon,
        "thick_pieces": _layer_thick_pieces,
        "thin_parts": _layer_thin_parts,
        "crosscuts": _layer_crosscuts,
        "conformal_images": _layer_conformal_images,
        "final_mesh": lambda r: _layer_final_mesh(r, color_by),
        "block_layout": _layer_block_layout,
        "bad_quads": _layer_bad_quads,
    }
    if name not in builders:
        raise ValueError(f"unknown layer {name!r}; expected one of {PLANE_LAYERS + DISK_LAYERS}")
    parts = [p for p in builders[name](result) if p.mesh.n_points > 0]
    origin = complex(getattr(result, "origin", 0j))
    if origin and name in (
        "thick_pieces",
        "thin_parts",
        "crosscuts",
        "conformal_images",
        "block_layout",
    ):
        # these stages ran on the polygon translated by −origin (MeshResult.origin)
        for p in parts:
            p.mesh.translate((origin.real, origin.imag, 0.0), inplace=True)
    shift = complex(getattr(result, "mesh_origin", 0j) or 0j)
    if shift and name in ("final_mesh", "bad_quads"):
        # the mesh is stored relative to mesh_origin (a polygon far from (0, 0))
        for p in parts:
            p.mesh.translate((shift.real, shift.imag, 0.0), inplace=True)
    return LayerGeometry(name, "plane", parts)


# ----------------------------------------------------------------------------- drawing
def add_layer(plotter: Any, geometry: LayerGeometry, *, visible: bool = True) -> list[Any]:
    """Add the parts of ``geometry`` to a pyvista plotter; return their actors.

    Colour bars are keyed by their title (``plotter.scalar_bars[title]``) and hidden together
    with the layer when ``visible`` is False.
    """
    actors = []
    for part in geometry.parts:
        if part.mesh.n_points == 0:
            continue
        kw: dict[str, Any] = {
            "opacity": part.opacity,
            "line_width": part.line_width,
            "lighting": False,
            "reset_camera": False,
            "render": False,
            "pickable": False,
        }
        if part.style == "points":
            kw.update(style="points", point_size=part.point_size, render_points_as_spheres=True)
        elif part.style == "wireframe":
            kw.update(style="wireframe")
        if part.scalars is not None:
            arr = part.mesh[part.scalars]
            if arr.ndim == 2 and arr.dtype == np.uint8:
                kw.update(scalars=part.scalars, rgb=True, show_scalar_bar=False)
            else:
                kw.update(scalars=part.scalars, cmap=part.cmap, clim=part.clim)
                if part.scalar_bar_title:
                    kw.update(
                        show_scalar_bar=True,
                        scalar_bar_args={
                            "title": part.scalar_bar_title,
                            "vertical": False,
                            "position_x": 0.2,
                            "position_y": 0.02,
                            "height": 0.12,
                            "width": 0.6,
                            "fmt": "%.1f",
                            "color": "black",
                            "title_font_size": 14,
                            "label_font_size": 12,
                            "n_labels": 2,  # the range ends; the title sits between them
                        },
                    )
                else:
                    kw.update(show_scalar_bar=False)
        else:
            kw.update(color=part.color)
        actor = plotter.add_mesh(part.mesh, **kw)
        actor.SetVisibility(visible)
        actors.append(actor)
    for title in geometry.scalar_bar_titles:
        if title in plotter.scalar_bars.keys():
            bar = plotter.scalar_bars[title]
            bar.SetBarRatio(0.3)
            bar.SetVisibility(visible)
    return actors


def _offscreen_plotter(size: tuple[int, int]) -> Any:
    """An off-screen pyvista plotter; without an X display VTK is told to use EGL directly."""
    import os

    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    return pv.Plotter(off_screen=True, window_size=list(size))


def fit_camera(plotter: Any, bounds: tuple[float, float, float, float], aspect: float) -> None:
    """Look down the z axis with a parallel projection that shows exactly ``bounds``
    (xmin, xmax, ymin, ymax) in a viewport of width/height ``aspect``."""
    x0, x1, y0, y1 = bounds
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    hw, hh = 0.5 * (x1 - x0), 0.5 * (y1 - y0)
    cam = plotter.camera
    plotter.enable_parallel_projection()
    cam.focal_point = (cx, cy, 0.0)
    dist = 10.0 * max(hw, hh, 1e-12)
    cam.position = (cx, cy, dist)
    cam.up = (0.0, 1.0, 0.0)
    cam.parallel_scale = max(hh, hw / aspect, 1e-12)
    # everything lies in z = 0; set the range explicitly (VTK keeps a stale one when nothing
    # is drawn yet)
    cam.clipping_range = (0.5 * dist, 2.0 * dist)


def _setup_2d(plotter: Any, view: str, size: tuple[int, int], bounds: Any = None) -> None:
    plotter.set_background("white")
    if bounds is None:
        bounds = (-1.07, 1.07, -1.07, 1.07)
    fit_camera(plotter, bounds, size[0] / size[1])


def render_png(
    result: Any,
    path: str | Path,
    view: str = "plane",
    layers: Sequence[str] | None = None,
    size: tuple[int, int] = (1200, 900),
    *,
    piece: int = 0,
    color_by: str = "corner",
) -> Path:
    """Render the chosen layers of ``result`` off screen into a PNG at ``path``.

    ``layers`` defaults to ``polygon`` + ``final_mesh`` (plane) or ``region_w`` + ``disk_mesh`` +
    ``prevertices`` (disk).  Needs no X server (VTK falls back to EGL / OSMesa).
    """

    names = layer_names(view)
    if layers is None:
        layers = (
            ["final_mesh", "polygon"]
            if view == "plane"
            else ["region_w", "disk_mesh", "prevertices"]
        )
    unknown = [n for n in layers if n not in names]
    if unknown:
        raise ValueError(f"unknown {view} layers {unknown}; expected some of {names}")
    path = Path(path)
    pl = _offscreen_plotter(size)
    try:
        if view == "disk":
            add_layer(pl, LayerGeometry("unit_circle", "disk", [unit_circle_part()]))
        for name in sorted(layers, key=names.index):
            add_layer(pl, build_layer(result, name, piece=piece, color_by=color_by))
        bounds = None
        if view == "plane":
            z = _complex_vertices(result.polygon)
            pad = 0.04 * max(np.ptp(z.real), np.ptp(z.imag))
            # the colour bar of the final mesh sits along the bottom edge: leave it room
            bar = 0.13 * max(np.ptp(z.imag), np.ptp(z.real) * size[1] / size[0])
            bottom = pad + (bar if "final_mesh" in layers else 0.0)
            bounds = (
                z.real.min() - pad,
                z.real.max() + pad,
                z.imag.min() - bottom,
                z.imag.max() + pad,
            )
        _setup_2d(pl, view, size, bounds)
        pl.screenshot(str(path))
    finally:
        pl.close()
    return path


def render_disk_png(
    disk_mesh: Any,
    path: str | Path,
    *,
    intervals: np.ndarray | None = None,
    prevertices: np.ndarray | None = None,
    size: tuple[int, int] = (1000, 1000),
) -> Path:
    """Render a ``DiskMesh`` alone (region W coloured by kind, the mesh edges and the arcs J_j,
    plus I_j / prevertices when given) off screen into a PNG at ``path``."""

    path = Path(path)
    pl = _offscreen_plotter(size)
    try:
        add_layer(pl, LayerGeometry("unit_circle", "disk", [unit_circle_part()]))
        for name in ("region_w", "disk_mesh", "prevertices"):
            add_layer(
                pl,
                build_disk_layer(name, disk_mesh, prevertices=prevertices, intervals=intervals),
            )
        _setup_2d(pl, "disk", size)
        pl.screenshot(str(path))
    finally:
        pl.close()
    return path
