"""The real league (``results/real/league.md``): every window model on every real data set, held-out errors with
bootstrap intervals over command steps, and a plain statement of where an ICR model does not beat ideal differential drive.

Data sets: each folder of the data root (``../shared/data``, or ``SKIDBENCH_DATA``) holding a DRIVE table, with its
platform from :data:`KNOWN` (the Husky's folder) or from a ``platform.toml`` beside the table
(:mod:`bench.real.platform`).  Each is scored by :func:`bench.real.benchmark.run_real_benchmark` with every registered
plugin that has window models (the same split and rows as its own report, which the league links); the page lists
the registered plugins without window models, which it does not score.

Intervals: the held-out windows are resampled by command step (all windows of a step together: they share the
step's command and ground), :data:`N_BOOT` times with ``numpy.random.default_rng(SEED)``; a cell is the statistic with
its 2.5-97.5 % percentile interval.  "Beats ideal DD": the paired bootstrap interval of (median error of the model -
median error of ideal DD) lies below zero; "worse": above; else "no clear difference".
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bench.real.windows import ICR_FAMILY

__all__ = ["KNOWN", "data_sets", "step_draws", "bootstrap_median", "paired_median_difference", "comparison",
           "league_markdown", "write_real_league"]

TABLE_SUFFIXES = (".parquet", ".pkl", ".pickle", ".csv")  # what bench.real.drive reads (a run too, as .parquet)
KNOWN = {"drive_husky/husky_windows.parquet": "husky"}  # table -> platform name (its README names the robot)
N_BOOT = 1000
SEED = 0


def data_sets(root: Path) -> list[tuple[Path, str | Path]]:
    """(table, platform) of every real data set under ``root``."""
    out: list[tuple[Path, str | Path]] = []
    for rel, plat in KNOWN.items():
        if (root / rel).is_file():
            out.append((root / rel, plat))
    for toml in sorted(root.glob("*/platform.toml")):
        for table in sorted(p for p in toml.parent.iterdir() if p.suffix.lower() in TABLE_SUFFIXES):
            if table.relative_to(root).as_posix() not in KNOWN:
                out.append((table, toml))
    return out


def _resample(steps: np.ndarray, rng: np.random.Generator, n_boot: int) -> list[np.ndarray]:
    ids = np.unique(steps)
    members = [np.flatnonzero(steps == s) for s in ids]
    return [np.concatenate([members[k] for k in rng.integers(0, ids.size, ids.size)]) for _ in range(n_boot)]


def step_draws(steps: np.ndarray, n_boot: int = N_BOOT, seed: int = SEED) -> list[np.ndarray]:
    """``n_boot`` resamples of the windows by command step (all windows of a step together), seeded."""
    return _resample(np.asarray(steps), np.random.default_rng(seed), n_boot)


def paired_median_difference(a: np.ndarray, b: np.ndarray, draws: Sequence[np.ndarray]) -> tuple[float, float]:
    """The 2.5-97.5 % interval of median(a) - median(b) over the paired step resamples ``draws`` (the same windows
    for both: a and b are two models' errors on the same held-out windows)."""
    a, b = np.asarray(a), np.asarray(b)
    d = np.array([np.median(a[dr]) - np.median(b[dr]) for dr in draws])
    lo, hi = np.percentile(d, [2.5, 97.5])
    return float(lo), float(hi)


def comparison(lo: float, hi: float) -> str:
    """"beats" (the interval of the difference below zero), "worse" (above) or "no clear difference"."""
    return "beats" if hi < 0 else "worse" if lo > 0 else "no clear difference"


def bootstrap_median(e: np.ndarray, draws: Sequence[np.ndarray]) -> tuple[float, float, float]:
    """(median, 2.5 %, 97.5 %) of ``e`` over the step resamples ``draws``."""
    if e.size == 0:
        return math.nan, math.nan, math.nan
    meds = np.array([np.median(e[d]) for d in draws])
    return float(np.median(e)), float(np.percentile(meds, 2.5)), float(np.percentile(meds, 97.5))


def _cell(m: float, lo: float, hi: float, digits: int = 3) -> str:
    return "—" if not math.isfinite(m) else f"{m:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _rows(res: Mapping[str, Any]) -> tuple[list[str], list[str]]:
    win = res["_windows"]
    steps, steady = np.asarray(win["step"]), np.asarray(win["steady"], bool)
    draws = step_draws(steps)
    sub = {"steady": np.flatnonzero(steady), "transitory": np.flatnonzero(~steady)}
    sub_draws = {k: step_draws(steps[ix]) for k, ix in sub.items()}
    errs = win["errors"]
    rows = []
    ideal = np.asarray(errs["ideal_dd"][0]) if "ideal_dd" in errs else None
    verdicts = []
    for name, m in res["models"].items():
        et, ey = (np.asarray(a) for a in errs[name])
        st = m["stats"]["all"]
        cells = [_cell(*bootstrap_median(et, draws)), f"{st['trans']['mean']:.3f}", f"{st['trans']['p95']:.3f}",
                 _cell(*bootstrap_median(ey, draws)),
                 *(_cell(*bootstrap_median(et[ix], sub_draws[k])) for k, ix in sub.items())]
        versus = "—"
        if ideal is not None and name != "ideal_dd":
            lo, hi = paired_median_difference(et, ideal, draws)
            versus = comparison(lo, hi) + f" ({lo:+.3f}, {hi:+.3f})"
            if name in ICR_FAMILY and not hi < 0:
                verdicts.append(f"`{name}` does not beat ideal differential drive on this data set "
                                f"(paired interval of the median difference {lo:+.3f} to {hi:+.3f} m).")
        inputs = tuple(m.get("inputs", ("wheel speeds",)))
        shown = f"`{name}`" + ("" if inputs == ("wheel speeds",) else f" ({' + '.join(inputs)})")
        rows.append(f"| {shown} | " + " | ".join([*cells, versus]) + " |")
    return rows, verdicts


def league_markdown(results: Sequence[tuple[Path, Mapping[str, Any], str]], unscored: Sequence[str] = ()) -> str:
    """The league page of the data sets' benchmark results ``(table, result, report file name)``; ``unscored``: the
    registered plugins without window models."""
    L = ["# Real league: every window model on every real data set", "",
         "Generated by `skidbench reproduce real` (`bench/real/league.py`). Each model is fitted on the calibration "
         "half of a data set's command steps and predicts each held-out 2 s window from its measured wheel speeds "
         "(or commands) and the window's initial reference pose; a model that reads other inputs lists them "
         "beside its name; errors at the window's end. Cells: median "
         f"[95 % interval over {N_BOOT} resamples of the held-out command steps, seed {SEED}]; mean and p95 without "
         "interval. \"vs ideal DD\": the paired interval of the difference of medians [m].", ""]
    if unscored:
        L += ["Not scored (registered plugins without window models: they read inputs a DRIVE window lacks, such as "
              "torques or GNSS, or are written against Runs only; `bench.real.adapter.PluginModel` scores a Run-based "
              "one on request): " + ", ".join(f"`{n}`" for n in unscored) + ".", ""]
    for table, res, report in results:
        L += [f"## {res['platform']}: `{table.parent.name}/{table.name}`", "",
              f"{res['n_test_windows']} held-out windows ({res['n_test_steady']} steady, {res['n_test_transitory']} "
              f"transitory) of {len(res['test_steps'])} steps; report with the chi-vs-curvature-ratio figure: "
              f"[{report}]({report}).", "",
              "| model | translation median [m] | mean | p95 | yaw median [rad] | steady: translation median | "
              "transitory: translation median | vs ideal DD |", "|---|---|---|---|---|---|---|---|"]
        rows, verdicts = _rows(res)
        L += rows + [""]
        warn = [f for f in res.get("sanity", {}).get("findings", []) if not f["ok"]]
        L += [f"Data check warning: `{f['check']}`: {f['evidence']}" for f in warn]
        L += verdicts or ["Every ICR-family model beats ideal differential drive here (paired intervals below zero)."]
        L.append("")
    if not results:
        L += ["No real data set found (set SKIDBENCH_DATA to the folder that holds them).", ""]
    return "\n".join(L)


def write_real_league(root: Path, out_dir: Path, done: Mapping[Path, Mapping[str, Any]] | None = None) -> Path:
    """Score every data set of ``root`` (reusing ``done`` results by table) and write ``out_dir/league.md``."""
    from bench.real.benchmark import every_window_plugin, plugins_without_window_models, run_real_benchmark
    from bench.real.platform import kinematic_platform
    from bench.report.io import atomic_write_text

    done = dict(done or {})
    results = []
    for table, plat in data_sets(root):
        res = done.get(table)
        if res is None:
            p = kinematic_platform(plat)
            res = run_real_benchmark(table, out_dir, platform=p, models=every_window_plugin(),
                                     label=f"{table.stem}-{p['name']}")
        results.append((table, res, Path(res["files"][-1]).name))
    path = Path(out_dir) / "league.md"
    atomic_write_text(path, league_markdown(results, plugins_without_window_models()))
    return path
