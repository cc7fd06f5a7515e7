"""The reference quantities of Yi 2009's experiments: slip from the vision pose, its agreement, the truth's S.

:func:`vision_slip`: wheel slips by eqs. (3), (4), (6) from the reference pose, as the paper's vision system gives
them (Sec. V-A); :func:`slip_agreement`: estimated against reference slips (Fig. 7); :func:`s_gamma_truth_point`:
(gamma, S) of eqs. (40), (7) of a steady turn from the testbed truth (declared truth, for the figure).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import savgol_filter

from bench.run import Run, RunError
from methods.yi2009.repro.settings import _geometry

def _wheel_angle(run: Run, channel: str) -> tuple[np.ndarray, np.ndarray]:
    """Wheel angle [rad] at the encoder samples, rebuilt from the count-difference speeds
    (speed_k * dT_k is the count difference times the angle quantum: exact up to the first count)."""
    t, w = run.samples(channel)
    if t.size < 2:
        raise RunError(run.where, channel, f"{t.size} samples", "the vision slip needs encoder samples")
    return t, np.concatenate(([0.0], np.cumsum(w[1:] * np.diff(t))))


def vision_slip(run: Run, window: float = 1.0, min_speed: float = 0.05, polyorder: int = 2
                ) -> tuple[np.ndarray, np.ndarray]:
    """Wheel slips (lambda_L, lambda_R) from the reference pose, as the paper computes them with its
    vision system (Sec. V-A: "velocity and slip calculations ... from the numerical differentiation of
    the position information").

    On a uniform grid at the reference rate: x, y, yaw differentiated by a Savitzky-Golay filter
    (``window`` s, local polynomial of order ``polyorder``); v_Gx = R(psi)^T [xdot, ydot]; v_Lx, v_Rx
    by eqs. (3)-(4); wheel speeds w_L, w_R by the same filter applied to the encoder angle (so both sides of eq. (6) have the same
    delay); lambda = (r w - v_x)/(r w), eq. (6), clipped to [-1, 1] (Sec. III-A); NaN where the tread
    speed r|w| is below ``min_speed``.  Returns (t (n,), lambda (n, 2))."""
    r, track = _geometry(run)
    d = run.data
    for c in ("ref_x", "ref_y", "ref_yaw"):
        if c not in d.columns:
            raise RunError(run.where, c, None, "missing reference channel needed by the vision slip")
    ok = np.isfinite(d["ref_x"].to_numpy()) & np.isfinite(d["ref_y"].to_numpy()) & np.isfinite(d["ref_yaw"].to_numpy())
    tr = run.t[ok]
    if tr.size < 8:
        raise RunError(run.where, "ref_x", f"{tr.size} samples", "the vision slip needs >= 8 reference samples")
    h = float(np.median(np.diff(tr)))
    tg = np.arange(tr[0], tr[-1] + 0.5 * h, h)
    win = max(5, int(round(window / h)) | 1)
    if win > tg.size:
        raise RunError(run.where, "ref_x", f"{tg.size} grid samples", f"shorter than the {window} s slip window")
    kw = dict(window_length=win, polyorder=polyorder, delta=h, mode="interp")
    xs, ys = np.interp(tg, tr, d["ref_x"].to_numpy()[ok]), np.interp(tg, tr, d["ref_y"].to_numpy()[ok])
    yaws = np.interp(tg, tr, np.unwrap(d["ref_yaw"].to_numpy()[ok]))
    xd, yd = savgol_filter(xs, deriv=1, **kw), savgol_filter(ys, deriv=1, **kw)
    psid, psi = savgol_filter(yaws, deriv=1, **kw), savgol_filter(yaws, deriv=0, **kw)
    v_gx = np.cos(psi) * xd + np.sin(psi) * yd
    v_side = np.column_stack((v_gx - 0.5 * track * psid, v_gx + 0.5 * track * psid))  # eqs. (3), (4)
    lam = np.empty_like(v_side)
    for j, ch in enumerate(("enc_wl", "enc_wr")):
        te, ang = _wheel_angle(run, ch)
        rw = r * savgol_filter(np.interp(tg, te, ang), deriv=1, **kw)
        fast = np.abs(rw) >= min_speed
        with np.errstate(divide="ignore", invalid="ignore"):
            lam[:, j] = np.where(fast, np.clip((rw - v_side[:, j]) / rw, -1.0, 1.0), np.nan)  # eq. (6)
    return tg, lam


def slip_agreement(t_ref: np.ndarray, lam_ref: np.ndarray, t_est: np.ndarray, lam_est: np.ndarray,
                   mask: np.ndarray | None = None) -> dict[str, float]:
    """Agreement of estimated slips with reference slips (both (n, 2): left, right).

    The estimate is interpolated linearly to ``t_ref``; samples where either side is NaN or ``mask``
    is False are dropped.  Returns ``rms`` (RMS of the difference over both sides), ``corr`` (Pearson
    correlation over time, mean of the two sides; NaN when a side is constant), ``ref_rms`` (RMS of
    the reference, its magnitude), ``ref_std`` (std over time, mean of the sides) and ``n``."""
    t_ref, lam_ref = np.asarray(t_ref, float), np.asarray(lam_ref, float)
    est = np.column_stack([np.interp(t_ref, t_est[np.isfinite(c)], c[np.isfinite(c)], left=np.nan, right=np.nan)
                           if np.isfinite(c).sum() >= 2 else np.full(t_ref.size, np.nan)
                           for c in np.asarray(lam_est, float).T])
    ok = np.isfinite(lam_ref).all(axis=1) & np.isfinite(est).all(axis=1)
    if mask is not None:
        ok &= mask
    n = int(ok.sum())
    if n < 3:
        return {"rms": math.nan, "corr": math.nan, "ref_rms": math.nan, "ref_std": math.nan, "n": float(n)}
    a, b = est[ok], lam_ref[ok]
    corr = []
    for j in range(2):
        if np.std(a[:, j]) > 0 and np.std(b[:, j]) > 0:
            corr.append(float(np.corrcoef(a[:, j], b[:, j])[0, 1]))
        else:
            corr.append(math.nan)
    return {"rms": float(np.sqrt(np.mean((a - b) ** 2))), "corr": float(np.mean(corr)),
            "ref_rms": float(np.sqrt(np.mean(b**2))), "ref_std": float(np.mean(np.std(b, axis=0))), "n": float(n)}


def s_gamma_truth_point(run: Run, settle: float = 1.0) -> tuple[float, float]:
    """(gamma, S [m]) of a steady turn from the testbed truth (declared truth, for the figure only):
    medians over t >= ``settle`` of truth_x_icr (S, eq. (7)) and of eq. (40) with truth body
    velocities and eqs. (3)-(4)."""
    _, track = _geometry(run)
    w = run.t >= settle
    vx, wz = run["truth_vx"][w], run["truth_wz"][w]
    with np.errstate(divide="ignore", invalid="ignore"):
        gam = (-track * wz) / (2.0 * vx)  # eq. (40) with (3), (4): (v_Lx - v_Rx)/(v_Lx + v_Rx)
    return float(np.nanmedian(gam)), float(np.nanmedian(run["truth_x_icr"][w]))
