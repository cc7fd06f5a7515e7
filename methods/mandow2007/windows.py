"""Mandow 2007 on the real-data benchmark's command windows (the window protocol of :mod:`bench.real.windows`).

:class:`AsymmetricICR` (row ``mandow2007_icr``, offered by ``mandow2007.asymmetric_ga`` and
``mandow2007.asymmetric_de``): Mandow's parameterisation ``K = {x_ICRl, x_ICRr, y_ICRv, alpha_r, alpha_l}``
(eqs. (6)-(7), :func:`methods.mandow2007.kinematics.body_velocities`) in skidbench axes: ``y_l = -x_ICRl``,
``y_r = -x_ICRr``, ``x_icr = y_ICRv`` (Mandow's Y is our x, his X our -y), tread speeds ``alpha_i r w_i``;
fitted with ``scipy.optimize.least_squares`` on the calibration windows' end poses, minimising Mandow's J
(eq. (13): squared x, y [m] and yaw [rad] errors, equal weights), in place of his GA.  The search starts
from the symmetric model with the constant chi that ``wang2015.constant_chi``'s window model fits on the
same windows (taken through :func:`bench.registry.get`: a GA-free, deterministic start).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from bench import registry
from bench.real.drive import DriveWindows
from bench.real.windows import Pose, VelocityWindowModel, fit_end_poses, tread_speeds
from methods.mandow2007.kinematics import IcrParams, body_velocities

SYMMETRIC_START = "wang2015.constant_chi"  # plugin whose first window model gives the fit's starting chi


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
        chi0 = registry.get(SYMMETRIC_START).window_models(self.wheel_radius, self.track)[0].fit(calib).chi
        half = chi0 * self.track / 2.0
        names = ["y_l", "y_r", "x_icr", "alpha_l", "alpha_r"]
        lo = [0.05, -5.0, -2.0, 0.3, 0.3]
        hi = [5.0, -0.05, 2.0, 3.0, 3.0]
        return fit_end_poses(self, names, [half, -half, 0.0, 1.0, 1.0], (lo, hi), calib)

    def icr_params(self) -> IcrParams:
        """K in Mandow's axes: ``x_ICRl = -y_l``, ``x_ICRr = -y_r``, ``y_ICRv = x_icr``."""
        return IcrParams(-self.y_l, -self.y_r, self.x_icr, self.alpha_l, self.alpha_r)

    def velocities(self, w: DriveWindows) -> Pose:
        return body_velocities(self.icr_params(), *tread_speeds(w, self.wheel_radius))

    def params(self) -> dict[str, float]:
        return {"y_l": self.y_l, "y_r": self.y_r, "x_icr": self.x_icr, "alpha_l": self.alpha_l,
                "alpha_r": self.alpha_r, "chi": (self.y_l - self.y_r) / self.track}
