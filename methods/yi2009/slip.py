"""Wheel slip of Yi 2009 eq. (6) and its sign constraint, eq. (14), on arrays.

Eq. (6) lambda = (r w - v_x)/(r w), clipped to [-1, 1] (Sec. III-A: lambda = -1 below -1 under braking), is
:func:`slip_ratio`; eq. (14), the constrained slips lambda'_L, lambda'_R of the longitudinal velocity (13), with the
cases of the sentence that derives it (equal wheel speeds: the w_L <= w_R case for both wheels), is
:func:`constrained_slip`.  The EKF loop evaluates the same equations inline, per step
(:func:`methods.yi2009.consistent.filter.run_filter_gm`).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

def slip_ratio(wheel_speed: ArrayLike, v_wheel: ArrayLike, wheel_radius: float, min_speed: float = 0.01) -> np.ndarray:
    """lambda = (r w - v_x)/(r w), eq. (6), clipped to [-1, 1] (Sec. III-A); 0 where r|w| < min_speed."""
    rw = wheel_radius * np.asarray(wheel_speed, float)
    v = np.asarray(v_wheel, float)
    ok = np.abs(rw) >= min_speed
    lam = np.where(ok, (rw - v) / np.where(ok, rw, 1.0), 0.0)
    return np.clip(lam, -1.0, 1.0)


def constrained_slip(lam_l: ArrayLike, lam_r: ArrayLike, w_l: ArrayLike, w_r: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """lambda'_L, lambda'_R of eq. (14): the outer (faster) side keeps only traction slip (>= 0), the inner side
    only braking slip (<= 0).

    The cases are those of the sentence that derives (14) (Sec. III-C): "if w_L <= w_R, the robot turns left, and
    the wheel slips satisfy lambda_L <= 0 and lambda_R >= 0"; "if w_L > w_R, then lambda_L > 0 and lambda_R < 0".
    At w_L = w_R the left side therefore keeps only braking slip and the right only traction slip (on a straight
    line, lambda_L = lambda_R, the two bounds together say lambda = 0: one wheel's encoder speed enters (13)).
    The printed (14) assigns w_L = w_R to its ">=" case for lambda'_L (traction on both sides); that bounds v_x
    (13) from above only and lets a filter speed behind the wheels latch at the +1 clip of (6) on a straight
    line whose encoders read exactly equal (methods.yi2009.consistent.filter.run_filter_gm, ``slip_rows``)."""
    lam_l, lam_r = np.asarray(lam_l, float), np.asarray(lam_r, float)
    w_l, w_r = np.asarray(w_l, float), np.asarray(w_r, float)
    pl = np.where(w_l > w_r, np.maximum(lam_l, 0.0), np.minimum(lam_l, 0.0))
    pr = np.where(w_l <= w_r, np.maximum(lam_r, 0.0), np.minimum(lam_r, 0.0))
    return pl, pr
