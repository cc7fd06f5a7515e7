"""Wang 2015 Secs. 2.1 and 3.5: the symmetric kinematic model, eqs. (10)-(15), and dead reckoning with the
default P3-AT model (eq. (46)) or the proposed chi(curvature ratio) model (eq. (47)); the validation inputs
of eq. (48).

Axes: Wang's body frame is x forward, y left (Fig. 1), the suite's own; no conversion.

Inconsistency in the paper (reported, not silently fixed)
    Eqs. (46)-(47) write ``omega_z = (v_r - v_l) / (2 B chi)``, but eq. (11) gives
    ``omega_z = (v_r - v_l) / (2 y0)`` and eq. (15) ``y0 = B chi / 2``, i.e.
    ``omega_z = (v_r - v_l) / (B chi)``.  The literal form would put the tread ICRs at +-B chi
    (chi = 1.5 -> 0.6 m for the P3-AT, twice Mandow's 0.3 m for the same default model).  The
    consistent eq. (15) form is the default; ``literal_eq46=True`` reproduces the printed equations.

Straight motion (v_l = v_r, lambda infinite) uses chi at the end of the curve's domain, with no effect
since omega_z = 0.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bench.kinematics import curvature_ratio
from bench.registry import Estimate, make_estimate
from bench.run import Run
from methods.baselines import dead_reckon, encoder_speeds, initial_pose, platform_geometry

CHI_P3AT_DEFAULT = 1.5  # Sec. 3.5, eq. (46)

VALIDATION_PROFILE = (  # eq. (48): (t_end [s], v_l [m/s], v_r [m/s]); zero before 0 and after 6 s
    (1.0, 0.2, 0.15), (2.0, 0.2, 0.1), (3.0, 0.3, 0.1), (4.0, 0.4, 0.0), (5.0, 0.3, 0.2), (6.0, 0.3, 0.25),
)


def symmetric_velocities(v_l: ArrayLike, v_r: ArrayLike, chi: ArrayLike, track: float, literal_eq46: bool = False
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (11) with eq. (15): ``vx = (v_l + v_r)/2``, ``vy = 0``, ``wz = (v_r - v_l)/(B chi)``
    (``literal_eq46``: ``(v_r - v_l)/(2 B chi)`` as printed in eqs. (46)-(47))."""
    v_l, v_r, chi = np.asarray(v_l, float), np.asarray(v_r, float), np.asarray(chi, float)
    scale = 2.0 if literal_eq46 else 1.0
    vx = 0.5 * (v_l + v_r)
    wz = (v_r - v_l) / (scale * track * chi)
    return vx, np.zeros_like(vx), wz


def _estimate(name: str, run: Run, chi_fn: Any, literal_eq46: bool, info: dict[str, Any]) -> Estimate:
    track, radius = platform_geometry(run)
    t, wl, wr = encoder_speeds(run)
    v_l, v_r = radius * wl, radius * wr
    cr = curvature_ratio(v_l, v_r)
    cr = np.where(v_r == v_l, np.inf, cr)  # straight or standing: no turn, chi at the domain end
    chi = np.broadcast_to(np.asarray(chi_fn(cr), float), t.shape).copy()
    vx, vy, wz = symmetric_velocities(v_l, v_r, chi, track, literal_eq46)
    pose0 = initial_pose(run)
    x, y, yaw = dead_reckon(t, vx, vy, wz, pose0)
    y0 = (2.0 if literal_eq46 else 1.0) * track * chi / 2.0  # effective tread-ICR distance
    info = dict(info, track=track, wheel_radius=radius, literal_eq46=literal_eq46, initial_pose=pose0)
    return make_estimate(name, info, t=t, x=x, y=y, yaw=yaw, vx=vx, vy=vy, wz=wz,
                         y_l=y0, y_r=-y0, x_icr=np.zeros_like(t), chi=chi)
