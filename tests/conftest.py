"""Shared fixtures. Simulated runs are cached per test session (the testbed is deterministic)."""
from __future__ import annotations

import functools
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
