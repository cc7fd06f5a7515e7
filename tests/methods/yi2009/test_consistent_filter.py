"""The consistent configuration (not Yi's): the EKF loop with error states and options,
methods.yi2009.consistent.filter.run_filter_gm.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from methods.yi2009.consistent.filter import run_filter_gm
from methods.yi2009.consistent.gauss_markov import GaussMarkov
from methods.yi2009.consistent.plugin import ekf_v2_consistent, ekf_v3_consistent
from methods.yi2009.consistent.rows import IcrCorrection
from methods.yi2009.ekf import EkfParams, align_inputs, initial_state, run_filter
from methods.yi2009.s_gamma import PUBLISHED_S_GAMMA
from methods.yi2009.slip import constrained_slip
from tests.methods.yi2009.synthetic import G, R_WHEEL, TRACK, Sensors, synthetic_run


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
