"""The dashboard's metric finder (``metrics.html``): every metric id, grouped by paper and table, each a
link to its chart (or compact row) on the table page that holds it, with its latest value and how
often it moved beyond tolerance.  A filter box (inline JavaScript, :data:`bench.report.html_page.FILTER_JS`:
space-separated words, all must occur in the id; ``metrics.html#q=nees`` pre-fills it) narrows the list;
without JavaScript the box is hidden and the page is the plain list.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from bench.report.chart import esc, fmt
from bench.report.html_page import FILTER_JS, html_page

__all__ = ["MetricLocation", "metric_index_page"]

KIND_TEXT = {"chart": "chart", "row": "compact row", "none": "no finite value"}


@dataclass(frozen=True)
class MetricLocation:
    """Where a metric is shown: ``page`` and ``anchor`` (the element id), as a chart, a compact row with a
    sparkline, or in the list of metrics without a finite value ("none")."""

    metric: str
    table: str
    page: str
    anchor: str
    kind: str
    latest: float | None
    moved: int  # steps beyond tolerance in its history

    @property
    def href(self) -> str:
        return f"{self.page}#{self.anchor}"


def metric_index_page(locations: Sequence[MetricLocation], nav: str) -> str:
    """The page: a heading per table, under it the metrics as a list of links."""
    body = [f"<p>All {len(locations)} metrics. Each links to its chart; a metric of a large table that never "
            "moved beyond its tolerance is a compact row with a sparkline (hover it for every run's value). "
            "Type words of a metric id to filter the list.</p>",
            '<p><input id="metric-filter" type="search" placeholder="filter: e.g. nees mi_ukf" hidden '
            'aria-label="filter the metrics"> <span id="metric-count" class="v"></span></p>',
            '<div id="metric-list">']
    by_table: dict[str, list[MetricLocation]] = {}
    for loc in sorted(locations, key=lambda x: x.metric):
        by_table.setdefault(loc.table, []).append(loc)
    for table in sorted(by_table):
        locs = by_table[table]
        body.append(f'<h3 id="t-{esc(table)}">{esc(table)} <span class="v">({len(locs)})</span></h3><ul class="metrics">')
        for loc in locs:
            latest = "" if loc.latest is None else f" latest {fmt(loc.latest)}"
            moved = f", moved {loc.moved}×" if loc.moved else ""
            body.append(f'<li data-id="{esc(loc.metric)}"><a href="{esc(loc.href)}">{esc(loc.metric)}</a>'
                        f' <span class="v">{esc(KIND_TEXT[loc.kind])}{esc(latest)}{esc(moved)}</span></li>')
        body.append("</ul>")
    body.append("</div>")
    return html_page("skidbench: find a metric", body, nav, scripts=[FILTER_JS])
