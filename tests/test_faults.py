"""Fault functions and recovery measures of bench/robustness/faults.py on synthetic Runs with
closed-form expectations (the filters under these faults: tests/test_stress.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bench.robustness import faults as F
from bench.run import Run, RunError, from_arrays

# ============================================================================================
# Fault functions on a synthetic run
# ============================================================================================
def _synthetic(duration: float = 20.0, seed: int = 0) -> Run:
    """100 Hz log: IMU every row, encoders at 50 Hz, GNSS at 10 Hz (NaN between), truth columns."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * 100) + 1) / 100.0
    n = t.size
    cols = {"t": t}
    for c in F.IMU_CHANNELS:  # within the saturation below (20 m/s^2, 3 rad/s), as a real IMU's
        cols[c] = rng.normal(0.0, 0.5, n) + (9.81 if c == "imu_az" else 0.0)
    enc_rows = np.arange(n) % 2 == 0
    for c in F.ENCODER_CHANNELS:
        cols[c] = np.where(enc_rows, rng.normal(5.0, 0.1, n), np.nan)
    gnss_rows = np.arange(n) % 10 == 0
    for c in F.GNSS_CHANNELS:
        cols[c] = np.where(gnss_rows, rng.normal(0.0, 1.0, n), np.nan)
    cols["truth_x"], cols["truth_y"] = 0.5 * t, np.zeros(n)
    meta = {"run_id": "synthetic", "platform": {"sensors": {"imu": {"saturation_accel": 20.0, "saturation_gyro": 3.0}}}}
    return from_arrays(cols, meta)


def _unchanged_except(a: Run, b: Run, changed: tuple[str, ...]) -> None:
    assert list(a.data.columns) == list(b.data.columns)
    for c in a.data.columns:
        if c not in changed:
            assert np.array_equal(a[c], b[c], equal_nan=True), c


def test_gnss_outage_blanks_exactly_the_window():
    run = _synthetic()
    before = run.data.copy()
    out = F.gnss_outage(run, 5.0, 8.0)
    t = run.t
    win = (t >= 5.0) & (t < 8.0)
    for c in F.GNSS_CHANNELS:
        assert not np.isfinite(out[c][win]).any(), c
        assert np.array_equal(out[c][~win], run[c][~win], equal_nan=True), c
    _unchanged_except(run, out, F.GNSS_CHANNELS)  # truth, IMU, encoders untouched
    assert run.data.equals(before)  # the input run is not modified
    rec = out.meta["faults"][-1]
    assert rec["kind"] == "gnss_outage" and rec["samples_removed"] == 5 * 30  # 10 Hz x 3 s x 5 channels
    assert out.content_hash() != run.content_hash() and out.id.startswith("synthetic+gnss_outage")


def test_encoder_dropout_one_side_and_stacking():
    run = _synthetic()
    out = F.encoder_dropouts(run, 2.0, 3.0, channels=("enc_wl",))
    win = (run.t >= 2.0) & (run.t < 3.0)
    assert not np.isfinite(out["enc_wl"][win]).any()
    assert np.array_equal(out["enc_wr"], run["enc_wr"], equal_nan=True)
    _unchanged_except(run, out, ("enc_wl",))
    both = F.gnss_outage(out, 10.0, 12.0)
    assert [f["kind"] for f in both.meta["faults"]] == ["encoder_dropout", "gnss_outage"]
    assert out.meta["faults"][0]["samples_removed"] == 50  # 50 Hz x 1 s


def test_imu_spikes_clipped_at_saturation_and_located():
    run = _synthetic()
    times = [3.0, 7.004, 12.5]
    out = F.imu_saturation_spikes(run, times, magnitude=1.0, seed=3, width=0.02)
    sat = {"a": 20.0, "g": 3.0}
    t = run.t
    expected_rows = np.zeros(t.size, bool)
    for tau in times:
        rows = (t >= tau) & (t <= tau + 0.02)
        expected_rows |= rows
    assert expected_rows.sum() == 2 + 3 + 3  # 7.004 s: rows 7.01, 7.02 (+7.00 excluded); 3.00-3.02; 12.50-12.52
    for c in F.IMU_CHANNELS:
        s = sat[c[4]]
        d = out[c] - run[c]
        assert np.all(np.abs(out[c]) <= s + 1e-12), c
        assert np.array_equal(np.flatnonzero(d != 0), np.flatnonzero(expected_rows)), c
        # each spike adds +-s, then clips: |change| <= s and the sample moves toward the rail
        assert np.all(np.abs(d[expected_rows]) <= s + 1e-12)
        k = expected_rows
        assert np.allclose(out[c][k], np.clip(run[c][k] + np.sign(d[k]) * s, -s, s)), c
    _unchanged_except(run, out, F.IMU_CHANNELS)
    # magnitude 2 full scales: every spiked sample lands exactly on a rail
    rail = F.imu_saturation_spikes(run, times, magnitude=2.0, seed=3, width=0.02)
    for c in F.IMU_CHANNELS:
        assert np.all(np.abs(rail[c][expected_rows]) == sat[c[4]]), c


def test_imu_spikes_deterministic_and_seeded():
    run = _synthetic()
    a = F.imu_saturation_spikes(run, [4.0, 9.0], 1.0, seed=11)
    b = F.imu_saturation_spikes(run, [4.0, 9.0], 1.0, seed=11)
    c = F.imu_saturation_spikes(run, [4.0, 9.0], 1.0, seed=12)
    assert a.content_hash() == b.content_hash()
    signs = lambda r: np.concatenate([np.sign(r[ch] - run[ch])[[400, 900]] for ch in F.IMU_CHANNELS])  # noqa: E731
    assert not np.array_equal(signs(a), signs(c))


def test_fault_bad_input_names_the_problem():
    run = _synthetic()
    with pytest.raises(ValueError, match="t1 > t0"):
        F.gnss_outage(run, 5.0, 5.0)
    with pytest.raises(RunError, match="enc_wx"):
        F.encoder_dropouts(run, 1.0, 2.0, channels=("enc_wx",))
    with pytest.raises(ValueError, match="after the last"):
        F.imu_saturation_spikes(run, [25.0], 1.0)
    with pytest.raises(ValueError, match="magnitude"):
        F.imu_saturation_spikes(run, [2.0], 0.0)
    no_sat = Run(run.data, {"run_id": "nosat", "platform": {}})
    with pytest.raises(RunError, match="saturation_accel"):
        F.imu_saturation_spikes(no_sat, [2.0], 1.0)


# ============================================================================================
# Measures: closed forms
# ============================================================================================
def test_recovery_closed_form_step():
    """Error 1 before the fault, 10 from t0 until t1 + 5 s, then 1: the 1 s trailing mean is
    10 - 9 d at d s after the drop, <= 2 x 1 from d = 8/9 s: recovery = 5 + 8/9 s."""
    dt = 0.001
    t = np.arange(0.0, 100.0 + dt / 2, dt)
    t0, t1 = 40.0, 50.0
    err = np.where((t >= t0) & (t < t1 + 5.0), 10.0, 1.0)
    rec = F.recovery(t, err, t0, t1)
    assert rec.pre == pytest.approx(1.0)
    assert rec.recovery_time == pytest.approx(5.0 + 8.0 / 9.0, abs=2 * dt)
    assert rec.max_total == 10.0 and rec.max_after == 10.0 and rec.max_fault == 10.0
    assert not rec.recovered_within(5.0) and rec.recovered_within(6.0)
    # an error that never comes back
    rec2 = F.recovery(t, np.where(t >= t0, 10.0, 1.0), t0, t1)
    assert math.isinf(rec2.recovery_time) and not rec2.recovered_within(1e9)
    # a NaN is never "recovered": NaN on (t1 + 20, t1 + 21) keeps every 1 s window that holds it
    # above the bound, the last one ending just before t1 + 22
    bad = err.copy()
    bad[(t > t1 + 20) & (t < t1 + 21)] = np.nan
    rec3 = F.recovery(t, bad, t0, t1, horizon=25.0)
    assert rec3.recovery_time == pytest.approx(22.0, abs=2 * dt) and math.isinf(rec3.max_after)


def test_paired_recovery_follows_the_fault_free_error():
    """Paired criterion: a reference error (the fault-free run's) that rises from 1 to 4 at t1 + 3 s raises the
    bound to 2 x 4 from there.  A faulted error of 6 from t0 on recovers exactly when the reference's 1 s trailing
    mean reaches 3 (6 <= 2 x 3): t1 + 3 + 2/3 s; unpaired it never recovers (6 > 2 x 1).  The fault-free run
    paired with itself recovers at once."""
    dt = 0.001
    t = np.arange(0.0, 100.0 + dt / 2, dt)
    t0, t1 = 40.0, 50.0
    ref = np.where(t >= t1 + 3.0, 4.0, 1.0)
    err = np.where(t >= t0, 6.0, 1.0)
    assert math.isinf(F.recovery(t, err, t0, t1).recovery_time)
    assert F.recovery(t, err, t0, t1, reference=ref).recovery_time == pytest.approx(3.0 + 2.0 / 3.0, abs=2 * dt)
    assert F.recovery(t, ref, t0, t1, reference=ref).recovery_time == 0.0


def test_recovery_pre_level_is_percentile_of_smoothed_error():
    t = np.arange(0.0, 80.0, 0.01)
    err = 1.0 + 0.5 * np.sin(2 * np.pi * t / 4.0)  # period 4 s
    rec = F.recovery(t, err, 30.0, 35.0)
    # the 1 s trailing mean of a sine of period 4 s is a sine of amplitude 0.5 sin(pi/4)/(pi/4); a
    # sinusoid A sin(phi) exceeds v for the fraction (pi - 2 asin(v/A)) / (2 pi) of the time, so its
    # 95th percentile is A sin(0.45 pi)
    amp = 0.5 * math.sin(math.pi / 4) / (math.pi / 4)
    assert rec.pre == pytest.approx(1.0 + amp * math.sin(0.45 * math.pi), abs=2e-3)
    mean_level = F.recovery(t, err, 30.0, 35.0, pre_percentile=None).pre
    assert mean_level == pytest.approx(1.0, abs=5e-3)


def test_covariance_health():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(50, 4, 4))
    P = A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(4)
    h = F.covariance_health(P, chunk=7)
    assert h.positive_definite and h.finite and h.max_asymmetry == 0.0
    assert h.min_eig == pytest.approx(np.linalg.eigvalsh(P)[:, 0].min())
    Q = P.copy()
    Q[33] = np.diag([1.0, 1.0, -1e-9, 1.0])
    h = F.covariance_health(Q, chunk=7)
    assert not h.positive_definite and h.min_eig_step == 33 and h.min_eig == pytest.approx(-1e-9)
    Q = P.copy()
    Q[12, 0, 1] += 1e-3
    assert not F.covariance_health(Q).positive_definite
    Q = P.copy()
    Q[40, 2, 2] = np.nan
    h = F.covariance_health(Q)
    assert not h.positive_definite and not h.finite and h.min_eig_step == 40
