"""Wang 2015 plugins: chi(lambda) identified end to end and dead reckoning of eq. (48) (synthetic runs)."""
from __future__ import annotations

import numpy as np
import pytest

from bench import registry
from methods import wang2015 as W
from tests.methods.wang2015.synthetic import circle_run, symmetric_run


def test_chi_lambda_identifies_and_dead_reckons_end_to_end():
    """Section 3 on 40 synthetic steady circles whose chi follows eq. (44) with (a, b) = (0.5, 0.08),
    then dead reckoning of the eq. (48) validation inputs driven by the same chi(lambda) law."""
    a, b = 0.5, 0.08
    law = lambda cr: 1 + a / (1 + b * np.sqrt(np.abs(cr)))  # noqa: E731
    runs = [circle_run(p.curvature_ratio, p.speed, law(p.curvature_ratio), duration=15.0, run_id=f"c{i}")
            for i, p in enumerate(W.identification_plan())]
    runs.append(circle_run(1e12, 0.3, 1.4, duration=4.0, run_id="straight"))  # skipped: no rotation
    m = registry.calibrate(W.ChiLambda(), runs)
    assert (m.curve.a, m.curve.b) == pytest.approx((a, b), abs=1e-9)
    assert [s[0] for s in m.identification.skipped] == ["straight"]
    table = m.identification.table()
    assert sorted(table) == list(range(8)) and all(n == 5 for _, _, n in table.values())
    assert table[3][0] == pytest.approx(law(3.0))
    # validation path of eq. (48)
    t = np.arange(701) / 100.0
    v_l, v_r = np.zeros_like(t), np.zeros_like(t)
    t_start = 0.0
    for t_end, vl, vr in W.VALIDATION_PROFILE:
        seg = (t > t_start) & (t <= t_end)  # eq. (48): v(t) on (t_start, t_end]
        v_l[seg], v_r[seg] = vl, vr
        t_start = t_end
    # the encoder at t_k reports the speed held over [t_k, t_k+1)
    v_l, v_r = np.r_[v_l[1:], 0.0], np.r_[v_r[1:], 0.0]
    cr = np.where(v_r == v_l, np.inf, (v_l + v_r) / np.where(v_r == v_l, 1.0, v_r - v_l))
    truth = symmetric_run(v_l, v_r, law(np.minimum(np.abs(cr), 10.0)), t, run_id="validation")
    est = registry.estimate(m, truth)
    np.testing.assert_allclose(est["x"], truth["truth_x"], atol=1e-10)
    np.testing.assert_allclose(est["y"], truth["truth_y"], atol=1e-10)
    np.testing.assert_allclose(est["yaw"], truth["truth_yaw"], atol=1e-10)
    assert est.info["identification"]["a"] == pytest.approx(a)
    with pytest.raises(registry.CalibrationLeak):
        registry.estimate(m, runs[0])
    # the published curve and the default model differ from the identified law on this path
    pub = W.ChiLambda(curve=W.PUBLISHED_CURVE).estimate(truth)
    assert np.max(np.abs(pub["yaw"] - truth["truth_yaw"])) > 1e-3


def test_chi_lambda_needs_calibration_and_turning_runs():
    run = circle_run(2.0, 0.3, 1.4, duration=3.0)
    with pytest.raises(W.NotCalibratedError):
        W.ChiLambda().estimate(run)
    with pytest.raises(W.CalibrationDataError, match="two turning runs"):
        W.ChiLambda().calibrate([run])
