"""Speed of a reproduction stage, cold and warm (pytest-benchmark; run by `make bench`).

The smallest paper stage (yu2010, 74 runs) through the command line, as a user runs it: cold = empty run and result
caches (every run simulated, every table computed), warm = the same command again (everything from the caches).
The whole reproduction's per-stage seconds, cold and warm, are in REPORT.md's stage table and ``results/timing.json``
(:mod:`bench.reproduce.timing`), and per commit on the dashboard's speed page; a full cold run is minutes, too long
for a benchmark round.  The stage table of each round is kept in ``extra_info``.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
STAGE = "yu2010"


def _reproduce(cache: Path, results: Path) -> dict:
    env = dict(os.environ, SKIDBENCH_CACHE=str(cache / "runs"))
    subprocess.run([sys.executable, "-m", "bench.cli", "reproduce", STAGE, "--workers", "2", "--results",
                    str(results)], cwd=REPO, env=env, check=True, capture_output=True)
    report = (results / "REPORT.md").read_text()
    return {"report_lines": report.count("\n")}


def test_stage_cold(benchmark, tmp_path) -> None:
    def setup():
        shutil.rmtree(tmp_path / "cache", ignore_errors=True)
        shutil.rmtree(tmp_path / "results", ignore_errors=True)
        return (tmp_path / "cache", tmp_path / "results"), {}

    out = benchmark.pedantic(_reproduce, setup=setup, rounds=2, iterations=1)
    assert out["report_lines"] > 10
    benchmark.extra_info["stage"] = STAGE
    benchmark.extra_info["mode"] = "cold"


def test_stage_warm(benchmark, tmp_path) -> None:
    cache, results = tmp_path / "cache", tmp_path / "results"
    _reproduce(cache, results)  # fill the caches
    out = benchmark.pedantic(_reproduce, args=(cache, results), rounds=3, iterations=1)
    assert out["report_lines"] > 10
    benchmark.extra_info["stage"] = STAGE
    benchmark.extra_info["mode"] = "warm"
    benchmark.extra_info["runs_in_cache"] = len(list((cache / "runs").glob("*.parquet")))
    assert json.loads(json.dumps(benchmark.extra_info))  # plain JSON for .benchmarks/latest.json
