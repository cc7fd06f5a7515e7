"""Changes beyond tolerance between consecutive runs, and their grouping by commit pair.

:func:`find_steps` applies :func:`bench.cli.reproduce.compare_metrics` (the rule of ``skidbench compare``)
to every pair of consecutive runs of the same mode that both ran a paper, with each metric's tolerance
from the baseline metrics.json.  A real history has thousands of them (a refactor moves hundreds of
metrics at once), so the pages show them grouped: :func:`group_steps` makes one :class:`StepGroup` per
(before, after, mode) and :func:`pairs_table` one row per group with the number of metrics that moved,
the count per table and a collapsible ``<details>`` list of the metrics (the first :data:`MAX_LISTED`,
then "and N more"; each metric links to its chart).  :func:`summary_table` is the index page's view:
one row per commit pair with the count per paper.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from bench.report.chart import esc, fmt

if TYPE_CHECKING:
    from bench.report.dashboard import Entry

__all__ = ["Step", "StepGroup", "find_steps", "group_steps", "pairs_table", "summary_table", "MAX_LISTED",
           "DEFAULT_TOLERANCE", "table_key"]

DEFAULT_TOLERANCE: Mapping[str, float] = {"rel": 0.05, "abs": 1e-6}  # bench.reproduce's default
MAX_LISTED = 50  # metrics listed per commit pair


def table_key(metric: str) -> str:
    """``paper.table`` of a metric id ``paper.table.name`` (``paper`` for a two-part id)."""
    parts = metric.split(".")
    return ".".join(parts[:2]) if len(parts) >= 3 else parts[0]


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

    @property
    def vanished(self) -> bool:
        """The metric is missing in the later run (not a change of its value)."""
        return self.why.startswith("missing")


@dataclass(frozen=True)
class StepGroup:
    """The steps between one pair of runs (before -> after, one mode)."""

    before: Entry
    after: Entry
    mode: str
    steps: tuple[Step, ...]

    @property
    def anchor(self) -> str:
        return f"pair-{self.before.index}-{self.after.index}-{self.mode}"

    def per_table(self) -> list[tuple[str, int]]:
        """(paper.table, metrics) sorted by count, then name."""
        c = Counter(table_key(s.metric) for s in self.steps)
        return sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))

    def per_paper(self) -> dict[str, int]:
        return dict(Counter(s.metric.split(".", 1)[0] for s in self.steps))


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


def group_steps(steps: Sequence[Step]) -> list[StepGroup]:
    """One group per (before run, after run, mode), newest first; the steps of a group sorted by metric."""
    groups: dict[tuple[int, int, str], list[Step]] = {}
    for s in steps:
        groups.setdefault((s.before.index, s.after.index, s.mode), []).append(s)
    out = [StepGroup(v[0].before, v[0].after, v[0].mode, tuple(sorted(v, key=lambda s: s.metric)))
           for v in groups.values()]
    return sorted(out, key=lambda g: (-g.after.index, -g.before.index, g.mode))


def _commit(e: Entry) -> str:
    return f'<code title="{esc(e.commit)} · {esc(e.date)}">{esc(e.short)}</code> {esc(e.day)}'


def _pair_cells(g: StepGroup) -> str:
    return (f'<td class="c">{_commit(g.before)}</td><td class="c">{_commit(g.after)}</td><td>{g.mode}</td>'
            f'<td class="num">{len(g.steps)}</td>')


def pairs_table(groups: Sequence[StepGroup], href_of: Callable[[str], str], table_href: Callable[[str], str],
                cap: int = MAX_LISTED) -> list[str]:
    """One row per commit pair: the two commits, mode, metrics moved, per table counts (links to the
    table pages) and a ``<details>`` with the first ``cap`` metrics (link to the chart: ``href_of(metric)``)."""
    if not groups:
        return ["<p>None: no metric moved beyond its tolerance between consecutive runs of the same mode.</p>"]
    rows = ['<table class="pairs"><tr><th>from</th><th>to</th><th>mode</th><th>metrics</th><th>per table</th>'
            "<th>metrics that moved</th></tr>"]
    for g in groups:
        tables = ", ".join(f'<a href="{esc(table_href(t))}">{esc(t)}</a>&nbsp;{n}' for t, n in g.per_table())
        items = []
        for s in g.steps[:cap]:
            new = "—" if s.new is None else esc(fmt(s.new))
            items.append(f'<tr class="moved" data-metric="{esc(s.metric)}"><td><a href="{esc(href_of(s.metric))}">'
                         f'{esc(s.metric)}</a></td><td class="num">{esc(fmt(s.old))}</td><td class="num">{new}</td>'
                         f"<td>{esc(s.why)}</td></tr>")
        more = len(g.steps) - cap
        vanished = sum(1 for s in g.steps if s.vanished)
        note = f" ({vanished} missing in the later run)" if vanished else ""
        rows.append(f'<tr class="pair" id="{g.anchor}" data-before="{esc(g.before.commit)}" '
                    f'data-after="{esc(g.after.commit)}" data-mode="{g.mode}" data-count="{len(g.steps)}">'
                    f"{_pair_cells(g)}<td>{tables}</td><td><details><summary>{len(g.steps)} metrics{note}</summary>"
                    "<table><tr><th>metric</th><th>before</th><th>after</th><th>change</th></tr>" + "".join(items)
                    + "</table>" + (f"<p>and {more} more (see the table pages)</p>" if more > 0 else "")
                    + "</details></td></tr>")
    rows.append("</table>")
    return rows


def summary_table(groups: Sequence[StepGroup], papers: Sequence[str], paper_href: Callable[[str], str]) -> list[str]:
    """The index page's view: one row per commit pair across papers, the metrics moved per paper (each a
    link to that paper's row of the pair)."""
    if not groups:
        return ["<p>None: no metric moved beyond its tolerance between consecutive runs of the same mode.</p>"]
    head = "".join(f"<th>{esc(p)}</th>" for p in papers)
    rows = [f'<table class="pairs"><tr><th>from</th><th>to</th><th>mode</th><th>metrics</th>{head}'
            "<th>largest tables</th></tr>"]
    for g in groups:
        per = g.per_paper()
        cells = "".join(f'<td class="num"><a href="{esc(paper_href(p))}#{g.anchor}">{per[p]}</a></td>' if p in per
                        else '<td class="num"></td>' for p in papers)
        top = ", ".join(f"{esc(t)}&nbsp;{n}" for t, n in g.per_table()[:3])
        rows.append(f'<tr class="pair" id="{g.anchor}" data-before="{esc(g.before.commit)}" '
                    f'data-after="{esc(g.after.commit)}" data-mode="{g.mode}" data-count="{len(g.steps)}">'
                    f"{_pair_cells(g)}{cells}<td>{top}</td></tr>")
    rows.append("</table>")
    return rows
