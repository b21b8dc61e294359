"""Quad mesh of a hyperbolic thin part: a channel between two straight walls and two crosscuts.

Paper: Bishop, "Optimal angle bounds for quadrilateral meshes", section "Meshing the thin
parts" (figure "HyperConnect"): the P vertices of crosscut gamma_1 are joined to the P vertices
of gamma_2 by polygonal chains through intermediate circular crosscuts; the chains approximate
logarithmic spirals, i.e. the image under exp of straight segments in log coordinates.

Walls (:class:`Walls`):

* ``Walls.wedge(origin, wall1_dir, beta)``: wall 1 is the ray from O in direction ``wall1_dir``,
  wall 2 the ray at angle ``beta`` (radians, counter-clockwise) from it; the channel lies between
  them. Coordinates: w = log((z - O)/wall1_dir) = (log r, angle).
* ``Walls.parallel(origin, direction, width)``: wall 1 is the line through ``origin`` with
  direction ``direction``, wall 2 the parallel line at distance ``width`` to its left.
  Coordinates: w = (z - origin)/direction (Cartesian strip coordinates).
* ``Walls.from_crosscuts(gamma1, gamma2)``: both walls are the lines through the crosscut
  endpoints (g1_0, g2_0) and (g1_{P-1}, g2_{P-1}); parallel when these lines are parallel.

In coordinates the channel is roughly the rectangle [x(gamma_1), x(gamma_2)] x [0, beta] (width
for parallel walls). Chain k is the segment from w1_k to w2_k, sampled where it meets the J
intermediate crosscuts x = x_j (equally spaced between the two crosscuts); mapped back, the
chains are log-spiral polygons and the crosscuts circular arcs about O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ThinPartError
from .mesh import KIND_CHAIN, ChannelMesh, quad_signed_areas, require_angles

__all__ = ["Walls", "default_crosscut_count", "mesh_channel"]


@dataclass(frozen=True)
class Walls:
    """The two straight walls of a channel (see the module docstring).

    Attributes:
        origin: O (wedge) or a point of wall 1 (parallel walls).
        direction: unit direction of wall 1 (from O for a wedge).
        beta: angle from wall 1 to wall 2 (radians) for a wedge, None for parallel walls.
        width: distance of wall 2 to the left of wall 1 for parallel walls, None for a wedge.
    """

    origin: complex
    direction: complex
    beta: float | None = None
    width: float | None = None

    @classmethod
    def wedge(cls, origin: complex, wall1_dir: complex, beta: float) -> Walls:
        """Walls on two rays from ``origin`` with angle ``beta`` in (0, π) between them."""
        if not (0.0 < beta < math.pi) or abs(wall1_dir) == 0.0:
            raise ThinPartError(f"invalid wedge walls (beta = {beta!r})")
        return cls(complex(origin), complex(wall1_dir) / abs(wall1_dir), float(beta), None)

    @classmethod
    def parallel(cls, origin: complex, direction: complex, width: float) -> Walls:
        """Two parallel walls: wall 2 is ``width`` to the left of wall 1."""
        if not width > 0.0 or abs(direction) == 0.0:
            raise ThinPartError(f"invalid parallel walls (width = {width!r})")
        return cls(complex(origin), complex(direction) / abs(direction), None, float(width))

    @classmethod
    def from_crosscuts(
        cls, gamma1: np.ndarray, gamma2: np.ndarray, parallel_tol: float = 1e-9
    ) -> Walls:
        """Walls through the crosscut endpoints; wall 1 through g1_0 and g2_0."""
        a0, a1 = complex(gamma1[0]), complex(gamma2[0])
        b0, b1 = complex(gamma1[-1]), complex(gamma2[-1])
        d1, d2 = a1 - a0, b1 - b0
        if abs(d1) == 0.0 or abs(d2) == 0.0:
            raise ThinPartError("crosscut endpoints coincide; walls undefined")
        cross = (d1.conjugate() * d2).imag / (abs(d1) * abs(d2))
        if abs(cross) <= parallel_tol:
            u = d1 / abs(d1)
            width = ((b0 - a0) / u).imag
            if width < 0:
                raise ThinPartError("wall 2 is not to the left of wall 1")
            return cls.parallel(a0, u, width)
        # intersection O = a0 + s d1 = b0 + t d2
        mat = np.array([[d1.real, -d2.real], [d1.imag, -d2.imag]])
        s, _ = np.linalg.solve(mat, np.array([(b0 - a0).real, (b0 - a0).imag]))
        origin = a0 + s * d1
        u1 = a0 - origin if abs(a0 - origin) > abs(a1 - origin) else a1 - origin
        u2 = b0 - origin if abs(b0 - origin) > abs(b1 - origin) else b1 - origin
        beta = float(np.angle(u2 / u1))
        if beta < 0:
            raise ThinPartError("crosscuts are not ordered from wall 1 to wall 2")
        return cls.wedge(origin, u1, abs(beta))

    @property
    def is_parallel(self) -> bool:
        """True for parallel walls."""
        return self.beta is None

    @property
    def span(self) -> float:
        """beta (wedge) or width (parallel): the extent of the channel across, in coordinates."""
        return float(self.width if self.beta is None else self.beta)

    def to_coords(self, z: np.ndarray) -> np.ndarray:
        """Log coordinates (wedge) or strip coordinates (parallel) of the points ``z``."""
        rel = (np.asarray(z, dtype=np.complex128) - self.origin) / self.direction
        if self.beta is None:
            return rel
        w = np.log(rel)
        return w.real + 1j * np.where(w.imag < -math.pi / 2, w.imag + 2 * math.pi, w.imag)

    def from_coords(self, w: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_coords`; points with y = 0 / y = span land exactly on the walls."""
        w = np.asarray(w, dtype=np.complex128)
        if self.beta is None:
            z = self.origin + self.direction * w
            return z
        return self.origin + self.direction * np.exp(w)

    def wall_point(self, wall: int, x: np.ndarray) -> np.ndarray:
        """Points of wall 1 or 2 at coordinate x (exactly on the wall line up to rounding)."""
        x = np.asarray(x, dtype=float)
        if self.beta is None:
            off = 0.0 if wall == 1 else self.width
            return self.origin + self.direction * (x + 1j * off)
        d = self.direction if wall == 1 else self.direction * np.exp(1j * self.beta)
        return self.origin + d * np.exp(x)


def default_crosscut_count(dy_max: float, eta_deg: float = 5.0) -> int:
    """J with J + 1 = ceil(max|dy| / eta): each chain segment turns <= eta."""
    return max(0, math.ceil(dy_max / math.radians(eta_deg) - 1e-12) - 1)


def mesh_channel(
    gamma1: np.ndarray,
    gamma2: np.ndarray,
    *,
    walls: Walls | None = None,
    eta_deg: float = 5.0,
    n_intermediate: int | None = None,
    bounded_geometry: bool = False,
    max_intermediate: int = 4096,
    tol: float = 1e-9,
) -> ChannelMesh:
    """Quad-mesh a hyperbolic thin part between crosscuts ``gamma1`` and ``gamma2``.

    Both crosscuts have P vertices ordered from wall 1 to wall 2, with their first and last
    vertices on wall 1 resp. wall 2. ``walls`` defaults to :meth:`Walls.from_crosscuts`. The
    number J of intermediate crosscuts is ``n_intermediate`` if given, else from the turning
    budget ``eta_deg`` (J + 1 = ceil(max_k |y2_k - y1_k| / eta), wedge only; parallel walls give
    straight chains, J = 0), raised to J + 1 >= ell / (min vertical gap) when
    ``bounded_geometry`` (cells about square in coordinates; end of the paper's section).
    Paper: section "Meshing the thin parts", figure "HyperConnect"

    Raises:
        ThinPartError: different vertex counts, endpoints off the walls, crosscuts not ordered
            across the channel or overlapping along it, J above ``max_intermediate``, or a
            produced angle outside [60°, 120°].
    """
    g1 = np.asarray(gamma1, dtype=np.complex128).ravel()
    g2 = np.asarray(gamma2, dtype=np.complex128).ravel()
    n_pts = len(g1)
    if len(g2) != n_pts or n_pts < 2:
        raise ThinPartError(
            f"crosscuts must have the same number (>= 2) of vertices, got {len(g1)} and {len(g2)}"
        )
    if not (np.all(np.isfinite(g1)) and np.all(np.isfinite(g2))):
        raise ThinPartError("crosscut has non-finite vertices")
    if walls is None:
        walls = Walls.from_crosscuts(g1, g2)
    span = walls.span
    w1, w2 = walls.to_coords(g1), walls.to_coords(g2)
    scale = max(np.ptp(np.concatenate([w1.real, w2.real])), span)
    for w, name in ((w1, "gamma1"), (w2, "gamma2")):
        if abs(w[0].imag) > tol * scale or abs(w[-1].imag - span) > tol * scale:
            raise ThinPartError(f"{name} does not start on wall 1 and end on wall 2")
        if np.any(np.diff(w.imag) <= 0):
            raise ThinPartError(f"{name} is not ordered from wall 1 to wall 2")
    w1 = w1.real + 1j * np.concatenate([[0.0], w1.imag[1:-1], [span]])
    w2 = w2.real + 1j * np.concatenate([[0.0], w2.imag[1:-1], [span]])
    direction = 1.0 if w2.real.mean() > w1.real.mean() else -1.0
    x_in = (w1.real * direction).max()
    x_out = (w2.real * direction).min()
    if x_out <= x_in:
        raise ThinPartError("the two crosscuts overlap along the channel")

    if n_intermediate is not None:
        n_mid = int(n_intermediate)
    elif walls.is_parallel:
        n_mid = 0
    else:
        n_mid = default_crosscut_count(float(np.max(np.abs(w2.imag - w1.imag))), eta_deg)
    if bounded_geometry:
        gap = min(np.diff(w1.imag).min(), np.diff(w2.imag).min())
        ell = x_out - x_in
        n_mid = max(n_mid, math.ceil(ell / gap) - 1)
    if n_mid > max_intermediate:
        raise ThinPartError(
            f"channel needs {n_mid} intermediate crosscuts (limit {max_intermediate})"
        )

    # Intermediate crosscuts x = x_j between the crosscuts; chain k meets them linearly in x.
    xs = direction * (x_in + (x_out - x_in) * np.arange(1, n_mid + 1) / (n_mid + 1))
    t = (xs[:, None] - w1.real[None, :]) / (w2.real - w1.real)[None, :]
    ys = w1.imag[None, :] + t * (w2.imag - w1.imag)[None, :]
    ring = walls.from_coords(xs[:, None] + 1j * ys)
    if n_mid:
        ring[:, 0] = walls.wall_point(1, xs)
        ring[:, -1] = walls.wall_point(2, xs)

    verts = np.concatenate([g1, g2, ring.ravel()])
    g1_idx = np.arange(n_pts)
    g2_idx = np.arange(n_pts, 2 * n_pts)
    ring_idx = 2 * n_pts + np.arange(n_mid * n_pts).reshape(n_mid, n_pts)
    grid = np.vstack([g1_idx[None, :], ring_idx, g2_idx[None, :]])
    quads = np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1)
    quads = quads.reshape(-1, 4)
    if quad_signed_areas(verts, quads[:1])[0] < 0:
        quads = quads[:, ::-1]
    mesh = ChannelMesh(
        vertices=verts,
        quads=quads,
        kind=np.full(len(quads), KIND_CHAIN, dtype=np.uint8),
        gamma1_index=g1_idx,
        gamma2_index=g2_idx,
        wall1=grid[:, 0].copy(),
        wall2=grid[:, -1].copy(),
        n_intermediate=n_mid,
    )
    require_angles(verts, quads, np.ones(quads.shape, dtype=bool), 60.0, 120.0, "channel mesh")
    return mesh
