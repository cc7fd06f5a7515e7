"""Tests of methods/liu2020.py on synthetic skid-steer runs generated from a known ICR model.

The generator integrates a DUBHE-like vehicle (Liu Table 1: B = 0.87 m, r = 0.23 m) whose tread
ICRs are known (y_l ~ 0.6, y_r ~ -0.6, x_icr ~ 0.05, optionally varying slowly in time like terrain
patches) at 1 kHz with the exact SE(2) integrator, and samples IMU (specific force, gyro), quantised
encoders, GNSS (position, world velocity, dual-antenna yaw) and the truth from it.  The
expectations are the truth itself, closed-form kinematics, and the paper's orderings on data where
they must hold (constant-ICR DR beats no-slip DR on slipping data; GNSS-aided filters beat DR).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bench import registry
from bench.kinematics import icr_forward, integrate_se2
from bench.registry import Method
from bench.run import Run, RunError, from_arrays
from bench.spec import load_platform, to_dict
from bench.estimation.ukf import FilterError, nees
from tests.test_ukf import _sincos_mean, _wrapped_resid  # FilterPy adapters, shared
from methods.liu2020 import EnDr, IcrDr, LiuUkfParams, MiUkf, UkfIcr, fit_icr, run_liu_filter

PLATFORM = to_dict(load_platform("dubhe"))
B, RW = PLATFORM["track"], PLATFORM["wheel_radius"]


# ----------------------------------------------------------------------------- synthetic data
def _profile(kind: str, t: np.ndarray, phase: float) -> tuple[np.ndarray, np.ndarray]:
    """Commanded forward speed v and no-slip yaw rate w_c (tread speeds v -/+ w_c B/2)."""
    ramp = 1.0 - np.exp(-t / 1.5)
    if kind == "mixed":  # straight cruise, large- and small-radius turns, speed changes
        v = ramp * (1.6 + 0.6 * np.sin(2 * np.pi * t / 23.0 + phase))
        w = ramp * (0.9 * np.sin(2 * np.pi * t / 19.0 + 2 * phase) + 0.5 * np.sin(2 * np.pi * t / 7.3 + phase))
    elif kind == "circle":  # Liu scenario 3: backwards on a small radius, heading wraps often
        v = -0.6 * ramp
        w = -3.0 * ramp
    elif kind == "straight":
        v = 2.0 * ramp
        w = 0.02 * np.sin(2 * np.pi * t / 10.0 + phase) * ramp
    else:
        raise ValueError(kind)
    return v, w


def make_run(seed: int, duration: float = 60.0, kind: str = "mixed", icr=(0.6, -0.6, 0.05),
             icr_var: float = 0.2, rate: float = 100.0, gnss_rate: float = 10.0,
             outage: tuple[float, float] | None = None, phase: float | None = None) -> Run:
    """A synthetic skid-steer Run with truth from a known (time-varying) ICR model."""
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi) if phase is None else phase
    fine = 1000.0
    sub = int(round(fine / rate))
    tf = np.arange(int(round(duration * fine)) + 1) / fine
    v, wc = _profile(kind, tf, phase)
    v_l, v_r = v - wc * B / 2, v + wc * B / 2
    # truth ICR: slow terrain-like variation around the nominal locations
    y_l = icr[0] * (1 + icr_var * np.sin(2 * np.pi * tf / 37.0 + phase))
    y_r = icr[1] * (1 + icr_var * np.sin(2 * np.pi * tf / 23.0 + 1.0 + phase))
    x_i = icr[2] * (1 + icr_var * np.sin(2 * np.pi * tf / 31.0 + 2.0))
    vx, vy, wz = icr_forward(v_l, v_r, y_l, y_r, x_i)
    yaw0 = rng.uniform(-np.pi, np.pi)
    X, Y, yaw = integrate_se2(tf, vx, vy, wz, 3.0, -2.0, yaw0)
    # specific force in the body frame: dv/dt + w x v
    dvx, dvy = np.gradient(vx, tf), np.gradient(vy, tf)
    ax_t, ay_t = dvx - wz * vy, dvy + wz * vx
    # encoder: quantised wheel angle differenced over each log interval
    cpr = PLATFORM["sensors"]["encoder"]["counts_per_rev"]
    ang_l = np.concatenate(([0.0], np.cumsum(v_l[:-1] / RW * np.diff(tf))))
    ang_r = np.concatenate(([0.0], np.cumsum(v_r[:-1] / RW * np.diff(tf))))
    idx = np.arange(0, tf.size, sub)
    t = tf[idx]
    n = t.size
    dt = 1.0 / rate
    cnt_l, cnt_r = np.floor(ang_l[idx] * cpr / (2 * np.pi)), np.floor(ang_r[idx] * cpr / (2 * np.pi))
    enc_l = np.concatenate(([0.0], np.diff(cnt_l))) * 2 * np.pi / cpr / dt
    enc_r = np.concatenate(([0.0], np.diff(cnt_r))) * 2 * np.pi / cpr / dt
    s_acc, s_gyr = 0.05, 0.003
    cols = {
        "t": t,
        "cmd_wl": v_l[idx] / RW, "cmd_wr": v_r[idx] / RW,
        "enc_wl": enc_l, "enc_wr": enc_r,
        "imu_ax": ax_t[idx] + rng.normal(0, s_acc, n), "imu_ay": ay_t[idx] + rng.normal(0, s_acc, n),
        "imu_az": 9.81 + rng.normal(0, s_acc, n),
        "imu_gx": rng.normal(0, s_gyr, n), "imu_gy": rng.normal(0, s_gyr, n),
        "imu_gz": wz[idx] + 0.002 + rng.normal(0, s_gyr, n),  # small constant gyro bias
    }
    gsub = int(round(rate / gnss_rate))
    g = np.zeros(n, dtype=bool)
    g[::gsub] = True
    if outage is not None:
        g &= ~((t >= outage[0]) & (t < outage[1]))
    yw = yaw[idx]
    vxw = vx[idx] * np.cos(yw) - vy[idx] * np.sin(yw)
    vyw = vx[idx] * np.sin(yw) + vy[idx] * np.cos(yw)

    def gn(a, s):
        out = np.full(n, np.nan)
        out[g] = a[g] + rng.normal(0, s, int(g.sum()))
        return out

    cols |= {
        "gnss_x": gn(X[idx], 0.02), "gnss_y": gn(Y[idx], 0.02),
        "gnss_vx": gn(vxw, 0.03), "gnss_vy": gn(vyw, 0.03),
        "gnss_yaw": np.where(g, (gn(yw, 0.005) + np.pi) % (2 * np.pi) - np.pi, np.nan),
    }
    vxl, vxr = vx[idx] - B / 2 * wz[idx], vx[idx] + B / 2 * wz[idx]
    with np.errstate(divide="ignore", invalid="ignore"):
        sl = (v_l[idx] - vxl) / v_l[idx]
        sr = (v_r[idx] - vxr) / v_r[idx]
    cols |= {
        "truth_x": X[idx], "truth_y": Y[idx], "truth_yaw": (yw + np.pi) % (2 * np.pi) - np.pi,
        "truth_vx": vx[idx], "truth_vy": vy[idx], "truth_wz": wz[idx],
        "truth_y_l": y_l[idx], "truth_y_r": y_r[idx], "truth_x_icr": x_i[idx],
        "truth_slip_l": sl, "truth_slip_r": sr,
    }
    meta = {"run_id": f"synthetic-{kind}-{seed}", "seed": seed, "platform": PLATFORM}
    return from_arrays(cols, meta)


def pos_rms(est, run: Run) -> float:
    return float(np.sqrt(np.mean((est["x"] - run["truth_x"]) ** 2 + (est["y"] - run["truth_y"]) ** 2)))


def yaw_err(est, run: Run) -> np.ndarray:
    return (est["yaw"] - run["truth_yaw"] + np.pi) % (2 * np.pi) - np.pi


def start_aligned_rms(est, run: Run) -> float:
    """Position RMS after moving the estimate's start pose onto the true start pose (SE(2)): removes
    the GNSS noise of the first fix that dead reckoning starts from."""
    d = float(run["truth_yaw"][0] - est["yaw"][0])
    c, s = math.cos(d), math.sin(d)
    ex, ey = est["x"] - est["x"][0], est["y"] - est["y"][0]
    x = run["truth_x"][0] + c * ex - s * ey
    y = run["truth_y"][0] + s * ex + c * ey
    return float(np.sqrt(np.mean((x - run["truth_x"]) ** 2 + (y - run["truth_y"]) ** 2)))


# ----------------------------------------------------------------------------- FilterPy twin
class FilterPyUkf:
    """FilterPy's UnscentedKalmanFilter + MerweScaledSigmaPoints behind bench.estimation.ukf.Ukf's interface,
    running the same model functions (one sigma point at a time, as FilterPy calls them), the same
    sin/cos mean, wrapped residuals and wrapped state add.  NaN elements are dropped by passing
    FilterPy the reduced z, h and R.  No multi-innovation (FilterPy has none); its covariance update
    is P - K S K^T, equal to our Joseph form because Liu's h is linear."""

    def __init__(self, fx, hx, x0, P0, Q, R, *, sigma, x_angles, z_angles, joseph, gate, mi_weights):
        from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

        if gate is not None or tuple(mi_weights) != (1.0,):
            raise ValueError("FilterPyUkf: no gating, no multi-innovation")
        n, m = len(x0), len(R)
        xa = list(x_angles)
        self._hx, self._R, self._za = hx, np.asarray(R, float), set(z_angles)
        self._cache: dict = {}

        def state_add(x, dx):
            out = x + dx
            out[xa] = (out[xa] + np.pi) % (2 * np.pi) - np.pi
            return out

        pts = MerweScaledSigmaPoints(n, sigma.alpha, sigma.beta, sigma.kappa)
        self.kf = UnscentedKalmanFilter(n, m, 0.01, hx=None, fx=lambda s, dt, u: fx(s[None], dt, u)[0], points=pts,
                                        x_mean_fn=_sincos_mean(xa), residual_x=_wrapped_resid(xa), state_add=state_add)
        self.kf.x, self.kf.P, self.kf.Q = np.array(x0, float), np.array(P0, float), np.array(Q, float)
        self.step = 0

    @property
    def x(self):
        return self.kf.x

    @property
    def P(self):
        return self.kf.P

    def predict(self, dt, u, Q):
        self.step += 1
        self.kf.Q = Q
        self.kf.predict(dt=dt, u=u)

    def update(self, z):
        ok = np.isfinite(z)
        key = ok.tobytes()
        if key not in self._cache:
            idx = np.flatnonzero(ok)
            za = [j for j, i in enumerate(idx) if i in self._za]
            hx = self._hx
            self._cache[key] = (idx, self._R[np.ix_(idx, idx)], _sincos_mean(za), _wrapped_resid(za),
                                lambda s: hx(s[None])[0][idx])
        idx, R, zm, zr, h = self._cache[key]
        if idx.size == 0:
            return 0
        self.kf.z_mean, self.kf.residual_z = zm, zr
        self.kf.update(z[idx], R=R, hx=h)
        return int(idx.size)


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def calib_run() -> Run:
    return make_run(101, duration=40.0, kind="mixed")


@pytest.fixture(scope="module")
def score_run() -> Run:
    return make_run(202, duration=60.0, kind="mixed")


@pytest.fixture(scope="module")
def estimates(calib_run, score_run):
    icr = registry.calibrate(IcrDr(), [calib_run])
    out = {}
    for m in (EnDr(), icr, UkfIcr(), MiUkf()):
        out[m.name] = registry.estimate(m, score_run)
    return out


# ----------------------------------------------------------------------------- tests
def test_plugins_satisfy_protocol():
    for m in (EnDr(), IcrDr(), UkfIcr(), MiUkf()):
        assert isinstance(m, Method)
        assert m.name.startswith("liu2020.") and m.paper == "Liu et al. 2020"
        assert not any(c.startswith("truth_") for c in m.requires)
    assert MiUkf().params.innovation_length == 2 and MiUkf().params.mi_a == 0.5
    assert UkfIcr().params.innovation_length == 1
    assert LiuUkfParams().icr_clamp == 20.0


def test_ukf_icr_parity_with_filterpy_on_liu_model():
    """The whole UKF+ICR run (encoder-ICR pseudo-measurements, GNSS at 10 Hz with NaN rows dropped,
    heading wraps) on our core and on FilterPy: same states and covariances to 1e-9."""
    run = make_run(31, duration=8.0, kind="circle")
    p = UkfIcr().params
    ours = run_liu_filter(run, p, "ours")
    fp = run_liu_filter(run, p, "filterpy", make_filter=FilterPyUkf)
    assert np.sum(np.abs(np.diff(run["truth_yaw"])) > np.pi) >= 1
    dstate = max(float(np.max(np.abs(ours[c] - fp[c]))) for c in ("x", "y", "vx", "vy", "wz", "y_l", "y_r"))
    dyaw = float(np.max(np.abs((ours["yaw"] - fp["yaw"] + np.pi) % (2 * np.pi) - np.pi)))
    dP = float(np.max(np.abs(ours.info["P"] - fp.info["P"])))
    print(f"parity over {run.t.size} steps: state {dstate:.2e}, yaw {dyaw:.2e}, P {dP:.2e}")
    assert dstate < 1e-9 and dyaw < 1e-9 and dP < 1e-9


def test_en_dr_exact_on_no_slip_data():
    """With ICRs at +-B/2 and x = 0 (pure rolling) the no-slip DR reproduces the truth (closed form)."""
    run = make_run(3, duration=40.0, icr=(B / 2, -B / 2, 0.0), icr_var=0.0)
    est = EnDr().estimate(run)
    assert start_aligned_rms(est, run) < 0.01  # only encoder quantisation and the ZOH step
    assert pos_rms(est, run) > start_aligned_rms(est, run)  # the GNSS start point's own error
    assert np.max(np.abs(yaw_err(est, run))) < 0.02
    np.testing.assert_allclose(est["slip_l"][np.isfinite(est["slip_l"])], 0.0, atol=1e-12)


def test_icr_dr_with_true_constant_icr_is_exact_and_calibration_recovers_it():
    run = make_run(4, duration=40.0, icr=(0.6, -0.6, 0.05), icr_var=0.0)
    est = IcrDr(0.6, -0.6, 0.05).estimate(run)
    assert start_aligned_rms(est, run) < 0.01
    assert start_aligned_rms(EnDr().estimate(run), run) > 1.0  # the no-slip model is wrong here
    cal = make_run(5, duration=60.0, icr=(0.6, -0.6, 0.05), icr_var=0.0)
    y_l, y_r, x_icr, info = fit_icr([cal])
    assert abs(y_l - 0.6) < 0.03 and abs(y_r + 0.6) < 0.03 and abs(x_icr - 0.05) < 0.03, (y_l, y_r, x_icr)
    assert info["fit_samples"] > 100


def test_paper_orderings_on_slipping_data(estimates, score_run):
    """Liu Table 2 orderings where they must hold: ICR DR < En-DR, and both GNSS-aided UKFs < ICR DR
    (position RMS against the truth); the filters also beat DR on heading and velocity."""
    rms = {k: pos_rms(e, score_run) for k, e in estimates.items()}
    print("position RMS [m]:", {k: round(v, 4) for k, v in rms.items()})
    assert rms["liu2020.icr"] < 0.5 * rms["liu2020.en_dr"]
    for k in ("liu2020.ukf_icr", "liu2020.mi_ukf"):
        assert rms[k] < 0.25 * rms["liu2020.icr"]
        assert rms[k] < 0.1  # GNSS at 2 cm, 10 Hz
        yaw_rms = float(np.sqrt(np.mean(yaw_err(estimates[k], score_run) ** 2)))
        assert yaw_rms < 0.02
        ev = np.hypot(estimates[k]["vx"] - score_run["truth_vx"], estimates[k]["vy"] - score_run["truth_vy"])
        assert float(np.sqrt(np.mean(ev**2))) < 0.1


def test_online_icr_and_slip_track_truth(estimates, score_run):
    """The filters' ICR (eqs. (2), (3), (5)) and slip outputs follow the truth while turning."""
    est = estimates["liu2020.mi_ukf"]
    turning = (np.abs(score_run["truth_wz"]) > 0.4) & (score_run.t > 5.0)
    assert turning.sum() > 500
    for col in ("y_l", "y_r"):
        err = np.abs(est[col][turning] - score_run[f"truth_{col}"][turning])
        assert np.median(err) < 0.1, (col, np.median(err))
    for col in ("slip_l", "slip_r"):
        e, tr = est[col][turning], score_run[f"truth_{col}"][turning]
        ok = np.isfinite(e) & np.isfinite(tr) & (np.abs(tr) < 2)
        assert np.median(np.abs(e[ok] - tr[ok])) < 0.05
    assert np.all(np.abs(est["y_l"]) <= 20) and np.all(np.abs(est["x_icr"]) <= 20)


def _yaw_steps(est) -> np.ndarray:
    return np.abs((np.diff(est["yaw"]) + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("cls", [UkfIcr, MiUkf])
def test_no_heading_chattering_on_small_circle(cls):
    """Liu Figs. 16-17: small-radius backwards circle, heading crosses -pi/pi many times.  Every
    step-to-step yaw change stays within |true yaw rate| * dt + a noise margin."""
    run = make_run(7, duration=40.0, kind="circle", icr_var=0.1)
    truth_yaw = run["truth_yaw"]
    crossings = int(np.sum(np.abs(np.diff(truth_yaw)) > np.pi))
    assert crossings >= 8
    est = cls().estimate(run)
    dt = np.diff(run.t)
    bound = np.abs(run["truth_wz"][1:]) * dt + 0.02
    steps = _yaw_steps(est)
    assert np.all(steps <= bound), (float(np.max(steps - bound)), int(np.argmax(steps - bound)))
    assert np.max(np.abs(yaw_err(est, run))[run.t > 2.0]) < 0.05


def test_gnss_outage_20s():
    """20 s without GNSS: no NaN, covariance PD, position error bounded and recovered afterwards."""
    run = make_run(9, duration=60.0, kind="mixed", outage=(20.0, 40.0))
    dr = EnDr().estimate(run)
    for cls in (UkfIcr, MiUkf):
        est = cls().estimate(run)
        for c in ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr"):
            assert np.all(np.isfinite(est[c])), c
        P = est.info["P"]
        np.linalg.cholesky(P)  # raises if any step is not positive definite
        e = np.hypot(est["x"] - run["truth_x"], est["y"] - run["truth_y"])
        e_dr = np.hypot(dr["x"] - run["truth_x"], dr["y"] - run["truth_y"])
        t = run.t
        end = np.searchsorted(t, 40.0) - 1
        travelled = np.sum(np.hypot(np.diff(run["truth_x"]), np.diff(run["truth_y"]))[(t[1:] > 20) & (t[1:] <= 40)])
        assert travelled > 20.0
        assert e[end] < e_dr[end]
        assert e[end] < 0.05 * travelled  # IMU + encoder-ICR carry the GNSS-calibrated slip
        assert np.max(e[(t > 5) & (t < 20)]) < 0.1
        assert np.max(e[t > 55.0]) < e[end]  # GNSS back: the error shrinks again


def _check_consistency(run: Run) -> dict:
    est = UkfIcr().estimate(run)
    P = est.info["P"]
    assert np.array_equal(P, np.swapaxes(P, 1, 2))
    assert np.all(np.linalg.eigvalsh(P)[:, 0] > 0)
    err = np.column_stack((est["x"] - run["truth_x"], est["y"] - run["truth_y"], yaw_err(est, run),
                           est["vx"] - run["truth_vx"], est["vy"] - run["truth_vy"], est["wz"] - run["truth_wz"]))
    v = nees(err, P)
    assert np.all(np.isfinite(v))
    return {"nees_mean": float(v.mean()), "pos_rms": pos_rms(est, run)}


def test_covariance_pd_long_run_default():
    """2 minutes at 100 Hz (12000 steps): P symmetric positive definite at every step."""
    out = _check_consistency(make_run(12, duration=120.0, kind="mixed"))
    print("2 min run:", out)
    assert out["pos_rms"] < 0.1


@pytest.mark.slow
def test_covariance_pd_one_hour_reduced_rate():
    """1 hour at a 20 Hz log rate (72000 steps): P symmetric positive definite at every step."""
    out = _check_consistency(make_run(13, duration=3600.0, kind="mixed", rate=20.0, gnss_rate=5.0))
    print("1 h run:", out)
    assert out["pos_rms"] < 0.2


def test_deterministic_and_truth_blind():
    run = make_run(17, duration=10.0)
    a = MiUkf().estimate(run)
    b = MiUkf().estimate(make_run(17, duration=10.0).without_truth())
    for c in a.data.columns:
        assert np.array_equal(a[c], b[c], equal_nan=True), c


def test_bad_input_errors():
    score_run = make_run(18, duration=20.0)
    no_imu = Run(score_run.data.drop(columns=["imu_ax"]), score_run.meta)
    with pytest.raises(RunError, match="imu_ax"):
        MiUkf().estimate(no_imu)
    no_geom = Run(score_run.data, {"run_id": "x"})
    with pytest.raises(RunError, match="platform"):
        EnDr().estimate(no_geom)
    with pytest.raises(RuntimeError, match="calibrate"):
        IcrDr().estimate(score_run)
    # a NaN burst in the IMU and encoders is held/dropped, not fused
    d = score_run.data.copy()
    d.loc[1000:1100, ["imu_ax", "imu_ay", "imu_gz", "enc_wl", "enc_wr"]] = np.nan
    est = UkfIcr().estimate(Run(d, score_run.meta))
    assert np.all(np.isfinite(est["x"])) and pos_rms(est, score_run) < 0.1
    # a corrupt (infinite) value is a RunError naming channel and row
    d = score_run.data.copy()
    d.loc[500, "imu_ay"] = np.inf
    with pytest.raises(RunError, match=r"imu_ay.*row 500"):
        MiUkf().estimate(Run(d, score_run.meta))
    with pytest.raises(ValueError, match="q_vel"):
        LiuUkfParams(q_vel=float("nan"))
    # a covariance that cannot be factored is a FilterError naming step, run and time, not a NaN
    bad = UkfIcr(replace(UkfIcr().params, p0_yaw=0.0))
    with pytest.raises(FilterError, match=r"step 1 \(predict\).*positive definite.*run synthetic-mixed-18, t = 0.010"):
        bad.estimate(score_run)


# ----------------------------------------------------------------------------- consistent configuration
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
    from methods.liu2020 import _ar1_plus_white

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
    gyro 0.003 rad/s.  The calibrated filter refuses its calibration run; uncalibrated, it refuses to run."""
    from methods.liu2020 import MiUkfConsistent, UkfIcrConsistent

    calib = sim("liu_calib", 100)
    m = registry.calibrate(UkfIcrConsistent(), [calib])
    gn = PLATFORM["sensors"]["gnss"]
    info = m.noise_info
    assert info["gnss_bias_tau"] == pytest.approx(gn["drift_tau"], rel=0.1)
    assert info["gnss_bias_p0"] == pytest.approx(gn["initial_drift"] / math.sqrt(2), rel=0.1)
    assert info["gnss_white_std"] == pytest.approx(gn["pos_noise"], rel=0.15)
    assert info["gnss_vel_std"] == pytest.approx(gn["vel_noise"], rel=0.15)
    assert info["gnss_yaw_std"] == pytest.approx(gn["yaw_noise"], rel=0.15)
    assert info["gyro_std"] == pytest.approx(PLATFORM["sensors"]["imu"]["gyro_noise"], rel=0.15)
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

    from methods.liu2020 import _InnovationUkf

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


@pytest.mark.parametrize("t0", [0.0, 0.3, 12.345, 1000.0, 3600.1])
def test_gap_rules_do_not_depend_on_the_rounding_of_the_times(t0):
    """A sensor at 3 samples per 7 rows of a 125 Hz log (intervals of 2 and 3 rows, median 2) has intervals of
    exactly 1.5 median intervals, the limit of both gap rules.  Whatever the start time (whose rounding decides
    without slack: 150-168 of 2096 times refused at 0, 0.3 and 3600.1 s, none at 12.345 or 1000 s), no time within
    the samples' span is a gap for _within_sampling and no sample is stale for _encoder_fresh; a real gap of 5
    rows (2.5 median intervals, one sample dropped) still is, in both (stale from 4 rows, 2 intervals, on)."""
    from methods.liu2020 import _encoder_fresh, _within_sampling

    grid = t0 + np.arange(3000) / 125.0
    rows = np.cumsum(np.tile([2, 2, 3], 300))[:899]
    span = slice(rows[0], rows[-1] + 1)
    enc_ok = np.zeros(grid.size, bool)
    enc_ok[rows] = True
    assert _within_sampling(grid[rows], grid[span]).all()
    assert _encoder_fresh(grid, enc_ok)[span].all()
    gap = rows[rows != rows[400]]  # samples at rows[399] and rows[401]: 2 + 3 = 5 rows apart
    inside = _within_sampling(grid[gap], grid[span])
    assert not inside[rows[399] - rows[0] + 1:rows[401] - rows[0]].any() and inside.sum() >= grid[span].size - 4
    enc_ok[rows[400]] = False
    fresh = _encoder_fresh(grid, enc_ok)
    assert not fresh[rows[399] + 4:rows[401]].any() and fresh[rows[399]:rows[399] + 4].all()
