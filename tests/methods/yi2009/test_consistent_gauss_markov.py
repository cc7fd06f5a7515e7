"""The consistent configuration (not Yi's): Gauss-Markov row errors and their fit, methods.yi2009.consistent.gauss_markov.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from methods.yi2009.consistent.gauss_markov import (GM_NEGLIGIBLE_SIGMA, YAW_RATE_SCALE_SECONDS, GaussMarkov,
                                                    ar1_mean_var_factor, gauss_markov_fit, gm_sigma_steps,
                                                    moving_mean_var, yaw_rate_scale)
from methods.yi2009.consistent.plugin import ekf_v1_consistent
from tests.methods.yi2009.synthetic import _ar1


WINDOWS = (2.0, 4.0, 8.0, 16.0)


def test_gauss_markov_fit_of_a_bias_is_the_long_correlation_limit():
    """A constant bias (0.02 m/s) plus white noise (sd 0.01): the mean is kept, so sigma is the bias, the
    correlation time is at its upper bound (100 x the longest window: a bias), and the white part comes back."""
    rng = np.random.default_rng(3)
    runs = [0.02 + 0.01 * rng.standard_normal(20_000) for _ in range(3)]
    fit = gauss_markov_fit(runs, 0.008, WINDOWS)
    assert fit.sigma == pytest.approx(0.02, rel=0.03)
    assert fit.tau == pytest.approx(100 * max(WINDOWS), rel=1e-6)
    assert fit.white == pytest.approx(0.01, rel=0.05)
    with pytest.raises(ValueError, match="must be > 0"):
        gauss_markov_fit(runs, 0.0, WINDOWS)
    with pytest.raises(ValueError, match="at least 2 windows"):
        gauss_markov_fit(runs, 0.008, (2.0,))


def test_gauss_markov_fit_of_white_noise_has_no_correlated_part():
    """Pure white noise (sd 0.05, 100 seeds of 6000 samples): closed form V(W) = sd^2 / W at every window, which
    the white part alone gives, so the correlated part is ~0: its low-frequency share sigma^2 g(a, W) at the 2 s
    window stays below 3 sd of the sampling error of V(2 s) (sd^2 / W sqrt(2 W / N) for overlapping windows,
    generous), and the white part is the sd."""
    rng = np.random.default_rng(7)
    dt, sd, n = 0.008, 0.05, 6000
    w = int(round(2.0 / dt))
    for _ in range(100):
        e = sd * rng.standard_normal(n)
        fit = gauss_markov_fit([e], dt, WINDOWS)
        share = fit.sigma**2 * ar1_mean_var_factor(math.exp(-dt / fit.tau), w)
        assert share <= 3.0 * sd**2 / w * math.sqrt(2.0 * w / n) * 3.0
        assert fit.white == pytest.approx(sd, rel=0.05)


def test_gauss_markov_fit_of_a_fast_error_keeps_its_low_frequency_power_and_variance():
    """AR(1) with tau = 0.1 s (below the resolution of the 2-16 s windows) and variance 0.04^2: tau is held at its
    lower bound (1 s, half the shortest window), the fitted model reproduces the measured moving-mean variances at
    every window within 25 % (the low-frequency power a filter integrates; a 1 s Gauss-Markov's moving-mean variance
    falls more slowly than a 0.1 s one's between 2 and 16 s, so the log-fit splits the difference), and
    sigma^2 + white^2 is the variance."""
    rng = np.random.default_rng(5)
    dt, tau, sigma = 0.008, 0.1, 0.04
    series = [_ar1(rng, 8000, dt, tau, sigma) for _ in range(10)]
    fit = gauss_markov_fit(series, dt, WINDOWS)
    assert fit.tau == pytest.approx(0.5 * min(WINDOWS), rel=1e-6)
    a = math.exp(-dt / fit.tau)
    for wsec in WINDOWS:
        w = int(round(wsec / dt))
        model = fit.sigma**2 * ar1_mean_var_factor(a, w) + fit.white**2 / w
        assert model == pytest.approx(moving_mean_var(series, w), rel=0.25), wsec
    assert fit.sigma**2 + fit.white**2 == pytest.approx(sigma**2, rel=0.05)


def test_gauss_markov_fit_masked_steps_keep_windows_in_time_and_floor_the_white_part():
    """NaN-masked steps (every other sample) with windows allowed at >= 45 % finite samples leave the AR(1) fit
    unchanged in time units (windows are counted on the full grid, not in the surviving samples); without the
    allowance no window is complete (clear error); a white floor above the true white sd is applied and flagged."""
    rng = np.random.default_rng(11)
    dt, tau, sigma = 0.008, 3.0, 0.04
    series = [_ar1(rng, 8000, dt, tau, sigma) + 0.002 * rng.standard_normal(8000) for _ in range(30)]
    masked = [np.where(np.arange(e.size) % 2 == 0, e, np.nan) for e in series]
    fit = gauss_markov_fit(masked, dt, WINDOWS, white_floor=0.01, min_fraction=0.45)
    full = gauss_markov_fit(series, dt, WINDOWS)
    assert fit.tau == pytest.approx(full.tau, rel=0.05) and fit.sigma == pytest.approx(full.sigma, rel=0.05)
    assert fit.tau == pytest.approx(tau, rel=0.3) and fit.sigma == pytest.approx(sigma, rel=0.15)
    assert fit.white == 0.01 and fit.white_floored
    assert not full.white_floored
    with pytest.raises(ValueError, match="no window"):
        gauss_markov_fit(masked, dt, WINDOWS)  # every window has half its samples masked


def test_gauss_markov_fit_recovers_a_known_ar1_plus_white_model():
    """Residuals generated as b(k) = a b(k-1) + w (a = exp(-dT/tau), stationary std sigma) plus white noise: the
    moving-mean fit recovers sigma, tau and the white part (white^2 = C(0) - sigma^2 is a difference, resolved when
    white is not small against sigma); ar1_mean_var_factor (the closed form of the variance of a W-sample mean of a
    unit AR(1)) is checked against a simulation."""
    rng = np.random.default_rng(5)
    dt, tau, sigma, white = 0.008, 1.5, 0.04, 0.03
    series = [_ar1(rng, 8000, dt, tau, sigma) + white * rng.standard_normal(8000) for _ in range(40)]
    fit = gauss_markov_fit(series, dt, WINDOWS)
    assert fit.sigma == pytest.approx(sigma, rel=0.15)
    assert fit.tau == pytest.approx(tau, rel=0.3)
    assert fit.white == pytest.approx(white, rel=0.2)
    ar = [_ar1(rng, 8000, dt, tau, 1.0) for _ in range(40)]
    assert ar1_mean_var_factor(math.exp(-dt / tau), 250) == pytest.approx(moving_mean_var(ar, 250), rel=0.1)
    assert ar1_mean_var_factor(0.0, 7) == pytest.approx(1 / 7, rel=1e-12)
    assert ar1_mean_var_factor(1.0, 7) == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(ValueError, match="must be finite and > 0"):
        GaussMarkov(0.0, 1.0, 0.01)


def test_gauss_markov_fit_subtracts_a_known_moving_average_error():
    """AR(1) (sigma 0.004, tau 3 s) plus a count-difference error u_k - u_(k-1) (u white, sd 0.007, as the encoder
    quantisation) plus white (0.003): given the known share of the count difference (2 sd^2 / W^2 for a W-sample mean,
    2 sd^2 at lag 0), the fit recovers the AR(1) and a white part without the count difference; without it the
    white part absorbs it (sigma^2 + white^2 = total variance)."""
    rng = np.random.default_rng(9)
    dt, sq = 0.008, 0.007
    series = []
    for _ in range(30):
        u = sq * rng.standard_normal(8001)
        series.append(_ar1(rng, 8000, dt, 3.0, 0.004) + np.diff(u) + 0.003 * rng.standard_normal(8000))
    fit = gauss_markov_fit(series, dt, WINDOWS, known_var=lambda w: 2 * sq * sq / (w * w))
    assert fit.sigma == pytest.approx(0.004, rel=0.2) and fit.tau == pytest.approx(3.0, rel=0.4)
    assert fit.white == pytest.approx(0.003, rel=0.15)
    blind = gauss_markov_fit(series, dt, WINDOWS)
    assert blind.white**2 + blind.sigma**2 == pytest.approx(moving_mean_var(series, 1), rel=1e-9)
    assert blind.white == pytest.approx(math.sqrt(0.003**2 + 2 * sq * sq), rel=0.15)


def test_gm_sigma_steps_scales_with_the_trailing_yaw_rate():
    """A per_yaw_rate Gauss-Markov std is sigma x the trailing mean of |w_z| over YAW_RATE_SCALE_SECONDS (closed form
    on a constant turn of -0.4 rad/s after the window fills; 0 rad/s gives the floor), a constant one stays sigma,
    and no per_yaw_rate error means no per-step sigma (None)."""
    dt, n = 0.008, 400
    t = np.arange(n) * dt
    gyr = np.zeros((n, 3))
    gyr[200:, 2] = -0.4
    gx, gy = GaussMarkov(0.002, 1.0, 0.01), GaussMarkov(0.003, 2.0, 1e-4, per_yaw_rate=True)
    sig = gm_sigma_steps((gx, gy), yaw_rate_scale(gyr, t))
    w = int(round(YAW_RATE_SCALE_SECONDS / dt))
    np.testing.assert_allclose(yaw_rate_scale(gyr, t)[200 + w:], 0.4, rtol=1e-12)
    assert np.all(sig[:, 0] == 0.002)
    np.testing.assert_allclose(sig[200 + w:, 1], math.hypot(0.003 * 0.4, GM_NEGLIGIBLE_SIGMA), rtol=1e-12)
    np.testing.assert_allclose(sig[:200, 1], GM_NEGLIGIBLE_SIGMA, rtol=1e-12)
    assert gm_sigma_steps((gx,), yaw_rate_scale(gyr, t)) is None
    with pytest.raises(ValueError, match="vx_gate"):
        ekf_v1_consistent(vx_gate=-0.1)


def test_gauss_markov_fit_recovers_a_per_yaw_rate_model():
    """Residuals b(k) = s(k) beta(k) + white, beta a unit AR(1) x sigma, s alternating 20 s at 0.5 rad/s and 20 s at
    0 (turns and straights): the fit with the scale recovers sigma [m per rad/s], tau and the white part; without
    the scale it returns the turn-and-straight average; a scale that is zero everywhere is a clear error."""
    rng = np.random.default_rng(11)
    dt, tau, sigma, white, n = 0.008, 1.5, 0.01, 0.002, 10000
    scale = np.where((np.arange(n) * dt // 20.0) % 2 == 0, 0.5, 0.0)
    series = [scale * _ar1(rng, n, dt, tau, sigma) + white * rng.standard_normal(n) for _ in range(40)]
    fit = gauss_markov_fit(series, dt, WINDOWS, scale=[scale] * len(series))
    assert fit.per_yaw_rate and fit.sigma == pytest.approx(sigma, rel=0.15)
    assert fit.tau == pytest.approx(tau, rel=0.3) and fit.white == pytest.approx(white, rel=0.2)
    flat = gauss_markov_fit(series, dt, WINDOWS)
    assert not flat.per_yaw_rate and flat.sigma == pytest.approx(sigma * 0.5 * math.sqrt(np.mean(scale > 0)), rel=0.15)
    with pytest.raises(ValueError, match="scale is zero"):
        gauss_markov_fit(series, dt, WINDOWS, scale=[np.zeros(n)] * len(series))
