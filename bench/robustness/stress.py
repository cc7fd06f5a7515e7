"""Filters under stress: every filter on every sensor fault, and ``results/stress.md``.

Cases (faults from :mod:`bench.robustness.faults`, applied to one simulated run per seed so that the clean
and faulted runs share physics and sensor noise; the fault times are after the GNSS initial drift
of DUBHE's receiver has decayed, tau = 20 s):

    none             the fault-free run, scored with the GNSS-outage window: checks that the
                     recovery criterion does not flag a run without a fault (its false-alarm rate)
    gnss_outage      GNSS position/velocity/heading missing for ``outage`` s        (Liu only)
    imu_spikes       full-scale spikes on all six IMU channels at t0, t0+1.3, t0+2.7 s, clipped at
                     the platform's saturation
    encoder_dropout  both encoders missing for ``dropout`` s

Filters: Liu 2020 UKF+ICR and MI-UKF on DUBHE (scenarios/stress_dubhe_random.toml), as the paper
defines them ("paper") and, for the GNSS outage, with the ICR hold of Sec. IV-A
(``LiuUkfParams.icr_hold_gnss_timeout``, "icr_hold"), and in their consistent configuration on every
fault (``methods.liu2020.UkfIcrConsistent`` / ``MiUkfConsistent``, noise identified on the calibration
run ``liu_calib`` seed 100, "consistent"); Yi 2009 EKF schemes 1-3 on Yi's robot
(scenarios/stress_yi_random.toml, published S(gamma) for scheme 3).  Yi's EKF reads no GNSS, so a
GNSS outage does not concern it, and with no absolute position sensor its position error grows
without bound: position recovery is not defined for it.  For Yi the report gives instead the
offset of its body speed (observed by the encoders) from the fault-free run's estimate 10-30 s
after the fault.

Measures per case (definitions in :mod:`bench.robustness.faults`): pre-fault level, max error, recovery time
(criterion: back within 2x the larger of the pre-fault level and the fault-free run's error within 10 s of the
fault's end; the 1-hour runs, without a fault-free twin, the pre-fault level alone), NaN count in the
estimate, covariance health (symmetric, finite, smallest eigenvalue at any step).  Full mode adds
seeds and the 1-hour runs (all faults in one run, spaced 15 min apart).
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bench.robustness import faults as F
from bench.procs import process_pool
from bench.run import Run

__all__ = ["StressSettings", "QUICK", "FULL", "liu_method", "fault_cases", "evaluate", "stress_rows",
           "stress_markdown", "stress_report"]

ESTIMATE_STATE = ("x", "y", "yaw", "vx", "vy", "wz")


@dataclass(frozen=True)
class StressSettings:
    seeds: tuple[int, ...] = (1,)
    duration: float | None = None  # [s] short runs; None: the scenario file's (180 s)
    t0: float = 90.0  # [s] fault start in the short runs
    outage: float = 30.0  # [s] GNSS outage length (issue: 30 s)
    dropout: float = 10.0  # [s] encoder dropout length
    spike_offsets: tuple[float, ...] = (0.0, 1.3, 2.7)  # [s] after t0
    spike_magnitude: float = 1.0  # fraction of full scale (bench.robustness.faults.imu_saturation_spikes)
    spike_seed: int = 0
    gnss_timeout: float = 1.0  # [s] ICR hold variant: hold once the latest GNSS fix is older than this
    pre_window: float = 20.0
    horizon: float = 30.0
    factor: float = 2.0
    recover_within: float = 10.0
    liu_filters: tuple[str, ...] = ("liu2020.ukf_icr", "liu2020.mi_ukf")
    yi_filters: tuple[str, ...] = ("yi2009.ekf_v1", "yi2009.ekf_v2", "yi2009.ekf_v3")
    liu_scenario: str = "stress_dubhe_random"
    yi_scenario: str = "stress_yi_random"
    hour: float = 0.0  # > 0: also the long runs of this duration [s] (3600 in full mode)
    hour_seed: int = 1
    hour_fault_times: tuple[float, float, float] = (900.0, 1800.0, 2700.0)  # spikes, dropout, outage
    # Liu "consistent" variant (methods.liu2020.UkfIcrConsistent / MiUkfConsistent): noise identified on
    # this calibration run (not a stress run), run on every fault
    consistent: bool = True
    calib_scenario: str = "liu_calib"
    calib_seed: int = 100


QUICK = StressSettings()
FULL = StressSettings(seeds=(1, 2, 3, 4, 5, 6), hour=3600.0)


def liu_method(name: str, hold_timeout: float | None = None) -> Any:
    """A Liu filter from the registry, as the paper defines it or with the ICR hold (Sec. IV-A)."""
    from bench import registry

    m = registry.get(name)
    if hold_timeout is None:
        return m
    return dataclasses.replace(m, params=dataclasses.replace(m.params, icr_hold_gnss_timeout=hold_timeout))


def liu_consistent_method(name: str, s: StressSettings) -> Any:
    """The consistent configuration of a Liu filter (``liu2020.ukf_icr`` -> ``UkfIcrConsistent``),
    calibrated on ``s.calib_scenario`` seed ``s.calib_seed`` (a run no stress case uses)."""
    from bench import registry
    from bench.sim import simulate
    from bench.spec import load_scenario

    return registry.calibrate(registry.get(f"{name}_consistent"),
                              [simulate(load_scenario(s.calib_scenario), s.calib_seed)])


def _variants(name: str, s: StressSettings) -> list[tuple[str, Any]]:
    out = [("paper", liu_method(name)), ("icr_hold", liu_method(name, s.gnss_timeout))]
    if s.consistent:
        out.append(("consistent", liu_consistent_method(name, s)))
    return out


def _yi_method(name: str) -> Any:
    from bench import registry

    return registry.get(name, store_covariance=True)


def fault_cases(run: Run, s: StressSettings, t0: float | None = None, gnss: bool = True
                ) -> dict[str, tuple[Run, float, float]]:
    """name -> (run, fault start, fault end) for the short runs (the "none" case is the clean run
    with the GNSS-outage window)."""
    t0 = s.t0 if t0 is None else t0
    spikes = [t0 + o for o in s.spike_offsets]
    out = {"none": (run, t0, t0 + s.outage)}
    if gnss:
        out["gnss_outage"] = (F.gnss_outage(run, t0, t0 + s.outage), t0, t0 + s.outage)
    out["imu_spikes"] = (F.imu_saturation_spikes(run, spikes, s.spike_magnitude, s.spike_seed), t0, max(spikes))
    out["encoder_dropout"] = (F.encoder_dropouts(run, t0, t0 + s.dropout), t0, t0 + s.dropout)
    return out


def _nan_count(est: Any) -> int:
    return int(sum((~np.isfinite(est[c])).sum() for c in ESTIMATE_STATE if c in est.data.columns))


def evaluate(truth_run: Run, est: Any, t0: float, t1: float, s: StressSettings, clean: Any = None) -> dict[str, Any]:
    """Recovery and health of one estimate around one fault [t0, t1]; ``clean``: the same estimator on the
    fault-free run, the reference of the paired recovery criterion (:func:`bench.robustness.faults.recovery`)."""
    t, err = F.position_error(truth_run, est)
    ref = None if clean is None else F.position_error(truth_run, clean)[1]
    rec = F.recovery(t, err, t0, t1, pre_window=s.pre_window, factor=s.factor, horizon=s.horizon, reference=ref)
    row: dict[str, Any] = {
        "pre": rec.pre, "max_fault": rec.max_fault, "max_after": rec.max_after, "max_err": rec.max_total,
        "recovery_time": rec.recovery_time, "recovered": rec.recovered_within(s.recover_within),
        "nan": _nan_count(est),
    }
    P = est.info.get("P")
    if P is not None:
        h = F.covariance_health(P)
        row.update(min_eig=h.min_eig, pd=h.positive_definite, max_asym=h.max_asymmetry)
    return row


def _speed_offset(est: Any, clean: Any, t1: float, s: StressSettings) -> float:
    """max |v_x(faulted) - v_x(fault-free)| over [t1 + recover_within, t1 + horizon]."""
    t = est.t
    m = (t >= t1 + s.recover_within) & (t <= t1 + s.horizon)
    return float(np.max(np.abs(est["vx"][m] - clean["vx"][m]))) if m.any() else math.nan


def _dur(s: StressSettings) -> dict[str, float]:
    """Duration override (none by default: the random path depends on the duration, so the short
    runs keep the scenario file's)."""
    return {} if s.duration is None else {"duration": s.duration}


def _short_liu_rows(seed: int, s: StressSettings) -> list[dict[str, Any]]:
    from bench import registry
    from bench.sim import simulate
    from bench.spec import load_scenario

    rows: list[dict[str, Any]] = []
    run = simulate(load_scenario(s.liu_scenario, _dur(s)), seed)
    cases = fault_cases(run, s)
    for name in s.liu_filters:
        for variant, m in _variants(name, s):
            clean = registry.estimate(m, run)  # the "none" case's estimate: every fault's paired reference
            for fault, (r, a, b) in cases.items():
                if variant == "icr_hold" and fault != "gnss_outage":
                    continue  # GNSS present: the hold never engages, the estimate is the paper's
                est = clean if fault == "none" else registry.estimate(m, r)
                row = {"filter": name, "variant": variant, "fault": fault, "seed": seed, "t0": a, "t1": b,
                       **evaluate(run, est, a, b, s, clean)}
                if fault == "none":
                    tt, err = F.position_error(run, est)
                    row["max_err_run"] = float(err[tt >= 5.0].max())
                rows.append(row)
    return rows


def yi_velocity_nees(run: Run, est: Any, t_min: float = 5.0) -> float:
    """Time-mean NEES of Yi's horizontal velocity (V_I x, y: state block 3:5 of its covariance, 2 dof;
    consistent: 2) against the truth, after ``t_min`` s.  The estimate's body velocity is rotated
    by its yaw (flat ground: roll and pitch ~0), the truth's by the true yaw, at the estimate's times.
    Yi has no absolute position sensor, so only the velocity block, observed by the encoder
    constraints (11)-(15), can be consistent."""
    from bench.estimation.nees import velocity_nees_series

    return float(np.mean(velocity_nees_series(run, est, t_min)))


def _short_yi_rows(seed: int, s: StressSettings) -> list[dict[str, Any]]:
    from bench import registry
    from bench.sim import simulate
    from bench.spec import load_scenario

    rows: list[dict[str, Any]] = []
    run = simulate(load_scenario(s.yi_scenario, _dur(s)), seed)
    cases = fault_cases(run, s, gnss=False)
    for name in s.yi_filters:
        m = _yi_method(name)
        clean = registry.estimate(m, run)
        for fault, (r, a, b) in cases.items():
            est = clean if fault == "none" else registry.estimate(m, r)
            row = {"filter": name, "variant": "paper", "fault": fault, "seed": seed, "t0": a, "t1": b,
                   **evaluate(run, est, a, b, s, clean)}
            row["recovered"] = None  # not defined without an absolute position sensor
            row["speed_offset"] = _speed_offset(est, clean, b, s)
            row["n_vx_updates"] = int(est.info["n_updates"]["vx"])
            if fault == "none":
                row["vel_nees"] = yi_velocity_nees(run, est)
            rows.append(row)
    return rows


def _hour_rows(platform: str, s: StressSettings) -> list[dict[str, Any]]:
    """One long run with all faults (spikes, encoder dropout, GNSS outage at ``hour_fault_times``)."""
    from bench import registry
    from bench.sim import simulate
    from bench.spec import load_scenario

    ts, td, tg = s.hour_fault_times
    liu = platform == "liu"
    run = simulate(load_scenario(s.liu_scenario if liu else s.yi_scenario, {"duration": s.hour}), s.hour_seed)
    faulted = F.imu_saturation_spikes(run, [ts + o for o in s.spike_offsets], s.spike_magnitude, s.spike_seed)
    faulted = F.encoder_dropouts(faulted, td, td + s.dropout)
    windows = {"imu_spikes": (ts, ts + max(s.spike_offsets)), "encoder_dropout": (td, td + s.dropout)}
    if liu:
        faulted = F.gnss_outage(faulted, tg, tg + s.outage)
        windows["gnss_outage"] = (tg, tg + s.outage)
    rows = []
    methods: list[tuple[str, str, Any]] = []
    if liu:
        for name in s.liu_filters:
            methods += [(name, variant, m) for variant, m in _variants(name, s)]
    else:
        methods += [(name, "paper", _yi_method(name)) for name in s.yi_filters]
    for name, variant, m in methods:
        est = registry.estimate(m, faulted)
        t, err = F.position_error(run, est)
        h = F.covariance_health(est.info["P"])
        base = {"filter": name, "variant": variant, "seed": s.hour_seed, "duration": s.hour, "nan": _nan_count(est),
                "min_eig": h.min_eig, "pd": h.positive_definite, "max_asym": h.max_asymmetry,
                "max_err_run": float(err[t >= 5.0].max()), "final_err": float(err[-1])}
        if liu:
            fix = np.isfinite(faulted["gnss_x"]) & np.isfinite(faulted["gnss_y"])
            fix[0] = False  # step 0 holds the prior P0, not an update
            P = est.info["P"]
            base["max_pos_std_at_fix"] = float(np.sqrt(np.maximum(P[fix, 0, 0], P[fix, 1, 1])).max())
            base["r_gnss_pos"] = float(m.params.r_gnss[0])
        for fault, (a, b) in windows.items():
            if variant == "icr_hold" and fault != "gnss_outage":
                continue  # the hold engages only without GNSS: elsewhere the estimate is the paper's
            rec = F.recovery(t, err, a, b, pre_window=s.pre_window, factor=s.factor, horizon=s.horizon)
            rows.append({**base, "fault": fault, "t0": a, "t1": b, "pre": rec.pre, "max_err": rec.max_total,
                         "recovery_time": rec.recovery_time,
                         "recovered": rec.recovered_within(s.recover_within) if liu else None})
        del est
    return rows


def _task(args: tuple[str, Any, StressSettings]) -> list[dict[str, Any]]:
    kind, key, s = args
    fn = {"liu": _short_liu_rows, "yi": _short_yi_rows, "hour": _hour_rows}[kind]
    return fn(key, s)


def stress_rows(s: StressSettings = QUICK, workers: int | None = None) -> list[dict[str, Any]]:
    """Every case of ``s`` (short runs per seed and platform, and the long runs if ``s.hour``) in a
    fixed order, computed by ``workers`` processes (default: CPU count, at most the number of
    tasks; the long tasks are started first).  Deterministic: the order of the rows does not depend
    on the scheduling."""
    tasks: list[tuple[str, Any, StressSettings]] = []
    for seed in s.seeds:
        tasks += [(p, seed, s) for p, names in (("liu", s.liu_filters), ("yi", s.yi_filters)) if names]
    if s.hour > 0:
        tasks += [("hour", p, s) for p, names in (("liu", s.liu_filters), ("yi", s.yi_filters)) if names]
    order = sorted(range(len(tasks)), key=lambda i: (tasks[i][0] != "hour", i))  # long tasks first
    n = max(1, min(workers or os.cpu_count() or 1, len(tasks)))
    if n == 1:
        done = [_task(tasks[i]) for i in order]
    else:
        with process_pool(n) as pool:
            done = list(pool.map(_task, [tasks[i] for i in order]))
    parts: list[list[dict[str, Any]]] = [[] for _ in tasks]
    for i, part in zip(order, done):
        parts[i] = part
    return [r for part in parts for r in part]


# --------------------------------------------------------------------------------------------
# Markdown
# --------------------------------------------------------------------------------------------
def _f(x: Any, nd: int = 3) -> str:
    if x is None:
        return "n/a"
    if isinstance(x, bool):
        return "yes" if x else "**no**"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "not recovered (> horizon)"
    return f"{x:.{nd}g}" if abs(x) < 1e-3 else f"{x:.{nd}f}"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def _fmt_dur(s: StressSettings) -> str:
    if s.duration is not None:
        return f"{s.duration:g} s"
    from bench.spec import load_scenario

    return f"{load_scenario(s.liu_scenario).duration:g} s (DUBHE) / {load_scenario(s.yi_scenario).duration:g} s (Yi)"


def stress_markdown(rows: Sequence[Mapping[str, Any]], s: StressSettings) -> str:
    short = [r for r in rows if "duration" not in r]
    hour = [r for r in rows if "duration" in r]
    L = [
        "# Filters under stress",
        "",
        "Generated by `bench.robustness.stress.stress_report` (tests: `tests/test_stress.py`). Faults from `bench/robustness/faults.py`,",
        "applied to the simulated run of each seed (truth untouched). Position error = |estimate - truth| (m).",
        "",
        "* **pre**: pre-fault level = 95th percentile of the 1 s trailing-mean error over the "
        f"{s.pre_window:g} s before the fault.",
        f"* **recovery**: time after the fault's end from which the 1 s trailing-mean error stays <= {s.factor:g} x the "
        "larger of pre and the same filter's (1 s trailing-mean) error on the fault-free run at that time (paired: the "
        f"error the path itself causes is not the fault's; the 1-hour runs have no fault-free twin and use pre alone) "
        f"up to {s.horizon:g} s after the fault; criterion: within {s.recover_within:g} s.",
        "* **max err**: max error from the fault's start to the end of the horizon. **NaN**: non-finite values of "
        "x, y, yaw, vx, vy, wz. **min eig P**: smallest eigenvalue of the posterior covariance over all steps "
        "(**PD**: finite, symmetric and > 0 at every step).",
        "* Fault `none` is the fault-free run scored on the GNSS-outage window (the criterion's false-alarm check); "
        "its **max err (run)** is the max over the whole run after 5 s.",
        f"* Faults at t0 = {s.t0:g} s of {_fmt_dur(s)} runs: GNSS outage {s.outage:g} s (Liu only: Yi's EKF reads "
        f"no GNSS); IMU spikes at t0 + {', '.join(f'{o:g}' for o in s.spike_offsets)} s, {s.spike_magnitude:g} x full "
        f"scale on all six channels, clipped at the saturation; encoder dropout {s.dropout:g} s.",
        f"* Liu `icr_hold`: `LiuUkfParams(icr_hold_gnss_timeout={s.gnss_timeout:g})`, the ICR held through the "
        "outage at its least-squares fit over the last 20 s with GNSS (Liu Sec. IV-A; see methods/liu2020/icr.py). "
        "`paper`: the ICR recomputed after every update, as written.",
        (f"* Liu `consistent`: `methods.liu2020.UkfIcrConsistent` / `MiUkfConsistent` (no encoder pose pseudo-measurement, "
         f"GNSS bias states, noise identified on {s.calib_scenario} seed {s.calib_seed}; see results/liu2020/"
         "nees_consistency.md); its position covariance grows through the outage, so the returning GNSS fixes pull the "
         "estimate back (UKF+ICR's covariance covers its outage error; MI-UKF's does not: the multi-innovation "
         "correction is not in its covariance update, see tests/test_stress.py)." if s.consistent else
         "* Liu's consistent configurations (skidbench's own, `methods.liu2020.UkfIcrConsistent` / `MiUkfConsistent`) "
         "under the same faults: `skidbench reproduce stress --extended` (results/extended/stress.md; half of this "
         "report's time, so not in `make reproduce`, as in the league table)."),
        "* Yi 2009: no absolute position sensor, so the position error grows and **recovery is not defined**; "
        "the column *speed offset* gives max |v_x(faulted) - v_x(fault-free)| over 10-30 s after the fault "
        "(v_x is observed by the encoders).",
        "",
    ]
    keys = sorted({(r["filter"], r["variant"], r["fault"]) for r in short},
                  key=lambda k: (k[0], ("none", "gnss_outage", "imu_spikes", "encoder_dropout").index(k[2]), k[1]))
    if len(s.seeds) == 1:
        L.append(f"## Short runs (seed {s.seeds[0]})")
    else:
        L.append(f"## Short runs, seeds {', '.join(map(str, s.seeds))}: per-seed values, then a summary")
    L.append("")
    hdr = ["filter", "variant", "fault", "seed", "pre [m]", "max err [m]", "recovery [s]", "recovered", "NaN",
           "min eig P", "PD", "max err (run) / speed offset"]
    body = []
    for k in keys:
        for r in sorted((r for r in short if (r["filter"], r["variant"], r["fault"]) == k), key=lambda r: r["seed"]):
            extra = _f(r.get("max_err_run")) if "max_err_run" in r else (
                f"{_f(r['speed_offset'])} m/s" if "speed_offset" in r else "")
            body.append([r["filter"], r["variant"], r["fault"], str(r["seed"]), _f(r["pre"]), _f(r["max_err"]),
                         _f(r["recovery_time"], 2), _f(r["recovered"]), str(r["nan"]), _f(r.get("min_eig")),
                         _f(r.get("pd")), extra])
    L += _table(hdr, body)
    if len(s.seeds) > 1:
        L += ["", "### Summary over seeds", ""]
        sb = []
        for k in keys:
            rs = [r for r in short if (r["filter"], r["variant"], r["fault"]) == k]
            rec = [r["recovered"] for r in rs if r["recovered"] is not None]
            sb.append([k[0], k[1], k[2], str(len(rs)), _f(float(np.median([r["max_err"] for r in rs]))),
                       _f(max(r["max_err"] for r in rs)),
                       _f(float(np.median([r["recovery_time"] for r in rs])), 2),
                       f"{sum(rec)}/{len(rec)}" if rec else "n/a", str(sum(r["nan"] for r in rs)),
                       _f(min(r.get("min_eig", math.nan) for r in rs)), _f(all(r.get("pd", False) for r in rs))])
        L += _table(["filter", "variant", "fault", "seeds", "median max err", "worst max err", "median recovery [s]",
                     "recovered within criterion", "NaN", "min eig P", "PD all"], sb)
    if hour:
        dur = hour[0]["duration"]
        ts, td, tg = s.hour_fault_times
        L += ["", f"## {dur / 3600:g}-hour runs (seed {s.hour_seed}), all faults in one run", "",
              f"IMU spikes at {ts:g} s, encoder dropout {td:g}-{td + s.dropout:g} s, GNSS outage {tg:g}-{tg + s.outage:g} s "
              "(Liu only). *pos std at fixes*: max over the steps with a GNSS fix (after the first step) of the posterior "
              "position standard deviation; with a direct position measurement of std r_gnss it cannot exceed r_gnss "
              "(the GNSS fix alone is an estimate with that error).", ""]
        hb = []
        for r in hour:
            hb.append([r["filter"], r["variant"], r["fault"], _f(r["pre"]), _f(r["max_err"]), _f(r["recovery_time"], 2),
                       _f(r["recovered"]), str(r["nan"]), _f(r["min_eig"]), _f(r["pd"]), _f(r["max_err_run"]),
                       _f(r["final_err"]),
                       f"{_f(r['max_pos_std_at_fix'])} (r_gnss {r['r_gnss_pos']:g})" if "max_pos_std_at_fix" in r else "n/a"])
        L += _table(["filter", "variant", "fault", "pre [m]", "max err [m]", "recovery [s]", "recovered", "NaN",
                     "min eig P", "PD", "max err over the run [m]", "final err [m]", "pos std at fixes [m]"], hb)
    yi_nees = [r for r in short if "vel_nees" in r]
    if yi_nees:
        L += ["", "### Yi 2009: velocity NEES on the fault-free run", "",
              "Time mean after 5 s of the NEES of the horizontal velocity (V_I x, y; 2 dof, consistent: 2; the "
              "single-run 95% band of one step is [0.05, 7.38]); Yi has no absolute position sensor, so the velocity "
              "block, observed by the encoder constraints, is the only one that can be consistent.", ""]
        L += _table(["filter", "seed", "velocity NEES (2 dof)"],
                    [[r["filter"], str(r["seed"]), _f(r["vel_nees"], 2)] for r in sorted(yi_nees, key=lambda r: (r["filter"], r["seed"]))])
    fails = [r for r in rows if r.get("recovered") is False and r["fault"] != "none"]
    alarms = [r for r in rows if r.get("recovered") is False and r["fault"] == "none"]
    bad_cov = [r for r in rows if r.get("pd") is False or r["nan"]]
    excursions = [r for r in rows if r["fault"] == "none" and r.get("max_err_run", 0.0) > 1.0]
    L += ["", "## Verdict", ""]
    L.append(f"* NaN or covariance not positive definite: {len(bad_cov)} case(s)"
             + (": " + "; ".join(f"{r['filter']}/{r['variant']}/{r['fault']}/seed {r['seed']}" for r in bad_cov) if bad_cov else "."))
    L.append(f"* Recovery criterion failed: {len(fails)} case(s)" + (": " + "; ".join(
        f"{r['filter']}/{r['variant']}/{r['fault']}/seed {r['seed']}{' (1 h)' if 'duration' in r else ''} "
        f"({_f(r['recovery_time'], 2)} s, max {_f(r['max_err'])} m, pre {_f(r['pre'])} m)" for r in fails) if fails else "."))
    L.append(f"* False alarms of the criterion on fault-free runs: {len(alarms)} case(s)" + (": " + "; ".join(
        f"{r['filter']}/seed {r['seed']} ({_f(r['recovery_time'], 2)} s)" for r in alarms) if alarms else "."))
    L.append(f"* Fault-free Liu runs with a position error above 1 m (an excursion without any fault): "
             f"{len(excursions)} case(s)" + (": " + "; ".join(
                 f"{r['filter']}/seed {r['seed']} (max {_f(r['max_err_run'])} m)" for r in excursions) if excursions else "."))
    return "\n".join(L) + "\n"


def stress_report(out_dir: str | Path, quick: bool = True, settings: StressSettings | None = None,
                  workers: int | None = None, extended: bool = False) -> Path:
    """Run the stress cases (:data:`QUICK` or :data:`FULL`) and write ``<out_dir>/stress.md``
    atomically; returns its path.  Signature fits ``bench.cli.reproduce.register_extra``.  Liu's consistent
    configurations (skidbench's own, like the league's ``*_consistent``) run only with ``extended``."""
    from bench.report.io import atomic_write_text

    s = settings or dataclasses.replace(QUICK if quick else FULL, consistent=extended)
    rows = stress_rows(s, workers)
    path = Path(out_dir) / "stress.md"
    atomic_write_text(path, stress_markdown(rows, s))
    return path
