"""Tangential tire-ground force laws of the testbed (per wheel, scalar, called every step).

Bullet's own wheel friction is switched off (its friction rows are fixed to world axes and make
turning depend on the world heading, DESIGN.md "Testbed notes"); the tangential force at each
wheel contact comes from here.  Two laws, chosen by ``Terrain.model``:

* ``coulomb``: smooth Coulomb friction, ``F = -mu N s / sqrt(|s|^2 + eps^2)`` on the sliding
  velocity ``s`` of the contact point (the law of Caracciolo/Kozlowski that Yu 2010 criticises).
* ``janosi``: Janosi-Hanamoto shear stress ``tau = p mu (1 - exp(-j/K))`` (Yu 2010 eq. (7),
  Wang 2015 eq. (17)) over a contact patch of length ``Lp``: the shear displacement grows
  linearly from the leading edge, ``j(x) = |s| x / v_ref`` with ``v_ref = max(|r w|, |v_lon|)``
  (the rolled distance), so the patch average is

      F = mu N [1 - (K / j_max) (1 - exp(-j_max / K))],  j_max = |s| Lp / v_ref,

  directed against the sliding velocity.  It depends on the slip *ratio*, not the slip speed,
  which is what makes chi nearly speed-independent (Wang 2015 Fig. 12b).

``mu_sa``/``mu_op`` (Yu 2010 Sec. V-A): friction when the motor drives / brakes the wheel, blended
smoothly on the sign of torque x wheel speed.  Lateral friction is ``mu * mu_lat_ratio``.
The force magnitude is capped at ``k_max |s|`` (k_max = m_eff/dt) so the explicit coupling to
Bullet's chassis integration stays stable at tiny slips (DESIGN.md testbed notes).
"""
from __future__ import annotations

import math
from typing import Callable


def friction_coefficient(mu_sa: float, mu_op: float, torque: float, w: float, scale: float = 0.05) -> float:
    """Yu's mu_sa when the motor drives the wheel (torque and speed of one sign), mu_op when it brakes."""
    drive = 0.5 * (1.0 + math.tanh(torque * w / scale))
    return mu_op + (mu_sa - mu_op) * drive


def janosi_fraction(j_max: float, K: float) -> float:
    """Patch average of 1 - exp(-j/K) for j uniform in [0, j_max] (exact; series near 0)."""
    z = j_max / K
    if z < 1e-6:
        return 0.5 * z
    return 1.0 - (1.0 - math.exp(-z)) / z


def tire_constants(K: float, K_lat_ratio: float, patch: float, eps: float) -> tuple[float, float, float]:
    """(patch / K, patch / K_lat, eps^2) bound by :func:`tire_law` and by the testbed's C step."""
    return patch / K, patch / (K * K_lat_ratio), eps * eps


def tire_law(model_janosi: bool, mu_lat_ratio: float, K: float, K_lat_ratio: float, patch: float,
             eps: float, k_max: float) -> Callable[[float, float, float, float, float, float], tuple[float, float, float]]:
    """The terrain's tire law with its constants bound (called 4 times per physics step):
    ``law(s_lon, s_lat, u, v_lon, normal, mu) -> (F_lon, F_lat, stiffness)``.

    Tangential force (F_lon, F_lat) in the wheel frame on the vehicle at one contact, and the
    secant stiffness |F| / |s| [N s/m] used by the semi-implicit wheel-spin update (for a
    saturating law the secant bounds the tangent from above, so the update stays stable; the
    steady state does not depend on it).

    s_lon, s_lat: sliding velocity of the contact point (v_lon - r w, v_lat) [m/s];
    u: tread speed r w; v_lon: longitudinal velocity of the contact point; normal: N [N] (>= 0).
    Janosi: shear displacement normalised per direction, ``z_i = j_i / K_i`` with
    ``K_lat = K * K_lat_ratio`` (tires shear more easily sideways); the force follows the normalised
    displacement while the patch adheres and turns to the sliding direction as it saturates
    (brush-model behaviour: Coulomb direction in full sliding).
    """
    hypot, exp = math.hypot, math.exp
    c_lon, c_lat, eps2 = tire_constants(K, K_lat_ratio, patch, eps)

    def janosi(s_lon: float, s_lat: float, u: float, v_lon: float, normal: float, mu: float
               ) -> tuple[float, float, float]:
        if normal <= 0.0:
            return 0.0, 0.0, 0.0
        s = hypot(s_lon, s_lat)
        if s < 1e-12:
            return 0.0, 0.0, k_max
        v_ref = abs(u)  # max(|u|, hypot(v_lon, s_lat), eps), without the builtin's call cost
        h = hypot(v_lon, s_lat)
        if h > v_ref:
            v_ref = h
        if eps > v_ref:
            v_ref = eps
        z_lon = s_lon * c_lon / v_ref
        z_lat = s_lat * c_lat / v_ref
        z = hypot(z_lon, z_lat)
        frac = 0.5 * z if z < 1e-6 else 1.0 - (1.0 - exp(-z)) / z  # janosi_fraction(z, 1)
        a, b = (1.0 - frac) / z, frac / s
        mag = mu * normal * frac
        if mag > k_max * s:
            mag = k_max * s
        return -mag * (a * z_lon + b * s_lon), -mag * mu_lat_ratio * (a * z_lat + b * s_lat), mag / s

    def coulomb(s_lon: float, s_lat: float, u: float, v_lon: float, normal: float, mu: float
                ) -> tuple[float, float, float]:
        if normal <= 0.0:
            return 0.0, 0.0, 0.0
        s = hypot(s_lon, s_lat)
        if s < 1e-12:
            return 0.0, 0.0, k_max
        mag = mu * normal * s / math.sqrt(s * s + eps2)
        if mag > k_max * s:
            mag = k_max * s
        return -mag * s_lon / s, -mag * mu_lat_ratio * s_lat / s, mag / s

    return janosi if model_janosi else coulomb
