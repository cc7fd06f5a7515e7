"""Blind tests of terrain.friction_speed_decay (Dugoff friction reduction mu/(1 + A_s |s|)) and of the gap
workflow's "speed_slip" effect, written by a helper from the public spec only (not the implementation), with
scenarios, seeds (>= 700) and magnitudes of its own.

They found one defect: a uniform friction scale of 0.8 hidden on gap_test_coulomb (seed 721) and gap_test_janosi
(seed 727) was named "speed_slip" (A_s 3.06 and 1.70), the friction change not even refined: the screening ranked
candidates by a linear prediction of their cost, which put friction (predicted 363) behind speed_slip (129).  Each
linearised estimate is now simulated as well (bench.gap.screening.simulate_estimates: friction's costs 36) and the best
candidates by either cost are refined.  Ten cases run by default (the two that failed among them), the rest with
``-m slow``."""
from __future__ import annotations

import numpy as np
import pytest

from bench.gap import find_gap

KEY = "terrain.friction_speed_decay"
PAR = "friction_speed_decay"


def _ov(**kw):
    return tuple(sorted((k.replace("__", "."), v) for k, v in kw.items()))


@pytest.fixture
def run_of(sim):
    """run_of(scenario, seed, ((dotted field, value), ...)) -> the simulated Run (the session's cached ``sim``)."""
    return lambda scenario, seed, over: sim(scenario, seed, **{k.replace(".", "__"): v for k, v in over})


def _report(res):
    ch = res.most_affected_channel()
    eff = [(e["name"], e.get("parameters"), e.get("uncertainty")) for e in res.effects]
    return (f"verdict_kind={res.verdict_kind} named={res.named} effects={eff} ch={ch} "
            f"rms_before={res.gap_before[ch]['rms']:.4g} rms_after={res.gap_after[ch]['rms']:.4g} "
            f"verdict={res.verdict!r}")


# --------------------------------------------------------------------------------------------------------------
# gap workflow: hidden speed_slip is named and fitted
# --------------------------------------------------------------------------------------------------------------
SLOW = pytest.mark.slow
HIDDEN = [
    ("gap_test_coulomb", 0.3, 701),
    pytest.param("gap_test_coulomb", 4.0, 702, marks=SLOW),
    pytest.param("gap_test_janosi", 0.3, 703, marks=SLOW),
    pytest.param("gap_test_janosi", 1.0, 704, marks=SLOW),
    pytest.param("gap_test_janosi", 4.0, 705, marks=SLOW),
    pytest.param("gap_blind_turns", 1.0, 706, marks=SLOW),
    pytest.param("gap_blind_turns", 10.0, 707, marks=SLOW),
    # 40 s patrol, solid tires: at 0.5 s/m every channel is already at the noise floor before the fit (tau/i at
    # 0.55 sigma, imu_ax ~1.02 sigma is "most affected"), so the >= 50 % shrink cannot be asked there; 2 s/m is used
    pytest.param("gap_blind_patrol", 2.0, 708, marks=SLOW),
]


@pytest.mark.parametrize("scenario,a_s,seed", HIDDEN)
def test_hidden_speed_slip_is_named_and_fitted(run_of, scenario, a_s, seed):
    measured = run_of(scenario, seed, ((KEY, a_s),))
    res = find_gap(measured, scenario)
    info = _report(res)
    print(scenario, a_s, seed, info)
    assert res.verdict_kind == "missing_effect", info
    assert res.named and res.named[0] == "speed_slip", info
    eff = res.effects[0]
    fitted = eff["parameters"][PAR]
    se = eff["uncertainty"][PAR]
    assert np.isfinite(fitted) and np.isfinite(se) and se > 0, info
    assert abs(fitted - a_s) <= 0.2 * a_s, info
    assert abs(fitted - a_s) <= 3 * se, info  # the standard error covers the truth within 3 sigma
    ch = res.most_affected_channel()
    before, after = res.gap_before[ch]["rms"], res.gap_after[ch]["rms"]
    assert after <= 0.5 * before, info


@pytest.mark.slow
def test_neutral_value_is_the_scenarios_terrain_value(run_of):
    """Nominal model with A_s = 0.5 (override), measured data with A_s = 2: speed_slip named, the fit is the
    measured value, and the effect's nominal is the scenario's 0.5."""
    scenario, seed = "gap_test_janosi", 730
    measured = run_of(scenario, seed, ((KEY, 2.0),))
    res = find_gap(measured, scenario, overrides={KEY: 0.5})
    info = _report(res)
    print(info)
    assert res.named and res.named[0] == "speed_slip", info
    eff = res.effects[0]
    assert eff["nominal"][PAR] == pytest.approx(0.5), eff["nominal"]
    assert abs(eff["parameters"][PAR] - 2.0) <= 0.2 * 2.0, info


@pytest.mark.slow
def test_matching_nonzero_nominal_is_clean(run_of):
    """Nominal and measured both at A_s = 1.0: nothing missing."""
    scenario, seed = "gap_test_coulomb", 731
    measured = run_of(scenario, seed, ((KEY, 1.0),))
    res = find_gap(measured, scenario, overrides={KEY: 1.0})
    info = _report(res)
    print(info)
    assert res.effects == [], info
    assert res.verdict_kind == "no_significant_effect", info


# --------------------------------------------------------------------------------------------------------------
# gap workflow: clean data, and another effect hidden
# --------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scenario,seed", [("gap_test_coulomb", 711), pytest.param("gap_test_janosi", 712, marks=SLOW),
                                           pytest.param("gap_blind_turns", 713, marks=SLOW)])
def test_clean_data_names_nothing(run_of, scenario, seed):
    res = find_gap(run_of(scenario, seed, ()), scenario)
    info = _report(res)
    print(scenario, seed, info)
    assert res.effects == [], info
    assert "speed_slip" not in res.named, info
    assert res.verdict_kind == "no_significant_effect", info
    assert "no significant missing effect" in res.verdict.lower(), info


def _terrain_mu(scenario):
    from bench.spec import load_scenario

    t = load_scenario(scenario, {}).terrain
    return t.mu_sa, t.mu_op


@pytest.mark.parametrize("scenario,factor,seed", [("gap_test_coulomb", 0.8, 721),  # the two that failed before
                                                  pytest.param("gap_test_coulomb", 1.2, 726, marks=SLOW),
                                                  ("gap_test_janosi", 0.8, 727),
                                                  pytest.param("gap_test_janosi", 1.25, 722, marks=SLOW),
                                                  pytest.param("gap_blind_turns", 0.7, 723, marks=SLOW)])
def test_uniform_friction_change_is_not_speed_slip(run_of, scenario, factor, seed):
    mu_sa, mu_op = _terrain_mu(scenario)
    measured = run_of(scenario, seed, _ov(terrain__mu_sa=mu_sa * factor, terrain__mu_op=mu_op * factor))
    res = find_gap(measured, scenario)
    info = _report(res)
    print(scenario, factor, seed, info)
    assert res.named and res.named[0] == "friction", info
    assert "speed_slip" not in res.named, info


# --------------------------------------------------------------------------------------------------------------
# physics, independent of the gap workflow
# --------------------------------------------------------------------------------------------------------------
def test_zero_decay_is_bit_identical(run_of):
    for scenario in ("gap_test_coulomb", "gap_test_janosi"):
        a = run_of(scenario, 740, ())
        b = run_of(scenario, 740, ((KEY, 0.0),))
        assert list(a.data.columns) == list(b.data.columns)
        for c in a.data.columns:
            np.testing.assert_array_equal(a.data[c].to_numpy(), b.data[c].to_numpy(), err_msg=f"{scenario}:{c}")


def test_range_is_validated():
    from bench.spec import load_scenario

    assert load_scenario("gap_test_janosi", {KEY: 20.0}).terrain.friction_speed_decay == 20.0
    assert load_scenario("gap_test_janosi", {KEY: 0.0}).terrain.friction_speed_decay == 0.0
    for bad in (-0.1, 20.5):
        with pytest.raises(Exception):
            load_scenario("gap_test_janosi", {KEY: bad})


def test_nonzero_decay_changes_the_run(run_of):
    """A_s > 0 must change a run with turning (the turns slide)."""
    a = run_of("gap_test_janosi", 741, ())
    b = run_of("gap_test_janosi", 741, ((KEY, 1.0),))
    assert np.max(np.abs(a["truth_yaw"] - b["truth_yaw"])) > 1e-3 or \
        np.max(np.abs(a["tau_l"] - b["tau_l"])) > 1e-2


def test_straight_low_speed_nearly_unchanged(run_of):
    """Straight at 0.2 m/s: hardly any sliding, so mu/(1 + A_s |s|) ~ mu and the run barely moves, even at 4 s/m."""
    a = run_of("straight_0p2_vinyl", 742, ())
    b = run_of("straight_0p2_vinyl", 742, ((KEY, 4.0),))
    d_end = np.hypot(a["truth_x"][-1] - b["truth_x"][-1], a["truth_y"][-1] - b["truth_y"][-1])
    travel = np.hypot(a["truth_x"][-1] - a["truth_x"][0], a["truth_y"][-1] - a["truth_y"][0])
    print("straight end difference", d_end, "of", travel)
    assert d_end < 1e-3 * travel
    sel = a.t > 2.0
    ta, tb = np.nanmean(np.abs(a["tau_l"][sel])), np.nanmean(np.abs(b["tau_l"][sel]))
    assert abs(ta - tb) < 0.02 * ta


@pytest.mark.parametrize("terrain_model", ["janosi", "coulomb"])
def test_spin_on_the_spot_needs_less_torque_with_larger_decay(run_of, terrain_model):
    """Pure rotation: every contact slides (laterally at ~ w * half wheelbase), so each friction force is divided by
    1 + A_s |s| > 1; with speed-controlled wheels the drive torque the motors supply in the steady spin must
    fall strictly and monotonically with A_s, and clearly (> 5 %) at 4 s/m."""
    scn = "mandow_rotation_asphalt_solid"
    means = []
    for a_s in (0.0, 1.0, 4.0):
        r = run_of(scn, 743, _ov(terrain__model=terrain_model, terrain__friction_speed_decay=a_s))
        sel = r.t > 3.0
        tau = 0.5 * (np.nanmean(np.abs(r["tau_l"][sel])) + np.nanmean(np.abs(r["tau_r"][sel])))
        means.append(tau)
        assert abs(np.nanmean(r["truth_wz"][sel])) > 0.3  # it does spin
    print(terrain_model, "mean |tau| at A_s = 0, 1, 4:", means)
    assert means[0] > means[1] > means[2]
    assert means[2] < 0.95 * means[0]
