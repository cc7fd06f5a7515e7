"""Paper reproduction: tables reproduced beside the published numbers, claims with verdicts.

Each paper declares its experiments in ``scenarios/papers/<paper>.toml``::

    paper = "wang2015"
    citation = "T. Wang et al., Sensors 15(5), 2015"
    module = "methods.wang2015_repro"          # where the compute functions live

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
    source = "Wang 2015 Sec. 3.4"
    kind = "trend"                              # ordering | ratio | trend | within | flag
    series = ["table3.chi_lambda0", "table3.chi_lambda1"]
    direction = "decreasing"
    tolerance = 0.01

An ``ordering`` claim (``metrics = [a, b, ...]``, holds when a < b < ...) may name a ``margin`` metric (e.g. two
standard errors of the difference): it then holds only when a + margin < b at each step, so that an ordering
inside the measurement's sampling error is not reported as holding.

Metric ids are ``<table>.<metric>`` inside a paper and ``<paper>.<table>.<metric>`` globally.
A compute function receives a :class:`Context` (cached/parallel simulation, seeds, quick mode,
figure and note registration) and returns its metrics.  Verdicts are computed from the numbers;
nothing is written by hand.  Every file is written atomically.
"""
from __future__ import annotations

import hashlib
import importlib
import json
import pickle
import math
import os
import platform as _platform
import subprocess
import time
import tomllib
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Mapping

from bench.report.io import atomic_path, atomic_write_json, atomic_write_text, dumps_json
from bench.reproduce.runner import REPO, Runner
from bench.spec import SCENARIO_DIR, SpecError

PAPERS_DIR = SCENARIO_DIR / "papers"
RESULTS = REPO / "results"
CLAIM_KINDS = ("ordering", "ratio", "trend", "within", "flag")


@dataclass
class Context:
    """What a compute function gets: simulation through the cache, seeds, output folder."""

    paper: str
    runner: Runner
    out_dir: Path
    quick: bool = False
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
        """Attach an explanation to a table or claim id (shown beside it in the report)."""
        self.notes[key] = text


# ----------------------------------------------------------------------------------- declarations
def load_paper(name_or_path: str | Path) -> dict[str, Any]:
    path = Path(name_or_path)
    if not path.suffix:
        path = PAPERS_DIR / f"{name_or_path}.toml"
    if not path.is_file():
        raise SpecError(path, "<file>", str(path), "no such paper declaration")
    with open(path, "rb") as fh:
        try:
            decl = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise SpecError(path, "<file>", str(path), f"malformed TOML: {exc}") from None
    for key in ("paper", "module", "tables"):
        if key not in decl:
            raise SpecError(path, key, None, "required field is missing")
    table_ids = [t.get("id") for t in decl["tables"]]
    for i, tid in enumerate(table_ids):
        if table_ids.index(tid) != i:
            raise SpecError(path, f"tables[{i}].id", tid, "table ids must be unique")
    claim_ids: set[str] = set()
    for i, c in enumerate(decl.get("claims", [])):
        if c.get("kind") not in CLAIM_KINDS:
            raise SpecError(path, f"claims[{i}].kind", c.get("kind"), f"one of {CLAIM_KINDS}")
        if c.get("id") in claim_ids:
            raise SpecError(path, f"claims[{i}].id", c.get("id"), "claim ids must be unique")
        claim_ids.add(c.get("id"))
        for mid in claim_metric_ids(c):
            if mid.split(".")[0] not in table_ids:
                raise SpecError(path, f"claims[{i}]", mid, f"a metric '<table>.<metric>' of a declared table {table_ids}")
    decl["_path"] = str(path)
    return decl


def claim_metric_ids(claim: Mapping[str, Any]) -> list[str]:
    """The metric ids a claim reads, by its kind."""
    kind = claim.get("kind")
    if kind == "ordering":
        return list(claim["metrics"]) + ([claim["margin"]] if "margin" in claim else [])
    if kind == "ratio":
        return [claim["num"], claim["den"]]
    if kind == "trend":
        return list(claim["series"])
    return [claim["metric"]]


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


def list_papers() -> list[str]:
    return sorted(p.stem for p in PAPERS_DIR.glob("*.toml"))


# ----------------------------------------------------------------------------------- verdicts
def _fmt(x: Any) -> str:
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        if x is None or (isinstance(x, float) and math.isnan(x)):
            return "n/a"
        ax = abs(x)
        if ax != 0 and (ax < 1e-3 or ax >= 1e5):
            return f"{x:.3e}"
        return f"{x:.4g}"
    return "n/a" if x is None else str(x)


def row_verdict(reproduced: float | None, row: Mapping[str, Any]) -> str:
    pub = row.get("published")
    if reproduced is None or (isinstance(reproduced, float) and math.isnan(reproduced)):
        return "not reproduced"
    if pub is None:
        return "—"
    if "tolerance_abs" in row:
        ok = abs(reproduced - pub) <= row["tolerance_abs"]
        return f"{'matches' if ok else 'differs'} (|Δ| {'≤' if ok else '>'} {row['tolerance_abs']})"
    if "tolerance_rel" in row:
        rel = abs(reproduced - pub) / max(abs(pub), 1e-12)
        ok = rel <= row["tolerance_rel"]
        return f"{'matches' if ok else 'differs'} ({rel:.1%} {'≤' if ok else '>'} {row['tolerance_rel']:.1%})"
    return "—"


def evaluate_claim(claim: Mapping[str, Any], metrics: Mapping[str, float]) -> tuple[bool | None, str]:
    """(holds, measured-numbers text). ``None`` when a metric is missing."""
    def get(mid: str) -> float | None:
        v = metrics.get(mid)
        return None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)

    kind = claim["kind"]
    if kind == "ordering":  # a < b < ...; with "margin" (a metric, e.g. 2 standard errors): a + margin < b ...
        ids = claim["metrics"]
        vals = [get(m) for m in ids]
        margin = get(claim["margin"]) if "margin" in claim else 0.0
        if any(v is None for v in vals) or margin is None:
            return None, "missing metric"
        ok = all(a + margin < b for a, b in zip(vals, vals[1:]))
        text = " < ".join(f"{m.split('.')[-1]} = {_fmt(v)}" for m, v in zip(ids, vals))
        if "margin" in claim:
            text += f" by more than {claim['margin'].split('.')[-1]} = {_fmt(margin)}"
        return ok, text
    if kind == "ratio":
        n, d = get(claim["num"]), get(claim["den"])
        if n is None or d is None or d == 0:
            return None, "missing metric"
        r = n / d
        op, val = claim.get("op", "<="), float(claim["value"])
        ok = {"<": r < val, "<=": r <= val, ">": r > val, ">=": r >= val}[op]
        return ok, f"{claim['num'].split('.')[-1]} / {claim['den'].split('.')[-1]} = {_fmt(n)} / {_fmt(d)} = {_fmt(r)} (claim: {op} {val})"
    if kind == "trend":
        vals = [get(m) for m in claim["series"]]
        if any(v is None for v in vals):
            return None, "missing metric"
        tol = float(claim.get("tolerance", 0.0))
        sign = -1 if claim.get("direction", "decreasing") == "decreasing" else 1
        ok = all(sign * (b - a) >= -tol for a, b in zip(vals, vals[1:])) and sign * (vals[-1] - vals[0]) > 0
        return ok, "series: " + ", ".join(_fmt(v) for v in vals) + f" ({claim.get('direction', 'decreasing')}, tolerance {tol})"
    if kind == "within":
        v = get(claim["metric"])
        if v is None:
            return None, "missing metric"
        target = float(claim["value"])
        if "tolerance_abs" in claim:
            ok = abs(v - target) <= claim["tolerance_abs"]
            return ok, f"{_fmt(v)} vs {target} ± {claim['tolerance_abs']}"
        tol = float(claim.get("tolerance_rel", 0.1))
        ok = abs(v - target) <= tol * abs(target)
        return ok, f"{_fmt(v)} vs {target} ± {tol:.0%}"
    if kind == "flag":
        v = get(claim["metric"])
        if v is None:
            return None, "missing metric"
        return bool(v) == bool(claim.get("expect", True)), f"{claim['metric'].split('.')[-1]} = {_fmt(bool(v))}"
    raise ValueError(f"unknown claim kind {kind}")


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
    figure_bytes: dict[str, bytes] = field(default_factory=dict)


def code_key(*extra: str) -> str:
    """Hash of everything a result depends on: the source of bench/ and methods/, the scenario,
    platform, terrain and paper files, the installed package versions, plus ``extra``."""
    h = hashlib.sha256()
    for folder, pattern in (("bench", "**/*.py"), ("methods", "**/*.py"), ("scenarios", "**/*.toml")):
        for p in sorted((REPO / folder).glob(pattern)):
            h.update(str(p.relative_to(REPO)).encode())
            h.update(p.read_bytes())
    h.update(json.dumps(package_versions(), sort_keys=True).encode())
    h.update(json.dumps(sorted((k, v) for k, v in os.environ.items() if k.startswith("SKIDBENCH_")
                               and k != "SKIDBENCH_CACHE")).encode())
    for e in extra:
        h.update(e.encode())
    return h.hexdigest()[:24]


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
                    log: Callable[[str], None] = lambda s: None, use_cache: bool = True) -> PaperResult:
    """Compute one paper's tables and claims and write ``results/<paper>/``.  When nothing the
    result depends on changed (:func:`code_key`), the previous result is re-written from the
    result cache instead of being recomputed."""
    decl = load_paper(name)
    paper = decl["paper"]
    out_dir = results_dir / paper
    key = code_key(paper, str(quick), decl["_path"])
    if use_cache and (hit := _cached_result(_result_cache(runner), paper, key)) is not None:
        log(f"{paper}: unchanged since the last run, results taken from the cache")
        write_paper(hit, out_dir)
        _copy_figures(hit, out_dir)
        return hit
    ctx = Context(paper=paper, runner=runner, out_dir=out_dir, quick=quick)
    module = importlib.import_module(decl["module"])
    runner.served.clear()
    metrics: dict[str, float] = {}
    t0 = time.perf_counter()
    tables = []
    for tab in decl["tables"]:
        log(f"{paper}: {tab['id']} — {tab.get('title', '')}")
        fn = getattr(module, tab["compute"])
        got = fn(ctx) or {}
        for k, v in got.items():
            metrics[f"{tab['id']}.{k}"] = float(v) if isinstance(v, (int, float, bool)) else v
        rows = []
        for row in tab.get("rows", []):
            rep = got.get(row["metric"])
            rows.append({**row, "reproduced": rep, "verdict": row_verdict(rep, row)})
        tables.append({**tab, "rows_out": rows, "all_metrics": got})
    claims = []
    for c in decl.get("claims", []):
        holds, text = evaluate_claim(c, metrics)
        claims.append({**c, "holds": holds, "measured": text, "why": ctx.notes.get(c["id"], c.get("explain_if_fails", "") if holds is False else "")})
    served = sorted(set(runner.served))
    ctx.info.setdefault("seeds", sorted({seed for _, seed in served}))
    ctx.info["runs"] = [f"{sid} seed {seed}" for sid, seed in served]
    res = PaperResult(paper, decl, metrics, tables, claims, ctx.figures, ctx.notes, time.perf_counter() - t0, ctx.info)
    write_paper(res, out_dir)
    res.figure_bytes = {rel: (out_dir.parent / rel).read_bytes() for rel, _ in ctx.figures
                        if (out_dir.parent / rel).is_file()}
    if use_cache:
        _store_result(_result_cache(runner), paper, key, res)
    return res


def _copy_figures(res: PaperResult, out_dir: Path) -> None:
    """Figures of a cached result, written back when missing (e.g. into another results folder)."""
    for rel, data in getattr(res, "figure_bytes", {}).items():
        target = out_dir.parent / rel
        if not target.is_file() or target.read_bytes() != data:
            with atomic_path(target) as tmp:
                tmp.write_bytes(data)


def _cell(x: Any) -> str:
    """Markdown table cell: pipes escaped, newlines folded."""
    return str(x).replace("|", "\\|").replace("\n", " ")


def _table_md(tab: Mapping[str, Any], notes: Mapping[str, str]) -> str:
    lines = [f"### {tab.get('title', tab['id'])}", "", f"Source: {tab.get('source', '')}", ""]
    if tab["rows_out"]:
        lines += ["| quantity | reproduced | published | verdict |", "|---|---|---|---|"]
        for r in tab["rows_out"]:
            lines.append(f"| {_cell(r.get('label', r['metric']))} | {_fmt(r['reproduced'])} | {_fmt(r.get('published'))} | {r['verdict']} |")
    else:
        lines += ["| metric | reproduced |", "|---|---|"]
        for k, v in tab["all_metrics"].items():
            lines.append(f"| {k} | {_fmt(v)} |")
    for text in (tab.get("note"), notes.get(tab["id"])):
        if text:
            lines += ["", f"> Note: {text.strip()}"]
    return "\n".join(lines) + "\n"


def _table_csv(tab: Mapping[str, Any]) -> str:
    import csv
    import io

    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["metric", "label", "reproduced", "published", "verdict"])
    if tab["rows_out"]:
        for r in tab["rows_out"]:
            w.writerow([r["metric"], r.get("label", ""), r["reproduced"], r.get("published", ""), r["verdict"]])
    else:
        for k, v in tab["all_metrics"].items():
            w.writerow([k, "", v, "", ""])
    return buf.getvalue()


def _claims_md(res: PaperResult) -> str:
    lines = ["| claim | source | verdict | measured | why |", "|---|---|---|---|---|"]
    for c in res.claims:
        v = {True: "**holds**", False: "**does not hold**", None: "not evaluated"}[c["holds"]]
        lines.append(f"| {_cell(c['text'])} | {_cell(c.get('source', ''))} | {v} | {_cell(c['measured'])} | {_cell(c.get('why', ''))} |")
    return "\n".join(lines) + "\n"


def paper_markdown(res: PaperResult, link_prefix: str = "") -> str:
    d = res.decl
    out = [f"## {d.get('title', res.paper)}", "", f"*{d.get('citation', '')}*", ""]
    if d.get("note"):
        out += [f"> {d['note'].strip()}", ""]
    for tab in res.tables:
        out.append(_table_md(tab, res.notes))
    out += ["### Claims", "", _claims_md(res)]
    if res.figures:
        out += ["### Figures", ""]
        for path, caption in res.figures:
            out.append(f"- [{caption}]({link_prefix}{path})")
        out.append("")
    return "\n".join(out)


def write_paper(res: PaperResult, out_dir: Path) -> None:
    for tab in res.tables:
        atomic_write_text(out_dir / f"{tab['id']}.md", _table_md(tab, res.notes))
        atomic_write_text(out_dir / f"{tab['id']}.csv", _table_csv(tab))
    atomic_write_text(out_dir / "claims.md", _claims_md(res))
    atomic_write_text(out_dir / "README.md", paper_markdown(res, link_prefix="../"))


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!results"], cwd=REPO,
                               capture_output=True, text=True).stdout.strip()
        return out.stdout.strip() + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"  # (results/ itself is excluded from the dirty check: reproduce writes it)


def package_versions() -> dict[str, str]:
    from importlib import metadata

    out = {"python": _platform.python_version()}
    for pkg in ("numpy", "scipy", "pandas", "pyarrow", "pybullet", "matplotlib", "pygad", "filterpy"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    return out


def metrics_document(results: list[PaperResult], quick: bool, tolerances: Mapping[str, Any] | None = None) -> dict[str, Any]:
    metrics: dict[str, Any] = {}
    for res in results:
        rows = {f"{t['id']}.{r['metric']}": r for t in res.tables for r in t["rows_out"]}
        default_tol = res.decl.get("regression_tolerance", {"rel": 0.05, "abs": 1e-6})
        for mid, v in res.metrics.items():
            if not isinstance(v, (int, float)):
                continue
            row = rows.get(mid, {})
            metrics[f"{res.paper}.{mid}"] = {
                "value": v, "published": row.get("published"),
                "tolerance": {**default_tol, **res.decl.get("metric_tolerance", {}).get(mid, {})},
            }
    return {"quick": quick, "commit": git_commit(), "metrics": dict(sorted(metrics.items()))}


def write_report(results: list[PaperResult], results_dir: Path, quick: bool, runner: Runner, seconds: float) -> Path:
    lines = [
        "# skidbench reproduction report", "",
        f"Generated by `skidbench reproduce{' --quick' if quick else ''}` at commit `{git_commit()}`.",
        f"Wall time {seconds:.1f} s; runs simulated {runner.stats['simulated']}, taken from the cache {runner.stats['cached']}.",
        "Every number below is computed; verdicts compare it with the published value or claim. A claim that does",
        "not hold in simulation is reported as such, with the measured numbers and the reason where known.", "",
        "Package versions: " + ", ".join(f"{k} {v}" for k, v in package_versions().items()), "",
        "## Summary", "", "| paper | claims holding | claims not holding | time (s) |", "|---|---|---|---|",
    ]
    for res in results:
        h = sum(c["holds"] is True for c in res.claims)
        f = sum(c["holds"] is False for c in res.claims)
        lines.append(f"| [{res.paper}](#{res.paper}) | {h} | {f} | {res.seconds:.1f} |")
    lines.append("")
    for res in results:
        lines.append(f'<a id="{res.paper}"></a>')
        lines.append(paper_markdown(res))
        seeds = res.info.get("seeds")
        if seeds:
            lines.append(f"Seeds: {seeds}; {len(res.info.get('runs', []))} simulated runs "
                         f"(listed with their content hashes in runs_manifest.json).\n")
    path = results_dir / ("REPORT_quick.md" if quick else "REPORT.md")
    atomic_write_text(path, "\n".join(lines))
    return path


def reproduce(papers: list[str] | None = None, *, quick: bool = False, workers: int = 1,
              dask_scheduler: str | None = None, results_dir: Path = RESULTS,
              log: Callable[[str], None] = print, progress: Callable[[int, int], None] | None = None,
              cache_dir: Path | None = None) -> list[PaperResult]:
    """Reproduce ``papers`` (default: all) into ``results_dir``.

    Parallelism: with a Dask scheduler, or one worker, the papers run one after the other in this
    process and their simulations go to the pool / cluster.  With ``workers > 1`` locally, the papers
    themselves run as jobs in a process pool (longest first, :data:`PAPER_COST_ORDER`), each with a
    serial runner sharing the run cache: a paper's computation (filters, identification) is most of
    its time, so this keeps both cores busy where a pool of simulations alone leaves one idle.  Every
    job is deterministic, so the results are the same bytes either way (tested)."""
    papers = papers or list_papers()
    runner = Runner(workers=workers, dask_scheduler=dask_scheduler, progress=progress)
    if cache_dir is not None:
        runner.cache_dir = Path(cache_dir)
    t0 = time.perf_counter()
    if workers > 1 and dask_scheduler is None and len(papers) > 1:
        results = _reproduce_parallel(papers, runner, results_dir, quick, log, progress)
    else:
        results = [reproduce_paper(p, runner, results_dir, quick, log) for p in papers]
    seconds = time.perf_counter() - t0
    suffix = "_quick" if quick else ""
    atomic_write_json(results_dir / f"metrics{suffix}.json", metrics_document(results, quick))
    atomic_write_json(results_dir / f"runs_manifest{suffix}.json", runner.manifest)
    write_report(results, results_dir, quick, runner, seconds)
    append_history(results_dir, results, quick, seconds)
    return results


EXTRA_RESULTS = (  # (file under results/, what it is): written by the extras of `reproduce --all`
    ("league{suffix}.md", "cross-paper league table: every method on every scenario where its sensors exist"),
    ("real/husky.md", "real Clearpath Husky (DRIVE data): calibrated kinematic models scored on held-out steps"),
    ("real/husky_gap.md", "gap workflow with the testbed's husky model against the real data"),
    ("gap/worked_example.md", "gap workflow worked example on simulated data with a hidden effect"),
    ("stress.md", "filters under stress: GNSS outage, IMU spikes, encoder dropouts"),
)
EXTRAS_BEGIN, EXTRAS_END = "<!-- extras -->", "<!-- /extras -->"


def link_extras(results_dir: Path, quick: bool) -> Path | None:
    """Add (or refresh) the section of REPORT.md that links the extras' results that exist; it sits
    after the summary table, between two HTML comments, so that a rerun replaces it."""
    path = results_dir / ("REPORT_quick.md" if quick else "REPORT.md")
    if not path.is_file():
        return None
    text = path.read_text()
    if EXTRAS_BEGIN in text and EXTRAS_END in text:
        head, _, rest = text.partition(EXTRAS_BEGIN)
        text = head + rest.partition(EXTRAS_END)[2].lstrip("\n")
    suffix = "_quick" if quick else ""
    rows = [f"- [{rel.format(suffix=suffix)}]({rel.format(suffix=suffix)}): {what}"
            for rel, what in EXTRA_RESULTS if (results_dir / rel.format(suffix=suffix)).is_file()]
    if rows:
        section = "\n".join([EXTRAS_BEGIN, "## Beyond the papers", "", *rows, EXTRAS_END, "", ""])
        at = text.find('<a id="')
        text = text[:at] + section + text[at:] if at >= 0 else text + "\n" + section
    atomic_write_text(path, text)
    return path


# Papers by their measured reproduction time (longest first), the order in which parallel jobs are
# submitted so that the longest one does not start last; a paper not listed goes last.
PAPER_COST_ORDER = ("mandow2007", "liu2020", "yi2009", "wang2015", "yu2010")


def _paper_job(name: str, results_dir: Path, quick: bool, cache_dir: Path) -> tuple[PaperResult, dict, dict]:
    """Worker: one paper with a serial runner on the shared run cache (runs are written atomically,
    so two jobs asking for the same run at once both write the same bytes)."""
    runner = Runner(cache_dir=cache_dir, workers=1)
    res = reproduce_paper(name, runner, results_dir, quick, log=lambda s: print(s, flush=True))
    return res, runner.manifest, runner.stats


def _reproduce_parallel(papers: list[str], runner: Runner, results_dir: Path, quick: bool,
                        log: Callable[[str], None], progress: Callable[[int, int], None] | None
                        ) -> list[PaperResult]:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    rank = {p: i for i, p in enumerate(PAPER_COST_ORDER)}
    order = sorted(papers, key=lambda p: rank.get(p, len(rank)))
    done: dict[str, PaperResult] = {}
    with ProcessPoolExecutor(max_workers=runner.workers) as ex:
        futures = {ex.submit(_paper_job, p, results_dir, quick, runner.cache_dir): p for p in order}
        for fut in as_completed(futures):
            res, manifest, stats = fut.result()
            done[futures[fut]] = res
            log(f"{res.paper}: ready (its computation took {res.seconds:.1f} s)")
            if progress:
                progress(len(done), len(papers))
            for k in ("simulated", "cached"):
                runner.stats[k] += stats[k]
            runner.manifest["scenarios"].update(manifest["scenarios"])
            runner.manifest["runs"].update(manifest["runs"])
    # the manifest's key order follows the papers' order, not the completion order
    runner.manifest["runs"] = dict(sorted(runner.manifest["runs"].items()))
    runner.manifest["scenarios"] = dict(sorted(runner.manifest["scenarios"].items()))
    return [done[p] for p in papers]


def append_history(results_dir: Path, results: list[PaperResult], quick: bool, seconds: float) -> None:
    """One JSON line per reproduce: commit, date, metrics, wall time (read by the dashboard)."""
    entry = {
        "commit": git_commit(), "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "quick": quick, "seconds": round(seconds, 3),
        "metrics": {f"{r.paper}.{k}": v for r in results for k, v in r.metrics.items() if isinstance(v, (int, float))},
    }
    bench_json = REPO / ".benchmarks" / "latest.json"
    if bench_json.is_file():
        try:
            b = json.loads(bench_json.read_text())
            entry["bench"] = {x["name"]: x["stats"]["mean"] for x in b.get("benchmarks", [])}
        except (ValueError, KeyError):
            pass
    path = results_dir / "history.jsonl"
    old = path.read_text() if path.is_file() else ""
    atomic_write_text(path, old + dumps_json(entry, sort_keys=True) + "\n")
