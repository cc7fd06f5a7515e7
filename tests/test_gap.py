"""Gap workflow building blocks against independent expectations (closed forms, exact replays),
the report/JSON/CLI contract, plugin models, determinism and bad input.

The blind every-effect tests are in ``tests/test_gap_hidden.py``."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench.gap import catalogue as C
from bench.gap import find_gap
from bench.gap.model import replay_command
from bench.gap.regimes import REGIMES, label_run
from bench.gap.residuals import build_space, noise_scale
from bench.gap.regimes import regimes_for
from bench.run import RunError, from_arrays
from bench.sim.commands import wheel_reference
from bench.spec import CommandSpec, Segment, load_scenario
from tests.test_strict_json import strict_loads

SCN = "gap_dev_coulomb"  # development scenario: these tests check mechanics, not thresholds
REQUIRED = ("rolling_resistance", "friction", "shear_displacement", "wheel_radius", "cg_offset", "payload",
            "slope", "motor_saturation", "actuator_delay", "encoder_scale", "gyro_bias")


# ------------------------------------------------------------------------------------------ replay
def test_replay_command_reproduces_the_reference_on_the_physics_grid():
    """Command samples at the log rows -> segments: the reference the testbed computes from them
    equals the original command's at every physics step (steps fall on sample times)."""
    plat = load_scenario(SCN).platform
    orig = CommandSpec(kind="wheel_speeds", segments=(Segment(1.0, 1.0, 2.0), Segment(2.5, -0.5, 0.7),
                                                      Segment(4.0, 3.0, 3.0)), accel=0.5)
    t_rows = np.unique(np.concatenate([np.arange(0, 401) / 100.0, np.arange(0, 541) / 135.0]))
    t_rows = t_rows[t_rows <= 4.0]
    cl, cr = wheel_reference(t_rows, orig, plat)
    run = from_arrays({"t": t_rows, "cmd_wl": cl, "cmd_wr": cr}, {"run_id": "synthetic"})
    rep = replay_command(run, orig.accel)
    assert [s.t_end for s in rep.segments[:2]] == [1.0, 2.5]
    assert rep.accel == orig.accel
    grid = np.arange(0, 481) / 120.0
    a = np.column_stack(wheel_reference(grid, orig, plat))
    b = np.column_stack(wheel_reference(grid, rep, plat))
    np.testing.assert_array_equal(a, b)


def test_replay_of_a_clean_run_leaves_only_sensor_noise(sim):
    """No hidden effect: drive signals replay exactly (the physics is seed independent) and the
    other residuals are the sensors' own noise: encoder quantisation q/(T sqrt 6), gyro and
    reference-sensor noise of the spec."""
    measured = sim(SCN, 3)
    scn = load_scenario(SCN)
    res = find_gap(measured, SCN, catalogue=(C.get("gyro_bias"),), workers=1)
    g = res.gap_before
    assert g["tau_l"]["rms"] < 1e-9 and g["i_r"]["rms"] < 1e-9
    enc = scn.platform.sensors.encoder
    q = 2 * math.pi / enc.counts_per_rev * enc.rate_hz / math.sqrt(6)
    assert g["enc_wl"]["rms"] == pytest.approx(q, rel=0.15)
    imu = scn.platform.sensors.imu
    assert g["imu_gz"]["rms"] == pytest.approx(imu.gyro_noise, rel=0.15)
    ref = scn.platform.sensors.reference
    assert g["ref_x"]["rms"] == pytest.approx(ref.pos_noise, rel=0.2)
    assert g["ref_yaw"]["rms"] == pytest.approx(ref.yaw_noise, rel=0.2)
    assert res.verdict == "no significant missing effect" and res.effects == []


# ------------------------------------------------------------------------------------------ residuals
def test_noise_scale_of_white_noise_on_smooth_and_stepped_signals():
    rng = np.random.default_rng(5)
    t = np.arange(20000) / 100.0
    for base in (np.sin(0.3 * t) * 2.0, np.where(t % 20 < 10, 1.0, -1.0)):
        v = base + rng.normal(0, 0.03, t.size)
        assert noise_scale(v) == pytest.approx(0.03, rel=0.05)


def test_pose_alignment_recovers_a_known_initial_pose_error(sim):
    """The model trajectory displaced by a known SE(2) error of its initial pose is realigned."""
    measured = sim(SCN, 0).without_truth()
    scn = load_scenario(SCN)
    space = build_space(measured, regimes_for(scn.platform))
    mx, my, myaw = space.meas["ref_x"], space.meas["ref_y"], space.meas["ref_yaw"]
    d, tx, ty = 0.01, 0.006, -0.004
    c, s = math.cos(d), math.sin(d)
    model = {"ref_x": tx + c * (mx - mx[0]) - s * (my - my[0]) + mx[0],
             "ref_y": ty + s * (mx - mx[0]) + c * (my - my[0]) + my[0], "ref_yaw": myaw + d}
    before = np.sqrt(np.mean((model["ref_x"] - mx) ** 2 + (model["ref_y"] - my) ** 2))
    al = space.align_pose(model)
    after = np.sqrt(np.mean((al["ref_x"] - mx) ** 2 + (al["ref_y"] - my) ** 2))
    assert before > 0.01 and after < 3e-4
    assert np.max(np.abs(al["ref_yaw"] - myaw)) < 1e-4


def test_regimes_of_a_synthetic_run():
    """Known phases -> labels: standstill, accelerating, steady straight, three curvature bands,
    braking, climbing (accelerometer sees g sin(5 deg) at constant speed)."""
    plat = load_scenario(SCN).platform
    r, B = plat.wheel_radius, plat.track
    t = np.arange(0, 18.0, 0.01)
    v = np.interp(t, [0, 1, 3, 13, 15, 18], [0, 0, 0.5, 0.5, 0.0, 0.0])
    kappa = np.select([(t >= 5) & (t < 7), (t >= 7) & (t < 9), (t >= 9) & (t < 11)], [0.5, 2.0, 5.0], 0.0)
    w = v * kappa
    wl, wr = (v - w * B / 2) / r, (v + w * B / 2) / r
    ax = np.gradient(v, t)
    climb = (t >= 11.3) & (t < 12.7)
    ax = ax + np.where(climb, 9.81 * math.sin(math.radians(5)), 0.0)
    s = plat.wheel_radius_scale_l
    run = from_arrays({"t": t, "cmd_wl": wl, "cmd_wr": wr, "enc_wl": wl / s, "enc_wr": wr / s, "imu_ax": ax})
    grid, lab = label_run(run, plat)

    def at(tt: float) -> str:
        return REGIMES[lab[int(round(tt / 0.02))]]

    assert at(0.5) == "standstill"
    assert at(2.0) == "accelerating"
    assert at(4.0) == "steady straight"
    assert at(6.0) == "turning gentle"
    assert at(8.0) == "turning medium"
    assert at(10.0) == "turning tight"
    assert at(12.0) == "climbing"
    assert at(14.0) == "braking"


def test_a_noisy_accelerometer_on_flat_ground_is_not_climbing():
    """White accelerometer noise of 1.2 m/s^2 per sample at 20 Hz (the real Husky's a_x): the 0.5 s mean has a noise
    std of 1.2 / sqrt(10) = 0.38 m/s^2, more than g sin(2 deg) = 0.34, so the 2 deg test alone labels a flat, steady
    run "climbing" on 2 Phi(-0.34 / 0.38) = 37 % of it or more (measured here: 47 %, the mean of the interpolated
    0.02 s grid is noisier than that of 10 independent samples); with the noise floor (3 x 0.38): 0.2 %.  A 10 deg
    climb (1.70 m/s^2) in the same noise is still found on most of its samples (here all)."""
    plat = load_scenario(SCN).platform
    r = plat.wheel_radius
    rng = np.random.default_rng(5)
    t = np.arange(0, 30.0, 0.05)
    wl = wr = np.full(t.size, 0.5 / r)
    climb = (t >= 20) & (t < 26)
    ax = rng.normal(0.0, 1.2, t.size) + np.where(climb, 9.81 * math.sin(math.radians(10)), 0.0)
    run = from_arrays({"t": t, "cmd_wl": wl, "cmd_wr": wr, "enc_wl": wl, "enc_wr": wr, "imu_ax": ax})
    grid, lab = label_run(run, plat)
    is_climb = lab == REGIMES.index("climbing")
    flat = (grid > 1) & (grid < 19)
    assert is_climb[flat].mean() < 0.02
    assert is_climb[(grid > 20.5) & (grid < 25.5)].mean() > 0.8


@pytest.mark.parametrize("scenario,mount,truth,raw_below", [
    ("mandow_rotation_asphalt_pneumatic_50psi", {"lever_x": 0.4}, "spin", 0.5),
    ("mandow_rotation_asphalt_pneumatic_50psi", {"lever_y": 0.4}, "spin", 0.99),
    ("ramp_asphalt_5p4", {"yaw_misalignment": math.pi / 2}, "climbing", 0.5),
], ids=["spin_lever_x", "spin_lever_y", "ramp_sideways_imu"])
def test_regimes_undo_the_imu_mounting_the_platform_declares(sim, scenario, mount, truth, raw_below):
    """The testbed's IMU mounted as declared (0.4 m ahead of / beside the CoM on a spin on the spot, or turned 90 deg
    on a 5.4 deg ramp): labelled with the platform as declared, every sample gets its true regime; with the
    mounting left out of the platform (the raw accelerometer, as before) the centripetal -w^2 l_x makes a spin
    "climbing" (96 % of the samples), the tangential alpha l_y its spin-up (3 %), and the turned axes hide the
    ramp (17 % "climbing")."""
    over = {f"platform.sensors.imu.{k}": v for k, v in mount.items()}
    run = sim(scenario, 7, **{k.replace(".", "__"): v for k, v in over.items()})
    for plat, share in ((load_scenario(scenario, over).platform, 1.0), (load_scenario(scenario).platform, None)):
        _, lab = label_run(run, plat)
        right = float(np.mean(lab == REGIMES.index(truth)))
        if share is not None:
            assert right == share
        else:
            assert right < raw_below


# ------------------------------------------------------------------------------------------ catalogue
def test_catalogue_has_every_required_effect_and_maps_to_valid_spec_fields():
    assert set(REQUIRED) <= set(C.BY_NAME)
    scn = load_scenario(SCN)
    for e in C.CATALOGUE:
        assert e.meaning and e.signature and e.channels and e.params
        vals = e.neutral(scn) or tuple(p.lower * 2 if p.log else 0.5 * (p.lower + p.upper) for p in e.params)
        ov = e.spec_overrides(scn, vals)
        # the same fields through the `--set` path build a valid scenario with those values
        via_set = load_scenario(SCN, ov)
        from bench.gap.model import apply_overrides

        via_replace = apply_overrides(scn, ov)
        assert via_set.platform == via_replace.platform and via_set.terrain == via_replace.terrain, e.name


def test_sensor_effect_fit_equals_the_closed_form(sim):
    """A constant gyro bias: the least-squares estimate is the mean of measured minus model yaw
    rate, and the model's yaw rate is the measured run's true yaw rate (exact replay)."""
    measured = sim(SCN, 4, **{"platform__sensors__imu__gyro_bias_z": 0.02})
    res = find_gap(measured, SCN, catalogue=(C.get("gyro_bias"), C.get("encoder_scale")), workers=1)
    t, gz = measured.samples("imu_gz")
    truth = np.interp(t, measured.t, measured["truth_wz"])
    expected = float(np.mean(gz - truth))
    assert res.named == ["gyro_bias"]
    fitted = res.effects[0]["parameters"]["gyro_bias_z"]
    assert fitted == pytest.approx(expected, abs=2e-5)
    se = res.effects[0]["uncertainty"]["gyro_bias_z"]
    assert 0 < se < 1e-3


def test_block_jackknife_standard_error_matches_monte_carlo_where_the_classical_one_is_optimistic():
    """Independent expectation: the Monte Carlo spread of a least-squares estimate over 300 realisations.
    Residuals white: the block jackknife and the classical standard error both match it.  Residuals AR(1)
    with a 0.5 s correlation time (as the gap workflow's pose residuals and model errors are): the classical
    one claims ~1/10 of the spread, the jackknife over 2 s blocks matches it (within 25 %)."""
    from scipy.signal import lfilter

    from bench.gap.fit import block_jackknife_cov

    rng = np.random.default_rng(1)
    t = np.arange(2000) * 0.01
    X = np.column_stack([np.ones_like(t), np.sin(2 * np.pi * t / 7.0) + t / 20.0])
    blocks = np.floor(t / 2.0).astype(int)
    for phi in (0.0, 0.98):
        est, jk, cl = [], [], []
        for _ in range(300):
            y = X @ np.array([0.3, 1.2]) + lfilter([1.0], [1.0, -phi], rng.standard_normal(t.size))
            beta = np.linalg.lstsq(X, y, rcond=None)[0]
            z = y - X @ beta
            est.append(beta)
            jk.append(np.diag(block_jackknife_cov(-X, z, blocks)))
            cl.append(np.diag(np.linalg.inv(X.T @ X)) * (z @ z) / (t.size - 2))
        mc_sd = np.std(est, axis=0)
        jk_ratio = np.sqrt(np.mean(jk, axis=0)) / mc_sd
        cl_ratio = np.sqrt(np.mean(cl, axis=0)) / mc_sd
        assert np.all((jk_ratio > 0.75) & (jk_ratio < 1.25)), (phi, jk_ratio)
        if phi == 0.0:
            assert np.all((cl_ratio > 0.8) & (cl_ratio < 1.2)), cl_ratio
        else:
            assert np.all(cl_ratio < 0.2), cl_ratio


def test_block_jackknife_of_the_free_parameters_with_fixed_columns_and_bounds():
    """The last p columns are the free parameters (the fixed effects' columns refitted beside them); with
    bounds, a block's step stops at the bound; one block gives NaN (no jackknife)."""
    from bench.gap.fit import block_jackknife_cov

    rng = np.random.default_rng(3)
    J = rng.standard_normal((400, 3))
    z = rng.standard_normal(400)
    blocks = np.repeat(np.arange(8), 50)
    full = block_jackknife_cov(J, z, blocks)
    assert np.allclose(block_jackknife_cov(J, z, blocks, p=2), full[1:, 1:], rtol=1e-12, atol=0)
    u, lo, hi = np.zeros(3), np.full(3, -1e-9), np.full(3, 1e-9)
    # every step clipped to +-1e-9: each deviation from the mean <= 2e-9, so (B - 1)/B sum dev^2 <= (B - 1) 4e-18
    assert np.all(np.abs(block_jackknife_cov(J, z, blocks, u, lo, hi)) <= 7 * 4e-18)
    assert np.max(np.abs(full)) > 1e-6  # unclipped, the spread is far larger
    assert np.isnan(block_jackknife_cov(J, z, np.zeros(400, int))).all()


def test_cost_jitter_is_zero_on_a_smooth_bowl_and_recovers_known_jitter():
    """Closed form: with a linear residual z(u) = z0 + J u the cost |z0 + J u|^2 is the bowl itself, so the
    jitter is 0 (to rounding); with iid N(0, 2^2) added to the costs it recovers 2 (within the sampling error of
    200 evaluations); evaluations outside the radius or at the solution are not used, repeated ones once; a
    single neighbour gives its own difference."""
    from bench.gap.fit import cost_jitter

    rng = np.random.default_rng(5)
    J = rng.standard_normal((300, 2))
    z0 = rng.standard_normal(300)
    u_star = np.linalg.lstsq(J, -z0, rcond=None)[0]
    z = z0 + J @ u_star
    steps = np.array([0.01, 0.02])
    pts = u_star + rng.uniform(-0.25, 0.25, (200, 2)) * steps
    smooth = [(u, float((z0 + J @ u) @ (z0 + J @ u))) for u in pts]
    s, n = cost_jitter(J, z, u_star, smooth, steps)
    assert n == 200 and s < 1e-9
    noisy = [(u, c + 2.0 * rng.standard_normal()) for u, c in smooth]
    s, n = cost_jitter(J, z, u_star, noisy, steps)
    assert s == pytest.approx(2.0, rel=0.15)
    far = [(u_star + 0.3 * steps, 1e6), (u_star, 1e6)]
    s_far, n_far = cost_jitter(J, z, u_star, noisy + far + noisy[:5], steps)  # repeats (cache hits) count once
    assert n_far == 200 and s_far == pytest.approx(s, rel=1e-12)
    one = cost_jitter(J, z, u_star, noisy[:1], steps)
    assert one[1] == 1 and one[0] == pytest.approx(abs(noisy[0][1] - smooth[0][1]), rel=1e-9)
    assert cost_jitter(J, z, u_star, far, steps) == (0.0, 0)


# ------------------------------------------------------------------------------------------ report / CLI
def test_report_files_and_json_contract(sim, tmp_path):
    from bench.gap.report import write_report

    measured = sim(SCN, 2, **{"platform__sensors__imu__gyro_bias_z": -0.012})
    res = find_gap(measured, SCN, catalogue=(C.get("gyro_bias"), C.get("rolling_resistance")), workers=1)
    out = write_report(res, tmp_path, hidden={"platform.sensors.imu.gyro_bias_z": -0.012})
    doc = strict_loads(out["json"].read_text())
    for key in ("effects", "gap_before", "gap_after", "verdict"):
        assert key in doc
    e = doc["effects"][0]
    assert e["name"] == "gyro_bias" and set(e) >= {"name", "parameters", "uncertainty"}
    assert set(doc["gap_before"]) == set(doc["gap_after"]) and "imu_gz" in doc["gap_before"]
    assert {"rms", "percent"} <= set(doc["gap_before"]["imu_gz"])
    assert doc["gap_after"]["imu_gz"]["rms"] < 0.5 * doc["gap_before"]["imu_gz"]["rms"]
    md = out["markdown"].read_text()
    assert res.verdict in md and "imu_gz" in md
    assert out["figure"].stat().st_size > 10_000


def test_cli_gap_writes_json(sim, tmp_path):
    import bench.cli.gap  # noqa: F401  (registers the command)
    from bench.cli import main

    measured = sim(SCN, 1, **{"terrain__rolling_resistance": 0.06})
    p = tmp_path / "m.parquet"
    measured.to_parquet(p)
    out = tmp_path / "gap.json"
    assert main(["gap", "--measured", str(p), "--scenario", SCN, "--json", str(out), "--quiet", "--workers", "1"]) == 0
    doc = strict_loads(out.read_text())
    assert doc["verdict_kind"] == "missing_effect" and doc["effects"][0]["name"] == "rolling_resistance"
    assert doc["effects"][0]["parameters"]["rolling_resistance"] == pytest.approx(0.06, rel=0.05)


def test_plugin_model_gets_only_sensor_effects(sim):
    measured = sim("straight_0p2_vinyl", 0, **{"platform__sensors__imu__gyro_bias_z": 0.03})
    res = find_gap(measured, "straight_0p2_vinyl", model="yu2010.closed_loop", workers=1)
    assert "slope" in res.not_applicable and "gyro_bias" not in res.not_applicable
    assert {"enc_wl", "tau_l", "imu_gz", "ref_x"} <= set(res.gap_before)
    assert res.verdict_kind in ("missing_effect", "unexplained_residual", "no_significant_effect")
    for e in res.effects + res.partial:
        assert C.get(e["name"]).kind == "sensor"


def test_same_input_same_output_serial_or_parallel(sim):
    measured = sim(SCN, 6, **{"platform__payload": 6.0})
    cat = tuple(C.get(n) for n in ("payload", "rolling_resistance", "gyro_bias"))
    a = find_gap(measured, SCN, catalogue=cat, workers=1).to_json()
    b = find_gap(measured, SCN, catalogue=cat, workers=2).to_json()
    for d in (a, b):
        assert "runtime_s" not in d  # a wall time: the JSON is the same run after run
        d.pop("n_simulations")
    assert json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True, default=str)
    assert a["effects"][0]["name"] == "payload"


# ------------------------------------------------------------------------------------------ bad input
def test_bad_input_names_run_and_channel(sim):
    measured = sim(SCN, 0)
    broken = type(measured)(measured.data.drop(columns=["cmd_wl"]), dict(measured.meta, run_id="broken-run"))
    with pytest.raises(RunError, match="cmd_wl"):
        find_gap(broken, SCN, workers=1)
    empty = type(measured)(measured.data.assign(cmd_wr=np.nan), dict(measured.meta, run_id="nan-run"))
    with pytest.raises(RunError, match="nan-run.*cmd_wr|cmd_wr.*nan-run"):
        find_gap(empty, SCN, workers=1)


def test_a_run_without_residual_channels_is_a_one_line_error_alone_or_among_several(sim):
    from bench.gap.residuals import CHANNELS

    measured = sim(SCN, 0)
    keep = [c for c in measured.data.columns if c not in CHANNELS and not c.startswith("gnss_")]  # (GNSS: body_v*)
    bare = type(measured)(measured.data[keep], dict(measured.meta, run_id="bare-run"))
    for arg in (bare, [measured, bare]):
        with pytest.raises(RunError, match="bare-run.*no residual channel"):
            find_gap(arg, SCN, workers=1)


def test_change_of_a_zero_gap_is_zero_not_nan():
    from bench.gap.report import change_text

    assert change_text(0.0, 0.0) == "+0%" and change_text(0.0, 0.1) == "new"
    assert change_text(2.0, 1.0) == "-50%" and change_text(float("nan"), 1.0) == "n/a"


def test_powertrain_lag_reference_is_the_first_order_step_response():
    """The testbed's PID references with ``powertrain_tau_l/r`` set follow the closed-form first-order step
    response 1 - exp(-t/tau) of the command (each side its own tau); at tau = 0 they are the command itself."""
    import dataclasses

    from bench.sim.testbed import _references

    scn = load_scenario("gap_test_coulomb")
    n = int(round(3.0 / scn.dt))
    plain_l, plain_r = map(np.asarray, _references(scn, 0, n))
    plat = dataclasses.replace(scn.platform, powertrain_tau_l=0.12, powertrain_tau_r=0.4)
    lag_l, lag_r = map(np.asarray, _references(dataclasses.replace(scn, platform=plat), 0, n))
    assert np.array_equal(plain_l, _references(scn, 0, n)[0])  # default: unchanged
    k = np.flatnonzero(plain_l != 0)[0]  # the first commanded step: constant up to the next segment
    seg = k + np.flatnonzero(np.diff(plain_l[k:]) != 0)[0] + 1 if np.any(np.diff(plain_l[k:]) != 0) else n + 1
    t = (np.arange(k, seg) - k + 1) * scn.dt
    for lag, plain, tau in ((lag_l, plain_l, 0.12), (lag_r, plain_r, 0.4)):
        assert np.allclose(lag[k:seg], plain[k] * (1 - np.exp(-t / tau)), rtol=0, atol=1e-9 * abs(plain[k]))
    assert C.get("powertrain_lag").spec_overrides(scn, (0.1, 0.2)) == {
        "platform.powertrain_tau_l": 0.1, "platform.powertrain_tau_r": 0.2}


def test_pose_channels_take_part_in_the_where_analysis_by_the_growth_of_their_error():
    """A heading error made only in regime 1 (the model's yaw drifts there at a constant rate, then holds the
    error) is found there: the excess of regime 1 is the closed form w (d^2 / (2 sigma^2) - noise2) of the
    per-sample increment d, regime 0 (where the error only persists) has none, and the time profile puts the
    excess in the bins of the drift.  With the pose left out, as before, neither regime had any excess."""
    from bench.gap.residuals import ResidualSpace, regime_table, time_profile

    t = np.arange(200) * 0.05
    reg = np.where((t >= 3.0) & (t < 6.0), 1, 0)
    rate, sigma, sigma_hat = 0.2, 0.003, 0.001  # [rad/s], [rad]
    drift = rate * np.clip(t - 3.0, 0.0, 3.0)  # made in regime 1, kept after it
    sp = ResidualSpace(channels=("enc_wl", "ref_yaw"), t={"enc_wl": t, "ref_yaw": t},
                       meas={"enc_wl": np.ones_like(t), "ref_yaw": drift}, sigma_hat={"enc_wl": 0.1, "ref_yaw": sigma_hat},
                       sigma={"enc_wl": 0.1, "ref_yaw": sigma}, weight={"enc_wl": 1.0, "ref_yaw": 1.0},
                       regime={"enc_wl": reg, "ref_yaw": reg}, regime_names=("cruise", "turn"), missing=())
    model = {"enc_wl": np.ones_like(t), "ref_yaw": np.zeros_like(t)}
    tab = regime_table(sp, model)
    d = rate * 0.05
    inside = (reg[1:] == 1)
    expect = np.mean(np.where(np.diff(drift) > 0, d, 0.0)[inside] ** 2) / (2 * sigma**2) - (sigma_hat / sigma) ** 2
    assert tab["turn"]["excess_cost"] == pytest.approx(expect, rel=1e-9)
    assert tab["cruise"]["excess_cost"] == 0.0  # the error is still there (normalised RMS > 1) but not made here
    assert tab["cruise"]["normalised_rms"]["ref_yaw"] > 10
    assert max(tab["turn"]["local_rms"], key=tab["turn"]["local_rms"].get) == "ref_yaw"
    centres, prof = time_profile(sp, model, bin_s=0.5)
    assert np.all(prof[(centres > 3.25) & (centres < 5.75)] > 0) and np.all(prof[(centres < 2.75) | (centres > 6.25)] == 0)
