"""Synthetic DRIVE windows for the Baril 2024 tests: the truth is ideal differential drive plus a known linear slip
on DRIVE's regressors, integrated here window by window with exact constant-twist arcs (no skidbench integrator),
optionally with wheel speeds that follow commands through a first-order lag with a dead time (a loop written here)."""
from __future__ import annotations

import math

import numpy as np

from bench.real.drive import DRIVE_DT, DriveWindows

R, B = 0.165, 0.55  # Husky wheel radius and track [m]
N = 40  # samples per window
#: the generating slip weights on (v), (v w), (v w, v, w) (signs as a skid-steer's: it under-turns, lags)
TRUE_SLIP = {"x": (-0.12,), "y": (0.04,), "yaw": (0.015, 0.01, -0.5)}


def true_velocities(wl: np.ndarray, wr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v, w = R * (wl + wr) / 2, R * (wr - wl) / B
    sx = TRUE_SLIP["x"][0] * v
    sy = TRUE_SLIP["y"][0] * v * w
    a, b, c = TRUE_SLIP["yaw"]
    return v + sx, sy, w + a * v * w + b * v + c * w


def arcs(vx, vy, wz, x0, y0, h0, dt=DRIVE_DT):
    """Poses of one window: each body twist held over one interval, integrated in closed form."""
    n = len(vx)
    x, y, h = np.empty(n), np.empty(n), np.empty(n)
    x[0], y[0], h[0] = x0, y0, h0
    for k in range(n - 1):
        th = wz[k] * dt
        if abs(th) < 1e-12:
            dxb, dyb = vx[k] * dt, vy[k] * dt
        else:
            s, c1 = math.sin(th) / th, (1 - math.cos(th)) / th
            dxb, dyb = (s * vx[k] - c1 * vy[k]) * dt, (c1 * vx[k] + s * vy[k]) * dt
        c, sn = math.cos(h[k]), math.sin(h[k])
        x[k + 1], y[k + 1], h[k + 1] = x[k] + c * dxb - sn * dyb, y[k] + sn * dxb + c * dyb, h[k] + th
    return x, y, h


def lag(cmd: np.ndarray, w0: float, tau: float, delay: int, dt=DRIVE_DT) -> np.ndarray:
    """First-order lag with a whole-sample dead time, exact under a zero-order hold of the command."""
    out = [w0]
    for k in range(len(cmd) - 1):
        u = cmd[max(k - delay, 0)]
        out.append(u + (out[-1] - u) * math.exp(-dt / tau))
    return np.array(out)


def windows(rng: np.random.Generator, n: int, powertrain: tuple[float, int] | None = None,
            noise: float = 0.0) -> DriveWindows:
    """``n`` windows (every third one transitory), one step each; with ``powertrain = (tau, delay)`` the wheel speeds
    follow step commands through :func:`lag` from the previous level, else they are noisy constant levels that the
    commands equal on average.  ``noise``: Gaussian ICP noise [m, rad] on every sample after the first."""
    lvl = rng.uniform(-6, 6, (n, 2))
    prev = rng.uniform(-6, 6, (n, 2))
    cmd_l, cmd_r = np.repeat(lvl[:, :1], N, 1), np.repeat(lvl[:, 1:], N, 1)
    if powertrain is None:
        wl = cmd_l + rng.normal(0, 0.2, (n, N))
        wr = cmd_r + rng.normal(0, 0.2, (n, N))
    else:
        tau, d = powertrain
        cmd_l[:, :2], cmd_r[:, :2] = prev[:, :1], prev[:, 1:]  # the step lands at sample 2
        wl = np.array([lag(c, p, tau, d) for c, p in zip(cmd_l, prev[:, 0])])
        wr = np.array([lag(c, p, tau, d) for c, p in zip(cmd_r, prev[:, 1])])
    vx, vy, wz = true_velocities(wl, wr)
    poses = [arcs(vx[i], vy[i], wz[i], *rng.uniform([-2, -2, -np.pi], [2, 2, np.pi])) for i in range(n)]
    x, y, h = (np.array([p[j] for p in poses]) for j in range(3))
    if noise:
        for a in (x, y, h):
            a[:, 1:] += rng.normal(0, noise, a[:, 1:].shape)
    transitory = np.arange(n) % 3 == 0
    return DriveWindows(
        source="<synthetic baril2024>", dt=DRIVE_DT,
        channels={"cmd_wl": cmd_l, "cmd_wr": cmd_r, "enc_wl": wl, "enc_wr": wr, "ref_x": x, "ref_y": y,
                  "ref_yaw": h},
        calib_step=np.arange(n), calib_step_label=np.arange(n), window=np.zeros(n, int), steady=~transitory,
        transitory=transitory, overlap=np.zeros(n, int), frame_yaw=np.zeros(n), row=np.arange(n),
    )
