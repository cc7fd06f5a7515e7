"""The state-space model of Liu's UKF+ICR and MI-UKF (Sec. III-C, IV-C and the Appendix): state, process
model and the GNSS/gyro block of the measurement.

Paper equation -> code
    Sec. IV: six states (X, Y, phi, v_x, v_y, theta_dot) ............. STATE_NAMES
    (12), (13a-f), (14), (30) process model f(x, u) ................... liu_fx
    (14), (31), Appendix h(x) = (X, Y, phi, v_x, v_y, theta_dot) twice  liu_hx
    (32) block 1: GNSS x, y, yaw, body v_x, v_y and the gyro .......... _gnss_block
    (32) block 2, Appendix: the encoder-ICR pseudo-measurement ........ methods.liu2020.ukf.run_liu_filter

* State: the six states of Sec. IV, ``(X, Y, phi, v_x, v_y, theta_dot)``; the ICR locations are not
  states (see :mod:`methods.liu2020.ukf`).
* Frames: Liu's world rotation (13d-e) is printed as ``[[cos, sin], [sin, -cos]]``, a reflection
  (det = -1); with y left and yaw CCW (ENU, DESIGN.md) the proper rotation ``X' = vx cos - vy sin``,
  ``Y' = vx sin + vy cos`` is used everywhere, including the encoder pseudo-measurement of the Appendix.
* Input (12), (13a-b), (30): the accelerometer ``(a_x, a_y)`` drives ``v_x, v_y``.  Liu's (13a-b)
  omit the rotating-frame transport terms; with ``transport_terms=True`` (default) the body-frame
  kinematics ``dv_x = (a_x + theta_dot v_y) dT``, ``dv_y = (a_y - theta_dot v_x) dT`` are used (a
  specific force measured on a turning body contains the centripetal term).  ``False`` is the
  literal (13a-b).  The yaw rate is a random walk (13c); the gyro enters as the sixth measurement
  (the "theta_dot_{k+1}" row of the first block of (32), noise 0.01 of the Appendix).
* Measurement (32): block 1 is (gnss_x, gnss_y, gnss_yaw, body v_x, body v_y, gyro z), the GNSS
  world velocity rotated into the body frame with the GNSS heading.
"""
from __future__ import annotations

import numpy as np

from bench.run import Run
from methods.liu2020.inputs import _wrap

STATE_NAMES = ("X", "Y", "phi", "v_x", "v_y", "yaw_rate")


def liu_fx(sig: np.ndarray, dt: float, u: tuple[float, float, bool]) -> np.ndarray:
    """Process model (13a-f)/(30), vectorised over sigma points: Euler step of the pose with the
    body velocities, accelerometer input on v_x, v_y, random-walk yaw rate.  ``u = (a_x, a_y,
    transport)``: with ``transport`` the body-frame terms +theta_dot v_y, -theta_dot v_x are added."""
    ax, ay, transport = u
    out = sig.copy()
    phi = sig[:, 2]
    c, s = np.cos(phi), np.sin(phi)
    vx, vy, w = sig[:, 3], sig[:, 4], sig[:, 5]
    vxdt, vydt, wdt = vx * dt, vy * dt, w * dt
    out[:, 0] += vxdt * c - vydt * s
    out[:, 1] += vxdt * s + vydt * c
    out[:, 2] += wdt
    if transport:
        out[:, 3] += wdt * vy + ax * dt
        out[:, 4] += ay * dt - wdt * vx
    else:
        out[:, 3] += ax * dt
        out[:, 4] += ay * dt
    return out


_H_IDX = np.array([0, 1, 2, 3, 4, 5, 0, 1, 2, 3, 4, 5])


def liu_hx(sig: np.ndarray) -> np.ndarray:
    """Measurement model of the Appendix: h(x) = (X, Y, phi, v_x, v_y, theta_dot) twice."""
    return sig[:, _H_IDX]


def _gnss_block(run: Run) -> np.ndarray:
    """(T, 6) block 1 of (32): gnss x, y, yaw, body v_x, v_y (GNSS world velocity rotated by the
    GNSS heading, as (32) rotates by phi_N) and the gyro yaw rate; NaN where there is no sample.
    Without a position fix the heading row goes too (Sec. IV-C, after (32): "the dimension of the measurement
    vector will descend to 9x1 with the position readings deleted"), while a heading sample still rotates the
    GNSS velocity: rows v_x, v_y and the gyro stay.  A fix that is missing whole (every channel NaN) drops
    the same rows either way."""
    gx, gy, gyaw = run["gnss_x"], run["gnss_y"], run["gnss_yaw"]
    gvx, gvy = run["gnss_vx"], run["gnss_vy"]
    c, s = np.cos(gyaw), np.sin(gyaw)  # NaN yaw -> NaN body velocity (dropped)
    yaw_row = np.where(np.isfinite(gx) & np.isfinite(gy), _wrap(gyaw), np.nan)
    return np.column_stack((gx, gy, yaw_row, c * gvx + s * gvy, -s * gvx + c * gvy, run["imu_gz"]))
