"""The dashboard's charts: one inline SVG line chart per metric over the reproduce runs (full and quick
runs as two series, the published value as a dashed line, the baseline's regression band as a shaded
rect, steps beyond tolerance ringed in red).

The SVG is written here (no plotting call per chart: a page has hundreds of charts and matplotlib takes
~0.15 s each); tick positions come from :class:`matplotlib.ticker.MaxNLocator`.  Each chart is an
``<svg class="chart">`` with ``data-points`` (finite points drawn), checked in the browser by the
pages' script (:mod:`bench.report.dashboard`).
"""
from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence

if TYPE_CHECKING:
    from bench.report.dashboard import Entry, Step

__all__ = ["Series", "svg_chart"]

COLORS = {"full": "#1f5fa8", "quick": "#e07b00"}
W, H = 440, 230                      # chart size (px, viewBox units)
ML, MR, MT, MB = 62, 34, 12, 46      # margins: left (y labels), right, top, bottom (2-line x labels)
MAX_XLABELS = 7


@dataclass(frozen=True)
class Series:
    """One data series of a chart: ``slots`` are x positions (0..n_slots-1), NaN values leave gaps."""

    label: str
    mode: str
    slots: tuple[int, ...]
    values: tuple[float, ...]
    entries: tuple[Entry, ...]
    marked: frozenset[int] = frozenset()   # slots drawn as a step (red ring)


def _fmt(v: float, step: float | None = None) -> str:
    if v == 0:
        return "0"
    if step is not None and step > 0 and 1e-4 <= abs(v) < 1e5 and step >= 1e-4:
        d = max(0, -int(math.floor(math.log10(step) + 1e-9)))
        return f"{v:.{d}f}"
    av = abs(v)
    return f"{v:.3e}" if av < 1e-3 or av >= 1e5 else f"{v:.4g}"


def _esc(s: Any) -> str:
    return html.escape(str(s), quote=True)


def _yticks(lo: float, hi: float) -> list[float]:
    from matplotlib.ticker import MaxNLocator

    if not hi > lo:
        pad = max(abs(lo) * 0.05, 1e-9)
        lo, hi = lo - pad, hi + pad
    ticks = [float(t) for t in MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)]
    return ticks


def svg_chart(chart_id: str, title: str, series: Sequence[Series], labels: Sequence[tuple[str, str, str]],
              published: float | None = None, band: tuple[float, float] | None = None,
              unit: str = "", scale: float = 1.0) -> str:
    """One inline SVG line chart.

    ``labels[slot] = (short commit, date, full tooltip text)`` for each x slot; values are multiplied
    by ``scale`` for display (e.g. 1e3 for ms).  The published value is a dashed horizontal line
    (``class="published"``), the baseline regression band a rect (``class="band"``)."""
    n = len(labels)
    pts = [(s, k, v * scale) for s in series for k, v in zip(s.slots, s.values) if math.isfinite(v)]
    ys = [v for _, _, v in pts]
    pub = published * scale if published is not None and math.isfinite(published) else None
    bnd = (band[0] * scale, band[1] * scale) if band is not None else None
    extra = ([pub] if pub is not None else []) + (list(bnd) if bnd else [])
    allv = ys + extra
    lo, hi = (min(allv), max(allv)) if allv else (0.0, 1.0)
    ticks = _yticks(lo, hi)
    y0, y1 = ticks[0], ticks[-1]
    step = ticks[1] - ticks[0] if len(ticks) > 1 else None
    pw, ph = W - ML - MR, H - MT - MB

    def X(k: int) -> float:
        return ML + (pw / 2 if n <= 1 else pw * (0.03 + 0.94 * k / (n - 1)))

    def Y(v: float) -> float:
        return MT + ph * (1 - (v - y0) / (y1 - y0))

    out = [f'<svg class="chart" id="{_esc(chart_id)}" data-metric="{_esc(title)}" data-points="{len(pts)}" '
           f'data-published="{"" if pub is None else _fmt(pub)}" viewBox="0 0 {W} {H}" width="{W}" height="{H}" '
           f'role="img" aria-label="{_esc(title)}" xmlns="http://www.w3.org/2000/svg">',
           f"<title>{_esc(title)}</title>",
           f'<rect class="frame" x="{ML}" y="{MT}" width="{pw}" height="{ph}"/>']
    for t in ticks:
        yt = Y(t)
        out.append(f'<line class="grid" x1="{ML}" x2="{ML + pw}" y1="{yt:.2f}" y2="{yt:.2f}"/>'
                   f'<text class="ytick" x="{ML - 5}" y="{yt + 3.5:.2f}">{_esc(_fmt(t, step))}</text>')
    if unit:
        ym = MT + ph / 2
        out.append(f'<text class="unit" x="12" y="{ym:.2f}" transform="rotate(-90 12 {ym:.2f})">{_esc(unit)}</text>')
    every = max(1, math.ceil(n / MAX_XLABELS))
    shown = [k for k in range(n) if k % every == 0 or k == n - 1]
    if len(shown) > 1 and shown[-1] - shown[-2] < every:  # keep the last label, drop a crowding one
        shown.pop(-2)
    for k in shown:
        short, day, _tip = labels[k]
        out.append(f'<text class="xtick" x="{X(k):.2f}" y="{MT + ph + 14}">{_esc(short)}'
                   f'<tspan x="{X(k):.2f}" dy="12">{_esc(day)}</tspan></text>')
    if bnd is not None:
        out.append(f'<rect class="band" x="{ML}" y="{Y(bnd[1]):.2f}" width="{pw}" '
                   f'height="{max(Y(bnd[0]) - Y(bnd[1]), 0.5):.2f}"><title>regression band of the baseline: '
                   f'{_fmt(bnd[0])} .. {_fmt(bnd[1])}</title></rect>')
    if pub is not None:
        yp = Y(pub)
        out.append(f'<line class="published" x1="{ML}" x2="{ML + pw}" y1="{yp:.2f}" y2="{yp:.2f}" '
                   f'data-value="{pub!r}"><title>published {_fmt(pub)}</title></line>'
                   f'<text class="publabel" x="{ML + pw - 3}" y="{yp - 4:.2f}">published {_esc(_fmt(pub))}</text>')
    for s in series:
        good = [(k, v * scale, e) for k, v, e in zip(s.slots, s.values, s.entries) if math.isfinite(v)]
        if not good:
            continue
        out.append(f'<g class="series series-{_esc(s.mode)}" data-mode="{_esc(s.mode)}" '
                   f'style="stroke:{COLORS.get(s.mode, "#444")};fill:{COLORS.get(s.mode, "#444")}">')
        seg: list[str] = []
        segs: list[list[str]] = []
        for k, v in zip(s.slots, s.values):  # a NaN value breaks the line
            if math.isfinite(v):
                seg.append(f"{X(k):.2f},{Y(v * scale):.2f}")
            elif seg:
                segs.append(seg)
                seg = []
        if seg:
            segs.append(seg)
        for sg in segs:
            if len(sg) > 1:
                out.append(f'<polyline class="line" points="{" ".join(sg)}"/>')
        for k, v, e in good:
            cls = "pt step" if k in s.marked else "pt"
            tip = f"{labels[k][2]} · {s.label} · {_fmt(v)}{(' ' + unit) if unit else ''}"
            out.append(f'<circle class="{cls}" cx="{X(k):.2f}" cy="{Y(v):.2f}" r="3.2" data-value="{v!r}" '
                       f'data-commit="{_esc(e.commit)}"><title>{_esc(tip)}</title></circle>')
        out.append("</g>")
    out.append("</svg>")
    return "".join(out)


def _chart_for(chart_id: str, title: str, entries: Sequence[Entry], values_of, *, published: float | None = None,
               band: tuple[float, float] | None = None, unit: str = "", scale: float = 1.0,
               steps: Mapping[tuple[str, int], Step] | None = None, key: str = "") -> tuple[str, int]:
    """Chart of ``values_of(entry)`` (None: the run did not record it) over the runs that recorded it."""
    runs = [(e, values_of(e)) for e in entries]
    runs = [(e, v) for e, v in runs if v is not None]
    labels = [(e.short, e.day, f"{e.commit} · {e.date}") for e, _ in runs]
    series = []
    for mode in ("full", "quick"):
        idx = [(k, e, v) for k, (e, v) in enumerate(runs) if e.mode == mode]
        if not idx:
            continue
        marked = frozenset(k for k, e, _ in idx if steps and (key, e.index) in steps)
        series.append(Series(f"{mode} run", mode, tuple(k for k, _, _ in idx), tuple(v for _, _, v in idx),
                             tuple(e for _, e, _ in idx), marked))
    svg = svg_chart(chart_id, title, series, labels, published=published, band=band, unit=unit, scale=scale)
    return svg, sum(1 for _, v in runs if math.isfinite(v))


def _chart_id(key: str) -> str:
    return "c-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in key)


def _time_unit(values: Sequence[float]) -> tuple[str, float]:
    finite = [abs(v) for v in values if math.isfinite(v)]
    top = max(finite) if finite else 1.0
    for unit, scale in (("s", 1.0), ("ms", 1e3), ("µs", 1e6)):
        if top * scale >= 1.0:
            return unit, scale
    return "ns", 1e9
