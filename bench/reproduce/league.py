"""Cross-paper league table: every registered method on every league scenario where its
sensors exist; position RMS against the testbed truth, mean and 95% bootstrap interval over
seeds (``results/league.md``, ``results/league.csv``).

Fairness rules:

* Each method is calibrated once per (platform, terrain) on a *calibration set* simulated on the
  same platform and terrain but with other commands and seeds (pure rotation, straight line,
  steady circles at curvature ratios 1..7, a joystick-like random path; seeds >= 1000): never on
  a scored run, which ``bench.registry.estimate`` also enforces.  Each method takes from the set
  what its paper's identification uses (Mandow: rotation + straight, GA on the random path;
  Wang: the steady circles; Yi: S(gamma) from the turns; Liu: ICR from the reference).
* Scored runs: the league scenarios with seeds 0..n-1; identical runs for every method.
* A method whose calibration or estimate fails on a scenario gets a cell that says why in words (no machine
  path), not a silent zero; an estimate that diverges (:func:`bench.metrics.divergence`) is reported as
  "diverged at t = ..." with its step, never averaged.
* The table (:mod:`bench.reproduce.league_table`) ranks methods only against those that read the same sensors.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from scipy import stats

from bench import registry
from bench.metrics import Divergence, Trajectory, divergence, position_rms
from bench.procs import process_pool
from bench.report.io import atomic_write_text
from bench.reproduce.runner import Runner
from bench.run import RunError
from bench.spec import CommandSpec, Scenario, Segment, load_scenario

LEAGUE_SCENARIOS = (
    "circle_vinyl", "wang_validation_path", "yu_lemniscate", "mandow_joystick_asphalt_pneumatic_20psi",
    "yi_circle", "yi_figure8", "liu_large_radius", "liu_small_radius",
)
CALIBRATION_SEED = 1000


def calibration_set(scn: Scenario, quick: bool = False) -> list[tuple[Scenario, int]]:
    """Runs on the scenario's platform and terrain with other commands (never the scored path)."""
    plat = scn.platform
    v = min(0.3, 0.15 * plat.wheel_radius / 0.1075 * 2)  # a moderate tread speed for the platform
    dur = 6.0 if quick else 10.0
    reqs: list[tuple[Scenario, int]] = [
        (dataclasses.replace(scn, id=f"{scn.id}-cal-rotation", command=CommandSpec(kind="rotation", v=v), duration=dur,
                             initial_speed=0.0), CALIBRATION_SEED),
        (dataclasses.replace(scn, id=f"{scn.id}-cal-straight", command=CommandSpec(
            kind="v_radius", segments=(Segment(dur, 2 * v, math.inf),), accel=1.0), duration=dur, initial_speed=0.0),
         CALIBRATION_SEED),
    ]
    for lam in ((2.0, 5.0) if quick else (1.0, 2.0, 3.0, 5.0, 7.0)):
        reqs.append((dataclasses.replace(scn, id=f"{scn.id}-cal-circle{lam:g}", command=CommandSpec(
            kind="v_curvature_ratio", segments=(Segment(dur, 2 * v, lam),)), duration=dur, initial_speed=0.0),
            CALIBRATION_SEED))
    reqs.append((dataclasses.replace(scn, id=f"{scn.id}-cal-random", command=CommandSpec(
        kind="random", step=2.0, v_max=2 * v, w_max=1.0, accel=1.0), duration=30.0 if quick else 60.0,
        initial_speed=0.0), CALIBRATION_SEED + 1))
    return reqs


@dataclass
class Cell:
    """One method on one league scenario: the position RMS of each scored seed (``values[i]`` is seed ``i``), the
    seeds whose estimate diverged (:func:`bench.metrics.divergence`: ``(seed, t, step, error, bound)``), the error that
    kept the method from running (in words, no machine path) and a note on its calibration."""

    method: str
    scenario: str
    values: list[float]
    error: str = ""
    note: str = ""
    diverged: list[tuple[int, float, int, float, float]] = field(default_factory=list)

    def summary(self) -> tuple[float, float, float]:
        """Mean and 95 % bootstrap interval over the seeds; NaN when any seed diverged (never averaged)."""
        v = np.asarray([x for x in self.values if math.isfinite(x)])
        if v.size == 0 or self.diverged:
            return math.nan, math.nan, math.nan
        if v.size < 3 or np.ptp(v) == 0:
            return float(v.mean()), float(v.min()), float(v.max())
        ci = stats.bootstrap((v,), np.mean, confidence_level=0.95, n_resamples=2000, method="percentile",
                             random_state=np.random.default_rng(0)).confidence_interval
        return float(v.mean()), float(ci.low), float(ci.high)


def _score(run: Any, est: Any) -> tuple[float, Divergence | None]:
    """Position RMS of the estimate against the truth (planar; z ignored) and its divergence, if any."""
    d = run.data
    ref = Trajectory.planar(d["t"], d["truth_x"], d["truth_y"], d["truth_yaw"], name="truth")
    e = est.data
    ok = np.isfinite(e["x"].to_numpy()) & np.isfinite(e["y"].to_numpy()) & np.isfinite(e["yaw"].to_numpy())
    if not ok.any():
        raise ValueError("the estimate has no finite pose")
    traj = Trajectory.planar(e["t"][ok], e["x"][ok], e["y"][ok], e["yaw"][ok], name=est.method)
    rms, div = position_rms(ref, traj), divergence(ref, traj)
    if not ok[-1]:  # a filter that blew up to NaN / inf and stayed there: diverged where its last finite run ended
        i_est = int(np.flatnonzero(ok)[-1]) + 1
        t_bad = float(e["t"].iloc[i_est])
        step = int(np.searchsorted(ref.t, t_bad))
        if step < ref.t.size and (div is None or t_bad < div.t):
            div = Divergence(float(ref.t[step]), step, math.nan, math.nan)
    return rms, div


_PATH = re.compile(r"(?<![\w.~-])/(?:[^\s:'\"/]+/)*([^\s:'\"/]+)")


def reason(exc: BaseException) -> str:
    """An exception as the words of a table note: its type and message with every absolute path replaced by the
    file's name (a run file's path, first in a RunError, is dropped: the cell already names the run)."""
    msg = str(exc)
    if isinstance(exc, RunError) or msg.startswith("/"):
        head, sep, rest = msg.partition(": ")
        if sep and _PATH.fullmatch(head):
            msg = rest
    return f"{type(exc).__name__}: {_PATH.sub(lambda m: m.group(1), msg)}"


def _calibrate(name: str, cal: list, note: list[str]) -> tuple[Any, str]:
    """Calibrate on the whole set; a method that rejects some kinds of run gets the steady runs only; one that
    still fails runs with its published defaults (said in the notes).  Returns the method and, when no
    calibration took, why (the cell reports it if the defaults cannot run either)."""
    try:
        return registry.calibrate(registry.get(name), cal), ""
    except Exception as exc:
        first = reason(exc)
    steady = [r for r in cal if r.meta.get("scenario_kind") != "random"]
    try:
        m = registry.calibrate(registry.get(name), steady)
        note.append(f"calibrated on the steady runs only, the random path refused ({first})")
        return m, ""
    except Exception as exc:
        why = reason(exc)
        note.append(f"uncalibrated, published defaults (calibration failed: {why})")
        return registry.get(name), why


def _league_requests(sname: str, quick: bool, n_seeds: int) -> tuple[list, list]:
    """(scenario, seed) requests of one league scenario: its calibration set and its scored runs."""
    scn = load_scenario(sname, {"duration": 12.0} if quick else None)
    return calibration_set(scn, quick), [(scn, s) for s in range(n_seeds)]


def _league_runs(runner: Runner, sname: str, quick: bool, n_seeds: int) -> tuple[list, list]:
    """The calibration set and the scored runs of one league scenario (simulated or from the cache)."""
    cal, scored = _league_requests(sname, quick, n_seeds)
    return runner.simulate_many(cal), runner.simulate_many(scored)


@functools.lru_cache(maxsize=2)
def _cached_runs(sname: str, quick: bool, n_seeds: int, cache_dir: str) -> tuple[list, list]:
    """Per worker process: the runs of the last two scenarios it scored (jobs are ordered by cost, so a
    worker may come back to a scenario: then the runs are read from the run cache again)."""
    return _league_runs(Runner(cache_dir=Path(cache_dir), workers=1), sname, quick, n_seeds)


def _cell(name: str, sname: str, cal: list, scored: list) -> Cell:
    """One method on one scenario: calibrate on the calibration set, score every seed, flag divergences."""
    cell = Cell(name, sname, [])
    failed_calibration = ""
    try:
        missing = sorted(registry.get(name).requires - set(scored[0].data.columns))
        if missing:
            cell.error = f"the scenario's runs have no {', '.join(missing)}"
            return cell
        note: list[str] = []
        m, failed_calibration = _calibrate(name, cal, note)
        cell.note = "; ".join(note)
        for seed, run in enumerate(scored):
            rms, div = _score(run, registry.estimate(m, run))
            cell.values.append(rms)
            if div is not None:
                cell.diverged.append((seed, div.t, div.step, div.error, div.bound))
    except Exception as exc:  # reported in the table, never a silent number
        cell.values = []
        cell.error = (f"cannot run here: its calibration failed ({failed_calibration})" if failed_calibration
                      else reason(exc))
        cell.note = ""
    return cell


def _cell_job(names: tuple[str, ...], sname: str, quick: bool, n_seeds: int, cache_dir: str) -> list[Cell]:
    """Worker: the cells of ``names`` on one scenario (its runs read from the run cache once for all of them)."""
    cal, scored = _cached_runs(sname, quick, n_seeds, cache_dir)
    return [_cell(name, sname, cal, scored) for name in names]


# Relative cost of a cell (calibration + 5 estimates; measured on yi_figure8, seconds on one core: the paper UKFs
# ~6 s, their consistent configurations 28-39 s, the GA ~2-3 s with its cost in C (11 s in numpy), the EKFs ~1.3 s,
# their consistent ones 3-5 s, the rest < 1 s; a scenario's 13 runs take ~2.5 s to read, once per job): jobs are
# submitted most expensive first.
CELL_COST = {"liu2020.mi_ukf": 6.0, "liu2020.ukf_icr": 6.0, "liu2020.mi_ukf_consistent": 38.0,
             "liu2020.ukf_icr_consistent": 28.0, "mandow2007.asymmetric_ga": 2.5,
             "mandow2007.asymmetric_de": 0.6, "yi2009.ekf_v1": 1.3, "yi2009.ekf_v2": 1.3, "yi2009.ekf_v3": 1.3,
             "yi2009.ekf_v1_consistent": 3.0, "yi2009.ekf_v2_consistent": 4.0, "yi2009.ekf_v3_consistent": 4.5,
             "yu2010.closed_loop": 1.2, "yu2010.open_loop": 1.2}


def _jobs(pairs: list[tuple[str, str]], workers: int) -> list[tuple[tuple[str, ...], str]]:
    """The cells grouped into jobs: per scenario, its methods dealt into ``workers`` parts of about equal cost
    (most expensive first; one part when there are at least two scenarios per worker), so that a job reads its
    scenario's runs once (a job per cell read them per cell:
    the parquet reads were a large part of the league's time); jobs ordered most expensive first."""
    by_scenario: dict[str, list[str]] = {}
    for name, sname in pairs:
        by_scenario.setdefault(sname, []).append(name)
    jobs: list[tuple[float, tuple[str, ...], str]] = []
    # with at least two scenarios per worker, one job per scenario balances as well and reads its runs once
    n_parts = 1 if len(by_scenario) >= 2 * max(1, workers) else max(1, workers)
    for sname, names in by_scenario.items():
        parts: list[tuple[float, list[str]]] = [(0.0, []) for _ in range(n_parts)]
        for name in sorted(names, key=lambda n: -CELL_COST.get(n, 0.5)):
            i = min(range(len(parts)), key=lambda j: parts[j][0])
            parts[i] = (parts[i][0] + CELL_COST.get(name, 0.5), parts[i][1] + [name])
        jobs += [(cost, tuple(names_), sname) for cost, names_ in parts if names_]
    jobs.sort(key=lambda j: -j[0])
    return [(names_, sname) for _, names_, sname in jobs]


def league_methods(extended: bool = False) -> list[str]:
    """The registered methods of the league: every paper's configuration and the baselines; with ``extended`` also
    the configurations that are skidbench's own (a plugin with ``beyond_paper = True``, e.g. the consistent
    filters: 70 % of the league's time, ``reproduce --extended``)."""
    names = list(registry.discover())
    return names if extended else [n for n in names if not getattr(registry.get(n), "beyond_paper", False)]


def run_league(runner: Runner, n_seeds: int = 5, quick: bool = False, methods: list[str] | None = None,
               scenarios: tuple[str, ...] = LEAGUE_SCENARIOS, log: Callable[[str], None] = lambda s: None,
               extended: bool = False) -> list[Cell]:
    """Every method on every scenario.  The runs are simulated first (through ``runner``: cache,
    pool or Dask); then, with ``runner.workers > 1``, the cells (method x scenario) run in a process pool as
    jobs of one scenario each (:func:`_jobs`), most expensive first.  Each cell is deterministic and independent of the others,
    so the table is the same bytes serial or parallel (tested)."""
    names = methods or league_methods(extended)
    seeds = 2 if quick else n_seeds
    pairs = [(name, sname) for sname in scenarios for name in names]
    parallel = runner.workers > 1 and not runner.dask_scheduler
    runs = {}
    for sname in scenarios:
        cal, scored = _league_requests(sname, quick, seeds)
        if parallel:  # simulate only: the workers read the runs from the run cache
            runner.prepare(cal + scored)
        else:
            runs[sname] = runner.simulate_many(cal), runner.simulate_many(scored)
        log(f"league: {sname} ({len(cal)} calibration runs, {len(scored)} scored)")
    if not parallel:
        return [_cell(name, sname, *runs[sname]) for name, sname in pairs]
    with process_pool(runner.workers) as ex:
        futures = [ex.submit(_cell_job, names_, sname, quick, seeds, str(runner.cache_dir))
                   for names_, sname in _jobs(pairs, runner.workers)]
        got = {(c.method, c.scenario): c for fut in futures for c in fut.result()}
    cells = [got[pair] for pair in pairs]
    log(f"league: {len(cells)} cells on {runner.workers} workers")
    return cells


def write_league(results_dir: Path, quick: bool, runner: Runner | None = None,
                 log: Callable[[str], None] = print, extended: bool = False) -> list[Cell]:
    runner = runner or Runner(workers=os.cpu_count() or 1)
    n = 2 if quick else 5
    cells = run_league(runner, n_seeds=n, quick=quick, log=log, extended=extended)
    suffix = "_quick" if quick else ""
    from bench.reproduce.league_table import league_csv, league_markdown

    columns = {}
    for sname in dict.fromkeys(c.scenario for c in cells):
        scn = load_scenario(sname)
        columns[sname] = f"{scn.platform.name}, {scn.terrain.name}"
    atomic_write_text(results_dir / f"league{suffix}.md", league_markdown(cells, n, extended, columns))
    atomic_write_text(results_dir / f"league{suffix}.csv", league_csv(cells))
    return cells
