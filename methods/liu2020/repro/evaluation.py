"""The Liu 2020 reproduction's shared evaluation: settings, the methods compared, one batch of runs
simulated, calibrated, estimated and scored once per reproduction (:func:`_evaluate`, memoised in
``ctx.info``), and the per-run scores every table reads (:mod:`methods.liu2020.repro.tables`,
:mod:`methods.liu2020.repro.consistency`, :mod:`methods.liu2020.repro.figures`).

The choices (scenarios, seeds, reference, intervals, calibration, steady window) are listed in
:mod:`methods.liu2020.repro`.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from bench.reproduce import mean_ci
from bench.reproduce import published_values as _published_values
from bench import registry
from bench.metrics import Trajectory, final_position_error, position_rms, velocity_rms
from bench.registry import Estimate
from bench.run import Run
from bench.spec import Scenario, load_scenario
from bench.estimation.ukf import nees as nees_values
from bench.estimation.ukf import FilterError, wrap
from bench.robustness.faults import gnss_outage
from methods.liu2020 import MiUkfConsistent, SlipDr, UkfIcrConsistent, run_liu_filter
from methods.liu2020.inputs import geometry
from methods.liu2020.model import _gnss_block

SCENARIOS = {"s1": "liu_straight", "s2": "liu_large_radius", "s3": "liu_small_radius"}
METHODS = {"en_dr": "liu2020.en_dr", "icr": "liu2020.icr", "ukf_icr": "liu2020.ukf_icr", "mi_ukf": "liu2020.mi_ukf"}
FILTERS = ("ukf_icr", "mi_ukf")
# consistent configuration of the two filters (methods.liu2020.UkfIcrConsistent / MiUkfConsistent): noise
# identified on the calibration run, reported beside the paper's filters in the NEES and outage tables only
CONSISTENT = {"ukf_icr_c": "liu2020.ukf_icr_consistent", "mi_ukf_c": "liu2020.mi_ukf_consistent"}
ALL_FILTERS = (*FILTERS, *CONSISTENT)
LABELS = {"en_dr": "En-DR", "icr": "ICR", "ukf_icr": "UKF+ICR", "mi_ukf": "MI-UKF", "truth": "truth", "gnss": "GNSS",
          "ukf_icr_c": "UKF+ICR (consistent)", "mi_ukf_c": "MI-UKF (consistent)"}
COLORS = {"en_dr": "0.55", "icr": "tab:blue", "ukf_icr": "tab:green", "mi_ukf": "tab:red", "truth": "k", "gnss": "tab:orange",
          "ukf_icr_c": "tab:olive", "mi_ukf_c": "tab:purple"}
ESTIMATE_COLUMNS = ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr")
_CACHE_KEY = "_liu2020_evaluation"


@dataclass(frozen=True)
class Settings:
    """Experiment settings of the reproduction (SI units)."""

    seeds_full: tuple[int, ...] = (0, 1, 2, 3, 4)
    seeds_quick: tuple[int, ...] = (0, 1)
    quick_duration: float = 12.0  # [s] scored scenarios in quick mode
    calib_scenario: str = "liu_calib"
    calib_seed: int = 100
    samepath_seed: int = 100  # same-scenario calibration (sensitivity check only)
    steady_t0: float = 5.0  # [s] start of the steady window
    sweep_speed: float = 3.0  # [m/s]
    sweep_radii: tuple[float, ...] = (8.0, 4.0, 2.0)  # [m]; 17 m is scenario 2 itself
    # scenario 1 as Liu drove it (Sec. V-B-1: heading 1.18 -> 0.67 rad, ~8 s of motion from 14 s to the
    # deceleration after 22 s, Figs. 8, 10): -0.064 rad/s at 4 m/s, radius 63 m clockwise; used by the ICR
    # smoothness claim s2 vs s1 only (the testbed straight has no yaw rate: its ICR does not exist)
    s1_liu_radius: float = -63.0  # [m], + CCW
    heading_initial_yaw: float = -2.8  # [rad]
    heading_margin: float = 0.02  # [rad]
    outage: tuple[float, float] = (8.0, 28.0)  # [s]
    # Liu's outage (Sec. IV-C, after eq. (32)): "the dimension of the measurement vector will descend to 9x1 with
    # the position readings deleted": GNSS x, y go (and with them the heading row: model._gnss_block), the GNSS
    # velocity stays
    outage_9x1_channels: tuple[str, ...] = ("gnss_x", "gnss_y")
    outage_duration: float = 30.0  # [s]
    confidence: float = 0.95
    # ICR statistics only over the steady samples where the ICR exists (the testbed truth defines it at
    # |yaw rate| >= 1e-3 rad/s, bench.sim); NaN when fewer than this fraction of the window has one
    icr_defined_fraction: float = 0.5


SETTINGS = Settings()


def published_values(table_id: str) -> dict[str, float]:
    """Published numbers of a table as declared in ``scenarios/papers/liu2020.toml`` (metric -> value)."""
    return _published_values("liu2020", table_id)


def _steady(run: Run, t0: float) -> np.ndarray:
    return run.t >= t0


def _gnss_body_velocity(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, v_x, v_y) of the GNSS fixes in the body frame (world velocity rotated by the GNSS heading)."""
    gx, gy, gyaw = run["gnss_vx"], run["gnss_vy"], run["gnss_yaw"]
    m = np.isfinite(gx) & np.isfinite(gy) & np.isfinite(gyaw)
    c, s = np.cos(gyaw[m]), np.sin(gyaw[m])
    return run.t[m], c * gx[m] + s * gy[m], -s * gx[m] + c * gy[m]


def _state_error(run: Run, est: Estimate) -> np.ndarray:
    """(T, 6) estimate minus truth: X, Y, wrapped phi, v_x, v_y, yaw rate."""
    return np.column_stack((est["x"] - run["truth_x"], est["y"] - run["truth_y"], wrap(est["yaw"] - run["truth_yaw"]),
                            est["vx"] - run["truth_vx"], est["vy"] - run["truth_vy"], est["wz"] - run["truth_wz"]))


def _score(run: Run, est: Estimate) -> dict[str, float]:
    """Per-run scores of one estimate (truth and GNSS references)."""
    e = Trajectory.from_estimate(est)
    truth = Trajectory.from_run(run, "truth")
    out = {"rms": position_rms(truth, e), "rms_gnss": position_rms(Trajectory.from_run(run, "gnss"), e),
           "final": final_position_error(truth, e)}
    g = np.isfinite(run["gnss_x"]) & np.isfinite(run["gnss_y"])  # Sec. V-C-1: "difference between GNSS and MI-UKF"
    out["max_gnss"] = float(np.max(np.hypot(est["x"][g] - run["gnss_x"][g], est["y"][g] - run["gnss_y"][g])))
    dyaw = wrap(est["yaw"] - run["truth_yaw"])
    out["yaw_rms"] = float(np.sqrt(np.mean(dyaw * dyaw)))
    ref = {c: run[f"truth_{c}"] for c in ("vx", "vy", "wz")}
    out.update({f"{c}_rms": v for c, v in velocity_rms(run.t, ref, est["t"], {c: est[c] for c in ("vx", "vy", "wz")}).items()})
    out["v_rms"] = math.hypot(out["vx_rms"], out["vy_rms"])
    # against the GNSS body velocity (Liu's reference for the velocity figures, Secs. V-B-2, V-C-2)
    gx, gy, gyaw = run["gnss_vx"], run["gnss_vy"], run["gnss_yaw"]
    gm = np.isfinite(gx) & np.isfinite(gy) & np.isfinite(gyaw)
    c, s_ = np.cos(gyaw[gm]), np.sin(gyaw[gm])
    out["v_rms_gnss"] = float(np.sqrt(np.mean((est["vx"][gm] - (c * gx[gm] + s_ * gy[gm])) ** 2
                                              + (est["vy"][gm] - (-s_ * gx[gm] + c * gy[gm])) ** 2)))
    return out


def _cv(v: np.ndarray) -> float:
    """std / |mean| of the finite values (NaN when none)."""
    v = v[np.isfinite(v)]
    return float(np.std(v) / abs(np.mean(v))) if v.size else math.nan


def _icr_stats(run: Run, est: Estimate, t0: float) -> dict[str, float]:
    """ICR means and spread over the steady window (t >= t0), restricted to the samples where the ICR
    exists (truth yaw rate at least bench.sim's 1e-3 rad/s: ``truth_y_l`` finite); NaN when fewer than
    ``SETTINGS.icr_defined_fraction`` of the window has one (a straight line: eqs. (2), (3), (5) are 0/0).
    ``cv_icr`` / ``cv_slip``: std/|mean| of y_l, y_r and of the slip rates s_l, s_r (mean of the two)."""
    w = _steady(run, t0)
    d = w & np.isfinite(run["truth_y_l"])
    out = {"wz": float(np.mean(est["wz"][w])), "vx": float(np.mean(est["vx"][w])),
           "defined": float(d.sum() / max(w.sum(), 1))}
    if d.sum() < SETTINGS.icr_defined_fraction * w.sum() or not d.any():
        return {**out, **{q: math.nan for q in ("y_l", "y_r", "x_icr", "icr_std", "cv_icr", "cv_slip")}}
    return {**out, "y_l": float(np.mean(est["y_l"][d])), "y_r": float(np.mean(est["y_r"][d])),
            "x_icr": float(np.mean(est["x_icr"][d])),
            "icr_std": 0.5 * float(np.std(est["y_l"][d]) + np.std(est["y_r"][d])),
            "cv_icr": 0.5 * (_cv(est["y_l"][d]) + _cv(est["y_r"][d])),
            "cv_slip": 0.5 * (_cv(est["slip_l"][d]) + _cv(est["slip_r"][d]))}


def _heading_excess(run: Run, est: Estimate, margin: float) -> np.ndarray:
    steps = np.abs(wrap(np.diff(est["yaw"])))
    return steps - (np.abs(run["truth_wz"][1:]) * np.diff(run.t) + margin)


@dataclass(frozen=True)
class ScenarioResult:
    """Everything measured on one scored scenario (all seeds)."""

    key: str
    seeds: tuple[int, ...]
    scores: Mapping[str, tuple[Mapping[str, float], ...]]  # method -> per-seed scores (+ "icr_samepath")
    icr_stats: Mapping[str, tuple[Mapping[str, float], ...]]  # filter -> per-seed ICR statistics
    nees6: Mapping[str, np.ndarray]  # filter -> (n_seeds, T - 1)
    nees3: Mapping[str, np.ndarray]
    truth_stats: Mapping[str, float]
    run0: Run
    est0: Mapping[str, Estimate]
    samepath_icr: tuple[float, float, float]

    def mean(self, method: str, metric: str) -> tuple[float, float, float]:
        return mean_ci([s[metric] for s in self.scores[method]], SETTINGS.confidence)


@dataclass(frozen=True)
class Evaluation:
    seeds: tuple[int, ...]
    quick: bool
    calib_icr: tuple[float, float, float]
    calib_info: Mapping[str, Any]
    scenarios: Mapping[str, ScenarioResult]
    sweep: Mapping[float, tuple[Mapping[str, float], ...]]  # radius -> per-seed MI-UKF ICR stats (+ abs_wz)
    s1_liu: tuple[Mapping[str, float], ...]  # scenario 1 as Liu drove it: per-seed MI-UKF ICR stats (+ abs_wz)
    nodrift: Mapping[str, Mapping[str, tuple[float, ...]]]  # scenario -> filter -> per-seed RMS, GNSS drift removed
    slip_info: Mapping[str, float]  # the slip model fitted on the calibration run (s_l, s_r, beta, fit_rms)
    heading_runs: tuple[Run, ...]
    heading_est: Mapping[str, tuple[Estimate, ...]]
    outage_runs: tuple[Run, ...]  # no GNSS channel in the outage (our check, beyond the paper)
    outage_est: Mapping[str, tuple[Estimate, ...]]
    outage_9x1_runs: tuple[Run, ...]  # Liu's 9x1 mode: GNSS position and heading deleted, velocity kept
    outage_9x1_est: Mapping[str, tuple[Estimate, ...]]  # the paper's filters (FILTERS)


def _scenario(name: str, duration: float | None, **overrides: Any) -> Scenario:
    ov = dict(overrides)
    if duration is not None:
        ov["duration"] = duration
    return load_scenario(name, ov)


def _nanmean(v: np.ndarray) -> float:
    """Mean of the finite values; NaN when there is none (truth ICR on a straight path)."""
    ok = np.isfinite(v)
    return float(np.mean(v[ok])) if ok.any() else math.nan


_BLOCKS = {"pos": slice(0, 2), "yaw": slice(2, 3), "vel": slice(3, 5), "wz": slice(5, 6)}


def _score_scenario(key: str, runs: Sequence[Run], methods: Mapping[str, Any], extras: Mapping[str, Any],
                    cfg: Settings) -> ScenarioResult:
    """Estimate every method on every seed of one scenario and collect scores, ICR statistics, NEES.
    ``extras``: scored beside the methods, in no table of the paper's four (``icr_samepath``: the ICR
    method calibrated on the same scenario; ``slip_dr``: the traditional slip model)."""
    seeds = tuple(int(r.meta["seed"]) for r in runs)
    scores: dict[str, list[dict[str, float]]] = {m: [] for m in (*methods, *extras)}
    filters = [f for f in ALL_FILTERS if f in methods]
    icr_stats: dict[str, list[dict[str, float]]] = {f: [] for f in filters}
    n6: dict[str, list[np.ndarray]] = {f: [] for f in filters}
    n3: dict[str, list[np.ndarray]] = {f: [] for f in filters}
    est0: dict[str, Estimate] = {}
    gnss_err = []
    for i, run in enumerate(runs):
        for m, meth in (*methods.items(), *extras.items()):
            est = registry.estimate(meth, run)
            scores[m].append(_score(run, est))
            if m in filters:
                err, P = _state_error(run, est)[1:], est.info["P"][1:]
                st = _icr_stats(run, est, cfg.steady_t0)
                st["pos_sd"] = float(np.mean(np.sqrt(P[:, 0, 0] + P[:, 1, 1])))  # the filter's claimed position error
                for blk, sl in _BLOCKS.items():  # time-mean NEES of each state block (diagnosis)
                    st[f"nees_{blk}"] = float(np.mean(nees_values(err[:, sl], P[:, sl, sl])))
                icr_stats[m].append(st)
                n6[m].append(nees_values(err, P))
                n3[m].append(nees_values(err[:, :3], P[:, :3, :3]))
            if i == 0:
                est0[m] = est
        g = np.isfinite(run["gnss_x"])  # the GNSS error itself (drift + noise), read from truth by the reproduction
        gnss_err.append(float(np.sqrt(np.mean((run["gnss_x"][g] - run["truth_x"][g]) ** 2
                                              + (run["gnss_y"][g] - run["truth_y"][g]) ** 2))))
    run0 = runs[0]
    w = _steady(run0, cfg.steady_t0)
    tg, gvx, gvy = _gnss_body_velocity(run0)
    gs = tg >= cfg.steady_t0
    geo = geometry(run0)
    v_l, v_r = geo.wheel_radius * run0["enc_wl"][w], geo.wheel_radius * run0["enc_wr"][w]
    v_tread, w_tread = _nanmean(0.5 * (v_l + v_r)), _nanmean((v_r - v_l) / geo.track)
    gyro = _nanmean(run0["imu_gz"][w])
    truth_stats = {
        # the sensors' view of the steady motion (Sec. V-D: GNSS vs encoder): encoder tread speed and the
        # no-slip (En-DR) turn radius, GNSS speed / gyro radius and GNSS sideslip angle
        "v_tread": v_tread, "wz_tread": w_tread, "wz_gyro": gyro,
        "radius_en_dr": abs(v_tread / w_tread) if w_tread else math.inf,
        "radius_gnss": float(np.mean(np.hypot(gvx[gs], gvy[gs]))) / abs(gyro) if gyro else math.inf,
        "sideslip_gnss_deg": math.degrees(float(np.mean(np.arctan(gvy[gs] / gvx[gs])))),
        "abs_wz": float(np.mean(np.abs(run0["truth_wz"][w]))), "wz": float(np.mean(run0["truth_wz"][w])),
        "vx": float(np.mean(run0["truth_vx"][w])), "vx_gnss": float(np.mean(gvx[tg >= cfg.steady_t0])),
        "abs_slip": _nanmean(np.abs(np.concatenate((run0["truth_slip_l"][w], run0["truth_slip_r"][w])))),
        "gnss_err_rms": float(np.mean(gnss_err)),
        "y_l": _nanmean(run0["truth_y_l"][w]), "y_r": _nanmean(run0["truth_y_r"][w]),
        "x_icr": _nanmean(run0["truth_x_icr"][w]),
    }
    return ScenarioResult(
        key, seeds, {m: tuple(v) for m, v in scores.items()}, {m: tuple(v) for m, v in icr_stats.items()},
        {m: np.vstack(v) for m, v in n6.items()}, {m: np.vstack(v) for m, v in n3.items()}, truth_stats,
        run0, est0, (float(extras["icr_samepath"].y_l), float(extras["icr_samepath"].y_r),
                     float(extras["icr_samepath"].x_icr)))


def _consistent_method(name: str) -> Any:
    """A consistent-configuration filter: from the registry once its entry point is installed, else
    the class itself (methods.liu2020)."""
    try:
        return registry.get(name)
    except KeyError:
        return {c.name: c for c in (UkfIcrConsistent, MiUkfConsistent)}[name]()


OUTAGE_COLUMNS = ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr")


def _outage_estimate(method: Any, run: Run) -> Estimate:
    """The estimate through the GNSS outage.  A filter that stops there on a non-finite or non-positive-definite
    covariance (:class:`bench.estimation.ukf.FilterError`) gives NaN at every step and a NaN covariance, with the
    error in ``info``: the outage check (``outage.no_nan``) then fails instead of the whole reproduction."""
    try:
        return registry.estimate(method, run)
    except FilterError as exc:
        n = run.t.size
        data = pd.DataFrame({"t": run.t} | {c: np.full(n, np.nan) for c in OUTAGE_COLUMNS})
        return Estimate(data, getattr(method, "name", ""), {"P": np.full((n, 6, 6), np.nan), "error": str(exc)})


def _evaluate(ctx: Any) -> Evaluation:
    """Simulate every run (one batch through the runner), calibrate, estimate and score; memoised in
    ``ctx.info`` for the other compute functions of the same reproduction."""
    cached = ctx.info.get(_CACHE_KEY)
    if cached is not None:
        return cached
    cfg = SETTINGS
    quick = bool(ctx.quick)
    seeds = cfg.seeds_quick if quick else cfg.seeds_full
    ctx.info["seeds"] = list(seeds)
    dur = cfg.quick_duration if quick else None
    scored = {k: _scenario(n, dur) for k, n in SCENARIOS.items()}
    sweep_dur = dur if dur is not None else scored["s2"].duration
    sweep = {r: _scenario(SCENARIOS["s2"], sweep_dur, **{"command.segments": [[sweep_dur, cfg.sweep_speed, r]]})
             for r in cfg.sweep_radii}
    s1_dur = dur if dur is not None else scored["s1"].duration
    s1_liu = _scenario(SCENARIOS["s1"], s1_dur, **{"command.segments": [[s1_dur, scored["s1"].command.segments[0].a,
                                                                            cfg.s1_liu_radius]]})
    # Liu's protocol for the GNSS (Sec. IV-C, Figs. 3-4): the zero drift is removed at the start; here the
    # testbed's initial drift is set to 0 instead (a protocol variant of the scored scenarios, mi_vs_ukf_nodrift)
    nodrift = {k: _scenario(SCENARIOS[k], dur, **{"platform.sensors.gnss.initial_drift": 0.0}) for k in scored}
    heading_scn = _scenario(SCENARIOS["s3"], dur, initial_yaw=cfg.heading_initial_yaw)
    # both outages blank the same runs (F.gnss_outage): the same physics and noise, only the deleted rows differ
    outage_scn = _scenario(SCENARIOS["s2"], cfg.outage_duration)
    calib_scn = load_scenario(cfg.calib_scenario)

    tags: list[tuple[Any, ...]] = [("calib",)]
    reqs: list[tuple[Scenario, int]] = [(calib_scn, cfg.calib_seed)]
    for k, scn in scored.items():
        tags.append(("samepath", k))
        reqs.append((scn, cfg.samepath_seed))
        for s in seeds:
            tags.append(("scored", k, s))
            reqs.append((scn, s))
    for r, scn in sweep.items():
        for s in seeds:
            tags.append(("sweep", r, s))
            reqs.append((scn, s))
    for s in seeds:
        tags += [("heading", s), ("outage", s), ("s1_liu", s)]
        reqs += [(heading_scn, s), (outage_scn, s), (s1_liu, s)]
        for k, scn in nodrift.items():
            tags.append(("nodrift", k, s))
            reqs.append((scn, s))
    runs = dict(zip(tags, ctx.simulate_many(reqs)))

    calib_run = runs[("calib",)]
    methods = {m: registry.calibrate(registry.get(name), [calib_run]) for m, name in METHODS.items()}
    consistent = {m: registry.calibrate(_consistent_method(name), [calib_run]) for m, name in CONSISTENT.items()}
    ctx.info["liu2020_consistent_noise"] = {k: v for k, v in consistent["ukf_icr_c"].noise_info.items()
                                            if not k.startswith(("q_", "r1_", "nis_"))}  # shared by both filters
    ctx.info["liu2020_consistent_q"] = {m: {k: v for k, v in c.noise_info.items() if k.startswith(("q_", "nis_", "r1_"))}
                                        for m, c in consistent.items()}
    # diagnosis: the consistent filters' NEES per block on their own calibration run (truth read by the
    # reproduction only; the plugin refuses to estimate on its calibration run, so the filter is run directly)
    calib_nees: dict[str, dict[str, float]] = {}
    for m, c in consistent.items():
        est = run_liu_filter(calib_run, dataclasses.replace(c.params, store_covariance=True), c.name)
        err, P = _state_error(calib_run, est)[1:], est.info["P"][1:]
        calib_nees[m] = {blk: float(np.mean(nees_values(err[:, sl], P[:, sl, sl]))) for blk, sl in _BLOCKS.items()}
    ctx.info["liu2020_consistent_calib_nees"] = calib_nees
    # the GNSS heading / body velocity and gyro errors on the calibration run (truth; diagnosis only)
    zg = _gnss_block(calib_run)
    act = np.column_stack((zg[:, 2] - calib_run["truth_yaw"], zg[:, 3] - calib_run["truth_vx"],
                           zg[:, 4] - calib_run["truth_vy"], zg[:, 5] - calib_run["truth_wz"]))
    act[:, 0] = wrap(act[:, 0])
    sd = [float(np.sqrt(np.nanmean(act[:, j] ** 2))) for j in range(4)]
    ctx.info["liu2020_calib_actual_noise"] = {"yaw": sd[0], "vel": math.sqrt(0.5 * (sd[1] ** 2 + sd[2] ** 2)), "wz": sd[3]}
    icr_m = methods["icr"]
    calib_icr = (float(icr_m.y_l), float(icr_m.y_r), float(icr_m.x_icr))

    slip = SlipDr().calibrate([calib_run])  # the traditional slip model, fitted like the ICR method
    slip_info = {"s_l": float(slip.s_l), "s_r": float(slip.s_r), "beta": float(slip.beta),
                 "fit_rms": float(slip.fit_info["fit_rms"])}
    results = {k: _score_scenario(k, [runs[("scored", k, s)] for s in seeds], {**methods, **consistent},
                                  {"icr_samepath": registry.calibrate(registry.get(METHODS["icr"]), [runs[("samepath", k)]]),
                                   "slip_dr": slip}, cfg)
               for k in scored}

    def mi_icr_stats(run: Run) -> dict[str, float]:
        st = _icr_stats(run, registry.estimate(methods["mi_ukf"], run), cfg.steady_t0)
        st["abs_wz"] = float(np.mean(np.abs(run["truth_wz"][_steady(run, cfg.steady_t0)])))
        return st

    sweep_stats = {r: tuple(mi_icr_stats(runs[("sweep", r, s)]) for s in seeds) for r in cfg.sweep_radii}
    s1_liu_stats = tuple(mi_icr_stats(runs[("s1_liu", s)]) for s in seeds)
    truth_ref = {k: [Trajectory.from_run(runs[("nodrift", k, s)], "truth") for s in seeds] for k in scored}
    nodrift_rms = {k: {f: tuple(position_rms(tr, Trajectory.from_estimate(registry.estimate(methods[f], runs[("nodrift", k, s)])))
                                for s, tr in zip(seeds, truth_ref[k])) for f in FILTERS} for k in scored}

    heading_runs = tuple(runs[("heading", s)] for s in seeds)
    outage_runs = tuple(gnss_outage(runs[("outage", s)], *cfg.outage) for s in seeds)
    outage_9x1_runs = tuple(gnss_outage(runs[("outage", s)], *cfg.outage, channels=cfg.outage_9x1_channels)
                            for s in seeds)
    outage_9x1_est = {f: tuple(_outage_estimate(methods[f], r) for r in outage_9x1_runs) for f in FILTERS}
    heading_est = {f: tuple(registry.estimate(methods[f], r) for r in heading_runs) for f in FILTERS}
    outage_est = {m: tuple(_outage_estimate(meth, r) for r in outage_runs) for m, meth in {**methods, **consistent}.items()}
    ev = Evaluation(tuple(seeds), quick, calib_icr, dict(icr_m.fit_info), results, sweep_stats, s1_liu_stats,
                    nodrift_rms, slip_info, heading_runs, heading_est, outage_runs, outage_est, outage_9x1_runs,
                    outage_9x1_est)
    ctx.info[_CACHE_KEY] = ev
    return ev
