"""Schwarz–Christoffel disk maps for the thick pieces.

* :class:`DiskMap` — solve ``f : D → Ω`` with ``f(0) = c``; forward, derivative, inverse,
  Taylor series (§1.10) and the accuracy checks of §1.7.
* :func:`inscribed_center` — centre and radius of the largest inscribed disk (§2.4).
* :func:`harmonic_measure` — harmonic measure of every side seen from a point (finite
  elements); the prevertex gaps are 2π times it, which makes it the solver's initial guess and
  the decomposition's crowding estimate.
"""

from .center import harmonic_measure, inscribed_center
from .diskmap import ConformalAccuracy, DiskMap, TaylorSeries

__all__ = ["ConformalAccuracy", "DiskMap", "TaylorSeries", "harmonic_measure", "inscribed_center"]
