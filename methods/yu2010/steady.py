"""Steady-state uses of the resistance model: Fig. 9 torques over commanded radii (Yu 2010 Sec.
V-A) and Wang 2015's chi vs curvature ratio (Sec. 2.2, eqs. (16)-(23), Fig. 5).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from bench.kinematics import chi as chi_of_icr, icr_inverse
from methods.yu2010.commands import inverse_kinematics
from methods.yu2010.params import YuParams
from methods.yu2010.resistance import mu_consistent, patch_nodes, resistance, rolling_force, side_unit_forces


def steady_torques(radii: ArrayLike, v: ArrayLike, params: YuParams, slope: float = 0.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Model side of Fig. 9: steady left/right torques [N m] of eqs. (18)/(21) at commanded radii
    [m] (+ CCW, inf straight) and linear speed v [m/s].  The commanded radius is the no-slip one of
    Sec. V-A (kinematic model (2) with zero slip), so the wheel speeds are
    w_{l,r} = (v -/+ v B/(2R))/r; the resistance itself uses eq. (1) with ``params.alpha``."""
    wl, wr = inverse_kinematics(v, radii, params, alpha=1.0)
    return resistance(wl, wr, params, slope=slope)


def wang2015_table1_params(base: YuParams | None = None) -> YuParams:
    """Wang 2015 Table 1: Yu's P3-AT parameters with m = 31 kg and r = 0.11 m."""
    return (base or YuParams()).replace(m=31.0, r=0.11)


@dataclass(frozen=True)
class WangSteadyState:
    """Steady turning states solved from Wang 2015 eq. (16), skidbench body frame (x fwd, y left).

    ``chi`` = (y_l - y_r)/B (eq. (15)); ``residual``: force/moment balance residual at the
    solution, in units of the weight m g (moment: m g B)."""

    curvature_ratio: np.ndarray
    v_l: np.ndarray
    v_r: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    wz: np.ndarray
    chi: np.ndarray
    residual: np.ndarray


def _tread_speeds(curvature_ratio: np.ndarray, v: float) -> tuple[np.ndarray, np.ndarray]:
    """Tread speeds for Wang's curvature ratio (v_l + v_r)/(v_r - v_l) (his lambda, eq. (13)) and
    mean speed v; curvature ratio 0 (turning on the spot) uses v as the tread speed."""
    lam = np.asarray(curvature_ratio, float)
    with np.errstate(divide="ignore"):
        inv = np.where(np.isinf(lam), 0.0, 1.0 / np.where(lam == 0.0, 1.0, lam))
    v_l = np.where(lam == 0.0, -v, v * (1.0 - inv))
    v_r = np.where(lam == 0.0, v, v * (1.0 + inv))
    return v_l, v_r


def _balance(z: np.ndarray, wl: float, wr: float, params: YuParams, nodes) -> np.ndarray:
    """Residuals of Wang eq. (16) in Yu's frame for the body twist z = (u_x, u_y, phidot)."""
    ux, uy, ph = z
    f_r = rolling_force(params)
    tot = np.zeros(3)
    for w, x_w in ((wl, -params.B / 2.0), (wr, params.B / 2.0)):
        fy, fx, mz = (float(a) for a in side_unit_forces(w, ux, uy, ph, x_w, params, nodes=nodes))
        mu = float(mu_consistent(np.array(fy), np.array(w), f_r, params.mu_sa, params.mu_op))
        sg = float(np.sign(w))
        tot += (mu * fx, mu * fy - f_r * sg, mu * mz - x_w * f_r * sg)
    m, mg = params.m, params.m * params.g
    # m a = sum F with a = phidot z x u = (-phidot u_y, phidot u_x); moment balance M_d - M_r = 0
    return np.array([(tot[0] + m * ph * uy) / mg, (tot[1] - m * ph * ux) / mg, tot[2] / (mg * params.B)])


def wang_steady_state(params: YuParams, curvature_ratios: ArrayLike, v: float) -> WangSteadyState:
    """Solve Wang 2015 eq. (16) (longitudinal and lateral force balance with the centripetal
    force, moment balance M_d = M_r) for the body twist at each curvature ratio, with the shear
    stress model of Yu (Wang eqs. (17)-(21): longitudinal *and* lateral friction of the four
    patches), rolling resistance R_x = m g mu_roll (eq. (22)) and the mu_sa/mu_op rule per side.
    Unlike eq. (1), no expansion factor is assumed: the yaw rate and the lateral slip follow from
    the balance.  Least squares (scipy) per operating point, as Wang's eq. (23)."""
    lam = np.atleast_1d(np.asarray(curvature_ratios, float))
    v_l, v_r = _tread_speeds(lam, float(v))
    nodes = patch_nodes(params)
    chi0 = 1.0 + (params.L / params.B) ** 2  # isotropic Coulomb estimate, only a start value
    out = np.zeros((lam.size, 4))
    for i in range(lam.size):
        wl, wr = v_l[i] / params.r, v_r[i] / params.r
        z0 = np.array([0.0, (v_l[i] + v_r[i]) / 2.0, (v_r[i] - v_l[i]) / (chi0 * params.B)])
        scale = np.array([0.01 * abs(v), max(abs(v), 1e-3), max(abs(v) / params.B, 1e-3)])
        sol = least_squares(_balance, z0, args=(wl, wr, params, nodes), x_scale=scale, xtol=1e-12,
                            ftol=1e-12, gtol=1e-12, method="trf")
        out[i, :3] = sol.x
        out[i, 3] = float(np.max(np.abs(sol.fun)))
    ux, uy, ph = out[:, 0], out[:, 1], out[:, 2]
    vx, vy, wz = uy, -ux, ph
    y_l, y_r, _ = icr_inverse(v_l, v_r, vx, vy, wz, min_wz=1e-9)
    return WangSteadyState(lam, v_l, v_r, vx, vy, wz, chi_of_icr(y_l, y_r, params.B), out[:, 3])


def chi_vs_curvature_ratio(params: YuParams, curvature_ratios: ArrayLike, v: float) -> np.ndarray:
    """Wang 2015 Fig. 5: the ICR coefficient chi = (y_l - y_r)/B at each curvature ratio
    (v_l + v_r)/(v_r - v_l) and mean speed ``v`` from the dynamic steady state
    (:func:`wang_steady_state`)."""
    return wang_steady_state(params, curvature_ratios, v).chi
