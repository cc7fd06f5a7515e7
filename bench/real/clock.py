"""Time offsets between a window table's input streams and its reference pose (the ICP of a DRIVE table).

The real benchmark integrates each input sample k over [t_k, t_k+1] (:mod:`bench.real.windows`) and scores the end
pose against the reference.  When a stream's clock is offset from the reference's (a late pose estimate, a gyro
stamped on arrival), a model that reads it is scored against a reference that is early or late, and its transitory
windows pay for it.  :func:`stream_offset` measures the offset as the shift ``s`` (in samples, on a half-sample grid)
that best fits the reference's rate over each interval [t_k, t_k+1] by the stream at sample ``k + s`` (linear
interpolation), with a free gain (least squares through the origin: a scale or a chi does not matter) over the
interior samples of every window (``MAX_SHIFT`` kept clear of both ends, so that every shift reads inside the
window).  ``s > 0``: the stream is late (the reference's motion shows in it ``s`` samples later); ``s < 0``: early.

Streams and reference rates:

* ``imu_gz`` against the reference yaw rate ``(psi_k+1 - psi_k) / dt``;
* the wheels' forward speed ``(w_l + w_r) / 2`` against the reference's forward speed, the displacement over the
  interval along the heading at its start;
* the wheels' turn ``w_r - w_l`` against the reference yaw rate (shown, not judged: in a skid-steer turn the yaw
  follows the treads through the turn's dynamics, so its best shift need not be a clock offset).

:func:`shift_stream` moves a stream by ``-s`` samples so that its sample k is its reading at k + s, taking the samples
beyond a window's ends from the table's previous / next row when that row is the adjacent block of the log (its
``row`` one less / more, minus the samples the rows share, ``DriveWindows.overlap``), else holding the end sample.
"""
from __future__ import annotations

import dataclasses
from typing import Collection

import numpy as np

from bench.real.drive import DriveWindows

__all__ = ["SHIFTS", "MAX_SHIFT", "stream_offset", "offsets", "shift_stream"]

MAX_SHIFT = 6  # [samples] the largest offset looked for (0.3 s at DRIVE's 20 Hz)
SHIFTS = np.arange(-2 * MAX_SHIFT, 2 * MAX_SHIFT + 1) / 2.0  # [samples] half-sample grid


def _at(a: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """``a`` (n, m) read at fractional sample positions ``pos`` (k,) inside [0, m - 1], linear interpolation."""
    lo = np.clip(np.floor(pos).astype(int), 0, a.shape[1] - 2)
    frac = pos - lo
    return a[:, lo] * (1.0 - frac) + a[:, lo + 1] * frac


def stream_offset(ref_rate: np.ndarray, stream: np.ndarray) -> tuple[float, np.ndarray]:
    """The shift of :data:`SHIFTS` whose stream best fits the reference rate (module docstring) and the residual
    sum of squares at every shift.  ``ref_rate`` (n, m - 1): the reference's rate over each interval; ``stream``
    (n, m): the stream's samples.  NaN where a window has no finite pair."""
    n, m = stream.shape
    k = np.arange(MAX_SHIFT, m - 1 - MAX_SHIFT)
    if k.size < 2:
        return float("nan"), np.full(SHIFTS.size, np.nan)
    y = ref_rate[:, k]
    rss = np.empty(SHIFTS.size)
    for i, s in enumerate(SHIFTS):
        x = _at(stream, k + s)
        ok = np.isfinite(x) & np.isfinite(y)
        xx, xy, yy = (float(np.sum(a[ok] * b[ok])) for a, b in ((x, x), (x, y), (y, y)))
        rss[i] = yy - xy * xy / xx if xx > 0 else np.nan
    if not np.isfinite(rss).any():
        return float("nan"), rss
    return float(SHIFTS[int(np.nanargmin(rss))]), rss


def offsets(w: DriveWindows, streams: Collection[str] = ("imu_gz", "wheels_forward", "wheels_turn")) -> dict[str, float]:
    """The offsets [samples] of the streams the table has (module docstring), of those in ``streams``: ``imu_gz``,
    ``wheels_forward``, ``wheels_turn``."""
    if isinstance(streams, str):
        raise TypeError(f"offsets: streams is a collection of names, not the string {streams!r}")
    if not all(w.has(c) for c in ("ref_x", "ref_y", "ref_yaw")) or w.n_samples < 2 * MAX_SHIFT + 3:
        return {}
    x, y, yaw = (np.asarray(w[c], float) for c in ("ref_x", "ref_y", "ref_yaw"))
    yaw_rate = np.diff(yaw, axis=1) / w.dt
    forward = (np.cos(yaw[:, :-1]) * np.diff(x, axis=1) + np.sin(yaw[:, :-1]) * np.diff(y, axis=1)) / w.dt
    out: dict[str, float] = {}
    if "imu_gz" in streams and w.has("imu_gz"):
        out["imu_gz"] = stream_offset(yaw_rate, np.asarray(w["imu_gz"], float))[0]
    if {"wheels_forward", "wheels_turn"} & set(streams) and w.has("enc_wl") and w.has("enc_wr"):
        wl, wr = np.asarray(w["enc_wl"], float), np.asarray(w["enc_wr"], float)
        if "wheels_forward" in streams:
            out["wheels_forward"] = stream_offset(forward, (wl + wr) / 2.0)[0]
        if "wheels_turn" in streams:
            out["wheels_turn"] = stream_offset(yaw_rate, wr - wl)[0]
    return {k: v for k, v in out.items() if np.isfinite(v)}  # a stream without the reference's motion: no offset


def shift_stream(w: DriveWindows, channel: str, s: float) -> DriveWindows:
    """``w`` with ``channel``'s sample k replaced by its reading at k + s (module docstring)."""
    if not np.isfinite(s):
        raise ValueError(f"shift_stream: the shift of {channel} must be finite, not {s}")
    a = np.asarray(w[channel], float)
    n, m = a.shape
    pad = int(np.ceil(abs(s))) + 1
    ext = np.concatenate([np.repeat(a[:, :1], pad, axis=1), a, np.repeat(a[:, -1:], pad, axis=1)], axis=1)
    row, overlap = np.asarray(w.row), np.asarray(w.overlap)
    for i in range(n):
        if i > 0 and row[i - 1] == row[i] - 1:  # the previous block of the log: its samples before the shared ones
            prev = a[i - 1, : m - int(overlap[i])]
            take = min(pad, prev.size)
            ext[i, pad - take:pad] = prev[prev.size - take:]
        if i + 1 < n and row[i + 1] == row[i] + 1:  # the next block: its samples after the shared ones
            nxt = a[i + 1, int(overlap[i + 1]):]
            take = min(pad, nxt.size)
            ext[i, pad + m:pad + m + take] = nxt[:take]
    shifted = _at(ext, pad + np.arange(m) + s)
    return dataclasses.replace(w, channels={**w.channels, channel: shifted})
