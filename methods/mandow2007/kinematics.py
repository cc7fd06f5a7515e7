"""Mandow 2007 Sec. II: the ICR kinematic model of a skid-steer vehicle, eqs. (2)-(10).

The kinematic parameters K = {x_ICRl, x_ICRr, y_ICRv, alpha_l, alpha_r} (:class:`IcrParams`, eqs. (2)-(5)),
the kinematic matrix A of eqs. (6)-(7) and its symmetric form, eq. (8), the steering efficiency chi of
eq. (9) and the eccentricity e of eq. (10), and dead reckoning of eq. (6) with (7) from the encoders.

Axes (converted here, at the boundary)
    Mandow's local frame has Y forward and X lateral pointing to the RIGHT (eq. (7): a positive
    yaw rate needs V_r > V_l when x_ICRr > x_ICRl).  The suite's body frame has x forward, y left.
    Hence, for the ICR coordinates::

        y_l   = -x_ICRl        y_r = -x_ICRr        x_icr = y_ICRv
        vx    = Mandow v_y     vy  = -Mandow v_x    wz    = omega_z

    :class:`IcrParams` keeps Mandow's names and signs (so Table I can be typed in as printed);
    :meth:`IcrParams.body_icr` gives the suite's ``(y_l, y_r, x_icr)``.  Mandow's tread speeds
    ``V_l, V_r`` are the nominal ones, ``r * w`` with the platform's nominal wheel radius; the
    correction factors ``alpha_l, alpha_r`` turn them into the speeds that move the ICRs (eqs. (3)-(4)).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike

from bench.kinematics import icr_forward
from bench.registry import Estimate, make_estimate
from bench.run import Run
from methods.baselines import dead_reckon, encoder_speeds, initial_pose, platform_geometry

PARAM_NAMES = ("x_icr_l", "x_icr_r", "y_icr_v", "alpha_l", "alpha_r")


@dataclass(frozen=True)
class IcrParams:
    """Kinematic parameters K = {x_ICRl, x_ICRr, y_ICRv, alpha_l, alpha_r} in Mandow's axes
    (X lateral to the right, Y forward) [m, m, m, -, -]."""

    x_icr_l: float
    x_icr_r: float
    y_icr_v: float
    alpha_l: float = 1.0
    alpha_r: float = 1.0

    def __post_init__(self) -> None:
        vals = self.as_array()
        if not np.all(np.isfinite(vals)):
            raise ValueError(f"IcrParams must be finite, got {dict(zip(PARAM_NAMES, vals, strict=True))}")
        if not self.x_icr_r > self.x_icr_l:
            raise ValueError(f"IcrParams needs x_icr_r > x_icr_l (right tread ICR right of the left one), "
                             f"got x_icr_l={self.x_icr_l}, x_icr_r={self.x_icr_r}")

    @classmethod
    def symmetric(cls, alpha: float, x_icr: float) -> "IcrParams":
        """Eq. (8): alpha_l = alpha_r = alpha, x_ICR = -x_ICRl = x_ICRr, y_ICRv = 0."""
        return cls(-x_icr, x_icr, 0.0, alpha, alpha)

    @classmethod
    def ideal(cls, track: float) -> "IcrParams":
        """No-slip differential drive: tread ICRs on the tread centre lines, alpha = 1."""
        return cls.symmetric(1.0, track / 2.0)

    @classmethod
    def from_array(cls, k: ArrayLike) -> "IcrParams":
        k = np.asarray(k, float).ravel()
        return cls(*(float(v) for v in k))

    def as_array(self) -> np.ndarray:
        return np.array([self.x_icr_l, self.x_icr_r, self.y_icr_v, self.alpha_l, self.alpha_r], float)

    def as_dict(self) -> dict[str, float]:
        return dict(zip(PARAM_NAMES, (float(v) for v in self.as_array()), strict=True))

    def body_icr(self) -> tuple[float, float, float]:
        """The suite's ``(y_l, y_r, x_icr)`` = ``(-x_ICRl, -x_ICRr, y_ICRv)`` (axes conversion)."""
        return -self.x_icr_l, -self.x_icr_r, self.y_icr_v

    def steering_efficiency(self, track: float) -> float:
        return float(steering_efficiency(self.x_icr_l, self.x_icr_r, track))

    def eccentricity(self) -> float:
        return float(eccentricity(self.x_icr_l, self.x_icr_r))


def kinematic_matrix(p: IcrParams) -> np.ndarray:
    """Eq. (7): the 3x2 matrix A with (v_x, v_y, omega_z)^T = A (V_l, V_r)^T in Mandow's axes."""
    d = p.x_icr_r - p.x_icr_l
    return np.array([
        [-p.y_icr_v * p.alpha_l, p.y_icr_v * p.alpha_r],
        [p.x_icr_r * p.alpha_l, -p.x_icr_l * p.alpha_r],
        [-p.alpha_l, p.alpha_r],
    ]) / d


def body_velocities(p: IcrParams, v_l: ArrayLike, v_r: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. (6)-(7) in the suite's body frame: ``(vx, vy, wz)`` from nominal tread speeds
    ``V = r w`` [m/s].  Uses :func:`bench.kinematics.icr_forward` on the corrected speeds
    ``alpha V`` with ``(y_l, y_r, x_icr) = (-x_ICRl, -x_ICRr, y_ICRv)``."""
    y_l, y_r, x_icr = p.body_icr()
    return icr_forward(p.alpha_l * np.asarray(v_l, float), p.alpha_r * np.asarray(v_r, float), y_l, y_r, x_icr)


def steering_efficiency(x_icr_l: ArrayLike, x_icr_r: ArrayLike, track: float) -> np.ndarray:
    """Eq. (9): chi = L / (x_ICRr - x_ICRl), 0 < chi <= 1 (the inverse of Wang's chi)."""
    return track / (np.asarray(x_icr_r, float) - np.asarray(x_icr_l, float))


def eccentricity(x_icr_l: ArrayLike, x_icr_r: ArrayLike) -> np.ndarray:
    """Eq. (10): e = (x_ICRr + x_ICRl) / (x_ICRr - x_ICRl)."""
    x_icr_l, x_icr_r = np.asarray(x_icr_l, float), np.asarray(x_icr_r, float)
    return (x_icr_r + x_icr_l) / (x_icr_r - x_icr_l)


def dead_reckoning(p: IcrParams, run: Run, name: str = "mandow2007", info: Mapping[str, Any] | None = None
                   ) -> Estimate:
    """Dead reckoning of eq. (6) with (7) from the encoders, from :func:`methods.baselines.initial_pose`."""
    track, radius = platform_geometry(run)
    t, wl, wr = encoder_speeds(run)
    vx, vy, wz = body_velocities(p, radius * wl, radius * wr)
    pose0 = initial_pose(run)
    x, y, yaw = dead_reckon(t, vx, vy, wz, pose0)
    y_l, y_r, x_icr = p.body_icr()
    n = t.size
    out = {"params": p.as_dict(), "body_icr": {"y_l": y_l, "y_r": y_r, "x_icr": x_icr},
           "steering_efficiency": p.steering_efficiency(track), "eccentricity": p.eccentricity(),
           "initial_pose": pose0}
    out.update(info or {})
    return make_estimate(
        name, out, t=t, x=x, y=y, yaw=yaw, vx=vx, vy=vy, wz=wz,
        y_l=np.full(n, y_l), y_r=np.full(n, y_r), x_icr=np.full(n, x_icr),
        chi=np.full(n, (y_l - y_r) / track),
    )
