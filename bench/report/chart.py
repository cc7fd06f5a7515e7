"""The dashboard's charts: inline SVG line charts over commits, and tiny sparklines.

:func:`svg_chart` draws one chart: its series (e.g. full and quick runs), the published value as a
dashed line, the baseline's regression band as a shaded rect, steps beyond tolerance ringed in red and,
for timings, a +-stddev bar per point.  :func:`runs_chart` builds the series from a list of runs (history
lines or ``make bench`` lines) and draws them; :func:`sparkline` is the small picture of a metric's
series in a table row.

The x axis is one slot per run.  Its labels are the short commit and the day (``5c2a280`` over ``12-03``,
:func:`axis_label`), thinned so that no two overlap whatever the number of runs: the label width in
viewBox units is estimated from its characters (monospace font, :data:`CHAR_W`) and only every k-th slot,
counted back from the latest run, is labelled, k the smallest stride that leaves :data:`LABEL_GAP` between
neighbours.  The chart scales with its box (viewBox), text included, so the check holds at any page width.
The full commit and date of each point are in its marker (``data-commit``, ``data-date``, tooltip).

No plotting library per chart (a page has hundreds of charts and matplotlib takes ~0.15 s each); tick
values come from :class:`matplotlib.ticker.MaxNLocator`.  Each chart is an ``<svg class="chart">`` with
``data-points`` (finite points drawn), checked in the browser by the pages' script
(:mod:`bench.report.html_page`): every series laid out, as many markers as declared, no two tick labels
overlapping.
"""
from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

__all__ = ["Series", "svg_chart", "runs_chart", "sparkline", "axis_label", "shown_labels", "fmt", "esc",
           "time_unit", "COLORS", "W", "H"]

COLORS = {"full": "#1f5fa8", "quick": "#e07b00",
          # the speed page: reproduce runs by mode and cache state, make bench by CPU model
          "full-cold": "#0b3d91", "full-warm": "#6fa8e8", "full-unrecorded": "#8a8a8a",
          "quick-cold": "#a04000", "quick-warm": "#f0b060", "quick-unrecorded": "#b5b5b5"}
PALETTE = ("#2a7f3a", "#7b3fa0", "#b8860b", "#c2185b", "#00838f", "#5d4037")  # make bench, one per CPU model
W, H = 440, 230                      # chart size (px, viewBox units)
ML, MR, MT, MB = 62, 34, 12, 46      # margins: left (y labels), right, top, bottom (2-line x labels)
XFONT = 9.0                          # x tick label font size (viewBox units; .xtick in the page CSS)
CHAR_W = 0.64                        # width of a character of the monospace x labels, in em (DejaVu Sans Mono 0.60)
LABEL_GAP = 6.0                      # at least this much space between two x labels (viewBox units)


@dataclass(frozen=True)
class Series:
    """One data series of a chart: ``slots`` are x positions (0..n_slots-1), NaN values leave gaps.

    ``runs`` are the points' runs (anything with ``commit`` and ``date``), ``marked`` the slots drawn as a
    step (red ring), ``errors`` an optional +-spread per point (drawn as a bar), ``color`` overrides
    :data:`COLORS` [mode]."""

    label: str
    mode: str
    slots: tuple[int, ...]
    values: tuple[float, ...]
    runs: tuple[Any, ...]
    marked: frozenset[int] = frozenset()
    errors: tuple[float, ...] = ()
    color: str = ""
    notes: tuple[str, ...] = ()        # per point, appended to its tooltip (e.g. "41 rounds")


def fmt(v: float, step: float | None = None) -> str:
    """A number for a label: with the decimals of ``step`` (a tick spacing) when given, else 4 digits."""
    if v == 0:
        return "0"
    if not math.isfinite(v):
        return str(v)
    if step is not None and step > 0 and 1e-4 <= abs(v) < 1e5 and step >= 1e-4:
        d = max(0, -int(math.floor(math.log10(step) + 1e-9)))
        return f"{v:.{d}f}"
    av = abs(v)
    return f"{v:.3e}" if av < 1e-3 or av >= 1e5 else f"{v:.4g}"


def esc(s: Any) -> str:
    return html.escape(str(s), quote=True)


def axis_label(commit: str, date: str) -> tuple[str, str]:
    """(short commit, day) of an x label: 7 hex digits (``+`` when the tree was dirty) and ``MM-DD``."""
    base, _, dirty = commit.partition("+")
    day = date[5:10] if len(date) >= 10 and date[4] == "-" else date[:5]
    return base[:7] + ("+" if dirty else ""), day


def _yticks(lo: float, hi: float) -> list[float]:
    from matplotlib.ticker import MaxNLocator

    if not hi > lo:
        pad = max(abs(lo) * 0.05, 1e-9)
        lo, hi = lo - pad, hi + pad
    return [float(t) for t in MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)]


def _tick_texts(ticks: Sequence[float]) -> list[str]:
    """Tick labels, with as many digits as it takes to tell neighbours apart."""
    step = ticks[1] - ticks[0] if len(ticks) > 1 else None
    texts = [fmt(t, step) for t in ticks]
    digits = 4
    while len(set(texts)) < len(texts) and digits < 12:
        digits += 1
        texts = ["0" if t == 0 else f"{t:.{digits}g}" for t in ticks]
    return texts


def shown_labels(n: int, label_chars: int, thin: bool = True) -> list[int]:
    """The slots that get an x label: every slot if they fit, else every k-th one counted back from the
    latest (always labelled), k the smallest stride whose spacing exceeds a label's width + the gap."""
    if n <= 0:
        return []
    if not thin or n == 1:
        return list(range(n))
    dx = (W - ML - MR) * 0.94 / (n - 1)
    need = label_chars * CHAR_W * XFONT + LABEL_GAP
    stride = max(1, math.ceil(need / dx - 1e-9))
    return sorted(range(n - 1, -1, -stride))


def _x(k: int, n: int) -> float:
    pw = W - ML - MR
    return ML + (pw / 2 if n <= 1 else pw * (0.03 + 0.94 * k / (n - 1)))


def svg_chart(chart_id: str, title: str, series: Sequence[Series], labels: Sequence[tuple[str, str, str]],
              published: float | None = None, band: tuple[float, float] | None = None,
              unit: str = "", scale: float = 1.0, thin: bool = True) -> str:
    """One inline SVG line chart.

    ``labels[slot] = (short commit, day, tooltip text)`` for each x slot; values are multiplied by
    ``scale`` for display (e.g. 1e3 for ms).  The published value is a dashed horizontal line
    (``class="published"``), the baseline regression band a rect (``class="band"``).  ``thin=False``
    labels every slot however crowded (for the test of the in-browser overlap check)."""
    n = len(labels)
    pts = [(k, v * scale) for s in series for k, v in zip(s.slots, s.values) if math.isfinite(v)]
    spread = [(v - e) * scale for s in series for v, e in zip(s.values, s.errors) if math.isfinite(v) and e > 0] + \
             [(v + e) * scale for s in series for v, e in zip(s.values, s.errors) if math.isfinite(v) and e > 0]
    pub = published * scale if published is not None and math.isfinite(published) else None
    bnd = (band[0] * scale, band[1] * scale) if band is not None else None
    allv = [v for _, v in pts] + spread + ([pub] if pub is not None else []) + (list(bnd) if bnd else [])
    lo, hi = (min(allv), max(allv)) if allv else (0.0, 1.0)
    ticks = _yticks(lo, hi)
    y0, y1 = ticks[0], ticks[-1]
    pw, ph = W - ML - MR, H - MT - MB

    def Y(v: float) -> float:
        return MT + ph * (1 - (v - y0) / (y1 - y0))

    out = [f'<svg class="chart" id="{esc(chart_id)}" data-metric="{esc(title)}" data-points="{len(pts)}" '
           f'data-published="{"" if pub is None else fmt(pub)}" viewBox="0 0 {W} {H}" width="{W}" height="{H}" '
           f'role="img" aria-label="{esc(title)}" xmlns="http://www.w3.org/2000/svg">',
           f"<title>{esc(title)}</title>",
           f'<rect class="frame" x="{ML}" y="{MT}" width="{pw}" height="{ph}"/>']
    for t, text in zip(ticks, _tick_texts(ticks)):
        yt = Y(t)
        out.append(f'<line class="grid" x1="{ML}" x2="{ML + pw}" y1="{yt:.2f}" y2="{yt:.2f}"/>'
                   f'<text class="ytick" x="{ML - 5}" y="{yt + 3.5:.2f}">{esc(text)}</text>')
    if unit:
        ym = MT + ph / 2
        out.append(f'<text class="unit" x="10" y="{ym:.2f}" transform="rotate(-90 10 {ym:.2f})">{esc(unit)}</text>')
    chars = max((max(len(a), len(b)) for a, b, _ in labels), default=0)
    for k in shown_labels(n, chars, thin):
        short, day, tip = labels[k]
        xk = _x(k, n)
        out.append(f'<text class="xtick" x="{xk:.2f}" y="{MT + ph + 14}"><title>{esc(tip)}</title>{esc(short)}'
                   f'<tspan x="{xk:.2f}" dy="11">{esc(day)}</tspan></text>')
    if bnd is not None:
        out.append(f'<rect class="band" x="{ML}" y="{Y(bnd[1]):.2f}" width="{pw}" '
                   f'height="{max(Y(bnd[0]) - Y(bnd[1]), 0.5):.2f}"><title>regression band of the baseline: '
                   f'{fmt(bnd[0])} .. {fmt(bnd[1])}</title></rect>')
    if pub is not None:
        yp = Y(pub)
        out.append(f'<line class="published" x1="{ML}" x2="{ML + pw}" y1="{yp:.2f}" y2="{yp:.2f}" '
                   f'data-value="{pub!r}"><title>published {fmt(pub)}</title></line>'
                   f'<text class="publabel" x="{ML + pw - 3}" y="{yp - 4:.2f}">published {esc(fmt(pub))}</text>')
    for s in series:
        out += _series(s, n, Y, unit, scale)
    out.append("</svg>")
    return "".join(out)


def _series(s: Series, n: int, Y: Callable[[float], float], unit: str, scale: float) -> list[str]:
    good = [i for i, v in enumerate(s.values) if math.isfinite(v)]
    if not good:
        return []
    color = s.color or COLORS.get(s.mode, "#444")
    out = [f'<g class="series series-{esc(s.mode)}" data-mode="{esc(s.mode)}" data-label="{esc(s.label)}" '
           f'style="stroke:{color};fill:{color}">']
    segs: list[list[str]] = [[]]
    for k, v in zip(s.slots, s.values):  # a NaN value breaks the line
        if math.isfinite(v):
            segs[-1].append(f"{_x(k, n):.2f},{Y(v * scale):.2f}")
        elif segs[-1]:
            segs.append([])
    for sg in segs:
        if len(sg) > 1:
            out.append(f'<polyline class="line" points="{" ".join(sg)}"/>')
    if s.errors:
        bars = [f"M{_x(s.slots[i], n):.2f} {Y((s.values[i] - s.errors[i]) * scale):.2f}"
                f"V{Y((s.values[i] + s.errors[i]) * scale):.2f}" for i in good if s.errors[i] > 0]
        if bars:
            out.append(f'<path class="err" d="{"".join(bars)}"/>')
    for i in good:
        k, v, run = s.slots[i], s.values[i] * scale, s.runs[i]
        cls = "pt step" if k in s.marked else "pt"
        err = f" ± {fmt(s.errors[i] * scale)}" if s.errors and s.errors[i] > 0 else ""
        note = f" · {s.notes[i]}" if s.notes and s.notes[i] else ""
        tip = f"{run.commit} · {run.date} · {s.label} · {fmt(v)}{err}{(' ' + unit) if unit else ''}{note}"
        out.append(f'<circle class="{cls}" cx="{_x(k, n):.2f}" cy="{Y(v):.2f}" r="3.2" data-value="{v!r}" '
                   f'data-commit="{esc(run.commit)}"><title>{esc(tip)}</title></circle>')
    out.append("</g>")
    return out


SeriesKey = Callable[[Any], "tuple[str, str, str]"]  # run -> (mode key, label, colour or "")


def runs_chart(chart_id: str, title: str, runs: Sequence[Any], value_of: Callable[[Any], float | None],
               series_of: SeriesKey, *, order: Sequence[str] = (), published: float | None = None,
               band: tuple[float, float] | None = None, unit: str = "", scale: float = 1.0,
               marked: Callable[[Any], bool] | None = None, error_of: Callable[[Any], float] | None = None,
               note_of: Callable[[Any], str] | None = None, thin: bool = True) -> tuple[str, int]:
    """Chart of ``value_of(run)`` (None: the run did not record it) over the runs that recorded it, one
    series per ``series_of(run)`` key (in ``order``, then by first appearance); (svg, finite points)."""
    rec = [(r, v) for r, v in ((r, value_of(r)) for r in runs) if v is not None]
    labels = [(*axis_label(r.commit, r.date), f"{r.commit} · {r.date}") for r, _ in rec]
    keys: dict[str, tuple[str, str]] = {}
    for r, _ in rec:
        key, label, color = series_of(r)
        keys.setdefault(key, (label, color))
    ordered = [k for k in order if k in keys] + [k for k in keys if k not in order]
    series = []
    for key in ordered:
        idx = [(k, r, v) for k, (r, v) in enumerate(rec) if series_of(r)[0] == key]
        series.append(Series(keys[key][0], key, tuple(k for k, _, _ in idx), tuple(v for _, _, v in idx),
                             tuple(r for _, r, _ in idx),
                             frozenset(k for k, r, _ in idx if marked is not None and marked(r)),
                             tuple(error_of(r) for _, r, _ in idx) if error_of else (),
                             keys[key][1], tuple(note_of(r) for _, r, _ in idx) if note_of else ()))
    svg = svg_chart(chart_id, title, series, labels, published=published, band=band, unit=unit, scale=scale,
                    thin=thin)
    return svg, sum(1 for _, v in rec if math.isfinite(v))


SW, SH = 150, 26  # sparkline size


def sparkline(spark_id: str, title: str, points: Sequence[tuple[int, float, str]], n_slots: int,
              tooltip: str) -> str:
    """A small inline SVG of a series: ``points`` are (slot, value, mode); one polyline per mode scaled to
    the series' own range, the latest point as a dot; ``tooltip`` (every run's value) on hover."""
    finite = [(k, v, m) for k, v, m in points if math.isfinite(v)]
    vals = [v for _, v, _ in finite]
    lo, hi = (min(vals), max(vals)) if vals else (0.0, 1.0)
    if not hi > lo:
        lo, hi = lo - 1.0, hi + 1.0

    def X(k: int) -> float:
        return 3 + (SW - 6) * (0.5 if n_slots <= 1 else k / (n_slots - 1))

    def Y(v: float) -> float:
        return SH - 3 - (SH - 6) * (v - lo) / (hi - lo)

    out = [f'<svg class="spark" id="{esc(spark_id)}" data-metric="{esc(title)}" data-points="{len(finite)}" '
           f'viewBox="0 0 {SW} {SH}" width="{SW}" height="{SH}" role="img" aria-label="{esc(title)}" '
           f'xmlns="http://www.w3.org/2000/svg"><title>{esc(tooltip)}</title>']
    for mode in dict.fromkeys(m for _, _, m in points):
        segs: list[list[str]] = [[]]
        for k, v, m in points:
            if m != mode:
                continue
            if math.isfinite(v):
                segs[-1].append(f"{X(k):.1f},{Y(v):.1f}")
            elif segs[-1]:
                segs.append([])
        color = COLORS.get(mode, "#444")
        for sg in segs:
            if len(sg) > 1:
                out.append(f'<polyline points="{" ".join(sg)}" style="stroke:{color}"/>')
            elif sg:
                x, y = sg[0].split(",")
                out.append(f'<circle cx="{x}" cy="{y}" r="1.6" style="fill:{color}"/>')
    if finite:
        k, v, m = max(finite, key=lambda p: p[0])
        out.append(f'<circle class="last" cx="{X(k):.1f}" cy="{Y(v):.1f}" r="2.2" '
                   f'style="fill:{COLORS.get(m, "#444")}"/>')
    out.append("</svg>")
    return "".join(out)


def time_unit(values: Sequence[float]) -> tuple[str, float]:
    """(unit, scale) so that the largest of ``values`` (seconds) reads >= 1."""
    finite = [abs(v) for v in values if math.isfinite(v)]
    top = max(finite) if finite else 1.0
    for unit, scale in (("s", 1.0), ("ms", 1e3), ("µs", 1e6)):
        if top * scale >= 1.0:
            return unit, scale
    return "ns", 1e9


def series_by_mode(run: Any) -> tuple[str, str, str]:
    """A history line's series on a metric chart: full or quick run."""
    return (run.mode, f"{run.mode} run", "")

