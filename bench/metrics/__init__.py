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
   * :func:`divergence` -- where the position error went past the reference's path length so far (at least
     1 m) and stayed past it to the end: the league reports it instead of an RMS.
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

Modules: :mod:`~bench.metrics.trajectory` (Trajectory, time association, interpolation),
:mod:`~bench.metrics.alignment` (Umeyama, alignment modes), :mod:`~bench.metrics.ape_rpe` (APE, RPE,
statistics), :mod:`~bench.metrics.position` and :mod:`~bench.metrics.velocity` (errors without
alignment), :mod:`~bench.metrics.segments` (Mandow segments, window-end errors); :func:`summary` (the
runner's one-call summary) is here.  Every public name is importable from ``bench.metrics``.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation  # noqa: F401  (bench.metrics.Rotation, as before the split)

from bench.metrics.alignment import ALIGNMENTS, Alignment, align, umeyama  # noqa: F401
from bench.metrics.ape_rpe import (_so3_angle, ErrorResult, Stats, ape, rpe, rpe_pairs,  # noqa: F401
                                   statistics)
from bench.metrics.position import Divergence, divergence, final_position_error, position_errors, position_rms
from bench.metrics.segments import (SegmentDeadReckoner, SegmentErrors, WindowErrors, segment_errors,
                                    trajectory_reckoner, velocity_reckoner, window_end_errors)
from bench.metrics.trajectory import MetricError, Trajectory, associate, interpolate
from bench.metrics.velocity import velocity_rms
from bench.run import Run

__all__ = [
    "MetricError", "Trajectory", "Stats", "statistics", "Alignment", "umeyama", "align",
    "associate", "interpolate", "ErrorResult", "ape", "rpe", "rpe_pairs",
    "Divergence", "divergence", "position_errors", "position_rms", "final_position_error", "velocity_rms",
    "SegmentDeadReckoner", "velocity_reckoner", "trajectory_reckoner", "SegmentErrors",
    "segment_errors", "WindowErrors", "window_end_errors", "summary",
]



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
