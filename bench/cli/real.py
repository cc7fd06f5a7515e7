"""Real data: ``skidbench real DATA... --platform PLATFORM --out DIR [--json F] [--fix NAME]`` (any robot's DRIVE
window tables scored by every registered plugin with window models, outputs named ``<data>-<platform>.*``, the data's
sanity checks printed and reported), and the real-data run of ``skidbench reproduce`` (the extra ``real``): where
measured data lives (:func:`data_root`) and the DRIVE Husky benchmark plus its gap workflow (:func:`_extra_real`).

Registered as an extra by :mod:`bench.cli.reproduce` (first of the extras, as before).
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from bench.cli import command, count, output_files, unwritable_folder
from bench.cli.formats import print_sanity
from bench.schema import SpecError


def data_root() -> Path:
    """Where measured data lives: $SKIDBENCH_DATA, else ../shared/data beside the checkout (bench.paths)."""
    from bench.paths import default_data

    return default_data()


def _extra_real(results_dir: Path, quick: bool, workers: int = 1) -> None:  # serial: < 1 min
    from bench.real.benchmark import every_window_plugin, run_real_benchmark
    from bench.real.league import data_sets, write_real_league
    from bench.reproduce.publish import final_dir

    root = data_root()
    table = root / "drive_husky" / "husky_windows.parquet"
    if not table.is_file():
        if not data_sets(root):
            print(f"real: skipped, no data at {root} (set SKIDBENCH_DATA to the folder holding drive_husky/ "
                  "or folders with a DRIVE table and a platform.toml)")
            return
        league = write_real_league(root, results_dir / "real")  # the other robots' data sets; no Husky gap
        print(f"real: {final_dir(results_dir) / 'real' / Path(league).name} (no Husky table at {table})")
        return
    res = run_real_benchmark(table, results_dir / "real", models=every_window_plugin())
    league = write_real_league(root, results_dir / "real", done={table: res})
    print(f"real: {final_dir(results_dir) / 'real' / Path(league).name}")  # where it is published, not staged
    v = res["verdict"]
    print(f"real: best ICR model {v['best_icr_model']} median {v['best_icr_median_trans']:.3f} m vs ideal DD "
          f"{v['ideal_dd_median_trans']:.3f} m ({res['runtime_s']:.1f} s)")
    # the gap workflow with the testbed's husky model against the same data (bounded: bench.real.gap.BOUNDED)
    from bench.real.gap import BOUNDED, run_real_gap

    gap = run_real_gap(table, results_dir / "real", config=BOUNDED)
    ho = gap["doc"]["held_out"]["cost"]
    print(f"real gap: {gap['doc']['workflow']['verdict']}; held-out cost {ho['before_mean']:.4g} -> "
          f"{ho['after_mean']:.4g} ({gap['runtime_s']:.1f} s; total {res['runtime_s'] + gap['runtime_s']:.1f} s)")


# ------------------------------------------------------------------------------------------ real
def _real_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", nargs="+", type=Path, help="DRIVE window tables (.parquet, .pkl, .csv) or continuous runs (.parquet of import-bag / "
                   "import-csv / simulate), cut into the same windows")
    p.add_argument("--platform", required=True,
                   help="a platform name (skidbench list) or a TOML file with wheel_radius and track [m]")
    p.add_argument("--out", type=Path, required=True, help="output folder (nothing is written anywhere else)")
    p.add_argument("--json", type=Path, default=None, help="also write every data set's numbers to this JSON file")
    p.add_argument("--seed", type=count(0), default=0, help="seed of the calibration / held-out split by command step")
    p.add_argument("--methods", default=None,
                   help="comma-separated plugin names (default: every registered plugin with window models)")
    p.add_argument("--fix", action="append", default=[], metavar="NAME",
                   help="apply a sanity check's correction: flip_gyro, imu_offset, align_gyro, drop_stale (repeatable)")
    p.add_argument("--no-figures", action="store_true")


def _real(a: argparse.Namespace) -> int:
    from bench.real.benchmark import every_window_plugin
    from bench.real.platform import kinematic_platform
    from bench.report.io import atomic_write_text, dumps_json

    plat = kinematic_platform(a.platform)
    methods = [m.strip() for m in a.methods.split(",") if m.strip()] if a.methods else every_window_plugin()
    if not methods:
        raise SpecError("<command line>", "--methods", a.methods, "at least one plugin name")
    methods = list(dict.fromkeys(["baseline.ideal_dd", *methods]))  # every verdict is against ideal DD
    output_files(a, "json")
    with staged_folder(a.out) as stage:  # every table's files appear in --out together, or none of them
        docs = _score_tables(a, plat, methods, stage)
    if a.json:
        atomic_write_text(a.json, dumps_json({"platform": plat, "methods": methods, "data": docs}, indent=1,
                                             sort_keys=True) + "\n")
    return 0


def _score_tables(a: argparse.Namespace, plat: dict, methods: list[str], stage: Path) -> dict[str, dict]:
    from bench.real.benchmark import run_real_benchmark

    docs, written = {}, []
    for data in a.data:
        label = f"{data.stem}-{plat['name']}"
        res = run_real_benchmark(data, stage, a.seed, platform=plat, models=methods, figures=not a.no_figures,
                                 label=label, fixes=a.fix)
        print_sanity(data, res["sanity"])
        for name, why in res["skipped_models"].items():
            print(f"{data}: {name} not scored: {why}")
        v = res["verdict"]
        best = (f"best ICR model {v['best_icr_model']} median {v['best_icr_median_trans']:.3f} m vs ideal DD "
                f"{v['ideal_dd_median_trans']:.3f} m" if v["best_icr_model"] else "no ICR-family model scored")
        print(f"{data}: {len(res['models'])} models on {res['n_test_windows']} held-out windows; {best}")
        written.append(a.out / (label + ".md"))
        docs[str(data)] = {k: res[k] for k in res if k not in ("files", "runtime_s") and not k.startswith("_")}
    # the reports appear in --out together once every table is scored (staged_folder): named only then
    for path in written:
        print(f"-> {path}")
    return docs


def dead_stage(folder: Path) -> bool:
    """Whether ``folder`` is the staging folder (``.staging.<pid>.<random>.tmp``) of a process that no longer runs: a
    killed ``real`` or ``real-gap`` (the ``finally`` of :func:`staged_folder` never ran).  A live process's stage,
    one of another user's, one named otherwise, and any on a system without POSIX signals are not."""
    parts = folder.name.split(".")
    if os.name != "posix" or len(parts) < 4 or parts[1] != "staging" or not parts[2].isdigit():
        return False
    try:
        os.kill(int(parts[2]), 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OverflowError):
        return False  # alive (another user's), or not a pid this system has: left alone
    return False  # alive, or its pid taken by another process since: left for a later run


def _remove_dead_stages(out: Path) -> None:
    for d in out.glob(".staging.*.tmp"):
        if d.is_dir() and dead_stage(d):
            shutil.rmtree(d, ignore_errors=True)


@contextlib.contextmanager
def staged_folder(out: Path) -> Iterator[Path]:
    """A hidden folder inside ``out`` to write into (the same file system: the moves are renames); its files are
    moved into ``out`` when the block ends normally and it is removed either way.  On a failure ``out`` is as it
    was: removed again if this call made it."""
    if out.exists() and not out.is_dir():
        raise SpecError("<command line>", "--out", str(out), "a folder, not a file")
    if (folder := unwritable_folder(out)) is not None:
        raise SpecError("<command line>", "--out", str(out), f"cannot be written: {folder} is not a writable folder")
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    _remove_dead_stages(out)
    stage = Path(tempfile.mkdtemp(prefix=f".staging.{os.getpid()}.", suffix=".tmp", dir=out))
    try:
        yield stage
        for f in sorted(stage.iterdir()):
            os.replace(f, out / f.name)
    except BaseException:
        if made:
            shutil.rmtree(out, ignore_errors=True)
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)


command("real", "score the registered plugins on real DRIVE window tables: skidbench real DATA... --platform P "
        "--out DIR")((_real_args, _real))


# ------------------------------------------------------------------------------------------ real-gap
def _gap_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", type=Path, help="a DRIVE window table or a continuous run (.parquet of import-bag / "
                   "import-csv)")
    p.add_argument("--platform", required=True,
                   help="the testbed platform: a name (skidbench list) or the path of a full platform TOML (the "
                        "dynamic model needs mass, inertia, wheels and motors)")
    p.add_argument("--terrain", default=None, help="nominal terrain (name or TOML; default asphalt)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--json", type=Path, default=None, help="also copy the JSON document here")
    p.add_argument("--seed", type=count(0), default=0, help="seed of the calibration / held-out split by command step")
    p.add_argument("--full", action="store_true", help="three consecutive fit steps instead of two")
    p.add_argument("--fit-steps", type=count(1), default=None, metavar="N",
                   help="fit on the first N calibration steps, each replayed on its own from its measured initial "
                        "state (bench.gap.segments), instead of the first consecutive ones as one run")
    p.add_argument("--max-effects", type=count(1), default=None, metavar="K", help="effects selected at most "
                   "(default 2)")
    p.add_argument("--no-steady", action="store_true",
                   help="skip the steady stages, the command and turn responses identified on the calibration half's "
                        "steady windows (bench.real.command_response, turn_response): the simulation starts from the "
                        "nominal model")
    p.add_argument("--no-transient", action="store_true",
                   help="skip the transient stage (bench.real.transient_response: delay, acceleration limits and "
                        "encoder latency from the first 2 s of each calibration step)")
    p.add_argument("--validation-steps", type=count(1), default=None, metavar="N",
                   help="judge the fit block's effects on the first N other calibration steps (default: all)")
    p.add_argument("--workers", type=count(1), default=None)


def _real_gap(a: argparse.Namespace) -> int:
    from bench.real.gap import BOUNDED, FULL, nominal_scenario, run_real_gap
    from bench.report.io import atomic_write_text

    name = nominal_scenario(a.platform, a.terrain).platform.name  # a missing spec field stops here, before any run
    label = f"{a.data.stem}-{name}"
    config = FULL if a.full else BOUNDED
    if a.fit_steps is not None:
        config = dataclasses.replace(config, n_fit=a.fit_steps, separate=True)
    if a.max_effects is not None:
        config = dataclasses.replace(config, max_effects=a.max_effects)
    if a.no_steady:
        config = dataclasses.replace(config, steady=False)
    if a.no_transient:
        config = dataclasses.replace(config, transient=False)
    if a.validation_steps is not None:
        config = dataclasses.replace(config, n_validation=a.validation_steps)
    output_files(a, "json")
    with staged_folder(a.out) as stage:  # the report's files appear in --out together, or none of them
        r = run_real_gap(a.data, stage, a.seed, platform=a.platform, terrain=a.terrain, config=config,
                         workers=a.workers, label=label)
        doc_json = Path(r["files"][-2]).read_text()
    print_sanity(a.data, r["sanity"])
    ho = r["doc"]["held_out"]["cost"]
    print(f"{r['doc']['workflow']['verdict']}; held-out cost {ho['before_mean']:.4g} -> {ho['after_mean']:.4g} "
          f"-> {a.out / (label + '_gap.md')}")
    if a.json:
        atomic_write_text(a.json, doc_json)
    return 0


command("real-gap", "the gap workflow of a testbed platform against real data: skidbench real-gap DATA --platform P "
        "--out DIR")((_gap_args, _real_gap))
