"""Example polygons shipped in ``resources/polygons/*.json`` and the generator that makes them.

Each file is ``{"name": ..., "description": ..., "n": ..., "vertices": [[x, y], ...]}`` with
the vertices counter-clockwise, no repeated closing point.  The set spans n = 3 … 1000 and
the situations the paper treats separately: small original angles (kept unsplit, Theorem
1.1), reflex corners, narrow channels (hyperbolic thin parts, paper §8), many vertices.

``python -m quadmesh.examples`` regenerates the files (random shapes use fixed seeds, so the
output is reproducible).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .errors import InputFormatError

__all__ = ["example_info", "example_names", "example_path", "load_example", "main"]


def polygons_dir() -> Path:
    """The ``resources/polygons`` directory of the repository (editable installs)."""
    return Path(__file__).resolve().parent.parent / "resources" / "polygons"


def example_names() -> list[str]:
    """Names of the example polygons (file stems), sorted."""
    return sorted(p.stem for p in polygons_dir().glob("*.json"))


def example_path(name: str) -> Path:
    """Path of the example file called ``name``."""
    path = polygons_dir() / f"{name}.json"
    if not path.is_file():
        raise InputFormatError(
            f"no example polygon named {name!r}; known: {', '.join(example_names())}"
        )
    return path


def example_info(name: str) -> dict:
    """The example's JSON content: ``name``, ``description``, ``n``, ``vertices`` (pairs)."""
    return json.loads(example_path(name).read_text(encoding="utf-8"))


def load_example(name: str) -> np.ndarray:
    """Vertices (n, 2) float64 of the example polygon ``name``, counter-clockwise."""
    return np.asarray(example_info(name)["vertices"], dtype=np.float64)


# ----------------------------------------------------------------------------- generators
def _xy(z: np.ndarray) -> np.ndarray:
    z = np.asarray(z, dtype=np.complex128)
    return np.column_stack([z.real, z.imag])


def _regular(n: int) -> np.ndarray:
    t = np.pi / 2 + 2 * np.pi * np.arange(n) / n
    return _xy(np.exp(1j * t))


def _radial(n: int, radius: np.ndarray, jitter: float = 0.0, seed: int = 0) -> np.ndarray:
    """Star-shaped polygon r(θ_k) e^{iθ_k} (simple by construction: θ increasing)."""
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * (np.arange(n) + jitter * rng.uniform(-0.5, 0.5, n)) / n
    return _xy(radius(t) * np.exp(1j * t))


def _fourier(k_max: int, seed: int, lo: float = 0.6, hi: float = 1.4, decay: float = 1.0):
    """Smooth random radius function with values spread over exactly [lo, hi]."""
    rng = np.random.default_rng(seed)
    k = np.arange(1, k_max + 1)
    amp = rng.normal(size=k_max) / k**decay
    phase = rng.uniform(0, 2 * np.pi, k_max)

    def raw(t: np.ndarray) -> np.ndarray:
        return np.sum(amp[:, None] * np.cos(k[:, None] * t[None, :] + phase[:, None]), axis=0)

    fine = raw(np.linspace(0, 2 * np.pi, 4096, endpoint=False))
    a, b = fine.min(), fine.max()
    return lambda t: lo + (hi - lo) * (raw(t) - a) / (b - a)


def _star(n: int, k_max: int, seed: int) -> np.ndarray:
    return _radial(n, _fourier(k_max, seed), jitter=0.3, seed=seed + 1)


def _buffered(line: list[tuple[float, float]], half_width: float, mitre: bool) -> np.ndarray:
    """Outline of a thick polyline (shapely buffer, flat caps), counter-clockwise."""
    import shapely
    from shapely.geometry import LineString
    from shapely.geometry.polygon import orient

    geom = LineString(line).buffer(
        half_width, cap_style="flat", join_style="mitre" if mitre else "round", quad_segs=4
    )
    geom = orient(shapely.simplify(geom, half_width * 1e-3), 1.0)
    return np.asarray(geom.exterior.coords)[:-1]


def _comb() -> np.ndarray:
    teeth, w, length, gap, base = 6, 0.05, 1.0, 0.15, 0.2
    pts = [(0.0, 0.0), (teeth * w + (teeth - 1) * gap, 0.0)]
    x = teeth * w + (teeth - 1) * gap
    for k in range(teeth):
        right = x - k * (w + gap)
        left = right - w
        pts += [(right, base + length), (left, base + length)]
        if k < teeth - 1:
            pts += [(left, base), (left - gap, base)]
    return np.asarray(pts)


def _glyph_s() -> np.ndarray:
    # the letter S as a thick stroke: the upper arc counter-clockwise from 20° over the top to
    # the middle, then the lower arc clockwise from the middle round the right to -160°
    a1 = np.radians(np.linspace(20, 270, 24))
    top = 0.5j + 0.5 * np.exp(1j * a1)
    a2 = np.radians(np.linspace(90, -160, 24))
    bottom = -0.5j + 0.5 * np.exp(1j * a2)
    line = np.r_[top, bottom[1:]]
    return _buffered(list(zip(line.real, line.imag)), 0.11, mitre=True)


def _island() -> np.ndarray:
    base = _fourier(6, 11, lo=0.85, hi=1.15)
    bays = [(0.6, 0.4, 0.16), (2.2, 0.3, 0.1), (3.5, 0.5, 0.13), (5.0, 0.3, 0.2)]
    rng = np.random.default_rng(12)
    noise_k = np.arange(7, 40)
    noise_a = rng.normal(size=noise_k.size) * 0.008 / np.sqrt(noise_k / 7)
    noise_p = rng.uniform(0, 2 * np.pi, noise_k.size)

    def radius(t: np.ndarray) -> np.ndarray:
        r = base(t)
        for centre, depth, width in bays:
            d = np.angle(np.exp(1j * (t - centre)))
            r = r - depth * np.exp(-((d / width) ** 2))
        r = r + np.sum(noise_a[:, None] * np.cos(noise_k[:, None] * t + noise_p[:, None]), axis=0)
        return r

    return _radial(240, radius, jitter=0.2, seed=13)


def _leaf() -> np.ndarray:
    x = -np.cos(np.linspace(0, np.pi, 32))  # clustered towards the tips
    upper = 0.45 * (1 - x**2) * (1 + 0.35 * x)
    lower = -0.3 * (1 - x**2) * (1 - 0.2 * x)
    bottom = x + 1j * lower  # left to right
    top = (x + 1j * upper)[::-1][1:-1]  # right to left, tips not repeated
    return _xy(np.r_[bottom, top])


def _blob() -> np.ndarray:
    return _radial(90, _fourier(5, 21, lo=0.7, hi=1.3, decay=1.5), jitter=0.4, seed=22)


def _corner5() -> np.ndarray:
    half = np.radians(2.5)
    z = [0.0, 3 * np.exp(-1j * half), 3.4 + 0.0j, 3.3 + 0.25j, 3 * np.exp(1j * half)]
    return _xy(np.asarray(z))


def _slit355() -> np.ndarray:
    tip_y, half = 0.3, np.radians(2.5)
    h = (1.0 - tip_y) * np.tan(half)
    return np.array(
        [[0, 0], [1, 0], [1, 1], [0.5 + h, 1], [0.5, tip_y], [0.5 - h, 1], [0, 1]], dtype=float
    )


def _spiral() -> np.ndarray:
    line = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (2.0, -1.0)]
    line += [(2.0, 2.0), (-2.0, 2.0), (-2.0, -2.0), (2.5, -2.0)]
    return _buffered(line, 0.2, mitre=True)


def _right10() -> np.ndarray:
    return np.array([[0, 0], [1, 0], [1, np.tan(np.radians(10))]], dtype=float)


def _noisy_circle_1000() -> np.ndarray:
    rng = np.random.default_rng(1000)
    smooth = _fourier(10, 1001, lo=0.85, hi=1.15)
    noise = rng.uniform(-0.0015, 0.0015, 1000)
    return _radial(1000, lambda t: smooth(t) + noise, jitter=0.3, seed=1002)


def _catalogue() -> dict[str, tuple[str, Callable[[], np.ndarray]]]:
    L = [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]
    T = [(0, 2), (0, 3), (3, 3), (3, 2), (2, 2), (2, 0), (1, 0), (1, 2)]
    U = [(0, 0), (3, 0), (3, 3), (2, 3), (2, 1), (1, 1), (1, 3), (0, 3)]
    cross = [(1, 0), (2, 0), (2, 1), (3, 1), (3, 2), (2, 2), (2, 3), (1, 3), (1, 2), (0, 2)]
    cross += [(0, 1), (1, 1)]
    dumbbell = [(0, 0), (1, 0), (1, 0.45), (2, 0.45), (2, 0), (3, 0), (3, 1), (2, 1)]
    dumbbell += [(2, 0.55), (1, 0.55), (1, 1), (0, 1)]
    bent = [(0, 0), (1, 0), (1, 1), (0.9, 1), (0.9, 0.1), (0, 0.1)]
    arr = np.asarray
    return {
        "triangle": ("a scalene acute triangle", lambda: arr([[0, 0], [1, 0], [0.3, 0.8]], float)),
        "equilateral_triangle": (
            "the equilateral triangle: every angle exactly 60°",
            lambda: _regular(3),
        ),
        "right_triangle_10deg": ("a right triangle with a 10° corner (kept unsplit)", _right10),
        "square": ("the unit square", lambda: arr([[0, 0], [1, 0], [1, 1], [0, 1]], float)),
        "rectangle_2x1": ("a 2:1 rectangle", lambda: arr([[0, 0], [2, 0], [2, 1], [0, 1]], float)),
        "l_shape": ("an L-shape with one 270° corner", lambda: arr(L, float)),
        "t_shape": ("a T-shape with two reflex corners", lambda: arr(T, float)),
        "u_shape": ("a U-shape with a deep notch", lambda: arr(U, float)),
        "cross": ("a plus-shaped cross with four reflex corners", lambda: arr(cross, float)),
        "pentagon": ("the regular pentagon", lambda: _regular(5)),
        "hexagon": ("the regular hexagon: every angle 120°", lambda: _regular(6)),
        "octagon": ("the regular octagon (135° angles must be split)", lambda: _regular(8)),
        "dodecagon": ("the regular 12-gon", lambda: _regular(12)),
        "regular_64": ("the regular 64-gon", lambda: _regular(64)),
        "star_30": (
            "random smooth star-shaped 30-gon, radii in [0.6, 1.4]",
            lambda: _star(30, 4, 30),
        ),
        "star_100": (
            "random smooth star-shaped 100-gon, radii in [0.6, 1.4]",
            lambda: _star(100, 7, 100),
        ),
        "star_300": (
            "random smooth star-shaped 300-gon, radii in [0.6, 1.4]",
            lambda: _star(300, 12, 300),
        ),
        "comb": ("a comb of six teeth of width/length 1/20 (narrow channels)", _comb),
        "channel_20": (
            "a long thin channel: a 20 x 1 rectangle",
            lambda: arr([[0, 0], [20, 0], [20, 1], [0, 1]], float),
        ),
        "bent_channel": (
            "an L-shaped corridor of width 1/10 and arm length 1",
            lambda: arr(bent, float),
        ),
        "square_spiral": ("a square spiral corridor of width 0.4 with gaps 0.6", _spiral),
        "dumbbell": (
            "two unit squares joined by a corridor of width 0.1",
            lambda: arr(dumbbell, float),
        ),
        "corner_5deg": ("a needle pentagon with a 5° corner", _corner5),
        "slit_355deg": ("a square with a thin V-notch whose tip is a 355° reflex corner", _slit355),
        "blob": ("a hand-drawn-looking smooth blob", _blob),
        "leaf": ("a leaf with two pointed tips", _leaf),
        "island": ("a 'map island' with four bays and a ragged coast", _island),
        "glyph_s": ("outline of the letter S (a thick stroke)", _glyph_s),
        "noisy_circle_1000": ("a noisy circle with 1000 vertices", _noisy_circle_1000),
        "stroke_spiral": ("a pen stroke along a spiral of 3 turns, round ends", _stroke_spiral),
        "river": ("a meandering river reach with ragged banks, 380 vertices", _river),
    }


def _pen(centre: np.ndarray, width: float) -> np.ndarray:
    """A pen stroke: the centreline buffered by half the width (round ends and joins)."""
    import shapely

    g = shapely.LineString(centre).buffer(width / 2, quad_segs=6).simplify(0.01 * width)
    return np.asarray(shapely.geometry.polygon.orient(g, 1.0).exterior.coords)[:-1]


def _stroke_s() -> np.ndarray:
    """50 clicks along an S (the hand's jitter: 1 % of the height), a pen 1/12 of it wide."""
    rng = np.random.default_rng(50)
    t = np.linspace(0.0, 1.0, 50)
    x = 0.3 * np.sin(2 * np.pi * t) + 0.01 * rng.normal(size=50)
    y = t + 0.01 * rng.normal(size=50)
    return _pen(np.column_stack([x, y]), 1.0 / 12.0)


def _stroke_spiral() -> np.ndarray:
    """An Archimedean spiral of 3 turns (radius 1 to 4), a pen 0.5 wide."""
    a = np.linspace(0.0, 6.0 * np.pi, 240)
    r = 1.0 + 3.0 * a / (6.0 * np.pi)
    return _pen(np.column_stack([r * np.cos(a), r * np.sin(a)]), 0.5)


def _river() -> np.ndarray:
    """A river reach of quadmesh.families (seeded): meanders, ragged banks, flat ends."""
    from .families import river

    return river(np.random.default_rng([0, 4, 5])).vertices


def _ccw(v: np.ndarray) -> np.ndarray:
    x, y = v[:, 0], v[:, 1]
    area = np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)
    return v if area > 0 else v[::-1]


def generate() -> dict[str, dict]:
    """Build every example: name -> {"name", "description", "vertices" (n, 2) array}."""
    out = {}
    for name, (description, make) in _catalogue().items():
        v = _ccw(np.round(np.asarray(make(), dtype=np.float64), 12) + 0.0)
        out[name] = {"name": name, "description": description, "vertices": v}
    return out


def _dump(entry: dict) -> str:
    rows = ",\n".join(f"    [{x!r}, {y!r}]" for x, y in entry["vertices"].tolist())
    meta = {"name": entry["name"], "description": entry["description"], "n": len(entry["vertices"])}
    head = json.dumps(meta, ensure_ascii=False)[:-1]
    return f'{head},\n  "vertices": [\n{rows}\n  ]\n}}\n'


def main(argv: list[str] | None = None) -> int:
    """Regenerate ``resources/polygons/*.json`` (validated before writing)."""
    from .polygon import validate_polygon

    target = polygons_dir()
    target.mkdir(parents=True, exist_ok=True)
    for name, entry in generate().items():
        poly = validate_polygon(entry["vertices"])
        if poly.reversed_input or poly.n != len(entry["vertices"]):
            raise InputFormatError(f"example {name} is not a clean counter-clockwise polygon")
        (target / f"{name}.json").write_text(_dump(entry), encoding="utf-8")
        print(f"{name:24s} n = {poly.n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
