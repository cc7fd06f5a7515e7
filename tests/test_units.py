"""Wheel speeds and gyro rates in the wrong unit, in real logs (bench.real.sanity: wheel_scale, gyro_sign,
refuse_unit_slips): refused in one line by `skidbench real`, `real-gap`, `import-drive` and the run imports when the
numbers name the unit (a log in rpm, deg/s), never for a log that merely looks odd (pivot turns).  The synthetic robot
and its defects are tests/test_real_cli.py's.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from bench.cli import main
from bench.run import RunError
from bench.spec import SCENARIO_DIR
from tests.test_drive import N
from tests.test_real_cli import B, R, _cols, _log, _run_of, _table, clean, defect  # noqa: F401  (clean: fixture)


@pytest.mark.parametrize("kind, column", [("wheel_scale", "left_wheel_vel"), ("gyro_deg", "imu_yaw")])
@pytest.mark.parametrize("command", ["real", "real-gap", "import-drive"])
def test_a_log_in_rpm_or_deg_per_s_is_refused_in_one_line(clean, tmp_path, capsys, kind, column, command):
    """A unit mistake the numbers name (slope 0.105: rpm; 57.3: deg/s) is bad input: exit 2 before anything is
    computed or written, one line naming the file, the column and the unit, never a scored report."""
    path = tmp_path / "robot_rpm.parquet"
    defect(clean[1], kind).to_parquet(path)
    toml = tmp_path / "robot.toml"
    toml.write_text(f"wheel_radius = {R}\ntrack = {B}\n")
    full = tmp_path / "husky_r30.toml"  # real-gap simulates: a full spec, the Husky's with the log's wheel radius
    husky = (SCENARIO_DIR / "platforms" / "husky.toml").read_text()
    full.write_text(re.sub(r"(?m)^wheel_radius = [0-9.]+", f"wheel_radius = {R}", husky, count=1))
    out = tmp_path / "o"
    argv = {"real": ["real", str(path), "--platform", str(toml), "--out", str(out)],
            "real-gap": ["real-gap", str(path), "--platform", str(full), "--out", str(out)],
            "import-drive": ["import-drive", str(path), "--wheel-radius", str(R), "--track", str(B), "-o", str(out)]}
    assert main(argv[command]) == 2
    err = capsys.readouterr().err.strip()
    unit = "rpm" if kind == "wheel_scale" else "deg/s"
    assert err.count("\n") == 0 and "robot_rpm.parquet" in err and column in err and f"{unit} given as rad/s" in err
    assert not out.exists() or not any(out.iterdir())


def test_a_log_of_pivot_turns_is_not_taken_for_a_unit_mistake(tmp_path):
    """Turning on the spot, the body's path speed is the reference's noise (2 mm per sample here) and the mean tread
    speed the encoders' noise: the slope is anything, no window is straight; the data are scored, never refused."""
    from bench.real.sanity import scored_windows

    df = _table(_log(n_steps=20, pivot=True))
    rng = np.random.default_rng(5)
    for b in ("icp_x", "icp_y"):
        df[_cols(df, b)] += rng.normal(0, 0.002, size=(len(df), N))
    path = tmp_path / "pivots.parquet"
    df.to_parquet(path)
    _, w, found = scored_windows(path, R)
    scale = next(f for f in found if f.check == "wheel_scale")
    assert scale.unit is None and scale.values["n_straight"] == 0, scale.line()  # no straight window to judge by
    assert w.n_windows > 0


@pytest.mark.parametrize("case", ["one_speed_rpm", "gyro_deg_flipped"])
def test_a_unit_mistake_is_found_where_a_correlation_could_not(clean, tmp_path, case):
    """A log driven at one speed (its path and tread speeds cannot correlate) in rpm, and a flipped gyro in deg/s (a
    negative slope of 57): both refused, the first by the ratio on its straight windows."""
    from bench.real.sanity import scored_windows

    df = _table(_log(n_steps=20, one_speed=True)) if case == "one_speed_rpm" else clean[1]
    df = defect(df, "wheel_scale" if case == "one_speed_rpm" else "gyro_deg_flipped")
    path = tmp_path / f"{case}.parquet"
    df.to_parquet(path)
    with pytest.raises(RunError) as exc:
        scored_windows(path, R)
    assert ("rpm" if case == "one_speed_rpm" else "deg/s") + " given as rad/s" in str(exc.value)


def test_motor_shaft_speeds_are_refused_naming_the_gearbox_beside_rpm(clean, tmp_path):
    """Wheel speeds logged at the motor shaft through a 10:1 gearbox read 10 times too fast, a slope (0.1) rpm's 0.105
    also gives: refused as rpm is, the message naming the gearbox whose ratio the straight windows give (1 / 0.1)."""
    from bench.real.sanity import scored_windows

    df = clean[1].copy()
    for b in ("left_wheel_vel", "right_wheel_vel"):
        df[_cols(df, b)] *= 10.0
    path = tmp_path / "motor_shaft.parquet"
    df.to_parquet(path)
    with pytest.raises(RunError) as exc:
        scored_windows(path, R)
    msg = str(exc.value)
    ratio = float(re.search(r"through a ([0-9.]+):1 gearbox", msg).group(1))
    assert "rpm given as rad/s" in msg and ratio == pytest.approx(10.0, abs=0.3), msg


def test_a_run_in_deg_per_s_is_refused_by_the_run_check_naming_its_channel():
    """The run imports' check (bench.real.run_sanity.check_run) refuses a gyro in deg/s and names the Run's channel
    (imu_gz), not a DRIVE column."""
    from bench.real.run_sanity import check_run

    run = _run_of(_log(n_steps=12))
    run.data["imu_gz"] *= 180.0 / np.pi
    with pytest.raises(RunError) as exc:
        check_run(run)
    msg = str(exc.value)
    assert "'imu_gz'" in msg and "deg/s given as rad/s" in msg and "imu_yaw" not in msg
