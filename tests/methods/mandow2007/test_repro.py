"""Mandow 2007 (and both papers' result files): the quick reproductions end to end.

The reproduced numbers are checked against independent expectations: eqs. (9)-(10) on the identified K, the
DGPS noise floor of Table III; for both papers, verdicts, declared rows, files and provenance.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from methods.mandow2007 import repro as MR
from tests.methods.mandow2007.reproduction import TIRE_COLUMN, quick_reproductions


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Quick reproductions of both papers, cold cache, two simulation processes (run once per session)."""
    return quick_reproductions(tmp_path_factory)


def test_every_claim_gets_a_verdict_with_numbers(results):
    """Quick mode evaluates every claim (no interval metric missing); a paper claim that does not hold has its
    cause (one of method, testbed, protocol, paper; at most 300 characters)."""
    res, _ = results
    for paper, r in res.items():
        assert r.claims, paper
        for c in r.claims:
            assert c["holds"] in (True, False), (paper, c["id"], c["measured"])
            assert re.search(r"\d", c["measured"]), (paper, c["id"])
            if c["verdict"] == "does not hold" and c["scope"] == "paper":
                cause = c.get("cause") or {}
                assert cause.get("kind") in ("method", "testbed", "protocol", "paper"), f"{paper}.{c['id']}"
                assert 0 < len(cause["text"]) <= 300, f"{paper}.{c['id']}"


def test_every_declared_row_maps_to_a_returned_metric(results):
    res, _ = results
    for paper, r in res.items():
        for tab in r.tables:
            for row in tab["rows_out"]:
                assert row["metric"] in tab["all_metrics"], (paper, tab["id"], row["metric"])
                assert np.isfinite(row["reproduced"]), (paper, tab["id"], row["metric"])
                assert row["verdict"] != "not reproduced"


def test_files_written(results):
    res, out = results
    for paper, r in res.items():
        d = out / paper
        for tab in r.tables:
            assert (d / f"{tab['id']}.md").stat().st_size > 0
            assert (d / f"{tab['id']}.csv").read_text().startswith("metric,label,reproduced,published,verdict")
        assert "| claim |" in (d / "claims.md").read_text()
        assert (d / "README.md").is_file()
        assert r.figures
        for rel, caption in r.figures:
            assert (out / rel).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and caption
    figs = {Path(p).name for p, _ in res["wang2015"].figures}
    assert {"wang2015_fig13.png", "wang2015_fig14.png", "wang2015_fig15.png"} <= figs
    assert "mandow2007_fig6.png" in {Path(p).name for p, _ in res["mandow2007"].figures}
    assert "0.0359 for all three models" in (out / "mandow2007" / "table3.md").read_text()
    assert "LARGER value in every column" in (out / "wang2015" / "table4.md").read_text()


def test_mandow_indexes_follow_from_identified_parameters(results):
    """Eqs. (9)-(10) on the reproduced K give the reproduced chi and e (L = 0.4 m)."""
    m = results[0]["mandow2007"].metrics
    for terrain, table in (("asphalt", "table1"), ("smooth_concrete", "table2")):
        for tire in TIRE_COLUMN:
            for opt in ("ga", "de"):
                p = f"{table}.{terrain}_{tire}_{opt}_"
                xl, xr = m[p + "x_icr_l"], m[p + "x_icr_r"]
                assert m[p + "chi"] == pytest.approx(0.4 / (xr - xl), rel=1e-12)
                assert m[p + "e"] == pytest.approx((xr + xl) / (xr - xl), rel=1e-12, abs=1e-15)
                # the GA lives on the 8-bit gene grid of its ranges
                lo, hi = -1.2 * 0.4, -0.4 * 0.4
                if opt == "ga":
                    code = (xl - lo) / ((hi - lo) / 255)
                    assert abs(code - round(code)) < 1e-6


def test_mandow_table3_sits_on_the_dgps_noise_floor(results):
    """DGPS-referenced mean squares = truth-referenced model error + the reference's increment noise
    2 sigma^2 per axis (sigma = the scenario's DGPS noise), within the sampling error of the mean."""
    from bench.spec import load_scenario

    ref = load_scenario("mandow_joystick_asphalt_pneumatic_20psi").platform.sensors.reference
    m = results[0]["mandow2007"].metrics
    for model in ("asymmetric", "p3at", "symmetric"):
        for key, sigma in (("ms_dx", ref.pos_noise), ("ms_dy", ref.pos_noise), ("ms_dphi", ref.yaw_noise)):
            expected = m[f"table3.{model}_truth_{key}"] + 2 * sigma**2
            assert m[f"table3.{model}_{key}"] == pytest.approx(expected, rel=0.3), (model, key)
        parts = sum(m[f"table3.{model}_{k}"] for k in ("ms_dx", "ms_dy", "ms_dphi"))
        assert m[f"table3.{model}_ms_j"] == pytest.approx(parts, rel=1e-12)


def test_calibration_and_scoring_runs_differ(results):
    """Provenance recorded by the compute functions: every calibrated method has calibration runs, and
    no scored run is among them (the registry would refuse to score it, bench.registry.CalibrationLeak)."""
    res, _ = results
    info = res["mandow2007"].info
    assert set(info["calibration_runs"]) == {f"{t}_{w}" for t in MR.TERRAINS for w in TIRE_COLUMN}
    assert info["scored_runs"], "no validation run recorded"
    for cond, scored in info["scored_runs"].items():
        for method in ("ga", "de", "symmetric"):
            calib = info["calibration_runs"][cond][method]
            assert calib and scored not in calib, (cond, method)
    winfo = res["wang2015"].info
    scored = set(winfo["scored_runs"])
    assert len(winfo["calibration_runs"]["chi_lambda"]) == 16  # the quick grid: 8 curvature ratios x 2 speeds
    for method, calib in winfo["calibration_runs"].items():
        assert not scored & set(calib), method
