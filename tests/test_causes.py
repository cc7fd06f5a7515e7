"""Causes that match their numbers: whether a failing claim's means favour it (bench.reproduce.claims.favours), the
quick run's own cause (``cause_quick``), and the committed verdicts' consistency between the full and quick runs."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.reproduce import claims as R
from bench.reproduce.paper import FULL_RUN, claim_result, list_papers, load_paper

RESULTS = Path(__file__).resolve().parents[1] / "results"


def _fav(claim, **metrics):
    return R.favours(claim, {f"t.{k}": v for k, v in metrics.items()})


def test_favours_reads_the_point_values_of_a_claim_failing_by_its_margin():
    o = {"kind": "ordering", "metrics": ["t.a", "t.b"], "margin": "t.m"}
    assert _fav(o, a=1.0, b=1.2, m=0.5) is True          # a < b, but a + m >= b: fails by the interval alone
    assert _fav(o, a=1.3, b=1.2, m=0.5) is False         # a > b: the means are against the claim
    assert _fav(o, a=1.0, b=2.0, m=0.5) is None          # holds
    assert _fav({"kind": "ordering", "metrics": ["t.a", "t.b"]}, a=2.0, b=1.0) is None  # no margin
    three = {"kind": "ordering", "metrics": ["t.a", "t.b", "t.c"], "margin": "t.m"}
    assert _fav(three, a=1.0, b=1.1, c=1.2, m=0.5) is True
    assert _fav(three, a=1.0, b=1.1, c=1.05, m=0.5) is False  # the second step's means are reversed
    r = {"kind": "ratio", "num": "t.n", "den": "t.d", "op": "<=", "value": 0.966, "margin": "t.m"}
    assert _fav(r, n=0.9655, d=1.0, m=0.011) is True     # Liu's quick mi_vs_ukf: 0.0005 under the bound
    assert _fav(r, n=0.9698, d=1.0, m=0.0225) is False   # the full run's: above it
    g = {"kind": "ratio", "num": "t.n", "den": "t.d", "op": ">=", "value": 1.0, "margin": "t.m"}
    assert _fav(g, n=1.05, d=1.0, m=0.1) is True and _fav(g, n=0.95, d=1.0, m=0.1) is False


CLAIM = {"id": "c", "text": "x", "kind": "ordering", "metrics": ["t.a", "t.b"], "margin": "t.m",
         "cause": {"kind": "testbed", "text": "full"}, "cause_quick": {"kind": "protocol", "text": "quick"}}


def test_a_quick_run_shows_cause_quick_and_a_full_run_cause():
    m = {"t.a": 1.0, "t.b": 1.2, "t.m": 0.5}
    full, quick = claim_result("p", CLAIM, m, {}), claim_result("p", CLAIM, m, {}, quick=True)
    assert full["cause"] == CLAIM["cause"] and quick["cause"] == CLAIM["cause_quick"]
    assert "cause_quick" not in full and "cause_quick" not in quick
    assert full["refuted"] is False and full["favours"] is True
    only_full = {k: v for k, v in CLAIM.items() if k != "cause_quick"}
    # no quick cause: the cause, marked as the full run's
    assert claim_result("p", only_full, m, {}, quick=True)["cause"] == {"kind": "testbed", "text": "full",
                                                                         "of": FULL_RUN}
    only_quick = {k: v for k, v in CLAIM.items() if k != "cause"}
    assert "cause" not in claim_result("p", only_quick, m, {})  # a full run never shows a quick run's reason


def _declared() -> dict[str, dict]:
    return {f"{p}.{c['id']}": c for p in list_papers() for c in load_paper(p).get("claims", [])}


def test_committed_quick_failures_that_differ_from_the_full_run_have_a_quick_cause():
    """A claim failing in the committed quick run whose full-run verdict differs, or whose means point the other way
    (``favours``), gets its reason from ``cause_quick``: the full run's cause, written with the full run's numbers,
    would contradict the quick numbers shown beside it."""
    full = json.loads((RESULTS / "extended" / "claims.json").read_text())["claims"]  # the extended-only claims,
    full |= json.loads((RESULTS / "claims.json").read_text())["claims"]  # the full run's where it has them
    quick = json.loads((RESULTS / "quick" / "claims_quick.json").read_text())["claims"]
    declared = _declared()
    need = sorted(k for k, q in quick.items() if q["verdict"] == "does not hold"
                  and (full[k]["verdict"] != "does not hold" or full[k].get("favours") != q.get("favours")))
    assert "yi2009.nees_consistent" in need  # extended run: holds; quick: does not
    assert need, "no quick-only failure: this check would be vacuous"
    assert [k for k in need if "cause_quick" not in declared[k]] == []
    metrics = json.loads((RESULTS / "quick" / "metrics_quick.json").read_text())["metrics"]
    for k in need:  # and the quick file shows it, with the quick run's numbers where it quotes metrics
        paper = k.split(".")[0]
        local = {m.split(".", 1)[1]: v["value"] for m, v in metrics.items() if m.startswith(paper + ".")}
        want = declared[k]["cause_quick"]
        assert quick[k]["cause"] == {**want, "text": R.fill_numbers(want["text"], local)}, k


@pytest.mark.parametrize("name", ["claims.json", "quick/claims_quick.json"])
def test_committed_claims_record_whether_their_means_favour_them(name):
    claims = json.loads((RESULTS / name).read_text())["claims"]
    inside = {k: c for k, c in claims.items() if c["verdict"] == "does not hold" and c["refuted"] is False}
    assert inside and all(isinstance(c["favours"], bool) for c in inside.values())
