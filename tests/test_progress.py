"""Progress bars of ``skidbench reproduce`` (bench.cli.progress): a bar per stage, its ETA from the last run's stage
time, steps where no time is known, 100 % at the end, none left at 0 % (the cached rerun had a bar stuck there)."""
from __future__ import annotations

import argparse
import io
import json

from rich.console import Console
from rich.progress import Progress

from bench.cli.progress import StageBars, expected_seconds


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _progress() -> Progress:
    return Progress(console=Console(file=io.StringIO(), width=120), auto_refresh=False)


def test_a_stage_with_a_known_time_measures_it_and_its_eta_is_what_remains():
    clock, prog = Clock(), _progress()
    bars = StageBars(prog, {"yi2009": 40.0}, clock=clock)
    bars.event("start", "yi2009")
    task = prog.tasks[bars.tasks["yi2009"]]
    assert task.total == 40.0 and task.completed == 0
    clock.t += 10
    bars.event("step", "yi2009", 2, 7, "table3")
    assert task.completed == 10.0 and task.percentage == 25.0
    assert task.description == "yi2009: table3 (2/7)"
    clock.t += 100  # longer than last time: held below 100 % until it ends
    bars.tick()
    assert task.completed == 0.99 * 40.0
    bars.event("done", "yi2009", False)
    assert task.finished and task.percentage == 100.0 and task.description == "yi2009: done in 110.0 s"


def test_a_stage_without_a_known_time_counts_its_steps_then_its_runs():
    clock, prog = Clock(), _progress()
    bars = StageBars(prog, {"short": 0.5}, clock=clock)  # under MIN_EXPECTED: steps, not time
    bars.event("sim", "new", 3, 12)
    task = prog.tasks[bars.tasks["new"]]
    assert (task.completed, task.total) == (3, 12) and task.description == "new: simulating runs 3/12"
    bars.event("step", "new", 1, 4, "t1")
    assert (task.completed, task.total) == (1, 4)
    bars.event("start", "short")
    short = prog.tasks[bars.tasks["short"]]
    assert short.total is None  # pulsing until it ends
    bars.event("done", "short", True)
    assert short.finished and short.description == "short: from the result cache"


def test_expected_seconds_take_this_runs_computed_stages_else_the_last_cold_runs(tmp_path):
    doc = {"this_run": {"stages": {"a": {"seconds": 3.0, "from_cache": False}, "b": {"seconds": 0.1, "from_cache": True}}},
           "last_cold": {"stages": {"a": {"seconds": 9.0, "from_cache": False}, "b": {"seconds": 20.0, "from_cache": False}}}}
    (tmp_path / "timing.json").write_text(json.dumps(doc))
    assert expected_seconds(tmp_path, quick=False) == {"a": 3.0, "b": 20.0}
    assert expected_seconds(tmp_path, quick=True) == {}  # no timing_quick.json
    (tmp_path / "timing.json").write_text("not json")
    assert expected_seconds(tmp_path, quick=False) == {}


def test_reproduce_ends_every_bar_at_100_percent_cold_and_cached(tmp_path, monkeypatch):
    """Two papers in a process pool (events from the jobs through the queue) and an extra, run twice: the second run
    takes everything from the caches.  Every stage has its bar, every bar ends finished, none at 0 %."""
    import bench.cli.reproduce as C
    import bench.reproduce.runner
    from tests.test_reproduce import PAPER

    papers = tmp_path / "papers"
    papers.mkdir()
    for name in ("fake", "fake2"):
        (papers / f"{name}.toml").write_text(PAPER.replace('paper = "fake"', f'paper = "{name}"'))
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", papers)
    monkeypatch.setattr(bench.reproduce.runner, "DEFAULT_CACHE", tmp_path / "cache" / "runs")

    def extra(results_dir, quick, workers=1):
        (results_dir / "league.md").write_text("an extra\n")

    monkeypatch.setitem(C.EXTRAS, "league", extra)
    made: list[Progress] = []

    def progress() -> Progress:
        made.append(_progress())
        return made[-1]

    monkeypatch.setattr(C, "_progress", progress)
    args = argparse.Namespace(papers=["fake", "fake2", "league"], all=False, quick=False, workers=2,
                              dask_scheduler=None, results=tmp_path / "results")
    for run in ("cold", "cached"):
        assert C._reproduce(args) == 0
        tasks = {t.description.split(":")[0]: t for t in made[-1].tasks}
        assert set(tasks) == {"fake", "fake2", "league"}, run
        assert all(t.finished and t.percentage == 100.0 for t in tasks.values()), run
    assert all("from the result cache" in t.description for t in made[-1].tasks)
