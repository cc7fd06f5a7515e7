"""``skidbench evaluate GT EST``: score one's own trajectories with evo's APE / RPE semantics (bench.metrics, the
evo-exact implementation; parity with evo's ``evo_ape`` / ``evo_rpe`` command line is tested).

    skidbench evaluate gt.tum est.tum [--align none|se2|se3|sim3] [--project-to-plane]
                       [--relation trans|angle_deg|angle_rad|full] [--rpe-delta D --delta-unit m|frames]
                       [--max-diff S] [--plot FILE] [--json FILE]

GT and EST: TUM files, runs (``.parquet``: the truth, or ``--gt-source ref|gnss``) or estimates (``.csv`` from
``skidbench estimate``).  Poses are associated by time as evo does (``--max-diff``, default 0.01 s).  Without
``--rpe-delta`` the result is the APE; with it, the RPE over pairs ``D`` metres or frames apart.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from bench.cli import command, output_files

ALIGN = {"none": "none", "se2": "se2", "se3": "se3", "sim3": "sim3"}  # CLI name -> bench.metrics.align mode
RELATIONS = {"trans": "translation", "angle_deg": "rotation_angle_deg", "angle_rad": "rotation_angle_rad",
             "full": "full"}


def load_trajectory(path: Path, source: str = "truth"):  # noqa: ANN201 - bench.metrics.Trajectory
    """A trajectory from a TUM file, a run (its ``source`` pose channels) or an estimate CSV; runs and estimates in
    the frame of ``export-tum`` (:func:`bench.formats.tum.pose_rows`: z as the height change since the first pose,
    the full attitude where logged), so a run's truth and an estimate of it compare as their TUM exports do."""
    from scipy.spatial.transform import Rotation

    from bench.formats import read_estimate_csv, read_tum
    from bench.formats.tum import pose_rows
    from bench.metrics import Trajectory
    from bench.run import Run, RunError

    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    if path.suffix == ".parquet":
        run = Run.from_parquet(path).validate()
        t, xyz, quat = pose_rows(run.data, f"{source}_", run.where)
        name = f"{run.id}:{source}"
    elif path.suffix == ".csv":
        frame = read_estimate_csv(path)
        t, xyz, quat = pose_rows(frame, "", str(path))
        name = path.stem
    else:
        return read_tum(path)
    return Trajectory(t, xyz, Rotation.from_quat(quat).as_matrix(), name)


def _args(p: argparse.ArgumentParser) -> None:
    p.add_argument("gt", type=Path, help="reference: TUM file, run (.parquet) or estimate (.csv)")
    p.add_argument("est", type=Path, help="estimate: TUM file, run (.parquet) or estimate (.csv)")
    p.add_argument("--align", choices=list(ALIGN), default="none",
                   help="none; se2 (planar, not in evo); se3 (evo -a); sim3 (evo -as)")
    p.add_argument("--project-to-plane", action="store_true", help="evo's --project_to_plane xy (after alignment)")
    p.add_argument("--relation", choices=list(RELATIONS), default="trans", help="evo's -r (default trans_part)")
    p.add_argument("--rpe-delta", type=float, default=None, help="RPE with pairs this far apart (default: APE)")
    p.add_argument("--delta-unit", choices=["m", "frames"], default="frames")
    p.add_argument("--max-diff", type=float, default=0.01, help="time association tolerance [s] (evo's default)")
    p.add_argument("--gt-source", choices=["truth", "ref", "gnss"], default="truth", help="pose channels of a GT run")
    p.add_argument("--plot", type=Path, default=None, help="a figure: both trajectories (xy) and the error")
    p.add_argument("--json", type=Path, default=None, help="statistics and settings as JSON")


def _plot(path: Path, ref, est, res) -> None:  # noqa: ANN001
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.io import atomic_savefig

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4.5))
    ax0.plot(ref.x, ref.y, "k--", lw=1, label=f"reference ({ref.name or 'gt'})")
    aligned = res.alignment.apply(est)
    ax0.plot(aligned.x, aligned.y, "C0", lw=1, label=f"estimate ({est.name or 'est'}, {res.alignment.mode})")
    ax0.set_aspect("equal", adjustable="datalim")
    ax0.set_xlabel("x [m]")
    ax0.set_ylabel("y [m]")
    ax0.legend(fontsize=8)
    ax1.plot(res.t - res.t[0], res.errors, "C3", lw=1)
    s = res.stats
    for val, style, name in ((s.rmse, "-", "rmse"), (s.median, ":", "median"), (s.mean, "--", "mean")):
        ax1.axhline(val, color="0.4", ls=style, lw=0.8, label=f"{name} {val:.4g}")
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel(f"{res.kind} {res.relation} [{res.unit}]")
    ax1.legend(fontsize=8)
    fig.tight_layout()
    atomic_savefig(fig, path)
    plt.close(fig)


def _evaluate(a: argparse.Namespace) -> int:
    from bench.metrics import MetricError, ape, rpe
    from bench.report.io import atomic_write_text
    from bench.spec import SpecError

    for name in ("rpe_delta", "max_diff"):
        v = getattr(a, name)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise SpecError("<command line>", f"--{name.replace('_', '-')}", v, "a finite number > 0")
    output_files(a, "plot", "json")
    if a.plot is not None:
        import matplotlib.pyplot as plt

        fmt = a.plot.suffix.lstrip(".").lower()
        if fmt not in plt.gcf().canvas.get_supported_filetypes():
            raise SpecError("<command line>", "--plot", str(a.plot),
                            "a file name ending in a figure format (.png, .pdf, .svg ...)")
        plt.close("all")
    ref, est = load_trajectory(a.gt, a.gt_source), load_trajectory(a.est)
    kw = dict(relation=RELATIONS[a.relation], align_mode=ALIGN[a.align], max_diff=a.max_diff,
              project_to_plane=a.project_to_plane)
    try:
        res = (ape(ref, est, **kw) if a.rpe_delta is None else
               rpe(ref, est, delta=a.rpe_delta, delta_unit=a.delta_unit, **kw))
    except MetricError as exc:
        print(f"error: {a.gt} vs {a.est}: {exc}", file=sys.stderr)
        return 2
    out = {"gt": str(a.gt), "est": str(a.est), "align": a.align, "project_to_plane": a.project_to_plane,
           "max_diff": a.max_diff, **res.as_dict()}
    if a.plot:  # the files first: a reader of stdout that goes away (`| head`) does not lose them
        _plot(a.plot, ref, est, res)
    if a.json:
        atomic_write_text(a.json, json.dumps(out, indent=1, default=float) + "\n")
    print(f"{res.kind} ({res.relation}, {res.unit}; align {a.align}"
          f"{', projected to xy' if a.project_to_plane else ''}; {res.errors.size} values)")
    for k in ("rmse", "mean", "median", "std", "min", "max", "sse"):
        print(f"  {k:>6} {out[k]:.9g}")
    return 0


command("evaluate", "APE / RPE of an estimate against a reference, evo's semantics")((_args, _evaluate))
