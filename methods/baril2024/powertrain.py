"""DRIVE's powertrain: commanded wheel speeds -> wheel speeds, a bounded first-order lag with a dead time, per side.

Baril et al. 2024 (DRIVE) drive the slip model by commands through a powertrain model identified on the same
calibration data.  Read here as (per side j in {l, r}):

    tau_j dw_j/dt = u_j(t - d_j) - w_j(t),     w_j clipped to [w_min,j, w_max,j]

``tau`` the time constant [s], ``d`` the dead time, ``[w_min, w_max]`` the measured wheel-speed range of the
calibration data (the input limits DRIVE characterises).  The paper's text could not be read in this session; the
form (first order, delay, bounds, one model per side, fitted on wheel-speed errors over calibration windows from
each window's initial measured wheel speed) follows the authors' public implementation
(``models/powertrain/bounded_powertrain.py``, ``model_trainers/powertrain_trainer.py``).  Choices made here, the
simplest readings: the lag is discretised exactly under a zero-order hold of the command
(``w_{k+1} = w_k + (1 - exp(-dt/tau)) (u_{k-d} - w_k)``, the authors step it by forward Euler); the dead time is a
whole number of samples (commands before a window's first sample are held at its first one; the authors instead
hold the wheel speed for ``d`` after the window's start); ``tau`` and ``d`` minimise the mean absolute wheel-speed
error over the transitory calibration windows, as the authors' trainer does (a bounded scalar search of ``tau`` for
every whole dead time up to :data:`MAX_DELAY`, in place of their Nelder-Mead from ``tau = 0.4 s, d = 0.05 s``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

TAU_BOUNDS = (1e-3, 3.0)  # [s] search interval of the time constant
MAX_DELAY = 20  # [samples] largest dead time tried (1 s at 20 Hz, the authors' upper bound on the delay)


@dataclass(frozen=True)
class Powertrain:
    """One side's bounded first-order-plus-dead-time powertrain."""

    tau: float = 0.1  # [s]
    delay: int = 0  # [samples]
    w_min: float = -math.inf  # [rad/s]
    w_max: float = math.inf  # [rad/s]
    fit_cost: float = math.nan  # mean absolute wheel-speed error on the fitted windows [rad/s]

    def simulate(self, cmd: np.ndarray, w0: np.ndarray, dt: float) -> np.ndarray:
        """Wheel speeds (n_windows, n_samples) from commands (n_windows, n_samples) and each window's initial
        wheel speed ``w0`` (n_windows,)."""
        return simulate(cmd, w0, dt, self.tau, self.delay, self.w_min, self.w_max)


def delayed(cmd: np.ndarray, delay: int) -> np.ndarray:
    """``u_{k - delay}`` within each window (rows), the first command held before the window."""
    if delay <= 0:
        return cmd
    d = min(int(delay), cmd.shape[1])
    return np.concatenate([np.repeat(cmd[:, :1], d, axis=1), cmd[:, :cmd.shape[1] - d]], axis=1)


def simulate(cmd: np.ndarray, w0: np.ndarray, dt: float, tau: float, delay: int,
             w_min: float = -math.inf, w_max: float = math.inf) -> np.ndarray:
    """The bounded lag stepped over each window; sample 0 is ``w0`` (clipped)."""
    cmd = np.asarray(cmd, float)
    u = delayed(cmd, delay)
    g = 1.0 - math.exp(-dt / tau)
    out = np.empty_like(cmd)
    out[:, 0] = np.clip(np.asarray(w0, float), w_min, w_max)
    for k in range(cmd.shape[1] - 1):
        out[:, k + 1] = np.clip(out[:, k] + g * (u[:, k] - out[:, k]), w_min, w_max)
    return out


def fit_powertrain(cmd: np.ndarray, enc: np.ndarray, dt: float, bounds: tuple[float, float] | None = None,
                   max_delay: int = MAX_DELAY) -> Powertrain:
    """``tau`` and ``delay`` of one side minimising the mean absolute error between the simulated and the measured
    wheel speeds ``enc`` over the windows (rows) where both are finite, each simulated from its first measured speed;
    ``bounds`` = (w_min, w_max), by default the measured range of these windows."""
    cmd, enc = np.asarray(cmd, float), np.asarray(enc, float)
    ok = np.isfinite(cmd).all(axis=1) & np.isfinite(enc).all(axis=1)
    cmd, enc = cmd[ok], enc[ok]
    if cmd.shape[0] == 0:
        return Powertrain()
    lo, hi = bounds if bounds is not None else (float(enc.min()), float(enc.max()))

    def cost(tau: float, d: int) -> float:
        return float(np.mean(np.abs(simulate(cmd, enc[:, 0], dt, tau, d, lo, hi) - enc)[:, 1:]))

    best = Powertrain(w_min=lo, w_max=hi, fit_cost=math.inf)
    for d in range(max_delay + 1):
        sol = minimize_scalar(lambda lt: cost(math.exp(lt), d), bounds=tuple(map(math.log, TAU_BOUNDS)),
                              method="bounded", options={"xatol": 1e-4})
        if sol.fun < best.fit_cost:
            best = Powertrain(tau=float(math.exp(sol.x)), delay=d, w_min=lo, w_max=hi, fit_cost=float(sol.fun))
    return best
