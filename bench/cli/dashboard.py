"""CLI command ``skidbench dashboard [--results DIR] [--out DIR] [--asv]``.

Renders the static regression dashboard (:mod:`bench.report.dashboard`) from
``<results>/history.jsonl`` and ``<results>/metrics.json`` into ``<out>`` (default
``<results>/dashboard``).  ``--asv`` additionally runs the optional asv suite (``asv.conf.json``,
``benchmarks/``) in the current interpreter and publishes asv's own site into ``<out>/asv``
(that site needs an HTTP server to be viewed: ``asv preview``).  Registered into
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


def _args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results", type=Path, default=None, help="results folder with history.jsonl (default results/)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default <results>/dashboard)")
    p.add_argument("--asv", action="store_true",
                   help="also run the asv benchmarks (environment 'existing') and publish asv's site into <out>/asv")


def run_asv(repo: Path, results_dir: Path, html_dir: Path) -> int:
    """``asv machine --yes``, ``asv run --environment existing`` at HEAD, ``asv publish``; exit code."""
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
             [asv, "run", "--config", conf, "--environment", f"existing:{sys.executable}",
              "--set-commit-hash", head.stdout.strip()],
             [asv, "publish", "--config", conf, "--html-dir", str(html_dir.resolve())]]
    for cmd in steps:
        rc = subprocess.run(cmd, cwd=repo, env=env).returncode
        if rc != 0:
            print(f"error: {' '.join(cmd[:2])} exited {rc}", file=sys.stderr)
            return rc
    return 0


def _dashboard(a: argparse.Namespace) -> int:
    from bench.report.dashboard import render_dashboard
    from bench.paths import default_results
    from bench.reproduce.runner import REPO

    results = a.results or default_results()
    out = a.out or (results / "dashboard")
    if a.asv:
        rc = run_asv(REPO, results, out / "asv")
        if rc != 0:
            return rc
    pages = render_dashboard(results, out)
    n = sum(pages.charts.values())
    print(f"wrote {out / 'index.html'} and {len(pages.charts) - 1} pages ({n} charts, "
          f"{len(pages.steps)} changes beyond tolerance)")
    return 0


command("dashboard", "render the regression dashboard (results/dashboard/index.html) from history.jsonl")(
    (_args, _dashboard))
