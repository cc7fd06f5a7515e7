"""Bad command-line input ends in one line naming what is wrong, exit 2 (usage errors) or 130 (Ctrl-C), no traceback."""
from __future__ import annotations

import pytest

from bench import cli


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
    (cli.CalibrationLeak("m: refusing to estimate on run 'r', which it was calibrated on"), 2,
     "error: m: refusing to estimate on run 'r', which it was calibrated on"),
    (cli.MetricError("no reference sample of 'truth' inside the time span of 'm'"), 2,
     "error: no reference sample of 'truth' inside the time span of 'm'"),
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
