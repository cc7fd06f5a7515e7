"""Importer of DRIVE-format window tables (real robot logs) into Runs and per-window arrays.

Source format: the ``torch_ready_dataframe`` written by the DRIVE data parser
(Baril et al., "DRIVE: Data-driven Robot Input Vector Exploration", ICRA 2024, arXiv 2309.10718;
code: github.com/norlab-ulaval/DRIVE, ``model_training/data_utils/dataset_parser.py``).  One row per
window of ``N`` samples (N = 40 for 2 s at 20 Hz); per-sample columns carry a suffix ``_0 .. _{N-1}``:

=========================  ==================  ==============================================
DRIVE column               Run channel         meaning
=========================  ==================  ==============================================
cmd_left_k, cmd_right_k    cmd_wl, cmd_wr      commanded wheel speeds [rad/s]
left/right_wheel_vel_k     enc_wl, enc_wr      measured wheel speeds [rad/s]
icp_x_k, icp_y_k           ref_x, ref_y        lidar ICP position (the reference sensor) [m]
icp_yaw_k                  ref_yaw             ICP heading [rad] (re-expressed, see below)
imu_acceleration_x/y/z_k   imu_ax/ay/az        accelerometer, specific force [m/s^2]
imu_yaw_k                  imu_gz              gyro z rate [rad/s] (NOT an angle, see below)
steady/transitory_mask     steady, transitory  per-window flags, repeated per sample
calib_step                 calib_step          command step id (repaired, see below)
=========================  ==================  ==============================================

No robot constant lives here: the wheel radius and track only go to ``run.meta["platform"]``
(given as a platform name/Platform, optionally overridden by ``wheel_radius``/``track``).  The only
constants are the DRIVE parser's own: 20 Hz resampling (:data:`DRIVE_DT`) and the 5-sample
frame average (:data:`DRIVE_FRAME_SAMPLES`).

What the data say (checked on the Husky table, 603 windows, 201 steps; the tests re-check it):

* **Window order and steps.**  DRIVE cuts every 6 s command step backwards from its end into three
  2 s windows: one ``transitory`` window (the first 2 s after the command change) then two ``steady``
  ones.  The rows follow that order strictly (T, S, S, T, S, S, ...).  The ``calib_step`` label of a
  window is the step id at its first sample; the transitory window often starts 1-2 samples before
  the command change, so 62 of 201 transitory windows carry the *previous* step's label (hence
  steps of "2" and "4" windows when grouping by the label).  We therefore group windows into steps
  structurally: a step starts at each transitory window (if a table has no transitory window at all,
  at each change of the label), and the step id is the label of its steady windows (majority;
  ties: the last one's); a step cut down to its transitory window alone keeps that window's label,
  plus one if it repeats the previous step's.  ``calib_step_label`` keeps the raw label.
* **Time between windows.**  Windows of a step are consecutive blocks of the 20 Hz log, not
  overlapping by design, but DRIVE's backward 2 s walk over jittered timestamps makes adjacent
  windows share 1-3 samples at some boundaries (Husky: 71 of 602 boundaries share 1 sample, 6
  share 2, 2 share 3) and skip 1-2 samples at others (T->S1 boundaries mostly, shown by ``gt_icp_*``
  matching no sample of the window; not measurable from the table).  Shared samples are detected
  by exact equality of all non-ICP channels (IMU, wheel speeds, commands) over the overlap; IMU
  alone is not enough (the logger repeats a held IMU sample in 0.4 % of Husky rows while the wheel
  speeds change).  A row repeating *all* of them would fake an overlap: a 50 ms time shift at worst.
  A step Run keeps a shared sample once (labelled with the earlier window) and puts the next window
  right after it: ``t = DRIVE_DT * sample index`` within the step; an undetected skip shifts later
  samples by <= 0.1 s.
* **ICP frames.**  Each window's ICP pose is expressed in its own frame: origin at the first sample's
  position, axes rotated by the *mean of the first 5 samples'* absolute Euler angles (roll, pitch,
  yaw), while ``icp_yaw_k`` is the raw difference ``yaw_k - yaw_0`` of wrapped angles (2 pi jumps
  when the heading crosses +-pi: 88 Husky windows).  The heading in the window frame is thus
  ``icp_yaw_k - m`` with ``m = mean(icp_yaw_0..4)`` (exact, also when DRIVE's mean straddled +-pi);
  we unwrap it along the window.  A step Run chains its windows' frames into the first window's
  frame: exactly at a shared sample, else by extrapolating the last 0.5 s of ICP motion by one
  sample at constant twist.  Roll/pitch of the frame are ignored (planar).
* **imu_yaw is a yaw *rate*.**  Its window mean follows the ICP yaw rate with slope 0.99 and
  correlation 0.99 (Husky), and it does not integrate to the ICP yaw; the DRIVE parser also labels
  the source column ``imu_yaw_vel``.  It is therefore mapped to ``imu_gz`` (body z rate, CCW +).

NaN handling: structural columns (``calib_step``, the masks) must be finite, else :class:`RunError`.
A NaN sample of a measured channel stays NaN in the Run (the Run convention for "no sample") and in
the window arrays; consumers drop it (the real benchmark excludes a window whose wheel speeds or
ICP start/end pose are not finite, and counts it).  An infinite value is a :class:`RunError`.
"""
from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from bench.run import Run, RunError, from_arrays, wrap_angle
from bench.spec import Platform, SpecError, load_platform, to_dict

DRIVE_DT = 0.05  # [s] DRIVE resamples every log at 20 Hz (dataset_parser.py: ``self.rate = 0.05``)
MAX_WHEEL_SPEED = 300.0  # [rad/s] no wheeled robot's wheel turns faster (a 5 cm wheel at 15 m/s): a unit error
DRIVE_FRAME_SAMPLES = 5  # DRIVE's window frame uses the mean Euler angles of the first 5 samples
EXTRAPOLATION_SAMPLES = 10  # ICP motion over the last 0.5 s sets the one-sample chaining step

#: per-sample DRIVE series -> Run channel; required ones first
REQUIRED_SERIES: Mapping[str, str] = {
    "cmd_left": "cmd_wl", "cmd_right": "cmd_wr",
    "left_wheel_vel": "enc_wl", "right_wheel_vel": "enc_wr",
    "icp_x": "ref_x", "icp_y": "ref_y", "icp_yaw": "ref_yaw",
}
OPTIONAL_SERIES: Mapping[str, str] = {
    "imu_acceleration_x": "imu_ax", "imu_acceleration_y": "imu_ay", "imu_acceleration_z": "imu_az",
    "imu_yaw": "imu_gz",
}
REQUIRED_SCALARS = ("calib_step", "steady_state_mask", "transitory_state_mask")
OPTIONAL_SCALARS = ("icp_vx", "icp_vy", "icp_omega")  # DRIVE's per-window mean body velocities
_REF = ("ref_x", "ref_y", "ref_yaw")


@dataclass(frozen=True)
class DriveWindows:
    """Tidy per-window view of a DRIVE table: channel arrays of shape (n_windows, n_samples).

    ``channels`` uses Run channel names; ``ref_x, ref_y, ref_yaw`` are the ICP pose in each
    window's own DRIVE frame (heading unwrapped; start pose ``(0, 0, wrap(-frame_yaw))``).
    Per-window arrays: ``calib_step`` (repaired step id), ``calib_step_label`` (as in the file),
    ``window`` (index within its step), ``steady``/``transitory`` (bool), ``overlap`` (samples
    shared with the previous row of the table; 0 for the first row), ``frame_yaw`` (``m``), ``row``
    (row in the file), and ``body_velocity`` (DRIVE's ``icp_vx``, ``icp_vy``, ``icp_omega`` if present).
    """

    source: str
    dt: float
    channels: Mapping[str, np.ndarray]
    calib_step: np.ndarray
    calib_step_label: np.ndarray
    window: np.ndarray
    steady: np.ndarray
    transitory: np.ndarray
    overlap: np.ndarray
    frame_yaw: np.ndarray
    row: np.ndarray
    body_velocity: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_windows(self) -> int:
        return int(self.calib_step.shape[0])

    @property
    def n_samples(self) -> int:
        return int(self.channels["enc_wl"].shape[1])

    @property
    def t(self) -> np.ndarray:
        """Sample times within a window [s], shape (n_samples,)."""
        return self.dt * np.arange(self.n_samples)

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.channels:
            raise RunError(self.source, name, None, f"missing channel; the table has {sorted(self.channels)}")
        return self.channels[name]

    def has(self, name: str) -> bool:
        return name in self.channels

    def subset(self, select: np.ndarray) -> "DriveWindows":
        """The windows selected by a boolean mask or an index array (order kept)."""
        idx = np.flatnonzero(select) if np.asarray(select).dtype == bool else np.asarray(select, dtype=np.intp)
        per_window = {
            f.name: getattr(self, f.name)[idx]
            for f in dataclasses.fields(self)
            if f.name not in ("source", "dt", "channels", "body_velocity")
        }
        return dataclasses.replace(
            self,
            channels={k: v[idx] for k, v in self.channels.items()},
            body_velocity={k: v[idx] for k, v in self.body_velocity.items()},
            **per_window,
        )


# ------------------------------------------------------------------------------------------
# reading and validation
# ------------------------------------------------------------------------------------------
def _read_table(path: Path) -> pd.DataFrame:
    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    suffix = path.suffix.lower()
    try:
        if suffix == ".parquet":
            return pd.read_parquet(path)
        if suffix in (".pkl", ".pickle"):
            # DRIVE publishes pickles: loaded by an unpickler that rebuilds numpy/pandas objects alone (a pickle can
            # run any code: pd.read_pickle would)
            from bench.real.restricted_pickle import load_table_pickle

            return load_table_pickle(path)
        if suffix == ".csv":
            return pd.read_csv(path)
    except RunError:
        raise
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad input file
        raise RunError(str(path), "<file>", str(path), f"not a readable DRIVE table ({exc})") from None
    raise RunError(str(path), "<file>", suffix, "expected a .parquet, .pkl or .csv DRIVE table")


def _n_samples(df: pd.DataFrame, where: str) -> int:
    """Samples per window: 1 + the largest suffix of any known per-sample series (so that a missing
    last column of one series is reported, not taken as a shorter window)."""
    bases = "|".join(map(re.escape, (*REQUIRED_SERIES, *OPTIONAL_SERIES)))
    ks = [int(m.group(2)) for c in df.columns if (m := re.fullmatch(rf"({bases})_(\d+)", str(c)))]
    if not ks:
        raise RunError(where, "left_wheel_vel_0", None, "missing column (no per-sample DRIVE columns)")
    n = max(ks) + 1
    if n < 2:
        raise RunError(where, "left_wheel_vel_1", None, "missing column: a window needs at least 2 samples")
    return n


def _series(df: pd.DataFrame, base: str, n: int, where: str, required: bool) -> np.ndarray | None:
    cols = [f"{base}_{k}" for k in range(n)]
    missing = [c for c in cols if c not in df.columns]
    if missing:
        if required or len(missing) < n:
            raise RunError(where, missing[0], None, f"missing column (the table has {n} samples per window)")
        return None
    arr = _numeric(df[cols], where)
    if np.isinf(arr).any():
        i, k = np.argwhere(np.isinf(arr))[0]
        raise RunError(where, cols[k], f"row {i}: {arr[i, k]}", "value must be finite or NaN (inf found)")
    return arr


def _numeric(frame: pd.DataFrame | pd.Series, where: str) -> np.ndarray:
    try:
        return frame.to_numpy(dtype=np.float64)
    except (TypeError, ValueError):
        cols = [frame.name] if isinstance(frame, pd.Series) else list(frame.columns)
        for c in cols:
            s = frame if isinstance(frame, pd.Series) else frame[c]
            bad = pd.to_numeric(s, errors="coerce").isna() & s.notna()
            if bad.any():
                i = int(np.flatnonzero(bad.to_numpy())[0])
                raise RunError(where, str(c), f"row {i}: {s.iloc[i]!r}", "expected a number") from None
        raise


def _scalar(df: pd.DataFrame, name: str, where: str) -> np.ndarray:
    if name not in df.columns:
        raise RunError(where, name, None, "missing column")
    v = _numeric(df[name], where)
    if not np.isfinite(v).all():
        i = int(np.flatnonzero(~np.isfinite(v))[0])
        raise RunError(where, name, f"row {i}: {v[i]}", "structural column must be finite")
    return v


def _mask(df: pd.DataFrame, name: str, where: str) -> np.ndarray:
    v = _scalar(df, name, where)
    bad = (v != 0) & (v != 1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise RunError(where, name, f"row {i}: {v[i]}", "a window mask must be 0 or 1")
    return v.astype(bool)


# ------------------------------------------------------------------------------------------
# structure: steps, overlaps, frames
# ------------------------------------------------------------------------------------------
def _nan_unwrap(a: np.ndarray) -> np.ndarray:
    """np.unwrap along axis 1 ignoring NaN samples (they stay NaN and do not break later ones)."""
    a = np.asarray(a, float)
    finite = np.isfinite(a)
    if finite.all():
        return np.unwrap(a, axis=1)
    n, m = a.shape
    idx = np.where(finite, np.arange(m)[None, :], 0)
    np.maximum.accumulate(idx, axis=1, out=idx)  # forward fill by the last finite index
    filled = np.take_along_axis(np.where(finite, a, 0.0), idx, axis=1)
    first = np.argmax(finite, axis=1)  # back fill leading NaNs with the first finite value
    lead = np.arange(m)[None, :] < first[:, None]
    filled = np.where(lead, np.take_along_axis(filled, first[:, None], axis=1), filled)
    out = np.unwrap(filled, axis=1)
    out[~finite] = np.nan
    return out


def _steps(transitory: np.ndarray, label: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(step id per window, index of the window within its step); see the module docstring."""
    n = label.shape[0]
    if transitory.any():
        start = transitory.copy()
    else:
        start = np.r_[True, label[1:] != label[:-1]]
    start[0] = True
    group = np.cumsum(start) - 1
    first = np.flatnonzero(start)
    window = np.arange(n) - first[group]
    step = np.empty(n, dtype=np.int64)
    prev = None
    for g, s in enumerate(first):
        e = first[g + 1] if g + 1 < first.size else n
        lab = label[s:e][~transitory[s:e]]
        if lab.size:  # the steady windows' label (majority; ties: the last one's)
            vals, counts = np.unique(lab, return_counts=True)
            best = vals[counts == counts.max()]
            sid = int(lab[-1]) if best.size > 1 and lab[-1] in best else int(best[0])
        else:  # a step cut down to its transitory window: its label, +1 if it repeats the previous step's
            sid = int(label[s]) + int(prev is not None and int(label[s]) == prev)
        step[s:e] = sid
        prev = sid
    return step, window


def _overlaps(signature: np.ndarray, max_overlap: int = 3) -> np.ndarray:
    """Samples shared by each row with the previous row: the largest o with
    ``sig[k-1, N-o:] == sig[k, :o]`` over all channels (exact equality; NaN never matches)."""
    n, m, _ = signature.shape
    out = np.zeros(n, dtype=np.int64)
    for o in range(1, min(max_overlap, m - 1) + 1):
        eq = np.all(signature[:-1, m - o:, :] == signature[1:, :o, :], axis=(1, 2))
        out[1:][eq] = o
    return out


def import_drive_windows(path: str | Path, dt: float = DRIVE_DT, max_overlap: int = 3) -> DriveWindows:
    """Read a DRIVE window table (Parquet, pickle or CSV) into :class:`DriveWindows`.

    Raises :class:`RunError` naming the file and the column on a missing column, a non-numeric or
    infinite value, or a non-finite structural column (``calib_step``, masks).
    """
    path = Path(path)
    where = str(path)
    df = _read_table(path)
    if len(df) == 0:
        raise RunError(where, "<rows>", 0, "the table has no windows (a header only)")
    n = _n_samples(df, where)
    channels: dict[str, np.ndarray] = {}
    for base, name in REQUIRED_SERIES.items():
        channels[name] = _series(df, base, n, where, required=True)  # type: ignore[assignment]
    for base, name in OPTIONAL_SERIES.items():
        arr = _series(df, base, n, where, required=False)
        if arr is not None:
            channels[name] = arr
    for base in ("left_wheel_vel", "right_wheel_vel", "cmd_left", "cmd_right"):
        a = np.abs(channels[REQUIRED_SERIES[base]])
        if np.any(a > MAX_WHEEL_SPEED):  # NaN compares False
            i, k = (int(v[0]) for v in np.nonzero(a > MAX_WHEEL_SPEED))
            raise RunError(where, f"{base}_{k}", f"row {i}: {float(a[i, k])}",
                           f"a wheel speed beyond {MAX_WHEEL_SPEED:g} rad/s (the table's unit is rad/s)")
    label = _scalar(df, "calib_step", where)
    if np.any(label != np.round(label)) or np.any(np.abs(label) >= 2**53):
        i = int(np.flatnonzero((label != np.round(label)) | (np.abs(label) >= 2**53))[0])
        raise RunError(where, "calib_step", f"row {i}: {label[i]}", "a step id must be an integer below 2^53")
    label = label.astype(np.int64)
    steady = _mask(df, "steady_state_mask", where)
    transitory = _mask(df, "transitory_state_mask", where)
    both = steady & transitory
    if both.any():
        i = int(np.flatnonzero(both)[0])
        raise RunError(where, "transitory_state_mask", f"row {i}: 1", "a window cannot be steady and transitory")
    body = {c: _numeric(df[c], where) for c in OPTIONAL_SCALARS if c in df.columns}

    # heading in DRIVE's window frame (module docstring): raw yaw differences, frame at their 5-mean
    raw = channels["ref_yaw"]
    with np.errstate(invalid="ignore"):
        m = np.mean(raw[:, :DRIVE_FRAME_SAMPLES], axis=1)
    unwrapped = _nan_unwrap(raw)
    channels["ref_yaw"] = unwrapped - unwrapped[:, :1] + np.asarray(wrap_angle(-m))[:, None]

    step, window = _steps(transitory, label)
    sig_names = [c for c in channels if c not in _REF]
    overlap = _overlaps(np.stack([channels[c] for c in sig_names], axis=-1), max_overlap)
    return DriveWindows(
        source=where, dt=float(dt), channels=channels, calib_step=step, calib_step_label=label,
        window=window, steady=steady, transitory=transitory, overlap=overlap, frame_yaw=m,
        row=np.arange(label.shape[0]), body_velocity=body,
    )


# ------------------------------------------------------------------------------------------
# SE(2) helpers for chaining window frames
# ------------------------------------------------------------------------------------------
def _compose(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    ax, ay, at = a
    bx, by, bt = b
    c, s = np.cos(at), np.sin(at)
    return ax + c * bx - s * by, ay + s * bx + c * by, at + bt


def _between(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    """a^-1 * b."""
    ax, ay, at = a
    c, s = np.cos(at), np.sin(at)
    dx, dy = b[0] - ax, b[1] - ay
    return c * dx + s * dy, -s * dx + c * dy, b[2] - at


def _se2_power(p: tuple[float, float, float], k: float) -> tuple[float, float, float]:
    """exp(k log p): the pose reached by following p's constant twist for the fraction k."""
    x, y, th = p
    if abs(th) < 1e-9:
        return k * x, k * y, k * th
    # log: twist (u, v, th) with p = exp(u, v, th)
    a, b = np.sin(th) / th, (1 - np.cos(th)) / th
    det = a * a + b * b
    u, v = (a * x + b * y) / det, (-b * x + a * y) / det
    tk = k * th
    ak, bk = np.sin(tk) / tk, (1 - np.cos(tk)) / tk
    return (ak * u * k - bk * v * k), (bk * u * k + ak * v * k), tk


def _frame_link(prev: tuple[np.ndarray, np.ndarray, np.ndarray], overlap: int, start_heading: float
                ) -> tuple[float, float, float]:
    """Pose of the next window's frame expressed in the previous window's frame."""
    x, y, h = prev
    m = x.shape[0]
    if overlap >= 1:
        j = m - overlap
        s = (float(x[j]), float(y[j]), float(h[j]))
    else:
        k = min(EXTRAPOLATION_SAMPLES, m - 1)
        last = (float(x[-1]), float(y[-1]), float(h[-1]))
        back = (float(x[-1 - k]), float(y[-1 - k]), float(h[-1 - k]))
        s = _compose(last, _se2_power(_between(back, last), 1.0 / k))
    return s[0], s[1], s[2] - start_heading


# ------------------------------------------------------------------------------------------
# platform and Runs
# ------------------------------------------------------------------------------------------
def resolve_platform(platform: str | Path | Platform | Mapping[str, Any] | None,
                     wheel_radius: float | None = None, track: float | None = None) -> dict[str, Any]:
    """The platform as a dict for ``run.meta["platform"]``: a name/path (``load_platform``), a
    Platform or a mapping, with ``wheel_radius``/``track`` overriding it; with no platform both
    overrides are required (a minimal dict is returned)."""
    for name, v in (("wheel_radius", wheel_radius), ("track", track)):
        ok, expected = Platform._checks[name]  # a wheeled robot's range, the testbed Platform's own check
        if v is not None and not (np.isfinite(v) and ok(v)):
            raise SpecError("<command line>", name, v, f"expected a length {expected}")
    if platform is None:
        if wheel_radius is None or track is None:
            raise SpecError("<command line>", "platform", None, "give a platform, or both wheel_radius and track")
        return {"name": "unspecified", "wheel_radius": float(wheel_radius), "track": float(track)}
    if isinstance(platform, (str, Path)):
        platform = load_platform(platform)
    out = to_dict(platform) if isinstance(platform, Platform) else dict(platform)
    for key in ("wheel_radius", "track"):
        if key not in out:
            raise SpecError("<platform>", key, None, "required field is missing")
    if wheel_radius is not None:
        out["wheel_radius"] = float(wheel_radius)
    if track is not None:
        out["track"] = float(track)
    return out


def windows_to_runs(windows: DriveWindows, platform: Mapping[str, Any] | None = None) -> list[Run]:
    """One Run per step of ``windows`` (windows concatenated; see the module docstring)."""
    runs = []
    stem = Path(windows.source).stem
    chans = [c for c in windows.channels if c not in _REF]
    steps = windows.calib_step
    bounds = np.flatnonzero(np.r_[True, steps[1:] != steps[:-1], True])
    seen: set[int] = set()
    for s, e in zip(bounds[:-1], bounds[1:]):
        step = int(steps[s])
        if step in seen:
            raise RunError(windows.source, "calib_step", step, "two separate groups of windows have the same step id")
        seen.add(step)
        pieces: dict[str, list[np.ndarray]] = {c: [] for c in (*chans, *_REF, "window", "window_sample",
                                                              "steady", "transitory", "calib_step_label")}
        frame = (0.0, 0.0, 0.0)
        prev = None
        overlaps = []
        for w in range(s, e):
            o = int(windows.overlap[w]) if w > s else 0
            overlaps.append(o)
            x, y, h = (windows.channels[c][w] for c in _REF)
            if prev is not None:
                frame = _compose(frame, _frame_link(prev, o, float(h[0])))
            prev = (x, y, h)
            c, sn = np.cos(frame[2]), np.sin(frame[2])
            keep = slice(o, None)
            pieces["ref_x"].append((frame[0] + c * x - sn * y)[keep])
            pieces["ref_y"].append((frame[1] + sn * x + c * y)[keep])
            pieces["ref_yaw"].append((frame[2] + h)[keep])
            for ch in chans:
                pieces[ch].append(windows.channels[ch][w, keep])
            k = windows.n_samples - o
            pieces["window"].append(np.full(k, w - s))
            pieces["window_sample"].append(np.arange(o, windows.n_samples))
            pieces["steady"].append(np.full(k, float(windows.steady[w])))
            pieces["transitory"].append(np.full(k, float(windows.transitory[w])))
            pieces["calib_step_label"].append(np.full(k, float(windows.calib_step_label[w])))
        cols = {k: np.concatenate(v) for k, v in pieces.items()}
        cols["ref_yaw"] = _nan_unwrap(cols["ref_yaw"][None, :])[0]
        n = cols["ref_x"].shape[0]
        data = {"t": windows.dt * np.arange(n)}
        data.update({c: cols[c] for c in ("cmd_wl", "cmd_wr", "enc_wl", "enc_wr", *_REF) if c in cols})
        data.update({c: cols[c] for c in chans if c not in data})
        data["calib_step"] = np.full(n, float(step))
        for c in ("calib_step_label", "window", "window_sample", "steady", "transitory"):
            data[c] = cols[c]
        meta = {
            "run_id": f"{stem}:step{step:03d}",
            "source_file": windows.source,
            "calib_step": step,
            "platform": dict(platform or {}),
            "n_windows": int(e - s),
            "window_overlaps": overlaps,
            "reference": "icp: DRIVE window frames chained into the first window's frame",
            "dt": windows.dt,
            "imu_gz_source": "imu_yaw (a yaw rate in DRIVE tables)" if "imu_gz" in chans else None,
        }
        runs.append(from_arrays(data, meta).validate())
    return runs


def import_drive(path: str | Path, platform: str | Path | Platform | Mapping[str, Any] | None = None,
                 wheel_radius: float | None = None, track: float | None = None,
                 fixes: Sequence[str] = ()) -> list[Run]:
    """Import a DRIVE window table as one :class:`Run` per command step (see module docstring).

    ``platform``: a platform name/path (``bench.spec.load_platform``), a Platform or a mapping;
    ``wheel_radius`` and ``track`` override it (or replace it when ``platform`` is None).  The data's sanity checks
    (:mod:`bench.real.sanity`, on the windows with finite wheel speeds and reference) go to every Run's
    ``meta["sanity"]`` (``findings``, and the corrections ``fixes`` applied before the cut into Runs).
    """
    from bench.real.sanity import apply_fixes, check_windows, refuse_unit_slips
    from bench.real.windows import valid_windows

    plat = resolve_platform(platform, wheel_radius, track)
    w = import_drive_windows(path)
    findings = check_windows(w.subset(valid_windows(w)), float(plat["wheel_radius"]))
    refuse_unit_slips(findings, str(path))
    w, fixed = apply_fixes(w, fixes)
    sanity = {"findings": [dataclasses.asdict(f) for f in findings], "fixes": fixed}
    return [Run(r.data, {**r.meta, "sanity": sanity}) for r in windows_to_runs(w, plat)]


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m bench.real.drive TABLE --platform husky [--wheel-radius R --track B] [--out DIR]``."""
    ap = argparse.ArgumentParser(prog="python -m bench.real.drive", description=main.__doc__)
    ap.add_argument("table", type=Path)
    ap.add_argument("--platform", default=None, help="platform name or TOML path")
    ap.add_argument("--wheel-radius", type=float, default=None, help="[m], overrides the platform")
    ap.add_argument("--track", type=float, default=None, help="[m], overrides the platform")
    ap.add_argument("--out", type=Path, default=None, help="write one Parquet Run per step here")
    args = ap.parse_args(argv)
    try:
        runs = import_drive(args.table, args.platform, args.wheel_radius, args.track)
    except (RunError, SpecError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    n_win = sum(r.meta["n_windows"] for r in runs)
    shared = sum(int(o > 0) for r in runs for o in r.meta["window_overlaps"])
    print(f"{args.table}: {n_win} windows, {len(runs)} steps, {shared} in-step boundaries with shared samples")
    if args.out is not None:
        for r in runs:
            r.to_parquet(args.out / f"step{r.meta['calib_step']:03d}.parquet")
        print(f"wrote {len(runs)} runs to {args.out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
