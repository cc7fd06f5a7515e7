"""The consistent configuration (not Yi's): encoder quantisation, odometer window, trailing means, traction transients,
methods.yi2009.consistent.sensors.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from bench.run import Run, RunError
from methods.yi2009.consistent.plugin import ekf_v1_consistent
from methods.yi2009.consistent.sensors import (encoder_odometer_sd, encoder_quantisation, odometer_min_window,
                                               traction_transient, trailing_mean)
from tests.methods.yi2009.synthetic import PLATFORM, R_WHEEL, synthetic_run


def test_traction_transient_gate_closed_form():
    """f_x of 2 m/s^2 for 0.2 s at 100 Hz: the 0.1 s (10-sample) trailing mean exceeds a 0.5 m/s^2 gate while the
    window holds at least 3 pulse samples (0.6 > 0.5 > 0.4), samples 102-126, and the gate stays shut 0.3 s
    (30 samples) longer, to 156; gate 0: never."""
    dt, n = 0.01, 400
    t = np.arange(n) * dt
    acc = np.zeros((n, 3))
    acc[100:120, 0] = 2.0
    want = np.zeros(n, bool)
    want[102:157] = True
    np.testing.assert_array_equal(traction_transient(acc, t, 0.5), want)
    np.testing.assert_array_equal(traction_transient(-acc, t, 0.5), want)  # braking as well
    assert not traction_transient(acc, t, 0.0).any() and not traction_transient(acc, t, 2.5).any()


def test_encoder_quantisation_from_the_platform_spec():
    """r q rate / sqrt(24) with q = 2 pi / counts_per_rev (the mean of two wheels' uniform count residuals, in m/s);
    a run without the encoder spec is a clear error."""
    run = synthetic_run("straight", 3)
    enc = PLATFORM["sensors"]["encoder"]
    want = R_WHEEL * 2 * math.pi / enc["counts_per_rev"] * enc["rate_hz"] / math.sqrt(24.0)
    assert encoder_quantisation(run) == pytest.approx(want, rel=1e-12)
    meta = copy.deepcopy(dict(run.meta))
    del meta["platform"]["sensors"]["encoder"]
    with pytest.raises(RunError, match="counts_per_rev"):
        encoder_quantisation(Run(run.data, meta))


def test_odometer_window_rule_and_the_consistent_default():
    """encoder_odometer_sd is (r q)^2 / 12 of the two end counts of both wheels (q = 2 pi / counts_per_rev);
    odometer_min_window gives the shortest whole number of steps with the window's mean-speed quantisation
    sd / T at most a quarter of accel_noise sqrt(T dT) (closed form), 0.176 s on Yi's platform at its 125 Hz and
    0.05 m/s^2; the consistent configuration's 0.2 s default satisfies it, and an odometer excludes the per-step
    options."""
    run = synthetic_run("straight", 3)
    enc = PLATFORM["sensors"]["encoder"]
    rq = R_WHEEL * 2 * math.pi / enc["counts_per_rev"]
    assert encoder_odometer_sd(run) == pytest.approx(rq / math.sqrt(12.0), rel=1e-12)
    dt, sa = 1.0 / enc["rate_hz"], 0.05
    t_min = odometer_min_window(run, sa, dt)
    m = round(t_min / dt)
    assert m == pytest.approx(t_min / dt, abs=1e-9)
    assert rq / math.sqrt(12.0) / (m * dt) <= 0.25 * sa * math.sqrt(m * dt * dt)  # the rule holds at T
    assert rq / math.sqrt(12.0) / ((m - 1) * dt) > 0.25 * sa * math.sqrt((m - 1) * dt * dt)  # and not one step less
    assert t_min == pytest.approx(0.176) and ekf_v1_consistent().odometer_window >= t_min
    for kw in ({"quantisation_states": True}, {"adaptive_white": 2.0}):
        with pytest.raises(ValueError, match="odometer_window"):
            ekf_v1_consistent(**kw)
        ekf_v1_consistent(odometer_window=0.0, **kw)
    with pytest.raises(ValueError, match="odometer_window"):
        ekf_v1_consistent(odometer_window=-0.1)


def test_trailing_mean_of_count_differences_telescopes():
    """Encoder speeds as count differences of a wheel at 21.3 counts per sample: the trailing mean over N samples
    is the count difference over N samples (exact, closed form), so its quantisation error is below one count over
    the window, q / (N dT), where a single sample's is up to q / dT; NaN samples are skipped."""
    dt, q, n_win = 0.008, 2 * math.pi / 2000, 12
    t = np.arange(400) * dt
    w_true = 21.3 * q / dt
    counts = np.floor(w_true * t / q + 0.37)
    w = np.concatenate(([0.0], np.diff(counts) * q / dt))
    enc = np.column_stack((w, 0.5 * w))
    sm = trailing_mean(enc, t, n_win * dt)
    k = np.arange(n_win, t.size)
    np.testing.assert_allclose(sm[k, 0], (counts[k] - counts[k - n_win]) * q / (n_win * dt), rtol=1e-12)
    assert np.abs(sm[k, 0] - w_true).max() <= q / (n_win * dt) + 1e-12
    assert np.abs(w[1:] - w_true).max() > 0.5 * q / dt
    enc[100, 0] = np.nan
    assert np.isfinite(trailing_mean(enc, t, n_win * dt)[100:120, 0]).all()
    np.testing.assert_array_equal(trailing_mean(enc, t, 0.0), enc)
