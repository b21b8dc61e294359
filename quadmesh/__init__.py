"""quadmesh: quadrilateral meshes of simple polygons with every new angle in [60°, 120°].

Implements C. J. Bishop, "Optimal angle bounds for quadrilateral meshes".
"""

from .decompose import Decomposition, decompose
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
from .mesh import QuadMesh, QualityReport, VerificationReport
from .pipeline import mesh_polygon
from .polygon import Polygon, validate_polygon
from .result import MeshOptions, MeshResult

__version__ = "0.1.0"

__all__ = [
    "Cancelled",
    "ConformalMapError",
    "Decomposition",
    "DecompositionError",
    "DiskConstructionError",
    "InputFormatError",
    "MeshOptions",
    "MeshResult",
    "MeshVerificationError",
    "Polygon",
    "PolygonError",
    "QuadMesh",
    "QuadmeshError",
    "QualityReport",
    "ThinPartError",
    "VerificationReport",
    "decompose",
    "mesh_polygon",
    "validate_polygon",
]
