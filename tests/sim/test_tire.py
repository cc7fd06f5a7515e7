"""The tire types of issue 31 (bench/sim/tire.py) against closed forms computed here by hand: the toroidal-membrane
pneumatic contact, the Hertz line contact of a solid rubber tire, the rolling-resistance formulas the platform files
quote, and the cornering stiffness of the Janosi law at small slip, mu W l / (2 K_lat)."""
from __future__ import annotations

import math

import pytest

from bench.sim.tire import (hysteresis_rolling_resistance, pneumatic_rolling_resistance, tire_contact,
                            tire_law)
from bench.spec import load_platform

PSI = 6894.757293168361  # Pa
W = 30.6 * 9.81 / 4  # static load of one P3-AT wheel [N]


def test_pneumatic_patch_and_loaded_radius_by_hand():
    """20 psi, r = 0.1075 m, b = 0.05 m: the ellipse area 2 pi delta sqrt(r b/2) times p carries W, so
    delta = 1.671 mm; patch 2 sqrt(2 r delta) = 37.9 mm (Yu 2010 Table II: (L - C)/2 = 35 mm); radius r - delta/3."""
    r, b, p = 0.1075, 0.05, 20 * PSI
    delta = W / (2 * math.pi * p * math.sqrt(r * b / 2))
    assert delta == pytest.approx(1.671e-3, rel=1e-3)
    p_coef, q_coef = tire_contact(r, b, p, 0.0)
    assert p_coef * math.sqrt(W) == pytest.approx(2 * math.sqrt(2 * r * delta), rel=1e-12)
    assert p_coef * math.sqrt(W) == pytest.approx(0.035, rel=0.1)  # Yu's measured patch of the P3-AT tire
    assert r * (1 - q_coef * W) == pytest.approx(r - delta / 3, rel=1e-12)
    # 50 psi: delta scales 1/p, the patch 1/sqrt(p)
    p50, q50 = tire_contact(r, b, 50 * PSI, 0.0)
    assert p50 / p_coef == pytest.approx(math.sqrt(20 / 50), rel=1e-12) and q50 / q_coef == pytest.approx(0.4)


def test_solid_patch_is_the_hertz_line_contact():
    """Johnson 1985 Sec. 4.3: a = sqrt(4 P R / (pi E*)), P = W / b, E* = E / (1 - 0.5^2); no radius change."""
    r, b, e = 0.095, 0.05, 5.52e6
    a = math.sqrt(4 * (W / b) * r / (math.pi * e / 0.75))
    p_coef, q_coef = tire_contact(r, b, 0.0, e)
    assert p_coef * math.sqrt(W) == pytest.approx(2 * a, rel=1e-12)
    assert 2 * a == pytest.approx(0.00993, rel=1e-3) and q_coef == 0.0
    with pytest.raises(ValueError, match="not both"):
        tire_contact(r, b, 1e5, e)


def test_platform_rolling_resistances_are_the_quoted_formulas():
    """Gillespie 1992: 0.005 + 0.01 / p_bar; Tabor / Johnson 1985 Sec. 8.4: (2 alpha / 3 pi) a / r, alpha = 0.2."""
    f20, f50 = 0.005 + 0.01 / (20 * PSI / 1e5), 0.005 + 0.01 / (50 * PSI / 1e5)
    assert pneumatic_rolling_resistance(20 * PSI) == pytest.approx(f20, rel=1e-12)
    assert load_platform("p3at_pneumatic_20psi").tire_rolling_resistance == 0.0  # the terrains' reference tire
    assert load_platform("p3at_pneumatic_50psi").tire_rolling_resistance == pytest.approx(f50 - f20, abs=1e-5)
    a = math.sqrt(4 * (W / 0.05) * 0.095 / (math.pi * 5.52e6 / 0.75))
    f_solid = 2 * 0.2 / (3 * math.pi) * a / 0.095
    assert hysteresis_rolling_resistance(a, 0.095, 0.2) == pytest.approx(f_solid, rel=1e-12)
    assert load_platform("p3at_solid").tire_rolling_resistance == pytest.approx(f_solid - f20, abs=1e-4)


@pytest.mark.parametrize("patch", [0.0379, 0.0240, 0.00995])
def test_cornering_stiffness_of_the_janosi_law_is_mu_w_l_over_2_k_lat(patch):
    """At a small slip angle the lateral force per radian is mu mu_lat_ratio W l / (2 K_lat): the tire types'
    cornering stiffness differs through their patch length (the law bound per metre, ps = l as the testbed does)."""
    mu, ratio, K, k_lat_ratio, v = 0.8, 1.06, 0.004, 1.4, 0.4
    law = tire_law(True, ratio, K, k_lat_ratio, 1.0, 0.02, k_max=1e12)
    alpha = 1e-5
    _, f_lat, _ = law(0.0, v * alpha, v, v, W, mu, patch)
    assert -f_lat / alpha == pytest.approx(mu * ratio * W * patch / (2 * K * k_lat_ratio), rel=1e-4)


@pytest.mark.parametrize("janosi", [False, True], ids=["coulomb", "janosi"])
def test_friction_speed_decay_is_dugoffs_reduction_of_the_sliding_force(janosi):
    """In full sliding (patch saturated) the force magnitude is mu N / (1 + A_s |s|) (times Coulomb's smooth
    sign): Dugoff's mu_0 (1 - A_s V_s) to first order, computed here by hand.  (A_s = 0 leaves every run as before
    bit for bit: the reproduction's metrics.json is unchanged.)"""
    mu, n, a_s = 0.7, W, 2.5
    base = tire_law(janosi, 1.0, 1e-6, 1.0, 0.05, 0.02, k_max=1e12)
    decayed = tire_law(janosi, 1.0, 1e-6, 1.0, 0.05, 0.02, k_max=1e12, speed_decay=a_s)
    for s_lon, s_lat in ((0.8, 0.0), (0.3, -0.4), (0.05, 0.12)):
        s = math.hypot(s_lon, s_lat)
        f0 = base(s_lon, s_lat, 0.1, 0.1 + s_lon, n, mu)
        f1 = decayed(s_lon, s_lat, 0.1, 0.1 + s_lon, n, mu)
        assert math.hypot(*f1[:2]) == pytest.approx(math.hypot(*f0[:2]) / (1 + a_s * s), rel=1e-12)
        sat = 1.0 if janosi else s / math.sqrt(s * s + 0.02 ** 2)  # Janosi saturated; Coulomb's smooth sign
        assert math.hypot(*f1[:2]) == pytest.approx(sat * mu * n / (1 + a_s * s), rel=2e-3)
        assert f1[0] * s_lon <= 0 and f1[1] * s_lat <= 0  # still against the sliding
