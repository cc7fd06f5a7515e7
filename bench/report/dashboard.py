"""Regression dashboard: static, self-contained HTML pages from ``results/history.jsonl``.

    render_dashboard(results_dir, out_dir) -> DashboardPages

writes into ``out_dir``:

* ``index.html``: the papers, the changes beyond tolerance grouped by commit pair across papers (one row
  per pair: metrics moved per paper), the run history with commit ids and dates, links;
* ``<paper>.html``: the paper's tables (metrics, charts, pages), its changes beyond tolerance grouped by
  commit pair (one row per pair: metrics moved, per table counts, a collapsible list of the metrics with
  links to their charts; :mod:`bench.report.changes`) and its runs;
* ``<paper>.<table>.html`` (``<paper>.<table>.<k>.html`` for the k-th part of a large table): one chart
  per metric over the reproduce runs (full and quick runs as two series, the published value as a dashed
  line, the regression band of the baseline ``metrics.json`` as a shaded band, steps beyond tolerance
  ringed).  A table of more than :data:`FULL_TABLE` metrics charts only those that moved beyond tolerance
  at least once (a metric that merely vanished from later runs has not moved); the others are compact rows
  with a sparkline whose tooltip lists every run's value.  A table's charts and rows are split into parts of
  at most ``page_budget`` bytes, so that every page stays under 2 MB;
* ``metrics.html``: every metric id with a link to its chart, and a filter box (:mod:`bench.report.metric_index`);
* ``speed.html``: ``make bench`` over commits from ``results/bench_history.jsonl`` and the reproduce wall
  time and stage seconds, cold and warm (:mod:`bench.report.speed_page`).

Why hand-written pages and not asv's site (DESIGN.md names asv): asv's published site loads its data
with ``fetch()`` from JSON files, which browsers refuse on ``file://``, so it needs an HTTP server to
be looked at or tested; and its history is per commit of asv runs, while ours already exists in
``history.jsonl`` (written by every ``skidbench reproduce``).  These pages are one file each, with
inline SVG (:mod:`bench.report.chart`; no JavaScript needed to see them, no network, no CDN), so they open
from disk, from a CI artefact or from the committed ``results/`` folder.  asv remains available:
``skidbench dashboard --asv`` (quick ``track_*`` benchmarks) or ``asv run`` (:mod:`bench.cli.dashboard`).

Every page carries the in-browser check of :mod:`bench.report.html_page` (charts laid out, no overlapping
axis labels), read by the headless-Chromium tests.  Steps between consecutive runs of the same mode use
:func:`bench.cli.reproduce.compare_metrics`, the same rule as ``skidbench compare``.  Output is a pure
function of the input files (no clock, sorted keys): rendering twice gives the same bytes.  Every file is
written atomically.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from bench.report.bench_history import load_bench_history
from bench.report.changes import (DEFAULT_TOLERANCE, Step, find_steps, group_steps, pairs_table, summary_table,
                                  table_key)
from bench.report.chart import Series, axis_label, esc, fmt, runs_chart, series_by_mode, sparkline, svg_chart
from bench.report.html_page import html_page, legend, nav_bar
from bench.report.io import atomic_write_text, json_number, jsonl_objects
from bench.report.metric_index import MetricLocation, metric_index_page
from bench.report.speed_page import speed_page
from bench.spec import SpecError

__all__ = ["Entry", "Series", "Step", "DashboardPages", "load_history", "load_baselines", "find_steps",
           "svg_chart", "render_dashboard", "DEFAULT_TOLERANCE", "FULL_TABLE", "PAGE_BUDGET"]

FULL_TABLE = 40            # a table of at most this many metrics charts every metric
PAGE_BUDGET = 1_300_000    # bytes of charts and rows per table page (with its frame a page stays < 2 MB)


# ------------------------------------------------------------------------------------------ inputs
@dataclass(frozen=True)
class Entry:
    """One line of history.jsonl: one ``skidbench reproduce``."""

    index: int
    commit: str
    date: str
    quick: bool
    seconds: float | None
    metrics: Mapping[str, float]
    bench: Mapping[str, float]
    stages: Mapping[str, float] = field(default_factory=dict)  # seconds per stage (bench.reproduce.timing)
    cold: bool | None = None  # the run computed everything (empty run cache, nothing from the result cache); None: not recorded

    @property
    def short(self) -> str:
        """Short commit id (7 hex digits, ``+`` when the tree was dirty)."""
        return axis_label(self.commit, self.date)[0]

    @property
    def day(self) -> str:
        return self.date[:10]

    @property
    def mode(self) -> str:
        return "quick" if self.quick else "full"


def _num(x: Any) -> float | None:
    """A JSON value as a float: numbers, bools and the strings "inf" / "-inf" (bench.report.io);
    None for null and anything else."""
    if isinstance(x, bool):
        return float(x)
    if isinstance(x, (int, float)):
        return float(x)
    if isinstance(x, str):
        return json_number(x)
    return None


def load_history(path: str | Path) -> list[Entry]:
    """Parse history.jsonl (one JSON object per line, blank lines ignored), in file order.

    A malformed line raises :class:`bench.spec.SpecError` naming the file, the line and the field."""
    path = Path(path)
    if not path.is_file():
        raise SpecError(path, "<file>", str(path), "no history file: run `skidbench reproduce` first")
    entries: list[Entry] = []
    for lineno, obj in jsonl_objects(path, ("commit", "metrics")):
        if not isinstance(obj["metrics"], dict):
            raise SpecError(path, f"line {lineno}: metrics", obj["metrics"], "an object {metric id: number}")
        if obj.get("extended"):
            continue  # reproduce --extended: other tables and league than the full runs' series (results/extended/)
        # null is a metric without a value (NaN, as the old writer wrote it): kept, so "became NaN" is seen
        metrics = {str(k): v for k, v in ((k, math.nan if v is None else _num(v)) for k, v in obj["metrics"].items())
                   if v is not None}
        bench = {str(k): v for k, v in ((k, _num(v)) for k, v in (obj.get("bench") or {}).items()) if v is not None}
        stages = {str(k): v for k, v in ((k, _num(v)) for k, v in (obj.get("stages") or {}).items()) if v is not None}
        cold = obj.get("cold")
        entries.append(Entry(index=len(entries), commit=str(obj["commit"]), date=str(obj.get("date", "")),
                             quick=bool(obj.get("quick", False)), seconds=_num(obj.get("seconds")),
                             metrics=metrics, bench=bench, stages=stages, cold=None if cold is None else bool(cold)))
    return entries


def load_baselines(results_dir: str | Path) -> dict[str, dict[str, Any]]:
    """Per metric id: ``published``, and the baseline ``value``/``tolerance``/``quick`` of
    ``metrics.json`` (preferred) or ``metrics_quick.json``.  Missing files give an empty mapping."""
    out: dict[str, dict[str, Any]] = {}
    for name in ("quick/metrics_quick.json", "metrics_quick.json", "metrics.json"):  # full last: it wins
        path = Path(results_dir) / name
        if not path.is_file():
            continue
        try:
            doc = json.loads(path.read_text())
        except ValueError as exc:
            raise SpecError(path, "<file>", str(path), f"malformed JSON: {exc}") from None
        for mid, m in (doc.get("metrics") or {}).items():
            if not isinstance(m, dict):
                raise SpecError(path, f"metrics.{mid}", m, "an object with value, published, tolerance")
            prev = out.get(mid, {})
            pub = m.get("published")
            out[mid] = {"value": _num(m.get("value")), "published": _num(pub) if pub is not None else prev.get("published"),
                        "tolerance": m.get("tolerance") or dict(DEFAULT_TOLERANCE),
                        "quick": bool(doc.get("quick", name.endswith("_quick.json"))),
                        "commit": doc.get("commit", ""), "file": name}
    return out


def _allowed(value: float, tol: Mapping[str, Any]) -> float:
    return max(float(tol.get("abs", 0.0)), float(tol.get("rel", 0.0)) * abs(value))


# ------------------------------------------------------------------------------------------ layout
def _safe_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "_"


def _unique(keys: Sequence[str], make: Callable[[str], str]) -> dict[str, str]:
    """key -> make(key), with ``-2``, ``-3``... where two keys would give the same name (sorted order)."""
    out: dict[str, str] = {}
    used: set[str] = set()
    for k in sorted(keys):
        base = name = make(k)
        i = 1
        while name in used:
            i += 1
            name = f"{base}-{i}"
        used.add(name)
        out[k] = name
    return out


@dataclass(frozen=True)
class _Context:
    entries: Sequence[Entry]
    baselines: Mapping[str, Mapping[str, Any]]
    step_at: Mapping[tuple[str, int], Step]
    moved: Mapping[str, int]          # metric -> steps beyond tolerance in its history
    valued: frozenset[str]            # metrics whose value moved at least once (not only vanished)
    anchor: Mapping[str, str]         # metric -> element id
    papers: Sequence[str]
    table_stem: Mapping[str, str]     # paper.table -> file stem
    budget: int
    info: Mapping[str, Mapping[str, Any]]

    def nav(self, here: str, extra: Sequence[tuple[str, str]] = ()) -> str:
        links = [("index.html", "index"), ("metrics.html", "find a metric"), ("speed.html", "speed"),
                 *((_safe_name(p) + ".html", p) for p in self.papers)]
        return nav_bar(links, here) + (" | " + nav_bar(extra, here) if extra else "")


@dataclass(frozen=True)
class _Item:
    metric: str
    kind: str  # chart | row | none
    html: str


def _band(base: Mapping[str, Any]) -> tuple[float, float] | None:
    if base.get("value") is not None and math.isfinite(base["value"]):
        a = _allowed(base["value"], base.get("tolerance", DEFAULT_TOLERANCE))
        return base["value"] - a, base["value"] + a
    return None


def _chart_item(mid: str, ctx: _Context, prefix: str) -> str:
    base = ctx.baselines.get(mid, {})
    pub = base.get("published")
    svg, _ = runs_chart(ctx.anchor[mid], mid, ctx.entries, lambda e: e.metrics.get(mid), series_by_mode,
                        order=("full", "quick"), published=pub, band=_band(base),
                        marked=lambda e: (mid, e.index) in ctx.step_at)
    recs = [(e, e.metrics[mid]) for e in ctx.entries if mid in e.metrics]
    latest = ", ".join(f"{mode} {fmt(v)}" for mode in ("full", "quick")
                       if (v := _latest_by_mode(recs, mode)) is not None)
    moved = f" · moved {ctx.moved[mid]}×" if ctx.moved.get(mid) else ""
    return (f'<figure><figcaption><b>{esc(mid[len(prefix):])}</b> <span class="v">latest {esc(latest)}'
            f'{"" if pub is None else " · published " + esc(fmt(pub))}{moved}</span></figcaption>{svg}</figure>')


def _latest_by_mode(recs: Sequence[tuple[Entry, float]], mode: str) -> float | None:
    return next((v for e, v in reversed(recs) if e.mode == mode), None)


def _row_item(mid: str, ctx: _Context, prefix: str) -> str:
    recs = [(e, e.metrics[mid]) for e in ctx.entries if mid in e.metrics]
    pub = ctx.baselines.get(mid, {}).get("published")
    lines = [f"{mid}, every run (commit day mode: value):"] + _runs_text(recs)
    spark = sparkline("s" + ctx.anchor[mid][1:], mid, [(k, v, e.mode) for k, (e, v) in enumerate(recs)], len(recs),
                      "\n".join(lines))
    first, last = recs[0][0], recs[-1][0]
    gone = "" if last.index == ctx.entries[-1].index else " (not in later runs)"
    cells = [f'<td class="num">{"" if v is None else esc(fmt(v))}</td>'
             for v in (_latest_by_mode(recs, mode) for mode in ("full", "quick"))]
    mode = "full" if any(e.mode == "full" for e, _ in recs) else "quick"
    main = [v for e, v in recs if e.mode == mode and math.isfinite(v)]
    rng = f"{esc(fmt(min(main)))} … {esc(fmt(max(main)))}" if main else ""  # of the full runs (else the quick)
    return (f'<tr class="stable" id="{esc(ctx.anchor[mid])}" data-metric="{esc(mid)}" data-runs="{len(recs)}">'
            f"<td><code>{esc(mid[len(prefix):])}</code></td>{''.join(cells)}"
            f'<td class="num">{"" if pub is None else esc(fmt(pub))}</td><td class="num c">{rng}</td>'
            f'<td class="num">{len(recs)}</td><td class="c"><code>{esc(first.short)}</code> {esc(first.day[5:])} … '
            f"<code>{esc(last.short)}</code> {esc(last.day[5:])}{gone}</td><td>{spark}</td></tr>")


def _runs_text(recs: Sequence[tuple[Entry, float]]) -> list[str]:
    """One line per stretch of consecutive runs of one mode with the same value (6 digits): the first and
    the last run's commit and day, the mode, the value and the number of runs; in order of first run."""
    groups: list[list[Any]] = []  # [first, last, mode, text, count]
    last_of: dict[str, list[Any]] = {}
    for e, v in recs:
        text = f"{v:.6g}"
        g = last_of.get(e.mode)
        if g is not None and g[3] == text:
            g[1], g[4] = e, g[4] + 1
            continue
        g = [e, e, e.mode, text, 1]
        groups.append(g)
        last_of[e.mode] = g
    out = []
    for first, last, mode, text, count in groups:
        span = " ".join(axis_label(first.commit, first.date))
        if count > 1:
            span += " … " + " ".join(axis_label(last.commit, last.date)) + f" ({count} runs)"
        out.append(f"{span} {mode}: {text}")
    return out


def _pack(items: Sequence[_Item], budget: int) -> list[list[_Item]]:
    """Consecutive items into parts of at most ``budget`` bytes (an oversized item is a part of its own)."""
    parts: list[list[_Item]] = [[]]
    size = 0
    for it in items:
        n = len(it.html.encode())
        if parts[-1] and size + n > budget:
            parts.append([])
            size = 0
        parts[-1].append(it)
        size += n
    return parts


def _part_name(stem: str, k: int) -> str:
    return f"{stem}.html" if k == 1 else f"{stem}.{k}.html"


@dataclass(frozen=True)
class _TablePlan:
    """One table's pages: the items of each part (charts, then compact rows, then metrics without a value)."""

    paper: str
    table: str
    metrics: tuple[str, ...]
    full: bool
    parts: tuple[tuple[_Item, ...], ...]
    names: tuple[str, ...]

    def locations(self, ctx: _Context) -> list[MetricLocation]:
        return [MetricLocation(it.metric, self.table, name, ctx.anchor[it.metric], it.kind,
                               next((e.metrics[it.metric] for e in reversed(ctx.entries) if it.metric in e.metrics),
                                    None), ctx.moved.get(it.metric, 0))
                for name, part in zip(self.names, self.parts) for it in part]


def _plan_table(paper: str, tkey: str, mids: Sequence[str], ctx: _Context) -> _TablePlan:
    prefix = tkey + "."
    full = len(mids) <= FULL_TABLE
    finite = {m for m in mids if any(m in e.metrics and math.isfinite(e.metrics[m]) for e in ctx.entries)}
    charts = [m for m in mids if m in finite and (full or m in ctx.valued)]
    rows = [] if full else [m for m in mids if m in finite and m not in ctx.valued]
    items = ([_Item(m, "chart", _chart_item(m, ctx, prefix)) for m in charts]
             + [_Item(m, "row", _row_item(m, ctx, prefix)) for m in rows]
             + [_Item(m, "none", f'<li id="{esc(ctx.anchor[m])}"><code>{esc(m)}</code></li>')
                for m in mids if m not in finite])
    parts = _pack(items, ctx.budget)
    names = tuple(_part_name(ctx.table_stem[tkey], k) for k in range(1, len(parts) + 1))
    return _TablePlan(paper, tkey, tuple(mids), full, tuple(tuple(p) for p in parts), names)


def _table_pages(plan: _TablePlan, ctx: _Context, steps: Sequence[Step], href: Callable[[str], str],
                 table_href: Callable[[str], str]) -> list[tuple[str, str, int, int, list[str]]]:
    """The pages of one table: (file name, html, charts, compact rows, metrics without a value)."""
    paper, tkey, parts, names = plan.paper, plan.table, plan.parts, plan.names
    kinds = [it.kind for part in parts for it in part]
    nchart, nrow, nnone = kinds.count("chart"), kinds.count("row"), kinds.count("none")
    out = []
    for k, part in enumerate(parts, start=1):
        name = names[k - 1]
        extra = [(_safe_name(paper) + ".html", f"{paper} (overview)")]
        if len(parts) > 1:
            extra += [(n, f"part {i}") for i, n in enumerate(names, start=1)]
        title = f"{paper} · {tkey[len(paper) + 1:] or tkey}" + (f" (part {k} of {len(parts)})" if len(parts) > 1 else "")
        body = [f"<p>{len(plan.metrics)} metrics in <code>{esc(tkey)}</code>: {nchart} charts"
                + ("" if plan.full else " (the metrics that moved beyond tolerance at least once)")
                + (f", {nrow} compact rows (never moved beyond tolerance; hover a sparkline for every run's value)"
                   if nrow else "")
                + (f", {nnone} without a finite value" if nnone else "")
                + (f". This is part {k} of {len(parts)}: <code>{esc(part[0].metric)}</code> … "
                   f"<code>{esc(part[-1].metric)}</code>" if len(parts) > 1 else "")
                + f'. Runs and citation: <a href="{_safe_name(paper)}.html">{esc(paper)}</a>; '
                  'every metric: <a href="metrics.html">find a metric</a>.</p>']
        figs = [it.html for it in part if it.kind == "chart"]
        trs = [it.html for it in part if it.kind == "row"]
        none = [it for it in part if it.kind == "none"]
        if figs:
            body += [legend(), '<div class="charts">' + "".join(figs) + "</div>"]
        if trs:
            body += ["<h2>Never moved beyond tolerance</h2>",
                     '<table class="stable"><tr><th>metric</th><th>latest full run</th><th>latest quick run</th>'
                     "<th>published</th><th>min … max (full runs)</th><th>runs</th><th>first … last run</th>"
                     "<th>history (full blue, quick orange)</th></tr>",
                     *trs, "</table>"]
        if none:
            body.append("<h2>Not charted (no finite value in any run)</h2><ul>" + "".join(it.html for it in none)
                        + "</ul>")
        on_page = {it.metric for it in part}
        body.append("<h2>Changes beyond tolerance between consecutive runs</h2>")
        body += pairs_table(group_steps([s for s in steps if s.metric in on_page]), href, table_href)
        out.append((name, html_page(title, body, ctx.nav(name, extra)), len(figs), len(trs),
                    [it.metric for it in none]))
    return out


# ------------------------------------------------------------------------------------------ pages
@dataclass(frozen=True)
class DashboardPages:
    """What was written: per page the charts and compact rows on it and the metrics not charted; the steps
    beyond tolerance; where each metric is."""

    out_dir: Path
    charts: dict[str, int] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)
    not_charted: dict[str, list[str]] = field(default_factory=dict)
    steps: list[Step] = field(default_factory=list)
    locations: dict[str, MetricLocation] = field(default_factory=dict)


def _history_table(entries: Sequence[Entry]) -> list[str]:
    rows = ["<table><tr><th>#</th><th>commit</th><th>date (UTC)</th><th>mode</th><th>cache</th><th>wall time (s)</th>"
            "<th>metrics</th></tr>"]
    for e in reversed(entries):
        cache = "" if e.cold is None else ("cold" if e.cold else "warm")
        rows.append(f'<tr><td class="num">{e.index}</td><td><code title="{esc(e.commit)}">{esc(e.commit)}</code></td>'
                    f"<td>{esc(e.date)}</td><td>{e.mode}</td><td>{cache}</td>"
                    f'<td class="num">{"" if e.seconds is None else f"{e.seconds:.1f}"}</td>'
                    f'<td class="num">{len(e.metrics)}</td></tr>')
    rows.append("</table>")
    return rows


def _paper_info(paper: str) -> dict[str, Any]:
    """Title and citation from scenarios/papers/<paper>.toml when it is declared (else just the id)."""
    try:
        from bench.reproduce import load_paper

        return load_paper(paper)
    except (SpecError, OSError, ImportError):
        return {}


def _paper_page(paper: str, mids: Sequence[str], ctx: _Context, steps: Sequence[Step], res: DashboardPages,
                href: Callable[[str], str], table_href: Callable[[str], str],
                table_pages: Mapping[str, list[str]]) -> str:
    info = ctx.info[paper]
    runs = [e for e in ctx.entries if any(m in e.metrics for m in mids)]
    last = runs[-1]
    tables = sorted({table_key(m) for m in mids})
    body = [f"<p><em>{esc(info['citation'])}</em></p>"] if info.get("citation") else []
    body.append(f"<p>{len(mids)} metrics in {len(tables)} tables over {len(runs)} reproduce runs; latest run "
                f"<code>{esc(last.commit)}</code> on {esc(last.date)} ({last.mode}). Tables and claims: "
                f"<code>results/{esc(paper)}/</code>; every number in <code>results/metrics.json</code>.</p>")
    body.append("<h2>Tables</h2><table><tr><th>table</th><th>metrics</th><th>charts</th><th>compact rows</th>"
                "<th>no value</th><th>metrics that moved</th><th>pages</th></tr>")
    for t in tables:
        tm = [m for m in mids if table_key(m) == t]
        pages = table_pages[t]
        kinds = [res.locations[m].kind for m in tm]
        links = " ".join(f'<a href="{esc(p)}">{i}</a>' for i, p in enumerate(pages, start=1))
        body.append(f'<tr><td><a href="{esc(pages[0])}">{esc(t)}</a></td><td class="num">{len(tm)}</td>'
                    f'<td class="num">{kinds.count("chart")}</td><td class="num">{kinds.count("row")}</td>'
                    f'<td class="num">{kinds.count("none")}</td>'
                    f'<td class="num">{sum(1 for m in tm if ctx.moved.get(m))}</td><td>{links}</td></tr>')
    body.append("</table>")
    body.append("<h2>Changes beyond tolerance between consecutive runs, by commit pair</h2>")
    body += pairs_table(group_steps(steps), href, table_href)
    body.append("<h2>Runs</h2>")
    body += _history_table(runs)
    title = f"{paper}: {info['title']}" if info.get("title") else paper
    name = _safe_name(paper) + ".html"
    return html_page(title, body, ctx.nav(name))


def _index_page(ctx: _Context, mids_of: Mapping[str, list[str]], steps: Sequence[Step], res: DashboardPages,
                source: str, has_asv: bool) -> str:
    entries = ctx.entries
    last = entries[-1]
    body = [f"<p>Regression history of the paper reproductions: {len(entries)} reproduce runs from "
            f"<code>{esc(source)}</code>; latest <code>{esc(last.commit)}</code> on {esc(last.date)}. "
            "Each paper page lists its tables; each table page charts its metrics over the commits, with the "
            'published value as a dashed line. <a href="metrics.html">Find a metric</a> by its id; '
            f'<a href="speed.html">speed over commits</a> ({res.charts.get("speed.html", 0)} charts).'
            + (' <a href="asv/index.html">asv site</a> (it needs an HTTP server: <code>asv preview</code>).'
               if has_asv else "") + "</p>",
            "<h2>Papers</h2>",
            "<table><tr><th>paper</th><th>title</th><th>metrics</th><th>tables</th><th>charts</th>"
            "<th>with a published value</th><th>changes beyond tolerance (all runs)</th><th>in the latest run</th>"
            "<th>last run</th></tr>"]
    for p in ctx.papers:
        mids = mids_of[p]
        runs = [e for e in entries if any(m in e.metrics for m in mids)]
        ps = [s for s in steps if s.metric.split(".", 1)[0] == p]
        latest = [s for s in ps if s.after.index == runs[-1].index]
        npub = sum(1 for m in mids if ctx.baselines.get(m, {}).get("published") is not None)
        ncharts = sum(1 for m in mids if res.locations[m].kind == "chart")
        body.append(f'<tr><td><a href="{_safe_name(p)}.html">{esc(p)}</a></td><td>{esc(ctx.info[p].get("title", ""))}</td>'
                    f'<td class="num">{len(mids)}</td><td class="num">{len({table_key(m) for m in mids})}</td>'
                    f'<td class="num">{ncharts}</td><td class="num">{npub}</td><td class="num">{len(ps)}</td>'
                    f'<td class="num{" bad" if latest else ""}">{len(latest)}</td>'
                    f"<td><code>{esc(runs[-1].short)}</code> {esc(runs[-1].day)}</td></tr>")
    body.append("</table>")
    body.append(f"<h2>Changes beyond tolerance by commit pair ({len(steps)} in all)</h2>")
    body += summary_table(group_steps(steps), ctx.papers, lambda p: _safe_name(p) + ".html")
    body.append("<h2>Runs</h2>")
    body += _history_table(entries)
    return html_page("skidbench regression dashboard", body, ctx.nav("index.html"))


def render_dashboard(results_dir: str | Path, out_dir: str | Path | None = None,
                     history: str | Path | None = None, bench_history: str | Path | None = None,
                     page_budget: int = PAGE_BUDGET) -> DashboardPages:
    """Write index.html, metrics.html, speed.html, one page per paper and the table pages into ``out_dir``
    (default ``results_dir/dashboard``) from ``results_dir/history.jsonl``, ``metrics.json`` and
    ``bench_history.jsonl``; table pages (``<paper>.<table>[.<k>].html``) left from an earlier render with
    other parts are removed.  ``page_budget``: bytes of charts and rows per table page."""
    results_dir = Path(results_dir)
    out_dir = Path(out_dir) if out_dir is not None else results_dir / "dashboard"
    hist_path = Path(history) if history is not None else results_dir / "history.jsonl"
    bench_path = Path(bench_history) if bench_history is not None else results_dir / "bench_history.jsonl"
    entries = load_history(hist_path)
    if not entries:
        raise SpecError(hist_path, "<file>", str(hist_path), "history is empty: run `skidbench reproduce` first")
    bench_runs = load_bench_history(bench_path)
    baselines = load_baselines(results_dir)
    all_mids = sorted({m for e in entries for m in e.metrics})
    mids_of: dict[str, list[str]] = {}
    for m in all_mids:
        mids_of.setdefault(m.split(".", 1)[0], []).append(m)
    papers = sorted(mids_of)
    steps = find_steps(entries, all_mids, baselines)
    moved: dict[str, int] = {}
    for s in steps:
        moved[s.metric] = moved.get(s.metric, 0) + 1
    tkeys = sorted({table_key(m) for m in all_mids})
    ctx = _Context(entries=entries, baselines=baselines, step_at={(s.metric, s.after.index): s for s in steps},
                   moved=moved, valued=frozenset(s.metric for s in steps if not s.vanished),
                   anchor=_unique(all_mids, lambda m: "c-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in m)),
                   papers=papers, budget=page_budget, info={p: _paper_info(p) for p in papers},
                   table_stem=_unique(tkeys, lambda t: ".".join(_safe_name(x) for x in t.split(".", 1))
                                      if "." in t else _safe_name(t) + "._"))
    res = DashboardPages(out_dir=out_dir, steps=steps)
    plans = {t: _plan_table(t.split(".", 1)[0], t, [m for m in all_mids if table_key(m) == t], ctx) for t in tkeys}
    for plan in plans.values():
        res.locations.update((loc.metric, loc) for loc in plan.locations(ctx))
    table_pages = {t: list(plan.names) for t, plan in plans.items()}

    def href(metric: str) -> str:
        return res.locations[metric].href

    def table_href(t: str) -> str:
        return table_pages[t][0] if t in table_pages else ""

    for p in papers:
        ps = [s for s in steps if s.metric.split(".", 1)[0] == p]
        for t in sorted({table_key(m) for m in mids_of[p]}):
            for name, page, n, nrows, none in _table_pages(plans[t], ctx, [s for s in ps if table_key(s.metric) == t],
                                                           href, table_href):
                atomic_write_text(out_dir / name, page)
                res.charts[name], res.rows[name], res.not_charted[name] = n, nrows, none
        name = _safe_name(p) + ".html"
        atomic_write_text(out_dir / name, _paper_page(p, mids_of[p], ctx, ps, res, href, table_href, table_pages))
        res.charts[name] = 0
    page, n = speed_page(entries, bench_runs, ctx.nav("speed.html"), _rel(bench_path, results_dir))
    atomic_write_text(out_dir / "speed.html", page)
    res.charts["speed.html"] = n
    atomic_write_text(out_dir / "metrics.html", metric_index_page(list(res.locations.values()), ctx.nav("metrics.html")))
    res.charts["metrics.html"] = 0
    has_asv = (out_dir / "asv" / "index.html").is_file()
    atomic_write_text(out_dir / "index.html", _index_page(ctx, mids_of, steps, res, _rel(hist_path, results_dir),
                                                          has_asv))
    res.charts["index.html"] = 0
    for old in sorted(out_dir.glob("*.*.html")):  # table pages of an earlier render that this one did not write
        if old.name not in res.charts:
            old.unlink()
    return res


def _rel(path: Path, base: Path) -> str:
    try:
        return str(Path(base.name) / path.resolve().relative_to(base.resolve()))
    except ValueError:
        return path.name
