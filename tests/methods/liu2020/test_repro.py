"""The Liu 2020 reproduction (scenarios/papers/liu2020.toml + methods/liu2020/repro/).

One quick reproduction runs into a temporary results folder with its own run cache (module fixture);
the tests check it against independent expectations: the published numbers parsed from the paper's
text, a second implementation of the position RMS, the ICR fit redone on the calibration run, the
chi-square and Student-t quantiles of printed tables, and the files the reproduction must write.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bench import registry
from bench import reproduce as R
from bench.reproduce.runner import Runner
from bench.spec import load_scenario
from methods.liu2020 import repro as L
from methods.liu2020 import fit_icr

PAPER_TEXT = Path("/work/shared/papers/liu2020_slip_aware_mi_ukf.md")
METHOD_COLUMNS = ("en_dr", "icr", "ukf_icr", "mi_ukf")


@pytest.fixture(scope="module")
def repro(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("liu2020_repro")
    runner = Runner(cache_dir=tmp / "cache")
    res = R.reproduce_paper("liu2020", runner, tmp / "results", quick=True)
    return res, runner, tmp / "results" / "liu2020"


def _paper_table2() -> dict[str, float]:
    """Table 2 parsed from the paper's text: 'scenario<TAB>En-DR<TAB>ICR<TAB>UKF+ICR<TAB>MI-UKF' rows in metres."""
    if not PAPER_TEXT.is_file():
        pytest.skip(f"paper text not available: {PAPER_TEXT}")
    text = PAPER_TEXT.read_text()
    block = text[text.index("TABLE 2. Estimation error of robot"):]
    out = {}
    for m in re.finditer(r"^([123])\t([\d.]+)m\t([\d.]+)m\t([\d.]+)m\t([\d.]+)m\s*$", block, re.M):
        for col, v in zip(METHOD_COLUMNS, m.groups()[1:]):
            out[f"s{m.group(1)}.{col}"] = float(v)
        if len(out) == 12:
            break
    assert len(out) == 12, "Table 2 not found in the paper text"
    return out


def test_published_values_are_the_papers_table2():
    pub = _paper_table2()
    decl = R.load_paper("liu2020")
    tables = {t["id"]: t for t in decl["tables"]}
    for tid in ("table2", "table2_gnss"):
        declared = {r["metric"]: r["published"] for r in tables[tid]["rows"]}
        assert declared == pub, tid
    # the ICR means of Secs. V-C-3 and V-D-3, as printed
    text = PAPER_TEXT.read_text()
    icr_pub = {r["metric"]: r["published"] for r in tables["icr"]["rows"] if "published" in r}
    s2 = re.search(r"means of the ICR locations are ([\d.]+)m, \$-([\d.]+)m\$, and \$([\d.]+)m\$", text)
    s3 = re.search(r"means of the ICR locations are ([\d.]+)m , -([\d.]+)m , and ([\d.]+)m", text)
    assert s2 and s3
    assert (icr_pub["s2.y_l"], icr_pub["s2.y_r"], icr_pub["s2.x_icr"]) == (float(s2[1]), -float(s2[2]), float(s2[3]))
    assert (icr_pub["s3.y_l"], icr_pub["s3.y_r"], icr_pub["s3.x_icr"]) == (float(s3[1]), -float(s3[2]), float(s3[3]))


def test_every_claim_has_a_verdict_with_numbers(repro):
    res, _, _ = repro
    assert len(res.claims) >= 10
    for c in res.claims:
        assert c["holds"] in (True, False), (c["id"], c["measured"])
        numbers = c["measured"] + (c["why"] if c["kind"] == "flag" else "")  # a flag's numbers are in its note
        assert re.search(r"\d", numbers), c["id"]
        if c["holds"] is False:
            assert c["why"], f"failing claim {c['id']} has no reason"


def test_every_declared_row_maps_to_a_metric(repro):
    res, _, _ = repro
    for tab in res.tables:
        for row in tab["rows_out"]:
            v = row["reproduced"]
            assert v is not None and math.isfinite(v), (tab["id"], row["metric"])
            assert f"{tab['id']}.{row['metric']}" in res.metrics
    assert res.info["seeds"] == list(L.SETTINGS.seeds_quick)


def test_files_written(repro):
    res, _, out = repro
    for tab in res.decl["tables"]:
        for ext in ("md", "csv"):
            assert (out / f"{tab['id']}.{ext}").stat().st_size > 0
    for name in ("claims.md", "README.md", "table2_intervals.md", "table2_gnss_intervals.md", "nees_consistency.md"):
        assert (out / name).stat().st_size > 0, name
    assert len(res.figures) >= 7
    for path, caption in res.figures:
        p = out.parent / path
        assert p.suffix == ".png" and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", path
        assert caption
    assert "| Scenario 2: MI-UKF |" in (out / "table2.md").read_text()


def test_table2_rms_matches_a_second_implementation(repro):
    """Position RMS recomputed with plain numpy on the cached runs (estimates at the log rows, so no
    interpolation) equals the reproduced seed mean; the ICR method's constants equal fit_icr redone on
    the calibration run, and the calibration run is not a scored run."""
    res, runner, _ = repro
    seeds = L.SETTINGS.seeds_quick
    calib_run = runner.simulate(load_scenario(L.SETTINGS.calib_scenario), L.SETTINGS.calib_seed)
    y_l, y_r, x_icr, _ = fit_icr([calib_run.without_truth()])
    assert (res.metrics["table2.calib.y_l"], res.metrics["table2.calib.y_r"], res.metrics["table2.calib.x_icr"]) == (y_l, y_r, x_icr)
    icr = registry.calibrate(registry.get("liu2020.icr"), [calib_run])
    scn = load_scenario("liu_large_radius", {"duration": L.SETTINGS.quick_duration})
    runs = runner.simulate_many([(scn, s) for s in seeds])
    assert calib_run.content_hash() not in {r.content_hash() for r in runs}
    for key, meth in (("en_dr", registry.get("liu2020.en_dr")), ("icr", icr)):
        rms = []
        for run in runs:
            est = registry.estimate(meth, run)
            assert np.array_equal(est["t"], run.t)
            e2 = (est["x"] - run["truth_x"]) ** 2 + (est["y"] - run["truth_y"]) ** 2
            rms.append(math.sqrt(float(np.mean(e2))))
        assert res.metrics[f"table2.s2.{key}"] == pytest.approx(np.mean(rms), rel=1e-9)


def test_claim_metrics_are_consistent(repro):
    """Ratio inputs are the table means; the heading flag had a -pi/pi crossing to test; the outage
    variant really had no GNSS fix during the outage."""
    res, _, _ = repro
    m = res.metrics
    for k in ("s1", "s2", "s3"):
        lo, hi = m[f"table2.{k}.mi_ukf.ci_lo"], m[f"table2.{k}.mi_ukf.ci_hi"]
        assert lo <= m[f"table2.{k}.mi_ukf"] <= hi
    gm = math.exp(np.mean([math.log(m[f"table2.{k}.mi_ukf"]) for k in ("s1", "s2", "s3")]))
    assert m["table2.gmean.mi_ukf"] == pytest.approx(gm, rel=1e-12)
    assert m["heading.truth_crossings"] >= 1
    assert m["outage.gnss_fixes_in_outage"] == 0.0
    assert m["outage.ukf_icr.nan_count"] == 0.0 and m["outage.mi_ukf.nan_count"] == 0.0


def test_interval_and_band_helpers_against_printed_quantiles():
    # Student t: t_0.975(2) = 4.303 (printed tables): data 1, 2, 3 -> mean 2, sd 1
    m, lo, hi = L.mean_ci([1.0, 2.0, 3.0])
    assert m == 2.0
    assert hi - m == pytest.approx(4.3027 / math.sqrt(3), rel=1e-4)
    assert m - lo == pytest.approx(hi - m)
    assert math.isnan(L.mean_ci([1.0])[1])
    # chi-square 95% two-sided: chi2_0.025(3) = 0.2158, chi2_0.975(3) = 9.348; N runs divide chi2(N n)
    lo, hi = L.nees_band(1, 3)
    assert (lo, hi) == (pytest.approx(0.2158, abs=1e-4), pytest.approx(9.348, abs=1e-3))
    lo, hi = L.nees_band(5, 6)  # chi2_0.025(30) = 16.791, chi2_0.975(30) = 46.979
    assert (lo, hi) == (pytest.approx(16.791 / 5, abs=1e-3), pytest.approx(46.979 / 5, abs=1e-3))


def test_nees_paper_and_consistent_side_by_side(repro):
    """Both configurations are in the NEES table; the claim flags equal a recomputation from the table's
    means and the chi-square bands; the consistent filters' noise is the identification redone on the
    calibration run (not a scored run); Table 2 holds the paper's four methods only."""
    from methods.liu2020 import UkfIcrConsistent, identify_noise

    res, runner, out = repro
    m = res.metrics
    n = len(L.SETTINGS.seeds_quick)
    b6, b3 = L.nees_band(n, 6), L.nees_band(n, 3)
    for tag, fs in (("paper", L.FILTERS), ("consistent", tuple(L.CONSISTENT))):
        ok6 = all(m[f"nees.{k}.{f}.in_band"] >= 0.9 for k in L.SCENARIOS for f in fs)  # Bar-Shalom per-step test
        ok3 = all(m[f"nees.{k}.{f}.pose_in_band"] >= 0.9 for k in L.SCENARIOS for f in fs)
        assert m[f"nees.{tag}_in_band"] == float(ok6 and ok3), tag
        assert m[f"nees.{tag}_pose_in_band"] == float(ok3), tag
        mean_ok = (all(b6[0] <= m[f"nees.{k}.{f}.nees"] <= b6[1] for k in L.SCENARIOS for f in fs)
                   and all(b3[0] <= m[f"nees.{k}.{f}.nees_pose"] <= b3[1] for k in L.SCENARIOS for f in fs))
        assert m[f"nees.{tag}_mean_in_band"] == float(mean_ok), tag
    claims = {c["id"]: c for c in res.claims}
    assert claims["nees_consistent"]["holds"] is (m["nees.consistent_in_band"] == 1.0)
    assert claims["nees_consistent_pose"]["holds"] is (m["nees.consistent_pose_in_band"] == 1.0)
    assert claims["nees_paper"]["holds"] is (m["nees.paper_in_band"] == 1.0)
    text = (out / "nees_consistency.md").read_text()
    assert "| s2 | UKF+ICR (consistent) |" in text and "| s2 | MI-UKF |" in text
    assert not any(k.startswith("table2.") and "_c" in k.split(".")[2] for k in m if k.count(".") >= 2)
    calib = runner.simulate(load_scenario(L.SETTINGS.calib_scenario), L.SETTINGS.calib_seed)
    _, info = identify_noise([calib.without_truth()], UkfIcrConsistent().params)
    for key in ("gnss_bias_tau", "gnss_bias_p0", "gnss_white_std", "enc_vx_r"):
        assert m[f"nees.noise.{key}"] == info[key], key
