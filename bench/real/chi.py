"""The chi (ICR spread) side of the real-data benchmark: measured chi by curvature-ratio bin, the
references it is read against, and a scored model's own chi.

* :func:`chi_by_bin`: Wang 2015 eq. (25)/(42) chi measured per steady turning window
  (:func:`bench.real.windows.window_chi`), tabulated by |curvature ratio| bin (:data:`CHI_BINS`).
* :data:`WANG_P3AT`, :func:`wang_p3at_chi`: Wang 2015's published P3-AT curve (eq. (45): a = 0.4728,
  b = 0.0538 in eq. (44)), a column of that table -- published data to read the measurements against,
  not a model the benchmark scores (the scored Wang model is the ``wang2015.chi_lambda`` plugin's).
* :func:`testbed_chi`: the testbed's own chi (eq. (25) on its truth) for the gap workflow's nominal
  husky model (:data:`TESTBED_CHI_SCENARIO`).
* :func:`model_chi`: the chi a fitted window model implies at a curvature ratio, measured on its own
  prediction with the same eq. (25) (any :class:`~bench.real.windows.WindowModel`; used for the figure).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import numpy as np

from bench.real.drive import DRIVE_DT, DriveWindows
from bench.real.windows import WindowModel, window_chi

CHI_BINS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, math.inf)  # |curvature ratio| bin edges
WANG_P3AT = (0.4728, 0.0538)  # Wang 2015 eq. (45): (a, b) for the Pioneer P3-AT on tile
TESTBED_CHI_SCENARIO = "real_husky_asphalt"  # the gap workflow's nominal husky model (bench.real.gap)


def testbed_chi(platform_name: str, abs_ratios: Sequence[float], tread_speeds: Sequence[float],
                duration: float = 6.0, settle: float = 3.0, seed: int = 0) -> list[float]:
    """The testbed's chi (Wang eq. (25) on its truth, ``bench.sim.validate.chi_eq25``) for steady
    CCW turns at each curvature ratio, outer tread speed as given; the nominal husky model of the gap
    workflow (scenario :data:`TESTBED_CHI_SCENARIO`).  NaN for a platform other than that model's."""
    from bench.sim import simulate
    from bench.sim.validate import chi_eq25
    from bench.spec import CommandSpec, Segment, load_scenario

    base = load_scenario(TESTBED_CHI_SCENARIO)
    if base.platform.name != platform_name:
        return [math.nan] * len(abs_ratios)
    out = []
    for lam, v in zip(abs_ratios, tread_speeds):
        cmd = CommandSpec(kind="v_curvature_ratio", segments=(Segment(duration, float(v), float(lam)),))
        run = simulate(dataclasses.replace(base, command=cmd, duration=duration), seed)
        out.append(chi_eq25(run.data, base.platform, settle))
    return out


def wang_p3at_chi(abs_ratio: np.ndarray) -> np.ndarray:
    """Wang 2015 eq. (45), the published P3-AT curve: eq. (44) ``chi = 1 + a / (1 + b sqrt|ratio|)``
    with (a, b) = :data:`WANG_P3AT`; 1 on a straight line (|ratio| = inf)."""
    a, b = WANG_P3AT
    lam = np.asarray(abs_ratio, float)
    with np.errstate(invalid="ignore", over="ignore"):
        return 1.0 + a / (1.0 + b * np.sqrt(np.abs(lam)))


def chi_by_bin(chi: np.ndarray, lam: np.ndarray, edges: Sequence[float] = CHI_BINS) -> list[dict[str, float]]:
    """Measured chi per |curvature ratio| bin: n, median, quartiles, median |ratio|, Wang P3-AT chi."""
    rows = []
    a = np.abs(lam)
    for lo, hi in zip(edges[:-1], edges[1:]):
        s = (a >= lo) & (a < hi)
        c = chi[s]
        med_l = float(np.median(a[s])) if s.any() else math.nan
        rows.append({
            "lo": float(lo), "hi": float(hi), "n": int(s.sum()),
            "median": float(np.median(c)) if c.size else math.nan,
            "q25": float(np.percentile(c, 25)) if c.size else math.nan,
            "q75": float(np.percentile(c, 75)) if c.size else math.nan,
            "median_abs_ratio": med_l,
            "wang_p3at": float(wang_p3at_chi(np.array(med_l))) if s.any() else math.nan,
        })
    return rows


def model_chi(model: WindowModel, abs_ratio: np.ndarray, wheel_radius: float, track: float,
              n_samples: int = 2) -> np.ndarray:
    """The chi ``model`` implies at each curvature ratio: eq. (25) (:func:`window_chi`) on the model's own
    prediction of a CCW turn at constant tread speeds ``v_l = (ratio - 1)/2``, ``v_r = (ratio + 1)/2``
    [m/s] (so ``(v_l + v_r)/(v_r - v_l) = ratio``), one window per ratio."""
    lam = np.asarray(abs_ratio, float)
    n = lam.size
    ones = np.ones((n, n_samples))
    wl = ((lam - 1.0) / 2.0 / wheel_radius)[:, None] * ones
    wr = ((lam + 1.0) / 2.0 / wheel_radius)[:, None] * ones
    zero = np.zeros((n, n_samples))
    w = DriveWindows(
        source="<model chi>", dt=DRIVE_DT,
        channels={"cmd_wl": wl, "cmd_wr": wr, "enc_wl": wl, "enc_wr": wr,
                  "ref_x": zero, "ref_y": zero, "ref_yaw": zero},
        calib_step=np.arange(n), calib_step_label=np.arange(n), window=np.zeros(n, int),
        steady=np.ones(n, bool), transitory=np.zeros(n, bool), overlap=np.zeros(n, int),
        frame_yaw=np.zeros(n), row=np.arange(n),
    )
    x, y, yaw = model.predict(w)
    w = dataclasses.replace(w, channels={**w.channels, "ref_x": x, "ref_y": y, "ref_yaw": yaw})
    return window_chi(w, wheel_radius, track, min_turn=0.0)[0]
