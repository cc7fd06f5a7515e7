"""Held-out scoring of the real-data gap workflow (:mod:`bench.real.gap`): each held-out step replayed
with the nominal testbed model, with the model the simulation started from (the calibration-half stages of
:mod:`bench.real.command_response`, :mod:`bench.real.turn_response` and :mod:`bench.real.transient_response`, when they
changed anything) and with the model the workflow ended with, residuals measured - model in
:mod:`bench.gap`'s own residual space, pooled over steps per channel and per driving regime."""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from bench.gap import GapResult
from bench.gap.catalogue import ModelConfig, get, nominal_config
from bench.gap.fit import Evaluator
from bench.gap.model import measured_grid, replay_scenario, testbed_trace
from bench.gap.regimes import regimes_for
from bench.gap.residuals import CHANNELS, UNITS, build_space, local_terms
from bench.real.stall import motion_ratio, space_series
from bench.run import Run

MIN_REGIME_SHARE = 0.05  # a regime must hold this share of the held-out samples to be "where"


def final_config(res: GapResult, scn: Any) -> ModelConfig:
    """The model the workflow ended with, for a (replayed) scenario ``scn``: the nominal
    configuration plus every effect it kept (named, or partial candidates), at the fitted values."""
    cfg = nominal_config(scn)
    for e in res.effects + res.partial:
        eff = get(e["name"])
        cfg = eff.apply(scn, cfg, tuple(float(e["parameters"][p.name]) for p in eff.params))
    return cfg


def step_residuals(run: Run, scenario: Any, res: GapResult, start: Any = None, keep: bool = True,
                   nominal: bool = True) -> dict[str, Any]:
    """Residuals measured - model (nominal and final) of one held-out Run, with the sample regimes,
    noise scales and costs (bench.gap's own residual space: same channels, normalisation and pose
    alignment as inside the workflow), and the motion ratio (:func:`bench.real.stall.motion_ratio`) of the robot and
    of the final model.  ``start``: the scenario the workflow started from when it is not the
    nominal ``scenario`` (the calibration-half stages of :mod:`bench.real.gap.start_model` applied); the final
    model is then ``res`` on top of it, each model replayed from the initial state it settles on, and the start
    model's own cost is ``cost["start"]``.  ``keep=False``: the final model is the start model itself (the fit
    block's effects were not kept, :func:`bench.real.gap.validate`).  ``nominal=False`` with a ``start``: the nominal
    model is not simulated (no ``"before"`` cost or residuals)."""
    run = run.without_truth()
    space = build_space(run, regimes_for(scenario.platform))
    out: dict[str, Any] = {"space": space, "cost": {}, "raw": {}}
    models = [("before", scenario, False)] if nominal or start is None else []
    if start is not None:
        models.append(("start", start, False))
    models.append(("after", scenario if start is None else start, True))
    evs: dict[int, tuple[Any, Evaluator]] = {}
    for key, scn, final in models:
        if id(scn) not in evs:
            rscn, init = replay_scenario(run, scn)
            evs[id(scn)] = (rscn, Evaluator(rscn, measured_grid(run, space.t, init, scn), space, testbed_trace,
                                            workers=1))
        rscn, ev = evs[id(scn)]
        sig = ev.signals(final_config(res, rscn) if final and keep else nominal_config(rscn))
        if key != "start":
            out["raw"][key] = space.raw(sig)
        out["cost"][key] = space.cost(sig)
    out["j_noise"] = space.j_noise
    r, track = scenario.platform.wheel_radius, scenario.platform.track
    out["motion"] = {"measured": motion_ratio(space_series(space), r, track),
                     "final": motion_ratio(space_series(space, out["raw"]["after"]), r, track)}
    return out


def wheel_series(run: Run, scenario: Any, res: GapResult, start: Any = None,
                 keep: bool = True) -> dict[str, dict[str, np.ndarray]]:
    """For the figure: commanded, measured, nominal-model and final-model wheel speeds of ``run``."""
    r = step_residuals(run, scenario, res, start, keep)
    sp = r["space"]
    out = {}
    for c, cmd in (("enc_wl", "cmd_wl"), ("enc_wr", "cmd_wr")):
        if c not in sp.channels:
            continue
        t = sp.t[c]
        out[c] = {"t": t, "measured": sp.meas[c], "command": np.interp(t, run.t, run[cmd]),
                  "nominal": sp.meas[c] - r["raw"]["before"][c], "final": sp.meas[c] - r["raw"]["after"][c]}
    return out


def score_held_out(steps: Sequence[dict[str, Any]], regime_names: Sequence[str]) -> dict[str, Any]:
    """Pool per-step residuals: per channel RMS [SI] and normalised RMS before/after; per regime the
    share of samples and the excess cost over every channel's local term (as bench.gap.residuals.regime_table,
    pooled over steps: sum_c w_c max(mean z2 - (sigma_hat/sigma)^2, 0), z2 of bench.gap.residuals.local_terms:
    the pose channels by the growth of their error between samples)."""
    chans = [c for c in CHANNELS if any(c in s["space"].channels for s in steps)]
    per: dict[str, dict[str, float]] = {}
    for c in chans:
        row: dict[str, float] = {"unit": UNITS[c]}
        for key in ("before", "after"):
            r2, z2, n = 0.0, 0.0, 0
            for s in steps:
                if c not in s["space"].channels:
                    continue
                r = s["raw"][key][c]
                ok = np.isfinite(r)
                r2 += float(np.sum(r[ok] ** 2))
                z2 += float(np.sum((r[ok] / s["space"].sigma[c]) ** 2))
                n += int(ok.sum())
            row[f"rms_{key}"] = math.sqrt(r2 / n) if n else math.nan
            row[f"normalised_rms_{key}"] = math.sqrt(z2 / n) if n else math.nan
            row["n"] = n
        row["change_percent"] = (100.0 * (row["rms_after"] / row["rms_before"] - 1.0)
                                 if row["rms_before"] > 0 else math.nan)
        per[c] = row
    regimes: dict[str, dict[str, Any]] = {}
    total = sum(int(np.isfinite(s["raw"]["before"][c]).sum()) for s in steps for c in s["space"].channels)
    terms = [{key: local_terms(s["space"], s["raw"][key]) for key in ("before", "after")} for s in steps]
    for i, name in enumerate(regime_names):
        entry: dict[str, Any] = {"n": 0}
        for key in ("before", "after"):
            excess, nrms, local, count = 0.0, {}, {}, 0
            for c in chans:
                acc, n, lacc, ln, noise = 0.0, 0, 0.0, 0, 0.0
                for s, tm in zip(steps, terms):
                    sp = s["space"]
                    if c not in sp.channels:
                        continue
                    m = (sp.regime[c] == i) & np.isfinite(s["raw"][key][c])
                    acc += float(np.sum((s["raw"][key][c][m] / sp.sigma[c]) ** 2))
                    n += int(m.sum())
                    _, reg, z2, noise2 = tm[key][c]
                    k = (reg == i) & np.isfinite(z2)
                    lacc += float(z2[k].sum())
                    ln += int(k.sum())
                    noise += float(k.sum()) * noise2
                if n == 0:
                    continue
                count += n
                nrms[c] = math.sqrt(acc / n)
                if ln:
                    local[c] = math.sqrt(lacc / ln)
                    excess += CHANNELS[c][1] * max(lacc / ln - noise / ln, 0.0)
            entry[f"excess_{key}"] = excess
            entry[f"normalised_rms_{key}"] = nrms
            entry[f"local_rms_{key}"] = local
            entry["n"] = count
        if entry["n"]:
            entry["share"] = entry["n"] / total if total else 0.0
            local = entry["local_rms_after"]
            entry["worst_channel_after"] = max(local, key=local.get) if local else ""
            regimes[name] = entry
    pool = {k: v for k, v in regimes.items() if v["share"] >= MIN_REGIME_SHARE} or regimes
    worst = max(pool, key=lambda k: pool[k]["excess_after"]) if pool else None
    cost_b = [s["cost"]["before"] for s in steps]
    cost_a = [s["cost"]["after"] for s in steps]
    cost_s = [s["cost"]["start"] for s in steps if "start" in s["cost"]]
    jn = [s["j_noise"] for s in steps]
    ratio = np.array([a / b if b > 0 else math.nan for a, b in zip(cost_a, cost_b)])
    q = np.nanquantile(ratio, [0.25, 0.5, 0.75]) if np.isfinite(ratio).any() else np.full(3, math.nan)
    return {
        "channels": per, "regimes": regimes, "worst_regime": worst,
        "cost": {"before_mean": float(np.mean(cost_b)), "after_mean": float(np.mean(cost_a)),
                 "j_noise_mean": float(np.mean(jn)),
                 "steps_improved": int(sum(a < b for a, b in zip(cost_a, cost_b))), "n_steps": len(steps),
                 "ratio_quartiles": [float(v) for v in q],  # of final / nominal per step
                 **({"start_mean": float(np.mean(cost_s)),
                     "steps_improved_start": int(sum(a < b for a, b in zip(cost_s, cost_b)))}
                    if cost_s and len(cost_s) == len(steps) else {}),
                 "per_step": [{"before": s["cost"]["before"], "after": s["cost"]["after"], "j_noise": s["j_noise"],
                               **({"start": s["cost"]["start"]} if "start" in s["cost"] else {}),
                               **({f"motion_{k}": v for k, v in s["motion"].items()} if "motion" in s else {})}
                              for s in steps]},
    }
