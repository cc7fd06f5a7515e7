"""Timestamped poses and their time association (evo's semantics, see :mod:`bench.metrics`).

:class:`Trajectory` (N poses: ``t``, positions ``xyz``, rotations ``rot``; from a Run's pose
channels or an Estimate), :func:`interpolate` (positions linear, orientations slerp, no
extrapolation) and :func:`associate` (evo ``sync.associate_trajectories``: nearest stamps within
``max_diff``, or interpolation of the longer trajectory).  :class:`MetricError` is the error of
every metric.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from bench.run import Run

__all__ = ["MetricError", "Trajectory", "interpolate", "associate"]


class MetricError(ValueError):
    """A metric cannot be computed (too few poses, no matching timestamps, degenerate alignment)."""


# ------------------------------------------------------------------------------------------
# Trajectory
# ------------------------------------------------------------------------------------------
def _tmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched a^T b for (n, 3, 3) stacks (matmul: faster than einsum here)."""
    return np.swapaxes(a, -1, -2) @ b


def _rot_z(yaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    r = np.zeros(yaw.shape + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 1, 0], r[..., 1, 1], r[..., 2, 2] = c, -s, s, c, 1.0
    return r


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Timestamped poses: ``t`` (N,), positions ``xyz`` (N, 3), rotations ``rot`` (N, 3, 3)."""

    t: np.ndarray
    xyz: np.ndarray
    rot: np.ndarray
    name: str = ""

    def __post_init__(self) -> None:
        t = np.asarray(self.t, float).reshape(-1)
        xyz = np.asarray(self.xyz, float).reshape(-1, 3)
        rot = np.asarray(self.rot, float).reshape(-1, 3, 3)
        if not (t.size == xyz.shape[0] == rot.shape[0]):
            raise MetricError(f"trajectory '{self.name}': t, xyz, rot lengths differ "
                              f"({t.size}, {xyz.shape[0]}, {rot.shape[0]})")
        for label, a in (("t", t), ("position", xyz), ("rotation", rot)):
            if not np.all(np.isfinite(a)):
                raise MetricError(f"trajectory '{self.name}': non-finite {label} values")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "rot", rot)

    # constructors ---------------------------------------------------------------------------
    @classmethod
    def planar(cls, t: ArrayLike, x: ArrayLike, y: ArrayLike, yaw: ArrayLike,
               z: ArrayLike | float = 0.0, name: str = "") -> "Trajectory":
        t = np.asarray(t, float)
        x, y, yaw = (np.broadcast_to(np.asarray(a, float), t.shape) for a in (x, y, yaw))
        z = np.broadcast_to(np.asarray(z, float), t.shape)
        return cls(t, np.stack([x, y, z], axis=1), _rot_z(yaw), name)

    @classmethod
    def from_run(cls, run: Run, source: str = "truth") -> "Trajectory":
        """Pose channels ``{source}_x, _y, _yaw`` of a Run (``truth``, ``ref`` or ``gnss``) at
        the rows where all three are finite (``truth_z`` used when present)."""
        cols = [f"{source}_x", f"{source}_y", f"{source}_yaw"]
        x, y, yaw = (run[c] for c in cols)
        m = np.isfinite(x) & np.isfinite(y) & np.isfinite(yaw)
        z = run[f"{source}_z"][m] if f"{source}_z" in run.channels else 0.0
        if not m.any():
            raise MetricError(f"{run.where}: no finite {source} pose sample")
        return cls.planar(run.t[m], x[m], y[m], yaw[m], z, name=f"{run.id}:{source}")

    @classmethod
    def from_estimate(cls, est: Any) -> "Trajectory":
        """From a :class:`bench.registry.Estimate` (rows with finite x, y, yaw)."""
        x, y, yaw, t = est["x"], est["y"], est["yaw"], est["t"]
        m = np.isfinite(x) & np.isfinite(y) & np.isfinite(yaw) & np.isfinite(t)
        return cls.planar(t[m], x[m], y[m], yaw[m], name=getattr(est, "method", "") or "estimate")

    # access ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def x(self) -> np.ndarray:
        return self.xyz[:, 0]

    @property
    def y(self) -> np.ndarray:
        return self.xyz[:, 1]

    @property
    def yaw(self) -> np.ndarray:
        """Heading (rotation about z) in [-pi, pi]; meaningful for planar rotations."""
        return np.arctan2(self.rot[:, 1, 0], self.rot[:, 0, 0])

    def take(self, idx: ArrayLike) -> "Trajectory":
        idx = np.asarray(idx)
        return Trajectory(self.t[idx], self.xyz[idx], self.rot[idx], self.name)

    def with_t(self, t: ArrayLike) -> "Trajectory":
        return Trajectory(np.asarray(t, float), self.xyz, self.rot, self.name)

    def path_lengths(self) -> np.ndarray:
        """Accumulated travelled distance at each pose (evo ``accumulated_distances``)."""
        return np.concatenate(([0.0], np.cumsum(np.linalg.norm(self.xyz[:-1] - self.xyz[1:], axis=1))))




# ------------------------------------------------------------------------------------------
# Time association / interpolation
# ------------------------------------------------------------------------------------------
def interpolate(traj: Trajectory, tq: ArrayLike) -> Trajectory:
    """Poses at ``tq``: positions linear, orientations slerp (shortest arc); times outside the
    trajectory's span are clamped to the first/last pose (evo ``interpolate``, no extrapolation)."""
    tq = np.atleast_1d(np.asarray(tq, float))
    n = len(traj)
    if n < 2:
        raise MetricError(f"trajectory '{traj.name}': cannot interpolate with fewer than two poses")
    idx = np.clip(np.searchsorted(traj.t, tq, side="left"), 1, n - 1)
    t0, t1 = traj.t[idx - 1], traj.t[idx]
    dt = t1 - t0
    frac = np.where(dt > 0.0, (tq - t0) / np.where(dt > 0.0, dt, 1.0), 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    xyz = traj.xyz[idx - 1] + frac[:, None] * (traj.xyz[idx] - traj.xyz[idx - 1])
    r0 = traj.rot[idx - 1]
    rel = Rotation.from_matrix(_tmul(r0, traj.rot[idx])).as_rotvec()
    rot = r0 @ Rotation.from_rotvec(frac[:, None] * rel).as_matrix()
    return Trajectory(tq, xyz, rot, traj.name)


def _match_nearest(short: np.ndarray, long: np.ndarray, max_diff: float) -> tuple[np.ndarray, np.ndarray]:
    """evo ``matching_time_indices`` for sorted ``long`` (vectorised)."""
    if long.size == 0 or short.size == 0:
        return np.zeros(0, int), np.zeros(0, int)
    inside = (short >= long[0] - max_diff) & (short <= long[-1] + max_diff)
    idx = np.minimum(np.searchsorted(long, short, side="right"), long.size - 1)
    diff_ub = long[idx] - short
    diff_lb = np.where(idx > 0, short - long[np.maximum(idx - 1, 0)], np.inf)
    take_ub = (diff_ub <= max_diff) & (diff_ub < diff_lb)
    take_lb = ~take_ub & (diff_lb <= max_diff) & (diff_lb <= diff_ub)
    ok = inside & (take_ub | take_lb)
    best = np.where(take_ub, idx, idx - 1)
    return np.flatnonzero(ok), best[ok]


def associate(ref: Trajectory, est: Trajectory, max_diff: float = 0.01, offset: float = 0.0,
              method: str = "nearest") -> tuple[Trajectory, Trajectory]:
    """Synchronise (evo ``associate_trajectories``): returns (ref, est) with equal pose counts.

    The trajectory with fewer poses (``est`` on a tie) keeps the matched subset of its own
    poses; the other is reduced to its nearest poses (``method="nearest"``) or interpolated at
    the matched stamps (``method="interpolate"``).  ``offset`` is added to the estimate's stamps
    for matching only (evo ``--t_offset``)."""
    if method not in ("nearest", "interpolate"):
        raise MetricError(f"sync method '{method}' unknown; expected 'nearest' or 'interpolate'")
    for tr in (ref, est):
        if len(tr) and np.any(np.diff(tr.t) < 0):
            raise MetricError(f"trajectory '{tr.name}': timestamps are not sorted")
    second_longer = len(est) > len(ref)
    short, long = (ref, est) if second_longer else (est, ref)
    off = offset if second_longer else -offset
    i_short, i_long = _match_nearest(short.t, long.t + off, max_diff)
    if i_short.size == 0:
        raise MetricError(
            f"found no matching timestamps between '{ref.name or 'reference'}' and "
            f"'{est.name or 'estimate'}' with max. time diff {max_diff} (s) and offset {offset} (s)")
    short = short.take(i_short)
    long = interpolate(long, short.t - off) if method == "interpolate" else long.take(i_long)
    return (short, long) if second_longer else (long, short)
