"""Thick pieces meshed in worker processes (:mod:`quadmesh.parallel`, ``MeshOptions.jobs``,
``mesh_polygon(executor=...)``, ``quadmesh mesh --jobs``): the same mesh bit for bit as the
serial run, the same errors and partial results, progress as pieces finish, prompt cancel."""

from __future__ import annotations

import multiprocessing as mp
import pickle
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from quadmesh import MeshOptions, mesh_polygon
from quadmesh.cli import EXIT_INPUT, EXIT_OK, main
from quadmesh.errors import Cancelled, ConformalMapError, DiskConstructionError, QuadmeshError
from quadmesh.examples import example_path, load_example

#: Cancel must take effect within this many seconds of cancel() turning True.
MAX_LATENCY = 1.5


def _same_result(a, b) -> None:
    """Every array of the two results is equal, bit for bit."""
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert np.array_equal(a.mesh.quads, b.mesh.quads)
    assert np.array_equal(a.quad_source, b.quad_source)
    assert len(a.pieces) == len(b.pieces) >= 2
    for p, q in zip(a.pieces, b.pieces, strict=True):
        assert (p.index, p.n_used, p.depth_step_used, p.fixes) == (
            q.index,
            q.n_used,
            q.depth_step_used,
            q.fixes,
        )
        assert np.array_equal(p.intervals, q.intervals) and np.array_equal(p.image, q.image)
        assert np.array_equal(p.map.prevertices, q.map.prevertices)
    assert [(t.kind, t.owner) for t in a.thin] == [(t.kind, t.owner) for t in b.thin]


#: One normalisation of each piece's map (not eight): the same code paths at a third less
#: time, so that the tests stay short.
FAST = MeshOptions(rotations=1)


@pytest.mark.parametrize(
    ("name", "options"),
    [
        # two pieces; without the local repair the adaptive loop raises n to 3 for both, so
        # the pieces are shipped twice (one round per n)
        ("dumbbell", replace(FAST, repair=False)),
        # three pieces on two workers (one waits for a free worker), with local angle repairs
        ("bent_channel", MeshOptions()),
    ],
)
def test_two_jobs_give_the_serial_mesh_bit_for_bit(name, options):
    poly = load_example(name)
    serial = mesh_polygon(poly, options)
    got: list[tuple[str, float]] = []
    parallel = mesh_polygon(
        poly,
        replace(options, jobs=2),
        progress=lambda s, f: got.append((s, f)),
    )
    _same_result(serial, parallel)
    if name == "dumbbell":
        assert all(p.n_used == 3 for p in parallel.pieces) and parallel.pieces[0].fixes
    # progress: never backwards, and the pieces' stages move the bar as pieces finish
    fractions = [f for _, f in got]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    disk = [f for s, f in got if s == "disk mesh"]
    assert len(set(disk)) >= 2 and max(disk) == pytest.approx(0.7)


def test_a_stage_failure_after_parallel_pieces_is_the_serial_one():
    """The dumbbell without adaptive loop and repair fails the angle check of piece 1 after
    both pieces were meshed in workers: same error, same partial result as serially."""
    poly = load_example("dumbbell")
    strict = replace(FAST, adaptive=False, repair=False)
    errors = []
    for jobs in (1, 2):
        with pytest.raises(DiskConstructionError) as info:
            mesh_polygon(poly, replace(strict, jobs=jobs))
        errors.append(info.value)
    a, b = errors
    assert str(a) == str(b) and a.piece == b.piece == 1
    assert a.partial.failed_piece == b.partial.failed_piece == 1
    assert [p.index for p in a.partial.pieces] == [p.index for p in b.partial.pieces] == [0, 1]
    for p, q in zip(a.partial.pieces, b.partial.pieces, strict=True):
        assert np.array_equal(p.image, q.image) and np.array_equal(p.intervals, q.intervals)


@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="needs fork")
def test_an_error_raised_in_a_worker_reaches_the_caller_unchanged(monkeypatch):
    """The map of piece 1 (the dumbbell's right bulb) cannot be evaluated: raised inside a
    worker of a caller's executor, it arrives as the serial run's ConformalMapError (message,
    failing piece, partial result with piece 0's image and piece 1's disk without image)."""
    import quadmesh.thick

    real = quadmesh.thick.push_forward

    def broken(fmap, disk, theta, z):
        if np.mean(np.asarray(z).real) > 1.5:
            raise FloatingPointError("overflow in the map's series")
        return real(fmap, disk, theta, z)

    monkeypatch.setattr(quadmesh.thick, "push_forward", broken)  # forked workers inherit it
    poly = load_example("dumbbell")
    with pytest.raises(ConformalMapError) as serial:
        mesh_polygon(poly, FAST)
    with ProcessPoolExecutor(2, mp_context=mp.get_context("fork")) as pool:
        with pytest.raises(ConformalMapError) as parallel:
            mesh_polygon(poly, FAST, executor=pool)
    a, b = serial.value, parallel.value
    assert type(a) is type(b) and str(a) == str(b) and "evaluating its conformal map" in str(b)
    assert a.piece == b.piece == 1 and b.partial.failed_piece == 1
    p0, p1 = b.partial.pieces
    assert np.array_equal(p0.image, a.partial.pieces[0].image)
    assert p1.disk is not None and p1.image is None
    # a failure with its partial result survives pickling (as a worker or a batch sends it)
    c = pickle.loads(pickle.dumps(b))
    assert type(c) is ConformalMapError and str(c) == str(b) and c.stage == "conformal"
    assert c.piece == 1 and c.partial.failed_piece == 1 and len(c.partial.pieces) == 2


def test_cancel_stops_the_workers_promptly():
    """Cancel while the comb's seven pieces run on two workers (from a thread, as the app
    does): Cancelled within MAX_LATENCY and no worker process left running."""
    flag = threading.Event()
    stages: list[str] = []
    out: dict[str, object] = {}

    def work() -> None:
        try:
            mesh_polygon(
                load_example("comb"),
                MeshOptions(jobs=2),
                progress=lambda s, f: stages.append(s),
                cancel=flag.is_set,
            )
        except BaseException as exc:
            out["exc"] = exc
        out["end"] = time.monotonic()

    th = threading.Thread(target=work, daemon=True)
    th.start()
    deadline = time.monotonic() + 20
    while "conformal map" not in stages and th.is_alive() and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.3)
    assert th.is_alive(), "the run ended before the cancel"
    t_cancel = time.monotonic()
    flag.set()
    th.join(10.0)
    assert isinstance(out.get("exc"), Cancelled), f"expected Cancelled, got {out.get('exc')!r}"
    assert float(out["end"]) - t_cancel < MAX_LATENCY
    time.sleep(0.2)
    assert mp.active_children() == []


def test_jobs_must_be_a_positive_integer(tmp_path: Path, capsys):
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="jobs must be a positive integer"):
            MeshOptions(jobs=bad)
    out = tmp_path / "m.json"
    rc = main(["mesh", str(example_path("dumbbell")), "-o", str(out), "--jobs", "0"])
    assert rc == EXIT_INPUT
    assert "--jobs must be at least 1" in capsys.readouterr().err and not out.exists()


def test_cli_jobs_writes_the_serial_mesh(tmp_path: Path, capsys):
    poly = example_path("channel_20")  # two thick pieces joined by a channel
    one, two = tmp_path / "one.json", tmp_path / "two.json"
    assert main(["mesh", str(poly), "-o", str(one)]) == EXIT_OK
    assert main(["mesh", str(poly), "-o", str(two), "--jobs", "2"]) == EXIT_OK
    assert one.read_bytes() == two.read_bytes()
    assert "wrote" in capsys.readouterr().out


def test_errors_are_picklable_with_their_fields():
    for exc in (QuadmeshError("x", stage="s", piece=3), DiskConstructionError("y", piece=0)):
        c = pickle.loads(pickle.dumps(exc))
        assert type(c) is type(exc) and str(c) == str(exc) and c.piece == exc.piece


def _blas_threads() -> list[int]:
    from threadpoolctl import threadpool_info

    return [d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"]


def test_blas_runs_single_threaded_during_a_call_and_is_restored_after():
    """``MeshOptions.blas_threads`` (default 1) holds for the whole call from the main thread —
    seen from the progress callback, which runs inside it — and the caller's setting comes
    back after; None leaves the libraries alone, and so does a call from another thread (the
    limit is process-wide state that thread could race on)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        if not before or max(before) < 2:
            pytest.skip("no multi-threaded BLAS here")
        seen: list[list[int]] = []
        mesh_polygon(load_example("l_shape"), progress=lambda *_: seen.append(_blas_threads()))
        assert seen and all(t == [1] * len(before) for t in seen)
        assert _blas_threads() == before
        seen.clear()
        opts = MeshOptions(blas_threads=None)
        mesh_polygon(
            load_example("l_shape"), opts, progress=lambda *_: seen.append(_blas_threads())
        )
        assert seen and all(t == before for t in seen)
        seen.clear()
        th = threading.Thread(
            target=mesh_polygon,
            args=(load_example("l_shape"),),
            kwargs={"progress": lambda *_: seen.append(_blas_threads())},
        )
        th.start()
        th.join(60)
        assert seen and all(t == before for t in seen)
        assert _blas_threads() == before
    with pytest.raises(ValueError, match="blas_threads"):
        MeshOptions(blas_threads=0)
