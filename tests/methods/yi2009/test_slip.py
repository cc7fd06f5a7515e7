"""Yi 2009 slip (6) and its sign constraint (14): methods.yi2009.slip.
"""
from __future__ import annotations

import numpy as np

from methods.yi2009.slip import constrained_slip, slip_ratio
from tests.methods.yi2009.synthetic import R_WHEEL


def test_slip_ratio_definition_and_clipping():
    """Eq. (6) and the [-1, 1] bound of Sec. III-A; 0 at standstill."""
    lam = slip_ratio([10.0, 10.0, 10.0, 10.0, 0.0], [0.9 * R_WHEEL * 10, R_WHEEL * 10 * 1.2, -1.0, 50.0, 0.3], R_WHEEL)
    np.testing.assert_allclose(lam, [0.1, -0.2, 1.0, -1.0, 0.0], atol=1e-12)


def test_constrained_slip_follows_turn_direction():
    """Eq. (14): the faster side keeps only lambda >= 0, the slower only lambda <= 0; equal speeds are the
    w_L <= w_R case of Sec. III-C's sentence ("lambda_L <= 0 and lambda_R >= 0"): left braking, right traction."""
    lam_l = np.array([0.2, -0.2, 0.2, -0.2, 0.1, -0.1])
    lam_r = np.array([-0.1, 0.1, 0.3, -0.3, 0.1, -0.1])
    w_l = np.array([8.0, 8.0, 4.0, 4.0, 5.0, 5.0])
    w_r = np.array([4.0, 4.0, 8.0, 8.0, 5.0, 5.0])
    pl, pr = constrained_slip(lam_l, lam_r, w_l, w_r)
    np.testing.assert_array_equal(pl, [0.2, 0.0, 0.0, -0.2, 0.0, -0.1])
    np.testing.assert_array_equal(pr, [-0.1, 0.0, 0.3, 0.0, 0.1, 0.0])


def test_constrained_slip_at_equal_speeds_bounds_the_speed_from_both_sides():
    """On a straight line (w_L = w_R, zero yaw rate: lambda_L = lambda_R = lambda) the v_x of eq. (13),
    r w (1 - (lambda'_L + lambda'_R)/2), is the mean of the encoder speed and the filter's own, r w (1 - lambda / 2),
    whatever the sign of lambda: a filter speed behind the wheels (lambda > 0, up to the +1 clip) is pulled up and
    one ahead (lambda < 0) pulled down.  The printed (14)'s ">=" for lambda'_L (traction on both sides) gives
    r w (1 - lambda) for lambda > 0: the filter's own speed, and 0 at the clip (the latch).  Equal speeds also give
    the limit of w_L < w_R (the case the sentence assigns them to)."""
    lam = np.array([1.0, 0.6, 0.2, -0.2, -0.6])
    w = np.full(lam.size, 3.14)
    pl, pr = constrained_slip(lam, lam, w, w)
    v13 = R_WHEEL * w * (1.0 - (pl + pr) / 2.0)
    np.testing.assert_allclose(v13, R_WHEEL * w * (1.0 - lam / 2.0), rtol=0, atol=1e-15)
    assert v13[0] == R_WHEEL * 3.14 / 2.0  # at the +1 clip (filter speed 0) (13) still reads half the wheel speed
    pl2, pr2 = constrained_slip(lam, lam, w, w + 1e-9)
    np.testing.assert_array_equal(pl, pl2)
    np.testing.assert_array_equal(pr, pr2)


def test_the_straight_line_slip_claim_is_decided_by_the_testbed_not_by_construction(sim):
    """yi2009.slip_straight_near_zero ("less force is needed to drive the robot"): on Yi's concrete straight (30/30
    rpm) the four driven wheels need no net traction (rolling resistance on rigid ground is a moment at each wheel,
    bench/sim/testbed.py), so the truth slip is ~0; the same straight up a 5 deg grade needs traction m g sin(5 deg)
    and its truth slip RMS passes the vision slip's error (the claim's denominator, committed full run): the claim
    evaluated on those numbers fails."""
    import json
    import tomllib
    from pathlib import Path

    from bench.reproduce.claims import evaluate_claim
    from methods.yi2009.repro.settings import SETTINGS

    repo = Path(__file__).resolve().parents[3]
    claim = next(c for c in tomllib.loads((repo / "scenarios/papers/yi2009.toml").read_text())["claims"]
                 if c["id"] == "slip_straight_near_zero")
    den = json.loads((repo / "results/metrics.json").read_text())["metrics"]["yi2009.fig7.straight.ref_vs_truth"]["value"]

    def truth_rms(run) -> float:  # as methods/yi2009/repro/evaluation.py _truth_diagnostics
        tl = np.clip(np.column_stack((run["truth_slip_l"], run["truth_slip_r"])), -1.0, 1.0)
        keep = (run.t >= SETTINGS.slip_t0) & np.isfinite(tl).all(axis=1)
        return float(np.sqrt(np.mean(tl[keep] ** 2)))

    flat = truth_rms(sim("yi_straight", 0, duration=10.0))
    grade = truth_rms(sim("yi_straight", 0, duration=10.0, terrain__slope_deg=5.0))
    assert flat < 1e-4 < den < grade  # measured: ~1e-6, 0.035, 0.051
    holds = {rms: evaluate_claim(claim, {claim["num"]: rms, claim["den"]: den})[0] for rms in (flat, grade)}
    assert holds == {flat: True, grade: False}
