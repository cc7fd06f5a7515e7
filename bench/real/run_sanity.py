"""The data sanity checks of :mod:`bench.real.sanity` on a continuous run, at ``import-bag`` / ``import-csv`` time.

:func:`check_run` cuts the run into the DRIVE windows the real benchmark will score
(:func:`bench.real.run_windows.windows_from_run`), runs :func:`bench.real.sanity.check_windows` on them and records
the findings in the run's metadata (``meta["sanity"]``: ``findings``; ``fixes``, one line per correction; with
``--fix imu_offset`` the ``offsets`` subtracted; with any fix ``after``, the findings on the corrected samples; and
``skipped`` with the reason when the run has no windows, e.g. no reference pose).  The corrections that act on the run's samples are applied
to the run itself, with the values measured on its windows:

* ``flip_gyro``: ``imu_gz`` multiplied by -1;
* ``imu_offset``: the steady-window offsets of ``imu_ax``, ``imu_ay`` and the gyro bias subtracted (measured after
  the flip, as :func:`~bench.real.sanity.apply_fixes` does);
* ``drop_stale`` selects windows, and ``align_gyro`` reads the gyro at another sample of the scored windows: refused
  here with a one-line error (pass them to ``skidbench real``).

The same checks run again when the imported run is scored (``skidbench real RUN.parquet``), so the import's record is
what the data looked like as recorded, and the score's is what was scored.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Sequence

from bench.real.run_windows import windows_from_run
from bench.real.sanity import FIXES, RUN_UNIT_COLUMNS, check_windows, refuse_needless_flip, refuse_unit_slips
from bench.run import Run, RunError
from bench.spec import SpecError

__all__ = ["check_run", "RUN_FIXES"]

RUN_FIXES = ("flip_gyro", "imu_offset")  # the corrections that act on samples (drop_stale selects windows)


def _wheel_radius(run: Run) -> float | None:
    """The platform's wheel radius [m] from the run's metadata (the ``wheel_scale`` check), None when not given."""
    r = (run.meta.get("platform") or {}).get("wheel_radius")
    return float(r) if isinstance(r, (int, float)) and not isinstance(r, bool) and r > 0 else None


def check_run(run: Run, fixes: Sequence[str] = (), where: str = "--fix") -> Run:
    """``run`` with the sanity findings in ``meta["sanity"]`` and the corrections ``fixes`` applied (module doc)."""
    for f in fixes:
        if f not in FIXES:
            raise SpecError("<command line>", where, f, f"expected one of {', '.join(RUN_FIXES)}")
        if f not in RUN_FIXES:
            what = ("drops scored windows, not samples" if f == "drop_stale"
                    else "reads the gyro at another sample of the scored windows")
            raise SpecError("<command line>", where, f, f"{f} {what}: pass it to `skidbench real` instead")
    try:
        w = windows_from_run(run)
    except RunError as e:
        return Run(run.data, {**run.meta, "sanity": {"findings": [], "fixes": [], "skipped": str(e)}})
    r = _wheel_radius(run)
    found = check_windows(w, r)
    refuse_unit_slips(found, run.where, RUN_UNIT_COLUMNS)
    sanity: dict[str, Any] = {"findings": [dataclasses.asdict(f) for f in found], "fixes": []}
    if not fixes:
        return Run(run.data, {**run.meta, "sanity": sanity})
    data, lines = run.data.copy(), []
    if "flip_gyro" in fixes and "imu_gz" in data.columns:
        refuse_needless_flip(next((f for f in found if f.check == "gyro_sign"), None), where)
        data["imu_gz"] = -data["imu_gz"]
        lines.append("flip_gyro: imu_gz multiplied by -1")
    if "imu_offset" in fixes:  # measured after the flip, on the windows of the corrected samples
        found = {f.check: f for f in check_windows(windows_from_run(Run(data, run.meta)))}
        offset = found.get("imu_offset")
        sanity["offsets"] = dict(offset.values) if offset is not None else {}
        for col, v in sanity["offsets"].items():
            data[col] = data[col] - v
            lines.append(f"imu_offset: {col} {-v:+.4g}")
    sanity["fixes"] = lines
    sanity["after"] = [dataclasses.asdict(f) for f in check_windows(windows_from_run(Run(data, run.meta)), r)]
    return Run(data, {**run.meta, "sanity": sanity})
