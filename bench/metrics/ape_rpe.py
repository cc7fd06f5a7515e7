"""evo-compatible absolute and relative pose errors (APE, RPE) and their statistics.

APE (Kuemmerle et al. 2009 / evo ``metrics.APE``) per synchronised pose, RPE (Sturm et al. 2012 /
evo ``metrics.RPE``) over index pairs from :func:`rpe_pairs` (evo ``id_pairs_from_delta``), for the
pose relations of evo's ``PoseRelation``; :func:`statistics` is evo's ``get_all_statistics``.  The
definitions are in the docstring of :mod:`bench.metrics`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike

from bench.metrics.alignment import Alignment, align
from bench.metrics.trajectory import MetricError, Trajectory, _tmul, associate

__all__ = ["Stats", "statistics", "ErrorResult", "ape", "rpe", "rpe_pairs", "project_xy"]


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


def project_xy(traj: Trajectory) -> Trajectory:
    """evo's ``PosePath3D.project(Plane.XY)``: z = 0 and each rotation replaced by the rotation about z by its
    static-xyz Euler angle about z (``atan2(R[1, 0], R[0, 0])``)."""
    return Trajectory.planar(traj.t, traj.x, traj.y, traj.yaw, 0.0, name=traj.name)


def ape(ref: Trajectory, est: Trajectory, relation: str = "translation", align_mode: str = "none",
        *, n_to_align: int = -1, max_diff: float | None = 0.01, sync: str = "nearest",
        offset: float = 0.0, project_to_plane: bool = False) -> ErrorResult:
    """Absolute pose error (evo ``main_ape.ape`` after ``associate_trajectories``); ``project_to_plane``: evo's
    ``--project_to_plane xy``, after the alignment as in evo."""
    rel = _relation(relation)
    ref, est = _prepare(ref, est, max_diff, sync, offset)
    al = align(ref, est, align_mode, n_to_align)
    est = al.apply(est)
    if project_to_plane:
        ref, est = project_xy(ref), project_xy(est)
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
        max_diff: float | None = 0.01, sync: str = "nearest", offset: float = 0.0,
        project_to_plane: bool = False) -> ErrorResult:
    """Relative pose error (evo ``main_rpe.rpe`` after ``associate_trajectories``).  ``t`` of the
    result holds the estimate's timestamp of each pair's end pose; ``project_to_plane`` as in :func:`ape`."""
    rel = _relation(relation)
    ref, est = _prepare(ref, est, max_diff, sync, offset)
    al = align(ref, est, align_mode, n_to_align)
    est = al.apply(est)
    if project_to_plane:
        ref, est = project_xy(ref), project_xy(est)
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
