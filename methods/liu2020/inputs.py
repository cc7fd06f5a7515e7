"""What Liu's estimators read from a Run: platform geometry (Table 1: B, r), the channels each needs,
the start pose, sample holding and the dropout rules.

Paper: eq. (1) (one speed per side: the Run's ``enc_wl``, ``enc_wr``), Table 1 (track B, wheel radius r),
the start point of Fig. 6 (the first GNSS fix).

* Time: the log rows are the filter steps; the step k -> k+1 uses the IMU input at k (zero-order
  hold of the latest sample, :func:`_ffill`) and the measurements at k+1 (Appendix: ``v^ICR_{k+1}``);
  encoder speeds are taken as the average over the interval ending at their sample (DR does the same,
  :func:`_interval_speed`).
* Initial pose (all four plugins): the first GNSS fix (gnss_x, gnss_y, gnss_yaw), held from t_0 (the
  runs start at rest, as Liu's Fig. 6 starts the DR at the GNSS start point; :func:`_initial_pose`).
* Dropouts (not Liu's; the paper does not treat missing samples): a sample older, or a gap longer,
  than ``GAP_INTERVALS`` median sample intervals is a dropout (:func:`_encoder_fresh`,
  :func:`_within_sampling`); see :mod:`methods.liu2020.ukf` and :mod:`methods.liu2020.dead_reckoning`
  for what the estimators do in one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from bench.run import Run, RunError

PAPER = "Liu et al. 2020"
ENCODERS = frozenset({"enc_wl", "enc_wr"})
GNSS_POSE = frozenset({"gnss_x", "gnss_y", "gnss_yaw"})
GNSS_VEL = frozenset({"gnss_vx", "gnss_vy"})
IMU = frozenset({"imu_ax", "imu_ay", "imu_gz"})


@dataclass(frozen=True)
class Geometry:
    """What a user knows of the platform (Liu Table 1): track B and wheel radius r [m]."""

    track: float
    wheel_radius: float


def geometry(run: Run) -> Geometry:
    """B and r from ``run.meta["platform"]``; a missing or non-positive value is a RunError."""
    plat = run.meta.get("platform")
    if not isinstance(plat, Mapping):
        raise RunError(run.where, "meta.platform", plat, "Liu 2020 needs the platform geometry (track, wheel_radius)")
    vals = {}
    for key in ("track", "wheel_radius"):
        v = plat.get(key)
        if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise RunError(run.where, f"meta.platform.{key}", v, "expected a positive number [m]")
        vals[key] = float(v)
    return Geometry(**vals)


def _check_channels(run: Run, channels: frozenset[str], who: str) -> None:
    """Required channels present and non-empty (``Run.require``), and no infinite value (a NaN is
    a missing sample and is handled; an inf is a corrupt log)."""
    run.require(channels, who)
    for c in sorted(channels):
        v = run[c]
        bad = np.isinf(v)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise RunError(run.where, c, f"row {i}: {v[i]}", f"value must be finite (read by {who})")


def _ffill(v: np.ndarray, before: float = 0.0) -> np.ndarray:
    """Zero-order hold of the finite samples (``before`` until the first one)."""
    ok = np.isfinite(v)
    if ok.all():
        return v.astype(float, copy=True)
    idx = np.where(ok, np.arange(v.size), -1)
    np.maximum.accumulate(idx, out=idx)
    out = np.where(idx >= 0, v[np.maximum(idx, 0)], before)
    return out


def _interval_speed(v: np.ndarray) -> np.ndarray:
    """Per-row speed for the interval ending at the row, held until the next sample; the last
    value is repeated so that ``integrate_se2`` (which uses element k for [t_k, t_k+1)) sees the
    speed measured over [t_k, t_k+1] at index k."""
    f = _ffill(v, before=np.nan)
    first = np.flatnonzero(np.isfinite(f))
    f = np.where(np.isfinite(f), f, f[first[0]] if first.size else 0.0)
    return np.concatenate((f[1:], f[-1:]))


def _initial_pose(run: Run) -> tuple[float, float, float, int]:
    """First GNSS fix with x, y and yaw (the start point of Liu's Fig. 6)."""
    x, y, yaw = run["gnss_x"], run["gnss_y"], run["gnss_yaw"]
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y) & np.isfinite(yaw))
    if ok.size == 0:
        raise RunError(run.where, "gnss_x/gnss_y/gnss_yaw", "no joint sample", "Liu 2020 starts from the first GNSS fix")
    i = int(ok[0])
    return float(x[i]), float(y[i]), float(yaw[i]), i


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


GAP_INTERVALS = 1.5  # a sample older / a gap longer than this many median sample intervals is a dropout
TIME_SLACK = 1e-9  # [s] slack of the two gap rules against the rounding of the log times


def _gap_limit(ts: np.ndarray) -> float:
    """[s] the longest age / interval of the samples at times ``ts`` that is not a dropout: ``GAP_INTERVALS``
    median intervals plus ``TIME_SLACK`` (only the slack with fewer than 2 samples)."""
    period = float(np.median(np.diff(ts))) if ts.size >= 2 else 0.0
    return GAP_INTERVALS * period + TIME_SLACK


def _encoder_fresh(t: np.ndarray, enc_ok: np.ndarray) -> np.ndarray:
    """(T,) bool: is the latest encoder pair at step k at most 1.5 of the encoders' median sample
    interval old?  Eqs. (2), (3), (5) give the ICR from the posterior velocities and the wheel speeds
    of the same instant; with the wheel speeds stale (an encoder dropout) they are no observation of
    the ICR, which is then held (the paper does not treat dropouts).  Between the samples of a
    slower encoder the held pair is fresh, as before; before the first pair there is none.  (The age
    limit is :func:`_gap_limit`, with 1e-9 s of slack: at half the row rate, 1.5 intervals fall on a row,
    where the rounding of the times would otherwise decide.)"""
    when = np.where(enc_ok, t, np.nan)
    return (t - _ffill(when, before=-np.inf)) <= _gap_limit(t[enc_ok])


def _within_sampling(ts: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """(len(tq),) bool: does each query time lie between two consecutive samples ``ts`` at most 1.5 of
    their median interval apart (or on a sample)?  False in a gap (a dropout) and outside the samples.
    (The limit is :func:`_gap_limit`, as :func:`_encoder_fresh`'s, with its ``TIME_SLACK``: a sensor at 3 samples
    per 7 log rows has intervals of 2 and 3 rows, median 2, and 3 rows is exactly 1.5 intervals, where the
    rounding of the times would otherwise decide: without the slack 150-168 of 2096 query times were refused at
    start times 0, 0.3 and 3600.1 s and none at 12.345 or 1000 s.)"""
    if ts.size < 2:
        return np.isin(tq, ts)
    i = np.clip(np.searchsorted(ts, tq), 1, ts.size - 1)
    inside = (tq >= ts[0]) & (tq <= ts[-1])
    return inside & ((ts[i] - ts[i - 1] <= _gap_limit(ts)) | (tq == ts[i]) | (tq == ts[i - 1]))
