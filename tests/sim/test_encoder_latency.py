"""Encoder (wheel-speed) latency of the testbed (``EncoderSpec.latency``) and of the gap model's noise-free encoder
prediction (``bench.gap.model.sample_trace``): a step in wheel speed appears in the encoder samples exactly
``latency`` later, on the sample grid.  Expectations are closed forms of a piecewise-linear wheel angle (the mean
speed over each counting interval moved back by the latency), and, for the default 0, the bytes the testbed made
before the field existed."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bench.gap.model import Grid, InitialState, sample_trace
from bench.sim import sensors as S
from bench.spec import CommandSpec, Segment, SpecError, load_scenario, replace

W0, W1, T_STEP = 2.0, 5.0, 0.5  # wheel speed [rad/s] before / after a step at T_STEP [s]


def _angle(t: np.ndarray) -> np.ndarray:
    """Closed form: wheel angle of a wheel turning at W0, then at W1 from T_STEP (angle 0 at t = 0; t < 0 too)."""
    t = np.asarray(t, float)
    return np.where(t < T_STEP, W0 * t, W0 * T_STEP + W1 * (t - T_STEP))


def _expected_speed(t: np.ndarray, period: float, latency: float) -> np.ndarray:
    """Mean wheel speed over the counting interval [t - period - latency, t - latency] (first sample 0)."""
    out = (_angle(t - latency) - _angle(t - period - latency)) / period
    out[0] = 0.0
    return out


@pytest.mark.parametrize("latency", [0.0, 0.07, 0.0333])
def test_encoder_samples_show_a_speed_step_latency_later(latency):
    """100 Hz encoder with 2^24 counts/rev (quantum q/T = 3.7e-5 rad/s): each sample is the closed-form mean speed
    over its counting interval moved back by ``latency``, within one count per period; for a latency of whole
    periods (0.07 s = 7) the first sample at the new speed is exactly 7 samples after the zero-latency one.  The
    wheel moves before the physics trace begins (a moving start): the samples before ``latency`` read W0, not 0."""
    rate, counts = 100.0, 2 ** 24
    scn = load_scenario("gap_test_coulomb")
    scn = replace(scn, **{"platform.sensors.encoder.counts_per_rev": counts, "platform.sensors.encoder.rate_hz": rate,
                          "platform.sensors.encoder.latency": latency})
    t_phys = np.arange(0, 1201) / 1200.0  # a physics trace at 1.2 kHz over 1 s (T_STEP on its grid)
    te = S.sample_times(rate, 1.0) / 1e6
    th = S.encoder_angles(te, t_phys, _angle(t_phys), W0, latency)
    enc_l, _ = S.encoders(te, th, th, scn, np.random.default_rng(1))
    q_t = 2 * math.pi / counts * rate
    np.testing.assert_allclose(enc_l, _expected_speed(te, 1.0 / rate, latency), rtol=0, atol=q_t + 1e-9)
    first_new = int(np.argmax(enc_l > W1 - 1e-3))
    assert te[first_new] == pytest.approx(T_STEP + 1.0 / rate + math.ceil(latency * rate - 1e-9) / rate, abs=1e-9)
    if latency == 0.07:
        assert first_new == int(round((T_STEP + 1.0 / rate) * rate)) + 7


def test_gap_model_encoder_prediction_is_late_by_the_latency():
    """The gap model's noise-free encoder at 20 Hz (the DRIVE Husky's rate) from the same closed-form wheel angle:
    the closed-form mean over [t - T - L, t - L] exactly (no quantisation), for L = 0, 0.15 and 0.2 s; the wheel's
    initial speed comes from the trace's ``w_init``."""
    t_phys = np.arange(0, 1201) / 1200.0
    trace = {"t": t_phys, "th_l": _angle(t_phys), "th_r": _angle(t_phys), "w_init": np.array([W0, W0])}
    te = np.arange(0, 21) / 20.0
    grid = Grid({"enc_wl": te, "enc_wr": te}, 0.05, InitialState(0.0, 0.0, 0.0, 0.0))
    for latency in (0.0, 0.15, 0.2):
        out = sample_trace(trace, grid, enc_latency=latency, x_offset=(0.0, 0.0))
        np.testing.assert_allclose(out["enc_wl"], _expected_speed(te, 0.05, latency), rtol=0, atol=1e-9)
        # the step shows in full first at the sample T_STEP + T + L
        assert te[int(np.argmax(out["enc_wl"] > W1 - 1e-9))] == pytest.approx(T_STEP + 0.05 + latency, abs=1e-9)


def test_encoder_latency_delays_the_simulated_samples_by_whole_periods():
    """End to end (testbed): a step from rest to (3, 4) rad/s; with a latency of 10 periods (0.1 s at 100 Hz) every
    encoder sample equals the zero-latency run's sample 10 periods earlier (the same seed draws the same count
    phases), and the first 11 samples read 0 (sample 0 has no previous count, 1-10 count the wheel at rest before
    the start); body motion and IMU unchanged."""
    cmd = CommandSpec(kind="wheel_speeds", units="rad/s", segments=(Segment(3.0, 3.0, 4.0),), accel=0.0)
    base = dataclasses.replace(load_scenario("gap_test_coulomb"), command=cmd, duration=1.5)
    from bench.sim import simulate

    r0 = simulate(base, 4)
    r1 = simulate(replace(base, **{"platform.sensors.encoder.latency": 0.1}), 4)
    assert base.platform.sensors.encoder.rate_hz == 100.0
    for c in ("enc_wl", "enc_wr"):
        _, a = r0.samples(c)
        t1, b = r1.samples(c)
        assert np.abs(a).max() > 2.5
        # the same counts; the speeds' last digits differ only through the float periods t_k - t_(k-1)
        np.testing.assert_allclose(b[11:], a[1:-10], rtol=1e-12, atol=0)
        assert np.all(b[:11] == 0.0)
    for c in ("imu_gz", "imu_ax", "ref_x", "truth_wl"):
        np.testing.assert_array_equal(r0[c], r1[c])


def test_encoder_latency_range_is_checked():
    with pytest.raises(SpecError, match="latency"):
        load_scenario("gap_test_coulomb", {"platform.sensors.encoder.latency": -0.01})
