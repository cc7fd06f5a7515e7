"""Reproduction machinery: declared tables and computed claim verdicts, metrics.json, compare,
the run cache, atomic writes, serial vs parallel identity."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from bench import reproduce as R
from bench.cli.reproduce import compare_metrics
from bench.report.io import dumps_json
from bench.reproduce.runner import Runner
from bench.spec import SpecError
from bench.spec import load_scenario

PAPER = textwrap.dedent('''
    paper = "fake"
    title = "A fake paper"
    citation = "Nobody 2026"
    module = "tests.fixtures.fake_paper"

    [[tables]]
    id = "t1"
    title = "Straight line"
    source = "Table 1"
    compute = "straight"
      [[tables.rows]]
      metric = "speed"
      label = "steady speed"
      published = 0.194
      tolerance_rel = 0.05
      [[tables.rows]]
      metric = "double"
      published = 10.0
      tolerance_abs = 0.1

    [[claims]]
    id = "order"
    text = "speed < double"
    kind = "ordering"
    metrics = ["t1.speed", "t1.double"]

    [[claims]]
    id = "ratio"
    text = "double is 3x speed"
    kind = "within"
    metric = "t1.double"
    value = 3.0
    tolerance_rel = 0.01
''')


@pytest.fixture
def paper_dir(tmp_path, monkeypatch):
    d = tmp_path / "papers"
    d.mkdir()
    (d / "fake.toml").write_text(PAPER)
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", d)  # where load_paper and list_papers look it up
    return d


def test_claims_are_computed_not_written(paper_dir, tmp_path):
    runner = Runner(cache_dir=tmp_path / "cache")
    res = R.reproduce_paper("fake", runner, tmp_path / "results")
    speed = res.metrics["t1.speed"]
    assert 0.18 < speed < 0.2
    rows = {r["metric"]: r for r in res.tables[0]["rows_out"]}
    assert rows["speed"]["verdict"].startswith("matches")
    assert rows["double"]["verdict"].startswith("differs")
    claims = {c["id"]: c for c in res.claims}
    assert claims["order"]["holds"] is True
    assert claims["ratio"]["holds"] is False and "3.0" in claims["ratio"]["measured"]
    assert claims["order"]["verdict"] == "holds" and claims["ratio"]["verdict"] == "does not hold"
    assert claims["ratio"]["fails_if"] == "t1.double outside [2.97, 3.03]"
    md = (tmp_path / "results" / "fake" / "t1.md").read_text()
    assert "| steady speed |" in md and "0.194" in md
    readme = (tmp_path / "results" / "fake" / "README.md").read_text()
    assert readme.index("### Headline claims") < readme.index("speed < double") < readme.index("[Straight line](t1.md)")
    assert "**no cause given**" in readme  # the failing claim of the paper declares no cause
    assert '<a id="claim-ratio"></a>' in (tmp_path / "results" / "fake" / "claims_details.md").read_text()


def test_evaluate_claim_kinds():
    m = {"a.x": 1.0, "a.y": 2.0, "a.z": 1.5}
    assert R.evaluate_claim({"kind": "ordering", "metrics": ["a.x", "a.y"]}, m)[0] is True
    assert R.evaluate_claim({"kind": "ordering", "metrics": ["a.y", "a.x"]}, m)[0] is False
    assert R.evaluate_claim({"kind": "ratio", "num": "a.x", "den": "a.y", "op": "<=", "value": 0.5}, m)[0] is True
    assert R.evaluate_claim({"kind": "trend", "series": ["a.y", "a.z", "a.x"], "direction": "decreasing"}, m)[0] is True
    assert R.evaluate_claim({"kind": "trend", "series": ["a.x", "a.y"], "direction": "decreasing"}, m)[0] is False
    assert R.evaluate_claim({"kind": "within", "metric": "a.z", "value": 1.4, "tolerance_abs": 0.2}, m)[0] is True
    assert R.evaluate_claim({"kind": "flag", "metric": "a.x"}, m)[0] is True
    assert R.evaluate_claim({"kind": "flag", "metric": "a.missing"}, m)[0] is None


def test_ordering_claim_with_a_margin_holds_only_beyond_it():
    """a < b by 1.0: holds with a margin of 0.9, not with 1.1 (an ordering inside the sampling error), and a
    missing margin metric is a missing metric, not a pass."""
    m = {"a.x": 1.0, "a.y": 2.0, "a.small": 0.9, "a.big": 1.1}
    claim = {"kind": "ordering", "metrics": ["a.x", "a.y"]}
    ok, text = R.evaluate_claim({**claim, "margin": "a.small"}, m)
    assert ok is True and "by more than small = 0.9" in text
    assert R.evaluate_claim({**claim, "margin": "a.big"}, m)[0] is False
    assert R.evaluate_claim({**claim, "margin": "a.none"}, m)[0] is None
    assert R.claim_metric_ids({**claim, "margin": "a.big"}) == ["a.x", "a.y", "a.big"]


def test_paired_margin_is_two_standard_errors_of_the_mean_difference():
    """Independent paired differences (sd 1, 20000 pairs): two standard errors 2 / sqrt(n) (closed form) within
    10 %; MA(1) differences e_k - e_(k-1) (adjacent segments sharing a reference sample) have a sum that
    telescopes, so the batch-means margin is far below the iid formula's 2 sqrt(2) / sqrt(n)."""
    import numpy as np
    from methods.mandow2007.repro import paired_margin

    rng = np.random.default_rng(5)
    n = 20_000
    d = rng.standard_normal(n)
    assert paired_margin(d, np.zeros(n)) == pytest.approx(2.0 / np.sqrt(n), rel=0.1)
    e = rng.standard_normal(n + 1)
    ma = e[1:] - e[:-1]
    assert paired_margin(ma, np.zeros(n)) < 0.5 * 2.0 * np.sqrt(2.0) / np.sqrt(n)
    assert np.isnan(paired_margin(d[:15], np.zeros(15)))


def test_cache_second_run_simulates_nothing(tmp_path):
    scn = load_scenario("straight_0p2_vinyl", {"duration": 1.0})
    r1 = Runner(cache_dir=tmp_path)
    a = r1.simulate_many([(scn, 0), (scn, 1), (scn, 0)])
    assert r1.stats["simulated"] == 2
    r2 = Runner(cache_dir=tmp_path)
    b = r2.simulate_many([(scn, 0), (scn, 1)])
    assert r2.stats["simulated"] == 0 and r2.stats["cached"] == 2
    assert a[0].content_hash() == b[0].content_hash()


def test_serial_and_parallel_runs_identical(tmp_path):
    scn = load_scenario("circle_vinyl", {"duration": 2.0})
    reqs = [(scn, s) for s in range(3)]
    serial = Runner(cache_dir=tmp_path / "s", workers=1).simulate_many(reqs)
    par = Runner(cache_dir=tmp_path / "p", workers=2).simulate_many(reqs)
    assert [r.content_hash() for r in serial] == [r.content_hash() for r in par]


def test_compare_flags_broken_method_by_name(paper_dir, tmp_path, monkeypatch):
    runner = Runner(cache_dir=tmp_path / "cache")
    base = R.metrics_document([R.reproduce_paper("fake", runner, tmp_path / "r1")], quick=True)
    same = R.metrics_document([R.reproduce_paper("fake", runner, tmp_path / "r2")], quick=True)
    assert compare_metrics(base, same) == []
    monkeypatch.setenv("SKIDBENCH_BREAK_METHOD", "1")
    broken = R.metrics_document([R.reproduce_paper("fake", runner, tmp_path / "r3")], quick=True)
    moved = compare_metrics(base, broken)
    assert {m["metric"] for m in moved} == {"fake.t1.speed", "fake.t1.double"}
    b, n = tmp_path / "base.json", tmp_path / "new.json"
    b.write_text(json.dumps(base))
    n.write_text(json.dumps(broken))
    out = subprocess.run([sys.executable, "-m", "bench.cli", "compare", str(b), str(n)], capture_output=True, text=True)
    assert out.returncode == 1 and "fake.t1.speed" in out.stdout


def test_interrupted_write_leaves_no_partial_file(tmp_path):
    from bench.report.io import atomic_path

    target = tmp_path / "results" / "table.md"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half of a ta")
            raise RuntimeError("killed")
    assert not target.exists()
    assert list((tmp_path / "results").iterdir()) == []


def test_manifest_reproduces_in_fresh_processes(paper_dir, tmp_path):
    """Determinism suite: the runs a reproduction used re-simulate to identical content hashes in
    fresh processes, serially and with two workers; a tampered hash is reported."""
    runner = Runner(cache_dir=tmp_path / "cache")
    R.reproduce_paper("fake", runner, tmp_path / "r")
    man = tmp_path / "manifest.json"
    man.write_text(dumps_json(runner.manifest))  # as reproduce writes it: strict JSON, inf as "inf"
    assert '"command_limit_mean": "inf"' in man.read_text()  # the default platform has no command limit
    for workers in ("1", "2"):
        out = subprocess.run([sys.executable, "-m", "bench.cli", "verify-runs", str(man), "--workers", workers],
                             capture_output=True, text=True)
        assert out.returncode == 0, out.stdout + out.stderr
        assert "2/2 runs re-simulated to identical" in out.stdout
    bad = json.loads(man.read_text())
    key = sorted(bad["runs"])[0]
    bad["runs"][key]["content_hash"] = "0" * 64
    man.write_text(json.dumps(bad))
    out = subprocess.run([sys.executable, "-m", "bench.cli", "verify-runs", str(man)], capture_output=True, text=True)
    assert out.returncode == 1 and "MISMATCH" in out.stdout


def test_second_reproduce_comes_from_the_result_cache(paper_dir, tmp_path):
    runner = Runner(cache_dir=tmp_path / "cache")
    first = R.reproduce_paper("fake", runner, tmp_path / "a")
    runner2 = Runner(cache_dir=tmp_path / "cache")
    second = R.reproduce_paper("fake", runner2, tmp_path / "b")
    assert (runner2.stats["simulated"], runner2.stats["cached"]) == (0, 0)  # not even a cached run was read
    assert runner2.stats["result_cache_hits"] == 1
    assert second.metrics == first.metrics
    for name in ("t1.md", "t1_extra.md"):  # also the files the compute function wrote itself
        assert (tmp_path / "a" / "fake" / name).read_bytes() == (tmp_path / "b" / "fake" / name).read_bytes()
    # and the manifest still lists the runs the numbers come from (an empty runs_manifest.json had been written)
    assert runner.manifest["runs"] and runner2.manifest == runner.manifest


def test_a_cached_reproduce_writes_the_same_runs_manifest(paper_dir, tmp_path):
    """reproduce_papers twice into two folders: the second takes the paper from the result cache and writes the same
    runs_manifest.json, byte for byte."""
    for out in ("a", "b"):
        R.reproduce(["fake"], results_dir=tmp_path / out, cache_dir=tmp_path / "cache", log=lambda s: None)
    a, b = ((tmp_path / out / "runs_manifest.json").read_text() for out in ("a", "b"))
    assert json.loads(a)["runs"] and a == b


@pytest.mark.parametrize("paper", R.list_papers())
def test_every_paper_declaration_is_consistent(paper):
    """Every shipped declaration loads: unique table and claim ids, every claim reads metrics of a
    declared table, every table names a compute function of its module."""
    import importlib

    decl = R.load_paper(paper)
    module = importlib.import_module(decl["module"])
    for tab in decl["tables"]:
        assert callable(getattr(module, tab["compute"])), (paper, tab["id"])


def test_claim_naming_an_undeclared_table_is_rejected(paper_dir):
    text = (paper_dir / "fake.toml").read_text().replace('"t1.double"]', '"t9.double"]')
    (paper_dir / "fake.toml").write_text(text)
    with pytest.raises(SpecError) as ei:
        R.load_paper("fake")
    assert ei.value.field == "claims[0]" and "t9.double" in str(ei.value)


def test_parallel_papers_write_the_same_bytes_as_serial(paper_dir, tmp_path):
    """``workers > 1`` runs the papers as jobs in a process pool: same metrics, tables and manifest.
    (The monkeypatched PAPERS_DIR reaches the workers because Linux forks them: Python 3.11's default.)"""
    (paper_dir / "fake2.toml").write_text(PAPER.replace('paper = "fake"', 'paper = "fake2"'))
    out = {}
    for workers in (1, 2):
        res = tmp_path / f"results{workers}"
        got = R.reproduce(["fake", "fake2"], workers=workers, results_dir=res, log=lambda s: None,
                          cache_dir=tmp_path / f"cache{workers}" / "runs")
        assert [r.paper for r in got] == ["fake", "fake2"]
        out[workers] = {p.relative_to(res).as_posix(): p.read_bytes() for p in sorted(res.rglob("*"))
                        if p.is_file() and p.name not in ("REPORT.md", "history.jsonl")}
    assert out[1].keys() == out[2].keys() and "runs_manifest.json" in out[1]
    assert {k for k in out[1] if out[1][k] != out[2][k]} == set()


def test_report_links_the_extras_that_exist_and_a_rerun_replaces_the_section(tmp_path):
    rep = tmp_path / "REPORT.md"
    rep.write_text("# r\n\n## Summary\n\n| a |\n\n<a id=\"p\"></a>\n## Paper p\n\ntext\n")
    (tmp_path / "league.md").write_text("x")
    R.link_extras(tmp_path, quick=False)
    first = rep.read_text()
    assert "[league.md](league.md)" in first and "stress.md" not in first
    assert first.index("Beyond the papers") < first.index('<a id="p">') and first.endswith("## Paper p\n\ntext\n")
    (tmp_path / "stress.md").write_text("y")
    R.link_extras(tmp_path, quick=False)
    second = rep.read_text()
    assert second.count("Beyond the papers") == 1 and "[stress.md](stress.md)" in second
    assert second.replace("- [stress.md](stress.md): " + dict(R.EXTRA_RESULTS)["stress.md"] + "\n", "") == first


def test_extra_is_kept_only_while_the_results_folder_holds_its_output(tmp_path, monkeypatch):
    """`reproduce <extra>` skips an extra whose marker (code, data, output folder) exists only while the folder still
    holds the files that run wrote, with their content: a file reset (e.g. `git checkout results`), deleted, or a
    marker of the earlier format without the record recomputes it; an unchanged folder keeps it."""
    import argparse

    import bench.cli.reproduce as C
    import bench.reproduce.runner

    monkeypatch.setattr(bench.reproduce.runner, "DEFAULT_CACHE", tmp_path / "cache" / "runs")
    calls = []

    def fake_extra(results_dir, quick, workers=1):
        calls.append(1)
        (results_dir / "fake").mkdir(parents=True, exist_ok=True)
        (results_dir / "fake" / "out.md").write_text(f"run {len(calls)}\n")

    monkeypatch.setitem(C.EXTRAS, "fake_extra", fake_extra)
    res = tmp_path / "results"
    (res / "other").mkdir(parents=True)
    (res / "other" / "paper.md").write_text("not the extra's\n")
    args = argparse.Namespace(papers=["fake_extra"], all=False, quick=False, workers=1, dask_scheduler=None,
                              results=res)
    out = res / "fake" / "out.md"
    C._reproduce(args)
    marker = C._extra_marker("fake_extra", res, False)
    assert len(calls) == 1 and json.loads(marker.read_text())["outputs"].keys() == {"fake/out.md"}
    C._reproduce(args)
    assert len(calls) == 1  # kept
    out.write_text("an older run\n")  # the folder reset to other content
    C._reproduce(args)
    assert len(calls) == 2 and out.read_text() == "run 2\n"
    out.unlink()
    C._reproduce(args)
    assert len(calls) == 3 and out.is_file()
    marker.write_text("done\n")  # the earlier format
    C._reproduce(args)
    assert len(calls) == 4
    C._reproduce(args)
    assert len(calls) == 4


def test_an_extra_records_only_its_own_files_while_papers_write_beside_it(tmp_path, monkeypatch):
    """An extra run beside the papers records in its marker only the files under its output prefixes: a paper's file
    written at the same time is not the extra's (else a later reset of that paper file would recompute the extra)."""
    import bench.cli.reproduce as C
    import bench.reproduce.runner

    monkeypatch.setattr(bench.reproduce.runner, "DEFAULT_CACHE", tmp_path / "cache" / "runs")
    res = tmp_path / "results"
    (res / "yi2009").mkdir(parents=True)

    def extra(results_dir, quick, workers=1):
        (results_dir / "yi2009" / "table.csv").write_text("a paper's file, written meanwhile\n")
        (results_dir / "league.md").write_text("the extra's\n")

    monkeypatch.setitem(C.EXTRAS, "league", extra)
    stages = C._extras_job(["league"], res, False, 1, False)
    marker = C._extra_marker("league", res, False)
    assert json.loads(marker.read_text())["outputs"].keys() == {"league.md"}
    assert stages["league"]["from_cache"] is False
    assert C.EXTRA_OUTPUTS["league"] == ("league",) and C.EXTRA_OUTPUTS["stress"] == ("stress",)


def test_the_result_key_ignores_where_the_caches_are(monkeypatch):
    """The result cache's key (provenance.code_key) hashes the SKIDBENCH_* settings that change a result (e.g. the
    kernel) but not the ones that only say where caches live: CI's SKIDBENCH_TEST_CACHE lets the test fixtures find
    the quick results the command line has just made."""
    from bench.reproduce.provenance import code_key

    for var in ("SKIDBENCH_CACHE", "SKIDBENCH_TEST_CACHE", "SKIDBENCH_KERNEL"):
        monkeypatch.delenv(var, raising=False)
    base = code_key("yi2009", "True")
    monkeypatch.setenv("SKIDBENCH_TEST_CACHE", "/somewhere/runs")
    monkeypatch.setenv("SKIDBENCH_CACHE", "/elsewhere/runs")
    assert code_key("yi2009", "True") == base
    monkeypatch.setenv("SKIDBENCH_KERNEL", "python")
    assert code_key("yi2009", "True") != base


def test_compiled_extensions_are_found_by_file_and_enter_the_result_key(tmp_path, monkeypatch):
    """A C source with a module this interpreter loads beside it is "built" (a copy of the testbed's own), one whose
    source changed after it was built "stale", one that does not load "fails to load", one without a module
    "not built"; SKIDBENCH_KERNEL=python turns a built one "off"; a module built for another interpreter does not
    count.  The result cache's key changes with that state: a result computed with Mandow's numpy cost (a checkout
    whose build failed) is never served to one with the C cost (the DE polish moves the league's DE row in the 5th
    digit)."""
    import os
    import shutil
    from importlib.machinery import EXTENSION_SUFFIXES

    from bench.reproduce import provenance as P
    from bench.sim import testbed

    if testbed.KERNEL is None:
        pytest.skip("the testbed's C step is not built here")
    monkeypatch.delenv("SKIDBENCH_KERNEL", raising=False)
    sim, old, paper = tmp_path / "bench" / "sim", tmp_path / "bench" / "old", tmp_path / "methods" / "paper"
    for d in (sim, old, paper):
        d.mkdir(parents=True)
    for d in (sim, old):  # the module must keep its name: its init function is PyInit__kernel
        (d / "_kernel.c").write_text("")
        shutil.copy(testbed.KERNEL.__file__, d / f"_kernel{EXTENSION_SUFFIXES[0]}")
    later = os.stat(old / f"_kernel{EXTENSION_SUFFIXES[0]}").st_mtime + 10
    os.utime(old / "_kernel.c", (later, later))
    (paper / "_cost.c").write_text("")
    (paper / "_cost.cpython-299-x86_64-linux-gnu.so.bak").write_bytes(b"")
    (paper / "_broken.c").write_text("")
    (paper / f"_broken{EXTENSION_SUFFIXES[0]}").write_bytes(b"not an ELF file")
    assert P.compiled_extensions(tmp_path) == {
        "bench.old._kernel": "stale", "bench.sim._kernel": "built", "methods.paper._broken": "fails to load",
        "methods.paper._cost": "not built"}
    monkeypatch.setenv("SKIDBENCH_KERNEL", "python")
    assert P.compiled_extensions(tmp_path)["bench.sim._kernel"] == "off"
    monkeypatch.delenv("SKIDBENCH_KERNEL")

    base = P.code_key("mandow2007", "False")
    built = P.compiled_extensions()
    monkeypatch.setattr(P, "compiled_extensions", lambda: {**built, "methods.mandow2007._cost": "not built"})
    assert P.code_key("mandow2007", "False") != base
