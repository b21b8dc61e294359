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
    piece's (a thin part, the final verification). ``failed_prevertices`` and
    ``failed_prevertices_kind``: when the failing piece's map could not be solved, the
    prevertex placement its :class:`ConformalMapError` carried (see there), else None and "".
    ``other_failed``: the other pieces whose conformal map failed too (indices; the run
    solves every piece's map before it stops). ``thin`` is empty. Every layer of
    :func:`quadmesh.render.build_layer` except ``thin_parts``, ``final_mesh`` and
    ``bad_quads`` can be drawn from it."""

    def __init__(
        self,
        polygon: object,
        decomposition: object,
        origin: complex = 0j,
        pieces: tuple = (),
        failed_piece: int | None = None,
        failed_prevertices: object = None,
        failed_prevertices_kind: str = "",
        other_failed: tuple = (),
    ) -> None:
        self.polygon = polygon
        self.decomposition = decomposition
        self.origin = origin
        self.pieces: tuple = tuple(pieces)
        self.failed_piece = failed_piece
        self.failed_prevertices = failed_prevertices
        self.failed_prevertices_kind = failed_prevertices_kind
        self.other_failed: tuple = tuple(other_failed)
        self.thin: tuple = ()

    @classmethod
    def of(
        cls, exc: QuadmeshError, polygon: object, decomposition: object, origin: complex = 0j
    ) -> PartialResult:
        """The partial result of the failure ``exc``: the piece stages and failing piece it
        (or the error it was raised from) carries."""
        pieces: tuple = ()
        failed: int | None = None
        pre: object = None
        kind = ""
        others: tuple = ()
        e: BaseException | None = exc
        while e is not None:
            others = others or tuple(getattr(e, "other_failed", ()))
            pieces = pieces or tuple(getattr(e, "piece_stages", ()))
            failed = failed if failed is not None else getattr(e, "piece", None)
            if pre is None and getattr(e, "prevertices", None) is not None:
                pre, kind = e.prevertices, str(getattr(e, "prevertices_kind", ""))
            e = e.__cause__
        if failed is None or any(p.index == failed for p in pieces):
            pre, kind = None, ""  # the failing piece has a map: its own prevertices are shown
        return cls(polygon, decomposition, origin, pieces, failed, pre, kind, others)


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
    """The Schwarz–Christoffel map could not be computed to the required accuracy.

    ``prevertices``: where the failed solve placed the piece's prevertices, when it had a
    placement (unit complex, in the piece's vertex order, the first at 1), else None;
    ``prevertices_kind`` says which placement: the harmonic-measure estimate the crowding
    check uses, the solver's last iterate, or a solution that failed its checks."""

    stage = "conformal"
    prevertices: object = None
    prevertices_kind: str = ""
    #: the other thick pieces (indices) whose map failed too, when the message names several
    other_failed: tuple = ()
    #: True when the piece has too many vertices for this machine's memory (the map was not
    #: attempted): no other route through the paper's construction would fare better
    too_large: bool = False


class DiskConstructionError(QuadmeshError):
    """The disk construction (Lemma 2.2 and the piece meshes) failed. ``distortion``: True when
    the pushed-forward mesh's angles stayed out of range after the adaptive loop (or with it
    off), False when the arcs could not be placed or the map crowds the mesh to degeneracy."""

    stage = "disk"
    distortion: bool = False


class ThinPartError(QuadmeshError):
    """A thin part (vertex sector or channel) could not be meshed within the angle bounds."""

    stage = "thin"


class MeshVerificationError(QuadmeshError):
    """The assembled mesh failed verification (conformity, orientation, area or angles)."""

    stage = "verify"


class Cancelled(QuadmeshError):
    """The computation was cancelled through the progress callback."""

    stage = "cancelled"
