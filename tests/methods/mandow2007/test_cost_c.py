"""Mandow 2007 eq. (13) in C (methods/mandow2007/_cost.c) against its numpy reference
(segments.segment_cost_numpy): the same J(K) to 1e-12 relative on every kind of row (on and off the
solution, degenerate, large per-interval turns), and the GA identifies the same K with either."""
from __future__ import annotations

import numpy as np
import pytest

from methods import mandow2007 as M
from methods.mandow2007 import segments as S
from tests.methods.mandow2007.synthetic import PLATFORM, joystick_run, on_grid

pytestmark = pytest.mark.skipif(S._COST is None, reason="methods.mandow2007._cost not built")


def _rows(ranges: M.GeneRanges, n: int, seed: int) -> np.ndarray:
    b = ranges.bounds()
    return b[:, 0] + np.random.default_rng(seed).random((n, 5)) * (b[:, 1] - b[:, 0])


@pytest.mark.parametrize("period", [None, 1.0])
def test_c_cost_equals_the_numpy_cost(period: float | None) -> None:
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    truth = M.TABLE_I["pneumatic_50psi"]
    seg = M.build_segments([joystick_run(truth, duration=12.0, seed=1), joystick_run(truth, duration=6.0, seed=4)],
                           segment_period=period)
    k = np.vstack([_rows(ranges, 64, 0), truth.as_array(), [0.3, -0.3, 0.0, 1.0, 1.0],  # degenerate: inf
                   [-0.02, 0.02, 0.0, 1.1, 1.1]])  # a narrow ICR: per-interval turns beyond the series' 0.05 rad
    ref = S.segment_cost_numpy(seg, k)
    got = S.segment_cost(seg, k)
    assert np.isinf(got[-2]) and np.isinf(ref[-2])
    fin = np.isfinite(ref)
    np.testing.assert_allclose(got[fin], ref[fin], rtol=1e-12, atol=1e-24)
    assert float(S.segment_cost(seg, truth.as_array())) == pytest.approx(float(ref[64]), rel=1e-12, abs=1e-24)


def test_c_cost_is_used_and_the_ga_finds_the_same_parameters(monkeypatch: pytest.MonkeyPatch) -> None:
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    truth = on_grid(M.TABLE_I["pneumatic_20psi"], ranges)
    seg = M.build_segments([joystick_run(truth, duration=8.0, seed=3)])
    st = M.GaSettings(population=40, parents_mating=20, generations=40, stop_saturate=None)
    calls = []
    real = S._COST.segment_cost
    monkeypatch.setattr(S, "_COST", type("C", (), {"segment_cost": staticmethod(
        lambda *a: calls.append(1) or real(*a))}))
    fast = M.identify_ga(seg, ranges, st)
    assert calls
    monkeypatch.setenv("SKIDBENCH_KERNEL", "python")
    ref = M.identify_ga(seg, ranges, st)
    assert fast.params == ref.params and fast.iterations == ref.iterations
    np.testing.assert_allclose(fast.cost_history, ref.cost_history, rtol=1e-12, atol=1e-24)


def test_c_cost_refuses_inconsistent_arrays() -> None:
    seg = M.build_segments([joystick_run(M.TABLE_I["solid_rubber"], duration=3.0, seed=5)])
    dl, dr, first, dx, dy, dphi = S._c_arrays(seg)
    with pytest.raises(ValueError, match="inconsistent"):
        S._COST.segment_cost(np.zeros((2, 5)), dl, dr, first, dx, dy, dphi, np.empty(3))
    with pytest.raises(ValueError, match="strictly increase"):
        S._COST.segment_cost(np.zeros((1, 5)), dl, dr, first[::-1].copy(), dx, dy, dphi, np.empty(1))
