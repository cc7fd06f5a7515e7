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
Friction falls with the sliding speed ``|s|`` of the contact point when ``Terrain.friction_speed_decay``
(A_s [s/m]) is set: ``mu / (1 + A_s |s|)``, Dugoff's friction reduction ``mu_0 (1 - A_s V_s)`` (Dugoff, Fancher
and Segel, SAE 700377, 1970; V_s the sliding speed) to first order, kept positive at any speed.  It makes the
slip grow with speed: the wheels of a faster turn slide faster and hold less.  The whole law is scaled: the Janosi
law's small-slip stiffness (proportional to mu) falls with it, a second-order change there since |s| is small, where
Dugoff's linear region keeps its stiffness; on Bekker soil the shear strength ``c A + W tan(phi)`` (the ``mu`` the
testbed passes) falls alike.
The force magnitude is capped at ``k_max |s|`` (k_max = m_eff/dt) so the explicit coupling to
Bullet's chassis integration stays stable at tiny slips (DESIGN.md testbed notes).

Tire types (:func:`tire_contact`, ``Platform.tire_pressure`` / ``tire_modulus``): each wheel's patch length
follows from its current load W, ``l = patch_coef sqrt(W)``, and so does its loaded rolling radius
``r (1 - radius_coef W)``; the law's small-slip stiffness, and with it the cornering stiffness
``C_alpha = mu W l / (2 K_lat)`` [N/rad], scales with l.
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


def tire_contact(radius: float, width: float, pressure: float, modulus: float) -> tuple[float, float]:
    """(patch_coef, radius_coef): a wheel under load W [N] has the patch length ``patch_coef sqrt(W)`` [m] and the
    loaded rolling radius ``radius (1 - radius_coef W)``.

    Pneumatic (``pressure`` p > 0): a toroidal membrane, crown radius r and section radius rho = b / 2, pressed
    delta into the ground touches it on an ellipse of semi-axes sqrt(2 r delta) and sqrt(2 rho delta) (small
    delta, geometry); the inflation pressure over that area carries the load, the carcass stiffness neglected
    (Wong, Theory of Ground Vehicles, 3rd ed. 2001, Sec. 1.1: average contact pressure ~ inflation pressure):
    ``delta = W / (2 pi p sqrt(r rho))``, patch ``l = 2 sqrt(2 r delta)``; the effective rolling radius of a loaded
    tire is ``r - delta / 3`` (Jazar, Vehicle Dynamics: Theory and Application, 2008, Sec. 3.3).
    Solid rubber (``modulus`` E > 0): Hertz line contact of an incompressible rubber cylinder (nu = 0.5) on rigid
    ground (Johnson, Contact Mechanics, 1985, Sec. 4.3): half-width ``a = sqrt(4 W r / (pi b E*))``, E* = E / (1 -
    nu^2), ``l = 2 a``; its deflection (~0.1 mm) is not applied to the radius (radius_coef 0).
    """
    if pressure > 0.0 and modulus > 0.0:
        raise ValueError("a tire is pneumatic (tire_pressure) or solid (tire_modulus), not both")
    if pressure > 0.0:
        delta_per_n = 1.0 / (2.0 * math.pi * pressure * math.sqrt(radius * width / 2.0))
        return 2.0 * math.sqrt(2.0 * radius * delta_per_n), delta_per_n / (3.0 * radius)
    if modulus > 0.0:
        e_star = modulus / (1.0 - 0.25)
        return 2.0 * math.sqrt(4.0 * radius / (math.pi * width * e_star)), 0.0
    raise ValueError("no tire: tire_pressure and tire_modulus are both 0")


def pneumatic_rolling_resistance(pressure: float) -> float:
    """Rolling-resistance coefficient of a pneumatic tire at low speed on a hard road, pressure [Pa]:
    ``0.005 + 0.01 / p_bar`` (Gillespie, Fundamentals of Vehicle Dynamics, 1992, Ch. 4, passenger-car tires;
    its speed term 0.0095 (V / 100 km/h)^2 / p_bar is < 1e-5 below 2 km/h)."""
    return 0.005 + 0.01 / (pressure / 1e5)


def hysteresis_rolling_resistance(half_width: float, radius: float, alpha: float) -> float:
    """Rolling-resistance coefficient of a cylinder in line contact that loses the fraction ``alpha`` of the elastic
    work of the leading half of its Hertz contact: ``(2 alpha / (3 pi)) a / r`` (Tabor's hysteresis theory; Johnson,
    Contact Mechanics, 1985, Sec. 8.4: the moment of the leading half of the Hertz pressure, 2 W a / (3 pi))."""
    return 2.0 * alpha / (3.0 * math.pi) * half_width / radius


def tire_constants(K: float, K_lat_ratio: float, patch: float, eps: float) -> tuple[float, float, float]:
    """(patch / K, patch / K_lat, eps^2) bound by :func:`tire_law` and by the testbed's C step."""
    return patch / K, patch / (K * K_lat_ratio), eps * eps


def tire_law(model_janosi: bool, mu_lat_ratio: float, K: float, K_lat_ratio: float, patch: float,
             eps: float, k_max: float, speed_decay: float = 0.0
             ) -> Callable[[float, float, float, float, float, float], tuple[float, float, float]]:
    """The terrain's tire law with its constants bound (called 4 times per physics step):
    ``law(s_lon, s_lat, u, v_lon, normal, mu, ps) -> (F_lon, F_lat, stiffness)``; ``ps`` scales ``patch`` (1: the
    patch as bound; the testbed binds 1 m and passes each wheel's patch length when the platform has a tire model).

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
    ``speed_decay`` A_s [s/m]: ``mu`` becomes ``mu / (1 + A_s |s|)`` (module docstring; 0: unchanged, bit for bit).
    """
    hypot, exp = math.hypot, math.exp
    c_lon, c_lat, eps2 = tire_constants(K, K_lat_ratio, patch, eps)

    def janosi(s_lon: float, s_lat: float, u: float, v_lon: float, normal: float, mu: float, ps: float = 1.0
               ) -> tuple[float, float, float]:
        if normal <= 0.0:
            return 0.0, 0.0, 0.0
        s = hypot(s_lon, s_lat)
        if s < 1e-12:
            return 0.0, 0.0, k_max
        if speed_decay > 0.0:
            mu = mu / (1.0 + speed_decay * s)
        v_ref = abs(u)  # max(|u|, hypot(v_lon, s_lat), eps), without the builtin's call cost
        h = hypot(v_lon, s_lat)
        if h > v_ref:
            v_ref = h
        if eps > v_ref:
            v_ref = eps
        z_lon = s_lon * (c_lon * ps) / v_ref
        z_lat = s_lat * (c_lat * ps) / v_ref
        z = hypot(z_lon, z_lat)
        frac = 0.5 * z if z < 1e-6 else 1.0 - (1.0 - exp(-z)) / z  # janosi_fraction(z, 1)
        a, b = (1.0 - frac) / z, frac / s
        mag = mu * normal * frac
        if mag > k_max * s:
            mag = k_max * s
        return -mag * (a * z_lon + b * s_lon), -mag * mu_lat_ratio * (a * z_lat + b * s_lat), mag / s

    def coulomb(s_lon: float, s_lat: float, u: float, v_lon: float, normal: float, mu: float, ps: float = 1.0
                ) -> tuple[float, float, float]:
        if normal <= 0.0:
            return 0.0, 0.0, 0.0
        s = hypot(s_lon, s_lat)
        if s < 1e-12:
            return 0.0, 0.0, k_max
        if speed_decay > 0.0:
            mu = mu / (1.0 + speed_decay * s)
        mag = mu * normal * s / math.sqrt(s * s + eps2)
        if mag > k_max * s:
            mag = k_max * s
        return -mag * s_lon / s, -mag * mu_lat_ratio * s_lat / s, mag / s

    return janosi if model_janosi else coulomb
