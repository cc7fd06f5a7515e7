"""Yu 2010 reproduction (scenarios/papers/yu2010.toml, methods/yu2010/repro/).

One quick reproduction into a temporary results folder and run cache (module fixture); the tests
check the declaration against what the compute functions return, the transcription of Table I
against an independent transcription of the paper, the written files, and the helpers against
closed forms (rate-limited command, power-limited climbing speed, Yu's variation numbers).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bench import reproduce as R
from bench.registry import CalibrationLeak, estimate
from bench.run import from_arrays
from bench.reproduce.runner import Runner
from bench.spec import load_platform
from methods.yu2010 import ResistanceTable, YuParams, simulate_closed_loop
from methods.yu2010 import repro
from tests.conftest import run_cache

PAPER = Path("/work/shared/papers/yu2010_dynamic_model_closed_loop.md")

# Yu 2010 Table I, transcribed a second time from the paper (N: K [m], mu_sa, mu_op)
TABLE_I = {
    2: (0.00060, 0.4609, 0.3186), 3: (0.00051, 0.4567, 0.3193), 4: (0.00064, 0.4521, 0.3113),
    5: (0.00061, 0.4510, 0.3109), 6: (0.00059, 0.4400, 0.3083), 7: (0.00054, 0.4437, 0.3093),
    8: (0.00056, 0.4321, 0.3033), 11: (0.00054, 0.4323, 0.3061), 16: (0.00052, 0.4208, 0.2981),
    31: (0.00050, 0.4151, 0.2964),
}


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    return run_cache(tmp_path_factory, "yu_cache")


@pytest.fixture(scope="module")
def result(tmp_path_factory, cache_dir) -> tuple[R.PaperResult, Path]:
    out = tmp_path_factory.mktemp("yu_results")
    runner = Runner(cache_dir=cache_dir, workers=2)
    return R.reproduce_paper("yu2010", runner, out, quick=True, use_cache=False), out


# ----------------------------------------------------------------------------------- declaration
def test_declaration_loads_and_names_existing_functions() -> None:
    decl = R.load_paper("yu2010")
    assert decl["module"] == "methods.yu2010.repro"
    ids = [t["id"] for t in decl["tables"]]
    assert len(ids) == len(set(ids))
    for tab in decl["tables"]:
        assert callable(getattr(repro, tab["compute"]))
    claim_ids = [c["id"] for c in decl["claims"]]
    assert len(claim_ids) == len(set(claim_ids))
    for c in decl["claims"]:
        for mid in R.claim_metric_ids(c):
            assert mid.split(".")[0] in ids, (c["id"], mid)


def test_table_i_transcription_matches_the_paper() -> None:
    pub = repro.published_table1()
    assert len(pub) == 30
    for n, (k, sa, op) in TABLE_I.items():
        assert pub[f"K_N{n}"] == k and pub[f"mu_sa_N{n}"] == sa and pub[f"mu_op_N{n}"] == op


def test_yus_variation_is_relative_to_n2() -> None:
    # Sec. V-A: "16.7% for K, 9.9% for mu_sa, and 7.0% for mu_op" follow from Table I only when the
    # change from N = 2 to N = 31 is divided by the N = 2 value
    for j, pct in enumerate((0.167, 0.099, 0.070)):
        a, b = TABLE_I[2][j], TABLE_I[31][j]
        assert repro.variation(a, b) == pytest.approx(pct, abs=5e-4)
    assert abs(TABLE_I[2][0] - TABLE_I[31][0]) / TABLE_I[31][0] == pytest.approx(0.20)  # not /v(31)


# ----------------------------------------------------------------------------------- the run
def test_every_declared_row_and_claim_is_computed(result) -> None:
    res, _ = result
    for tab in res.tables:
        for row in tab["rows_out"]:
            assert row["metric"] in tab["all_metrics"], (tab["id"], row["metric"])
            assert np.isfinite(row["reproduced"]), (tab["id"], row["metric"])
    for c in res.claims:
        for mid in R.claim_metric_ids(c):
            assert mid in res.metrics, (c["id"], mid)
        assert c["holds"] is not None, c["id"]
        assert c["measured"] and c["measured"] != "missing metric"


def test_table_i_rows_carry_the_published_values(result) -> None:
    res, _ = result
    tabs = {t["id"]: t for t in res.tables}
    rows = {r["metric"]: r for r in tabs["table1"]["rows_out"]}
    assert tabs["table1"].get("published_on") == "real robot"  # Yu's robot: shown as ratios, never scored
    for n, (k, sa, op) in TABLE_I.items():
        got = tuple(rows[f"{p}_N{n}"]["published"] for p in ("K", "mu_sa", "mu_op"))
        assert got == (k, sa, op)
        assert rows[f"K_N{n}"]["verdict"].startswith("ratio")
    defs = {r["metric"]: r for r in tabs["table1_definition"]["rows_out"]}
    for p, pct in (("K", 0.167), ("mu_sa", 0.099), ("mu_op", 0.070)):  # the definition rows match Yu's percentages
        assert defs[f"pub_var_{p}"]["verdict"].startswith("matches")
        assert defs[f"pub_var_{p}"]["reproduced"] == pytest.approx(pct, abs=5e-4)
    m = res.metrics
    assert m["table1.K_calibrate"] == pytest.approx(m["table1.K_N31"], rel=1e-9)  # calibrate == N = 31 row
    assert 0 < m["table1.K_N31"] < 0.05 and 0 < m["table1.mu_op_N31"] < 1


def test_claim_verdicts_follow_the_numbers(result) -> None:
    res, _ = result
    m = res.metrics
    claims = {c["id"]: c for c in res.claims}
    ratio = m["fig14_16.rms_vx_closed"] / m["fig14_16.rms_vx_open"]
    assert claims["closed_beats_open"]["holds"] is (ratio < 1.0)
    assert claims["saturation_model"]["holds"] is (abs(m["fig17.v_final_model"] - m["fig17.v_final_tb"]) <= 0.01)
    assert claims["lemniscate_torque"]["holds"] is (m["fig22_29.rms_tau"] < m["fig22_29.rms_tau_rolling"])
    # the outcome codes agree with the speeds they summarise (OUTCOMES: holds, decelerates, fails, other)
    assert m["fig18_20.whiteboard_outcome_tb"] == repro.OUTCOMES.index("fails")
    assert m["fig18_20.whiteboard_v_final_tb"] <= 0
    for key in ("asphalt", "wood", "whiteboard"):
        same = m[f"fig18_20.{key}_outcome_tb"] == m[f"fig18_20.{key}_outcome_model"]
        assert bool(m[f"fig18_20.{key}_model_predicts"]) is same
        assert claims[f"ramp_{key}_model"]["holds"] is same
    if m["fig18_20.wood_outcome_tb"] == repro.OUTCOMES.index("decelerates"):
        assert m["fig18_20.wood_v_final_tb"] < m["fig18_20.wood_v0"]
    # the power limit slows the model on 15 deg: without it the model ends faster (Sec. V-B)
    assert m["fig18_20.wood_v_final_model_no_power_limit"] > m["fig18_20.wood_v_final_model"]


def _normalised(text: str) -> str:
    text = text.replace("$", "").replace("μ_{sa}", "μ_sa").replace("μ_{op}", "μ_op").replace(" ,", ",")
    return re.sub(r"\s+", " ", text)


def test_the_paper_claims_are_quoted_with_section_and_page() -> None:
    """Every claim of the paper gives section and page and quotes the paper verbatim: each piece of its quote
    (between '...' elisions, and around the one sentence Table II splits) is in the stored paper text."""
    if not PAPER.is_file():
        pytest.skip(f"{PAPER} not available")
    paper = _normalised(PAPER.read_text(encoding="utf-8"))
    for c in R.load_paper("yu2010")["claims"]:
        if c.get("scope", "paper") != "paper":
            continue
        assert "Sec." in c["source"] and "p." in c["source"], c["id"]
        assert 0 < len(c["quote"]) <= 300, c["id"]
        for piece in re.split(r"\.\.\.|(?<=only) (?=a small number)", c["quote"]):
            piece = _normalised(piece).strip(" .")
            assert piece in paper, (c["id"], piece[:60])


def test_every_claim_can_fail() -> None:
    """Each declared claim evaluated on numbers that violate it does not hold (and holds on numbers that meet
    it): no claim is encoded so that it cannot fail."""
    from bench.reproduce.claims import evaluate_claim

    for c in R.load_paper("yu2010")["claims"]:
        good, bad = _meeting_and_violating(c)
        assert evaluate_claim(c, good)[0] is True, c["id"]
        assert evaluate_claim(c, bad)[0] is False, c["id"]


def _meeting_and_violating(c: dict) -> tuple[dict, dict]:
    kind = c["kind"]
    if kind == "ordering":
        ids = c["metrics"]
        return ({m: float(i) for i, m in enumerate(ids)}, {m: float(-i) for i, m in enumerate(ids)})
    if kind == "ratio":
        v = float(c["value"])
        lo, hi = (0.5 * v, 1.5 * v) if c["op"] in ("<", "<=") else (1.5 * v, 0.5 * v)
        return {c["num"]: lo, c["den"]: 1.0}, {c["num"]: hi, c["den"]: 1.0}
    if kind == "trend":
        n = len(c["series"])
        step = 1.0 if c["direction"] == "increasing" else -1.0
        good = {m: step * i for i, m in enumerate(c["series"])}
        bad = dict(good)
        bad[c["series"][n // 2]] = good[c["series"][n // 2]] - step * (2.0 + float(c.get("tolerance", 0.0)))
        return good, bad
    if kind == "within":
        tol = c.get("tolerance_abs", abs(c["value"]) * c.get("tolerance_rel", 0.0))
        return {c["metric"]: c["value"] + 0.5 * tol}, {c["metric"]: c["value"] + 1.5 * tol + 1e-12}
    expect = bool(c.get("expect", True))
    return {c["metric"]: float(expect)}, {c["metric"]: float(not expect)}


def test_files_written(result) -> None:
    res, out = result
    d = out / "yu2010"
    for tab in res.tables:
        assert (d / f"{tab['id']}.md").is_file() and (d / f"{tab['id']}.csv").is_file()
    assert (d / "claims.md").is_file() and (d / "README.md").is_file()
    assert res.figures
    for path, caption in res.figures:
        assert (out / path).is_file() and (out / path).stat().st_size > 1000, path
        assert caption
    text = (d / "table1.md").read_text()
    assert "0.4609" in text and "not Yu's vinyl floor" in text


def test_result_pickles_without_the_runs(result) -> None:
    # the result cache pickles the PaperResult: the shared scratch (runs, model) must not go with it
    import pickle

    res, _ = result
    assert repro.MEMO_KEY not in res.info  # the runs live in ctx.scratch, which is not part of the result
    blob = pickle.dumps(res)
    assert len(blob) < 5_000_000


def test_calibration_and_scored_runs_differ(cache_dir) -> None:
    from bench.reproduce import Context

    ctx = Context(paper="yu2010", runner=Runner(cache_dir=cache_dir), out_dir=cache_dir / "unused", quick=True)
    ex = repro.experiments(ctx)  # served from the module's cache
    cal_runs = (*ex.sweep, ex.straight_cal, *ex.flat_cal.values(), *ex.lem_sweep, ex.lem_straight)
    cal = {r.content_hash() for r in cal_runs}
    scored = {r.content_hash() for r in ex.scored.values()}
    assert len(cal) == len(ex.sweep) + 1 + len(ex.flat_cal) + len(ex.lem_sweep) + 1 and not cal & scored
    assert {r.meta["terrain"]["name"] for r in ex.lem_sweep} == {ex.scored["yu_lemniscate"].meta["terrain"]["name"]}
    model = repro.calibrated(ctx).model
    with pytest.raises(CalibrationLeak):
        estimate(model, ex.sweep[3])
    with pytest.raises(CalibrationLeak):
        estimate(repro.calibrated_lemniscate(ctx), ex.lem_sweep[5])


# ----------------------------------------------------------------------------------- helpers
def test_ramped_command_is_a_rate_limited_step() -> None:
    r, accel = 0.1, 1.0
    t = np.round(np.arange(0, 2, 0.01), 10)
    enc = np.full_like(t, 1.0)
    enc[0] = 0.0  # a count-difference encoder reads 0 at the first stamp
    run = from_arrays({"t": t, "cmd_wl": np.full_like(t, 5.0), "cmd_wr": np.full_like(t, -2.0),
                       "enc_wl": enc, "enc_wr": enc}, {"run_id": "step"})
    out = repro.ramped_command(run, accel, r)
    slope = accel / r  # 10 rad/s^2, from the initial encoder speed 1 rad/s
    np.testing.assert_allclose(out["cmd_wl"], np.minimum(1.0 + slope * t, 5.0), atol=1e-12)
    np.testing.assert_allclose(out["cmd_wr"], np.maximum(1.0 - slope * t, -2.0), atol=1e-12)
    assert repro.ramped_command(run, 0.0, r) is run


def test_ramp_outcome_classes() -> None:
    t = np.linspace(0, 4, 401)
    res = 0.0767  # one encoder count per sample at 8192 counts/rev, 100 Hz
    w_cmd = 0.7 / 0.1075
    # at the commanded wheel speed within one count: holds, whatever the vehicle speed does (tire slip)
    near = np.full_like(t, w_cmd - 0.5 * res)
    assert repro.ramp_outcome(t, np.full_like(t, 0.66), near, w_cmd, 0.0, res)[0] == "holds"
    # wheels short of the command by more than a count, ending below the entry speed: decelerates
    w_cmd = 1.2 / 0.1075
    slow = np.full_like(t, 4.0)
    assert repro.ramp_outcome(t, 0.49 - 0.02 * t, slow, w_cmd, 0.49, res)[0] == "decelerates"
    assert repro.ramp_outcome(t, np.full_like(t, 0.489), slow, w_cmd, 0.49, res)[0] == "decelerates"
    assert repro.ramp_outcome(t, 0.5 + 0.02 * t, slow, w_cmd, 0.49, res)[0] == "other"
    falling = 0.57 - 0.5 * t
    v_end = float(np.mean(falling[t >= 3.5]))
    assert repro.ramp_outcome(t, falling, slow, w_cmd, 0.57, res) == ("fails", pytest.approx(v_end))
    assert repro.ramp_outcome(t, np.zeros_like(t), np.full_like(t, w_cmd), w_cmd, 0.57, res)[0] == "fails"  # stopped
    assert repro.monotone([3, 2, 2.005, 1], increasing=False, tol=0.01)
    assert not repro.monotone([3, 2, 2.05, 1], increasing=False, tol=0.01)


def test_skill_ratio_is_the_error_over_the_signal_spread() -> None:
    t = np.linspace(0.0, 6.0 * math.pi, 3000, endpoint=False)  # three whole periods
    meas = 0.2 + 0.05 * np.sin(t)
    assert repro.skill_ratio(meas, meas) == 0.0
    assert repro.skill_ratio(np.full_like(t, meas.mean()), meas) == pytest.approx(1.0)  # its own mean: 1
    # a constant offset d: RMS d over the RMS deviation 0.05 / sqrt(2)
    assert repro.skill_ratio(meas + 0.01, meas) == pytest.approx(0.01 / (0.05 / math.sqrt(2.0)), rel=1e-3)
    # two signals keep their own means: offsetting one of them by its mean difference is not "variation"
    two = np.vstack([meas, meas + 1.0])
    assert repro.skill_ratio(two, two) == 0.0
    assert repro.skill_ratio(np.vstack([meas, meas]) + np.array([[0.0], [1.0]]), two) == 0.0


def test_motor_power_limit_sets_the_climbing_speed() -> None:
    """Yu's 'motor power limitations': climbing a 15 deg slope with |tau_m w_m| <= P_max per motor,
    the steady wheel speed is n P_max / tau, tau = m g r (sin b + mu_roll cos b) / 2 per side."""
    q = YuParams().with_platform(load_platform("p3at_pneumatic_20psi"))
    assert q.P_max == 10.0 and q.side_power == 20.0  # from the platform's motor.max_power
    beta = math.radians(15.0)
    q = q.replace(slope=beta)
    need = q.m * q.g * q.r * (math.sin(beta) + q.mu_roll * math.cos(beta)) / 2
    w_cmd = 1.2 / q.r
    w0 = 0.49 / q.r
    res = simulate_closed_loop([0, 6], [w_cmd, w_cmd], [w_cmd, w_cmd], q, w0=(w0, w0),
                               table=ResistanceTable.build(q, 1024))
    w_power = q.side_power / need
    assert w_power < w0 < q.saturation_wheel_speed(need)  # power, not voltage, limits: it decelerates
    assert res.wl[-1] == pytest.approx(w_power, rel=1e-4)
    assert np.all(np.abs(res.tau_l * res.wl) <= q.side_power * (1 + 1e-12))
    free = simulate_closed_loop([0, 6], [w_cmd, w_cmd], [w_cmd, w_cmd], q.replace(P_max=0.0), w0=(w0, w0),
                                table=ResistanceTable.build(q, 1024))
    assert free.wl[-1] > w0  # without the limit the model accelerates up the 15 deg ramp
    with pytest.raises(ValueError, match="P_max"):
        YuParams(P_max=-1.0)


def test_initial_wheel_speed_within_one_count_is_rest() -> None:
    """The first count difference after t0 is the initial wheel speed, except within one count per sample of 0
    (2 pi / counts_per_rev x rate_hz = 1.2566 rad/s here), which is rest: a wheel starting under a ramp reads one
    count in its first sample.  Without the encoder spec no reading is rounded."""
    from methods.yu2010.plugin import initial_wheel_speeds

    t = np.round(np.arange(0, 1, 0.01), 10)
    one = 2 * np.pi / 500 * 100
    enc_spec = {"platform": {"sensors": {"encoder": {"counts_per_rev": 500, "rate_hz": 100.0}}}}

    def run_with(wl1: float, wr1: float, meta: dict):
        wl, wr = np.zeros_like(t), np.zeros_like(t)
        wl[1:], wr[1:] = wl1, wr1
        return from_arrays({"t": t, "enc_wl": wl, "enc_wr": wr}, {"run_id": "init", **meta})

    assert initial_wheel_speeds(run_with(one, -one, enc_spec)) == (0.0, 0.0)
    assert initial_wheel_speeds(run_with(2 * one, one, enc_spec)) == pytest.approx((2 * one, 0.0))
    assert initial_wheel_speeds(run_with(one, one, {})) == pytest.approx((one, one))
    assert initial_wheel_speeds(from_arrays({"t": t}, {"run_id": "no encoders"})) == (0.0, 0.0)
