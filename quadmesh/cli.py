"""The ``quadmesh`` command line: mesh a polygon, check a mesh, describe a polygon.

Subcommands (``quadmesh <command> --help`` for details):

* ``mesh POLYGON -o MESH [--jobs N]``: run Bishop's construction
  (:func:`quadmesh.pipeline.mesh_polygon`, the thick pieces in N worker processes) and write
  the verified mesh;
* ``check MESH --polygon POLYGON``: verify a mesh file against a polygon
  (:meth:`quadmesh.mesh.QuadMesh.verify`) and print its report, including the edge lengths
  against the polygon's local feature size (smallest ratio and where, median, shares of
  edges below 1/1000 and 1/50; measured, never a reason to refuse);
* ``batch DIR -o OUTDIR [--jobs N] [--method M] [--size H] [--format F] [--timeout S]
  [--stats]``: mesh every polygon file of a folder (:func:`quadmesh.batch.mesh_files`), one
  mesh each, and print a table;
  exit code 0 if all were meshed, 1 if some were not (listed);
* ``info POLYGON``: vertex count, area and angle summary of a polygon file;
* ``disk-demo -o disk.png``: picture of the disk construction (Lemma 2.2).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import InputFormatError, MeshVerificationError, PolygonError, QuadmeshError
from .io import MESH_FORMATS
from .mesh import ANGLE_TOL_DEG

__all__ = ["EXIT_INPUT", "EXIT_INVALID", "EXIT_OK", "EXIT_STAGE", "build_parser", "main"]

EXIT_OK = 0
EXIT_INVALID = 1
EXIT_INPUT = 2
EXIT_STAGE = 3

_EPILOG = """\
exit codes:
  0  success (for check: the mesh is valid and every new angle lies in [60°, 120°])
  1  the mesh is invalid (check failed, or the mesher's own verification failed);
     for batch: some files were not meshed (listed at the end)
  2  usage or input error (unreadable file, invalid polygon, bad option value)
  3  a mesher stage failed (decomposition, conformal map, disk construction, thin parts)

polygon files: .json {"vertices": [[x, y], ...]}, .csv/.txt (two columns), .geojson,
.svg (first closed path). mesh files: .json {"vertices", "quads"}, .vtk, .vtu, .msh, .obj,
.ply, .mesh.
"""


def _add_command(sub: argparse._SubParsersAction, name: str, help_: str) -> argparse.ArgumentParser:
    """A subcommand whose ``--help`` ends with the exit codes and file formats (``_EPILOG``)."""
    return sub.add_parser(
        name, help=help_, epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def _size_arg(text: str) -> tuple[float, bool]:
    """``--size``: ``(value, relative)``; a trailing ``d`` means a fraction of the diameter."""
    t = text.strip().lower()
    rel = t.endswith("d")
    try:
        v = float(t[:-1] if rel else t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a length: {text!r} (e.g. 0.5 or 0.05d)") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"the size must be positive, got {text!r}")
    return v, rel


def _add_method_arguments(p: argparse.ArgumentParser) -> None:
    """``--method`` and ``--size`` (of ``mesh`` and ``batch``)."""
    p.add_argument(
        "--method",
        choices=("bishop", "blocks"),
        help="bishop: the paper's construction (default); blocks: straight cuts into convex "
        "blocks refined by grids, far fewer quads (falls back to bishop where no layout is found)",
    )
    p.add_argument(
        "--size",
        type=_size_arg,
        help="target edge length for --method blocks: a length, or a fraction of the "
        "polygon's diameter written with a trailing 'd' (0.05d); default 0.05d",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``quadmesh`` command."""
    parser = argparse.ArgumentParser(
        prog="quadmesh",
        description="Quadrilateral meshes of simple polygons with every new angle in "
        "[60°, 120°] (C. J. Bishop, Optimal angle bounds for quadrilateral meshes).",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = _add_command(sub, "mesh", "mesh a polygon file")
    p.add_argument("polygon", type=Path, help="polygon file")
    p.add_argument("-o", "--output", type=Path, required=True, help="mesh file to write")
    _add_method_arguments(p)
    p.add_argument("--n", type=int, help="steps per half pentagon side (Lemma 4.1)")
    p.add_argument("--depth-step", type=float, help="spacing of the depth sequence (Lemma 5.1)")
    p.add_argument("--delta", type=float, help="extremal-distance threshold of narrow channels")
    p.add_argument(
        "--refine",
        type=int,
        help="split every quad into a k × k bilinear grid (k ≥ 1; not for polygons with "
        "corners below 60°)",
    )
    p.add_argument(
        "--stats",
        action="store_true",
        help="print the quality report (angles, edge length / local feature size) and timings",
    )
    p.add_argument(
        "-j",
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="mesh the thick pieces (each one's conformal map, disk mesh and push-forward) in "
        "N worker processes when the polygon has two or more; the mesh is identical to the "
        "one-process mesh. Pays on polygons with several large pieces; each run pays the "
        "workers' start (default 1: all in this process)",
    )
    p.add_argument("--png", type=Path, help="also render the mesh into this PNG")
    p.add_argument("-v", "--verbose", action="store_true", help="print progress to stderr")
    p.set_defaults(func=_cmd_mesh)

    p = _add_command(
        sub, "check", "verify a mesh file against a polygon; report angles and edge sizes"
    )
    p.add_argument("mesh", type=Path, help="mesh file")
    p.add_argument("--polygon", type=Path, required=True, help="polygon file")
    p.add_argument(
        "--angle-tol",
        type=float,
        default=None,
        help="fixed slack in degrees on 60° and 120°, the same for every quad "
        "(default: the mesher's own, 1e-5)",
    )
    p.set_defaults(func=_cmd_check)

    p = _add_command(sub, "batch", "mesh every polygon file of a folder (in parallel with --jobs)")
    p.add_argument(
        "inputs",
        nargs="+",
        type=Path,
        metavar="DIR",
        help="folder of polygon files (.json .geojson .svg .csv .txt ...), or polygon files",
    )
    p.add_argument(
        "-o", "--output", type=Path, required=True, help="folder for the mesh files (created)"
    )
    p.add_argument(
        "-j", "--jobs", type=int, default=1, help="worker processes (default 1: one by one)"
    )
    _add_method_arguments(p)
    p.add_argument(
        "--format",
        default="json",
        choices=[f[1:] for f in MESH_FORMATS],
        help="mesh file format (default json)",
    )
    p.add_argument(
        "--timeout",
        type=float,
        help="seconds per polygon; a polygon still meshing then is stopped and reported",
    )
    p.add_argument(
        "--stats",
        action="store_true",
        help="also print the seconds in the mesher and per stage, per file",
    )
    p.set_defaults(func=_cmd_batch)

    p = sub.add_parser("info", help="describe a polygon file")
    p.add_argument("polygon", type=Path, help="polygon file")
    p.set_defaults(func=_cmd_info)

    sub.add_parser(
        "bench",
        help="benchmark: time per stage and quads against n; --families: the corridor "
        "test families (quadmesh bench --help)",
    )

    p = sub.add_parser("disk-demo", help="render the disk construction of Lemma 2.2")
    p.add_argument("-o", "--output", type=Path, required=True, help="PNG to write")
    p.set_defaults(func=_cmd_disk_demo)
    return parser


def _read_polygon(path: Path):
    from .io import read_polygon
    from .polygon import validate_polygon

    verts, notes = read_polygon(path)
    for note in notes:
        print(f"note: {note}")
    poly = validate_polygon(verts)
    if poly.reversed_input:
        print("note: the polygon was clockwise and has been reversed")
    return poly


def _cmd_mesh(args: argparse.Namespace) -> int:
    from .io import MESH_FORMATS, result_cell_data, write_mesh
    from .pipeline import MeshOptions, mesh_polygon

    if args.output.suffix.lower() not in MESH_FORMATS:
        raise InputFormatError(
            f"{args.output}: unsupported mesh format {args.output.suffix!r} "
            f"(use {', '.join(MESH_FORMATS)})"
        )
    if args.jobs < 1:
        raise InputFormatError(f"--jobs must be at least 1, got {args.jobs}")
    poly = _read_polygon(args.polygon)
    size = args.size
    if size is not None and size[1]:
        size = (size[0] * poly.diameter, False)
    given = {
        "method": args.method,
        "size": None if size is None else size[0],
        "n": args.n,
        "depth_step": args.depth_step,
        "channel_delta": args.delta,
        "refine": args.refine,
        "jobs": args.jobs,
    }
    options = dataclasses.replace(
        MeshOptions(), **{k: v for k, v in given.items() if v is not None}
    )

    def progress(stage: str, fraction: float) -> None:
        print(f"[{fraction * 100:5.1f}%] {stage}", file=sys.stderr)

    t0 = time.perf_counter()
    result = mesh_polygon(poly, options, progress=progress if args.verbose else None)
    elapsed = time.perf_counter() - t0
    origin = result.mesh_origin
    # per quad: the four angles, worst deviation, stage kind and piece (ParaView can colour
    # and threshold by them)
    write_mesh(args.output, result.mesh, origin=origin, cell_data=result_cell_data(result))
    _check_written(args.output, result, poly)
    q = result.quality
    if origin:
        where = (
            'its "origin" field'
            if args.output.suffix.lower() == ".json"
            else "this origin (the file format has no place for it)"
        )
        print(
            f"note: the polygon lies {abs(origin) / poly.diameter:.3g} diameters from (0, 0), "
            "where float64 absolute coordinates cannot hold the mesh's angles within "
            f"{ANGLE_TOL_DEG:g}°: the mesh is written relative to the origin "
            f"({origin.real:.17g}, {origin.imag:.17g}); add {where} to get absolute positions"
        )
    print(
        f"wrote {args.output}: {q.n_quads} quads, {q.n_vertices} vertices for n = {poly.n}; "
        f"new angles in [{q.min_angle:.3f}°, {q.max_angle:.3f}°] (checked on the written "
        f"coordinates within {ANGLE_TOL_DEG:g}°); {elapsed:.2f} s"
    )
    if result.blocks is not None:
        lay = result.blocks
        what = (
            f"{len(lay.cuts)} cuts, {len(lay.faces)} faces"
            if lay.kind == "cuts"
            else f"{len(lay.cuts)} {lay.cut_noun}s of a {lay.title}"
        )
        print(
            f"block layout: {what}, {lay.n_cells} blocks"
            + (
                f", {len(lay.tips)} corner{'s' if len(lay.tips) > 1 else ''} below 60° kept "
                + ("whole in a tip kite" if lay.kites else "whole")
                if len(lay.tips)
                else ""
            )
        )
        from .blocks import UNDERSIZED_FRACTION, default_block_size, undersized_edges

        size = result.options.size or default_block_size(poly.z)
        small, n_edges, least = undersized_edges(result.mesh, poly.z - result.mesh_origin, size)
        print(
            f"element sizes: {small} of {n_edges} edges ({100 * small / n_edges:.3g} %) are "
            f"shorter than {UNDERSIZED_FRACTION:g} × the smaller of the size ({size:.4g}) and "
            f"the polygon's local feature size there; the shortest is {least:.3g} × it"
        )
        alone, paper = len(lay.local_faces), len(lay.fallback_faces)
        if alone or paper:
            print(
                f"faces that did not split with the others: {alone} laid out on their own"
                + (f", {paper} meshed by the paper's construction" if paper else "")
            )
    if result.fallback:
        print(f"note: {result.fallback}")
    if result.options.arc_choice == "sized":
        print(
            "note: the mesh on centred arcs failed; the arcs were chosen for size instead "
            "(larger crosscuts at reflex corners)"
        )
    if args.stats:
        print(q.summary())
        print("timings:")
        for stage, sec in result.timings.items():
            print(f"  {stage:<20s} {sec:8.3f} s")
        fixes = list(dict.fromkeys(f for piece in result.pieces for f in piece.fixes))
        if fixes:
            print("adaptive fixes:")
            for f in fixes:
                print(f"  {f}")
    if args.png is not None:
        from .render import render_png

        render_png(result, args.png)
        print(f"wrote {args.png}")
    return EXIT_OK


def _check_written(path: Path, result, poly) -> None:
    """Read the written mesh file back; unless it holds exactly the verified coordinates and
    quads, verify what it holds. Raises MeshVerificationError if that fails."""
    from .batch import check_written

    check_written(path, result, poly)


def _cmd_check(args: argparse.Namespace) -> int:
    from .io import read_mesh_with_origin

    poly = _read_polygon(args.polygon)
    mesh, origin = read_mesh_with_origin(args.mesh)
    if origin:
        print(f"note: the mesh's vertices are relative to ({origin.real:.17g}, {origin.imag:.17g})")
    tol = ANGLE_TOL_DEG if args.angle_tol is None else args.angle_tol
    report = mesh.verify(poly, angle_tol=tol, origin=origin)
    print(report.summary())
    return EXIT_OK if report.ok else EXIT_INVALID


def _cmd_batch(args: argparse.Namespace) -> int:
    from .batch import format_table, mesh_files, polygon_files
    from .result import MeshOptions

    if args.jobs < 1:
        raise InputFormatError(f"--jobs must be at least 1, got {args.jobs}")
    if args.timeout is not None and not args.timeout > 0:
        raise InputFormatError(f"--timeout must be positive, got {args.timeout}")
    paths: list[Path] = []
    for item in args.inputs:
        if item.is_dir():
            found = polygon_files(item)
            if not found:
                print(f"note: {item} holds no polygon files")
            paths += found
        elif item.is_file():
            paths.append(item)
        else:
            raise InputFormatError(f"{item}: no such file or folder")
    if not paths:
        raise InputFormatError("no polygon files to mesh")
    total = len(paths)
    done = 0

    def report(i: int, r) -> None:
        nonlocal done
        done += 1
        what = f"{r.quads} quads" if r.ok else f"{r.status}: {r.error}"
        print(f"[{done}/{total}] {r.path.name}: {what} ({r.time:.2f} s)", flush=True)

    options = MeshOptions() if args.method is None else MeshOptions(method=args.method)
    relative = None
    if args.size is not None and args.size[1]:
        relative = args.size[0]
    elif args.size is not None:
        options = dataclasses.replace(options, size=args.size[0])
    t0 = time.perf_counter()
    results = mesh_files(
        paths,
        args.output,
        jobs=args.jobs,
        fmt=args.format,
        timeout=args.timeout,
        options=options,
        relative_size=relative,
        on_result=report,
    )
    wall = time.perf_counter() - t0
    print(format_table(results, stats=args.stats))
    ok = [r for r in results if r.ok]
    print(
        f"meshed {len(ok)} of {total} files into {args.output} in {wall:.2f} s "
        f"({args.jobs} job{'s' if args.jobs > 1 else ''}; "
        f"{sum(r.time for r in results):.2f} s summed over the files)"
    )
    for r in results:
        for note in r.notes:
            print(f"note: {r.path.name}: {note}")
        if r.origin:
            where = (
                'its "origin" field'
                if args.format == "json"
                else "this origin (the file format has no place for it)"
            )
            print(
                f"note: {r.output.name}: vertices relative to ({r.origin.real:.17g}, "
                f"{r.origin.imag:.17g}); add {where} to get absolute positions"
            )
    failed = [r for r in results if not r.ok]
    if failed:
        print(f"{len(failed)} file{'s' if len(failed) > 1 else ''} not meshed:", file=sys.stderr)
        for r in failed:
            print(f"  {r.path}: {r.error}: {r.message}", file=sys.stderr)
        return EXIT_INVALID
    return EXIT_OK


def _cmd_info(args: argparse.Namespace) -> int:
    poly = _read_polygon(args.polygon)
    ang = np.degrees(poly.angles)
    lengths = poly.edge_lengths
    print(f"file: {args.polygon}")
    print(f"vertices: {poly.n}")
    print(
        f"area: {poly.area:.10g}   perimeter: {lengths.sum():.10g}   diameter: {poly.diameter:.6g}"
    )
    print(f"edge lengths: min {lengths.min():.4g}  max {lengths.max():.4g}")
    print(f"interior angles: min {ang.min():.4f}°  max {ang.max():.4f}°")
    straight = np.abs(ang - 180.0) < 1e-9
    print(
        f"  below 60° (kept unsplit): {np.count_nonzero(ang < 60.0)}   "
        f"60°–120°: {np.count_nonzero((ang >= 60.0) & (ang <= 120.0))}   "
        f"120°–180°: {np.count_nonzero((ang > 120.0) & (ang < 180.0) & ~straight)}   "
        f"180° (collinear): {np.count_nonzero(straight)}   "
        f"reflex: {np.count_nonzero((ang > 180.0) & ~straight)}"
    )
    _print_parts(poly)
    return EXIT_OK


def _print_parts(poly) -> None:
    """The decomposition: thick pieces, narrow channels, and whether the polygon is meshed as
    a corridor (a ladder of straight cells), has an arm that is, or a bridge (a cut across a
    corridor between two bodies, and the corridor from it)."""
    from .decompose import decompose
    from .errors import QuadmeshError
    from .thin.corridor import arm_and_body, bridge_cuts, bridge_layout, whole_corridor

    try:
        dec = decompose(poly)
    except QuadmeshError as exc:
        print(f"decomposition: refused ({exc})")
        return
    print(f"thick pieces: {len(dec.thick)}   narrow channels: {len(dec.channels)}")
    corridor, why = whole_corridor(dec)
    if corridor is not None:
        lay = corridor.layout
        print(
            f"corridor: yes — {len(lay.cells)} cells, {len(lay.rungs)} crosscuts, "
            f"{len(lay.round_caps)} round ends, {len(lay.sectors)} bends (no conformal map)"
        )
        return
    if not why:
        return  # not crowded: Bishop's construction
    print(f"corridor: no ({why})")
    split = arm_and_body(dec.polygon.z)
    if split is not None:
        lay, body = split
        print(
            f"arm: a corridor of {len(lay.rungs)} crosscuts from a tip, cut where the rest "
            f"({len(body)} vertices) begins"
        )
        return
    for cut in bridge_cuts(dec.polygon.z):
        for far in (cut.second, cut.first):
            got = bridge_layout(far)
            if got is None:
                continue
            lay, _q, body = got
            rest = "to the far end" if body is None else f"to a far body of {len(body)} vertices"
            print(
                f"bridge: a cut from ({cut.a.real:.6g}, {cut.a.imag:.6g}) to "
                f"({cut.b.real:.6g}, {cut.b.imag:.6g}) and a corridor of {len(lay.rungs)} "
                f"crosscuts from it {rest}"
            )
            return


def _cmd_disk_demo(args: argparse.Namespace) -> int:
    from .disk.demo import render_disk_demo

    render_disk_demo(args.output)
    print(f"wrote {args.output}")
    return EXIT_OK


def _exit_code(exc: SystemExit) -> int:
    """Exit code of an argparse ``SystemExit`` (a non-integer code counts as an input error)."""
    return int(exc.code) if isinstance(exc.code, int) else EXIT_INPUT


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``quadmesh`` command with ``argv`` (default ``sys.argv[1:]``); return the exit
    code (see the epilog of ``quadmesh --help``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["bench"]:  # its own options (quadmesh.benchmark)
        from .benchmark import main as bench_main

        try:
            return bench_main(argv[1:])
        except SystemExit as exc:
            return _exit_code(exc)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help or a usage error
        return _exit_code(exc)
    try:
        return int(args.func(args))
    except (InputFormatError, PolygonError) as exc:
        print(f"quadmesh: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except MeshVerificationError as exc:
        print(f"quadmesh: the mesh is invalid: {exc}", file=sys.stderr)
        return EXIT_INVALID
    except QuadmeshError as exc:
        print(f"quadmesh: a mesher stage failed: {exc}", file=sys.stderr)
        return EXIT_STAGE
    except (ValueError, OSError) as exc:
        print(f"quadmesh: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except ImportError as exc:
        print(f"quadmesh: error: a required module is missing ({exc})", file=sys.stderr)
        return EXIT_INPUT


if __name__ == "__main__":
    sys.exit(main())
