"""Command helpers of Yu 2010 Sec. V: the 31 commanded radii (Sec. V-A), the inverse kinematics of
Fig. 8 and the lemniscate command of eqs. (29)-(30) (Figs. 21-23)."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from bench.kinematics import inverse_v_radius
from methods.yu2010.params import YuParams

LEMNISCATE_PERIOD_SCALE = 50.0  # the "t/50" of eqs. (29)-(30) [s]
# Curve time where the partial lemniscate starts (our reading of Fig. 21, which the text does not
# give): the speed minimum near (5.41, 9.54); over the next 18 s the speed rises 0.156 -> 0.24 m/s
# with accelerations in [0, 0.006] m/s^2 (Yu: "in the range [0 0.02] m/s^2") and the radius
# sweeps 1.45 -> 12 m ("a large range of vehicle velocities and turning radii").
LEMNISCATE_TAU0 = 31.45


def commanded_radii() -> np.ndarray:
    """Yu's 31 commanded radii [m] (Sec. V-A, experiments i = 1..31), read as

    {0.2, 0.3, ..., 1.0} (9, step 0.1) U {2, 3, ..., 10} (9, step 1) U {10^1.2, ..., 10^2}
    (5, exponent step 0.2) U {10^2.2, ..., 10^3.2} (6, exponent step 0.2) U {10^3.6, 10^4} (2):
    9 + 9 + 5 + 6 + 2 = 31, increasing."""
    out = np.concatenate([
        np.round(np.arange(2, 11) * 0.1, 10),
        np.arange(2.0, 11.0),
        10.0 ** np.round(np.arange(1.2, 2.01, 0.2), 10),
        10.0 ** np.round(np.arange(2.2, 3.21, 0.2), 10),
        10.0 ** np.array([3.6, 4.0]),
    ])
    assert out.size == 31 and np.all(np.diff(out) > 0)
    return out


def inverse_kinematics(v: ArrayLike, radius: ArrayLike, params: YuParams, alpha: float | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 8: desired linear speed v_y,d [m/s] and turning radius rho_d [m] (+ CCW, inf straight)
    -> desired wheel speeds (w_l,d, w_r,d) [rad/s] by inverting eq. (1):
    w_{l,r} = (v -/+ (v/rho) alpha B / 2) / r.  ``alpha`` defaults to ``params.alpha``; alpha = 1
    is the no-slip model (2) with zero slip that Sec. V-A uses to define the commanded radius."""
    a = params.alpha if alpha is None else alpha
    vl, vr = inverse_v_radius(v, radius, params.B, a)
    return vl / params.r, vr / params.r


def lemniscate_xy(tau: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. (29)-(30): X = 9 cos(s)/(1 + sin^2 s), Y = 27 sin(s) cos(s)/(1 + sin^2 s), s = tau/50."""
    s = np.asarray(tau, float) / LEMNISCATE_PERIOD_SCALE
    d = 1.0 + np.sin(s) ** 2
    return 9.0 * np.cos(s) / d, 27.0 * np.sin(s) * np.cos(s) / d


def _lemniscate_d1(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dX/ds, dY/ds of eqs. (29)-(30) (analytic)."""
    sn, cs = np.sin(s), np.cos(s)
    d = 1.0 + sn**2
    dx = -9.0 * sn * (3.0 - sn**2) / d**2
    dy = 27.0 * (np.cos(2 * s) * d - 2.0 * sn**2 * cs**2) / d**2
    return dx, dy


def lemniscate_v_radius(tau: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Desired linear speed v_y,d [m/s] and signed turning radius rho_d [m] (+ CCW) along the
    lemniscate at curve time ``tau`` [s] (Figs. 22-23): v = |dP/dtau|,
    rho = |P'|^3 / (X' Y'' - Y' X'')."""
    s = np.asarray(tau, float) / LEMNISCATE_PERIOD_SCALE
    dx, dy = _lemniscate_d1(s)
    h = 1e-5
    dxp, dyp = _lemniscate_d1(s + h)
    dxm, dym = _lemniscate_d1(s - h)
    ddx, ddy = (dxp - dxm) / (2 * h), (dyp - dym) / (2 * h)
    speed_s = np.hypot(dx, dy)
    cross = dx * ddy - dy * ddx
    with np.errstate(divide="ignore"):
        rho = np.where(cross != 0.0, speed_s**3 / cross, np.inf)
    return speed_s / LEMNISCATE_PERIOD_SCALE, rho


def lemniscate_command(t: ArrayLike, tau0: float = LEMNISCATE_TAU0, ramp_time: float = 3.0, accel: float = 1.0,
                       duration: float = 18.0) -> tuple[np.ndarray, np.ndarray]:
    """Command of Sec. V-C: (v_d, rho_d) at times ``t`` [s].

    For t < ramp_time the speed rises at ``accel`` (1 m/s^2) up to the curve's initial speed
    v_d(tau0) and holds it (reached well within 3 s), at the initial radius rho_d(tau0); then for
    ``duration`` (18 s) the curve is followed from curve time tau0: (v_d, rho_d)(tau0 + t -
    ramp_time); afterwards the command is a stop (v = 0, straight).  Which part of the curve Yu
    drove (Fig. 21) is not given in the text: ``tau0`` selects it (default
    :data:`LEMNISCATE_TAU0`, the speed minimum, after which the speed only rises, matching the
    non-negative accelerations Yu reports)."""
    t = np.asarray(t, float)
    v0, rho0 = lemniscate_v_radius(tau0)
    v_curve, rho_curve = lemniscate_v_radius(tau0 + np.maximum(t - ramp_time, 0.0))
    ramp = t < ramp_time
    v = np.where(ramp, np.minimum(accel * np.maximum(t, 0.0), v0), v_curve)
    rho = np.where(ramp, rho0, rho_curve)
    stop = t > ramp_time + duration
    return np.where(stop, 0.0, v), np.where(stop, np.inf, rho)
