"""Sanity checks of a real data set before it is scored: defects a log carries that no model should be blamed for.

Each check gives a :class:`Finding` (its evidence in numbers, a warning when the data look wrong, and the correction
``--fix NAME`` applies, when one exists); :func:`check_windows` runs them on :class:`~bench.real.drive.DriveWindows`
and :func:`apply_fixes` returns corrected windows.  The findings go to the report and its JSON (``sanity``).

=====================  ================================================================  =====================
check                  evidence                                                          warning when / fix
=====================  ================================================================  =====================
``gyro_sign``          slope of the window-mean ``imu_gz`` against the reference (ICP)  slope < 0 (``flip_gyro``:
                       yaw rate, least squares through the origin, and their             ``imu_gz`` * -1); |slope|
                       correlation                                                       < 0.5 or r < 0.5: axis?
``imu_offset``         median over steady windows of the mean ``imu_ax``, ``imu_ay``     beyond 0.3 m/s^2 (2 deg
                       (steady: no acceleration), and the intercept of the mean          of tilt) or 0.02 rad/s;
                       ``imu_gz`` against the reference yaw rate (gyro bias)             ``imu_offset`` subtracts
``update_rate``        each measured channel's effective rate: samples that differ      under 40 % of the table's
                       from the one before, over the samples that move (a held         rate (no fix: a held
                       sample repeats the last value; commands are held by design)      sample is no new data)
``stale_reference``    share of windows whose reference pose at the last sample has     over 10 % (windows whose
                       been held longer than the reference's own update interval (the   end is stale: dropped by
                       score compares the end pose)                                      ``drop_stale``)
``command_lag``        median time from a command step's half-way crossing to the      T10 > 1 s or < -0.1 s
                       wheel speed's crossing of 10 % (T10) and 50 % (T50) of the step, (a clock offset between
                       each transitory window joined to the one before it              the streams?); no fix
``clock_offset``       the shift, in samples, that best fits the reference's yaw rate   gyro off by 2 samples or
                       by ``imu_gz`` (and, shown, its forward speed and yaw rate by     more (``align_gyro``)
                       the wheels' mean and difference; :mod:`bench.real.clock`)
``wheel_scale``        slope (least squares through the origin) of the reference's     slope outside 1/3..3
                       path speed (ICP path length over the window, signed as the      (0.105: rpm as rad/s;
                       treads) against the tread speed r (w_l + w_r) / 2, when the     0.017: deg/s; or the
                       wheel radius r is known; and its median over straight windows    radius); no fix
=====================  ================================================================  =====================

Thresholds are physical bounds, not fitted to the Husky table: a 0.3 m/s^2 accelerometer offset is 1.7 deg of
tilt; a gyro following the heading with a slope under 0.5 misses half the rotation; a stream at under 40 % of the
table's rate repeats more samples than it updates (the Husky's wheel speeds and ICP run at half its 20 Hz: reported,
not flagged); the Husky's powertrain answers a step with T10 0.43 s and T50 0.75 s (measured: a slow response is
the robot's, reported, not a defect), while a T10 beyond 1 s (half a DRIVE window) or a wheel speed ahead of its
command are what a clock offset between the streams gives.  A skid-steered body moves slower than its treads in a
turn and never 3 times faster or slower over a whole log (Husky: slope 0.97); wheel speeds logged in rpm read 9.5
times too fast (slope 0.105), in deg/s 57 times (motor-shaft speeds through a 7-13:1 gearbox give rpm's slope: the
message names both).  A rpm log at a Husky's speeds (under 70 rpm) passes the table
reader's 300 rad/s bound, and a kinematic platform TOML gives no motor to bound it by: this check catches it.  A
wheel-speed scale is refused as bad input (:func:`refuse_unit_slips`) when the whole log's slope and the median
ratio of its straight windows (tread difference under 20 % of the tread speed; at least 5, their IQR under half the
median; Husky: 0.99 on 75 windows) both lie within 35 % of one such factor: a log of pivot turns,
whose path speed is ICP noise, has no straight window and only warns, and a log driven at one speed is judged by
its straight windows, not by a correlation it cannot have.  A gyro slope is taken for a unit when gyro and
reference rates correlate at 0.6 or better (Husky 0.99), whatever its sign (a flipped gyro in deg/s is both).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bench.real.drive import DriveWindows
from bench.run import RunError
from bench.spec import SpecError

__all__ = ["Finding", "check_windows", "apply_fixes", "FIXES", "refuse_unit_slips", "scored_windows",
           "RUN_UNIT_COLUMNS"]

GYRO_MIN_SLOPE = 0.5
IMU_MAX_OFFSET = 0.3  # [m/s^2]
GYRO_MAX_BIAS = 0.02  # [rad/s]
MIN_RATE_SHARE = 0.4
MAX_STALE_SHARE = 0.10
MAX_LAG = 1.0  # [s] T10 beyond half a DRIVE window: the transitory window cannot hold the response
MAX_LEAD = 0.1  # [s] wheel speeds ahead of their command: a clock offset the other way
MIN_STEP = 1.0  # [rad/s] command steps smaller than this are not timed
WHEEL_SCALE = (1.0 / 3.0, 3.0)  # reference path speed / tread speed: outside it, a unit or radius error
UNIT_MIN_R = 0.6  # a gyro slope is read as a unit mistake only when gyro and reference correlate this well
STRAIGHT_TURN = 0.2  # a window is straight when its tread difference is under this share of its tread speed
MIN_STRAIGHT, MAX_STRAIGHT_SPREAD = 5, 0.5  # straight windows needed, and their ratios' IQR / median, for a unit
MAX_CLOCK_OFFSET = 2.0  # [samples] 0.1 s at 20 Hz: 5 % of a 2 s window's motion between the gyro and reference
FIXES = ("flip_gyro", "imu_offset", "align_gyro", "drop_stale")


@dataclass(frozen=True)
class Finding:
    check: str
    ok: bool
    evidence: str
    values: dict[str, float]
    fix: str | None = None  # the --fix that corrects it (None: no correction exists)
    unit: str | None = None  # the unit mistake its numbers match ("rpm given as rad/s"): bad input, not a warning

    def line(self) -> str:
        fix = f" (--fix {self.fix} corrects it)" if self.fix and not self.ok else ""
        return f"{'ok' if self.ok else 'WARNING'} {self.check}: {self.evidence}{fix}"


UNIT_SLIPS = {"rpm given as rad/s": 2 * math.pi / 60, "deg/s given as rad/s": math.pi / 180,
              "rev/s given as rad/s": 2 * math.pi}  # reference / channel slope each gives (gyro: its inverse)


def _unit_slip(slope: float) -> str | None:
    """The unit mistake a slope matches within 35 % (|log| < 0.3), else None."""
    if not slope > 0:
        return None
    name, f = min(UNIT_SLIPS.items(), key=lambda kv: abs(math.log(slope / kv[1])))
    return name if abs(math.log(slope / f)) < 0.3 else None


def _ref_rate(w: DriveWindows) -> np.ndarray:
    yaw = w["ref_yaw"]
    return (yaw[:, -1] - yaw[:, 0]) / (w.dt * (w.n_samples - 1))


def _gyro_sign(w: DriveWindows) -> Finding | None:
    if not (w.has("imu_gz") and w.has("ref_yaw")):
        return None
    x, y = _ref_rate(w), np.nanmean(w["imu_gz"], axis=1)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3 or not np.any(x[ok]):
        return None
    x, y = x[ok], y[ok]
    slope = float(x @ y / (x @ x))
    r = float(np.corrcoef(x, y)[0, 1]) if np.std(x) > 0 and np.std(y) > 0 else math.nan
    values = {"slope": slope, "r": r, "n": float(x.size)}
    if abs(slope) > 1.0 / GYRO_MIN_SLOPE:  # the gyro reads more than twice the rotation: a unit (and maybe flipped)
        unit = _unit_slip(1.0 / abs(slope)) if abs(r) >= UNIT_MIN_R else None
        flipped = ", and the sign flipped" if slope < 0 else ""
        return Finding("gyro_sign", False, f"imu_gz reads {slope:.3g} times the reference yaw rate (r {r:.2f}): "
                       + (f"{unit}?" if unit else "the wrong unit?") + flipped, values,
                       "flip_gyro" if slope < 0 else None, unit=unit)
    if slope < 0:
        return Finding("gyro_sign", False, f"imu_gz against the reference yaw rate: slope {slope:.2f}, r {r:.2f} "
                       f"over {x.size} windows: the gyro sign looks flipped", values, "flip_gyro")
    if slope < GYRO_MIN_SLOPE or not (abs(r) >= 0.5):
        return Finding("gyro_sign", False, f"imu_gz hardly follows the reference yaw rate (slope {slope:.2f}, r {r:.2f}): "
                       "the wrong axis or unit?", values)
    return Finding("gyro_sign", True, f"imu_gz follows the reference yaw rate (slope {slope:.2f}, r {r:.2f})", values)


def _imu_offset(w: DriveWindows) -> Finding | None:
    if not w.steady.any():
        return None
    values: dict[str, float] = {}
    parts = []
    for c in ("imu_ax", "imu_ay"):
        if w.has(c):
            values[c] = float(np.nanmedian(np.nanmean(w[c][w.steady], axis=1)))
            parts.append(f"{c} {values[c]:+.2f} m/s^2")
    if w.has("imu_gz") and w.has("ref_yaw"):
        # the intercept of the window-mean gyro against the reference yaw rate (a flipped or scaled gyro is the
        # gyro_sign check's, not a bias)
        g, r = np.nanmean(w["imu_gz"][w.steady], axis=1), _ref_rate(w)[w.steady]
        ok = np.isfinite(g) & np.isfinite(r)
        if ok.sum() >= 3:
            values["imu_gz"] = float(np.polyfit(r[ok], g[ok], 1)[1])
            parts.append(f"gyro bias {values['imu_gz']:+.3f} rad/s")
    if not values:
        return None
    bad = [c for c in ("imu_ax", "imu_ay") if abs(values.get(c, 0.0)) > IMU_MAX_OFFSET]
    bad += ["imu_gz"] if abs(values.get("imu_gz", 0.0)) > GYRO_MAX_BIAS else []
    where = f"median over {int(w.steady.sum())} steady windows (steady: no acceleration): " + ", ".join(parts)
    if bad:
        return Finding("imu_offset", False, f"{where}; offset beyond {IMU_MAX_OFFSET} m/s^2 / {GYRO_MAX_BIAS} rad/s "
                       f"on {', '.join(bad)}", values, "imu_offset")
    return Finding("imu_offset", True, where, values)


def _update_rate(w: DriveWindows) -> Finding:
    rate = 1.0 / w.dt
    values, slow = {}, []
    for c in sorted(w.channels):
        if c.startswith("cmd_"):
            continue  # commands are held for the step by design
        a = np.asarray(w[c], float)
        if a.ndim != 2 or a.shape[1] < 2:
            continue
        d = np.diff(a, axis=1)
        moving = np.isfinite(d)
        # a sample that moves: differs from the one before, or the stream is not at rest (a held non-zero value)
        at_rest = (a[:, 1:] == 0) & (a[:, :-1] == 0)
        n = int((moving & ~at_rest).sum())
        if n == 0:
            continue
        eff = rate * float(((d != 0) & moving & ~at_rest).sum()) / n
        values[c] = eff
        if eff < MIN_RATE_SHARE * rate:
            slow.append(f"{c} {eff:.1f} Hz")
    text = ", ".join(f"{c} {v:.1f} Hz" for c, v in values.items())
    if slow:
        return Finding("update_rate", False, f"effective update rates in a {rate:.0f} Hz table: {', '.join(slow)} "
                       "(held samples: the stream updates slower than the table)", values)
    return Finding("update_rate", True, f"effective update rates: {text}", values)


def _held_samples(a: np.ndarray) -> np.ndarray:
    """Per window: how many samples before the last one repeat its value (0: the last sample is new)."""
    same = a[:, :-1] == a[:, -1:]
    return np.argmin(same[:, ::-1], axis=1) + same.all(axis=1) * same.shape[1]


def _stale(w: DriveWindows, rates: Finding | None = None) -> np.ndarray:
    """Windows whose reference pose at the last sample has been held longer than the reference's own update interval
    (a 10 Hz ICP in a 20 Hz table holds every other sample: that is its rate, not a stale pose)."""
    held = np.minimum(_held_samples(w["ref_x"]), _held_samples(w["ref_y"]))
    rate = (rates or _update_rate(w)).values.get("ref_x", 1.0 / w.dt)
    normal = max(0, int(math.ceil(1.0 / (w.dt * rate) - 1e-9)) - 1)
    return held > normal


def _stale_reference(w: DriveWindows, rates: Finding | None = None) -> Finding | None:
    if not (w.has("ref_x") and w.has("ref_y")) or w.n_samples < 2:
        return None
    stale = _stale(w, rates)
    share = float(stale.mean())
    values = {"share": share, "n": float(stale.sum())}
    text = (f"{int(stale.sum())} of {w.n_windows} windows ({100 * share:.0f} %) end on a reference pose held longer "
            "than the reference's update interval")
    if share > MAX_STALE_SHARE:
        return Finding("stale_reference", False, text + " (the end-pose score compares a stale pose)", values,
                       "drop_stale")
    return Finding("stale_reference", True, text, values)


def _step_crossings(w: DriveWindows, share: float) -> list[float]:
    """Per command step and side: the time from the command's half-way crossing to the wheel speed's crossing of
    ``share`` of the same step, on each transitory window joined to the window before it (the previous step's end)."""
    idx = np.flatnonzero(w.transitory[1:] & (w.calib_step[1:] != w.calib_step[:-1])) + 1
    tail = max(2, w.n_samples // 4)
    lags = []
    for i in idx:
        for cmd, enc in (("cmd_wl", "enc_wl"), ("cmd_wr", "enc_wr")):
            c = np.concatenate([w[cmd][i - 1], w[cmd][i]])
            e = np.concatenate([w[enc][i - 1], w[enc][i]])
            c0, c1 = np.nanmedian(c[:tail]), np.nanmedian(c[-tail:])
            e0 = np.nanmedian(e[w.n_samples - tail: w.n_samples])
            step = c1 - c0
            if not (abs(step) > MIN_STEP and np.isfinite(e0)):
                continue
            k_c = np.flatnonzero(np.abs(c - c0) > abs(step) / 2)
            k_e = np.flatnonzero((e - e0) / step > share)
            if k_c.size and k_e.size:
                lags.append((int(k_e[0]) - int(k_c[0])) * w.dt)
    return lags


def _command_lag(w: DriveWindows) -> Finding | None:
    """T10 and T50 of the wheel speeds after command steps (medians of :func:`_step_crossings`)."""
    if not all(w.has(c) for c in ("cmd_wl", "cmd_wr", "enc_wl", "enc_wr")):
        return None
    t10, t50 = _step_crossings(w, 0.1), _step_crossings(w, 0.5)
    if not t10:
        return None
    values = {"t10_s": float(np.median(t10)), "t50_s": float(np.median(t50)) if t50 else math.nan,
              "n": float(len(t10))}
    text = (f"after a command step the wheel speeds reach 10 % of it in {values['t10_s']:.2f} s and 50 % in "
            f"{values['t50_s']:.2f} s (medians over {len(t10)} steps and sides)")
    if values["t10_s"] > MAX_LAG or values["t10_s"] < -MAX_LEAD:
        why = "ahead of their command" if values["t10_s"] < 0 else f"no response within {MAX_LAG} s"
        return Finding("command_lag", False, f"{text}: {why}, a clock offset between the command and wheel-speed "
                       "streams?", values)
    return Finding("command_lag", True, text, values)


def _clock_offset(w: DriveWindows) -> Finding | None:
    """The input streams' time offsets to the reference (:func:`bench.real.clock.offsets`).  Only the gyro's is judged:
    every model reads the wheel speeds, so their offset moves all rows alike (shown: a held stream is late by half
    its hold, and in a turn the yaw follows the treads through the turn's dynamics), while a gyro offset is paid by
    the models that read the gyro alone."""
    from bench.real.clock import offsets

    values = offsets(w)
    if not values:
        return None
    names = {"imu_gz": "imu_gz", "wheels_forward": "wheels' forward speed", "wheels_turn": "wheels' turn"}
    text = ("best fit to the reference's rate at a shift of " + ", ".join(
        f"{names[k]} {v:+.1f} samples ({1000 * v * w.dt:+.0f} ms)" for k, v in values.items())
        + " (+: the stream is late; the wheels' are shown, not judged)")
    if abs(values.get("imu_gz", 0.0)) >= MAX_CLOCK_OFFSET:
        return Finding("clock_offset", False, f"{text}; the gyro is off by {MAX_CLOCK_OFFSET:g} samples or more: a "
                       "model that reads it is scored against a reference that is early or late for it", values,
                       "align_gyro")
    return Finding("clock_offset", True, text, values)


def _wheel_scale(w: DriveWindows, wheel_radius: float | None) -> Finding | None:
    """The reference's path speed against the tread speed (module docstring): a unit or radius check."""
    if wheel_radius is None or not all(w.has(c) for c in ("enc_wl", "enc_wr", "ref_x", "ref_y")) or w.n_samples < 2:
        return None
    u = wheel_radius * np.nanmean(w["enc_wl"] + w["enc_wr"], axis=1) / 2.0
    path = np.nansum(np.hypot(np.diff(w["ref_x"], axis=1), np.diff(w["ref_y"], axis=1)), axis=1)
    v = np.sign(u) * path / (w.dt * (w.n_samples - 1))
    ok = np.isfinite(u) & np.isfinite(v)
    if ok.sum() < 3 or not np.any(u[ok]):
        return None
    turn = wheel_radius * np.nanmean(np.abs(w["enc_wr"] - w["enc_wl"]), axis=1) / 2.0
    u, v, turn = u[ok], v[ok], turn[ok]
    slope = float(u @ v / (u @ u))
    a, b = np.abs(u), np.abs(v)
    # the straight windows (tread difference under 20 % of the mean tread speed, at a quarter of the log's p90 speed
    # or more): their path speed over tread speed is the scale itself, whatever the log's mix of turns and speeds
    straight = (a >= 0.25 * np.percentile(a, 90)) & (a > 0) & (turn < STRAIGHT_TURN * a)
    q = b[straight] / a[straight]
    q_med = float(np.median(q)) if q.size else math.nan
    q_spread = float(np.subtract(*np.percentile(q, [75, 25])) / q_med) if q.size and q_med > 0 else math.nan
    values = {"slope": slope, "n": float(u.size), "straight_ratio": q_med, "straight_spread": q_spread,
              "n_straight": float(q.size), "wheel_radius": float(wheel_radius)}
    text = (f"reference path speed against the tread speed r (w_l + w_r) / 2 with r = {wheel_radius:g} m: slope "
            f"{slope:.3f} over {u.size} windows, {q_med:.3f} on the {q.size} straight ones")
    lo, hi = WHEEL_SCALE
    if not lo <= slope <= hi:
        # a unit only when the straight windows agree on a scale (not the noise of a log of pivot turns)
        unit = _unit_slip(q_med) if q.size >= MIN_STRAIGHT and q_spread <= MAX_STRAIGHT_SPREAD else None
        unit = unit if unit == _unit_slip(slope) else None  # the whole log's slope names the same unit
        hint = f"{unit} (slope {UNIT_SLIPS[unit]:.3g})?" if unit else "a unit?"
        if unit and unit.startswith("rpm"):  # a gear ratio of 7-13 gives the same slope
            hint = f"{hint} or motor-shaft speeds through a {1 / q_med:.1f}:1 gearbox?"
        return Finding("wheel_scale", False, f"{text}, outside {lo:.2f}..{hi:g}: {hint} or the wheel radius", values,
                       unit=unit)
    return Finding("wheel_scale", True, text, values)


UNIT_COLUMNS = {"wheel_scale": "left_wheel_vel_*, right_wheel_vel_*", "gyro_sign": "imu_yaw_*"}


RUN_UNIT_COLUMNS = {"wheel_scale": "enc_wl, enc_wr", "gyro_sign": "imu_gz"}  # the same, in a Run (imports)


def refuse_unit_slips(findings: Sequence[Finding], where: str, columns: Mapping[str, str] = UNIT_COLUMNS) -> None:
    """A one-line :class:`RunError` for the first finding whose numbers match a unit mistake (its ``unit``): a log in
    rpm or deg/s is bad input, scored it would blame the robot's model for a factor of 9.5 or 57.  ``columns``: the
    data's names of the channels each check reads (a DRIVE table's by default; :data:`RUN_UNIT_COLUMNS` for a Run)."""
    for f in findings:
        if f.unit:
            raise RunError(where, columns.get(f.check, f.check), f"slope {f.values['slope']:.4g}",
                           f"{f.evidence}; convert the column to the wheel's rad/s")


def scored_windows(data_path: str | Path, wheel_radius: float | None) -> tuple[DriveWindows, DriveWindows,
                                                                                list[Finding]]:
    """The windows of a DRIVE table or a continuous Run (``import-bag`` / ``import-csv``), those the real benchmark
    scores (:func:`bench.real.windows.valid_windows`) and their findings; a unit mistake is refused
    (:func:`refuse_unit_slips`).  Used by ``skidbench real`` and ``real-gap``."""
    from bench.real.drive import import_drive_windows
    from bench.real.run_windows import is_run_file, windows_from_run
    from bench.real.windows import valid_windows
    from bench.run import Run

    data_path = Path(data_path)
    if is_run_file(data_path):  # a continuous run (import-bag / import-csv): cut into DRIVE windows
        allw = windows_from_run(Run.from_parquet(data_path), where=str(data_path))
    else:
        allw = import_drive_windows(data_path)
    w = allw.subset(valid_windows(allw))
    findings = check_windows(w, wheel_radius)
    refuse_unit_slips(findings, str(data_path))
    return allw, w, findings


def check_windows(w: DriveWindows, wheel_radius: float | None = None) -> list[Finding]:
    """Every check that the table's channels allow (see the module docstring); ``wheel_radius`` [m] adds the
    ``wheel_scale`` check."""
    rates = _update_rate(w)  # the stale-pose check reads the reference's rate from it
    found = [_gyro_sign(w), _imu_offset(w), rates, _stale_reference(w, rates), _command_lag(w), _clock_offset(w),
             _wheel_scale(w, wheel_radius)]
    return [f for f in found if f is not None]


def refuse_needless_flip(finding: Finding | None, where: str = "--fix") -> None:
    """A one-line error for ``flip_gyro`` on a gyro that follows the reference (flipping it would corrupt it)."""
    if finding is not None and finding.values.get("slope", -1.0) > 0:
        raise SpecError("<command line>", where, "flip_gyro", f"nothing to flip: {finding.evidence}")


def apply_fixes(w: DriveWindows, fixes: Sequence[str], where: str = "--fix",
                measure_on: np.ndarray | None = None) -> tuple[DriveWindows, list[str]]:
    """``w`` with the corrections ``fixes`` (names of :data:`FIXES`) applied in that table's order (the offsets are
    measured after the gyro flip), and a line per correction.  ``measure_on``: the windows (a mask of ``w``) the
    offsets are measured on, e.g. the calibration half's, so that no held-out window shapes a correction; default
    every window."""
    for f in fixes:
        if f not in FIXES:
            raise SpecError("<command line>", where, f, f"expected one of {', '.join(FIXES)}")
    ch: dict[str, Any] = dict(w.channels)
    done = []
    if "flip_gyro" in fixes and "imu_gz" in ch:
        refuse_needless_flip(_gyro_sign(w), where)
        ch["imu_gz"] = -np.asarray(ch["imu_gz"])
        done.append("flip_gyro: imu_gz multiplied by -1")
    out = dataclasses.replace(w, channels=ch)
    offset = None
    if "imu_offset" in fixes:  # measured after the flip
        offset = _imu_offset(out if measure_on is None else out.subset(np.asarray(measure_on, bool)))
    if offset is not None:
        for c, v in offset.values.items():
            ch[c] = np.asarray(ch[c]) - v
            done.append(f"imu_offset: {c} {-v:+.4g}")
        out = dataclasses.replace(w, channels=ch)
    if "align_gyro" in fixes and w.has("imu_gz"):  # measured after the flip and the offset, like them
        from bench.real.clock import offsets, shift_stream

        s = offsets(out if measure_on is None else out.subset(np.asarray(measure_on, bool)), ("imu_gz",)).get("imu_gz")
        if s is None:  # no gyro signal to time against the reference: nothing to shift
            done.append("align_gyro: no offset measured (imu_gz does not follow the reference's yaw rate)")
        else:
            out = shift_stream(out, "imu_gz", s)
            done.append(f"align_gyro: imu_gz read {s:+.1f} samples ({1000 * s * w.dt:+.0f} ms) from its stamp")
    if "drop_stale" in fixes and w.has("ref_x"):
        stale = _stale(out)
        out = out.subset(~stale)
        done.append(f"drop_stale: {int(stale.sum())} windows dropped")
    return out, done
