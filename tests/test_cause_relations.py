"""The relations a cause text's words state ("loses", "vs", "inside the interval"), declared beside it and checked on
every run (bench.reproduce.claims module doc): hand-worked cases, a committed cause whose numbers, flipped, make its
words stale, the declaration errors, and the committed runs' metrics against the declared words."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.reproduce.claims import check_claim, parse_relation, relation_metrics, stale_relations
from bench.reproduce.paper import claim_result, list_papers, load_paper
from bench.reproduce.report import _cause, claims_details
from bench.spec import SpecError

RESULTS = Path(__file__).resolve().parents[1] / "results"


def test_relations_are_evaluated_as_written():
    """Each side a metric, a number or |X - Y|; "<" is strict, "<=" is not; a missing or NaN metric is stale."""
    m = {"t.a": 0.171, "t.b": 0.095, "t.h": 0.08, "t.n": float("nan"), "t.chi": 1.494, "t.path": 1.485}
    assert parse_relation("|t.a - t.b| < t.h") == ("|t.a - t.b|", "<", "t.h")
    assert parse_relation("t.a >> t.b") is None and parse_relation("t.a - t.b < 1") is None
    assert relation_metrics("|1.5 - t.chi| < |t.path-t.chi|") == ["t.chi", "t.path", "t.chi"]
    assert relation_metrics("t.a > -2e-3") == ["t.a"]
    assert stale_relations(["t.a > t.b", "t.a >= 0.171", "|1.5 - t.chi| < |t.path - t.chi|"], m) == []
    # 0.171 - 0.095 = 0.076 < 0.08 holds; against 0.07 it does not
    assert stale_relations(["|t.a - t.b| < t.h"], m) == []
    assert stale_relations(["|t.a - t.b| < 0.07"], m) == ["|t.a - t.b| < 0.07 (0.076 vs 0.07)"]
    assert stale_relations(["t.a < 0.171", "t.b > t.a"], m) == ["t.a < 0.171 (0.171 vs 0.171)", "t.b > t.a (0.095 vs 0.171)"]
    assert stale_relations(["t.n < 1", "t.gone > 0"], m) == ["t.n < 1 (n/a vs 1)", "t.gone > 0 (n/a vs 0)"]
    # ratios: 1.485 / 1.494 - 1 = -0.602 %, inside 1 %, outside 0.5 %; a zero denominator is stale
    assert parse_relation("|t.path / t.chi - 1| < 0.01") == ("|t.path / t.chi - 1|", "<", "0.01")
    assert stale_relations(["|t.path / t.chi - 1| < 0.01", "t.b / t.a < 0.56"], m) == []
    assert stale_relations(["|t.path / t.chi - 1| < 0.005"], m) == ["|t.path / t.chi - 1| < 0.005 (0.006024 vs 0.005)"]
    assert stale_relations(["t.a / t.z > 0"], {**m, "t.z": 0.0}) == ["t.a / t.z > 0 (n/a vs 0)"]
    assert parse_relation("t.a / t.b / t.c < 1") is None


def _metrics(name: str, paper: str) -> dict[str, float]:
    doc = json.loads((RESULTS / name).read_text())["metrics"]
    return {k[len(paper) + 1:]: v["value"] for k, v in doc.items() if k.startswith(paper + ".")}


def test_a_committed_cause_goes_stale_when_its_numbers_turn():
    """yi2009.superior_figure8's cause says scheme 3 loses with the true S and wins without the feedback: with the
    committed full run's numbers its words hold; with v1 raised above every scheme-3 variant they do not, and the
    report says so beside the cause and in the details."""
    claim = next(c for c in load_paper("yi2009")["claims"] if c["id"] == "superior_figure8")
    m = _metrics("metrics.json", "yi2009")
    ok = claim_result("yi2009", claim, m, {})
    assert ok["holds"] is False and "stale" not in ok["cause"]
    turned = {**m, "diagnosis.figure8.attribution.v1": 1.0}  # scheme 1 now worst: "scheme 3 still loses" is false
    got = claim_result("yi2009", claim, turned, {})
    assert got["cause"]["stale"] == [
        "diagnosis.figure8.attribution.v3_true_s > diagnosis.figure8.attribution.v1 "
        f"({m['diagnosis.figure8.attribution.v3_true_s']:.4g} vs 1)"]
    assert "stale: this run's numbers contradict its words" in _cause(got, "details.md")
    assert "stale" not in _cause(ok, "details.md")


def test_the_details_page_lists_what_the_run_does_not_meet():
    from types import SimpleNamespace

    claim = {"id": "c", "text": "b below a", "source": "s", "kind": "ordering", "metrics": ["t.b", "t.a"],
             "cause": {"kind": "testbed", "text": "a {t.a} vs b {t.b}: a loses", "relations": ["t.a > t.b"]}}
    res = SimpleNamespace(paper="p", claims=[claim_result("p", claim, {"t.a": 1.0, "t.b": 2.0}, {})])
    details = claims_details(res)
    assert "- cause (testbed, **stale: this run's numbers contradict its words**): a 1 vs b 2: a loses" in details
    assert "- not met by this run: t.a > t.b (1 vs 2)" in details


@pytest.mark.parametrize("cause, match", [
    ({"kind": "method", "text": "a {t.a} vs b {t.b}"}, "state the relations"),
    ({"kind": "method", "text": "a {t.a} loses", "relations": ["t.a >> t.b"]}, "a relation 'X op Y'"),
    ({"kind": "method", "text": "a {t.a} loses", "relations": ["zz.a > t.b"]}, "of a declared table"),
    ({"kind": "method", "text": "a {t.a} loses", "relations": "t.a > t.b"}, "a list of relations"),
    ({"kind": "method", "text": "a {t.a} vs b {t.b}", "relation": ["t.a > t.b"]}, "fields among"),
    ({"kind": "method", "text": "a {t.a} is within 1 % of b {t.b}"}, "state the relations"),
    ({"kind": "method", "text": "A {t.a}. Loses to b."}, "state the relations"),
    ({"kind": "method", "text": "a {t.a} loses", "relations": ["1 < 2"]}, "reads a metric"),
])
def test_a_cause_that_compares_without_stating_or_with_a_bad_relation_is_a_one_line_error(cause, match):
    claim = {"id": "c", "text": "t", "source": "s", "kind": "ordering", "metrics": ["t.a", "t.b"], "cause": cause}
    with pytest.raises(SpecError, match=match) as e:
        check_claim(Path("p.toml"), 0, claim, ["t"])
    assert "\n" not in str(e.value) and "p.toml" in str(e.value) and "claims.c.cause" in str(e.value)
    words_only = {**claim, "cause": {"kind": "method", "text": "0.5 vs 0.4, no quoted metric"}}
    assert check_claim(Path("p.toml"), 0, words_only, ["t"]) == []


@pytest.mark.parametrize("name, quick", [("metrics.json", False), ("quick/metrics_quick.json", True),
                                         ("extended/metrics.json", False)])
def test_the_committed_runs_meet_the_words_of_every_cause_they_show(name: str, quick: bool):
    """The declared relations of every cause a committed run shows (a failing claim's), evaluated on that run's
    committed metrics: none stale.  Recomputed here, so a cause edited after the run is checked too."""
    stale, shown = {}, 0
    for paper in list_papers():
        m = _metrics(name, paper)
        if not m:
            continue
        for c in load_paper(paper)["claims"]:
            got = claim_result(paper, c, m, {}, quick)
            shown += bool(got.get("cause", {}).get("relations")) and got["holds"] is False
            if got.get("cause", {}).get("stale"):
                stale[f"{paper}.{c['id']}"] = got["cause"]["stale"]
    assert shown >= 5
    assert stale == {}
