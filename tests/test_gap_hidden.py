"""Blind tests of the gap workflow: measured data from the testbed with an effect hidden through
spec overrides (as ``--set``) that the nominal model does not have.

Test data differ from the development data the selection thresholds were chosen on
(``bench/gap/dev.py``: scenarios gap_dev_coulomb/gap_dev_janosi, seeds 0-4, magnitudes
``DEV_HIDDEN``): other scenarios (gap_test_coulomb: P3-AT 50 psi on Coulomb tile; gap_test_janosi:
P3-AT 20 psi on asphalt), seeds >= 100 and other magnitudes (several of opposite sign).

For every catalogue effect: the hidden effect is named first, every hidden parameter is fitted
within 20 % of its *change from the nominal value* (stricter than 20 % of the value itself; a
parameter the test leaves at nominal must stay within 20 % of the changed one's change), and the
RMS gap of the channel it affects most (largest residual/noise before) shrinks by >= 50 %.
"""
from __future__ import annotations

import math

import pytest

from bench.gap import find_gap
from bench.gap.catalogue import get
from bench.spec import load_scenario

COUL, JAN = "gap_test_coulomb", "gap_test_janosi"


def _mu(scn: str, scale: float) -> dict:
    t = load_scenario(scn).terrain
    return {"terrain.mu_sa": t.mu_sa * scale, "terrain.mu_op": t.mu_op * scale}


def _motor(scn: str):
    return load_scenario(scn).platform.motor


# effect, scenario, hidden overrides, seed, hidden parameter values (catalogue parameter names)
CASES = [
    ("rolling_resistance", JAN, {"terrain.rolling_resistance": 0.075}, 101, {"rolling_resistance": 0.075}),
    ("friction", COUL, _mu(COUL, 1.35), 102, {"mu_scale": 1.35}),
    ("shear_displacement", COUL, {"terrain.model": "janosi", "terrain.shear_modulus": 0.006}, 103,
     {"shear_modulus": 0.006}),
    ("wheel_radius", JAN, {"platform.wheel_radius_scale_r": 0.945}, 104, {"radius_scale_r": 0.945}),
    ("cg_offset", COUL, {"platform.cg_offset_x": -0.04, "platform.cg_offset_y": 0.03}, 105,
     {"cg_offset_x": -0.04, "cg_offset_y": 0.03}),
    ("payload", COUL, {"platform.payload": 5.0}, 106, {"payload": 5.0}),
    ("slope", JAN, {"terrain.slope": math.radians(-3.0)}, 107, {"slope_deg": -3.0}),
    ("motor_saturation", JAN, {"platform.motor.max_current": 2.2}, 108, {"max_current": 2.2}),
    ("actuator_delay", COUL, {"platform.actuator_delay": 0.045}, 109, {"delay": 0.045}),
    ("powertrain_lag", COUL, {"platform.powertrain_tau_l": 0.12, "platform.powertrain_tau_r": 0.18}, 114,
     {"tau_l": 0.12, "tau_r": 0.18}),
    ("command_map", JAN, {"platform.command_gain_sum": 0.92, "platform.command_gain_diff": 1.25}, 112,
     {"gain_sum": 0.92, "gain_diff": 1.25}),
    ("command_limit", COUL, {"platform.command_limit_mean": 3.6, "platform.command_limit_diff": 1.3}, 113,
     {"limit_mean": 3.6, "limit_diff": 1.3}),
    ("wheel_speed_limit", COUL, {"platform.wheel_speed_limit": 4.2}, 115, {"limit": 4.2}),
    ("command_accel", COUL, {"platform.command_accel_mean": 3.0, "platform.command_accel_diff": 2.0}, 116,
     {"accel_mean": 3.0, "accel_diff": 2.0}),
    ("lateral_friction", COUL, {"terrain.mu_lat_ratio": 1.3}, 117, {"mu_lat_ratio": 1.3}),
    ("speed_slip", JAN, {"terrain.friction_speed_decay": 1.2}, 125, {"friction_speed_decay": 1.2}),
    ("motor_torque", JAN, {"platform.motor.stall_torque": _motor(JAN).stall_torque * 0.6,
                           "platform.motor.max_current": _motor(JAN).max_current * 0.6}, 118, {"torque_scale": 0.6}),
    ("encoder_scale", JAN, {"platform.sensors.encoder.scale_error_l": -0.04}, 110, {"scale_error_l": -0.04}),
    ("gyro_bias", COUL, {"platform.sensors.imu.gyro_bias_z": -0.015}, 111, {"gyro_bias_z": -0.015}),
    ("encoder_latency", JAN, {"platform.sensors.encoder.latency": 0.12}, 119, {"latency": 0.12}),
    ("gyro_scale", COUL, {"platform.sensors.imu.gyro_scale_z": -1.0}, 123, {"gyro_scale_z": -1.0}),
    ("imu_mounting", JAN, {"platform.sensors.imu.yaw_misalignment": 0.12, "platform.sensors.imu.lever_x": -0.25},
     124, {"yaw_misalignment": 0.12, "lever_x": -0.25}),
]
DEFAULT_RUN = {"rolling_resistance", "shear_displacement", "wheel_radius", "motor_saturation", "encoder_scale",
               "command_limit", "powertrain_lag", "wheel_speed_limit", "command_accel", "lateral_friction",
               "motor_torque", "encoder_latency", "gyro_scale", "imu_mounting", "speed_slip"}


def _measured(sim, scenario: str, seed: int, hidden: dict):
    return sim(scenario, seed, **{k.replace(".", "__"): v for k, v in hidden.items()})


def check_hidden(res, effect: str, scenario: str, hidden_values: dict) -> None:
    assert res.verdict_kind == "missing_effect", res.verdict
    assert res.named[0] == effect, res.verdict
    e = res.effects[0]
    nominal = dict(zip((p.name for p in get(effect).params), get(effect).neutral(load_scenario(scenario)) or
                       (None,) * get(effect).n_params))
    changes = []
    for name, hv in hidden_values.items():
        nv = nominal.get(name)
        change = abs(hv - nv) if nv is not None else abs(hv)
        changes.append(change)
        assert e["parameters"][name] == pytest.approx(hv, abs=0.2 * change), (name, e["parameters"], hv)
        # the reported standard error covers the hidden value and resolves the change
        se = e["uncertainty"][name]
        assert abs(e["parameters"][name] - hv) <= 3.0 * se < 0.6 * change, (name, e["parameters"][name], hv, se)
    for name, fv in e["parameters"].items():
        if name not in hidden_values and nominal.get(name) is not None:
            assert fv == pytest.approx(nominal[name], abs=0.2 * min(changes)), (name, fv)
    ch = res.most_affected_channel()
    assert res.gap_after[ch]["rms"] <= 0.5 * res.gap_before[ch]["rms"], (ch, res.gap_before[ch], res.gap_after[ch])


@pytest.mark.parametrize(
    "effect,scenario,hidden,seed,values",
    [pytest.param(*c, id=c[0], marks=() if c[0] in DEFAULT_RUN else pytest.mark.slow) for c in CASES],
)
def test_hidden_effect_is_named_fitted_and_closes_the_gap(sim, effect, scenario, hidden, seed, values):
    measured = _measured(sim, scenario, seed, hidden)
    res = find_gap(measured, scenario)
    check_hidden(res, effect, scenario, values)


def _null_false_names(sim, seeds) -> tuple[int, list[str]]:
    false, verdicts = 0, []
    for i, seed in enumerate(seeds):
        scn = COUL if i % 2 == 0 else JAN
        res = find_gap(sim(scn, seed), scn)
        false += bool(res.effects)
        verdicts.append(res.verdict)
    return false, verdicts


def test_null_case_names_no_effect_quick(sim):
    false, verdicts = _null_false_names(sim, range(200, 204))
    assert false == 0, verdicts
    assert all(v == "no significant missing effect" for v in verdicts), verdicts


@pytest.mark.slow
def test_null_case_at_most_one_false_name_over_ten_seeds(sim):
    false, verdicts = _null_false_names(sim, range(200, 210))
    assert false <= 1, verdicts


def test_two_hidden_effects_are_both_named(sim):
    hidden = {"platform.cg_offset_x": 0.04, "terrain.rolling_resistance": 0.06}
    res = find_gap(_measured(sim, JAN, 120, hidden), JAN)
    assert res.verdict_kind == "missing_effect", res.verdict
    assert set(res.named) == {"cg_offset", "rolling_resistance"}, res.verdict
    params = {k: v for e in res.effects for k, v in e["parameters"].items()}
    assert params["cg_offset_x"] == pytest.approx(0.04, rel=0.2)
    assert params["rolling_resistance"] == pytest.approx(0.06, abs=0.2 * (0.06 - load_scenario(JAN).terrain.rolling_resistance))


ENC = "platform.sensors.encoder."


@pytest.mark.parametrize("scenario,seed,rate", [(COUL, 121, 100.0), (JAN, 122, 20.0)], ids=["100Hz", "20Hz"])
def test_hidden_encoder_latency_is_named_first_and_fitted_within_its_standard_error(sim, scenario, seed, rate):
    """0.2 s of wheel-speed latency (at the scenario's 100 Hz encoder, and at 20 Hz as the DRIVE Husky's): named
    first, alone, and the fitted latency within one standard error of 0.2 s."""
    nominal = load_scenario(scenario, {ENC + "rate_hz": rate})
    res = find_gap(_measured(sim, scenario, seed, {ENC + "latency": 0.2, ENC + "rate_hz": rate}), nominal)
    assert res.named == ["encoder_latency"], res.verdict
    e = res.effects[0]
    assert abs(e["parameters"]["latency"] - 0.2) <= e["uncertainty"]["latency"] < 0.02, e


def test_actuator_delay_and_encoder_latency_are_told_apart(sim):
    """A 0.2 s actuator delay (the robot moves late: gyro, pose and wheels) with 0.15 s more latency of the
    wheel-speed samples (the wheels are reported later still): both named, each within one standard error."""
    res = find_gap(_measured(sim, COUL, 123, {"platform.actuator_delay": 0.2, ENC + "latency": 0.15}), COUL)
    assert set(res.named) == {"actuator_delay", "encoder_latency"}, res.verdict
    p = {k: (v, e["uncertainty"][k]) for e in res.effects for k, v in e["parameters"].items()}
    for name, truth in (("delay", 0.2), ("latency", 0.15)):
        assert abs(p[name][0] - truth) <= p[name][1] < 0.5 * truth, (name, p[name])


def test_effect_outside_the_catalogue_ends_in_unexplained_residual(sim):
    # FrictionPatch(x_min, x_max, y_min, y_max, mu_scale, t_period): friction halves and recovers
    # with a 1.8 s period on 1.5 m < x < 3 m
    patch = ((1.5, 3.0, -1e3, 1e3, 0.5, 1.8),)
    measured = sim(COUL, 130, terrain__friction_patches=patch)
    res = find_gap(measured, COUL)
    assert res.verdict_kind == "unexplained_residual", res.verdict
    assert res.effects == []  # no wrong name
    assert res.verdict.startswith("unexplained residual:") and "largest in regime" in res.verdict


def test_a_limit_that_never_binds_is_reported_not_identified(sim):
    """Only the turn limit is hidden (the mean speed stays far below any mean limit): the fitted
    limit_mean has no effect on the residuals (zero Jacobian column), so its standard error is
    infinite ("not identified"), while limit_diff is fitted with a finite one."""
    from bench.gap.report import uncertainty_text

    measured = _measured(sim, COUL, 114, {"platform.command_limit_diff": 1.2})
    res = find_gap(measured, COUL, catalogue=[get("command_limit")])
    e = (res.effects + res.partial)[0]
    assert e["name"] == "command_limit" and e["parameters"]["limit_diff"] == pytest.approx(1.2, rel=0.05)
    assert math.isfinite(e["uncertainty"]["limit_diff"])
    assert e["parameters"]["limit_mean"] > 5.2  # above every commanded mean of the scenario (5.12 rad/s)
    assert math.isinf(e["uncertainty"]["limit_mean"])
    assert uncertainty_text("command_limit", "limit_mean", e["parameters"]["limit_mean"],
                            e["uncertainty"]["limit_mean"]).startswith("not identified")


def _worked_example_z(seeds) -> list[float]:
    """(fitted - hidden) / std. error of both radius scales of the worked example (gap_example, right tyre
    under-inflated) on ``seeds``."""
    from bench.gap import WORKED_EXAMPLE as ex
    from bench.sim import simulate

    # the left scale is the platform's own (1 since issue 31: the tire's loaded radius is physics, not a scale)
    truth = {"radius_scale_l": 1.0, "radius_scale_r": ex["hidden"]["platform.wheel_radius_scale_r"]}
    assert load_scenario(ex["scenario"]).platform.wheel_radius_scale_l == truth["radius_scale_l"]
    z = []
    for seed in seeds:
        res = find_gap(simulate(load_scenario(ex["scenario"], ex["hidden"]), seed), ex["scenario"])
        assert res.named == ["wheel_radius"], (seed, res.verdict)
        e = res.effects[0]
        z += [(e["parameters"][k] - v) / e["uncertainty"][k] for k, v in truth.items()]
    return z


def test_worked_example_standard_error_covers_the_hidden_radius():
    """The published worked example (seed 7): both fitted radius scales within 2 std. errors of the hidden
    ones (the white-residual standard error alone put them 35 and 32 std. errors away)."""
    from bench.gap import WORKED_EXAMPLE as ex

    z = _worked_example_z([ex["seed"]])
    assert max(abs(v) for v in z) <= 2.0, z


@pytest.mark.slow
def test_standard_errors_cover_the_truth_over_seeds():
    """20 seeds of the worked example other than those looked at while building the uncertainty (1-20): every
    fitted radius scale within 3 std. errors of the hidden one, >= 90 % within 2."""
    z = _worked_example_z(range(30, 50))
    assert max(abs(v) for v in z) <= 3.0, z
    assert sum(abs(v) <= 2.0 for v in z) >= 0.9 * len(z), z
