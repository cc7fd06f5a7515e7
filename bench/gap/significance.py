"""Whole-log significance of a candidate effect, the absolute goodness of fit, detection limits.

The selection's development thresholds (:mod:`bench.gap.select`) are in units of the cost ``J``, a
weighted *mean* over the samples of each channel: they do not grow with the length of the log.  A
gyro bias of 0.57 noise sigma over 5,000 gyro samples (about 40 sigma in total) gains 0.06
``J_noise``, below ``MIN_GAIN``, and was "no significant missing effect".  This module counts the
samples.

Whole-log statistic of a candidate (:func:`chi2_gain`): with ``e = r / sigma`` the unit-variance
residuals (``z * row_scale``),

    D = sum_c ( sum_k e_ck,current^2 - sum_k e_ck,candidate^2 ) / tau_c

over the *local* channels.  For nested least squares on white Gaussian noise ``D ~ chi2_p``
(``p`` the candidate's fitted parameters, Wilks 1938); ``tau_c >= 1``, the integrated
autocorrelation time of channel ``c``'s residual under the candidate (:func:`integrated_time`:
``1 + 2 sum rho_k`` up to the first non-positive lag, Geyer 1992's initial positive sequence), makes
``N_c`` correlated samples count as ``N_c / tau_c`` independent ones.  The pose channels are left
out: they integrate every earlier error and carry the initial-pose nuisance of the alignment, so
their samples are not independent evidence (the cost and the development tests still use them).

Absolute goodness of fit (:func:`fit_quality`): the final cost over ``J_noise`` beside its sampling
band for a correct model, ``J_noise +- 3 sd`` with ``var J = sum_c w_c^2 2 s_c^4 tau_c / N_c``
(``s_c = sigma_hat_c / sigma_c``; a mean of ``N_c / tau_c`` independent squares).

Detection limits (:func:`detection_limits`): from the screening sensitivity ``S = dz/du`` at the
neutral value, the smallest change of each parameter the selection would have accepted: through the
whole-log test ``|du| = sqrt(chi2_p,alpha [I^-1]_jj)`` (``I = S_e' T^-1 S_e``, local rows,
``S_e = S * row_scale``); through the absolute gain ``|du| = sqrt(MIN_GAIN J_noise [(S'S)^-1]_jj)``; the smaller of the two.
A linearisation: reported as a size, not as a guarantee.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.stats import chi2 as chi2_dist

from bench.gap.catalogue import Effect
from bench.gap.residuals import CUMULATIVE_CHANNELS, ResidualSpace
from bench.spec import Scenario


def integrated_time(x: np.ndarray) -> float:
    """Integrated autocorrelation time ``1 + 2 sum_k rho_k`` of ``x`` (mean removed), summed up to
    the first lag with ``rho_k <= 0`` and at most ``n / 4`` lags; at least 1 (never more than ``n``
    independent samples are claimed; a differenced noise would give less than 1)."""
    v = np.asarray(x, float)
    v = v[np.isfinite(v)]
    n = v.size
    if n < 8:
        return 1.0
    v = v - v.mean()
    var = float(v @ v)
    if not var > 0:
        return 1.0
    f = np.fft.rfft(v, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[: n // 4 + 1] / var
    nonpos = np.flatnonzero(acf[1:] <= 0.0)
    stop = int(nonpos[0]) + 1 if nonpos.size else acf.size
    return max(1.0, 1.0 + 2.0 * float(np.sum(acf[1:stop])))


def _local_rows(space: ResidualSpace) -> list[tuple[str, slice]]:
    out, k = [], 0
    for c in space.channels:
        n = space.meas[c].size
        if c not in CUMULATIVE_CHANNELS:
            out.append((c, slice(k, k + n)))
        k += n
    return out


def channel_times(space: ResidualSpace, z: np.ndarray) -> dict[str, float]:
    """``tau_c`` of every local channel's unit-variance residual of the stacked residual ``z``."""
    e = z * space.row_scale()
    return {c: integrated_time(e[sl]) for c, sl in _local_rows(space)}


def chi2_gain(space: ResidualSpace, z_current: np.ndarray, z_candidate: np.ndarray) -> float:
    """The whole-log statistic ``D`` of the candidate over the current model (module docstring)."""
    rs = space.row_scale()
    e0, e1 = z_current * rs, z_candidate * rs
    tau = channel_times(space, z_candidate)
    return float(sum((e0[sl] @ e0[sl] - e1[sl] @ e1[sl]) / tau[c] for c, sl in _local_rows(space)))


def chi2_scale(space: ResidualSpace, z: np.ndarray) -> float:
    """Largest ``N_c / (w_c tau_c)`` of the local channels: a gain ``G`` in cost units is at most
    about ``G x`` this in the whole-log statistic (a cheap bound for skipping refinements)."""
    tau = channel_times(space, z)
    vals = [space.meas[c].size / (space.weight[c] * tau[c]) for c, _ in _local_rows(space)]
    return max(vals, default=0.0)


def chi2_threshold(p: int, alpha: float) -> float:
    """Upper ``alpha`` quantile of chi2 with ``p`` degrees of freedom."""
    return float(chi2_dist.isf(alpha, max(int(p), 1)))


@dataclass(frozen=True)
class FitQuality:
    """What the final model leaves against the noise floor."""

    ratio: float  # final (in-sample) cost / J_noise
    ratio_cv: float  # final held-out cost / J_noise
    band: tuple[float, float]  # sampling band of the ratio for a correct model (J_noise +- 3 sd) / J_noise
    verdict: str  # at the noise floor | above the noise floor | far above the noise floor

    def to_json(self) -> dict[str, Any]:
        return {"final_over_noise": self.ratio, "final_cv_over_noise": self.ratio_cv,
                "noise_band": list(self.band), "verdict": self.verdict}


def fit_quality(space: ResidualSpace, z_final: np.ndarray, cost: float, cost_cv: float, far_above: float
                ) -> FitQuality:
    """The absolute goodness of fit of the final model (module docstring): "far above the noise
    floor" when the held-out cost exceeds ``J_noise`` by more than ``far_above`` x ``J_noise`` and
    lies above the band; "above" when above the band only."""
    jn = max(space.j_noise, 1e-12)
    rs = space.row_scale()
    e = z_final * rs
    var, k = 0.0, 0
    for c in space.channels:
        n = space.meas[c].size
        s2 = (space.sigma_hat[c] / space.sigma[c]) ** 2
        tau = integrated_time(e[k:k + n])
        var += space.weight[c] ** 2 * 2.0 * s2 ** 2 * tau / max(n, 1)
        k += n
    sd = math.sqrt(var)
    lo, hi = (jn - 3.0 * sd) / jn, (jn + 3.0 * sd) / jn
    r, rcv = cost / jn, cost_cv / jn
    if rcv > hi and rcv - 1.0 > far_above:
        verdict = "far above the noise floor"
    elif rcv > hi:
        verdict = "above the noise floor"
    else:
        verdict = "at the noise floor"
    return FitQuality(float(r), float(rcv), (float(lo), float(hi)), verdict)


def detection_limits(space: ResidualSpace, scn: Scenario, effects: Sequence[Effect],
                     sensitivities: Mapping[str, np.ndarray | None], z0: np.ndarray, j_noise: float,
                     min_gain: float, alpha: float) -> dict[str, dict[str, Any]]:
    """Per effect and parameter: the smallest change from the neutral value the selection would
    have detected (module docstring), in the parameter's unit (a relative change for scale
    parameters fitted in log10), with how (``whole-log chi2`` or ``absolute gain``); ``None`` with a
    reason where the effect has no neutral value or no response."""
    rs = space.row_scale()
    local = np.zeros(z0.size, bool)
    inv_tau = np.zeros(z0.size)
    tau = channel_times(space, z0)
    for c, sl in _local_rows(space):
        local[sl] = True
        inv_tau[sl] = 1.0 / tau[c]
    out: dict[str, dict[str, Any]] = {}
    for e in effects:
        S = sensitivities.get(e.name)
        neutral = e.neutral(scn)
        if S is None or neutral is None or S.shape[1] != e.n_params:
            out[e.name] = {"limits": None, "reason": "no neutral value or no response to screen"}
            continue
        S = np.where(np.isfinite(S), S, 0.0)
        Se = S * rs[:, None]
        info = (Se * inv_tau[:, None]).T @ Se
        gram = S.T @ S
        try:
            ic, ig = np.linalg.pinv(info), np.linalg.pinv(gram)
        except np.linalg.LinAlgError:
            out[e.name] = {"limits": None, "reason": "no response"}
            continue
        p = e.n_params
        lim: dict[str, Any] = {}
        for j, prm in enumerate(e.params):
            if not (gram[j, j] > 0):
                lim[prm.name] = {"change": math.inf, "unit": prm.unit, "how": "no response"}
                continue
            if info[j, j] > 1e-12 * float(np.max(np.diag(info))) and info[j, j] > 0:
                du_chi2 = math.sqrt(chi2_threshold(p, alpha) * max(ic[j, j], 0.0))
            else:  # only the pose channels respond: the whole-log test does not see it
                du_chi2 = math.inf
            du_gain = math.sqrt(min_gain * j_noise * max(ig[j, j], 0.0))
            du, how = (du_chi2, "whole-log chi2") if du_chi2 <= du_gain else (du_gain, "absolute gain")
            lo, hi = e.bounds(scn)[j]  # the catalogue's, narrowed by the scenario's geometry
            span = (math.log10(hi) - math.log10(lo)) if prm.log else hi - lo
            if not du <= span:  # beyond the catalogue's bounds: these data would not detect it
                lim[prm.name] = {"change": math.inf, "unit": prm.unit, "how": "beyond the bounds"}
            elif prm.log:
                lim[prm.name] = {"change": float(neutral[j] * (10.0 ** du - 1.0)), "relative": float(10.0 ** du - 1.0),
                                 "unit": prm.unit, "how": how}
            else:
                lim[prm.name] = {"change": float(du), "unit": prm.unit, "how": how}
        out[e.name] = {"limits": lim, "nominal": dict(zip((q.name for q in e.params), map(float, neutral)))}
    return out


__all__ = ["integrated_time", "channel_times", "chi2_gain", "chi2_scale", "chi2_threshold", "FitQuality",
           "fit_quality", "detection_limits"]
