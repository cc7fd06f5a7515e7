"""Wang 2015: published values declared in scenarios/papers/wang2015.toml against the paper's text."""
from __future__ import annotations

import math
import re

from bench import reproduce as R
from methods import wang2015 as W
from tests.methods.mandow2007.reproduction import WANG_MD, numbers, paper_lines, rows


def test_wang_published_values_equal_paper():
    decl = R.load_paper("wang2015")
    t3, fit, t4, corr = (rows(decl, t) for t in ("table3", "fit", "table4", "table3_corrected"))
    text = paper_lines(WANG_MD)
    table3 = {int(ln.split("\t")[0]): numbers(ln) for ln in text if re.match(r"^[0-7]\t1\.4\d{3}\t", ln)}
    assert sorted(table3) == list(range(8))
    for cr, (mu, sd, rel) in table3.items():
        assert t3[f"chi_lambda{cr}"]["published"] == mu == W.TABLE_3[cr][0] == corr[f"corr_chi_lambda{cr}"]["published"]
        assert t3[f"sigma_lambda{cr}"]["published"] == sd == W.TABLE_3[cr][1]
        assert math.isclose(t3[f"max_rel_err_lambda{cr}"]["published"], rel, abs_tol=1e-12)
    assert t3["max_abs_rel_err"]["published"] == max(abs(v[2]) for v in table3.values())
    assert fit["a"]["published"] == W.PUBLISHED_CURVE.a == 0.4728
    assert fit["b"]["published"] == W.PUBLISHED_CURVE.b == 0.0538
    t4_paper = {ln.split("\t")[0]: numbers(ln) for ln in text if ln.startswith(("P3-AT model\t", "Proposed model\t"))}
    for label, model in (("P3-AT model", "constant"), ("Proposed model", "chi_lambda")):
        for key, value in zip(("dx", "dy", "dphi"), t4_paper[label]):
            assert t4[f"{model}_ms_{key}"]["published"] == value  # as printed ("mean squared")
            assert t4[f"{model}_rms_{key}"]["published"] == value  # the same value read as an RMS
