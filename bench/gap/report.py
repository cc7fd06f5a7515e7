"""Gap report: markdown summary, figure (measured vs model before vs model after) and JSON.

All files are written atomically (``bench.report.io``).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from bench.gap.catalogue import get
from bench.report.io import atomic_savefig, atomic_write_json, atomic_write_text

if TYPE_CHECKING:  # pragma: no cover
    from bench.gap import GapResult


STDERR_NOTE = ("Std. error (bench.gap.fit): the larger of the classical one (Jacobian at the fit, residuals taken as "
               "white) and a delete-one-block jackknife over the 2 s time blocks of the folds (keeps the residuals' "
               "correlation in time), plus the optimiser's resolution on the simulated cost's jitter (contacts make "
               "the cost jump between nearby parameters; a parameter whose smooth cost is within the jitter's RMS "
               "of the minimum is not told apart); an actuator delay, found on the grid of physics steps, adds the "
               "step dt/sqrt(12) in quadrature. The two fold estimates are beside it.")


def change_text(before: float, after: float) -> str:
    """The relative change of an RMS gap: "+0%" when both are zero (no gap before or after: nothing changed), "new"
    when a zero gap became non-zero, "n/a" when either is not a number."""
    if not (math.isfinite(before) and math.isfinite(after)):
        return "n/a"
    if before == 0:
        return "+0%" if after == 0 else "new"
    return f"{100.0 * (after / before - 1.0):+.0f}%"


def window_text(conc: Mapping[str, Any]) -> str:
    """The 2 s window of a concentration (``window_s``; ``window_runs`` when several runs were fitted: each end on its
    own run's clock, runs counted from 1)."""
    (a, b), runs = conc["window_s"], conc.get("window_runs")
    if not runs:
        return f"{a:.1f}-{b:.1f} s"
    if runs[0] == runs[1]:
        return f"{a:.1f}-{b:.1f} s of run {runs[0]}"
    return f"{a:.1f} s of run {runs[0]} to {b:.1f} s of run {runs[1]}"


def uncertainty_text(effect: str, param: str, value: float, stderr: float | None, digits: int = 2,
                     bounds: Sequence[float] | None = None) -> str:
    """The std. error cell: "not identified" when the data do not determine the parameter (infinite
    standard error, bench.gap.fit), and "(at bound)" when the fit sits on a bound: ``bounds`` (the scenario's, as the
    fit used them: the entry's "bounds"), else the catalogue's."""
    if stderr is not None and math.isinf(stderr):
        txt = "not identified"
    else:
        txt = "n/a" if stderr is None or not math.isfinite(stderr) else f"{stderr:.{digits}g}"
    prm = {p.name: p for p in get(effect).params}.get(param)
    if prm is not None and math.isfinite(value):
        lo, hi = (prm.lower, prm.upper) if bounds is None else (float(bounds[0]), float(bounds[1]))
        tol = 1e-4 * (hi - lo)  # the optimiser stops just inside a bound
        if value <= lo + tol or value >= hi - tol:
            txt += f" (at bound {lo if value <= lo + tol else hi:g})"
    return txt


def _f(x: Any, nd: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, (int, float, np.floating)):
        if not math.isfinite(float(x)):
            return "nan"
        return f"{float(x):.{nd}g}"
    return str(x)


def markdown(res: "GapResult", hidden: Mapping[str, Any] | None = None, figure: str | None = None) -> str:
    L: list[str] = []
    L.append(f"# Gap report: `{res.run_id}` vs scenario `{res.scenario}` (model: {res.model})")
    L.append("")
    L.append(f"**Verdict:** {res.verdict}")
    L.append("")
    if hidden is not None:
        L.append("Measured data: the testbed with a hidden effect the nominal model does not have "
                 f"(`--set` {', '.join(f'{k}={v}' for k, v in hidden.items())}); the workflow ran blind.")
        L.append("")
    c = res.cost
    L.append(f"Cost (weighted normalised mean square, sensor noise alone ~ {_f(c['j_noise'], 3)}): "
             f"nominal {_f(c['nominal'], 4)} -> final {_f(c['final'], 4)} (held-out {_f(c['final_cv'], 4)}); "
             f"explained fraction of the excess {100 * c['explained_fraction']:.1f}%. "
             f"{res.n_simulations} simulations, {res.runtime_s:.1f} s.")
    L.append("")
    fq = getattr(res, "fit", {}) or {}
    if fq:
        lo, hi = fq["noise_band"]
        L.append(f"Goodness of fit: {fq['verdict']} (final held-out cost {_f(fq['final_cv_over_noise'], 3)} x the "
                 f"noise floor J_noise; a correct model lies within {lo:.2f}-{hi:.2f} x, the sampling band).")
        L.append("")
    det = getattr(res, "detection_limits", {}) or {}
    if det:
        L.append("## Detection limits (nothing significant found)")
        L.append("")
        L.append("Smallest change from the nominal value the selection would have detected on these data "
                 "(screening sensitivity x the significance threshold; bench/gap/significance.py):")
        L.append("")
        L.append("| effect | parameter | nominal | detectable change | via |")
        L.append("|---|---|---|---|---|")
        for name, d in det.items():
            if not d.get("limits"):
                L.append(f"| {name} | - | - | n/a ({d.get('reason', '')}) | - |")
                continue
            for k, v in d["limits"].items():
                unit = "" if v["unit"] in ("-", "") else f" {v['unit']}"
                ch = ("not detectable" if not math.isfinite(v["change"]) else
                      f"{100 * v['relative']:.3g}% ({_f(v['change'], 3)}{unit})" if "relative" in v else
                      f"{_f(v['change'], 3)}{unit}")
                L.append(f"| {name} | {k} | {_f(d['nominal'].get(k))} | {ch} | {v['how']} |")
        L.append("")
    for title, rows in (("Named effects", res.effects), ("Partial candidates (not named)", res.partial)):
        if not rows:
            continue
        L.append(f"## {title}")
        L.append("")
        L.append("| effect | parameter | fitted | std. error | nominal | fold estimates | spec override |")
        L.append("|---|---|---|---|---|---|---|")
        for e in rows:
            for k, v in e["parameters"].items():
                unit = e["units"].get(k, "")
                folds = ", ".join(_f(x) for x in e["fold_estimates"].get(k, []))
                ov = ", ".join(f"`{kk}={_f(vv, 5)}`" for kk, vv in e["overrides"].items())
                se = uncertainty_text(e["name"], k, v, e["uncertainty"][k], bounds=e.get("bounds", {}).get(k))
                L.append(f"| {e['name']} | {k} [{unit}] | {_f(v, 5)} | {se} | {_f(e['nominal'].get(k))} | {folds} | {ov} |")
        L.append("")
        L.append(STDERR_NOTE)
        L.append("")
        for e in rows:
            L.append(f"- **{e['name']}** ({e['title']}): {e['meaning']}")
        L.append("")
    L.append("## Gap per channel (measured - model)")
    L.append("")
    L.append("| channel | unit | RMS before | RMS after | % of signal before | % after | change | noise scale |")
    L.append("|---|---|---|---|---|---|---|---|")
    for ch, b in res.gap_before.items():
        a = res.gap_after[ch]
        L.append(f"| {ch} | {b['unit']} | {_f(b['rms'])} | {_f(a['rms'])} | {_f(b['percent'], 3)}% | "
                 f"{_f(a['percent'], 3)}% | {change_text(b['rms'], a['rms'])} | {_f(b['noise'], 2)} |")
    L.append("")
    if res.channels_missing:
        L.append(f"Channels not compared (absent in the measured run or the model): {', '.join(res.channels_missing)}.")
        L.append("")
    L.append("## Where the disagreement sits")
    L.append("")
    for when in ("before", "after"):
        cc = res.concentration[when]
        win = cc.get("window_s")
        L.append(f"- {when}: most intense in regime **{cc.get('regime', '-')}**, which carries "
                 f"{100 * cc.get('regime_share', 0):.0f}% of the excess (worst channel there: {cc.get('regime_channel', '-')})"
                 + (f"; 2 s window {window_text(cc)} holds {100 * cc['window_share']:.0f}%" if win else ""))
    L.append("")
    L.append("Excess cost per sample over every channel's local term (the pose residuals accumulate, so they take "
             "part by the growth of their error between consecutive samples: bench.gap.residuals.local_terms):")
    L.append("")
    L.append("| regime | time share | excess cost before | excess cost after |")
    L.append("|---|---|---|---|")
    for name, rb in res.regimes_before.items():
        ra = res.regimes_after.get(name, {})
        L.append(f"| {name} | {100 * rb['time_share']:.0f}% | {_f(rb['excess_cost'], 3)} | {_f(ra.get('excess_cost'), 3)} |")
    L.append("")
    L.append("## Candidates")
    L.append("")
    for r in res.candidates:
        L.append(f"Round {r['round']}: {'accepted' if r['accepted'] else 'rejected'} ({r['reason']}).")
        L.append("")
        L.append("| effect | screening estimate | screening cost | simulated at the estimate | how |")
        L.append("|---|---|---|---|---|")
        for s in sorted(r["screening"], key=lambda s: s["predicted_cost"]):
            sim = s.get("simulated_cost")
            L.append(f"| {s['effect']} | {', '.join(_f(x) for x in s['estimate'])} | {_f(s['predicted_cost'], 4)} | "
                     f"{'-' if sim is None else _f(sim, 4)} | {s['how']} |")
        L.append("")
        if r["fits"]:
            L.append("| refined model | cost | held-out cost |")
            L.append("|---|---|---|")
            for fdict in r["fits"]:
                L.append(f"| {' + '.join(fdict['effects'])} | {_f(fdict['cost'], 4)} | {_f(fdict['cost_cv'], 4)} |")
            L.append("")
    if res.not_applicable:
        L.append(f"Not applicable to model {res.model}: {', '.join(res.not_applicable)}.")
        L.append("")
    L.append("## Method")
    L.append("")
    L.append(f"Comparison: {res.comparison}. Pose channels after the least-squares SE(2) correction of the "
             "initial pose, estimated on the first second of the run (longer when it holds fewer than 20 pose "
             "samples; the rotation only where those samples determine it). Selection thresholds "
             "(bench/gap/select.py): "
             + ", ".join(f"{k} = {v}" for k, v in res.thresholds.items()) + ".")
    L.append("")
    if figure:
        L.append(f"![measured vs model before vs after]({figure})")
        L.append("")
    return "\n".join(L)


def figure(res: "GapResult"):
    """Measured vs model before vs model after for the channel(s) the final model changes most."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = res.series
    chans = s.get("channels", [])
    n = len(chans) + (1 if chans else 0)
    fig, axes = plt.subplots(max(n, 1), 1, figsize=(9, 2.6 * max(n, 1)), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], chans):
        t = np.asarray(s["t"][c])
        ax.plot(t, s["before"][c], "-", lw=1.2, color="tab:red", label="model before", zorder=2)
        ax.plot(t, s["after"][c], "-", lw=1.2, color="tab:blue", label="model after", zorder=2)
        ax.plot(t, s["measured"][c], ".", ms=1.2, color="black", alpha=0.5, label="measured", zorder=3)
        b, a = res.gap_before[c]["rms"], res.gap_after[c]["rms"]
        ax.set_ylabel(f"{c} [{res.gap_before[c]['unit']}]")
        ax.set_title(f"{c}: RMS gap {b:.3g} -> {a:.3g}", fontsize=9)
        ax.grid(alpha=0.3)
    if chans:  # residual of the first channel, before and after
        c = chans[0]
        ax = axes[len(chans), 0]
        t = np.asarray(s["t"][c])
        meas = np.asarray(s["measured"][c])
        for key, col in (("before", "tab:red"), ("after", "tab:blue")):
            r = meas - np.asarray(s[key][c])
            if c == "ref_yaw":
                r = (r + np.pi) % (2 * np.pi) - np.pi
            ax.plot(t, r, "-", lw=0.8, color=col, label=f"measured - model {key}")
        ax.axhline(0, color="0.5", lw=0.6)
        ax.set_ylabel(f"residual {c}")
        ax.legend(loc="best", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(res.verdict[:110] + ("..." if len(res.verdict) > 110 else ""), fontsize=9)
    fig.tight_layout()
    return fig


def write_report(res: "GapResult", out_dir: str | Path, hidden: Mapping[str, Any] | None = None,
                 stem: str = "gap") -> dict[str, Path]:
    """Write ``<stem>.md``, ``<stem>.png`` and ``<stem>.json`` into ``out_dir``."""
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    fig = figure(res)
    png = atomic_savefig(fig, out / f"{stem}.png", dpi=110)
    plt.close(fig)
    doc = res.to_json()
    if hidden is not None:
        doc["hidden"] = dict(hidden)
    js = atomic_write_json(out / f"{stem}.json", doc)
    md = atomic_write_text(out / f"{stem}.md", markdown(res, hidden, figure=png.name) + "\n")
    return {"markdown": md, "figure": png, "json": js}


__all__ = ["markdown", "figure", "write_report"]
