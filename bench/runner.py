"""The scenario x seed matrix: run cache, local process pool or Dask.

A run is identified by its *cache key*: the scenario's content hash (every spec field after
overrides), the seed, and the hash of the testbed's source code (``bench/sim/*.py``), so any change
to the physics invalidates the cache by itself.  Cached runs live in ``.cache/runs/<key>.parquet``
(written atomically).  ``simulate_many`` returns runs in request order; the testbed is
deterministic, so serial, ``--workers N`` and Dask give identical runs (tested).
"""
from __future__ import annotations

import functools
import hashlib
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from bench.run import Run
from bench.spec import Scenario

REPO = Path(__file__).resolve().parent.parent
DEFAULT_CACHE = Path(os.environ.get("SKIDBENCH_CACHE", REPO / ".cache" / "runs"))


@functools.lru_cache(maxsize=1)
def testbed_code_hash() -> str:
    h = hashlib.sha256()
    for p in sorted((REPO / "bench" / "sim").glob("*.py")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cache_key(scn: Scenario, seed: int) -> str:
    from bench.sim import scenario_hash

    return hashlib.sha256(f"{scenario_hash(scn)}|{seed}|{testbed_code_hash()}".encode()).hexdigest()[:24]


def _simulate_to(scn: Scenario, seed: int, path: str) -> str:
    """Worker: simulate and write the run (atomic); returns the path."""
    from bench.sim import simulate

    simulate(scn, seed).to_parquet(path)
    return path


@dataclass
class Runner:
    """Simulate (scenario, seed) pairs with a cache and optional parallelism.

    ``workers``: local processes (1 = serial in this process). ``dask_scheduler``: address of a
    Dask scheduler; when given, missing runs are computed there.
    """

    cache_dir: Path = DEFAULT_CACHE
    workers: int = 1
    dask_scheduler: str | None = None
    use_cache: bool = True
    progress: Callable[[int, int], None] | None = None
    stats: dict = field(default_factory=lambda: {"simulated": 0, "cached": 0})

    def path_for(self, scn: Scenario, seed: int) -> Path:
        return Path(self.cache_dir) / f"{cache_key(scn, seed)}.parquet"

    def simulate(self, scn: Scenario, seed: int = 0) -> Run:
        return self.simulate_many([(scn, seed)])[0]

    def simulate_many(self, requests: Sequence[tuple[Scenario, int]]) -> list[Run]:
        paths = [self.path_for(s, seed) for s, seed in requests]
        todo: dict[Path, tuple[Scenario, int]] = {}
        for (s, seed), path in zip(requests, paths):
            if not (self.use_cache and path.is_file()) and path not in todo:
                todo[path] = (s, seed)
        self.stats["cached"] += len(set(paths)) - len(todo)
        if todo:
            Path(self.cache_dir).mkdir(parents=True, exist_ok=True)
            self._compute(todo)
            self.stats["simulated"] += len(todo)
        return [Run.from_parquet(p) for p in paths]

    def _compute(self, todo: dict[Path, tuple[Scenario, int]]) -> None:
        items = list(todo.items())
        done = 0
        if self.dask_scheduler:
            from distributed import Client

            with Client(self.dask_scheduler) as client:
                futures = [client.submit(_simulate_to, s, seed, str(p), pure=False) for p, (s, seed) in items]
                for fut in futures:
                    fut.result()
                    done += 1
                    if self.progress:
                        self.progress(done, len(items))
            return
        if self.workers <= 1 or len(items) == 1:
            for p, (s, seed) in items:
                _simulate_to(s, seed, str(p))
                done += 1
                if self.progress:
                    self.progress(done, len(items))
            return
        with ProcessPoolExecutor(max_workers=self.workers) as ex:
            futures = [ex.submit(_simulate_to, s, seed, str(p)) for p, (s, seed) in items]
            for fut in futures:
                fut.result()
                done += 1
                if self.progress:
                    self.progress(done, len(items))
