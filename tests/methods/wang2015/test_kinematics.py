"""Wang 2015 eqs. (11), (14)-(15), (46): the symmetric model's dead reckoning (synthetic runs)."""
from __future__ import annotations

import numpy as np

from bench.run import from_arrays
from methods import mandow2007, wang2015 as W
from tests.methods.wang2015.synthetic import B, PLATFORM, R, symmetric_run


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

