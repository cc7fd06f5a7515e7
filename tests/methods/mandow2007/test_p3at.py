"""Mandow 2007 Sec. IV-B: the P3-AT default model and the server parameters of eqs. (14)-(15)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.run import from_arrays
from methods import mandow2007 as M
from tests.methods.mandow2007.synthetic import PLATFORM


def test_default_p3at_model():
    """Sec. IV-B: alpha = 1 and x_ICR = 0.3 m: omega = (V_r - V_l)/0.6, v = (V_l + V_r)/2."""
    r = PLATFORM["wheel_radius"]
    t = np.arange(501) / 100.0
    run = from_arrays({"t": t, "enc_wl": np.full(t.size, 1.0), "enc_wr": np.full(t.size, 3.0)},
                      {"platform": PLATFORM, "run_id": "p3at"})
    est = M.DefaultP3at().estimate(run)
    np.testing.assert_allclose(est["wz"], r * 2.0 / 0.6)
    np.testing.assert_allclose(est["vx"], r * 2.0)
    np.testing.assert_allclose(est["yaw"][-1], 5.0 * r * 2.0 / 0.6, rtol=1e-12)
    assert est.info["steering_efficiency"] == pytest.approx(0.4 / 0.6)


def test_p3at_server_parameters_eqs_14_15():
    """Default model (alpha = 1, x_ICR = 300 mm) with 110 mm wheels: Ticksmm = round(110 * 138/110)
    = 138, Revcount = round(2 pi 300 * 138 / 8) = round(32515.48) = 32515."""
    assert M.p3at_server_parameters(1.0, 0.3, 0.11) == (138, 32515)
    back = M.p3at_symmetric_model(138, 32515, 0.11)
    assert back.alpha_l == back.alpha_r == pytest.approx(1.0, rel=1e-15)
    assert back.x_icr_r == pytest.approx(0.3, abs=8 / (2 * np.pi * 138) / 1000)  # one Revcount step
    ticks, rev = M.p3at_server_parameters(0.91, 0.275, 0.11)  # Sec. IV-D symmetric model
    assert ticks == round(0.91 * 138) and rev == round(2 * np.pi * 275 * ticks / 8)
