"""Where the time of a reproduction goes: one row per stage (each paper, with its simulation time, and each extra:
real, league, gap, stress), this run's and the last cold run's, in ``results/timing.json`` and in REPORT.md: one line
in its header, the table right after the headline claims (each between two HTML comments, so a rerun replaces
them; the report's first table stays the headline claims).

A run is *cold* when it computed everything: the run cache was empty at its start and no paper or extra was taken
from the result cache.  ``timing.json`` keeps the last cold run's table beside the current one, so the committed report shows both
when it was written from the caches (warm).
"""
from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Mapping

from bench.report.io import atomic_write_json, atomic_write_text
from bench.reproduce.provenance import git_commit

BEGIN, END = "<!-- timing: begin -->", "<!-- timing: end -->"
LINE_BEGIN, LINE_END = "<!-- timing line: begin -->", "<!-- timing line: end -->"


def _file(results_dir: Path, quick: bool) -> Path:
    return Path(results_dir) / ("timing_quick.json" if quick else "timing.json")


def record(results_dir: Path, quick: bool, stages: Mapping[str, Mapping[str, Any]], wall: float,
           simulated: int, cached: int, workers: int, cache_was_empty: bool, extended: bool = False) -> dict[str, Any]:
    """Write ``timing.json`` with this run (``stages``: name -> seconds, simulation_seconds, from_cache) and the
    last cold run (this one when it is cold: the run cache was empty at its start and no stage came from the result
    cache; ``cached`` then counts the runs asked for twice); return the document."""
    run = {"commit": git_commit(), "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "wall_seconds": round(wall, 1), "workers": workers, "runs_simulated": simulated, "runs_cached": cached,
           "stages": {k: {"seconds": round(float(v["seconds"]), 1),
                          "simulation_seconds": (round(float(v["simulation_seconds"]), 1)
                                                 if v.get("simulation_seconds") is not None else None),
                          "from_cache": bool(v.get("from_cache", False))} for k, v in stages.items()}}
    run["cold"] = bool(cache_was_empty) and not any(v["from_cache"] for v in run["stages"].values())
    path = _file(results_dir, quick)
    old: dict[str, Any] = {}
    if path.is_file():
        try:
            old = json.loads(path.read_text())
        except ValueError:
            old = {}
    doc = {"this_run": run, "last_cold": run if run["cold"] else old.get("last_cold")}
    atomic_write_json(path, doc)
    _annotate_history(Path(results_dir), run, quick, extended)
    return doc


def _annotate_history(results_dir: Path, run: Mapping[str, Any], quick: bool, extended: bool) -> None:
    """Add the stage seconds and the cold flag to the last line of ``history.jsonl`` (written by the same
    reproduce, before its extras ran) for the dashboard's speed page; nothing when that line is another commit's
    or another mode's."""
    from bench.report.io import dumps_json
    from bench.reproduce.report import history_path

    path = history_path(results_dir)
    if not path.is_file():
        return
    lines = path.read_text().splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        return
    try:
        last = json.loads(lines[-1])
    except ValueError:
        return
    if (last.get("commit"), bool(last.get("quick")), bool(last.get("extended"))) != (run["commit"], quick, extended):
        return
    last["stages"] = {k: v["seconds"] for k, v in run["stages"].items()}
    last["cold"] = run["cold"]
    lines[-1] = dumps_json(last, sort_keys=True)
    atomic_write_text(path, "\n".join(lines) + "\n")


def table(doc: Mapping[str, Any]) -> list[str]:
    """The stage table (markdown lines)."""
    run, cold = doc["this_run"], doc.get("last_cold") or {}
    names = list(run["stages"]) + [k for k in cold.get("stages", {}) if k not in run["stages"]]

    def sec(r: Mapping[str, Any], k: str, key: str = "seconds") -> str:
        st = r.get("stages", {}).get(k)
        if st is None or st.get(key) is None:  # an extra's simulation time is not measured apart
            return "—"
        return f"{st[key]:.1f}" + (" (cache)" if key == "seconds" and st["from_cache"] else "")

    when = (f"last cold run: commit `{cold['commit'][:12]}`, {cold['date']}, {cold['workers']} workers, "
            f"{cold['runs_simulated']} runs simulated" if cold else "no cold run recorded yet")
    lines = ["## Where the time goes", "",
             f"This run: {run['wall_seconds']:.1f} s wall on {run['workers']} workers, {run['runs_simulated']} runs "
             f"simulated, {run['runs_cached']} served again from the run cache ({'cold' if run['cold'] else 'warm'}); {when}. "
             "Seconds per stage (" + ("the papers and the extras run side by side on the workers, so their sum "
                                      "exceeds the wall time; " if run["workers"] > 1 else "")
             + "simulation: the part of a paper's time spent stepping the testbed; an extra's is not measured "
             "apart).", "",
             "| stage | this run [s] | of it simulation [s] | last cold run [s] | of it simulation [s] |",
             "|---|---|---|---|---|"]
    for k in names:
        lines.append(f"| {k} | {sec(run, k)} | {sec(run, k, 'simulation_seconds')} | {sec(cold, k)} "
                     f"| {sec(cold, k, 'simulation_seconds')} |")
    lines.append(f"| **wall time** | **{run['wall_seconds']:.1f}** | | **{cold['wall_seconds']:.1f}** | |"
                 if cold else f"| **wall time** | **{run['wall_seconds']:.1f}** | | — | |")
    return lines


def summary(doc: Mapping[str, Any]) -> str:
    """The header's one line: this run's wall time and where the stage table is."""
    run, cold = doc["this_run"], doc.get("last_cold") or {}
    last = f"; last cold run {cold['wall_seconds']:.1f} s" if cold else ""
    how = "cold" if run["cold"] else f"{run['runs_simulated']} runs simulated, {run['runs_cached']} from the run cache"
    return (f"Where the time goes: {run['wall_seconds']:.1f} s wall on {run['workers']} workers "
            f"({how}){last}; per stage: [below](#where-the-time-goes).")


def _cut(text: str, begin: str, end: str) -> str:
    """``text`` without the first ``begin`` ... ``end`` section (an ``end`` before any ``begin`` is not one)."""
    i = text.find(begin)
    j = text.find(end, i) if i >= 0 else -1
    return text if j < 0 else text[:i] + text[j + len(end):].lstrip("\n")


def _para(text: str) -> str:
    """``text`` ending in exactly one blank line (so that a section put after it is the same on every rerun)."""
    return text.rstrip("\n") + "\n\n"


def insert(report: Path, doc: Mapping[str, Any]) -> None:
    """Put (or replace) the header's timing line before the headline claims and the stage table after their table
    (before the next section)."""
    if not report.is_file():
        return
    text = _cut(_cut(report.read_text(), BEGIN, END), LINE_BEGIN, LINE_END)
    line = "\n".join([LINE_BEGIN, summary(doc), LINE_END, "", ""])
    section = "\n".join([BEGIN, *table(doc), END, "", ""])
    at = text.find("## Headline claims")
    if at < 0:
        atomic_write_text(report, _para(text) + line + section.rstrip("\n") + "\n")
        return
    nxt = text.find("\n## ", at + 1)
    if nxt < 0:
        text = _para(text) + section.rstrip("\n") + "\n"
    else:
        text = _para(text[:nxt + 1]) + section + text[nxt + 1:]
    atomic_write_text(report, text[:at] + line + text[at:])
