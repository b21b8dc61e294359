"""Errors raised by the quadmesh pipeline.

Every stage that cannot do its job raises a subclass of :class:`QuadmeshError` whose
``stage`` names the stage and whose message says why.
"""

from __future__ import annotations


class QuadmeshError(Exception):
    """Base class of every error raised on purpose by quadmesh.

    ``partial``: when :func:`~quadmesh.mesh_polygon` fails after the decomposition, a
    :class:`PartialResult` with what was computed up to there (so a viewer can show it), else
    None. ``piece``: the index (in ``Decomposition.thick``) of the thick piece that failed,
    None when the failure is not one piece's. ``piece_stages``: what the thick pieces had
    computed when it was raised (:attr:`PartialResult.pieces`), set by the thick-piece stage
    on its way out."""

    stage: str = "quadmesh"
    partial: object = None
    piece: int | None = None
    piece_stages: tuple = ()

    def __init__(self, message: str, *, stage: str | None = None, piece: int | None = None) -> None:
        if stage is not None:
            self.stage = stage
        if piece is not None:
            self.piece = piece
        super().__init__(message)

    def __str__(self) -> str:
        return f"[{self.stage}] {super().__str__()}"


class PartialResult:
    """What a failed run computed before it stopped: the validated ``polygon``, its
    ``decomposition`` and the working ``origin`` (stage data are relative to it), and per thick
    piece whose conformal map was solved what that piece computed (``pieces``).

    ``pieces``: :class:`~quadmesh.result.ThickPieceResult` objects in ``Decomposition.thick``
    order, each with its ``map`` (prevertices on the unit circle) and, where the stage got
    that far, its ``intervals`` (the arcs I_j; (0, 2) when they could not be chosen), its
    ``disk`` mesh and its pushed-forward ``image`` (None where they were not built). Pieces
    whose map could not be solved are absent. ``failed_piece``: the index (in
    ``Decomposition.thick``) of the piece that failed, None when the failure is not one
    piece's (a thin part, the final verification). ``thin`` is empty. Every layer of
    :func:`quadmesh.render.build_layer` except ``thin_parts``, ``final_mesh`` and
    ``bad_quads`` can be drawn from it."""

    def __init__(
        self,
        polygon: object,
        decomposition: object,
        origin: complex = 0j,
        pieces: tuple = (),
        failed_piece: int | None = None,
    ) -> None:
        self.polygon = polygon
        self.decomposition = decomposition
        self.origin = origin
        self.pieces: tuple = tuple(pieces)
        self.failed_piece = failed_piece
        self.thin: tuple = ()

    @classmethod
    def of(
        cls, exc: QuadmeshError, polygon: object, decomposition: object, origin: complex = 0j
    ) -> PartialResult:
        """The partial result of the failure ``exc``: the piece stages and failing piece it
        (or the error it was raised from) carries."""
        pieces: tuple = ()
        failed: int | None = None
        e: BaseException | None = exc
        while e is not None and not (pieces and failed is not None):
            pieces = pieces or tuple(getattr(e, "piece_stages", ()))
            failed = failed if failed is not None else getattr(e, "piece", None)
            e = e.__cause__
        return cls(polygon, decomposition, origin, pieces, failed)


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
