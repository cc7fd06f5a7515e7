"""The league table compares like with like: sensor groups, divergence flagged, every cell explained, no machine path."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from bench import registry
from bench.metrics import Trajectory, divergence
from bench.metrics.trajectory import MetricError
from bench.reproduce import league
from bench.reproduce.league_table import SENSOR_GROUPS, group_of, league_csv, league_markdown, median_over_scenarios
from bench.run import RunError

ROOT = Path(__file__).resolve().parent.parent


def _line(t: np.ndarray, vx: float, dy: float = 0.0, name: str = "x") -> Trajectory:
    return Trajectory.planar(t, vx * t, np.full_like(t, dy), np.zeros_like(t), name=name)


def test_divergence_closed_forms() -> None:
    """Truth: 1 m/s along x for 10 s.  An estimate going the other way is 2t off, past max(t, 1 m) for good from
    t > 0.5 s; an offset under the 1 m floor never diverges; an excursion that comes back inside the bound is not a
    divergence; one that lasts to the end is, from its first sample."""
    t = np.round(np.arange(0.0, 10.0 + 1e-9, 0.01), 10)
    ref = _line(t, 1.0, name="truth")
    d = divergence(ref, _line(t, -1.0))
    assert d is not None and d.step == 51 and d.t == pytest.approx(0.51) and d.error == pytest.approx(1.02)
    assert d.bound == 1.0
    assert divergence(ref, _line(t, 1.0)) is None
    assert divergence(ref, _line(t, 1.0, dy=0.99)) is None
    assert divergence(ref, _line(t, 1.0, dy=1.01)) is None  # past the floor at the start, inside once s > 1.01 m
    spike = Trajectory.planar(t, t + np.where((t > 2.0) & (t < 3.0), 3.0, 0.0), np.zeros_like(t), np.zeros_like(t),
                              name="spike")
    assert divergence(ref, spike) is None  # 3 m off on a 2-3 m path, then back
    late = Trajectory.planar(t, t + np.where(t > 8.0, 30.0, 0.0), np.zeros_like(t), np.zeros_like(t), name="late")
    d = divergence(ref, late)
    assert d is not None and d.t == pytest.approx(8.01) and d.error == pytest.approx(30.0)
    # back inside for a while, then out for good: the last excursion counts
    twice = Trajectory.planar(t, t + np.where((t > 1.0) & (t < 1.5), 5.0, 0.0) + np.where(t > 6.0, 20.0, 0.0),
                              np.zeros_like(t), np.zeros_like(t), name="twice")
    assert divergence(ref, twice).t == pytest.approx(6.01)
    with pytest.raises(MetricError, match="floor"):
        divergence(ref, ref, floor=0.0)


@dataclass(frozen=True)
class BiasedAccelKF:
    """A Kalman filter (FilterPy) that integrates the body-x accelerometer along the start heading, with an
    accelerometer bias it does not model and no measurement update: its position error grows as b t^2 / 2, past
    the path length of a robot at speed v after t = 2 v / b.  A filter made to diverge."""

    bias: float = 2.0
    name: ClassVar[str] = "test.biased_accel_kf"
    paper: ClassVar[str] = "test"
    requires: ClassVar[frozenset[str]] = frozenset({"imu_ax"})

    def calibrate(self, runs):  # noqa: ANN001 - the plugin protocol
        return self

    def estimate(self, run):  # noqa: ANN001
        from filterpy.kalman import KalmanFilter

        t, ax = run.samples("imu_ax")
        kf = KalmanFilter(dim_x=2, dim_z=1)
        kf.x = np.zeros(2)
        xs = np.empty(t.size)
        for k in range(t.size):
            dt = t[k] - t[k - 1] if k else 0.0
            kf.F = np.array([[1.0, dt], [0.0, 1.0]])
            kf.B = np.array([0.5 * dt * dt, dt])
            kf.predict(u=ax[k] + self.bias)
            xs[k] = kf.x[0]
        return registry.make_estimate(self.name, {}, t=t, x=xs, y=np.zeros_like(t), yaw=np.zeros_like(t))


def test_a_diverged_filter_is_reported_with_its_time_and_step_never_averaged(monkeypatch, tmp_path) -> None:
    from bench.reproduce.runner import Runner
    from bench.spec import load_scenario

    scn = load_scenario("straight_0p2_vinyl", {"duration": 4.0, "initial_speed": 0.0})
    runs = Runner(cache_dir=tmp_path, workers=1).simulate_many([(scn, 0), (scn, 1)])
    real_get = registry.get
    monkeypatch.setattr(registry, "get", lambda n, **kw: BiasedAccelKF() if n == BiasedAccelKF.name else real_get(n, **kw))
    monkeypatch.setattr(league.registry, "get", registry.get)
    cell = league._cell(BiasedAccelKF.name, scn.id, [], runs)
    assert not cell.error and len(cell.values) == 2 and len(cell.diverged) == 2
    seed, t_div, step, err, bound = cell.diverged[0]
    # the truth's own numbers: the first sample where b t^2/2 (+ the filter's integration of the true acceleration,
    # i.e. the truth's path) is past max(path, 1 m); with v <= 0.2 m/s that is about t = 1 s (b t^2 / 2 = 1 m)
    assert seed == 0 and 0.9 < t_div < 1.3 and err > bound >= 1.0
    assert runs[0].data["t"].iloc[step] == pytest.approx(t_div)
    assert all(math.isnan(x) for x in cell.summary())
    md = league_markdown([cell, league.Cell("baseline.ideal_dd", scn.id, [0.1, 0.12])], 2)
    row = next(line for line in md.splitlines() if BiasedAccelKF.name in line)
    assert f"diverged at t = {t_div:.2f} s (step {step}, seed 0; 2 of 2 seeds)" in row
    assert row.startswith("| - |") and "**" not in row  # no rank, never the best
    assert "0@" in league_csv([cell]) and ",nan,nan,nan," in league_csv([cell])


def _fake_cells(methods: list[str], scenarios: list[str]) -> list[league.Cell]:
    rng = np.random.default_rng(3)
    return [league.Cell(m, s, list(rng.uniform(0.01, 1.0, 5))) for m in methods for s in scenarios]


def test_one_ranked_table_per_sensor_group_with_what_its_methods_read() -> None:
    """Every registered method falls into one of the sensor groups by what its estimate reads; each group gets its
    own table, ranked by the median over scenarios, with the one-line statement of what the methods there read."""
    names = list(registry.discover())
    groups = {n: group_of(n).title for n in names}
    assert set(groups.values()) <= {g.title for g in SENSOR_GROUPS}
    assert groups["baseline.ideal_dd"] == groups["mandow2007.asymmetric_ga"] == groups["wang2015.chi_lambda"] \
        == groups["liu2020.en_dr"] == "Wheel odometry"  # Liu's En-DR reads the GNSS for its start point only
    assert groups["yi2009.ekf_v3"] == "Wheels + IMU" and groups["liu2020.mi_ukf"] == "Wheels + IMU + GNSS"
    assert groups["yu2010.open_loop"] == groups["yu2010.closed_loop"] == "Dynamic model (no odometry)"
    scen = ["s1", "s2", "s3"]
    cells = _fake_cells(names, scen)
    md = league_markdown(cells, 5)
    sections = re.split(r"^## ", md, flags=re.M)[1:]
    assert [s.splitlines()[0] for s in sections] == [g.title for g in SENSOR_GROUPS]
    by = {(c.method, c.scenario): c for c in cells}
    for sec, g in zip(sections, SENSOR_GROUPS):
        assert f"Methods here read {g.reads}." in sec
        rows = [ln.split(" | ") for ln in sec.splitlines() if ln.startswith("| ") and not ln.startswith("| rank")]
        meds = [median_over_scenarios(by[(r[1], s)] for s in scen)[0] for r in rows]
        assert [r[0].strip("| ") for r in rows] == [str(i + 1) for i in range(len(rows))]
        assert meds == sorted(meds) and {r[1] for r in rows} == {n for n in names if groups[n] == g.title}
        for j, s in enumerate(scen):  # bold: the best mean of the column within the group
            col = [r[3 + j].strip(" |") for r in rows]
            best = min(rows, key=lambda r: by[(r[1], s)].summary()[0])[1]
            assert [r[1] for r, txt in zip(rows, col) if txt.startswith("**")] == ([best] if len(rows) > 1 else [])


def test_median_counts_only_scenarios_with_a_number() -> None:
    cells = [league.Cell("m", "a", [1.0] * 3), league.Cell("m", "b", [3.0] * 3), league.Cell("m", "c", [], error="x"),
             league.Cell("m", "d", [100.0] * 3, diverged=[(0, 1.0, 10, 2.0, 1.0)])]
    assert median_over_scenarios(cells) == (2.0, 2)


def test_every_empty_cell_says_why_in_words_without_a_machine_path() -> None:
    exc = RunError("/work/cache/runs/bea7d3.parquet", "calibration", "none", "it identifies its noise on "
                   "calibration runs; see /home/someone/skidbench/scenarios/x.toml")
    assert league.reason(exc) == ("RunError: column 'calibration' = 'none': it identifies its noise on calibration "
                                  "runs; see x.toml")
    assert league.reason(ValueError("0.3 m/s at 1/1920 s")) == "ValueError: 0.3 m/s at 1/1920 s"
    cells = [league.Cell("baseline.ideal_dd", "a", [], error=league.reason(exc)),
             league.Cell("baseline.ideal_dd", "b", [0.2, 0.3])]
    md = league_markdown(cells, 2)
    row = next(line for line in md.splitlines() if line.startswith("| 1 | baseline.ideal_dd"))
    assert all(cell.strip() for cell in row.strip("|").split("|"))


ABSOLUTE_PATH = re.compile(r"(?<![\w.~:/-])/(?:[\w.+~-]+/)+[\w.+~-]+")


def test_no_committed_result_names_a_path_of_the_machine_that_made_it() -> None:
    """Every text file under results/ (reports, tables, manifests, JSON) is free of absolute paths."""
    hits = []
    for p in sorted((ROOT / "results").rglob("*")):
        if p.suffix not in {".md", ".csv", ".json", ".jsonl", ".txt", ".html", ".svg", ".toml"} or not p.is_file():
            continue
        for m in ABSOLUTE_PATH.finditer(p.read_text(errors="replace")):
            hits.append(f"{p.relative_to(ROOT)}: {m.group()}")
    assert not hits, f"{len(hits)} absolute paths, e.g. {hits[:3]}"


def test_the_path_scan_finds_a_path() -> None:
    """The scan's pattern catches a machine path and leaves units, ratios and URLs alone."""
    assert ABSOLUTE_PATH.search("RunError: /work/cache/runs/x.parquet: column")
    assert ABSOLUTE_PATH.search('"source_file": "/home/u/scenarios/a.toml"')
    for ok in ("0.3 m/s", "1/1920 s", "rad/s/s", "https://github.com/MichaelGrupp/evo", "(real/husky.md)", "m/s^2"):
        assert not ABSOLUTE_PATH.search(ok), ok


def test_manifest_records_the_scenario_file_relative_to_the_repository() -> None:
    from bench.reproduce.runner import portable_source
    from bench.spec import SCENARIO_DIR

    assert portable_source(str(SCENARIO_DIR / "yi_circle.toml")) == "scenarios/yi_circle.toml"
    assert portable_source("/elsewhere/my_robot.toml") == "my_robot.toml" and portable_source("") == ""


def test_an_estimate_that_ends_in_nan_is_a_divergence() -> None:
    """A filter whose state blew up to NaN and stayed there diverged where its finite part ended."""
    import pandas as pd

    from bench.registry import make_estimate

    t = np.round(np.arange(0.0, 5.0 + 1e-9, 0.01), 10)
    run = type("R", (), {"data": pd.DataFrame({"t": t, "truth_x": 0.2 * t, "truth_y": 0 * t, "truth_yaw": 0 * t})})()
    x = np.where(t < 3.0, 0.2 * t, np.nan)
    rms, div = league._score(run, make_estimate("m", {}, t=t, x=x, y=0 * t, yaw=0 * t))
    assert rms == pytest.approx(0.0, abs=1e-12) and div is not None and div.t == pytest.approx(3.0) and div.step == 300
    rms, div = league._score(run, make_estimate("m", {}, t=t, x=0.2 * t, y=0 * t, yaw=0 * t))
    assert div is None


def test_rank_compares_methods_on_the_same_scenarios() -> None:
    """A method with numbers on fewer scenarios is ranked on the scenarios every method of the group has, not on
    its own (a low median over easy scenarios does not put it first)."""
    cells = [league.Cell("baseline.ideal_dd", "easy", [0.1] * 3), league.Cell("baseline.ideal_dd", "hard", [9.0] * 3),
             league.Cell("wang2015.chi_lambda", "easy", [0.2] * 3),
             league.Cell("wang2015.chi_lambda", "hard", [], error="cannot run here: its calibration failed (x)")]
    md = league_markdown(cells, 3)
    rows = [ln for ln in md.splitlines() if ln.startswith("| 1 |") or ln.startswith("| 2 |")]
    assert rows[0].startswith("| 1 | baseline.ideal_dd | 4.55 |") and rows[1].startswith("| 2 | wang2015.chi_lambda | 0.2 (of 1) |")
    assert "Ranked by the median over the 1 scenarios where every method here has a number (easy)." in md
