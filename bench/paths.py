"""Where skidbench reads its scenario files and writes its results and run cache, in a checkout and installed.

* **In a checkout** (``pyproject.toml`` and ``scenarios/`` beside the ``bench`` package, also an editable install):
  the scenarios are the checkout's ``scenarios/``, results go to its ``results/`` (the committed ones), the run cache
  to its ``.cache/runs``.
* **Installed from the wheel**: the scenarios are the package data ``bench/scenarios`` (the same files, shipped by
  ``setup.py``), results go to ``./results`` of the current directory, the run cache to the user cache directory
  (``platformdirs.user_cache_path("skidbench") / "runs"``: ``~/.cache/skidbench/runs`` on Linux); nothing is ever
  written into site-packages.

Overrides: ``--results DIR`` of the commands, ``SKIDBENCH_CACHE`` for the run cache (its parent holds the result
cache), ``SKIDBENCH_DATA`` for the real data sets, ``SKIDBENCH_SCENARIOS`` for the scenario folder (the sensitivity
study, :mod:`bench.reproduce.sensitivity`, runs the papers on a copy with one chosen parameter changed; a result's
key hashes the folder's files, not its path).
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["PACKAGE", "CHECKOUT", "in_checkout", "SCENARIO_DIR", "default_results", "default_cache", "default_data"]

PACKAGE = Path(__file__).resolve().parent
CHECKOUT = PACKAGE.parent  # the checkout's root (installed: site-packages)


def in_checkout() -> bool:
    """True when the package runs from a source checkout (also an editable install)."""
    return (CHECKOUT / "pyproject.toml").is_file() and (CHECKOUT / "scenarios").is_dir()


SCENARIO_DIR = (Path(os.environ["SKIDBENCH_SCENARIOS"]).resolve() if os.environ.get("SKIDBENCH_SCENARIOS")
                else CHECKOUT / "scenarios" if in_checkout() else PACKAGE / "scenarios")


def default_results() -> Path:
    """The results folder when no ``--results`` is given: the checkout's ``results/``, else ``./results``."""
    return CHECKOUT / "results" if in_checkout() else Path.cwd() / "results"


def default_cache() -> Path:
    """The run cache: ``SKIDBENCH_CACHE``, else the checkout's ``.cache/runs``, else the user cache directory."""
    if os.environ.get("SKIDBENCH_CACHE"):
        return Path(os.environ["SKIDBENCH_CACHE"])
    if in_checkout():
        return CHECKOUT / ".cache" / "runs"
    from platformdirs import user_cache_path

    return user_cache_path("skidbench") / "runs"


def default_data() -> Path:
    """The real data sets: ``SKIDBENCH_DATA``, else ``../shared/data`` beside the checkout (installed: ``./data``)."""
    if os.environ.get("SKIDBENCH_DATA"):
        return Path(os.environ["SKIDBENCH_DATA"])
    return CHECKOUT.parent / "shared" / "data" if in_checkout() else Path.cwd() / "data"
