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
