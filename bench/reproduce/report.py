"""Writing the results: per paper its claims, tables (markdown and CSV) and README (``results/<paper>/``); for a
reproduce, ``metrics.json`` (the regression baseline), ``claims.json`` (every claim's verdict), ``REPORT.md`` with
the links to the extras' results, and one line of ``history.jsonl``.  Every file is written atomically.

Layout (a reader starts from the verdicts, details are one link away):

* ``REPORT.md``: ONE table of every paper's headline claims (paper | claim | verdict | cause | key numbers), then
  a short summary per paper (headline claims holding / failing by cause / calibration targets, the other claims,
  the checks beyond the paper apart) linking ``<paper>/README.md``; under 300 lines.
* ``<paper>/README.md``: its headline claims, the other claims of the paper, the checks beyond the paper (each:
  verdict, measured numbers, the result that would fail it, where its tolerance comes from, cause or note), then
  the links to the per-table files and figures.
* ``<paper>/claims_details.md``: per claim (anchor ``claim-<id>``) the quote, the numbers and the whole note of the
  compute functions; ``<paper>/claims.md``: the three claims tables; ``<paper>/<table>.md|csv``: one per table.

No table cell is longer than :data:`CELL_LIMIT` characters: a longer text is shortened and linked to its details.
"""
from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

from bench.report.cells import CELL_LIMIT, cell, long_cells
from bench.report.io import atomic_write_json, atomic_write_text, dumps_json
from bench.reproduce.claims import _fmt, row_ratio
from bench.reproduce.provenance import compiled_extensions, git_commit, package_versions
from bench.paths import default_results
from bench.reproduce.runner import REPO, Runner

if TYPE_CHECKING:
    from bench.reproduce.paper import PaperResult

__all__ = ["CELL_LIMIT", "cell", "long_cells", "paper_markdown", "claims_details", "write_paper", "metrics_document",
           "claims_document", "write_report", "EXTRA_RESULTS", "link_extras", "append_history"]

DETAILS = "claims_details.md"


# ------------------------------------------------------------------------------------------ tables
def _real_robot(tab: Mapping[str, Any]) -> bool:
    return tab.get("published_on") == "real robot"


def _table_md(tab: Mapping[str, Any], notes: Mapping[str, str]) -> str:
    lines = [f"### {tab.get('title', tab['id'])}", "", f"Source: {tab.get('source', '')}", ""]
    if _real_robot(tab):
        lines += ["Published numbers measured on a real robot: shown beside ours as the ratio reproduced / "
                  "published, never scored.", "",
                  "| quantity | reproduced | published (real robot) | reproduced / published |", "|---|---|---|---|"]
        for r in tab["rows_out"]:
            lines.append(f"| {cell(r.get('label', r['metric']))} | {_fmt(r['reproduced'])} | {_fmt(r.get('published'))}"
                         f" | {_fmt(row_ratio(r['reproduced'], r.get('published')))} |")
    elif tab["rows_out"]:
        lines += ["| quantity | reproduced | published | verdict |", "|---|---|---|---|"]
        for r in tab["rows_out"]:
            lines.append(f"| {cell(r.get('label', r['metric']))} | {_fmt(r['reproduced'])} | {_fmt(r.get('published'))}"
                         f" | {cell(r['verdict'])} |")
    else:
        lines += ["| metric | reproduced |", "|---|---|"]
        for k, v in tab["all_metrics"].items():
            lines.append(f"| {cell(k)} | {cell(_fmt(v))} |")
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


def _table_summary(tab: Mapping[str, Any]) -> str:
    rows = tab["rows_out"]
    if _real_robot(tab):
        return f"{len(rows)} numbers published on a real robot (ratios, not scored)"
    if not rows:
        return f"{len(tab['all_metrics'])} metrics"
    match = sum(str(r["verdict"]).startswith("matches") for r in rows)
    differ = sum(str(r["verdict"]).startswith("differs") for r in rows)
    return f"{len(rows)} rows: {match} match, {differ} differ"


# ------------------------------------------------------------------------------------------ claims
_BOLD = {"holds": "**holds**", "does not hold": "**does not hold**"}


def _groups(claims: Iterable[Mapping[str, Any]]) -> dict[str, list[Mapping[str, Any]]]:
    """headline / other (claims of the paper) / beyond (our own checks), in declaration order."""
    out: dict[str, list[Mapping[str, Any]]] = {"headline": [], "other": [], "beyond": []}
    for c in claims:
        key = "beyond" if c.get("scope", "paper") == "beyond" else ("headline" if c.get("headline") else "other")
        out[key].append(c)
    return out


NOT_REFUTED = "not refuted: inside its 95 % interval"  # the claim's margin: over seeds, or over segments (Mandow)
NOT_RESOLVED = "not refuted: the means favour the claim, inside its 95 % interval"


def _verdict(c: Mapping[str, Any]) -> str:
    v = c.get("verdict") or {True: "holds", False: "does not hold", None: "not evaluated"}[c["holds"]]
    if v != "does not hold" or c.get("refuted") is not False:
        return _BOLD.get(v, v)
    return _BOLD.get(v, v) + f" ({NOT_RESOLVED if c.get('favours') else NOT_REFUTED})"


def _cause_head(cause: Mapping[str, Any]) -> str:
    """A cause's kind, whose reason it is when a quick run shows the full run's (``cause["of"]``), and a mark when
    this run's numbers contradict a relation its words state (``cause["stale"]``:
    :func:`bench.reproduce.claims.stale_relations`)."""
    head = f"{cause['kind']} ({cause['of']})" if cause.get("of") else str(cause["kind"])
    return f"{head}, **stale: this run's numbers contradict its words**" if cause.get("stale") else head


def _cause(c: Mapping[str, Any], more: str | None, with_note: bool = True) -> str:
    """What explains the verdict: the chosen parameter of a calibration target, the cause of a failing claim
    (or that none is given), else (``with_note``) the compute functions' note, shortened and linked."""
    v = c.get("verdict")
    if v == "calibration target":
        names = ", ".join(p["parameter"] for p in c.get("calibration", []))
        alone = {True: "holds", False: "does not hold"}.get(c["holds"], "not evaluated")
        return cell(f"parameter chosen for this outcome: {names} (the numbers alone: {alone})", more)
    if c["holds"] is False and c.get("cause"):
        return cell(f"{_cause_head(c['cause'])}: {c['cause']['text']}", more)
    if c["holds"] is False and c.get("scope", "paper") == "paper":
        note = f"; note: {c['why']}" if with_note and c.get("why") else ""
        return cell(f"**no cause given**{note}", more)
    if c["holds"] is None:
        return cell(c.get("why", ""), more) if with_note else "—"
    return cell(c.get("why", ""), more) if with_note else ""


def _claims_table(claims: list[Mapping[str, Any]], details: str, beyond: bool = False) -> list[str]:
    head = "check" if beyond else "claim"
    lines = [f"| {head} | source | verdict | measured | fails if | tolerance from | cause / note |",
             "|---|---|---|---|---|---|---|"]
    for c in claims:
        more = f"{details}#claim-{c['id']}"
        lines.append(f"| {cell(c['text'], more)} | {cell(c.get('source', ''), more)} | {_verdict(c)} "
                     f"| {cell(c['measured'], more)} | {cell(c.get('fails_if', ''), more)} "
                     f"| {cell(c.get('tolerance_origin', '—' if _no_tolerance(c) else '**not stated**'), more)} "
                     f"| {_cause(c, more)} |")
    return lines


def _no_tolerance(c: Mapping[str, Any]) -> bool:
    from bench.reproduce.claims import needs_tolerance_origin

    return c.get("scope", "paper") == "beyond" or needs_tolerance_origin(c) is None


def _claims_sections(res: PaperResult, details: str) -> list[str]:
    g = _groups(res.claims)
    out = ["### Headline claims", ""]
    out += _claims_table(g["headline"], details) if g["headline"] else ["No claim of this paper is marked headline."]
    out += ["", "### Other claims of the paper", ""]
    out += _claims_table(g["other"], details) if g["other"] else ["None."]
    if g["beyond"]:
        out += ["", "### Checks beyond the paper (ours; never counted among the paper's claims)", ""]
        out += _claims_table(g["beyond"], details, beyond=True)
    return out + [""]


def _claims_md(res: PaperResult) -> str:
    return "\n".join(_claims_sections(res, DETAILS)) + "\n"


def _sensitivity_doc(results_dir: Path) -> dict[str, Any]:
    """The last extended run's sensitivity study (``<results_dir>/extended/sensitivity.json``), {} when absent."""
    try:
        doc = json.loads((Path(results_dir) / "extended" / "sensitivity.json").read_text())
        return doc if isinstance(doc, dict) else {}
    except (OSError, ValueError):
        return {}


def _decided(doc: Mapping[str, Any]) -> list[tuple[Mapping[str, Any], Mapping[str, Any]]]:
    """(choice, flip) of each verdict a choice changes that is not a calibration target (KeyError or TypeError on a
    malformed document)."""
    return [(c, r) for c in doc["choices"] for r in c["flips"] if not r["target"]]


def decided_lines(results_dir: Path) -> dict[str, list[str]]:
    """{claim: a line per chosen parameter whose alternative changes its verdict} from the last extended run's
    sensitivity study (``<results_dir>/extended/sensitivity.json``; none when it has not run), for the claims that are
    not calibration targets: what the verdict becomes and the numbers it is computed from."""
    doc = _sensitivity_doc(results_dir)
    try:
        out: dict[str, list[str]] = {}
        for c, r in _decided(doc):
            at = ", ".join(f"{e['name']} = {e['alternative']!r}" for e in c["edits"])
            why = f"chosen for {', '.join(c['claims'])}" if c["claims"] else "a testbed choice, no claim in view"
            out.setdefault(r["claim"], []).append(
                f"- decided by a testbed choice: at {at} ({why}) it "
                f"{r['alternative']}: {r['alternative_measured']} ([the sensitivity study](../"
                f"{SENSITIVITY_LINK}), commit `{str(doc.get('commit', '?'))[:12]}`)")
        return out
    except (KeyError, TypeError):
        return {}


def claims_details(res: PaperResult, decided: Mapping[str, list[str]] | None = None) -> str:
    """Every claim in full: quote, numbers, the result that would fail it, cause, calibration, the whole note;
    ``decided``: :func:`decided_lines`."""
    decided = decided or {}
    out = [f"# {res.paper}: claims in detail", "", "Back to the [paper's summary](README.md).", ""]
    for c in res.claims:
        scope = "check beyond the paper" if c.get("scope", "paper") == "beyond" else (
            "headline claim" if c.get("headline") else "claim of the paper")
        out += [f'<a id="claim-{c["id"]}"></a>', "", f"## {c['id']}: {c['text']}", "",
                f"- {scope}, {c['kind']}; verdict: {_verdict(c)}", f"- source: {c.get('source', '—')}"]
        if c.get("quote"):
            out.append(f"- the paper: \"{c['quote']}\"")
        out += [f"- measured: {c['measured']}", f"- fails if: {c.get('fails_if', '')}"]
        if c.get("fails_if_engine") and c.get("fails_if_engine") != c.get("fails_if"):
            out.append(f"- fails if (from the kind and numbers): {c['fails_if_engine']}")
        if c.get("tolerance_origin"):
            out.append(f"- tolerance from: {c['tolerance_origin']}")
        if c.get("cause"):
            out.append(f"- cause ({_cause_head(c['cause'])}): {c['cause']['text']}")
            out += [f"- not met by this run: {rel}" for rel in c["cause"].get("stale", [])]
        for p in c.get("calibration", []):
            out.append(f"- calibration target: {p['parameter']} ({p['file']}) was chosen for it: {p['ref']}")
        out += decided.get(f"{res.paper}.{c['id']}", [])
        if c.get("why"):
            out += ["", c["why"].strip()]
        out.append("")
    return "\n".join(out)


def _seeds_line(res: PaperResult) -> str:
    seeds = res.info.get("seeds")
    return (f"Seeds: {seeds}; {len(res.info.get('runs', []))} simulated runs (listed with their content hashes in "
            "runs_manifest.json).") if seeds else ""


def paper_markdown(res: PaperResult, link_prefix: str = "") -> str:
    """``<paper>/README.md``: headline claims first, then the other claims, the checks beyond the paper, the
    per-table files and the figures (``link_prefix``: from the README's folder to ``results/``)."""
    d = res.decl
    out = [f"## {d.get('title', res.paper)}", ""] + ([f"*{d['citation']}*", ""] if d.get("citation") else [])
    out += _claims_sections(res, DETAILS)
    out += [f"Every claim in full (quote, numbers, notes): [{DETAILS}]({DETAILS}).", ""]
    if d.get("note"):
        out += ["### Setup", "", f"> {d['note'].strip()}", ""]
    out += ["### Tables", ""]
    for tab in res.tables:
        src = f" ({tab['source']})" if tab.get("source") else ""
        out.append(f"- [{tab.get('title', tab['id'])}]({tab['id']}.md){src} ([csv]({tab['id']}.csv)): "
                   f"{_table_summary(tab)}")
    out.append("")
    if res.figures:
        out += ["### Figures", ""]
        for path, caption in res.figures:
            out.append(f"- [{caption}]({link_prefix}{path})")
        out.append("")
    if line := _seeds_line(res):
        out += [line, ""]
    return "\n".join(out)


def write_paper(res: PaperResult, out_dir: Path) -> None:
    for tab in res.tables:
        atomic_write_text(out_dir / f"{tab['id']}.md", _table_md(tab, res.notes))
        atomic_write_text(out_dir / f"{tab['id']}.csv", _table_csv(tab))
    atomic_write_text(out_dir / "claims.md", _claims_md(res))
    atomic_write_text(out_dir / DETAILS, claims_details(res, decided_lines(Path(out_dir).parent)))
    atomic_write_text(out_dir / "README.md", paper_markdown(res, link_prefix="../"))


# ------------------------------------------------------------------------------------------ documents
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
                "tolerance": {**default_tol, **res.decl.get("metric_tolerance", {}).get(mid, {}),
                              **res.info.get("metric_tolerance", {}).get(mid, {})},
            }
    return {"quick": quick, "commit": git_commit(), "metrics": dict(sorted(metrics.items()))}


def claims_document(results: list[PaperResult], quick: bool) -> dict[str, Any]:
    """``claims.json``: every claim's verdict by ``<paper>.<claim id>`` (scope, headline, cause, calibration)."""
    claims = {}
    for res in results:
        for c in res.claims:
            claims[f"{res.paper}.{c['id']}"] = {
                "verdict": c.get("verdict"), "holds": c["holds"], "refuted": c.get("refuted"), "favours": c.get("favours"),
                "scope": c.get("scope", "paper"),
                "headline": bool(c.get("headline")), "kind": c["kind"], "measured": c["measured"],
                "fails_if": c.get("fails_if"), "cause": c.get("cause") if c["holds"] is False else None,
                "calibration": [p["parameter"] for p in c.get("calibration", [])],
            }
    return {"quick": quick, "commit": git_commit(), "claims": claims}


def _counts(claims: list[Mapping[str, Any]], causes: bool = True) -> str:
    """"holding 3; failing 2 (method 1, no cause given 1, 1 of them not refuted (inside the interval));
    calibration targets 1; not evaluated 1"."""
    if not claims:
        return "none"
    v = [c.get("verdict") for c in claims]
    parts = [f"holding {v.count('holds')}"]
    failing = [c for c in claims if c.get("verdict") == "does not hold"]
    by: dict[str, int] = {}
    for c in failing:
        k = c["cause"]["kind"] if c.get("cause") else "no cause given"
        by[k] = by.get(k, 0) + 1
    inside = sum(c.get("refuted") is False for c in failing)
    favour = sum(c.get("refuted") is False and bool(c.get("favours")) for c in failing)
    detail = [f"{k} {n}" for k, n in sorted(by.items())] if causes else []
    detail += [f"{inside} of them not refuted (inside the interval"
               + (f"; the means favour the claim in {favour})" if favour else ")")] if inside else []
    parts.append(f"failing {len(failing)}" + (f" ({', '.join(detail)})" if failing and detail else ""))
    for name in ("calibration target", "not evaluated"):
        if v.count(name):
            parts.append(f"{name}{'s' if name.endswith('target') else ''} {v.count(name)}")
    return "; ".join(parts)


def _extended_verdicts(results_dir: Path, res: PaperResult) -> str:
    """The verdicts of the claims that rest on a paper's extended tables, as the last extended run
    (``results/extended/claims.json``) gave them: a default report must not hide a failing check by leaving it out."""
    from bench.reproduce.claims import claim_tables

    skipped = set(res.info.get("extended_tables", ()))
    ids = [c["id"] for c in res.decl.get("claims", []) if claim_tables(c) & skipped]
    path = Path(results_dir) / "extended" / "claims.json"
    try:
        doc = json.loads(path.read_text())
        got = doc["claims"]
    except (OSError, ValueError, KeyError):
        return f"their claims ({', '.join(ids)}) have no extended run yet" if ids else "no claim rests on them"
    parts = [f"{cid} **{got[f'{res.paper}.{cid}']['verdict']}**" if f"{res.paper}.{cid}" in got else f"{cid} not run"
             for cid in ids]
    commit = str(doc.get("commit", "?"))[:12]
    return f"their claims in the last extended run (commit `{commit}`): {', '.join(parts)}" if parts else ""


def choice_label(edits: Sequence[Mapping[str, Any]]) -> list[str]:
    """How a headline cell names a choice: its parameters (``<file>.<key>``), or, for a choice of more than three,
    its keys and the number of files (the lateral tire ratios of ten terrains), so that the cell stays short."""
    names = [str(e["name"]) for e in edits]
    if len(names) <= 3:
        return names
    keys = sorted({n.split(".", 1)[1] for n in names})
    return [f"{', '.join(keys)} of {len({n.split('.', 1)[0] for n in names})} files"]


def _sensitivity(results_dir: Path) -> tuple[dict[str, list[str]], set[str], str] | None:
    """From the last extended run's sensitivity study (``results/extended/sensitivity.json``,
    :mod:`bench.reproduce.sensitivity`): {claim: the chosen parameters whose alternative changes its verdict} for the
    claims that are not calibration targets, the papers it re-ran and its commit; None when it has not run."""
    doc = _sensitivity_doc(results_dir)
    try:
        decided: dict[str, list[str]] = {}
        for c, r in _decided(doc):
            decided.setdefault(r["claim"], []).extend(choice_label(c["edits"]))
        return decided, {p for c in doc["choices"] for p in c["papers"]}, str(doc.get("commit", "?"))[:12]
    except (KeyError, TypeError):
        return None


SENSITIVITY_LINK = "extended/sensitivity.md"


def write_report(results: list[PaperResult], results_dir: Path, quick: bool, runner: Runner, seconds: float,
                 extended: bool = False) -> Path:
    from bench.cpu import dispatch_state

    flag = " --quick" if quick else " --extended" if extended else ""
    lines = [
        "# skidbench reproduction report", "",
        f"Generated by `skidbench reproduce{flag}` at commit `{git_commit()}`; the papers' wall time "
        f"{seconds:.1f} s; runs simulated {runner.stats['simulated']}, taken from the cache {runner.stats['cached']}.",
        "Package versions: " + ", ".join(f"{k} {v}" for k, v in package_versions().items())
        + f"; CPU dispatch: {dispatch_state()} (bench.cpu); C extensions: "
        + (", ".join(f"{m} {state}" for m, state in compiled_extensions().items()) or "none") + ".", "",
        "Every verdict is computed from the numbers: **holds**, **does not hold** (with its cause: `method` the testbed "
        "has the physics the claim rests on, `testbed` an effect it lacks, `protocol` our experiment differs, `paper` "
        "the paper contradicts itself; a claim scored against a 95 % interval (over the seeds, or the segments of a path) "
        "that fails inside it is marked *not refuted*: the data cannot tell it from the bound, and *the means favour the claim* when it fails by the "
        "interval alone; a quick run's fewer seeds and shorter runs may give a cause of their own), *calibration target* (a testbed parameter was chosen "
        "to produce this outcome: never counted as a verdict), *not evaluated* (a metric is missing). Checks of our own (NEES, NaN, outages) "
        "are listed apart, per paper. A verdict marked *decided by a testbed choice* changes when a parameter the "
        "testbed chose (for another claim, or with no published value) takes its declared alternative "
        f"([the sensitivity study]({SENSITIVITY_LINK}), "
        "`reproduce --extended`): it holds or fails at the testbed's choice, not at a published number.", "",
        "## Headline claims", "", "| paper | claim | verdict | cause | key numbers |", "|---|---|---|---|---|",
    ]
    sens = None if quick else _sensitivity(results_dir)
    decided = sens[0] if sens else {}
    for res in results:
        heads = _groups(res.claims)["headline"]
        if not heads:
            lines.append(f"| [{res.paper}]({res.paper}/README.md) | no claim marked headline | — | — | — |")
        for c in heads:
            more = f"{res.paper}/{DETAILS}#claim-{c['id']}"
            by = decided.get(f"{res.paper}.{c['id']}")
            mark = f" *decided by a testbed choice* ([{', '.join(sorted(set(by)))}]({SENSITIVITY_LINK}))" if by else ""
            lines.append(f"| [{res.paper}]({res.paper}/README.md) | {cell(c['text'], more)} | {_verdict(c)}{mark} "
                         f"| {_cause(c, more, with_note=False)} | {cell(c['measured'], more)} |")
    lines += ["", "## Per paper", ""]
    for res in results:
        g = _groups(res.claims)
        lines += [f'<a id="{res.paper}"></a>', "",
                  f"### [{res.paper}]({res.paper}/README.md): {cell(res.decl.get('title', res.paper))}", "",
                  f"- headline claims ({len(g['headline'])}): {_counts(g['headline'])}",
                  f"- other claims of the paper ({len(g['other'])}): {_counts(g['other'])}",
                  f"- checks beyond the paper ({len(g['beyond'])}): {_counts(g['beyond'], causes=False)}"]
        if res.info.get("extended_tables"):
            verdicts = _extended_verdicts(results_dir, res)
            lines.append(f"- studies beyond the paper run by `skidbench reproduce --extended` only "
                         f"([results/extended/](extended/REPORT.md)): {', '.join(res.info['extended_tables'])}"
                         + (f"; {verdicts}" if verdicts else ""))
        targets = [f"{c['id']} ({', '.join(p['parameter'] for p in c.get('calibration', []))})"
                   for c in res.claims if c.get("verdict") == "calibration target"]
        if targets:
            lines.append(f"- calibration targets: {', '.join(targets)}")
        if sens and res.paper in sens[1]:
            mine = sorted(k.split(".", 1)[1] for k in decided if k.startswith(res.paper + "."))
            lines.append(f"- verdicts decided by a testbed choice (they change at its alternative; last extended "
                         f"run, commit `{sens[2]}`, [sensitivity]({SENSITIVITY_LINK})): {', '.join(mine) or 'none'}")
        lines += [f"- {len(res.tables)} tables, {len(res.figures)} figures, every claim in detail: "
                  f"[{res.paper}/{DETAILS}]({res.paper}/{DETAILS}); computed in {res.seconds:.1f} s", ""]
    path = results_dir / ("REPORT_quick.md" if quick else "REPORT.md")
    atomic_write_text(path, "\n".join(lines))
    return path


def write_documents(results: list[PaperResult], results_dir: Path, quick: bool) -> None:
    suffix = "_quick" if quick else ""
    atomic_write_json(results_dir / f"metrics{suffix}.json", metrics_document(results, quick))
    atomic_write_json(results_dir / f"claims{suffix}.json", claims_document(results, quick))


EXTRA_RESULTS = (  # (file under results/, what it is): written by the extras of `reproduce --all`
    ("league{suffix}.md", "cross-paper league table: every method on every scenario, ranked within its sensor group (wheel odometry; wheels + IMU; wheels + IMU + GNSS; dynamic model)"),
    ("real/husky.md", "real Clearpath Husky (DRIVE data): calibrated kinematic models scored on held-out steps"),
    ("real/husky_gap.md", "gap workflow with the testbed's husky model against the real data"),
    ("gap/worked_example.md", "gap workflow worked example on simulated data with a hidden effect"),
    ("stress.md", "filters under stress: GNSS outage, IMU spikes, encoder dropouts"),
    ("extended/sensitivity.md", "verdicts a chosen testbed parameter decides: the papers re-run at each choice's "
                                "declared alternative (`reproduce --extended`)"),
)
EXTRAS_BEGIN, EXTRAS_END = "<!-- extras -->", "<!-- /extras -->"


def link_extras(results_dir: Path, quick: bool) -> Path | None:
    """Add (or refresh) the section of REPORT.md that links the extras' results that exist; it sits
    after the headline table, before the per-paper summaries, between two HTML comments, so that a rerun
    replaces it."""
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


def history_path(results_dir: Path) -> Path:
    """``history.jsonl`` of a results folder; ``results/quick/`` and ``results/extended/`` write to the one of
    ``results/`` (one history per project, read by the dashboard: a log across runs, so theirs is written at once, not
    published with their set by :mod:`bench.reproduce.publish`)."""
    from bench.reproduce.publish import final_dir

    results = default_results().resolve()
    sub = final_dir(Path(results_dir)).resolve()  # a staging folder: the folder it will be published as
    return (results if sub in (results / "quick", results / "extended") else Path(results_dir)) / "history.jsonl"


def append_history(results_dir: Path, results: list[PaperResult], quick: bool, seconds: float,
                   extended: bool = False) -> None:
    """One JSON line per reproduce: commit, date, mode, metrics, wall time (read by the dashboard, which leaves the
    extended runs out: their papers and league differ from the full run's)."""
    entry = {
        "commit": git_commit(), "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "quick": quick, "extended": extended, "seconds": round(seconds, 3),
        "metrics": {f"{r.paper}.{k}": v for r in results for k, v in r.metrics.items() if isinstance(v, (int, float))},
    }
    # the speed benchmarks have a history of their own: `make bench` appends to results/bench_history.jsonl
    path = history_path(results_dir)
    old = path.read_text() if path.is_file() else ""
    atomic_write_text(path, old + dumps_json(entry, sort_keys=True) + "\n")
