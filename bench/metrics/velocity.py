"""Body-velocity errors against the truth: RMS per channel (vx, vy, wz)."""
from __future__ import annotations

from typing import Mapping

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["velocity_rms"]


def velocity_rms(t_ref: ArrayLike, ref: Mapping[str, ArrayLike], t_est: ArrayLike,
                 est: Mapping[str, ArrayLike], channels: tuple[str, ...] = ("vx", "vy", "wz")
                 ) -> dict[str, float]:
    """RMS of ``est[c] - ref[c]`` per channel at the reference times where both are finite (the
    estimate interpolated linearly, NaN outside its span).  Channels absent from either side
    are skipped."""
    t_ref, t_est = np.asarray(t_ref, float), np.asarray(t_est, float)
    out: dict[str, float] = {}
    for c in channels:
        if c not in ref or c not in est:
            continue
        r = np.asarray(ref[c], float)
        e_raw = np.asarray(est[c], float)
        ok = np.isfinite(e_raw)
        if ok.sum() < 1:
            continue
        e = np.interp(t_ref, t_est[ok], e_raw[ok], left=np.nan, right=np.nan)
        m = np.isfinite(e) & np.isfinite(r)
        if m.any():
            d = e[m] - r[m]
            out[c] = float(np.sqrt(np.mean(d * d)))
    return out
