"""The real-data commands' handling of what a user gives them: a needless fix, a NaN in any input, a plugin that
does not load, --methods without the ICR family, data folders in every table format.  Synthetic DRIVE tables of
tests/test_real_cli.py (a robot of known chi, driven by command steps)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bench.cli import main
from tests.test_real_cli import clean  # noqa: F401  (fixture)


def test_flipping_a_gyro_that_follows_the_reference_is_refused(clean, tmp_path, capsys):
    """--fix flip_gyro on a good gyro would corrupt it: one line naming the fix and the check's evidence, exit 2,
    nothing written; on a flipped gyro it corrects it (test_fixes_correct_what_they_name)."""
    out = tmp_path / "o"
    assert main(["real", str(clean[0]), "--platform", "husky", "--out", str(out), "--fix", "flip_gyro",
                 "--no-figures"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "flip_gyro" in err[0] and "nothing to flip" in err[0] and "slope" in err[0]
    assert not out.exists() or not any(out.iterdir())


def test_methods_always_score_ideal_dd_and_say_when_no_icr_model_ran(clean, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["real", str(clean[0]), "--platform", "husky", "--out", str(out), "--methods", "wang2015.constant_chi",
                 "--no-figures", "--json", str(tmp_path / "a.json")]) == 0
    res = json.loads((tmp_path / "a.json").read_text())["data"][str(clean[0])]
    assert set(res["models"]) == {"ideal_dd", "icr_sym_chi"} and res["verdict"]["best_icr_model"] == "icr_sym_chi"
    assert main(["real", str(clean[0]), "--platform", "husky", "--out", str(tmp_path / "p"), "--methods",
                 "yi2009.ekf_v3", "--no-figures"]) == 0
    assert "no ICR-family model scored" in capsys.readouterr().out
    md = next((tmp_path / "p").glob("*.md")).read_text()
    assert "No verdict: no ICR-family model" in md and "None" not in md and "nan" not in md.split("## Verdict")[1]


def test_a_plugin_that_fails_to_load_is_one_line(clean, tmp_path, capsys, monkeypatch):
    """A broken installed plugin (its entry point names a missing class) stops `real` with one line naming it."""
    from bench import registry

    class BrokenEntryPoint:
        name, value = "brokenlab.nope", "brokenlab.mod:Nope"

        def load(self):
            raise AttributeError("module 'brokenlab.mod' has no attribute 'Nope'")

    found = registry.discover()
    monkeypatch.setattr(registry, "discover", lambda: {**found, "brokenlab.nope": BrokenEntryPoint()})
    with pytest.raises(registry.PluginLoadError, match="brokenlab.mod:Nope"):
        registry.get("brokenlab.nope")
    assert main(["real", str(clean[0]), "--platform", "husky", "--out", str(tmp_path / "o"), "--no-figures"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "brokenlab.nope" in err[0] and "failed to load" in err[0]


@pytest.mark.parametrize("column", ["cmd_left_3", "imu_yaw_10", "left_wheel_vel_39"])
def test_a_nan_in_any_input_drops_the_window_for_every_model(clean, tmp_path, column):
    from bench.real.benchmark import run_real_benchmark

    df = clean[1].copy()
    df.loc[df.index[4], column] = np.nan
    p = tmp_path / "nan.parquet"
    df.to_parquet(p)
    res = run_real_benchmark(p, tmp_path / "out", figures=False, models=["baseline.ideal_dd", "yi2009.ekf_v3"])
    assert res["n_excluded"] == 1
    assert all(np.isfinite(m["stats"]["all"][e]["median"]) for m in res["models"].values() for e in ("trans", "yaw"))


def test_data_sets_take_every_table_format_and_the_league_runs_without_the_husky(clean, tmp_path, monkeypatch, capsys):
    """A data folder with a platform.toml and a DRIVE table in any format the reader takes (.parquet, .pkl, .csv) is a
    data set; a README beside it is not; with no Husky table the real stage still scores the others."""
    from bench.cli.real import _extra_real
    from bench.real.league import data_sets

    root = tmp_path / "data"
    bot = root / "bot"
    bot.mkdir(parents=True)
    (bot / "platform.toml").write_text('name = "bot"\nwheel_radius = 0.165\ntrack = 0.55\n')
    clean[1].to_parquet(bot / "a.parquet")
    for name in ("b.csv", "c.pkl", "README.md"):
        (bot / name).write_text("")
    assert [(t.name, p.name) for t, p in data_sets(root)] == [(n, "platform.toml") for n in ("a.parquet", "b.csv",
                                                                                              "c.pkl")]
    for name in ("b.csv", "c.pkl"):
        (bot / name).unlink()
    monkeypatch.setenv("SKIDBENCH_DATA", str(root))
    _extra_real(tmp_path / "results", quick=True)
    league = (tmp_path / "results" / "real" / "league.md").read_text()
    assert "## bot: `bot/a.parquet`" in league and "no Husky table" in capsys.readouterr().out


def test_a_report_is_named_only_once_every_table_is_scored(clean, tmp_path, capsys):
    """`real good bad`: the second table fails, nothing is published, and no report path is printed (the first one's
    would name a file that never appears); with two good tables both paths are printed after the scoring."""
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(b"not parquet")
    out = tmp_path / "o"
    assert main(["real", str(clean[0]), str(bad), "--platform", "husky", "--out", str(out), "--no-figures"]) == 2
    printed = capsys.readouterr().out
    assert "-> " not in printed and (not out.exists() or not any(out.iterdir()))
    assert main(["real", str(clean[0]), "--platform", "husky", "--out", str(out), "--no-figures"]) == 0
    arrows = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("-> ")]
    assert len(arrows) == 1 and (out / arrows[0][3:].split("/")[-1]).is_file()


def test_a_gyro_that_is_nan_throughout_is_absent_not_a_reason_to_drop_every_window(clean, tmp_path):
    """An optional channel with no finite sample at all counts as missing: every window is still scored (a NaN in
    some samples of a channel that is there drops those windows: test_a_nan_in_any_input_...)."""
    from bench.real.benchmark import run_real_benchmark

    df = clean[1].copy()
    df[[c for c in df.columns if c.startswith("imu_yaw_")]] = np.nan
    p = tmp_path / "nogyro.parquet"
    df.to_parquet(p)
    res = run_real_benchmark(p, tmp_path / "out", figures=False, models=["baseline.ideal_dd", "wang2015.constant_chi"])
    assert res["n_excluded"] == 0 and res["verdict"]["best_icr_model"] == "icr_sym_chi"
