"""Mandow 2007 eq. (13): segments and the batched segment dead reckoning (synthetic runs)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.kinematics import integrate_se2
from methods import mandow2007 as M
from methods.baselines import encoder_speeds
from tests.methods.mandow2007.synthetic import joystick_run


def test_segment_increments_match_integrate_se2_per_segment():
    """The batched segment dead reckoning equals bench.kinematics.integrate_se2 restarted at each
    segment's reference pose (second implementation)."""
    truth = M.TABLE_I["pneumatic_50psi"]
    run = joystick_run(truth, duration=10.0, seed=7)
    seg = M.build_segments([run])
    assert seg.n_segments == 50 and seg.n_intervals == 1000
    p = M.IcrParams(-0.31, 0.27, 0.02, 0.95, 0.9)
    dx, dy, dphi = (a[0] for a in M.segment_increments(seg, p.as_array()))
    t = run.t
    _, wl, wr = encoder_speeds(run)  # the speeds of the periods [t_k, t_(k+1)]
    vx, vy, wz = M.body_velocities(p, wl * 0.11, wr * 0.11)
    ends = np.flatnonzero(np.isfinite(run["ref_x"]))
    for i, (a, b) in enumerate(zip(ends[:-1], ends[1:], strict=True)):
        x, y, yaw = integrate_se2(t[a:b + 1], vx[a:b + 1], vy[a:b + 1], wz[a:b + 1])
        assert (dx[i], dy[i], dphi[i]) == pytest.approx((x[-1], y[-1], yaw[-1]), abs=1e-14)
    # the reference increments are expressed in the frame of the segment's start pose
    rx, ry, ryaw = run["ref_x"][ends], run["ref_y"][ends], run["ref_yaw"][ends]
    c, s = np.cos(ryaw[:-1]), np.sin(ryaw[:-1])
    np.testing.assert_allclose(seg.ref_dx, c * np.diff(rx) + s * np.diff(ry), atol=1e-15)
    np.testing.assert_allclose(seg.ref_dy, -s * np.diff(rx) + c * np.diff(ry), atol=1e-15)


def test_cost_is_zero_at_truth_and_errors_are_world_frame():
    truth = M.TABLE_II["solid_rubber"]
    seg = M.build_segments([joystick_run(truth, duration=10.0, seed=2)])
    pop = np.vstack([truth.as_array(), truth.as_array() + [0.01, 0, 0, 0, 0], [0.3, -0.3, 0, 1, 1]])
    j = M.segment_cost(seg, pop)
    assert j[0] < 1e-24 and j[1] > 1e-6 and j[2] == np.inf  # last row: x_ICRr < x_ICRl, degenerate
    assert float(M.segment_cost(seg, truth.as_array())) == pytest.approx(j[0], abs=1e-30)
    wrong = M.IcrParams.symmetric(1.0, 0.3)
    err = M.segment_errors(seg, wrong)
    total = np.sum(err["ex"] ** 2 + err["ey"] ** 2 + err["ephi"] ** 2)
    assert total == pytest.approx(float(M.segment_cost(seg, wrong.as_array())), rel=1e-12)


def test_segments_at_the_reference_rate_and_merged():
    truth = M.TABLE_I["pneumatic_50psi"]
    run = joystick_run(truth, duration=10.0, seed=1, ref_rate=20.0)
    assert M.build_segments([run]).n_segments == 200
    merged = M.build_segments([run], segment_period=0.5)
    assert merged.n_segments == 20 and np.allclose(merged.duration, 0.5)
    two = M.build_segments([run, joystick_run(truth, duration=5.0, seed=2)])
    assert two.n_segments == 200 + 25 and two.run_ids == ("joystick1", "joystick2")
    assert float(M.segment_cost(two, truth.as_array())) < 1e-24
