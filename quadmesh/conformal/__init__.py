"""Schwarz–Christoffel disk maps for the thick pieces (CONFORMAL.md §1).

* :class:`DiskMap` — solve ``f : D → Ω`` with ``f(0) = c``; forward, derivative, inverse,
  Taylor series (§1.10) and the accuracy checks of §1.7.
* :func:`inscribed_center` — centre and radius of the largest inscribed disk (§2.4).
"""

from .center import inscribed_center
from .diskmap import ConformalAccuracy, DiskMap, TaylorSeries

__all__ = ["ConformalAccuracy", "DiskMap", "TaylorSeries", "inscribed_center"]
