"""Position errors against the reference, no alignment: the RMS over time (Liu et al. 2020,
Table 2: "the GNSS position is regarded as the reference") and the error at the last common sample;
the estimate is interpolated linearly at the reference timestamps.
"""
from __future__ import annotations

import numpy as np

from bench.metrics.trajectory import MetricError, Trajectory

__all__ = ["position_errors", "position_rms", "final_position_error"]


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
