"""FilterPy's UnscentedKalmanFilter behind bench.estimation.ukf.Ukf's interface, for the parity test of
methods/liu2020/ukf.py (tests/methods/liu2020/test_ukf.py) and the speed benchmark
(tests/bench/test_bench_filters.py)."""
from __future__ import annotations

import numpy as np

from tests.test_ukf import _sincos_mean, _wrapped_resid  # FilterPy adapters, shared


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
