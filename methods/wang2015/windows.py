"""Wang 2015 on the real-data benchmark's command windows (the window protocol of :mod:`bench.real.windows`).

Two window models, each vectorised over the windows of a DRIVE table:

* :class:`SymmetricChi` (row ``icr_sym_chi``, offered by ``wang2015.constant_chi``): the symmetric model
  with a constant chi, ``y_l = -y_r = chi B / 2``, ``x_icr = 0`` (eqs. (10)-(11), (15)); chi fitted by
  least squares on the calibration windows' end-pose errors (Mandow 2007 eq. (13)) from the default
  P3-AT value of eq. (46), where the plugin keeps eq. (46)'s chi = 1.5.
* :class:`WangChiCurve` (row ``wang2015_chi_curve``, offered by ``wang2015.chi_lambda``): chi as a function
  of the curvature ratio ``(v_l + v_r)/(v_r - v_l)`` (eq. (13)) through eq. (44) (:func:`wang_chi`, the
  curve of :func:`methods.wang2015.chi.chi_of_curvature_ratio` without the domain limit), evaluated per
  sample inside the symmetric model (eq. (47), whose ``2 B chi`` is a typo for ``2 y0 = chi B``, eq. (15));
  ``a, b`` fitted as Wang does: a nonlinear least-squares curve fit to chi measured per steady turning
  calibration window with eq. (25) (his (42), :func:`bench.real.windows.window_chi`), starting from the
  published fit of eq. (45) (:data:`WANG_P3AT`).

The body velocities are :func:`bench.kinematics.icr_forward` with the symmetric tread ICRs (eqs. (8)-(10)).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from bench.kinematics import curvature_ratio, icr_forward
from bench.real.drive import DriveWindows
from bench.real.windows import MIN_TURN, Pose, VelocityWindowModel, fit_end_poses, tread_speeds, window_chi
from methods.wang2015.chi import PUBLISHED_CURVE, chi_of_curvature_ratio
from methods.wang2015.kinematics import CHI_P3AT_DEFAULT

WANG_P3AT = (PUBLISHED_CURVE.a, PUBLISHED_CURVE.b)  # Wang 2015 eq. (45): (a, b) for the Pioneer P3-AT on tile


def wang_chi(lam: np.ndarray, a: float, b: float) -> np.ndarray:
    """Wang 2015 eq. (44): chi = 1 + a / (1 + b sqrt|curvature_ratio|); 1 on a straight line
    (|ratio| = inf); 1 + a when undefined (both treads stopped, where wz = 0 anyway)."""
    lam = np.asarray(lam, float)
    with np.errstate(invalid="ignore", over="ignore"):
        out = chi_of_curvature_ratio(lam, a, b, curvature_ratio_max=None)
    return np.where(np.isnan(lam), 1.0 + a, out)


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
        return fit_end_poses(self, ["chi"], [CHI_P3AT_DEFAULT], ([0.5], [10.0]), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        half = self.chi * self.track / 2.0
        return icr_forward(*tread_speeds(w, self.wheel_radius), half, -half, 0.0)

    def params(self) -> dict[str, float]:
        return {"chi": self.chi}


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
