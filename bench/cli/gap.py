"""``skidbench gap``: find where simulation and a measured run disagree, name the missing effect.

    skidbench gap --measured RUN.parquet --scenario SCENARIO [--model testbed|yu2010.closed_loop]
                  [--set key=value ...] [--json out.json] [--report-dir DIR] [--workers N]

Prints the verdict and the per-channel gap before/after; ``--json`` writes the result document
(effects with parameters and uncertainty, gap_before, gap_after per channel, verdict, ...);
``--report-dir`` writes the markdown summary, the figure and the JSON there.

Registered in ``bench.cli.COMMANDS`` on import (``add_gap_command`` does the same for any
argparse sub-parsers object).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench.cli import command, count, parse_sets


def gap_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--measured", required=True, type=Path, help="measured run log (Parquet)")
    p.add_argument("--scenario", required=True, help="scenario name (scenarios/<name>.toml) or path")
    p.add_argument("--model", default="testbed", help="testbed (default) or a model plugin name, e.g. yu2010.closed_loop")
    p.add_argument("--set", dest="sets", action="append", metavar="KEY=VALUE",
                   help="override a spec field of the nominal model, e.g. --set terrain.mu_sa=0.5")
    p.add_argument("--json", dest="json_out", type=Path, default=None, help="write the result as JSON here")
    p.add_argument("--report-dir", type=Path, default=None, help="write markdown + figure + JSON here")
    p.add_argument("--workers", type=count(1), default=None, help="simulation processes (default min(2, cpus))")
    p.add_argument("--quiet", action="store_true")


def gap_main(a: argparse.Namespace) -> int:
    from bench.gap import find_gap
    from bench.gap.report import change_text
    from bench.report.io import atomic_write_json
    from bench.run import Run

    run = Run.from_parquet(a.measured).validate()
    log = (lambda s: None) if a.quiet else (lambda s: print(f"  {s}", file=sys.stderr))
    res = find_gap(run, a.scenario, model=a.model, overrides=parse_sets(a.sets), workers=a.workers, progress=log)
    if a.json_out is not None:
        atomic_write_json(a.json_out, res.to_json())
    if a.report_dir is not None:
        from bench.gap.report import write_report

        write_report(res, a.report_dir)
    print(res.verdict)
    if not a.quiet:
        print(f"{'channel':9s} {'RMS before':>12s} {'RMS after':>12s} {'change':>8s}")
        for ch, b in res.gap_before.items():
            aft = res.gap_after[ch]["rms"]
            print(f"{ch:9s} {b['rms']:12.4g} {aft:12.4g} {change_text(b['rms'], aft):>8s}")
    return 0


def add_gap_command(subparsers) -> argparse.ArgumentParser:
    """Add ``gap`` to an argparse sub-parsers object (for a parser built elsewhere)."""
    sp = subparsers.add_parser("gap", help=HELP)
    gap_args(sp)
    sp.set_defaults(handler=gap_main)
    return sp


HELP = "find the sim-vs-measured gap and name the missing effect"
command("gap", HELP)((gap_args, gap_main))

__all__ = ["gap_args", "gap_main", "add_gap_command"]
