"""Regression dashboard: static, self-contained HTML pages from ``results/history.jsonl``.

    render_dashboard(results_dir, out_dir) -> DashboardPages

writes ``out_dir/index.html`` (papers, the run history with commit ids and dates, links),
``out_dir/<paper>.html`` (one chart per metric over the reproduce runs: full and quick runs as two
series, the published value as a dashed horizontal line, the regression band of the baseline
``metrics.json`` as a shaded band, and a table of the changes beyond tolerance between consecutive
runs) and ``out_dir/speed.html`` (reproduce wall time and every pytest-benchmark mean recorded by
``make bench`` over the runs).

Why hand-written pages and not asv's site (DESIGN.md names asv): asv's published site loads its data
with ``fetch()`` from JSON files, which browsers refuse on ``file://``, so it needs an HTTP server to
be looked at or tested; and its history is per commit of asv runs, while ours already exists in
``history.jsonl`` (written by every ``skidbench reproduce``).  These pages are one file each, with
inline SVG (no JavaScript needed to see them, no network, no CDN), so they open from disk, from a CI
artefact or from the committed ``results/`` folder.  asv remains available for those who want it:
``asv.conf.json`` + ``benchmarks/`` (``track_*`` over ``results/metrics.json``, ``time_*`` speed) run
with ``asv run --environment existing``.

The SVG is written by :mod:`bench.report.chart` (no plotting call per chart: a page has hundreds of
charts and matplotlib takes ~0.15 s each); tick positions come from :class:`matplotlib.ticker.MaxNLocator`.
Each chart is an ``<svg class="chart">`` with ``data-points`` (finite points drawn); a short inline script checks
in the browser that every chart's data series has a non-empty laid-out box and as many markers as
declared, marks each chart ``data-rendered="ok"|"empty"`` and writes the totals into
``#render-status`` (read by the headless-Chromium test).  Steps between consecutive runs of the same
mode use :func:`bench.cli.reproduce.compare_metrics`, the same rule as ``skidbench compare``.

Output is a pure function of the input files (no clock, sorted keys): rendering twice gives the same
bytes.  Every file is written atomically.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

from bench.report.chart import COLORS, Series, _chart_for, _chart_id, _esc, _fmt, _time_unit, svg_chart
from bench.report.io import atomic_write_text, json_number
from bench.spec import SpecError

__all__ = ["Entry", "Series", "Step", "DashboardPages", "load_history", "load_baselines", "find_steps",
           "svg_chart", "render_dashboard", "DEFAULT_TOLERANCE"]

DEFAULT_TOLERANCE: Mapping[str, float] = {"rel": 0.05, "abs": 1e-6}  # bench.reproduce's default


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
    cold: bool = False  # the run computed everything (empty run cache, nothing from the result cache)

    @property
    def short(self) -> str:
        """Short commit id (8 hex digits, ``+`` when the tree was dirty)."""
        base, _, dirty = self.commit.partition("+")
        return base[:8] + ("+" if dirty else "")

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
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except ValueError as exc:
            raise SpecError(path, f"line {lineno}", line[:60], f"malformed JSON: {exc}") from None
        if not isinstance(obj, dict):
            raise SpecError(path, f"line {lineno}", line[:60], "a JSON object per line")
        for key in ("commit", "metrics"):
            if key not in obj:
                raise SpecError(path, f"line {lineno}: {key}", None, "required field is missing")
        if not isinstance(obj["metrics"], dict):
            raise SpecError(path, f"line {lineno}: metrics", obj["metrics"], "an object {metric id: number}")
        if obj.get("extended"):
            continue  # reproduce --extended: other tables and league than the full runs' series (results/extended/)
        # null is a metric without a value (NaN, as the old writer wrote it): kept, so "became NaN" is seen
        metrics = {str(k): v for k, v in ((k, math.nan if v is None else _num(v)) for k, v in obj["metrics"].items())
                   if v is not None}
        bench = {str(k): v for k, v in ((k, _num(v)) for k, v in (obj.get("bench") or {}).items()) if v is not None}
        stages = {str(k): v for k, v in ((k, _num(v)) for k, v in (obj.get("stages") or {}).items()) if v is not None}
        entries.append(Entry(index=len(entries), commit=str(obj["commit"]), date=str(obj.get("date", "")),
                             quick=bool(obj.get("quick", False)), seconds=_num(obj.get("seconds")),
                             metrics=metrics, bench=bench, stages=stages, cold=bool(obj.get("cold", False))))
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


# ------------------------------------------------------------------------------------------ steps
@dataclass(frozen=True)
class Step:
    """A metric that moved beyond its tolerance between two consecutive runs of the same mode."""

    metric: str
    mode: str
    before: Entry
    after: Entry
    old: float
    new: float | None
    why: str


def find_steps(entries: Sequence[Entry], metric_ids: Sequence[str],
               baselines: Mapping[str, Mapping[str, Any]]) -> list[Step]:
    """Changes beyond tolerance between consecutive runs (same mode) that both ran the metric's paper.

    The rule is :func:`bench.cli.reproduce.compare_metrics` (the one ``skidbench compare`` applies), with
    each metric's tolerance from the baseline metrics.json (else bench.reproduce's default)."""
    from bench.cli.reproduce import compare_metrics

    steps: list[Step] = []
    by_paper: dict[str, list[str]] = {}
    for mid in metric_ids:
        by_paper.setdefault(mid.split(".", 1)[0], []).append(mid)
    for mids in by_paper.values():
        for quick in (False, True):
            runs = [e for e in entries if e.quick == quick and any(m in e.metrics for m in mids)]
            for a, b in zip(runs, runs[1:]):
                base = {"metrics": {m: {"value": a.metrics[m],
                                        "tolerance": baselines.get(m, {}).get("tolerance", DEFAULT_TOLERANCE)}
                                    for m in mids if m in a.metrics}}
                new = {"metrics": {m: {"value": b.metrics[m]} for m in mids if m in b.metrics}}
                for mv in compare_metrics(base, new):
                    steps.append(Step(mv["metric"], "quick" if quick else "full", a, b, mv["base"], mv["new"], mv["why"]))
    return sorted(steps, key=lambda s: (s.metric, s.after.index, s.mode))


# ------------------------------------------------------------------------------------------ pages
CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:1.2em 2em;color:#222;max-width:1500px}
h1{font-size:1.5em} h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ddd} h3{font-size:1.05em}
table{border-collapse:collapse;font-size:.88em;margin:.6em 0} td,th{border:1px solid #ccc;padding:2px 7px;text-align:left}
th{background:#f2f2f2} td.num{text-align:right;font-variant-numeric:tabular-nums} code{font-size:.95em}
.charts{display:grid;grid-template-columns:repeat(auto-fill,minmax(450px,1fr));gap:10px 14px}
figure{margin:0;border:1px solid #e3e3e3;padding:4px 6px} figcaption{font-size:.82em;margin-bottom:2px}
figcaption .v{color:#555}
svg.chart{display:block;width:100%;height:auto;font-size:10px}
svg .frame{fill:#fff;stroke:#999;stroke-width:1} svg .grid{stroke:#eee;stroke-width:1}
svg .ytick{text-anchor:end;fill:#444} svg .unit{text-anchor:middle;fill:#444} svg .xtick{text-anchor:middle;fill:#444;font-size:9px}
svg .band{fill:#3a9d3a;fill-opacity:.13;stroke:none}
svg .published{stroke:#000;stroke-width:1.4;stroke-dasharray:6 4}
svg .publabel{text-anchor:end;font-size:9px;fill:#000}
svg .line{fill:none;stroke-width:1.6} svg .pt{stroke:none} svg .pt.step{stroke:#d00;stroke-width:2.2;fill:#fff}
.legend span{margin-right:1.2em;font-size:.85em} .sw{display:inline-block;width:18px;height:3px;vertical-align:middle;margin-right:4px}
.bad{color:#b00;font-weight:bold} .ok{color:#070} nav a{margin-right:1em}
"""

CHECK_JS = """
(function(){
  var charts=document.querySelectorAll('svg.chart'), ok=0, bad=[];
  charts.forEach(function(svg){
    var r=svg.getBoundingClientRect(), g=svg.querySelectorAll('g.series'), pts=svg.querySelectorAll('g.series circle.pt');
    var good=r.width>0&&r.height>0&&g.length>0&&pts.length>0&&pts.length==+svg.getAttribute('data-points');
    g.forEach(function(s){var b=s.getBoundingClientRect();
      if(!(b.width>0&&b.height>0&&b.left>=r.left-1&&b.right<=r.right+1&&b.top>=r.top-1&&b.bottom<=r.bottom+1)) good=false;});
    if(svg.getAttribute('data-published')!==''){var p=svg.querySelector('line.published');
      if(!p||!(p.getBoundingClientRect().width>0)) good=false;}
    svg.setAttribute('data-rendered', good?'ok':'empty');
    if(good) ok++; else bad.push(svg.id);
  });
  var s=document.getElementById('render-status');
  if(s){s.setAttribute('data-charts',charts.length);s.setAttribute('data-ok',ok);
    s.className=bad.length?'bad':'ok';
    s.textContent=ok+' of '+charts.length+' charts rendered'+(bad.length?'; empty: '+bad.join(', '):'');}
})();
"""


def _page(title: str, body: list[str], nav: str) -> str:
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_esc(title)}</title><style>{CSS}</style></head><body>",
        f"<nav>{nav}</nav>", f"<h1>{_esc(title)}</h1>", *body,
        '<p id="render-status" data-charts="" data-ok="">charts not checked (JavaScript off)</p>',
        f"<script>{CHECK_JS}</script>", "</body></html>", ""])


def _legend(published: bool = True) -> str:
    items = [f'<span><i class="sw" style="background:{COLORS["full"]}"></i>full run</span>',
             f'<span><i class="sw" style="background:{COLORS["quick"]}"></i>quick run (--quick)</span>']
    if published:
        items += ['<span><i class="sw" style="background:#000"></i>published value (dashed)</span>',
                  '<span><i class="sw" style="background:#3a9d3a;opacity:.35;height:9px"></i>regression band of metrics.json</span>',
                  '<span><i class="sw" style="background:#fff;border:2px solid #d00;width:6px;height:6px;border-radius:50%"></i>'
                  'moved beyond tolerance since the previous run</span>']
    return f'<p class="legend">{"".join(items)}</p>'


def _paper_info(paper: str) -> dict[str, Any]:
    """Title and citation from scenarios/papers/<paper>.toml when it is declared (else just the id)."""
    try:
        from bench.reproduce import load_paper

        return load_paper(paper)
    except (SpecError, OSError, ImportError):
        return {}


def _safe_name(paper: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in paper) or "paper"


def _nav(papers: Sequence[str]) -> str:
    return " ".join(['<a href="index.html">index</a>', *(f'<a href="{_safe_name(p)}.html">{_esc(p)}</a>' for p in papers),
                     '<a href="speed.html">speed</a>'])


@dataclass
class DashboardPages:
    """What was written: page path -> number of charts on it (and per page the metrics not charted)."""

    out_dir: Path
    charts: dict[str, int] = field(default_factory=dict)
    not_charted: dict[str, list[str]] = field(default_factory=dict)
    steps: list[Step] = field(default_factory=list)


def _history_table(entries: Sequence[Entry]) -> list[str]:
    rows = ["<table><tr><th>#</th><th>commit</th><th>date (UTC)</th><th>mode</th><th>wall time (s)</th>"
            "<th>metrics</th><th>speed benchmarks</th></tr>"]
    for e in reversed(entries):
        rows.append(f'<tr><td class="num">{e.index}</td><td><code title="{_esc(e.commit)}">{_esc(e.commit)}</code></td>'
                    f"<td>{_esc(e.date)}</td><td>{e.mode}</td>"
                    f'<td class="num">{"" if e.seconds is None else f"{e.seconds:.1f}"}</td>'
                    f'<td class="num">{len(e.metrics)}</td><td class="num">{len(e.bench)}</td></tr>')
    rows.append("</table>")
    return rows


def _paper_page(paper: str, mids: list[str], entries: Sequence[Entry], baselines: Mapping[str, Mapping[str, Any]],
                steps: list[Step], papers: Sequence[str]) -> tuple[str, int, list[str]]:
    info = _paper_info(paper)
    step_at = {(s.metric, s.after.index): s for s in steps}
    body = []
    if info.get("citation"):
        body.append(f"<p><em>{_esc(info['citation'])}</em></p>")
    runs = [e for e in entries if any(m in e.metrics for m in mids)]
    last = runs[-1]
    body.append(f"<p>{len(mids)} metrics over {len(runs)} reproduce runs; latest run <code>{_esc(last.commit)}</code> "
                f"on {_esc(last.date)} ({last.mode}). Tables and claims: <code>results/{_esc(paper)}/</code>; "
                f"every number in <code>results/metrics.json</code>.</p>")
    body.append("<h2>Changes beyond tolerance between consecutive runs</h2>")
    if steps:
        body.append("<table><tr><th>metric</th><th>mode</th><th>from</th><th>to</th><th>before</th><th>after</th><th>change</th></tr>")
        for s in steps:
            body.append(f"<tr><td><a href=\"#{_esc(_chart_id(s.metric))}\">{_esc(s.metric)}</a></td><td>{s.mode}</td>"
                        f'<td><code title="{_esc(s.before.commit)}">{_esc(s.before.short)}</code> {_esc(s.before.day)}</td>'
                        f'<td><code title="{_esc(s.after.commit)}">{_esc(s.after.short)}</code> {_esc(s.after.day)}</td>'
                        f'<td class="num">{_esc(_fmt(s.old))}</td>'
                        f'<td class="num">{"—" if s.new is None else _esc(_fmt(s.new))}</td><td>{_esc(s.why)}</td></tr>')
        body.append("</table>")
    else:
        body.append("<p>None: no metric moved beyond its tolerance between consecutive runs of the same mode.</p>")
    body.append("<h2>Metrics over commits</h2>")
    body.append(_legend())
    n_charts, skipped = 0, []
    table_of = {m: m.split(".")[1] if m.count(".") >= 2 else "" for m in mids}
    for table in sorted(dict.fromkeys(table_of.values())):
        figs = []
        for mid in (m for m in mids if table_of[m] == table):
            base = baselines.get(mid, {})
            band = None
            if base.get("value") is not None and math.isfinite(base["value"]):
                a = _allowed(base["value"], base.get("tolerance", DEFAULT_TOLERANCE))
                band = (base["value"] - a, base["value"] + a)
            svg, npts = _chart_for(_chart_id(mid), mid, entries, lambda e, m=mid: e.metrics.get(m),
                                   published=base.get("published"), band=band, steps=step_at, key=mid)
            if npts == 0:
                skipped.append(mid)
                continue
            lastv = next((e.metrics[mid] for e in reversed(entries) if mid in e.metrics), float("nan"))
            pub = base.get("published")
            cap = (f'<figcaption><b>{_esc(mid.split(".", 2)[-1])}</b> <span class="v">latest {_esc(_fmt(lastv))}'
                   f'{"" if pub is None else " · published " + _esc(_fmt(pub))}</span></figcaption>')
            figs.append(f"<figure>{cap}{svg}</figure>")
            n_charts += 1
        if figs:
            body.append(f"<h3>{_esc(table or 'metrics')}</h3>")
            body.append('<div class="charts">' + "".join(figs) + "</div>")
    if skipped:
        body.append("<h2>Not charted (no finite value in any run)</h2><ul>"
                    + "".join(f"<li><code>{_esc(m)}</code></li>" for m in skipped) + "</ul>")
    body.append("<h2>Runs</h2>")
    body += _history_table(runs)
    title = f"{paper}: {info['title']}" if info.get("title") else paper
    return _page(title, body, _nav(papers)), n_charts, skipped



def _speed_page(entries: Sequence[Entry], papers: Sequence[str]) -> tuple[str, int]:
    body = ["<p>Wall time of each <code>skidbench reproduce</code>, the seconds of each of its stages (each paper, "
            "real, league, gap, stress; cold runs: nothing from a cache), and the mean time of each speed benchmark "
            "(<code>make bench</code>, pytest-benchmark; recorded into the next reproduce's history line).</p>",
            _legend(published=False)]
    figs = []
    secs = [e.seconds for e in entries if e.seconds is not None]
    if secs:
        unit, scale = _time_unit(secs)
        svg, n = _chart_for("c-reproduce-wall-time", "reproduce wall time", entries, lambda e: e.seconds,
                            unit=unit, scale=scale)
        if n:
            figs.append(f"<figure><figcaption><b>reproduce wall time</b></figcaption>{svg}</figure>")
    for stage in sorted({k for e in entries for k in e.stages}):  # bench.reproduce.timing: per stage and run
        vals = [e.stages[stage] for e in entries if stage in e.stages]
        unit, scale = _time_unit(vals)
        svg, n = _chart_for(_chart_id("stage-" + stage), f"stage {stage}", entries,
                            lambda e, k=stage: e.stages.get(k), unit=unit, scale=scale)
        if n:
            cold = [e.stages[stage] for e in entries if stage in e.stages and e.cold]
            last = f"latest {_fmt(vals[-1] * scale)} {unit}" + (f", last cold {_fmt(cold[-1] * scale)} {unit}"
                                                                  if cold else "")
            figs.append(f"<figure><figcaption><b>stage {_esc(stage)}</b> <span class=\"v\">{_esc(last)}</span>"
                        f"</figcaption>{svg}</figure>")
    names = sorted({b for e in entries for b in e.bench})
    for name in names:
        vals = [e.bench[name] for e in entries if name in e.bench]
        unit, scale = _time_unit(vals)
        svg, n = _chart_for(_chart_id("bench-" + name), name, entries, lambda e, b=name: e.bench.get(b),
                            unit=unit, scale=scale)
        if n:
            figs.append(f"<figure><figcaption><b>{_esc(name)}</b> <span class=\"v\">latest "
                        f"{_esc(_fmt(vals[-1] * scale))} {unit}</span></figcaption>{svg}</figure>")
    if not names:
        body.append("<p>No speed benchmarks recorded yet: run <code>make bench</code> before "
                    "<code>skidbench reproduce</code>.</p>")
    body.append('<div class="charts">' + "".join(figs) + "</div>")
    return _page("skidbench: speed over commits", body, _nav(papers)), len(figs)


def _index_page(entries: Sequence[Entry], papers: Sequence[str], mids_of: Mapping[str, list[str]],
                baselines: Mapping[str, Mapping[str, Any]], steps: Sequence[Step], charts: Mapping[str, int],
                source: str, has_asv: bool) -> str:
    last = entries[-1]
    body = [f"<p>Regression history of the paper reproductions: {len(entries)} reproduce runs from "
            f"<code>{_esc(source)}</code>; latest <code>{_esc(last.commit)}</code> on {_esc(last.date)}. "
            "Each paper page charts every metric over the commits, with the published value as a dashed line.</p>",
            "<h2>Papers</h2>",
            "<table><tr><th>paper</th><th>title</th><th>metrics</th><th>charted</th><th>with a published value</th>"
            "<th>changes beyond tolerance (all runs)</th><th>in the latest run</th><th>last run</th></tr>"]
    for p in papers:
        mids = mids_of[p]
        info = _paper_info(p)
        runs = [e for e in entries if any(m in e.metrics for m in mids)]
        ps = [s for s in steps if s.metric.split(".", 1)[0] == p]
        latest = [s for s in ps if s.after.index == runs[-1].index]
        npub = sum(1 for m in mids if baselines.get(m, {}).get("published") is not None)
        body.append(f'<tr><td><a href="{_safe_name(p)}.html">{_esc(p)}</a></td><td>{_esc(info.get("title", ""))}</td>'
                    f'<td class="num">{len(mids)}</td><td class="num">{charts.get(_safe_name(p) + ".html", 0)}</td>'
                    f'<td class="num">{npub}</td><td class="num">{len(ps)}</td>'
                    f'<td class="num{" bad" if latest else ""}">{len(latest)}</td>'
                    f'<td><code>{_esc(runs[-1].short)}</code> {_esc(runs[-1].day)}</td></tr>')
    body.append("</table>")
    body.append(f'<p><a href="speed.html">Speed over commits</a> ({charts.get("speed.html", 0)} charts).'
                + (' <a href="asv/index.html">asv site</a> (serve over HTTP: <code>asv preview</code>).' if has_asv else "")
                + "</p>")
    body.append("<h2>Runs</h2>")
    body += _history_table(entries)
    return _page("skidbench regression dashboard", body, _nav(papers))


def render_dashboard(results_dir: str | Path, out_dir: str | Path | None = None,
                     history: str | Path | None = None) -> DashboardPages:
    """Write index.html, one page per paper and speed.html into ``out_dir`` (default
    ``results_dir/dashboard``) from ``results_dir/history.jsonl`` and ``metrics.json``."""
    results_dir = Path(results_dir)
    out_dir = Path(out_dir) if out_dir is not None else results_dir / "dashboard"
    hist_path = Path(history) if history is not None else results_dir / "history.jsonl"
    entries = load_history(hist_path)
    if not entries:
        raise SpecError(hist_path, "<file>", str(hist_path), "history is empty: run `skidbench reproduce` first")
    baselines = load_baselines(results_dir)
    all_mids = sorted({m for e in entries for m in e.metrics})
    mids_of: dict[str, list[str]] = {}
    for m in all_mids:
        mids_of.setdefault(m.split(".", 1)[0], []).append(m)
    papers = sorted(mids_of)
    steps = find_steps(entries, all_mids, baselines)
    res = DashboardPages(out_dir=out_dir, steps=steps)
    for p in papers:
        page, n, skipped = _paper_page(p, mids_of[p], entries, baselines,
                                       [s for s in steps if s.metric.split(".", 1)[0] == p], papers)
        name = _safe_name(p) + ".html"
        atomic_write_text(out_dir / name, page)
        res.charts[name], res.not_charted[name] = n, skipped
    page, n = _speed_page(entries, papers)
    atomic_write_text(out_dir / "speed.html", page)
    res.charts["speed.html"] = n
    has_asv = (out_dir / "asv" / "index.html").is_file()
    atomic_write_text(out_dir / "index.html", _index_page(entries, papers, mids_of, baselines, steps, res.charts,
                                                          _rel(hist_path, results_dir), has_asv))
    res.charts["index.html"] = 0
    return res


def _rel(path: Path, base: Path) -> str:
    try:
        return str(Path(base.name) / path.resolve().relative_to(base.resolve()))
    except ValueError:
        return path.name
