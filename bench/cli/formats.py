"""CLI commands that import and export logs: ``import-drive``, ``export-tum``, ``import-csv``, ``import-bag``.

    skidbench import-drive TABLE [--platform P] [--wheel-radius R] [--track B] -o FOLDER
    skidbench export-tum INPUT [--source truth|ref|gnss] -o out.tum
    skidbench import-csv LOG --map MAPPING.toml -o run.parquet
    skidbench import-bag BAG --map MAPPING.toml -o run.parquet

Registered into :data:`bench.cli.COMMANDS` on import.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from bench.cli import command


# ------------------------------------------------------------------------------------------ DRIVE
def _drive_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("table", type=Path, help="DRIVE window table (Parquet or pickle)")
    p.add_argument("--platform", default=None, help="platform name or TOML path (e.g. husky)")
    p.add_argument("--wheel-radius", type=float, default=None, help="[m], overrides the platform")
    p.add_argument("--track", type=float, default=None, help="[m], overrides the platform")
    p.add_argument("-o", "--output", type=Path, required=True, help="folder for one Parquet run per command step")
    p.add_argument("--fix", action="append", default=[], metavar="NAME",
                   help="apply a sanity check's correction: flip_gyro, imu_offset, align_gyro, drop_stale (repeatable)")


def print_sanity(where: Path, sanity: dict) -> None:
    """The data sanity warnings (bench.real.sanity) and the corrections applied, one line each."""
    if sanity.get("skipped"):
        print(f"{where}: sanity checks skipped: {sanity['skipped']}")
    for f in sanity["findings"]:
        if not f["ok"]:
            print(f"warning: {where}: {f['check']}: {f['evidence']}"
                  + (f" (--fix {f['fix']} corrects it)" if f["fix"] else ""))
    for line in sanity["fixes"]:
        print(f"{where}: corrected: {line}")


def _import_drive(a: argparse.Namespace) -> int:
    from bench.real.drive import import_drive

    runs = import_drive(a.table, a.platform, a.wheel_radius, a.track, fixes=a.fix)
    print_sanity(a.table, runs[0].meta["sanity"] if runs else {"findings": [], "fixes": []})
    for r in runs:
        r.to_parquet(a.output / f"step{r.meta['calib_step']:03d}.parquet")
    print(f"wrote {len(runs)} runs to {a.output}")
    return 0


command("import-drive", "import a DRIVE window table as one run per command step")((_drive_args, _import_drive))


# ------------------------------------------------------------------------------------------ formats
def _tum_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", type=Path, help="a run (.parquet) or an estimate (.csv from `skidbench estimate`)")
    p.add_argument("--source", default="truth", choices=["truth", "ref", "gnss"], help="pose channels of a run")
    p.add_argument("-o", "--output", type=Path, required=True)


def _export_tum(a: argparse.Namespace) -> int:
    from bench.formats import read_estimate_csv, run_to_tum
    from bench.registry import Estimate
    from bench.run import Run

    if a.input.suffix == ".csv":
        src = Estimate(read_estimate_csv(a.input), method=a.input.stem)
        run_to_tum(None, src, a.output)
    else:
        run_to_tum(Run.from_parquet(a.input).validate(), a.source, a.output)
    print(f"wrote {a.output}")
    return 0


command("export-tum", "write a run's or an estimate's trajectory in TUM format")((_tum_args, _export_tum))


def _imp_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", type=Path)
    p.add_argument("--map", dest="mapping", type=Path, required=True, help="mapping TOML (columns/topics, units)")
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--fix", action="append", default=[], metavar="NAME",
                   help="apply a sanity check's correction to the samples: flip_gyro, imu_offset (repeatable)")


def _import_csv(a: argparse.Namespace) -> int:
    from bench.formats import import_csv
    from bench.real.run_sanity import check_run

    run = check_run(import_csv(a.log, a.mapping), a.fix)  # findings in the run's metadata (meta["sanity"])
    print_sanity(a.log, run.meta["sanity"])
    run.to_parquet(a.output)
    print(f"wrote {a.output} ({len(run.data)} rows)")
    return 0


def _import_bag(a: argparse.Namespace) -> int:
    from bench.formats import import_bag
    from bench.real.run_sanity import check_run

    run = check_run(import_bag(a.log, a.mapping), a.fix)  # findings in the run's metadata (meta["sanity"])
    print_sanity(a.log, run.meta["sanity"])
    run.to_parquet(a.output)
    print(f"wrote {a.output} ({len(run.data)} rows)")
    return 0


command("import-csv", "import a CSV log through a mapping file")((_imp_args, _import_csv))
command("import-bag", "import a ROS 1/ROS 2 bag through a mapping file (rosbags)")((_imp_args, _import_bag))
