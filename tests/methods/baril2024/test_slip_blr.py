"""The Bayesian linear regression of DRIVE's slip (methods.baril2024.slip_blr) against closed forms computed here
independently: the posterior mean is the ridge/MAP solution of the augmented least-squares system (np.linalg.lstsq),
the posterior covariance sigma^2 (X^T X + Lambda_0)^-1, the noise-free fit recovers the generating weights, and the
predictive variance grows away from the data."""
from __future__ import annotations

import numpy as np
import pytest

from methods.baril2024.slip_blr import (
    AUTHORS_PRIOR_PRECISION, BayesianLinearRegression, SlipBlr, SlipBlrError, body_twist, idd_velocities,
    posterior, slip_features,
)
from bench.kinematics import integrate_se2


def _data(rng: np.random.Generator, n: int, w: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    X = rng.uniform(-1.5, 1.5, (n, w.size))
    return X, X @ w + rng.normal(0.0, sigma, n)


def test_posterior_mean_is_the_augmented_least_squares_solution_and_covariance_closed_form():
    rng = np.random.default_rng(0)
    w_true, sigma = np.array([0.3, -1.2, 0.05]), 0.1
    X, y = _data(rng, 200, w_true, sigma)
    lam0 = np.diag([2.0, 0.5, 10.0])  # a non-isotropic prior precision (units of 1/sigma^2)
    m0 = np.array([0.1, 0.0, -0.2])
    post = posterior(X, y, m0, lam0, noise_variance=sigma**2)
    # MAP = argmin |y - X w|^2 + (w - m0)^T Lambda0 (w - m0): least squares on [X; L^T] w = [y; L^T m0]
    L = np.linalg.cholesky(lam0)
    aug_X, aug_y = np.vstack([X, L.T]), np.concatenate([y, L.T @ m0])
    w_map = np.linalg.lstsq(aug_X, aug_y, rcond=None)[0]
    np.testing.assert_allclose(post.mean, w_map, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(post.covariance, sigma**2 * np.linalg.inv(X.T @ X + lam0), rtol=1e-10)
    # the known-noise predictive variance: sigma^2 (1 + x^T (X^T X + Lambda0)^-1 x)
    xs = rng.normal(size=(5, 3))
    mean, var = post.predict(xs)
    np.testing.assert_allclose(mean, xs @ w_map, rtol=1e-10)
    A = np.linalg.inv(X.T @ X + lam0)
    np.testing.assert_allclose(var, sigma**2 * (1 + np.array([x @ A @ x for x in xs])), rtol=1e-10)


def test_estimated_noise_is_the_normal_inverse_gamma_update():
    """Unknown noise: a_N = a0 + n/2, b_N = b0 + (y^T y + m0^T L0 m0 - m_N^T L_N m_N)/2 (the textbook form), the
    predictive variance of the Student-t b_N/(a_N - 1) (1 + x^T L_N^-1 x), and sigma^2 estimated near the truth."""
    rng = np.random.default_rng(1)
    w_true, sigma = np.array([0.8, -0.4]), 0.05
    X, y = _data(rng, 4000, w_true, sigma)
    a0, b0, lam0, m0 = 2.0, 0.01, 0.3 * np.eye(2), np.zeros(2)
    post = posterior(X, y, m0, lam0, a0, b0)
    lam_n = lam0 + X.T @ X
    m_n = np.linalg.solve(lam_n, X.T @ y)
    assert post.a == a0 + 2000
    assert post.b == pytest.approx(b0 + 0.5 * (y @ y + m0 @ lam0 @ m0 - m_n @ lam_n @ m_n), rel=1e-9)
    assert np.sqrt(post.sigma2) == pytest.approx(sigma, rel=0.05)
    x = np.array([[0.5, 2.0]])
    _, var = post.predict(x)
    assert var[0] == pytest.approx(post.b / (post.a - 1) * (1 + x[0] @ np.linalg.solve(lam_n, x[0])), rel=1e-12)
    # the class with the authors' prior is this update with w_0 = 0, Lambda_0 = 1e-12 I, a0 = b0 = 0
    auth = BayesianLinearRegression().fit(X, y)
    ref = posterior(X, y, np.zeros(2), AUTHORS_PRIOR_PRECISION * np.eye(2))
    np.testing.assert_array_equal(auth.mean, ref.mean)
    assert (auth.a, auth.b) == (ref.a, ref.b) == (2000.0, pytest.approx(0.5 * np.sum((y - X @ ref.mean) ** 2)))


def test_noise_free_fit_recovers_the_true_coefficients():
    rng = np.random.default_rng(2)
    w_true = np.array([-0.7, 0.25, 1.9])
    X, y = _data(rng, 500, w_true, 0.0)
    post = BayesianLinearRegression().fit(X, y)
    np.testing.assert_allclose(post.mean, w_true, atol=1e-9)
    assert post.sigma2 == pytest.approx(0.0, abs=1e-12)  # only the 1e-12 prior term of b_N is left


def test_predictive_variance_grows_away_from_the_data():
    rng = np.random.default_rng(3)
    X = rng.uniform(-1.0, 1.0, (100, 1))
    y = 0.4 * X[:, 0] + rng.normal(0, 0.1, 100)
    post = BayesianLinearRegression(prior_precision=1.0).fit(X, y)
    _, var = post.predict(np.array([[0.0], [1.0], [3.0], [10.0], [100.0]]))
    assert np.all(np.diff(var) > 0)
    assert var[0] == pytest.approx(post.sigma2 * (1 + 0.0), rel=1e-12)  # at x = 0 only the noise is left


def test_shapes_are_checked():
    with pytest.raises(SlipBlrError):
        posterior(np.ones((3, 2)), np.ones(4), np.zeros(2), np.eye(2))
    with pytest.raises(SlipBlrError):
        BayesianLinearRegression().fit(np.ones((3, 2)), np.ones(3)).predict(np.ones((2, 3)))
    with pytest.raises(SlipBlrError, match="no sample"):
        SlipBlr.fit((np.full(3, np.nan),) * 3, (np.zeros(3),) * 3)


def test_features_and_slip_model_recover_a_linear_slip():
    """Slips generated on the authors' regressors (v; v w; v w, v, w) are recovered, and the body velocity is
    IDD + slip."""
    rng = np.random.default_rng(4)
    v, w = rng.uniform(-1, 1, 300), rng.uniform(-1.5, 1.5, 300)
    fx, fy, fyaw = slip_features(v, w)
    np.testing.assert_array_equal(fx[:, 0], v)
    np.testing.assert_array_equal(fy[:, 0], v * w)
    np.testing.assert_array_equal(fyaw, np.column_stack([v * w, v, w]))
    sx, sy, syaw = -0.1 * v, 0.05 * v * w, 0.02 * v * w + 0.01 * v - 0.45 * w
    model = SlipBlr.fit((v, np.zeros_like(v), w), (v + sx, sy, w + syaw))
    p = model.params()
    assert p["s_x[v]"] == pytest.approx(-0.1) and p["s_y[vw]"] == pytest.approx(0.05)
    assert (p["s_yaw[vw]"], p["s_yaw[v]"], p["s_yaw[w]"]) == pytest.approx((0.02, 0.01, -0.45))
    bx, by, bw = model.body_velocity((v, np.zeros_like(v), w))
    np.testing.assert_allclose(bx, v + sx, atol=1e-12)
    np.testing.assert_allclose(by, sy, atol=1e-12)
    np.testing.assert_allclose(bw, w + syaw, atol=1e-12)


def test_body_twist_inverts_the_zero_order_hold_integration():
    """The harness integrates a velocity held over each interval exactly (integrate_se2); body_twist recovers it."""
    rng = np.random.default_rng(5)
    t = 0.05 * np.arange(41)
    vx, vy, wz = rng.uniform(-1, 1, 41), rng.uniform(-0.2, 0.2, 41), rng.uniform(-2, 2, 41)
    wz[7] = 0.0  # a straight interval
    x, y, h = integrate_se2(t, vx, vy, wz, 0.3, -1.0, 2.5)
    bx, by, bw = body_twist(x, y, h, 0.05)
    np.testing.assert_allclose(bx, vx[:-1], atol=1e-9)
    np.testing.assert_allclose(by, vy[:-1], atol=1e-9)
    np.testing.assert_allclose(bw, wz[:-1], atol=1e-9)
    ivx, ivy, iwz = idd_velocities(np.array([1.0]), np.array([3.0]), 0.2, 0.5)
    assert (ivx[0], ivy[0], iwz[0]) == pytest.approx((0.4, 0.0, 0.8))
