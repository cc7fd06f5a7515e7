"""Mandow 2007 test data: synthetic runs of a robot that moves exactly as Mandow's model.

The synthetic runs are built here from the paper's own relations, not from methods.mandow2007:
joystick-like body velocities (v, omega), lateral velocity from eq. (5) (v_x = y_ICRv omega, Mandow's
X to the right), tread speeds from the inverse kinematics of eqs. (16)-(17), poses from the exact SE(2)
integration of bench.kinematics.  Encoder speeds change only at encoder instants (each reading the speed of the
period ending at its stamp, as the testbed's encoder reports it), so a model with
the true parameters reproduces the reference exactly.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from bench.kinematics import integrate_se2
from bench.run import from_arrays
from methods import mandow2007 as M
from tests.fixtures.encoders import readings

PLATFORM = {"name": "p3at", "track": 0.4, "wheel_radius": 0.11, "wheelbase": 0.27}


def joystick(duration: float, rate: float, seed: int, v_max: float = 0.5, w_max: float = 1.0, hold: float = 2.0,
             tau: float = 0.4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random (v, omega) set points every ``hold`` s through a first-order lag: a joystick-driven path."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * rate)) + 1) / rate
    k = np.floor(t / hold).astype(int)
    v_set = rng.uniform(-0.3 * v_max, v_max, k.max() + 1)
    w_set = rng.uniform(-w_max, w_max, k.max() + 1)
    a = 1 - np.exp(-1 / (rate * tau))
    return t, lfilter([a], [1, a - 1], v_set[k]), lfilter([a], [1, a - 1], w_set[k])


def simulate_icr_run(x_l: float, x_r: float, y_v: float, a_l: float, a_r: float, t: np.ndarray, vx: np.ndarray,
                     wz: np.ndarray, ref_rate: float = 5.0, pose0=(1.0, 2.0, 0.3), run_id: str = "synth",
                     meta: dict | None = None):
    """Run of a robot that moves exactly as Mandow's model with K = (x_l, x_r, y_v, a_l, a_r)."""
    rate = 1.0 / (t[1] - t[0])
    r = PLATFORM["wheel_radius"]
    v_l = (vx + x_l * wz) / a_l  # eq. (16)
    v_r = (vx + x_r * wz) / a_r  # eq. (17)
    vy = -y_v * wz  # eq. (5): Mandow's lateral v_x = y_ICRv omega, X to the right = our -y
    x, y, yaw = integrate_se2(t, vx, vy, wz, *pose0)
    ref = np.zeros(t.size, bool)
    ref[:: int(round(rate / ref_rate))] = True
    enc_l, enc_r = readings(v_l / r), readings(v_r / r)
    cols = {"t": t, "cmd_wl": v_l / r, "cmd_wr": v_r / r, "enc_wl": enc_l, "enc_wr": enc_r,
            "ref_x": np.where(ref, x, np.nan), "ref_y": np.where(ref, y, np.nan),
            "ref_yaw": np.where(ref, yaw, np.nan), "truth_x": x, "truth_y": y, "truth_yaw": yaw}
    return from_arrays(cols, {"platform": dict(PLATFORM), "run_id": run_id, **(meta or {})})


def joystick_run(p: M.IcrParams, duration: float = 20.0, seed: int = 1, ref_rate: float = 5.0):
    t, v, w = joystick(duration, 100.0, seed)
    return simulate_icr_run(*p.as_array(), t, v, w, ref_rate=ref_rate, run_id=f"joystick{seed}")


def on_grid(p: M.IcrParams, ranges: M.GeneRanges) -> M.IcrParams:
    """Parameters rounded to the 8-bit gene grid (so the discretised problem's optimum is the truth)."""
    b, q = ranges.bounds(), ranges.quantum()
    return M.IcrParams.from_array(b[:, 0] + np.round((p.as_array() - b[:, 0]) / q) * q)
