"""Synthetic skid-steer runs generated from a known ICR model, for the tests of methods/liu2020/.

The generator integrates a DUBHE-like vehicle (Liu Table 1: B = 0.87 m, r = 0.23 m) whose tread
ICRs are known (y_l ~ 0.6, y_r ~ -0.6, x_icr ~ 0.05, optionally varying slowly in time like terrain
patches) at 1 kHz with the exact SE(2) integrator, and samples IMU (specific force, gyro), quantised
encoders, GNSS (position, world velocity, dual-antenna yaw) and the truth from it; plus the error
measures the tests compare against the truth.
"""
from __future__ import annotations

import math

import numpy as np

from bench.kinematics import icr_forward, integrate_se2
from bench.run import Run, from_arrays
from bench.spec import load_platform, to_dict

PLATFORM = to_dict(load_platform("dubhe"))
B, RW = PLATFORM["track"], PLATFORM["wheel_radius"]


def _profile(kind: str, t: np.ndarray, phase: float) -> tuple[np.ndarray, np.ndarray]:
    """Commanded forward speed v and no-slip yaw rate w_c (tread speeds v -/+ w_c B/2)."""
    ramp = 1.0 - np.exp(-t / 1.5)
    if kind == "mixed":  # straight cruise, large- and small-radius turns, speed changes
        v = ramp * (1.6 + 0.6 * np.sin(2 * np.pi * t / 23.0 + phase))
        w = ramp * (0.9 * np.sin(2 * np.pi * t / 19.0 + 2 * phase) + 0.5 * np.sin(2 * np.pi * t / 7.3 + phase))
    elif kind == "circle":  # Liu scenario 3: backwards on a small radius, heading wraps often
        v = -0.6 * ramp
        w = -3.0 * ramp
    elif kind == "straight":
        v = 2.0 * ramp
        w = 0.02 * np.sin(2 * np.pi * t / 10.0 + phase) * ramp
    else:
        raise ValueError(kind)
    return v, w


def make_run(seed: int, duration: float = 60.0, kind: str = "mixed", icr=(0.6, -0.6, 0.05),
             icr_var: float = 0.2, rate: float = 100.0, gnss_rate: float = 10.0,
             outage: tuple[float, float] | None = None, phase: float | None = None) -> Run:
    """A synthetic skid-steer Run with truth from a known (time-varying) ICR model."""
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi) if phase is None else phase
    fine = 1000.0
    sub = int(round(fine / rate))
    tf = np.arange(int(round(duration * fine)) + 1) / fine
    v, wc = _profile(kind, tf, phase)
    v_l, v_r = v - wc * B / 2, v + wc * B / 2
    # truth ICR: slow terrain-like variation around the nominal locations
    y_l = icr[0] * (1 + icr_var * np.sin(2 * np.pi * tf / 37.0 + phase))
    y_r = icr[1] * (1 + icr_var * np.sin(2 * np.pi * tf / 23.0 + 1.0 + phase))
    x_i = icr[2] * (1 + icr_var * np.sin(2 * np.pi * tf / 31.0 + 2.0))
    vx, vy, wz = icr_forward(v_l, v_r, y_l, y_r, x_i)
    yaw0 = rng.uniform(-np.pi, np.pi)
    X, Y, yaw = integrate_se2(tf, vx, vy, wz, 3.0, -2.0, yaw0)
    # specific force in the body frame: dv/dt + w x v
    dvx, dvy = np.gradient(vx, tf), np.gradient(vy, tf)
    ax_t, ay_t = dvx - wz * vy, dvy + wz * vx
    # encoder: quantised wheel angle differenced over each log interval
    cpr = PLATFORM["sensors"]["encoder"]["counts_per_rev"]
    ang_l = np.concatenate(([0.0], np.cumsum(v_l[:-1] / RW * np.diff(tf))))
    ang_r = np.concatenate(([0.0], np.cumsum(v_r[:-1] / RW * np.diff(tf))))
    idx = np.arange(0, tf.size, sub)
    t = tf[idx]
    n = t.size
    dt = 1.0 / rate
    cnt_l, cnt_r = np.floor(ang_l[idx] * cpr / (2 * np.pi)), np.floor(ang_r[idx] * cpr / (2 * np.pi))
    enc_l = np.concatenate(([0.0], np.diff(cnt_l))) * 2 * np.pi / cpr / dt
    enc_r = np.concatenate(([0.0], np.diff(cnt_r))) * 2 * np.pi / cpr / dt
    s_acc, s_gyr = 0.05, 0.003
    cols = {
        "t": t,
        "cmd_wl": v_l[idx] / RW, "cmd_wr": v_r[idx] / RW,
        "enc_wl": enc_l, "enc_wr": enc_r,
        "imu_ax": ax_t[idx] + rng.normal(0, s_acc, n), "imu_ay": ay_t[idx] + rng.normal(0, s_acc, n),
        "imu_az": 9.81 + rng.normal(0, s_acc, n),
        "imu_gx": rng.normal(0, s_gyr, n), "imu_gy": rng.normal(0, s_gyr, n),
        "imu_gz": wz[idx] + 0.002 + rng.normal(0, s_gyr, n),  # small constant gyro bias
    }
    gsub = int(round(rate / gnss_rate))
    g = np.zeros(n, dtype=bool)
    g[::gsub] = True
    if outage is not None:
        g &= ~((t >= outage[0]) & (t < outage[1]))
    yw = yaw[idx]
    vxw = vx[idx] * np.cos(yw) - vy[idx] * np.sin(yw)
    vyw = vx[idx] * np.sin(yw) + vy[idx] * np.cos(yw)

    def gn(a, s):
        out = np.full(n, np.nan)
        out[g] = a[g] + rng.normal(0, s, int(g.sum()))
        return out

    cols |= {
        "gnss_x": gn(X[idx], 0.02), "gnss_y": gn(Y[idx], 0.02),
        "gnss_vx": gn(vxw, 0.03), "gnss_vy": gn(vyw, 0.03),
        "gnss_yaw": np.where(g, (gn(yw, 0.005) + np.pi) % (2 * np.pi) - np.pi, np.nan),
    }
    vxl, vxr = vx[idx] - B / 2 * wz[idx], vx[idx] + B / 2 * wz[idx]
    with np.errstate(divide="ignore", invalid="ignore"):
        sl = (v_l[idx] - vxl) / v_l[idx]
        sr = (v_r[idx] - vxr) / v_r[idx]
    cols |= {
        "truth_x": X[idx], "truth_y": Y[idx], "truth_yaw": (yw + np.pi) % (2 * np.pi) - np.pi,
        "truth_vx": vx[idx], "truth_vy": vy[idx], "truth_wz": wz[idx],
        "truth_y_l": y_l[idx], "truth_y_r": y_r[idx], "truth_x_icr": x_i[idx],
        "truth_slip_l": sl, "truth_slip_r": sr,
    }
    meta = {"run_id": f"synthetic-{kind}-{seed}", "seed": seed, "platform": PLATFORM}
    return from_arrays(cols, meta)


def pos_rms(est, run: Run) -> float:
    return float(np.sqrt(np.mean((est["x"] - run["truth_x"]) ** 2 + (est["y"] - run["truth_y"]) ** 2)))


def yaw_err(est, run: Run) -> np.ndarray:
    return (est["yaw"] - run["truth_yaw"] + np.pi) % (2 * np.pi) - np.pi


def start_aligned_rms(est, run: Run) -> float:
    """Position RMS after moving the estimate's start pose onto the true start pose (SE(2)): removes
    the GNSS noise of the first fix that dead reckoning starts from."""
    d = float(run["truth_yaw"][0] - est["yaw"][0])
    c, s = math.cos(d), math.sin(d)
    ex, ey = est["x"] - est["x"][0], est["y"] - est["y"][0]
    x = run["truth_x"][0] + c * ex - s * ey
    y = run["truth_y"][0] + s * ex + c * ey
    return float(np.sqrt(np.mean((x - run["truth_x"]) ** 2 + (y - run["truth_y"]) ** 2)))
