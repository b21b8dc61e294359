"""Pictures of the disk construction (paper §3, Figure "W4"): tessellation, pieces of W, mesh.

``render_disk_demo(path)`` draws, for a bundled example, the tiles of T5 near W, the pieces of
Lemma 2.2 coloured by kind, and the conforming quad mesh of :func:`disk_mesh`.  matplotlib is
imported lazily inside the function (the core needs only numpy/scipy).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["EXAMPLES", "render_disk_demo", "spread_intervals"]

EXAMPLES: dict[str, tuple[NDArray[np.float64], float]] = {
    "three": (np.array([[0.3, 0.01], [2.4, 0.015], [4.3, 0.008]]), 16.0),
    "one": (np.array([[1.0, 0.02]]), 16.0),
    "five": (
        np.array([[0.2, 0.006], [1.5, 0.004], [2.8, 0.008], [4.0, 0.005], [5.2, 0.006]]),
        25.0,
    ),
}
"""Interval sets (start, length) and A of the worked examples (3 intervals A=16,
1 interval A=16, 5 intervals A=25)."""


def spread_intervals(m: int, A: float, seed: int = 0) -> NDArray[np.float64]:
    """``m`` random, well-spread arcs whose A-fold expansions are disjoint (for benchmarks)."""
    rng = np.random.default_rng(seed)
    sp = 2.0 * np.pi / m
    c = np.arange(m) * sp + rng.uniform(-0.1, 0.1, m) * sp
    ell = sp / (A * 1.3) * rng.uniform(0.2, 1.0, m)
    return np.column_stack([np.mod(c - ell / 2.0, 2.0 * np.pi), ell])


def _p0_edge_samples(k: int = 16) -> NDArray[np.complex128]:
    """Points along P0's 5 edges (on their geodesic circles), shape (5, k)."""
    from .tessellation import EDGE_CENTERS, P0_VERTICES

    out = np.empty((5, k), dtype=np.complex128)
    for e in range(5):
        c = EDGE_CENTERS[e]
        a0 = np.angle(P0_VERTICES[e] - c)
        a1 = np.angle(P0_VERTICES[(e + 1) % 5] - c)
        da = np.angle(np.exp(1j * (a1 - a0)))
        out[e] = c + abs(P0_VERTICES[e] - c) * np.exp(1j * (a0 + da * np.linspace(0, 1, k)))
    return out


def render_disk_demo(
    path: str,
    example: str = "three",
    *,
    n: int = 2,
    depth_step: float = 0.25,
    dpi: int = 100,
) -> None:
    """Draw the disk construction for a bundled example and save it as a PNG at ``path``.

    Left: the tessellation T5 (grey), the pieces of W from Lemma 2.2 (pentagons grey, Carleson
    quadrilaterals blue, Carleson triangles red, inner triangles ``T_i`` dark red), the
    geodesics ``γ_j`` (green) and the intervals ``I_j`` (magenta).  Right: the quad mesh of
    :func:`~quadmesh.disk.assembly.disk_mesh` with the same colours.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    from .assembly import disk_mesh
    from .tessellation import generate_tiles

    iv, A = EXAMPLES[example]
    D = disk_mesh(iv, A=A, n=n, depth_step=depth_step)
    R = D.pieces
    colours = {
        "pentagon": "#c8c8c8",
        "carleson_quadrilateral": "#8fb4e3",
        "carleson_triangle": "#eb9a9a",
    }
    fc = np.array([colours[k] for k in D.kind], dtype=object)
    fc[D.inner] = "#b03030"
    poly = D.vertices[D.quads]
    xy = np.stack([poly.real, poly.imag], axis=-1)

    # piece outlines: mesh edges between different pieces, and boundary edges
    e = np.stack([D.quads, np.roll(D.quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    pc = np.repeat(D.piece, 4)
    key = np.sort(e, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks, ps = key[order], pc[order]
    same_next = np.all(ks[1:] == ks[:-1], axis=1)
    outline = np.ones(ks.shape[0], dtype=bool)
    pair = np.flatnonzero(same_next)
    inside = ps[pair] == ps[pair + 1]
    outline[pair[inside]] = False
    outline[pair[inside] + 1] = False
    seg = D.vertices[ks[outline]]
    seg_xy = np.stack([seg.real, seg.imag], axis=-1)

    tiles, _ = generate_tiles(min_diameter=0.03)
    samp = _p0_edge_samples()
    te = tiles.apply_rows(samp.ravel()).reshape(-1, samp.shape[1])
    te_xy = np.stack([te.real, te.imag], axis=-1)

    fig, axes = plt.subplots(1, 2, figsize=(12.0, 6.3))
    t = np.linspace(0, 2 * np.pi, 721)
    for ax in axes:
        ax.plot(np.cos(t), np.sin(t), color="black", lw=0.8)
        ax.set_aspect("equal")
        ax.set_xlim(-1.03, 1.03)
        ax.set_ylim(-1.03, 1.03)
        ax.axis("off")
    ax = axes[0]
    ax.add_collection(LineCollection(te_xy, colors="#dddddd", linewidths=0.4))
    ax.add_collection(PolyCollection(xy, facecolors=fc, edgecolors="none", alpha=0.9))
    ax.add_collection(LineCollection(seg_xy, colors="black", linewidths=0.5))
    for g in D.gamma:
        ax.plot(D.vertices[g].real, D.vertices[g].imag, color="#1a9a1a", lw=1.6)
    for s, ell in R.intervals:
        a = np.linspace(s, s + ell, 30)
        ax.plot(1.012 * np.cos(a), 1.012 * np.sin(a), color="magenta", lw=3.0)
    ax.set_title(
        f"Lemma 2.2: W for {R.m} interval(s), A = {R.A:g}: {R.n_pentagons} pentagons, "
        f"{len(R.quads)} C-quads, {len(R.triangles)} C-triangles",
        fontsize=9,
    )
    ax = axes[1]
    ax.add_collection(PolyCollection(xy, facecolors=fc, edgecolors="#333333", linewidths=0.12))
    ax.add_collection(LineCollection(seg_xy, colors="black", linewidths=0.5))
    for g in D.gamma:
        ax.plot(D.vertices[g].real, D.vertices[g].imag, color="#1a9a1a", lw=1.2)
    ax.set_title(
        f"disk_mesh: {D.quads.shape[0]} quads (n = {n}, depth step {depth_step}); "
        "dark red: inner triangles T_i",
        fontsize=9,
    )
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.94, wspace=0.03)
    import io

    from PIL import Image  # a matplotlib dependency

    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format="png")
    plt.close(fig)
    buf.seek(0)
    with Image.open(buf) as im:  # palette PNG: same picture, a third of the size
        im.convert("RGB").quantize(colors=128).save(path, optimize=True)
