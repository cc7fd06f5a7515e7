"""Baril 2024 on DRIVE windows: on synthetic windows whose truth is ideal differential drive plus a known linear slip
(tests/methods/baril2024/synthetic.py), the BLR rows recover the slip and the powertrain, and their held-out end-pose
errors are near zero and far below ideal differential drive's."""
from __future__ import annotations

import numpy as np
import pytest

from bench import registry
from bench.real.windows import end_errors
from methods.baril2024.powertrain import fit_powertrain, simulate
from methods.baril2024.windows import BlrSlipCmdWindows, BlrSlipWindows, NotFittedError
from tests.methods.baril2024.synthetic import B, R, TRUE_SLIP, lag, windows


def _split(w):
    calib = w.subset(np.arange(w.n_windows) % 2 == 0)
    return calib, w.subset(np.arange(w.n_windows) % 2 == 1)


def _ideal_dd():
    (m,) = registry.get("baseline.ideal_dd").window_models(R, B)
    return m


def test_measured_wheel_speed_row_recovers_the_slip_and_beats_ideal_dd():
    rng = np.random.default_rng(0)
    calib, test = _split(windows(rng, 60))
    (enc, cmd) = registry.get("baril2024.blr_slip").window_models(R, B)
    assert isinstance(enc, BlrSlipWindows) and isinstance(cmd, BlrSlipCmdWindows)
    assert (enc.name, cmd.name) == ("baril2024_blr_slip", "baril2024_blr_slip_cmd")
    with pytest.raises(NotFittedError):
        enc.predict(test)
    fit = enc.fit(calib)
    p = fit.params()
    assert p["s_x[v]"] == pytest.approx(TRUE_SLIP["x"][0], abs=1e-8)
    assert p["s_y[vw]"] == pytest.approx(TRUE_SLIP["y"][0], abs=1e-8)
    assert (p["s_yaw[vw]"], p["s_yaw[v]"], p["s_yaw[w]"]) == pytest.approx(TRUE_SLIP["yaw"], abs=1e-8)
    assert p["n"] == fit.n_fit == 20 * 39  # the steady calibration windows' intervals (every third window is transitory)
    e_blr, y_blr = end_errors(fit.predict(test), test)
    e_idd, _ = end_errors(_ideal_dd().predict(test), test)
    assert np.median(e_idd) > 0.1  # the slip matters
    assert np.max(e_blr) < 1e-8 and np.max(y_blr) < 1e-8
    assert np.median(e_blr) < 1e-3 * np.median(e_idd)


def test_noisy_reference_still_gives_a_near_zero_held_out_error():
    """5 mm / 5 mrad ICP noise on every sample: differenced, it is a large velocity noise (~0.14 m/s), but the
    regression averages it out."""
    rng = np.random.default_rng(1)
    calib, test = _split(windows(rng, 120, noise=0.005))
    fit = BlrSlipWindows(R, B).fit(calib)
    truth = windows(np.random.default_rng(1), 120)  # the same draws without noise: the true end poses
    _, test_true = _split(truth)
    e_blr, _ = end_errors(fit.predict(test_true), test_true)
    e_idd, _ = end_errors(_ideal_dd().predict(test_true), test_true)
    assert np.median(e_blr) < 0.01 < 0.1 < np.median(e_idd)
    assert fit.params()["sigma_x"] == pytest.approx(np.sqrt(2) * 0.005 / 0.05, rel=0.15)


def test_powertrain_fit_recovers_time_constant_and_dead_time():
    rng = np.random.default_rng(2)
    cmd = np.repeat(rng.uniform(-5, 5, (30, 1)), 40, 1)
    w0 = rng.uniform(-5, 5, 30)
    cmd[:, :2] = w0[:, None]
    enc = np.array([lag(c, a, 0.35, 3) for c, a in zip(cmd, w0)])
    p = fit_powertrain(cmd, enc, 0.05)
    assert p.delay == 3 and p.tau == pytest.approx(0.35, rel=1e-3) and p.fit_cost < 1e-4
    np.testing.assert_allclose(simulate(cmd, w0, 0.05, 0.35, 3), enc, atol=1e-12)
    # the bounds clip
    clipped = simulate(cmd, w0, 0.05, 0.35, 3, -1.0, 2.0)
    assert clipped.min() >= -1.0 and clipped.max() <= 2.0


def test_command_row_recovers_the_powertrain_and_predicts_from_commands():
    rng = np.random.default_rng(3)
    calib, test = _split(windows(rng, 90, powertrain=(0.3, 2)))
    fit = BlrSlipCmdWindows(R, B).fit(calib)
    p = fit.params()
    assert p["delay_l[samples]"] == p["delay_r[samples]"] == 2
    assert (p["tau_l"], p["tau_r"]) == pytest.approx((0.3, 0.3), rel=1e-3)
    np.testing.assert_allclose(fit.wheel_speeds(test)[0], test["enc_wl"], atol=0.05)  # clip at the calib range only
    e_cmd, _ = end_errors(fit.predict(test), test)
    e_idd, _ = end_errors(_ideal_dd().predict(test), test)
    assert np.median(e_cmd) < 1e-3 < 0.1 < np.median(e_idd)
