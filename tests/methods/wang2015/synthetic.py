"""Wang 2015 test data: synthetic runs of a robot that moves exactly as the symmetric model.

Synthetic runs follow the symmetric model written out here from eqs. (11), (13), (15):
vx = (v_l + v_r)/2, omega = (v_r - v_l)/(B chi), poses by bench.kinematics.integrate_se2.
"""
from __future__ import annotations

import numpy as np

from bench.kinematics import integrate_se2
from bench.run import from_arrays
from tests.fixtures.encoders import readings

PLATFORM = {"name": "p3at", "track": 0.4, "wheel_radius": 0.11}
B, R = PLATFORM["track"], PLATFORM["wheel_radius"]


def symmetric_run(v_l: np.ndarray, v_r: np.ndarray, chi: np.ndarray, t: np.ndarray, ref_rate: float = 135.0,
                  pose0=(0.0, 0.0, 0.0), run_id: str = "sym"):
    vx = 0.5 * (v_l + v_r)
    wz = (v_r - v_l) / (B * chi)
    x, y, yaw = integrate_se2(t, vx, np.zeros_like(t), wz, *pose0)
    step = max(1, int(round(1.0 / ((t[1] - t[0]) * ref_rate))))
    ref = np.zeros(t.size, bool)
    ref[::step] = True
    ref[-1] = True
    enc_l, enc_r = readings(v_l / R), readings(v_r / R)
    cols = {"t": t, "enc_wl": enc_l, "enc_wr": enc_r, "ref_x": np.where(ref, x, np.nan),
            "ref_y": np.where(ref, y, np.nan), "ref_yaw": np.where(ref, yaw, np.nan),
            "truth_x": x, "truth_y": y, "truth_yaw": yaw}
    return from_arrays(cols, {"platform": dict(PLATFORM), "run_id": run_id})


def circle_run(curvature_ratio: float, v: float, chi: float, duration: float = 20.0, run_id: str = "circle"):
    t = np.arange(int(duration * 100) + 1) / 100.0
    if curvature_ratio == 0:
        v_l, v_r = -v, v
    else:
        v_l, v_r = v * (1 - 1 / curvature_ratio), v * (1 + 1 / curvature_ratio)
    return symmetric_run(np.full(t.size, v_l), np.full(t.size, v_r), np.full(t.size, chi), t, run_id=run_id)


def eq45(cr):
    return 1 + 0.4728 / (1 + 0.0538 * np.sqrt(np.abs(cr)))

