"""The reference sensor in the consistent configuration's noise identification (not Yi's).

The body velocity from the reference pose by Savitzky-Golay differentiation, divided by the derivative's gain on a
turn (:func:`reference_body_velocity`, :func:`savgol_turn_gain`), its smoothing error at command changes predicted
from the gyro and the encoders (:func:`reference_smoothing_bias`) and the variance of its noise over W-sample means
(:func:`reference_velocity_noise_mean_var`).  The paper's own use of the reference, eq. (7) for Fig. 4, is
:func:`methods.yi2009.s_gamma.reference_s_gamma_point`.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import cumulative_trapezoid
from scipy.signal import savgol_filter

from bench.run import Run, RunError, reference_position_noise, sensor_spec_value
from methods.yi2009.consistent.sensors import _no_slip_speed
from methods.yi2009.s_gamma import REF_CHANNELS

def _reference_derivative(run: Run, window: float, polyorder: int) -> tuple[np.ndarray, float, int, np.ndarray]:
    """(rows with a full reference pose, reference sample period h [s], Savitzky-Golay window [samples, odd] for
    ``window`` s, its first-derivative coefficients c_k) of :func:`reference_body_velocity`."""
    from scipy.signal import savgol_coeffs

    d = run.data
    for c in REF_CHANNELS:
        if c not in d.columns:
            raise RunError(run.where, c, None, "missing reference channel needed by the noise identification")
    ok = np.isfinite(d["ref_x"].to_numpy()) & np.isfinite(d["ref_y"].to_numpy()) & np.isfinite(d["ref_yaw"].to_numpy())
    tr = run.t[ok]
    h = float(np.median(np.diff(tr))) if tr.size > 1 else math.nan
    win = max(polyorder + 2, int(round(window / h)) | 1) if math.isfinite(h) else 0
    if tr.size < max(win, 8):
        raise RunError(run.where, "ref_x", f"{tr.size} samples", f"too few reference samples for a {window} s derivative")
    return ok, h, win, savgol_coeffs(win, polyorder, deriv=1, delta=h, use="dot")


def reference_body_velocity(run: Run, t: np.ndarray, window: float = 1.0, polyorder: int = 2
                            ) -> tuple[np.ndarray, np.ndarray, float]:
    """Body velocity (v_x, v_y) [m/s] at times ``t`` from the reference pose (ref_x, ref_y, ref_yaw),
    by Savitzky-Golay differentiation over ``window`` s (local polynomial of ``polyorder``) on the
    reference's own uniform grid, divided by the filter's gain on a turn at the smoothed yaw rate (exact
    for a steady turn), rotated by the smoothed reference yaw; NaN outside the reference span.
    Also returns the variance of the derivative's noise per axis, pos_noise^2 sum(c_k^2) with the
    filter's derivative coefficients c_k and ``meta.platform.sensors.reference.pos_noise`` (0 if absent)."""
    d = run.data
    ok, h, win, coef = _reference_derivative(run, window, polyorder)
    vx, vy = _savgol_body_velocity(run.t[ok], d["ref_x"].to_numpy()[ok], d["ref_y"].to_numpy()[ok],
                                   np.unwrap(d["ref_yaw"].to_numpy()[ok]), t, h, win, coef, polyorder)
    return vx, vy, reference_position_noise(run) ** 2 * float(np.sum(coef**2))


def _savgol_body_velocity(tr: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray, t: np.ndarray, h: float,
                          win: int, coef: np.ndarray, polyorder: int) -> tuple[np.ndarray, np.ndarray]:
    """The operator of :func:`reference_body_velocity` on a pose (x, y, unwrapped yaw) sampled at ``tr``."""
    tg = np.arange(tr[0], tr[-1] + 0.5 * h, h)
    xs, ys, yaws = (np.interp(tg, tr, v) for v in (x, y, yaw))
    kw = dict(window_length=win, polyorder=polyorder, delta=h, mode="interp")
    xd, yd = savgol_filter(xs, deriv=1, **kw), savgol_filter(ys, deriv=1, **kw)
    psi = savgol_filter(yaws, deriv=0, **kw)
    psid = savgol_filter(yaws, deriv=1, **kw)
    gain = savgol_turn_gain(psid, coef, h)  # divided out: exact for a steady turn
    c, s = np.cos(psi), np.sin(psi)
    vx, vy = (c * xd + s * yd) / gain, (-s * xd + c * yd) / gain
    inside = (t >= tg[0]) & (t <= tg[-1])
    return np.where(inside, np.interp(t, tg, vx), np.nan), np.where(inside, np.interp(t, tg, vy), np.nan)


def savgol_turn_gain(w: ArrayLike, coef: np.ndarray, h: float) -> np.ndarray:
    """gain(w) = sum_k c_k sin(w t_k) / w: the share of the true velocity that the Savitzky-Golay first-derivative
    coefficients ``coef`` (window centred, sample period ``h`` [s]) return on a turn at yaw rate ``w`` [rad/s]
    (antisymmetric c_k: no phase shift; 1 on a straight line, ~2.5 % low at 1 rad/s over 1 s)."""
    tk = (np.arange(coef.size) - coef.size // 2) * h
    w = np.asarray(w, float)
    w = np.where(np.abs(w) > 1e-6, w, 1e-6)
    return (np.sin(np.multiply.outer(w, tk)) @ coef) / w


REFERENCE_BIAS_SMOOTHING = 0.1  # [s] moving mean of the encoder speed in reference_smoothing_bias


def reference_smoothing_bias(run: Run, t: np.ndarray, gyr: np.ndarray, enc: np.ndarray, r: float,
                             window: float = 1.0, polyorder: int = 2,
                             smoothing: float = REFERENCE_BIAS_SMOOTHING) -> tuple[np.ndarray, np.ndarray]:
    """Smoothing error (v_x, v_y) [m/s] of :func:`reference_body_velocity` at times ``t``, predicted from the
    robot's inner sensors (not Yi's): the reference's Savitzky-Golay derivative is exact only where the position is
    locally a polynomial of ``polyorder`` over ``window`` s, so at a change of the commanded speed or turn it
    returns a smoothed velocity (measured on the step calibration run against the testbed truth: 0.023 m/s RMS
    along the heading where the position noise accounts for 0.009).  The same operator is applied to the pose
    dead-reckoned from the gyro (yaw) and the encoders' no-slip speed (a ``smoothing``-s moving mean, no lateral
    velocity), sampled at the reference's times; its output minus the dead-reckoned body velocity is the
    operator's error on that motion, which differs from the error on the true motion only by the operator's
    error on the slip velocities (slower and smaller).  NaN encoder samples are interpolated over; no finite
    speed: zeros."""
    from scipy.ndimage import uniform_filter1d

    ok, h, win, coef = _reference_derivative(run, window, polyorder)
    v = _no_slip_speed(enc, r)
    fin = np.isfinite(v)
    if not fin.any():
        return np.zeros(t.size), np.zeros(t.size)
    v = np.interp(t, t[fin], v[fin])
    n = max(1, int(round(smoothing / float(np.median(np.diff(t)))))) if t.size > 1 else 1
    v = uniform_filter1d(v, n, mode="nearest")
    yaw = cumulative_trapezoid(np.nan_to_num(gyr[:, 2]), t, initial=0.0)
    x = cumulative_trapezoid(v * np.cos(yaw), t, initial=0.0)
    y = cumulative_trapezoid(v * np.sin(yaw), t, initial=0.0)
    tr = run.t[ok]
    bx, by = _savgol_body_velocity(tr, np.interp(tr, t, x), np.interp(tr, t, y), np.interp(tr, t, yaw), t, h, win,
                                   coef, polyorder)
    return bx - v, by


def reference_velocity_noise_mean_var(run: Run, dt: float, window: float = 1.0, polyorder: int = 2,
                                      speed_ms: float = 0.0, yaw_rates: ArrayLike | None = None
                                      ) -> Callable[[int], float]:
    """Variance of the W-sample mean (filter grid ``dt``) of the noise of :func:`reference_body_velocity` per axis:
    the Savitzky-Golay derivative of white position noise (``reference_position_noise``) has the autocovariance
    pos_noise^2 sum_k c_k c_(k+m) at m reference samples (zero beyond the window), interpolated to the filter's
    lags; returns W -> (1/W^2) sum_i sum_j acov(|i - j| dt).  With ``speed_ms`` > 0 (the mean square forward speed
    [m^2/s^2], for the lateral axis) it adds the rotation by the smoothed reference yaw: its noise (white yaw noise
    ``meta.platform.sensors.reference.yaw_noise``, 0 if absent, through the smoothing coefficients d_k) turns the
    forward speed into a lateral error -v_x dpsi, autocovariance speed_ms yaw_noise^2 sum_k d_k d_(k+m).
    ``yaw_rates`` [rad/s] (the yaw rates of the steps the means are taken over; None: no turning): the position
    noise's derivative is isotropic in the world frame and is rotated into the body frame, which turns at w
    against it, so its per-axis autocovariance there is acov(tau) cos(w tau) (E[R(-psi(t)) n(t) n(t+tau)^T
    R(psi(t+tau))] = acov(tau) R(w tau) at a steady w), and divided, like the velocity, by the derivative's turn gain
    (:func:`savgol_turn_gain`), acov(tau) cos(w tau) / gain(w)^2, averaged over the steps (on a steady turn at
    1.3 rad/s, 200 seeds of the closed-form run: without the gain the single-sample variance was 4-13 % above the
    formula, as 1 / gain^2 = 1.09 predicts; on a straight line 2-5 % below).  A derivative's coefficients
    sum to zero, so without turning the noise of a long mean telescopes (variance ~ 1/W^2); in a turn it does not
    (~ the derivative's spectrum at w, ~ 1/W): measured on the calibration runs against the truth, the reference's
    v_y error at 2 / 4 s means in turns was 2.36 / 1.41 mm/s where the formula without turning gives 2.19 /
    1.15, and that excess (0.9 / 0.8 mm/s, the size of the v_y row's own error) was identified as row error."""
    _, h, win, coef = _reference_derivative(run, window, polyorder)
    ac_ref = _coef_autocovariance(coef) * reference_position_noise(run) ** 2
    if yaw_rates is not None:
        w = np.asarray(yaw_rates, float)
        w = w[np.isfinite(w)]
        if w.size:
            ac_ref = ac_ref * (np.cos(np.outer(np.arange(ac_ref.size) * h, w)) / savgol_turn_gain(w, coef, h) ** 2
                               ).mean(axis=1)
    if speed_ms > 0:
        from scipy.signal import savgol_coeffs

        yaw_noise = sensor_spec_value(run, "reference", "yaw_noise") or 0.0
        ac_ref = ac_ref + speed_ms * yaw_noise**2 * _coef_autocovariance(savgol_coeffs(win, polyorder, use="dot"))

    def mean_var(w: int) -> float:
        m = np.arange(int(w))
        ac = np.interp(m * dt / h, np.arange(win + 1), ac_ref, right=0.0)
        return float((w * ac[0] + 2.0 * np.sum((w - m[1:]) * ac[1:])) / (w * w))

    return mean_var


def _coef_autocovariance(coef: np.ndarray) -> np.ndarray:
    """sum_k c_k c_(k+m) for m = 0 .. len(coef) (the last 0): the autocovariance of a filter's output on unit white
    noise, per sample lag."""
    win = coef.size
    return np.array([float(coef[:win - m] @ coef[m:]) for m in range(win)] + [0.0])
