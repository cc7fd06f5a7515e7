"""CLI command ``skidbench dashboard [--results DIR] [--out DIR] [--asv [--asv-bench REGEX]]``.

Renders the static regression dashboard (:mod:`bench.report.dashboard`) from
``<results>/history.jsonl``, ``<results>/metrics.json`` and ``<results>/bench_history.jsonl`` (written by
``make bench``, :mod:`bench.report.bench_history`) into ``<out>`` (default ``<results>/dashboard``).

``--asv`` additionally runs the optional asv suite (``asv.conf.json``, ``benchmarks/``) in the current
interpreter and publishes asv's own site into ``<out>/asv``.  By default only the quick ``track_*`` benchmark
``DistanceToPublished.track_abs_error`` runs (|reproduced - published| of the metrics with a published value,
each once: ``asv run --quick``; ~1.5 min for ~250 metrics).  asv runs every parameter in a process of its own,
so ``Reproduced.track_value`` over all ~3,400 metric ids takes ~20 min (``--asv-bench track_``) and the
``time_*`` speed benchmarks with asv's repeats many more (``make bench`` measures the same code).  The whole
suite: ``--asv-bench .`` (still --quick), or asv itself::

    asv machine --yes
    asv run --environment existing:$(which python) --set-commit-hash $(git rev-parse HEAD)
    asv publish && asv preview

asv's site loads its data with fetch(), which browsers refuse on file://: it is blank when opened from
disk and must be viewed through ``asv preview --html-dir <out>/asv`` (an HTTP server).  Registered into
:data:`bench.cli.COMMANDS` on import.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

from bench.cli import command

ASV_DEFAULT_BENCH = "DistanceToPublished"  # asv run --bench: the track_* benchmark of the published metrics


def _args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results", type=Path, default=None, help="results folder with history.jsonl (default results/)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default <results>/dashboard)")
    p.add_argument("--asv", action="store_true",
                   help="also run the asv benchmarks (environment 'existing', --quick) and publish asv's site into "
                        "<out>/asv (view it with `asv preview`: it needs an HTTP server)")
    p.add_argument("--asv-bench", default=ASV_DEFAULT_BENCH, metavar="REGEX",
                   help=f"with --asv: the benchmarks to run (asv run --bench; default {ASV_DEFAULT_BENCH!r}: "
                        "track_abs_error of the published metrics, ~1.5 min; 'track_' every track_* benchmark, ~20 min; "
                        "'.' the whole suite, time_* included)")


def run_asv(repo: Path, results_dir: Path, html_dir: Path, bench: str = ASV_DEFAULT_BENCH) -> int:
    """``asv machine --yes``, ``asv run --quick --bench <bench> --environment existing`` at HEAD,
    ``asv publish``; exit code."""
    sibling = Path(sys.executable).with_name("asv")
    asv = str(sibling) if sibling.is_file() else shutil.which("asv")
    if asv is None:
        print("error: --asv needs asv (pip install asv)", file=sys.stderr)
        return 2
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True)
    if head.returncode != 0:
        print(f"error: --asv needs a git checkout at {repo}: {head.stderr.strip()}", file=sys.stderr)
        return 2
    conf = str(repo / "asv.conf.json")
    env = {**os.environ, "SKIDBENCH_RESULTS": str(results_dir.resolve())}
    steps = [[asv, "machine", "--yes", "--config", conf],
             [asv, "run", "--config", conf, "--environment", f"existing:{sys.executable}", "--quick",
              "--bench", bench, "--set-commit-hash", head.stdout.strip()],
             [asv, "publish", "--config", conf, "--html-dir", str(html_dir.resolve())]]
    for cmd in steps:
        rc = subprocess.run(cmd, cwd=repo, env=env).returncode
        if rc != 0:
            print(f"error: {' '.join(cmd[:2])} exited {rc}", file=sys.stderr)
            return rc
    print(f"asv's site is in {html_dir}: it needs an HTTP server (opened from disk it is blank); view it with\n"
          f"    asv preview --config {conf} --html-dir {html_dir}")
    return 0


def _dashboard(a: argparse.Namespace) -> int:
    from bench.report.dashboard import render_dashboard
    from bench.paths import default_results
    from bench.reproduce.runner import REPO

    results = a.results or default_results()
    out = a.out or (results / "dashboard")
    if a.asv:
        rc = run_asv(REPO, results, out / "asv", a.asv_bench)
        if rc != 0:
            return rc
    pages = render_dashboard(results, out)
    n = sum(pages.charts.values())
    rows = sum(pages.rows.values())
    print(f"wrote {out / 'index.html'} and {len(pages.charts) - 1} pages ({n} charts, {rows} compact rows, "
          f"{len(pages.steps)} changes beyond tolerance)")
    return 0


command("dashboard", "render the regression dashboard (results/dashboard/index.html) from history.jsonl")(
    (_args, _dashboard))
