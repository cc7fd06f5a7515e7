"""CLI command ``skidbench verify-runs [MANIFEST] [--workers N] [--limit N]``: determinism of the run logs.

Re-simulates the runs of a manifest (default ``results/runs_manifest.json``) and checks identical content hashes.
Registered into :data:`bench.cli.COMMANDS` on import.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench.cli import command


# ------------------------------------------------------------------------------------------ determinism
def _verify_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("manifest", type=Path, nargs="?", default=None, help="default results/runs_manifest.json")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--limit", type=int, default=None, help="only the first N runs")


def _verify(a: argparse.Namespace) -> int:
    from bench.reproduce import RESULTS
    from bench.reproduce.runner import verify_manifest

    path = a.manifest or RESULTS / "runs_manifest.json"
    manifest = json.loads(path.read_text())
    bad = verify_manifest(manifest, workers=a.workers, limit=a.limit)
    n = min(len(manifest["runs"]), a.limit or len(manifest["runs"]))
    for b in bad:
        print(f"MISMATCH {b['scenario']} seed {b['seed']}: recorded {b['content_hash'][:12]}, got {b['got'][:12]}")
    print(f"{n - len(bad)}/{n} runs re-simulated to identical content hashes (workers={a.workers})")
    return 1 if bad else 0


command("verify-runs", "re-simulate the runs of a manifest and check identical content hashes")((_verify_args, _verify))
