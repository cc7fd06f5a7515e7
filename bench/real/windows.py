"""The window protocol of the real-data benchmark: what a plugin implements to be scored on command windows.

A DRIVE table (:mod:`bench.real.drive`) holds fixed-length windows of one command step each (20 Hz,
``n_samples`` samples).  A method plugin that can be scored on them offers
``window_models(wheel_radius, track) -> list[WindowModel]``: each :class:`WindowModel` is fitted on the
calibration windows (``fit``) and predicts every window's poses from its measured wheel speeds (``predict``),
vectorised over windows.  The models live in the paper's package (``methods/<paper>/windows.py``) and use the
paper's own equations; this module has only what every model shares: integration of body velocities from each
window's initial ICP pose, the end-pose errors and Mandow 2007 eq. (13)'s residuals that the scoring and the
end-pose fits use, the tread speeds, Wang 2015 eq. (25)'s measured chi, and the SE(2) twist of a window.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Protocol, Sequence, runtime_checkable

import numpy as np
from scipy.optimize import least_squares

from bench.kinematics import curvature_ratio, integrate_se2
from bench.real.drive import DriveWindows
from bench.run import wrap_angle

MIN_TURN = 0.2  # [rad] a steady window must turn this much for chi (eq. (25)) to be measured
#: the rows of the ICR family, whose best the real benchmark's verdict sets against ideal differential drive
ICR_FAMILY = ("icr_sym_chi", "mandow2007_icr", "wang2015_chi_curve")

Pose = tuple[np.ndarray, np.ndarray, np.ndarray]


@runtime_checkable
class WindowModel(Protocol):
    """What the real benchmark scores: fit on calibration windows, predict every window's poses."""

    name: str
    label: str

    def fit(self, calib: DriveWindows) -> "WindowModel": ...

    def predict(self, windows: DriveWindows) -> Pose: ...

    def params(self) -> dict[str, float]: ...


@runtime_checkable
class WindowMethod(Protocol):
    """A method plugin that the real-data benchmark can score: it offers its window models for a platform of
    this wheel radius and track [m] (one or more rows of the benchmark, each a :class:`WindowModel`)."""

    name: str

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]: ...


class VelocityWindowModel:
    """Base of the models defined by body velocities from the measured wheel speeds: ``velocities(windows)``
    gives (v_x, v_y, w_z), each (n_windows, n_samples); ``predict`` integrates them from each window's initial
    ICP pose (:func:`predict_from_velocities`)."""

    def velocities(self, w: DriveWindows) -> Pose:  # pragma: no cover - abstract
        raise NotImplementedError

    def predict(self, windows: DriveWindows) -> Pose:
        return predict_from_velocities(windows, *self.velocities(windows))


def fit_end_poses(model: Any, names: Sequence[str], x0: Sequence[float],
                  bounds: tuple[Sequence[float], Sequence[float]], calib: DriveWindows) -> Any:
    """``model`` (a frozen dataclass with a ``fit_cost`` field) with the fields ``names`` fitted by
    ``scipy.optimize.least_squares`` on Mandow 2007's J (eq. (13): squared x, y [m] and yaw [rad] errors at each
    calibration window's end, equal weights) from ``x0`` within ``bounds``; ``fit_cost`` = J per window."""

    def resid(p: np.ndarray) -> np.ndarray:
        return end_residuals(dataclasses.replace(model, **dict(zip(names, map(float, p)))).predict(calib), calib)

    sol = least_squares(resid, np.asarray(x0, float), bounds=bounds, x_scale="jac", method="trf")
    return dataclasses.replace(model, **dict(zip(names, map(float, sol.x))),
                               fit_cost=float(2 * sol.cost / max(calib.n_windows, 1)))


def integrate_windows(dt: float, vx: np.ndarray, vy: np.ndarray, wz: np.ndarray,
                      x0: np.ndarray, y0: np.ndarray, yaw0: np.ndarray) -> Pose:
    """Integrate body velocities (n_windows, n_samples) held over each ``dt`` from each window's
    initial pose; returns x, y, yaw of shape (n_windows, n_samples).

    All windows go through one call of :func:`bench.kinematics.integrate_se2`: they are laid end
    to end, and each window's poses are re-expressed relative to its first one (an SE(2) relative
    pose does not depend on where the chain put the window, nor on the link interval driven by the
    previous window's last sample), then moved to the window's initial pose.
    """
    vx, vy, wz = (np.asarray(a, float) for a in (vx, vy, wz))
    n, m = vx.shape
    t = dt * np.arange(n * m)
    x, y, yaw = integrate_se2(t, vx.ravel(), vy.ravel(), wz.ravel())
    x, y, yaw = x.reshape(n, m), y.reshape(n, m), yaw.reshape(n, m)
    dx, dy = x - x[:, :1], y - y[:, :1]
    c0, s0 = np.cos(yaw[:, :1]), np.sin(yaw[:, :1])
    xr, yr, yawr = c0 * dx + s0 * dy, -s0 * dx + c0 * dy, yaw - yaw[:, :1]
    x0, y0, yaw0 = (np.asarray(a, float)[:, None] for a in (x0, y0, yaw0))
    c, s = np.cos(yaw0), np.sin(yaw0)
    return x0 + c * xr - s * yr, y0 + s * xr + c * yr, yaw0 + yawr


INPUTS = ("enc_wl", "enc_wr", "cmd_wl", "cmd_wr", "imu_gz")  # what the window models read, where the table has it


def valid_windows(w: DriveWindows) -> np.ndarray:
    """Windows whose inputs (:data:`INPUTS` the table has: wheel speeds, commands, gyro; every sample, as either
    reading of the wheel speeds' stamps uses a different end) and ICP start/end pose are finite: a NaN in one
    sample drops the window for every model alike (the comparisons stay paired), never one model's row."""
    ok = np.ones(w.n_windows, bool)
    for c in INPUTS:
        if w.has(c) and np.isfinite(w[c]).any():  # a channel NaN throughout is absent (its models are skipped)
            ok &= np.isfinite(w[c]).all(axis=1)
    for c in ("ref_x", "ref_y", "ref_yaw"):
        ok &= np.isfinite(w[c][:, 0]) & np.isfinite(w[c][:, -1])
    return ok


def predict_from_velocities(w: DriveWindows, vx: np.ndarray, vy: np.ndarray, wz: np.ndarray) -> Pose:
    """Dead-reckon every window from its initial ICP pose with the given body velocities."""
    return integrate_windows(w.dt, vx, vy, wz, w["ref_x"][:, 0], w["ref_y"][:, 0], w["ref_yaw"][:, 0])


def end_errors(pred: Pose, w: DriveWindows) -> tuple[np.ndarray, np.ndarray]:
    """Translation [m] and absolute yaw [rad] error at each window's last sample."""
    x, y, yaw = pred
    et = np.hypot(x[:, -1] - w["ref_x"][:, -1], y[:, -1] - w["ref_y"][:, -1])
    ey = np.abs(np.asarray(wrap_angle(yaw[:, -1] - w["ref_yaw"][:, -1])))
    return et, ey


def end_residuals(pred: Pose, w: DriveWindows) -> np.ndarray:
    """Mandow 2007 eq. (13) residuals (dx [m], dy [m], dphi [rad]) at each window's end, flattened."""
    x, y, yaw = pred
    return np.concatenate([
        x[:, -1] - w["ref_x"][:, -1],
        y[:, -1] - w["ref_y"][:, -1],
        np.asarray(wrap_angle(yaw[:, -1] - w["ref_yaw"][:, -1])),
    ])


def tread_speeds(w: DriveWindows, wheel_radius: float) -> tuple[np.ndarray, np.ndarray]:
    return wheel_radius * w["enc_wl"], wheel_radius * w["enc_wr"]


def window_chi(w: DriveWindows, wheel_radius: float, track: float, min_turn: float = MIN_TURN
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Wang 2015 eq. (25)/(42) per window: ``chi = (S_r - S_l) / (phi B)``.

    Returns (chi, curvature_ratio, phi, usable) with ``S_i = r sum_k w_i,k dt`` over the samples the
    integration uses, ``phi`` the ICP yaw change from the first to the last sample, the curvature
    ratio ``(S_l + S_r)/(S_r - S_l)``, and ``usable`` = steady, finite and ``|phi| >= min_turn``.
    """
    sl = wheel_radius * np.sum(w["enc_wl"][:, :-1], axis=1) * w.dt
    sr = wheel_radius * np.sum(w["enc_wr"][:, :-1], axis=1) * w.dt
    phi = w["ref_yaw"][:, -1] - w["ref_yaw"][:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        chi = (sr - sl) / (phi * track)
        lam = curvature_ratio(sl, sr)
    usable = w.steady & np.isfinite(chi) & np.isfinite(lam) & (np.abs(phi) >= min_turn)
    return chi, lam, phi, usable


def window_twist(w: DriveWindows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Constant body twist (u, v, phi) that carries each window's first ICP pose to its last one
    (SE(2) logarithm of the relative end pose): ``u, v`` [m] forward/left displacement along the
    arc, ``phi`` [rad] the yaw change; divided by the duration they are ``v_Gx, v_Gy, psi_dot``."""
    x, y, h = (w[c] for c in ("ref_x", "ref_y", "ref_yaw"))
    dx, dy = x[:, -1] - x[:, 0], y[:, -1] - y[:, 0]
    c0, s0 = np.cos(h[:, 0]), np.sin(h[:, 0])
    bx, by = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
    phi = h[:, -1] - h[:, 0]
    small = np.abs(phi) < 1e-9
    ph = np.where(small, 1.0, phi)
    a = np.where(small, 1.0, np.sin(ph) / ph)
    b = np.where(small, 0.0, (1.0 - np.cos(ph)) / ph)
    det = a * a + b * b
    return (a * bx + b * by) / det, (-b * bx + a * by) / det, phi
