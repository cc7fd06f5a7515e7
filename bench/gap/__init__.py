"""The sim-vs-measured gap workflow (DESIGN.md "Gap workflow").

    find_gap(measured: Run, scenario, model="testbed") -> GapResult

1. Replay the measured run's commands in the model from the measured initial state
   (:mod:`bench.gap.model`): the nominal testbed built from the scenario's specs, or a model
   plugin (a registered method that predicts from commands, e.g. ``yu2010.closed_loop``).
2. Residuals per channel and per regime, and where in time they concentrate
   (:mod:`bench.gap.residuals`, :mod:`bench.gap.regimes`).
3. A named catalogue of candidate effects (:mod:`bench.gap.catalogue`).
4. Fit each candidate (scipy.optimize), score it on held-out data with a complexity penalty and
   select greedily (:mod:`bench.gap.fit`, :mod:`bench.gap.select`: thresholds and how they were
   chosen are in that module's docstring).
5. Add the selected effect(s), re-run, and report the gap before/after per channel with a figure
   and a markdown summary (:mod:`bench.gap.report`).
6. Say "no significant missing effect" (with the detection limit of every effect: the smallest
   size the data would have detected) or "unexplained residual: ..., largest in regime ..."
   when that is what the data say; beside named effects, the absolute goodness of fit (what is
   left against the noise floor, :mod:`bench.gap.significance`): a model that explains most of a
   large gap but leaves far more than the noise is an unexplained residual, not a named effect.

The measured run's truth columns are never read (the workflow works on ``without_truth()``).
With a model plugin only the sensor effects of the catalogue apply (a plugin has no spec to
augment); the others are listed as not applicable.
"""
from __future__ import annotations

import functools
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from bench.gap.catalogue import CATALOGUE, BY_NAME, Effect, ModelConfig, get, nominal_config
from bench.gap.fit import Evaluator, FitResult
from bench.gap.model import measured_grid, plugin_trace, replay_scenario, testbed_trace
from bench.gap.regimes import regimes_for
from bench.gap.residuals import ResidualSpace, build_space, gap_table, regime_table, time_profile
from bench.gap.select import Selection, Thresholds, run_selection
from bench.gap.report import window_text
from bench.run import Run
from bench.spec import Scenario, load_scenario


@dataclass
class GapResult:
    """Everything the workflow found; :meth:`to_json` is the ``--json`` document."""

    run_id: str
    scenario: str
    model: str
    verdict: str  # one sentence
    verdict_kind: str  # no_significant_effect | missing_effect | unexplained_residual
    effects: list[dict[str, Any]]  # named effects: name, title, parameters, uncertainty, overrides
    partial: list[dict[str, Any]]  # candidates that helped but leave an unexplained residual
    gap_before: dict[str, dict[str, float]]
    gap_after: dict[str, dict[str, float]]
    regimes_before: dict[str, dict]
    regimes_after: dict[str, dict]
    concentration: dict[str, Any]  # where in time/regime the disagreement sits (before and after)
    cost: dict[str, float]  # J_noise, nominal, final, explained fraction
    candidates: list[dict[str, Any]]  # per round: screening and refined fits
    channels_missing: list[str]
    not_applicable: list[str]
    thresholds: dict[str, float]
    runtime_s: float
    n_simulations: int
    comparison: str
    series: dict[str, Any] = field(default_factory=dict, repr=False)  # for the figure
    fit: dict[str, Any] = field(default_factory=dict)  # absolute goodness of fit (bench.gap.significance)
    detection_limits: dict[str, Any] = field(default_factory=dict)  # per effect, when nothing is significant

    def to_json(self) -> dict[str, Any]:
        """The result as a JSON document.  The wall time ``runtime_s`` is left out (the Markdown report and
        the CLI print it): the same input gives the same document, run after run."""
        return {
            "run": self.run_id, "scenario": self.scenario, "model": self.model,
            "verdict": self.verdict, "verdict_kind": self.verdict_kind,
            "effects": self.effects, "partial_candidates": self.partial,
            "gap_before": self.gap_before, "gap_after": self.gap_after,
            "regimes_before": self.regimes_before, "regimes_after": self.regimes_after,
            "concentration": self.concentration, "cost": self.cost, "candidates": self.candidates,
            "channels_missing": self.channels_missing, "not_applicable": self.not_applicable,
            "thresholds": self.thresholds, "n_simulations": self.n_simulations,
            "comparison": self.comparison, "fit": self.fit, "detection_limits": self.detection_limits,
        }

    @property
    def named(self) -> list[str]:
        return [e["name"] for e in self.effects]

    def most_affected_channel(self) -> str:
        """The channel with the largest normalised gap before (residual RMS / noise scale)."""
        return max(self.gap_before, key=lambda c: self.gap_before[c]["normalised_rms"])


COMPARISON = ("measured channels vs the model's noise-free signals (physics trace of the replayed "
              "model), residuals normalised by noise scales estimated from the measured data; model pose "
              "corrected by an SE(2) initial-pose offset fitted on the first second (or the first 20 pose samples; "
              "the rotation only where they determine it)")


def _const_trace(trace: dict[str, np.ndarray], scn: Scenario, overrides: Mapping[str, Any]) -> dict[str, np.ndarray]:
    if overrides:
        raise ValueError("a model plugin cannot take spec overrides")
    return trace


def _resolve_scenario(scenario: str | Path | Scenario, overrides: Mapping[str, Any] | None) -> Scenario:
    if isinstance(scenario, Scenario):
        if overrides:
            from bench.gap.model import apply_overrides
            return apply_overrides(scenario, overrides)
        return scenario
    return load_scenario(scenario, overrides)


def _concentration(space: ResidualSpace, signals: Mapping[str, np.ndarray], regimes: dict[str, dict]) -> dict[str, Any]:
    centres, prof = time_profile(space, signals, bin_s=0.5)
    total = float(prof.sum())
    out: dict[str, Any] = {"total_excess": total}
    if total > 0:
        # the 2 s window with the largest share of the excess
        w = 4
        csum = np.convolve(prof, np.ones(w), mode="valid") if prof.size >= w else np.array([total])
        k = int(np.argmax(csum))
        out["window_s"] = [float(centres[k] - 0.25), float(centres[min(k + w - 1, centres.size - 1)] + 0.25)]
        out["window_share"] = float(csum[k] / total)
        offsets = getattr(space, "offsets", ())  # several runs (bench.gap.segments): each end on its run's own clock
        if offsets:
            runs = [max(int(np.searchsorted(offsets, t, side="right")) - 1, 0) for t in out["window_s"]]
            out["window_s"] = [t - offsets[r] for t, r in zip(out["window_s"], runs)]
            out["window_runs"] = [r + 1 for r in runs]
    if regimes:
        # the regime with the most intense disagreement (mean excess per sample) among those that
        # last >= 5 % of the run; its share of the total excess beside it
        pool = {k: v for k, v in regimes.items() if v["time_share"] >= 0.05} or regimes
        worst = max(pool, key=lambda r: pool[r]["excess_cost"])
        share = regimes[worst]["excess_cost"] * regimes[worst]["time_share"]
        tot = sum(v["excess_cost"] * v["time_share"] for v in regimes.values())
        chans = regimes[worst].get("local_rms", {})  # the pose channels by the growth of their error
        out["regime"] = worst
        out["regime_share"] = float(share / tot) if tot > 0 else 0.0
        out["regime_channel"] = max(chans, key=chans.get) if chans else ""
        out["regime_excess_cost"] = regimes[worst]["excess_cost"]
    return out


def _effect_entry(name: str, fit: FitResult, scn: Scenario) -> dict[str, Any]:
    e = get(name)
    vals = tuple(fit.values[name][p.name] for p in e.params)
    return {
        "name": name, "title": e.title, "meaning": e.meaning,
        "parameters": {p.name: fit.values[name][p.name] for p in e.params},
        "uncertainty": {p.name: fit.stderr[name][p.name] for p in e.params},
        "units": {p.name: p.unit for p in e.params},
        "bounds": {p.name: list(b) for p, b in zip(e.params, e.bounds(scn))},
        "fold_estimates": fit.fold_values.get(name, {}),
        "nominal": dict(zip((p.name for p in e.params), e.neutral(scn) or (None,) * e.n_params)),
        "overrides": e.spec_overrides(scn, vals),
    }


def find_gap(measured: Run | Sequence[Run], scenario: str | Path | Scenario, model: str = "testbed", *,
             overrides: Mapping[str, Any] | None = None, catalogue: Sequence[Effect] = CATALOGUE,
             thresholds: Thresholds = Thresholds(), workers: int | None = None,
             channels: Sequence[str] | None = None,
             progress: Callable[[str], None] | None = None) -> GapResult:
    """Run the gap workflow on ``measured`` against ``scenario``'s nominal model (see module doc).

    ``measured`` may be a sequence of runs of the same robot: one model is fitted to all of them, each replayed
    from its own initial state (:mod:`bench.gap.segments`; the testbed model only, every channel the runs share).

    ``overrides`` change the nominal model's spec (dotted keys as ``--set``); ``workers`` is the
    process-pool size for simulations (default min(2, cpus)); ``channels`` restricts the residual
    channels.
    """
    t_start = time.perf_counter()
    if not isinstance(measured, Run):  # several runs: one model fitted to all (bench.gap.segments)
        return _find_gap_segments(list(measured), scenario, model, overrides=overrides, catalogue=catalogue,
                                  thresholds=thresholds, workers=workers, channels=channels, progress=progress,
                                  t_start=t_start)
    run = measured.without_truth()
    run.validate()
    scn0 = _resolve_scenario(scenario, overrides)
    rscn, init = replay_scenario(run, scn0)
    space = build_space(run, regimes_for(scn0.platform), channels=tuple(channels) if channels else None,
                        required=True)
    grid = measured_grid(run, space.t, init, scn0)
    n_workers = workers if workers is not None else min(2, os.cpu_count() or 1)
    if model == "testbed":
        ev = Evaluator(rscn, grid, space, testbed_trace, workers=n_workers)
        physics = True
    else:
        from bench import registry

        method = registry.get(model)
        tr = plugin_trace(method, run)
        ev = Evaluator(rscn, grid, space, functools.partial(_const_trace, tr), workers=1, pose_offset=(0.0, 0.0))
        physics = False
        # channels the plugin does not predict are dropped
        sig = ev.signals(nominal_config(rscn))
        keep = tuple(c for c in space.channels if c in sig and np.isfinite(sig[c]).any())
        if keep != space.channels:
            space = build_space(run, regimes_for(scn0.platform), channels=keep)
            grid = measured_grid(run, space.t, init, scn0)
            ev = Evaluator(rscn, grid, space, functools.partial(_const_trace, tr), workers=1, pose_offset=(0.0, 0.0))
    sel = run_selection(ev, catalogue, thresholds, physics_model=physics, progress=progress)
    return _assemble(run.id, scn0, model, ev, sel, time.perf_counter() - t_start)


def _find_gap_segments(runs: list[Run], scenario: str | Path | Scenario, model: str, *,
                       overrides: Mapping[str, Any] | None, catalogue: Sequence[Effect], thresholds: Thresholds,
                       workers: int | None, channels: Sequence[str] | None,
                       progress: Callable[[str], None] | None, t_start: float) -> GapResult:
    from bench.gap.segments import segment_evaluator

    if model != "testbed":
        raise ValueError(f"several measured runs are fitted with the testbed model only, not {model!r}")
    if not runs:
        raise ValueError("no measured run")
    scn0 = _resolve_scenario(scenario, overrides)
    ev = segment_evaluator(runs, scn0, workers if workers is not None else min(2, os.cpu_count() or 1), channels)
    sel = run_selection(ev, catalogue, thresholds, physics_model=True, progress=progress)
    return _assemble("+".join(r.id for r in runs), scn0, model, ev, sel, time.perf_counter() - t_start)


def _fmt_params(entry: dict[str, Any]) -> str:
    parts = []
    for k, v in entry["parameters"].items():
        se = entry["uncertainty"].get(k, float("nan"))
        unit = entry["units"].get(k, "")
        unit = "" if unit in ("-", "") else f" {unit}"
        parts.append(f"{k} = {v:.4g} ± {se:.2g}{unit}")
    return ", ".join(parts)


def _assemble(run_id: str, scn: Scenario, model: str, ev: Evaluator, sel: Selection, elapsed: float) -> GapResult:
    space = ev.space
    sig_before = ev.signals(sel.nominal.config)
    sig_after = ev.signals(sel.final.config)
    gb, ga = gap_table(space, sig_before), gap_table(space, sig_after)
    rb, ra = regime_table(space, sig_before), regime_table(space, sig_after)
    conc_b, conc_a = _concentration(space, sig_before, rb), _concentration(space, sig_after, ra)
    entries = [_effect_entry(n, sel.final, ev.scn) for n in sel.selected]
    effects, partial = (entries, []) if sel.named else ([], entries)
    q = sel.quality
    fit_text = (f"{q.verdict}: final cost {q.ratio_cv:.3g} x the noise floor (band {q.band[0]:.2f}-{q.band[1]:.2f})"
                if q is not None else "")
    if sel.verdict == "missing effect":
        kind = "missing_effect"
        label = "missing effect" if len(effects) == 1 else "missing effects"
        verdict = f"{label}: " + "; ".join(f"{e['name']} ({_fmt_params(e)})" for e in effects)
        if fit_text:
            verdict += f"; residual {fit_text}"
    elif sel.verdict == "no significant missing effect":
        kind = "no_significant_effect"
        verdict = "no significant missing effect"
    else:
        kind = "unexplained_residual"
        c = conc_a if partial else conc_b
        where = (f"largest in regime {c.get('regime', '?')} (channel {c.get('regime_channel', '?')}"
                 + (f", t = {window_text(c)}" if "window_s" in c else "") + ")")
        left = 100.0 * (1.0 - sel.explained_fraction) if partial else 100.0
        if partial:
            verdict = (f"unexplained residual: {left:.0f}% of the excess gap remains after the best candidate(s) "
                       f"{', '.join(e['name'] for e in partial)}" + (f" ({fit_text})" if fit_text else "")
                       + f", {where}")
        else:
            verdict = f"unexplained residual: no catalogue effect explains the gap, {where}"
    candidates = []
    for i, r in enumerate(sel.rounds):
        candidates.append({
            "round": i + 1, "accepted": r.accepted, "gain": r.gain, "chi2": r.chi2, "reason": r.reason,
            "screening": [{"effect": s.effect, "estimate": list(s.theta), "predicted_cost": s.predicted_cost,
                           "simulated_cost": s.simulated_cost, "how": s.note} for s in r.screens],
            "fits": [f.brief() for f in r.fits],
        })
    jn = sel.j_noise
    cost = {"j_noise": jn, "nominal": sel.nominal.cost, "final": sel.final.cost, "final_cv": sel.final.cost_cv,
            "explained_fraction": sel.explained_fraction, "final_jitter": sel.final.jitter}
    # figure series: the channel the final model improves most (else the worst channel)
    def improvement(c: str) -> float:
        return (gb[c]["rms"] - ga[c]["rms"]) / space.sigma[c]

    fig_ch = max(space.channels, key=improvement) if effects or partial else \
        max(space.channels, key=lambda c: gb[c]["normalised_rms"])
    second = [c for c in sorted(space.channels, key=improvement, reverse=True) if c != fig_ch][:1]
    series = {"channels": [fig_ch] + second, "t": {}, "measured": {}, "before": {}, "after": {}}
    al_before, al_after = space.align_pose(sig_before), space.align_pose(sig_after)  # as compared
    for c in series["channels"]:
        series["t"][c] = space.t[c]
        series["measured"][c] = space.meas[c]
        series["before"][c] = al_before[c]
        series["after"][c] = al_after[c]
    thr = sel.thresholds
    return GapResult(
        run_id=run_id, scenario=scn.id, model=model, verdict=verdict, verdict_kind=kind, effects=effects,
        partial=partial, gap_before=gb, gap_after=ga, regimes_before=rb, regimes_after=ra,
        concentration={"before": conc_b, "after": conc_a}, cost=cost, candidates=candidates,
        channels_missing=list(space.missing), not_applicable=sel.not_applicable,
        thresholds={"kappa": thr.kappa, "min_gain": thr.min_gain, "min_gain_fraction": thr.min_gain_fraction,
                    "min_gain_initial": thr.min_gain_initial,
                    "significant_excess": thr.significant_excess, "unexplained_fraction": thr.unexplained_fraction,
                    "significance_p": thr.significance_p, "far_above": thr.far_above,
                    "max_effects": thr.max_effects},
        runtime_s=float(elapsed), n_simulations=ev.n_sims, comparison=COMPARISON, series=series,
        fit=q.to_json() if q is not None else {}, detection_limits=sel.detection)


def write_worked_example(out_dir: str | Path = "results/gap", workers: int | None = None) -> GapResult:
    """The worked example of ``make reproduce``: measured data from the testbed with a hidden
    effect (``WORKED_EXAMPLE``), the workflow run blind, report + figure + JSON in ``out_dir``."""
    from bench.gap.report import write_report
    from bench.sim import simulate

    ex = WORKED_EXAMPLE
    measured = simulate(load_scenario(ex["scenario"], ex["hidden"]), ex["seed"])
    res = find_gap(measured, ex["scenario"], workers=workers)
    write_report(res, out_dir, hidden=ex["hidden"], stem="worked_example")
    return res


WORKED_EXAMPLE = {
    "scenario": "gap_example",
    "seed": 7,
    "hidden": {"platform.wheel_radius_scale_r": 0.94},  # right tires under-inflated
}

__all__ = ["find_gap", "GapResult", "write_worked_example", "CATALOGUE", "BY_NAME", "Thresholds", "ModelConfig"]
