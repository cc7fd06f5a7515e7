"""Trajectory and velocity error metrics.

Two families:

1. **evo-compatible APE/RPE** (Grupp, *evo: Python package for the evaluation of odometry and
   SLAM*, https://github.com/MichaelGrupp/evo, v1.38).  The definitions below reproduce evo's
   numbers (checked to 1e-9 by ``tests/test_metrics.py``, which runs evo itself); evo is GPLv3
   and is **never imported here** -- this is an independent, vectorised implementation of the
   published definitions:

   * APE (Kuemmerle et al. 2009 / evo ``metrics.APE``): per synchronised pose,
     ``E_i = P_i^-1 Q_i`` (``P`` estimate, ``Q`` reference); translation part = ``|p_i - q_i|``.
   * RPE (Sturm et al. 2012, TUM RGB-D / evo ``metrics.RPE``): for index pairs ``(i, j)``,
     ``E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``.  Pairs come from the *estimate* poses by default
     (evo's ``pairs_from_reference=False``), after alignment.
   * Pose relations (evo ``PoseRelation``): ``translation`` (``trans_part``, m),
     ``rotation_angle_rad`` / ``rotation_angle_deg`` (``angle_rad`` / ``angle_deg``: the angle of
     the rotation part's logarithm, in [0, pi]), ``rotation_part`` (``rot_part``: the
     dimension-less Frobenius norm ``|R_E - I|``, *not* an angle), ``full`` (``|E - I_4|``),
     ``point_distance`` and ``point_distance_error_ratio`` (RPE only, %).
   * Alignment (applied to the estimate before the metric, as evo): ``none``; ``se3`` (evo
     ``-a``: Umeyama 1991 rotation + translation on the 3-D positions); ``sim3`` (evo ``-as``:
     Umeyama with scale); ``scale`` (evo ``-s`` alone: scale only); ``origin`` (evo
     ``--align_origin``); and ``se2`` (not in evo: planar Umeyama on x, y only -- a rotation
     about z and an x/y translation; z is left untouched).  For planar data the 3-D ``se3``
     Umeyama may return a 180 deg flip about a horizontal axis when the best 2-D fit is a
     reflection (nearly collinear paths); ``se2`` never does.
   * Statistics (evo ``get_all_statistics``): rmse, mean, median, std (population), min, max,
     sse.
   * Time association (:func:`associate`) follows evo's ``sync.associate_trajectories``: the
     trajectory with fewer poses keeps its timestamps; each of them is matched to the nearest
     stamp of the other within ``max_diff`` (default 0.01 s, ties to the earlier stamp), or, with
     ``method="interpolate"``, the longer trajectory is resampled at the matched stamps
     (positions linearly, orientations by slerp, no extrapolation).  Unmatched poses are
     dropped.  :func:`ape` and :func:`rpe` associate first unless ``max_diff=None`` (inputs
     already synchronised, equal length).

2. **Skid-steer metrics** used by the papers:

   * :func:`position_rms` -- RMS over time of the Euclidean position error against the
     reference, no alignment (Liu et al. 2020, Table 2: "the GNSS position is regarded as the
     reference"); the estimate is interpolated linearly at the reference timestamps.
   * :func:`final_position_error` -- position error at the last common reference sample.
   * :func:`velocity_rms` -- RMS per body-velocity channel (vx, vy, wz) against truth.
   * :func:`segment_errors` -- Mandow et al. 2007 Sec. III eq. (13) and Table III: the path is
     cut into N short segments at the external-sensor samples; each segment is dead-reckoned
     from the *reference* pose at its start; mean squared errors of (Delta x, Delta y,
     Delta phi) and ``J`` = their sum.  The dead reckoning is a callable (see
     :class:`SegmentDeadReckoner`), so a method plugs in its own kinematic model.
   * :func:`window_end_errors` -- position/heading error at the end of fixed windows (2 s by
     default) after re-anchoring the estimate at the reference pose at each window start:
     mean, median and 95th percentile.

Conventions: world ENU, yaw CCW, SI units (DESIGN.md).  Everything is vectorised with numpy; the
only Python loops run over RPE pairs in the path/angle ``delta_unit`` modes (evo's
accumulate-and-reset rule is sequential), never over samples.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from bench.run import Run, wrap_angle

__all__ = [
    "MetricError", "Trajectory", "Stats", "statistics", "Alignment", "umeyama", "align",
    "associate", "interpolate", "ErrorResult", "ape", "rpe", "rpe_pairs",
    "position_errors", "position_rms", "final_position_error", "velocity_rms",
    "SegmentDeadReckoner", "velocity_reckoner", "trajectory_reckoner", "SegmentErrors",
    "segment_errors", "WindowErrors", "window_end_errors", "summary",
]


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
# Statistics
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Stats:
    """evo's ``get_all_statistics``: rmse, mean, median, std (population), min, max, sse."""

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    sse: float

    def as_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ("rmse", "mean", "median", "std", "min", "max", "sse")}


def statistics(errors: ArrayLike) -> Stats:
    e = np.asarray(errors, float)
    if e.size == 0:
        raise MetricError("no error values: cannot compute statistics")
    sq = e * e
    return Stats(
        rmse=float(np.sqrt(np.mean(sq))), mean=float(np.mean(e)), median=float(np.median(e)),
        std=float(np.std(e)), min=float(np.min(e)), max=float(np.max(e)), sse=float(np.sum(sq)),
    )


# ------------------------------------------------------------------------------------------
# Alignment
# ------------------------------------------------------------------------------------------
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


# ------------------------------------------------------------------------------------------
# APE / RPE
# ------------------------------------------------------------------------------------------
_RELATION_ALIASES = {
    "trans_part": "translation", "translation_part": "translation", "translation": "translation",
    "angle_rad": "rotation_angle_rad", "rotation_angle_rad": "rotation_angle_rad",
    "angle_deg": "rotation_angle_deg", "rotation_angle_deg": "rotation_angle_deg",
    "rot_part": "rotation_part", "rotation_part": "rotation_part",
    "full": "full", "full_transformation": "full",
    "point_distance": "point_distance", "point_distance_error_ratio": "point_distance_error_ratio",
}
_UNITS = {"translation": "m", "point_distance": "m", "rotation_angle_rad": "rad",
          "rotation_angle_deg": "deg", "rotation_part": "", "full": "", "point_distance_error_ratio": "%"}


def _relation(name: str) -> str:
    try:
        return _RELATION_ALIASES[name]
    except KeyError:
        raise MetricError(f"pose relation '{name}' unknown; expected one of "
                          f"{sorted(set(_RELATION_ALIASES))}") from None


def _so3_angle(r: np.ndarray) -> np.ndarray:
    """Rotation angle in [0, pi] of (..., 3, 3) matrices: atan2(|axis| sin, cos), accurate near
    0 and pi (the arccos of the trace is not)."""
    s = 0.5 * np.sqrt((r[..., 2, 1] - r[..., 1, 2]) ** 2 + (r[..., 0, 2] - r[..., 2, 0]) ** 2
                      + (r[..., 1, 0] - r[..., 0, 1]) ** 2)
    c = 0.5 * (r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2] - 1.0)
    return np.arctan2(s, c)


def _pose_error_values(rel: str, e_rot: np.ndarray, e_t: np.ndarray) -> np.ndarray:
    if rel == "translation":
        return np.linalg.norm(e_t, axis=1)
    if rel == "rotation_angle_rad":
        return _so3_angle(e_rot)
    if rel == "rotation_angle_deg":
        return np.rad2deg(_so3_angle(e_rot))
    d = e_rot - np.eye(3)
    if rel == "rotation_part":
        return np.sqrt(np.einsum("nij,nij->n", d, d))
    if rel == "full":
        return np.sqrt(np.einsum("nij,nij->n", d, d) + np.einsum("ni,ni->n", e_t, e_t))
    raise MetricError(f"pose relation '{rel}' not supported here")


@dataclass(frozen=True, eq=False)
class ErrorResult:
    """Per-pose (APE) or per-pair (RPE) errors with their statistics and provenance."""

    kind: str
    relation: str
    unit: str
    errors: np.ndarray
    t: np.ndarray
    stats: Stats
    alignment: Alignment
    pairs: np.ndarray | None = None
    info: Mapping[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "relation": self.relation, "unit": self.unit,
                "alignment": self.alignment.mode, "scale": self.alignment.scale,
                "n": int(self.errors.size), **self.stats.as_dict(), **dict(self.info)}


def _prepare(ref: Trajectory, est: Trajectory, max_diff: float | None, sync: str, offset: float
             ) -> tuple[Trajectory, Trajectory]:
    if max_diff is not None:
        return associate(ref, est, max_diff, offset, sync)
    if len(ref) != len(est):
        raise MetricError(f"trajectories must have the same number of poses ({len(ref)} vs {len(est)}); "
                          "pass max_diff to associate them by timestamp")
    return ref, est


def ape(ref: Trajectory, est: Trajectory, relation: str = "translation", align_mode: str = "none",
        *, n_to_align: int = -1, max_diff: float | None = 0.01, sync: str = "nearest",
        offset: float = 0.0) -> ErrorResult:
    """Absolute pose error (evo ``main_ape.ape`` after ``associate_trajectories``)."""
    rel = _relation(relation)
    ref, est = _prepare(ref, est, max_diff, sync, offset)
    al = align(ref, est, align_mode, n_to_align)
    est = al.apply(est)
    if rel in ("translation", "point_distance"):
        err = np.linalg.norm(est.xyz - ref.xyz, axis=1)
    elif rel == "point_distance_error_ratio":
        raise MetricError("point_distance_error_ratio is an RPE relation")
    else:
        e_rot = _tmul(est.rot, ref.rot)  # R_est^T R_ref
        e_t = np.einsum("nki,nk->ni", est.rot, ref.xyz - est.xyz)
        err = _pose_error_values(rel, e_rot, e_t)
    return ErrorResult("APE", rel, _UNITS[rel], err, est.t, statistics(err), al,
                       info={"n_synced": len(est)})


def _first_reaching(step: np.ndarray, delta: float) -> np.ndarray:
    """evo's consecutive accumulate-and-reset rule over per-step increments ``step`` (length
    n-1, step k between pose k and k+1): returns the selected pose ids [0, j1, j2, ...].

    The running sum restarts at 0 after each selection and is accumulated sequentially in
    float64 (np.cumsum over a local window), so the comparison with ``delta`` rounds exactly
    as evo's loop; the loop runs once per selected pair, never per sample."""
    cum = np.concatenate(([0.0], np.cumsum(step)))
    n = cum.size
    ids = [0]
    start = 0
    while start < n - 1:
        guess = int(np.searchsorted(cum, cum[start] + delta, side="left"))
        hi = min(n, max(guess + 8, start + 2))
        while True:
            run = np.cumsum(step[start:hi - 1])
            hit = np.flatnonzero(run >= delta)
            if hit.size or hi >= n:
                break
            hi = min(n, start + 2 * (hi - start))
        if not hit.size:
            break
        start = start + 1 + int(hit[0])
        ids.append(start)
    return np.asarray(ids, int)


def rpe_pairs(traj: Trajectory, delta: float, delta_unit: str = "frames", all_pairs: bool = False,
              rel_delta_tol: float = 0.1) -> np.ndarray:
    """Index pairs (M, 2) as evo ``id_pairs_from_delta``.

    ``frames``: consecutive pairs ``(0, d), (d, 2d), ...`` or all ``(i, i + d)``.
    ``m``: travelled path; consecutive pairs accumulate the path from the last selected pose and
    select the first pose where it reaches ``delta``; ``all_pairs`` takes, for every ``i``, the
    later pose whose path distance is closest to ``delta`` (first on ties), kept if within
    ``delta * rel_delta_tol``.  ``deg``/``rad``: accumulated relative rotation angle,
    consecutive pairs only."""
    n = len(traj)
    unit = {"f": "frames", "frames": "frames", "m": "m", "meters": "m", "d": "deg", "deg": "deg",
            "degrees": "deg", "r": "rad", "rad": "rad", "radians": "rad"}.get(delta_unit)
    if unit is None:
        raise MetricError(f"delta_unit '{delta_unit}' unknown; expected frames, m, deg or rad")
    if not np.isfinite(delta) or delta < 0:
        raise MetricError(f"delta must be a positive number, got {delta}")
    if unit == "frames":
        if float(delta) != int(delta):
            raise MetricError(f"delta must be an integer for delta unit frames, got {delta}")
        d = int(delta)
        if d == 0:
            raise MetricError("delta must be >= 1 frame")
        if all_pairs:
            i = np.arange(max(n - d, 0))
            pairs = np.stack([i, i + d], axis=1)
        else:
            ids = np.arange(0, n, d)
            pairs = np.stack([ids[:-1], ids[1:]], axis=1)
    elif unit == "m":
        dist = traj.path_lengths()
        if all_pairs:
            pairs = _all_pairs_by_path(dist, float(delta), float(delta) * rel_delta_tol)
        else:
            ids = _first_reaching(np.linalg.norm(traj.xyz[1:] - traj.xyz[:-1], axis=1), float(delta))
            pairs = np.stack([ids[:-1], ids[1:]], axis=1)
    else:
        if all_pairs:
            raise MetricError("all_pairs with an angular delta is not supported")
        lim = 180.0 if unit == "deg" else np.pi
        if delta > lim:
            raise MetricError(f"delta angle must be within [0, {lim}]")
        drad = np.deg2rad(delta) if unit == "deg" else float(delta)
        step = _so3_angle(_tmul(traj.rot[:-1], traj.rot[1:]))
        ids = _first_reaching(step, drad)
        pairs = np.stack([ids[:-1], ids[1:]], axis=1)
    pairs = pairs.reshape(-1, 2).astype(int)
    if pairs.shape[0] == 0:
        raise MetricError(f"delta = {delta} ({unit}) produced an empty index list - try lower values "
                          "or a less strict tolerance")
    return pairs


def _all_pairs_by_path(dist: np.ndarray, delta: float, tol: float) -> np.ndarray:
    n = dist.size
    if n < 2:
        return np.zeros((0, 2), int)
    i = np.arange(n - 1)
    k = np.searchsorted(dist, dist[i] + delta, side="left")
    cands = []
    for off in (-2, -1, 0, 1):
        c = np.clip(k + off, i + 1, n - 1)
        first = np.searchsorted(dist, dist[c], side="left")  # first index of a plateau
        cands += [c, np.clip(first, i + 1, n - 1)]
    cand = np.stack(cands, axis=1)
    err = np.abs((dist[cand] - dist[i][:, None]) - delta)
    # minimal error, then the smallest index (np.argmin's first-occurrence rule in evo)
    best_err = err.min(axis=1)
    masked = np.where(err == best_err[:, None], cand, n)
    j = masked.min(axis=1)
    keep = best_err <= tol
    return np.stack([i[keep], j[keep]], axis=1)


def rpe(ref: Trajectory, est: Trajectory, relation: str = "translation", delta: float = 1,
        delta_unit: str = "frames", align_mode: str = "none", *, all_pairs: bool = False,
        rel_delta_tol: float = 0.1, pairs_from_reference: bool = False, n_to_align: int = -1,
        max_diff: float | None = 0.01, sync: str = "nearest", offset: float = 0.0) -> ErrorResult:
    """Relative pose error (evo ``main_rpe.rpe`` after ``associate_trajectories``).  ``t`` of the
    result holds the estimate's timestamp of each pair's end pose."""
    rel = _relation(relation)
    ref, est = _prepare(ref, est, max_diff, sync, offset)
    al = align(ref, est, align_mode, n_to_align)
    est = al.apply(est)
    pairs = rpe_pairs(ref if pairs_from_reference else est, delta, delta_unit, all_pairs, rel_delta_tol)
    i, j = pairs[:, 0], pairs[:, 1]
    info: dict[str, Any] = {"delta": delta, "delta_unit": delta_unit, "all_pairs": all_pairs,
                            "n_pairs": int(i.size)}
    if rel in ("point_distance", "point_distance_error_ratio"):
        dq = np.linalg.norm(ref.xyz[j] - ref.xyz[i], axis=1)
        dp = np.linalg.norm(est.xyz[j] - est.xyz[i], axis=1)
        err = np.abs(dq - dp)
        if rel == "point_distance_error_ratio":
            nz = dq != 0
            pairs, err = pairs[nz], err[nz] / dq[nz] * 100.0
            j = pairs[:, 1]
    else:
        q_r = _tmul(ref.rot[i], ref.rot[j])
        q_t = np.einsum("nki,nk->ni", ref.rot[i], ref.xyz[j] - ref.xyz[i])
        p_r = _tmul(est.rot[i], est.rot[j])
        p_t = np.einsum("nki,nk->ni", est.rot[i], est.xyz[j] - est.xyz[i])
        e_rot = _tmul(q_r, p_r)
        e_t = np.einsum("nki,nk->ni", q_r, p_t - q_t)
        err = _pose_error_values(rel, e_rot, e_t)
    return ErrorResult("RPE", rel, _UNITS[rel], err, est.t[j], statistics(err), al, pairs, info)


# ------------------------------------------------------------------------------------------
# Skid-steer metrics
# ------------------------------------------------------------------------------------------
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


def velocity_rms(t_ref: ArrayLike, ref: Mapping[str, ArrayLike], t_est: ArrayLike,
                 est: Mapping[str, ArrayLike], channels: tuple[str, ...] = ("vx", "vy", "wz")
                 ) -> dict[str, float]:
    """RMS of ``est[c] - ref[c]`` per channel at the reference times where both are finite (the
    estimate interpolated linearly, NaN outside its span).  Channels absent from either side
    are skipped."""
    t_ref, t_est = np.asarray(t_ref, float), np.asarray(t_est, float)
    out: dict[str, float] = {}
    for c in channels:
        if c not in ref or c not in est:
            continue
        r = np.asarray(ref[c], float)
        e_raw = np.asarray(est[c], float)
        ok = np.isfinite(e_raw)
        if ok.sum() < 1:
            continue
        e = np.interp(t_ref, t_est[ok], e_raw[ok], left=np.nan, right=np.nan)
        m = np.isfinite(e) & np.isfinite(r)
        if m.any():
            d = e[m] - r[m]
            out[c] = float(np.sqrt(np.mean(d * d)))
    return out


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


# ------------------------------------------------------------------------------------------
# One-call summary for the runner
# ------------------------------------------------------------------------------------------
def summary(run: Run, estimate: Any, reference: str = "truth", window: float = 2.0) -> dict[str, float]:
    """Headline numbers of an estimate against ``reference`` (``truth`` or ``ref``) of ``run``:
    APE translation rmse (none / se2), APE yaw rmse [rad], RPE 1-frame translation rmse,
    position RMS (Liu), final position error, window-end position stats and velocity RMS."""
    ref = Trajectory.from_run(run, reference)
    est = Trajectory.from_estimate(estimate)
    out: dict[str, float] = {}
    # the estimate is interpolated at the reference stamps: no poses dropped by max_diff
    est_i = interpolate(est, ref.t)
    inside = (ref.t >= est.t[0]) & (ref.t <= est.t[-1])
    r, e = ref.take(np.flatnonzero(inside)), est_i.take(np.flatnonzero(inside))
    out["ape_rmse"] = ape(r, e, max_diff=None).stats.rmse
    out["ape_se2_rmse"] = ape(r, e, align_mode="se2", max_diff=None).stats.rmse
    out["ape_yaw_rmse"] = ape(r, e, "rotation_angle_rad", max_diff=None).stats.rmse
    out["rpe_rmse"] = rpe(r, e, max_diff=None).stats.rmse
    out["position_rms"] = position_rms(ref, est)
    out["final_position_error"] = final_position_error(ref, est)
    try:
        w = window_end_errors(ref, est, window).as_dict()
        out.update({f"window_{k}": v for k, v in w.items() if k not in ("n", "window")})
    except MetricError:
        pass
    if reference == "truth":
        truth = {c: run[f"truth_{c}"] for c in ("vx", "vy", "wz") if f"truth_{c}" in run.channels}
        estv = {c: estimate[c] for c in ("vx", "vy", "wz") if c in estimate.data.columns}
        out.update({f"{c}_rms": v for c, v in velocity_rms(run.t, truth, estimate["t"], estv).items()})
    return out

