"""Unscented Kalman filter core shared by the skidbench filters (written once, used by Liu 2020).

Equations cited from: F. Liu, X. Li, S. Yuan and W. Lan, "Slip-Aware Motion Estimation for Off-Road
Mobile Robots via Multi-Innovation Unscented Kalman Filter", IEEE Access, vol. 8, 2020,
doi:10.1109/ACCESS.2020.2977889 (sigma points after R. van der Merwe's scaled unscented transform).

Sigma points and weights are the scaled unscented transform of Liu et al. 2020 eqs. (16)-(18)
(van der Merwe's scaled sigma points: ``alpha``, ``beta``, ``kappa``; ``lambda = alpha^2 (n +
kappa) - n``), the prediction and update are Liu eqs. (19)-(24), and the optional
multi-innovation correction is Liu eqs. (26)-(29).  Everything is vectorised over the sigma
points: the process function takes and returns an ``(n_sigma, n)`` array, the measurement function
takes ``(n_sigma, n)`` and returns ``(n_sigma, m)``.

Filter hygiene (DESIGN.md, "Filter hygiene"):

* angles: the caller names the state and measurement indices that are angles; their sigma-point
  means use sin/cos averaging (``atan2(sum W sin, sum W cos)``), their residuals and innovations
  are wrapped to [-pi, pi), and the angle states are wrapped after every update;
* a missing/NaN measurement element is dropped (the measurement vector shrinks, with the matching
  rows/columns of R), never fused; an all-NaN measurement is a predict-only step;
* Joseph-form covariance update (``joseph=True``, the default) with the statistically linearised
  measurement matrix ``H = Pxz^T P^-1`` (exact for a linear ``h``; then identical to FilterPy's
  ``P - K S K^T`` for the optimal gain), followed by re-symmetrisation;
* a Cholesky failure (covariance not positive definite, or not finite) raises
  :class:`FilterError` naming the step index and stage, never a silent NaN;
* optional per-element Mahalanobis gating (``gate`` in standard deviations, off by default).

Relation to FilterPy's ``UnscentedKalmanFilter`` + ``MerweScaledSigmaPoints`` (checked side by side
to 1e-9 in ``tests/test_ukf.py`` and ``tests/methods/liu2020/test_ukf.py``): same sigma points, weights, means,
gain.  Like FilterPy, the update draws fresh sigma points from the predicted ``(x, P)`` (so the
additive Q of eq. (20) enters the cross covariance) where Liu eq. (21) writes the propagated points
``x_{k+1|k}(i)``.  With ``joseph=False`` the covariance update is FilterPy's (and Liu eq. (24)'s)
``P - K S K^T``; the default Joseph form equals it for a linear ``h`` (Liu's ``h`` is linear) and
differs at second order for a nonlinear ``h``.  FilterPy has no multi-innovation update, no
element dropping (it needs the reduced ``z``, ``h``, ``R`` passed in) and no gating.

Paper equation -> code
    (16) sigma points                   Ukf._sigmas
    (17), (18) weights Wm, Wc           merwe_weights
    (19), (20) predicted mean/cov       Ukf.predict
    (21), (22) measurement mean/cov     Ukf.update
    (23) cross covariance, gain         Ukf.update
    (24) state/covariance update        Ukf.update (Joseph form by default)
    (26)-(29) multi-innovation update   Ukf.update with ``mi_weights=(1, lambda_2, ..., lambda_p)``
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg.blas import dtrsm
from scipy.linalg.lapack import dposv, dpotrf

__all__ = ["SigmaParams", "FilterError", "Ukf", "merwe_weights", "nees", "wrap", "mi_weights", "NEES_MIN_STEP_FRACTION"]

_PI = math.pi
_TWO_PI = 2.0 * math.pi

ProcessFn = Callable[..., np.ndarray]  # fx(sigmas (N, n), dt, u) -> (N, n)
MeasureFn = Callable[..., np.ndarray]  # hx(sigmas (N, n), *args) -> (N, m)


class FilterError(RuntimeError):
    """The filter cannot continue: names the step index, the stage and what failed."""

    def __init__(self, step: int, stage: str, detail: str):
        self.step, self.stage, self.detail = step, stage, detail
        super().__init__(f"UKF step {step} ({stage}): {detail}")


@dataclass(frozen=True)
class SigmaParams:
    """Scaled sigma-point parameters (Liu eqs. (16)-(18)).  Liu: ``alpha`` in [0, 1], ``beta = 2``,
    ``kappa = 0``; Liu gives no ``alpha``: 1.0 keeps every weight non-negative (a large negative
    centre weight makes the sin/cos mean of a widely spread angle unstable)."""

    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def __post_init__(self) -> None:
        if not (self.alpha > 0 and math.isfinite(self.alpha)):
            raise ValueError(f"SigmaParams.alpha = {self.alpha!r}: expected > 0")


def merwe_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean weights Wm (eq. (17)), covariance weights Wc (eq. (18)) and the spread ``n + lambda``."""
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    if not c > 0:
        raise ValueError(f"n + lambda = {c!r} must be > 0 (alpha={alpha}, kappa={kappa}, n={n})")
    wm = np.full(2 * n + 1, 0.5 / c)
    wc = wm.copy()
    wm[0] = lam / c
    wc[0] = lam / c + (1.0 - alpha**2 + beta)
    return wm, wc, c


def mi_weights(p: int, a: float) -> tuple[float, ...]:
    """Multi-innovation weights of Liu eq. (29): lambda_1 = 1, lambda_2..p = a / (p - 1)."""
    if p < 1:
        raise ValueError(f"innovation length p = {p!r}: expected >= 1")
    if not 0.0 <= a <= 1.0:
        raise ValueError(f"weight a = {a!r}: expected 0 <= a <= 1 (Liu eq. (29))")
    return (1.0,) + (a / (p - 1),) * (p - 1) if p > 1 else (1.0,)


def wrap(a: ArrayLike) -> np.ndarray:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a, dtype=float) + _PI) % _TWO_PI - _PI


# Bar-Shalom, Li, Kirubarajan 2001, Sec. 5.4: for a consistent filter the N-run average NEES lies in
# the two-sided 95% band [chi2_0.025(N n)/N, chi2_0.975(N n)/N] at about 95% of the steps.  A filter
# "passes" in this suite when it does so at >= NEES_MIN_STEP_FRACTION of the steps (some slack for
# transients and correlated steps).  The time mean of the NEES inside the single-step band is a much
# weaker test (an underconfident and an overconfident phase can average out) and is reported only.
NEES_MIN_STEP_FRACTION = 0.9


def nees(err: ArrayLike, P: ArrayLike) -> np.ndarray:
    """Normalised estimation error squared ``e^T P^-1 e`` (vectorised over leading axes).

    ``err`` has shape (..., n) and ``P`` (..., n, n); angle components of ``err`` must already be
    wrapped.  A consistent filter gives NEES ~ chi^2(n) (mean n)."""
    e = np.asarray(err, dtype=float)
    P = np.asarray(P, dtype=float)
    if P.shape[-2:] != (e.shape[-1], e.shape[-1]) or P.shape[:-2] != e.shape[:-1]:
        raise ValueError(f"nees: err shape {e.shape} does not match P shape {P.shape}")
    sol = np.linalg.solve(P, e[..., None])[..., 0]
    return np.einsum("...i,...i->...", e, sol)


class Ukf:
    """Angle-aware, vectorised unscented Kalman filter with optional multi-innovation update.

    Parameters
    ----------
    fx : ``fx(sigmas, dt, u) -> (N, n)`` process model applied to all sigma points at once.
    hx : ``hx(sigmas, *args) -> (N, m)`` measurement model applied to all sigma points at once.
    x0, P0 : initial mean (n,) and covariance (n, n) (Liu eq. (15)).
    Q : process noise (n, n) (additive, eq. (20)); ``predict(Q=...)`` overrides per step.
    R : measurement noise (m, m) of the full measurement vector; ``update(R=...)`` overrides.
    sigma : sigma-point parameters.
    x_angles, z_angles : indices of the state / measurement elements that are angles [rad].
    joseph : Joseph-form covariance update (default) or ``P - K S K^T``.
    gate : per-element gate in standard deviations of the innovation (``|y_j| / sqrt(S_jj)``);
        elements beyond it are dropped.  ``None`` (default, as in the papers) disables gating.
    mi_weights : (lambda_1, ..., lambda_p) of Liu eqs. (28)-(29); ``(1.0,)`` is the standard UKF.
        The correction of an update is ``sum_i lambda_i K_{k+2-i} e_{k+2-i}`` with the stored
        gain-times-innovation products of the previous updates (angle parts already wrapped); the
        covariance update uses the current gain only (eq. (28)).
    mi_covariance : (p = 2 only; not Liu's) the covariance accounts for the re-applied correction
        lambda_2 d_(k-1), d_(k-1) = K_(k-1) e_(k-1): the error of the prior and d_(k-1) are correlated (d was
        computed from the previous prior's error and measurement noise), so the filter carries
        C = Cov(prior error, d_(k-1)) and D = Cov(d_(k-1)) = K S K^T, propagates C with the statistically
        linearised process Jacobian F = Cov(X, chi) P^-1 at each prediction, and updates
        P+ = A P A^T + K R K^T + lambda_2^2 D - lambda_2 (A C + C^T A^T), A = I - K H, and
        Cov(posterior error, d_k) = A P H^T K^T - K R K^T - lambda_2 C^T H^T K^T (the error of the MI update,
        posterior error = A (prior error) - K v - lambda_2 d_(k-1), written out; Joseph form implied).
        Exact for linear models (checked against a Monte Carlo ensemble in tests/test_ukf.py).

    Linear algebra goes through LAPACK/BLAS directly (``dpotrf``, ``dposv``, ``dtrsm``): for the
    6-12 dimensional problems here the per-call overhead of ``numpy.linalg`` dominates a step.
    """

    def __init__(
        self,
        fx: ProcessFn,
        hx: MeasureFn,
        x0: ArrayLike,
        P0: ArrayLike,
        Q: ArrayLike,
        R: ArrayLike,
        *,
        sigma: SigmaParams = SigmaParams(),
        x_angles: Sequence[int] = (),
        z_angles: Sequence[int] = (),
        joseph: bool = True,
        gate: float | None = None,
        mi_weights: Sequence[float] = (1.0,),
        mi_covariance: bool = False,
    ) -> None:
        self.fx, self.hx = fx, hx
        self.x = np.array(x0, dtype=float).ravel()
        n = self.x.size
        self.n = n
        self.P = np.array(P0, dtype=float).reshape(n, n)
        self.Q = np.array(Q, dtype=float).reshape(n, n)
        self.R = np.atleast_2d(np.array(R, dtype=float))
        self.m = self.R.shape[0]
        self.sigma = sigma
        self.Wm, self.Wc, c = merwe_weights(n, sigma.alpha, sigma.beta, sigma.kappa)
        self._sqrt_c = math.sqrt(c)
        # sigma offsets: sig = x + E @ L^T with E = sqrt(n + lambda) [0; I; -I]   (eq. (16))
        self._E = self._sqrt_c * np.vstack((np.zeros((1, n)), np.eye(n), -np.eye(n)))
        self._pxz_scale = float(self.Wc[1]) * self._sqrt_c  # Pxz = Wc_1 sqrt(c) L (dZ+ - dZ-)
        self._h_scale = 0.5 / self._sqrt_c  # H = (L^-T D)^T / (2 sqrt(c))
        self._xa = tuple(sorted(set(int(i) for i in x_angles)))
        self._xa_arr = np.asarray(self._xa, dtype=np.intp)
        za = np.zeros(self.m, dtype=bool)
        za[list(z_angles)] = True
        self._za_mask = za
        self._za = tuple(int(i) for i in np.flatnonzero(za))
        self.joseph = bool(joseph)
        self.gate = None if gate is None else float(gate)
        w = tuple(float(v) for v in mi_weights)
        if not w or w[0] != 1.0:
            raise ValueError(f"mi_weights = {w!r}: lambda_1 must be 1 (Liu eq. (29))")
        self.mi_weights = w
        self.mi_covariance = bool(mi_covariance)
        if self.mi_covariance and len(w) != 2:
            raise ValueError(f"mi_covariance needs innovation length p = 2 (mi_weights of length 2), got {w!r}")
        self._mi_C = np.zeros((n, n))  # Cov(prior or posterior error, d_(k-1)) (mi_covariance)
        self._mi_D = np.zeros((n, n))  # Cov(d_(k-1))
        self._hist: deque[np.ndarray] = deque(maxlen=max(len(w) - 1, 1))
        self._eye = np.eye(n)
        self._mask_cache: dict[bytes, tuple[np.ndarray, np.ndarray, tuple[int, ...]]] = {}
        self.step = 0
        # diagnostics of the last update
        self.y: np.ndarray = np.zeros(0)
        self.S: np.ndarray = np.zeros((0, 0))
        self.K: np.ndarray = np.zeros((n, 0))
        self.used: np.ndarray = np.zeros(self.m, dtype=bool)
        self.wrap_state()

    # ------------------------------------------------------------------ helpers
    def wrap_state(self) -> None:
        x = self.x
        for i in self._xa:
            x[i] = (x[i] + _PI) % _TWO_PI - _PI

    def _chol(self, stage: str) -> np.ndarray:
        """Lower Cholesky factor of P; a failure is a :class:`FilterError` naming the step."""
        P = self.P
        L, info = dpotrf(P, lower=1, clean=1)
        if info != 0 or not (math.isfinite(L[-1, -1]) and math.isfinite(self.x.sum())):
            if not (np.isfinite(P).all() and np.isfinite(self.x).all()):
                raise FilterError(self.step, stage, "state or covariance not finite (NaN/inf)")
            ev = float(np.linalg.eigvalsh(0.5 * (P + P.T)).min())
            raise FilterError(self.step, stage,
                              f"covariance not positive definite (Cholesky failed, min eigenvalue {ev:.3e})")
        return L

    def _sigmas(self, stage: str) -> tuple[np.ndarray, np.ndarray]:
        """Sigma points of eq. (16) (rows) and the lower Cholesky factor L of P."""
        L = self._chol(stage)
        sig = self._E @ L.T
        sig += self.x
        return sig, L

    def _mean(self, X: np.ndarray, ang: tuple[int, ...]) -> np.ndarray:
        """Weighted mean (eq. (19)/(21)); angle columns by sin/cos averaging."""
        Wm = self.Wm
        m = Wm @ X
        if len(ang) == 1:
            i = ang[0]
            a = X[:, i]
            m[i] = math.atan2(Wm @ np.sin(a), Wm @ np.cos(a))
        elif ang:
            idx = list(ang)
            A = X[:, idx]
            m[idx] = np.arctan2(Wm @ np.sin(A), Wm @ np.cos(A))
        return m

    @staticmethod
    def _wrap_cols(d: np.ndarray, ang: tuple[int, ...]) -> None:
        """Wrap the angle columns of a residual array in place."""
        if len(ang) == 1:
            col = d[:, ang[0]]
            col += _PI
            np.remainder(col, _TWO_PI, out=col)
            col -= _PI
        elif ang:
            idx = list(ang)
            d[:, idx] = (d[:, idx] + _PI) % _TWO_PI - _PI

    # ------------------------------------------------------------------ filter
    def predict(self, dt: float, u: Any = None, Q: ArrayLike | None = None) -> None:
        """Eqs. (16), (19), (20): propagate the sigma points through ``fx(sigmas, dt, u)``."""
        self.step += 1
        sig, L = self._sigmas("predict")
        X = self.fx(sig, dt, u)
        x = self._mean(X, self._xa)
        d = X - x
        self._wrap_cols(d, self._xa)
        if self.mi_covariance and self._hist:
            # F = Cov(X, chi) P^-1 = (L^-T Dx)^T / (2 sqrt(c)), Dx = dX+ - dX- (as H in update)
            n = self.n
            F = dtrsm(self._h_scale, L, d[1:n + 1] - d[n + 1:], lower=1, trans_a=1).T
            self._mi_C = F @ self._mi_C
        P = (d.T * self.Wc) @ d
        P += self.Q if Q is None else Q
        P += P.T
        P *= 0.5
        self.x = x
        self.P = P

    def _subset(self, ok: np.ndarray, R: np.ndarray, cache: bool) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
        key = ok.tobytes()
        hit = self._mask_cache.get(key) if cache else None
        if hit is None:
            idx = np.flatnonzero(ok)
            hit = (idx, np.ascontiguousarray(R[np.ix_(idx, idx)]), tuple(int(i) for i in np.flatnonzero(self._za_mask[idx])))
            if cache:
                self._mask_cache[key] = hit
        return hit

    def update(self, z: ArrayLike, R: ArrayLike | None = None, args: tuple = ()) -> int:
        """Eqs. (21)-(24) (and (28) with multi-innovation).  NaN elements of ``z`` are dropped.

        Returns the number of measurement elements fused (0: nothing fused, state unchanged)."""
        z = np.asarray(z, dtype=float)
        ok = np.isfinite(z)
        nok = int(np.count_nonzero(ok))
        if nok == 0:
            self.used = ok
            return 0
        sig, L = self._sigmas("update")
        Z = self.hx(sig, *args)
        if nok < z.size:
            idx, R, za = self._subset(ok, self.R if R is None else np.asarray(R, float), R is None)
            Z = Z[:, idx]
            z = z[idx]
        else:
            R = self.R if R is None else np.asarray(R, dtype=float)
            za = self._za
        zp = self._mean(Z, za)
        dZ = Z - zp
        y = z - zp
        if za:
            self._wrap_cols(dZ, za)
            for i in za:
                y[i] = (y[i] + _PI) % _TWO_PI - _PI
        S = (dZ.T * self.Wc) @ dZ
        S += R
        n = self.n
        D = dZ[1:n + 1] - dZ[n + 1:]  # (n, m): sigma offsets are exactly +/- sqrt(c) L[:, i]
        Pxz = L @ D
        Pxz *= self._pxz_scale  # eq. (23)
        if self.gate is not None:
            keep = np.abs(y) <= self.gate * np.sqrt(np.diag(S))
            if not keep.all():
                ok = ok.copy()
                ok[np.flatnonzero(ok)[~keep]] = False
                if not keep.any():
                    self.used = ok
                    return 0
                kk = np.ix_(keep, keep)
                y, S, Pxz, D, R = y[keep], S[kk], Pxz[:, keep], D[:, keep], R[kk]
        _, KT, info = dposv(S, Pxz.T, lower=1)  # K = Pxz S^-1, S symmetric positive definite
        if info != 0:
            raise FilterError(self.step, "update", "innovation covariance S not positive definite")
        K = KT.T
        dx = K @ y
        had_past = bool(self._hist)
        if len(self.mi_weights) > 1:  # eq. (28): + sum_{i>=2} lambda_i K_{k+2-i} e_{k+2-i}
            corr = dx.copy()
            for lam, past in zip(self.mi_weights[1:], reversed(self._hist)):
                corr += lam * past
            self._hist.append(dx)
            self.x = self.x + corr
        else:
            self.x = self.x + dx
        self.wrap_state()
        P = self.P
        if self.joseph or self.mi_covariance:
            # statistical linearisation H = Pxz^T P^-1 = (L^-T D)^T / (2 sqrt(c))
            H = dtrsm(self._h_scale, L, D, lower=1, trans_a=1).T
            A = self._eye - K @ H
            KRKt = K @ R @ KT
            if self.mi_covariance:  # see the class docstring (mi_covariance)
                AP = A @ P
                P_new = AP @ A.T + KRKt
                C_new = AP @ H.T @ KT - KRKt
                if had_past:
                    lam2, C = self.mi_weights[1], self._mi_C
                    AC = A @ C
                    P_new += lam2 * lam2 * self._mi_D - lam2 * (AC + AC.T)
                    C_new -= lam2 * (C.T @ H.T @ KT)
                self._mi_C, self._mi_D = C_new, K @ S @ KT
                P = P_new
            else:
                P = A @ P @ A.T + KRKt
        else:
            P = P - K @ S @ KT
        P += P.T
        P *= 0.5
        self.P = P
        self.y, self.S, self.K, self.used = y, S, K, ok
        return int(y.size)

    def reset_history(self) -> None:
        """Forget the stored innovations of the multi-innovation update."""
        self._hist.clear()
        self._mi_C[:] = 0.0
        self._mi_D[:] = 0.0
