"""Shared planar kinematics: ICR forward/inverse kinematics and SE(2) pose integration.

Body frame x forward, y left; yaw CCW positive (DESIGN.md).  Tread (side) speeds
``v_l = r * w_l``, ``v_r = r * w_r``.  The ICRs of the left and right treads lie on the line
``x = x_icr`` at lateral coordinates ``y_l`` and ``y_r`` (Wang 2015 eqs. (4)-(9); Mandow 2007
eq. (6) with Mandow's axes swapped: his X is our -y, his Y our x).

Forward kinematics (Wang 2015 eq. (8)-(9)):

    vx = (y_l v_r - y_r v_l) / (y_l - y_r)
    vy = x_icr (v_l - v_r) / (y_l - y_r)
    wz = (v_r - v_l) / (y_l - y_r)

Ideal differential drive: y_l = B/2, y_r = -B/2, x_icr = 0.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def icr_forward(v_l: ArrayLike, v_r: ArrayLike, y_l: ArrayLike, y_r: ArrayLike, x_icr: ArrayLike = 0.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body velocities (vx, vy, wz) from tread speeds and ICR coordinates (Wang eq. (8)-(9))."""
    v_l, v_r = np.asarray(v_l, float), np.asarray(v_r, float)
    y_l, y_r, x_icr = np.asarray(y_l, float), np.asarray(y_r, float), np.asarray(x_icr, float)
    d = y_l - y_r
    vx = (y_l * v_r - y_r * v_l) / d
    wz = (v_r - v_l) / d
    vy = -x_icr * wz
    return vx, vy, wz


def icr_inverse(v_l: ArrayLike, v_r: ArrayLike, vx: ArrayLike, vy: ArrayLike, wz: ArrayLike,
                min_wz: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ICR coordinates (y_l, y_r, x_icr) from tread speeds and body velocities (Wang eqs. (5)-(7),
    Yi eq. (9a)); NaN where |wz| < ``min_wz`` (the ICRs are undefined on a straight line)."""
    v_l, v_r = np.asarray(v_l, float), np.asarray(v_r, float)
    vx, vy, wz = np.asarray(vx, float), np.asarray(vy, float), np.asarray(wz, float)
    ok = np.abs(wz) >= min_wz
    w = np.where(ok, wz, np.nan)
    return (vx - v_l) / w, (vx - v_r) / w, -vy / w


def chi(y_l: ArrayLike, y_r: ArrayLike, track: float) -> np.ndarray:
    """ICR coefficient chi = (y_l - y_r) / B (Wang eq. (15)); Mandow's steering efficiency is 1/chi."""
    return (np.asarray(y_l, float) - np.asarray(y_r, float)) / track


def curvature_ratio(v_l: ArrayLike, v_r: ArrayLike) -> np.ndarray:
    """Wang's path curvature variable (v_l + v_r)/(v_r - v_l) (his lambda, eq. (13)); inf when straight."""
    v_l, v_r = np.asarray(v_l, float), np.asarray(v_r, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (v_l + v_r) / (v_r - v_l)


def integrate_se2(t: ArrayLike, vx: ArrayLike, vy: ArrayLike, wz: ArrayLike,
                  x0: float = 0.0, y0: float = 0.0, yaw0: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate body velocities held constant over each interval [t_k, t_k+1) (zero-order hold)
    with the exact SE(2) exponential; vectorised.  Returns x, y, yaw (unwrapped) at each t."""
    t = np.asarray(t, float)
    vx, vy, wz = (np.asarray(a, float) for a in (vx, vy, wz))
    dt = np.diff(t)
    w = wz[:-1]
    dth = w * dt
    small = np.abs(dth) < 1e-9
    safe = np.where(small, 1.0, dth)
    s = np.where(small, 1.0 - dth**2 / 6.0, np.sin(safe) / safe)  # sin(d)/d
    c = np.where(small, dth / 2.0, (1.0 - np.cos(safe)) / safe)  # (1-cos d)/d
    dxb = (s * vx[:-1] - c * vy[:-1]) * dt
    dyb = (c * vx[:-1] + s * vy[:-1]) * dt
    yaw = yaw0 + np.concatenate(([0.0], np.cumsum(dth)))
    cy, sy = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    x = x0 + np.concatenate(([0.0], np.cumsum(cy * dxb - sy * dyb)))
    y = y0 + np.concatenate(([0.0], np.cumsum(sy * dxb + cy * dyb)))
    return x, y, yaw


def ideal_dd(v_l: ArrayLike, v_r: ArrayLike, track: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ideal differential drive (no slip): y_l = B/2, y_r = -B/2, x_icr = 0."""
    return icr_forward(v_l, v_r, track / 2.0, -track / 2.0, 0.0)


def inverse_v_radius(v: ArrayLike, radius: ArrayLike, track: float, chi_: float = 1.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Tread speeds (v_l, v_r) for linear speed v and turning radius (+ = CCW; inf = straight) of a
    symmetric model with ICR coefficient ``chi_`` (Yu 2010 Fig. 8 inverse kinematics; chi_ = 1 is
    the no-slip model Yu uses to define the commanded radius, Sec. V-A)."""
    v, radius = np.asarray(v, float), np.asarray(radius, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        wz = np.where(np.isinf(radius), 0.0, v / radius)
    half = chi_ * track / 2.0
    return v - wz * half, v + wz * half
