"""methods/liu2020/inputs.py: the two dropout rules (_encoder_fresh, _within_sampling) at their limit."""
from __future__ import annotations

import numpy as np
import pytest


@pytest.mark.parametrize("t0", [0.0, 0.3, 12.345, 1000.0, 3600.1])
def test_gap_rules_do_not_depend_on_the_rounding_of_the_times(t0):
    """A sensor at 3 samples per 7 rows of a 125 Hz log (intervals of 2 and 3 rows, median 2) has intervals of
    exactly 1.5 median intervals, the limit of both gap rules.  Whatever the start time (whose rounding decides
    without slack: 150-168 of 2096 times refused at 0, 0.3 and 3600.1 s, none at 12.345 or 1000 s), no time within
    the samples' span is a gap for _within_sampling and no sample is stale for _encoder_fresh; a real gap of 5
    rows (2.5 median intervals, one sample dropped) still is, in both (stale from 4 rows, 2 intervals, on)."""
    from methods.liu2020.inputs import _encoder_fresh, _within_sampling

    grid = t0 + np.arange(3000) / 125.0
    rows = np.cumsum(np.tile([2, 2, 3], 300))[:899]
    span = slice(rows[0], rows[-1] + 1)
    enc_ok = np.zeros(grid.size, bool)
    enc_ok[rows] = True
    assert _within_sampling(grid[rows], grid[span]).all()
    assert _encoder_fresh(grid, enc_ok)[span].all()
    gap = rows[rows != rows[400]]  # samples at rows[399] and rows[401]: 2 + 3 = 5 rows apart
    inside = _within_sampling(grid[gap], grid[span])
    assert not inside[rows[399] - rows[0] + 1:rows[401] - rows[0]].any() and inside.sum() >= grid[span].size - 4
    enc_ok[rows[400]] = False
    fresh = _encoder_fresh(grid, enc_ok)
    assert not fresh[rows[399] + 4:rows[401]].any() and fresh[rows[399]:rows[399] + 4].all()


def test_without_a_position_fix_block_1_keeps_the_velocity_rows_and_drops_the_heading_row() -> None:
    """Liu Sec. IV-C after (32): GNSS unavailable, the measurement vector descends to 9x1 "with the position readings
    deleted".  A sample with heading and velocity but no position keeps the body velocity rows (the GNSS world
    velocity rotated by the GNSS heading, checked here in closed form) and the gyro, loses x, y and heading; a whole
    fix keeps all six rows."""
    from bench.robustness.faults import gnss_outage
    from methods.liu2020.model import _gnss_block
    from tests.methods.liu2020.synthetic import make_run

    run = make_run(0, duration=6.0)
    t = run.t
    cut = gnss_outage(run, 2.0, 4.0, channels=("gnss_x", "gnss_y"))
    full, nine = _gnss_block(run), _gnss_block(cut)
    fix = np.isfinite(run["gnss_x"])
    inside = fix & (t >= 2.0) & (t < 4.0)
    assert inside.sum() > 5
    assert np.isnan(nine[inside][:, :3]).all()  # x, y and the heading row deleted
    yaw, vx, vy = run["gnss_yaw"][inside], run["gnss_vx"][inside], run["gnss_vy"][inside]
    body = np.column_stack((np.cos(yaw) * vx + np.sin(yaw) * vy, -np.sin(yaw) * vx + np.cos(yaw) * vy))
    np.testing.assert_allclose(nine[inside][:, 3:5], body, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(nine[inside][:, 5], run["imu_gz"][inside])
    outside = fix & ~((t >= 2.0) & (t < 4.0))
    np.testing.assert_array_equal(nine[outside], full[outside])
    assert np.isfinite(full[fix]).all()
