"""Speed of the kinematic models (Mandow 2007, Wang 2015, ideal differential drive).

Run with ``make bench`` (pytest-benchmark); skipped in the normal test run.  Fixed synthetic data
(tests/methods/mandow2007/synthetic.py generators): a 30 s joystick calibration path with a 5 Hz reference
(150 segments, 3000 encoder intervals) for the identifications, a 20 min 100 Hz log for dead
reckoning.  ``extra_info`` records the recovered parameters (in gene quanta from the truth) and
the dead-reckoning samples per second.
"""
from __future__ import annotations

import numpy as np
import pytest

from methods import mandow2007 as M
from methods.baselines import IdealDD
from methods.wang2015 import PUBLISHED_CURVE, ChiLambda, ConstantChi
from tests.methods.mandow2007.synthetic import PLATFORM, joystick_run, on_grid

RANGES = M.GeneRanges.for_track(PLATFORM["track"])
TRUTH = on_grid(M.TABLE_I["pneumatic_50psi"], RANGES)


@pytest.fixture(scope="module")
def segments():
    return M.build_segments([joystick_run(TRUTH, duration=30.0, seed=21)])


@pytest.fixture(scope="module")
def long_run():
    return joystick_run(TRUTH, duration=1200.0, seed=22)


def _record_params(benchmark, ident: M.Identification) -> None:
    err = (ident.params.as_array() - TRUTH.as_array()) / RANGES.quantum()
    benchmark.extra_info.update(
        params=ident.params.as_dict(), error_in_quanta=err.round(3).tolist(), cost=ident.cost,
        evaluations=ident.n_evaluations, iterations=ident.iterations, segments=ident.n_segments,
    )


def test_bench_ga_identification(benchmark, segments):
    ident = benchmark.pedantic(M.identify_ga, args=(segments, RANGES), rounds=3, iterations=1)
    _record_params(benchmark, ident)
    assert np.all(np.abs(ident.params.as_array() - TRUTH.as_array()) <= RANGES.quantum() * (1 + 1e-9))


def test_bench_de_identification(benchmark, segments):
    ident = benchmark.pedantic(M.identify_de, args=(segments, RANGES), rounds=3, iterations=1)
    _record_params(benchmark, ident)
    assert np.all(np.abs(ident.params.as_array() - TRUTH.as_array()) <= RANGES.quantum())


def test_bench_cost_population(benchmark, segments):
    """One GA generation's fitness: eq. (13) for 100 candidates."""
    pop = TRUTH.as_array() + np.random.default_rng(0).normal(0.0, 0.01, (100, 5))
    benchmark(M.segment_cost, segments, pop)
    benchmark.extra_info["candidate_intervals_per_s"] = 100 * segments.n_intervals / benchmark.stats.stats.min


@pytest.mark.parametrize("method", [
    IdealDD(), M.DefaultP3at(), M.AsymmetricGa(params=TRUTH), ConstantChi(), ChiLambda(curve=PUBLISHED_CURVE),
], ids=lambda m: m.name)
def test_bench_dead_reckoning(benchmark, long_run, method):
    benchmark.pedantic(method.estimate, args=(long_run,), rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info["samples"] = long_run.t.size
    benchmark.extra_info["samples_per_s"] = long_run.t.size / benchmark.stats.stats.min
