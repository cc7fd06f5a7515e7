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
    p.add_argument("--limit", type=count(1), default=None, help="only the first N runs")


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
    _check_manifest(manifest, path)
    bad = verify_manifest(manifest, workers=a.workers, limit=a.limit, source=str(path))
    n = min(len(manifest["runs"]), a.limit or len(manifest["runs"]))
    for b in bad:
        print(f"MISMATCH {b.get('scenario', b['key'])} seed {b['seed']}: recorded {b['content_hash'][:12]}, got {b['got'][:12]}")
    made = manifest.get("cpu_dispatch", "not recorded")
    print(f"{n - len(bad)}/{n} runs re-simulated to identical content hashes (workers={a.workers}; CPU dispatch: "
          f"made under {made}, checked under {dispatch_state()})")
    return 1 if bad else 0


def _check_manifest(manifest: object, path: Path) -> None:
    """Every field :func:`bench.reproduce.runner.verify_manifest` reads, with its type: a one-line error otherwise."""
    from bench.spec import SpecError

    if not isinstance(manifest, dict) or not isinstance(manifest["runs"], dict) \
            or not isinstance(manifest["scenarios"], dict):
        raise SpecError(path, "runs", None, "'runs' and 'scenarios' must be JSON objects")
    for key, r in manifest["runs"].items():
        if not isinstance(r, dict):
            raise SpecError(path, f"runs.{key}", r, "a JSON object with scenario_hash, seed and content_hash")
        for field, ok, what in (("scenario_hash", lambda v: isinstance(v, str) and v in manifest["scenarios"],
                                 "the key of a scenario in 'scenarios'"),
                                ("seed", lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
                                 "an integer >= 0"),
                                ("content_hash", lambda v: isinstance(v, str), "a string")):
            if not ok(r.get(field)):
                raise SpecError(path, f"runs.{key}.{field}", r.get(field), f"expected {what}")
    for key, scn in manifest["scenarios"].items():
        if not isinstance(scn, dict):
            raise SpecError(path, f"scenarios.{key}", scn, "a JSON object (a scenario)")


command("verify-runs", "re-simulate the runs of a manifest and check identical content hashes")((_verify_args, _verify))
