"""Yi 2009's EKF as the paper defines it (Sec. IV-A) and its plugin: methods.yi2009.ekf.

Synthetic runs: tests.methods.yi2009.synthetic.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench import registry
from bench.run import Run, RunError
from methods.yi2009.ekf import (EkfParams, FilterDivergence, Yi2009Ekf, align_inputs, dcm, ekf_v1, ekf_v2, ekf_v3,
                                initial_state, run_filter)
from methods.yi2009.s_gamma import PUBLISHED_S_GAMMA
from methods.yi2009.slip import slip_ratio
from tests.methods.yi2009.synthetic import (PAPER, R_WHEEL, TESTBED, TRACK, estimate_cached, imu_only,
                                            no_slip_dead_reckoning, pos_rms, synthetic_run)


def test_dcm_is_zyx_euler_rotation():
    """Eq. (2) equals the Z-Y-X intrinsic rotation R_z(psi) R_y(theta) R_x(phi)."""
    rng = np.random.default_rng(1)
    for phi, th, psi in rng.uniform([-1, -1.2, -3], [1, 1.2, 3], size=(20, 3)):
        np.testing.assert_allclose(dcm(phi, th, psi), Rotation.from_euler("ZYX", [psi, th, phi]).as_matrix(), atol=1e-14)


def _reference_ekf(t, acc, gyr, enc, variant, params, x0, p0, s_model):
    """The same recursion written from the paper with FilterPy's ExtendedKalmanFilter (Joseph
    update) and central-difference Jacobians of f (10)/(19) and h (16)."""
    from filterpy.kalman import ExtendedKalmanFilter

    def rot(x):
        return Rotation.from_euler("ZYX", [x[8], x[7], x[6]]).as_matrix()

    def f(x, u, dt):
        phi, th = x[6], x[7]
        a, w = u[:3], u[3:]
        euler_rates = np.array([
            w[0] + math.tan(th) * (math.sin(phi) * w[1] + math.cos(phi) * w[2]),
            math.cos(phi) * w[1] - math.sin(phi) * w[2],
            (math.sin(phi) * w[1] + math.cos(phi) * w[2]) / math.cos(th),
        ])
        return x + dt * np.concatenate([x[3:6], rot(x) @ a + [0, 0, -params.gravity], euler_rates])

    def h(x):
        return rot(x).T @ x[3:6]

    def jac(fun, x, eps=1e-7):
        return np.column_stack([(fun(x + eps * e) - fun(x - eps * e)) / (2 * eps) for e in np.eye(9)])

    ekf = ExtendedKalmanFilter(dim_x=9, dim_z=3)
    ekf.x = x0.reshape(9, 1).copy()
    ekf.P = p0.copy()
    r_all = np.array([(R_WHEEL * params.sigma_enc) ** 2, params.sigma_vy**2, params.sigma_vz**2])
    def slips(xk, w, g):  # eqs. (3)-(6) from the posterior
        vb = h(xk)
        psid = (math.sin(xk[6]) * g[1] + math.cos(xk[6]) * g[2]) / math.cos(xk[7])
        return slip_ratio(w, [vb[0] - TRACK / 2 * psid, vb[0] + TRACK / 2 * psid], R_WHEEL, params.min_wheel_speed)

    w_held = enc[0].copy()
    lam = slips(x0, w_held, gyr[0]) if np.isfinite(w_held).all() else np.zeros(2)
    xs = [ekf.x.ravel().copy()]
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        u = np.concatenate([acc[k - 1], gyr[k - 1]])
        x_prev = ekf.x.ravel()
        ekf.F = jac(lambda x: f(x, u, dt), x_prev)
        ekf.Q = np.diag([params.pos_noise**2] * 3 + [(params.accel_noise * dt) ** 2] * 3 + [(params.gyro_noise * dt) ** 2] * 3)
        ekf.predict_x = lambda _u=None, _x=x_prev: setattr(ekf, "x", f(_x, u, dt).reshape(9, 1))
        ekf.predict()
        xp = ekf.x.ravel()
        psid = (math.sin(xp[6]) * gyr[k, 1] + math.cos(xp[6]) * gyr[k, 2]) / math.cos(xp[7])
        if np.isfinite(enc[k]).all():
            w_held = enc[k].copy()
            wl, wr = enc[k]
            if variant >= 2:  # eq. (14), the cases of Sec. III-C's sentence (w_L <= w_R: lambda_L <= 0 <= lambda_R)
                pl = max(lam[0], 0) if wl > wr else min(lam[0], 0)
                pr = max(lam[1], 0) if wl <= wr else min(lam[1], 0)
            else:
                pl = pr = 0.0
            z = [R_WHEEL / 2 * (wl + wr - pl * wl - pr * wr)]  # eq. (13)
            rows = [0]
            if variant == 3:
                v_l, v_r = (1 - pl) * R_WHEEL * wl, (1 - pr) * R_WHEEL * wr
                s_val = s_model((v_l - v_r) / (v_l + v_r)) if abs(v_l + v_r) > 1e-9 else 0.0  # eqs. (40), (41)
                z.append(-s_val * psid)  # eq. (15)
                rows.append(1)
            z.append(0.0)
            rows.append(2)
        else:
            z, rows = [0.0], [2]
        ekf.update(np.array(z).reshape(-1, 1), lambda x: jac(h, x.ravel())[rows], lambda x: h(x.ravel())[rows].reshape(-1, 1),
                   R=np.diag(r_all[rows]))
        ekf.x[8, 0] = (ekf.x[8, 0] + math.pi) % (2 * math.pi) - math.pi
        xk = ekf.x.ravel()
        if np.isfinite(w_held).all():
            lam = slips(xk, w_held, gyr[k])
        xs.append(xk.copy())
    return np.array(xs)


@pytest.mark.parametrize("variant", [1, 2, 3])
def test_filter_matches_independent_filterpy_implementation(variant):
    """250 steps of the '8' while turning and speeding up (slip, some encoder samples missing): the
    hand-written Jacobians (20)-(25) and the recursion agree with FilterPy + numerical Jacobians."""
    run = synthetic_run("figure8", 3)
    d = run.data.iloc[1200:1450].copy()
    d.loc[d.index[3::7], "enc_wl"] = np.nan  # every 7th encoder sample missing
    sub = Run(d.reset_index(drop=True), run.meta)
    t, acc, gyr, enc = align_inputs(sub)
    params = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, params, (1.0, -2.0, 0.3))
    assert x0[3:5] @ x0[3:5] > 0.2  # a moving start
    res = run_filter(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=variant, s_gamma=PUBLISHED_S_GAMMA,
                     params=params, x0=x0, p0=p0)
    ref = _reference_ekf(t, acc, gyr, enc, variant, params, x0, p0, PUBLISHED_S_GAMMA)
    np.testing.assert_allclose(res.state, ref, atol=1e-6)
    assert res.n_updates[0] == np.isfinite(enc).all(axis=1)[1:].sum()


@pytest.mark.parametrize("kind", ["circle", "figure8"])
def test_ekf_beats_imu_integration_and_no_slip_dead_reckoning(kind):
    """Every variant beats pure IMU integration and no-slip encoder dead reckoning on turning paths
    (testbed-grade sensors); variant 3 by a factor >= 4."""
    run = synthetic_run(kind, 0, TESTBED)
    e_imu = pos_rms(run.t, *imu_only(run), run)
    e_dr = pos_rms(run.t, *no_slip_dead_reckoning(run), run)
    for v in (1, 2, 3):
        _, est = estimate_cached(v, kind, 0, TESTBED)
        e = pos_rms(est.t, est["x"], est["y"], run)
        assert e < min(e_imu, e_dr), (v, e, e_imu, e_dr)
        if v == 3:
            assert 4 * e < min(e_imu, e_dr), (e, e_imu, e_dr)


SEEDS = (0, 1, 2)


def test_variant_ordering_fig5():
    """Fig. 5/6 claim: position error of scheme 3 (xyz + slip) <= 2 (xz + slip) <= 1 (xz, no slip) on
    turning paths with lateral velocity and 10 % net slip (PAPER regime).  On the '8' it holds for
    every seed; on the circle schemes 2 and 3 beat 1 on every seed, and 3 <= 2 holds on the mean of
    the seeds (seed 1 has 3 > 2: the margin is small there)."""
    err = {}
    for kind in ("figure8", "circle"):
        for seed in SEEDS:
            run = estimate_cached(1, kind, seed, PAPER)[0]
            err[kind, seed] = [pos_rms(est.t, est["x"], est["y"], run)
                               for est in (estimate_cached(v, kind, seed, PAPER)[1] for v in (1, 2, 3))]
    for seed in SEEDS:
        e1, e2, e3 = err["figure8", seed]
        assert e3 <= e2 <= e1, ("figure8", seed, err["figure8", seed])
        e1, e2, e3 = err["circle", seed]
        assert max(e2, e3) <= e1, ("circle", seed, err["circle", seed])
    m1, m2, m3 = np.mean([err["circle", s] for s in SEEDS], axis=0)
    assert m3 <= m2 <= m1, (m1, m2, m3)


def test_slip_estimates_track_true_slip():
    """Fig. 7(c): on the '8' (slips change sign) the slip estimates of the slip-feedback schemes
    follow the true slips: correlation >= 0.7 (both variants); RMS <= 0.08 for scheme 2."""
    for seed in SEEDS:
        for v in (2, 3):
            run, est = estimate_cached(v, "figure8", seed, PAPER)
            moving = np.interp(est.t, run.t, run["truth_vx"]) > 0.1
            for side in ("l", "r"):
                true = np.interp(est.t, run.t, run[f"truth_slip_{side}"])[moving]
                got = est[f"slip_{side}"][moving]
                assert np.corrcoef(true, got)[0, 1] >= 0.7, (seed, v, side)
                if v == 2:
                    assert np.sqrt(np.mean((got - true) ** 2)) <= 0.08, (seed, side)


def test_covariance_symmetric_positive_definite_every_step():
    run = synthetic_run("figure8", 5)
    t, acc, gyr, enc = align_inputs(run.without_truth())
    params = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, params, (0.0, 0.0, 0.0))
    for v in (1, 3):
        res = run_filter(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=v, s_gamma=PUBLISHED_S_GAMMA,
                         params=params, x0=x0, p0=p0, store_cov=True)
        cov = res.cov
        assert cov.shape == (t.size, 9, 9)
        assert np.array_equal(cov, np.swapaxes(cov, 1, 2))
        assert np.linalg.eigvalsh(cov).min() > 0


def test_nan_encoder_samples_are_dropped_not_fused():
    """NaN encoder elements (scattered + a 1 s outage, one wheel only) skip the v_x/v_y rows: finite
    output, one v_x update per complete pair, accuracy close to the complete run."""
    run = synthetic_run("figure8", 2)
    d = run.data.copy()
    rng = np.random.default_rng(0)
    bad = rng.choice(np.arange(200, len(d)), 150, replace=False)
    d.loc[bad, "enc_wl"] = np.nan
    d.loc[(d.t > 12) & (d.t < 13), ["enc_wl", "enc_wr"]] = np.nan
    d.loc[300, "enc_wr"] = np.nan
    holed = Run(d, run.meta)
    est = ekf_v3().estimate(holed.without_truth())
    full = ekf_v3().estimate(run.without_truth())
    cols = ["x", "y", "yaw", "vx", "vy", "wz", "slip_l", "slip_r", "x_icr"]
    assert np.isfinite(est.data[cols].to_numpy()).all()
    n_pairs = int((np.isfinite(d.enc_wl) & np.isfinite(d.enc_wr)).to_numpy()[1:].sum())
    assert est.info["n_updates"]["vx"] == est.info["n_updates"]["vy"] == n_pairs
    assert est.info["n_updates"]["vz"] == len(d) - 1
    assert pos_rms(est.t, est["x"], est["y"], run) < pos_rms(full.t, full["x"], full["y"], run) + 0.1


def test_slower_encoder_and_missing_imu_rows():
    """Filter steps are the IMU rows; encoder samples at half rate are each fused once."""
    run = synthetic_run("circle", 4)
    d = run.data.copy()
    d.loc[d.index % 2 == 1, ["enc_wl", "enc_wr"]] = np.nan
    imu_cols = [c for c in d.columns if c.startswith("imu_")]
    d.loc[d.index % 10 == 5, imu_cols] = np.nan
    est = ekf_v1().estimate(Run(d, run.meta).without_truth())
    keep = d.index % 10 != 5
    np.testing.assert_array_equal(est.t, d.t[keep].to_numpy())
    assert est.info["n_updates"]["vx"] == int(np.isfinite(d.enc_wl).to_numpy()[1:].sum())
    assert pos_rms(est.t, est["x"], est["y"], run) < 0.5


def test_cholesky_failure_names_step():
    """A perfect constraint (R = 0) with zero prior covariance and Q = 0 makes S (26e) singular."""
    zero = EkfParams(accel_noise=0, gyro_noise=0, pos_noise=0, sigma_enc=0, sigma_vy=0, sigma_vz=0,
                     p0_pos=0, p0_vel=0, p0_rollpitch=0, p0_yaw=0)
    run = synthetic_run("circle", 1)
    with pytest.raises(FilterDivergence, match=r"step 1 \(t = 0\.008"):
        Yi2009Ekf(variant=1, params=zero).estimate(run.without_truth())


def test_bad_input_errors_name_the_channel():
    run = synthetic_run("circle", 1)
    with pytest.raises(RunError, match="enc_wr"):
        registry.estimate(ekf_v1(), Run(run.data.drop(columns=["enc_wr"]), run.meta))
    with pytest.raises(RunError, match="meta.platform"):
        ekf_v1().estimate(Run(run.data, {"run_id": "no-platform"}))
    d = run.data.copy()
    d.loc[50, "t"] = d.loc[49, "t"]
    with pytest.raises(RunError, match="row 50"):
        ekf_v1().estimate(Run(d, run.meta))
    with pytest.raises(ValueError, match="variant"):
        Yi2009Ekf(variant=4)
    with pytest.raises(ValueError, match="sigma_vz"):
        EkfParams(sigma_vz=-1.0)


def test_deterministic_and_plugin_protocol():
    run = synthetic_run("figure8", 7)
    a = registry.estimate(ekf_v2(), run)
    b = registry.estimate(ekf_v2(), run)
    assert a.data.equals(b.data)
    for factory, name in ((ekf_v1, "yi2009.ekf_v1"), (ekf_v2, "yi2009.ekf_v2"), (ekf_v3, "yi2009.ekf_v3")):
        m = factory()
        assert isinstance(m, registry.Method) and m.name == name and a.method == "yi2009.ekf_v2"
        assert m.requires == frozenset({"enc_wl", "enc_wr", "imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz"})
    assert {"slip_l", "slip_r", "vx", "vy", "wz"} <= set(a.data.columns)
    assert not any(c.startswith("truth_") for c in a.data.columns)


@pytest.mark.parametrize("variant", [1, 2, 3])
def test_paper_plugin_is_run_filter_with_the_paper_parameters(variant):
    """The paper plugins (Fig. 5 schemes) are a direct run_filter call with EkfParams(): the consistent section
    does not enter their path."""
    run = synthetic_run("figure8", 4).without_truth()
    plain = Yi2009Ekf(variant=variant).estimate(run)
    assert plain.method == f"yi2009.ekf_v{variant}"
    t, acc, gyr, enc = align_inputs(run)
    x0, p0 = initial_state(acc, enc, R_WHEEL, EkfParams(), (0.0, 0.0, 0.0))
    res = run_filter(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=variant, s_gamma=PUBLISHED_S_GAMMA,
                     params=EkfParams(), x0=x0, p0=p0)
    assert np.array_equal(plain["x"], res.state[:, 0]) and np.array_equal(plain["vx"], res.v_body[:, 0])
    assert np.array_equal(plain["slip_l"], res.slip[:, 0], equal_nan=True)


STEP_FROM_REST_RPM = [(0, 0, 0), (0.02, 30, 30), (20, 30, 30)]  # a 30/30 rpm step after the 1 s rest (Fig. 5a)


def _straight_step(seed: int, lam0: float = 0.0) -> Run:
    """The straight line of Fig. 5a started by a step command from rest, closed-form truth (synthetic.py): both
    encoders read the same counts (one wheel-speed profile, one quantisation), as on the testbed's 30/30 rpm path."""
    import dataclasses

    return synthetic_run("straight", seed, dataclasses.replace(TESTBED, lam0=lam0), knots_rpm=STEP_FROM_REST_RPM)


@pytest.mark.parametrize("seed", [0, 1])
def test_slip_does_not_latch_after_a_start_from_rest(seed):
    """Start from rest with a step command on a straight line, truth slip lam0 = 0 (eq. (6) of the closed-form truth):
    the slip-feedback schemes' slip stays within 0.1 of the truth at >= 95 % of the steps from 1 s after the start of
    motion, never at the +1 clip of (6), and scheme 3's position RMS is below 20 % of the path length (issue 30's
    criteria).  With (14)'s equal-speed case as printed (traction on both sides: v_x (13) bounded from above only) the
    filter's speed fell behind the wheels, the slip latched at +1 and (13) measured v_x = 0: within 0.1 at 4-10 % of
    the steps, at the clip 22-34 %, scheme 3 RMS 1.4-1.6 m of 5.4 m (seeds 0-1)."""
    run = _straight_step(seed)
    t_move = TESTBED.t_rest
    length = float(np.sum(np.hypot(np.diff(run["truth_x"]), np.diff(run["truth_y"]))))
    for v in (2, 3):
        est = Yi2009Ekf(variant=v).estimate(run.without_truth())
        after = est.t >= t_move + 1.0
        lam = np.column_stack((est["slip_l"], est["slip_r"]))[after]
        truth = np.column_stack([np.interp(est.t, run.t, run[f"truth_slip_{s}"]) for s in "lr"])[after]
        within = float(np.mean(np.abs(lam - truth).max(axis=1) <= 0.1))
        assert within >= 0.95, (v, within)
        assert not np.any(np.abs(lam) >= 0.999), (v, float(np.mean(np.abs(lam).max(axis=1) >= 0.999)))
        if v == 3:
            e = pos_rms(est.t, est["x"], est["y"], run)
            assert e < 0.2 * length, (e, length)


def test_slip_feedback_follows_a_known_net_slip_below_the_wheel_speed():
    """With a net traction slip of 3 % (truth v_x = 0.97 r w) the estimated speed of scheme 3 stays between the truth and
    the wheel speed (the bounds of (13)-(14) at equal speeds: the right side traction, the left braking, so the row
    is the mean of r w and the filter's own speed) and the along-track position error stays below the path's
    no-slip dead-reckoning error r w t - x, the most the row can add (closed form: 0.03 x)."""
    run = _straight_step(0, lam0=0.03)
    est = Yi2009Ekf(variant=3).estimate(run.without_truth())
    x_end = float(run["truth_x"][-1])
    assert abs(float(est["x"][-1]) - x_end) <= 0.03 / 0.97 * x_end + 0.02, (float(est["x"][-1]), x_end)


def test_roll_is_unobserved_without_the_lateral_row():
    """Schemes 1-2 fuse v_x (13) and v_z (11) only: on a straight line at v_By = 0 neither row's roll column is nonzero
    (-v_By in (25) for v_z, 0 for v_x), so to first order the roll variance stays at its P0 (plus the gyro's Q): Sec.
    IV-B's analysis assumes the attitude known.  Scheme 3's v_y row (15) sees roll through gravity, g droll leaking
    into v_By in the prediction (10b), and observes it.  (Later, once the unobserved v_By estimate has drifted, the
    roll column -v_By of the v_z row is no longer 0 and schemes 1-2 start claiming roll information that a first-
    order analysis at the true state does not give: after 4 s of motion their sd falls to 0.014-0.019 rad.)"""
    run = _straight_step(2)
    t, acc, gyr, enc = align_inputs(run.without_truth())
    params = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, params, (0.0, 0.0, 0.0))
    sd = {}
    for v in (1, 2, 3):
        res = run_filter(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=v, s_gamma=PUBLISHED_S_GAMMA,
                         params=params, x0=x0, p0=p0, store_cov=True)
        sd[v] = float(np.sqrt(res.cov[np.searchsorted(t, TESTBED.t_rest + 2.0), 6, 6]))  # 2 s of motion
    p0_sd = math.sqrt(p0[6, 6])
    assert sd[1] >= 0.95 * p0_sd and sd[2] >= 0.95 * p0_sd, (sd, p0_sd)
    assert sd[3] <= 0.1 * p0_sd, (sd, p0_sd)
