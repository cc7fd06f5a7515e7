"""CSV log import (one row per log tick, a header line with column names, an empty cell is "no
sample"): :func:`import_csv`, with the field counts and the numbers of every line checked; and the estimate
CSV ``skidbench estimate`` writes (:func:`read_estimate_csv`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from bench.formats.channels import _check_time, _finish, _pose_channels
from bench.formats.mapping import (_ACCEL_UNITS, _ANGLE_UNITS, _GYRO_UNITS, _POS_UNITS, _POSE_PREFIX, _TIME_UNITS,
                                   _WHEEL_PREFIX, ImportMapping, PoseMap, WheelMap, _as_mapping, _platform,
                                   _wheel_factor)
from bench.formats.plausible import _check_yaw_unit
from bench.run import Run, RunError
from bench.spec import SpecError

__all__ = ["import_csv", "read_estimate_csv"]


# ------------------------------------------------------------------------------------------
# CSV
# ------------------------------------------------------------------------------------------
def _check_csv_rows(path: Path, raw: bytes, sep: bytes = b",") -> None:
    """Every line has as many separators as the header (a truncated or overlong line is named)."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    nl = np.flatnonzero(buf == ord("\n"))
    ends = np.append(nl, buf.size) if (buf.size and (nl.size == 0 or nl[-1] != buf.size - 1)) else nl
    if ends.size == 0:
        return
    starts = np.concatenate(([0], ends[:-1] + 1))
    seps = np.flatnonzero(buf == sep[0])
    counts = np.searchsorted(seps, ends) - np.searchsorted(seps, starts)
    nonblank = ends > starts
    if b'"' in raw[: int(ends[0])]:
        return  # quoted header: leave field counting to the parser
    bad = np.flatnonzero(nonblank & (counts != counts[0]))
    if bad.size:
        i = int(bad[0])
        line = raw[int(starts[i]):int(ends[i])].decode(errors="replace")
        last = i == ends.size - 1 and not raw.endswith(b"\n")
        raise RunError(str(path), "<file>", f"line {i + 1}: {line[:60]!r}",
                       f"expected {counts[0] + 1} fields like the header, found {counts[i] + 1}"
                       + (" (file truncated?)" if last or counts[i] < counts[0] else ""))


def _parse_column(path: Path, name: str, raw: pd.Series, policy: str, required_full: bool = False
                  ) -> np.ndarray:
    s = raw.astype(str).str.strip()
    empty = s.eq("").to_numpy()
    v = pd.to_numeric(s.where(~s.eq(""), None), errors="coerce").to_numpy(dtype=float, copy=True)
    notnum = np.isnan(v) & ~empty & ~s.str.lower().isin(["nan", "+nan", "-nan"]).to_numpy()
    if notnum.any():
        i = int(np.flatnonzero(notnum)[0])
        raise RunError(str(path), name, f"line {i + 2}: {s.iloc[i]!r}", "expected a number")
    nonfinite = ~np.isfinite(v) & ~empty
    if nonfinite.any():
        if policy == "drop" and not required_full:
            v[nonfinite] = np.nan
        else:
            i = int(np.flatnonzero(nonfinite)[0])
            raise RunError(str(path), name, f"line {i + 2}: {s.iloc[i]!r}",
                           "NaN/inf is not a sample: leave the cell empty for 'no sample' "
                           "(or set nan_policy = \"drop\")")
    if required_full and empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise RunError(str(path), name, f"line {i + 2}: empty", "every row needs a timestamp")
    return v


def import_csv(csv_path: str | Path, mapping: ImportMapping | str | Path, *, check: bool = True) -> Run:
    """Import a CSV log (one row per log tick, header line with column names; an empty cell is
    "no sample").  See the module docstring for the mapping."""
    path = Path(csv_path)
    mp = _as_mapping(mapping)
    platform = _platform(mp)
    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    raw = path.read_bytes()
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False, skip_blank_lines=False)
    except pd.errors.EmptyDataError:
        raise RunError(str(path), "<file>", "empty file", "a CSV log needs a header line and rows") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
        raise RunError(str(path), "<file>", str(exc).strip().splitlines()[-1], "malformed CSV") from None
    _check_csv_rows(path, raw)
    df.columns = [str(c).strip() for c in df.columns]
    hints: dict[str, str] = {}

    def col(section: str, fieldname: str, name: str, required_full: bool = False) -> np.ndarray:
        if name not in df.columns:
            raise RunError(str(path), name, None,
                           f"column named by mapping {section}.{fieldname} is not in the CSV; "
                           f"columns: {list(df.columns)}")
        return _parse_column(path, name, df[name], mp.nan_policy, required_full)

    t = col("time", "column", mp.time.column, required_full=True)
    if t.size == 0:
        raise RunError(str(path), mp.time.column, "empty", "the log has no rows")
    _check_time(str(path), mp.time.column, t)
    t = t * _TIME_UNITS[mp.time.unit]
    cols: dict[str, np.ndarray] = {"t": t - t[0]}

    for section, prefix in _WHEEL_PREFIX.items():
        wm: WheelMap = getattr(mp, section)
        if not (wm.left or wm.right):
            continue
        k = _wheel_factor(wm, section, platform, mp)
        for side, name, inv in (("left", wm.left, wm.invert_left), ("right", wm.right, wm.invert_right)):
            if not name:
                raise SpecError(mp.source_file or "<mapping>", f"{section}.{side}", "",
                                "both wheel columns are needed")
            ch = f"{prefix}_w{side[0]}"
            cols[ch] = col(section, side, name) * (k * (-1.0 if inv else 1.0))
            hints[ch] = f"CSV column '{name}', mapping {section}.unit = '{wm.unit}'"
    im = mp.imu
    for key, unit in (("ax", _ACCEL_UNITS[im.accel_unit]), ("ay", _ACCEL_UNITS[im.accel_unit]),
                      ("az", _ACCEL_UNITS[im.accel_unit]), ("gx", _GYRO_UNITS[im.gyro_unit]),
                      ("gy", _GYRO_UNITS[im.gyro_unit]), ("gz", _GYRO_UNITS[im.gyro_unit])):
        name = getattr(im, key)
        if name:
            cols[f"imu_{key}"] = col("imu", key, name) * unit
            u = im.accel_unit if key[0] == "a" else im.gyro_unit
            hints[f"imu_{key}"] = f"CSV column '{name}', mapping imu.{'accel' if key[0] == 'a' else 'gyro'}_unit = '{u}'"
    for section, prefix in _POSE_PREFIX.items():
        pm: PoseMap = getattr(mp, section)
        if not (pm.x or pm.y):
            continue
        if not (pm.x and pm.y):
            raise SpecError(mp.source_file or "<mapping>", f"{section}.{'y' if pm.x else 'x'}", "",
                            "a pose source needs both x and y columns")
        kp, ka = _POS_UNITS[pm.position_unit], _ANGLE_UNITS[pm.yaw_unit]
        get = {f: (col(section, f, getattr(pm, f)) if getattr(pm, f) else None)
               for f in ("x", "y", "yaw", "vx", "vy", "wz")}
        if get["yaw"] is not None:
            _check_yaw_unit(str(path), pm.yaw, get["yaw"], pm, section)
        yaw = None if get["yaw"] is None else get["yaw"] * ka
        try:
            cols.update(_pose_channels(
                prefix, get["x"] * kp, get["y"] * kp, yaw,
                None if get["vx"] is None else get["vx"] * kp, None if get["vy"] is None else get["vy"] * kp,
                None if get["wz"] is None else get["wz"] * ka, pm.velocity_frame))
        except ValueError:
            raise SpecError(mp.source_file or "<mapping>", f"{section}.yaw", "",
                            "converting velocities between body and world frame needs a yaw column") from None
    return _finish(cols, path, mp, platform, hints, check)


def read_estimate_csv(path: str | Path) -> pd.DataFrame:
    """An estimate CSV (``skidbench estimate``'s output): numeric columns t, x, y, yaw at least, t strictly
    increasing; anything else is a :class:`RunError` naming the file, the column and the value."""
    path = Path(path)
    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    try:
        frame = pd.read_csv(path)
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:  # EmptyDataError is a ValueError
        raise RunError(str(path), "<file>", str(exc).splitlines()[0], "an estimate CSV (t, x, y, yaw)") from None
    missing = [c for c in ("t", "x", "y", "yaw") if c not in frame.columns]
    if missing:
        raise RunError(str(path), ", ".join(missing), "missing", "an estimate CSV has columns t, x, y, yaw")
    for c in ("t", "x", "y", "yaw"):
        if not pd.api.types.is_numeric_dtype(frame[c]) or pd.api.types.is_bool_dtype(frame[c]):
            raise RunError(str(path), c, str(frame[c].dtype), "expected numbers")
    t = frame["t"].to_numpy(float)
    if t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        bad = "fewer than 2 rows" if t.size < 2 else "not finite and strictly increasing"
        raise RunError(str(path), "t", bad, "time stamps: at least 2, finite, strictly increasing")
    return frame
