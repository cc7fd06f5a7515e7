"""Yi 2009 reproduction (scenarios/papers/yi2009.toml, methods/yi2009/repro/).

One quick reproduction into a temporary results folder and run cache (the package fixture ``result`` of
conftest.py); the tests check the declaration (published a1, a2, a3 against the paper's text, every declared row
computed, every claim with a verdict that follows from the numbers), the written files, the S(gamma) fit against a
second implementation (scipy curve_fit) on the same points, the separation of identification and scored runs, and
the helpers against closed forms (synthetic runs built here).

The NEES study (beyond the paper) is tested in test_nees.py.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import stats
from scipy.optimize import curve_fit

from bench import reproduce as R
from bench.kinematics import integrate_se2
from bench.registry import calibrated_on
from bench.run import RunError, from_arrays
from bench.spec import load_platform, to_dict
from methods.yi2009 import repro as Y
from methods.yi2009.s_gamma import PUBLISHED_S_GAMMA


PAPER_MD = Path(__file__).resolve().parents[4] / "shared" / "papers" / "yi2009_skid_steer_kinematics_imu_ekf.md"
# Sec. V-B of the paper, transcribed a second time: a1 = 2.148 cm, a2 = 0.249, a3 = 0.039
PAPER_A = (2.148, 0.249, 0.039)
PLATFORM = to_dict(load_platform("yi2009_4wd"))


def test_published_s_gamma_equals_the_paper() -> None:
    if PAPER_MD.is_file():  # read the numbers out of the paper's text itself
        text = PAPER_MD.read_text()
        got = tuple(float(re.search(rf"a_{i}\s*=\s*([0-9.]+)", text).group(1)) for i in (1, 2, 3))
        assert got == PAPER_A
    rows = {r["metric"]: r for r in next(t for t in R.load_paper("yi2009")["tables"] if t["id"] == "fig4")["rows"]}
    a1, a2, a3 = PAPER_A
    assert (rows["a1_cm"]["published"], rows["a2"]["published"], rows["a3"]["published"]) == PAPER_A
    assert (PUBLISHED_S_GAMMA.a1_cm, PUBLISHED_S_GAMMA.a2, PUBLISHED_S_GAMMA.a3) == pytest.approx(PAPER_A, abs=1e-12)
    # derived published values: eq. (41) evaluated by hand
    assert rows["s0_cm"]["published"] == pytest.approx(a1 / a3, rel=1e-4)
    assert rows["k"]["published"] == pytest.approx(a2 / a3, rel=1e-4)
    assert rows["s_g025_cm"]["published"] == pytest.approx(a1 / (0.25 * a2 + a3), rel=1e-4)
    assert rows["s_g1_cm"]["published"] == pytest.approx(a1 / (a2 + a3), rel=1e-4)
    assert rows["n_points"]["published"] == 11  # "We ran 11 sets of experiments"


def test_declaration_names_existing_functions_and_metrics() -> None:
    decl = R.load_paper("yi2009")
    assert decl["module"] == "methods.yi2009.repro"
    ids = [t["id"] for t in decl["tables"]]
    assert len(ids) == len(set(ids))
    for tab in decl["tables"]:
        assert callable(getattr(Y, tab["compute"]))
    claim_ids = [c["id"] for c in decl["claims"]]
    assert len(claim_ids) == len(set(claim_ids))
    for c in decl["claims"]:
        for mid in R.claim_metric_ids(c):
            assert mid.split(".")[0] in ids, (c["id"], mid)


def test_ordering_claims_read_scheme3_scheme2_scheme1() -> None:
    claims = {c["id"]: c for c in R.load_paper("yi2009")["claims"]}
    for path in ("straight", "circle", "figure8"):
        assert claims[f"order_{path}"]["metrics"] == [f"fig5_6.{path}.v{v}" for v in (3, 2, 1)]


def test_every_declared_row_maps_to_a_returned_metric(result) -> None:
    res, _ = result
    for tab in res.tables:
        for row in tab["rows_out"]:
            v = row["reproduced"]
            assert v is not None and math.isfinite(v), (tab["id"], row["metric"], v)
    bad = {k: v for k, v in res.metrics.items() if not math.isfinite(v)}
    assert not bad  # metrics.json is the regression baseline: no NaN


def test_every_claim_gets_a_verdict_that_follows_from_the_numbers(result) -> None:
    res, _ = result
    m = res.metrics
    assert len(res.claims) == len(R.load_paper("yi2009")["claims"])
    for c in res.claims:
        assert c["holds"] in (True, False), (c["id"], c["measured"])
        # a flag's measured text is "<flag> = yes/no": its numbers are in the note (why)
        assert re.search(r"\d", c["why"] if c["kind"] == "flag" else c["measured"]), c["id"]
        if c["holds"] is False:
            assert c["why"], c["id"]  # a failing claim carries a measured reason
        if c["kind"] == "ordering":
            vals = [m[k] for k in c["metrics"]]
            margin = m[c["margin"]] if c.get("margin") else 0.0  # the seeds' interval (fig5_6 order_margins)
            assert c["holds"] == all(a + margin < b for a, b in zip(vals, vals[1:]))
        elif c["kind"] == "within":
            assert c["holds"] == (abs(m[c["metric"]] - c["value"]) <= c["tolerance_abs"])


def test_files_are_written(result) -> None:
    res, out = result
    d = out / "yi2009"
    for tab in res.tables:
        assert (d / f"{tab['id']}.md").is_file() and (d / f"{tab['id']}.csv").is_file()
    for name in ("claims.md", "README.md", "fig4_points.md", "fig5_6_intervals.md"):
        assert (d / name).stat().st_size > 200, name
    assert len(res.figures) == 4
    for path, caption in res.figures:
        p = out / path
        assert p.suffix == ".png" and p.stat().st_size > 10_000 and p.read_bytes()[:4] == b"\x89PNG", path
        assert caption
    readme = (d / "README.md").read_text()
    assert "2.148" in readme
    for c in res.claims:
        assert c["text"] in readme


def test_s_gamma_fit_agrees_with_curve_fit_and_holds_a3(result) -> None:
    res, _ = result
    ev = res.info["_yi2009_evaluation"]
    g = np.array([abs(p["gamma"]) for p in ev.ident])
    s = np.array([p["s"] for p in ev.ident])
    assert len(g) == len(Y.SETTINGS.ident_quick_idx) == res.metrics["fig4.n_points"]
    assert res.metrics["fig4.a3"] == PUBLISHED_S_GAMMA.a3  # held, not fitted
    # second implementation: scipy curve_fit (LM, unbounded) with a3 fixed at 0.039
    (a1, a2), _ = curve_fit(lambda x, a1, a2: a1 / (a2 * x + 0.039), g, s, p0=[0.039 * s.mean(), 0.1],
                            maxfev=20000, xtol=1e-14, ftol=1e-14)
    if a2 >= 0:  # the plugin bounds a2 >= 0 (eq. (41): a_i > 0); compare where the bound is inactive
        assert res.metrics["fig4.a1_cm"] == pytest.approx(100 * a1, rel=1e-6)
        assert res.metrics["fig4.a2"] == pytest.approx(a2, rel=1e-5, abs=1e-9)
    fitted = res.metrics["fig4.a1_cm"] / 100 / (res.metrics["fig4.a2"] * g + 0.039)
    assert res.metrics["fig4.residual_rms_cm"] == pytest.approx(100 * np.sqrt(np.mean((fitted - s) ** 2)), rel=1e-9)
    assert res.metrics["fig4.s0_cm"] == pytest.approx(res.metrics["fig4.a1_cm"] / 0.039, rel=1e-12)
    # the reference-sensor S agrees with the testbed truth S (the vision method, not the physics, is checked)
    assert res.metrics["fig4.ref_vs_truth_rms_cm"] < 1.0


def test_identification_runs_are_not_scored_runs(result) -> None:
    res, _ = result
    ev = res.info["_yi2009_evaluation"]
    hashes = calibrated_on(ev.calibrated)
    assert len(hashes) == len(ev.ident)
    for pr in ev.paths.values():
        assert pr.run0.content_hash() not in hashes
    ident_scenarios = {r.split(" seed ")[0] for r in res.info["runs"] if r.startswith("yi_s_gamma")}
    calib = {(sid, int(seed)) for sid, seed in (r.split(" seed ") for r in res.info["runs"]) if sid.startswith("yi_calib")}
    scored = {r.split(" seed ")[0] for r in res.info["runs"] if not r.startswith(("yi_s_gamma", "yi_calib"))}
    assert ident_scenarios and scored == set(Y.PATHS.values())
    assert calib == set(Y.SETTINGS.nees_calibration)  # the consistent configuration's calibration runs (nees)


def test_position_table_is_a_mean_over_seeds_with_an_interval(result) -> None:
    res, _ = result
    ev = res.info["_yi2009_evaluation"]
    assert ev.seeds == Y.SETTINGS.seeds_quick
    for path, pr in ev.paths.items():
        for v in (1, 2, 3):
            per_seed = [s["rms"] for s in pr.scores[f"v{v}"]]
            m, lo, hi = (res.metrics[f"fig5_6.{path}.v{v}{x}"] for x in ("", ".ci_lo", ".ci_hi"))
            assert m == pytest.approx(np.mean(per_seed), rel=1e-12)
            half = stats.t.ppf(0.975, len(per_seed) - 1) * np.std(per_seed, ddof=1) / math.sqrt(len(per_seed))
            assert (lo, hi) == pytest.approx((m - half, m + half), rel=1e-9, abs=1e-12)


def _synthetic_turn(lam_l: float, lam_r: float, s_icr: float = 0.05, wl_rpm: float = 80.0, wr_rpm: float = 40.0,
                    duration: float = 10.0, counts_per_rev: int = 200000, pos_noise: float = 0.0, seed: int = 0):
    """Steady turn with known slips (eq. (6)), S (eq. (7)); IMU-rate grid 125 Hz, reference every 5th row
    (25 Hz), encoders as quantised count differences at every row."""
    r, track = PLATFORM["wheel_radius"], PLATFORM["track"]
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / 125.0)
    n = t.size
    wl, wr = np.full(n, wl_rpm * math.pi / 30), np.full(n, wr_rpm * math.pi / 30)
    v_l, v_r = (1 - lam_l) * r * wl, (1 - lam_r) * r * wr  # eq. (6)
    vx, wz = 0.5 * (v_l + v_r), (v_r - v_l) / track  # eqs. (3), (4)
    vy = -s_icr * wz  # eq. (7)
    x, y, yaw = integrate_se2(t, vx, vy, wz)
    q = 2 * math.pi / counts_per_rev

    def enc(w):
        c = np.floor(w * t / q)
        return np.concatenate(([0.0], np.diff(c) * q / np.diff(t)))

    ref = np.full((n, 3), np.nan)
    idx = np.arange(0, n, 5)
    ref[idx] = np.column_stack((x[idx], y[idx], (yaw[idx] + np.pi) % (2 * np.pi) - np.pi))
    ref[idx, :2] += pos_noise * rng.standard_normal((idx.size, 2))
    cols = dict(t=t, enc_wl=enc(wl), enc_wr=enc(wr), ref_x=ref[:, 0], ref_y=ref[:, 1], ref_yaw=ref[:, 2],
                truth_x=x, truth_y=y, truth_yaw=yaw, truth_vx=vx, truth_vy=vy, truth_wz=wz, truth_x_icr=np.full(n, s_icr))
    return from_arrays(cols, {"run_id": "synthetic-turn", "platform": PLATFORM})


def test_vision_slip_recovers_known_slips() -> None:
    """Steady turn with slips 0.10 / -0.20 and S = 5 cm, noise-free.  On a circle the SG derivative of
    the position shrinks the speed by c = sum_k h_k sin(w k h) / w (h_k the kernel, w the yaw rate);
    the yaw rate (linear yaw) is exact.  Expected slip = (r w_i - (c v_Gx -+ W/2 w))/(r w_i), eq. (6)."""
    from scipy.signal import savgol_coeffs

    run = _synthetic_turn(0.10, -0.20)
    t, lam = Y.vision_slip(run, window=1.0, polyorder=2)
    mid = (t > 1.0) & (t < t[-1] - 1.0)
    h, r, track = 0.04, PLATFORM["wheel_radius"], PLATFORM["track"]
    wz, v_gx = run["truth_wz"][0], run["truth_vx"][0]
    kern = savgol_coeffs(25, 2, deriv=1, delta=h, use="dot")  # dot-product order: kern @ x[k-12:k+13]
    c = float(np.sum(kern * np.sin(wz * h * np.arange(-12, 13))) / wz)
    rw = r * np.array([80.0, 40.0]) * math.pi / 30
    expected = (rw - (c * v_gx + np.array([-0.5, 0.5]) * track * wz)) / rw
    assert abs(c - 1.0) > 1e-3  # the bias is real at 0.5 rad/s ...
    assert np.allclose(lam[mid], expected, atol=2e-5)  # ... and exactly the closed form
    assert np.allclose(lam[mid], [0.10, -0.20], atol=0.015)  # a bias of ~1 slip point at 0.5 rad/s, 1 s window


def test_vision_slip_noise_matches_the_savitzky_golay_noise_gain() -> None:
    """Straight line, zero slip, reference position noise sigma: the slip noise is
    sigma * ||h|| / (r w) with h the SG first-derivative kernel (independent closed form)."""
    from scipy.signal import savgol_coeffs

    sigma = 0.0149
    run = _synthetic_turn(0.0, 0.0, s_icr=0.0, wl_rpm=30.0, wr_rpm=30.0, duration=60.0, pos_noise=sigma)
    t, lam = Y.vision_slip(run, window=1.0, polyorder=2)
    mid = (t > 1.0) & (t < t[-1] - 1.0)
    h = 0.04
    kernel = savgol_coeffs(int(round(1.0 / h)) | 1, 2, deriv=1, delta=h)
    expected = sigma * np.linalg.norm(kernel) / (PLATFORM["wheel_radius"] * math.pi)  # r w = r * 30 rpm
    assert np.std(lam[mid, 0]) == pytest.approx(expected, rel=0.15)


def test_vision_slip_names_the_missing_channel() -> None:
    run = _synthetic_turn(0.0, 0.0)
    bad = from_arrays({c: run[c] for c in run.channels if c != "ref_yaw"}, run.meta)
    with pytest.raises(RunError, match="ref_yaw"):
        Y.vision_slip(bad)


def test_slip_agreement_closed_form() -> None:
    t = np.linspace(0.0, 10.0, 501)
    ref = np.column_stack((0.1 * np.sin(t), -0.2 * np.cos(t)))
    same = Y.slip_agreement(t, ref, t, ref)
    assert same["rms"] == pytest.approx(0.0, abs=1e-15) and same["corr"] == pytest.approx(1.0)
    shifted = Y.slip_agreement(t, ref, t, ref + 0.03)
    assert shifted["rms"] == pytest.approx(0.03) and shifted["corr"] == pytest.approx(1.0)
    flipped = Y.slip_agreement(t, ref, t, -ref)
    assert flipped["corr"] == pytest.approx(-1.0) and flipped["rms"] == pytest.approx(2 * np.sqrt(np.mean(ref**2)))
    masked = Y.slip_agreement(t, ref, t, ref + 0.5 * (t > 5)[:, None], mask=t <= 5)
    assert masked["rms"] == pytest.approx(0.0, abs=1e-15)


def test_s_gamma_truth_point_closed_form() -> None:
    run = _synthetic_turn(0.05, -0.1, s_icr=0.07)
    g, s = Y.s_gamma_truth_point(run)
    r = PLATFORM["wheel_radius"]
    v_l, v_r = 0.95 * r * 80 * math.pi / 30, 1.1 * r * 40 * math.pi / 30
    assert g == pytest.approx((v_l - v_r) / (v_l + v_r), rel=1e-9)  # eq. (40)
    assert s == pytest.approx(0.07)


def test_mean_ci_closed_form() -> None:
    m, lo, hi = Y.mean_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    half = 2.7764451051977987 * math.sqrt(2.5) / math.sqrt(5)  # t_0.975(4) * s / sqrt(n)
    assert (m, lo, hi) == pytest.approx((3.0, 3.0 - half, 3.0 + half))
    assert all(math.isnan(v) for v in Y.mean_ci([1.0])[1:])


def test_gyro_roll_error_closed_form() -> None:
    """The direct integration of (10c) with a constant roll-rate bias b (no noise, no other rate, level start): roll(t)
    = b t, so its RMS against a zero truth roll over t in [t0, T] is b sqrt((T^3 - t0^3) / (3 (T - t0)))."""
    import dataclasses

    from methods.yi2009.repro.evaluation import gyro_roll_error
    from tests.methods.yi2009.synthetic import TESTBED, synthetic_run

    b = 2e-3
    sens = dataclasses.replace(TESTBED, acc_noise=0.0, gyr_noise=0.0, acc_bias=(0.0, 0.0, 0.0), gyr_bias=(b, 0.0, 0.0),
                               t_rest=0.0)
    run = synthetic_run("straight", 0, sens, knots_rpm=[(0, 30, 30), (10, 30, 30)])
    d = run.data.copy()
    d["truth_roll"] = 0.0
    run = from_arrays({c: d[c].to_numpy() for c in d.columns}, run.meta)
    t = run.t
    t0, t_end = 1.0, float(t[-1])
    m = t >= t0
    expected = float(np.sqrt(np.mean((b * t[m]) ** 2)))  # the same grid (forward Euler of a constant rate is exact)
    assert expected == pytest.approx(b * math.sqrt((t_end**3 - t0**3) / (3 * (t_end - t0))), rel=2e-3)
    assert gyro_roll_error(run, t0) == pytest.approx(expected, rel=1e-9)


def test_ordering_margin_is_the_paired_t_half_width() -> None:
    """fig5_6's ordering margins against scipy's paired t-test: the half-width h of the per-seed paired difference's
    95 % interval is the mean difference over the t statistic times t_{0.975, n-1}; the claims engine's ordering with
    that margin does not hold for a mean gap inside h (scheme 3 ahead of scheme 1 by a few mm, as on the '8')."""
    from methods.yi2009.repro.evaluation import PathResult
    from methods.yi2009.repro.figures import order_margins

    v1 = [0.10, 0.25, 0.12, 0.21, 0.106]
    v3 = [0.14, 0.17, 0.16, 0.15, 0.1501]
    v2 = [0.90, 0.85, 0.95, 0.88, 0.88]
    scores = {f"v{k}": tuple({"rms": x} for x in v) for k, v in ((1, v1), (2, v2), (3, v3))}
    pr = PathResult("figure8", (0, 1, 2, 3, 4), scores, {}, None, {}, (np.zeros(0), np.zeros(0)))
    m = order_margins(pr, "figure8")

    def half(a, b):
        d = np.subtract(b, a)
        t = stats.ttest_rel(b, a).statistic
        return float(np.mean(d) / t * stats.t.ppf(0.975, len(d) - 1))

    assert m["figure8.margin.v3_v1"] == pytest.approx(abs(half(v3, v1)), rel=1e-9)
    assert m["figure8.margin.order"] == pytest.approx(max(abs(half(v3, v2)), abs(half(v2, v1))), rel=1e-9)
    gap = np.mean(v1) - np.mean(v3)
    assert 0 < gap < m["figure8.margin.v3_v1"]  # ahead on the means, inside the seeds' interval
    from bench.reproduce.claims import evaluate_claim

    claim = {"id": "c", "text": "t", "kind": "ordering", "metrics": ["a", "b"], "margin": "m"}
    metrics = {"a": float(np.mean(v3)), "b": float(np.mean(v1)), "m": m["figure8.margin.v3_v1"]}
    assert evaluate_claim(claim, metrics)[0] is False
    assert evaluate_claim(claim, {**metrics, "m": 0.0})[0] is True  # without the margin it would hold
