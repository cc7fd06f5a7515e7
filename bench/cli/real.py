"""The real-data run of ``skidbench reproduce`` (the extra ``real``): where measured data lives
(:func:`data_root`) and the DRIVE Husky benchmark plus its gap workflow (:func:`_extra_real`).

Registered as an extra by :mod:`bench.cli.reproduce` (first of the extras, as before).
"""
from __future__ import annotations

from pathlib import Path


def data_root() -> Path:
    """Where measured data lives: $SKIDBENCH_DATA, else ../shared/data beside the checkout (bench.paths)."""
    from bench.paths import default_data

    return default_data()


def _extra_real(results_dir: Path, quick: bool, workers: int = 1) -> None:  # serial: < 1 min
    from bench.real.benchmark import run_real_benchmark

    table = data_root() / "drive_husky" / "husky_windows.parquet"
    if not table.is_file():
        print(f"real: skipped, no data at {table} (set SKIDBENCH_DATA to the folder holding drive_husky/)")
        return
    res = run_real_benchmark(table, results_dir / "real")
    v = res["verdict"]
    print(f"real: best ICR model {v['best_icr_model']} median {v['best_icr_median_trans']:.3f} m vs ideal DD "
          f"{v['ideal_dd_median_trans']:.3f} m ({res['runtime_s']:.1f} s)")
    # the gap workflow with the testbed's husky model against the same data (bounded: bench.real.gap.BOUNDED)
    from bench.real.gap import BOUNDED, run_real_gap

    gap = run_real_gap(table, results_dir / "real", config=BOUNDED)
    ho = gap["doc"]["held_out"]["cost"]
    print(f"real gap: {gap['doc']['workflow']['verdict']}; held-out cost {ho['before_mean']:.4g} -> "
          f"{ho['after_mean']:.4g} ({gap['runtime_s']:.1f} s; total {res['runtime_s'] + gap['runtime_s']:.1f} s)")
