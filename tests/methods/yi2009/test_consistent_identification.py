"""The consistent configuration (not Yi's): the noise identified on calibration runs,
methods.yi2009.consistent.identification.identify_yi_noise.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from methods.yi2009.consistent.identification import identify_yi_noise
from methods.yi2009.consistent.plugin import ekf_v1_consistent, ekf_v2_consistent, ekf_v3_consistent
from methods.yi2009.consistent.sensors import static_imu_noise
from methods.yi2009.ekf import EkfParams, align_inputs
from methods.yi2009.s_gamma import SGamma
from tests.methods.yi2009.synthetic import CAL_COMBOS_RPM, G, RPM_TO_RADS, R_WHEEL, TESTBED, synthetic_run


def test_static_imu_noise_and_scheme1_bias_identified_on_synthetic_calibration_runs(consistent_runs):
    """identify_yi_noise on steady turns with a known net slip lam0 (scheme 1 fuses v_x = r (w_L + w_R)/2 without
    slip, so its error is lam0 times the tread speed, closed form from the wheel-speed profile): the IMU white noise
    from the 1 s rest (minus the 0.25 s guard) equals the generator's 0.05 m/s^2 / 0.005 rad/s; the Gauss-Markov sigma of the v_x row
    equals the RMS of that bias (mean kept) and its correlation time is long (a bias); levelling precision is
    accel_noise / (g sqrt(level_samples))."""
    runs = [r.without_truth() for r in consistent_runs]
    sa, sg, n = static_imu_noise(runs)
    assert sa == pytest.approx(TESTBED.acc_noise, rel=0.1) and sg == pytest.approx(TESTBED.gyr_noise, rel=0.1)
    assert 0.6 * len(runs) * TESTBED.t_rest * TESTBED.rate_hz <= n <= len(runs) * TESTBED.t_rest * TESTBED.rate_hz
    params, gm_x, gm_y, _, _, info = identify_yi_noise(runs, ekf_v1_consistent(traction_slip=False), max_iterations=1)
    assert gm_y is None and (params.accel_noise, params.gyro_noise) == (sa, sg)
    assert params.p0_rollpitch == pytest.approx(sa / (G * math.sqrt(EkfParams().level_samples)), rel=1e-12)
    sq, n = 0.0, 0
    for i, run in zip((0, 3, 6, 9), consistent_runs):
        lam0 = 0.03 if i % 2 == 0 else 0.08
        wl, wr = CAL_COMBOS_RPM[i]
        tm = run.t[(run.t >= run.t[0] + 1.0)] - TESTBED.t_rest  # settle 1 s, as identify_yi_noise
        tread = R_WHEEL * RPM_TO_RADS * 0.5 * (wl + wr) * np.clip(tm, 0.0, 1.0)  # 1 s ramp, then steady
        sq += float(np.sum((lam0 * tread) ** 2))
        n += tm.size
    assert gm_x.sigma == pytest.approx(math.sqrt(sq / n), rel=0.15)
    assert gm_x.tau > 20.0
    assert info["vx"] == dataclasses.asdict(gm_x)


def _steady_turns_with_half_s():
    """Three steady turns (after a 1 s ramp) whose true S is 0.2 m at every gamma (eq. (41) with a2 = 0), the S(gamma)
    they are identified with (0.1 m) and the RMS of the v_y row's error (S_true - S_used) x yaw rate after the first
    second (closed form)."""
    s_true = (0.02, 0.0, 0.1)  # S = 0.2 m at every gamma
    runs, sq, n = [], 0.0, 0
    for i, (wl, wr) in enumerate(((80, 40), (40, 80), (90, 30))):
        sens = dataclasses.replace(TESTBED, lam0=0.03)
        run = synthetic_run(f"vy{i}", 300 + i, sens, knots_rpm=[(0, 0, 0), (1, wl, wr), (9, wl, wr)], s_model=s_true)
        tm = run.t[run.t >= run.t[0] + 1.0] - TESTBED.t_rest
        wz = np.interp(tm, [0, 1, 9], [0, 1, 1]) * run["truth_wz"][-1]
        sq += float(np.sum(((0.2 - 0.1) * wz) ** 2))
        n += tm.size
        runs.append(run.without_truth())
    return runs, SGamma(0.01, 0.0, 0.1), math.sqrt(sq / n)


def test_scheme3_icr_correction_identified_from_a_wrong_s_gamma():
    """The steady turns of :func:`_steady_turns_with_half_s`: the v_y row's error is (S_true - S_used) w_z = 0.1 m x
    w_z (closed form), so the S correction is c_0 = 0.1 m with no speed term (c_1 v |w_z| below 1 cm at these
    turns; c_0 within 15 %: the fit sees the vision reference's derivative, which lags in the 1 s ramps), the
    Gauss-Markov state identified after it carries less than a fifth of the uncorrected error's RMS, and the row's
    white floor is the gyro noise through the corrected row's gain, S + c_0 + 2 c_1 v |w_z| ~ 0.2 m.  Calibrated
    and run on a further turn of the same world, the plugin's lateral velocity error is below a third of the
    uncorrected configuration's, it reports the correction, and its x_icr column is the S the row uses (0.2 m);
    schemes 1-2 get no correction."""
    runs, used, rms_error = _steady_turns_with_half_s()
    base = ekf_v3_consistent(s_gamma=used, traction_slip=False, refit_s_gamma=False)
    params, _, gm_y, _, icr, info = identify_yi_noise(runs, base, max_iterations=2)
    v_wz = 0.0
    for run in runs:
        _, _, gyr, enc = align_inputs(run)
        v_wz = max(v_wz, float(np.max(0.5 * R_WHEEL * (enc[:, 0] + enc[:, 1]) * np.abs(gyr[:, 2]))))
    assert icr.c_0 == pytest.approx(0.1, rel=0.15) and abs(icr.c_1) * v_wz < 0.01
    assert gm_y.sigma < 0.2 * rms_error and info["icr"]["rms_after"] < 0.2 * info["icr"]["rms_before"]
    assert info["vy_white_floor"] == pytest.approx(0.2 * params.gyro_noise, rel=0.15)
    model, plain = base.calibrate(runs), dataclasses.replace(base, icr_correction=False).calibrate(runs)
    sens = dataclasses.replace(TESTBED, lam0=0.03)
    run = synthetic_run("vy9", 309, sens, knots_rpm=[(0, 0, 0), (1, 85, 35), (9, 85, 35)], s_model=(0.02, 0.0, 0.1))

    def vy_rms(est):
        late = est["t"] >= est["t"][0] + 2.0
        return float(np.sqrt(np.mean((est["vy"][late] - np.interp(est["t"][late], run.t, run["truth_vy"])) ** 2)))

    est = model.estimate(run.without_truth())
    assert vy_rms(est) < vy_rms(plain.estimate(run.without_truth())) / 3
    assert est.info["icr"] == dataclasses.asdict(model.icr)
    late = est["t"] >= est["t"][0] + 2.0
    assert np.median(est["x_icr"][late]) == pytest.approx(0.2, rel=0.15)
    assert ekf_v2_consistent(traction_slip=False).calibrate(runs).icr is None


def test_scheme3_vy_gauss_markov_identified_from_a_wrong_s_gamma():
    """Scheme 3 on the steady turns of :func:`_steady_turns_with_half_s` without the S correction: the v_y row's
    error is (S_true - S_used) x yaw rate, constant on each turn after the ramp (closed form).  With a constant
    sigma (``vy_per_yaw_rate`` False) the Gauss-Markov sigma is the RMS of that bias (mean kept); per yaw rate (the
    default) it is the S error itself, 0.1 m per rad/s; tau is long either way."""
    runs, used, rms_error = _steady_turns_with_half_s()
    for per_yaw_rate, want in ((False, rms_error), (True, 0.1)):
        model = ekf_v3_consistent(s_gamma=used, traction_slip=False, icr_correction=False,
                                  vy_per_yaw_rate=per_yaw_rate)
        _, _, gm_y, _, _, info = identify_yi_noise(runs, model, max_iterations=2)
        assert gm_y.per_yaw_rate is per_yaw_rate
        assert gm_y.sigma == pytest.approx(want, rel=0.15)
        assert gm_y.tau > 10.0 and info["iterations"] <= 2
