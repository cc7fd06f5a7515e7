"""Outputs of the real-data benchmark (:mod:`bench.real.benchmark`): the markdown report, the error and
chi CSV tables and the three PNG figures (chi vs curvature ratio, error CDFs, example windows), all
written atomically (:mod:`bench.real.io`) and without wall-clock data, so the same input gives the same
bytes.  Every sentence's number is derived from the benchmark's results here, none written by hand."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bench.real.chi import TESTBED_CHI_SCENARIO, WANG_P3AT, model_chi, wang_p3at_chi
from bench.real.drive import DriveWindows
from bench.real.io import _atomic_write_text, _new_figure, _save_figure
from bench.real.league import N_BOOT, comparison
from bench.real.windows import ICR_FAMILY, MIN_TURN, WindowModel
from bench.report.cells import CELL_LIMIT, cell

SUBSETS = ("all", "steady", "transitory")

#: inputs of Yi's full method (the EKF of Sec. IV) that a DRIVE table lacks
YI_MISSING = ("roll and pitch gyro rates (imu_gx, imu_gy: eqs. (10c)-(10e) and the EKF of Sec. IV-A)",)


def _fmt(v: float, nd: int = 3) -> str:
    return "n/a" if v is None or not np.isfinite(v) else f"{v:.{nd}f}"



def write_report(out: Mapping[str, Any], fitted: Sequence[WindowModel], results: Mapping[str, Any],
                 test: DriveWindows, chi: np.ndarray, lam: np.ndarray, out_dir: Path, name: str,
                 figures: bool) -> list[Path]:
    """Write ``<name>.csv``, ``<name>_chi.csv``, the figures (if ``figures``) and ``<name>.md`` into
    ``out_dir``; ``chi``, ``lam`` are the usable windows' measured chi and curvature ratio."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [_write_csv(out, out_dir / f"{name}.csv"), _write_chi_csv(out, out_dir / f"{name}_chi.csv")]
    if figures:
        files += _figures(out, fitted, results, test, chi, lam, out_dir, name)
    files.append(_atomic_write_text(out_dir / f"{name}.md", _report(out, figures, name)))
    return files


def _write_csv(out: Mapping[str, Any], path: Path) -> Path:
    lines = ["model,subset,error,unit,n,mean,median,p95"]
    for mname, m in out["models"].items():
        for s in SUBSETS:
            for e, unit in (("trans", "m"), ("yaw", "rad")):
                st = m["stats"][s][e]
                lines.append(f"{mname},{s},{e},{unit},{st['n']},{st['mean']:.6f},{st['median']:.6f},{st['p95']:.6f}")
    return _atomic_write_text(path, "\n".join(lines) + "\n")


def _write_chi_csv(out: Mapping[str, Any], path: Path) -> Path:
    lines = ["abs_ratio_lo,abs_ratio_hi,n,chi_median,chi_q25,chi_q75,median_abs_ratio,wang_p3at_chi,testbed_chi,"
             "testbed_tread_speed"]
    for b in out["chi"]["bins"]:
        lines.append(",".join(f"{b[k]:.6f}" if isinstance(b[k], float) else str(b[k])
                              for k in ("lo", "hi", "n", "median", "q25", "q75", "median_abs_ratio", "wang_p3at",
                                        "testbed", "testbed_speed")))
    return _atomic_write_text(path, "\n".join(lines) + "\n")


def _figures(out: Mapping[str, Any], fitted: Sequence[WindowModel], results: Mapping[str, Any],
             test: DriveWindows, chi: np.ndarray, lam: np.ndarray, out_dir: Path, name: str) -> list[Path]:
    files = []
    # 1. chi versus |curvature ratio|
    fig = _new_figure(6.4, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    a = np.abs(lam)
    ax.scatter(a, chi, s=8, alpha=0.35, color="0.4", label=f"{name}: steady windows, eq. (25)")
    bins = [b for b in out["chi"]["bins"] if b["n"] > 0]
    mx = np.array([b["median_abs_ratio"] for b in bins])
    ax.errorbar(mx, [b["median"] for b in bins],
                yerr=[[b["median"] - b["q25"] for b in bins], [b["q75"] - b["median"] for b in bins]],
                fmt="o-", color="C0", capsize=3, label=f"{name}: bin median, IQR")
    grid = np.linspace(0, max(10.0, float(np.percentile(a, 99)) if a.size else 10.0), 300)
    ax.plot(grid, wang_p3at_chi(grid), "C3--", label="Wang 2015 eq. (45), P3-AT (published)")
    for m in fitted:  # the fitted chi models' own chi (rows of wang2015.chi_lambda, wang2015.constant_chi)
        if m.name == "wang2015_chi_curve":
            p = m.params()
            ax.plot(grid, model_chi(m, grid, out["wheel_radius"], out["track"]), "C2-",
                    label=f"eq. (44) fitted on calib. half (a={p['a']:.3f}, b={p['b']:.3f})")
        if m.name == "icr_sym_chi":
            c = m.params()["chi"]
            ax.axhline(c, color="C1", ls=":", label=f"constant chi, end-pose fit ({c:.3f})")
    ax.set_xlabel("|curvature ratio| = |(v_l + v_r) / (v_r - v_l)|")
    ax.set_ylabel("chi = (y_l - y_r) / B")
    ax.set_xlim(0, grid[-1])
    lo = float(np.nanpercentile(chi, 1)) if chi.size else 1.0
    hi = float(np.nanpercentile(chi, 99)) if chi.size else 3.0
    ax.set_ylim(min(1.0, lo) - 0.1, max(1.6, hi) + 0.1)
    ax.legend(fontsize=7)
    ax.set_title(f"ICR coefficient vs curvature ratio ({name})", fontsize=9)
    fig.tight_layout()
    files.append(_save_figure(fig, out_dir / f"{name}_chi.png"))

    # 2. CDF of end translation errors per model, steady vs transitory
    fig = _new_figure(8.0, 3.6)
    for k, (sub, mask) in enumerate((("steady", test.steady), ("transitory", test.transitory))):
        ax = fig.add_subplot(1, 2, k + 1)
        for i, m in enumerate(fitted):
            e = np.sort(results[m.name]["trans"][mask])
            ax.step(e, np.arange(1, e.size + 1) / max(e.size, 1), where="post", color=f"C{i}", label=m.name)
        ax.set_xlabel("translation error at window end [m]")
        ax.set_ylabel("fraction of test windows")
        ax.set_title(f"{sub} test windows (n={int(mask.sum())})", fontsize=9)
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    fig.tight_layout()
    files.append(_save_figure(fig, out_dir / f"{name}_errors.png"))

    # 3. example test windows: ICP vs models (quantiles of the ideal-DD error)
    preds = {m.name: m.predict(test) for m in fitted}
    e0 = results[fitted[0].name]["trans"]
    order = np.argsort(e0, kind="stable")
    picks = order[np.unique(np.round(np.linspace(0.1, 0.9, 6) * (order.size - 1)).astype(int))] if order.size else []
    fig = _new_figure(9.0, 5.6)
    for k, i in enumerate(picks):
        ax = fig.add_subplot(2, 3, k + 1)
        ax.plot(test["ref_x"][i], test["ref_y"][i], "k.-", ms=3, lw=1, label="ICP")
        for j, m in enumerate(fitted):
            px, py, _ = preds[m.name]
            ax.plot(px[i], py[i], color=f"C{j}", lw=1, label=m.name)
        ax.set_aspect("equal", adjustable="datalim")
        kind = "steady" if test.steady[i] else "transitory"
        ax.set_title(f"step {int(test.calib_step[i])} win {int(test.window[i])} ({kind})", fontsize=8)
        ax.tick_params(labelsize=7)
        if k == 0:
            ax.legend(fontsize=6)
    fig.tight_layout()
    files.append(_save_figure(fig, out_dir / f"{name}_examples.png"))
    return files


def _report(out: Mapping[str, Any], figures: bool, name: str) -> str:
    L: list[str] = []
    add = L.append
    v = out["verdict"]
    add(f"# Real benchmark: {name} (DRIVE windows)\n")
    add("Generated by `bench.real.benchmark.run_real_benchmark` (`skidbench reproduce real` or `skidbench real`). "
        "Kinematic models predict each 2 s window of a real robot from its measured wheel speeds and its initial ICP "
        "pose; the error is taken at the window's last sample (1.95 s after the first).\n")
    add("## Data and split\n")
    add(f"- Table: `{out['data_file']}` (sha256 `{out['data_sha256'][:16]}...`), {out['n_windows']} windows of "
        f"2 s at 20 Hz, {len(out['calib_steps']) + len(out['test_steps'])} command steps; "
        f"{out['n_excluded']} windows excluded (a non-finite input sample: wheel speeds, commands, gyro; or ICP start/end pose).")
    add(f"- Platform `{out['platform']}`: wheel radius r = {out['wheel_radius']} m, track B = {out['track']} m.")
    add(f"- Split by command step, seed {out['seed']}: `numpy.random.default_rng(seed).permutation(steps)`, first "
        f"half calibrates. Calibration: {len(out['calib_steps'])} steps, {out['n_calib_windows']} windows. "
        f"Test: {len(out['test_steps'])} steps, {out['n_test_windows']} windows "
        f"({out['n_test_steady']} steady, {out['n_test_transitory']} transitory).\n")
    if out.get("sanity"):
        add("## Sanity checks of the data (bench.real.sanity)\n")
        for f in out["sanity"]["findings"]:
            fix = f" (`--fix {f['fix']}` corrects it)" if f["fix"] and not f["ok"] else ""
            add(f"- {'ok' if f['ok'] else '**warning**'} `{f['check']}`: {f['evidence']}{fix}")
        for line in out["sanity"]["fixes"]:
            add(f"- corrected: {line}")
        add("")
    add("## Fitted models (calibration half)\n")
    add("| model | description | parameters |")
    add("|---|---|---|")
    long_lists = []  # a parameter list too long for a table cell goes below the table, whole
    for mname, m in out["models"].items():
        ps = ", ".join(f"{k} = {_fmt(val, 4)}" for k, val in m["params"].items()) or "-"
        if len(ps) > CELL_LIMIT:
            long_lists.append(f"- `{mname}`: {ps}")
            ps = "listed below the table"
        add(f"| `{mname}` | {cell(m['label'])} | {ps} |")
    add("")
    if long_lists:
        L.extend(long_lists + [""])
    for err, unit, title in (("trans", "m", "Translation error at window end"),
                             ("yaw", "rad", "Yaw error at window end")):
        add(f"## {title} [{unit}], test half\n")
        add("| model | all: mean | all: median | all: p95 | steady: mean | steady: median | steady: p95 | "
            "transitory: mean | transitory: median | transitory: p95 |")
        add("|---|" + "---:|" * 9)
        for mname, m in out["models"].items():
            cells = [_fmt(m["stats"][s][err][q]) for s in SUBSETS for q in ("mean", "median", "p95")]
            add(f"| `{mname}` | " + " | ".join(cells) + " |")
        add("")
    add("## Verdict\n")
    ideal, best, bm = v["ideal_dd_median_trans"], v["best_icr_model"], v["best_icr_median_trans"]
    lo, hi = v.get("best_minus_ideal_interval", (math.nan, math.nan))
    paired = (f"paired 95 % interval of the difference of medians {lo:+.3f} to {hi:+.3f} m over {N_BOOT} resamples of "
              f"the held-out command steps; `{best}` is the ICR-family model with the lowest median on this test half, "
              f"chosen on it")
    if best is None:
        add("No verdict: no ICR-family model (" + ", ".join(f"`{k}`" for k in ICR_FAMILY) + ") was scored on "
            "this data set (the rows chosen with `--methods`, or the plugins that could not run on it).\n")
    elif v["passed"]:
        add(f"The best calibrated ICR-family model, `{best}`, has a lower median 2 s translation error on the test "
            f"half than ideal differential drive with the nominal track: **{_fmt(bm)} m vs {_fmt(ideal)} m** "
            f"({100 * (1 - bm / ideal):.0f} % lower; {paired}).\n")
    else:
        add(f"**Not met**: the best calibrated ICR-family model, `{best}`, has a median 2 s translation error of "
            f"{_fmt(bm)} m on the test half against ideal differential drive's {_fmt(ideal)} m, not lower beyond the "
            f"interval ({paired}). See the example windows and the chi figure for why.\n")
    later = v.get("later_wheel_speeds")
    if later and best is not None:
        llo, lhi = later["best_minus_ideal_interval"]
        same = bool(later["passed"]) == bool(v["passed"])
        other = later.get("best_icr_model") or best
        which = "" if other == best else f" (its best ICR-family model is `{other}`)"
        add(f"{TIME_CONVENTION} the interval is {llo:+.3f} to {lhi:+.3f} m{which}: the verdict "
            + ("is the same.\n" if same else "**changes** (decided by the time convention).\n"))
    yi = _yi_sentences(out)
    if yi:
        add("## Yi 2009 S(gamma) kinematics\n")
        L.extend(yi)
        add("")
    notes = _reading(out)
    if notes:
        add("## Reading the fitted parameters\n")
        L.extend(notes)
        add("")
    c = out["chi"]
    add(f"## Measured chi versus curvature ratio (all steady windows of both halves turning >= {c['min_turn']} rad: "
        "a description of the data; no model is fitted on it)\n")
    add(f"chi = (S_r - S_l) / (phi B) per window (Wang 2015 eq. (25)/(42); S_i = r * sum(w_i dt), phi = ICP yaw "
        f"change over the same samples). {c['n']} windows: median {_fmt(c['median'])}, interquartile "
        f"{_fmt(c['q25'])}-{_fmt(c['q75'])}. Wang's P3-AT curve (eq. (45), published: a = 0.4728, b = 0.0538) is "
        "evaluated at each bin's median |ratio|. The testbed column is the testbed's own chi for this platform "
        f"(scenario `{TESTBED_CHI_SCENARIO}`: asphalt, the gap workflow's nominal model): a steady CCW turn at the "
        "bin's median |ratio| and median outer tread speed, Wang eq. (25) on the testbed's truth after 3 s.\n")
    add("| abs(curvature ratio) bin | n | chi median | chi IQR | median abs(ratio) | testbed (outer tread speed) | "
        "Wang P3-AT eq. (45) |")
    add("|---|---:|---:|---|---:|---:|---:|")
    for b in c["bins"]:
        hi = "inf" if not np.isfinite(b["hi"]) else f"{b['hi']:g}"
        tb = f"{_fmt(b['testbed'])} ({_fmt(b['testbed_speed'], 2)} m/s)" if np.isfinite(b["testbed"]) else "n/a"
        add(f"| [{b['lo']:g}, {hi}) | {b['n']} | {_fmt(b['median'])} | {_fmt(b['q25'])}-{_fmt(b['q75'])} | "
            f"{_fmt(b['median_abs_ratio'], 2)} | {tb} | {_fmt(b['wang_p3at'])} |")
    add("")
    tb_bins = [b for b in c["bins"] if b["n"] > 0 and np.isfinite(b["testbed"])]
    if len(tb_bins) >= 2:
        lo, hi = tb_bins[0], tb_bins[-1]
        level = np.median([b["testbed"] / b["median"] for b in tb_bins])
        add(f"From the first to the last bin the measured chi goes {_fmt(lo['median'])} -> {_fmt(hi['median'])} and "
            f"the testbed's {_fmt(lo['testbed'])} -> {_fmt(hi['testbed'])}; the testbed's level is "
            f"{100 * abs(1 - level):.0f} % {'below' if level < 1 else 'above'} the measured one (median over bins of "
            "testbed / measured).\n")
    if figures:
        add(f"Figures: [`{name}_chi.png`]({name}_chi.png) (chi vs curvature ratio), "
            f"[`{name}_errors.png`]({name}_errors.png) (error CDFs, steady and transitory), "
            f"[`{name}_examples.png`]({name}_examples.png) (six test windows at the 10-90 % quantiles of the "
            "ideal-DD error: ICP vs each model).\n")
    add("## Data notes (measured while importing; see `bench/real/drive.py`)\n")
    imp, ck = out["import"], out["checks"]
    shared = ", ".join(f"{n} share {k}" for k, n in sorted(imp["shared_sample_boundaries"].items()) if k > 0)
    add(f"- {imp['relabelled_windows']} transitory windows carry the previous step's `calib_step` label (their first "
        "sample precedes the command change); steps are regrouped structurally (transitory window + its steady "
        "windows).")
    add(f"- Adjacent windows are consecutive blocks of the 20 Hz log; at some boundaries they share samples "
        f"({shared} sample(s)); a Run keeps a shared sample once.")
    add("- ICP poses are in per-window frames rotated by the mean of the first 5 samples' yaw while `icp_yaw` is "
        "relative to the first sample: the initial heading in the frame is `-mean(icp_yaw_0..4)`, used as the start "
        "pose of every prediction.")
    if "gyro_vs_icp_rate_slope" in ck:
        add(f"- `imu_yaw` is a yaw *rate*: its window mean follows the ICP yaw rate with slope "
            f"{_fmt(ck['gyro_vs_icp_rate_slope'])}; it is imported as `imu_gz`.")
    if "drive_icp_omega_vs_icp_rate_slope" in ck:
        add(f"- DRIVE's per-window `icp_omega` is {_fmt(ck['drive_icp_omega_vs_icp_rate_slope'])} x the ICP yaw change "
            f"over the window divided by its duration (the gyro agrees with the latter), so chi computed from "
            f"`icp_omega` with `icr_inverse` (median {_fmt(ck['chi_from_drive_icp_omega_median'])} over "
            f"{ck['chi_from_drive_icp_omega_n']} steady windows with |icp_omega| >= {MIN_TURN} rad/s) is biased low; "
            "the table above uses the ICP yaw change.")
    add("")
    return "\n".join(L)


#: the other reading of the wheel speeds' time stamps (bench.real.benchmark.later_wheel_speeds), for the verdicts
TIME_CONVENTION = ("With the wheel speeds read one sample later (sample k as the speed over the period ending at its "
                   "stamp, as skidbench's Runs read a wheel-speed reading; the table does not say which period a "
                   "sample covers), every model refitted and scored again,")


def _yi_sentences(out: Mapping[str, Any]) -> list[str]:
    """What the Yi models use and whether they beat the best ICR-family model (numbers derived here)."""
    ms, v = out["models"], out["verdict"]
    best = v["best_icr_model"]
    if best is None:
        return []
    bt, by = (ms[best]["stats"]["all"][e]["median"] for e in ("trans", "yaw"))
    lines = []
    inputs = {"yi2009_s_gamma": "the measured wheel speeds only (the same input as the ICR family)",
              "yi2009_s_gamma_gyro": "the measured wheel speeds and the gyro yaw rate (`imu_yaw` of the DRIVE "
                                     "table, a rate: `imu_gz`) as psi_dot"}
    for name, what in inputs.items():
        if name not in ms:
            continue
        m = ms[name]
        t, y = (m["stats"]["all"][e]["median"] for e in ("trans", "yaw"))
        p = m["params"]
        iv = v.get("yi_vs_best", {}).get(name, {"trans": (math.nan, math.nan), "yaw": (math.nan, math.nan)})
        (tlo, thi), (ylo, yhi) = iv["trans"], iv["yaw"]
        words = {"beats": "beats", "worse": "is worse than", "no clear difference": "shows no clear difference from"}
        lines.append(
            f"- `{name}` uses {what}; S(gamma) fitted on {int(p['n_S_points'])} steady turning calibration windows "
            f"(S(0) = a1/a3 = {_fmt(p['S(0)'])} m, a2/a3 = {_fmt(p['a2'] / p['a3'])}, S reversing with the travel "
            f"direction, x_M = {_fmt(p['x_M'])} m, point scatter {_fmt(p['S_fit_rms'])} m RMS), common traction slip "
            f"lambda_0 = {_fmt(p['lambda_0'])}. Median test "
            f"error {_fmt(t, 4)} m / {_fmt(y)} rad against the best ICR-family model `{best}`'s {_fmt(bt, 4)} m / "
            f"{_fmt(by)} rad: in translation it {words[comparison(tlo, thi)]} it (paired 95 % interval of the "
            f"difference of medians {1000 * tlo:+.1f} to {1000 * thi:+.1f} mm), in yaw it "
            f"{words[comparison(ylo, yhi)]} it ({1000 * ylo:+.1f} to {1000 * yhi:+.1f} mrad; {N_BOOT} resamples of "
            f"the held-out command steps).")
        later = v.get("later_wheel_speeds", {}).get("yi_vs_best", {}).get(name)
        if later:
            changed = [(e, later[e]) for e, (lo, hi) in (("trans", (tlo, thi)), ("yaw", (ylo, yhi)))
                       if comparison(*later[e]) != comparison(lo, hi)]
            lines[-1] += " With the wheel speeds read one sample later (see the verdict) " + (
                "both comparisons are the same." if not changed else "; ".join(
                    f"in {'translation' if e == 'trans' else 'yaw'} it {words[comparison(lo, hi)]} it "
                    f"({1000 * lo:+.1f} to {1000 * hi:+.1f} {'mm' if e == 'trans' else 'mrad'})"
                    for e, (lo, hi) in changed) + ": decided by the time convention.")
    if lines:
        lines.append(
            "- Missing for Yi's full method (the EKF of Sec. IV, which estimates the slips on line): "
            + "; ".join(YI_MISSING) + ". The DRIVE table has the z gyro rate and the three accelerometer axes "
            "only, so the slips are calibrated constants here (eq. (8) with fitted tread ICRs) instead of EKF "
            "estimates, and psi_dot = gyro z (roll and pitch taken as 0 in eq. (10e)).")
    return lines


def _reading(out: Mapping[str, Any]) -> list[str]:
    """Sentences derived from the fitted values (no number is written here by hand)."""
    lines = []
    ms = out["models"]
    if "mandow2007_icr" in ms:
        p = ms["mandow2007_icr"]["params"]
        where = "behind" if p["x_icr"] < 0 else "ahead of"
        lines.append(
            f"- `mandow2007_icr`: alpha_l = {_fmt(p['alpha_l'])}, alpha_r = {_fmt(p['alpha_r'])}: the end-pose fit "
            f"takes the treads to move {100 * (1 - (p['alpha_l'] + p['alpha_r']) / 2):.0f} % less than r*w "
            f"(longitudinal slip "
            f"or a smaller effective radius, traded jointly with the ICR spread); neither symmetric model has this "
            f"freedom. Its ICRs lie "
            f"{_fmt(abs(p['x_icr']))} m {where} the reference point (this includes any offset of the ICP frame "
            f"origin from the wheel-geometry centre); chi = (y_l - y_r)/B = {_fmt(p['chi'])}, and the rotation it "
            f"predicts per unit of r*(w_r - w_l) matches a symmetric chi of "
            f"{_fmt(p['chi'] / ((p['alpha_l'] + p['alpha_r']) / 2))}.")
    if "icr_sym_chi" in ms:
        lines.append(f"- `icr_sym_chi`: chi = {_fmt(ms['icr_sym_chi']['params']['chi'])} minimises Mandow's J over the "
                     f"calibration windows; the median chi measured per steady window of both halves with eq. (25) (below) is "
                     f"{_fmt(out['chi']['median'])}.")
    if "wang2015_chi_curve" in ms:
        p = ms["wang2015_chi_curve"]["params"]
        lines.append(
            f"- `wang2015_chi_curve`: a = {_fmt(p['a'])}, b = {_fmt(p['b'])} (chi = {_fmt(p['chi(0)'])} at a zero "
            f"curvature ratio) against Wang's P3-AT a = {WANG_P3AT[0]}, b = {WANG_P3AT[1]} "
            f"(chi = {1 + WANG_P3AT[0]:.4f}).")
    return lines

