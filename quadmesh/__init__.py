"""quadmesh: quadrilateral meshes of simple polygons with every new angle in [60°, 120°].

Implements C. J. Bishop, "Optimal angle bounds for quadrilateral meshes".
"""

from .errors import (
    Cancelled,
    ConformalMapError,
    DecompositionError,
    DiskConstructionError,
    InputFormatError,
    MeshVerificationError,
    PolygonError,
    QuadmeshError,
    ThinPartError,
)
from .polygon import Polygon, validate_polygon

__version__ = "0.1.0"

__all__ = [
    "Cancelled",
    "ConformalMapError",
    "DecompositionError",
    "DiskConstructionError",
    "InputFormatError",
    "MeshVerificationError",
    "Polygon",
    "PolygonError",
    "QuadmeshError",
    "ThinPartError",
    "validate_polygon",
]
