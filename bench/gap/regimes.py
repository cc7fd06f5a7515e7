"""Driving regimes of a measured run, from measured signals only (commands, encoders, IMU).

One label per instant, first match wins:

* ``climbing``: |pitch| > 2 deg, pitch from the accelerometer, ``g sin(pitch) = a_x,meas - dv/dt``
  (low-passed over 0.5 s; v from the encoders), and ``g |sin(pitch)|`` above ``PITCH_NOISE_SIGMAS`` x the
  noise of that 0.5 s mean (the accelerometer's white-noise scale, :func:`bench.gap.residuals.noise_scale`, over
  the square root of its samples in 0.5 s): a noisy accelerometer cannot tell 2 deg from flat ground (the real
  Husky's a_x, 1.2 m/s^2 per 20 Hz sample, labelled 45 % of its flat-ground samples "climbing"); a_x,meas is
  first brought to the centre of mass and the body's axes when the platform declares its IMU mounting
  (:func:`forward_specific_force`: a 0.4 m lever arm put 96 % of a spin on the spot in "climbing")
* ``standstill``: |v| < 0.02 m/s and |commanded yaw rate| < 0.05 rad/s
* ``spin``: |v| < 0.02 m/s, turning on the spot
* ``accelerating`` / ``braking``: |dv/dt| > 0.1 m/s^2, speeding up / slowing down
* ``steady straight``: commanded curvature |kappa| < 0.05 1/m
* ``turning gentle`` (|kappa| <= 1 1/m, radius >= 1 m), ``turning medium`` (1-3 1/m),
  ``turning tight`` (> 3 1/m, radius < 0.33 m)

Curvature from the commanded wheel speeds with the nominal geometry:
``kappa = (2/B) (w_r - w_l)/(w_r + w_l)``.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from bench.gap.residuals import noise_scale
from bench.run import Run
from bench.spec import Platform

REGIMES = ("climbing", "standstill", "spin", "accelerating", "braking", "steady straight",
           "turning gentle", "turning medium", "turning tight")
GRID_DT = 0.02
SMOOTH_S = 0.5
STILL_SPEED = 0.02
ACCEL_THRESHOLD = 0.1
PITCH_THRESHOLD_DEG = 2.0
PITCH_NOISE_SIGMAS = 3.0  # a pitch must stand this many noise stds of the smoothed accelerometer above 0
KAPPA_STRAIGHT = 0.05
KAPPA_BANDS = (1.0, 3.0)
G = 9.81


def _smooth(v: np.ndarray, n: int) -> np.ndarray:
    if n <= 1:
        return v
    k = np.ones(n) / n
    pad = np.pad(v, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(pad, k, mode="valid")


def _samples(run: Run, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, values) of channel ``name``'s samples, None when the run has none."""
    if name not in run.data.columns or not run.has(name):
        return None
    return run.samples(name)


def _interp_channel(run: Run, name: str, grid: np.ndarray) -> np.ndarray | None:
    s = _samples(run, name)
    if s is None:
        return None
    t, v = s
    return np.interp(grid, t, v)


def forward_specific_force(run: Run, platform: Platform, grid: np.ndarray) -> np.ndarray | None:
    """The accelerometer's forward specific force at the centre of mass in body axes [m/s^2] on ``grid``: the
    platform's declared IMU mounting (:class:`~bench.sensor_spec.ImuSpec` ``yaw_misalignment``, ``lever_x``,
    ``lever_y``; :func:`bench.sim.sensors.imu_mounting`) undone at the accelerometer's own sample times, the axes
    turned back with a_y, then the lever arm's -w^2 l_x - alpha l_y taken out with the gyro's yaw rate (its declared
    gain and bias undone) and its derivative at the gyro's rate.  The raw a_x when nothing is declared or a channel
    it needs is missing; None without a_x."""
    acc = _samples(run, "imu_ax")
    if acc is None:
        return None
    imu = platform.sensors.imu
    ta, ax = acc
    lateral = _samples(run, "imu_ay") if imu.yaw_misalignment else None
    if lateral is not None:
        ay = np.interp(ta, *lateral)
        ax = np.cos(imu.yaw_misalignment) * ax - np.sin(imu.yaw_misalignment) * ay
    gyro = _samples(run, "imu_gz") if (imu.lever_x or imu.lever_y) and imu.gyro_scale_z != 0.0 else None
    if gyro is not None:
        tg, gz = gyro
        w = (gz - imu.gyro_bias_z) / imu.gyro_scale_z
        alpha = np.gradient(w, tg) if tg.size > 1 else np.zeros_like(w)
        ax = ax + np.interp(ta, tg, w) ** 2 * imu.lever_x + np.interp(ta, tg, alpha) * imu.lever_y
    return np.interp(grid, ta, ax)


def label_run(run: Run, platform: Platform) -> tuple[np.ndarray, np.ndarray]:
    """(grid times, regime index per grid time) for ``run``."""
    t_end = float(run.t[-1])
    grid = np.arange(0.0, t_end + GRID_DT / 2, GRID_DT)
    r, B = platform.wheel_radius, platform.track
    cl = _interp_channel(run, "cmd_wl", grid)
    cr = _interp_channel(run, "cmd_wr", grid)
    if cl is None or cr is None:
        cl = cr = np.zeros_like(grid)
    el = _interp_channel(run, "enc_wl", grid)
    er = _interp_channel(run, "enc_wr", grid)
    n = max(1, int(round(SMOOTH_S / GRID_DT)))
    if el is not None and er is not None:
        v = _smooth(0.5 * r * (platform.wheel_radius_scale_l * el + platform.wheel_radius_scale_r * er), n)
    else:
        v = _smooth(0.5 * r * (cl + cr), n)
    dv = np.gradient(v, grid) if grid.size > 1 else np.zeros_like(grid)
    w_cmd = r * (cr - cl) / B
    v_cmd = 0.5 * r * (cr + cl)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(np.abs(v_cmd) > 1e-6, w_cmd / v_cmd, np.inf)
    ax = forward_specific_force(run, platform, grid)
    labels = np.full(grid.size, REGIMES.index("steady straight"))
    ak = np.abs(kappa)
    labels = np.where(ak > KAPPA_STRAIGHT, REGIMES.index("turning gentle"), labels)
    labels = np.where(ak > KAPPA_BANDS[0], REGIMES.index("turning medium"), labels)
    labels = np.where(ak > KAPPA_BANDS[1], REGIMES.index("turning tight"), labels)
    moving_fast = np.abs(dv) > ACCEL_THRESHOLD
    speeding = dv * np.sign(np.where(v == 0, 1.0, v)) > 0
    labels = np.where(moving_fast & speeding, REGIMES.index("accelerating"), labels)
    labels = np.where(moving_fast & ~speeding, REGIMES.index("braking"), labels)
    still = np.abs(v) < STILL_SPEED
    labels = np.where(still & (np.abs(w_cmd) >= 0.05), REGIMES.index("spin"), labels)
    labels = np.where(still & (np.abs(w_cmd) < 0.05) & ~moving_fast, REGIMES.index("standstill"), labels)
    if ax is not None:
        g_sin = _smooth(ax, n) - dv
        ta, a = run.samples("imu_ax")
        rate = (ta.size - 1) / (ta[-1] - ta[0]) if ta.size > 1 and ta[-1] > ta[0] else 1.0 / GRID_DT
        noise = noise_scale(a) / np.sqrt(max(1.0, SMOOTH_S * rate))  # std of the 0.5 s mean of a_x
        floor = max(G * np.sin(np.radians(PITCH_THRESHOLD_DEG)), PITCH_NOISE_SIGMAS * noise)
        labels = np.where(np.abs(g_sin) > floor, REGIMES.index("climbing"), labels)
    return grid, labels


def regimes_for(platform: Platform) -> Callable[[Run], tuple[tuple[str, ...], Callable[[np.ndarray], np.ndarray]]]:
    """A function run -> (regime names, labeller of sample times) for :func:`residuals.build_space`."""

    def fn(run: Run):
        grid, labels = label_run(run, platform)

        def label(tt: np.ndarray) -> np.ndarray:
            k = np.clip(np.rint(np.asarray(tt) / GRID_DT).astype(int), 0, grid.size - 1)
            return labels[k]

        return REGIMES, label

    return fn


__all__ = ["REGIMES", "forward_specific_force", "label_run", "regimes_for"]
