"""Wang 2015 eqs. (25)-(27), (44)-(45): chi per run, the identification plan and the (a, b) fit."""
from __future__ import annotations

import numpy as np
import pytest

from bench.run import RunError
from methods import wang2015 as W
from tests.methods.wang2015.synthetic import B, circle_run, eq45


def test_fit_recovers_published_a_b_from_eq45_points():
    plan = W.identification_plan()
    assert len(plan) == 40
    cr = np.array([p.curvature_ratio for p in plan])
    curve = W.fit_chi_curve(cr, eq45(cr))
    assert curve.a == pytest.approx(0.4728, abs=1e-9)
    assert curve.b == pytest.approx(0.0538, abs=1e-9)
    # negative curvature ratios (clockwise turns) enter through |lambda|; NaN points are dropped
    curve2 = W.fit_chi_curve(np.r_[-cr, np.nan], np.r_[eq45(cr), 1.4])
    assert (curve2.a, curve2.b) == pytest.approx((0.4728, 0.0538), abs=1e-9)
    with pytest.raises(W.CalibrationDataError):
        W.fit_chi_curve([1.0], [1.4])


def test_fit_with_table3_data_is_close_to_published():
    """Table 3 means (8 points) give a fit near eq. (45) (the paper fits all its runs)."""
    cr = np.array(list(W.TABLE_3))
    chi = np.array([W.TABLE_3[k][0] for k in W.TABLE_3])
    curve = W.fit_chi_curve(cr, chi)
    assert np.max(np.abs(curve(cr) - eq45(cr))) < 0.01
    assert np.max(np.abs(curve(cr) - chi)) < 0.01


def test_chi_curve_domain_and_published_values():
    assert W.PUBLISHED_CURVE(0.0) == pytest.approx(1.4728)
    assert W.PUBLISHED_CURVE(4.0) == pytest.approx(1 + 0.4728 / 1.1076)
    assert W.PUBLISHED_CURVE(25.0) == W.PUBLISHED_CURVE(10.0)  # held beyond lambda = 10
    assert W.PUBLISHED_CURVE(np.inf) == W.PUBLISHED_CURVE(10.0)
    assert W.chi_of_curvature_ratio(np.inf, 0.4728, 0.0538, None) == 1.0  # extrapolated limit
    assert W.PUBLISHED_CURVE(-3.0) == W.PUBLISHED_CURVE(3.0)


def test_identification_plan_matches_eqs_26_27():
    from bench.kinematics import curvature_ratio
    for p in W.identification_plan():
        if p.curvature_ratio == 0:
            assert (p.v_l, p.v_r) == (-p.speed, p.speed)
        else:
            assert float(curvature_ratio(p.v_l, p.v_r)) == pytest.approx(p.curvature_ratio)
            assert (p.v_l + p.v_r) / 2 == pytest.approx(p.speed)


# ------------------------------------------------------------------------------------------------ eq. (25)
@pytest.mark.parametrize("cr,v,chi", [(3.0, 0.3, 1.43), (0.0, 0.2, 1.47), (-5.0, 0.4, 1.41), (1.0, 0.1, 1.6)])
def test_chi_per_run_on_a_steady_circle(cr, v, chi):
    got = W.chi_per_run(circle_run(cr, v, chi, duration=15.0))
    assert got.chi == pytest.approx(chi, rel=1e-12)
    assert got.y0 == pytest.approx(B * chi / 2, rel=1e-12)
    if cr != 0:
        assert got.curvature_ratio == pytest.approx(cr, rel=1e-12)
        assert got.speed == pytest.approx(v, rel=1e-12)
    else:
        assert got.curvature_ratio == 0.0 and got.tread_speed == pytest.approx(v)


def test_chi_per_run_errors():
    straight = circle_run(1e9, 0.3, 1.4, duration=5.0, run_id="line")
    with pytest.raises(RunError, match=r"line.*ref_yaw.*turning run"):
        W.chi_per_run(straight)
    run = circle_run(2.0, 0.3, 1.4, duration=5.0)
    with pytest.raises(RunError, match="ref_yaw"):
        W.chi_per_run(type(run)(run.data.drop(columns="ref_yaw"), run.meta))

