"""The stage table of a reproduction (bench.reproduce.timing), the --extended switch and what it moves."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bench.reproduce import timing

REPO = Path(__file__).resolve().parents[1]


def _stages(seconds: float, from_cache: bool = False) -> dict:
    return {"mandow2007": {"seconds": seconds, "simulation_seconds": seconds / 4, "from_cache": from_cache},
            "league": {"seconds": 2 * seconds, "from_cache": from_cache}}


def test_a_warm_run_keeps_the_last_cold_table(tmp_path):
    cold = timing.record(tmp_path, False, _stages(100.0), 250.0, 300, 4, workers=2, cache_was_empty=True)
    assert cold["this_run"]["cold"] and cold["last_cold"] == cold["this_run"]
    warm = timing.record(tmp_path, False, _stages(1.0, True), 3.0, 0, 300, workers=2, cache_was_empty=False)
    assert not warm["this_run"]["cold"]
    assert warm["last_cold"]["wall_seconds"] == 250.0  # read back from timing.json
    assert json.loads((tmp_path / "timing.json").read_text())["last_cold"]["stages"]["league"]["seconds"] == 200.0
    rows = {line.split(" | ")[0].strip("| "): line for line in timing.table(warm) if line.startswith("| ")}
    assert "1.0 (cache)" in rows["mandow2007"] and "100.0" in rows["mandow2007"] and "25.0" in rows["mandow2007"]
    # a run with a filled run cache is not cold, even when nothing came from the result cache
    again = timing.record(tmp_path, False, _stages(5.0), 9.0, 0, 300, workers=2, cache_was_empty=False)
    assert not again["this_run"]["cold"] and again["last_cold"]["wall_seconds"] == 250.0
    # the header says how many runs it simulated, not "warm", when the cache was only partly valid
    part = timing.record(tmp_path, False, _stages(5.0), 9.0, 289, 41, workers=2, cache_was_empty=False)
    assert "(289 runs simulated, 41 from the run cache); last cold run 250.0 s" in timing.summary(part)
    assert "(cold)" in timing.summary(cold)


def test_the_first_table_is_the_headline_claims_and_the_stage_table_follows_it_once(tmp_path):
    """Issue 30: REPORT.md's first table lists the headline claims; issue 34: the header says where the time goes
    (one line, linking the stage table right after the headline claims)."""
    report = tmp_path / "REPORT.md"
    report.write_text("# report\n\nheader\n\n## Headline claims\n\n| a |\n|---|\n\n## Per paper\n\ntext\n")
    doc = timing.record(tmp_path, False, _stages(10.0), 30.0, 5, 0, workers=2, cache_was_empty=True)
    timing.insert(report, doc)
    timing.insert(report, doc)
    text = report.read_text()
    assert text.count("## Where the time goes") == 1 and text.count("Where the time goes: 30.0 s wall") == 1
    first_table = next(i for i, line in enumerate(text.splitlines()) if line.startswith("|"))
    assert text.splitlines()[first_table] == "| a |"
    assert (text.index("Where the time goes: 30.0 s") < text.index("## Headline claims")
            < text.index("## Where the time goes") < text.index("## Per paper"))
    assert "(#where-the-time-goes)" in text and "\n\n\n" not in text


@pytest.mark.parametrize("body", [
    "# report\n\nheader\n\n## Headline claims\n\n| a |\n|---|",          # no final newline, no next section
    "# report\n\nheader\n",                                                  # no headline section at all
    "# r\n\n<!-- timing: end -->\n\n## Headline claims\n\n| a |\n\n## Per paper\n\nkept\n",  # a stray end marker
])
def test_the_timing_sections_settle_after_one_rerun_and_keep_the_rest(tmp_path, body):
    """Whatever the report looks like, a second insert gives the same file as the first, and no text of the
    report is lost (a stray end marker before any begin marker is not a section)."""
    report = tmp_path / "REPORT.md"
    report.write_text(body)
    doc = timing.record(tmp_path, False, _stages(10.0), 30.0, 5, 0, workers=2, cache_was_empty=True)
    timing.insert(report, doc)
    once = report.read_text()
    timing.insert(report, doc)
    assert report.read_text() == once and "\n\n\n" not in once
    assert once.count("## Where the time goes") == 1 and once.count("Where the time goes: 30.0 s") == 1
    for piece in ("# r", "header", "| a |", "kept"):
        assert (piece in once) == (piece in body), piece


def test_quick_and_extended_exclude_each_other():
    r = subprocess.run([sys.executable, "-m", "bench.cli", "reproduce", "yu2010", "--quick", "--extended"], cwd=REPO,
                       capture_output=True, text=True)
    assert r.returncode == 2 and "exclude each other" in r.stderr and "Traceback" not in r.stderr


def test_the_league_shows_the_papers_configurations_and_extended_adds_skidbench_own():
    from bench import registry
    from bench.reproduce.league import league_methods

    every, default = league_methods(extended=True), league_methods()
    beyond = set(every) - set(default)
    assert beyond and all(registry.get(n).beyond_paper for n in beyond)
    assert all(n.endswith("_consistent") for n in beyond)  # the consistent configurations of Yi and Liu
    assert {"liu2020.mi_ukf", "yi2009.ekf_v3", "mandow2007.asymmetric_ga"} <= set(default)


def test_the_nees_study_is_light_unless_extended():
    from types import SimpleNamespace

    from methods.yi2009.repro.nees_evaluation import NULL_DRAWS, nees_light

    assert nees_light(SimpleNamespace(quick=False, extended=False))
    assert nees_light(SimpleNamespace(quick=True, extended=False))
    assert not nees_light(SimpleNamespace(quick=False, extended=True))
    assert NULL_DRAWS[False] >= 2000 > NULL_DRAWS[True]
