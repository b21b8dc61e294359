"""The arc choice of a thick piece and its rotation (quadmesh.arcs, paper §7 with Lemmas 2.1
and 2.2): the batched and shortened searches give what the plain ones give, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from quadmesh.arcs import (
    ROTATION_COLLAR_COST,
    _off_centre_cores,
    _rotated_intervals,
    best_rotation,
    piece_intervals,
)
from quadmesh.disk.region import build_region
from quadmesh.errors import DiskConstructionError
from quadmesh.result import MeshOptions


def _pieces(n: int, seed: int) -> list[tuple[np.ndarray, list[tuple[int, int]]]]:
    """Random prevertices (3–12, some crowded) with 0–2 crosscut stretches (runs of close
    prevertices)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        k = int(rng.integers(3, 13))
        theta = np.sort(rng.uniform(0, 2 * np.pi, k))
        stretches = []
        for a, b in ((0, 1), (4, 6)):
            if b < k - 1 and rng.random() < 0.5:
                w = 10 ** rng.uniform(-3, -1.5)
                theta[a : b + 1] = theta[a] + w * np.arange(b - a + 1)
                stretches.append((a, b))
        if k >= 9 and rng.random() < 0.5:
            theta[8] = theta[7] + 10 ** rng.uniform(-5, -2)  # a crowded pair
        out.append((np.mod(theta, 2 * np.pi), stretches))
    return out


def _best_rotation_reference(theta, stretches, options):
    """best_rotation's documented rule, one rotation at a time with the whole W built."""
    two_pi = 2 * np.pi
    best = None
    for k in range(options.rotations):
        psi = two_pi / 5 * k / options.rotations
        th = np.mod(theta + psi, two_pi) if k else theta
        try:
            got = piece_intervals(th, stretches, options)
            cover = len(build_region(got[0], A=options.lemma_A).cover)
        except DiskConstructionError:
            continue
        th = np.mod(theta + psi, two_pi)
        cost = cover + ROTATION_COLLAR_COST * _off_centre_cores(th, stretches, *got, options)
        if best is None or cost < best[0]:
            best = (cost, psi, got)
    return best


def test_rotated_intervals_equal_one_rotation_at_a_time() -> None:
    opts = MeshOptions()
    psis = 2 * np.pi / 5 * np.arange(8) / 8
    for theta, stretches in _pieces(12, seed=3):
        batched = _rotated_intervals(theta, stretches, opts, psis)
        for psi, got in zip(psis, batched):
            try:
                one = piece_intervals(np.mod(theta + psi, 2 * np.pi), stretches, opts)
            except DiskConstructionError:
                assert got is None
                continue
            assert got is not None
            assert np.array_equal(got[0], one[0]) and got[1] == one[1]


@pytest.mark.parametrize("seed", [3, 7, 8])
def test_best_rotation_equals_building_every_rotation(seed: int) -> None:
    opts = MeshOptions()
    for theta, stretches in _pieces(6, seed=seed):
        try:
            first = piece_intervals(theta, stretches, opts)
        except DiskConstructionError:
            # the unrotated arcs do not fit: the first rotation whose arcs fit and whose W
            # builds, or the unrotated failure when none does
            try:
                psi, arcs, owners = best_rotation(theta, stretches, opts)
            except DiskConstructionError:
                continue
            assert psi > 0.0
            rot = piece_intervals(np.mod(theta + psi, 2 * np.pi), stretches, opts)
            assert np.array_equal(arcs, rot[0]) and owners == rot[1]
            build_region(arcs, A=opts.lemma_A)
            continue
        ref = _best_rotation_reference(theta, stretches, opts) or (0.0, 0.0, first)
        psi, arcs, owners = best_rotation(theta, stretches, opts)
        assert psi == ref[1]
        assert np.array_equal(arcs, ref[2][0]) and owners == ref[2][1]


def test_a_core_at_the_tessellations_breakpoint_is_meshed_after_a_rotation() -> None:
    # prevertices of a thick piece of the STIX "n" (a stem cut off by a crosscut whose
    # prevertex stretch starts at θ_0 = 0, where every arc of the tessellation ends): no I5
    # arc is both centred on the stretch and small against its gap at ψ = 0, and with 17 arcs
    # the rotation trial was skipped, so the glyph was refused
    theta = np.array(
        [
            0.0,
            0.0031,
            0.0106,
            0.0181,
            0.0212,
            0.36,
            0.93,
            1.63,
            2.01,
            2.14,
            2.163,
            2.1646,
            2.1647,
            4.221,
            4.2212,
            4.2219,
            4.235,
            4.308,
            4.53,
            4.99,
            5.55,
        ]
    )
    options = MeshOptions()
    with pytest.raises(DiskConstructionError, match="no arc"):
        piece_intervals(theta, [(0, 4)], options)
    psi, arcs, owners = best_rotation(theta, [(0, 4)], options)
    assert 0.0 < psi < 2 * np.pi / 5
    assert owners[0] == ("crosscut", 0) and len(owners) == arcs.shape[0] == 17
    region = build_region(arcs, A=options.lemma_A)  # W exists for the rotated arcs
    assert region is not None
    # and each arc I_j still lies around its core, rotated with the prevertices
    rotated = np.mod(theta + psi, 2 * np.pi)
    mid = np.mod(arcs[1:, 0] + arcs[1:, 1] / 2, 2 * np.pi)
    assert np.allclose(mid, rotated[5:], atol=0.4 * arcs[1:, 1].max())
