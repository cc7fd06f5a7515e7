"""CLI command ``skidbench verify-runs [MANIFEST] [--workers N] [--limit N]``: determinism of the run logs.

Re-simulates the runs of a manifest (default ``results/runs_manifest.json``) and checks identical content hashes.
Registered into :data:`bench.cli.COMMANDS` on import.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench.cli import command, count


# ------------------------------------------------------------------------------------------ determinism
def _verify_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("manifest", type=Path, nargs="?", default=None, help="default results/runs_manifest.json")
    p.add_argument("--workers", type=count(1), default=1)
    p.add_argument("--limit", type=int, default=None, help="only the first N runs")


def _verify(a: argparse.Namespace) -> int:
    from bench.cpu import dispatch_state
    from bench.reproduce import RESULTS
    from bench.reproduce.runner import verify_manifest
    from bench.spec import SpecError

    path = a.manifest or RESULTS / "runs_manifest.json"
    try:
        manifest = json.loads(path.read_text())
        manifest["runs"], manifest["scenarios"]
    except OSError as exc:
        raise SpecError(path, "<file>", str(path), f"cannot read the manifest ({exc.strerror})") from None
    except (ValueError, KeyError, TypeError):
        raise SpecError(path, "runs", None, "not a runs manifest (JSON with 'runs' and 'scenarios')") from None
    bad = verify_manifest(manifest, workers=a.workers, limit=a.limit)
    n = min(len(manifest["runs"]), a.limit or len(manifest["runs"]))
    for b in bad:
        print(f"MISMATCH {b['scenario']} seed {b['seed']}: recorded {b['content_hash'][:12]}, got {b['got'][:12]}")
    made = manifest.get("cpu_dispatch", "not recorded")
    print(f"{n - len(bad)}/{n} runs re-simulated to identical content hashes (workers={a.workers}; CPU dispatch: "
          f"made under {made}, checked under {dispatch_state()})")
    return 1 if bad else 0


command("verify-runs", "re-simulate the runs of a manifest and check identical content hashes")((_verify_args, _verify))
