"""Liu's two dead-reckoning estimators ("En-DR" and "ICR" of Figs. 6-20 and Table 2), the constant-ICR
fit that calibrates the second, and the traditional wheel-slip model the paper compares the ICR model with
(abstract: "the ICRs-based model operates more steady than the traditional wheel slip/skid model").

Paper equation -> code
    (1), (8) at y_l = B/2, y_r = -B/2, x = 0, then (9)  no-slip DR ...... EnDr, _dr_estimate
    (8) with constant ICR locations, then (9)          ICR DR ......... IcrDr, _dr_estimate
    (6)-(8) (equivalently (2), (3), (5)) fitted on GNSS  constant ICR ... fit_icr (IcrDr.calibrate)
    (9)  body -> world, integrated exactly on SE(2) ....................... bench.kinematics.integrate_se2
    (10) slip of the outputs .............................................. methods.liu2020.icr.slip_rates
    traditional slip/skid model ([35], [36]): constant slip rates and
         sideslip angle, fitted on GNSS like the ICR ...................... slip_forward, fit_slip, SlipDr

* Slip model (the comparator of the abstract; the paper gives its definition only through (10) and
  [35], [36]): each side's ground speed is ``v_i = (1 - s_i) r w_i`` with the slip rate
  ``s_i = (r w_i - v_i)/(r w_i)`` (the repo convention of :func:`methods.liu2020.icr.slip_rates`),
  ``v_x = (v_l + v_r)/2``, ``theta_dot = (v_r - v_l)/B`` and a sideslip angle ``beta`` ([36]):
  ``v_y = v_x tan(beta)``; three constants (s_l, s_r, beta) against the ICR model's three (y_l, y_r, x),
  fitted by :func:`fit_slip` with the residuals and loss of :func:`fit_icr` on the same calibration runs.

* Frames: Liu's world rotation (9) is printed as ``[[cos, sin], [sin, -cos]]``, a reflection
  (det = -1); with y left and yaw CCW (ENU, DESIGN.md) the proper rotation is used
  (``bench.kinematics.integrate_se2``).  A_ICR (8): its printed second row is garbled; eq. (5)
  ``v_y = -x theta_dot`` is used (as in ``bench.kinematics.icr_forward``).
* Encoder dropout (not Liu's): the dead reckoning, which has nothing better, integrates the last wheel
  speeds through the dropout but reports them NaN in ``wl``, ``wr``, the slips too, and counts the
  stale steps in ``info["stale_encoder_steps"]``.  :func:`fit_icr` drops the GNSS samples that fall in
  an encoder gap instead of interpolating the wheel speeds across it.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np

from bench.kinematics import icr_forward, integrate_se2
from bench.registry import Estimate, NotCalibratedError, make_estimate
from bench.run import Run, RunError
from methods.liu2020.icr import slip_rates
from methods.liu2020.inputs import (
    ENCODERS,
    GNSS_POSE,
    GNSS_VEL,
    PAPER,
    Geometry,
    _check_channels,
    _encoder_fresh,
    _initial_pose,
    _interval_speed,
    _within_sampling,
    _wrap,
    geometry,
)


def _dr_estimate(name: str, run: Run, geom: Geometry, y_l: float, y_r: float, x_icr: float,
                 info: Mapping[str, Any]) -> Estimate:
    """Dead reckoning with A_ICR (8) at the given ICR, integrated with (9).  Through an encoder
    dropout the last wheel speeds are integrated (dead reckoning has nothing better); at those
    steps ``wl``, ``wr`` and the slips are NaN (the held pair is no measurement of the step) and
    ``info["stale_encoder_steps"]`` counts them."""
    t = run.t
    wl_raw, wr_raw = run["enc_wl"], run["enc_wr"]
    v_l = geom.wheel_radius * _interval_speed(wl_raw)
    v_r = geom.wheel_radius * _interval_speed(wr_raw)
    vx, vy, wz = icr_forward(v_l, v_r, y_l, y_r, x_icr)  # eq. (8) / (11)
    x0, y0, yaw0, _ = _initial_pose(run)
    x, y, yaw = integrate_se2(t, vx, vy, wz, x0, y0, yaw0)  # eq. (9), exact SE(2)
    sl, sr = slip_rates(v_l, v_r, vx, wz, geom.track)
    fresh = _encoder_fresh(t, np.isfinite(wl_raw) & np.isfinite(wr_raw))
    stale = ~np.concatenate((fresh[1:], fresh[-1:]))  # row k holds the speeds sampled at k + 1 (_interval_speed)
    wl, wr = (np.where(stale, np.nan, v / geom.wheel_radius) for v in (v_l, v_r))
    sl, sr = np.where(stale, np.nan, sl), np.where(stale, np.nan, sr)
    n = t.size
    return make_estimate(
        name, {**info, "stale_encoder_steps": int(np.count_nonzero(stale))}, t=t, x=x, y=y, yaw=_wrap(yaw),
        vx=vx, vy=vy, wz=wz, slip_l=sl, slip_r=sr,
        y_l=np.full(n, y_l), y_r=np.full(n, y_r), x_icr=np.full(n, x_icr),
        chi=np.full(n, (y_l - y_r) / geom.track), wl=wl, wr=wr,
    )


@dataclass(frozen=True)
class EnDr:
    """Encoder dead reckoning with the no-slip model ("En-DR" of Liu Figs. 6-20, Table 2):
    A_ICR of eq. (8) at y_l = B/2, y_r = -B/2, x = 0 (Sec. III-A), integrated with (9)."""

    name: ClassVar[str] = "liu2020.en_dr"
    paper: ClassVar[str] = PAPER
    requires: ClassVar[frozenset[str]] = ENCODERS | GNSS_POSE
    start_pose_channels: ClassVar[frozenset[str]] = GNSS_POSE  # read for the first fix only (the start point)

    def calibrate(self, runs: Sequence[Run]) -> "EnDr":
        return self

    def estimate(self, run: Run) -> Estimate:
        _check_channels(run, self.requires, self.name)
        g = geometry(run)
        return _dr_estimate(self.name, run, g, g.track / 2, -g.track / 2, 0.0, {"model": "no-slip"})


@dataclass(frozen=True)
class IcrDr:
    """ICR dead reckoning ("ICR" of Liu Figs. 6-20, Table 2): A_ICR of eq. (8) with constant ICR
    locations, integrated with (9), no GNSS after the start point.

    The ICR locations are given, or fitted by :meth:`calibrate` on calibration runs against the GNSS
    (body velocity from gnss_vx/vy rotated by gnss_yaw, yaw rate from the gyro): the least-squares
    fit of eqs. (6)-(8) (equivalently (2), (3), (5)) over all moving samples."""

    y_l: float | None = None
    y_r: float | None = None
    x_icr: float | None = None
    fit_info: Mapping[str, Any] = field(default_factory=dict, compare=False)

    name: ClassVar[str] = "liu2020.icr"
    paper: ClassVar[str] = PAPER
    requires: ClassVar[frozenset[str]] = ENCODERS | GNSS_POSE
    start_pose_channels: ClassVar[frozenset[str]] = GNSS_POSE  # read for the first fix only (the start point)
    calibration_requires: ClassVar[frozenset[str]] = ENCODERS | GNSS_POSE | GNSS_VEL | frozenset({"imu_gz"})

    def calibrate(self, runs: Sequence[Run]) -> "IcrDr":
        y_l, y_r, x_icr, info = fit_icr(runs)
        return dataclasses.replace(self, y_l=y_l, y_r=y_r, x_icr=x_icr, fit_info=info)

    def estimate(self, run: Run) -> Estimate:
        _check_channels(run, self.requires, self.name)
        if self.y_l is None or self.y_r is None or self.x_icr is None:
            raise NotCalibratedError(f"{self.name}: ICR locations unknown; call calibrate(runs) or pass y_l, y_r, "
                                     "x_icr")
        g = geometry(run)
        if not self.y_l - self.y_r > 0:
            raise ValueError(f"{self.name}: y_l - y_r = {self.y_l - self.y_r!r} must be > 0")
        info = {"y_l": self.y_l, "y_r": self.y_r, "x_icr": self.x_icr, **dict(self.fit_info)}
        return _dr_estimate(self.name, run, g, self.y_l, self.y_r, self.x_icr, info)


def slip_forward(v_l: np.ndarray, v_r: np.ndarray, s_l: float, s_r: float, beta: float, track: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body velocities (v_x, v_y, theta_dot) of the slip model from the tread speeds ``r w_l``, ``r w_r``:
    side ground speeds ``(1 - s_i) r w_i``, their mean and difference over the track B, ``v_y = v_x tan(beta)``."""
    gl, gr = (1.0 - s_l) * np.asarray(v_l, float), (1.0 - s_r) * np.asarray(v_r, float)
    vx = 0.5 * (gl + gr)
    return vx, vx * math.tan(beta), (gr - gl) / track


def _gnss_fit_samples(runs: Sequence[Run], min_speed: float) -> tuple[float, tuple[np.ndarray, ...]]:
    """(track, (v_l, v_r, v_x, v_y, theta_dot)) of the moving GNSS samples of calibration runs: tread speeds
    and gyro interpolated to the GNSS times, GNSS body velocity (world velocity rotated by the GNSS heading);
    a GNSS sample in a gap of the encoders or the gyro (:func:`_within_sampling`) or outside their span is dropped."""
    if not runs:
        raise ValueError("fit: no calibration runs")
    vl, vr, vx, vy, wz, keep = [], [], [], [], [], []
    track = None
    for run in runs:
        _check_channels(run, IcrDr.calibration_requires, IcrDr.name)
        g = geometry(run)
        if track is not None and not math.isclose(g.track, track):
            raise RunError(run.where, "meta.platform.track", g.track, f"calibration runs disagree ({track})")
        track, r = g.track, g.wheel_radius
        gx, gy, gyaw = run["gnss_vx"], run["gnss_vy"], run["gnss_yaw"]
        rows = np.flatnonzero(np.isfinite(gx) & np.isfinite(gy) & np.isfinite(gyaw))
        if rows.size == 0:
            raise RunError(run.where, "gnss_vx/gnss_vy/gnss_yaw", "no joint sample", "needed to fit the model")
        tg = run.t[rows]
        c, s = np.cos(gyaw[rows]), np.sin(gyaw[rows])
        vx.append(c * gx[rows] + s * gy[rows])
        vy.append(-s * gx[rows] + c * gy[rows])
        sampled = np.ones(tg.size, dtype=bool)  # not in an encoder or gyro gap: no interpolation across one
        for name, out, scale in (("enc_wl", vl, r), ("enc_wr", vr, r), ("imu_gz", wz, 1.0)):
            ts, v = run.samples(name)
            sampled &= _within_sampling(ts, tg)
            out.append(scale * np.interp(tg, ts, v))
        keep.append(sampled)
    vl_, vr_, vx_, vy_, wz_ = (np.concatenate(a) for a in (vl, vr, vx, vy, wz))
    moving = (np.maximum(np.abs(vl_), np.abs(vr_)) >= min_speed) & np.concatenate(keep)
    if moving.sum() < 10:
        raise RunError(runs[0].where, "enc_wl/enc_wr", int(moving.sum()), "too few moving samples to fit the model")
    assert track is not None
    return track, tuple(a[moving] for a in (vl_, vr_, vx_, vy_, wz_))


def fit_slip(runs: Sequence[Run], min_speed: float = 0.05, max_slip: float = 20.0
             ) -> tuple[float, float, float, dict]:
    """Constant slip rates (s_l, s_r) and sideslip angle beta of the slip model (:func:`slip_forward`)
    fitted to the GNSS body velocities and gyro yaw rate of calibration runs, with the residuals, loss
    and samples of :func:`fit_icr` (v_x, v_y, ``B/2 theta_dot``; soft-L1); bounds s_i in [-max_slip,
    0.999], |beta| <= 1.5 rad."""
    from scipy.optimize import least_squares

    track, (vl_, vr_, vx_, vy_, wz_) = _gnss_fit_samples(runs, min_speed)
    half = 0.5 * track

    def resid(p: np.ndarray) -> np.ndarray:
        ex, ey, ew = slip_forward(vl_, vr_, p[0], p[1], p[2], track)
        return np.concatenate((ex - vx_, ey - vy_, half * (ew - wz_)))

    sol = least_squares(resid, x0=[0.0, 0.0, 0.0], bounds=([-max_slip, -max_slip, -1.5], [0.999, 0.999, 1.5]),
                        loss="soft_l1", f_scale=0.05, x_scale=[0.1, 0.1, 0.1])
    s_l, s_r, beta = (float(v) for v in sol.x)
    rms = float(np.sqrt(np.mean(resid(sol.x) ** 2)))
    return s_l, s_r, beta, {"fit_samples": int(vl_.size), "fit_rms": rms, "fit_status": int(sol.status)}


@dataclass(frozen=True)
class SlipDr:
    """Dead reckoning with the traditional wheel-slip model (the comparator of Liu's abstract; not one of
    the four estimators of Table 2): constant slip rates and sideslip angle (:func:`slip_forward`),
    fitted by :meth:`calibrate` (:func:`fit_slip`), integrated with (9) from the first GNSS fix."""

    s_l: float | None = None
    s_r: float | None = None
    beta: float | None = None
    fit_info: Mapping[str, Any] = field(default_factory=dict, compare=False)

    name: ClassVar[str] = "liu2020.slip_dr"
    paper: ClassVar[str] = PAPER
    requires: ClassVar[frozenset[str]] = ENCODERS | GNSS_POSE
    start_pose_channels: ClassVar[frozenset[str]] = GNSS_POSE  # read for the first fix only (the start point)
    calibration_requires: ClassVar[frozenset[str]] = ENCODERS | GNSS_POSE | GNSS_VEL | frozenset({"imu_gz"})

    def calibrate(self, runs: Sequence[Run]) -> "SlipDr":
        s_l, s_r, beta, info = fit_slip(runs)
        return dataclasses.replace(self, s_l=s_l, s_r=s_r, beta=beta, fit_info=info)

    def estimate(self, run: Run) -> Estimate:
        _check_channels(run, self.requires, self.name)
        if self.s_l is None or self.s_r is None or self.beta is None:
            raise NotCalibratedError(f"{self.name}: slip parameters unknown; call calibrate(runs) or pass s_l, s_r, "
                                     "beta")
        g = geometry(run)
        t = run.t
        v_l = g.wheel_radius * _interval_speed(run["enc_wl"])
        v_r = g.wheel_radius * _interval_speed(run["enc_wr"])
        vx, vy, wz = slip_forward(v_l, v_r, self.s_l, self.s_r, self.beta, g.track)
        x0, y0, yaw0, _ = _initial_pose(run)
        x, y, yaw = integrate_se2(t, vx, vy, wz, x0, y0, yaw0)
        info = {"s_l": self.s_l, "s_r": self.s_r, "beta": self.beta, **dict(self.fit_info)}
        return make_estimate(self.name, info, t=t, x=x, y=y, yaw=_wrap(yaw), vx=vx, vy=vy, wz=wz)


def fit_icr(runs: Sequence[Run], min_speed: float = 0.05, clamp: float = 20.0) -> tuple[float, float, float, dict]:
    """Constant (y_l, y_r, x_icr) fitted to GNSS body velocities and gyro yaw rate (eqs. (6)-(8)).

    Residuals (m/s): v_x, v_y and ``B/2 * theta_dot``; soft-L1 loss; bounds y_l in (0, clamp],
    y_r in [-clamp, 0), |x| <= clamp (the [-20, 20] of Sec. V-B-3).  The wheel speeds and the yaw rate
    are interpolated to the GNSS times; a GNSS sample in a gap of either (a dropout: more than 1.5
    sample intervals between the samples around it, :func:`_within_sampling`) or outside their span
    is not used."""
    from scipy.optimize import least_squares

    track, (vl_, vr_, vx_, vy_, wz_) = _gnss_fit_samples(runs, min_speed)
    half = 0.5 * track

    def resid(p: np.ndarray) -> np.ndarray:
        ex, ey, ew = icr_forward(vl_, vr_, p[0], p[1], p[2])
        return np.concatenate((ex - vx_, ey - vy_, half * (ew - wz_)))

    sol = least_squares(resid, x0=[half, -half, 0.0], bounds=([1e-3, -clamp, -clamp], [clamp, -1e-3, clamp]),
                        loss="soft_l1", f_scale=0.05, x_scale=[half, half, half])
    y_l, y_r, x_icr = (float(v) for v in sol.x)
    rms = float(np.sqrt(np.mean(resid(sol.x) ** 2)))
    return y_l, y_r, x_icr, {"fit_samples": int(vl_.size), "fit_rms": rms, "fit_status": int(sol.status)}
