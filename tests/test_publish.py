"""One reproduce, one published set (bench.reproduce.publish): the results folder holds either the previous run's
files or the new run's, never a mix, whatever stops the run (an exception, SIGKILL, a kill between the two renames),
and two runs cannot write one results tree at once."""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from bench.reproduce.publish import ResultsBusy, final_dir, recover, staged


def _tree(d: Path) -> dict[str, bytes]:
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.fixture
def results(tmp_path: Path) -> Path:
    d = tmp_path / "results"
    (d / "paper").mkdir(parents=True)
    (d / "metrics.json").write_text('{"run": 1}')
    (d / "REPORT.md").write_text("run 1\n")
    (d / "paper" / "table.md").write_text("run 1\n")
    (d / "kept.md").write_text("not rewritten by run 2\n")
    return d


def _siblings(d: Path) -> list[str]:
    return sorted(p.name for p in d.parent.iterdir() if p.name.startswith(f".{d.name}."))  # a lock file too


def test_a_finished_run_replaces_the_set_and_keeps_what_it_did_not_rewrite(results):
    with staged(results) as stage:
        assert stage != results and final_dir(stage) == results.resolve()
        (stage / "metrics.json").write_text('{"run": 2}')
        (stage / "paper" / "table.md").write_text("run 2\n")
        assert (results / "metrics.json").read_text() == '{"run": 1}'  # nothing published before the end
    assert _tree(results) == {"REPORT.md": b"run 1\n", "kept.md": b"not rewritten by run 2\n",
                              "metrics.json": b'{"run": 2}', "paper/table.md": b"run 2\n"}
    assert _siblings(results) == []  # no staging or old folder left


def test_an_exception_leaves_the_previous_set_untouched(results):
    before = _tree(results)
    with pytest.raises(RuntimeError):
        with staged(results) as stage:
            (stage / "metrics.json").write_text('{"run": 2}')  # metrics.json written, REPORT.md not yet
            raise RuntimeError("the run failed between two writes")
    assert _tree(results) == before and _siblings(results) == []


def test_a_first_run_into_no_folder_publishes_it(tmp_path):
    with staged(tmp_path / "new") as stage:
        (stage / "a.md").write_text("x")
    assert _tree(tmp_path / "new") == {"a.md": b"x"}


KILLED = """
import os, signal, sys
from pathlib import Path
from bench.reproduce.publish import staged
with staged(Path(sys.argv[1])) as stage:
    (stage / "metrics.json").write_text('{"run": 2}')
    os.kill(os.getpid(), signal.SIGKILL)
"""


def test_sigkill_during_the_run_leaves_the_previous_set_and_the_next_run_cleans_up(results, tmp_path):
    before = _tree(results)
    script = tmp_path / "killed.py"
    script.write_text(KILLED)
    p = subprocess.run([sys.executable, str(script), str(results)], env={**os.environ, "PYTHONPATH": os.getcwd()})
    assert p.returncode == -signal.SIGKILL
    assert _tree(results) == before
    assert _siblings(results) == [".results.lock", ".results.staging"]  # the killed run's set, not published
    with staged(results) as stage:  # the next run: the lock of the dead process is free, its staging is removed
        assert json.loads((stage / "metrics.json").read_text()) == {"run": 1}
    assert _tree(results) == before and _siblings(results) == []


def _between_renames(results: Path, complete: bool) -> None:
    """The state a kill between the two renames leaves: results moved to .old, the staging folder not yet moved."""
    stage, old = results.parent / ".results.staging", results.parent / ".results.old"
    import shutil

    shutil.copytree(results, stage)
    (stage / "metrics.json").write_text('{"run": 2}')
    (stage / ".staging.json").write_text(json.dumps({"final": str(results.resolve()), "complete": complete}))
    os.replace(results, old)


@pytest.mark.parametrize("complete", [True, False])
def test_a_kill_between_the_two_renames_is_finished_or_undone(results, complete):
    before = _tree(results)
    _between_renames(results, complete)
    assert not results.exists()  # absent, not mixed
    recover(results)
    want = {**before, "metrics.json": b'{"run": 2}'} if complete else before
    assert _tree(results) == want and _siblings(results) == []


def test_two_runs_cannot_write_one_results_tree(results, monkeypatch):
    monkeypatch.setattr("bench.reproduce.publish.default_results", lambda: results)
    with staged(results):
        with pytest.raises(ResultsBusy, match=r"another skidbench reproduce \(pid \d+\) is writing"):
            with staged(results / "quick"):  # results/quick is published inside results/: the same lock
                pass
    with staged(results / "quick") as stage:  # free again
        (stage / "x.md").write_text("q")
    assert (results / "quick" / "x.md").read_text() == "q"


def test_a_run_removes_its_lock_file_and_never_trusts_a_removed_one(results, monkeypatch):
    """No lock file is left beside the results folder; a run that opened the file just before the run holding it
    removed it (the race a removed lock file opens) locks the file then at the path, never the removed one."""
    import fcntl

    from bench.reproduce import publish

    lock = results.parent / f".{results.name}.lock"
    monkeypatch.setattr(publish, "default_results", lambda: results)
    with staged(results):
        assert lock.read_text() == f"{os.getpid()}\n"
        late = open(lock, "a+")  # opened while the first run holds it
    assert not lock.exists() and _siblings(results) == []
    fcntl.flock(late, fcntl.LOCK_EX | fcntl.LOCK_NB)  # the removed file is free to lock: it must not count
    opened = iter([late])
    monkeypatch.setattr(publish, "open", lambda *a, **k: next(opened, None) or open(*a, **k), raising=False)
    fh = publish._open_locked(lock, results)
    try:
        assert fh is not late and os.path.samestat(os.stat(lock), os.fstat(fh.fileno()))
        with pytest.raises(ResultsBusy):  # and it excludes a third run
            with staged(results):
                pass
    finally:
        fh.close()
        late.close()


def test_history_of_a_staged_quick_run_is_the_projects(results, monkeypatch):
    """results/quick/ appends to results/history.jsonl (a log across runs), also from its staging folder; the full
    run's history is inside its own set."""
    from bench.reproduce.report import history_path

    monkeypatch.setattr("bench.reproduce.report.default_results", lambda: results)
    with staged(results / "quick") as stage:
        assert history_path(stage) == results / "history.jsonl"
    with staged(results) as stage:
        assert history_path(stage) == stage / "history.jsonl"


def test_reproduce_failing_after_metrics_json_leaves_the_previous_results(tmp_path, monkeypatch):
    """The command line end to end: a failure after metrics.json was written and before REPORT.md (the mix a kill
    could leave) leaves the results folder as the previous run wrote it."""
    import bench.cli.reproduce as C
    import bench.reproduce as R
    import bench.reproduce.runner
    from tests.test_reproduce import PAPER

    papers = tmp_path / "papers"
    papers.mkdir()
    (papers / "fake.toml").write_text(PAPER)
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", papers)
    monkeypatch.setattr(bench.reproduce.runner, "DEFAULT_CACHE", tmp_path / "cache" / "runs")
    res = tmp_path / "results"
    args = argparse.Namespace(papers=["fake"], all=False, quick=False, workers=1, dask_scheduler=None, results=res)
    assert C._reproduce(args) == 0
    before = _tree(res)
    assert {"metrics.json", "REPORT.md", "history.jsonl"} <= set(before)

    def broken(*a, **k):
        raise RuntimeError("killed before REPORT.md")

    monkeypatch.setenv("SKIDBENCH_BREAK_METHOD", "1")  # the second run's metrics differ
    monkeypatch.setattr(R, "write_report", broken)
    with pytest.raises(RuntimeError, match="killed before REPORT.md"):
        C._reproduce(args)
    assert _tree(res) == before and _siblings(res) == []
