"""Stalls: steps where the robot barely moves while its wheels turn, measured from the data alone.

A skid-steered robot in a hard turn must overcome the treads' resistance to turning with the traction of its
sides.  Near that limit it can stall: the wheels turn at the commanded speeds while the body hardly moves or yaws
(on the Husky's DRIVE steps: one side near stop, the other at about 6 rad/s, the ICP body speed about 0 where
other steps with the same wheel speeds move at 0.3-0.4 m/s and yaw at 0.8 rad/s).  A testbed model that turns as
the robot usually does cannot follow such a step, and a mean-square score over steps is then carried by the few
that stall.  This module names them, beside the held-out score of :mod:`bench.real.held_out`; it fits nothing
and no fitting stage of :mod:`bench.real.gap` reads it.

The measure (:func:`motion_ratio`): after the first :data:`SETTLE` s of a step (DRIVE's transitory window), in
blocks of :data:`BLOCK` s, the body's motion ``hypot(v, B/2 w_z)`` (``v`` the reference position's displacement
over the block / its duration, ``w_z`` the gyro's mean) against the motion its wheels imply,
``hypot(r (w_l + w_r)/2, B/2 r (w_r - w_l)/B)`` (the ideal differential drive, Wang 2015 eq. (25) with chi = 1),
summed over the blocks.  1 for a robot that moves as its wheels roll; a skid-steer turning at chi ~ 2.5 is at
about 0.5; a step below :data:`STALL_RATIO` is a stall.  Without a reference position (or with fewer than two of
its samples) the translation is left out of both sides (the yaw alone).  The same measure is taken on a model's
replay (its own wheels, pose and gyro), so the report can say whether the model stalls where the robot does.
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from bench.gap.residuals import measured_channels

__all__ = ["STALL_RATIO", "SETTLE", "BLOCK", "SPIN_SHARE", "SPIN_MIN", "motion_ratio", "run_series", "space_series",
           "spin_like_steps", "stall_summary"]

STALL_RATIO = 0.2  # testbed choice, diagnostic only: set after the Husky's worst held-out steps were seen (0.0-0.2
#                    there, 0.4-0.8 on most steps); it changes no fit and no score
SETTLE = 2.0  # [s] the start of a step left out (DRIVE's transitory window)
BLOCK = 0.5  # [s] reference displacement taken over blocks this long (the ICP's noise is mm, a stalled body's
#              motion over a block cm)
SPIN_SHARE, SPIN_MIN = 0.5, 3.0  # testbed choices, diagnostic only (set after the Husky's stalls were seen): a step
#   is commanded like a spin when its mean wheel-speed command is under SPIN_SHARE of its half-difference, and the
#   half-difference above SPIN_MIN [rad/s]
Series = Mapping[str, tuple[np.ndarray, np.ndarray]]  # channel -> (t [s], values [SI])


def _block_means(t: np.ndarray, v: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Mean of the finite samples of ``v`` in each block ``[edges[i], edges[i + 1])`` (NaN for an empty block)."""
    ok = np.isfinite(v)
    idx = np.digitize(t[ok], edges) - 1
    inside = (idx >= 0) & (idx < edges.size - 1)
    n = np.bincount(idx[inside], minlength=edges.size - 1).astype(float)
    s = np.bincount(idx[inside], weights=v[ok][inside], minlength=edges.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, s / n, np.nan)


def _displacement(t: np.ndarray, x: np.ndarray, y: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Distance [m] between the reference positions at consecutive block edges (linear interpolation of the finite
    samples; NaN outside them)."""
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return np.full(edges.size - 1, np.nan)
    px = np.interp(edges, t[ok], x[ok], left=np.nan, right=np.nan)
    py = np.interp(edges, t[ok], y[ok], left=np.nan, right=np.nan)
    return np.hypot(np.diff(px), np.diff(py))


def motion_ratio(series: Series, radius: float, track: float, settle: float = SETTLE, block: float = BLOCK) -> float:
    """The body's motion over the motion its wheels imply, after ``settle`` s (module docstring).  ``series`` needs
    ``enc_wl``, ``enc_wr`` [rad/s] and ``imu_gz`` [rad/s]; ``ref_x``, ``ref_y`` [m] when present add the translation.
    NaN when the wheels imply no motion or a channel is missing."""
    if not all(c in series for c in ("enc_wl", "enc_wr", "imu_gz")):
        return math.nan
    t_all = np.concatenate([np.asarray(series[c][0], float) for c in ("enc_wl", "enc_wr", "imu_gz")])
    t0, t1 = float(np.nanmin(t_all)) + settle, float(np.nanmax(t_all))
    n = int((t1 - t0) // block)
    if n < 1:
        return math.nan
    edges = t0 + block * np.arange(n + 1)
    wl = _block_means(*(np.asarray(a, float) for a in series["enc_wl"]), edges)
    wr = _block_means(*(np.asarray(a, float) for a in series["enc_wr"]), edges)
    wz = _block_means(*(np.asarray(a, float) for a in series["imu_gz"]), edges)
    half = 0.5 * track
    turn_ideal = half * radius * (wr - wl) / track
    v = np.full(n, np.nan)
    if "ref_x" in series and "ref_y" in series:  # one sensor: x and y share their sample times
        (tx, x), (_, y) = series["ref_x"], series["ref_y"]
        v = _displacement(np.asarray(tx, float), np.asarray(x, float), np.asarray(y, float), edges) / block
    if np.isfinite(v).any():
        v_ideal = radius * 0.5 * (wl + wr)
    else:  # no usable reference: the yaw alone
        v, v_ideal = np.zeros(n), np.zeros(n)
    moved, ideal = np.hypot(v, half * wz), np.hypot(v_ideal, turn_ideal)
    ok = np.isfinite(moved) & np.isfinite(ideal)
    total = float(np.sum(ideal[ok]))
    return float(np.sum(moved[ok])) / total if total > 0 else math.nan


def run_series(run: Any) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A measured :class:`bench.run.Run`'s channels for :func:`motion_ratio`, the samples the residual space keeps
    (:func:`bench.gap.residuals.measured_channels`: pose rows the reference sensor reported, wheel speeds not held by
    the logger), so that a step measures the same here as in :func:`space_series`."""
    return {c: v for c, v in measured_channels(run).items() if c in ("enc_wl", "enc_wr", "imu_gz", "ref_x", "ref_y")}


def space_series(space: Any, raw: Mapping[str, np.ndarray] | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A residual space's measured channels (``raw`` None) or a model's, ``measured - raw`` (the model's pose as
    aligned by :meth:`bench.gap.residuals.ResidualSpace.raw`), for :func:`motion_ratio`."""
    out = {}
    for c in ("enc_wl", "enc_wr", "imu_gz", "ref_x", "ref_y"):
        if c in space.channels:
            out[c] = (space.t[c], space.meas[c] if raw is None else space.meas[c] - raw[c])
    return out


def spin_like_steps(w: Any, steps: Sequence[int]) -> list[int]:
    """The ``steps`` (``calib_step`` ids of a DRIVE window table ``w``) commanded like a spin: the mean over the
    step's windows of the commanded half-sum ``(w_l + w_r)/2`` is under :data:`SPIN_SHARE` of the half-difference
    ``(w_r - w_l)/2``, and that above :data:`SPIN_MIN` rad/s."""
    step, cmd_l, cmd_r = np.asarray(w.calib_step), np.asarray(w["cmd_wl"]), np.asarray(w["cmd_wr"])
    out = []
    for s in steps:
        rows = step == s
        if not rows.any():
            continue
        cl, cr = float(np.nanmean(cmd_l[rows])), float(np.nanmean(cmd_r[rows]))
        half_sum, half_diff = 0.5 * (cl + cr), 0.5 * (cr - cl)
        if abs(half_diff) > SPIN_MIN and abs(half_sum) < SPIN_SHARE * abs(half_diff):
            out.append(int(s))
    return out


def stall_summary(steps: Sequence[int], measured: Sequence[float], model: Sequence[float],
                  cost_nominal: Sequence[float], cost_final: Sequence[float],
                  threshold: float = STALL_RATIO) -> dict[str, Any]:
    """Held-out steps whose measured motion ratio is below ``threshold``: their ids, the model's ratio on them
    (median, and how many of them the model stalls on too), their share of the summed final cost, and the final /
    nominal ratio of the mean costs over the steps measured not to stall (NaN without any); a step whose ratio is
    not measured (NaN) is in neither group, counted in ``n_unmeasured``."""
    meas, mod = np.asarray(measured, float), np.asarray(model, float)
    c0, c1 = np.asarray(cost_nominal, float), np.asarray(cost_final, float)
    stalled = meas < threshold
    rest = meas >= threshold
    return {"threshold": threshold, "steps": [int(s) for s, k in zip(steps, stalled) if k],
            "model_stalls": int(np.sum(stalled & (mod < threshold))), "n_unmeasured": int(np.sum(np.isnan(meas))),
            "measured_median": float(np.median(meas[stalled])) if stalled.any() else math.nan,
            "model_median": float(np.nanmedian(mod[stalled])) if stalled.any() and np.isfinite(mod[stalled]).any()
            else math.nan,
            "share_of_final_cost": float(c1[stalled].sum() / c1.sum()) if c1.sum() > 0 else math.nan,
            "others_final_over_nominal": float(c1[rest].mean() / c0[rest].mean()) if rest.any() and c0[rest].mean() > 0
            else math.nan,
            "n_others": int(rest.sum())}
