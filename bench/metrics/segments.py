"""Mandow et al. 2007 segment errors (Sec. III, eq. (13) and Table III) and re-anchored window errors.

The path is cut into short segments at the external-sensor samples; each segment is dead-reckoned
from the *reference* pose at its start by a :class:`SegmentDeadReckoner` (a method's kinematic model,
:func:`velocity_reckoner` for body velocities, :func:`trajectory_reckoner` for an estimated
trajectory); :func:`segment_errors` gives the mean squared errors of (Delta x, Delta y, Delta phi)
and ``J``, their sum.  :func:`window_end_errors`: position/heading error at the end of fixed windows
after re-anchoring the estimate at the reference pose at each window start.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from bench.metrics.position import _interp_planar
from bench.metrics.trajectory import MetricError, Trajectory
from bench.run import wrap_angle

__all__ = ["SegmentDeadReckoner", "velocity_reckoner", "trajectory_reckoner", "SegmentErrors",
           "segment_errors", "WindowErrors", "window_end_errors"]


class SegmentDeadReckoner(Protocol):
    """Dead-reckons many segments at once (the signature a method provides for Mandow's test).

    ``t0``, ``t1``: (N,) segment start/end times; ``pose0``: (N, 3) start poses (x, y, yaw) --
    the *reference* poses at ``t0``.  Returns (N, 3) end poses (x, y, yaw) with yaw continuous
    (``yaw0`` + integrated rotation, not wrapped).  The implementation integrates its kinematic
    model over the internal readings in [t0, t1] (Mandow 2007 Sec. III, "integrating (6) with
    (7)"); :func:`velocity_reckoner` builds one from body velocities."""

    def __call__(self, t0: np.ndarray, t1: np.ndarray, pose0: np.ndarray) -> np.ndarray: ...


def _compose(pose0: np.ndarray, dx: np.ndarray, dy: np.ndarray, dyaw: np.ndarray) -> np.ndarray:
    """pose0 (+) (dx, dy, dyaw) with (dx, dy) in the frame of pose0."""
    c, s = np.cos(pose0[:, 2]), np.sin(pose0[:, 2])
    return np.stack([pose0[:, 0] + c * dx - s * dy, pose0[:, 1] + s * dx + c * dy, pose0[:, 2] + dyaw], axis=1)


def _relative(xa, ya, yawa, xb, yb, yawb) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a^-1 b) as (dx, dy in a's frame, dyaw)."""
    c, s = np.cos(yawa), np.sin(yawa)
    ddx, ddy = xb - xa, yb - ya
    return c * ddx + s * ddy, -s * ddx + c * ddy, yawb - yawa


def velocity_reckoner(t: ArrayLike, vx: ArrayLike, vy: ArrayLike, wz: ArrayLike) -> SegmentDeadReckoner:
    """Exact zero-order-hold SE(2) dead reckoning of body velocities sampled at ``t`` (the
    velocity at ``t[k]`` holds on [t[k], t[k+1]), as :func:`bench.kinematics.integrate_se2`),
    for segments starting and ending at any time inside [t[0], t[-1]].

    Integrates once (``integrate_se2``) and takes relative motions, which equals integrating
    each segment from its own start pose (SE(2) integration is left-invariant)."""
    from bench.kinematics import integrate_se2

    t = np.asarray(t, float)
    vx, vy, wz = (np.asarray(a, float) for a in (vx, vy, wz))
    if not (np.all(np.isfinite(vx)) and np.all(np.isfinite(vy)) and np.all(np.isfinite(wz))):
        raise MetricError("velocity_reckoner: non-finite velocity samples (drop them first)")
    px, py, pyaw = integrate_se2(t, vx, vy, wz)

    def pose_at(tq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if np.any((tq < t[0]) | (tq > t[-1])):
            raise MetricError(f"segment time outside the dead-reckoned span [{t[0]}, {t[-1]}]")
        k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 1)
        tau = tq - t[k]
        d = wz[k] * tau
        small = np.abs(d) < 1e-9
        safe = np.where(small, 1.0, d)
        s = np.where(small, 1.0 - d * d / 6.0, np.sin(safe) / safe)
        c = np.where(small, d / 2.0, (1.0 - np.cos(safe)) / safe)
        dxb = (s * vx[k] - c * vy[k]) * tau
        dyb = (c * vx[k] + s * vy[k]) * tau
        cy, sy = np.cos(pyaw[k]), np.sin(pyaw[k])
        return px[k] + cy * dxb - sy * dyb, py[k] + sy * dxb + cy * dyb, pyaw[k] + d

    def reckon(t0: np.ndarray, t1: np.ndarray, pose0: np.ndarray) -> np.ndarray:
        a, b = pose_at(np.asarray(t0, float)), pose_at(np.asarray(t1, float))
        return _compose(np.asarray(pose0, float).reshape(-1, 3), *_relative(*a, *b))

    return reckon


def trajectory_reckoner(traj: Trajectory) -> SegmentDeadReckoner:
    """Re-anchoring of an estimated trajectory: the segment's end pose is the start pose
    composed with the estimate's relative motion between t0 and t1 (poses interpolated
    linearly, yaw unwrapped)."""

    def reckon(t0: np.ndarray, t1: np.ndarray, pose0: np.ndarray) -> np.ndarray:
        a = _interp_planar(traj, np.asarray(t0, float))
        b = _interp_planar(traj, np.asarray(t1, float))
        return _compose(np.asarray(pose0, float).reshape(-1, 3), *_relative(*a, *b))

    return reckon


@dataclass(frozen=True, eq=False)
class SegmentErrors:
    """Per-segment errors (reference increment minus dead-reckoned increment) and Mandow's
    Table III means.  ``dx``, ``dy`` are in the world frame (``frame="world"``) or in the frame of
    the segment's start pose (``frame="start"``: x forward, y left -- Mandow's X lateral / Y
    forward are our -y / x)."""

    t0: np.ndarray
    t1: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    dphi: np.ndarray
    frame: str = "start"

    @property
    def n(self) -> int:
        return int(self.t0.size)

    @property
    def ms_dx(self) -> float:
        return float(np.mean(self.dx ** 2))

    @property
    def ms_dy(self) -> float:
        return float(np.mean(self.dy ** 2))

    @property
    def ms_dphi(self) -> float:
        return float(np.mean(self.dphi ** 2))

    @property
    def J(self) -> float:
        """Mean of eq. (13)'s summand: ms_dx + ms_dy + ms_dphi (Table III 'mean squared J')."""
        return self.ms_dx + self.ms_dy + self.ms_dphi

    def as_dict(self) -> dict[str, float]:
        return {"n": self.n, "ms_dx": self.ms_dx, "ms_dy": self.ms_dy, "ms_dphi": self.ms_dphi, "J": self.J}


def _segment_bounds(ref: Trajectory, every: int, duration: float | None, step: float | None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Start indices into ``ref`` and end times."""
    t = ref.t
    if duration is None:
        if every < 1:
            raise MetricError(f"segment length must be >= 1 reference sample, got {every}")
        starts = np.arange(0, t.size - every, every)
        return starts, t[starts + every]
    if not duration > 0:
        raise MetricError(f"segment duration must be > 0, got {duration}")
    step = duration if step is None else step
    grid = t[0] + step * np.arange(int(np.floor((t[-1] - t[0]) / step)) + 1)
    starts = np.unique(np.searchsorted(t, grid - 1e-9 * max(1.0, step), side="left"))
    starts = starts[starts < t.size]
    t1 = t[starts] + duration
    keep = t1 <= t[-1] + 1e-12
    return starts[keep], t1[keep]


def segment_errors(ref: Trajectory, reckoner: SegmentDeadReckoner | Trajectory, *, every: int = 1,
                   duration: float | None = None, step: float | None = None, frame: str = "start"
                   ) -> SegmentErrors:
    """Mandow 2007 eq. (13) segment errors.

    Segments run between consecutive reference samples (``every`` samples long, not
    overlapping), or last ``duration`` seconds with starts every ``step`` seconds (default
    ``duration``) snapped to the next reference sample.  Each segment is dead-reckoned from the
    reference pose at its start; the reference increment comes from the reference pose at the
    end (interpolated when the end is between samples).  Delta phi errors are wrapped to
    [-pi, pi).  ``frame="start"`` (default, as ``methods.mandow2007``) expresses the (dx, dy)
    errors in the frame of the segment's reference start pose; ``"world"`` in the world frame
    (dx^2 + dy^2 is the same in both)."""
    if frame not in ("world", "start"):
        raise MetricError(f"frame '{frame}' unknown; expected 'world' or 'start'")
    if isinstance(reckoner, Trajectory):
        reckoner = trajectory_reckoner(reckoner)
    starts, t1 = _segment_bounds(ref, every, duration, step)
    if starts.size == 0:
        raise MetricError(f"reference '{ref.name}' too short for one segment")
    t0 = ref.t[starts]
    yaw_ref = np.unwrap(ref.yaw)
    pose0 = np.stack([ref.x[starts], ref.y[starts], yaw_ref[starts]], axis=1)
    xe, ye, yawe = (np.interp(t1, ref.t, a) for a in (ref.x, ref.y, yaw_ref))
    end = np.asarray(reckoner(t0, t1, pose0), float).reshape(-1, 3)
    dx_ref, dy_ref = xe - pose0[:, 0], ye - pose0[:, 1]
    dx_est, dy_est = end[:, 0] - pose0[:, 0], end[:, 1] - pose0[:, 1]
    ex, ey = dx_ref - dx_est, dy_ref - dy_est
    if frame == "start":
        c, s = np.cos(pose0[:, 2]), np.sin(pose0[:, 2])
        ex, ey = c * ex + s * ey, -s * ex + c * ey
    dphi = np.asarray(wrap_angle((yawe - pose0[:, 2]) - (end[:, 2] - pose0[:, 2])))
    return SegmentErrors(t0, t1, ex, ey, dphi, frame)


@dataclass(frozen=True, eq=False)
class WindowErrors:
    """Errors at the end of re-anchored windows: position [m] and |heading| [rad]."""

    t0: np.ndarray
    position: np.ndarray
    heading: np.ndarray
    window: float

    def as_dict(self) -> dict[str, float]:
        p, h = self.position, self.heading
        return {"n": int(p.size), "window": self.window,
                "pos_mean": float(np.mean(p)), "pos_median": float(np.median(p)),
                "pos_p95": float(np.percentile(p, 95)),
                "yaw_mean": float(np.mean(h)), "yaw_median": float(np.median(h)),
                "yaw_p95": float(np.percentile(h, 95))}


def window_end_errors(ref: Trajectory, est: Trajectory | SegmentDeadReckoner, window: float = 2.0,
                      step: float | None = None) -> WindowErrors:
    """Re-anchor the estimate (relative motion of a trajectory, or a dead-reckoner) at the
    reference pose at each window start (starts every ``step`` s, default ``window``), and
    measure the position and heading error ``window`` seconds later."""
    span_end = ref.t[-1]
    if isinstance(est, Trajectory):
        span_end = min(span_end, est.t[-1])
        ref_c = ref.take(np.flatnonzero((ref.t >= est.t[0]) & (ref.t <= span_end)))
    else:
        ref_c = ref
    if len(ref_c) < 2:
        raise MetricError(f"reference '{ref.name}' has fewer than two samples in the estimate's span")
    seg = segment_errors(ref_c, est, duration=window, step=step, frame="world")
    if seg.n == 0:
        raise MetricError(f"no {window} s window fits in the reference '{ref.name}'")
    return WindowErrors(seg.t0, np.hypot(seg.dx, seg.dy), np.abs(seg.dphi), window)
