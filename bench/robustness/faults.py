"""Sensor faults applied to a recorded Run, and the "filters under stress" measures.

Fault injection (pure functions: a new Run is returned, the input is not modified; ``truth_*``
columns are never touched; each fault appends a record to ``meta["faults"]`` and a tag to the run
id, so a faulted run has its own content hash and a readable name):

    imu_saturation_spikes(run, times, magnitude, seed)   shock spikes on the IMU, clipped at the
                                                         platform's saturation (ImuSpec.saturation_*)
    encoder_dropouts(run, t0, t1)                        encoder samples in [t0, t1) -> NaN
    gnss_outage(run, t0, t1)                             GNSS samples in [t0, t1) -> NaN (the same
                                                         effect as ``platform.sensors.gnss.outages``
                                                         in the spec, but on an existing run, so the
                                                         clean and faulted runs share physics and noise)

Measures (on the estimate against the run's truth, for tests and reports only):

    position_error(run, est)        (t, |p_est - p_truth|) at the estimate's times
    recovery(t, err, t0, t1)        pre-fault level, max error, recovery time after the fault
    covariance_health(P)            symmetry, finiteness and the minimum eigenvalue per step

Recovery (the issue's criterion "error back within 2x its pre-fault level within 10 s of GNSS
returning"; for the other faults, of the fault's end), made precise here:
    smoothed error   = trailing mean of the error over ``smooth`` s            (default 1 s)
    pre-fault level  = 95th percentile of the smoothed error over [t0 - pre_window, t0)
                       (default 20 s; ``pre_percentile=None``: the plain mean of the error)
    recovery time    = the smallest tau >= 0 such that the smoothed error stays <= factor x pre
                       (factor 2) at every step of [t1 + tau, t1 + horizon]  (default horizon 30 s);
                       +inf when it is still above at the end of the horizon (not recovered).
    paired           = with the same estimator's error on the fault-free run (``reference``), the bound at
                       each step is factor x max(pre, the reference's smoothed error there): the error the
                       path itself causes after the window is not counted against the fault.
The trailing 1 s mean removes the sample-to-sample noise of the error (a 2-D Gaussian error
exceeds twice its mean at about 4 % of the samples) without hiding a real excursion.  The level is
the pre-fault band, not the mean, because a GNSS-aided filter's error wanders slowly (turns,
heading): with the mean, the criterion flagged 8 of 24 fault-free windows of the DUBHE stress runs
(Liu's two filters, seeds 1-6, windows at 60 s and 90 s) as "not recovered"; with the 95th
percentile 1 of 24 (a real 0.19 m excursion of the fault-free run).  A criterion that flags
fault-free runs measures noise, not recovery.  Since the soil of issue 31 (DUBHE slips on the stress path's dirt)
the fault-free error itself rises up to 5x its pre-fault band after some windows (seed 1, UKF+ICR: 0.05 -> 0.24 m
after 92.7 s), so the stress report pairs every faulted estimate with the fault-free one (``reference``);
tests/test_stress.py shows the unpaired criterion flagging the fault-free run and the paired one not.

:func:`bench.robustness.stress.stress_report` runs every filter on every fault and writes ``results/stress.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from bench.run import Run, RunError, sensor_spec, sensor_spec_value

IMU_CHANNELS = ("imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz")
ENCODER_CHANNELS = ("enc_wl", "enc_wr")
GNSS_CHANNELS = ("gnss_x", "gnss_y", "gnss_vx", "gnss_vy", "gnss_yaw")

__all__ = [
    "IMU_CHANNELS", "ENCODER_CHANNELS", "GNSS_CHANNELS", "imu_saturation_spikes", "encoder_dropouts",
    "gnss_outage", "imu_saturation", "position_error", "Recovery", "recovery", "CovarianceHealth",
    "covariance_health",
]


# --------------------------------------------------------------------------------------------
# Fault injection
# --------------------------------------------------------------------------------------------
def _check_window(run: Run, t0: float, t1: float, who: str) -> None:
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ValueError(f"{who}({run.where}): window [{t0!r}, {t1!r}) must be finite with t1 > t0")


def _with_fault(run: Run, data: pd.DataFrame, record: Mapping[str, Any], tag: str) -> Run:
    meta = dict(run.meta)
    meta["faults"] = [*meta.get("faults", []), dict(record)]
    meta["run_id"] = f"{run.id}+{tag}"
    return Run(data, meta)


def _blank(run: Run, channels: Sequence[str], t0: float, t1: float, kind: str) -> Run:
    _check_window(run, t0, t1, kind)
    for c in channels:
        run[c]  # a missing channel is a RunError naming it
    t = run.t
    rows = (t >= t0) & (t < t1)
    data = run.data.copy()
    for c in channels:
        col = data[c].to_numpy(dtype=np.float64, copy=True)
        col[rows] = np.nan
        data[c] = col
    n = int(sum(np.isfinite(run[c][rows]).sum() for c in channels))
    rec = {"kind": kind, "t0": float(t0), "t1": float(t1), "channels": list(channels), "samples_removed": n}
    return _with_fault(run, data, rec, f"{kind}({t0:g},{t1:g})")


def encoder_dropouts(run: Run, t0: float, t1: float, channels: Sequence[str] = ENCODER_CHANNELS) -> Run:
    """Encoder samples with ``t0 <= t < t1`` set to NaN (both sides by default; pass
    ``channels=("enc_wl",)`` for one side).  Truth and every other channel are unchanged."""
    return _blank(run, tuple(channels), float(t0), float(t1), "encoder_dropout")


def gnss_outage(run: Run, t0: float, t1: float, channels: Sequence[str] = GNSS_CHANNELS) -> Run:
    """GNSS samples (position, velocity, heading) with ``t0 <= t < t1`` set to NaN."""
    return _blank(run, tuple(channels), float(t0), float(t1), "gnss_outage")


def imu_saturation(run: Run) -> tuple[float, float]:
    """(accelerometer, gyro) saturation [m/s^2, rad/s] of the run's platform (``meta.platform.
    sensors.imu.saturation_accel/_gyro``); a missing or non-positive value is a RunError."""
    out = []
    for key in ("saturation_accel", "saturation_gyro"):
        v = sensor_spec_value(run, "imu", key)
        if v is None or v <= 0:  # the error names the value as stored
            raise RunError(run.where, f"meta.platform.sensors.imu.{key}", sensor_spec(run, "imu", key),
                           "expected a positive number (IMU saturation)")
        out.append(v)
    return out[0], out[1]


def imu_saturation_spikes(run: Run, times: Iterable[float], magnitude: float = 1.0, seed: int = 0,
                          width: float = 0.0, channels: Sequence[str] = IMU_CHANNELS) -> Run:
    """Shock spikes on the IMU, clipped at the platform's saturation.

    At each time ``tau`` in ``times``, every IMU sample of ``channels`` with ``tau <= t <= tau + width``
    (at least the first sample at or after ``tau``) becomes ``clip(v + s * magnitude * sat, -sat,
    sat)``: ``magnitude`` is the spike amplitude as a fraction of the channel's full scale ``sat``
    (saturation_accel for imu_a*, saturation_gyro for imu_g*; 1.0 = one full scale, so the sample
    lands on or near the rail), ``s = +-1`` is drawn per spike and channel from
    ``numpy.random.default_rng(seed)``.  Deterministic for a given seed."""
    if not (math.isfinite(magnitude) and magnitude > 0):
        raise ValueError(f"imu_saturation_spikes({run.where}): magnitude {magnitude!r} must be > 0 (fraction of full scale)")
    if not (math.isfinite(width) and width >= 0):
        raise ValueError(f"imu_saturation_spikes({run.where}): width {width!r} must be >= 0 s")
    times = [float(x) for x in times]
    if not times or not all(math.isfinite(x) for x in times):
        raise ValueError(f"imu_saturation_spikes({run.where}): times {times!r} must be a non-empty list of finite numbers")
    sat_a, sat_g = imu_saturation(run)
    chans = tuple(channels)
    for c in chans:
        if c not in IMU_CHANNELS:
            raise RunError(run.where, c, None, f"not an IMU channel ({', '.join(IMU_CHANNELS)})")
    t = run.t
    rng = np.random.default_rng(seed)
    signs = rng.choice(np.array([-1.0, 1.0]), size=(len(times), len(chans)))
    data = run.data.copy()
    hit = 0
    for j, c in enumerate(chans):
        sat = sat_a if c.startswith("imu_a") else sat_g
        col = data[c].to_numpy(dtype=np.float64, copy=True)
        have = np.flatnonzero(np.isfinite(col))
        if have.size == 0:
            raise RunError(run.where, c, "all NaN", "no IMU sample to put a spike on")
        for i, tau in enumerate(times):
            first = np.searchsorted(t[have], tau, side="left")
            if first >= have.size:
                raise ValueError(f"imu_saturation_spikes({run.where}): spike time {tau:g} s is after the last {c} sample")
            rows = have[(t[have] >= tau) & (t[have] <= tau + width)]
            rows = rows if rows.size else have[first:first + 1]
            col[rows] = np.clip(col[rows] + signs[i, j] * magnitude * sat, -sat, sat)
            hit += rows.size
        data[c] = col
    rec = {"kind": "imu_spikes", "times": times, "magnitude": float(magnitude), "seed": int(seed),
           "width": float(width), "channels": list(chans), "samples_changed": int(hit),
           "saturation": [sat_a, sat_g]}
    return _with_fault(run, data, rec, f"imu_spikes(n={len(times)},m={magnitude:g})")


# --------------------------------------------------------------------------------------------
# Measures
# --------------------------------------------------------------------------------------------
def position_error(run: Run, est: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t, e): the estimate's times and its horizontal position error against ``truth_x/y`` of
    ``run`` (truth interpolated at the estimate's times; exact at the log rows)."""
    t = np.asarray(est.t, dtype=float)
    rt = run.t
    ex = np.asarray(est["x"], float) - np.interp(t, rt, run["truth_x"])
    ey = np.asarray(est["y"], float) - np.interp(t, rt, run["truth_y"])
    return t, np.hypot(ex, ey)


@dataclass(frozen=True)
class Recovery:
    """Position error around one fault (metres, seconds)."""

    pre: float  # pre-fault level (95th percentile of the 1 s mean error over the pre-fault window)
    max_fault: float  # max error during [t0, t1]
    max_after: float  # max error over (t1, t1 + horizon]
    max_total: float  # max error from t0 to the end of the horizon
    recovery_time: float  # s after t1; inf = not recovered within the horizon
    factor: float
    t0: float
    t1: float

    def recovered_within(self, seconds: float) -> bool:
        return self.recovery_time <= seconds


def _trailing_mean(t: np.ndarray, v: np.ndarray, window: float) -> np.ndarray:
    """Mean of ``v`` over (t_k - window, t_k] at every k (cumulative sums); +inf where the window
    holds a non-finite value."""
    ok = np.isfinite(v)
    c = np.concatenate(([0.0], np.cumsum(np.where(ok, v, 0.0))))
    nbad = np.concatenate(([0], np.cumsum(~ok)))
    lo = np.searchsorted(t, t - window, side="right")
    hi = np.arange(1, t.size + 1)
    return np.where(nbad[hi] - nbad[lo] > 0, np.inf, (c[hi] - c[lo]) / (hi - lo))


def recovery(t: np.ndarray, err: np.ndarray, t0: float, t1: float, *, pre_window: float = 20.0,
             factor: float = 2.0, smooth: float = 1.0, horizon: float = 30.0,
             pre_percentile: float | None = 95.0, reference: np.ndarray | None = None) -> Recovery:
    """Pre-fault level, peaks and recovery time of an error trace around a fault [t0, t1)
    (definitions in the module docstring).  A non-finite error counts as not recovered.  ``reference``: the same
    estimator's error on the fault-free run at the times ``t`` (paired criterion: the bound at each step is factor x
    the larger of the pre-fault level and the reference's smoothed error there)."""
    t = np.asarray(t, dtype=float)
    err = np.asarray(err, dtype=float)
    pre_m = (t >= t0 - pre_window) & (t < t0)
    if not pre_m.any():
        raise ValueError(f"recovery: no sample in the pre-fault window [{t0 - pre_window:g}, {t0:g})")
    if t[-1] < t1 + horizon:
        raise ValueError(f"recovery: the trace ends at {t[-1]:g} s, before t1 + horizon = {t1 + horizon:g} s")
    finite = np.where(np.isfinite(err), err, np.inf)
    sm = _trailing_mean(t, err, smooth)
    pre = float(np.mean(finite[pre_m]) if pre_percentile is None else np.percentile(sm[pre_m], pre_percentile))
    during = (t >= t0) & (t <= t1)
    after = (t > t1) & (t <= t1 + horizon)
    level = pre if reference is None else np.maximum(pre, _trailing_mean(t, np.asarray(reference, dtype=float), smooth))
    bad = after & ~(sm <= factor * level)
    if bad[after][-1]:
        rec = math.inf
    elif not bad.any():
        rec = 0.0
    else:
        last_bad = int(np.flatnonzero(bad)[-1])
        rec = float(t[last_bad + 1] - t1)
    span = (t >= t0) & (t <= t1 + horizon)
    return Recovery(pre, float(finite[during].max()) if during.any() else math.nan, float(finite[after].max()),
                    float(finite[span].max()), rec, factor, float(t0), float(t1))


@dataclass(frozen=True)
class CovarianceHealth:
    steps: int
    finite: bool
    max_asymmetry: float  # max |P - P^T| over all steps and elements
    min_eig: float  # min over steps of the smallest eigenvalue
    min_eig_step: int
    positive_definite: bool  # every step: finite, symmetric to 1e-12 relative, smallest eigenvalue > 0


def covariance_health(P: np.ndarray, chunk: int = 50_000) -> CovarianceHealth:
    """Symmetry, finiteness and smallest eigenvalue of a covariance history ``P`` (T, n, n),
    evaluated in chunks (LAPACK ``syevd`` through ``numpy.linalg.eigvalsh``)."""
    P = np.asarray(P, dtype=float)
    if P.ndim != 3 or P.shape[1] != P.shape[2]:
        raise ValueError(f"covariance_health: expected (T, n, n), got {P.shape}")
    T = P.shape[0]
    finite = True
    asym = 0.0
    scale = 0.0
    min_eig, min_step = math.inf, -1
    for a in range(0, T, chunk):
        blk = P[a:a + chunk]
        ok = np.isfinite(blk).all(axis=(1, 2))
        finite &= bool(ok.all())
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            min_eig, min_step = math.nan, a + i
            break
        asym = max(asym, float(np.abs(blk - np.swapaxes(blk, 1, 2)).max()))
        scale = max(scale, float(np.abs(blk).max()))
        ev = np.linalg.eigvalsh(blk)[:, 0]
        j = int(np.argmin(ev))
        if ev[j] < min_eig:
            min_eig, min_step = float(ev[j]), a + j
    pd_ok = finite and asym <= 1e-12 * max(scale, 1.0) and min_eig > 0
    return CovarianceHealth(T, finite, asym, min_eig, min_step, bool(pd_ok))
