"""The NEES study of the Yi 2009 reproduction (not a Yi claim; issue 4): methods.yi2009.repro's nees table,
its statistics, notes and the truth-informed attribution (the quick reproduction: the package fixture ``result``).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bench.estimation.consistency import NullNees
from bench.registry import calibrated_on
from bench.run import from_arrays
from bench.spec import load_scenario
from methods.yi2009 import repro as Y
from methods.yi2009.s_gamma import PUBLISHED_S_GAMMA


def test_nees_band_flags_and_fractions_equal_a_recomputation(result) -> None:
    """The nees table's band is chi2(2N)/N (checked by Monte Carlo: a consistent filter's N-seed mean of chi2(2)
    NEES falls inside 95 % of the time), and its per-path means, in-band fractions and the two flags equal a
    recomputation from the stored per-step NEES series."""
    res, _ = result
    m = res.metrics
    ne = res.info["_yi2009_nees"]
    n = len(Y.SETTINGS.seeds_quick)
    lo, hi = m["nees.band_lo"], m["nees.band_hi"]
    draws = np.random.default_rng(0).chisquare(2, size=(200_000, n)).mean(axis=1)
    assert np.mean((draws >= lo) & (draws <= hi)) == pytest.approx(0.95, abs=0.005)
    assert np.mean(draws < lo) == pytest.approx(0.025, abs=0.003)
    flags = {"paper": True, "consistent": True}
    mean_flags = {"paper": True, "consistent": True}
    assert {c for (_, c, _) in ne["series"]} == set(flags) and len(ne["series"]) == 2 * 3 * len(Y.PATHS)
    for (path, cfg, v), arr in ne["series"].items():
        assert arr.shape[0] == n
        avg = arr.sum(axis=0) / n
        mean = float(avg.sum() / avg.size)
        assert m[f"nees.{path}.{cfg}.v{v}.nees"] == pytest.approx(mean, rel=1e-12)
        inside = sum(1 for a in avg if lo <= a <= hi) / avg.size
        assert m[f"nees.{path}.{cfg}.v{v}.in_band"] == pytest.approx(inside, abs=1e-12)
        assert m[f"nees.{path}.{cfg}.v{v}.below"] == pytest.approx(sum(1 for a in avg if a < lo) / avg.size, abs=1e-12)
        assert (m[f"nees.{path}.{cfg}.v{v}.in_band"] + m[f"nees.{path}.{cfg}.v{v}.below"]
                + m[f"nees.{path}.{cfg}.v{v}.above"]) == pytest.approx(1.0, abs=1e-12)
        flags[cfg] = flags[cfg] and inside >= 0.9  # Bar-Shalom's per-step test (bench.estimation.ukf.NEES_MIN_STEP_FRACTION)
        mean_flags[cfg] = mean_flags[cfg] and lo <= mean <= hi
        assert m[f"nees.{path}.{cfg}.v{v}.pos_rms"] == pytest.approx(np.mean(ne["rms"][(path, cfg, v)]), rel=1e-12)
    assert m["nees.paper_in_band"] == float(flags["paper"]) and m["nees.consistent_in_band"] == float(flags["consistent"])
    assert m["nees.paper_mean_in_band"] == float(mean_flags["paper"])
    assert m["nees.consistent_mean_in_band"] == float(mean_flags["consistent"])
    claims = {c["id"]: c for c in res.claims}
    assert claims["nees_consistent"]["holds"] == flags["consistent"] and claims["nees_paper"]["holds"] == flags["paper"]


def test_nees_paper_configuration_is_the_scored_plugin(result) -> None:
    """The nees table's paper rows are the Fig. 5-6 filters: same position RMS per path and scheme, calibrated on the
    identification runs; the consistent filters were calibrated on the dedicated calibration runs only (yi_calib,
    yi_calib_steps: neither identification nor scored runs), differ from the paper filter only in the identified IMU
    noise / levelling precision and their Gauss-Markov error states, and scheme 3 keeps the paper's S(gamma) fit."""
    res, _ = result
    m = res.metrics
    ne = res.info["_yi2009_nees"]
    ev = res.info["_yi2009_evaluation"]
    for path in Y.PATHS:
        for v in (1, 2, 3):
            assert m[f"nees.{path}.paper.v{v}.pos_rms"] == pytest.approx(m[f"fig5_6.{path}.v{v}"], rel=1e-12)
    ident_hashes = calibrated_on(ev.calibrated)
    calib_hashes = set()
    for (cfg, v), meth in ne["methods"].items():
        if cfg == "paper":
            assert calibrated_on(meth) == ident_hashes, (cfg, v)
            assert meth.params == ev.calibrated.params
            continue
        assert meth.name == f"yi2009.ekf_v{v}_consistent" and meth.calibrated
        assert meth.noise_info["calibration_runs"] and all(
            rid.startswith("yi_calib") for rid in meth.noise_info["calibration_runs"])
        assert not meth.refit_s_gamma and meth.noise_info["imu_noise_source"] == "rest"
        calib_hashes |= calibrated_on(meth)
        differ = {f.name for f in dataclasses.fields(meth.params)
                  if getattr(meth.params, f.name) != getattr(ev.calibrated.params, f.name)}
        assert differ <= {"accel_noise", "gyro_noise", "p0_rollpitch"}, differ
        assert (meth.gm_y is not None) == (v == 3)
        if v == 3:
            assert meth.s_gamma == ev.calibrated.s_gamma
    assert len(calib_hashes) == len(Y.SETTINGS.nees_calibration) and not calib_hashes & ident_hashes
    for pr in ev.paths.values():
        assert pr.run0.content_hash() not in calib_hashes
    for pr in ev.paths.values():
        assert pr.run0.content_hash() not in ident_hashes


def test_body_velocity_errors_rotate_the_error_and_its_covariance() -> None:
    """body_velocity_errors against conservation laws on a random estimate: the rotation into the heading frame
    keeps the error norm (along^2 + across^2 = |e|^2, e written out here from the world-frame velocities) and the
    trace of the velocity covariance (sd_along^2 + sd_across^2 = P_xx + P_yy); the window starts at t_min."""
    from bench.registry import make_estimate

    rng = np.random.default_rng(4)
    n = 400
    t = np.arange(n) * 0.02
    tyaw, tvx, tvy = rng.uniform(-3, 3, n), rng.normal(0.3, 0.1, n), rng.normal(0.0, 0.05, n)
    run = from_arrays(dict(t=t, truth_yaw=tyaw, truth_vx=tvx, truth_vy=tvy), dict(run_id="synthetic-bve"))
    yaw, vx, vy = tyaw + rng.normal(0, 0.1, n), tvx + rng.normal(0, 0.05, n), tvy + rng.normal(0, 0.05, n)
    A = rng.normal(size=(n, 9, 9))
    P = A @ A.transpose(0, 2, 1) * 1e-3
    est = make_estimate("test", {"P": P}, t=t, x=np.zeros(n), y=np.zeros(n), yaw=yaw, vx=vx, vy=vy)
    got = Y.body_velocity_errors(run, est, t_min=2.0)
    m = t >= 2.0
    ex = np.cos(yaw) * vx - np.sin(yaw) * vy - (np.cos(tyaw) * tvx - np.sin(tyaw) * tvy)
    ey = np.sin(yaw) * vx + np.cos(yaw) * vy - (np.sin(tyaw) * tvx + np.cos(tyaw) * tvy)
    assert got.shape == (int(m.sum()), 4)
    assert np.allclose(got[:, 0] ** 2 + got[:, 1] ** 2, (ex**2 + ey**2)[m], rtol=1e-10, atol=1e-14)
    assert np.allclose(got[:, 2] ** 2 + got[:, 3] ** 2, (P[:, 3, 3] + P[:, 4, 4])[m], rtol=1e-10, atol=1e-14)
    assert np.allclose(got[:, 0], (np.cos(yaw) * ex + np.sin(yaw) * ey)[m], rtol=1e-10, atol=1e-14)


def test_consistent_plugins_calibrate_on_a_league_calibration_set() -> None:
    """The league calibrates the registered consistent plugins on bench.reproduce.league.calibration_set (runs that start
    moving: no rest for the IMU noise): calibration succeeds with the paper's IMU noise / P0 ("paper default"),
    scheme 3 fits S(gamma) on those runs (refit_s_gamma), and the estimate on the scored path runs, finite."""
    from bench.reproduce import league
    from bench.registry import calibrate, estimate
    from bench.sim import simulate
    from methods.yi2009 import EkfParams, ekf_v3_consistent

    scn = load_scenario("yi_figure8")
    runs = [simulate(s, seed) for s, seed in league.calibration_set(scn, quick=True)]
    m = calibrate(ekf_v3_consistent(), runs)
    p = EkfParams()
    assert m.noise_info["imu_noise_source"] == "paper default"
    assert (m.params.accel_noise, m.params.gyro_noise, m.params.p0_rollpitch) == (p.accel_noise, p.gyro_noise,
                                                                                 p.p0_rollpitch)
    assert m.calibration is not None and len(m.calibration_points) >= 2 and m.s_gamma != PUBLISHED_S_GAMMA
    est = estimate(m, simulate(scn, 0))
    assert np.isfinite(est["vx"]).all() and np.isfinite(est["x"]).all()
    assert est.info["calibration"]["points"]


def test_nees_note_sentences_follow_the_per_cell_numbers(tmp_path) -> None:
    """The nees_consistent note's explanations are gated on each cell's own numbers: a cell with its seed-averaged
    NEES above the band at most steps and its slip at the clip 90 % of the time gets the clip sentence with its
    numbers, the same cell at 10 % does not; a cell mostly below the band is classified by its per-step fractions
    even when its time mean lies inside the band (one huge outlier step).  The slow-slip and adaptive_r sentences
    follow their metrics: "exceeds" only when the Gauss-Markov sigma exceeds every path's slow slip, "falls more than
    the claim" only when the error's ratio is below the claim's in every cell, the stall clause only on a path
    without high-frequency row error whose matched R is within 3x the per-step process noise; without the ablation
    (quick mode) no adaptive_r sentence."""
    from types import SimpleNamespace

    lo, hi = Y.nees_band(2, 2)
    T = 100
    cells = [(k, c, v) for k in Y.PATHS for c in Y.NEES_CONFIGS for v in (1, 2, 3)]

    abl = [(k, "ablation_adaptive_r", v) for k in Y.PATHS for v in (1, 2, 3)]
    per_step = [(k, Y.TOLD_BASE, v) for k in Y.PATHS for v in (1, 2, 3)]  # the base of the adaptive_r comparison

    def ne(clip: float, sigma: float = 0.05, extra: bool = False, err_abl: float = 0.002,
           odometer: tuple[float, float] = (0.0, 7.8e-5)) -> dict:
        series = {key: np.full((2, T), 2.0) for key in cells + (abl + per_step if extra else [])}
        series[("straight", "consistent", 2)] = np.full((2, T), 10 * hi)  # above at every step
        low = np.full((2, T), 0.5 * lo)
        low[:, 0] = 2.0 * T  # time mean inside the band, yet 99 % of the steps below it
        series[("circle", "consistent", 1)] = low
        d = dict(clip_frac=0.0, first_clip_s=math.nan, roll_err=1e-3, roll_sd=1e-3)
        diag = {key: [dict(d), dict(d)] for key in cells}
        diag[("straight", "consistent", 2)] = [dict(d, clip_frac=clip, first_clip_s=1.5)] * 2
        gm = dict(sigma=sigma, tau=2.0, white=0.01, white_floored=False)
        noise = {v: dict(accel_noise=0.05, gyro_noise=0.005, p0_rollpitch=1e-3, iterations=3, last_change=0.01,
                         converged=True, imu_noise_source="rest", vx=gm, vy=gm if v == 3 else None) for v in (1, 2, 3)}
        per_seed = {key: [np.full((T, 4), 0.01), np.full((T, 4), 0.01)] for key in cells + per_step}
        if extra:  # (err along, across, claimed sd along, across): the error 0.01 -> err_abl, the claim 0.01 -> 0.005
            per_seed.update({key: [np.tile([err_abl, 0.01, 0.005, 0.01], (T, 1))] * 2 for key in abl})
        calib_nees = {(sid, v): dict(nees=2.0, err_along=0.01, sd_along=0.01, err_across=0.01, sd_across=0.01)
                      for sid, _ in Y.SETTINGS.nees_calibration for v in (1, 2, 3)}
        out = dict(series=series, rms={key: [0.1, 0.1] for key in cells + abl + per_step}, diag=diag, noise=noise,
                   odometer=odometer,
                   axes=per_seed,
                   calib_nees=calib_nees, abs_yaw_rate={k: 0.3 for k in Y.PATHS}, calibration=["cal seed 9"],
                   row_slip={"straight": 1e-4, "circle": 3e-4, "figure8": 4e-4}, calib_row_slip={"yi_calib": 7e-4},
                   row_hf={"straight": 0.0, "circle": 0.006, "figure8": 0.01},
                   null={("circle", 1): NullNees(np.linspace(0.0, 1.0, 101), np.linspace(1.0, 3.0, 101)),
                         ("figure8", 1): NullNees(np.full(101, 1.0), np.linspace(1.9, 2.1, 101))},
                   replication={
                       ("figure8", 1): (np.full(T, 2.0), NullNees(np.full(101, 1.0), np.linspace(1.9, 2.1, 101))),
                       ("circle", 1): (np.full(T, 1.0), NullNees(np.full(101, 0.5), np.linspace(1.8, 2.2, 101)))})
        if extra:
            out["r_adapt"] = {("straight", "ablation_adaptive_r", 1): 6e-4, ("circle", "ablation_adaptive_r", 1): 3e-3,
                              ("figure8", "ablation_adaptive_r", 1): 9e-4}
            out["imu_dt"] = 0.008
        return out

    for clip, expect in ((0.9, True), (0.1, False)):
        notes: dict[str, str] = {}
        ctx = SimpleNamespace(info={Y._NEES_KEY: ne(clip), "seeds": [0, 1]}, quick=True, out_dir=tmp_path,
                              note=notes.__setitem__)
        m = Y.nees(ctx)
        txt = notes["nees_consistent"]
        assert ("sits at the +-1 clip" in txt) is expect and ("90% of the steps (straight 2" in txt) is expect
        assert m["circle.consistent.v1.below"] == pytest.approx(0.99) and lo <= m["circle.consistent.v1.nees"] <= hi
        assert "Mostly below the band (circle scheme 1" in txt and "Mostly above the band (straight scheme 2" in txt
        assert "Roll error" not in txt  # roll error = claimed sd everywhere
        # identical errors in both seeds: correlation 1, N_eff 1, named for the failing cells only
        assert m["circle.consistent.v1.seed_corr"] == pytest.approx(1.0) and m["circle.consistent.v1.n_eff"] == 1.0
        assert "circle 1 1.00 (N_eff 1)" in txt and "figure8 1 1.00" not in txt
        assert "sigma (0.05 m/s, the slip left after the traction model over gradual and step commands) exceeds" in txt
        assert "straight 0.0001, circle 0.0003, figure8 0.0004 m/s; calibration runs yi_calib 0.0007 m/s" in txt
        assert "adaptive_r" not in txt  # quick mode: no ablation
        assert "odometer" not in txt  # the per-step v_x row
        # the null's statistics as given: circle 1 has no step in band (1 of the 101 null fractions is <= 0) and its
        # time mean (one step at 2 T, 99 at lo / 2) lies inside the null's means; figure8 1 (mean 2, every step in
        # band) sits at the middle of its null's; Bonferroni over the 2 cells: 0.05 / 2 > 1 / 101 -> not consistent
        obs = (2.0 * T + (T - 1) * 0.5 * lo) / T
        assert m["circle.consistent.v1.null_p_in_band"] == pytest.approx(1 / 101)
        assert m["circle.consistent.v1.null_p_mean"] == pytest.approx(2 * np.mean(np.linspace(1, 3, 101) >= obs))
        assert m["figure8.consistent.v1.null_p_mean"] == pytest.approx(1.0) and m["consistent_null_ok"] == 0.0
        assert m["circle.consistent.v1.null_rule_pass"] == pytest.approx(11 / 101)
        assert "significant at 0.05 (Bonferroni over the cells) in circle scheme 1" in txt
        # the replication on SETTINGS.nees_replication_seeds (its own band chi2(2N)/N): figure8 1 every step in band
        # at the null's middle; circle 1 (NEES 1, below the band at N = 20) under every null in-band fraction (0.5)
        # and mean -> p 0 in both -> not consistent
        rlo, rhi = Y.nees_band(len(Y.SETTINGS.nees_replication_seeds), 2)
        assert rlo > 1.0 and (m["rep_band_lo"], m["rep_band_hi"]) == pytest.approx((rlo, rhi))
        assert m["figure8.consistent.v1.rep_in_band"] == 1.0 and m["figure8.consistent.v1.rep_p_mean"] == 1.0
        assert m["circle.consistent.v1.rep_in_band"] == 0.0 and m["circle.consistent.v1.rep_p_in_band"] == 0.0
        assert m["circle.consistent.v1.rep_p_mean"] == 0.0 and m["consistent_rep_ok"] == 0.0
        assert m["circle.consistent.v1.rep_rule_pass"] == 0.0 and m["figure8.consistent.v1.rep_rule_pass"] == 1.0
        md = (tmp_path / "nees_consistency.md").read_text()
        assert "## Replication: the same test on 20 seeds" in md and "| circle | 1 | 0% | 0% | 0.000 | 1 |" in md
    # the replication's Bonferroni level is 0.05 over its own cells: with two cells (0.025), a p (mean) of 0.03
    # passes and one of 0.02 fails (the null means: 3 or 2 of 200 at or above the observed 2, the rest at 1)
    for n_above, ok in ((3, 1.0), (2, 0.0)):
        info = ne(0.1)
        null_mean = np.r_[np.full(200 - n_above, 1.0), np.full(n_above, 3.0)]
        info["replication"] = {
            ("figure8", 1): (np.full(T, 2.0), NullNees(np.full(200, 1.0), np.linspace(1.9, 2.1, 200))),
            ("straight", 1): (np.full(T, 2.0), NullNees(np.full(200, 0.5), null_mean))}
        ctx = SimpleNamespace(info={Y._NEES_KEY: info, "seeds": [0, 1]}, quick=True, out_dir=tmp_path,
                              note=notes.__setitem__)
        m = Y.nees(ctx)
        assert m["straight.consistent.v1.rep_p_mean"] == pytest.approx(2 * n_above / 200)
        assert m["straight.consistent.v1.rep_p_in_band"] == 1.0 and m["consistent_rep_ok"] == ok
        txt = notes["nees_consistent"]
        assert ("The same test on 20 seeds of each path" in txt
                and ("no cell significant at 0.05 / 2; smallest p 0.03 (straight scheme 1, time-mean NEES 2)" in txt)
                is bool(ok) and ("significant in straight scheme 1" in txt) is (not ok))
    # with the odometer: the configuration names it, and a cell below the band along the heading gets its sentence
    ctx = SimpleNamespace(info={Y._NEES_KEY: ne(0.1, odometer=(0.2, 7.8e-5)), "seeds": [0, 1]}, quick=True,
                          out_dir=tmp_path, note=notes.__setitem__)
    Y.nees(ctx)
    txt = notes["nees_consistent"]
    assert "the v_x row fused as the odometer's displacement over 0.2 s windows (quantisation sd 0.078 mm" in txt
    assert "most along the heading in circle scheme 1: the odometer claims the quantisation of its window's" in txt
    assert "white part identified on the calibration runs" not in txt
    notes = {}
    for sigma, err_abl, more in ((1e-4, 0.002, True), (0.05, 0.008, False)):
        ctx = SimpleNamespace(info={Y._NEES_KEY: ne(0.1, sigma, True, err_abl), "seeds": [0, 1]}, quick=True,
                              out_dir=tmp_path, note=notes.__setitem__)
        Y.nees(ctx)
        txt = notes["nees_consistent"]
        assert ("0.0001 m/s, the slip left after the traction model over gradual and step commands) is to be "
                "compared with" in txt) is (sigma < 4e-4)
        assert ("the along-track error falls more than the claim (error / claimed sd [m/s], constant R -> matched R: "
                f"circle 1 0.01 / 0.01 -> {err_abl:.2g} / 0.005" in txt) is more
        assert ("the along-track error and the claim change" in txt) is not more
        # straight: no high-frequency error, 6e-4 < 3 x 0.05 x 0.008; figure8: 9e-4 but row_hf 0.01; circle: 3e-3
        assert "settles at 0.0006 m/s (straight), 0.003 m/s (circle), 0.0009 m/s (figure8)" in txt
        assert "is 0.0004 m/s): where the row has no high-frequency error (straight) the matched R stalls" in txt
        assert "last 2 s of rows" in (tmp_path / "nees_consistency.md").read_text()


def test_row_slip_error_is_the_slow_row_error_after_the_traction_model():
    """row_slip_error: on closed-form runs with a constant net slip lam0 (tests.methods.yi2009.synthetic's model, testbed
    encoder quantisation and IMU noise) the no-slip row r (w_L + w_R)/2 exceeds v_x by lam0 r (w_L + w_R)/2, so the
    RMS of its 1 s means is that (the quantisation telescopes within a window); a traction model whose c_w |w_z|
    equals it on the circle removes it; windows at rest or in traction transients are left out."""
    from methods.yi2009.consistent import TractionSlip, Yi2009EkfConsistent
    from tests.methods.yi2009.synthetic import R_WHEEL, RPM_TO_RADS, Sensors, synthetic_run

    lam0 = 0.04
    model = Yi2009EkfConsistent(variant=1)
    straight = synthetic_run("straight", 2, Sensors(lam0=lam0))
    assert Y.row_slip_error(straight, model) == pytest.approx(lam0 * R_WHEEL * 30 * RPM_TO_RADS, rel=0.02)
    circle = synthetic_run("circle", 2, Sensors(lam0=lam0))
    want = lam0 * R_WHEEL * 60 * RPM_TO_RADS
    assert Y.row_slip_error(circle, model) == pytest.approx(want, rel=0.02)
    w_z = float(np.mean(np.abs(circle["imu_gz"][circle.t > 5.0])))
    exact = dataclasses.replace(model, traction=TractionSlip(c_f=0.0, c_w=want / w_z))
    assert Y.row_slip_error(circle, exact) < 0.05 * want
    # a stop for 10 s (braked from and restarted to 30 rpm in 0.05 s: traction transients): the windows at rest or
    # around the transients do not count, so the RMS stays the moving slip (with the rest counted it would fall to
    # sqrt(2/3) of it); a run that never moves has no qualifying window
    stop = [(0, 0, 0), (1, 30, 30), (10, 30, 30), (10.05, 0, 0), (20, 0, 0), (20.05, 30, 30), (31, 30, 30)]
    stopping = synthetic_run("straight", 2, Sensors(lam0=lam0), knots_rpm=stop)
    assert Y.row_slip_error(stopping, model) == pytest.approx(lam0 * R_WHEEL * 30 * RPM_TO_RADS, rel=0.02)
    assert math.isnan(Y.row_slip_error(synthetic_run("straight", 2, knots_rpm=[(0, 0, 0), (10, 0, 0)]), model))


def test_told_noise_sets_the_v_x_row_levels_and_nothing_else():
    """told_noise (the nees table's truth-informed attribution): the v_x row per step (odometer off, where the white
    part acts); told the model's own identified levels, the filter is the per-step consistent one, bit for bit
    (states and covariance); a smaller told white part lowers the claimed along-track
    sd and a larger one raises it; the levels are floored (state and R > 0); the null test's linearisation is never
    stored; an uncalibrated model, a negative or NaN level are refused with the offending value."""
    from methods.yi2009.consistent import ADAPTIVE_R_FLOOR, GM_NEGLIGIBLE_SIGMA, GaussMarkov, Yi2009EkfConsistent
    from tests.methods.yi2009.synthetic import Sensors, synthetic_run

    run = synthetic_run("straight", 3, Sensors(lam0=0.02))
    gm = GaussMarkov(sigma=0.003, tau=2.0, white=0.01)
    model = Yi2009EkfConsistent(variant=1, traction_slip=False, store_covariance=True, store_linearisation=True,
                                calibrated=True, gm_x=gm, odometer_window=0.0,
                                start_yaw_sd=None)  # the paper's 1 mrad: white / 4 -> 0.85 x (0.92 x at 0.1 mrad)
    assert Y.told_noise(dataclasses.replace(model, odometer_window=0.2)).odometer_window == 0.0  # per step
    same = Y.told_noise(model, slip=gm.sigma, white=gm.white)
    assert same.gm_x == gm and not same.store_linearisation and Y.told_noise(model).gm_x == gm
    ref, got = model.estimate(run), same.estimate(run)
    assert "lin" in ref.info and "lin" not in got.info
    assert np.array_equal(ref.info["P"], got.info["P"]) and np.array_equal(ref["x"], got["x"])

    def claimed_along(m: Yi2009EkfConsistent) -> float:
        return float(np.sqrt(np.mean(Y.body_velocity_errors(run, m.estimate(run))[:, 2] ** 2)))

    base = claimed_along(model)
    assert claimed_along(Y.told_noise(model, white=gm.white / 4)) < 0.9 * base
    assert claimed_along(Y.told_noise(model, white=gm.white * 4)) > 1.1 * base
    for told, want in (({"white": 0.004}, dataclasses.replace(gm, white=0.004, white_floored=False)),
                       ({"slip": 0.001}, dataclasses.replace(gm, sigma=0.001))):  # one level told: the other kept
        one = Y.told_noise(model, **told)
        assert one.gm_x == want and not one.store_linearisation
    # the copy keeps the calibration guard: registry.estimate refuses its calibration runs as the original does
    from bench import registry
    guarded = registry.calibrate(model, [run])
    assert registry.calibrated_on(Y.told_noise(guarded, white=0.004)) == registry.calibrated_on(guarded) != frozenset()
    with pytest.raises(registry.CalibrationLeak, match="calibrated on"):
        registry.estimate(Y.told_noise(guarded, white=0.004), run)
    floored = Y.told_noise(model, slip=0.0, white=0.0).gm_x
    assert (floored.sigma, floored.white, floored.tau) == (GM_NEGLIGIBLE_SIGMA, ADAPTIVE_R_FLOOR, gm.tau)
    with pytest.raises(ValueError, match="calibrated"):
        Y.told_noise(Yi2009EkfConsistent(variant=1), slip=1e-3)
    for bad in (-1e-3, math.nan):
        with pytest.raises(ValueError, match=f"white = {bad!r}"):
            Y.told_noise(model, white=bad)


def test_told_note_sentence_follows_the_told_cells():
    """_told_txt: the change of the claimed along-track sd is the range over the cells of told / identified - 1 (one
    value when both ends round alike); "n of 6 cells pass" counts the told_both cells at >= 90 % in band; a failing
    cell is named with its side of the band and the axis furthest off (below: the smallest error : sd ratio; above:
    the largest), and each axis clause only where a named cell shows it; the verdicts on the levels only where a cell
    failed as identified; nothing without the told cells (quick mode)."""
    out: dict[str, float] = {}
    cells = [(k, v) for k in Y.PATHS for v in Y.TOLD_VARIANTS]
    for k in Y.PATHS:
        out[f"{k}.told.slip"], out[f"{k}.told.white"] = 1e-4, 1e-3
    for k, v in cells:
        for c, sd_along in ((Y.TOLD_BASE, 2e-3), ("told_slip", 1.9e-3), ("told_white", 1.0e-3), ("told_both", 0.8e-3)):
            p = f"{k}.{c}.v{v}"
            out.update({p + ".in_band": 0.95, p + ".below": 0.05, p + ".above": 0.0, p + ".err_along": 1e-3,
                        p + ".sd_along": sd_along, p + ".err_across": 1e-3, p + ".sd_across": 1e-3})
    txt = Y._told_txt(out)  # every cell passes, as identified and told: no verdict on the levels
    assert "by -5% with the slip sigma told and by -50% with the white part told" in txt
    assert txt.endswith("with both told 6 of 6 cells pass (per step as identified: 6). ")
    out[f"circle.{Y.TOLD_BASE}.v3.in_band"] = 0.35
    out["straight.told_slip.v1.sd_along"] = 2.2e-3  # one cell's claim rises: the range is -5 % to +10 %
    txt = Y._told_txt(out)
    assert "changes by -5% to +10% with the slip sigma told and by -50% with the white part told" in txt
    assert "with both told 6 of 6 cells pass (per step as identified: 5): the v_x row's noise levels account for" in txt
    # two told cells fail: one below the band (across over-covered), one above (along under-covered)
    out.update({"figure8.told_both.v1.in_band": 0.79, "figure8.told_both.v1.below": 0.21,
                "figure8.told_both.v1.sd_across": 4e-3, "straight.told_both.v3.in_band": 0.02,
                "straight.told_both.v3.above": 0.98, "straight.told_both.v3.below": 0.0,
                "straight.told_both.v3.err_along": 4e-3})
    txt = Y._told_txt(out)
    assert "with both told 4 of 6 cells pass (per step as identified: 5)" in txt and "account for" not in txt
    assert "straight scheme 3 2% of the steps in band, mostly above, along 4 : 0.8 mm/s" in txt
    assert "figure8 scheme 1 79% of the steps in band, mostly below, across 1 : 4 mm/s" in txt
    assert "noise levels are not the whole cause" in txt and "the error exceeds the claim" in txt
    assert "across the track the error is not the v_x row's" in txt and "the claim stays above the error" not in txt
    # the same failures when every cell passed as identified: no verdict on the levels; an along cell below the band
    out[f"circle.{Y.TOLD_BASE}.v3.in_band"] = 0.95
    out.update({"circle.told_both.v1.in_band": 0.5, "circle.told_both.v1.below": 0.5})
    txt = Y._told_txt(out)
    assert "per step as identified: 6" in txt and "not the whole cause" not in txt
    assert "circle scheme 1 50% of the steps in band, mostly below, along 1 : 0.8 mm/s" not in txt  # err > sd there
    assert "the claim stays above the error" not in txt
    out["circle.told_both.v1.err_along"] = 0.2e-3
    assert "the claim stays above the error" in Y._told_txt(out)
    del out["figure8.told_both.v3.in_band"]
    assert Y._told_txt(out) == ""
    assert Y._told_txt({k: val for k, val in out.items() if ".told." not in k}) == ""
