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

What is adopted, so that a robot whose wheels track their command gets the nominal model back (backward
elimination, one parameter at a time, each time refitting the rest):
- a limit (``L_diff``, ``W``) only when at least :data:`MIN_BEYOND` steady windows ask for more than it (their
  mapped command beyond the fitted limit): a limit no window reaches is not identified and stays off;
- each parameter only when leaving it at its neutral value (gain 1, no limit) raises the residual sum of squares by
  more than :data:`CHI2_ADOPT` times the residual variance (a likelihood-ratio test with one degree of freedom at
  p = 0.001; the windows are taken as independent, which two windows per command step are not quite, hence the
  strict level).  For a limit the level is nominal only ("no limit" sits on the boundary and the limit's location
  is fitted, so the statistic is not chi2(1)); :data:`MIN_BEYOND` is what keeps a limit from being fitted to noise
  (a null calibration of 400 seeds x 200 windows adopted something in 0.5 % of them).
With enough steady windows (:data:`MIN_WINDOWS`) the identified map replaces the platform's own map entirely
(:meth:`CommandResponse.fields`: what is not adopted goes back to neutral, and the mean clip, which the steady map
does without, to none), so that the model the simulation starts from is the map the windows were fitted with.  A steady response cannot tell a controller's
clip from a drive that cannot go faster: both are a ceiling on the steady wheel speeds, which is what is modelled.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy.optimize import least_squares

from bench.real.drive import DriveWindows
from bench.sim.commands import wheel_speed_scale

__all__ = ["CommandResponse", "identify_command_response", "steady_map", "MIN_BEYOND", "CHI2_ADOPT", "MIN_WINDOWS",
           "STEADY_EFFECTS"]

CHI2_ADOPT = 10.83  # chi2(1) at p = 0.001: the drop in residual sum of squares / variance a parameter must earn
MIN_BEYOND = 3    # a limit is adopted when at least this many steady windows ask for more than it
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
    windows it rests on and the steady wheel-speed RMS [rad/s] of measured - model before (the command itself)
    and after."""

    parameters: dict[str, float]
    stderr: dict[str, float]
    adopted: tuple[str, ...]
    n_windows: int
    n_beyond: dict[str, int] = field(default_factory=dict)
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
                "n_windows": self.n_windows, "n_beyond": dict(self.n_beyond),
                "rms_before": fin(self.rms_before), "rms_after": fin(self.rms_after)}


def _steady_means(w: DriveWindows, steps: Sequence[int] | None) -> tuple[np.ndarray, ...]:
    sel = np.array(w.steady, dtype=bool)  # a copy: the caller's windows are not changed
    if steps is not None:
        sel &= np.isin(w.calib_step, np.asarray(list(steps), dtype=w.calib_step.dtype))
    with np.errstate(all="ignore"):
        means = [np.nanmean(w[k][sel], axis=1) if sel.any() else np.zeros(0)
                 for k in ("cmd_wl", "cmd_wr", "enc_wl", "enc_wr")]
    ok = np.all([np.isfinite(m) for m in means], axis=0) if sel.any() else np.zeros(0, bool)
    return tuple(m[ok] for m in means)


def _fit(free: Sequence[str], u_l, u_r, y_l, y_r) -> tuple[dict[str, float], dict[str, float], float]:
    """Least squares of the free parameters (the others neutral): values, standard errors from the Jacobian, and
    the residual sum of squares."""
    if not free:
        p_l, p_r = steady_map({}, u_l, u_r)
        return {}, {}, float(np.sum((p_l - y_l) ** 2 + (p_r - y_r) ** 2))
    top = max(float(np.abs(np.r_[y_l, y_r]).max(initial=1.0)), 1.0)
    lo, hi = [_PARAMS[k][2] for k in free], [_PARAMS[k][3] for k in free]

    def resid(x):
        p_l, p_r = steady_map(dict(zip(free, x)), u_l, u_r)
        return np.r_[p_l - y_l, p_r - y_r]

    best = None
    for scale in (2.0, 0.9, 0.5):  # a limit started above every window has no gradient: start some below
        start = np.clip([_PARAMS[k][4] if _PARAMS[k][4] is not None else scale * top for k in free], lo, hi)
        f = least_squares(resid, start, bounds=(lo, hi))
        if best is None or f.cost < best.cost:
            best = f
    ss = float(np.sum(best.fun ** 2))
    s2 = ss / max(best.fun.size - len(free), 1)
    se = np.sqrt(np.maximum(np.diag(np.linalg.pinv(best.jac.T @ best.jac)) * s2, 0.0))
    se = np.where(np.all(best.jac == 0, axis=0), np.inf, se)  # a limit nothing reaches: no information
    return dict(zip(free, (float(x) for x in best.x))), dict(zip(free, (float(v) for v in se))), ss


def _beyond(theta: dict[str, float], u_l, u_r) -> dict[str, int]:
    """Per limit: steady windows whose command, mapped by the stages before it, asks for more than the limit."""
    g_sum, g_diff = theta.get("gain_sum", 1.0), theta.get("gain_diff", 1.0)
    half = g_diff * 0.5 * (u_r - u_l)
    out = {}
    if "limit_diff" in theta:
        out["limit_diff"] = int(np.sum(np.abs(half) > theta["limit_diff"]))
    if "wheel_limit" in theta:
        h = np.clip(half, -theta.get("limit_diff", math.inf), theta.get("limit_diff", math.inf))
        m = g_sum * 0.5 * (u_l + u_r)
        out["wheel_limit"] = int(np.sum(np.maximum(np.abs(m - h), np.abs(m + h)) > theta["wheel_limit"]))
    return out


def identify_command_response(w: DriveWindows, steps: Sequence[int] | None = None) -> CommandResponse:
    """The steady map (module docstring) from the steady windows of ``steps`` (all windows when None)."""
    u_l, u_r, y_l, y_r = _steady_means(w, steps)
    n = int(u_l.size)
    neutral = {k: v[1] for k, v in _PARAMS.items()}
    rms0 = float(np.sqrt(np.mean(np.r_[u_l - y_l, u_r - y_r] ** 2))) if n else math.nan
    if n < MIN_WINDOWS:
        return CommandResponse(neutral, {k: math.inf for k in _PARAMS}, (), n, {}, rms0, rms0)
    free = list(_PARAMS)
    theta, se, ss = _fit(free, u_l, u_r, y_l, y_r)
    while free:  # backward elimination (module docstring)
        beyond = _beyond(theta, u_l, u_r)
        unreached = [k for k in free if k in beyond and beyond[k] < MIN_BEYOND]
        if unreached:
            drop = unreached[0]
        else:
            s2 = ss / max(2 * n - len(free), 1)
            gain = {}
            for k in free:
                rise = _fit([j for j in free if j != k], u_l, u_r, y_l, y_r)[2] - ss
                gain[k] = rise / s2 if s2 > 0 else (math.inf if rise > 0 else 0.0)  # noise-free data: any rise
            drop = min(gain, key=gain.get)
            if gain[drop] > CHI2_ADOPT:
                break
        free = [k for k in free if k != drop]
        theta, se, ss = _fit(free, u_l, u_r, y_l, y_r)
    beyond = _beyond(theta, u_l, u_r)
    params = {**neutral, **theta}
    p_l, p_r = steady_map(theta, u_l, u_r)
    rms1 = float(np.sqrt(np.mean(np.r_[p_l - y_l, p_r - y_r] ** 2)))
    return CommandResponse(params, {k: se.get(k, math.inf) for k in _PARAMS}, tuple(free), n, beyond, rms0, rms1)
