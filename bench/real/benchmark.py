"""The real benchmark: kinematic models scored on real DRIVE windows (Clearpath Husky by default).

Protocol (``run_real_benchmark``):

1. Import the DRIVE table as per-window arrays (:func:`bench.real.drive.import_drive_windows`).  A window
   is scored if its measured wheel speeds and its ICP start and end poses are finite.
2. Split the command steps (the repaired step ids of :mod:`bench.real.drive`) into a calibration and a
   test half **by step**: a ``numpy.random.default_rng(seed)`` permutation of the step ids, the
   first ``ceil(n/2)`` steps calibrate, the others test.  All windows of a step go to its half.
3. Fit every model on the calibration windows only (:meth:`WindowModel.fit`).
4. On the test windows, predict each window from its measured wheel speeds (zero-order hold over
   the 20 Hz samples, exact SE(2) integration, ``bench.kinematics.integrate_se2``) starting at the
   window's initial ICP pose, and score the pose at the window's last sample (1.95 s later):
   translation error ``|p_hat - p_icp|`` and yaw error ``|wrap(yaw_hat - yaw_icp)|``; report mean,
   median and 95th percentile, for all, steady and transitory windows.

Models (each a small frozen object with ``fit(calib_windows)`` and ``predict(windows)``; a
:class:`bench.registry.Method` plugin fits in through :class:`PluginModel`):

* :class:`IdealDD`: ideal differential drive with the nominal track (``bench.kinematics.ideal_dd``).
* :class:`SymmetricChi`: symmetric ICR model, ``y_l = -y_r = chi B / 2``, ``x_icr = 0`` (Wang 2015
  eqs. (10)-(11), (15)); constant chi fitted by least squares on the calibration windows' end-pose
  errors (Mandow 2007 eq. (13)).
* :class:`AsymmetricICR`: Mandow 2007's parameterisation ``K = {x_ICRl, x_ICRr, y_ICRv, alpha_r,
  alpha_l}`` (eqs. (6)-(7)) in skidbench axes: ``y_l = -x_ICRl``, ``y_r = -x_ICRr``,
  ``x_icr = y_ICRv`` (Mandow's Y is our x, his X our -y), tread speeds ``alpha_i r w_i``; fitted
  with ``scipy.optimize.least_squares`` on the calibration windows' end poses, minimising Mandow's
  J (eq. (13): squared x, y [m] and yaw [rad] errors, equal weights), in place of his GA.
* :class:`WangChiCurve`: chi as a function of the curvature ratio ``(v_l+v_r)/(v_r-v_l)`` (Wang
  2015 eq. (44), ``chi = 1 + a / (1 + b sqrt|curvature_ratio|)``), evaluated per sample inside the
  symmetric model (eq. (47), whose ``2 B chi`` is a typo for ``2 y0 = chi B``, eq. (15)); ``a, b``
  fitted as Wang does: a nonlinear least-squares curve fit to chi measured per steady turning
  calibration window with eq. (25) (his (42)).
* :class:`YiSGamma`: Yi 2009 kinematics: tread speeds with slip (eqs. (6), (8): a common traction
  slip lambda_0 and constant tread-ICR positions), v_Gx by eq. (13), lateral velocity by eq. (15)
  with the longitudinal ICR S(gamma) of eq. (41), gamma of eq. (40).  S(gamma) is fitted as Yi does
  (Sec. V-B: nonlinear least squares of eq. (41), :func:`methods.yi2009.fit_s_gamma`, on one (gamma, S)
  point per steady turning calibration window measured on the ICP reference); the slip parameters
  on the end poses.  Two rows: ``yi2009_s_gamma`` (psi_dot from the wheel speeds: the ICR family's
  inputs) and ``yi2009_s_gamma_gyro`` (psi_dot = the measured gyro z rate, Yi's IMU yaw rate).  Yi's
  EKF (Sec. IV) cannot run: DRIVE tables lack the roll and pitch gyro rates (:data:`YI_MISSING`).
  Not part of :data:`ICR_FAMILY` (the issue's verdict); the report compares it with the best of it.

Measured chi: per steady window turning at least ``MIN_TURN`` rad, Wang eq. (25)/(42)
``chi = 2 y0 / B = (S_r - S_l) / (phi B)`` with ``S_i = r * sum(w_i dt)`` and ``phi`` the ICP yaw
change over the same samples; tabulated by |curvature ratio| bin beside Wang's published P3-AT
curve (eq. (45): a = 0.4728, b = 0.0538).

Outputs (written atomically: temp file + ``os.replace``): ``<out>/<platform>.md`` (report),
``<platform>.csv`` (error statistics), ``<platform>_chi.csv`` (chi by bin) and three PNG figures.
Files hold no wall-clock data, so the same input gives the same bytes; the runtime is returned.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import io
import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from bench.real.drive import DriveWindows, import_drive_windows, resolve_platform
from bench.kinematics import curvature_ratio, icr_forward, icr_inverse, ideal_dd
from bench.run import Run, from_arrays
from bench.real.windows import (MIN_TURN, Pose, VelocityWindowModel, WindowModel, end_errors, end_residuals,  # noqa: F401
                                fit_end_poses, integrate_windows, predict_from_velocities, tread_speeds,
                                valid_windows, window_chi, window_twist)

CHI_BINS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, math.inf)  # |curvature ratio| bin edges
WANG_P3AT = (0.4728, 0.0538)  # Wang 2015 eq. (45): (a, b) for the Pioneer P3-AT on tile
SUBSETS = ("all", "steady", "transitory")
ICR_FAMILY = ("icr_sym_chi", "mandow2007_icr", "wang2015_chi_curve")



# ------------------------------------------------------------------------------------------
# integration and scoring primitives (vectorised over windows)
# ------------------------------------------------------------------------------------------
def stats(e: np.ndarray) -> dict[str, float]:
    e = np.asarray(e, float)
    if e.size == 0:
        return {"n": 0, "mean": math.nan, "median": math.nan, "p95": math.nan}
    return {"n": int(e.size), "mean": float(np.mean(e)), "median": float(np.median(e)),
            "p95": float(np.percentile(e, 95))}


TESTBED_CHI_SCENARIO = "real_husky_asphalt"  # the gap workflow's nominal husky model (bench.real.gap)


def testbed_chi(platform_name: str, abs_ratios: Sequence[float], tread_speeds: Sequence[float],
                duration: float = 6.0, settle: float = 3.0, seed: int = 0) -> list[float]:
    """The testbed's chi (Wang eq. (25) on its truth, ``bench.sim.validate.chi_eq25``) for steady
    CCW turns at each curvature ratio, outer tread speed as given; the nominal husky model of the gap
    workflow (scenario :data:`TESTBED_CHI_SCENARIO`).  NaN for a platform other than that model's."""
    from bench.sim import simulate
    from bench.sim.validate import chi_eq25
    from bench.spec import CommandSpec, Segment, load_scenario

    base = load_scenario(TESTBED_CHI_SCENARIO)
    if base.platform.name != platform_name:
        return [math.nan] * len(abs_ratios)
    out = []
    for lam, v in zip(abs_ratios, tread_speeds):
        cmd = CommandSpec(kind="v_curvature_ratio", segments=(Segment(duration, float(v), float(lam)),))
        run = simulate(dataclasses.replace(base, command=cmd, duration=duration), seed)
        out.append(chi_eq25(run.data, base.platform, settle))
    return out


def wang_chi(lam: np.ndarray, a: float, b: float) -> np.ndarray:
    """Wang 2015 eq. (44): chi = 1 + a / (1 + b sqrt|curvature_ratio|); 1 on a straight line
    (|ratio| = inf); 1 + a when undefined (both treads stopped, where wz = 0 anyway)."""
    lam = np.asarray(lam, float)
    with np.errstate(invalid="ignore", over="ignore"):
        out = 1.0 + a / (1.0 + b * np.sqrt(np.abs(lam)))
    return np.where(np.isnan(lam), 1.0 + a, out)


# ------------------------------------------------------------------------------------------
# models
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class IdealDD(VelocityWindowModel):
    """Ideal differential drive with the nominal track and wheel radius (nothing to fit)."""

    wheel_radius: float
    track: float
    name: str = "ideal_dd"
    label: str = "ideal differential drive, nominal B"
    fit_cost: float = math.nan

    def fit(self, calib: DriveWindows) -> "IdealDD":
        return self

    def velocities(self, w: DriveWindows) -> Pose:
        return ideal_dd(*tread_speeds(w, self.wheel_radius), self.track)

    def params(self) -> dict[str, float]:
        return {"B": self.track, "r": self.wheel_radius}


@dataclass(frozen=True)
class SymmetricChi(VelocityWindowModel):
    """Symmetric ICR model with constant chi (Wang eqs. (11), (15)); chi fitted on end poses."""

    wheel_radius: float
    track: float
    chi: float = 1.0
    name: str = "icr_sym_chi"
    label: str = "symmetric ICR, constant chi (end-pose LSQ)"
    fit_cost: float = math.nan

    def fit(self, calib: DriveWindows) -> "SymmetricChi":
        return fit_end_poses(self, ["chi"], [1.5], ([0.5], [10.0]), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        half = self.chi * self.track / 2.0
        return icr_forward(*tread_speeds(w, self.wheel_radius), half, -half, 0.0)

    def params(self) -> dict[str, float]:
        return {"chi": self.chi}


@dataclass(frozen=True)
class AsymmetricICR(VelocityWindowModel):
    """Mandow 2007 eqs. (6)-(7) in skidbench axes (module docstring); fitted on end poses."""

    wheel_radius: float
    track: float
    y_l: float = math.nan
    y_r: float = math.nan
    x_icr: float = 0.0
    alpha_l: float = 1.0
    alpha_r: float = 1.0
    name: str = "mandow2007_icr"
    label: str = "asymmetric ICR (Mandow: y_l, y_r, x_icr, alpha_l, alpha_r)"
    fit_cost: float = math.nan

    def fit(self, calib: DriveWindows) -> "AsymmetricICR":
        # start from the symmetric fit (a GA-free, deterministic start for Mandow's search)
        chi0 = SymmetricChi(self.wheel_radius, self.track).fit(calib).chi
        half = chi0 * self.track / 2.0
        names = ["y_l", "y_r", "x_icr", "alpha_l", "alpha_r"]
        lo = [0.05, -5.0, -2.0, 0.3, 0.3]
        hi = [5.0, -0.05, 2.0, 3.0, 3.0]
        return fit_end_poses(self, names, [half, -half, 0.0, 1.0, 1.0], (lo, hi), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        v_l, v_r = tread_speeds(w, self.wheel_radius)
        return icr_forward(self.alpha_l * v_l, self.alpha_r * v_r, self.y_l, self.y_r, self.x_icr)

    def params(self) -> dict[str, float]:
        return {"y_l": self.y_l, "y_r": self.y_r, "x_icr": self.x_icr, "alpha_l": self.alpha_l,
                "alpha_r": self.alpha_r, "chi": (self.y_l - self.y_r) / self.track}


@dataclass(frozen=True)
class WangChiCurve(VelocityWindowModel):
    """Wang 2015 eq. (44) chi(curvature ratio) in the symmetric model (eq. (47), corrected)."""

    wheel_radius: float
    track: float
    a: float = WANG_P3AT[0]
    b: float = WANG_P3AT[1]
    min_turn: float = MIN_TURN
    name: str = "wang2015_chi_curve"
    label: str = "chi(curvature ratio), Wang eq. (44) fitted to measured chi"
    fit_cost: float = math.nan
    n_fit: int = 0

    def fit(self, calib: DriveWindows) -> "WangChiCurve":
        chi, lam, _, usable = window_chi(calib, self.wheel_radius, self.track, self.min_turn)
        chi, lam = chi[usable], lam[usable]
        if chi.size < 2:
            return dataclasses.replace(self, n_fit=int(chi.size))
        sol = least_squares(lambda p: wang_chi(lam, p[0], p[1]) - chi, np.array(WANG_P3AT),
                            bounds=([0.0, 0.0], [np.inf, np.inf]), method="trf")
        return dataclasses.replace(self, a=float(sol.x[0]), b=float(sol.x[1]),
                                   fit_cost=float(2 * sol.cost / chi.size), n_fit=int(chi.size))

    def velocities(self, w: DriveWindows) -> Pose:
        v_l, v_r = tread_speeds(w, self.wheel_radius)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = curvature_ratio(v_l, v_r)
        half = wang_chi(lam, self.a, self.b) * self.track / 2.0
        return icr_forward(v_l, v_r, half, -half, 0.0)

    def params(self) -> dict[str, float]:
        return {"a": self.a, "b": self.b, "chi(0)": 1.0 + self.a}


def yi_s_points(w: DriveWindows, track: float, min_turn: float = MIN_TURN
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Yi 2009 Sec. V-B data points (gamma, S [m]) per window, from the reference (as Yi does with
    his vision system): S = -v_Gy / psi_dot (eq. (7)) and gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx)
    (eq. (40)) with v_Lx, v_Rx = v_Gx -+ W psi_dot / 2 (eqs. (3)-(4)), i.e. gamma = -W phi / (2 u),
    for the window's constant twist (:func:`window_twist`).  Returns (gamma, S, usable); usable =
    steady, turning at least ``min_turn`` rad, both finite."""
    u, v, phi = window_twist(w)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -v / phi
        gam = -track * phi / (2.0 * u)
    usable = w.steady & (np.abs(phi) >= min_turn) & np.isfinite(s) & np.isfinite(gam)
    return gam, s, usable


def s_of_gamma(gamma: np.ndarray, a1: float, a2: float, a3: float) -> np.ndarray:
    """Yi eq. (41) S = a1 / (a2 |gamma| + a3), with its limits: S -> 0 for |gamma| -> inf (a2 > 0),
    S = a1/a3 where gamma is undefined (0/0: wheels stopped, where psi_dot = 0 and S is not used)."""
    g = np.abs(np.asarray(gamma, float))
    with np.errstate(invalid="ignore", over="ignore"):
        s = a1 / (a2 * np.where(np.isfinite(g), g, 0.0) + a3)
    s = np.where(np.isinf(g), 0.0 if a2 > 0 else a1 / a3, s)
    return np.where(np.isnan(g), a1 / a3, s)


MIN_S_POINTS_PER_DIRECTION = 10  # S(gamma) points per travel direction needed to fit x_M as well


@dataclass(frozen=True)
class YiSGamma(VelocityWindowModel):
    """Yi 2009 kinematics (Sec. III-A, III-C, V-B) as a window model (Yi's EKF itself cannot run on
    DRIVE data: it needs the roll and pitch gyro rates, absent there; see :data:`YI_MISSING`).

    * Treads: wheel-centre speeds with slip, eq. (6) ``v_ix = (1 - lambda_i) r w_i``, where the slip
      is a common traction slip ``slip`` (lambda_0, both sides) plus the turning slip of eq. (8),
      ``Delta v_Lx = (y_lc - W/2) psi_dot``, ``Delta v_Rx = (y_rc + W/2) psi_dot`` with constant
      lateral tread-ICR positions ``y_l``, ``y_r`` (eq. (9a)).
    * ``yaw_rate="wheels"``: psi_dot and v_Gx from eqs. (3)-(4) closed with those speeds:
      ``psi_dot = (1-lambda_0) r (w_R - w_L) / (y_l - y_r)``, ``v_Gx`` = mean tread speed (eq. (13)
      with x_M = y_M = 0) -- inputs: wheel speeds only.
    * ``yaw_rate="gyro"``: psi_dot is the measured gyro z rate (``imu_gz``; eq. (10e) with roll and
      pitch taken as 0: they are not measured), the turning slips are symmetric (y_l = -y_r, eq. (8)),
      so eq. (13) gives ``v_Gx = (1-lambda_0) r (w_L + w_R)/2`` -- inputs: wheel speeds + gyro.
    * Lateral: eq. (15) ``v_By = (x_M - S) psi_dot`` with S(gamma) of eq. (41), gamma of eq. (40) from
      the model's tread speeds: ``gamma = -W psi_dot / (2 v_Gx)``.  Yi's runs are all forward; the
      ICR's longitudinal offset S is the slip's response to the centripetal load and reverses with the
      direction of travel, so here ``S = sign(v_Gx) S(|gamma|)``.  ``x_M`` (eq. (15): the
      longitudinal position of the measured point, here the ICP frame's origin) is fitted when the
      calibration windows drive both ways (otherwise 0, as for Yi's IMU at the centre).

    Fitting (calibration windows only): S(gamma) as Yi does (Sec. V-B): eq. (41) fitted by nonlinear
    least squares (:func:`methods.yi2009.fit_s_gamma`, a3 held at the published 0.039, only a1/a3
    and a2/a3 being identifiable) to one (gamma, S) point per steady turning window measured on the
    reference (:func:`yi_s_points`); then the slip parameters by least squares on Mandow's J over the
    windows' end poses (like the other models), S(gamma) held.  The sign rule (14) is not imposed:
    it follows from eq. (8) for forward driving when y_l >= W/2 >= -y_r and would be wrong for a
    wheel turning backwards, which the DRIVE steps contain.
    """

    wheel_radius: float
    track: float
    yaw_rate: str = "wheels"
    slip: float = 0.0
    y_l: float = math.nan
    y_r: float = math.nan
    a1: float = 0.02148  # published S(gamma), Sec. V-B (a1 = 2.148 cm)
    a2: float = 0.249
    a3: float = 0.039
    x_m: float = 0.0  # eq. (15) x_M [m]
    min_turn: float = MIN_TURN
    name: str = "yi2009_s_gamma"
    label: str = "Yi S(gamma) (eqs. (6), (8), (13), (15), (40), (41)); wheel speeds"
    fit_cost: float = math.nan
    n_fit: int = 0
    s_fit_rms: float = math.nan

    def __post_init__(self) -> None:
        if self.yaw_rate not in ("wheels", "gyro"):
            raise ValueError(f"YiSGamma.yaw_rate = {self.yaw_rate!r}: 'wheels' or 'gyro'")

    @classmethod
    def gyro(cls, wheel_radius: float, track: float, **kw: Any) -> "YiSGamma":
        return cls(wheel_radius, track, yaw_rate="gyro", name="yi2009_s_gamma_gyro",
                   label="Yi S(gamma) (eqs. (6), (13), (15), (40), (41)); wheel speeds + gyro yaw rate", **kw)

    def _s_fit(self, calib: DriveWindows) -> "YiSGamma":
        from methods.yi2009 import fit_s_gamma

        gam, s, usable = yi_s_points(calib, self.track, self.min_turn)
        if np.unique(np.abs(gam[usable])).size < 2:
            return dataclasses.replace(self, n_fit=int(usable.sum()))  # too few points: published curve kept
        u = window_twist(calib)[0]
        fwd = usable & (u > 0)
        bwd = usable & (u < 0)
        if min(fwd.sum(), bwd.sum()) < MIN_S_POINTS_PER_DIRECTION:  # one direction (Yi's case): x_M = 0
            fit = fit_s_gamma(gam[usable], s[usable] * np.sign(u[usable]), a3=self.a3)  # (41) uses |gamma|
            sg = fit.s_gamma
            return dataclasses.replace(self, a1=sg.a1, a2=sg.a2, a3=sg.a3, x_m=0.0, n_fit=fit.n_points,
                                       s_fit_rms=fit.residual_rms)
        # both directions: the measured -v_By/psi_dot = sign(u) S(|gamma|) - x_M (eq. (15)), a3 held
        g, sg_, sm = np.abs(gam[usable]), np.sign(u[usable]), s[usable]
        start = fit_s_gamma(gam[fwd], s[fwd], a3=self.a3).s_gamma

        def resid(q: np.ndarray) -> np.ndarray:
            return sg_ * q[1] / (q[2] * g + self.a3) - q[0] - sm

        lo, hi = np.array([-5.0, -5.0, 0.0]), np.array([5.0, 5.0, 1e3])
        q0 = np.clip([0.0, start.a1, start.a2], lo + 1e-9, hi - 1e-9)
        sol = least_squares(resid, q0, bounds=(lo, hi))
        r = resid(sol.x)
        return dataclasses.replace(self, x_m=float(sol.x[0]), a1=float(sol.x[1]), a2=float(sol.x[2]),
                                   n_fit=int(usable.sum()), s_fit_rms=float(np.sqrt(np.mean(r * r))))

    def fit(self, calib: DriveWindows) -> "YiSGamma":
        m = self._s_fit(calib)
        if self.yaw_rate == "gyro":
            return fit_end_poses(m, ["slip"], [0.0], ([-0.9], [0.9]), calib)
        chi0 = SymmetricChi(self.wheel_radius, self.track).fit(calib).chi
        half = chi0 * self.track / 2.0
        return fit_end_poses(m, ["slip", "y_l", "y_r"], [0.0, half, -half],
                              ([-0.9, 0.05, -5.0], [0.9, 5.0, -0.05]), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        v_l, v_r = tread_speeds(w, self.wheel_radius)
        k = 1.0 - self.slip
        if self.yaw_rate == "gyro":
            wz = np.asarray(w["imu_gz"], float)
            vx = k * (v_l + v_r) / 2.0
        else:
            vx, _, wz = icr_forward(k * v_l, k * v_r, self.y_l, self.y_r, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            gam = -self.track * wz / (2.0 * vx)
        return vx, (self.x_m - np.sign(vx) * s_of_gamma(gam, self.a1, self.a2, self.a3)) * wz, wz

    def params(self) -> dict[str, float]:
        out = {"lambda_0": self.slip}
        if self.yaw_rate == "wheels":
            out.update({"y_lc": self.y_l, "y_rc": self.y_r, "chi": (self.y_l - self.y_r) / self.track})
        out.update({"a1_cm": 100.0 * self.a1, "a2": self.a2, "a3": self.a3, "S(0)": self.a1 / self.a3, "x_M": self.x_m,
                    "n_S_points": float(self.n_fit), "S_fit_rms": self.s_fit_rms})
        return out


#: inputs of Yi's full method (the EKF of Sec. IV) that a DRIVE table lacks
YI_MISSING = ("roll and pitch gyro rates (imu_gx, imu_gy: eqs. (10c)-(10e) and the EKF of Sec. IV-A)",)


def window_runs(w: DriveWindows, platform: Mapping[str, Any] | None = None, with_reference: bool = True
                ) -> list[Run]:
    """One Run per window (t from 0), for plugins written against :class:`bench.run.Run`."""
    runs = []
    names = [c for c in w.channels if with_reference or not c.startswith("ref_")]
    stem = Path(w.source).stem
    for i in range(w.n_windows):
        cols = {"t": w.t, **{c: w.channels[c][i] for c in names}}
        runs.append(from_arrays(cols, {"run_id": f"{stem}:row{int(w.row[i])}", "source_file": w.source,
                                       "platform": dict(platform or {}), "calib_step": int(w.calib_step[i])}))
    return runs


@dataclass(frozen=True)
class PluginModel:
    """Adapter: a :class:`bench.registry.Method` plugin as a :class:`WindowModel`.

    ``fit`` calibrates the method on one Run per calibration window (reference included, as the
    papers' identification reads it); ``predict`` runs ``estimate`` on each window with the
    reference withheld, takes the estimated pose at the window's samples, and re-bases it on the
    window's initial ICP pose (the estimate's own start pose is not trusted).  Loops over windows.
    """

    method: Any
    platform: Mapping[str, Any] = field(default_factory=dict)
    name: str = ""
    label: str = ""
    fit_cost: float = math.nan

    def __post_init__(self) -> None:
        if not self.name:
            object.__setattr__(self, "name", str(getattr(self.method, "name", type(self.method).__name__)))
        if not self.label:
            object.__setattr__(self, "label", f"plugin {self.name}")

    def fit(self, calib: DriveWindows) -> "PluginModel":
        return dataclasses.replace(self, method=self.method.calibrate(window_runs(calib, self.platform)))

    def predict(self, windows: DriveWindows) -> Pose:
        n, m = windows.n_windows, windows.n_samples
        out = [np.empty((n, m)) for _ in range(3)]
        for i, run in enumerate(window_runs(windows, self.platform, with_reference=False)):
            est = self.method.estimate(run)
            xe, ye, he = (np.interp(windows.t, est.t, est[c]) for c in ("x", "y", "yaw"))
            c0, s0 = np.cos(he[0]), np.sin(he[0])
            dx, dy = xe - xe[0], ye - ye[0]
            xr, yr = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
            x0, y0, h0 = (windows[c][i, 0] for c in ("ref_x", "ref_y", "ref_yaw"))
            out[0][i] = x0 + np.cos(h0) * xr - np.sin(h0) * yr
            out[1][i] = y0 + np.sin(h0) * xr + np.cos(h0) * yr
            out[2][i] = h0 + np.unwrap(he) - he[0]
        return out[0], out[1], out[2]

    def params(self) -> dict[str, float]:
        return {}


def default_models(wheel_radius: float, track: float) -> list[WindowModel]:
    return [IdealDD(wheel_radius, track), SymmetricChi(wheel_radius, track),
            AsymmetricICR(wheel_radius, track), WangChiCurve(wheel_radius, track),
            YiSGamma(wheel_radius, track), YiSGamma.gyro(wheel_radius, track)]


# ------------------------------------------------------------------------------------------
# split and evaluation
# ------------------------------------------------------------------------------------------
def split_steps(w: DriveWindows, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(calibration steps, test steps): a seeded permutation of the step ids, first ceil(n/2) calibrate."""
    steps = np.unique(w.calib_step)
    perm = np.random.default_rng(seed).permutation(steps)
    k = (steps.size + 1) // 2
    return np.sort(perm[:k]), np.sort(perm[k:])


def evaluate(model: WindowModel, w: DriveWindows) -> dict[str, Any]:
    """Per-window end errors and their statistics for all, steady and transitory windows."""
    et, ey = end_errors(model.predict(w), w)
    masks = {"all": np.ones(w.n_windows, bool), "steady": w.steady, "transitory": w.transitory}
    return {
        "trans": et, "yaw": ey,
        "stats": {s: {"trans": stats(et[mk]), "yaw": stats(ey[mk])} for s, mk in masks.items()},
    }


def chi_by_bin(chi: np.ndarray, lam: np.ndarray, edges: Sequence[float] = CHI_BINS) -> list[dict[str, float]]:
    """Measured chi per |curvature ratio| bin: n, median, quartiles, median |ratio|, Wang P3-AT chi."""
    rows = []
    a = np.abs(lam)
    for lo, hi in zip(edges[:-1], edges[1:]):
        s = (a >= lo) & (a < hi)
        c = chi[s]
        med_l = float(np.median(a[s])) if s.any() else math.nan
        rows.append({
            "lo": float(lo), "hi": float(hi), "n": int(s.sum()),
            "median": float(np.median(c)) if c.size else math.nan,
            "q25": float(np.percentile(c, 25)) if c.size else math.nan,
            "q75": float(np.percentile(c, 75)) if c.size else math.nan,
            "median_abs_ratio": med_l,
            "wang_p3at": float(wang_chi(np.array(med_l), *WANG_P3AT)) if s.any() else math.nan,
        })
    return rows


# ------------------------------------------------------------------------------------------
# atomic outputs
# ------------------------------------------------------------------------------------------
def _atomic_write_bytes(path: Path, data: bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; results are shared files
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def _atomic_write_text(path: Path, text: str) -> Path:
    return _atomic_write_bytes(path, text.encode("utf-8"))


def _save_figure(fig: Any, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    return _atomic_write_bytes(path, buf.getvalue())


def _new_figure(w: float, h: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)  # Agg canvas, no pyplot global state
    return fig


# ------------------------------------------------------------------------------------------
# the benchmark
# ------------------------------------------------------------------------------------------
def _fmt(v: float, nd: int = 3) -> str:
    return "n/a" if v is None or not np.isfinite(v) else f"{v:.{nd}f}"


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(y)
    return float(np.polyfit(x[ok], y[ok], 1)[0]) if ok.sum() >= 2 else math.nan


def run_real_benchmark(data_path: str | Path, out_dir: str | Path, seed: int = 0,
                       platform: str | Mapping[str, Any] | None = "husky",
                       wheel_radius: float | None = None, track: float | None = None,
                       models: Sequence[WindowModel] | None = None, figures: bool = True) -> dict[str, Any]:
    """Run the real benchmark (module docstring) and write the report; returns the numbers.

    ``platform`` names the platform spec (default ``husky``); ``wheel_radius``/``track`` override it.
    """
    t_start = time.perf_counter()
    data_path, out_dir = Path(data_path), Path(out_dir)
    plat = resolve_platform(platform, wheel_radius, track)
    r, B = float(plat["wheel_radius"]), float(plat["track"])
    name = str(plat.get("name") or data_path.stem)
    if name == "unspecified":
        name = data_path.stem
    allw = import_drive_windows(data_path)
    ok = valid_windows(allw)
    w = allw.subset(ok)
    calib_steps, test_steps = split_steps(w, seed)
    calib = w.subset(np.isin(w.calib_step, calib_steps))
    test = w.subset(np.isin(w.calib_step, test_steps))
    fitted = [m.fit(calib) for m in (models if models is not None else default_models(r, B))]
    results = {m.name: evaluate(m, test) for m in fitted}

    # measured chi (all usable steady windows) and two independent checks of the time base
    chi, lam, phi, usable = window_chi(w, r, B)
    bins = chi_by_bin(chi[usable], lam[usable])
    # the testbed's chi beside it: same |curvature ratio| (bin median) and outer tread speed (bin median)
    vl, vr = tread_speeds(w, r)
    outer = np.max(np.abs(np.column_stack((vl.mean(axis=1), vr.mean(axis=1)))), axis=1)[usable]
    a_lam = np.abs(lam[usable])
    full = [b for b in bins if b["n"] > 0]
    speeds = [float(np.clip(np.median(outer[(a_lam >= b["lo"]) & (a_lam < b["hi"])]), 0.1, 1.5)) for b in full]
    for b, c, v in zip(full, testbed_chi(name, [b["median_abs_ratio"] for b in full], speeds), speeds):
        b["testbed"], b["testbed_speed"] = c, v
    for b in bins:
        b.setdefault("testbed", math.nan)
        b.setdefault("testbed_speed", math.nan)
    rate_icp = phi / (w.dt * (w.n_samples - 1))
    checks: dict[str, float] = {}
    if w.has("imu_gz"):
        checks["gyro_vs_icp_rate_slope"] = _slope(rate_icp, np.mean(w["imu_gz"][:, :-1], axis=1))
    if "icp_omega" in w.body_velocity:
        om = w.body_velocity["icp_omega"]
        checks["drive_icp_omega_vs_icp_rate_slope"] = _slope(rate_icp, om)
        v_l, v_r = (r * np.mean(w[c], axis=1) for c in ("enc_wl", "enc_wr"))
        y_l, y_r, _ = icr_inverse(v_l, v_r, w.body_velocity.get("icp_vx", np.zeros_like(om)),
                                  w.body_velocity.get("icp_vy", np.zeros_like(om)), om, min_wz=MIN_TURN)
        chi_om = (y_l - y_r) / B
        ok_om = w.steady & np.isfinite(chi_om)
        checks["chi_from_drive_icp_omega_median"] = float(np.median(chi_om[ok_om])) if ok_om.any() else math.nan
        checks["chi_from_drive_icp_omega_n"] = int(ok_om.sum())

    ideal = results["ideal_dd"]["stats"]["all"]["trans"]["median"] if "ideal_dd" in results else math.nan
    family = {k: results[k]["stats"]["all"]["trans"]["median"] for k in ICR_FAMILY if k in results}
    best = min(family, key=family.get) if family else None
    verdict = {
        "ideal_dd_median_trans": ideal,
        "best_icr_model": best,
        "best_icr_median_trans": family.get(best, math.nan) if best else math.nan,
        "passed": bool(best is not None and family[best] < ideal),
    }
    out = {
        "platform": name, "wheel_radius": r, "track": B, "seed": int(seed),
        "data_file": data_path.name, "data_sha256": hashlib.sha256(data_path.read_bytes()).hexdigest(),
        "n_windows": allw.n_windows, "n_excluded": int((~ok).sum()),
        "calib_steps": calib_steps.tolist(), "test_steps": test_steps.tolist(),
        "n_calib_windows": calib.n_windows, "n_test_windows": test.n_windows,
        "n_test_steady": int(test.steady.sum()), "n_test_transitory": int(test.transitory.sum()),
        "models": {m.name: {"label": m.label, "params": m.params(), "fit_cost": getattr(m, "fit_cost", math.nan),
                            "stats": results[m.name]["stats"]} for m in fitted},
        "chi": {"n": int(usable.sum()), "median": float(np.median(chi[usable])) if usable.any() else math.nan,
                "q25": float(np.percentile(chi[usable], 25)) if usable.any() else math.nan,
                "q75": float(np.percentile(chi[usable], 75)) if usable.any() else math.nan,
                "bins": bins, "min_turn": MIN_TURN},
        "checks": checks,
        "import": {"relabelled_windows": int((allw.calib_step != allw.calib_step_label).sum()),
                   "shared_sample_boundaries": {int(k): int(v) for k, v in
                                                zip(*np.unique(allw.overlap[1:], return_counts=True))}},
        "verdict": verdict,
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [_write_csv(out, out_dir / f"{name}.csv"), _write_chi_csv(out, out_dir / f"{name}_chi.csv")]
    if figures:
        files += _figures(out, fitted, results, test, chi[usable], lam[usable], out_dir, name)
    files.append(_atomic_write_text(out_dir / f"{name}.md", _report(out, figures, name)))
    out["files"] = [str(p) for p in files]
    out["runtime_s"] = time.perf_counter() - t_start
    return out


def _write_csv(out: Mapping[str, Any], path: Path) -> Path:
    lines = ["model,subset,error,unit,n,mean,median,p95"]
    for mname, m in out["models"].items():
        for s in SUBSETS:
            for e, unit in (("trans", "m"), ("yaw", "rad")):
                st = m["stats"][s][e]
                lines.append(f"{mname},{s},{e},{unit},{st['n']},{st['mean']:.6f},{st['median']:.6f},{st['p95']:.6f}")
    return _atomic_write_text(path, "\n".join(lines) + "\n")


def _write_chi_csv(out: Mapping[str, Any], path: Path) -> Path:
    lines = ["abs_ratio_lo,abs_ratio_hi,n,chi_median,chi_q25,chi_q75,median_abs_ratio,wang_p3at_chi,testbed_chi,"
             "testbed_tread_speed"]
    for b in out["chi"]["bins"]:
        lines.append(",".join(f"{b[k]:.6f}" if isinstance(b[k], float) else str(b[k])
                              for k in ("lo", "hi", "n", "median", "q25", "q75", "median_abs_ratio", "wang_p3at",
                                        "testbed", "testbed_speed")))
    return _atomic_write_text(path, "\n".join(lines) + "\n")


def _figures(out: Mapping[str, Any], fitted: Sequence[WindowModel], results: Mapping[str, Any],
             test: DriveWindows, chi: np.ndarray, lam: np.ndarray, out_dir: Path, name: str) -> list[Path]:
    files = []
    # 1. chi versus |curvature ratio|
    fig = _new_figure(6.4, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    a = np.abs(lam)
    ax.scatter(a, chi, s=8, alpha=0.35, color="0.4", label=f"{name}: steady windows, eq. (25)")
    bins = [b for b in out["chi"]["bins"] if b["n"] > 0]
    mx = np.array([b["median_abs_ratio"] for b in bins])
    ax.errorbar(mx, [b["median"] for b in bins],
                yerr=[[b["median"] - b["q25"] for b in bins], [b["q75"] - b["median"] for b in bins]],
                fmt="o-", color="C0", capsize=3, label=f"{name}: bin median, IQR")
    grid = np.linspace(0, max(10.0, float(np.percentile(a, 99)) if a.size else 10.0), 300)
    ax.plot(grid, wang_chi(grid, *WANG_P3AT), "C3--", label="Wang 2015 eq. (45), P3-AT (published)")
    for m in fitted:
        if isinstance(m, WangChiCurve):
            ax.plot(grid, wang_chi(grid, m.a, m.b), "C2-",
                    label=f"eq. (44) fitted on calib. half (a={m.a:.3f}, b={m.b:.3f})")
        if isinstance(m, SymmetricChi):
            ax.axhline(m.chi, color="C1", ls=":", label=f"constant chi, end-pose fit ({m.chi:.3f})")
    ax.set_xlabel("|curvature ratio| = |(v_l + v_r) / (v_r - v_l)|")
    ax.set_ylabel("chi = (y_l - y_r) / B")
    ax.set_xlim(0, grid[-1])
    lo = float(np.nanpercentile(chi, 1)) if chi.size else 1.0
    hi = float(np.nanpercentile(chi, 99)) if chi.size else 3.0
    ax.set_ylim(min(1.0, lo) - 0.1, max(1.6, hi) + 0.1)
    ax.legend(fontsize=7)
    ax.set_title(f"ICR coefficient vs curvature ratio ({name})", fontsize=9)
    fig.tight_layout()
    files.append(_save_figure(fig, out_dir / f"{name}_chi.png"))

    # 2. CDF of end translation errors per model, steady vs transitory
    fig = _new_figure(8.0, 3.6)
    for k, (sub, mask) in enumerate((("steady", test.steady), ("transitory", test.transitory))):
        ax = fig.add_subplot(1, 2, k + 1)
        for i, m in enumerate(fitted):
            e = np.sort(results[m.name]["trans"][mask])
            ax.step(e, np.arange(1, e.size + 1) / max(e.size, 1), where="post", color=f"C{i}", label=m.name)
        ax.set_xlabel("translation error at window end [m]")
        ax.set_ylabel("fraction of test windows")
        ax.set_title(f"{sub} test windows (n={int(mask.sum())})", fontsize=9)
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    fig.tight_layout()
    files.append(_save_figure(fig, out_dir / f"{name}_errors.png"))

    # 3. example test windows: ICP vs models (quantiles of the ideal-DD error)
    preds = {m.name: m.predict(test) for m in fitted}
    e0 = results[fitted[0].name]["trans"]
    order = np.argsort(e0, kind="stable")
    picks = order[np.unique(np.round(np.linspace(0.1, 0.9, 6) * (order.size - 1)).astype(int))] if order.size else []
    fig = _new_figure(9.0, 5.6)
    for k, i in enumerate(picks):
        ax = fig.add_subplot(2, 3, k + 1)
        ax.plot(test["ref_x"][i], test["ref_y"][i], "k.-", ms=3, lw=1, label="ICP")
        for j, m in enumerate(fitted):
            px, py, _ = preds[m.name]
            ax.plot(px[i], py[i], color=f"C{j}", lw=1, label=m.name)
        ax.set_aspect("equal", adjustable="datalim")
        kind = "steady" if test.steady[i] else "transitory"
        ax.set_title(f"step {int(test.calib_step[i])} win {int(test.window[i])} ({kind})", fontsize=8)
        ax.tick_params(labelsize=7)
        if k == 0:
            ax.legend(fontsize=6)
    fig.tight_layout()
    files.append(_save_figure(fig, out_dir / f"{name}_examples.png"))
    return files


def _report(out: Mapping[str, Any], figures: bool, name: str) -> str:
    L: list[str] = []
    add = L.append
    v = out["verdict"]
    add(f"# Real benchmark: {name} (DRIVE windows)\n")
    add("Generated by `bench.real.run_real_benchmark` (`skidbench reproduce real`). Kinematic models predict each "
        "2 s window of a real robot from its measured wheel speeds and its initial ICP pose; the error is taken at "
        "the window's last sample (1.95 s after the first).\n")
    add("## Data and split\n")
    add(f"- Table: `{out['data_file']}` (sha256 `{out['data_sha256'][:16]}...`), {out['n_windows']} windows of "
        f"2 s at 20 Hz, {len(out['calib_steps']) + len(out['test_steps'])} command steps; "
        f"{out['n_excluded']} windows excluded (non-finite wheel speeds or ICP start/end pose).")
    add(f"- Platform `{name}`: wheel radius r = {out['wheel_radius']} m, track B = {out['track']} m.")
    add(f"- Split by command step, seed {out['seed']}: `numpy.random.default_rng(seed).permutation(steps)`, first "
        f"half calibrates. Calibration: {len(out['calib_steps'])} steps, {out['n_calib_windows']} windows. "
        f"Test: {len(out['test_steps'])} steps, {out['n_test_windows']} windows "
        f"({out['n_test_steady']} steady, {out['n_test_transitory']} transitory).\n")
    add("## Fitted models (calibration half)\n")
    add("| model | description | parameters |")
    add("|---|---|---|")
    for mname, m in out["models"].items():
        ps = ", ".join(f"{k} = {_fmt(val, 4)}" for k, val in m["params"].items()) or "-"
        add(f"| `{mname}` | {m['label']} | {ps} |")
    add("")
    for err, unit, title in (("trans", "m", "Translation error at window end"),
                             ("yaw", "rad", "Yaw error at window end")):
        add(f"## {title} [{unit}], test half\n")
        add("| model | all: mean | all: median | all: p95 | steady: mean | steady: median | steady: p95 | "
            "transitory: mean | transitory: median | transitory: p95 |")
        add("|---|" + "---:|" * 9)
        for mname, m in out["models"].items():
            cells = [_fmt(m["stats"][s][err][q]) for s in SUBSETS for q in ("mean", "median", "p95")]
            add(f"| `{mname}` | " + " | ".join(cells) + " |")
        add("")
    add("## Verdict\n")
    ideal, best, bm = v["ideal_dd_median_trans"], v["best_icr_model"], v["best_icr_median_trans"]
    if v["passed"]:
        add(f"The best calibrated ICR-family model, `{best}`, has a lower median 2 s translation error on the test "
            f"half than ideal differential drive with the nominal track: **{_fmt(bm)} m vs {_fmt(ideal)} m** "
            f"({100 * (1 - bm / ideal):.0f} % lower).\n")
    else:
        add(f"**Not met**: the best calibrated ICR-family model, `{best}`, has a median 2 s translation error of "
            f"{_fmt(bm)} m on the test half, not below ideal differential drive ({_fmt(ideal)} m). See the example "
            f"windows and the chi figure for why.\n")
    yi = _yi_sentences(out)
    if yi:
        add("## Yi 2009 S(gamma) kinematics\n")
        L.extend(yi)
        add("")
    notes = _reading(out)
    if notes:
        add("## Reading the fitted parameters\n")
        L.extend(notes)
        add("")
    c = out["chi"]
    add(f"## Measured chi versus curvature ratio (all steady windows turning >= {c['min_turn']} rad)\n")
    add(f"chi = (S_r - S_l) / (phi B) per window (Wang 2015 eq. (25)/(42); S_i = r * sum(w_i dt), phi = ICP yaw "
        f"change over the same samples). {c['n']} windows: median {_fmt(c['median'])}, interquartile "
        f"{_fmt(c['q25'])}-{_fmt(c['q75'])}. Wang's P3-AT curve (eq. (45), published: a = 0.4728, b = 0.0538) is "
        "evaluated at each bin's median |ratio|. The testbed column is the testbed's own chi for this platform "
        f"(scenario `{TESTBED_CHI_SCENARIO}`: asphalt, the gap workflow's nominal model): a steady CCW turn at the "
        "bin's median |ratio| and median outer tread speed, Wang eq. (25) on the testbed's truth after 3 s.\n")
    add("| abs(curvature ratio) bin | n | chi median | chi IQR | median abs(ratio) | testbed (outer tread speed) | "
        "Wang P3-AT eq. (45) |")
    add("|---|---:|---:|---|---:|---:|---:|")
    for b in c["bins"]:
        hi = "inf" if not np.isfinite(b["hi"]) else f"{b['hi']:g}"
        tb = f"{_fmt(b['testbed'])} ({_fmt(b['testbed_speed'], 2)} m/s)" if np.isfinite(b["testbed"]) else "n/a"
        add(f"| [{b['lo']:g}, {hi}) | {b['n']} | {_fmt(b['median'])} | {_fmt(b['q25'])}-{_fmt(b['q75'])} | "
            f"{_fmt(b['median_abs_ratio'], 2)} | {tb} | {_fmt(b['wang_p3at'])} |")
    add("")
    tb_bins = [b for b in c["bins"] if b["n"] > 0 and np.isfinite(b["testbed"])]
    if len(tb_bins) >= 2:
        lo, hi = tb_bins[0], tb_bins[-1]
        level = np.median([b["testbed"] / b["median"] for b in tb_bins])
        add(f"From the first to the last bin the measured chi goes {_fmt(lo['median'])} -> {_fmt(hi['median'])} and "
            f"the testbed's {_fmt(lo['testbed'])} -> {_fmt(hi['testbed'])}; the testbed's level is "
            f"{100 * abs(1 - level):.0f} % {'below' if level < 1 else 'above'} the measured one (median over bins of "
            "testbed / measured).\n")
    if figures:
        add(f"Figures: [`{name}_chi.png`]({name}_chi.png) (chi vs curvature ratio), "
            f"[`{name}_errors.png`]({name}_errors.png) (error CDFs, steady and transitory), "
            f"[`{name}_examples.png`]({name}_examples.png) (six test windows at the 10-90 % quantiles of the "
            "ideal-DD error: ICP vs each model).\n")
    add("## Data notes (measured while importing; see `bench/real/drive.py`)\n")
    imp, ck = out["import"], out["checks"]
    shared = ", ".join(f"{n} share {k}" for k, n in sorted(imp["shared_sample_boundaries"].items()) if k > 0)
    add(f"- {imp['relabelled_windows']} transitory windows carry the previous step's `calib_step` label (their first "
        "sample precedes the command change); steps are regrouped structurally (transitory window + its steady "
        "windows).")
    add(f"- Adjacent windows are consecutive blocks of the 20 Hz log; at some boundaries they share samples "
        f"({shared} sample(s)); a Run keeps a shared sample once.")
    add("- ICP poses are in per-window frames rotated by the mean of the first 5 samples' yaw while `icp_yaw` is "
        "relative to the first sample: the initial heading in the frame is `-mean(icp_yaw_0..4)`, used as the start "
        "pose of every prediction.")
    if "gyro_vs_icp_rate_slope" in ck:
        add(f"- `imu_yaw` is a yaw *rate*: its window mean follows the ICP yaw rate with slope "
            f"{_fmt(ck['gyro_vs_icp_rate_slope'])}; it is imported as `imu_gz`.")
    if "drive_icp_omega_vs_icp_rate_slope" in ck:
        add(f"- DRIVE's per-window `icp_omega` is {_fmt(ck['drive_icp_omega_vs_icp_rate_slope'])} x the ICP yaw change "
            f"over the window divided by its duration (the gyro agrees with the latter), so chi computed from "
            f"`icp_omega` with `icr_inverse` (median {_fmt(ck['chi_from_drive_icp_omega_median'])} over "
            f"{ck['chi_from_drive_icp_omega_n']} steady windows with |icp_omega| >= {MIN_TURN} rad/s) is biased low; "
            "the table above uses the ICP yaw change.")
    add("")
    return "\n".join(L)


def _yi_sentences(out: Mapping[str, Any]) -> list[str]:
    """What the Yi models use and whether they beat the best ICR-family model (numbers derived here)."""
    ms, v = out["models"], out["verdict"]
    best = v["best_icr_model"]
    if best is None:
        return []
    bt, by = (ms[best]["stats"]["all"][e]["median"] for e in ("trans", "yaw"))
    lines = []
    inputs = {"yi2009_s_gamma": "the measured wheel speeds only (the same input as the ICR family)",
              "yi2009_s_gamma_gyro": "the measured wheel speeds and the gyro yaw rate (`imu_yaw` of the DRIVE "
                                     "table, a rate: `imu_gz`) as psi_dot"}
    for name, what in inputs.items():
        if name not in ms:
            continue
        m = ms[name]
        t, y = (m["stats"]["all"][e]["median"] for e in ("trans", "yaw"))
        p = m["params"]
        d_mm = 1000.0 * (t - bt)
        verdict_t = ("matches (within 1 mm)" if abs(d_mm) < 1.0 else
                     f"beats (by {-d_mm:.0f} mm)" if d_mm < 0 else f"does not beat ({d_mm:.0f} mm worse than)")
        lines.append(
            f"- `{name}` uses {what}; S(gamma) fitted on {int(p['n_S_points'])} steady turning calibration windows "
            f"(S(0) = a1/a3 = {_fmt(p['S(0)'])} m, a2/a3 = {_fmt(p['a2'] / p['a3'])}, S reversing with the travel "
            f"direction, x_M = {_fmt(p['x_M'])} m, point scatter {_fmt(p['S_fit_rms'])} m RMS), common traction slip "
            f"lambda_0 = {_fmt(p['lambda_0'])}. Median test "
            f"error {_fmt(t, 4)} m / {_fmt(y)} rad: it {verdict_t} the best ICR-family model `{best}` "
            f"({_fmt(bt, 4)} m / {_fmt(by)} rad) in translation and is "
            f"{'better' if y < by else 'not better'} in yaw.")
    if lines:
        lines.append(
            "- Missing for Yi's full method (the EKF of Sec. IV, which estimates the slips on line): "
            + "; ".join(YI_MISSING) + ". The DRIVE table has the z gyro rate and the three accelerometer axes "
            "only, so the slips are calibrated constants here (eq. (8) with fitted tread ICRs) instead of EKF "
            "estimates, and psi_dot = gyro z (roll and pitch taken as 0 in eq. (10e)).")
    return lines


def _reading(out: Mapping[str, Any]) -> list[str]:
    """Sentences derived from the fitted values (no number is written here by hand)."""
    lines = []
    ms = out["models"]
    if "mandow2007_icr" in ms:
        p = ms["mandow2007_icr"]["params"]
        where = "behind" if p["x_icr"] < 0 else "ahead of"
        lines.append(
            f"- `mandow2007_icr`: alpha_l = {_fmt(p['alpha_l'])}, alpha_r = {_fmt(p['alpha_r'])}: the end-pose fit "
            f"takes the treads to move {100 * (1 - (p['alpha_l'] + p['alpha_r']) / 2):.0f} % less than r*w "
            f"(longitudinal slip "
            f"or a smaller effective radius, traded jointly with the ICR spread); neither symmetric model has this "
            f"freedom. Its ICRs lie "
            f"{_fmt(abs(p['x_icr']))} m {where} the reference point (this includes any offset of the ICP frame "
            f"origin from the wheel-geometry centre); chi = (y_l - y_r)/B = {_fmt(p['chi'])}, and the rotation it "
            f"predicts per unit of r*(w_r - w_l) matches a symmetric chi of "
            f"{_fmt(p['chi'] / ((p['alpha_l'] + p['alpha_r']) / 2))}.")
    if "icr_sym_chi" in ms:
        lines.append(f"- `icr_sym_chi`: chi = {_fmt(ms['icr_sym_chi']['params']['chi'])} minimises Mandow's J over the "
                     f"calibration windows; the median chi measured per steady window with eq. (25) (below) is "
                     f"{_fmt(out['chi']['median'])}.")
    if "wang2015_chi_curve" in ms:
        p = ms["wang2015_chi_curve"]["params"]
        lines.append(
            f"- `wang2015_chi_curve`: a = {_fmt(p['a'])}, b = {_fmt(p['b'])} (chi = {_fmt(p['chi(0)'])} at a zero "
            f"curvature ratio) against Wang's P3-AT a = {WANG_P3AT[0]}, b = {WANG_P3AT[1]} "
            f"(chi = {1 + WANG_P3AT[0]:.4f}).")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m bench.real.benchmark [TABLE] [--out results/real] [--seed 0] [--platform husky]``."""
    root = Path(__file__).resolve().parents[2]
    data_root = Path(os.environ.get("SKIDBENCH_DATA", root.parent / "shared" / "data"))
    default = data_root / "drive_husky" / "husky_windows.parquet"
    ap = argparse.ArgumentParser(prog="python -m bench.real.benchmark", description=main.__doc__)
    ap.add_argument("table", type=Path, nargs="?", default=default)
    ap.add_argument("--out", type=Path, default=root / "results" / "real")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--platform", default="husky")
    ap.add_argument("--wheel-radius", type=float, default=None)
    ap.add_argument("--track", type=float, default=None)
    args = ap.parse_args(argv)
    res = run_real_benchmark(args.table, args.out, args.seed, args.platform, args.wheel_radius, args.track)
    for mname, m in res["models"].items():
        s = m["stats"]["all"]["trans"]
        print(f"{mname:22s} median {s['median']:.3f} m  mean {s['mean']:.3f} m  p95 {s['p95']:.3f} m")
    v = res["verdict"]
    print(f"verdict: {'met' if v['passed'] else 'NOT met'} ({v['best_icr_model']} {v['best_icr_median_trans']:.3f} m "
          f"vs ideal_dd {v['ideal_dd_median_trans']:.3f} m); runtime {res['runtime_s']:.1f} s")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
