"""The dashboard's speed page: ``make bench`` over commits, and the reproduce's own timings.

* one chart per pytest-benchmark benchmark from ``results/bench_history.jsonl``
  (:mod:`bench.report.bench_history`: one line per ``make bench``): the mean per run with a +-stddev
  bar, one series per CPU model (timings of two machines are not comparable);
* the wall time of each ``skidbench reproduce`` and the seconds of each of its stages from
  ``history.jsonl``, one series per mode and cache state: cold (the run computed everything, empty run
  cache and nothing from the result cache: the ``cold`` field), warm, or not recorded (older lines).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

from bench.report.chart import COLORS, PALETTE, esc, fmt, runs_chart, time_unit
from bench.report.html_page import html_page

if TYPE_CHECKING:
    from bench.report.bench_history import BenchRun
    from bench.report.dashboard import Entry

__all__ = ["speed_page", "SERIES_ORDER"]

SERIES_ORDER = ("full-cold", "full-warm", "full-unrecorded", "quick-cold", "quick-warm", "quick-unrecorded")


def _cache_series(e: Entry) -> tuple[str, str, str]:
    state = "unrecorded" if e.cold is None else ("cold" if e.cold else "warm")
    label = f"{e.mode} run, " + {"cold": "cold (nothing cached)", "warm": "warm (caches used)",
                                 "unrecorded": "cache state not recorded"}[state]
    return f"{e.mode}-{state}", label, ""


def _legend_history() -> str:
    names = {"full-cold": "full, cold", "full-warm": "full, warm", "full-unrecorded": "full, cache state not recorded",
             "quick-cold": "quick, cold", "quick-warm": "quick, warm", "quick-unrecorded": "quick, not recorded"}
    return '<p class="legend">' + "".join(
        f'<span><i class="sw" style="background:{COLORS[k]}"></i>{esc(v)}</span>' for k, v in names.items()) + "</p>"


def _figure(svg: str, title: str, note: str) -> str:
    return f'<figure><figcaption><b>{esc(title)}</b> <span class="v">{esc(note)}</span></figcaption>{svg}</figure>'


def _bench_charts(runs: Sequence[BenchRun], thin: bool) -> list[str]:
    cpus = list(dict.fromkeys(r.cpu for r in runs))
    color = {c: PALETTE[i % len(PALETTE)] for i, c in enumerate(cpus)}
    figs = []
    for name in sorted({b for r in runs for b in r.benchmarks}):
        means = [r.benchmarks[name].mean for r in runs if name in r.benchmarks]
        unit, scale = time_unit(means)
        svg, n = runs_chart(
            "c-bench-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in name), name, runs,
            lambda r, b=name: r.benchmarks[b].mean if b in r.benchmarks else None,
            lambda r: (f"cpu{cpus.index(r.cpu)}", r.cpu or "CPU not recorded", color[r.cpu]),
            error_of=lambda r, b=name: r.benchmarks[b].stddev,
            note_of=lambda r, b=name: f"{r.benchmarks[b].rounds} rounds · {r.cpu}",
            unit=unit, scale=scale, thin=thin)
        if n:
            last = next(r for r in reversed(runs) if name in r.benchmarks)
            st = last.benchmarks[name]
            figs.append(_figure(svg, name, f"latest {fmt(st.mean * scale)} ± {fmt(st.stddev * scale)} {unit} "
                                           f"({st.rounds} rounds, {last.cpu})"))
    return figs


def speed_page(entries: Sequence[Entry], bench_runs: Sequence[BenchRun], nav: str, bench_source: str,
               thin: bool = True) -> tuple[str, int]:
    """The page and its number of charts."""
    body = ["<p>How fast the code is, per commit: the speed benchmarks of <code>make bench</code> "
            f"(pytest-benchmark, <code>tests/bench</code>; one line per run in <code>{esc(bench_source)}</code>), "
            "and the wall time of each <code>skidbench reproduce</code> with the seconds of each of its stages.</p>"]
    body += ["<h2>Reproduce wall time and stages (history.jsonl)</h2>", _legend_history()]
    rfigs = []
    secs = [e.seconds for e in entries if e.seconds is not None]
    if secs:
        unit, scale = time_unit(secs)
        svg, n = runs_chart("c-reproduce-wall-time", "reproduce wall time (the papers)", entries, lambda e: e.seconds,
                            _cache_series, order=SERIES_ORDER, unit=unit, scale=scale, thin=thin)
        if n:
            rfigs.append(_figure(svg, "reproduce wall time (the papers)", _latest(entries, lambda e: e.seconds, unit, scale)))
    for stage in sorted({k for e in entries for k in e.stages}):  # bench.reproduce.timing: per stage and run
        vals = [e.stages[stage] for e in entries if stage in e.stages]
        unit, scale = time_unit(vals)
        svg, n = runs_chart("c-stage-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in stage),
                            f"stage {stage}", entries, lambda e, k=stage: e.stages.get(k), _cache_series,
                            order=SERIES_ORDER, unit=unit, scale=scale, thin=thin)
        if n:
            rfigs.append(_figure(svg, f"stage {stage}", _latest(entries, lambda e, k=stage: e.stages.get(k),
                                                                unit, scale)))
    if not rfigs:
        body.append("<p>No reproduce timings in the history.</p>")
    body.append('<div class="charts">' + "".join(rfigs) + "</div>")
    body.append("<h2>Speed benchmarks (make bench)</h2>")
    figs = _bench_charts(bench_runs, thin)
    if figs:
        cpus = list(dict.fromkeys(r.cpu for r in bench_runs))
        body.append('<p class="legend">' + "".join(
            f'<span><i class="sw" style="background:{PALETTE[i % len(PALETTE)]}"></i>{esc(c or "CPU not recorded")}'
            "</span>" for i, c in enumerate(cpus))
            + '<span>bar: ± one standard deviation over the rounds</span></p>')
        body.append(f"<p>{len(figs)} benchmarks over {len(bench_runs)} runs of <code>make bench</code>; mean time "
                    "per call.</p>")
        body.append('<div class="charts">' + "".join(figs) + "</div>")
    else:
        body.append(f"<p>No speed history yet: <code>make bench</code> appends one line to <code>{esc(bench_source)}"
                    "</code> (or: <code>python -m bench.report.bench_history .benchmarks/latest.json</code> after "
                    "<code>pytest tests/bench --benchmark-only --benchmark-json=.benchmarks/latest.json</code>).</p>")
    return html_page("skidbench: speed over commits", body, nav), len(figs) + len(rfigs)


def _latest(entries: Sequence[Entry], value_of: Any, unit: str, scale: float) -> str:
    """Latest cold and warm value of the full runs (else of any run)."""
    parts = []
    for mode in ("full", "quick"):
        for state, want in (("cold", True), ("warm", False)):
            v = next((value_of(e) for e in reversed(entries)
                      if e.mode == mode and e.cold is want and value_of(e) is not None), None)
            if v is not None:
                parts.append(f"{mode} {state} {fmt(v * scale)} {unit}")
    if parts:
        return "latest: " + ", ".join(parts)
    v = next((value_of(e) for e in reversed(entries) if value_of(e) is not None), None)
    return f"latest {fmt(v * scale)} {unit}" if v is not None else ""
