"""Filters under stress (bench/robustness/faults.py, bench/robustness/stress.py).

Issue: 1-hour runs, a 30 s GNSS outage, IMU saturation spikes and encoder dropouts: no NaN, the
covariance stays positive definite, and the estimate recovers after the fault (position error back
within 2x its pre-fault level within 10 s of the fault's end; bench/robustness/faults.py gives the exact
definition).

* Fault functions and measures: tests/test_faults.py (synthetic Runs, closed forms).
* Liu 2020 UKF+ICR and MI-UKF on DUBHE (scenarios/stress_dubhe_random.toml, seed 1, 180 s, faults at
  t0 = 90 s, after the GNSS initial drift has decayed): every fault, as the paper defines the filter
  and, for the GNSS outage, with the ICR hold of Liu Sec. IV-A (LiuUkfParams.icr_hold_gnss_timeout);
  and in their consistent configuration (methods.liu2020.UkfIcrConsistent / MiUkfConsistent, noise
  identified on liu_calib seed 100), which recovers from the 30 s outage the paper's filters do not
  (their non-recovery stays visible as strict xfails with the measured numbers).
* Yi 2009 EKF schemes 1-3 on Yi's robot (scenarios/stress_yi_random.toml): IMU spikes and encoder
  dropouts (Yi reads no GNSS).  Yi has no absolute position sensor: its position error grows, so
  position recovery is not defined for it and not asserted.
* The default run uses 180 s simulated runs; the 1-hour runs are behind ``@pytest.mark.slow``.

A case that genuinely fails a criterion keeps its assertion and is marked
``xfail(strict=True, reason=<measured numbers>)``.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bench.robustness import faults as F
from bench import registry
from bench.robustness import stress as S
from bench.run import Run

SEED = 1
T0 = 90.0
OUTAGE = (T0, T0 + 30.0)
DROPOUT = (T0, T0 + 10.0)
SPIKES = (T0, T0 + 1.3, T0 + 2.7)
LIU = ("liu2020.ukf_icr", "liu2020.mi_ukf")
YI = ("yi2009.ekf_v1", "yi2009.ekf_v2", "yi2009.ekf_v3")
HOLD_TIMEOUT = 1.0
RECOVER_WITHIN = 10.0


# ============================================================================================
# Liu 2020 on DUBHE
# ============================================================================================
@pytest.fixture(scope="module")
def dubhe(sim) -> Run:
    return sim("stress_dubhe_random", SEED)


@pytest.fixture(scope="module")
def liu_cases(dubhe):
    """Faulted runs: case -> (run, fault start, fault end)."""
    half = _odd_encoder_rows(dubhe)
    return {
        "none": (dubhe, *OUTAGE),
        "gnss_outage": (F.gnss_outage(dubhe, *OUTAGE), *OUTAGE),
        "imu_spikes": (F.imu_saturation_spikes(dubhe, SPIKES, 1.0, seed=0), T0, max(SPIKES)),
        "encoder_dropout": (F.encoder_dropouts(dubhe, *DROPOUT), *DROPOUT),
        # encoders at half the rate, sampled between the rows of the dropout's ends (no sample at t1)
        "encoder_50hz": (half, *DROPOUT),
        "encoder_50hz_dropout": (F.encoder_dropouts(half, *DROPOUT), *DROPOUT),
    }


def _odd_encoder_rows(run: Run) -> Run:
    """``run`` with every encoder sample of an even row removed (half the encoder rate)."""
    data = run.data.copy()
    even = np.arange(len(data)) % 2 == 0
    for c in F.ENCODER_CHANNELS:
        data.loc[even, c] = np.nan
    return Run(data, dict(run.meta))


@pytest.fixture(scope="module")
def liu_est(liu_cases):
    cache: dict = {}

    def get(name: str, case: str, hold: bool = False):
        key = (name, case, hold)
        if key not in cache:
            m = registry.get(name)
            if hold:
                m = dataclasses.replace(m, params=dataclasses.replace(m.params, icr_hold_gnss_timeout=HOLD_TIMEOUT))
            cache[key] = registry.estimate(m, liu_cases[case][0])
        return cache[key]
    return get


LIU_CASES = [(n, c, h) for n in LIU for c, h in
             (("gnss_outage", False), ("gnss_outage", True), ("imu_spikes", False), ("encoder_dropout", False))]


def _case_id(p) -> str:
    n, c, h = p
    return f"{n.split('.')[1]}-{c}{'-icr_hold' if h else ''}"


@pytest.mark.parametrize("case", LIU_CASES, ids=_case_id)
def test_liu_no_nan_and_covariance_pd(case, liu_est, liu_cases):
    """No NaN in the estimate; P symmetric positive definite at every step; and bounded: at every
    step with a GNSS fix (after the first) the posterior position std is below the GNSS std r_gnss
    (the fix alone is an estimate with that error; Liu's h is linear, so the UKF update is the
    Kalman update)."""
    name, fault, hold = case
    est = liu_est(name, fault, hold)
    run = liu_cases[fault][0]
    for c in ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr"):
        assert np.isfinite(est[c]).all(), c
    P = est.info["P"]
    assert P.shape == (run.t.size, 6, 6)
    h = F.covariance_health(P)
    assert h.positive_definite, h
    assert np.array_equal(P, np.swapaxes(P, 1, 2))
    fix = np.isfinite(run["gnss_x"]) & np.isfinite(run["gnss_y"])
    fix[0] = False  # step 0 is the prior P0 (p0_pos = r_gnss), not an update
    r_pos = registry.get(name).params.r_gnss[0]
    assert np.sqrt(np.maximum(P[fix, 0, 0], P[fix, 1, 1])).max() < r_pos


# Measured on seed 1 (pre-fault level = 95th percentile of the 1 s mean error over 70-90 s):
XFAIL_RECOVERY = {  # measured on seed 1 of the stress path (DUBHE on the dirt's Bekker soil), paired criterion
    ("liu2020.ukf_icr", "gnss_outage", False):
        "UKF+ICR as in the paper (ICR recomputed from unconstrained velocities during the outage, it wanders "
        "to the [-20, 20] clamp): max error 25.6 m, pre-fault 0.051 m, back within 2x of the fault-free error "
        "only after 28.1 s > 10 s",
    ("liu2020.mi_ukf", "gnss_outage", False):
        "MI-UKF as in the paper (ICR wanders during the outage): max error 51.9 m, pre-fault 0.038 m, back "
        "within 2x of the fault-free error only after 18.9 s > 10 s",
    ("liu2020.ukf_icr", "gnss_outage", True):
        "UKF+ICR with the Sec. IV-A ICR hold: the held ICR stops the wandering (max 1.31 m instead of 25.6 m), "
        "but the error is back within 2x of the fault-free one only after 13.7 s > 10 s. Measured: the outage "
        "ends at 1.27 m (before the soil of issue 31: 0.38 m, 5.2 s), then 0.41 m at +4 s, 0.16 at +8 s, 0.08 at "
        "+14 s (a 4-6 s decay of the paper's noise setting): from 1.3 m that takes more than 10 s to reach 0.1 m",
    ("liu2020.mi_ukf", "gnss_outage", True):
        "MI-UKF with the Sec. IV-A ICR hold: max 1.34 m instead of 51.9 m, back within 2x of the fault-free "
        "error after 11.2 s > 10 s. Measured: the outage ends at 1.30 m (before the soil of issue 31: 0.41 m, "
        "4.0 s), then 0.24 m at +4 s, 0.08 at +8-10 s, 0.02 at +14 s: the larger error the soil leaves needs "
        "more than 10 s to reach 2x the pre-fault 0.038 m",
}


def _recovery_params():
    out = []
    for case in LIU_CASES:
        reason = XFAIL_RECOVERY.get(case)
        marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
        out.append(pytest.param(case, marks=marks, id=_case_id(case)))
    return out


@pytest.mark.parametrize("case", _recovery_params())
def test_liu_recovers_after_fault(case, liu_est, liu_cases, dubhe):
    """Position error back within 2x its pre-fault level within 10 s of the fault's end."""
    name, fault, hold = case
    est = liu_est(name, fault, hold)
    _, t0, t1 = liu_cases[fault]
    t, err = F.position_error(dubhe, est)
    rec = F.recovery(t, err, t0, t1, reference=F.position_error(dubhe, liu_est(name, "none", hold))[1])
    print(f"{name} {fault} hold={hold}: pre {rec.pre:.3f} m, max {rec.max_total:.3f} m, recovery {rec.recovery_time:.2f} s")
    assert rec.recovery_time <= RECOVER_WITHIN, rec


# ---- consistent configuration (methods.liu2020.UkfIcrConsistent / MiUkfConsistent) ----
@pytest.fixture(scope="module")
def liu_consistent(sim, liu_cases):
    """name -> calibrated consistent filter (noise identified on liu_calib seed 100, not a stress run),
    and a cache of its estimates per fault."""
    from methods import liu2020

    calib = sim("liu_calib", 100)
    meth = {n: registry.calibrate(c(), [calib]) for n, c in
            (("liu2020.ukf_icr", liu2020.UkfIcrConsistent), ("liu2020.mi_ukf", liu2020.MiUkfConsistent))}
    cache: dict = {}

    def get(name: str, case: str):
        if (name, case) not in cache:
            cache[(name, case)] = registry.estimate(meth[name], liu_cases[case][0])
        return cache[(name, case)]
    return get


def _consistent_params():
    out = []
    for n in LIU:
        for fault in ("gnss_outage", "imu_spikes", "encoder_dropout"):
            marks = [] if fault == "gnss_outage" else [pytest.mark.slow]
            out.append(pytest.param(n, fault, marks=marks, id=f"{n.split('.')[1]}-{fault}"))
    return out


@pytest.mark.parametrize(("name", "fault"), _consistent_params())
def test_liu_consistent_recovers_and_stays_healthy(name, fault, liu_consistent, liu_cases, dubhe):
    """The consistent configuration: no NaN, P positive definite at every step, and the position error
    back within 2x its pre-fault level within 10 s of the fault's end (the paper's filters do not
    recover from the 30 s outage: XFAIL_RECOVERY).  Measured on seed 1: outage recovery 0.96 s
    (UKF+ICR, max 1.08 m) and 1.09 s (MI-UKF, max 4.92 m); spikes 1.71 s / 0.00 s, dropout 0.00 s."""
    est = liu_consistent(name, fault)
    for c in ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr"):
        assert np.isfinite(est[c]).all(), c
    h = F.covariance_health(est.info["P"])
    assert h.positive_definite, h
    _, t0, t1 = liu_cases[fault]
    t, err = F.position_error(dubhe, est)
    rec = F.recovery(t, err, t0, t1, reference=F.position_error(dubhe, liu_consistent(name, "none"))[1])
    print(f"consistent {name} {fault}: pre {rec.pre:.3f} m, max {rec.max_total:.3f} m, recovery {rec.recovery_time:.2f} s")
    assert rec.recovery_time <= RECOVER_WITHIN, rec


@pytest.mark.parametrize("name", LIU)
def test_liu_consistent_covariance_grows_through_outage(name, liu_consistent, liu_est, liu_cases, dubhe):
    """Why it recovers: without the encoder pose pseudo-measurement nothing observes the position
    during the outage, so its covariance grows with the dead-reckoning error (error at the outage's
    end within 3 sigma of the filter's own position std, which grew > 10x), while the paper's filter
    keeps a position std of a few cm (pose NEES >> 3) against a metres-large error.  (MI-UKF consistent, seed 1:
    error 2.4 m at sd 1.16 m; it was 5.5 sigma, 5.49 m at sd 1.00 m, while the testbed logged Bullet's step
    velocities dT/2 behind the pose, testbed version 1: the gyro then lagged the truth heading.)"""
    t = dubhe.t
    a, b = OUTAGE
    i0, i1 = int(np.searchsorted(t, a)) - 1, int(np.searchsorted(t, b)) - 1
    for est, consistent in ((liu_consistent(name, "gnss_outage"), True), (liu_est(name, "gnss_outage"), False)):
        P = est.info["P"]
        sd = np.sqrt(P[:, 0, 0] + P[:, 1, 1])
        e = math.hypot(est["x"][i1] - dubhe["truth_x"][i1], est["y"][i1] - dubhe["truth_y"][i1])
        print(f"{name} consistent={consistent}: pos sd {sd[i0]:.3f} -> {sd[i1]:.3f} m, error at outage end {e:.3f} m")
        if consistent:
            assert sd[i1] > 10 * sd[i0] and e < 3 * sd[i1]
        else:
            assert e > 3 * sd[i1]


@pytest.mark.parametrize("name", LIU)
def test_recovery_criterion_quiet_on_fault_free_run(name, liu_est, liu_cases, dubhe):
    """Validity of the criterion: the fault-free run, scored on the same windows, 'recovers' at once under the
    paired criterion (its error is not a fault's).  Why the pairing: on this path (DUBHE slipping on the dirt's
    soil) the fault-free error itself rises beyond 2x its pre-fault band after one of the windows, so the unpaired
    criterion would flag a run that had no fault."""
    est = liu_est(name, "none")
    t, err = F.position_error(dubhe, est)
    unpaired = []
    for fault in ("gnss_outage", "imu_spikes", "encoder_dropout"):
        _, t0, t1 = liu_cases[fault]
        assert F.recovery(t, err, t0, t1, reference=err).recovery_time == 0.0, fault
        unpaired.append(F.recovery(t, err, t0, t1).recovery_time)
    assert max(unpaired) > RECOVER_WITHIN, unpaired


@pytest.mark.parametrize("name", LIU)
def test_liu_icr_through_outage(name, liu_est, liu_cases, dubhe):
    """Paper: the ICR, recomputed from unconstrained velocities during the outage, wanders (to the
    [-20, 20] clamp).  Hold: constant from 1 s after the last fix until GNSS returns, equal to the
    least-squares solution of eqs. (2), (3), (5) over the previous 20 s (second implementation:
    numpy lstsq on the estimate's own columns)."""
    run = liu_cases["gnss_outage"][0]
    t = run.t
    paper, held = liu_est(name, "gnss_outage"), liu_est(name, "gnss_outage", True)
    fix_t = t[np.isfinite(run["gnss_x"]) & np.isfinite(run["gnss_y"])]
    last = fix_t[np.maximum(np.searchsorted(fix_t, t, side="right") - 1, 0)]
    hold_rows = t - last > HOLD_TIMEOUT
    assert held.info["icr_held_steps"] == int(hold_rows.sum())
    # last fix at t0 - 0.1 s (10 Hz): held from t0 - 0.1 + timeout to the end of the outage (+-1 row at the boundary)
    assert abs(held.info["icr_held_steps"] - int(np.sum((t > OUTAGE[0] - 0.1 + HOLD_TIMEOUT) & (t < OUTAGE[1])))) <= 1
    k = int(np.flatnonzero(hold_rows)[0])
    icr = np.column_stack((held["y_l"], held["y_r"], held["x_icr"]))
    assert np.all(icr[hold_rows] == icr[k])
    r = dubhe.meta["platform"]["wheel_radius"]
    w = (t >= t[k] - 20.0) & (np.arange(t.size) < k) & ~hold_rows & (np.abs(held["wz"]) >= 1e-3)
    wz = held["wz"][w][:, None]
    expect = [np.linalg.lstsq(wz, rhs, rcond=None)[0][0] for rhs in
              (held["vx"][w] - r * held["wl"][w], held["vx"][w] - r * held["wr"][w], -held["vy"][w])]
    np.testing.assert_allclose(icr[k], np.clip(expect, -20, 20), rtol=1e-9, atol=1e-12)
    out = (t >= OUTAGE[0]) & (t < OUTAGE[1])
    spread = np.ptp(paper["y_l"][out]) + np.ptp(paper["y_r"][out]) + np.ptp(paper["x_icr"][out])
    assert spread > 10.0
    assert max(np.abs(paper[c][out]).max() for c in ("y_l", "y_r", "x_icr")) == 20.0  # at the clamp
    before = t < OUTAGE[0]
    for c in ("x", "y", "yaw"):  # identical before the outage: the hold changes nothing while GNSS is there
        assert np.array_equal(paper[c][before], held[c][before])


@pytest.mark.parametrize("name", LIU)
def test_liu_encoder_dropout_is_not_fused(name, liu_est, liu_cases):
    run = liu_cases["encoder_dropout"][0]
    est = liu_est(name, "encoder_dropout")
    nf = est.info["n_fused"]
    win = (run.t >= DROPOUT[0]) & (run.t < DROPOUT[1])
    assert nf[win].max() <= 6  # GNSS block (5) + gyro only: the encoder block is dropped
    enc = np.isfinite(run["enc_wl"]) & np.isfinite(run["enc_wr"])
    assert np.all(nf[enc & ~win][1:] >= 7)  # elsewhere the 6 encoder elements are fused


def _dropout_cases(rate: str) -> tuple[str, str]:
    """(case with the dropout, the same case without it) of liu_cases at encoder ``rate`` ("" for 100 Hz)."""
    return (f"{rate}_dropout", rate) if rate else ("encoder_dropout", "none")


def _stale_rows(run: Run) -> tuple[np.ndarray, int, float]:
    """(stale rows, last fresh row before the dropout, time of the first pair after it) of ``run`` with the
    encoder dropout DROPOUT: the rows before the first encoder pair, and the rows after the last pair before
    the dropout has aged beyond 1.5 median sample intervals (methods.liu2020.TIME_SLACK of slack) until the
    first pair after it (whatever the encoder rate: that pair need not fall on the dropout's end)."""
    from methods.liu2020 import TIME_SLACK

    t = run.t
    enc_t = t[np.isfinite(run["enc_wl"]) & np.isfinite(run["enc_wr"])]
    last = enc_t[enc_t < DROPOUT[0]].max()
    limit = 1.5 * np.median(np.diff(enc_t)) + TIME_SLACK
    back = enc_t[enc_t >= DROPOUT[1]].min()
    aged = (t - last > limit) & (t < back)
    return aged | (t < enc_t[0]), int(np.flatnonzero((t >= last) & (t - last <= limit))[-1]), float(back)


@pytest.mark.parametrize("rate", ["", "encoder_50hz"])
@pytest.mark.parametrize("name", LIU)
def test_liu_icr_is_held_through_an_encoder_dropout(name, rate, liu_est, liu_cases):
    """Eqs. (2), (3), (5) need the wheel speeds of the step: through a dropout the ICR stays at its
    value of the last step whose encoder pair is fresh (<= 1.5 sample intervals old), and before the
    dropout the estimate is that of the run without it (the rule changes nothing while encoders report).
    The held wheel speeds are no measurement: wl, wr and the slips (10) are NaN at the stale steps.
    At 100 Hz and at 50 Hz encoders (whose first sample after the dropout is not at its end)."""
    case, clean_case = _dropout_cases(rate)
    run = liu_cases[case][0]
    est, clean = liu_est(name, case), liu_est(name, clean_case)
    t = run.t
    stale, k0, back = _stale_rows(run)
    clean_stale = t < t[np.isfinite(run["enc_wl"])][0]  # before the first pair (row 0 at 50 Hz)
    assert stale[t >= DROPOUT[0]].sum() > 900  # ~10 s at 100 Hz rows
    for c in ("y_l", "y_r", "x_icr"):
        assert np.all(est[c][stale & (t >= DROPOUT[0])] == est[c][k0]), c
        assert np.array_equal(est[c][t < DROPOUT[0]], clean[c][t < DROPOUT[0]]), c
    assert est.info["icr_stale_encoder_steps"] == int(stale.sum())
    assert clean.info["icr_stale_encoder_steps"] == int(clean_stale.sum()) <= 1
    untouched = (t < DROPOUT[0]) | (t >= back)  # the held pair and the clean run's agree outside the dropout
    for c in ("wl", "wr", "slip_l", "slip_r"):
        assert np.isnan(est[c][stale]).all() and np.isnan(clean[c][clean_stale]).all(), c
        if c in ("wl", "wr"):  # the slips depend on the posterior, which the dropout changes after it
            assert np.array_equal(est[c][untouched], clean[c][untouched], equal_nan=True), c
            # between the samples of the slower encoder the held pair is fresh
            assert np.isfinite(est[c][~stale]).all() and np.isfinite(clean[c][~clean_stale]).all(), c
    assert np.array_equal(est["slip_l"][t < DROPOUT[0]], clean["slip_l"][t < DROPOUT[0]], equal_nan=True)


def test_liu_icr_fit_skips_gnss_samples_in_an_encoder_gap(liu_cases):
    """fit_icr does not interpolate the wheel speeds across a dropout: on the run with the dropout it
    gives exactly the fit of the intact run whose GNSS samples between the encoder pairs around the gap
    are removed (the same samples, the same wheel speeds), and not the fit of the intact run."""
    from methods.liu2020 import fit_icr

    run, clean = liu_cases["encoder_dropout"][0], liu_cases["none"][0]
    enc_t = run.t[np.isfinite(run["enc_wl"])]
    last, back = enc_t[enc_t < DROPOUT[0]].max(), enc_t[enc_t >= DROPOUT[1]].min()
    without = F.gnss_outage(clean, np.nextafter(last, np.inf), back)
    got, expect, intact = fit_icr([run]), fit_icr([without]), fit_icr([clean])
    assert got[:3] == expect[:3] and got[3]["fit_samples"] == expect[3]["fit_samples"]
    assert intact[3]["fit_samples"] - got[3]["fit_samples"] >= 90  # ~10 s of 10 Hz fixes while moving
    assert got[:3] != intact[:3]


@pytest.mark.parametrize("rate", ["", "encoder_50hz"])
@pytest.mark.parametrize("name", ("liu2020.en_dr", "liu2020.icr"))
def test_liu_dead_reckoning_flags_an_encoder_dropout(name, rate, liu_cases):
    """Dead reckoning integrates the last wheel speeds through a dropout (it has nothing better): the
    pose is finite and equals, at the end of the dropout, the integral of the held speeds; the stale
    steps report NaN wheel speeds and slips, and info counts them."""
    case, clean_case = _dropout_cases(rate)
    run, clean_run = liu_cases[case][0], liu_cases[clean_case][0]
    m = registry.get(name)
    if name == "liu2020.icr":
        m = dataclasses.replace(m, y_l=0.6, y_r=-0.55, x_icr=0.02)
    est, clean = registry.estimate(m, run), registry.estimate(m, clean_run)
    stale, _, _ = _stale_rows(run)
    # row k of dead reckoning holds the speeds of the interval ending at row k + 1
    stale_dr = np.concatenate((stale[1:], stale[-1:]))
    assert est.info["stale_encoder_steps"] == int(stale_dr.sum()) and clean.info["stale_encoder_steps"] == 0
    for c in ("wl", "wr", "slip_l", "slip_r"):
        assert np.isnan(est[c][stale_dr]).all(), c
    assert np.isfinite(est["wl"][~stale_dr]).all() and np.isfinite(clean["wl"]).all()
    for c in ("x", "y", "yaw", "vx", "wz"):
        assert np.isfinite(est[c]).all(), c
    # through the dropout the body velocity is the last fresh pair's
    k_last = int(np.flatnonzero(stale_dr)[0]) - 1
    assert np.all(est["vx"][stale_dr] == est["vx"][k_last]) and np.all(est["wz"][stale_dr] == est["wz"][k_last])


# ============================================================================================
# Yi 2009 on Yi's robot
# ============================================================================================
@pytest.fixture(scope="module")
def yi_run(sim) -> Run:
    return sim("stress_yi_random", SEED)


@pytest.fixture(scope="module")
def yi_cases(yi_run):
    return {
        "imu_spikes": (F.imu_saturation_spikes(yi_run, SPIKES, 1.0, seed=0), T0, max(SPIKES)),
        "encoder_dropout": (F.encoder_dropouts(yi_run, *DROPOUT), *DROPOUT),
    }


@pytest.fixture(scope="module")
def yi_est(yi_cases):
    cache: dict = {}

    def get(name: str, case: str):
        if (name, case) not in cache:
            cache[(name, case)] = registry.estimate(registry.get(name, store_covariance=True), yi_cases[case][0])
        return cache[(name, case)]
    return get


@pytest.mark.parametrize("case", ["imu_spikes", "encoder_dropout"])
@pytest.mark.parametrize("name", YI)
def test_yi_no_nan_and_covariance_pd(name, case, yi_est, yi_cases, yi_run):
    """No NaN, P (9x9) symmetric positive definite at every IMU step.  Recovery: not defined (no
    absolute position sensor; the position error of every scheme grows)."""
    est = yi_est(name, case)
    for c in ("x", "y", "yaw", "vx", "vy", "wz"):
        assert np.isfinite(est[c]).all(), c
    P = est.info["P"]
    assert P.shape == (est.t.size, 9, 9)
    h = F.covariance_health(P)
    assert h.positive_definite, h
    _, t0, t1 = yi_cases[case]
    t = est.t
    vx_err = np.abs(est["vx"] - np.interp(t, yi_run.t, yi_run["truth_vx"]))
    if case == "imu_spikes":  # the fault reached the filter (the test is not vacuous)
        assert vx_err[(t >= t0) & (t <= t1 + 0.5)].max() > 0.3 > vx_err[(t >= t0 - 20) & (t < t0)].max()


@pytest.mark.parametrize("name", YI)
def test_yi_encoder_dropout_fuses_exactly_the_remaining_pairs(name, yi_est, yi_cases, yi_run):
    """Encoders and IMU both at 125 Hz on the same rows: every encoder pair after the first IMU
    step is one v_x update (v_y too in scheme 3); the 1250 pairs of the 10 s dropout are not fused,
    v_z = 0 (11) still is at every step."""
    run = yi_cases["encoder_dropout"][0]
    pairs = lambda r: np.isfinite(r["enc_wl"]) & np.isfinite(r["enc_wr"])  # noqa: E731
    imu_rows = np.flatnonzero(np.isfinite(run["imu_gz"]))
    assert np.array_equal(np.flatnonzero(pairs(yi_run)), imu_rows)
    assert int(pairs(yi_run).sum() - pairs(run).sum()) == 1250
    est = yi_est(name, "encoder_dropout")
    n = est.info["n_updates"]
    assert n["vx"] == int(pairs(run)[imu_rows[1:]].sum())
    assert n["vy"] == (n["vx"] if name.endswith("v3") else 0)
    assert n["vz"] == imu_rows.size - 1


# ============================================================================================
# The report
# ============================================================================================
def test_stress_report_writes_markdown(tmp_path):
    s = S.StressSettings(duration=36.0, t0=18.0, outage=5.0, dropout=3.0, pre_window=8.0, horizon=12.0,
                         liu_filters=("liu2020.ukf_icr",), yi_filters=("yi2009.ekf_v1",), consistent=False)
    path = S.stress_report(tmp_path, settings=s, workers=1)
    assert path == tmp_path / "stress.md" and sorted(p.name for p in tmp_path.iterdir()) == ["stress.md"]
    text = path.read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| liu2020") or ln.startswith("| yi2009")]
    # Liu: none, gnss paper, gnss hold, spikes, dropout; Yi: none, spikes, dropout; Yi velocity NEES: 1
    assert len(rows) == 9
    assert "### Yi 2009: velocity NEES on the fault-free run" in text
    assert "## Verdict" in text and "recovery is not defined" in text
    # one number recomputed independently
    from bench.sim import simulate
    from bench.spec import load_scenario

    run = simulate(load_scenario("stress_dubhe_random", {"duration": 36.0}), 1)  # as stress_rows does
    est = registry.estimate(registry.get("liu2020.ukf_icr"), F.gnss_outage(run, 18.0, 23.0))
    t, err = F.position_error(run, est)
    rec = F.recovery(t, err, 18.0, 23.0, pre_window=8.0, horizon=12.0)
    row = next(r for r in rows if "| paper | gnss_outage |" in r and "ukf_icr" in r)
    assert f"| {rec.max_total:.3f} |" in row and f"| {rec.pre:.3f} |" in row


# ============================================================================================
# One hour (slow): all faults in one run, 15 min apart
# ============================================================================================
HOUR = 3600.0
HOUR_SPIKES = (900.0, 901.3, 902.7)
HOUR_DROPOUT = (1800.0, 1810.0)
HOUR_OUTAGE = (2700.0, 2730.0)
HOUR_WINDOWS = {"imu_spikes": (900.0, 902.7), "encoder_dropout": HOUR_DROPOUT, "gnss_outage": HOUR_OUTAGE}


@pytest.fixture(scope="module")
def hour_dubhe(sim):
    run = sim("stress_dubhe_random", SEED, duration=HOUR)
    faulted = F.imu_saturation_spikes(run, HOUR_SPIKES, 1.0, seed=0)
    faulted = F.gnss_outage(F.encoder_dropouts(faulted, *HOUR_DROPOUT), *HOUR_OUTAGE)
    return run, faulted


@pytest.fixture(scope="module")
def hour_liu_est(hour_dubhe):
    cache: dict = {}

    def get(name: str, hold: bool):
        if (name, hold) not in cache:
            m = registry.get(name)
            if hold:
                m = dataclasses.replace(m, params=dataclasses.replace(m.params, icr_hold_gnss_timeout=HOLD_TIMEOUT))
            cache[(name, hold)] = registry.estimate(m, hour_dubhe[1])
        return cache[(name, hold)]
    return get


@pytest.mark.slow
@pytest.mark.parametrize("hold", [False, True], ids=["paper", "icr_hold"])
@pytest.mark.parametrize("name", LIU)
def test_one_hour_liu_no_nan_covariance_pd_and_bounded(name, hold, hour_liu_est, hour_dubhe):
    """1 hour at 100 Hz (360000 steps) with spikes, an encoder dropout and a GNSS outage: no NaN, P
    symmetric positive definite at every step, and after the first step the posterior position std
    stays below the GNSS std at every fix (bounded covariance)."""
    run = hour_dubhe[1]
    est = hour_liu_est(name, hold)
    for c in ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr"):
        assert np.isfinite(est[c]).all(), c
    P = est.info["P"]
    h = F.covariance_health(P)
    assert h.positive_definite and h.steps == run.t.size, h
    fix = np.isfinite(run["gnss_x"]) & np.isfinite(run["gnss_y"])
    fix[0] = False  # step 0 is the prior P0 (p0_pos = r_gnss), not an update
    std = np.sqrt(np.maximum(P[fix, 0, 0], P[fix, 1, 1]))
    assert std.max() < registry.get(name).params.r_gnss[0]


# Measured on the 1-hour run (seed 1), testbed v2:
XFAIL_HOUR = {
    ("liu2020.ukf_icr", False, "gnss_outage"): "UKF+ICR as in the paper, 1 h run: 30 s outage at 2700 s, max error "
                                               "95.3 m (pre-fault 0.041 m), not back within 2x in 30 s; ICR hold: 5.4 s",
    ("liu2020.mi_ukf", False, "gnss_outage"): "MI-UKF as in the paper, 1 h run: max error 155 m (pre-fault 0.031 m), "
                                              "back within 2x after 27.4 s; ICR hold: 4.4 s",
    ("liu2020.ukf_icr", False, "imu_spikes"): "UKF+ICR, 1 h run: spikes at 900 s, max error 0.33 m (pre-fault 0.038 m), "
                                              "back within 2x after 12.2 s > 10 s (gyro spikes -> heading error)",
    ("liu2020.mi_ukf", False, "imu_spikes"): "MI-UKF, 1 h run: spikes at 900 s, max error 0.41 m (pre-fault 0.027 m), "
                                             "back within 2x after 11.5 s > 10 s (gyro spikes -> heading error)",
}


def _hour_params():
    out = []
    for name in LIU:
        for hold, faults in ((False, ("imu_spikes", "encoder_dropout", "gnss_outage")), (True, ("gnss_outage",))):
            for fault in faults:
                reason = XFAIL_HOUR.get((name, hold, fault))
                marks = [pytest.mark.slow] + ([pytest.mark.xfail(strict=True, reason=reason)] if reason else [])
                out.append(pytest.param(name, hold, fault, marks=marks,
                                        id=f"{name.split('.')[1]}-{'icr_hold' if hold else 'paper'}-{fault}"))
    return out


@pytest.mark.parametrize(("name", "hold", "fault"), _hour_params())
def test_one_hour_liu_recovers(name, hold, fault, hour_liu_est, hour_dubhe):
    """Each fault of the 1-hour run: position error back within 2x its pre-fault level within 10 s."""
    run = hour_dubhe[0]
    est = hour_liu_est(name, hold)
    t, err = F.position_error(run, est)
    rec = F.recovery(t, err, *HOUR_WINDOWS[fault])
    print(f"1 h {name} hold={hold} {fault}: pre {rec.pre:.3f} m, max {rec.max_total:.3f} m, recovery {rec.recovery_time:.2f} s")
    assert rec.recovery_time <= RECOVER_WITHIN, rec


@pytest.mark.slow
@pytest.mark.parametrize("name", YI)
def test_one_hour_yi_no_nan_covariance_pd(name, sim):
    """Yi 2009 on its robot, 1 hour at 125 Hz (450000 steps) with spikes and an encoder dropout: no
    NaN, P symmetric positive definite at every step.  The position error grows without an absolute
    sensor (recovery not defined); the velocity block of P, observed through (11)-(15), stays bounded:
    its largest standard deviation over the last 10 min is below that over the first 10 min times
    sqrt(6) (a random walk would grow with sqrt(time): 60 min / 10 min).  Measured (seed 1): velocity
    std 0.194 -> 0.189 (v1), 0.188 -> 0.241 (v2), 0.013 -> 0.013 m/s (v3); position std, which nothing
    observes, 1.43 -> 3.20 (v1), 1.43 -> 3.17 (v2), 0.19 -> 0.53 m (v3)."""
    run = sim("stress_yi_random", SEED, duration=HOUR)
    faulted = F.encoder_dropouts(F.imu_saturation_spikes(run, HOUR_SPIKES, 1.0, seed=0), *HOUR_DROPOUT)
    est = registry.estimate(registry.get(name, store_covariance=True), faulted)
    for c in ("x", "y", "yaw", "vx", "vy", "wz"):
        assert np.isfinite(est[c]).all(), c
    P = est.info["P"]
    h = F.covariance_health(P)
    assert h.positive_definite and h.steps == est.t.size, h
    t = est.t
    vel_std = np.sqrt(np.max(np.diagonal(P[:, 3:6, 3:6], axis1=1, axis2=2), axis=1))
    first, last = vel_std[(t > 60) & (t < 600)].max(), vel_std[t > HOUR - 600].max()
    pos_std = np.sqrt(np.maximum(P[:, 0, 0], P[:, 1, 1]))
    p_first, p_last = pos_std[(t > 60) & (t < 600)].max(), pos_std[t > HOUR - 600].max()
    print(f"1 h {name}: velocity std first 10 min {first:.4f}, last 10 min {last:.4f} m/s; position std "
          f"{p_first:.3f} -> {p_last:.3f} m; min eig P {h.min_eig:.3e}")
    assert last < math.sqrt(6.0) * first
