"""Shared fixtures. Simulated runs are cached per test session (the testbed is deterministic)."""
from __future__ import annotations

import functools
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=64)
def _sim(name: str, seed: int, overrides: tuple = ()):
    from bench.sim import simulate
    from bench.spec import load_scenario

    return simulate(load_scenario(name, dict(overrides)), seed)


@pytest.fixture(scope="session")
def sim():
    """sim(name, seed=0, **overrides) -> Run (cached)."""
    def get(name: str, seed: int = 0, **overrides):
        return _sim(name, seed, tuple(sorted((k.replace("__", "."), v) for k, v in overrides.items())))
    return get


def run_cache(tmp_path_factory: pytest.TempPathFactory, name: str) -> Path:
    """The run cache of a reproduction fixture: ``SKIDBENCH_TEST_CACHE`` when set (``.ci/run`` points it at the run
    cache its quick reproduction has just filled with the same code: a fixture then takes those runs, and the quick
    paper results from the result cache beside it, instead of computing them again), else a fresh folder."""
    shared = os.environ.get("SKIDBENCH_TEST_CACHE")
    return Path(shared) if shared else tmp_path_factory.mktemp(name)
