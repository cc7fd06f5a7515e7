"""Regression dashboard (bench/report/dashboard.py, `skidbench dashboard`) on histories built here (tmp dirs).

`built`: 10 runs (drift within tolerance, a jump at a known commit, a NaN gap, a metric never finite, a paper only in
later runs, quick/cold/warm runs, a `make bench` per commit); `crowded`: 60 runs, dirty commits, a table of 120 metrics
(60 jump at one commit, 60 never move), a small page budget.  Expectations come from that construction.  Headless
Chromium opens every page: every chart rendered, no overlapping axis labels; it must flag a chart without its series
and one with unthinned labels; screenshots show the charts.  The committed history renders to pages under 2 MB.
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from bench.report.bench_history import load_bench_history, record_bench
from bench.report.dashboard import render_dashboard
from bench.report.io import dumps_json
from bench.spec import SpecError
from tests.test_strict_json import strict_loads

REPO = Path(__file__).resolve().parents[1]
N_RUNS = 10
QUICK = (2, 6)            # runs made with --quick
JUMP = 5                  # alpha.t1.chi jumps from 1.40 to 1.82 at this run
NAN_AT = 3                # alpha.t2.gap is NaN in this run
BETA_FROM = 6             # paper beta appears from this run on
BENCH_B_FROM = 5
MB2 = 2_000_000


def _history() -> list[dict]:
    rng = np.random.default_rng(7)
    out = []
    for i in range(N_RUNS):
        quick = i in QUICK
        m = {"alpha.t1.rms": (0.22 if quick else 0.20) * (1 + 0.01 * i),      # 1 %/run, tolerance 5 %
             "alpha.t1.chi": 1.41 if quick else (1.40 if i < JUMP else 1.82),
             "alpha.t2.gap": float("nan") if i == NAN_AT else 0.5, "alpha.t2.never": float("nan"),
             **({"beta.t9.err": 3.0 + 0.01 * i} if i >= BETA_FROM else {})}
        out.append({"commit": rng.bytes(20).hex(), "date": f"2026-11-{1 + i:02d}T08:30:00+00:00", "quick": quick,
                    "seconds": 100.0 + i, "metrics": m, "bench": {"test_bench_a": 99.0}, "cold": i % 4 == 0})
    return out


def _bench_means(i: int) -> dict[str, float]:
    return {"test_bench_a": 0.012 * (1 + 0.002 * i), **({"test_bench_b[circle]": 2.5e-5} if i >= BENCH_B_FROM else {})}


def _pytest_benchmark_json(path: Path, means: dict[str, float], date: str, cpu: str) -> Path:
    path.write_text(json.dumps({"machine_info": {"cpu": {"brand_raw": cpu}, "python_version": "3.11.7"},
                                "datetime": date, "version": "5.3.1", "benchmarks": [
        {"name": k, "fullname": f"tests/bench/x.py::{k}", "stats": {"mean": v, "stddev": v / 100, "rounds": 7,
                                                                     "min": v, "max": v}} for k, v in means.items()]}))
    return path


BASELINE = {"quick": False, "commit": "x", "metrics": {
    "alpha.t1.rms": {"value": 0.218, "published": 0.3, "tolerance": {"rel": 0.05, "abs": 1e-6}},
    "alpha.t1.chi": {"value": 1.82, "published": 1.456, "tolerance": {"rel": 0.05, "abs": 1e-6}},
    "beta.t9.err": {"value": 3.09, "published": None, "tolerance": {"rel": 0.05, "abs": 1e-6}},
}}


def _write_results(d: Path, hist: list[dict], baseline: dict = BASELINE, cpus=lambda i: "Test CPU") -> Path:
    d.mkdir(parents=True, exist_ok=True)  # history as bench.reproduce.append_history writes it: a NaN metric as null
    (d / "history.jsonl").write_text("".join(dumps_json(h, sort_keys=True) + "\n" for h in hist))
    (d / "metrics.json").write_text(json.dumps(baseline))
    for i, h in enumerate(hist):  # one `make bench` per commit
        latest = _pytest_benchmark_json(d / "latest.json", _bench_means(i), h["date"][:19] + ".123456+00:00", cpus(i))
        record_bench(latest, d / "bench_history.jsonl", commit=h["commit"])
    (d / "latest.json").unlink()
    return d


def _finite(hist: list[dict], mid: str) -> list[tuple[float, str]]:
    return [(h["metrics"][mid], h["commit"]) for h in hist if mid in h["metrics"] and math.isfinite(h["metrics"][mid])]


class _Page(HTMLParser):
    """Charts (attributes, markers, published line y, polylines, series labels, x labels), rows, ids, list items."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.charts, self.trs, self.items, self.ids, self._texts = [], [], [], set(), []
        self.cur = self.status = self._xtick = None
        self._title, self._mode = False, ""
        self.feed(text)
        self.text = "".join(self._texts)

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        cls = a.get("class", "").split()
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "svg" and "chart" in cls:
            self.cur = {"attrs": a, "points": [], "published": [], "polylines": {}, "series": [], "xlabels": []}
            self.charts.append(self.cur)
        elif self.cur is not None:
            if tag == "circle" and "pt" in cls:
                self.cur["points"].append((float(a["data-value"]), float(a["cy"]), a["data-commit"], "step" in cls))
            elif tag == "line" and "published" in cls:
                self.cur["published"].append(float(a["y1"]))
            elif tag == "g" and "series" in cls:
                self._mode = a["data-mode"]
                self.cur["series"].append(a["data-label"])
            elif tag == "polyline":
                self.cur["polylines"][self._mode] = self.cur["polylines"].get(self._mode, 0) + 1
            elif tag in ("text", "title"):
                self._xtick, self._title = ([], False) if "xtick" in cls else (self._xtick, tag == "title")
        self.status = a if tag == "p" and a.get("id") == "render-status" else self.status
        self.trs += [a] if tag == "tr" else []
        self.items += [a] if tag == "li" and "data-id" in a else []
        if tag == "a" and self.items and "href" not in self.items[-1]:
            self.items[-1]["href"] = a["href"]

    def handle_endtag(self, tag):
        self.cur = None if tag == "svg" else self.cur
        self._title = False if tag == "title" else self._title
        if tag == "text" and self._xtick is not None and self.cur is not None:
            self.cur["xlabels"].append(" ".join(self._xtick))
            self._xtick = None

    def handle_data(self, data):
        self._texts.append(data)
        if self._xtick is not None and data.strip() and self.cur is not None and not self._title:
            self._xtick.append(data.strip())


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    hist = _history()
    res = _write_results(tmp_path_factory.mktemp("results"), hist)
    return hist, res, render_dashboard(res, res / "dashboard")


def _read(res: Path, name: str) -> _Page:
    return _Page((res / "dashboard" / name).read_text())


def _charts(res: Path, names) -> dict[str, dict]:
    return {c["attrs"]["data-metric"]: c for n in names for c in _read(res, n).charts}


# ------------------------------------------------------------------------------------------ static
def _is_quick(hist, commit):
    return next(h["quick"] for h in hist if h["commit"] == commit)


def test_every_metric_with_a_finite_value_has_a_chart_with_its_values_and_published_line(built):
    hist, res, _ = built
    expected = {"alpha.t1.html": ["alpha.t1.chi", "alpha.t1.rms"], "alpha.t2.html": ["alpha.t2.gap"],
                "beta.t9.html": ["beta.t9.err"]}  # one page per (paper, table); small tables chart every metric
    for page, mids in expected.items():
        p = _read(res, page)
        assert sorted(c["attrs"]["data-metric"] for c in p.charts) == mids, page
        for c in p.charts:  # full run markers first, then quick ones; each in history order
            want = _finite(hist, mid := c["attrs"]["data-metric"])
            order = [x for x in want if not _is_quick(hist, x[1])] + [x for x in want if _is_quick(hist, x[1])]
            assert [(v, commit) for v, _, commit, _ in c["points"]] == order, mid
            assert int(c["attrs"]["data-points"]) == len(want)
    t2 = _read(res, "alpha.t2.html")
    assert "alpha.t2.never" in t2.text and "Not charted" in t2.text
    assert t2.charts[0]["polylines"] == {"full": 2, "quick": 1}  # the full series is broken at the NaN run
    assert sorted(f.name for f in (res / "dashboard").iterdir()) == [
        "alpha.html", "alpha.t1.html", "alpha.t2.html", "beta.html", "beta.t9.html", "index.html", "metrics.html",
        "speed.html"]
    # the value axis and the published line
    charts = _charts(res, ["alpha.t1.html", "alpha.t2.html"])
    for c in charts.values():  # larger value -> higher on the page (smaller y)
        pts = sorted(c["points"])
        assert all(a[1] >= b[1] for a, b in zip(pts, pts[1:]))
    rms, chi = charts["alpha.t1.rms"], charts["alpha.t1.chi"]
    assert len(rms["published"]) == 1 and rms["published"][0] < min(p[1] for p in rms["points"])  # 0.3 above all
    y_pub = chi["published"][0]                                    # 1.456 between 1.40/1.41 and 1.82
    assert max(p[1] for p in chi["points"] if p[0] > 1.456) < y_pub < min(p[1] for p in chi["points"] if p[0] < 1.456)
    assert charts["alpha.t2.gap"]["published"] == []               # no published value, no line
    assert _read(res, "beta.t9.html").charts[0]["published"] == []


def _pairs(p: _Page) -> dict[tuple[str, str, str], dict]:
    return {(r["data-before"], r["data-after"], r["data-mode"]): r for r in p.trs if r.get("class") == "pair"}


def test_changes_beyond_tolerance_are_grouped_by_commit_pair(built):
    hist, res, pages = built
    full = [h for h in hist if not h["quick"]]
    jump_prev = full[[h["commit"] for h in full].index(hist[JUMP]["commit"]) - 1]
    nan_prev = full[[h["commit"] for h in full].index(hist[NAN_AT]["commit"]) - 1]
    got = {(s.metric, s.mode, s.before.commit, s.after.commit) for s in pages.steps}
    assert got == {("alpha.t1.chi", "full", jump_prev["commit"], hist[JUMP]["commit"]),
                   ("alpha.t2.gap", "full", nan_prev["commit"], hist[NAN_AT]["commit"])}
    want = {(jump_prev["commit"], hist[JUMP]["commit"], "full"): "1", (nan_prev["commit"], hist[NAN_AT]["commit"], "full"): "1"}
    for name in ("alpha.html", "index.html"):
        assert {k: r["data-count"] for k, r in _pairs(_read(res, name)).items()} == want, name
    alpha = _read(res, "alpha.html")
    assert [r["data-metric"] for r in alpha.trs if r.get("class") == "moved"] == ["alpha.t1.chi", "alpha.t2.gap"]
    assert jump_prev["commit"][:7] in alpha.text and hist[JUMP]["commit"][:7] in alpha.text
    chi = _charts(res, ["alpha.t1.html"])["alpha.t1.chi"]
    assert [p[2] for p in chi["points"] if p[3]] == [hist[JUMP]["commit"]]   # the marked point
    assert "None: no metric moved" in _read(res, "beta.html").text


def test_pages_show_commit_ids_and_dates(built):
    hist, res, _ = built
    index, alpha, beta = (_read(res, n).text for n in ("index.html", "alpha.html", "beta.html"))
    for i, h in enumerate(hist):
        assert h["commit"] in index and h["date"] in index
        assert h["commit"] in alpha and h["date"][:10] in alpha
        assert (h["commit"] in beta) == (i >= BETA_FROM)
    rms = _charts(res, ["alpha.t1.html"])["alpha.t1.rms"]
    # x labels: short sha + day (MM-DD); the latest run is labelled; the full commit is in every marker
    assert rms["xlabels"][-1] == f"{hist[-1]['commit'][:7]} 11-10"
    assert all(re.fullmatch(r"[0-9a-f]{7}\+? \d\d-\d\d", x) for x in rms["xlabels"])
    assert {p[2] for p in rms["points"]} == {h["commit"] for h in hist}
    from bench.report.chart import MR, ML, W, shown_labels  # labels thinned, never closer than their width

    mono = 0.62 * 9  # the widest monospace digit (DejaVu Sans Mono 0.602 em) at the labels' 9 px
    for n in range(1, 400):
        for chars in (7, 8):
            shown = shown_labels(n, chars)
            assert shown[-1] == n - 1 and shown == sorted(set(shown))
            if n > 1:
                dx = (W - ML - MR) * 0.94 / (n - 1)
                assert min(b - a for a, b in zip(shown, shown[1:]) or [n]) * dx >= chars * mono + 2, (n, chars)
    assert shown_labels(37, 8, thin=False) == list(range(37))


def test_speed_page_charts_bench_history_and_reproduce_times_cold_and_warm(built):
    hist, res, pages = built
    runs = load_bench_history(res / "bench_history.jsonl")
    assert [r.commit for r in runs] == [h["commit"] for h in hist]
    assert runs[0].date == hist[0]["date"] and runs[0].cpu == "Test CPU"  # to the second, from pytest-benchmark
    charts = _charts(res, ["speed.html"])
    assert set(charts) == {"reproduce wall time (the papers)", "test_bench_a", "test_bench_b[circle]"}
    wall, cold = charts["reproduce wall time (the papers)"], [h["seconds"] for h in hist if h["cold"]]
    assert wall["series"] == ["full run, cold (nothing cached)", "full run, warm (caches used)", "quick run, warm (caches used)"]
    assert [v for v, *_ in wall["points"]][:len(cold)] == cold
    assert sorted(v for v, *_ in wall["points"]) == sorted(h["seconds"] for h in hist)
    assert [round(v, 9) for v, *_ in charts["test_bench_a"]["points"]] == [  # bench_history, not the lines' "bench"
        round(_bench_means(i)["test_bench_a"] * 1e3, 9) for i in range(N_RUNS)]
    b = [v for v, *_ in charts["test_bench_b[circle]"]["points"]]
    assert len(b) == N_RUNS - BENCH_B_FROM and all(math.isclose(v, 25.0) for v in b)  # 2.5e-5 s shown in µs
    assert "µs" in (text := _read(res, "speed.html").text) and pages.charts["speed.html"] == 3 and "Test CPU" in text


def test_make_bench_appends_one_line_with_commit_cpu_and_stats(tmp_path, capsys):
    from bench.report import bench_history as BH

    latest, out = _pytest_benchmark_json(tmp_path / "latest.json", {"t1": 0.5, "t2[x]": 1e-4}, "2026-12-03T10:00:00.5+00:00",
                                         ""), tmp_path / "bench_history.jsonl"
    assert BH.main([str(latest), "--out", str(out)]) == 0
    assert BH.main([str(latest), "--out", str(out), "--commit", "abc"]) == 0
    lines = [strict_loads(x) for x in out.read_text().splitlines()]
    assert len(lines) == 2 and lines[1]["commit"] == "abc"
    assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?|unknown", lines[0]["commit"])  # git rev-parse HEAD (+dirty)
    assert lines[0]["date"] == "2026-12-03T10:00:00+00:00" and lines[0]["cpu"]  # no brand_raw: /proc/cpuinfo
    assert lines[0]["benchmarks"] == {"t1": {"mean": 0.5, "stddev": 0.005, "rounds": 7},
                                      "t2[x]": {"mean": 1e-4, "stddev": 1e-6, "rounds": 7}}
    latest.write_text(latest.read_text().replace('"mean": 0.0001, ', ""))
    with pytest.raises(SpecError, match=r"latest\.json.*benchmarks\[1\]\.stats \(t2\[x\]\)\.mean"):
        record_bench(latest, out)
    assert BH.main([str(latest), "--out", str(out)]) == 2 and capsys.readouterr().err.count("\n") == 1
    assert len(out.read_text().splitlines()) == 2  # nothing appended
    recipe = re.search(r"^bench:.*?\n((?:\t.*\n)+)", (REPO / "Makefile").read_text(), re.M).group(1)
    assert re.search(r"--benchmark-json=.benchmarks/latest.json\n.*-m bench.report.bench_history .benchmarks/latest.json", recipe)


def test_same_input_same_bytes_and_no_temp_files(built, tmp_path):
    render_dashboard(res := built[1], tmp_path / "again")
    assert sorted(f.name for f in (tmp_path / "again").iterdir()) == sorted(f.name for f in (res / "dashboard").iterdir())
    assert all(f.read_bytes() == (tmp_path / "again" / f.name).read_bytes() for f in (res / "dashboard").iterdir())


def test_bad_history_is_named_by_file_line_and_field(tmp_path):
    good, d = json.dumps(_history()[0]), tmp_path / "r"
    d.mkdir()
    (d / "history.jsonl").write_text(good + "\n\n" + '{"commit": "abc", "metrics": {"a.b": 1.0}\n')
    with pytest.raises(SpecError, match=r"history\.jsonl.*line 3.*malformed JSON"):
        render_dashboard(d)
    (d / "history.jsonl").write_text(good + "\n" + '{"commit": "abc", "date": "2026-11-02"}\n')
    with pytest.raises(SpecError, match=r"line 2: metrics.*required field is missing"):
        render_dashboard(d)
    (d / "history.jsonl").write_text(good + "\n")
    (d / "bench_history.jsonl").write_text('{"commit": "a", "date": "d", "benchmarks": {"t": {"mean": -1, '
                                           '"stddev": 0, "rounds": 1}}}\n')
    with pytest.raises(SpecError, match=r"bench_history\.jsonl.*line 1: benchmarks\.t\.mean.*-1"):
        render_dashboard(d)
    with pytest.raises(SpecError, match="no history file"):
        render_dashboard(tmp_path / "nowhere")


def test_cli_dashboard_command(tmp_path, capsys, monkeypatch):
    import bench.cli.dashboard as D  # registers the command (bench.cli loads it too once listed)
    from bench.cli import main

    res = _write_results(tmp_path / "results", _history())
    assert main(["dashboard", "--results", str(res), "--out", str(tmp_path / "site")]) == 0
    assert (tmp_path / "site" / "index.html").is_file() and (tmp_path / "site" / "alpha.t1.html").is_file()
    assert "(7 charts, 0 compact rows, 2 changes beyond tolerance)" in capsys.readouterr().out  # alpha 3, beta 1, speed 3
    (res / "history.jsonl").write_text("not json\n")
    assert main(["dashboard", "--results", str(res)]) == 2
    assert "line 1" in capsys.readouterr().err
    calls = []  # --asv: the quick track_* benchmark, and how to view asv's site
    monkeypatch.setattr(D.shutil, "which", lambda name: "/bin/asv")
    monkeypatch.setattr(D.subprocess, "run", lambda cmd, **kw: calls.append(cmd) or subprocess.CompletedProcess(
        cmd, 0, stdout="0" * 40 + "\n", stderr=""))
    assert D.run_asv(REPO, tmp_path, tmp_path / "asv") == 0
    run = next(c for c in calls if c[1:2] == ["run"])
    assert "--quick" in run and run[run.index("--bench") + 1] == "DistanceToPublished"  # track_abs_error only
    assert "asv preview" in capsys.readouterr().out


# ------------------------------------------------------------------------------------------ a crowded history
N2, JUMP2, BUDGET2 = 60, 30, 200_000
JUMPERS = [f"gamma.big.j{j:03d}" for j in range(60)]
STABLE = [f"gamma.big.s{j:03d}" for j in range(60)]
SMALL = ["gamma.small.a", "gamma.small.b", "gamma.small.c"]


def _crowded_history() -> list[dict]:
    rng = np.random.default_rng(11)
    out = []
    for i in range(N2):
        m = {mid: (1.0 + j) * (1.5 if i >= JUMP2 else 1.0) for j, mid in enumerate(JUMPERS)}
        m.update({mid: (2.0 + j) * (1 + 0.001 * i) for j, mid in enumerate(STABLE)})
        m.update({"gamma.small.a": 3.0, "gamma.small.b": 0.5 + 0.001 * i, "gamma.small.c": -1.0})
        out.append({"commit": rng.bytes(20).hex() + ("+dirty" if i % 7 == 3 else ""), "quick": i % 5 == 4,
                    "date": f"2026-{11 + i // 30:02d}-{1 + i % 30:02d}T{i % 24:02d}:00:00+00:00", "seconds": 50.0 + i,
                    "metrics": m, **({"cold": i % 6 == 0, "stages": {"gamma": 10.0 + 0.1 * i, "league": 5.0}}
                                     if i >= 10 else {})})
    return out


@pytest.fixture(scope="module")
def crowded(tmp_path_factory):
    hist = _crowded_history()
    res = _write_results(tmp_path_factory.mktemp("crowded"), hist, {"metrics": {}},
                         cpus=lambda i: "CPU A" if i < 30 else "CPU B")
    return hist, res, render_dashboard(res, res / "dashboard", page_budget=BUDGET2)


def test_large_table_is_split_into_pages_stable_metrics_are_rows_and_every_metric_is_findable(built, crowded):
    site = crowded[1] / "dashboard"
    big = sorted(site.glob("gamma.big*.html"))
    assert len(big) >= 3 and (site / "gamma.big.html") in big
    charts, rows = [], []
    for f in big:
        p = _Page(f.read_text())
        charts += [c["attrs"]["data-metric"] for c in p.charts]
        rows += [r["data-metric"] for r in p.trs if r.get("class") == "stable"]
        assert f.stat().st_size < BUDGET2 + 60_000, f.name
    assert sorted(charts) == JUMPERS and sorted(rows) == STABLE  # every metric once
    assert sorted(_charts(crowded[1], ["gamma.small.html"])) == SMALL
    assert all(f.stat().st_size < MB2 for f in site.iterdir())
    for hist, res, _ in (built, crowded):  # the metric finder links every metric to its element
        p = _read(res, "metrics.html")
        assert sorted(i["data-id"] for i in p.items) == sorted({m for h in hist for m in h["metrics"]})
        assert 'id="metric-filter"' in (res / "dashboard" / "metrics.html").read_text()
        for it in p.items:
            page, anchor = it["href"].split("#")
            assert anchor in _read(res, page).ids, it


def test_many_changes_at_one_commit_are_one_row_with_a_capped_list(crowded):
    hist, res, pages = crowded
    full = [h for h in hist if not h["quick"]]
    after = next(h for h in full if hist.index(h) >= JUMP2)
    before = full[full.index(after) - 1]
    paper = _read(res, "gamma.html")
    assert _pairs(paper)[(before["commit"], after["commit"], "full")]["data-count"] == "60"
    assert len([r for r in paper.trs if r.get("class") == "moved"]) <= 2 * 50
    assert "and 10 more" in paper.text and "gamma.big\xa060" in paper.text
    assert _pairs(_read(res, "index.html"))[(before["commit"], after["commit"], "full")]["data-count"] == "60"
    speed = _charts(res, ["speed.html"])
    assert speed["test_bench_a"]["series"] == ["CPU A", "CPU B"]
    assert speed["stage gamma"]["series"] == [f"{m} run, {c}" for m in ("full", "quick")  # i % 6 == 0: cold
                                               for c in ("cold (nothing cached)", "warm (caches used)")]
    assert speed["reproduce wall time (the papers)"]["series"][2] == "full run, cache state not recorded"  # runs 0-9
    assert any(x.split()[0].endswith("+") for x in speed["reproduce wall time (the papers)"]["xlabels"])  # dirty commits


# ------------------------------------------------------------------------------------------ browser
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1400,1000"]
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="no headless Chromium (Debian: apt-get install -y chromium)")


def _chromium(page: Path, *args: str) -> str:
    with tempfile.TemporaryDirectory(prefix="skidbench-chromium-") as profile:
        out = subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args, page.resolve().as_uri()],
                             capture_output=True, text=True, timeout=180)
    assert out.returncode == 0, f"chromium failed on {page}: {out.stderr[-2000:]}"
    return out.stdout


def _dump_all(pages: list[Path]) -> dict[str, _Page]:
    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
        doms = dict(zip([p.name for p in pages], pool.map(lambda p: _chromium(p, "--dump-dom"), pages)))
    assert all("</html>" in d for d in doms.values())
    return {n: _Page(d) for n, d in doms.items()}


@pytest.fixture(scope="module")
def browsed(built):
    site = built[1] / "dashboard"
    broken, text = site / "broken.html", (site / "alpha.t1.html").read_text()  # one chart's series removed
    target = re.search(r'<svg class="chart" id="c-alpha-t1-rms".*?</svg>', text, re.S).group(0)
    broken.write_text(text.replace(target, re.sub(r'<g class="series.*?</g>', "", target, flags=re.S)))
    doms = _dump_all(sorted(site.glob("*.html")))
    broken.unlink()
    return built[0], doms


def _assert_all_ok(name: str, p: _Page, n: int | None = None) -> None:
    assert len(p.charts) == (n := len(p.charts) if n is None else n), name
    assert [(c["attrs"].get("data-rendered"), c["attrs"].get("data-labels")) for c in p.charts] == [("ok", "ok")] * n, name
    assert (s := p.status) and s["data-charts"] == s["data-ok"] == s["data-labels-ok"] == str(n), name
    assert s["data-sparks"] == s["data-sparks-ok"] and s["class"] == "ok", name
    assert f"{n} of {n} charts rendered; axis labels readable" in p.text, name


@needs_chromium
def test_chromium_renders_every_chart_with_readable_labels_and_flags_an_empty_one(browsed):
    hist, doms = browsed
    expected = {"index.html": 0, "metrics.html": 0, "alpha.html": 0, "beta.html": 0, "alpha.t1.html": 2,
                "alpha.t2.html": 1, "beta.t9.html": 1, "speed.html": 3}
    assert set(doms) == set(expected) | {"broken.html"}
    for name, n in expected.items():
        _assert_all_ok(name, doms[name], n)
    assert all(h["commit"] in doms["alpha.html"].text and h["date"][:10] in doms["alpha.html"].text for h in hist)
    p = doms["broken.html"]  # the check flags the chart without its series
    assert {c["attrs"]["data-metric"]: c["attrs"]["data-rendered"] for c in p.charts} == {
        "alpha.t1.rms": "empty", "alpha.t1.chi": "ok"}
    assert p.status["class"] == "bad" and p.status["data-ok"] == "1"
    assert "empty: c-alpha-t1-rms" in p.text


@needs_chromium
def test_chromium_crowded_history_every_page_readable(crowded):
    doms = _dump_all(sorted((crowded[1] / "dashboard").glob("*.html")))
    assert len(doms) >= 9 and all(_assert_all_ok(name, p) is None for name, p in doms.items())
    assert sum(int(p.status["data-sparks"]) for p in doms.values()) == len(STABLE)


@needs_chromium
def test_chromium_check_flags_overlapping_labels(tmp_path):
    from types import SimpleNamespace as Run

    from bench.report.chart import runs_chart, series_by_mode
    from bench.report.html_page import html_page

    runs = [Run(commit=f"{i:07x}abcdef", date=f"2026-12-{1 + i % 28:02d}T00:00", mode="full", index=i) for i in range(N2)]
    figs = [runs_chart(f"c-{thin}", f"thin={thin}", runs, lambda r: float(r.index % 5), series_by_mode, thin=thin)[0]
            for thin in (False, True)]
    (tmp_path / "crowded.html").write_text(html_page("crowded", ['<div class="charts">' + "".join(figs) + "</div>"], ""))
    p = _dump_all([tmp_path / "crowded.html"])["crowded.html"]
    assert {c["attrs"]["id"]: c["attrs"]["data-labels"] for c in p.charts} == {"c-False": "overlap", "c-True": "ok"}
    assert len(p.charts[0]["xlabels"]) == N2 and len(p.charts[1]["xlabels"]) < 12
    assert p.status["class"] == "bad" and "overlapping axis labels: c-False" in p.text


@needs_chromium
def test_screenshots_show_the_charts(built, browsed, tmp_path):
    from PIL import Image

    from bench.report.chart import COLORS

    res, doms = built[1], browsed[1]
    for name, colour in (("alpha.t1.html", COLORS["full"]), ("speed.html", COLORS["full-warm"])):
        png = tmp_path / (name + ".png")
        _chromium(res / "dashboard" / name, f"--screenshot={png}")
        img = np.asarray(Image.open(png).convert("RGB")).astype(float)
        assert img.shape[:2] == (1000, 1400) and img.std() > 20, name   # not blank
        x, y, w, h = (int(v) for v in doms[name].charts[0]["attrs"]["data-box"].split(","))
        assert w > 300 and h > 150 and y + h <= 1000, (name, x, y, w, h)  # the first chart is on screen
        rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)], float)
        hits = (np.abs(img[y:y + h, x:x + w] - rgb).max(axis=2) < 40).sum()
        assert hits > 150, (name, hits)                                   # the series is drawn in its colour
        assert (np.abs(img[:, :x] - rgb).max(axis=2) < 40).sum() < hits   # ... inside the chart, not elsewhere


def test_committed_history_renders_pages_under_2_mb(tmp_path):
    if not ((results := REPO / "results") / "history.jsonl").is_file():
        pytest.skip("no committed results/history.jsonl")
    t0 = time.perf_counter()
    pages, took = render_dashboard(results, tmp_path / "site"), time.perf_counter() - t0
    sizes = {f.name: f.stat().st_size for f in (tmp_path / "site").iterdir()}
    assert max(sizes.values()) < MB2, sorted(sizes.items(), key=lambda kv: -kv[1])[:3]
    lines = [strict_loads(x) for x in (results / "history.jsonl").read_text().splitlines() if x.strip()]
    assert set(pages.locations) == {m for h in lines if not h.get("extended") for m in h["metrics"]} and took < 30, took
    if CHROMIUM:  # the largest page and the speed page, in the browser
        for name, p in _dump_all([tmp_path / "site" / max(sizes, key=sizes.get), tmp_path / "site" / "speed.html"]).items():
            _assert_all_ok(name, p)


# ------------------------------------------------------------------------------------------ asv
def _asv() -> str | None:
    sib = Path(sys.executable).with_name("asv")
    return str(sib) if sib.is_file() else shutil.which("asv")


@pytest.mark.skipif(_asv() is None, reason="asv not installed (optional: pip install asv)")
def test_asv_track_benchmarks_report_metrics_json(tmp_path):
    conf = json.loads("\n".join(ln for ln in (REPO / "asv.conf.json").read_text().splitlines()
                                 if not ln.strip().startswith("//")))
    assert conf["environment_type"] == "existing"
    conf.update(repo=str(REPO), benchmark_dir=str(REPO / "benchmarks"), env_dir=str(tmp_path / "env"),
                results_dir=str(tmp_path / "res"), html_dir=str(tmp_path / "html"))
    (tmp_path / "asv.conf.json").write_text(json.dumps(conf))
    _write_results(tmp_path / "results", _history())
    env = {**os.environ, "HOME": str(tmp_path), "SKIDBENCH_RESULTS": str(tmp_path / "results")}
    cfg = ["--config", str(tmp_path / "asv.conf.json")]
    subprocess.run([_asv(), "machine", "--yes", "--machine", "ci", *cfg], env=env, cwd=tmp_path,
                   capture_output=True, check=True, timeout=120)
    out = subprocess.run([_asv(), "run", *cfg, "--environment", f"existing:{sys.executable}", "--quick", "--dry-run",
                          "--machine", "ci", "--bench", "Reproduced|DistanceToPublished"],
                         env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    tables = {name: {k: float(v) for k, v in re.findall(r"^\s+(\w+\.\w+\.\w+)\s+(\S+)\s*$", body, re.M)}
              for name, body in re.findall(r"benchmarks\.(\w+\.\w+)\s+ok\n(.*?)(?=\n\[|\Z)", out.stdout, re.S)}
    assert tables["Reproduced.track_value"] == {m: v["value"] for m, v in BASELINE["metrics"].items()}
    dist = tables["DistanceToPublished.track_abs_error"]
    assert set(dist) == {"alpha.t1.rms", "alpha.t1.chi"}  # beta has no published value
    assert math.isclose(dist["alpha.t1.rms"], abs(0.218 - 0.3), rel_tol=1e-9)
    assert math.isclose(dist["alpha.t1.chi"], abs(1.82 - 1.456), rel_tol=1e-9)


# ------------------------------------------------------------------------------------------ citation
def _norm(s: str) -> str:
    return " ".join(s.replace("*", "").split()).casefold()


def test_citation_cff_matches_the_package_and_the_papers():
    import tomllib

    yaml = pytest.importorskip("yaml")
    doc = yaml.safe_load((REPO / "CITATION.cff").read_text())
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert doc["cff-version"] == "1.2.0" and doc["message"] and doc["title"]
    assert doc["version"] == project["version"] and doc["license"] == project["license"] == "MIT"  # SPDX (PEP 639)
    assert str(doc["date-released"]) == "2026-11-25" and doc["authors"] == [{"name": "The skidbench developers"}]
    refs = doc["references"]
    assert sorted(r["year"] for r in refs) == [2007, 2009, 2010, 2015, 2020]
    assert {r["doi"] for r in refs if "doi" in r} >= {"10.1109/TRO.2010.2042540"}
    papers = REPO.parent / "shared" / "papers"
    if not papers.is_dir():
        pytest.skip(f"paper texts not found at {papers}: titles and DOIs not cross-checked")
    texts = {p.name: _norm(p.read_text()) for p in papers.glob("*.md")}
    for r in refs:  # each reference's title is a paper of shared/papers, and its DOI is printed in that paper
        own = [n for n, t in texts.items() if _norm(r["title"]) in t[:3000]]
        assert len(own) == 1, r["title"]
        assert r.get("doi", "").casefold() in texts[own[0]] and str(r["year"]) in texts[own[0]], (r, own[0])
    cff = shutil.which("cffconvert")
    if cff:  # optional schema validation (pip install cffconvert)
        out = subprocess.run([cff, "--validate", "-i", str(REPO / "CITATION.cff")], capture_output=True, text=True)
        assert out.returncode == 0, out.stdout + out.stderr


# ------------------------------------------------------------------------------------------ end to end
def test_history_written_by_reproduce_renders(tmp_path, monkeypatch):
    """Two real `reproduce` runs of the fake paper (tests/fixtures), the second with the method
    deliberately broken (speed halved): the table page charts its metrics from the history that
    bench.reproduce wrote and the paper page lists the two moved metrics."""
    from bench import reproduce as R
    from tests.test_reproduce import PAPER

    (papers := tmp_path / "papers").mkdir()
    (papers / "fake.toml").write_text(PAPER)
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", papers)  # where load_paper looks it up
    res = tmp_path / "results"
    R.reproduce(["fake"], results_dir=res, log=lambda s: None)
    monkeypatch.setenv("SKIDBENCH_BREAK_METHOD", "1")
    R.reproduce(["fake"], results_dir=res, log=lambda s: None)
    lines = [strict_loads(x) for x in (res / "history.jsonl").read_text().splitlines()]
    assert len(lines) == 2 and (pages := render_dashboard(res))
    charts = _charts(res, ["fake.t1.html"])
    assert set(charts) == {"fake.t1.speed", "fake.t1.double", "fake.t1.flag_true"}
    speeds = [v for v, *_ in charts["fake.t1.speed"]["points"]]
    assert speeds == [lines[0]["metrics"]["fake.t1.speed"], lines[1]["metrics"]["fake.t1.speed"]]
    assert math.isclose(speeds[1], speeds[0] / 2)
    assert len(charts["fake.t1.speed"]["published"]) == 1 and charts["fake.t1.flag_true"]["published"] == []
    assert {s.metric for s in pages.steps} == {"fake.t1.speed", "fake.t1.double"}
    page = _read(res, "fake.html")
    assert [r["data-metric"] for r in page.trs if r.get("class") == "moved"] == ["fake.t1.double", "fake.t1.speed"]
    assert "A fake paper" in page.text and lines[1]["commit"] in page.text and lines[1]["date"] in page.text
