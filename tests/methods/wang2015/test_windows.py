"""Wang 2015 on real-data command windows: the window models the plugins offer (``window_models``) predict the
same end poses and fit the same parameters as the original bench/real/benchmark.py classes (copied in
tests/methods/wang2015/original_windows.py), and follow the closed forms of eqs. (11), (15) and (44)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.real.drive import DRIVE_DT
from bench.real.windows import window_chi
from methods import wang2015 as W
from methods.wang2015 import windows as WW
from tests.methods.wang2015.original_windows import (B, N, R, OriginalSymmetricChi, OriginalWangChiCurve,
                                                     drive_speeds, make_windows, same_poses, wang_chi,
                                                     with_reference)


def test_constant_chi_offers_the_original_symmetric_chi():
    rng = np.random.default_rng(11)
    wl, wr = drive_speeds(rng, 30)
    w = with_reference(make_windows(wl, wr), OriginalSymmetricChi(R, B, chi=2.3), rng, noise=0.01)
    models = W.ConstantChi().window_models(R, B)
    assert len(models) == 1
    new, old = models[0], OriginalSymmetricChi(R, B)
    assert isinstance(new, WW.SymmetricChi) and new == WW.SymmetricChi(R, B)
    assert (new.name, new.label, new.params()) == (old.name, old.label, old.params()) == (
        "icr_sym_chi", old.label, {"chi": 1.0})
    for chi in (1.0, 1.5, 2.3, 4.0):
        assert same_poses(dataclasses.replace(new, chi=chi).predict(w), dataclasses.replace(old, chi=chi).predict(w))
    fn, fo = new.fit(w), old.fit(w)
    assert fn.chi == fo.chi and fn.fit_cost == fo.fit_cost and fn.params() == fo.params()
    assert fn.chi == pytest.approx(2.3, abs=0.01)
    assert same_poses(fn.predict(w), fo.predict(w))


def test_symmetric_chi_is_the_closed_form_arc():
    """Constant wheel speeds: eq. (11) with eq. (15), v = (v_l + v_r)/2, omega = (v_r - v_l)/(B chi), held over
    the N - 1 intervals of a window, is a circular arc from the initial ICP pose."""
    rng = np.random.default_rng(4)
    wl, wr = drive_speeds(rng, 12, steady=True)
    w = with_reference(make_windows(wl, wr), OriginalSymmetricChi(R, B, chi=1.0), rng)
    chi = 1.7
    x, y, h = dataclasses.replace(W.ConstantChi().window_models(R, B)[0], chi=chi).predict(w)
    v, om = R * (wl[:, 0] + wr[:, 0]) / 2, R * (wr[:, 0] - wl[:, 0]) / (B * chi)
    x0, y0, h0 = w["ref_x"][:, 0], w["ref_y"][:, 0], w["ref_yaw"][:, 0]
    T = (N - 1) * DRIVE_DT
    turn = np.abs(om) > 0
    rad = np.where(turn, v / np.where(turn, om, 1.0), 0.0)
    h1 = h0 + om * T
    xe = np.where(turn, x0 + rad * (np.sin(h1) - np.sin(h0)), x0 + v * T * np.cos(h0))
    ye = np.where(turn, y0 + rad * (np.cos(h0) - np.cos(h1)), y0 + v * T * np.sin(h0))
    np.testing.assert_allclose(x[:, -1], xe, atol=1e-10)
    np.testing.assert_allclose(y[:, -1], ye, atol=1e-10)
    np.testing.assert_allclose(h[:, -1], h1, atol=1e-12)


def test_chi_lambda_offers_the_original_wang_chi_curve():
    rng = np.random.default_rng(3)
    n = 60
    wl, wr = drive_speeds(rng, n, steady=True)
    steady = rng.uniform(size=n) < 0.7
    w = with_reference(make_windows(wl, wr, steady=steady), OriginalWangChiCurve(R, B, a=1.2, b=0.15), rng)
    models = W.ChiLambda().window_models(R, B)
    assert len(models) == 1
    new, old = models[0], OriginalWangChiCurve(R, B)
    assert isinstance(new, WW.WangChiCurve) and new == WW.WangChiCurve(R, B)
    assert (new.name, new.label, new.params(), new.min_turn) == (old.name, old.label, old.params(), old.min_turn)
    for a, b in ((0.4728, 0.0538), (1.2, 0.15), (0.5, 0.0)):
        pn = dataclasses.replace(new, a=a, b=b).predict(w)
        assert same_poses(pn, dataclasses.replace(old, a=a, b=b).predict(w))
        # straight (lambda = inf) and standing (0/0) windows are finite when b > 0 (b = 0: 0 * sqrt(inf) is NaN, as
        # in the original, and bench.real.windows.integrate_windows chains the windows, so every pose is NaN)
        assert all(np.isfinite(p).all() for p in pn) == (b > 0)
    fn, fo = new.fit(w), old.fit(w)
    assert (fn.a, fn.b, fn.fit_cost, fn.n_fit) == (fo.a, fo.b, fo.fit_cost, fo.n_fit)
    assert fn.params() == fo.params()
    assert (fn.a, fn.b) == pytest.approx((1.2, 0.15), abs=1e-6)
    assert fn.n_fit == window_chi(w, R, B)[3].sum() > 20
    assert same_poses(fn.predict(w), fo.predict(w))
    few = make_windows(wl[:3], wr[:3], steady=np.zeros(3, bool))  # no usable window: published curve kept
    assert new.fit(few) == dataclasses.replace(new, n_fit=0) and old.fit(few).n_fit == 0


def test_wang_chi_is_eq44_without_the_domain_limit():
    a, b = 0.4728, 0.0538  # Wang 2015 eq. (45)
    assert WW.WANG_P3AT == (a, b) == (W.PUBLISHED_CURVE.a, W.PUBLISHED_CURVE.b)
    lam = np.array([0.0, 1.0, 4.0, -4.0, 400.0, np.inf, np.nan])
    np.testing.assert_allclose(WW.wang_chi(lam, a, b), [1 + a, 1 + a / (1 + b), 1 + a / (1 + 2 * b),
                                                        1 + a / (1 + 2 * b), 1 + a / (1 + 20 * b), 1.0, 1 + a])
    rng = np.random.default_rng(2)
    lam = np.r_[rng.normal(0, 30, 200), np.inf, -np.inf, np.nan, 0.0]
    for a, b in ((a, b), (1.2, 0.15), (0.3, 0.0)):
        assert np.array_equal(WW.wang_chi(lam, a, b), wang_chi(lam, a, b), equal_nan=True)
    # the plugins' own curve holds chi(10) beyond lambda = 10; the window model extrapolates eq. (44)
    assert float(W.PUBLISHED_CURVE(400.0)) == float(W.PUBLISHED_CURVE(10.0)) > float(WW.wang_chi(400.0, a, b))
