"""Families of realistic outlines for stress runs (``quadmesh bench --outlines``).

The bundled examples (:mod:`quadmesh.examples`) are fixed polygons; these are generated, seeded
outlines of the kinds users bring: floor plans (rectilinear, many reflex corners), pixel
contours (staircases of 90°/270° corners), quantised contours, multi-scale notches (a feature
1e-3 … 1e-9 of the polygon's size), spiky and random stars, fractal coastlines, keyholes and
thick pen strokes (font-glyph-like curved corridors). Every outline is a valid simple polygon,
counter-clockwise, as an (n, 2) float array; the same seed gives the same outlines.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import shapely

__all__ = ["OUTLINE_FAMILIES", "stress_outlines"]


def _ring(geom: shapely.Geometry) -> np.ndarray:
    """Exterior ring of the largest polygon of ``geom``, counter-clockwise, without the
    closing point."""
    if geom.geom_type == "MultiPolygon":
        geom = max(geom.geoms, key=lambda g: g.area)
    geom = shapely.geometry.polygon.orient(geom, 1.0)
    return np.asarray(geom.exterior.coords)[:-1].copy()


def floor_plan(rng: np.random.Generator, rooms: int = 6) -> np.ndarray:
    """Union of ``rooms`` axis-parallel rectangles on an integer grid (reflex corners, long
    straight walls, collinear runs merged)."""
    boxes = []
    for _ in range(rooms):
        x, y = rng.integers(0, 8, 2)
        w, h = rng.integers(2, 5, 2)
        boxes.append(shapely.box(x, y, x + w, y + h))
    return _ring(shapely.union_all(boxes).simplify(0))


def pixel_contour(rng: np.random.Generator, size: int = 30, blobs: int = 5) -> np.ndarray:
    """Outline of a union of pixels (random disks rasterised): a staircase of 90° and 270°
    corners, as traced from a binary image without smoothing."""
    yy, xx = np.mgrid[:size, :size]
    img = np.zeros((size, size), dtype=bool)
    for _ in range(blobs):
        cx, cy = rng.uniform(0.3 * size, 0.7 * size, 2)
        r = rng.uniform(0.13, 0.27) * size
        img |= (xx - cx) ** 2 + (yy - cy) ** 2 < r * r
    cells = [shapely.box(i, j, i + 1, j + 1) for i, j in zip(*np.nonzero(img), strict=True)]
    return _ring(shapely.union_all(cells).simplify(0))


def quantised_contour(rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """A smooth closed curve sampled at n points and rounded to a half-pixel grid (the output
    of a contour tracer on a coarse image: short edges, 45° and 90° turns)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    k = rng.integers(2, 5)
    r = 10 + 2 * np.cos(k * t + rng.uniform(0, 6)) + np.cos((2 * k + 1) * t)
    pts = np.round(np.column_stack([r * np.cos(t), r * np.sin(t)]) * 2) / 2
    keep = np.r_[True, np.any(np.diff(pts, axis=0) != 0, axis=1)]
    return _ring(shapely.Polygon(pts[keep]).buffer(0))


def notch(rng: np.random.Generator, size: float = 1e-6) -> np.ndarray:
    """Unit square with a square notch of side ``size`` cut into its top side at a random
    position (a feature 1/size times smaller than the polygon)."""
    x = rng.uniform(0.2, 0.8)
    h = size / 2
    return np.array(
        [
            [0, 0],
            [1, 0],
            [1, 1],
            [x + h, 1],
            [x + h, 1 - size],
            [x - h, 1 - size],
            [x - h, 1],
            [0, 1],
        ],
        dtype=float,
    )


def spiky_star(rng: np.random.Generator, arms: int = 20, inner: float = 0.15) -> np.ndarray:
    """Star with ``arms`` sharp spikes (tip angles of a few degrees, deep reflex valleys)."""
    t = np.linspace(0, 2 * np.pi, 2 * arms, endpoint=False) + rng.uniform(0, 1)
    r = np.where(np.arange(2 * arms) % 2 == 0, 1.0, inner)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def random_star(rng: np.random.Generator, n: int = 40) -> np.ndarray:
    """Star-shaped polygon with n vertices at random angles and random radii in [0.4, 1]."""
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(0.4, 1.0, n)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def coastline(rng: np.random.Generator, levels: int = 5, roughness: float = 0.3) -> np.ndarray:
    """Fractal island: midpoint displacement of a jittered octagon, ``levels`` times
    (bays and headlands at every scale), cleaned to its largest simple component."""
    n0 = 8
    t = np.linspace(0, 2 * np.pi, n0, endpoint=False)
    p = np.exp(1j * t) * (1 + 0.2 * rng.standard_normal(n0))
    for d in range(levels):
        q = np.roll(p, -1)
        m = (p + q) / 2 + roughness * 0.5**d * 1j * (q - p) * rng.standard_normal(p.size)
        p = np.column_stack([p, m]).ravel()
    geom = shapely.Polygon(np.column_stack([p.real, p.imag])).buffer(0)
    return _ring(geom.simplify(1e-4))


def keyhole(rng: np.random.Generator, slot: float = 0.2) -> np.ndarray:
    """Disk with a straight slot of width ``slot`` running out of it (a lock's keyhole)."""
    disk = shapely.Point(0, 0).buffer(1.0, quad_segs=16)
    length = rng.uniform(2.0, 3.0)
    return _ring(disk.union(shapely.box(-slot / 2, -length, slot / 2, 0)))


def stroke(rng: np.random.Generator, turns: float = 0.75, width: float = 0.8) -> np.ndarray:
    """A thick pen stroke along a circular arc of ``turns`` full turns (the curved corridor of
    glyphs such as C, S, G, e): walls are chains of short edges."""
    a = np.linspace(0, 2 * np.pi * turns, 60) + rng.uniform(0, 6)
    line = shapely.LineString(np.column_stack([3 * np.cos(a), 3 * np.sin(a)]))
    return _ring(line.buffer(width / 2, quad_segs=8).simplify(0.02 * width))


OUTLINE_FAMILIES: dict[str, Callable[[np.random.Generator], np.ndarray]] = {
    "floor_plan": floor_plan,
    "pixel_contour": pixel_contour,
    "quantised_contour": quantised_contour,
    "notch_1e-3": lambda rng: notch(rng, 1e-3),
    "notch_1e-6": lambda rng: notch(rng, 1e-6),
    "notch_1e-9": lambda rng: notch(rng, 1e-9),
    "spiky_star_8": lambda rng: spiky_star(rng, 8, 0.3),
    "spiky_star_20": spiky_star,
    "random_star_40": random_star,
    "random_star_120": lambda rng: random_star(rng, 120),
    "coastline_256": coastline,
    "coastline_1024": lambda rng: coastline(rng, 7, 0.25),
    "keyhole": keyhole,
    "stroke_half_turn": lambda rng: stroke(rng, 0.5),
    "stroke_three_quarters": stroke,
}
"""Generator of each family: ``f(rng) -> (n, 2)`` counter-clockwise vertices."""


def stress_outlines(seed: int = 0) -> dict[str, np.ndarray]:
    """One outline of every family in :data:`OUTLINE_FAMILIES`, from ``seed``."""
    out = {}
    for i, (name, make) in enumerate(OUTLINE_FAMILIES.items()):
        out[name] = np.asarray(make(np.random.default_rng([seed, i])), dtype=float)
    return out
