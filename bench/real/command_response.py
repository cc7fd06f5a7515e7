"""The robot's steady command response, identified from the steady windows of the calibration half.

A real robot's logged command is often not its wheels' reference: its own velocity controller maps the command
(a gain on the mean wheel speed, another on the half-difference, the turn), clips the turn, and scales both sides
so that the faster wheel stays within the drive's speed limit.  Once the wheels have settled (DRIVE's
``steady_state_mask``: the 2-6 s of each 6 s command step) the measured wheel speeds are that map of the command
alone, with no dynamics.  So the map is identified from the window means of the steady windows without any
simulation, as a least-squares fit (:func:`scipy.optimize.least_squares`) of the testbed's own map
(:func:`bench.sim.testbed._references`, stage by stage: ``Platform.command_gain_sum/diff``,
``command_limit_diff``, ``wheel_speed_limit``):

    m = g_sum (u_l + u_r) / 2,   h = clip(g_diff (u_r - u_l) / 2, +-L_diff),
    (w_l, w_r) = (m - h, m + h) * min(1, W / max(|m - h|, |m + h|))

with ``u`` the commanded and ``w`` the measured steady wheel speeds [rad/s].  The gap workflow
(:func:`bench.real.gap.run_real_gap`) starts from the model with this map and simulates only what the steady
windows cannot show (transients, the yaw response).

The statistical unit is a steady command, not a window: the steady windows of one command step share its
command and most of their error (on the Husky's calibration half the residuals of a step's two windows correlate
at 0.68 left and 0.41 right), so they are averaged into one point per (step, command).  The two sides' errors are
correlated too, so the residuals are taken in the map's own coordinates, the half-sum and the half-difference of
the wheel speeds, each weighted by its own residual variance (equal side variances make the two uncorrelated).

What is adopted, so that a robot whose wheels track their command gets the nominal model back (backward
elimination, one parameter at a time, each time refitting the rest):
- a parameter only when at least :data:`MIN_BEYOND` steady commands identify it: for a limit (``L_diff``, ``W``)
  those that ask for more than it (their mapped command beyond the fitted limit: a limit no command reaches is
  not identified and stays off); for the mean's gain those below the wheel limit (with every command at the limit
  only the ratio of the gains shows, and a mean gain fitted there is wrong by far more than its standard error:
  the difference's gain carries the ratio, :func:`_support`);
- each parameter only when leaving it at its neutral value (gain 1, no limit) raises the weighted residual sum of
  squares by more than :data:`CHI2_ADOPT` (a likelihood-ratio test with one degree of freedom at p = 0.001).  For
  a limit the level is nominal only ("no limit" sits on the boundary and the limit's location is fitted, so the
  statistic is not chi2(1)); :data:`MIN_BEYOND` is what keeps a limit from being fitted to noise.  Residual
  variances are floored at (1e-9 x the largest wheel speed)^2, so noise-free data adopt only what rounding cannot
  explain.
With enough steady windows (:data:`MIN_WINDOWS`) the identified map replaces the platform's own map entirely
(:meth:`CommandResponse.fields`: what is not adopted goes back to neutral, and the mean clip, which the steady map
does without, to none), so that the model the simulation starts from is the map the windows were fitted with.  A
steady response cannot tell a controller's clip from a drive that cannot go faster: both are a ceiling on the
steady wheel speeds, which is what is modelled.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy.optimize import least_squares

from bench.real.drive import DriveWindows
from bench.sim.commands import wheel_speed_scale

__all__ = ["CommandResponse", "identify_command_response", "steady_map", "steady_window_means", "per_command",
           "MIN_BEYOND", "CHI2_ADOPT", "MIN_WINDOWS", "STEADY_EFFECTS"]

CHI2_ADOPT = 10.83  # chi2(1) at p = 0.001: the drop in residual sum of squares / variance a parameter must earn
MIN_BEYOND = 3    # a parameter is adopted only when at least this many steady commands identify it (_support)
MIN_WINDOWS = 8   # fewer steady windows: nothing identified (the nominal map kept)
# the gap catalogue's effects on the same platform fields: with enough steady windows the steady map is what the
# windows say about them, and the simulation stage (fitted on a few seconds) does not refit them
STEADY_EFFECTS = ("command_map", "command_limit", "wheel_speed_limit")

# parameter -> (platform field, neutral value, lower bound, upper bound, start)
_PARAMS = {
    "gain_sum": ("command_gain_sum", 1.0, 0.2, 3.0, 1.0),
    "gain_diff": ("command_gain_diff", 1.0, 0.05, 3.0, 1.0),
    "limit_diff": ("command_limit_diff", math.inf, 0.1, 50.0, None),
    "wheel_limit": ("wheel_speed_limit", math.inf, 0.3, 50.0, None),
}


def steady_map(theta: dict[str, float], u_l: np.ndarray, u_r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Steady wheel speeds for commanded ones under the map ``theta`` (module docstring; missing keys neutral)."""
    g_sum, g_diff = theta.get("gain_sum", 1.0), theta.get("gain_diff", 1.0)
    lim = theta.get("limit_diff", math.inf)
    mean = g_sum * 0.5 * (u_l + u_r)
    half = np.clip(g_diff * 0.5 * (u_r - u_l), -lim, lim)
    return wheel_speed_scale(mean - half, mean + half, theta.get("wheel_limit", math.inf))


@dataclass(frozen=True)
class CommandResponse:
    """The identified steady map: adopted parameters (neutral when not adopted), their standard errors, the
    windows it rests on and the steady commands they average to (``n_commands``, the statistical unit), per
    parameter the steady commands that identify it (``n_support``, :func:`_support`), and the
    steady wheel-speed RMS [rad/s] of measured - model over the windows before (the command itself) and after."""

    parameters: dict[str, float]
    stderr: dict[str, float]
    adopted: tuple[str, ...]
    n_windows: int
    n_support: dict[str, int] = field(default_factory=dict)
    n_commands: int = 0
    rms_before: float = math.nan
    rms_after: float = math.nan

    def overrides(self) -> dict[str, float]:
        """Platform fields of the adopted parameters (``{}``: the nominal map)."""
        return {_PARAMS[k][0]: float(self.parameters[k]) for k in self.adopted}

    def fields(self) -> dict[str, float]:
        """Every platform field of the robot's command map as identified (neutral where not adopted, no mean clip),
        ``{}`` when there were too few steady windows to identify anything."""
        if self.n_windows < MIN_WINDOWS:
            return {}
        return {"command_limit_mean": math.inf, **{f: float(self.parameters[k]) if k in self.adopted else neutral
                                                  for k, (f, neutral, *_) in _PARAMS.items()}}

    def to_json(self) -> dict[str, Any]:
        fin = (lambda x: float(x) if math.isfinite(x) else None)
        return {"parameters": {k: fin(v) for k, v in self.parameters.items()},
                "stderr": {k: fin(v) for k, v in self.stderr.items()},
                "adopted": list(self.adopted), "platform_overrides": self.overrides(),
                "n_windows": self.n_windows, "n_commands": self.n_commands, "n_support": dict(self.n_support),
                "rms_before": fin(self.rms_before), "rms_after": fin(self.rms_after)}


def steady_window_means(w: DriveWindows, steps: Sequence[int] | None,
                        channels: Sequence[str] = ("cmd_wl", "cmd_wr", "enc_wl", "enc_wr")) -> tuple[np.ndarray, ...]:
    """Per steady window of ``steps`` (all when None) with every channel finite: its step and the means of
    ``channels`` (the caller's windows are not changed)."""
    sel = np.array(w.steady, dtype=bool)  # a copy
    if steps is not None:
        sel &= np.isin(w.calib_step, np.asarray(list(steps), dtype=w.calib_step.dtype))
    if not sel.any():
        return tuple(np.zeros(0) for _ in range(len(channels) + 1))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN window: dropped below
        means = [np.nanmean(w[k][sel], axis=1) for k in channels]
    ok = np.all([np.isfinite(m) for m in means], axis=0)
    return (np.asarray(w.calib_step)[sel][ok].astype(float), *(m[ok] for m in means))


def per_command(step: np.ndarray, u_l: np.ndarray, u_r: np.ndarray, *others: np.ndarray) -> tuple[np.ndarray, ...]:
    """The windows averaged into one point per (step, command) (module docstring: the statistical unit): the
    commands and each of ``others``."""
    if not step.size:
        return (u_l, u_r, *others)
    key = np.c_[step, np.round(u_l, 6), np.round(u_r, 6)]
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    n = np.bincount(inv).astype(float)
    return tuple(np.bincount(inv, weights=x) / n for x in (u_l, u_r, *others))


def _channels(theta: dict[str, float], u_l, u_r, y_l, y_r) -> tuple[np.ndarray, np.ndarray]:
    """Residuals model - measured in the map's coordinates: the half-sum and the half-difference."""
    p_l, p_r = steady_map(theta, u_l, u_r)
    return 0.5 * ((p_l + p_r) - (y_l + y_r)), 0.5 * ((p_r - p_l) - (y_r - y_l))


def _variances(theta: dict[str, float], n_free: int, u_l, u_r, y_l, y_r) -> np.ndarray:
    """Residual variance of each channel under ``theta`` (dof: commands - free parameters), floored (docstring)."""
    floor = (1e-9 * max(float(np.abs(np.r_[y_l, y_r]).max(initial=1.0)), 1.0)) ** 2
    return np.array([max(float(np.sum(r ** 2)) / max(u_l.size - n_free, 1), floor)
                     for r in _channels(theta, u_l, u_r, y_l, y_r)])


def _fit(free: Sequence[str], var: np.ndarray, u_l, u_r, y_l, y_r
         ) -> tuple[dict[str, float], dict[str, float], float]:
    """Weighted least squares of the free parameters (the others neutral; channel variances ``var``): values,
    standard errors from the Jacobian, and the weighted residual sum of squares."""
    wts = 1.0 / np.sqrt(var)

    def resid(x) -> np.ndarray:
        r_sum, r_diff = _channels(dict(zip(free, x)), u_l, u_r, y_l, y_r)
        return np.r_[wts[0] * r_sum, wts[1] * r_diff]

    if not free:
        return {}, {}, float(np.sum(resid([]) ** 2))
    top = max(float(np.abs(np.r_[y_l, y_r]).max(initial=1.0)), 1.0)
    lo, hi = [_PARAMS[k][2] for k in free], [_PARAMS[k][3] for k in free]
    best = None
    for scale in (2.0, 0.9, 0.5):  # a limit started above every window has no gradient: start some below
        start = np.clip([_PARAMS[k][4] if _PARAMS[k][4] is not None else scale * top for k in free], lo, hi)
        f = least_squares(resid, start, bounds=(lo, hi))
        if best is None or f.cost < best.cost:
            best = f
    wss = float(np.sum(best.fun ** 2))
    se = np.sqrt(np.maximum(np.diag(np.linalg.pinv(best.jac.T @ best.jac)), 0.0))  # unit-variance residuals
    se = np.where(np.all(best.jac == 0, axis=0), np.inf, se)  # a limit nothing reaches: no information
    return dict(zip(free, (float(x) for x in best.x))), dict(zip(free, (float(v) for v in se))), wss


def _support(theta: dict[str, float], u_l, u_r) -> dict[str, int]:
    """Per free parameter, the steady commands that identify it: for a limit those whose command, mapped by the
    stages before it, asks for more; for the mean's gain those below the wheel limit; for the difference's gain
    those that turn within the clip (at the wheel limit they still show its ratio to the mean's gain, which is
    what a neutral mean gain leaves it to carry)."""
    g_sum, g_diff = theta.get("gain_sum", 1.0), theta.get("gain_diff", 1.0)
    lim, top = theta.get("limit_diff", math.inf), theta.get("wheel_limit", math.inf)
    half = g_diff * 0.5 * (u_r - u_l)
    h = np.clip(half, -lim, lim)
    m = g_sum * 0.5 * (u_l + u_r)
    fast = np.maximum(np.abs(m - h), np.abs(m + h))
    clipped, limited = np.abs(half) > lim, fast > top
    counts = {"gain_sum": int(np.sum(~limited & (np.abs(m) > 0))),
              "gain_diff": int(np.sum(~clipped & (np.abs(half) > 0))),  # at the wheel limit: its ratio to gain_sum
              "limit_diff": int(np.sum(clipped)), "wheel_limit": int(np.sum(limited))}
    return {k: v for k, v in counts.items() if k in theta}


def identify_command_response(w: DriveWindows, steps: Sequence[int] | None = None) -> CommandResponse:
    """The steady map (module docstring) from the steady windows of ``steps`` (all windows when None)."""
    step, *win = steady_window_means(w, steps)
    n_win = int(step.size)
    neutral = {k: v[1] for k, v in _PARAMS.items()}
    rms0 = float(np.sqrt(np.mean(np.r_[win[0] - win[2], win[1] - win[3]] ** 2))) if n_win else math.nan
    u_l, u_r, y_l, y_r = per_command(step, *win)
    n = int(u_l.size)
    if n_win < MIN_WINDOWS:
        return CommandResponse(neutral, {k: math.inf for k in _PARAMS}, (), n_win, {}, n, rms0, rms0)
    free = list(_PARAMS)
    var = _variances(neutral, 0, u_l, u_r, y_l, y_r)  # first fit: weights of the command itself
    theta, _, _ = _fit(free, var, u_l, u_r, y_l, y_r)
    while free:  # backward elimination (module docstring); theta is fitted for free
        var = _variances(theta, len(free), u_l, u_r, y_l, y_r)  # the channels' variances under the current model
        theta, se, wss = _fit(free, var, u_l, u_r, y_l, y_r)
        support = _support(theta, u_l, u_r)
        unsupported = [k for k in free if support.get(k, 0) < MIN_BEYOND]
        if unsupported:
            drop = unsupported[0]
        else:
            rise = {k: _fit([j for j in free if j != k], var, u_l, u_r, y_l, y_r)[2] - wss for k in free}
            drop = min(rise, key=rise.get)
            if rise[drop] > CHI2_ADOPT:
                break
        free = [k for k in free if k != drop]
        theta, se, _ = _fit(free, var, u_l, u_r, y_l, y_r)
    support = _support(theta, u_l, u_r)
    params = {**neutral, **theta}
    p_l, p_r = steady_map(theta, win[0], win[1])
    rms1 = float(np.sqrt(np.mean(np.r_[p_l - win[2], p_r - win[3]] ** 2)))
    return CommandResponse(params, {k: se.get(k, math.inf) for k in _PARAMS}, tuple(free), n_win, support, n,
                           rms0, rms1)
