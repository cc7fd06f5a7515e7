"""bench.consistency: the null distribution of the NEES test statistics from a filter's own error recursion."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bench.consistency import Linearisation, NullNees, null_nees, simulate_nees
from methods.yi2009 import (PUBLISHED_S_GAMMA, EkfParams, GaussMarkov, align_inputs, initial_state, run_filter_gm)
from tests.test_yi2009 import R_WHEEL, TRACK, synthetic_run


def _random_walk(n: int, q: float, p0: float, dof: int) -> Linearisation:
    """An unobserved random walk per axis: A = I, C = q I, P_k = (p0 + k q) I (closed form)."""
    eye = np.broadcast_to(np.eye(dof), (n, dof, dof))
    return Linearisation(eye.copy(), q * eye, (p0 + q * np.arange(n))[:, None, None] * eye)


def test_simulated_errors_have_the_filter_covariance_and_chi_square_nees():
    """Unobserved 2-dof random walk (closed-form P_k = p0 + k q): the simulated errors' NEES has mean 2 and the
    chi-square(2) distribution at every step (ensemble over 4000 draws; mean within 4 standard errors, KS test at
    the last step), i.e. the recursion reproduces the filter's own covariance."""
    lin = _random_walk(300, 0.01, 0.5, 2)
    sims = simulate_nees(lin, slice(0, 2), np.ones(300, bool), 4000, np.random.default_rng(1))
    se = 2.0 / np.sqrt(4000)  # sd of chi2(2) is 2
    assert np.all(np.abs(sims.mean(axis=0) - 2.0) < 4 * se * 1.5)
    assert stats.kstest(sims[:, -1], stats.chi2(2).cdf).pvalue > 0.001


def test_fixed_fraction_rule_fails_a_consistent_random_walk_filter_often():
    """Consistent filter, 5 runs, 2-dof random-walk error, band chi2(10)/5: the share of experiments whose
    seed-averaged NEES is in band at >= 90 % of the steps, from null_nees, equals a direct simulation of the same
    experiment (cumulative sums of white noise, written out here) within Monte Carlo error, and it is well below
    1 (the rule's false-fail rate is large), while the mean fraction in band is 95 % as the band says."""
    n, runs, draws = 1500, 5, 600
    lo, hi = stats.chi2.ppf(0.025, 2 * runs) / runs, stats.chi2.ppf(0.975, 2 * runs) / runs
    lin = _random_walk(n, 1.0, 1.0, 2)
    mask = np.arange(n) >= 100
    nl = null_nees([lin] * runs, slice(0, 2), [mask] * runs, (lo, hi), draws, np.random.default_rng(2))
    rng = np.random.default_rng(3)
    direct = []
    for _ in range(draws):
        e = np.cumsum(rng.standard_normal((runs, 2, n)), axis=2)  # e_0 ~ N(0, 1), then unit increments: var k + 1
        avg = ((e**2).sum(axis=1) / (1.0 + np.arange(n))).mean(axis=0)[mask]
        direct.append(np.mean((avg >= lo) & (avg <= hi)))
    direct = np.array(direct)
    rule_null, rule_direct = np.mean(nl.in_band >= 0.9), np.mean(direct >= 0.9)
    se = np.sqrt(rule_direct * (1 - rule_direct) / draws)
    assert abs(rule_null - rule_direct) < 4 * np.sqrt(2) * se
    assert rule_direct < 0.9 and nl.in_band.mean() == pytest.approx(0.95, abs=0.02)
    assert nl.quantile_in_band(0.05) < 0.9
    lo_m, hi_m = nl.mean_interval()
    assert lo_m < 2.0 < hi_m and nl.p_mean(2.0) > 0.2 and nl.p_mean(100.0) == 0.0
    assert nl.p_in_band(1.0) == 1.0 and nl.p_in_band(-1.0) == 0.0


def test_yi_filter_linearisation_propagates_its_own_covariance():
    """run_filter_gm(store_lin=True) on a synthetic figure-8 (scheme 3, Gauss-Markov rows, traction offset): the
    stored recursion satisfies P_k = A_k P_(k-1) A_k^T + C_k at every step to 1e-9 relative (the Joseph update of
    the filter written as the error recursion), P equals the stored covariance, and the states are those of the run
    without it (bit for bit); quantisation states are refused."""
    run = synthetic_run("figure8", 3).without_truth()
    t, acc, gyr, enc = align_inputs(run)
    p = EkfParams()
    x0, p0 = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.0))
    kw = dict(wheel_radius=R_WHEEL, track=TRACK, s_gamma=PUBLISHED_S_GAMMA, params=p, x0=x0, p0=p0,
              gm_x=GaussMarkov(0.005, 2.0, 0.01), gm_y=GaussMarkov(0.03, 2.0, 0.01), variant=3, slip_rows="state",
              vx_offset=0.03 * acc[:, 0], store_cov=True)
    res, b, _ = run_filter_gm(t, acc, gyr, enc, store_lin=True, **kw)
    ref, b_ref, _ = run_filter_gm(t, acc, gyr, enc, **kw)
    assert np.array_equal(res.state, ref.state) and np.array_equal(b, b_ref)
    lin = res.lin
    assert np.array_equal(lin.p, res.cov)
    pred = np.einsum("kij,kjl,kml->kim", lin.a[1:], lin.p[:-1], lin.a[1:]) + lin.c[1:]
    scale = np.abs(lin.p[1:]).max(axis=(1, 2))[:, None, None]
    assert np.max(np.abs(pred - lin.p[1:]) / scale) < 1e-9
    with pytest.raises(ValueError, match="store_lin"):
        run_filter_gm(t, acc, gyr, enc, store_lin=True, enc_quant=0.001,
                      **{**kw, "vx_offset": None})
    with pytest.raises(ValueError, match="Linearisation.c"):
        Linearisation(lin.a, lin.c[:-1], lin.p)
    assert isinstance(NullNees.from_draws([np.ones((3, 5))], (0.5, 2.0)), NullNees)
