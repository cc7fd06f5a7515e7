"""methods/liu2020/consistent.py and gnss_bias.py (beyond the paper): the GNSS bias states in closed form,
the consistent options on a decaying GNSS offset, the noise identification on the testbed calibration
run, the recorded innovations against FilterPy's Kalman filter and their statistics.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bench import registry
from bench.run import Run, RunError
from bench.estimation.ukf import nees
from methods.liu2020 import LiuUkfParams, run_liu_filter
from tests.methods.liu2020.synthetic import PLATFORM, make_run


def test_gnss_bias_process_and_measurement_closed_form():
    """liu_fx_gnss_bias = liu_fx on the six navigation states and b <- b exp(-dT/tau) on the bias
    states; liu_hx_gnss_bias adds the bias to the GNSS position rows only."""
    from methods.liu2020 import liu_fx, liu_fx_gnss_bias, liu_hx, liu_hx_gnss_bias

    rng = np.random.default_rng(4)
    sig = rng.normal(size=(17, 8))
    dt, tau = 0.01, 20.0
    out = liu_fx_gnss_bias(sig, dt, (0.3, -0.2, True, math.exp(-dt / tau)))
    np.testing.assert_array_equal(out[:, :6], liu_fx(sig, dt, (0.3, -0.2, True))[:, :6])
    np.testing.assert_allclose(out[:, 6:], sig[:, 6:] * math.exp(-dt / tau), rtol=1e-15)
    h, h0 = liu_hx_gnss_bias(sig), liu_hx(sig[:, :6])
    np.testing.assert_allclose(h[:, :2], h0[:, :2] + sig[:, 6:8], rtol=1e-15)
    np.testing.assert_array_equal(h[:, 2:], h0[:, 2:])
    with pytest.raises(ValueError, match="gnss_bias_tau"):
        LiuUkfParams(gnss_bias_tau=0.0)
    with pytest.raises(ValueError, match="must exceed gnss_bias_p0"):
        LiuUkfParams(gnss_bias_tau=20.0, gnss_bias_p0=0.3, p0_pos=0.3)


def _biased(run: Run, b0: tuple[float, float], tau: float) -> Run:
    """The GNSS position of ``run`` plus a decaying initial offset b0 exp(-t/tau) (DUBHE's receiver model)."""
    d = run.data.copy()
    decay = np.exp(-run.t / tau)
    d["gnss_x"] = d["gnss_x"] + b0[0] * decay
    d["gnss_y"] = d["gnss_y"] + b0[1] * decay
    return Run(d, run.meta)


def test_consistent_options_fix_the_overconfidence_on_a_decaying_gnss_offset():
    """A 0.28 m GNSS offset decaying with tau = 20 s (the testbed receiver's error, here on synthetic
    data with known truth).  The paper's filter fuses it as white 0.3 m noise at 10 Hz and the encoder
    pose pseudo-measurement at every step: its position NEES (2 dof, consistent mean 2) is far above
    the chi-square range.  With the pose pseudo-measurement dropped and the offset as Gauss-Markov bias
    states of the true tau and initial std, the position NEES is at the 2-dof level and the estimated
    bias follows the true one.  Fused element counts: 6 GNSS + 3 encoder velocities at GNSS rows,
    gyro + 3 encoder velocities elsewhere (paper: 6 + 6 and 1 + 6)."""
    b0, tau = (0.2, -0.2), 20.0
    run = _biased(make_run(31, duration=60.0, kind="mixed"), b0, tau)
    g = np.isfinite(run["gnss_x"])
    sw = 0.02
    base = LiuUkfParams(r_gnss=(sw, sw, 0.005, 0.03, 0.03, 0.003), r_encoder=(0.5, 0.5, 0.5, 0.3, 0.03, 0.02))
    cons = replace(base, encoder_pose=False, gnss_bias_tau=tau, gnss_bias_p0=0.2, p0_pos=math.hypot(0.2, sw))
    res = {}
    for tag, p in (("paper", base), ("consistent", cons)):
        est = run_liu_filter(run, p, tag)
        e = np.column_stack((est["x"] - run["truth_x"], est["y"] - run["truth_y"]))[1:]
        res[tag] = float(nees(e, est.info["P"][1:, :2, :2]).mean())
        nf = est.info["n_fused"][1:]
        assert np.all(nf[g[1:]] == (12 if tag == "paper" else 9)) and np.all(nf[~g[1:]] == (7 if tag == "paper" else 4))
        if tag == "consistent":
            b = est.info["gnss_bias"]
            true_b = np.column_stack((b0[0] * np.exp(-run.t / tau), b0[1] * np.exp(-run.t / tau)))
            late = run.t > 20.0
            assert np.sqrt(np.mean(np.sum((b[late] - true_b[late]) ** 2, axis=1))) < 0.05
    print(res)
    assert res["paper"] > 20.0
    assert 0.5 < res["consistent"] < 4.0


def test_ar1_plus_white_recovers_known_parameters():
    """AR(1) (rho 0.9, stationary var 1) + white (var 0.25): the split of _ar1_plus_white."""
    from methods.liu2020.consistent import _ar1_plus_white

    rng = np.random.default_rng(0)
    n, rho = 400_000, 0.9
    e = rng.normal(0, math.sqrt(1 - rho ** 2), n)
    x = np.empty(n)
    x[0] = rng.normal()
    for i in range(1, n):  # plain recursion: the closed-form AR(1)
        x[i] = rho * x[i - 1] + e[i]
    c0, sc2, r = _ar1_plus_white(x + rng.normal(0, 0.5, n))
    assert r == pytest.approx(0.9, abs=0.01) and sc2 == pytest.approx(1.0, rel=0.05) and c0 == pytest.approx(1.25, rel=0.05)
    c0, sc2, r = _ar1_plus_white(rng.normal(0, 0.5, n))  # white only
    assert sc2 < 0.01 * c0


def test_consistent_identifies_the_receiver_model_on_a_calibration_run(sim):
    """identify_noise on the testbed calibration run (liu_calib seed 100, reference sensor, no truth)
    recovers DUBHE's sensor spec (scenarios/platforms/dubhe.toml): GNSS drift 0.3 m (per-axis std
    0.3/sqrt(2)) decaying with tau = 20 s, position noise 0.02 m, velocity 0.03 m/s, heading 0.005 rad,
    gyro 0.003 rad/s.  On flat ground: the scenario's ISO 8608 ground shakes the body (its yaw rate has
    real content above the filter's model at every bump), which the identification rightly counts as gyro
    noise -- there it finds more than the sensor's 0.003 rad/s.  The calibrated filter refuses its
    calibration run; uncalibrated, it refuses to run."""
    from methods.liu2020 import MiUkfConsistent, UkfIcrConsistent, identify_noise

    calib = sim("liu_calib", 100, terrain__roughness_gd0=0.0)
    rough = identify_noise([sim("liu_calib", 100).without_truth()], UkfIcrConsistent().params)[1]
    m = registry.calibrate(UkfIcrConsistent(), [calib])
    gn = PLATFORM["sensors"]["gnss"]
    info = m.noise_info
    assert info["gnss_bias_tau"] == pytest.approx(gn["drift_tau"], rel=0.1)
    assert info["gnss_bias_p0"] == pytest.approx(gn["initial_drift"] / math.sqrt(2), rel=0.1)
    assert info["gnss_white_std"] == pytest.approx(gn["pos_noise"], rel=0.15)
    assert info["gnss_vel_std"] == pytest.approx(gn["vel_noise"], rel=0.15)
    assert info["gnss_yaw_std"] == pytest.approx(gn["yaw_noise"], rel=0.15)
    assert info["gyro_std"] == pytest.approx(PLATFORM["sensors"]["imu"]["gyro_noise"], rel=0.15)
    assert rough["gyro_std"] > 1.15 * info["gyro_std"]  # the bumps' yaw-rate content, beyond the sensor's noise
    assert rough["gnss_yaw_std"] == pytest.approx(gn["yaw_noise"], rel=0.15)  # the GNSS heading sees no bump
    assert info["gnss_bias_q"] < 0.01  # the receiver model has no random walk (drift_walk = 0)
    p = m.params
    assert not p.encoder_pose and p.gnss_bias_tau == info["gnss_bias_tau"] and p.r_gnss[0] == info["gnss_white_std"]
    assert p.r_encoder[3] == pytest.approx(info["enc_vx_r"]) and p.r_encoder[3] > 5 * p.r_encoder[4]
    # process noise (match_process_noise, whiteness for the UKF+ICR): once the innovations are white, their level
    # is near 1 where R dominates S (GNSS heading and velocity rows) -- an independent check of the separately
    # identified R and of the whiteness answer; the gyro row's level is far below 1 (documented model misfit)
    assert info["q_criterion"] == 0.0 and info["q_converged"] == 1.0
    assert info["nis_yaw"] == pytest.approx(1.0, abs=0.15) and info["nis_vel"] == pytest.approx(1.0, abs=0.15)
    assert info["nis_yaw_rate"] < 0.1
    assert p.q_pos == LiuUkfParams().q_pos
    with pytest.raises(registry.CalibrationLeak):
        registry.estimate(m, calib)
    with pytest.raises(RunError, match="calibrate"):
        MiUkfConsistent().estimate(calib.without_truth())
    with pytest.raises(RunError, match="ref_x"):
        registry.calibrate(UkfIcrConsistent(), [Run(calib.data.drop(columns=["ref_x"]), calib.meta)])


def test_recorded_innovations_equal_filterpy_kalman_filter_on_a_linear_model():
    """_InnovationUkf's normalised innovations y_j / sqrt(S_jj) of rows 2-5 of a 6-row measurement on a linear model,
    where the UKF is the Kalman filter: equal to FilterPy's KalmanFilter (its y and S after each update), with
    row 3 missing at some steps (not recorded then)."""
    from filterpy.kalman import KalmanFilter

    from methods.liu2020.consistent import _InnovationUkf

    rng = np.random.default_rng(7)
    n, dt = 6, 0.1
    F = np.eye(n) + dt * np.diag(np.ones(n - 1), 1)
    Q = np.diag(rng.uniform(0.01, 0.1, n))
    R = np.diag(rng.uniform(0.05, 0.2, n))
    P0 = np.eye(n)
    ukf = _InnovationUkf(lambda sig, dt_, u: sig @ F.T, lambda sig: sig.copy(), np.zeros(n), P0, Q, R)
    kf = KalmanFilter(dim_x=n, dim_z=n)
    kf.F, kf.H, kf.Q, kf.P, kf.x = F, np.eye(n), Q, P0.copy(), np.zeros(n)
    ref: dict[int, list[float]] = {j: [] for j in ukf.innovations}
    x = rng.normal(size=n)
    for k in range(200):
        x = F @ x + rng.normal(size=n) * np.sqrt(np.diag(Q))
        z = x + rng.normal(size=n) * np.sqrt(np.diag(R))
        if k % 7 == 3:
            z[3] = np.nan
        ukf.predict(dt, None, Q)
        ukf.update(z)
        ok = np.isfinite(z)
        kf.predict()
        kf.update(z[ok], R=R[np.ix_(ok, ok)], H=np.eye(n)[ok])
        pos = np.cumsum(ok) - 1
        for j in ref:
            if ok[j]:
                ref[j].append(kf.y[pos[j]] / math.sqrt(kf.S[pos[j], pos[j]]))
    np.testing.assert_allclose(ukf.x, kf.x, atol=1e-9)
    assert sorted(ukf.innovations) == [2, 3, 4, 5] and len(ref[3]) < len(ref[2]) == 200
    for j in ref:
        np.testing.assert_allclose(ukf.innovations[j], ref[j], rtol=1e-9, atol=1e-12)


def test_innovation_statistics_closed_form():
    """innovation_statistics: white unit noise -> (1, 0); AR(1) with rho 0.6 and variance 4 -> (4, 0.6);
    pooled over runs and rows."""
    from methods.liu2020 import innovation_statistics

    rng = np.random.default_rng(3)
    white = [{2: rng.normal(size=50_000).tolist()}, {2: rng.normal(size=50_000).tolist()}]
    nis, r1 = innovation_statistics(white, (2,))
    assert nis == pytest.approx(1.0, abs=0.02) and abs(r1) < 0.01
    rho, n = 0.6, 100_000
    e = rng.normal(0, 2.0 * math.sqrt(1 - rho ** 2), n)
    v = np.empty(n)
    v[0] = rng.normal(0, 2.0)
    for i in range(1, n):  # plain recursion: the closed-form AR(1)
        v[i] = rho * v[i - 1] + e[i]
    nis, r1 = innovation_statistics([{3: v[: n // 2].tolist(), 4: v[n // 2:].tolist()}], (3, 4))
    assert nis == pytest.approx(4.0, rel=0.03) and r1 == pytest.approx(rho, abs=0.01)
    assert all(math.isnan(x) for x in innovation_statistics([{2: [0.1, 0.2]}], (2,)))


@pytest.mark.slow
def test_whiteness_criterion_is_insensitive_to_an_error_in_r(sim):
    """The design claim of match_process_noise: with the GNSS velocity noise R 10 % too large, the level
    criterion's q_vel moves by far more than the whiteness criterion's (R dominates S for the GNSS rows)."""
    from methods.liu2020 import UkfIcrConsistent, match_process_noise

    calib = sim("liu_calib", 100)
    p = registry.calibrate(UkfIcrConsistent(), [calib]).params
    rg = list(p.r_gnss)
    rg[3] = rg[4] = 1.1 * rg[3]
    q = {}
    for tag, length in (("whiteness", 1), ("level", 2)):  # p = 2 with a = 0 (lambda_2 = 0) is the same UKF, level criterion
        for scale, r_gnss in (("ok", p.r_gnss), ("off", tuple(rg))):
            _, info = match_process_noise([calib], replace(p, innovation_length=length, mi_a=0.0, r_gnss=r_gnss))
            q[tag, scale] = info["q_vel"]
    move = {tag: abs(math.log(q[tag, "off"] / q[tag, "ok"])) for tag in ("whiteness", "level")}
    assert move["level"] > 2.0 * move["whiteness"], (q, move)
