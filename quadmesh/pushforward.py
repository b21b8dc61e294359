"""The push-forward of a disk mesh into a thick piece (paper §7): f = the Schwarz–Christoffel
map at every vertex, circle vertices put exactly on their polygon side, and inside every inner
triangle T_i the linear map h(ζ) = g(c) + (ζ − c)·g'(c), g = f∘τ⁻¹, so that the model angles of
the T_i quads survive exactly. Also the rotated normalisation f(e^{−iψ}z) of a map
(:class:`RotatedMap`, chosen by :func:`quadmesh.arcs.best_rotation`).
"""

from __future__ import annotations

import numpy as np

from .progress import checkpoint, span

__all__ = ["RotatedMap", "evaluate_map", "project_to_sides", "push_forward", "triangle_centres"]


def project_to_sides(
    w: np.ndarray, t: np.ndarray, theta: np.ndarray, zpoly: np.ndarray
) -> np.ndarray:
    """Put images of circle points exactly on their polygon side.

    A point e^{it} of the circle between prevertices θ_k and θ_{k+1} maps to side
    [w_k, w_{k+1}]; the computed value carries quadrature error, so it is replaced by its
    orthogonal projection onto that segment. ``t`` and ``theta`` may be long double (the
    side of a circle vertex next to a crowded prevertex is then decided at ~1e-19).
    """
    order = np.argsort(theta)
    ts = theta[order]
    two_pi = 2 * np.pi if ts.dtype != np.longdouble else 2 * np.longdouble(np.pi)
    pos = np.searchsorted(ts, np.mod(t, two_pi), side="right") - 1
    k = order[np.mod(pos, theta.size)]
    a = zpoly[k]
    b = zpoly[(k + 1) % zpoly.size]
    d = b - a
    s = np.clip(((w - a) * np.conj(d)).real / np.abs(d) ** 2, 0.0, 1.0)
    return a + s * d


def push_forward(fmap, disk, theta: np.ndarray, zpoly: np.ndarray) -> np.ndarray:
    """Images in the plane of the disk-mesh vertices (paper §7).

    f at every vertex (by per-piece power series where they converge), circle vertices projected
    onto their side, and inside each inner triangle T_i
    the linear map h(ζ) = g(c) + (ζ − c)·g'(c) with g = f∘τ⁻¹ (a similarity, so the model
    angles of the T_i quads survive exactly).

    Every evaluation uses exact offsets (the disk mesh's extended-precision frames,
    :meth:`~quadmesh.disk.DiskMesh.offsets_from`), not the complex128 vertices: cells of
    1e-15 next to prevertex gaps of 1e-13 (crowded pieces) keep their shape; circle vertices
    find their side from their long double angle, the triangle centres τ⁻¹(c) come in long
    double from the apex frames.
    """
    with span(0.0, 0.8):
        image = evaluate_map(fmap, disk)
    circ = np.flatnonzero(np.asarray(disk.on_circle, dtype=bool))
    if circ.size:
        ang = np.angle(disk.exact_vertices()[circ])
        th = getattr(fmap, "theta_ld", None)
        if th is None:  # a map without crowded clusters: float64 angles suffice
            th, ang = theta, ang.astype(float)
        image[circ] = project_to_sides(image[circ], ang, th, zpoly)
    tris = disk.triangles
    checkpoint(0.85)
    if len(tris):
        idx = np.concatenate([np.asarray(t.inner_vertices) for t in tris])
        zeta = np.concatenate([np.asarray(t.inner_model) for t in tris])
        tid = np.repeat(np.arange(len(tris)), [len(t.inner_vertices) for t in tris])
        apex, off, dzc = triangle_centres(tris)
        with span(0.85, 1.0):
            gc, fpc = evaluate_map(fmap, frames=apex, offsets=off)
        dgc = fpc * dzc
        c0 = np.array([t.center for t in tris], dtype=complex)
        image[idx] = gc[tid] + (zeta - c0[tid]) * dgc[tid]
    return image


def triangle_centres(tris) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """τ⁻¹(c) and (τ⁻¹)'(c) for every Carleson triangle, c the model centre of T_i.

    τ⁻¹ = φ_a⁻¹ ∘ τ_local (a = the triangle's apex frame, in long double) is evaluated in this
    factored form: ``τ⁻¹(c) − a = u(1 − |a|²)/(1 + āu)`` with ``u = τ_local(c)`` and
    ``1 − |a|²`` from the long double apex, which keeps relative accuracy for tiny triangles
    near the circle (a centre that neither complex128 nor long double resolves). Returns the
    apices ``a`` (clongdouble), the offsets ``τ⁻¹(c) − a`` (complex128) and ``(τ⁻¹)'(c)``.
    """
    from .disk.tessellation import frame_offsets, one_minus_abs2

    loc = np.stack([np.asarray(t.tau_local) for t in tris])
    a = np.array([t.frame_ld for t in tris], dtype=np.clongdouble)
    c0 = np.array([t.center for t in tris], dtype=complex)
    p, q, r, s = loc[:, 0, 0], loc[:, 0, 1], loc[:, 1, 0], loc[:, 1, 1]
    u = (p * c0 + q) / (r * c0 + s)
    du = (p * s - q * r) / (r * c0 + s) ** 2
    off = frame_offsets(a, u)
    a64 = a.astype(np.complex128)
    dphi = one_minus_abs2(a) / (1.0 + np.conj(a64) * u) ** 2
    return a, off, dphi * du


def evaluate_map(fmap, disk=None, *, frames=None, offsets=None):
    """f at all disk-mesh vertices (``disk``), grouped by piece for the power-series
    evaluator, with the exact offsets of the disk mesh (``DiskMesh.offsets_from``); or
    ``(f, f')`` at the points ``frames + offsets`` (long double frame points, complex128
    offsets with full relative accuracy; grouped in cells as by ``DiskMap.__call__``).

    A map rotated by :func:`quadmesh.arcs.best_rotation` is evaluated through its base map, with the
    points and offsets rotated back (``f_ψ(z) = f(z/r)``, ``r = e^{iψ}``)."""
    rotated = isinstance(fmap, RotatedMap)
    base = fmap.base if rotated else fmap
    r = fmap._r if rotated else 1.0
    r_ld = np.clongdouble(r)
    if frames is not None:
        fr = np.asarray(frames, dtype=np.clongdouble).ravel()
        of = np.asarray(offsets, dtype=np.complex128).ravel()

        def point_offsets(refs: np.ndarray, index: np.ndarray) -> np.ndarray:
            return ((fr[index] - refs * r_ld).astype(np.complex128) + of[index]) / r

        approx = (fr.astype(np.complex128) + of) / r
        f, fp = base.map_clusters(approx, None, None, derivative=True, offsets=point_offsets)
        return f, fp / r
    if rotated:

        def vertex_offsets(refs: np.ndarray, index: np.ndarray) -> np.ndarray:
            return disk.offsets_from(refs * r_ld, index) / r

    else:
        vertex_offsets = disk.offsets_from
    return np.asarray(
        base.map_clusters(
            disk.vertices / r,
            disk.vertex_piece,
            disk.piece_center_ld / r_ld,
            offsets=vertex_offsets,
        )
    )


class RotatedMap:
    """The map z ↦ f(e^{−iψ}z) of a :class:`~quadmesh.conformal.DiskMap` f: the same thick
    piece with the same f(0), prevertices rotated by ψ (see :func:`quadmesh.arcs.best_rotation`).

    Provides what the pipeline and the viewer use: ``theta``, ``prevertices``, evaluation
    (``__call__``, ``derivative``, ``map_clusters``, ``direct``), ``inverse``; rotation-free
    data (vertices, angles, accuracy, …) are those of ``base``.
    """

    _SHARED = frozenset(
        (
            "vertices n center angles beta gaps residual iterations continuation_steps "
            "solve_time accuracy"
        ).split()
    )

    def __init__(self, base, psi: float) -> None:
        self.base = base
        self.rotation = float(psi)
        self._r = complex(np.exp(1j * psi))
        self.theta = np.mod(np.asarray(base.theta, dtype=float) + psi, 2 * np.pi)
        self.prevertices = np.asarray(base.prevertices) * self._r
        th_ld = getattr(base, "theta_ld", None)
        if th_ld is not None:  # crowded maps: the sides of circle points decided at ~1e-19
            two_pi = 2 * np.longdouble(np.pi)
            self.theta_ld = np.mod(np.asarray(th_ld, dtype=np.longdouble) + psi, two_pi)

    prevertex_angles = property(lambda self: self.theta, doc="Alias of ``theta``.")

    def __getattr__(self, name: str):
        if name in RotatedMap._SHARED:
            return getattr(self.base, name)
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")

    def __call__(self, z: np.ndarray) -> np.ndarray:
        return self.base(np.asarray(z, dtype=np.complex128) / self._r)

    def direct(self, z: np.ndarray) -> np.ndarray:
        return self.base.direct(np.asarray(z, dtype=np.complex128) / self._r)

    def derivative(self, z: np.ndarray) -> np.ndarray:
        return self.base.derivative(np.asarray(z, dtype=np.complex128) / self._r) / self._r

    def map_clusters(self, points, cluster_ids, centers, derivative: bool = False):
        r = self._r
        got = self.base.map_clusters(
            np.asarray(points, dtype=np.complex128) / r,
            cluster_ids,
            np.asarray(centers, dtype=np.complex128) / r,
            derivative,
        )
        return (got[0], got[1] / r) if derivative else got

    def inverse(self, w: np.ndarray, tol: float = 1e-14) -> np.ndarray:
        return self.base.inverse(w, tol) * self._r
