"""DRIVE's learned slip: the IDD body velocity plus three Bayesian linear regressions of the body slip.

Sources (:mod:`methods.baril2024` says what each gives): the paper's abstract ("a novel learned slip approach",
stored text), and for the formulas the authors' public code (norlab-ulaval/DRIVE,
``drive/model_training/models/learning/blr_slip.py``, ``model_trainers/blr_slip_trainer.py``).  The paper's method
section, and so its equation numbers, could not be retrieved in this session: none is cited.

Bayesian linear regression with the conjugate Normal-Inverse-Gamma prior (Murphy 2012, Sec. 7.6.3 notation)::

    y = X w + e,  e ~ N(0, sigma^2 I)
    prior:      w | sigma^2 ~ N(w_0, sigma^2 Lambda_0^-1),   sigma^2 ~ InvGamma(a_0, b_0)
    posterior:  Lambda_N = Lambda_0 + X^T X
                w_N      = Lambda_N^-1 (Lambda_0 w_0 + X^T y)
                a_N      = a_0 + N / 2
                b_N      = b_0 + (y^T y + w_0^T Lambda_0 w_0 - w_N^T Lambda_N w_N) / 2
    predictive at x*: Student-t, 2 a_N degrees of freedom, mean x*^T w_N,
                      scale^2 = (b_N / a_N)(1 + x*^T Lambda_N^-1 x*),  variance = b_N / (a_N - 1) (1 + x*^T Lambda_N^-1 x*)

as the authors' ``SlipBayesianLinearRegression`` (``train_params``, ``predict_slip``) computes it.  With a known noise
variance sigma^2 (``noise_variance``) the posterior is Gaussian, ``w ~ N(w_N, sigma^2 Lambda_N^-1)`` (the same w_N), and
the predictive variance is ``sigma^2 (1 + x*^T Lambda_N^-1 x*)``.  The authors' prior: ``w_0 = 0``, ``a_0 = b_0 = 0``,
``Lambda_0 = (variance_init / param_variance_init) I = 1e-12 I`` (``blr_slip_trainer.py``), practically flat: the
posterior mean is then least squares (:data:`AUTHORS_PRIOR_PRECISION`).

Slip (this suite's sign): ``s = body velocity - IDD velocity``, so the model's body velocity is ``IDD + E[s]``
(:meth:`SlipBlr.body_velocity`); the authors' code learns ``IDD - body`` and subtracts it, the same model with the
weights negated.  Regressors (authors' ``FullBodySlipBayesianLinearRegression.train_params``), on the IDD body
velocities ``v`` [m/s] and ``w`` [rad/s], no intercept (:data:`FEATURES`, :func:`slip_features`): longitudinal slip
on ``v``; lateral slip on ``v w`` ("centrifugal force"); angular slip on ``v w``, ``v`` ("asymmetry") and ``w``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from numpy.typing import ArrayLike

from bench.kinematics import ideal_dd

AUTHORS_PRIOR_PRECISION = 1e-12  # Lambda_0 / I = variance_init / param_variance_init = 1e9 / 1e21 (their trainer)
AXES = ("x", "y", "yaw")  # body slip: longitudinal [m/s], lateral [m/s], angular [rad/s]
FEATURES: Mapping[str, tuple[str, ...]] = {"x": ("v",), "y": ("vw",), "yaw": ("vw", "v", "w")}

Velocities = tuple[np.ndarray, np.ndarray, np.ndarray]  # (v_x [m/s], v_y [m/s], w_z [rad/s])


class SlipBlrError(ValueError):
    """Inconsistent shapes, or a fit without a single usable sample."""


# ------------------------------------------------------------------------------------------------
# Bayesian linear regression
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class BlrPosterior:
    """``w | sigma^2 ~ N(mean, sigma^2 precision^-1)``, ``sigma^2 ~ InvGamma(a, b)``, or sigma^2 = ``noise_variance``
    when it was known; ``n`` samples seen.  ``mean`` is w_N (d,), ``precision`` Lambda_N (d, d)."""

    mean: np.ndarray
    precision: np.ndarray
    a: float
    b: float
    n: int
    noise_variance: float | None = None

    @property
    def sigma2(self) -> float:
        """The noise variance: the known one, else its posterior mean ``b_N / (a_N - 1)`` (NaN when a_N <= 1)."""
        if self.noise_variance is not None:
            return float(self.noise_variance)
        return self.b / (self.a - 1.0) if self.a > 1.0 else math.nan

    @property
    def covariance(self) -> np.ndarray:
        """Posterior covariance of w: ``sigma^2 Lambda_N^-1`` (known noise; else the Student-t marginal's,
        ``b_N / (a_N - 1) Lambda_N^-1``)."""
        return self.sigma2 * np.linalg.inv(self.precision)

    def predict(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Predictive mean and variance of y at the rows of ``X`` (n, d) (module docstring)."""
        X = _design(X, self.mean.shape[0])
        leverage = np.einsum("ij,ji->i", X, np.linalg.solve(self.precision, X.T))  # x^T Lambda_N^-1 x per row
        return X @ self.mean, self.sigma2 * (1.0 + leverage)


def _design(X: ArrayLike, d: int | None = None) -> np.ndarray:
    X = np.asarray(X, float)
    X = X[:, None] if X.ndim == 1 else X
    if X.ndim != 2 or (d is not None and X.shape[1] != d):
        raise SlipBlrError(f"design matrix of shape {X.shape}; expected (n, {d if d is not None else 'd'})")
    return X


def posterior(X: ArrayLike, y: ArrayLike, mean0: ArrayLike, precision0: ArrayLike, a0: float = 0.0,
              b0: float = 0.0, noise_variance: float | None = None) -> BlrPosterior:
    """The conjugate update (module docstring) of the prior ``(w_0, Lambda_0, a_0, b_0)`` on ``X`` (n, d), ``y`` (n,)."""
    X = _design(X)
    y = np.asarray(y, float).ravel()
    m0, lam0 = np.asarray(mean0, float).ravel(), np.asarray(precision0, float)
    if y.shape[0] != X.shape[0] or m0.shape[0] != X.shape[1] or lam0.shape != (X.shape[1], X.shape[1]):
        raise SlipBlrError(f"X {X.shape}, y {y.shape}, w_0 {m0.shape}, Lambda_0 {lam0.shape} do not agree")
    lam_n = lam0 + X.T @ X
    w_n = np.linalg.solve(lam_n, lam0 @ m0 + X.T @ y)
    r, dw = y - X @ w_n, w_n - m0
    # b_N in its residual form: algebraically the module docstring's, without its cancellation
    b_n = b0 + 0.5 * (float(r @ r) + float(dw @ lam0 @ dw))
    return BlrPosterior(w_n, lam_n, a0 + 0.5 * X.shape[0], b_n, int(X.shape[0]), noise_variance)


@dataclass(frozen=True)
class BayesianLinearRegression:
    """The prior of one slip regression: ``w_0 = 0``, ``Lambda_0 = prior_precision I``, ``InvGamma(a0, b0)`` on the
    noise, or the noise variance fixed (``noise_variance``).  Defaults: the authors' prior."""

    prior_precision: float = AUTHORS_PRIOR_PRECISION
    a0: float = 0.0
    b0: float = 0.0
    noise_variance: float | None = None

    def fit(self, X: ArrayLike, y: ArrayLike) -> BlrPosterior:
        """The posterior on the rows of ``X`` (n, d) and ``y`` (n,)."""
        d = _design(X).shape[1]
        return posterior(X, y, np.zeros(d), self.prior_precision * np.eye(d), self.a0, self.b0, self.noise_variance)


# ------------------------------------------------------------------------------------------------
# kinematics of the slip model
# ------------------------------------------------------------------------------------------------
def idd_velocities(wl: ArrayLike, wr: ArrayLike, wheel_radius: float, track: float) -> Velocities:
    """Ideal differential drive from the wheel speeds [rad/s]: ``v = r (w_l + w_r)/2``, ``v_y = 0``,
    ``w = r (w_r - w_l)/B`` (:func:`bench.kinematics.ideal_dd`)."""
    r = float(wheel_radius)
    return ideal_dd(r * np.asarray(wl, float), r * np.asarray(wr, float), float(track))


def body_twist(x: ArrayLike, y: ArrayLike, yaw: ArrayLike, dt: ArrayLike) -> Velocities:
    """The constant body velocity that carries each pose to the next one along the last axis (the SE(2) logarithm of
    the relative pose, divided by ``dt`` [s], scalar or one per interval): what a zero-order-hold prediction must
    hold over that interval to reproduce the reference.  Shapes: (..., n) poses -> (..., n - 1) velocities."""
    x, y, h = (np.asarray(a, float) for a in (x, y, yaw))
    dx, dy, dh = np.diff(x, axis=-1), np.diff(y, axis=-1), np.diff(h, axis=-1)
    c, s = np.cos(h[..., :-1]), np.sin(h[..., :-1])
    bx, by = c * dx + s * dy, -s * dx + c * dy  # the next position in the current body frame
    small = np.abs(dh) < 1e-9
    ph = np.where(small, 1.0, dh)
    a = np.where(small, 1.0 - dh * dh / 6.0, np.sin(ph) / ph)
    b = np.where(small, dh / 2.0, (1.0 - np.cos(ph)) / ph)
    det = a * a + b * b
    dt = np.asarray(dt, float)
    return (a * bx + b * by) / det / dt, (-b * bx + a * by) / det / dt, dh / dt


def slip_features(v: ArrayLike, w: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Design matrices of the x, y and yaw slips (:data:`FEATURES`) from the IDD ``v`` [m/s] and ``w`` [rad/s] (any
    equal shapes, flattened): ``[v]``, ``[v w]``, ``[v w, v, w]``."""
    v, w = np.asarray(v, float).ravel(), np.asarray(w, float).ravel()
    c = v * w
    return v[:, None], c[:, None], np.column_stack((c, v, w))


@dataclass(frozen=True, eq=False)
class SlipBlr:
    """The three slip posteriors of DRIVE's model, keyed by :data:`AXES`."""

    posteriors: Mapping[str, BlrPosterior]

    @classmethod
    def fit(cls, idd: Velocities, body: Velocities, prior: BayesianLinearRegression = BayesianLinearRegression()
            ) -> "SlipBlr":
        """Slip = ``body - idd`` on the samples (any equal shapes) where every velocity is finite; one
        :meth:`BayesianLinearRegression.fit` per axis on :func:`slip_features` of the IDD velocity."""
        idd_a = [np.asarray(a, float).ravel() for a in idd]
        body_a = [np.asarray(a, float).ravel() for a in body]
        if len({a.shape for a in (*idd_a, *body_a)}) != 1:
            raise SlipBlrError("the IDD and body velocities must have the same shapes")
        ok = np.logical_and.reduce([np.isfinite(a) for a in (*idd_a, *body_a)])
        if not ok.any():
            raise SlipBlrError("no sample with finite IDD and body velocities to learn the slip from")
        feats = slip_features(idd_a[0][ok], idd_a[2][ok])
        slips = [b[ok] - i[ok] for b, i in zip(body_a, idd_a)]
        return cls({axis: prior.fit(f, s) for axis, f, s in zip(AXES, feats, slips)})

    def predict(self, v: ArrayLike, w: ArrayLike) -> tuple[Velocities, Velocities]:
        """((mean s_x, s_y, s_yaw), (their predictive variances)) at the IDD velocities, shaped like ``v``."""
        shape = np.shape(v)
        out = [self.posteriors[a].predict(f) for a, f in zip(AXES, slip_features(v, w))]
        means = tuple(m.reshape(shape) for m, _ in out)
        var = tuple(s.reshape(shape) for _, s in out)
        return means, var  # type: ignore[return-value]

    def body_velocity(self, idd: Velocities) -> Velocities:
        """The model's body velocity: IDD plus the predictive-mean slip."""
        vx, vy, wz = (np.asarray(a, float) for a in idd)
        (sx, sy, sw), _ = self.predict(vx, wz)
        return vx + sx, vy + sy, wz + sw

    def params(self) -> dict[str, float]:
        """Posterior-mean weights (``s_<axis>[<feature>]``), noise standard deviations and the sample count."""
        out: dict[str, float] = {}
        for axis in AXES:
            post = self.posteriors[axis]
            out.update({f"s_{axis}[{f}]": float(c) for f, c in zip(FEATURES[axis], post.mean)})
            out[f"sigma_{axis}"] = math.sqrt(post.sigma2) if post.sigma2 >= 0 else math.nan
        out["n"] = float(self.posteriors["x"].n)
        return out
