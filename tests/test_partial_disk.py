"""A run that fails in a thick piece after that piece's conformal map was solved keeps what the
piece computed — its prevertices, its arcs I_j and, where built, its disk mesh and image — in
the failure's PartialResult, next to the pieces that got further, and the render layers draw
them."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh import MeshOptions, mesh_polygon
from quadmesh.errors import (
    ConformalMapError,
    DiskConstructionError,
    PartialResult,
    QuadmeshError,
    ThinPartError,
)
from quadmesh.geometry import quad_angles_deg
from quadmesh.render import KIND_COLORS, build_layer
from tests.helpers import LSHAPE

#: No adaptive loop and no local repair: the L-shape's pushed-forward pentagon cells leave
#: [60°, 120°] (about 58.4°) and the run fails in its only thick piece, after the map.
STRICT = MeshOptions(adaptive=False, repair=False)


def _fail(polygon, options=None) -> tuple[QuadmeshError, PartialResult]:
    with pytest.raises(QuadmeshError) as info:
        mesh_polygon(polygon, options)
    partial = info.value.partial
    assert isinstance(partial, PartialResult)
    return info.value, partial


def _check_map_and_arcs(partial: PartialResult, p) -> None:
    """The piece's prevertices lie on T, one per piece vertex, and every arc I_j owned by a
    polygon vertex lies nearer that vertex's prevertex than any other prevertex."""
    piece = partial.decomposition.thick[p.index]
    pv = np.asarray(p.map.prevertices)
    assert pv.size == len(piece.z) == len(p.vertices)
    np.testing.assert_allclose(np.abs(pv), 1.0, atol=1e-12)
    iv = np.asarray(p.intervals)
    assert iv.ndim == 2 and iv.shape[1] == 2 and len(iv) == len(p.interval_owner) >= 1
    assert np.all(iv[:, 1] > 0) and iv[:, 1].sum() < 2 * np.pi  # disjoint arcs
    source = np.asarray(piece.source)
    for (start, length), owner in zip(iv, p.interval_owner, strict=True):
        if owner[0] != "vertex":
            continue
        k = int(np.flatnonzero(source == owner[1])[0])
        mid = np.exp(1j * (start + length / 2))
        assert int(np.argmin(np.abs(pv - mid))) == k


def test_angle_failure_keeps_the_failing_piece_with_its_disk():
    """The L-shape without the adaptive loop fails its angle check after the push-forward:
    the partial result holds its map, arcs, disk mesh and the image whose angles failed."""
    exc, partial = _fail(LSHAPE, STRICT)
    assert isinstance(exc, DiskConstructionError)
    assert partial.failed_piece == 0 and [p.index for p in partial.pieces] == [0]
    p = partial.pieces[0]
    _check_map_and_arcs(partial, p)
    assert len(p.intervals) == 6  # no channels: one arc per vertex
    assert p.disk is not None and p.n_used == 2 and p.depth_step_used == STRICT.depth_step
    assert np.all(np.abs(p.disk.vertices) <= 1 + 1e-12)
    # the kept image is the one that failed: some pentagon angle below 60°
    ang = quad_angles_deg(np.asarray(p.image), p.disk.quads)
    pent = np.asarray(p.disk.kind) == "pentagon"
    assert ang[pent].min() < 59.0 and np.all(np.isfinite(p.image))
    # the layers of the failing piece: 6 prevertices, 6 arcs I_j, the region W and its mesh
    pre = build_layer(partial, "prevertices", piece=0)
    assert pre.part("prevertices").mesh.n_points == 6
    assert pre.part("I arcs").mesh.n_lines == 6
    for name, kw in (("region_w", {"piece": 0}), ("conformal_images", {})):
        geo = build_layer(partial, name, **kw)
        assert sum(q.mesh.n_cells for q in geo.parts if q.label in KIND_COLORS) == len(p.disk.quads)
    assert build_layer(partial, "crosscuts").parts[0].mesh.n_lines == 6


def test_pieces_before_and_after_the_failing_one_are_kept():
    """The dumbbell (two thick pieces and a channel) fails in piece 1 without the adaptive
    loop; piece 0, which passed, is kept with its disk mesh and image too."""
    _, partial = _fail(_dumbbell(), STRICT)
    assert partial.failed_piece == 1
    assert [p.index for p in partial.pieces] == [0, 1]
    for p in partial.pieces:
        _check_map_and_arcs(partial, p)
        assert p.disk is not None and np.all(np.isfinite(p.image))
        assert any(o[0] == "channel" for o in p.interval_owner)


def _dumbbell() -> np.ndarray:
    from quadmesh.examples import load_example

    return np.asarray(load_example("dumbbell"))


def test_push_forward_failure_keeps_the_disk_without_image(monkeypatch):
    """A map that cannot be evaluated at the disk mesh: the piece's disk mesh is kept, its
    image is None, and only the disk layers (not the plane's pushed-forward ones) draw it."""
    import quadmesh.thick

    def broken(*args, **kwargs):
        raise FloatingPointError("overflow in the map's series")

    monkeypatch.setattr(quadmesh.thick, "push_forward", broken)
    exc, partial = _fail(LSHAPE)
    assert isinstance(exc, ConformalMapError) and "evaluating its conformal map" in str(exc)
    assert partial.failed_piece == 0
    (p,) = partial.pieces
    _check_map_and_arcs(partial, p)
    assert p.disk is not None and p.image is None
    assert build_layer(partial, "disk_mesh", piece=0).parts
    assert build_layer(partial, "prevertices", piece=0).part("J arcs").mesh.n_lines == 6
    assert build_layer(partial, "conformal_images").parts == []


def test_disk_construction_failure_keeps_map_and_arcs(monkeypatch):
    """Lemma 2.2's region cannot be built (forced, also at the wider fallback spacing): the
    piece keeps its prevertices and arcs, with no disk mesh; its disk layers show the
    prevertices and I arcs only."""
    import quadmesh.disk

    calls = []

    def refuse(intervals, **kwargs):
        calls.append(np.asarray(intervals).copy())
        raise DiskConstructionError("the expanded arcs interlock")

    monkeypatch.setattr(quadmesh.disk, "disk_mesh", refuse)
    exc, partial = _fail(LSHAPE)
    assert isinstance(exc, DiskConstructionError)
    assert partial.failed_piece == 0
    (p,) = partial.pieces
    _check_map_and_arcs(partial, p)
    assert p.disk is None and p.image is None
    np.testing.assert_array_equal(p.intervals, calls[0])  # the arcs handed to Lemma 2.2
    pre = build_layer(partial, "prevertices", piece=0)
    assert pre.part("prevertices").mesh.n_points == 6 and pre.part("I arcs").mesh.n_lines == 6
    assert "J arcs" not in [q.label for q in pre.parts]
    assert build_layer(partial, "region_w", piece=0).parts == []
    assert build_layer(partial, "crosscuts").parts == []


def test_thin_failure_keeps_every_piece_and_names_none(monkeypatch):
    """A thin part failing after every thick piece was meshed: all pieces are kept whole and
    no piece is named as the failing one."""
    import quadmesh.pipeline

    def refuse(*args, **kwargs):
        raise ThinPartError("the sector at vertex 3 cannot be meshed")

    monkeypatch.setattr(quadmesh.pipeline, "glue_thin_parts", refuse)
    hexagon = np.exp(2j * np.pi * np.arange(6) / 6)
    exc, partial = _fail(np.column_stack([hexagon.real, hexagon.imag]), STRICT)
    assert isinstance(exc, ThinPartError) and partial.failed_piece is None
    (p,) = partial.pieces
    _check_map_and_arcs(partial, p)
    assert p.disk is not None and np.all(np.isfinite(p.image))


def test_unsolved_maps_name_every_piece_and_keep_the_estimate(monkeypatch):
    """When the conformal map of a piece fails, the other pieces' maps are still solved: with
    both dumbbell pieces failing (their solve forced to stop at the harmonic-measure estimate,
    the path of the crowding rejection) the message names both parts, the partial result
    marks piece 0 as failed and piece 1 as failing too, and carries piece 0's estimated
    prevertices (on T, one per vertex, θ_0 = 0, spaced as 2π times the harmonic measure)."""
    from quadmesh.conformal import DiskMap, harmonic_measure
    from quadmesh.conformal import diskmap as dm
    from quadmesh.examples import load_example

    calls = []

    def refuse(cls, vertices, center=None, tol=1e-10, **kw):
        calls.append(len(vertices))
        w = np.asarray(vertices, dtype=np.complex128)
        gaps = 2 * np.pi * harmonic_measure(w, center)
        err = ConformalMapError("crowding: refused for the test")
        raise dm._estimated(err, gaps, 0, dm.ESTIMATE_KIND)

    monkeypatch.setattr(DiskMap, "from_polygon", classmethod(refuse))
    exc, partial = _fail(np.asarray(load_example("dumbbell")))
    thick = partial.decomposition.thick
    assert len(thick) == 2 and calls[:2] == [len(thick[0].z), len(thick[1].z)]
    assert isinstance(exc, ConformalMapError)
    text = str(exc)
    assert text.count("crowding: refused for the test") == 2
    for piece in thick:
        assert partial.decomposition.describe_piece(piece.index) in text
    assert partial.failed_piece == 0 and partial.other_failed == (1,) and partial.pieces == ()
    pre = np.asarray(partial.failed_prevertices)
    assert pre.shape == (len(thick[0].z),)
    np.testing.assert_allclose(np.abs(pre), 1.0, atol=1e-12)
    assert pre[0] == 1.0
    gaps = np.mod(np.angle(np.roll(pre, -1) / pre), 2 * np.pi)
    want = 2 * np.pi * harmonic_measure(np.asarray(thick[0].z), thick[0].center)
    np.testing.assert_allclose(gaps, want * (2 * np.pi / want.sum()), rtol=1e-9, atol=1e-12)
    assert "harmonic-measure estimate" in partial.failed_prevertices_kind
