"""The real benchmark: kinematic models scored on real DRIVE windows (Clearpath Husky by default).

Protocol (``run_real_benchmark``):

1. Import the DRIVE table as per-window arrays (:func:`bench.real.drive.import_drive_windows`; a continuous Run from
   ``import-bag`` / ``import-csv`` is cut into the same windows by :func:`bench.real.run_windows.windows_from_run`).  A window
   is scored if its measured wheel speeds and its ICP start and end poses are finite.
2. Split the command steps (the repaired step ids of :mod:`bench.real.drive`) into a calibration and a
   test half **by step**: a ``numpy.random.default_rng(seed)`` permutation of the step ids, the
   first ``ceil(n/2)`` steps calibrate, the others test.  All windows of a step go to its half.
3. Fit every model on the calibration windows only (:meth:`WindowModel.fit`).
4. On the test windows, predict each window from its measured wheel speeds (zero-order hold over
   the 20 Hz samples, exact SE(2) integration, ``bench.kinematics.integrate_se2``) starting at the
   window's initial ICP pose, and score the pose at the window's last sample (1.95 s later):
   translation error ``|p_hat - p_icp|`` and yaw error ``|wrap(yaw_hat - yaw_icp)|``; report mean,
   median and 95th percentile, for all, steady and transitory windows.

Models: the registered method plugins named in :data:`DEFAULT_METHODS` (``bench.registry`` names), each
offering its rows through ``window_models(wheel_radius, track)`` (the window protocol,
:mod:`bench.real.windows`; the models and their equations live in the paper's package).  In row order:

* ``baseline.ideal_dd`` -> ``ideal_dd``: ideal differential drive with the nominal track.
* ``wang2015.constant_chi`` -> ``icr_sym_chi``: symmetric ICR model, ``y_l = -y_r = chi B / 2``,
  ``x_icr = 0`` (Wang 2015 eqs. (10)-(11), (15)); constant chi fitted by least squares on the
  calibration windows' end-pose errors (Mandow 2007 eq. (13)).
* ``mandow2007.asymmetric_ga`` -> ``mandow2007_icr``: Mandow 2007's ``K = {x_ICRl, x_ICRr, y_ICRv,
  alpha_r, alpha_l}`` (eqs. (6)-(7)) fitted on the calibration windows' end poses (J of eq. (13)) by
  least squares, in place of his GA.
* ``wang2015.chi_lambda`` -> ``wang2015_chi_curve``: chi as a function of the curvature ratio (Wang
  2015 eq. (44)) in the symmetric model; ``a, b`` fitted to chi measured per steady turning
  calibration window with eq. (25) (his (42)).
* ``yi2009.ekf_v3`` -> ``yi2009_s_gamma``, ``yi2009_s_gamma_gyro``: Yi 2009 kinematics with the
  longitudinal ICR S(gamma) (eqs. (6), (8), (13), (15), (40), (41)), psi_dot from the wheel speeds
  (the ICR family's inputs) or the measured gyro z rate.  Yi's EKF (Sec. IV) cannot run: DRIVE tables
  lack the roll and pitch gyro rates (:data:`bench.real.report.YI_MISSING`).  Not part of
  :data:`ICR_FAMILY` (the issue's verdict); the report compares it with the best of it.

``models`` of :func:`run_real_benchmark` takes other plugin names or :class:`WindowModel` objects; a
plugin written against Runs only fits in through :class:`bench.real.adapter.PluginModel`.

Time convention of the wheel speeds.  Step 4 holds wheel-speed sample k over [t_k, t_k+1].  A DRIVE table does not
say which period its ``left_wheel_vel`` covers; skidbench's Runs read a reading as the speed over the period *ending*
at its stamp (``docs/plugins.md``), which is sample k+1 over [t_k, t_k+1].  The verdicts are computed again with
that reading (:func:`later_wheel_speeds`: every model refitted and scored the same way) and the report says which
ones change: a verdict that changes is decided by a convention the data do not give.

Measured chi (:mod:`bench.real.chi`): per steady window turning at least ``MIN_TURN`` rad, Wang eq. (25)/(42)
``chi = 2 y0 / B = (S_r - S_l) / (phi B)`` with ``S_i = r * sum(w_i dt)`` and ``phi`` the ICP yaw
change over the same samples; tabulated by |curvature ratio| bin beside Wang's published P3-AT
curve (eq. (45): a = 0.4728, b = 0.0538).

Outputs (:mod:`bench.real.report`, written atomically: temp file + ``os.replace``): ``<out>/<platform>.md``
(report), ``<platform>.csv`` (error statistics), ``<platform>_chi.csv`` (chi by bin) and three PNG figures.
Files hold no wall-clock data, so the same input gives the same bytes; the runtime is returned.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import math
import os
import time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bench import registry
from bench.kinematics import icr_inverse
from bench.real.chi import chi_by_bin, testbed_chi
from bench.real.drive import DriveWindows, resolve_platform
from bench.real.report import write_report
from bench.real.league import paired_median_difference, step_draws
from bench.real.sanity import apply_fixes, scored_windows
from bench.run import RunError
from bench.real.windows import ICR_FAMILY, MIN_TURN, WindowModel, end_errors, tread_speeds, window_chi

#: the plugins whose window models the benchmark scores by default, in the order of their rows
DEFAULT_METHODS = ("baseline.ideal_dd", "wang2015.constant_chi", "mandow2007.asymmetric_ga", "wang2015.chi_lambda",
                   "yi2009.ekf_v3")


def stats(e: np.ndarray) -> dict[str, float]:
    e = np.asarray(e, float)
    if e.size == 0:
        return {"n": 0, "mean": math.nan, "median": math.nan, "p95": math.nan}
    return {"n": int(e.size), "mean": float(np.mean(e)), "median": float(np.median(e)),
            "p95": float(np.percentile(e, 95))}


class NoWindowModels(TypeError):
    """A method plugin asked for by the real-data benchmark offers no ``window_models``."""


def plugin_window_models(name: str, wheel_radius: float, track: float) -> list[WindowModel]:
    """The window models of the registered plugin ``name`` for this wheel radius and track [m]."""
    method = registry.get(name)
    if not callable(getattr(method, "window_models", None)):
        raise NoWindowModels(f"method '{name}' offers no window_models(wheel_radius, track): the real-data "
                             f"benchmark cannot score it (wrap a Run-based plugin in bench.real.adapter.PluginModel)")
    return list(method.window_models(wheel_radius, track))


def every_window_plugin() -> list[str]:
    """Every registered plugin that offers window models, ideal differential drive first, one plugin per row name
    (Yi's EKF variants share their window rows, Mandow's GA and DE their kinematics: the first name in order)."""
    rows: dict[str, str] = {}
    order = {n: i for i, n in enumerate(DEFAULT_METHODS)}  # the default rows first, in their order
    names = sorted(registry.discover(), key=lambda n: (order.get(n, len(order)), n))
    for n in names:
        method = registry.get(n)
        if callable(getattr(method, "window_models", None)):
            for m in method.window_models(1.0, 1.0):
                rows.setdefault(m.name, n)
    return list(dict.fromkeys(rows.values()))


def plugins_without_window_models() -> list[str]:
    """The registered plugins that offer no window models (the real benchmark does not score them: they need
    inputs a DRIVE window lacks, e.g. torques or GNSS, or are Run-based only; :class:`bench.real.adapter.PluginModel`
    scores a Run-based one on request)."""
    return sorted(n for n in registry.discover() if not callable(getattr(registry.get(n), "window_models", None)))


def resolve_models(models: Sequence[WindowModel | str] | None, wheel_radius: float, track: float
                   ) -> list[WindowModel]:
    """Window models from plugin names (``bench.registry``; :data:`DEFAULT_METHODS` when ``models`` is
    None) and/or :class:`WindowModel` objects, in the order given."""
    out: list[WindowModel] = []
    for m in (DEFAULT_METHODS if models is None else models):
        out.extend(plugin_window_models(m, wheel_radius, track) if isinstance(m, str) else [m])
    return out


# ------------------------------------------------------------------------------------------
# split and evaluation
# ------------------------------------------------------------------------------------------
def split_steps(w: DriveWindows, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(calibration steps, test steps): a seeded permutation of the step ids, first ceil(n/2) calibrate; fewer than 2
    steps leave nothing to hold out (a one-line :class:`RunError` naming the data)."""
    steps = np.unique(w.calib_step)
    if steps.size < 2:
        raise RunError(w.source, "calib_step", int(steps.size), "at least 2 command steps with usable windows are "
                       f"needed (one half calibrates, the other is held out); {w.n_windows} usable windows")
    perm = np.random.default_rng(seed).permutation(steps)
    k = (steps.size + 1) // 2
    return np.sort(perm[:k]), np.sort(perm[k:])


def evaluate(model: WindowModel, w: DriveWindows) -> dict[str, Any]:
    """Per-window end errors and their statistics for all, steady and transitory windows."""
    et, ey = end_errors(model.predict(w), w)
    masks = {"all": np.ones(w.n_windows, bool), "steady": w.steady, "transitory": w.transitory}
    return {
        "trans": et, "yaw": ey,
        "stats": {s: {"trans": stats(et[mk]), "yaw": stats(ey[mk])} for s, mk in masks.items()},
    }


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(y)
    return float(np.polyfit(x[ok], y[ok], 1)[0]) if ok.sum() >= 2 else math.nan


def later_wheel_speeds(w: DriveWindows) -> DriveWindows:
    """The windows with wheel-speed sample k+1 in place of sample k (``enc_wl``, ``enc_wr``; the last sample
    held): step 4's hold then integrates each reading over the period ending at its stamp, the convention of
    skidbench's Runs (module docstring)."""
    ch = dict(w.channels)
    for c in ("enc_wl", "enc_wr"):
        a = np.asarray(w[c], float)
        ch[c] = np.concatenate([a[:, 1:], a[:, -1:]], axis=1)
    return dataclasses.replace(w, channels=ch)


def _verdicts(results: Mapping[str, Mapping[str, Any]], best: str | None, draws: Sequence[np.ndarray]
              ) -> dict[str, Any]:
    """The paired intervals of the verdicts: best ICR-family model against ideal DD, and each Yi row against the
    best ICR-family model, in translation and yaw (over the held-out step resamples ``draws``)."""

    def paired(a: str, b: str, err: str) -> list[float]:
        return list(paired_median_difference(results[a][err], results[b][err], draws))

    interval = paired(best, "ideal_dd", "trans") if best is not None and "ideal_dd" in results else [math.nan] * 2
    return {
        # met when the paired interval over the held-out steps of (best - ideal DD) median lies below zero
        "best_minus_ideal_interval": interval,
        "passed": bool(best is not None and interval[1] < 0),
        # the Yi models against the best ICR-family model, paired the same way
        "yi_vs_best": {k: {e: paired(k, best, e) for e in ("trans", "yaw")}
                       for k in ("yi2009_s_gamma", "yi2009_s_gamma_gyro") if k in results and best is not None},
    }


def _best_icr(results: Mapping[str, Mapping[str, Any]]) -> tuple[str | None, dict[str, float]]:
    """The ICR-family row with the lowest median translation error (None without one) and the family's medians."""
    family = {k: results[k]["stats"]["all"]["trans"]["median"] for k in ICR_FAMILY if k in results}
    return (min(family, key=family.get) if family else None), family


def _fit_all(models: Sequence[WindowModel], calib: DriveWindows, named: Sequence[Any] | None
             ) -> tuple[list[WindowModel], dict[str, str]]:
    fitted, skipped = [], {}
    for m in models:
        try:
            fitted.append(m.fit(calib))
        except RunError as exc:  # a channel the model reads is not in this data set
            if named is not None and m.name in named:
                raise
            skipped[m.name] = str(exc)
    return fitted, skipped


def run_real_benchmark(data_path: str | Path, out_dir: str | Path, seed: int = 0,
                       platform: str | Mapping[str, Any] | None = "husky",
                       wheel_radius: float | None = None, track: float | None = None,
                       models: Sequence[WindowModel | str] | None = None, figures: bool = True,
                       label: str | None = None, fixes: Sequence[str] = ()) -> dict[str, Any]:
    """Run the real benchmark (module docstring) and write the report; returns the numbers.

    ``platform`` names the platform spec (default ``husky``); ``wheel_radius``/``track`` override it.
    ``models``: plugin names and/or :class:`WindowModel` objects (:func:`resolve_models`; default
    :data:`DEFAULT_METHODS`).  ``label``: the output files' stem (default the platform's name).  The data's sanity
    checks (:mod:`bench.real.sanity`) run on the scored windows and go to the report; ``fixes`` applies their
    corrections first.
    """
    t_start = time.perf_counter()
    data_path, out_dir = Path(data_path), Path(out_dir)
    plat = resolve_platform(platform, wheel_radius, track)
    r, B = float(plat["wheel_radius"]), float(plat["track"])
    name = str(plat.get("name") or data_path.stem)
    if name == "unspecified":
        name = data_path.stem
    allw, w, findings = scored_windows(data_path, r)
    n_excluded = allw.n_windows - w.n_windows  # a non-finite input sample or reference end (valid_windows)
    measured = {"imu_offset", "align_gyro"} & set(fixes)  # measured on the calibration half only, so after the split
    fixed_w, fixed = apply_fixes(w, [f for f in fixes if f not in measured])  # the windows the split is drawn from
    calib_steps, test_steps = split_steps(fixed_w, seed)
    if measured:  # the same windows: these two change the gyro and accelerometers, never which windows are kept
        fixed_w, fixed = apply_fixes(w, fixes, measure_on=np.isin(w.calib_step, calib_steps))
    w = fixed_w
    calib = w.subset(np.isin(w.calib_step, calib_steps))
    test = w.subset(np.isin(w.calib_step, test_steps))
    unfitted = resolve_models(models, r, B)
    fitted, skipped = _fit_all(unfitted, calib, models)
    results = {m.name: evaluate(m, test) for m in fitted}

    # measured chi (all usable steady windows) and two independent checks of the time base
    chi, lam, phi, usable = window_chi(w, r, B)
    bins = chi_by_bin(chi[usable], lam[usable])
    # the testbed's chi beside it: same |curvature ratio| (bin median) and outer tread speed (bin median)
    vl, vr = tread_speeds(w, r)
    outer = np.max(np.abs(np.column_stack((vl.mean(axis=1), vr.mean(axis=1)))), axis=1)[usable]
    a_lam = np.abs(lam[usable])
    full = [b for b in bins if b["n"] > 0]
    speeds = [float(np.clip(np.median(outer[(a_lam >= b["lo"]) & (a_lam < b["hi"])]), 0.1, 1.5)) for b in full]
    for b, c, v in zip(full, testbed_chi(name, [b["median_abs_ratio"] for b in full], speeds), speeds):
        b["testbed"], b["testbed_speed"] = c, v
    for b in bins:
        b.setdefault("testbed", math.nan)
        b.setdefault("testbed_speed", math.nan)
    rate_icp = phi / (w.dt * (w.n_samples - 1))
    checks: dict[str, float] = {}
    if w.has("imu_gz"):
        checks["gyro_vs_icp_rate_slope"] = _slope(rate_icp, np.mean(w["imu_gz"][:, :-1], axis=1))
    if "icp_omega" in w.body_velocity:
        om = w.body_velocity["icp_omega"]
        checks["drive_icp_omega_vs_icp_rate_slope"] = _slope(rate_icp, om)
        v_l, v_r = (r * np.mean(w[c], axis=1) for c in ("enc_wl", "enc_wr"))
        y_l, y_r, _ = icr_inverse(v_l, v_r, w.body_velocity.get("icp_vx", np.zeros_like(om)),
                                  w.body_velocity.get("icp_vy", np.zeros_like(om)), om, min_wz=MIN_TURN)
        chi_om = (y_l - y_r) / B
        ok_om = w.steady & np.isfinite(chi_om)
        checks["chi_from_drive_icp_omega_median"] = float(np.median(chi_om[ok_om])) if ok_om.any() else math.nan
        checks["chi_from_drive_icp_omega_n"] = int(ok_om.sum())

    ideal = results["ideal_dd"]["stats"]["all"]["trans"]["median"] if "ideal_dd" in results else math.nan
    best, family = _best_icr(results)  # chosen on the test half: the report says so
    draws = step_draws(test.calib_step)
    verdict = {
        "ideal_dd_median_trans": ideal,
        "best_icr_model": best,
        "best_icr_median_trans": family.get(best, math.nan) if best else math.nan,
        **_verdicts(results, best, draws),
    }
    # the same verdicts with the other reading of the wheel speeds' time stamps (module docstring): the best
    # ICR-family model chosen again under it, the same resamples of the held-out steps
    later_fitted, _ = _fit_all(unfitted, later_wheel_speeds(calib), models)
    later = {m.name: evaluate(m, later_wheel_speeds(test)) for m in later_fitted}
    best_later, _ = _best_icr(later)
    verdict["later_wheel_speeds"] = {
        "best_icr_model": best_later,
        **_verdicts(later, best_later, draws),
        "medians_trans": {k: v["stats"]["all"]["trans"]["median"] for k, v in later.items()},
    }
    out = {
        "platform": name, "wheel_radius": r, "track": B, "seed": int(seed),
        "data_file": data_path.name, "data_sha256": hashlib.sha256(data_path.read_bytes()).hexdigest(),
        "n_windows": allw.n_windows, "n_excluded": n_excluded,
        "calib_steps": calib_steps.tolist(), "test_steps": test_steps.tolist(),
        "n_calib_windows": calib.n_windows, "n_test_windows": test.n_windows,
        "n_test_steady": int(test.steady.sum()), "n_test_transitory": int(test.transitory.sum()),
        "models": {m.name: {"label": m.label, "params": m.params(), "fit_cost": getattr(m, "fit_cost", math.nan),
                            "inputs": list(getattr(m, "inputs", ("wheel speeds",))),
                            "stats": results[m.name]["stats"]} for m in fitted},
        "chi": {"n": int(usable.sum()), "median": float(np.median(chi[usable])) if usable.any() else math.nan,
                "q25": float(np.percentile(chi[usable], 25)) if usable.any() else math.nan,
                "q75": float(np.percentile(chi[usable], 75)) if usable.any() else math.nan,
                "bins": bins, "min_turn": MIN_TURN},
        "checks": checks,
        "import": {"relabelled_windows": int((allw.calib_step != allw.calib_step_label).sum()),
                   "shared_sample_boundaries": {int(k): int(v) for k, v in
                                                zip(*np.unique(allw.overlap[1:], return_counts=True))}},
        "verdict": verdict,
        "sanity": {"findings": [dataclasses.asdict(f) for f in findings], "fixes": fixed},
        "skipped_models": skipped,
    }
    files = write_report(out, fitted, results, test, chi[usable], lam[usable], out_dir, label or name, figures)
    out["files"] = [str(p) for p in files]
    # per held-out window (not in the JSON: keys with "_"): the real league's bootstrap over steps
    out["_windows"] = {"step": test.calib_step, "steady": test.steady,
                       "errors": {k: (v["trans"], v["yaw"]) for k, v in results.items()}}
    out["runtime_s"] = time.perf_counter() - t_start
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m bench.real.benchmark [TABLE] [--out results/real] [--seed 0] [--platform husky]``."""
    root = Path(__file__).resolve().parents[2]
    data_root = Path(os.environ.get("SKIDBENCH_DATA", root.parent / "shared" / "data"))
    default = data_root / "drive_husky" / "husky_windows.parquet"
    ap = argparse.ArgumentParser(prog="python -m bench.real.benchmark", description=main.__doc__)
    ap.add_argument("table", type=Path, nargs="?", default=default)
    ap.add_argument("--out", type=Path, default=root / "results" / "real")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--platform", default="husky")
    ap.add_argument("--wheel-radius", type=float, default=None)
    ap.add_argument("--track", type=float, default=None)
    args = ap.parse_args(argv)
    res = run_real_benchmark(args.table, args.out, args.seed, args.platform, args.wheel_radius, args.track)
    for mname, m in res["models"].items():
        s = m["stats"]["all"]["trans"]
        print(f"{mname:22s} median {s['median']:.3f} m  mean {s['mean']:.3f} m  p95 {s['p95']:.3f} m")
    v = res["verdict"]
    print(f"verdict: {'met' if v['passed'] else 'NOT met'} ({v['best_icr_model']} {v['best_icr_median_trans']:.3f} m "
          f"vs ideal_dd {v['ideal_dd_median_trans']:.3f} m); runtime {res['runtime_s']:.1f} s")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
