"""Bad input found by a blind fuzz of the command line (each case ended in a traceback, a silent success or half-written
output before): now one line naming the file, the field and the value, exit 2, and nothing written."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from bench.cli import main
from bench.run import META_KEY, RunError, from_arrays
from tests.test_real_cli import _log, _table


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def run_file(tmp_path_factory) -> Path:
    from bench.sim import simulate
    from bench.spec import load_scenario

    path = tmp_path_factory.mktemp("runs") / "r.parquet"
    simulate(load_scenario("straight_0p2_vinyl", {"duration": 1.0}), 0).to_parquet(path)
    return path


@pytest.fixture(scope="module")
def drive_table(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("drive") / "robot_x.parquet"
    _table(_log(n_steps=6)).to_parquet(path)
    return path


def test_a_toml_that_is_not_utf8_is_named(tmp_path, capsys) -> None:
    bad = tmp_path / "s.toml"
    bad.write_bytes(b'platform = "husky"\nduration = 1.0\n# caf\xe9\n')
    assert main(["simulate", str(bad), "-o", str(tmp_path / "x.parquet")]) == 2
    err = _one_line(capsys)
    assert str(bad) in err and "not UTF-8" in err and not (tmp_path / "x.parquet").exists()


@pytest.mark.parametrize("meta", [b"{not json", b"[1, 2]"])
def test_run_metadata_that_is_not_a_json_object_is_named(tmp_path, capsys, meta) -> None:
    path = tmp_path / "r.parquet"
    table = pa.table({"t": np.arange(5) * 0.1, "enc_wl": np.ones(5), "enc_wr": np.ones(5)})
    pq.write_table(table.replace_schema_metadata({META_KEY: meta}), path)
    assert main(["export-tum", str(path), "-o", str(tmp_path / "x.tum")]) == 2
    err = _one_line(capsys)
    assert str(path) in err and "<metadata>" in err and not (tmp_path / "x.tum").exists()


@pytest.mark.parametrize("over, field, words", [
    ("platform.yaw_inertia=1e-6", "platform.yaw_inertia", "its four wheels"),  # passed the spec, crashed the testbed
    ("platform.cg_offset_x=inf", "platform.cg_offset_x", "finite"),
    ("initial_speed=1e6", "initial_speed", "[-20, 20] m/s"),
    ("platform.sensors.imu.rate_hz=1e9", "platform.sensors.imu.rate_hz", "(0, 10000] Hz"),  # was killed for memory
    ("platform.wheel_radius=1e-6", "platform.wheel_radius", "[0.01, 2] m"),
])
def test_values_the_testbed_cannot_run_are_refused_before_it_starts(tmp_path, capsys, over, field, words) -> None:
    assert main(["simulate", "straight_0p2_vinyl", "--set", over, "--set", "duration=0.5",
                 "-o", str(tmp_path / "x.parquet")]) == 2
    err = _one_line(capsys)
    assert f"'{field}'" in err and words in err and not (tmp_path / "x.parquet").exists()


def test_stdout_has_the_result_line_and_no_bar_when_not_a_terminal(tmp_path, capsys) -> None:
    """A redirected run: the bar is not drawn (it went to stdout, frozen at its last frame), stdout is the result."""
    out = tmp_path / "x.parquet"
    assert main(["simulate", "straight_0p2_vinyl", "--set", "duration=0.5", "-o", str(out)]) == 0
    cap = capsys.readouterr()
    assert cap.out.startswith(f"wrote {out} (") and cap.out.count("\n") == 1 and cap.err == ""


def test_an_output_path_that_is_a_folder_is_one_line(tmp_path, capsys) -> None:
    assert main(["simulate", "straight_0p2_vinyl", "--set", "duration=0.5", "-o", str(tmp_path)]) == 2
    assert str(tmp_path) in _one_line(capsys)


def test_a_calibration_run_without_the_needed_experiment_is_one_line(tmp_path, capsys, run_file) -> None:
    """Mandow's symmetric model calibrated on a straight line: the method's CalibrationDataError is bad input."""
    assert main(["estimate", "mandow2007.symmetric", str(run_file), "--calibrate", str(run_file),
                 "-o", str(tmp_path / "e.csv")]) == 2
    assert "Traceback" not in capsys.readouterr().err and not (tmp_path / "e.csv").exists()


@pytest.mark.parametrize("text, words", [("", "an estimate CSV"), ("t,x,y,yaw\na,b,c,d\n", "expected numbers"),
                                         ("t,x,y,yaw\n0,0,0,0\n0,1,0,0\n", "strictly increasing")])
def test_an_estimate_csv_that_is_not_one_is_named(tmp_path, capsys, text, words) -> None:
    est = tmp_path / "e.csv"
    est.write_text(text)
    assert main(["export-tum", str(est), "-o", str(tmp_path / "x.tum")]) == 2
    err = _one_line(capsys)
    assert str(est) in err and words in err and not (tmp_path / "x.tum").exists()


def test_evaluate_checks_the_plot_name_before_writing_the_json(tmp_path, capsys, run_file) -> None:
    out = tmp_path / "a.json"
    assert main(["evaluate", str(run_file), str(run_file), "--json", str(out), "--plot", str(tmp_path / "a.xyz")]) == 2
    assert "--plot" in _one_line(capsys) and not out.exists()


@pytest.mark.parametrize("entry, field", [(1.5, "metrics.m"), ({"value": "big"}, "metrics.m.value"),
                                          ({"value": 1.0, "tolerance": 0.1}, "metrics.m.tolerance"),
                                          ({"value": 1.0, "tolerance": {"rel": "x"}}, "metrics.m.tolerance.rel")])
def test_compare_names_a_malformed_metric(tmp_path, capsys, entry, field) -> None:
    bad, good = tmp_path / "bad.json", tmp_path / "good.json"
    bad.write_text(json.dumps({"metrics": {"m": entry}}))
    good.write_text(json.dumps({"metrics": {"m": {"value": 1.0}}}))
    for base, new in ((bad, good), (good, bad)):
        assert main(["compare", str(base), str(new)]) == 2
        err = _one_line(capsys)
        assert str(bad) in err and f"'{field}'" in err


def test_compare_of_one_paper_against_the_full_baseline(tmp_path, capsys) -> None:
    """A one-paper reproduce lacks the other papers' metrics: without --papers they are 'missing in new'; with it
    only that paper is compared, and a moved metric of it is still a regression; an unknown id is one line."""
    m = lambda v: {"value": v, "tolerance": {"abs": 0.01}}  # noqa: E731
    base, new = tmp_path / "base.json", tmp_path / "new.json"
    base.write_text(json.dumps({"metrics": {"yu2010.t.a": m(1.0), "yi2009.t.b": m(2.0)}}))
    new.write_text(json.dumps({"metrics": {"yu2010.t.a": m(1.005)}}))
    assert main(["compare", str(base), str(new)]) == 1
    assert "yi2009.t.b" in capsys.readouterr().out
    assert main(["compare", str(base), str(new), "--papers", "yu2010"]) == 0
    assert "1 compared" in capsys.readouterr().out
    new.write_text(json.dumps({"metrics": {"yu2010.t.a": m(1.5)}}))
    assert main(["compare", str(base), str(new), "--papers", "yu2010"]) == 1
    capsys.readouterr()
    assert main(["compare", str(base), str(new), "--papers", "yu2011"]) == 2
    err = _one_line(capsys)
    assert "--papers" in err and "yu2011" in err and "yu2010" in err


@pytest.mark.parametrize("runs, field", [([1], "runs"), ({"k": 3}, "runs.k"),
                                         ({"k": {"scenario_hash": "h", "seed": -1, "content_hash": "0"}}, "runs.k.seed"),
                                         ({"k": {"scenario_hash": "zz", "seed": 0, "content_hash": "0"}},
                                          "runs.k.scenario_hash")])
def test_verify_runs_names_a_malformed_manifest_entry(tmp_path, capsys, runs, field) -> None:
    man = tmp_path / "m.json"
    man.write_text(json.dumps({"runs": runs, "scenarios": {"h": {}}}))
    assert main(["verify-runs", str(man)]) == 2
    err = _one_line(capsys)
    assert str(man) in err and f"'{field}'" in err


def test_real_refuses_a_header_only_table_and_writes_nothing_of_the_others(tmp_path, capsys, drive_table) -> None:
    import pandas as pd

    empty = tmp_path / "empty.parquet"
    pd.read_parquet(drive_table).iloc[:0].to_parquet(empty)
    out = tmp_path / "out"
    assert main(["real", str(drive_table), str(empty), "--platform", "husky", "--out", str(out), "--no-figures"]) == 2
    err = _one_line(capsys)
    assert str(empty) in err and "no windows" in err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["empty.parquet"]  # no staging left
    out.mkdir()
    (out / "kept.txt").write_text("mine")  # an existing --out keeps what it had, and only that
    assert main(["real", str(drive_table), str(empty), "--platform", "husky", "--out", str(out), "--no-figures"]) == 2
    assert sorted(p.name for p in out.iterdir()) == ["kept.txt"]
    capsys.readouterr()


def test_real_needs_two_command_steps_and_a_plausible_platform(tmp_path, capsys, drive_table) -> None:
    import pandas as pd

    one = tmp_path / "one.parquet"
    pd.read_parquet(drive_table).iloc[:1].to_parquet(one)  # one window: nothing left to score
    assert main(["real", str(one), "--platform", "husky", "--out", str(tmp_path / "o"), "--no-figures"]) == 2
    assert "at least 2 command steps" in _one_line(capsys)
    big = tmp_path / "big.toml"
    big.write_text("wheel_radius = 0.3\ntrack = 5e3\n")
    assert main(["real", str(drive_table), "--platform", str(big), "--out", str(tmp_path / "o")]) == 2
    err = _one_line(capsys)
    assert "big.toml" in err and "'track' = 5000.0" in err and "[0.05, 10] m" in err
    with pytest.raises(SystemExit) as ei:
        main(["real", str(drive_table), "--platform", "husky", "--out", str(tmp_path / "o"), "--seed", "-1"])
    assert ei.value.code == 2
    assert not (tmp_path / "o").exists()


def test_a_run_whose_time_is_not_in_seconds_is_named_before_any_allocation() -> None:
    from bench.real.run_windows import windows_from_run

    t = np.arange(50) * 0.05 * 1e12  # stamps in picoseconds: 8 TiB on DRIVE's grid
    run = from_arrays({"t": t, "enc_wl": np.ones(50), "enc_wr": np.ones(50), "ref_x": t * 0, "ref_y": t * 0,
                       "ref_yaw": t * 0}, {"run_id": "ps"})
    with pytest.raises(RunError, match="days long"):
        windows_from_run(run)


def test_wheel_speeds_in_another_unit_are_named_on_import(tmp_path, capsys, drive_table) -> None:
    import pandas as pd

    df = pd.read_parquet(drive_table)
    cols = [c for c in df.columns if c.startswith("left_wheel_vel_")]
    df[cols] *= 1e6
    bad = tmp_path / "huge.parquet"
    df.to_parquet(bad)
    assert main(["import-drive", str(bad), "--platform", "husky", "-o", str(tmp_path / "o")]) == 2
    err = _one_line(capsys)
    assert str(bad) in err and "left_wheel_vel_" in err and "300 rad/s" in err and not (tmp_path / "o").exists()


def test_export_tum_and_evaluate_validate_the_run_they_read(tmp_path, capsys, run_file) -> None:
    import pandas as pd

    df = pd.read_parquet(run_file)
    df.loc[3, "t"] = df.loc[2, "t"]  # a duplicated time stamp
    bad = tmp_path / "dup.parquet"
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(
        pq.read_schema(run_file).metadata), bad)
    assert main(["export-tum", str(bad), "-o", str(tmp_path / "x.tum")]) == 2
    assert "duplicated timestamp" in _one_line(capsys)
    assert main(["evaluate", str(bad), str(run_file)]) == 2
    assert "duplicated timestamp" in _one_line(capsys) and not (tmp_path / "x.tum").exists()


def test_the_gap_offers_no_slope_on_rough_ground() -> None:
    """`gap --scenario liu_straight` (class C field) screened the slope effect, which the testbed cannot build on a
    heightfield: a traceback.  The slope is now not a candidate there, and still one on flat ground."""
    from bench.gap.catalogue import get
    from bench.gap.select import applicable
    from bench.spec import load_scenario

    slope = get("slope")
    assert not applicable(slope, True, load_scenario("liu_straight"))
    assert applicable(slope, True, load_scenario("straight_0p2_vinyl"))


def test_command_tracking_of_a_straight_run_has_no_difference_slope(tmp_path) -> None:
    """Every steady command with the same (zero) wheel-speed difference: the slope of the difference is undefined
    (numpy's least squares failed to converge on it), so it is left out instead of raising."""
    from bench.real.drive import import_drive_windows
    from bench.real.gap import command_tracking

    log = _log(n_steps=4)
    log["cmd_right"] = log["cmd_left"].copy()  # both sides the same command: straight runs
    path = tmp_path / "straight.parquet"
    _table(log).to_parquet(path)
    out = command_tracking(import_drive_windows(path), 0.3, 1.1)
    assert "slope_difference" not in out and "slope_sum" in out and out["n_steady_windows"] >= 2


def test_real_gap_needs_a_held_out_step(tmp_path, capsys, drive_table) -> None:
    """One window: `real-gap` used to report "held-out cost nan -> nan" and exit 0."""
    import pandas as pd

    one = tmp_path / "one.parquet"
    pd.read_parquet(drive_table).iloc[:1].to_parquet(one)
    assert main(["real-gap", str(one), "--platform", "husky", "--out", str(tmp_path / "o"), "--no-steady",
                 "--no-transient"]) == 2
    assert "at least 2 command steps" in _one_line(capsys) and not (tmp_path / "o").exists()


@pytest.mark.parametrize("over, field", [("platform.motor.stall_torque=1e9", "platform.motor.stall_torque"),
                                         ("platform.motor.gear_ratio=1e-9", "platform.motor.gear_ratio"),
                                         ("platform.pid.kp=1e12", "platform.pid.kp"),
                                         ("terrain.shear_modulus=1e-9", "terrain.shear_modulus")])
def test_typed_but_absurd_drive_and_tire_values_are_refused(tmp_path, capsys, over, field) -> None:
    """These simulated before (a stall torque of 1e9 N m, a PID gain of 1e12): now out of the spec's ranges."""
    assert main(["simulate", "straight_0p2_vinyl", "--set", over, "-o", str(tmp_path / "x.parquet")]) == 2
    assert f"'{field}'" in _one_line(capsys) and not (tmp_path / "x.parquet").exists()


def test_real_gap_refuses_a_folder_for_json_before_running(tmp_path, capsys, drive_table) -> None:
    """--json naming a folder is refused before the workflow runs (it used to fail after writing the report)."""
    import pandas as pd

    one = tmp_path / "one.parquet"
    pd.read_parquet(drive_table).iloc[:1].to_parquet(one)
    out = tmp_path / "o"
    assert main(["real-gap", str(one), "--platform", "husky", "--out", str(out), "--json", str(tmp_path)]) == 2
    assert "--json" in _one_line(capsys) and not out.exists()


def test_a_killed_real_leaves_a_stage_that_the_next_run_removes(tmp_path, monkeypatch) -> None:
    """``real``/``real-gap`` stage their files in ``--out/.staging.<pid>.*.tmp``; a SIGKILL leaves that folder. The
    next staged write removes the stage of a process that no longer runs and keeps a live one's; ``reproduce``
    removes a dead one under results/ too (it used to unlink it: IsADirectoryError) and leaves a live one."""
    import os
    import subprocess

    import bench.reproduce.runner as runner_mod
    from bench.cli.real import staged_folder
    import time

    from bench.cli.reproduce import STALE_TEMP_AGE, _remove_stale_temp_files

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        out = tmp_path / "out"
        (out / f".staging.{dead.pid}.abc.tmp").mkdir(parents=True)
        (out / f".staging.{dead.pid}.abc.tmp" / "half.md").write_text("half")
        (out / f".staging.{live.pid}.def.tmp").mkdir()
        with staged_folder(out) as stage:
            (stage / "table.md").write_text("whole")
        assert sorted(p.name for p in out.iterdir()) == [f".staging.{live.pid}.def.tmp", "table.md"]
    finally:
        live.kill()
        live.wait()
    results = tmp_path / "results"
    (results / "real" / f".staging.{dead.pid}.x.tmp").mkdir(parents=True)
    (results / "real" / f".staging.{dead.pid}.x.tmp" / "half.md").write_text("half")
    (results / "real" / f".staging.{os.getpid()}.y.tmp").mkdir()  # a live `real` writing into results/real
    (results / "real" / ".half.md.abc.tmp").write_text("half")
    old = time.time() - 2 * STALE_TEMP_AGE  # an interrupted run's temp file: old
    os.utime(results / "real" / ".half.md.abc.tmp", (old, old))
    (results / "real" / ".live.md.def.tmp").write_text("a write in progress")  # another reproduction's, now
    monkeypatch.setattr(runner_mod, "DEFAULT_CACHE", tmp_path / "cache")
    _remove_stale_temp_files(results)
    assert sorted(p.name for p in (results / "real").iterdir()) == [".live.md.def.tmp", f".staging.{os.getpid()}.y.tmp"]


def _warn_in_a_forked_worker() -> None:
    import warnings

    warnings.warn("a note of a worker", UserWarning)


@pytest.mark.parametrize("bad_input", [True, False])
def test_a_warning_before_an_input_error_does_not_break_its_one_line(monkeypatch, capfd, bad_input) -> None:
    """numpy's RuntimeWarning on a bad column used to come before the error line; the command line holds this
    process's warnings until the command ends and drops them when it stops on bad input; a command that succeeds
    shows them after.  A forked worker (the process pools) prints its own as they come, also under the hold."""
    import multiprocessing as mp
    import warnings

    import numpy as np

    from bench import cli
    from bench.spec import SpecError

    def run(a):
        with np.errstate(invalid="warn"):
            np.log(np.array([-1.0]))
        warnings.warn("a note of the command", UserWarning)
        worker = mp.get_context("fork").Process(target=_warn_in_a_forked_worker)
        worker.start()
        worker.join()
        if bad_input:
            raise SpecError("log.csv", "wl", "-1", "a wheel speed")
        return 0

    def to_stderr(message, category, filename, lineno, file=None, line=None):  # Python's own, outside pytest's
        sys.stderr.write(f"{category.__name__}: {message}\n")
        sys.stderr.flush()

    monkeypatch.setitem(cli.COMMANDS, "warns", (lambda p: None, run, "test"))
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = to_stderr
        code = cli.main(["warns"])
    err = capfd.readouterr().err.strip().splitlines()
    assert "UserWarning: a note of a worker" in err  # printed by the worker itself, held by no one
    mine = [line for line in err if line != "UserWarning: a note of a worker"]
    if bad_input:
        assert code == 2 and len(mine) == 1 and mine[0].startswith("error:") and "log.csv" in mine[0]
    else:
        assert code == 0 and mine == ["RuntimeWarning: invalid value encountered in log",
                                      "UserWarning: a note of the command"]
