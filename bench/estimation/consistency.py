"""Null distribution of the NEES test statistics for a consistent filter with the same error dynamics.

Bar-Shalom's test (Bar-Shalom, Li, Kirubarajan 2001, Sec. 5.4.2) compares the N-run average NEES at each step with
the chi-square band chi2(N n_x)/N.  For a consistent filter each step is inside the band with probability 0.95, but
the steps are not independent: when the error is a slowly varying quantity (an integrated random walk, a bias) the
N-run average stays on one side of the band for long stretches, so the *fraction* of steps in the band, and the
time mean of the average NEES, scatter far more than independent steps would.  A fixed threshold on the fraction
(``bench.estimation.ukf.NEES_MIN_STEP_FRACTION``) then fails a consistent filter often (a random-walk error with 5 runs:
about 1 experiment in 5 below 90 %; measured in tests/test_consistency.py).

This module simulates what a consistent filter would give on the same experiment: the linearised error recursion
of the filter itself, e_k = A_k e_(k-1) + w_k with A_k = (I - K_k H_k) F_k and Cov w_k = C_k = (I - K_k H_k) Q_k
(I - K_k H_k)^T + K_k R_k K_k^T (the Joseph form's two terms), e_0 ~ N(0, P_0), whose covariance is exactly the
filter's P_k (covariance analysis: Gelb 1974 Sec. 7.2 / Maybeck 1979 Sec. 6.8).  Errors drawn from it are, by
construction, the errors of a filter whose model is true; their NEES test statistics are the null distribution
against which the observed ones are judged (a parametric bootstrap of the test).

Shared model errors.  Bar-Shalom's band assumes N independent runs: every random quantity of the filter's model is
drawn afresh in each.  A benchmark's seeds repeat one path and change only the sensor noise, so whatever the filter
models as a random process but is in truth a deterministic function of the path (a Gauss-Markov state for the slip
or the kinematic model's misfit) is one realisation, the same in all N runs; averaging over the seeds does not
average it.  ``Linearisation.shared`` carries the loading of that part of the noise, and :func:`null_nees` with a
``shared_seed`` draws it once per experiment for all N runs (the independent part per run), which is the null
distribution of the experiment actually run.  ``Linearisation.shared0`` does the same for the initial error of a
state the filter starts from the scenario (a given start pose, a start at rest) rather than from the run's sensors:
x0 minus the truth's start, the same in every seed.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np


@dataclass(frozen=True)
class Linearisation:
    """Per-step error recursion of a filter run: ``a`` (n, nx, nx) = (I - K H) F, ``c`` (n, nx, nx) the covariance
    of its run-own noise, ``p`` (n, nx, nx) the filter's posterior covariance (``a[0]`` unused: e_0 ~ N(0, p[0])).
    ``shared`` (n, nx, m), optional: the loading of m unit-variance noises that every run of an experiment shares
    (the model errors the runs repeat; module docstring): e_k = a_k e_(k-1) + c_k^(1/2) z_k + shared_k u_k, so
    p_k = a_k p_(k-1) a_k^T + c_k + shared_k shared_k^T, and e_0 = (p_0 - shared_0 shared_0^T - shared0
    shared0^T)^(1/2) z_0 + shared_0 u_0 + shared0 u'_0.  ``shared0`` (nx, m0), optional: a shared part of e_0 alone
    (an initial error the runs repeat: a start state taken from the scenario, not from the run's sensors).  The
    shared draws are matched by position: the columns of ``shared`` and ``shared0`` must mean the same in every
    run of an experiment."""

    a: np.ndarray
    c: np.ndarray
    p: np.ndarray
    shared: np.ndarray | None = None
    shared0: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.p.shape[0]
        for name in ("a", "c", "p"):
            arr = getattr(self, name)
            if arr.ndim != 3 or arr.shape[0] != n or arr.shape[1] != arr.shape[2] or not np.isfinite(arr).all():
                raise ValueError(f"Linearisation.{name}: shape {arr.shape}, must be a finite (n, nx, nx) stack "
                                 f"with n = {n}")
        sh = self.shared
        if sh is not None and (sh.ndim != 3 or sh.shape[:2] != self.p.shape[:2] or not np.isfinite(sh).all()):
            raise ValueError(f"Linearisation.shared: shape {sh.shape}, must be a finite (n, nx, m) stack with "
                             f"(n, nx) = {self.p.shape[:2]}")
        s0 = self.shared0
        if s0 is not None and (s0.ndim != 2 or s0.shape[0] != self.p.shape[1] or not np.isfinite(s0).all()):
            raise ValueError(f"Linearisation.shared0: shape {s0.shape}, must be a finite (nx, m0) array with nx = "
                             f"{self.p.shape[1]}")
        if sh is not None or s0 is not None:  # the run-own part of e_0's covariance must be positive semi-definite
            rest = self.p0_own()
            low = float(np.linalg.eigvalsh(0.5 * (rest + rest.T))[0])
            if low < -1e-12 * max(float(np.abs(self.p[0]).max()), 1e-300):
                raise ValueError(f"Linearisation.shared[0] / shared0: p[0] minus the shared parts has eigenvalue "
                                 f"{low:.3g} < 0 (the shared part of e_0 exceeds its covariance)")

    def p0_own(self) -> np.ndarray:
        """The covariance of the run-own part of e_0: p[0] minus the shared parts."""
        rest = self.p[0]
        if self.shared is not None:
            rest = rest - self.shared[0] @ self.shared[0].T
        if self.shared0 is not None:
            rest = rest - self.shared0 @ self.shared0.T
        return rest


def _psd_sqrt(c: np.ndarray) -> np.ndarray:
    """Batched square root L with L L^T = c of symmetric positive semi-definite matrices (eigenvalues floored at 0)."""
    lam, v = np.linalg.eigh(0.5 * (c + np.swapaxes(c, -1, -2)))
    return v * np.sqrt(np.maximum(lam, 0.0))[..., None, :]


def simulate_nees(lin: Linearisation, block: slice, mask: np.ndarray, n_draws: int, rng: np.random.Generator,
                  shared_rng: np.random.Generator | None = None) -> np.ndarray:
    """(n_draws, mask.sum()) NEES of the state ``block`` at the masked steps for ``n_draws`` error sequences of the
    recursion of ``lin`` (vectorised over the draws; the NEES uses the filter's own P block).  The run-own noise is
    drawn from ``rng``; the shared noise of ``lin.shared`` and ``lin.shared0`` from ``shared_rng`` (give every run
    of an experiment a generator in the same state: draw j of each run then shares its model errors), or from
    ``rng`` when None (the runs independent in everything)."""
    n, nx, _ = lin.p.shape
    if mask.shape != (n,):
        raise ValueError(f"simulate_nees: mask of shape {mask.shape} for {n} steps")
    sh = lin.shared
    srng = rng if shared_rng is None else shared_rng
    roots = _psd_sqrt(lin.c)
    e = _psd_sqrt(lin.p0_own()[None])[0] @ rng.standard_normal((nx, n_draws))
    if sh is not None:
        e = e + sh[0] @ srng.standard_normal((sh.shape[2], n_draws))
    if lin.shared0 is not None:
        e = e + lin.shared0 @ srng.standard_normal((lin.shared0.shape[1], n_draws))
    p_inv = np.linalg.inv(lin.p[:, block, block][mask])
    out = np.empty((n_draws, int(mask.sum())))
    j = 0
    for k in range(n):
        if k > 0:
            e = lin.a[k] @ e + roots[k] @ rng.standard_normal((nx, n_draws))
            if sh is not None:
                e = e + sh[k] @ srng.standard_normal((sh.shape[2], n_draws))
        if mask[k]:
            eb = e[block]
            out[:, j] = np.einsum("id,ij,jd->d", eb, p_inv[j], eb)
            j += 1
    return out


@dataclass(frozen=True)
class NullNees:
    """Null distribution of the two NEES test statistics over ``n_experiments`` simulated experiments of N runs:
    the fraction of steps whose N-run average NEES is in [lo, hi], and its time mean."""

    in_band: np.ndarray
    mean: np.ndarray

    @classmethod
    def from_draws(cls, sims: Sequence[np.ndarray], band: tuple[float, float]) -> "NullNees":
        """From per-run simulated NEES (each (n_experiments, T_i)): experiment j averages draw j of every run,
        step by step over the common length."""
        t = min(a.shape[1] for a in sims)
        avg = np.mean([a[:, :t] for a in sims], axis=0)
        return cls(np.mean((avg >= band[0]) & (avg <= band[1]), axis=1), np.mean(avg, axis=1))

    def quantile_in_band(self, q: float) -> float:
        return float(np.quantile(self.in_band, q))

    def p_in_band(self, observed: float) -> float:
        """Share of consistent experiments with an in-band fraction at or below ``observed`` (one-sided p)."""
        return float(np.mean(self.in_band <= observed + 1e-12))

    def mean_interval(self, confidence: float = 0.95) -> tuple[float, float]:
        a = 0.5 * (1.0 - confidence)
        return float(np.quantile(self.mean, a)), float(np.quantile(self.mean, 1.0 - a))

    def p_mean(self, observed: float) -> float:
        """Two-sided p of an observed time-mean NEES: 2 min(P(null <= obs), P(null >= obs)), at most 1."""
        return float(min(1.0, 2.0 * min(np.mean(self.mean <= observed), np.mean(self.mean >= observed))))


def truncated_sum(total: np.ndarray | None, x: np.ndarray) -> np.ndarray:
    """``total + x`` over the common length of their last axis (``x`` itself when ``total`` is None): the running
    sum of per-run series of slightly different lengths, step by step, as :meth:`NullNees.from_draws` averages them
    (one run in memory at a time)."""
    if total is None:
        return np.array(x, dtype=float)
    t = min(total.shape[-1], x.shape[-1])
    return total[..., :t] + x[..., :t]


def null_nees(lins: Sequence[Linearisation], block: slice, masks: Sequence[np.ndarray], band: tuple[float, float],
              n_experiments: int, rng: np.random.Generator, shared_seed: int | Sequence[int] | None = None
              ) -> NullNees:
    """Null distribution of the test statistics for experiments of N = len(lins) runs, run i with the recursion of
    ``lins[i]`` (each seed's own linearisation), the N-run average taken step by step over the common length.
    ``shared_seed``: the runs' shared noise (``Linearisation.shared``) is drawn from ``default_rng(shared_seed)``
    afresh for each run, i.e. one draw per experiment; None: from ``rng``, independent between the runs."""
    if not lins or len(lins) != len(masks):
        raise ValueError(f"null_nees: {len(lins)} linearisations for {len(masks)} masks")
    return NullNees.from_draws(
        [simulate_nees(lin, block, m, n_experiments, rng,
                       None if shared_seed is None else np.random.default_rng(shared_seed))
         for lin, m in zip(lins, masks)], band)
