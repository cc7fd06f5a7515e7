"""Regression dashboard (bench/report/dashboard.py, `skidbench dashboard`) on a history built here.

The history (tmp dir, never the real results/) has ten reproduce runs over ten commits: a metric that
drifts within tolerance, one that jumps at a known commit, one with a NaN gap, one never finite, a
paper that appears only in the later runs, quick runs beside full ones and speed benchmarks.  The
expectations (charts per page, points per chart, values, the published line's position, the steps
and their commits) come from that construction, not from the renderer.  Headless Chromium (Debian
package `chromium`) opens every page and the in-page check must mark every chart as rendered; the
same check must flag a chart whose series was removed.  The asv suite is run with --quick if asv
is installed.
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
from concurrent.futures import ThreadPoolExecutor
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

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


def _history() -> list[dict]:
    rng = np.random.default_rng(7)
    out = []
    for i in range(N_RUNS):
        quick = i in QUICK
        m = {
            "alpha.t1.rms": (0.22 if quick else 0.20) * (1 + 0.01 * i),      # 1 %/run, tolerance 5 %
            "alpha.t1.chi": 1.41 if quick else (1.40 if i < JUMP else 1.82),
            "alpha.t2.gap": float("nan") if i == NAN_AT else 0.5,
            "alpha.t2.never": float("nan"),
        }
        if i >= BETA_FROM:
            m["beta.t9.err"] = 3.0 + 0.01 * i
        bench = {"test_bench_a": 0.012 * (1 + 0.002 * i)}
        if i >= BENCH_B_FROM:
            bench["test_bench_b[circle]"] = 2.5e-5
        out.append({"commit": rng.bytes(20).hex(), "date": f"2026-11-{1 + i:02d}T08:30:00+00:00", "quick": quick,
                    "seconds": 100.0 + i, "metrics": m, "bench": bench})
    return out


BASELINE = {"quick": False, "commit": "x", "metrics": {
    "alpha.t1.rms": {"value": 0.218, "published": 0.3, "tolerance": {"rel": 0.05, "abs": 1e-6}},
    "alpha.t1.chi": {"value": 1.82, "published": 1.456, "tolerance": {"rel": 0.05, "abs": 1e-6}},
    "beta.t9.err": {"value": 3.09, "published": None, "tolerance": {"rel": 0.05, "abs": 1e-6}},
}}


def _write_results(d: Path, hist: list[dict]) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    # as bench.reproduce.append_history writes it: strict JSON, a NaN metric as null
    (d / "history.jsonl").write_text("".join(dumps_json(h, sort_keys=True) + "\n" for h in hist))
    (d / "metrics.json").write_text(json.dumps(BASELINE))
    return d


def _finite(hist: list[dict], mid: str) -> list[tuple[float, str]]:
    return [(h["metrics"][mid], h["commit"]) for h in hist if mid in h["metrics"] and math.isfinite(h["metrics"][mid])]


class _Page(HTMLParser):
    """Charts of a page: attributes, markers (value, cy, commit, step?), published line y, polylines."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.charts: list[dict] = []
        self.cur: dict | None = None
        self.status: dict | None = None
        self.rows: list[list[str]] = []
        self._row: list[str] | None = None
        self._texts: list[str] = []
        self.feed(text)
        self.text = "".join(self._texts)

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        cls = a.get("class", "").split()
        if tag == "svg" and "chart" in cls:
            self.cur = {"attrs": a, "points": [], "published": [], "polylines": {}}
            self._mode = ""
            self.charts.append(self.cur)
        elif self.cur is not None:
            if tag == "circle" and "pt" in cls:
                self.cur["points"].append((float(a["data-value"]), float(a["cy"]), a["data-commit"], "step" in cls))
            elif tag == "line" and "published" in cls:
                self.cur["published"].append(float(a["y1"]))
            elif tag == "g" and "series" in cls:
                self._mode = a["data-mode"]
            elif tag == "polyline":
                self.cur["polylines"][self._mode] = self.cur["polylines"].get(self._mode, 0) + 1
        if tag == "p" and a.get("id") == "render-status":
            self.status = a
        if tag == "tr":
            self._row = []

    def handle_endtag(self, tag):
        if tag == "svg":
            self.cur = None
        if tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        self._texts.append(data)
        if self._row is not None and data.strip():
            self._row.append(data.strip())


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    hist = _history()
    res = _write_results(tmp_path_factory.mktemp("results"), hist)
    pages = render_dashboard(res, res / "dashboard")
    return hist, res, pages


def _read(res: Path, name: str) -> _Page:
    return _Page((res / "dashboard" / name).read_text())


# ------------------------------------------------------------------------------------------ static
def test_every_metric_with_a_finite_value_has_a_chart_with_its_values(built):
    hist, res, _ = built
    expected = {"alpha.html": ["alpha.t1.chi", "alpha.t1.rms", "alpha.t2.gap"], "beta.html": ["beta.t9.err"]}
    for page, mids in expected.items():
        p = _read(res, page)
        assert sorted(c["attrs"]["data-metric"] for c in p.charts) == mids, page
        for c in p.charts:
            mid = c["attrs"]["data-metric"]
            want = _finite(hist, mid)
            got = [(v, commit) for v, _, commit, _ in c["points"]]
            # full run markers first, then quick ones; each in history order
            order = [x for x in want if not _is_quick(hist, x[1])] + [x for x in want if _is_quick(hist, x[1])]
            assert got == order, mid
            assert int(c["attrs"]["data-points"]) == len(want)
    alpha = _read(res, "alpha.html")
    assert "alpha.t2.never" in alpha.text and "Not charted" in alpha.text
    gap = next(c for c in alpha.charts if c["attrs"]["data-metric"] == "alpha.t2.gap")
    assert gap["polylines"] == {"full": 2, "quick": 1}  # the full series is broken at the NaN run


def _is_quick(hist, commit):
    return next(h["quick"] for h in hist if h["commit"] == commit)


def test_value_axis_and_published_line_positions(built):
    _, res, _ = built
    charts = {c["attrs"]["data-metric"]: c for c in _read(res, "alpha.html").charts}
    for c in charts.values():  # larger value -> higher on the page (smaller y)
        pts = sorted(c["points"])
        assert all(a[1] >= b[1] for a, b in zip(pts, pts[1:]))
    rms, chi = charts["alpha.t1.rms"], charts["alpha.t1.chi"]
    assert len(rms["published"]) == 1 and rms["published"][0] < min(p[1] for p in rms["points"])  # 0.3 above all
    y_pub = chi["published"][0]                                    # 1.456 between 1.40/1.41 and 1.82
    assert max(p[1] for p in chi["points"] if p[0] > 1.456) < y_pub < min(p[1] for p in chi["points"] if p[0] < 1.456)
    assert charts["alpha.t2.gap"]["published"] == []               # no published value, no line
    assert _read(res, "beta.html").charts[0]["published"] == []


def test_changes_beyond_tolerance_are_listed_with_their_commits(built):
    hist, res, pages = built
    full = [h for h in hist if not h["quick"]]
    jump_prev = full[[h["commit"] for h in full].index(hist[JUMP]["commit"]) - 1]
    nan_prev = full[[h["commit"] for h in full].index(hist[NAN_AT]["commit"]) - 1]
    got = {(s.metric, s.mode, s.before.commit, s.after.commit) for s in pages.steps}
    assert got == {("alpha.t1.chi", "full", jump_prev["commit"], hist[JUMP]["commit"]),
                   ("alpha.t2.gap", "full", nan_prev["commit"], hist[NAN_AT]["commit"])}
    alpha = _read(res, "alpha.html")
    rows = [r for r in alpha.rows if r and r[0].startswith("alpha.")]
    assert {r[0] for r in rows} == {"alpha.t1.chi", "alpha.t2.gap"}
    chi_row = next(r for r in rows if r[0] == "alpha.t1.chi")
    assert jump_prev["commit"][:8] in chi_row and hist[JUMP]["commit"][:8] in chi_row
    chi = next(c for c in alpha.charts if c["attrs"]["data-metric"] == "alpha.t1.chi")
    assert [p[2] for p in chi["points"] if p[3]] == [hist[JUMP]["commit"]]   # the marked point
    assert "None: no metric moved" in _read(res, "beta.html").text


def test_pages_show_commit_ids_and_dates(built):
    hist, res, _ = built
    index = _read(res, "index.html").text
    alpha = _read(res, "alpha.html").text
    beta = _read(res, "beta.html").text
    for i, h in enumerate(hist):
        assert h["commit"] in index and h["date"] in index
        assert h["commit"] in alpha and h["date"][:10] in alpha
        assert (h["commit"] in beta) == (i >= BETA_FROM)
    assert hist[-1]["commit"][:8] in alpha  # x-axis label of the latest run


def test_speed_page_charts_wall_time_and_every_benchmark(built):
    hist, res, pages = built
    p = _read(res, "speed.html")
    charts = {c["attrs"]["data-metric"]: c for c in p.charts}
    assert set(charts) == {"reproduce wall time", "test_bench_a", "test_bench_b[circle]"}
    assert [v for v, *_ in charts["reproduce wall time"]["points"]] == \
        [h["seconds"] for h in hist if not h["quick"]] + [h["seconds"] for h in hist if h["quick"]]
    b = charts["test_bench_b[circle]"]
    assert len(b["points"]) == N_RUNS - BENCH_B_FROM
    assert all(math.isclose(v, 25.0) for v, *_ in b["points"])  # 2.5e-5 s shown in µs
    assert "µs" in p.text and pages.charts["speed.html"] == 3


def test_same_input_same_bytes_and_no_temp_files(built, tmp_path):
    _, res, _ = built
    render_dashboard(res, tmp_path / "again")
    for f in (res / "dashboard").iterdir():
        assert f.read_bytes() == (tmp_path / "again" / f.name).read_bytes(), f.name
    assert sorted(f.name for f in (tmp_path / "again").iterdir()) == ["alpha.html", "beta.html", "index.html", "speed.html"]


def test_bad_history_is_named_by_file_line_and_field(tmp_path):
    good = json.dumps(_history()[0])
    d = tmp_path / "r"
    d.mkdir()
    (d / "history.jsonl").write_text(good + "\n\n" + '{"commit": "abc", "metrics": {"a.b": 1.0}\n')
    with pytest.raises(SpecError, match=r"history\.jsonl.*line 3.*malformed JSON"):
        render_dashboard(d)
    (d / "history.jsonl").write_text(good + "\n" + '{"commit": "abc", "date": "2026-11-02"}\n')
    with pytest.raises(SpecError, match=r"line 2: metrics.*required field is missing"):
        render_dashboard(d)
    with pytest.raises(SpecError, match="no history file"):
        render_dashboard(tmp_path / "nowhere")


def test_cli_dashboard_command(tmp_path, capsys):
    import bench.cli.dashboard  # noqa: F401  (registers the command; bench.cli loads it too once listed)
    from bench.cli import main

    res = _write_results(tmp_path / "results", _history())
    assert main(["dashboard", "--results", str(res), "--out", str(tmp_path / "site")]) == 0
    assert (tmp_path / "site" / "index.html").is_file() and (tmp_path / "site" / "alpha.html").is_file()
    assert "(7 charts, 2 changes beyond tolerance)" in capsys.readouterr().out  # alpha 3 + beta 1 + speed 3
    (res / "history.jsonl").write_text("not json\n")
    assert main(["dashboard", "--results", str(res)]) == 2
    assert "line 1" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ browser
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1400,1000"]
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="headless Chromium not installed (Debian: apt-get install -y chromium); "
                             "the in-browser render check of the dashboard is skipped")


def _dump_dom(page: Path) -> str:
    with tempfile.TemporaryDirectory(prefix="skidbench-chromium-") as profile:
        out = subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--dump-dom",
                              page.resolve().as_uri()], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "</html>" in out.stdout, f"chromium failed on {page}: {out.stderr[-2000:]}"
    return out.stdout


@pytest.fixture(scope="module")
def browsed(built):
    hist, res, pages = built
    site = res / "dashboard"
    broken = site / "broken.html"   # one chart's data series removed: the check must flag it
    text = (site / "alpha.html").read_text()
    target = re.search(r'<svg class="chart" id="c-alpha-t1-rms".*?</svg>', text, re.S).group(0)
    emptied = re.sub(r'<g class="series.*?</g>', "", target, flags=re.S)
    assert emptied != target
    broken.write_text(text.replace(target, emptied))
    names = ["index.html", "alpha.html", "beta.html", "speed.html", "broken.html"]
    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
        doms = dict(zip(names, pool.map(lambda n: _dump_dom(site / n), names)))
    broken.unlink()
    return hist, doms


@needs_chromium
def test_chromium_renders_every_chart(browsed):
    hist, doms = browsed
    expected = {"index.html": 0, "alpha.html": 3, "beta.html": 1, "speed.html": 3}
    for name, n in expected.items():
        p = _Page(doms[name])
        assert len(p.charts) == n, name
        assert [c["attrs"].get("data-rendered") for c in p.charts] == ["ok"] * n, name
        assert p.status is not None and p.status["data-charts"] == str(n) and p.status["data-ok"] == str(n), name
        assert f"{n} of {n} charts rendered" in p.text
    alpha = _Page(doms["alpha.html"]).text
    for h in hist:
        assert h["commit"] in alpha and h["date"][:10] in alpha


@needs_chromium
def test_chromium_check_flags_an_empty_chart(browsed):
    _, doms = browsed
    p = _Page(doms["broken.html"])
    state = {c["attrs"]["data-metric"]: c["attrs"].get("data-rendered") for c in p.charts}
    assert state == {"alpha.t1.rms": "empty", "alpha.t1.chi": "ok", "alpha.t2.gap": "ok"}
    assert p.status["class"] == "bad" and p.status["data-ok"] == "2"
    assert "empty: c-alpha-t1-rms" in p.text


# ------------------------------------------------------------------------------------------ asv
def _asv() -> str | None:
    sib = Path(sys.executable).with_name("asv")
    return str(sib) if sib.is_file() else shutil.which("asv")


@pytest.mark.skipif(_asv() is None, reason="asv not installed (optional: pip install asv)")
def test_asv_track_benchmarks_report_metrics_json(tmp_path):
    conf_text = "\n".join(ln for ln in (REPO / "asv.conf.json").read_text().splitlines() if not ln.strip().startswith("//"))
    conf = json.loads(conf_text)
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
    tables = {}
    for name, body in re.findall(r"benchmarks\.(\w+\.\w+)\s+ok\n(.*?)(?=\n\[|\Z)", out.stdout, re.S):
        tables[name] = {k: float(v) for k, v in re.findall(r"^\s+(\w+\.\w+\.\w+)\s+(\S+)\s*$", body, re.M)}
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
        if "doi" in r:
            assert r["doi"].casefold() in texts[own[0]], (r["doi"], own[0])
        assert str(r["year"]) in texts[own[0]]
    cff = shutil.which("cffconvert")
    if cff:  # optional schema validation (pip install cffconvert)
        out = subprocess.run([cff, "--validate", "-i", str(REPO / "CITATION.cff")], capture_output=True, text=True)
        assert out.returncode == 0, out.stdout + out.stderr


# ------------------------------------------------------------------------------------------ end to end
def test_history_written_by_reproduce_renders(tmp_path, monkeypatch):
    """Two real `reproduce` runs of the fake paper (tests/fixtures), the second with the method
    deliberately broken (speed halved): the page charts its metrics from the history that
    bench.reproduce wrote and lists the two moved metrics."""
    from bench import reproduce as R
    from tests.test_reproduce import PAPER

    papers = tmp_path / "papers"
    papers.mkdir()
    (papers / "fake.toml").write_text(PAPER)
    monkeypatch.setattr("bench.reproduce.paper.PAPERS_DIR", papers)  # where load_paper looks it up
    res = tmp_path / "results"
    R.reproduce(["fake"], results_dir=res, log=lambda s: None)
    monkeypatch.setenv("SKIDBENCH_BREAK_METHOD", "1")
    R.reproduce(["fake"], results_dir=res, log=lambda s: None)
    lines = [strict_loads(x) for x in (res / "history.jsonl").read_text().splitlines()]
    assert len(lines) == 2
    pages = render_dashboard(res)
    page = _read(res, "fake.html")
    charts = {c["attrs"]["data-metric"]: c for c in page.charts}
    assert set(charts) == {"fake.t1.speed", "fake.t1.double", "fake.t1.flag_true"}
    speeds = [v for v, *_ in charts["fake.t1.speed"]["points"]]
    assert speeds == [lines[0]["metrics"]["fake.t1.speed"], lines[1]["metrics"]["fake.t1.speed"]]
    assert math.isclose(speeds[1], speeds[0] / 2)
    assert len(charts["fake.t1.speed"]["published"]) == 1 and charts["fake.t1.flag_true"]["published"] == []
    assert {s.metric for s in pages.steps} == {"fake.t1.speed", "fake.t1.double"}
    assert "A fake paper" in page.text and lines[1]["commit"] in page.text and lines[1]["date"] in page.text
