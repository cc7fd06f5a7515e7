"""The runs of the Yi 2009 reproduction (Figs. 3-7), simulated, calibrated, estimated and scored once.

:func:`_evaluate`: the identification runs of Fig. 4 (scheme 3's ``calibrate`` fits S(gamma) (41) on them), the
140/60 rpm runs of Fig. 3, the diagnostic speed pairs, and the scored paths (with the better-sensor sensitivity
variant) estimated by the three schemes and scored (:class:`Evaluation`, :class:`PathResult`); memoised in
``ctx.info`` for the compute functions of :mod:`methods.yi2009.repro.figures` and the NEES study.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bench import registry
from bench.metrics import Trajectory, final_position_error, position_rms
from bench.registry import Estimate
from bench.reproduce import mean_ci
from bench.run import Run
from bench.spec import Scenario, load_scenario
from methods.yi2009.ekf import Yi2009Ekf
from methods.yi2009.repro.settings import METHOD_NAMES, PATHS, S_SCENARIO, SETTINGS, VARIANTS, Settings, _geometry
from methods.yi2009.repro.vision import s_gamma_truth_point, slip_agreement, vision_slip
from methods.yi2009.s_gamma import PUBLISHED_S_GAMMA, reference_s_gamma_point

_CACHE_KEY = "_yi2009_evaluation"


@dataclass(frozen=True)
class PathResult:
    """Everything measured on one scored path (all seeds) and the diagnostics."""

    key: str
    seeds: tuple[int, ...]
    scores: Mapping[str, tuple[Mapping[str, float], ...]]  # "v1".."v3", "v3_pub", "fine_v1".. -> per seed
    truth: Mapping[str, float]  # truth diagnostics (seed independent physics)
    run0: Run
    est0: Mapping[int, Estimate]
    vision0: tuple[np.ndarray, np.ndarray]

    def mean(self, method: str, metric: str) -> tuple[float, float, float]:
        return mean_ci([s[metric] for s in self.scores[method]], SETTINGS.confidence)


@dataclass(frozen=True)
class Evaluation:
    seeds: tuple[int, ...]
    quick: bool
    calibrated: Yi2009Ekf  # scheme 3 with the fitted S(gamma)
    ident: tuple[dict[str, Any], ...]  # per identification run: terrain, rpm, gamma, S (ref), truth
    fig3: Mapping[str, dict[str, float]]  # terrain -> S (ref) and truth at 140/60 rpm
    speed: Mapping[tuple[float, float], tuple[float, float]]  # (w_L, w_R) rpm -> truth (|gamma|, S [m]), concrete
    paths: Mapping[str, PathResult]


def _ident_scenario(terrain: str, wl_rpm: float, wr_rpm: float, duration: float) -> Scenario:
    return load_scenario(S_SCENARIO[terrain], {"command.segments": [[duration, wl_rpm, wr_rpm]], "duration": duration})


def _score(run: Run, est: Estimate, vis: tuple[np.ndarray, np.ndarray], cfg: Settings, slips: bool = True
           ) -> dict[str, float]:
    """Per-run scores of one estimate."""
    e = Trajectory.from_estimate(est)
    truth = Trajectory.from_run(run, "truth")
    out = {"rms": position_rms(truth, e), "rms_ref": position_rms(Trajectory.from_run(run, "ref"), e),
           "final": final_position_error(truth, e)}
    if not slips:
        return out
    t_end = float(run.t[-1]) - 0.5 * cfg.slip_window
    lam_est = np.column_stack((est["slip_l"], est["slip_r"]))
    tv, lv = vis
    a = slip_agreement(tv, lv, est["t"], lam_est, (tv >= cfg.slip_t0) & (tv <= t_end))
    out.update({"slip_rms": a["rms"], "slip_corr": a["corr"]})
    r, _ = _geometry(run)
    tt = run.t
    truth_lam = np.column_stack((run["truth_slip_l"], run["truth_slip_r"]))
    fast = (r * np.abs(run["truth_wl"]) >= cfg.slip_min_speed) & (r * np.abs(run["truth_wr"]) >= cfg.slip_min_speed)
    b = slip_agreement(tt, np.clip(truth_lam, -1.0, 1.0), est["t"], lam_est, (tt >= cfg.slip_t0) & (tt <= t_end) & fast)
    out.update({"slip_rms_truth": b["rms"], "slip_corr_truth": b["corr"]})
    moving = est["t"] >= cfg.slip_t0
    at_bound = np.nanmax(np.abs(lam_est[moving]), axis=1) >= cfg.bound_level
    out["at_bound"] = float(np.mean(at_bound))
    # issue 30's no-latch criterion: the share of the steps after slip_t0 whose slips (both sides) are within
    # slip_within of the truth's (eq. (6) of the truth, clipped as (6) is)
    lam_t = np.column_stack([np.interp(est["t"][moving], tt, np.clip(run[f"truth_slip_{s}"], -1.0, 1.0)) for s in "lr"])
    out["slip_within"] = float(np.mean(np.abs(lam_est[moving] - lam_t).max(axis=1) <= cfg.slip_within))
    te = est["t"]
    droll = est["roll"][moving] - np.interp(te[moving], tt, run["truth_roll"])
    out["roll_err"] = float(np.sqrt(np.mean(droll**2)))
    yaw_t = np.interp(te, tt, np.unwrap(run["truth_yaw"]))  # cross-track: the error normal to the true heading
    ex, ey = est["x"] - np.interp(te, tt, run["truth_x"]), est["y"] - np.interp(te, tt, run["truth_y"])
    out["cross_rms"] = float(np.sqrt(np.mean((-np.sin(yaw_t) * ex + np.cos(yaw_t) * ey) ** 2)))
    if "x_icr" in est.data.columns:
        out["s_used"] = float(np.nanmedian(est["x_icr"][moving]))
    return out


def _truth_s(run: Run, cfg: Settings) -> float | None:
    """The truth's S [m] on a path (median after ``slip_t0``), None where it has none (no turn: eq. (7) is 0/0)."""
    s = run["truth_x_icr"][run.t >= cfg.slip_t0]
    return float(np.nanmedian(s)) if np.isfinite(s).any() else None


def _truth_diagnostics(run: Run, vis: tuple[np.ndarray, np.ndarray], cfg: Settings) -> dict[str, float]:
    """Truth quantities of a scored path (declared truth): net longitudinal slip, S, yaw rate, and the
    magnitude/variation of the vision slip reference."""
    r, _ = _geometry(run)
    w = run.t >= cfg.slip_t0
    tread = 0.5 * r * (run["truth_wl"][w] + run["truth_wr"][w])
    out = {"net_slip": float(1.0 - np.sum(run["truth_vx"][w]) / np.sum(tread)),
           "abs_wz": float(np.mean(np.abs(run["truth_wz"][w])))}
    s_true = _truth_s(run, cfg)
    out["s_truth"] = math.nan if s_true is None else s_true
    tv, lv = vis
    t_end = float(run.t[-1]) - 0.5 * cfg.slip_window
    m = (tv >= cfg.slip_t0) & (tv <= t_end) & np.isfinite(lv).all(axis=1)
    out["ref_rms"] = float(np.sqrt(np.mean(lv[m] ** 2)))
    out["ref_std"] = float(np.mean(np.std(lv[m], axis=0)))
    tl = np.clip(np.column_stack((run["truth_slip_l"], run["truth_slip_r"])), -1.0, 1.0)
    fin = w & np.isfinite(tl).all(axis=1)
    out["truth_rms"] = float(np.sqrt(np.mean(tl[fin] ** 2)))
    out["ref_vs_truth"] = slip_agreement(run.t, tl, tv, lv, (run.t >= cfg.slip_t0) & (run.t <= t_end))["rms"]
    _, track = _geometry(run)
    turn = w & (np.abs(run["truth_wz"]) > cfg.turn_rate) & (np.abs(run["truth_vx"]) > 1e-3)
    out["abs_gamma"] = (float(np.median(np.abs(track * run["truth_wz"][turn] / (2.0 * run["truth_vx"][turn]))))
                        if turn.any() else math.nan)  # eq. (40) with (3), (4)
    # Sec. III-A after eq. (8): turning counterclockwise the left treads brake (lambda_L <= 0), the right pull
    # (lambda_R >= 0), and clockwise the reverse: the share of the turning steps whose truth slips have these signs
    ok = np.where(run["truth_wz"] > 0, (tl[:, 0] <= 0) & (tl[:, 1] >= 0), (tl[:, 0] >= 0) & (tl[:, 1] <= 0))
    turn &= np.isfinite(tl).all(axis=1)
    out["sign_rule"] = float(np.mean(ok[turn])) if turn.any() else math.nan
    outer_l = np.abs(run["truth_wl"]) >= np.abs(run["truth_wr"])  # the faster wheel's side is the outer one
    sides = {"outer": np.where(outer_l, tl[:, 0], tl[:, 1]), "inner": np.where(outer_l, tl[:, 1], tl[:, 0])}
    for side, col in sides.items():
        out[f"slip_{side}"] = float(np.median(col[turn])) if turn.any() else math.nan  # eq. (6), truth, turning
    # Fig. 7c: a side whose truth slip takes both signs: the smaller of its two excursions (positive and negative)
    out["sign_excursion"] = float(max(min(np.max(tl[fin, j]), -np.min(tl[fin, j])) for j in range(2)))
    return out


def gyro_roll_error(run: Run, t_min: float) -> float:
    """RMS [rad] after ``t_min`` of the roll of the direct integration of the gyro's Euler rates (10c)-(10e) from the
    filter's initial attitude (its x0), against the truth: the error an estimate without roll information
    accumulates from the gyro alone (the paper's "direct integration" of Fig. 8(a))."""
    from methods.yi2009.ekf import EkfParams, align_inputs, initial_state

    t, acc, gyr, enc = align_inputs(run)
    r, _ = _geometry(run)
    x0, _ = initial_state(acc, enc, r, EkfParams(), (0.0, 0.0, 0.0))
    phi, th = float(x0[6]), float(x0[7])
    roll = np.empty(t.size)
    roll[0] = phi
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        wx, wy, wz = gyr[k - 1]
        sf, cf = math.sin(phi), math.cos(phi)
        phi, th = phi + dt * (wx + math.tan(th) * (sf * wy + cf * wz)), th + dt * (cf * wy - sf * wz)
        roll[k] = phi
    m = t >= t_min
    return float(np.sqrt(np.mean((roll[m] - np.interp(t[m], run.t, run["truth_roll"])) ** 2)))


def attribution_estimate(model: Yi2009Ekf, run: Run, *, s_true: float | None, feedback: bool) -> Estimate:
    """Scheme 3 with one or both of its two error sources on the testbed removed (a diagnostic, not Yi's filter).

    ``s_true`` [m] (not None): S(gamma) of (41) replaced by that constant (a2 = 0, a1 = s_true a3), the truth's S on
    the path.  ``feedback`` False: the slip is not fed back into (13) (lambda' = 0 there and in gamma (40), as in
    scheme 1's v_x row; :func:`methods.yi2009.consistent.filter.run_filter_gm` with ``slip_rows="state"`` and no error
    states).  Everything else is ``model``'s filter (:meth:`Yi2009Ekf.estimate_rows`): (10), (11), (15),
    (26a)-(26f), its Q, R, x0 and P0."""
    from methods.yi2009.s_gamma import SGamma

    if model.variant != 3:
        raise ValueError(f"attribution_estimate: scheme 3 only (got {model.variant})")
    if s_true is not None:
        a3 = model.s_gamma.a3
        model = dataclasses.replace(model, s_gamma=SGamma(s_true * a3, 0.0, a3))
    return model.estimate_rows(run, "feedback" if feedback else "state", name=f"{model.name}.attribution")


def _evaluate(ctx: Any) -> Evaluation:
    """Simulate every run (one batch through the runner), calibrate S(gamma) on the identification runs,
    estimate and score the scored runs; memoised in ``ctx.info`` for the other compute functions."""
    cached = ctx.info.get(_CACHE_KEY)
    if cached is not None:
        return cached
    cfg = SETTINGS
    quick = bool(ctx.quick)
    seeds = cfg.seeds_quick if quick else cfg.seeds_full
    ctx.info["seeds"] = list(seeds)
    sens = dict(cfg.sensitivity)

    tags: list[tuple[Any, ...]] = []
    reqs: list[tuple[Scenario, int]] = []
    for i, (terrain, wl, wr) in cfg.ident(quick):
        tags.append(("ident", i))
        reqs.append((_ident_scenario(terrain, wl, wr, cfg.ident_duration), cfg.ident_seed0 + i))
    fig3_idx = {}
    for terrain in cfg.fig3_terrains:  # the 140/60 run of an identification surface is that run
        hit = [i for i, (tt, wl, wr) in cfg.ident(quick) if tt == terrain and (wl, wr) == cfg.fig3_pair_rpm]
        if hit:
            fig3_idx[terrain] = ("ident", hit[0])
        else:
            fig3_idx[terrain] = ("fig3", terrain)
            tags.append(("fig3", terrain))
            reqs.append((_ident_scenario(terrain, *cfg.fig3_pair_rpm, cfg.ident_duration), cfg.ident_seed0))
    speed_seed = cfg.ident_seed0 + cfg.ident_full.index(("concrete", *cfg.fig3_pair_rpm))  # 140/60 = that run
    for wl, wr in cfg.speed_pairs_rpm:
        tags.append(("speed", wl, wr))
        reqs.append((_ident_scenario("concrete", wl, wr, cfg.ident_duration), speed_seed))
    scored = {k: load_scenario(n) for k, n in PATHS.items()}
    fine = {k: load_scenario(n, sens) for k, n in PATHS.items()}
    for k in PATHS:
        for s in seeds:
            tags += [("scored", k, s), ("fine", k, s)]
            reqs += [(scored[k], s), (fine[k], s)]
    runs = dict(zip(tags, ctx.simulate_many(reqs)))

    # ---- identification (Sec. V-B): scheme 3's calibrate fits eq. (41) on the reference-sensor points
    ident_runs = [runs[("ident", i)] for i, _ in cfg.ident(quick)]
    methods = {v: registry.calibrate(registry.get(METHOD_NAMES[v]), ident_runs) for v in VARIANTS}
    v3 = methods[3]
    pts = {rid: (g, s) for rid, g, s in v3.calibration_points}
    ident = []
    for (i, (terrain, wl, wr)), run in zip(cfg.ident(quick), ident_runs):
        g, s = pts.get(run.id, (math.nan, math.nan))
        gt, st = s_gamma_truth_point(run, cfg.s_settle)
        ident.append({"index": i, "terrain": terrain, "wl_rpm": wl, "wr_rpm": wr, "seed": cfg.ident_seed0 + i,
                      "gamma": g, "s": s, "gamma_truth": gt, "s_truth": st})
    fig3 = {}
    for terrain, tag in fig3_idx.items():
        run = runs[tag]
        p = reference_s_gamma_point(run, _geometry(run)[1], settle=cfg.s_settle)
        fig3[terrain] = {"s": p[1] if p else math.nan, "gamma": p[0] if p else math.nan,
                         "s_truth": s_gamma_truth_point(run, cfg.s_settle)[1]}

    # ---- scored paths
    v3_pub = Yi2009Ekf(variant=3, s_gamma=PUBLISHED_S_GAMMA)
    levelled = {v: registry.calibrate(dataclasses.replace(registry.get(METHOD_NAMES[v]), params=dataclasses.replace(
        m.params, p0_rollpitch=cfg.levelled_p0_rollpitch)), ident_runs) for v, m in methods.items()}
    results = {}
    for k in PATHS:
        scores: dict[str, list[dict[str, float]]] = {}
        est0: dict[int, Estimate] = {}
        vis0 = None
        truth: dict[str, float] = {}
        for i, s in enumerate(seeds):
            run, frun = runs[("scored", k, s)], runs[("fine", k, s)]
            vis = vision_slip(run, cfg.slip_window, cfg.slip_min_speed, cfg.slip_polyorder)
            fvis = vision_slip(frun, cfg.slip_window, cfg.slip_min_speed, cfg.slip_polyorder)
            for v in VARIANTS:
                est = registry.estimate(methods[v], run)
                scores.setdefault(f"v{v}", []).append(_score(run, est, vis, cfg))
                scores.setdefault(f"fine_v{v}", []).append(_score(frun, registry.estimate(methods[v], frun), fvis, cfg))
                scores.setdefault(f"levelled_v{v}", []).append(_score(run, registry.estimate(levelled[v], run), vis, cfg))
                if i == 0:
                    est0[v] = est
            scores.setdefault("v3_pub", []).append(_score(run, registry.estimate(v3_pub, run), vis, cfg))
            s_true = _truth_s(run, cfg)  # the physics is seed independent: one S per path
            for name, s_, fb in (("v3_true_s", s_true, True), ("v3_no_feedback", None, False),
                                 ("v3_true_s_no_feedback", s_true, False)):
                if s_true is None and "true_s" in name:
                    continue  # the straight: no true S to put in
                scores.setdefault(name, []).append(
                    _score(run, attribution_estimate(v3, run, s_true=s_, feedback=fb), vis, cfg, slips=False))
            scores.setdefault("gyro", []).append({"roll_err": gyro_roll_error(run, cfg.slip_t0)})
            if i == 0:
                vis0 = vis
                truth = _truth_diagnostics(run, vis, cfg)
        results[k] = PathResult(k, tuple(seeds), {m: tuple(v) for m, v in scores.items()}, truth,
                                runs[("scored", k, seeds[0])], est0, vis0)
    speed = {}
    for wl, wr in cfg.speed_pairs_rpm:
        g, s_ = s_gamma_truth_point(runs[("speed", wl, wr)], cfg.s_settle)
        speed[(wl, wr)] = (abs(g), s_)
    ev = Evaluation(tuple(seeds), quick, v3, tuple(ident), fig3, speed, results)
    ctx.info[_CACHE_KEY] = ev
    return ev
