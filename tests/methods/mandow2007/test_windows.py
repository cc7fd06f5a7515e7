"""Mandow 2007 on real-data command windows: the window model the asymmetric plugins offer (``window_models``)
predicts the same end poses and fits the same parameters as the original bench/real/benchmark.py class (copied
in tests/methods/wang2015/original_windows.py), and is eq. (7) in skidbench axes."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from methods import mandow2007 as M
from methods.mandow2007 import windows as MW
from tests.methods.wang2015.original_windows import (B, R, OriginalAsymmetricICR, OriginalSymmetricChi, drive_speeds,
                                                     make_windows, same_poses, with_reference)

TRUTH = dict(y_l=0.62, y_r=-0.51, x_icr=-0.08, alpha_l=0.86, alpha_r=0.91)  # tests/test_real.py's generating model


def test_asymmetric_plugins_offer_the_original_asymmetric_icr():
    rng = np.random.default_rng(7)
    wl, wr = drive_speeds(rng, 40)
    w = with_reference(make_windows(wl, wr), OriginalAsymmetricICR(R, B, **TRUTH), rng, noise=0.01)
    (ga,), (de,) = M.AsymmetricGa().window_models(R, B), M.AsymmetricDe().window_models(R, B)
    assert isinstance(ga, MW.AsymmetricICR) and ga == de == MW.AsymmetricICR(R, B)
    old = OriginalAsymmetricICR(R, B)
    assert (ga.name, ga.label) == (old.name, old.label) == ("mandow2007_icr", old.label)
    for k in (TRUTH, dict(y_l=0.3, y_r=-0.3, x_icr=0.0, alpha_l=1.0, alpha_r=1.0),
              dict(y_l=1.4, y_r=-0.2, x_icr=0.3, alpha_l=1.2, alpha_r=0.7)):
        new_k, old_k = dataclasses.replace(ga, **k), dataclasses.replace(old, **k)
        assert same_poses(new_k.predict(w), old_k.predict(w))
        assert new_k.params() == old_k.params()
    fn, fo = ga.fit(w), old.fit(w)
    assert fn.params() == fo.params() and fn.fit_cost == fo.fit_cost
    assert fn.params() == pytest.approx({**TRUTH, "chi": (0.62 + 0.51) / B}, abs=0.02)
    assert same_poses(fn.predict(w), fo.predict(w))


def test_asymmetric_icr_is_eq7_in_skidbench_axes():
    """Velocities of the window model = Mandow's matrix A (eq. (7)) on the nominal tread speeds, converted from his
    axes (X lateral right, Y forward): vx = v_y, vy = -v_x; K maps as x_ICRl = -y_l, x_ICRr = -y_r, y_ICRv = x_icr."""
    rng = np.random.default_rng(5)
    wl, wr = drive_speeds(rng, 10)
    w = make_windows(wl, wr)
    m = dataclasses.replace(M.AsymmetricGa().window_models(R, B)[0], **TRUTH)
    k = m.icr_params()
    assert k == M.IcrParams(-0.62, 0.51, -0.08, 0.86, 0.91) and k.body_icr() == (0.62, -0.51, -0.08)
    vx, vy, wz = m.velocities(w)
    mv = M.kinematic_matrix(k) @ np.vstack([R * wl.ravel(), R * wr.ravel()])
    np.testing.assert_allclose(vx.ravel(), mv[1], atol=1e-13)
    np.testing.assert_allclose(vy.ravel(), -mv[0], atol=1e-13)
    np.testing.assert_allclose(wz.ravel(), mv[2], atol=1e-13)


def test_asymmetric_icr_recovers_generating_models():
    """Noise-free windows of a known K give K back; symmetric windows (constant chi) give the symmetric model,
    whose chi is also the fit's start (``wang2015.constant_chi``'s window model, through the registry)."""
    rng = np.random.default_rng(7)
    wl, wr = drive_speeds(rng, 80)
    m = M.AsymmetricDe().window_models(R, B)[0]
    w = with_reference(make_windows(wl, wr), OriginalAsymmetricICR(R, B, **TRUTH), rng)
    fit = m.fit(w)
    for name, value in TRUTH.items():
        assert getattr(fit, name) == pytest.approx(value, abs=1e-5), name
    assert fit.fit_cost < 1e-12
    ws = with_reference(make_windows(wl, wr), OriginalSymmetricChi(R, B, chi=2.3), rng)
    fa = m.fit(ws)
    assert (fa.y_l, fa.y_r, fa.x_icr, fa.alpha_l, fa.alpha_r) == pytest.approx((2.3 * B / 2, -2.3 * B / 2, 0, 1, 1),
                                                                                abs=1e-5)
