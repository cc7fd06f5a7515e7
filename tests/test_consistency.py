"""bench.estimation.consistency: the null distribution of the NEES test statistics from a filter's own error recursion."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bench.estimation.consistency import Linearisation, NullNees, null_nees, simulate_nees, truncated_sum
from methods.yi2009 import (PUBLISHED_S_GAMMA, EkfParams, GaussMarkov, align_inputs, initial_state, run_filter_gm,
                           shared_initial_states)
from tests.methods.yi2009.synthetic import R_WHEEL, TRACK, synthetic_run


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


def _shared_random_walk(n: int, q: float, p0: float, rho: float) -> Linearisation:
    """A 2-dof unobserved random walk whose noise (and e_0) is a share ``rho`` of variance shared by the runs of an
    experiment and 1 - rho their own; P_k = (p0 + k q) I as in :func:`_random_walk`."""
    lin = _random_walk(n, q, p0, 2)
    sh = np.broadcast_to(np.sqrt(rho * q) * np.eye(2), (n, 2, 2)).copy()
    sh[0] = np.sqrt(rho * p0) * np.eye(2)
    return Linearisation(lin.a, (1.0 - rho) * lin.c, lin.p, sh)


def test_shared_noise_correlates_the_runs_as_the_closed_form_says():
    """Runs that share a share rho of every noise (rho = 0.6, 5 runs, 3000 experiments): each run's NEES is still
    chi-square(2) (its marginal is the filter's P), two runs' errors have correlation rho per axis, so their NEES
    (a sum of two squares) correlation rho^2, and the 5-run average NEES has variance 4/N (1 + (N - 1) rho^2) instead
    of chi2(2N)/N's 4/N (closed forms for jointly Gaussian errors; each checked at 3 steps within about 3 Monte Carlo
    standard errors).  Through null_nees(shared_seed) the time mean's spread over the experiments grows by about the
    factor sqrt(1 + (N - 1) rho^2) = 1.56 over the independent runs' (exact for a white error; the random walk's
    steps are correlated, but every step's terms scale alike).  The runs' shared draws are the same only with a
    shared generator: without it the runs are independent (correlation ~ 0), and with rho = 1 every run is the same
    draw.  A shared part larger than P_0 is refused."""
    n, runs, draws, rho = 200, 5, 3000, 0.6
    lin = _shared_random_walk(n, 0.02, 0.5, rho)
    mask = np.ones(n, bool)
    sims = [simulate_nees(lin, slice(0, 2), mask, draws, np.random.default_rng([4, i]), np.random.default_rng(5))
            for i in range(runs)]
    for k in (0, 99, 199):
        x = np.array([a[:, k] for a in sims])
        expect = 4.0 / runs * (1 + (runs - 1) * rho**2)
        assert x.mean() == pytest.approx(2.0, abs=3.5 * np.sqrt(expect / draws))
        corr = np.corrcoef(x[0], x[1])[0, 1]
        assert corr == pytest.approx(rho**2, abs=0.07)
        assert x.mean(axis=0).var() == pytest.approx(expect, rel=0.12)
    lo, hi = stats.chi2.ppf(0.025, 2 * runs) / runs, stats.chi2.ppf(0.975, 2 * runs) / runs
    shared = null_nees([lin] * runs, slice(0, 2), [mask] * runs, (lo, hi), 400, np.random.default_rng(6), shared_seed=7)
    indep = null_nees([lin] * runs, slice(0, 2), [mask] * runs, (lo, hi), 400, np.random.default_rng(6))
    assert shared.mean.std() / indep.mean.std() == pytest.approx(np.sqrt(1 + (runs - 1) * rho**2), rel=0.25)
    same = [simulate_nees(_shared_random_walk(n, 0.02, 0.5, 1.0), slice(0, 2), mask, 50, np.random.default_rng(i),
                          np.random.default_rng(8)) for i in range(2)]
    assert np.allclose(same[0], same[1], rtol=1e-12, atol=0.0)
    ind2 = [simulate_nees(lin, slice(0, 2), mask, draws, np.random.default_rng([9, i])) for i in range(2)]
    assert abs(np.corrcoef(ind2[0][:, -1], ind2[1][:, -1])[0, 1]) < 0.07
    with pytest.raises(ValueError, match="Linearisation.shared"):
        Linearisation(lin.a, lin.c, lin.p, lin.shared[:-1])
    with pytest.raises(ValueError, match=r"Linearisation.shared\[0\]"):
        Linearisation(lin.a, lin.c, lin.p, 1.5 * lin.shared)


def _recursion_misfit(lin: Linearisation) -> float:
    """Largest relative misfit of P_k = A_k P_(k-1) A_k^T + C_k + S_k S_k^T over the steps."""
    pred = np.einsum("kij,kjl,kml->kim", lin.a[1:], lin.p[:-1], lin.a[1:]) + lin.c[1:]
    if lin.shared is not None:
        pred = pred + np.einsum("kim,kjm->kij", lin.shared[1:], lin.shared[1:])
    scale = np.abs(lin.p[1:]).max(axis=(1, 2))[:, None, None]
    return float(np.max(np.abs(pred - lin.p[1:]) / scale))


def test_yi_filter_linearisation_propagates_its_own_covariance():
    """run_filter_gm(store_lin=True) on a synthetic figure-8 (scheme 3, Gauss-Markov rows, traction offset): the
    stored recursion satisfies P_k = A_k P_(k-1) A_k^T + C_k + S_k S_k^T at every step to 1e-9 relative (the Joseph
    update of the filter written as the error recursion, S the shared loading of the two Gauss-Markov states'
    driving noise), P equals the stored covariance, and the states are those of the run without it (bit for bit).
    The shared loading at k = 0 is the error states' stationary sd (0.005, 0.03), so P_0 - S_0 S_0^T is P_0 with
    those two variances removed; the shared noise is what (I - K H) makes of the driving noise sigma^2 (1 - a^2)
    (checked at a step from the stored A: column b of S_k is sqrt(q_b) times the b column of (I - K H), which is
    A_k's b column / a).  The identity holds with the odometer state (reset after each window) and per-step
    Gauss-Markov sds too, whose shared loading at k = 0 is the first step's sd.  Quantisation states are refused."""
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
    sh = lin.shared
    assert sh is not None and sh.shape == (t.size, lin.p.shape[1], 2)
    assert np.allclose(np.diag(sh[0][9:11]), [0.005, 0.03], rtol=1e-12) and not sh[0][:9].any()
    dt, k = float(np.median(np.diff(t))), 500
    a_b = np.exp(-dt / 2.0)  # both states' tau = 2 s
    ikh_b = lin.a[k][:, 9:11] / a_b  # F's b columns are a on the diagonal and 0 elsewhere (no odometer here)
    assert np.allclose(sh[k], ikh_b * np.array([0.005, 0.03]) * np.sqrt(1 - a_b**2), rtol=1e-9, atol=1e-15)
    assert _recursion_misfit(lin) < 1e-9
    # the odometer (its state reset to 0 after each window) and per-step Gauss-Markov sds (sigma_k of the yaw rate)
    sig = np.array([0.005, 0.03]) * (1.0 + 0.5 * np.abs(np.sin(0.3 * t)))[:, None]
    odo, _, _ = run_filter_gm(t, acc, gyr, enc, store_lin=True, odo_window=25, odo_sd=1e-4, gm_sigma=sig, **kw)
    assert odo.lin.shared is not None and _recursion_misfit(odo.lin) < 1e-9
    assert np.allclose(np.diag(odo.lin.shared[0][9:11]), sig[0], rtol=1e-12)
    # initial errors the seeds share (x0 from the scenario, not the sensors): their block of P0's square root is
    # shared0, column j for state j (zero columns for roll and pitch here); the per-step loading is unchanged
    init = (0, 1, 2, 3, 4, 5, 8)
    shi, _, _ = run_filter_gm(t, acc, gyr, enc, store_lin=True, shared_init=init, **kw)
    s0 = shi.lin.shared0
    assert np.array_equal(shi.state, ref.state) and np.array_equal(shi.lin.shared, sh)
    assert s0.shape == (lin.p.shape[1], 9) and not s0[:, [6, 7]].any() and not s0[9:].any()
    assert np.allclose(s0[:9], np.diag(np.where(np.isin(np.arange(9), init), np.sqrt(np.diag(p0)), 0.0)),
                       rtol=1e-12, atol=0.0)
    rest = shi.lin.p0_own()  # what is drawn per run: roll and pitch, and the error states' run-own part (none)
    assert np.allclose(np.diag(rest)[[6, 7]], np.diag(p0)[[6, 7]], rtol=1e-12)
    assert np.allclose(np.delete(np.diag(rest), [6, 7]), 0.0, atol=1e-18)
    assert _recursion_misfit(shi.lin) < 1e-9
    with pytest.raises(ValueError, match="shared0"):  # a shared initial error larger than P0
        Linearisation(shi.lin.a, shi.lin.c, shi.lin.p, shi.lin.shared, 1.01 * s0)
    with pytest.raises(ValueError, match="couples"):
        p0c = p0.copy()
        p0c[0, 6] = p0c[6, 0] = 1e-8
        run_filter_gm(t, acc, gyr, enc, store_lin=True, shared_init=init, **{**kw, "p0": p0c})
    with pytest.raises(ValueError, match="shared_init"):
        run_filter_gm(t, acc, gyr, enc, shared_init=init, **kw)
    with pytest.raises(ValueError, match="store_lin"):
        run_filter_gm(t, acc, gyr, enc, store_lin=True, enc_quant=0.001,
                      **{**kw, "vx_offset": None})
    with pytest.raises(ValueError, match="Linearisation.c"):
        Linearisation(lin.a, lin.c[:-1], lin.p)
    assert isinstance(NullNees.from_draws([np.ones((3, 5))], (0.5, 2.0)), NullNees)


def test_shared_initial_states_are_those_not_taken_from_the_sensors():
    """shared_initial_states on the x0 that initial_state builds: levelled roll/pitch (wheels at rest over the
    levelling samples) and a nonzero encoder start speed come from the run's sensors, so they stay per run;
    everything else is taken from the scenario (pose, zero velocity)."""
    p = EkfParams()
    n = 100
    acc = np.tile((0.1, -0.2, 9.8), (n, 1))
    still, rolling, creep = np.zeros((n, 2)), np.full((n, 2), 2.0), np.zeros((n, 2))
    creep[0] = 2.0  # a first encoder speed (as a log that starts moving), then wheels at rest: not levelled
    cases = {"still": (still, (0, 1, 2, 3, 4, 5, 8)), "rolling": (rolling, (0, 1, 2, 6, 7, 8)),
             "creep": (creep, (0, 1, 2, 6, 7, 8))}
    for name, (enc, want) in cases.items():
        x0, _ = initial_state(acc, enc, R_WHEEL, p, (0.0, 0.0, 0.3))
        assert shared_initial_states(enc, R_WHEEL, p, x0) == want, name
    enc0 = rolling.copy()
    enc0[0] = 0.0  # a testbed log: the first count difference is 0, so x0's speed is 0 and shared
    x0, _ = initial_state(acc, enc0, R_WHEEL, p, (0.0, 0.0, 0.3))
    assert shared_initial_states(enc0, R_WHEEL, p, x0) == tuple(range(9))


def test_truncated_sum_averages_runs_as_from_draws():
    """The replication's running sum over runs of unequal length (truncated_sum), divided by the number of runs, is
    the step-by-step average NullNees.from_draws takes of the list: same statistics, common length the shortest."""
    rng = np.random.default_rng(3)
    sims = [rng.chisquare(2, (40, t)) for t in (50, 48, 51)]
    total = None
    for a in sims:
        total = truncated_sum(total, a)
    assert total.shape == (40, 48)
    one, ref = NullNees.from_draws([total / 3], (0.5, 3.0)), NullNees.from_draws(sims, (0.5, 3.0))
    assert np.allclose(one.mean, ref.mean, rtol=1e-14) and np.array_equal(one.in_band, ref.in_band)
    obs = truncated_sum(truncated_sum(None, np.arange(5.0)), np.arange(4.0))  # 1-D series too
    assert np.array_equal(obs, [0.0, 2.0, 4.0, 6.0])
