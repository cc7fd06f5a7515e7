"""Tests of bench.real.gap: the gap workflow with the testbed's husky model on the real DRIVE data.

Skipped with a message when the real table is absent (``SKIDBENCH_DATA``, as tests/test_drive.py).
Independent expectations: the step structure recomputed from the raw table; the held-out residuals
of the gyro and the encoders recomputed here from the testbed's physics trace with an own sampling
(not bench.gap's residual space), through the importer's per-step Runs (not the module's block
Runs), with the spec overrides the workflow reports for its effects.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.real.drive import import_drive
from bench.gap.catalogue import get
from bench.gap import model as gap_model
from bench.real.gap import CONTINUITY, SCENARIO, GapRunConfig, run_real_gap
from bench.spec import load_scenario, replace
from tests.test_strict_json import strict_loads
from tests.test_drive import N, husky_df, raw  # noqa: F401  (fixture)

SMALL = GapRunConfig(n_fit=1, n_test=2, max_effects=1)
CANDIDATES = tuple(get(n) for n in ("wheel_radius", "friction", "encoder_scale", "gyro_bias"))


@pytest.fixture(scope="module")
def slice30(husky_df: pd.DataFrame, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("gap") / "husky_slice30.parquet"
    husky_df.iloc[:30].to_parquet(path)
    return path


@pytest.fixture(scope="module")
def gap_run(slice30: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    out = tmp_path_factory.mktemp("gapout")
    res = run_real_gap(slice30, out, config=SMALL, catalogue=CANDIDATES, workers=1, figure=False)
    res["out"] = out
    return res


def _own_residuals(run, scn, overrides, enc_scale=(0.0, 0.0), gyro_bias=0.0, gyro_scale=1.0,
                   latency=0.0) -> dict[str, np.ndarray]:
    """measured - model for imu_gz and the encoders: the model's yaw rate interpolated at the gyro's
    sample times (+ bias); its wheel angle differenced over each encoder sample interval (the wheel speeds the
    DRIVE logger wrote again between the 10 Hz reports left out)."""
    rscn, _ = gap_model.replay_scenario(run, scn)
    tr = gap_model.testbed_trace(rscn, overrides)
    out = {}
    t = run.t
    g = run["imu_gz"]
    ok = np.isfinite(g)
    out["imu_gz"] = g[ok] - (gyro_scale * np.interp(t[ok], tr["t"], tr["wz"]) + gyro_bias)
    wl, wr = run["enc_wl"], run["enc_wr"]  # a pair equal to the previous one (not at rest) is the logger's repeat
    held = np.r_[False, (wl[1:] == wl[:-1]) & (wr[1:] == wr[:-1]) & ((wl[1:] != 0) | (wr[1:] != 0))]
    period = float(np.median(np.diff(t[np.isfinite(wl) & ~held])))
    for c, th, e in (("enc_wl", "th_l", enc_scale[0]), ("enc_wr", "th_r", enc_scale[1])):
        v = run[c]
        ok = np.isfinite(v) & ~held
        tt = t[ok]
        w0 = tr["w_init"][0 if c == "enc_wl" else 1]  # the wheel's start speed before the trace (a latency)
        tq = tt - latency
        ang = np.where(tq < tr["t"][0], tr[th][0] + w0 * (tq - tr["t"][0]), np.interp(tq, tr["t"], tr[th]))
        prev_t = np.r_[tt[0] - period, tt[:-1]]
        prev_a = np.r_[ang[0], ang[:-1]]
        out[c] = v[ok] - (ang - prev_a) / (tt - prev_t) * (1.0 + e)
    return out


def test_steps_split_and_files(gap_run: dict, husky_df: pd.DataFrame) -> None:
    doc = gap_run["doc"]
    fit, held = doc["fit_steps"], doc["held_out_steps"]
    assert len(fit) == 1 and len(held) == 2 and not set(fit) & set(held)
    # fit on the calibration half, held out from the test half of the real benchmark's split
    from bench.real.benchmark import split_steps

    calib, test = split_steps(_windows(husky_df.iloc[:30]), 0)
    assert set(fit) <= set(calib.tolist()) and set(held) <= set(test.tolist())
    names = sorted(p.name for p in gap_run["out"].iterdir())
    assert names == ["husky_gap.json", "husky_gap.md"]
    disk = strict_loads((gap_run["out"] / "husky_gap.json").read_text())
    assert disk["workflow"]["verdict"] == doc["workflow"]["verdict"] and "runtime_s" not in json.dumps(disk)
    md = (gap_run["out"] / "husky_gap.md").read_text()
    assert doc["workflow"]["verdict"] in md


def _windows(df: pd.DataFrame):
    import tempfile

    from bench.real.drive import import_drive_windows

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "s.parquet"
        df.to_parquet(p)
        return import_drive_windows(p)


def test_named_or_not_is_consistent(gap_run: dict) -> None:
    wf = gap_run["doc"]["workflow"]
    kind = wf["verdict_kind"]
    if kind == "missing_effect":
        assert wf["effects"] and not wf["partial_candidates"]
        assert all(e["name"] in wf["verdict"] for e in wf["effects"])
    elif kind == "no_significant_effect":
        assert not wf["effects"] and not wf["partial_candidates"]
    else:
        assert kind == "unexplained_residual" and not wf["effects"]
    # the cost the workflow reports can only come down from the nominal (the nominal is a candidate)
    assert wf["cost"]["final"] <= wf["cost"]["nominal"] + 1e-9


def test_held_out_residuals_recomputed(gap_run: dict, slice30: Path) -> None:
    """The held-out gyro and encoder gaps before/after, recomputed independently, match the report;
    the channels the report says the fitted model improves are improved in the recomputation.  The final model is
    the steady command response's platform fields (the JSON's ``applied``: what it changed in the platform) with the effects on top, replayed
    from the initial state that model settles on."""
    doc = gap_run["doc"]
    wf = doc["workflow"]
    runs = {r.meta["calib_step"]: r for r in import_drive(slice30, "husky")}
    scn = load_scenario(SCENARIO)
    steady = {k: (math.inf if v is None else v) for k, v in doc["command_response"]["applied"].items()}
    scn_after = replace(scn, platform=replace(scn.platform, **steady)) if steady else scn
    turn = doc["turn_response"]["overrides"]  # the steady turn response: catalogue fields, dotted
    scn_after = replace(scn_after, **turn) if turn else scn_after
    transient = dict(doc["transient_response"]["overrides"])  # the transient response: the latency is recomputed here
    lat = transient.pop("platform.sensors.encoder.latency", 0.0)
    transient = {k: (math.inf if v == "inf" else v) for k, v in transient.items()}
    scn_after = replace(scn_after, **transient) if transient else scn_after
    # the fit block's effects, unless the calibration steps outside it rejected them (then the start model is final)
    kept = wf["effects"] + wf["partial_candidates"] if doc["validation"]["kept"] else []
    over, enc, bias, gain = {}, [0.0, 0.0], 0.0, 1.0
    for e in kept:
        if e["name"] == "encoder_scale":
            enc = [e["parameters"]["scale_error_l"], e["parameters"]["scale_error_r"]]
        elif e["name"] == "gyro_bias":
            bias = e["parameters"]["gyro_bias_z"]
        elif e["name"] == "gyro_scale":
            gain = e["parameters"]["gyro_scale_z"]
        elif e["name"] == "encoder_latency":
            lat += e["parameters"]["latency"]
        elif e["name"] != "imu_mounting":  # the accelerometer only: not among the channels recomputed here
            over.update(e["overrides"])
    pooled = {k: {c: [] for c in ("imu_gz", "enc_wl", "enc_wr")} for k in ("before", "after")}
    for s in doc["held_out_steps"]:
        run = runs[s]
        for key, model, args in (("before", scn, ({}, (0.0, 0.0), 0.0)),
                                 ("after", scn_after, (over, tuple(enc), bias, gain, lat))):
            for c, r in _own_residuals(run, model, *args).items():
                pooled[key][c].append(r)
    ch = doc["held_out"]["channels"]
    for c in ("imu_gz", "enc_wl", "enc_wr"):
        rb = float(np.sqrt(np.mean(np.concatenate(pooled["before"][c]) ** 2)))
        ra = float(np.sqrt(np.mean(np.concatenate(pooled["after"][c]) ** 2)))
        assert ch[c]["rms_before"] == pytest.approx(rb, rel=1e-6), c
        assert ch[c]["rms_after"] == pytest.approx(ra, rel=1e-6), c
        if ch[c]["change_percent"] < -0.5:  # the report claims an improvement on held-out data
            assert ra < rb, c
    if not kept and not steady and not turn and not transient and not lat:
        assert all(ch[c]["rms_after"] == ch[c]["rms_before"] for c in ch)


def test_fit_block_steps_follow_in_time(husky_df: pd.DataFrame) -> None:
    """bench.real.gap.fit_block against the raw table: adjacent rows, wheel speeds continuous."""
    from bench.real.gap import continuous_with_previous, fit_block

    w = _windows(husky_df.iloc[:60])
    cont = continuous_with_previous(w)
    wl, wr = raw(husky_df.iloc[:60], "left_wheel_vel"), raw(husky_df.iloc[:60], "right_wheel_vel")
    for step, ok in cont.items():
        rows = np.flatnonzero(w.calib_step == step)
        if rows[0] == 0:
            assert not ok
            continue
        i = rows[0]
        jump = max(abs(wl[i, 0] - wl[i - 1, N - 1]), abs(wr[i, 0] - wr[i - 1, N - 1]))
        assert ok == (jump <= CONTINUITY)
    steps = [int(s) for s in np.unique(w.calib_step)]
    block = fit_block(w, steps, 3)
    assert all(cont[s] for s in block[1:])


def test_command_tracking_slopes() -> None:
    """Synthetic steady windows whose wheels run at 1.5 x the commanded half-sum and 0.4 x the
    commanded difference: the slopes come back; the yaw-rate maxima are the arrays' own."""
    from tests.test_real import B, R, make_windows
    from bench.real.gap import command_tracking

    rng = np.random.default_rng(5)
    cl, cr = rng.uniform(-8, 8, (30, 1)), rng.uniform(-8, 8, (30, 1))
    s, d = 1.5 * (cl + cr) / 2, 0.4 * (cr - cl)
    el, er = np.repeat(s - d / 2, N, axis=1), np.repeat(s + d / 2, N, axis=1)
    w = make_windows(el, er)
    ch = dict(w.channels, cmd_wl=np.repeat(cl, N, axis=1), cmd_wr=np.repeat(cr, N, axis=1),
              imu_gz=np.full((30, N), 0.7))
    import dataclasses

    f = command_tracking(dataclasses.replace(w, channels=ch), R, B)
    assert f["slope_sum"] == pytest.approx(1.5, abs=1e-9) and f["slope_difference"] == pytest.approx(0.4, abs=1e-9)
    assert f["max_abs_gyro_rate"] == 0.7
    assert f["max_abs_cmd_yaw_rate_ideal"] == pytest.approx(R * np.max(np.abs(cr - cl)) / B)


def test_a_zero_gap_prints_zero_percent_not_nan(gap_run: dict) -> None:
    """A channel with no gap before or after (e.g. a perfect sensor) reads "+0%" in both tables of the report."""
    import copy

    from bench.real.gap_report import _markdown

    doc = copy.deepcopy(gap_run["doc"])
    ch = next(iter(doc["workflow"]["gap_before"]))
    doc["workflow"]["gap_before"][ch]["rms"] = doc["workflow"]["gap_after"][ch]["rms"] = 0.0
    row = doc["held_out"]["channels"][ch]
    row["rms_before"], row["rms_after"], row["change_percent"] = 0.0, 0.0, float("nan")
    md = _markdown(doc, False, "x_gap")
    lines = [ln for ln in md.splitlines() if ln.startswith(f"| {ch} |")]
    assert len(lines) == 2 and all("| +0% |" in ln and "nan" not in ln for ln in lines), lines


def test_per_step_ratio_and_steps_not_lowered(gap_run: dict) -> None:
    """The report's per-step summary: quartiles of final / nominal cost (numpy's percentile of the per-step
    costs, a second computation) and the ids of the steps whose cost the final model does not lower."""
    doc = gap_run["doc"]
    hc = doc["held_out"]["cost"]
    before = np.array([p["before"] for p in hc["per_step"]])
    after = np.array([p["after"] for p in hc["per_step"]])
    assert hc["ratio_quartiles"] == pytest.approx(np.percentile(after / before, [25, 50, 75]), rel=1e-12)
    worse = [s for s, b, a in zip(doc["held_out_steps"], before, after) if a >= b]
    assert hc["steps_improved"] == len(before) - len(worse)
    md = (gap_run["out"] / "husky_gap.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("Per step, final / nominal cost"))
    if worse:
        assert line.rstrip(".").split("not lowered on ")[1].split(" ", 1)[1] == ", ".join(map(str, worse))
    else:
        assert line.endswith("lowered on every step.")


def test_stall_diagnostic_in_the_document_and_report(gap_run: dict) -> None:
    """The stall diagnostic (bench.real.stall) sits beside the held-out score: per step the robot's and the final
    model's motion ratio, the stalled steps are those whose measured ratio is below the threshold, the others'
    ratio of mean costs recomputed from the per-step costs; the report names the steps."""
    doc = gap_run["doc"]
    hc, st = doc["held_out"]["cost"], doc["held_out"]["stalls"]
    meas = [p["motion_measured"] for p in hc["per_step"]]
    assert all(0.0 <= m < 2.0 for m in meas) and all(0.0 <= p["motion_final"] < 2.0 for p in hc["per_step"])
    stalled = [s for s, m in zip(doc["held_out_steps"], meas) if m < st["threshold"]]
    assert st["steps"] == stalled
    rest = [p for p, m in zip(hc["per_step"], meas) if m >= st["threshold"]]
    if rest:
        assert st["others_final_over_nominal"] == pytest.approx(
            np.mean([p["after"] for p in rest]) / np.mean([p["before"] for p in rest]), rel=1e-12)
    md = (gap_run["out"] / "husky_gap.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("**Stalls**"))
    assert (f"steps {', '.join(map(str, stalled))};" in line) if stalled else "stalls." in line


def test_bounded_run_holds_out_every_test_step() -> None:
    """make reproduce scores the whole test half, not a subset of it (issue 32: 100 Husky steps)."""
    from bench.real.gap import BOUNDED, FULL

    assert BOUNDED.n_test is None and FULL.n_test is None
    assert "every test-half step" in BOUNDED.describe()


def test_steps_not_lowered_are_named_by_their_ids(gap_run: dict) -> None:
    """The report names the held-out steps the final model does not lower (ties count as not lowered), by their
    step ids in held-out order, and prints the quartiles it was given."""
    import copy

    from bench.real.gap_report import _markdown

    doc = copy.deepcopy(gap_run["doc"])
    steps = doc["held_out_steps"]
    hc = doc["held_out"]["cost"]
    assert len(steps) == len(hc["per_step"]) == 2
    for ids, after in (([steps[1]], (0.5, 1.0)), (steps, (1.0, 1.0))):
        for p, a in zip(hc["per_step"], after):
            p["before"], p["after"] = 1.0, a
        hc["ratio_quartiles"] = [0.125, 0.25, 0.375]
        line = next(x for x in _markdown(doc, False, "x_gap").splitlines() if x.startswith("Per step"))
        word = "step" if len(ids) == 1 else "steps"
        assert line.endswith(f"not lowered on {word} {', '.join(map(str, ids))}."), line
        assert "median 0.25 (quartiles 0.125-0.375)" in line, line


def test_validation_keeps_the_fit_blocks_effects_only_if_they_lower_the_mean_cost(monkeypatch) -> None:
    """bench.real.gap.validate: kept exactly when the mean cost with the effects is below the start model's over the
    calibration steps outside the fit block (here one step lowered 10 -> 8 and one raised 10 -> 13: mean 10.5, not
    kept; the nominal key when there is no start model); nothing is simulated without effects."""
    from types import SimpleNamespace

    import bench.real.gap as G

    def fake(costs):
        it = iter(costs)
        return lambda *a, **k: {"cost": next(it)}

    res = SimpleNamespace(effects=[{"name": "x"}], partial=[])
    monkeypatch.setattr(G, "step_residuals", fake([{"start": 10.0, "after": 8.0}, {"start": 10.0, "after": 13.0}]))
    v = G.validate([None, None], None, res, start=object())
    assert v == {"n_steps": 2, "kept": False, "start_mean": 10.0, "final_mean": 10.5, "steps_lowered": 1}
    monkeypatch.setattr(G, "step_residuals", fake([{"before": 10.0, "after": 8.0}, {"before": 10.0, "after": 11.0}]))
    assert G.validate([None, None], None, res)["kept"] is True
    monkeypatch.setattr(G, "step_residuals", fake([]))  # would raise StopIteration if called
    assert G.validate([None], None, SimpleNamespace(effects=[], partial=[]))["kept"] is True


def test_a_rejected_fit_leaves_the_start_model_as_final(gap_run: dict, slice30: Path) -> None:
    """step_residuals(keep=False): the final model is the start model, cost for cost (and the nominal model is not
    simulated with nominal=False); with keep=True the fit block's effects are on top (a different cost when it kept
    any)."""
    from bench.real.held_out import step_residuals

    res, doc = gap_run["result"], gap_run["doc"]
    run = {r.meta["calib_step"]: r for r in import_drive(slice30, "husky")}[doc["held_out_steps"][0]]
    scn = load_scenario(SCENARIO)
    start = replace(scn, platform=replace(scn.platform, command_gain_sum=1.5))
    off = step_residuals(run, scn, res, start, keep=False)["cost"]
    assert off["after"] == off["start"]
    assert "before" not in step_residuals(run, scn, res, start, keep=False, nominal=False)["cost"]
    on = step_residuals(run, scn, res, start)["cost"]
    assert on["start"] == off["start"]
    if res.effects or res.partial:
        assert on["after"] != off["after"]
