"""The consistent configuration (not Yi's): the traction slip and the S correction of the rows,
methods.yi2009.consistent.rows.
"""
from __future__ import annotations

import numpy as np
import pytest

from methods.yi2009.consistent.rows import fit_icr_correction, fit_traction_slip, icr_features, traction_features
from tests.methods.yi2009.synthetic import G, R_WHEEL, _ar1


def test_fit_traction_slip_recovers_the_generating_coefficients():
    """Residuals built as c_f f_x + c_w |w_z| + AR(1) (sigma 0.002, tau 3 s) + white (0.01, the quantisation level),
    with the features seen through IMU-level noise (0.05 m/s^2, 0.005 rad/s) as the filter sees them: the 2 s
    moving-mean least squares recovers (c_f, c_w) within 5 % (the noise on the features averages to ~0.003 m/s^2
    over a window against a feature spread of ~0.2 m/s^2, so the errors-in-variables attenuation is < 0.1 %), and
    the explained share is reported (rms_after well below rms_before)."""
    rng = np.random.default_rng(11)
    dt, n, c_f, c_w = 0.008, 7500, 0.03, -0.004
    res, feats = [], []
    for _ in range(6):
        tt = np.arange(n) * dt
        f_x = 0.3 * np.sin(2 * np.pi * tt / rng.uniform(4, 9)) * np.sin(2 * np.pi * tt / rng.uniform(15, 25))
        w_z = 0.5 * np.sin(2 * np.pi * tt / rng.uniform(10, 20) + rng.uniform(0, 6))
        e = c_f * f_x + c_w * np.abs(w_z) + _ar1(rng, n, dt, 3.0, 0.002) + 0.01 * rng.standard_normal(n)
        e[:100] = np.nan
        res.append(e)
        acc = np.column_stack((f_x + 0.05 * rng.standard_normal(n), np.zeros(n), np.full(n, G)))
        gyr = np.column_stack((np.zeros((n, 2)), w_z + 0.005 * rng.standard_normal(n)))
        feats.append(traction_features(acc, gyr))
    model, info = fit_traction_slip(res, feats, dt)
    assert model.c_f == pytest.approx(c_f, rel=0.05) and model.c_w == pytest.approx(c_w, rel=0.05)
    assert info["rms_after"] < 0.5 * info["rms_before"] and info["window"] == pytest.approx(2.0, abs=dt)
    moving = np.arange(n) % 2 == 0
    off = model.offset(acc, gyr, moving)
    assert np.array_equal(off[~moving], np.zeros(np.count_nonzero(~moving)))
    assert np.allclose(off[moving], (model.c_f * acc[:, 0] + model.c_w * np.abs(gyr[:, 2]))[moving], rtol=0, atol=0)
    with pytest.raises(ValueError, match="no full"):
        fit_traction_slip([np.full(100, np.nan)], [np.zeros((100, 2))], dt)


def test_fit_icr_correction_recovers_the_generating_coefficients():
    """v_y row residuals built as (c_0 + c_1 v |w_z|) w_z + AR(1) (sigma 0.002, tau 3 s) + white (0.005), with the
    yaw rate seen through gyro-level noise (0.005 rad/s) and the speed through 2000-count encoders' quantisation as
    the filter sees them: the 2 s moving-mean least squares recovers (c_0, c_1) within 5 %; the offset is
    (c_0 + c_1 v |w_z|) w_z on the moving steps and 0 elsewhere."""
    rng = np.random.default_rng(12)
    dt, n, c_0, c_1 = 0.008, 7500, -0.12, 0.08
    res, feats = [], []
    for _ in range(6):
        tt = np.arange(n) * dt
        v = 0.3 + 0.25 * np.sin(2 * np.pi * tt / rng.uniform(20, 40))
        w_z = 0.6 * np.sin(2 * np.pi * tt / rng.uniform(10, 20) + rng.uniform(0, 6))
        e = (c_0 + c_1 * v * np.abs(w_z)) * w_z + _ar1(rng, n, dt, 3.0, 0.002) + 0.005 * rng.standard_normal(n)
        e[:100] = np.nan
        res.append(e)
        q = 2 * np.pi / 2000 * 125.0  # one count per sample [rad/s]
        enc = np.round(np.column_stack((v, v)) / R_WHEEL / q + rng.uniform(-0.5, 0.5, (n, 2))) * q
        gyr = np.column_stack((np.zeros((n, 2)), w_z + 0.005 * rng.standard_normal(n)))
        feats.append(icr_features(gyr, enc, R_WHEEL))
    model, info = fit_icr_correction(res, feats, dt)
    assert model.c_0 == pytest.approx(c_0, rel=0.05) and model.c_1 == pytest.approx(c_1, rel=0.05)
    assert info["rms_after"] < 0.5 * info["rms_before"]
    moving = np.arange(n) % 2 == 0
    off = model.offset(gyr, enc, R_WHEEL, moving)
    assert np.array_equal(off[~moving], np.zeros(np.count_nonzero(~moving)))
    v_enc = 0.5 * R_WHEEL * (enc[:, 0] + enc[:, 1])
    expect = (model.c_0 + model.c_1 * v_enc * np.abs(gyr[:, 2])) * gyr[:, 2]
    assert np.allclose(off[moving], expect[moving], rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="fit_icr_correction: no full"):
        fit_icr_correction([np.full(100, np.nan)], [np.zeros((100, 2))], dt)
