"""``skidbench real`` on a robot the code has never seen, from a TOML with its wheel radius and track alone, and the
data's sanity checks (bench.real.sanity): each fires on a synthetic table with its defect and stays silent on the
clean table.

The synthetic robot: r = 0.30 m, B = 1.10 m, a symmetric ICR model with chi = 1.6 (Wang 2015 eq. (15): the yaw rate is
(v_r - v_l) / (chi B)), a first-order powertrain (tau = 0.15 s) following random 6 s command steps, exact SE(2) poses
at 20 Hz, a gyro reading the yaw rate, an accelerometer reading no acceleration in steady state.  Cut into DRIVE
windows by tests.test_drive.drive_cut (one transitory and two steady windows per step).
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.cli import main
from bench.real.drive import DRIVE_DT, import_drive_windows
from bench.real.sanity import apply_fixes, check_windows
from bench.spec import SCENARIO_DIR
from tests.test_drive import N, drive_cut

R, B, CHI, TAU = 0.30, 1.10, 1.6, 0.15
PER = 120  # samples per 6 s step


def _log(n_steps: int = 40, seed: int = 1, lag: int = 0, chi: float = CHI, pivot: bool = False,
         one_speed: bool = False) -> dict:
    rng = np.random.default_rng(seed)
    pre = N + 5
    n = pre + n_steps * PER + 5
    label = np.clip((np.arange(n) - pre) // PER, 0, n_steps - 1)
    cmd = rng.uniform(-4, 4, size=(n_steps, 2))[label]
    if pivot:  # turns on the spot only: the sides opposite and equal
        cmd[:, 1] = -cmd[:, 0]
    if one_speed:  # driven at one speed, gently steered: the wheel and path speeds cannot correlate
        cmd = 3.0 + rng.uniform(-0.3, 0.3, size=(n_steps, 2))[label]
    cmd[:pre] = 0.0
    wheel = np.zeros((n, 2))
    a = DRIVE_DT / TAU
    for i in range(1, n):  # first-order powertrain (exact discretisation of a step held over the row)
        wheel[i] = wheel[i - 1] + (1 - np.exp(-a)) * (cmd[i - 1] - wheel[i - 1])
    if lag:  # the wheel-speed stream's clock behind the commands': samples arrive `lag` rows late
        wheel = np.vstack([np.zeros((lag, 2)), wheel[:-lag]])
    v = R * (wheel[:, 0] + wheel[:, 1]) / 2
    wz = R * (wheel[:, 1] - wheel[:, 0]) / (chi * B)
    x, y, yaw = np.zeros(n), np.zeros(n), np.zeros(n)
    for i in range(n - 1):
        u, w = v[i] * DRIVE_DT, wz[i] * DRIVE_DT
        dx, dy = (np.sin(w) * u / w, (1 - np.cos(w)) * u / w) if abs(w) > 1e-12 else (u, 0.0)
        c, s = np.cos(yaw[i]), np.sin(yaw[i])
        x[i + 1], y[i + 1], yaw[i + 1] = x[i] + c * dx - s * dy, y[i] + s * dx + c * dy, yaw[i] + w
    return {"x": x, "y": y, "yaw": yaw, "label": label, "cmd_left": cmd[:, 0], "cmd_right": cmd[:, 1],
            "left_wheel_vel": wheel[:, 0] + rng.normal(0, 0.02, n),
            "right_wheel_vel": wheel[:, 1] + rng.normal(0, 0.02, n),
            "imu_acceleration_x": np.gradient(v, DRIVE_DT) + rng.normal(0, 0.05, n),
            "imu_acceleration_y": v * wz + rng.normal(0, 0.05, n), "imu_acceleration_z": 9.81 + rng.normal(0, 0.05, n),
            "imu_yaw": wz + rng.normal(0, 0.005, n), "pre": pre, "n_steps": n_steps}


def _table(log: dict) -> pd.DataFrame:
    starts = []
    for k in range(log["n_steps"]):
        t0 = log["pre"] + k * PER - 1
        starts += [(t0, k, True), (t0 + N, k, False), (t0 + 2 * N, k, False)]
    return drive_cut(log, starts)


def _cols(df: pd.DataFrame, base: str) -> list[str]:
    return [f"{base}_{k}" for k in range(N)]


def defect(df: pd.DataFrame, kind: str) -> pd.DataFrame:
    df = df.copy()
    if kind == "gyro_sign":
        df[_cols(df, "imu_yaw")] *= -1
    elif kind == "imu_offset":
        df[_cols(df, "imu_acceleration_x")] -= 1.1
    elif kind == "update_rate":  # wheel speeds updating at 4 Hz inside the 20 Hz table
        for b in ("left_wheel_vel", "right_wheel_vel"):
            a = df[_cols(df, b)].to_numpy()
            df[_cols(df, b)] = a[:, (np.arange(N) // 5) * 5]
    elif kind == "wheel_scale":  # the whole log in rpm: wheel speeds and commands (rad/s * 60 / 2 pi)
        for b in ("left_wheel_vel", "right_wheel_vel", "cmd_left", "cmd_right"):
            df[_cols(df, b)] *= 60.0 / (2.0 * np.pi)
    elif kind == "gyro_deg":  # the gyro in deg/s
        df[_cols(df, "imu_yaw")] *= 180.0 / np.pi
    elif kind == "gyro_deg_flipped":  # in deg/s and upside down
        df[_cols(df, "imu_yaw")] *= -180.0 / np.pi
    elif kind == "clock_offset":  # the gyro 4 samples (0.2 s) early: each sample is the rate 4 samples later
        a = df[_cols(df, "imu_yaw")].to_numpy()
        df[_cols(df, "imu_yaw")] = a[:, np.minimum(np.arange(N) + 4, N - 1)]
    elif kind == "stale_reference":  # the reference held over the last 10 samples of 80 % of the windows
        rows = np.random.default_rng(0).random(len(df)) < 0.8
        for b in ("icp_x", "icp_y", "icp_yaw"):
            a = df[_cols(df, b)].to_numpy(copy=True)
            a[rows, N - 10:] = a[rows, N - 11:N - 10]
            df[_cols(df, b)] = a
    return df


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> tuple[Path, pd.DataFrame]:
    df = _table(_log())
    path = tmp_path_factory.mktemp("real") / "robot_x.parquet"
    df.to_parquet(path)
    return path, df


def _findings(df: pd.DataFrame, tmp_path: Path, wheel_radius: float | None = R) -> dict:
    path = tmp_path / "t.parquet"
    df.to_parquet(path)
    return {f.check: f for f in check_windows(import_drive_windows(path), wheel_radius)}


def test_clean_table_raises_no_warning(clean, tmp_path):
    found = _findings(clean[1], tmp_path)
    assert set(found) == {"gyro_sign", "imu_offset", "update_rate", "stale_reference", "command_lag", "clock_offset",
                          "wheel_scale"}
    assert all(f.ok for f in found.values()), [f.line() for f in found.values() if not f.ok]
    assert found["gyro_sign"].values["slope"] == pytest.approx(1.0, abs=0.02)
    # the synthetic body moves at the tread speed R (w_l + w_r) / 2 exactly (no longitudinal slip)
    assert found["wheel_scale"].values["slope"] == pytest.approx(1.0, abs=0.03)
    assert "wheel_scale" not in _findings(clean[1], tmp_path, wheel_radius=None)  # no radius, no check
    # T50 of a first-order lag is tau ln 2 = 0.10 s, counted in whole 0.05 s samples from the command's crossing
    assert 0.05 <= found["command_lag"].values["t50_s"] <= 0.2


@pytest.mark.parametrize("kind", ["gyro_sign", "imu_offset", "update_rate", "stale_reference", "clock_offset",
                                  "wheel_scale"])
def test_each_defect_fires_its_check_alone(clean, tmp_path, kind):
    found = _findings(defect(clean[1], kind), tmp_path)
    assert not found[kind].ok, found[kind].line()
    assert [c for c, f in found.items() if not f.ok] == [kind]


def test_check_values_measure_the_defect(clean, tmp_path):
    assert _findings(defect(clean[1], "gyro_sign"), tmp_path)["gyro_sign"].values["slope"] == pytest.approx(-1.0, abs=0.02)
    assert _findings(defect(clean[1], "imu_offset"), tmp_path)["imu_offset"].values["imu_ax"] == pytest.approx(-1.1, abs=0.05)
    rpm = _findings(defect(clean[1], "wheel_scale"), tmp_path)["wheel_scale"]
    assert rpm.values["slope"] == pytest.approx(2 * np.pi / 60, rel=0.03) and "rpm given as rad/s" in rpm.evidence
    # a wheel radius given 4 times too small: slope 4, outside 1/3..3, and no unit is named
    small = _findings(clean[1], tmp_path, wheel_radius=R / 4)["wheel_scale"]
    assert not small.ok and small.values["slope"] == pytest.approx(4.0, rel=0.03) and "a unit?" in small.evidence
    deg = _findings(defect(clean[1], "gyro_deg"), tmp_path)["gyro_sign"]
    assert not deg.ok and deg.values["slope"] == pytest.approx(180 / np.pi, rel=0.03)
    assert deg.unit == "deg/s given as rad/s" and rpm.unit == "rpm given as rad/s" and small.unit is None
    rate = _findings(defect(clean[1], "update_rate"), tmp_path)["update_rate"].values
    # 4 Hz holds of 5 samples: 7 changes over the 39 sample pairs of a 40-sample window, at 20 Hz
    assert rate["enc_wl"] == pytest.approx(20 * 7 / 39, rel=1e-9) and rate["imu_gz"] > 19


def test_a_clock_offset_between_commands_and_wheel_speeds_fires(tmp_path):
    found = _findings(_table(_log(n_steps=20, lag=30)), tmp_path)  # 1.5 s late
    assert not found["command_lag"].ok and found["command_lag"].values["t10_s"] > 1.0


def test_fixes_correct_what_they_name(clean, tmp_path):
    path = tmp_path / "bad.parquet"
    defect(defect(clean[1], "gyro_sign"), "imu_offset").to_parquet(path)
    w = import_drive_windows(path)
    fixed, lines = apply_fixes(w, ["flip_gyro", "imu_offset"])
    found = {f.check: f for f in check_windows(fixed)}
    assert found["gyro_sign"].ok and found["imu_offset"].ok and len(lines) >= 2
    assert abs(found["imu_offset"].values["imu_ax"]) < 0.01


def test_the_imu_offset_is_measured_on_the_windows_it_is_told(clean, tmp_path):
    """``measure_on`` (the benchmark passes the calibration half's windows): a held-out window's offset does not
    shape the correction.  Here only the first half of the steps carries a -1.1 m/s^2 offset."""
    path = tmp_path / "half.parquet"
    clean[1].to_parquet(path)
    w = import_drive_windows(path)
    steps = np.unique(w.calib_step)
    first = np.isin(w.calib_step, steps[: steps.size // 2])
    ax = np.array(w["imu_ax"], float)
    ax[first] -= 1.1
    w = dataclasses.replace(w, channels={**w.channels, "imu_ax": ax})

    def correction(mask):
        lines = apply_fixes(w, ["imu_offset"], measure_on=mask)[1]
        return {ln.split()[1]: float(ln.split()[2]) for ln in lines if ln.startswith("imu_offset:")}

    assert correction(first)["imu_ax"] == pytest.approx(1.1, abs=0.05)
    assert correction(~first)["imu_ax"] == pytest.approx(0.0, abs=0.05)

def test_an_unseen_robot_scores_from_a_radius_and_track_toml(clean, tmp_path, capsys):
    path, _ = clean
    toml = tmp_path / "robot.toml"
    toml.write_text('name = "bigbot"\nwheel_radius_cm = 30\ntrack = 1.1\n')
    out = tmp_path / "out"
    assert main(["real", str(path), "--platform", str(toml), "--out", str(out), "--json", str(tmp_path / "r.json"),
                 "--no-figures"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["robot_x-bigbot.csv", "robot_x-bigbot.md", "robot_x-bigbot_chi.csv"]
    doc = json.loads((tmp_path / "r.json").read_text())
    res = doc["data"][str(path)]
    assert res["wheel_radius"] == 0.3 and res["track"] == 1.1 and res["platform"] == "bigbot"
    med = {m: v["stats"]["all"]["trans"]["median"] for m, v in res["models"].items()}
    assert med["icr_sym_chi"] < 0.2 * med["ideal_dd"]  # chi = 1.6: ideal DD over-turns by 60 %
    assert res["models"]["icr_sym_chi"]["params"]["chi"] == pytest.approx(CHI, rel=0.02)
    assert res["chi"]["median"] == pytest.approx(CHI, rel=0.02)  # Wang eq. (25) measured on the windows
    assert "husky" not in capsys.readouterr().out.lower()


@pytest.mark.parametrize("toml, field", [('wheel_radius = 0.3\n', "track"), ('track = 1.1\n', "wheel_radius"),
                                         ('wheel_radius = -1\ntrack = 1\n', "wheel_radius"),
                                         ('wheel_radius = 0.3\nwheel_radius_cm = 30\ntrack = 1\n', "wheel_radius"),
                                         ('wheel_radius = 0.3\nwheelradius = 0.2\ntrack = 1\n', "wheelradius")])
def test_a_platform_toml_missing_what_the_models_need_is_one_line(clean, tmp_path, capsys, toml, field):
    p = tmp_path / "bad.toml"
    p.write_text(toml)
    assert main(["real", str(clean[0]), "--platform", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.toml" in err and field in err
    assert not (tmp_path / "o").exists()


def test_real_needs_an_output_folder_and_a_known_fix(clean, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["real", str(clean[0]), "--platform", "husky"])
    assert exc.value.code == 2
    assert main(["real", str(clean[0]), "--platform", "husky", "--out", str(tmp_path / "o"), "--fix", "magic"]) == 2
    assert "magic" in capsys.readouterr().err


def test_bootstrap_interval_over_steps_is_the_percentiles_of_resampled_medians():
    from bench.real.league import _resample, bootstrap_median

    steps = np.repeat(np.arange(4), 3)
    same = np.full(12, 0.7)
    assert bootstrap_median(same, _resample(steps, np.random.default_rng(0), 200)) == (0.7, 0.7, 0.7)
    e = np.repeat([0.1, 0.2, 0.3, 0.4], 3)  # each step's windows equal: a resample's median is a step value
    m, lo, hi = bootstrap_median(e, _resample(steps, np.random.default_rng(0), 500))
    assert m == pytest.approx(0.25) and 0.1 <= lo < m < hi <= 0.4


def test_league_says_plainly_where_an_icr_model_does_not_beat_ideal_dd(tmp_path):
    """A robot whose chi is 1 (no skid: ideal DD is exact): the calibrated ICR models cannot beat it, and the league
    says so; the chi = 1.6 robot's models beat it."""
    from bench.real.benchmark import run_real_benchmark
    from bench.real.league import league_markdown

    out = []
    for chi in (1.0, CHI):
        path = tmp_path / f"chi{chi}.parquet"
        _table(_log(chi=chi)).to_parquet(path)
        plat = {"name": f"chi{chi}", "wheel_radius": R, "track": B}
        res = run_real_benchmark(path, tmp_path / "o", platform=plat, figures=False, label=path.stem,
                                 models=["baseline.ideal_dd", "wang2015.constant_chi"])
        out.append((path, res, f"{path.stem}.md"))
    text = league_markdown(out)
    one, other = text.split("## chi1.6")
    assert "`icr_sym_chi` does not beat ideal differential drive on this data set" in one
    assert "does not beat" not in other and "| `icr_sym_chi` |" in other and "beats (" in other
    # the registered plugins without window models are named as not scored, and none of them has a row
    from bench.real.benchmark import plugins_without_window_models

    names = plugins_without_window_models()
    assert "mandow2007.symmetric" in names and "baseline.ideal_dd" not in names
    listed = league_markdown(out, names)
    assert "Not scored (registered plugins without window models" in listed and "Not scored" not in text
    assert all(f"`{n}`" in listed and f"| `{n}` |" not in listed for n in names)


def _run_of(log: dict, imu_every: int = 1) -> "Run":
    """The continuous log as a Run: 20 Hz wheels, commands and reference; the gyro every ``imu_every`` rows (NaN
    between, the Run convention for a slower sensor)."""
    from bench.run import Run

    n = log["x"].size
    gz = np.full(n, np.nan)
    gz[::imu_every] = log["imu_yaw"][::imu_every]
    data = pd.DataFrame({"t": DRIVE_DT * np.arange(n), "cmd_wl": log["cmd_left"], "cmd_wr": log["cmd_right"],
                         "enc_wl": log["left_wheel_vel"], "enc_wr": log["right_wheel_vel"], "imu_gz": gz,
                         "ref_x": log["x"], "ref_y": log["y"], "ref_yaw": (log["yaw"] + np.pi) % (2 * np.pi) - np.pi})
    return Run(data, {"run_id": "synthetic_robot"})


def test_a_continuous_run_is_cut_into_the_windows_of_its_command_steps(tmp_path):
    from bench.real.run_windows import windows_from_run

    log = _log(n_steps=6)
    w = windows_from_run(_run_of(log, imu_every=3))
    # the 45 samples at rest before the first command: a step of one window (the 5 left over dropped); then each
    # 6 s step (120 samples) holds three whole 2 s windows: T, S, S
    assert log["pre"] == N + 5 and w.n_windows == 1 + 18 and w.n_samples == N
    assert w.transitory.tolist() == [True] + [True, False, False] * 6
    assert w.calib_step.tolist() == [0] + list(np.repeat(range(1, 7), 3))
    # window k of command step j starts at pre + j * PER + k * N, with its pose at (0, 0, 0)
    j, k = 4, 2
    s = log["pre"] + j * PER + k * N
    i = 1 + 3 * j + k
    np.testing.assert_array_equal(w["enc_wl"][i], log["left_wheel_vel"][s:s + N])
    assert (w["ref_x"][i, 0], w["ref_y"][i, 0], w["ref_yaw"][i, 0]) == (0.0, 0.0, 0.0)
    c, sn = np.cos(log["yaw"][s]), np.sin(log["yaw"][s])
    dx, dy = log["x"][s + N - 1] - log["x"][s], log["y"][s + N - 1] - log["y"][s]
    assert w["ref_x"][i, -1] == pytest.approx(c * dx + sn * dy, abs=1e-12)
    assert w["ref_yaw"][i, -1] == pytest.approx(log["yaw"][s + N - 1] - log["yaw"][s], abs=1e-9)
    # the gyro every third row: held in between (zero-order hold)
    np.testing.assert_array_equal(w["imu_gz"][i], log["imu_yaw"][(np.arange(s, s + N) // 3) * 3])


def test_real_scores_an_imported_run_like_its_drive_table(tmp_path):
    log = _log()
    run_path = tmp_path / "robot_run.parquet"
    _run_of(log).to_parquet(run_path)
    toml = tmp_path / "robot.toml"
    toml.write_text(f"wheel_radius = {R}\ntrack = {B}\n")
    assert main(["real", str(run_path), "--platform", str(toml), "--out", str(tmp_path / "o"), "--no-figures",
                 "--json", str(tmp_path / "r.json"), "--methods", "baseline.ideal_dd,wang2015.constant_chi"]) == 0
    res = json.loads((tmp_path / "r.json").read_text())["data"][str(run_path)]
    assert res["models"]["icr_sym_chi"]["params"]["chi"] == pytest.approx(CHI, rel=0.02)
    assert res["chi"]["median"] == pytest.approx(CHI, rel=0.02)
    assert (tmp_path / "o" / "robot_run-robot.md").is_file()


def test_import_drive_warns_and_records_the_checks_in_the_runs(clean, tmp_path, capsys):
    from bench.run import Run

    bad = tmp_path / "flipped.parquet"
    defect(clean[1], "gyro_sign").to_parquet(bad)
    assert main(["import-drive", str(bad), "--platform", "husky", "-o", str(tmp_path / "runs")]) == 0
    out = capsys.readouterr().out
    assert "warning:" in out and "gyro_sign" in out and "--fix flip_gyro" in out
    run = Run.from_parquet(sorted((tmp_path / "runs").glob("*.parquet"))[0])
    assert [f["check"] for f in run.meta["sanity"]["findings"] if not f["ok"]] == ["gyro_sign"]
    assert main(["import-drive", str(bad), "--platform", "husky", "--fix", "flip_gyro", "-o", str(tmp_path / "r2")]) == 0
    run2 = Run.from_parquet(sorted((tmp_path / "r2").glob("*.parquet"))[0])
    assert run2.meta["sanity"]["fixes"] == ["flip_gyro: imu_gz multiplied by -1"]
    np.testing.assert_array_equal(run2.data["imu_gz"].to_numpy(), -run.data["imu_gz"].to_numpy())


def _platform_toml(tmp_path: Path, drop: str | None = None) -> Path:
    """A full testbed platform spec of the synthetic robot: the Husky's file with its name, wheel radius and track
    changed (and a field dropped)."""
    from bench.spec import SCENARIO_DIR

    lines, top = [], True
    for ln in (SCENARIO_DIR / "platforms" / "husky.toml").read_text().splitlines():
        top = top and not ln.startswith("[")  # the top-level fields, not the [sources] table
        key = ln.split("=")[0].strip()
        if top and key == drop:
            continue
        new = {"name": 'name = "bigbot"', "wheel_radius": f"wheel_radius = {R}", "track": f"track = {B}"}
        lines.append(new.get(key, ln) if top else ln)
    p = tmp_path / "bigbot.toml"
    p.write_text("\n".join(lines) + "\n")
    return p


def test_real_gap_runs_on_another_robot_from_its_platform_toml(clean, tmp_path, capsys):
    out = tmp_path / "gap"
    assert main(["real-gap", str(clean[0]), "--platform", str(_platform_toml(tmp_path)), "--out", str(out),
                 "--json", str(tmp_path / "g.json"), "--workers", "1"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["robot_x-bigbot_gap.json", "robot_x-bigbot_gap.md",
                                                      "robot_x-bigbot_gap.png"]
    doc = json.loads((tmp_path / "g.json").read_text())
    assert doc["platform"] == "bigbot" and doc["data_file"] == "robot_x.parquet"
    md = (out / "robot_x-bigbot_gap.md").read_text()
    assert "husky" not in md.lower() and "robot_x-bigbot_gap.png" in md
    # every stage ran, and the fit block's effects were judged on every other calibration step
    from bench.real.benchmark import split_steps
    from bench.real.drive import import_drive_windows
    from bench.real.windows import valid_windows

    allw = import_drive_windows(clean[0])
    calib, _ = split_steps(allw.subset(valid_windows(allw)), 0)
    v = doc["validation"]
    assert doc["transient_response"]["n_transitions"] > 0 and "Transient response" in md
    fitted = doc["workflow"]["effects"] + doc["workflow"]["partial_candidates"]
    assert v["n_steps"] == (len(calib) - len(doc["fit_steps"]) if fitted else 0)
    assert "husky" not in capsys.readouterr().out.lower()


def test_real_gap_fits_several_calibration_steps_each_on_its_own(clean, tmp_path, capsys):
    """--fit-steps 2: the first two calibration-half steps (table order), each replayed from its own initial state
    (bench.gap.segments), none of them held out; the report says how the fit saw them."""
    from bench.real.benchmark import split_steps
    from bench.real.drive import import_drive_windows
    from bench.real.windows import valid_windows

    out = tmp_path / "gap"
    assert main(["real-gap", str(clean[0]), "--platform", str(_platform_toml(tmp_path)), "--out", str(out),
                 "--json", str(tmp_path / "g.json"), "--workers", "1", "--fit-steps", "2", "--max-effects", "1",
                 "--no-transient", "--validation-steps", "6"]) == 0
    doc = json.loads((tmp_path / "g.json").read_text())
    allw = import_drive_windows(clean[0])
    w = allw.subset(valid_windows(allw))
    calib, test = split_steps(w, 0)
    firsts = [int(s) for s in dict.fromkeys(w.calib_step.tolist()) if int(s) in set(int(c) for c in calib)][:2]
    assert doc["fit_separate"] is True and doc["fit_steps"] == firsts
    assert not set(doc["fit_steps"]) & set(doc["held_out_steps"])
    assert doc["bounds"]["max_effects"] == 1 and len(doc["workflow"]["candidates"]) <= 1
    md = (out / "robot_x-bigbot_gap.md").read_text()
    assert "each replayed on its own from its measured initial state" in md


def test_real_gap_names_the_field_a_platform_toml_lacks(clean, tmp_path, capsys):
    bad = _platform_toml(tmp_path, drop="mass")
    assert main(["real-gap", str(clean[0]), "--platform", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "mass" in err and "bigbot.toml" in err and not (tmp_path / "o").exists()


CSV_MAP = """
run_id = "robot_csv"
[time]
column = "t"
[wheels]
left = "wl"
right = "wr"
[commands]
left = "cl"
right = "cr"
[imu]
ax = "ax"
gz = "gz"
[reference]
x = "x"
y = "y"
yaw = "yaw"
"""


def _csv_of(log: dict, path: Path, kind: str | None = None) -> Path:
    """The continuous synthetic log as a CSV (20 Hz) with one recording defect of :func:`defect`'s kinds."""
    n = log["x"].size
    wl, wr = log["left_wheel_vel"].copy(), log["right_wheel_vel"].copy()
    ax, gz = log["imu_acceleration_x"].copy(), log["imu_yaw"].copy()
    if kind == "gyro_sign":
        gz = -gz
    elif kind == "imu_offset":
        ax = ax - 1.1
    elif kind == "update_rate":  # wheel speeds updating at 4 Hz
        i = (np.arange(n) // 5) * 5
        wl, wr = wl[i], wr[i]
    pd.DataFrame({"t": DRIVE_DT * np.arange(n), "wl": wl, "wr": wr, "cl": log["cmd_left"], "cr": log["cmd_right"],
                  "ax": ax, "gz": gz, "x": log["x"], "y": log["y"],
                  "yaw": (log["yaw"] + np.pi) % (2 * np.pi) - np.pi}).to_csv(path, index=False)
    return path


@pytest.mark.parametrize("kind", [None, "gyro_sign", "imu_offset", "update_rate"])
def test_import_csv_checks_the_data_and_records_the_findings(tmp_path, capsys, kind):
    from bench.run import Run

    log = _log(n_steps=12)
    csv = _csv_of(log, tmp_path / "log.csv", kind)
    (tmp_path / "map.toml").write_text(CSV_MAP)
    out_path = tmp_path / "run.parquet"
    assert main(["import-csv", str(csv), "--map", str(tmp_path / "map.toml"), "-o", str(out_path)]) == 0
    out = capsys.readouterr().out
    run = Run.from_parquet(out_path)
    bad = [f["check"] for f in run.meta["sanity"]["findings"] if not f["ok"]]
    assert bad == ([] if kind is None else [kind])
    assert ("warning:" in out) == (kind is not None)
    if kind:
        assert f"{csv}: {kind}:" in out


def test_import_csv_fixes_a_flipped_gyro_and_an_imu_offset_on_the_samples(tmp_path, capsys):
    from bench.run import Run

    log = _log(n_steps=12)
    (tmp_path / "map.toml").write_text(CSV_MAP)
    csv = _csv_of(log, tmp_path / "log.csv", "gyro_sign")
    df = pd.read_csv(csv)
    df["ax"] -= 1.1
    df.to_csv(csv, index=False)
    out_path = tmp_path / "run.parquet"
    assert main(["import-csv", str(csv), "--map", str(tmp_path / "map.toml"), "-o", str(out_path),
                 "--fix", "flip_gyro", "--fix", "imu_offset"]) == 0
    run = Run.from_parquet(out_path)
    s = run.meta["sanity"]
    assert sorted(f["check"] for f in s["findings"] if not f["ok"]) == ["gyro_sign", "imu_offset"]
    assert [f["check"] for f in s["after"] if not f["ok"]] == []
    assert s["fixes"][0] == "flip_gyro: imu_gz multiplied by -1"
    # the gyro back to the truth's sign; the accelerometer's -1.1 m/s^2 removed (the synthetic log's own steady
    # mean is the derivative of a constant speed plus zero-mean noise: 0 within the noise over the steady windows)
    off = s["offsets"]
    np.testing.assert_allclose(run.data["imu_gz"].to_numpy() + off["imu_gz"], log["imu_yaw"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.data["imu_ax"].to_numpy() + off["imu_ax"], log["imu_acceleration_x"] - 1.1,
                               rtol=0, atol=1e-12)
    assert off["imu_ax"] == pytest.approx(-1.1, abs=0.02) and abs(off["imu_gz"]) < 0.002


def test_import_csv_refuses_drop_stale_with_one_line(tmp_path, capsys):
    log = _log(n_steps=6)
    (tmp_path / "map.toml").write_text(CSV_MAP)
    csv = _csv_of(log, tmp_path / "log.csv")
    assert main(["import-csv", str(csv), "--map", str(tmp_path / "map.toml"), "-o", str(tmp_path / "r.parquet"),
                 "--fix", "drop_stale"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "drop_stale" in err[0] and "skidbench real" in err[0]
    assert not (tmp_path / "r.parquet").exists()


def test_real_gap_without_the_steady_stage(clean, tmp_path):
    """--no-steady: no steady stage in the JSON or the report, the simulation starts from the nominal model (the
    held-out scoring has no start model); with them, the JSON says what the steady windows gave."""
    docs = {}
    for flag in ([], ["--no-steady"]):
        out = tmp_path / ("gap" + "".join(flag))
        assert main(["real-gap", str(clean[0]), "--platform", str(_platform_toml(tmp_path)), "--out", str(out),
                     "--json", str(tmp_path / "g.json"), "--workers", "1", "--max-effects", "1",
                     "--no-transient", "--validation-steps", "6", *flag]) == 0
        docs[bool(flag)] = (json.loads((tmp_path / "g.json").read_text()), (out / "robot_x-bigbot_gap.md").read_text())
    (on, md_on), (off, md_off) = docs[False], docs[True]
    assert off["command_response"] is None and "Steady command response" not in md_off
    assert off["bounds"]["steady"] is False and on["bounds"]["steady"] is True
    assert "start_mean" not in off["held_out"]["cost"]
    cr = on["command_response"]
    assert cr["n_windows"] > 0 and "Steady command response" in md_on
    # this robot's wheels settle on their command (a first-order lag, no controller map): nothing is adopted, the
    # simulation starts from the nominal model as without the stage
    assert cr["adopted"] == [] and cr["platform_overrides"] == {}
    # its yaw response is the synthetic robot's chi 1.6 (closed form), not the testbed bigbot's ~1.2: the steady
    # turn response measures it and solves the lateral friction for it, so the start model turns as the robot does
    tr = on["turn_response"]
    assert tr["chi"] == pytest.approx(CHI, abs=0.01) and tr["chi_nominal"] < CHI - 0.2
    assert "mu_lat_ratio" in tr["adopted"] and tr["chi_final"] == pytest.approx(CHI, abs=0.02)
    assert off["turn_response"] is None and "Steady turn response" in md_on and "Steady turn response" not in md_off
    assert off["transient_response"] is None and on["transient_response"] is None  # --no-transient
    assert "Transient response" not in md_on + md_off
    assert on["held_out"]["cost"]["start_mean"] < on["held_out"]["cost"]["before_mean"]


def test_the_steady_stage_replaces_a_platforms_own_command_map(clean, tmp_path):
    """A platform TOML with its own command gain and mean clip, on a robot whose wheels settle on their command: the
    steady windows ask for neither, so the model the simulation starts from has them back at neutral (the map the
    windows were fitted with), and the JSON says what was changed."""
    p = _platform_toml(tmp_path)
    text = p.read_text().replace("\n[motor]", "\ncommand_gain_sum = 1.2\ncommand_limit_mean = 3.0\n\n[motor]", 1)
    text = text.replace("\n[sources]\n", '\n[sources]\ncommand_gain_sum = {kind = "testbed", ref = "test"}\n'
                        'command_limit_mean = {kind = "testbed", ref = "test"}\n', 1)
    p.write_text(text)
    assert main(["real-gap", str(clean[0]), "--platform", str(p), "--out", str(tmp_path / "gap"), "--json",
                 str(tmp_path / "g.json"), "--workers", "1", "--max-effects", "1", "--no-transient",
                 "--validation-steps", "6"]) == 0
    cr = json.loads((tmp_path / "g.json").read_text())["command_response"]
    assert cr["adopted"] == [] and cr["applied"] == {"command_gain_sum": 1.0, "command_limit_mean": None}
    assert cr["catalogue_without"] == ["command_map", "command_limit", "wheel_speed_limit"]


@pytest.mark.parametrize("command", ["real", "real-gap"])
def test_an_output_that_cannot_be_written_is_refused_before_the_run(clean, tmp_path, capsys, command):
    """--json under a regular file (no folder can be made there): one line naming the option, before any model is
    fitted or simulated, and --out is not created."""
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    out = tmp_path / "o"
    plat = "husky"
    assert main([command, str(clean[0]), "--platform", plat, "--out", str(out), "--json", str(blocker / "r.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--json" in err and "not a writable folder" in err
    assert not out.exists()
    assert main([command, str(clean[0]), "--platform", plat, "--out", str(blocker / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--out" in err and "not a writable folder" in err
