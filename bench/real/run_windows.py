"""A continuous run (``import-bag``, ``import-csv``, ``simulate``) cut into the DRIVE windows the real benchmark scores.

:func:`windows_from_run` gives the :class:`~bench.real.drive.DriveWindows` that a DRIVE table of the same log would:

1. **Resampling.**  Every channel is put on a uniform grid at ``dt`` (DRIVE's 20 Hz) from the run's start, each grid
   time taking the channel's last finite sample at or before it (zero-order hold: a Run has NaN between a slow
   sensor's samples; DRIVE's parser holds the last message too).  Grid times before a channel's first sample are NaN.
2. **Command steps.**  A step begins where the commanded wheel speeds change by more than ``min_change`` [rad/s]
   on either side, and lasts while they stay within it (DRIVE's protocol: piecewise-constant steps).  Each step is cut
   forward into whole windows of ``window`` seconds: the first is *transitory* (the response to the change), the
   others *steady*; a remainder shorter than a window is dropped.  When no step holds for a whole window (a teleop
   log with continuously varying commands), the log is cut into consecutive 3-window blocks taken as steps, every
   window transitory (none is steady: the chi of Wang eq. (25) is then not measured).  Without command channels the
   log is cut into such blocks too.
3. **Rows.**  ``row`` numbers the windows in log order, skipping a number where samples lie between two windows
   (what :class:`~bench.real.drive.DriveWindows` calls adjacent rows follow each other without a gap).
4. **Frames.**  Each window's reference pose (``ref_x``, ``ref_y``, ``ref_yaw``) is expressed in a frame at its first
   sample: origin at its position, axes along its heading (so the window starts at (0, 0, 0); ``frame_yaw`` = 0);
   the heading is unwrapped along the window.

The windows need ``enc_wl``, ``enc_wr`` and the reference pose; the other sensor channels come along when present.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.real.drive import DRIVE_DT, DriveWindows
from bench.run import Run, RunError

__all__ = ["windows_from_run", "is_run_file", "WINDOW", "MIN_CHANGE"]

WINDOW = 2.0  # [s] DRIVE's window length
MIN_CHANGE = 0.05  # [rad/s] a command change smaller than this is not a new step
_NEEDED = ("enc_wl", "enc_wr", "ref_x", "ref_y", "ref_yaw")
_CARRIED = ("cmd_wl", "cmd_wr", "imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz")


MAX_SPAN = 7 * 86400.0  # [s] the longest run cut into windows (a week: 12 million samples on DRIVE's grid)


def is_run_file(path: Path) -> bool:
    """True for a skidbench Run (Parquet with the run metadata), False for any other file (e.g. a DRIVE table)."""
    if Path(path).suffix.lower() != ".parquet":
        return False
    import pyarrow.parquet as pq

    from bench.run import META_KEY

    try:
        meta = pq.read_schema(path).metadata or {}
    except Exception:  # noqa: BLE001 - not readable as Parquet: the table reader names the problem
        return False
    return META_KEY in meta


def _hold(t: np.ndarray, v: np.ndarray, grid: np.ndarray) -> np.ndarray:
    ok = np.isfinite(v)
    if not ok.any():
        return np.full(grid.shape, np.nan)
    ts, vs = t[ok], v[ok]
    i = np.searchsorted(ts, grid + 1e-9 * max(1.0, abs(float(grid[-1]))), side="right") - 1
    out = vs[np.clip(i, 0, None)]
    out[i < 0] = np.nan
    return out


def _steps(cmd: np.ndarray | None, n: int, per: int, min_change: float) -> tuple[list[tuple[int, int, int]], bool]:
    """(start, end, step id) of the command steps on the grid and whether they are the protocol's steps."""
    if cmd is not None:
        c = np.nan_to_num(cmd, nan=np.inf)
        change = np.r_[True, np.any(np.abs(np.diff(c, axis=0)) > min_change, axis=1)]
        starts = np.flatnonzero(change)
        ends = np.r_[starts[1:], n]
        segs = [(int(s), int(e)) for s, e in zip(starts, ends) if e - s >= per and np.all(np.isfinite(cmd[s]))]
        if segs:
            return [(s, e, k) for k, (s, e) in enumerate(segs)], True
    block = 3 * per
    return [(s, s + block, k) for k, s in enumerate(range(0, n - per + 1, block))], False


def windows_from_run(run: Run, where: str | None = None, dt: float = DRIVE_DT, window: float = WINDOW,
                     min_change: float = MIN_CHANGE) -> DriveWindows:
    """The DRIVE windows of ``run`` (module docstring); a one-line :class:`RunError` if it cannot have any."""
    where = where or run.id
    missing = [c for c in _NEEDED if c not in run.data.columns]
    if missing:
        raise RunError(where, missing[0], None, "missing channel: the real benchmark needs the wheel speeds "
                       "(enc_wl, enc_wr) and a reference pose (ref_x, ref_y, ref_yaw)")
    t = run.t
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise RunError(where, "t", None, "expected at least two finite sample times")
    if (span := float(t[-1] - t[0])) > MAX_SPAN:
        raise RunError(where, "t", span, f"a run over {MAX_SPAN / 86400:g} days long: time stamps in another unit "
                       "than seconds?")
    per = int(round(window / dt)) + 0  # samples per window
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    chans = [c for c in (*_NEEDED, *_CARRIED) if c in run.data.columns]
    g = {c: _hold(t, run.data[c].to_numpy(float), grid) for c in chans}
    if "ref_yaw" in g:
        g["ref_yaw"] = np.unwrap(np.where(np.isfinite(g["ref_yaw"]), g["ref_yaw"], 0.0)) + np.where(
            np.isfinite(g["ref_yaw"]), 0.0, np.nan)
    cmd = np.column_stack([g["cmd_wl"], g["cmd_wr"]]) if "cmd_wl" in g and "cmd_wr" in g else None
    steps, protocol = _steps(cmd, grid.size, per, min_change)
    rows, steady, step_id, index = [], [], [], []
    for s, e, k in steps:
        for j, w0 in enumerate(range(s, e - per + 1, per)):
            rows.append(np.arange(w0, w0 + per))
            steady.append(protocol and j > 0)
            step_id.append(k)
            index.append(j)
    if not rows:
        raise RunError(where, "t", float(t[-1] - t[0]), f"the run is shorter than one {window} s window")
    idx = np.array(rows)
    ch = {c: g[c][idx] for c in chans}
    x0, y0, h0 = ch["ref_x"][:, :1], ch["ref_y"][:, :1], ch["ref_yaw"][:, :1]
    c0, s0 = np.cos(h0), np.sin(h0)
    dx, dy = ch["ref_x"] - x0, ch["ref_y"] - y0
    ch["ref_x"], ch["ref_y"], ch["ref_yaw"] = c0 * dx + s0 * dy, -s0 * dx + c0 * dy, ch["ref_yaw"] - h0
    n = idx.shape[0]
    steady_a = np.array(steady, bool)
    step_a = np.array(step_id, float)
    return DriveWindows(source=str(where), dt=dt, channels=ch, calib_step=step_a, calib_step_label=step_a.copy(),
                        window=np.array(index), steady=steady_a, transitory=~steady_a,
                        overlap=np.zeros(n, int), frame_yaw=np.zeros(n), row=_rows(idx))


def _rows(idx: np.ndarray) -> np.ndarray:
    """The windows' ``row`` numbers: consecutive for windows that follow each other on the grid without a gap, one
    more apart where samples were dropped between them (a step's remainder, a step shorter than a window), so that
    :func:`bench.real.clock.shift_stream` borrows samples from a neighbour only across a real boundary."""
    gap = np.r_[False, idx[1:, 0] != idx[:-1, -1] + 1]
    return np.arange(idx.shape[0]) + np.cumsum(gap)
