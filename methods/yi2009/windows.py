"""Yi 2009's kinematics as real-data window models (the protocol of :mod:`bench.real.windows`): :class:`YiSGamma`.

Yi's EKF (Sec. IV) cannot run on DRIVE windows: they lack the roll and pitch gyro rates of eqs. (10c)-(10e).  The
window path is the paper's kinematics (Sec. III-A, III-C, V-B): tread speeds with slip, eqs. (6) and (8) (a common
traction slip and constant tread-ICR positions y_lc, y_rc of eq. (9a)), v_Gx by eq. (13), the lateral velocity by
eq. (15) with S(gamma) of eq. (41) (:func:`s_of_gamma`: eq. (41) with its limits) and gamma of eq. (40) with
eqs. (3)-(4); S(gamma) fitted as in Sec. V-B (:func:`methods.yi2009.s_gamma.fit_s_gamma`) on the (gamma, S)
points of eq. (7) measured on the reference (:func:`yi_s_points`).  Two rows of the real-data benchmark, offered
by :meth:`methods.yi2009.ekf.Yi2009Ekf.window_models`: ``yi2009_s_gamma`` (psi_dot from the wheel speeds) and
``yi2009_s_gamma_gyro`` (psi_dot the gyro's z rate).  Moved unchanged from bench/real/benchmark.py (commit
c1fd38c), except the start chi of the tread-ICR fit, which comes from the symmetric ICR model's own plugin
(:func:`symmetric_chi_start`) instead of the benchmark's copy of that model.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from bench import registry
from bench.kinematics import icr_forward
from bench.real.drive import DriveWindows
from bench.real.windows import MIN_TURN, Pose, VelocityWindowModel, fit_end_poses, tread_speeds, window_twist
from methods.yi2009.s_gamma import fit_s_gamma

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


SYMMETRIC_CHI_MODEL = ("wang2015.constant_chi", "icr_sym_chi")  # (plugin, row) of the start of the y_l, y_r fit


def symmetric_chi_start(calib: DriveWindows, wheel_radius: float, track: float) -> float:
    """chi of the symmetric ICR model with constant chi (Wang 2015 eqs. (11), (15); row ``icr_sym_chi``) fitted on
    the calibration windows' end poses (Mandow 2007 eq. (13)): the start of :class:`YiSGamma`'s tread-ICR fit, from
    that model's own plugin through the registry (:data:`SYMMETRIC_CHI_MODEL`), not a copy of it."""
    plugin, row = SYMMETRIC_CHI_MODEL
    model = next(m for m in registry.get(plugin).window_models(wheel_radius, track) if m.name == row)
    return float(model.fit(calib).params()["chi"])


MIN_S_POINTS_PER_DIRECTION = 10  # S(gamma) points per travel direction needed to fit x_M as well


@dataclass(frozen=True)
class YiSGamma(VelocityWindowModel):
    """Yi 2009 kinematics (Sec. III-A, III-C, V-B) as a window model (Yi's EKF itself cannot run on
    DRIVE data: it needs the roll and pitch gyro rates, absent there; see the real benchmark's ``YI_MISSING``).

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
    least squares (:func:`methods.yi2009.s_gamma.fit_s_gamma`, a3 held at the published 0.039, only a1/a3
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

    @property
    def inputs(self) -> tuple[str, ...]:
        """What the model reads of a window besides its initial reference pose (the real league shows it)."""
        return ("wheel speeds", "gyro z") if self.yaw_rate == "gyro" else ("wheel speeds",)

    def __post_init__(self) -> None:
        if self.yaw_rate not in ("wheels", "gyro"):
            raise ValueError(f"YiSGamma.yaw_rate = {self.yaw_rate!r}: 'wheels' or 'gyro'")

    @classmethod
    def gyro(cls, wheel_radius: float, track: float, **kw: Any) -> "YiSGamma":
        return cls(wheel_radius, track, yaw_rate="gyro", name="yi2009_s_gamma_gyro",
                   label="Yi S(gamma) (eqs. (6), (13), (15), (40), (41)); wheel speeds + gyro yaw rate", **kw)

    def _s_fit(self, calib: DriveWindows) -> "YiSGamma":
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
        chi0 = symmetric_chi_start(calib, self.wheel_radius, self.track)
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
