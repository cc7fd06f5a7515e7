"""bench.real.stall: the motion ratio against closed forms, and the stall summary against hand arithmetic."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import spearmanr

from bench.real.stall import BLOCK, SETTLE, STALL_RATIO, motion_ratio, space_series, stall_summary

R, B, DT, T = 0.165, 0.55, 0.05, 6.0


def _series(wl, wr, v, wz, ref=True, t=None):
    """Channels of a planar body with wheel speeds wl(t), wr(t), forward speed v(t) and yaw rate wz(t), integrated
    exactly on a fine grid and sampled at DT."""
    t = np.arange(0.0, T, DT) if t is None else t
    fine = np.linspace(0.0, T, 60001)
    yaw = np.concatenate([[0.0], np.cumsum(0.5 * (wz(fine[1:]) + wz(fine[:-1])) * np.diff(fine))])
    vx, vy = v(fine) * np.cos(yaw), v(fine) * np.sin(yaw)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * np.diff(fine))])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * np.diff(fine))])
    out = {"enc_wl": (t, wl(t)), "enc_wr": (t, wr(t)), "imu_gz": (t, wz(t))}
    if ref:
        out["ref_x"], out["ref_y"] = (t, np.interp(t, fine, x)), (t, np.interp(t, fine, y))
    return out


def const(c):
    return lambda t: np.full(np.shape(t), float(c))


def test_straight_line_ratio_is_one_minus_the_slip():
    w = 4.0
    for slip in (0.0, 0.1, 0.5):
        s = _series(const(w), const(w), const((1 - slip) * R * w), const(0.0))
        assert motion_ratio(s, R, B) == pytest.approx(1.0 - slip, rel=1e-4)


def test_spin_in_place_ratio_is_one_over_chi():
    """Wang 2015 eq. (25): w_z = r (w_r - w_l) / (chi B); no translation."""
    w = 3.0
    for chi in (1.0, 2.5):
        s = _series(const(-w), const(w), const(0.0), const(R * 2 * w / (chi * B)))
        assert motion_ratio(s, R, B) == pytest.approx(1.0 / chi, rel=1e-3)


def test_turn_ratio_closed_form():
    """A turn at chi: v = r (wl + wr) / 2, w_z = r (wr - wl) / (chi B); the ratio is
    hypot(v, B/2 w_z) / hypot(v, B/2 r (wr - wl) / B) (a circle: the chord over a block is 2 R sin(w_z dt / 2),
    which the block's straight displacement takes, a relative error ~ (w_z BLOCK)^2 / 24)."""
    wl, wr, chi = 1.0, 5.0, 2.5
    v, wz = R * (wl + wr) / 2, R * (wr - wl) / (chi * B)
    expect = math.hypot(v, B / 2 * wz) / math.hypot(v, B / 2 * R * (wr - wl) / B)
    chord = math.sin(wz * BLOCK / 2) / (wz * BLOCK / 2)  # chord / arc over one block
    expect_chord = math.hypot(v * chord, B / 2 * wz) / math.hypot(v, B / 2 * R * (wr - wl) / B)
    got = motion_ratio(_series(const(wl), const(wr), const(v), const(wz)), R, B)
    assert got == pytest.approx(expect_chord, rel=1e-4)
    assert got == pytest.approx(expect, rel=0.01)


def test_a_stalled_body_is_near_zero_and_below_the_threshold_with_icp_noise():
    """Wheels at 6 / -0.3 rad/s, the body still: the ratio is the reference noise's displacement over a block,
    E|d| = sigma sqrt(pi) for independent 2-D Gaussian positions (Rayleigh mean of their difference)."""
    rng = np.random.default_rng(3)
    s = _series(const(-0.3), const(6.0), const(0.0), const(0.0))
    assert motion_ratio(s, R, B) == pytest.approx(0.0, abs=1e-12)
    sigma = 0.003
    t = s["ref_x"][0]
    noisy = {**s, "ref_x": (t, s["ref_x"][1] + rng.normal(0, sigma, t.size)),
             "ref_y": (t, s["ref_y"][1] + rng.normal(0, sigma, t.size))}
    ideal = math.hypot(R * (6.0 - 0.3) / 2, B / 2 * R * 6.3 / B)
    expect = sigma * math.sqrt(math.pi) / BLOCK / ideal
    got = motion_ratio(noisy, R, B)
    assert got < STALL_RATIO / 5
    assert got == pytest.approx(expect, rel=0.5)


def test_the_first_settle_seconds_are_left_out():
    """Stalled for the first SETTLE s, rolling freely after: ratio 1; stalled after: ratio 0."""
    w = 4.0
    v_late = lambda t: np.where(np.asarray(t) >= SETTLE, R * w, 0.0)  # noqa: E731
    v_early = lambda t: np.where(np.asarray(t) < SETTLE, R * w, 0.0)  # noqa: E731
    assert motion_ratio(_series(const(w), const(w), v_late, const(0.0)), R, B) == pytest.approx(1.0, rel=1e-3)
    assert motion_ratio(_series(const(w), const(w), v_early, const(0.0)), R, B) == pytest.approx(0.0, abs=1e-3)


def test_without_reference_only_the_yaw_counts_and_missing_channels_give_nan():
    w, chi = 3.0, 2.0
    s = _series(const(1.0), const(1.0 + 2 * w), const(0.0), const(R * 2 * w / (chi * B)), ref=False)
    assert motion_ratio(s, R, B) == pytest.approx(1.0 / chi, rel=1e-3)
    assert math.isnan(motion_ratio({k: v for k, v in s.items() if k != "imu_gz"}, R, B))
    assert math.isnan(motion_ratio(_series(const(0.0), const(0.0), const(0.0), const(0.0)), R, B))
    short = _series(const(1.0), const(2.0), const(0.1), const(0.1), t=np.arange(0.0, SETTLE + 0.2, DT))
    assert math.isnan(motion_ratio(short, R, B))
    # a reference channel with no finite sample counts as absent: the yaw alone, as without it
    t = s["enc_wl"][0]
    blind = {**s, "ref_x": (t, np.full(t.size, np.nan)), "ref_y": (t, np.full(t.size, np.nan))}
    assert motion_ratio(blind, R, B) == pytest.approx(1.0 / chi, rel=1e-3)


def test_space_series_gives_the_model_as_measured_minus_raw():
    class Space:
        channels = ("enc_wl", "imu_gz")
        t = {"enc_wl": np.arange(3.0), "imu_gz": np.arange(3.0)}
        meas = {"enc_wl": np.array([1.0, 2.0, 3.0]), "imu_gz": np.array([0.5, 0.5, 0.5])}
    raw = {"enc_wl": np.array([0.5, 0.0, -1.0]), "imu_gz": np.zeros(3)}
    assert space_series(Space())["enc_wl"][1].tolist() == [1.0, 2.0, 3.0]
    assert space_series(Space(), raw)["enc_wl"][1].tolist() == [0.5, 2.0, 4.0]
    assert set(space_series(Space())) == {"enc_wl", "imu_gz"}


def test_stall_summary_hand_arithmetic():
    out = stall_summary([3, 7, 9, 11], measured=[0.1, 0.5, 0.05, 0.6], model=[0.4, 0.5, 0.6, 0.6],
                        cost_nominal=[10.0, 20.0, 30.0, 40.0], cost_final=[8.0, 2.0, 10.0, 4.0], threshold=0.2)
    assert out["steps"] == [3, 9]
    assert out["measured_median"] == pytest.approx(0.075)
    assert out["model_median"] == pytest.approx(0.5)
    assert out["share_of_final_cost"] == pytest.approx(18.0 / 24.0)
    assert out["others_final_over_nominal"] == pytest.approx(3.0 / 30.0)
    assert out["n_others"] == 2
    assert out["model_stalls"] == 0 and out["n_unmeasured"] == 0
    none = stall_summary([1], [0.7], [0.7], [1.0], [0.5])
    assert none["steps"] == [] and math.isnan(none["measured_median"]) and none["others_final_over_nominal"] == 0.5
    # an unmeasured step (NaN) is in neither group; a model that stalls too is counted
    mixed = stall_summary([1, 2, 3], [0.1, math.nan, 0.5], [0.05, 0.5, 0.5], [10.0, 100.0, 20.0], [5.0, 50.0, 2.0])
    assert mixed["steps"] == [1] and mixed["n_others"] == 1 and mixed["n_unmeasured"] == 1
    assert mixed["model_stalls"] == 1 and mixed["others_final_over_nominal"] == pytest.approx(0.1)


def _stalls(**kw):
    base = {"threshold": 0.2, "steps": [52], "measured_median": 0.067, "model_median": 0.6, "model_stalls": 0,
            "n_unmeasured": 0, "share_of_final_cost": 0.25, "others_final_over_nominal": 0.0982, "n_others": 9,
            "calibration_steps": [], "n_calibration": 11}
    return {**base, **kw}


def test_the_report_paragraph_names_steps_and_words_the_cause_as_unmeasured():
    from bench.real.gap_report import _stalls_text

    one = _stalls_text(_stalls(), 10)
    assert "Held out: 1 of 10 (step 52; robot 7 % median, the final model 60 %)" in one
    assert "stalls on none of them" in one and "25 % of the held-out final cost" in one
    assert "other 9 steps the final model's mean cost is 9.8 % of the nominal's" in one
    assert "Calibration half: 0 of 11. " in one and "What stops the robot is not measured" in one
    both = _stalls_text(_stalls(steps=[3, 52], model_stalls=2, model_median=0.1, calibration_steps=[17]), 10)
    assert "steps 3, 52;" in both and "stalls on all of them" in both and "(step 17)" in both
    assert "not measured (a hard turn" not in both
    nan = _stalls_text(_stalls(model_median=math.nan, n_unmeasured=2), 10)
    assert "the final model not measured" in nan and "2 held-out step(s) without a measured ratio" in nan
    assert "nan" not in nan.lower().replace("not measured", "")
    quiet = _stalls_text(_stalls(steps=[]), 10)
    assert "None of the 10 held-out steps stalls." in quiet
    spin = _stalls_text(_stalls(spin_like={"held_out": {"n": 5, "stalled": 1}, "calibration": {"n": 4, "stalled": 0}}),
                        10)
    assert "1 of 5 stall held out and 0 of 4 in the calibration half" in spin and "spin" not in one
    none_held = _stalls_text(_stalls(steps=[], calibration_steps=[17], spin_like={"held_out": {"n": 5, "stalled": 0},
                                                                                  "calibration": {"n": 4, "stalled": 1}}), 10)
    assert "None of the 10 held-out steps stalls." in none_held and "0 of 5 stall held out and 1 of 4" in none_held


def test_spin_like_steps_by_hand():
    """Half-sum (w_l + w_r)/2 and half-difference (w_r - w_l)/2 of the step's mean command: a spin when the
    half-difference exceeds SPIN_MIN and the half-sum is under SPIN_SHARE of it; a step's windows are averaged."""
    from bench.real.stall import SPIN_MIN, SPIN_SHARE, spin_like_steps

    assert (SPIN_SHARE, SPIN_MIN) == (0.5, 3.0)
    # per window (w_l, w_r): step 1 (-4, 4) spin; 2 (2, 6) half-sum 4 > 0.5 * 2; 3 (-2, 2) half-difference 2 < 3;
    # 4 mean of (-6, 2) and (-4, 4) = (-5, 3): half-sum -1, half-difference 4: spin; 5 (1, 8): 4.5 > 0.5 * 3.5
    cmd = np.array([[-4, 4], [2, 6], [-2, 2], [-6, 2], [-4, 4], [1, 8]], float)
    table = {"cmd_wl": np.repeat(cmd[:, :1], 3, axis=1), "cmd_wr": np.repeat(cmd[:, 1:], 3, axis=1)}
    w = type("W", (), {"calib_step": np.array([1, 2, 3, 4, 4, 5]), "__getitem__": lambda self, c: table[c]})()
    assert spin_like_steps(w, [1, 2, 3, 4, 5, 9]) == [1, 4]


HUSKY = Path(__file__).resolve().parents[2] / "shared" / "data" / "drive_husky" / "husky_windows.parquet"


@pytest.mark.skipif(not HUSKY.exists(), reason="real Husky data not present")
def test_husky_stalls_agree_with_drive_own_body_velocities():
    """A second measure: DRIVE's own per-window ICP body velocities (icp_vx, icp_omega, computed by the DRIVE
    authors) over the steady windows, against the ideal drive of the windows' encoders.  No step either measure
    puts clearly below the threshold is clearly above it by the other, and the two rank the steps alike."""
    from bench.real.drive import import_drive_windows
    from bench.real.gap import block_run
    from bench.real.stall import run_series
    from bench.real.windows import valid_windows
    from bench.spec import load_scenario, to_dict
    w = import_drive_windows(HUSKY)
    w = w.subset(valid_windows(w))
    plat = load_scenario("real_husky_asphalt").platform
    pd = to_dict(plat)
    ours, drive = {}, {}
    for s in sorted(set(int(x) for x in w.calib_step)):
        k = (w.calib_step == s) & w.steady
        if not k.any():
            continue
        wl, wr = w["enc_wl"][k].mean(axis=1), w["enc_wr"][k].mean(axis=1)
        ideal = np.hypot(plat.wheel_radius * (wl + wr) / 2, plat.wheel_radius * (wr - wl) / 2)
        moved = np.hypot(w.body_velocity["icp_vx"][k], plat.track / 2 * w.body_velocity["icp_omega"][k])
        drive[s] = float(moved.sum() / ideal.sum())
        ours[s] = motion_ratio(run_series(block_run(w, [s], pd)), plat.wheel_radius, plat.track)
    low_ours = {s for s, v in ours.items() if v < STALL_RATIO * 0.75}
    low_drive = {s for s, v in drive.items() if v < STALL_RATIO * 0.75}
    high_ours = {s for s, v in ours.items() if v > STALL_RATIO * 1.5}
    high_drive = {s for s, v in drive.items() if v > STALL_RATIO * 1.5}
    assert len(low_ours) >= 3
    assert not (low_ours & high_drive) and not (low_drive & high_ours)
    # DRIVE's window velocities have outliers (ratios of 1.3-3.1, more than the wheels imply, on 8 steps; icp_vx
    # -2.49 m/s in a window of step 111): ranks and the median difference, not a Pearson correlation (0.67)
    a, b = np.array([ours[s] for s in drive]), np.array([drive[s] for s in drive])
    assert spearmanr(a, b)[0] > 0.75  # 0.85 measured
    assert np.median(np.abs(a - b)) < 0.1  # 0.058 measured
