"""Tests of methods.yi2009 (Yi et al. 2009 EKF) on synthetic runs built here from closed-form kinematics.

The synthetic truth is an ICR model independent of the method: tread speeds r*w from wheel-speed
profiles in rpm (the paper's Figs. 5-7: straight 30/30, circle 80/40, "8" shape 80/40 -> 40/80 at
10 rpm/s), a net traction slip lam0 and an ICR expansion chi give
    v_x = (1 - lam0)(v_l + v_r)/2,  w_z = (1 - lam0)(v_r - v_l)/(chi W),
    v_y = -S(gamma) w_z with S of eq. (41) (known a1, a2, a3) and gamma of eq. (40),
the pose by exact SE(2) integration (bench.kinematics.integrate_se2), the IMU as specific force
(gravity included) + noise + bias, the encoders as quantised count differences, the reference
sensor (ref_*) as noisy 31.25 Hz pose samples.  The truth slips follow from eq. (6).

Two sensor regimes: TESTBED (the yi2009_4wd platform's sensors: 2000-count encoders, IMU noise
0.05 m/s^2 / 0.005 rad/s per sample, biases) and PAPER (better sensors, 10 % net slip: the regime
where the paper's Fig. 5 ordering holds on this synthetic data; see the report of the helper).
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_trapezoid
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from bench import registry
from bench.kinematics import ideal_dd, integrate_se2
from bench.run import Run, RunError, from_arrays
from bench.spec import load_platform, to_dict
from methods.yi2009 import (
    PUBLISHED_S_GAMMA,
    EkfParams,
    FilterDivergence,
    SGamma,
    Yi2009Ekf,
    GaussMarkov,
    align_inputs,
    ar1_mean_var_factor,
    at_rest_start,
    ekf_v1_consistent,
    ekf_v2_consistent,
    ekf_v3_consistent,
    identify_yi_noise,
    reference_body_velocity,
    savgol_turn_gain,
    _reference_derivative,
    constrained_slip,
    dcm,
    ekf_v1,
    ekf_v2,
    ekf_v3,
    fit_s_gamma,
    gauss_markov_fit,
    moving_mean_var,
    encoder_odometer_sd,
    encoder_quantisation,
    initial_state,
    odometer_min_window,
    reference_s_gamma_point,
    run_filter,
    run_filter_gm,
    slip_ratio,
    static_imu_noise,
    fit_traction_slip,
    traction_features,
    fit_icr_correction,
    icr_features,
    IcrCorrection,
    reference_smoothing_bias,
    reference_velocity_noise_mean_var,
    trailing_mean,
    traction_transient,
    gm_sigma_steps,
    yaw_rate_scale,
    YAW_RATE_SCALE_SECONDS,
    GM_NEGLIGIBLE_SIGMA,
)

RPM_TO_RADS = 2.0 * math.pi / 60.0
PLATFORM = to_dict(load_platform("yi2009_4wd"))
R_WHEEL, TRACK = PLATFORM["wheel_radius"], PLATFORM["track"]
TRUE_S = (0.02148, 0.249, 0.039)  # eq. (41) with the published values, a1 in metres
G = 9.81

# (time since start of motion [s], w_L [rpm], w_R [rpm]); 1 s ramp from rest (Figs. 5-7)
PROFILES_RPM = {
    "straight": [(0, 0, 0), (1, 30, 30), (31, 30, 30)],
    "circle": [(0, 0, 0), (1, 80, 40), (31, 80, 40)],
    "figure8": [(0, 0, 0), (1, 80, 40), (9, 80, 40), (13, 40, 80), (21, 40, 80), (25, 80, 40), (31, 80, 40)],
}


@dataclass(frozen=True)
class Sensors:
    lam0: float = 0.05  # net traction slip
    chi: float = 1.4  # ICR expansion
    counts_per_rev: int = 2000
    acc_noise: float = 0.05  # per sample [m/s^2]
    gyr_noise: float = 0.005  # per sample [rad/s]
    acc_bias: tuple[float, float, float] = (0.01, -0.01, 0.005)
    gyr_bias: tuple[float, float, float] = (5e-4, -5e-4, 1e-3)
    rate_hz: float = 125.0
    t_rest: float = 1.0
    ref_every: int = 4


TESTBED = Sensors()
PAPER = Sensors(lam0=0.10, counts_per_rev=20000, acc_noise=0.01, gyr_noise=0.001,
                acc_bias=(0.002, -0.002, 0.001), gyr_bias=(1e-4, -1e-4, 2e-4))


def synthetic_run(kind: str, seed: int = 0, sensors: Sensors = TESTBED, knots_rpm=None, s_model=TRUE_S) -> Run:
    """A Run of the closed-form model described in the module docstring (truth_* columns included)."""
    rng = np.random.default_rng(seed)
    kn = np.asarray(knots_rpm if knots_rpm is not None else PROFILES_RPM[kind], float)
    t = np.arange(0.0, sensors.t_rest + kn[-1, 0], 1.0 / sensors.rate_hz)
    n = t.size
    tm = t - sensors.t_rest
    wl = np.interp(tm, kn[:, 0], kn[:, 1]) * RPM_TO_RADS
    wr = np.interp(tm, kn[:, 0], kn[:, 2]) * RPM_TO_RADS
    vl, vr = R_WHEEL * wl, R_WHEEL * wr
    vx = (1 - sensors.lam0) * (vl + vr) / 2
    wz = (1 - sensors.lam0) * (vr - vl) / (sensors.chi * TRACK)
    vlx, vrx = vx - TRACK / 2 * wz, vx + TRACK / 2 * wz  # eqs. (3)-(4)
    moving = vl + vr > 0
    gam = np.where(moving, (vlx - vrx) / np.where(moving, vlx + vrx, 1.0), 0.0)  # eq. (40)
    s_true = s_model[0] / (s_model[1] * np.abs(gam) + s_model[2])  # eq. (41)
    vy = -s_true * wz  # eq. (7)
    x, y, yaw = integrate_se2(t, vx, vy, wz)
    fx = np.gradient(vx, t) - wz * vy  # specific force of planar motion, gravity on z
    fy = np.gradient(vy, t) + wz * vx
    acc = np.column_stack([fx, fy, np.full(n, G)]) + sensors.acc_bias + sensors.acc_noise * rng.standard_normal((n, 3))
    gyr = np.column_stack([np.zeros(n), np.zeros(n), wz]) + sensors.gyr_bias + sensors.gyr_noise * rng.standard_normal((n, 3))
    q = 2 * math.pi / sensors.counts_per_rev

    def encoder(w: np.ndarray) -> np.ndarray:  # count differences per sample
        angle = cumulative_trapezoid(w, t, initial=0.0)
        return np.concatenate(([0.0], np.diff(np.floor(angle / q)) * q * sensors.rate_hz))

    with np.errstate(divide="ignore", invalid="ignore"):
        slip_l = np.where(vl > 0, 1 - vlx / vl, 0.0)
        slip_r = np.where(vr > 0, 1 - vrx / vr, 0.0)
    ref = np.full((n, 3), np.nan)
    idx = np.arange(0, n, sensors.ref_every)
    ref[idx, 0] = x[idx] + 0.0149 * rng.standard_normal(idx.size)
    ref[idx, 1] = y[idx] + 0.0149 * rng.standard_normal(idx.size)
    ref[idx, 2] = (yaw[idx] + 0.01 * rng.standard_normal(idx.size) + np.pi) % (2 * np.pi) - np.pi
    cols = dict(
        t=t, enc_wl=encoder(wl), enc_wr=encoder(wr),
        imu_ax=acc[:, 0], imu_ay=acc[:, 1], imu_az=acc[:, 2], imu_gx=gyr[:, 0], imu_gy=gyr[:, 1], imu_gz=gyr[:, 2],
        ref_x=ref[:, 0], ref_y=ref[:, 1], ref_yaw=ref[:, 2],
        truth_x=x, truth_y=y, truth_yaw=yaw, truth_vx=vx, truth_vy=vy, truth_wz=wz,
        truth_slip_l=slip_l, truth_slip_r=slip_r, truth_x_icr=s_true,
    )
    return from_arrays(cols, dict(run_id=f"synthetic-{kind}-{seed}", platform=PLATFORM))


def pos_rms(t_est: np.ndarray, x: np.ndarray, y: np.ndarray, run: Run) -> float:
    xt, yt = np.interp(t_est, run.t, run["truth_x"]), np.interp(t_est, run.t, run["truth_y"])
    return float(np.sqrt(np.mean((x - xt) ** 2 + (y - yt) ** 2)))


def imu_only(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """Pure strapdown integration of eqs. (10a)-(10e) (no constraint, no encoder) from rest at the
    origin, roll/pitch levelled from the accelerometer at rest, like the EKF's initial state."""
    t, acc = run.t, np.column_stack([run[f"imu_a{a}"] for a in "xyz"])
    gyr = np.column_stack([run[f"imu_g{a}"] for a in "xyz"])
    a0 = acc[:25].mean(axis=0)
    att = np.array([math.atan2(a0[1], a0[2]), math.atan2(-a0[0], math.hypot(a0[1], a0[2])), 0.0])
    v, p = np.zeros(3), np.zeros(3)
    out = np.zeros((t.size, 2))
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        phi, th = att[0], att[1]
        w = gyr[k - 1]
        rate = np.array([w[0] + math.tan(th) * (math.sin(phi) * w[1] + math.cos(phi) * w[2]),
                         math.cos(phi) * w[1] - math.sin(phi) * w[2],
                         (math.sin(phi) * w[1] + math.cos(phi) * w[2]) / math.cos(th)])
        c_bi = Rotation.from_euler("ZYX", att[::-1]).as_matrix()
        p = p + dt * v
        v = v + dt * (c_bi @ acc[k - 1] - [0.0, 0.0, G])
        att = att + dt * rate
        out[k] = p[:2]
    return out[:, 0], out[:, 1]


def no_slip_dead_reckoning(run: Run) -> tuple[np.ndarray, np.ndarray]:
    vx, vy, wz = ideal_dd(R_WHEEL * run["enc_wl"], R_WHEEL * run["enc_wr"], TRACK)
    x, y, _ = integrate_se2(run.t, vx, vy, wz)
    return x, y


_CACHE: dict = {}


def estimate_cached(variant: int, kind: str, seed: int, sensors: Sensors):
    key = (variant, kind, seed, sensors)
    if key not in _CACHE:
        run = synthetic_run(kind, seed, sensors)
        _CACHE[key] = (run, Yi2009Ekf(variant=variant).estimate(run.without_truth()))
    return _CACHE[key]


# ------------------------------------------------------------------------------------------
# Kinematic pieces
# ------------------------------------------------------------------------------------------
def test_dcm_is_zyx_euler_rotation():
    """Eq. (2) equals the Z-Y-X intrinsic rotation R_z(psi) R_y(theta) R_x(phi)."""
    rng = np.random.default_rng(1)
    for phi, th, psi in rng.uniform([-1, -1.2, -3], [1, 1.2, 3], size=(20, 3)):
        np.testing.assert_allclose(dcm(phi, th, psi), Rotation.from_euler("ZYX", [psi, th, phi]).as_matrix(), atol=1e-14)


def test_slip_ratio_definition_and_clipping():
    """Eq. (6) and the [-1, 1] bound of Sec. III-A; 0 at standstill."""
    lam = slip_ratio([10.0, 10.0, 10.0, 10.0, 0.0], [0.9 * R_WHEEL * 10, R_WHEEL * 10 * 1.2, -1.0, 50.0, 0.3], R_WHEEL)
    np.testing.assert_allclose(lam, [0.1, -0.2, 1.0, -1.0, 0.0], atol=1e-12)


def test_constrained_slip_follows_turn_direction():
    """Eq. (14): the faster side keeps only lambda >= 0, the slower only lambda <= 0; straight: both >= 0."""
    lam_l = np.array([0.2, -0.2, 0.2, -0.2, 0.1, -0.1])
    lam_r = np.array([-0.1, 0.1, 0.3, -0.3, 0.1, -0.1])
    w_l = np.array([8.0, 8.0, 4.0, 4.0, 5.0, 5.0])
    w_r = np.array([4.0, 4.0, 8.0, 8.0, 5.0, 5.0])
    pl, pr = constrained_slip(lam_l, lam_r, w_l, w_r)
    np.testing.assert_array_equal(pl, [0.2, 0.0, 0.0, -0.2, 0.1, 0.0])
    np.testing.assert_array_equal(pr, [-0.1, 0.0, 0.3, 0.0, 0.1, 0.0])


# ------------------------------------------------------------------------------------------
# S(gamma), eq. (41), Sec. V-B
# ------------------------------------------------------------------------------------------
def test_published_s_gamma_units():
    """a1 = 2.148 cm converted at the boundary; S(0) = a1/a3, S -> 0 for |gamma| -> inf."""
    s = PUBLISHED_S_GAMMA
    assert s.a1 == pytest.approx(0.02148, rel=1e-15) and s.a1_cm == pytest.approx(2.148)
    assert s(0.0) == pytest.approx(0.02148 / 0.039)
    assert s(np.inf) == 0.0
    assert s(-0.3) == s(0.3) == pytest.approx(0.02148 / (0.249 * 0.3 + 0.039))


def test_fit_s_gamma_recovers_published_coefficients():
    """Points generated by eq. (41) with the published (a1, a2, a3): the nonlinear least-squares fit
    (a3 held at its normalisation value) returns a1 and a2 to 1e-6 relative."""
    gamma = np.array([-0.55, -0.4, -0.3, -0.2, -0.1, 0.05, 0.1, 0.2, 0.33, 0.5, 0.7])  # 11 runs as in Fig. 4
    s = PUBLISHED_S_GAMMA(gamma)
    fit = fit_s_gamma(gamma, s)
    assert fit.s_gamma.a1 == pytest.approx(PUBLISHED_S_GAMMA.a1, rel=1e-6)
    assert fit.s_gamma.a2 == pytest.approx(PUBLISHED_S_GAMMA.a2, rel=1e-6)
    assert fit.s_gamma.a3 == PUBLISHED_S_GAMMA.a3
    assert fit.residual_rms < 1e-10 and fit.n_points == 11


def test_fit_s_gamma_is_only_defined_up_to_scale():
    """(a1, a2, a3) and c(a1, a2, a3) are the same curve: with a3 normalised to 2 a3 the fit returns
    2 a1, 2 a2 and the identical curve, so only a1/a3 and a2/a3 are identifiable."""
    gamma = np.linspace(0.02, 0.8, 15)
    s = PUBLISHED_S_GAMMA(gamma)
    fit = fit_s_gamma(gamma, s, a3=2 * PUBLISHED_S_GAMMA.a3)
    assert fit.s_gamma.a1 == pytest.approx(2 * PUBLISHED_S_GAMMA.a1, rel=1e-6)
    assert fit.s_gamma.a2 == pytest.approx(2 * PUBLISHED_S_GAMMA.a2, rel=1e-6)
    assert fit.s_gamma.s0 == pytest.approx(PUBLISHED_S_GAMMA.s0, rel=1e-6)
    g = np.linspace(0, 3, 40)
    np.testing.assert_allclose(fit.s_gamma(g), PUBLISHED_S_GAMMA(g), rtol=1e-6)


def test_fit_s_gamma_rejects_degenerate_input():
    with pytest.raises(ValueError, match="distinct"):
        fit_s_gamma([0.2, -0.2, 0.2], [0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="point 1"):
        fit_s_gamma([0.1, np.nan, 0.3], [0.2, 0.2, 0.2])
    with pytest.raises(ValueError):
        SGamma(0.02, -0.1, 0.039)


CAL_COMBOS_RPM = [(80, 40), (100, 50), (140, 60), (60, 40), (120, 100), (40, 80), (50, 100), (60, 140), (40, 60),
                  (100, 120), (150, 50)]


@pytest.fixture(scope="module")
def calibration_runs() -> list[Run]:
    """11 steady turns (Sec. V-B), alternating 'concrete' (3 % net slip) and 'sand' (8 %)."""
    runs = []
    for i, (wl, wr) in enumerate(CAL_COMBOS_RPM):
        sens = dataclasses.replace(TESTBED, lam0=0.03 if i % 2 == 0 else 0.08)
        runs.append(synthetic_run(f"cal{i}", 100 + i, sens, knots_rpm=[(0, 0, 0), (1, wl, wr), (11, wl, wr)]))
    return runs


def test_reference_points_match_truth(calibration_runs):
    """Per-run (gamma, S) from the noisy 31 Hz reference (eq. (7), (40)) within 0.002 / 5 mm of truth."""
    for run in calibration_runs:
        gamma, s, n = reference_s_gamma_point(run.without_truth(), TRACK)
        m = run.t > 3.0
        vlx = run["truth_vx"][m] - TRACK / 2 * run["truth_wz"][m]
        vrx = run["truth_vx"][m] + TRACK / 2 * run["truth_wz"][m]
        assert gamma == pytest.approx(np.median((vlx - vrx) / (vlx + vrx)), abs=2e-3), run.id
        assert s == pytest.approx(np.median(run["truth_x_icr"][m]), abs=5e-3), run.id
        assert n > 100


def test_calibrate_recovers_s_gamma_curve(calibration_runs):
    """calibrate() on 11 reference runs (concrete + sand) recovers the S(gamma) used to generate
    them: curve within 3 mm over the calibrated gamma range, a1/a2 within 3 %."""
    m = registry.calibrate(ekf_v3(), calibration_runs)
    assert len(m.calibration_points) == 11
    true = SGamma(*TRUE_S)
    g = np.linspace(0.0, 0.4, 41)
    assert np.max(np.abs(m.s_gamma(g) - true(g))) < 3e-3
    assert m.s_gamma.a1 == pytest.approx(true.a1, rel=0.03)
    assert m.s_gamma.a2 == pytest.approx(true.a2, rel=0.03)
    with pytest.raises(registry.CalibrationLeak):
        registry.estimate(m, calibration_runs[0])


def test_calibrate_needs_turning_runs():
    runs = [synthetic_run("straight", s) for s in (1, 2)]
    with pytest.raises(RunError, match="turning runs"):
        ekf_v3().calibrate([r.without_truth() for r in runs])
    assert ekf_v1().calibrate([r.without_truth() for r in runs]) == ekf_v1()  # v1/v2 do not use S


# ------------------------------------------------------------------------------------------
# The filter against an independent implementation (FilterPy EKF, numerical Jacobians)
# ------------------------------------------------------------------------------------------
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
            if variant >= 2:  # eq. (14)
                pl = max(lam[0], 0) if wl >= wr else min(lam[0], 0)
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


# ------------------------------------------------------------------------------------------
# Behaviour on the synthetic paths (Figs. 5-7)
# ------------------------------------------------------------------------------------------
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


# ------------------------------------------------------------------------------------------
# Consistent configuration (not the paper's): noise identified on calibration runs
# ------------------------------------------------------------------------------------------
def _ar1(rng: np.random.Generator, n: int, dt: float, tau: float, sigma: float) -> np.ndarray:
    """Stationary AR(1) sample path, b(k) = a b(k-1) + w, a = exp(-dT/tau), std sigma (stationary start)."""
    from scipy.signal import lfilter

    a = math.exp(-dt / tau)
    return lfilter([1.0], [1.0, -a], rng.standard_normal(n) * sigma * math.sqrt(1 - a * a),
                   zi=[a * sigma * rng.standard_normal()])[0]


WINDOWS = (2.0, 4.0, 8.0, 16.0)


def test_gauss_markov_fit_of_a_bias_is_the_long_correlation_limit():
    """A constant bias (0.02 m/s) plus white noise (sd 0.01): the mean is kept, so sigma is the bias, the
    correlation time is at its upper bound (100 x the longest window: a bias), and the white part comes back."""
    rng = np.random.default_rng(3)
    runs = [0.02 + 0.01 * rng.standard_normal(20_000) for _ in range(3)]
    fit = gauss_markov_fit(runs, 0.008, WINDOWS)
    assert fit.sigma == pytest.approx(0.02, rel=0.03)
    assert fit.tau == pytest.approx(100 * max(WINDOWS), rel=1e-6)
    assert fit.white == pytest.approx(0.01, rel=0.05)
    with pytest.raises(ValueError, match="must be > 0"):
        gauss_markov_fit(runs, 0.0, WINDOWS)
    with pytest.raises(ValueError, match="at least 2 windows"):
        gauss_markov_fit(runs, 0.008, (2.0,))


def test_reference_body_velocity_noise_matches_its_stated_variance():
    """The reference-derived body velocity (Savitzky-Golay, 1 s, quadratic, turn gain divided out) against the
    closed-form truth on a steady turn: unbiased (the uncorrected filter is ~0.6 % low at this yaw rate), and its
    error variance is the stated pos_noise^2 sum(c_k^2) (within 30 %)."""
    run = synthetic_run("circle", 11)
    t = run.t
    vx, vy, var = reference_body_velocity(run.without_truth(), t)
    m = (t > 3.0) & (t < t[-1] - 1.0)
    ex, ey = vx[m] - run["truth_vx"][m], vy[m] - run["truth_vy"][m]
    assert abs(ex.mean()) < 1e-3 and abs(ey.mean()) < 1e-3
    assert 0.5 * (ex.var() + ey.var()) == pytest.approx(var, rel=0.3)
    assert var > 0


@pytest.fixture(scope="module")
def consistent_runs() -> list[Run]:
    """Four steady turns of the calibration set (concrete 3 % / sand 8 % net slip)."""
    out = []
    for i in (0, 3, 6, 9):
        wl, wr = CAL_COMBOS_RPM[i]
        sens = dataclasses.replace(TESTBED, lam0=0.03 if i % 2 == 0 else 0.08)
        out.append(synthetic_run(f"cal{i}", 100 + i, sens, knots_rpm=[(0, 0, 0), (1, wl, wr), (11, wl, wr)]))
    return out


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


def test_gauss_markov_fit_of_white_noise_has_no_correlated_part():
    """Pure white noise (sd 0.05, 100 seeds of 6000 samples): closed form V(W) = sd^2 / W at every window, which
    the white part alone gives, so the correlated part is ~0: its low-frequency share sigma^2 g(a, W) at the 2 s
    window stays below 3 sd of the sampling error of V(2 s) (sd^2 / W sqrt(2 W / N) for overlapping windows,
    generous), and the white part is the sd."""
    rng = np.random.default_rng(7)
    dt, sd, n = 0.008, 0.05, 6000
    w = int(round(2.0 / dt))
    for _ in range(100):
        e = sd * rng.standard_normal(n)
        fit = gauss_markov_fit([e], dt, WINDOWS)
        share = fit.sigma**2 * ar1_mean_var_factor(math.exp(-dt / fit.tau), w)
        assert share <= 3.0 * sd**2 / w * math.sqrt(2.0 * w / n) * 3.0
        assert fit.white == pytest.approx(sd, rel=0.05)


def test_gauss_markov_fit_of_a_fast_error_keeps_its_low_frequency_power_and_variance():
    """AR(1) with tau = 0.1 s (below the resolution of the 2-16 s windows) and variance 0.04^2: tau is held at its
    lower bound (1 s, half the shortest window), the fitted model reproduces the measured moving-mean variances at
    every window within 25 % (the low-frequency power a filter integrates; a 1 s Gauss-Markov's moving-mean variance
    falls more slowly than a 0.1 s one's between 2 and 16 s, so the log-fit splits the difference), and
    sigma^2 + white^2 is the variance."""
    rng = np.random.default_rng(5)
    dt, tau, sigma = 0.008, 0.1, 0.04
    series = [_ar1(rng, 8000, dt, tau, sigma) for _ in range(10)]
    fit = gauss_markov_fit(series, dt, WINDOWS)
    assert fit.tau == pytest.approx(0.5 * min(WINDOWS), rel=1e-6)
    a = math.exp(-dt / fit.tau)
    for wsec in WINDOWS:
        w = int(round(wsec / dt))
        model = fit.sigma**2 * ar1_mean_var_factor(a, w) + fit.white**2 / w
        assert model == pytest.approx(moving_mean_var(series, w), rel=0.25), wsec
    assert fit.sigma**2 + fit.white**2 == pytest.approx(sigma**2, rel=0.05)


def test_gauss_markov_fit_masked_steps_keep_windows_in_time_and_floor_the_white_part():
    """NaN-masked steps (every other sample) with windows allowed at >= 45 % finite samples leave the AR(1) fit
    unchanged in time units (windows are counted on the full grid, not in the surviving samples); without the
    allowance no window is complete (clear error); a white floor above the true white sd is applied and flagged."""
    rng = np.random.default_rng(11)
    dt, tau, sigma = 0.008, 3.0, 0.04
    series = [_ar1(rng, 8000, dt, tau, sigma) + 0.002 * rng.standard_normal(8000) for _ in range(30)]
    masked = [np.where(np.arange(e.size) % 2 == 0, e, np.nan) for e in series]
    fit = gauss_markov_fit(masked, dt, WINDOWS, white_floor=0.01, min_fraction=0.45)
    full = gauss_markov_fit(series, dt, WINDOWS)
    assert fit.tau == pytest.approx(full.tau, rel=0.05) and fit.sigma == pytest.approx(full.sigma, rel=0.05)
    assert fit.tau == pytest.approx(tau, rel=0.3) and fit.sigma == pytest.approx(sigma, rel=0.15)
    assert fit.white == 0.01 and fit.white_floored
    assert not full.white_floored
    with pytest.raises(ValueError, match="no window"):
        gauss_markov_fit(masked, dt, WINDOWS)  # every window has half its samples masked


def test_gm_filter_rows_feedback_is_yi_13_and_state_is_the_no_slip_row():
    """The v_x rows run_filter_gm reports as fused: "feedback" = Yi's (13) with the constrained slips (14) of the
    previous posterior, rebuilt here with constrained_slip from the output slips; "state" = the no-slip row
    r (w_L + w_R)/2 at every encoder step (written out here), so that scheme 2 with "state" is scheme 1 (same
    states to the last bit); scheme 3 "state" evaluates gamma (40) with the raw wheel speeds; v_y NaN unless scheme 3."""
    run = synthetic_run("figure8", 3).without_truth()
    t, acc, gyr, enc = align_inputs(run)
    p = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.05, 2.0, 0.01), gm_y=GaussMarkov(0.03, 2.0, 0.01))
    fb, _, rows_fb = run_filter_gm(t, acc, gyr, enc, variant=2, slip_rows="feedback", **kw)
    lam = np.vstack((np.zeros((1, 2)), np.nan_to_num(fb.slip[:-1])))
    pl, pr = constrained_slip(lam[:, 0], lam[:, 1], enc[:, 0], enc[:, 1])
    want = 0.5 * R_WHEEL * (enc[:, 0] * (1 - pl) + enc[:, 1] * (1 - pr))
    want[0] = np.nan  # step 0 is the initial state, nothing fused
    assert np.allclose(rows_fb[:, 0], want, rtol=0, atol=1e-12, equal_nan=True)
    assert np.isnan(rows_fb[:, 1]).all()
    st1, b1, rows1 = run_filter_gm(t, acc, gyr, enc, variant=1, slip_rows="state", **kw)
    st2, b2, rows2 = run_filter_gm(t, acc, gyr, enc, variant=2, slip_rows="state", **kw)
    no_slip = 0.5 * R_WHEEL * (enc[:, 0] + enc[:, 1])
    no_slip[0] = np.nan
    assert np.array_equal(rows2[:, 0], no_slip, equal_nan=True) and np.array_equal(rows1, rows2, equal_nan=True)
    assert np.array_equal(st1.state, st2.state) and np.array_equal(b1, b2)
    st3, _, rows3 = run_filter_gm(t, acc, gyr, enc, variant=3, slip_rows="state", **kw)
    k = np.flatnonzero(np.abs(enc[:, 0] - enc[:, 1]) > 1.0)[5]
    gam = abs((enc[k, 0] - enc[k, 1]) / (enc[k, 0] + enc[k, 1]))
    assert st3.s_icr[k] == pytest.approx(PUBLISHED_S_GAMMA.a1 / (PUBLISHED_S_GAMMA.a2 * gam + PUBLISHED_S_GAMMA.a3),
                                         rel=1e-12)
    assert np.isfinite(rows3[1:, 1]).all()
    with pytest.raises(ValueError, match="slip_rows"):
        run_filter_gm(t, acc, gyr, enc, variant=2, slip_rows="lock", **kw)
    with pytest.raises(ValueError, match="enc_quant"):
        run_filter_gm(t, acc, gyr, enc, variant=2, enc_quant=-1.0, **kw)

def test_fit_traction_slip_recovers_the_generating_coefficients():
    """Residuals built as c_f f_x + c_w |w_z| + AR(1) (sigma 0.002, tau 3 s) + white (0.01, the quantisation level),
    with the features seen through IMU-level noise (0.05 m/s^2, 0.005 rad/s) as the filter sees them: the 2 s
    moving-mean least squares recovers (c_f, c_w) within 5 % (the noise on the features averages to ~0.003 m/s^2
    over a window against a feature spread of ~0.2 m/s^2, so the errors-in-variables attenuation is < 0.1 %), and
    the explained share is reported (rms_after well below rms_before)."""
    rng = np.random.default_rng(11)
    dt, n, c_f, c_w = 0.008, 7500, 0.03, -0.004
    res, feats = [], []
    for _ in range(6):
        tt = np.arange(n) * dt
        f_x = 0.3 * np.sin(2 * np.pi * tt / rng.uniform(4, 9)) * np.sin(2 * np.pi * tt / rng.uniform(15, 25))
        w_z = 0.5 * np.sin(2 * np.pi * tt / rng.uniform(10, 20) + rng.uniform(0, 6))
        e = c_f * f_x + c_w * np.abs(w_z) + _ar1(rng, n, dt, 3.0, 0.002) + 0.01 * rng.standard_normal(n)
        e[:100] = np.nan
        res.append(e)
        acc = np.column_stack((f_x + 0.05 * rng.standard_normal(n), np.zeros(n), np.full(n, G)))
        gyr = np.column_stack((np.zeros((n, 2)), w_z + 0.005 * rng.standard_normal(n)))
        feats.append(traction_features(acc, gyr))
    model, info = fit_traction_slip(res, feats, dt)
    assert model.c_f == pytest.approx(c_f, rel=0.05) and model.c_w == pytest.approx(c_w, rel=0.05)
    assert info["rms_after"] < 0.5 * info["rms_before"] and info["window"] == pytest.approx(2.0, abs=dt)
    moving = np.arange(n) % 2 == 0
    off = model.offset(acc, gyr, moving)
    assert np.array_equal(off[~moving], np.zeros(np.count_nonzero(~moving)))
    assert np.allclose(off[moving], (model.c_f * acc[:, 0] + model.c_w * np.abs(gyr[:, 2]))[moving], rtol=0, atol=0)
    with pytest.raises(ValueError, match="no full"):
        fit_traction_slip([np.full(100, np.nan)], [np.zeros((100, 2))], dt)


def test_gm_filter_vx_offset_is_the_row_shifted_by_the_offset():
    """run_filter_gm with ``vx_offset`` o(k) (slip state, scheme 1) equals the filter run on wheel speeds lowered by
    o(k)/r on both sides (the same row r (w_L + w_R)/2 - o, a second way to form it): same states and error state
    to 1e-9; the fused rows are the shifted row.  Offsets with the fed-back slip, of the wrong length or NaN are
    refused, and so is the consistent configuration's traction slip with the fed-back slip."""
    run = synthetic_run("figure8", 3).without_truth()
    t, acc, gyr, enc = align_inputs(run)
    p = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.005, 2.0, 0.01), variant=1, slip_rows="state")
    off = 0.03 * acc[:, 0] - 0.004 * np.abs(gyr[:, 2])
    a, ba, rows_a = run_filter_gm(t, acc, gyr, enc, vx_offset=off, **kw)
    b, bb, rows_b = run_filter_gm(t, acc, gyr, enc - (off / R_WHEEL)[:, None], **kw)
    assert np.allclose(a.state, b.state, rtol=0, atol=1e-9) and np.allclose(ba, bb, rtol=0, atol=1e-9)
    assert np.allclose(rows_a[1:, 0], 0.5 * R_WHEEL * (enc[1:, 0] + enc[1:, 1]) - off[1:], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="vx_offset"):
        run_filter_gm(t, acc, gyr, enc, vx_offset=off, **{**kw, "slip_rows": "feedback", "variant": 2})
    with pytest.raises(ValueError, match="vx_offset"):
        run_filter_gm(t, acc, gyr, enc, vx_offset=off[:-1], **kw)
    with pytest.raises(ValueError, match="vx_offset"):
        run_filter_gm(t, acc, gyr, enc, vx_offset=np.where(np.arange(t.size) == 7, np.nan, off), **kw)
    with pytest.raises(ValueError, match="traction_slip"):
        ekf_v2_consistent(slip_rows="feedback")
    assert not ekf_v2_consistent(slip_rows="feedback", traction_slip=False, odometer_window=0.0).traction_slip
    with pytest.raises(ValueError, match="odometer_window"):  # the odometer sums rows that must not use the filter
        ekf_v2_consistent(slip_rows="feedback", traction_slip=False)


def test_fit_icr_correction_recovers_the_generating_coefficients():
    """v_y row residuals built as (c_0 + c_1 v |w_z|) w_z + AR(1) (sigma 0.002, tau 3 s) + white (0.005), with the
    yaw rate seen through gyro-level noise (0.005 rad/s) and the speed through 2000-count encoders' quantisation as
    the filter sees them: the 2 s moving-mean least squares recovers (c_0, c_1) within 5 %; the offset is
    (c_0 + c_1 v |w_z|) w_z on the moving steps and 0 elsewhere."""
    rng = np.random.default_rng(12)
    dt, n, c_0, c_1 = 0.008, 7500, -0.12, 0.08
    res, feats = [], []
    for _ in range(6):
        tt = np.arange(n) * dt
        v = 0.3 + 0.25 * np.sin(2 * np.pi * tt / rng.uniform(20, 40))
        w_z = 0.6 * np.sin(2 * np.pi * tt / rng.uniform(10, 20) + rng.uniform(0, 6))
        e = (c_0 + c_1 * v * np.abs(w_z)) * w_z + _ar1(rng, n, dt, 3.0, 0.002) + 0.005 * rng.standard_normal(n)
        e[:100] = np.nan
        res.append(e)
        q = 2 * np.pi / 2000 * 125.0  # one count per sample [rad/s]
        enc = np.round(np.column_stack((v, v)) / R_WHEEL / q + rng.uniform(-0.5, 0.5, (n, 2))) * q
        gyr = np.column_stack((np.zeros((n, 2)), w_z + 0.005 * rng.standard_normal(n)))
        feats.append(icr_features(gyr, enc, R_WHEEL))
    model, info = fit_icr_correction(res, feats, dt)
    assert model.c_0 == pytest.approx(c_0, rel=0.05) and model.c_1 == pytest.approx(c_1, rel=0.05)
    assert info["rms_after"] < 0.5 * info["rms_before"]
    moving = np.arange(n) % 2 == 0
    off = model.offset(gyr, enc, R_WHEEL, moving)
    assert np.array_equal(off[~moving], np.zeros(np.count_nonzero(~moving)))
    v_enc = 0.5 * R_WHEEL * (enc[:, 0] + enc[:, 1])
    expect = (model.c_0 + model.c_1 * v_enc * np.abs(gyr[:, 2])) * gyr[:, 2]
    assert np.allclose(off[moving], expect[moving], rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="fit_icr_correction: no full"):
        fit_icr_correction([np.full(100, np.nan)], [np.zeros((100, 2))], dt)


def test_gm_filter_vy_offset_is_subtracted_from_the_fused_row_and_refused_where_undefined():
    """run_filter_gm with ``vy_offset`` o(k) (scheme 3): with the v_y row given no weight (white 1e6 m/s) the states
    are those without the offset (1e-9) and the fused v_y row is the row without it minus o(k) at every fused step
    (1e-12); with weight, the estimate changes; offsets outside scheme 3, of the wrong length or NaN are refused,
    and so is the consistent configuration's S correction with the fed-back slip."""
    run = synthetic_run("figure8", 3).without_truth()
    t, acc, gyr, enc = align_inputs(run)
    p = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.005, 2.0, 0.01), gm_y=GaussMarkov(0.01, 2.0, 0.005), variant=3, slip_rows="state")
    off = -0.1 * gyr[:, 2]
    weightless = {**kw, "gm_y": GaussMarkov(1e-9, 2.0, 1e6)}  # the v_y row without weight: same states either way
    a, _, rows_a = run_filter_gm(t, acc, gyr, enc, vy_offset=off, **weightless)
    b, _, rows_b = run_filter_gm(t, acc, gyr, enc, **weightless)
    fused = np.isfinite(rows_b[:, 1])
    assert fused.sum() > 0.9 * t.size and np.allclose(a.state, b.state, rtol=0, atol=1e-9)
    assert np.allclose(rows_a[fused, 1], rows_b[fused, 1] - off[fused], rtol=0, atol=1e-12)
    a, _, _ = run_filter_gm(t, acc, gyr, enc, vy_offset=off, **kw)
    b, _, _ = run_filter_gm(t, acc, gyr, enc, **kw)
    assert np.max(np.abs(a.v_body[:, 1] - b.v_body[:, 1])) > 0.01
    with pytest.raises(ValueError, match="vy_offset"):
        run_filter_gm(t, acc, gyr, enc, vy_offset=off, **{**kw, "variant": 1})
    with pytest.raises(ValueError, match="vy_offset"):
        run_filter_gm(t, acc, gyr, enc, vy_offset=off[:-1], **kw)
    with pytest.raises(ValueError, match="vy_offset"):
        run_filter_gm(t, acc, gyr, enc, vy_offset=np.where(np.arange(t.size) == 7, np.nan, off), **kw)
    with pytest.raises(ValueError, match="icr_correction"):
        ekf_v3_consistent(slip_rows="feedback", traction_slip=False)
    ekf_v2_consistent(slip_rows="feedback", traction_slip=False, odometer_window=0.0)  # the S correction: scheme 3
    with pytest.raises(ValueError, match="needs scheme 3"):
        ekf_v2_consistent(icr=IcrCorrection(0.1, 0.0))
    with pytest.raises(ValueError, match="needs scheme 3"):
        ekf_v3_consistent(icr=IcrCorrection(0.1, 0.0), icr_correction=False)


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


def test_gauss_markov_fit_recovers_a_known_ar1_plus_white_model():
    """Residuals generated as b(k) = a b(k-1) + w (a = exp(-dT/tau), stationary std sigma) plus white noise: the
    moving-mean fit recovers sigma, tau and the white part (white^2 = C(0) - sigma^2 is a difference, resolved when
    white is not small against sigma); ar1_mean_var_factor (the closed form of the variance of a W-sample mean of a
    unit AR(1)) is checked against a simulation."""
    rng = np.random.default_rng(5)
    dt, tau, sigma, white = 0.008, 1.5, 0.04, 0.03
    series = [_ar1(rng, 8000, dt, tau, sigma) + white * rng.standard_normal(8000) for _ in range(40)]
    fit = gauss_markov_fit(series, dt, WINDOWS)
    assert fit.sigma == pytest.approx(sigma, rel=0.15)
    assert fit.tau == pytest.approx(tau, rel=0.3)
    assert fit.white == pytest.approx(white, rel=0.2)
    ar = [_ar1(rng, 8000, dt, tau, 1.0) for _ in range(40)]
    assert ar1_mean_var_factor(math.exp(-dt / tau), 250) == pytest.approx(moving_mean_var(ar, 250), rel=0.1)
    assert ar1_mean_var_factor(0.0, 7) == pytest.approx(1 / 7, rel=1e-12)
    assert ar1_mean_var_factor(1.0, 7) == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(ValueError, match="must be finite and > 0"):
        GaussMarkov(0.0, 1.0, 0.01)


def test_gauss_markov_fit_subtracts_a_known_moving_average_error():
    """AR(1) (sigma 0.004, tau 3 s) plus a count-difference error u_k - u_(k-1) (u white, sd 0.007, as the encoder
    quantisation) plus white (0.003): given the known share of the count difference (2 sd^2 / W^2 for a W-sample mean,
    2 sd^2 at lag 0), the fit recovers the AR(1) and a white part without the count difference; without it the
    white part absorbs it (sigma^2 + white^2 = total variance)."""
    rng = np.random.default_rng(9)
    dt, sq = 0.008, 0.007
    series = []
    for _ in range(30):
        u = sq * rng.standard_normal(8001)
        series.append(_ar1(rng, 8000, dt, 3.0, 0.004) + np.diff(u) + 0.003 * rng.standard_normal(8000))
    fit = gauss_markov_fit(series, dt, WINDOWS, known_var=lambda w: 2 * sq * sq / (w * w))
    assert fit.sigma == pytest.approx(0.004, rel=0.2) and fit.tau == pytest.approx(3.0, rel=0.4)
    assert fit.white == pytest.approx(0.003, rel=0.15)
    blind = gauss_markov_fit(series, dt, WINDOWS)
    assert blind.white**2 + blind.sigma**2 == pytest.approx(moving_mean_var(series, 1), rel=1e-9)
    assert blind.white == pytest.approx(math.sqrt(0.003**2 + 2 * sq * sq), rel=0.15)


@pytest.mark.parametrize("variant", [1, 2, 3])
def test_gm_filter_with_a_vanishing_error_state_is_the_paper_filter(variant):
    """run_filter_gm with a negligible Gauss-Markov state (sigma 1e-9 m/s) and the paper's white R is the paper's
    run_filter (second implementation): same states, velocities and slips to 1e-7."""
    run = synthetic_run("figure8", 4).without_truth()
    t, acc, gyr, enc = align_inputs(run)
    p = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, variant=variant, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0)
    ref = run_filter(t, acc, gyr, enc, **kw)
    got, b, _ = run_filter_gm(t, acc, gyr, enc, gm_x=GaussMarkov(1e-9, 1.0, R_WHEEL * p.sigma_enc),
                              gm_y=GaussMarkov(1e-9, 1.0, p.sigma_vy), **kw)  # defaults: Yi's rows
    assert b.shape == (t.size, 2 if variant == 3 else 1) and np.max(np.abs(b)) < 1e-6
    assert np.allclose(got.state, ref.state, atol=1e-7, rtol=0)
    assert np.allclose(got.slip, ref.slip, atol=1e-6, rtol=0, equal_nan=True)
    assert got.n_updates == ref.n_updates


def _level_rest(n: int = 300, dt: float = 0.008):
    """Inputs of the level-rest linear case: IMU reading exactly gravity, encoders reading 0."""
    t = np.arange(n) * dt
    acc = np.tile([0.0, 0.0, G], (n, 1))
    p = EkfParams()
    enc = np.zeros((n, 2))
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    return t, acc, np.zeros((n, 3)), enc, p, x0, p0


def _level_rest_kalman(p: EkfParams, p0: np.ndarray, gm: GaussMarkov, dt: float, nq: int = 0):
    """FilterPy KalmanFilter of the level-rest case written out from the model (strapdown at zero attitude:
    dV/dtheta = g, dV_y/dphi = -g; b(k) = exp(-dT/tau) b(k-1), Q_b = sigma^2 (1 - a^2); rows v_x = V_x + b
    (R = white^2) and v_z = V_z (R = sigma_vz^2)); ``nq`` extra states with zero blocks for the caller to fill."""
    from filterpy.kalman import KalmanFilter

    nx = 10 + nq
    a = math.exp(-dt / gm.tau)
    kf = KalmanFilter(dim_x=nx, dim_z=2)
    F = np.eye(nx)
    F[0, 3] = F[1, 4] = F[2, 5] = dt
    F[3, 7], F[4, 6], F[9, 9] = dt * G, -dt * G, a
    kf.F = F
    kf.Q = np.diag([p.pos_noise**2] * 3 + [(p.accel_noise * dt) ** 2] * 3 + [(p.gyro_noise * dt) ** 2] * 3
                   + [gm.sigma**2 * (1 - a * a)] + [0.0] * nq)
    kf.H = np.zeros((2, nx))
    kf.H[0, 3] = kf.H[0, 9] = 1.0
    kf.H[1, 5] = 1.0
    kf.R = np.diag([gm.white**2, p.sigma_vz**2])
    kf.P = np.diag(list(np.diag(p0)) + [gm.sigma**2] + [0.0] * nq)
    kf.x = np.zeros(nx)
    return kf


def test_gm_filter_covariance_equals_filterpy_on_the_linear_level_rest_case():
    """Robot level and at rest, IMU reading exactly gravity, encoders reading 0: the EKF state stays 0, so its
    covariance follows the linear Kalman recursion with F, Q, H, R written out from the model
    (:func:`_level_rest_kalman`), computed by FilterPy's KalmanFilter (Joseph update).  Without encoder rows the
    error state keeps its stationary variance sigma^2."""
    t, acc, gyr, enc, p, x0, p0 = _level_rest()
    n, dt = t.size, float(t[1] - t[0])
    gm = GaussMarkov(0.03, 0.7, 0.012)
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, variant=1, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=gm, store_cov=True)
    res, b, _ = run_filter_gm(t, acc, gyr, enc, **kw)
    assert np.all(res.state == 0.0) and np.all(b == 0.0)
    kf = _level_rest_kalman(p, p0, gm, dt)
    assert np.allclose(res.cov[0], kf.P, rtol=0, atol=1e-15)
    for k in range(1, n):
        kf.predict()
        kf.update(np.zeros(2))
        assert np.allclose(res.cov[k], kf.P, rtol=1e-8, atol=1e-14), k
    res2, _, _ = run_filter_gm(t, acc, gyr, np.full((n, 2), np.nan), **kw)
    assert np.allclose(res2.cov[:, 9, 9], gm.sigma**2, rtol=1e-12, atol=0)


def test_gm_filter_quantisation_states_equal_filterpy_with_the_shift_as_prediction():
    """The level-rest linear case of the previous test with quantisation states (enc_quant 0.007 m/s): FilterPy's
    KalmanFilter with the two residuals as ordinary states, u_prev <- u and a fresh u ~ N(0, enc_quant^2) written
    as its prediction (F block [[0, 1], [0, 0]], Q diag(0, enc_quant^2)) and the row v_x = V_x + b + u - u_prev
    (second implementation: run_filter_gm resets u before and shifts it after each fused row).  The 10 states
    other than the residuals agree at every step; run_filter_gm's u_prev after the shift is FilterPy's u."""
    t, acc, gyr, enc, p, x0, p0 = _level_rest()
    n, sq = t.size, 0.007
    gm = GaussMarkov(0.03, 0.7, 0.004)
    res, _, _ = run_filter_gm(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=1,
                              s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0, gm_x=gm, store_cov=True, enc_quant=sq)
    assert res.cov.shape == (n, 12, 12) and np.all(res.state == 0.0)
    kf = _level_rest_kalman(p, p0, gm, float(t[1] - t[0]), nq=2)
    kf.F[10, 10], kf.F[10, 11], kf.F[11, 11] = 0.0, 1.0, 0.0
    kf.Q[11, 11] = sq * sq
    kf.H[0, 11], kf.H[0, 10] = 1.0, -1.0
    kf.P[10, 10] = kf.P[11, 11] = sq * sq
    for k in range(1, n):
        kf.predict()
        kf.update(np.zeros(2))
        assert np.allclose(res.cov[k][:10, :10], kf.P[:10, :10], rtol=1e-8, atol=1e-14), k
        assert np.allclose(res.cov[k][10, :10], kf.P[11, :10], rtol=1e-8, atol=1e-14), k
        assert res.cov[k][10, 10] == pytest.approx(kf.P[11, 11], rel=1e-8)


def test_gm_filter_with_a_per_step_sigma_and_skipped_rows_equals_filterpy():
    """The level-rest linear case with the Gauss-Markov std changing per step (``gm_sigma``: 0.01 m/s, then 0.05)
    and the v_x row skipped on steps 100-159 (``vx_skip``): FilterPy's KalmanFilter with Q_b(k) = sigma_k^2 (1 - a^2)
    set before each prediction and, on the skipped steps, the v_z row alone (second implementation).  Covariances
    agree at every step; a constant gm_sigma equal to the model's sigma gives the filter without it, bit for bit."""
    t, acc, gyr, enc, p, x0, p0 = _level_rest()
    n, dt = t.size, float(t[1] - t[0])
    gm = GaussMarkov(0.01, 0.7, 0.012)
    sig = np.where(np.arange(n) < 150, 0.01, 0.05)[:, None]
    skip = (np.arange(n) >= 100) & (np.arange(n) < 160)
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, variant=1, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=gm, store_cov=True)
    res, _, rows = run_filter_gm(t, acc, gyr, enc, gm_sigma=sig, vx_skip=skip, **kw)
    assert np.isnan(rows[skip, 0]).all() and np.isfinite(rows[1:][~skip[1:], 0]).all()
    assert res.n_updates[0] == n - 1 - int(skip.sum())
    kf = _level_rest_kalman(p, p0, gm, dt)
    a = math.exp(-dt / gm.tau)
    for k in range(1, n):
        kf.Q[9, 9] = sig[k, 0] ** 2 * (1 - a * a)
        kf.predict()
        if skip[k]:
            kf.update(np.zeros(1), R=kf.R[1:, 1:], H=kf.H[1:])
        else:
            kf.update(np.zeros(2))
        assert np.allclose(res.cov[k], kf.P, rtol=1e-8, atol=1e-14), k
    same, _, _ = run_filter_gm(t, acc, gyr, enc, gm_sigma=np.full((n, 1), gm.sigma), **kw)
    plain, _, _ = run_filter_gm(t, acc, gyr, enc, **kw)
    np.testing.assert_array_equal(same.cov, plain.cov)
    with pytest.raises(ValueError, match="gm_sigma needs shape"):
        run_filter_gm(t, acc, gyr, enc, gm_sigma=np.full((n, 2), 0.01), **kw)
    with pytest.raises(ValueError, match="vx_skip needs shape"):
        run_filter_gm(t, acc, gyr, enc, vx_skip=skip[:-1], **kw)


def test_scheme3_skipped_vy_rows_equal_filterpy():
    """Scheme 3 in the level-rest linear case with the v_y row (15) skipped on steps 80-139 (``vy_skip``) and the v_x
    row on steps 100-119: FilterPy's KalmanFilter (second implementation) with b_y as an 11th state (a_y, Q_by) and,
    per step, the rows that are fused (v_x = V_x + b_x, v_y = V_y + b_y, v_z = V_z at zero attitude).  Covariances
    agree at every step; b_y keeps its propagation while its row is off; vy_skip needs scheme 3."""
    from filterpy.kalman import KalmanFilter

    t, acc, gyr, enc, p, x0, p0 = _level_rest()
    n, dt = t.size, float(t[1] - t[0])
    gx, gy = GaussMarkov(0.01, 0.7, 0.012), GaussMarkov(0.004, 0.4, 0.002)
    skip_x = (np.arange(n) >= 100) & (np.arange(n) < 120)
    skip_y = (np.arange(n) >= 80) & (np.arange(n) < 140)
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, variant=3, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=gx, gm_y=gy, store_cov=True, slip_rows="state")
    res, _, rows = run_filter_gm(t, acc, gyr, enc, vx_skip=skip_x, vy_skip=skip_y, **kw)
    assert np.isnan(rows[skip_y, 1]).all() and np.isfinite(rows[1:][~skip_y[1:], 1]).all()
    assert res.n_updates[:2] == (n - 1 - int(skip_x.sum()), n - 1 - int(skip_y.sum()))
    ax_, ay_ = math.exp(-dt / gx.tau), math.exp(-dt / gy.tau)
    kf = KalmanFilter(dim_x=11, dim_z=3)
    F = np.eye(11)
    F[0, 3] = F[1, 4] = F[2, 5] = dt
    F[3, 7], F[4, 6], F[9, 9], F[10, 10] = dt * G, -dt * G, ax_, ay_
    kf.F = F
    kf.Q = np.diag([p.pos_noise**2] * 3 + [(p.accel_noise * dt) ** 2] * 3 + [(p.gyro_noise * dt) ** 2] * 3
                   + [gx.sigma**2 * (1 - ax_ * ax_), gy.sigma**2 * (1 - ay_ * ay_)])
    h_all = np.zeros((3, 11))
    h_all[0, 3] = h_all[0, 9] = h_all[1, 4] = h_all[1, 10] = h_all[2, 5] = 1.0
    r_all = np.array([gx.white**2, gy.white**2, p.sigma_vz**2])
    kf.P = np.diag(list(np.diag(p0)) + [gx.sigma**2, gy.sigma**2])
    kf.x = np.zeros(11)
    for k in range(1, n):
        kf.predict()
        use = [i for i, off in enumerate((skip_x[k], skip_y[k], False)) if not off]
        kf.update(np.zeros(len(use)), R=np.diag(r_all[use]), H=h_all[use])
        assert np.allclose(res.cov[k], kf.P, rtol=1e-8, atol=1e-14), k
    assert res.cov[139][10, 10] > res.cov[79][10, 10]  # b_y unobserved while its row is off
    with pytest.raises(ValueError, match="vy_skip needs scheme 3"):
        run_filter_gm(t, acc, gyr, enc, **{**kw, "variant": 1, "gm_y": None}, vy_skip=skip_y)
    with pytest.raises(ValueError, match="vy_skip needs scheme 3"):
        run_filter_gm(t, acc, gyr, enc, vy_skip=skip_y[:-1], **kw)


def test_skipped_row_makes_the_previous_quantisation_residual_fresh():
    """With quantisation states, a step whose v_x row is skipped leaves the next row's u_(k-1) a fresh residual:
    variance enc_quant^2, uncorrelated with every other state (the count residual of a sample no row has used)."""
    t, acc, gyr, enc, p, x0, p0 = _level_rest(n=60)
    sq = 0.007
    skip = np.zeros(t.size, bool)
    skip[30] = True
    res, _, _ = run_filter_gm(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=1,
                              s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0, gm_x=GaussMarkov(0.03, 0.7, 0.004),
                              store_cov=True, enc_quant=sq, vx_skip=skip)
    row = res.cov[30][10]
    assert row[10] == pytest.approx(sq * sq, rel=1e-12) and np.all(np.delete(row, 10) == 0.0)
    assert np.any(res.cov[29][10, :10] != 0.0)  # after a fused row u_prev is correlated with the velocity


def test_traction_transient_gate_closed_form():
    """f_x of 2 m/s^2 for 0.2 s at 100 Hz: the 0.1 s (10-sample) trailing mean exceeds a 0.5 m/s^2 gate while the
    window holds at least 3 pulse samples (0.6 > 0.5 > 0.4), samples 102-126, and the gate stays shut 0.3 s
    (30 samples) longer, to 156; gate 0: never."""
    dt, n = 0.01, 400
    t = np.arange(n) * dt
    acc = np.zeros((n, 3))
    acc[100:120, 0] = 2.0
    want = np.zeros(n, bool)
    want[102:157] = True
    np.testing.assert_array_equal(traction_transient(acc, t, 0.5), want)
    np.testing.assert_array_equal(traction_transient(-acc, t, 0.5), want)  # braking as well
    assert not traction_transient(acc, t, 0.0).any() and not traction_transient(acc, t, 2.5).any()


def test_gm_sigma_steps_scales_with_the_trailing_yaw_rate():
    """A per_yaw_rate Gauss-Markov std is sigma x the trailing mean of |w_z| over YAW_RATE_SCALE_SECONDS (closed form
    on a constant turn of -0.4 rad/s after the window fills; 0 rad/s gives the floor), a constant one stays sigma,
    and no per_yaw_rate error means no per-step sigma (None)."""
    dt, n = 0.008, 400
    t = np.arange(n) * dt
    gyr = np.zeros((n, 3))
    gyr[200:, 2] = -0.4
    gx, gy = GaussMarkov(0.002, 1.0, 0.01), GaussMarkov(0.003, 2.0, 1e-4, per_yaw_rate=True)
    sig = gm_sigma_steps((gx, gy), yaw_rate_scale(gyr, t))
    w = int(round(YAW_RATE_SCALE_SECONDS / dt))
    np.testing.assert_allclose(yaw_rate_scale(gyr, t)[200 + w:], 0.4, rtol=1e-12)
    assert np.all(sig[:, 0] == 0.002)
    np.testing.assert_allclose(sig[200 + w:, 1], math.hypot(0.003 * 0.4, GM_NEGLIGIBLE_SIGMA), rtol=1e-12)
    np.testing.assert_allclose(sig[:200, 1], GM_NEGLIGIBLE_SIGMA, rtol=1e-12)
    assert gm_sigma_steps((gx,), yaw_rate_scale(gyr, t)) is None
    with pytest.raises(ValueError, match="vx_gate"):
        ekf_v1_consistent(vx_gate=-0.1)


def test_gauss_markov_fit_recovers_a_per_yaw_rate_model():
    """Residuals b(k) = s(k) beta(k) + white, beta a unit AR(1) x sigma, s alternating 20 s at 0.5 rad/s and 20 s at
    0 (turns and straights): the fit with the scale recovers sigma [m per rad/s], tau and the white part; without
    the scale it returns the turn-and-straight average; a scale that is zero everywhere is a clear error."""
    rng = np.random.default_rng(11)
    dt, tau, sigma, white, n = 0.008, 1.5, 0.01, 0.002, 10000
    scale = np.where((np.arange(n) * dt // 20.0) % 2 == 0, 0.5, 0.0)
    series = [scale * _ar1(rng, n, dt, tau, sigma) + white * rng.standard_normal(n) for _ in range(40)]
    fit = gauss_markov_fit(series, dt, WINDOWS, scale=[scale] * len(series))
    assert fit.per_yaw_rate and fit.sigma == pytest.approx(sigma, rel=0.15)
    assert fit.tau == pytest.approx(tau, rel=0.3) and fit.white == pytest.approx(white, rel=0.2)
    flat = gauss_markov_fit(series, dt, WINDOWS)
    assert not flat.per_yaw_rate and flat.sigma == pytest.approx(sigma * 0.5 * math.sqrt(np.mean(scale > 0)), rel=0.15)
    with pytest.raises(ValueError, match="scale is zero"):
        gauss_markov_fit(series, dt, WINDOWS, scale=[np.zeros(n)] * len(series))


def test_encoder_quantisation_from_the_platform_spec():
    """r q rate / sqrt(24) with q = 2 pi / counts_per_rev (the mean of two wheels' uniform count residuals, in m/s);
    a run without the encoder spec is a clear error."""
    run = synthetic_run("straight", 3)
    enc = PLATFORM["sensors"]["encoder"]
    want = R_WHEEL * 2 * math.pi / enc["counts_per_rev"] * enc["rate_hz"] / math.sqrt(24.0)
    assert encoder_quantisation(run) == pytest.approx(want, rel=1e-12)
    meta = copy.deepcopy(dict(run.meta))
    del meta["platform"]["sensors"]["encoder"]
    with pytest.raises(RunError, match="counts_per_rev"):
        encoder_quantisation(Run(run.data, meta))


def test_gm_filter_odometer_equals_filterpy_with_a_resettable_state():
    """The level-rest linear case with the v_x row fused as the odometer (``odo_window`` 25): FilterPy's KalmanFilter
    (second implementation) with d as an 11th state (F row: dT on V_x and on b_x, 1 on d), on the window's last step
    the row z = d (R = odo_sd^2) with v_z, on the others v_z alone, and d reset to 0 with its row and column of P
    after each fused window.  Covariances agree at every step; only the window ends carry a v_x row."""
    t, acc, gyr, enc, p, x0, p0 = _level_rest()
    n, dt, m, sd = t.size, float(t[1] - t[0]), 25, 1e-4
    gm = GaussMarkov(0.03, 0.7, 0.012)
    res, _, rows = run_filter_gm(t, acc, gyr, enc, wheel_radius=R_WHEEL, track=TRACK, variant=1,
                                 s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0, gm_x=gm, store_cov=True,
                                 slip_rows="state", odo_window=m, odo_sd=sd)
    assert res.cov.shape == (n, 11, 11) and np.all(res.state == 0.0)
    ends = (np.arange(n) % m == 0) & (np.arange(n) > 0)
    assert np.isfinite(rows[ends, 0]).all() and np.isnan(rows[~ends, 0]).all() and res.n_updates[0] == ends.sum()
    kf = _level_rest_kalman(p, p0, gm, dt, nq=1)
    kf.F[10, 3] = kf.F[10, 9] = dt
    h_odo = np.zeros((2, 11))
    h_odo[0, 10], h_odo[1, 5] = 1.0, 1.0
    for k in range(1, n):
        kf.predict()
        if ends[k]:
            kf.update(np.zeros(2), R=np.diag([sd * sd, p.sigma_vz**2]), H=h_odo)
            kf.P[10, :] = kf.P[:, 10] = 0.0
        else:
            kf.update(np.zeros(1), R=kf.R[1:, 1:], H=kf.H[1:])
        assert np.allclose(res.cov[k], kf.P, rtol=1e-8, atol=1e-14), k


def test_gm_filter_odometer_follows_a_constant_acceleration_exactly():
    """Level straight line at a = 0.5 m/s^2 from 0.3 m/s, IMU exact, encoders reading the mean speed over each
    sample interval (v0 + a (t_k - dT/2)) / r (no quantisation, no slip): each window's summed rows equal the
    odometer's trapezoid integral of the strapdown velocity, so every innovation is 0 and the velocity is v0 + a t
    to rounding (without the trapezoid's dT/2 term the odometer would lag a dT^2/2 per step, 0.4 mm a window).
    A step without its row (vx_skip at 30) restarts the window after it: the rows are fused at 25, 55, 80, ..."""
    dt, n, a, v0 = 0.008, 400, 0.5, 0.3
    t = np.arange(n) * dt
    acc = np.tile([a, 0.0, G], (n, 1))
    v_mean = np.concatenate(([v0], v0 + a * (t[1:] - dt / 2)))
    enc = np.column_stack((v_mean, v_mean)) / R_WHEEL
    p = EkfParams()
    _, p0 = initial_state(np.tile([0.0, 0.0, G], (n, 1)), np.zeros((n, 2)), R_WHEEL, p, (0.0, 0.0, 0.0))
    x0 = np.array([0.0, 0.0, 0.0, v0, 0.0, 0.0, 0.0, 0.0, 0.0])
    skip = np.zeros(n, bool)
    skip[30] = True
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, variant=1, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.001, 1.0, 0.01), slip_rows="state", imu_mean=True, odo_window=25, odo_sd=1e-4)
    gyr = np.zeros((n, 3))
    res, b, rows = run_filter_gm(t, acc, gyr, enc, vx_skip=skip, **kw)
    np.testing.assert_allclose(res.state[:, 3], v0 + a * t, rtol=0, atol=1e-9)
    assert np.abs(b).max() < 1e-9 and np.abs(res.state[:, 4:9]).max() < 1e-9
    fused = np.flatnonzero(np.isfinite(rows[:, 0]))
    assert fused[:3].tolist() == [25, 55, 80] and np.all(np.diff(fused[1:]) == 25)
    with pytest.raises(ValueError, match="odo_window"):
        run_filter_gm(t, acc, gyr, enc, **{**kw, "slip_rows": "feedback"})
    with pytest.raises(ValueError, match="odo_window"):
        run_filter_gm(t, acc, gyr, enc, enc_quant=0.007, **kw)


def test_odometer_window_rule_and_the_consistent_default():
    """encoder_odometer_sd is (r q)^2 / 12 of the two end counts of both wheels (q = 2 pi / counts_per_rev);
    odometer_min_window gives the shortest whole number of steps with the window's mean-speed quantisation
    sd / T at most a quarter of accel_noise sqrt(T dT) (closed form), 0.176 s on Yi's platform at its 125 Hz and
    0.05 m/s^2; the consistent configuration's 0.2 s default satisfies it, and an odometer excludes the per-step
    options."""
    run = synthetic_run("straight", 3)
    enc = PLATFORM["sensors"]["encoder"]
    rq = R_WHEEL * 2 * math.pi / enc["counts_per_rev"]
    assert encoder_odometer_sd(run) == pytest.approx(rq / math.sqrt(12.0), rel=1e-12)
    dt, sa = 1.0 / enc["rate_hz"], 0.05
    t_min = odometer_min_window(run, sa, dt)
    m = round(t_min / dt)
    assert m == pytest.approx(t_min / dt, abs=1e-9)
    assert rq / math.sqrt(12.0) / (m * dt) <= 0.25 * sa * math.sqrt(m * dt * dt)  # the rule holds at T
    assert rq / math.sqrt(12.0) / ((m - 1) * dt) > 0.25 * sa * math.sqrt((m - 1) * dt * dt)  # and not one step less
    assert t_min == pytest.approx(0.176) and ekf_v1_consistent().odometer_window >= t_min
    for kw in ({"quantisation_states": True}, {"adaptive_white": 2.0}):
        with pytest.raises(ValueError, match="odometer_window"):
            ekf_v1_consistent(**kw)
        ekf_v1_consistent(odometer_window=0.0, **kw)
    with pytest.raises(ValueError, match="odometer_window"):
        ekf_v1_consistent(odometer_window=-0.1)


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


@pytest.fixture(scope="module")
def consistent_v2(consistent_runs):
    return registry.calibrate(ekf_v2_consistent(store_covariance=True), consistent_runs)


def _velocity_nees(run: Run, est) -> float:
    """Time-mean NEES of V_I (x, y) against the closed-form truth after 5 s (written out here)."""
    t = est["t"]
    tyaw = np.interp(t, run.t, run["truth_yaw"])
    tvx, tvy = np.interp(t, run.t, run["truth_vx"]), np.interp(t, run.t, run["truth_vy"])
    ev = np.column_stack((est["vx"], est["vy"]))
    rot = np.array([[[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]] for a in est["yaw"]])
    vi_est = np.einsum("nij,nj->ni", rot, ev)
    vi_true = np.column_stack((np.cos(tyaw) * tvx - np.sin(tyaw) * tvy, np.sin(tyaw) * tvx + np.cos(tyaw) * tvy))
    e = vi_est - vi_true
    m = t >= 5.0
    P = est.info["P"][m][:, 3:5, 3:5]
    return float(np.mean([ei @ np.linalg.solve(Pi, ei) for ei, Pi in zip(e[m], P)]))


def test_consistent_scheme2_nees_far_below_the_overconfident_paper_filter(consistent_v2, consistent_runs):
    """Synthetic circle (testbed sensors, 5 % net slip, not a calibration run): the paper's scheme 2 has a
    velocity NEES far above 2 (v_x (13) with fed-back slip fused as white 125 Hz noise); the consistent
    configuration identified on the steady turns is more than 10x lower.  Not a consistency test (one seed, a
    time mean, and the generator's accelerometer bias of 0.01 m/s^2 is in no filter's model)."""
    run = synthetic_run("circle", 21)
    paper = registry.estimate(Yi2009Ekf(variant=2, store_covariance=True), run)
    cons = registry.estimate(consistent_v2, run)
    n_paper, n_cons = _velocity_nees(run, paper), _velocity_nees(run, cons)
    assert n_paper > 50.0 and n_cons < n_paper / 10.0
    assert cons.info["gm_x"] == dataclasses.asdict(consistent_v2.gm_x)
    assert cons.info["P"].shape == (cons.data.shape[0], 9, 9) and cons.info["P_aug"].shape[1:] == (11, 11)  # b_x, d


def test_consistent_slip_state_not_overconfident_where_the_fed_back_slip_is():
    """Same calibration turns and circle without IMU biases (the filters' IMU model has none): with the slip as the
    b_x state the time-mean velocity NEES is below the chi-square 99.9 % quantile of 2 dof, and below the NEES of the
    same configuration with Yi's fed-back slip (slip_rows="feedback"), whose row is a copy of the filter's previous
    velocity and counts the prior again (both without the traction slip model: the synthetic slip is a constant
    ratio, and the feedback configuration cannot take it; both with the per-step v_x row, which the feedback needs)."""
    clean = dataclasses.replace(TESTBED, acc_bias=(0.0, 0.0, 0.0), gyr_bias=(0.0, 0.0, 0.0))
    cal = []
    for i in (0, 3, 6, 9):
        wl, wr = CAL_COMBOS_RPM[i]
        sens = dataclasses.replace(clean, lam0=0.03 if i % 2 == 0 else 0.08)
        cal.append(synthetic_run(f"cal{i}", 100 + i, sens, knots_rpm=[(0, 0, 0), (1, wl, wr), (11, wl, wr)]))
    run = synthetic_run("circle", 21, clean)
    nees = {}
    for rows in ("state", "feedback"):
        m = registry.calibrate(ekf_v2_consistent(store_covariance=True, slip_rows=rows, traction_slip=False,
                                                 odometer_window=0.0), cal)  # both fuse the row per step
        nees[rows] = _velocity_nees(run, registry.estimate(m, run))
    assert nees["state"] <= stats.chi2.ppf(0.999, 2) and nees["state"] < nees["feedback"]


def test_start_yaw_sd_is_carried_unchanged_where_heading_is_unobserved(consistent_v2):
    """A run at rest (no row carries heading: v_B = C^T V does not depend on yaw at V = 0): the yaw variance is its
    P0 plus the gyro's accumulated process noise, so the consistent filter's 1e-4 rad start and the paper's 1 mrad
    differ by p0_yaw^2 - 1e-8 rad^2 at every step (closed form, the P0 offset is neither observed nor forgotten;
    (*) to 0.1 %: the estimated velocity is not exactly 0, measured 7e-5 relative); start_yaw_sd=None keeps the
    paper's p0_yaw; a bad value is refused with its name."""
    run = synthetic_run("rest", 31, knots_rpm=[(0, 0, 0), (10, 0, 0)])
    assert consistent_v2.start_yaw_sd == 1e-4
    p_start = registry.estimate(consistent_v2, run).info["P"][:, 8, 8]
    p_paper = registry.estimate(dataclasses.replace(consistent_v2, start_yaw_sd=None), run).info["P"][:, 8, 8]
    assert p_start[0] == pytest.approx(1e-8, rel=1e-9) and p_paper[0] == pytest.approx(EkfParams().p0_yaw**2, rel=1e-9)
    np.testing.assert_allclose(p_paper - p_start, EkfParams().p0_yaw**2 - 1e-8, rtol=1e-3)  # (*)
    assert p_start[-1] > 1.5 * p_start[0]  # the gyro's noise accumulates on top
    with pytest.raises(ValueError, match="start_yaw_sd"):
        ekf_v2_consistent(start_yaw_sd=0.0)


def test_consistent_needs_calibration_and_refuses_its_calibration_runs(consistent_v2, consistent_runs):
    run = synthetic_run("circle", 22)
    with pytest.raises(RunError, match="calibrate first"):
        ekf_v3_consistent().estimate(run.without_truth())
    with pytest.raises(registry.CalibrationLeak):
        registry.estimate(consistent_v2, consistent_runs[1])
    assert consistent_v2.calibrated and consistent_v2.noise_info["calibration_runs"] == [r.id for r in consistent_runs]
    no_ref = from_arrays({c: run[c] for c in run.data.columns if not c.startswith("ref_")}, dict(run.meta))
    with pytest.raises(RunError, match="ref_"):
        registry.calibrate(ekf_v1_consistent(), [no_ref])
    rows = run.t >= TESTBED.t_rest + 0.5  # drop the rest at the start: no static IMU data
    cut = from_arrays({c: run[c][rows] for c in run.data.columns}, dict(run.meta))
    with pytest.raises(RunError, match="at rest"):
        static_imu_noise([cut])
    assert static_imu_noise([cut], required=False) is None
    enc = align_inputs(run)[3]
    assert at_rest_start(enc, R_WHEEL, EkfParams()) and not at_rest_start(align_inputs(cut)[3], R_WHEEL, EkfParams())
    # no rest in the calibration runs (league calibration sets): the model's IMU noise and the paper's P0 are kept
    m = registry.calibrate(ekf_v1_consistent(), [cut])
    p = EkfParams()
    assert m.noise_info["imu_noise_source"] == "paper default" and m.noise_info["static_samples"] == 0
    assert (m.params.accel_noise, m.params.gyro_noise, m.params.p0_rollpitch) == (p.accel_noise, p.gyro_noise,
                                                                                 p.p0_rollpitch)
    assert consistent_v2.noise_info["imu_noise_source"] == "rest"
    assert np.isfinite(registry.estimate(m, synthetic_run("circle", 23))["vx"]).all()


def test_reference_smoothing_bias_removes_the_derivative_error_at_a_speed_change():
    """A speed doubling within 0.2 s (60 -> 120 rpm, straight): the reference's 1 s quadratic Savitzky-Golay
    derivative cannot follow it, so its error against the closed-form truth in the 1.5 s after the change is ~10x
    the position noise's share; removing the error the same operator makes on the pose dead-reckoned from the gyro
    and the encoders leaves less than a third of it (the rest: the net slip, which dead reckoning leaves out, and
    the 0.1 s smoothing of the encoder speed)."""
    run = synthetic_run("step", 3, knots_rpm=[(0, 0, 0), (1, 60, 60), (5, 60, 60), (5.2, 120, 120), (10, 120, 120)])
    ref_only = run.without_truth()
    t, _, gyr, enc = align_inputs(ref_only)
    vx, _, var = reference_body_velocity(ref_only, t)
    bx, by = reference_smoothing_bias(ref_only, t, gyr, enc, R_WHEEL)
    w = (t > TESTBED.t_rest + 4.5) & (t < TESTBED.t_rest + 6.0)
    before = np.sqrt(np.mean((vx - run["truth_vx"])[w] ** 2))
    after = np.sqrt(np.mean((vx - bx - run["truth_vx"])[w] ** 2))
    assert before > 5 * math.sqrt(var)
    assert after < before / 3
    steady = (t > TESTBED.t_rest + 2.0) & (t < TESTBED.t_rest + 4.0)  # a quadratic fits: no correction there
    assert np.abs(bx[steady]).max() < 1e-3 and np.nanmax(np.abs(by)) < 1e-3  # straight: no lateral smoothing error


def test_lateral_reference_noise_includes_the_smoothed_yaw_noise():
    """Straight line at 150 rpm, 8 seeds: the variance of the W-sample means of the reference's lateral velocity
    error (truth closed form) matches reference_velocity_noise_mean_var with the mean square speed (the smoothed yaw
    noise rotates the forward speed into v_y) within 25 % at 2 and 4 s windows, where the position noise alone is
    at least 40 % low."""
    errs = []
    for seed in range(8):
        run = synthetic_run("fast", seed, knots_rpm=[(0, 0, 0), (1, 150, 150), (31, 150, 150)])
        t = run.t
        _, vy, _ = reference_body_velocity(run.without_truth(), t)
        errs.append(np.where((t > 3.0) & (t < t[-1] - 1.0), vy - run["truth_vy"], np.nan))
    dt = float(np.median(np.diff(run.t)))
    v = float(np.mean(run["truth_vx"][run.t > 3.0]))
    pos_only = reference_velocity_noise_mean_var(run, dt)
    with_yaw = reference_velocity_noise_mean_var(run, dt, speed_ms=v * v)
    for w in (250, 500):
        data = moving_mean_var(errs, w)
        assert with_yaw(w) == pytest.approx(data, rel=0.25)
        assert pos_only(w) < 0.6 * data


def test_reference_noise_in_a_turn_does_not_telescope():
    """Steady turn (150/60 rpm, yaw rate ~ -1.3 rad/s), 40 seeds: the variance of the W-sample means of the
    reference's body-frame velocity error (truth closed form) on both axes matches reference_velocity_noise_mean_var
    given the run's yaw rates within 12 % for single samples and 2 and 4 s windows (measured data : formula
    0.96-1.00; in five blocks of 40 seeds 0.93-1.13, so 40 seeds resolve about 10 %).  The position noise's
    derivative, rotated into the turning body frame (per-axis autocovariance acov(tau) cos(w tau)), no longer
    telescopes over a long mean; the formula without the yaw rates (a straight line's) is at least 40 % low there
    (measured data : formula 1.7-3.3).  The velocity, and so its noise, is divided by the derivative's turn gain:
    without it (8 seeds, the earlier version of this test) the data were 12-18 % above the formula."""
    errs_x, errs_y, rates = [], [], []
    for seed in range(40):
        run = synthetic_run("turn", seed, knots_rpm=[(0, 0, 0), (1, 150, 60), (31, 150, 60)])
        t = run.t
        vx, vy, _ = reference_body_velocity(run.without_truth(), t)
        keep = (t > 3.0) & (t < t[-1] - 1.0)
        errs_x.append(np.where(keep, vx - run["truth_vx"], np.nan))
        errs_y.append(np.where(keep, vy - run["truth_vy"], np.nan))
        rates.append(run["imu_gz"][keep])
    dt = float(np.median(np.diff(run.t)))
    w_z = np.concatenate(rates)
    assert np.abs(w_z).mean() > 1.2
    v2 = float(np.mean(run["truth_vx"][run.t > 3.0] ** 2))
    straight_x, straight_y = (reference_velocity_noise_mean_var(run, dt),
                              reference_velocity_noise_mean_var(run, dt, speed_ms=v2))
    turn_x, turn_y = (reference_velocity_noise_mean_var(run, dt, yaw_rates=w_z),
                      reference_velocity_noise_mean_var(run, dt, speed_ms=v2, yaw_rates=w_z))
    for w in (1, 250, 500):
        for errs, turn, straight in ((errs_x, turn_x, straight_x), (errs_y, turn_y, straight_y)):
            data = moving_mean_var(errs, w)
            assert turn(w) == pytest.approx(data, rel=0.12)
            if w > 1:
                assert straight(w) < 0.6 * data
    # a single sample: no lag, so no rotation; only the turn gain's 1 / gain^2 (~ 1.09 at 1.3 rad/s)
    ok, h, win, coef = _reference_derivative(run, 1.0, 2)
    g2 = float(np.mean(savgol_turn_gain(w_z, coef, h) ** -2))
    assert 1.05 < g2 < 1.15
    assert turn_x(1) == pytest.approx(straight_x(1) * g2, rel=1e-9)


def test_savgol_turn_gain_is_scipys_derivative_on_a_circle():
    """On a circle of radius rho traversed at w, scipy's savgol_filter (first derivative, 1 s window, quadratic)
    returns the speed rho w times savgol_turn_gain(w) (to 1e-9; antisymmetric coefficients: no phase error), which
    is 1 on a straight line and falls with |w| (about 2.5 % at 1 rad/s)."""
    from scipy.signal import savgol_coeffs, savgol_filter

    h, win, rho = 0.032, 31, 2.0
    coef = savgol_coeffs(win, 2, deriv=1, delta=h, use="dot")
    t = np.arange(400) * h
    for w in (0.3, 1.0, 2.5, -1.3):
        x, y = rho * np.cos(w * t), rho * np.sin(w * t)
        kw = dict(window_length=win, polyorder=2, deriv=1, delta=h, mode="interp")
        speed = np.hypot(savgol_filter(x, **kw), savgol_filter(y, **kw))[win:-win]
        np.testing.assert_allclose(speed, rho * abs(w) * savgol_turn_gain(w, coef, h), rtol=1e-9)
    assert savgol_turn_gain(0.0, coef, h) == pytest.approx(1.0, abs=1e-9)
    g = savgol_turn_gain(np.array([0.5, 1.0, 2.0]), coef, h)
    assert np.all(np.diff(g) < 0) and 0.96 < g[1] < 0.99


def test_trailing_mean_of_count_differences_telescopes():
    """Encoder speeds as count differences of a wheel at 21.3 counts per sample: the trailing mean over N samples
    is the count difference over N samples (exact, closed form), so its quantisation error is below one count over
    the window, q / (N dT), where a single sample's is up to q / dT; NaN samples are skipped."""
    dt, q, n_win = 0.008, 2 * math.pi / 2000, 12
    t = np.arange(400) * dt
    w_true = 21.3 * q / dt
    counts = np.floor(w_true * t / q + 0.37)
    w = np.concatenate(([0.0], np.diff(counts) * q / dt))
    enc = np.column_stack((w, 0.5 * w))
    sm = trailing_mean(enc, t, n_win * dt)
    k = np.arange(n_win, t.size)
    np.testing.assert_allclose(sm[k, 0], (counts[k] - counts[k - n_win]) * q / (n_win * dt), rtol=1e-12)
    assert np.abs(sm[k, 0] - w_true).max() <= q / (n_win * dt) + 1e-12
    assert np.abs(w[1:] - w_true).max() > 0.5 * q / dt
    enc[100, 0] = np.nan
    assert np.isfinite(trailing_mean(enc, t, n_win * dt)[100:120, 0]).all()
    np.testing.assert_array_equal(trailing_mean(enc, t, 0.0), enc)


def test_imu_mean_integrates_a_linear_yaw_rate_exactly():
    """Level, at rest in translation, gyro z = alpha t sampled without noise, no encoder rows: the trapezoidal
    strapdown (imu_mean) gives the yaw alpha t^2 / 2 to rounding; holding each sample over the next step (Yi's
    forward Euler) leaves it behind by alpha t dT / 2 = w dT / 2 (closed form)."""
    t, acc, gyr, enc, p, x0, p0 = _level_rest(n=400)  # yaw stays below pi
    alpha, dt = 0.4, float(t[1] - t[0])
    gyr = gyr.copy()
    gyr[:, 2] = alpha * t
    enc = np.full_like(enc, np.nan)
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, variant=1, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.01, 1.0, 0.01), slip_rows="state")
    yaw_mean = run_filter_gm(t, acc, gyr, enc, imu_mean=True, **kw)[0].state[:, 8]
    yaw_fwd = run_filter_gm(t, acc, gyr, enc, imu_mean=False, **kw)[0].state[:, 8]
    np.testing.assert_allclose(yaw_mean, alpha * t**2 / 2, atol=1e-12)
    np.testing.assert_allclose(alpha * t**2 / 2 - yaw_fwd, alpha * t * dt / 2, atol=1e-12)


def test_enc_gamma_is_refused_outside_scheme_3_with_the_slip_state():
    t, acc, gyr, enc, p, x0, p0 = _level_rest(n=20)
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.01, 1.0, 0.01), gm_y=GaussMarkov(0.01, 1.0, 0.01))
    with pytest.raises(ValueError, match="enc_gamma needs scheme 3"):
        run_filter_gm(t, acc, gyr, enc, variant=1, slip_rows="state", enc_gamma=enc, **kw)
    with pytest.raises(ValueError, match="enc_gamma needs scheme 3"):
        run_filter_gm(t, acc, gyr, enc, variant=3, slip_rows="feedback", enc_gamma=enc, **kw)
    with pytest.raises(ValueError, match="enc_gamma needs scheme 3"):
        run_filter_gm(t, acc, gyr, enc, variant=3, slip_rows="state", enc_gamma=enc[:5], **kw)


def test_gamma_smoothing_must_be_finite_and_non_negative():
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(ValueError, match="gamma_smoothing"):
            ekf_v3_consistent(gamma_smoothing=bad)
    assert ekf_v3_consistent(gamma_smoothing=0.0).gamma_speeds(np.arange(3.0), np.zeros((3, 2))) is None


@pytest.mark.parametrize("row_sd", [0.002, 0.005, 0.02])
def test_gm_filter_adaptive_r_recovers_the_row_white_noise(row_sd):
    """run_filter_gm(adaptive_vx): residual-based covariance matching (Mohamed & Schwarz 1999) estimates the v_x
    row's white R from the filter's own post-fit residuals.  On a synthetic figure-8 whose only v_x row error is
    white wheel-speed noise of known std (no slip, no IMU bias, quantisation 1000x finer than the testbed's) and
    whose IMU noise is the filter's Q, the R it settles on over the second half matches the generating row
    variance, started from a white part 10x too large or 10x too small."""
    sens = Sensors(lam0=0.0, acc_bias=(0.0, 0.0, 0.0), gyr_bias=(0.0, 0.0, 0.0), counts_per_rev=2_000_000)
    run = synthetic_run("figure8", 11, sens)
    rng = np.random.default_rng(5)
    t, acc, gyr, enc = align_inputs(run.without_truth())
    enc = enc + (math.sqrt(2.0) * row_sd / R_WHEEL) * rng.standard_normal(enc.shape)  # row r (w_L + w_R)/2: row_sd
    p = EkfParams(accel_noise=sens.acc_noise, gyro_noise=sens.gyr_noise)
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0, variant=1,
              slip_rows="state", roll_model_jacobian=True)
    window = int(round(2.0 * sens.rate_hz))
    half = t >= t[-1] / 2
    for start in (10.0 * row_sd, 0.1 * row_sd):
        gm = GaussMarkov(1e-4, 2.0, start)
        res, _, _ = run_filter_gm(t, acc, gyr, enc, gm_x=gm, adaptive_vx=window, **kw)
        r_est = res.r_vx[half & np.isfinite(res.r_vx)]
        # 2000 rows in the second half: the variance's sampling sd sqrt(2/2000) = 3 %, the std's 1.6 %; without the
        # h P+ h^T term (P+ / R ~ sqrt(q / R)) the estimate is 4 % low at row_sd 0.005, more at 0.002
        assert np.sqrt(np.mean(r_est)) == pytest.approx(row_sd, rel=0.035)
        const, _, _ = run_filter_gm(t, acc, gyr, enc, gm_x=gm, **kw)
        assert const.r_vx is None
    with pytest.raises(ValueError, match="adaptive_vx"):
        run_filter_gm(t, acc, gyr, enc, gm_x=gm, adaptive_vx=-1, **kw)
    with pytest.raises(ValueError, match="adaptive_vx needs gm_x"):
        run_filter_gm(t, acc, gyr, enc, gm_x=None, adaptive_vx=window, **kw)
