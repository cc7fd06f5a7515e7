"""methods/liu2020/dead_reckoning.py: En-DR and ICR dead reckoning against closed-form kinematics on
synthetic runs (tests/methods/liu2020/synthetic.py), and the constant-ICR fit recovering the true ICR.
"""
from __future__ import annotations

import numpy as np

from methods.liu2020 import EnDr, IcrDr, fit_icr
from tests.methods.liu2020.synthetic import B, make_run, pos_rms, start_aligned_rms, yaw_err


def test_en_dr_exact_on_no_slip_data():
    """With ICRs at +-B/2 and x = 0 (pure rolling) the no-slip DR reproduces the truth (closed form)."""
    run = make_run(3, duration=40.0, icr=(B / 2, -B / 2, 0.0), icr_var=0.0)
    est = EnDr().estimate(run)
    assert start_aligned_rms(est, run) < 0.01  # only encoder quantisation and the ZOH step
    assert pos_rms(est, run) > start_aligned_rms(est, run)  # the GNSS start point's own error
    assert np.max(np.abs(yaw_err(est, run))) < 0.02
    np.testing.assert_allclose(est["slip_l"][np.isfinite(est["slip_l"])], 0.0, atol=1e-12)


def test_icr_dr_with_true_constant_icr_is_exact_and_calibration_recovers_it():
    run = make_run(4, duration=40.0, icr=(0.6, -0.6, 0.05), icr_var=0.0)
    est = IcrDr(0.6, -0.6, 0.05).estimate(run)
    assert start_aligned_rms(est, run) < 0.01
    assert start_aligned_rms(EnDr().estimate(run), run) > 1.0  # the no-slip model is wrong here
    cal = make_run(5, duration=60.0, icr=(0.6, -0.6, 0.05), icr_var=0.0)
    y_l, y_r, x_icr, info = fit_icr([cal])
    assert abs(y_l - 0.6) < 0.03 and abs(y_r + 0.6) < 0.03 and abs(x_icr - 0.05) < 0.03, (y_l, y_r, x_icr)
    assert info["fit_samples"] > 100
