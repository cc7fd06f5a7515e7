"""The diagnosis' scheme-3 variants (methods.yi2009.repro.evaluation.attribution_estimate) on synthetic runs of
tests/methods/yi2009/synthetic.py: with nothing removed they are the plugin's filter, the true S replaces S(gamma)
(41) exactly, and on a run where every measurement row is exact (no slip, chi = 1, good sensors) the true S makes the
filter follow the truth while a wrong S does not."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from methods.yi2009.ekf import Yi2009Ekf
from methods.yi2009.repro.evaluation import attribution_estimate
from methods.yi2009.s_gamma import SGamma
from tests.methods.yi2009.synthetic import PAPER, pos_rms, synthetic_run

EXACT = dataclasses.replace(PAPER, lam0=0.0, chi=1.0)  # no slip, no ICR expansion: (13), (15) are the truth
WRONG = Yi2009Ekf(variant=3, s_gamma=SGamma(0.03 * 0.039, 0.0, 0.039))  # S = 3 cm everywhere


@pytest.fixture(scope="module")
def run():
    return synthetic_run("circle", 0, EXACT)


def test_nothing_removed_is_the_plugins_filter(run):
    a, b = attribution_estimate(WRONG, run, s_true=None, feedback=True), WRONG.estimate(run)
    for c in ("x", "y", "yaw", "vx", "vy", "slip_l", "slip_r", "x_icr"):
        np.testing.assert_array_equal(a[c], b[c])


def test_the_true_s_is_the_s_the_filter_uses(run):
    s_true = float(np.nanmedian(run["truth_x_icr"][run.t > 2.0]))
    est = attribution_estimate(WRONG, run, s_true=s_true, feedback=False)
    moving = est.t > 2.0
    np.testing.assert_allclose(est["x_icr"][moving], s_true, rtol=1e-12)


@pytest.mark.parametrize("feedback", [True, False])
def test_exact_rows_with_the_true_s_follow_the_truth(run, feedback):
    """On the circle the truth's S is constant (gamma is): with it every row is exact and the error is the sensors'
    (mm); with S = 3 cm instead of ~18 cm the v_y row is wrong and the path drifts by decimetres."""
    s_true = float(np.nanmedian(run["truth_x_icr"][run.t > 2.0]))
    good = attribution_estimate(WRONG, run, s_true=s_true, feedback=feedback)
    bad = attribution_estimate(WRONG, run, s_true=None, feedback=feedback)
    e_good, e_bad = (pos_rms(e.t, e["x"], e["y"], run) for e in (good, bad))
    assert e_good < 0.01 and e_bad > 10 * e_good
