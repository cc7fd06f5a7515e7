"""Position errors against the reference, no alignment: the RMS over time (Liu et al. 2020,
Table 2: "the GNSS position is regarded as the reference") and the error at the last common sample;
the estimate is interpolated linearly at the reference timestamps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.metrics.trajectory import MetricError, Trajectory

__all__ = ["Divergence", "divergence", "position_errors", "position_rms", "final_position_error"]

DIVERGENCE_FLOOR = 1.0  # [m] the smallest error bound of :func:`divergence` (a protocol choice: near the start the path
# length is ~0 and an error of a few cm would otherwise count)


def _interp_planar(traj: Trajectory, tq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, yaw (continuous, unwrapped) at ``tq``, linear; NaN outside the time span."""
    yaw = np.unwrap(traj.yaw)
    out = [np.interp(tq, traj.t, a, left=np.nan, right=np.nan) for a in (traj.x, traj.y, yaw)]
    return out[0], out[1], out[2]


def position_errors(ref: Trajectory, est: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """(t, |p_est - p_ref|) at the reference timestamps inside the estimate's time span; the
    estimate is interpolated linearly; no alignment."""
    x, y, _ = _interp_planar(est, ref.t)
    m = np.isfinite(x)
    return ref.t[m], np.hypot(x[m] - ref.x[m], y[m] - ref.y[m])


def position_rms(ref: Trajectory, est: Trajectory) -> float:
    """RMS over time of the position error (Liu et al. 2020 Table 2)."""
    _, e = position_errors(ref, est)
    if e.size == 0:
        raise MetricError(f"no reference sample of '{ref.name}' inside the time span of '{est.name}'")
    return float(np.sqrt(np.mean(e * e)))


def final_position_error(ref: Trajectory, est: Trajectory) -> float:
    """Position error at the last reference sample inside the estimate's time span."""
    _, e = position_errors(ref, est)
    if e.size == 0:
        raise MetricError(f"no reference sample of '{ref.name}' inside the time span of '{est.name}'")
    return float(e[-1])


@dataclass(frozen=True)
class Divergence:
    """Where an estimate first left the bound of :func:`divergence`: time [s], the reference sample's index, the
    error and the bound there [m]."""

    t: float
    step: int
    error: float
    bound: float


def divergence(ref: Trajectory, est: Trajectory, floor: float = DIVERGENCE_FLOOR) -> Divergence | None:
    """Where the estimate diverged for good: the first reference sample of the excursion past the bound
    ``max(s(t), floor)`` that lasts to the end of the estimate (``s(t)``: the path length the reference has travelled
    since its first sample; the error as :func:`position_errors`: no alignment, the estimate interpolated at the
    reference stamps); None when the estimate ends inside the bound (a transient excursion that comes back is an
    error, not a divergence).

    A dead-reckoned estimate whose speeds are right is at most ``2 s(t)`` off, and only when it went the opposite
    way: past ``s(t)`` the estimate is farther from the robot than the robot is from its start, i.e. it says
    nothing about where the robot is.  Such an estimate is a divergence to report, not an error to average."""
    if not (np.isfinite(floor) and floor > 0):
        raise MetricError(f"divergence: floor = {floor!r} must be finite and > 0 [m]")
    x, y, _ = _interp_planar(est, ref.t)
    path = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(ref.x), np.diff(ref.y)))))
    err = np.hypot(x - ref.x, y - ref.y)
    bound = np.maximum(path, floor)
    idx = np.flatnonzero(np.isfinite(err))
    if idx.size == 0 or not err[idx[-1]] > bound[idx[-1]]:
        return None
    inside = idx[err[idx] <= bound[idx]]
    i = int(idx[0]) if inside.size == 0 else int(idx[np.searchsorted(idx, inside[-1], side="right")])
    return Divergence(float(ref.t[i]), i, float(err[i]), float(bound[i]))
