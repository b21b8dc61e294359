"""Hyperbolic-geometry toolkit for the disk construction (paper §2§1).

Disk model D (``ds = 2|dz|/(1−|z|²)``, curvature −1), upper half-plane H (``ds = |dz|/y``),
Klein model for intersections.  Points are complex numbers; geodesics are pairs of ideal
endpoints ``(p, q)`` oriented ``p→q``; isometries are :class:`Isometry` pairs ``(M, sigma)``,
single or stacked.  All functions are vectorised over numpy arrays.
"""

from . import geodesic, hypercycle, isometry
from .geodesic import *  # noqa: F403  (names listed in geodesic.__all__)
from .hypercycle import *  # noqa: F403
from .isometry import *  # noqa: F403

__all__ = sorted([*geodesic.__all__, *hypercycle.__all__, *isometry.__all__])
