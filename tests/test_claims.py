"""The claims engine: every claim kind fails on numbers that violate it and holds on numbers that satisfy it (edges:
equality, the margin, the tolerance boundary, NaN); every claim encoded in scenarios/papers/*.toml can fail and can
hold; the result that would fail a claim; the checks of a declaration (errors name file, claim, field and value);
calibration targets from the parameter sources; numbers published on a real robot; the report's size and cells."""
from __future__ import annotations

import json
import math
import re
import textwrap
import tomllib
from pathlib import Path
from typing import Any

import pytest

from bench import reproduce as R
from bench.reproduce.claims import check_claim, needs_tolerance_origin
from bench.reproduce.paper import FULL_RUN, FULL_RUN_QUOTED, PaperResult, claim_result
from bench.reproduce.report import CELL_LIMIT, cell, long_cells, write_paper, write_report
from bench.reproduce.runner import Runner
from bench.spec import SpecError

NAN = math.nan
PAPERS = Path(__file__).resolve().parents[1] / "scenarios" / "papers"


def ev(claim, **metrics):
    return R.evaluate_claim(claim, {f"t.{k}": v for k, v in metrics.items()})[0]


# ------------------------------------------------------------------------------------------ each kind
def test_ordering_holds_only_strictly_and_beyond_its_margin():
    c = {"kind": "ordering", "metrics": ["t.a", "t.b", "t.c"]}
    assert ev(c, a=1.0, b=2.0, c=3.0) is True
    assert ev(c, a=3.0, b=2.0, c=1.0) is False          # reversed
    assert ev(c, a=1.0, b=3.0, c=2.0) is False          # the second step violated
    assert ev(c, a=1.0, b=1.0, c=2.0) is False          # equality is not "<"
    assert ev(c, a=1.0, b=NAN, c=2.0) is None           # NaN: not evaluated
    assert ev(c, a=1.0, b=2.0) is None                  # missing: not evaluated
    m = {"kind": "ordering", "metrics": ["t.a", "t.b"], "margin": "t.m"}
    assert ev(m, a=1.0, b=2.0, m=0.5) is True
    assert ev(m, a=1.0, b=2.0, m=1.0) is False          # a + margin == b: inside the sampling error
    assert ev(m, a=1.0, b=2.0, m=1.5) is False
    assert ev(m, a=1.0, b=2.0, m=NAN) is None


@pytest.mark.parametrize("op, at, past, inside", [("<", 0.5, 0.6, 0.4), ("<=", 0.5, 0.6, 0.4),
                                                   (">", 0.5, 0.4, 0.6), (">=", 0.5, 0.4, 0.6)])
def test_ratio_at_and_past_its_value(op, at, past, inside):
    c = {"kind": "ratio", "num": "t.n", "den": "t.d", "op": op, "value": 0.5}
    assert ev(c, n=inside * 2, d=2.0) is True
    assert ev(c, n=past * 2, d=2.0) is False
    assert ev(c, n=at * 2, d=2.0) is (op in ("<=", ">="))  # the value itself: only the non-strict operators
    assert ev(c, n=NAN, d=2.0) is None and ev(c, n=1.0, d=NAN) is None
    assert ev(c, n=1.0, d=0.0) is None                     # no ratio, never a verdict
    m = {**c, "margin": "t.m"}  # the ratio's interval must clear the value: inside*2/2 is 0.1 from it
    assert ev(m, n=inside * 2, d=2.0, m=0.05) is True
    assert ev(m, n=inside * 2, d=2.0, m=0.15) is False     # the value inside the ratio's interval
    assert ev(m, n=past * 2, d=2.0, m=0.0) is False
    assert ev(m, n=inside * 2, d=2.0, m=NAN) is None


def test_refuted_only_when_the_whole_interval_is_on_the_failing_side():
    """A failing claim with a margin: refuted when its interval clears the bound on the failing side, not refuted
    when the bound lies inside it; None for a holding claim, one without a margin and one not evaluated."""
    def rf(claim, **metrics):
        return R.refuted(claim, {f"t.{k}": v for k, v in metrics.items()})
    o = {"kind": "ordering", "metrics": ["t.a", "t.b"], "margin": "t.m"}
    assert rf(o, a=1.0, b=2.0, m=0.5) is None                 # holds
    assert rf(o, a=2.0, b=1.0, m=0.5) is True                 # b - a = -1, interval [-1.5, -0.5]
    assert rf(o, a=1.2, b=1.0, m=0.5) is False                # interval [-0.7, 0.3] holds 0
    assert rf(o, a=1.0, b=1.5, m=0.5) is False                # a + m == b: fails, but not refuted
    assert rf({"kind": "ordering", "metrics": ["t.a", "t.b"]}, a=2.0, b=1.0) is None  # no interval
    assert rf(o, a=2.0, b=1.0, m=NAN) is None                 # not evaluated
    three = {"kind": "ordering", "metrics": ["t.a", "t.b", "t.c"], "margin": "t.m"}
    assert rf(three, a=1.0, b=1.1, c=0.0, m=0.5) is True      # refuted at the second step
    for op in ("<", "<="):
        r = {"kind": "ratio", "num": "t.n", "den": "t.d", "op": op, "value": 0.966, "margin": "t.m"}
        assert rf(r, n=0.9698, d=1.0, m=0.0225) is False       # Liu's mi_vs_ukf: 0.9473 .. 0.9923 holds 0.966
        assert rf(r, n=1.312, d=1.0, m=0.0194) is True
        assert rf(r, n=0.9, d=1.0, m=0.01) is None
    for op in (">", ">="):
        r = {"kind": "ratio", "num": "t.n", "den": "t.d", "op": op, "value": 1.0, "margin": "t.m"}
        assert rf(r, n=0.95, d=1.0, m=0.1) is False and rf(r, n=0.8, d=1.0, m=0.1) is True
    assert rf({"kind": "ratio", "num": "t.n", "den": "t.d", "op": "<=", "value": 0.5}, n=0.9, d=1.0) is None
    w = {"kind": "within", "metric": "t.x", "value": 1.0, "tolerance_abs": 0.1, "margin": "t.m"}
    assert rf(w, x=1.0, m=0.05) is None                       # [0.95, 1.05] inside the band [0.9, 1.1]: holds
    assert rf(w, x=2.0, m=0.1) is True                        # [1.9, 2.1]: wholly outside
    assert rf(w, x=1.15, m=0.1) is False                      # [1.05, 1.25] reaches into the band
    assert rf(w, x=1.05, m=0.1) is False                      # the point inside, the interval wider than the band
    fav = {"kind": "within", "metric": "t.x", "value": 1.0, "tolerance_abs": 0.1, "margin": "t.m"}
    assert R.favours(fav, {"t.x": 1.05, "t.m": 0.1}) is True and R.favours(fav, {"t.x": 1.15, "t.m": 0.1}) is False
    # Mandow's y_icr_v_behind as committed before its margin: -2.4 +- 10.3 mm against -12 +- 4 mm: not refuted
    y = {"kind": "within", "metric": "t.x", "value": -0.012, "tolerance_abs": 0.004, "margin": "t.m"}
    assert R.evaluate_claim(y, {"t.x": -0.002353, "t.m": 0.0103})[0] is False and rf(y, x=-0.002353, m=0.0103) is False
    assert rf(y, x=0.01, m=0.0103) is True and R.evaluate_claim(y, {"t.x": -0.012, "t.m": 0.003})[0] is True
    # a negative half-width (a defect of a metric) never widens the band or narrows an ordering's gap
    assert R.evaluate_claim(y, {"t.x": -0.02, "t.m": -0.01})[0] is False
    assert R.evaluate_claim(o, {"t.a": 1.0, "t.b": 0.9, "t.m": -0.5})[0] is False


def test_trend_direction_step_tolerance_and_end_points():
    dec = {"kind": "trend", "series": ["t.a", "t.b", "t.c"], "direction": "decreasing", "tolerance": 0.125}
    assert ev(dec, a=3.0, b=2.0, c=1.0) is True
    assert ev(dec, a=1.0, b=2.0, c=3.0) is False                      # reversed
    assert ev(dec, a=3.0, b=3.125, c=1.0) is True                     # a rise of exactly the tolerance
    assert ev(dec, a=3.0, b=3.25, c=1.0) is False                     # a rise beyond it
    assert ev(dec, a=2.0, b=2.0625, c=2.0) is False                   # no net decrease: last == first
    assert ev(dec, a=3.0, b=NAN, c=1.0) is None
    inc = {"kind": "trend", "series": ["t.a", "t.b"], "direction": "increasing"}
    assert ev(inc, a=1.0, b=2.0) is True and ev(inc, a=2.0, b=1.0) is False and ev(inc, a=1.0, b=1.0) is False


def test_within_tolerance_boundary_absolute_and_relative():
    a = {"kind": "within", "metric": "t.x", "value": 1.0, "tolerance_abs": 0.25}
    assert ev(a, x=1.25) is True and ev(a, x=0.75) is True           # on the boundary
    assert ev(a, x=1.2500001) is False and ev(a, x=0.7499999) is False
    assert ev(a, x=NAN) is None
    r = {"kind": "within", "metric": "t.x", "value": -4.0, "tolerance_rel": 0.25}
    assert ev(r, x=-5.0) is True and ev(r, x=-3.0) is True           # 25 % of |-4|
    assert ev(r, x=-5.001) is False and ev(r, x=-2.999) is False


def test_flag_expectation_and_nan():
    assert ev({"kind": "flag", "metric": "t.f"}, f=1.0) is True
    assert ev({"kind": "flag", "metric": "t.f"}, f=0.0) is False
    assert ev({"kind": "flag", "metric": "t.f", "expect": False}, f=0.0) is True
    assert ev({"kind": "flag", "metric": "t.f", "expect": False}, f=1.0) is False
    assert ev({"kind": "flag", "metric": "t.f"}, f=NAN) is None


def test_fails_if_states_the_negation_of_each_kind():
    assert R.fails_if({"kind": "ordering", "metrics": ["t.a", "t.b"], "margin": "t.m"}) == "t.a + t.m >= t.b"
    assert R.fails_if({"kind": "ordering", "metrics": ["t.a", "t.b", "t.c"]}) == "t.a >= t.b or t.b >= t.c (at some step)"
    for op, neg in (("<", ">="), ("<=", ">"), (">", "<="), (">=", "<")):
        assert R.fails_if({"kind": "ratio", "num": "t.n", "den": "t.d", "op": op, "value": 0.95}) == f"t.n / t.d {neg} 0.95"
    assert R.fails_if({"kind": "ratio", "num": "t.n", "den": "t.d", "op": "<=", "value": 0.9, "margin": "t.m"}) == \
        "t.n / t.d + t.m > 0.9"
    assert R.fails_if({"kind": "ratio", "num": "t.n", "den": "t.d", "op": ">", "value": 1.0, "margin": "t.m"}) == \
        "t.n / t.d - t.m <= 1"
    assert R.fails_if({"kind": "trend", "series": ["t.a", "t.b"], "direction": "decreasing", "tolerance": 0.01}) == \
        "a step of the series rises by more than 0.01, or t.b >= t.a"
    assert R.fails_if({"kind": "trend", "series": ["t.a", "t.b"], "direction": "increasing"}) == \
        "a step of the series falls, or t.b <= t.a"
    assert R.fails_if({"kind": "within", "metric": "t.x", "value": 0.93, "tolerance_rel": 0.05}) == \
        "t.x outside [0.8835, 0.9765]"
    assert R.fails_if({"kind": "within", "metric": "t.x", "value": 0.0, "tolerance_abs": 0.05}) == "t.x outside [-0.05, 0.05]"
    assert R.fails_if({"kind": "flag", "metric": "t.f"}) == "t.f is false (0)"
    assert R.fails_if({"kind": "flag", "metric": "t.f", "expect": False}) == "t.f is true (non-zero)"


def test_verdicts():
    assert R.verdict(True) == "holds" and R.verdict(False) == "does not hold" and R.verdict(None) == "not evaluated"
    assert R.verdict(True, ["vinyl.shear_modulus"]) == R.verdict(False, ["x"]) == "calibration target"
    assert R.verdict(None, ["x"]) == "not evaluated"


# ------------------------------------------------------------------------------------------ every encoded claim
def violating(c):
    """Metrics that violate the claim, from its own kind and fields (assigned by metric id, so a claim reading one
    metric twice gets the same number twice)."""
    kind = c["kind"]
    if kind == "ordering":  # reversed
        m = {mid: float(len(c["metrics"]) - k) for k, mid in enumerate(c["metrics"])}
        if "margin" in c:
            m.setdefault(c["margin"], 0.0)
        return m
    if kind == "ratio":  # just past the value (den 1: the ratio is the numerator exactly)
        v, op = float(c["value"]), c.get("op", "<=")
        num = {"<": v, "<=": math.nextafter(v, math.inf), ">": v, ">=": math.nextafter(v, -math.inf)}[op]
        return {c["den"]: 1.0, c["num"]: num, **({c["margin"]: 0.0} if "margin" in c else {})}
    if kind == "trend":  # reversed, each step beyond the tolerance
        sign = 1.0 if c.get("direction", "decreasing") == "decreasing" else -1.0
        step = 2.0 * float(c.get("tolerance", 0.0)) + 1.0
        return {mid: sign * step * k for k, mid in enumerate(c["series"])}
    if kind == "within":  # outside the tolerance
        v = float(c["value"])
        tol = float(c["tolerance_abs"]) if "tolerance_abs" in c else float(c.get("tolerance_rel", 0.1)) * abs(v)
        return {c["metric"]: v + 2.0 * tol + 1.0, **({c["margin"]: 0.0} if "margin" in c else {})}
    if kind == "flag":  # inverted
        return {c["metric"]: 0.0 if c.get("expect", True) else 1.0}
    raise AssertionError(kind)


def satisfying(c):
    kind = c["kind"]
    if kind == "ordering":
        m = {mid: 10.0 * k for k, mid in enumerate(c["metrics"])}
        if "margin" in c:
            m.setdefault(c["margin"], 1.0)
        return m
    if kind == "ratio":
        v, op = float(c["value"]), c.get("op", "<=")
        return {c["den"]: 1.0, c["num"]: v - 1.0 if op in ("<", "<=") else v + 1.0,
                **({c["margin"]: 0.5} if "margin" in c else {})}
    if kind == "trend":
        sign = -1.0 if c.get("direction", "decreasing") == "decreasing" else 1.0
        return {mid: sign * k for k, mid in enumerate(c["series"])}
    if kind == "within":
        return {c["metric"]: float(c["value"]), **({c["margin"]: 0.0} if "margin" in c else {})}
    if kind == "flag":
        return {c["metric"]: 1.0 if c.get("expect", True) else 0.0}
    raise AssertionError(kind)


def _encoded_claims():
    out = []
    for path in sorted(PAPERS.glob("*.toml")):
        with open(path, "rb") as fh:
            decl = tomllib.load(fh)
        out += [(path.stem, c.get("id")) for c in decl.get("claims", [])]
    return out


@pytest.mark.parametrize("paper, claim_id", _encoded_claims())
def test_every_encoded_claim_can_fail_and_can_hold(paper, claim_id):
    """No encoded claim is one that cannot fail: numbers built from its own kind and fields to violate it give
    "does not hold" (and numbers built to satisfy it give "holds": a claim that can never hold is as broken)."""
    claim = next(c for c in R.load_paper(paper)["claims"] if c["id"] == claim_id)
    bad = violating(claim)
    assert R.evaluate_claim(claim, bad)[0] is False, f"{paper}.{claim_id} cannot fail: {bad}"
    good = satisfying(claim)
    assert R.evaluate_claim(claim, good)[0] is True, f"{paper}.{claim_id} cannot hold: {good}"


def test_the_mutation_builders_catch_a_claim_that_cannot_fail():
    """The builders are not vacuous: a ratio of a metric to itself (always 1) under "< 2", and a within claim with an
    infinite tolerance, cannot fail, and the violating numbers do not make them fail."""
    for c in ({"kind": "ratio", "num": "t.x", "den": "t.x", "op": "<", "value": 2.0},
              {"kind": "within", "metric": "t.x", "value": 0.0, "tolerance_abs": math.inf}):
        assert R.evaluate_claim(c, violating(c))[0] is not False


# ------------------------------------------------------------------------------------------ declaration checks
BASE = {"id": "c1", "text": "x", "kind": "ratio", "num": "t1.a", "den": "t1.b", "op": "<", "value": 1.0}


def _check(**fields):
    return check_claim("papers/p.toml", 0, {**BASE, **fields}, ["t1"])


@pytest.mark.parametrize("fields, field, value", [
    ({"scope": "ours"}, "claims.c1.scope", "ours"),
    ({"cause": {"kind": "implementation", "text": "a bug"}}, "claims.c1.cause.kind", "implementation"),
    ({"cause": {"kind": "method", "text": "y" * 301}}, "claims.c1.cause.text", None),
    ({"cause_quick": {"kind": "implementation", "text": "a bug"}}, "claims.c1.cause_quick.kind", "implementation"),
    ({"cause_quick": {"kind": "protocol", "text": " "}}, "claims.c1.cause_quick.text", " "),
    ({"quote": "q" * 301}, "claims.c1.quote", None),
    ({"headline": True, "value": 0.95}, "claims.c1.tolerance_origin", None),
    ({"headline": True, "scope": "beyond"}, "claims.c1.scope", "beyond"),
    ({"op": "<<"}, "claims.c1.op", "<<"),
    ({"headline": "yes"}, "claims.c1.headline", "yes"),
    ({"headline": False, "tolerance_orign": "typo"}, "claims.c1.tolerance_orign", "typo"),
])
def test_a_malformed_claim_is_a_one_line_error_naming_file_claim_field_and_value(fields, field, value):
    with pytest.raises(SpecError) as ei:
        _check(**fields)
    e = ei.value
    assert e.field == field and "papers/p.toml" in str(e) and "c1" in str(e) and "\n" not in str(e)
    if value is not None:
        assert e.value == value and repr(value) in str(e)
    else:
        assert len(str(e)) < 400  # a 301-character text is named by its start and length, not copied whole


def test_new_requirements_are_warnings_until_a_claim_sets_headline():
    w = _check(value=0.95)
    assert len(w) == 1 and "claims.c1.tolerance_origin" in w[0] and "0.95" in w[0]
    assert _check(value=0.95, tolerance_origin="the paper's spread, Table 2") == []
    assert _check(value=0.95, scope="beyond") == []            # our own checks need no origin
    assert _check(headline=True) == []                         # a plain comparison with 1 needs none
    assert _check(headline=True, quote="q" * 300, cause={"kind": "paper", "text": "t" * 300}) == []
    within = {"kind": "within", "metric": "t1.a", "value": 0.0}
    assert any("tolerance_abs" in x for x in check_claim("p.toml", 0, {**BASE, **within, "tolerance_origin": "s"},
                                                          ["t1"]))
    assert needs_tolerance_origin({"kind": "trend", "tolerance": 0.0}) is None
    assert needs_tolerance_origin({"kind": "ordering", "margin": "t.m"}) == "margin"


def test_reproduce_exits_2_on_a_malformed_paper_before_any_run(tmp_path, monkeypatch, capsys):
    from bench.cli import main

    d = tmp_path / "papers"
    d.mkdir()
    (d / "bad.toml").write_text(textwrap.dedent('''
        paper = "bad"
        module = "tests.fixtures.fake_paper"
        [[tables]]
        id = "t1"
        compute = "straight"
        [[claims]]
        id = "slip_latch"
        text = "x"
        kind = "flag"
        metric = "t1.flag_true"
        cause = {kind = "implementation", text = "our bug"}
    '''))
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", d)
    assert main(["reproduce", "bad", "--results", str(tmp_path / "r"), "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.toml" in err and "claims.slip_latch.cause.kind" in err
    assert "'implementation'" in err and not (tmp_path / "r" / "bad").exists()


def test_reproduce_check_lists_warnings_without_running(tmp_path, monkeypatch, capsys):
    from bench.cli import main

    d = tmp_path / "papers"
    d.mkdir()
    (d / "p.toml").write_text(FAKE.replace('metrics = ["t1.speed", "t1.double"]',
                                           'metrics = ["t1.speed", "t1.double"]\nmargin = "t1.double"', 1)
                              .replace("headline = true\nkind = \"ordering\"", "kind = \"ordering\"", 1))
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", d)
    monkeypatch.setattr("bench.reproduce.calibration_targets", lambda: {})  # the shipped sources name real papers' claims
    assert main(["reproduce", "--check", "--results", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "claims.order.tolerance_origin" in out and "1 paper declaration(s) checked: no error, 1 warning(s)" in out
    assert not (tmp_path / "r").exists()


# ------------------------------------------------------------------------------------------ calibration targets
def _sources(tmp_path):
    plat, terr = tmp_path / "platforms", tmp_path / "terrains"
    plat.mkdir()
    terr.mkdir()
    (terr / "vinyl.toml").write_text(textwrap.dedent('''
        name = "vinyl"
        shear_modulus = 0.003
        mu_sa = 0.44
        [sources]
        mu_sa = {kind = "paper", ref = "Yu 2010 Table II"}
        shear_modulus = {kind = "chosen", ref = "K = 3 mm gives Wang's trend", claims = ["p.order", "q.other"]}
    '''))
    (plat / "robot.toml").write_text(textwrap.dedent('''
        name = "robot"
        [motor]
        max_power = 10.0
        [sources]
        "motor.max_power" = {kind = "chosen", ref = "ramp power limited", claims = ["p.order"]}
        [sources.motor]
        max_current = {kind = "datasheet", ref = "Maxon"}
    '''))
    (plat / "old.toml").write_text('name = "old"\nmass = 1.0\n')  # no [sources] yet
    return (plat, terr)


def test_calibration_targets_from_chosen_sources(tmp_path):
    dirs = _sources(tmp_path)
    names = {(s.name, s.kind) for s in R.parameter_sources(dirs)}
    assert names == {("vinyl.mu_sa", "paper"), ("vinyl.shear_modulus", "chosen"), ("robot.motor.max_power", "chosen"),
                     ("robot.motor.max_current", "datasheet")}
    t = R.calibration_targets(dirs)
    assert sorted(t) == ["p.order", "q.other"]
    assert sorted(s.name for s in t["p.order"]) == ["robot.motor.max_power", "vinyl.shear_modulus"]
    assert R.calibration_targets((tmp_path / "platforms",))["p.order"][0].file == "platforms/robot.toml"


def test_the_shipped_parameter_sources_name_declared_claims():
    """Today's platform and terrain files are read (with or without [sources]); every claim a chosen parameter lists
    is a claim some paper declares (a renamed claim would silently stop being a calibration target)."""
    declared = {f"{p}.{cid}" for p, cid in _encoded_claims()}
    unknown = {c: [s.name for s in srcs] for c, srcs in R.calibration_targets().items() if c not in declared}
    assert unknown == {}


FAKE = textwrap.dedent('''
    paper = "p"
    title = "A fake paper"
    module = "tests.fixtures.fake_paper"
    [[tables]]
    id = "t1"
    title = "Real robot numbers"
    compute = "straight"
    published_on = "real robot"
      [[tables.rows]]
      metric = "speed"
      published = 0.4
      tolerance_rel = 0.05
    [[claims]]
    id = "order"
    text = "speed < double"
    headline = true
    kind = "ordering"
    metrics = ["t1.speed", "t1.double"]
    [[claims]]
    id = "fails"
    text = "double < speed"
    headline = true
    kind = "ordering"
    metrics = ["t1.double", "t1.speed"]
    cause = {kind = "testbed", text = "the testbed lacks tire deflection"}
''')


def reproduce_fake(tmp_path: Path, monkeypatch) -> tuple[Path, Any]:
    """The FAKE paper reproduced into ``tmp_path / "results"`` with its parameter sources: (results folder, result)."""
    d = tmp_path / "papers"
    d.mkdir()
    (d / "p.toml").write_text(FAKE)
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", d)
    monkeypatch.setattr("bench.reproduce.sources.SOURCE_DIRS", _sources(tmp_path))
    out = tmp_path / "results"
    res, = R.reproduce(["p"], results_dir=out, cache_dir=tmp_path / "cache" / "runs", log=lambda s: None)
    return out, res


def test_calibration_target_and_real_robot_table_in_the_written_report(tmp_path, monkeypatch):
    out, res = reproduce_fake(tmp_path, monkeypatch)
    claims = {c["id"]: c for c in res.claims}
    assert claims["order"]["holds"] is True and claims["order"]["verdict"] == "calibration target"
    assert claims["fails"]["verdict"] == "does not hold" and claims["fails"]["refuted"] is None  # no margin
    report = (out / "REPORT.md").read_text()
    assert "not refuted: inside its 95 % interval" not in report.split("## Headline claims")[1]
    assert "vinyl.shear_modulus" in report and "robot.motor.max_power" in report
    assert "testbed: the testbed lacks tire deflection" in report
    assert re.search(r"headline claims \(2\): holding 0; failing 1 \(testbed 1\); calibration targets 1", report)
    table = (out / "p" / "t1.md").read_text()
    speed = res.metrics["t1.speed"]
    assert "reproduced / published" in table and f"{speed / 0.4:.4g}" in table
    assert "matches" not in table and "differs" not in table
    assert R.load_paper("p")["tables"][0]["published_on"] == "real robot"
    import json
    doc = json.loads((out / "claims.json").read_text())["claims"]
    assert sorted(doc["p.order"]["calibration"]) == ["robot.motor.max_power", "vinyl.shear_modulus"]
    assert doc["p.fails"]["cause"] == {"kind": "testbed", "text": "the testbed lacks tire deflection"}


def test_unknown_published_on_is_refused(tmp_path, monkeypatch):
    d = tmp_path / "papers"
    d.mkdir()
    (d / "p.toml").write_text(FAKE.replace('"real robot"', '"robot"'))
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", d)
    with pytest.raises(SpecError, match="tables.t1.published_on"):
        R.load_paper("p")


# ------------------------------------------------------------------------------------------ report size
def test_cell_shortens_to_the_limit_and_links_the_rest():
    assert cell("a | b\nc") == "a \\| b c"
    long = "First sentence here. " + "word " * 200
    got = cell(long, more="x/claims_details.md#claim-a")
    assert len(got) <= CELL_LIMIT and got.endswith("… [more](x/claims_details.md#claim-a)")
    assert got.startswith("First sentence here.")
    assert len(cell("`code " + "y" * 400 + "`")) <= CELL_LIMIT
    assert long_cells("| a | " + "z" * 301 + " |\n| b \\| c |") == ["z" * 301]


def _fake_result(i: int, n_claims: int = 20) -> PaperResult:
    paper = f"paper{i}"
    tab = {"id": "t1", "title": "A table", "rows": [], "rows_out": [
        {"metric": f"m{k}", "label": "l" * 400, "reproduced": float(k), "published": 1.0,
         "verdict": R.row_verdict(float(k), {"published": 1.0, "tolerance_abs": 0.5})} for k in range(5)],
        "all_metrics": {f"m{k}": float(k) for k in range(5)}}
    metrics = {f"t1.m{k}": float(k) for k in range(5)}
    kinds = [{"kind": "ordering", "metrics": ["t1.m1", "t1.m2"]}, {"kind": "ordering", "metrics": ["t1.m2", "t1.m1"]},
             {"kind": "flag", "metric": "t1.m0"}, {"kind": "within", "metric": "t1.m3", "value": 3.0, "tolerance_abs": 0.1}]
    notes, decl = {}, []
    for k in range(n_claims):
        c = {"id": f"c{k}", "text": f"claim {k}: " + "t" * 350, "source": "Sec. 3, p. 4 " * 40,
             "headline": k < 12, "scope": "beyond" if k >= 17 else "paper", **kinds[k % 4]}
        if k == 5:
            c["cause"] = {"kind": "method", "text": "the testbed has load transfer " + "m" * 270}
        decl.append(c)
        notes[f"c{k}"] = "A long note. " + "n" * 2000
    claims = [claim_result(paper, c, metrics, notes) for c in decl]
    return PaperResult(paper, {"paper": paper, "title": "T" * 400, "claims": decl}, metrics, [tab], claims,
                       [], notes, 1.0, {"seeds": [0, 1], "runs": ["a seed 0"]})


def test_report_of_5_papers_x_20_claims_with_2000_character_notes_stays_short(tmp_path):
    """No table cell of any written file over 300 characters; REPORT.md under 300 lines; each README opens with its
    headline claims; the whole note is in claims_details.md, linked from the cells."""
    results = [_fake_result(i) for i in range(5)]
    for res in results:
        write_paper(res, tmp_path / res.paper)
    path = write_report(results, tmp_path, False, Runner(cache_dir=tmp_path / "cache"), 1.0)
    report = path.read_text()
    assert len(report.splitlines()) < 300
    for f in sorted(tmp_path.rglob("*.md")):
        assert long_cells(f.read_text()) == [], f
    head = report[report.index("## Headline claims"):report.index("## Per paper")]
    assert head.count("| [paper") == 5 * 12                   # every headline claim, none other
    assert "method: the testbed has load transfer " + "m" * 100 in head and "**no cause given**" in head
    readme = (tmp_path / "paper0" / "README.md").read_text()
    assert readme.index("### Headline claims") < readme.index("### Other claims") < readme.index("### Checks beyond")
    assert readme.index("### Headline claims") < readme.index("### Tables")
    details = (tmp_path / "paper0" / "claims_details.md").read_text()
    assert '<a id="claim-c7"></a>' in details and "n" * 2000 in details
    assert "(claims_details.md#claim-c7)" in readme
    assert "- checks beyond the paper (3)" in report and "- headline claims (12)" in report


def test_committed_results_have_no_table_cell_over_the_limit() -> None:
    """Every markdown file under results/ as committed (the paper reports, the real-data and gap reports, the
    league, the quick run): no table cell over CELL_LIMIT characters."""
    root = Path(__file__).resolve().parents[1] / "results"
    files = sorted(root.rglob("*.md"))
    assert files
    bad = {str(f.relative_to(root)): [c[:60] for c in long_cells(f.read_text())] for f in files}
    assert {k: v for k, v in bad.items() if v} == {}


@pytest.mark.parametrize("name", ["claims.json", "quick/claims_quick.json", "extended/claims.json"])
def test_committed_failing_claims_carry_a_cause(name: str) -> None:
    """The shipped verdicts (results/ as committed): every claim that does not hold, of the paper or a check beyond
    it, names its cause, of one of the four kinds, with a text."""
    path = Path(__file__).resolve().parents[1] / "results" / name
    claims = json.loads(path.read_text())["claims"]
    failing = {k: v for k, v in claims.items() if v["verdict"] == "does not hold"}
    assert failing
    bad = {k: v["cause"] for k, v in failing.items()
           if not v["cause"] or v["cause"].get("kind") not in ("method", "testbed", "protocol", "paper")
           or not v["cause"].get("text", "").strip()}
    assert bad == {}
    # a cause quoting a metric the run did not compute would show "[no metric ...]"
    assert {k for k, v in failing.items() if "[no metric" in v["cause"]["text"]} == set()


def test_a_cause_quotes_this_runs_numbers_and_a_quick_run_says_whose_reason_it_shows():
    """{metric} / {metric:fmt} in a cause text is the run's value (format as Python's; default .4g); a metric the run
    lacks is marked, not guessed; a quick run without cause_quick shows the full run's reason, marked."""
    claim = {"id": "c", "kind": "ordering", "metrics": ["a", "b"],
             "cause": {"kind": "method", "text": "a = {a:.2f} against b = {b}; net {n:.1%}; {gone}"}}
    metrics = {"a": 2.0, "b": 1.0 / 3.0, "n": -0.0027}
    got = claim_result("p", claim, metrics, {})
    assert got["holds"] is False
    assert got["cause"]["text"] == "a = 2.00 against b = 0.3333; net -0.3%; [no metric gone]"
    quick = claim_result("p", claim, metrics, {}, quick=True)["cause"]
    assert quick == {**got["cause"], "of": FULL_RUN_QUOTED}
    plain = {**claim, "cause": {"kind": "method", "text": "0.5 vs 0.4"}}
    assert claim_result("p", plain, metrics, {}, quick=True)["cause"]["of"] == FULL_RUN
    own = {**claim, "cause_quick": {"kind": "method", "text": "quick: {a:.1f}"}}
    assert claim_result("p", own, metrics, {}, quick=True)["cause"] == {"kind": "method", "text": "quick: 2.0"}


@pytest.mark.parametrize("text, field", [("x {t.a:.2q}", "format"), ("x {t.a} and a stray } brace", "braces"),
                                         ("{t.a:.3f} " * 60, "as shown"), ("x" * 294 + "{t.a:.2g}", "as shown"),
                                         ("x {zz.a}", "declared table")])
def test_a_bad_quoted_metric_is_a_one_line_error(text: str, field: str) -> None:
    """A bad format, a stray brace, a metric of an undeclared table, or a text over 300 characters as shown (a quoted
    number counted at the longest its format prints: .2g of 1.2e-05 takes 8 characters, 294 + 8 > 300)."""
    claim = {"id": "c", "text": "t", "source": "s", "kind": "ordering", "metrics": ["t.a", "t.b"],
             "cause": {"kind": "method", "text": text}}
    with pytest.raises(SpecError, match=re.escape(field)) as e:
        check_claim(Path("p.toml"), 0, claim, ["t"])
    assert "\n" not in str(e.value) and "claims.c.cause.text" in str(e.value)
    fine = {**claim, "cause": {"kind": "method", "text": "x" * 292 + "{t.a:.2g}"}}
    assert check_claim(Path("p.toml"), 0, fine, ["t"]) == []


def test_a_quoted_metric_that_is_not_a_finite_number_says_so():
    from bench.reproduce.claims import fill_numbers
    import numpy as np

    got = fill_numbers("{a} {b} {c:.1f} {d} {e}", {"a": math.nan, "b": math.inf, "c": np.float32(2.25), "d": True})
    assert got == "[a: nan] [b: inf] 2.2 [no metric d] [no metric e]"


@pytest.mark.parametrize("name", ["claims.json", "quick/claims_quick.json", "extended/claims.json"])
def test_committed_causes_are_at_most_300_characters_as_printed(name: str) -> None:
    claims = json.loads((Path(__file__).resolve().parents[1] / "results" / name).read_text())["claims"]
    assert {k: len(c["cause"]["text"]) for k, c in claims.items()
            if c.get("cause") and len(c["cause"]["text"]) > 300} == {}


def test_a_failing_claim_inside_its_interval_is_marked_not_refuted_in_the_report():
    from bench.reproduce.report import NOT_REFUTED, NOT_RESOLVED, _counts, _verdict

    inside = {"verdict": "does not hold", "holds": False, "refuted": False, "cause": {"kind": "protocol", "text": "x"}}
    beyond = {**inside, "refuted": True}
    plain = {**inside, "refuted": None}
    assert _verdict(inside) == f"**does not hold** ({NOT_REFUTED})"
    assert _verdict({**inside, "favours": True}) == f"**does not hold** ({NOT_RESOLVED})"
    assert _verdict({**beyond, "favours": True}) == "**does not hold**"  # refuted: favours is moot
    assert _verdict(beyond) == _verdict(plain) == "**does not hold**"
    assert _verdict({"verdict": "holds", "holds": True, "refuted": False}) == "**holds**"
    assert _counts([inside, beyond, {"verdict": "holds", "holds": True}]) == \
        "holding 1; failing 2 (protocol 2, 1 of them not refuted (inside the interval))"
    assert _counts([beyond]) == "holding 0; failing 1 (protocol 1)"
    assert _counts([inside, {**inside, "favours": True}]) == \
        "holding 0; failing 2 (protocol 2, 2 of them not refuted (inside the interval; the means favour the claim in 1))"


def test_a_redirected_reproduce_logs_whole_lines_without_markup(tmp_path, monkeypatch, capsys):
    """Off a terminal the log goes to stderr line by line, a long line unwrapped and "[m/s]" kept (rich markup would
    eat a bracketed word and wrap at 80 columns), and stdout stays empty of it."""
    from bench.cli import main

    title = "Real robot numbers, speed [m/s] over the straight, " + " ".join(["a long title"] * 8)
    d = tmp_path / "papers"
    d.mkdir()
    (d / "p.toml").write_text(FAKE.replace('title = "Real robot numbers"', f'title = "{title}"', 1))
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", d)
    monkeypatch.setattr("bench.reproduce.sources.SOURCE_DIRS", _sources(tmp_path))
    assert main(["reproduce", "p", "--results", str(tmp_path / "r"), "--workers", "1"]) == 0
    cap = capsys.readouterr()
    assert any(line.endswith(title) for line in cap.err.splitlines()), cap.err
    assert title not in cap.out
