"""Bad command-line input ends in one line naming what is wrong, exit 2 (usage errors) or 130 (Ctrl-C), no traceback."""
from __future__ import annotations

import pytest

from bench import cli
from bench.metrics.trajectory import MetricError
from bench.registry import CalibrationLeak


@pytest.mark.parametrize("argv, words", [
    (["simulate", "straight_0p2_vinyl", "--seed", "-1", "-o", "x.parquet"], "error: argument --seed: -1 must be >= 0"),
    (["simulate", "straight_0p2_vinyl", "--seed", "two", "-o", "x.parquet"], "error: argument --seed: 'two' is not an integer"),
    (["reproduce", "yu2010", "--workers", "0"], "error: argument --workers: 0 must be >= 1"),
    (["verify-runs", "--workers", "-3"], "error: argument --workers: -3 must be >= 1"),
])
def test_counts_out_of_range_are_usage_errors(argv, words, capsys) -> None:
    with pytest.raises(SystemExit) as ei:
        cli.main(argv)
    assert ei.value.code == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def _raising(exc: BaseException):
    def fn(_a):
        raise exc
    return fn


@pytest.mark.parametrize("exc, code, line", [
    (KeyboardInterrupt(), 130, "interrupted"),
    (CalibrationLeak("m: refusing to estimate on run 'r', which it was calibrated on"), 2,
     "error: m: refusing to estimate on run 'r', which it was calibrated on"),
    (MetricError("no reference sample of 'truth' inside the time span of 'm'"), 2,
     "error: no reference sample of 'truth' inside the time span of 'm'"),
    (FileNotFoundError(2, "No such file or directory", "runs/a.parquet"), 2,
     "error: runs/a.parquet: No such file or directory"),  # the user's path: bad input
    (OSError(28, "No space left on device", "results/REPORT.md"), 1,
     "error: results/REPORT.md: No space left on device"),  # the machine's failure: one line, not exit 2
])
def test_interrupts_and_scoring_errors_end_in_one_line(monkeypatch, capsys, exc, code, line) -> None:
    cli.build_parser()  # registers the commands
    add_args, _fn, help_ = cli.COMMANDS["list"]
    monkeypatch.setitem(cli.COMMANDS, "list", (add_args, _raising(exc), help_))
    assert cli.main(["list"]) == code
    assert capsys.readouterr().err.strip().splitlines() == [line]


def test_estimate_of_a_method_that_needs_calibration_says_so(tmp_path, capsys) -> None:
    """Liu's ICR dead reckoning without --calibrate: one line naming the run, the method and the option, exit 2."""
    from bench.sim import simulate
    from bench.spec import load_scenario

    run = tmp_path / "r.parquet"
    simulate(load_scenario("straight_0p2_vinyl", {"duration": 1.0}), 0).to_parquet(run)
    assert cli.main(["estimate", "liu2020.icr", str(run), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(run) in err[0] and "liu2020.icr cannot estimate uncalibrated" in err[0]
    assert "--calibrate" in err[0] and not (tmp_path / "e.csv").exists()


def test_estimate_does_not_blame_calibration_for_a_plugins_own_error(tmp_path, monkeypatch) -> None:
    """A plugin whose estimate raises its own ValueError: shown whole (its author needs the traceback), never
    "cannot estimate uncalibrated ... give calibration runs", which would send its user the wrong way."""
    from bench import registry
    from bench.sim import simulate
    from bench.spec import load_scenario

    class Buggy:
        name, requires = "test.buggy", frozenset({"enc_wl"})

        def calibrate(self, runs):
            return self

        def estimate(self, run):
            raise ValueError("my plugin bug")

    monkeypatch.setattr(registry, "get", lambda name, **kw: Buggy())
    run = tmp_path / "r.parquet"
    simulate(load_scenario("straight_0p2_vinyl", {"duration": 1.0}), 0).to_parquet(run)
    with pytest.raises(ValueError, match="my plugin bug"):
        cli.main(["estimate", "test.buggy", str(run), "-o", str(tmp_path / "e.csv")])
    assert not (tmp_path / "e.csv").exists()


@pytest.mark.parametrize("dtype", ["str", "string", "bool"])
def test_a_run_with_a_non_numeric_channel_is_named(tmp_path, capsys, dtype) -> None:
    """A channel stored as text (or booleans) in a run's Parquet: one line naming the file, the column and its type."""
    from bench.run import from_arrays

    import numpy as np

    run = from_arrays({"t": np.arange(5) * 0.1, "enc_wl": np.ones(5), "enc_wr": np.ones(5)}, {"run_id": "r"})
    run.data["enc_wl"] = run.data["enc_wl"].astype(dtype) if dtype != "bool" else run.data["enc_wl"] > 0
    path = tmp_path / "r.parquet"
    run.data.to_parquet(path)
    assert cli.main(["export-tum", str(path), "-o", str(tmp_path / "x.tum")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "'enc_wl'" in err[0] and "expected a numeric column" in err[0]


def test_a_start_yaw_rate_out_of_range_is_one_line_naming_file_field_value(capsys) -> None:
    """--set initial_yaw_rate / initial_skid_ratio are range-checked like any scenario field (exit 2, one line)."""
    for over, words in (("initial_yaw_rate=11", "field 'initial_yaw_rate' = 11.0: expected in [-10, 10] rad/s"),
                        ("initial_skid_ratio=-1", "field 'initial_skid_ratio' = -1.0: expected in [0, 20]")):
        assert cli.main(["simulate", "circle_vinyl", "--set", over, "-o", "x.parquet"]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "circle_vinyl.toml" in lines[0] and words in lines[0]


@pytest.mark.parametrize("argv", [["list"], ["list", "--json"]])  # rich's console, and print
def test_a_reader_that_goes_away_ends_the_command_quietly(argv) -> None:
    """`skidbench list | head -0`: stdout closed before the command writes; no traceback, exit 1 (rich's own
    handling of a broken pipe, and ours for print)."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-m", "bench.cli", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait() == 1 and err == "", err


def test_a_broken_pipe_that_is_not_stdout_is_not_swallowed(monkeypatch) -> None:
    """A worker's or a child's pipe breaking is a defect: raised, not a quiet exit 1 (only a closed stdout is)."""
    cli.build_parser()
    add_args, _fn, help_ = cli.COMMANDS["list"]
    monkeypatch.setitem(cli.COMMANDS, "list", (add_args, _raising(BrokenPipeError(32, "Broken pipe")), help_))
    with pytest.raises(BrokenPipeError):
        cli.main(["list"])
