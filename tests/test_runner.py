"""Runner: identical runs serial, with a local process pool and on a Dask cluster; an interrupted
reproduce leaves no half-written file and the next run resumes from the cache."""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.reproduce.runner import Runner
from bench.spec import load_scenario

REPO = Path(__file__).resolve().parents[1]


def test_dask_local_cluster_gives_the_serial_runs(tmp_path):
    distributed = pytest.importorskip("distributed")
    scn = load_scenario("circle_vinyl", {"duration": 1.5})
    reqs = [(scn, s) for s in range(3)]
    serial = Runner(cache_dir=tmp_path / "serial").simulate_many(reqs)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        dask = Runner(cache_dir=tmp_path / "dask", dask_scheduler=cluster.scheduler_address).simulate_many(reqs)
    assert [r.content_hash() for r in dask] == [r.content_hash() for r in serial]


def test_killed_reproduce_leaves_no_partial_file_and_resumes(tmp_path):
    """Start a reproduction, kill it mid-run, check results/ and the cache hold only whole files,
    then run again: the runs finished before the kill come from the cache."""
    results, cache = tmp_path / "results", tmp_path / "cache"
    env = dict(os.environ, SKIDBENCH_CACHE=str(cache))
    cmd = [sys.executable, "-m", "bench.cli", "reproduce", "league", "--quick", "--workers", "2", "--results", str(results)]
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and len(list(cache.glob("*.parquet"))) < 3:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done_before = {p.name for p in cache.glob("*.parquet")}
    assert done_before, "the reproduction did not get far enough to test an interruption"
    # a write cut by SIGKILL can only leave a hidden temp file, never a file under its final name
    leftovers = [p for d in (results, cache) if d.exists() for p in d.rglob("*")
                 if p.is_file() and p.name.endswith(".tmp")]
    assert all(p.name.startswith(".") for p in leftovers), leftovers
    if results.exists():
        assert not list(results.rglob("league_quick.md"))  # the table is written only when complete
    from bench.run import Run

    for p in cache.glob("*.parquet"):
        Run.from_parquet(p)  # every cached run is whole
    # the next reproduce removes such temp files before it starts
    import bench.reproduce.runner as runner_mod
    from bench.cli.reproduce import STALE_TEMP_AGE, _remove_stale_temp_files

    old = time.time() - 2 * STALE_TEMP_AGE  # left by the killed run (a younger one may be a live write: kept)
    (cache / ".stale.parquet.abc123.tmp").write_bytes(b"half a parquet")
    for p in [p for d in (results, cache) if d.exists() for p in d.rglob(".*.tmp") if p.is_file()]:
        os.utime(p, (old, old))
    saved = runner_mod.DEFAULT_CACHE
    runner_mod.DEFAULT_CACHE = cache
    try:
        _remove_stale_temp_files(results)
    finally:
        runner_mod.DEFAULT_CACHE = saved
    assert not [p for d in (results, cache) if d.exists() for p in d.rglob(".*.tmp")]
    # resume: every run finished before the kill is served from the cache, none simulated again.  The cache key
    # carries the CPU dispatch (bench.cpu), so the check runs under the pin the killed CLI ran under.
    from bench.cpu import pinned_env

    snippet = (
        "import json, sys\n"
        "from bench.cpu import dispatch_state\n"
        "from bench.reproduce.league import LEAGUE_SCENARIOS, _league_requests\n"
        "from bench.reproduce.runner import Runner\n"
        "r = Runner(cache_dir=sys.argv[1]); done = set(sys.argv[2:])\n"
        "reqs = [q for n in LEAGUE_SCENARIOS for part in _league_requests(n, True, 2) for q in part]\n"
        "found = {r.path_for(s, k).name: (s, k) for s, k in reqs if r.path_for(s, k).name in done}\n"
        "r.simulate_many(list(found.values()))\n"
        "print(json.dumps({'found': sorted(found), 'stats': [r.stats['cached'], r.stats['simulated']],"
        " 'dispatch': dispatch_state()}))\n")
    out = subprocess.run([sys.executable, "-c", snippet, str(cache), *sorted(done_before)], cwd=REPO,
                         env=pinned_env(env), capture_output=True, text=True, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["found"] == sorted(done_before), "cached runs that are not the league's requests"
    assert got["stats"] == [len(done_before), 0], got


def test_league_cells_in_parallel_equal_serial(tmp_path):
    """The league's cells run as process-pool jobs with workers > 1: the same table as serial."""
    from bench.reproduce.league import run_league
    from bench.reproduce.league_table import league_csv

    kw = dict(quick=True, methods=["baseline.ideal_dd", "wang2015.constant_chi", "mandow2007.symmetric"],
              scenarios=("circle_vinyl", "yi_circle"))
    serial = run_league(Runner(cache_dir=tmp_path, workers=1), **kw)
    par = run_league(Runner(cache_dir=tmp_path, workers=2), **kw)
    assert [(c.method, c.scenario) for c in par] == [(c.method, c.scenario) for c in serial]
    assert all(len(c.values) == 2 and all(map(math.isfinite, c.values)) for c in serial if not c.error)
    assert league_csv(par) == league_csv(serial)


def test_seeds_share_the_physics_and_give_the_runs_of_separate_simulations(tmp_path):
    """A scenario whose command draws nothing from the seed is stepped once for all its seeds: each seed's run
    is, bit for bit, the run of its own simulate() call (which steps the physics itself); a joystick command
    (seeded references) gets its own physics per seed."""
    from bench.sim import assemble_run, physics_seed, run_physics

    scn = load_scenario("circle_vinyl", {"duration": 1.0})
    seeds = (0, 3, 4)
    grouped = Runner(cache_dir=tmp_path / "g").simulate_many([(scn, s) for s in seeds])
    # the reference steps the physics with each run's own seed (no physics_seed involved)
    own = [assemble_run(run_physics(scn, s), scn, s) for s in seeds]
    assert [r.content_hash() for r in grouped] == [r.content_hash() for r in own]
    assert len({r.content_hash() for r in grouped}) == len(seeds)  # the sensors differ per seed
    assert {physics_seed(scn, s) for s in seeds} == {0}
    joy = load_scenario("mandow_joystick_asphalt_pneumatic_20psi", {"duration": 1.0})
    assert joy.command.kind == "random" and physics_seed(joy, 3) == 3


def test_only_seeded_command_kinds_change_the_wheel_references():
    """SEEDED_COMMANDS names exactly the command kinds whose references move with the seed."""
    import numpy as np

    from bench.sim.commands import SEEDED_COMMANDS, wheel_reference
    from bench.spec import SCENARIO_DIR

    t = np.linspace(0.0, 30.0, 301)
    seen: set[str] = set()
    for path in sorted(SCENARIO_DIR.glob("*.toml")):
        try:
            scn = load_scenario(path.stem)
        except Exception:  # noqa: BLE001 - templates / non-scenario files
            continue
        kind = scn.command.kind
        if kind in seen:
            continue
        seen.add(kind)
        a, b = wheel_reference(t, scn.command, scn.platform, 0), wheel_reference(t, scn.command, scn.platform, 7)
        moved = not (np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]))
        assert moved == (kind in SEEDED_COMMANDS), kind
    assert SEEDED_COMMANDS <= seen


def test_league_jobs_read_each_scenario_once_per_part_and_cover_every_cell():
    """_jobs deals a scenario's methods into at most `workers` parts of similar cost; every cell exactly once."""
    from bench.reproduce.league import CELL_COST, _jobs

    names = list(CELL_COST) + ["baseline.ideal_dd", "wang2015.constant_chi"]
    pairs = [(n, s) for s in ("a", "b", "c") for n in names]
    jobs = _jobs(pairs, 2)
    cells = [(n, s) for names_, s in jobs for n in names_]
    assert sorted(cells) == sorted(pairs)
    for s in ("a", "b", "c"):
        parts = [names_ for names_, s_ in jobs if s_ == s]
        assert len(parts) == 2
        costs = sorted(sum(CELL_COST.get(n, 0.5) for n in p) for p in parts)
        assert costs[1] - costs[0] <= max(CELL_COST.values())  # greedy: within one cell's cost
    cost = [sum(CELL_COST.get(n, 0.5) for n in names_) for names_, _ in jobs]
    assert cost == sorted(cost, reverse=True)
    # two scenarios per worker or more: one job per scenario (its runs read once)
    four = [(n, s) for s in "abcd" for n in names]
    jobs = _jobs(four, 2)
    assert sorted(s for _, s in jobs) == list("abcd") and sorted(c for n_, s in jobs for c in ((n, s) for n in n_)) == sorted(four)
