"""Wang 2015: chi(curvature ratio) model, chi per run, the (a, b) fit, plugins (synthetic runs).

Synthetic runs follow the symmetric model written out here from eqs. (11), (13), (15):
vx = (v_l + v_r)/2, omega = (v_r - v_l)/(B chi), poses by bench.kinematics.integrate_se2.
"""
from __future__ import annotations

import numpy as np
import pytest

from bench import registry
from bench.kinematics import integrate_se2
from bench.run import RunError, from_arrays
from methods import mandow2007, wang2015 as W

PLATFORM = {"name": "p3at", "track": 0.4, "wheel_radius": 0.11}
B, R = PLATFORM["track"], PLATFORM["wheel_radius"]


def symmetric_run(v_l: np.ndarray, v_r: np.ndarray, chi: np.ndarray, t: np.ndarray, ref_rate: float = 135.0,
                  pose0=(0.0, 0.0, 0.0), run_id: str = "sym"):
    vx = 0.5 * (v_l + v_r)
    wz = (v_r - v_l) / (B * chi)
    x, y, yaw = integrate_se2(t, vx, np.zeros_like(t), wz, *pose0)
    step = max(1, int(round(1.0 / ((t[1] - t[0]) * ref_rate))))
    ref = np.zeros(t.size, bool)
    ref[::step] = True
    ref[-1] = True
    cols = {"t": t, "enc_wl": v_l / R, "enc_wr": v_r / R, "ref_x": np.where(ref, x, np.nan),
            "ref_y": np.where(ref, y, np.nan), "ref_yaw": np.where(ref, yaw, np.nan),
            "truth_x": x, "truth_y": y, "truth_yaw": yaw}
    return from_arrays(cols, {"platform": dict(PLATFORM), "run_id": run_id})


def circle_run(curvature_ratio: float, v: float, chi: float, duration: float = 20.0, run_id: str = "circle"):
    t = np.arange(int(duration * 100) + 1) / 100.0
    if curvature_ratio == 0:
        v_l, v_r = -v, v
    else:
        v_l, v_r = v * (1 - 1 / curvature_ratio), v * (1 + 1 / curvature_ratio)
    return symmetric_run(np.full(t.size, v_l), np.full(t.size, v_r), np.full(t.size, chi), t, run_id=run_id)


def eq45(cr):
    return 1 + 0.4728 / (1 + 0.0538 * np.sqrt(np.abs(cr)))


# ------------------------------------------------------------------------------------------------ eq. (44)
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


# ------------------------------------------------------------------------------------------------ models
def test_consistent_eq15_form_equals_mandow_default_and_literal_halves_the_rate():
    """chi = 1.5 with y0 = B chi / 2 = 0.3 m is Mandow's P3-AT default (x_ICR = 0.3 m, alpha = 1);
    the literal eq. (46) turns half as fast."""
    t = np.arange(1001) / 100.0
    rng = np.random.default_rng(5)
    v_l = np.repeat(rng.uniform(-0.4, 0.6, 11), 91)[: t.size]
    v_r = np.repeat(rng.uniform(-0.4, 0.6, 11), 91)[: t.size]
    run = symmetric_run(v_l, v_r, np.full(t.size, 1.5), t)
    wang = W.ConstantChi().estimate(run)
    mandow = mandow2007.DefaultP3at().estimate(run)
    for c in ("x", "y", "yaw", "y_l", "y_r"):
        np.testing.assert_allclose(wang[c], mandow[c], atol=1e-12, err_msg=c)
    np.testing.assert_allclose(wang["x"], run["truth_x"], atol=1e-12)
    literal = W.ConstantChi(literal_eq46=True).estimate(run)
    np.testing.assert_allclose(literal["wz"], wang["wz"] / 2, atol=1e-15)
    np.testing.assert_allclose(literal["y_l"], 2 * wang["y_l"])


def test_constant_chi_circle_closes_to_analytic_circle():
    """Constant speed circle: radius R = lambda y0 (eq. (14)), back at the start after one turn."""
    cr, v, chi = 4.0, 0.3, 1.5
    y0 = B * chi / 2
    w = 2 * v / (cr * B * chi)
    period = 2 * np.pi / w
    t = np.linspace(0, period, 3001)
    v_l, v_r = v * (1 - 1 / cr), v * (1 + 1 / cr)
    run = from_arrays({"t": t, "enc_wl": np.full(t.size, v_l / R), "enc_wr": np.full(t.size, v_r / R)},
                      {"platform": PLATFORM, "run_id": "c"})
    est = W.ConstantChi(chi=chi).estimate(run)
    radius = cr * y0
    np.testing.assert_allclose(est["x"], radius * np.sin(w * t), atol=1e-10)
    np.testing.assert_allclose(est["y"], radius * (1 - np.cos(w * t)), atol=1e-10)
    assert abs(est["x"][-1]) < 1e-10 and abs(est["y"][-1]) < 1e-10


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
