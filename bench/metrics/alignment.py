"""Alignment of an estimate onto the reference before a metric (evo's ``-a``, ``-as``, ``-s``,
``--align_origin``, plus a planar ``se2``): Umeyama 1991 least-squares similarity, eqs. (34)-(43).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from bench.metrics.trajectory import MetricError, Trajectory

__all__ = ["ALIGNMENTS", "Alignment", "umeyama", "align"]


ALIGNMENTS = ("none", "se2", "se3", "sim3", "scale", "origin")


@dataclass(frozen=True, eq=False)
class Alignment:
    """Similarity applied to the estimate: ``p' = scale * R p + t``, ``R' = R R_est``
    (``scale_only``: ``p' = scale * p``, rotations unchanged, as evo's ``-s``)."""

    mode: str = "none"
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float = 1.0

    def apply(self, traj: Trajectory) -> Trajectory:
        if self.mode == "none":
            return traj
        r, t, s = self.rotation, self.translation, self.scale
        xyz = s * traj.xyz @ r.T + t
        rot = r @ traj.rot
        return Trajectory(traj.t, xyz, rot, traj.name)

    def matrix(self) -> np.ndarray:
        """4x4 Sim(3) matrix (evo ``alignment_transformation_sim3``)."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.translation
        return m


def umeyama(src: ArrayLike, dst: ArrayLike, with_scale: bool = False
            ) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares similarity ``dst ~ c R src + t`` (Umeyama 1991, eqs. (34)-(43)).

    ``src``, ``dst``: (n, m) points.  Returns (R (m, m), t (m,), c).  Raises
    :class:`MetricError` when the covariance has rank < m - 1 (degenerate, as evo)."""
    x, y = np.asarray(src, float), np.asarray(dst, float)
    if x.shape != y.shape or x.ndim != 2:
        raise MetricError(f"umeyama: point sets of shapes {x.shape} and {y.shape} differ")
    n, m = x.shape
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    sigma_x = np.sum(xc * xc) / n  # eq. (36)
    cov = yc.T @ xc / n  # eq. (38)
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < m - 1:
        raise MetricError("degenerate covariance rank: Umeyama alignment is not possible "
                          "(too few or coincident poses)")
    s = np.ones(m)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[-1] = -1.0  # eq. (43): proper rotation
    r = (u * s) @ vt  # eq. (40)
    c = float(np.sum(d * s) / sigma_x) if with_scale else 1.0  # eq. (42)
    t = my - c * (r @ mx)  # eq. (41)
    return r, t, c


def align(ref: Trajectory, est: Trajectory, mode: str = "se3", n_to_align: int = -1) -> Alignment:
    """Alignment of ``est`` onto ``ref`` (synchronised, same length); modes in :data:`ALIGNMENTS`."""
    if mode not in ALIGNMENTS:
        raise MetricError(f"alignment '{mode}' unknown; expected one of {ALIGNMENTS}")
    if mode == "none":
        return Alignment()
    if len(ref) != len(est):
        raise MetricError(f"alignment needs synchronised trajectories ({len(ref)} vs {len(est)} poses)")
    if len(est) == 0:
        raise MetricError("cannot align an empty trajectory")
    if mode == "origin":
        r = ref.rot[0] @ est.rot[0].T
        return Alignment("origin", r, ref.xyz[0] - r @ est.xyz[0], 1.0)
    k = slice(None) if n_to_align == -1 else slice(0, n_to_align)
    if mode == "se2":
        r2, t2, _ = umeyama(est.xyz[k, :2], ref.xyz[k, :2], False)
        r = np.eye(3)
        r[:2, :2] = r2
        return Alignment("se2", r, np.array([t2[0], t2[1], 0.0]), 1.0)
    r, t, c = umeyama(est.xyz[k], ref.xyz[k], mode in ("sim3", "scale"))
    if mode == "scale":
        return Alignment("scale", np.eye(3), np.zeros(3), c)
    return Alignment(mode, r, t, c)
