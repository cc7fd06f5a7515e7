"""Mandow 2007 Sec. IV: the Pioneer P3-AT case study.

The server's symmetric model from its integer parameters Ticksmm and Revcount (eqs. (14)-(15)), the
manufacturer's default model (Sec. IV-B: alpha = 1, x_ICR = 0.3 m) and the published parameters of
Tables I (asphalt) and II (smooth concrete), in Mandow's axes (:mod:`methods.mandow2007.kinematics`).
"""
from __future__ import annotations

import numpy as np

from methods.mandow2007.kinematics import IcrParams

P3AT_DEFAULT = IcrParams.symmetric(1.0, 0.3)
"""Sec. IV-B: the manufacturer's implicit symmetric model of the P3-AT, alpha = 1, x_ICR = 0.3 m."""

TABLE_I = {  # asphalt (Mandow Table I), Mandow's axes
    "pneumatic_50psi": IcrParams(-0.2758, 0.2998, -0.0080, 0.9464, 0.9253),
    "pneumatic_20psi": IcrParams(-0.2553, 0.3071, -0.0120, 0.9271, 0.9049),
    "solid_rubber": IcrParams(-0.2667, 0.2588, -0.0120, 0.9047, 0.9128),
}
TABLE_II = {  # smooth concrete (Mandow Table II)
    "pneumatic_50psi": IcrParams(-0.2878, 0.2758, -0.0159, 0.9457, 0.9418),
    "pneumatic_20psi": IcrParams(-0.2772, 0.2899, -0.0128, 0.9222, 0.9183),
    "solid_rubber": IcrParams(-0.2659, 0.2703, -0.0139, 0.9047, 0.9139),
}


P3AT_ENCODER_GEAR = 138 / 110  # eq. (14): encoder and transmission constant of the P3-AT


def p3at_server_parameters(alpha: float, x_icr: float, wheel_radius: float) -> tuple[int, int]:
    """Eqs. (14)-(15): the P3-AT server's integer ``(Ticksmm, Revcount)`` for a symmetric model
    (alpha, x_ICR [m]) and the wheel radius [m] (the equations take millimetres: converted here)."""
    r_mm, x_icr_mm = 1000.0 * wheel_radius, 1000.0 * x_icr
    ticksmm = round(alpha * r_mm * P3AT_ENCODER_GEAR)
    return ticksmm, round(2 * np.pi * x_icr_mm * ticksmm / 8)


def p3at_symmetric_model(ticksmm: int, revcount: int, wheel_radius: float) -> IcrParams:
    """Inverse of eqs. (14)-(15): the symmetric model (eq. (8)) implied by the server parameters."""
    alpha = ticksmm / (1000.0 * wheel_radius * P3AT_ENCODER_GEAR)
    return IcrParams.symmetric(alpha, 8 * revcount / (2 * np.pi * ticksmm) / 1000.0)
