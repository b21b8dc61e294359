"""Assembly of the final mesh (paper §8, "Meshing the thin parts"): one global vertex
numbering for all stages, the pushed-forward thick pieces added first, then the thin parts glued
onto their crosscut vertices by index, never merged by distance — a vertex sector at every
polygon vertex (parabolic case), a log-spiral connector across every narrow channel
(hyperbolic case), each through a conformal collar when its crosscut is not round.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .errors import ThinPartError
from .result import MeshOptions, ThickPieceResult, ThinPartResult
from .thick import PieceWork, repair_note

__all__ = ["Assembler", "glue_thick_pieces", "glue_thin_parts"]


@dataclass
class Assembler:
    """Collects vertices and quads of all stages into one global numbering.

    Shared vertices are glued by index: a thin part receives
    the global ids of the crosscut vertices it was built on, never a merge by distance.
    """

    chunks: list[np.ndarray] = field(default_factory=list)
    quads: list[np.ndarray] = field(default_factory=list)
    source: list[np.ndarray] = field(default_factory=list)
    count: int = 0

    def add_vertices(self, z: np.ndarray) -> np.ndarray:
        ids = np.arange(self.count, self.count + z.size)
        self.chunks.append(np.asarray(z, dtype=np.complex128))
        self.count += z.size
        return ids

    def add_quads(self, quads: np.ndarray, source: int) -> None:
        self.quads.append(np.asarray(quads, dtype=np.int64))
        self.source.append(np.full(len(quads), source, dtype=np.int8))

    def vertices(self) -> np.ndarray:
        return np.concatenate(self.chunks) if self.chunks else np.zeros(0, complex)

    def all_quads(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.quads:
            return np.zeros((0, 4), np.int64), np.zeros(0, np.int8)
        return np.concatenate(self.quads), np.concatenate(self.source)


def _orient_to_walls(gamma_ids: np.ndarray, pts: np.ndarray, frame) -> np.ndarray:
    """Order a channel-side crosscut from wall 1 to wall 2 (wall 1 = the frame's real axis)."""
    w = (pts[[0, -1]] - frame.origin) / frame.direction
    d1 = np.abs(np.angle(w)) if frame.kind == "angled" else np.abs(w.imag)
    return gamma_ids if d1[0] <= d1[1] else gamma_ids[::-1]


def _walls_of(frame):
    from .thin.channel import Walls

    if frame.kind == "angled":
        return Walls.wedge(frame.origin, frame.direction, frame.beta)
    return Walls.parallel(frame.origin, frame.direction, frame.width)


def _glue(asm: Assembler, verts: np.ndarray, quads: np.ndarray, fixed: dict, source: int):
    """Add a thin-part mesh: vertices listed in ``fixed`` (local index -> global id) are
    the crosscut vertices it was built on; all others are new. Returns the global ids."""
    gl = np.full(verts.size, -1, dtype=np.int64)
    loc = np.fromiter(fixed.keys(), dtype=np.int64, count=len(fixed))
    gl[loc] = np.fromiter(fixed.values(), dtype=np.int64, count=len(fixed))
    own = gl < 0
    gl[own] = asm.add_vertices(verts[own])
    asm.add_quads(gl[np.asarray(quads)], source=source)
    return gl


def _collar(asm, thin, gamma, gamma_gl, walls, toward, part, what):
    """Conformal collar between a crosscut image and a straight (round) crosscut, glued
    onto the crosscut's global vertices; returns the straight crosscut's points and ids.
    ``part`` is the (kind, owner, source) of the thin part it belongs to."""
    from .thin.collar import conformal_collar

    try:
        col = conformal_collar(gamma, walls, toward=toward)
    except ThinPartError as exc:
        raise ThinPartError(f"{what}; collar: {exc.args[0]}") from exc
    kind, owner, source = part
    fixed = dict(zip(np.asarray(col.gamma_index).tolist(), gamma_gl.tolist()))
    cgl = _glue(asm, np.asarray(col.vertices), col.quads, fixed, source)
    thin.append(ThinPartResult(kind, owner, col, cgl))
    si = np.asarray(col.straight_index)
    return np.asarray(col.vertices)[si], cgl[si]


def _sector(corner, gamma: np.ndarray, gamma_gl: np.ndarray, options, asm, thin, dec):
    """Vertex sector (paper §8, parabolic case), through a conformal collar when the
    crosscut is not round about the vertex. Messages name the vertex as the user numbered
    it (``dec.polygon``)."""
    from .thin.collar import vertex_walls
    from .thin.parabolic import mesh_vertex_sector

    args = (corner.apex, corner.dir_out, float(corner.angle))
    try:
        sec = mesh_vertex_sector(*args, gamma, lam=options.sector_ratio)
    except ThinPartError as first:
        walls = vertex_walls(*args)
        vertex = dec.polygon.describe_vertex(corner.index)
        what = f"{vertex}: {first.args[0]}"
        part = ("parabolic", corner.index, 1)
        gamma, gamma_gl = _collar(asm, thin, gamma, gamma_gl, walls, "inner", part, what)
        try:
            sec = mesh_vertex_sector(*args, gamma, lam=options.sector_ratio)
        except ThinPartError as exc:
            raise ThinPartError(f"{vertex}: {exc.args[0]}") from exc
    fixed = dict(zip(np.asarray(sec.gamma_index).tolist(), gamma_gl.tolist()))
    gl = _glue(asm, np.asarray(sec.vertices), sec.quads, fixed, 1)
    thin.append(ThinPartResult("parabolic", corner.index, sec, gl))


def _channel(ch, ga, ga_gl, gb, gb_gl, asm, thin, dec):
    """Channel connector (paper §8, hyperbolic case) between the two thick pieces'
    crosscut images, each first straightened by a conformal collar if needed. Messages name
    the channel by its wall edges as the user numbered them (``dec``)."""
    from .thin.channel import mesh_channel

    walls = _walls_of(ch.frame)
    try:
        cm = mesh_channel(ga, gb, walls=walls)
    except ThinPartError as first:
        passage = dec.describe_channel(ch.id)
        what = f"{passage}: {first.args[0]}"
        part = ("hyperbolic", ch.id, 2)
        ga, ga_gl = _collar(asm, thin, ga, ga_gl, walls, "outer", part, what)
        gb, gb_gl = _collar(asm, thin, gb, gb_gl, walls, "inner", part, what)
        try:
            cm = mesh_channel(ga, gb, walls=walls)
        except ThinPartError as exc:
            raise ThinPartError(f"{passage}: {exc.args[0]}") from exc
    fixed = dict(zip(np.asarray(cm.gamma1_index).tolist(), ga_gl.tolist()))
    fixed.update(zip(np.asarray(cm.gamma2_index).tolist(), gb_gl.tolist()))
    gl = _glue(asm, np.asarray(cm.vertices), cm.quads, fixed, 2)
    thin.append(ThinPartResult("hyperbolic", ch.id, cm, gl))


def glue_thick_pieces(
    asm: Assembler,
    work: list[PieceWork],
    disks: list[tuple[object, np.ndarray]],
    dec,
    n: int,
    step: float,
    fixes: tuple[str, ...],
) -> tuple[list[ThickPieceResult], dict[tuple, tuple[np.ndarray, np.ndarray]]]:
    """Add every thick piece's pushed-forward disk mesh to ``asm``. Returns the pieces'
    results and, per crosscut (("vertex", polygon vertex) or ("channel", channel, end)), its
    image points and global vertex ids (a channel side ordered from wall 1 to wall 2)."""
    pieces: list[ThickPieceResult] = []
    gam: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
    for pd, (disk, image) in zip(work, disks):
        ids = asm.add_vertices(image)
        asm.add_quads(ids[disk.quads], source=0)
        src = np.asarray(dec.thick[pd.index].source)
        owners = []
        for j, (kind, idx) in enumerate(pd.owners):
            g = np.asarray(disk.gamma[j])
            if kind == "vertex":
                owners.append(("vertex", int(src[idx])))
                gam[("vertex", int(src[idx]))] = (image[g], ids[g])
            else:
                cc = dec.thick[pd.index].crosscuts[idx]
                ch = dec.channels[cc.channel]
                g = _orient_to_walls(g, image[g], ch.frame)
                owners.append(("channel", int(cc.channel), int(cc.end)))
                gam[("channel", int(cc.channel), int(cc.end))] = (image[g], ids[g])
        pieces.append(
            ThickPieceResult(
                index=pd.index,
                vertices=pd.z,
                map=pd.fmap,
                intervals=pd.intervals,
                interval_owner=tuple(owners),
                disk=disk,
                image=image,
                n_used=n,
                fixes=fixes + repair_note(pd),
                depth_step_used=step,
            )
        )
    return pieces, gam


def glue_thin_parts(
    asm: Assembler,
    dec,
    gam: dict[tuple, tuple[np.ndarray, np.ndarray]],
    options: MeshOptions,
    report: Callable[[str, float], None],
) -> list[ThinPartResult]:
    """Mesh every thin part and glue it onto the crosscut vertices ``gam`` of
    :func:`glue_thick_pieces`: a vertex sector per polygon corner, then a connector per
    channel. Raises :class:`~quadmesh.errors.ThinPartError` when one cannot be built."""
    thin: list[ThinPartResult] = []
    for corner in dec.corners:
        report("vertex sectors", 0.7 + 0.1 * corner.index / len(dec.corners))
        pts, gl = gam[("vertex", int(corner.index))]
        _sector(corner, pts, gl, options, asm, thin, dec)
    for ch in dec.channels:
        report("channels", 0.8)
        (ga, ga_gl), (gb, gb_gl) = gam[("channel", ch.id, 0)], gam[("channel", ch.id, 1)]
        _channel(ch, ga, ga_gl, gb, gb_gl, asm, thin, dec)
    return thin
