"""The gap workflow fitted to several measured runs at once (bench.gap.segments): one model, each run replayed
from its own initial state, the residual spaces concatenated.  Expectations: an exact identity (a run fitted
twice over costs what it costs alone), the block layout of the concatenated time axis, and a hidden effect
named and fitted from two runs (and nothing named on two clean ones)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.gap import find_gap
from bench.gap.catalogue import nominal_config
from bench.gap.fit import Evaluator
from bench.gap import model as M
from bench.gap.regimes import regimes_for
from bench.gap.residuals import build_space
from bench.gap.segments import segment_evaluator
from bench.spec import load_scenario

SCN = "gap_test_coulomb"


def test_a_run_fitted_twice_over_costs_what_it_costs_alone(sim):
    """Two copies of one run: every channel's mean squared normalised residual is the single run's (same samples
    twice, same noise scales), so the concatenated cost equals the single run's for the nominal model and for a
    changed one; the second copy starts on a block boundary at least half a block after the first ends."""
    scn = load_scenario(SCN)
    run = sim(SCN, 140).without_truth()
    rscn, init = M.replay_scenario(run, scn)
    space = build_space(run, regimes_for(scn.platform))
    single = Evaluator(rscn, M.measured_grid(run, space.t, init, scn), space, M.testbed_trace)
    double = segment_evaluator([run, run], scn, workers=1)
    cfg = nominal_config(rscn)
    changed = cfg.with_overrides(**{"platform.wheel_radius_scale_r": 0.97})
    for c in (cfg, changed):
        assert double.cost(c) == pytest.approx(single.cost(c), rel=1e-12)
    sp = double.space
    end = max(float(space.t[c][-1]) for c in space.channels)
    assert sp.offsets[1] % sp.block == 0 and sp.offsets[1] - end >= 0.5 * sp.block
    assert all(sp.t[c].size == 2 * space.t[c].size for c in sp.channels)
    assert np.all(sp.row_block()[: sp.parts[0].meas[sp.channels[0]].size] < sp.offsets[1] / sp.block)


def test_two_different_runs_cost_the_pooled_sum_of_their_own_residuals(sim):
    """Two runs of one robot with other commands, seeds and starting headings (the second starts turned by 1 rad):
    the concatenated cost is sum_c w_c sum_k sum_i (r_kci / sigma_c)^2 / N_c, with each run's residual r_k from its
    own space (its pose aligned on its own start) and sigma_c the RMS of the runs' noise scales weighted by their
    sample counts; J_noise is the same pooling of the runs' own.  (Aligned on the joined axis instead, the second
    run's pose would be turned by the first's correction: a different cost.)"""
    scn = load_scenario("gap_dev_janosi")
    runs = [sim("gap_dev_janosi", 146).without_truth(), sim("gap_blind_turns", 147, initial_yaw=1.0).without_truth()]
    ev = segment_evaluator(runs, scn, workers=1)
    cfg = nominal_config(ev.scn)
    parts = [p.space for p in ev.parts]
    raws = [sp.raw(p.signals(cfg)) for sp, p in zip(parts, ev.parts)]
    expect, j_noise = 0.0, 0.0
    for c in ev.space.channels:
        n = np.array([sp.meas[c].size for sp in parts], float)
        sig = np.sqrt(np.sum(n * np.array([sp.sigma[c] for sp in parts]) ** 2) / n.sum())
        sig_hat = np.sqrt(np.sum(n * np.array([sp.sigma_hat[c] for sp in parts]) ** 2) / n.sum())
        z2 = sum(float(np.sum(np.nan_to_num(r[c] / sig) ** 2)) for r in raws)
        expect += parts[0].weight[c] * z2 / n.sum()
        j_noise += parts[0].weight[c] * (sig_hat / sig) ** 2
    assert ev.cost(cfg) == pytest.approx(expect, rel=1e-9)
    assert ev.space.j_noise == pytest.approx(j_noise, rel=1e-12)


def test_no_pose_growth_is_counted_across_the_start_of_a_run():
    """Run 1's heading error grows in regime "turn"; run 2 (regime "cruise") fits exactly.  Joined, the pose term
    from run 1's end to run 2's start would be the whole accumulated error in "cruise"; it is not counted: cruise
    has no excess, and the time profile has none in run 2."""
    from bench.gap.residuals import ResidualSpace, local_terms, regime_table, time_profile
    from bench.gap.segments import segment_space

    t = np.arange(120) * 0.05
    sigma = 0.003

    def part(reg: int, drift: float) -> ResidualSpace:
        return ResidualSpace(("ref_yaw",), {"ref_yaw": t}, {"ref_yaw": drift * t}, {"ref_yaw": sigma / 3},
                             {"ref_yaw": sigma}, {"ref_yaw": 1.0}, {"ref_yaw": np.full(t.size, reg)},
                             ("cruise", "turn"), ())

    sp = segment_space([part(1, 0.2), part(0, 0.0)])
    model = {"ref_yaw": np.zeros(2 * t.size)}
    z2 = local_terms(sp, sp.raw(model))["ref_yaw"][2]
    assert np.isnan(z2[t.size - 1]) and np.isfinite(z2[: t.size - 1]).all() and np.isfinite(z2[t.size:]).all()
    tab = regime_table(sp, model)
    assert tab["cruise"]["excess_cost"] == 0.0
    assert tab["turn"]["excess_cost"] == pytest.approx((0.2 * 0.05) ** 2 / (2 * sigma**2) - 1 / 9, rel=1e-9)
    centres, prof = time_profile(sp, model, bin_s=0.5)
    assert np.all(prof[centres > sp.offsets[1]] == 0.0)


def test_a_hidden_effect_is_named_and_fitted_from_two_runs(sim):
    """Right tires 5 % small (radius scale 0.95) in two runs of other seeds: named first, fitted within 20 % of the
    change, and two clean runs name nothing."""
    hidden = {"platform__wheel_radius_scale_r": 0.95}
    res = find_gap([sim(SCN, 141, **hidden), sim(SCN, 142, **hidden)], SCN, workers=1)
    assert res.named and res.named[0] == "wheel_radius", res.verdict
    assert res.effects[0]["parameters"]["radius_scale_r"] == pytest.approx(0.95, abs=0.01)
    clean = find_gap([sim(SCN, 143), sim(SCN, 144)], SCN, workers=1)
    assert clean.verdict == "no significant missing effect", clean.verdict


def test_several_runs_need_the_testbed_model(sim):
    with pytest.raises(ValueError, match="testbed model only"):
        find_gap([sim(SCN, 140), sim(SCN, 140)], SCN, model="yu2010.closed_loop")


def test_where_the_gap_sits_is_told_on_each_runs_own_clock(sim):
    """Two runs fitted together; the model's gyro made wrong by 0.2 rad/s in the second run only, between 3 and 5 s
    of that run's own time: the 2 s window of the largest excess is that run's [3, 5] s (not the joined axis's
    [offset + 3, offset + 5]), and the report text says so."""
    from bench.gap import _concentration
    from bench.gap.report import window_text

    scn = load_scenario(SCN)
    runs = [sim(SCN, 143).without_truth(), sim(SCN, 144).without_truth()]
    ev = segment_evaluator(runs, scn, workers=1)
    sp = ev.space
    parts = sp.split(ev.signals(nominal_config(ev.scn)))
    t2 = sp.parts[1].t["imu_gz"]
    parts[1]["imu_gz"] = parts[1]["imu_gz"] + 0.2 * ((t2 >= 3.0) & (t2 < 5.0))
    c = _concentration(sp, sp.join(parts), {})
    assert c["window_runs"] == [2, 2]
    assert c["window_s"] == pytest.approx([3.0, 5.0], abs=0.26)  # to the 0.5 s bins of the profile
    assert window_text(c).endswith(" s of run 2")
