"""Tests of the shared UKF core (bench/estimation/ukf.py).

Independent expectations: FilterPy's UnscentedKalmanFilter + MerweScaledSigmaPoints (a second
implementation), the closed-form linear Kalman filter (a UKF is exact on a linear-Gaussian model),
chi-square statistics of a consistent filter, and hand-computed multi-innovation corrections.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from bench.estimation.ukf import FilterError, SigmaParams, Ukf, merwe_weights, mi_weights, nees, wrap

ALPHA, BETA, KAPPA = 0.5, 2.0, 1.0
LANDMARKS = np.array([[10.0, 5.0], [-4.0, 12.0]])


# ----------------------------------------------------------------------------- models
def ctrv(sig: np.ndarray, dt: float, u=None) -> np.ndarray:
    """Constant turn rate and velocity, state (x, y, theta, v, omega); vectorised over rows."""
    x, y, th, v, w = sig.T
    out = sig.copy()
    small = np.abs(w) < 1e-9
    ws = np.where(small, 1.0, w)
    th2 = th + w * dt
    out[:, 0] = np.where(small, x + v * np.cos(th) * dt, x + v / ws * (np.sin(th2) - np.sin(th)))
    out[:, 1] = np.where(small, y + v * np.sin(th) * dt, y + v / ws * (np.cos(th) - np.cos(th2)))
    out[:, 2] = th2
    return out


def range_bearing(sig: np.ndarray) -> np.ndarray:
    """(r1, b1, r2, b2) to two landmarks; bearings relative to heading, wrapped."""
    out = np.empty((sig.shape[0], 2 * len(LANDMARKS)))
    for j, (lx, ly) in enumerate(LANDMARKS):
        dx, dy = lx - sig[:, 0], ly - sig[:, 1]
        out[:, 2 * j] = np.hypot(dx, dy)
        out[:, 2 * j + 1] = wrap(np.arctan2(dy, dx) - sig[:, 2])
    return out


def pose_meas(sig: np.ndarray) -> np.ndarray:
    """Linear measurement: (x, y, theta)."""
    return sig[:, :3].copy()


def simulate_ctrv(seed: int, steps: int, dt: float, hx, R: np.ndarray, z_angles) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = np.array([0.0, 0.0, 3.0, 1.0, 0.6])
    xs, zs = [], []
    for _ in range(steps):
        x = ctrv(x[None], dt)[0]
        x[3] += rng.normal(0, 0.05)
        x[4] += rng.normal(0, 0.02)
        x[2] = wrap(x[2])
        z = hx(x[None])[0] + rng.multivariate_normal(np.zeros(len(R)), R)
        z[list(z_angles)] = wrap(z[list(z_angles)])
        xs.append(x.copy())
        zs.append(z)
    return np.array(xs), np.array(zs)


def filterpy_ukf(fx, hx, n, m, x_angles, z_angles, x0, P0, Q, R, dt):
    """FilterPy configured with the same sin/cos mean, wrapped residuals and wrapped state add."""
    xa, za = list(x_angles), list(z_angles)

    mean_fn, resid_fn = _sincos_mean, _wrapped_resid

    def state_add(x, dx):
        out = x + dx
        out[xa] = wrap(out[xa])
        return out

    pts = MerweScaledSigmaPoints(n, alpha=ALPHA, beta=BETA, kappa=KAPPA)
    kf = UnscentedKalmanFilter(dim_x=n, dim_z=m, dt=dt, hx=lambda s: hx(s[None])[0],
                               fx=lambda s, dt: fx(s[None], dt)[0], points=pts,
                               x_mean_fn=mean_fn(xa), z_mean_fn=mean_fn(za),
                               residual_x=resid_fn(xa), residual_z=resid_fn(za), state_add=state_add)
    kf.x, kf.P, kf.Q, kf.R = x0.copy(), P0.copy(), Q.copy(), R.copy()
    return kf


def _setup(hx, R, z_angles, steps=300, seed=1):
    dt = 0.1
    Q = np.diag([1e-4, 1e-4, 1e-4, 0.05**2, 0.02**2])
    x0 = np.array([0.1, -0.1, 2.9, 0.8, 0.55])
    P0 = np.diag([0.5, 0.5, 0.2, 0.3, 0.05])
    truth, zs = simulate_ctrv(seed, steps, dt, hx, R, z_angles)
    return dt, Q, x0, P0, truth, zs


# ----------------------------------------------------------------------------- parity
def test_weights_and_sigma_points_match_filterpy():
    n = 5
    wm, wc, c = merwe_weights(n, ALPHA, BETA, KAPPA)
    pts = MerweScaledSigmaPoints(n, ALPHA, BETA, KAPPA)
    np.testing.assert_allclose(wm, pts.Wm, rtol=0, atol=1e-15)
    np.testing.assert_allclose(wc, pts.Wc, rtol=0, atol=1e-15)
    assert math.isclose(wm.sum(), 1.0, abs_tol=1e-12)
    rng = np.random.default_rng(0)
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    x = rng.normal(size=n)
    kf = Ukf(ctrv, pose_meas, x, P, np.eye(n), np.eye(3), sigma=SigmaParams(ALPHA, BETA, KAPPA))
    sig, _ = kf._sigmas("test")
    np.testing.assert_allclose(sig, pts.sigma_points(x, P), rtol=0, atol=1e-12)
    # the sigma points reproduce the mean and covariance exactly (eqs. (16)-(18))
    np.testing.assert_allclose(wm @ sig, x, atol=1e-12)
    d = sig - x
    np.testing.assert_allclose((d.T * wc) @ d, P, atol=1e-10)


@pytest.mark.parametrize("joseph", [False, True])
def test_parity_with_filterpy_nonlinear_angles(joseph):
    """CTRV with range-bearing measurements: heading and bearings cross +-pi many times.

    With joseph=False our update is FilterPy's P - K S K^T: agreement to rounding.  With the
    Joseph form and a nonlinear h the two updates differ (statistical linearisation), so only
    the state-estimate gap is bounded loosely there; the exact Joseph parity is the linear-h test."""
    R = np.diag([0.1**2, 0.02**2, 0.1**2, 0.02**2])
    dt, Q, x0, P0, truth, zs = _setup(range_bearing, R, (1, 3))
    ours = Ukf(ctrv, range_bearing, x0, P0, Q, R, sigma=SigmaParams(ALPHA, BETA, KAPPA),
               x_angles=(2,), z_angles=(1, 3), joseph=joseph)
    fp = filterpy_ukf(ctrv, range_bearing, 5, 4, (2,), (1, 3), x0, P0, Q, R, dt)
    dx = dP = 0.0
    wraps = 0
    for k, z in enumerate(zs):
        ours.predict(dt)
        fp.predict()
        ours.update(z)
        fp.update(z)
        if k and abs(truth[k, 2] - truth[k - 1, 2]) > math.pi:
            wraps += 1
        dx = max(dx, float(np.max(np.abs(wrap(ours.x - fp.x)))))
        dP = max(dP, float(np.max(np.abs(ours.P - fp.P))))
    assert wraps >= 3  # the run really exercises the angle handling
    if joseph:
        assert dx < 0.05  # same filter up to a second-order covariance difference
    else:
        assert dx < 1e-9 and dP < 1e-9, (dx, dP)
    err = wrap(ours.x[:3] - truth[-1, :3])
    assert np.all(np.abs(err) < 0.5)  # and the filter tracks the truth


def test_joseph_equals_filterpy_for_linear_measurement():
    """For a linear h the Joseph form equals P - K S K^T at the optimal gain: to 1e-9 over 300 steps."""
    R = np.diag([0.2**2, 0.2**2, 0.05**2])
    dt, Q, x0, P0, truth, zs = _setup(pose_meas, R, (2,), steps=300, seed=3)
    ours = Ukf(ctrv, pose_meas, x0, P0, Q, R, sigma=SigmaParams(ALPHA, BETA, KAPPA),
               x_angles=(2,), z_angles=(2,), joseph=True)
    fp = filterpy_ukf(ctrv, pose_meas, 5, 3, (2,), (2,), x0, P0, Q, R, dt)
    dx = dP = 0.0
    for z in zs:
        ours.predict(dt)
        fp.predict()
        ours.update(z)
        fp.update(z)
        dx = max(dx, float(np.max(np.abs(wrap(ours.x - fp.x)))))
        dP = max(dP, float(np.max(np.abs(ours.P - fp.P))))
    assert dx < 1e-9 and dP < 1e-9, (dx, dP)


def test_nan_elements_dropped_equals_reduced_filterpy_update():
    """A NaN element is dropped: same result as FilterPy fed the reduced z, h and R."""
    R = np.diag([0.1**2, 0.02**2, 0.1**2, 0.02**2])
    dt, Q, x0, P0, truth, zs = _setup(range_bearing, R, (1, 3), steps=60, seed=5)
    rng = np.random.default_rng(9)
    ours = Ukf(ctrv, range_bearing, x0, P0, Q, R, sigma=SigmaParams(ALPHA, BETA, KAPPA),
               x_angles=(2,), z_angles=(1, 3), joseph=False)
    fp = filterpy_ukf(ctrv, range_bearing, 5, 4, (2,), (1, 3), x0, P0, Q, R, dt)
    dropped = 0
    for z in zs:
        z = z.copy()
        z[rng.random(4) < 0.4] = np.nan
        ours.predict(dt)
        fp.predict()
        n_used = ours.update(z)
        ok = np.isfinite(z)
        assert n_used == ok.sum()
        dropped += int((~ok).sum())
        if ok.any():
            idx = np.flatnonzero(ok)
            za = [i for i, j in enumerate(idx) if j in (1, 3)]
            fp.z_mean = _sincos_mean(za)
            fp.residual_z = _wrapped_resid(za)
            fp.update(z[ok], R=R[np.ix_(idx, idx)], hx=lambda s: range_bearing(s[None])[0][idx])
        assert np.all(np.isfinite(ours.x)) and np.all(np.isfinite(ours.P))
        np.testing.assert_allclose(wrap(ours.x - fp.x), 0, atol=1e-9)
        np.testing.assert_allclose(ours.P, fp.P, atol=1e-9)
    assert dropped > 50
    # an all-NaN measurement is a predict-only step
    x, P = ours.x.copy(), ours.P.copy()
    assert ours.update(np.full(4, np.nan)) == 0
    assert np.array_equal(ours.x, x) and np.array_equal(ours.P, P)


def _sincos_mean(idx):
    def f(sigmas, Wm):
        mu = np.dot(Wm, sigmas)
        for i in idx:
            mu[i] = math.atan2(np.dot(Wm, np.sin(sigmas[:, i])), np.dot(Wm, np.cos(sigmas[:, i])))
        return mu
    return f


def _wrapped_resid(idx):
    def f(a, b):
        d = np.subtract(a, b)
        d[idx] = wrap(d[idx])
        return d
    return f


# ----------------------------------------------------------------------------- closed form
def _linear_model(seed: int, steps: int):
    dt = 0.1
    F = np.array([[1, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1.0]])
    G = np.array([[dt**2 / 2, 0], [dt, 0], [0, dt**2 / 2], [0, dt]])
    Q = G @ G.T * 0.5**2
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    R = np.diag([0.3**2, 0.2**2])
    rng = np.random.default_rng(seed)
    x = np.zeros(4)
    xs, zs = [], []
    for _ in range(steps):
        x = F @ x + G @ rng.normal(0, 0.5, 2)
        xs.append(x)
        zs.append(H @ x + rng.normal(0, [0.3, 0.2]))
    return dt, F, Q, H, R, np.array(xs), np.array(zs)


def test_linear_gaussian_equals_kalman_filter_and_is_consistent():
    """A UKF is exact on a linear-Gaussian model: it equals the Kalman filter, and its time-
    averaged NEES lies in the two-sided 99% chi-square interval."""
    from scipy.stats import chi2

    steps = 1200
    dt, F, Q, H, R, xs, zs = _linear_model(11, steps)
    x0, P0 = np.zeros(4), np.eye(4)
    kf = Ukf(lambda s, dt, u: s @ F.T, lambda s: s @ H.T, x0, P0, Q, R, sigma=SigmaParams(0.3, 2.0, 0.0))
    x, P = x0.copy(), P0.copy()
    e, Ps = [], []
    for z in zs:
        kf.predict(dt)
        kf.update(z)
        x, P = F @ x, F @ P @ F.T + Q
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x, P = x + K @ (z - H @ x), (np.eye(4) - K @ H) @ P
        np.testing.assert_allclose(kf.x, x, atol=1e-9)
        np.testing.assert_allclose(kf.P, P, atol=1e-9)
        e.append(kf.x)
        Ps.append(kf.P)
    err = np.array(e) - xs
    v = nees(err[100:], np.array(Ps)[100:])
    N = len(v)
    lo, hi = chi2.ppf([0.005, 0.995], 4 * N) / N
    # errors are correlated in time: widen the interval by a factor covering the autocorrelation
    assert 0.8 * lo < v.mean() < 1.2 * hi, (v.mean(), lo, hi)
    assert 3.0 < v.mean() < 5.0


def test_nees_closed_form():
    rng = np.random.default_rng(2)
    e = rng.normal(size=(50, 3))
    s = rng.uniform(0.5, 2.0, size=(50, 3))
    P = np.zeros((50, 3, 3))
    P[:, range(3), range(3)] = s**2
    np.testing.assert_allclose(nees(e, P), np.sum((e / s) ** 2, axis=1), rtol=1e-12)
    A = rng.normal(size=(3, 3))
    Pf = A @ A.T + np.eye(3)
    assert math.isclose(float(nees(e[0], Pf)), float(e[0] @ np.linalg.inv(Pf) @ e[0]), rel_tol=1e-10)
    with pytest.raises(ValueError):
        nees(e, Pf)


# ----------------------------------------------------------------------------- hygiene
def test_cholesky_failure_names_step():
    kf = Ukf(ctrv, pose_meas, np.zeros(5), np.eye(5), np.eye(5) * 1e-3, np.eye(3))
    for _ in range(3):
        kf.predict(0.1)
        kf.update(np.zeros(3))
    kf.P = -np.eye(5)
    with pytest.raises(FilterError, match=r"step 4 \(predict\).*not positive definite"):
        kf.predict(0.1)
    kf2 = Ukf(ctrv, pose_meas, np.zeros(5), np.eye(5), np.eye(5) * 1e-3, np.eye(3))
    kf2.predict(0.1)
    kf2.P[1, 0] = kf2.P[0, 1] = np.nan
    with pytest.raises(FilterError, match=r"step 1 \(update\).*not finite"):
        kf2.update(np.zeros(3))
    kf3 = Ukf(ctrv, pose_meas, np.array([np.nan, 0, 0, 0, 0]), np.eye(5), np.eye(5), np.eye(3))
    with pytest.raises(FilterError, match="step 1"):
        kf3.predict(0.1)


def test_angle_mean_across_wrap_is_sincos():
    """Sigma points straddling +-pi: the mean is near pi, not the arithmetic mean near 0."""
    ident = lambda s, dt, u: s.copy()  # noqa: E731
    kf = Ukf(ident, lambda s: s[:, :1], [math.pi - 0.05], [[0.2**2]], [[0.0]], [[1.0]], x_angles=(0,))
    kf.predict(0.1)
    assert abs(wrap(kf.x[0] - (math.pi - 0.05))) < 1e-6
    assert math.isclose(kf.P[0, 0], 0.04, rel_tol=1e-6)  # residuals wrapped: no 2 pi spread
    naive = Ukf(ident, lambda s: s[:, :1], [math.pi - 0.05], [[0.2**2]], [[0.0]], [[1.0]], x_angles=())
    naive.predict(0.1)
    assert math.isclose(naive.x[0], math.pi - 0.05, abs_tol=1e-9)  # (no wrap: no problem either)


def test_heading_tracking_across_wrap_needs_angle_awareness():
    """Track a spinning heading with wrapped measurements.  Angle-aware: every step-to-step change
    is bounded by rate * dt + noise margin.  Negative control: without angle indices the
    innovation at the wrap is ~2 pi and the estimate jumps."""
    dt, rate = 0.05, 2.0
    fx = lambda s, dt, u: np.column_stack([s[:, 0] + s[:, 1] * dt, s[:, 1]])  # noqa: E731
    hx = lambda s: s[:, :1]  # noqa: E731
    rng = np.random.default_rng(4)
    t = np.arange(400) * dt
    z = wrap(0.3 + rate * t + rng.normal(0, 0.02, t.size))

    def run(angles):
        kf = Ukf(fx, hx, [0.3, rate], np.diag([0.01, 0.01]), np.diag([1e-6, 1e-4]), [[0.02**2]],
                 x_angles=angles, z_angles=angles, mi_weights=mi_weights(2, 0.5))
        out = []
        for zk in z[1:]:
            kf.predict(dt)
            kf.update([zk])
            out.append(kf.x[0])
        return np.array(out)

    good = run((0,))
    assert np.max(np.abs(wrap(np.diff(good)))) < rate * dt + 0.05
    bad = run(())
    assert np.max(np.abs(wrap(np.diff(bad)))) > 0.5


def test_gating_drops_outlier_element():
    R = np.diag([0.2**2, 0.2**2, 0.05**2])
    args = dict(sigma=SigmaParams(ALPHA, BETA, KAPPA), x_angles=(2,), z_angles=(2,))
    x0, P0, Q = np.array([0, 0, 0.5, 1.0, 0.1]), np.eye(5) * 0.1, np.eye(5) * 1e-3
    gated = Ukf(ctrv, pose_meas, x0, P0, Q, R, gate=4.0, **args)
    ref = Ukf(ctrv, pose_meas, x0, P0, Q, R, **args)
    off = Ukf(ctrv, pose_meas, x0, P0, Q, R, **args)
    for f in (gated, ref, off):
        f.predict(0.1)
    z = ctrv(x0[None], 0.1)[0][:3]
    z_bad = z.copy()
    z_bad[0] += 50.0
    assert gated.update(z_bad) == 2
    assert not gated.used[0] and gated.used[1:].all()
    ref.update(np.array([np.nan, z[1], z[2]]))
    np.testing.assert_allclose(gated.x, ref.x, atol=1e-12)
    np.testing.assert_allclose(gated.P, ref.P, atol=1e-12)
    assert off.update(z_bad) == 3 and off.x[0] > 5.0  # without gating the outlier is fused


def test_multi_innovation_adds_weighted_past_correction():
    """Eq. (28) with p = 2, a = 0.5: x+ = x_pred + K_k e_k + 0.5 K_{k-1} e_{k-1}; P as the UKF."""
    R = np.diag([0.2**2, 0.2**2, 0.05**2])
    dt, Q, x0, P0, truth, zs = _setup(pose_meas, R, (2,), steps=5, seed=8)
    kw = dict(sigma=SigmaParams(ALPHA, BETA, KAPPA), x_angles=(2,), z_angles=(2,))
    mi = Ukf(ctrv, pose_meas, x0, P0, Q, R, mi_weights=mi_weights(2, 0.5), **kw)
    assert mi.mi_weights == (1.0, 0.5)
    mi.predict(dt)
    mi.update(zs[0])
    first = mi.K @ mi.y
    std = Ukf(ctrv, pose_meas, mi.x, mi.P, Q, R, **kw)
    mi.predict(dt)
    std.predict(dt)
    mi.update(zs[1])
    std.update(zs[1])
    np.testing.assert_allclose(wrap(mi.x - wrap_vec(std.x + 0.5 * first)), 0, atol=1e-12)
    np.testing.assert_allclose(mi.P, std.P, atol=1e-14)
    assert mi_weights(3, 0.5) == (1.0, 0.25, 0.25)
    with pytest.raises(ValueError):
        mi_weights(2, 1.5)


def test_mi_covariance_matches_a_monte_carlo_ensemble_where_the_plain_mi_covariance_does_not():
    """Linear constant-velocity model, position measured (sd 0.05), MI update p = 2, a = 0.5: over 500 Monte Carlo
    trials (truth and noise drawn from the model), the ensemble-mean NEES of steps 1-11 is 2 (chi-square, 2 dof;
    sampling sd of the pooled mean < 0.05) when the covariance accounts for the re-applied correction
    (``mi_covariance``), but well above 2 with Liu's covariance (24), which ignores it.  The first step (no past
    correction yet) is the plain Kalman filter in both."""
    dt = 0.1
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = np.diag([1e-5, 4e-3])
    R = np.array([[0.05**2]])
    P0 = np.diag([0.1**2, 0.2**2])

    def fx(sig, dt_, u):
        return sig @ F.T

    def hx(sig):
        return sig[:, :1]

    rng = np.random.default_rng(1)
    M, T = 500, 12
    nees_mc = {False: np.zeros((M, T)), True: np.zeros((M, T))}
    for m in range(M):
        x_true0 = rng.multivariate_normal([0.0, 0.5], P0)
        w = rng.multivariate_normal([0.0, 0.0], Q, size=T)
        v = 0.05 * rng.standard_normal(T)
        for micov in (False, True):
            kf = Ukf(fx, hx, [0.0, 0.5], P0, Q, R, mi_weights=mi_weights(2, 0.5), mi_covariance=micov)
            xt = x_true0
            for k in range(T):
                xt = F @ xt + w[k]
                kf.predict(dt)
                kf.update([xt[0] + v[k]])
                e = xt - kf.x
                nees_mc[micov][m, k] = e @ np.linalg.solve(kf.P, e)
    with_cov, plain = nees_mc[True].mean(axis=0), nees_mc[False].mean(axis=0)
    assert with_cov[0] == plain[0]
    assert abs(with_cov[1:].mean() - 2.0) < 0.15
    assert plain[1:].mean() > 2.5
    with pytest.raises(ValueError, match="p = 2"):
        Ukf(fx, hx, [0.0, 0.5], P0, Q, R, mi_weights=mi_weights(3, 0.5), mi_covariance=True)


def wrap_vec(x):
    x = x.copy()
    x[2] = wrap(x[2])
    return x


@settings(max_examples=25, deadline=None)
@given(k_meas=st.lists(st.integers(-3, 3), min_size=30, max_size=30), k0=st.integers(-2, 2),
       theta0=st.floats(-math.pi, math.pi))
def test_invariant_to_2pi_shifts_of_angles(k_meas, k0, theta0):
    """Property: adding 2 pi k to any angle measurement or to the initial heading changes nothing
    (the wrap is applied to innovations, residuals, means and the state), and the heading state
    always lies in [-pi, pi)."""
    R = np.diag([0.2**2, 0.2**2, 0.05**2])
    rng = np.random.default_rng(abs(hash((tuple(k_meas), k0))) % 2**32)
    x0 = np.array([0.0, 0.0, theta0, 1.0, 0.9])
    zs = [np.array([0.1 * i, 0.05 * i, wrap(theta0 + 0.09 * i)]) + rng.normal(0, 0.05, 3) for i in range(30)]
    kw = dict(sigma=SigmaParams(ALPHA, BETA, KAPPA), x_angles=(2,), z_angles=(2,), mi_weights=mi_weights(2, 0.5))
    a = Ukf(ctrv, pose_meas, x0, np.eye(5) * 0.1, np.eye(5) * 1e-3, R, **kw)
    b = Ukf(ctrv, pose_meas, x0 + [0, 0, 2 * math.pi * k0, 0, 0], np.eye(5) * 0.1, np.eye(5) * 1e-3, R, **kw)
    for z, k in zip(zs, k_meas):
        a.predict(0.1)
        b.predict(0.1)
        a.update(z)
        b.update(z + [0, 0, 2 * math.pi * k])
        assert -math.pi <= b.x[2] < math.pi
        np.testing.assert_allclose(wrap(a.x - b.x), 0, atol=1e-9)
        np.testing.assert_allclose(a.P, b.P, atol=1e-9)
