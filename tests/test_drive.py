"""Tests of bench.real.drive: the DRIVE window-table importer.

Two sources of truth:
* a synthetic DRIVE table cut from a known continuous 20 Hz log by an independent (planar)
  re-implementation of DRIVE's window cutting (dataset_parser.py: frame at the mean of the first
  5 absolute yaws, raw yaw differences, windows starting before the command change, shared
  samples), so the reconstructed Runs can be compared with the log they came from;
* a 20-window slice of the real Husky table (skipped with a message when the data is absent;
  ``SKIDBENCH_DATA`` overrides the data root ``../shared/data``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.real.drive import DRIVE_DT, import_drive, import_drive_windows, main, resolve_platform
from bench.run import RunError
from bench.spec import SpecError, load_platform

N = 40
DATA_ROOT = Path(os.environ.get("SKIDBENCH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
HUSKY = DATA_ROOT / "drive_husky" / "husky_windows.parquet"


# ------------------------------------------------------------------------------------------
# fixtures
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def husky_df() -> pd.DataFrame:
    if not HUSKY.is_file():
        pytest.skip(f"real Husky DRIVE table not found at {HUSKY} (set SKIDBENCH_DATA to the data root)")
    return pd.read_parquet(HUSKY)


@pytest.fixture(scope="session")
def husky_slice(husky_df: pd.DataFrame, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first 20 windows of the real table (6 full steps + the transitory window of a 7th)."""
    path = tmp_path_factory.mktemp("drive") / "husky_slice.parquet"
    husky_df.iloc[:20].to_parquet(path)
    return path


def raw(df: pd.DataFrame, base: str) -> np.ndarray:
    return df[[f"{base}_{k}" for k in range(N)]].to_numpy()


# ------------------------------------------------------------------------------------------
# synthetic DRIVE table
# ------------------------------------------------------------------------------------------
def synthetic_log(n_steps: int = 3, seed: int = 0, pre: int = 5, per_step: int = 120):
    """A continuous 20 Hz log: piecewise-constant body twist per step, exact SE(2) poses, yaw
    starting just below pi so that it crosses +-pi within the first window's first 5 rows."""
    rng = np.random.default_rng(seed)
    n = pre + n_steps * per_step + 5
    step_of_row = np.clip((np.arange(n) - pre) // per_step, 0, n_steps - 1)
    twists = np.array([[0.6, 0.05, 0.5], [0.4, -0.02, -0.8], [0.8, 0.0, 0.3]])[:n_steps]
    tw = twists[step_of_row]
    x, y, yaw = np.zeros(n), np.zeros(n), np.zeros(n)
    yaw[0] = np.pi - 0.16  # crosses +pi at row ~6.4, inside the first window's rows 4..8
    for i in range(n - 1):  # exact constant-twist motion over one row (independent closed form)
        u, v, w = tw[i] * DRIVE_DT
        dx = (np.sin(w) * u - (1 - np.cos(w)) * v) / w
        dy = ((1 - np.cos(w)) * u + np.sin(w) * v) / w
        c, s = np.cos(yaw[i]), np.sin(yaw[i])
        x[i + 1], y[i + 1], yaw[i + 1] = x[i] + c * dx - s * dy, y[i] + s * dx + c * dy, yaw[i] + w
    cmd = rng.uniform(-6, 6, size=(n_steps, 2))[step_of_row]
    log = {
        "x": x, "y": y, "yaw": yaw, "label": step_of_row,
        "cmd_left": cmd[:, 0], "cmd_right": cmd[:, 1],
        "left_wheel_vel": cmd[:, 0] + rng.normal(0, 0.1, n), "right_wheel_vel": cmd[:, 1] + rng.normal(0, 0.1, n),
        "imu_acceleration_x": rng.normal(0, 1, n), "imu_acceleration_y": rng.normal(0, 1, n),
        "imu_acceleration_z": 9.81 + rng.normal(0, 1, n), "imu_yaw": tw[:, 2] + rng.normal(0, 0.01, n),
    }
    return log, pre, per_step


def drive_cut(log: dict, starts: list[tuple[int, int, bool]]) -> pd.DataFrame:
    """DRIVE's window construction (planar): one row per (start row, step, transitory)."""
    rows = []
    for s, _, trans in starts:
        r = np.arange(s, s + N)
        wrapped = (log["yaw"] + np.pi) % (2 * np.pi) - np.pi  # ICP reports wrapped angles
        frame = np.mean(wrapped[s:s + 5])  # mean of raw angles, as DRIVE does (even across +-pi)
        c, sn = np.cos(frame), np.sin(frame)
        dx, dy = log["x"][r] - log["x"][s], log["y"][r] - log["y"][s]
        row = {"init_icp_x": 0.0, "calib_step": float(log["label"][s]),
               "steady_state_mask": float(not trans), "transitory_state_mask": float(trans)}
        for k in range(N):
            row[f"icp_x_{k}"] = c * dx[k] + sn * dy[k]
            row[f"icp_y_{k}"] = -sn * dx[k] + c * dy[k]
            row[f"icp_yaw_{k}"] = wrapped[r[k]] - wrapped[s]
            for b in ("cmd_left", "cmd_right", "left_wheel_vel", "right_wheel_vel", "imu_acceleration_x",
                      "imu_acceleration_y", "imu_acceleration_z", "imu_yaw"):
                row[f"{b}_{k}"] = log[b][r[k]]
        rows.append(row)
    return pd.DataFrame(rows)


def synthetic_table(tmp_path: Path, n_steps: int = 3) -> tuple[Path, dict, list[tuple[int, int, bool]]]:
    log, pre, per = synthetic_log(n_steps)
    starts = []
    for k in range(n_steps):
        s0 = pre + k * per
        t0 = s0 - 1  # transitory window starts one row before the command change
        shared = 1 if k != 1 else 2  # S1 -> S2 boundary shares 1 or 2 rows; T -> S1 is consecutive
        starts += [(t0, k, True), (t0 + N, k, False), (t0 + 2 * N - shared, k, False)]
    path = tmp_path / "synthetic_drive.parquet"
    drive_cut(log, starts).to_parquet(path)
    return path, log, starts


@pytest.fixture(scope="session")
def synth(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, list[tuple[int, int, bool]]]:
    return synthetic_table(tmp_path_factory.mktemp("synthetic"))


# ------------------------------------------------------------------------------------------
# synthetic: reconstruction against the log it was cut from
# ------------------------------------------------------------------------------------------
def test_synthetic_steps_are_regrouped_and_labels_repaired(synth: tuple) -> None:
    path, log, starts = synth
    w = import_drive_windows(path)
    # windows of steps 1 and 2 start one row early: DRIVE labels their transitory window k-1
    assert w.calib_step_label.tolist() == [0, 0, 0, 0, 1, 1, 1, 2, 2]
    assert w.calib_step.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    assert w.window.tolist() == [0, 1, 2] * 3
    assert w.overlap.tolist()[1:] == [0, 1, 0, 0, 2, 0, 0, 1]  # first row has no predecessor


def test_step_cut_to_its_relabelled_transitory_window(synth: tuple, tmp_path: Path) -> None:
    """A table ending with a transitory window labelled with the previous step (it started before
    the command change) yields a separate, one-window step with the next id."""
    path, _, _ = synth
    p = tmp_path / "cut.parquet"
    pd.read_parquet(path).iloc[:7].to_parquet(p)
    w = import_drive_windows(p)
    assert w.calib_step_label.tolist() == [0, 0, 0, 0, 1, 1, 1]
    assert w.calib_step.tolist() == [0, 0, 0, 1, 1, 1, 2]
    assert [r.meta["n_windows"] for r in import_drive(p, "husky")] == [3, 3, 1]


def test_synthetic_runs_reproduce_the_log(synth: tuple) -> None:
    """Time, channels and the chained ICP reference equal the original log, in the first window's
    DRIVE frame, also through a +-pi crossing inside DRIVE's 5-sample frame average."""
    path, log, starts = synth
    runs = import_drive(path, "husky")
    assert [r.meta["calib_step"] for r in runs] == [0, 1, 2]
    wrapped = (log["yaw"] + np.pi) % (2 * np.pi) - np.pi
    for run, k in zip(runs, range(3)):
        s = starts[3 * k][0]
        rows = s + np.arange(len(run.data))
        # consecutive T -> S1, shared rows S1 -> S2 kept once: the Run is rows s, s+1, ... of the log
        assert len(run.data) == 3 * N - (2 if k == 1 else 1)
        np.testing.assert_allclose(run.t, DRIVE_DT * np.arange(len(rows)), atol=0)
        np.testing.assert_array_equal(run["imu_ax"], log["imu_acceleration_x"][rows])
        np.testing.assert_array_equal(run["enc_wl"], log["left_wheel_vel"][rows])
        np.testing.assert_array_equal(run["imu_gz"], log["imu_yaw"][rows])
        frame = np.mean(wrapped[s:s + 5])
        c, sn = np.cos(frame), np.sin(frame)
        dx, dy = log["x"][rows] - log["x"][s], log["y"][rows] - log["y"][s]
        np.testing.assert_allclose(run["ref_x"], c * dx + sn * dy, atol=1e-9)
        np.testing.assert_allclose(run["ref_y"], -sn * dx + c * dy, atol=1e-9)
        d = run["ref_yaw"] - (log["yaw"][rows] - frame)
        np.testing.assert_allclose(np.angle(np.exp(1j * d)), 0.0, atol=1e-9)
        assert np.ptp(d) < 1e-9  # continuous heading, no 2 pi jumps
        assert run.data["window"].tolist() == [0] * N + [1] * N + [2] * (N - (2 if k == 1 else 1))
        assert set(run.data["transitory"][run.data["window"] == 0]) == {1.0}
        assert set(run.data["steady"][run.data["window"] > 0]) == {1.0}


def test_synthetic_first_window_frame_straddles_pi(synth: tuple) -> None:
    """The synthetic case is the hard one: DRIVE's frame mean is taken across the +-pi jump."""
    path, log, starts = synth
    wrapped = (log["yaw"] + np.pi) % (2 * np.pi) - np.pi
    s = starts[0][0]
    assert np.ptp(wrapped[s:s + 5]) > np.pi  # precondition of the test above
    w = import_drive_windows(path)
    # heading at the window start, in DRIVE's window frame, is the true yaw minus the (odd) frame yaw
    d = w["ref_yaw"][0, 0] - (log["yaw"][s] - np.mean(wrapped[s:s + 5]))
    assert abs(np.angle(np.exp(1j * d))) < 1e-12


# ------------------------------------------------------------------------------------------
# real data slice
# ------------------------------------------------------------------------------------------
def test_husky_slice_runs(husky_df: pd.DataFrame, husky_slice: Path) -> None:
    df = husky_df.iloc[:20]
    runs = import_drive(husky_slice, "husky")
    cols = {"t", "cmd_wl", "cmd_wr", "enc_wl", "enc_wr", "ref_x", "ref_y", "ref_yaw", "imu_ax", "imu_ay",
            "imu_az", "imu_gz", "calib_step", "calib_step_label", "window", "window_sample", "steady", "transitory"}
    assert all(set(r.data.columns) == cols for r in runs)
    assert all(r.meta["platform"]["track"] == 0.55 and r.meta["platform"]["wheel_radius"] == 0.165 for r in runs)
    # steps: a transitory window followed by its steady windows (independent of the importer)
    trans = df["transitory_state_mask"].to_numpy() == 1
    assert len(runs) == trans.sum()
    assert sum(r.meta["n_windows"] for r in runs) == 20
    # shared samples, computed here from the raw sensor vectors of adjacent windows (IMU alone is not
    # enough: the logger sometimes repeats a held IMU sample while the wheel speeds change)
    imu = np.stack([raw(df, b) for b in ("imu_acceleration_x", "imu_acceleration_y", "imu_acceleration_z",
                                         "imu_yaw", "left_wheel_vel", "right_wheel_vel", "cmd_left",
                                         "cmd_right")], -1)
    new_step = np.r_[True, trans[1:]]
    total = 0
    for i in range(20):
        o = 0
        if not new_step[i]:
            for k in (1, 2, 3):
                if np.array_equal(imu[i - 1, N - k:], imu[i, :k]):
                    o = k
        total += N - o
    assert sum(len(r.data) for r in runs) == total
    row = 0
    for r in runs:
        r.validate()
        assert np.all(np.diff(r.t) > 0)
        np.testing.assert_allclose(np.diff(r.t), DRIVE_DT)
        for wi in range(r.meta["n_windows"]):
            sel = r.data["window"].to_numpy() == wi
            k = r.data["window_sample"].to_numpy()[sel].astype(int)
            for base, ch in (("left_wheel_vel", "enc_wl"), ("cmd_right", "cmd_wr"), ("imu_acceleration_y", "imu_ay"),
                             ("imu_yaw", "imu_gz")):
                np.testing.assert_array_equal(r[ch][sel], raw(df, base)[row, k])
            assert set(r.data["steady"][sel]) == {float(df["steady_state_mask"].iloc[row])}
            assert set(r.data["calib_step_label"][sel]) == {float(df["calib_step"].iloc[row])}
            row += 1
        # the step id is the majority label of its windows; the command is one step's command
        labels = df["calib_step"].to_numpy()[row - r.meta["n_windows"]:row]
        vals, counts = np.unique(labels, return_counts=True)
        if r.meta["n_windows"] == 3:
            assert r.meta["calib_step"] == vals[np.argmax(counts)]
        modal = [pd.Series(raw(df, "cmd_left")[j]).mode().iloc[0] for j in range(row - r.meta["n_windows"], row)]
        assert len(set(modal)) == 1


def test_husky_slice_has_relabelled_window_and_yaw_wrap(husky_df: pd.DataFrame, husky_slice: Path) -> None:
    """The slice exercises the two repairs: a transitory window labelled with the previous step,
    and an ICP heading crossing +-pi (a 2 pi jump in the raw icp_yaw) which the import unwraps."""
    df = husky_df.iloc[:20]
    w = import_drive_windows(husky_slice)
    relabelled = np.flatnonzero(w.calib_step != w.calib_step_label)
    assert relabelled.size >= 1
    assert np.all(w.transitory[relabelled]) and np.all(w.calib_step_label[relabelled] == w.calib_step[relabelled] - 1)
    jumps = np.abs(np.diff(raw(df, "icp_yaw"), axis=1)).max(axis=1) > np.pi
    assert jumps.any()
    assert np.abs(np.diff(w["ref_yaw"], axis=1)).max() < 1.0  # no sample-to-sample jump after unwrapping
    m = raw(df, "icp_yaw")[:, :5].mean(axis=1)
    np.testing.assert_allclose(np.angle(np.exp(1j * (w["ref_yaw"][:, 0] + m))), 0.0, atol=1e-12)


def test_imu_yaw_is_a_rate(husky_df: pd.DataFrame) -> None:
    """Evidence for mapping imu_yaw to imu_gz: its window mean tracks the ICP yaw rate (slope ~1),
    while its change over a window does not track the ICP yaw change (it is not an angle)."""
    yaw = np.unwrap(raw(husky_df, "icp_yaw"), axis=1)
    rate = (yaw[:, -1] - yaw[:, 0]) / (DRIVE_DT * (N - 1))
    g = raw(husky_df, "imu_yaw")
    assert np.corrcoef(g[:, :-1].mean(axis=1), rate)[0, 1] > 0.95
    assert 0.9 < np.polyfit(rate, g[:, :-1].mean(axis=1), 1)[0] < 1.1
    assert abs(np.corrcoef(g[:, -1] - g[:, 0], yaw[:, -1] - yaw[:, 0])[0, 1]) < 0.3


# ------------------------------------------------------------------------------------------
# platform from the command line
# ------------------------------------------------------------------------------------------
def test_platform_from_command_line(synth: tuple, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, _, _ = synth
    runs = import_drive(path, None, wheel_radius=0.3, track=1.2)  # another robot: no Husky constant
    assert runs[0].meta["platform"] == {"name": "unspecified", "wheel_radius": 0.3, "track": 1.2}
    over = import_drive(path, "husky", track=0.6)[0].meta["platform"]
    assert over["track"] == 0.6 and over["wheel_radius"] == load_platform("husky").wheel_radius
    assert main([str(path), "--wheel-radius", "0.3", "--track", "1.2", "--out", str(tmp_path / "runs")]) == 0
    assert "9 windows, 3 steps" in capsys.readouterr().out
    assert len(list((tmp_path / "runs").glob("step*.parquet"))) == 3
    with pytest.raises(SpecError, match="wheel_radius and track"):
        resolve_platform(None, wheel_radius=0.3)
    with pytest.raises(SpecError, match="track"):
        resolve_platform("husky", track=-1.0)


def test_husky_platform_spec() -> None:
    p = load_platform("husky")
    assert (p.wheel_radius, p.track, p.wheelbase) == (0.165, 0.55, 0.512)
    assert 45 <= p.mass <= 55 and p.sensors.reference.kind == "icp"


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("column", ["icp_yaw_17", "left_wheel_vel_39", "steady_state_mask", "calib_step"])
def test_missing_column_names_file_and_column(synth: tuple, tmp_path: Path, column: str) -> None:
    path, _, _ = synth
    df = pd.read_parquet(path).drop(columns=[column])
    bad = tmp_path / "bad.parquet"
    df.to_parquet(bad)
    with pytest.raises(RunError) as err:
        import_drive(bad, "husky")
    assert err.value.column == column and str(bad) in str(err.value)


def test_bad_values(synth: tuple, tmp_path: Path) -> None:
    path, _, _ = synth
    df = pd.read_parquet(path)
    for col, val, match in (("calib_step", np.nan, "structural"), ("right_wheel_vel_3", np.inf, "inf"),
                            ("transitory_state_mask", 0.5, "0 or 1")):
        bad = df.copy()
        bad.loc[1, col] = val
        p = tmp_path / f"bad_{col}.parquet"
        bad.to_parquet(p)
        with pytest.raises(RunError, match=match) as err:
            import_drive_windows(p)
        assert err.value.column == col
    with pytest.raises(RunError, match="file not found"):
        import_drive_windows(tmp_path / "nope.parquet")


def test_nan_sample_is_kept_as_missing(synth: tuple, tmp_path: Path) -> None:
    path, log, starts = synth
    df = pd.read_parquet(path)
    df.loc[4, "left_wheel_vel_7"] = np.nan
    df.loc[4, "icp_yaw_9"] = np.nan
    p = tmp_path / "nan.parquet"
    df.to_parquet(p)
    w = import_drive_windows(p)
    assert np.isnan(w["enc_wl"][4, 7]) and np.isnan(w["ref_yaw"][4, 9])
    assert np.isfinite(w["ref_yaw"][4, 10:]).all()  # a NaN does not break the unwrap of later samples
    run = import_drive(p, "husky")[1]
    sel = (run.data["window"] == 1).to_numpy()
    assert np.isnan(run["enc_wl"][sel][7]) and np.isfinite(np.delete(run["enc_wl"], np.flatnonzero(sel)[7])).all()
