"""CLI commands for reproduction and regression: ``reproduce``, ``compare``; the extras of ``reproduce``.

    skidbench reproduce [PAPER|EXTRA ...] [--all] [--quick] [--workers N] [--dask-scheduler ADDR] [--results DIR]
    skidbench reproduce --check [PAPER ...]      # check the declarations only (no run): exit 2 on an error
    skidbench compare BASE.json NEW.json

A malformed paper declaration (``scenarios/papers/<paper>.toml``: :func:`bench.reproduce.paper.load_paper`) stops
``reproduce`` before any run with a one-line error naming file, claim, field and value (exit 2); claims not yet
converted to the claim schema of :mod:`bench.reproduce.claims` are listed as warnings.

The extras (:data:`EXTRAS`: league, stress, real, gap, run longest first by ``--all``, beside the papers when
``--workers`` > 1) and their result cache (a marker per extra recording the files it wrote, :func:`_extra_kept`).  Registered into :data:`bench.cli.COMMANDS`
on import.
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import math
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any, Mapping

from bench.cli import _progress, command, count
from bench.cli.real import _extra_real, data_root, dead_stage
from bench.report.io import atomic_write_text


# ------------------------------------------------------------------------------------------ reproduce
def _repro_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("papers", nargs="*", help="paper ids (scenarios/papers/<id>.toml) and extras (league, stress, "
                   "real, gap; sensitivity with --extended); default all")
    p.add_argument("--all", action="store_true", help="every paper, the league table, the gap example, the real data and the stress report")
    p.add_argument("--quick", action="store_true", help="shorter runs / fewer seeds (CI); default output folder results/quick/")
    p.add_argument("--extended", action="store_true",
                   help="also the studies beyond the papers' tables and headline claims (the NEES null distribution and "
                        "its replication, ablations); default output folder results/extended/")
    p.add_argument("--workers", type=count(1), default=os.cpu_count() or 1)
    p.add_argument("--dask-scheduler", default=None, metavar="ADDRESS")
    p.add_argument("--results", type=Path, default=None,
                   help="output folder (default results/, results/quick/ with --quick, results/extended/ with --extended)")
    p.add_argument("--check", action="store_true",
                   help="only check the paper declarations and list their warnings (no run; exit 2 on an error)")


EXTRAS: dict[str, Any] = {}  # name -> callable(results_dir: Path, quick: bool, workers: int[, extended: bool])
EXTENDED_EXTRAS = ("league", "stress", "sensitivity")  # the extras `reproduce --extended --all` runs
EXTENDED_ONLY = ("sensitivity",)  # ... and those only it runs
# the extras' cost order (cold, 2 workers), longest first: the order in which they run beside the papers
EXTRA_COST_ORDER = ("sensitivity", "league", "stress", "real", "gap")


EXTRA_OUTPUTS: dict[str, tuple[str, ...]] = {}  # name -> the relative-path prefixes of its files in the results folder
EXTRA_INPUTS: dict[str, Any] = {}  # name -> () -> str: what it reads beyond the code, specs and data (its marker's key)


def register_extra(name: str, outputs: tuple[str, ...] = ("",), inputs: Any = None):
    """Register an extra: ``fn(results_dir, quick, workers=..., [extended=True])``.  ``outputs``: the prefixes of the
    relative paths of the files it writes (default: any file of the results folder); its result-cache marker records
    those files.  ``inputs``: a function giving a digest of anything else it reads (enters its marker's key).  Only an
    extra that names its outputs runs beside the papers (the papers write the folder meanwhile)."""
    def deco(fn):
        EXTRAS[name] = fn
        EXTRA_OUTPUTS[name] = tuple(outputs)
        if inputs is not None:
            EXTRA_INPUTS[name] = inputs
        return fn
    return deco


def _extra_marker(name: str, results_dir: Path, quick: bool, extended: bool = False) -> Path:
    """A marker per (extra, everything it depends on): code, specs, data, output folder."""
    from bench.reproduce import code_key
    from bench.reproduce.publish import final_dir
    from bench.reproduce.runner import DEFAULT_CACHE

    table = data_root() / "drive_husky" / "husky_windows.parquet"
    data_id = f"{table}:{table.stat().st_size if table.is_file() else 'absent'}"
    more = EXTRA_INPUTS[name]() if name in EXTRA_INPUTS else ""
    key = code_key("extra", name, str(quick), str(final_dir(Path(results_dir)).resolve()), data_id, str(extended), more)
    return Path(DEFAULT_CACHE).parent / "result-cache" / f"extra-{name}-{key}.done"


def _file_state(results_dir: Path, prefixes: tuple[str, ...] = ("",)) -> dict[str, int]:
    """mtime (ns) of every file under ``results_dir`` (whose relative path starts with one of ``prefixes``) by its
    relative path (what an extra rewrites: atomic writes give each written file a new mtime even when its content is
    unchanged)."""
    root = Path(results_dir)
    if not root.is_dir():
        return {}
    return {rel: p.stat().st_mtime_ns for p in root.rglob("*")
            if p.is_file() and (rel := p.relative_to(root).as_posix()).startswith(prefixes)}


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _extra_outputs(results_dir: Path, before: Mapping[str, int], prefixes: tuple[str, ...] = ("",)) -> dict[str, str]:
    """{relative path: sha256} of the files under ``results_dir`` (starting with ``prefixes``) written since ``before``."""
    after = _file_state(results_dir, prefixes)
    return {rel: _sha256(Path(results_dir) / rel) for rel, mt in sorted(after.items()) if before.get(rel) != mt}


def _extra_kept(marker: Path, results_dir: Path) -> bool:
    """True when the extra's marker exists and every file it recorded is in ``results_dir`` with the recorded
    content: the marker alone (keyed on the code, data and output folder) does not show that the folder still holds
    that run's output (a folder reset by git or edited by hand keeps the marker valid but not the files)."""
    if not marker.is_file():
        return False
    try:
        outputs = json.loads(marker.read_text())["outputs"]
    except (ValueError, KeyError, TypeError):
        return False  # a marker of the earlier format (no record of the files): recompute
    return all((Path(results_dir) / rel).is_file() and _sha256(Path(results_dir) / rel) == digest
               for rel, digest in outputs.items())


STALE_TEMP_AGE = 3600.0  # [s] a temp file this old is no live write's (an atomic write lasts seconds)


def _remove_stale_temp_files(results_dir: Path) -> None:
    """Temp files of an interrupted earlier run (``.<name>.<random>.tmp``: the atomic writes never
    give them a final name) are deleted before a new run starts, once older than :data:`STALE_TEMP_AGE`: a younger
    one may be the live write of another reproduction sharing the cache (the sensitivity study's child runs)."""
    from bench.reproduce.runner import DEFAULT_CACHE

    now = time.time()
    for folder in (Path(results_dir), Path(DEFAULT_CACHE), Path(DEFAULT_CACHE).parent / "result-cache"):
        if folder.is_dir():
            for p in folder.rglob(".*.tmp"):
                if not p.is_dir():
                    with contextlib.suppress(OSError):
                        if now - p.stat().st_mtime > STALE_TEMP_AGE:
                            p.unlink(missing_ok=True)
                elif dead_stage(p):  # the stage of a killed `skidbench real --out results/...` (a live one stays)
                    shutil.rmtree(p, ignore_errors=True)


def _extras_job(extras: list[str], results_dir: Path, quick: bool, workers: int, extended: bool,
                log: Any = None, events: Any = None) -> dict[str, dict[str, Any]]:
    """The extras (longest first, :data:`EXTRA_COST_ORDER`), each skipped when its result-cache marker still holds
    (:func:`_extra_kept`); returns their stage times.  Run in a process of its own beside the papers (``--workers``
    > 1) or after them.  ``events``: as :func:`bench.reproduce.reproduce`'s ("start" and "done" per extra)."""
    log = log or (lambda msg: print(msg, flush=True))
    events = events or (lambda *ev: None)
    stages: dict[str, dict[str, Any]] = {}
    rank = {x: i for i, x in enumerate(EXTRA_COST_ORDER)}
    for name in sorted(extras, key=lambda x: rank.get(x, len(rank))):
        t_x = time.perf_counter()
        events("start", name)
        marker = _extra_marker(name, results_dir, quick, extended)
        if _extra_kept(marker, results_dir):
            log(f"{name}: unchanged since the last run, results kept")
            stages[name] = {"seconds": time.perf_counter() - t_x, "from_cache": True}
            events("done", name, True)
            continue
        log(f"extra: {name}")
        prefixes = EXTRA_OUTPUTS.get(name, ("",))
        before = _file_state(results_dir, prefixes)
        EXTRAS[name](results_dir, quick, workers=workers, **({"extended": True} if extended else {}))
        marker.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(marker, json.dumps({"outputs": _extra_outputs(results_dir, before, prefixes)}, indent=1) + "\n")
        stages[name] = {"seconds": time.perf_counter() - t_x, "from_cache": False}
        events("done", name, False)
    return stages


def _reproduce(a: argparse.Namespace) -> int:
    from bench import reproduce as R

    extended = bool(getattr(a, "extended", False))
    if extended and a.quick:
        print("error: reproduce: --quick and --extended exclude each other", file=sys.stderr)
        return 2
    # the quick and extended runs have folders of their own: neither overwrites the full run's per-paper files
    results_dir = a.results or (R.RESULTS / "extended" if extended else R.RESULTS / "quick" if a.quick else R.RESULTS)
    papers = [p for p in a.papers if p not in EXTRAS] or None
    if getattr(a, "check", False):
        checked = papers or R.list_papers()
        warnings: list[str] = []
        R.check_declarations(checked, warnings.append)
        for w in warnings:
            print(w)
        print(f"{len(checked)} paper declaration(s) checked: no error, {len(warnings)} warning(s)")
        return 0
    if extended:
        having = [p for p in R.list_papers() if any(t.get("extended") for t in R.load_paper(p)["tables"])]
        if papers is not None and (none := [p for p in papers if p not in having]):
            print(f"error: reproduce --extended: {', '.join(none)} has no extended table (papers that have one: "
                  f"{', '.join(having) or 'none'})", file=sys.stderr)
            return 2
        if papers is None and (a.all or not a.papers):  # the papers that have a study beyond them
            papers = having  # [] when none has one: then no paper runs
    extras = [p for p in a.papers if p in EXTRAS]
    if a.all or not a.papers:
        extras = list(EXTENDED_EXTRAS if extended else [x for x in EXTRAS if x not in EXTENDED_ONLY])
    if not extended and (only := [x for x in extras if x in EXTENDED_ONLY]):
        print(f"error: reproduce: {', '.join(only)} runs with --extended only", file=sys.stderr)
        return 2
    if extended and (bad := [x for x in extras if x not in EXTENDED_EXTRAS]):
        print(f"error: reproduce --extended: {', '.join(bad)} has no extended variant "
              f"(those that have: {', '.join(EXTENDED_EXTRAS)})", file=sys.stderr)
        return 2
    from bench.reproduce.publish import staged

    with staged(results_dir) as stage:  # published as one set when everything below has finished
        wall = _reproduce_into(a, stage, papers, extras, extended)
    print(f"reproduce finished in {wall:.1f} s -> {results_dir}")
    return 0


def _reproduce_into(a: argparse.Namespace, results_dir: Path, papers: list[str] | None, extras: list[str],
                    extended: bool) -> float:
    """The papers and extras of ``reproduce`` written into ``results_dir`` (the staging folder), with a progress bar
    per stage (:mod:`bench.cli.progress`); the wall time."""
    import threading

    from bench import reproduce as R
    from bench.cli.progress import Sink, StageBars, expected_seconds, pump
    from bench.procs import queue_manager
    from bench.reproduce.runner import DEFAULT_CACHE

    _remove_stale_temp_files(results_dir)
    cache_was_empty = not any(Path(DEFAULT_CACHE).glob("*.parquet")) if Path(DEFAULT_CACHE).is_dir() else True
    t0 = time.perf_counter()
    stages: dict[str, dict[str, Any]] = {}
    stats = {"simulated": 0, "cached": 0}
    with _progress() as prog, queue_manager() as manager:
        lock, stop = threading.Lock(), threading.Event()
        bars = StageBars(prog, expected_seconds(results_dir, a.quick))
        q = manager.Queue()
        events = Sink(q)  # picklable: the pool processes of the papers and of the extras send through it
        reader = threading.Thread(target=pump, args=(q, bars, stop, lock), daemon=True)
        reader.start()

        def log(msg: str) -> None:
            with lock:
                prog.console.print(msg, markup=False, highlight=False)  # "[m]" in a message is text, not markup

        run_papers = papers != [] and (papers is not None or a.all or not a.papers)

        def papers_stage() -> None:
            runner_stats: dict[str, Any] = {}
            R.reproduce(papers, quick=a.quick, workers=a.workers, dask_scheduler=a.dask_scheduler,
                        results_dir=results_dir, log=log, extended=extended, stats_out=runner_stats, events=events)
            stages.update(runner_stats.get("stages", {}))
            for k in stats:
                stats[k] += runner_stats.get(k, 0)

        try:
            beside_ok = all(EXTRA_OUTPUTS.get(x, ("",)) != ("",) for x in extras)
            if run_papers and extras and beside_ok and a.workers > 1 and a.dask_scheduler is None:
                # the extras run beside the papers, in a process of their own that waits on their pools (longest
                # first): the cores the last paper jobs leave idle do the league and the stress cases.  A process, not
                # a thread: the pools fork, and a fork from a process with a busy second thread can copy a lock that
                # thread holds
                from bench.procs import process_pool

                with process_pool(1) as beside:
                    fut = beside.submit(_extras_job, extras, results_dir, a.quick, a.workers, extended, None, events)
                    try:
                        papers_stage()
                    finally:
                        stages.update(fut.result())
            else:
                if run_papers:
                    papers_stage()
                stages.update(_extras_job(extras, results_dir, a.quick, a.workers, extended, log, events))
        finally:
            stop.set()
            reader.join()
    R.link_extras(Path(results_dir), a.quick)
    wall = time.perf_counter() - t0
    if (a.all or not a.papers) and (papers is None or extended):  # the whole reproduction: its stage table
        from bench.reproduce import timing

        doc = timing.record(Path(results_dir), a.quick, stages, wall, stats["simulated"], stats["cached"], a.workers,
                            cache_was_empty, extended)
        timing.insert(Path(results_dir) / ("REPORT_quick.md" if a.quick else "REPORT.md"), doc)
    return wall


command("reproduce", "regenerate paper tables, figures, REPORT.md and metrics.json")((_repro_args, _reproduce))


# ------------------------------------------------------------------------------------------ compare
def compare_metrics(base: Mapping[str, Any], new: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Metrics of ``base`` that moved beyond their tolerance in ``new`` (or vanished / became NaN).

    Values are read with :func:`bench.report.io.json_number`: null is NaN (no value: a NaN baseline
    has nothing to move from), "inf" / "-inf" are infinite and equal only to the same infinity (a
    change between finite and infinite, either way, is flagged; before strict JSON an infinite
    baseline had an infinite relative tolerance and was never flagged)."""
    from bench.report.io import json_number

    out = []
    bm, nm = base.get("metrics", {}), new.get("metrics", {})
    for mid, b in bm.items():
        bv = json_number(b["value"])
        tol = b.get("tolerance", {})
        allowed = max(float(tol.get("abs", 0.0)), float(tol.get("rel", 0.0)) * abs(bv or 0.0))
        if mid not in nm:
            out.append({"metric": mid, "base": b["value"], "new": None, "allowed": allowed, "why": "missing in new"})
            continue
        nv = json_number(nm[mid]["value"])
        if bv is None or nv is None:
            out.append({"metric": mid, "base": b["value"], "new": nm[mid]["value"], "allowed": allowed,
                        "why": "value is not a number"})
            continue
        if math.isnan(nv) and not math.isnan(bv):
            out.append({"metric": mid, "base": bv, "new": nv, "allowed": allowed, "why": "became NaN"})
        elif math.isnan(bv) or math.isnan(nv):
            continue  # no value before (a NaN baseline has nothing to move from)
        elif math.isinf(bv) or math.isinf(nv):
            if nv != bv:
                out.append({"metric": mid, "base": bv, "new": nv, "allowed": allowed,
                            "why": f"changed from {bv} to {nv}"})
        elif abs(nv - bv) > allowed:
            out.append({"metric": mid, "base": bv, "new": nv, "allowed": allowed,
                        "why": f"moved by {nv - bv:+.4g} (allowed ±{allowed:.3g})"})
    return out


def _cmp_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("base", type=Path)
    p.add_argument("new", type=Path)
    p.add_argument("--papers", default=None, metavar="P1,P2",
                   help="compare only these papers' metrics (e.g. a one-paper reproduce against the full baseline)")


def _read_metrics(path: Path) -> dict[str, Any]:
    """A metrics document, or a :class:`~bench.spec.SpecError` naming the file (one line, exit 2)."""
    from bench.spec import SpecError

    try:
        doc = json.loads(path.read_text())
    except OSError as exc:
        raise SpecError(path, "<file>", str(path), f"cannot read the metrics file ({exc.strerror})") from None
    except ValueError as exc:
        raise SpecError(path, "<file>", str(path), f"not JSON ({exc})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("metrics"), dict):
        raise SpecError(path, "metrics", None, "not a metrics document (a JSON object with 'metrics')")
    from bench.report.io import json_number

    for mid, m in doc["metrics"].items():
        if not isinstance(m, dict) or "value" not in m:
            raise SpecError(path, f"metrics.{mid}", m, "a JSON object with a 'value'")
        if json_number(m["value"]) is None:
            raise SpecError(path, f"metrics.{mid}.value", m["value"], "a number, null, \"inf\" or \"-inf\"")
        tol = m.get("tolerance", {})
        if not isinstance(tol, dict):
            raise SpecError(path, f"metrics.{mid}.tolerance", tol, "a JSON object with 'abs' and/or 'rel'")
        for k in ("abs", "rel"):
            v = tol.get(k, 0.0)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v >= 0 and math.isfinite(v)):
                raise SpecError(path, f"metrics.{mid}.tolerance.{k}", v, "a finite number >= 0")
    return doc


def _only(doc: Mapping[str, Any], papers: set[str]) -> dict[str, Any]:
    """``doc`` with the metrics of ``papers`` only (a metric id begins with its paper: ``<paper>.<table>.<key>``)."""
    return {**doc, "metrics": {k: v for k, v in doc["metrics"].items() if k.split(".", 1)[0] in papers}}


def _compare(a: argparse.Namespace) -> int:
    from bench.spec import SpecError

    base = _read_metrics(a.base)
    new = _read_metrics(a.new)
    if a.papers is not None:
        papers = {p.strip() for p in a.papers.split(",") if p.strip()}
        known = {k.split(".", 1)[0] for k in base["metrics"]}
        if not papers or not papers <= known:
            raise SpecError("<command line>", "--papers", a.papers,
                            f"paper ids of the baseline: {', '.join(sorted(known))}")
        base, new = _only(base, papers), _only(new, papers)
    moved = compare_metrics(base, new)
    if not moved:
        print(f"no metric moved beyond its tolerance ({len(base.get('metrics', {}))} compared)")
        return 0
    for m in moved:
        print(f"REGRESSION {m['metric']}: {m['base']} -> {m['new']} ({m['why']})")
    print(f"{len(moved)} metric(s) moved beyond tolerance", file=sys.stderr)
    return 1


command("compare", "list metrics that moved beyond tolerance; non-zero exit on regression")((_cmp_args, _compare))


# ------------------------------------------------------------------------------------------ extras
register_extra("real", outputs=("real/",))(_extra_real)  # the real data (bench.cli.real)


@register_extra("league", outputs=("league",))
def _extra_league(results_dir: Path, quick: bool, workers: int = 1, extended: bool = False) -> None:
    from bench.reproduce.league import write_league
    from bench.reproduce.runner import Runner

    write_league(results_dir, quick, Runner(workers=workers), extended=extended)


@register_extra("gap", outputs=("gap/",))
def _extra_gap(results_dir: Path, quick: bool, workers: int = 1) -> None:  # serial: one worked example
    from bench.gap import write_worked_example

    write_worked_example(Path(results_dir) / "gap")


def _sensitivity_base() -> str:
    """The full run the sensitivity study compares with (its claims and runs manifest): their digest, or 'absent'."""
    from bench.reproduce.sensitivity import base_files

    return ";".join(_sha256(p) if p.is_file() else "absent" for p in base_files())


@register_extra("sensitivity", outputs=("sensitivity",), inputs=_sensitivity_base)
def _extra_sensitivity(results_dir: Path, quick: bool, workers: int = 1, extended: bool = False) -> None:
    """The verdicts a chosen testbed parameter decides (``sensitivity.md``, :mod:`bench.reproduce.sensitivity`):
    each choice's papers re-run at its declared alternative, against the full run's ``results/claims.json``
    (skipped, saying so, when there is no full run to compare with)."""
    from bench.reproduce.sensitivity import base_files, run_sensitivity

    if missing := [str(p) for p in base_files() if not p.is_file()]:
        print(f"sensitivity: skipped: no full run to compare with ({', '.join(missing)} missing; `make reproduce` "
              "first)")
        return
    doc = run_sensitivity(results_dir, workers=workers)
    n = sum(1 for c in doc["choices"] for r in c["flips"] if not r["target"])
    print(f"sensitivity: {len(doc['choices'])} choices, {n} verdicts that are not calibration targets change")


@register_extra("stress", outputs=("stress",))
def _extra_stress(results_dir: Path, quick: bool, workers: int = 1, extended: bool = False) -> None:
    """Filters under stress (``results/stress.md``): in ``make reproduce`` the short runs of seed 1
    (``bench.robustness.stress.QUICK``, the paper filters; Liu's consistent configurations too with ``--extended``); the six-seed + 1-hour table (``bench.robustness.stress.FULL``,
    tens of minutes) is ``python -c "from bench.robustness.stress import stress_report; stress_report('results',
    quick=False)"``.  Skipped by ``reproduce --quick`` (CI): ``make test`` runs the stress tests."""
    if quick:
        print("stress: skipped in --quick (tests/test_stress.py runs in make test)")
        return
    from bench.robustness.stress import stress_report

    print(f"stress: {stress_report(results_dir, quick=True, workers=workers, extended=extended)}")
