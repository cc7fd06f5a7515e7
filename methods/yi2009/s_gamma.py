"""S(gamma) of Yi 2009 eq. (41), gamma of eq. (40), and the identification of Sec. V-B (Fig. 4).

Eq. (41) S(gamma) = a1 / (a2 |gamma| + a3) is :class:`SGamma` (the published coefficients, Sec. V-B:
:data:`PUBLISHED_S_GAMMA`); eq. (40) gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx) is :func:`gamma_ratio`; the nonlinear
least-squares fit of (41) is :func:`fit_s_gamma`; one (gamma, S) point of Fig. 4 from a run's reference pose, by
eq. (7) S = -v_Gy / psi_dot with v_Lx, v_Rx of eqs. (3)-(4), as the paper does with its vision system, is
:func:`reference_s_gamma_point` (its channels: :data:`REF_CHANNELS`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from bench.run import Run, RunError

REF_CHANNELS = ("ref_x", "ref_y", "ref_yaw")


@dataclass(frozen=True)
class SGamma:
    """Longitudinal ICR location model S(gamma) = a1 / (a2 |gamma| + a3), eq. (41); a1 in metres.

    Only the ratios a1/a3 (= S at gamma = 0) and a2/a3 are identifiable: (a1, a2, a3) and
    c (a1, a2, a3) give the same curve for any c != 0."""

    a1: float  # [m]
    a2: float  # [-]
    a3: float  # [-]

    def __post_init__(self) -> None:
        for k in ("a1", "a2", "a3"):
            v = getattr(self, k)
            if not math.isfinite(v):
                raise ValueError(f"SGamma.{k} = {v!r}: must be finite")
        if not (self.a3 > 0 and self.a2 >= 0):
            raise ValueError(f"SGamma(a2={self.a2!r}, a3={self.a3!r}): need a2 >= 0 and a3 > 0 so that "
                             "a2|gamma| + a3 > 0 for every gamma (eq. (41))")

    @classmethod
    def from_cm(cls, a1_cm: float, a2: float, a3: float) -> "SGamma":
        """Build from the paper's units (a1 in cm, Sec. V-B)."""
        return cls(a1_cm / 100.0, a2, a3)

    @property
    def a1_cm(self) -> float:
        return self.a1 * 100.0

    @property
    def s0(self) -> float:
        """S at gamma = 0 (straight driving) [m]: a1 / a3."""
        return self.a1 / self.a3

    @property
    def k(self) -> float:
        """Identifiable shape ratio a2 / a3."""
        return self.a2 / self.a3

    def __call__(self, gamma: ArrayLike) -> np.ndarray:
        """S [m] at gamma (eq. (41)); S -> 0 as |gamma| -> inf (turning on the spot)."""
        g = np.abs(np.asarray(gamma, dtype=float))
        with np.errstate(over="ignore"):
            return self.a1 / (self.a2 * g + self.a3)


PUBLISHED_S_GAMMA = SGamma.from_cm(2.148, 0.249, 0.039)  # Sec. V-B, Fig. 4


@dataclass(frozen=True)
class SGammaFit:
    """Result of :func:`fit_s_gamma`."""

    s_gamma: SGamma
    residual_rms: float  # [m]
    n_points: int
    nfev: int


def fit_s_gamma(gamma: ArrayLike, s: ArrayLike, a3: float = PUBLISHED_S_GAMMA.a3) -> SGammaFit:
    """Fit eq. (41) to points (gamma_i, S_i [m]) by nonlinear least squares (Sec. V-B, Fig. 4).

    Eq. (41) is invariant to scaling (a1, a2, a3) by a common factor, so a3 is held at a
    normalisation value (default: the published 0.039) and (a1, a2) are fitted; the identifiable
    curve does not depend on that choice.  a2 >= 0 keeps the denominator positive; a1 is free in
    sign (the paper has a1 > 0, i.e. the ICR ahead of the centre of mass)."""
    g = np.abs(np.asarray(gamma, dtype=float)).ravel()
    sv = np.asarray(s, dtype=float).ravel()
    if g.shape != sv.shape:
        raise ValueError(f"fit_s_gamma: gamma has {g.size} points, S has {sv.size}")
    bad = ~(np.isfinite(g) & np.isfinite(sv))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"fit_s_gamma: point {i} is not finite (gamma={g[i]!r}, S={sv[i]!r})")
    if np.unique(g).size < 2:
        raise ValueError(f"fit_s_gamma: need points at >= 2 distinct |gamma| to fit (a1, a2); got {np.unique(g)}")
    if not (math.isfinite(a3) and a3 > 0):
        raise ValueError(f"fit_s_gamma: normalisation a3 = {a3!r} must be > 0")

    # Initial guess from the linearised model 1/S = (a2/a1)|gamma| + a3/a1 (if S keeps one sign).
    p0 = np.array([float(np.mean(sv)) * a3, 0.0])
    if np.all(sv > 0) or np.all(sv < 0):
        slope, icpt = np.polyfit(g, 1.0 / sv, 1)
        if icpt != 0 and slope / icpt >= 0:
            a1_0 = a3 / icpt
            p0 = np.array([a1_0, max(slope * a1_0, 0.0)])

    def resid(p: np.ndarray) -> np.ndarray:
        return p[0] / (p[1] * g + a3) - sv

    def jac(p: np.ndarray) -> np.ndarray:
        den = p[1] * g + a3
        return np.column_stack((1.0 / den, -p[0] * g / den**2))

    sol = least_squares(resid, p0, jac=jac, bounds=([-np.inf, 0.0], [np.inf, np.inf]), method="trf",
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=10_000)
    a1, a2 = (float(v) for v in sol.x)
    return SGammaFit(SGamma(a1, a2, float(a3)), float(np.sqrt(np.mean(sol.fun**2))), int(g.size), int(sol.nfev))


def gamma_ratio(v_lx: ArrayLike, v_rx: ArrayLike) -> np.ndarray:
    """gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx), eq. (40); +-inf when v_Lx + v_Rx = 0."""
    v_lx, v_rx = np.asarray(v_lx, float), np.asarray(v_rx, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (v_lx - v_rx) / (v_lx + v_rx)


def reference_s_gamma_point(run: Run, track: float, smooth_window: float = 1.0, settle: float = 1.0,
                            min_yaw_rate: float = 0.05) -> tuple[float, float, int] | None:
    """One (gamma, S [m], n_samples) point of Fig. 4 from a run's reference pose (ref_x, ref_y,
    ref_yaw), as the paper does with its vision system: velocities by numerical differentiation
    (Savitzky-Golay over ``smooth_window`` s on a uniform grid), body velocities
    v_G = R(psi)^T [xdot, ydot], then S as the least-squares solution of eq. (7) over the samples
    after ``settle`` s with |yaw rate| >= ``min_yaw_rate``, S = -sum(v_Gy psidot)/sum(psidot^2),
    and gamma the median of eq. (40) with v_Lx, v_Rx from eqs. (3)-(4) (= -W psidot / (2 v_Gx)).
    Returns None when the run does not turn enough (S is 0/0 on a straight line, Remark 1)."""
    d = run.data
    for c in REF_CHANNELS:
        if c not in d.columns:
            raise RunError(run.where, c, None, "missing reference channel needed by the S(gamma) calibration")
    ok = np.isfinite(d["ref_x"].to_numpy()) & np.isfinite(d["ref_y"].to_numpy()) & np.isfinite(d["ref_yaw"].to_numpy())
    tr = run.t[ok]
    if tr.size < 8:
        return None
    rx, ry = d["ref_x"].to_numpy()[ok], d["ref_y"].to_numpy()[ok]
    ryaw = np.unwrap(d["ref_yaw"].to_numpy()[ok])
    h = float(np.median(np.diff(tr)))
    tg = np.arange(tr[0], tr[-1] + 0.5 * h, h)
    xs, ys, yaws = (np.interp(tg, tr, v) for v in (rx, ry, ryaw))
    win = max(5, int(round(smooth_window / h)) | 1)
    if win > tg.size:
        return None
    kw = dict(window_length=win, polyorder=3, delta=h, mode="interp")
    xd, yd = savgol_filter(xs, deriv=1, **kw), savgol_filter(ys, deriv=1, **kw)
    psid = savgol_filter(yaws, deriv=1, **kw)
    psi = savgol_filter(yaws, deriv=0, **kw)
    c, s = np.cos(psi), np.sin(psi)
    v_gx, v_gy = c * xd + s * yd, -s * xd + c * yd
    m = (tg >= tg[0] + settle) & (np.abs(psid) >= min_yaw_rate)
    if m.sum() < max(10, win):
        return None
    s_val = float(-np.sum(v_gy[m] * psid[m]) / np.sum(psid[m] ** 2))  # eq. (7), least squares
    half = 0.5 * track
    gam = gamma_ratio(v_gx[m] - half * psid[m], v_gx[m] + half * psid[m])  # eqs. (3), (4), (40)
    gam = gam[np.isfinite(gam)]
    if gam.size == 0:
        return None
    return float(np.median(gam)), s_val, int(m.sum())
