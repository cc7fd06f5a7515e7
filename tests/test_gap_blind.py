"""Blind tests of the gap workflow for the defects reported from blind testing (one class each).

Every test here failed before its fix.  Data: the testbed with the ``gap_blind_*`` scenarios (other
platforms, terrains, commands and sensors than the development scenarios the selection thresholds
were chosen on, ``bench/gap/dev.py``, and than ``tests/test_gap_hidden.py``), seeds >= 300 and
magnitudes of their own.

1. Start from rest with a step command or a hard launch: the replay started moving at the speed of
   the first encoder samples (a torque gap of ~0.3 N m in the first 0.5 s, "unexplained").
2. Quantised encoders at a constant speed: the noise scale collapsed to its floor (false excess).
3. A 5 Hz DGPS reference: the pose alignment fitted a rotation on 6 samples (false pose gap); held
   (zero-order-hold) reference samples counted as samples.
4. Significance per sample: a small gyro bias over 5,000 samples (~40 sigma in total) was "no
   significant missing effect".
5. Relative-only "unexplained" test: a wrong pair of effects explaining 89 % of a large gap but
   leaving ~80 x the noise was named; no detection limit was reported with "no significant".
6. A run that starts in a turn (issue 32, the real Husky's held-out steps): the replay started the model from
   the forward speed only, going straight, so a heading error that stays for the whole run (the reference yaw,
   noise 0.003 rad here) was blamed on an effect.
7. Float wheel speeds held by the logger between reports (the DRIVE Husky table: 10 Hz wheels in 20 Hz rows, every
   other row a repeat): the repeats counted as samples, each compared with the model's mean wheel speed since the
   previous row.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from bench.gap import find_gap
from bench.gap.model import replay_scenario
from bench.spec import load_scenario

STEP, LAUNCH, CRUISE, DGPS, PATROL, TURNS = ("gap_blind_step", "gap_blind_launch", "gap_blind_cruise",
                                             "gap_blind_dgps", "gap_blind_patrol", "gap_blind_turns")
NONE = "no significant missing effect"


def _ov(hidden: dict) -> dict:
    return {k.replace(".", "__"): v for k, v in hidden.items()}


# ------------------------------------------------------------------ 1. start from rest
@pytest.mark.parametrize("scenario,seed", [(STEP, 302), (LAUNCH, 312)])
def test_start_from_rest_is_replayed_from_rest_and_blames_nothing(sim, scenario, seed):
    """A step command at t = 0 (no ramp) and a 2.5 m/s^2 launch, both from rest, no hidden effect: the
    replay starts at rest (the first encoder samples, mean speeds after t0, read 0.03-0.15 m/s), the drive
    torques replay exactly (they replayed 22-34 noise scales off) and nothing is blamed."""
    measured = sim(scenario, seed)
    _, init = replay_scenario(measured.without_truth(), load_scenario(scenario))
    assert init.speed == 0.0
    res = find_gap(measured, scenario)
    assert res.gap_before["tau_l"]["rms"] < 0.01 and res.gap_before["tau_r"]["rms"] < 0.01, res.gap_before["tau_l"]
    assert res.verdict == NONE and res.effects == [] and res.partial == [], res.verdict


def test_a_moving_start_stays_moving(sim):
    """The guard the fix must not break: a run that starts moving (Yu's ramp, 0.49 m/s at t = 0) is replayed
    moving, at the encoders' speed."""
    measured = sim("ramp_wood_15", 300).without_truth()
    _, init = replay_scenario(measured, load_scenario("ramp_wood_15"))
    assert init.speed == pytest.approx(0.49, rel=0.1)


@pytest.mark.slow
def test_payload_hidden_behind_a_step_start_is_named(sim):
    """A hidden payload (7 kg) in the step-from-rest scenario: named and fitted, not confused with the start."""
    res = find_gap(sim(STEP, 303, **_ov({"platform.payload": 7.0})), STEP)
    assert res.verdict_kind == "missing_effect" and res.named[0] == "payload", res.verdict
    assert res.effects[0]["parameters"]["payload"] == pytest.approx(7.0, rel=0.2)


# ------------------------------------------------------------------ 2. quantised encoders
def test_quantised_encoders_at_constant_speed_show_no_false_excess(sim):
    """9 s at 40.05 encoder counts per sample: the count difference is the same on most samples (the MAD of
    second differences is 0), yet the residual against the noise-free model is the quantisation error,
    sqrt(f (1 - f)) q = 0.22 q.  The noise scale is at least the quantisation's (q / 2 for a count difference),
    so the encoders show no excess (they showed 3.7 x the floor) and nothing is blamed."""
    scn = load_scenario(CRUISE)
    enc = scn.platform.sensors.encoder
    q = 2 * math.pi / enc.counts_per_rev * enc.rate_hz
    res = find_gap(sim(CRUISE, 322), CRUISE)
    for c in ("enc_wl", "enc_wr"):
        assert res.gap_before[c]["noise"] >= 0.5 * q * (1 - 1e-9), res.gap_before[c]
        assert res.gap_before[c]["normalised_rms"] <= 1.0, res.gap_before[c]
    assert res.verdict == NONE, res.verdict


def test_float_wheel_speeds_held_by_the_logger_are_not_samples(sim):
    """Float wheel speeds (2^30 counts per revolution: not quantised) written again on every row of the run
    (forward-filled, as a logger that samples the last report at every IMU and reference row): the repeats are
    left out, so the residual space has the sensor's own samples (less the 3 of 1001 that equal the one before
    at constant speed: indistinguishable from a repeat), the same noise scales, and the workflow says what it
    says on the original run (nothing missing).  Before, each repeat was compared with the model's
    mean wheel speed since the previous row: the encoders showed 2.1 x their noise and the workflow blamed
    encoder_latency ("unexplained residual")."""
    from bench.gap.regimes import regimes_for
    from bench.gap.residuals import build_space

    over = {"platform__sensors__encoder__counts_per_rev": 2**30}
    run = sim(CRUISE, 325, **over)
    data = run.data.copy()
    data[["enc_wl", "enc_wr"]] = data[["enc_wl", "enc_wr"]].ffill()
    held = type(run)(data, dict(run.meta, run_id="held-encoders"))
    assert np.isfinite(held["enc_wl"]).sum() > 2 * np.isfinite(run["enc_wl"]).sum()  # the logger's extra rows
    scn = load_scenario(CRUISE)
    a, b = (build_space(r.without_truth(), regimes_for(scn.platform)) for r in (run, held))
    for c in ("enc_wl", "enc_wr"):
        extra = ~np.isin(b.t[c], a.t[c])  # kept beyond the sensor's samples: only zeros (a wheel at rest reads 0
        assert np.all(b.meas[c][extra] == 0.0) and extra.sum() <= 3  # again: samples) at the start
        lost = np.flatnonzero(~np.isin(a.t[c], b.t[c]))  # the sensor's own samples left out: only exact repeats of
        assert lost.size <= 0.01 * a.t[c].size and np.all(a.meas[c][lost] == a.meas[c][lost - 1])  # the one before
        assert b.sigma_hat[c] == pytest.approx(a.sigma_hat[c], rel=0.05)
    res = find_gap(held, CRUISE)
    assert res.verdict == NONE, res.verdict
    for c in ("enc_wl", "enc_wr"):
        assert res.gap_before[c]["normalised_rms"] <= 1.5, res.gap_before[c]


def test_a_replay_starts_from_the_sensors_own_wheel_speeds_not_the_loggers_repeats(sim):
    """A run that starts in a turn (TURN_START, below) with float wheel speeds forward-filled onto every row: the
    replay's initial state (speed, yaw rate, skid ratio from the first wheel-speed samples) and the encoder period
    of its grid are those of the original run, exactly.  Before, the initial speeds averaged the first rows with
    their repeats (one sample counted twice) and the period was the logger's row interval, not the sensor's."""
    from bench.gap.model import measured_grid

    sim_run = sim(TURNS, 353, platform__sensors__encoder__counts_per_rev=2**30, **TURN_START)
    data = sim_run.data.copy()
    data.loc[data.index[0], ["enc_wl", "enc_wr"]] = np.nan  # the testbed's first sample, a difference with nothing
    run = type(sim_run)(data.copy(), dict(sim_run.meta))  # before it (0): a driver in motion reports its speed
    data[["enc_wl", "enc_wr"]] = data[["enc_wl", "enc_wr"]].ffill()
    held = type(run)(data, dict(run.meta, run_id="held-encoders"))
    scn = load_scenario(TURNS)
    (_, a), (_, b) = (replay_scenario(r.without_truth(), scn) for r in (run, held))
    assert a.speed > 0.3 and a.yaw_rate > 0.1  # a moving, turning start: the first samples decide it
    assert b == a
    assert measured_grid(held, {}, b, scn).enc_period == measured_grid(run, {}, a, scn).enc_period


def test_quantised_wheel_speeds_that_repeat_are_samples(sim):
    """The testbed's quantised encoders repeat a count difference now and then (the Husky at 30 Hz, whose integer-
    microsecond sample intervals alternate 33333 / 33334 us, so the speeds are off a lattice, but the count
    differences, speed x interval, are on it; a constant-speed cruise at 100 Hz): none of those rows is a logger's
    repeat.  The first version, checking the speeds for a lattice and taking any repeat, dropped one real sample
    of the launch."""
    from bench.gap.residuals import held_encoder_rows

    for name, seed in ((LAUNCH, 312), (CRUISE, 322), (STEP, 302)):
        assert not held_encoder_rows(sim(name, seed)).any(), name


def test_quantisation_step_of_a_lattice_and_of_a_float_signal():
    """Independent expectation: count differences at a constant 40.3 counts per sample (a step q, rounding
    noise of n q / T) give q back; white noise on floats gives 0 (not quantised); the noise scale of the
    lattice is q / 2 >= its actual residual RMS sqrt(0.3 x 0.7) q."""
    from bench.gap.residuals import quantisation_noise, quantisation_step

    q = 2 * math.pi / 8192 * 100.0
    counts = np.floor(40.3 * np.arange(2000) + 0.37)
    v = np.diff(counts) * (2 * math.pi / 8192) / 0.01
    assert quantisation_step(v) == pytest.approx(q, rel=1e-9)
    assert quantisation_noise("enc_wl", v) == pytest.approx(q / 2, rel=1e-9)
    assert quantisation_noise("enc_wl", v) >= np.std(v - 40.3 * q)
    rng = np.random.default_rng(0)
    assert quantisation_step(rng.normal(1.0, 0.01, 2000)) == 0.0


# ------------------------------------------------------------------ 3. low-rate reference
@pytest.mark.parametrize("seed", [343, 345])
def test_dgps_at_5hz_leaves_no_false_pose_gap(sim, seed):
    """DUBHE with its 5 Hz DGPS (1 cm, 0.005 rad), 24 s and ~45 m: a rotation fitted on the 6 samples of the
    first second turned the model trajectory by its error (2-4 mrad: pose gaps of 2-4.5 noise scales,
    "unexplained residual").  Now the alignment uses >= 20 samples and fits the rotation only where they
    determine it."""
    res = find_gap(sim(DGPS, seed), DGPS)
    for c in ("ref_x", "ref_y"):
        assert res.gap_before[c]["normalised_rms"] < 1.3, (c, res.gap_before[c])
    assert res.verdict == NONE, res.verdict


def test_held_reference_samples_are_not_samples(sim):
    """The same 5 Hz DGPS logged at the 100 Hz rows with each pose held until the next (as the DRIVE table
    holds its lidar poses): only the reported poses count, so the result is the one of the unheld log
    (before, the held staircase's noise scale collapsed to the floor: a false gap of ~5 noise scales)."""
    from bench.gap.regimes import regimes_for
    from bench.gap.residuals import build_space

    run = sim(DGPS, 344)
    d = run.data.copy()
    for c in ("ref_x", "ref_y", "ref_yaw"):
        d[c] = d[c].ffill()
    held = type(run)(d, dict(run.meta, run_id="held-dgps"))
    scn = load_scenario(DGPS)
    a = build_space(held.without_truth(), regimes_for(scn.platform))
    b = build_space(run.without_truth(), regimes_for(scn.platform))
    assert a.meas["ref_x"].size == b.meas["ref_x"].size == int(round(scn.duration * 5)) + 1
    res_h, res = find_gap(held, DGPS), find_gap(run, DGPS)
    assert res_h.verdict == res.verdict == NONE, res_h.verdict
    assert res_h.gap_before["ref_y"]["normalised_rms"] == pytest.approx(res.gap_before["ref_y"]["normalised_rms"],
                                                                         rel=1e-9)


@pytest.mark.slow
def test_wheel_radius_under_a_5hz_dgps_is_named(sim):
    """A right tyre 2.5 % small under the 5 Hz DGPS: named, fitted within 20 % of its change, and the pose
    gap after it is the DGPS noise (the rotation fitted on 6 samples left ~2 noise scales)."""
    res = find_gap(sim(DGPS, 346, **_ov({"platform.wheel_radius_scale_r": 0.975})), DGPS)
    assert res.verdict_kind == "missing_effect" and res.named[0] == "wheel_radius", res.verdict
    assert res.effects[0]["parameters"]["radius_scale_r"] == pytest.approx(0.975, abs=0.2 * 0.025)
    for c in ("ref_x", "ref_y"):
        assert res.gap_after[c]["normalised_rms"] < 1.3, (c, res.gap_after[c])


# ------------------------------------------------------------------ 4. significance per log
def test_small_gyro_bias_over_a_long_log_is_named(sim):
    """A gyro bias of 0.0011 rad/s (0.55 x the gyro noise per sample, ~39 sigma over the 5,000 samples of
    40 s) gains 0.06 J_noise, below the per-sample threshold: it was "no significant missing effect".  The
    whole-log test names it, fitted within 3 standard errors, and the fit is at the noise floor."""
    b = 0.0011
    res = find_gap(sim(PATROL, 342, **_ov({"platform.sensors.imu.gyro_bias_z": b})), PATROL)
    assert res.verdict_kind == "missing_effect" and res.named == ["gyro_bias"], res.verdict
    e = res.effects[0]
    assert abs(e["parameters"]["gyro_bias_z"] - b) <= 3 * e["uncertainty"]["gyro_bias_z"] < 0.3 * b
    assert res.fit["verdict"] == "at the noise floor", res.fit


@pytest.mark.slow
def test_small_encoder_scale_over_a_long_log_is_named(sim):
    """An encoder scale error of 0.8 % on the left (below the 1.2 % per-sample detection limit of the
    development table) over the 40 s patrol: named."""
    res = find_gap(sim(PATROL, 344, **_ov({"platform.sensors.encoder.scale_error_l": 0.008})), PATROL)
    assert res.named[:1] == ["encoder_scale"], res.verdict
    assert res.effects[0]["parameters"]["scale_error_l"] == pytest.approx(0.008, abs=0.2 * 0.008)


# ------------------------------------------------------------------ 5. absolute goodness of fit, detection limits
def _check_far_above(res, explained: float, left: float, n_partial: tuple[int, ...] = (2,)):
    assert res.verdict_kind == "unexplained_residual" and res.effects == [], res.verdict
    assert len(res.partial) in n_partial, res.verdict
    assert res.cost["explained_fraction"] > explained  # the relative test alone let it be named
    assert res.fit["verdict"] == "far above the noise floor" and res.fit["final_cv_over_noise"] > left, res.fit
    assert "noise floor" in res.verdict


def test_wrong_pair_far_above_the_noise_is_unexplained(sim):
    """Lateral shear modulus 3 x the longitudinal one (anisotropic tyres: no catalogue effect) in the turns
    scenario: the best pair (cg offset + wheel radii) explained 89 % of a gap of ~740 J_noise and left ~80 x
    the noise.  It was named; then it was an unexplained residual with the pair as partial candidates.  Since the
    catalogue has lateral friction anisotropy (mu_lat_ratio, a near miss for a lateral shear modulus), that one
    effect explains 96 % and leaves 30 x the noise, and it is still an unexplained residual, not a name."""
    res = find_gap(sim(TURNS, 352, **_ov({"terrain.shear_modulus_lat_ratio": 3.0})), TURNS)
    _check_far_above(res, 0.85, 20.0, n_partial=(1, 2))


@pytest.mark.slow
def test_lateral_friction_is_named_not_a_wrong_pair(sim):
    """Lateral friction 0.6 x in the turns scenario: before the catalogue had lateral friction anisotropy, shear
    displacement + cg offset explained 97.6 % and left ~20 x the noise (named, then an unexplained residual);
    now the effect itself is named and fitted within 20 % of its change."""
    res = find_gap(sim(TURNS, 352, **_ov({"terrain.mu_lat_ratio": 0.6})), TURNS)
    nominal = load_scenario(TURNS).terrain.mu_lat_ratio
    assert res.verdict_kind == "missing_effect" and res.named[0] == "lateral_friction", res.verdict
    assert res.effects[0]["parameters"]["mu_lat_ratio"] == pytest.approx(0.6, abs=0.2 * abs(0.6 - nominal))


def test_detection_limit_is_reported_and_is_what_the_data_detect(sim):
    """Nothing hidden: every applicable effect gets a detection limit.  The gyro bias's is the closed form of
    the whole-log test for white gyro noise, sqrt(chi2_1(1e-6)) sigma / sqrt(N) (within 15 %); a bias at twice
    it is then named, one at half of it is not."""
    from scipy.stats import chi2

    res = find_gap(sim(PATROL, 343), PATROL)
    assert res.verdict == NONE
    det = res.detection_limits
    assert {"gyro_bias", "encoder_scale", "payload", "wheel_radius"} <= set(det)
    lim = det["gyro_bias"]["limits"]["gyro_bias_z"]
    t, _ = sim(PATROL, 343).samples("imu_gz")
    sigma = res.gap_before["imu_gz"]["sigma"]
    closed = math.sqrt(chi2.isf(1e-6, 1)) * sigma / math.sqrt(t.size)
    assert lim["change"] == pytest.approx(closed, rel=0.15) and lim["how"] == "whole-log chi2"
    assert all(v["change"] > 0 for d in det.values() if d["limits"] for v in d["limits"].values())
    big = find_gap(sim(PATROL, 343, **_ov({"platform.sensors.imu.gyro_bias_z": 2.0 * lim["change"]})), PATROL)
    small = find_gap(sim(PATROL, 343, **_ov({"platform.sensors.imu.gyro_bias_z": 0.5 * lim["change"]})), PATROL)
    assert big.named == ["gyro_bias"], big.verdict
    assert small.verdict == NONE, small.verdict


# ------------------------------------------------------------------ null cases
NULL_SCENARIOS = (LAUNCH, DGPS, PATROL)


@pytest.mark.slow
def test_null_cases_at_most_one_false_name_over_twenty_seeds(sim):
    """No hidden effect, 20 seeds on each of 3 nominal scenarios that no threshold was chosen on: at most one
    run names an effect, and at most one says anything but "no significant missing effect" (before the fixes
    33 of the 60 were "unexplained residual": every hard launch, 13 of the DGPS runs)."""
    false, verdicts = 0, []
    for scenario in NULL_SCENARIOS:
        for seed in range(500, 520):
            res = find_gap(sim(scenario, seed), scenario)
            false += bool(res.effects)
            verdicts.append((scenario, seed, res.verdict))
    print(f"null cases: {false} false name(s) in {len(verdicts)} runs")
    assert false <= 1, [v for v in verdicts if v[2] != NONE]
    assert sum(v[2] != NONE for v in verdicts) <= 1, [v for v in verdicts if v[2] != NONE]


# ------------------------------------------------------------------ 6. a start in a turn
TURN_START = {"command__segments": ((1.5, 0.4, 1.0), (3.0, 0.5, -2.5), (4.0, 0.5, math.inf), (5.5, 0.35, 0.4),
                                    (7.0, 0.45, -0.9), (8.0, 0.2, math.inf)),
              "duration": 8.0, "initial_speed": 0.4, "initial_yaw_rate": 0.27, "initial_skid_ratio": 1.46}
# gap_blind_turns entered in its first turn (v 0.4 m/s, radius 1 m): the wheels at the command's references
# (2.98, 4.47 rad/s), the chassis near the yaw rate these wheels hold (0.274 rad/s after 1 s from rest)


@pytest.mark.parametrize("seed", [362, 364])
def test_a_start_in_a_turn_is_replayed_turning_and_blames_nothing(sim, seed, monkeypatch):
    """The replay's initial state is the truth's at t0 (speed, chassis yaw rate from the gyro, the wheels' ratio from
    the encoders per side), the nominal replay's heading is at the noise (normalised RMS ~1), and with no hidden effect
    nothing is blamed.  The control: the same run replayed from its forward speed only (as before the fix) starts
    straight and keeps a heading error of 7-8 noise scales for the whole run (no actuator delay here: the PID spins
    the wheels up within ~0.1 s; the Husky's 0.43 s delay held the straight start that long)."""
    import bench.gap.model as M

    measured = sim(TURNS, seed, **TURN_START)
    d = measured.data
    _, init = replay_scenario(measured.without_truth(), load_scenario(TURNS))
    assert init.speed == pytest.approx(float(d.truth_vx.iloc[0]), abs=0.02)
    assert init.yaw_rate == pytest.approx(float(d.truth_wz.iloc[0]), rel=0.1)
    plat = load_scenario(TURNS).platform
    wheels = plat.wheel_radius * (float(d.truth_wr.iloc[0]) - float(d.truth_wl.iloc[0])) / plat.track
    assert init.yaw_rate * init.skid_ratio == pytest.approx(wheels, rel=0.05)
    assert _nominal_yaw_gap(measured) < 2.0  # 0.94, 1.06 on these seeds
    res = find_gap(measured, TURNS)
    assert res.verdict == NONE and res.effects == [] and res.partial == [], res.verdict
    monkeypatch.setattr(M, "_start_turn", lambda *a: (0.0, 1.0))  # the replay before the fix
    assert _nominal_yaw_gap(measured) > 5.0  # 7.2, 8.0: the straight start's heading error stays


def _nominal_yaw_gap(measured) -> float:
    """Normalised RMS of the reference-yaw residual of the nominal model replaying ``measured`` (bench.gap's own
    residual space and pose alignment, as the held-out scoring of bench.real.held_out)."""
    from bench.gap.catalogue import nominal_config
    from bench.gap.fit import Evaluator
    from bench.gap.model import measured_grid, testbed_trace
    from bench.gap.regimes import regimes_for
    from bench.gap.residuals import build_space, gap_table

    run, scn = measured.without_truth(), load_scenario(TURNS)
    rscn, init = replay_scenario(run, scn)
    space = build_space(run, regimes_for(scn.platform))
    ev = Evaluator(rscn, measured_grid(run, space.t, init, scn), space, testbed_trace, workers=1)
    return gap_table(space, ev.signals(nominal_config(rscn)))["ref_yaw"]["normalised_rms"]


def test_a_start_from_rest_into_a_turn_stays_at_rest(sim):
    """The guard of class 1 for turns: a step command from rest into a turn (the first encoder samples, means after
    t0, differ per side) is replayed from rest, speed and yaw rate 0."""
    measured = sim(STEP, 305, **{"command__segments": ((2.0, 2.5, 5.0), (8.0, 4.0, 4.0))})
    _, init = replay_scenario(measured.without_truth(), load_scenario(STEP))
    assert (init.speed, init.yaw_rate, init.skid_ratio) == (0.0, 0.0, 1.0)
