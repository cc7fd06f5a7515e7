"""First-order Gauss-Markov errors of the pseudo-measurement rows and their identification (not Yi's).

:class:`GaussMarkov` (b(k) = a b(k-1) + w(k) plus a white part), its std per yaw rate (:func:`yaw_rate_scale`,
:func:`gm_sigma_steps`), the variances of the moving means of residual series (:func:`moving_mean_var`,
:func:`ar1_mean_var_factor`) and the white + Gauss-Markov fit on them (:func:`gauss_markov_fit`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from methods.yi2009.consistent.sensors import trailing_mean

@dataclass(frozen=True)
class GaussMarkov:
    """First-order Gauss-Markov error of a pseudo-measurement row, b(k) = a b(k-1) + w(k) with
    a = exp(-dT/tau), Var w = sigma^2 (1 - a^2) (stationary std ``sigma``; Gelb 1974 Table 3.8-1; autocorrelated
    measurement noise by state augmentation: Bar-Shalom, Li, Kirubarajan 2001 Sec. 8.4), plus the white part
    ``white`` of the row's error (``white_floored``: the estimate fell below the physical floor and was raised to it).
    ``per_yaw_rate``: the error's std is not constant but proportional to the turning, sigma_k = sigma s_k with s_k
    the :func:`yaw_rate_scale` (variance-modulated Gauss-Markov process, Var w_k = sigma_k^2 (1 - a^2); sigma in [m]
    per rad/s): the error of the v_y row (15) is (S_true - S) w_z, nil on a straight line whatever the S error."""

    sigma: float  # [m/s] stationary std of the correlated error ([m] per rad/s with per_yaw_rate)
    tau: float  # [s] correlation time
    white: float  # [m/s] std of the white part (the row's R)
    white_floored: bool = False
    per_yaw_rate: bool = False  # stationary std sigma x the yaw-rate scale s_k (gm_sigma_steps), not constant

    def __post_init__(self) -> None:
        for k in ("sigma", "tau", "white"):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"GaussMarkov.{k} = {v!r}: must be finite and > 0")


GM_NEGLIGIBLE_SIGMA = 1e-4  # [m/s] sigma of a correlated part that is not resolved (kept > 0 for the state)
YAW_RATE_SCALE_SECONDS = 0.5  # [s] trailing mean of |w_z| that scales a per_yaw_rate Gauss-Markov error


def yaw_rate_scale(gyr: np.ndarray, t: np.ndarray) -> np.ndarray:
    """s_k [rad/s]: the trailing mean of the gyro's |w_z| over the last ``YAW_RATE_SCALE_SECONDS`` (the scale of a
    ``per_yaw_rate`` :class:`GaussMarkov`; the mean keeps the gyro's white noise, 0.005 rad/s per sample, out of the
    scale: 62 samples at 125 Hz reduce it 8-fold)."""
    return trailing_mean(np.abs(gyr[:, 2:3]), t, YAW_RATE_SCALE_SECONDS)[:, 0]


def gm_sigma_steps(gms: Sequence[GaussMarkov], s: np.ndarray) -> np.ndarray | None:
    """(n, len(gms)) stationary std per step of the Gauss-Markov row errors (``gm_sigma`` of :func:`run_filter_gm`):
    sigma, or sqrt((sigma s_k)^2 + GM_NEGLIGIBLE_SIGMA^2) for a ``per_yaw_rate`` one (``s`` (n,), the
    :func:`yaw_rate_scale`; the floor keeps the state's variance > 0 at s = 0).  None when none is ``per_yaw_rate``
    (constant sigmas)."""
    if not any(g.per_yaw_rate for g in gms):
        return None
    return np.column_stack([np.sqrt(np.square(g.sigma * s) + GM_NEGLIGIBLE_SIGMA**2) if g.per_yaw_rate
                            else np.full(s.size, g.sigma) for g in gms])


def _window_means(res: Sequence[np.ndarray], window: int, min_fraction: float = 1.0,
                  over: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """The centred ``window``-sample moving means of the series (of ``over``, one series per ``res`` series, when
    given) over the windows in which ``res`` has at least ``min_fraction`` of its samples finite (NaN = masked step;
    the mean is over the finite samples), pooled over the series.  ValueError when no window qualifies."""
    out = []
    k = np.ones(int(window))
    for i, e in enumerate(res):
        e = np.asarray(e, float)
        if e.size < window:
            continue
        ok = np.isfinite(e)
        cnt = np.convolve(ok.astype(float), k, mode="valid")
        use = cnt >= max(min_fraction * window, 0.5)
        x = e if over is None else np.asarray(over[i], float)
        out.append(np.convolve(np.where(ok, x, 0.0), k, mode="valid")[use] / cnt[use])
    m = np.concatenate(out) if out else np.empty(0)
    if m.size == 0:
        raise ValueError(f"moving_mean_var: no window of {window} samples with >= {min_fraction:.0%} finite")
    return m


def moving_mean_var(res: Sequence[np.ndarray], window: int, min_fraction: float = 1.0,
                    over: Sequence[np.ndarray] | None = None) -> float:
    """Mean square of the centred ``window``-sample moving mean of the series (mean kept), pooled over the series
    and over the windows with at least ``min_fraction`` of their samples finite (NaN = masked step on the full time
    grid; the mean is over the finite samples).  ``over``: the same for these series (one per ``res`` series, same
    length), averaged over the samples and windows that ``res`` qualifies (the scale of a per_yaw_rate fit)."""
    m = _window_means(res, window, min_fraction, over)
    return float(m @ m) / m.size


def ar1_mean_var_factor(a: float, window: int) -> float:
    """Variance of the mean of ``window`` consecutive samples of a stationary AR(1) of unit variance and lag-1
    correlation ``a``: (W + 2 sum_{m=1}^{W-1} (W - m) a^m) / W^2."""
    m = np.arange(1, int(window))
    return float((window + 2.0 * np.sum((window - m) * a**m)) / window**2)


def gauss_markov_fit(res: Sequence[np.ndarray], dt: float, windows: Sequence[float],
                     known_var: Callable[[int], float] | None = None, white_floor: float = 0.0,
                     min_fraction: float = 1.0, scale: Sequence[np.ndarray] | None = None) -> GaussMarkov:
    """White + first-order Gauss-Markov model of residual series on a uniform grid (NaN = masked step; mean kept)
    from the variance of their moving means over ``windows`` [s] (the averaging-time method of the Allan variance,
    IEEE Std 952-1997 Annex C, with overlapping windows): V(W) = sigma^2 g(a, W) + white^2 / W + K(W), where
    g = :func:`ar1_mean_var_factor`, a = exp(-dT/tau) and K(W) = ``known_var(W)`` the variance of the W-sample
    mean of the error parts that are known and independent of the row's (the reference derivative's noise, the
    encoder quantisation).  white^2 = C(0) - K(1) - sigma^2 (floored at ``white_floor``, flagged when it applies).
    (sigma, tau) minimise the squared log-ratio of model and data over the windows (scipy.optimize.least_squares,
    starts tau = 0.3, 3, 30 s); tau is bounded to [min(windows)/2, 100 max(windows)]: a shorter correlation is not
    resolved by the windows (there it acts as white noise and the fit represents its low-frequency power), a longer
    one is a bias (mean kept).  Windows whose data K explains entirely give sigma -> 0 (``GM_NEGLIGIBLE_SIGMA``).
    ``min_fraction``: least share of finite samples in a window (:func:`moving_mean_var`); windows that no series
    fills are dropped (ValueError when fewer than 2 remain).
    ``scale`` (one series per ``res`` series, e.g. :func:`yaw_rate_scale`): a ``per_yaw_rate`` model, the std
    sigma s_k; the variance of a W-sample mean, sigma^2 / W^2 sum_ij s_i s_j a^|i-j|, is then taken as
    sigma^2 (g^2 S_1(W) + g (1 - g) S_2(W)), g = g(a, W), with S_1 the mean square of the scale's W-sample means and
    S_2 the mean of its W-sample mean squares over the same windows: exact when s is constant within the window, and
    in the two limits where it is not (tau >> W: (mean s)^2; tau << W: the mean of s^2 times g); the white part is
    C(0) - K(1) - sigma^2 S_2(1).
    Replaces the two-lag autocovariance fit (C(L), C(2L) at 1.25 / 2.5 s) of the previous version: with the
    row's correlated error at the level of the sampling noise of C(L), the ratio C(2L)/C(L) was unstable (sigma
    0.014 m/s on the v_x row of the calibration runs where the 2-16 s moving means give 0.003 m/s)."""
    from scipy.optimize import least_squares

    if not (dt > 0 and len(windows) >= 2):
        raise ValueError(f"gauss_markov_fit: dt = {dt!r} must be > 0 and at least 2 windows, got {windows!r}")
    kv = known_var or (lambda w: 0.0)
    c0 = moving_mean_var(res, 1)
    def scale_means(w: int) -> tuple[float, float]:  # (S_1, S_2) of the docstring over the W-sample windows
        if scale is None:
            return 1.0, 1.0
        return (moving_mean_var(res, w, min_fraction, over=scale),
                float(np.mean(_window_means(res, w, min_fraction, over=[np.square(x) for x in scale]))))

    s2_1 = scale_means(1)[1]
    ws, v_l, s2_l = [], [], []
    for wsec in windows:  # windows without a single qualifying stretch in any series are dropped
        w = max(1, int(round(wsec / dt)))
        try:
            v_l.append(moving_mean_var(res, w, min_fraction) - kv(w))
        except ValueError:
            continue
        s2_l.append(scale_means(w))
        ws.append(w)
    if len(ws) < 2:
        raise ValueError(f"gauss_markov_fit: no window of the {list(windows)} s with >= {min_fraction:.0%} finite "
                         f"samples for at least 2 of them (series of {[np.asarray(e).size for e in res]} samples)")
    windows = [w * dt for w in ws]
    v = np.array(v_l)
    floor = max(float(white_floor), 1e-6)
    vmin = 1e-4 * max(c0, 1e-30)
    v_fit = np.maximum(v, vmin)

    if s2_1 <= 0.0 or min(min(sw) for sw in s2_l) <= 0.0:
        raise ValueError(f"gauss_markov_fit: the scale is zero on every qualifying sample (mean squares {s2_1!r}, "
                         f"{s2_l!r}): a per_yaw_rate error needs turning in the calibration runs")

    def model(p: np.ndarray) -> np.ndarray:
        s2, tau = math.exp(p[0]), math.exp(p[1])
        a = math.exp(-dt / tau)
        w2 = max(c0 - kv(1) - s2 * s2_1, floor**2)
        gs = [ar1_mean_var_factor(a, w) for w in ws]
        if scale is None:
            return np.array([s2 * g + w2 / w for w, g in zip(ws, gs)])
        return np.array([s2 * (g * g * s1w + g * (1.0 - g) * s2w) + w2 / w for w, g, (s1w, s2w) in zip(ws, gs, s2_l)])

    lo, hi = np.log([1e-14, 0.5 * min(windows)]), np.log([max(c0 / s2_1, 1e-13), 100.0 * max(windows)])
    best = None
    for tau0 in (0.3, 3.0, 30.0):
        x0 = np.clip(np.log([max(v_fit[-1] / s2_l[-1][1], 1e-13), tau0]), lo + 1e-9, hi - 1e-9)
        fit = least_squares(lambda p: np.log(model(p)) - np.log(v_fit), x0, bounds=(lo, hi))
        if best is None or fit.cost < best.cost:
            best = fit
    s2, tau = math.exp(best.x[0]), math.exp(best.x[1])
    white2 = c0 - kv(1) - s2 * s2_1
    return GaussMarkov(math.sqrt(max(s2, GM_NEGLIGIBLE_SIGMA**2)), tau, math.sqrt(max(white2, floor**2)),
                       bool(white2 < floor**2 and white_floor > 0), per_yaw_rate=scale is not None)


def _row_gms(gm_x: GaussMarkov, gm_y: GaussMarkov | None, variant: int) -> tuple[GaussMarkov, ...]:
    """The Gauss-Markov row errors :func:`run_filter_gm` augments for ``variant``: (gm_x,), scheme 3 (gm_x, gm_y)."""
    return (gm_x, gm_y) if variant == 3 and gm_y is not None else (gm_x,)
