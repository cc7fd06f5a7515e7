"""Synthetic runs for the tests of methods.yi2009 (Yi et al. 2009 EKF), built here from closed-form kinematics.

The synthetic truth is an ICR model independent of the method: tread speeds r*w from wheel-speed
profiles in rpm (the paper's Figs. 5-7: straight 30/30, circle 80/40, "8" shape 80/40 -> 40/80 at
10 rpm/s), a net traction slip lam0 and an ICR expansion chi give
    v_x = (1 - lam0)(v_l + v_r)/2,  w_z = (1 - lam0)(v_r - v_l)/(chi W),
    v_y = -S(gamma) w_z with S of eq. (41) (known a1, a2, a3) and gamma of eq. (40),
the pose by exact SE(2) integration (bench.kinematics.integrate_se2), the IMU as specific force
(gravity included) + noise + bias, the encoders as quantised count differences, the reference
sensor (ref_*) as noisy 31.25 Hz pose samples.  The truth slips follow from eq. (6).

Two sensor regimes: TESTBED (the yi2009_4wd platform's sensors: 2000-count encoders, IMU noise
0.05 m/s^2 / 0.005 rad/s per sample, biases) and PAPER (better sensors, 10 % net slip: the regime
where the paper's Fig. 5 ordering holds on this synthetic data; see the report of the helper).

Shared by the test modules of tests/methods/yi2009/ (and tests/test_consistency.py); also the AR(1)
test series and the wheel-speed pairs of the synthetic calibration runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.spatial.transform import Rotation

from bench.kinematics import ideal_dd, integrate_se2
from bench.run import Run, from_arrays
from bench.spec import load_platform, to_dict
from methods.yi2009.ekf import Yi2009Ekf


RPM_TO_RADS = 2.0 * math.pi / 60.0
PLATFORM = to_dict(load_platform("yi2009_4wd"))
R_WHEEL, TRACK = PLATFORM["wheel_radius"], PLATFORM["track"]
TRUE_S = (0.02148, 0.249, 0.039)  # eq. (41) with the published values, a1 in metres
G = 9.81


# (time since start of motion [s], w_L [rpm], w_R [rpm]); 1 s ramp from rest (Figs. 5-7)
PROFILES_RPM = {
    "straight": [(0, 0, 0), (1, 30, 30), (31, 30, 30)],
    "circle": [(0, 0, 0), (1, 80, 40), (31, 80, 40)],
    "figure8": [(0, 0, 0), (1, 80, 40), (9, 80, 40), (13, 40, 80), (21, 40, 80), (25, 80, 40), (31, 80, 40)],
}


@dataclass(frozen=True)
class Sensors:
    lam0: float = 0.05  # net traction slip
    chi: float = 1.4  # ICR expansion
    counts_per_rev: int = 2000
    acc_noise: float = 0.05  # per sample [m/s^2]
    gyr_noise: float = 0.005  # per sample [rad/s]
    acc_bias: tuple[float, float, float] = (0.01, -0.01, 0.005)
    gyr_bias: tuple[float, float, float] = (5e-4, -5e-4, 1e-3)
    rate_hz: float = 125.0
    t_rest: float = 1.0
    ref_every: int = 4


TESTBED = Sensors()
PAPER = Sensors(lam0=0.10, counts_per_rev=20000, acc_noise=0.01, gyr_noise=0.001,
                acc_bias=(0.002, -0.002, 0.001), gyr_bias=(1e-4, -1e-4, 2e-4))


def synthetic_run(kind: str, seed: int = 0, sensors: Sensors = TESTBED, knots_rpm=None, s_model=TRUE_S) -> Run:
    """A Run of the closed-form model described in the module docstring (truth_* columns included)."""
    rng = np.random.default_rng(seed)
    kn = np.asarray(knots_rpm if knots_rpm is not None else PROFILES_RPM[kind], float)
    t = np.arange(0.0, sensors.t_rest + kn[-1, 0], 1.0 / sensors.rate_hz)
    n = t.size
    tm = t - sensors.t_rest
    wl = np.interp(tm, kn[:, 0], kn[:, 1]) * RPM_TO_RADS
    wr = np.interp(tm, kn[:, 0], kn[:, 2]) * RPM_TO_RADS
    vl, vr = R_WHEEL * wl, R_WHEEL * wr
    vx = (1 - sensors.lam0) * (vl + vr) / 2
    wz = (1 - sensors.lam0) * (vr - vl) / (sensors.chi * TRACK)
    vlx, vrx = vx - TRACK / 2 * wz, vx + TRACK / 2 * wz  # eqs. (3)-(4)
    moving = vl + vr > 0
    gam = np.where(moving, (vlx - vrx) / np.where(moving, vlx + vrx, 1.0), 0.0)  # eq. (40)
    s_true = s_model[0] / (s_model[1] * np.abs(gam) + s_model[2])  # eq. (41)
    vy = -s_true * wz  # eq. (7)
    x, y, yaw = integrate_se2(t, vx, vy, wz)
    fx = np.gradient(vx, t) - wz * vy  # specific force of planar motion, gravity on z
    fy = np.gradient(vy, t) + wz * vx
    acc = np.column_stack([fx, fy, np.full(n, G)]) + sensors.acc_bias + sensors.acc_noise * rng.standard_normal((n, 3))
    gyr = np.column_stack([np.zeros(n), np.zeros(n), wz]) + sensors.gyr_bias + sensors.gyr_noise * rng.standard_normal((n, 3))
    q = 2 * math.pi / sensors.counts_per_rev

    def encoder(w: np.ndarray) -> np.ndarray:  # count differences per sample
        angle = cumulative_trapezoid(w, t, initial=0.0)
        return np.concatenate(([0.0], np.diff(np.floor(angle / q)) * q * sensors.rate_hz))

    with np.errstate(divide="ignore", invalid="ignore"):
        slip_l = np.where(vl > 0, 1 - vlx / vl, 0.0)
        slip_r = np.where(vr > 0, 1 - vrx / vr, 0.0)
    ref = np.full((n, 3), np.nan)
    idx = np.arange(0, n, sensors.ref_every)
    ref[idx, 0] = x[idx] + 0.0149 * rng.standard_normal(idx.size)
    ref[idx, 1] = y[idx] + 0.0149 * rng.standard_normal(idx.size)
    ref[idx, 2] = (yaw[idx] + 0.01 * rng.standard_normal(idx.size) + np.pi) % (2 * np.pi) - np.pi
    cols = dict(
        t=t, enc_wl=encoder(wl), enc_wr=encoder(wr),
        imu_ax=acc[:, 0], imu_ay=acc[:, 1], imu_az=acc[:, 2], imu_gx=gyr[:, 0], imu_gy=gyr[:, 1], imu_gz=gyr[:, 2],
        ref_x=ref[:, 0], ref_y=ref[:, 1], ref_yaw=ref[:, 2],
        truth_x=x, truth_y=y, truth_yaw=yaw, truth_vx=vx, truth_vy=vy, truth_wz=wz,
        truth_slip_l=slip_l, truth_slip_r=slip_r, truth_x_icr=s_true,
    )
    return from_arrays(cols, dict(run_id=f"synthetic-{kind}-{seed}", platform=PLATFORM))


def pos_rms(t_est: np.ndarray, x: np.ndarray, y: np.ndarray, run: Run) -> float:
    xt, yt = np.interp(t_est, run.t, run["truth_x"]), np.interp(t_est, run.t, run["truth_y"])
    return float(np.sqrt(np.mean((x - xt) ** 2 + (y - yt) ** 2)))


def imu_only(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """Pure strapdown integration of eqs. (10a)-(10e) (no constraint, no encoder) from rest at the
    origin, roll/pitch levelled from the accelerometer at rest, like the EKF's initial state."""
    t, acc = run.t, np.column_stack([run[f"imu_a{a}"] for a in "xyz"])
    gyr = np.column_stack([run[f"imu_g{a}"] for a in "xyz"])
    a0 = acc[:25].mean(axis=0)
    att = np.array([math.atan2(a0[1], a0[2]), math.atan2(-a0[0], math.hypot(a0[1], a0[2])), 0.0])
    v, p = np.zeros(3), np.zeros(3)
    out = np.zeros((t.size, 2))
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        phi, th = att[0], att[1]
        w = gyr[k - 1]
        rate = np.array([w[0] + math.tan(th) * (math.sin(phi) * w[1] + math.cos(phi) * w[2]),
                         math.cos(phi) * w[1] - math.sin(phi) * w[2],
                         (math.sin(phi) * w[1] + math.cos(phi) * w[2]) / math.cos(th)])
        c_bi = Rotation.from_euler("ZYX", att[::-1]).as_matrix()
        p = p + dt * v
        v = v + dt * (c_bi @ acc[k - 1] - [0.0, 0.0, G])
        att = att + dt * rate
        out[k] = p[:2]
    return out[:, 0], out[:, 1]


def no_slip_dead_reckoning(run: Run) -> tuple[np.ndarray, np.ndarray]:
    vx, vy, wz = ideal_dd(R_WHEEL * run["enc_wl"], R_WHEEL * run["enc_wr"], TRACK)
    x, y, _ = integrate_se2(run.t, vx, vy, wz)
    return x, y


_CACHE: dict = {}


def estimate_cached(variant: int, kind: str, seed: int, sensors: Sensors):
    key = (variant, kind, seed, sensors)
    if key not in _CACHE:
        run = synthetic_run(kind, seed, sensors)
        _CACHE[key] = (run, Yi2009Ekf(variant=variant).estimate(run.without_truth()))
    return _CACHE[key]


CAL_COMBOS_RPM = [(80, 40), (100, 50), (140, 60), (60, 40), (120, 100), (40, 80), (50, 100), (60, 140), (40, 60),
                  (100, 120), (150, 50)]


def _ar1(rng: np.random.Generator, n: int, dt: float, tau: float, sigma: float) -> np.ndarray:
    """Stationary AR(1) sample path, b(k) = a b(k-1) + w, a = exp(-dT/tau), std sigma (stationary start)."""
    from scipy.signal import lfilter

    a = math.exp(-dt / tau)
    return lfilter([1.0], [1.0, -a], rng.standard_normal(n) * sigma * math.sqrt(1 - a * a),
                   zi=[a * sigma * rng.standard_normal()])[0]
