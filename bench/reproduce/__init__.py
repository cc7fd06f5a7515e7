"""Paper reproduction: tables reproduced beside the published numbers, claims with verdicts.

Each paper declares its experiments in ``scenarios/papers/<paper>.toml``::

    paper = "wang2015"
    citation = "T. Wang et al., Sensors 15(5), 2015"
    module = "methods.wang2015.repro"          # where the compute functions live

    [[tables]]
    id = "table3"
    title = "ICR coefficient chi per curvature ratio"
    source = "Wang 2015 Table 3"
    compute = "table3"                          # module.table3(ctx) -> dict[str, float]
    note = "..."                                # optional, printed beside the table
      [[tables.rows]]
      metric = "chi_lambda0"                    # key returned by compute
      label = "chi at curvature ratio 0"
      published = 1.4662
      tolerance_rel = 0.05                      # or tolerance_abs; none -> no per-row verdict

    [[claims]]
    id = "chi_decreases"
    text = "chi decreases as the curvature ratio grows"
    quote = "..."                               # the paper's words, <= 300 characters
    source = "Wang 2015 Sec. 3.4, p. 9693"
    headline = true                             # abstract / conclusions / main comparative result
    scope = "paper"                             # or "beyond": our own check, listed apart
    kind = "trend"                              # ordering | ratio | trend | within | flag
    series = ["table3.chi_lambda0", "table3.chi_lambda1"]
    direction = "decreasing"
    tolerance = 0.01
    tolerance_origin = "..."                    # where the tolerance comes from
      [claims.cause]                            # why it fails, when it does
      kind = "testbed"                          # method | testbed | protocol | paper
      text = "..."                              # <= 300 characters

A table whose published numbers were measured on a real robot sets ``published_on = "real robot"``: its rows show
the ratio reproduced / published and no verdict.  A claim a testbed parameter was chosen for (``[sources]`` of a
platform or terrain, kind "chosen": :mod:`bench.reproduce.sources`) gets the verdict "calibration target".

An ``ordering`` claim (``metrics = [a, b, ...]``, holds when a < b < ...) may name a ``margin`` metric (e.g. two
standard errors of the difference): it then holds only when a + margin < b at each step, so that an ordering
inside the measurement's sampling error is not reported as holding.  A ``ratio`` claim may name one too (the
half-width of the seeds' 95 % interval of the ratio): ``num / den + margin`` must then meet its ``<=`` value.  A
failing claim with a margin is *refuted* only when the whole interval lies on the failing side; otherwise the report
says "not refuted: inside the seeds' 95 % interval" beside "does not hold" (:func:`refuted`), and "the means favour
the claim" when the point values alone are on its side (:func:`favours`).  A quick run shows a claim's
``cause_quick`` when it declares one (its fewer seeds and shorter runs give other numbers, sometimes another reason),
else its cause marked as the full run's.  A cause text quotes the run's own numbers as ``{<table>.<metric>:.3f}``
(:func:`bench.reproduce.claims.fill_numbers`).

Metric ids are ``<table>.<metric>`` inside a paper and ``<paper>.<table>.<metric>`` globally.
A compute function receives a :class:`Context` (cached/parallel simulation, seeds, quick mode,
figure and note registration) and returns its metrics.  Verdicts are computed from the numbers;
nothing is written by hand.  Every file is written atomically.

Modules: :mod:`~bench.reproduce.paper` (declarations, Context, one paper's reproduction and its result
cache), :mod:`~bench.reproduce.claims` (claim kinds, verdicts), :mod:`~bench.reproduce.report` (tables,
REPORT.md, metrics.json, history), :mod:`~bench.reproduce.provenance` (commit, package versions, code key),
:mod:`~bench.reproduce.runner` (scenario x seed runs through the run cache), :mod:`~bench.reproduce.sources`
(calibration targets from the parameter sources), :mod:`~bench.reproduce.league`;
:func:`reproduce` (all papers, serially or as parallel jobs) is here.  The names importers use are
importable from ``bench.reproduce``.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from bench.report.io import atomic_write_json
from bench.reproduce.claims import (CAUSE_KINDS, CLAIM_KINDS, SCOPES, VERDICTS, claim_metric_ids, evaluate_claim,
                                    fails_if, favours, refuted, row_verdict, verdict)
from bench.reproduce.paper import (PAPERS_DIR, RESULTS, Context, PaperResult, claim_result, half_width, list_papers,
                                   load_paper, mean_ci, published_values, reproduce_paper)
from bench.reproduce.provenance import code_key, git_commit, package_versions
from bench.reproduce.report import (EXTRA_RESULTS, EXTRAS_BEGIN, EXTRAS_END, append_history, claims_document,
                                    link_extras, metrics_document, paper_markdown, write_documents, write_paper,
                                    write_report)
from bench.reproduce.runner import REPO, Runner
from bench.reproduce.sources import calibration_targets, parameter_sources

__all__ = [
    "reproduce", "check_declarations", "PAPER_COST_ORDER", "CLAIM_KINDS", "CAUSE_KINDS", "SCOPES", "VERDICTS", "claim_metric_ids",
    "evaluate_claim", "refuted", "favours", "fails_if", "row_verdict", "verdict", "PAPERS_DIR", "RESULTS", "Context", "PaperResult",
    "claim_result", "half_width", "list_papers", "load_paper", "mean_ci", "published_values", "reproduce_paper", "code_key",
    "git_commit", "package_versions", "EXTRA_RESULTS", "EXTRAS_BEGIN", "EXTRAS_END", "append_history",
    "claims_document", "link_extras", "metrics_document", "paper_markdown", "write_documents", "write_paper",
    "write_report", "REPO", "Runner", "calibration_targets", "parameter_sources",
]


def reproduce(papers: list[str] | None = None, *, quick: bool = False, workers: int = 1,
              dask_scheduler: str | None = None, results_dir: Path = RESULTS,
              log: Callable[[str], None] = print, progress: Callable[[int, int], None] | None = None,
              cache_dir: Path | None = None, extended: bool = False,
              stats_out: dict | None = None, events: Callable[..., None] | None = None) -> list[PaperResult]:
    """Reproduce ``papers`` (default: all) into ``results_dir``.

    Parallelism: with a Dask scheduler, or one worker, the papers run one after the other in this
    process and their simulations go to the pool / cluster.  With ``workers > 1`` locally, the papers
    themselves run as jobs in a process pool (longest first, :data:`PAPER_COST_ORDER`), each with a
    runner of its own (a pool of as many simulation workers) sharing the run cache: a paper's computation
    (filters, identification) is most of its time, so this keeps both cores busy where a pool of simulations
    alone leaves one idle.  Every job is deterministic, so the results are the same bytes either way (tested).

    ``events``: a picklable callable given each paper's progress, ``events(kind, paper, *args)`` with kind "start",
    "step" (tables done, total, table id), "sim" (runs simulated, total) and "done" (from the result cache?); the
    command line's bars (:mod:`bench.cli.progress`)."""
    papers = papers or list_papers()
    check_declarations(papers, log)  # a malformed declaration stops here, before any run
    runner = Runner(workers=workers, dask_scheduler=dask_scheduler, progress=progress)
    if cache_dir is not None:
        runner.cache_dir = Path(cache_dir)
    t0 = time.perf_counter()
    if workers > 1 and dask_scheduler is None and len(papers) > 1:
        results = _reproduce_parallel(papers, runner, results_dir, quick, log, progress, extended, events)
    else:
        results = []
        for p in papers:
            t_p, sim0 = time.perf_counter(), runner.stats["sim_seconds"]
            hits = runner.stats["result_cache_hits"]
            if events is not None:
                events("start", p)
                runner.progress = _sim_events(events, p, progress)
            results.append(reproduce_paper(p, runner, results_dir, quick, log, extended=extended,
                                           step=_step_events(events, p)))
            runner.stats["stages"][p] = {"seconds": time.perf_counter() - t_p,
                                         "simulation_seconds": runner.stats["sim_seconds"] - sim0,
                                         "from_cache": runner.stats["result_cache_hits"] > hits}
            if events is not None:
                events("done", p, runner.stats["stages"][p]["from_cache"])
    seconds = time.perf_counter() - t0
    for res in results:
        for c in res.claims:
            if c.get("verdict") == "does not hold" and not c.get("cause"):
                log(f"warning: {res.paper}.{c['id']} does not hold and declares no cause "
                    f"([claims.cause{'_quick' if quick else ''}])")
            for rel in (c.get("cause") or {}).get("stale", []):
                log(f"warning: {res.paper}.{c['id']}: its cause's words state {rel}, which this run does not meet")
    suffix = "_quick" if quick else ""
    write_documents(results, results_dir, quick)
    atomic_write_json(results_dir / f"runs_manifest{suffix}.json", runner.manifest)
    write_report(results, results_dir, quick, runner, seconds, extended)
    append_history(results_dir, results, quick, seconds, extended)
    if stats_out is not None:
        stats_out.update(runner.stats)
    return results


def check_declarations(papers: list[str], log: Callable[[str], None] = print) -> None:
    """Load every paper's declaration (a :class:`~bench.spec.SpecError` on the first error: ``skidbench reproduce``
    exits 2), log its warnings (claims not yet converted to the schema of :mod:`bench.reproduce.claims`), and warn
    about a parameter source naming a claim no paper declares."""
    declared = set()
    for p in papers:
        decl = load_paper(p)
        declared |= {f"{decl['paper']}.{c['id']}" for c in decl.get("claims", [])}
        for w in decl["_warnings"]:
            log(f"warning: {w}")
    every = papers == list_papers()
    for claim, sources in sorted(calibration_targets().items()):
        if every and claim not in declared:
            log(f"warning: {', '.join(f'{s.file} [sources] {s.parameter}' for s in sources)} names claim "
                f"'{claim}', which no paper declares")


# Papers by their measured reproduction time (longest first), the order in which parallel jobs are
# submitted so that the longest one does not start last; a paper not listed goes last.
# cold, 2 workers, beside the extras (fresh clone, 304c11c): 172, 144, 111, 73, 33 s
PAPER_COST_ORDER = ("wang2015", "liu2020", "mandow2007", "yi2009", "yu2010")


def _sim_events(events: Callable[..., None] | None, paper: str,
                also: Callable[[int, int], None] | None = None) -> Callable[[int, int], None] | None:
    """A runner's progress callback sending "sim" events for ``paper`` (and calling ``also``)."""
    if events is None:
        return also

    def sim(done: int, total: int) -> None:
        events("sim", paper, done, total)
        if also is not None:
            also(done, total)
    return sim


def _step_events(events: Callable[..., None] | None, paper: str) -> Callable[[int, int, str], None] | None:
    return None if events is None else (lambda done, total, label: events("step", paper, done, total, label))


def _paper_job(name: str, results_dir: Path, quick: bool, cache_dir: Path, extended: bool = False,
               sim_workers: int = 1, events: Callable[..., None] | None = None) -> tuple[PaperResult, dict, dict]:
    """Worker: one paper with a runner of its own on the shared run cache (runs are written atomically,
    so two jobs asking for the same run at once both write the same bytes).  Its missing runs are simulated in a
    pool of ``sim_workers`` processes: a paper whose time is simulation (Wang's stiff tile at 1/1920 s) then
    uses the cores the other jobs leave idle (the runs are the same bytes on any number of workers)."""
    runner = Runner(cache_dir=cache_dir, workers=sim_workers, progress=_sim_events(events, name))
    t0 = time.perf_counter()
    if events is not None:
        events("start", name)
    res = reproduce_paper(name, runner, results_dir, quick, log=lambda s: print(s, flush=True), extended=extended,
                          step=_step_events(events, name))
    runner.stats["stages"][name] = {"seconds": time.perf_counter() - t0,
                                    "simulation_seconds": runner.stats["sim_seconds"],
                                    "from_cache": runner.stats["result_cache_hits"] > 0}
    if events is not None:
        events("done", name, runner.stats["stages"][name]["from_cache"])
    return res, runner.manifest, runner.stats


def _reproduce_parallel(papers: list[str], runner: Runner, results_dir: Path, quick: bool,
                        log: Callable[[str], None], progress: Callable[[int, int], None] | None,
                        extended: bool = False, events: Callable[..., None] | None = None) -> list[PaperResult]:
    from concurrent.futures import as_completed

    from bench.procs import process_pool

    rank = {p: i for i, p in enumerate(PAPER_COST_ORDER)}
    order = sorted(papers, key=lambda p: rank.get(p, len(rank)))
    done: dict[str, PaperResult] = {}
    with process_pool(runner.workers) as ex:
        # each job's simulation pool: at least 2 (a job whose time is simulation fills the core the other jobs
        # leave idle), else the cores shared among the concurrent jobs (no workers x workers processes)
        sim_workers = min(runner.workers, max(2, runner.workers // min(runner.workers, len(papers))))
        futures = {ex.submit(_paper_job, p, results_dir, quick, runner.cache_dir, extended, sim_workers, events): p
                   for p in order}
        for fut in as_completed(futures):
            res, manifest, stats = fut.result()
            done[futures[fut]] = res
            log(f"{res.paper}: ready (its computation took {res.seconds:.1f} s)")
            if progress:
                progress(len(done), len(papers))
            for k in ("simulated", "cached", "sim_seconds", "result_cache_hits"):
                runner.stats[k] += stats[k]
            runner.stats["stages"].update(stats["stages"])
            runner.add_manifest(manifest)
    # the manifest's key order follows the papers' order, not the completion order
    runner.manifest["runs"] = dict(sorted(runner.manifest["runs"].items()))
    runner.manifest["scenarios"] = dict(sorted(runner.manifest["scenarios"].items()))
    return [done[p] for p in papers]
