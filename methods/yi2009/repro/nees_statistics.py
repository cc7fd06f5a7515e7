"""Statistics of the NEES study (not a Yi claim; issue 4): the band, the summary and the per-run diagnostics.

The two-sided chi-square band of an N-run average NEES (:func:`nees_band`), the nees table's metrics from per-step
NEES arrays (:func:`nees_summary`), the velocity error along / across the heading and its claimed sd
(:func:`body_velocity_errors`, :func:`axis_rms`, :func:`seed_error_correlation`), the slip-clip and roll
diagnostics (:func:`slip_lock_and_roll`), the v_x row's error against the truth (:func:`row_high_frequency_error`,
:func:`row_slip_error`) and one cell's calibrated test against its null distribution.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from bench.estimation.consistency import NullNees
from bench.estimation.nees import horizontal_velocity_error
from bench.estimation.ukf import NEES_MIN_STEP_FRACTION
from bench.registry import Estimate
from bench.run import Run
from methods.yi2009.consistent.filter import SLIP_CLIP_TOL
from methods.yi2009.consistent.plugin import Yi2009EkfConsistent
from methods.yi2009.consistent.rows import _row_offsets
from methods.yi2009.consistent.sensors import _moving, traction_transient
from methods.yi2009.ekf import align_inputs
from methods.yi2009.repro.settings import _geometry

NEES_T_MIN = 5.0  # [s] NEES window start (as bench.robustness.stress.yi_velocity_nees)
NEES_CONFIGS = ("paper", "consistent")


def nees_band(n_runs: int, dof: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided band of the N-run average NEES of a consistent filter: chi2(N dof) / N."""
    from scipy import stats

    a = (1.0 - confidence) / 2
    return float(stats.chi2.ppf(a, n_runs * dof) / n_runs), float(stats.chi2.ppf(1 - a, n_runs * dof) / n_runs)


def body_velocity_errors(run: Run, est: Estimate, t_min: float = NEES_T_MIN) -> np.ndarray:
    """(T, 4) per step after ``t_min``: the horizontal velocity error of :func:`velocity_nees_series` and its
    covariance (block 3:5 of ``est.info["P"]``) rotated into the estimate's heading frame: error along / across
    the heading, and the standard deviation the filter claims along / across (which axis is over- or under-covered)."""
    e, c, s_ = horizontal_velocity_error(run, est)
    P = est.info["P"][:, 3:5, 3:5]
    pxx = c * c * P[:, 0, 0] + 2 * c * s_ * P[:, 0, 1] + s_ * s_ * P[:, 1, 1]
    pyy = s_ * s_ * P[:, 0, 0] - 2 * c * s_ * P[:, 0, 1] + c * c * P[:, 1, 1]
    m = est["t"] >= t_min
    return np.column_stack((c * e[:, 0] + s_ * e[:, 1], -s_ * e[:, 0] + c * e[:, 1], np.sqrt(pxx), np.sqrt(pyy)))[m]


def slip_lock_and_roll(run: Run, est: Estimate, t_min: float = NEES_T_MIN) -> dict[str, float]:
    """Per-run diagnostics of the nees table from the estimate: fraction of steps whose posterior slip (6) of either
    side is at the +-1 clip and the time of the first such step (NaN if none; whole run), the roll error RMS against
    ``truth_roll`` and the RMS roll sd the filter claims (P[6, 6]) after ``t_min``."""
    t = est["t"]
    sl = np.column_stack((est["slip_l"], est["slip_r"]))
    clipped = (np.abs(np.nan_to_num(sl)) >= 1.0 - SLIP_CLIP_TOL).any(axis=1)
    m = t >= t_min
    droll = est["roll"][m] - np.interp(t[m], run.t, run["truth_roll"])
    return {"clip_frac": float(np.mean(clipped)),
            "first_clip_s": float(t[np.argmax(clipped)] - t[0]) if clipped.any() else math.nan,
            "roll_err": float(np.sqrt(np.mean(droll**2))),
            "roll_sd": float(np.sqrt(np.mean(est.info["P"][m][:, 6, 6])))}


def _vx_row_error(run: Run, model: Yi2009EkfConsistent | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, acc, enc, e) on the filter grid (:func:`align_inputs`): e the no-slip v_x row's error against the testbed
    truth, r (w_L + w_R)/2 - v_x, after ``model``'s traction slip c_f f_x + c_w |w_z| when it has one (NaN where the
    step has no encoder pair)."""
    r, _ = _geometry(run)
    t, acc, gyr, enc = align_inputs(run)
    e = 0.5 * r * (enc[:, 0] + enc[:, 1]) - np.interp(t, run.t, run["truth_vx"])
    vx_off = None if model is None else _row_offsets(model.traction, None, acc, gyr, enc, r, model.params)[0]
    return t, acc, enc, (e if vx_off is None else e - vx_off)


def row_high_frequency_error(run: Run, window: float = 0.5, t_min: float = NEES_T_MIN,
                             model: Yi2009EkfConsistent | None = None) -> float:
    """RMS [m/s] of the high-frequency part of the no-slip v_x row's error against the testbed truth, r (w_L + w_R)/2
    - v_x minus its centred ``window``-s moving mean, after ``t_min`` s (diagnostic: the share the row's white R
    stands for, mostly the encoder quantisation).  With ``model``: the row as that model fuses it, after its traction
    slip c_f f_x + c_w |w_z| (which adds the IMU samples' noise)."""
    t, _, _, e = _vx_row_error(run, model)
    e = np.where(np.isfinite(e), e, 0.0)
    w = max(1, int(round(window / float(np.median(np.diff(t))))))
    hf = e - np.convolve(e, np.ones(w) / w, mode="same")
    return float(np.sqrt(np.mean(hf[(t >= t_min) & (np.arange(t.size) >= w) & (np.arange(t.size) < t.size - w)] ** 2)))


def row_slip_error(run: Run, model: Yi2009EkfConsistent, window: float = 1.0, t_min: float = NEES_T_MIN) -> float:
    """RMS [m/s] of the centred ``window``-s moving mean of the no-slip v_x row's error against the testbed truth after
    ``model``'s traction slip, r (w_L + w_R)/2 - c_f f_x - c_w |w_z| - v_x, over the windows centred at t >= ``t_min``
    s in which the wheels turn and ``model`` does not gate the row (no step at rest or in a traction transient; steps
    without a fresh encoder pair are skipped, at least half the window must have one).  Diagnostic: the slow slip that
    the model's v_x Gauss-Markov state stands for, on a scored path or a calibration run.  NaN when no window
    qualifies."""
    t, acc, enc, e = _vx_row_error(run, model)
    seen = np.isfinite(e)
    bad = seen & ~(_moving(enc, _geometry(run)[0], model.params.min_wheel_speed)
                   & ~traction_transient(acc, t, model.vx_gate))
    w = max(1, int(round(window / float(np.median(np.diff(t))))))
    n_bad = pd.Series(bad.astype(float)).rolling(w, center=True, min_periods=w).sum().to_numpy()  # NaN: no whole window
    mm = pd.Series(np.where(seen, e, np.nan)).rolling(w, center=True, min_periods=max(1, w // 2)).mean().to_numpy()
    ok = (n_bad == 0) & np.isfinite(mm) & (t >= t_min)
    return float(np.sqrt(np.mean(mm[ok] ** 2))) if ok.any() else math.nan


def axis_rms(a: np.ndarray) -> dict[str, float]:
    """RMS over the rows of :func:`body_velocity_errors` arrays: velocity error and claimed sd along / across the
    heading (``err_along``, ``err_across``, ``sd_along``, ``sd_across``)."""
    return {key: float(np.sqrt(np.mean(a[:, j] ** 2)))
            for j, key in enumerate(("err_along", "err_across", "sd_along", "sd_across"))}


def seed_error_correlation(per_seed: Sequence[np.ndarray]) -> float:
    """Mean over seed pairs of the (uncentred) correlation of their normalised velocity errors, along and across
    the heading pooled: sum_t z_i z_j / sqrt(sum_t z_i^2 sum_t z_j^2) with z = error / claimed sd, from the (T, 4)
    arrays of :func:`body_velocity_errors` (one per seed, truncated to the shortest).  1 when the seeds' errors are
    the same (a common cause: the seeds change only the sensor noise, not the physics), 0 when independent; the
    seed-averaged NEES then behaves as if from N_eff = N / (1 + (N - 1) rho) independent runs (design effect)."""
    T = min(a.shape[0] for a in per_seed)
    z = [np.concatenate((a[:T, 0] / a[:T, 2], a[:T, 1] / a[:T, 3])) for a in per_seed]
    rho = [float(zi @ zj / math.sqrt((zi @ zi) * (zj @ zj))) for i, zi in enumerate(z) for zj in z[i + 1:]]
    return float(np.mean(rho)) if rho else math.nan


def nees_summary(series: Mapping[tuple[str, str, int], np.ndarray], n_seeds: int, dof: int = 2,
                 confidence: float = 0.95) -> dict[str, float]:
    """Metrics of the nees table from per-step NEES arrays (n_seeds, T): ``<path>.<config>.v<k>.nees`` (time
    mean of the seed-averaged NEES), ``.in_band`` / ``.below`` / ``.above`` (fraction of steps whose seed-averaged
    NEES is inside / below / above the band; they sum to 1), ``<config>_in_band`` = 1 when every path's and scheme's seed-averaged NEES is in the
    band at >= ``bench.estimation.ukf.NEES_MIN_STEP_FRACTION`` of the steps (Bar-Shalom's test), and ``<config>_mean_in_band``
    (reported only) = 1 when every time mean lies in the band."""
    lo, hi = nees_band(n_seeds, dof, confidence)
    out: dict[str, float] = {"band_lo": lo, "band_hi": hi, "n_seeds": float(n_seeds)}
    ok = {c: True for c in NEES_CONFIGS}
    ok_mean = {c: True for c in NEES_CONFIGS}
    for (k, c, v), arr in series.items():
        avg = np.mean(arr, axis=0)
        m = float(np.mean(avg))
        out[f"{k}.{c}.v{v}.nees"] = m
        out[f"{k}.{c}.v{v}.in_band"] = float(np.mean((avg >= lo) & (avg <= hi)))
        out[f"{k}.{c}.v{v}.below"] = float(np.mean(avg < lo))
        out[f"{k}.{c}.v{v}.above"] = float(np.mean(avg > hi))
        if c in ok:  # ablation configurations are reported, not judged
            ok[c] = ok[c] and out[f"{k}.{c}.v{v}.in_band"] >= NEES_MIN_STEP_FRACTION
            ok_mean[c] = ok_mean[c] and lo <= m <= hi
    for c in NEES_CONFIGS:
        out[f"{c}_in_band"] = float(ok[c])
        out[f"{c}_mean_in_band"] = float(ok_mean[c])
    return out


def _null_test(nl: NullNees, in_band: float, mean_nees: float) -> dict[str, float]:
    """One cell's calibrated test against its null ``nl``: the share of consistent experiments that pass the
    ``NEES_MIN_STEP_FRACTION`` rule, the p of the observed fraction of steps in band ``in_band`` and of the observed
    time-mean NEES ``mean_nees``, and the null's 95 % interval of that mean."""
    lo, hi = nl.mean_interval(0.95)
    return {"rule_pass": float(np.mean(nl.in_band >= NEES_MIN_STEP_FRACTION)), "p_in_band": nl.p_in_band(in_band),
            "mean_lo": lo, "mean_hi": hi, "p_mean": nl.p_mean(mean_nees)}


def _min_p(out: Mapping[str, float], cell: tuple[str, int], test: str) -> float:
    """The smaller of a cell's two p of the calibrated test ``test`` ("null": 5 seeds; "rep": the replication)."""
    key = f"{cell[0]}.consistent.v{cell[1]}.{test}"
    return min(out[f"{key}_p_in_band"], out[f"{key}_p_mean"])
