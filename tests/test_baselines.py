"""baseline.ideal_dd and the shared run helpers of methods.baselines (synthetic runs, closed forms)."""
from __future__ import annotations

import numpy as np
import pytest

from bench import registry
from bench.run import RunError, from_arrays
from methods.baselines import IdealDD, encoder_speeds, held_integral, initial_pose, reference_poses

PLATFORM = {"name": "test", "track": 0.4, "wheel_radius": 0.11}


def constant_run(wl: float, wr: float, duration: float = 10.0, rate: float = 100.0, pose0=(0.0, 0.0, 0.0),
                 with_ref: bool = True, platform=PLATFORM):
    t = np.arange(int(round(duration * rate)) + 1) / rate
    cols = {"t": t, "enc_wl": np.full(t.size, wl), "enc_wr": np.full(t.size, wr)}
    if with_ref:
        ref = np.full(t.size, np.nan)
        cols |= {"ref_x": ref.copy(), "ref_y": ref.copy(), "ref_yaw": ref.copy()}
        cols["ref_x"][0], cols["ref_y"][0], cols["ref_yaw"][0] = pose0
    return from_arrays(cols, {"platform": dict(platform), "run_id": f"const_{wl}_{wr}"})


def test_ideal_dd_circle_closed_form():
    """No-slip circle: radius (B/2)(v_r + v_l)/(v_r - v_l) about the point left of the start."""
    r, b = PLATFORM["wheel_radius"], PLATFORM["track"]
    wl, wr = 2.0, 3.0
    pose0 = (1.0, -2.0, 0.7)
    est = IdealDD().estimate(constant_run(wl, wr, pose0=pose0))
    v, w = r * (wl + wr) / 2, r * (wr - wl) / b
    t = est.t
    yaw = pose0[2] + w * t
    cx, cy = pose0[0] - v / w * np.sin(pose0[2]), pose0[1] + v / w * np.cos(pose0[2])
    np.testing.assert_allclose(est["x"], cx + v / w * np.sin(yaw), atol=1e-12)
    np.testing.assert_allclose(est["y"], cy - v / w * np.cos(yaw), atol=1e-12)
    np.testing.assert_allclose(est["yaw"], yaw, atol=1e-12)
    np.testing.assert_allclose(est["chi"], 1.0)


def test_initial_pose_from_first_reference_else_origin():
    run = constant_run(1.0, 1.0, pose0=(3.0, 4.0, -1.0))
    assert initial_pose(run) == (3.0, 4.0, -1.0)
    assert initial_pose(constant_run(1.0, 1.0, with_ref=False)) == (0.0, 0.0, 0.0)
    # a row with only some reference channels is not a pose: the first complete row is used
    df = run.data.copy()
    df.loc[0, "ref_yaw"] = np.nan
    df.loc[5, ["ref_x", "ref_y", "ref_yaw"]] = [7.0, 8.0, 0.5]
    assert initial_pose(type(run)(df, run.meta)) == (7.0, 8.0, 0.5)


def test_nan_encoder_rows_are_dropped_not_integrated():
    rng = np.random.default_rng(0)
    run = constant_run(1.0, 1.5)
    wl = 1.0 + 0.1 * rng.standard_normal(run.t.size)
    df = run.data.assign(enc_wl=wl)
    holes = np.zeros(run.t.size, bool)
    holes[[10, 11, 50, 300]] = True
    with_nan = type(run)(df.assign(enc_wl=np.where(holes, np.nan, wl)), run.meta)
    without_rows = type(run)(df[~holes].reset_index(drop=True), run.meta)
    t, left, _ = encoder_speeds(with_nan)
    assert t.size == run.t.size - 4 and np.all(np.isfinite(left))
    a, b = IdealDD().estimate(with_nan), IdealDD().estimate(without_rows)
    np.testing.assert_array_equal(a.data.to_numpy(), b.data.to_numpy())


def test_bad_input_errors_name_run_and_channel():
    run = constant_run(1.0, 1.0)
    no_right = type(run)(run.data.drop(columns="enc_wr"), run.meta)
    with pytest.raises(RunError, match="enc_wr"):
        IdealDD().estimate(no_right)
    all_nan = type(run)(run.data.assign(enc_wl=np.nan), run.meta)
    with pytest.raises(RunError, match="enc_wl"):
        IdealDD().estimate(all_nan)
    no_track = type(run)(run.data, {"platform": {"wheel_radius": 0.1}, "run_id": "r1"})
    with pytest.raises(RunError, match=r"r1.*meta\.platform\.track"):
        IdealDD().estimate(no_track)
    back = run.data.copy()
    back.loc[5, "t"] = back.loc[4, "t"]
    with pytest.raises(RunError, match="increase"):
        encoder_speeds(type(run)(back, run.meta))
    with pytest.raises(RunError, match="ref_x"):
        reference_poses(constant_run(1.0, 1.0, with_ref=False))


def test_encoder_readings_are_integrated_over_the_period_they_measure():
    """A reading is the count difference over the period ending at its stamp (bench.sim.sensors.encoders).  Ramp
    theta = a t^2 / 2 on both wheels: the straight-line travel at every encoder instant is r theta(t) exactly
    (closed form), and through the testbed's own encoder model within one count.  Holding each reading over the
    NEXT period (the earlier convention) gave r theta(t) - r a t dt: one sample late."""
    from bench.sim.sensors import encoders
    from bench.spec import load_scenario

    a, rate = 2.0, 100.0
    t = np.arange(201) / rate
    theta = 0.5 * a * t**2
    diff = np.diff(theta, prepend=theta[0]) * rate  # the period before the log: no motion
    run = from_arrays({"t": t, "enc_wl": diff, "enc_wr": diff}, {"platform": dict(PLATFORM), "run_id": "ramp"})
    est = IdealDD().estimate(run)
    np.testing.assert_allclose(est["x"], PLATFORM["wheel_radius"] * theta, rtol=0, atol=1e-12)
    _, wl, _ = encoder_speeds(run)
    np.testing.assert_allclose(held_integral(t, wl, 0.0, t[-1]), theta[-1], rtol=0, atol=1e-12)

    scn = load_scenario("straight_0p2_vinyl")
    q = 2.0 * np.pi / scn.platform.sensors.encoder.counts_per_rev
    el, er = encoders(t, theta, theta, scn, np.random.default_rng(3))
    run = from_arrays({"t": t, "enc_wl": el, "enc_wr": er}, {"platform": dict(PLATFORM), "run_id": "ramp_q"})
    _, wl, wr = encoder_speeds(run)
    scale = 1.0 + np.array([scn.platform.sensors.encoder.scale_error_l, scn.platform.sensors.encoder.scale_error_r])
    travel = np.array([held_integral(t, w, 0.0, t[-1]) for w in (wl, wr)]) / scale
    assert np.all(np.abs(travel - theta[-1]) <= q)  # one count; the late hold is short by a t dt = 0.04 rad


def test_held_integral_partial_intervals():
    t = np.array([0.0, 1.0, 2.0, 4.0])
    v = np.array([1.0, -2.0, 3.0, 10.0])
    # [0.5, 3.0]: 0.5*1 + 1*(-2) + 1*3
    assert held_integral(t, v, 0.5, 3.0) == pytest.approx(1.5)
    # past the last sample the last value is held; vectorised over bounds
    np.testing.assert_allclose(held_integral(t, v, [0.0, 3.5], [4.0, 5.0]), [1 - 2 + 6, 1.5 + 10])


def test_registry_withholds_truth_and_refuses_the_calibration_run():
    calib = constant_run(1.0, 2.0)
    calib = type(calib)(calib.data.assign(truth_x=0.0), calib.meta)
    other = constant_run(2.0, 1.0)
    m = registry.calibrate(IdealDD(), [calib])
    with pytest.raises(registry.CalibrationLeak):
        registry.estimate(m, calib)
    est = registry.estimate(m, other)
    assert est.method == "baseline.ideal_dd" and est.t.size == other.t.size
    assert not registry.calibrated_on(IdealDD())  # the default instance is untouched
