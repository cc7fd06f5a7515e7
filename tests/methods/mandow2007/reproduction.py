"""Mandow 2007 and Wang 2015 reproduction tests: the papers' text, declaration helpers and the quick reproductions.

The quick reproductions of both papers run once per test session, into a temporary results folder and run
cache (cold: every run is simulated), for tests/methods/mandow2007/test_repro.py and
tests/methods/wang2015/test_repro.py (:func:`quick_reproductions`).  The papers' text is read from
``../shared/papers`` (tests that need it are skipped when it is absent).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from bench import reproduce as R
from bench.reproduce.runner import Runner
from tests.conftest import run_cache

PAPERS = Path(__file__).resolve().parents[4] / "shared" / "papers"
MANDOW_MD = PAPERS / "mandow2007_experimental_kinematics.md"
WANG_MD = PAPERS / "wang2015_laser_scanner_icr_chi.md"
TIRE_COLUMN = {"50psi": 0, "20psi": 1, "solid": 2}  # column order of Mandow Tables I-II
TIRE_NAME = {"50psi": "pneumatic_50psi", "20psi": "pneumatic_20psi", "solid": "solid"}
PARAM_ROW = {"y_icr_v": "y_{ICRv}", "x_icr_r": "x_{ICRr}", "x_icr_l": "x_{ICRl}", "alpha_r": "\\alpha_r",
             "alpha_l": "\\alpha_l", "chi": "\\chi", "e": "e"}


_SESSION: dict[str, Any] = {}


def quick_reproductions(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path]:
    """Quick reproductions of both papers, cold cache, two simulation processes (once per session)."""
    if "results" not in _SESSION:
        runner = Runner(cache_dir=run_cache(tmp_path_factory, "cache"), workers=2)
        out = tmp_path_factory.mktemp("results")
        res = {p: R.reproduce_paper(p, runner, out, quick=True, use_cache=False) for p in ("mandow2007", "wang2015")}
        _SESSION["results"] = (res, out)
    return _SESSION["results"]


def rows(decl: dict, table: str) -> dict[str, dict]:
    tab = next(t for t in decl["tables"] if t["id"] == table)
    return {r["metric"]: r for r in tab.get("rows", [])}


def paper_lines(path: Path) -> list[str]:
    if not path.is_file():
        pytest.skip(f"paper text not available at {path}")
    return path.read_text().splitlines()


def numbers(line: str) -> list[float]:
    return [float(x.rstrip("%")) / (100 if x.endswith("%") else 1)
            for x in re.findall(r"-?\d+\.\d+%?", line.split("\t", 1)[1] if "\t" in line else line)]

