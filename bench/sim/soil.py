"""Deformable soil as a force model: Bekker pressure-sinkage, compaction resistance, Janosi-Hanamoto shear.

Wong, Theory of Ground Vehicles (3rd ed., 2001), Ch. 2; Bekker, Introduction to Terrain-Vehicle Systems (1969):

* pressure-sinkage (Bekker, Wong Ch. 2):  ``p = (k_c / b + k_phi) z^n``;
* static sinkage of a rigid wheel of radius r and width b under load W (Bekker's closed form, Wong Ch. 2):
  ``z = [3 W / ((3 - n) (k_c + b k_phi) sqrt(2 r))]^(2 / (2n + 1))``  -> :func:`sinkage`;
* compaction (motion) resistance, the work of pressing a rut of depth z (Wong Ch. 2):
  ``R_c = b (k_c / b + k_phi) z^(n + 1) / (n + 1)``  -> :func:`compaction_resistance`;
* Janosi-Hanamoto shear (Wong Ch. 2): ``tau = (c + p tan phi)(1 - exp(-j / K))``; over the contact area
  A its full-slip limit is ``c A + W tan phi`` -> :func:`traction_limit`, with A = b l and the chord length of the
  rut ``l = sqrt(2 r z)`` (small sinkage)  -> :func:`contact_length`.

How the testbed uses it (bench/sim/testbed.py and bench/sim/_kernel.c, ``Terrain.soil_model == "bekker"``):
every step and at each wheel, the wheel's current normal load W gives z(W); R_c(W) acts on the body at the contact,
along the wheel's forward axis against its travel (the horizontal part of the rim's normal pressure, which passes
through the axle: no torque about it; Wong Ch. 2, drawbar pull DP = F - R_c), so the tire's shear must carry it and
the wheels slip, as on real loose ground; the terrain's rigid-ground ``rolling_resistance`` (a wheel moment) is not
applied on soil.  The tire law's friction limit ``mu N`` becomes the soil's shear strength ``c A(W) + W tan phi``
(so ``mu`` is ``tan phi + c A / W``; Yu's mu_sa / mu_op drive-brake split does not apply on soil).  The contact
geometry is not moved (Bullet's wheel still rests on the rigid ground): a force model, exact for the steady
resistance and traction of a rigid wheel, without the rut's effect on pitch and on the rolling radius.  Simplifications:
the cohesion's area uses the rut chord, the shear build-up the tire's patch length; every wheel presses a fresh rut
(no multi-pass effect of a rear wheel in the front wheel's rut, so a straight's R_c is an upper bound); no
bulldozing of a laterally skidding wheel.
"""
from __future__ import annotations

import math


def sinkage(load: float, radius: float, width: float, n: float, k_c: float, k_phi: float) -> float:
    """Bekker's static sinkage z [m] of a rigid wheel under ``load`` W [N] (Wong Ch. 2); k_c in N/m^(n+1),
    k_phi in N/m^(n+2)."""
    if load <= 0.0:
        return 0.0
    return (3.0 * load / ((3.0 - n) * (k_c + width * k_phi) * math.sqrt(2.0 * radius))) ** (2.0 / (2.0 * n + 1.0))


def pressure(z: float, width: float, n: float, k_c: float, k_phi: float) -> float:
    """Bekker's pressure p [Pa] at sinkage z (Wong Ch. 2)."""
    return (k_c / width + k_phi) * z ** n


def compaction_resistance(z: float, width: float, n: float, k_c: float, k_phi: float) -> float:
    """Compaction resistance R_c [N] of one wheel at sinkage z (Wong Ch. 2)."""
    return width * (k_c / width + k_phi) * z ** (n + 1.0) / (n + 1.0)


def contact_length(z: float, radius: float) -> float:
    """Length of the rut chord under a rigid wheel at sinkage z, sqrt(2 r z) (small z/r)."""
    return math.sqrt(2.0 * radius * z)


def janosi_shear(j: float, p: float, cohesion: float, friction_angle: float, K: float) -> float:
    """Janosi-Hanamoto shear stress tau [Pa] at shear displacement j (Wong Ch. 2)."""
    return (cohesion + p * math.tan(friction_angle)) * (1.0 - math.exp(-j / K))


def traction_limit(load: float, radius: float, width: float, n: float, k_c: float, k_phi: float,
                   cohesion: float, friction_angle: float) -> float:
    """Full-slip shear force c A + W tan phi [N] of one wheel under ``load`` (Wong Ch. 2 over A = b l)."""
    z = sinkage(load, radius, width, n, k_c, k_phi)
    return cohesion * width * contact_length(z, radius) + load * math.tan(friction_angle)


def soil_constants(radius: float, width: float, n: float, k_c: float, k_phi: float, cohesion: float,
                   friction_angle: float) -> tuple[float, float, float, float, float, float]:
    """Constants of the per-step form ``z = z_coef W^z_exp``, ``R_c = rc_coef z^(n+1)``,
    ``mu = tan phi + ca_coef sqrt(z) / W`` bound by the testbed's loops (Python and C):
    (z_coef, z_exp, rc_coef, n + 1, tan phi, ca_coef)."""
    z_exp = 2.0 / (2.0 * n + 1.0)
    z_coef = (3.0 / ((3.0 - n) * (k_c + width * k_phi) * math.sqrt(2.0 * radius))) ** z_exp
    rc_coef = width * (k_c / width + k_phi) / (n + 1.0)
    return z_coef, z_exp, rc_coef, n + 1.0, math.tan(friction_angle), cohesion * width * math.sqrt(2.0 * radius)
