"""Strict JSON (RFC 8259) for everything skidbench writes: a non-finite float is null (NaN) or the
string "inf" / "-inf", read back by bench.report.io.json_number, bench.spec.build and compare."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.cli.reproduce import compare_metrics
from bench.report.io import dumps_json, json_number, json_safe
from bench.sim import scenario_hash
from bench.spec import Scenario, build, load_scenario, replace, to_dict

RESULTS = Path(__file__).resolve().parents[1] / "results"


def strict_loads(text: str):
    """json.loads refusing NaN / Infinity / -Infinity, as JavaScript's JSON.parse does (used by the
    tests of every writer of results JSON)."""
    def refuse(name: str):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=refuse)


def test_non_finite_floats_become_null_or_inf_strings_and_read_back():
    obj = {"a": math.nan, "b": [math.inf, -math.inf, 1.5, 2], "c": {"d": np.float64("nan"), "e": np.float32(-np.inf)},
           "f": (True, None, "x")}
    text = dumps_json(obj, sort_keys=True)
    back = strict_loads(text)
    assert back == {"a": None, "b": ["inf", "-inf", 1.5, 2], "c": {"d": None, "e": "-inf"}, "f": [True, None, "x"]}
    assert math.isnan(json_number(back["a"])) and json_number(back["b"][0]) == math.inf
    assert json_number(back["b"][1]) == -math.inf and json_number(back["b"][2]) == 1.5
    assert json_number("a string") is None and json_number([1]) is None
    # finite values are left as they are, so every finite number is written as before
    finite = {"x": [0.1, 3], "y": "z"}
    assert json_safe(finite) == finite and dumps_json(finite) == json.dumps(finite)
    with pytest.raises(ValueError):
        strict_loads('{"v": NaN}')  # the check itself refuses what the old writer produced


def test_scenario_with_infinite_limits_round_trips_through_strict_json():
    """runs_manifest.json stores the scenario specs: "inf" must rebuild the same scenario (same hash)."""
    scn = load_scenario("liu_straight")
    assert math.isinf(scn.platform.command_limit_mean)  # the default: no command limit
    data = strict_loads(dumps_json(to_dict(scn)))
    assert data["platform"]["command_limit_mean"] == "inf"
    again = build(Scenario, data)
    assert again == scn and scenario_hash(again) == scenario_hash(scn)
    limited = replace(scn, platform=replace(scn.platform, command_limit_mean=4.0))
    assert build(Scenario, strict_loads(dumps_json(to_dict(limited)))) == limited


def test_a_string_other_than_inf_in_a_float_field_is_still_refused():
    from bench.spec import SpecError

    data = strict_loads(dumps_json(to_dict(load_scenario("liu_straight"))))
    data["platform"]["command_limit_mean"] = "infinite"
    with pytest.raises(SpecError, match="command_limit_mean"):
        build(Scenario, data)


def _doc(**values):
    return {"metrics": {k: {"value": v, "tolerance": {"rel": 0.05, "abs": 1e-6}} for k, v in values.items()}}


def test_compare_reads_null_as_nan_and_inf_strings_as_infinity():
    old_file = _doc(icr=math.nan, r=1.0, lim=math.inf)          # an old baseline (Python's NaN / Infinity)
    new_file = strict_loads(dumps_json(_doc(icr=math.nan, r=1.0, lim=math.inf)))  # the strict writer's
    assert compare_metrics(old_file, new_file) == [] and compare_metrics(new_file, old_file) == []
    moved = {m["metric"]: m["why"] for m in compare_metrics(new_file, _doc(icr=0.5, r=None, lim=-math.inf))}
    assert set(moved) == {"r", "lim"} and moved["r"] == "became NaN"  # a NaN baseline has nothing to move from
    assert [m["metric"] for m in compare_metrics(_doc(r=2.0), _doc(r=math.inf))] == ["r"]
    # deliberate: an infinite baseline moving to a finite value is flagged (before strict JSON its relative
    # tolerance was infinite, so nothing that started at +-inf could ever be flagged)
    assert [m["metric"] for m in compare_metrics(_doc(r=math.inf), _doc(r=3.0))] == ["r"]
    assert compare_metrics(_doc(r="+inf"), _doc(r=math.inf)) == []
    bad = compare_metrics(_doc(r=1.0), {"metrics": {"r": {"value": "1.0"}}})
    assert [m["why"] for m in bad] == ["value is not a number"]


@pytest.mark.parametrize("path", sorted(p.relative_to(RESULTS).as_posix() for p in RESULTS.rglob("*.json*")
                                        if p.suffix in (".json", ".jsonl")))
def test_committed_results_are_strict_json(path):
    text = (RESULTS / path).read_text()
    for line in (text.splitlines() if path.endswith(".jsonl") else [text]):
        if line.strip():
            strict_loads(line)


def test_dashboard_reads_a_no_value_metric_as_nan_in_old_and_strict_history_lines(tmp_path):
    from bench.report.dashboard import load_history

    entry = {"commit": "a", "date": "", "quick": False, "seconds": 1.0,
             "metrics": {"p.t.icr": math.nan, "p.t.lim": math.inf, "p.t.rms": 0.5}}
    (tmp_path / "h.jsonl").write_text(json.dumps(entry) + "\n" + dumps_json(entry) + "\n")  # old writer, then new
    old, new = load_history(tmp_path / "h.jsonl")
    for e in (old, new):
        assert math.isnan(e.metrics["p.t.icr"]) and e.metrics["p.t.lim"] == math.inf and e.metrics["p.t.rms"] == 0.5
