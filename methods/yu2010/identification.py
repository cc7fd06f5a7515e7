"""Terrain parameter identification of Yu 2010 Sec. V-A.

* (K, mu_sa, mu_op): nonlinear least squares of eq. (28) on the steady-state torques of N
  experiments at evenly spaced commanded radii (Table I), with scipy.optimize.least_squares
  (Yu used MATLAB's lsqnonlin, also a trust-region reflective least squares).
* mu_roll: mean applied torque of a straight constant-speed run over (r * weight): the two sides
  carry half the weight each, so mu_roll = (tau_l + tau_r) / (r m g cos beta).
* alpha: ratio of the no-slip (commanded) yaw rate r (w_r - w_l)/B to the measured yaw rate,
  eq. (1), pooled by least squares over the turning runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from methods.yu2010.commands import inverse_kinematics
from methods.yu2010.params import YuParams
from methods.yu2010.resistance import patch_nodes, side_torque, unit_long_forces


@dataclass(frozen=True)
class IdentificationResult:
    """Result of eq. (28): identified K [m], mu_sa, mu_op; the experiments used (``indices``),
    the final sum of squares ``cost`` (eq. (28), N m^2), the RMS torque residual [N m], the
    optimiser status and evaluation count."""

    K: float
    mu_sa: float
    mu_op: float
    indices: np.ndarray
    cost: float
    rms: float
    success: bool
    nfev: int

    def apply(self, params: YuParams) -> YuParams:
        return params.replace(K=self.K, mu_sa=self.mu_sa, mu_op=self.mu_op)


def evenly_spaced(n_total: int, n: int) -> np.ndarray:
    """Indices of ``n`` evenly spaced experiments among ``n_total`` (first and last included)."""
    if not 1 <= n <= n_total:
        raise ValueError(f"n_experiments = {n}: expected 1 <= n <= {n_total}")
    if n == 1:
        return np.array([n_total - 1])
    return np.unique(np.round(np.linspace(0, n_total - 1, n)).astype(int))


def identify_from_speeds(wl: ArrayLike, wr: ArrayLike, tau_l_meas: ArrayLike, tau_r_meas: ArrayLike,
                         params: YuParams, x0: tuple[float, float, float] | None = None,
                         indices: np.ndarray | None = None, fit_K: bool = True) -> IdentificationResult:
    """Eq. (28) on operating points given as steady wheel speeds (w_l, w_r) [rad/s] and the measured
    steady torques; mu_roll and alpha are held at ``params``' values.  ``x0`` (K, mu_sa, mu_op)
    defaults to ``params``.  ``fit_K=False`` holds K at its start value and fits mu_sa, mu_op only
    (with a tiny K: the Coulomb limit of eq. (7), which Yu's Sec. V-A argues against)."""
    wl, wr = np.asarray(wl, float).ravel(), np.asarray(wr, float).ravel()
    tl, tr = np.asarray(tau_l_meas, float).ravel(), np.asarray(tau_r_meas, float).ravel()
    if not (wl.size == wr.size == tl.size == tr.size):
        raise ValueError(f"identify: sizes differ: w_l {wl.size}, w_r {wr.size}, tau_l {tl.size}, tau_r {tr.size}")
    for name, a in (("w_l", wl), ("w_r", wr), ("tau_l", tl), ("tau_r", tr)):
        if not np.all(np.isfinite(a)):
            i = int(np.flatnonzero(~np.isfinite(a))[0])
            raise ValueError(f"identify: {name}[{i}] = {a[i]!r}: expected a finite value")
    idx = np.arange(wl.size) if indices is None else np.asarray(indices)
    wl, wr, tl, tr = wl[idx], wr[idx], tl[idx], tr[idx]
    nodes = patch_nodes(params)
    k0, sa0, op0 = x0 or (params.K, params.mu_sa, params.mu_op)
    cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def forces(K: float) -> tuple[np.ndarray, np.ndarray]:
        if K not in cache:
            cache.clear()
            cache[K] = unit_long_forces(wl, wr, params, K=K, nodes=nodes)
        return cache[K]

    def residuals(z: np.ndarray) -> np.ndarray:
        K, mu_sa, mu_op = (z[0] * k0, z[1], z[2]) if fit_K else (k0, z[0], z[1])
        Fl, Fr = forces(K)
        ml = side_torque(Fl, wl, params, mu_sa=mu_sa, mu_op=mu_op)
        mr = side_torque(Fr, wr, params, mu_sa=mu_sa, mu_op=mu_op)
        return np.concatenate([ml - tl, mr - tr])  # Delta tau_lRes, Delta tau_rRes of eq. (28)

    # bounds are ours (the paper states none): mu <= 3, where a fit along a flat valley (Table I, N = 2) stops
    z0, lo, hi, xs = np.array([1.0, sa0, op0]), [1e-3, 1e-3, 1e-3], [1e3, 3.0, 3.0], np.array([0.3, 0.1, 0.1])
    if not fit_K:
        z0, lo, hi, xs = z0[1:], lo[1:], hi[1:], xs[1:]
    sol = least_squares(residuals, z0, bounds=(lo, hi), x_scale=xs, xtol=1e-12, ftol=1e-12, gtol=1e-12,
                        diff_step=1e-6, method="trf")
    res = sol.fun
    x = sol.x if fit_K else np.concatenate([[1.0], sol.x])
    return IdentificationResult(
        K=float(x[0] * k0), mu_sa=float(x[1]), mu_op=float(x[2]), indices=idx,
        cost=float(res @ res), rms=float(np.sqrt(np.mean(res**2))), success=bool(sol.success), nfev=int(sol.nfev),
    )


def identify(radii: ArrayLike, v: ArrayLike, tau_l_meas: ArrayLike, tau_r_meas: ArrayLike, params: YuParams,
             n_experiments: int | None = None, x0: tuple[float, float, float] | None = None) -> IdentificationResult:
    """Eq. (28) / Table I: identify (K, mu_sa, mu_op) from the steady torques measured at the
    commanded ``radii`` [m] (+ CCW) and linear speed(s) ``v`` [m/s], using ``n_experiments``
    evenly spaced experiments (all when None).  Wheel speeds follow the no-slip definition of the
    commanded radius (Sec. V-A)."""
    radii = np.asarray(radii, float).ravel()
    v = np.broadcast_to(np.asarray(v, float), radii.shape)
    wl, wr = inverse_kinematics(v, radii, params, alpha=1.0)
    idx = None if n_experiments is None else evenly_spaced(radii.size, int(n_experiments))
    return identify_from_speeds(wl, wr, tau_l_meas, tau_r_meas, params, x0=x0, indices=idx)


def rolling_from_straight(tau_l: ArrayLike, tau_r: ArrayLike, params: YuParams, slope: float = 0.0) -> float:
    """mu_roll from a straight constant-speed run (Sec. V-A): rolling resistance (total applied
    torque / r) over the weight m g cos(beta).  NaN samples are ignored."""
    tl, tr = np.asarray(tau_l, float), np.asarray(tau_r, float)
    ml, mr = np.nanmean(tl), np.nanmean(tr)
    if not (np.isfinite(ml) and np.isfinite(mr)):
        raise ValueError("rolling_from_straight: no finite torque sample")
    return float((ml + mr) / (params.r * params.m * params.g * math.cos(slope)))


def alpha_from_yaw_rate(wl: ArrayLike, wr: ArrayLike, yaw_rate: ArrayLike, params: YuParams) -> float:
    """alpha of eq. (1): measured yaw rate = r (w_r - w_l) / (alpha B).  Least squares of
    1/alpha over the operating points: 1/alpha = sum(c m) / sum(c^2), c the no-slip yaw rate."""
    c = params.r * (np.asarray(wr, float) - np.asarray(wl, float)) / params.B
    m = np.asarray(yaw_rate, float)
    ok = np.isfinite(c) & np.isfinite(m)
    den = float(np.sum(c[ok] * m[ok]))
    if den <= 0 or not np.any(ok):
        raise ValueError("alpha_from_yaw_rate: no turning operating point with a measured yaw rate")
    return float(np.sum(c[ok] ** 2) / den)
