"""bench.real.clock: the time offsets of a window table's streams against its reference, and the gyro's alignment.

Independent expectation: a continuous synthetic log (a smooth random yaw rate and forward speed, the pose their
exact integral) whose gyro and wheel speeds are sampled a known delay off the reference's clock, with the reference
held at half the table's rate as the Husky's ICP is; cut into 2 s windows that share samples at some boundaries, as
DRIVE's walk over jittered stamps does.  The offset found must be the delay put in (within the half-sample grid);
reading the gyro at the found shift must give the samples of the undelayed gyro.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.real.clock import offsets, shift_stream, stream_offset
from bench.real.drive import DRIVE_DT, DriveWindows
from bench.real.sanity import MAX_CLOCK_OFFSET, apply_fixes, check_windows

M = 40  # samples per window


def _smooth(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    """A random signal with steps every 2 s filtered by a 0.3 s first-order lag (a DRIVE-like command response)."""
    steps = np.repeat(rng.uniform(-scale, scale, n // M + 1), M)[:n]
    out, a = np.empty(n), DRIVE_DT / 0.3
    acc = 0.0
    for i, v in enumerate(steps):
        acc += a * (v - acc)
        out[i] = acc
    return out


def _log(delay_gz: float, delay_wheels: float, seed: int = 3, n_windows: int = 120, fine: int = 10
         ) -> tuple[DriveWindows, np.ndarray]:
    """Windows of a continuous log; the gyro reads the yaw rate ``delay_gz`` samples late (negative: early), the
    wheels the forward speed ``delay_wheels`` samples late.  Also returns the undelayed gyro per window."""
    rng = np.random.default_rng(seed)
    pad = 20
    n = (n_windows * M + 2 * pad) * fine  # a fine grid: the pose is the exact integral of the rates
    dt = DRIVE_DT / fine
    wz, v = _smooth(rng, n // fine, 0.8), _smooth(rng, n // fine, 1.0)
    t_coarse = DRIVE_DT * np.arange(n // fine)
    t = dt * np.arange(n)
    wz_f, v_f = np.interp(t, t_coarse, wz), np.interp(t, t_coarse, v)
    yaw = np.concatenate(([0.0], np.cumsum(wz_f[:-1] * dt)))
    x = np.concatenate(([0.0], np.cumsum(v_f[:-1] * np.cos(yaw[:-1]) * dt)))
    y = np.concatenate(([0.0], np.cumsum(v_f[:-1] * np.sin(yaw[:-1]) * dt)))
    k = np.arange(pad, pad + n_windows * M)
    tk = DRIVE_DT * k
    held = (k // 2) * 2  # the reference updates at 10 Hz: held over every other sample
    ref = {c: np.interp(DRIVE_DT * held, t, a) for c, a in (("ref_x", x), ("ref_y", y), ("ref_yaw", yaw))}
    # a rate "at sample k" is the mean over [t_k, t_k+1] (the interval the benchmark holds it over)
    rate = lambda a, d: np.interp(tk + DRIVE_DT * (0.5 - d), t, a)  # noqa: E731
    gz, gz0, wheels = rate(wz_f, delay_gz), rate(wz_f, 0.0), rate(v_f, delay_wheels) / 0.165
    # consecutive windows; every 7th shares its first sample with the previous window's last
    starts, s = [], 0
    for i in range(n_windows - 2):
        starts.append(s)
        s += M - (1 if i % 7 == 6 else 0)
    idx = np.array(starts)[:, None] + np.arange(M)
    overlap = np.r_[0, [(1 if i % 7 == 6 else 0) for i in range(len(starts) - 1)]]
    ch = {"enc_wl": wheels[idx], "enc_wr": wheels[idx], "imu_gz": gz[idx], **{c: a[idx] for c, a in ref.items()}}
    nw = idx.shape[0]
    w = DriveWindows(source="<synthetic>", dt=DRIVE_DT, channels=ch, calib_step=np.arange(nw) // 3,
                     calib_step_label=np.arange(nw) // 3, window=np.arange(nw) % 3, steady=np.arange(nw) % 3 > 0,
                     transitory=np.arange(nw) % 3 == 0, overlap=overlap, frame_yaw=np.zeros(nw), row=np.arange(nw))
    return w, gz0[idx]


HOLD = 0.5  # [samples] the reference held over every other sample is itself late by half a sample on average


@pytest.mark.parametrize("delay", [-3.5, -2.0, 0.0, 1.5, 3.0])
def test_the_offset_found_is_the_delay_put_in(delay: float) -> None:
    """Against the reference as the table holds it (late by HOLD): the delay less HOLD, to the half-sample grid."""
    w, _ = _log(delay, -delay / 2)
    got = offsets(w)
    assert got["imu_gz"] == pytest.approx(delay - HOLD, abs=0.25)
    assert got["wheels_forward"] == pytest.approx(-delay / 2 - HOLD, abs=0.5)


def test_a_stream_without_the_reference_motion_has_no_offset() -> None:
    w, _ = _log(0.0, 0.0)
    flat = dataclasses.replace(w, channels={**w.channels, "imu_gz": np.zeros_like(w["imu_gz"])})
    shift, rss = stream_offset(np.diff(w["ref_yaw"], axis=1) / w.dt, flat["imu_gz"])
    assert np.isnan(shift) and np.isnan(rss).all()


def test_shifting_the_gyro_by_its_offset_gives_the_undelayed_samples_across_window_ends() -> None:
    delay = -3.0  # early: the shift reads samples before each window's start, from the previous block of the log
    w, gz0 = _log(delay, 0.0)
    out = shift_stream(w, "imu_gz", delay)  # sample k read at k + delay: the undelayed gyro's sample k
    # every window whose previous row is its adjacent block: exact (an integer shift reads samples, no interpolation),
    # the first samples from the previous window (minus the sample they share, where they share one)
    np.testing.assert_allclose(out["imu_gz"][1:], gz0[1:], atol=1e-12)
    # the first window has no previous block: its first samples hold the window's first sample
    np.testing.assert_allclose(out["imu_gz"][0, :3], w["imu_gz"][0, 0], atol=1e-12)
    np.testing.assert_allclose(out["imu_gz"][0, 3:], gz0[0, 3:], atol=1e-12)
    # a half-sample shift interpolates between neighbours
    half = shift_stream(w, "imu_gz", 0.5)["imu_gz"]
    np.testing.assert_allclose(half[5, :-1], (w["imu_gz"][5, :-1] + w["imu_gz"][5, 1:]) / 2, atol=1e-12)
    # rows that are not adjacent blocks of the log hold the end sample instead of borrowing
    apart = dataclasses.replace(w, row=2 * np.arange(w.n_windows))
    np.testing.assert_allclose(shift_stream(apart, "imu_gz", -2.0)["imu_gz"][4, :2], w["imu_gz"][4, 0], atol=1e-12)
    assert set(out.channels) == set(w.channels)
    assert all(out[c] is w[c] for c in w.channels if c != "imu_gz")


def test_the_check_flags_an_offset_of_two_samples_and_the_fix_removes_it() -> None:
    for delay, flagged in ((-1.0, False), (HOLD - MAX_CLOCK_OFFSET, True), (-3.5, True), (3.0, True)):
        w, _ = _log(delay, 0.0)
        f = next(f for f in check_windows(w) if f.check == "clock_offset")
        assert f.ok is not flagged and (f.fix == "align_gyro") is flagged, (delay, f)
        assert f.values["imu_gz"] == pytest.approx(delay - HOLD, abs=0.25)
        fixed, lines = apply_fixes(w, ["align_gyro"])
        assert lines and lines[0].startswith("align_gyro: imu_gz read")
        assert abs(offsets(fixed)["imu_gz"]) <= 0.5
    # measured on the windows it is told (e.g. the calibration half): the same shift for all windows
    w, _ = _log(-3.0, 0.0)
    half = np.arange(w.n_windows) < w.n_windows // 2
    fixed, lines = apply_fixes(w, ["align_gyro"], measure_on=half)
    assert f"{-3.0 - HOLD:+.1f} samples" in lines[0]


def test_the_fix_is_measured_on_the_windows_it_is_told():
    """The same motion (same seed) with the gyro 3 samples early in the first half and 1 in the second: measured on
    the first half (the benchmark's calibration half) the shift is the first half's, on the second the second's."""
    early, _ = _log(-3.0, 0.0)
    late, _ = _log(-1.0, 0.0)
    half = np.arange(early.n_windows) < early.n_windows // 2
    gz = np.where(half[:, None], early["imu_gz"], late["imu_gz"])
    w = dataclasses.replace(early, channels={**early.channels, "imu_gz": gz})
    assert apply_fixes(w, ["align_gyro"], measure_on=half)[1] == [f"align_gyro: imu_gz read {-3.0 - HOLD:+.1f} samples "
                                                                  f"({1000 * (-3.0 - HOLD) * w.dt:+.0f} ms) from its stamp"]
    assert f"{-1.0 - HOLD:+.1f} samples" in apply_fixes(w, ["align_gyro"], measure_on=~half)[1][0]


def test_a_gyro_without_signal_has_no_offset_and_the_fix_says_so():
    """A gyro reading zeros: no offset is measured (the check does not print nan), and --fix align_gyro shifts
    nothing and says why instead of failing."""
    w, _ = _log(-3.0, 0.0)
    flat = dataclasses.replace(w, channels={**w.channels, "imu_gz": np.zeros_like(w["imu_gz"])})
    assert "imu_gz" not in offsets(flat)
    f = next(f for f in check_windows(flat) if f.check == "clock_offset")
    assert f.ok and "nan" not in f.evidence and "imu_gz" not in f.values
    fixed, lines = apply_fixes(flat, ["align_gyro"])
    assert lines == ["align_gyro: no offset measured (imu_gz does not follow the reference's yaw rate)"]
    np.testing.assert_array_equal(fixed["imu_gz"], flat["imu_gz"])
    with pytest.raises(ValueError, match="finite"):
        shift_stream(w, "imu_gz", float("nan"))


def test_windows_cut_from_a_run_borrow_samples_only_across_a_real_boundary():
    """A continuous run cut into windows drops samples between some of them (the samples at rest before the first
    command step form a window with 5 samples left over): those windows' rows are not consecutive, so the gyro's
    shift holds the window's end sample there instead of reading the next window's, which is later in time."""
    from bench.real.run_windows import windows_from_run
    from tests.test_real_cli import _log as drive_log, _run_of

    w = windows_from_run(_run_of(drive_log(n_steps=6)))
    assert w.row[1] - w.row[0] == 2 and np.all(np.diff(w.row[1:]) == 1)
    out = shift_stream(w, "imu_gz", 3.0)["imu_gz"]
    np.testing.assert_allclose(out[0, -3:], w["imu_gz"][0, -1], atol=1e-12)  # no neighbour after the gap: held
    np.testing.assert_allclose(out[1, -3:], w["imu_gz"][2, :3], atol=1e-12)  # the next window follows: borrowed
