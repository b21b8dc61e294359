"""Regenerable test families of corridor-like polygons (``quadmesh bench --families``).

Polygons whose long, narrow corridors have walls made of many short edges: pen strokes,
font glyphs, contours traced from images, rivers and fjorded coasts, buffered random walks.
Every member is generated from a seed (or from a package's bundled data: matplotlib's fonts,
scikit-image's sample images), is a valid simple polygon (:func:`quadmesh.validate_polygon`
accepts it unchanged), counter-clockwise, as an (n, 2) float array without a closing point.

Families (:data:`FAMILIES`, each ``f(seed) -> list[Member]``):

* ``strokes``: buffered centrelines (S, C, spirals of 2–5 turns, zigzags, curls), round or
  flat caps, 30–400 vertices, width 1/5 … 1/60 of the centreline length;
* ``glyphs_stix``, ``glyphs_cm``: the outer contour of A–Z, a–z, 0–9 in STIXGeneral and in
  Computer Modern (cmr10), holes dropped, curves flattened to 1/1000 em (seed ignored);
* ``images``: the largest closed contours of scikit-image's bundled sample images (coins,
  text, page, camera, horse) after smoothing and thresholding, 40–1,000 vertices;
* ``rivers``: meandering centrelines buffered with a noisy width and ragged banks, 200–2,000
  vertices; ``coasts``: a blob with narrow fjords cut in and peninsulas added, boundary noise,
  200–2,000 vertices;
* ``walks``: buffered self-avoiding-enough random walks 10–60 widths long.

Each :class:`Member` carries its nominal corridor ``length`` and ``width`` where they are
defined (strokes, rivers, walks, fjords) so a report can show the length/width ratio;
:func:`local_width` measures a width for any polygon.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import shapely

from .polygon import validate_polygon

__all__ = [
    "FAMILIES",
    "Member",
    "coast",
    "family_members",
    "glyph_outline",
    "glyphs",
    "image_contours",
    "local_width",
    "pen_stroke",
    "polygon_metrics",
    "random_walk",
    "river",
]


@dataclass(frozen=True)
class Member:
    """One polygon of a family.

    Attributes:
        name: short name, unique within its family (e.g. ``"spiral3_2"``, ``"cmr10_g"``).
        vertices: (n, 2) float64, counter-clockwise, simple, no closing point.
        length: nominal corridor length (centreline length), or None.
        width: nominal corridor width, or None.
        meta: further generator parameters (caps, turns, font, image, ...).
    """

    name: str
    vertices: np.ndarray
    length: float | None = None
    width: float | None = None
    meta: dict = field(default_factory=dict)

    @property
    def aspect(self) -> float | None:
        """Nominal length/width ratio of the corridor (None when not defined)."""
        if self.length is None or not self.width:
            return None
        return self.length / self.width


# ---------------------------------------------------------------------------------------------
# clean-up shared by every family


def _largest_polygon(geom: shapely.Geometry) -> shapely.Polygon:
    """The largest-area polygon of ``geom`` (made valid first), holes dropped."""
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    polys = [g for g in getattr(geom, "geoms", [geom]) if g.geom_type == "Polygon"]
    polys += [
        h
        for g in getattr(geom, "geoms", [geom])
        if g.geom_type in ("MultiPolygon", "GeometryCollection")
        for h in g.geoms
        if h.geom_type == "Polygon"
    ]
    if not polys:
        raise ValueError(f"no polygon in a {geom.geom_type}")
    return shapely.Polygon(max(polys, key=lambda g: g.area).exterior)


def _clean_ring(xy: np.ndarray) -> np.ndarray:
    """Drop the closing point, consecutive duplicates and exactly collinear vertices (repeat
    until none is left); orient counter-clockwise."""
    xy = np.asarray(xy, dtype=float)
    if len(xy) > 1 and np.all(xy[0] == xy[-1]):
        xy = xy[:-1]
    while True:
        keep = np.any(xy != np.roll(xy, 1, axis=0), axis=1)
        xy = xy[keep]
        d_in = xy - np.roll(xy, 1, axis=0)
        d_out = np.roll(xy, -1, axis=0) - xy
        cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
        straight = cross == 0.0
        if not np.any(straight) or len(xy) - np.count_nonzero(straight) < 3:
            break
        # drop every other straight vertex of a run at once, the rest in the next pass
        idx = np.flatnonzero(straight)
        drop = idx[np.r_[True, np.diff(idx) > 1]]
        xy = np.delete(xy, drop, axis=0)
    area = 0.5 * np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1])
    return xy[::-1].copy() if area < 0 else xy


def _finish(geom: shapely.Geometry) -> np.ndarray:
    """Exterior of the largest polygon of ``geom`` as a validated CCW (n, 2) array."""
    xy = _clean_ring(np.asarray(_largest_polygon(geom).exterior.coords))
    validate_polygon(xy)  # raises PolygonError when not simple
    return xy


def _n_vertices(geom: shapely.Geometry) -> int:
    return len(geom.exterior.coords) - 1


def _fit_budget(
    poly: shapely.Polygon, tol: float, lo: int, hi: int, scale: float
) -> shapely.Polygon:
    """Simplify ``poly`` with tolerance ``tol``; if it then has more than ``hi`` vertices,
    raise the tolerance (bisection) until it has at most ``hi``; if fewer than ``lo``,
    subdivide its edges until it has at least ``lo``. ``scale`` is the largest tolerance
    tried (about the corridor width)."""
    poly = _largest_polygon(poly)
    out = poly.simplify(tol, preserve_topology=True)
    if _n_vertices(out) > hi:
        a, b = math.log(tol), math.log(scale)
        best = poly.simplify(scale, preserve_topology=True)
        for _ in range(40):
            m = 0.5 * (a + b)
            s = poly.simplify(math.exp(m), preserve_topology=True)
            if _n_vertices(s) <= hi:
                b, best = m, s
            else:
                a = m
        out = best
    out = _largest_polygon(out)
    if _n_vertices(out) < lo:
        step = out.exterior.length / (lo + 2)
        out = shapely.segmentize(out, step)
    return out


def _clearance_ok(line: np.ndarray, width: float, factor: float = 1.5) -> bool:
    """True when parts of the polyline ``line`` that are more than 3 widths apart along the
    line are more than ``factor`` widths apart in the plane (the buffer is a corridor that
    does not touch itself)."""
    seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    # resample at spacing width/4 to bound the pairwise cost
    m = max(int(s[-1] / (0.25 * width)), 2)
    t = np.linspace(0, s[-1], m)
    p = np.column_stack([np.interp(t, s, line[:, 0]), np.interp(t, s, line[:, 1])])
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    far_along = np.abs(t[:, None] - t[None, :]) > 3 * width
    return not np.any(far_along & (d <= factor * width))


def _curve_from_heading(heading: np.ndarray, length: float) -> np.ndarray:
    """Polyline of total ``length`` whose tangent angle at equal arc steps is ``heading``."""
    ds = length / (len(heading) - 1)
    mid = 0.5 * (heading[1:] + heading[:-1])
    steps = ds * np.column_stack([np.cos(mid), np.sin(mid)])
    return np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])


def _polyline_length(line: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(line, axis=0), axis=1)))


# ---------------------------------------------------------------------------------------------
# (a) pen strokes

STROKE_SHAPES = ("S", "C", "spiral", "zigzag", "curl")


def _stroke_centreline(rng: np.random.Generator, shape: str, turns: float) -> np.ndarray:
    """Centreline of a stroke of unit-ish size (length normalised later)."""
    if shape == "C":
        sweep = rng.uniform(1.1, 1.7) * np.pi
        a = np.linspace(0, sweep, 400) + rng.uniform(0, 2 * np.pi)
        ry = rng.uniform(0.8, 1.3)
        return np.column_stack([np.cos(a), ry * np.sin(a)])
    if shape == "S":
        # upper arc (centre (0, 1)) counter-clockwise over the top down to (0, 0), then the
        # lower arc (centre (0, -1)) clockwise from (0, 0): tangents agree at the junction
        k = np.linspace(0, 1, 300)
        a = 1.5 * np.pi - rng.uniform(1.1, 1.5) * np.pi * (1 - k)
        b = 0.5 * np.pi - rng.uniform(1.1, 1.5) * np.pi * k
        upper = np.column_stack([np.cos(a), 1 + np.sin(a)])
        lower = np.column_stack([np.cos(b), -1 + np.sin(b)])
        return np.vstack([upper, lower[1:]]) * [rng.uniform(0.7, 1.2), 1.0]
    if shape == "spiral":
        # Archimedean r = r0 + s θ / 2π in units of the stroke width: turn spacing s in
        # [1.6, 3] widths, inner radius r0 in [1, 2] widths (the inner end is a round cap,
        # not a pinch point)
        th = np.linspace(0, 2 * np.pi * turns, int(200 * turns))
        r0, spacing = rng.uniform(1.0, 2.0), rng.uniform(1.6, 3.0)
        rad = r0 + spacing * th / (2 * np.pi)
        return np.column_stack([rad * np.cos(th), rad * np.sin(th)])
    if shape == "zigzag":
        k = int(rng.integers(3, 9))
        x = np.arange(k + 1, dtype=float) + rng.uniform(-0.15, 0.15, k + 1)
        y = np.where(np.arange(k + 1) % 2 == 0, 0.0, rng.uniform(0.8, 2.0)) + rng.uniform(
            -0.1, 0.1, k + 1
        )
        return np.column_stack([x, y])
    if shape == "curl":
        # heading θ(s): a drift plus a few random smooth modes with large amplitude, so the
        # stroke curls round by more than a half turn without closing a loop
        s = np.linspace(0, 1, 500)
        th = rng.uniform(2, 5) * np.pi * s * rng.choice([-1, 1])
        for j in range(1, 4):
            th += rng.normal(0, 2.0 / j) * np.sin(np.pi * j * s + rng.uniform(0, 2 * np.pi))
        return _curve_from_heading(th, 10.0)
    raise ValueError(f"unknown stroke shape {shape!r}")


def pen_stroke(
    rng: np.random.Generator,
    shape: str = "S",
    *,
    turns: float = 2.0,
    ratio: float | None = None,
    cap: str = "round",
    max_tries: int = 60,
) -> Member:
    """A pen stroke: the centreline of ``shape`` (S, C, spiral of ``turns`` turns, zigzag,
    curl) buffered to width ``length / ratio`` (``ratio`` drawn log-uniform in [5, 60] when
    None; a spiral's ratio follows from its turns: turn spacing 1.6–3 widths and inner radius
    1–2 widths make it about 20 at 2 turns and 200 at 5) with ``cap`` ("round" or "flat")
    caps, then simplified to 30–400 vertices.
    Centrelines whose buffer would touch itself are redrawn (up to ``max_tries`` times)."""
    for _ in range(max_tries):
        line = _stroke_centreline(rng, shape, turns)
        length = _polyline_length(line)
        if shape == "spiral":  # built in units of the width
            width = 1.0
        else:
            r = ratio if ratio is not None else math.exp(rng.uniform(math.log(5), math.log(60)))
            width = length / r
        if not _clearance_ok(line, width):
            continue
        geom = shapely.LineString(line).buffer(
            width / 2, quad_segs=16, cap_style=cap, join_style="round"
        )
        if geom.geom_type != "Polygon" or len(geom.interiors):
            continue
        tol = width * math.exp(rng.uniform(math.log(0.003), math.log(0.05)))
        geom = _fit_budget(geom, tol, 30, 400, 0.5 * width)
        try:
            xy = _finish(geom)
        except ValueError:
            continue
        if 30 <= len(xy) <= 400:
            return Member("", xy, length, width, {"shape": shape, "cap": cap, "turns": turns})
    raise RuntimeError(f"no valid {shape} stroke in {max_tries} tries")


def strokes(seed: int = 0) -> list[Member]:
    """20 pen strokes: 4 each of S, C, spiral (2, 3, 4, 5 turns), zigzag, curl; caps
    alternate between round and flat."""
    out = []
    for i, shape in enumerate(STROKE_SHAPES):
        for j in range(4):
            rng = np.random.default_rng([seed, 1, i, j])
            turns = 2.0 + j if shape == "spiral" else 1.0
            m = pen_stroke(rng, shape, turns=turns, cap="round" if j % 2 == 0 else "flat")
            label = f"{shape}{int(turns)}" if shape == "spiral" else shape
            out.append(Member(f"{label}_{j}", m.vertices, m.length, m.width, m.meta))
    return out


# ---------------------------------------------------------------------------------------------
# (b) font glyphs

GLYPH_CHARS = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789"
GLYPH_FONTS = {"glyphs_stix": "STIXGeneral", "glyphs_cm": "cmr10"}
GLYPH_TOLERANCE = 1e-3
"""Flattening tolerance of glyph curves, as a fraction of the em size."""


def _font_path(family: str) -> str:
    from matplotlib import font_manager

    return font_manager.findfont(
        font_manager.FontProperties(family=family), fallback_to_default=False
    )


def _flatten_path(path, tol: float) -> list[np.ndarray]:
    """Subpaths of a matplotlib Path as polylines; each Bézier of degree d is cut into
    ``ceil(sqrt(d (d-1) max|Δ²P| / (8 tol)))`` equal parameter steps (chord error ≤ tol)."""
    from matplotlib.path import Path

    rings: list[list[np.ndarray]] = []
    for bez, code in path.iter_bezier():
        cp = np.asarray(bez.control_points, dtype=float)
        if code == Path.MOVETO:
            rings.append([cp[:1]])
            continue
        d = len(cp) - 1
        if d >= 2:
            dd = np.max(np.linalg.norm(np.diff(cp, 2, axis=0), axis=1))
            k = max(1, math.ceil(math.sqrt(d * (d - 1) * dd / (8 * tol))))
        else:
            k = 1
        t = np.linspace(0, 1, k + 1)[1:]
        rings[-1].append(np.asarray(bez(t)))
    return [np.vstack(r) for r in rings if sum(len(p) for p in r) >= 4]


def glyph_outline(char: str, font: str, tol: float = GLYPH_TOLERANCE) -> np.ndarray:
    """Outer contour of glyph ``char`` of the matplotlib-bundled font ``font`` (e.g.
    "STIXGeneral", "cmr10"), at em size 1: curves flattened to ``tol`` em, the largest
    exterior ring kept (holes and separate parts such as the dot of i dropped), made simple
    and counter-clockwise."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    tp = TextPath((0, 0), char, size=1.0, prop=FontProperties(fname=_font_path(font)))
    rings = _flatten_path(tp, tol)
    if not rings:
        raise ValueError(f"glyph {char!r} of {font} has no closed contour")
    polys = [shapely.Polygon(r) for r in rings]
    outer = max(polys, key=lambda p: abs(shapely.Polygon(p.exterior).area))
    geom = outer if outer.is_valid else shapely.make_valid(outer)
    geom = _largest_polygon(geom)
    if not geom.is_valid:
        geom = _largest_polygon(geom.buffer(0))
    return _finish(geom)


def glyphs(font: str) -> list[Member]:
    """Outer contours of A–Z, a–z, 0–9 in ``font``."""
    return [
        Member(f"{font}_{c}", glyph_outline(c, font), meta={"font": font, "char": c})
        for c in GLYPH_CHARS
    ]


# ---------------------------------------------------------------------------------------------
# (c) contours of scikit-image sample images

IMAGES = {
    # name: (foreground is dark?, Gaussian sigma, contours kept)
    "coins": (False, 2.0, 4),
    "text": (True, 1.0, 4),
    "page": (True, 1.0, 4),
    "camera": (True, 2.0, 3),
    "horse": (True, 1.0, 1),
}
"""Sample images of ``skimage.data`` (all bundled with the package, no download)."""


def image_contours(
    name: str, rng: np.random.Generator | None = None, *, lo: int = 40, hi: int = 1000
) -> list[Member]:
    """The largest closed contours of ``skimage.data.<name>()``: the grey image is smoothed,
    thresholded (Otsu; a local threshold for the unevenly lit ``page``), the binary mask
    padded with background and smoothed again, contours traced at level 1/2
    (``find_contours``), each made simple and simplified to a vertex budget in [lo, hi]
    (drawn from ``rng``, or the largest that fits when None)."""
    import skimage.data
    import skimage.filters
    import skimage.measure

    dark, sigma, keep = IMAGES[name]
    img = np.asarray(getattr(skimage.data, name)(), dtype=float)
    if img.ndim == 3:
        img = img[..., :3].mean(axis=2)
    img = skimage.filters.gaussian(img, sigma=sigma, preserve_range=True)
    if name == "page":
        thr = skimage.filters.threshold_local(img, 35, offset=8)
    else:
        thr = skimage.filters.threshold_otsu(img)
    mask = img < thr if dark else img > thr
    mask = np.pad(mask, 2, constant_values=False).astype(float)
    mask = skimage.filters.gaussian(mask, sigma=1.0)
    polys = []
    for c in skimage.measure.find_contours(mask, 0.5):
        if len(c) < lo or np.any(c[0] != c[-1]):
            continue
        p = shapely.Polygon(np.column_stack([c[:, 1], -c[:, 0]]))
        p = _largest_polygon(p if p.is_valid else p.buffer(0))
        polys.append(p)
    polys.sort(key=lambda p: -p.area)
    out = []
    for k, p in enumerate(polys[:keep]):
        n_raw = _n_vertices(p)
        top = min(hi, n_raw)
        budget = top if rng is None else int(rng.integers(min(lo, top), top + 1))
        g = _fit_budget(p, 0.05, lo, budget, 5.0)
        xy = _finish(g)
        if lo <= len(xy) <= hi:
            out.append(Member(f"{name}_{k}", xy, meta={"image": name, "raw_vertices": n_raw}))
    return out


def images(seed: int = 0) -> list[Member]:
    """Largest closed contours of the sample images of :data:`IMAGES`; vertex budgets drawn
    from ``seed``."""
    out = []
    for i, name in enumerate(IMAGES):
        out += image_contours(name, np.random.default_rng([seed, 3, i]))
    return out


# ---------------------------------------------------------------------------------------------
# (d) rivers and coasts


def _smooth_noise(rng: np.random.Generator, n: int, modes: int = 6) -> np.ndarray:
    """A smooth random function on n equal steps of [0, 1], values about in [-1, 1]."""
    s = np.linspace(0, 1, n)
    f = np.zeros(n)
    for j in range(1, modes + 1):
        f += rng.normal(0, 1 / j) * np.sin(np.pi * j * s + rng.uniform(0, 2 * np.pi))
    return f / max(np.max(np.abs(f)), 1e-12)


def river(
    rng: np.random.Generator,
    *,
    n_vertices: int | None = None,
    ratio: float | None = None,
    max_tries: int = 60,
) -> Member:
    """A river reach: a meandering centreline (heading = decaying sine meanders plus smooth
    noise) of length ``ratio`` widths (drawn in [15, 80] when None), banks offset by half a
    noisy width (±30 % smooth; per-vertex raggedness ±8 % of the half width, at most a
    quarter of the vertex spacing), flat ends; ``n_vertices``
    (drawn in [200, 2000] when None) split between the two banks."""
    for _ in range(max_tries):
        n = int(rng.integers(200, 2001)) if n_vertices is None else n_vertices
        r = rng.uniform(15, 80) if ratio is None else ratio
        m = n // 2
        s = np.linspace(0, 1, m)
        meanders = rng.uniform(1.5, 5)
        amp = rng.uniform(0.6, 1.6)
        heading = amp * np.sin(2 * np.pi * meanders * s + rng.uniform(0, 2 * np.pi))
        heading += 0.4 * _smooth_noise(rng, m)
        length = 1.0
        width = length / r
        line = _curve_from_heading(heading, length)
        if not _clearance_ok(line, width, 1.8):
            continue
        tang = np.gradient(line, axis=0)
        tang /= np.linalg.norm(tang, axis=1)[:, None]
        normal = np.column_stack([-tang[:, 1], tang[:, 0]])
        half = 0.5 * width * (1 + 0.3 * _smooth_noise(rng, m))
        # raggedness: ±8 % of the half width, but at most a quarter of the vertex spacing
        rag = min(0.08 * 0.5 * width, 0.25 * length / m)
        left = line + (half + rag * rng.uniform(-1, 1, m))[:, None] * normal
        right = line - (half + rag * rng.uniform(-1, 1, m))[:, None] * normal
        ring = np.vstack([right, left[::-1]])
        p = shapely.Polygon(ring)
        if not p.is_valid:
            continue
        xy = _finish(p)
        if 200 <= len(xy) <= 2000:
            return Member("", xy, length, width, {"meanders": meanders})
    raise RuntimeError(f"no valid river in {max_tries} tries")


def coast(
    rng: np.random.Generator,
    *,
    fjords: int | None = None,
    peninsulas: int | None = None,
    n_vertices: int | None = None,
    max_tries: int = 30,
) -> Member:
    """A coast: a smooth random blob of radius ~1 with ``fjords`` (drawn in [2, 8]) narrow
    meandering inlets (width 0.012–0.05, length 0.25–0.7) cut in and ``peninsulas`` (drawn
    in [1, 4]) narrow headlands added, then resampled to ``n_vertices`` (drawn in [200, 2000])
    points with normal noise of a tenth of the spacing. ``length``/``width`` are those of
    the narrowest fjord (length/width largest)."""
    for _ in range(max_tries):
        nf = int(rng.integers(2, 9)) if fjords is None else fjords
        npn = int(rng.integers(1, 5)) if peninsulas is None else peninsulas
        n = int(rng.integers(200, 2001)) if n_vertices is None else n_vertices
        t = np.linspace(0, 2 * np.pi, 256, endpoint=False)
        rad = 1 + 0.15 * np.interp(t, np.linspace(0, 2 * np.pi, 256), _smooth_noise(rng, 256))
        blob = shapely.Polygon(np.column_stack([rad * np.cos(t), rad * np.sin(t)]))
        k = nf + npn
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        if k > 1 and np.min(np.diff(np.r_[ang, ang[0] + 2 * np.pi])) < 0.35:
            continue
        kinds = rng.permutation(np.r_[np.zeros(nf), np.ones(npn)])
        best = (0.0, 1.0, 1.0)
        cuts, adds = [], []
        for a, kind in zip(ang, kinds):
            r0 = float(np.interp(a, t, rad, period=2 * np.pi))
            ln = rng.uniform(0.25, 0.7) if kind == 0 else rng.uniform(0.15, 0.4)
            w = rng.uniform(0.012, 0.05) if kind == 0 else rng.uniform(0.03, 0.08)
            m = 80
            heading = a + np.pi * (kind == 0) + 0.5 * _smooth_noise(rng, m)
            line = _curve_from_heading(heading, ln + 0.1)
            start = (r0 + (0.05 if kind == 0 else -0.05)) * np.array([np.cos(a), np.sin(a)])
            line = line + start
            g = shapely.LineString(line).buffer(w / 2, quad_segs=8, cap_style="round")
            (cuts if kind == 0 else adds).append(g)
            if kind == 0 and ln / w > best[0]:
                best = (ln / w, ln, w)
        shape = blob.union(shapely.union_all(adds)) if adds else blob
        if cuts:
            shape = shape.difference(shapely.union_all(cuts))
        if shape.geom_type != "Polygon" or len(shape.interiors):
            continue
        # resample to n points, then jitter along the normal by a tenth of the spacing
        ext = shape.exterior
        spacing = ext.length / n
        pts = shapely.get_coordinates(
            shapely.line_interpolate_point(ext, np.linspace(0, ext.length, n, endpoint=False))
        )
        tang = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
        tang /= np.linalg.norm(tang, axis=1)[:, None]
        normal = np.column_stack([-tang[:, 1], tang[:, 0]])
        pts = pts + (0.1 * spacing * rng.uniform(-1, 1, n))[:, None] * normal
        p = shapely.Polygon(pts)
        if not p.is_valid:
            continue
        try:
            xy = _finish(p)
        except ValueError:
            continue
        if 200 <= len(xy) <= 2000:
            return Member("", xy, best[1], best[2], {"fjords": nf, "peninsulas": npn})
    raise RuntimeError(f"no valid coast in {max_tries} tries")


def rivers(seed: int = 0) -> list[Member]:
    """10 rivers (vertex counts and length/width ratios drawn from ``seed``)."""
    out = []
    for j in range(10):
        m = river(np.random.default_rng([seed, 4, j]))
        out.append(Member(f"river_{j}", m.vertices, m.length, m.width, m.meta))
    return out


def coasts(seed: int = 0) -> list[Member]:
    """10 coasts with fjords and peninsulas (drawn from ``seed``)."""
    out = []
    for j in range(10):
        m = coast(np.random.default_rng([seed, 5, j]))
        out.append(Member(f"coast_{j}", m.vertices, m.length, m.width, m.meta))
    return out


# ---------------------------------------------------------------------------------------------
# (e) random walks


def random_walk(
    rng: np.random.Generator,
    *,
    widths: float | None = None,
    step: float = 0.5,
    turn: float = 0.5,
    max_tries: int = 60,
) -> Member:
    """A buffered random walk of unit width and length ``widths`` (drawn in [10, 60] when
    None): steps of ``step`` widths whose heading changes by N(0, ``turn``) radians, a step
    redrawn when it would come within 1.5 widths of the walk more than 3 widths back along
    it (so the buffer is a simple corridor without holes). Round caps and joins, simplified
    to 1/50 of the width."""
    for _ in range(max_tries):
        target = rng.uniform(10, 60) if widths is None else widths
        n_steps = math.ceil(target / step)
        pts = [np.zeros(2)]
        heading = rng.uniform(0, 2 * np.pi)
        back = math.ceil(3 / step)
        ok = True
        for _ in range(n_steps):
            for _attempt in range(30):
                h = heading + rng.normal(0, turn)
                q = pts[-1] + step * np.array([math.cos(h), math.sin(h)])
                old = np.asarray(pts[: max(len(pts) - back, 0)])
                if len(old) == 0 or np.min(np.hypot(*(old - q).T)) > 1.5:
                    break
            else:
                ok = False
                break
            heading = h
            pts.append(q)
        if not ok:
            continue
        line = np.asarray(pts)
        if not _clearance_ok(line, 1.0):
            continue
        g = shapely.LineString(line).buffer(0.5, quad_segs=8)
        if g.geom_type != "Polygon" or len(g.interiors):
            continue
        g = g.simplify(0.02, preserve_topology=True)
        try:
            xy = _finish(g)
        except ValueError:
            continue
        return Member("", xy, _polyline_length(line), 1.0, {"steps": len(line) - 1})
    raise RuntimeError(f"no valid random walk in {max_tries} tries")


def walks(seed: int = 0) -> list[Member]:
    """10 buffered random walks, 10–60 widths long (drawn from ``seed``)."""
    out = []
    for j in range(10):
        m = random_walk(np.random.default_rng([seed, 6, j]))
        out.append(Member(f"walk_{j}", m.vertices, m.length, m.width, m.meta))
    return out


# ---------------------------------------------------------------------------------------------
# registry and metrics

FAMILIES: dict[str, Callable[[int], list[Member]]] = {
    "strokes": strokes,
    "glyphs_stix": lambda seed=0: glyphs(GLYPH_FONTS["glyphs_stix"]),
    "glyphs_cm": lambda seed=0: glyphs(GLYPH_FONTS["glyphs_cm"]),
    "images": images,
    "rivers": rivers,
    "coasts": coasts,
    "walks": walks,
}
"""Generator of each family: ``f(seed) -> list[Member]`` (glyphs ignore the seed)."""


def family_members(name: str, seed: int = 0) -> list[Member]:
    """The members of family ``name`` of :data:`FAMILIES` for ``seed``."""
    if name not in FAMILIES:
        raise KeyError(f"unknown family {name!r} (known: {', '.join(FAMILIES)})")
    return FAMILIES[name](seed)


def local_width(vertices: np.ndarray, iterations: int = 48) -> np.ndarray:
    """Local width at every edge k = [v_k, v_{k+1}] of the CCW polygon ``vertices``: the
    diameter of the largest disk inside the polygon tangent to edge k at its midpoint
    (bisection on the radius to 2^-iterations of the diameter; disks tangent at one point
    are nested, so the test "centre at distance ≥ radius from the boundary" is monotone).
    In a corridor this is the distance across it; at a convex corner it shrinks with the
    corner."""
    v = np.asarray(vertices, dtype=float)
    w = np.roll(v, -1, axis=0)
    mid = 0.5 * (v + w)
    e = w - v
    inward = np.column_stack([-e[:, 1], e[:, 0]]) / np.linalg.norm(e, axis=1)[:, None]
    tree = shapely.STRtree(shapely.linestrings(np.stack([v, w], axis=1)))
    diam = float(np.hypot(*np.ptp(v, axis=0)))
    lo = np.zeros(len(v))
    hi = np.full(len(v), diam)
    for _ in range(iterations):
        r = 0.5 * (lo + hi)
        c = mid + r[:, None] * inward
        _, dist = tree.query_nearest(shapely.points(c), return_distance=True, all_matches=False)
        ok = dist >= r * (1 - 1e-9)
        lo = np.where(ok, r, lo)
        hi = np.where(ok, hi, r)
    return 2 * lo


def polygon_metrics(vertices: np.ndarray) -> dict[str, float]:
    """Corridor measures of a polygon from :func:`local_width`: ``min_edge_over_width`` =
    min over edges of edge length / local width (how many edges span a width: below 1 the
    walls are chains of edges shorter than the corridor is wide); ``width`` = the
    length-weighted median local width; ``aspect`` = area / width² (length/width of a
    corridor of that width and the polygon's area)."""
    v = np.asarray(vertices, dtype=float)
    lw = local_width(v)
    edge = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
    order = np.argsort(lw)
    cum = np.cumsum(edge[order])
    wmed = float(lw[order][np.searchsorted(cum, 0.5 * cum[-1])])
    area = 0.5 * abs(float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])))
    return {
        "min_edge_over_width": float(np.min(edge / np.maximum(lw, 1e-300))),
        "width": wmed,
        "aspect": area / wmed**2 if wmed > 0 else math.inf,
    }
