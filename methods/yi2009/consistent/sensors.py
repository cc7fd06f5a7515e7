"""The robot's inner sensors in the consistent configuration (not Yi's): their speeds, errors and noise.

The encoders' no-slip speed r (w_L + w_R)/2 and the steps with a wheel turning; the encoder quantisation as the
v_x row's white floor (:func:`encoder_white_floor`), as states (:func:`encoder_quantisation`) and as the odometer's
error over a window (:func:`encoder_odometer_sd`, :func:`odometer_min_window`); the IMU's white noise from the rest
at the start of calibration runs (:func:`static_imu_noise`); causal trailing means (:func:`trailing_mean`) and the
traction transients in which the v_x row is not fused (:func:`traction_transient`).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import pandas as pd

from bench.run import Run, RunError, encoder_count_speed, sensor_spec, sensor_spec_value
from methods.yi2009.ekf import _geometry, align_inputs

def _no_slip_speed(enc: np.ndarray, r: float) -> np.ndarray:
    """r (w_L + w_R)/2 per step [m/s] (NaN where an encoder sample is NaN)."""
    return 0.5 * r * (enc[:, 0] + enc[:, 1])


def _moving(enc: np.ndarray, r: float, min_wheel_speed: float) -> np.ndarray:
    """Steps with a wheel turning (r |w| >= ``min_wheel_speed`` on either side; NaN counts as at rest)."""
    return r * np.abs(np.nan_to_num(enc)).max(axis=1) >= min_wheel_speed


def trailing_mean(enc: np.ndarray, t: np.ndarray, seconds: float) -> np.ndarray:
    """(n, m) trailing (causal) mean of the columns (the encoder speeds; also used for IMU channels) over the last
    ``seconds`` s of samples (NaN samples skipped; NaN until a finite one).  A wheel speed is a count difference
    over one sample, so its quantisation error telescopes in the mean: over N samples it is (u_N - u_0)/N (see
    :func:`encoder_quantisation`)."""
    n_win = max(1, int(round(seconds / float(np.median(np.diff(t)))))) if t.size > 1 and seconds > 0 else 1
    if n_win == 1:
        return np.array(enc, float, copy=True)
    return pd.DataFrame(enc).rolling(n_win, min_periods=1).mean().to_numpy()


TRANSIENT_MEAN_SECONDS = 0.1  # [s] trailing mean of f_x compared with the v_x row's gate
TRANSIENT_HOLD_SECONDS = 0.3  # [s] the gate stays shut this long after the mean falls back below it


def traction_transient(acc: np.ndarray, t: np.ndarray, gate: float) -> np.ndarray:
    """(n,) bool: the steps where the v_x row (13) is not fused (``vx_skip`` of :func:`run_filter_gm`): the
    ``TRANSIENT_MEAN_SECONDS`` trailing mean of the specific force f_x exceeds ``gate`` [m/s^2] in magnitude, and
    the ``TRANSIENT_HOLD_SECONDS`` after.  At a wheel-speed step the treads slip far beyond the linear traction
    region of :class:`TractionSlip` for a few tenths of a second (the v_x row minus the reference on
    ``yi_calib_steps``: see :class:`Yi2009EkfConsistent`), an error neither the traction slip nor a stationary
    Gauss-Markov state represents; the strapdown prediction bridges it.  ``gate`` <= 0: never (all False)."""
    n = acc.shape[0]
    if gate <= 0 or n == 0:
        return np.zeros(n, bool)
    over = np.abs(trailing_mean(acc[:, 0:1], t, TRANSIENT_MEAN_SECONDS)[:, 0]) > gate
    hold = math.ceil(TRANSIENT_HOLD_SECONDS / float(np.median(np.diff(t))) - 1e-6) + 1 if n > 1 else 1
    return pd.Series(over.astype(float)).rolling(hold, min_periods=1).max().to_numpy() > 0.0


def static_imu_noise(runs: Sequence[Run], min_samples: int = 50, guard: float = 0.25, required: bool = True
                     ) -> tuple[float, float, int] | None:
    """White noise per sample of the accelerometer [m/s^2] and gyro [rad/s] from the initial rest of
    calibration runs (IMU steps more than ``guard`` s before the first non-zero encoder reading: the first count
    lags the start of the motion): per-run, per-axis sample variance about the axis mean (the gravity/bias level),
    pooled over runs with weights n_i - 1 (degrees of freedom) and as the mean over axes.  Returns (accel std,
    gyro std, samples used); when no run has ``min_samples`` at rest: RunError if ``required``, else None."""
    va, vg, dof, n = np.zeros(3), np.zeros(3), 0, 0
    for run in runs:
        t, acc, gyr, enc = align_inputs(run)
        moving = np.flatnonzero(np.isfinite(enc).all(axis=1) & (np.abs(enc).max(axis=1, initial=0.0) > 1e-9))
        stop = int(np.searchsorted(t, t[moving[0]] - guard)) if moving.size else t.size
        if stop < min_samples:
            continue
        va += (stop - 1) * np.var(acc[:stop], axis=0, ddof=1)
        vg += (stop - 1) * np.var(gyr[:stop], axis=0, ddof=1)
        dof += stop - 1
        n += stop
    if n == 0:
        if not required:
            return None
        raise RunError(", ".join(r.id for r in runs) or "(no runs)", "enc_wl/enc_wr", "no rest at the start",
                       f"the IMU noise identification needs >= {min_samples} IMU samples at rest before the wheels "
                       "move")
    return float(np.sqrt(np.mean(va / dof))), float(np.sqrt(np.mean(vg / dof))), n


def _encoder_speed_quantum(run: Run) -> float | None:
    """r q rate_hz [m/s] with q = 2 pi / counts_per_rev (``meta.platform.sensors.encoder``): one count per
    sample as a tread speed; None when the spec lacks either value."""
    quantum = encoder_count_speed(run)
    return None if quantum is None else _geometry(run)[0] * quantum


def encoder_white_floor(run: Run) -> tuple[float, str]:
    """Lower bound [m/s] of the white noise of the v_x row (13), r (w_L + w_R)/2: the encoder speed quantisation
    q = 2 pi rate / counts_per_rev (``meta.platform.sensors.encoder``), each wheel speed a difference of two
    uniformly quantised counts (sd q / sqrt(6)), averaged over the two wheels: r q / sqrt(12).  An explicit
    ``encoder.noise`` [rad/s] in the meta takes precedence (r noise / sqrt(2)); (0, "none") when neither exists."""
    noise = sensor_spec_value(run, "encoder", "noise")
    if noise is not None and noise > 0:
        return _geometry(run)[0] * noise / math.sqrt(2.0), "encoder noise spec"
    quantum = _encoder_speed_quantum(run)
    return (0.0, "none") if quantum is None else (quantum / math.sqrt(12.0), "encoder quantisation")


def encoder_quantisation(run: Run) -> float:
    """Std [m/s] of the quantisation residual u of the v_x row (13), r (w_L + w_R)/2, whose error is u_k - u_(k-1):
    each wheel speed is a count difference times q = 2 pi / counts_per_rev over the sample interval, so its error
    is the difference of two uniform residuals of r q rate_hz (sd r q rate / sqrt(12) each); the mean of two wheels
    gives u with sd r q rate / sqrt(24) (``meta.platform.sensors.encoder``).  RunError when the spec is absent."""
    quantum = _encoder_speed_quantum(run)
    if quantum is None:
        got = {k: sensor_spec(run, "encoder", k) for k in ("counts_per_rev", "rate_hz")}
        raise RunError(run.where, "meta platform.sensors.encoder", got,
                       "the encoder quantisation states need counts_per_rev and rate_hz (> 0)")
    return quantum / math.sqrt(24.0)


def encoder_odometer_sd(run: Run) -> float:
    """Std [m] of the quantisation error of the v_x row's displacement over a window, r q (c_L + c_R) / 2 between
    two samples: each count's residual uniform over one count, four of them, (r q / 2)^2 4 / 12 = (r q)^2 / 12."""
    quantum = _encoder_speed_quantum(run)
    rate = sensor_spec_value(run, "encoder", "rate_hz")
    if quantum is None or rate is None or not rate > 0:
        raise RunError(run.where, "meta platform.sensors.encoder", rate,
                       "the odometer needs counts_per_rev and rate_hz")
    return quantum / rate / math.sqrt(12.0)


def odometer_min_window(run: Run, accel_noise: float, dt: float, share: float = 0.25) -> float:
    """Shortest odometer window T [s] (a whole number of filter steps ``dt``) whose mean-speed quantisation error
    r q / (sqrt(12) T) (:func:`encoder_odometer_sd` / T) is at most ``share`` of the velocity random walk that the
    accelerometer's white noise (``accel_noise`` per sample, one sample per step) adds over it,
    accel_noise sqrt(T dt): T^(3/2) >= r q / (sqrt(12) share accel_noise sqrt(dt))."""
    if not (accel_noise > 0 and dt > 0 and share > 0):
        raise ValueError(f"odometer_min_window: accel_noise = {accel_noise!r}, dt = {dt!r}, share = {share!r} must "
                         "be > 0")
    t_min = (encoder_odometer_sd(run) / (share * accel_noise * math.sqrt(dt))) ** (2.0 / 3.0)
    return math.ceil(t_min / dt - 1e-9) * dt
