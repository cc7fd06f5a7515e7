"""Mandow 2007 (and both papers' claims): published values declared in scenarios/papers/*.toml against the paper's text."""
from __future__ import annotations

import re

import pytest

from bench import reproduce as R
from methods import mandow2007 as M
from methods.mandow2007 import repro as MR
from tests.methods.mandow2007.reproduction import (MANDOW_MD, PARAM_ROW, TIRE_COLUMN, TIRE_NAME, WANG_MD, numbers,
                                                   paper_lines, rows)


def mandow_paper_tables() -> list[dict[str, list[float]]]:
    """Tables I and II of the paper text: {param: [50 psi, 20 psi, solid]}."""
    found: list[tuple[str, list[float]]] = []
    for line in paper_lines(MANDOW_MD):
        m = re.match(r"^\$(.+?)\$\t(.+)$", line)
        if m and len(vals := numbers(line)) == 3:
            found.append((m.group(1), vals))
    assert len(found) == 14, found
    inv = {v: k for k, v in PARAM_ROW.items()}
    return [{inv[name]: vals for name, vals in found[i:i + 7]} for i in (0, 7)]


@pytest.mark.parametrize("terrain,table,index", [("asphalt", "table1", 0), ("smooth_concrete", "table2", 1)])
def test_mandow_tables_i_ii_published_values_equal_paper(terrain, table, index):
    decl = R.load_paper("mandow2007")
    declared = rows(decl, table)
    paper = mandow_paper_tables()[index]
    plugin = MR.PUBLISHED_TABLES[terrain]
    for tire, col in TIRE_COLUMN.items():
        k = plugin[MR.PUBLISHED_TIRE[TIRE_NAME[tire]]]
        for opt in ("ga", "de"):
            for name in PARAM_ROW:
                pub = declared[f"{terrain}_{tire}_{opt}_{name}"]["published"]
                assert pub == paper[name][col], (tire, opt, name)
                if name in M.PARAM_NAMES:  # the plugin's own transcription agrees
                    assert getattr(k, name) == pub
        # the paper's indexes follow from its K by eqs. (9)-(10) (rounding of the printed K: < 2e-4)
        assert abs(M.steering_efficiency(k.x_icr_l, k.x_icr_r, 0.4) - paper["chi"][col]) < 2e-4
        assert abs(M.eccentricity(k.x_icr_l, k.x_icr_r) - paper["e"][col]) < 2e-4


def test_mandow_table_i_asphalt_20psi_column_transcribed():
    """Mandow Table I, pneumatic 20 psi column, typed here from the paper (a third transcription)."""
    declared = rows(R.load_paper("mandow2007"), "table1")
    column = {"y_icr_v": -0.0120, "x_icr_r": 0.3071, "x_icr_l": -0.2553, "alpha_r": 0.9049, "alpha_l": 0.9271,
              "chi": 0.7112, "e": 0.0921}
    for name, value in column.items():
        assert declared[f"asphalt_20psi_ga_{name}"]["published"] == value


def test_mandow_table_iii_published_values_equal_paper():
    declared = rows(R.load_paper("mandow2007"), "table3")
    lines = [ln for ln in paper_lines(MANDOW_MD) if ln.startswith("mean squared")]
    assert len(lines) == 4
    for line, key in zip(lines, ("ms_dx", "ms_dy", "ms_dphi", "ms_j")):
        for model, value in zip(("asymmetric", "p3at", "symmetric"), numbers(line)):
            assert declared[f"{model}_{key}"]["published"] == value
    assert declared["symmetric_alpha"]["published"] == 0.91  # Sec. IV-D
    assert declared["symmetric_x_icr"]["published"] == 0.275



def test_claims_reference_declared_tables():
    for paper in ("mandow2007", "wang2015"):
        decl = R.load_paper(paper)
        tables = {t["id"] for t in decl["tables"]}
        for c in decl["claims"]:
            ids = c.get("metrics") or c.get("series") or [c.get("metric") or c.get("num")]
            ids = ids + ([c["den"]] if "den" in c else [])
            assert all(i.split(".")[0] in tables for i in ids), (paper, c["id"])


# ------------------------------------------------------------------------------------------ claims
def _plain(text: str) -> str:
    """Text for a verbatim comparison: the paper's LaTeX symbols as the Greek letters of the quotes, then only
    letters and digits, lower case."""
    for tex, greek in (("\\chi", "χ"), ("\\lambda", "λ"), ("\\alpha", "α"), ("\\sigma", "σ"), ("\\Delta", "Δ"),
                       ("\\phi", "φ"), ("\\Phi", "Φ")):
        text = text.replace(tex, greek)
    return "".join(ch for ch in text.lower() if ch.isalnum())


@pytest.mark.parametrize("paper,md", [("mandow2007", MANDOW_MD), ("wang2015", WANG_MD)])
def test_claim_quotes_are_the_papers_words(paper, md):
    """Every quote (fragments joined by ' / ') occurs verbatim in the paper text (symbols and spacing aside)."""
    text = _plain("\n".join(paper_lines(md)))
    for c in R.load_paper(paper)["claims"]:
        assert c.get("quote"), (paper, c["id"])
        for fragment in c["quote"].split(" / "):
            assert _plain(fragment) in text, (paper, c["id"], fragment)


@pytest.mark.parametrize("paper", ["mandow2007", "wang2015"])
def test_claims_name_section_and_page_and_their_tolerance(paper):
    for c in R.load_paper(paper)["claims"]:
        assert re.search(r"\b(Sec\.|Abstract|Conclusions|Table)", c["source"]), (paper, c["id"])
        assert re.search(r"\bp\. ~?\d{4}", c["source"]), (paper, c["id"])
        assert "headline" in c, (paper, c["id"])
        if "margin" in c:  # a margin is an interval metric of the reproduction, named in the origin
            assert c["margin"] in c["tolerance_origin"] and "95 %" in c["tolerance_origin"] or \
                "two standard errors" in c["tolerance_origin"], (paper, c["id"])
        if "tolerance_abs" in c or "tolerance" in c:
            assert "paper" in c["tolerance_origin"], (paper, c["id"])  # a spread the paper itself reports


def test_mandow_chi_terrain_claim_only_where_tables_support_it():
    """Tables I-II support 'chi lower on asphalt than on smooth concrete' for the 50 psi tires only: that is the
    claim encoded, and the published numbers say so."""
    ids = {c["id"] for c in R.load_paper("mandow2007")["claims"]}
    chi = {(t, w): MR.published_parameters(t, w)["chi"] for t in MR.TERRAINS for w in MR.TIRES}
    supported = {w for w in MR.TIRES if chi[("asphalt", w)] < chi[("smooth_concrete", w)]}
    assert supported == {"pneumatic_50psi"}
    assert "chi_asphalt_lt_concrete_50psi" in ids
    assert not {"chi_asphalt_lt_concrete_20psi", "chi_asphalt_lt_concrete_solid"} & ids
