"""Mandow 2007 Sec. III: the GA and the differential evolution recover K (synthetic runs)."""
from __future__ import annotations

import numpy as np
import pytest

from methods import mandow2007 as M
from tests.methods.mandow2007.synthetic import PLATFORM, joystick_run, on_grid


def test_ga_recovers_parameters_within_one_gene_quantum():
    """40-bit GA on a 12 s joystick path, noise-free reference at the published 5 Hz (DGPS)."""
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    truth = on_grid(M.TABLE_I["pneumatic_50psi"], ranges)
    seg = M.build_segments([joystick_run(truth, duration=12.0, seed=1)])
    ident = M.identify_ga(seg, ranges)
    q = ranges.quantum()
    assert np.all(np.abs(ident.params.as_array() - truth.as_array()) <= q * (1 + 1e-9)), (
        (ident.params.as_array() - truth.as_array()) / q)
    assert ident.quantum == pytest.approx(tuple(q))
    assert ident.n_evaluations > 0 and ident.cost == pytest.approx(float(M.segment_cost(seg, ident.params.as_array())))


def test_de_recovers_parameters_within_one_gene_quantum():
    truth = M.TABLE_I["solid_rubber"]  # off the gene grid: DE works on continuous K
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    seg = M.build_segments([joystick_run(truth, duration=20.0, seed=2)])
    ident = M.identify_de(seg, ranges, M.DeSettings(maxiter=150))
    assert np.all(np.abs(ident.params.as_array() - truth.as_array()) <= ranges.quantum())
    assert ident.cost < 1e-10


def test_optimisers_are_deterministic_and_seeded():
    truth = M.TABLE_I["pneumatic_20psi"]
    seg = M.build_segments([joystick_run(truth, duration=5.0, seed=3)])
    st = M.GaSettings(population=20, parents_mating=10, generations=15, stop_saturate=None)
    a, b = M.identify_ga(seg, settings=st), M.identify_ga(seg, settings=st)
    assert a == b and a.cost_history == b.cost_history and len(a.cost_history) == 15
    other = M.identify_ga(seg, settings=M.GaSettings(population=20, parents_mating=10, generations=15,
                                                     stop_saturate=None, seed=99))
    assert other.cost_history != a.cost_history
    assert list(a.cost_history) == sorted(a.cost_history, reverse=True)  # elitism: never worse
    de = M.DeSettings(maxiter=10, popsize=5, polish=False)
    assert M.identify_de(seg, settings=de) == M.identify_de(seg, settings=de)


def test_decode_chromosomes_gray_and_binary():
    ranges = M.GeneRanges((-1.0, 0.0), (0.0, 1.0), (-1.0, 1.0), (0.5, 1.5), (0.5, 1.5))
    codes = np.array([0, 255, 128, 1, 170])
    bits = ((codes[:, None] >> np.arange(7, -1, -1)) & 1).ravel()
    b = ranges.bounds()
    np.testing.assert_allclose(M.decode_chromosomes(bits, ranges, gray_code=False)[0],
                               b[:, 0] + codes * (b[:, 1] - b[:, 0]) / 255)
    gray = codes ^ (codes >> 1)  # Gray encoding of the same codes decodes to the same values
    gbits = ((gray[:, None] >> np.arange(7, -1, -1)) & 1).ravel()
    np.testing.assert_allclose(M.decode_chromosomes(gbits, ranges, gray_code=True)[0],
                               b[:, 0] + codes * (b[:, 1] - b[:, 0]) / 255)


def test_a_candidates_cost_does_not_depend_on_its_batch():
    """The GA's fitness memo (identify_ga) reuses a chromosome's cost from an earlier batch: valid because
    segment_cost computes each row alone, bit for bit the same in any batch, chunk or position."""
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    seg = M.build_segments([joystick_run(M.TABLE_I["pneumatic_50psi"], duration=8.0, seed=4)])
    rng = np.random.default_rng(5)
    bits = rng.integers(0, 2, size=(37, 40))
    k = M.decode_chromosomes(bits, ranges)
    whole = M.segment_cost(seg, k)
    alone = np.array([M.segment_cost(seg, k[i:i + 1])[0] for i in range(k.shape[0])])
    shuffled = rng.permutation(k.shape[0])
    assert np.array_equal(whole, alone)
    assert np.array_equal(M.segment_cost(seg, k[shuffled]), whole[shuffled])
    small_chunks = M.segment_increments(seg, k, max_elements=seg.n_intervals * 3)
    assert all(np.array_equal(a, b) for a, b in zip(small_chunks, M.segment_increments(seg, k)))
