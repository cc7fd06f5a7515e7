"""One paper's reproduction: its declaration (``scenarios/papers/<paper>.toml``, loaded and checked), the
:class:`Context` a compute function gets, helpers for compute functions (published values, mean and
confidence interval over seeds), and :func:`reproduce_paper`, which computes the tables and the claims'
verdicts and writes ``results/<paper>/``, through the result cache keyed by
:func:`bench.reproduce.provenance.code_key`.
"""
from __future__ import annotations

import importlib
import math
import pickle
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from bench.report.io import atomic_path
from bench.reproduce.claims import (check_claim, check_published_on, claim_tables, evaluate_claim, fails_if, favours,
                                    fill_numbers, quoted_metrics, refuted, row_verdict, stale_relations,
                                    verdict)
from bench.reproduce.provenance import code_key
from bench.reproduce.report import write_paper
from bench.reproduce.runner import Runner
from bench.reproduce.sources import calibration_targets
from bench.paths import default_results
from bench.schema import read_toml
from bench.spec import SCENARIO_DIR, SpecError

__all__ = ["PAPERS_DIR", "RESULTS", "Context", "load_paper", "claim_result", "published_values", "mean_ci",
           "list_papers", "PaperResult", "reproduce_paper"]

PAPERS_DIR = SCENARIO_DIR / "papers"
RESULTS = default_results()  # the checkout's results/, installed: ./results (bench.paths)


@dataclass
class Context:
    """What a compute function gets: simulation through the cache, seeds, output folder."""

    paper: str
    runner: Runner
    out_dir: Path
    quick: bool = False
    extended: bool = False  # `reproduce --extended`: also the studies beyond the papers' tables and headline claims
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    figures: list[tuple[str, str]] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)  # persisted with the result (keep it small)
    scratch: dict[str, Any] = field(default_factory=dict)  # shared between compute functions, never persisted

    def simulate(self, scn: Any, seed: int = 0):
        return self.runner.simulate(scn, seed)

    def simulate_many(self, requests):
        return self.runner.simulate_many(requests)

    def figure(self, path: Path, caption: str) -> None:
        self.figures.append((str(Path(path).relative_to(self.out_dir.parent)), caption))

    def note(self, key: str, text: str) -> None:
        """Attach an explanation to a table or claim id: a table's is printed under it; a claim's is shown whole in
        ``claims_details.md`` and shortened (with a link) in the claims tables."""
        self.notes[key] = text


# ----------------------------------------------------------------------------------- declarations
def load_paper(name_or_path: str | Path) -> dict[str, Any]:
    """A paper's declaration, checked (:func:`bench.reproduce.claims.check_claim`): an error is a :class:`SpecError`
    naming the file, the field (``claims.<id>.<field>``) and the value; the new schema's requirements on a claim not
    yet converted (no ``headline`` field) are collected in ``decl["_warnings"]``."""
    path = Path(name_or_path)
    if not path.suffix:
        path = PAPERS_DIR / f"{name_or_path}.toml"
    decl = read_toml(path, "paper declaration")
    for key in ("paper", "module", "tables"):
        if key not in decl:
            raise SpecError(path, key, None, "required field is missing")
    table_ids = [t.get("id") for t in decl["tables"]]
    for i, tid in enumerate(table_ids):
        if table_ids.index(tid) != i:
            raise SpecError(path, f"tables[{i}].id", tid, "table ids must be unique")
        check_published_on(path, decl["tables"][i])
    claim_ids: set[str] = set()
    warnings: list[str] = []
    for i, c in enumerate(decl.get("claims", [])):
        warnings += check_claim(path, i, c, table_ids)
        if c["id"] in claim_ids:
            raise SpecError(path, f"claims.{c['id']}.id", c["id"], "claim ids must be unique")
        claim_ids.add(c["id"])
    extended = {t["id"] for t in decl["tables"] if t.get("extended", False)}
    for i, t in enumerate(decl["tables"]):
        if not isinstance(t.get("extended", False), bool):
            raise SpecError(path, f"tables[{i}].extended", t["extended"], "true or false")
    for c in decl.get("claims", []):  # the default run reports every claim of the paper: none may rest on a study
        uses = sorted(claim_tables(c) & extended)  # that only --extended runs
        if uses and (c.get("headline") or c.get("scope", "paper") == "paper"):
            raise SpecError(path, f"claims.{c['id']}.scope", c.get("scope", "paper"),
                            f"a claim of the paper rests on the extended table(s) {uses}: only claims with scope "
                            "'beyond' may")
    decl["_warnings"] = warnings
    decl["_path"] = str(path)
    return decl


#: what a quick run's cause taken from the full run says of itself (``cause["of"]``, shown before its text)
FULL_RUN = "full run's"
FULL_RUN_QUOTED = "full run's; quoted numbers: this run's"


def claim_result(paper: str, c: dict[str, Any], metrics: dict[str, float], notes: dict[str, str],
                 quick: bool = False) -> dict[str, Any]:
    """A declared claim with its evaluation: holds (True / False / None), the measured numbers, the verdict (a claim a
    testbed parameter was chosen for is a calibration target: :func:`bench.reproduce.sources.calibration_targets`),
    the result that would fail it, whether a failing claim with a margin is refuted beyond the seeds' interval
    (:func:`bench.reproduce.claims.refuted`) and whether its means favour it
    (:func:`bench.reproduce.claims.favours`), its cause (``cause_quick`` in a quick run when declared) and the note
    of the compute functions (``why``)."""
    holds, text = evaluate_claim(c, metrics)
    chosen = calibration_targets().get(f"{paper}.{c['id']}", [])
    out = {k: v for k, v in c.items() if k not in ("cause", "cause_quick")}
    cause = c.get("cause_quick", c.get("cause")) if quick else c.get("cause")
    if cause:  # this run's numbers written into the text; a quick run showing the full run's reason says so
        cause = {**cause, "text": fill_numbers(cause["text"], metrics)}
        if holds is False and (stale := stale_relations(cause.get("relations", []), metrics)):
            cause["stale"] = stale  # the words state what this run's numbers no longer meet
        if quick and "cause_quick" not in c:
            cause["of"] = FULL_RUN_QUOTED if quoted_metrics(c["cause"]["text"]) else FULL_RUN
    return {**out, **({"cause": cause} if cause else {}), "scope": c.get("scope", "paper"),
            "headline": bool(c.get("headline", False)), "holds": holds, "measured": text,
            "verdict": verdict(holds, chosen), "refuted": refuted(c, metrics), "favours": favours(c, metrics),
            "fails_if": c.get("fails_if") or fails_if(c), "fails_if_engine": fails_if(c),
            "calibration": [{"parameter": s.name, "file": s.file, "ref": s.ref} for s in chosen],
            "why": notes.get(c["id"], c.get("explain_if_fails", "") if holds is False else "")}


def published_values(paper: str, table_id: str) -> dict[str, float]:
    """Published numbers of a declared table (metric -> value), for compute functions that need them."""
    for tab in load_paper(paper)["tables"]:
        if tab["id"] == table_id:
            return {r["metric"]: float(r["published"]) for r in tab.get("rows", []) if "published" in r}
    raise KeyError(f"{paper}.toml declares no table '{table_id}'")


def mean_ci(values: Any, confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean and two-sided Student-t confidence interval of the mean (NaN bounds for < 2 values)."""
    import numpy as np
    from scipy import stats

    x = np.asarray(values, dtype=float)
    m = float(np.mean(x))
    if x.size < 2:
        return m, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + confidence / 2, x.size - 1) * np.std(x, ddof=1) / math.sqrt(x.size))
    return m, m - half, m + half


def half_width(values: Any, confidence: float = 0.95) -> float:
    """Half-width of :func:`mean_ci`'s interval, mean - lower bound (NaN for < 2 values): the margin of an ordering
    over seeds when ``values`` are the per-seed paired differences."""
    m, lo, _ = mean_ci(values, confidence)
    return m - lo


def list_papers() -> list[str]:
    return sorted(p.stem for p in PAPERS_DIR.glob("*.toml"))


# ----------------------------------------------------------------------------------- running
@dataclass
class PaperResult:
    paper: str
    decl: dict[str, Any]
    metrics: dict[str, float]
    tables: list[dict[str, Any]]
    claims: list[dict[str, Any]]
    figures: list[tuple[str, str]]
    notes: dict[str, str]
    seconds: float
    info: dict[str, Any]
    file_bytes: dict[str, bytes] = field(default_factory=dict)  # results-relative path -> bytes this computation wrote
    manifest: dict[str, Any] = field(default_factory=dict)  # the runs it was computed from (Runner.manifest_of)


def _result_cache(runner: Runner) -> Path:
    return Path(runner.cache_dir).parent / "result-cache"


def _cached_result(folder: Path, name: str, key: str) -> PaperResult | None:
    path = folder / f"{name}-{key}.pkl"
    if not path.is_file():
        return None
    try:
        with open(path, "rb") as fh:
            return pickle.load(fh)
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError):
        return None


def _store_result(folder: Path, name: str, key: str, res: PaperResult) -> None:
    with atomic_path(folder / f"{name}-{key}.pkl") as tmp:
        with open(tmp, "wb") as fh:
            pickle.dump(res, fh)


def reproduce_paper(name: str, runner: Runner, results_dir: Path = RESULTS, quick: bool = False,
                    log: Callable[[str], None] = lambda s: None, use_cache: bool = True,
                    extended: bool = False, step: Callable[[int, int, str], None] | None = None) -> PaperResult:
    """Compute one paper's tables and claims and write ``results/<paper>/``.  When nothing the
    result depends on changed (:func:`code_key`), the previous result is re-written from the
    result cache instead of being recomputed.  ``extended``: the compute functions also run the studies
    beyond the paper (:attr:`Context.extended`).  ``step(done, total, table id)`` is called as each table begins and
    once all are done (the command line's progress bar)."""
    if quick and extended:
        raise ValueError("reproduce: --quick and --extended exclude each other")
    decl = load_paper(name)
    paper = decl["paper"]
    out_dir = results_dir / paper
    where = Path(decl["_path"]).resolve()  # the paper's file by its place in the scenario folder, not on this disk
    where_key = where.relative_to(SCENARIO_DIR).as_posix() if where.is_relative_to(SCENARIO_DIR) else str(where)
    key = code_key(paper, str(quick), where_key, "extended" if extended else "")
    if use_cache and (hit := _cached_result(_result_cache(runner), paper, key)) is not None:
        log(f"{paper}: unchanged since the last run, results taken from the cache")
        runner.stats["result_cache_hits"] = runner.stats.get("result_cache_hits", 0) + 1
        runner.add_manifest(hit.manifest)  # runs_manifest.json lists the runs the numbers come from, cached or not
        _copy_files(hit, out_dir)
        write_paper(hit, out_dir)  # after: its files may read what changed since (the sensitivity study's marks)
        return hit
    ctx = Context(paper=paper, runner=runner, out_dir=out_dir, quick=quick, extended=extended)
    before = _file_stamps(out_dir)
    module = importlib.import_module(decl["module"])
    runner.served_keys.clear()
    metrics: dict[str, float] = {}
    t0 = time.perf_counter()
    tables = []
    # the full run skips the studies beyond the paper (reproduce --extended runs them in full); the quick run (CI)
    # keeps them, in their light form (Context.quick), so that their code stays under the regression check
    skipped = [t["id"] for t in decl["tables"] if t.get("extended") and not (extended or quick)]
    if skipped:
        ctx.info["extended_tables"] = skipped
    ran = [t for t in decl["tables"] if t["id"] not in skipped]
    for tab in decl["tables"]:
        if step is not None and tab["id"] not in skipped:
            step(ran.index(tab), len(ran), tab["id"])
        if tab["id"] in skipped:  # a study beyond the paper's tables and headline claims: reproduce --extended
            log(f"{paper}: {tab['id']} — skipped (reproduce --extended)")
            continue
        log(f"{paper}: {tab['id']} — {tab.get('title', '')}")
        fn = getattr(module, tab["compute"])
        got = fn(ctx) or {}
        for k, v in got.items():
            metrics[f"{tab['id']}.{k}"] = float(v) if isinstance(v, (int, float, bool)) else v
        rows = []
        for row in tab.get("rows", []):
            rep = got.get(row["metric"])
            rows.append({**row, "reproduced": rep, "verdict": row_verdict(rep, row, tab.get("published_on"))})
        tables.append({**tab, "rows_out": rows, "all_metrics": got})
    if step is not None:
        step(len(ran), len(ran), "claims")
    claims = [claim_result(paper, c, metrics, ctx.notes, quick) for c in decl.get("claims", [])
              if not claim_tables(c) & set(skipped)]
    manifest = runner.manifest_of(runner.served_keys)
    served = sorted({(r["scenario"], r["seed"]) for r in manifest["runs"].values()})
    ctx.info.setdefault("seeds", sorted({seed for _, seed in served}))
    ctx.info["runs"] = [f"{sid} seed {seed}" for sid, seed in served]
    res = PaperResult(paper, decl, metrics, tables, claims, ctx.figures, ctx.notes, time.perf_counter() - t0, ctx.info,
                      manifest=manifest)
    write_paper(res, out_dir)
    # every file this computation wrote (tables, notes, figures, the compute functions' own files): a cache hit
    # writes them back, also into another results folder
    after = _file_stamps(out_dir)
    res.file_bytes = {str(p.relative_to(out_dir.parent)): p.read_bytes() for p, stamp in after.items()
                      if before.get(p) != stamp}
    if use_cache:
        _store_result(_result_cache(runner), paper, key, res)
    return res


def _file_stamps(folder: Path) -> dict[Path, tuple[int, int]]:
    """(mtime_ns, size) of every file under ``folder`` (empty when it does not exist)."""
    stats = ((p, p.stat()) for p in folder.rglob("*") if p.is_file())  # rglob of a missing folder yields nothing
    return {p: (st.st_mtime_ns, st.st_size) for p, st in stats}


def _copy_files(res: PaperResult, out_dir: Path) -> None:
    """The files a cached result's computation wrote, written back when missing or different (e.g. into another
    results folder)."""
    for rel, data in res.file_bytes.items():
        target = out_dir.parent / rel
        if not target.is_file() or target.read_bytes() != data:
            with atomic_path(target) as tmp:
                tmp.write_bytes(data)
