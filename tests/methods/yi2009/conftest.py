"""Fixtures shared by the test modules of tests/methods/yi2009/: the synthetic calibration runs of the consistent
configuration and one quick reproduction of the paper (package-scoped: it runs once)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from bench import reproduce as R
from bench.reproduce.runner import Runner
from bench.run import Run
from tests.methods.yi2009.synthetic import CAL_COMBOS_RPM, TESTBED, synthetic_run
from tests.conftest import run_cache


@pytest.fixture(scope="module")
def consistent_runs() -> list[Run]:
    """Four steady turns of the calibration set (concrete 3 % / sand 8 % net slip)."""
    out = []
    for i in (0, 3, 6, 9):
        wl, wr = CAL_COMBOS_RPM[i]
        sens = dataclasses.replace(TESTBED, lam0=0.03 if i % 2 == 0 else 0.08)
        out.append(synthetic_run(f"cal{i}", 100 + i, sens, knots_rpm=[(0, 0, 0), (1, wl, wr), (11, wl, wr)]))
    return out


@pytest.fixture(scope="package")  # the reproduction runs once for test_repro.py and test_nees.py
def result(tmp_path_factory) -> tuple[R.PaperResult, Path]:
    out = tmp_path_factory.mktemp("yi_results")
    runner = Runner(cache_dir=run_cache(tmp_path_factory, "yi_cache"), workers=2)
    return R.reproduce_paper("yi2009", runner, out, quick=True), out
