"""Deformable soil (bench/sim/soil.py) against independent expectations: the exact pressure integral over a
rigid wheel's contact arc (Bekker's closed form is its small-sinkage approximation), the rut-pressing work,
the Janosi-Hanamoto limit in full slip, and the simulated straight run's torque balance."""
import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.special import beta

from bench.sim import simulate
from bench.sim.soil import (compaction_resistance, janosi_shear, pressure, sinkage, soil_constants,
                            traction_limit)
from bench.sim.testbed import GRAVITY
from bench.sim.tire import janosi_fraction, tire_contact, tire_law
from bench.spec import load_scenario, load_terrain

SAND = load_terrain("sand")  # Wong Table 2.3 dry sand
LOAM = load_terrain("dirt")  # Wong Table 2.3 sandy loam, 15 %
R, B = 0.086, 0.095


def _soil(t):
    return t.soil_n, t.soil_k_c, t.soil_k_phi


@pytest.mark.parametrize("terr", [SAND, LOAM])
@pytest.mark.parametrize("load", [5.0, 25.0])
def test_sinkage_balances_the_pressure_over_the_contact_arc(terr, load):
    """W = b r int p(r (cos t - cos t0)) cos t dt over the arc.  Bekker's closed form replaces the exact small-sinkage
    integral b k sqrt(r/2) z^(n+1/2) B(n+1, 1/2) by b k sqrt(2r) z^(n+1/2) (3-n)/3, so the arc's load is
    3 B(n+1, 1/2) / (2 (3 - n)) times W (1.024 for dry sand, 0.953 for sandy loam), within 3 % at z/r < 0.15."""
    n, kc, kphi = _soil(terr)
    z = sinkage(load, R, B, n, kc, kphi)
    t0 = math.acos(1.0 - z / R)
    w = B * R * quad(lambda t: pressure(R * (math.cos(t) - math.cos(t0)), B, n, kc, kphi) * math.cos(t), 0.0, t0)[0]
    assert z / R < 0.15
    ratio = 3.0 * beta(n + 1.0, 0.5) / (2.0 * (3.0 - n))
    assert w == pytest.approx(load * ratio, rel=0.03)
    assert abs(ratio - 1.0) < 0.05  # the closed form is within 5 % of the arc's load for these soils


@pytest.mark.parametrize("terr", [SAND, LOAM])
def test_compaction_resistance_is_the_rut_pressing_work(terr):
    """R_c = work per unit length of pressing a rut of width b to depth z: b int_0^z p dz."""
    n, kc, kphi = _soil(terr)
    z = sinkage(25.0, R, B, n, kc, kphi)
    work = B * quad(lambda s: pressure(s, B, n, kc, kphi), 0.0, z)[0]
    assert compaction_resistance(z, B, n, kc, kphi) == pytest.approx(work, rel=1e-9)


def test_sinkage_grows_with_load_as_bekker_power():
    n, kc, kphi = _soil(SAND)
    z1, z2 = sinkage(10.0, R, B, n, kc, kphi), sinkage(20.0, R, B, n, kc, kphi)
    assert z2 / z1 == pytest.approx(2.0 ** (2.0 / (2.0 * n + 1.0)), rel=1e-12)


def test_janosi_shear_reaches_soil_strength_in_full_slip():
    p = pressure(0.01, B, *_soil(SAND))
    tau_max = SAND.soil_cohesion + p * math.tan(SAND.soil_friction_angle)
    assert janosi_shear(10.0, p, SAND.soil_cohesion, SAND.soil_friction_angle, 0.01) == pytest.approx(tau_max, rel=1e-12)
    assert janosi_shear(0.01, p, SAND.soil_cohesion, SAND.soil_friction_angle, 0.01) == pytest.approx(
        tau_max * (1 - math.exp(-1)), rel=1e-12)


@pytest.mark.parametrize("terr", [SAND, LOAM])
def test_tire_law_on_soil_saturates_at_c_a_plus_w_tan_phi(terr):
    """The testbed's per-step friction on soil (mu = tan phi + c A / W, as testbed.py and _kernel.c bind it)
    makes the Janosi tire law's full-slip force c b sqrt(2 r z) + W tan phi."""
    n, kc, kphi = _soil(terr)
    z_coef, z_exp, rc_coef, n1, tan_phi, ca_coef = soil_constants(R, B, n, kc, kphi, terr.soil_cohesion,
                                                                  terr.soil_friction_angle)
    load = 25.0
    z = z_coef * load ** z_exp
    assert z == pytest.approx(sinkage(load, R, B, n, kc, kphi), rel=1e-12)
    assert rc_coef * z ** n1 == pytest.approx(compaction_resistance(z, B, n, kc, kphi), rel=1e-12)
    mu = tan_phi + ca_coef * math.sqrt(z) / load
    patch = 0.05
    law = tire_law(True, 1.0, terr.shear_modulus, 1.0, patch, terr.slip_velocity_eps, 1e12)
    f_lon, f_lat, _ = law(-5.0, 0.0, 5.0, 0.0, load, mu)  # wheel spinning in place: slip 1, j_max = patch
    expect = traction_limit(load, R, B, n, kc, kphi, terr.soil_cohesion, terr.soil_friction_angle)
    assert abs(f_lat) < 1e-12
    # Janosi over the patch, j uniform in [0, patch]: the average of 1 - exp(-j/K) times the full-slip strength
    assert f_lon == pytest.approx(expect * janosi_fraction(patch, terr.shear_modulus), rel=1e-12)


def test_rigid_terrains_leave_the_soil_off():
    for name in ("vinyl", "tile", "concrete", "asphalt", "smooth_concrete"):
        assert load_terrain(name).soil_model == "rigid"


def test_straight_on_sand_torque_balances_compaction():
    """Constant speed on the flat: tau_l + tau_r = r sum_i R_c(W_i), W_i the simulated loads; the terrain's
    rigid-ground rolling_resistance takes no part (the compaction resistance is the ground's deformation)."""
    base = load_scenario("straight_0p2_vinyl")
    scn = dataclasses.replace(base, terrain=dataclasses.replace(SAND, slope=0.0))
    d = simulate(scn, 0).data
    d = d[d["t"] >= 3.0]
    plat, terr = scn.platform, scn.terrain
    r = plat.wheel_radius * plat.wheel_radius_scale_l
    rc = sum(compaction_resistance(sinkage(w, plat.wheel_radius, plat.wheel_width, *_soil(terr)), plat.wheel_width,
                                   *_soil(terr))
             for w in (np.nanmean(d[c]) for c in ("truth_n_fl", "truth_n_rl", "truth_n_fr", "truth_n_rr")))
    expect = r * rc
    got = float(np.nanmean(d["tau_l"]) + np.nanmean(d["tau_r"]))
    assert got == pytest.approx(expect, rel=0.02)
    # and not with the rigid-ground term added (it would be 20 % or more above the balance)
    assert r * (terr.rolling_resistance * plat.total_mass * GRAVITY + rc) > 1.2 * got


def test_straight_on_sand_slips_until_the_shear_carries_the_compaction_resistance():
    """The compaction resistance is the horizontal part of the rim's normal pressure: a force against the travel,
    not a torque about the axle (Wong Ch. 2: drawbar pull DP = F - R_c).  At constant speed DP = 0, so each
    wheel's Janosi patch force at its slip i carries R_c of its load: mu W [1 - (1 - e^-z)/z] = R_c(W),
    z = i l / K (l the tire's patch at W, mu = tan phi + c A / W).  The measured slip 1 - v / (r_loaded w) is that
    i within 3 %; with R_c booked as a wheel torque the wheels would roll without slip."""
    base = load_scenario("straight_0p2_vinyl")
    scn = dataclasses.replace(base, terrain=dataclasses.replace(SAND, slope=0.0))
    d = simulate(scn, 0).data
    d = d[d["t"] >= 3.0]
    plat, terr = scn.platform, scn.terrain
    p_coef, q_coef = tire_contact(plat.wheel_radius, plat.wheel_width, plat.tire_pressure, plat.tire_modulus)
    expect, radius = [], []
    for w in (float(np.nanmean(d[c])) for c in ("truth_n_fl", "truth_n_rl", "truth_n_fr", "truth_n_rr")):
        z = sinkage(w, plat.wheel_radius, plat.wheel_width, *_soil(terr))
        r_c = compaction_resistance(z, plat.wheel_width, *_soil(terr))
        mu = math.tan(terr.soil_friction_angle) + terr.soil_cohesion * plat.wheel_width * math.sqrt(
            2.0 * plat.wheel_radius * z) / w
        zz = brentq(lambda x: mu * w * (1.0 - (1.0 - math.exp(-x)) / x) - r_c, 1e-9, 100.0)
        expect.append(zz * terr.shear_modulus / (p_coef * math.sqrt(w)))
        radius.append(plat.wheel_radius * (1.0 - q_coef * w))
    w_side = 0.5 * (np.mean(d["truth_wl"]) + np.mean(d["truth_wr"]))
    measured = 1.0 - float(np.mean(d["truth_vx"])) / (float(np.mean(radius)) * w_side)
    assert measured == pytest.approx(float(np.mean(expect)), rel=0.03)
    assert measured > 0.1  # Wong's self-propelled slip on loose sand is far from 0
