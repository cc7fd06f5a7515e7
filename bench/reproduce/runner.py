"""The scenario x seed matrix: run cache, local process pool or Dask.

A run is identified by its *cache key*: the scenario's content hash (every spec field after
overrides), the seed, and the hash of the testbed's source code (``bench/sim/*.py``), so any change
to the physics invalidates the cache by itself.  Cached runs live in ``.cache/runs/<key>.parquet``
(written atomically).  ``simulate_many`` returns runs in request order; the testbed is
deterministic, so serial, ``--workers N`` and Dask give identical runs (tested).  The missing runs of one
scenario whose seeds change the sensor noise only (:func:`bench.sim.physics_seed`) are one job: the physics is
stepped once and each seed's sensors are drawn from that trace.
"""
from __future__ import annotations

import functools
import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

from bench.paths import CHECKOUT as REPO, PACKAGE, default_cache
from bench.procs import process_pool
from bench.run import Run
from bench.spec import Scenario

DEFAULT_CACHE = default_cache()


@functools.lru_cache(maxsize=1)
def testbed_code_hash() -> str:
    h = hashlib.sha256()
    for p in sorted([*(PACKAGE / "sim").glob("*.py"), *(PACKAGE / "sim").glob("*.c")]):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cache_key(scn: Scenario, seed: int) -> str:
    """The run's identity in the cache: scenario, seed, testbed code and the CPU dispatch the run is made under
    (:func:`bench.cpu.dispatch_state`: a run of the native dispatch is not served to a pinned process)."""
    from bench.cpu import dispatch_state
    from bench.sim import scenario_hash

    return hashlib.sha256(f"{scenario_hash(scn)}|{seed}|{testbed_code_hash()}|{dispatch_state()}".encode()
                          ).hexdigest()[:24]


def _simulate_to(scn: Scenario, seeds: Sequence[int], paths: Sequence[str]) -> tuple[list[str], str]:
    """Worker: simulate the seeds of one scenario that share their physics (:func:`bench.sim.physics_seed`: the
    trace is stepped once) and write each run (atomic); returns the paths and the worker's CPU dispatch
    (:func:`bench.cpu.dispatch_state`), which must be the one the cache keys were made with."""
    from bench.cpu import dispatch_state
    from bench.sim import simulate_seeds

    for run, path in zip(simulate_seeds(scn, seeds), paths):
        run.to_parquet(path)
    return list(paths), dispatch_state()


def _physics_groups(todo: dict[Path, tuple[Scenario, int]]) -> list[tuple[Scenario, list[int], list[str]]]:
    """The runs to compute, grouped by what their physics depends on (scenario hash, physics seed), in the
    order of their first request."""
    from bench.sim import physics_seed, scenario_hash

    groups: dict[tuple[str, int], tuple[Scenario, list[int], list[str]]] = {}
    for path, (scn, seed) in todo.items():
        g = groups.setdefault((scenario_hash(scn), physics_seed(scn, seed)), (scn, [], []))
        g[1].append(int(seed))
        g[2].append(str(path))
    return list(groups.values())


def portable_source(path: str) -> str:
    """A scenario's file as the manifest records it: relative to the repository (``scenarios/x.toml``) when it is one
    of the suite's, else its file name; never a path of the machine that made the run (the run's identity does not
    depend on it: :func:`bench.sim.scenario_hash` leaves it out)."""
    from bench.spec import SCENARIO_DIR

    if not path:
        return ""
    p = Path(path)
    try:
        return p.resolve().relative_to(SCENARIO_DIR.parent).as_posix()
    except ValueError:
        return p.name


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
    stats: dict = field(default_factory=lambda: {"simulated": 0, "cached": 0, "sim_seconds": 0.0,
                                                 "result_cache_hits": 0, "stages": {}})
    manifest: dict = field(default_factory=lambda: {"scenarios": {}, "runs": {}})  # + cpu_dispatch when served
    served_keys: list = field(default_factory=list)  # the run-cache key of every run handed out (the manifest's)

    def path_for(self, scn: Scenario, seed: int) -> Path:
        return Path(self.cache_dir) / f"{cache_key(scn, seed)}.parquet"

    def simulate(self, scn: Scenario, seed: int = 0) -> Run:
        return self.simulate_many([(scn, seed)])[0]

    def prepare(self, requests: Sequence[tuple[Scenario, int]]) -> list[Path]:
        """Simulate the requested runs that are not in the cache; return every request's cache path
        (nothing is read: for callers whose workers read the runs themselves)."""
        paths = [self.path_for(s, seed) for s, seed in requests]
        todo: dict[Path, tuple[Scenario, int]] = {}
        for (s, seed), path in zip(requests, paths):
            if not (self.use_cache and path.is_file()) and path not in todo:
                todo[path] = (s, seed)
        self.stats["cached"] += len(set(paths)) - len(todo)
        if todo:
            Path(self.cache_dir).mkdir(parents=True, exist_ok=True)
            t0 = time.perf_counter()
            self._compute(todo)
            self.stats["sim_seconds"] += time.perf_counter() - t0
            self.stats["simulated"] += len(todo)
        return paths

    def simulate_many(self, requests: Sequence[tuple[Scenario, int]]) -> list[Run]:
        paths = self.prepare(requests)
        runs = [Run.from_parquet(p) for p in paths]
        for (s, seed), path, run in zip(requests, paths, runs):
            self._record(s, seed, path.stem, run)
        return runs

    def _record(self, scn: Scenario, seed: int, key: str, run: Run) -> None:
        """Provenance: every served run's scenario spec, seed and content hash (runs_manifest.json)."""
        from bench.sim import scenario_hash
        from bench.spec import to_dict

        from bench.cpu import dispatch_state

        sh = scenario_hash(scn)
        self.manifest["cpu_dispatch"] = dispatch_state()
        self.manifest["scenarios"].setdefault(sh, dict(to_dict(scn), source_file=portable_source(scn.source_file)))
        self.served_keys.append(key)
        self.manifest["runs"][key] = {"scenario": scn.id, "scenario_hash": sh, "seed": int(seed),
                                      "content_hash": run.content_hash()}

    def manifest_of(self, keys: Sequence[str]) -> dict:
        """The part of :attr:`manifest` the runs ``keys`` take (their runs, scenarios and CPU dispatch): what a paper
        served, kept with its cached result so that a cache hit still writes the runs its numbers come from."""
        runs = {k: self.manifest["runs"][k] for k in sorted(set(keys))}
        out = {"scenarios": {r["scenario_hash"]: self.manifest["scenarios"][r["scenario_hash"]] for r in runs.values()},
               "runs": runs}
        if runs and "cpu_dispatch" in self.manifest:
            out["cpu_dispatch"] = self.manifest["cpu_dispatch"]
        return out

    def add_manifest(self, part: Mapping) -> None:
        """Merge a manifest (a paper job's, or a cached result's :meth:`manifest_of`) into :attr:`manifest`."""
        self.manifest["scenarios"].update(part.get("scenarios", {}))
        self.manifest["runs"].update(part.get("runs", {}))
        if "cpu_dispatch" in part:
            self.manifest["cpu_dispatch"] = part["cpu_dispatch"]

    def _compute(self, todo: dict[Path, tuple[Scenario, int]]) -> None:
        from bench.cpu import dispatch_state

        groups = _physics_groups(todo)
        done = 0
        mine = dispatch_state()

        def tick(result: tuple[list[str], str]) -> None:
            nonlocal done
            paths, state = result
            if state != mine:  # e.g. an unpinned Dask worker: its runs would sit under this process's keys
                for p in paths:
                    Path(p).unlink(missing_ok=True)
                raise RuntimeError(f"a simulation worker ran under CPU dispatch {state}, this process under {mine}: "
                                   "start the workers with bench.cpu.pinned_env() (README) or set SKIDBENCH_CPU=native")
            done += len(paths)
            if self.progress:
                self.progress(done, len(todo))

        if self.dask_scheduler:
            from distributed import Client

            with Client(self.dask_scheduler) as client:
                futures = [client.submit(_simulate_to, *g, pure=False) for g in groups]
                for fut in futures:
                    tick(fut.result())
            return
        if self.workers <= 1 or len(groups) == 1:
            for g in groups:
                tick(_simulate_to(*g))
            return
        with process_pool(self.workers) as ex:
            for fut in [ex.submit(_simulate_to, *g) for g in groups]:
                tick(fut.result())


def verify_manifest(manifest: dict, workers: int = 1, limit: int | None = None,
                    progress: Callable[[int, int], None] | None = None, source: str = "<manifest>") -> list[dict]:
    """Re-simulate the runs of a manifest (no cache, in worker processes when ``workers`` > 1)
    and return those whose content hash differs from the recorded one; ``source`` names the manifest in errors."""
    import tempfile

    from bench.spec import Scenario, build

    items = sorted(manifest["runs"].items())[: limit or None]
    with tempfile.TemporaryDirectory() as tmp:
        runner = Runner(cache_dir=Path(tmp), workers=workers, use_cache=False, progress=progress)
        reqs = [(build(Scenario, manifest["scenarios"][r["scenario_hash"]], f"{source} (scenarios.{r['scenario_hash']})"),
                 r["seed"]) for _, r in items]
        runs = runner.simulate_many(reqs)
    return [{"key": k, **r, "got": run.content_hash()} for (k, r), run in zip(items, runs)
            if run.content_hash() != r["content_hash"]]
