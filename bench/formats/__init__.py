"""Log import/export: TUM trajectories, CSV logs and ROS 1/ROS 2 bags -> :class:`bench.run.Run`.

* TUM (``timestamp tx ty tz qx qy qz qw``, one pose a line, ``#`` comments; the format of the
  TUM RGB-D benchmark, read by evo): :func:`write_tum`, :func:`read_tum`, :func:`run_to_tum`.
  Numbers are written as Python's repr (shortest exact text), so a float64 round-trips exactly.
* CSV and bags: :func:`import_csv`, :func:`import_bag`.  A *mapping* TOML file
  (:class:`ImportMapping`, see :func:`load_mapping`) names, per Run channel group, the CSV
  columns or the bag topic and the units the log uses; values are converted to SI at this
  boundary (rpm -> rad/s, m/s tread speed -> rad/s with the wheel radius, deg -> rad, g ->
  m/s^2, ms -> s, ...).  Example::

      run_id = "field_test_3"
      [time]
      column = "stamp"            # CSV; bags use header stamps (source = "header" | "receive")
      unit = "ms"
      [platform]
      name = "p3at_pneumatic_20psi"   # scenarios/platforms/<name>.toml: geometry + plausibility
      [wheels]                    # -> enc_wl, enc_wr   ([commands] -> cmd_wl, cmd_wr)
      left = "wl"                 # CSV columns
      right = "wr"
      topic = "/joint_states"     # bags: sensor_msgs/JointState velocities, averaged per side
      left_joints = ["front_left_wheel", "rear_left_wheel"]
      right_joints = ["front_right_wheel", "rear_right_wheel"]
      unit = "rpm"                # rad/s | rpm | deg/s | m/s (tread speed; needs wheel_radius)
      [imu]                       # -> imu_ax..az, imu_gx..gz (sensor_msgs/Imu on bags)
      topic = "/imu/data"
      gyro_unit = "rad/s"         # or deg/s ; accel_unit = "m/s^2" or "g"
      [gnss]                      # -> gnss_x, gnss_y, gnss_yaw, gnss_vx, gnss_vy (world frame)
      topic = "/gnss/odom"        # nav_msgs/Odometry | geometry_msgs/PoseStamped
      [reference]                 # -> ref_x, ref_y, ref_yaw
      [truth]                     # -> truth_x, truth_y, truth_yaw (+ truth_vx, vy, wz: body frame)

  Bags are read with ``rosbags`` (``rosbags.highlevel.AnyReader``: ROS 1 ``.bag`` files and
  ROS 2 bag directories, no ROS install).  Rows of the Run are the union of all sample
  timestamps (no resampling: a channel is NaN where its sensor has no sample), starting at
  t = 0; the absolute time of the first row is ``meta["time_origin_ns"]``.

Every problem raises :class:`bench.run.RunError` (data) or :class:`bench.spec.SpecError`
(mapping) naming the file, the column/topic/field, the value and what was expected.

:func:`check_plausible` rejects implausible magnitudes given the platform (wheel speeds beyond
the motor's no-load speed -- typically rpm given as rad/s --, gyro rates beyond the fastest
possible turn -- deg/s as rad/s --, an accelerometer reading ~1 at rest -- g as m/s^2).
"""
from __future__ import annotations

import math
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd

from bench.metrics import Trajectory
from bench.report.io import atomic_write_text
from bench.run import Run, RunError, from_arrays
from bench.spec import Platform, SpecError, build, load_platform, to_dict

__all__ = [
    "write_tum", "read_tum", "run_to_tum", "TimeMap", "WheelMap", "ImuMap", "PoseMap",
    "PlatformMap", "ImportMapping", "load_mapping", "import_csv", "import_bag", "check_plausible",
    "max_wheel_speed", "max_yaw_rate",
]

G0 = 9.80665

# ------------------------------------------------------------------------------------------
# TUM
# ------------------------------------------------------------------------------------------
TUM_HEADER = "# timestamp tx ty tz qx qy qz qw"


_atomic_write_text = atomic_write_text  # one implementation: bench.report.io


def _tum_text(t: np.ndarray, xyz: np.ndarray, quat_xyzw: np.ndarray) -> str:
    mat = np.column_stack([t, xyz, quat_xyzw])
    fmt = " ".join(["%r"] * 8)  # repr: shortest text that round-trips a float64 exactly
    body = "\n".join(fmt % tuple(row) for row in mat.tolist())
    return f"{TUM_HEADER}\n{body}\n" if body else f"{TUM_HEADER}\n"


def write_tum(path: str | Path, t: Any, x: Any, y: Any, yaw: Any, z: Any = 0.0) -> Path:
    """Write a planar trajectory as TUM text (quaternion of a rotation ``yaw`` about z)."""
    t = np.asarray(t, float).reshape(-1)
    cols = {"x": x, "y": y, "yaw": yaw, "z": z}
    arr = {k: np.broadcast_to(np.asarray(v, float), t.shape) for k, v in cols.items()}
    for name, v in (("t", t), *arr.items()):
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise RunError(str(path), name, f"row {i}: {v[i]}", "TUM export needs finite values")
    half = 0.5 * arr["yaw"]
    quat = np.column_stack([np.zeros_like(t), np.zeros_like(t), np.sin(half), np.cos(half)])
    xyz = np.column_stack([arr["x"], arr["y"], arr["z"]])
    return _atomic_write_text(Path(path), _tum_text(t, xyz, quat))


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM file into a :class:`bench.metrics.Trajectory` (general 3-D rotations)."""
    from scipy.spatial.transform import Rotation

    path = Path(path)
    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    try:
        mat = np.loadtxt(path, comments="#", ndmin=2, dtype=float)
    except ValueError as exc:
        raise RunError(str(path), "<file>", str(exc).splitlines()[0].split(";")[0],
                       "TUM rows must be 8 numbers: timestamp tx ty tz qx qy qz qw") from None
    if mat.size == 0:
        raise RunError(str(path), "<file>", "empty", "a TUM file needs at least one pose")
    if mat.shape[1] != 8:
        raise RunError(str(path), "<file>", f"{mat.shape[1]} columns",
                       "TUM rows must be 8 numbers: timestamp tx ty tz qx qy qz qw")
    bad = ~np.isfinite(mat)
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        names = ("timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
        raise RunError(str(path), names[c], f"pose {r}: {mat[r, c]}", "must be finite")
    qn = np.linalg.norm(mat[:, 4:], axis=1)
    off = np.abs(qn - 1.0) > 1e-6
    if off.any():
        r = int(np.flatnonzero(off)[0])
        raise RunError(str(path), "qx qy qz qw", f"pose {r}: norm {qn[r]}", "a unit quaternion")
    rot = Rotation.from_quat(mat[:, 4:]).as_matrix()
    return Trajectory(mat[:, 0], mat[:, 1:4], rot, name=path.stem)


def run_to_tum(run: Run, source: Any = "truth", path: str | Path | None = None) -> str | Path:
    """TUM export of a Run's ``truth``/``ref``/``gnss`` pose channels or of an Estimate.

    Returns the written path when ``path`` is given, otherwise the TUM text."""
    if isinstance(source, str):
        traj = Trajectory.from_run(run, source)
    else:
        traj = Trajectory.from_estimate(source)
    if path is None:
        half = 0.5 * traj.yaw
        quat = np.column_stack([np.zeros(len(traj)), np.zeros(len(traj)), np.sin(half), np.cos(half)])
        return _tum_text(traj.t, traj.xyz, quat)
    return write_tum(path, traj.t, traj.x, traj.y, traj.yaw, traj.xyz[:, 2])


# ------------------------------------------------------------------------------------------
# Mapping
# ------------------------------------------------------------------------------------------
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_WHEEL_UNITS = ("rad/s", "rpm", "deg/s", "m/s")
_GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
_ACCEL_UNITS = {"m/s^2": 1.0, "g": G0}
_POS_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}


@dataclass(frozen=True)
class TimeMap:
    column: str = "t"  # CSV column
    unit: str = "s"
    source: str = "header"  # bags: header stamp or bag receive time
    _checks = {
        "unit": (lambda x: x in _TIME_UNITS, f"one of {sorted(_TIME_UNITS)}"),
        "source": (lambda x: x in ("header", "receive"), "'header' or 'receive'"),
        "column": (lambda x: x != "", "a column name"),
    }


@dataclass(frozen=True)
class WheelMap:
    """Wheel speeds of the left/right side (both wheels of a side share one speed)."""

    left: str = ""  # CSV columns
    right: str = ""
    topic: str = ""  # bags: sensor_msgs/JointState
    left_joints: tuple[str, ...] = ()
    right_joints: tuple[str, ...] = ()
    unit: str = "rad/s"
    wheel_radius: float = 0.0  # [m], for unit m/s; 0 = the platform's
    invert_left: bool = False
    invert_right: bool = False
    _checks = {
        "unit": (lambda x: x in _WHEEL_UNITS, f"one of {list(_WHEEL_UNITS)}"),
        "wheel_radius": (lambda x: 0 <= x < 5 and math.isfinite(x), "in [0, 5) m (0 = platform's)"),
    }

    @property
    def used(self) -> bool:
        return bool(self.left or self.right or self.topic)


@dataclass(frozen=True)
class ImuMap:
    topic: str = ""  # bags: sensor_msgs/Imu
    ax: str = ""  # CSV columns
    ay: str = ""
    az: str = ""
    gx: str = ""
    gy: str = ""
    gz: str = ""
    accel_unit: str = "m/s^2"
    gyro_unit: str = "rad/s"
    _checks = {
        "accel_unit": (lambda x: x in _ACCEL_UNITS, f"one of {sorted(_ACCEL_UNITS)}"),
        "gyro_unit": (lambda x: x in _GYRO_UNITS, f"one of {sorted(_GYRO_UNITS)}"),
    }

    @property
    def used(self) -> bool:
        return bool(self.topic or any((self.ax, self.ay, self.az, self.gx, self.gy, self.gz)))


@dataclass(frozen=True)
class PoseMap:
    """A planar pose source (GNSS/odometry, external reference or ground truth)."""

    topic: str = ""  # bags: nav_msgs/Odometry, geometry_msgs/PoseStamped(WithCovarianceStamped)
    x: str = ""  # CSV columns
    y: str = ""
    yaw: str = ""
    vx: str = ""
    vy: str = ""
    wz: str = ""
    position_unit: str = "m"  # also for vx, vy (per second)
    yaw_unit: str = "rad"  # also for wz (per second)
    velocity_frame: str = "body"  # CSV vx, vy given in the body or the world frame
    yaw_unwrapped: bool = False  # True: yaw may exceed +-pi (skips the degrees check)
    _checks = {
        "position_unit": (lambda x: x in _POS_UNITS, f"one of {sorted(_POS_UNITS)}"),
        "yaw_unit": (lambda x: x in _ANGLE_UNITS, f"one of {sorted(_ANGLE_UNITS)}"),
        "velocity_frame": (lambda x: x in ("body", "world"), "'body' or 'world'"),
    }

    @property
    def used(self) -> bool:
        return bool(self.topic or self.x or self.y or self.yaw)


@dataclass(frozen=True)
class PlatformMap:
    name: str = ""  # scenarios/platforms/<name>.toml
    max_wheel_speed: float = 0.0  # [rad/s] override of the motor-derived limit; 0 = derive
    _checks = {"max_wheel_speed": (lambda x: 0 <= x < 1e4 and math.isfinite(x), "in [0, 1e4) rad/s")}


@dataclass(frozen=True)
class ImportMapping:
    run_id: str = ""
    nan_policy: str = "error"  # error | drop (a NaN/inf sample becomes "no sample")
    time: TimeMap = field(default_factory=TimeMap)
    platform: PlatformMap = field(default_factory=PlatformMap)
    wheels: WheelMap = field(default_factory=WheelMap)
    commands: WheelMap = field(default_factory=WheelMap)
    imu: ImuMap = field(default_factory=ImuMap)
    gnss: PoseMap = field(default_factory=PoseMap)
    reference: PoseMap = field(default_factory=PoseMap)
    truth: PoseMap = field(default_factory=PoseMap)
    source_file: str = ""
    _checks = {"nan_policy": (lambda x: x in ("error", "drop"), "'error' or 'drop'")}


_POSE_PREFIX = {"gnss": "gnss", "reference": "ref", "truth": "truth"}
_WHEEL_PREFIX = {"wheels": "enc", "commands": "cmd"}


def load_mapping(path: str | Path) -> ImportMapping:
    """Parse and validate a mapping TOML (unknown keys, wrong types and units raise
    :class:`SpecError` naming the file and the dotted field)."""
    import tomllib

    path = Path(path)
    if not path.is_file():
        raise SpecError(path, "<file>", str(path), "mapping file not found")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(path, "<file>", str(path), f"malformed TOML: {exc}") from None
    data = dict(data, source_file=str(path))
    return build(ImportMapping, data, path)


def _as_mapping(mapping: ImportMapping | str | Path) -> ImportMapping:
    return mapping if isinstance(mapping, ImportMapping) else load_mapping(mapping)


def _platform(mapping: ImportMapping) -> Platform | None:
    name = mapping.platform.name
    if not name:
        return None
    try:
        return load_platform(name)
    except SpecError as exc:
        if exc.field != "<file>":
            raise
        from bench.spec import SCENARIO_DIR

        known = sorted(p.stem for p in (SCENARIO_DIR / "platforms").glob("*.toml"))
        raise SpecError(mapping.source_file or "<mapping>", "platform.name", name,
                        f"unknown platform; known: {known}") from None


def _wheel_factor(wm: WheelMap, section: str, platform: Platform | None, mapping: ImportMapping) -> float:
    if wm.unit == "rad/s":
        return 1.0
    if wm.unit == "rpm":
        return 2.0 * math.pi / 60.0
    if wm.unit == "deg/s":
        return math.pi / 180.0
    r = wm.wheel_radius or (platform.wheel_radius if platform else 0.0)
    if r <= 0:
        raise SpecError(mapping.source_file or "<mapping>", f"{section}.wheel_radius", wm.wheel_radius,
                        "unit m/s needs the wheel radius (here or via platform.name)")
    return 1.0 / r


# ------------------------------------------------------------------------------------------
# Plausibility
# ------------------------------------------------------------------------------------------
def _platform_obj(platform: Platform | Mapping[str, Any] | None) -> Platform | None:
    if platform is None or isinstance(platform, Platform):
        return platform
    return build(Platform, platform, "<run meta>")


def max_wheel_speed(platform: Platform) -> float:
    """No-load wheel speed [rad/s] at the supply voltage: omega_n / g_r * V_cc / V_nom."""
    m = platform.motor
    return m.no_load_speed / m.gear_ratio * m.supply_voltage / m.nominal_voltage


def max_yaw_rate(platform: Platform, w_max: float | None = None) -> float:
    """Fastest turn of an ideal differential drive with both sides at +-w_max: 2 r w_max / B
    (skid-steering only slows the turn down)."""
    w = max_wheel_speed(platform) if w_max is None else w_max
    return 2.0 * platform.wheel_radius * w / platform.track


def check_plausible(run: Run, platform: Platform | Mapping[str, Any] | None = None,
                    hints: Mapping[str, str] | None = None, max_wheel: float = 0.0) -> Run:
    """Reject magnitudes the platform cannot produce, with a unit suggestion.

    ``platform`` defaults to ``run.meta["platform"]``; ``hints`` maps a channel to where it came
    from (e.g. ``"CSV column 'wl', mapping wheels.unit = 'rad/s'"``).  Checks: wheel speeds
    (enc_*, cmd_*) against 1.5 x :func:`max_wheel_speed`; |imu_gz| against 1.5 x
    :func:`max_yaw_rate`; the median accelerometer norm (0.5..2 looks like g).
    """
    plat = _platform_obj(platform if platform is not None else run.meta.get("platform"))
    hints = dict(hints or {})
    where = run.where
    if plat is None:
        return run

    def src(c: str) -> str:
        return f"{c} ({hints[c]})" if c in hints else c

    w_max = max_wheel or max_wheel_speed(plat)
    lim = 1.5 * w_max
    for c in ("enc_wl", "enc_wr", "cmd_wl", "cmd_wr"):
        if c not in run.channels:
            continue
        v = run[c]
        a = np.abs(v[np.isfinite(v)])
        if a.size and a.max() > lim:
            vmax = float(a.max())
            as_rpm = vmax * 2.0 * math.pi / 60.0
            as_deg = vmax * math.pi / 180.0
            if as_rpm <= lim:
                hint = (f"looks like rpm ({vmax:.4g} rpm = {as_rpm:.3g} rad/s); set unit = \"rpm\" "
                        "in the mapping")
            elif as_deg <= lim:
                hint = (f"looks like deg/s ({vmax:.4g} deg/s = {as_deg:.3g} rad/s); set unit = "
                        "\"deg/s\" in the mapping")
            else:
                hint = "check the unit and the platform"
            raise RunError(where, src(c), vmax,
                           f"wheel speed exceeds 1.5 x the maximum {w_max:.3g} rad/s of platform "
                           f"'{plat.name}': {hint}")
    if "imu_gz" in run.channels:
        g = run["imu_gz"]
        a = np.abs(g[np.isfinite(g)])
        r_max = max_yaw_rate(plat, w_max)
        if a.size and a.max() > 1.5 * r_max:
            vmax = float(a.max())
            as_rad = vmax * math.pi / 180.0
            hint = (f"looks like deg/s ({vmax:.4g} deg/s = {as_rad:.3g} rad/s); set gyro_unit = "
                    "\"deg/s\" in the mapping" if as_rad <= 1.5 * r_max else "check the unit")
            raise RunError(where, src("imu_gz"), vmax,
                           f"yaw rate exceeds 1.5 x the fastest turn {r_max:.3g} rad/s of platform "
                           f"'{plat.name}': {hint}")
    acc = [c for c in ("imu_ax", "imu_ay", "imu_az") if c in run.channels]
    if len(acc) == 3:
        a = np.column_stack([run[c] for c in acc])
        m = np.all(np.isfinite(a), axis=1)
        if m.any():
            med = float(np.median(np.linalg.norm(a[m], axis=1)))
            if 0.5 < med < 2.0:
                raise RunError(where, src("imu_az"), med,
                               "median specific-force norm should be about 9.81 m/s^2 (gravity); "
                               "it looks like g: set accel_unit = \"g\" in the mapping")
    return run


def _check_yaw_unit(where: str, col: str, yaw: np.ndarray, pm: PoseMap, section: str) -> None:
    if pm.yaw_unwrapped or pm.yaw_unit != "rad":
        return
    a = np.abs(yaw[np.isfinite(yaw)])
    if a.size and a.max() > 2 * math.pi + 0.5:
        raise RunError(where, col, float(a.max()),
                       f"a heading in rad stays within +-pi; this looks like degrees: set "
                       f"{section}.yaw_unit = \"deg\" (or {section}.yaw_unwrapped = true)")


# ------------------------------------------------------------------------------------------
# CSV
# ------------------------------------------------------------------------------------------
def _check_csv_rows(path: Path, raw: bytes, sep: bytes = b",") -> None:
    """Every line has as many separators as the header (a truncated or overlong line is named)."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    nl = np.flatnonzero(buf == ord("\n"))
    ends = np.append(nl, buf.size) if (buf.size and (nl.size == 0 or nl[-1] != buf.size - 1)) else nl
    if ends.size == 0:
        return
    starts = np.concatenate(([0], ends[:-1] + 1))
    seps = np.flatnonzero(buf == sep[0])
    counts = np.searchsorted(seps, ends) - np.searchsorted(seps, starts)
    nonblank = ends > starts
    if b'"' in raw[: int(ends[0])]:
        return  # quoted header: leave field counting to the parser
    bad = np.flatnonzero(nonblank & (counts != counts[0]))
    if bad.size:
        i = int(bad[0])
        line = raw[int(starts[i]):int(ends[i])].decode(errors="replace")
        last = i == ends.size - 1 and not raw.endswith(b"\n")
        raise RunError(str(path), "<file>", f"line {i + 1}: {line[:60]!r}",
                       f"expected {counts[0] + 1} fields like the header, found {counts[i] + 1}"
                       + (" (file truncated?)" if last or counts[i] < counts[0] else ""))


def _parse_column(path: Path, name: str, raw: pd.Series, policy: str, required_full: bool = False
                  ) -> np.ndarray:
    s = raw.astype(str).str.strip()
    empty = s.eq("").to_numpy()
    v = pd.to_numeric(s.where(~s.eq(""), None), errors="coerce").to_numpy(dtype=float, copy=True)
    notnum = np.isnan(v) & ~empty & ~s.str.lower().isin(["nan", "+nan", "-nan"]).to_numpy()
    if notnum.any():
        i = int(np.flatnonzero(notnum)[0])
        raise RunError(str(path), name, f"line {i + 2}: {s.iloc[i]!r}", "expected a number")
    nonfinite = ~np.isfinite(v) & ~empty
    if nonfinite.any():
        if policy == "drop" and not required_full:
            v[nonfinite] = np.nan
        else:
            i = int(np.flatnonzero(nonfinite)[0])
            raise RunError(str(path), name, f"line {i + 2}: {s.iloc[i]!r}",
                           "NaN/inf is not a sample: leave the cell empty for 'no sample' "
                           "(or set nan_policy = \"drop\")")
    if required_full and empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise RunError(str(path), name, f"line {i + 2}: empty", "every row needs a timestamp")
    return v


def _check_time(where: str, name: str, t: np.ndarray, label: str = "line", base: int = 2) -> None:
    d = np.diff(t)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0])
        kind = "duplicated" if d[i] == 0 else "non-monotonic"
        raise RunError(where, name, f"{label} {i + 1 + base}: {float(t[i + 1])!r} after {float(t[i])!r}",
                       f"timestamps must increase strictly ({kind} timestamp)")


def _world_body(vx: np.ndarray, vy: np.ndarray, yaw: np.ndarray, to_world: bool) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(yaw), np.sin(yaw)
    if to_world:
        return c * vx - s * vy, s * vx + c * vy
    return c * vx + s * vy, -s * vx + c * vy


def _pose_channels(prefix: str, x: np.ndarray, y: np.ndarray, yaw: np.ndarray | None,
                   vx: np.ndarray | None, vy: np.ndarray | None, wz: np.ndarray | None,
                   vel_frame: str) -> dict[str, np.ndarray]:
    """Run channels of a pose source; gnss velocities are world-frame, truth velocities body."""
    out = {f"{prefix}_x": x, f"{prefix}_y": y}
    if yaw is not None:
        out[f"{prefix}_yaw"] = yaw
    if prefix == "ref":
        return out
    if vx is not None and vy is not None:
        want_world = prefix == "gnss"
        if (vel_frame == "world") != want_world:
            if yaw is None:
                raise ValueError("velocity frame conversion needs a yaw")
            vx, vy = _world_body(vx, vy, yaw, to_world=want_world)
        out[f"{prefix}_vx"], out[f"{prefix}_vy"] = vx, vy
    if wz is not None and prefix == "truth":
        out["truth_wz"] = wz
    return out


def import_csv(csv_path: str | Path, mapping: ImportMapping | str | Path, *, check: bool = True) -> Run:
    """Import a CSV log (one row per log tick, header line with column names; an empty cell is
    "no sample").  See the module docstring for the mapping."""
    path = Path(csv_path)
    mp = _as_mapping(mapping)
    platform = _platform(mp)
    if not path.is_file():
        raise RunError(str(path), "<file>", str(path), "file not found")
    raw = path.read_bytes()
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False, skip_blank_lines=False)
    except pd.errors.EmptyDataError:
        raise RunError(str(path), "<file>", "empty file", "a CSV log needs a header line and rows") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
        raise RunError(str(path), "<file>", str(exc).strip().splitlines()[-1], "malformed CSV") from None
    _check_csv_rows(path, raw)
    df.columns = [str(c).strip() for c in df.columns]
    hints: dict[str, str] = {}

    def col(section: str, fieldname: str, name: str, required_full: bool = False) -> np.ndarray:
        if name not in df.columns:
            raise RunError(str(path), name, None,
                           f"column named by mapping {section}.{fieldname} is not in the CSV; "
                           f"columns: {list(df.columns)}")
        return _parse_column(path, name, df[name], mp.nan_policy, required_full)

    t = col("time", "column", mp.time.column, required_full=True)
    if t.size == 0:
        raise RunError(str(path), mp.time.column, "empty", "the log has no rows")
    _check_time(str(path), mp.time.column, t)
    t = t * _TIME_UNITS[mp.time.unit]
    cols: dict[str, np.ndarray] = {"t": t - t[0]}

    for section, prefix in _WHEEL_PREFIX.items():
        wm: WheelMap = getattr(mp, section)
        if not (wm.left or wm.right):
            continue
        k = _wheel_factor(wm, section, platform, mp)
        for side, name, inv in (("left", wm.left, wm.invert_left), ("right", wm.right, wm.invert_right)):
            if not name:
                raise SpecError(mp.source_file or "<mapping>", f"{section}.{side}", "",
                                "both wheel columns are needed")
            ch = f"{prefix}_w{side[0]}"
            cols[ch] = col(section, side, name) * (k * (-1.0 if inv else 1.0))
            hints[ch] = f"CSV column '{name}', mapping {section}.unit = '{wm.unit}'"
    im = mp.imu
    for key, unit in (("ax", _ACCEL_UNITS[im.accel_unit]), ("ay", _ACCEL_UNITS[im.accel_unit]),
                      ("az", _ACCEL_UNITS[im.accel_unit]), ("gx", _GYRO_UNITS[im.gyro_unit]),
                      ("gy", _GYRO_UNITS[im.gyro_unit]), ("gz", _GYRO_UNITS[im.gyro_unit])):
        name = getattr(im, key)
        if name:
            cols[f"imu_{key}"] = col("imu", key, name) * unit
            u = im.accel_unit if key[0] == "a" else im.gyro_unit
            hints[f"imu_{key}"] = f"CSV column '{name}', mapping imu.{'accel' if key[0] == 'a' else 'gyro'}_unit = '{u}'"
    for section, prefix in _POSE_PREFIX.items():
        pm: PoseMap = getattr(mp, section)
        if not (pm.x or pm.y):
            continue
        if not (pm.x and pm.y):
            raise SpecError(mp.source_file or "<mapping>", f"{section}.{'y' if pm.x else 'x'}", "",
                            "a pose source needs both x and y columns")
        kp, ka = _POS_UNITS[pm.position_unit], _ANGLE_UNITS[pm.yaw_unit]
        get = {f: (col(section, f, getattr(pm, f)) if getattr(pm, f) else None)
               for f in ("x", "y", "yaw", "vx", "vy", "wz")}
        if get["yaw"] is not None:
            _check_yaw_unit(str(path), pm.yaw, get["yaw"], pm, section)
        yaw = None if get["yaw"] is None else get["yaw"] * ka
        try:
            cols.update(_pose_channels(
                prefix, get["x"] * kp, get["y"] * kp, yaw,
                None if get["vx"] is None else get["vx"] * kp, None if get["vy"] is None else get["vy"] * kp,
                None if get["wz"] is None else get["wz"] * ka, pm.velocity_frame))
        except ValueError:
            raise SpecError(mp.source_file or "<mapping>", f"{section}.yaw", "",
                            "converting velocities between body and world frame needs a yaw column") from None
    return _finish(cols, path, mp, platform, hints, check)


def _finish(cols: dict[str, np.ndarray], path: Path, mp: ImportMapping, platform: Platform | None,
            hints: Mapping[str, str], check: bool, extra_meta: Mapping[str, Any] | None = None) -> Run:
    meta: dict[str, Any] = {"run_id": mp.run_id or path.stem, "source_file": str(path),
                            "imported_from": path.name, "mapping": _mapping_meta(mp)}
    if platform is not None:
        meta["platform"] = to_dict(platform)
    meta.update(extra_meta or {})
    run = from_arrays(cols, meta)
    if len(cols) == 1:
        raise RunError(str(path), "<mapping>", mp.source_file or "<mapping>",
                       "the mapping names no channel to import")
    run.validate()
    if check and platform is not None:
        check_plausible(run, platform, hints, mp.platform.max_wheel_speed)
    return run


def _mapping_meta(mp: ImportMapping) -> dict[str, Any]:
    return {k: v for k, v in asdict(mp).items()}


# ------------------------------------------------------------------------------------------
# Bags
# ------------------------------------------------------------------------------------------
_POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped",
               "geometry_msgs/msg/PoseWithCovarianceStamped")


def _yaw_from_quat(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _extract(msgtype: str, msg: Any) -> tuple[float, ...] | list[Any]:
    """Numeric payload of one message (kept lean: this runs once per message)."""
    if msgtype == "sensor_msgs/msg/Imu":
        a, g = msg.linear_acceleration, msg.angular_velocity
        return (a.x, a.y, a.z, g.x, g.y, g.z)
    if msgtype == "sensor_msgs/msg/JointState":
        return [list(msg.name), np.asarray(msg.velocity, float)]
    if msgtype == "nav_msgs/msg/Odometry":
        p, q, v, w = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear, msg.twist.twist.angular
        return (p.x, p.y, q.x, q.y, q.z, q.w, v.x, v.y, w.z)
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        return (p.x, p.y, q.x, q.y, q.z, q.w)
    p, q = msg.pose.position, msg.pose.orientation  # PoseStamped
    return (p.x, p.y, q.x, q.y, q.z, q.w)


def import_bag(bag_path: str | Path, mapping: ImportMapping | str | Path, *, check: bool = True) -> Run:
    """Import a ROS 1 ``.bag`` file or a ROS 2 bag directory (see the module docstring)."""
    from rosbags.highlevel import AnyReader

    path = Path(bag_path)
    mp = _as_mapping(mapping)
    platform = _platform(mp)
    if not path.exists():
        raise RunError(str(path), "<file>", str(path), "file not found")
    where = str(path)
    sections: dict[str, tuple[str, tuple[str, ...]]] = {}
    for s in ("wheels", "commands"):
        wm: WheelMap = getattr(mp, s)
        if wm.topic:
            if not (wm.left_joints and wm.right_joints):
                raise SpecError(mp.source_file or "<mapping>", f"{s}.left_joints", list(wm.left_joints),
                                "a JointState topic needs left_joints and right_joints")
            sections[s] = (wm.topic, ("sensor_msgs/msg/JointState",))
    if mp.imu.topic:
        sections["imu"] = (mp.imu.topic, ("sensor_msgs/msg/Imu",))
    for s in _POSE_PREFIX:
        pm: PoseMap = getattr(mp, s)
        if pm.topic:
            sections[s] = (pm.topic, _POSE_TYPES)
    if not sections:
        raise RunError(where, "<mapping>", mp.source_file or "<mapping>", "the mapping names no topic to import")

    data: dict[str, tuple[list[int], list[Any]]] = {s: ([], []) for s in sections}
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as exc:  # rosbags raises several reader/storage errors: one message for all
        raise RunError(where, "<file>", f"{type(exc).__name__}: {exc}", "not a readable ROS 1/ROS 2 bag") from None
    try:
        conns = {c.topic: c for c in reader.connections}
        topic_of = {}
        for s, (topic, types) in sections.items():
            if topic not in conns:
                raise RunError(where, topic, None, f"topic named by mapping {s}.topic is not in the bag; "
                                                   f"topics: {sorted(conns)}")
            if conns[topic].msgtype not in types:
                raise RunError(where, topic, conns[topic].msgtype, f"mapping {s} expects a message of type "
                                                                   f"{' or '.join(types)}")
            topic_of.setdefault(topic, []).append(s)
        use_header = mp.time.source == "header"
        wanted = [conns[t] for t in topic_of]
        try:
            for con, stamp, rawdata in reader.messages(connections=wanted):
                msg = reader.deserialize(rawdata, con.msgtype)
                if use_header:
                    st = msg.header.stamp
                    stamp = int(st.sec) * 1_000_000_000 + int(st.nanosec)
                payload = _extract(con.msgtype, msg)
                for s in topic_of[con.topic]:
                    data[s][0].append(stamp)
                    data[s][1].append(payload)
        except RunError:
            raise
        except Exception as exc:
            raise RunError(where, "<file>", f"{type(exc).__name__}: {exc}",
                           "a readable bag (truncated or corrupt message data)") from None
    finally:
        reader.close()

    empty = [sections[s][0] for s, (st, _) in data.items() if not st]
    if empty:
        raise RunError(where, empty[0], "0 messages", "the topic named by the mapping has no message (empty run)")
    stamps = {s: np.asarray(st, np.int64) for s, (st, _) in data.items()}
    for s, st in stamps.items():
        _check_time(where, sections[s][0], st.astype(float) * 1e-9, label="message", base=0)
    t0 = min(int(st[0]) for st in stamps.values())
    grid = np.unique(np.concatenate(list(stamps.values())))
    tt = (grid - t0).astype(float) * 1e-9
    n = grid.size
    cols: dict[str, np.ndarray] = {"t": tt}
    hints: dict[str, str] = {}

    def place(s: str, values: np.ndarray) -> np.ndarray:
        out = np.full(n, np.nan)
        out[np.searchsorted(grid, stamps[s])] = values
        return out

    def finite(s: str, labels: tuple[str, ...], v: np.ndarray) -> np.ndarray:
        bad = ~np.isfinite(v)
        if bad.any():
            if mp.nan_policy == "drop":
                return np.where(bad, np.nan, v)
            i, k = (int(a) for a in np.argwhere(bad)[0])
            raise RunError(where, f"{sections[s][0]} {labels[k]}", f"message {i}: {v[i, k]}",
                           "NaN/inf in a message field (set nan_policy = \"drop\" to treat it as no sample)")
        return v

    for s, prefix in _WHEEL_PREFIX.items():
        if s not in data:
            continue
        wm = getattr(mp, s)
        names_seen = data[s][1][0][0]
        changed = [i for i, p in enumerate(data[s][1]) if p[0] != names_seen]
        if changed:
            raise RunError(where, f"{wm.topic} name", data[s][1][changed[0]][0],
                           f"message {changed[0]}: every JointState must list the joints {names_seen} in one order")
        vel = np.full((len(data[s][1]), 2), np.nan)
        for side, joints in ((0, wm.left_joints), (1, wm.right_joints)):
            missing = [j for j in joints if j not in names_seen]
            if missing:
                raise RunError(where, f"{wm.topic} name", names_seen, f"joints {missing} named by mapping {s} "
                                                                       "are missing from the JointState")
        idx_l = [names_seen.index(j) for j in wm.left_joints]
        idx_r = [names_seen.index(j) for j in wm.right_joints]
        try:
            arr = np.stack([p[1] for p in data[s][1]])
        except ValueError:
            raise RunError(where, f"{wm.topic} velocity", "ragged", "every JointState with the same joints") from None
        if arr.ndim != 2 or arr.shape[1] != len(names_seen):
            raise RunError(where, f"{wm.topic} velocity", f"{arr.shape[1] if arr.ndim == 2 else 0} values",
                           f"one velocity per joint ({len(names_seen)})")
        vel[:, 0], vel[:, 1] = arr[:, idx_l].mean(axis=1), arr[:, idx_r].mean(axis=1)
        vel = finite(s, ("velocity (left joints)", "velocity (right joints)"), vel)
        k = _wheel_factor(wm, s, platform, mp)
        cols[f"{prefix}_wl"] = place(s, vel[:, 0] * k * (-1.0 if wm.invert_left else 1.0))
        cols[f"{prefix}_wr"] = place(s, vel[:, 1] * k * (-1.0 if wm.invert_right else 1.0))
        for ch in ("wl", "wr"):
            hints[f"{prefix}_{ch}"] = f"topic {wm.topic}, mapping {s}.unit = '{wm.unit}'"
    if "imu" in data:
        arr = finite("imu", tuple(f"{a}.{c}" for a in ("linear_acceleration", "angular_velocity") for c in "xyz"),
                     np.asarray(data["imu"][1], float))
        ka, kg = _ACCEL_UNITS[mp.imu.accel_unit], _GYRO_UNITS[mp.imu.gyro_unit]
        for k, key in enumerate(("ax", "ay", "az", "gx", "gy", "gz")):
            cols[f"imu_{key}"] = place("imu", arr[:, k] * (ka if k < 3 else kg))
            hints[f"imu_{key}"] = (f"topic {mp.imu.topic}, mapping imu."
                                   f"{'accel_unit' if k < 3 else 'gyro_unit'} = "
                                   f"'{mp.imu.accel_unit if k < 3 else mp.imu.gyro_unit}'")
    for s, prefix in _POSE_PREFIX.items():
        if s not in data:
            continue
        pm = getattr(mp, s)
        arr = np.asarray(data[s][1], float)
        arr = finite(s, ("pose.position.x", "pose.position.y", "pose.orientation.x", "pose.orientation.y",
                         "pose.orientation.z", "pose.orientation.w", "twist.linear.x", "twist.linear.y",
                         "twist.angular.z")[: arr.shape[1]], arr)
        yaw = _yaw_from_quat(arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5])
        vx = vy = wz = None
        if arr.shape[1] == 9:  # Odometry: twist in the child (body) frame
            vx, vy, wz = arr[:, 6], arr[:, 7], arr[:, 8]
        kp = _POS_UNITS[pm.position_unit]
        if vx is not None:
            vx, vy = vx * kp, vy * kp
        ch = _pose_channels(prefix, arr[:, 0] * kp, arr[:, 1] * kp, yaw, vx, vy, wz, "body")
        cols.update({k: place(s, v) for k, v in ch.items()})
    return _finish(cols, path, mp, platform, hints, check,
                   {"time_origin_ns": t0, "time_source": mp.time.source})
