"""Speed of the Yi 2009 EKF (methods.yi2009.run_filter): filter steps per second.

Run with `make bench` (skipped by the normal test run: --benchmark-skip).  The input is a 30 s
closed-form '8' at 125 Hz (3 875 IMU steps) with IMU noise and 125 Hz encoders, built here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from methods.yi2009 import PUBLISHED_S_GAMMA, EkfParams, initial_state, run_filter

R_WHEEL, TRACK, RATE = 0.086, 0.419, 125.0


def _inputs(seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 31.0, 1.0 / RATE)
    kn = np.array([(0, 0, 0), (1, 80, 40), (9, 80, 40), (13, 40, 80), (21, 40, 80), (25, 80, 40), (31, 80, 40)], float)
    wl, wr = (np.interp(t, kn[:, 0], kn[:, i]) * 2 * math.pi / 60 for i in (1, 2))
    vx = 0.95 * R_WHEEL * (wl + wr) / 2
    wz = 0.95 * R_WHEEL * (wr - wl) / (1.4 * TRACK)
    vy = -0.2 * wz
    n = t.size
    acc = np.column_stack([np.gradient(vx, t) - wz * vy, np.gradient(vy, t) + wz * vx, np.full(n, 9.81)])
    acc += 0.05 * rng.standard_normal((n, 3))
    gyr = np.column_stack([np.zeros(n), np.zeros(n), wz]) + 0.005 * rng.standard_normal((n, 3))
    enc = np.column_stack([wl, wr]) + 0.05 * rng.standard_normal((n, 2))
    return t, acc, gyr, enc


@pytest.mark.parametrize("variant", [1, 3])
def test_bench_run_filter_steps_per_second(benchmark, variant):
    t, acc, gyr, enc = _inputs()
    params = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, params, (0.0, 0.0, 0.0))

    def run():
        return run_filter(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=variant,
                          s_gamma=PUBLISHED_S_GAMMA, params=params, x0=x0, p0=p0)

    res = benchmark(run)
    assert np.isfinite(res.state).all()
    benchmark.extra_info["steps"] = int(t.size)
    benchmark.extra_info["steps_per_second"] = t.size / benchmark.stats.stats.mean
