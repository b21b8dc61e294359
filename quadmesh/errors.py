"""Errors raised by the quadmesh pipeline.

Every stage that cannot do its job raises a subclass of :class:`QuadmeshError` whose
``stage`` names the stage and whose message says why.
"""

from __future__ import annotations


class QuadmeshError(Exception):
    """Base class of every error raised on purpose by quadmesh.

    ``partial``: when :func:`~quadmesh.mesh_polygon` fails after the decomposition, a
    :class:`PartialResult` with what was computed up to there (so a viewer can show it), else
    None."""

    stage: str = "quadmesh"
    partial: object = None

    def __init__(self, message: str, *, stage: str | None = None) -> None:
        if stage is not None:
            self.stage = stage
        super().__init__(message)

    def __str__(self) -> str:
        return f"[{self.stage}] {super().__str__()}"


class PartialResult:
    """What a failed run computed before it stopped: the validated ``polygon``, its
    ``decomposition`` and the working ``origin`` (stage data are relative to it). Plane layers
    that need only these (``polygon``, ``thick_pieces``, ``crosscuts``) can be drawn from it by
    :func:`quadmesh.render.build_layer`; ``pieces`` and ``thin`` are empty."""

    def __init__(self, polygon: object, decomposition: object, origin: complex = 0j) -> None:
        self.polygon = polygon
        self.decomposition = decomposition
        self.origin = origin
        self.pieces: tuple = ()
        self.thin: tuple = ()


class PolygonError(QuadmeshError, ValueError):
    """The input polygon is invalid (too few points, non-finite, self-intersecting, ...)."""

    stage = "validate"


class InputFormatError(QuadmeshError, ValueError):
    """A polygon or mesh file cannot be read."""

    stage = "io"


class DecompositionError(QuadmeshError):
    """The thick/thin decomposition failed."""

    stage = "decompose"


class ConformalMapError(QuadmeshError):
    """The Schwarz–Christoffel map could not be computed to the required accuracy."""

    stage = "conformal"


class DiskConstructionError(QuadmeshError):
    """The disk construction (Lemma 2.2 and the piece meshes) failed."""

    stage = "disk"


class ThinPartError(QuadmeshError):
    """A thin part (vertex sector or channel) could not be meshed within the angle bounds."""

    stage = "thin"


class MeshVerificationError(QuadmeshError):
    """The assembled mesh failed verification (conformity, orientation, area or angles)."""

    stage = "verify"


class Cancelled(QuadmeshError):
    """The computation was cancelled through the progress callback."""

    stage = "cancelled"
